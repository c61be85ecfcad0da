"""The row pass of sampled volumes (flying edges, kernels/flying_edges.py) against the block
grid's slab pass, which it replaces for "mc" and "mc33": the same vertices (within float32
rounding), the same triangles with the same winding, the same vertex flags, value range
and statistics, on random fields with ties, zeros and ambiguous cells, levels, signs,
caps, spacings, clearances, label and bool volumes, and slab sizes."""

import numpy as np
import pytest
import warp as wp
from scipy.spatial import cKDTree

import warpmesh as wm
from tests.helpers.meshcheck import check_mesh
from warpmesh.surface.volume import check_closed_outward, extract_fields, extract_volume, label_rows


def _extract(vol, engine, method, *, level=0.0, sign=1.0, cap=True, label=None, spacing=(1.0, 1.0, 1.0),
             slab_voxels=1 << 24, clearance=0.05):
    info = {}
    points, faces, flags, rng = extract_volume(
        vol, (0.5, -1.0, 2.0), np.asarray(spacing, dtype=np.float64), level=level, sign=sign, method=method,
        cap=cap, cull=True, device=wp.get_device("cpu"), slab_voxels=slab_voxels, label=label, timings={},
        info=info, clearance=clearance, engine=engine)
    return points, faces, flags, rng, info


def _assert_same(rows, slabs):
    """The same vertices (matched by position), triangles (as cyclic vertex sequences:
    winding kept), flags and value range; the same counts in the statistics."""
    pa, fa, ga, ra, ia = slabs
    pb, fb, gb, rb, ib = rows
    assert ra == rb
    assert len(pa) == len(pb) and len(fa) == len(fb)
    assert ia["interior_vertices"] == ib["interior_vertices"]
    if ia["slabs"] == 1:  # the slab pass counts a moved seam vertex in both its slabs
        assert ia["clearance_moved"] == ib["clearance_moved"]
    if len(pa) == 0:
        return
    d, idx = cKDTree(pa).query(pb)
    assert d.max() == 0.0  # bit for bit: both measure float32 positions from the volume's node 0
    assert len(np.unique(idx)) == len(idx)
    assert np.array_equal(ga[idx], gb)

    def cyclic(tris):
        first = np.argmin(tris, axis=1)
        return {tuple(np.roll(t, -f)) for t, f in zip(tris.tolist(), first.tolist())}

    assert cyclic(fa) == cyclic(idx[fb])


@pytest.mark.parametrize("method", ["mc", "mc33"])
def test_random_fields_ties_and_caps(method):
    rng = np.random.default_rng(7)
    for it in range(24):
        shape = tuple(int(v) for v in rng.integers(3, 13, 3))
        vol = rng.uniform(-1, 1, shape).astype(np.float32)
        if it % 3 == 0:  # values on the level: ties in the deciders, zeros at nodes
            vol = np.round(vol * 2).astype(np.float32)
        kw = dict(cap=bool(it % 2), level=float(rng.choice([0.0, 0.25])), sign=float(rng.choice([1.0, -1.0])),
                  spacing=tuple(rng.uniform(0.2, 3.0, 3)), clearance=float(rng.choice([0.0, 0.05, 0.3])))
        _assert_same(_extract(vol, "rows", method, slab_voxels=int(rng.integers(1, 400)), **kw),
                     _extract(vol, "slabs", method, slab_voxels=int(rng.integers(1, 400)), **kw))


@pytest.mark.parametrize("method", ["mc", "mc33"])
def test_mc33_tunnels_and_long_rows(method):
    """Rows longer than one 64-node word, a smooth field with tunnels (interior vertices)."""
    x = np.linspace(0, 3 * np.pi, 70)
    i, j, k = x[:21, None, None], x[None, :17, None], x[None, None, :]
    vol = (np.sin(i) * np.cos(j) + np.sin(j) * np.cos(k) + np.sin(k) * np.cos(i)).astype(np.float32)
    rows = _extract(vol, "rows", method, level=0.1)
    _assert_same(rows, _extract(vol, "slabs", method, level=0.1))
    assert vol.shape[2] > 64 and len(rows[1]) > 1000


def test_ambiguous_cells_exercise_every_mc33_branch():
    """Checkerboard-like noise: ambiguous faces and interior tests, hubs and spokes."""
    rng = np.random.default_rng(3)
    vol = (rng.uniform(-1, 1, (14, 15, 16)) * np.where(np.indices((14, 15, 16)).sum(axis=0) % 2, 1, -1))
    vol = vol.astype(np.float32)
    rows = _extract(vol, "rows", "mc33", cap=False)
    _assert_same(rows, _extract(vol, "slabs", "mc33", cap=False))
    assert rows[4]["interior_vertices"] > 0


@pytest.mark.parametrize("method", ["mc", "mc33"])
def test_label_and_bool_volumes(method):
    rng = np.random.default_rng(11)
    for _ in range(6):
        shape = tuple(int(v) for v in rng.integers(3, 14, 3))
        labels = rng.integers(0, 4, shape).astype(np.uint8)
        sp = tuple(rng.uniform(0.3, 2.0, 3))
        for label in (1, 3):
            _assert_same(_extract(labels, "rows", method, level=0.5, label=label, spacing=sp, slab_voxels=50),
                         _extract(labels, "slabs", method, level=0.5, label=label, spacing=sp))
        wide = labels.astype(np.int16) * 300  # another integer dtype: its indicator, as uint8
        _assert_same(_extract(wide, "rows", method, level=0.5, label=600),
                     _extract(wide, "slabs", method, level=0.5, label=600))
        ball = labels > 1
        _assert_same(_extract(ball, "rows", method, level=0.5, spacing=sp),
                     _extract(ball, "slabs", method, level=0.5, spacing=sp))
        _assert_same(_extract(labels, "rows", method, level=1.5, sign=-1.0),  # uint8 values, not a label
                     _extract(labels, "slabs", method, level=1.5, sign=-1.0))


def test_strided_float_volume_is_copied_once_and_meshed_alike():
    rng = np.random.default_rng(5)
    vol = rng.normal(size=(12, 11, 20)).astype(np.float32)[:, ::-1, ::2]
    assert not vol.flags.c_contiguous
    _assert_same(_extract(vol, "rows", "mc33"), _extract(vol, "slabs", "mc33"))


def test_mesh_surface_takes_the_row_pass_where_it_applies(device):
    g = np.linspace(-1, 1, 60)
    vol = (0.8 - np.sqrt(g[:, None, None] ** 2 + g[None, :, None] ** 2 + g[None, None, :] ** 2))
    m = wm.mesh_surface(vol.astype(np.float32), spacing=g[1] - g[0], device=device)
    assert m.info["engine"] == "rows" and "signed_volume" not in m.info
    check_mesh(m)
    assert m.info["enclosed_volume"] == pytest.approx(4 / 3 * np.pi * 0.8**3, rel=0.02)
    # the kernel's signed volume is the one the host check computes from the triangles
    assert check_closed_outward(m.points, m.cells["triangle"]) == pytest.approx(m.info["enclosed_volume"],
                                                                                 rel=1e-6)
    assert wm.mesh_surface(vol, device=device).info["engine"] == "slabs"  # float64: float32 copies per slab
    assert wm.mesh_surface(vol.astype(np.float32), method="mt", device=device).info["engine"] == "slabs"


def test_engine_choice_is_checked():
    vol = np.zeros((4, 4, 4), np.float32)
    vol[1:3, 1:3, 1:3] = 1
    with pytest.raises(ValueError, match="'engine'"):
        _extract(vol, "flying", "mc")
    with pytest.raises(ValueError, match="row pass"):
        _extract(vol, "rows", "mt")
    with pytest.raises(ValueError, match="row pass"):
        _extract(vol.astype(np.float64), "rows", "mc")


def test_labels_share_one_pass_over_the_rows():
    """extract_fields: the labels of a uint8 volume classified from the rows holding each
    (one listing pass, 64 labels a word: 70 labels take two) mesh as the slab pass does."""
    rng = np.random.default_rng(13)
    labels = np.zeros((14, 12, 75), np.uint8)
    for value in range(1, 71):  # blocks of 70 labels, some rows holding none
        i, j, k = rng.integers(0, (11, 9, 70))
        labels[i:i + 3, j:j + 3, k:k + 5] = value
    labels[5] = 0  # a plane of rows without any label
    fields = list(range(1, 71)) + [200]  # and a label that is absent
    opts = dict(level=0.5, sign=1.0, method="mc33", cap=True, cull=True, device=wp.get_device("cpu"),
                slab_voxels=1 << 24, timings={}, clearance=0.05)
    shared = list(extract_fields(labels, (0.0, 0.0, 0.0), np.ones(3), fields, info={}, **opts))
    assert len(shared) == len(fields)
    for label, got in zip(fields, shared):
        info = {}
        ref = extract_volume(labels, (0.0, 0.0, 0.0), np.ones(3), label=label, info=info, engine="slabs", **opts)
        _assert_same((*got, info), (*ref, info))
    assert shared[-1][3][1] <= 0.0  # the absent label: no sample inside (the pipeline refuses it)
    assert label_rows(labels, [1, 2, None, 300], "cpu").numpy().max() < 4  # bits only for meshed uint8 values


def test_label_volumes_through_mesh_surface(device):
    labels = np.zeros((30, 28, 26), np.uint8)
    labels[3:12, 4:20, 5:21] = 1
    labels[14:27, 4:20, 5:21] = 2
    labels[16:20, 23:26, 9:13] = 3  # apart from the others (touching labels share faces: not embedded)
    m = wm.mesh_surface(labels, labels="all", device=device)
    check_mesh(m)
    assert m.info["engine"] == "rows" and sorted(set(m.cell_refs["triangle"].tolist())) == [1, 2, 3]
    one = wm.mesh_surface(labels, labels=[3], device=device)
    assert np.count_nonzero(m.cell_refs["triangle"] == 3) == len(one.cells["triangle"])
