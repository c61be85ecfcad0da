"""Planar shapes: primitives against closed forms, 2D transforms, the bundled examples."""

import math

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep.planar_field import PlanarField, check_bounds2d

RNG = np.random.default_rng(5)
P = RNG.uniform(-2, 2, size=(500, 2))


def test_coords2_and_dim():
    x, y = wm.coords(2)
    assert wm.Shape(1 - x * x - y * y).dim == 2
    assert wm.sphere(1.0).dim == 3 and wm.circle(1.0).dim == 2
    assert wm.cylinder(0.5).dim == 2  # an infinite cylinder along z is its planar section
    with pytest.raises(ValueError, match="dim"):
        wm.coords(4)


def test_circle_is_the_signed_distance():
    f = wm.circle(0.7, center=(0.2, -0.1)).eval_numpy(P[:, 0], P[:, 1])
    assert np.allclose(f, 0.7 - np.hypot(P[:, 0] - 0.2, P[:, 1] + 0.1))


def test_rectangle_is_the_signed_distance():
    f = wm.rectangle((1.0, 0.6)).eval_numpy(P[:, 0], P[:, 1])
    q = np.abs(P) - (0.5, 0.3)
    exact = -(np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0))
    assert np.allclose(f, exact)


def test_ellipse_sign_and_bound():
    e = wm.ellipse((1.0, 0.25))
    f = e.eval_numpy(P[:, 0], P[:, 1])
    inside = (P[:, 0] / 1.0) ** 2 + (P[:, 1] / 0.25) ** 2 < 1
    assert np.array_equal(f > 0, inside)
    assert not e.exact and wm.ellipse((0.5, 0.5)).exact


def test_halfplane_and_polygon():
    h = wm.halfplane((1.0, 1.0), (0.5, 0.0))
    assert np.allclose(h.eval_numpy(P[:, 0], P[:, 1]), (0.5 - P[:, 0] - P[:, 1]) / math.sqrt(2))
    square = wm.regular_polygon(4, radius=math.sqrt(2))  # vertices at angles 0, 90, ...: a diamond
    assert np.allclose(square.eval_numpy(np.array([0.0, 1.4, 0.0]), np.array([0.0, 0.0, 1.5])),
                       [1.0, 1 - 1.4 / math.sqrt(2), 1 - 1.5 / math.sqrt(2)], atol=1e-12)


def test_planar_transforms_take_two_values():
    c = wm.circle(1.0)
    moved = c.translate((1.0, 2.0)).eval_numpy(1.0, 2.0)
    assert np.isclose(moved, 1.0)
    big = c.scale((2.0, 2.0))
    assert big.exact and np.isclose(big.eval_numpy(0.0, 0.0), 2.0)
    turned = wm.rectangle((2.0, 0.2)).rotate(math.pi / 2)
    assert turned.eval_numpy(0.0, 0.9) > 0 and turned.eval_numpy(0.9, 0.0) < 0
    mirrored = wm.circle(0.5, (1.0, 0.0)).mirror((1.0, 0.0))
    assert mirrored.eval_numpy(-1.0, 0.0) > 0
    with pytest.raises(ValueError):
        wm.sphere(1.0).translate((1.0, 2.0))  # 3D shapes still take 3 values


def test_cassini_topology_sign():
    for b, inside_origin in ((0.95, False), (1.05, True)):
        s = wm.cassini(1.0, b)
        assert (s.eval_numpy(0.0, 0.0) > 0) == inside_origin
        assert s.eval_numpy(1.0, 0.0) > 0  # the foci are inside
    assert wm.cassini(1.0, 1.0).eval_numpy(0.0, 0.0) == 0.0  # the lemniscate's double point


@pytest.mark.parametrize("name", wm.EXAMPLES_2D)
def test_examples_are_planar_and_cross_zero(name):
    shape, bounds = wm.example(name)
    assert shape.dim == 2
    _, _, f = PlanarField(shape, bounds).grid(64, 64)
    assert (f > 0).any() and (f < 0).any()


def test_bad_arguments():
    for make in (lambda: wm.circle(0), lambda: wm.circle(1, (0, 0, 0)), lambda: wm.ellipse((1, 0)),
                 lambda: wm.rectangle((1, -1)), lambda: wm.halfplane((0, 0)), lambda: wm.regular_polygon(2),
                 lambda: wm.regular_polygon(3.5), lambda: wm.cassini(0, 1), lambda: wm.example("nope")):
        with pytest.raises(ValueError):
            make()
    with pytest.raises(ValueError, match="at most 4096 sides for 'n', got 1000000"):  # (a minute to build)
        wm.regular_polygon(10**6)
    with pytest.raises(ValueError, match="bounds"):
        check_bounds2d(((0, 0), (0, 1)))
    with pytest.raises(ValueError, match="bounds"):
        check_bounds2d("box")
    with pytest.raises(ValueError, match="planar"):
        PlanarField(wm.sphere(1.0), ((-1, -1), (1, 1)))
    with pytest.raises(TypeError):
        PlanarField("circle", ((-1, -1), (1, 1)))
