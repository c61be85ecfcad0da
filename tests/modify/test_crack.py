"""Cracks [FG §17.5, Figs. 17.15, 17.16]: the mesh is cut open along interior facets.

Every case is a planar crack (axis = value, over a region of the plane) in a mesh whose
facets cover that plane, so the expected answer follows from geometry alone: a crack
vertex is duplicated unless it lies on an in-plane facet that is not cracked (a tip or
the crack front) — the rule of the book's first method (two meshes merged with
attributes that keep the crack vertices apart), which one test emulates in full.
"""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv
import scipy.sparse as sp
from tests.helpers.cellcheck import check_cells
from scipy.sparse.csgraph import connected_components

from warpmesh.modify.crack import crack
from warpmesh.mesh import Mesh
from warpmesh.cells.reference import cell_measures, reference_cell

DELTA = 0.05  # crack opening, in units of the mesh size


# ----------------------------------------------------------------------------- meshes
def _shuffle(points, cells: dict, seed: int = 0):
    """Random point and cell numbering, so no result depends on a structured order."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(points))
    inv = np.argsort(perm)
    return points[perm], {t: inv[c][rng.permutation(len(c))] for t, c in cells.items()}


def _fix_orientation(points, cells, t):
    neg = cell_measures(points, cells, t) < 0
    cells[neg] = cells[neg][:, reference_cell(t).mirror]
    return cells


def square(n: int, kind: str) -> Mesh:
    """Unit square, n x n quads or 2n^2 triangles."""
    g = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)  # g[j, i]: x = i / n, y = j / n
    pts = np.stack(np.meshgrid(np.arange(n + 1), np.arange(n + 1)), -1).reshape(-1, 2) / n
    a, b, c, d = g[:-1, :-1].ravel(), g[:-1, 1:].ravel(), g[1:, 1:].ravel(), g[1:, :-1].ravel()
    cells = (np.stack([a, b, c, d], 1) if kind == "quad"
             else np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]))
    pts, blocks = _shuffle(pts.astype(float), {kind: cells})
    return Mesh(pts, blocks)


def _cube_grid(n: int):
    g = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)  # g[i, j, k]
    pts = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3) / n
    corner = [g[i:n + i, j:n + j, k:n + k].ravel() for k in (0, 1) for j in (0, 1) for i in (0, 1)]
    return pts.astype(float), np.stack(corner, 1)  # (m, 8): bit 0 = x, bit 1 = y, bit 2 = z


def kuhn_cube(n: int) -> Mesh:
    """Unit cube, 6 n^3 tetrahedra of the Kuhn (Freudenthal) split: conforming."""
    pts, c = _cube_grid(n)
    paths = [(1, 2, 4), (1, 4, 2), (2, 1, 4), (2, 4, 1), (4, 1, 2), (4, 2, 1)]
    tets = np.concatenate([c[:, [0, a, a + b, 7]] for a, b, _ in paths])
    tets = _fix_orientation(pts, tets, "tetra")
    pts, blocks = _shuffle(pts, {"tetra": tets}, 1)
    return Mesh(pts, blocks)


def hex_cube(n: int):
    pts, c = _cube_grid(n)
    return pts, c[:, [0, 1, 3, 2, 4, 5, 7, 6]]  # VTK order


def pyramid_cube(n: int) -> Mesh:
    """Unit cube, each of n^3 cubes split into 6 pyramids with their apex at its centre."""
    pts, h = hex_cube(n)
    centre = len(pts) + np.arange(len(h))
    pts = np.concatenate([pts, pts[h].mean(axis=1)])
    faces = reference_cell("hexahedron").faces
    pyr = np.concatenate([np.column_stack([h[:, list(f)], centre]) for f in faces])
    pyr = _fix_orientation(pts, pyr, "pyramid")
    pts, blocks = _shuffle(pts, {"pyramid": pyr}, 2)
    return Mesh(pts, blocks)


def wedge_slab(n: int) -> Mesh:
    """Unit cube, triangles of the square extruded in n layers."""
    base = square(n, "triangle")
    p2, t = base.points, base.cells["triangle"]
    np2 = len(p2)
    pts = np.concatenate([np.column_stack([p2, np.full(np2, k / n)]) for k in range(n + 1)])
    w = np.concatenate([np.column_stack([t + k * np2, t + (k + 1) * np2]) for k in range(n)])
    return Mesh(pts, {"wedge": _fix_orientation(pts, w, "wedge")})


def hexbeam() -> Mesh:
    m = Mesh.from_pyvista(pv.examples.load_hexbeam())
    return m.replace(cell_refs={"hexahedron": np.arange(m.n_cells) % 3})


# ----------------------------------------------------------------------------- helpers
def _oriented_facets(mesh):
    """(owner, oriented rows padded -1) of the top-dimension cells' facets, in one array."""
    rows, owner, off = [], [], 0
    for t, c in mesh.cells.items():
        ref = reference_cell(t)
        if ref.tdim != mesh.dim:
            continue
        local = [tuple(e) for e in ref.edges.tolist()] if ref.tdim == 2 else list(ref.faces)
        for f in local:
            r = c[:, list(f)]
            rows.append(np.pad(r, ((0, 0), (0, 4 - r.shape[1])), constant_values=-1))
            owner.append(np.arange(len(c)) + off)
        off += len(c)
    return np.concatenate(owner), np.concatenate(rows)


def _key(rows):
    s = np.sort(np.where(rows < 0, np.iinfo(np.int64).max, rows), axis=1)
    return np.where(s == np.iinfo(np.int64).max, -1, s)


def cells_ok(mesh) -> dict:
    """``check_cells``, and the same checks here for wedges and pyramids (triangle and quad
    faces together), which tests/cellcheck.py cannot concatenate yet."""
    if not any(t in ("wedge", "pyramid") for t in mesh.cells):
        return check_cells(mesh, embedded=False)  # a crack's two lips coincide by design
    from warpmesh.cells.reference import corner_jacobians

    total = 0.0
    for t, c in mesh.cells.items():
        if reference_cell(t).tdim == 3:
            assert (corner_jacobians(mesh.points, c, t) > 0).all(), f"inverted {t}"
            total += float(cell_measures(mesh.points, c, t).sum())
    _, rows = _oriented_facets(mesh)
    _, inv, cnt = np.unique(_key(rows), axis=0, return_inverse=True, return_counts=True)
    assert cnt.max() <= 2, "a face in more than two cells"
    b = rows[cnt[inv.ravel()] == 1]
    w = (b >= 0).sum(axis=1)
    edges = np.concatenate([np.sort(np.stack([b[w == k][:, :k], np.roll(b[w == k][:, :k], -1, 1)], 2)
                                    .reshape(-1, 2), 1) for k in (3, 4)])
    assert (np.unique(edges, axis=0, return_counts=True)[1] % 2 == 0).all(), "open boundary"
    return {"measure": total, "boundary_measure": facet_measure(mesh.points, b)}


def plane_facets(mesh, axis: int, value: float, region) -> tuple[np.ndarray, np.ndarray]:
    """Facets in the plane x[axis] = value, once each, as (k, w) rows in a cell's order:
    (in the region, not in the region)."""
    _, rows = _oriented_facets(mesh)
    _, first = np.unique(_key(rows), axis=0, return_index=True)
    keys = rows[first]  # one oriented row per facet (cyclic order, for quad measures)
    x = np.where(keys[..., None] >= 0, mesh.points[np.maximum(keys, 0)], np.nan)
    on = np.nanmax(np.abs(x[..., axis] - value), axis=1) < 1e-12
    inside = region(np.nanmean(x, axis=1))
    trim = lambda k: k[:, : (k >= 0).sum(axis=1).max()] if len(k) else k  # noqa: E731
    return trim(keys[on & inside]), keys[on & ~inside]


def facet_measure(points, keys) -> float:
    total = 0.0
    for w in (2, 3, 4):
        k = keys[(keys >= 0).sum(axis=1) == w][:, :w]
        if len(k):
            total += float(cell_measures(points, k, {2: "line", 3: "triangle", 4: "quad"}[w]).sum())
    return total


def expected_duplicates(crack_keys, other_plane_keys) -> int:
    """Crack vertices not on an uncracked in-plane facet [FG Fig. 17.15]."""
    cv = np.unique(crack_keys[crack_keys >= 0])
    return len(np.setdiff1d(cv, other_plane_keys[other_plane_keys >= 0]))


def components(mesh) -> int:
    owner, rows = _oriented_facets(mesh)
    _, fid = np.unique(_key(rows), axis=0, return_inverse=True)
    fid = fid.ravel()
    o = np.argsort(fid, kind="stable")
    same = np.flatnonzero(fid[o][1:] == fid[o][:-1])
    ne = owner.max() + 1
    g = sp.csr_matrix((np.ones(len(same)), (owner[o][same], owner[o][same + 1])), shape=(ne, ne))
    return connected_components(g, directed=False)[0]


def centroids(mesh):
    return np.concatenate([mesh.points[c].mean(axis=1) for t, c in mesh.cells.items()
                           if reference_cell(t).tdim == mesh.dim])


def open_crack(cracked, axis, value, h):
    """Move the duplicated vertices used only by cells above the plane by DELTA * h."""
    pairs = cracked.info["crack_pairs"]
    users_above = np.zeros(cracked.n_points, int)
    users_below = np.zeros(cracked.n_points, int)
    for t, c in cracked.cells.items():
        if reference_cell(t).tdim == cracked.dim:
            above = cracked.points[c].mean(axis=1)[:, axis] > value
            np.add.at(users_above, c[above].ravel(), 1)
            np.add.at(users_below, c[~above].ravel(), 1)
    move = np.zeros(cracked.n_points, bool)
    move[pairs.ravel()] = True
    move &= (users_above > 0) & (users_below == 0)
    pts = cracked.points.copy()
    pts[move, axis] += DELTA * h
    return cracked.replace(points=pts), move


def check_crack(mesh, facets, axis, value, region, h, *, n_components, single=None):
    """The checks (a)-(d) of a planar crack; returns the cracked mesh. ``single(x)`` marks
    the crack vertices at x that must stay single (default: those on an uncracked facet
    of the plane)."""
    crack_keys, other = plane_facets(mesh, axis, value, region)
    if facets is None:
        facets = crack_keys
    before = cells_ok(mesh)
    out = crack(mesh, facets)
    after = cells_ok(out)  # (a) orientation, conformity, closed boundary
    assert after["measure"] == pytest.approx(before["measure"], rel=1e-12)
    if single is None:
        n_dup = expected_duplicates(crack_keys, other)
    else:
        cv = np.unique(crack_keys[crack_keys >= 0])
        n_dup = int((~single(mesh.points[cv])).sum())
    assert out.info["n_duplicated"] == n_dup == out.n_points - mesh.n_points
    pairs = out.info["crack_pairs"]
    assert np.allclose(out.points[pairs[:, 1]], out.points[pairs[:, 0]])
    assert out.info["n_crack_facets"] == len(crack_keys)
    # (b) every facet with a duplicated vertex opens: the boundary grows by twice its measure
    dup = np.zeros(mesh.n_points, bool)
    dup[pairs[:, 0]] = True
    opened = crack_keys[(dup[np.maximum(crack_keys, 0)] & (crack_keys >= 0)).any(axis=1)]
    assert out.info["n_opened_facets"] == len(opened)
    assert after["boundary_measure"] == pytest.approx(
        before["boundary_measure"] + 2 * facet_measure(mesh.points, opened), rel=1e-12)
    # the lips: one element's outward facet, and the other's (mirrored), at the same places
    lips = out.info["crack_lips"]
    assert len(lips) == len(opened)
    assert np.allclose(out.points[lips[:, 0]], out.points[lips[:, 1]])  # -1 pads match too
    assert (lips[:, 0] != lips[:, 1]).any(axis=1).all()
    _, rows = _oriented_facets(out)
    outward = {tuple(r) for r in _as_cyclic_set_padded(rows).tolist()}
    for lip in (lips[:, 0], _mirror_padded(lips[:, 1])):
        assert all(tuple(r) in outward for r in _as_cyclic_set_padded(lip).tolist())
    # (c) opening the crack keeps every cell positive and removes exactly the gap
    opened_mesh, move = open_crack(out, axis, value, h)
    assert move.sum() == n_dup  # one lip of each duplicated vertex moves
    d = np.zeros(mesh.n_points)
    d[pairs[:, 0]] = DELTA * h
    gap = 0.0
    for w in (2, 3, 4):
        k = crack_keys[(crack_keys >= 0).sum(axis=1) == w][:, :w]
        if len(k):
            meas = cell_measures(mesh.points, k, {2: "line", 3: "triangle", 4: "quad"}[w])
            gap += float((meas * d[k].mean(axis=1)).sum())
    assert cells_ok(opened_mesh)["measure"] == pytest.approx(before["measure"] - gap, rel=1e-12)
    # (d) components
    assert components(mesh) == 1 and components(out) == n_components
    return out


# ----------------------------------------------------------------------------- 2D
@pytest.mark.parametrize("kind", ["triangle", "quad"])
def test_2d_crack_from_the_boundary_keeps_the_tip_single(kind):
    m = square(8, kind)
    out = check_crack(m, None, 1, 0.5, lambda c: c[:, 0] < 0.5, 1 / 8, n_components=1)
    pts = out.points[out.info["crack_pairs"][:, 0]]
    assert np.allclose(pts[:, 1], 0.5) and pts[:, 0].min() == 0 and pts[:, 0].max() < 0.5
    tip = np.flatnonzero(np.all(np.isclose(m.points, [0.5, 0.5]), axis=1))
    assert tip.size == 1 and tip[0] not in out.info["crack_pairs"]  # Fig. 17.15, right
    mouth = np.flatnonzero(np.all(np.isclose(m.points, [0.0, 0.5]), axis=1))
    assert mouth[0] in out.info["crack_pairs"][:, 0]  # Fig. 17.15, middle


@pytest.mark.parametrize("kind", ["triangle", "quad"])
def test_2d_crack_through_cuts_in_two(kind):
    m = square(6, kind)
    out = check_crack(m, None, 0, 0.5, lambda c: np.ones(len(c), bool), 1 / 6, n_components=2)
    assert out.info["n_duplicated"] == 7  # every vertex of the line x = 0.5, both ends too


def test_2d_interior_crack_has_two_tips():
    m = square(8, "triangle")
    out = check_crack(m, None, 1, 0.5, lambda c: np.abs(c[:, 0] - 0.5) < 0.3, 1 / 8, n_components=1)
    assert out.info["n_duplicated"] == 3  # 5 crack vertices, 2 tips


@pytest.mark.parametrize("kind", ["triangle", "quad"])
def test_branching_crack_gives_each_sheet_a_copy(kind):
    m = square(6, kind)
    flat, _ = plane_facets(m, 1, 0.5, lambda c: np.ones(len(c), bool))  # y = 1/2, through
    up, _ = plane_facets(m, 0, 0.5, lambda c: c[:, 1] > 0.5)  # x = 1/2 from the centre up
    out = crack(m, np.concatenate([flat, up]))
    before, after = check_cells(m), check_cells(out, embedded=False)  # the lips coincide
    assert after["measure"] == pytest.approx(before["measure"], rel=1e-12)
    assert after["boundary_measure"] == pytest.approx(before["boundary_measure"] + 2 * 1.5)
    assert components(out) == 3
    centre = np.flatnonzero(np.isclose(m.points, 0.5).all(axis=1))[0]
    pairs = out.info["crack_pairs"]
    assert (pairs[:, 0] == centre).sum() == 2  # three groups around the T junction
    assert out.info["n_duplicated"] == 7 + 3 + 1  # the line, the stem, the junction twice


def test_single_interior_edge_stays_closed():
    m = square(4, "quad")
    keys, _ = plane_facets(m, 1, 0.5, lambda c: np.abs(c[:, 0] - 0.375) < 0.01)
    out = crack(m, keys)
    assert out.info["n_duplicated"] == 0 and out.info["n_opened_facets"] == 0
    assert out.info["n_crack_facets"] == 1 and np.array_equal(out.cells["quad"], m.cells["quad"])


def test_facet_order_and_repeats_do_not_matter():
    m = square(6, "triangle")
    keys, _ = plane_facets(m, 1, 0.5, lambda c: c[:, 0] < 0.6)
    a = crack(m, keys)
    b = crack(m, np.concatenate([keys[::-1, ::-1], keys[:2]]))
    assert np.array_equal(a.cells["triangle"], b.cells["triangle"])
    assert np.array_equal(a.info["crack_pairs"], b.info["crack_pairs"])


# ----------------------------------------------------------------------------- 3D
def test_tetra_crack_reaching_three_faces():
    m = kuhn_cube(4)
    out = check_crack(m, None, 2, 0.5, lambda c: c[:, 0] < 0.5, 1 / 4, n_components=1)
    x = out.points[out.info["crack_pairs"][:, 0]]
    assert np.allclose(x[:, 2], 0.5) and x[:, 0].max() < 0.5  # the front x = 0.5 stays single


def test_tetra_interior_crack_and_cut_through():
    m = kuhn_cube(4)
    out = check_crack(m, None, 2, 0.5, lambda c: np.abs(c[:, :2] - 0.5).max(axis=1) < 0.25,
                      1 / 4, n_components=1)
    assert out.info["n_duplicated"] == 1  # 3 x 3 crack vertices, the 8 of the front stay
    check_crack(m, None, 1, 0.75, lambda c: np.ones(len(c), bool), 1 / 4, n_components=2)


def gmsh_box_with_sheet(h: float) -> Mesh:
    """A gmsh tetrahedral mesh of the unit cube with the rectangle z = 1/2, x < 1/2 embedded
    (fragmented into the volume), so its faces are mesh facets; nothing else of that
    plane is."""
    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        occ = gmsh.model.occ
        occ.fragment([(3, occ.addBox(0, 0, 0, 1, 1, 1))], [(2, occ.addRectangle(0, 0, 0.5, 0.5, 1))])
        occ.synchronize()
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.model.mesh.generate(3)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        _, _, nodes = gmsh.model.mesh.getElements(3)
    finally:
        gmsh.finalize()
    index = np.zeros(int(tags.max()) + 1, np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    return Mesh(xyz.reshape(-1, 3), {"tetra": index[nodes[0].astype(np.int64).reshape(-1, 4)]})


def test_gmsh_tetra_crack_on_an_embedded_sheet():
    m = gmsh_box_with_sheet(0.2)
    out = check_crack(m, None, 2, 0.5, lambda c: c[:, 0] < 0.5, 0.2, n_components=1,
                      single=lambda x: np.isclose(x[:, 0], 0.5))  # the front stays single
    assert out.info["n_duplicated"] > 10


def test_triangle_surface_in_3d():
    import trimesh

    m = Mesh.from_trimesh(trimesh.creation.uv_sphere(radius=1.0, count=[16, 16]))
    z = np.round(m.points[:, 2], 9)
    ring = m.edges[(z[m.edges] == np.unique(z)[6]).all(axis=1)]  # a closed latitude loop
    arc = ring[(m.points[ring, 0] > -1e-9).all(axis=1)]
    before = m.stats()
    for edges, n_dup, n_comp in ((ring, len(ring), 2), (arc, len(arc) - 1, 1)):
        out = crack(m, edges)
        s = out.stats()
        assert out.info["n_duplicated"] == n_dup and out.info["n_opened_facets"] == len(edges)
        assert s["components"] == n_comp and s["oriented"] and not s["watertight"]
        assert s["area"] == pytest.approx(before["area"], rel=1e-12)
        assert s["euler"] == before["euler"] + n_dup - len(edges)  # V grows, E grows, F same
        t = out.cells["triangle"]
        e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
        _, cnt = np.unique(e, axis=0, return_counts=True)
        assert (cnt == 1).sum() == 2 * len(edges) and cnt.max() == 2  # the two lips


def test_hexbeam_crack_across_part_of_a_section():
    m = hexbeam()
    out = check_crack(m, None, 2, 2.5, lambda c: c[:, 0] < 0.5, 0.5, n_components=1)
    assert np.array_equal(out.cell_refs["hexahedron"], m.cell_refs["hexahedron"])
    for name, v in m.point_data.items():
        assert np.array_equal(out.point_data[name][: m.n_points], v)
        assert np.array_equal(out.point_data[name][m.n_points:], v[out.info["crack_pairs"][:, 0]])
    assert np.array_equal(out.cell_data["sample_cell_scalars"]["hexahedron"],
                          m.cell_data["sample_cell_scalars"]["hexahedron"])
    check_crack(m, None, 2, 2.5, lambda c: np.ones(len(c), bool), 0.5, n_components=2)


def test_wedges_crack_on_quad_and_triangle_faces():
    m = wedge_slab(4)
    check_crack(m, None, 0, 0.5, lambda c: c[:, 2] < 0.5, 1 / 4, n_components=1)  # quads
    check_crack(m, None, 2, 0.5, lambda c: c[:, 1] > 0.5, 1 / 4, n_components=1)  # triangles


def test_pyramids_crack_on_quad_faces():
    m = pyramid_cube(3)
    check_crack(m, None, 2, 1 / 3, lambda c: c[:, 0] < 0.5, 1 / 3, n_components=1)


# ----------------------------------------------------------------------------- method 1
def merge_two_sides(mesh, crack_keys, other_keys, axis, value):
    """The book's first method, emulated: the two sides become two meshes with their own
    points, crack vertices off the uncracked part of the plane get a side attribute, and
    points are merged when coordinates and attributes agree (§17.2)."""
    top = next(iter(mesh.cells.values()))
    side = mesh.points[top].mean(axis=1)[:, axis] > value
    apart = np.zeros(mesh.n_points, bool)
    apart[np.setdiff1d(crack_keys[crack_keys >= 0], other_keys[other_keys >= 0])] = True
    pts, attrs, cells = [], [], []
    for s in (False, True):
        used, local = np.unique(top[side == s], return_inverse=True)
        cells.append(local.reshape(-1, top.shape[1]) + sum(len(p) for p in pts))
        pts.append(mesh.points[used])
        attrs.append(np.where(apart[used], 1 + int(s), 0))
    key = np.column_stack([np.round(np.concatenate(pts), 9), np.concatenate(attrs)])
    _, num = np.unique(key, axis=0, return_inverse=True)
    return num.max() + 1, num.ravel()[np.concatenate(cells)]


def _n_edges(cells):
    e = np.sort(np.concatenate([cells[:, [i, (i + 1) % cells.shape[1]]] for i in range(cells.shape[1])]), 1)
    return len(np.unique(e, axis=0))


@pytest.mark.parametrize("build, axis, region", [
    (lambda: square(8, "triangle"), 1, lambda c: c[:, 0] < 0.6),
    (lambda: square(8, "quad"), 1, lambda c: np.abs(c[:, 0] - 0.5) < 0.3),
    (lambda: kuhn_cube(3), 2, lambda c: c[:, 1] > 0.4),
])
def test_same_points_as_merging_two_meshes(build, axis, region):
    m = build()
    value = 0.5 if m.dim == 2 else 2 / 3
    keys, other = plane_facets(m, axis, value, region)
    n_points, merged_cells = merge_two_sides(m, keys, other, axis, value)
    out = crack(m, keys)
    assert out.n_points == n_points
    top = next(iter(out.cells.values()))
    assert _n_edges(top) == _n_edges(merged_cells)  # the same topology, edge for edge


# ----------------------------------------------------------------------------- lower blocks
def _boundary_lines(mesh):
    owner, rows = _oriented_facets(mesh)
    _, inv, cnt = np.unique(_key(rows), axis=0, return_inverse=True, return_counts=True)
    b = cnt[inv.ravel()] == 1
    return rows[b][:, : (rows[0] >= 0).sum()], owner[b]


def _as_cyclic_set(rows):
    """Rows up to rotation (orientation kept): the rotation starting at the smallest."""
    k = rows.shape[1]
    if k == 2:
        return rows
    s = np.argmin(rows, axis=1)
    return rows[np.arange(len(rows))[:, None], (s[:, None] + np.arange(k)) % k]


def test_ref_crack_2d_lips_are_oriented_boundary_lines():
    m = square(8, "triangle")
    blines, _ = _boundary_lines(m)
    keys, _ = plane_facets(m, 1, 0.5, lambda c: c[:, 0] < 0.5)
    up = m.points[keys[:, 1], 0] < m.points[keys[:, 0], 0]
    keys[up] = keys[up][:, ::-1]  # crack lines run in +x: their left is the upper side
    lines = np.concatenate([blines, keys])
    refs = np.r_[np.ones(len(blines), int), np.full(len(keys), 5)]
    m = m.replace(cells={**m.cells, "line": lines}, cell_refs={"line": refs},
                  cell_data={"id": {"triangle": np.zeros(len(m.cells["triangle"])),
                                    "line": np.arange(len(lines))}},
                  point_refs=np.arange(m.n_points) % 4)
    out = crack(m, ref=5, side_refs=(6, 7))
    # the lines are exactly the new boundary, domain on the left, in the same rows order
    new_b, owner = _boundary_lines(out)
    assert len(out.cells["line"]) == len(new_b) == len(blines) + 2 * len(keys)
    assert np.array_equal(np.unique(out.cells["line"], axis=0), np.unique(new_b, axis=0))
    r = out.cell_refs["line"]
    assert (r == 1).sum() == len(blines) and (r == 6).sum() == (r == 7).sum() == len(keys)
    # ref 6 lips belong to the cells on the left of the original lines: above y = 0.5
    cen = centroids(out)
    pos = {tuple(e): o for e, o in zip(new_b.tolist(), owner)}
    side = np.array([cen[pos[tuple(e)], 1] > 0.5 for e in out.cells["line"].tolist()])
    assert side[r == 6].all() and not side[r == 7].any()
    ids = out.cell_data["id"]["line"]
    assert np.array_equal(np.sort(np.unique(ids)), np.arange(len(lines)))
    assert np.array_equal(out.point_refs[out.info["crack_pairs"][:, 1]],
                          m.point_refs[out.info["crack_pairs"][:, 0]])
    # a mouth at the boundary: the boundary lines there use both copies
    mouth = out.info["crack_pairs"][np.isclose(out.points[out.info["crack_pairs"][:, 0], 0], 0)]
    assert len(mouth) == 1 and np.isin(mouth, out.cells["line"][r == 1]).all()


def _as_cyclic_set_padded(rows):
    """Padded rows (w <= 4, -1 at the end) up to rotation, orientation kept, padded to 4."""
    rows = np.pad(rows, ((0, 0), (0, 4 - rows.shape[1])), constant_values=-1)
    out = rows.copy()
    for w in (2, 3, 4):
        sel = (rows >= 0).sum(axis=1) == w
        out[sel, :w] = rows[sel, :w] if w == 2 else _as_cyclic_set(rows[sel, :w])
    return out


def _mirror_padded(rows):
    """Reverse each padded row's orientation (lines: swap the ends)."""
    out = rows.copy()
    w = (rows >= 0).sum(axis=1)
    for k in np.unique(w):
        out[w == k, :k] = rows[w == k, :k][:, ::-1]
    return out


def test_ref_crack_3d_quads_face_out_of_the_domain():
    m = hexbeam()
    bq, _ = _boundary_lines(m)
    keys, _ = plane_facets(m, 2, 2.5, lambda c: c[:, 0] < 0.5)
    quads = np.concatenate([bq, _quad_order(m, keys)])
    refs = np.r_[np.ones(len(bq), int), np.full(len(keys), 5)]
    edge = np.flatnonzero(np.isclose(m.points, [0, 0, 2.5]).all(axis=1))
    m = m.replace(cells={**m.cells, "quad": quads, "vertex": edge[:, None]},
                  cell_refs={"quad": refs, "vertex": [9]}, cell_data={})
    out = crack(m, ref=5)
    new_b, _ = _boundary_lines(out)
    got = np.unique(_as_cyclic_set(out.cells["quad"]), axis=0)
    assert len(out.cells["quad"]) == len(bq) + 2 * len(keys)
    assert np.array_equal(got, np.unique(_as_cyclic_set(new_b), axis=0))  # oriented outwards
    assert out.cells["vertex"].ravel().tolist() == sorted(out.info["crack_pairs"][
        out.info["crack_pairs"][:, 0] == edge[0]].ravel().tolist())  # one vertex cell per side
    assert out.cell_refs["vertex"].tolist() == [9, 9]


def _quad_order(m, keys):
    """Crack faces as the cyclic quads they are in the hexahedra (any orientation)."""
    _, rows = _oriented_facets(m)
    k = _key(rows)
    want = {tuple(r) for r in _key(keys).tolist()}
    pick = np.array([tuple(r) in want for r in k.tolist()])
    rows, k = rows[pick], k[pick]
    _, first = np.unique(k, axis=0, return_index=True)
    return rows[first]


# ----------------------------------------------------------------------------- bad input
def _tiny():
    pts = [[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]]
    return Mesh(pts, {"quad": [[0, 1, 4, 3], [1, 2, 5, 4]], "line": [[0, 1], [1, 4]]},
                cell_refs={"line": [1, 2]})


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(facets=[[0, 4]]), ValueError, r"\[0, 4\] which is not a facet"),
    (dict(facets=[[0, 1]]), ValueError, r"\[0, 1\] which is on the boundary"),
    (dict(facets=[[1, 4, 2]]), ValueError, r"shape \(k, 2\)"),
    (dict(facets=[[-1, 4]]), ValueError, "expected vertex indices in"),
    (dict(facets=[[1, 6]]), ValueError, "expected vertex indices in"),
    (dict(facets=[[1.0, 4.0]]), TypeError, "integer array for 'facets'"),
    (dict(facets=np.zeros((0, 2), int)), ValueError, "k >= 1"),
    (dict(), ValueError, "exactly one of 'facets'"),
    (dict(facets=[[1, 4]], ref=2), ValueError, "exactly one of 'facets'"),
    (dict(ref=3), ValueError, r"'line' cells with ref 3 .*got none \(refs present .*\[1, 2\]"),
    (dict(ref=1), ValueError, "'line' cell with ref 1 0 \\[0, 1\\] which is on the boundary"),
    (dict(ref="2"), TypeError, "int for 'ref'"),
    (dict(ref=2, side_refs=(1,)), ValueError, "'side_refs' as two ints"),
    (dict(ref=2, width=0.1), TypeError, "width"),
])
def test_bad_input(kwargs, error, match):
    with pytest.raises(error, match=match):
        crack(_tiny(), **kwargs)


def test_bad_mesh():
    with pytest.raises(ValueError, match="then raise the order with to_order"):
        crack(square(2, "triangle").to_order(2), [[0, 1]])
    with pytest.raises(ValueError, match="expected 2D or 3D elements"):
        crack(Mesh([[0.0, 0], [1, 0]], {"line": [[0, 1]]}), [[0, 1]])
    with pytest.raises(TypeError, match="Mesh for 'mesh'"):
        crack(np.zeros((3, 2)), [[0, 1]])
    fan = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0.5], [1, 1, 1]],
               {"tetra": [[0, 1, 2, 3], [0, 1, 3, 4], [0, 1, 5, 3]]})  # face 0-1-3 in three
    with pytest.raises(ValueError, match=r"\[0, 1, 3\] which is shared by 3 elements"):
        crack(fan, [[0, 1, 3]])


def test_a_cracked_mesh_is_embedded():
    """The two lips of a crack are coincident faces (edges in the plane) that touch; the check
    counted them as crossing (36 pairs of tetrahedra for an interior crack, 484 for a plane
    through a tetrahedral cube, 11 for the planar example), though no interiors overlap."""
    import itertools

    import warpmesh as wm

    n = 4
    g = np.array(list(itertools.product(range(n + 1), repeat=3)), float)[:, ::-1] / n
    idx = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)  # noqa: E731
    hexes = [[idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k), idx(i, j, k + 1),
              idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)]
             for k in range(n) for j in range(n) for i in range(n)]
    tets = wm.Mesh(g, {"hexahedron": hexes}).convert("tetra")
    t = tets.cells["tetra"]
    faces = np.sort(np.concatenate([t[:, list(c)] for c in itertools.combinations(range(4), 3)]), axis=1)
    u, cnt = np.unique(faces, axis=0, return_counts=True)
    inner = u[cnt == 2]
    on_plane = np.abs(tets.points[inner][:, :, 0] - 0.5).max(axis=1) < 1e-9
    for sel in (on_plane, on_plane & (np.abs(tets.points[inner][:, :, 1:] - 0.5).max(axis=(1, 2)) <= 0.25 + 1e-9)):
        cracked = tets.crack(inner[sel])
        assert cracked.n_points > tets.n_points and len(cracked.check()) == 0
        assert cracked.stats()["self_intersections"] == 0
    pts = np.array([[x, y] for y in range(3) for x in range(3)], float)
    tris = [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]]
    planar = crack(Mesh(pts, {"triangle": tris, "line": [[3, 4], [4, 5]]}, cell_refs={"line": [5, 5]}), ref=5)
    assert planar.n_points == 12 and len(planar.check()) == 0
    # an overlap is still one with duplicated points: the same triangle twice, one on copies
    twice = Mesh(np.concatenate([pts, pts[[0, 1, 4]]]), {"triangle": [[0, 1, 4], [9, 10, 11]]})
    assert twice.check().tolist() == [[0, 1]]
    tet_twice = Mesh(np.concatenate([tets.points, tets.points[t[0]]]),
                     {"tetra": [t[0], np.arange(4) + tets.n_points]})
    assert tet_twice.check().tolist() == [[0, 1]]
