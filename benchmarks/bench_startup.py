#!/usr/bin/env python3
"""A fresh process (issue 22, target 2): what a user waits for before the first mesh.

Every case runs in a new Python process (``python -c CODE``), ``--repeat`` times
(default 5) in round-robin order, after one untimed round that warms the disk caches, the
Warp kernel cache, warpmesh's table cache and Python's bytecode cache (the children run
without ``PYTHONDONTWRITEBYTECODE``, as an installed package has its ``.pyc`` files). Times are the parent's wall clock around
the child (interpreter start and exit included) and the child's CPU seconds (user + sys,
``getrusage(RUSAGE_CHILDREN)``); the tables give medians.

Cases:

- ``python``: ``pass``, the interpreter alone;
- ``import numpy``, ``import warp`` (Warp's own import, not initialised), ``import warp +
  init`` (``wp.init()``): the floor under any Warp program;
- ``import warpmesh``: the package (target: <= 0.3 s);
- ``part 128``: ``import warpmesh``, ``wm.example("part")``, ``wm.mesh_surface(part,
  bounds=bounds, resolution=128)`` with the Warp kernel cache and the table cache warm
  (target: <= 0.5 s);
- ``part 128, no table cache``: the same with ``WARPMESH_CACHE_DIR`` set to an empty
  folder per run, so the marching-cubes tables are generated in the process (what every
  process paid before the table cache);
- ``cli part 128``: ``python -m warpmesh.cli mesh --example part --resolution 128 --json``;
  the stages it prints must add up to its printed total (checked), and the table shows the
  printed total beside the wall time measured here.

Ratios: each case against ``import numpy`` and against ``import warp + init`` (what
warpmesh cannot go below while it imports Warp), and the two targets.

``--baseline DIR``: also run the warpmesh cases ("before: ...") with ``PYTHONPATH=DIR``, a
checkout of an earlier commit, in the same rounds (``git worktree add DIR <commit>``;
the script links ``DIR/warpmesh/kernels`` to ``DIR/kernels`` so that the checkout's own
kernels are imported, and checks in each child that warpmesh comes from ``DIR``).

Run:  python benchmarks/bench_startup.py [--repeat 5] [--baseline DIR] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import finish, load_banner, version

PART = ("import warpmesh as wm\npart, bounds = wm.example('part')\n"
        "m = wm.mesh_surface(part, bounds=bounds, resolution=128)\nassert m.n_cells > 0\n")
CASES = {
    "python": "pass",
    "import numpy": "import numpy",
    "import warp": "import warp",
    "import warp + init": "import warp\nwarp.config.log_level = warp.LOG_WARNING\nwarp.init()",
    "import warpmesh": "import warpmesh",
    "part 128": PART,
    "part 128, no table cache": PART,
    "cli part 128": None,  # the command line, below
}
TARGETS = {"import warpmesh": 0.3, "part 128": 0.5}
CLI = ["-m", "warpmesh.cli", "mesh", "--example", "part", "--resolution", "128", "--json"]


def _child(name: str, code: str | None, baseline: str | None = None) -> tuple[float, float, dict | None]:
    """(wall s, CPU s, the CLI's printed times or None) of one fresh process."""
    # bytecode written and read as after `pip install` (which compiles it): a shell with
    # PYTHONDONTWRITEBYTECODE set would make every child compile warpmesh's sources anew
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    if baseline is not None:  # the checkout first on the path, the installed (editable) finder out of the way
        env["PYTHONPATH"] = baseline
        check = ("import sys, os\nsys.meta_path[:] = [f for f in sys.meta_path if not "
                 "getattr(f, '__module__', '').startswith('__editable__')]\nimport warpmesh\n"
                 f"assert os.path.realpath(warpmesh.__file__).startswith({os.path.realpath(baseline)!r}), "
                 "warpmesh.__file__\n")
        if code is None:  # the command line, as python -m warpmesh.cli
            code = f"import runpy\nsys.argv = ['warpmesh', *{CLI[2:]!r}]\nrunpy.run_module('warpmesh.cli', run_name='__main__')"
            name = "cli"
        code = check + code
    with tempfile.TemporaryDirectory(prefix="warpmesh-bench-") as empty:
        if name == "part 128, no table cache":
            env["WARPMESH_CACHE_DIR"] = empty
        argv = [sys.executable, *(CLI if code is None else ["-c", code])]
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        run = subprocess.run(argv, capture_output=True, text=True, env=env, timeout=900, cwd=empty, check=False)  # no ./warpmesh
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if run.returncode != 0:
        raise RuntimeError(f"{name} failed:\n{run.stderr}")
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    times = json.loads(run.stdout)["time"] if code is None or name == "cli" else None
    return wall, cpu, times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--json", help="write the results to this file")
    ap.add_argument("--baseline", help="a checkout of an earlier commit, run as 'before: <case>'")
    args = ap.parse_args()
    cases = {name: (code, None) for name, code in CASES.items()}
    if args.baseline:
        link = os.path.join(args.baseline, "warpmesh", "kernels")
        if not os.path.exists(link):
            os.symlink(os.path.join("..", "kernels"), link)
        for name in ("import warpmesh", "part 128", "cli part 128"):
            cases[f"before: {name}"] = (CASES[name], args.baseline)
    t_start = time.perf_counter()
    load0 = load_banner(f"fresh-process start-up, {os.cpu_count()} cores, Python {sys.version.split()[0]}, "
                        f"numpy {version('numpy')}, warp-lang {version('warp-lang')}")
    for name, (code, base) in cases.items():  # untimed: disk caches, Warp's kernel cache, the table cache
        _child(name, code, base)
    walls = {n: [] for n in cases}
    cpus = {n: [] for n in cases}
    printed, printed_before = [], []
    for _ in range(args.repeat):
        for name, (code, base) in cases.items():
            wall, cpu, times = _child(name, code, base)
            walls[name].append(wall)
            cpus[name].append(cpu)
            if times is not None:
                (printed if base is None else printed_before).append(times)
    med = {n: statistics.median(v) for n, v in walls.items()}
    cpu = {n: statistics.median(v) for n, v in cpus.items()}
    numpy_s, warp_s = med["import numpy"], med["import warp + init"]
    print(f"\nmedian of {args.repeat} fresh processes per case (wall includes interpreter start and exit)")
    print(f"{'case':28s} {'wall s':>8s} {'CPU s':>7s} {'/ numpy':>8s} {'/ warp+init':>12s} {'target':>8s}")
    for name in cases:
        target = TARGETS.get(name)
        verdict = "" if target is None else f"{target:.1f} s {'met' if med[name] <= target else 'NOT met'}"
        print(f"{name:28s} {med[name]:8.3f} {cpu[name]:7.3f} {med[name] / numpy_s:8.2f} {med[name] / warp_s:12.2f}"
              f" {verdict:>8s}")
    gain = med["part 128, no table cache"] - med["part 128"]
    print(f"\ntable cache: part 128 is {gain:.3f} s faster with the tables loaded than generated")
    for name, target in TARGETS.items():
        print(f"{name}: {med[name]:.3f} s = {med[name] / target:.2f} x the {target} s target")
    print(f"part 128 above the Warp floor (import warp + init): {med['part 128'] - warp_s:.3f} s")
    sums = [abs(sum(v for k, v in t.items() if k != "total") - t["total"]) for t in printed]
    cli_total = statistics.median(t["total"] for t in printed)
    cli_import = statistics.median(t.get("import", 0.0) for t in printed)
    print(f"\ncli part 128: printed total {cli_total:.3f} s (import stage {cli_import:.3f} s), wall {med['cli part 128']:.3f}"
          f" s; printed stages add up to the printed total within {max(sums):.1e} s")
    print("stages of the last run: " + ", ".join(f"{k} {v:.3f}" for k, v in printed[-1].items()))
    if printed_before:
        total = statistics.median(t["total"] for t in printed_before)
        staged = statistics.median(sum(v for k, v in t.items() if k not in ("total", "other")) for t in printed_before)
        print(f"before: cli part 128 printed total {total:.3f} s (stages {staged:.3f} s + other), wall "
              f"{med['before: cli part 128']:.3f} s")
        for name in ("import warpmesh", "part 128", "cli part 128"):
            print(f"{name}: before {med['before: ' + name]:.3f} s, now {med[name]:.3f} s "
                  f"({med['before: ' + name] / med[name]:.1f}x faster; CPU {cpu['before: ' + name]:.3f} -> {cpu[name]:.3f} s)")
    finish(t_start, load0, args.json, {"median_wall_s": med, "median_cpu_s": cpu, "walls": walls, "cpus": cpus,
                                       "cli_times": printed})


if __name__ == "__main__":
    main()
