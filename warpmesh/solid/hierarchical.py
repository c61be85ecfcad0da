"""The hierarchical approach of [FG §16.5.2] in 3D through TetGen (the cross-check of
isosurface stuffing): the surface first, then the volume it encloses.

:func:`warpmesh.surface.pipeline.mesh_surface` triangulates f = 0 on a grid of cube side
``h`` (closed by caps on the bounds), :func:`warpmesh.optimize.remesh.optimize` remeshes it
on the exact surface with edges near ``h`` (sharp edges recovered), and the optional
``tetgen`` package fills it with quality tetrahedra (radius-edge ratio <= ``minratio``,
dihedral angles >= ``mindihedral``, volumes near that of a regular tetrahedron of edge h:
TetGen's target, not a bound; measured on the sphere, torus and part at sizes 0.1-0.2, the
largest interior tetrahedron within 1.25x of it, and within 2x with a face on the boundary,
which TetGen may not split).
TetGen is told not to split the boundary (``nobisect``), so the boundary triangles of the
result are the optimised surface's, refs included (``SURFACE_REF`` on f = 0, ``CAP_REF``
on the bounds).

Example
-------
>>> import warpmesh as wm
>>> vol = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.15, method="tetgen")
>>> s = vol.stats()
>>> s["euler"], s["negative_tets"], abs(s["volume"] - 4.18879) < 0.08
(2, 0, True)
"""

from __future__ import annotations

import math
import time

import numpy as np

from warpmesh import _conventions as C
from warpmesh.errors import WarpMeshError
from warpmesh.optimize.remesh import optimize
from warpmesh.surface.pipeline import mesh_surface

__all__ = ["mesh_tetgen", "max_tet_volume", "TETGEN_MINRATIO", "TETGEN_MINDIHEDRAL"]

#: TetGen's quality switches: largest radius-edge ratio, smallest dihedral angle (degrees)
TETGEN_MINRATIO = 1.5
TETGEN_MINDIHEDRAL = 10.0


def _import_tetgen():
    try:
        import tetgen
    except ImportError:
        raise ImportError("method='tetgen' needs the optional 'tetgen' package: pip install tetgen") from None
    return tetgen


def _face_key(f: np.ndarray, n: int) -> np.ndarray:
    f = np.sort(np.asarray(f, dtype=np.int64), axis=1)
    return (f[:, 0] * n + f[:, 1]) * n + f[:, 2]


def max_tet_volume(h: float) -> float:
    """TetGen's volume bound for cube size ``h``: the regular tetrahedron of edge ``h``.

    TetGen's ``-a`` switch only takes a number with ``fixedvolume=True``; without it the
    bound is silently ignored (the torus at size 0.12 had tetrahedra 18 times larger).

    >>> round(max_tet_volume(0.12), 7)
    0.0002036
    """
    return h**3 / (6 * math.sqrt(2))


def mesh_tetgen(shape, box: np.ndarray, h: float, device="cpu"):
    """Tetrahedra of {f > 0} in ``box`` by TetGen inside the optimised surface mesh (already
    validated arguments; :func:`warpmesh.solid.pipeline.mesh_domain` with ``method="tetgen"``
    is the public entry point).

    Returns
    -------
    points : (n, 3) float64
    tets : (m, 4) int64, positive
    tris : (k, 3) int64, the boundary triangles, outward
    refs : (k,) int64, the surface's triangle refs
    info : dict of counts and timings
    """
    tetgen = _import_tetgen()
    t0 = time.perf_counter()
    resolution = int(math.ceil(float(np.max(box[1] - box[0])) / h))
    surf = mesh_surface(shape, bounds=box, resolution=resolution, cap=True, device=device)
    t1 = time.perf_counter()
    surf = optimize(surf, shape, bounds=box, size=h)
    t2 = time.perf_counter()
    pts = np.asarray(surf.points, dtype=np.float64)
    tris = np.asarray(surf.cells["triangle"], dtype=np.int64)
    cell_refs = surf.cell_refs or {}
    refs = np.asarray(cell_refs.get("triangle", np.full(len(tris), C.SURFACE_REF)), dtype=np.int64)
    tg = tetgen.TetGen(pts, tris.astype(np.int32))
    try:
        nodes, elems, *_ = tg.tetrahedralize(order=1, quality=True, nobisect=True, minratio=TETGEN_MINRATIO,
                                             mindihedral=TETGEN_MINDIHEDRAL, fixedvolume=True,
                                             maxvolume=max_tet_volume(h), quiet=True)
    except RuntimeError as exc:
        raise WarpMeshError(f"TetGen refused the optimised surface ({exc}); try another 'size'") from exc
    t3 = time.perf_counter()
    points = np.asarray(nodes, dtype=np.float64)
    tets = np.asarray(elems, dtype=np.int64)
    p = points[tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    tets[vol < 0] = tets[vol < 0][:, [0, 1, 3, 2]]  # TetGen's orientation is the other way round
    if not np.allclose(points[: len(pts)], pts):
        raise WarpMeshError("TetGen renumbered the surface's vertices; the boundary refs cannot be carried over")
    # the boundary: faces of one tetrahedron, outward; refs from the surface (nobisect kept it)
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    n = len(points)
    key = _face_key(faces, n)
    _, inv, counts = np.unique(key, return_inverse=True, return_counts=True)
    bnd = faces[counts[inv] == 1]
    skey = _face_key(tris, n)
    order = np.argsort(skey)
    pos = np.clip(np.searchsorted(skey[order], _face_key(bnd, n)), 0, len(skey) - 1)
    found = skey[order][pos] == _face_key(bnd, n)
    if not found.all() or len(bnd) != len(tris):
        raise WarpMeshError(f"TetGen's boundary ({len(bnd)} faces) is not the surface's ({len(tris)}); "
                            f"{int((~found).sum())} faces new")
    info = {"surface_triangles": int(len(tris)), "tetgen_minratio": TETGEN_MINRATIO,
            "tetgen_mindihedral": TETGEN_MINDIHEDRAL, "time_surface": t1 - t0, "time_optimize": t2 - t1,
            "time_tetgen": t3 - t2, "steiner_points": int(n - len(pts)), "cube_size": float(h)}
    return points, tets, bnd, refs[order][pos].astype(np.int64), info


