"""warpmesh.surface.orientation: consistent orientation by adjacency [FG §16.4.4], on known shapes."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from tests.helpers.meshcheck import check_mesh

import warpmesh as wm
from warpmesh.cells import topology as topo
from warpmesh.errors import TopologyError
from warpmesh.surface.orientation import orient, orient_faces


# ----------------------------------------------------------------------------- shapes
def _pf(tm, shift=(0.0, 0.0, 0.0)):
    return np.asarray(tm.vertices) + shift, np.asarray(tm.faces)


def _sphere(radius=1.0, subdivisions=3, shift=(0.0, 0.0, 0.0)):
    return _pf(trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius), shift)


def _torus():
    return _pf(trimesh.creation.torus(1.0, 0.3, major_sections=32, minor_sections=16))


def _merge(*parts):
    """Concatenate (points, faces) pairs into one mesh, renumbering the faces."""
    offsets = np.cumsum([0] + [len(p) for p, _ in parts[:-1]])
    points = np.vstack([p for p, _ in parts])
    faces = np.vstack([f + o for (_, f), o in zip(parts, offsets)])
    return points, faces


def _grid(n=12):
    """An open n x n square patch in the plane z = 0.1 x y, two triangles per square."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    pts = np.stack([i.ravel(), j.ravel(), 0.1 * (i * j).ravel()], axis=1) / n
    v = (i[:-1, :-1] * (n + 1) + j[:-1, :-1]).ravel()
    faces = np.concatenate(
        [np.stack([v, v + n + 1, v + n + 2], 1), np.stack([v, v + n + 2, v + 1], 1)]
    )
    return pts.astype(float), faces


def _hemisphere():
    pts, faces = _sphere(subdivisions=3)
    return pts, faces[pts[faces].mean(axis=1)[:, 2] > 0.1]


def _moebius(n=24, width=0.3):
    """A Möbius strip: a band of n quads (two triangles each) with a half twist."""
    t = 2 * np.pi * np.arange(n) / n
    centre = np.stack([np.cos(t), np.sin(t), 0 * t], axis=1)
    across = np.stack([np.cos(t / 2) * np.cos(t), np.cos(t / 2) * np.sin(t), np.sin(t / 2)], 1)
    pts = np.vstack([centre - width * across, centre + width * across])  # a_i = i, b_i = n + i
    a, b = np.arange(n), n + np.arange(n)
    a1, b1 = np.roll(a, -1), np.roll(b, -1)
    a1[-1], b1[-1] = b[0], a[0]  # the half twist swaps the sides when closing the band
    faces = np.concatenate([np.stack([a, b, b1], 1), np.stack([a, b1, a1], 1)])
    return pts, faces


def _flip(faces, mask):
    out = faces.copy()
    out[mask] = out[mask][:, [0, 2, 1]]
    return out


def _volumes(points, faces):
    """Signed volume of each edge-connected component, in order of first appearance."""
    n, labels = topo.connected_components(faces)
    return [topo.signed_volume(points, faces[labels == c]) for c in range(n)]


# ----------------------------------------------------------------------------- closed surfaces
@pytest.mark.parametrize("shape", [_sphere, _torus])
@pytest.mark.parametrize("fraction", [0.0, 0.3, 0.5, 0.9, 1.0])
def test_random_flips_of_a_closed_surface_are_undone_exactly(shape, fraction):
    points, faces = shape()
    mask = np.random.default_rng(7).random(len(faces)) < fraction
    fixed, report = orient_faces(points, _flip(faces, mask))
    np.testing.assert_array_equal(fixed, faces)
    assert report == {
        "components": 1, "closed": 1, "open": 0, "inward": 0, "flipped": int(mask.sum()),
        "non_orientable": 0, "outward": True,
    }
    check_mesh(points, fixed)


def test_reversed_rows_are_reoriented_up_to_rotation():
    points, faces = _torus()
    mask = np.random.default_rng(1).random(len(faces)) < 0.4
    scrambled = faces.copy()
    scrambled[mask] = scrambled[mask][:, ::-1]  # (a, b, c) -> (c, b, a)
    fixed, _ = orient_faces(points, scrambled)
    np.testing.assert_array_equal(fixed[~mask], faces[~mask])
    for f in (fixed, faces):  # same cyclic order: compare rows rotated to their smallest vertex
        f[:] = np.take_along_axis(f, (np.argmin(f, 1)[:, None] + np.arange(3)) % 3, axis=1)
    np.testing.assert_array_equal(fixed, faces)


def test_two_disjoint_closed_components_both_outward():
    sphere = _sphere(subdivisions=2)
    torus = _torus()
    points, faces = _merge(sphere, (torus[0] + [4.0, 0, 0], torus[1]))
    scrambled = _flip(faces, np.arange(len(faces)) < len(sphere[1]) + 100)  # sphere inverted
    fixed, report = orient_faces(points, scrambled)
    np.testing.assert_array_equal(fixed, faces)
    assert (report["components"], report["closed"], report["inward"]) == (2, 2, 0)
    assert all(v > 0 for v in _volumes(points, fixed))


def test_nested_shells_outer_outward_inner_inward():
    """A solid ball inside the cavity of a hollow sphere: +, -, + by nesting depth."""
    parts = [_sphere(r, subdivisions=3) for r in (3.0, 2.0, 1.0)]
    points, faces = _merge(*parts)
    mask = np.random.default_rng(3).random(len(faces)) < 0.5
    fixed, report = orient_faces(points, _flip(faces, mask))
    vol = _volumes(points, fixed)
    assert vol[0] > 0 and vol[1] < 0 and vol[2] > 0
    np.testing.assert_allclose(
        np.abs(vol), [topo.signed_volume(*p) for p in parts], rtol=1e-12
    )
    assert (report["closed"], report["inward"]) == (3, 1)
    check_mesh(points, fixed)


def test_nested_axis_aligned_boxes_rays_through_edges():
    """Concentric boxes: rays from face centroids pass through the outer boxes' diagonals."""
    boxes = [_pf(trimesh.creation.box(extents=[e] * 3)) for e in (6.0, 4.0, 2.0)]
    points, faces = _merge(*boxes)
    fixed, report = orient_faces(points, _flip(faces, np.ones(len(faces), bool)))
    middle = (np.arange(len(faces)) >= 12) & (np.arange(len(faces)) < 24)
    np.testing.assert_array_equal(fixed, _flip(faces, middle))
    vol = _volumes(points, fixed)
    np.testing.assert_allclose(vol, [216.0, -64.0, 8.0])
    assert report["inward"] == 1


def test_rays_through_a_vertex_and_along_a_shared_edge():
    """Each ray from a component's first-face centroid along +x meets the next container
    exactly at a vertex (the octahedron's tip) or on a diagonal edge (the box's face)."""
    box = _pf(trimesh.creation.box(extents=[4.0] * 3))
    octa = (
        np.array([[1.5, 0, 0], [0, 1.5, 0], [0, 0, 1.5], [-1.5, 0, 0], [0, -1.5, 0], [0, 0, -1.5]]),
        np.array([[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2],
                  [1, 0, 5], [3, 1, 5], [4, 3, 5], [0, 4, 5]]),
    )
    tet = (  # first face centred on the x axis, in the plane x = 0
        np.array([[0, -0.1, -0.1], [0, 0.2, -0.1], [0, -0.1, 0.2], [-0.3, 0, 0]]),
        np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [0, 2, 3]]),
    )
    points, faces = _merge(box, octa, tet)
    for mask in (np.zeros(len(faces), bool), np.ones(len(faces), bool)):
        fixed, report = orient_faces(points, _flip(faces, mask))
        assert np.sign(_volumes(points, fixed)).tolist() == [1, -1, 1]
        assert report["inward"] == 1


def test_several_bodies_in_one_cavity_and_one_outside():
    cavity = _sphere(4.0, subdivisions=3)
    shell = _sphere(5.0, subdivisions=3)
    balls = [_sphere(0.8, subdivisions=1, shift=s) for s in ([2, 0, 0], [-2, 0.5, 0], [0, 2, 1])]
    outside = _sphere(1.0, subdivisions=1, shift=[8, 0, 0])
    points, faces = _merge(shell, cavity, *balls, outside)
    fixed, report = orient_faces(points, faces[:, [0, 2, 1]])
    assert np.sign(_volumes(points, fixed)).tolist() == [1, -1, 1, 1, 1, 1]
    counts = (report["components"], report["inward"], report["flipped"])
    assert counts == (6, 1, len(faces) - len(cavity[1]))


def test_many_small_closed_components():
    rng = np.random.default_rng(5)
    centres = np.stack(np.meshgrid(*[np.arange(6) * 3.0] * 3, indexing="ij"), -1).reshape(-1, 3)
    parts = [_sphere(1.0, subdivisions=1, shift=c) for c in centres]
    points, faces = _merge(*parts)
    inverted = np.repeat(rng.random(len(parts)) < 0.5, len(parts[0][1]))
    fixed, report = orient_faces(points, _flip(faces, inverted))
    np.testing.assert_array_equal(fixed, faces)
    assert (report["components"], report["closed"], report["inward"]) == (216, 216, 0)


def test_outward_false_keeps_the_majority():
    points, faces = _sphere()
    rng = np.random.default_rng(2)
    few = rng.random(len(faces)) < 0.3
    fixed, report = orient_faces(points, _flip(faces, few), outward=False)
    np.testing.assert_array_equal(fixed, faces)
    most = ~few
    fixed, report = orient_faces(points, _flip(faces, most), outward=False)
    np.testing.assert_array_equal(fixed, faces[:, [0, 2, 1]])  # all inward: the majority's choice
    assert report["flipped"] == few.sum() and report["outward"] is False


def test_hollow_sphere_from_the_mesher_is_restored():
    """mesh_surface follows the same convention: scrambling and orienting gives it back."""
    shape = wm.difference(wm.sphere(1.0), wm.sphere(0.5))
    mesh = wm.mesh_surface(shape, bounds=((-1.2,) * 3, (1.2,) * 3), resolution=24)
    mask = np.random.default_rng(4).random(len(mesh.triangles)) < 0.5
    out = orient(mesh.replace(cells={"triangle": _flip(mesh.triangles, mask)}))
    np.testing.assert_array_equal(out.triangles, mesh.triangles)
    assert out.info["orient"]["inward"] == 1


# ----------------------------------------------------------------------------- open surfaces
@pytest.mark.parametrize("shape", [_grid, _hemisphere])
def test_open_surface_oriented_with_the_majority(shape):
    points, faces = shape()
    mask = np.random.default_rng(8).random(len(faces)) < 0.35
    fixed, report = orient_faces(points, _flip(faces, mask))
    np.testing.assert_array_equal(fixed, faces)
    assert (report["open"], report["closed"], report["flipped"]) == (1, 0, mask.sum())
    check_mesh(points, fixed, closed=False)
    fixed, _ = orient_faces(points, _flip(faces, ~mask))  # now most faces are the other way
    np.testing.assert_array_equal(fixed, faces[:, [0, 2, 1]])


def test_tie_keeps_the_first_face():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    fixed, report = orient_faces(points, [[0, 1, 2], [1, 2, 3]])
    assert fixed.tolist() == [[0, 1, 2], [1, 3, 2]] and report["flipped"] == 1


def test_triangle_soup_is_left_alone():
    points, faces = _sphere(subdivisions=1)
    soup_pts = points[faces].reshape(-1, 3)
    soup = np.arange(len(soup_pts)).reshape(-1, 3)[:, ::-1].copy()
    fixed, report = orient_faces(soup_pts, soup)
    np.testing.assert_array_equal(fixed, soup)
    assert (report["components"], report["open"], report["flipped"]) == (len(faces),) * 2 + (0,)


def test_planar_mesh_gets_positive_areas():
    points, faces = _grid(8)
    points = points[:, :2]
    mask = np.random.default_rng(9).random(len(faces)) < 0.7
    fixed, report = orient_faces(points, _flip(faces, mask))
    np.testing.assert_array_equal(fixed, faces)
    d1, d2 = points[fixed[:, 1]] - points[fixed[:, 0]], points[fixed[:, 2]] - points[fixed[:, 0]]
    assert np.all(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0] > 0)


# ----------------------------------------------------------------------------- Mesh in, Mesh out
def test_mesh_keeps_rows_refs_data_and_other_blocks():
    points, faces = _sphere(subdivisions=2)
    mask = np.random.default_rng(6).random(len(faces)) < 0.5
    tris = _flip(faces, mask)
    refs = np.arange(len(faces)) % 5
    mesh = wm.Mesh(
        points,
        {"triangle": tris, "line": [[0, 1], [1, 2]]},
        cell_refs={"triangle": refs},
        cell_data={"q": {"triangle": np.arange(len(faces)) * 0.5, "line": [1.0, 2.0]}},
        info={"source": "test"},
    )
    out = orient(mesh)
    np.testing.assert_array_equal(out.triangles, faces)
    np.testing.assert_array_equal(mesh.triangles, tris)  # input untouched
    np.testing.assert_array_equal(out.cell_refs["triangle"], refs)
    np.testing.assert_array_equal(out.cell_data["q"]["triangle"], mesh.cell_data["q"]["triangle"])
    np.testing.assert_array_equal(out.cells["line"], mesh.cells["line"])
    assert out.info["source"] == "test" and "orientation" not in mesh.info
    assert out.info["orient"]["flipped"] == mask.sum()
    assert out.info["orientation"] == f"outward (closed components; cavity walls inward, open ones by majority): " \
        f"{mask.sum()} of {len(faces)} faces flipped"
    s = out.stats()
    assert s["oriented"] and s["volume"] > 0 and s["orient"]["closed"] == 1 and isinstance(s["orientation"], str)


# ----------------------------------------------------------------------------- topology errors
def test_moebius_strip_is_not_orientable():
    points, faces = _moebius()
    assert topo.is_edge_manifold(faces) and not topo.is_watertight(faces)
    msg = r"component 0 \(first face 0, 48 faces\) is not orientable"
    with pytest.raises(TopologyError, match=msg):
        orient_faces(points, faces)


def test_moebius_strip_next_to_a_sphere_names_its_component():
    points, faces = _merge(_sphere(subdivisions=1, shift=[5, 0, 0]), _moebius())
    with pytest.raises(TopologyError, match=r"component 1 \(first face 80, 48 faces\)"):
        orient_faces(points, faces)


def test_non_manifold_edge_raises():
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    faces = [[0, 1, 2], [1, 0, 3], [0, 1, 4]]
    with pytest.raises(TopologyError, match=r"edge \(0, 1\) is shared by 3 faces \[0, 1, 2\]"):
        orient_faces(points, faces)


# ----------------------------------------------------------------------------- bad input
def test_rejects_a_tuple_instead_of_a_mesh():
    with pytest.raises(TypeError, match="expected a warpmesh Mesh for 'mesh', got tuple"):
        orient(_sphere(subdivisions=0))


def test_rejects_a_mesh_without_triangles():
    tet = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], {"tetra": [[0, 1, 2, 3]]})
    msg = r"expected a 'triangle' block in 'mesh', got cell blocks \['tetra'\]"
    with pytest.raises(ValueError, match=msg):
        orient(tet)


def test_rejects_an_empty_triangle_block():
    with pytest.raises(ValueError, match="expected at least one triangle"):
        orient(wm.Mesh([[0, 0, 0]], {"triangle": np.zeros((0, 3), int)}))


def test_rejects_no_faces():
    with pytest.raises(ValueError, match="expected at least one face in 'faces'"):
        orient_faces([[0, 0, 0]], [])


def test_rejects_a_face_with_a_repeated_vertex():
    points, faces = _sphere(subdivisions=0)
    faces = faces.copy()
    faces[3, 2] = faces[3, 0]
    with pytest.raises(ValueError, match=r"got face 3 = \[\d+, \d+, \d+\] \(1 degenerate faces\)"):
        orient_faces(points, faces)


def test_rejects_float_faces():
    with pytest.raises(TypeError, match="expected an integer array for 'faces', got dtype float64"):
        orient_faces([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0.0, 1.0, 2.0]])


def test_rejects_out_of_range_indices():
    with pytest.raises(ValueError, match=r"expected indices in \[0, 3\) in 'faces', got face 0"):
        orient_faces([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]])


def test_rejects_bad_points():
    with pytest.raises(ValueError, match=r"expected 'points' of shape \(n, 2\) or \(n, 3\)"):
        orient_faces(np.zeros((3, 4)), [[0, 1, 2]])


def test_rejects_nan_points_of_nested_closed_components():
    points, faces = _merge(_sphere(2.0, subdivisions=1), _sphere(1.0, subdivisions=1))
    points[faces[-1, 0]] = np.nan
    with pytest.raises(ValueError, match=r"expected finite coordinates in 'points', got NaN or inf at a vertex of face"):
        orient_faces(points, faces)


def test_rejects_a_non_bool_outward():
    with pytest.raises(TypeError, match="expected a bool for 'outward', got str"):
        orient_faces([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], outward="yes")


# ----------------------------------------------------------------------------- scale
def test_million_faces():
    """1.3 M faces (icosphere, 8 subdivisions): vectorised, about a second."""
    points, faces = _sphere(subdivisions=8)
    mask = np.random.default_rng(0).random(len(faces)) < 0.5
    fixed, report = orient_faces(points, _flip(faces, mask))
    np.testing.assert_array_equal(fixed, faces)
    assert report["flipped"] == mask.sum() and len(faces) == 1_310_720


@pytest.mark.parametrize("dim,outward,rule", [
    (2, True, "counter-clockwise (each component's signed area positive)"),
    (3, True, "outward (closed components; cavity walls inward, open ones by majority)"),
    (2, False, "by majority in each component"),
    (3, False, "by majority in each component"),
])
def test_orientation_info_says_the_rule_in_words(dim, outward, rule):
    """``info["orientation"]`` is a sentence whatever made the mesh (the meshers write one too);
    the counts are in ``info["orient"]``."""
    points, faces = _grid(6)
    mask = np.random.default_rng(3).random(len(faces)) < 0.2
    out = orient(wm.Mesh(points[:, :dim], {"triangle": _flip(faces, mask)}), outward=outward)
    assert out.info["orientation"] == f"{rule}: {out.info['orient']['flipped']} of {len(faces)} faces flipped"
    assert out.info["orient"]["flipped"] == mask.sum()
