"""Adaptive quadtree sampling of an implicit curve [FG §16.3.1, "method by recursive subdivision"].

From the bounding box, the cells of one level are processed together (vectorised per
level; the only Python loops are over levels and bisection iterations):

1. **Culling** (rigorous): a cell whose interval enclosure of f (interval arithmetic on
   the tape, :meth:`PlanarField.intervals`) excludes 0 holds no point of the curve and
   is dropped. A component is therefore never lost above the finest level: the cells
   holding it are kept down to ``max_level``.
2. **Criteria** (Fig 16.7): a kept cell is split while one of the book's criteria fails:

   - *intersection count*: the sign changes along its four edges (each edge sampled at
     its ends and 3 interior points) are not exactly 2, an edge changes sign more than
     once, or f may vanish on an edge without sign change (a possible hidden pair of
     crossings): its interval contains 0, and still does on some piece after bisecting
     the edge 5 times (interval arithmetic overestimates, e.g. 5x on a Cassini oval's
     edges, so the whole-edge test alone sends most cells to ``max_level``);
   - a cell without sign change whose interval contains 0 (a component inside it, or a
     near tangency) is split, unless its 8 x 8 sub-boxes' intervals all exclude 0, in which
     case it is dropped (still rigorous culling);
   - *planarity*: the angle between the normals grad f / |grad f| at the two crossings
     exceeds ``max_angle``;
   - *radius of curvature*: the turning 2 asin(c |kappa| / 2) of an arc of chord c at
     the curvature kappa of either crossing exceeds ``max_angle``; this bounds the chord
     deviation where the curvature varies between the crossings (an S-bend or a bump
     whose end normals agree passes the planarity test). kappa comes from the exact
     gradient and a central-difference Hessian (step ``field.fd_step``).

   **Default max_angle.** An arc of radius R turning by theta has chord c = 2 R sin(theta/2)
   and sagitta s = R (1 - cos(theta/2)), so s / c = tan(theta/4) / 2 ~ theta / 8. Asking
   s <= eps c (``tolerance`` = eps, a chord deviation relative to the chord length) gives
   ``max_angle = 4 atan(2 eps)`` (~ 8 eps radians).
3. **Conforming polyline.** The tree is not balanced (the book does not ask for the 2:1
   rule). Each leaf side is split at the corners of the smaller kept leaves that touch
   it, so two neighbours share the same *elementary edges*; one crossing point is
   computed per elementary edge whose end signs differ (bisection to ``tolerance`` times
   its length, then a safeguarded Newton polish along the edge), and both leaves use it:
   no cracks, no T-junction gaps, every vertex of a closed curve has one segment in and one
   out.
4. **Connection in a leaf.** Going counter-clockwise around the leaf boundary, crossings
   alternate between X (f goes + to -) and Y (- to +). A segment goes from an X to a Y
   adjacent to it, which puts f > 0 on its left. With 2 crossings the pairing is unique.
   With more (only at ``max_level``, or from float32 noise), X is joined to the next Y
   when the positive corners are connected through the leaf (``plus``), to the previous
   Y otherwise; ``plus`` is the asymptotic decider (sign of the bilinear interpolant at
   its saddle) on a finest leaf with its 4 corners, and the sign of f at the centre on a
   leaf with more elementary edges. Chords between boundary-adjacent crossings never
   cross.

Known limits: a closed component lying inside a leaf that another arc crosses twice is
not seen (no criterion looks inside); a component or pair of crossings smaller than a
finest cell leaves a kept leaf without segments (counted in ``info["empty_leaves"]``);
at a singular point the polyline is split at the nearest finest corners (f = 0 counts
as outside, [FG §16.4.2]), e.g. the lemniscate gives two loops a finest cell apart.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> s = sample_quadtree(PlanarField(wm.circle(1.0), ((-1.5, -1.5), (1.5, 1.5))), tolerance=1e-2)
>>> bool(np.allclose(np.linalg.norm(s.points, axis=1), 1.0, atol=1e-5))
True
>>> len(s.segments) == len(s.points), s.info["components"]
(True, 1)
"""

from __future__ import annotations

import time

import numpy as np

from warpmesh._conventions import EDGE_T_MIN, INDEX_DTYPE, REAL_DTYPE
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.planar.polyline import components

__all__ = ["sample_quadtree", "edge_roots", "default_max_angle", "pair_around_cells"]

_TINY = 1.0e-30
#: interior samples per edge for the intersection count (the edge is cut in _PIECES pieces)
_PIECES = 4
#: bisections of an edge / a cell without sign change before f is said to possibly vanish there
_EDGE_DEPTH = 5
_CELL_DEPTH = 3
#: Newton polish steps of the edge roots
_NEWTON_STEPS = 2
#: deepest quadtree level accepted (2^16 finest cells per side)
MAX_LEVEL = 16


def default_max_angle(tolerance: float) -> float:
    """Normal turning 4 atan(2 eps) of a circular arc whose chord deviation is eps times its chord."""
    return float(4.0 * np.arctan(2.0 * tolerance))


# -- roots on segments ----------------------------------------------------------------
def edge_roots(field: PlanarField, a: np.ndarray, b: np.ndarray, fa: np.ndarray, fb: np.ndarray, *,
               rel_tol: float, newton: bool = True, counter: dict | None = None) -> np.ndarray:
    """Roots of f on segments [a_i, b_i] whose end values differ in sign (f > 0 vs f <= 0).

    Bisection until the bracket is below ``rel_tol`` times the segment length, the root
    placed by linear interpolation in the last bracket (eq. 16.12), then ``_NEWTON_STEPS``
    Newton steps along the segment kept inside the bracket. The parameter is clamped to
    [EDGE_T_MIN, 1 - EDGE_T_MIN] so that a root never lands on a segment end.

    Parameters
    ----------
    a, b : (n, 2) float64
        Segment ends.
    fa, fb : (n,) float64
        f at ``a`` and ``b`` (inside means f > 0; the signs must differ).
    rel_tol : float
        Bracket size relative to the segment length.

    Returns
    -------
    (n, 2) float64 points.
    """
    a, b = np.asarray(a, REAL_DTYPE).reshape(-1, 2), np.asarray(b, REAL_DTYPE).reshape(-1, 2)
    n = len(a)
    if n == 0:
        return np.zeros((0, 2))
    flo, fhi = np.asarray(fa, REAL_DTYPE).ravel(), np.asarray(fb, REAL_DTYPE).ravel()
    sa = flo > 0
    lo, hi = np.zeros(n), np.ones(n)
    iters = int(np.ceil(np.log2(1.0 / max(rel_tol, 1e-12))))
    d = b - a
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        fm = field.values(a + mid[:, None] * d)
        same = (fm > 0) == sa
        lo, flo = np.where(same, mid, lo), np.where(same, fm, flo)
        hi, fhi = np.where(same, hi, mid), np.where(same, fhi, fm)
    if counter is not None:
        counter["evaluations"] = counter.get("evaluations", 0) + iters * n
    # linear interpolation in the final bracket (eq. 16.12)
    den = flo - fhi
    w = np.where(np.abs(den) > _TINY, flo / np.where(np.abs(den) > _TINY, den, 1.0), 0.5)
    t = lo + np.clip(w, 0.0, 1.0) * (hi - lo)
    if newton:
        for _ in range(_NEWTON_STEPS):
            f, g = field.value_gradient(a + t[:, None] * d)
            dfdt = np.einsum("ij,ij->i", g, d)
            ok = np.abs(dfdt) > _TINY
            tn = t - np.where(ok, f / np.where(ok, dfdt, 1.0), 0.0)
            t = np.where(ok & (tn >= lo) & (tn <= hi), tn, t)
        if counter is not None:
            counter["gradients"] = counter.get("gradients", 0) + _NEWTON_STEPS * n
    t = np.clip(t, EDGE_T_MIN, 1.0 - EDGE_T_MIN)
    return a + t[:, None] * d


def _curvature(field: PlanarField, p: np.ndarray, g: np.ndarray) -> np.ndarray:
    """|kappa| = |f_y^2 f_xx - 2 f_x f_y f_xy + f_x^2 f_yy| / |grad f|^3, Hessian by central
    differences of the exact gradient (inf where the gradient vanishes)."""
    h = field.fd_step
    e = np.array([[h, 0.0], [-h, 0.0], [0.0, h], [0.0, -h]])
    _, gg = field.value_gradient((p[:, None, :] + e[None]).reshape(-1, 2))
    gg = gg.reshape(len(p), 4, 2)
    hxx = (gg[:, 0, 0] - gg[:, 1, 0]) / (2 * h)
    hyy = (gg[:, 2, 1] - gg[:, 3, 1]) / (2 * h)
    hxy = 0.25 * ((gg[:, 0, 1] - gg[:, 1, 1]) + (gg[:, 2, 0] - gg[:, 3, 0])) / h
    fx, fy = g[:, 0], g[:, 1]
    num = np.abs(fy * fy * hxx - 2 * fx * fy * hxy + fx * fx * hyy)
    n3 = np.linalg.norm(g, axis=1) ** 3
    return np.where(n3 > _TINY, num / np.maximum(n3, _TINY), np.inf)


# -- connecting crossings inside cells --------------------------------------------------
def pair_around_cells(cell: np.ndarray, perim: np.ndarray, is_x: np.ndarray, point: np.ndarray,
                      plus: np.ndarray) -> np.ndarray:
    """Directed segments joining the crossings on the boundaries of cells.

    Parameters
    ----------
    cell : (k,) int
        Cell of each crossing.
    perim : (k,) float
        Position of the crossing along its cell boundary, counter-clockwise.
    is_x : (k,) bool
        True where f goes from > 0 to <= 0 counter-clockwise through the crossing (X),
        False for - to + (Y). X and Y alternate around each cell.
    point : (k,) int
        Point index of each crossing.
    plus : (n_cells,) bool
        Cells with more than 2 crossings whose positive corners connect through the
        cell: X joins the next Y counter-clockwise; otherwise the previous Y.

    Returns
    -------
    (m, 2) int64 segments from X to Y (f > 0 on their left).
    """
    order = np.lexsort((perim, cell))
    c, x, pt = cell[order], is_x[order], point[order]
    if len(c) == 0:
        return np.zeros((0, 2), INDEX_DTYPE)
    start = np.flatnonzero(np.r_[True, c[1:] != c[:-1]])
    count = np.diff(np.r_[start, len(c)])
    first = np.repeat(start, count)
    cnt = np.repeat(count, count)
    rank = np.arange(len(c)) - first
    step = np.where(plus[c], 1, -1)
    partner = first + (rank + step) % cnt
    xs = np.flatnonzero(x)
    return np.column_stack([pt[xs], pt[partner[xs]]]).astype(INDEX_DTYPE)


# -- the per-level pass ------------------------------------------------------------------
def _check_args(field, tolerance, max_level, min_level, max_angle):
    if not isinstance(field, PlanarField):
        raise TypeError(f"expected 'field' a PlanarField, got {type(field).__name__}")
    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 0.5):
        raise ValueError(f"expected 'tolerance' a number in (0, 0.5), got {tolerance!r}")
    for name, v in (("max_level", max_level), ("min_level", min_level)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 0 <= v <= MAX_LEVEL:
            raise ValueError(f"expected '{name}' an integer in [0, {MAX_LEVEL}], got {v!r}")
    if min_level > max_level:
        raise ValueError(f"expected 'min_level' <= 'max_level' ({max_level}), got {min_level}")
    if max_angle is not None and not (isinstance(max_angle, (int, float)) and 0 < max_angle < np.pi):
        raise ValueError(f"expected 'max_angle' None or an angle in (0, pi) radians, got {max_angle!r}")


def _unique_edges(ci, cj):
    """Unique edges of cells (ci, cj): horizontal (i, j)-(i+1, j) kind 0, vertical kind 1.
    Returns (kind, i, j) of unique edges and the (n_cells, 4) edge ids, sides in ccw order
    bottom, right, top, left."""
    kind = np.concatenate([np.zeros(len(ci), np.int64), np.ones(len(ci), np.int64),
                           np.zeros(len(ci), np.int64), np.ones(len(ci), np.int64)])
    ei = np.concatenate([ci, ci + 1, ci, ci])
    ej = np.concatenate([cj, cj, cj + 1, cj])
    key = np.column_stack([kind, ei, ej])
    uk, inv = np.unique(key, axis=0, return_inverse=True)
    return uk, inv.ravel().reshape(4, -1).T


def _may_vanish(field, lo, hi, depth, cnt):
    """True where f may vanish in the box [lo, hi] ((n, 2) each; a zero extent makes it an
    edge): the box is bisected ``depth`` times along its non-zero extents, keeping the
    pieces whose interval contains 0; a box is cleared as soon as none is left."""
    owner = np.arange(len(lo))
    out = np.zeros(len(lo), bool)
    lo, hi = np.asarray(lo, REAL_DTYPE), np.asarray(hi, REAL_DTYPE)
    for r in range(depth + 1):
        if len(owner) == 0:
            break
        iv = field.intervals(lo, hi)
        cnt["intervals"] += len(iv)
        c = (iv[:, 0] <= 0) & (iv[:, 1] >= 0)
        owner, lo, hi = owner[c], lo[c], hi[c]
        if r == depth:
            out[owner] = True
            break
        for axis in (0, 1):
            cut = hi[:, axis] > lo[:, axis]
            mid = 0.5 * (lo[cut, axis] + hi[cut, axis])
            lo2, hi2 = lo[cut].copy(), hi[cut].copy()
            lo2[:, axis] = mid
            hi = hi.copy()
            hi[np.flatnonzero(cut), axis] = mid
            owner, lo, hi = np.r_[owner, owner[cut]], np.r_[lo, lo2], np.r_[hi, hi2]
    return out


def _level_pass(field, ci, cj, size, origin, rel_tol, max_angle, cnt):
    """Criteria of [FG §16.3.1] on the kept cells (ci, cj) of one level.

    Returns ``fails`` (n,) (split the cell), ``empty`` (n,) (no sign change and f cannot
    vanish inside: drop it) and ``total`` (n,) sign changes on the cell boundary."""
    uk, eid = _unique_edges(ci, cj)
    a = origin + uk[:, 1:3] * size
    d = np.where(uk[:, :1] == 0, [size[0], 0.0], [0.0, size[1]])
    t = np.linspace(0.0, 1.0, _PIECES + 1)
    samples = a[:, None, :] + t[None, :, None] * d[:, None, :]
    f = field.values(samples.reshape(-1, 2)).reshape(len(uk), _PIECES + 1)
    cnt["evaluations"] += f.size
    s = f > 0
    changes = np.count_nonzero(s[:, 1:] != s[:, :-1], axis=1)
    total = changes[eid].sum(axis=1)
    # a cell without sign change: drop it when a finer interval enclosure clears it
    empty = np.zeros(len(ci), bool)
    none = np.flatnonzero(total == 0)
    if len(none):
        lo = origin + np.column_stack([ci[none], cj[none]]) * size
        empty[none] = ~_may_vanish(field, lo, lo + size, _CELL_DEPTH, cnt)
    # an edge without sign change where f may vanish may hide a pair of crossings
    used = np.zeros(len(uk), bool)
    used[eid[~empty]] = True
    quiet = np.flatnonzero((changes == 0) & used)
    hidden = np.zeros(len(uk), bool)
    if len(quiet):
        hidden[quiet] = _may_vanish(field, a[quiet], a[quiet] + d[quiet], _EDGE_DEPTH, cnt)
    fails = (total != 2) | (changes[eid] > 1).any(axis=1) | hidden[eid].any(axis=1)
    # two crossings: roots, normals and curvatures
    two = np.flatnonzero(~fails)
    if len(two):
        e2 = eid[two]
        cross = e2[changes[e2] == 1].reshape(-1, 2)  # the two crossing edges of each cell, in ccw order
        ue, inv = np.unique(cross.ravel(), return_inverse=True)
        p = edge_roots(field, a[ue], a[ue] + d[ue], f[ue, 0], f[ue, -1], rel_tol=rel_tol, newton=False,
                       counter=cnt)
        _, g = field.value_gradient(p)
        kappa = _curvature(field, p, g)
        cnt["gradients"] += 5 * len(p)
        gn = np.linalg.norm(g, axis=1)
        nrm = g / np.maximum(gn, _TINY)[:, None]
        i0, i1 = inv.ravel()[0::2], inv.ravel()[1::2]
        cosang = np.einsum("ij,ij->i", nrm[i0], nrm[i1])
        angle = np.arccos(np.clip(cosang, -1.0, 1.0))
        chord = np.linalg.norm(p[i0] - p[i1], axis=1)
        kmax = np.maximum(kappa[i0], kappa[i1])
        turn = 2.0 * np.arcsin(np.clip(0.5 * chord * np.where(np.isfinite(kmax), kmax, 1e300), 0.0, 1.0))
        singular = (gn[i0] <= _TINY) | (gn[i1] <= _TINY)
        fails[two] = singular | (angle > max_angle) | (turn > max_angle)
    return fails & ~empty, empty, total


def sample_quadtree(field: PlanarField, *, tolerance: float = 1e-3, max_level: int = 10, min_level: int = 2,
                    max_angle: float | None = None, newton: bool = True) -> CurveSample:
    """Sample f = 0 by adaptive quadtree subdivision with interval culling [FG §16.3.1].

    Parameters
    ----------
    field : PlanarField
        The curve's function over its box (the root cell; cells keep the box's aspect).
    tolerance : float
        Chord deviation relative to the chord length (eps, so delta <= eps * h), also the
        root accuracy relative to the edge length.
    max_level : int
        Deepest level (finest cells are box / 2**max_level), at most 16.
    min_level : int
        Levels subdivided without looking at the criteria.
    max_angle : float, optional
        Planarity and curvature threshold in radians; default ``4 atan(2 tolerance)``.
    newton : bool
        Polish the bisected crossings of the output by Newton steps along their edges.

    Returns
    -------
    CurveSample
        Points on the curve, directed segments (f > 0 on the left), ``cells`` the kept
        leaves (x0, y0, x1, y1), ``info`` with counts: "leaves", "leaves_per_level",
        "visited", "culled", "unresolved" (finest leaves that still fail a criterion),
        "empty_leaves" (finest kept leaves without a sign change), "ambiguous" (leaves with
        more than 2 crossings), "components", "max_angle", "evaluations", "gradients",
        "intervals", "seconds".

    Raises
    ------
    TypeError
        ``field`` is not a PlanarField.
    ValueError
        ``tolerance``, ``max_level``, ``min_level`` or ``max_angle`` out of range.

    Examples
    --------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> s = sample_quadtree(PlanarField(wm.ellipse((1.0, 0.3)), ((-1.2, -0.5), (1.2, 0.5))), tolerance=1e-2)
    >>> s.info["components"], s.info["unresolved"]
    (1, 0)
    """
    _check_args(field, tolerance, max_level, min_level, max_angle)
    t0 = time.perf_counter()
    angle = default_max_angle(tolerance) if max_angle is None else float(max_angle)
    origin, ext = field.bounds[0], field.bounds[1] - field.bounds[0]
    cnt = {"evaluations": 0, "gradients": 0, "intervals": 0}
    ci, cj = np.zeros(1, np.int64), np.zeros(1, np.int64)
    leaves = []  # (level, i, j) arrays per level
    visited = culled = unresolved = empty = 0
    per_level = []
    for level in range(max_level + 1):
        size = ext / 2.0**level
        visited += len(ci)
        lo = origin + np.column_stack([ci, cj]) * size
        iv = field.intervals(lo, lo + size)
        cnt["intervals"] += len(iv)
        keep = (iv[:, 0] <= 0) & (iv[:, 1] >= 0)
        culled += int(np.count_nonzero(~keep))
        ci, cj = ci[keep], cj[keep]
        if level < min_level:
            split = np.ones(len(ci), bool)
        else:
            fails, drop, total = _level_pass(field, ci, cj, size, origin, tolerance, angle, cnt)
            culled += int(np.count_nonzero(drop))
            split = fails if level < max_level else np.zeros(len(ci), bool)
            if level == max_level:
                unresolved = int(np.count_nonzero(fails & (total > 0)))
                empty = int(np.count_nonzero(fails & (total == 0)))
            keep = ~drop
            ci, cj, split = ci[keep], cj[keep], split[keep]
        leaf = ~split
        leaves.append((level, ci[leaf], cj[leaf]))
        per_level.append(int(np.count_nonzero(leaf)))
        ci, cj = ci[split], cj[split]
        if len(ci) == 0:
            break
        ci = (2 * ci[:, None] + np.array([0, 1, 0, 1])).ravel()
        cj = (2 * cj[:, None] + np.array([0, 0, 1, 1])).ravel()
    points, segments, boxes, ambiguous = _connect(field, leaves, max_level, tolerance, newton, cnt)
    n_comp, _ = components(segments, len(points))
    info = {"leaves": len(boxes), "leaves_per_level": per_level, "visited": visited, "culled": culled,
            "unresolved": unresolved, "empty_leaves": empty, "ambiguous": ambiguous, "components": n_comp,
            "max_angle": angle, **cnt, "seconds": time.perf_counter() - t0}
    return CurveSample(points, segments, info, boxes)


# -- the conforming polyline -----------------------------------------------------------
def _connect(field, leaves, max_level, tolerance, newton, cnt):
    """Crossings on the elementary edges shared by neighbouring leaves, joined in each leaf."""
    lv = np.concatenate([np.full(len(i), l, np.int64) for l, i, _ in leaves])
    li = np.concatenate([i for _, i, _ in leaves]).astype(np.int64)
    lj = np.concatenate([j for _, _, j in leaves]).astype(np.int64)
    origin, ext = field.bounds[0], field.bounds[1] - field.bounds[0]
    unit = ext / 2.0**max_level
    m = np.left_shift(1, max_level - lv)  # leaf side in finest units
    x0, y0 = li * m, lj * m
    boxes = np.column_stack([origin + np.column_stack([x0, y0]) * unit,
                             origin + np.column_stack([x0 + m, y0 + m]) * unit])
    n_leaf = len(lv)
    if n_leaf == 0:
        return np.zeros((0, 2)), np.zeros((0, 2), INDEX_DTYPE), boxes, 0
    # corners of all leaves, on the finest integer lattice
    w = np.int64(2**max_level + 1)
    cx = np.concatenate([x0, x0 + m, x0 + m, x0])
    cy = np.concatenate([y0, y0, y0 + m, y0 + m])
    corners = np.unique(np.column_stack([cx, cy]), axis=0)
    fc = field.values(origin + corners * unit)
    cnt["evaluations"] += len(fc)
    key_h = corners[:, 1] * w + corners[:, 0]  # sorted along horizontal lines
    oh = np.argsort(key_h)
    key_v = corners[:, 0] * w + corners[:, 1]  # along vertical lines
    ov = np.argsort(key_v)
    # pieces of each side: (leaf, ccw position of the piece start, corner from, corner to)
    parts = []
    sides = (  # (line key start, end, sorted keys, order, reversed?, ccw offset in units of m)
        (y0 * w + x0, y0 * w + x0 + m, key_h[oh], oh, False, 0),  # bottom, +x
        ((x0 + m) * w + y0, (x0 + m) * w + y0 + m, key_v[ov], ov, False, 1),  # right, +y
        ((y0 + m) * w + x0, (y0 + m) * w + x0 + m, key_h[oh], oh, True, 2),  # top, -x
        (x0 * w + y0, x0 * w + y0 + m, key_v[ov], ov, True, 3),  # left, -y
    )
    for k0, k1, skeys, order, rev, off in sides:
        a = np.searchsorted(skeys, k0)
        b = np.searchsorted(skeys, k1)  # index of the side's end corner
        npieces = b - a
        leaf = np.repeat(np.arange(n_leaf), npieces)
        first = np.repeat(a, npieces)
        r = np.arange(len(leaf)) - np.repeat(np.cumsum(npieces) - npieces, npieces)
        c_lo, c_hi = order[first + r], order[first + r + 1]
        pos_lo = skeys[first + r] - np.repeat(k0, npieces)
        pos_hi = skeys[first + r + 1] - np.repeat(k0, npieces)
        if rev:  # traversed from the high end to the low end
            c_from, c_to, pos = c_hi, c_lo, m[leaf] - pos_hi
        else:
            c_from, c_to, pos = c_lo, c_hi, pos_lo
        parts.append(np.column_stack([leaf, off * m[leaf] + pos, c_from, c_to]))
    parts = np.concatenate(parts)
    s_from, s_to = fc[parts[:, 2]] > 0, fc[parts[:, 3]] > 0
    cross = parts[s_from != s_to]
    ekey = np.sort(cross[:, 2:4], axis=1)
    uedge, inv = np.unique(ekey, axis=0, return_inverse=True)
    ca, cb = corners[uedge[:, 0]], corners[uedge[:, 1]]
    # bisection to tolerance times the elementary edge (the smaller adjacent leaf's side)
    points = edge_roots(field, origin + ca * unit, origin + cb * unit, fc[uedge[:, 0]], fc[uedge[:, 1]],
                        rel_tol=tolerance, newton=newton, counter=cnt)
    is_x = fc[cross[:, 2]] > 0
    counts = np.bincount(cross[:, 0], minlength=n_leaf)
    plus = np.zeros(n_leaf, bool)
    amb = np.flatnonzero(counts > 2)
    if len(amb):
        fine = amb[m[amb] == 1]
        if len(fine):  # asymptotic decider on the bilinear interpolant of the 4 corners
            lat = np.column_stack([x0[fine], y0[fine]])
            f4 = field.values(origin + np.concatenate([lat, lat + [1, 0], lat + [1, 1], lat + [0, 1]]) * unit)
            cnt["evaluations"] += len(f4)
            f00, f10, f11, f01 = f4.reshape(4, -1)
            den = f00 + f11 - f10 - f01
            saddle = (f00 * f11 - f10 * f01) / np.where(np.abs(den) > _TINY, den, _TINY)
            plus[fine] = saddle > 0
        big = amb[m[amb] > 1]
        if len(big):  # a larger leaf: the sign of f at its centre
            centre = 0.5 * (boxes[big, :2] + boxes[big, 2:])
            plus[big] = field.values(centre) > 0
            cnt["evaluations"] += len(big)
    segs = pair_around_cells(cross[:, 0], cross[:, 1].astype(REAL_DTYPE), is_x, inv.ravel(), plus)
    return points, segs, boxes, int(len(amb))
