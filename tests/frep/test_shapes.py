"""F-Rep shapes: primitives, booleans, transforms and arithmetic on the coordinates.

Reference distances are computed here independently of ``warpmesh.frep.shapes`` (distances
to the profile segments of solids of revolution, clamping for boxes and segments,
scipy rotations for transforms). Sign convention: f > 0 inside.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest
import warp as wp
from scipy.spatial.transform import Rotation

import warpmesh as wm
from warpmesh.frep import expr as E
from warpmesh.kernels import opcodes as O

wp.config.quiet = True
wp.init()
HAS_CUDA = wp.get_cuda_device_count() > 0
DEVICES = ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(not HAS_CUDA, reason="no CUDA device"))]


def f32(a) -> np.ndarray:
    return np.asarray(a, np.float32).astype(np.float64)


def rng_for(name: str) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(name.encode()))


def ev(shape, pts) -> np.ndarray:
    pts = np.asarray(pts, np.float64).reshape(-1, 3)
    return np.broadcast_to(shape.eval_numpy(pts[:, 0], pts[:, 1], pts[:, 2]), (len(pts),))


# -- independent reference geometry ------------------------------------------------------------
def seg_dist(p, a, b):
    """Distance from points p (n, d) to the segment ab (d,)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


AXIS = {"x": 0, "y": 1, "z": 2}


def meridian(pts, axis, center=(0, 0, 0)):
    """(rho, w): distance to the axis line through center, coordinate along it."""
    q = pts - np.asarray(center, float)
    k = AXIS[axis]
    w = q[:, k]
    rho = np.linalg.norm(np.delete(q, k, axis=1), axis=1)
    return rho, w


def profile_sdf(rho, w, segments, inside):
    """Signed distance of a solid of revolution from its meridian profile segments."""
    p = np.stack([rho, w], axis=1)
    d = np.min([seg_dist(p, a, b) for a, b in segments], axis=0)
    return np.where(inside, d, -d)


def box_sdf(pts, size, center=(0, 0, 0)):
    h = np.asarray(size, float) / 2
    q = pts - np.asarray(center, float)
    outside = np.linalg.norm(q - np.clip(q, -h, h), axis=1)
    inside_d = np.min(h - np.abs(q), axis=1)
    is_in = np.all(np.abs(q) < h, axis=1)
    return np.where(is_in, inside_d, -outside)


def finite_cylinder_sdf(pts, r, height, axis, center):
    rho, w = meridian(pts, axis, center)
    hh = height / 2
    segs = [((r, -hh), (r, hh)), ((0, hh), (r, hh)), ((0, -hh), (r, -hh))]
    return profile_sdf(rho, w, segs, (rho < r) & (np.abs(w) < hh))


def cone_sdf(pts, r, h, axis, center):
    rho, w = meridian(pts, axis, center)
    segs = [((0, 0), (r, 0)), ((r, 0), (0, h))]
    return profile_sdf(rho, w, segs, (w > 0) & (w < h) & (rho < r * (1 - w / h)))


def torus_sdf(pts, big, small, axis="z", center=(0, 0, 0)):
    rho, w = meridian(pts, axis, center)
    return small - np.hypot(rho - big, w)


def capsule_sdf(pts, a, b, r):
    return r - seg_dist(pts, a, b)


def lipschitz_ratio(shape, rng, n=4000, lo=-2.0, hi=2.0, step=1e-3):
    """max |f(p) - f(q)| / |p - q| over random nearby pairs (an estimate of max |grad f|)."""
    p = rng.uniform(lo, hi, (n, 3))
    d = rng.normal(size=(n, 3))
    d *= step / np.linalg.norm(d, axis=1, keepdims=True)
    return float(np.max(np.abs(ev(shape, p + d) - ev(shape, p)) / step))


# -- primitives: exact values at known points ---------------------------------------------------
@pytest.mark.parametrize("shape, point, value", [
    (wm.sphere(2.0, (1, 2, 3)), (1, 2, 3), 2.0),
    (wm.sphere(2.0, (1, 2, 3)), (3, 2, 3), 0.0),
    (wm.sphere(2.0, (1, 2, 3)), (1, 2, 6), -1.0),
    (wm.box((2, 2, 0.6)), (0, 0, 0.3), 0.0),
    (wm.box((2, 2, 0.6)), (0, 0, 0), 0.3),
    (wm.box((2, 2, 0.6)), (1, 1, 0.3), 0.0),
    (wm.box((2, 2, 0.6)), (3, 0, 0), -2.0),
    (wm.box((2, 2, 0.6)), (2, 2, 0), -math.sqrt(2)),
    (wm.box((2, 2, 0.6), (1, 0, 0)), (1, 0, 0), 0.3),
    (wm.cylinder(1.0), (0, 0, 100), 1.0),
    (wm.cylinder(1.0), (3, 0, -7), -2.0),
    (wm.cylinder(1.0, axis="x"), (50, 0.6, 0.8), 0.0),
    (wm.cylinder(0.5, 2.0, "z", (0, 0, 1)), (0, 0, 2), 0.0),
    (wm.cylinder(0.5, 2.0, "z", (0, 0, 1)), (0, 0, 1), 0.5),
    (wm.cylinder(0.5, 2.0, "y"), (0, 1, 0), 0.0),
    (wm.cylinder(0.5, 2.0, "y"), (0, 2, 0), -1.0),
    (wm.cylinder(0.5, 2.0, "x"), (1.5, 0, 0), -0.5),
    (wm.cylinder(0.5, 2.0, "x"), (0, 0.5, 0), 0.0),
    (wm.cylinder(0.5, 2.0, "x"), (2, 0, 1.5), -math.sqrt(2)),
    (wm.cone(1.0, 2.0), (0, 0, 2), 0.0),  # apex
    (wm.cone(1.0, 2.0), (0, 0, 0), 0.0),  # centre of the base
    (wm.cone(1.0, 2.0), (1, 0, 0), 0.0),  # rim
    (wm.cone(1.0, 2.0), (0.5, 0, 1), 0.0),  # half way up the side
    (wm.cone(1.0, 2.0), (0, 0, -1), -1.0),
    (wm.cone(1.0, 2.0, "x"), (1, 0, 0), 0.5 * 2 / math.sqrt(5)),  # side: (r (1 - w/h) - rho) cos
    (wm.torus(1.0, 0.25), (1.25, 0, 0), 0.0),
    (wm.torus(1.0, 0.25), (0, -1, 0), 0.25),
    (wm.torus(1.0, 0.25), (0, 1, 0.25), 0.0),
    (wm.torus(1.0, 0.25), (0, 0, 0), -0.75),
    (wm.torus(1.0, 0.25, "x"), (0, 0, 1), 0.25),
    (wm.torus(1.0, 0.25, "y", (0, 5, 0)), (1, 5, 0), 0.25),
    (wm.ellipsoid((1, 0.5, 0.25)), (1, 0, 0), 0.0),
    (wm.ellipsoid((1, 0.5, 0.25)), (0, -0.5, 0), 0.0),
    (wm.ellipsoid((1, 0.5, 0.25)), (0, 0, 0.25), 0.0),
    (wm.ellipsoid((1, 0.5, 0.25)), (0, 0, 0), 0.25),
    (wm.ellipsoid((2, 2, 2), (1, 1, 1)), (1, 1, 4), -1.0),
    (wm.halfspace((0, 0, 1), (0, 0, 1)), (0, 0, 0), 1.0),
    (wm.halfspace((0, 0, 1), (0, 0, 1)), (5, -5, 1), 0.0),
    (wm.halfspace((0, 0, 2), (0, 0, 1)), (0, 0, 3), -2.0),
    (wm.halfspace((1, 1, 0)), (1, 1, 7), -math.sqrt(2)),
    (wm.capsule(), (0, 0, 0.75), 0.0),
    (wm.capsule(), (0.25, 0, 0.4), 0.0),
    (wm.capsule(), (0, 0, 0), 0.25),
    (wm.capsule(), (0, 0, -1.75), -1.0),
    (wm.capsule((0, 0, 0), (2, 0, 0), 0.5), (1, 0.5, 0), 0.0),
    (wm.superquadric((1, 0.5, 0.25), 0.5, 0.5), (1, 0, 0), 0.0),
    (wm.superquadric((1, 0.5, 0.25), 0.5, 0.5), (0, 0.5, 0), 0.0),
    (wm.superquadric((1, 0.5, 0.25), 0.5, 0.5), (0, 0, -0.25), 0.0),
    (wm.superquadric((1, 0.5, 0.25), 0.5, 0.5), (0, 0, 0), 0.25),
    (wm.superquadric((1, 1, 1), 1.0, 1.0), (0, 0, 3), -2.0),  # a sphere
    (wm.superquadric((1, 1, 1), 0.5, 0.5, (1, 1, 1)), (1, 1, 1), 1.0),
    (wm.supertorus(1.0, 0.3), (1.3, 0, 0), 0.0),
    (wm.supertorus(1.0, 0.3), (0, 0.7, 0), 0.0),
    (wm.supertorus(1.0, 0.3), (1, 0, 0.3), 0.0),
    (wm.supertorus(1.0, 0.3), (1, 0, 0), 0.3),
    (wm.supertorus(1.0, 0.3, axis="x"), (0, 0, 1), 0.3),
    (wm.supertorus(1.0, 0.3, 1.0, 1.0), (0, 0, 0), -0.7),  # exact torus
])
def test_primitive_values_at_known_points(shape, point, value):
    assert float(ev(shape, point)[0]) == pytest.approx(value, abs=1e-12)
    got = wm.evaluate(shape, np.array([point], float))[0]
    assert got == pytest.approx(value, abs=2e-6)


def test_exactness_flags():
    exact = [wm.sphere(), wm.box(), wm.cylinder(), wm.cylinder(1, 2, "x"), wm.torus(), wm.halfspace(),
             wm.capsule(), wm.ellipsoid((1, 1, 1)), wm.supertorus(1, 0.3, 1.0, 1.0)]
    bounds = [wm.cone(), wm.ellipsoid((1, 0.5, 0.5)), wm.superquadric(), wm.superquadric((1, 1, 1), 1, 1),
              wm.supertorus(), wm.supertorus(1, 0.3, 1.0, 0.5)]
    assert all(s.exact for s in exact)
    assert not any(s.exact for s in bounds)
    assert all(isinstance(s, wm.Shape) for s in exact + bounds)


# -- primitives: exact ones are true signed distances -------------------------------------------
EXACT = {
    "sphere": (wm.sphere(1.3, (0.2, -0.1, 0.3)),
               lambda p: 1.3 - np.linalg.norm(p - (0.2, -0.1, 0.3), axis=1)),
    "box": (wm.box((1.6, 1.0, 0.6), (0.1, 0.2, -0.3)), lambda p: box_sdf(p, (1.6, 1.0, 0.6), (0.1, 0.2, -0.3))),
    "box-cube": (wm.box(1.0), lambda p: box_sdf(p, (1, 1, 1))),
    "torus": (wm.torus(1.0, 0.3), lambda p: torus_sdf(p, 1.0, 0.3)),
    "capsule": (wm.capsule((-0.5, 0.2, 0.1), (0.6, -0.4, 0.5), 0.35),
                lambda p: capsule_sdf(p, (-0.5, 0.2, 0.1), (0.6, -0.4, 0.5), 0.35)),
    "halfspace": (wm.halfspace((1, -2, 2), (0.3, 0.1, 0.0)),
                  lambda p: (np.array([1, -2, 2]) / 3) @ (0.3, 0.1, 0.0) - p @ (np.array([1, -2, 2]) / 3)),
    "ellipsoid-iso": (wm.ellipsoid((0.9, 0.9, 0.9), (0.1, 0, 0)),
                      lambda p: 0.9 - np.linalg.norm(p - (0.1, 0, 0), axis=1)),
    "supertorus-1-1": (wm.supertorus(1.0, 0.4, 1.0, 1.0, "y"), lambda p: torus_sdf(p, 1.0, 0.4, "y")),
}
for _ax in "xyz":
    EXACT[f"cylinder-inf-{_ax}"] = (wm.cylinder(0.6, axis=_ax, center=(0.1, -0.2, 0.3)),
                                    lambda p, a=_ax: 0.6 - meridian(p, a, (0.1, -0.2, 0.3))[0])
    EXACT[f"cylinder-{_ax}"] = (wm.cylinder(0.6, 1.5, _ax, (0.1, -0.2, 0.3)),
                                lambda p, a=_ax: finite_cylinder_sdf(p, 0.6, 1.5, a, (0.1, -0.2, 0.3)))
    EXACT[f"torus-{_ax}"] = (wm.torus(0.9, 0.35, _ax, (0.0, 0.2, -0.1)),
                             lambda p, a=_ax: torus_sdf(p, 0.9, 0.35, a, (0.0, 0.2, -0.1)))


@pytest.mark.parametrize("dev", DEVICES)
@pytest.mark.parametrize("name", sorted(EXACT))
def test_exact_primitives_are_signed_distances(name, dev):
    shape, sdf = EXACT[name]
    assert shape.exact
    rng = rng_for(name)
    pts = f32(rng.uniform(-2.0, 2.0, (3000, 3)))
    want = sdf(pts)
    assert (want > 0).sum() > 20 and (want < 0).sum() > 20
    assert np.allclose(ev(shape, pts), want, rtol=0, atol=1e-9)
    got = wm.evaluate(shape, pts, device=dev)
    assert np.allclose(got, want, rtol=0, atol=1e-5)


@pytest.mark.parametrize("axis", "xyz")
def test_cone_is_a_bound(axis):
    center = (0.1, -0.2, 0.0)
    shape = wm.cone(0.8, 1.4, axis, center)
    assert not shape.exact
    rng = rng_for("cone" + axis)
    pts = rng.uniform(-2, 2, (5000, 3))
    true = cone_sdf(pts, 0.8, 1.4, axis, center)
    f = ev(shape, pts)
    away = np.abs(true) > 1e-9
    assert np.array_equal(f[away] > 0, true[away] > 0)
    assert np.all(np.abs(f) <= np.abs(true) + 1e-9)
    inside = true > 0  # the min of the two plane distances is exact inside a convex cone
    assert np.allclose(f[inside], true[inside], atol=1e-9)
    assert lipschitz_ratio(shape, rng) <= 1 + 1e-6


def superquadric_F(pts, a, e1, e2):
    q = np.abs(pts) / np.asarray(a, float)
    return (q[:, 0] ** (2 / e2) + q[:, 1] ** (2 / e2)) ** (e2 / e1) + q[:, 2] ** (2 / e1)


def spow(v, e):
    return np.sign(v) * np.abs(v) ** e


@pytest.mark.parametrize("a, e1, e2", [((1, 1, 1), 0.5, 0.5), ((1.2, 0.8, 0.5), 0.3, 0.8),
                                       ((1, 0.7, 0.9), 1.0, 1.0), ((0.6, 1, 0.8), 0.8, 0.2)])
def test_superquadric_is_a_bound(a, e1, e2):
    shape = wm.superquadric(a, e1, e2)
    assert not shape.exact
    rng = rng_for(f"sq{a}{e1}{e2}")
    pts = rng.uniform(-1.5, 1.5, (5000, 3))
    F = superquadric_F(pts, a, e1, e2)
    f = ev(shape, pts)
    away = np.abs(F - 1) > 1e-9
    assert np.array_equal(f[away] > 0, F[away] < 1)
    # Barr's parametric surface lies on f = 0
    eta, om = rng.uniform(-math.pi / 2, math.pi / 2, 500), rng.uniform(-math.pi, math.pi, 500)
    surf = np.stack([a[0] * spow(np.cos(eta), e1) * spow(np.cos(om), e2),
                     a[1] * spow(np.cos(eta), e1) * spow(np.sin(om), e2),
                     a[2] * spow(np.sin(eta), e1)], axis=1)
    assert np.allclose(ev(shape, surf), 0.0, atol=1e-9)
    # homogeneous of degree one along rays from the centre: f(t p) = min(a) (1 - t (1 - f(p)/min(a)))
    m = min(a)
    t = rng.uniform(0.1, 3.0, len(pts))
    assert np.allclose(ev(shape, pts * t[:, None]), m * (1 - t * (1 - f / m)), atol=1e-9)
    assert lipschitz_ratio(shape, rng) <= 1 + 1e-6


@pytest.mark.parametrize("e1, e2", [(0.5, 0.5), (0.3, 0.9), (1.0, 1.0), (0.8, 0.4)])
def test_supertorus_is_a_bound(e1, e2):
    big, small = 1.0, 0.35
    shape = wm.supertorus(big, small, e1, e2)
    assert shape.exact == (e1 == 1.0 and e2 == 1.0)
    rng = rng_for(f"st{e1}{e2}")
    pts = rng.uniform(-1.6, 1.6, (5000, 3))
    rho = (np.abs(pts[:, 0]) ** (2 / e2) + np.abs(pts[:, 1]) ** (2 / e2)) ** (e2 / 2)
    F = np.abs((rho - big) / small) ** (2 / e1) + np.abs(pts[:, 2] / small) ** (2 / e1)
    f = ev(shape, pts)
    away = np.abs(F - 1) > 1e-9
    assert np.array_equal(f[away] > 0, F[away] < 1)
    eta, om = rng.uniform(-math.pi, math.pi, 500), rng.uniform(-math.pi, math.pi, 500)
    ring = big + small * spow(np.cos(eta), e1)
    surf = np.stack([ring * spow(np.cos(om), e2), ring * spow(np.sin(om), e2), small * spow(np.sin(eta), e1)], 1)
    assert np.allclose(ev(shape, surf), 0.0, atol=1e-9)
    assert lipschitz_ratio(shape, rng) <= 1 + 1e-6


def test_anisotropic_ellipsoid_is_a_bound():
    a = (1.2, 0.6, 0.4)
    shape = wm.ellipsoid(a)
    assert not shape.exact
    rng = rng_for("ellipsoid")
    pts = rng.uniform(-1.5, 1.5, (5000, 3))
    F = np.sum((pts / a) ** 2, axis=1)
    f = ev(shape, pts)
    assert np.array_equal(f > 0, F < 1)
    assert np.allclose(f, 0.4 * (1 - np.sqrt(F)), atol=1e-12)
    assert lipschitz_ratio(shape, rng) <= 1 + 1e-6


@pytest.mark.parametrize("shape", [
    pytest.param(wm.superquadric((1, 1, 1), 2.0, 2.0), id="superquadric-octahedron-e2"),
    pytest.param(wm.superquadric((1, 1, 1), 1.0, 3.0), id="superquadric-e2=3"),
    pytest.param(wm.supertorus(1.0, 0.3, 1.0, 2.0), id="supertorus-e2=2"),
    pytest.param(wm.supertorus(1.0, 0.3, 2.0, 1.0), id="supertorus-e1=2"),
])
def test_bound_primitives_with_large_exponents_keep_only_the_sign(shape):
    """Documented: for exponents > 1 only the sign is meaningful (steeper than 1)."""
    assert lipschitz_ratio(shape, np.random.default_rng(0), lo=-1.5, hi=1.5) > 1 + 1e-3
    assert float(ev(shape, (1.0, 0.0, 0.0))[0]) > 0 or float(ev(shape, (0.0, 0.0, 0.0))[0]) > 0


def test_primitive_argument_validation():
    bad = [lambda: wm.sphere(0), lambda: wm.sphere(-1), lambda: wm.sphere(math.nan),
           lambda: wm.sphere(1, (0, 0)), lambda: wm.box((1, 0, 1)), lambda: wm.box((1, 1)),
           lambda: wm.box((1, math.inf, 1)), lambda: wm.cylinder(0), lambda: wm.cylinder(1, -1),
           lambda: wm.cylinder(1, 1, axis="w"), lambda: wm.cylinder(1, axis=2), lambda: wm.cone(1, 0),
           lambda: wm.cone(-1, 1), lambda: wm.torus(0.3, 0.5), lambda: wm.torus(0.5, 0.5),
           lambda: wm.torus(1, 0), lambda: wm.ellipsoid((1, -1, 1)), lambda: wm.halfspace((0, 0, 0)),
           lambda: wm.capsule((1, 1, 1), (1, 1, 1)), lambda: wm.capsule(radius=0),
           lambda: wm.superquadric(e1=0), lambda: wm.superquadric(e2=-1), lambda: wm.superquadric((1, 0, 1)),
           lambda: wm.supertorus(0.3, 0.5), lambda: wm.supertorus(e1=0), lambda: wm.supertorus(axis="q")]
    for i, make in enumerate(bad):
        with pytest.raises(ValueError):
            make()
            pytest.fail(f"bad primitive #{i} accepted")
    with pytest.raises(ValueError, match="axis"):
        wm.cylinder(1, axis="w")
    # strings, bools and None are not numbers (float() took "1" and True without a word)
    for make, name in ((lambda: wm.sphere("1"), "radius"), (lambda: wm.sphere(True), "radius"),
                       (lambda: wm.sphere(None), "radius"), (lambda: wm.cylinder(1.0, height="2"), "height"),
                       (lambda: wm.box(("1", 1, 1)), "size"), (lambda: wm.sphere(1.0, (0, 0, True)), "center")):
        with pytest.raises(TypeError, match=f"expected (a number|numbers) for '{name}'"):
            make()
    assert wm.sphere(np.float32(2.0)).field is not None and wm.box(np.array([1, 2, 3])) is not None


# -- booleans ---------------------------------------------------------------------------------
A = wm.sphere(1.0, (0.3, 0.0, 0.1))
B = wm.box((1.2, 1.4, 1.0), (-0.4, 0.2, 0.0))
C = wm.torus(0.8, 0.25, "x", (0.0, -0.3, 0.2))
METHODS = ("rfunction", "minmax", "smooth")
K = 0.2


def boolean_points():
    rng = np.random.default_rng(42)
    pts = rng.uniform(-2, 2, (20000, 3))
    a, b, c = ev(A, pts), ev(B, pts), ev(C, pts)
    keep = (np.abs(a) > 1e-6) & (np.abs(b) > 1e-6) & (np.abs(c) > 1e-6)
    return pts[keep], a[keep], b[keep], c[keep]


@pytest.mark.parametrize("method", METHODS)
def test_boolean_signs_follow_set_logic(method):
    pts, a, b, c = boolean_points()
    ina, inb, inc = a > 0, b > 0, c > 0
    smooth = method == "smooth"
    checks = [
        (wm.union(A, B, method=method, k=K), ina | inb, np.abs(a - b) > K),
        (wm.intersection(A, B, method=method, k=K), ina & inb, np.abs(a - b) > K),
        (wm.difference(A, B, method=method, k=K), ina & ~inb, np.abs(a + b) > K),
        (wm.complement(A), ~ina, np.ones_like(ina)),
        (wm.union(A, B, C, method=method, k=K), ina | inb | inc,
         (np.abs(a - b) > K) & (np.abs(np.maximum(a, b) - c) > 1.25 * K)),
        (wm.intersection(A, B, C, method=method, k=K), ina & inb & inc,
         (np.abs(a - b) > K) & (np.abs(np.minimum(a, b) - c) > 1.25 * K)),
    ]
    for i, (shape, want, clear) in enumerate(checks):
        mask = clear if smooth else np.ones_like(want)
        assert mask.mean() > 0.2  # smooth: outside the blend regions (a blend moves f by <= k/4)
        f = ev(shape, pts)
        assert np.array_equal(f[mask] > 0, want[mask]), f"{method} boolean #{i}"
        assert shape.exact == (i == 3)  # only the complement keeps a distance exact
        got = wm.evaluate(shape, f32(pts[mask][:2000]))
        ref = ev(shape, f32(pts[mask][:2000]))
        assert np.allclose(got, ref, atol=1e-5 * (1 + np.abs(ref).max()))


def test_boolean_operators_are_the_functions():
    assert (A | B).field is wm.union(A, B).field
    assert (A & B).field is wm.intersection(A, B).field
    assert (A - B).field is wm.difference(A, B).field
    assert (~A).field is wm.complement(A).field
    assert (A - B).field is wm.intersection(A, ~B).field
    assert (A | B | C).field is wm.union(A, B, C).field
    assert (~A).field is (-A.field)
    p = transform_points(0)
    assert np.array_equal(ev(~~A, p), ev(A, p))
    assert (~A).exact and (~~A).exact


def test_rfunction_formula_eq_16_17():
    pts, a, b, _ = boolean_points()
    h = np.sqrt(a * a + b * b)
    assert np.allclose(ev(A | B, pts), a + b + h, atol=1e-12)
    assert np.allclose(ev(A & B, pts), a + b - h, atol=1e-12)
    assert np.allclose(ev(A - B, pts), a - b - h, atol=1e-12)
    assert np.allclose(ev(~A, pts), -a, atol=0)
    got = wm.evaluate(A | B, f32(pts[:3000]))
    fa, fb = ev(A, f32(pts[:3000])), ev(B, f32(pts[:3000]))
    assert np.allclose(got, fa + fb + np.hypot(fa, fb), atol=1e-5)
    assert (A | B).field.op == O.RUNION and (A & B).field.op == O.RINTER


def test_minmax_and_smooth_formulas():
    pts, a, b, _ = boolean_points()
    assert np.allclose(ev(wm.union(A, B, method="minmax"), pts), np.maximum(a, b), atol=0)
    assert np.allclose(ev(wm.intersection(A, B, method="minmax"), pts), np.minimum(a, b), atol=0)
    assert np.allclose(ev(wm.difference(A, B, method="minmax"), pts), np.minimum(a, -b), atol=0)
    h = np.maximum(K - np.abs(a - b), 0) / K
    su = ev(wm.union(A, B, method="smooth", k=K), pts)
    assert np.allclose(su, np.maximum(a, b) + K / 4 * h * h, atol=1e-12)
    assert np.all(su >= np.maximum(a, b) - 1e-12) and np.all(su <= np.maximum(a, b) + K / 4 + 1e-12)
    si = ev(wm.intersection(A, B, method="smooth", k=K), pts)
    assert np.allclose(si, np.minimum(a, b) - K / 4 * h * h, atol=1e-12)
    far = np.abs(a - b) >= K
    assert np.array_equal(su[far], np.maximum(a, b)[far])


def test_boolean_argument_errors():
    for fn in (wm.union, wm.intersection, wm.difference):
        with pytest.raises(ValueError) as info:
            fn(A, B, method="blend")
        msg = str(info.value)
        assert "blend" in msg and all(m in msg for m in METHODS)
        with pytest.raises(ValueError):
            fn(A, B, method="smooth", k=0.0)
        with pytest.raises(ValueError):
            fn(A, B, method="smooth", k=-1.0)
    with pytest.raises(ValueError, match="at least one"):
        wm.union()
    with pytest.raises(ValueError, match="at least one"):
        wm.intersection()
    with pytest.raises(TypeError):
        wm.union(A, 3.0)
    with pytest.raises(TypeError):
        A | "sphere"
    # one shape: itself (exactness kept)
    assert wm.union(A).field is A.field and wm.union(A).exact
    assert wm.intersection(B).field is B.field
    assert wm.difference(A).field is A.field
    # expressions are accepted as operands
    x, y, z = E.coords()
    assert (A | (1 - x * x)).field is E.runion(A.field, 1 - x * x)


def test_difference_of_one_shape_validates_the_method():
    with pytest.raises(ValueError):
        wm.difference(A, method="blend")


# -- transforms --------------------------------------------------------------------------------
BASE = wm.box((1.0, 0.6, 0.4), (0.2, 0.1, 0.0)) | wm.sphere(0.3, (0.5, 0.4, 0.2))  # no symmetry


def transform_points(seed=0, n=3000):
    return np.random.default_rng(seed).uniform(-1.5, 1.5, (n, 3))


def rot_matrix(angle, axis):
    ax = np.asarray(axis, float)
    return Rotation.from_rotvec(angle * ax / np.linalg.norm(ax)).as_matrix()


@pytest.mark.parametrize("angle, axis, about", [
    (0.7, (0, 0, 1), (0, 0, 0)), (-2.1, (1, 2, 3), (0.3, -0.2, 0.5)), (math.pi, (1, 0, 0), (0, 1, 0)),
    (1.3, "x", (0, 0, 0)), (0.4, "y", (1, 1, 1)), (5.0, (0, -1, 0.5), (0, 0, 0))])
def test_rotate(angle, axis, about):
    p = transform_points(1)
    ax = np.eye(3)[AXIS[axis]] if isinstance(axis, str) else axis
    R = rot_matrix(angle, ax)
    c = np.asarray(about, float)
    moved = (p - c) @ R.T + c
    g = BASE.rotate(angle, axis, about)
    assert np.allclose(ev(g, moved), ev(BASE, p), atol=1e-12)
    assert wm.sphere(1.0).rotate(angle, axis, about).exact


def test_rotate_direction_and_defaults():
    # +90 degrees about +z takes +x to +y (right-hand rule), about the origin by default
    s = wm.sphere(0.1, (1, 0, 0)).rotate(math.pi / 2)
    assert float(ev(s, (0, 1, 0))[0]) == pytest.approx(0.1, abs=1e-12)
    assert float(ev(s, (1, 0, 0))[0]) < 0


def test_rotate_full_turn_is_identity():
    p = transform_points(2)
    for axis in ((0, 0, 1), (1, 1, 0), "y"):
        g = BASE.rotate(2 * math.pi, axis, (0.3, 0.1, -0.2))
        assert np.allclose(ev(g, p), ev(BASE, p), atol=1e-12)


@pytest.mark.parametrize("offset", [(1, 2, 3), (-0.5, 0, 0.25), 0.3])
def test_translate(offset):
    p = transform_points(3)
    t = np.broadcast_to(np.asarray(offset, float), (3,))
    g = BASE.translate(offset)
    assert np.allclose(ev(g, p + t), ev(BASE, p), atol=1e-12)
    assert wm.box().translate(offset).exact and not BASE.translate(offset).exact


@pytest.mark.parametrize("factor, about", [(2.0, (0, 0, 0)), (0.5, (0.2, -0.3, 0.1)), ((1.0, 2.0, 0.5), (0, 0, 0)),
                                           ((3.0, 1.5, 0.8), (0.5, 0.5, -0.5))])
def test_scale(factor, about):
    p = transform_points(4)
    s = np.broadcast_to(np.asarray(factor, float), (3,))
    c = np.asarray(about, float)
    g = BASE.scale(factor, about)
    # iso: s f(p) (a distance stays a distance); aniso: min(s) f(p) (a bound)
    assert np.allclose(ev(g, c + (p - c) * s), s.min() * ev(BASE, p), atol=1e-12)
    iso = bool(np.all(s == s[0]))
    sph = wm.sphere(0.7).scale(factor, about)
    assert sph.exact == iso
    if iso:
        assert np.allclose(ev(sph, p), 0.7 * s[0] - np.linalg.norm(p - c * (1 - s[0]), axis=1), atol=1e-12)
    else:
        assert lipschitz_ratio(sph, np.random.default_rng(0)) <= 1 + 1e-6


@pytest.mark.parametrize("normal, point", [((1, 0, 0), (0, 0, 0)), ((1, 1, 0), (0.2, 0, 0)),
                                           ((0.3, -1, 2), (0.1, 0.2, -0.4))])
def test_mirror(normal, point):
    p = transform_points(5)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    c = np.asarray(point, float)
    reflected = p - 2 * ((p - c) @ n)[:, None] * n
    g = BASE.mirror(normal, point)
    assert np.allclose(ev(g, reflected), ev(BASE, p), atol=1e-12)
    assert np.allclose(ev(g.mirror(normal, point), p), ev(BASE, p), atol=1e-12)  # an involution
    assert wm.torus().mirror(normal, point).exact
    # the mirror image of a point of the shape
    q = np.array([0.5, 0.4, 0.2])
    assert float(ev(g, q - 2 * ((q - c) @ n) * n)[0]) == pytest.approx(float(ev(BASE, q)[0]), abs=1e-12)


@pytest.mark.parametrize("kind", ["shear", "similarity", "reflect-similarity", "homogeneous"])
def test_affine(kind):
    rng = np.random.default_rng(6)
    p = transform_points(6)
    t = np.array([0.3, -0.2, 0.5])
    R = rot_matrix(0.8, (1, 2, -1))
    m = {"shear": np.array([[1.0, 0.5, 0.0], [0.0, 1.2, 0.3], [0.2, 0.0, 0.8]]),
         "similarity": 1.7 * R, "reflect-similarity": 0.6 * R @ np.diag([1, 1, -1]),
         "homogeneous": np.array([[1.0, 0.5, 0.0], [0.0, 1.2, 0.3], [0.2, 0.0, 0.8]])}[kind]
    smin = np.linalg.svd(m, compute_uv=False).min()
    if kind == "homogeneous":
        h = np.eye(4)
        h[:3, :3], h[:3, 3] = m, t
        g, sph = BASE.affine(h), wm.sphere(0.5).affine(h)
    else:
        g, sph = BASE.affine(m, t), wm.sphere(0.5).affine(m, t)
    assert np.allclose(ev(g, p @ m.T + t), smin * ev(BASE, p), atol=1e-12)
    similar = kind in ("similarity", "reflect-similarity")
    assert sph.exact == similar
    if similar:
        s = abs(np.linalg.det(m)) ** (1 / 3)
        assert np.allclose(ev(sph, p), 0.5 * s - np.linalg.norm(p - t, axis=1), atol=1e-12)
    assert lipschitz_ratio(sph, rng) <= 1 + 1e-6


def test_affine_rejects_a_projective_matrix():
    h = np.eye(4)
    h[3, 0] = 1.0
    with pytest.raises(ValueError):
        wm.sphere().affine(h)


def test_transforms_chain_and_compile():
    g = wm.sphere(1.0).translate((1, 0, 0)).scale(2).rotate(math.pi / 2, "z")
    # centre: (1,0,0) -> (2,0,0) -> (0,2,0); radius 2
    assert g.exact
    assert float(ev(g, (0, 2, 0))[0]) == pytest.approx(2.0, abs=1e-12)
    assert wm.evaluate(g, np.array([[0.0, 2.0, 0.0], [0.0, 4.0, 0.0]])) == pytest.approx([2.0, 0.0], abs=1e-5)


def test_transform_argument_errors():
    s = wm.sphere()
    bad = [lambda: s.rotate(1.0, (0, 0, 0)), lambda: s.rotate(1.0, "w"), lambda: s.rotate(1.0, (1, 0)),
           lambda: s.rotate(1.0, (0, 0, 1), (0, 0)), lambda: s.rotate(1.0, (math.nan, 0, 1)),
           lambda: s.affine(np.zeros((3, 3))), lambda: s.affine([[1, 0, 0], [0, 1, 0], [1, 1, 0]]),
           lambda: s.affine(np.eye(2)), lambda: s.affine(np.full((3, 3), math.nan)),
           lambda: s.affine(np.eye(3), (1, 2)), lambda: s.scale(-1.0), lambda: s.scale(0.0),
           lambda: s.scale((1, 2)), lambda: s.scale((1, -2, 1)), lambda: s.scale(math.inf),
           lambda: s.translate((1, 2)), lambda: s.translate((1, 2, 3, 4)), lambda: s.translate((0, math.nan, 0)),
           lambda: s.mirror((0, 0, 0)), lambda: s.mirror((1, 0, 0), (1, 1))]
    for i, make in enumerate(bad):
        with pytest.raises(ValueError):
            make()
            pytest.fail(f"bad transform #{i} accepted")
    with pytest.raises(ValueError, match="singular"):
        s.affine([[1, 0, 0], [0, 1, 0], [1, 1, 0]])


# -- arithmetic on the coordinates -------------------------------------------------------------
@pytest.mark.parametrize("dev", DEVICES)
def test_degree_six_one_liner(dev):
    x, y, z = wm.coords()
    f = (x**2 + y**2 - 4) * (x**2 + z**2 - 4) * (y**2 + z**2 - 4) - 4.0078
    assert float(f.eval_numpy(0.0, 0.0, 0.0)) == pytest.approx(-68.0078, abs=1e-12)
    assert float(f(2.0, 0.0, 0.0)) == pytest.approx(0 * (-4) * (-4) - 4.0078)
    p = f32(np.random.default_rng(8).uniform(-3, 3, (4000, 3)))
    X, Y, Z = p.T
    want = (X**2 + Y**2 - 4) * (X**2 + Z**2 - 4) * (Y**2 + Z**2 - 4) - 4.0078
    assert np.allclose(f.eval_numpy(X, Y, Z), want, rtol=1e-13, atol=1e-12)
    got = wm.evaluate(f, p, device=dev)
    mags = np.abs(X**2 + Y**2 - 4 + 1) * np.abs(X**2 + Z**2 - 4 + 1) * np.abs(Y**2 + Z**2 - 4 + 1) + 5
    assert np.all(np.abs(got - want) <= 1e-5 * mags)
    shape, _ = wm.example("degree6")
    assert shape.field is f  # hash-consing: the same DAG
    # broadcasting open grids
    g = f.eval_numpy(np.linspace(-1, 1, 4)[:, None, None], np.linspace(-1, 1, 5)[None, :, None],
                     np.linspace(-1, 1, 6)[None, None, :])
    assert g.shape == (4, 5, 6)


def test_functions_on_expressions_and_numbers():
    x, y, z = wm.coords()
    p = np.random.default_rng(9).uniform(0.1, 2.0, (500, 3))
    X, Y, Z = p.T
    pairs = [(wm.sqrt(x + y), np.sqrt(X + Y)), (wm.abs(x - 1), np.abs(X - 1)),
             (wm.min(x, y), np.minimum(X, Y)), (wm.max(x, y, z), np.maximum(np.maximum(X, Y), Z)),
             (wm.min(x, 1.0, z), np.minimum(np.minimum(X, 1.0), Z)), (wm.sin(x * y), np.sin(X * Y)),
             (wm.cos(z) + wm.exp(-x), np.cos(Z) + np.exp(-X)), (wm.log(x * z), np.log(X * Z)),
             (wm.sqrt(x - 1), np.sqrt(np.maximum(X - 1, 0))), (abs(y - z), np.abs(Y - Z)),
             (2 / x - y / 3 + (1 - z), 2 / X - Y / 3 + (1 - Z)), (-x ** 3 + x ** -2, -X ** 3 + X ** -2.0)]
    for ex, want in pairs:
        assert isinstance(ex, wm.Expr)
        assert np.allclose(ex.eval_numpy(X, Y, Z), want, rtol=1e-13, atol=1e-13)
        got = wm.evaluate(ex, f32(p))
        ref = ex.eval_numpy(*f32(p).T)
        assert np.allclose(got, ref, rtol=1e-5, atol=1e-5)
    for ex, want in [(wm.sqrt(4), 2.0), (wm.abs(-3), 3.0), (wm.min(3, 1, 2), 1.0), (wm.max(3, 1, 2), 3.0),
                     (wm.sin(0.5), math.sin(0.5)), (wm.cos(0.5), math.cos(0.5)), (wm.exp(1), math.e),
                     (wm.log(math.e), 1.0), (wm.sqrt(-4), 0.0)]:
        assert isinstance(ex, wm.Expr) and ex.op == O.CONST
        assert ex.imm == pytest.approx(want, rel=1e-15)
    assert wm.sqrt(x).op == O.SQRT and wm.abs(x).op == O.ABS
    # a shape is accepted where an expression is expected (its field)
    assert wm.max(wm.sphere(1), 0.0) is E.max(wm.sphere(1).field, 0.0)


def test_expressions_have_no_truth_value():
    x, y, z = wm.coords()
    with pytest.raises(TypeError):
        bool(x)
    with pytest.raises(TypeError):
        bool(x * y - 1)
    with pytest.raises(TypeError):
        if x + 1:
            pass
    with pytest.raises(TypeError):
        not z
    with pytest.raises(TypeError):
        x < 1  # noqa: B015
    with pytest.raises(TypeError):
        bool(wm.sphere(1).field)


def test_coords_are_leaves():
    x, y, z = wm.coords()
    assert (x.op, y.op, z.op) == (O.X, O.Y, O.Z)
    assert wm.coords()[0] is x
    assert float(x.eval_numpy(1.5, 2.5, 3.5)) == 1.5 and float(z(1.5, 2.5, 3.5)) == 3.5
    assert float(z.eval_numpy(1.0, 2.0)) == 0.0  # z defaults to 0


# -- bundled examples -------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(wm.EXAMPLES))
def test_examples(name):
    shape, bounds = wm.example(name)
    assert isinstance(shape, wm.Shape)
    lo, hi = np.asarray(bounds[0], float), np.asarray(bounds[1], float)
    assert lo.shape == hi.shape == (3,) and np.all(lo < hi)
    grid = [np.linspace(lo[k], hi[k], 33) for k in range(3)]
    f = shape.eval_numpy(grid[0][:, None, None], grid[1][None, :, None], grid[2][None, None, :])
    assert f.shape == (33, 33, 33)
    assert (f > 0).any() and (f < 0).any()  # a surface inside the bounds
    if name != "degree6":  # closed shapes lie inside their bounds (degree6 is clipped)
        faces = np.concatenate([f[0].ravel(), f[-1].ravel(), f[:, 0].ravel(), f[:, -1].ravel(),
                                f[:, :, 0].ravel(), f[:, :, -1].ravel()])
        assert np.all(faces < 0)
    got = wm.evaluate(shape, np.array([(lo + hi) / 2]))
    assert np.isfinite(got).all()


def test_example_names():
    assert list(wm.EXAMPLES) == ["part", "degree6", "sphere", "torus"]
    with pytest.raises(ValueError) as info:
        wm.example("teapot")
    msg = str(info.value)
    assert "teapot" in msg and all(n in msg for n in wm.EXAMPLES)
    # 'part': plate with four holes, plus a ball in the middle
    part, _ = wm.example("part")
    assert float(ev(part, (0, 0, 0.45))[0]) > 0 and float(ev(part, (0.6, 0.6, 0))[0]) < 0
    assert float(ev(part, (0.9, 0, 0))[0]) > 0 and float(ev(part, (0, 0, 0.7))[0]) < 0
