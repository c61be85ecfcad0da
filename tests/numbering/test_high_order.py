"""warpmesh.numbering.high_order: higher-order node creation [FG §17.3] and the p-compatibility check."""

from __future__ import annotations

import itertools
import os
import warnings

import numpy as np
import pytest
import pyvista as pv
from scipy.spatial import Delaunay

import warpmesh as wm
from warpmesh.mesh import CELL_TYPES, Mesh, load
from warpmesh.cells.lagrange import reference_nodes
from warpmesh.numbering.high_order import inverted_elements, jacobians, to_order

R = 1.0
BOUNDS = ((-1.2,) * 3, (1.2,) * 3)
#: (P1 type, order) -> meshio name
TYPES = {
    ("line", 2): "line3", ("line", 3): "line4", ("line", 4): "line5",
    ("triangle", 2): "triangle6", ("triangle", 3): "triangle10", ("triangle", 4): "triangle15",
    ("tetra", 2): "tetra10", ("tetra", 3): "tetra20", ("tetra", 4): "tetra35",
    ("quad", 2): "quad9", ("hexahedron", 2): "hexahedron27",
}
GMSH_IDS = {"line3": 8, "line4": 26, "line5": 27, "triangle6": 9, "triangle10": 21,
            "triangle15": 23, "tetra10": 11, "tetra20": 29, "tetra35": 30, "quad9": 10,
            "hexahedron27": 12}
#: meshio's gmsh -> VTK node permutations (meshio/gmsh/common.py); the other types agree
GMSH_TO_VTK = {
    "tetra10": [0, 1, 2, 3, 4, 5, 6, 7, 9, 8],
    "hexahedron27": [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 13, 9, 16, 18, 19, 17, 10, 12, 14, 15,
                     22, 23, 21, 24, 20, 25, 26],
}
GMSH_ORDERED = ("line4", "line5", "triangle10", "triangle15", "tetra20", "tetra35")
HEXBEAM = os.path.join(os.path.dirname(pv.__file__), "examples", "hexbeam.vtk")


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def sphere_surface() -> Mesh:
    s = wm.sphere(R)
    return wm.mesh_surface(s, bounds=BOUNDS, resolution=12).optimize(s)


@pytest.fixture(scope="module")
def ball(sphere_surface) -> Mesh:
    """A tetrahedral ball from TetGen, its surface vertices on the sphere; refs 1 on the
    surface and 2 inside, cell refs, a float point field."""
    tetgen = pytest.importorskip("tetgen")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # tetgen reads a deprecated pyvista array
        nodes, elems = tetgen.TetGen(sphere_surface.to_pyvista()).tetrahedralize(
            order=1, mindihedral=20, minratio=1.5)[:2]
    on_surface = np.arange(len(nodes)) < sphere_surface.n_points  # TetGen keeps them first
    assert np.allclose(nodes[on_surface], sphere_surface.points)
    return Mesh(nodes, {"tetra": elems}, point_refs=np.where(on_surface, 1, 2),
                cell_refs={"tetra": np.arange(len(elems)) % 3 + 1},
                point_data={"x": nodes[:, 0].copy()})


@pytest.fixture(scope="module")
def gmsh_api():
    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize(["-noenv"], readConfigFiles=False, interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    yield gmsh
    gmsh.finalize()


def _gmsh_reference(gmsh, name: str) -> np.ndarray:
    """gmsh's reference coordinates of the nodes of ``name``, mapped to [0, 1] per axis."""
    _, dim, _, n, coords, _ = gmsh.model.mesh.getElementProperties(GMSH_IDS[name])
    xi = np.asarray(coords).reshape(n, dim)
    return (xi + 1) / 2 if name.startswith(("line", "quad", "hexahedron")) else xi


def _vtk_reference(vtk_id: int, n: int) -> np.ndarray:
    """VTK's parametric coordinates of a cell of type ``vtk_id`` with n nodes."""
    grid = pv.UnstructuredGrid(np.r_[n, np.arange(n)].astype(pv.ID_TYPE),
                               np.array([vtk_id], np.uint8), np.random.default_rng(0).random((n, 3)))
    pc = grid.GetCell(0).GetParametricCoords()
    return np.array([pc[i] for i in range(3 * n)]).reshape(n, 3)


def _affine_cell(base: str, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The vertices (nv, 3) of a random affine image of the reference P1 cell, with (A, b)."""
    ref = reference_nodes(base)
    a = np.eye(3)[:, : ref.shape[1]] + 0.3 * rng.standard_normal((3, ref.shape[1]))
    b = rng.standard_normal(3)
    return ref @ a.T + b, a, b


def _edges_of(cells: np.ndarray, local_edges) -> np.ndarray:
    return np.unique(np.sort(cells[:, np.array(local_edges)].reshape(-1, 2), axis=1), axis=0)


# ----------------------------------------------------------------------------- tables
@pytest.mark.parametrize("name", list(GMSH_IDS))
def test_reference_table_matches_gmsh(gmsh_api, name):
    ours = reference_nodes(name)
    theirs = _gmsh_reference(gmsh_api, name)[GMSH_TO_VTK.get(name, slice(None))]
    assert np.allclose(ours, theirs, atol=1e-12)


@pytest.mark.parametrize("name", list(GMSH_IDS))
def test_gmsh_reads_our_nodes_where_it_expects_them(gmsh_api, name, tmp_path):
    """A cell whose nodes sit at our reference coordinates, written by meshio: gmsh finds
    node i of its element at its own reference node i (meshio permutes to gmsh itself)."""
    ref = reference_nodes(name)
    pts = np.column_stack([ref, np.zeros((len(ref), 3 - ref.shape[1]))])
    path = Mesh(pts, {name: [np.arange(len(ref))]}).save(tmp_path / "one.msh")
    gmsh_api.open(str(path))
    types, _, node_tags = gmsh_api.model.mesh.getElements()
    assert list(types) == [GMSH_IDS[name]]
    tags, coords, _ = gmsh_api.model.mesh.getNodes()
    where = dict(zip(tags.tolist(), np.asarray(coords).reshape(-1, 3), strict=True))
    found = np.array([where[t] for t in node_tags[0]])[:, : ref.shape[1]]
    assert np.allclose(found, _gmsh_reference(gmsh_api, name), atol=1e-12)
    gmsh_api.clear()


@pytest.mark.parametrize("name", list(GMSH_IDS))
def test_reference_table_matches_vtk(name):
    """VTK's own parametric coordinates agree for every type but tetra20/35, whose VTK
    Lagrange order differs (so to_pyvista refuses them)."""
    n, _, vtk_id = CELL_TYPES[name]
    ref = reference_nodes(name)
    vtk_ref = _vtk_reference(vtk_id, n)[:, : ref.shape[1]]
    if name in ("tetra20", "tetra35"):
        assert not np.allclose(ref, vtk_ref)  # same nodes, other order
        assert np.allclose(np.sort(ref, axis=0), np.sort(vtk_ref, axis=0))
    else:
        assert np.allclose(ref, vtk_ref, atol=1e-12)


# ----------------------------------------------------------------------------- straight Pk
@pytest.mark.parametrize(("base", "k"), list(TYPES))
def test_straight_nodes_are_the_affine_image_of_the_table(base, k):
    rng = np.random.default_rng(k)
    verts, a, b = _affine_cell(base, rng)
    name = TYPES[base, k]
    p = to_order(Mesh(verts, {base: [np.arange(len(verts))]}), k)
    cell = p.cells[name][0]
    assert np.array_equal(np.sort(cell), np.arange(p.n_points))
    assert np.allclose(p.points[cell], reference_nodes(name) @ a.T + b, atol=1e-12)
    assert np.allclose(jacobians(p)[name], 1.0, atol=1e-10)
    assert p.info["order"] == k and p.info["n_nodes"] == p.n_points and p.info["n_inverted"] == 0


@pytest.mark.parametrize("k", [3, 4])
def test_face_nodes_shared_by_two_tetra_in_any_vertex_order(k):
    """Two tetrahedra sharing face (0 1 2), the second listing it in every vertex order:
    one set of face nodes, each read at the same place by both (straight positions)."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.3, 1.0], [0.3, 0.2, -1.0]])
    name = TYPES["tetra", k]
    for perm in itertools.permutations([0, 1, 2]):
        second = [*perm, 4]
        mesh = Mesh(pts, {"tetra": [[0, 1, 2, 3], second], "triangle": [list(perm[::-1])]})
        p = to_order(mesh, k, check=False)
        n_edges, q = 9, (k - 1) * (k - 2) // 2
        assert p.n_points == 5 + (k - 1) * n_edges + q * 7 + (k == 4) * 2
        for t in (name, TYPES["triangle", k]):
            for cell in p.cells[t]:
                ref = reference_nodes(t)
                v = p.points[cell[: ref.shape[1] + 1]]
                straight = v[0] + ref @ (v[1:] - v[0])
                assert np.allclose(p.points[cell], straight, atol=1e-12)
        shared = [set(c.tolist()) for c in p.cells[name]]
        face = set(p.cells[TYPES["triangle", k]][0])
        assert face <= shared[0] and face <= shared[1]  # the boundary triangle reads them too


# ----------------------------------------------------------------------------- curved surfaces
@pytest.mark.parametrize("k", [2, 3, 4])
def test_sphere_surface(sphere_surface, k):
    m = sphere_surface
    p = m.to_order(k, wm.sphere(R), bounds=BOUNDS)
    name = TYPES["triangle", k]
    cells = p.cells[name]
    new = p.points[m.n_points:]
    assert np.abs(np.linalg.norm(new, axis=1) - R).max() < 1e-9
    assert jacobians(p)[name].min() > 0 and not inverted_elements(p)
    edges = _edges_of(m.triangles, [(0, 1), (1, 2), (2, 0)])
    face_nodes = (k - 1) * (k - 2) // 2
    assert p.n_points == m.n_points + (k - 1) * len(edges) + face_nodes * len(cells)
    assert p.info["to_order"]["n_projected"] == p.n_points - m.n_points
    # each unique edge: its k-1 nodes in exactly the two triangles of that edge, read in
    # opposite directions, and by no other edge
    occ_nodes = np.stack([cells[:, 3 + (k - 1) * e + np.arange(k - 1)] for e in range(3)], 1)
    ends = np.stack([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]], 1)
    key = np.sort(ends, axis=2).reshape(-1, 2)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    assert np.all(counts == 2)
    order = np.argsort(inv.reshape(-1), kind="stable")
    pairs = occ_nodes.reshape(-1, k - 1)[order].reshape(-1, 2, k - 1)
    assert np.array_equal(pairs[:, 0], pairs[:, 1, ::-1])
    assert len(np.unique(pairs[:, 0])) == (k - 1) * len(edges)


def test_disk_with_boundary_lines():
    """2D: boundary edge nodes go onto the circle; line3 cells share the triangles' edge
    nodes; a vertex block and an unused point are kept; refs and data follow."""
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.column_stack([np.cos(t), np.sin(t)])
    pts = np.vstack([ring, 0.55 * ring[::2], [[0, 0]], [[5, 5]]])  # the last point is unused
    tri = Delaunay(pts[:-1]).simplices
    e1, e2 = pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]
    flip = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]
    lines = np.column_stack([np.arange(24), (np.arange(24) + 1) % 24])
    refs = np.r_[np.ones(24, int), 2 * np.ones(len(pts) - 24, int)]
    mesh = Mesh(pts, {"triangle": tri, "line": lines, "vertex": [[36]]}, point_refs=refs,
                cell_refs={"line": np.full(24, 7)}, point_data={"u": pts[:, 0] + 2 * pts[:, 1]})
    p = wm.to_order(mesh, 2, wm.sphere(1.0))
    assert list(p.cells) == ["triangle6", "line3", "vertex"]
    assert np.array_equal(p.points[: len(pts)], pts) and p.cells["vertex"].tolist() == [[36]]
    tri6, line3 = p.cells["triangle6"], p.cells["line3"]
    boundary = line3[:, 2]
    assert np.abs(np.linalg.norm(p.points[boundary], axis=1) - 1).max() < 1e-9
    on_edge = {tuple(sorted(e)): n for e, n in zip(lines.tolist(), boundary.tolist(), strict=True)}
    for cell in tri6:
        for e, node in zip([(0, 1), (1, 2), (2, 0)], cell[3:], strict=True):
            key = tuple(sorted(cell[list(e)].tolist()))
            if key in on_edge:
                assert on_edge[key] == node  # one global node wherever the edge appears
            else:
                assert np.allclose(p.points[node], p.points[list(key)].mean(axis=0), atol=1e-15)
                assert p.point_refs[node] == (2 if min(key) >= 24 else 0)
    assert np.all(p.point_refs[boundary] == 1)
    ends = lines
    assert np.allclose(p.point_data["u"][boundary], mesh.point_data["u"][ends].mean(axis=1))
    assert p.cell_refs["line3"].tolist() == [7] * 24
    assert all(s.min() > 0 for s in jacobians(p).values())


def test_ball_tetra10(ball):
    s = wm.sphere(R)
    p = ball.to_order(2, s)
    assert p.info["n_inverted"] == 0 and jacobians(p)["tetra10"].min() > 0
    tets, nodes = ball.cells["tetra"], p.cells["tetra10"]
    local = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]  # VTK's tetra10 edges
    ends = np.stack([tets[:, list(e)] for e in local], 1).reshape(-1, 2)
    mids = nodes[:, 4:].reshape(-1)
    faces = np.sort(np.concatenate([tets[:, f] for f in ([1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2])]), 1)
    uf, fc = np.unique(faces, axis=0, return_counts=True)
    bface = uf[fc == 1]
    bedges = {tuple(e) for f in bface.tolist() for e in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2]))}
    on_boundary = np.array([tuple(sorted(e)) in bedges for e in ends.tolist()])
    assert on_boundary.any() and (~on_boundary).any()
    r = np.linalg.norm(p.points[mids[on_boundary]], axis=1)
    assert np.abs(r - R).max() < 1e-9
    straight = ball.points[ends[~on_boundary]].mean(axis=1)
    assert np.abs(p.points[mids[~on_boundary]] - straight).max() < 1e-14
    # refs and data: cell refs carried, midside refs from the two ends, x interpolated
    assert np.array_equal(p.cell_refs["tetra10"], ball.cell_refs["tetra"])
    r_ends = ball.point_refs[ends]
    expect = np.where(r_ends[:, 0] == r_ends[:, 1], r_ends[:, 0], 0)
    assert np.array_equal(p.point_refs[mids], expect)
    assert np.allclose(p.point_data["x"][mids], ball.points[ends, 0].mean(axis=1))
    # volume: det J of the P2 map integrated with a conical Gauss rule
    v1, v2, exact = ball.stats()["volume"], _tetra10_volume(p), 4 * np.pi / 3
    assert _tetra10_volume(ball.to_order(2)) == pytest.approx(v1, rel=1e-12)  # straight: P1's
    assert abs(v2 - exact) < abs(v1 - exact) / 20  # here 8e-5 against 5e-2


def _tetra10_volume(mesh: Mesh) -> float:
    """Sum over tetra10 cells of the integral of det J, P2 shape functions in closed form."""
    g, w = np.polynomial.legendre.leggauss(4)
    g, w = (g + 1) / 2, w / 2
    u, v, z = (a.ravel() for a in np.meshgrid(g, g, g, indexing="ij"))
    wt = np.einsum("i,j,k->ijk", w, w, w).ravel() * (1 - u) ** 2 * (1 - v)
    xi = np.column_stack([u, (1 - u) * v, (1 - u) * (1 - v) * z])
    lam = np.column_stack([1 - xi.sum(1), xi])
    dlam = np.array([[-1, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    pairs = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    dn = [(4 * lam[:, i, None] - 1) * dlam[i] for i in range(4)]
    dn += [4 * (lam[:, i, None] * dlam[j] + lam[:, j, None] * dlam[i]) for i, j in pairs]
    dn = np.stack(dn, 1)  # (s, 10, 3)
    x = mesh.points[mesh.cells["tetra10"]]
    det = np.linalg.det(np.einsum("mnd,snt->msdt", x, dn))
    return float((det * wt).sum())


# ----------------------------------------------------------------------------- p-compatibility
def test_flat_boundary_tetra_is_found_and_warned(ball):
    """A sliver whose four vertices lie on the sphere, added to the ball as a separate
    piece: its boundary nodes pushed onto the sphere turn it inside out."""
    phi = np.array([0, 0.5, 1, 1.5]) * np.pi
    theta = 0.5 + np.array([0.04, -0.04, 0.04, -0.04])
    sliver = np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    n, m = ball.n_points, len(ball.cells["tetra"])
    tets = np.vstack([ball.cells["tetra"], n + np.arange(4)])
    mesh = Mesh(np.vstack([ball.points, sliver]), {"tetra": tets})
    assert jacobians(mesh)["tetra"].min() == 1.0  # valid as P1
    with pytest.warns(UserWarning, match=r"1 elements \(1 of \d+ tetra10\) are inverted .*inverted_elements"):
        p = to_order(mesh, 2, wm.sphere(R))
    assert p.info["n_inverted"] == 1
    bad = inverted_elements(p)
    assert list(bad) == ["tetra10"] and bad["tetra10"].tolist() == [m]


def test_midside_node_pushed_through_the_opposite_face():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], float)
    p = Mesh(pts, {"tetra": [[0, 1, 2, 3], [1, 2, 3, 4]]}).to_order(2)
    assert jacobians(p)["tetra10"].tolist() == pytest.approx([1.0, 1.0])
    bent = p.points.copy()
    node = p.cells["tetra10"][0, 4]  # on edge (0 1), which the second tetra does not have
    bent[node] = [1.5, 0.0, 0.0]  # beyond the face (1 2 3) opposite vertex 0
    score = jacobians(p.replace(points=bent))["tetra10"]
    assert score[0] < 0 < score[1]
    assert {t: i.tolist() for t, i in inverted_elements(p.replace(points=bent)).items()} == {"tetra10": [0]}


# ----------------------------------------------------------------------------- quad9 / hex27
@pytest.fixture(scope="module")
def hexbeam() -> Mesh:
    return Mesh.from_pyvista(pv.read(HEXBEAM))


def test_hexbeam_hexahedron27(hexbeam):
    grid = pv.read(HEXBEAM)
    p = hexbeam.to_order(2)
    n_edges = grid.extract_all_edges().n_cells
    n_cells = grid.n_cells
    n_faces = 1 - grid.n_points + n_edges + n_cells  # Euler: V - E + F - C = 1 for a beam
    assert p.n_points == grid.n_points + n_edges + n_faces + n_cells
    assert np.allclose(jacobians(p)["hexahedron27"], 1.0, atol=1e-12)
    before = hexbeam.to_pyvista().compute_cell_sizes()["Volume"]
    after = p.to_pyvista().compute_cell_sizes()["Volume"]
    assert np.allclose(after, before, rtol=1e-12)
    # data: floats interpolated (a cell centre gets the mean of its 8 corners), ints like refs
    z = hexbeam.points[:, 2] ** 2
    p = hexbeam.replace(point_data={**hexbeam.point_data, "z2": z}).to_order(2)
    centre = p.cells["hexahedron27"][:, 26]
    assert np.allclose(p.point_data["z2"][centre], z[hexbeam.cells["hexahedron"]].mean(1))
    assert hexbeam.point_data["VTKorigID"].dtype.kind == "i"
    assert np.all(p.point_data["VTKorigID"][hexbeam.n_points:] == 0)  # ids never agree


def test_hexbeam_surface_quad9(hexbeam):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        surf = pv.read(HEXBEAM).extract_surface()
    m = Mesh.from_pyvista(surf)
    p = m.to_order(2)
    n_edges = surf.extract_all_edges().n_cells
    assert p.n_points == m.n_points + n_edges + len(m.cells["quad"])
    assert np.allclose(jacobians(p)["quad9"], 1.0, atol=1e-12)
    before = m.to_pyvista().compute_cell_sizes()["Area"]
    after = p.to_pyvista().compute_cell_sizes()["Area"]
    assert np.allclose(after, before, rtol=1e-12)


# ----------------------------------------------------------------------------- files, pyvista
@pytest.mark.parametrize(("base", "k"), list(TYPES))
def test_msh_round_trip(base, k, tmp_path):
    rng = np.random.default_rng(10 + k)
    verts, _, _ = _affine_cell(base, rng)
    p = Mesh(verts, {base: [np.arange(len(verts))]}, cell_refs={base: [3]}).to_order(k)
    back = load(p.save(tmp_path / "p.msh"))
    name = TYPES[base, k]
    assert np.array_equal(back.points, p.points)
    assert list(back.cells) == [name] and np.array_equal(back.cells[name], p.cells[name])
    assert back.cell_refs[name].tolist() == [3]


@pytest.mark.parametrize("name", GMSH_ORDERED)
def test_vtk_files_refuse_gmsh_only_types(name, tmp_path):
    base, k = next(key for key, v in TYPES.items() if v == name)
    verts, _, _ = _affine_cell(base, np.random.default_rng(0))
    p = Mesh(verts, {base: [np.arange(len(verts))]}).to_order(k)
    with pytest.raises(ValueError, match=rf"got \['{name}'\]; .*pick one of \['gmsh'\]"):
        p.save(tmp_path / "p.vtu")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["line3", "line4", "line5", "triangle6", "triangle10",
                                  "triangle15", "tetra10", "quad9", "hexahedron27"])
def test_pyvista_round_trip(name):
    base, k = next(key for key, v in TYPES.items() if v == name)
    verts, _, _ = _affine_cell(base, np.random.default_rng(1))
    p = Mesh(verts, {base: [np.arange(len(verts))]}).to_order(k)
    grid = p.to_pyvista()
    size = {1: "Length", 2: "Area", 3: "Volume"}[CELL_TYPES[name][1]]
    p1 = Mesh(verts, {base: [np.arange(len(verts))]}).to_pyvista().compute_cell_sizes()[size]
    assert np.allclose(grid.compute_cell_sizes()[size], p1, rtol=1e-12)
    back = Mesh.from_pyvista(grid)
    assert list(back.cells) == [name] and np.array_equal(back.cells[name], p.cells[name])


@pytest.mark.parametrize("name", ["tetra20", "tetra35"])
def test_to_pyvista_refuses_tetra20_and_35(name):
    verts, _, _ = _affine_cell("tetra", np.random.default_rng(2))
    p = Mesh(verts, {"tetra": [np.arange(4)]}).to_order(int(name == "tetra35") + 3)
    with pytest.raises(ValueError, match=rf"\['{name}'\].*Lagrange tetrahedron.*\.msh"):
        p.to_pyvista()


def test_from_pyvista_refuses_lagrange_tetra_of_20_nodes():
    grid = pv.UnstructuredGrid(np.r_[20, np.arange(20)].astype(pv.ID_TYPE), np.array([71], np.uint8),
                               np.random.default_rng(3).random((20, 3)))
    with pytest.raises(ValueError, match="LAGRANGE_TETRAHEDRON of 20 nodes"):
        Mesh.from_pyvista(grid)


# ----------------------------------------------------------------------------- API and bad input
def test_order_one_and_api():
    m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
    assert to_order(m, 1) is m and m.to_order(1) is m
    assert wm.to_order is to_order and "to_order" in wm.__all__
    assert wm.numbering.high_order.jacobians is jacobians
    assert np.array_equal(m.to_order(2).cells["triangle6"], to_order(m, 2).cells["triangle6"])


TRI = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
QUAD = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
WEDGE = Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]]),
             {"wedge": [np.arange(6)]})


def test_order_zero():
    with pytest.raises(ValueError, match="'order' 1, 2, 3 or 4, got 0"):
        to_order(TRI, 0)


def test_order_five():
    with pytest.raises(ValueError, match="'order' 1, 2, 3 or 4, got 5"):
        to_order(TRI, 5)


def test_order_float():
    with pytest.raises(TypeError, match="an int for 'order'.*2.5"):
        to_order(TRI, 2.5)


def test_order_string():
    with pytest.raises(TypeError, match="an int for 'order'.*'2'"):
        to_order(TRI, "2")


def test_order_three_on_quads():
    with pytest.raises(ValueError, match=r"'order' in \[1, 2\] for 'quad' cells.*order=3"):
        to_order(QUAD, 3)


def test_wedge_block():
    with pytest.raises(ValueError, match="'wedge' cells"):
        to_order(WEDGE, 2)


def test_already_quadratic_block():
    with pytest.raises(ValueError, match="'triangle6' cells \\(already higher-order\\)"):
        to_order(TRI.to_order(2), 2)


def test_shape_that_is_not_a_shape():
    with pytest.raises(TypeError, match="'shape'"):
        to_order(TRI, 2, shape="sphere")


def test_mesh_that_is_not_a_mesh():
    with pytest.raises(TypeError, match="warpmesh Mesh for 'mesh'"):
        to_order(TRI.to_trimesh(), 2)


def test_bounds_without_shape():
    with pytest.raises(ValueError, match="'shape' with 'bounds'"):
        to_order(TRI, 2, bounds=BOUNDS)


def test_jacobians_without_a_lagrange_block():
    with pytest.raises(ValueError, match="expected a block of the types"):
        jacobians(WEDGE)
