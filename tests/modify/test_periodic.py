"""Periodic meshes [FG §17.5]: node pairs under a transformation, and meshes made of a
pattern and its transformed copies (translation, rotation closing up, reflection)."""

from __future__ import annotations

import numpy as np
import pytest
from tests.helpers.cellcheck import check_cells
from tests.helpers.blocks import hex_block, kuhn_block, tri_square

from warpmesh.mesh import Mesh
from warpmesh.errors import MergeError
from warpmesh.modify.periodic import periodic, periodic_pairs
from warpmesh.cells.reference import cell_measures


def translation(*v):
    m = np.eye(len(v) + 1)
    m[: len(v), -1] = v
    return m


def rotation_z(angle, d=2):
    m = np.eye(d + 1)
    c, s = np.cos(angle), np.sin(angle)
    m[:2, :2] = [[c, -s], [s, c]]
    return m


def sector(n):
    """The equilateral triangle (0,0), (1,0), (cos 60°, sin 60°), n^2 lattice triangles:
    one sixth of a hexagon."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij"))
    keep = i + j <= n
    i, j = i[keep], j[keep]
    num = np.full((n + 2, n + 2), -1)
    num[i, j] = np.arange(len(i))
    p1, p2 = np.array([1.0, 0.0]), np.array([0.5, np.sqrt(3) / 2])
    pts = (i[:, None] * p1 + j[:, None] * p2) / n
    up = (i + j) < n
    tri_up = np.stack([num[i, j], num[i + 1, j], num[i, j + 1]], axis=1)[up]
    down = (i + j) < n - 1
    tri_dn = np.stack([num[i + 1, j], num[i + 1, j + 1], num[i, j + 1]], axis=1)[down]
    return Mesh(pts, {"triangle": np.concatenate([tri_up, tri_dn])})


def test_strip_translated_four_times():
    n = 9
    pattern = tri_square(n, seed=3)  # sides x = 0 and x = 1 have the same n nodes
    pattern = pattern.replace(point_data={"u": pattern.points[:, 1].copy()},
                              cell_refs={"triangle": np.full(len(pattern.cells["triangle"]), 5)})
    t = translation(1.0, 0.0)
    pairs = periodic_pairs(pattern, t)
    assert len(pairs) == n
    np.testing.assert_allclose(pattern.points[pairs[:, 0]] + [1, 0], pattern.points[pairs[:, 1]], atol=1e-12)
    assert np.allclose(pattern.points[pairs[:, 0], 0], 0.0)
    m = periodic(pattern, t, 4, check="full")
    assert m.n_points == 4 * pattern.n_points - 3 * n
    assert len(m.cells["triangle"]) == 4 * len(pattern.cells["triangle"])
    got = check_cells(m)
    assert got["measure"] == pytest.approx(4.0) and got["boundary_measure"] == pytest.approx(10.0)
    pp = m.info["periodic_pairs"]
    assert pp.shape == (n, 2) and m.info["copies"] == 4
    np.testing.assert_allclose(m.points[pp[:, 0]] + [4, 0], m.points[pp[:, 1]], atol=1e-12)
    assert (pp[:, 0] < pattern.n_points).all()  # the first pattern's free side
    np.testing.assert_array_equal(m.point_data["u"], m.points[:, 1])
    np.testing.assert_array_equal(m.cell_refs["triangle"], 5)
    assert m.info["euler"] == 1


def test_sector_rotated_six_times_closes_up():
    n = 6
    pattern = sector(n)
    m = periodic(pattern, rotation_z(np.pi / 3), 6, check="full")
    assert m.n_points == 1 + 3 * n * (n + 1)  # the hexagonal lattice with n rings
    assert len(m.cells["triangle"]) == 6 * n * n
    got = check_cells(m)  # conforming, positively oriented, closed boundary
    assert got["measure"] == pytest.approx(3 * np.sqrt(3) / 2)  # regular hexagon of side 1
    assert got["boundary_measure"] == pytest.approx(6.0)
    assert len(m.info["periodic_pairs"]) == 0 and m.info["euler"] == 1
    # the pattern's own periodic pairs: side θ = 0 onto side θ = 60°, the centre excluded
    pairs = periodic_pairs(pattern, rotation_z(np.pi / 3))
    assert len(pairs) == n


def test_tetra_column_translated_and_periodic_pairs_3d():
    pattern = kuhn_block(3)
    m = periodic(pattern, translation(0.0, 0.0, 1.0), 3, check="full")
    side = 4 * 4
    assert m.n_points == 3 * pattern.n_points - 2 * side
    assert check_cells(m)["measure"] == pytest.approx(3.0)
    assert len(m.info["periodic_pairs"]) == side
    assert m.info["euler"] == 1


def _with_boundary_quads(mesh):
    h = mesh.cells["hexahedron"]
    faces = h[:, [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]].reshape(-1, 4)
    _, inv, cnt = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    return mesh.replace(cells={"hexahedron": h, "quad": faces[cnt[inv.ravel()] == 1]})


def _quad_normals_outward(mesh):
    q = mesh.points[mesh.cells["quad"]]
    n = np.cross(q[:, 2] - q[:, 0], q[:, 3] - q[:, 1])
    centre = mesh.points.mean(axis=0)
    return np.einsum("ij,ij->i", n, q.mean(axis=1) - centre) > 0


def test_reflection_keeps_orientation():
    pattern = _with_boundary_quads(hex_block(3))
    assert _quad_normals_outward(pattern).all()
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    mirror[0, 3] = 2.0  # x -> 2 - x
    m = periodic(pattern, mirror, 2, duplicates="drop")  # the inner face is no boundary
    assert (cell_measures(m.points, m.cells["hexahedron"], "hexahedron") > 0).all()
    assert check_cells(m)["measure"] == pytest.approx(2.0)
    assert len(m.cells["quad"]) == 2 * len(pattern.cells["quad"]) - 2 * 9
    assert _quad_normals_outward(m).all()  # the box [0, 2] x [0, 1]^2 is convex
    assert m.n_points == 2 * pattern.n_points - 16


def test_sides_meshed_differently_fail_the_euler_check():
    # a Kuhn cube rotated by 90° about x before the translation: the shared faces are split
    # along different diagonals [FG Remark 17.16]
    cube = kuhn_block(1)
    rot = np.eye(4)
    rot[1:3, 1:3] = [[0, -1], [1, 0]]
    t = translation(1.0, 0.0, 0.0) @ translation(0.5, 0.5, 0.5) @ rot @ translation(-0.5, -0.5, -0.5)
    with pytest.raises(MergeError):
        periodic(cube, t, 2)


def test_bad_inputs():
    sq = tri_square(4)
    with pytest.raises(ValueError, match="shape"):
        periodic_pairs(sq, np.eye(4))
    with pytest.raises(TypeError, match="matrix"):
        periodic_pairs(sq, np.array([["a"] * 3] * 3))
    with pytest.raises(ValueError, match="affine"):
        periodic_pairs(sq, np.ones((3, 3)))
    with pytest.raises(ValueError, match="invertible"):
        periodic_pairs(sq, np.diag([1.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="finite"):
        periodic_pairs(sq, np.diag([1.0, np.nan, 1.0]))
    with pytest.raises(TypeError, match="Mesh"):
        periodic_pairs(sq.points, np.eye(3))
    with pytest.raises(ValueError, match="copies"):
        periodic(sq, translation(1.0, 0.0), 0)
    with pytest.raises(TypeError, match="copies"):
        periodic(sq, translation(1.0, 0.0), 2.5)
    with pytest.raises(TypeError, match="unexpected keyword argument .shuffle."):
        periodic(sq, translation(1.0, 0.0), 2, shuffle=True)
    with pytest.raises(ValueError, match="tolerance"):
        periodic(sq, translation(1.0, 0.0), 2, tolerance=-1.0)


def test_annular_sector_with_a_chord_closes_up():
    """Delaunay triangles of an annular sector fill its concave inner side, so one boundary
    edge (a chord) joins the two radial sides. When the last copy closes the ring both ends
    of that chord are common vertices, yet the chord is not on the interface: the Euler
    check must count only facets that lie on the other mesh (found while writing the
    notebook: a check on "all vertices common" alone refused this valid merge)."""
    from scipy.spatial import Delaunay

    a, r = np.meshgrid(np.linspace(0, np.pi / 3, 7), np.linspace(0.4, 1.0, 5))
    pts = np.c_[(r * np.cos(a)).ravel(), (r * np.sin(a)).ravel()]
    pattern = Mesh(pts, {"triangle": Delaunay(pts).simplices})
    ring = periodic(pattern, rotation_z(np.pi / 3), 6, check="full")
    assert ring.info["euler_ok"] and ring.info["euler"] == 0  # an annulus
    assert ring.n_points == 6 * len(pts) - 6 * 5
    assert len(ring.info["periodic_pairs"]) == 0
    got = check_cells(ring)
    assert got["measure"] == pytest.approx(6 * cell_measures(pts, pattern.cells["triangle"], "triangle").sum())


@pytest.mark.parametrize("copies", [2, 5, 6, 7])
def test_copies_merged_in_halves_equal_copies_merged_one_by_one(copies):
    """The halves-merged result (copies x log(copies) work) is the one of merging each copy
    into everything before it: same points in the same order, same cells, same pairs."""
    from warpmesh.modify.merge import merge
    from warpmesh.modify.periodic import _transformed

    for pattern, t in ((tri_square(5, seed=1), translation(1.0, 0.0)), (sector(4), rotation_z(np.pi / 3))):
        if copies > 6 and pattern.n_points == sector(4).n_points:
            continue  # a seventh sixth would lie on the first
        got = periodic(pattern, t, copies, check="full")
        want, power = pattern, np.eye(3)
        for _ in range(copies - 1):
            power = t @ power
            want = merge(want, _transformed(pattern, power), got.info["merge_tolerance"], check="full")
        np.testing.assert_array_equal(got.points, want.points)
        np.testing.assert_array_equal(got.cells["triangle"], want.cells["triangle"])
        assert got.info["euler"] == want.info["euler"]


def test_overlapping_copies_are_warned_about_and_the_identity_refused():
    """(Six copies of a ball rotated by 60 degrees, or a square moved by half its side,
    passed the Euler check and came back without a word.)"""
    import warnings

    from warpmesh.modify import transforms as T

    square = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
    with pytest.warns(UserWarning, match=r"periodic: the copies overlap \([0-9]+ pairs of cells cross"):
        periodic(square, T.translation((0.5, 0.0)), 2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        row = periodic(square, T.translation((1.0, 0.0)), 3)  # side by side: no warning
        periodic(square, T.translation((0.5, 0.0)), 2, check=False)  # no checks asked for
    assert len(row.cells["triangle"]) == 6 and not len(row.check())
    tets = kuhn_block(2)  # [0, 1]^3
    with pytest.warns(UserWarning, match="the copies overlap"):
        periodic(tets, T.translation((0.3, 0.0, 0.0)), 2)  # (at 0.5 the shared points fail the merge)
    with pytest.raises(ValueError, match="got the identity"):
        periodic(square, np.eye(3), 3)


def test_copies_whose_seams_do_not_match_are_told_so():
    """A pattern whose two sides are sampled differently (the planar mesher's left and right
    sides of a rectangle) touches its copies along the seam without sharing vertices there:
    the warning said the transform moved it by less than its extent, which it did not."""
    import warpmesh as wm
    from warpmesh.modify import transforms as T

    pattern = wm.mesh_domain(wm.rectangle((2.0, 1.0)), bounds=((-1.5, -1), (1.5, 1)), size=0.1)
    left, right = (np.sort(pattern.points[np.isclose(pattern.points[:, 0], x), 1]) for x in (-1.0, 1.0))
    assert not np.array_equal(left, right)  # the premise: the sides differ
    with pytest.warns(UserWarning, match=r"touch along their seams without sharing vertices there .* "
                                         r"\(2 node pairs match under the transform\)") as record:
        row = periodic(pattern, T.translation((2.0, 0.0)), 3)
    assert not any("less than its extent" in str(w.message) for w in record)
    assert row.stats()["components"] == 3
    # the same sides, made to match (the right side's nodes copied from the left): no warning
    square = Mesh([[0, 0], [1, 0], [1, 0.4], [1, 1], [0, 1], [0, 0.4]],
                  {"triangle": [[0, 1, 2], [0, 2, 5], [5, 2, 3], [5, 3, 4]]})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        joined = periodic(square, T.translation((1.0, 0.0)), 3)
    assert joined.stats()["components"] == 1
    skewed = Mesh([[0, 0], [1, 0], [1, 0.6], [1, 1], [0, 1], [0, 0.4]],
                  {"triangle": [[0, 1, 2], [0, 2, 5], [5, 2, 3], [5, 3, 4]]})
    with pytest.warns(UserWarning, match="touch along their seams"):
        periodic(skewed, T.translation((1.0, 0.0)), 2)
    # an overlap of 5e-7 of the side (deeper than the merge tolerance, 2.4e-7 of the box) is one
    with pytest.warns(UserWarning, match="the copies overlap") as record:
        periodic(square, T.translation((0.9999995, 0.0)), 2)
    assert not any("seams" in str(w.message) for w in record)
