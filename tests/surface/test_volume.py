"""Volumes at scale (warpmesh.surface.volume): slabs welded exactly, label surfaces, bad input;
and the finite-difference gradient option of the shape pipeline."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import warpmesh as wm
from tests.helpers.meshcheck import check_mesh
from warpmesh.surface.volume import slab_ranges


def _ball_volume(n=70, r=0.8, dtype=np.float32):
    g = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    return (r - np.sqrt(x**2 + y**2 + z**2)).astype(dtype), g[1] - g[0]


def _same_mesh(a, b, tol=1e-6):
    """Same vertices (within float32 rounding of the slab frames) and the same triangles."""
    d, idx = cKDTree(a.points).query(b.points)
    assert d.max() < tol
    assert len(np.unique(idx)) == len(idx) == len(a.points)
    ta = {tuple(t) for t in np.sort(a.cells["triangle"], axis=1).tolist()}
    tb = {tuple(t) for t in np.sort(idx[b.cells["triangle"]], axis=1).tolist()}
    assert ta == tb


def test_slab_ranges_cover_and_share_planes():
    for n0, plane, voxels in ((20, 100, 1000), (9, 10, 10), (100, 7, 10**9), (17, 1, 8)):
        r = slab_ranges(n0, plane, voxels)
        assert r[0][0] == 0 and r[-1][1] == n0 - 1
        assert all(b0 == a1 for (_, b0), (a1, _) in zip(r, r[1:]))  # consecutive slabs share a plane
        assert all(b - a >= 1 for a, b in r)


@pytest.mark.parametrize("method", ["mc", "mt"])
@pytest.mark.parametrize("slab_voxels", [5_000, 40_000])
def test_slabs_give_the_same_mesh(method, slab_voxels, device):
    vol, h = _ball_volume()
    whole = wm.mesh_surface(vol, spacing=h, origin=(-1, -1, -1), method=method, device=device)
    parts = wm.mesh_surface(vol, spacing=h, origin=(-1, -1, -1), method=method, slab_voxels=slab_voxels,
                            device=device)
    assert whole.info["slabs"] == 1 and parts.info["slabs"] > 1
    check_mesh(parts)
    _same_mesh(whole, parts)
    assert parts.stats()["euler"] == 2


def test_slabs_cap_only_the_volume_faces(device):
    """A slab ends inside the solid: its seam must not be capped (one closed surface)."""
    vol = np.full((50, 12, 12), 1.0, dtype=np.float32)  # all inside: the caps are the whole surface
    vol[24, 6, 6] = 0.0  # and one outside sample: a small cavity on a seam plane
    m = wm.mesh_surface(vol, level=0.5, slab_voxels=12 * 12 * 9, device=device)
    check_mesh(m)
    s = m.stats()
    assert m.info["slabs"] > 3
    assert s["components"] == 2 and s["euler"] == 4


def test_labels_mesh_each_region(device):
    labels = np.zeros((40, 30, 30), dtype=np.uint8)
    labels[5:15, 5:25, 5:25] = 1
    labels[15:35, 5:25, 5:25] = 2  # touches label 1: two closed surfaces sharing an interface
    labels[20:25, 10:15, 10:15] = 0  # a cavity inside label 2
    m = wm.mesh_surface(labels, labels="all", slab_voxels=9_000, device=device)
    # one closed surface per label: the interface between labels 1 and 2 is in both (the
    # surfaces touch there by construction), so each label's surface is checked on its own
    check_mesh(m, embedded=False)
    refs = m.cell_refs["triangle"]
    for value in (1, 2):
        check_mesh(m.points, m.cells["triangle"][refs == value], closed=False)
    assert set(refs.tolist()) == {1, 2}
    for value, euler in ((1, 2), (2, 4)):  # label 2: a box with a cavity, two spheres
        sub = wm.mesh_surface(labels, labels=[value], device=device)
        assert sub.stats()["euler"] == euler
        assert np.count_nonzero(refs == value) == len(sub.cells["triangle"])
    # the volumes enclosed are the label volumes (vertices at midpoints: exact for boxes)
    assert m.info["enclosed_volume"] == pytest.approx((10 * 20 * 20) + (20 * 20 * 20 - 125), rel=0.05)


def test_label_volume_bad_input():
    labels = np.zeros((10, 10, 10), dtype=np.uint8)
    labels[2:5, 2:5, 2:5] = 3
    with pytest.raises(ValueError, match="label 7"):
        wm.mesh_surface(labels, labels=[7])
    with pytest.raises(ValueError, match="'labels'"):
        wm.mesh_surface(labels, labels="some")
    with pytest.raises(ValueError, match="distinct"):
        wm.mesh_surface(labels, labels=[3, 3])
    with pytest.raises(ValueError, match="whole-number"):  # whole-number floats are labels, others are not
        wm.mesh_surface(labels.astype(np.float32) + 0.5, labels="all")
    with pytest.raises(TypeError, match="real numeric 'volume'"):
        wm.mesh_surface(labels.astype(np.complex64), labels="all")
    with pytest.raises(ValueError, match="only 0"):
        wm.mesh_surface(np.zeros((5, 5, 5), np.uint8), labels="all")
    with pytest.raises(ValueError, match="'level'.*labels|labels"):
        wm.mesh_surface(labels, labels="all", level=0.2)
    with pytest.raises(ValueError, match="slab_voxels"):
        wm.mesh_surface(labels, labels="all", slab_voxels=0)
    with pytest.raises(ValueError, match="slab_voxels"):
        wm.mesh_surface(wm.sphere(1.0), bounds=((-2,) * 3, (2,) * 3), slab_voxels=10)


def test_slabs_still_validate_the_whole_volume():
    vol, h = _ball_volume(30)
    bad = vol.copy()
    bad[25, 3, 3] = np.nan  # in a late slab
    with pytest.raises(ValueError, match="NaN"):
        wm.mesh_surface(bad, slab_voxels=2_000)
    with pytest.raises(ValueError, match="non-constant"):
        wm.mesh_surface(np.ones((30, 10, 10)), slab_voxels=500)
    with pytest.raises(ValueError, match="'level' within"):
        wm.mesh_surface(vol, level=5.0, slab_voxels=2_000)


# -- finite-difference gradients (eq. 16.13, 16.14) ------------------------------------------
@pytest.mark.parametrize("gradient", ["exact", "central", "forward"])
def test_newton_with_each_gradient_lands_on_the_surface(gradient, device):
    shape = wm.torus(1.0, 0.35)
    bounds = ((-1.5, -1.5, -0.5), (1.5, 1.5, 0.5))
    m = wm.mesh_surface(shape, bounds=bounds, resolution=48, root="newton", gradient=gradient, cap=False,
                        device=device)
    f = wm.evaluate(shape, m.points).astype(np.float64)
    assert np.max(np.abs(f)) < 1e-4  # the torus is an exact distance: |f| is the distance


@pytest.mark.parametrize("gradient", ["central", "forward"])
def test_finite_difference_normals_match_exact_ones(gradient):
    shape, bounds = wm.example("sphere")
    exact = wm.mesh_surface(shape, bounds=bounds, resolution=32, normals=True)
    fd = wm.mesh_surface(shape, bounds=bounds, resolution=32, normals=True, gradient=gradient)
    dots = np.sum(exact.point_data["normals"] * fd.point_data["normals"], axis=1)
    assert np.min(dots) > (1 - 1e-6 if gradient == "central" else 1 - 1e-3)


def test_gradient_refused_where_unused():
    shape, bounds = wm.example("sphere")
    with pytest.raises(ValueError, match="'gradient' applies"):
        wm.mesh_surface(shape, bounds=bounds, resolution=16, gradient="central")
    with pytest.raises(ValueError, match="Unknown gradient"):
        wm.mesh_surface(shape, bounds=bounds, resolution=16, root="newton", gradient="sobel")


@pytest.mark.parametrize("method", ["mc33", "mt", "mc"])
def test_slabs_random_fields_identical(method):
    """Noise (ambiguous cells, mt quads everywhere): one pass and thin slabs agree exactly."""
    rng = np.random.default_rng(1)
    for _ in range(10):
        vol = rng.uniform(-1, 1, tuple(rng.integers(4, 12, 3))).astype(np.float32)
        if (vol[1:-1, 1:-1, 1:-1] > 0).any():
            _same_mesh(wm.mesh_surface(vol, method=method), wm.mesh_surface(vol, method=method, slab_voxels=1))


def test_bool_volume_surface_halfway():
    g = np.indices((40, 40, 40)) - 19.5
    ball = np.sqrt((g**2).sum(axis=0)) < 12
    m = wm.mesh_surface(ball)
    assert m.info["enclosed_volume"] == pytest.approx(4 / 3 * np.pi * 12**3, rel=0.05)
    assert m.stats()["worst_q"] < 5  # vertices at edge midpoints, not on the False samples
    with pytest.raises(ValueError, match="'level'"):
        wm.mesh_surface(ball, level=True)


def test_huge_labels_refused():
    labels = np.zeros((6, 6, 6), dtype=np.uint64)
    labels[2:4, 2:4, 2:4] = np.uint64(2**63 + 5)
    with pytest.raises(ValueError, match="int64"):
        wm.mesh_surface(labels, labels="all")
