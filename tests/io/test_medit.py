"""The fast Medit writer gives meshio's file byte for byte, and warpmesh's save/load round
trip through it."""

from __future__ import annotations

import warnings

import meshio
import numpy as np
import pytest

import warpmesh as wm
from warpmesh.io import medit


def _mesh(rng, dim=3, dtype=np.float64, refs=True):
    pts = (rng.normal(size=(300, dim)) * rng.choice([1e-7, 1.0, 3e5], (300, 1))).astype(dtype)
    pts[0] = 0.0
    cells = [("tetra", rng.integers(0, 300, (500, 4))), ("triangle", rng.integers(0, 300, (40, 3))),
             ("line", rng.integers(0, 300, (7, 2))), ("hexahedron", rng.integers(0, 300, (3, 8)))]
    point_data, cell_data = {}, {}
    if refs:
        point_data = {"medit:ref": rng.integers(-3, 4, 300)}
        cell_data = {"medit:ref": [rng.integers(-50, 10**6, len(c)) for _, c in cells]}
    return meshio.Mesh(pts, cells, point_data=point_data, cell_data=cell_data)


@pytest.mark.parametrize("case", ["refs", "no refs", "2d", "float32", "chunks"])
def test_medit_file_is_meshios_byte_for_byte(tmp_path, monkeypatch, case):
    rng = np.random.default_rng(len(case))
    data = _mesh(rng, dim=2 if case == "2d" else 3, dtype=np.float32 if case == "float32" else np.float64,
                 refs=case != "no refs")
    if case == "chunks":  # rows split over chunks, a last one short
        monkeypatch.setattr(medit, "CHUNK_ROWS", 7)
    medit.write_medit(tmp_path / "fast.mesh", data)
    meshio.write(tmp_path / "meshio.mesh", data, file_format="medit")
    assert (tmp_path / "fast.mesh").read_bytes() == (tmp_path / "meshio.mesh").read_bytes()


def test_integer_rows_are_percent_d():
    rng = np.random.default_rng(4)
    columns = [rng.integers(-10**12, 10**12, 1000), rng.integers(0, 10, 1000), np.zeros(1000, np.int64)]
    columns[0][:3] = [0, -1, 10**12]
    want = "".join(f"{a} {b} {c}\n" for a, b, c in zip(*[c.tolist() for c in columns])).encode()
    assert medit.integer_rows(columns) == want


def test_save_and_load_a_volume_mesh_through_medit(tmp_path):
    labels = np.zeros((12, 12, 12), np.uint8)
    labels[2:10, 2:10, 2:10] = 1
    labels[5:10, 5:10, 5:10] = 2
    m = wm.mesh_domain(labels, labels="all", size=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # Medit keeps only the refs
        path = m.save(tmp_path / "regions.mesh")
    back = wm.load(path)
    np.testing.assert_array_equal(back.points, m.points)
    for t in m.cells:
        np.testing.assert_array_equal(back.cells[t], m.cells[t])
        np.testing.assert_array_equal(back.cell_refs[t], m.cell_refs[t])


def test_medit_writer_refuses_unknown_options_and_other_dtypes(tmp_path):
    data = _mesh(np.random.default_rng(1))
    with pytest.raises(ValueError, match="unknown options"):
        medit.write_medit(tmp_path / "a.mesh", data, float_fmt=".8e")
    bad = meshio.Mesh(np.zeros((4, 3), np.int32), [("tetra", np.array([[0, 1, 2, 3]]))])
    with pytest.raises(ValueError, match="'points'"):
        medit.write_medit(tmp_path / "b.mesh", bad)


# ----------------------------------------------------------------------------- reading
def _same(a: meshio.Mesh, b: meshio.Mesh) -> None:
    np.testing.assert_array_equal(a.points, b.points)
    assert a.points.dtype == b.points.dtype
    assert [c.type for c in a.cells] == [c.type for c in b.cells]
    for x, y in zip(a.cells, b.cells):
        np.testing.assert_array_equal(x.data, y.data)
    np.testing.assert_array_equal(a.point_data["medit:ref"], b.point_data["medit:ref"])
    for x, y in zip(a.cell_data["medit:ref"], b.cell_data["medit:ref"]):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("case", ["refs", "no refs", "2d", "float32", "crlf", "tabs and signs", "hexaedra"])
def test_read_medit_gets_meshios_mesh(tmp_path, case):
    rng = np.random.default_rng(len(case))
    data = _mesh(rng, dim=2 if case == "2d" else 3, dtype=np.float32 if case == "float32" else np.float64,
                 refs=case != "no refs")
    path = tmp_path / "m.mesh"
    medit.write_medit(path, data)
    text = path.read_bytes()
    if case == "crlf":
        text = text.replace(b"\n", b"\r\n")
    elif case == "tabs and signs":  # "+7" and tabs in the integer rows (the vertices keep their spaces)
        head, rows = text.split(b"Tetrahedra", 1)
        text = head + b"Tetrahedra" + rows.replace(b" ", b" \t+", 40)
    elif case == "hexaedra":
        text = text.replace(b"Hexahedra", b"Hexaedra")
    path.write_bytes(text)
    _same(medit.read_medit(path), meshio.read(path, file_format="medit"))


@pytest.mark.parametrize("case", ["comments", "corners", "rows over lines", "vertices over lines", "19 digits"])
def test_other_medit_files_go_to_meshios_reader(tmp_path, monkeypatch, case):
    data = _mesh(np.random.default_rng(3))
    path = tmp_path / "m.mesh"
    medit.write_medit(path, data)
    text = path.read_bytes()
    text = {
        "comments": lambda t: t.replace(b"\nVertices", b"\n# made here\nVertices"),
        "corners": lambda t: t.replace(b"\nEnd", b"\nCorners\n2\n1\n2\n\nEnd"),
        "rows over lines": lambda t: t.replace(b"\nTetrahedra\n500\n", b"\nTetrahedra\n500\n\n", 1),
        "vertices over lines": lambda t: t.replace(b"\nVertices\n300\n", b"\nVertices\n300\n\n", 1),
        "19 digits": lambda t: t.replace(b"\nTetrahedra\n500\n", b"\nTetrahedra\n500\n000000000000000000", 1),
    }[case](text)
    path.write_bytes(text)
    calls = []
    real = medit.meshio_medit.read
    monkeypatch.setattr(medit.meshio_medit, "read", lambda p: calls.append(p) or real(p))
    _same(medit.read_medit(path), real(path))
    assert len(calls) == 1  # read_medit handed the file over


def test_a_cut_or_inconsistent_medit_file_is_a_read_error(tmp_path):
    data = _mesh(np.random.default_rng(4))
    path = tmp_path / "m.mesh"
    medit.write_medit(path, data)
    whole = path.read_bytes()
    for cut in np.linspace(0.3, 0.99, 12):  # in the element blocks
        (tmp_path / "cut.mesh").write_bytes(whole[:int(len(whole) * cut)])
        with pytest.raises(wm.ReadError, match=r"cut\.mesh"):
            wm.load(tmp_path / "cut.mesh")
    bad = whole.replace(b"\nEdges\n7\n", b"\nEdges\n7\n301 ", 1)
    (tmp_path / "far.mesh").write_bytes(bad[:bad.index(b"301 ")] + b"301 1 1\n"
                                        + bad[bad.index(b"\n", bad.index(b"301 ")) + 1:])
    with pytest.raises(wm.ReadError, match="outside the 300 vertices"):
        medit.read_medit(tmp_path / "far.mesh")
