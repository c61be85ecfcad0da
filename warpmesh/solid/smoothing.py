"""Smoothing of tetrahedral meshes that never lowers the smallest dihedral angle [FG §16.4.3,
"metric modifications": points move, connections stay].

A sweep moves every free vertex once: an interior vertex towards the centroid of its
neighbours, a boundary vertex on f = 0 towards the centroid of its boundary neighbours,
projected back onto f = 0 (Newton steps on the exact field); vertices on the caps of the
bounds stay. The full move and shorter ones (``STEPS``) are tried; the one that raises the
vertex's smallest dihedral angle most is kept. Vertices
move in rounds of an independent set (random priorities, local maxima: no two share a
tetrahedron), so each move is judged alone: it is kept only when the smallest dihedral
angle of the tetrahedra around the vertex does not drop, the largest stays below the mesh's
largest before smoothing, and every volume stays positive. The mesh's smallest dihedral
angle therefore never drops.

Example
-------
>>> import warpmesh as wm
>>> a = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.25)
>>> b = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.25, smooth=2)
>>> b.stats()["dihedral_min"] >= a.stats()["dihedral_min"]
True
"""

from __future__ import annotations

import numpy as np

from warpmesh.frep.tape import value_gradient_at
from warpmesh.solid.adjacency import TRI_EDGES, Neighbours, unique_edges
from warpmesh.solid.dihedral import tet_quality

__all__ = ["smooth_tets"]

PROJECTION_STEPS = 3
MAX_ROUNDS = 12
#: fractions of the move to the neighbours' centroid tried for each vertex (the best kept)
STEPS = (1.0, 0.5, 0.25)


def _project(tape, x: np.ndarray, device) -> np.ndarray:
    for _ in range(PROJECTION_STEPS):
        f, g = value_gradient_at(tape, x, device=device)
        g2 = np.einsum("ij,ij->i", g, g)
        x = x - np.where(g2[:, None] > 0, (f / np.where(g2 > 0, g2, 1.0))[:, None] * g, 0.0)
    return x


def smooth_tets(points, tets, tris, on_f, on_cap, tape, *, sweeps: int = 3, device="cpu", seed: int = 0,
                only=None):
    """Smooth a tetrahedral mesh without lowering its smallest dihedral angle.

    Parameters
    ----------
    points : (n, 3) float64
    tets : (m, 4) int, positive
    tris : (k, 3) int, the boundary triangles
    on_f : (n,) bool, boundary vertices on f = 0 that may slide on it
    on_cap : (n,) bool, vertices on the bounds (fixed)
    tape : Tape of the shape (the projection's field)
    sweeps : int
    only : (n,) bool, optional: the vertices that may move (default all that are free)

    Returns
    -------
    points : (n, 3) float64, the smoothed positions
    moved : int, accepted moves over all sweeps
    """
    pts = np.array(points, dtype=np.float64, copy=True)
    tets = np.asarray(tets, dtype=np.int64)
    n = len(pts)
    boundary = np.zeros(n, bool)
    boundary[np.asarray(tris).ravel()] = True
    free_in = ~boundary
    free_f = boundary & np.asarray(on_f) & ~np.asarray(on_cap)
    if only is not None:
        free_in &= np.asarray(only)
        free_f &= np.asarray(only)
    graph = Neighbours(unique_edges(tets), n)
    surface = Neighbours(unique_edges(tris, TRI_EDGES), n)
    q = tet_quality(pts, tets, device)
    t_min, t_max = q[:, 0].copy(), q[:, 1].copy()
    ceiling = float(t_max.max()) if len(t_max) else 180.0
    rng = np.random.default_rng(seed)
    moved = 0
    for _ in range(sweeps):
        todo = free_in | free_f
        for _ in range(MAX_ROUNDS):
            if not todo.any():
                break
            prio = np.where(todo, rng.random(n), -1.0)
            sel = todo & (prio >= graph.max_of(prio)) & (prio >= 0)
            todo &= ~sel
            cin = graph.mean_of(pts)
            csurf = surface.mean_of(pts)
            sf = np.flatnonzero(sel & free_f)
            # the tetrahedra around selected vertices: one selected vertex each (independent set)
            hit = sel[tets]
            around = np.flatnonzero(hit.any(axis=1))
            if not len(around):
                continue
            owner = tets[around, np.argmax(hit[around], axis=1)]
            before = np.full(n, np.inf)
            np.minimum.at(before, owner, t_min[around])
            best_gain = np.full(n, -np.inf)
            best_pos = pts.copy()
            best_min = best_max = None
            for step in STEPS:  # the full move to the centroid, then shorter ones
                target = pts.copy()
                target[sel & free_in] = pts[sel & free_in] + step * (cin[sel & free_in] - pts[sel & free_in])
                if len(sf):
                    target[sf] = _project(tape, pts[sf] + step * (csurf[sf] - pts[sf]), device)
                trial = pts.copy()
                trial[owner] = target[owner]
                q = tet_quality(trial, tets[around], device)  # a Warp kernel, float64
                new_min, new_max, vol = q[:, 0], q[:, 1], q[:, 3]
                after = np.full(n, np.inf)
                worst = np.zeros(n)
                np.minimum.at(after, owner, np.where(vol > 0, new_min, -np.inf))
                np.maximum.at(worst, owner, new_max)
                fine = sel & (after >= before) & (worst <= ceiling) & np.isfinite(after)
                gain = np.full(n, -np.inf)
                gain[fine] = after[fine] - before[fine]
                better = gain > best_gain
                best_gain[better] = gain[better]
                best_pos[better] = target[better]
                take = better[owner]
                if best_min is None:
                    best_min, best_max = new_min.copy(), new_max.copy()
                best_min[take] = new_min[take]
                best_max[take] = new_max[take]
            ok = np.isfinite(best_gain)
            if not ok.any():
                continue
            pts[ok] = best_pos[ok]
            keep = ok[owner]
            t_min[around[keep]] = best_min[keep]
            t_max[around[keep]] = best_max[keep]
            moved += int(ok.sum())
    return pts, moved
