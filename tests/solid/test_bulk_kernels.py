"""The tetrahedral meshes' bulk passes that moved from numpy into Warp kernels
(``kernels/stuffing.py``): signed volumes, edge keys, longest edges, the merge of two
sorted edge indices, the unresolved edges, the speck sizes and the cleaving's fans give what
the numpy code they replaced gives, bit for bit, on random input, ties and empty runs
included, and refuse bad input by name."""

from __future__ import annotations

import numpy as np
import pytest

from warpmesh.solid import graded as G
from warpmesh.solid.dihedral import signed_volumes, tet_quality
from warpmesh.solid.stencils import EDGES

_EDGES = np.array(EDGES)  # the local edge order of the kernels: 01, 02, 03, 12, 13, 23


def _numpy_volumes(points, tets):
    p = points[tets]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0


def _numpy_longest(coords, tets, keys):
    p = coords[tets]
    d = p[:, _EDGES[:, 0]] - p[:, _EDGES[:, 1]]
    length2 = np.einsum("mek,mek->me", d, d)
    best = length2.max(axis=1, keepdims=True)
    cand = np.where(length2 == best, keys, np.iinfo(np.int64).max)
    return cand.min(axis=1), np.sqrt(best[:, 0])


def _numpy_merged(sorted_flat, order, add, where):
    keys = np.concatenate([add, sorted_flat])
    o = np.argsort(keys, kind="stable")
    return keys[o], np.concatenate([where, order])[o]


@pytest.mark.parametrize("scale", [1.0, 1.0e3, 1.0e-3])
def test_signed_volumes_equal_numpys(scale):
    rng = np.random.default_rng(7)
    pts = rng.normal(size=(20_000, 3)) * scale
    tets = rng.integers(0, len(pts), size=(300_000, 4))
    got = signed_volumes(pts, tets)
    ref = _numpy_volumes(pts, tets)
    # the documented order (products of components 0 and 2 added first) restated elementwise
    p = pts[tets]
    u, v, w = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    c0, c1, c2 = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1], u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2], \
        u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    assert np.array_equal(got, ((c0 * w[:, 0] + c2 * w[:, 2]) + c1 * w[:, 1]) / 6.0)
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * scale**3)
    big = np.abs(ref) > 1e-6 * scale**3  # away from rounding: swapping two vertices flips the sign
    assert (np.sign(got[big]) == -np.sign(signed_volumes(pts, tets[big][:, [1, 0, 2, 3]]))).all()


def test_signed_volumes_bad_input_names_the_argument():
    pts = np.eye(4, 3)
    assert signed_volumes(pts, np.zeros((0, 4), int)).shape == (0,)
    with pytest.raises(ValueError, match="'tets'"):
        signed_volumes(pts, [[0, 1, 2, 4]])
    with pytest.raises(ValueError, match="'tets'"):
        signed_volumes(pts, [[0, 1, -1, 2]])
    with pytest.raises(ValueError, match="'tets'"):
        signed_volumes(pts, [[0, 1, 2]])
    with pytest.raises(ValueError, match="'points'"):
        signed_volumes(np.zeros((4, 2)), [[0, 1, 2, 3]])


@pytest.mark.parametrize("bad", [[[0, 1, 2, 4]], [[0, 1, -1, 2]], [[0, 1, 2, 2**31 + 1]]])
def test_tet_quality_refuses_indices_outside_the_points(bad):
    """The quality kernel reads the points in place: an index outside them (or one that int32
    would wrap) is a ValueError naming 'tets', from the per-tetrahedron call and the summary."""
    from warpmesh.solid.dihedral import tet_quality_summary

    pts = np.eye(4, 3)
    with pytest.raises(ValueError, match="'tets'"):
        tet_quality(pts, bad)
    with pytest.raises(ValueError, match="'tets'"):
        tet_quality_summary(pts, bad)
    assert tet_quality(pts, np.zeros((0, 4), int)).shape == (0, 4)


def test_tet_quality_split_across_cores_is_per_tetrahedron():
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(2_000, 3))
    tets = rng.integers(0, len(pts), size=(100_000, 4))
    q = tet_quality(pts, tets)
    # each row depends only on its tetrahedron: the same as the rows computed alone
    rows = rng.integers(0, len(tets), 50)
    assert np.array_equal(q[rows], np.concatenate([tet_quality(pts, tets[r:r + 1]) for r in rows]))
    np.testing.assert_allclose(q[:, 3], _numpy_volumes(pts, tets), rtol=1e-10, atol=1e-14)


def test_edge_keys_equal_numpys():
    rng = np.random.default_rng(5)
    tets = rng.integers(0, 2**30, size=(200_000, 4))
    a, b = tets[:, _EDGES[:, 0]], tets[:, _EDGES[:, 1]]
    assert np.array_equal(G.tet_edges(tets), np.minimum(a, b) * G.EDGE_KEY + np.maximum(a, b))
    assert G.tet_edges(np.zeros((0, 4), np.int64)).shape == (0, 6)


@pytest.mark.parametrize("lattice", [False, True])
def test_longest_edges_equal_numpys_ties_to_the_smallest_key(lattice):
    rng = np.random.default_rng(11)
    coords = (rng.integers(0, 3, size=(400, 3)) * 0.5) if lattice else rng.normal(size=(5_000, 3))
    tets = rng.integers(0, len(coords), size=(100_000, 4))
    keys = G.tet_edges(tets)
    lkey, llen = G._longest(coords, tets, keys)
    rkey, rlen = _numpy_longest(coords, tets, keys)
    assert np.array_equal(lkey, rkey) and np.array_equal(llen, rlen)
    if lattice:  # small half-integer lattices: many equal lengths, decided by the key
        p = coords[tets]
        l2 = ((p[:, _EDGES[:, 0]] - p[:, _EDGES[:, 1]]) ** 2).sum(axis=2)
        assert ((l2 == l2.max(axis=1, keepdims=True)).sum(axis=1) > 1).mean() > 0.3


@pytest.mark.parametrize("na, nb, high", [(0, 5, 3), (5, 0, 3), (1, 1, 2), (7, 7, 1), (10, 1_000, 50),
                                          (1_000, 10, 50), (300_000, 2_000_000, 10**6), (500_000, 500_000, 100)])
def test_merged_index_equals_the_stable_sort(na, nb, high):
    rng = np.random.default_rng(na + nb)
    add, flat = np.sort(rng.integers(0, high, na)), np.sort(rng.integers(0, high, nb))
    where, order = rng.integers(0, 10**9, na), rng.integers(0, 10**9, nb)
    keys, values = G._merged(flat, order, add, where)
    ref_keys, ref_values = _numpy_merged(flat, order, add, where)
    assert np.array_equal(keys, ref_keys) and np.array_equal(values, ref_values)


@pytest.mark.parametrize("trial", range(6))
def test_unresolved_edges_kernel_equals_the_numpy_sampling(trial):
    from warpmesh.solid.thin import VoxelLabels, unresolved_edges

    rng = np.random.default_rng(trial)
    shape = tuple(int(x) for x in rng.integers(5, 30, 3))
    n_codes = [2, 3, 6, 200, 300, 70_000][trial]
    dtype = np.uint8 if n_codes <= 256 else np.uint16 if n_codes <= 65_536 else np.int32
    codes = rng.integers(0, min(n_codes, 5) if trial % 2 else n_codes, size=shape).astype(dtype)
    if trial % 3 == 0:
        codes = np.asfortranarray(codes)  # the layout label_codes gives
    spacing = rng.uniform(0.5, 2.0, 3)
    labels = VoxelLabels(codes, spacing, int(codes.max()) + 1)
    a = rng.uniform(-0.2, 1.2, (5_000, 3)) * np.array(shape) * spacing  # some ends outside the volume
    b = a + rng.normal(size=(5_000, 3)) * rng.uniform(0.5, 6.0)
    a[:50] = (np.round(a[:50] / spacing) + 0.5) * spacing  # samples on ties of the rounding
    b[50:60] = a[50:60]  # zero-length edges
    focus = rng.random(int(codes.max()) + 2) < 0.5
    hits = 0
    for fo in (None, focus):
        for per_voxel, min_run in ((4, None), (2, 1), (4, 5)):
            got = unresolved_edges(labels, a, b, spacing, per_voxel, min_run=min_run, focus=fo)
            want = unresolved_edges(labels, a, b, spacing, per_voxel, min_run=min_run, focus=fo, kernel=False)
            assert np.array_equal(got, want)
            hits += int(got.sum())
    assert hits > 0


def test_voxel_labels_without_a_kernel_layout_use_numpy():
    from warpmesh.solid.thin import VoxelLabels, labels_at, unresolved_edges

    codes = np.arange(64, dtype=np.int64).reshape(4, 4, 4) % 3  # int64 codes and a strided view: no kernel
    for c in (codes, codes.astype(np.uint8)[::2]):
        labels = VoxelLabels(c, [1.0, 1.0, 1.0], 7)
        assert (labels.kernel_codes() is None) == (c.dtype == np.int64 or not c.flags.c_contiguous)
        a, b = np.zeros((3, 3)), np.array([[3.0, 0, 0], [0, 3.0, 0], [1.0, 1.0, 0]])
        got = unresolved_edges(labels, a, b, np.ones(3), 4)
        assert np.array_equal(got, unresolved_edges(labels, a, b, np.ones(3), 4, kernel=False))
        np.testing.assert_array_equal(labels(a), labels_at(c, a, np.ones(3), 7))


@pytest.mark.parametrize("trial", range(6))
def test_speck_sizes_kernel_equals_the_numpy_levels(trial):
    from warpmesh.solid.thin import Specks

    rng = np.random.default_rng(trial)
    shape = rng.integers(8, 60, 3)
    spacing = rng.uniform(0.5, 2.0, 3)
    n_voxels = int(rng.integers(1, 30))
    voxels = np.stack([rng.integers(0, s, n_voxels) for s in shape], 1)
    sizes = rng.choice([0.7, 1.3, 2.9][: 1 + trial % 3], n_voxels)  # one to three levels
    largest = float(rng.uniform(2, 10))
    specks = Specks(voxels, sizes, shape, spacing, largest)
    n = 20_000
    centre = rng.uniform(-0.1, 1.1, (n, 3)) * shape * spacing  # some boxes off the volume
    scale = rng.choice([0.3, 2.0, largest], (n, 1))  # boxes of every block level, none wider than largest
    nodes = (centre[:, None, :] + rng.uniform(-0.5, 0.5, (n, 4, 3)) * scale[:, :, None]).reshape(-1, 3)
    tets = np.arange(4 * n).reshape(n, 4)[rng.permutation(n)]
    got = specks.size_of(nodes, tets)
    want = specks.size_of(nodes, tets, kernel=False)
    assert np.array_equal(got, want)
    assert 0.002 < np.isfinite(want).mean() < 0.998  # both near and far tetrahedra (40 or more of each)
    if trial % 3:
        assert len(np.unique(want[np.isfinite(want)])) > 1  # several levels hit


def _cleaving_inputs(trial: int):
    """The arguments ``cleave`` hands the sub-tetrahedra (and so ``_fans``) on a random label
    volume: a few balls and slabs of several labels, thin ones included, at a size that
    snaps some cuts and grades where labels are thin."""
    from warpmesh.solid import regions as R

    rng = np.random.default_rng(100 + trial)
    n = 20 + 4 * trial
    g = np.indices((n, n, n)).astype(float)
    vol = np.zeros((n, n, n), np.int16)
    for label in rng.choice(np.arange(1, 30), size=3 + trial % 3, replace=False):
        c, r = rng.uniform(0.2 * n, 0.8 * n, 3), rng.uniform(2, 0.35 * n)
        vol[((g - c[:, None, None, None]) ** 2).sum(0) < r * r] = label
    a = rng.integers(1, n - 4)
    vol[a:a + 1 + trial % 2, 2:n - 2, 3:n - 3] = 31  # a slab one or two voxels thick
    seen = []
    orig = R._fans

    def spy(*args, **kw):
        seen.append((args, kw))
        return orig(*args, **kw)

    R._fans = spy
    try:
        R.mesh_regions(vol, size=float(rng.uniform(2.0, 3.5)), min_size=1.0 if trial % 2 else None)
    finally:
        R._fans = orig
    return seen


@pytest.mark.parametrize("trial", range(4))
def test_cleave_fans_kernel_equals_the_numpy_faces(trial):
    """Sub-tetrahedra, their codes, interface triangles and their two codes: the same arrays in
    the same order from the kernel (count, prefix sums, write) as from the face-by-face numpy
    code, with and without tetrahedra placed first (``lead``), on every call of a cleaving."""
    from warpmesh.solid import regions as R

    calls = _cleaving_inputs(trial)
    assert calls and any(len(args[0]) for args, _ in calls)
    for args, kw in calls:
        got = R._fans(*args, **kw)
        want = R._fans_numpy(*args, **kw)
        for name, a, b in zip(("tets", "codes", "triangles", "lower", "upper"), got, want):
            assert a.dtype == np.int64 and a.shape == b.shape and np.array_equal(a, b), name
        if kw.get("lead") is not None:
            bare = R._fans(*args)
            assert np.array_equal(bare[0], got[0][len(kw["lead"][0]):]) and np.array_equal(bare[2], got[2])
    tets, codes, tris, lower, upper = R._fans(*calls[-1][0])
    assert len(tris) and (lower < upper).all()  # the volume has interfaces: the comparison saw some


def test_cleave_fans_kernel_on_no_tetrahedra():
    from warpmesh.solid import regions as R

    lead = (np.arange(8, dtype=np.int64).reshape(2, 4), np.array([3, 4], np.int64))
    e = np.zeros((0, 4), np.int64)
    out = R._fans(e, e.astype(np.int32), np.zeros((0, 6), np.int64), np.zeros(0, np.int64), e, 10, 0, lead)
    assert np.array_equal(out[0], lead[0]) and np.array_equal(out[1], lead[1])
    assert [len(a) for a in out[2:]] == [0, 0, 0]


@pytest.mark.parametrize("chunk", [7, 1000, 1 << 20])
def test_quality_summary_by_chunks_equals_the_whole_array(monkeypatch, chunk):
    """tet_quality_summary reduces chunk by chunk: the extremes and the count are those of the
    whole (m, 4) quality array, the mean within rounding, chunks of 7 to all at once (a last
    chunk short, inverted and flat tetrahedra included)."""
    from warpmesh.solid import dihedral as D

    rng = np.random.default_rng(3)
    pts = rng.normal(size=(400, 3))
    tets = rng.integers(0, 400, size=(999, 4))
    tets[5] = [1, 1, 2, 3]  # flat: zero volume
    monkeypatch.setattr(D, "SUMMARY_CHUNK", chunk)
    got = D.tet_quality_summary(pts, tets)
    q = tet_quality(pts, tets)
    assert got["dihedral_min"] == q[:, 0].min() and got["dihedral_max"] == q[:, 1].max()
    assert got["radius_edge_max"] == q[:, 2].max() and got["min_volume"] == q[:, 3].min()
    assert got["negative_tets"] == int((q[:, 3] <= 0).sum()) > 1
    assert got["radius_edge_mean"] == pytest.approx(q[:, 2].mean(), rel=1e-12)


def test_tet_quality_equals_the_numpy_references():
    """The kernel's extreme dihedral angles and radius-edge ratio against the numpy
    functions (every angle computed, then reduced), on random and near-flat tetrahedra."""
    from warpmesh.solid.dihedral import dihedral_angles, radius_edge_ratio

    rng = np.random.default_rng(8)
    pts = rng.normal(size=(500, 3))
    tets = np.argsort(rng.random((4000, 500)), axis=1)[:, :4]
    pts[499] = 0.5 * (pts[tets[0, 0]] + pts[tets[0, 1]]) + 1e-7  # a near-flat one: angles near 0 and 180
    tets[0, 2] = 499
    q = tet_quality(pts, tets)
    ang = np.degrees(dihedral_angles(pts, tets))
    # (acos is ill-conditioned near +-1: the near-flat one agrees to 1e-6 degrees only)
    np.testing.assert_allclose(q[1:, 0], ang[1:].min(axis=1), rtol=0, atol=1e-7)
    np.testing.assert_allclose(q[1:, 1], ang[1:].max(axis=1), rtol=0, atol=1e-7)
    np.testing.assert_allclose(q[0, :2], [ang[0].min(), ang[0].max()], rtol=0, atol=1e-6)
    assert q[0, 0] < 1e-3 or q[0, 1] > 179.0
    np.testing.assert_allclose(q[:, 2], radius_edge_ratio(pts, tets), rtol=1e-9)
