"""Compile an expression DAG to a flat instruction tape and evaluate it with Warp.

The tape is data, not code: one generic interpreter kernel family
(:mod:`warpmesh.kernels.tape`) runs every tape, so building or editing a shape never
waits on a Warp compile. Common subexpressions are shared (the DAG is hash-consed) and
registers are reused once their last reader has run (linear-scan allocation).

Example
-------
>>> import numpy as np, warpmesh as wm
>>> tape = wm.compile_tape(wm.sphere(1.0))
>>> vals = wm.evaluate(wm.sphere(1.0), np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]]))
>>> np.round(vals, 5).tolist()
[1.0, -1.0]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warpmesh._util.validate import check_device
from warpmesh.frep.codegen import EVALUATORS, Evaluator, generated_kernel
from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh.frep.expr import Expr, Param, check_values, last_uses, origin
from warpmesh.frep.shapes import as_shape
from warpmesh.kernels import opcodes as O
from warpmesh.kernels import tape as K

BATCH = 256  # points per interpreter thread (column-wise evaluation)
CHUNK_POINTS = {True: 1 << 18, False: 1 << 20}  # points per launch, CPU / GPU (bounds the scratch)


@dataclass
class Tape:
    """A compiled shape: ``code`` (n, 4) int32 rows (op, dst, a, b), ``imm`` (n,) float32.

    ``params`` maps each parameter's name (:func:`warpmesh.param`) to its CONST row: its
    value is ``imm[row]``. :meth:`with_values` makes the tape of other values, sharing
    ``code`` (so the interpreter and a generated kernel of the structure both run it at once).

    Example
    -------
    >>> import warpmesh as wm
    >>> tape = wm.compile_tape(wm.sphere(wm.param("r", 0.5, lo=0.1, hi=1.0)))
    >>> edited = tape.with_values({"r": 0.75})
    >>> edited.code is tape.code, float(edited.imm[edited.params["r"]]), float(tape.imm[tape.params["r"]])
    (True, 0.75, 0.5)
    """

    code: np.ndarray
    imm: np.ndarray
    n_registers: int
    output: int
    _device_cache: dict = field(default_factory=dict, repr=False)
    params: dict = field(default_factory=dict)  # name -> row of its CONST instruction
    param_nodes: dict = field(default_factory=dict, repr=False)  # name -> Param: its [lo, hi]

    def __len__(self) -> int:
        return len(self.code)

    def values(self) -> dict[str, float]:
        """The current parameter values, by name (float32, as the kernels read them)."""
        return {name: float(self.imm[row]) for name, row in self.params.items()}

    def with_values(self, values) -> "Tape":
        """The same tape with new parameter values: ``code`` shared, ``imm`` copied.

        Parameters
        ----------
        values : mapping of str to float
            New values of some parameters; each within its [lo, hi].

        Raises
        ------
        ValueError
            An unknown name or a value outside the parameter's range.
        """
        checked = check_values(self.param_nodes, values)
        imm = self.imm.copy()
        for name, v in checked.items():
            imm[self.params[name]] = v
        return Tape(self.code, imm, self.n_registers, self.output, params=self.params,
                    param_nodes=self.param_nodes)

    def arrays(self, device="cpu"):
        """(code, imm) as Warp arrays on ``device``, uploaded once per device."""
        key = str(device)
        if key not in self._device_cache:
            self._device_cache[key] = (
                wp.array(self.code, dtype=wp.int32, device=device),
                wp.array(self.imm, dtype=wp.float32, device=device),
            )
        return self._device_cache[key]

    def describe(self) -> str:
        """A human-readable listing, one instruction a line."""
        lines = []
        for (op, d, a, b), c in zip(self.code.tolist(), self.imm.tolist()):
            args = ", ".join(f"r{r}" for r in (a, b) if r >= 0)
            imm = f" {c:g}" if op in (O.CONST, O.ADDC, O.MULC, O.RSUBC, O.RDIVC, O.MINC, O.MAXC,
                                      O.POWI, O.POWF) else ""
            lines.append(f"r{d} = {O.NAMES[op]}({args}){imm}")
        return "\n".join(lines)


def compile_tape(shape) -> Tape:
    """Compile a shape or expression to a :class:`Tape`.

    Parameters
    ----------
    shape : Shape or Expr
        The field to compile.

    Returns
    -------
    Tape
    """
    root: Expr = as_shape(shape).field if not isinstance(shape, Expr) else shape
    nodes = root.nodes()
    index, last_use = last_uses(nodes)
    last_use[-1] = len(nodes)  # the output lives to the end

    params: dict[str, int] = {}
    param_nodes: dict[str, Param] = {}
    reg_of: dict[int, int] = {}
    free: list[int] = []
    n_regs = 0
    code = np.empty((len(nodes), 4), np.int32)
    imm = np.empty(len(nodes), np.float32)
    for i, n in enumerate(nodes):
        srcs = [reg_of[id(a)] for a in n.args] + [-1] * (2 - len(n.args))
        for a in n.args:  # release operands whose last reader is this instruction
            if last_use[index[id(a)]] == i and reg_of[id(a)] not in free:
                free.append(reg_of[id(a)])
        if free:
            dst = free.pop()
        else:
            dst, n_regs = n_regs, n_regs + 1
        reg_of[id(n)] = dst
        code[i] = (n.op, dst, srcs[0], srcs[1])
        imm[i] = n.imm
        if isinstance(n, Param):
            if n.name in params:
                raise ValueError(f"two different parameters are named {n.name!r} ({param_nodes[n.name]!r} "
                                 f"and {n!r}); give each parameter one wm.param(...) and reuse it")
            params[n.name], param_nodes[n.name] = i, n
    return Tape(code, imm, max(n_regs, 1), reg_of[id(root)], params=params, param_nodes=param_nodes)


_TAPE_CACHE: dict[int, tuple] = {}


def tape_of(shape) -> Tape:
    """Compile once per expression object (expressions are immutable and hash-consed).

    An expression bound to new parameter values (:meth:`Expr.with_params`) gets the tape
    of the expression it was bound from with other constants: ``code`` shared, no compile.
    """
    root = shape if isinstance(shape, Expr) else as_shape(shape).field
    hit = _TAPE_CACHE.get(id(root))
    if hit is not None and hit[0] is root:
        return hit[1]
    bound = origin(root)
    if bound is not None:  # new parameter values of a known structure: data only, no compile
        tape = tape_of(bound[0]).with_values(bound[1])
    else:
        tape = compile_tape(root)
    if len(_TAPE_CACHE) > 64:
        _TAPE_CACHE.clear()
    _TAPE_CACHE[id(root)] = (root, tape)
    return tape


# -- launching ---------------------------------------------------------------------------
def _eval(tape: Tape, kernel, inputs: list, n: int, out: wp.array, dtype, device) -> None:
    """Launch an interpreter kernel over n items in chunks (bounded scratch), split
    across CPU cores; ``inputs`` are the kernel's per-item arrays."""
    code, imm = tape.arrays(device)
    if n == 0:
        return
    wp.load_module(K, device=device)  # compile/load once here, not in two worker threads at once
    batch = batch_size(device)

    def job(lo, hi):
        span = min(hi - lo, CHUNK_POINTS[wp.get_device(device).is_cpu])
        n_threads = (span + batch - 1) // batch
        scratch = wp.empty(n_threads * tape.n_registers * batch, dtype=dtype, device=device)
        for start in range(lo, hi, span):
            stop = min(start + span, hi)
            wp.launch(kernel, dim=(stop - start + batch - 1) // batch,
                      inputs=[code, imm, tape.n_registers, tape.output, *inputs, start, stop, batch],
                      outputs=[scratch, out], device=device)

    run_parallel([lambda lo=lo, hi=hi: job(lo, hi) for lo, hi in parallel_ranges(n, device)])


def batch_size(device) -> int:
    """Points per interpreter thread: a batch on the CPU (the dispatch is paid once per
    instruction and batch), one point per thread on a GPU (coalesced, many threads)."""
    return BATCH if wp.get_device(device).is_cpu else 1


def eval_values(tape: Tape, points: wp.array, out: wp.array | None = None, device="cpu",
                evaluator: Evaluator = "auto") -> wp.array:
    """f at ``points`` (wp.array of vec3) into ``out`` (wp.array of float32).

    ``evaluator`` picks the interpreter or the kernel generated for the tape's structure
    (:mod:`warpmesh.frep.codegen`); both give the same values.
    """
    if evaluator not in EVALUATORS:
        raise ValueError(f"Unknown evaluator {evaluator!r}. Pick one of {list(EVALUATORS)}")
    n = points.shape[0]
    if out is None:
        out = wp.empty(n, dtype=wp.float32, device=device)
    kernel = generated_kernel(tape, device, evaluator, n) if n else None
    if kernel is None:
        _eval(tape, K.eval_tape_kernel, [points], n, out, wp.float32, device)
        return out
    _, imm = tape.arrays(device)
    batch = batch_size(device)
    run_parallel([lambda lo=lo, hi=hi: wp.launch(kernel, dim=(hi - lo + batch - 1) // batch,
                                                 inputs=[imm, points, lo, hi, batch], outputs=[out],
                                                 device=device)
                  for lo, hi in parallel_ranges(n, device)])
    return out


def eval_gradients(tape: Tape, points: wp.array, out: wp.array | None = None, device="cpu") -> wp.array:
    """(f, df/dx, df/dy, df/dz) at ``points`` (forward-mode, exact) as wp.array of vec4."""
    if out is None:
        out = wp.empty(points.shape[0], dtype=wp.vec4, device=device)
    _eval(tape, K.eval_tape_dual_kernel, [points], points.shape[0], out, wp.vec4, device)
    return out


def eval_intervals(tape: Tape, boxes_lo: wp.array, boxes_hi: wp.array, out: wp.array | None = None,
                   device="cpu") -> wp.array:
    """An interval (lo, hi) enclosing f over each box, as wp.array of vec2.

    Every float32 value :func:`eval_values` gives at a point of the box lies in [lo, hi]
    (bounds may be ±inf, never clamped); (-inf, inf) means f may be NaN in the box (NaN
    propagates, through min and max too). The rules per opcode and what is exact are in
    :mod:`warpmesh.kernels.tape`.
    """
    n = boxes_lo.shape[0]
    if out is None:
        out = wp.empty(n, dtype=wp.vec2, device=device)
    _eval(tape, K.eval_tape_interval_kernel, [boxes_lo, boxes_hi], n, out, wp.vec2, device)
    return out


#: the largest coordinate a float32 evaluation takes (beyond, x * x overflows to infinity)
FLOAT32_REACH = float(np.sqrt(np.finfo(np.float32).max))


def points_array(points, device, name: str = "points") -> wp.array:
    pts = np.asarray(points)
    if pts.dtype.kind not in "iuf":  # (bools became 0/1, complex numbers lost their imaginary part)
        raise TypeError(f"expected real numbers in {name!r}, got {pts.dtype} values")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"expected an (n, 3) array for {name!r}, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError(f"expected finite values in {name!r}, got NaN or infinity")
    if pts.size and float(np.abs(pts).max()) > FLOAT32_REACH:
        raise ValueError(f"expected coordinates within +-{FLOAT32_REACH:.3g} in {name!r} (f is evaluated in "
                         f"float32), got {float(np.abs(pts).max()):.3g}")
    return wp.array(np.ascontiguousarray(pts, dtype=np.float32), dtype=wp.vec3, device=device)


def evaluate(shape, points, *, gradient: bool = False, device: str = "cpu",
             evaluator: Evaluator = "auto") -> np.ndarray:
    """Evaluate a shape at points with the Warp tape interpreter.

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 3) array_like
    gradient : bool
        Also return the exact gradient (forward mode).
    device : str
        Warp device, "cpu" (default) or "cuda".
    evaluator : {'auto', 'interpreter', 'compiled'}
        Values only: the tape interpreter, or a kernel generated for the shape's structure
        (:mod:`warpmesh.frep.codegen`; "auto" uses it once compiled, never waiting for it).

    Returns
    -------
    (n,) float32 array, or (n, 4) array of (f, fx, fy, fz) when ``gradient``.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> fg = wm.evaluate(wm.sphere(2.0), np.array([[0.0, 0.0, 1.0]]), gradient=True)
    >>> (fg + 0.0).round(3).tolist()  # f = 1, grad f = (0, 0, -1); + 0.0 folds -0.0
    [[1.0, 0.0, 0.0, -1.0]]
    """
    tape = tape_of(shape)
    device = check_device(device)
    if not isinstance(gradient, (bool, np.bool_)):
        raise TypeError(f"expected True or False for 'gradient', got {gradient!r}")
    pts = points_array(points, device)
    if gradient:
        if evaluator != "auto":
            raise ValueError("'evaluator' applies to values; gradients always use the interpreter")
        return eval_gradients(tape, pts, device=device).numpy()
    return eval_values(tape, pts, device=device, evaluator=evaluator).numpy()


def evaluate_interval(shape, lo, hi, *, device: str = "cpu") -> np.ndarray:
    """Intervals (m, 2) enclosing f over boxes [lo_i, hi_i] (each (m, 3)); for one box
    given as two points (3,), its interval (2,).

    Each interval holds every value :func:`evaluate` gives in its box (float32, no
    tolerance needed); a bound may be ±inf, and (-inf, inf) says that f may be NaN
    somewhere in the box (``log`` of a negative, ``0 / 0``, ...: NaN propagates, through
    ``wm.min`` and ``wm.max`` too).

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> x, y, z = wm.coords()
    >>> wm.evaluate_interval(wm.log(x), np.array([[-1.0, 0, 0]]), np.array([[1.0, 0, 0]])).tolist()
    [[-inf, inf]]
    >>> wm.evaluate_interval(x + y, (0, 0, 0), (1, 2, 3)).tolist()
    [0.0, 3.0]
    """
    tape = tape_of(shape)
    device = check_device(device)
    lo_, hi_ = np.asarray(lo), np.asarray(hi)
    for name, a in (("lo", lo_), ("hi", hi_)):
        if a.shape != (3,) and (a.ndim != 2 or a.shape[1] != 3):
            raise ValueError(f"expected a point (3,) or an (n, 3) array for {name!r}, got shape {a.shape}")
    one = lo_.shape == (3,) and hi_.shape == (3,)
    lo_, hi_ = np.atleast_2d(lo_), np.atleast_2d(hi_)
    blo, bhi = points_array(lo_, device, "lo"), points_array(hi_, device, "hi")
    if blo.shape != bhi.shape:
        raise ValueError(f"expected 'lo' and 'hi' of one shape, got {blo.shape} and {bhi.shape}")
    if np.any(lo_ > hi_):
        raise ValueError("expected 'lo' <= 'hi' for every box")
    out = eval_intervals(tape, blo, bhi, device=device).numpy()
    return out[0] if one else out


def value_gradient_at(tape: Tape, points: np.ndarray, device="cpu") -> tuple[np.ndarray, np.ndarray]:
    """f and its exact gradient at float64 points, on the host.

    Parameters
    ----------
    tape : Tape
    points : (n, d) float array, d = 2 (evaluated at z = 0) or 3
    device : str

    Returns
    -------
    f : (n,) float64
    grad : (n, d) float64

    Examples
    --------
    >>> import numpy as np, warpmesh as wm
    >>> f, g = value_gradient_at(tape_of(wm.sphere(1.0)), np.array([[2.0, 0.0, 0.0]]))
    >>> float(f[0]), (g.round(6) + 0.0).tolist()
    (-1.0, [[-1.0, 0.0, 0.0]])
    """
    p = np.asarray(points)
    n, d = p.shape
    if n == 0:
        return np.zeros(0), np.zeros((0, d))
    p3 = np.zeros((n, 3), np.float32)
    p3[:, :d] = p
    fg = eval_gradients(tape, wp.array(p3, dtype=wp.vec3, device=device), device=device).numpy()
    fg = fg.astype(np.float64)
    return fg[:, 0], fg[:, 1:1 + d]
