"""Shapes from the user on the command line (``FILE.py[:NAME]``, ``--expr``, ``--bounds``,
``--version``) and what the commands print (one line per figure, each once; ``--json``)."""

import json
import re
import shutil
import subprocess
import sys
import textwrap

import pytest

import warpmesh as wm
from warpmesh.cli.commands import main

DEGREE6 = "(x**2 + y**2 - 4) * (x**2 + z**2 - 4) * (y**2 + z**2 - 4) - 4.0078"  # frep/examples.py
CUBE = ["--bounds", "-3", "-3", "-3", "3", "3", "3"]


def _command() -> list[str]:
    """The installed ``warpmesh`` script, as a user's shell runs it (else ``python -m warpmesh.cli``)."""
    script = shutil.which("warpmesh")
    return [script] if script else [sys.executable, "-m", "warpmesh.cli"]


@pytest.fixture
def torus_file(tmp_path):
    path = tmp_path / "rings.py"
    path.write_text(textwrap.dedent("""
        import warpmesh as wm

        shape = wm.torus(1.0, 0.35)
        thin = wm.torus(1.0, 0.2)
        bounds = ((-1.5, -1.5, -0.5), (1.5, 1.5, 0.5))
        count = 3
    """))
    return path


def test_torus_in_a_user_file_meshed_from_the_shell(torus_file, tmp_path):
    out = tmp_path / "torus.ply"
    done = subprocess.run([*_command(), "mesh", str(torus_file), "--resolution", "32", "-o", str(out), "--json"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr
    stats = json.loads(done.stdout)  # stdout holds the JSON object and nothing else
    assert stats["euler"] == 0 and stats["genus"] == 1 and stats["watertight"] is True
    assert stats["written"] == str(out) and wm.load(out).stats()["euler"] == 0


def test_a_named_shape_of_the_file_and_bounds_from_the_command_line(torus_file, capsys):
    assert main(["mesh", f"{torus_file}:thin", "--resolution", "24", "--bounds", "-1.3", "-1.3", "-0.3",
                 "1.3", "1.3", "0.3", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["euler"] == 0
    lo, hi = stats["bounds"]
    assert hi[2] == pytest.approx(0.2, abs=0.02) and lo[0] > -1.3  # the thin ring, inside --bounds


def test_degree_six_surface_from_an_expression(capsys):
    assert main(["mesh", "--expr", DEGREE6, *CUBE, "--resolution", "48", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["euler"] == -8 and stats["watertight"] is True  # capped on the box [FG §16.4.5]


def test_expressions_in_the_plane_and_domains_of_both_dimensions(tmp_path, capsys):
    assert main(["curve", "--expr", "1 - x**2 - 4 * y**2", "--bounds", "-1.5", "-1", "1.5", "1", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["components"] == 1 and stats["n_cells"] == stats["np"]  # one closed polyline
    disc = tmp_path / "disc.vtu"
    assert main(["domain", "--expr", "1 - wm.sqrt(x**2 + y**2)", "--bounds", "-1.2", "-1.2", "1.2", "1.2",
                 "--size", "0.3", "-o", str(disc), "--json"]) == 0
    assert "triangle" in wm.load(disc, dim=2).cells and json.loads(capsys.readouterr().out)["euler"] == 1
    ball = tmp_path / "ball.mesh"
    assert main(["domain", "--expr", "1 - x**2 - y**2 - z**2", "--bounds", "-1.2", "-1.2", "-1.2", "1.2", "1.2",
                 "1.2", "--size", "0.4", "-o", str(ball), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_tetra"] > 0 and "tetra" in wm.load(ball).cells


@pytest.mark.parametrize("argv, needle", [
    (["mesh", "--expr", "__import__('os').getcwd()", *CUBE], "'__import__'"),
    (["mesh", "--expr", "x.__class__", *CUBE], "'__class__'"),
    (["mesh", "--expr", "open('/etc/passwd')", *CUBE], "'open' is not defined"),
    (["mesh", "--expr", "x + w", *CUBE], "the names are x, y, z"),
    (["mesh", "--expr", "wm.io.files.os.getcwd()", *CUBE], "got wm.io"),
    (["mesh", "--expr", "(lambda m: m.io)(wm)", *CUBE], "lambda"),
    (["mesh", "--expr", "[wm][0].io", *CUBE], "wm alone"),
    (["mesh", "--expr", "2 + 3", *CUBE], "constant 5"),
    (["mesh", "--expr", "x**2 +", *CUBE], "--expr"),
    (["mesh", "--expr", DEGREE6], "expected --bounds with --expr"),
    (["mesh", "--expr", DEGREE6, "--bounds", "0", "0", "0", "1", "1"], "--bounds"),
    (["mesh", "--expr", DEGREE6, "--bounds", "1", "0", "0", "0", "1", "1"], "x0 < x1"),
    (["curve", "--expr", "1 - x**2 - z**2", "--bounds", "-1", "-1", "1", "1"], "the names are x, y, sqrt"),
    (["curve", "{file}", "--bounds", "-1", "-1", "1", "1"], "rings.py:shape depends on z"),
    (["mesh", "{file}:count"], "got int"),
    (["mesh", "{file}:ring"], "shapes found there: ['shape', 'thin']"),
    (["mesh", "{missing}"], "no such shape file"),
    (["mesh", "{broken}"], "broken.py, line 3: ZeroDivisionError"),
    (["mesh", "{nobounds}"], "defines no 'bounds'"),
])
def test_bad_shapes_are_reported_with_the_users_words(torus_file, tmp_path, capsys, argv, needle):
    broken = tmp_path / "broken.py"
    broken.write_text("import warpmesh as wm\n\nshape = 1 / 0\n")
    nobounds = tmp_path / "nobounds.py"
    nobounds.write_text("import warpmesh as wm\nshape = wm.sphere(1)\n")
    names = dict(file=torus_file, missing=tmp_path / "missing.py", broken=broken, nobounds=nobounds)
    assert main([a.format(**names) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("warpmesh: error:") and needle in err, err


def test_version(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f"warpmesh {wm.__version__}"


def _figures(text: str) -> tuple[dict, dict, list]:
    """(figure lines {label: value}, stage times {stage: seconds}, table rows) of a printed report."""
    figures, times, rows, section = {}, {}, [], None
    for line in text.splitlines():
        if line.startswith("|"):
            rows.append([c.strip() for c in line.strip("|").split("|")])
        elif line.endswith(":") and not line.startswith(" "):
            section = line[:-1]
        elif section == "time" and line.startswith("  "):
            label, value = re.split(r"\s{2,}", line.strip())
            assert value.endswith(" s") and label not in times, line
            times[label] = float(value[:-2])
        elif not line.startswith(" "):
            section = None
            label, value = re.split(r"\s{2,}", line, maxsplit=1)
            assert label not in figures, f"{label!r} printed twice"
            figures[label] = value
    return figures, times, rows


def _numbers(values) -> list[float]:
    """The numbers of each figure (a grid's 33 x 33 x 33 counts once), small counts left out."""
    found = []
    for v in values:
        found += {float(n.replace(",", "")) for n in re.findall(r"(?<![\w.])-?\d[\d,]*\.?\d*(?:e[-+]?\d+)?", v)}
    return [n for n in found if abs(n) >= 10 or n != int(n)]  # counts below 10 may coincide honestly


@pytest.mark.parametrize("argv", [
    ["mesh", "--example", "part", "--resolution", "32"],
    ["mesh", "--example", "sphere", "--method", "mc", "--resolution", "16", "--optimize"],
])
def test_the_printed_statistics_hold_no_figure_twice(tmp_path, capsys, argv):
    out = tmp_path / "m.ply"
    assert main([*argv, "-o", str(out)]) == 0
    text = capsys.readouterr().out
    figures, times, rows = _figures(text)
    mesh = wm.load(out)
    # no figure under two names: every number of some size appears once, tables included
    cells = [c for row in rows[2:] for c in row[1:]]
    # (not the written path: pytest's tmp folders are numbered, pytest-72 would count as a 72)
    numbers = _numbers([v for k, v in figures.items() if k != "written"] + cells)
    assert len(numbers) == len(set(numbers)), sorted(n for n in numbers if numbers.count(n) > 1)
    for alias in ("ne", "n cells", "n triangles", "q mean", "q worst", "vertices", "triangles count", "signed volume"):
        assert alias not in figures
    assert f"{mesh.n_cells:,}" in text and f"{mesh.n_points:,}" in text  # the result, once
    assert figures["bounds"].count("(") == 2 and "\n" not in figures["bounds"]
    assert figures["written"].startswith(str(out)) and figures["written"].endswith(" MB)")
    # stage times add up to the total (each printed to the millisecond)
    assert "other" in times and sum(v for k, v in times.items() if k != "total") == pytest.approx(
        times["total"], abs=0.0005 * len(times) + 1e-9)
    if "--optimize" in argv:
        assert [r[0] for r in rows[2:]] == ["before", "after"]
        assert f"{mesh.n_points:,}" == rows[3][1]  # the "after" row is the written mesh
        assert not re.search(r"tolerance\s+[\d.]+\s*s", text) and "{" not in text  # no dict dumps, no "0.009s"
        assert "optimize" in times


def test_json_is_the_whole_statistics_and_nothing_else(capsys):
    assert main(["mesh", "--example", "sphere", "--resolution", "16", "--json"]) == 0
    out = capsys.readouterr().out
    stats = json.loads(out)  # the whole of stdout
    shape, bounds = wm.example("sphere")
    expected = wm.mesh_surface(shape, bounds=bounds, resolution=16, evaluator="interpreter").stats()
    assert set(expected) <= set(stats) and stats["np"] == expected["np"] and stats["euler"] == 2
    t = stats["time"]
    assert t["total"] == pytest.approx(sum(v for k, v in t.items() if k != "total"))


def test_domain_takes_every_3d_method_the_library_has(tmp_path):
    """The README's `--method delaunay|tetgen`: tetgen was not a choice of the CLI."""
    import meshio

    for method in ("stuffing", "delaunay", "tetgen"):
        out = tmp_path / f"{method}.msh"
        assert main(["domain", "--example", "torus", "--size", "0.2", "--method", method, "-o", str(out)]) == 0
        back = meshio.gmsh.read(str(out))
        assert "tetra" in back.cells_dict and len(back.cells_dict["tetra"]) > 100


def test_bounds_in_scientific_notation_and_infinite_ones(capsys):
    """``--bounds -1.2e0 ...`` are values (argparse took ``-1.2e0`` for an unknown flag and said
    "--bounds: expected at least one argument"); ``-inf`` reaches the bounds check, which names it."""
    argv = ["mesh", "--expr", "1 - x**2 - y**2 - z**2", "--resolution", "12", "--json", "--bounds"]
    assert main(argv + ["-1.2e0", "-1.2E0", "-12e-1", "1.2", "1.2", "1.2"]) == 0
    assert json.loads(capsys.readouterr().out)["euler"] == 2
    assert main(argv + ["-inf", "-1", "-1", "1", "1", "1"]) == 2
    assert "expected finite --bounds" in capsys.readouterr().err
