"""A rigorous upper bound of |grad f| over a box: forward-mode interval arithmetic on the DAG.

[FG §16.1.2] ('Practical aspects') turns a Lipschitz constant lambda of f into a
distance bound: |f(p)| / lambda is a lower bound of the distance from p to f = 0. This
module encloses the gradient of a shape's field over boxes: each expression node carries
an interval of its value, an interval per gradient component and a scalar bound on its
gradient norm, propagated through the DAG (``shape.field.nodes()``, children first) in
numpy, vectorised over a grid of sub-boxes.

Non-smooth nodes are handled by their generalised gradients: a MIN / MAX whose branches'
value intervals overlap takes the hull of both branches' gradient intervals (f is
piecewise smooth and continuous, so its Lipschitz constant on a segment is the largest
branch gradient met); ABS straddling 0 takes the hull of +grad and -grad. The Euclidean
norm sqrt(t_1² + ... + t_k²) (circles, spheres, tori, rounded corners) is recognised:
its gradient is J^T w with |w| <= 1, so its norm is at most ||J||_2 even at the norm's
singular point; the R-functions a + b ± sqrt(a² + b²) have partials 1 ± a / sqrt(a² + b²)
in [0, 2], enclosed exactly from the operands' intervals. Other square roots, divisions,
logarithms and negative powers whose argument interval reaches their singularity give
an unbounded (inf) bound. Value intervals are tightened by the centred form
f(box) in f(centre) +- sum_k |df/dx_k| r_k (the mean value theorem). Over large boxes the
overestimation of nested R-functions snowballs (each level can double the bound), so
:func:`lipschitz_bound` refines the worst sub-boxes (branch and bound).

Measured bound / sampled max |grad f| (depth 5, default refinement): 1.00 on circles,
ellipses, spheres, polygons and min/max unions; 1.06 on an R-function union of two
discs; 1.04 on the lemniscate; 1.36 on the 'gear' example (about 500 without the
refinement), 1.25 on the 'plate'; 1.41 on a torus; 2.2 on the exact rectangle, whose
'outside + inside' terms never act together but are summed (intervals forget that).

The enclosure is rigorous in real arithmetic; float64 rounding (~1e-16 relative) is not
directed, which is negligible against the slack of the bound itself.

Example
-------
>>> import warpmesh as wm
>>> round(lipschitz_bound(wm.circle(1.0), ((-2, -2), (2, 2))), 6)
1.0
>>> x, y = wm.coords(2)
>>> lipschitz_bound(x * x + y, ((0, 0), (1, 1)), depth=3) >= 5 ** 0.5   # |grad| = |(2x, 1)|
True
"""

from __future__ import annotations

import math

import numpy as np

from warpmesh._conventions import REAL_DTYPE
from warpmesh._util.validate import check_box
from warpmesh.frep.expr import _NUMPY, Expr, depends_on, last_uses
from warpmesh.frep.shapes import Shape
from warpmesh.frep.tape import tape_of, value_gradient_at
from warpmesh.kernels import opcodes as O

__all__ = ["lipschitz_bound", "gradient_enclosure", "MAX_BOXES"]

#: the largest number of sub-boxes one call evaluates ((2**depth)**d)
MAX_BOXES = 1 << 21


def _root(shape):
    """The expression of a Shape or an Expr (TypeError for anything else)."""
    if isinstance(shape, Expr):
        return shape
    if isinstance(shape, Shape):
        return shape.field
    raise TypeError(f"expected a Shape or an Expr for 'shape', got {type(shape).__name__}")


def _mul(alo, ahi, blo, bhi):
    with np.errstate(invalid="ignore"):
        c = np.stack(np.broadcast_arrays(alo * blo, alo * bhi, ahi * blo, ahi * bhi))
    c = np.where(np.isnan(c), 0.0, c)  # 0 * inf: an exact zero factor
    return c.min(axis=0), c.max(axis=0)


def _absmax(lo, hi):
    return np.maximum(np.abs(lo), np.abs(hi))


def _square(lo, hi):
    m = _absmax(lo, hi)
    low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(lo * lo, hi * hi))
    return low, m * m


def _ipow(lo, hi, n: int):
    """[lo, hi] ** n for an integer n (n < 0 only where 0 is not in [lo, hi])."""
    if n == 0:
        return np.ones_like(lo), np.ones_like(hi)
    if n < 0:
        plo, phi = _ipow(lo, hi, -n)
        return 1.0 / phi, 1.0 / plo
    if n % 2:
        return lo**n, hi**n
    m = _absmax(lo, hi)
    low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)) ** n)
    return low, m**n


def _sin(lo, hi):
    """Interval of sin over [lo, hi]."""
    two_pi = 2 * math.pi
    with np.errstate(invalid="ignore"):
        top = np.floor((hi - math.pi / 2) / two_pi) >= np.ceil((lo - math.pi / 2) / two_pi)
        bot = np.floor((hi + math.pi / 2) / two_pi) >= np.ceil((lo + math.pi / 2) / two_pi)
    s1, s2 = np.sin(lo), np.sin(hi)
    wide = ~np.isfinite(hi - lo) | (hi - lo >= two_pi)
    return (np.where(bot | wide, -1.0, np.minimum(s1, s2)), np.where(top | wide, 1.0, np.maximum(s1, s2)))


def _unit_ratio(ulo, uhi, rlo, rhi):
    """Range of u / sqrt(u² + r) over u in [ulo, uhi], r in [rlo, rhi] (r >= 0), 0 at u = r = 0.

    It increases with u; for a fixed u its magnitude decreases with r."""
    def ratio(u, r):
        den = np.sqrt(u * u + r)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0, u / np.where(den > 0, den, 1.0), 0.0)

    low = ratio(ulo, np.where(ulo < 0, rlo, rhi))
    high = ratio(uhi, np.where(uhi > 0, rlo, rhi))
    low = np.where(np.isfinite(low), low, -1.0)
    high = np.where(np.isfinite(high), high, 1.0)
    return np.clip(low, -1.0, 1.0), np.clip(high, -1.0, 1.0)


def _norm_terms(node):
    """(terms [(t, c)], c0) with node = sum c t² + c0 (c > 0, c0 >= 0), or None."""
    if node.op == O.SQUARE:
        return [(node.args[0], 1.0)], 0.0
    if node.op == O.ADD:
        a, b = _norm_terms(node.args[0]), _norm_terms(node.args[1])
        return None if a is None or b is None else (a[0] + b[0], a[1] + b[1])
    if node.op == O.ADDC and node.imm >= 0:
        a = _norm_terms(node.args[0])
        return None if a is None else (a[0], a[1] + node.imm)
    if node.op == O.MULC and node.imm > 0:
        a = _norm_terms(node.args[0])
        return None if a is None else ([(t, c * node.imm) for t, c in a[0]], a[1] * node.imm)
    return None


class _Iv:
    """Interval value (lo, hi) (m,), gradient intervals (glo, ghi) (m, d), norm bound L (m,)."""

    __slots__ = ("lo", "hi", "glo", "ghi", "L")

    def __init__(self, lo, hi, glo, ghi, L=None):
        self.lo, self.hi, self.glo, self.ghi = lo, hi, glo, ghi
        box = np.sqrt(np.sum(_absmax(glo, ghi) ** 2, axis=1))
        self.L = box if L is None else np.minimum(np.where(np.isnan(L), np.inf, L), box)


def _chain(a: _Iv, vlo, vhi, dlo, dhi, dmax=None) -> _Iv:
    """A unary node of value [vlo, vhi] and derivative in [dlo, dhi] with respect to a."""
    glo, ghi = _mul(a.glo, a.ghi, dlo[:, None], dhi[:, None])
    dm = _absmax(dlo, dhi) if dmax is None else dmax
    with np.errstate(invalid="ignore"):
        L = np.where(a.L == 0, 0.0, dm * a.L)
    return _Iv(vlo, vhi, glo, ghi, L)


def _select(a: _Iv, b: _Iv, a_only, b_only, vlo, vhi) -> _Iv:
    """MIN / MAX: the branch that wins on the whole box, else the hull of both gradients."""
    hlo, hhi = np.minimum(a.glo, b.glo), np.maximum(a.ghi, b.ghi)
    glo = np.where(a_only[:, None], a.glo, np.where(b_only[:, None], b.glo, hlo))
    ghi = np.where(a_only[:, None], a.ghi, np.where(b_only[:, None], b.ghi, hhi))
    L = np.where(a_only, a.L, np.where(b_only, b.L, np.maximum(a.L, b.L)))
    return _Iv(vlo, vhi, glo, ghi, L)


def _const(m, d, c) -> _Iv:
    z = np.zeros((m, d))
    return _Iv(np.full(m, c), np.full(m, c), z, z.copy(), np.zeros(m))


def _unbounded(m, d, lo=-np.inf, hi=np.inf) -> _Iv:
    inf = np.full((m, d), np.inf)
    return _Iv(np.broadcast_to(lo, (m,)).astype(float), np.broadcast_to(hi, (m,)).astype(float), -inf, inf,
               np.full(m, np.inf))


def _norm_node(terms, c0, vals, m, d) -> _Iv:
    """sqrt(sum c_i t_i² + c0): gradient sum w_i sqrt(c_i) grad t_i with |w| <= 1."""
    u = [(np.sqrt(c) * vals[id(t)].lo, np.sqrt(c) * vals[id(t)].hi) for t, c in terms]
    sq = [_square(lo, hi) for lo, hi in u]
    slo, shi = sum(s[0] for s in sq) + c0, sum(s[1] for s in sq) + c0
    glo, ghi = np.zeros((m, d)), np.zeros((m, d))
    rows_c, rows_r = [], []
    for (t, c), (ulo, uhi), (qlo, qhi) in zip(terms, u, sq):
        wlo, whi = _unit_ratio(ulo, uhi, slo - qlo, shi - qhi)
        jlo, jhi = np.sqrt(c) * vals[id(t)].glo, np.sqrt(c) * vals[id(t)].ghi
        plo, phi = _mul(jlo, jhi, wlo[:, None], whi[:, None])
        glo, ghi = glo + plo, ghi + phi
        with np.errstate(invalid="ignore"):
            rows_c.append(0.5 * (jlo + jhi))
            rows_r.append(0.5 * (jhi - jlo))
    jc, jr = np.stack(rows_c, axis=1), np.stack(rows_r, axis=1)  # (m, k, d)
    finite = np.all(np.isfinite(jc), axis=(1, 2)) & np.all(np.isfinite(jr), axis=(1, 2))
    jc, jr = np.where(finite[:, None, None], jc, 0.0), np.where(finite[:, None, None], jr, 0.0)
    L = np.linalg.norm(jc, ord=2, axis=(1, 2)) + np.sqrt(np.sum(jr * jr, axis=(1, 2)))
    return _Iv(np.sqrt(np.maximum(slo, 0.0)), np.sqrt(np.maximum(shi, 0.0)), glo, ghi,
               np.where(finite, L, np.inf))


def _rfunction(a: _Iv, b: _Iv, s: float) -> _Iv:
    """a + b + s sqrt(a² + b²), s = +1 (union) or -1 (intersection); increasing in a and b."""
    def r(x, y):
        return x + y + s * np.hypot(x, y)

    with np.errstate(invalid="ignore"):
        vlo, vhi = r(a.lo, b.lo), r(a.hi, b.hi)
    alo2, ahi2 = _square(a.lo, a.hi)
    blo2, bhi2 = _square(b.lo, b.hi)
    walo, wahi = _unit_ratio(a.lo, a.hi, blo2, bhi2)
    wblo, wbhi = _unit_ratio(b.lo, b.hi, alo2, ahi2)
    if s > 0:
        dalo, dahi, dblo, dbhi = 1 + walo, 1 + wahi, 1 + wblo, 1 + wbhi
    else:
        dalo, dahi, dblo, dbhi = 1 - wahi, 1 - walo, 1 - wbhi, 1 - wblo
    glo_a, ghi_a = _mul(a.glo, a.ghi, dalo[:, None], dahi[:, None])
    glo_b, ghi_b = _mul(b.glo, b.ghi, dblo[:, None], dbhi[:, None])
    with np.errstate(invalid="ignore"):
        L = np.minimum(dahi * a.L + dbhi * b.L, a.L + b.L + np.hypot(a.L, b.L))
    return _Iv(vlo, vhi, glo_a + glo_b, ghi_a + ghi_b, L)


def _apply(node, args, vals, m, d) -> _Iv:  # noqa: C901 - one branch per opcode
    op, c = node.op, node.imm
    a = args[0] if args else None
    b = args[1] if len(args) > 1 else None
    if op == O.CONST:
        return _const(m, d, c)
    if op in (O.ADD, O.SUB):
        sg = 1.0 if op == O.ADD else -1.0
        blo, bhi = (b.lo, b.hi) if sg > 0 else (-b.hi, -b.lo)
        bglo, bghi = (b.glo, b.ghi) if sg > 0 else (-b.ghi, -b.glo)
        return _Iv(a.lo + blo, a.hi + bhi, a.glo + bglo, a.ghi + bghi, a.L + b.L)
    if op == O.MUL:
        vlo, vhi = _mul(a.lo, a.hi, b.lo, b.hi)
        p1 = _mul(a.glo, a.ghi, b.lo[:, None], b.hi[:, None])
        p2 = _mul(b.glo, b.ghi, a.lo[:, None], a.hi[:, None])
        with np.errstate(invalid="ignore"):
            L = np.nan_to_num(_absmax(b.lo, b.hi) * a.L, nan=0.0) + np.nan_to_num(_absmax(a.lo, a.hi) * b.L, nan=0.0)
        return _Iv(vlo, vhi, p1[0] + p2[0], p1[1] + p2[1], L)
    if op == O.DIV:
        ok = (b.lo > 0) | (b.hi < 0)
        rlo = np.where(ok, 1.0 / np.where(ok, b.hi, 1.0), -np.inf)  # 1 / b, unbounded if 0 in b
        rhi = np.where(ok, 1.0 / np.where(ok, b.lo, 1.0), np.inf)
        qlo, qhi = _mul(a.lo, a.hi, rlo, rhi)
        t1 = _mul(b.glo, b.ghi, qlo[:, None], qhi[:, None])
        nlo, nhi = a.glo - t1[1], a.ghi - t1[0]
        glo, ghi = _mul(nlo, nhi, rlo[:, None], rhi[:, None])
        with np.errstate(invalid="ignore"):
            L = (a.L + _absmax(qlo, qhi) * b.L) * _absmax(rlo, rhi)
        out = _Iv(qlo, qhi, glo, ghi, L)
        return out
    if op in (O.MIN, O.MAX):
        if op == O.MIN:
            return _select(a, b, a.hi < b.lo, b.hi < a.lo, np.minimum(a.lo, b.lo), np.minimum(a.hi, b.hi))
        return _select(a, b, a.lo > b.hi, b.lo > a.hi, np.maximum(a.lo, b.lo), np.maximum(a.hi, b.hi))
    if op in (O.MINC, O.MAXC):
        k = _const(m, d, c)
        if op == O.MINC:
            return _select(a, k, a.hi < c, a.lo > c, np.minimum(a.lo, c), np.minimum(a.hi, c))
        return _select(a, k, a.lo > c, a.hi < c, np.maximum(a.lo, c), np.maximum(a.hi, c))
    if op == O.ADDC:
        return _Iv(a.lo + c, a.hi + c, a.glo, a.ghi, a.L)
    if op == O.MULC:
        lo, hi = (a.lo * c, a.hi * c) if c >= 0 else (a.hi * c, a.lo * c)
        glo, ghi = (a.glo * c, a.ghi * c) if c >= 0 else (a.ghi * c, a.glo * c)
        return _Iv(lo, hi, glo, ghi, abs(c) * a.L)
    if op in (O.NEG, O.RSUBC):
        k = 0.0 if op == O.NEG else c
        return _Iv(k - a.hi, k - a.lo, -a.ghi, -a.glo, a.L)
    if op in (O.RDIVC, O.LOG) or (op == O.POWI and c < 0):
        ok = (a.lo > 0) | ((a.hi < 0) & (op != O.LOG))
        if not ok.all():
            bad = _unbounded(m, d)
            a = _Iv(np.where(ok, a.lo, 1.0), np.where(ok, a.hi, 1.0), a.glo, a.ghi, a.L)
        if op == O.RDIVC:
            rlo, rhi = 1.0 / a.hi, 1.0 / a.lo
            vlo, vhi = (c * rlo, c * rhi) if c >= 0 else (c * rhi, c * rlo)
            slo, shi = _square(rlo, rhi)
            out = _chain(a, vlo, vhi, *((-c * shi, -c * slo) if c >= 0 else (-c * slo, -c * shi)))
        elif op == O.LOG:
            out = _chain(a, np.log(a.lo), np.log(a.hi), 1.0 / a.hi, 1.0 / a.lo)
        else:
            n = int(c)
            dlo, dhi = _ipow(a.lo, a.hi, n - 1)
            out = _chain(a, *_ipow(a.lo, a.hi, n), *((n * dhi, n * dlo)))
        if not ok.all():
            out = _Iv(np.where(ok, out.lo, bad.lo), np.where(ok, out.hi, bad.hi),
                      np.where(ok[:, None], out.glo, bad.glo), np.where(ok[:, None], out.ghi, bad.ghi),
                      np.where(ok, out.L, np.inf))
        return out
    if op == O.ABS:
        pos, neg = a.lo >= 0, a.hi <= 0
        gm = _absmax(a.glo, a.ghi)
        glo = np.where(pos[:, None], a.glo, np.where(neg[:, None], -a.ghi, -gm))
        ghi = np.where(pos[:, None], a.ghi, np.where(neg[:, None], -a.glo, gm))
        lo = np.where(pos, a.lo, np.where(neg, -a.hi, 0.0))
        return _Iv(lo, _absmax(a.lo, a.hi), glo, ghi, a.L)
    if op == O.SQUARE:
        return _chain(a, *_square(a.lo, a.hi), 2 * a.lo, 2 * a.hi)
    if op == O.POWI:
        n = int(c)
        dlo, dhi = _ipow(a.lo, a.hi, n - 1)
        return _chain(a, *_ipow(a.lo, a.hi, n), *((n * dlo, n * dhi)))
    if op == O.SQRT:
        terms = _norm_terms(node.args[0])
        if terms is not None:
            return _norm_node(terms[0], terms[1], vals, m, d)
        vlo, vhi = np.sqrt(np.maximum(a.lo, 0.0)), np.sqrt(np.maximum(a.hi, 0.0))
        with np.errstate(divide="ignore"):
            dlo = np.where(a.hi > 0, 0.5 / np.where(a.hi > 0, vhi, 1.0), 0.0)
            dhi = np.where(a.lo > 0, 0.5 / np.where(a.lo > 0, vlo, 1.0), np.where(a.hi > 0, np.inf, 0.0))
        return _chain(a, vlo, vhi, dlo, dhi)
    if op in (O.SIN, O.COS):
        shift = 0.0 if op == O.SIN else math.pi / 2
        vlo, vhi = _sin(a.lo + shift, a.hi + shift)
        if op == O.SIN:
            dlo, dhi = _sin(a.lo + math.pi / 2, a.hi + math.pi / 2)
        else:
            nlo, nhi = _sin(a.lo, a.hi)
            dlo, dhi = -nhi, -nlo
        return _chain(a, vlo, vhi, dlo, dhi)
    if op == O.EXP:
        vlo, vhi = np.exp(a.lo), np.exp(a.hi)
        return _chain(a, vlo, vhi, vlo, vhi)
    if op == O.POWF:
        mlo = np.where((a.lo <= 0) & (a.hi >= 0), 0.0, np.minimum(np.abs(a.lo), np.abs(a.hi)))
        mhi = _absmax(a.lo, a.hi)
        with np.errstate(divide="ignore"):
            p = (mlo**c, mhi**c) if c > 0 else (mhi**c, mlo**c)
            q = (mlo ** (c - 1), mhi ** (c - 1)) if c >= 1 else (mhi ** (c - 1), mlo ** (c - 1))
        dmag_lo, dmag_hi = abs(c) * q[0], abs(c) * q[1]
        sgn = math.copysign(1.0, c)
        dlo = np.where(a.lo > 0, sgn * np.where(sgn > 0, dmag_lo, dmag_hi),
                       np.where(a.hi < 0, -sgn * np.where(sgn > 0, dmag_hi, dmag_lo), -dmag_hi))
        dhi = np.where(a.lo > 0, sgn * np.where(sgn > 0, dmag_hi, dmag_lo),
                       np.where(a.hi < 0, -sgn * np.where(sgn > 0, dmag_lo, dmag_hi), dmag_hi))
        return _chain(a, p[0], p[1], dlo, dhi)
    if op == O.RUNION:
        return _rfunction(a, b, 1.0)
    if op == O.RINTER:
        return _rfunction(a, b, -1.0)
    if op == O.COPY:
        return a
    raise ValueError(f"expected an expression of known opcodes, got opcode {op}")  # pragma: no cover


def _sub_boxes(box, depth):
    d = box.shape[1]
    k = 1 << depth
    edges = [np.linspace(box[0, i], box[1, i], k + 1) for i in range(d)]
    idx = np.stack([g.ravel() for g in np.meshgrid(*([np.arange(k)] * d), indexing="ij")], axis=1)
    lo = np.stack([edges[i][idx[:, i]] for i in range(d)], axis=1)
    hi = np.stack([edges[i][idx[:, i] + 1] for i in range(d)], axis=1)
    return lo, hi


def gradient_enclosure(shape, lo, hi):
    """Intervals of f, of each gradient component, and a bound of |grad f| over boxes.

    Parameters
    ----------
    shape : Shape or Expr
    lo, hi : (m, d) array_like
        Box corners, d = 2 (the boxes lie in z = 0) or 3, lo <= hi.

    Returns
    -------
    value : (m, 2) float64
    grad_lo, grad_hi : (m, d) float64
    norm : (m,) float64 upper bound of |grad f| over each box (may be inf)
    """
    root = _root(shape)
    lo, hi = np.asarray(lo, REAL_DTYPE), np.asarray(hi, REAL_DTYPE)
    m, d = lo.shape
    nodes = root.nodes()
    index, last = last_uses(nodes)
    keep_alive = set()  # the terms of norm patterns are read by their SQRT, not by the sum
    for n in nodes:
        if n.op == O.SQRT and _norm_terms(n.args[0]) is not None:
            for t, _ in _norm_terms(n.args[0])[0]:
                last[index[id(t)]] = max(last[index[id(t)]], index[id(n)])
                keep_alive.add(id(t))
    vals: dict[int, _Iv] = {}
    mids: dict[int, np.ndarray] = {}  # every node's value at the box centres
    eye = np.eye(d)
    centre, radius = 0.5 * (lo + hi), 0.5 * (hi - lo)
    rnorm = np.linalg.norm(radius, axis=1)
    for i, n in enumerate(nodes):
        if n.op in (O.X, O.Y, O.Z):
            k = n.op - O.X
            if k < d:
                g = np.broadcast_to(eye[k], (m, d)).copy()
                vals[id(n)] = _Iv(lo[:, k].copy(), hi[:, k].copy(), g, g.copy(), np.ones(m))
                mids[id(n)] = centre[:, k]
            else:
                vals[id(n)] = _const(m, d, 0.0)
                mids[id(n)] = np.zeros(m)
            continue
        with np.errstate(all="ignore"):
            iv = _apply(n, [vals[id(a)] for a in n.args], vals, m, d)
            if n.op == O.CONST:
                mid = np.full(m, n.imm)
            else:
                ma = [mids[id(a)] for a in n.args] + [None] * (2 - len(n.args))
                mid = np.broadcast_to(_NUMPY[n.op](ma[0], ma[1], n.imm), (m,)).astype(REAL_DTYPE)
            # centred form (mean value theorem; f is Lipschitz where the bound is finite):
            # f(box) lies in f(centre) +- sum |df/dx_k| r_k, and +- L |r|
            spread = np.minimum(np.sum(_absmax(iv.glo, iv.ghi) * radius, axis=1), iv.L * rnorm)
            ok = np.isfinite(spread) & np.isfinite(mid)
            iv.lo = np.where(ok, np.maximum(iv.lo, mid - spread), iv.lo)
            iv.hi = np.where(ok, np.minimum(iv.hi, mid + spread), iv.hi)
        vals[id(n)], mids[id(n)] = iv, mid
        for a in n.args:
            if last[index[id(a)]] <= i and id(a) in vals:
                del vals[id(a)], mids[id(a)]
        for t in [t for t in keep_alive if t in vals and last[index[t]] <= i]:
            del vals[t], mids[t]
    out = vals[id(root)]
    norm = np.where(np.isnan(out.L), np.inf, out.L)
    return np.column_stack([out.lo, out.hi]), out.glo, out.ghi, norm


def _centre_gradient_norms(root, lo, hi, d):
    """|grad f| at the box centres (exact forward mode on the tape): a lower bound of the max."""
    return np.linalg.norm(value_gradient_at(tape_of(root), 0.5 * (lo + hi))[1], axis=1)


def _split(lo, hi):
    """The 2**d halves of each box (m, d) -> (m 2**d, d)."""
    m, d = lo.shape
    mid = 0.5 * (lo + hi)
    parts_lo, parts_hi = [], []
    for corner in range(1 << d):
        bits = np.array([(corner >> k) & 1 for k in range(d)], bool)
        parts_lo.append(np.where(bits, mid, lo))
        parts_hi.append(np.where(bits, hi, mid))
    return np.concatenate(parts_lo), np.concatenate(parts_hi)


def lipschitz_bound(shape, bounds, depth: int = 5, *, refine: int = 6, rtol: float = 0.25,
                    budget: int = 1 << 14, local: bool = False):
    """A rigorous upper bound of |grad f| over a box (a Lipschitz constant of f there).

    The box is split into 2**depth sub-boxes per axis and the gradient enclosed on each by
    forward-mode interval arithmetic (module docstring). Then, branch and bound: the
    sub-boxes whose bound exceeds (1 + ``rtol``) times the largest |grad f| sampled at the
    box centres (a lower bound of the true maximum) are halved along every axis and
    enclosed again, for at most ``refine`` levels and ``budget`` new sub-boxes. The result
    is the largest bound over the final sub-boxes, so |f(p)| / bound is a lower bound of
    the distance from p to f = 0 [FG §16.1.2, 'Practical aspects'] for p and its nearest
    curve point in the box.

    Parameters
    ----------
    shape : Shape or Expr
    bounds : ((x0, y0), (x1, y1)) or ((x0, y0, z0), (x1, y1, z1))
        2D bounds mean the plane z = 0 (the shape must not read z).
    depth : int
        Uniform subdivision levels: (2**depth)**d sub-boxes (at most ``MAX_BOXES``).
    refine : int
        Branch-and-bound levels after the uniform ones (0: none).
    rtol : float
        Stop refining the boxes whose bound is within this fraction of the sampled maximum.
    budget : int
        Most sub-boxes the refinement may add.
    local : bool
        Also return the final sub-boxes and their bounds.

    Returns
    -------
    float, or (float, lo (m, d), hi (m, d), bounds (m,)) when ``local``.
    inf where the field has an unbounded derivative (a square root, division or log at
    its singularity, other than a Euclidean norm).

    Raises
    ------
    TypeError
        ``shape`` is not a shape or an expression.
    ValueError
        Bad ``bounds``, ``depth``, ``refine``, ``rtol`` or ``budget``, or 2D bounds for a
        shape reading z.

    Example
    -------
    >>> import warpmesh as wm
    >>> lam = lipschitz_bound(wm.cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6)))
    >>> 15.44 < lam < 1.25 * 15.45     # the largest |grad f| is 15.44..., at the box corners
    True
    """
    box = check_box(bounds)
    d = box.shape[1]
    root = _root(shape)
    if d == 2 and depends_on(root, 2):
        raise ValueError("expected 3D 'bounds' for a shape that depends on z, got 2D bounds")
    for name, v in (("depth", depth), ("refine", refine), ("budget", budget)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise ValueError(f"expected a non-negative integer '{name}', got {v!r}")
    if (1 << depth) ** d > MAX_BOXES:
        raise ValueError(f"expected (2**depth)**{d} <= {MAX_BOXES} sub-boxes, got depth {depth}")
    if not (isinstance(rtol, (int, float, np.floating)) and np.isfinite(rtol) and rtol >= 0):
        raise ValueError(f"expected a non-negative finite 'rtol', got {rtol!r}")
    lo, hi = _sub_boxes(box, int(depth))
    norm = gradient_enclosure(root, lo, hi)[3]
    lower = float(_centre_gradient_norms(root, lo, hi, d).max())
    added = 0
    for _ in range(int(refine)):
        split = norm > (1.0 + rtol) * lower
        room = (budget - added) >> d
        if room < int(split.sum()):  # over budget: the worst boxes first
            split &= norm >= np.sort(norm[split])[::-1][room - 1] if room > 0 else False
            split[np.flatnonzero(split)[room:]] = False
        n_new = int(split.sum()) << d
        if n_new == 0:
            break
        clo, chi = _split(lo[split], hi[split])
        cnorm = gradient_enclosure(root, clo, chi)[3]
        lower = max(lower, float(_centre_gradient_norms(root, clo, chi, d).max()))
        lo, hi = np.concatenate([lo[~split], clo]), np.concatenate([hi[~split], chi])
        norm = np.concatenate([norm[~split], cnorm])
        added += n_new
    bound = float(norm.max())
    return (bound, lo, hi, norm) if local else bound
