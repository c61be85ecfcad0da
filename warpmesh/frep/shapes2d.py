"""Planar F-Rep shapes: primitives in x, y and the bundled 2D examples.

A planar shape is a :class:`~warpmesh.frep.shapes.Shape` whose field does not read z
(``shape.dim == 2``): the same booleans (``|``, ``&``, ``-``, ``~``, R-functions by
default) and transforms (``translate((dx, dy))``, ``rotate(angle)`` about the z axis,
``scale``, ``mirror((nx, ny))``) apply. Its zero set is an implicit curve [FG §16.1.2],
meshed by :func:`warpmesh.mesh_curve`; the domain f > 0 is meshed by
:func:`warpmesh.mesh_domain`.

Example
-------
>>> import warpmesh as wm
>>> plate = wm.rectangle((2.0, 1.0)) - wm.circle(0.3)
>>> plate.dim, bool(plate.eval_numpy(0.8, 0.0) > 0), bool(plate.eval_numpy(0.0, 0.0) > 0)
(2, True, False)
"""

from __future__ import annotations

import math

import numpy as np

from warpmesh.frep import expr as E
from warpmesh.frep.shapes import Shape, _lin, _min_of, _positive, _primitive, _vector, _zero

__all__ = ["circle", "ellipse", "rectangle", "halfplane", "regular_polygon", "cassini"]


def _vec2(value, name: str, *, positive: bool = False, params: bool = True) -> np.ndarray:
    return _vector(value, name, 2, positive=positive, params=params)


def _placed(shape: Shape, center) -> Shape:
    c = _vec2(center, "center")
    return shape.translate((c[0], c[1], 0.0)) if any(not _zero(v) for v in c) else shape


@_primitive
def circle(radius: float = 1.0, center=(0.0, 0.0)) -> Shape:
    """Disc of ``radius`` (exact signed distance): f = r - |p - c|."""
    r = _positive(radius, "radius")
    x, y = E.coords(2)
    return _placed(Shape(r - E.sqrt(x * x + y * y), True), center)


@_primitive
def ellipse(semi_axes=(1.0, 0.5), center=(0.0, 0.0)) -> Shape:
    """Ellipse with semi-axes (a, b) along x and y (a bound: min(a, b) (1 - |p / (a, b)|);
    exact for a circle)."""
    a = _vec2(semi_axes, "semi_axes", positive=True)
    x, y = E.coords(2)
    rho = E.sqrt((x * (1 / a[0])) ** 2 + (y * (1 / a[1])) ** 2)
    if a.dtype == object:  # parameters (wm.param)
        return _placed(Shape((1.0 - rho) * _min_of(list(a)), a[0] is a[1]), center)
    return _placed(Shape((1.0 - rho) * float(a.min()), bool(a[0] == a[1])), center)


@_primitive
def rectangle(size=(1.0, 1.0), center=(0.0, 0.0)) -> Shape:
    """Axis-aligned rectangle with edge lengths ``size`` = (w, h) (exact signed distance)."""
    h = _vec2(size, "size", positive=True) / 2.0
    x, y = E.coords(2)
    qx, qy = abs(x) - h[0], abs(y) - h[1]
    outside = E.sqrt(E.max(qx, 0.0) ** 2 + E.max(qy, 0.0) ** 2)
    inside = E.min(E.max(qx, qy), 0.0)
    return _placed(Shape(-(outside + inside), True), center)


@_primitive
def halfplane(normal=(0.0, 1.0), point=(0.0, 0.0)) -> Shape:
    """Half-plane behind the line through ``point`` with outward ``normal`` (exact)."""
    n = _vec2(normal, "normal", params=False)
    if not np.any(n):
        raise ValueError("expected a non-zero 'normal', got (0, 0)")
    n = n / np.linalg.norm(n)
    p = _vec2(point, "point")
    x, y = E.coords(2)
    level = _lin([(float(n[0]), p[0]), (float(n[1]), p[1])]) if p.dtype == object else float(n @ p)
    return Shape(level - (x * n[0] + y * n[1]), True)


#: sides of :func:`regular_polygon` at most (its tape holds a half-plane per side)
MAX_POLYGON_SIDES = 4096


@_primitive
def regular_polygon(n: int, radius: float = 1.0, center=(0.0, 0.0)) -> Shape:
    """Convex regular polygon with ``n`` >= 3 vertices on the circle of ``radius``, one at
    angle 0 (a bound: the min of its edges' half-planes, exact inside)."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 3:
        raise ValueError(f"expected an integer 'n' >= 3, got {n!r}")
    if n > MAX_POLYGON_SIDES:  # (10**6 sides took a minute to build, and no mesher could use them)
        raise ValueError(f"expected at most {MAX_POLYGON_SIDES} sides for 'n', got {n}: a polygon of that many "
                         "sides is a circle to within 3e-7 of its radius, use wm.circle")
    r = _positive(radius, "radius")
    x, y = E.coords(2)
    apothem = r * math.cos(math.pi / n)
    sides = [apothem - (x * math.cos(t) + y * math.sin(t))
             for t in (2 * math.pi * (k + 0.5) / n for k in range(n))]
    return _placed(Shape(E.min(*sides), False), center)


@_primitive
def cassini(a: float = 1.0, b: float = 1.05) -> Shape:
    """Cassini ovals |p - (a, 0)| |p + (a, 0)| = b²: one oval for b > a, two for b < a,
    the lemniscate of Bernoulli (a singular point at the origin) for b = a. f > 0 inside,
    f = b⁴ - ((x² + y² + a²)² - 4 a² x²)."""
    a, b = _positive(a, "a"), _positive(b, "b")
    x, y = E.coords(2)
    return Shape(b**4 - ((x * x + y * y + a * a) ** 2 - 4 * a * a * x * x))
