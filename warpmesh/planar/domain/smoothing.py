"""Smoothing of planar triangle meshes that never lowers the local minimum angle.

The last step of the global approach of [FG §16.5.2] is an optimisation on element
shape. Here: Laplacian smoothing of the free (interior) vertices, one independent set at
a time (no two vertices of a set share a triangle, so each move is judged alone), each
vertex trying a few steps towards the centroid of its neighbours and keeping the best
one only when the smallest angle of its incident triangles does not decrease and every
incident triangle keeps a positive area.

Example
-------
>>> import numpy as np
>>> pts = np.array([[0, 0], [2, 0], [1, 1.7], [1.6, 0.3]], float)
>>> tris = np.array([[0, 1, 3], [1, 2, 3], [2, 0, 3]])
>>> free = np.array([False, False, False, True])
>>> from warpmesh.planar.domain.delaunay import min_angles
>>> new = smooth(pts, tris, free)
>>> bool(min_angles(new, tris)[0].min() > min_angles(pts, tris)[0].min())
True
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from warpmesh._conventions import INDEX_DTYPE
from warpmesh.planar.domain.delaunay import min_angles, signed_area2

if TYPE_CHECKING:  # annotations only: scipy is imported where it is used
    import scipy.sparse as sp

__all__ = ["smooth", "independent_sets"]

#: fractions of the step to the neighbours' centroid tried at each vertex
STEPS = (1.0, 0.5, 0.25)


def _vertex_graph(tris: np.ndarray, n: int) -> sp.csr_matrix:
    import scipy.sparse as sp

    a = tris.ravel()
    b = tris[:, [1, 2, 0]].ravel()
    g = sp.coo_matrix((np.ones(2 * len(a)), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n, n)).tocsr()
    g.data[:] = 1.0
    return g


def independent_sets(graph: sp.csr_matrix, candidates: np.ndarray, seed: int = 0) -> list[np.ndarray]:
    """Partition ``candidates`` (bool (n,)) into independent sets of ``graph`` (Luby:
    a vertex joins the current set when its random priority beats every remaining
    neighbour's)."""
    rng = np.random.default_rng(seed)
    prio = rng.random(graph.shape[0]) + 1.0
    left = np.asarray(candidates, bool).copy()
    sets = []
    while left.any():
        p = np.where(left, prio, 0.0)
        nb_max = graph.multiply(p[None, :]).tocsr().max(axis=1).toarray().ravel()
        pick = left & (p > nb_max)
        sets.append(np.flatnonzero(pick))
        left &= ~pick
    return sets


def _vertex_min(values: np.ndarray, tris: np.ndarray, n: int) -> np.ndarray:
    out = np.full(n, np.inf)
    for j in range(3):  # three corners
        np.minimum.at(out, tris[:, j], values)
    return out


def smooth(points: np.ndarray, tris: np.ndarray, free: np.ndarray, iterations: int = 4,
           stats: dict | None = None) -> np.ndarray:
    """Move free vertices towards their neighbours' centroid where it helps.

    Parameters
    ----------
    points : (n, 2) float64
    tris : (k, 3) int
        Counter-clockwise triangles.
    free : (n,) bool
        Vertices allowed to move (interior ones).
    iterations : int
        Sweeps over all free vertices.

    Returns
    -------
    (n, 2) float64
        New points; the smallest angle of the triangles around any vertex never
        decreases, and no triangle is inverted.
    """
    p = np.array(points, dtype=np.float64, copy=True)
    n = len(p)
    tris = np.asarray(tris, INDEX_DTYPE)
    graph = _vertex_graph(tris, n)
    deg = np.asarray(graph.sum(axis=1)).ravel()
    movable = np.asarray(free, bool) & (deg > 0)
    sets = independent_sets(graph, movable)
    moved = 0
    for _ in range(iterations):
        for s in sets:  # one independent set at a time
            ang, _ = min_angles(p, tris)
            old = _vertex_min(ang, tris, n)[s]
            centroid = (graph @ p)[s] / deg[s, None]
            has = np.isin(tris, s)
            t_idx = np.flatnonzero(has.any(axis=1))
            owner = tris[t_idx][has[t_idx]]  # the one vertex of s in each such triangle
            best, best_pos = old.copy(), p[s].copy()
            local = np.full(n, -1, INDEX_DTYPE)
            local[s] = np.arange(len(s))
            for lam in STEPS:  # a few candidate positions
                q = p.copy()
                q[s] = p[s] + lam * (centroid - p[s])
                a_new, _ = min_angles(q, tris[t_idx])
                a_new = np.where(signed_area2(q, tris[t_idx]) > 0, a_new, -1.0)
                vmin = np.full(len(s), np.inf)
                np.minimum.at(vmin, local[owner], a_new)
                better = vmin > best
                best = np.where(better, vmin, best)
                best_pos[better] = q[s][better]
            moved += int((best > old).sum())
            p[s] = best_pos
    if stats is not None:
        stats["smoothing_moves"] = moved
    return p
