"""The command line's output paths and interruptions: an output that cannot be written is
refused before any meshing, errors name the user's path and CLI flags, the help lists only
extensions whose writer stores the command's cells, Ctrl-C ends with one line and status 130."""

import os
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.cli.commands import main
from warpmesh.cli.output import save_output
from warpmesh.io.files import FILE_FORMATS


@pytest.fixture
def no_meshing(monkeypatch):
    """Every mesher replaced by one that records its calls: the tests check nothing ran."""
    calls = []

    def fake(*args, **kwargs):
        calls.append(args)
        raise AssertionError("meshing ran")

    for name in ("mesh_surface", "mesh_curve", "mesh_domain"):
        monkeypatch.setattr(wm, name, fake)
    return calls


def _bad_outputs(tmp_path):
    a_file = tmp_path / "plain.txt"
    a_file.write_text("not a folder")
    return {
        "missing folder": (tmp_path / "no" / "such" / "part.ply", "does not exist"),
        "a file as folder": (a_file / "part.ply", "is not a folder"),
        "a folder that takes no file": ("/proc/part.ply", "no new file can be made"),
        "a folder as the file": (tmp_path, "got the folder"),
        "unknown extension": (tmp_path / "part.xyz", "unknown extension '.xyz'"),
    }


@pytest.mark.parametrize("case", ["missing folder", "a file as folder", "a folder that takes no file",
                                  "a folder as the file", "unknown extension"])
def test_an_output_that_cannot_be_written_is_refused_before_meshing(tmp_path, capsys, no_meshing, case):
    out, reason = _bad_outputs(tmp_path)[case]
    before = sorted(os.listdir(tmp_path))
    assert main(["mesh", "--example", "part", "--resolution", "1024", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert no_meshing == [], "meshing ran before the output was checked"
    assert err.count("\n") == 1 and reason in err and str(out) in err and "-o/--output" in err, err
    assert "file_format" not in err and ".tmp" not in err
    assert sorted(os.listdir(tmp_path)) == before  # the probe file is gone too


def test_planar_outputs_are_checked_for_their_cells_before_meshing(tmp_path, capsys, no_meshing):
    assert main(["curve", "--example", "gear", "-o", str(tmp_path / "gear.stl")]) == 2
    assert "cannot store line cells" in capsys.readouterr().err
    assert main(["domain", "--example", "part", "-o", str(tmp_path / "part.ply")]) == 2
    assert "cannot store tetra and triangle cells" in capsys.readouterr().err
    assert no_meshing == [] and not list(tmp_path.iterdir())


def test_a_failed_save_names_the_users_path_not_the_temporary_file(tmp_path):
    mesh = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]})
    with pytest.raises(ValueError) as err:
        save_output(mesh, "/proc/part.ply")  # the atomic save's temporary file cannot be made there
    assert "'/proc/part.ply'" in str(err.value) and ".tmp" not in str(err.value) and "-o/--output" in str(err.value)


def test_messages_name_flags_not_python_arguments(tmp_path, capsys):
    src = tmp_path / "in.msh"
    wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).save(src)
    for argv in (["info", str(tmp_path / "m.xyz")], ["renumber", str(tmp_path / "m.xyz"), str(tmp_path / "o.msh")],
                 ["renumber", str(src), str(tmp_path / "o.xyz")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "file_format" not in err and "unknown extension" in err, err


def _help_extensions(command: str, capsys) -> set[str]:
    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = capsys.readouterr().out
    block = re.search(r"-o OUTPUT, --output OUTPUT(.*?)(?:\n  -|\Z)", text, re.S).group(1)
    return set(re.findall(r"(?<![\w.])\.[a-z]+", block))


@pytest.mark.parametrize("command, cells", [
    ("mesh", {"triangle": [[0, 1, 2], [0, 2, 3]]}),
    ("curve", {"line": [[0, 1], [1, 2]]}),
    ("domain", {"triangle": [[0, 1, 2]], "line": [[0, 1]]}),   # its planar meshes: triangles and boundary lines
])
def test_the_help_lists_only_extensions_that_work(tmp_path, capsys, command, cells):
    listed = _help_extensions(command, capsys)
    mesh = wm.Mesh(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), cells)
    for ext in FILE_FORMATS:
        try:
            mesh.save(tmp_path / f"m{ext}")
            works = True
        except ValueError:
            works = False
        assert (ext in listed) == works, (command, ext, listed)
    assert listed <= set(FILE_FORMATS)


def test_interrupted_in_process_one_line_and_status_130(tmp_path, capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(wm, "mesh_surface", interrupted)
    assert main(["mesh", "--example", "sphere", "-o", str(tmp_path / "s.ply")]) == 130
    captured = capsys.readouterr()
    assert captured.err == "warpmesh: interrupted\n" and captured.out == "" and not list(tmp_path.iterdir())


def test_sigint_while_the_commands_load_exits_130_with_one_line():
    """Ctrl-C before main's own handler exists (numpy and the commands still importing) ends
    the same way, not with an import's traceback [issue 24 item 3]."""
    script = (
        "import builtins, os, signal, sys\n"
        "real = builtins.__import__\n"
        "def loading(name, *args, **kwargs):\n"
        "    if name == 'warpmesh.cli.commands':\n"
        "        os.kill(os.getpid(), signal.SIGINT)\n"
        "    return real(name, *args, **kwargs)\n"
        "builtins.__import__ = loading\n"
        "from warpmesh.cli import main\n"
        "sys.argv = ['warpmesh', 'info', 'nothing.vtu']\n"
        "sys.exit(main())\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 130 and run.stderr == "warpmesh: interrupted\n" and run.stdout == ""


def _cpu_seconds(pid: int) -> float:
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.skipif(not os.path.exists("/proc/self/stat"), reason="reads the child's CPU time from /proc")
def test_sigint_to_a_running_mesh_exits_130_with_one_line_and_no_file(tmp_path):
    script = shutil.which("warpmesh")
    command = [script] if script else [sys.executable, "-m", "warpmesh.cli"]
    out = tmp_path / "big.ply"
    child = subprocess.Popen([*command, "mesh", "--example", "part", "--resolution", "1024", "-o", str(out)],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # importing warpmesh and Warp costs about 2.5 s of CPU; meshing 1024^3 many times that: send
        # the signal once the child has spent 4 s of its own CPU (wall time would depend on the load)
        while child.poll() is None and _cpu_seconds(child.pid) < 4.0:
            time.sleep(0.05)
        assert child.poll() is None, "the child finished before it was interrupted"
        child.send_signal(signal.SIGINT)
        sent = time.perf_counter()
        stdout, stderr = child.communicate(timeout=90)
        waited = time.perf_counter() - sent
    finally:
        if child.poll() is None:
            child.kill()
    assert child.returncode == 130, stderr
    assert stderr == "warpmesh: interrupted\n" and stdout == ""
    assert list(tmp_path.iterdir()) == []  # no output, no temporary file
    assert waited < 10.0, f"{waited:.1f} s from Ctrl-C to the exit"  # not after the worker threads' launches


@pytest.mark.parametrize("argv, flag", [
    (["mesh", "--example", "sphere", "--root", "bisection", "--root-iterations", "0"], "--root-iterations"),
    (["mesh", "--example", "sphere", "--resolution", "16", "--level", "0.1"], "--level does not apply"),
    (["mesh", "--example", "sphere", "--resolution", "16", "--simplify", "2"], "--simplify"),
    (["mesh", "--example", "sphere", "--resolution", "16", "--simplify", "0.5", "--max-error", "-1"], "--max-error"),
    (["domain", "--example", "part", "--size", "100"], "lower --size or enlarge --bounds"),
])
def test_library_errors_are_told_in_cli_flags(capsys, argv, flag):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert flag in err and not re.search(r"'(root_iterations|level|fraction|tolerance|size|bounds)'", err), err


def test_warnings_are_one_line_of_the_command(tmp_path, capsys):
    """(A UserWarning printed its module path, line number and the source line.)"""
    labels = np.zeros((12, 12, 12), np.uint8)
    labels[3:8, 3:8, 3:8] = 1
    labels[6:10, 6:10, 6:10] = 2
    np.save(tmp_path / "l.npy", labels)
    assert main(["mesh", "--volume", str(tmp_path / "l.npy"), "--labels", "all", "-o", str(tmp_path / "l.obj")]) == 0
    err = capsys.readouterr().err
    assert "warpmesh: warning: obj files cannot store ['medit:ref']; not saved\n" in err
    assert "UserWarning" not in err and ".py:" not in err


def test_touching_labels_crossings_point_to_shared_interfaces(tmp_path, capsys):
    labels = np.zeros((12, 12, 12), np.uint8)
    labels[3:8, 3:8, 3:8] = 1
    labels[6:10, 6:10, 6:10] = 2  # touching label 1
    np.save(tmp_path / "l.npy", labels)
    for interfaces, hint in (("separate", True), ("shared", False)):
        assert main(["mesh", "--volume", str(tmp_path / "l.npy"), "--labels", "all", "--interfaces", interfaces,
                     "-o", str(tmp_path / "l.vtu")]) == 0
        line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("self-intersections"))
        assert ("--interfaces shared meshes each interface once" in line) == hint, line
        assert line.split()[1] != "0" if hint else line.split()[1] == "0"


def test_ascii_writes_a_labelled_ply_that_meshio_reads(tmp_path, capsys):
    """``--ascii`` for meshio, whose binary PLY reader cannot read face properties: the same
    triangles and labels as the binary file, read by meshio."""
    import meshio

    vol = np.zeros((8, 8, 8), np.uint8)
    vol[1:7, 1:7, 1:4] = 1
    vol[1:7, 1:7, 4:7] = 2
    np.save(tmp_path / "labels.npy", vol)
    for name, extra in (("text.ply", ["--ascii"]), ("raw.ply", [])):
        assert main(["mesh", "--volume", str(tmp_path / "labels.npy"), "--labels", "all", "--interfaces", "shared",
                     "-o", str(tmp_path / name), *extra]) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert (tmp_path / "text.ply").read_bytes().startswith(b"ply\nformat ascii 1.0\n")
    assert (tmp_path / "raw.ply").read_bytes().startswith(b"ply\nformat binary_little_endian 1.0\n")
    text, raw = meshio.read(tmp_path / "text.ply"), wm.load(tmp_path / "raw.ply")
    np.testing.assert_array_equal(text.cells[0].data, raw.triangles)
    np.testing.assert_array_equal(text.cell_data["label_above"][0], raw.cell_data["label_above"]["triangle"])


def test_ascii_for_a_format_of_one_encoding_is_refused_before_any_work(tmp_path, capsys, no_meshing):
    for argv in (["mesh", "--example", "part", "-o", str(tmp_path / "part.vtu"), "--ascii"],
                 ["curve", "--example", "gear", "-o", str(tmp_path / "gear.mesh"), "--ascii"],
                 ["domain", "--example", "part", "-o", str(tmp_path / "part.msh"), "--ascii"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "--ascii applies to .vtk .ply .stl files" in err and argv[-2] in err, err
    src = tmp_path / "in.vtk"
    wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]}).save(src)
    assert main(["renumber", str(src), str(tmp_path / "out.obj"), "--ascii"]) == 2
    assert "--ascii applies to" in capsys.readouterr().err
    assert main(["renumber", str(src), str(tmp_path / "out.vtk"), "--ascii"]) == 0
    assert (tmp_path / "out.vtk").read_bytes().splitlines()[2] == b"ASCII"
    assert no_meshing == [] and sorted(p.name for p in tmp_path.iterdir()) == ["in.vtk", "out.vtk"]


def test_ascii_without_an_output_file_is_refused_before_any_work(tmp_path, capsys, no_meshing, monkeypatch):
    """``--ascii`` sets the encoding of the file ``-o`` writes: without ``-o`` (the commands
    whose output is optional) it would be ignored, so it is refused, naming both flags."""
    monkeypatch.chdir(tmp_path)
    for argv in (["mesh", "--example", "part", "--ascii"], ["curve", "--example", "gear", "--ascii"],
                 ["domain", "--example", "part", "--ascii"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert "--ascii" in err and "-o/--output" in err, err
    assert no_meshing == [] and list(tmp_path.iterdir()) == []


def test_meshio_formats_beyond_the_curated_ones_in_and_out(tmp_path, capsys):
    """What wm.load and Mesh.save take, the commands take: .off (triangles only) and .inp written
    and read back; a cell type the format cannot hold, an unknown extension (the message lists
    meshio's formats too) and a folder refused before any work."""
    tri = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], {"triangle": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]})
    src = tri.save(tmp_path / "t.vtu")
    assert main(["renumber", str(src), str(tmp_path / "r.off")]) == 0
    assert main(["transform", str(tmp_path / "r.off"), str(tmp_path / "m.inp"), "--translate", "1", "0", "0"]) == 0
    capsys.readouterr()
    np.testing.assert_allclose(np.sort(wm.load(tmp_path / "m.inp").points[:, 0]), np.sort(tri.points[:, 0] + 1))
    assert main(["domain", "--example", "sphere", "--size", "0.3", "-o", str(tmp_path / "s.off")]) == 2
    assert "cannot store tetra" in capsys.readouterr().err
    assert main(["transform", str(src), str(tmp_path / "x.xyz9"), "--translate", "1", "0", "0"]) == 2
    err = capsys.readouterr().err
    assert "unknown extension '.xyz9'" in err and ".off" in err and ".inp" in err
    assert main(["transform", str(tmp_path), str(tmp_path / "o.vtu"), "--translate", "1", "0", "0"]) == 2
    assert "is a folder" in capsys.readouterr().err
    assert not (tmp_path / "s.off").exists() and not (tmp_path / "o.vtu").exists()


def test_an_ascii_vtk_is_written_without_meshio_calling_it_debugging(tmp_path, capsys):
    """meshio prints "VTK ASCII files are only meant for debugging." on every ascii .vtk: the user
    asked for ascii (--ascii), so it is not passed on; the file is ascii and reads back."""
    out = tmp_path / "s.vtk"
    assert main(["mesh", "--example", "sphere", "--resolution", "12", "--ascii", "-o", str(out)]) == 0
    assert "meant for debugging" not in capsys.readouterr().err
    assert out.read_bytes().splitlines()[2] == b"ASCII" and wm.load(out).n_cells > 0
