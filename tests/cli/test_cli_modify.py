"""The modification sub-commands: ``warpmesh transform | refine | convert | merge | crack |
periodic`` on pyvista's hexbeam (a mesh made elsewhere), written and read back."""

import json

import numpy as np
import pytest
from tests.helpers.cellcheck import check_cells
from pyvista import examples

import warpmesh as wm
from warpmesh.cli.commands import main


@pytest.fixture
def beam(tmp_path):
    """hexbeam (2 x 2 x 10 hexahedra, z in [0, 5]) with the 4 quads at z = 0.5 as ref 7."""
    b = wm.Mesh.from_pyvista(examples.load_hexbeam())
    h = b.cells["hexahedron"]
    low = b.points[h].mean(axis=1)[:, 2] < 0.5
    m = wm.Mesh(b.points, {"hexahedron": h, "quad": h[low][:, [4, 5, 6, 7]]},
                cell_refs={"quad": np.full(int(low.sum()), 7)})
    return m, m.save(tmp_path / "beam.mesh")


def run(capsys, *argv):
    code = main([str(a) for a in argv] + ["--json"])
    out = capsys.readouterr().out
    return code, (json.loads(out) if code == 0 else None)


def test_transform_mirror_keeps_volumes_positive(beam, tmp_path, capsys):
    mesh, path = beam
    out = tmp_path / "mirrored.vtu"
    code, report = run(capsys, "transform", path, out, "--mirror", 1, 0, 0, 0, "--translate", 2, 0, 0)
    assert code == 0 and report["orientation_reversed"] is True
    assert set(mesh.stats()) <= set(report["before"]) and report["after"]["bounds"][1][0] == pytest.approx(2.0)
    got = wm.load(out)
    np.testing.assert_allclose(got.points[:, 0], 2 - mesh.points[:, 0])
    assert check_cells(got)["measure"] == pytest.approx(5.0)


def test_transform_rotation_about_an_axis(beam, tmp_path, capsys):
    _, path = beam
    out = tmp_path / "turned.vtu"
    assert run(capsys, "transform", path, out, "--rotate", 90, "--axis", 0, 1, 0, "--center", 0, 0, 0)[0] == 0
    got = wm.load(out)
    assert got.points[:, 0].min() == pytest.approx(0) and got.points[:, 0].max() == pytest.approx(5)
    assert check_cells(got)["measure"] == pytest.approx(5.0)


def test_refine_uniform_and_local(beam, tmp_path, capsys):
    _, path = beam
    out = tmp_path / "fine.vtu"
    code, report = run(capsys, "refine", path, out, "-n", 2)
    assert code == 0 and report["after"]["ne"] == 320
    tet = tmp_path / "tet.vtu"
    assert run(capsys, "convert", path, tet, "--to", "tetra")[0] == 0
    local = tmp_path / "local.vtu"
    assert run(capsys, "refine", tet, local, "--max-length", 0.4)[0] == 0
    got = wm.load(local)
    e = got.cells["tetra"][:, [0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3]].reshape(-1, 2)
    assert np.linalg.norm(np.diff(got.points[e], axis=1), axis=2).max() <= 0.4 + 1e-12
    assert check_cells(got)["measure"] == pytest.approx(5.0)


def test_convert_to_tetra_five_and_auto(beam, tmp_path, capsys):
    _, path = beam
    for flags, expected in (([], None), (["--hexes", "5"], 200)):
        out = tmp_path / "tet.vtu"
        code, _ = run(capsys, "convert", path, out, "--to", "tetra", *flags)
        got = wm.load(out)
        assert code == 0 and check_cells(got)["measure"] == pytest.approx(5.0)
        assert expected is None or len(got.cells["tetra"]) == expected
        assert len(got.cells["triangle"]) == 8  # the ref-7 quads, each cut in two


def test_convert_to_hexahedra_prints_a_dash_for_figures_hexahedra_have_not(tmp_path, capsys):
    """(The quality columns printed "None" for the hexahedra.)"""
    tets = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.5)
    tets.save(tmp_path / "ball.msh")
    assert main(["convert", str(tmp_path / "ball.msh"), str(tmp_path / "hex.vtu"), "--to", "hexahedron"]) == 0
    after = next(line for line in capsys.readouterr().out.splitlines() if line.split()[:1] == ["after"])
    assert "None" not in after and after.split()[-1] == "-"


def test_merge_two_halves(beam, tmp_path, capsys):
    mesh, _ = beam
    h = mesh.cells["hexahedron"]
    low = mesh.points[h].mean(axis=1)[:, 2] < 2.5
    paths = []
    for k, keep in enumerate((low, ~low)):
        used = np.unique(h[keep])
        new = np.full(mesh.n_points, -1)
        new[used] = np.arange(len(used))
        paths.append(wm.Mesh(mesh.points[used], {"hexahedron": new[h[keep]]}).save(tmp_path / f"h{k}.vtu"))
    out = tmp_path / "whole.msh"
    code, report = run(capsys, "merge", *paths, out, "--tolerance", 1e-9)
    assert code == 0 and report["after"]["np"] == 99 and report["n_common_points"] == 9
    # checked on the layers of cells at the interface: 1 = 1 + 1 - 1 (blocks and a square)
    assert report["euler_ok"] is True and report["euler_interface"] == 1
    assert report["euler_star"] == report["euler_star_a"] + report["euler_star_b"] - 1 == 1


def test_crack_by_ref_cuts_the_beam_in_two(beam, tmp_path, capsys):
    _, path = beam
    out = tmp_path / "cracked.mesh"
    code, report = run(capsys, "crack", path, out, "--ref", 7, "--side-refs", 7, 8)
    assert code == 0 and report["n_duplicated"] == 9 and report["after"]["np"] == 108
    got = wm.load(out)
    assert sorted(np.unique(got.cell_refs["quad"]).tolist()) == [7, 8]
    assert check_cells(got)["measure"] == pytest.approx(5.0)


def test_periodic_translation(beam, tmp_path, capsys):
    _, path = beam
    out = tmp_path / "long.vtu"
    code, report = run(capsys, "periodic", path, out, "--translate", 0, 0, 5, "--copies", 3)
    assert code == 0 and report["after"]["np"] == 3 * 99 - 2 * 9
    assert check_cells(wm.load(out))["measure"] == pytest.approx(15.0)


@pytest.mark.parametrize("argv", [
    ["transform", "{src}", "{dst}"],                                 # no transformation
    ["transform", "{src}", "{dst}", "--axis", "0", "0", "1"],        # an axis without an angle
    ["refine", "{src}", "{dst}", "-n", "2", "--max-length", "0.3"],  # both kinds
    ["refine", "{src}", "{dst}", "-n", "0"],
    ["convert", "{src}", "{dst}", "--to", "triangle", "--hexes", "5"],  # option of another target
    ["crack", "{src}", "{dst}", "--ref", "99"],                      # no facet with that ref
    ["periodic", "{src}", "{dst}", "--translate", "0", "0", "5", "--copies", "0"],
    ["transform", "{src}", "{bad}", "--translate", "1", "0", "0"],   # unknown output extension
])
def test_bad_arguments_write_nothing(beam, tmp_path, capsys, argv):
    _, path = beam
    dst, bad = tmp_path / "out.vtu", tmp_path / "out.xyz123"
    args = [a.format(src=path, dst=dst, bad=bad) for a in argv]
    assert main(args) == 2
    assert "warpmesh: error:" in capsys.readouterr().err
    assert not dst.exists() and not bad.exists()


def test_a_planar_mesh_read_back_3d_takes_2d_motions(tmp_path, capsys):
    """A planar mesh saved as .vtu comes back with z = 0 columns (3D points): ``--translate X Y``
    and ``--mirror A B C`` are its planar motion, lifted (they were refused, the message naming
    Python calls); a 3D motion still applies to it as 3D."""
    sq = wm.Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
    src = sq.save(tmp_path / "sq.vtu")
    assert wm.load(src).dim == 3
    code, _ = run(capsys, "transform", src, tmp_path / "t.vtu", "--translate", 1, 2)
    assert code == 0
    np.testing.assert_allclose(wm.load(tmp_path / "t.vtu").points[:, :2], sq.points + [1, 2])
    code, _ = run(capsys, "transform", src, tmp_path / "m.vtu", "--mirror", 1, 0, -1)  # about x = 1
    got = wm.load(tmp_path / "m.vtu").points
    assert code == 0
    np.testing.assert_allclose(got[:, 0], 2.0 - sq.points[:, 0])
    np.testing.assert_allclose(got[:, 2], 0.0)
    code, report = run(capsys, "periodic", src, tmp_path / "p.vtu", "--translate", 1, 0, "--copies", 3)
    assert code == 0 and report["after"]["np"] == 3 * 4 - 2 * 2
    code, _ = run(capsys, "transform", src, tmp_path / "z.vtu", "--translate", 0, 0, 1)
    assert code == 0 and np.allclose(wm.load(tmp_path / "z.vtu").points[:, 2], 1.0)


def test_library_keywords_are_told_as_flags_and_one_facet_file_is_read(beam, tmp_path, capsys):
    _, path = beam
    for argv, flag in ((["refine", path, tmp_path / "o.vtu", "-n", "0"], "-n >= 1"),
                       (["transform", path, tmp_path / "o.vtu", "--translate", "nan", "0", "0"], "--translate"),
                       (["transform", path, tmp_path / "o.vtu", "--rotate", "nan"], "--rotate"),
                       (["periodic", path, tmp_path / "o.vtu", "--translate", 0, 0, 5, "--copies", 0], "--copies")):
        assert main([str(a) for a in argv]) == 2
        err = capsys.readouterr().err
        assert flag in err, err
    sq = wm.Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
    src = sq.save(tmp_path / "sq.mesh")
    (tmp_path / "one.txt").write_text("0 2\n")  # one facet: the diagonal
    code, report = run(capsys, "crack", src, tmp_path / "c.mesh", "--facets", tmp_path / "one.txt")
    assert code == 0 and report["after"]["np"] == 6
