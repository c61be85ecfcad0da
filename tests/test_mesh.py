"""warpmesh.mesh: construction checks, statistics, conversions and file round trips."""

from __future__ import annotations

import itertools
import warnings

import meshio
import numpy as np
import pytest
import pyvista as pv
import trimesh

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.errors import ReadError, WarpMeshError
from warpmesh.mesh import FILE_FORMATS, REF_KEY, Mesh, load

TRI = [[0, 1, 2]]
PTS2 = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]


@pytest.fixture(scope="module")
def surface() -> Mesh:
    """An icosphere with refs and data on points and triangles."""
    tm = trimesh.creation.icosphere(subdivisions=1, radius=1.25)
    n, m = len(tm.vertices), len(tm.faces)
    return Mesh(
        tm.vertices,
        {"triangle": tm.faces},
        point_refs=np.arange(n) % 4 + 1,
        cell_refs={"triangle": np.arange(m) % 3 + 1},
        point_data={"temp": np.linspace(0.0, 1.0, n)},
        cell_data={"q": {"triangle": np.linspace(2.0, 3.0, m)}},
        info={"time": {"emit": 0.25}, "resolution": 32},
    )


def _unit_cube_tetra() -> Mesh:
    """The unit cube as 6 positive Kuhn tetrahedra, its 12 boundary triangles and 1 line."""
    corners = np.array(list(itertools.product([0, 1], repeat=3)))[:, ::-1].astype(
        float
    )  # i = x + 2y + 4z
    tets = []
    for perm in itertools.permutations(range(3)):
        path = [0]
        for axis in perm:
            path.append(path[-1] + 2**axis)
        tets.append(path)
    tets = np.array(tets)
    p = corners[tets]
    neg = (
        np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) < 0
    )
    tets[neg] = tets[neg][:, [1, 0, 2, 3]]
    faces = tets[:, [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]].reshape(
        -1, 3
    )  # outward for positive tets
    _, inverse, counts = np.unique(
        np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    boundary = faces[counts[inverse.ravel()] == 1]
    return Mesh(
        corners,
        {"tetra": tets, "triangle": boundary, "line": [[0, 7]]},
        cell_refs={"tetra": np.full(6, 3), "triangle": np.arange(12) // 2 + 1, "line": [9]},
        point_refs=np.arange(8) + 10,
    )


@pytest.fixture(scope="module")
def cube() -> Mesh:
    return _unit_cube_tetra()


# ------------------------------------------------------------------------- construction
def test_construction_converts_dtypes_and_freezes():
    pts = np.array(PTS2, dtype=np.float32)
    faces = np.array(TRI, dtype=np.int32)
    m = Mesh(pts, {"triangle": faces})
    assert m.points.dtype == REAL_DTYPE and m.triangles.dtype == INDEX_DTYPE
    assert (m.n_points, m.n_cells, m.dim) == (3, 1, 2)
    with pytest.raises(ValueError):
        m.points[0, 0] = 5.0
    faces[0, 0] = 2  # the mesh holds its own copy
    assert m.triangles[0, 0] == 0


def test_cells_as_list_of_pairs_or_meshio_blocks():
    a = Mesh(PTS2, [("triangle", TRI), ("line", [[0, 1]])])
    b = Mesh(
        PTS2,
        [meshio.CellBlock("triangle", np.array(TRI)), meshio.CellBlock("line", np.array([[0, 1]]))],
    )
    assert list(a.cells) == list(b.cells) == ["triangle", "line"]
    assert Mesh(PTS2, {"line": [[0, 1]]}).triangles.shape == (0, 3)
    assert Mesh(PTS2, {}).n_cells == 0


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"points": [[0, 0], [np.nan, 0], [0, 1]]}, ValueError, "finite coordinates in 'points'"),
        (
            {"points": [0.0, 1.0, 2.0]},
            ValueError,
            r"'points' of shape \(n, 2\) or \(n, 3\), got shape \(3,\)",
        ),
        ({"points": np.zeros((3, 4))}, ValueError, r"got shape \(3, 4\)"),
        ({"points": [["a", "b"]] * 3}, TypeError, "float array for 'points'"),
        (
            {"cells": {"triangle": [[0, 1, 3]]}},
            ValueError,
            r"indices < n_points = 3 in cells\['triangle'\], got 3",
        ),
        ({"cells": {"triangle": [[0, -1, 2]]}}, ValueError, "non-negative indices"),
        ({"cells": {"trinagle": TRI}}, ValueError, r"unknown cell type 'trinagle'.*'triangle'"),
        (
            {"cells": {"triangle": [[0, 1]]}},
            ValueError,
            r"cells\['triangle'\] of shape \(m, 3\).*got shape \(1, 2\)",
        ),
        (
            {"cells": {"triangle": [[0.0, 1.0, 2.0]]}},
            TypeError,
            r"integer array for cells\['triangle'\]",
        ),
        ({"cells": np.array(TRI)}, TypeError, "e.g. cells="),
        ({"cells": [("triangle", TRI), ("triangle", TRI)]}, ValueError, "twice"),
        (
            {"cells": {"tetra": [[0, 1, 2, 2]]}},
            ValueError,
            "2D cells for 2D 'points', got 3D 'tetra'",
        ),
        ({"point_refs": [1, 2]}, ValueError, r"'point_refs' of length 3, got shape \(2,\)"),
        ({"point_refs": [1.5, 2, 3]}, TypeError, "integer array for 'point_refs'"),
        ({"cell_refs": {"quad": [1]}}, ValueError, "cell_refs keys among"),
        ({"cell_refs": [1]}, TypeError, "dict for 'cell_refs'"),
        ({"point_data": {"t": [1.0, 2.0]}}, ValueError, r"point_data\['t'\] of length 3"),
        ({"cell_data": {"q": [1.0]}}, TypeError, r"dict for 'cell_data\['q'\]'"),
        (
            {"cell_data": {"q": {"line": [1.0]}}},
            ValueError,
            r"cell_data\['q'\] keys \['triangle'\]",
        ),
        ({"point_data": {REF_KEY: [1, 2, 3]}}, ValueError, "pass it as point_refs"),
        # names and values every file format can hold (an int name broke the .vtu writer, a
        # newline in a name made .msh files no reader takes, object arrays failed mid-write)
        ({"point_data": {3: [1, 2, 3]}}, ValueError, "point_data names that are non-empty printable strings, got 3"),
        ({"cell_data": {"a\nb": {"triangle": [1.0]}}}, ValueError, r"cell_data names .*got 'a\\nb'"),
        ({"point_data": {"a": np.array([None, 1, "x"], object)}}, ValueError,
         r"numbers \(bool, int or float\) in point_data\['a'\], got object values"),
        ({"cell_data": {"z": {"triangle": [1j]}}}, ValueError, r"in cell_data\['z'\]\['triangle'\], got complex128"),
    ],
)
def test_bad_input_is_named(kwargs, error, message):
    args = {"points": PTS2, "cells": {"triangle": TRI}, **kwargs}
    with pytest.raises(error, match=message):
        Mesh(args.pop("points"), args.pop("cells"), **args)


def test_replace_returns_a_new_mesh(surface):
    other = surface.replace(point_refs=None, info={})
    assert other is not surface and other.point_refs is None and surface.point_refs is not None
    assert other.stats()["np"] == surface.n_points and "time" not in other.stats()
    with pytest.raises(TypeError, match="keywords among"):
        surface.replace(colour="red")


def test_empty_mesh_stats():
    s = Mesh(np.zeros((0, 3)), {}).stats()
    assert (s["np"], s["ne"], s["n_cells"]) == (0, 0, 0)
    assert s["euler"] is None and s["mean_q"] is None and s["bounds"] is None


def test_stats_returns_a_fresh_dict(surface):
    s = surface.stats()
    s["np"] = -1
    assert surface.stats()["np"] == 42
    with pytest.raises(ValueError):
        s["bounds"][0, 0] = 7.0


def test_repr(surface, cube):
    assert repr(surface) == "Mesh(np=42, dim=3, cells={triangle: 80}, point_refs, cell_refs)"
    assert (
        repr(cube)
        == "Mesh(np=8, dim=3, cells={tetra: 6, triangle: 12, line: 1}, point_refs, cell_refs)"
    )


# ------------------------------------------------------------------------- statistics
def test_stats_of_a_sphere(surface, check_mesh):
    check_mesh(surface)
    tm = surface.to_trimesh()
    s = surface.stats()
    assert (s["np"], s["ne"], s["n_triangles"], s["n_tetra"]) == (42, 80, 80, 0)
    assert s["watertight"] and s["manifold"] and s["oriented"]
    assert (s["euler"], s["components"], s["genus"]) == (2, 1, 0)
    assert s["area"] == pytest.approx(tm.area, rel=1e-12)
    assert s["volume"] == pytest.approx(tm.volume, rel=1e-12) and s["volume"] > 0
    assert 1.0 <= s["mean_q"] <= s["worst_q"] < 1.5
    np.testing.assert_allclose(s["bounds"], [[-1.25] * 3, [1.25] * 3])
    assert s["time"] == {"emit": 0.25} and s["resolution"] == 32
    assert len(surface.edges) == 120


def test_stats_of_a_torus_and_two_spheres():
    torus = Mesh.from_trimesh(
        trimesh.creation.torus(1.0, 0.3, major_sections=24, minor_sections=12)
    )
    assert (torus.stats()["euler"], torus.stats()["genus"]) == (0, 1)
    two = trimesh.util.concatenate(
        [trimesh.creation.icosphere(1), trimesh.creation.icosphere(1).apply_translation([3, 0, 0])]
    )
    s = Mesh.from_trimesh(two).stats()
    assert (s["euler"], s["components"], s["genus"]) == (4, 2, 0)


def test_stats_of_open_and_flipped_surfaces(surface):
    opened = surface.replace(
        cells={"triangle": surface.triangles[1:]}, cell_refs=None, cell_data=None
    )
    s = opened.stats()
    assert not s["watertight"] and s["euler"] == 1 and s["genus"] is None and s["volume"] is None
    flipped = surface.triangles.copy()
    flipped[0] = flipped[0, ::-1]
    s = surface.replace(cells={"triangle": flipped}).stats()
    assert s["watertight"] and not s["oriented"] and s["genus"] is None


def test_stats_of_a_2d_square():
    sq = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
    s = sq.stats()
    assert s["area"] == 1.0 and s["volume"] is None and not s["watertight"] and s["euler"] == 1
    assert s["mean_q"] == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3))


def test_stats_of_a_tetra_mesh(cube, check_mesh):
    check_mesh(cube)  # the boundary triangles
    s = cube.stats()
    assert (s["ne"], s["n_tetra"], s["n_triangles"], s["n_cells"]) == (6, 6, 12, 19)
    assert s["volume"] == pytest.approx(1.0, rel=1e-14)
    assert s["mean_q"] == pytest.approx(s["worst_q"])  # Kuhn tetrahedra are congruent


# ------------------------------------------------------------------------- conversions
def test_trimesh_round_trip_merges_nothing():
    pts = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]], float
    )  # point 3 duplicates point 0
    m = Mesh(pts, {"triangle": [[0, 1, 2], [3, 2, 1]]}, point_refs=[1, 2, 3, 4])
    tm = m.to_trimesh()
    assert len(tm.vertices) == 4 and tm.vertex_attributes[REF_KEY].tolist() == [1, 2, 3, 4]
    back = Mesh.from_trimesh(tm)
    np.testing.assert_array_equal(back.points, m.points)
    np.testing.assert_array_equal(back.triangles, m.triangles)
    assert back.point_refs.tolist() == [1, 2, 3, 4]


def test_to_trimesh_needs_triangles():
    with pytest.raises(ValueError, match="expected a 'triangle' block"):
        Mesh(PTS2, {"line": [[0, 1]]}).to_trimesh()


def _assert_same(a: Mesh, b: Mesh, *, refs=True, data=True):
    np.testing.assert_array_equal(a.points, b.points)
    assert list(a.cells) == list(b.cells)
    for t in a.cells:
        np.testing.assert_array_equal(a.cells[t], b.cells[t])
    if refs:
        np.testing.assert_array_equal(a.point_refs, b.point_refs)
        assert (a.cell_refs is None) == (b.cell_refs is None)
        for t in a.cell_refs or {}:
            np.testing.assert_array_equal(a.cell_refs[t], b.cell_refs[t])
    if data:
        assert set(a.point_data) == set(b.point_data) and set(a.cell_data) == set(b.cell_data)
        for k in a.point_data:
            np.testing.assert_array_equal(a.point_data[k], b.point_data[k])
        for k in a.cell_data:
            for t in a.cells:
                np.testing.assert_array_equal(a.cell_data[k][t], b.cell_data[k][t])


def test_meshio_round_trip(surface, cube):
    for m in (surface, cube):
        mm = m.to_meshio()
        assert REF_KEY in mm.cell_data and len(mm.cell_data[REF_KEY]) == len(m.cells)
        _assert_same(Mesh.from_meshio(mm), m)


def test_from_meshio_concatenates_blocks_and_reads_gmsh_tags():
    mm = meshio.Mesh(
        np.array(PTS2 + [[1.0, 1.0]]),
        [("triangle", np.array(TRI)), ("triangle", np.array([[1, 3, 2]]))],
        cell_data={
            "gmsh:physical": [np.array([5]), np.array([6])],
            "gmsh:geometrical": [np.array([5]), np.array([6])],
        },
    )
    m = Mesh.from_meshio(mm)
    assert m.triangles.tolist() == [[0, 1, 2], [1, 3, 2]]
    assert m.cell_refs["triangle"].tolist() == [5, 6] and not m.cell_data


def test_pyvista_surface_round_trip(surface):
    pd = surface.to_pyvista()
    assert isinstance(pd, pv.PolyData) and pd.n_cells == 80 and pd.is_all_triangles
    assert pd.area == pytest.approx(surface.stats()["area"])
    _assert_same(Mesh.from_pyvista(pd), surface)


def test_pyvista_volume_round_trip(cube):
    ug = cube.to_pyvista()
    assert isinstance(ug, pv.UnstructuredGrid) and ug.n_cells == 19
    sizes = ug.compute_cell_sizes()["Volume"][:6]
    np.testing.assert_allclose(sizes, 1 / 6)
    _assert_same(Mesh.from_pyvista(ug), cube)


def test_pyvista_wedge_has_positive_volume():
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]]
    m = Mesh(pts, {"wedge": [[0, 1, 2, 3, 4, 5]]})
    assert m.to_pyvista().compute_cell_sizes()["Volume"][0] == pytest.approx(0.5)
    _assert_same(Mesh.from_pyvista(m.to_pyvista()), m)


def test_pyvista_quads_voxels_and_2d():
    assert Mesh.from_pyvista(pv.Cube()).cells["quad"].shape == (6, 4)
    hexes = Mesh.from_pyvista(pv.ImageData(dimensions=(3, 3, 3), spacing=(0.5, 0.5, 0.5)))
    assert hexes.cells["hexahedron"].shape == (8, 8)
    np.testing.assert_allclose(hexes.to_pyvista().compute_cell_sizes()["Volume"], 0.125)
    flat = Mesh.from_pyvista(pv.ImageData(dimensions=(3, 3, 1)), dim=2)
    assert flat.dim == 2 and flat.cells["quad"].shape == (4, 4)


def test_pyvista_polygons_need_triangulate():
    pentagon = pv.PolyData(
        np.array([[0, 0, 0], [1, 0, 0], [1.5, 0.5, 0], [1, 1, 0], [0, 1, 0]], float),
        faces=[5, 0, 1, 2, 3, 4],
    )
    with pytest.raises(ValueError, match="triangulate=True"):
        Mesh.from_pyvista(pentagon)
    m = Mesh.from_pyvista(pentagon, triangulate=True)
    assert m.triangles.shape == (3, 3) and m.stats()["area"] == pytest.approx(pentagon.area)


def test_from_pyvista_rejects_other_objects():
    with pytest.raises(TypeError, match="pyvista.DataSet for 'obj'"):
        Mesh.from_pyvista(np.zeros((3, 3)))


# ------------------------------------------------------------------------- files
# extension -> (points exact?, what survives besides points and cells)
ROUND_TRIPS = {
    ".vtu": (True, {"point_refs", "cell_refs", "point_data", "cell_data"}),
    ".pvtu": (True, {"point_refs", "cell_refs", "point_data", "cell_data"}),
    ".vtk": (True, {"point_refs", "cell_refs", "point_data", "cell_data"}),
    ".msh": (True, {"point_refs", "cell_refs", "point_data", "cell_data"}),
    ".mesh": (True, {"point_refs", "cell_refs"}),
    ".ply": (True, {"point_refs", "cell_refs", "point_data", "cell_data"}),
    ".obj": (True, set()),
    ".stl": (False, set()),
}


def test_every_format_is_covered():
    assert set(ROUND_TRIPS) == set(FILE_FORMATS)


@pytest.mark.parametrize("ext", list(ROUND_TRIPS))
def test_surface_file_round_trip(surface, tmp_path, ext):
    exact, keeps = ROUND_TRIPS[ext]
    path = tmp_path / f"sphere{ext}"
    all_kept = keeps == {"point_refs", "cell_refs", "point_data", "cell_data"}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert surface.save(path) == path
    assert bool(caught) != all_kept, [str(w.message) for w in caught]
    pieces = ["sphere_0.vtu"] if ext == ".pvtu" else []  # a .pvtu names its piece beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name, *pieces]  # no temporary left behind
    back = load(path)
    assert bool(back.point_data) == ("point_data" in keeps)
    assert bool(back.cell_data) == ("cell_data" in keeps)
    if not exact:  # STL: float32, points merged and renumbered; compare the triangles' corners
        corners = lambda m: np.sort(m.points[m.triangles].reshape(len(m.triangles), -1), axis=0)  # noqa: E731
        np.testing.assert_allclose(corners(back), corners(surface), atol=1e-6)
        assert back.stats()["watertight"]
        return
    _assert_same(back, surface, refs=False, data=False)
    assert ("point_refs" in keeps) == (back.point_refs is not None)
    assert ("cell_refs" in keeps) == (back.cell_refs is not None)
    if "point_refs" in keeps:
        np.testing.assert_array_equal(back.point_refs, surface.point_refs)
    if "cell_refs" in keeps:
        np.testing.assert_array_equal(back.cell_refs["triangle"], surface.cell_refs["triangle"])
    if "point_data" in keeps:
        np.testing.assert_array_equal(back.point_data["temp"], surface.point_data["temp"])
    if "cell_data" in keeps:
        np.testing.assert_array_equal(
            back.cell_data["q"]["triangle"], surface.cell_data["q"]["triangle"]
        )


@pytest.mark.parametrize("ext", [".vtu", ".vtk", ".msh", ".mesh"])
def test_volume_file_round_trip(cube, tmp_path, ext):
    path = cube.save(tmp_path / f"cube{ext}")
    back = load(path)
    _assert_same(back, cube)
    assert back.stats()["volume"] == pytest.approx(1.0)


@pytest.mark.parametrize("ext", [".mesh", ".vtu", ".msh"])
def test_2d_file_round_trip(tmp_path, ext):
    m = Mesh(
        [[0, 0], [1, 0], [1, 1], [0, 1]],
        {"triangle": [[0, 1, 2], [0, 2, 3]], "line": [[0, 1]]},
        cell_refs={"line": [4]},
    )
    path = m.save(tmp_path / f"square{ext}")
    back = Mesh.load(path, dim=2)
    assert back.dim == 2
    _assert_same(back, m, refs=False)
    assert back.cell_refs["line"].tolist() == [4] and back.cell_refs["triangle"].tolist() == [0, 0]
    if ext == ".mesh":
        assert load(path).dim == 2  # Medit stores the dimension
    else:
        assert load(path).dim == 3 and load(path, dim=3).dim == 3


def test_load_dim2_rejects_nonzero_z(surface, tmp_path):
    path = surface.save(tmp_path / "s.vtu")
    with pytest.raises(ValueError, match="z == 0") as info:
        load(path, dim=2)
    assert not isinstance(info.value, ReadError)  # a bad argument, not a bad file
    with pytest.raises(ValueError, match="dim None, 2 or 3"):
        load(path, dim=4)


def test_save_with_explicit_format(surface, tmp_path):
    path = surface.save(tmp_path / "sphere.dat", file_format="vtu")
    assert load(path, file_format="vtu").n_cells == 80


def test_save_unknown_extension(surface, tmp_path):
    with pytest.raises(ValueError, match=r"unknown mesh file extension '\.xyz'.*'\.vtu'"):
        surface.save(tmp_path / "sphere.xyz")
    assert not list(tmp_path.iterdir())


def test_save_names_a_missing_folder_and_a_bad_path(surface, tmp_path):
    with pytest.raises(FileNotFoundError, match=r"no folder '.*nodir' to save 'a.vtu' in"):
        surface.save(tmp_path / "nodir" / "a.vtu")
    with pytest.raises(TypeError, match="expected a str or os.PathLike 'path', got int"):
        surface.save(3)
    assert not list(tmp_path.iterdir())


def test_save_unknown_format(surface, tmp_path):
    with pytest.raises(ValueError, match=r"unknown file_format 'acad'; expected one of \[.*'abaqus'"):
        surface.save(tmp_path / "sphere.vtu", file_format="acad")
    back = load(surface.save(tmp_path / "sphere.vtu", file_format="abaqus"), file_format="abaqus")
    assert back.n_cells == surface.n_cells  # meshio's other formats by name too (an .inp in a .vtu)


def test_save_cells_the_format_cannot_store(cube, tmp_path):
    with pytest.raises(
        ValueError,
        match=r"obj \(\.obj\) files store only \['triangle', 'quad'\] cells, "
        r"got \['tetra', 'line'\]",
    ):
        cube.save(tmp_path / "cube.obj")
    assert not list(tmp_path.iterdir())


def test_save_warns_about_what_the_format_drops(surface, tmp_path):
    with pytest.warns(UserWarning, match=r"stl files cannot store \['medit:ref', 'q', 'temp'\]"):
        surface.save(tmp_path / "sphere.stl")


def _is_ascii(data: bytes) -> bool:
    return all(0 < c < 128 for c in data)


@pytest.mark.parametrize("ext", [".vtk", ".ply", ".stl"])
def test_save_binary_false_writes_ascii_that_reads_back_the_same(surface, tmp_path, ext):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # stl drops the refs and data
        text = load(surface.save(tmp_path / f"text{ext}", binary=False))
        raw = load(surface.save(tmp_path / f"raw{ext}"))
        assert load(surface.save(tmp_path / f"raw2{ext}", binary=True)).n_cells == raw.n_cells
    assert _is_ascii((tmp_path / f"text{ext}").read_bytes())
    assert not _is_ascii((tmp_path / f"raw{ext}").read_bytes())  # the default stays binary
    assert (tmp_path / f"raw{ext}").read_bytes() == (tmp_path / f"raw2{ext}").read_bytes()
    np.testing.assert_array_equal(text.triangles, raw.triangles)
    np.testing.assert_allclose(text.points, raw.points, rtol=1e-6, atol=1e-12)
    assert (text.cell_refs is None) == (raw.cell_refs is None)
    if raw.cell_refs is not None:
        np.testing.assert_array_equal(text.cell_refs["triangle"], raw.cell_refs["triangle"])


def test_save_binary_is_refused_where_the_format_has_one_encoding(surface, tmp_path):
    for ext, name in ((".vtu", "vtu"), (".mesh", "medit"), (".obj", "obj")):
        with pytest.raises(ValueError, match=rf"expected binary=None for a {name} file \(written in one encoding\); "
                                             r"'binary' chooses between binary and ascii for vtk, ply, stl"):
            surface.save(tmp_path / f"s{ext}", binary=False)
    with pytest.raises(ValueError, match=r"expected binary=None for a gmsh file \(meshio's ascii gmsh writer puts "
                                         r"numpy 2's repr"):
        surface.save(tmp_path / "s.msh", binary=False)
    with pytest.raises(TypeError, match="expected True, False or None for 'binary', got str"):
        surface.save(tmp_path / "s.ply", binary="no")
    assert not list(tmp_path.iterdir())


def test_gmsh_drops_cell_data_of_several_blocks(cube, tmp_path):
    m = cube.replace(cell_data={"q": {t: np.ones(len(c)) for t, c in cube.cells.items()}})
    with pytest.warns(UserWarning, match=r"gmsh files cannot store \['q'\]"):
        path = m.save(tmp_path / "cube.msh")
    _assert_same(load(path), cube)


def test_failing_save_leaves_no_file(surface, tmp_path, monkeypatch):
    def broken_write(filename, mesh, **kwargs):
        with open(filename, "w") as f:
            f.write("half a mesh")
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", broken_write)
    with pytest.raises(OSError, match="disk full"):
        surface.save(tmp_path / "sphere.vtk")  # (.vtu: tests/io/test_vtu.py)
    assert not list(tmp_path.iterdir())


def test_failing_save_keeps_the_old_file(surface, tmp_path, monkeypatch):
    path = surface.save(tmp_path / "sphere.vtk")
    before = path.read_bytes()
    monkeypatch.setattr(meshio, "write", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        surface.save(path)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == [path.name]


def test_load_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such mesh file"):
        load(tmp_path / "nothing.vtu")


def test_load_unknown_extension(tmp_path):
    (tmp_path / "a.xyz").write_text("hello")
    with pytest.raises(ValueError, match="unknown mesh file extension"):
        load(tmp_path / "a.xyz")


@pytest.mark.parametrize("ext", list(ROUND_TRIPS))
def test_load_unparsable_file(tmp_path, ext):
    path = tmp_path / f"garbage{ext}"
    path.write_bytes(b"this is not a mesh\n\x00\xff\xfe garbage 1 2 3\n")
    with pytest.raises(
        ReadError, match=f"could not read '.*garbage\\{ext}' as {FILE_FORMATS[ext]}"
    ) as info:
        load(path)
    assert isinstance(info.value, WarpMeshError) and isinstance(info.value, ValueError)


def test_load_empty_file(tmp_path):
    path = tmp_path / "empty.obj"
    path.write_text("")
    with pytest.raises(ReadError, match="holds no points"):
        load(path)


def _tri_sphere() -> Mesh:
    t = trimesh.creation.icosphere(subdivisions=2)
    return Mesh(np.asarray(t.vertices), {"triangle": np.asarray(t.faces)})


@pytest.mark.parametrize("ext", list(ROUND_TRIPS))
def test_load_truncated_file(tmp_path, ext):
    """A file cut anywhere is a ReadError naming it, or (OBJ cut at a line end in its faces: the
    format has no terminator) a mesh of some of the faces; never points without cells (issue 19)."""
    mesh = _tri_sphere()
    data = mesh.save(tmp_path / f"whole{ext}").read_bytes()
    faces = {tuple(sorted(f)) for f in mesh.cells["triangle"].tolist()}
    for cut in np.linspace(0.03, 0.97, 25):
        path = tmp_path / f"cut{ext}"
        path.write_bytes(data[: int(len(data) * cut)])
        try:
            part = load(path)
        except ReadError as error:
            assert "cut" in str(error)
            continue
        assert ext == ".obj" and part.n_cells > 0, (ext, cut)
        assert {tuple(sorted(f)) for f in part.cells["triangle"].tolist()} <= faces


def test_load_ply_with_a_truncated_header_does_not_hang(tmp_path):
    """meshio's PLY reader reads lines until 'end_header' forever; warpmesh refuses the file first."""
    path = tmp_path / "head.ply"
    path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 54\nproperty double x\n")
    script = f"import warpmesh as wm\ntry:\n    wm.load({str(path)!r})\nexcept wm.ReadError as e:\n    print(e)\n"
    import subprocess
    import sys
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert "end_header" in run.stdout, run.stderr


def test_load_invalid_mesh_in_a_file(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(ReadError, match="invalid mesh"):
        load(path)


def test_saving_an_empty_mesh_is_refused(tmp_path):
    empty = Mesh(np.zeros((0, 3)), {"triangle": np.zeros((0, 3), dtype=int)})
    for ext in (".ply", ".vtk", ".mesh"):
        with pytest.raises(ValueError, match="empty"):
            empty.save(tmp_path / f"e{ext}")
    assert not list(tmp_path.iterdir())


def test_replace_info_only_shares_the_checked_arrays():
    """replace(info=...) keeps the arrays (checked and frozen once) and changes the info only;
    a Mesh built from read-only arrays that own their memory keeps them without a copy."""
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    tris = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int64)
    pts.setflags(write=False)
    tris.setflags(write=False)
    m = Mesh(pts, {"triangle": tris}, cell_refs={"triangle": [1, 2, 3, 4]}, info={"a": 1})
    assert m.points is pts and m.triangles is tris
    r = m.replace(info={"b": 2})
    assert r.points is m.points and r.triangles is m.triangles and r.cell_refs["triangle"] is m.cell_refs["triangle"]
    assert dict(r.info) == {"b": 2} and dict(m.info) == {"a": 1}
    assert r.stats()["watertight"] and r.stats()["n_triangles"] == 4 and r.stats()["b"] == 2
    with pytest.raises(TypeError, match="info"):
        m.replace(info=[1])


def test_a_mesh_goes_through_pickle_with_its_views_and_info():
    import pickle

    import warpmesh as wm

    vol = np.zeros((8, 8, 8), np.int16)
    vol[2:6, 2:6, 2:4], vol[2:6, 2:6, 4:6] = 1, 2
    for mesh in (wm.mesh_domain(vol, size=2.0), wm.mesh_surface(vol, labels="all", interfaces="shared")):
        back = pickle.loads(pickle.dumps(mesh))
        assert type(back) is Mesh and repr(back) == repr(mesh)
        np.testing.assert_array_equal(back.points, mesh.points)
        for t in mesh.cells:
            np.testing.assert_array_equal(back.cells[t], mesh.cells[t])
            np.testing.assert_array_equal(back.cell_refs[t], mesh.cell_refs[t])
            np.testing.assert_array_equal(back.cell_data["label_above"][t], mesh.cell_data["label_above"][t])
        a, b = back.stats(), mesh.stats()
        for key in ("np", "n_cells", "euler", "area", "self_intersections", "labels", "region_volumes"):
            assert a.get(key) == b.get(key), key
        assert back.info.keys() == mesh.info.keys()
        assert not back.points.flags.writeable
