"""The tape interpreter family: values, values with gradients (forward mode), intervals.

One thread evaluates the whole tape over a batch of ``batch`` points, one instruction at
a time over the batch (column-wise evaluation, as libfive does): the dispatch on the
opcode is paid once per instruction and batch, not per point, and the inner loops are
plain array arithmetic. Registers live in a flat scratch array laid out
``[thread][register][point]``.

The segment kernels (``eval_segments_kernel``, ``interval_segments_kernel``) run a
different tape per thread: each thread takes one segment of at most ``batch`` items that
share a pruned tape from a pool (:mod:`warpmesh.frep.prune`), and the interval one records
which MIN/MAX/MINC/MAXC its boxes decide. Both families share the per-instruction
helpers ``value_step`` and ``interval_step``.

Opcodes are defined in :mod:`warpmesh.kernels.opcodes`; the numpy semantics of each are
in :mod:`warpmesh.frep.expr` (the test oracle). COPY (dst = a) appears only in pruned tapes.

The NaN rule (one for points, gradients, intervals, the generated kernels and the numpy
oracle): **NaN propagates**. MIN, MAX, MINC and MAXC return NaN when an operand is NaN
(``numpy.minimum``, IEEE 754-2019 ``minimum``; not C's ``fmin``, which ``wp.min`` is),
so ``SQRT`` = ``sqrt(max(a, 0))`` of NaN is NaN too; every other opcode follows IEEE
arithmetic (``log`` of a negative, ``0 / 0``, ``inf - inf``, ``0 * inf``, ``sin(inf)``
make NaN). Meshing raises on a NaN at a sampled node.

Intervals ``(lo, hi)`` (float32, never clamped: bounds overflow to ±inf):

- an interval other than the whole line promises that every value a point kernel
  (``eval_tape_kernel``, the generated kernels) computes at a point of the box is a
  number (not NaN) in ``[lo, hi]``; ±inf bounds mean the values may be ±inf;
- ``(-inf, +inf)``, :func:`top`, promises nothing: f may be NaN somewhere in the box.
  Every opcode maps TOP to TOP, and an opcode that can make NaN from numbers over the
  box (``log`` of an interval reaching below 0, division by an interval holding 0,
  ``0 * inf``, ``sin`` of an infinite bound, ...) gives TOP;
- enclosure of the float32 point values is exact (no tolerance) for the opcodes whose
  bounds are the point operation applied to the operands' bounds (+, -, *, /, sqrt,
  abs, min, max, integer powers): float32 rounding to nearest is monotone. ``sin``,
  ``cos``, ``exp``, ``log``, ``|a|**c`` (library functions, a few ulps off) and the
  R-functions (not monotone after rounding) are widened outward by :data:`WIDEN` (16
  ulps) relative plus a tiny absolute amount; R-functions of operands beyond
  :data:`R_MAX` in magnitude give TOP.

Culling (:mod:`warpmesh.surface.block_grid`, the octree) skips a box only when both bounds
are finite and exclude 0, so it never hides a NaN or an infinite node value.
"""

import warp as wp

from warpmesh.kernels import opcodes as O

wp.set_module_options({"enable_backward": False,  # forward evaluation only: halves the compile
                        "fuse_fp": False})  # no FMA contraction: the same rounding as generated kernels

OP_X = wp.constant(O.X)
OP_Y = wp.constant(O.Y)
OP_Z = wp.constant(O.Z)
OP_CONST = wp.constant(O.CONST)
OP_ADD = wp.constant(O.ADD)
OP_SUB = wp.constant(O.SUB)
OP_MUL = wp.constant(O.MUL)
OP_DIV = wp.constant(O.DIV)
OP_MIN = wp.constant(O.MIN)
OP_MAX = wp.constant(O.MAX)
OP_ADDC = wp.constant(O.ADDC)
OP_MULC = wp.constant(O.MULC)
OP_RSUBC = wp.constant(O.RSUBC)
OP_RDIVC = wp.constant(O.RDIVC)
OP_MINC = wp.constant(O.MINC)
OP_MAXC = wp.constant(O.MAXC)
OP_NEG = wp.constant(O.NEG)
OP_ABS = wp.constant(O.ABS)
OP_SQUARE = wp.constant(O.SQUARE)
OP_SQRT = wp.constant(O.SQRT)
OP_SIN = wp.constant(O.SIN)
OP_COS = wp.constant(O.COS)
OP_EXP = wp.constant(O.EXP)
OP_LOG = wp.constant(O.LOG)
OP_POWI = wp.constant(O.POWI)
OP_POWF = wp.constant(O.POWF)
OP_RUNION = wp.constant(O.RUNION)
OP_RINTER = wp.constant(O.RINTER)
OP_COPY = wp.constant(O.COPY)

INF = wp.constant(wp.inf)
WIDEN = wp.constant(1.9073486328125e-06)  # 2**-19: outward widening of library functions, relative
TINY = wp.constant(1.0e-37)  # ... plus this absolute amount (subnormal results)
R_MAX = wp.constant(1.0e30)  # R-function operands beyond this magnitude: TOP (float32 overflow)
R_TINY = wp.constant(1.0e-18)  # absolute widening of R-functions: hypot underflows below ~1e-19
TRIG_TOL = wp.constant(1.0e-6)  # relative: where sin / cos extrema may sit, float32 rounding counted
TWO_PI = wp.constant(6.283185307179586)
HALF_PI = wp.constant(1.5707963267948966)


# -- scalar semantics ----------------------------------------------------------------------
@wp.func
def powi(a: float, n: int):
    m = n
    if m < 0:
        m = -m
    r = float(1.0)
    base = a
    while m > 0:
        if m % 2 == 1:
            r = r * base
        base = base * base
        m = m // 2
    if n < 0:
        r = 1.0 / r
    return r


@wp.func
def nan_min(a: float, b: float):
    """min(a, b), NaN when either is NaN (numpy.minimum); a on a tie, as a pruned tape
    decides it. The shape of Warp's CPU ``wp.min`` (C's fmin, which drops a NaN: ``a <= b ?
    a : (b == b ? b : a)``) with one test turned round, so it costs the same."""
    return wp.where(a <= b, a, wp.where(a == a, b, a))  # a NaN: a; b NaN: b


@wp.func
def nan_max(a: float, b: float):
    """max(a, b), NaN when either is NaN (numpy.maximum); a on a tie."""
    return wp.where(a >= b, a, wp.where(a == a, b, a))


@wp.func
def hypot(a: float, b: float):
    """sqrt(a^2 + b^2) without overflow for large a, b (scaled by the larger one)."""
    m = wp.max(wp.abs(a), wp.abs(b))
    if m < 1.0e18:  # squares stay far from float32 overflow: the plain formula
        return wp.sqrt(a * a + b * b)
    if not wp.isfinite(m):
        return m
    u = a / m
    v = b / m
    return m * wp.sqrt(u * u + v * v)


@wp.func
def rfunction(a: float, b: float, s: float):
    """a + b + s * sqrt(a^2 + b^2) (s = +1 union, -1 intersection of eq. 16.17), written
    so that the cancelling case divides instead of subtracting (no float32 cancellation)."""
    h = hypot(a, b)
    if s * (a + b) >= 0.0:
        return a + b + s * h
    return 2.0 * a * (b / (a + b - s * h))  # ((a+b)^2 - h^2) / (a+b - s h); |b / (..)| <= 1


@wp.func
def apply_value(op: int, a: float, b: float, c: float):
    """The value of one instruction (used for the less common opcodes)."""
    r = float(0.0)
    if op == OP_DIV:
        r = a / b
    elif op == OP_RSUBC:
        r = c - a
    elif op == OP_RDIVC:
        r = c / a
    elif op == OP_SIN:
        r = wp.sin(a)
    elif op == OP_COS:
        r = wp.cos(a)
    elif op == OP_EXP:
        r = wp.exp(a)
    elif op == OP_LOG:
        r = wp.log(a)
    elif op == OP_POWI:
        r = powi(a, int(c))
    elif op == OP_POWF:
        r = wp.pow(wp.abs(a), c)
    elif op == OP_COPY:  # (value_step copies without calling this)
        r = a
    return r


@wp.func
def value_step(op: int, d: int, a: int, b: int, has_b: bool, c: float, cnt: int,
               scratch: wp.array(dtype=wp.float32)):
    """One instruction (any opcode but X, Y, Z) over a batch of ``cnt`` points.

    ``d``, ``a``, ``b`` are the scratch offsets of the destination's and the operands'
    first point (register * batch + the thread's base); ``has_b`` says whether the
    instruction has a second operand.
    """
    if op == OP_CONST:
        for p in range(cnt):
            scratch[d + p] = c
    elif op == OP_COPY:
        for p in range(cnt):
            scratch[d + p] = scratch[a + p]
    elif op == OP_ADD:
        for p in range(cnt):
            scratch[d + p] = scratch[a + p] + scratch[b + p]
    elif op == OP_SUB:
        for p in range(cnt):
            scratch[d + p] = scratch[a + p] - scratch[b + p]
    elif op == OP_MUL:
        for p in range(cnt):
            scratch[d + p] = scratch[a + p] * scratch[b + p]
    elif op == OP_MIN:
        for p in range(cnt):
            scratch[d + p] = nan_min(scratch[a + p], scratch[b + p])
    elif op == OP_MAX:
        for p in range(cnt):
            scratch[d + p] = nan_max(scratch[a + p], scratch[b + p])
    elif op == OP_ADDC:
        for p in range(cnt):
            scratch[d + p] = scratch[a + p] + c
    elif op == OP_MULC:
        for p in range(cnt):
            scratch[d + p] = scratch[a + p] * c
    elif op == OP_MINC:
        for p in range(cnt):
            scratch[d + p] = nan_min(scratch[a + p], c)
    elif op == OP_MAXC:
        for p in range(cnt):
            scratch[d + p] = nan_max(scratch[a + p], c)
    elif op == OP_NEG:
        for p in range(cnt):
            scratch[d + p] = -scratch[a + p]
    elif op == OP_ABS:
        for p in range(cnt):
            scratch[d + p] = wp.abs(scratch[a + p])
    elif op == OP_SQUARE:
        for p in range(cnt):
            v = scratch[a + p]
            scratch[d + p] = v * v
    elif op == OP_SQRT:
        for p in range(cnt):
            scratch[d + p] = wp.sqrt(nan_max(scratch[a + p], 0.0))
    elif op == OP_RUNION:
        for p in range(cnt):
            u = scratch[a + p]
            v = scratch[b + p]
            scratch[d + p] = rfunction(u, v, 1.0)
    elif op == OP_RINTER:
        for p in range(cnt):
            u = scratch[a + p]
            v = scratch[b + p]
            scratch[d + p] = rfunction(u, v, -1.0)
    else:
        for p in range(cnt):
            bv = float(0.0)
            if has_b:
                bv = scratch[b + p]
            scratch[d + p] = apply_value(op, scratch[a + p], bv, c)


@wp.kernel
def eval_tape_kernel(
    code: wp.array2d(dtype=wp.int32),
    imm: wp.array(dtype=wp.float32),
    n_regs: int,
    out_reg: int,
    points: wp.array(dtype=wp.vec3),
    start: int,
    stop: int,
    batch: int,
    scratch: wp.array(dtype=wp.float32),
    out: wp.array(dtype=wp.float32),
):
    """One thread: the whole tape over points [start + tid*batch, ... + batch) ∩ [.., stop)."""
    t = wp.tid()
    p0 = start + t * batch
    cnt = wp.min(batch, stop - p0)
    if cnt <= 0:
        return
    base = t * n_regs * batch
    for i in range(code.shape[0]):
        op = code[i, 0]
        d = base + code[i, 1] * batch
        if op == OP_X or op == OP_Y or op == OP_Z:
            for p in range(cnt):
                scratch[d + p] = points[p0 + p][op]
        else:
            value_step(op, d, base + code[i, 2] * batch, base + code[i, 3] * batch, code[i, 3] >= 0,
                       imm[i], cnt, scratch)
    o = base + out_reg * batch
    for p in range(cnt):
        out[p0 + p] = scratch[o + p]


@wp.kernel
def eval_segments_kernel(
    pool: wp.array2d(dtype=wp.int32),
    pool_imm: wp.array(dtype=wp.float32),
    n_regs: int,
    out_reg: int,
    seg_item: wp.array(dtype=wp.int32),
    seg_count: wp.array(dtype=wp.int32),
    seg_row: wp.array(dtype=wp.int32),
    seg_rows: wp.array(dtype=wp.int32),
    items: wp.array(dtype=wp.int32),
    points: wp.array(dtype=wp.vec3),
    start: int,
    stop: int,
    batch: int,
    scratch: wp.array(dtype=wp.float32),
    out: wp.array(dtype=wp.float32),
):
    """One thread: segment ``start + tid`` (< stop), its own tape over its points.

    The segment's tape is pool rows ``[seg_row, seg_row + seg_rows)`` (columns op, dst,
    a, b, sel; sel is not used here); its points are ``points[items[k]]`` for k in
    ``[seg_item, seg_item + seg_count)``, ``seg_count <= batch``, and ``out[items[k]]``
    receives the value of register ``out_reg``.
    """
    t = wp.tid()
    s = start + t
    if s >= stop:
        return
    q0 = seg_item[s]
    cnt = seg_count[s]
    r0 = seg_row[s]
    base = t * n_regs * batch
    for i in range(r0, r0 + seg_rows[s]):
        op = pool[i, 0]
        d = base + pool[i, 1] * batch
        if op == OP_X or op == OP_Y or op == OP_Z:
            for p in range(cnt):
                scratch[d + p] = points[items[q0 + p]][op]
        else:
            value_step(op, d, base + pool[i, 2] * batch, base + pool[i, 3] * batch, pool[i, 3] >= 0,
                       pool_imm[i], cnt, scratch)
    o = base + out_reg * batch
    for p in range(cnt):
        out[items[q0 + p]] = scratch[o + p]


# -- forward mode: (value, d/dx, d/dy, d/dz) -------------------------------------------------
@wp.func
def chain(a: wp.vec4, value: float, slope: float):
    return wp.vec4(value, slope * a[1], slope * a[2], slope * a[3])


@wp.func
def apply_dual(op: int, a: wp.vec4, b: wp.vec4, c: float):
    """Value and gradient of one instruction from its operands' values and gradients."""
    r = wp.vec4(0.0)
    if op == OP_CONST:
        r = wp.vec4(c, 0.0, 0.0, 0.0)
    elif op == OP_COPY:
        r = a
    elif op == OP_ADD:
        r = a + b
    elif op == OP_SUB:
        r = a - b
    elif op == OP_MUL:
        r = wp.vec4(a[0] * b[0], a[1] * b[0] + a[0] * b[1], a[2] * b[0] + a[0] * b[2],
                    a[3] * b[0] + a[0] * b[3])
    elif op == OP_DIV:
        q = a[0] / b[0]
        r = (a - q * b) / b[0]
        r[0] = q
    elif op == OP_MIN:  # NaN propagates: a NaN b wins over a number a (a NaN a stays)
        r = a
        if b[0] < a[0] or wp.isnan(b[0]):
            r = b
    elif op == OP_MAX:
        r = a
        if b[0] > a[0] or wp.isnan(b[0]):
            r = b
    elif op == OP_ADDC:
        r = a
        r[0] = a[0] + c
    elif op == OP_MULC:
        r = a * c
    elif op == OP_RSUBC:
        r = -a
        r[0] = c - a[0]
    elif op == OP_RDIVC:
        r = chain(a, c / a[0], -c / (a[0] * a[0]))
    elif op == OP_MINC:
        r = a
        if c < a[0]:
            r = wp.vec4(c, 0.0, 0.0, 0.0)
    elif op == OP_MAXC:
        r = a
        if c > a[0]:
            r = wp.vec4(c, 0.0, 0.0, 0.0)
    elif op == OP_NEG:
        r = -a
    elif op == OP_ABS:
        r = a
        if a[0] < 0.0:
            r = -a
    elif op == OP_SQUARE:
        r = chain(a, a[0] * a[0], 2.0 * a[0])
    elif op == OP_SQRT:
        s = wp.sqrt(nan_max(a[0], 0.0))
        slope = float(0.0)
        if s > 0.0:
            slope = 0.5 / s
        r = chain(a, s, slope)
    elif op == OP_SIN:
        r = chain(a, wp.sin(a[0]), wp.cos(a[0]))
    elif op == OP_COS:
        r = chain(a, wp.cos(a[0]), -wp.sin(a[0]))
    elif op == OP_EXP:
        e = wp.exp(a[0])
        r = chain(a, e, e)
    elif op == OP_LOG:
        r = chain(a, wp.log(a[0]), 1.0 / a[0])
    elif op == OP_POWI:
        n = int(c)
        r = chain(a, powi(a[0], n), float(n) * powi(a[0], n - 1))
    elif op == OP_POWF:
        m = wp.abs(a[0])
        slope = float(0.0)
        if m > 0.0:
            slope = c * wp.pow(m, c - 1.0) * wp.sign(a[0])
        r = chain(a, wp.pow(m, c), slope)
    elif op == OP_RUNION or op == OP_RINTER:
        s = float(1.0)
        if op == OP_RINTER:
            s = -1.0
        h = hypot(a[0], b[0])
        da = float(1.0)
        db = float(1.0)
        if h > 0.0:
            da = 1.0 + s * a[0] / h
            db = 1.0 + s * b[0] / h
        r = da * a + db * b
        r[0] = rfunction(a[0], b[0], s)
    return r


@wp.kernel
def eval_tape_dual_kernel(
    code: wp.array2d(dtype=wp.int32),
    imm: wp.array(dtype=wp.float32),
    n_regs: int,
    out_reg: int,
    points: wp.array(dtype=wp.vec3),
    start: int,
    stop: int,
    batch: int,
    scratch: wp.array(dtype=wp.vec4),
    out: wp.array(dtype=wp.vec4),
):
    """One thread: value and exact gradient over a batch of points (as eval_tape_kernel)."""
    t = wp.tid()
    p0 = start + t * batch
    cnt = wp.min(batch, stop - p0)
    if cnt <= 0:
        return
    base = t * n_regs * batch
    for i in range(code.shape[0]):
        op = code[i, 0]
        d = base + code[i, 1] * batch
        a = base + wp.max(code[i, 2], 0) * batch
        b = base + wp.max(code[i, 3], 0) * batch
        c = imm[i]
        if op == OP_X or op == OP_Y or op == OP_Z:
            for p in range(cnt):
                r = wp.vec4(points[p0 + p][op], 0.0, 0.0, 0.0)
                r[op + 1] = 1.0
                scratch[d + p] = r
        else:
            for p in range(cnt):
                scratch[d + p] = apply_dual(op, scratch[a + p], scratch[b + p], c)
    o = base + out_reg * batch
    for p in range(cnt):
        out[p0 + p] = scratch[o + p]


# -- interval arithmetic: (lo, hi) --------------------------------------------------------------
@wp.func
def top():
    """TOP, the whole line (-inf, inf): "f may be NaN somewhere in the box"."""
    return wp.vec2(-INF, INF)


@wp.func
def is_top(a: wp.vec2):
    """Whether ``a`` is TOP, the whole line: f may be NaN in the box."""
    return a[0] == -INF and a[1] == INF


@wp.func
def iv(lo: float, hi: float):
    """The interval [lo, hi]; TOP when a bound is NaN (or lo > hi). Never clamped."""
    if not (lo <= hi):
        return top()
    return wp.vec2(lo, hi)


@wp.func
def down(v: float):
    """A lower bound moved outward by WIDEN (relative) + TINY; ±inf stays."""
    if wp.isfinite(v):
        return v - (wp.abs(v) * WIDEN + TINY)
    return v


@wp.func
def up(v: float):
    """An upper bound moved outward by WIDEN (relative) + TINY; ±inf stays."""
    if wp.isfinite(v):
        return v + (wp.abs(v) * WIDEN + TINY)
    return v


@wp.func
def iv_hull4(p: float, q: float, r: float, s: float):
    """The hull of four products or quotients; TOP when one is NaN (0 * inf, inf / inf:
    a point of the box can make that NaN)."""
    if wp.isnan(p + q + r + s):  # (also inf - inf: then the hull is the whole line anyway)
        return top()
    return wp.vec2(wp.min(wp.min(p, q), wp.min(r, s)), wp.max(wp.max(p, q), wp.max(r, s)))


@wp.func
def iv_mul(a: wp.vec2, b: wp.vec2):
    return iv_hull4(a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1])


@wp.func
def iv_div(a: wp.vec2, b: wp.vec2):
    """a / b from the four quotients, each the same float division a point evaluation
    does (so the interval holds every float value, not only the real ones); TOP when b
    holds 0 (0 / 0 may be NaN, x / 0 is ±inf)."""
    if b[0] <= 0.0 and b[1] >= 0.0:
        return top()
    return iv_hull4(a[0] / b[0], a[0] / b[1], a[1] / b[0], a[1] / b[1])


@wp.func
def iv_sin(a: wp.vec2):
    """Range of sin over [lo, hi]: wp.sin at the ends widened by 8 ulps of 1, and ±1 where
    a maximum (pi/2 + 2k pi) or a minimum (-pi/2 + 2k pi) may lie inside, the extremum's
    float32 position counted with a tolerance TRIG_TOL * |a|; TOP with an infinite bound
    (sin(inf) is NaN)."""
    if not (wp.isfinite(a[0]) and wp.isfinite(a[1])):
        return top()
    if a[1] - a[0] >= TWO_PI:
        return wp.vec2(-1.0, 1.0)
    tol = TRIG_TOL * (wp.abs(a[0]) + wp.abs(a[1]) + 1.0)
    lo = wp.min(wp.sin(a[0]), wp.sin(a[1])) - 4.76837158203125e-07
    hi = wp.max(wp.sin(a[0]), wp.sin(a[1])) + 4.76837158203125e-07
    k = wp.ceil((a[0] - tol - HALF_PI) / TWO_PI)
    if k * TWO_PI + HALF_PI <= a[1] + tol:
        hi = 1.0
    k = wp.ceil((a[0] - tol + HALF_PI) / TWO_PI)
    if k * TWO_PI - HALF_PI <= a[1] + tol:
        lo = -1.0
    return wp.vec2(wp.max(lo, -1.0), wp.min(hi, 1.0))


@wp.func
def iv_cos(a: wp.vec2):
    """Range of cos over [lo, hi]: as :func:`iv_sin`, with maxima at 2k pi and minima at
    (2k + 1) pi."""
    if not (wp.isfinite(a[0]) and wp.isfinite(a[1])):
        return top()
    if a[1] - a[0] >= TWO_PI:
        return wp.vec2(-1.0, 1.0)
    tol = TRIG_TOL * (wp.abs(a[0]) + wp.abs(a[1]) + 1.0)
    lo = wp.min(wp.cos(a[0]), wp.cos(a[1])) - 4.76837158203125e-07
    hi = wp.max(wp.cos(a[0]), wp.cos(a[1])) + 4.76837158203125e-07
    k = wp.ceil((a[0] - tol) / TWO_PI)  # a maximum (cos = 1) at 2 k pi
    if k * TWO_PI <= a[1] + tol:
        hi = 1.0
    k = wp.ceil((a[0] - tol - 3.141592653589793) / TWO_PI)  # a minimum at (2k + 1) pi
    if k * TWO_PI + 3.141592653589793 <= a[1] + tol:
        lo = -1.0
    return wp.vec2(wp.max(lo, -1.0), wp.min(hi, 1.0))


@wp.func
def iv_recip(b: wp.vec2):
    if b[0] <= 0.0 and b[1] >= 0.0:
        return top()
    return iv(1.0 / b[1], 1.0 / b[0])


@wp.func
def iv_even_pow(a: wp.vec2, n: int):
    """a^n for even n >= 2 (a not TOP)."""
    lo = powi(a[0], n)
    hi = powi(a[1], n)
    if a[0] <= 0.0 and a[1] >= 0.0:
        return wp.vec2(0.0, wp.max(lo, hi))
    return wp.vec2(wp.min(lo, hi), wp.max(lo, hi))


@wp.func
def iv_abs(a: wp.vec2):
    """|a| (a not TOP)."""
    if a[0] >= 0.0:
        return a
    if a[1] <= 0.0:
        return wp.vec2(-a[1], -a[0])
    return wp.vec2(0.0, wp.max(-a[0], a[1]))


@wp.func
def iv_runion(a: wp.vec2, b: wp.vec2, s: float):
    """a + b + s*sqrt(a^2 + b^2) is nondecreasing in a and b for s = +1 and s = -1; the
    float32 rfunction is not quite (rounding, its two branches), so the end values are
    widened. TOP for TOP or huge operands (the sum may overflow into inf - inf)."""
    m = wp.max(wp.max(wp.abs(a[0]), wp.abs(a[1])), wp.max(wp.abs(b[0]), wp.abs(b[1])))
    if not (m <= R_MAX):  # (also TOP: its bounds are infinite)
        return top()
    lo = rfunction(a[0], b[0], s)
    hi = rfunction(a[1], b[1], s)
    return iv(lo - (wp.abs(lo) * WIDEN + R_TINY), hi + (wp.abs(hi) * WIDEN + R_TINY))


@wp.func
def apply_interval(op: int, a: wp.vec2, b: wp.vec2, c: float):
    """An interval enclosing the instruction's value for operands in a and b (the rules
    of the module docstring: TOP in, TOP out)."""
    r = wp.vec2(0.0)
    if op == OP_CONST:
        r = wp.vec2(c, c)
    elif op == OP_ADD:
        r = iv(a[0] + b[0], a[1] + b[1])  # inf - inf: NaN, TOP
    elif op == OP_SUB:
        r = iv(a[0] - b[1], a[1] - b[0])
    elif op == OP_MUL:
        r = iv_mul(a, b)
    elif op == OP_DIV:
        r = iv_div(a, b)
    elif op == OP_MIN:
        if is_top(a) or is_top(b):
            r = top()
        else:
            r = wp.vec2(wp.min(a[0], b[0]), wp.min(a[1], b[1]))
    elif op == OP_MAX:
        if is_top(a) or is_top(b):
            r = top()
        else:
            r = wp.vec2(wp.max(a[0], b[0]), wp.max(a[1], b[1]))
    elif op == OP_ADDC:
        r = wp.vec2(a[0] + c, a[1] + c)  # c finite: TOP stays TOP
    elif op == OP_MULC:
        if c >= 0.0:
            r = iv(a[0] * c, a[1] * c)  # 0 * inf: NaN, TOP
        else:
            r = iv(a[1] * c, a[0] * c)
    elif op == OP_RSUBC:
        r = wp.vec2(c - a[1], c - a[0])
    elif op == OP_RDIVC:
        r = iv_div(wp.vec2(c, c), a)
    elif op == OP_MINC:
        if is_top(a):
            r = top()
        else:
            r = wp.vec2(wp.min(a[0], c), wp.min(a[1], c))
    elif op == OP_MAXC:
        if is_top(a):
            r = top()
        else:
            r = wp.vec2(wp.max(a[0], c), wp.max(a[1], c))
    elif op == OP_NEG:
        r = wp.vec2(-a[1], -a[0])
    elif op == OP_ABS:
        if is_top(a):
            r = top()
        else:
            r = iv_abs(a)
    elif op == OP_SQUARE:
        if is_top(a):
            r = top()
        else:
            r = iv_even_pow(a, 2)
    elif op == OP_SQRT:
        if is_top(a):
            r = top()
        else:
            r = wp.vec2(wp.sqrt(wp.max(a[0], 0.0)), wp.sqrt(wp.max(a[1], 0.0)))
    elif op == OP_SIN:
        r = iv_sin(a)
    elif op == OP_COS:
        r = iv_cos(a)
    elif op == OP_EXP:
        if is_top(a):
            r = top()
        else:
            r = wp.vec2(wp.max(down(wp.exp(a[0])), 0.0), up(wp.exp(a[1])))
    elif op == OP_LOG:
        if a[0] < 0.0:  # a point of the box may be negative: NaN (TOP included)
            r = top()
        else:
            r = wp.vec2(down(wp.log(a[0])), up(wp.log(a[1])))  # log(0) = -inf
    elif op == OP_POWI:
        n = int(c)
        m = n
        if m < 0:
            m = -m
        if m % 2 == 0:
            if is_top(a):
                r = top()
            else:
                r = iv_even_pow(a, m)
        else:
            r = iv(powi(a[0], m), powi(a[1], m))
        if n < 0:
            r = iv_recip(r)
    elif op == OP_POWF:
        if is_top(a):
            r = top()
        else:
            mag = iv_abs(a)
            if c >= 0.0:
                r = wp.vec2(wp.max(down(wp.pow(mag[0], c)), 0.0), up(wp.pow(mag[1], c)))
            elif mag[0] > 0.0:
                r = wp.vec2(wp.max(down(wp.pow(mag[1], c)), 0.0), up(wp.pow(mag[0], c)))
            else:
                r = wp.vec2(wp.max(down(wp.pow(mag[1], c)), 0.0), INF)  # 0 ** c = inf
    elif op == OP_RUNION:
        r = iv_runion(a, b, 1.0)
    elif op == OP_RINTER:
        r = iv_runion(a, b, -1.0)
    elif op == OP_COPY:  # (interval_step copies without calling this)
        r = a
    return r


@wp.func
def interval_step(op: int, d: int, a: int, b: int, c: float, cnt: int, scratch: wp.array(dtype=wp.vec2)):
    """One instruction (any opcode but X, Y, Z) over a batch of ``cnt`` boxes (offsets as
    in :func:`value_step`; an unused operand offset may point at any register).
    (A COPY branch here, before the loop, measured 2-3% slower on master tapes, so the
    segment kernel copies by itself.)"""
    for p in range(cnt):
        scratch[d + p] = apply_interval(op, scratch[a + p], scratch[b + p], c)


@wp.func
def branch_choice(op: int, a: wp.vec2, b: wp.vec2):
    """Which operand alone decides a MIN/MAX/MINC/MAXC over a box: 1 the first, 2 the
    second (or the immediate, passed as the point interval ``b``), 0 neither. Exact
    float comparisons of interval bounds; a tie of two equal points picks 1. Never
    decided when an operand is TOP: a NaN there would win (NaN propagates)."""
    if is_top(a) or is_top(b):
        return 0
    if op == OP_MIN or op == OP_MINC:
        if a[1] <= b[0]:
            return 1
        if b[1] <= a[0]:
            return 2
    else:
        if a[0] >= b[1]:
            return 1
        if b[0] >= a[1]:
            return 2
    return 0


@wp.kernel
def eval_tape_interval_kernel(
    code: wp.array2d(dtype=wp.int32),
    imm: wp.array(dtype=wp.float32),
    n_regs: int,
    out_reg: int,
    box_lo: wp.array(dtype=wp.vec3),
    box_hi: wp.array(dtype=wp.vec3),
    start: int,
    stop: int,
    batch: int,
    scratch: wp.array(dtype=wp.vec2),
    out: wp.array(dtype=wp.vec2),
):
    """One thread: an interval of f over each of a batch of boxes."""
    t = wp.tid()
    p0 = start + t * batch
    cnt = wp.min(batch, stop - p0)
    if cnt <= 0:
        return
    base = t * n_regs * batch
    for i in range(code.shape[0]):
        op = code[i, 0]
        d = base + code[i, 1] * batch
        if op == OP_X or op == OP_Y or op == OP_Z:
            for p in range(cnt):
                scratch[d + p] = wp.vec2(box_lo[p0 + p][op], box_hi[p0 + p][op])
        else:
            interval_step(op, d, base + wp.max(code[i, 2], 0) * batch, base + wp.max(code[i, 3], 0) * batch,
                          imm[i], cnt, scratch)
    o = base + out_reg * batch
    for p in range(cnt):
        out[p0 + p] = scratch[o + p]


@wp.kernel
def interval_segments_kernel(
    pool: wp.array2d(dtype=wp.int32),
    pool_imm: wp.array(dtype=wp.float32),
    n_regs: int,
    out_reg: int,
    seg_item: wp.array(dtype=wp.int32),
    seg_count: wp.array(dtype=wp.int32),
    seg_row: wp.array(dtype=wp.int32),
    seg_rows: wp.array(dtype=wp.int32),
    items: wp.array(dtype=wp.int32),
    box_lo: wp.array(dtype=wp.vec3),
    box_hi: wp.array(dtype=wp.vec3),
    start: int,
    stop: int,
    batch: int,
    scratch: wp.array(dtype=wp.vec2),
    out: wp.array(dtype=wp.vec2),
    choices: wp.array2d(dtype=wp.uint8),
):
    """One thread: segment ``start + tid`` (< stop), its own tape over its boxes, as
    :func:`eval_segments_kernel`; ``out[items[k]]`` receives the interval.

    Before each pool row with ``sel >= 0`` (a MIN, MAX, MINC or MAXC not yet decided),
    the thread records into ``choices[items[k], sel]`` the operand that alone decides
    the instruction over box k (:func:`branch_choice`: 1 the first, 2 the second or
    the immediate); an undecided box keeps its entry (inherited from its parent cell).
    RUNION and RINTER are never selections: an R-function is smooth and depends on both
    operands everywhere, so no box decides it.
    """
    t = wp.tid()
    s = start + t
    if s >= stop:
        return
    q0 = seg_item[s]
    cnt = seg_count[s]
    r0 = seg_row[s]
    base = t * n_regs * batch
    for i in range(r0, r0 + seg_rows[s]):
        op = pool[i, 0]
        d = base + pool[i, 1] * batch
        if op == OP_X or op == OP_Y or op == OP_Z:
            for p in range(cnt):
                k = items[q0 + p]
                scratch[d + p] = wp.vec2(box_lo[k][op], box_hi[k][op])
            continue
        a = base + wp.max(pool[i, 2], 0) * batch
        b = base + wp.max(pool[i, 3], 0) * batch
        c = pool_imm[i]
        sel = pool[i, 4]
        if sel >= 0 and (op == OP_MIN or op == OP_MAX or op == OP_MINC or op == OP_MAXC):
            two = op == OP_MIN or op == OP_MAX
            for p in range(cnt):  # before the step: dst may be an operand's register
                bv = wp.vec2(c, c)
                if two:
                    bv = scratch[b + p]
                ch = branch_choice(op, scratch[a + p], bv)
                if ch != 0:
                    choices[items[q0 + p], sel] = wp.uint8(ch)
        if op == OP_COPY:
            for p in range(cnt):
                scratch[d + p] = scratch[a + p]
        else:
            interval_step(op, d, a, b, c, cnt, scratch)
    o = base + out_reg * batch
    for p in range(cnt):
        out[items[q0 + p]] = scratch[o + p]
