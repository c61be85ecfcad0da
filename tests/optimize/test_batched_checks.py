"""The optimiser's batched checks in Warp (warpmesh.kernels.remesh) against straightforward
numpy references: the pair tests of face_violations (the former numpy implementation,
tests/optimize/violations_reference.py), the projectable fans and the quality Q_K."""

import numpy as np
import pytest
import trimesh
import warp as wp

import warpmesh as wm
from tests.optimize.violations_reference import reference_violations
from warpmesh.optimize.embedding import _fans_kernel, _projectable_fans, face_violations
from warpmesh.optimize.local_ops import quality_of


def _both(p, t, faces, **kw):
    """(kernel flags, kernel partners), (reference flags, reference partners), flags per listed face."""
    bad, partners = face_violations(p, t, faces, partners=True, **kw)
    ref, ref_partners = reference_violations(p, t, faces, **kw)
    u = np.unique(faces)
    return (bad, partners), (ref[np.searchsorted(u, faces)], ref_partners)


def test_pairs_of_triangles_as_the_reference():
    """Random pairs, sharing no vertex or one, in general position and coplanar, with and
    without the fold test; touching configurations (a vertex on the other's plane)."""
    rng = np.random.default_rng(3)
    hits = 0
    for trial in range(600):
        p = rng.normal(size=(6, 3))
        if trial % 3 == 1:
            p[:, 2] = 0.0  # coplanar
        elif trial % 3 == 2:
            p[3:, 2] = np.round(p[3:, 2])  # vertices on z = 0, -1, 1: touching cases
            p[:3, 2] = 0.0
        tri = np.array([[0, 1, 2], [3, 4, 5]]) if trial % 2 else np.array([[0, 1, 2], [0, 4, 5]])
        for fold_cos in (-2.0, -0.5):
            (a, _), (b, _) = _both(p, tri, np.array([1]), fold_cos=fold_cos)
            assert a.tolist() == b.tolist(), trial
            hits += int(a[0])
    assert 100 < hits < 1100  # both outcomes are exercised


def test_shared_edges_fold_as_the_reference():
    rng = np.random.default_rng(5)
    for trial in range(200):
        p = rng.normal(size=(4, 3))
        tri = np.array([[0, 1, 2], [1, 0, 3]])
        for fold_cos in (-0.9, 0.0, 0.5):
            (a, _), (b, _) = _both(p, tri, np.array([0]), fold_cos=fold_cos)
            assert a.tolist() == b.tolist(), trial


@pytest.mark.parametrize("name", ["part", "torus"])
def test_jittered_surfaces_as_the_reference(name):
    """A marching-cubes surface with its vertices jittered by a fraction of a cell (many
    crossings and folds), every face listed and a random subset: the same flags and the
    same partner faces."""
    shape, bounds = wm.example(name)
    raw = wm.mesh_surface(shape, bounds=bounds, resolution=32, method="mc")
    rng = np.random.default_rng(11)
    cell = float(np.max(np.subtract(bounds[1], bounds[0]))) / 32
    p = raw.points + rng.normal(scale=0.3 * cell, size=raw.points.shape)
    t = raw.triangles
    for faces in (np.arange(len(t)), rng.choice(len(t), 400, replace=False), np.array([5, 5, 17])):
        (a, pa), (b, pb) = _both(p, t, faces)
        assert np.array_equal(a, b) and np.array_equal(pa, pb)
    assert a.any() or len(faces) < 10
    assert face_violations(p, t, np.arange(len(t))).sum() > 10


def test_inversion_test_as_the_reference():
    ico = trimesh.creation.icosphere(2)
    p, t = ico.vertices.copy(), ico.faces.copy()
    p[7] *= -0.3  # through the sphere
    outward = lambda x: x / np.linalg.norm(x, axis=1)[:, None]  # noqa: E731
    for average in (False, True):
        (a, pa), (b, pb) = _both(p, t, np.arange(len(t)), normals=outward, average=average)
        assert np.array_equal(a, b) and a.sum() >= 5


def _fans(p, t, verts):
    points = wp.array(np.asarray(p, np.float64), dtype=wp.vec3d, device="cpu")
    tris = wp.array(np.asarray(t, np.int32).ravel(), dtype=wp.int32, device="cpu")
    return _fans_kernel(points, tris, verts, len(p), "cpu").astype(bool)


def test_fans_as_the_reference():
    """Closed fans of a sphere (projectable), one pushed inside out (not), an open fan of
    a cut sphere (not), and a subset of the vertices."""
    ico = trimesh.creation.icosphere(2)
    p, t = ico.vertices.copy(), ico.faces.copy()
    p[3] *= 0.2  # a dent: the fan around 3 folds
    p[9] = p[9] + 0.5 * (p[ico.vertex_neighbors[9][0]] - p[9]) * 3  # a vertex pulled past its neighbour
    for verts in (np.unique(t), np.array([3, 9, 10, 11]), t[:20]):
        assert np.array_equal(_fans(p, t, verts), _projectable_fans(p, t, np.unique(verts)))
    ok = _fans(p, t, np.unique(t))
    assert ok.sum() > 0.8 * len(p) and not ok.all()
    keep = p[t].mean(axis=1)[:, 2] < 0.3  # an open cap: the rim's fans are open
    t_open = t[keep]
    ok = _fans(p, t_open, np.unique(t_open))
    assert np.array_equal(ok, _projectable_fans(p, t_open, np.unique(t_open)))
    rim = np.unique(trimesh.Trimesh(p, t_open, process=False).edges[
        trimesh.grouping.group_rows(trimesh.Trimesh(p, t_open, process=False).edges_sorted, require_count=1)])
    assert len(rim) > 0 and not ok[rim].any()


def _quality_reference(p):
    """Q_K = (sqrt 3 / 6) h_max perimeter / (2 area), inf when 2 area <= 1e-14 h_max^2."""
    e = p[:, [1, 2, 0]] - p
    lens = np.linalg.norm(e, axis=2)
    area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    hmax = lens.max(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.sqrt(3.0) / 6.0 * hmax * lens.sum(axis=1) / area2
    return np.where(area2 > 1e-14 * hmax**2, q, np.inf)


def test_quality_as_the_reference():
    rng = np.random.default_rng(2)
    p = rng.normal(size=(5000, 3, 3))
    p[:20, 2] = p[:20, 1]  # repeated corner
    p[20:40, 2] = 0.5 * (p[20:40, 0] + p[20:40, 1])  # collinear
    p[40] = 0.0
    q, ref = quality_of(p), _quality_reference(p)
    assert np.array_equal(np.isinf(q), np.isinf(ref)) and np.isinf(q[:41]).all()
    fin = np.isfinite(ref)
    np.testing.assert_allclose(q[fin], ref[fin], rtol=1e-12)
    equilateral = np.array([[[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]]])
    assert quality_of(equilateral)[0] == pytest.approx(1.0, abs=1e-12)
    assert quality_of(np.zeros((0, 3, 3))).shape == (0,)
    # any layout of the corners: a strided view, float32 (computed in float64)
    p32 = p[::2].astype(np.float32)
    np.testing.assert_array_equal(quality_of(p32) == np.inf, _quality_reference(p32.astype(np.float64)) == np.inf)
