"""The parallel .vtu writer: what meshio's reader and VTK's reader get from its files is
what they get from meshio's own file of the same mesh (wedges as VTK measures them
positive, which meshio's writer reverses), for every cell type, any chunking, any zlib
level; bad input is refused, and a failed write leaves nothing."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
import pyvista as pv
from meshio._common import num_nodes_per_cell
from meshio._mesh import topological_dimension

import warpmesh as wm
from warpmesh.io import vtu


# meshio.Mesh cannot hold wedge15 cells (no topological dimension for them)
MESHIO_TYPES = tuple(t for t in vtu.VTK_CELL_TYPES if t in topological_dimension)


def _mesh(rng, n=200, types=MESHIO_TYPES):
    pts = rng.normal(size=(n, 3)) * rng.choice([1e-7, 1.0, 3e5], (n, 1))
    cells = [(t, rng.integers(0, n, (int(rng.integers(1, 40)), num_nodes_per_cell[t]))) for t in types]
    cells.append(("triangle", rng.integers(0, n, (5, 3))))  # a type in two blocks
    point_data = {"medit:ref": rng.integers(-3, 4, n), "u": rng.normal(size=(n, 3)).astype(np.float32),
                  "tensor": rng.normal(size=(n, 9)), "flag": rng.integers(0, 2, n).astype(np.uint8)}
    cell_data = {"medit:ref": [rng.integers(-50, 10**6, len(c)) for _, c in cells],
                 "q": [rng.normal(size=(len(c), 2)) for _, c in cells]}
    return meshio.Mesh(pts, cells, point_data=point_data, cell_data=cell_data)


def _meshio_write(path, data: meshio.Mesh, **kwargs) -> None:
    """meshio's file of ``data`` with the wedges as ``data`` holds them (its writer reverses
    them: given them reversed, it writes them back as they were)."""
    copy = meshio.Mesh(data.points, [(b.type, b.data) for b in data.cells], point_data=data.point_data,
                       cell_data=data.cell_data)
    meshio.write(path, vtu.meshio_wedges(copy), file_format="vtu", **kwargs)


def _meshio_read(path) -> meshio.Mesh:
    """meshio's reader (not meshio.read, which exits on failure), wedges as the file holds them."""
    return vtu.meshio_wedges(vtu.meshio_vtu.read(str(path)))


def _same_meshio(a: meshio.Mesh, b: meshio.Mesh) -> None:
    np.testing.assert_array_equal(a.points, b.points)
    assert [c.type for c in a.cells] == [c.type for c in b.cells]
    for x, y in zip(a.cells, b.cells):
        np.testing.assert_array_equal(x.data, y.data)
    assert a.point_data.keys() == b.point_data.keys() and a.cell_data.keys() == b.cell_data.keys()
    for k in a.point_data:
        np.testing.assert_array_equal(a.point_data[k], b.point_data[k])
        assert a.point_data[k].dtype == b.point_data[k].dtype
    for k in a.cell_data:
        for x, y in zip(a.cell_data[k], b.cell_data[k]):
            np.testing.assert_array_equal(x, y)


def _same_vtk(a: pv.UnstructuredGrid, b: pv.UnstructuredGrid) -> None:
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.cell_connectivity, b.cell_connectivity)
    np.testing.assert_array_equal(a.cell_offsets, b.cell_offsets)
    np.testing.assert_array_equal(a.celltypes, b.celltypes)
    for mine, theirs in ((a.point_data, b.point_data), (a.cell_data, b.cell_data)):
        assert sorted(mine.keys()) == sorted(theirs.keys())
        for k in mine.keys():
            np.testing.assert_array_equal(mine[k], theirs[k])
            assert mine[k].dtype == theirs[k].dtype


@pytest.mark.parametrize("case", ["default", "level 0", "level 9", "small chunks"])
def test_both_readers_get_what_they_get_from_meshios_file(tmp_path, monkeypatch, case):
    rng = np.random.default_rng(len(case))
    data = _mesh(rng)
    level = {"level 0": 0, "level 9": 9}.get(case, 1)
    if case == "small chunks":  # 64-byte blocks, 3 a chunk: every base64 carry, arrays of one block
        monkeypatch.setattr(vtu, "BLOCK_BYTES", 64)
        monkeypatch.setattr(vtu, "CHUNK_BLOCKS", 3)
        monkeypatch.setattr(vtu, "BLOCKS_PER_TASK", 1)
    vtu.write_vtu(tmp_path / "fast.vtu", data, level=level)
    _meshio_write(tmp_path / "meshio.vtu", data, binary=True)
    _same_meshio(_meshio_read(tmp_path / "fast.vtu"), _meshio_read(tmp_path / "meshio.vtu"))
    _same_vtk(pv.read(tmp_path / "fast.vtu"), pv.read(tmp_path / "meshio.vtu"))


def test_indices_beyond_int32_are_written_as_int64(tmp_path, monkeypatch):
    data = _mesh(np.random.default_rng(3), types=("tetra", "wedge"))
    monkeypatch.setattr(vtu, "_INT32_MAX", 50)
    vtu.write_vtu(tmp_path / "wide.vtu", data)
    text = (tmp_path / "wide.vtu").read_bytes()
    assert b'type="Int64" Name="connectivity"' in text and b'type="Int64" Name="offsets"' in text
    _same_meshio(_meshio_read(tmp_path / "wide.vtu"), data)
    _same_meshio(vtu.read_vtu(tmp_path / "wide.vtu"), data)
    monkeypatch.undo()
    vtu.write_vtu(tmp_path / "narrow.vtu", data)
    assert b'type="Int32" Name="connectivity"' in (tmp_path / "narrow.vtu").read_bytes()


def test_arrays_of_matrices_are_rows_of_components(tmp_path):
    data = _mesh(np.random.default_rng(5), types=("tetra",))
    data.point_data = {"stress": np.random.default_rng(6).normal(size=(len(data.points), 3, 3))}
    vtu.write_vtu(tmp_path / "m.vtu", data)  # meshio's writer makes a file no reader takes
    want = data.point_data["stress"].reshape(-1, 9)
    np.testing.assert_array_equal(meshio.read(tmp_path / "m.vtu").point_data["stress"], want)
    np.testing.assert_array_equal(pv.read(tmp_path / "m.vtu").point_data["stress"], want)


def test_blocks_compressed_on_many_threads_are_zlibs_blocks(monkeypatch):
    raw = np.random.default_rng(0).integers(0, 7, 3_000_000).astype(np.int32).tobytes()
    monkeypatch.setattr(vtu, "usable_cores", lambda: 4)
    sizes, joined = vtu.compress_blocks(memoryview(raw), 1)
    step = vtu.BLOCK_BYTES
    want = [vtu.zlib.compress(raw[k:k + step], 1) for k in range(0, len(raw), step)]
    assert sizes == [len(b) for b in want] and joined == b"".join(want)


def test_a_volume_mesh_saved_and_loaded_through_vtu(tmp_path):
    labels = np.zeros((12, 12, 12), np.uint8)
    labels[2:10, 2:10, 2:10] = 1
    labels[5:10, 5:10, 5:10] = 2
    m = wm.mesh_domain(labels, labels="all", size=2.0)
    path = m.save(tmp_path / "regions.vtu")
    assert b'Name="types" format="binary"' in path.read_bytes()
    back = wm.load(path)
    np.testing.assert_array_equal(back.points, m.points)
    for t in m.cells:
        np.testing.assert_array_equal(back.cells[t], m.cells[t])
        np.testing.assert_array_equal(back.cell_refs[t], m.cell_refs[t])
    grid = pv.read(path)  # VTK: positive volumes per region, as warpmesh measures them
    volumes = grid.compute_cell_sizes(length=False, area=False)["Volume"]
    tets = grid.celltypes == vtu.VTK_CELL_TYPES["tetra"]
    assert np.all(volumes[tets] > 0)
    np.testing.assert_allclose(volumes[tets].sum(), m.stats()["volume"], rtol=1e-9)


def _prisms() -> wm.Mesh:
    """Two layers of wedges over a triangulated 3 x 3 square, each wedge's first triangle
    counter-clockwise seen from its second (warpmesh's, meshio's and gmsh's orientation)."""
    k = 4
    xy = np.stack(np.meshgrid(np.arange(k), np.arange(k), indexing="ij"), -1).reshape(-1, 2) * 0.5
    pts = np.concatenate([np.column_stack([xy, np.full(len(xy), z)]) for z in (0.0, 0.3, 0.7)])
    i, j = np.meshgrid(np.arange(k - 1), np.arange(k - 1), indexing="ij")
    a = (i * k + j).ravel()
    tris = np.concatenate([np.stack([a, a + k, a + k + 1], 1), np.stack([a, a + k + 1, a + 1], 1)])
    n = len(xy)
    wedges = np.concatenate([np.hstack([tris + layer * n, tris + (layer + 1) * n]) for layer in (0, 1)])
    return wm.Mesh(pts, {"wedge": wedges})


@pytest.mark.parametrize("ext", [".vtu", ".vtk"])
def test_wedges_are_saved_as_vtk_measures_them_positive(tmp_path, ext):
    """VTK 9 takes the wedge whose first triangle turns counter-clockwise seen from the
    second as valid (its cell validator, Jacobian and cell sizes); meshio's writers reverse
    each wedge, which VTK then measures negative and calls misoriented."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersGeneral import vtkCellValidator

    def vtk_view(path):
        grid = pv.read(path)
        check = vtkCellValidator()
        check.SetInputData(grid)
        check.Update()
        states = vtk_to_numpy(check.GetOutput().GetCellData().GetArray("ValidityState"))
        return grid.compute_cell_sizes(length=False, area=False)["Volume"], states

    m = _prisms()
    assert m.stats()["volume"] == pytest.approx(1.5 * 1.5 * 0.7)
    path = m.save(tmp_path / f"prisms{ext}")
    volumes, states = vtk_view(path)
    assert np.all(volumes > 0) and not states.any()
    assert volumes.sum() == pytest.approx(1.5 * 1.5 * 0.7)
    back = wm.load(path)
    np.testing.assert_array_equal(back.cells["wedge"], m.cells["wedge"])
    meshios = tmp_path / f"meshio{ext}"  # the reason for the above: meshio's own file of the mesh
    meshio.write(meshios, m.to_meshio(), file_format=ext[1:])
    volumes, states = vtk_view(meshios)
    assert np.all(volumes < 0) and np.all(states == 32)  # vtkCellValidator: faces oriented incorrectly
    np.testing.assert_array_equal(wm.load(meshios).cells["wedge"], m.cells["wedge"][:, vtu.MESHIO_WEDGE_ORDER])


def test_bad_input_is_refused_naming_it(tmp_path):
    data = _mesh(np.random.default_rng(1), types=("tetra",))
    with pytest.raises(ValueError, match="unknown options"):
        vtu.write_vtu(tmp_path / "a.vtu", data, binary=True)
    for level in (-1, 10, 1.5, "1"):
        with pytest.raises(ValueError, match="'level'"):
            vtu.write_vtu(tmp_path / "a.vtu", data, level=level)
    flat = meshio.Mesh(data.points[:, :2], data.cells)
    with pytest.raises(ValueError, match=r"\(n, 3\) float 'points'"):
        vtu.write_vtu(tmp_path / "a.vtu", flat)
    quartic = meshio.Mesh(data.points, [("triangle15", np.zeros((1, 15), int))])
    with pytest.raises(ValueError, match=r"no VTK type for \['triangle15'\]"):
        vtu.write_vtu(tmp_path / "a.vtu", quartic)
    flags = meshio.Mesh(data.points, data.cells, point_data={"inside": np.ones(len(data.points), bool)})
    with pytest.raises(ValueError, match="cannot hold bool data: 'inside'"):
        vtu.write_vtu(tmp_path / "a.vtu", flags)
    short = meshio.Mesh(data.points, data.cells)
    short.point_data = {"u": np.ones(3)}  # (meshio.Mesh refuses it)
    with pytest.raises(ValueError, match="values in data array 'u'"):
        vtu.write_vtu(tmp_path / "a.vtu", short)
    ragged = meshio.Mesh(data.points, data.cells)
    ragged.cell_data = {"q": []}
    with pytest.raises(ValueError, match="an array per cell block in cell data 'q'"):
        vtu.write_vtu(tmp_path / "a.vtu", ragged)
    assert not list(tmp_path.iterdir())


def test_a_failed_write_leaves_nothing_and_keeps_the_old_file(tmp_path, monkeypatch):
    m = wm.Mesh(np.eye(3), {"triangle": np.array([[0, 1, 2]])})
    path = m.save(tmp_path / "t.vtu")
    before = path.read_bytes()

    def full(raw, level):
        raise OSError("disk full")

    monkeypatch.setattr(vtu, "compress_blocks", full)
    with pytest.raises(OSError, match="disk full"):
        m.save(path)
    with pytest.raises(OSError, match="disk full"):
        m.save(tmp_path / "new.vtu")
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == [path.name]


# ----------------------------------------------------------------------------- reading
def _same_read(path) -> meshio.Mesh:
    """read_vtu's mesh of the file equals meshio's reader's, array for array and dtype for
    dtype, but for the wedges, which meshio's reader reverses."""
    mine, theirs = vtu.read_vtu(path), _meshio_read(path)
    _same_meshio(mine, theirs)
    assert mine.field_data.keys() == theirs.field_data.keys()
    for k in theirs.field_data:
        np.testing.assert_array_equal(mine.field_data[k], theirs.field_data[k])
    for k in theirs.point_data:
        assert mine.point_data[k].shape == theirs.point_data[k].shape
    for k in theirs.cell_data:
        assert [x.shape for x in mine.cell_data[k]] == [x.shape for x in theirs.cell_data[k]]
    return mine


VTK_WRITERS = ["vtk binary zlib", "vtk binary none", "vtk appended zlib", "vtk appended none", "vtk base64 zlib",
               "vtk base64 none", "vtk ascii none", "vtk appended zlib UInt64", "vtk binary none UInt64"]


@pytest.mark.parametrize("writer", ["warpmesh", "warpmesh small blocks", "meshio zlib", "meshio raw",
                                    "meshio ascii", *VTK_WRITERS])
def test_read_vtu_gets_meshios_mesh_from_every_writer(tmp_path, monkeypatch, writer):
    rng = np.random.default_rng(len(writer))
    types = MESHIO_TYPES if writer.startswith(("warpmesh", "meshio")) else ("tetra", "triangle", "wedge", "quad")
    data = _mesh(rng, types=types)
    path = tmp_path / "m.vtu"
    if writer.startswith("warpmesh"):
        if writer.endswith("small blocks"):
            monkeypatch.setattr(vtu, "BLOCK_BYTES", 48)
            monkeypatch.setattr(vtu, "BLOCKS_PER_TASK", 2)
        vtu.write_vtu(path, data)
        monkeypatch.undo()
    elif writer.startswith("meshio"):
        kw = {"meshio zlib": {}, "meshio raw": {"compression": None}, "meshio ascii": {"binary": False}}[writer]
        _meshio_write(path, data, **kw)
    else:  # VTK's own writer, through pyvista
        grid = pv.UnstructuredGrid({vtu.VTK_CELL_TYPES[c.type]: c.data for c in data.cells[:-1]}, data.points)
        grid.point_data["u"] = data.point_data["u"]
        grid.point_data["flag"] = data.point_data["flag"]
        grid.cell_data["q"] = rng.normal(size=grid.n_cells)
        grid.field_data["TimeValue"] = [1.5]
        _vtk_write(grid, path, *writer.split()[1:])
    back = _same_read(path)
    assert sum(len(c.data) for c in back.cells) >= len(types)
    assert writer.startswith(("warpmesh", "meshio")) or back.field_data["TimeValue"].tolist() == [1.5]


def _vtk_write(grid, path, mode: str, compressor: str, header: str = "UInt32") -> None:
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    w = vtkXMLUnstructuredGridWriter()
    w.SetFileName(str(path))
    w.SetInputData(grid)
    {"binary": w.SetDataModeToBinary, "ascii": w.SetDataModeToAscii}.get(mode, w.SetDataModeToAppended)()
    w.SetEncodeAppendedData(mode == "base64")
    w.SetCompressorTypeToZLib() if compressor == "zlib" else w.SetCompressorTypeToNone()
    w.SetHeaderTypeToUInt64() if header == "UInt64" else w.SetHeaderTypeToUInt32()
    assert w.Write() == 1
    text = path.read_bytes()
    assert (b'format="appended"' in text) == (mode in ("appended", "base64"))
    assert (b'encoding="raw"' in text) == (mode == "appended") and (b"vtkZLib" in text) == (compressor == "zlib")


def test_read_vtu_joins_pieces_as_vtk_does(tmp_path):
    """(meshio's reader keeps only the last piece's cells: VTK is the reference here.)"""
    rng = np.random.default_rng(9)
    first, second = tmp_path / "a.vtu", tmp_path / "b.vtu"
    vtu.write_vtu(first, _mesh(rng, types=("tetra", "triangle")))
    vtu.write_vtu(second, _mesh(rng, n=50, types=("quad", "tetra")))
    a, b = first.read_bytes(), second.read_bytes()
    piece = b[b.index(b"<Piece"):b.index(b"</UnstructuredGrid>")]
    (tmp_path / "two.vtu").write_bytes(a.replace(b"</UnstructuredGrid>", piece + b"</UnstructuredGrid>"))
    back, grid = vtu.read_vtu(tmp_path / "two.vtu"), pv.read(tmp_path / "two.vtu")
    assert len(back.points) == 250 and back.cells[-1].data.max() >= 200
    np.testing.assert_array_equal(back.points, grid.points)
    np.testing.assert_array_equal(np.concatenate([c.data.ravel() for c in back.cells]), grid.cell_connectivity)
    np.testing.assert_array_equal(np.concatenate([np.full(len(c.data), vtu.VTK_CELL_TYPES[c.type]) for c in back.cells]),
                                  grid.celltypes)
    for k in ("medit:ref", "u", "tensor", "flag"):
        np.testing.assert_array_equal(back.point_data[k], grid.point_data[k])
    for k in ("medit:ref", "q"):
        np.testing.assert_array_equal(np.concatenate(back.cell_data[k]), grid.cell_data[k])


def test_read_vtu_refuses_cut_and_corrupt_files_naming_them(tmp_path):
    path = tmp_path / "m.vtu"
    vtu.write_vtu(path, _mesh(np.random.default_rng(2), types=("tetra",)))
    whole = path.read_bytes()
    for cut in np.linspace(0.05, 0.98, 30):
        (tmp_path / "cut.vtu").write_bytes(whole[:int(len(whole) * cut)])
        with pytest.raises(wm.ReadError, match=r"could not read '.*cut\.vtu' as vtu \(a cut or corrupt file\?\)"):
            vtu.read_vtu(tmp_path / "cut.vtu")
    at = whole.index(b'Name="connectivity"') + 200  # a byte of the compressed blocks changed
    (tmp_path / "bad.vtu").write_bytes(whole[:at] + (b"A" if whole[at:at + 1] != b"A" else b"B") + whole[at + 1:])
    with pytest.raises(wm.ReadError, match="bad.vtu"):
        vtu.read_vtu(tmp_path / "bad.vtu")
    (tmp_path / "image.vtu").write_bytes(whole.replace(b'type="UnstructuredGrid"', b'type="ImageData"', 1))
    with pytest.raises(wm.ReadError, match="UnstructuredGrid"):
        vtu.read_vtu(tmp_path / "image.vtu")


def test_other_compressors_and_polyhedra_go_to_meshios_reader(tmp_path, monkeypatch):
    data = _mesh(np.random.default_rng(4), types=("tetra", "wedge"))
    _meshio_write(tmp_path / "lzma.vtu", data, compression="lzma")
    calls = []
    real = vtu.meshio_vtu.read
    monkeypatch.setattr(vtu.meshio_vtu, "read", lambda p: calls.append(p) or real(p))
    back = vtu.read_vtu(tmp_path / "lzma.vtu")  # the wedges as the file holds them, as from the fast path
    _same_meshio(back, vtu.meshio_wedges(real(tmp_path / "lzma.vtu")))
    assert [b.type for b in back.cells] == [b.type for b in data.cells]
    for mine, given in zip(back.cells, data.cells):
        np.testing.assert_array_equal(mine.data, given.data)
    grid = pv.UnstructuredGrid({7: np.array([[0, 1, 2, 3, 4]])}, np.random.default_rng(0).random((5, 3)))
    grid.save(tmp_path / "polygon.vtu")
    assert vtu.read_vtu(tmp_path / "polygon.vtu").cells[0].type == "polygon"
    assert len(calls) == 2


def test_read_vtu_reads_files_with_string_arrays_meshio_refuses(tmp_path):
    grid = pv.UnstructuredGrid({10: np.array([[0, 1, 2, 3]])}, np.eye(4, 3))
    grid.field_data["TimeValue"] = [1.5]
    grid.field_data["label"] = ["frog"]  # VTK's String <Array>: meshio's reader gives up
    grid.save(tmp_path / "s.vtu")
    with pytest.raises(meshio.ReadError, match="String"):
        vtu.meshio_vtu.read(str(tmp_path / "s.vtu"))  # (meshio.read would call sys.exit)
    back = vtu.read_vtu(tmp_path / "s.vtu")
    assert back.cells[0].data.tolist() == [[0, 1, 2, 3]] and back.field_data["TimeValue"].tolist() == [1.5]
    assert wm.load(tmp_path / "s.vtu").n_cells == 1
