"""Scalar expressions over the coordinates: the hash-consed DAG under every shape.

An :class:`Expr` is an immutable node ``(op, args, imm)``. Nodes are hash-consed, so
two structurally equal expressions are the same object and common subexpressions are
shared for free when the tape is compiled. Arithmetic operators build new nodes and
fold constants.

Example
-------
>>> import warpmesh as wm
>>> x, y, z = wm.coords()
>>> f = (x**2 + y**2 - 4) * (x**2 + z**2 - 4) * (y**2 + z**2 - 4) - 4.0078
>>> round(float(f.eval_numpy(0.0, 0.0, 0.0)), 4)
-68.0078
"""

from __future__ import annotations

import math
import numbers
import weakref

import numpy as np

from warpmesh.kernels import opcodes as O

_TABLE: "weakref.WeakValueDictionary[tuple, Expr]" = weakref.WeakValueDictionary()

#: constants are stored as float32 on the device: larger magnitudes are refused
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: integer exponents are exact in a float32 immediate up to 2**24
MAX_INT_EXPONENT = 2**24

#: numpy semantics of every opcode (the test oracle); a, b arrays, c the immediate
_NUMPY = {
    O.ADD: lambda a, b, c: a + b,
    O.SUB: lambda a, b, c: a - b,
    O.MUL: lambda a, b, c: a * b,
    O.DIV: lambda a, b, c: a / b,
    O.MIN: lambda a, b, c: np.minimum(a, b),
    O.MAX: lambda a, b, c: np.maximum(a, b),
    O.ADDC: lambda a, b, c: a + c,
    O.MULC: lambda a, b, c: a * c,
    O.RSUBC: lambda a, b, c: c - a,
    O.RDIVC: lambda a, b, c: c / a,
    O.MINC: lambda a, b, c: np.minimum(a, c),
    O.MAXC: lambda a, b, c: np.maximum(a, c),
    O.NEG: lambda a, b, c: -a,
    O.ABS: lambda a, b, c: np.abs(a),
    O.SQUARE: lambda a, b, c: a * a,
    O.SQRT: lambda a, b, c: np.sqrt(np.maximum(a, 0.0)),
    O.SIN: lambda a, b, c: np.sin(a),
    O.COS: lambda a, b, c: np.cos(a),
    O.EXP: lambda a, b, c: np.exp(a),
    O.LOG: lambda a, b, c: np.log(a),
    O.POWI: lambda a, b, c: a ** int(c) if c >= 0 else 1.0 / a ** int(-c),
    O.POWF: lambda a, b, c: np.abs(a) ** c,
    O.RUNION: lambda a, b, c: a + b + np.hypot(a, b),
    O.RINTER: lambda a, b, c: a + b - np.hypot(a, b),
}
_UNARY = {O.NEG, O.ABS, O.SQUARE, O.SQRT, O.SIN, O.COS, O.EXP, O.LOG, O.POWI, O.POWF,
          O.ADDC, O.MULC, O.RSUBC, O.RDIVC, O.MINC, O.MAXC}
_LEAVES = {O.X, O.Y, O.Z, O.CONST}


def _node(op: int, args: tuple = (), imm: float = 0.0) -> "Expr":
    imm = float(imm)
    if not math.isfinite(imm) or math.fabs(imm) > FLOAT32_MAX:
        raise ValueError(f"expected a finite constant within float32 range, got {imm!r}")
    if op in _NUMPY and args and all(is_literal(a) for a in args):
        with np.errstate(all="ignore"):
            value = float(_NUMPY[op](*(np.float64(a.imm) for a in args), *([None] * (2 - len(args))), imm))
        if math.isfinite(value):
            return _node(O.CONST, (), value)
    key = (op, tuple(id(a) for a in args), imm + 0.0)
    node = _TABLE.get(key)
    if node is None:
        node = Expr.__new__(Expr)
        node.op, node.args, node.imm = op, args, imm
        _TABLE[key] = node
    return node


def is_literal(node: "Expr") -> bool:
    """A plain constant: folded into its readers' immediates. A :class:`Param` is a
    constant of the tape too (op CONST), but never folded: its value must stay a datum
    of the tape's constant array that an edit can change."""
    return node.op == O.CONST and type(node) is Expr


def as_expr(value) -> "Expr":
    """Convert a number or an :class:`Expr` (or a shape, through its field) to an Expr."""
    if isinstance(value, Expr):
        return value
    field = getattr(value, "field", None)
    if isinstance(field, Expr):
        return field
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return _node(O.CONST, (), float(value))
    raise TypeError(f"expected a number or an expression, got {type(value).__name__}")


def _shape_like(value) -> bool:
    """A Shape (a solid with a ``field`` expression), not an expression itself."""
    return not isinstance(value, Expr) and isinstance(getattr(value, "field", None), Expr)


class Expr:
    """A node of the expression DAG (build with :func:`coords` and operators).

    Arithmetic (``+ - * / **``, with numbers and expressions) builds fields; ``|`` and
    ``&`` (and ``~``) treat an expression as the solid {f > 0}, as a Shape does. Mixed with
    a :class:`~warpmesh.frep.shapes.Shape`, an expression is promoted to a shape, so
    ``expr - shape`` is the boolean difference and ``expr | shape`` the union.

    Examples
    --------
    >>> import warpmesh as wm
    >>> x, y, z = wm.coords()
    >>> ball = 1.0 - (x * x + y * y + z * z)                 # an expression: a field
    >>> type(ball - wm.sphere(0.5, (1, 0, 0))).__name__      # a boolean difference
    'Shape'
    >>> float((ball | (x - 2.0))(2.5, 0, 0)) > 0             # the R-function union
    True
    """

    __slots__ = ("op", "args", "imm", "__weakref__")

    def __init__(self, *a, **k):  # pragma: no cover - construction goes through _node
        raise TypeError("build expressions with warpmesh.coords(), numbers and operators")

    # -- arithmetic ---------------------------------------------------------------
    # Against a Shape (anything with a ``field`` that is not an Expr) every operator returns
    # NotImplemented, so that the Shape's reflected operator answers: ``expr - shape`` is
    # the boolean difference of the two solids, ``expr + shape`` the sum of the fields.
    def __add__(self, other):
        if _shape_like(other):
            return NotImplemented
        o = as_expr(other)
        if is_literal(o):
            return self if o.imm == 0.0 else _node(O.ADDC, (self,), o.imm)
        if is_literal(self):
            return o + self
        return _node(O.ADD, (self, o))

    __radd__ = __add__

    def __sub__(self, other):
        if _shape_like(other):
            return NotImplemented
        o = as_expr(other)
        if is_literal(o):
            return self + (-o.imm)
        if is_literal(self):
            return _node(O.RSUBC, (o,), self.imm)
        return _node(O.SUB, (self, o))

    def __rsub__(self, other):
        if _shape_like(other):
            return NotImplemented
        return as_expr(other) - self

    def __mul__(self, other):
        if _shape_like(other):
            return NotImplemented
        o = as_expr(other)
        if is_literal(o):
            if o.imm == 1.0:
                return self
            return _node(O.MULC, (self,), o.imm)
        if is_literal(self):
            return o * self
        if o is self:
            return _node(O.SQUARE, (self,))
        return _node(O.MUL, (self, o))

    __rmul__ = __mul__

    def __truediv__(self, other):
        if _shape_like(other):
            return NotImplemented
        o = as_expr(other)
        if is_literal(o):
            if o.imm == 0.0:
                raise ZeroDivisionError("division of an expression by the constant 0")
            return self * (1.0 / o.imm)
        if is_literal(self):
            return _node(O.RDIVC, (o,), self.imm)
        return _node(O.DIV, (self, o))

    def __rtruediv__(self, other):
        if _shape_like(other):
            return NotImplemented
        return as_expr(other) / self

    def __neg__(self):
        return _node(O.NEG, (self,))

    # -- booleans: an expression is the solid {f > 0} ------------------------------------
    def __or__(self, other):
        """Union of the solids {self > 0} and {other > 0}: the R-function union [FG eq. 16.17]."""
        if _shape_like(other):
            return NotImplemented  # Shape.__ror__: a Shape union
        return runion(self, other)

    __ror__ = __or__

    def __and__(self, other):
        """Intersection of the solids: the R-function intersection [FG eq. 16.17]."""
        if _shape_like(other):
            return NotImplemented
        return rintersection(self, other)

    __rand__ = __and__

    def __invert__(self):
        """The complement of the domain {f > 0}: the expression -f."""
        return _node(O.NEG, (self,))

    def __pos__(self):
        return self

    def __abs__(self):
        return _node(O.ABS, (self,))

    def __pow__(self, exponent):
        """``a ** c`` for a constant c: an integer c is an exact power (|c| <= 2**24, negative
        allowed); any other c means ``|a| ** c`` (the sign of a is dropped, as real powers of
        negatives are undefined): use it on non-negative quantities."""
        if isinstance(exponent, Param):
            raise TypeError(f"expected a number for the exponent, got the parameter {exponent.name!r}: "
                            "exponents are immediates of the tape's instructions, not editable data")
        if isinstance(exponent, Expr):
            if exponent.op != O.CONST:
                raise TypeError("expected a constant exponent, got an expression of the coordinates")
            exponent = exponent.imm
        if not isinstance(exponent, numbers.Real) or isinstance(exponent, bool):
            raise TypeError(f"expected a real exponent, got {type(exponent).__name__}")
        e = float(exponent)
        if e.is_integer():
            if math.fabs(e) > MAX_INT_EXPONENT:
                raise ValueError(f"expected an integer exponent within ±{MAX_INT_EXPONENT}, got {e:g}")
            if e == 1.0:
                return self
            if e == 2.0:
                return _node(O.SQUARE, (self,))
            if e == 0.0:
                return as_expr(1.0)
            return _node(O.POWI, (self,), e)
        return _node(O.POWF, (self,), e)

    # -- evaluation ---------------------------------------------------------------
    def nodes(self) -> list["Expr"]:
        """Every node of the DAG once, children before parents (topological order)."""
        order, seen, stack = [], set(), [(self, False)]
        while stack:
            node, expanded = stack.pop()
            if expanded:
                order.append(node)
                continue
            if id(node) in seen:
                continue
            seen.add(id(node))
            stack.append((node, True))
            for a in reversed(node.args):
                if id(a) not in seen:
                    stack.append((a, False))
        return order

    def node_values(self, x, y, z=0.0) -> dict[int, np.ndarray]:
        """The float64 value of every node of the DAG, keyed by ``id(node)``."""
        coords = {O.X: np.asarray(x, np.float64), O.Y: np.asarray(y, np.float64),
                  O.Z: np.asarray(z, np.float64)}
        values: dict[int, np.ndarray] = {}
        with np.errstate(all="ignore"):
            for node in self.nodes():
                if node.op in coords:
                    v = coords[node.op]
                elif node.op == O.CONST:
                    v = np.float64(node.imm)
                else:
                    args = [values[id(a)] for a in node.args] + [None] * (2 - len(node.args))
                    v = _NUMPY[node.op](args[0], args[1], node.imm)
                values[id(node)] = v
        return values

    def eval_numpy(self, x, y, z=0.0) -> np.ndarray:
        """Evaluate in float64 with numpy (the test oracle); arguments broadcast.

        Parameters
        ----------
        x, y, z : array_like
            Coordinates; any broadcastable shapes (open grids stay small).

        Returns
        -------
        numpy.ndarray
            f at the broadcast points.
        """
        return np.asarray(self.node_values(x, y, z)[id(self)])

    def __call__(self, x, y, z=0.0):
        return self.eval_numpy(x, y, z)

    def substitute(self, x: "Expr", y: "Expr", z: "Expr") -> "Expr":
        """The expression with the coordinates replaced by the expressions x, y, z."""
        repl = {O.X: as_expr(x), O.Y: as_expr(y), O.Z: as_expr(z)}
        new: dict[int, Expr] = {}
        for node in self.nodes():
            if node.op in repl:
                r = repl[node.op]
            elif not node.args:
                r = node
            else:
                r = _node(node.op, tuple(new[id(a)] for a in node.args), node.imm)
            new[id(node)] = r
        return new[id(self)]

    def __repr__(self):
        return f"<Expr {O.NAMES.get(self.op, self.op)} with {len(self.nodes())} nodes>"

    # -- parameters -----------------------------------------------------------------
    @property
    def params(self) -> dict[str, "Param"]:
        """The parameters (:func:`param`) the expression reads, by name, in the order the
        tape meets them; each with its current value."""
        return collect_params(self)

    def with_params(self, values=None, /, **more) -> "Expr":
        """The same expression with new parameter values (a mapping, or keywords).

        The structure is unchanged, so its tape is the original's with other numbers
        in the constant array (:func:`warpmesh.frep.tape.tape_of` derives it without
        compiling). Raises ValueError for an unknown name or a value outside [lo, hi].
        """
        return bind(self, values, **more)

    def __bool__(self):
        raise TypeError("an expression has no truth value; compare values after evaluating it")


class Param(Expr):
    """A named constant of the tape: build with :func:`param`.

    It is an expression leaf (opcode CONST) whose value sits in the tape's constant
    array; operators never fold it into their immediates, so a new value is a new datum,
    never a new tape structure. Immutable: :meth:`Expr.with_params` binds new values.
    """

    __slots__ = ("name", "lo", "hi")

    @property
    def value(self) -> float:
        """The current value (the tape's constant)."""
        return self.imm

    def check(self, value, argument: str = "params") -> float:
        """``value`` as a float if it is finite and within [lo, hi], else ValueError."""
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise TypeError(f"expected a number for parameter {self.name!r} in {argument!r}, "
                            f"got {type(value).__name__}")
        v = float(value)
        if not (math.isfinite(v) and self.lo <= v <= self.hi):
            raise ValueError(f"expected a value in [{self.lo:g}, {self.hi:g}] for parameter {self.name!r} "
                             f"in {argument!r}, got {value!r}")
        return v

    def __repr__(self):
        return f"<Param {self.name} = {self.imm:g} in [{self.lo:g}, {self.hi:g}]>"


def param(name: str, value: float, *, lo: float | None = None, hi: float | None = None) -> Param:
    """A named shape parameter: a constant usable wherever a shape or expression takes a number.

    Its value lives in the compiled tape's constant array (:class:`~warpmesh.frep.tape.Tape`),
    so editing it (``shape.with_params(r=0.15)``, ``mesh_surface(..., params={"r": 0.15})``,
    :class:`warpmesh.Preview`) changes data only: no new tape, no Warp compile, the
    compiled evaluator of the structure reused. Interval evaluation and pruning read the
    same array, so they are sound for the current values. Constructors that need a number
    on the host check the whole range [lo, hi] (a radius parameter needs lo > 0, a torus
    needs hi(minor) < lo(major)); exponents, rotation axes, matrices and normals stay
    numbers. Host-side analyses (the rigorous Lipschitz bound of
    :mod:`warpmesh.frep.lipschitz`, :mod:`warpmesh.frep.geometry`, ``shape.exact``) see the
    values bound on the shape they are given: the current ones, not the range.

    Parameters
    ----------
    name : str
        A Python identifier (it becomes a keyword of ``Preview.update``).
    value : float
        The current (initial) value, finite, within [lo, hi].
    lo, hi : float, optional
        The allowed range (sliders span it); unbounded when omitted.

    Returns
    -------
    Param

    Examples
    --------
    >>> import warpmesh as wm
    >>> r = wm.param("r", 0.5, lo=0.1, hi=1.0)
    >>> ball = wm.sphere(r)
    >>> list(ball.params), float(ball(0, 0, 0))
    (['r'], 0.5)
    >>> float(ball.with_params(r=0.8)(0, 0, 0))
    0.8
    >>> ball.with_params(r=2.0)
    Traceback (most recent call last):
    ...
    ValueError: expected a value in [0.1, 1] for parameter 'r' in 'params', got 2.0
    """
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"expected a Python identifier for 'name', got {name!r}")
    bounds = []
    for arg, v, default in (("lo", lo, -math.inf), ("hi", hi, math.inf)):
        if v is None:
            bounds.append(default)
            continue
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or math.isnan(float(v)):
            raise ValueError(f"expected a number for {arg!r}, got {v!r}")
        bounds.append(float(v))
    lo_, hi_ = bounds
    if lo_ > hi_:
        raise ValueError(f"expected lo <= hi, got lo={lo_:g}, hi={hi_:g}")
    return _param_node(name, _check_value(name, value, lo_, hi_, "value"), lo_, hi_)


def _check_value(name, value, lo, hi, argument) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"expected a number for {argument!r} of parameter {name!r}, got {type(value).__name__}")
    v = float(value)
    if not (math.isfinite(v) and lo <= v <= hi and math.fabs(v) <= FLOAT32_MAX):
        raise ValueError(f"expected a finite value in [{lo:g}, {hi:g}] for {argument!r} of parameter "
                         f"{name!r}, got {value!r}")
    return v


def _param_node(name: str, value: float, lo: float, hi: float) -> Param:
    key = ("param", name, value + 0.0, lo, hi)
    node = _TABLE.get(key)
    if node is None:
        node = Param.__new__(Param)
        node.op, node.args, node.imm = O.CONST, (), value
        node.name, node.lo, node.hi = name, lo, hi
        _TABLE[key] = node
    return node


def collect_params(expr) -> dict[str, Param]:
    """The parameters of an expression (or shape) by name, in topological order.

    Raises ValueError when two different parameters share a name (built by two
    :func:`param` calls with other values or ranges)."""
    out: dict[str, Param] = {}
    for node in as_expr(expr).nodes():
        if isinstance(node, Param):
            seen = out.setdefault(node.name, node)
            if seen is not node:
                raise ValueError(f"two different parameters are named {node.name!r} ({seen!r} and {node!r}); "
                                 "give each parameter one wm.param(...) and reuse it")
    return out


#: bound expression -> (the expression it was bound from, the values): lets the tape
#: compiler derive the bound tape from the original's (same code, other constants)
_ORIGIN: "weakref.WeakKeyDictionary[Expr, tuple[Expr, dict]]" = weakref.WeakKeyDictionary()


def check_values(params: dict[str, Param], values, argument: str = "params") -> dict[str, float]:
    """Validate new values for ``params``: known names, numbers within [lo, hi]."""
    if values is None:
        return {}
    if not hasattr(values, "items"):
        raise TypeError(f"expected a mapping of parameter names to numbers for {argument!r}, "
                        f"got {type(values).__name__}")
    out = {}
    for name, v in values.items():
        if name not in params:
            known = list(params) if params else "none: the shape has no wm.param"
            raise ValueError(f"Unknown parameter {name!r} in {argument!r}. Pick one of {known}")
        out[name] = params[name].check(v, argument)
    return out


def bind(expr, values=None, /, **more) -> Expr:
    """``expr`` with new parameter values (see :meth:`Expr.with_params`)."""
    root = as_expr(expr)
    params = collect_params(root)
    if values is not None and not hasattr(values, "items"):
        check_values(params, values)  # raises the TypeError
    new_values = check_values(params, {**(values or {}), **more})
    if all(params[n].imm == v for n, v in new_values.items()):
        return root
    repl = {id(p): _param_node(n, new_values.get(n, p.imm), p.lo, p.hi) for n, p in params.items()}
    new: dict[int, Expr] = {}
    for node in root.nodes():
        if id(node) in repl:
            r = repl[id(node)]
        elif not node.args:
            r = node
        else:
            r = _node(node.op, tuple(new[id(a)] for a in node.args), node.imm)
        new[id(node)] = r
    out = new[id(root)]
    base = _ORIGIN.get(root, (root, None))[0]
    if out is not base:  # (bound back to the original values: the original itself)
        _ORIGIN[out] = (base, {n: repl[id(p)].imm for n, p in params.items()})
    return out


def origin(expr: Expr) -> tuple[Expr, dict[str, float]] | None:
    """(the expression ``expr`` was bound from, every parameter value), or None."""
    return _ORIGIN.get(expr)


def coords(dim: int = 3) -> tuple[Expr, ...]:
    """The coordinate expressions: ``x, y, z`` (``dim=3``) or ``x, y`` (``dim=2``).

    A field built from ``coords(2)`` does not depend on z: it is a planar shape (an
    implicit curve f(x, y) = 0 bounding a domain f > 0), meshed by
    :func:`warpmesh.mesh_curve` and :func:`warpmesh.mesh_domain`.

    Example
    -------
    >>> import warpmesh as wm
    >>> x, y, z = wm.coords()
    >>> sphere = 1 - wm.sqrt(x**2 + y**2 + z**2)
    >>> x, y = wm.coords(2)
    >>> lemniscate = 2 * (x**2 - y**2) - (x**2 + y**2) ** 2
    """
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"expected dim 2 or 3 for 'dim', got {dim!r}")
    xyz = _node(O.X), _node(O.Y), _node(O.Z)
    return xyz[:dim]


def last_uses(nodes: list["Expr"]) -> tuple[dict[int, int], np.ndarray]:
    """For nodes in topological order (:meth:`Expr.nodes`): the position of each node
    (keyed by ``id``) and, per position, the position of the last node reading it (its
    own position when nothing reads it)."""
    index = {id(n): i for i, n in enumerate(nodes)}
    last = np.arange(len(nodes))
    for i, n in enumerate(nodes):  # a loop over expression nodes, not points
        for a in n.args:
            last[index[id(a)]] = i
    return index, last


def depends_on(expr: "Expr", axis: int) -> bool:
    """Whether ``expr`` reads coordinate ``axis`` (0, 1, 2 for x, y, z)."""
    op = (O.X, O.Y, O.Z)[axis]
    return any(n.op == op for n in as_expr(expr).nodes())


def sqrt(a) -> Expr:
    """Square root (of max(a, 0)): 0 for a negative a, NaN for a NaN a."""
    return _node(O.SQRT, (as_expr(a),))


def abs(a) -> Expr:  # noqa: A001 - mirrors numpy's name on purpose
    """Absolute value."""
    return _node(O.ABS, (as_expr(a),))


def _fold2(op: int, opc: int, a, b) -> Expr:
    ea, eb = as_expr(a), as_expr(b)
    if is_literal(ea) and not is_literal(eb):
        ea, eb = eb, ea
    if is_literal(eb):
        return _node(opc, (ea,), eb.imm)
    return _node(op, (ea, eb))


def min(a, b, *more) -> Expr:  # noqa: A001
    """Pointwise minimum of two or more expressions; NaN where any of them is NaN (as
    ``numpy.minimum``; every evaluator and interval follows this rule)."""
    out = _fold2(O.MIN, O.MINC, a, b)
    for m in more:
        out = _fold2(O.MIN, O.MINC, out, m)
    return out


def max(a, b, *more) -> Expr:  # noqa: A001
    """Pointwise maximum of two or more expressions; NaN where any of them is NaN (as
    ``numpy.maximum``)."""
    out = _fold2(O.MAX, O.MAXC, a, b)
    for m in more:
        out = _fold2(O.MAX, O.MAXC, out, m)
    return out


def sin(a) -> Expr:
    """Sine."""
    return _node(O.SIN, (as_expr(a),))


def cos(a) -> Expr:
    """Cosine."""
    return _node(O.COS, (as_expr(a),))


def exp(a) -> Expr:
    """Exponential."""
    return _node(O.EXP, (as_expr(a),))


def log(a) -> Expr:
    """Natural logarithm (of a positive argument; NaN for a negative one, which meshing
    reports as an error)."""
    return _node(O.LOG, (as_expr(a),))


def runion(a, b) -> Expr:
    """R-function union ``a + b + sqrt(a² + b²)`` [FG eq. 16.17]: > 0 where a > 0 or b > 0."""
    return _node(O.RUNION, (as_expr(a), as_expr(b)))


def rintersection(a, b) -> Expr:
    """R-function intersection ``a + b - sqrt(a² + b²)``: > 0 where a > 0 and b > 0."""
    return _node(O.RINTER, (as_expr(a), as_expr(b)))
