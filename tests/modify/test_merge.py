"""Merging two meshes [FG §17.2]: match_points' guarantees, the numbering, the common
entities and the Euler check, duplicates, refs (cracks), data carried."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from tests.helpers.cellcheck import check_cells
from scipy.spatial import cKDTree

from warpmesh.errors import MergeError
from warpmesh.modify.merge import match_points, merge
from warpmesh.modify.merge_hash import _grid
from warpmesh.mesh import Mesh
import warpmesh as wm
from warpmesh.cells.reference import cell_measures, reference_cell
from tests.helpers.blocks import hex_block, kuhn_block, positive, tri_square

RNG = np.random.default_rng(7)


# ----------------------------------------------------------------------------- meshes
def sphere_surface():
    return Mesh.from_trimesh(trimesh.creation.icosphere(3))


def split(mesh, side, *, shuffle=False, seed=0):
    """The sub-mesh of the cells whose centroid satisfies ``side`` (a function of (m, d)
    centroids, or a mask when the mesh has one block), its used points renumbered compactly
    (in a random order when ``shuffle``)."""
    cells = {}
    for t, c in mesh.cells.items():
        keep = side(mesh.points[c].mean(axis=1)) if callable(side) else side
        cells[t] = c[keep]
    used = np.unique(np.concatenate([c.ravel() for c in cells.values()]))
    if shuffle:
        used = np.random.default_rng(seed).permutation(used)
    new = np.full(mesh.n_points, -1)
    new[used] = np.arange(len(used))
    return Mesh(mesh.points[used], {t: new[c] for t, c in cells.items()})


def centroids(mesh):
    (c,) = mesh.cells.values()
    return mesh.points[c].mean(axis=1)


def chi(mesh) -> int:
    """V - E + F (- T) of the cells (all of one dimension), by np.unique(axis=0)
    (independent of merge.py)."""
    verts, edges, faces, tops, tdim = [], [], [], [], 0
    for t, c in mesh.cells.items():
        ref = reference_cell(t)
        tdim = ref.tdim
        verts.append(c.ravel())
        edges.append(np.sort(c[:, ref.edges].reshape(-1, 2), axis=1))
        faces += [np.sort(np.pad(c[:, list(f)], ((0, 0), (0, 4 - len(f))), constant_values=-1), axis=1)
                  for f in ref.faces]
        tops.append(np.sort(np.pad(c, ((0, 0), (0, 8 - c.shape[1])), constant_values=-1), axis=1))
    counts = [len(np.unique(np.concatenate(verts)))]
    if tdim >= 2:
        counts.append(len(np.unique(np.concatenate(edges), axis=0)))
    if tdim == 3:
        counts.append(len(np.unique(np.concatenate(faces), axis=0)))
    counts.append(len(np.unique(np.concatenate(tops), axis=0)))
    return sum((-1) ** k * n for k, n in enumerate(counts))


def same_cells(merged, original):
    """The merged mesh's cells, mapped to the original's points by coordinates, are the
    original's cells (as vertex sets), block by block."""
    dist, idx = cKDTree(original.points).query(merged.points)
    assert dist.max() < 1e-6
    assert set(merged.cells) == set(original.cells)
    for t, c in original.cells.items():
        mine = np.sort(idx[merged.cells[t]], axis=1)
        a = {tuple(r) for r in mine.tolist()}
        b = {tuple(r) for r in np.sort(c, axis=1).tolist()}
        assert len(mine) == len(c) and a == b


def hex_wedge_block(n=4):
    """hex_block with the columns of cubes of odd i + j split into two wedges each
    (conforming: the split is along the vertical diagonal plane, side faces stay quads,
    the triangles of the cubes above and below match)."""
    hb = hex_block(n)
    h = hb.cells["hexahedron"]
    c = (hb.points[h].mean(axis=1)[:, :2] * n - 0.5).round().astype(int).sum(axis=1) % 2 == 1
    w = np.concatenate([h[c][:, [0, 1, 2, 4, 5, 6]], h[c][:, [0, 2, 3, 4, 6, 7]]])
    return Mesh(hb.points, {"hexahedron": h[~c], "wedge": positive(hb.points, w, "wedge")})


CASES = {
    "triangle": (tri_square, lambda x: x[:, 0] + 0.3 * x[:, 1] < 0.6),
    "tetra": (kuhn_block, lambda x: x[:, 0] + 0.4 * x[:, 1] - 0.2 * x[:, 2] < 0.55),
    "hexahedron": (hex_block, lambda x: x[:, 0] < 0.5),
    "surface": (sphere_surface, lambda x: x[:, 2] + 0.3 * x[:, 0] < 0.1),
    "hex+wedge": (hex_wedge_block, lambda x: x[:, 0] + 0.5 * x[:, 1] < 0.6),
}


# ----------------------------------------------------------------------------- halves
@pytest.mark.parametrize("case", list(CASES))
def test_halves_give_back_the_mesh(case):
    make, side = CASES[case]
    whole = make()
    a, b = split(whole, side), split(whole, lambda x: ~side(x), shuffle=True)
    m = merge(a, b, check="full")
    assert m.n_points == whole.n_points and m.n_cells == whole.n_cells
    # the default check works on the cells around the interface: same verdict, same interface
    star = merge(a, b).info
    assert star["euler_ok"] and star["euler_check"] == "interface"
    assert star["euler_interface"] == m.info["euler_interface"]
    assert star["euler_star"] == star["euler_star_a"] + star["euler_star_b"] - star["euler_interface"]
    same_cells(m, whole)
    assert m.info["euler"] == chi(whole) == chi(m) == (2 if case == "surface" else 1)
    assert m.info["euler_ok"]
    assert m.info["euler_a"] == chi(a) and m.info["euler_b"] == chi(b)
    assert m.info["euler"] == m.info["euler_a"] + m.info["euler_b"] - m.info["euler_interface"]
    assert m.info["n_common_points"] == a.n_points + b.n_points - whole.n_points > 0
    # the book's numbering: a's points first, unchanged; b's interface points take a's numbers
    np.testing.assert_array_equal(m.points[: a.n_points], a.points)
    for t, c in a.cells.items():
        np.testing.assert_array_equal(m.cells[t][: len(c)], c)
    if case == "surface":
        assert m.stats()["watertight"] and m.stats()["euler"] == 2
        # the seam is a closed curve: χ = 0 for its edges, plus the triangles of the jagged
        # seam whose three vertices are all on it (each brings one edge and one face)
        assert m.info["n_common_edges"] > 0
        assert m.info["euler_interface"] == 0
    else:
        got = check_cells(m)
        assert got["measure"] == pytest.approx(check_cells(whole)["measure"])
    if case == "tetra":  # the interface is a surface: common faces, and χ(interface) = 1 (a disc)
        assert m.info["n_common_faces"] > 0 and m.info["euler_interface"] == 1


def test_quadratic_triangles_interface_nodes_merge():
    whole = tri_square(8).to_order(2)
    mask = centroids(Mesh(whole.points, {"triangle": whole.cells["triangle6"][:, :3]}))[:, 0] < 0.5
    c = whole.cells["triangle6"]
    used_a, used_b = np.unique(c[mask]), np.unique(c[~mask])
    na, nb = np.full(whole.n_points, -1), np.full(whole.n_points, -1)
    na[used_a], nb[used_b] = np.arange(len(used_a)), np.arange(len(used_b))
    a = Mesh(whole.points[used_a], {"triangle6": na[c[mask]]})
    b = Mesh(whole.points[used_b], {"triangle6": nb[c[~mask]]})
    m = merge(a, b, check="full")
    assert m.n_points == whole.n_points and m.info["euler_ok"] and m.info["euler"] == 1
    assert m.stats()["area"] == pytest.approx(1.0) if "triangle" in m.cells else True
    total = cell_measures(m.points, m.cells["triangle6"][:, :3], "triangle").sum()
    assert total == pytest.approx(1.0)


# ----------------------------------------------------------------------------- match_points
def _brute_pairs(a, b, tol):
    d = np.linalg.norm(a[:, None] - b[None], axis=2)
    d = np.where(d <= tol, d, np.inf)
    bi, bj = d.argmin(axis=1), d.argmin(axis=0)  # first minimum = smallest index on ties
    i = np.flatnonzero(np.isfinite(d.min(axis=1)))
    return {(int(x), int(bi[x])) for x in i if bj[bi[x]] == x}


@pytest.mark.parametrize("d", [1, 2, 3])
def test_match_points_equals_brute_force(d):
    eps = 0.01
    a = RNG.random((600, d))
    b = np.concatenate([a[:400] + RNG.normal(size=(400, d)) * eps, RNG.random((300, d))])
    b = np.concatenate([b, a[:50] + 0.3 * eps])  # second candidates for some points (Fig. 17.9)
    b = b[RNG.permutation(len(b))]
    pairs = match_points(a, b, eps)
    assert {tuple(p) for p in pairs.tolist()} == _brute_pairs(a, b, eps)
    assert len(np.unique(pairs[:, 0])) == len(pairs) == len(np.unique(pairs[:, 1]))
    assert np.all(np.linalg.norm(a[pairs[:, 0]] - b[pairs[:, 1]], axis=1) <= eps)


@pytest.mark.parametrize("d", [2, 3])
def test_jittered_pairs_straddling_cell_borders_all_found(d):
    eps = 1e-3  # a jittered lattice of spacing 20 eps: each point's partner is its only neighbour
    g = np.arange(0, 1, 20 * eps)[: int(5000 ** (1 / d))]
    a = np.stack([x.ravel() for x in np.meshgrid(*[g] * d, indexing="ij")], axis=1)
    a = a + RNG.uniform(0, 15 * eps, a.shape)
    b = a.copy()
    for x in (a, b):  # each side moved by less than eps / 2: partners closer than eps
        v = RNG.normal(size=x.shape)
        x += v / np.linalg.norm(v, axis=1)[:, None] * RNG.uniform(0, 0.499 * eps, (len(x), 1))
    perm = RNG.permutation(len(b))
    pairs = match_points(a, b[perm], eps)
    assert len(pairs) == len(a)
    np.testing.assert_array_equal(perm[pairs[:, 1]], pairs[:, 0])
    # the test is meaningful: many partners lie in different cells of the virtual grid
    _, _, origin, h, _ = _grid(a, b, eps)
    ca, cb = np.floor((a - origin) / h), np.floor((b - origin) / h)
    assert (ca != cb).any(axis=1).sum() > 0.05 * len(a)  # about 9% in 2D, 13% in 3D


def test_jittered_interface_of_two_halves_merges_completely():
    whole = tri_square(20)
    mask = centroids(whole)[:, 0] < 0.5
    a, b = split(whole, mask), split(whole, ~mask, shuffle=True)
    eps = 1e-4
    ja = RNG.uniform(-0.35, 0.35, a.points.shape) * eps  # |jitter| < eps / 2 on each side
    jb = RNG.uniform(-0.35, 0.35, b.points.shape) * eps
    m = merge(a.replace(points=a.points + ja), b.replace(points=b.points + jb), eps)
    assert m.n_points == whole.n_points and m.info["euler_ok"]
    check_cells(m)


def test_nothing_beyond_tolerance_is_merged():
    eps = 1e-3
    a = RNG.random((2000, 3))
    v = RNG.normal(size=a.shape)
    v /= np.linalg.norm(v, axis=1)[:, None]
    assert len(match_points(a, a + 1.01 * eps * v, eps)) == 0
    assert len(match_points(a, a + 0.99 * eps * v, eps)) == len(a)


def test_symmetric_pairing_fig_17_9():
    e = 1e-3
    a = np.array([[0.0, 0.0], [0.6 * e, 0.0], [5.0, 0.0]])
    b = np.array([[0.4 * e, 0.0], [5.0 + 0.2 * e, 0.0], [5.0 - 0.1 * e, 0.0]])
    # b0 is within e of a0 and a1: only its nearest, a1, pairs with it; a0 stays alone.
    # a2 has two candidates b1 and b2: the nearer b2 wins.
    assert match_points(a, b, e).tolist() == [[1, 0], [2, 2]]
    assert match_points(b, a, e).tolist() == [[0, 1], [2, 2]]


def test_remark_17_7_only_the_box_intersection_is_hashed():
    whole = hex_block(6)
    mask = centroids(whole)[:, 0] < 0.5
    m = merge(split(whole, mask), split(whole, ~mask))
    assert m.info["n_hashed_a"] == m.info["n_hashed_b"] == 7 * 7  # the plane x = 0.5 only


def test_refs_keep_coincident_vertices_of_different_refs_apart():
    whole = tri_square(11, jitter=0)
    mask = centroids(whole)[:, 0] < 0.5
    a, b = split(whole, mask), split(whole, ~mask)
    crack_a = (np.abs(a.points[:, 0] - 0.5) < 1e-9) & (a.points[:, 1] > 0.5)
    crack_b = (np.abs(b.points[:, 0] - 0.5) < 1e-9) & (b.points[:, 1] > 0.5)
    a = a.replace(point_refs=np.where(crack_a, 1, 0))
    b = b.replace(point_refs=np.where(crack_b, 2, 0))
    assert crack_a.sum() == crack_b.sum() == 5
    m = merge(a, b, refs=True, check="full")
    assert m.n_points == whole.n_points + crack_a.sum()
    assert merge(a, b).n_points == whole.n_points  # without refs: one mesh
    check_cells(m, embedded=False)  # the crack is a boundary curve run twice: still closed (not embedded)
    assert sorted(np.unique(m.point_refs).tolist()) == [0, 1, 2]
    assert m.info["euler"] == 1 and m.info["euler_ok"]


def _squares_with_lines():
    """Two triangulated unit squares side by side, each with its boundary as lines."""
    out = []
    for x0, ref in ((0.0, 1), (1.0, 2)):
        sq = tri_square(6, jitter=0, seed=int(x0))
        tri = sq.cells["triangle"]
        e = np.sort(tri[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2), axis=1)
        u, cnt = np.unique(e, axis=0, return_counts=True)
        lines = u[cnt == 1]
        pts = sq.points + [x0, 0]
        out.append(Mesh(pts, {"triangle": tri, "line": lines},
                        cell_refs={"triangle": np.full(len(tri), ref), "line": np.full(len(lines), 10 * ref)},
                        cell_data={"q": {"triangle": np.arange(len(tri)) * 1.0, "line": np.zeros(len(lines))}},
                        point_data={"u": np.full(len(pts), float(ref)), "only_" + str(ref): np.zeros(len(pts))}))
    return out


@pytest.mark.parametrize("mode, removed", [("merge", 1), ("keep", 0), ("drop", 2)])
def test_duplicates_modes_and_data_carried(mode, removed):
    a, b = _squares_with_lines()
    n_iface = 5  # the 6 x 6 grid has 5 segments on x = 1
    with pytest.warns(UserWarning, match="only_1.*only_2|only_2.*only_1"):
        m = merge(a, b, duplicates=mode)
    assert len(m.cells["line"]) == len(a.cells["line"]) + len(b.cells["line"]) - removed * n_iface
    assert m.info["n_duplicates"] == (0 if mode == "keep" else n_iface)
    assert len(m.cells["triangle"]) == len(a.cells["triangle"]) + len(b.cells["triangle"])
    np.testing.assert_array_equal(m.cell_refs["triangle"][: len(a.cells["triangle"])], 1)
    np.testing.assert_array_equal(m.cell_refs["triangle"][len(a.cells["triangle"]):], 2)
    assert len(m.cell_data["q"]["line"]) == len(m.cells["line"])
    iface = np.abs(m.points[:, 0] - 1.0) < 1e-12
    np.testing.assert_array_equal(m.point_data["u"][iface], 1.0)  # a's values on the interface
    assert set(m.point_data) == {"u"}
    check_cells(m)
    if mode == "drop":  # the interface no longer appears as a boundary line
        mid = m.points[m.cells["line"]].mean(axis=1)
        assert not (np.abs(mid[:, 0] - 1.0) < 1e-12).any()


def test_point_refs_from_one_mesh_only_and_missing_block_types():
    a, b = _squares_with_lines()
    a = a.replace(point_refs=np.full(a.n_points, 4), point_data={}, cell_data={})
    b = Mesh(b.points, {"triangle": b.cells["triangle"], "vertex": [[0]]})
    m = merge(a, b)
    assert list(m.cells) == ["triangle", "line", "vertex"]
    assert set(np.unique(m.point_refs[a.n_points:]).tolist()) == {0}
    np.testing.assert_array_equal(m.point_refs[: a.n_points], 4)
    np.testing.assert_array_equal(m.cell_refs["vertex"], [0])


# ----------------------------------------------------------------------------- Euler check
def test_euler_check_fails_on_a_hanging_node():
    a = Mesh([[0, 0], [1, 0], [1, 0.5], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 4], [2, 3, 4]]})
    b = Mesh([[1, 0], [2, 0], [2, 1], [1, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
    for check in ("interface", "full"):
        with pytest.raises(MergeError, match="meshed differently"):
            merge(a, b, check=check)
        with pytest.raises(MergeError, match="meshed differently"):
            merge(b, a, check=check)
    m = merge(a, b, check=False)  # merged as asked, unchecked
    assert m.n_points == 7 and "euler_ok" not in m.info


def test_euler_check_fails_on_other_face_diagonals_remark_17_16():
    cube = kuhn_block(1)
    # a copy rotated by 90 degrees about the x axis, then moved to x in [1, 2]: its face
    # x = 1 is split along the other diagonal
    p = cube.points - 0.5
    q = np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1) + 0.5 + [1, 0, 0]
    other = Mesh(q, cube.cells)
    for check in ("interface", "full"):
        with pytest.raises(MergeError, match="Remark 17.16"):
            merge(cube, other, check=check)
    same = Mesh(cube.points + [1, 0, 0], cube.cells)  # translated: same diagonal
    assert merge(cube, same, check="full").info["euler"] == 1


def test_a_large_tolerance_still_pairs_twins_only():
    # Remark 17.9: points near the interface have their twin (distance 0) as nearest, so
    # a tolerance several times the edge length merges the same pairs
    whole = tri_square(8, jitter=0.2)
    mask = centroids(whole)[:, 0] < 0.5
    a, b = split(whole, mask), split(whole, ~mask)
    small, large = merge(a, b), merge(a, b, 0.4)
    assert large.n_points == small.n_points == whole.n_points
    np.testing.assert_array_equal(large.cells["triangle"], small.cells["triangle"])


# ----------------------------------------------------------------------------- bad inputs
def test_bad_inputs():
    sq = tri_square(4)
    with pytest.raises(TypeError, match="'a'"):
        match_points(np.array([["x", "y"]]), [[0.0, 0.0]], 0.1)
    with pytest.raises(ValueError, match="shape"):
        match_points(np.zeros(3), [[0.0, 0.0]], 0.1)
    with pytest.raises(ValueError, match="same dimension"):
        match_points([[0.0, 0.0]], [[0.0, 0.0, 0.0]], 0.1)
    with pytest.raises(ValueError, match="finite"):
        match_points([[np.nan, 0.0]], [[0.0, 0.0]], 0.1)
    with pytest.raises(ValueError, match="tolerance"):
        match_points([[0.0, 0.0]], [[0.0, 0.0]], 0.0)
    with pytest.raises(ValueError, match="tolerance"):
        match_points([[0.0, 0.0]], [[0.0, 0.0]], float("nan"))
    with pytest.raises(TypeError, match="tolerance"):
        match_points([[0.0, 0.0]], [[0.0, 0.0]], "1e-3")
    with pytest.raises(ValueError, match="neither"):
        match_points([[0.0, 0.0]], [[0.0, 0.0]], 0.1, a_refs=[1])
    with pytest.raises(ValueError, match="b_refs"):
        match_points([[0.0, 0.0]], [[0.0, 0.0]], 0.1, a_refs=[1], b_refs=[1, 2])
    with pytest.raises(TypeError, match="a_refs"):
        match_points([[0.0, 0.0]], [[0.0, 0.0]], 0.1, a_refs=[0.5], b_refs=[1])
    with pytest.raises(TypeError, match="Mesh"):
        merge(sq.points, sq)
    with pytest.raises(ValueError, match="same dimension"):
        merge(sq, kuhn_block(1))
    with pytest.raises(ValueError, match="duplicates"):
        merge(sq, sq, duplicates="union")
    with pytest.raises(ValueError, match="tolerance"):
        merge(sq, sq, -1.0)
    with pytest.raises(TypeError, match="refs"):
        merge(sq, sq, refs="yes")
    with pytest.raises(ValueError, match="'check'"):
        merge(sq, sq, check="some")
    with pytest.raises(ValueError, match="same kind"):
        merge(sq, Mesh(sq.points, {"line": [[0, 1]]}))


def test_pairs_straddling_a_rounding_border_merge_unlike_trimesh():
    # trimesh.Trimesh.merge_vertices rounds coordinates to digits_vertex decimals (8 by
    # default, trimesh.tol.merge = 1e-8) and merges equal rounded rows: two points 4e-11
    # apart on either side of a rounding border (x * 1e8 = k + 1/2 -+ 0.002) stay apart.
    # match_points with a tolerance of 1e-8 pairs every one of them.
    n = 300
    a = RNG.random((n, 3))
    a[:, 0] = (np.floor(a[:, 0] * 1e8) + 0.502) * 1e-8
    b = a.copy()
    b[:, 0] -= 4e-11
    assert (np.round(a[:, 0] * 1e8) != np.round(b[:, 0] * 1e8)).all()  # every pair straddles
    pairs = match_points(a, b, 1e-8)
    np.testing.assert_array_equal(pairs, np.stack([np.arange(n), np.arange(n)], axis=1))
    tm = trimesh.Trimesh(vertices=np.concatenate([a, b]), faces=np.arange(2 * n).reshape(-1, 3), process=False)
    tm.merge_vertices()
    assert len(tm.vertices) == 2 * n  # trimesh merged none of the 300 pairs
    tm = trimesh.Trimesh(vertices=np.concatenate([a, a]), faces=np.arange(2 * n).reshape(-1, 3), process=False)
    tm.merge_vertices()
    assert len(tm.vertices) == n  # (and merges exact duplicates: the check above is not vacuous)


@pytest.mark.parametrize("dim", [2, 3])
def test_an_empty_mesh_is_merges_identity(dim):
    """Merging with a mesh that has no points gives the other mesh back (was a reshape error)."""
    sq = tri_square(3)
    pts = sq.points if dim == 2 else np.column_stack([sq.points, np.zeros(sq.n_points)])
    m = Mesh(pts, {"triangle": sq.cells["triangle"]})
    empty = Mesh(np.zeros((0, dim)), {"triangle": np.zeros((0, 3), dtype=np.int64)})
    for a, b in [(m, empty), (empty, m)]:
        out = merge(a, b)
        assert np.array_equal(out.points, m.points)
        assert np.array_equal(out.cells["triangle"], m.cells["triangle"])
    both = merge(empty, empty)
    assert both.n_points == 0 and both.n_cells == 0
    with pytest.raises(ValueError, match="same dimension"):
        merge(m, Mesh(np.zeros((0, 5 - dim)), {"triangle": np.zeros((0, 3), dtype=np.int64)}))


def test_meshes_sharing_top_cells_pass_the_euler_check():
    """Cells in both meshes belong to the interface complex T1 ∩ T2 (with their facets): a
    shared triangle made chi(T1 ∩ T2) one short and raised a MergeError on a valid merge, and
    a mesh merged with itself failed by the number of its cells."""
    pts = [[0, 0], [1, 0], [0, 1], [1, 1], [-1, 0]]
    a = wm.Mesh(pts, {"triangle": [[0, 1, 2], [1, 3, 2]]})
    b = wm.Mesh(pts, {"triangle": [[0, 1, 2], [0, 2, 4]]})
    for check in ("interface", "full"):
        m = a.merge(b, check=check)
        assert m.n_cells == 3 and m.info["euler_ok"] and m.info["n_duplicates"] == 1
    shape, bounds = wm.example("sphere")
    for mesh in (wm.mesh_surface(shape, bounds=bounds, resolution=12), wm.mesh_domain(shape, bounds, size=0.5)):
        same = mesh.merge(mesh, check="full")
        assert same.info["euler_ok"] and same.info["euler"] == mesh.info.get("euler", same.info["euler_a"])
        assert {t: len(c) for t, c in same.cells.items()} == {t: len(c) for t, c in mesh.cells.items()}


def test_full_check_refuses_meshes_that_overlap():
    """Two triangulations of one square merge into a valid complex (the Euler check passes)
    whose triangles overlap; check="full" now also checks the result's cells for crossings."""
    pts = [[0, 0], [1, 0], [0, 1], [1, 1]]
    a = wm.Mesh(pts, {"triangle": [[0, 1, 3], [0, 3, 2]]})
    b = wm.Mesh(pts, {"triangle": [[0, 1, 2], [1, 3, 2]]})
    assert a.merge(b).n_cells == 4  # the default (interface) check counts only
    with pytest.raises(MergeError, match="the merged cells overlap"):
        a.merge(b, check="full")
    shape, bounds = wm.example("sphere")
    tets = wm.mesh_domain(shape, bounds, size=0.5)
    lower = tets.points[:, 2] < 0.0
    keep = lower[tets.cells["tetra"]].all(axis=1)
    half = wm.Mesh(tets.points, {"tetra": tets.cells["tetra"][keep]})
    rest = wm.Mesh(tets.points, {"tetra": tets.cells["tetra"][~keep]})
    whole = half.merge(rest, check="full")  # halves sharing an interface: no overlap
    assert len(whole.cells["tetra"]) == len(tets.cells["tetra"])


def test_meshes_from_the_float32_meshers_weld_by_default():
    """A stuffed box and its translate by the box's width: their common face's nodes are a few
    float32 ulps apart (1.00000005 against 1.0), and the default tolerance (2 float32 epsilons
    of the box) welds every one of them (at 1e-8, 81 of the 221 stayed apart, silently): a
    conforming interface, every face of it shared."""
    c = wm.mesh_domain(wm.box((2.0, 2.0, 2.0)), bounds=((-1.0,) * 3, (1.0,) * 3), size=0.2)
    on_face = int(np.count_nonzero(np.abs(c.points[:, 0] - 1.0) < 1e-6))
    m = c.merge(c.transform(wm.transforms.translation([2.0, 0.0, 0.0])))
    assert m.info["n_common_points"] == on_face and m.n_points == 2 * c.n_points - on_face
    assert m.info["n_common_faces"] > 0 and len(wm.check(m)) == 0
