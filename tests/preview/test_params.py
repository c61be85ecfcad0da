"""Parameters (wm.param): constants of the tape's data, edits that change data only."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep.tape import compile_tape, tape_of
from warpmesh.kernels import opcodes as O

BOUNDS = ((-1.2,) * 3, (1.2,) * 3)


def part_of(r, boss):
    holes = [wm.cylinder(r, axis="z").translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
    return (wm.box((2, 2, 0.6)) - wm.union(*holes)) | wm.sphere(boss)


@pytest.fixture(scope="module")
def params():
    return wm.param("r", 0.2, lo=0.05, hi=0.28), wm.param("boss", 0.5, lo=0.3, hi=0.7)


def test_params_listed_and_held_in_the_constant_array(params):
    r, boss = params
    part = part_of(r, boss)
    assert list(part.params) == ["r", "boss"] or list(part.params) == ["boss", "r"]
    assert part.params["r"] is r and r.value == 0.2 and (r.lo, r.hi) == (0.05, 0.28)
    tape = compile_tape(part)
    for name, p in part.params.items():
        row = tape.params[name]
        assert tape.code[row, 0] == O.CONST and tape.imm[row] == np.float32(p.value)
    assert len([1 for c in tape.code if c[0] == O.CONST]) >= 2


def test_edit_changes_data_only(params):
    r, boss = params
    part = part_of(r, boss)
    tape = tape_of(part)
    edited = part.with_params(r=0.1, boss=0.6)
    t2 = tape_of(edited)
    assert t2.code is tape.code  # no rebuild: the same instructions
    assert t2.values() == {"r": pytest.approx(0.1), "boss": pytest.approx(0.6)}
    assert tape.values() == {"r": pytest.approx(0.2), "boss": pytest.approx(0.5)}  # the original is untouched
    # a second edit of the edited shape still derives from the same code
    assert tape_of(edited.with_params(r=0.12)).code is tape.code
    assert edited.params["r"].value == 0.1 and part.params["r"].value == 0.2
    # the kernel generated for the structure serves every edit (its source holds no constant)
    from warpmesh.frep.codegen import source, structure_key

    assert structure_key(t2) == structure_key(tape) and source(t2) == source(tape)
    assert "0.2" not in source(tape) and "0.5" not in source(tape)


@pytest.mark.parametrize("values", [{"r": 0.1, "boss": 0.35}, {"r": 0.27, "boss": 0.69}, {"r": 0.05}])
def test_edited_shape_evaluates_like_plain_numbers(params, values):
    r, boss = params
    edited = part_of(r, boss).with_params(values)
    plain = part_of(values.get("r", 0.2), values.get("boss", 0.5))
    pts = np.random.default_rng(1).uniform(-1.2, 1.2, (20000, 3))
    np.testing.assert_array_equal(wm.evaluate(edited, pts), wm.evaluate(plain, pts))
    np.testing.assert_array_equal(wm.evaluate(edited, pts, gradient=True), wm.evaluate(plain, pts, gradient=True))
    np.testing.assert_allclose(edited.eval_numpy(*pts.T), plain.eval_numpy(*pts.T), rtol=0, atol=1e-12)


def test_intervals_follow_the_current_values(params):
    r, boss = params
    ball = wm.sphere(boss)
    lo, hi = np.array([[0.55, -0.01, -0.01]]), np.array([[0.6, 0.01, 0.01]])
    assert wm.evaluate_interval(ball, lo, hi)[0, 1] < 0  # the box is outside the ball of 0.5
    grown = ball.with_params(boss=0.7)
    iv = wm.evaluate_interval(grown, lo, hi)[0]
    assert iv[0] > 0  # and inside the ball of 0.7: sound and tight for the new value
    pts = np.random.default_rng(2).uniform(0.55, 0.6, (100, 3)) * [1, 0.02, 0.02]
    vals = wm.evaluate(grown, pts)
    assert iv[0] <= vals.min() and vals.max() <= iv[1]


def test_mesh_surface_params_equal_plain_numbers(params):
    r, boss = params
    part = part_of(r, boss)
    edited = wm.mesh_surface(part, bounds=BOUNDS, resolution=40, params={"r": 0.12, "boss": 0.62},
                             evaluator="interpreter")
    plain = wm.mesh_surface(part_of(0.12, 0.62), bounds=BOUNDS, resolution=40, evaluator="interpreter")
    np.testing.assert_array_equal(edited.points, plain.points)
    np.testing.assert_array_equal(edited.triangles, plain.triangles)
    assert edited.stats()["euler"] == -6
    octree = wm.mesh_surface(part, bounds=BOUNDS, adaptive=True, max_level=5, params={"r": 0.12})
    assert octree.stats()["euler"] == -6


@pytest.mark.parametrize("bad, match", [({"radius": 0.1}, "Unknown parameter 'radius' in 'params'"),
                                        ({"r": 0.3}, r"expected a value in \[0.05, 0.28\] for parameter 'r' in 'params'"),
                                        ({"r": float("nan")}, "parameter 'r'")])
def test_bad_values_are_named(params, bad, match):
    part = part_of(*params)
    with pytest.raises(ValueError, match=match):
        wm.mesh_surface(part, bounds=BOUNDS, resolution=8, params=bad)
    with pytest.raises(ValueError, match=match):
        part.with_params(bad)


def test_params_refused_where_they_cannot_go():
    r = wm.param("r", 0.2, lo=0.05, hi=0.28)
    with pytest.raises(TypeError, match="'params' sets the parameters of a shape"):
        wm.mesh_surface(np.zeros((4, 4, 4)), params={"r": 0.1})
    with pytest.raises(TypeError, match="exponent"):
        wm.coords()[0] ** r
    with pytest.raises(TypeError, match="'e1'"):
        wm.superquadric(e1=r)
    with pytest.raises(TypeError, match="'normal'"):
        wm.halfspace(normal=(r, 0, 1))
    with pytest.raises(ValueError, match="lo > 0 for 'radius'"):
        wm.sphere(wm.param("s", 0.2, lo=-1, hi=1))
    with pytest.raises(ValueError, match="minor < major"):
        wm.torus(wm.param("R", 1.0, lo=0.25, hi=2), r)
    with pytest.raises(ValueError, match="two different parameters are named 'r'"):
        (wm.sphere(r) | wm.sphere(wm.param("r", 0.1, lo=0.05, hi=0.3))).params
    with pytest.raises(ValueError, match="identifier"):
        wm.param("not a name", 1.0)
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        wm.param("a", 2.0, lo=0, hi=1)


def _grid():
    return np.random.default_rng(3).uniform(-1.5, 1.5, (3000, 3))


P = {"t": (0.3, -1.0, 1.0, 0.7), "s": (1.2, 0.5, 2.0, 0.8), "x0": (0.1, -1.0, 1.0, -0.3), "r": (0.2, 0.05, 0.28, 0.12)}


def _builders():
    return [
        lambda t, s, x0, r: wm.box((s, 1, 1), center=(x0, 0, 0)),
        lambda t, s, x0, r: wm.sphere(1).rotate(t, axis=(1, 1, 0)).translate((x0, 0.2, 0)),
        lambda t, s, x0, r: wm.box((1, 0.5, 0.3)).rotate(t, axis="z", about=(x0, 0, 0)),
        lambda t, s, x0, r: wm.box((1, 0.5, 0.3)).scale(s, about=(x0, 0, 0)),
        lambda t, s, x0, r: wm.box((1, 0.5, 0.3)).scale((s, 1, 2)),
        lambda t, s, x0, r: wm.cone(s, 1.0),
        lambda t, s, x0, r: wm.torus(s, r),
        lambda t, s, x0, r: wm.ellipsoid((s, 1, 0.5)),
        lambda t, s, x0, r: wm.halfspace((1, 1, 0), (x0, 0, 0)),
        lambda t, s, x0, r: wm.capsule((x0, 0, 0), (1, 1, 0), r),
        lambda t, s, x0, r: wm.union(wm.sphere(1), wm.box((1, 1, 2)), method="smooth", k=r),
        lambda t, s, x0, r: wm.box(1).mirror((1, 0, 0), (x0, 0, 0)),
        lambda t, s, x0, r: wm.superquadric((s, 1, 1), 0.5, 0.5),
        lambda t, s, x0, r: wm.sphere(0.8) + r,
        lambda t, s, x0, r: wm.circle(r, (x0, 0)),
        lambda t, s, x0, r: wm.ellipse((s, 0.5)),
        lambda t, s, x0, r: wm.rectangle((s, r)).rotate(t),
        lambda t, s, x0, r: wm.halfplane((1, 1), (x0, 0)),
        lambda t, s, x0, r: wm.regular_polygon(5, s),
        lambda t, s, x0, r: wm.cassini(s, 1.05),
    ]


@pytest.mark.parametrize("k", range(len(_builders())))
def test_every_constructor_takes_parameters(k):
    build = _builders()[k]
    ps = {n: wm.param(n, v, lo=lo, hi=hi) for n, (v, lo, hi, _) in P.items()}
    shaped = build(**ps)
    pts = _grid()
    for values in ({n: v[0] for n, v in P.items()}, {n: v[3] for n, v in P.items()}):
        bound = shaped.with_params({n: v for n, v in values.items() if n in shaped.params})
        plain = build(**values)
        np.testing.assert_allclose(bound.eval_numpy(*pts.T), plain.eval_numpy(*pts.T), rtol=1e-12, atol=1e-12)
        assert bound.exact == plain.exact and bound.dim == plain.dim
    assert shaped.params, "the shape reads no parameter"


def test_tape_with_values_checks_names_and_ranges(params):
    tape = compile_tape(part_of(*params))
    with pytest.raises(ValueError, match="Unknown parameter 'x'"):
        tape.with_values({"x": 1.0})
    with pytest.raises(ValueError, match="parameter 'boss'"):
        tape.with_values({"boss": 0.1})
    with pytest.raises(TypeError, match="mapping"):
        tape.with_values([0.1])
    plain = compile_tape(wm.sphere(1.0))
    assert plain.params == {} and plain.with_values({}).code is plain.code
