"""Conforming Delaunay triangulation of a planar domain and Ruppert-style refinement.

The global approach of [FG §16.5.2] builds its elements with a Delaunay kernel; here
the kernel is ``scipy.spatial.Delaunay`` (Qhull), re-run on the whole point set once per
round, and everything around it is vectorised over triangles, edges and segments:

* boundary recovery by *conforming* Delaunay: a boundary segment missing from the
  triangulation is split at its midpoint projected onto the curve, until every
  segment is an edge (:func:`conform`);
* inside / outside by a flood fill over the triangle adjacency that never crosses a
  boundary segment, each region labelled by the side of the directed segments it
  touches (the domain is on the LEFT of a segment, :func:`classify`);
* Ruppert-style refinement (:func:`refine`): segments encroached by a vertex are split
  (free vertices inside their diametral circle are deleted); triangles whose smallest
  angle is below the bound receive their circumcentre (or Üngör's off-centre when that
  is nearer their shortest edge), unless it encroaches a segment, which is then split
  instead. Triangles whose smallest angle sits at a sharp input corner (< 60 degrees
  between two boundary segments) are left alone. All selected circumcentres of a round are inserted at
  once, thinned so that no two are closer than the larger circumradius.

Conventions: triangles are counter-clockwise (positive area); a boundary segment (a, b)
has the domain on its left, so the inside triangle on it holds the directed edge a -> b.

Example
-------
>>> import numpy as np
>>> sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], float)
>>> tris, _ = delaunay(sq)
>>> inside = classify(tris, np.array([[0, 1], [1, 2], [2, 3], [3, 0]]), len(sq))
>>> len(tris), bool(inside.all())
(4, True)
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.errors import WarpMeshError

if TYPE_CHECKING:  # annotations only: scipy is imported where it is used (0.5 s at start-up)
    from scipy.spatial import Delaunay

__all__ = ["delaunay", "ccw", "signed_area2", "edge_keys", "missing_segments", "regions", "classify", "conform",
           "refine", "circumcenters", "min_angles", "split_segments"]

_TINY = 1.0e-300
#: a vertex between two boundary segments meeting at less than this (degrees, inside the
#: domain) is a sharp input corner: triangles whose smallest angle sits there are left alone
SHARP_CORNER = 60.0
#: nearest segment midpoints searched for encroachment of a candidate circumcentre
_K_ENCROACH = 8
#: candidates of one round closer than this times the larger circumradius conflict (1: as
#: far apart as one-at-a-time insertion would leave them, which keeps refinement finite)
_THIN = 1.0
_K_THIN = 16


# -- basic geometry ----------------------------------------------------------------
def delaunay(points: np.ndarray) -> tuple[np.ndarray, Delaunay]:
    """Counter-clockwise Delaunay triangles (k, 3) of (n, 2) points, and Qhull's object.

    Raises
    ------
    WarpMeshError
        Qhull dropped points (duplicates): every point must be a vertex.
    """
    from scipy.spatial import Delaunay

    d = Delaunay(np.asarray(points, REAL_DTYPE))
    if len(d.coplanar):
        raise WarpMeshError(f"Delaunay dropped {len(d.coplanar)} duplicate point(s); weld the input first")
    return ccw(points, d.simplices.astype(INDEX_DTYPE)), d


def signed_area2(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Twice the signed area (k,) of triangles: positive when counter-clockwise."""
    p = points[tris]
    return ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))


def ccw(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Triangles (k, 3) reordered counter-clockwise (a copy)."""
    t = np.array(tris, INDEX_DTYPE, copy=True)
    flip = signed_area2(points, t) < 0
    t[flip] = t[flip][:, [0, 2, 1]]
    return t


def edge_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """Undirected edge keys min(a, b) * n + max(a, b), int64."""
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    return np.minimum(a, b) * n + np.maximum(a, b)


def _tri_edges(tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Directed edges (3k,) origins and ends of CCW triangles: edge j of triangle t is
    row 3 t + j, from corner j to corner j + 1 (the triangle on its left)."""
    return tris.ravel(), tris[:, [1, 2, 0]].ravel()


def missing_segments(tris: np.ndarray, segments: np.ndarray, n: int) -> np.ndarray:
    """(m,) bool: which segments are not edges of the triangulation."""
    a, b = _tri_edges(tris)
    present = np.unique(edge_keys(a, b, n))
    key = edge_keys(segments[:, 0], segments[:, 1], n)
    return ~np.isin(key, present)


def circumcenters(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circumcentres (k, 2) and circumradii (k,) of triangles."""
    p = points[tris]
    a = p[:, 0]
    b, c = p[:, 1] - a, p[:, 2] - a
    d = 2.0 * (b[:, 0] * c[:, 1] - b[:, 1] * c[:, 0])
    b2, c2 = np.einsum("ij,ij->i", b, b), np.einsum("ij,ij->i", c, c)
    d = np.where(np.abs(d) > _TINY, d, _TINY)
    u = np.column_stack([c[:, 1] * b2 - b[:, 1] * c2, b[:, 0] * c2 - c[:, 0] * b2]) / d[:, None]
    return a + u, np.linalg.norm(u, axis=1)


def min_angles(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Smallest interior angle (degrees, (k,)) of each triangle and the corner (0..2) it is at."""
    p = points[tris]
    ang = np.empty((len(tris), 3))
    for j in range(3):  # three corners
        u, v = p[:, (j + 1) % 3] - p[:, j], p[:, (j + 2) % 3] - p[:, j]
        cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
        ang[:, j] = np.degrees(np.arctan2(np.abs(cross), np.einsum("ij,ij->i", u, v)))
    corner = ang.argmin(axis=1) if len(tris) else np.zeros(0, INDEX_DTYPE)
    return (ang.min(axis=1) if len(tris) else np.zeros(0)), corner


# -- inside / outside ----------------------------------------------------------------
def regions(tris: np.ndarray, segments: np.ndarray, n: int) -> np.ndarray:
    """(k,) label of each triangle's region: triangles joined across every edge that is
    not a segment (connected components of the dual graph cut by the segments)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    k = len(tris)
    a, b = _tri_edges(tris)
    tri_of = np.repeat(np.arange(k), 3)
    key = edge_keys(a, b, n)
    order = np.argsort(key, kind="stable")
    ks = key[order]
    same = np.flatnonzero(ks[1:] == ks[:-1])  # pairs of triangles on one edge
    same = same[~np.isin(ks[same], edge_keys(segments[:, 0], segments[:, 1], n))]
    graph = sp.coo_matrix((np.ones(len(same)), (tri_of[order[same]], tri_of[order[same + 1]])), shape=(k, k))
    return connected_components(graph, directed=False)[1]


def classify(tris: np.ndarray, segments: np.ndarray, n: int) -> np.ndarray:
    """(k,) bool: triangles inside the domain bounded by directed ``segments``.

    Triangles are joined across every edge that is not a segment; each connected region
    is inside when one of its triangles holds a segment a -> b as a CCW edge (the domain
    is on the segment's left), outside when one holds b -> a. Regions touching no
    segment are outside. Every segment must be an edge (see :func:`conform`).

    Raises
    ------
    WarpMeshError
        A region lies on the left of one segment and on the right of another: the
        segments are not consistently oriented.
    """
    k = len(tris)
    a, b = _tri_edges(tris)
    tri_of = np.repeat(np.arange(k), 3)
    lab = regions(tris, segments, n)
    directed = a.astype(np.int64) * n + b
    left = np.isin(directed, segments[:, 0].astype(np.int64) * n + segments[:, 1])
    right = np.isin(directed, segments[:, 1].astype(np.int64) * n + segments[:, 0])
    n_lab = int(lab.max()) + 1 if k else 0
    ins = np.bincount(lab[tri_of[left]], minlength=n_lab) > 0
    out = np.bincount(lab[tri_of[right]], minlength=n_lab) > 0
    if np.any(ins & out):
        raise WarpMeshError("boundary segments are not consistently oriented (expected the domain on the "
                            "LEFT of every segment); a region lies on both sides")
    return ins[lab]


# -- segment splitting ----------------------------------------------------------------
def split_segments(points: np.ndarray, segments: np.ndarray, which: np.ndarray, field=None,
                   stats: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Split segments ``which`` (indices) at their midpoints, projected onto the curve.

    The projection (Newton, steps capped at a quarter of the segment) is kept only when
    it moves the midpoint by less than half the segment and stays a quarter segment
    away from both ends; otherwise the plain midpoint
    is used and counted in ``stats["unprojected"]``. Returns new points and segments
    (segment i becomes (a, m) in place, (m, b) is appended).
    """
    which = np.unique(np.asarray(which, INDEX_DTYPE))
    if len(which) == 0:
        return points, segments
    s = segments[which]
    a, b = points[s[:, 0]], points[s[:, 1]]
    mid = 0.5 * (a + b)
    ln = np.linalg.norm(b - a, axis=1)
    if field is not None:
        proj = field.project(mid, max_step=0.25 * ln)
        moved = np.linalg.norm(proj - mid, axis=1)
        ends = np.minimum(np.linalg.norm(proj - a, axis=1), np.linalg.norm(proj - b, axis=1))
        ok = np.isfinite(moved) & (moved < 0.5 * ln) & (ends > 0.25 * ln)
        mid = np.where(ok[:, None], proj, mid)
        if stats is not None:
            stats["unprojected"] = stats.get("unprojected", 0) + int((~ok).sum())
    m = np.arange(len(points), len(points) + len(which))
    segs = segments.copy()
    segs[which, 1] = m
    segs = np.concatenate([segs, np.column_stack([m, s[:, 1]])])
    if stats is not None:
        stats["splits"] = stats.get("splits", 0) + len(which)
    return np.concatenate([points, mid]), segs


def conform(points: np.ndarray, segments: np.ndarray, field=None, max_rounds: int = 40,
            stats: dict | None = None):
    """Split missing segments until every segment is a Delaunay edge.

    Returns ``(points, segments, tris, qhull)``.

    Raises
    ------
    WarpMeshError
        Segments are still missing after ``max_rounds`` rounds.
    """
    for _ in range(max_rounds):
        tris, d = delaunay(points)
        miss = np.flatnonzero(missing_segments(tris, segments, len(points)))
        if len(miss) == 0:
            return points, segments, tris, d
        points, segments = split_segments(points, segments, miss, field, stats)
        if stats is not None:
            stats["recovery_rounds"] = stats.get("recovery_rounds", 0) + 1
    raise WarpMeshError(f"boundary recovery: {len(miss)} segment(s) still missing after {max_rounds} rounds")


# -- Ruppert-style refinement -----------------------------------------------------------
def _boundary_angles(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Interior angle (degrees) at each point between its incoming and outgoing segment
    (the domain on the left); 360 at points with no single in / out segment."""
    n = len(points)
    out = np.full(n, 360.0)
    indeg = np.bincount(segments[:, 1], minlength=n)
    outdeg = np.bincount(segments[:, 0], minlength=n)
    inc = np.full(n, -1, INDEX_DTYPE)
    inc[segments[:, 1]] = np.arange(len(segments))
    v = np.flatnonzero((indeg == 1) & (outdeg == 1))
    s_out = np.full(n, -1, INDEX_DTYPE)
    s_out[segments[:, 0]] = np.arange(len(segments))
    fwd = points[segments[s_out[v], 1]] - points[v]
    back = points[segments[inc[v], 0]] - points[v]
    # angle swept counter-clockwise from the outgoing direction to the incoming one reversed
    ang = np.degrees(np.arctan2(fwd[:, 0] * back[:, 1] - fwd[:, 1] * back[:, 0], np.einsum("ij,ij->i", fwd, back)))
    out[v] = np.mod(ang, 360.0)
    return out


def _encroached_by_vertices(points, tris, segments, n):
    """Segments whose inside triangle's opposite vertex sees them at >= 90 degrees:
    (segment indices, the encroaching vertices)."""
    a, b = _tri_edges(tris)
    opp = tris[:, [2, 0, 1]].ravel()  # vertex opposite edge j (corner j + 2)
    seg_dir = segments[:, 0].astype(np.int64) * n + segments[:, 1]
    order = np.argsort(seg_dir)
    directed = a.astype(np.int64) * n + b
    pos = np.clip(np.searchsorted(seg_dir[order], directed), 0, len(order) - 1)
    hit = seg_dir[order][pos] == directed
    e = np.flatnonzero(hit)
    u, w = points[a[e]] - points[opp[e]], points[b[e]] - points[opp[e]]
    enc = np.einsum("ij,ij->i", u, w) <= 0.0
    return order[pos[e[enc]]], opp[e[enc]]


def _encroaching(c: np.ndarray, points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """For each point of ``c`` the nearest segment whose diametral circle contains it
    (among the nearest segment midpoints), or -1."""
    from scipy.spatial import cKDTree

    mid = 0.5 * (points[segments[:, 0]] + points[segments[:, 1]])
    half = 0.5 * np.linalg.norm(points[segments[:, 1]] - points[segments[:, 0]], axis=1)
    k = min(_K_ENCROACH, len(segments))
    dist, idx = cKDTree(mid).query(c, k=k)
    dist, idx = dist.reshape(len(c), k), idx.reshape(len(c), k)
    inside = dist < half[idx]
    first = np.argmax(inside, axis=1)  # nearest midpoint first
    return np.where(inside.any(axis=1), idx[np.arange(len(c)), first], -1)


def _steiner_points(points: np.ndarray, tris: np.ndarray, min_angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Where to refine each bad triangle: its circumcentre, or its off-centre (Üngör)
    when that is closer to the shortest edge: the apex, on the edge's bisector towards
    the circumcentre, of an isosceles triangle on the edge with apex angle a bit above
    ``min_angle``, so the new triangle on that edge is good at once. Returns the points
    and the circumradii (for thinning)."""
    c, r = circumcenters(points, tris)
    p = points[tris]
    ln = np.linalg.norm(p[:, [1, 2, 0]] - p, axis=2)  # edge j: corner j -> j + 1
    j = ln.argmin(axis=1)
    rows = np.arange(len(tris))
    a, b = p[rows, j], p[rows, (j + 1) % 3]
    m = 0.5 * (a + b)
    to_c = c - m
    dist_c = np.linalg.norm(to_c, axis=1)
    apex = np.radians(min(min_angle + 2.0, 60.0))
    dist_off = 0.5 * ln[rows, j] / np.tan(0.5 * apex)
    use = dist_off < dist_c
    off = m + to_c * (dist_off / np.maximum(dist_c, _TINY))[:, None]
    return np.where(use[:, None], off, c), r


def _thin(c: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Indices of a subset of ``c`` (in priority order) with no two points closer than
    the larger circumradius: of each conflicting pair the later one is dropped."""
    from scipy.spatial import cKDTree

    if len(c) < 2:
        return np.arange(len(c))
    k = min(_K_THIN, len(c))
    dist, idx = cKDTree(c).query(c, k=k)
    i = np.repeat(np.arange(len(c)), k)
    j, d = idx.ravel(), dist.ravel()
    conflict = (j > i) & (d < _THIN * np.maximum(r[i], r[j]))
    drop = np.zeros(len(c), bool)
    drop[j[conflict]] = True
    return np.flatnonzero(~drop)


def refine(points: np.ndarray, segments: np.ndarray, free: np.ndarray, field=None, *, min_angle: float = 28.0,
           max_points: int = 200_000, max_rounds: int = 100, stats: dict | None = None):
    """Ruppert-style Delaunay refinement of the domain bounded by ``segments``.

    Parameters
    ----------
    points : (n, 2) float64
        Boundary and interior points.
    segments : (m, 2) int
        Directed boundary segments (domain on the left).
    free : (n,) bool
        Points that may be deleted (interior points, not on the boundary).
    field : PlanarField, optional
        Split points are projected onto its curve.
    min_angle : float
        Triangles with a smaller angle are refined (degrees).

    Returns
    -------
    points, segments, triangles (inside ones, CCW), free, and the number of rounds.
    The refinement stops when no triangle is bad, when a round adds nothing, after
    ``max_rounds`` rounds or once ``max_points`` is reached (``stats["converged"]``).
    """
    stats = {} if stats is None else stats
    for key in ("splits", "unprojected", "recovery_rounds", "inserted", "deleted"):
        stats.setdefault(key, 0)
    free = np.asarray(free, bool)
    rounds = 0
    stats["converged"] = False
    for rounds in range(1, max_rounds + 1):
        n0 = len(points)
        points, segments, tris, _ = conform(points, segments, field, stats=stats)
        free = np.concatenate([free, np.zeros(len(points) - n0, bool)])
        n = len(points)
        inside = classify(tris, segments, n)
        tin = tris[inside]
        enc_seg, enc_v = _encroached_by_vertices(points, tin, segments, n)
        ang, corner = min_angles(points, tin)
        sharp = _boundary_angles(points, segments) < SHARP_CORNER
        bad = (ang < min_angle) & ~sharp[tin[np.arange(len(tin)), corner]]
        if len(enc_seg) == 0 and not bad.any():
            stats["converged"] = True
            break
        if n >= max_points:
            break
        # circumcentres (or off-centres) of bad triangles, worst first
        order = np.flatnonzero(bad)[np.argsort(ang[bad], kind="stable")]
        c, r = _steiner_points(points, tin[order], min_angle)
        # inside: f > 0 (a centre between a segment and the curve encroaches the segment)
        in_domain = field.values(c) > 0 if field is not None else np.ones(len(c), bool)
        enc_c = _encroaching(c, points, segments) if len(c) else np.zeros(0, INDEX_DTYPE)
        split = np.unique(np.concatenate([enc_seg, enc_c[enc_c >= 0]]))
        keep = np.flatnonzero(in_domain & (enc_c < 0))
        keep = keep[_thin(c[keep], r[keep])]
        keep = keep[: max(0, max_points - n)]
        if len(split) == 0 and len(keep) == 0:
            break  # nothing left to do: stalled (reported through stats["converged"])
        # free vertices encroaching a split segment are deleted (Ruppert)
        delete = np.zeros(n, bool)
        delete[enc_v[free[enc_v]]] = True
        points, segments = split_segments(points, segments, split, field, stats)
        free = np.concatenate([free, np.zeros(len(split), bool)])
        points = np.concatenate([points, c[keep]])
        free = np.concatenate([free, np.ones(len(keep), bool)])
        delete = np.concatenate([delete, np.zeros(len(points) - n, bool)])
        if delete.any():
            remap = np.cumsum(~delete) - 1
            points, free = points[~delete], free[~delete]
            segments = remap[segments]
        stats["inserted"] = stats.get("inserted", 0) + len(keep)
        stats["deleted"] = stats.get("deleted", 0) + int(delete.sum())
    else:
        points, segments, tris, _ = conform(points, segments, field, stats=stats)
        free = np.concatenate([free, np.zeros(len(points) - len(free), bool)])
        tin = tris[classify(tris, segments, len(points))]
    return points, segments, tin, free, rounds
