"""Triangle meshes of planar implicit domains {f > 0} [FG §16.5.2].

Given the boundary curve as a directed polyline (the domain on the LEFT of each
segment, as every curve sampler returns it), two approaches:

``method="global"`` (the book's global approach)
    1. a size function: the boundary edge size at the boundary, growing linearly with
       the distance to it (slope ``gradation - 1``), capped by ``size``;
    2. interior points from a covering-up: a quadtree of the box refined until each
       cell is no larger than the size at its centre; cells whose interval enclosure
       of f is negative are culled, and each leaf whose centre has f > 0 and lies
       farther than 0.7 cell sizes from the boundary gives one point (its centre);
    3. the Delaunay kernel (``scipy.spatial.Delaunay``) on boundary + interior points,
       boundary recovery by conforming Delaunay (missing segments split at their
       midpoints projected onto the curve), triangles outside removed by a flood fill;
    4. Ruppert-style refinement to ``min_angle`` (:mod:`warpmesh.planar.domain.delaunay`);
    5. smoothing that never lowers the local minimum angle (:mod:`warpmesh.planar.domain.smoothing`).

``method="triangle"`` (the hierarchical approach, as a cross-check)
    the same boundary handed to Shewchuk's Triangle (the optional ``triangle``
    package) with quality switch ``q`` (:mod:`warpmesh.planar.domain.hierarchical`); hole points
    come from our own classification of a constrained Delaunay triangulation of the
    boundary, so nested loops are handled; Steiner points Triangle puts on the boundary
    are projected onto the curve and the boundary handed back, until Triangle adds none.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> field = PlanarField(wm.circle(1.0), ((-1.2, -1.2), (1.2, 1.2)))
>>> t = np.linspace(0, 2 * np.pi, 64, endpoint=False)
>>> pts = np.column_stack([np.cos(t), np.sin(t)])
>>> segs = np.column_stack([np.arange(64), np.roll(np.arange(64), -1)])
>>> p, tris, info = mesh_domain_from_boundary(field, pts, segs, size=0.3)
>>> bool(info["min_angle"] >= 28.0), bool(abs(info["area"] - np.pi) < 0.01)
(True, True)
"""

from __future__ import annotations

import time
import warnings
from typing import Literal

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.planar.domain.delaunay import classify, conform, min_angles, refine, signed_area2
from warpmesh.planar.domain.smoothing import smooth
from warpmesh.errors import WarpMeshError
from warpmesh.cells.quality import triangle_quality
from warpmesh.planar.domain.hierarchical import mesh_triangle

__all__ = ["mesh_domain_from_boundary", "size_function", "interior_points", "METHODS"]

METHODS = ("global", "triangle")
#: interior points closer than this many cell sizes to the boundary are not seeded
_CLEARANCE = 0.7
#: a cell is split while its side exceeds this times the size at its centre, so leaf sides
#: (the interior point spacing) range over [h / sqrt 2, h sqrt 2]
_SPLIT = np.sqrt(2.0)
#: interior points are moved by up to this fraction of their cell's half side
_JITTER = 0.02
_TINY = 1.0e-300


# -- validation -------------------------------------------------------------------------
def _check(points, segments, size, min_angle, gradation, max_points, method):
    if method not in METHODS:
        raise ValueError(f"Unknown method {method!r}. Pick one of {list(METHODS)}")
    try:
        pts = np.asarray(points, REAL_DTYPE)
    except (TypeError, ValueError):
        raise ValueError(f"expected 'points' an (n, 2) array of numbers, got {type(points).__name__}") from None
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise ValueError(f"expected 'points' a non-empty (n, 2) array of finite numbers, got shape {pts.shape}")
    segs = np.asarray(segments)
    if segs.ndim != 2 or segs.shape[1] != 2 or len(segs) < 3:
        raise ValueError(f"expected 'segments' an (m, 2) array with m >= 3 (a closed boundary), got shape {segs.shape}")
    if not np.issubdtype(segs.dtype, np.integer):
        raise TypeError(f"expected 'segments' of integers, got dtype {segs.dtype}")
    segs = segs.astype(INDEX_DTYPE)
    if segs.min() < 0 or segs.max() >= len(pts) or np.any(segs[:, 0] == segs[:, 1]):
        raise ValueError(f"expected 'segments' of distinct point indices in [0, {len(pts)}), got out-of-range "
                         "or repeated indices")
    n = len(pts)
    if np.any(np.bincount(segs[:, 0], minlength=n) != np.bincount(segs[:, 1], minlength=n)):
        raise ValueError("expected 'segments' forming closed loops (each point entered as often as it is "
                         "left), got open chains; close the boundary or clip the domain by the box")
    if size is not None and (isinstance(size, bool) or not (np.isscalar(size) and np.isfinite(size) and size > 0)):
        raise ValueError(f"expected 'size' a positive number or None, got {size!r}")
    if not (np.isscalar(min_angle) and 0 < min_angle <= 33):
        raise ValueError(f"expected 'min_angle' in (0, 33] degrees (Delaunay refinement terminates only "
                         f"below about 33.8), got {min_angle!r}")
    if not (np.isscalar(gradation) and gradation > 1):
        raise ValueError(f"expected 'gradation' a number > 1 (size ratio between neighbours), got {gradation!r}")
    if not (isinstance(max_points, (int, np.integer)) and max_points > len(pts)):
        raise ValueError(f"expected 'max_points' an integer larger than the {len(pts)} boundary points, "
                         f"got {max_points!r}")
    # drop points no segment uses
    used = np.unique(segs)
    remap = np.full(n, -1, INDEX_DTYPE)
    remap[used] = np.arange(len(used))
    return pts[used], remap[segs]


# -- size function and covering-up --------------------------------------------------------
def size_function(points: np.ndarray, segments: np.ndarray, size: float, gradation: float):
    """h(x) = min(size, min_v (h_v + (gradation - 1) |x - v|)) over boundary vertices v,
    h_v the mean length of the segments at v. Returns a callable (q, 2) -> (q,)."""
    from scipy.spatial import cKDTree

    ln = np.linalg.norm(points[segments[:, 1]] - points[segments[:, 0]], axis=1)
    acc = np.bincount(segments.ravel(), weights=np.repeat(ln, 2), minlength=len(points))
    h_v = acc / np.maximum(np.bincount(segments.ravel(), minlength=len(points)), 1)
    tree, slope = cKDTree(points), gradation - 1.0
    k = min(16, len(points))

    def h(q):
        q = np.asarray(q, REAL_DTYPE).reshape(-1, 2)
        d, i = tree.query(q, k=k)
        d, i = d.reshape(len(q), k), i.reshape(len(q), k)
        return np.minimum(size, (h_v[i] + slope * d).min(axis=1))

    return h


def _distance_to_boundary(q, points, segments, k: int = 8):
    from scipy.spatial import cKDTree

    mid = 0.5 * (points[segments[:, 0]] + points[segments[:, 1]])
    k = min(k, len(segments))
    _, idx = cKDTree(mid).query(q, k=k)
    idx = idx.reshape(len(q), k)
    a, b = points[segments[idx, 0]], points[segments[idx, 1]]
    d = b - a
    rel = q[:, None, :] - a
    t = np.clip(np.einsum("ijk,ijk->ij", rel, d) / np.maximum(np.einsum("ijk,ijk->ij", d, d), _TINY), 0, 1)
    return np.linalg.norm(rel - t[..., None] * d, axis=2).min(axis=1)


def interior_points(field, points, segments, h, max_points: int, stats: dict | None = None) -> np.ndarray:
    """Centres of the leaves of a quadtree graded by the size function ``h``.

    The root is the square around the boundary; a cell is split while its side exceeds
    h at its centre, and culled when interval arithmetic proves f < 0 on it. A leaf gives
    its centre when f > 0 there and the centre lies at least 0.7 sides from the boundary.

    Raises
    ------
    WarpMeshError
        More than ``max_points`` cells or interior points would be created.
    """
    lo, hi = points.min(axis=0), points.max(axis=0)
    half = 0.5 * float((hi - lo).max()) * 1.001
    centres, halves = [], []
    cells = (0.5 * (lo + hi))[None, :]
    hs = half
    levels = 0
    while len(cells):
        levels += 1
        iv = field.intervals(cells - hs, cells + hs)
        cells = cells[iv[:, 1] > 0]  # culled: f < 0 on the whole cell
        split = 2 * hs > _SPLIT * h(cells)
        leaves = cells[~split]
        centres.append(leaves)
        halves.append(np.full(len(leaves), hs))
        cells = cells[split]
        if len(cells) + sum(map(len, centres)) > max_points:
            raise WarpMeshError(f"the covering-up would exceed max_points={max_points}; raise 'max_points' "
                                "or 'size', or coarsen the boundary")
        hs *= 0.5
        cells = (cells[:, None, :] + hs * np.array([[-1, -1], [1, -1], [-1, 1], [1, 1]])).reshape(-1, 2)
    c, hl = np.concatenate(centres), np.concatenate(halves)
    keep = field.values(c) > 0
    c, hl = c[keep], hl[keep]
    if stats is not None:
        stats["quadtree_levels"] = levels
        stats["quadtree_leaves"] = int(len(hl))
    keep = _distance_to_boundary(c, points, segments) > _CLEARANCE * 2 * hl
    c, hl = c[keep], hl[keep]
    if len(c) > max_points:
        raise WarpMeshError(f"the covering-up gives {len(c)} interior points, more than max_points={max_points} "
                            "leaves room for; raise 'max_points' or 'size'")
    # a small deterministic jitter breaks the grid's cocircularity (Qhull is faster on it)
    c = c + _JITTER * hl[:, None] * np.random.default_rng(0).uniform(-1.0, 1.0, c.shape)
    return c


# -- public entry -----------------------------------------------------------------------
def frame_inside(points, segments, frame: np.ndarray) -> bool:
    """Whether an inside triangle of the boundary-conforming Delaunay triangulation of
    ``points`` (before any refinement) uses one of the ``frame`` vertices: the segments
    then run the wrong way round (the unbounded region would be meshed)."""
    p, s, tris, _ = conform(points, segments)
    return bool(np.isin(tris[classify(tris, s, len(p))], frame).any())


def mesh_domain_from_boundary(field, points, segments, *, size: float | None = None, min_angle: float = 28.0,
                              gradation: float = 1.5, max_points: int = 200_000, optimize: bool = True,
                              method: Literal["global", "triangle"] = "global"):
    """Triangle mesh of the planar domain f > 0 bounded by a directed polyline.

    Parameters
    ----------
    field : PlanarField
        The domain's function: split points are projected onto f = 0, leaves are
        classified by its sign and interval enclosures.
    points : (n, 2) float
        Boundary vertices (on the curve, within the sampler's tolerance).
    segments : (m, 2) int
        Directed boundary segments forming closed loops, the domain on the LEFT of each
        (outer loops counter-clockwise, holes clockwise).
    size : float, optional
        Largest element size inside. Default: the larger of the longest boundary
        segment and a tenth of the boundary's smaller extent.
    min_angle : float
        Quality bound for Delaunay refinement, degrees in (0, 33].
    gradation : float
        > 1; the size grows away from the boundary with slope ``gradation - 1``
        (neighbouring cells differ by about this ratio).
    max_points : int
        Cap on the number of vertices.
    optimize : bool
        Smooth interior vertices afterwards (never lowering the local minimum angle).
    method : {"global", "triangle"}
        The book's global approach, or the ``triangle`` package (hierarchical).

    Returns
    -------
    points : (p, 2) float64
    triangles : (k, 3) int64
        Counter-clockwise (positive areas).
    info : dict
        ``np``, ``ne``, ``min_angle``, ``mean_q``, ``worst_q`` ([FG eq. 16.15], 1 is
        equilateral), ``area``, ``boundary_distance_max`` (of the boundary vertices to
        the curve), ``rounds``, ``converged``, counts of splits and insertions, ``time``.

    Raises
    ------
    ValueError
        Bad ``points`` (or not on f = 0), ``segments`` (not closed loops), ``size``,
        ``min_angle``, ``gradation``, ``max_points`` or ``method``.
    ImportError
        ``method="triangle"`` without the ``triangle`` package.
    WarpMeshError
        Boundary recovery fails, or the segments are not consistently oriented.
    """
    t0 = time.perf_counter()
    pts, segs = _check(points, segments, size, min_angle, gradation, max_points, method)
    ln = np.linalg.norm(pts[segs[:, 1]] - pts[segs[:, 0]], axis=1)
    shortest = np.full(len(pts), np.inf)
    np.minimum.at(shortest, segs[:, 0], ln)
    np.minimum.at(shortest, segs[:, 1], ln)
    off = field.estimate(pts) / shortest
    if np.any(off > 0.5):
        i = int(np.argmax(off))
        raise ValueError(f"expected boundary 'points' on the curve f = 0 of 'field' (within half a segment), "
                         f"got {pts[i].tolist()} at about {off[i]:.3g} segment lengths from it; is the field "
                         "the one the boundary was sampled from, with f > 0 inside?")
    if size is None:
        size = max(float(ln.max()), 0.1 * float((pts.max(axis=0) - pts.min(axis=0)).min()))
    stats = {"method": method, "size": float(size)}
    if method == "triangle":
        p, tris, free = mesh_triangle(field, pts, segs, float(size), float(min_angle), stats)
    else:
        h = size_function(pts, segs, float(size), float(gradation))
        inner = interior_points(field, pts, segs, h, max_points - len(pts), stats)
        stats["interior_seeds"] = len(inner)
        # four frame points well outside: the boundary is never on the convex hull, where
        # nearly collinear boundary vertices (a straight side) would make flat slivers whose
        # orientation is noise; the frame's triangles are outside and dropped with it
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        margin = 0.5 * (hi - lo).max()
        frame = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        frame += margin * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
        allp = np.concatenate([pts, inner, frame])
        free = np.concatenate([np.zeros(len(pts), bool), np.ones(len(inner), bool), np.zeros(4, bool)])
        if frame_inside(allp, segs, np.arange(len(allp) - 4, len(allp))):
            raise WarpMeshError("the region around the boundary lies on the LEFT of its segments: expected the "
                                "domain on the LEFT of every segment (outer loops counter-clockwise)")
        p, segs, tris, free, rounds = refine(allp, segs, free, field, min_angle=float(min_angle),
                                             max_points=max_points, stats=stats)
        stats["rounds"] = rounds
        if not stats["converged"]:
            warnings.warn(f"Delaunay refinement stopped before every angle reached {min_angle} degrees "
                          f"({len(p)} points, {rounds} rounds)", RuntimeWarning, stacklevel=2)
    # compact: only vertices of the inside triangles
    used = np.unique(tris)
    remap = np.full(len(p), -1, INDEX_DTYPE)
    remap[used] = np.arange(len(used))
    p, free, tris = p[used], free[used], remap[tris]
    if optimize:
        p = smooth(p, tris, free, stats=stats)
    return p, tris, _report(field, p, tris, free, stats, t0)


def _report(field, p, tris, free, stats, t0):
    if len(tris) == 0:
        raise WarpMeshError("the domain mesh has no triangle: is the domain on the LEFT of the segments "
                            "(outer loops counter-clockwise)?")
    area2 = signed_area2(p, tris)
    if np.any(area2 <= 0):
        raise WarpMeshError(f"the domain mesh has {int((area2 <= 0).sum())} inverted or flat triangle(s)")
    ang, _ = min_angles(p, tris)
    q = triangle_quality(p, tris)
    bnd = np.flatnonzero(~free)
    info = dict(stats)
    info.update(np=len(p), ne=len(tris), min_angle=float(ang.min()), mean_q=float(q.mean()),
                worst_q=float(q.max()), area=float(0.5 * area2.sum()),
                boundary_distance_max=float(field.distance(p[bnd]).max()) if len(bnd) else 0.0,
                n_boundary=len(bnd), time=time.perf_counter() - t0)
    return info
