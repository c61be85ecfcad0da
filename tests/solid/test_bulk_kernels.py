"""The tetrahedral meshes' bulk passes that moved from numpy into Warp kernels
(``kernels/stuffing.py``): signed volumes, edge keys, longest edges and the merge of two
sorted edge indices give what the numpy code they replaced gives, bit for bit, on random
input, ties and empty runs included, and refuse bad input by name."""

from __future__ import annotations

import numpy as np
import pytest

from warpmesh.solid import graded as G
from warpmesh.solid.dihedral import signed_volumes, tet_quality


def _numpy_volumes(points, tets):
    p = points[tets]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0


def _numpy_longest(coords, tets, keys):
    p = coords[tets]
    d = p[:, G._EDGES[:, 0]] - p[:, G._EDGES[:, 1]]
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
    a, b = tets[:, G._EDGES[:, 0]], tets[:, G._EDGES[:, 1]]
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
        l2 = ((p[:, G._EDGES[:, 0]] - p[:, G._EDGES[:, 1]]) ** 2).sum(axis=2)
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
