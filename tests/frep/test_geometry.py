"""Differential geometry of implicit curves and surfaces (warpmesh.frep.geometry, warpmesh.frep.lipschitz)
against closed forms: circles, ellipses, spheres, tori, quadratics, Cassini ovals."""

from __future__ import annotations

import math

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep import geometry as geo
from warpmesh.frep.lipschitz import gradient_enclosure, lipschitz_bound
from warpmesh.frep.examples import example

T = np.linspace(0.0, 2 * math.pi, 97, endpoint=False)


def on_ellipse(a, b, center=(0.0, 0.0)):
    return np.column_stack([a * np.cos(T) + center[0], b * np.sin(T) + center[1]])


def ellipse_curvature(a, b):
    return a * b / (a * a * np.sin(T) ** 2 + b * b * np.cos(T) ** 2) ** 1.5


def random_points(box, n, seed=0):
    box = np.asarray(box, float)
    return box[0] + (box[1] - box[0]) * np.random.default_rng(seed).random((n, box.shape[1]))


# -- first order -----------------------------------------------------------------------------
def test_circle_normal_tangent_orientation(device):
    c = np.array([0.3, -0.2])
    p = on_ellipse(0.7, 0.7, c) * 1.3 - 0.3 * c  # points off the curve too (radius 0.91)
    s = wm.circle(0.7, center=tuple(c))
    n = geo.normal(s, p, device=device)
    radial = (p - c) / np.linalg.norm(p - c, axis=1)[:, None]
    np.testing.assert_allclose(n, -radial, atol=1e-6)  # inward: towards f > 0
    t = geo.tangent(s, p, device=device)
    np.testing.assert_allclose(t, np.column_stack([-radial[:, 1], radial[:, 0]]), atol=1e-6)  # counter-clockwise
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(np.einsum("ij,ij->i", t, n), 0.0, atol=1e-6)


@pytest.mark.parametrize("shape", [wm.ellipse((1.0, 0.3)), wm.cassini(1.0, 1.05), wm.cassini(1.0, 0.9),
                                   wm.ellipse((1.2, 0.7)) - wm.circle(0.2, (0.3, 0.1))])
def test_tangent_keeps_domain_on_the_left(shape):
    bounds = ((-1.6, -1.0), (1.6, 1.0))
    p = geo.project(shape, random_points(bounds, 400, seed=3), max_step=0.05, steps=30)
    f, g = shape.eval_numpy(p[:, 0], p[:, 1]), geo.gradient(shape, p)
    on = (np.abs(f) < 1e-5) & (np.linalg.norm(g, axis=1) > 0.1)
    assert on.sum() > 50
    t = geo.tangent(shape, p[on])
    left = np.column_stack([-t[:, 1], t[:, 0]])
    seed_h = np.column_stack([-g[on, 1], g[on, 0]]) / np.linalg.norm(g[on], axis=1)[:, None]
    np.testing.assert_allclose(t, -seed_h, atol=1e-12)  # the book's H (eq. 16.11) is minus it
    eps = 1e-3
    inside = shape.eval_numpy(*(p[on] + eps * left).T)
    outside = shape.eval_numpy(*(p[on] - eps * left).T)
    assert np.all(inside > 0) and np.all(outside < 0)


def test_gradient_and_normal_3d(device):
    p = random_points(((-2, -2, -2), (2, 2, 2)), 200)
    g = geo.gradient(wm.sphere(1.0), p, device=device)
    np.testing.assert_allclose(g, -p / np.linalg.norm(p, axis=1)[:, None], atol=1e-6)
    x, y = wm.coords(2)
    p2 = random_points(((-2, -2), (2, 2)), 100)
    g2 = geo.gradient(x * x * y - 3 * y, p2, device=device)
    np.testing.assert_allclose(g2, np.column_stack([2 * p2[:, 0] * p2[:, 1], p2[:, 0] ** 2 - 3]), rtol=1e-6, atol=1e-6)
    assert np.all(geo.normal(x * x + y * y, np.zeros((1, 2))) == 0)  # critical point: zero normal


def test_distance_estimate():
    p = random_points(((-3, -3), (3, 3)), 300)
    r = np.linalg.norm(p, axis=1)
    np.testing.assert_allclose(geo.distance_estimate(wm.circle(1.2), p), np.abs(r - 1.2), atol=1e-6)
    x, y = wm.coords(2)
    np.testing.assert_allclose(geo.distance_estimate(1 - x * x - y * y, p), np.abs(1 - r * r) / (2 * r), rtol=1e-5)
    assert geo.distance_estimate(1 - x * x - y * y, np.zeros((1, 2)))[0] == np.inf  # eq. 16.6 undefined


def test_project_2d_3d(device):
    s = wm.ellipse((1.0, 0.4))
    q = geo.project(s, random_points(((-1.5, -1.5), (1.5, 1.5)), 200, seed=1), steps=20, device=device)
    np.testing.assert_allclose(np.hypot(q[:, 0], q[:, 1] / 0.4), 1.0, atol=1e-5)
    p = random_points(((-1.5, -1.5, -0.5), (1.5, 1.5, 0.5)), 200, seed=2)
    p = p[np.hypot(np.hypot(p[:, 0], p[:, 1]) - 1.0, p[:, 2]) > 0.05]  # off the torus' core circle
    q = geo.project(wm.torus(1.0, 0.25), p, device=device)
    np.testing.assert_allclose(np.hypot(np.hypot(q[:, 0], q[:, 1]) - 1.0, q[:, 2]), 0.25, atol=1e-5)
    # the cap: the Newton step from (0.1, 0) to the circle of radius 2 is +1.9 in x: capped to 0.1
    q1 = geo.project(wm.circle(2.0), np.array([[0.1, 0.0]]), max_step=0.1, steps=1)
    np.testing.assert_allclose(q1, [[0.2, 0.0]], atol=1e-7)
    np.testing.assert_allclose(geo.project(wm.circle(1.0), np.zeros((1, 2))), [[0.0, 0.0]])  # grad 0: stays


# -- second order ----------------------------------------------------------------------------
def test_hessian_of_quadratics(device):
    x, y, z = wm.coords()
    a = np.array([[2.0, -1.0, 0.5], [-1.0, 4.0, 3.0], [0.5, 3.0, -6.0]])
    q = (0.5 * (a[0, 0] * x * x + a[1, 1] * y * y + a[2, 2] * z * z)
         + a[0, 1] * x * y + a[0, 2] * x * z + a[1, 2] * y * z)
    p = random_points(((-3, -3, -3), (3, 3, 3)), 50)
    h = geo.hessian(q + 2 * x - 7, p, device=device)
    np.testing.assert_allclose(h, np.broadcast_to(a, h.shape), atol=1e-4 * 6)  # measured 7e-5
    x, y = wm.coords(2)
    p2 = random_points(((-2, -2), (2, 2)), 50)
    h2 = geo.hessian(x**3 * y + y**2, p2)  # exact: [[6xy, 3x²], [3x², 2]]
    xs, ys = p2.T
    ref = np.stack([np.column_stack([6 * xs * ys, 3 * xs**2]), np.column_stack([3 * xs**2, 2 + 0 * xs])], axis=1)
    np.testing.assert_allclose(h2, ref, atol=2e-4 * np.abs(ref).max())
    assert np.allclose(h2, h2.transpose(0, 2, 1))


@pytest.mark.parametrize("a, b, center", [(1.0, 1.0, (0.0, 0.0)), (2.0, 1.0, (0.0, 0.0)), (1.0, 0.1, (0.0, 0.0)),
                                          (0.3, 0.3, (0.5, 0.2)), (1.0, 0.5, (10.0, -5.0))])
def test_ellipse_curvature(a, b, center, device):
    s = wm.ellipse((a, b), center=center)
    k = geo.curvature(s, on_ellipse(a, b, center), device=device)
    ref = ellipse_curvature(a, b)
    # HESSIAN_STEP = 1e-3: measured worst 5e-5 relative over these cases
    assert np.abs(k - ref).max() <= 1e-4 * ref.max()
    ends = np.array([[a, 0.0], [0.0, b]]) + center
    np.testing.assert_allclose(geo.curvature(s, ends), [a / b**2, b / a**2], rtol=2e-4)
    np.testing.assert_allclose(geo.radius_of_curvature(s, ends), [b**2 / a, a**2 / b], rtol=2e-4)


def test_curvature_sign_inflection_and_radius():
    ring = wm.circle(2.0) - wm.circle(1.0)  # R-function difference: the outer circle convex, the hole concave
    p = np.array([[2.0, 0.0], [0.0, -2.0], [1.0, 0.0], [0.0, 1.0]])
    np.testing.assert_allclose(geo.curvature(ring, p), [0.5, 0.5, -1.0, -1.0], rtol=1e-3)
    x, y = wm.coords(2)
    xs = np.linspace(-1.0, 1.0, 21)
    cubic = y - x**3  # domain above the cubic: convex for x > 0, inflection at 0
    pts = np.column_stack([xs, xs**3])
    np.testing.assert_allclose(geo.curvature(cubic, pts), 6 * xs / (1 + 9 * xs**4) ** 1.5, atol=1e-4)
    hf = geo.inflection_function(cubic, pts)
    np.testing.assert_allclose(hf, -6 * xs, atol=1e-4)
    half = wm.halfplane((1.0, 1.0))
    assert np.all(geo.radius_of_curvature(half, pts) == np.inf)  # kappa = 0 exactly on a line
    assert np.isnan(geo.curvature(x * x + y * y, np.zeros((1, 2))))[0]


def test_hessian_step_adapts_to_the_feature_size():
    tiny = wm.circle(1e-3, center=(0.2, 0.0))
    p = np.array([[0.201, 0.0], [0.2, -1e-3]])
    np.testing.assert_allclose(geo.curvature(tiny, p), 1e3, rtol=1e-4)  # the default: two passes
    np.testing.assert_allclose(geo.curvature(tiny, p, step=5e-6), 1e3, rtol=1e-3)
    assert np.abs(geo.curvature(tiny, p, step=1e-3) - 1e3).max() > 10  # a fixed step too coarse there
    big = wm.ellipse((50.0, 30.0))
    np.testing.assert_allclose(geo.curvature(big, np.array([[50.0, 0.0]])), 50 / 30**2, rtol=1e-4)


def test_sphere_principal_curvatures(device):
    p = np.random.default_rng(4).normal(size=(200, 3))
    p = 0.7 * p / np.linalg.norm(p, axis=1)[:, None] + np.array([0.1, 0.2, -0.3])
    k1, k2, d1, d2 = geo.principal_curvatures(wm.sphere(0.7, center=(0.1, 0.2, -0.3)), p, device=device)
    np.testing.assert_allclose(k1, 1 / 0.7, rtol=1e-4)
    np.testing.assert_allclose(k2, 1 / 0.7, rtol=1e-4)
    n = (p - [0.1, 0.2, -0.3]) / 0.7
    for d in (d1, d2):
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.einsum("ij,ij->i", d, n), 0.0, atol=1e-6)  # float32 normals
    np.testing.assert_allclose(np.einsum("ij,ij->i", d1, d2), 0.0, atol=1e-12)


def test_torus_principal_curvatures():
    big, small = 1.0, 0.25
    u, v = [a.ravel() for a in np.meshgrid(np.linspace(0, 2 * math.pi, 13), np.linspace(0, 2 * math.pi, 17))]
    rho = big + small * np.cos(v)
    p = np.column_stack([rho * np.cos(u), rho * np.sin(u), small * np.sin(v)])
    k1, k2, d1, d2 = geo.principal_curvatures(wm.torus(big, small), p)
    k_meridian, k_parallel = np.full_like(v, 1 / small), np.cos(v) / rho  # convex side positive
    np.testing.assert_allclose(k1, np.maximum(k_meridian, k_parallel), atol=1e-4 / small)
    np.testing.assert_allclose(k2, np.minimum(k_meridian, k_parallel), atol=1e-4 / small)
    meridian = np.column_stack([-np.sin(v) * np.cos(u), -np.sin(v) * np.sin(u), np.cos(v)])  # d/dv, unit
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", d1, meridian)), 1.0, atol=1e-6)
    # outer equator: 1/r and 1/(R + r); inner equator: 1/r and -1/(R - r) (a saddle)
    k1, k2, _, _ = geo.principal_curvatures(wm.torus(big, small), np.array([[1.25, 0, 0], [0, -0.75, 0]]))
    np.testing.assert_allclose(k1, [4.0, 4.0], rtol=1e-4)
    np.testing.assert_allclose(k2, [0.8, -1 / 0.75], rtol=1e-4)


# -- critical and singular points ------------------------------------------------------------
def test_critical_points_double_well(device):
    x, y = wm.coords(2)
    cp = geo.critical_points((x * x - 1) ** 2 + y * y, ((-2, -1.3), (2.2, 1.1)), device=device)
    np.testing.assert_allclose(cp["points"], [[-1, 0], [0, 0], [1, 0]], atol=1e-6)
    assert cp["kind"] == ["minimum", "saddle", "minimum"]
    np.testing.assert_allclose(cp["values"], [0, 1, 0], atol=1e-10)
    np.testing.assert_allclose(cp["hessian"][1], [[-4, 0], [0, 2]], atol=1e-3)
    x, y, z = wm.coords()
    cp3 = geo.critical_points(-((x * x - 1) ** 2) - y * y - 2 * z * z + x * y * 0.1,
                              ((-1.7, -1.1, -0.9), (1.5, 1.2, 1.3)), resolution=24)
    assert cp3["kind"] == ["maximum", "saddle", "maximum"]
    assert np.abs(cp3["points"][1]).max() < 1e-6


@pytest.mark.parametrize("b", [0.8, 0.95, 1.0, 1.05, 1.3])
def test_cassini_critical_points(b):
    """f = b⁴ - ((x² + y² + a²)² - 4a²x²): maxima b⁴ at the foci (±a, 0), a saddle b⁴ - a⁴ at 0."""
    a = 1.0
    cp = geo.critical_points(wm.cassini(a, b), ((-1.9, -1.1), (1.7, 1.3)))
    np.testing.assert_allclose(cp["points"], [[-a, 0], [0, 0], [a, 0]], atol=1e-6)
    assert cp["kind"] == ["maximum", "saddle", "maximum"]
    np.testing.assert_allclose(cp["values"], [b**4, b**4 - a**4, b**4], atol=1e-9)
    # Hessians: at the foci -8a²(I) (diag -8, -8), at the origin diag(4a², -4a²)
    np.testing.assert_allclose(cp["hessian"][[0, 2]], np.broadcast_to(-8 * np.eye(2), (2, 2, 2)), rtol=1e-4, atol=1e-3)
    np.testing.assert_allclose(cp["hessian"][1], np.diag([4, -4]), atol=1e-3)
    sp = geo.singular_points(wm.cassini(a, b), ((-1.9, -1.1), (1.7, 1.3)))
    assert len(sp["points"]) == (1 if b == 1.0 else 0)


def test_degenerate_and_extrema_kinds():
    x, y = wm.coords(2)
    box = ((-1, -1.2), (1.3, 1))
    assert geo.critical_points(x**4 + y * y, box)["kind"] == ["degenerate"]
    assert geo.critical_points(-(x * x) - 2 * y * y + x * y, box)["kind"] == ["maximum"]
    assert geo.critical_points(x * x + y * y, box)["kind"] == ["minimum"]
    assert len(geo.critical_points(x + 2 * y, box)["points"]) == 0
    outside = geo.critical_points((x - 3) ** 2 + y * y, box)  # the minimum lies outside the box
    assert len(outside["points"]) == 0


def test_lemniscate_singular_point(device):
    sp = geo.singular_points(wm.cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6)), device=device)
    assert sp["points"].shape == (1, 2) and np.abs(sp["points"]).max() < 1e-7
    assert sp["kind"] == ["saddle"] and abs(sp["values"][0]) < 1e-12
    moved = wm.cassini(1.0, 1.0).rotate(0.3).translate((0.37, 0.21))
    sp = geo.singular_points(moved, ((-1.5, -1.5), (2.0, 2.0)))
    np.testing.assert_allclose(sp["points"], [[0.37, 0.21]], atol=1e-6)
    x, y = wm.coords(2)
    assert geo.singular_points(y * y - x**3, ((-1, -1), (1, 1)))["kind"] == ["degenerate"]  # cusp
    assert geo.singular_points(-(x * x) - y * y, ((-1, -1), (1, 1)))["kind"] == ["maximum"]  # isolated point


def test_singular_points_tolerance_and_thin_walls():
    near = wm.cassini(1.0, 1.01)  # the ovals' neck: a saddle with f = 0.04, not on the curve
    box = ((-1.6, -0.6), (1.6, 0.6))
    assert len(geo.singular_points(near, box)["points"]) == 0
    assert geo.singular_points(near, box, tolerance=0.05)["kind"] == ["saddle"]
    gear, bounds = example("gear")  # a 0.02 wall between the key way and a hole: a saddle near f = 0
    assert len(geo.singular_points(gear, bounds)["points"]) == 0
    x, y, z = wm.coords()
    cone = geo.singular_points(x * x + y * y - z * z, ((-1, -1, -1), (1.2, 1.1, 1.3)), resolution=16)
    assert cone["kind"] == ["saddle"] and np.abs(cone["points"]).max() < 1e-7


def test_inflection_points():
    x, y = wm.coords(2)
    ip = geo.inflection_points(y - wm.sin(x), ((-4, -2), (4.3, 2)))  # y = sin x: inflections at k pi
    np.testing.assert_allclose(ip["points"], [[-math.pi, 0], [0, 0], [math.pi, 0]], atol=1e-5)
    # the domain y > sin x is convex where sin is: kappa' = -cos x / (1 + cos² x)^1.5 per unit x,
    # times dx/ds = 1 / sqrt(2): -1/4 at 0, +1/4 at ±pi (the central difference over half a cell)
    np.testing.assert_allclose(ip["curvature_slope"], [0.25, -0.25, 0.25], rtol=2e-2)
    a, b = 1.0, 1.05  # a dented Cassini oval: 4 inflections on r⁴ = (b⁴ - a⁴) / 3
    ip = geo.inflection_points(wm.cassini(a, b), ((-1.6, -0.7), (1.6, 0.7)))
    assert ip["points"].shape == (4, 2)
    np.testing.assert_allclose(np.linalg.norm(ip["points"], axis=1), ((b**4 - a**4) / 3) ** 0.25, rtol=5e-5)
    np.testing.assert_allclose(np.abs(ip["points"]), np.abs(ip["points"][[0, 0, 0, 0]]), rtol=5e-5)  # symmetric
    for convex in (wm.ellipse((1.0, 0.3)), wm.cassini(1.0, 1.5), wm.regular_polygon(6)):
        assert len(geo.inflection_points(convex, ((-2, -2), (2, 2)))["points"]) == 0
    assert len(geo.inflection_points(wm.cassini(1.0, 1.0), ((-1.6, -0.7), (1.6, 0.7)))["points"]) == 0
    with pytest.raises(ValueError, match="2D 'bounds'"):
        geo.inflection_points(wm.circle(1.0), ((-1, -1, -1), (1, 1, 1)))


# -- Lipschitz bound -------------------------------------------------------------------------
_X, _Y = wm.coords(2)
LIPSCHITZ_CASES = [
    ("circle", wm.circle(1.0, center=(0.3, 0.1)), ((-2, -2), (2, 2)), 1.05),
    ("ellipse", wm.ellipse((1.0, 0.1)), ((-1.5, -1.5), (1.5, 1.5)), 1.05),
    ("rfunction union", wm.circle(0.5, (-0.6, 0)) | wm.circle(0.5, (0.6, 0)), ((-1.5, -1.5), (1.5, 1.5)), 1.25),
    ("minmax union", wm.union(wm.circle(0.5, (-0.6, 0)), wm.circle(0.5, (0.6, 0)), method="minmax"),
     ((-1.5, -1.5), (1.5, 1.5)), 1.05),
    ("cassini", wm.cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6)), 1.25),
    ("polygon", wm.regular_polygon(5), ((-1, -1), (1, 1)), 1.05),
    ("rectangle", wm.rectangle((1.0, 0.5)), ((-1, -1), (1, 1)), 2.5),  # outside + inside: a sum
    ("smooth union", wm.union(wm.circle(0.5, (-0.6, 0)), wm.circle(0.5, (0.6, 0)), method="smooth", k=0.2),
     ((-1.5, -1.5), (1.5, 1.5)), 2.5),
    ("elementary", wm.sin(3 * _X) * wm.cos(2 * _Y) + _X / (2 + _Y * _Y) + abs(_X) ** 1.5 + wm.exp(_Y)
     - wm.log(_X * _X + 1) + 0.1 / (_X + 3) + (_Y + 2) ** -2, ((-1, -1), (1, 1)), 1.25),
    ("sphere", wm.sphere(1.0), ((-2, -2, -2), (2, 2, 2)), 1.05),
    ("torus", wm.torus(1.0, 0.25), ((-1.5, -1.5, -1.5), (1.5, 1.5, 1.5)), 1.5),
]


@pytest.mark.parametrize("name, shape, bounds, factor", LIPSCHITZ_CASES, ids=[c[0] for c in LIPSCHITZ_CASES])
def test_lipschitz_bound_encloses_and_is_tight(name, shape, bounds, factor):
    b = np.asarray(bounds, float)
    d = b.shape[1]
    p = np.concatenate([random_points(b, 20000 if d == 2 else 40000, seed=5),
                        np.array(np.meshgrid(*b.T, indexing="ij")).reshape(d, -1).T])  # + the corners
    sampled = np.linalg.norm(geo.gradient(shape, p), axis=1).max()
    bound = lipschitz_bound(shape, bounds, depth=4 if d == 3 else 5)
    assert sampled * (1 - 1e-5) <= bound <= factor * sampled, (name, sampled, bound)


def test_lipschitz_enclosure_per_box_and_distance_bound():
    shape = wm.circle(0.5, (-0.6, 0)) | wm.circle(0.5, (0.6, 0))
    bound, lo, hi, norms = lipschitz_bound(shape, ((-1.5, -1.5), (1.5, 1.5)), depth=4, local=True)
    assert np.isclose(np.prod(hi - lo, axis=1).sum(), 9.0)  # the final boxes tile the box
    assert bound == norms.max()
    # every box's gradient and value enclosures hold at points inside it
    k = np.random.default_rng(6).integers(0, len(lo), 3000)
    p = lo[k] + (hi[k] - lo[k]) * np.random.default_rng(7).random((3000, 2))
    value, glo, ghi, nb = gradient_enclosure(shape, lo, hi)
    g = geo.gradient(shape, p)
    f = shape.eval_numpy(p[:, 0], p[:, 1])
    tol = 1e-6
    assert np.all((g >= glo[k] - tol) & (g <= ghi[k] + tol))
    assert np.all((f >= value[k, 0] - tol) & (f <= value[k, 1] + tol))
    assert np.all(np.linalg.norm(g, axis=1) <= nb[k] + tol)
    # |f| / lambda is a lower bound of the distance to the curve (closed form: two discs)
    q = random_points(((-1.2, -1.2), (1.2, 1.2)), 2000, seed=8)
    dist = np.abs(np.linalg.norm(q[:, None, :] - [[-0.6, 0], [0.6, 0]], axis=2) - 0.5).min(axis=1)
    est = np.abs(shape.eval_numpy(q[:, 0], q[:, 1])) / bound
    assert np.all(est <= dist + 1e-12)
    assert np.median(est / dist) > 0.3  # and not vacuous


def test_lipschitz_unbounded_and_refinement():
    x, y = wm.coords(2)
    assert lipschitz_bound(wm.sqrt(abs(x)) + y, ((-1, -1), (1, 1))) == np.inf  # sqrt at 0: unbounded
    assert lipschitz_bound(1 / x, ((-1, -1), (1, 1))) == np.inf
    assert np.isfinite(lipschitz_bound(wm.sqrt(abs(x)) + y, ((0.5, -1), (1, 1))))
    gear, bounds = example("gear")
    coarse = lipschitz_bound(gear, bounds, depth=4, refine=0)
    refined = lipschitz_bound(gear, bounds, depth=4)
    sampled = np.linalg.norm(geo.gradient(gear, random_points(bounds, 20000, seed=9)), axis=1).max()
    assert sampled <= refined < coarse and refined < 2 * sampled  # nested R-unions: branch and bound pays


# -- bad input -------------------------------------------------------------------------------
def test_bad_points():
    s = wm.circle(1.0)
    with pytest.raises(ValueError, match="points"):
        geo.gradient(s, np.zeros((3, 4)))
    with pytest.raises(ValueError, match="points"):
        geo.normal(s, np.zeros(2))
    with pytest.raises(ValueError, match="finite"):
        geo.curvature(s, np.array([[np.nan, 0.0]]))
    with pytest.raises(TypeError, match="numeric"):
        geo.hessian(s, np.array([["a", "b"]]))
    with pytest.raises(TypeError, match="shape"):
        geo.gradient("circle", np.zeros((1, 2)))
    with pytest.raises(ValueError, match="depends on z"):
        geo.gradient(wm.sphere(1.0), np.zeros((1, 2)))
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        geo.tangent(s, np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"\(n, 2\)"):
        geo.curvature(s, np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        geo.principal_curvatures(wm.sphere(1.0), np.zeros((1, 2)))


def test_bad_options():
    s = wm.circle(1.0)
    with pytest.raises(ValueError, match="step"):
        geo.hessian(s, np.zeros((1, 2)), step=0.0)
    with pytest.raises(ValueError, match="max_step"):
        geo.project(s, np.zeros((1, 2)), max_step=-1.0)
    with pytest.raises(ValueError, match="steps"):
        geo.project(s, np.zeros((1, 2)), steps=0)
    with pytest.raises(ValueError, match="resolution"):
        geo.critical_points(s, ((-1, -1), (1, 1)), resolution=1)
    with pytest.raises(ValueError, match="tolerance"):
        geo.singular_points(s, ((-1, -1), (1, 1)), tolerance=-1.0)


@pytest.mark.parametrize("bounds", [((1, -1), (-1, 1)), ((0, 0, 0, 0), (1, 1, 1, 1)), ((np.nan, 0), (1, 1)),
                                    "box", ((0, 0), (0, 1))])
def test_bad_bounds(bounds):
    with pytest.raises(ValueError, match="bounds"):
        geo.critical_points(wm.circle(1.0), bounds)
    with pytest.raises(ValueError, match="bounds"):
        lipschitz_bound(wm.circle(1.0), bounds)


def test_bad_dimension_and_lipschitz_options():
    with pytest.raises(ValueError, match="depends on z"):
        geo.singular_points(wm.sphere(1.0), ((-1, -1), (1, 1)))
    with pytest.raises(ValueError, match="depends on z"):
        lipschitz_bound(wm.sphere(1.0), ((-1, -1), (1, 1)))
    with pytest.raises(ValueError, match="depth"):
        lipschitz_bound(wm.circle(1.0), ((-1, -1), (1, 1)), depth=-1)
    with pytest.raises(ValueError, match="depth"):
        lipschitz_bound(wm.sphere(1.0), ((-1, -1, -1), (1, 1, 1)), depth=9)
    with pytest.raises(ValueError, match="rtol"):
        lipschitz_bound(wm.circle(1.0), ((-1, -1), (1, 1)), rtol=-0.1)
    with pytest.raises(TypeError, match="shape"):
        lipschitz_bound(3.0, ((-1, -1), (1, 1)))
