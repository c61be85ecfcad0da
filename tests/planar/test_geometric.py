"""Geometric meshes of implicit curves [FG §16.2.2, Def. 16.4, §16.3.2]: warpmesh.planar.geometric.

The raw polylines come from a dense sampler written here (exact parametrisations,
oriented with the domain on the left), independent of the library's samplers.
"""

from __future__ import annotations

import numpy as np
import pytest
from tests.helpers.curvecheck import check_curve

import warpmesh as wm
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.geometric import geometric_mesh
from warpmesh.planar.metric import chord_size
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.mesh import Mesh
from warpmesh.planar.polyline import orient_segments


# -- a test sampler: points of exact parametrisations -------------------------------------------
def _loops(*point_loops, field=None) -> CurveSample:
    """Closed polylines through the given (n_k, 2) loops; oriented by the field if given."""
    pts, segs, off = [], [], 0
    for p in point_loops:
        n = len(p)
        pts.append(p)
        segs.append(off + np.column_stack([np.arange(n), np.roll(np.arange(n), -1)]))
        off += n
    pts, segs = np.concatenate(pts), np.concatenate(segs)
    if field is not None:
        _, g = field.value_gradient(0.5 * (pts[segs[:, 0]] + pts[segs[:, 1]]))
        segs = orient_segments(pts, segs, g)
    return CurveSample(pts, segs)


def _ellipse_points(a, b, n, center=(0.0, 0.0), phase=0.0):
    t = phase + np.linspace(0.0, 2 * np.pi, n, endpoint=False)  # counter-clockwise
    return np.column_stack([center[0] + a * np.cos(t), center[1] + b * np.sin(t)])


def _mesh(out: CurveSample) -> Mesh:
    return Mesh(out.points, {"line": out.segments})


#: float32 tape: positions are known to a few 1e-7 (the bound on Hausdorff distances adds it)
F32_SLACK = 5e-7


def _lengths(out):
    p, s = out.points, out.segments
    return np.linalg.norm(p[s[:, 1]] - p[s[:, 0]], axis=1)


# -- chord deviations on the ellipse, measured exactly in float64 ----------------------------------
def _ellipse_chord_deviation(points, segments, a, b, samples=16):
    """Largest distance between each edge and its arc (points on x²/a² + y²/b² = 1, edges
    shorter than half the ellipse): arc points by the parameter, distance to the chord."""
    t = np.arctan2(points[:, 1] / b, points[:, 0] / a)
    t0, t1 = t[segments[:, 0]], t[segments[:, 1]]
    dt = (t1 - t0 + np.pi) % (2 * np.pi) - np.pi
    s = np.linspace(0.0, 1.0, samples)
    ts = t0[:, None] + s[None] * dt[:, None]
    q = np.stack([a * np.cos(ts), b * np.sin(ts)], axis=2)  # (m, samples, 2)
    pa, pb = points[segments[:, 0]][:, None], points[segments[:, 1]][:, None]
    d = pb - pa
    w = q - pa
    u = np.clip(np.sum(w * d, axis=2) / np.maximum(np.sum(d * d, axis=2), 1e-300), 0.0, 1.0)
    return np.linalg.norm(w - u[..., None] * d, axis=2).max(axis=1)


def _uniform_ellipse(a, b, n):
    """n vertices equally spaced in arc length (equal edges to first order) and their segments."""
    t = np.linspace(0.0, 2 * np.pi, 200001)
    ds = np.hypot(a * np.sin(t), b * np.cos(t))
    s = np.r_[0.0, np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(t))]
    tu = np.interp(np.linspace(0.0, s[-1], n, endpoint=False), s, t)
    pts = np.column_stack([a * np.cos(tu), b * np.sin(tu)])
    return pts, np.column_stack([np.arange(n), np.roll(np.arange(n), -1)])


def ellipse_uniform_factor(a=1.0, b=0.1, tolerance=1e-3):
    """(factor, geometric vertices, uniform vertices, worst chord error): the uniform polyline
    with the same worst chord deviation as the geometric mesh needs ``factor`` times more
    vertices; its edge count comes from a bisection (the deviation decreases with it)."""
    field = PlanarField(wm.ellipse((a, b)), ((-1.2 * a, -2 * b), (1.2 * a, 2 * b)))
    out = geometric_mesh(field, _loops(_ellipse_points(a, b, 3000)), tolerance=tolerance)
    worst = float(_ellipse_chord_deviation(out.points, out.segments, a, b).max())
    lo, hi = 8, 8
    while _ellipse_chord_deviation(*_uniform_ellipse(a, b, hi), a, b).max() > worst:
        lo, hi = hi, 2 * hi
    while hi - lo > 1:  # smallest n whose worst deviation is <= worst
        mid = (lo + hi) // 2
        if _ellipse_chord_deviation(*_uniform_ellipse(a, b, mid), a, b).max() > worst:
            lo = mid
        else:
            hi = mid
    return hi / len(out.points), len(out.points), hi, worst


# -- circles --------------------------------------------------------------------------------------
@pytest.mark.parametrize("raw_points", [24, 2000])
def test_circle_vertex_count_and_chord_deviation(raw_points):
    eps, r = 1e-3, 1.0
    field = PlanarField(wm.circle(r), ((-2, -2), (2, 2)))
    out = geometric_mesh(field, _loops(_ellipse_points(r, r, raw_points)), tolerance=eps)
    expected = int(np.ceil(2 * np.pi * r / (8 * eps * r)))  # closed form for h = 8 eps r: 786
    assert abs(out.info["vertices"] - expected) <= 2
    assert out.info["components"] == 1 and len(out.info["curvature_extrema"]) == 0
    h = _lengths(out)
    mid = 0.5 * (out.points[out.segments[:, 0]] + out.points[out.segments[:, 1]])
    delta = r - np.linalg.norm(mid, axis=1)  # exact chord deviation of a circle's chord
    assert np.all(delta <= eps * h + 2e-7)
    assert out.info["max_relative_deviation"] <= eps * 1.02
    res = check_curve(_mesh(out), field.shape, field.bounds, n_components=1, hausdorff=eps * h.max() + F32_SLACK)
    assert res["wrong_orientation"] == 0


def test_chord_size_is_exact_on_circles():
    eps, rho = 0.05, 2.0
    h = float(chord_size(rho, eps))
    sagitta = rho - np.sqrt(rho**2 - h**2 / 4)
    assert sagitta == pytest.approx(eps * h, rel=1e-12)
    assert h == pytest.approx(8 * eps * rho, rel=0.02)


# -- the ellipse: acceptance -------------------------------------------------------------------------
def test_ellipse_geometric_mesh_beats_uniform_polyline():
    factor, n_geo, n_uni, worst = ellipse_uniform_factor(1.0, 0.1, 1e-3)
    print(f"ellipse 1 x 0.1, eps 1e-3: geometric {n_geo} vertices, uniform {n_uni} for the same "
          f"max chord error {worst:.3g}: factor {factor:.2f}")
    assert factor > 1.5


def test_ellipse_vertices_are_mesh_vertices():
    a, b = 1.0, 0.1
    field = PlanarField(wm.ellipse((a, b)), ((-1.2, -0.2), (1.2, 0.2)))
    out = geometric_mesh(field, _loops(_ellipse_points(a, b, 3000, phase=0.3)), tolerance=1e-3)
    apex = np.array([[a, 0.0], [0.0, b], [-a, 0.0], [0.0, -b]])
    dist = np.linalg.norm(out.points[None] - apex[:, None], axis=2)
    near, gap = dist.argmin(axis=1), dist.min(axis=1)
    h = _lengths(out)
    local = np.array([h[(out.segments == v).any(axis=1)].max() for v in near])
    assert np.all(gap < 2e-3 * local), gap / local  # located to 0.2% of the local edge
    assert len(out.info["curvature_extrema"]) == 4
    assert h.max() / h.min() > 50  # sizes follow the radius of curvature (0.01 to 10)
    check_curve(_mesh(out), field.shape, field.bounds, n_components=1, hausdorff=1e-3 * h.max() + F32_SLACK)


# -- singular points, close components, open chains, corners ----------------------------------
def test_lemniscate_two_loops_share_the_origin():
    shape, bounds = wm.cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6))
    field = PlanarField(shape, bounds)
    c = np.sqrt(2.0)
    t = np.linspace(0.0, 2 * np.pi, 1200, endpoint=False) + 0.5 * 2 * np.pi / 1200  # misses the origin
    den = 1 + np.sin(t) ** 2
    raw = _loops(np.column_stack([c * np.cos(t) / den, c * np.sin(t) * np.cos(t) / den]), field=field)
    out = geometric_mesh(field, raw, tolerance=2e-3)
    origin = np.flatnonzero(np.linalg.norm(out.points, axis=1) < 1e-9)
    assert len(origin) == 1
    s = out.segments
    assert np.count_nonzero(s[:, 0] == origin[0]) == 2 and np.count_nonzero(s[:, 1] == origin[0]) == 2
    assert out.info["components"] == 1 and len(out.info["singular_points"]) == 1
    check_curve(_mesh(out), shape, bounds, n_components=1, singular=[(0.0, 0.0)],
                hausdorff=2e-3 * _lengths(out).max() + F32_SLACK)


def test_two_circles_nearly_touching_stay_apart():
    r, gap = 0.5, 0.01
    cx = r + gap / 2
    shape = wm.circle(r, (-cx, 0.0)) | wm.circle(r, (cx, 0.0))
    bounds = ((-1.2, -0.7), (1.2, 0.7))
    field = PlanarField(shape, bounds)
    raw = _loops(_ellipse_points(r, r, 800, (-cx, 0.0)), _ellipse_points(r, r, 800, (cx, 0.0)))
    out = geometric_mesh(field, raw, tolerance=1e-3)
    assert out.info["components"] == 2
    check_curve(_mesh(out), shape, bounds, n_components=2, hausdorff=1e-3 * _lengths(out).max() + F32_SLACK)


def test_open_chain_ends_on_the_box():
    field = PlanarField(wm.circle(1.0), ((0.0, -2.0), (2.0, 2.0)))
    t = np.linspace(-np.pi / 2, np.pi / 2, 200)
    pts = np.column_stack([np.cos(t), np.sin(t)])
    pts[[0, -1], 0] = 0.0
    raw = CurveSample(pts, np.column_stack([np.arange(199), np.arange(1, 200)]))
    out = geometric_mesh(field, raw, tolerance=1e-3)
    assert out.info["vertices"] == out.info["edges"] + 1
    ends = out.points[[out.segments[0, 0], out.segments[-1, 1]]]
    np.testing.assert_allclose(np.abs(ends), [[0.0, 1.0], [0.0, 1.0]], atol=1e-6)
    check_curve(_mesh(out), field.shape, field.bounds, n_components=1, closed=False)


def test_rectangle_corners_are_vertices():
    shape, bounds = wm.rectangle((1.0, 0.6)), ((-0.8, -0.5), (0.8, 0.5))
    field = PlanarField(shape, bounds)
    # a raw polygon that cuts the corners, as a grid sampler would
    s = np.linspace(0.0, 3.2, 160, endpoint=False) + 0.007
    x = np.interp(s, [0, 1.0, 1.6, 2.6, 3.2], [0.5, -0.5, -0.5, 0.5, 0.5])
    y = np.interp(s, [0, 1.0, 1.6, 2.6, 3.2], [0.3, 0.3, -0.3, -0.3, 0.3])
    cut = np.column_stack([x, y])
    cut = cut[np.abs(np.abs(cut) - [0.5, 0.3]).max(axis=1) > 0.005]
    out = geometric_mesh(field, _loops(cut, field=field), tolerance=1e-3)
    corners = np.array([[0.5, 0.3], [-0.5, 0.3], [-0.5, -0.3], [0.5, -0.3]])
    gap = np.linalg.norm(out.points[None] - corners[:, None], axis=2).min(axis=1)
    assert np.all(gap < 1e-4), gap
    assert len(out.info["corners"]) == 4
    assert out.info["vertices"] < 60  # straight sides: hmax-sized edges
    check_curve(_mesh(out), shape, bounds, n_components=1, hausdorff=1e-3 * _lengths(out).max() + F32_SLACK)


# -- the metric option (unit meshes, Def. 16.4) ----------------------------------------------------
def test_constant_size_gives_unit_edges():
    field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
    out = geometric_mesh(field, _loops(_ellipse_points(1.0, 1.0, 500)), tolerance=0.1, size=0.05)
    h = _lengths(out)
    assert np.all((h > 0.7 * 0.05) & (h < 1.4 * 0.05)), (h.min(), h.max())
    assert out.info["vertices"] == int(np.ceil(2 * np.pi / 0.05))


def test_graded_size_is_followed():
    field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))

    def size(p):
        return 0.02 + 0.08 * (p[:, 0] + 1.0) / 2.0  # 0.02 on the left, 0.1 on the right

    out = geometric_mesh(field, _loops(_ellipse_points(1.0, 1.0, 500)), tolerance=0.1, size=size)
    h = _lengths(out)
    mid = 0.5 * (out.points[out.segments[:, 0]] + out.points[out.segments[:, 1]])
    ratio = h / size(mid)
    assert np.all((ratio > 0.7) & (ratio < 1.4)), (ratio.min(), ratio.max())
    assert h[mid[:, 0] > 0.8].mean() > 3 * h[mid[:, 0] < -0.8].mean()


def test_geometric_size_wins_where_smaller():
    field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
    out = geometric_mesh(field, _loops(_ellipse_points(1.0, 1.0, 500)), tolerance=1e-3, size=0.05)
    assert _lengths(out).max() <= chord_size(1.0, 1e-3) * 1.001


# -- bad input ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, name", [
    ({"tolerance": -1e-3}, "tolerance"), ({"tolerance": 0.0}, "tolerance"), ({"tolerance": 0.7}, "tolerance"),
    ({"size": 0.0}, "size"), ({"size": -0.1}, "size"), ({"size": "big"}, "size"),
    ({"size": lambda p: np.ones(3)}, "size"), ({"size": lambda p: -np.ones(len(p))}, "size"),
    ({"hmin": 0.5, "hmax": 0.1}, "hmin"), ({"hmax": -1.0}, "hmax"),
    ({"singular": [1.0, 2.0, 3.0]}, "singular"),
])
def test_bad_arguments_name_the_argument(kwargs, name):
    field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
    with pytest.raises(ValueError, match=name):
        geometric_mesh(field, _loops(_ellipse_points(1.0, 1.0, 64)), **kwargs)


def test_empty_sample_is_refused():
    field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
    with pytest.raises(ValueError, match="sample"):
        geometric_mesh(field, CurveSample(np.zeros((0, 2)), np.zeros((0, 2), np.int64)))
    with pytest.raises(TypeError, match="sample"):
        geometric_mesh(field, np.zeros((3, 2)))
