"""Expressions and shapes combine as solids whichever side each is on: every operator,
each order of operands, checked by evaluating the result against the fields it is made of."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep import expr as E

RNG = np.random.default_rng(5)
P = RNG.uniform(-2.5, 2.5, (400, 3))


def f(obj, p=P):
    field = obj.field if isinstance(obj, wm.Shape) else obj
    return np.broadcast_to(np.asarray(field.eval_numpy(p[:, 0], p[:, 1], p[:, 2]), float), (len(p),))


def _operands():
    x, y, z = wm.coords()
    d6 = (x**2 + y**2 - 4) * (x**2 + z**2 - 4) * (y**2 + z**2 - 4) - 4.0078
    return d6, wm.sphere(1.0, (0.5, 0, 0))


def _inside(values):
    return values > 0


@pytest.mark.parametrize("order", ["expr-shape", "shape-expr", "expr-expr", "shape-shape"])
@pytest.mark.parametrize("op", ["|", "&", "-"])
def test_booleans_of_expressions_and_shapes(op, order):
    """Inside of the result == the set operation on the insides (R-functions keep the sign)."""
    d6, ball = _operands()
    a, b = {"expr-shape": (d6, ball), "shape-expr": (ball, d6), "expr-expr": (d6, ball.field),
            "shape-shape": (wm.Shape(d6), ball)}[order]
    if op == "-" and order == "expr-expr":
        out = a - b  # two expressions subtract as fields (x - 1 is arithmetic)
        assert isinstance(out, wm.Expr)
        np.testing.assert_allclose(f(out), f(a) - f(b), rtol=1e-12, atol=1e-12)
        return
    out = {"|": lambda: a | b, "&": lambda: a & b, "-": lambda: a - b}[op]()
    ia, ib = _inside(f(a)), _inside(f(b))
    want = {"|": ia | ib, "&": ia & ib, "-": ia & ~ib}[op]
    got = _inside(f(out))
    away = (np.abs(f(a)) > 1e-9) & (np.abs(f(b)) > 1e-9)
    assert np.array_equal(got[away], want[away])
    if order != "expr-expr":
        assert isinstance(out, wm.Shape)


def test_expression_minus_shape_is_the_boolean_difference_volume():
    """The issue's case: d6 - sphere is the difference of solids, not of fields."""
    d6, _ = _operands()
    bounds = ((-3.0,) * 3, (3.0,) * 3)
    ball = wm.sphere(1.0)
    via_expr = wm.mesh_surface(d6 - ball, bounds=bounds, resolution=48).stats()["volume"]
    via_shape = wm.mesh_surface(wm.difference(wm.Shape(d6), ball), bounds=bounds, resolution=48).stats()["volume"]
    arithmetic = wm.mesh_surface(wm.Shape(d6 - ball.field), bounds=bounds, resolution=48).stats()["volume"]
    assert via_expr == pytest.approx(via_shape, rel=1e-12)
    assert abs(arithmetic - via_expr) > 1.0  # the field difference is another solid


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("op", ["+", "*", "/"])
def test_shape_arithmetic_with_numbers_and_expressions(op, side):
    x, _, _ = wm.coords()
    ball = wm.sphere(1.0)
    for other in (0.25, 2, np.float32(3.0), x + 3.0):
        expr = {"+": lambda a, b: a + b, "*": lambda a, b: a * b, "/": lambda a, b: a / b}[op]
        out = expr(ball, other) if side == "left" else expr(other, ball)
        assert isinstance(out, wm.Shape)
        o = np.full(len(P), float(other)) if not isinstance(other, wm.Expr) else f(other)
        want = expr(f(ball), o) if side == "left" else expr(o, f(ball))
        np.testing.assert_allclose(f(out), want, rtol=1e-12, atol=1e-12)


def test_shape_minus_a_number_is_an_offset_of_the_field():
    ball = wm.sphere(1.0)
    np.testing.assert_allclose(f(ball - 0.25), f(ball) - 0.25)
    np.testing.assert_allclose(f(1.0 - ball), 1.0 - f(ball))
    grown = ball + 0.1
    assert f(grown, np.array([[1.05, 0, 0]]))[0] > 0 > f(ball, np.array([[1.05, 0, 0]]))[0]
    assert not grown.exact and (ball + 0).exact and ball.exact


def test_two_shapes_do_not_add_and_the_message_says_what_to_use():
    a, b = wm.sphere(1.0), wm.box((1, 1, 1))
    with pytest.raises(TypeError, match=r"'\|' for the union"):
        _ = a + b
    with pytest.raises(TypeError, match="a.field \\* b.field"):
        _ = a * b


def test_expression_or_expression_is_the_r_function_union():
    x, y, _ = wm.coords()
    u = x | y
    assert isinstance(u, wm.Expr) and u is E.runion(x, y)
    assert (x & y) is E.rintersection(x, y)
    assert (0.5 | x) is E.runion(x, 0.5)


def test_complement_is_the_same_for_both():
    d6, _ = _operands()
    np.testing.assert_allclose(f(~d6), -f(d6))
    np.testing.assert_allclose(f(~wm.Shape(d6)), -f(d6))
