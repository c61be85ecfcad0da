"""Label images on the command line: ``domain --volume`` (conforming tetrahedra of the
regions, lattice cleaving), ``mesh --volume --labels --interfaces shared [--smoothing]``,
and the program's allocator setting (:mod:`warpmesh._util.allocator`)."""

import json
import os
import subprocess
import sys
import textwrap

import meshio
import numpy as np
import pytest

import warpmesh as wm
from warpmesh._util.allocator import ENV, keep_freed_memory
from warpmesh.cells.intersections import count_self_intersecting_faces
from warpmesh.cli.commands import main

SPACING = (0.5, 0.5, 1.0)


@pytest.fixture
def slabs(tmp_path):
    """Labels 1 (k < 10) and 2 (k >= 10) in a block of a 0 background, and a speck of 5."""
    v = np.zeros((20, 20, 20), np.int16)
    v[4:16, 4:16, 4:10] = 1
    v[4:16, 4:16, 10:16] = 2
    v[1:3, 1:3, 17:19] = 5
    path = tmp_path / "slabs.npy"
    np.save(path, v)
    return path, v


def _signed_volumes(points, tets):
    a, b, c, d = (points[tets[:, i]] for i in range(4))
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0


def test_domain_volume_writes_conforming_regions_that_meshio_reads(slabs, tmp_path, capsys):
    path, v = slabs
    out = tmp_path / "slabs.msh"
    argv = ["domain", "--volume", str(path), "--spacing", *map(str, SPACING), "--labels", "1", "2",
            "--size", "1.5", "-o", str(out), "--json"]
    assert main(argv) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["negative_tets"] == 0 and stats["self_intersections"] == 0
    # the file, read by meshio (not warpmesh): one physical volume per label, all tetrahedra positive
    m = meshio.read(out)
    tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    assert tets.shape[0] == stats["n_tetra"]
    vols = _signed_volumes(m.points, tets)
    assert vols.min() > 0
    groups = {name: tags for name, tags in m.field_data.items()}
    assert {"label_1", "label_2"} <= set(groups) and "label_5" not in groups
    tag = np.concatenate([d for c, d in zip(m.cells, m.cell_data["gmsh:physical"]) if c.type == "tetra"])
    voxel = np.prod(SPACING)
    for label in (1, 2):
        region = vols[tag == groups[f"label_{label}"][0]].sum()
        assert region == pytest.approx(np.count_nonzero(v == label) * voxel, rel=0.05), label
    # the same mesh as the library call with the same arguments
    ref = wm.mesh_domain(wm.Volume(v, spacing=SPACING), labels=[1, 2], size=1.5)
    assert ref.cells["tetra"].shape[0] == tets.shape[0]
    np.testing.assert_allclose(np.sort(vols), np.sort(_signed_volumes(ref.points, ref.cells["tetra"])))


def test_domain_volume_defaults_to_every_label_but_zero(slabs, capsys):
    path, v = slabs
    assert main(["domain", "--volume", str(path), "--size", "2", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["labels"] == [1, 2, 5]


@pytest.mark.parametrize("extra, needle", [
    (["--smooth", "-2"], "non-negative integer for --smooth"),
    (["--method", "delaunay"], "--method does not apply to --volume"),
    (["--bounds", "0", "0", "0", "1", "1", "1"], "--bounds does not apply to --volume"),
    (["--size", "curvature"], "--size curvature grades shapes"),
    (["--labels", "7"], "--labels present"),
    (["--labels", "one"], "expected --labels all or integer labels"),
    (["--snap", "0.7"], "--snap"),
    (["--size", "-1"], "--size"),
    (["-o", "out.ply"], ".ply files cannot store tetra"),
])
def test_domain_volume_bad_flags_are_named(slabs, tmp_path, capsys, extra, needle):
    path, _ = slabs
    os.chdir(tmp_path)
    assert main(["domain", "--volume", str(path), *extra]) == 2
    err = capsys.readouterr().err
    assert needle in err, err
    assert not os.path.exists(tmp_path / "out.ply")


@pytest.mark.parametrize("extra, needle", [
    (["--labels", "1"], "--labels does not apply to a shape"),
    (["--snap", "0.2"], "--snap does not apply to a shape"),
    (["--snap", "0"], "--snap does not apply to a shape"),
    (["--min-size", "0"], "--min-size does not apply to a shape"),
    (["--min-size", "0.1"], "--min-size does not apply to a shape"),
    (["--spacing", "1"], "--spacing does not apply to a shape"),
])
def test_domain_shape_refuses_volume_flags(capsys, extra, needle):
    assert main(["domain", "--example", "sphere", *extra]) == 2
    assert needle in capsys.readouterr().err


def test_domain_volume_that_does_not_parse(tmp_path, capsys):
    bad = tmp_path / "broken.vti"
    bad.write_text("<VTKFile> not really")
    assert main(["domain", "--volume", str(bad)]) == 2
    assert f"cannot read --volume {str(bad)!r}" in capsys.readouterr().err
    assert main(["domain", "--volume", str(tmp_path / "missing.nii.gz")]) == 2
    assert "no such image file" in capsys.readouterr().err


def test_mesh_volume_shared_interfaces_once_each(slabs, tmp_path, capsys):
    path, v = slabs
    out = tmp_path / "slabs.vtu"
    assert main(["mesh", "--volume", str(path), "--labels", "all", "--interfaces", "shared",
                 "--smoothing", "3", "-o", str(out), "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["self_intersections"] == 0
    m = wm.load(out)
    tri = m.cells["triangle"]
    lo, hi = m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"]
    assert np.all(lo < hi)
    assert np.unique(np.sort(tri, axis=1), axis=0).shape[0] == tri.shape[0]  # no face twice
    assert count_self_intersecting_faces(m.points, tri) == 0
    assert {(a, b) for a, b in zip(lo.tolist(), hi.tolist())} == {(0, 1), (0, 2), (1, 2), (0, 5)}
    assert {label: (f["closed"], f["oriented"]) for label, f in stats["label_boundaries"].items()} == {
        "0": (True, True), "1": (True, True), "2": (True, True), "5": (True, True)}
    # the separate surfaces (the default) mesh the 1|2 interface twice: the shared one is smaller
    assert main(["mesh", "--volume", str(path), "--labels", "all", "--json"]) == 0
    separate = json.loads(capsys.readouterr().out)
    assert separate["n_triangles"] > stats["n_triangles"]
    # read by a person: the whole surface is not closed, and why; each label's boundary is
    assert main(["mesh", "--volume", str(path), "--labels", "all", "--interfaces", "shared"]) == 0
    lines = capsys.readouterr().out.splitlines()
    watertight = next(line for line in lines if line.startswith("watertight"))
    assert "interfaces meet at junction edges" in watertight
    assert any(line.startswith("label boundaries") and "4 of 4 closed and oriented outward" in line
               for line in lines), lines


def test_mesh_volume_shared_interfaces_simplify_and_optimize(slabs, tmp_path, capsys):
    """--simplify / --optimize of a shared surface run its own remeshing (they were refused:
    "expected one label with --labels when optimising"); the report prints its figures."""
    path, _ = slabs
    base = ["mesh", "--volume", str(path), "--labels", "all", "--interfaces", "shared"]
    assert main([*base, "--json"]) == 0
    raw = json.loads(capsys.readouterr().out)
    out = tmp_path / "fewer.vtu"
    assert main([*base, "--simplify", "0.3", "-o", str(out), "--json"]) == 0
    fewer = json.loads(capsys.readouterr().out)
    assert fewer["n_triangles"] < 0.45 * raw["n_triangles"] and fewer["self_intersections"] == 0
    assert fewer["q_worst"] <= max(raw["q_worst"], 6.0)
    back = wm.load(out)
    assert set(back.cell_data["label_above"]["triangle"].tolist()) <= {1, 2, 5}
    assert main([*base, "--optimize", "--size", "2"]) == 0
    text = capsys.readouterr().out
    assert "optimisation (before / after):" in text and "q worst" in text


@pytest.mark.parametrize("argv, needle", [
    (["--volume", "{path}", "--labels", "all", "--smoothing", "3"], "--smoothing applies with --interfaces 'shared'"),
    (["--example", "part", "--interfaces", "shared"], "--interfaces does not apply to a shape"),
    (["--volume", "{path}", "--interfaces", "both"], "invalid choice"),
])
def test_mesh_interfaces_flags_are_checked(slabs, capsys, argv, needle):
    path, _ = slabs
    argv = [a.format(path=path) for a in argv]
    if needle == "invalid choice":
        with pytest.raises(SystemExit):
            main(["mesh", *argv])
    else:
        assert main(["mesh", *argv]) == 2
    assert needle in capsys.readouterr().err


def test_keep_freed_memory_puts_large_blocks_in_the_heap():
    """In a fresh process, after the setting a 200 MB array comes from the heap (where a
    freed one is reused), where glibc's default maps it on its own (and unmaps it when freed):
    glibc's ``mallinfo2`` counts the mapped bytes (``hblkhd``) while the array lives."""
    code = textwrap.dedent("""
        import ctypes, sys
        from warpmesh._util.allocator import keep_freed_memory
        set_ = keep_freed_memory() if sys.argv[1] == "keep" else False
        import numpy as np

        class Info(ctypes.Structure):
            _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                              "usmblks", "fsmblks", "uordblks", "fordblks",
                                                              "keepcost")]
        libc = ctypes.CDLL(None)
        try:
            libc.mallinfo2.restype = Info
        except AttributeError:
            print("no-mallinfo2"); raise SystemExit
        a = np.ones(25_000_000)
        print(set_, libc.mallinfo2().hblkhd)
    """)
    runs = {}
    for mode in ("keep", "default"):
        out = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, check=True,
                             env={**os.environ, ENV: "1"}).stdout.split()
        if out[0] == "no-mallinfo2":
            pytest.skip("not glibc >= 2.33: the allocator setting cannot be observed here")
        runs[mode] = (out[0] == "True", int(out[1]))
    if not runs["keep"][0]:
        pytest.skip("not glibc: the allocator setting does not apply here")
    assert runs["default"][1] >= 200_000_000     # glibc's default: the array is a mapping of its own
    assert runs["keep"][1] < 1_000_000           # kept: in the heap


def test_keep_freed_memory_opt_out_and_the_program_only(monkeypatch):
    for off in ("0", "no", "False", " off "):
        assert keep_freed_memory(environ={ENV: off}) is False
    import warpmesh._util.allocator as allocator
    import warpmesh.cli as cli

    calls = []
    monkeypatch.setattr(allocator, "keep_freed_memory", lambda: calls.append(1) or True)
    monkeypatch.setattr(sys, "argv", ["warpmesh", "mesh", "--example", "sphere", "--resolution", "8", "--json"])
    assert cli.main(["mesh", "--example", "sphere", "--resolution", "8", "--json"]) == 0
    assert calls == []                                   # a caller's main([...]): the process is not ours
    assert cli.main() == 0
    assert calls == [1]                                  # the program


def test_a_volume_too_thin_to_cap_names_the_flag_that_opens_it(tmp_path, capsys):
    """The library's 'cap=True' read '--no-cap True' through the CLI."""
    path = tmp_path / "tiny.npy"
    np.save(path, np.ones((2, 2, 2), np.uint8))
    assert main(["mesh", "--volume", str(path), "--labels", "all", "-o", str(tmp_path / "a.stl")]) == 2
    err = capsys.readouterr().err
    assert "3 samples per axis" in err and "(--no-cap leaves the surface open)" in err and "True" not in err


def test_progress_bars_only_on_a_terminal(slabs, capsys, monkeypatch, tmp_path):
    """stderr redirected (as under pytest): no bar frames in it, though the bar would be drawn
    at once (DELAY 0); on a terminal (progress_bars() True) the stages' bar is drawn."""
    import warpmesh._util.progress as P
    import warpmesh.cli.curves as curves

    path, _ = slabs
    monkeypatch.setattr(P, "DELAY", 0.0)
    argv = ["domain", "--volume", str(path), "--size", "2", "-o", str(tmp_path / "d.msh")]
    assert main(argv) == 0
    assert "mesh_domain" not in capsys.readouterr().err
    monkeypatch.setattr(curves, "progress_bars", lambda: True)
    assert main(argv) == 0
    assert "warpmesh mesh_domain (labels)" in capsys.readouterr().err
