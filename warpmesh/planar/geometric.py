"""Geometric mesh of an implicit curve from any sampler's polyline [FG §16.2.2, §16.3.2].

A sampler (grid, Freudenthal, continuation, quadtree, rays) returns a raw polyline,
coarse or fine. :func:`geometric_mesh` remeshes it so that each edge of length h stays
within delta <= eps h of the curve [FG §16.2.2], following the general scheme of
[FG §16.2.2]:

1. mandatory vertices: the singular points (each pass of a chain near one is replaced
   by the exact point, shared by all passes: the lemniscate becomes two loops through
   the origin), the corners (G1 discontinuities of CSG shapes: a chain edge whose
   normals keep turning however short it gets; the vertex is the crossing of the two
   one-sided tangents), the chain ends on the box boundary, and the extrema of the
   curvature along each chain (the ellipse's four vertices);
2. a dense arc-length parametrisation of every chain: its edges are split (midpoints
   projected by Newton, capped steps) until each is shorter than a third of the local
   size and turns less than ``DENSE_TURN`` radians;
3. between consecutive mandatory vertices, n = ceil(L) edges where L is the metric
   length, the integral of ds / h(s), h = min(chord_size(rho), user size) (the metric
   intersection of Chapter 10); the vertices are equidistributed in metric length
   (a unit mesh, Definition 16.4) and projected onto the curve;
4. verification [FG §16.2.2: "sampling the segment"]: the chord deviation delta of
   every edge is the largest distance from 5 points of the edge to the curve, each
   measured to a curve point found from the edge's own arc (no jump to a nearby branch);
   edges with delta > eps h and edges crossing another edge are split at their arc
   midpoint, until none is left. The number of components is checked against the raw
   polyline's (after the merge at singular points); chains keep their direction, so the
   domain stays on the left and closed chains stay closed.

The float32 tape bounds the accuracy: the curve is located to ~2 ulps of the coordinates
plus 2 ulps of f's magnitude over |grad f|, so deviations below that floor (very short
edges on sharp curvature, or where f cancels large terms) are accepted; ``info``
reports the floor.

Everything is vectorised over the points of all chains at once; the loops run over
refinement rounds (and over chains only to find curvature extrema).
"""

from __future__ import annotations

import warnings

import numpy as np

from warpmesh.frep import geometry
from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.planar.metric import SizeOption, check_tolerance
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.errors import TopologyError
from warpmesh.cells.intersections import find_segment_intersections
from warpmesh.planar.polyline import chains, components, weld

__all__ = ["geometric_mesh"]

#: a dense edge is at most this fraction of the local size ...
DENSE_FRACTION = 1.0 / 3.0
#: ... and turns at most this angle (radians) where the curvature is smooth
DENSE_TURN = 0.05
#: a dense edge whose end normals turn more than this is split again, down to hmin ...
TURN_SPLIT = 0.1
#: ... and after that, an edge still turning more than this holds a corner
CORNER_TURN = 0.2
#: a curvature extremum is a vertex when its prominence exceeds this fraction of max |kappa|
PROMINENCE = 0.05
#: parameters of the chord-deviation check: points per edge, rounds
EDGE_SAMPLES = np.linspace(0.0, 1.0, 7)[1:-1]
MAX_ROUNDS = 40
#: splits of one dense edge in one round
MAX_PIECES = 32

# point kinds of the dense parametrisation (mandatory vertices are >= _END)
_FREE, _END, _SINGULAR, _CORNER, _EXTREMUM = 0, 1, 2, 3, 4
_TINY = 1.0e-30
_EPS32 = float(np.finfo(np.float32).eps)


def geometric_mesh(field, sample: CurveSample, *, tolerance: float = 1e-3, size=None, hmin=None, hmax=None,
                   singular=None) -> CurveSample:
    """Remesh a raw polyline of f = 0 into a geometric mesh: delta <= eps h on every edge.

    Parameters
    ----------
    field : PlanarField
        The curve's function over its box.
    sample : CurveSample
        A raw polyline from any sampler: points on the curve and directed segments with
        the domain f > 0 on their left; coarse or fine.
    tolerance : float
        Relative chord deviation eps in (0, 0.5): every edge of length h lies within
        eps h of the curve, so h <= 2 rho sin(2 atan(2 eps)) ~ 8 eps rho.
    size : None, float or callable, optional
        A size field h(x) intersected with the geometric one (a callable maps (n, 2)
        points to (n,) positive sizes); the mesh is a unit mesh of min(h_geo, h(x)).
    hmin, hmax : float, optional
        Clip of the sizes; defaults box diagonal * 1e-5 and box diagonal / 10.
    singular : (k, 2) array_like, optional
        Singular points of the curve; default ``geometry.singular_points`` over the box.

    Returns
    -------
    CurveSample
        ``points`` (n, 2), ``segments`` (m, 2) oriented as the input (domain on the left),
        ``info`` with ``vertices``, ``edges``, ``components``, ``max_deviation`` (largest
        delta measured), ``max_relative_deviation`` (largest delta / h net of
        ``deviation_floor``, the float32 noise of the tape: 2 ulps of the coordinates plus
        2 ulps of max |f| over the box / |grad f|),
        ``rounds`` (verification rounds), ``splits``,
        ``singular_points`` (k, 2), ``curvature_extrema`` (e, 2), ``corners`` (c, 2),
        ``dense_points`` and ``raw_vertices``.

    Raises
    ------
    ValueError
        A bad ``tolerance``, ``size`` (also a callable returning a wrong shape or
        non-positive sizes), ``hmin``, ``hmax``, ``singular``, or an empty ``sample``.
    TopologyError
        The raw polyline, projected onto the curve, crosses itself (its topology is not the
        curve's: sample finer), edges still cross after the splits, or the result does not
        have the components of the raw polyline.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> t = np.linspace(0, 2 * np.pi, 24, endpoint=False)          # a coarse raw polygon
    >>> ring = np.column_stack([np.arange(24), np.roll(np.arange(24), -1)])
    >>> raw = CurveSample(np.column_stack([np.cos(t), np.sin(t)]), ring)
    >>> out = geometric_mesh(PlanarField(wm.circle(1.0), ((-2, -2), (2, 2))), raw, tolerance=1e-3)
    >>> out.info["vertices"], out.info["max_relative_deviation"] <= 1e-3   # ceil(pi / (4 eps))
    (786, True)
    """
    eps = check_tolerance(tolerance)
    opt = SizeOption(size, field.bounds, hmin, hmax)
    pts, segs = _check_sample(sample, field)
    sing = _singular(field, singular)
    pts, segs, sing = _merge_singular(pts, segs, sing)
    n_raw = components(segs, len(pts))[0]
    d = _Dense.from_chains(field, pts, chains(segs, len(pts)), len(pts) - len(sing))
    d.refine_turns(opt.hmin)
    corners = d.insert_corners()
    d.curvatures()
    d.refine_lengths(eps, opt)
    _check_dense(d)
    extrema = d.mark_extrema()
    h = opt.sizes(d.p, d.kappa_filled(), eps, d.user)
    out = _place(d, h)
    out, stats = _verify(d, out, eps, opt.hmin)
    points, segments = _assemble(out)
    n_out = components(segments, len(points))[0]
    if n_out != n_raw:
        raise TopologyError(f"expected {n_raw} components as the raw polyline, got {n_out}")
    info = {"vertices": len(points), "edges": len(segments), "components": n_out, "tolerance": eps, **stats,
            "singular_points": sing, "curvature_extrema": extrema, "corners": corners,
            "dense_points": len(d.p), "raw_vertices": len(np.unique(sample.segments)), "hmin": opt.hmin,
            "hmax": opt.hmax}
    return CurveSample(points, segments, info, sample.cells)


# -- input -------------------------------------------------------------------------------------
def _check_sample(sample, field):
    if not isinstance(sample, CurveSample):
        raise TypeError(f"expected a CurveSample for 'sample', got {type(sample).__name__}")
    pts = np.asarray(sample.points, REAL_DTYPE).reshape(-1, 2)
    segs = np.asarray(sample.segments, INDEX_DTYPE).reshape(-1, 2)
    if len(segs) == 0:
        raise ValueError("expected a 'sample' with segments, got none (the sampler found no curve)")
    if segs.min() < 0 or segs.max() >= len(pts):
        raise ValueError(f"expected 'sample' segments indexing its {len(pts)} points, got indices "
                         f"in [{segs.min()}, {segs.max()}]")
    return weld(pts, segs, 1e-9 * field.size)


def _singular(field, singular) -> np.ndarray:
    if singular is None:
        return geometry.singular_points(field.shape, field.bounds, device=field.device)["points"]
    s = np.asarray(singular, REAL_DTYPE)
    if s.size == 0:
        return np.zeros((0, 2))
    if s.ndim != 2 or s.shape[1] != 2 or not np.all(np.isfinite(s)):
        raise ValueError(f"expected 'singular' a (k, 2) array of finite points, got shape {s.shape}")
    return s


def _point_segment_distance(q, a, b):
    """Distances (k, m) from points q (k, 2) to segments [a, b] (m, 2 each)."""
    d = b - a
    w = q[:, None, :] - a[None]
    t = np.clip(np.einsum("kmi,mi->km", w, d) / np.maximum(np.einsum("mi,mi->m", d, d), _TINY), 0.0, 1.0)
    return np.linalg.norm(w - t[..., None] * d[None], axis=2)


def _merge_singular(pts, segs, sing):
    """Replace every pass of the polyline near a singular point by that point (shared).

    A singular point counts when the polyline passes within two local segment lengths;
    the raw vertices within 2 d + 2.5 l of it (d its distance to the polyline, l the
    nearest segment's length) become the point. Returns (points, segments, points used);
    the used singular points are appended to the points."""
    if len(sing) == 0:
        return pts, segs, np.zeros((0, 2))
    a, b = pts[segs[:, 0]], pts[segs[:, 1]]
    dist = _point_segment_distance(sing, a, b)
    near = dist.argmin(axis=1)
    dnear, lloc = dist[np.arange(len(sing)), near], np.linalg.norm(b - a, axis=1)[near]
    keep = dnear <= 2.0 * lloc
    sing, radius = sing[keep], (2.0 * dnear + 2.5 * lloc)[keep]
    if len(sing) > 1:  # a pass belongs to one point
        gap = np.linalg.norm(sing[:, None] - sing[None], axis=2) + np.diag(np.full(len(sing), np.inf))
        radius = np.minimum(radius, 0.45 * gap.min(axis=1))
    rel = np.linalg.norm(pts[:, None, :] - sing[None], axis=2) / radius[None]
    owner = rel.argmin(axis=1) if len(sing) else np.zeros(len(pts), INDEX_DTYPE)
    inside = rel[np.arange(len(pts)), owner] < 1.0 if len(sing) else np.zeros(len(pts), bool)
    remap = np.where(inside, len(pts) + owner, np.arange(len(pts)))
    used = np.unique(owner[inside])
    new = remap[segs]
    new = new[new[:, 0] != new[:, 1]]
    # renumber the used singular points after the raw points
    ids = np.full(len(sing), -1, INDEX_DTYPE)
    ids[used] = len(pts) + np.arange(len(used))
    new = np.where(new >= len(pts), ids[np.clip(new - len(pts), 0, None)], new)
    return np.concatenate([pts, sing[used]]), new, sing[used]


# -- the dense parametrisation -------------------------------------------------------------------
class _Dense:
    """All chains as one flat array of curve points, chain after chain.

    A closed chain repeats its first point at its end (same key). ``key`` identifies raw
    chain ends (shared between chains: a singular point) and is -1 elsewhere; ``u`` is
    the arc length, increasing across the whole array (a gap of 1 between chains)."""

    def __init__(self, field, p, cid, key, kind):
        self.field, self.p, self.cid, self.key, self.kind = field, p, cid, key, kind
        self.nrm = self._normals(p)
        self.kappa = np.full(len(p), np.nan)
        self.masked = np.zeros(len(p), bool)
        self.opt = None  # the size option, once curvatures and user sizes are tracked
        self.user = None

    @classmethod
    def from_chains(cls, field, pts, chain_list, n_regular):
        verts, cid = [], []
        for c, (v, closed) in enumerate(chain_list):
            v = np.append(v, v[0]) if closed else v
            verts.append(v)
            cid.append(np.full(len(v), c, INDEX_DTYPE))
        v, cid = np.concatenate(verts), np.concatenate(cid)
        first = np.r_[True, cid[1:] != cid[:-1]]
        last = np.r_[cid[1:] != cid[:-1], True]
        end = first | last
        kind = np.where(end, _END, _FREE).astype(np.int8)
        kind[v >= n_regular] = _SINGULAR
        p = pts[v].copy()
        # raw points onto the curve (the same ends of several chains alike), ends on the box
        # sides along their side; singular points stay
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        seg = np.where(cid[1:] == cid[:-1], seg, np.inf)
        local = np.minimum(np.r_[np.inf, seg], np.r_[seg, np.inf])
        on_side = _on_side(field, p) & (kind == _END)
        move = np.flatnonzero((kind != _SINGULAR) & ~on_side)
        if len(move):
            p[move] = field.project(p[move], max_step=0.5 * local[move] + _TINY)
        side = np.flatnonzero(on_side)
        p[side] = _project_on_sides(field, p[side])
        return cls(field, p, cid, np.where(end, v, -1), kind)

    # -- per-point quantities
    def _normals(self, p):
        _, g = self.field.value_gradient(p)
        gn = np.linalg.norm(g, axis=1)
        return np.where(gn[:, None] > _TINY, g / np.maximum(gn, _TINY)[:, None], 0.0)

    def _kappa(self, p):
        """|curvature| at p, NaN within the Hessian stencil of a corner or singular point."""
        from scipy.spatial import cKDTree

        scale = np.maximum(min(1.0, 0.5 * self.field.size), np.abs(p).max(axis=1))
        step = geometry.HESSIAN_STEP * scale
        k = np.abs(geometry.curvature(self.field.shape, p, step=step, device=self.field.device))
        special = self.p[(self.kind == _CORNER) | (self.kind == _SINGULAR)]
        if len(special):
            dist, _ = cKDTree(special).query(p)
            k[dist <= 2.0 * step] = np.nan
        return k

    def curvatures(self):
        self.kappa = self._kappa(self.p)
        self.masked = np.isnan(self.kappa)

    def kappa_filled(self):
        """|kappa| with masked values taken from the nearest unmasked point of the chain (0 if none)."""
        k, n = self.kappa, len(self.kappa)
        idx = np.arange(n)
        ok = ~np.isnan(k)
        fwd = np.maximum.accumulate(np.where(ok, idx, -1))
        bwd = np.minimum.accumulate(np.where(ok, idx, n)[::-1])[::-1]
        start = np.r_[0, np.flatnonzero(self.cid[1:] != self.cid[:-1]) + 1]
        stop = np.r_[start[1:], n] - 1
        c = np.searchsorted(start, idx, side="right") - 1
        fok, bok = fwd >= start[c], bwd <= stop[c]
        pick = np.where(fok & bok, np.where(idx - fwd <= bwd - idx, fwd, bwd), np.where(fok, fwd, bwd))
        has = fok | bok
        return np.where(has, k[np.clip(pick, 0, n - 1)], 0.0)

    # -- edges
    def edges(self):
        return np.flatnonzero(self.cid[:-1] == self.cid[1:])

    def arc(self):
        """Arc length u (n,), increasing through all chains (a gap of 1 between chains)."""
        step = np.linalg.norm(np.diff(self.p, axis=0), axis=1)
        step = np.where(self.cid[1:] == self.cid[:-1], step, 1.0)
        return np.r_[0.0, np.cumsum(step)]

    def turns(self, e):
        """Angle between the unit normals at the ends of edges e (0 where one is undefined)."""
        na, nb = self.nrm[e], self.nrm[e + 1]
        ok = (np.abs(na).sum(axis=1) > 0) & (np.abs(nb).sum(axis=1) > 0)
        ok &= (self.kind[e] != _CORNER) & (self.kind[e + 1] != _CORNER)
        return np.where(ok, np.arccos(np.clip(np.einsum("ij,ij->i", na, nb), -1.0, 1.0)), 0.0)

    def split(self, e, pieces):
        """Split edges e into ``pieces`` equal parts; new points projected onto the curve."""
        pieces = np.minimum(pieces, MAX_PIECES)
        e, pieces = e[pieces > 1], pieces[pieces > 1]
        if len(e) == 0:
            return 0
        rep = np.repeat(np.arange(len(e)), pieces - 1)
        j = np.arange(len(rep)) - np.repeat(np.cumsum(pieces - 1) - (pieces - 1), pieces - 1) + 1
        t = j / pieces[rep]
        a, b = self.p[e[rep]], self.p[e[rep] + 1]
        q = a + t[:, None] * (b - a)
        q = self.field.project(q, max_step=np.linalg.norm(b - a, axis=1) + _TINY)
        self._insert(e[rep] + t, q)
        return len(q)

    def _insert(self, where, q, kind=_FREE):
        """Insert points q at fractional positions ``where`` (edge index + fraction)."""
        n = len(self.p)
        order = np.argsort(np.r_[np.arange(n, dtype=REAL_DTYPE), where], kind="stable")
        owner = np.floor(where).astype(INDEX_DTYPE)
        self.p = np.concatenate([self.p, q])[order]
        self.cid = np.concatenate([self.cid, self.cid[owner]])[order]
        self.key = np.concatenate([self.key, np.full(len(q), -1, INDEX_DTYPE)])[order]
        self.kind = np.concatenate([self.kind, np.full(len(q), kind, np.int8)])[order]
        self.nrm = np.concatenate([self.nrm, self._normals(q) if kind != _CORNER else np.zeros((len(q), 2))])[order]
        if self.opt is None:
            self.kappa = np.concatenate([self.kappa, np.full(len(q), np.nan)])[order]
            self.masked = np.concatenate([self.masked, np.zeros(len(q), bool)])[order]
        else:
            self.kappa = np.concatenate([self.kappa, self._kappa(q)])[order]
            self.masked = np.isnan(self.kappa)
            self.user = np.concatenate([self.user, self.opt.user(q)])[order]

    # -- refinement
    def refine_turns(self, lmin):
        """Split edges turning more than TURN_SPLIT until they are shorter than ``lmin``."""
        for _ in range(MAX_ROUNDS):
            e = self.edges()
            length = np.linalg.norm(self.p[e + 1] - self.p[e], axis=1)
            bad = (self.turns(e) > TURN_SPLIT) & (length > lmin)
            if not self.split(e[bad], np.full(int(bad.sum()), 2)):
                return

    def insert_corners(self):
        """Insert a corner where an edge still turns more than CORNER_TURN: the crossing of
        the one-sided tangents at its ends (its midpoint if that crossing is off the edge)."""
        e = self.edges()
        e = e[self.turns(e) > CORNER_TURN]
        if len(e) == 0:
            return np.zeros((0, 2))
        a, b, na, nb = self.p[e], self.p[e + 1], self.nrm[e], self.nrm[e + 1]
        mat = np.stack([na, nb], axis=1)
        rhs = np.stack([np.einsum("ij,ij->i", na, a), np.einsum("ij,ij->i", nb, b)], axis=1)
        c = np.linalg.solve(mat, rhs[..., None])[..., 0]
        mid, length = 0.5 * (a + b), np.linalg.norm(b - a, axis=1)
        off = np.linalg.norm(c - mid, axis=1) > length
        c[off] = mid[off]
        # a corner on an end of its edge (a raw point on the corner) marks that end
        at_a = np.linalg.norm(c - a, axis=1) < 0.05 * length
        at_b = ~at_a & (np.linalg.norm(c - b, axis=1) < 0.05 * length)
        mark = np.r_[e[at_a], e[at_b] + 1]
        keys = self.key[mark][self.key[mark] >= 0]
        mark = np.r_[mark, np.flatnonzero(np.isin(self.key, keys))]  # with a closed chain's copy
        self.kind[mark], self.nrm[mark] = _CORNER, 0.0
        new = ~(at_a | at_b)
        self._insert(e[new] + 0.5, c[new], _CORNER)
        return np.r_[c[at_a], c[at_b], c[new]]

    def refine_lengths(self, eps, opt):
        """Split edges longer than DENSE_FRACTION h or turning more than DENSE_TURN (smooth parts)."""
        self.opt, self.user = opt, opt.user(self.p)
        for _ in range(MAX_ROUNDS):
            kap = self.kappa_filled()
            h = opt.sizes(self.p, kap, eps, self.user)
            with np.errstate(divide="ignore"):
                target = np.minimum(DENSE_FRACTION * h, DENSE_TURN / np.maximum(kap, _TINY))
            e = self.edges()
            length = np.linalg.norm(self.p[e + 1] - self.p[e], axis=1)
            pieces = np.ceil(length / np.minimum(target[e], target[e + 1])).astype(INDEX_DTYPE)
            if not self.split(e, pieces):
                return

    def mark_extrema(self):
        """Mark the prominent extrema of |kappa| along each chain as mandatory and return them.

        A closed chain with extrema is rolled to start at one, so that its arbitrary
        first raw point is no longer a vertex."""
        from scipy.signal import find_peaks

        k, u = self.kappa_filled(), self.arc()
        start = np.r_[0, np.flatnonzero(self.cid[1:] != self.cid[:-1]) + 1, len(k)]
        perm = np.arange(len(k))
        found, pre, moves, twins = [], [], [], []
        for s, t in zip(start[:-1], start[1:]):  # one pass per chain
            closed = self.kind[s] != _SINGULAR and self.key[s] == self.key[t - 1]
            free_start = closed and self.kind[s] == _END  # an arbitrary raw point
            x = k[s:t - 1] if closed else k[s:t]
            if len(x) < 3 or x.max() <= 0:
                continue
            peaks = []
            for y in (x, -x):
                shift = int(np.argmin(y)) if closed else 0
                yy = np.roll(y, -shift)
                at, _ = find_peaks(np.r_[yy, yy[0]] if closed else yy, prominence=PROMINENCE * x.max())
                peaks.append((at + shift) % len(x))
            blocked = (self.kind[s:s + len(x)] != _FREE) | self.masked[s:s + len(x)]
            blocked[0] &= not free_start
            at = _separate(np.concatenate(peaks), blocked, closed)
            pre.append(s + at)
            moves.append(_extremum_arc(x, u[s:t] - u[s], at, closed) + u[s])
            twins.append(np.where(closed & (at == 0), t - 1, -1))
            if free_start and len(at) and at[0] > 0:
                r = int(at.min())
                perm[s:t - 1] = s + np.roll(np.arange(len(x)), -r)
                perm[t - 1] = s + r
                at = (at - r) % len(x)
            found.append(s + at)
        idx = np.concatenate(found) if found else np.zeros(0, INDEX_DTYPE)
        if found:
            self._move(np.concatenate(pre), np.concatenate(moves), u, np.concatenate(twins))
        rolled = np.flatnonzero(perm != np.arange(len(k)))
        old_start = np.intersect1d(rolled, start[:-1])
        keys = self.key[old_start]
        for name in ("p", "nrm", "kappa", "masked", "user", "kind", "key"):
            setattr(self, name, getattr(self, name)[perm])
        if len(old_start):  # the old first point becomes free, the new first one keeps its key
            moved = np.flatnonzero(np.isin(self.key, keys) & (self.kind == _END))
            self.key[moved], self.kind[moved] = -1, _FREE
            ends = np.r_[old_start, start[1:][np.searchsorted(start[:-1], old_start)] - 1]
            self.key[ends], self.kind[ends] = np.r_[keys, keys], _END
        self.kind[idx] = np.maximum(self.kind[idx], _EXTREMUM)
        return self.p[np.sort(idx)]

    def _move(self, idx, target, u, twin):
        """Move dense points idx to arc lengths ``target`` (within their neighbours' span);
        ``twin`` (same length, -1 for none) is the copy that closes a chain at that point."""
        if len(idx) == 0:
            return
        q = _at_arc(self, u, target)
        has = twin >= 0
        moved = np.r_[idx, twin[has]]
        self.p[moved] = np.concatenate([q, q[has]])
        self.nrm[moved] = self._normals(self.p[moved])
        self.kappa[moved] = self._kappa(self.p[moved])
        self.masked = np.isnan(self.kappa)
        self.user[moved] = self.opt.user(self.p[moved])


def _separate(at, blocked, closed, half: int = 4):
    """Extremum samples kept as vertices: at least ``half`` + 1 samples from any ``blocked``
    one (mandatory or masked) and from each other; ``closed`` chains wrap around."""
    at = np.unique(at)
    n = len(blocked)
    fixed = blocked
    near = np.zeros(len(at), bool)
    for o in range(-half, half + 1):  # a fixed window of offsets
        j = (at + o) % n if closed else np.clip(at + o, 0, n - 1)
        near |= fixed[j]
    at = at[~near]
    keep = np.r_[True, np.diff(at) > half][:len(at)]
    if closed and len(at) > 1 and at[-1] - at[0] >= n - half:
        keep[-1] = False
    return at[keep]


def _extremum_arc(x, u, at, closed, half: int = 4):
    """Arc lengths of the extrema of x near samples ``at``: vertex of the least-squares
    parabola through 2 half + 1 samples, kept between the neighbouring samples.

    ``x`` (L,) values, ``u`` (L + closed,) arc lengths from the chain start (the last one
    closing a closed chain)."""
    n = len(x)
    if len(at) == 0:
        return np.zeros(0)
    off = np.arange(-half, half + 1)
    if closed:
        period = u[n]
        j = at[:, None] + off[None]
        du = u[j % n] - u[at][:, None] + period * np.floor_divide(j, n)
        y = x[j % n]
    else:
        j = np.clip(at[:, None] + off[None], 0, n - 1)
        du, y = u[j] - u[at][:, None], x[j]
    a = np.stack([np.ones_like(du), du, du * du], axis=2)
    ata = np.einsum("mki,mkj->mij", a, a) + 1e-30 * np.eye(3)
    c = np.linalg.solve(ata, np.einsum("mki,mk->mi", a, y)[..., None])[..., 0]
    vertex = np.where(np.abs(c[:, 2]) > 0, -c[:, 1] / np.where(c[:, 2] != 0, 2 * c[:, 2], 1.0), 0.0)
    lo, hi = du[:, half - 1], du[:, half + 1]
    out = u[at] + np.clip(vertex, np.minimum(lo, 0.0), np.maximum(hi, 0.0))
    return np.where(closed & (out < 0), out + (u[n] if closed else 0.0), out)


def _on_side(field, p):
    """Points (n, 2) within 1e-6 of the box diagonal from a side of the box."""
    lo, hi = field.bounds
    return (np.minimum(np.abs(p - lo), np.abs(p - hi)) < 1e-6 * field.size).any(axis=1)


def _project_on_sides(field, p, steps: int = 6):
    """Points on a box side moved along that side onto f = 0 (Newton on the free coordinate)."""
    lo, hi = field.bounds
    tol = 1e-6 * field.size
    side = np.minimum(np.abs(p - lo), np.abs(p - hi)) < tol  # (n, 2): on an x side, on a y side
    free = np.where(side[:, 0] & ~side[:, 1], 1, np.where(side[:, 1] & ~side[:, 0], 0, -1))
    idx = np.flatnonzero(free >= 0)
    if len(idx) == 0:
        return p
    q, ax = p[idx].copy(), free[idx]
    rows = np.arange(len(idx))
    for _ in range(steps):
        f, g = field.value_gradient(q)
        gf = g[rows, ax]
        step = np.where(np.abs(gf) > _TINY, f / np.where(np.abs(gf) > _TINY, gf, 1.0), 0.0)
        step = np.clip(step, -0.01 * field.size, 0.01 * field.size)
        q[rows, ax] = np.clip(q[rows, ax] - step, lo[ax], hi[ax])
    out = p.copy()
    out[idx] = q
    return out


# -- the mesh -----------------------------------------------------------------------------------
class _Out:
    """Mesh vertices along the dense parametrisation: arc length u, point, chain, key, kind,
    and the measured chord deviation of the edge leaving each vertex (NaN: not measured)."""

    def __init__(self, u, p, cid, key, kind, dev=None):
        order = np.argsort(u, kind="stable")
        dev = np.full(len(u), np.nan) if dev is None else dev
        self.u, self.p, self.cid, self.key, self.kind = u[order], p[order], cid[order], key[order], kind[order]
        self.dev = dev[order]

    def add(self, u, p, cid):
        return _Out(np.r_[self.u, u], np.concatenate([self.p, p]), np.r_[self.cid, cid],
                    np.r_[self.key, np.full(len(u), -1, INDEX_DTYPE)], np.r_[self.kind, np.zeros(len(u), np.int8)],
                    np.r_[self.dev, np.full(len(u), np.nan)])

    def edges(self):
        return np.flatnonzero(self.cid[:-1] == self.cid[1:])


def _at_arc(d: _Dense, u_dense, u):
    """Curve points at arc lengths u: interpolated in the dense polyline, then projected."""
    i = np.clip(np.searchsorted(u_dense, u, side="right") - 1, 0, len(u_dense) - 2)
    t = np.clip((u - u_dense[i]) / np.maximum(u_dense[i + 1] - u_dense[i], _TINY), 0.0, 1.0)
    q = d.p[i] + t[:, None] * (d.p[i + 1] - d.p[i])
    # q is within the dense polyline's sagitta of the curve: Newton converges in 2 steps
    return d.field.project(q, max_step=np.linalg.norm(d.p[i + 1] - d.p[i], axis=1) + _TINY, steps=3)


def _place(d: _Dense, h):
    """Unit mesh of each piece between mandatory vertices: ceil(metric length) edges,
    vertices equidistributed in metric length."""
    u = d.arc()
    seglen = np.diff(u)
    same = d.cid[1:] == d.cid[:-1]
    dm = np.where(same, seglen * 0.5 * (1.0 / h[:-1] + 1.0 / h[1:]), 0.0)
    m = np.r_[0.0, np.cumsum(dm)]
    fixed = np.flatnonzero(d.kind != _FREE)
    pa, pb = fixed[:-1], fixed[1:]
    piece = d.cid[pa] == d.cid[pb]
    pa, pb = pa[piece], pb[piece]
    length = m[pb] - m[pa]
    n = np.maximum(1, np.ceil(length - 1e-9)).astype(INDEX_DTYPE)
    # a loop (closed chain, or a chain from a vertex back to it) needs at least 3 edges
    chain = d.cid[pa]
    per_chain = np.bincount(chain, minlength=int(d.cid.max()) + 1)
    starts = np.r_[0, np.flatnonzero(d.cid[1:] != d.cid[:-1]) + 1]
    stops = np.r_[starts[1:], len(d.cid)] - 1
    loop = d.key[starts] == d.key[stops]
    need = np.where(loop[chain], -(-3 // np.maximum(per_chain[chain], 1)), 1)
    n = np.maximum(n, need)
    rep = np.repeat(np.arange(len(pa)), n - 1)
    j = np.arange(len(rep)) - np.repeat(np.cumsum(n - 1) - (n - 1), n - 1) + 1
    target = m[pa[rep]] + j * length[rep] / n[rep]
    i = np.clip(np.searchsorted(m, target, side="right") - 1, pa[rep], pb[rep] - 1)
    t = np.clip((target - m[i]) / np.maximum(m[i + 1] - m[i], _TINY), 0.0, 1.0)
    u_new = u[i] + t * (u[i + 1] - u[i])
    base = _Out(u[fixed], d.p[fixed], d.cid[fixed], d.key[fixed], d.kind[fixed])
    return base.add(u_new, _at_arc(d, u, u_new), d.cid[pa[rep]])


def _assemble(out):
    """(points, segments) of an _Out or a _Dense: keyed points (chain ends, singular points) shared."""
    key = np.where(out.key >= 0, out.key, out.key.max(initial=0) + 1 + np.arange(len(out.key)))
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    e = out.edges()
    return out.p[first], np.column_stack([inv.ravel()[e], inv.ravel()[e + 1]]).astype(INDEX_DTYPE)


def _check_dense(d: _Dense):
    """The dense polyline lies on the curve: if it crosses itself, the raw polyline's
    topology is not the curve's (a sampler too coarse for a thin neck or a narrow gap)."""
    # chains lying on top of each other (cheap test first: their points nearly coincide)
    from scipy.spatial import cKDTree

    n = len(d.p)
    seg = np.where(d.cid[1:] == d.cid[:-1], np.linalg.norm(np.diff(d.p, axis=0), axis=1), np.inf)
    local = np.minimum(np.r_[np.inf, seg], np.r_[seg, np.inf])
    k = min(4, n)
    dist, j = cKDTree(d.p).query(d.p, k=k)
    i = np.repeat(np.arange(n), k).reshape(n, k)
    twin = (d.key[i] >= 0) & (d.key[i] == d.key[j])
    starts = np.r_[0, np.flatnonzero(d.cid[1:] != d.cid[:-1]) + 1]
    stops = np.r_[starts[1:], n] - 1
    count = (stops - starts + 1)[d.cid[i]]
    closed = (d.key[starts] == d.key[stops])[d.cid[i]]
    gap = np.abs(i - j)
    neighbours = (d.cid[i] == d.cid[j]) & ((gap <= 1) | (closed & (gap >= count - 2)))
    overlap = (dist < 0.25 * np.minimum(local[i], local[j])) & ~twin & ~neighbours & (i != j)
    cross = np.zeros((int(overlap.sum()), 2)) if overlap.any() else find_segment_intersections(*_assemble(d))
    if len(cross):
        raise TopologyError(f"the sample's polyline, projected onto the curve, crosses or overlaps itself "
                            f"({len(cross)} pairs): its topology is not the curve's; sample the curve finer")


def _deviation(d: _Dense, u_dense, out: _Out, e, foot_steps: int = 1):
    """Chord deviation delta of edges e: the largest distance from EDGE_SAMPLES points of the
    edge to the curve [FG §16.2.2]. Each distance is that to a curve point found from the
    edge's own arc (the arc point at the same fraction, then foot-point steps: drop the
    sample onto the tangent there, project again), so an upper bound that never measures
    to another branch and is not fooled by corners."""
    a, b = out.p[e], out.p[e + 1]
    t = np.tile(EDGE_SAMPLES, len(e))
    k = np.repeat(np.arange(len(e)), len(EDGE_SAMPLES))
    q = a[k] + t[:, None] * (b - a)[k]
    y = _at_arc(d, u_dense, out.u[e][k] + t * (out.u[e + 1] - out.u[e])[k])
    best = np.linalg.norm(q - y, axis=1)
    for _ in range(foot_steps):
        _, g = d.field.value_gradient(y)
        n = g / np.maximum(np.linalg.norm(g, axis=1), _TINY)[:, None]
        z = q - np.einsum("ij,ij->i", q - y, n)[:, None] * n
        y = d.field.project(z, max_step=np.maximum(best, _TINY), steps=3)
        best = np.minimum(best, np.linalg.norm(q - y, axis=1))
    return best.reshape(len(e), -1).max(axis=1)


def _verify(d: _Dense, out: _Out, eps, hmin):
    """Split (at the arc midpoint) edges with delta > eps h and edges that cross, until none
    (edges shorter than 2 hmin are not split: crossings left there raise TopologyError).

    Returns the final vertices and the statistics: rounds, splits, the largest deviation
    delta, the largest delta / h net of the float32 noise floor that the tape cannot
    resolve (2 ulps of the coordinates plus 2 ulps of max |f| over the box divided by
    |grad f|), and the largest floor."""
    u_dense = d.arc()
    fscale = float(np.abs(d.field.grid(16, 16)[2]).max())  # the magnitude of f over the box
    splits, history = 0, []
    for rounds in range(1, MAX_ROUNDS + 1):
        e = out.edges()
        a, b = out.p[e], out.p[e + 1]
        h = np.linalg.norm(b - a, axis=1)
        todo = np.isnan(out.dev[e])  # new edges only
        out.dev[e[todo]] = _deviation(d, u_dense, out, e[todo])
        dev = out.dev[e]
        # float32 floor: coordinates to 2 ulps, the curve to 2 ulps of f's scale / |grad f|
        _, g = d.field.value_gradient(0.5 * (a + b))
        noise = 2.0 * _EPS32 * (np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)).max(axis=1))
                                + fscale / np.maximum(np.linalg.norm(g, axis=1), _TINY))
        bad = dev > eps * h + noise
        points, segments = _assemble(out)
        cross = find_segment_intersections(points, segments)
        bad[cross.ravel()] = True
        bad &= h > 2.0 * hmin
        if not bad.any() or (rounds > 2 and len(cross) >= history[-2] > 0):  # crossings must go
            break
        history.append(len(cross))
        um = 0.5 * (out.u[e[bad]] + out.u[e[bad] + 1])
        out.dev[e[bad]] = np.nan
        out = out.add(um, _at_arc(d, u_dense, um), out.cid[e[bad]])
        splits += int(bad.sum())
    if len(cross):
        raise TopologyError(f"{len(cross)} pairs of edges still cross after {rounds} rounds: the raw polyline "
                            "does not follow the curve's topology (sample it finer)")
    left = int(np.count_nonzero(dev > eps * h + noise))
    if left:
        warnings.warn(f"chord deviation above tolerance on {left} edges (hmin or {MAX_ROUNDS} rounds reached)",
                      RuntimeWarning, stacklevel=3)
    stats = {"rounds": rounds, "splits": splits, "max_deviation": float(dev.max()),
             "max_relative_deviation": float((np.maximum(dev - noise, 0.0) / np.maximum(h, _TINY)).max()),
             "deviation_floor": float(noise.max())}
    return out, stats
