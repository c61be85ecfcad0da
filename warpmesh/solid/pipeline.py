"""``mesh_domain``: meshes of implicit domains, planar or 3D [FG §16.5.2, the global approach].

A planar shape with 2-value bounds goes to :func:`warpmesh.planar.curves.mesh_domain`
(triangles). A 3D shape (or any shape with 3-value bounds) is filled with tetrahedra by
isosurface stuffing (:mod:`warpmesh.solid.stuffing`): validate -> stuff the BCC lattice in
kernels -> boundary triangles (the faces of one tetrahedron), oriented outward, with refs
(``SURFACE_REF`` on f = 0, ``CAP_REF`` where the bounds clip the shape) -> optional smoothing
that never lowers the smallest dihedral angle -> a :class:`~warpmesh.mesh.Mesh` whose
``stats()`` report the dihedral range, the radius-edge ratio and the volume.

Example
-------
>>> import warpmesh as wm
>>> vol = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.2)
>>> s = vol.stats()
>>> s["euler"], s["dihedral_min"] > 10.7, s["dihedral_max"] < 164.8, abs(s["volume"] - 4.18879) < 0.05
(2, True, True, True)
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from warpmesh import _conventions as C
from warpmesh._util.validate import check_device
from warpmesh._util.validate import check_box
from warpmesh.distributed.bricks import refuse_bricking
from warpmesh.frep.expr import Expr
from warpmesh.frep.shapes import Shape, as_shape
from warpmesh.frep.tape import tape_of, value_gradient_at
from warpmesh.mesh import Mesh
from warpmesh.planar.curves import mesh_domain as planar_mesh_domain
from warpmesh.frep.projection import ImplicitTarget
from warpmesh.solid.dihedral import tet_quality_summary
from warpmesh.solid.flips import flip_tets
from warpmesh.solid.hierarchical import mesh_tetgen
from warpmesh.solid.features import DIHEDRAL_CEILING, DIHEDRAL_FLOOR, FEATURE_ANGLE, recover_features
from warpmesh.solid.regions import mesh_regions
from warpmesh.solid.smoothing import smooth_tets
from warpmesh.solid.stuffing import ALPHA_LONG, ALPHA_SHORT, ROOT_ITERATIONS, stuff
from warpmesh.surface.options import check_float32_grid

__all__ = ["mesh_domain", "METHODS_3D", "VOLUME_REF", "boundary_faces"]

METHODS_3D = ("stuffing", "delaunay", "tetgen")
#: the ref of the tetrahedra of a domain (one region)
VOLUME_REF = 1
#: a vertex within this fraction of the cube size of a face of the bounds lies on it (cap)
CAP_TOLERANCE = 1.0e-4
#: the faces of a positive tetrahedron (a, b, c, d), each counter-clockwise seen from outside
_FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))


def mesh_domain(shape, bounds=None, *, size=None, method: str | None = None, smooth: int = 0,
                features: bool = True, flips: bool = False, device: str = C.DEFAULT_DEVICE, client=None,
                bricks: tuple[int, int, int] | None = None, brick_cells: int | None = None, gather: bool = True,
                output=None, progress=True, **options) -> Mesh:
    """Mesh the domain {f > 0} inside ``bounds``: triangles in the plane, tetrahedra in 3D.

    Parameters
    ----------
    shape : Shape or Expr, or a label volume
        f > 0 inside. A label volume (an integer array, a :class:`~warpmesh.io.images.Volume`,
        a pyvista ImageData or an image path) gives conforming tetrahedra of its regions by
        lattice cleaving (:func:`warpmesh.solid.regions.mesh_regions`, which takes
        ``labels=``, ``size``, ``snap`` and ``min_size``; no ``bounds``).
        For a shape: a planar shape with 2-value bounds gives a planar mesh
        (:func:`warpmesh.planar.curves.mesh_domain`, whose options ``tolerance``,
        ``min_angle``, ``method`` ({'global', 'triangle'}) and ``boundary`` apply there).
    bounds : ((x0, y0, z0), (x1, y1, z1)) or ((x0, y0), (x1, y1))
        The box; where the shape reaches past it, the domain is clipped and closed by caps.
    size : float, callable or 'curvature', optional
        3D: the lattice's cube side, the length of the long edges (short edges are
        sqrt(3)/2 of it); default: the smallest side of the box / 20. Must be positive and
        below the smallest side of the box. Graded meshes (stuffing): a function of position
        (takes an (n, 3) float array, returns n positive sizes: the longest edge asked of the
        background there), or ``'curvature'``: angle / curvature on the surface, growing with
        the distance from it, within [side / 40, side / 6] (other bounds and angle:
        ``size=warpmesh.solid.graded.curvature_size(shape, smallest, largest)``). The lattice
        is then refined by longest-edge bisection (:mod:`warpmesh.solid.graded`); the dihedral
        bound is not proven there: ``info["graded_dihedral_min"]`` and ``"graded_dihedral_max"``
        give the range found. Stuffing only: the other methods refuse a graded size.
    method : {'stuffing', 'delaunay', 'tetgen'}, optional
        3D: isosurface stuffing (Labelle & Shewchuk 2007) on a body-centred cubic lattice
        (default); or the seed's second global variant, ``'delaunay'``: BCC lattice points
        inside and points on the clipped surface about ``0.5 * size`` apart (creases first),
        scipy's Delaunay kernel, boundary recovery by points projected onto f = 0, then boundary
        sliver peeling, ``features``, ``max(smooth, 2)`` smoothing sweeps and flips, always
        (:mod:`warpmesh.solid.delaunay`; no proven dihedral bound: read ``dihedral_min``); or
        the hierarchical approach, the cross-check: the surface from
        ``mesh_surface``, optimised on the exact shape with edges near ``size``, filled by
        TetGen (the optional ``tetgen`` package; :mod:`warpmesh.solid.hierarchical`).
        ``smooth``, ``features`` and the ``feature_*`` options apply to stuffing and delaunay,
        the other options to stuffing only.
    smooth : int
        3D: sweeps of smoothing (interior vertices to the centroid of their neighbours,
        boundary vertices along f = 0), each move kept only when the smallest dihedral
        angle around the vertex does not drop (:func:`warpmesh.solid.smoothing.smooth_tets`).
        A label volume: passes of interface smoothing (the staircase of the voxels towards
        the smooth interfaces, junction curves along themselves, each vertex within a voxel
        of its cleaved place, the dihedral range kept: :mod:`warpmesh.solid.region_smoothing`).
    features : bool
        3D: move boundary vertices onto the creases and corners of the exact surface (where
        primitives meet, and where the bounds cap the shape), each move kept only when every
        dihedral angle around it stays in [``feature_floor``, ``feature_ceiling``]
        (:func:`warpmesh.solid.features.recover_features`); crease vertices then stay put.
    flips : bool
        3D: after smoothing, 2-3, 3-2 and 4-4 flips of interior faces and edges, each kept only
        when it raises the smallest dihedral angle where it acts (:func:`warpmesh.solid.flips.flip_tets`).
        ``info["quality_stages"]`` lists the quality after each stage (stuffing, features,
        smooth, flips).
    device : str
    client : dask.distributed.Client, optional
        3D, stuffing on a uniform lattice (the default method and a number ``size``): stuff
        the lattice brick by brick on this Dask cluster (:mod:`warpmesh.distributed.domain`).
        Each brick's tetrahedra are computed on a window of the global lattice, their
        vertices keyed by global lattice ids, so the client joins them exactly and the
        stuffed tetrahedra are those of one process (same positions, same order). The
        stages after stuffing (boundary triangles, ``features``, ``smooth``, ``flips``) need
        the whole mesh and run on the client, on the gathered mesh. Not bricked (refused):
        graded sizes, ``method='delaunay'`` or ``'tetgen'``, label volumes, planar domains.
    bricks, brick_cells : (3,) ints or int, optional
        With ``client``: bricks per axis of the lattice, or black nodes per brick side (a
        multiple of 8; default 128).
    gather : bool
        With ``client``: return one Mesh (default); with False, a
        :class:`~warpmesh.distributed.run.PartitionedMesh` of VTU pieces holding the
        stuffed tetrahedra (needs ``output``, and ``features=False``, ``smooth=0``,
        ``flips=False``: those stages need the whole mesh).
    output : str or os.PathLike, optional
        With ``client``: a ``.pvtu`` path; one VTU piece per brick (tetrahedra, point array
        ``lattice_key``) is written beside it as bricks finish.
    progress : bool or callable
        With ``client``: a progress bar over the bricks, or ``progress(done, total)``; with
        a label volume: a bar over the cleaving's stages (shown once the call has taken a
        second), or ``progress(done, total)``.
    **options
        3D: ``alpha_long``, ``alpha_short`` (the violation thresholds, default the paper's
        0.24776 and 0.40630 that prove dihedral angles in [10.7°, 164.8°]) and
        ``root_iterations`` (steps of the cut points' bracketed root search, default 12),
        ``feature_floor``, ``feature_ceiling`` (degrees, default 10 and 165) and
        ``feature_angle`` (degrees between the normals across a crease, default 35).

    Returns
    -------
    Mesh or PartitionedMesh
        3D: positive ``"tetra"`` cells (ref ``VOLUME_REF``) and the boundary ``"triangle"``
        cells, outward, ref ``SURFACE_REF`` (1) on f = 0 and ``CAP_REF`` (2) on the bounds.
        ``stats()`` adds ``dihedral_min``, ``dihedral_max`` (degrees), ``radius_edge_max``,
        ``radius_edge_mean``, ``boundary_distance`` (the largest |f|/|grad f| of a boundary
        vertex on f = 0, in units of ``size``), counts and timings. With ``client`` and
        ``gather=False``: the pieces on disk (a ``PartitionedMesh``).

    Raises
    ------
    ValueError
        Bounds that are not a finite box; ``size`` not positive or not below the smallest
        side of the box; an unknown ``method`` or option; a shape with no inside in the box
        or one that evaluates to NaN there.
    TypeError
        ``shape`` is not a shape or an expression.

    Example
    -------
    >>> import warpmesh as wm
    >>> part, bounds = wm.example("part")
    >>> vol = wm.mesh_domain(part, bounds=bounds, size=0.1)
    >>> s = vol.stats()
    >>> s["euler"], s["n_tetra"] > 10000, sorted(set(vol.cell_refs["triangle"].tolist()))
    (-6, True, [1])

    On a Dask cluster (here in-process threads; a ``LocalCluster`` of processes or a remote
    scheduler alike), the same mesh; the bricks the shape's interval proves outside are
    never meshed:

    >>> from dask.distributed import Client, LocalCluster
    >>> cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    >>> client = Client(cluster)
    >>> bricked = wm.mesh_domain(part, bounds=bounds, size=0.1, client=client, brick_cells=8, progress=False)
    >>> bool((bricked.points == vol.points).all()), bricked.info["bricks"], bricked.info["bricks_culled"]
    (True, 64, 28)
    >>> client.close(); cluster.close()
    """
    bricked = {"client": client, "bricks": bricks, "brick_cells": brick_cells, "gather": gather, "output": output,
               "progress": progress}
    if not isinstance(shape, (Shape, Expr)):  # a label volume: its regions (lattice cleaving)
        if client is not None:
            raise ValueError("'client' stuffs the domain of a shape; a label volume's regions (lattice cleaving) "
                             "are meshed in one process: drop 'client'")
        refuse_bricking(**{k: v for k, v in bricked.items() if k not in ("client", "progress")})
        defaults = {"method": None, "smooth": 0, "features": True, "flips": False}
        given = {k: v for k, v in zip(defaults, (method, smooth, features, flips)) if v is not defaults[k]}
        return mesh_regions(shape, bounds, size=size, device=device, progress=progress, **given, **options)
    if client is None:
        refuse_bricking(**{k: v for k, v in bricked.items() if k != "client"})
        bricked = None
    box = check_box(bounds)
    device = check_device(device)
    if box.shape[1] == 2:
        if as_shape(shape).dim == 3:
            raise ValueError("expected 3-value 'bounds' ((x0, y0, z0), (x1, y1, z1)) for a 3D shape, "
                             f"got {box.tolist()}")
        if bricked is not None:
            raise ValueError("'client' stuffs 3D domains; a planar domain (2-value 'bounds') is meshed in one "
                             "process: drop 'client'")
        if smooth or features is not True or flips:
            raise ValueError("'smooth', 'features' and 'flips' apply to 3D domains; planar domains are smoothed by their own pipeline")
        if method is not None:
            options["method"] = method
        return planar_mesh_domain(shape, bounds, size=size, device=device, **options)
    for name, value in (("features", features), ("flips", flips)):
        if not isinstance(value, bool):
            raise ValueError(f"expected True or False for {name!r}, got {value!r}")
    return _mesh_solid(shape, box, size, method or "stuffing", smooth, (features, flips), device, options, bricked)


def _check_size(size, box: np.ndarray) -> float:
    extent = float(np.min(box[1] - box[0]))
    if size is None:
        return extent / 20.0
    if callable(size) or isinstance(size, str):  # graded: the smallest size stands for h downstream
        from warpmesh.solid.graded import smallest_size

        return smallest_size(size, box)
    ok = isinstance(size, (int, float, np.integer, np.floating)) and not isinstance(size, bool) \
        and math.isfinite(size) and size > 0
    if not ok:
        raise ValueError(f"expected a positive finite 'size' (the lattice's cube side), got {size!r}")
    if size >= extent:
        raise ValueError(f"expected 'size' below the smallest side of 'bounds' ({extent:g}), got {size!r}; "
                         "lower 'size' or enlarge 'bounds'")
    return float(size)


def _check_options(options: dict) -> dict:
    known = {"alpha_long": ALPHA_LONG, "alpha_short": ALPHA_SHORT, "root_iterations": ROOT_ITERATIONS,
             "feature_floor": DIHEDRAL_FLOOR, "feature_ceiling": DIHEDRAL_CEILING, "feature_angle": FEATURE_ANGLE}
    unknown = sorted(set(options) - set(known))
    if unknown:
        raise ValueError(f"unknown option {unknown[0]!r} for a 3D domain; it takes {sorted(known)} "
                         "besides size, method, smooth and device")
    out = {**known, **options}
    for name in ("alpha_long", "alpha_short"):
        a = out[name]
        if isinstance(a, bool) or not isinstance(a, (int, float, np.floating)) or not 0.0 <= a < 0.5:
            raise ValueError(f"expected 0 <= {name!r} < 0.5 (a fraction of the edge), got {a!r}")
    for name, lo, hi in (("feature_floor", 0.0, 60.0), ("feature_ceiling", 120.0, 180.0),
                         ("feature_angle", 5.0, 90.0)):
        a = out[name]
        if isinstance(a, bool) or not isinstance(a, (int, float, np.integer, np.floating)) or not lo <= a <= hi:
            raise ValueError(f"expected {lo:g} <= {name!r} <= {hi:g} (degrees), got {a!r}")
    it = out["root_iterations"]
    if isinstance(it, bool) or not isinstance(it, (int, np.integer)) or not 1 <= it <= 60:
        raise ValueError(f"expected an integer 'root_iterations' in [1, 60], got {it!r}")
    return out


def boundary_faces(tets: np.ndarray, on_surface: np.ndarray | None = None) -> np.ndarray:
    """(k, 3) the faces of exactly one tetrahedron, outward (the tetrahedra positive).

    ``on_surface`` (n,) bool, optional: the vertices that can lie on the boundary (a face
    with another vertex is interior); only the faces with three such vertices are sorted.

    Example
    -------
    >>> boundary_faces(np.array([[0, 1, 2, 3]])).tolist()
    [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]
    >>> boundary_faces(np.array([[0, 1, 2, 3], [1, 2, 3, 4]])).shape  # the shared face drops out
    (6, 3)
    """
    tets = np.asarray(tets, dtype=np.int64)
    faces = np.concatenate([tets[:, list(f)] for f in _FACES])
    if on_surface is not None:
        faces = faces[np.asarray(on_surface)[faces].all(axis=1)]
    key = np.sort(faces, axis=1)
    n = int(tets.max()) + 1 if len(tets) else 1
    if n < 2**20:
        _, inv, counts = np.unique((key[:, 0] * n + key[:, 1]) * n + key[:, 2], return_inverse=True,
                                   return_counts=True)
    else:
        _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return faces[counts[inv.ravel()] == 1]


def _face_refs(points: np.ndarray, tris: np.ndarray, box: np.ndarray, h: float) -> np.ndarray:
    """CAP_REF for the triangles lying in one face of the box, SURFACE_REF elsewhere."""
    refs = np.full(len(tris), C.SURFACE_REF, dtype=np.int64)
    tol = CAP_TOLERANCE * h
    for a in range(3):
        for side in (0, 1):
            on = np.abs(points[:, a] - box[side, a]) <= tol
            refs[on[tris].all(axis=1)] = C.CAP_REF
    return refs


def _surface_refs_on_the_bounds(refs: np.ndarray, points: np.ndarray, tris: np.ndarray, tape, h: float,
                                device) -> np.ndarray:
    """The output refs: a face in a face of the box that is also on f = 0 (its centroid within
    ``CAP_TOLERANCE`` h of the surface: a box filling its bounds) is the shape's surface,
    SURFACE_REF, not a cap (every face of such a box was ref 2, none 1, so boundary conditions
    on the shape's surface found nothing); caps proper (f > 0 there: the shape cut by the box)
    stay CAP_REF. (The stages before keep their caps fixed either way.)"""
    caps = np.flatnonzero(refs == C.CAP_REF)
    if not len(caps):
        return refs
    f, g = value_gradient_at(tape, points[tris[caps]].mean(axis=1), device=device)
    distance = np.abs(f) / np.maximum(np.linalg.norm(g, axis=1), 1e-300)
    out = refs.copy()
    out[caps[distance <= CAP_TOLERANCE * h]] = C.SURFACE_REF
    return out


def _boundary_distance(tape, points: np.ndarray, on_f: np.ndarray, h: float, device) -> float:
    idx = np.flatnonzero(on_f)
    if not len(idx):
        return 0.0
    f, g = value_gradient_at(tape, points[idx], device=device)
    gn = np.linalg.norm(g, axis=1)
    return float(np.max(np.abs(f) / np.where(gn > 0, gn, np.inf))) / h


def _check_bricked(method: str, size, smooth, features: bool, flips: bool, gather) -> None:
    """What stuffing on bricks does not do, refused naming the argument."""
    if method != "stuffing":
        raise ValueError(f"method={method!r} is not bricked: with 'client' use method='stuffing' (the default), "
                         "or drop 'client'")
    if callable(size) or isinstance(size, str):
        raise ValueError(f"a graded 'size' ({size!r}) is not bricked: with 'client' give 'size' as a number "
                         "(the lattice's cube side), or drop 'client'")
    if isinstance(gather, (bool, np.bool_)) and not gather:  # np.False_ too, as check_run takes it
        whole = [name for name, on in (("features", features), ("smooth", smooth), ("flips", flips)) if on]
        if whole:
            raise ValueError(f"gather=False writes the stuffed tetrahedra in pieces; {', '.join(map(repr, whole))} "
                             "need the whole mesh (they run on the client after a gather): give features=False, "
                             "smooth=0 and flips=False, or gather=True")


def _mesh_solid(shape, box: np.ndarray, size, method: str, smooth, switches, device, options,
                bricked: dict | None = None) -> Mesh:
    features, flips = switches
    if method not in METHODS_3D:
        raise ValueError(f"unknown method {method!r} for a 3D domain. Pick one of {list(METHODS_3D)}")
    if isinstance(smooth, bool) or not isinstance(smooth, (int, np.integer)) or smooth < 0:
        raise ValueError(f"expected a number of sweeps >= 0 for 'smooth', got {smooth!r}")
    if bricked is not None:
        _check_bricked(method, size, smooth, features, flips, bricked["gather"])
    if method != "stuffing" and (callable(size) or isinstance(size, str)):
        # (meshing the whole domain at the graded field's smallest size instead can take hours)
        raise ValueError(f"method={method!r} takes a number 'size'; a graded 'size' ({size!r}) grades the "
                         "stuffing lattice only: use method='stuffing' (the default) or give 'size' as a number")
    h = _check_size(size, box)
    # the lattice's nodes are evaluated in float32, as mesh_surface's grid is: a box far from the
    # origin whose edges float32 cannot resolve is refused (it gave boundaries 5 sizes off, silently)
    try:
        check_float32_grid(box, np.maximum(1.0, np.ceil((box[1] - box[0]) / h)))
    except ValueError as exc:
        raise ValueError(str(exc).replace("lower the resolution", "raise 'size'")) from None
    opts = _check_options(options)
    if method == "delaunay":
        from warpmesh.solid.delaunay import mesh_delaunay  # scipy's Qhull: imported when asked for

        stuffing_only = sorted(set(options) & {"alpha_long", "alpha_short", "root_iterations"})
        if stuffing_only:
            raise ValueError(f"method='delaunay' takes none of the stuffing options {stuffing_only}; drop them "
                             "or use method='stuffing'")
        points, tets, tris, on_f, info = mesh_delaunay(shape, box, h, smooth=int(smooth), features=features,
                                                       floor=opts["feature_floor"], ceiling=opts["feature_ceiling"],
                                                       angle=opts["feature_angle"], device=device)
        info.update(method=method, boundary_distance=_boundary_distance(tape_of(shape), points, on_f, h, device))
        return Mesh(points, {"tetra": tets, "triangle": tris}, info=info,
                    cell_refs={"tetra": np.full(len(tets), VOLUME_REF), "triangle": _face_refs(points, tris, box, h)})
    if method == "tetgen":
        if options or smooth or flips:
            raise ValueError("method='tetgen' takes no 'smooth' and none of the stuffing options "
                             f"{sorted(options)}; drop them or use method='stuffing'")
        points, tets, tris, refs, info = mesh_tetgen(shape, box, h, device)
        info.update(tet_quality_summary(points, tets, device), method=method)
        info["boundary_distance"] = _boundary_distance(tape_of(shape), points, np.isin(
            np.arange(len(points)), tris[refs == C.SURFACE_REF]), h, device)
        return Mesh(points, {"tetra": tets, "triangle": tris},
                    cell_refs={"tetra": np.full(len(tets), VOLUME_REF), "triangle": refs}, info=info)
    stuffing = {"alpha_long": opts["alpha_long"], "alpha_short": opts["alpha_short"],
                "iterations": opts["root_iterations"]}
    if bricked is not None:  # the lattice on a Dask cluster, gathered here (or left in pieces)
        from warpmesh.distributed.domain import stuff_bricks

        stuffed = stuff_bricks(shape, box, h, stuffing, device=device, **bricked)
        if not bricked["gather"]:
            if not stuffed.n_cells:
                raise ValueError("expected a 'shape' with an inside (f > 0) in 'bounds', found no lattice node "
                                 f"inside at size {h:g}; check the shape, move 'bounds' or lower 'size'")
            return stuffed
        points, tets, on_surface, info = stuffed
    else:
        points, tets, on_surface, info = stuff(shape, box, h, **stuffing, device=device,
                                               grading=size if callable(size) or isinstance(size, str) else None)
    if not len(tets):
        raise ValueError("expected a 'shape' with an inside (f > 0) in 'bounds', found no lattice node "
                         f"inside at size {h:g}; check the shape, move 'bounds' or lower 'size'")
    t0 = time.perf_counter()
    tris = boundary_faces(tets, on_surface)
    tape = tape_of(shape)
    info["time_boundary"] = time.perf_counter() - t0
    crease = np.zeros(len(points), bool)
    stages = [("stuffing", tet_quality_summary(points, tets, device))]
    if features:
        t0 = time.perf_counter()
        target = ImplicitTarget(shape, bounds=box, device=device)
        before = points, tets
        points, tets, tris, crease, finfo = recover_features(points, tets, tris, target, h, floor=opts["feature_floor"],
                                                 ceiling=opts["feature_ceiling"], angle=opts["feature_angle"],
                                                 device=device)
        info.update(finfo, time_features=time.perf_counter() - t0)
        unchanged = (points.shape == before[0].shape and tets.shape == before[1].shape
                     and np.array_equal(points, before[0]) and np.array_equal(tets, before[1]))
        stages.append(("features", stages[-1][1] if unchanged else tet_quality_summary(points, tets, device)))
    refs = _face_refs(points, tris, box, h)
    on_cap = np.zeros(len(points), bool)
    on_cap[tris[refs == C.CAP_REF].ravel()] = True
    on_f = np.zeros(len(points), bool)
    on_f[tris[refs == C.SURFACE_REF].ravel()] = True
    on_f &= ~on_cap
    if smooth:
        t0 = time.perf_counter()
        before = stages[-1][1]
        points, moved = smooth_tets(points, tets, tris, on_f & ~crease, on_cap | crease, tape,
                                    sweeps=int(smooth), device=device)
        info.update(smooth_sweeps=int(smooth), smooth_moved=moved,
                    dihedral_min_before=before["dihedral_min"], dihedral_max_before=before["dihedral_max"],
                    radius_edge_max_before=before["radius_edge_max"], time_smooth=time.perf_counter() - t0)
        stages.append(("smooth", tet_quality_summary(points, tets, device)))
    if flips:
        t0 = time.perf_counter()
        info["dihedral_min_before_flips"] = stages[-1][1]["dihedral_min"]
        tets, flip_info = flip_tets(points, tets, tris, device=device)
        info.update(flip_info, time_flips=time.perf_counter() - t0)
        stages.append(("flips", tet_quality_summary(points, tets, device)))
    info.update(stages[-1][1])
    info["quality_stages"] = [{"stage": k, **v} for k, v in stages]
    info["boundary_distance"] = _boundary_distance(tape, points, on_f, h, device)
    info["method"] = method
    _warn_open_boundary(tris, h, info)
    refs = _surface_refs_on_the_bounds(refs, points, tris, tape, h, device)
    return Mesh(points, {"tetra": tets, "triangle": tris},
                cell_refs={"tetra": np.full(len(tets), VOLUME_REF), "triangle": refs}, info=info)


def _warn_open_boundary(tris: np.ndarray, h: float, info: dict) -> None:
    """A UserWarning when the stuffed domain's boundary is not a closed 2-manifold (an edge in
    one boundary face, or in three or more): parts of the shape thinner than about the lattice's
    edge are met by no node, so the tetrahedra of a thin plate join along edges or leave holes
    (a plate 0.06 thick at size 0.1: volume -85 %, Euler characteristic 4, said nowhere before);
    ``info["boundary_bad_edges"]`` counts them."""
    from warpmesh.cells.topology import unique_edges as triangle_edges

    bad = int(np.count_nonzero(triangle_edges(tris)[2] != 2)) if len(tris) else 0
    info["boundary_bad_edges"] = bad
    if bad:
        warnings.warn(f"mesh_domain: the domain's boundary is not a closed manifold ({bad} edges in one boundary "
                      f"face or in three or more): parts of the shape thinner than about 'size' ({h:g}) are pinched "
                      "or cut through; a smaller 'size' resolves them", UserWarning, stacklevel=4)
