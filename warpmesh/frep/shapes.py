"""F-Rep shapes [FG §16.5.1]: primitives, booleans and transforms over :mod:`warpmesh.frep.expr`.

A :class:`Shape` wraps one scalar field ``f`` (an :class:`~warpmesh.frep.expr.Expr`) with
the sign convention f > 0 inside, f = 0 on the boundary, f < 0 outside. Shapes combine
with ``|`` (union), ``&`` (intersection), ``-`` (difference) and ``~`` (complement);
by default with the R-functions of eq. 16.17, or with ``method="minmax"`` / ``"smooth"``
through :func:`union`, :func:`intersection`, :func:`difference`. Transforms chain:
``sphere(1).translate((1, 0, 0)).scale(2)``.

Each primitive says whether its field is a true signed distance ("exact") or only has
the right sign and a gradient norm at most 1 ("bound").

Parameters (:func:`warpmesh.param`) go wherever a primitive, boolean or transform takes
a number, except the exponents of :func:`superquadric` / :func:`supertorus`, the axis and
matrix arguments of ``rotate``, ``mirror`` and ``affine``, and a halfspace's normal
(constants of the structure). A positive argument (radius, size, scale factor, blend
``k``) needs a parameter range with lo > 0; torus radii need hi(minor) < lo(major).

Example
-------
>>> import warpmesh as wm
>>> holes = [wm.cylinder(0.2).translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
>>> part = (wm.box((2, 2, 0.6)) - wm.union(*holes)) | wm.sphere(0.5)
>>> bool(part.eval_numpy(0.0, 0.0, 0.45) > 0), bool(part.eval_numpy(0.6, 0.6, 0.0) > 0)
(True, False)
"""

from __future__ import annotations

import functools

import math
import numbers
from typing import Literal

import numpy as np

from warpmesh.frep import expr as E
from warpmesh.frep.expr import Expr, Param, as_expr

BooleanMethod = Literal["rfunction", "minmax", "smooth"]
_METHODS = ("rfunction", "minmax", "smooth")
_AXES = {"x": 0, "y": 1, "z": 2}


def _has_param(value) -> bool:
    if isinstance(value, Param):
        return True
    return isinstance(value, (list, tuple, np.ndarray)) and any(isinstance(v, Param) for v in np.ravel(
        np.asarray(value, dtype=object)))


def _vector(value, name: str, n: int, *, positive: bool = False, fill: float | str | None = None,
            params: bool = True) -> np.ndarray:
    """n floats from a number or n values; for n = 3 with a ``fill``, also from 2 values (a
    planar shape's x, y) completed with it ("min": the smaller of the two, so a 2D scale
    stays isotropic). With parameters among the values (``params=True``), an object array
    of floats and :class:`~warpmesh.frep.expr.Param` ("min" fill: the smallest
    expression)."""
    if _has_param(value):
        if not params:
            raise TypeError(f"expected numbers for {name!r}, got a parameter: {name!r} is a constant of "
                            "the shape's structure (use parameters for sizes, positions and angles)")
        return _param_vector(value, name, n, positive=positive, fill=fill)
    raw = np.asarray(value)
    mixed_bool = isinstance(value, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in value)
    if raw.dtype.kind not in "iuf" or mixed_bool:  # (strings and bools converted without a word: sphere("1"))
        raise TypeError(f"expected numbers for {name!r}, got {value!r}")
    arr = raw.astype(np.float64)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if n == 3 and arr.shape == (2,) and fill is not None:
        arr = np.append(arr, arr.min() if fill == "min" else float(fill))
    if arr.shape != (n,):
        count = "2 or 3" if n == 3 and fill is not None else str(n)
        raise ValueError(f"expected {count} values for '{name}', got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"expected finite values for '{name}', got {arr.tolist()}")
    if positive and np.any(arr <= 0):
        raise ValueError(f"expected positive values for '{name}', got {arr.tolist()}")
    return arr


def _param_vector(value, name: str, n: int, *, positive: bool, fill) -> np.ndarray:
    items = [value] * n if isinstance(value, Param) else list(value)
    if n == 3 and len(items) == 2 and fill is not None:
        items.append(_min_of(items) if fill == "min" else float(fill))
    if len(items) != n:
        count = "2 or 3" if n == 3 and fill is not None else str(n)
        raise ValueError(f"expected {count} values for '{name}', got {len(items)}")
    out = np.empty(n, dtype=object)
    for i, v in enumerate(items):
        if isinstance(v, Expr) and not isinstance(v, Param):
            raise TypeError(f"expected numbers or parameters (wm.param) for {name!r}, got an expression")
        out[i] = _positive(v, name) if positive else _number(v, name)
    return out


def _real(value, name: str) -> float:
    """``value`` as a float when it is a real number (not a bool, a string or None)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.ndarray)) or (
            isinstance(value, np.ndarray) and (value.ndim != 0 or value.dtype.kind not in "iuf")):
        raise TypeError(f"expected a number for {name!r}, got {value!r}")
    return float(value)


def _number(value, name: str):
    """A finite float, or a parameter (kept as an expression leaf)."""
    if isinstance(value, Param):
        return value
    v = _real(value, name)
    if not math.isfinite(v):
        raise ValueError(f"expected a finite '{name}', got {value!r}")
    return v


def _min_of(items):
    """The smallest of numbers and parameters: a float, or an expression."""
    if not any(isinstance(v, Expr) for v in items):
        return float(min(items))
    return E.min(*items) if len(items) > 1 else items[0]


def _vec3(value, name: str, *, positive: bool = False, fill: float | str | None = None,
          params: bool = True) -> np.ndarray:
    return _vector(value, name, 3, positive=positive, fill=fill, params=params)


def _positive(value, name: str):
    """A positive finite float; a parameter whose whole range [lo, hi] is positive."""
    if isinstance(value, Param):
        if not value.lo > 0:
            raise ValueError(f"expected a parameter with lo > 0 for '{name}', got {value!r}: give "
                             f"wm.param({value.name!r}, ...) a positive lower bound")
        return value
    v = _real(value, name)
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"expected a positive finite '{name}', got {value!r}")
    return v


def _literal(value, name: str) -> float:
    """A number that must stay one (an exponent, a count): parameters refused by name."""
    if isinstance(value, Expr):
        what = f"the parameter {value.name!r}" if isinstance(value, Param) else "an expression"
        raise TypeError(f"expected a number for {name!r}, got {what}: {name!r} is a constant of the "
                        "shape's structure")
    return value


def _zero(v) -> bool:
    return not isinstance(v, Expr) and v == 0.0


def _lin(terms, const=0.0):
    """const + sum(coef * value) over numbers and expressions, skipping literal zeros."""
    out = const
    for coef, value in terms:
        if _zero(coef) or _zero(value):
            continue
        prod = value if (not isinstance(coef, Expr) and coef == 1.0) else (
            coef if (not isinstance(value, Expr) and value == 1.0) else coef * value)
        out = prod if _zero(out) else out + prod
    return out


def _axis_index(axis) -> int:
    if axis not in _AXES:
        raise ValueError(f"Unknown axis {axis!r}. Pick one of {list(_AXES)}")
    return _AXES[axis]


class Shape:
    """A solid given by a field f (f > 0 inside). Operations return new shapes.

    Parameters
    ----------
    field : Expr or number
        The defining function.
    exact : bool
        Whether ``field`` is a true signed distance.
    """

    __slots__ = ("field", "exact", "parts")

    def __init__(self, field, exact: bool = False, parts: tuple = ()):
        self.field: Expr = as_expr(field)
        self.exact = bool(exact)
        #: (name, field) of the primitives whose zero sets make up the boundary (booleans
        #: concatenate them, transforms map them); empty: the shape is its own primitive
        self.parts: tuple = tuple(parts)

    @property
    def primitives(self) -> list[tuple[str, "Shape"]]:
        """The primitives whose zero sets make up the boundary, in the order the shape was
        built: (name, shape) pairs. A shape made by arithmetic on fields (an offset, a
        product with an expression) is its own single primitive "field".

        Example
        -------
        >>> import warpmesh as wm
        >>> part = (wm.box((2, 2, 0.6)) - wm.cylinder(0.2)) | wm.sphere(0.5)
        >>> [name for name, _ in part.primitives]
        ['box', 'cylinder', 'sphere']
        """
        parts = self.parts or (("field", self.field),)
        return [(name, Shape(field)) for name, field in parts]

    def _keeping(self, field, exact) -> "Shape":
        """A shape with a new field whose zero set is made of the same primitives."""
        return Shape(field, exact, self.parts)

    # -- evaluation ---------------------------------------------------------------
    def eval_numpy(self, x, y, z=0.0) -> np.ndarray:
        """f at broadcast points, in float64 numpy (the test oracle)."""
        return self.field.eval_numpy(x, y, z)

    __call__ = eval_numpy

    def __repr__(self):
        kind = "signed distance" if self.exact else "bound"
        return f"<Shape {self.dim}D ({kind}) with {len(self.field.nodes())} expression nodes>"

    def _fill(self, value):
        """How a planar shape completes 2-value transform arguments (3D shapes take 3)."""
        return value if self.dim == 2 else None

    # -- parameters -----------------------------------------------------------------
    @property
    def params(self) -> dict:
        """The parameters (:func:`warpmesh.param`) of the shape by name, with their current values.

        Example
        -------
        >>> import warpmesh as wm
        >>> r = wm.param("r", 0.2, lo=0.05, hi=0.28)
        >>> plate = wm.box((2, 2, 0.6)) - wm.cylinder(r)
        >>> plate.params
        {'r': <Param r = 0.2 in [0.05, 0.28]>}
        """
        return self.field.params

    def with_params(self, values=None, /, **more) -> "Shape":
        """The shape with new parameter values (a mapping and/or keywords).

        Same structure, other constants: its tape is the original's with a new constant
        array (no compile). Raises ValueError for an unknown name or a value outside the
        parameter's [lo, hi].

        Example
        -------
        >>> import warpmesh as wm
        >>> ball = wm.sphere(wm.param("r", 0.5, lo=0.1, hi=1.0))
        >>> round(float(ball.with_params(r=0.25)(0, 0, 0)), 6), round(float(ball(0, 0, 0)), 6)
        (0.25, 0.5)
        """
        field = self.field.with_params(values, **more)  # checks the names and ranges
        given = {**dict(values or {}), **more}

        def rebound(f):  # a primitive takes the values of the parameters it holds
            own = {k: v for k, v in given.items() if k in f.params}
            return f.with_params(own) if own else f
        return Shape(field, self.exact, tuple((n, rebound(f)) for n, f in self.parts))

    @property
    def dim(self) -> int:
        """2 for a planar shape (its field does not read z), else 3."""
        return 3 if E.depends_on(self.field, 2) else 2

    # -- booleans (with shapes and expressions) -------------------------------------
    def __or__(self, other):
        return union(self, other)

    def __ror__(self, other):
        return union(other, self)

    def __and__(self, other):
        return intersection(self, other)

    def __rand__(self, other):
        return intersection(other, self)

    def __sub__(self, other):
        """The boolean difference with a shape or an expression; the field minus a number."""
        if _is_number(other):
            return self._offset(-float(other))
        return difference(self, other)

    def __rsub__(self, other):
        """``expr - shape``: the boolean difference; ``c - shape``: the field c - f."""
        if _is_number(other):
            return Shape(float(other) - self.field)
        return difference(other, self)

    def __invert__(self):
        return self._keeping(-self.field, self.exact)

    # -- arithmetic on the field (with numbers and expressions) ------------------------
    def _offset(self, c: float) -> "Shape":
        return Shape(self.field + c, self.exact and c == 0.0)

    def __add__(self, other):
        """The field plus a number (an offset: ``sphere(1) + 0.1`` grows the ball) or an
        expression. Two shapes do not add: use ``|`` for their union."""
        if _is_number(other):
            return self._offset(float(other))
        return Shape(self.field + _field_operand(other, "+"))

    __radd__ = __add__

    def __mul__(self, other):
        """The field times a number or an expression (a positive factor keeps the solid)."""
        if _is_number(other):
            out = Shape(self.field * float(other), self.exact and float(other) == 1.0)
            return self._keeping(out.field, out.exact) if float(other) != 0.0 else out  # same zero set
        return Shape(self.field * _field_operand(other, "*"))

    __rmul__ = __mul__

    def __truediv__(self, other):
        return Shape(self.field / (float(other) if _is_number(other) else _field_operand(other, "/")))

    def __rtruediv__(self, other):
        return Shape((float(other) if _is_number(other) else _field_operand(other, "/")) / self.field)

    # -- transforms (substitute the inverse map into the field) --------------------
    def _mapped(self, lin: np.ndarray, off: np.ndarray, scale, exact: bool) -> "Shape":
        """Shape whose field at p is ``scale * f(lin @ p + off)`` (entries numbers, or
        expressions of parameters)."""
        x, y, z = E.coords()
        c = (x, y, z)
        new = []
        for row, o in zip(lin, off):
            if isinstance(o, Expr) or any(isinstance(v, Expr) for v in row):
                new.append(as_expr(_lin([(v, var) for v, var in zip(row, c)], o)))
                continue
            term = as_expr(float(o))
            for coef, var in zip(row, c):
                if coef != 0.0:
                    term = term + var * float(coef)
            new.append(term)
        field = self.field.substitute(*new)
        parts = tuple((name, f.substitute(*new)) for name, f in self.parts)
        if isinstance(scale, Expr):
            return Shape(field * scale, exact, parts)
        return Shape(field * scale if scale != 1.0 else field, exact, parts)

    def translate(self, offset) -> "Shape":
        """Move by ``offset`` (3 values, or 2 for a planar shape; numbers or parameters).
        Keeps a signed distance exact."""
        t = _vec3(offset, "offset", fill=self._fill(0.0))
        return self._mapped(np.eye(3), -t, 1.0, self.exact)

    def rotate(self, angle: float, axis=(0.0, 0.0, 1.0), about=(0.0, 0.0, 0.0)) -> "Shape":
        """Rotate by ``angle`` radians (a number or a parameter) about the line through
        ``about`` along ``axis``."""
        if isinstance(angle, Param) or _has_param(about):
            return self._rotate_param(angle, axis, about)
        angle = float(angle)
        if not math.isfinite(angle):
            raise ValueError(f"expected a finite 'angle' (radians), got {angle!r}")
        a = _vec3(axis, "axis", params=False) if not isinstance(axis, str) else np.eye(3)[_axis_index(axis)]
        n = np.linalg.norm(a)
        if n == 0:
            raise ValueError("expected a non-zero 'axis', got (0, 0, 0)")
        a = a / n
        c = _vec3(about, "about", fill=self._fill(0.0))
        k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        rot = np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)
        inv = rot.T  # p -> R^T (p - c) + c
        return self._mapped(inv, c - inv @ c, 1.0, self.exact)

    def _rotate_param(self, angle, axis, about) -> "Shape":
        """``rotate`` with parameters: R = I + sin(t) K + (1 - cos(t)) K² as expressions."""
        angle = _number(angle, "angle")
        a = _vec3(axis, "axis", params=False) if not isinstance(axis, str) else np.eye(3)[_axis_index(axis)]
        n = np.linalg.norm(a)
        if n == 0:
            raise ValueError("expected a non-zero 'axis', got (0, 0, 0)")
        a = a / n
        c = _vec3(about, "about", fill=self._fill(0.0))
        k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
        kk = k @ k
        if isinstance(angle, Expr):
            sin_t, one_cos = E.sin(angle), 1.0 - E.cos(angle)
        else:
            sin_t, one_cos = math.sin(angle), 1.0 - math.cos(angle)
        # inv = R^T: entry (i, j) = I[j, i] + sin K[j, i] + (1 - cos) KK[j, i]
        inv = [[_lin([(float(k[j, i]), sin_t), (float(kk[j, i]), one_cos)], float(i == j)) for j in range(3)]
               for i in range(3)]
        off = [_lin([(-1.0, _lin([(inv[i][j], c[j]) for j in range(3)]))], c[i]) for i in range(3)]
        return self._mapped(inv, off, 1.0, self.exact)

    def scale(self, factor, about=(0.0, 0.0, 0.0)) -> "Shape":
        """Scale by a number (keeps a distance exact) or by 3 factors (a bound only);
        numbers or parameters (a parameter factor needs lo > 0)."""
        if _has_param(factor) or _has_param(about):
            s = _vec3(factor, "factor", positive=True, fill=self._fill("min"))
            c = _vec3(about, "about", fill=self._fill(0.0))
            inv = [[(1.0 / s[i] if i == j else 0.0) for j in range(3)] for i in range(3)]
            off = [_lin([(-1.0, inv[i][i] * c[i] if not (_zero(c[i])) else 0.0)], c[i]) for i in range(3)]
            iso = all(v is s[0] for v in s)
            return self._mapped(inv, off, _min_of(list(s)) if not iso else s[0], self.exact and iso)
        s = _vec3(factor, "factor", positive=True, fill=self._fill("min"))
        c = _vec3(about, "about", fill=self._fill(0.0))
        inv = np.diag(1.0 / s)
        iso = bool(np.all(s == s[0]))
        return self._mapped(inv, c - inv @ c, float(s.min()), self.exact and iso)

    def mirror(self, normal=(1.0, 0.0, 0.0), point=(0.0, 0.0, 0.0)) -> "Shape":
        """Reflect through the plane with ``normal`` through ``point``."""
        nrm = _vec3(normal, "normal", fill=self._fill(0.0), params=False)
        if not np.any(nrm):
            raise ValueError("expected a non-zero 'normal', got (0, 0, 0)")
        nrm = nrm / np.linalg.norm(nrm)
        h = np.eye(3) - 2.0 * np.outer(nrm, nrm)
        c = _vec3(point, "point", fill=self._fill(0.0))
        if c.dtype == object:
            off = [_lin([(-float(h[i, j]), c[j]) for j in range(3)], c[i]) for i in range(3)]
            return self._mapped(h, off, 1.0, self.exact)
        return self._mapped(h, c - h @ c, 1.0, self.exact)

    def affine(self, matrix, offset=(0.0, 0.0, 0.0)) -> "Shape":
        """Apply p -> matrix @ p + offset (matrix 3x3 invertible, or 4x4 homogeneous).

        The field is scaled by the smallest singular value of ``matrix`` so its gradient
        norm stays at most that of the original (a bound, exact only for similarities).
        """
        m = np.asarray(matrix, dtype=np.float64)
        if m.shape == (4, 4):
            if not np.allclose(m[3], (0.0, 0.0, 0.0, 1.0)):
                raise ValueError(f"expected a 4x4 'matrix' with last row (0, 0, 0, 1), got {m[3].tolist()}")
            if np.any(np.asarray(offset, dtype=np.float64) != 0.0):
                raise ValueError("expected either a 4x4 'matrix' or an 'offset', got both")
            m, offset = m[:3, :3], m[:3, 3]
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise ValueError(f"expected a finite 3x3 or 4x4 'matrix', got shape {m.shape}")
        sv = np.linalg.svd(m, compute_uv=False)
        if sv.min() <= 1e-12 * max(sv.max(), 1e-300):
            raise ValueError("expected an invertible 'matrix', got a singular one")
        t = _vec3(offset, "offset", params=False)
        inv = np.linalg.inv(m)
        similar = bool(np.isclose(sv.min(), sv.max()))
        return self._mapped(inv, -inv @ t, float(sv.min()), self.exact and similar)


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _field_operand(value, op: str) -> Expr:
    """An expression to combine arithmetically with a shape's field (never another shape)."""
    if isinstance(value, Shape):
        hint = {"+": "'|' for the union"}.get(op, "the fields: a.field {} b.field".format(op))
        raise TypeError(f"expected a number or an expression on the other side of '{op}' with a Shape, "
                        f"got a Shape: use {hint}")
    return as_expr(value)


def as_shape(value) -> Shape:
    """A :class:`Shape` from a shape, an expression or a number."""
    if isinstance(value, Shape):
        return value
    if isinstance(value, Expr):
        return Shape(value)
    raise TypeError(f"expected a Shape or an expression, got {type(value).__name__}")


# -- booleans ------------------------------------------------------------------------
def _check_method(method, k):
    if method not in _METHODS:
        raise ValueError(f"Unknown boolean method {method!r}. Pick one of {list(_METHODS)}")
    if method == "smooth":
        _positive(k, "k")


def _smooth_max(a: Expr, b: Expr, k: float) -> Expr:
    # polynomial smooth maximum: max(a, b) + k/4 * h^2, h = max(k - |a - b|, 0) / k
    h = E.max(k - abs(a - b), 0.0) * (1.0 / k)
    return E.max(a, b) + h * h * (k / 4.0)


def _combine(shapes, method, k, is_union: bool) -> Shape:
    if len(shapes) == 0:
        raise ValueError("expected at least one shape, got none")
    _check_method(method, k)
    fields = [as_shape(s).field for s in shapes]
    out = fields[0]
    for f in fields[1:]:
        if method == "rfunction":
            out = E.runion(out, f) if is_union else E.rintersection(out, f)
        elif method == "minmax":
            out = E.max(out, f) if is_union else E.min(out, f)
        else:
            out = _smooth_max(out, f, k) if is_union else -_smooth_max(-out, -f, k)
    exact = len(shapes) == 1 and as_shape(shapes[0]).exact
    parts = tuple(p for sh in shapes for p in (as_shape(sh).parts or (("field", as_shape(sh).field),)))
    return Shape(out, exact, parts)


def union(*shapes, method: BooleanMethod = "rfunction", k: float = 0.1) -> Shape:
    """Union of shapes (f > 0 where any is inside).

    Parameters
    ----------
    *shapes : Shape
        One or more shapes.
    method : {'rfunction', 'minmax', 'smooth'}
        R-function of eq. 16.17 (default, C¹ away from the shapes' common boundary),
        ``max`` of the fields, or a polynomial smooth maximum with blend radius ``k``.
    """
    return _combine(shapes, method, k, True)


def intersection(*shapes, method: BooleanMethod = "rfunction", k: float = 0.1) -> Shape:
    """Intersection of shapes (f > 0 where all are inside); options as :func:`union`."""
    return _combine(shapes, method, k, False)


def difference(a, *others, method: BooleanMethod = "rfunction", k: float = 0.1) -> Shape:
    """``a`` minus the union of ``others``; options as :func:`union`."""
    if not others:
        _check_method(method, k)
        return as_shape(a)
    cut = union(*others, method=method, k=k)
    return intersection(a, ~cut, method=method, k=k)


def complement(a) -> Shape:
    """Everything outside ``a`` (f -> -f)."""
    return ~as_shape(a)


# -- primitives ------------------------------------------------------------------------
def _primitive(fn):
    """Mark what ``fn`` returns as one primitive named after ``fn`` (``Shape.primitives``)."""
    @functools.wraps(fn)
    def make(*args, **kwargs) -> Shape:
        shape = fn(*args, **kwargs)
        return Shape(shape.field, shape.exact, ((fn.__name__, shape.field),))
    return make

def _frame(axis: str):
    """(u, v, w) coordinate expressions with w along ``axis``."""
    x, y, z = E.coords()
    i = _axis_index(axis)
    return [(y, z, x), (z, x, y), (x, y, z)][i]


def _centered(shape: Shape, center) -> Shape:
    c = _vec3(center, "center")
    return shape.translate(c) if any(not _zero(v) for v in c) else shape


@_primitive
def sphere(radius: float = 1.0, center=(0.0, 0.0, 0.0)) -> Shape:
    """Ball of ``radius`` (exact): f = r - |p - c|."""
    r = _positive(radius, "radius")
    x, y, z = E.coords()
    return _centered(Shape(r - E.sqrt(x * x + y * y + z * z), True), center)


@_primitive
def box(size=(1.0, 1.0, 1.0), center=(0.0, 0.0, 0.0)) -> Shape:
    """Axis-aligned box with edge lengths ``size`` (exact signed distance)."""
    h = _vec3(size, "size", positive=True) / 2.0
    x, y, z = E.coords()
    q = [abs(x) - h[0], abs(y) - h[1], abs(z) - h[2]]
    outside = E.sqrt(sum(E.max(qi, 0.0) ** 2 for qi in q))
    inside = E.min(E.max(*q), 0.0)
    return _centered(Shape(-(outside + inside), True), center)


@_primitive
def cylinder(radius: float = 1.0, height: float | None = None, axis: str = "z",
             center=(0.0, 0.0, 0.0)) -> Shape:
    """Cylinder of ``radius`` along ``axis``; infinite when ``height`` is None (exact)."""
    r = _positive(radius, "radius")
    u, v, w = _frame(axis)
    rho = E.sqrt(u * u + v * v)
    if height is None:
        return _centered(Shape(r - rho, True), center)
    hh = _positive(height, "height") / 2.0
    d0, d1 = rho - r, abs(w) - hh
    f = -(E.min(E.max(d0, d1), 0.0) + E.sqrt(E.max(d0, 0.0) ** 2 + E.max(d1, 0.0) ** 2))
    return _centered(Shape(f, True), center)


@_primitive
def cone(radius: float = 1.0, height: float = 1.0, axis: str = "z", center=(0.0, 0.0, 0.0)) -> Shape:
    """Solid cone: base disk of ``radius`` at w = 0, apex at w = ``height`` (a bound:
    the distance to the side and to the base plane, combined with min)."""
    r, hgt = _positive(radius, "radius"), _positive(height, "height")
    u, v, w = _frame(axis)
    if isinstance(r, Expr) or isinstance(hgt, Expr):
        cos_t = hgt / E.sqrt(as_expr(r) * r + as_expr(hgt) * hgt)
    else:
        cos_t = hgt / math.hypot(r, hgt)
    side = ((hgt - w) * (r / hgt) - E.sqrt(u * u + v * v)) * cos_t
    return _centered(Shape(E.min(side, w), False), center)


def _check_radii(small, big) -> None:
    """minor < major, over the whole ranges of parameters."""
    hi_small = small.hi if isinstance(small, Param) else small
    lo_big = big.lo if isinstance(big, Param) else big
    if hi_small >= lo_big:
        raise ValueError(f"expected minor < major (for every parameter value), got minor={small!r}, major={big!r}")


@_primitive
def torus(major: float = 1.0, minor: float = 0.25, axis: str = "z", center=(0.0, 0.0, 0.0)) -> Shape:
    """Torus around ``axis`` with radii ``major`` > ``minor`` (exact)."""
    big, small = _positive(major, "major"), _positive(minor, "minor")
    _check_radii(small, big)
    u, v, w = _frame(axis)
    q = E.sqrt(u * u + v * v) - big
    return _centered(Shape(small - E.sqrt(q * q + w * w), True), center)


@_primitive
def ellipsoid(semi_axes=(1.0, 0.5, 0.25), center=(0.0, 0.0, 0.0)) -> Shape:
    """Ellipsoid with ``semi_axes`` (a bound: min(a) * (1 - |p / a|), exact on a sphere)."""
    a = _vec3(semi_axes, "semi_axes", positive=True)
    x, y, z = E.coords()
    rho = E.sqrt((x * (1 / a[0])) ** 2 + (y * (1 / a[1])) ** 2 + (z * (1 / a[2])) ** 2)
    if a.dtype == object:  # parameters: the smallest axis and exactness as expressions / structure
        return _centered(Shape((1.0 - rho) * _min_of(list(a)), all(v is a[0] for v in a)), center)
    return _centered(Shape((1.0 - rho) * float(a.min()), bool(np.all(a == a[0]))), center)


@_primitive
def halfspace(normal=(0.0, 0.0, 1.0), point=(0.0, 0.0, 0.0)) -> Shape:
    """Half-space behind the plane through ``point`` with outward ``normal`` (exact)."""
    n = _vec3(normal, "normal", params=False)
    if not np.any(n):
        raise ValueError("expected a non-zero 'normal', got (0, 0, 0)")
    n = n / np.linalg.norm(n)
    p = _vec3(point, "point")
    x, y, z = E.coords()
    level = _lin([(float(n[i]), p[i]) for i in range(3)]) if p.dtype == object else float(n @ p)
    return Shape(level - (x * n[0] + y * n[1] + z * n[2]), True)


@_primitive
def capsule(a=(0.0, 0.0, -0.5), b=(0.0, 0.0, 0.5), radius: float = 0.25) -> Shape:
    """Points within ``radius`` of the segment ab (exact)."""
    pa, pb = _vec3(a, "a"), _vec3(b, "b")
    r = _positive(radius, "radius")
    ba = pb - pa
    if pa.dtype == object or pb.dtype == object:  # parameters: ba and |ba|² as expressions
        ll = _lin([(v, v) for v in ba])
        if not isinstance(ll, Expr) and ll == 0:
            raise ValueError("expected distinct end points 'a' and 'b'")
        x, y, z = E.coords()
        d = [x - pa[0], y - pa[1], z - pa[2]]
        t = E.min(E.max(_lin([(d[i], ba[i]) for i in range(3)]) * (1.0 / ll), 0.0), 1.0)
        q = [d[i] - _lin([(t, ba[i])]) for i in range(3)]
        return Shape(r - E.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2), True)
    ll = float(ba @ ba)
    if ll == 0:
        raise ValueError("expected distinct end points 'a' and 'b'")
    x, y, z = E.coords()
    d = [x - pa[0], y - pa[1], z - pa[2]]
    t = E.min(E.max((d[0] * ba[0] + d[1] * ba[1] + d[2] * ba[2]) * (1.0 / ll), 0.0), 1.0)
    q = [d[i] - t * ba[i] for i in range(3)]
    return Shape(r - E.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2), True)


@_primitive
def superquadric(semi_axes=(1.0, 1.0, 1.0), e1: float = 0.5, e2: float = 0.5,
                 center=(0.0, 0.0, 0.0)) -> Shape:
    """Barr's superellipsoid with shape exponents ``e1`` (along z) and ``e2`` (in xy).

    f = min(a) * (1 - F^(e1/2)), F = (|x/a|^(2/e2) + |y/b|^(2/e2))^(e2/e1) + |z/c|^(2/e1);
    homogeneous of degree one; e1 = e2 = 1 with equal axes is the exact sphere. A bound
    (|∇f| ≤ 1) for e1, e2 ≤ 1; for larger exponents only the sign is meaningful (the
    gradient grows towards sqrt(3) at e = 2 and is unbounded near the axes for e > 2).
    """
    a = _vec3(semi_axes, "semi_axes", positive=True)
    e1, e2 = _positive(_literal(e1, "e1"), "e1"), _positive(_literal(e2, "e2"), "e2")
    x, y, z = E.coords()
    xy = (abs(x * (1 / a[0])) ** (2 / e2) + abs(y * (1 / a[1])) ** (2 / e2)) ** (e2 / e1)
    big_f = xy + abs(z * (1 / a[2])) ** (2 / e1)
    return _centered(Shape((1.0 - big_f ** (e1 / 2)) * _min_of(list(a))), center)


@_primitive
def supertorus(major: float = 1.0, minor: float = 0.3, e1: float = 0.5, e2: float = 0.5,
               axis: str = "z", center=(0.0, 0.0, 0.0)) -> Shape:
    """Supertoroid [FG Fig. 16.22]: a torus whose section (``e1``) and sweep (``e2``)
    are superellipses. e1 = e2 = 1 gives the exact torus; a bound (|∇f| ≤ 1) for
    e1, e2 ≤ 1; for larger exponents only the sign is meaningful."""
    big, small = _positive(major, "major"), _positive(minor, "minor")
    _check_radii(small, big)
    e1, e2 = _positive(_literal(e1, "e1"), "e1"), _positive(_literal(e2, "e2"), "e2")
    u, v, w = _frame(axis)
    rho = (abs(u) ** (2 / e2) + abs(v) ** (2 / e2)) ** (e2 / 2)
    big_f = abs((rho - big) * (1 / small)) ** (2 / e1) + abs(w * (1 / small)) ** (2 / e1)
    exact = e1 == 1.0 and e2 == 1.0
    return _centered(Shape((1.0 - big_f ** (e1 / 2)) * small, exact), center)
