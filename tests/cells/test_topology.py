"""warpmesh.cells.topology on shapes whose answers are known, and the shared check_mesh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from tests.helpers.meshcheck import check_mesh as check_mesh_fn

from warpmesh.cells import topology as topo


def _pf(tm):
    return np.asarray(tm.vertices), np.asarray(tm.faces)


@pytest.fixture(scope="module")
def sphere():
    return _pf(trimesh.creation.icosphere(subdivisions=2, radius=1.5))


@pytest.fixture(scope="module")
def torus():
    return _pf(
        trimesh.creation.torus(
            major_radius=1.0, minor_radius=0.3, major_sections=24, minor_sections=12
        )
    )


def _two_tets_sharing_a_vertex():
    """Two closed tetrahedra glued at vertex 0: edge-manifold but not vertex-manifold."""
    pts = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, 0, 0], [0, -1, 0], [0, 0, -1]], float
    )
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    other = np.array([[0, 4, 5], [0, 6, 4], [4, 6, 5], [0, 5, 6]])
    return pts, np.vstack([tet, other])


# ------------------------------------------------------------------------- edges
def test_unique_edges_small_example():
    faces = np.array([[0, 1, 2], [2, 1, 3]])
    edges, face_edge, counts = topo.unique_edges(faces)
    assert edges.tolist() == [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    assert counts.tolist() == [1, 1, 2, 1, 1]
    assert face_edge.shape == (2, 3) and face_edge.dtype == np.int64
    expect = np.sort(np.stack([faces, np.roll(faces, -1, axis=1)], axis=2), axis=2)
    np.testing.assert_array_equal(edges[face_edge], expect)


def test_closed_surface_has_3f_over_2_edges(sphere):
    _, faces = sphere
    edges, _, counts = topo.unique_edges(faces)
    assert len(edges) == 3 * len(faces) // 2
    assert np.all(counts == 2)


# ------------------------------------------------------------------------- closed shapes
@pytest.mark.parametrize(
    ("make", "euler", "n_components"),
    [
        (lambda: trimesh.creation.icosphere(subdivisions=2), 2, 1),
        (lambda: trimesh.creation.box(extents=(1, 2, 3)), 2, 1),
        (lambda: trimesh.creation.torus(1.0, 0.3, major_sections=24, minor_sections=12), 0, 1),
        (
            lambda: trimesh.util.concatenate(
                [trimesh.creation.icosphere(1), trimesh.creation.box().apply_translation([5, 0, 0])]
            ),
            4,
            2,
        ),
    ],
    ids=["sphere", "box", "torus", "sphere+box"],
)
def test_closed_shapes(make, euler, n_components):
    pts, faces = _pf(make())
    assert topo.is_watertight(faces)
    assert topo.is_edge_manifold(faces)
    assert topo.is_vertex_manifold(faces, len(pts))
    assert topo.is_consistently_oriented(faces)
    assert topo.euler_characteristic(None, faces) == euler
    count, labels = topo.connected_components(faces, len(pts))
    assert count == n_components
    assert labels.shape == (len(faces),) and labels[0] == 0
    check_mesh_fn(pts, faces)


def test_euler_uses_given_vertex_count(sphere):
    _, faces = sphere
    assert topo.euler_characteristic(len(np.unique(faces)), faces) == 2
    # an unreferenced point changes nothing when V is counted from the faces
    assert topo.euler_characteristic(None, faces) == 2


def test_open_mesh_is_not_watertight(sphere):
    pts, faces = sphere
    open_faces = faces[1:]
    assert not topo.is_watertight(open_faces)
    assert topo.is_edge_manifold(open_faces)
    assert topo.is_consistently_oriented(open_faces)
    assert topo.is_vertex_manifold(open_faces)
    assert topo.euler_characteristic(None, open_faces) == 1  # a disk
    assert not topo.is_watertight(np.zeros((0, 3), int))


def test_one_flipped_face_is_not_oriented(sphere):
    _, faces = sphere
    flipped = faces.copy()
    flipped[7] = flipped[7, ::-1]
    assert topo.is_watertight(flipped)
    assert not topo.is_consistently_oriented(flipped)


def test_non_manifold_edge():
    faces = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    assert not topo.is_edge_manifold(faces)
    assert not topo.is_consistently_oriented(faces)
    assert not topo.is_vertex_manifold(faces)
    assert topo.nonmanifold_vertices(faces).tolist() == [True, True, False, False, False]


def test_vertex_shared_by_two_closed_surfaces():
    pts, faces = _two_tets_sharing_a_vertex()
    assert topo.is_watertight(faces) and topo.is_edge_manifold(faces)
    assert not topo.is_vertex_manifold(faces, len(pts))
    mask = topo.nonmanifold_vertices(faces, 9)
    assert mask.shape == (9,) and np.flatnonzero(mask).tolist() == [0]
    assert topo.connected_components(faces)[0] == 2
    assert topo.connected_components(faces, len(pts), connectivity="vertex")[0] == 1
    assert topo.euler_characteristic(None, faces) == 3  # 2 + 2 - 1 shared vertex


def test_components_labels_follow_first_appearance():
    faces = np.array([[10, 11, 12], [0, 1, 2], [11, 12, 13], [2, 1, 3]])
    count, labels = topo.connected_components(faces)
    assert count == 2
    assert labels.tolist() == [0, 1, 0, 1]


# ------------------------------------------------------------------------- geometry
def test_measures_match_trimesh():
    tm = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    pts, faces = _pf(tm)
    np.testing.assert_allclose(topo.face_areas(pts, faces), tm.area_faces, rtol=1e-12)
    np.testing.assert_allclose(topo.face_normals(pts, faces), tm.face_normals, atol=1e-12)
    assert topo.signed_volume(pts, faces) == pytest.approx(tm.volume, rel=1e-12)
    assert topo.signed_volume(pts, faces[:, ::-1]) == pytest.approx(-tm.volume, rel=1e-12)


def test_signed_volume_of_box_is_exact_far_from_origin():
    pts, faces = _pf(trimesh.creation.box(extents=(1, 2, 3)))
    assert topo.signed_volume(pts, faces) == pytest.approx(6.0, rel=1e-14)
    assert topo.signed_volume(pts + 1e7, faces) == pytest.approx(6.0, rel=1e-9)


def test_face_areas_2d_and_normals_of_degenerate():
    assert topo.face_areas([[0, 0], [2, 0], [0, 3]], [[0, 1, 2]]).tolist() == [3.0]
    normals = topo.face_normals([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    assert normals.tolist() == [[0.0, 0.0, 0.0]]


def test_degenerate_faces_are_scale_invariant():
    pts = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [0.5, 1e-15, 0]])
    faces = np.array([[0, 1, 3], [0, 1, 2], [0, 0, 3], [0, 1, 4]])
    expect = [False, True, True, True]
    assert topo.degenerate_faces(pts, faces).tolist() == expect
    assert topo.degenerate_faces(pts * 1e-6, faces).tolist() == expect
    assert topo.degenerate_faces(pts * 1e6, faces).tolist() == expect


def test_duplicate_faces_either_winding():
    faces = np.array([[0, 1, 2], [1, 2, 3], [2, 1, 0], [1, 2, 0], [3, 1, 2]])
    assert topo.duplicate_faces(faces).tolist() == [False, False, True, True, True]
    assert topo.duplicate_faces(np.zeros((0, 3), int)).tolist() == []


# ------------------------------------------------------------------------- bad input
def test_float_faces_rejected():
    with pytest.raises(TypeError, match="integer array for 'faces'"):
        topo.unique_edges(np.array([[0.0, 1.0, 2.0]]))


def test_wrong_face_shape_rejected():
    with pytest.raises(ValueError, match=r"shape \(m, 3\), got shape \(2, 4\)"):
        topo.is_watertight(np.zeros((2, 4), int))


def test_negative_index_rejected():
    with pytest.raises(ValueError, match="non-negative"):
        topo.is_watertight([[0, -1, 2]])


def test_unknown_connectivity_rejected():
    with pytest.raises(ValueError, match="connectivity 'edge' or 'vertex'"):
        topo.connected_components([[0, 1, 2]], connectivity="face")


def test_normals_need_3d_points():
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        topo.face_normals([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])


# ------------------------------------------------------------------------- check_mesh
def test_check_mesh_accepts_good_meshes(check_mesh, sphere, torus):
    assert check_mesh(*sphere)["n_boundary_edges"] == 0
    check_mesh(*torus)
    check_mesh(trimesh.creation.box())
    pts, faces = sphere
    assert check_mesh(pts, faces[1:], closed=False)["n_boundary_edges"] == 3


@pytest.mark.parametrize(
    ("defect", "message"),
    [
        ("nan", "non-finite points"),
        ("out_of_range", "index outside"),
        ("float_faces", "expected integers"),
        ("repeated_vertex", "degenerate faces"),
        ("zero_area", "degenerate faces"),
        ("duplicate", "duplicated faces"),
        ("open", "boundary edges"),
        ("flipped", "inconsistent orientation"),
        ("nonmanifold_edge", "more than two faces"),
        ("nonmanifold_vertex", "non-manifold vertices"),
    ],
)
def test_check_mesh_names_each_defect(check_mesh, sphere, defect, message):
    pts, faces = sphere[0].copy(), sphere[1].copy()
    if defect == "nan":
        pts[3, 1] = np.nan
    elif defect == "out_of_range":
        faces[5, 2] = len(pts)
    elif defect == "float_faces":
        faces = faces.astype(float)
    elif defect == "repeated_vertex":
        faces[5, 2] = faces[5, 1]
    elif defect == "zero_area":
        pts = np.vstack(
            [pts, pts[faces[0, 0]]]
        )  # a copy of a vertex: triangle (v, copy, w) is flat
        faces = np.vstack([faces, [faces[0, 0], len(pts) - 1, faces[0, 1]]])
    elif defect == "duplicate":
        faces = np.vstack([faces, faces[4, ::-1]])
    elif defect == "open":
        faces = faces[1:]
    elif defect == "flipped":
        faces[7] = faces[7, ::-1]
    elif defect == "nonmanifold_edge":
        pts = np.vstack([pts, [[5.0, 5.0, 5.0]]])
        faces = np.vstack([faces, [faces[0, 0], faces[0, 1], len(pts) - 1]])
    elif defect == "nonmanifold_vertex":
        pts, faces = _two_tets_sharing_a_vertex()
    with pytest.raises(AssertionError, match=message):
        check_mesh(pts, faces)


@pytest.mark.parametrize("seed", range(4))
def test_components_by_kernels_equal_the_graph_search(monkeypatch, seed):
    # random soups (non-manifold edges, isolated faces, faces in any order) and two shells
    # joined at a vertex: the same count and the same labels, numbered by first appearance
    from warpmesh.cells import topology

    rng = np.random.default_rng(seed)
    soups = [rng.integers(0, 40 + 30 * seed, (60 + 50 * seed, 3))]
    tet = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    soups.append(np.vstack([tet, tet + 3, tet + 10])[rng.permutation(12)])  # 0-3 and 3-6 share vertex 3
    for faces in soups:
        faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
        assert topology._kernels_apply(faces, int(faces.max()) + 1)
        fast = topology.connected_components(faces)
        with monkeypatch.context() as patch:
            patch.setattr(topology, "_kernels_apply", lambda *args: False)
            slow = topology.connected_components(faces)
        assert fast[0] == slow[0]
        np.testing.assert_array_equal(fast[1], slow[1])
        assert fast[1].dtype == slow[1].dtype
    assert fast[0] == 3
