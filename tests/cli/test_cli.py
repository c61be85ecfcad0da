"""The ``warpmesh`` command line."""

import json
import subprocess
import sys

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.cli.commands import main


def test_mesh_example_writes_a_file_and_prints_stats(tmp_path, capsys):
    out = tmp_path / "part.ply"
    assert main(["mesh", "--example", "part", "--resolution", "40", "-o", str(out), "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["euler"] == -6 and stats["watertight"] is True
    assert stats["written"] == str(out)
    loaded = wm.load(out)
    assert loaded.stats()["euler"] == -6
    assert main(["info", str(out)]) == 0
    assert "Euler characteristic            -6" in capsys.readouterr().out


def test_mesh_example_adaptive(tmp_path, capsys):
    out = tmp_path / "part.ply"
    assert main(["mesh", "--example", "part", "--adaptive", "--resolution", "64", "--tolerance", "0.05",
                 "-o", str(out), "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["watertight"] and stats["euler"] == -6 and stats["covering"] == "octree"
    assert main(["mesh", "--example", "part", "--tolerance", "0.05"]) == 2  # needs --adaptive
    capsys.readouterr()
    assert main(["mesh", "--example", "sphere", "--adaptive", "--resolution", "32"]) == 0
    text = capsys.readouterr().out
    header = next(line for line in text.splitlines() if "mean_tape_length" in line)  # the levels as a table
    assert header.split()[:2] == ["level", "cells"]


def test_mesh_volume_file(tmp_path, capsys):
    g = np.linspace(-1, 1, 24)
    vol = 0.7 - np.sqrt(g[:, None, None] ** 2 + g[None, :, None] ** 2 + g[None, None, :] ** 2)
    path = tmp_path / "ball.npy"
    np.save(path, vol)
    assert main(["mesh", "--volume", str(path), "--spacing", str(g[1] - g[0]), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["euler"] == 2


def test_optimize_and_simplify_from_the_command_line(tmp_path, capsys):
    out = tmp_path / "part.vtu"
    assert main(["mesh", "--example", "part", "--method", "mc", "--resolution", "40", "--optimize",
                 "--size", "0.08", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "before" in text and "after" in text and "distance max" in text
    m = wm.load(out)
    assert m.stats()["watertight"] and m.stats()["euler"] == -6 and m.stats()["q_worst"] < 3
    # one label of a segmentation, decimated to about a third within a voxel
    g = np.linspace(-1, 1, 28)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    lab = np.where(x**2 + (y / 0.7) ** 2 + (z / 0.5) ** 2 < 0.8, 3, 0).astype(np.uint8)
    path = tmp_path / "seg.npy"
    np.save(path, lab)
    full = tmp_path / "full.vtu"
    small = tmp_path / "small.vtu"
    assert main(["mesh", "--volume", str(path), "--labels", "3", "-o", str(full)]) == 0
    assert main(["mesh", "--volume", str(path), "--labels", "3", "--simplify", "0.3", "-o", str(small)]) == 0
    a, b = wm.load(full), wm.load(small)
    assert b.stats()["watertight"] and b.stats()["euler"] == 2
    assert 0.25 * a.n_cells < b.n_cells < 0.35 * a.n_cells
    assert main(["mesh", "--example", "sphere", "--optimize", "--simplify", "0.5"]) == 2


def test_errors_are_reported_not_raised(tmp_path, capsys):
    bad = tmp_path / "bad.npy"
    bad.write_text("not an array")
    assert main(["mesh", "--volume", str(bad)]) == 2
    assert "--volume" in capsys.readouterr().err
    assert main(["mesh", "--example", "sphere", "--resolution", "0"]) == 2
    assert "resolution" in capsys.readouterr().err
    missing = tmp_path / "missing.ply"
    assert main(["info", str(missing)]) == 2
    with pytest.raises(SystemExit):
        main(["mesh", "--example", "teapot"])
    assert main(["mesh", "--example", "sphere", "-o", str(tmp_path / "s.xyz")]) == 2
    assert "extension" in capsys.readouterr().err
    assert not list(tmp_path.glob("s.*"))
    np.save(tmp_path / "v.npy", np.arange(64.0).reshape(4, 4, 4))
    assert main(["mesh", "--volume", str(tmp_path / "v.npy"), "--level", "3", "--root", "newton"]) == 2
    assert "root" in capsys.readouterr().err


@pytest.mark.parametrize("module", ["warpmesh.cli", "warpmesh"])
def test_console_script_is_installed(module):
    done = subprocess.run([sys.executable, "-m", module, "--help"], capture_output=True, text=True)
    assert done.returncode == 0 and "mesh" in done.stdout


def test_labels_methods_and_continuation(tmp_path, capsys):
    labels = np.zeros((20, 16, 16), dtype=np.uint8)
    labels[3:9, 3:12, 3:12] = 1
    labels[11:17, 3:12, 3:12] = 4
    path = tmp_path / "seg.npy"
    np.save(path, labels)
    out = tmp_path / "seg.vtu"
    assert main(["mesh", "--volume", str(path), "--labels", "all", "--method", "mt", "--slab-voxels", "2000",
                 "-o", str(out), "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["components"] == 2 and stats["watertight"] is True
    assert set(wm.load(out).cell_refs["triangle"].tolist()) == {1, 4}
    assert main(["mesh", "--volume", str(path), "--labels", "one"]) == 2
    assert "--labels" in capsys.readouterr().err
    assert main(["mesh", "--example", "torus", "--resolution", "32", "--covering", "continuation",
                 "--root", "newton", "--gradient", "central", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["euler"] == 0


def test_renumber_writes_the_mesh_and_prints_table_17_1(tmp_path, capsys):
    import trimesh

    m = wm.Mesh.from_trimesh(trimesh.creation.icosphere(3))
    perm = np.random.default_rng(0).permutation(m.n_points)
    new = np.argsort(perm)
    src, out = tmp_path / "in.msh", tmp_path / "out.vtu"
    m.replace(points=m.points[perm], cells={"triangle": new[m.triangles]}).save(src)
    assert main(["renumber", str(src), str(out), "--method", "gibbs", "--color", "node"]) == 0
    text = capsys.readouterr().out
    assert "beta (final)" in text and "pr ratio" in text and "colours" in text
    r = wm.load(out)
    assert r.n_points == m.n_points and len(r.triangles) == len(m.triangles)
    assert main(["renumber", str(src), str(out), "--method", "rcm", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["bandwidth"] < stats["bandwidth_before"] and stats["method"] == "rcm"


def test_renumber_bad_input_leaves_nothing(tmp_path, capsys):
    src = tmp_path / "in.msh"
    wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).save(src)
    assert main(["renumber", str(src), str(tmp_path / "out.xyz")]) == 2
    assert "error" in capsys.readouterr().err
    assert main(["renumber", str(tmp_path / "missing.msh"), str(tmp_path / "out.msh")]) == 2
    assert not (tmp_path / "out.msh").exists() and not (tmp_path / "out.xyz").exists()
    with pytest.raises(SystemExit):
        main(["renumber", str(src), str(tmp_path / "o.msh"), "--method", "nested"])
