"""Polylines from segments: weld, orient (domain on the left), order into chains, count components.

Every curve sampler returns directed segments between sample points; this module turns
them into ordered chains [FG §16.3.2: "connecting the points two by two"] with
vectorised list ranking (pointer jumping, log n rounds), never a walk point by point.

Conventions: a segment (a, b) has the domain f > 0 on its left, i.e. its left normal
(-(b - a)_y, (b - a)_x) points up the gradient of f. A chain is a vertex sequence; a
closed chain repeats no vertex (its last vertex joins its first).

Example
-------
>>> import numpy as np
>>> segs = np.array([[2, 0], [0, 1], [1, 2], [3, 4]])
>>> [(c.tolist(), closed) for c, closed in chains(segs, 5)]
[([0, 1, 2], True), ([3, 4], False)]
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE

__all__ = ["chains", "chain_segments", "components", "orient_segments", "weld"]

_TINY = 1.0e-30


def weld(points: np.ndarray, segments: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge points closer than ``tol`` (snapped to a grid of step tol, so within 2 tol),
    drop unused points and segments that collapse; returns (points, segments)."""
    pts = np.asarray(points, REAL_DTYPE).reshape(-1, 2)
    segs = np.asarray(segments, INDEX_DTYPE).reshape(-1, 2)
    if len(pts) == 0:
        return pts, segs
    key = np.round((pts - pts.min(axis=0)) / tol).astype(np.int64)
    _, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.ravel()
    segs = inv[segs]
    segs = segs[segs[:, 0] != segs[:, 1]]
    used = np.unique(segs)
    remap = np.full(len(first), -1, INDEX_DTYPE)
    remap[used] = np.arange(len(used))
    return pts[first[used]], remap[segs]


def orient_segments(points: np.ndarray, segments: np.ndarray, gradients: np.ndarray) -> np.ndarray:
    """Segments flipped where needed so that f > 0 lies on their left.

    ``gradients`` (m, 2) is grad f at each segment's midpoint (or any point near it).
    """
    segs = np.asarray(segments, INDEX_DTYPE).reshape(-1, 2).copy()
    d = points[segs[:, 1]] - points[segs[:, 0]]
    flip = (-d[:, 1] * gradients[:, 0] + d[:, 0] * gradients[:, 1]) < 0
    segs[flip] = segs[flip, ::-1]
    return segs


def components(segments: np.ndarray, n_points: int) -> tuple[int, np.ndarray]:
    """Connected components of the segment graph: (count, label per point; -1 unused)."""
    segs = np.asarray(segments, INDEX_DTYPE).reshape(-1, 2)
    if len(segs) == 0:
        return 0, np.full(n_points, -1, INDEX_DTYPE)
    import scipy.sparse as sp  # here, not at import: scipy.sparse is slow to import
    from scipy.sparse.csgraph import connected_components

    graph = sp.coo_matrix((np.ones(len(segs)), (segs[:, 0], segs[:, 1])), shape=(n_points, n_points))
    _, lab = connected_components(graph, directed=False)
    used = np.zeros(n_points, bool)
    used[segs.ravel()] = True
    _, lab_used = np.unique(lab[used], return_inverse=True)
    out = np.full(n_points, -1, INDEX_DTYPE)
    out[used] = lab_used.ravel()
    return int(lab_used.max()) + 1 if used.any() else 0, out


def chains(segments: np.ndarray, n_points: int) -> list[tuple[np.ndarray, bool]]:
    """Ordered vertex chains of directed segments, each with a closed flag.

    A vertex where the segments do not continue one to one (two segments leaving or
    entering it: a singular point, a T-junction) ends the chains through it.
    Chains come out ordered by their smallest vertex index.
    """
    segs = np.asarray(segments, INDEX_DTYPE).reshape(-1, 2)
    if len(segs) == 0:
        return []
    n = n_points
    outdeg = np.bincount(segs[:, 0], minlength=n)
    indeg = np.bincount(segs[:, 1], minlength=n)
    # segment s continues with the segment leaving its end, where that end is entered and
    # left exactly once
    leave = np.full(n, -1, INDEX_DTYPE)
    single_out = outdeg[segs[:, 0]] == 1
    leave[segs[single_out, 0]] = np.flatnonzero(single_out)
    cont = leave[segs[:, 1]]
    nxt = np.where((cont >= 0) & (indeg[segs[:, 1]] == 1), cont, -1).astype(INDEX_DTYPE)
    m = len(segs)
    rounds = int(np.ceil(np.log2(m + 1))) + 1
    # pointer jumping: after 2^rounds >= m steps an open chain sits on its tail (no successor)
    # and a cycle is still inside itself; lab is the cycle's smallest segment
    succ = np.where(nxt >= 0, nxt, np.arange(m))
    lab = np.arange(m)
    for _ in range(rounds):
        lab = np.minimum(lab, lab[succ])
        succ = succ[succ]
    in_cycle = nxt[succ] >= 0
    nxt = np.where(in_cycle & (nxt == lab), -1, nxt)  # cut each cycle before its smallest segment
    # list ranking: distance to the chain's last segment
    succ = np.where(nxt >= 0, nxt, np.arange(m))
    rank = (nxt >= 0).astype(np.int64)
    for _ in range(rounds):
        rank = rank + np.where(succ != np.arange(m), rank[succ], 0)
        succ = succ[succ]
    tail = succ  # each segment's chain tail
    order = np.lexsort((-rank, tail))
    bounds = np.flatnonzero(np.diff(tail[order])) + 1
    out = []
    for group in np.split(order, bounds):
        closed = bool(in_cycle[group[0]])
        verts = np.append(segs[group, 0], segs[group[-1], 1])
        if closed:  # start a cycle at its smallest vertex
            verts = np.roll(verts[:-1], -int(np.argmin(verts[:-1])))
        out.append((verts, closed))
    out.sort(key=lambda c: int(c[0].min()))
    return out


def chain_segments(chain: np.ndarray, closed: bool) -> np.ndarray:
    """The (k, 2) segments of one chain, in order."""
    c = np.asarray(chain, INDEX_DTYPE)
    if closed:
        return np.column_stack([c, np.roll(c, -1)])
    return np.column_stack([c[:-1], c[1:]])
