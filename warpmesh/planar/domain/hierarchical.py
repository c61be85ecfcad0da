"""The hierarchical approach of [FG §16.5.2] through Shewchuk's Triangle (cross-check).

The boundary polyline (domain on the left) is handed to the optional ``triangle``
package as a PSLG with the quality switch ``q``. Hole points are not guessed from loop
orientation alone (a clockwise loop may hold an island): they come from our own
classification of a constrained Delaunay triangulation of the boundary, one per outside
region. Steiner points Triangle puts on boundary segments are projected onto the curve
and the refined boundary handed back, until Triangle adds none.

Example
-------
>>> import numpy as np, warpmesh as wm, triangle
>>> sq = lambda h: h * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
>>> pts = np.concatenate([sq(1.0), sq(0.5)[::-1]])
>>> segs = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4]])
>>> h = hole_points(triangle, pts, segs)      # one region outside: the hole
>>> h.shape, bool(np.all(np.abs(h) < 0.5))
((1, 2), True)
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.planar.domain.delaunay import ccw, classify, regions, signed_area2
from warpmesh.errors import WarpMeshError

__all__ = ["mesh_triangle", "hole_points"]

_TINY = 1.0e-300


def _import_triangle():
    try:
        import triangle
    except ImportError:
        raise ImportError("method='triangle' needs the optional 'triangle' package: pip install triangle") from None
    return triangle


def hole_points(tr, pts: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """One point inside each region outside the domain (holes, concavities, the space
    between nested loops): the regions of Triangle's constrained Delaunay triangulation
    of the boundary cut by the segments, those on the right of the segments, each
    represented by the incentre of its triangle of largest inradius (the point farthest
    from the segments that this triangulation offers)."""
    # four frame points well outside, so that no boundary vertex is on the convex hull (flat
    # slivers between nearly collinear vertices of a straight side would form regions of
    # arbitrary orientation); the unbounded region, the frame's, needs no hole point
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    frame = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    frame += 0.5 * (hi - lo).max() * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
    allp = np.concatenate([pts, frame])
    cdt = tr.triangulate({"vertices": allp, "segments": segs}, "p")
    if len(cdt["vertices"]) != len(allp):
        raise WarpMeshError("triangle changed the boundary of a plain constrained triangulation "
                            "(crossing segments?)")
    t = ccw(allp, cdt["triangles"])
    lab_all = regions(t, segs, len(allp))
    framed = np.isin(lab_all, lab_all[np.isin(t, np.arange(len(pts), len(allp))).any(axis=1)])
    out = np.flatnonzero(~classify(t, segs, len(allp)) & ~framed)
    if len(out) == 0:
        return np.zeros((0, 2))
    lab = lab_all[out]
    e = allp[t[out]]
    ln = np.linalg.norm(e[:, [1, 2, 0]] - e, axis=2)  # side j joins corners j and j + 1
    rho = np.abs(signed_area2(allp, t[out])) / np.maximum(ln.sum(axis=1), _TINY)
    best = np.lexsort((-rho, lab))
    first = best[np.r_[0, np.flatnonzero(np.diff(lab[best])) + 1]]
    w = ln[first][:, [1, 2, 0]]  # weight of corner j: the side opposite it (j + 1 -> j + 2)
    return np.einsum("ij,ijk->ik", w, e[first]) / w.sum(axis=1)[:, None]


def mesh_triangle(field, pts: np.ndarray, segs: np.ndarray, size: float, min_angle: float, stats: dict,
                  max_rounds: int = 6):
    """Quality mesh by Triangle (``pq<min_angle>a<area>``, area of the equilateral
    triangle of side ``size``); Steiner points on the boundary are projected onto the
    curve and the boundary handed back until Triangle adds none (at most ``max_rounds``).
    Returns points, CCW triangles and the mask of free (non-boundary) points."""
    tr = _import_triangle()
    area = np.sqrt(3.0) / 4.0 * size**2
    opts = f"pq{min_angle:g}a{area:.6g}"
    stats["triangle_options"] = opts
    for rnd in range(1, max_rounds + 1):
        holes = hole_points(tr, pts, segs)  # again each round: the boundary moved
        stats["holes"] = len(holes)
        arg = {"vertices": pts, "segments": segs}
        if len(holes):
            arg["holes"] = holes
        out = tr.triangulate(arg, opts)
        p = out["vertices"].astype(REAL_DTYPE)
        s = out["segments"].astype(INDEX_DTYPE)
        tris = ccw(p, out["triangles"])
        on_bnd = np.zeros(len(p), bool)
        on_bnd[s.ravel()] = True
        steiner = np.flatnonzero(on_bnd & (np.arange(len(p)) >= len(pts)))
        if len(steiner) == 0:
            break
        # Triangle returns subsegments undirected: orient each with the domain (its one
        # triangle) on the left, before the projection moves anything
        s = _orient_by_triangles(p, s, tris)
        stats["steiner_projected"] = stats.get("steiner_projected", 0) + len(steiner)
        p[steiner] = field.project(p[steiner], max_step=0.25 * _local_size(p, s, steiner))
        if rnd == max_rounds:
            break
        # hand the projected, refined boundary back
        old = np.flatnonzero(on_bnd)
        remap = np.full(len(p), -1, INDEX_DTYPE)
        remap[old] = np.arange(len(old))
        pts, segs = p[old], remap[s]
    stats["rounds"] = rnd
    stats["converged"] = len(steiner) == 0
    free = np.ones(len(p), bool)
    free[s.ravel()] = False
    return p, tris, free


def _local_size(p, s, v):
    ln = np.linalg.norm(p[s[:, 1]] - p[s[:, 0]], axis=1)
    acc = np.zeros(len(p))
    np.maximum.at(acc, s[:, 0], ln)
    np.maximum.at(acc, s[:, 1], ln)
    return acc[v]


def _orient_by_triangles(p, s, t):
    """Segments flipped so that the triangle (CCW) holding each is on its left."""
    n = len(p)
    directed = t.ravel().astype(np.int64) * n + t[:, [1, 2, 0]].ravel()
    fwd = np.isin(s[:, 0].astype(np.int64) * n + s[:, 1], directed)
    return np.where(fwd[:, None], s, s[:, ::-1])
