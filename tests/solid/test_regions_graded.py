"""Lattice cleaving on a background graded where the regions are thinner than its edges
(warpmesh.solid.thin, ``mesh_regions(..., min_size=)``; issue 23)."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.solid.regions import REFINE_ERROR, mesh_regions
from warpmesh.solid.thin import unresolved_edges

from tests.solid.test_regions import check_regions


def _layered(n=40, layer=2):
    """Label 1 below, a layer of label 2 ``layer`` voxels thick, label 3 above, in a rest of 0."""
    vol = np.zeros((n, n, n), np.uint8)
    mid = n // 2
    vol[4:n - 4, 4:n - 4, 4:mid - layer // 2] = 1
    vol[4:n - 4, 4:n - 4, mid - layer // 2:mid - layer // 2 + layer] = 2
    vol[4:n - 4, 4:n - 4, mid - layer // 2 + layer:n - 4] = 3
    return vol


def _errors(m):
    return {k: r["error"] for k, r in m.info["region_volumes"].items()}


def test_thin_layer_between_two_regions():
    """A layer 2 voxels thick at size 4 voxels (min_size 2 by default). (A layer of 1 voxel is
    not within 5 % at any min_size: +32 % measured, the limit the module docstring states.)"""
    vol = _layered(40, 2)
    uniform = mesh_regions(vol, size=4.0, min_size=4.0)
    assert not uniform.info["graded"]
    assert _errors(uniform)[2] < -0.2  # one cut point per edge: the layer loses a quarter or more
    graded = wm.mesh_domain(vol, labels="all", size=4.0)
    check_regions(graded, rest=0)
    assert graded.info["graded"] and 2 in graded.info["refined_labels"]
    assert graded.info["negative_tets"] == 0
    for label, e in _errors(graded).items():
        assert abs(e) < 0.05, (label, e)
    # the layer's interfaces: 1|2 and 2|3 triangles, no 1|3 (the layer is not pinched off)
    pairs = {tuple(p) for p in np.column_stack([graded.cell_refs["triangle"],
                                                graded.cell_data["label_above"]["triangle"]]).tolist()}
    assert (1, 2) in pairs and (2, 3) in pairs and (1, 3) not in pairs


def test_small_blobs_are_found_and_closer():
    """A 3-voxel cube is lost on the uniform lattice of 4 voxels and a 5-voxel cube loses more
    than 5 %; on the graded one both are specks (refined to half a voxel, their interfaces
    moved to their voxel volumes) and within 1 %."""
    vol = np.ones((32, 32, 32), np.uint8)
    vol[13:16, 14:17, 11:14] = 4
    vol[20:25, 5:10, 21:26] = 5
    uniform = mesh_regions(vol, size=4.0, min_size=4.0)
    graded = mesh_regions(vol, size=4.0, min_size=1.0)
    check_regions(graded, rest=0)
    e0, e1 = _errors(uniform), _errors(graded)
    assert e0[4] == -1.0 and e0[5] < -0.05
    assert abs(e1[4]) < 0.01 and abs(e1[5]) < 0.01 and abs(e1[1]) < 0.01
    assert sorted(graded.info["refined_labels"]) == [4, 5]
    assert sorted(graded.info["speck_offsets"]) == [4, 5]


def _specks(n=20):
    """Label 1 with label 2 above z = 13; specks of 1, 2, 4, 8 and 30 voxels inside label 1
    (labels 3-7), one voxel and 8 voxels touching label 2 (8, 9), one voxel at the volume's
    corner and 4 on its face (10, 11), two single voxels touching each other (12, 13)."""
    vol = np.ones((n, n, n), np.uint8)
    vol[:, :, 13:] = 2
    vol[4, 4, 4] = 3
    vol[9:11, 4, 4] = 4
    vol[4:6, 9:11, 3] = 5
    vol[9:11, 9:11, 8:10] = 6
    vol[2:5, 13:18, 7:9] = 7
    vol[15, 4, 12] = 8
    vol[14:16, 9:11, 11:13] = 9
    vol[0, 0, 0] = 10
    vol[n - 1, 14:16, 2:4] = 11
    vol[15, 15, 6] = 12
    vol[16, 15, 6] = 13
    return vol


def test_specks_within_five_percent():
    """Specks of 1 to 30 voxels (isolated, touching another label or each other, at the volume's
    edge) at size 4 voxels, spacing (1, 1, 1.5) (the frog's): every region within 5 % of its
    voxel volume (measured: 1.0 %; 26-28 % off before the speck zones, lone voxels up to 57 % on
    the frog), none lost, positive and conforming."""
    vol = _specks()
    m = wm.mesh_domain(wm.Volume(vol, spacing=(1.0, 1.0, 1.5)), labels="all", size=4.0)
    check_regions(m, rest=0)
    assert m.info["negative_tets"] == 0
    errors = _errors(m)
    assert sorted(errors) == list(range(1, 14))
    for label, e in errors.items():
        assert abs(e) < 0.05, (label, e)
    assert set(m.info["speck_offsets"]) == set(range(3, 14))
    assert max(abs(d) for d in m.info["speck_offsets"].values()) < 0.5  # voxels: a small move
    assert 0 < m.info["dihedral_min"] and m.info["dihedral_max"] < 180


def test_uniform_when_every_region_is_within_the_tolerance():
    vol = np.zeros((24, 24, 24), np.uint8)
    vol[3:21, 3:21, 3:12] = 1
    vol[3:21, 3:21, 12:21] = 2
    a = mesh_regions(vol, size=3.0)
    b = mesh_regions(vol, size=3.0, min_size=3.0)
    assert max(abs(e) for e in _errors(a).values()) <= REFINE_ERROR
    assert not a.info["graded"] and "refined_labels" not in a.info
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.cells["tetra"], b.cells["tetra"])
    np.testing.assert_array_equal(a.cells["triangle"], b.cells["triangle"])


def test_uniform_mesh_again_when_grading_finds_nothing_to_refine(monkeypatch):
    """A region off by more than the tolerance whose edges the lattice resolves after all (the
    graded background comes back None): the uniform mesh, remade after the uniform pass's
    arrays were let go, is returned, the same as with ``min_size=size``."""
    from warpmesh.solid import regions as R

    vol = _layered(40, 2)
    monkeypatch.setattr(R, "graded_background", lambda *a, **k: None)
    with pytest.warns(UserWarning, match=r"1 region\(s\) off their voxel volume .*label 2: "):
        a = mesh_regions(vol, size=4.0)
    with pytest.warns(UserWarning, match="label 2"):
        b = mesh_regions(vol, size=4.0, min_size=4.0)
    assert not a.info["graded"] and "refined_labels" not in a.info and a.info["min_size"] == 2.0
    np.testing.assert_array_equal(a.points, b.points)
    for kind in ("tetra", "triangle"):
        np.testing.assert_array_equal(a.cells[kind], b.cells[kind])
        np.testing.assert_array_equal(a.cell_refs[kind], b.cell_refs[kind])
    assert a.info["region_volumes"] == b.info["region_volumes"]


def test_graded_volume_with_spacing_and_a_subset():
    vol = _layered(32, 2)
    v = wm.Volume(vol, spacing=(0.5, 0.5, 0.5), origin=(1.0, 2.0, 3.0))
    m = wm.mesh_domain(v, labels=[2, 3], size=2.0)  # 4 voxels; label 1 is the rest
    check_regions(m, rest=0)
    # the box of labels 2 and 3 (voxels [4, 28) x [4, 28) x [15, 28)) in the world frame, to the
    # snapping of cut points (0.3 of an edge)
    box = np.array([1.0, 2.0, 3.0]) + 0.5 * (np.array([[4, 4, 15], [28, 28, 28]]) - 0.5)
    np.testing.assert_allclose(m.points.min(axis=0), box[0], atol=0.3 * 2.0)
    np.testing.assert_allclose(m.points.max(axis=0), box[1], atol=0.3 * 2.0)
    assert m.info["graded"] and sorted(m.info["region_volumes"]) == [2, 3]
    for label, e in _errors(m).items():
        assert abs(e) < 0.05, (label, e)


def test_unresolved_edges():
    vol = np.zeros((12, 4, 4), np.uint8)
    vol[5:7] = 2  # a layer 2 voxels thick across x
    vol[11] = 3

    def at(p):
        k = np.clip(np.rint(p).astype(int), 0, np.array(vol.shape) - 1)
        return vol[k[:, 0], k[:, 1], k[:, 2]]

    a = np.array([[1.0, 1, 1], [1.0, 1, 1], [7.5, 1, 1], [1.0, 1, 1], [5.4, 1, 1]])
    b = np.array([[9.0, 1, 1], [4.0, 1, 1], [11.0, 1, 1], [5.0, 2, 2], [6.6, 1, 1]])
    # across the layer (0 2 0): unresolved; in 0 only; one change 0 -> 3; one change 0 -> 2; in 2
    assert unresolved_edges(at, a, b, np.ones(3), 4).tolist() == [True, False, False, False, False]
    # an excursion shorter than the minimum run is no region
    vol[5:7] = 0
    vol[5, 1, 1] = 2
    clip = unresolved_edges(at, np.array([[4.8, 2.0, 1.45]]), np.array([[6.0, 0.8, 1.45]]), np.ones(3), 4)
    through = unresolved_edges(at, np.array([[4.0, 0.0, 0.0]]), np.array([[6.0, 2.0, 2.0]]), np.ones(3), 4)
    assert clip.tolist() == [False] and through.tolist() == [True]  # 0.28 voxel of the corner; 1.7 voxels
    focus = np.zeros(4, bool)
    focus[3] = True  # only label 3 in focus: the layer of 2 does not count
    vol[5:7] = 2
    assert unresolved_edges(at, a[:1], b[:1], np.ones(3), 4, focus=focus).tolist() == [False]


def test_resolution_samples_only_new_edges_and_answers_as_the_full_test():
    """thin._Resolution samples at each call only the edges with an end added since the last
    one (refine_tets' contract): its answers equal the test of every edge of every tetrahedron
    asked, and it samples each distinct edge asked exactly once."""
    from warpmesh.solid.graded import EDGE_KEY, SizeField, bcc_tetrahedra, refine_tets, tet_edges
    from warpmesh.solid.thin import _Resolution

    g = np.indices((13, 13, 13)).transpose(1, 2, 3, 0)
    vol = np.ones((13, 13, 13), np.uint8)
    vol[np.abs(g[..., 0] + 0.5 * g[..., 1] - 0.3 * g[..., 2] - 7.0) < 0.9] = 2  # a slanted layer
    vol[8:10, 2:4, 8:10] = 3  # a speck

    def at(p):
        k = np.clip(np.rint(p).astype(int), 0, 12)
        return vol[k[:, 0], k[:, 1], k[:, 2]]

    h, small, one = 4.0, 1.0, np.ones(3)
    res = _Resolution(at, one, h, small, 4, None)
    seen, calls = set(), []

    def tet_size(nodes, t):
        got = res(nodes, t)
        keys = tet_edges(t)
        u = np.unique(keys)
        bad = unresolved_edges(at, nodes[u // EDGE_KEY], nodes[u % EDGE_KEY], one, 4)
        np.testing.assert_array_equal(got, np.where(bad[np.searchsorted(u, keys)].any(axis=1), small, h))
        seen.update(u.tolist())
        calls.append(int((got == small).sum()))
        return got

    coords, tets = bcc_tetrahedra((4, 4, 4))
    _, _, levels = refine_tets(coords, tets, h, np.zeros(3), SizeField(lambda p: np.full(len(p), h), small, h),
                               tet_size=tet_size)
    assert len(calls) >= 3 and calls[0] > 0 and levels.max() >= 3
    assert res.sampled == len(seen)


def test_bad_min_size():
    vol = _layered(16, 2)
    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "small", [1.0]):
        with pytest.raises(ValueError, match="'min_size'"):
            mesh_regions(vol, size=3.0, min_size=bad)
    with pytest.raises(ValueError, match="quarter voxel"):
        mesh_regions(vol, size=3.0, min_size=0.1)


def test_frog_crop_at_four_voxels():
    """A 120 x 120 x 60 crop of pyvista's frog (18 labels) at size 4 voxels: the uniform lattice
    misses labels 1 and 13 (2-3 voxel layers in the crop) by more than 5 % and loses three
    specks; the graded one (the defaults) is conforming and brings every label within 5 %, the
    specks of 2 to 252 voxels in the crop included, none lost (measured: 1 -6.2 -> -0.9 %,
    13 -6.7 -> -1.6 %, specks within 0.8 %, worst 14 at -2.7 %; before the speck zones the specks
    were 10-100 % off)."""
    pv = pytest.importorskip("pyvista")
    frog = pv.examples.load_frog_tissues()
    values = frog.active_scalars.reshape(frog.dimensions, order="F")
    sub = np.ascontiguousarray(values[180:300, 150:270, 40:100])
    vol = wm.Volume(sub, spacing=frog.spacing)
    uniform = wm.mesh_domain(vol, labels="all", size=4.0, min_size=4.0)
    graded = wm.mesh_domain(vol, labels="all", size=4.0)
    check_regions(graded, rest=0)
    assert graded.info["graded"] and graded.info["negative_tets"] == 0
    big = [int(L) for L in np.unique(sub) if L != 0 and (sub == L).sum() >= 1000]
    e0, e1 = _errors(uniform), _errors(graded)
    assert max(abs(e0[L]) for L in big) > 0.05
    for L in big:
        assert abs(e1[L]) < 0.05, (L, e1[L])
    lost0 = sum(e == -1.0 for e in e0.values())
    assert lost0 > 0
    for L, e in e1.items():
        assert abs(e) < 0.05, (L, e)


def test_labels_at_is_the_same_for_every_memory_layout():
    """The flat gather of a contiguous volume (C or Fortran order) gives the labels of the
    strided path: every point, those outside the box (the rest) included."""
    from warpmesh.solid.thin import labels_at as _labels_at

    rng = np.random.default_rng(5)
    vol = rng.integers(1, 9, (7, 5, 6)).astype(np.uint8)
    spacing = np.array([1.0, 0.5, 1.5])
    pts = rng.uniform(-2.0, 1.0, (4000, 3)) * spacing + rng.uniform(0, 1, (4000, 3)) * np.array(vol.shape) * spacing
    want = np.array([vol[tuple(k)] if ((k >= 0) & (k < vol.shape)).all() else 0
                     for k in np.rint(pts / spacing).astype(int)], np.uint8)
    assert 0 < (want == 0).sum() < len(want)  # some outside, most inside
    layouts = (vol, np.asfortranarray(vol), np.ascontiguousarray(vol[:, ::-1, :])[:, ::-1, :],
               np.concatenate([vol, vol], axis=1)[:, :5, :])
    assert [(x.flags.c_contiguous, x.flags.f_contiguous) for x in layouts] == \
        [(True, False), (False, True), (False, False), (False, False)]
    for layout in layouts:
        np.testing.assert_array_equal(_labels_at(layout, pts, spacing, 0), want)


def test_refine_tets_asks_tet_size_only_above_the_smallest_size():
    """A tet_size equal to the field's own rule gives the field's background bit for bit,
    though the tetrahedra already at the smallest size are never handed to it; a size below
    the field's smallest raises."""
    from warpmesh.solid.graded import bcc_tetrahedra, refine_tets, size_field

    coords, tets = bcc_tetrahedra((5, 5, 5))
    h0, origin = 1.0, np.zeros(3)

    def size(p):
        return 0.3 + 0.4 * (p[:, 0] > 1.5)

    field = size_field(size, np.array([[0.0] * 3, [4.0] * 3]))
    asked = []

    def tet_size(nodes, t):
        asked.append(np.linalg.norm(nodes[t[:, :, None]] - nodes[t[:, None, :]], axis=-1).max(axis=(1, 2)))
        return np.minimum(size(nodes[t].reshape(-1, 3)).reshape(-1, 4).min(axis=1), size(nodes[t].mean(axis=1)))

    a = refine_tets(coords, tets, h0, origin, field)
    b = refine_tets(coords, tets, h0, origin, field, tet_size=tet_size)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    assert (b[2] > 0).any() and len(asked) > 1
    assert np.concatenate(asked).min() > field.smallest * (1 + 1e-9)
    with pytest.raises(ValueError, match="tet_size"):
        refine_tets(coords, tets, h0, origin, field, tet_size=lambda n, t: np.full(len(t), 0.5 * field.smallest))


def test_graded_background_boundary_check():
    """The background's own boundary (faces in one tetrahedron) must hold no meshed node:
    a block whose meshed node is interior passes, the same node on the boundary is refused."""
    from warpmesh.errors import WarpMeshError
    from warpmesh.solid.thin import _check_boundary

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.2, 0.2]], float)
    # four tetrahedra around the interior point 4, their outer faces the big tetrahedron's
    tets = np.array([[4, 1, 2, 3], [0, 4, 2, 3], [0, 1, 4, 3], [0, 1, 2, 4]])
    code = np.array([0, 0, 0, 0, 5])  # rest 0; node 4 meshed
    _check_boundary(pts, tets, code, 0)
    code[1] = 5  # a meshed node on the boundary
    with pytest.raises(WarpMeshError, match="3 faces of the graded background"):
        _check_boundary(pts, tets, code, 0)


def test_a_graded_mesh_worse_than_the_uniform_one_is_not_kept():
    """Four 1-voxel layers in a block at size 3: the uniform lattice is 3-4 % off (above
    REFINE_ERROR), the graded pass about 20 % (layers as thin as min_size): the uniform mesh
    is returned, and info says why."""
    v = np.zeros((20, 20, 20), np.uint8)
    v[2:-2, 2:-2, 2:-2] = 1
    for i, z in enumerate(range(5, 15, 3)):
        v[2:-2, 2:-2, z] = 2 + i % 2
    with pytest.warns(UserWarning, match="off their voxel volume"):
        m = wm.mesh_domain(v, size=3.0)
    check_regions(m, rest=0)
    rejected = m.info["graded_rejected"]
    assert m.info["graded"] is False and "refined_labels" not in m.info
    assert rejected["graded_error"] > rejected["uniform_error"] == pytest.approx(m.info["region_error_max"])
    assert m.info["region_error_max"] < 0.05
