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
