"""Boundary tags for physics: each surface triangle gets the ref of the CSG primitive it
lies on (``mesh_surface(shape, ..., refs="primitives")``).

A solver sets boundary conditions per face of the part (the plate's top, a hole's wall,
the boss): the primitives of the CSG tree (``Shape.primitives``, in the order the shape
was built) are those faces. Each triangle off the caps is given the primitive whose zero
set is nearest to *all three* of its vertices: the one that minimises the largest of the
vertices' distance estimates |f_i| / |grad f_i| [FG eq. 16.6]. A triangle that marching
cubes lays across a sharp edge (two vertices on one face, one on the other) goes to the
face holding two of its vertices. Primitive k (0-based) gets ref ``PRIMITIVE_REF0 + k``
(11, 12, ...), so the surface ref 1 and the cap ref 2 keep their meaning;
``mesh.info["primitives"]`` maps each ref to its primitive's name, and
``info["primitive_distance"]`` is, over the triangles, the largest distance from the
triangle's nearest vertex to its primitive, in cell sizes (0 to rounding with Newton or
bisection roots; a triangle across a chamfered edge has its other vertex up to a cell
off).

Example
-------
>>> import warpmesh as wm
>>> part, bounds = wm.example("part")
>>> m = wm.mesh_surface(part, bounds=bounds, resolution=32, refs="primitives")
>>> sorted(set(m.cell_refs["triangle"].tolist()))
[11, 12, 13, 14, 15, 16]
>>> m.info["primitives"][11], m.info["primitives"][16]
('box', 'sphere')
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import CAP_REF, INDEX_DTYPE
from warpmesh.frep.tape import evaluate

__all__ = ["PRIMITIVE_REF0", "primitive_refs", "REFS"]

#: the ref of the first primitive (the next ones follow); 1 and 2 stay surface and caps
PRIMITIVE_REF0 = 11
#: what ``mesh_surface(refs=...)`` takes
REFS = ("surface", "primitives")


def primitive_refs(shape, points: np.ndarray, triangles: np.ndarray, refs: np.ndarray | None,
                   cell_size: float) -> tuple[np.ndarray, dict]:
    """Per triangle the ref of its primitive (caps in ``refs`` keep ``CAP_REF``), and the
    info entries (``primitives``: ref -> name, ``primitive_distance``: in cell sizes)."""
    prims = shape.primitives
    used = np.unique(triangles)
    dist = np.empty((len(prims), len(points)))
    for k, (_, prim) in enumerate(prims):
        fg = evaluate(prim, points[used], gradient=True).astype(np.float64)
        dist[k, used] = np.abs(fg[:, 0]) / np.maximum(np.linalg.norm(fg[:, 1:], axis=1), 1e-300)
    worst = dist[:, triangles].max(axis=2)  # (primitives, triangles): the farthest vertex
    best = np.argmin(worst, axis=0)
    out = (PRIMITIVE_REF0 + best).astype(INDEX_DTYPE)
    surface = np.ones(len(triangles), bool) if refs is None else refs != CAP_REF
    if refs is not None:
        out[~surface] = CAP_REF
    nearest = dist[:, triangles].min(axis=2)
    reach = nearest[best, np.arange(len(triangles))][surface]
    info = {"primitives": {PRIMITIVE_REF0 + k: name for k, (name, _) in enumerate(prims)},
            "primitive_distance": float(reach.max() / cell_size) if len(reach) else 0.0}
    return out, info
