"""warpmesh's own PLY reader and writer (:mod:`warpmesh.io.ply`): face properties kept
(issue 24 part 5), every encoding and index type, cross-checked with trimesh, pyvista and
meshio, and bad files refused naming the file."""

from __future__ import annotations

import struct
import warnings

import meshio
import numpy as np
import pytest
import pyvista as pv
import trimesh

import warpmesh as wm
from warpmesh.errors import ReadError
from warpmesh.io.ply import read_ply, write_ply


def _mixed(seed: int = 0) -> meshio.Mesh:
    """A quad strip cut so that some cells are triangles, with point and face data."""
    rng = np.random.default_rng(seed)
    n = 12
    pts = np.column_stack([np.repeat(np.arange(n), 2), np.tile([0, 1], n), rng.uniform(-1, 1, 2 * n)])
    quads = np.array([[2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1] for i in range(0, n - 1, 2)])
    tris = np.array([t for i in range(1, n - 1, 2) for t in ([2 * i, 2 * i + 2, 2 * i + 3], [2 * i, 2 * i + 3, 2 * i + 1])])
    return meshio.Mesh(
        pts, [("triangle", tris), ("quad", quads)],
        point_data={"temp": rng.uniform(size=2 * n), "medit:ref": np.arange(2 * n) % 5,
                    "mask": (np.arange(2 * n) % 2).astype(np.uint8)},
        cell_data={"medit:ref": [np.arange(len(tris)) + 10, np.arange(len(quads)) + 50],
                   "label_above": [np.full(len(tris), 3, np.int64), np.full(len(quads), 4, np.int64)],
                   "q": [rng.uniform(size=len(tris)).astype(np.float32), rng.uniform(size=len(quads)).astype(np.float32)]},
    )


def _same(a: meshio.Mesh, b: meshio.Mesh) -> None:
    np.testing.assert_array_equal(np.asarray(a.points, float)[:, :3], np.asarray(b.points, float))
    assert [c.type for c in a.cells] == [c.type for c in b.cells]
    for ca, cb in zip(a.cells, b.cells, strict=True):
        np.testing.assert_array_equal(ca.data, cb.data)
    assert set(a.point_data) == set(b.point_data) and set(a.cell_data) == set(b.cell_data)
    for k in a.point_data:
        np.testing.assert_array_equal(a.point_data[k], b.point_data[k])
        assert b.point_data[k].dtype.kind == np.asarray(a.point_data[k]).dtype.kind
    for k in a.cell_data:
        for x, y in zip(a.cell_data[k], b.cell_data[k], strict=True):
            np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("binary", [True, False])
def test_round_trip_keeps_face_and_vertex_properties(tmp_path, binary):
    m = _mixed()
    back = read_ply(write_ply(tmp_path / "m.ply", m, binary=binary))
    _same(m, back)
    assert back.cell_data["q"][0].dtype == np.float32  # the declared type comes back


def _hand_written(path, order: str, faces: list, refs: list, count="uchar", index="int", name="vertex_indices"):
    """A PLY file written row by row from the spec (independent of write_ply): 4 points,
    ``faces`` in the given order (mixed sizes interleaved), an ``int ref`` per face, and an
    extra element after the faces."""
    pts = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.5), (0.0, 1.0, 0.25)]
    codes = {"uchar": "B", "ushort": "H", "int": "i", "uint": "I", "short": "h", "char": "b"}
    fmt = "ascii" if order == "ascii" else {"<": "binary_little_endian", ">": "binary_big_endian"}[order]
    head = (f"ply\nformat {fmt} 1.0\ncomment hand made\nelement vertex 4\nproperty float x\nproperty float y\n"
            f"property float z\nproperty ushort flag\nelement face {len(faces)}\n"
            f"property list {count} {index} {name}\nproperty int ref\n"
            "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n")
    if order == "ascii":
        body = "".join(f"{x} {y} {z} {i}\n" for i, (x, y, z) in enumerate(pts))
        body += "".join(f"{len(f)} {' '.join(map(str, f))} {r}\n" for f, r in zip(faces, refs))
        body += "0 1\n"
        data = (head + body).encode()
    else:
        data = head.encode()
        data += b"".join(struct.pack(order + "fffH", *p, i) for i, p in enumerate(pts))
        data += b"".join(struct.pack(f"{order}{codes[count]}{len(f)}{codes[index]}i", len(f), *f, r)
                         for f, r in zip(faces, refs))
        data += struct.pack(order + "ii", 0, 1)
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("order", ["<", ">", "ascii"])
@pytest.mark.parametrize("count,index", [("uchar", "int"), ("uchar", "uint"), ("int", "int"), ("ushort", "ushort"),
                                         ("char", "short")])
def test_every_encoding_and_index_type(tmp_path, order, count, index):
    rng = np.random.default_rng(7)
    tris = [[0, 1, 2], [0, 2, 3], [1, 2, 3], [0, 1, 3]]
    quads = [[0, 1, 2, 3], [3, 2, 1, 0]]
    kinds = rng.integers(0, 2, 40)  # interleaved triangles and quads: many runs
    faces = [tris[i % 4] if k == 0 else quads[i % 2] for i, k in enumerate(kinds)]
    refs = list(range(100, 140))
    name = "vertex_index" if count == "int" else "vertex_indices"
    path = _hand_written(tmp_path / "h.ply", order, faces, refs, count, index, name)
    with pytest.warns(UserWarning, match="element 'edge'"):
        m = read_ply(path)
    np.testing.assert_allclose(m.points, [(0, 0, 0), (1, 0, 0), (1, 1, 0.5), (0, 1, 0.25)])
    assert m.point_data["flag"].tolist() == [0, 1, 2, 3] and m.point_data["flag"].dtype == np.uint16
    want_t = [f for f in faces if len(f) == 3]
    want_q = [f for f in faces if len(f) == 4]
    assert [c.type for c in m.cells] == ["triangle", "quad"]
    assert m.cells[0].data.tolist() == want_t and m.cells[1].data.tolist() == want_q
    assert m.cell_data["medit:ref"][0].tolist() == [r for f, r in zip(faces, refs) if len(f) == 3]
    assert m.cell_data["medit:ref"][1].tolist() == [r for f, r in zip(faces, refs) if len(f) == 4]


def test_long_runs_and_many_runs_read_the_same(tmp_path):
    """Runs longer than the first read window (1024 rows) and a run change right after it."""
    faces = [[0, 1, 2]] * 3000 + [[0, 1, 2, 3]] + [[1, 2, 3]] * 1500 + [[0, 1, 2, 3], [0, 2, 3]] * 300
    refs = list(range(len(faces)))
    with pytest.warns(UserWarning):
        m = read_ply(_hand_written(tmp_path / "r.ply", "<", faces, refs))
    is_tri = np.array([len(f) == 3 for f in faces])
    assert m.cells[0].data.tolist() == [f for f in faces if len(f) == 3]
    assert m.cell_data["medit:ref"][0].tolist() == np.flatnonzero(is_tri).tolist()
    assert m.cell_data["medit:ref"][1].tolist() == np.flatnonzero(~is_tri).tolist()


def test_trimesh_and_pyvista_read_what_we_write(tmp_path):
    m = _mixed()
    tri_only = meshio.Mesh(m.points, [m.cells[0]], point_data={"temp": m.point_data["temp"]},
                           cell_data={"medit:ref": [m.cell_data["medit:ref"][0]]})
    for binary in (True, False):
        path = write_ply(tmp_path / f"t{binary}.ply", tri_only, binary=binary)
        t = trimesh.load(path, process=False, force="mesh")
        np.testing.assert_array_equal(t.vertices, m.points)
        np.testing.assert_array_equal(t.faces, m.cells[0].data)
        raw = t.metadata["_ply_raw"]  # trimesh keeps every property there
        np.testing.assert_array_equal(np.ravel(raw["face"]["data"]["ref"]), m.cell_data["medit:ref"][0])
        np.testing.assert_array_equal(np.ravel(raw["vertex"]["data"]["temp"]), m.point_data["temp"])
        p = pv.read(path)
        np.testing.assert_array_equal(p.points, m.points.astype(np.float32))  # VTK reads float32 points
        np.testing.assert_array_equal(p.regular_faces, m.cells[0].data)
        # mixed triangles and quads: VTK keeps the polygons; trimesh reads the ascii file
        # (its binary reader assumes one list length per element)
        path = write_ply(tmp_path / f"m{binary}.ply", m, binary=binary)
        p = pv.read(path)
        assert p.n_cells == len(m.cells[0]) + len(m.cells[1])
        cells = p.irregular_faces
        assert [list(c) for c in cells] == m.cells[0].data.tolist() + m.cells[1].data.tolist()
        if not binary:
            t = trimesh.load(path, process=False, force="mesh")
            np.testing.assert_array_equal(t.vertices, m.points)
            assert len(t.faces) == len(m.cells[0]) + 2 * len(m.cells[1])  # quads split in two


def test_we_read_what_trimesh_and_meshio_write(tmp_path):
    box = trimesh.creation.box()
    box.face_attributes["ref"] = np.arange(12) + 1
    box.vertex_attributes["temp"] = np.arange(8.0) / 8
    for enc in ("binary", "ascii"):
        path = tmp_path / f"tm_{enc}.ply"
        path.write_bytes(trimesh.exchange.ply.export_ply(box, encoding=enc, include_attributes=True))
        m = wm.load(path)
        np.testing.assert_allclose(m.points, box.vertices, rtol=0, atol=1e-7)  # trimesh writes float32 / 8 digits
        np.testing.assert_array_equal(m.triangles, box.faces)
        np.testing.assert_array_equal(m.cell_refs["triangle"], np.arange(12) + 1)
        np.testing.assert_allclose(m.point_data["temp"], np.arange(8.0) / 8)
    mm = _mixed()
    for binary in (True, False):
        path = tmp_path / f"meshio_{binary}.ply"
        meshio.write(path, meshio.Mesh(mm.points, mm.cells, point_data={"temp": mm.point_data["temp"]}),
                     file_format="ply", binary=binary)
        back = read_ply(path)
        np.testing.assert_allclose(back.points, mm.points)
        assert [c.type for c in back.cells] == ["triangle", "quad"]
        for a, b in zip(back.cells, mm.cells, strict=True):
            np.testing.assert_array_equal(a.data, b.data)
        np.testing.assert_allclose(back.point_data["temp"], mm.point_data["temp"])


def test_multi_label_surface_keeps_both_labels_in_ply(tmp_path):
    vol = np.zeros((8, 8, 8), dtype=np.uint8)
    vol[1:7, 1:7, 1:4] = 1
    vol[1:7, 1:7, 4:7] = 3
    m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing dropped
        path = m.save(tmp_path / "labels.ply")
    back = wm.load(path)
    np.testing.assert_array_equal(back.points, m.points)
    np.testing.assert_array_equal(back.triangles, m.triangles)
    np.testing.assert_array_equal(back.cell_refs["triangle"], m.cell_refs["triangle"])
    np.testing.assert_array_equal(back.cell_data["label_above"]["triangle"], m.cell_data["label_above"]["triangle"])
    raw = trimesh.load(path, process=False, force="mesh").metadata["_ply_raw"]["face"]["data"]
    assert sorted({(int(a), int(b)) for a, b in zip(np.ravel(raw["ref"]), np.ravel(raw["label_above"]))}) == [(0, 1), (0, 3), (1, 3)]


def _tri_file(tmp_path, faces_line: str, n_faces: int = 1):
    path = tmp_path / "bad.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    f"element face {n_faces}\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n1 0 0\n0 1 0\n1 1 0\n" + faces_line)
    return path


@pytest.mark.parametrize("case,text,match", [
    ("pentagon", "5 0 1 2 3 0\n", r"faces of \[5\] vertices.*triangulate"),
    ("edge as face", "2 0 1\n", r"faces of \[2\] vertices"),
    ("index out of range", "3 0 1 7\n", "outside 0..3"),
    ("negative index", "3 0 -1 2\n", "outside 0..3"),
    ("word in the body", "3 0 one 2\n", "not a number"),
    ("fraction as index", "3 0 1.5 2\n", "non-integer"),
    ("cut in the faces", "3 0 1\n", "cut"),
    ("numbers left over", "3 0 1 2\n7 7\n", "after the last element"),
])
def test_bad_files_are_refused_naming_the_file(tmp_path, case, text, match):
    path = _tri_file(tmp_path, text)
    with pytest.raises(ReadError, match=match) as info:
        wm.load(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("head,match", [
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "end_header"),
    (b"solid x\nfacet normal 0 0 1\n", "does not start with 'ply'"),
    (b"ply\nformat binary_middle_endian 1.0\nend_header\n", "header line 2"),
    (b"ply\nelement vertex 1\nproperty float x\nend_header\n0\n", "no 'format' line"),
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n0\n", "header line 4"),
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
     "lacks x, y or z"),
    ((b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      b"element face 1\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n"
      b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2 6 0 0 1 0 0 1\n"), "2 list properties"),
])
def test_bad_headers_are_refused(tmp_path, head, match):
    path = tmp_path / "h.ply"
    path.write_bytes(head)
    with pytest.raises(ReadError, match=match):
        read_ply(path)


@pytest.mark.parametrize("binary", [True, False])
def test_every_cut_of_a_mixed_file_is_a_read_error(tmp_path, binary):
    data = write_ply(tmp_path / "whole.ply", _mixed(), binary=binary).read_bytes()
    for cut in np.linspace(0.02, 0.98, 40):
        path = tmp_path / "cut.ply"
        path.write_bytes(data[: int(len(data) * cut)])
        with pytest.raises(ReadError, match="cut|end_header") as info:
            wm.load(path)
        assert "cut.ply" in str(info.value)


def test_writer_refuses_what_ply_cannot_hold(tmp_path):
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    with pytest.raises(ValueError, match="64-bit"):
        write_ply(tmp_path / "a.ply", meshio.Mesh(pts, [("triangle", [[0, 1, 2]])],
                                                  cell_data={"id": [np.array([2**40])]}))
    with pytest.raises(ValueError, match="rename"):
        write_ply(tmp_path / "a.ply", meshio.Mesh(pts, [("triangle", [[0, 1, 2]])],
                                                  point_data={"my temp": np.zeros(4)}))
    with pytest.raises(ValueError, match="triangle and quad"):
        write_ply(tmp_path / "a.ply", meshio.Mesh(pts, [("tetra", [[0, 1, 2, 3]])]))
    # through save: vector data is dropped with a warning, scalars kept
    m = wm.Mesh(pts, {"triangle": [[0, 1, 2], [0, 2, 3]]}, point_data={"v": np.zeros((4, 3)), "s": np.ones(4)})
    with pytest.warns(UserWarning, match="'v'"):
        back = wm.load(m.save(tmp_path / "b.ply"))
    assert set(back.point_data) == {"s"}


def test_meshio_reads_the_labels_of_an_ascii_file(tmp_path):
    """The way the module names for meshio, whose binary reader does not take face
    properties: ``save(..., binary=False)`` gives meshio the same triangles and both label
    arrays, and warpmesh reads the ascii file back the same."""
    vol = np.zeros((8, 8, 8), dtype=np.uint8)
    vol[1:7, 1:7, 1:4] = 1
    vol[1:7, 1:7, 4:7] = 3
    m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    path = m.save(tmp_path / "labels.ply", binary=False)
    assert path.read_bytes().startswith(b"ply\nformat ascii 1.0\n")
    mine = wm.load(path)
    np.testing.assert_array_equal(mine.triangles, m.triangles)
    np.testing.assert_array_equal(mine.cell_data["label_above"]["triangle"], m.cell_data["label_above"]["triangle"])
    back = meshio.read(path)
    assert [c.type for c in back.cells] == ["triangle"]
    np.testing.assert_array_equal(back.cells[0].data, m.triangles)
    np.testing.assert_allclose(back.points, m.points)
    np.testing.assert_array_equal(back.cell_data["ref"][0], m.cell_refs["triangle"])
    np.testing.assert_array_equal(back.cell_data["label_above"][0], m.cell_data["label_above"]["triangle"])
