#!/usr/bin/env python3
"""Issue 22's whole table in one run: every row re-measured by the benchmark that owns it.

Each group of rows runs one of the existing scripts of ``benchmarks/`` as a subprocess
with ``--json`` (or, for "first-run", one command-line process with empty caches) and
reads its results back; both tools of a row are always timed in the same process run of
that script, on the same input, with that script's own method (warm-up, round-robin,
allocator setting). Nothing is timed here except the first-run process. The rows:

=========== ======================================================================================
group       script and what its rows compare (full size; ``--quick`` in brackets)
=========== ======================================================================================
volume      ``bench_volume.py --cases sphere,gyroid,labels --sizes 257,320`` [65]: warpmesh mc33 and
            mc on in-memory float32 (sphere, gyroid) and uint8 (labels) volumes vs VTK flying edges
            (2 threads); the sphere also vs scikit-image. Target 1: <= 1x VTK.
surface     ``bench_surface.py --cases part,large --methods mc33 --slab-voxels 16777216`` [--quick:
            64^3 part, 128^3 volumes]: the CSG part at 256^3 from the function, min/max booleans vs
            Warp ``sparse_marching_cubes`` (target 6: <= 1/3) and R-functions vs numpy + VTK flying
            edges (target 6: <= 1/5); the 320^3 float field (32.8 M samples) and the 4-label uint8
            volume vs VTK flying edges / discrete flying edges, each tool in a fresh process.
labels      ``bench_labels.py --synthetic 0 --no-memory --smoothing 0 --no-crossings``: all 25 labels
            of pyvista's frog, warpmesh shared interfaces and separate surfaces vs ``contour_labels``.
startup     ``bench_startup.py`` [--repeat 1]: ``import warpmesh`` (target 2: <= 0.3 s) and import +
            part at 128^3 in a fresh process (<= 0.5 s), wall seconds, against ``import numpy`` and
            ``import warp`` + ``wp.init()``.
first-run   ``python -m warpmesh.cli mesh --example part --resolution 128 --json`` with empty
            ``WARP_CACHE_PATH`` and ``WARPMESH_CACHE_DIR``: a new machine. Target 2: the one-line
            compile notice on stderr, and printed stages that add up to the printed total.
optimize    ``bench_optimize.py --sections optimize --shapes part --featuredeg 30 --no-frog``
            [--quick --resolution 32]: ``optimize`` of the part's MC 64^3 surface vs pymeshlab
            isotropic remeshing. Target 3: <= 1x, worst Q <= 2, closed.
simplify    ``bench_optimize.py --sections simplify`` [--quick --shapes part --no-frog]: 10 % of the
            MC 128^3 meshes and of frog label 10 vs pymeshlab quadric. Target 3: <= 2x, closed.
stats       ``bench_stats.py --resolutions 1024`` [420: ~1 M triangles]: ``Mesh.stats()`` on ~6 M
            triangles vs the ``mesh_surface`` call that made them. Target 4: < 0.10x.
renumber    ``bench_renumber.py --methods gibbs`` on the meshes of 100 k nodes and more [plate-h0.01,
            part-R192]: Gibbs vs scipy RCM. Target 5: time <= 1x (nodes/s at least RCM's), profile
            <= RCM's.
adaptive    ``bench_adaptive.py --shapes part --sizes 256`` [64]: the adaptive part vs the culled
            grid. Target 7: <= 1x.
=========== ======================================================================================

ratio = warpmesh / peer, in time (> 1: warpmesh slower), as in the issue's table; for
``stats`` it is stats() / meshing time, for startup rows warpmesh / ``import numpy`` (the
targets there are absolute seconds). CPU seconds are shown where the script records them.

``--baseline DIR`` (a checkout of an earlier commit: ``git worktree add DIR <commit>``)
runs every group a second time, right after the first, with ``PYTHONPATH=DIR`` (the
current scripts, the old warpmesh; ``DIR/warpmesh/kernels`` is linked to ``DIR/kernels``
as ``bench_startup.py --baseline`` does), and adds a "before" column: the old warpmesh
figure and its ratio to the peer *of that before run*. ``bench_startup.py`` gets
``--baseline`` itself (old and new in the same rounds). A script that needs an API the
old commit lacks fails there, and its "before" cells say so.

Every script's own output goes to ``--logs DIR`` (one file per script and run); the
``--json`` document holds the table rows and every script's whole JSON document.

Run:  python benchmarks/bench_table22.py [--quick] [--repeat N] [--only volume,stats | --skip first-run]
                                         [--baseline DIR] [--cache DIR] [--logs DIR] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from _report import finish, load_banner, version

GROUPS = ("volume", "surface", "labels", "startup", "first-run", "optimize", "simplify", "stats", "renumber",
          "adaptive")
#: Gibbs' target applies from this many nodes (issue 22, target 5)
BIG_MESHES = "plate-h0.005,plate-h0.0036,part-R192,degree6-R128,ball-R40-a6.5e-6,part-tet-R64"
COMPILE_NOTICE = "compiling Warp kernels, first run only"


# =============================================================================================
# rows and targets (pure logic)
# =============================================================================================
@dataclass(frozen=True)
class Target:
    """A target of the issue: ``quantity`` ("ratio", or "seconds": the warpmesh seconds)
    compared by ``op`` ("<=" or "<") with ``limit``, or ``quantity="conditions"``: the
    row's conditions alone (no figure to compare); ``label`` is what the table prints."""

    quantity: str
    op: str
    limit: float
    label: str

    def __post_init__(self):
        if self.quantity not in ("ratio", "seconds", "conditions"):
            raise ValueError(f"expected quantity 'ratio', 'seconds' or 'conditions', got {self.quantity!r}")
        if self.op not in ("<=", "<"):
            raise ValueError(f"expected op '<=' or '<', got {self.op!r}")


def at_most(limit: float, label: str | None = None) -> Target:
    """ratio <= limit (e.g. ``at_most(1)``: no slower than the peer)."""
    return Target("ratio", "<=", float(limit), label or f"<= {limit:g}x")


@dataclass
class Row:
    """One line of the table. ``seconds`` is warpmesh's time (for absolute targets),
    ``conditions`` are further requirements of the target, each (what, held)."""

    group: str
    task: str
    warpmesh: str
    peer: str
    ratio: float | None = None
    target: Target | None = None
    seconds: float | None = None
    conditions: list = field(default_factory=list)
    note: str = ""
    before: str = ""
    met: bool | None = None


def evaluate(row: Row) -> bool | None:
    """Whether ``row`` meets its target: None without a target or without the figure it
    needs; otherwise the comparison and every condition."""
    t = row.target
    if t is None:
        return None
    if t.quantity == "conditions":
        return all(held for _, held in row.conditions) if row.conditions else None
    value = row.ratio if t.quantity == "ratio" else row.seconds
    if value is None or math.isnan(value):
        return None
    ok = value <= t.limit if t.op == "<=" else value < t.limit
    return bool(ok and all(held for _, held in row.conditions))


def verdict(row: Row) -> str:
    """The "met?" cell: yes / NO / - (no target) / ? (figure missing); failed conditions named."""
    if row.target is None:
        return "-"
    if row.met is None:
        return "?"
    if row.met:
        return "yes"
    failed = [what for what, held in row.conditions if not held]
    return "NO" + (f" ({', '.join(failed)})" if failed else "")


def fmt_ratio(r: float | None) -> str:
    if r is None or math.isnan(r):
        return "-"
    return f"{r:.3g}x" if r < 10 else f"{r:.0f}x"


def format_table(rows: list[Row], with_before: bool = False) -> str:
    """The markdown table ``task | warpmesh | peer | ratio | target | met?`` (and
    ``before`` when asked), then the rows' notes as a numbered list."""
    head = ["task", "warpmesh", "peer", "ratio", "target", "met?"] + (["before"] if with_before else [])
    lines = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    notes = []
    for r in rows:
        task = r.task
        if r.note:
            notes.append(r.note)
            task += f" [{len(notes)}]"
        cells = [task, r.warpmesh, r.peer, fmt_ratio(r.ratio), r.target.label if r.target else "-", verdict(r)]
        if with_before:
            cells.append(r.before or "-")
        lines.append("| " + " | ".join(c.replace("|", "/") for c in cells) + " |")
    lines += [""] + [f"[{i}] {n}" for i, n in enumerate(notes, 1)]
    return "\n".join(lines)


def failed_row(group: str, task: str, message: str) -> Row:
    """A row for a measurement that did not happen (the script failed, a figure is missing)."""
    return Row(group, task, f"failed: {message}", "-")


def _s(x: float | None, cpu: float | None = None) -> str:
    if x is None:
        return "-"
    return f"{x:.3g} s" + (f" (CPU {cpu:.3g})" if cpu is not None else "")


# =============================================================================================
# the groups: the command of each, and its rows from the script's JSON document
# =============================================================================================
def volume_args(quick: bool) -> list[str]:
    return ["--cases", "sphere,gyroid,labels", "--sizes", "65" if quick else "257,320"]


def volume_rows(doc: dict) -> list[Row]:
    rows = []
    for r in doc["rows"]:
        what = {"sphere": "sphere volume", "gyroid": "gyroid-like volume", "labels": "uint8 label volume"}
        task = f"{what.get(r['case'], r['case'])} {r['n']}^3 in memory, {r['method']}"
        rows.append(Row("volume", task + " vs VTK flying edges", _s(r["warpmesh_s"], r.get("warpmesh_cpu_s")),
                        f"VTK flying edges (2 threads) {_s(r['vtk_fe_s'], r.get('vtk_cpu_s'))}",
                        r["warpmesh_s"] / r["vtk_fe_s"], at_most(1, "<= 1x (target 1)"), r["warpmesh_s"]))
        if r["case"] == "sphere" and not math.isnan(r.get("skimage_s", math.nan)):
            rows.append(Row("volume", task + " vs scikit-image", _s(r["warpmesh_s"]),
                            f"scikit-image (Lewiner) {_s(r['skimage_s'])}", r["warpmesh_s"] / r["skimage_s"]))
    return rows


def surface_args(quick: bool) -> list[str]:
    return ["--cases", "part,large", "--methods", "mc33", "--slab-voxels", "16777216"] + (["--quick"] if quick else [])


def _tool(rows: list[dict], name: str, exact: bool = False) -> dict | None:
    """The first measured row whose tool is ``name`` (or starts with it)."""
    for r in rows:
        tool = r.get("tool", "")
        if (tool == name if exact else tool.startswith(name)) and "unavailable" not in r and "error" not in r:
            return r
    return None


def surface_rows(doc: dict) -> list[Row]:
    default = doc["environment"].get("warpmesh default method", "mc")
    wm_name = "warpmesh mc" if default == "mc" else f"warpmesh {default}"
    out = []
    for c in doc["cases"]:
        rows = c["rows"]
        if c["case"] in ("part-minmax", "part-rfunction"):
            n = c["cells"]
            w = _tool(rows, wm_name, exact=True)
            if c["case"] == "part-minmax":
                task, peer_name, target = (f"CSG part, min/max booleans, {n}^3 from the function",
                                           "Warp sparse_marching_cubes", at_most(1 / 3, "<= 0.333x (target 6)"))
            else:
                task, peer_name, target = (f"CSG part, R-function booleans, {n}^3 from the function",
                                           "numpy + VTK flying edges", at_most(1 / 5, "<= 0.2x (target 6)"))
            p = _tool(rows, peer_name)
            if w is None or p is None:
                out.append(failed_row("surface", task, f"no '{wm_name}' or '{peer_name}' row in bench_surface"))
                continue
            extract = w.get("stages_s", {}).get("extract")
            wcell = f"{_s(w['total_s'])}, {default}, {w['triangles']:,} tri" + (
                f" (extract stage {extract:.3g} s)" if extract is not None else "")
            pcell = f"{peer_name} {_s(p['total_s'])}, {p['triangles']:,} tri"
            if p.get("evaluate_s") is not None and peer_name.startswith("numpy"):
                pcell += f" (extraction alone {p['extract_s']:.3g} s)"
            out.append(Row("surface", task, wcell, pcell, w["total_s"] / p["total_s"], target, w["total_s"],
                           [("closed", bool(w["closed"]))]))
        elif c["case"].startswith("large-"):
            n = round(c["samples"] ** (1 / 3))
            kind = "float32 field" if "scalar" in c["case"] else "uint8 labels, 4 labels"
            peer_name = "VTK flying edges" if "scalar" in c["case"] else "VTK discrete flying edges"
            p = _tool(rows, peer_name)
            for method in ("mc33", "mc"):
                task = f"{n}^3 {kind} ({c['samples'] / 1e6:.1f} M samples), {method}, fresh process"
                w = _tool(rows, f"warpmesh {method},")
                if w is None or p is None:
                    out.append(failed_row("surface", task, f"no 'warpmesh {method}' or '{peer_name}' row"))
                    continue
                out.append(Row("surface", task, f"{_s(w['time_s'])}, peak extra {w['peak_extra_mb']:.0f} MB",
                               f"{peer_name} {_s(p['time_s'])}, peak extra {p['peak_extra_mb']:.0f} MB",
                               w["time_s"] / p["time_s"], at_most(1, "<= 1x (target 1)"), w["time_s"],
                               [("closed", bool(w["closed"]))]))
    return out


def labels_args(quick: bool) -> list[str]:
    return ["--synthetic", "0", "--no-memory", "--smoothing", "0", "--no-crossings"]


def labels_rows(doc: dict) -> list[Row]:
    rows = {r["tool"]: r for r in doc["rows"]}
    vtk = rows.get("VTK contour_labels('all')")
    out = []
    for name, what in (("warpmesh shared (surface nets)", "shared interfaces (surface nets)"),
                       ("warpmesh separate (mc33, per label)", "separate surfaces, every interface twice")):
        task = f"all 25 labels of pyvista's frog, {what}"
        w = rows.get(name)
        if w is None or vtk is None:
            out.append(failed_row("labels", task, f"no '{name}' or contour_labels row in bench_labels"))
            continue
        out.append(Row("labels", task, f"{_s(w['time_s'], w.get('cpu_s'))}, {w['triangles']:,} tri",
                       f"pyvista contour_labels {_s(vtk['time_s'], vtk.get('cpu_s'))}, {vtk['triangles']:,} tri",
                       w["time_s"] / vtk["time_s"], note="issue 22 sets no ratio for the frog; target 1 (uint8 "
                       "labels at most VTK flying edges' time) is checked on the label volumes above"
                       if name.startswith("warpmesh shared") else ""))
    return out


def startup_args(quick: bool) -> list[str]:
    return []


def startup_rows(doc: dict) -> list[Row]:
    wall, cpu = doc["median_wall_s"], doc["median_cpu_s"]
    numpy_s, floor = wall["import numpy"], wall["import warp + init"]
    out = [Row("startup", "`python -c \"import warpmesh\"`", _s(wall["import warpmesh"], cpu["import warpmesh"]),
               f"import numpy {_s(numpy_s, cpu['import numpy'])}", wall["import warpmesh"] / numpy_s,
               Target("seconds", "<=", 0.3, "<= 0.3 s (target 2)"), wall["import warpmesh"]),
           Row("startup", "fresh process: import + part at 128^3 (kernel cache warm)",
               _s(wall["part 128"], cpu["part 128"]), f"import numpy {_s(numpy_s)}; import warp + init "
               f"{_s(floor, cpu['import warp + init'])}", wall["part 128"] / numpy_s,
               Target("seconds", "<=", 0.5, "<= 0.5 s (target 2)"), wall["part 128"],
               note=f"part 128 with the tables generated in the process: {_s(wall['part 128, no table cache'])}; "
                    f"the CLI on the part: {_s(wall['cli part 128'])}")]
    for r in out:
        key = "import warpmesh" if r.task.startswith("`") else "part 128"
        if f"before: {key}" in wall:
            r.before = f"{_s(wall['before: ' + key], cpu['before: ' + key])}, same rounds"
    return out


def first_run(baseline: str | None, logs: str, tag: str) -> dict:
    """The CLI on the part at 128^3 in a fresh process with empty Warp kernel and warpmesh
    caches (a new machine): wall, the printed stages, whether the compile notice appeared."""
    with tempfile.TemporaryDirectory(prefix="warpmesh-first-run-") as tmp:
        env = dict(os.environ, WARP_CACHE_PATH=os.path.join(tmp, "warp"), WARPMESH_CACHE_DIR=os.path.join(tmp, "wm"))
        if baseline:
            env["PYTHONPATH"] = baseline
        argv = [sys.executable, "-m", "warpmesh.cli", "mesh", "--example", "part", "--resolution", "128", "--json"]
        t0 = time.perf_counter()
        run = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=tmp, check=False)
        wall = time.perf_counter() - t0
    with open(os.path.join(logs, f"first-run{tag}.log"), "w") as fh:
        fh.write(f"$ {' '.join(argv)}\n--- stdout\n{run.stdout}\n--- stderr\n{run.stderr}")
    if run.returncode != 0:
        raise RuntimeError(f"exit status {run.returncode}: {(run.stderr.strip().splitlines() or ['?'])[-1][:160]}")
    times = json.loads(run.stdout)["time"]
    return {"wall_s": wall, "time": times, "notice": COMPILE_NOTICE in run.stderr,
            "stderr_lines": run.stderr.strip().splitlines()}


def first_run_rows(doc: dict) -> list[Row]:
    t = doc["time"]
    staged = sum(v for k, v in t.items() if k != "total")
    adds_up = abs(staged - t["total"]) <= 0.01 * t["total"] + 1e-3
    return [Row("first-run", "first run on a new machine (empty kernel and table caches), CLI part 128^3",
                f"wall {_s(doc['wall_s'])}; printed total {t['total']:.3g} s, compile {t.get('compile', 0):.3g} s",
                "-", None, Target("conditions", "<=", 0.0, "notice + stages add up (target 2)"),
                doc["wall_s"], [("compile notice on stderr", doc["notice"]),
                                (f"stages add up ({staged:.3g} of {t['total']:.3g} s)", adds_up)],
                note="stderr: " + " / ".join(doc["stderr_lines"][:3]) if doc["stderr_lines"] else "stderr: empty")]


def optimize_args(quick: bool) -> list[str]:
    return ["--sections", "optimize", "--shapes", "part", "--featuredeg", "30", "--no-frog"] + (
        ["--quick", "--resolution", "32"] if quick else [])


def _optimize_like_rows(doc: dict, group: str) -> list[Row]:
    out = []
    for c in doc["cases"]:
        if c["section"] != group:
            continue
        rows = c["rows"]
        w = _tool(rows, f"warpmesh {group}")
        p = _tool(rows, "pymeshlab remesh" if group == "optimize" else "pymeshlab quadric")
        inp = next((r for r in rows if r.get("input")), {})
        if group == "optimize":
            task = f"`optimize` of the {c['case']}'s {inp.get('tool', 'MC')[7:]} surface ({inp.get('ne', 0):,} tri)"
            target = at_most(1, "<= 1x, worst Q <= 2 (target 3)")
        else:
            task = f"`simplify` to 10 % of the {c['case']} ({inp.get('tool', '')[7:]}, {inp.get('ne', 0):,} tri)"
            target = at_most(2, "<= 2x, closed (target 3)")
        if w is None or p is None:
            out.append(failed_row(group, task, f"no warpmesh or pymeshlab row in bench_optimize ({c['case']})"))
            continue
        conds = [("closed", w["bad_edges"] == 0)]
        if group == "optimize":
            conds.insert(0, (f"worst Q {w['worst_q']:.3g}", w["worst_q"] <= 2.0))
        out.append(Row(group, task, f"{_s(w['time_s'], w.get('cpu_s'))}, worst Q {w['worst_q']:.3g}, "
                       f"{w['ne']:,} tri", f"{p['tool']} {_s(p['time_s'], p.get('cpu_s'))}, worst Q {p['worst_q']:.3g}",
                       w["time_s"] / p["time_s"], target, w["time_s"], conds,
                       note="crossings are not checked here (bench_optimize.py --sections embedding does)"
                       if group == "optimize" else ""))
    return out


def optimize_rows(doc: dict) -> list[Row]:
    return _optimize_like_rows(doc, "optimize")


def simplify_args(quick: bool) -> list[str]:
    return ["--sections", "simplify"] + (["--quick", "--shapes", "part", "--no-frog"] if quick else [])


def simplify_rows(doc: dict) -> list[Row]:
    return _optimize_like_rows(doc, "simplify")


def stats_args(quick: bool) -> list[str]:
    return ["--resolutions", "420" if quick else "1024"]


def stats_rows(doc: dict) -> list[Row]:
    return [Row("stats", f"`stats()` on a {r['triangles'] / 1e6:.1f} M-triangle mesh (part at {r['resolution']})",
                _s(r["stats_s"], r.get("stats_cpu_s")), f"meshing it: mesh_surface {_s(r['mesh_s'])}",
                r["stats_s"] / r["mesh_s"], Target("ratio", "<", 0.10, "< 0.1x the meshing (target 4)"),
                r["stats_s"], [("same figures as the one-figure functions",
                                bool(r.get("figures_equal_one_figure_functions", True)))],
                note=f"stats() parts alone: topology + measures {r['topology_s'] + r['measures_s']:.3g} s, quality "
                     f"{r['quality_s']:.3g} s, self-intersections {r['self_intersections_s']:.3g} s")
            for r in doc["rows"]]


def renumber_args(quick: bool, cache: str | None = None) -> list[str]:
    return (["--methods", "gibbs", "--meshes", "plate-h0.01,part-R192" if quick else BIG_MESHES]
            + (["--cache", cache] if cache else []))


def renumber_rows(doc: dict) -> list[Row]:
    out = []
    for m in doc["meshes"]:
        g, s = m["tools"].get("gibbs", {}), m["tools"].get("scipy rcm", {})
        task = f"Gibbs renumbering, {m['name']} ({m['np']:,} nodes)"
        if g.get("error") or s.get("error") or "time_s" not in g or "time_s" not in s:
            out.append(failed_row("renumber", task, str(g.get("error") or s.get("error") or "no figures")))
            continue
        big = m["np"] >= 100_000
        out.append(Row("renumber", task, f"{g['nodes_per_second'] / 1e6:.3g} M nodes/s, {_s(g['time_s'], g['cpu_s'])}",
                       f"scipy RCM {s['nodes_per_second'] / 1e6:.3g} M nodes/s, {_s(s['time_s'], s['cpu_s'])}",
                       g["time_s"] / s["time_s"], at_most(1, "<= 1x, profile <= RCM's (target 5)") if big else None,
                       g["time_s"], [(f"profile {g['profile_vs_scipy']:.3g} of RCM's", g["profile_vs_scipy"] <= 1)],
                       note="" if big else "fewer than 100 k nodes: target 5 does not apply"))
    return out


def adaptive_args(quick: bool) -> list[str]:
    return ["--shapes", "part", "--sizes", "64" if quick else "256"]


def adaptive_rows(doc: dict) -> list[Row]:
    out = []
    for c in doc["cases"]:
        a, g = _tool(c["rows"], "warpmesh adaptive", exact=True), _tool(c["rows"], "warpmesh grid")
        task = f"adaptive {c['shape']} at {c['cells']}^3"
        if a is None or g is None:
            out.append(failed_row("adaptive", task, c.get("adaptive_missing") or "no adaptive or grid row"))
            continue
        out.append(Row("adaptive", task, f"{_s(a['time_s'])}, {a.get('evaluations') or 0:,} evaluations",
                       f"warpmesh culled grid {_s(g['time_s'])}", a["time_s"] / g["time_s"],
                       at_most(1, "<= 1x (target 7)"), a["time_s"]))
    return out


#: group -> (script, its arguments, its rows); "first-run" is run by this script itself
JOBS = {
    "volume": ("bench_volume.py", volume_args, volume_rows),
    "surface": ("bench_surface.py", surface_args, surface_rows),
    "labels": ("bench_labels.py", labels_args, labels_rows),
    "startup": ("bench_startup.py", startup_args, startup_rows),
    "first-run": (None, None, first_run_rows),
    "optimize": ("bench_optimize.py", optimize_args, optimize_rows),
    "simplify": ("bench_optimize.py", simplify_args, simplify_rows),
    "stats": ("bench_stats.py", stats_args, stats_rows),
    "renumber": ("bench_renumber.py", renumber_args, renumber_rows),
    "adaptive": ("bench_adaptive.py", adaptive_args, adaptive_rows),
}


# =============================================================================================
# running
# =============================================================================================
def baseline_env(path: str) -> dict:
    """The environment of a "before" run: the checkout first on the path (its kernels linked
    where the package expects them); checked once that warpmesh is imported from there."""
    path = os.path.realpath(path)
    if not os.path.isfile(os.path.join(path, "warpmesh", "__init__.py")):
        raise SystemExit(f"--baseline: expected a warpmesh checkout (DIR/warpmesh/__init__.py), got {path!r}")
    link = os.path.join(path, "warpmesh", "kernels")
    if not os.path.exists(link) and os.path.isdir(os.path.join(path, "kernels")):
        os.symlink(os.path.join("..", "kernels"), link)
    env = dict(os.environ, PYTHONPATH=path)
    probe = subprocess.run([sys.executable, "-c", "import os, warpmesh; print(os.path.realpath(warpmesh.__file__))"],
                           capture_output=True, text=True, env=env, cwd=tempfile.gettempdir(), check=False)
    if probe.returncode != 0 or not probe.stdout.strip().startswith(path):
        raise SystemExit(f"--baseline: warpmesh is not imported from {path} with PYTHONPATH set "
                         f"({probe.stdout.strip() or probe.stderr.strip()[-200:]})")
    return env


def run_script(script: str, argv: list[str], logs: str, tag: str, env: dict | None) -> dict:
    """Run ``benchmarks/<script> argv --json`` (its output to a log file); its JSON document."""
    name = os.path.splitext(script)[0]
    log = os.path.join(logs, f"{name}{tag}.log")
    out = os.path.join(logs, f"{name}{tag}.json")
    cmd = [sys.executable, os.path.join(HERE, script), *argv, "--json", out]
    with open(log, "w") as fh:
        fh.write(f"$ {' '.join(cmd)}\n")
        fh.flush()
        run = subprocess.run(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env, check=False)
    if run.returncode != 0 or not os.path.exists(out):
        with open(log) as fh:
            tail = [ln for ln in fh.read().strip().splitlines() if ln.strip()][-1:] or ["no output"]
        raise RuntimeError(f"{script} exit status {run.returncode}: {tail[0][:160]} (log {log})")
    with open(out) as fh:
        return json.load(fh)


def run_group(group: str, args, tag: str, env: dict | None, baseline: str | None) -> tuple[list[Row], dict]:
    """Rows and raw document of one group; a failed script gives one failed row."""
    script, make_args, make_rows = JOBS[group]
    try:
        if script is None:
            doc = first_run(baseline, args.logs, tag)
        else:
            argv = make_args(args.quick, args.cache) if group == "renumber" else make_args(args.quick)
            if args.repeat is not None:
                argv += ["--repeat", str(args.repeat)]
            if group == "startup" and args.baseline and not tag:
                argv += ["--baseline", args.baseline]
            doc = run_script(script, argv, args.logs, tag, env)
    except Exception as exc:  # noqa: BLE001 -- one group failing must not lose the others
        return [failed_row(group, f"{group} ({script or 'CLI first run'})", f"{type(exc).__name__}: {exc}")], {}
    try:
        rows = make_rows(doc)
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
        rows = [failed_row(group, f"{group} ({script})", f"could not read its JSON ({type(exc).__name__}: {exc})")]
    for r in rows:
        r.met = evaluate(r)
    return rows, doc


def before_cell(row: Row) -> str:
    """The "before" cell of a row measured on the baseline: its warpmesh figure and ratio."""
    if row.warpmesh.startswith("failed"):
        return row.warpmesh
    parts = ([f"{fmt_ratio(row.ratio)} of its run's peer"] if row.ratio else []) + (
        [f"met? {verdict(row)}"] if row.target is not None else [])
    return row.warpmesh.split(",")[0] + (f" ({'; '.join(parts)})" if parts else "")


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="smaller sizes and --repeat 1: a smoke run")
    p.add_argument("--repeat", type=int, default=None,
                   help="passed to every script (default: each script's own; 1 with --quick)")
    p.add_argument("--only", default=None, help=f"comma-separated groups to run, from {','.join(GROUPS)}")
    p.add_argument("--skip", default="", help="comma-separated groups to leave out")
    p.add_argument("--baseline", default=None, help="checkout of an earlier commit: adds a 'before' column")
    p.add_argument("--cache", default=None, help="bench_renumber.py --cache: keep its generated meshes here")
    p.add_argument("--logs", default=None, help="folder for every script's output and JSON (default: a new temp dir)")
    p.add_argument("--json", default=None, help="write the rows and every script's JSON document here")
    args = p.parse_args(argv)
    only = [g.strip() for g in (args.only or ",".join(GROUPS)).split(",") if g.strip()]
    skip = [g.strip() for g in args.skip.split(",") if g.strip()]
    bad = [g for g in only + skip if g not in GROUPS]
    if bad:
        p.error(f"unknown group(s) {bad} in --only/--skip; pick from {list(GROUPS)}")
    args.groups = [g for g in GROUPS if g in only and g not in skip]
    if not args.groups:
        p.error("no group left to run (check --only and --skip)")
    if args.repeat is None and args.quick:
        args.repeat = 1
    if args.repeat is not None and args.repeat < 1:
        p.error(f"--repeat must be >= 1, got {args.repeat}")
    args.logs = args.logs or tempfile.mkdtemp(prefix="bench_table22-")
    os.makedirs(args.logs, exist_ok=True)
    return args


def main(argv=None) -> None:
    args = parse_args(argv)
    env_before = baseline_env(args.baseline) if args.baseline else None
    t_start = time.perf_counter()
    load0 = load_banner(f"bench_table22: issue 22's table, groups {','.join(args.groups)}"
                        f"{' (quick)' if args.quick else ''}; warpmesh {version('warpmesh')}, {os.cpu_count()} cores; "
                        f"logs in {args.logs}")
    rows, raw = [], {}
    for group in args.groups:
        t0 = time.perf_counter()
        got, raw[group] = run_group(group, args, "", None, None)
        print(f"  {group}: {len(got)} row(s) in {time.perf_counter() - t0:.0f} s", flush=True)
        if env_before is not None and group != "startup":  # startup: old and new in the same rounds
            t0 = time.perf_counter()
            old, raw[f"before: {group}"] = run_group(group, args, "-before", env_before, args.baseline)
            old_by_task = {r.task: r for r in old}
            for r in got:
                o = old_by_task.get(r.task) or (old[0] if len(old) == 1 and old[0].warpmesh.startswith("failed")
                                                else None)
                r.before = before_cell(o) if o is not None else "not measured"
            print(f"  {group} (before): {len(old)} row(s) in {time.perf_counter() - t0:.0f} s", flush=True)
        rows += got
    print("\nratio = warpmesh / peer in time (> 1: warpmesh slower); startup rows: / import numpy; stats: stats() / "
          "meshing. Each row's two figures come from one process run of its script (logs above).\n")
    print(format_table(rows, with_before=args.baseline is not None))
    targets = [r for r in rows if r.target is not None]
    print(f"\ntargets met: {sum(bool(r.met) for r in targets)} of {len(targets)} rows with a target"
          + (f"; {sum(r.met is None for r in targets)} without the figure" if any(r.met is None for r in targets)
             else ""))
    finish(t_start, load0, args.json, {"quick": args.quick, "repeat": args.repeat, "baseline": args.baseline,
                                       "logs": args.logs, "rows": [{**asdict(r), "met": r.met} for r in rows],
                                       "raw": raw})


if __name__ == "__main__":
    main()
