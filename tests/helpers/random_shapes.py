"""Random F-Rep shapes for property tests, and the float32 tolerances of the tape tests.

The oracle is ``Expr.eval_numpy`` in float64; see ``tests/frep/test_tape.py`` for why
``|device - oracle| <= RTOL * intermediate_scale`` is the right acceptance.
"""

from __future__ import annotations

import numpy as np

import warpmesh as wm
from warpmesh.frep import expr as E

RTOL = 1e-5  # values: ~150 float32 ulps of the largest intermediate (see module doc)
ISLACK = 1e-5  # intervals: the interpreter rounds to nearest, not outward


def f32(a) -> np.ndarray:
    """Round to float32 and back, so device and oracle see identical points."""
    return np.asarray(a, np.float32).astype(np.float64)


def intermediate_scale(expr: E.Expr, pts: np.ndarray) -> np.ndarray:
    """Per point: max(1, |value of every node of the DAG|) (finite values only)."""
    scale = np.ones(len(pts))
    for v in expr.node_values(pts[:, 0], pts[:, 1], pts[:, 2]).values():
        v = np.broadcast_to(v, scale.shape)
        scale = np.maximum(scale, np.where(np.isfinite(v), np.abs(v), 0.0))
    return scale


def random_primitive(rng):
    k = rng.integers(11)
    c = tuple(rng.uniform(-0.5, 0.5, 3))
    ax = "xyz"[rng.integers(3)]
    if k == 0:
        return wm.sphere(rng.uniform(0.3, 1.2), c)
    if k == 1:
        return wm.box(rng.uniform(0.3, 1.5, 3), c)
    if k == 2:
        return wm.cylinder(rng.uniform(0.2, 0.8), None if rng.random() < 0.3 else rng.uniform(0.3, 1.5), ax, c)
    if k == 3:
        return wm.cone(rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.5), ax, c)
    if k == 4:
        return wm.torus(rng.uniform(0.6, 1.0), rng.uniform(0.1, 0.4), ax, c)
    if k == 5:
        return wm.ellipsoid(rng.uniform(0.3, 1.2, 3), c)
    if k == 6:
        return wm.halfspace(rng.normal(size=3), c)
    if k == 7:
        return wm.capsule(rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3), rng.uniform(0.1, 0.5))
    if k == 8:
        return wm.superquadric(rng.uniform(0.4, 1.2, 3), rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0), c)
    if k == 9:
        return wm.supertorus(1.0, rng.uniform(0.1, 0.5), rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0), ax, c)
    x, y, z = E.coords()
    return wm.Shape(x * y - z * rng.uniform(0.5, 2.0) + rng.uniform(-0.5, 0.5))


def random_shape(rng, depth):
    """Random primitives, booleans (all methods), transforms and arithmetic."""
    if depth == 0 or rng.random() < 0.2:
        return random_primitive(rng)
    k = rng.integers(8)
    if k <= 2:
        a, b = random_shape(rng, depth - 1), random_shape(rng, depth - 1)
        method = ("rfunction", "minmax", "smooth")[rng.integers(3)]
        op = (wm.union, wm.intersection, wm.difference)[k]
        return op(a, b, method=method, k=float(rng.uniform(0.05, 0.5)))
    s = random_shape(rng, depth - 1)
    if k == 3:
        return ~s
    if k == 4:
        t = rng.integers(6)
        if t == 0:
            return s.translate(rng.uniform(-0.5, 0.5, 3))
        if t == 1:
            return s.rotate(rng.uniform(-4, 4), rng.normal(size=3), rng.uniform(-0.5, 0.5, 3))
        if t == 2:
            return s.scale(rng.uniform(0.5, 2.0))
        if t == 3:
            return s.scale(rng.uniform(0.5, 2.0, 3), rng.uniform(-0.5, 0.5, 3))
        if t == 4:
            return s.mirror(rng.normal(size=3), rng.uniform(-0.5, 0.5, 3))
        return s.affine(np.eye(3) + 0.4 * rng.normal(size=(3, 3)), rng.uniform(-0.5, 0.5, 3))
    f = s.field
    x, y, z = E.coords()
    t = rng.integers(8)
    if t == 0:
        return wm.Shape(f * rng.uniform(-2, 2) + rng.uniform(-0.5, 0.5))
    if t == 1:
        return wm.Shape(abs(f) - 0.1)
    if t == 2:
        return wm.Shape(f + E.sin(x * rng.uniform(1, 8)) * 0.1)
    if t == 3:
        return wm.Shape(f * E.cos(y * rng.uniform(0.5, 3)))
    # (exp and cube clamp their argument: nested unbounded growth would overflow float32)
    if t == 4:
        return wm.Shape(E.exp(E.min(f, 3.0)) - 1.0)
    if t == 5:
        g = E.max(E.min(f, 3.0), -3.0)
        return wm.Shape(g ** 3 - g * random_shape(rng, 0).field)
    if t == 6:
        return wm.Shape(E.sqrt(f * f + 0.01) - 0.2)
    return wm.Shape(f / (z * z + 1.0))
