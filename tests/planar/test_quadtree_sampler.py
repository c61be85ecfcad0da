"""Adaptive quadtree sampling (warpmesh.planar.samplers.quadtree) against the exact curves.

Every polyline goes through ``check_curve`` (no crossings, closed, domain on the left,
two-sided Hausdorff distance to the exact curve); the chord bound tolerance x chord length
comes from the planarity criterion (max_angle = 4 atan(2 eps)).
"""

from __future__ import annotations

import numpy as np
import pytest
from tests.helpers.curvecheck import check_curve

import warpmesh as wm
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.quadtree import default_max_angle, pair_around_cells, sample_quadtree
from warpmesh.mesh import Mesh

TOL = 1e-2


def run(shape, bounds, **kw):
    s = sample_quadtree(PlanarField(shape, bounds), **{"tolerance": TOL, **kw})
    return s, Mesh(s.points, {"line": s.segments})


def chord_bound(s, m, tol=TOL):
    """Chord deviation eps * (longest segment), with room for the root tolerance."""
    return 1.5 * tol * m["max_length"] + 1e-5


def test_default_max_angle_is_the_chord_deviation_of_an_arc():
    # an arc of radius R turning by theta: sagitta / chord = tan(theta / 4) / 2
    for eps in (1e-3, 1e-2, 0.1):
        theta = default_max_angle(eps)
        assert np.tan(theta / 4) / 2 == pytest.approx(eps)
        assert theta == pytest.approx(8 * eps, rel=0.05)


def test_circle():
    shape, bounds = wm.circle(1.0), ((-1.2, -1.2), (1.2, 1.2))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, n_components=1)
    assert m["hausdorff"] <= chord_bound(s, m)
    assert np.allclose(np.linalg.norm(s.points, axis=1), 1.0, atol=1e-5)
    assert s.info["unresolved"] == 0 and s.info["empty_leaves"] == 0
    # every leaf of the covering-up holds segments, and every segment lies in its leaf
    assert s.cells.shape == (s.info["leaves"], 4)
    mid = 0.5 * (s.points[s.segments[:, 0]] + s.points[s.segments[:, 1]])
    inside = ((mid[:, None, :] >= s.cells[None, :, :2] - 1e-12) & (mid[:, None, :] <= s.cells[None, :, 2:] + 1e-12))
    assert inside.all(axis=2).any(axis=1).all()


def test_default_tolerance_meets_the_chord_bound():
    shape, bounds = wm.circle(1.0), ((-1.2, -1.2), (1.2, 1.2))
    s = sample_quadtree(PlanarField(shape, bounds))
    m = check_curve(Mesh(s.points, {"line": s.segments}), shape, bounds, n_components=1)
    assert s.info["unresolved"] == 0
    assert m["hausdorff"] <= 1.5e-3 * m["max_length"] + 1e-6
    assert m["max_length"] <= 2 * np.sin(default_max_angle(1e-3) / 2) * 1.0 + 1e-9  # chord of the arc


def test_newton_polish():
    shape, bounds = wm.ellipse((1.0, 0.5)), ((-1.2, -0.6), (1.2, 0.6))
    field = PlanarField(shape, bounds)
    raw = sample_quadtree(field, tolerance=0.1, newton=False)
    pol = sample_quadtree(field, tolerance=0.1)
    assert len(raw.points) == len(pol.points)
    e_raw, e_pol = field.estimate(raw.points), field.estimate(pol.points)
    # bisection to 0.1 x the edge, then linear interpolation in the last bracket; Newton: float32 noise
    assert e_raw.max() <= 0.1 * 2.4 / 2**2
    assert e_pol.max() < 1e-6 < e_raw.max()


def test_ellipse_is_conforming_across_leaf_sizes():
    shape, bounds = wm.ellipse((1.0, 0.1)), ((-1.2, -0.3), (1.2, 0.3))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, n_components=1)
    assert m["hausdorff"] <= chord_bound(s, m)
    assert s.info["unresolved"] == 0
    # leaves of many sizes, yet every vertex has exactly one segment in and one out
    sizes = np.unique(np.round(s.cells[:, 2] - s.cells[:, 0], 12))
    assert len(sizes) >= 5
    n = len(s.points)
    assert np.all(np.bincount(s.segments[:, 0], minlength=n) == 1)
    assert np.all(np.bincount(s.segments[:, 1], minlength=n) == 1)
    # a leaf next to smaller ones: its crossings are theirs (no T-junction gap)
    d = np.linalg.norm(s.points[:, None] - s.points[None], axis=2) + np.eye(n)
    assert d.min() > 1e-7


def test_leaves_adapt_to_the_curvature():
    shape, bounds = wm.ellipse((1.0, 0.1)), ((-1.2, -0.3), (1.2, 0.3))
    field = PlanarField(shape, bounds)
    s = sample_quadtree(field, tolerance=TOL, max_level=8)
    # the uniform grid of the finest leaf size: cells whose corners change sign
    n = 2**8
    _, _, f = field.grid(n, n)
    pos = f > 0
    corners = np.stack([pos[:-1, :-1], pos[1:, :-1], pos[1:, 1:], pos[:-1, 1:]])
    uniform = int(np.count_nonzero(corners.any(axis=0) & ~corners.all(axis=0)))
    assert s.info["leaves"] * 4 < uniform, (s.info["leaves"], uniform)
    # small leaves at the tips (curvature 100), large ones along the flat sides (curvature 0.1)
    size = s.cells[:, 2] - s.cells[:, 0]
    centre_x = 0.5 * (s.cells[:, 0] + s.cells[:, 2])
    assert size[np.abs(centre_x) > 0.98].max() * 8 <= size[np.abs(centre_x) < 0.5].min()


def test_smaller_max_angle_refines():
    shape, bounds = wm.circle(1.0), ((-1.2, -1.2), (1.2, 1.2))
    coarse, _ = run(shape, bounds, max_angle=0.2)
    fine, mesh = run(shape, bounds, max_angle=0.05)
    assert fine.info["leaves"] > 2 * coarse.info["leaves"]
    m = check_curve(mesh, shape, bounds, n_components=1)
    assert m["max_length"] <= 2 * np.sin(0.05 / 2) + 1e-9


def test_two_circles_nearly_touching():
    shape = wm.circle(0.5, (-0.505, 0.0)) | wm.circle(0.5, (0.505, 0.0))  # gap 0.01
    bounds = ((-1.2, -0.7), (1.2, 0.7))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, n_components=2)
    assert m["hausdorff"] <= chord_bound(s, m)


@pytest.mark.parametrize("b, n", [(0.95, 2), (1.05, 1)])
def test_cassini_either_side_of_the_topology_change(b, n):
    shape, bounds = wm.cassini(1.0, b), ((-1.6, -0.7), (1.6, 0.7))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, n_components=n)
    assert m["hausdorff"] <= 5e-3 * 3.2 / 2**10 + chord_bound(s, m)


def test_isolated_component_far_away():
    shape = wm.circle(0.5) | wm.circle(0.02, (1.7, 1.7))
    bounds = ((-2.0, -2.0), (2.0, 2.0))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, n_components=2)
    assert m["hausdorff"] < 2e-3
    # culling: no leaf between the two components
    c = 0.5 * (s.cells[:, :2] + s.cells[:, 2:])
    near = (np.abs(np.linalg.norm(c, axis=1) - 0.5) < 0.1) | (np.linalg.norm(c - 1.7, axis=1) < 0.1)
    assert near.all()
    assert s.info["culled"] > s.info["leaves"]


def test_component_below_the_finest_cell_is_kept_as_a_leaf():
    # radius 0.001 < finest cell 4 / 2**8: no sign change anywhere, but interval arithmetic keeps
    # the leaf around it down to max_level and reports it
    shape = wm.circle(0.5) | wm.circle(0.001, (1.7013, 1.7017))
    bounds = ((-2.0, -2.0), (2.0, 2.0))
    s = sample_quadtree(PlanarField(shape, bounds), tolerance=TOL, max_level=8)
    assert s.info["components"] == 1 and s.info["empty_leaves"] >= 1
    holds = np.all((s.cells[:, :2] <= [1.7013, 1.7017]) & (s.cells[:, 2:] >= [1.7013, 1.7017]), axis=1)
    assert holds.any()
    assert np.all(s.cells[holds, 2] - s.cells[holds, 0] == pytest.approx(4.0 / 2**8))


def test_lemniscate_singular_point():
    shape, bounds = wm.cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, singular=[(0.0, 0.0)])
    # f = 0 counts as outside at the crossing point: the two lobes are a finest cell apart
    assert m["components"] == 2
    assert m["hausdorff"] < 2e-3
    near = np.linalg.norm(s.points, axis=1) < 0.01
    assert near.sum() >= 2
    size = s.cells[:, 2] - s.cells[:, 0]
    holds = np.all((s.cells[:, :2] <= 1e-9) & (s.cells[:, 2:] >= -1e-9), axis=1)
    assert size[holds].max() == pytest.approx(3.2 / 2**10)  # refined to max_level at the singular point


@pytest.mark.parametrize("c", [0.01, -0.01])
def test_asymptotic_decider_on_a_saddle(c):
    # f = x y + c is bilinear: with one leaf the decider's saddle value is exactly c
    x, y = wm.coords(2)
    bounds = ((-1.0, -1.1), (1.0, 0.9))
    field = PlanarField(x * y + c, bounds)
    s = sample_quadtree(field, tolerance=TOL, max_level=0, min_level=0)
    assert s.info["ambiguous"] == 1 and len(s.segments) == 2
    a, b = s.points[s.segments[:, 0]], s.points[s.segments[:, 1]]
    # each segment joins two points of one branch of the hyperbola x y = -c
    assert np.all(np.sign(a[:, 0]) == np.sign(b[:, 0]))
    assert np.all(np.abs(a[:, 0] * a[:, 1] + c) < 1e-4)
    _, g = field.value_gradient(0.5 * (a + b))
    d = b - a
    assert np.all(-d[:, 1] * g[:, 0] + d[:, 0] * g[:, 1] > 0)  # f > 0 on the left


def test_pair_around_cells():
    # one cell, ccw: Y0 X0 Y1 X1; plus-connected joins X to the next Y, else to the previous
    cell, perim = np.zeros(4, int), np.array([0.5, 1.5, 2.5, 3.5])
    is_x, point = np.array([False, True, False, True]), np.arange(4)
    assert pair_around_cells(cell, perim, is_x, point, np.array([True])).tolist() == [[1, 2], [3, 0]]
    assert pair_around_cells(cell, perim, is_x, point, np.array([False])).tolist() == [[1, 0], [3, 2]]
    # order of the input does not matter
    p = np.array([2, 0, 3, 1])
    assert pair_around_cells(cell[p], perim[p], is_x[p], point[p], np.array([True])).tolist() == [[1, 2], [3, 0]]


def _random_csg(seed):
    rng = np.random.default_rng(seed)
    shape = wm.circle(rng.uniform(0.2, 0.5), tuple(rng.uniform(-1.2, 1.2, 2)))
    for _ in range(5):
        c = wm.circle(rng.uniform(0.05, 0.5), tuple(rng.uniform(-1.2, 1.2, 2)))
        shape = shape | c if rng.random() < 0.7 else shape - c
    return shape


@pytest.mark.parametrize("case", ["csg0", "csg1", "csg2", "saddles", "waves"])
def test_valid_on_harder_fields(case):
    # unions/differences of circles (corners where arcs meet), and sin 3x cos 3y + c: exact
    # saddles on the curve (c = 0) or many small ovals
    x, y = wm.coords(2)
    from warpmesh.frep import expr as E

    if case.startswith("csg"):
        shape = _random_csg(int(case[-1]))
    else:
        shape = E.sin(3 * x + 0.1) * E.cos(3 * y + 0.2) + (0.2 if case == "waves" else 0.0)
    bounds = ((-2.0, -2.0), (2.0, 2.0))
    s = sample_quadtree(PlanarField(shape, bounds), tolerance=TOL, max_level=9)
    m = check_curve(Mesh(s.points, {"line": s.segments}), shape, bounds, closed=False)
    # a corner where two arcs meet (G1 discontinuity) is cut within a finest cell
    assert m["hausdorff"] < 0.5 * np.hypot(4.0, 4.0) / 2**9


def test_curve_leaving_the_box():
    shape, bounds = wm.circle(1.0, (0.5, 0.0)), ((-1.2, -1.2), (1.2, 1.2))
    s, mesh = run(shape, bounds)
    m = check_curve(mesh, shape, bounds, n_components=1, closed=False)
    assert m["hausdorff"] <= chord_bound(s, m)


def test_no_curve():
    s, _ = run(wm.circle(0.5), ((2.0, 2.0), (3.0, 3.0)))
    assert len(s.segments) == 0 and len(s.points) == 0 and s.info["leaves"] == 0


def test_bad_arguments():
    field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
    with pytest.raises(TypeError, match="field"):
        sample_quadtree(wm.circle(1.0))
    with pytest.raises(ValueError, match="tolerance"):
        sample_quadtree(field, tolerance=0.0)
    with pytest.raises(ValueError, match="max_level"):
        sample_quadtree(field, max_level=17)
    with pytest.raises(ValueError, match="max_level"):
        sample_quadtree(field, max_level=2.5)
    with pytest.raises(ValueError, match="min_level"):
        sample_quadtree(field, min_level=5, max_level=4)
    with pytest.raises(ValueError, match="max_angle"):
        sample_quadtree(field, max_angle=0.0)
