"""Tests of the exhaustive-enumeration curve samplers (warpmesh/curve_grid.py, [FG §16.3.1-16.3.3]).

Hausdorff bounds used below (h = cell size, R = 1 / kappa the smallest radius of curvature):
every segment is a chord across one cell, of length <= sqrt(2) h, so its sagitta is at most
``R - sqrt(R^2 - h^2 / 2)`` (about kappa h^2 / 4); bisection and Newton add their root error
``tolerance * h``; linear interpolation (eq. 16.12) adds an O(kappa h^2) root error of the
same order, so its bound is taken as twice the chord bound.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep import expr as E
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.grid import sample_freudenthal, sample_grid
from warpmesh.mesh import Mesh
from warpmesh.planar.polyline import chains, components

from tests.helpers.curvecheck import check_curve

SAMPLERS = [pytest.param(sample_grid, id="grid"), pytest.param(sample_freudenthal, id="freudenthal")]
BOX3 = ((-1.5, -1.5), (1.5, 1.5))


def chord_bound(h: float, kappa: float) -> float:
    r = 1.0 / kappa
    assert h * h / 2 < r * r, "cell too large for the chord bound"
    return r - math.sqrt(r * r - h * h / 2)


def bound(sample, kappa: float) -> float:
    h = max(sample.info["cell_size"])
    if sample.info["root"] == "linear":
        return 2 * chord_bound(h, kappa)
    return chord_bound(h, kappa) + sample.info["tolerance"] * h


def run(sampler, shape, bounds, **kw):
    return sampler(PlanarField(shape, bounds), **kw)


def check(sample, shape, bounds, **kw):
    return check_curve(Mesh(sample.points, {"line": sample.segments}), shape, bounds, **kw)


def cassini_curvature(points, a, b):
    """Curvature of the Cassini oval at points (from the analytic derivatives of f)."""
    x, y = points[:, 0], points[:, 1]
    s = x * x + y * y + a * a
    fx, fy = -4 * x * s + 8 * a * a * x, -4 * y * s
    fxx, fyy, fxy = -4 * s - 8 * x * x + 8 * a * a, -4 * s - 8 * y * y, -8 * x * y
    return np.abs(fxx * fy**2 - 2 * fxy * fx * fy + fyy * fx**2) / np.hypot(fx, fy) ** 3


# ----------------------------------------------------------------------------- circle, roots


@pytest.mark.parametrize("root", ["linear", "bisection", "newton"])
@pytest.mark.parametrize("sampler", SAMPLERS)
def test_circle_each_root_method(sampler, root):
    s = run(sampler, wm.circle(1.0), BOX3, resolution=48, root=root, tolerance=1e-4)
    m = check(s, wm.circle(1.0), BOX3, n_components=1, hausdorff=bound(s, 1.0))
    h = max(s.info["cell_size"])
    radial = np.abs(np.linalg.norm(s.points, axis=1) - 1.0)
    if root == "linear":
        assert radial.max() < h * h  # O(h^2) root error of eq. 16.12
    else:  # roots to tolerance * h (float32 evaluation noise ~1e-7 on top)
        assert radial.max() <= 1e-4 * h / 2 + 1e-6
    assert m["wrong_orientation"] == 0 and s.info["unconverged"] == 0


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_welded_one_point_per_crossing_edge(sampler):
    field = PlanarField(wm.circle(1.0), BOX3)
    s = sampler(field, resolution=20)
    xs, ys, f = field.grid(20, 20)
    ins = f > 0
    n_cross = np.count_nonzero(ins[1:] != ins[:-1]) + np.count_nonzero(ins[:, 1:] != ins[:, :-1])
    if sampler is sample_freudenthal:
        n_cross += np.count_nonzero(ins[1:, 1:] != ins[:-1, :-1])
    assert len(s.points) == n_cross == len(np.unique(s.points, axis=0))
    # every point is shared by exactly one incoming and one outgoing segment (closed curve)
    assert np.all(np.bincount(s.segments[:, 0], minlength=len(s.points)) == 1)
    assert np.all(np.bincount(s.segments[:, 1], minlength=len(s.points)) == 1)
    # each segment lies in its crossed cell
    mid = 0.5 * (s.points[s.segments[:, 0]] + s.points[s.segments[:, 1]])
    if sampler is sample_freudenthal:
        box = s.cells
        assert len(box) == len(s.segments) == s.info["cells"]
        assert np.all((mid >= box[:, :2] - 1e-12) & (mid <= box[:, 2:] + 1e-12))
    else:
        sq = ((ins[:-1, :-1] != ins[1:, :-1]) | (ins[:-1, :-1] != ins[1:, 1:]) | (ins[:-1, :-1] != ins[:-1, 1:]))
        assert s.info["cells"] == len(s.cells) == np.count_nonzero(sq)


def test_linear_root_is_second_order():
    hd = [check(run(sample_grid, wm.circle(1.0), BOX3, resolution=r, root="linear"), wm.circle(1.0), BOX3,
                n_components=1)["hausdorff"] for r in (24, 48)]
    assert 3.0 < hd[0] / hd[1] < 5.0


def test_newton_needs_fewer_evaluations_than_bisection_at_tight_tolerance():
    ev = {r: run(sample_grid, wm.circle(1.0), BOX3, resolution=32, root=r, tolerance=1e-6).info["evaluations"]
          for r in ("bisection", "newton")}
    nodes = 33 * 33
    assert ev["newton"] - nodes < 0.5 * (ev["bisection"] - nodes)


# ----------------------------------------------------------------------------- test curves


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_thin_ellipse(sampler):
    shape, box = wm.ellipse((1.0, 0.1)), ((-1.2, -0.2), (1.2, 0.2))
    s = run(sampler, shape, box, resolution=256)
    check(s, shape, box, n_components=1, hausdorff=bound(s, 1.0 / 0.1**2))


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_two_circles_with_a_gap_below_the_cell_size(sampler):
    """Gap g = 0.02 between two discs of radius R = 0.5, cells h ~ 0.05 > g. What the sampler
    sees is decided by the nodes: a column of nodes in the gap (even resolution, x = 0 is a
    node) keeps the two circles apart; with the nodes straddling the gap (odd resolution) the
    cells across it are all inside and the circles merge into one closed curve through a
    bridge of half-height ~ sqrt(R (h - g)) - still a valid, oriented, closed polyline."""
    g, r = 0.02, 0.5
    shape = wm.circle(r, (-r - g / 2, 0)) | wm.circle(r, (r + g / 2, 0))
    box = ((-1.2, -0.6), (1.2, 0.6))
    apart = run(sampler, shape, box, resolution=48)
    check(apart, shape, box, n_components=2, hausdorff=bound(apart, 1 / r))
    merged = run(sampler, shape, box, resolution=49)
    h = max(merged.info["cell_size"])
    m = check(merged, shape, box, n_components=1)
    assert math.sqrt(r * (h - g)) - h < m["hausdorff"] < math.sqrt(r * h)


@pytest.mark.parametrize("resolution", [160, 161])
@pytest.mark.parametrize("sampler", SAMPLERS)
def test_two_circles_resolved_by_a_fine_grid(sampler, resolution):
    g, r = 0.02, 0.5
    shape = wm.circle(r, (-r - g / 2, 0)) | wm.circle(r, (r + g / 2, 0))
    box = ((-1.2, -0.6), (1.2, 0.6))
    s = run(sampler, shape, box, resolution=resolution)
    assert max(s.info["cell_size"]) < g
    check(s, shape, box, n_components=2, hausdorff=bound(s, 1 / r))


@pytest.mark.parametrize("b, n", [(0.95, 2), (1.05, 1)])
@pytest.mark.parametrize("sampler", SAMPLERS)
def test_cassini_either_side_of_the_topology_change(sampler, b, n):
    shape, box = wm.cassini(1.0, b), ((-1.6, -0.7), (1.6, 0.7))
    s = run(sampler, shape, box, resolution=64)
    kappa = cassini_curvature(PlanarField(shape, box).project(s.points), 1.0, b).max()
    check(s, shape, box, n_components=n, hausdorff=bound(s, kappa))


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_isolated_small_component_found_when_the_grid_resolves_it(sampler):
    """A disc of radius 0.05 far from the unit circle. It holds a grid node, hence is found,
    whenever h <= sqrt(2) r; centred in a cell of size h = 0.1 it holds none and is missed."""
    small = 0.05
    shape = wm.circle(1.0) | wm.circle(small, (1.55, 1.55))
    box = ((-2.0, -2.0), (2.0, 2.0))
    coarse = run(sampler, shape, box, resolution=40)  # h = 0.1, corners 0.0707 > r from the centre
    assert components(coarse.segments, len(coarse.points))[0] == 1
    fine = run(sampler, shape, box, resolution=64)  # h = 0.0625 <= sqrt(2) r
    assert max(fine.info["cell_size"]) <= math.sqrt(2) * small
    check(fine, shape, box, n_components=2, hausdorff=bound(fine, 1 / small))


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_lemniscate_singular_point_on_a_node(sampler):
    """f(0, 0) = 0 at the singular point, a grid node here: it counts as outside, so the two
    lobes are sampled as two closed curves that come within the root tolerance of the origin
    (the domain {f > 0} indeed has two components); never a crossing at the node."""
    shape, box = wm.example("lemniscate")
    s = run(sampler, shape, box, resolution=64)
    h = max(s.info["cell_size"])
    m = check(s, shape, box, n_components=2, singular=[(0.0, 0.0)], hausdorff=0.05 * h)
    # float32 evaluation: f(x, 0) = 2x^2 - x^4 rounds to 0 for |x| < ~2e-4, a zero stretch
    # whose end the bisection finds [FG Figure 16.9]
    assert np.linalg.norm(s.points, axis=1).min() < 0.01 * h
    assert m["wrong_orientation"] == 0


def test_lemniscate_singular_point_in_an_ambiguous_cell():
    """Rotated by 45 deg, f ~ 4xy - r^4 near the origin: the cell holding the singular point
    is ambiguous (inside corners on one diagonal). The bilinear saddle value is ~ -h^4 < 0, so
    the asymptotic decider keeps the lobes apart (2 closed curves, the topology of {f > 0});
    the centre value 4 xc yc > 0 makes the centre decider join them into one closed curve."""
    shape = wm.cassini(1.0, 1.0).rotate(math.pi / 4)
    h = 0.05
    off = np.array([0.3, 0.4]) * h  # the origin at (0.3 h, 0.4 h) from a cell corner
    box = ((-1.3 + off[0], -1.3 + off[1]), (1.3 + off[0], 1.3 + off[1]))
    asym = run(sample_grid, shape, box, resolution=52)
    centre = run(sample_grid, shape, box, resolution=52, decider="center")
    assert asym.info["ambiguous"] == centre.info["ambiguous"] == 1
    assert (asym.info["joined"], centre.info["joined"]) == (0, 1)
    check(asym, shape, box, n_components=2, singular=[(0.0, 0.0)], hausdorff=h)
    check(centre, shape, box, n_components=1, singular=[(0.0, 0.0)], hausdorff=h)


# ----------------------------------------------------------------------------- decider on a bilinear field


def _cut_corners(sample) -> set[tuple[int, int]]:
    """Corner of the unit cell cut off by each segment: x of its end on a vertical edge, y of
    its end on a horizontal edge."""
    out = set()
    for seg in sample.points[sample.segments]:
        vertical = np.isclose(seg[:, 0], 0.0) | np.isclose(seg[:, 0], 1.0)
        assert vertical.sum() == 1, "a segment joining opposite edges"
        out.add((round(seg[vertical][0, 0]), round(seg[~vertical][0, 1])))
    return out


@pytest.mark.parametrize("s, asym_joined, centre_joined", [(0.02, True, True), (-0.02, False, True),
                                                          (-0.06, False, False)])
def test_decider_on_a_bilinear_cell(s, asym_joined, centre_joined):
    """f = s - (x - 0.3)(y - 0.7) on the unit cell: corners 1 = (1, 0) and 3 = (0, 1) inside,
    0 and 2 outside. The inside corners are connected iff the saddle value s > 0 (asymptotic
    decider, always right for a bilinear f); the centre value s + 0.04 misleads the centre
    decider for -0.04 < s < 0."""
    x, y = wm.coords(2)
    field = PlanarField(s - (x - 0.3) * (y - 0.7), ((0.0, 0.0), (1.0, 1.0)))
    for decider, joined in (("asymptotic", asym_joined), ("center", centre_joined)):
        sample = sample_grid(field, resolution=1, decider=decider)
        assert sample.info["ambiguous"] == 1 and sample.info["joined"] == int(joined)
        assert len(sample.segments) == 2
        # joined: the outside corners are cut off; separated: the inside ones
        assert _cut_corners(sample) == ({(0, 0), (1, 1)} if joined else {(1, 0), (0, 1)}), (decider, s)


def _side(p, box) -> str:
    (x0, y0), (x1, y1) = box
    return {p[0] == x0: "left", p[0] == x1: "right", p[1] == y0: "bottom", p[1] == y1: "top"}[True]


@pytest.mark.parametrize("s", [0.002, 0.0002, -0.002])
def test_decider_on_a_hyperbola_across_many_cells(s):
    """f = s - (x - a)(y - b) is inside between the branches of a hyperbola. For s > 0 the
    branches run top-right and left-bottom of the saddle (a, b); for s < 0 left-top and
    bottom-right. The saddle sits off-centre in an ambiguous cell (for s = 0.0002 the centre
    value is negative); the asymptotic decider pairs the box sides as the exact curve does."""
    x, y = wm.coords(2)
    shape = s - (x - 0.13) * (y - 0.11)
    box = ((-1.0, -1.0), (1.0, 1.0))
    sample = sample_grid(PlanarField(shape, box), resolution=10)
    assert sample.info["ambiguous"] == 1
    # near the saddle the radius of curvature sqrt(2 |s|) is below the cell size h = 0.2: only
    # "within half a cell" holds there (measured 0.065 for s = 0.0002)
    check(sample, shape, box, closed=False, n_components=2, hausdorff=0.1)
    pairs = {frozenset(_side(sample.points[c[k]], box) for k in (0, -1))
             for c, _ in chains(sample.segments, len(sample.points))}
    expected = ({frozenset({"top", "right"}), frozenset({"left", "bottom"})} if s > 0 else
                {frozenset({"left", "top"}), frozenset({"bottom", "right"})})
    assert pairs == expected
    centre = sample_grid(PlanarField(shape, box), resolution=10, decider="center")
    # the centre (0.1, 0.1) has f = s - 0.0003: the centre decider is wrong for 0 < s < 0.0003
    assert (sample.info["joined"], centre.info["joined"]) == ((1, 1) if s > 0.0003 else (1, 0) if s > 0 else (0, 0))


# ----------------------------------------------------------------------------- special inputs


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_curve_leaving_the_box_gives_open_chains_on_the_boundary(sampler):
    box = ((0.2, -1.2), (1.4, 1.2))
    s = run(sampler, wm.circle(1.0), box, resolution=48)
    check(s, wm.circle(1.0), box, closed=False, n_components=1, hausdorff=bound(s, 1.0))
    (chain, closed), = chains(s.segments, len(s.points))
    assert not closed
    first, last = s.points[chain[0]], s.points[chain[-1]]
    assert first[0] == last[0] == 0.2  # both ends exactly on the left side of the box
    assert first[1] < 0 < last[1]  # counter-clockwise: the disc on the left


@pytest.mark.parametrize("root", ["linear", "bisection", "newton"])
def test_zero_at_nodes_counts_as_outside(root):
    """f = x vanishes on a column of nodes: those nodes are outside, the roots lie just right
    of them (never on them, so no zero-length segment), one open chain up the box."""
    x, _ = wm.coords(2)
    box = ((-1.0, -1.0), (1.0, 1.0))
    s = sample_grid(PlanarField(x, box), resolution=8, root=root, tolerance=1e-3)
    h = s.info["cell_size"][0]
    assert np.all((s.points[:, 0] > 0) & (s.points[:, 0] <= 1e-3 * h))
    check(s, x, box, closed=False, n_components=1, hausdorff=1e-3 * h)


@pytest.mark.parametrize("root", ["bisection", "newton"])
def test_root_past_a_zero_stretch_of_the_edge(root):
    """f = 0 on 0 <= x <= 0.3 [FG Figure 16.9, right]: the modified search returns the end
    of the zero stretch next to the positive node, x = 0.3."""
    x, _ = wm.coords(2)
    f = E.min(x, 0.0) + E.max(x - 0.3, 0.0)
    box = ((-1.0, -1.0), (1.0, 1.0))
    s = sample_grid(PlanarField(f, box), resolution=4, root=root, tolerance=1e-4)
    h = s.info["cell_size"][0]
    assert np.allclose(s.points[:, 0], 0.3, atol=1e-4 * h + 1e-6)


@pytest.mark.parametrize("sampler", SAMPLERS)
def test_no_zero_in_the_box_gives_an_empty_sample(sampler):
    for box, side in ((((3.0, 3.0), (4.0, 4.0)), "outside"), (((-0.2, -0.2), (0.2, 0.2)), "inside")):
        s = run(sampler, wm.circle(1.0), box, resolution=16)
        assert s.points.shape == (0, 2) and s.segments.shape == (0, 2)
        assert s.info["empty"] and s.info["cells"] == 0 and side in s.info["message"]


@pytest.mark.parametrize("sampler", SAMPLERS)
@pytest.mark.parametrize("kw, name", [
    ({"resolution": 0}, "resolution"), ({"resolution": -4}, "resolution"), ({"resolution": 2.5}, "resolution"),
    ({"resolution": True}, "resolution"), ({"resolution": (8, 0)}, "resolution"),
    ({"resolution": "64"}, "resolution"), ({"tolerance": 0.0}, "tolerance"), ({"tolerance": 1.5}, "tolerance"),
    ({"root": "secant"}, "root"),
])
def test_bad_arguments_name_the_argument(sampler, kw, name):
    field = PlanarField(wm.circle(1.0), BOX3)
    with pytest.raises(ValueError, match=f"'{name}'"):
        sampler(field, **kw)


def test_bad_decider_and_field():
    field = PlanarField(wm.circle(1.0), BOX3)
    with pytest.raises(ValueError, match="'decider'"):
        sample_grid(field, decider="middle")
    with pytest.raises(TypeError, match="'field'"):
        sample_grid(wm.circle(1.0))


def test_resolution_pair_and_square_cells():
    field = PlanarField(wm.circle(1.0), ((-1.5, -1.0), (1.5, 1.0)))
    assert sample_grid(field, resolution=30).info["resolution"] == (30, 20)
    assert sample_grid(field, resolution=(12, 40)).info["resolution"] == (12, 40)
    hx, hy = sample_grid(field, resolution=7).info["cell_size"]
    assert hy <= hx and hx == pytest.approx(3.0 / 7)
