"""A fresh process: ``import warpmesh`` imports none of the heavy packages, every public
name still works (lazily), Warp starts quietly before the first kernel, generated tables
are loaded from the install's cache, and a compile of warpmesh's kernels says so, once.

Behaviour only, never a time (``benchmarks/bench_startup.py`` times it)."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.kernels.startup import COMPILE_NOTICE, NO_DRIVER

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("warp", "scipy", "pyvista", "trimesh", "meshio")


def _run(code: str, env: dict | None = None) -> subprocess.CompletedProcess:
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                         env={**os.environ, **(env or {})})
    assert run.returncode == 0, run.stderr
    return run


def _loaded_after(code: str) -> set[str]:
    """The heavy packages in ``sys.modules`` after running ``code`` in a fresh process."""
    out = _run(code + f"\nimport sys, json; print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))")
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


# -- what a fresh process imports --------------------------------------------------------------
def test_import_warpmesh_imports_no_heavy_package():
    assert _loaded_after("import warpmesh") == set()


def test_version_and_building_shapes_need_no_mesher():
    assert _loaded_after("import warpmesh as wm\nassert wm.__version__\nwm.sphere(1.0) - wm.box(0.5)") \
        <= {"warp"}  # the opcodes live with the kernels


def test_meshing_a_shape_imports_neither_scipy_nor_the_converters():
    code = ("import warpmesh as wm\npart, bounds = wm.example('part')\n"
            "m = wm.mesh_surface(part, bounds=bounds, resolution=12)\nassert m.n_cells > 0")
    assert _loaded_after(code) == {"warp"}


def test_the_cli_parser_imports_no_scipy():
    code = "from warpmesh.cli.commands import _parser\n_parser()"
    assert "scipy" not in _loaded_after(code)


# -- the public face, lazily -------------------------------------------------------------------
def test_every_public_name_resolves():
    for name in wm.__all__:
        assert getattr(wm, name) is not None, name
    x, _, _ = wm.coords()
    assert isinstance(wm.min(x, 1.0), wm.Expr) and isinstance(wm.max(x, 1.0), wm.Expr)
    assert isinstance(wm.abs(x), wm.Expr)
    assert wm.mesh.Mesh is wm.Mesh and wm.transforms.__name__ == "warpmesh.modify.transforms"
    assert wm.geometry.__name__ == "warpmesh.frep.geometry" and wm.surface.__name__ == "warpmesh.surface"


def test_dir_lists_all_and_unknown_names_raise():
    assert set(wm.__all__) <= set(dir(wm))
    assert {"abs", "min", "max", "surface", "kernels"} <= set(dir(wm))
    with pytest.raises(AttributeError, match="no_such_name"):
        wm.no_such_name  # noqa: B018


def test_static_imports_match_the_lazy_table():
    """The ``TYPE_CHECKING`` imports (what editors and type checkers read) are the lazy table."""
    tree = ast.parse((ROOT / "warpmesh" / "__init__.py").read_text())
    block = next(n for n in tree.body if isinstance(n, ast.If) and getattr(n.test, "id", "") == "TYPE_CHECKING")
    static = {}
    for node in block.body:
        for a in node.names:
            static[a.asname] = f"{node.module}.{a.name}" if a.name in wm._MODULES else node.module
    lazy = {**wm._ORIGIN, **wm._MODULES}
    assert static == lazy


# -- Warp's start-up -----------------------------------------------------------------------------
def test_warp_starts_with_the_first_kernel_module_not_with_the_package():
    code = ("import warpmesh, sys\nassert 'warp' not in sys.modules\n"
            "import warp as wp\nassert wp._src.context.runtime is None\n"
            "from warpmesh.kernels import tape\n"
            "assert wp._src.context.runtime is not None and wp.config.log_level >= wp.LOG_WARNING")
    _run(code)


# exit handlers run last-registered first: "before" was registered before warpmesh started
# Warp, "after" after it; each prints how many objects the collector has frozen
_EXIT_PROBE = ("import atexit, gc, sys\n"
               "atexit.register(lambda: print('before', gc.get_freeze_count(), flush=True))\n"
               "import warpmesh as wm\n"
               "m = wm.mesh_surface(wm.sphere(1), bounds=((-1.2,)*3, (1.2,)*3), resolution=8)\n"
               "{extra}"
               "atexit.register(lambda: print('after', gc.get_freeze_count(), flush=True))\n")


def _exit_counts(extra: str = "") -> dict[str, int]:
    out = _run(_EXIT_PROBE.format(extra=extra)).stdout.split()
    return {out[i]: int(out[i + 1]) for i in range(0, len(out) - 1, 2) if out[i] in ("before", "after")}


def test_exit_freezes_the_live_objects_after_the_programs_own_exit_handlers():
    counts = _exit_counts()
    assert counts["after"] == 0  # the program's later handlers run with the collector untouched
    assert counts["before"] > 10_000  # Warp's and warpmesh's objects are out of the exit's collections


def test_garbage_cycles_are_still_finalised_at_exit(tmp_path):
    """A reference cycle that is garbage at exit still has its ``__del__`` run and its
    temporary file removed (the freeze came first and kept them for good)."""
    code = ("import sys, tempfile, warpmesh as wm\n"
            "m = wm.mesh_surface(wm.sphere(1), bounds=((-1.2,)*3, (1.2,)*3), resolution=8)\n"
            "class Cycle:\n"
            "    def __init__(self, path):\n        self.me, self.path = self, path\n"
            "    def __del__(self):\n        open(self.path, 'w').write('finalised')\n"
            "Cycle(sys.argv[1])\n"
            "t = tempfile.NamedTemporaryFile(dir=sys.argv[2], delete=True)\nt.me = t\ndel t\n")
    (tmp_path / "tmp").mkdir()
    run = subprocess.run([sys.executable, "-c", code, str(tmp_path / "del.txt"), str(tmp_path / "tmp")],
                         capture_output=True, encoding="utf-8", timeout=600)
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "del.txt").read_text() == "finalised"
    assert list((tmp_path / "tmp").iterdir()) == []


def test_the_exit_freeze_can_be_unregistered():
    counts = _exit_counts("from warpmesh.kernels.startup import freeze_at_exit\natexit.unregister(freeze_at_exit)\n")
    assert counts == {"after": 0, "before": 0}


@pytest.mark.parametrize("code", ["import warpmesh",
                                  "import sys; sys.argv = ['warpmesh', '--help']\n"
                                  "from warpmesh.cli import main\ntry:\n    main()\nexcept SystemExit:\n    pass",
                                  "import warpmesh as wm; wm.mesh_surface(wm.sphere(1), bounds=((-1.2,)*3, (1.2,)*3), "
                                  "resolution=8)"])
def test_no_cuda_warning_without_cuda(code):
    assert NO_DRIVER not in _run(code).stderr


def test_other_start_up_output_is_kept(monkeypatch, capfd):
    """The filter drops the one line only: what else start-up prints still shows."""
    import warp as wp

    from warpmesh.kernels import startup

    def fake_init():
        os.write(2, f"Warp CUDA warning: {NO_DRIVER}. GPU execution will not be available.\n".encode())
        os.write(2, b"Warp: something else worth seeing\n")
        monkeypatch.setattr(wp._src.context, "runtime", object())

    monkeypatch.setattr(wp._src.context, "runtime", None)
    monkeypatch.setattr(startup.wp, "init", fake_init)
    startup.init_warp()
    err = capfd.readouterr().err
    assert NO_DRIVER not in err and "something else worth seeing" in err
    startup.init_warp()  # initialised: nothing runs twice
    assert capfd.readouterr().err == ""


_COMPILE_ONE = """
import warp as wp
from warpmesh.kernels import numbering, startup
assert wp.config.kernel_cache_dir.startswith({cache!r}), wp.config.kernel_cache_dir
wp.load_module(numbering, device="cpu")
print(startup.compile_seconds())
"""


def test_a_compile_says_so_once_and_a_warm_cache_says_nothing(tmp_path):
    """One small kernel module compiled into an empty kernel cache (``WARP_CACHE_PATH``)."""
    cache = str(tmp_path / "warp-cache")
    os.makedirs(cache)
    code = _COMPILE_ONE.format(cache=os.path.realpath(cache))
    first = _run(code, env={"WARP_CACHE_PATH": cache})
    notices = [line for line in first.stderr.splitlines() if line.startswith("warpmesh: compiling")]
    assert len(notices) == 1, first.stderr
    prefix = COMPILE_NOTICE.split("{")[0]
    assert notices[0].startswith(prefix) and notices[0].endswith(" s)")
    assert float(first.stdout.split()[-1]) > 0.0
    second = _run(code, env={"WARP_CACHE_PATH": cache})
    assert "warpmesh: compiling" not in second.stderr
    assert float(second.stdout.split()[-1]) == 0.0


# -- the command line's stage times ----------------------------------------------------------------
def test_cli_stage_times_add_up_to_the_total_from_the_process_start():
    code = ("import sys\nfrom warpmesh.cli import main\n"
            "sys.argv = ['warpmesh', 'mesh', '--example', 'sphere', '--resolution', '8', '--json']\nsys.exit(main())")
    times = json.loads(_run(code).stdout)["time"]
    assert next(iter(times)) == "import" and times["import"] > 0.0
    assert sum(v for k, v in times.items() if k != "total") == pytest.approx(times["total"], rel=1e-9)


def test_clock_moves_compile_time_to_its_own_stage(monkeypatch):
    from warpmesh.cli.report import Clock
    from warpmesh.kernels import startup

    spent = [0.0]
    monkeypatch.setattr(startup, "compile_seconds", lambda: spent[0])
    clock = Clock(start=0.0)  # the stage "import" runs from 0.0: any start before now
    with clock.stage("mesh"):
        spent[0] += 2.0  # as if Warp compiled for 2 s inside the stage
    t = clock.times()
    assert list(t)[:3] == ["import", "mesh", "compile"] and t["compile"] == 2.0
    assert sum(v for k, v in t.items() if k != "total") == pytest.approx(t["total"])


# -- generated tables: once per install --------------------------------------------------------------
def test_cached_tables_equal_the_generators_output(tmp_path, monkeypatch):
    from warpmesh.kernels import mc33_tables as M33
    from warpmesh.kernels import mc_tables as MC
    from warpmesh.kernels import mt_tables as MT
    from warpmesh.kernels import table_cache

    monkeypatch.setenv("WARPMESH_CACHE_DIR", str(tmp_path))
    for name, build, sources, loaded in [
        ("mc", MC._build, (MC.__file__,), (MC.BASE_CONFIGS, MC.MAX_TRIS, MC.TRI_COUNT, MC.TRI_TABLE)),
        ("mc33", M33._build, (M33.__file__, MC.__file__),
         (M33.BASE_CASES, M33.CASE_OFFSET, M33.INTERIOR_TEST, M33.CASE_FEASIBLE, M33.CASE_TRI_COUNT, M33.MAX33,
          M33.CASE_TRIS, M33.CASE_INTERIOR)),
        ("mt", MT._build, (MT.__file__, MC.__file__),
         (MT.MT_TRI_COUNT, MT.MT_TRIS, MT.MAX_MT_TRIS, MT.MT_QUAD_COUNT, MT.MT_QUADS, MT.MAX_MT_QUADS)),
    ]:
        generated = build()
        path = table_cache.table_path(name, *sources)
        assert not path.exists()
        stored = table_cache.cached(name, build, *sources)  # generates and writes
        assert path.exists()
        again = table_cache.cached(name, lambda: pytest.fail("generated twice"), *sources)  # reads the file
        for values in (stored, again, loaded):  # the module's tables too (from the user's cache or generated)
            assert len(values) == len(generated)
            for v, g in zip(values, generated):
                if isinstance(g, int):
                    assert type(v) is int and v == g
                else:
                    assert v.dtype == g.dtype and np.array_equal(v, g)


def test_a_changed_generator_or_a_broken_file_is_generated_again(tmp_path, monkeypatch):
    from warpmesh.kernels import table_cache

    monkeypatch.setenv("WARPMESH_CACHE_DIR", str(tmp_path))
    src = tmp_path / "gen.py"
    src.write_text("A = 1\n")
    first = table_cache.table_path("t", src)
    table_cache.cached("t", lambda: (np.arange(3), 7), src)
    first.write_bytes(b"not a zip file")
    assert table_cache.cached("t", lambda: (np.arange(4), 8), src)[1] == 8  # unreadable: generated
    src.write_text("A = 2\n")
    assert table_cache.table_path("t", src) != first  # an edited generator names another file
    assert table_cache.cached("t", lambda: (np.arange(5), 9), src)[1] == 9


def test_numbering_modules_load_as_attributes():
    """The README's wm.numbering.high_order.jacobians and wm.numbering.renumber.format_table
    raised AttributeError in a fresh process (the modules load lazily)."""
    import subprocess
    import sys

    code = ("import warpmesh as wm; print(wm.numbering.high_order.jacobians.__name__, "
            "wm.numbering.renumber.format_table.__name__, 'coloring' in dir(wm.numbering))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["jacobians", "format_table", "True"]
