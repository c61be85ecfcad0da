"""The mesher-independent Euler-characteristic oracle on shapes of known topology."""

from __future__ import annotations

import time

import numpy as np
import pytest

from tests.helpers.topology_oracle import (
    CSG_PART_BOUNDS,
    CSG_PART_EXPECTED,
    DEGREE_SIX_BOUNDS,
    DEGREE_SIX_EXPECTED,
    DEGREE_SIX_SMALL_BOUNDS,
    boundary_trace_euler,
    csg_part,
    degree_six,
    mask_euler,
    open_surface_euler,
    sample_mask,
    solid_components,
    solid_euler,
    surface_euler,
)

UNIT = ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))


def ball(x, y, z):
    return 0.7 - np.sqrt(x * x + y * y + z * z)


def solid_torus(x, y, z):  # major radius 0.6, minor 0.25, axis z
    return 0.25 - np.sqrt((np.sqrt(x * x + y * y) - 0.6) ** 2 + z * z)


def box_with_four_holes(x, y, z):
    slab = np.minimum(np.minimum(0.8 - np.abs(x), 0.8 - np.abs(y)), 0.3 - np.abs(z))
    hole = 0.15 - np.sqrt((np.abs(x) - 0.4) ** 2 + (np.abs(y) - 0.4) ** 2)
    return np.minimum(slab, -hole)


def two_balls(x, y, z):
    return np.maximum(0.35 - np.sqrt((x - 0.5) ** 2 + y * y + z * z),
                      0.35 - np.sqrt((x + 0.5) ** 2 + y * y + z * z))


def hollow_shell(x, y, z):  # ball of radius 0.8 minus ball of radius 0.5
    r = np.sqrt(x * x + y * y + z * z)
    return np.minimum(0.8 - r, r - 0.5)


# (shape, solid chi, components)
KNOWN = [
    (ball, 1, 1),
    (solid_torus, 0, 1),
    (box_with_four_holes, -3, 1),  # 1 - 4 through holes
    (two_balls, 2, 2),
    (hollow_shell, 2, 1),  # boundary = two spheres
]


@pytest.mark.parametrize("n", [41, 64, 97])
@pytest.mark.parametrize("shape, chi, comps", KNOWN, ids=[k[0].__name__ for k in KNOWN])
def test_known_shapes(shape, chi, comps, n):
    assert solid_euler(shape, UNIT, n) == chi
    assert surface_euler(shape, UNIT, n) == 2 * chi
    assert solid_components(shape, UNIT, n) == comps
    # complement in the box: chi(box) = 1 = chi(M) + chi(M^c) - chi(boundary M)
    assert solid_euler(shape, UNIT, n, side=-1) == 1 + chi
    # the shapes stay away from the box faces: the open surface is the closed one
    assert boundary_trace_euler(shape, UNIT, n) == 0
    assert open_surface_euler(shape, UNIT, n) == 2 * chi


def test_hollow_shell_has_two_boundary_spheres():
    # chi(boundary) = 4 = two spheres; the complement splits into the cavity and the rest
    assert surface_euler(hollow_shell, UNIT, 80) == 4
    assert solid_components(hollow_shell, UNIT, 80, side=-1) == 2


def test_side_minus_one_is_the_negated_function():
    neg = lambda x, y, z: -solid_torus(x, y, z)  # noqa: E731
    for n in (33, 50):
        assert solid_euler(solid_torus, UNIT, n, side=-1) == solid_euler(neg, UNIT, n)
        assert solid_components(solid_torus, UNIT, n, side=-1) == solid_components(neg, UNIT, n)


def test_mask_euler_small_complexes():
    assert mask_euler(np.ones((2, 2, 2), bool)) == 1
    assert mask_euler(np.ones((5, 4, 3), bool)) == 1
    hollow = np.ones((3, 3, 3), bool)
    hollow[1, 1, 1] = False  # cubical sphere (the 26 surface nodes), chi 2
    assert mask_euler(hollow) == 2
    ring = np.ones((3, 3), bool)
    ring[1, 1] = False  # square ring, chi 0
    assert mask_euler(ring) == 0
    assert mask_euler(np.array([1, 1, 0, 1], bool)) == 2
    assert mask_euler(np.zeros((4, 4, 4), bool)) == 0


def test_region_touching_the_box():
    # half-space z < 0.25 in the box: a ball; trace on the box = a disc-like cap (chi 1)
    half = lambda x, y, z: 0.25 - z + 0 * x * y  # noqa: E731
    assert solid_euler(half, UNIT, 33) == 1
    assert boundary_trace_euler(half, UNIT, 33) == 1
    assert open_surface_euler(half, UNIT, 33) == 1  # the flat square z = 0.25
    # infinite z-cylinder through the box: a ball whose trace is two discs (chi 2)
    cyl = lambda x, y, z: 0.5 - np.sqrt(x * x + y * y) + 0 * z  # noqa: E731
    assert solid_euler(cyl, UNIT, 41) == 1
    assert boundary_trace_euler(cyl, UNIT, 41) == 2
    assert open_surface_euler(cyl, UNIT, 41) == 0  # an open tube (annulus)


def test_n300_is_fast():
    t0 = time.perf_counter()
    assert solid_euler(solid_torus, UNIT, 300) == 0
    assert time.perf_counter() - t0 < 10.0


@pytest.mark.parametrize("bounds", [DEGREE_SIX_BOUNDS, DEGREE_SIX_SMALL_BOUNDS],
                         ids=["box3", "box2.5"])
@pytest.mark.parametrize("n", [33, 97, 129])
def test_degree_six_expected(bounds, n):
    for key, side in (("inside", 1), ("outside", -1)):
        exp = DEGREE_SIX_EXPECTED[key]
        assert solid_components(degree_six, bounds, n, side) == exp["components"], key
        assert solid_euler(degree_six, bounds, n, side) == exp["solid_euler"], key
        assert surface_euler(degree_six, bounds, n, side) == exp["surface_euler"], key
    # the open surface {f = 0} ∩ box, seen from either side, is a genus-5 surface with
    # 6 holes (chi -4)
    assert open_surface_euler(degree_six, bounds, n, 1) == -4
    assert open_surface_euler(degree_six, bounds, n, -1) == -4


def test_degree_six_critical_box():
    # c = 4.0078 is (to 8e-6) P at the box-edge midpoints of [-2.2, 2.2]^3: just below
    # that box the wire frame breaks into the 8 corner blobs.
    assert degree_six(0.0, 2.2, 2.2) == pytest.approx(8e-6, abs=1e-9)
    small = ((-2.19,) * 3, (2.19,) * 3)
    assert solid_components(degree_six, small, 65) == 8
    assert solid_euler(degree_six, small, 65) == 8


@pytest.mark.parametrize("n", [33, 65, 129])
def test_csg_part(n):
    assert solid_components(csg_part, CSG_PART_BOUNDS, n) == CSG_PART_EXPECTED["components"]
    assert solid_euler(csg_part, CSG_PART_BOUNDS, n) == CSG_PART_EXPECTED["solid_euler"]
    assert surface_euler(csg_part, CSG_PART_BOUNDS, n) == CSG_PART_EXPECTED["surface_euler"]
    assert solid_euler(csg_part, CSG_PART_BOUNDS, n, side=-1) == -2


def test_sample_mask_shape_and_chunks():
    m = sample_mask(ball, UNIT, (30, 20, 10))
    assert m.shape == (30, 20, 10)
    # a constant callable that does not broadcast by itself
    m = sample_mask(lambda x, y, z: 1.0, UNIT, 5)
    assert m.all()
