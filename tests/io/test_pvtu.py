""".pvtu files: a mesh saved as a piece and its .pvtu comes back whole and VTK reads the
same; pieces that share points by global id are welded into the mesh they were cut from;
without global ids the pieces are joined as VTK joins them; bad files are ReadErrors
naming what is wrong, and a failed save leaves nothing."""

from __future__ import annotations

import numpy as np
import pytest
import pyvista as pv

import warpmesh as wm
from warpmesh.io import pvtu, vtu


def _sphere():
    return wm.mesh_surface(wm.sphere(1.0), bounds=[[-1.3] * 3, [1.3] * 3], resolution=20)


def _cut(mesh: wm.Mesh, parts: int, key: str | None, tmp_path, *, local_ids: bool = False):
    """``mesh``'s triangles cut into ``parts`` pieces by their centroids' x, each piece with
    its own copy of the points it uses (seam points in two pieces), written as .vtu pieces
    and a .pvtu; ``key`` names the point array of the points' numbers in ``mesh``, declared
    as the global ids (or not declared when ``key`` is None; ``local_ids``: each piece
    numbers its own points from 0, ids that are not global)."""
    tri = mesh.triangles
    x = mesh.points[tri].mean(axis=1)[:, 0]
    edges = np.quantile(x, np.linspace(0, 1, parts + 1))
    which = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, parts - 1)
    names = []
    for k in range(parts):
        mine = tri[which == k]
        used, local = np.unique(mine, return_inverse=True)
        ids = np.arange(len(used)) if local_ids else used
        names.append(f"cut_{k}.vtu")
        vtu.write_grid(tmp_path / names[-1], mesh.points[used], [("triangle", local.reshape(-1, 3))],
                       {"id": ids, "height": mesh.points[used, 2]}, {"ref": [np.full(len(mine), 7 + k)]},
                       global_ids=key)
    arrays = [("id", "Int64", 1), ("height", "Float64", 1)]
    (tmp_path / "cut.pvtu").write_text(pvtu.pvtu_text(names, arrays, [("ref", "Int64", 1)], global_ids=key))
    return tmp_path / "cut.pvtu", which


def test_save_and_load_keep_everything_and_vtk_reads_the_same(tmp_path):
    m = _sphere()
    m = m.replace(point_data={"h": m.points[:, 2].copy()}, cell_data={"q": {"triangle": m.quality()}})
    path = m.save(tmp_path / "s.pvtu")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.pvtu", "s_0.vtu"]
    back = wm.load(path)
    np.testing.assert_array_equal(back.points, m.points)
    np.testing.assert_array_equal(back.triangles, m.triangles)
    np.testing.assert_array_equal(back.point_data["h"], m.point_data["h"])
    np.testing.assert_array_equal(back.cell_data["q"]["triangle"], m.cell_data["q"]["triangle"])
    grid = pv.read(path)  # VTK's parallel reader, through the .pvtu's declarations
    np.testing.assert_array_equal(grid.points, m.points)
    np.testing.assert_array_equal(grid.cells_dict[pv.CellType.TRIANGLE], m.triangles)
    np.testing.assert_array_equal(grid.point_data["h"], m.point_data["h"])
    np.testing.assert_array_equal(grid.cell_data["q"], m.cell_data["q"]["triangle"])


@pytest.mark.parametrize("parts", [2, 5])
def test_pieces_with_global_ids_are_welded_into_the_mesh_they_were_cut_from(tmp_path, parts):
    m = _sphere()
    path, which = _cut(m, parts, "id", tmp_path)
    assert (pv.read(path).n_points > m.n_points)  # VTK keeps every copy
    back = wm.load(path)
    assert back.n_points == m.n_points and back.n_cells == m.n_cells
    ids = back.point_data["id"]
    np.testing.assert_array_equal(back.points, m.points[ids])  # each point where the mesh has it
    order = np.argsort(which, kind="stable")
    np.testing.assert_array_equal(ids[back.triangles], m.triangles[order])
    np.testing.assert_array_equal(back.cell_refs["triangle"], 7 + which[order])  # a bricked run's "ref"
    stats = back.stats()
    assert stats["watertight"] and stats["oriented"] and stats["components"] == 1 and stats["genus"] == 0
    assert stats["self_intersections"] == 0


def test_without_global_ids_the_pieces_are_joined_as_vtk_joins_them(tmp_path):
    m = _sphere()
    path, _ = _cut(m, 3, None, tmp_path)
    back, grid = wm.load(path), pv.read(path)
    assert back.n_points == grid.n_points > m.n_points
    np.testing.assert_array_equal(back.points, grid.points)
    np.testing.assert_array_equal(back.triangles, grid.cells_dict[pv.CellType.TRIANGLE])


def test_a_bad_pvtu_is_a_read_error_naming_what_is_wrong(tmp_path):
    m = _sphere()
    path, _ = _cut(m, 2, "id", tmp_path, local_ids=True)
    with pytest.raises(wm.ReadError, match=r"cut.pvtu' as pvtu: points with one global id \('id'\) lie .* apart"):
        wm.load(path)
    path, _ = _cut(m, 2, "id", tmp_path)
    good = path.read_text()
    cases = {
        "missing piece": (good.replace("cut_1.vtu", "gone.vtu"), "its piece 'gone.vtu' is missing"),
        "not xml": ("<VTKFile type=", "ParseError"),
        "other type": (good.replace('type="PUnstructuredGrid"', 'type="PImageData"'),
                       "expected a VTKFile of type PUnstructuredGrid, got VTKFile of type 'PImageData'"),
        "no pieces": (good.replace('<Piece Source="cut_0.vtu"/>', "").replace('<Piece Source="cut_1.vtu"/>', ""),
                      "lists no pieces"),
        "no source": (good.replace('Source="cut_1.vtu"', ""), "a <Piece> without a Source"),
    }
    for case, (text, why) in cases.items():
        bad = tmp_path / "bad.pvtu"
        bad.write_text(text)
        with pytest.raises(wm.ReadError, match=f"could not read '.*bad.pvtu' as pvtu: .*{why}"):
            wm.load(bad)
    cut = (tmp_path / "cut_1.vtu").read_bytes()
    (tmp_path / "cut_1.vtu").write_bytes(cut[:len(cut) // 2])
    with pytest.raises(wm.ReadError, match="cut.pvtu' as pvtu: its piece 'cut_1.vtu': could not read"):
        wm.load(path)


def test_a_failed_save_leaves_neither_file(tmp_path, monkeypatch):
    m = _sphere()
    m.save(tmp_path / "old.pvtu")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def fails(path, *args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(pvtu.Path, "write_text", fails)  # the piece is written, then the .pvtu fails
    for name in ("old.pvtu", "new.pvtu"):
        with pytest.raises(OSError, match="disk full"):
            m.save(tmp_path / name)
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    with pytest.raises(ValueError, match=r"unknown options for .pvtu files: \['binary'\]"):
        pvtu.write_pvtu(tmp_path / "x.pvtu", m.to_meshio(), binary=True)
    with pytest.raises(ValueError, match="name of a point array for 'global_ids'"):
        pvtu.pvtu_text(["a.vtu"], [], [], global_ids="id")
    with pytest.raises(ValueError, match="name of a point data array for 'global_ids'"):
        vtu.write_grid(tmp_path / "x.vtu", m.points, [("triangle", m.triangles)], global_ids="id")
    assert sorted(before) == sorted(p.name for p in tmp_path.iterdir())
