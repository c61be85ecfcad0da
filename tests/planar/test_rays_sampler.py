"""The naive ray-casting sampler (warpmesh.planar.samplers.rays): what it gets right with enough rays,
and its failure modes [FG §16.3.1, Fig 16.2] shown against the exact curve and against
the quadtree sampler, which has an a-priori criterion."""

from __future__ import annotations

import numpy as np
import pytest
from tests.helpers.curvecheck import check_curve

import warpmesh as wm
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.quadtree import sample_quadtree
from warpmesh.planar.samplers.rays import sample_rays
from warpmesh.mesh import Mesh

CIRCLE = (wm.circle(1.0), ((-1.2, -1.2), (1.2, 1.2)))
ELLIPSE = (wm.ellipse((1.0, 0.1)), ((-1.2, -0.3), (1.2, 0.3)))
TWO = (wm.circle(0.5, (-0.505, 0.0)) | wm.circle(0.5, (0.505, 0.0)), ((-1.2, -0.7), (1.2, 0.7)))


def run(shape, bounds, **kw):
    s = sample_rays(PlanarField(shape, bounds), **kw)
    return s, Mesh(s.points, {"line": s.segments})


@pytest.mark.parametrize("direction", ["x", "y", "both"])
def test_circle(direction):
    shape, bounds = CIRCLE
    s, mesh = run(shape, bounds, direction=direction)
    m = check_curve(mesh, shape, bounds, n_components=1)
    spacing = 2.4 / 64
    assert np.allclose(np.linalg.norm(s.points, axis=1), 1.0, atol=1e-6)
    # single family: the turning points are cut flat on the last ray (at most one spacing off);
    # both families: the grid of rays catches them
    assert m["hausdorff"] <= (spacing / 4 if direction != "both" else spacing / 50)
    rays = 64 * (2 if direction == "both" else 1)
    assert s.info["rays"] == rays and s.info["crossings"] == len(s.points)


@pytest.mark.parametrize("direction", ["x", "y", "both"])
def test_ellipse(direction):
    shape, bounds = ELLIPSE
    s, mesh = run(shape, bounds, direction=direction)
    m = check_curve(mesh, shape, bounds, n_components=1)
    assert m["hausdorff"] < 0.01


def test_points_lie_on_their_rays():
    shape, bounds = CIRCLE
    s, _ = run(shape, bounds, n_rays=16, direction="x")
    rays = -1.2 + (np.arange(16) + 0.5) * 2.4 / 16
    assert np.all(np.min(np.abs(s.points[:, 1, None] - rays[None]), axis=1) < 1e-12)
    s, _ = run(shape, bounds, n_rays=16, direction="y")
    assert np.all(np.min(np.abs(s.points[:, 0, None] - rays[None]), axis=1) < 1e-12)


def test_horizontal_and_vertical_rays_sample_differently():
    # Fig 16.2: the ellipse's flat sides are cut along horizontal rays close to the curve, its
    # tips (curvature 100) along vertical rays a whole ray spacing away
    shape, bounds = ELLIPSE
    sx, mx = run(shape, bounds, direction="x")
    sy, my = run(shape, bounds, direction="y")
    hx = check_curve(mx, shape, bounds, n_components=1)["hausdorff"]
    hy = check_curve(my, shape, bounds, n_components=1)["hausdorff"]
    assert hy > 3 * hx
    assert abs(len(sx.points) - len(sy.points)) > 0.5 * min(len(sx.points), len(sy.points))
    # and the topology can change: two circles 0.01 apart merge along vertical rays
    shape, bounds = TWO
    _, mx = run(shape, bounds, direction="x")
    sy, my = run(shape, bounds, direction="y")
    check_curve(mx, shape, bounds, n_components=2)
    assert sy.info["components"] == 1
    with pytest.raises(AssertionError):
        check_curve(my, shape, bounds, n_components=2)


@pytest.mark.parametrize("direction", ["x", "y", "both"])
def test_component_between_two_rays_is_missed(direction):
    # a circle of radius 0.01 centred at (0, 1.05), midway between rays in both directions
    shape = wm.circle(1.0) | wm.circle(0.01, (0.0, 1.05))
    bounds = CIRCLE[1]
    s, _ = run(shape, bounds, direction=direction)
    assert s.info["components"] == 1
    assert np.all(np.linalg.norm(s.points - [0.0, 1.05], axis=1) > 0.01)
    # the quadtree's interval culling finds it
    q = sample_quadtree(PlanarField(shape, bounds), tolerance=1e-2)
    assert q.info["components"] == 2


def test_component_on_a_single_ray_is_flat():
    # radius 0.01 around a point of ray 60 (x rays): its two crossings, joined twice
    y60 = -1.2 + 60.5 * 2.4 / 64
    shape = wm.circle(1.0) | wm.circle(0.01, (0.003, y60))
    s, _ = run(shape, CIRCLE[1], direction="x")
    assert s.info["components"] == 2
    on = np.flatnonzero(np.abs(s.points[:, 1] - y60) < 1e-12)
    assert len(on) == 2
    loop = s.segments[np.isin(s.segments, on).any(axis=1)]
    assert sorted(map(tuple, loop)) == sorted([(on[0], on[1]), (on[1], on[0])])  # zero area


def test_near_tangent_part_is_missed():
    # ray 58 (y = 0.99375) cuts the circle's top over 2 sqrt(2 r d) ~ 0.0028 < the sample
    # spacing 0.0094, between two samples: no sign change, no crossing on that ray
    n, spacing = 64, 2.4 / 256
    y58 = -1.2 + 58.5 * 2.4 / n
    cx = 0.5 * spacing  # midway between samples
    shape = wm.circle(1.0, (cx, y58 - 1.0 + 1e-6))
    field = PlanarField(shape, CIRCLE[1])
    assert field.values([[cx, y58]])[0] > 0  # the exact curve crosses the ray
    s = sample_rays(field, n_rays=n, direction="x")
    assert not np.any(np.abs(s.points[:, 1] - y58) < 1e-9)
    # with 4x the samples along the rays it is found
    s = sample_rays(field, n_rays=n, direction="x", samples_per_ray=1024)
    assert np.count_nonzero(np.abs(s.points[:, 1] - y58) < 1e-9) == 2


@pytest.mark.parametrize("b, n", [(0.95, 2), (1.05, 1)])
def test_cassini_with_enough_rays(b, n):
    shape, bounds = wm.cassini(1.0, b), ((-1.6, -0.7), (1.6, 0.7))
    _, mesh = run(shape, bounds, direction="x", n_rays=64)
    m = check_curve(mesh, shape, bounds, n_components=n)
    assert m["hausdorff"] < 1.4 / 64


def test_both_families_two_circles():
    shape, bounds = TWO
    s, mesh = run(shape, bounds, direction="both", n_rays=128)
    m = check_curve(mesh, shape, bounds, n_components=2)
    assert m["hausdorff"] < 1e-3
    assert s.cells.shape[1] == 4 and len(s.cells) > 0


def test_curve_leaving_the_box_stays_open():
    shape, bounds = wm.circle(1.0, (0.5, 0.0)), CIRCLE[1]
    s, _ = run(shape, bounds, direction="x")
    n = len(s.points)
    indeg, outdeg = np.bincount(s.segments[:, 1], minlength=n), np.bincount(s.segments[:, 0], minlength=n)
    ends = np.flatnonzero(indeg != outdeg)
    assert len(ends) == 2  # the last crossings before the curve leaves the box, within a ray spacing
    exits = np.array([[1.2, np.sqrt(1 - 0.7**2)], [1.2, -np.sqrt(1 - 0.7**2)]])
    d = np.linalg.norm(s.points[ends, None] - exits[None], axis=2).min(axis=1)
    assert np.all(d < 2.4 / 64)


def test_bad_arguments():
    field = PlanarField(*CIRCLE)
    with pytest.raises(TypeError, match="field"):
        sample_rays(CIRCLE[0])
    with pytest.raises(ValueError, match="n_rays"):
        sample_rays(field, n_rays=0)
    with pytest.raises(ValueError, match="n_rays"):
        sample_rays(field, n_rays=1, direction="both")
    with pytest.raises(ValueError, match="direction"):
        sample_rays(field, direction="z")
    with pytest.raises(ValueError, match="tolerance"):
        sample_rays(field, tolerance=-1.0)
    with pytest.raises(ValueError, match="samples_per_ray"):
        sample_rays(field, samples_per_ray=1)
