#!/usr/bin/env python3
"""Node renumbering ([FG §17.4], Tables 17.1-17.3): warpmesh against scipy.

Every mesh gets a random node permutation first (``--seed``, default 0), so the initial
numbering is bad on purpose, as in the book's tables. Then, on the symmetric node graph
``warpmesh.numbering.graph.node_graph(mesh.cells, mesh.n_points)`` (build time measured):

- ``scipy rcm``: ``scipy.sparse.csgraph.reverse_cuthill_mckee(graph, symmetric_mode=True)``
  (start node of minimal degree per component, already reversed);
- ``warpmesh <method>``: ``warpmesh.numbering.renumber.renumber_graph(graph, method)`` for each of
  ``warpmesh.numbering.renumber.METHODS`` (gibbs, rcm, frontal, frontal-diameter; default
  ``reverse="auto"``).

Both get the same graph object; each returns ``order`` (old indices in new order). The
statistics of every order come from one function, ``warpmesh.numbering.renumber.matrix_stats``
(bandwidth β, profile pr, mean profile pr / np; Table 17.1). Times: one untimed round
first (for warpmesh a full ``mesh.renumber(method)``: loads the Warp kernels and
cross-checks its ``info`` against the figures here), then ``--repeat`` rounds, one call per
tool per round (round-robin), best kept; nodes/s = np / best time (the book's v). CPU seconds
(process time, both cores; the least of the rounds) beside them, as the machine may be shared. The last
table checks issue 22's target on the meshes of 100,000 nodes or more: Gibbs at least scipy RCM's
nodes per second with a profile no larger.

Meshes (``--meshes``: names or groups ``plate``, ``surface``, ``tet``, ``frog``, ``all``;
default every mesh not marked optional):

- plate-h*: the 4 x 2 plate with three holes (tests/numbering_meshes.py), 2D Delaunay
  triangles at h = 0.01, 0.005, 0.0036;
- part / degree6 / sphere surfaces: ``wm.mesh_surface`` (default method) of
  ``wm.example("part")`` at 192, ``wm.example("degree6")`` at 128, ``wm.sphere(1.0)`` on
  [-1.2, 1.2]^3 at 128;
- frog10-surf: label 10 of pyvista's bundled frog segmentation (bench_optimize.load_frog
  crop), ``wm.mesh_surface(volume, labels=[10])``; frog-all-surf (optional): every tissue
  label of the whole volume, ``labels="all"``;
- tetrahedra from TetGen (``tetgen.TetGen(surface.to_pyvista()).tetrahedralize(order=1,
  quiet=True, ...)``, quality on) inside: the sphere surface at 56 with default switches
  (ball-R56: fine at the surface, large tetrahedra inside), the sphere surface at 32 and
  at 40 with ``fixedvolume=True, maxvolume=4e-5`` / ``6.5e-6, steinerleft=10**8``
  (ball-R32-a4e-5, ball-R40-a6.5e-6: uniform size inside), the part at 64 (part-tet-R64,
  default switches), frog label 10's surface meshed with ``method="mc"`` (frog10-tet,
  default switches).
  TetGen notes (tetgen 0.8.4): ``maxvolume=`` does nothing unless ``fixedvolume=True``
  is also given; the default ``steinerleft=100000`` caps the Steiner points, so quality
  refinement stops at surface points + 100,000 nodes (the part hits it; the ball at 40
  needs it raised to reach ~200k nodes); on the part's marching-cubes surface an unlimited
  budget ends in "Internal TetGen error" at every resolution tried (40-96); the frog's
  default (mc33) surface is refused ("self-intersections"), its plain-MC one is accepted.

``--cache DIR`` keeps generated meshes (before the shuffle) in DIR, keyed by their
parameters; without it every mesh is built anew (the TetGen meshes take most of the
run). A mesh whose generator fails is reported and skipped.

Measured (issue 22, target 5: Gibbs at least scipy RCM's nodes per second on meshes of
100 k nodes and more, profile no larger), 2026-12-03, 2 cores, load 1.5-1.8, ``--methods gibbs
--cache /tmp/wm_renumber_cache --repeat 9 --meshes plate-h0.005,plate-h0.0036,part-R192,
degree6-R128,ball-R40-a6.5e-6,part-tet-R64``, run twice at 19f0c5b and twice at cd6d579,
alternating (Gibbs / scipy RCM wall time, each run's own ratio; CPU ratios the same within 0.01;
orders, so profiles, identical before and after):

=================  =======  ===================  ===================  ==================  ========
mesh               nodes    Gibbs / RCM before   Gibbs / RCM after    M nodes/s Gibbs     pr / RCM
                                                                      (RCM), after
=================  =======  ===================  ===================  ==================  ========
plate-h0.005       262,509  2.03-2.13            1.33-1.38            4.7 (6.3-6.5)       0.904
plate-h0.0036      505,881  2.25-2.26            1.27-1.41            4.3 (5.4-6.1)       0.842
part-R192          105,018  2.75-2.76            1.59-1.81            4.6-4.8 (7.3-8.6)   0.867
degree6-R128       114,648  2.45-2.52            1.76-1.78            4.6 (8.1)           0.911
ball-R40-a6.5e-6   215,671  2.16-2.23            1.47                 3.0 (4.4-4.5)       1.010
part-tet-R64        33,518  3.46-3.68            2.67-2.71            3.1 (8.3-8.4)       0.611
=================  =======  ===================  ===================  ==================  ========

Target 5 is not met: Gibbs is 1.3-1.8x RCM's time on the meshes of 100 k nodes and more (it
was 2.0-2.8x), and its profile is 1 % above RCM's on ball-R40 (as before: the orders did not
change). Where Gibbs' 119 ms go on plate-h0.0036 (kernels alone, best of 15, load 0.6; at
19f0c5b in brackets, 194 ms in all): the first search, that relabels the randomly numbered
graph, 27 (47); the two George-Liu descents, with the symmetry check's column counts, 26 (45 +
5); Step 2, pairs 3 (3), pieces labelled 10 (17), placed 4 (numpy rounds, ~6); Step 3, sort 4
(numpy, ~10), numbering with both profiles on the way 28 (32 + a 7 ms profile pass); the rest
(host numpy, launches) 17 (38). scipy's RCM (85-93 ms) walks the graph once, from a node of
minimal degree; Gibbs walks it five times (search, two descents, pieces, numbering), and each
walk is near a plain breadth-first search's cost here (12-13 ms on the relabelled graph, 27 ms
on the random one with prefetching): matching RCM needs fewer walks, not faster ones.

Run:  python benchmarks/bench_renumber.py [--meshes all] [--repeat 3] [--seed 0]
                                          [--methods gibbs,rcm,frontal,frontal-diameter]
                                          [--cache /tmp/wm_renumber_cache] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

if __name__ == "__main__":  # memory as the other benchmarks (README.md): freed memory stays in the heap
    _report.keep_freed_memory()

import numpy as np  # noqa: E402
import scipy  # noqa: E402
import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING
from scipy.sparse.csgraph import reverse_cuthill_mckee  # noqa: E402

import warpmesh as wm  # noqa: E402
from warpmesh.numbering.graph import node_graph  # noqa: E402
from warpmesh.numbering.renumber import METHODS, format_table, matrix_stats, renumber_graph  # noqa: E402

import _meshes  # noqa: E402

SCIPY = "scipy rcm"
BALL_MAXVOLUME = 6.5e-6

#: name -> (group, generator parameters, optional); the parameters key the cache
MESHES: dict[str, tuple[str, dict, bool]] = {
    "plate-h0.01": ("plate", {"kind": "plate", "h": 0.01}, False),
    "plate-h0.005": ("plate", {"kind": "plate", "h": 0.005}, False),
    "plate-h0.0036": ("plate", {"kind": "plate", "h": 0.0036}, False),
    "part-R192": ("surface", {"kind": "surface", "shape": "part", "resolution": 192}, False),
    "degree6-R128": ("surface", {"kind": "surface", "shape": "degree6", "resolution": 128}, False),
    "sphere-R128": ("surface", {"kind": "surface", "shape": "sphere", "resolution": 128}, False),
    "frog10-surf": ("frog", {"kind": "frog-surface", "label": 10}, False),
    "frog-all-surf": ("frog", {"kind": "frog-surface", "label": "all"}, True),
    "ball-R56": ("tet", {"kind": "tet", "shape": "sphere", "resolution": 56, "tetgen": {}}, False),
    "ball-R32-a4e-5": ("tet", {"kind": "tet", "shape": "sphere", "resolution": 32,
                               "tetgen": {"fixedvolume": True, "maxvolume": 4e-5, "steinerleft": 10**8}}, False),
    "ball-R40-a6.5e-6": ("tet", {"kind": "tet", "shape": "sphere", "resolution": 40,
                                 "tetgen": {"fixedvolume": True, "maxvolume": BALL_MAXVOLUME,
                                            "steinerleft": 10**8}}, False),
    "part-tet-R64": ("tet", {"kind": "tet", "shape": "part", "resolution": 64, "tetgen": {}}, False),
    "frog10-tet": ("tet", {"kind": "frog-tet", "label": 10, "method": "mc", "tetgen": {}}, False),
}
GROUP_TITLES = {"plate": "2D triangles (plate with holes)", "surface": "warpmesh surfaces (triangles)",
                "frog": "frog segmentation surfaces (real data, triangles)", "tet": "TetGen tetrahedra"}


# =============================================================================================
# meshes
# =============================================================================================
def build_mesh(params: dict) -> tuple[wm.Mesh, dict]:
    kind = params["kind"]
    if kind == "plate":
        return _meshes.plate(params["h"]), {"what": f"plate with 3 holes, Delaunay, h = {params['h']}"}
    if kind == "surface":
        m = _meshes.shape_surface(params["shape"], params["resolution"])
        return m, {"what": f"wm.mesh_surface({params['shape']}, resolution={params['resolution']})"}
    if kind == "frog-surface":
        m, info = _meshes.frog_surface(params["label"])
        lab = params["label"]
        what = ("frog_tissues.vti, all tissue labels (labels='all', whole volume)" if lab == "all"
                else f"frog_tissues.vti label {lab} (crop {info.get('crop')}), wm.mesh_surface(labels=[{lab}])")
        return m, {"what": what, "frog": info}
    if kind in ("tet", "frog-tet"):
        t0 = time.perf_counter()
        if kind == "tet":
            surf = _meshes.shape_surface(params["shape"], params["resolution"])
            src = f"{params['shape']} surface at {params['resolution']}"
        else:
            surf, _ = _meshes.frog_surface(params["label"], method=params.get("method"))
            src = f"frog label {params['label']} surface (method={params.get('method')!r})"
        t1 = time.perf_counter()
        m = _meshes.tetrahedralize(surf, **params["tetgen"])
        t2 = time.perf_counter()
        opts = ", ".join(f"{k}={v}" for k, v in params["tetgen"].items()) or "default switches"
        return m, {"what": f"TetGen inside the {src} ({surf.n_points:,} vertices, {len(surf.triangles):,} "
                           f"triangles), {opts}", "surface_np": surf.n_points, "surface_s": t1 - t0,
                   "tetgen_s": t2 - t1}
    raise ValueError(f"unknown mesh kind {kind!r}")


# =============================================================================================
# timing
# =============================================================================================
def new_of(order: np.ndarray) -> np.ndarray:
    new = np.empty(len(order), np.int64)
    new[order] = np.arange(len(order))
    return new


def run_tool(tool: str, graph):
    if tool == SCIPY:
        return reverse_cuthill_mckee(graph, symmetric_mode=True)
    return renumber_graph(graph, tool)


def bench_mesh(name: str, mesh: wm.Mesh, tools: list[str], repeat: int) -> dict:
    n = mesh.n_points
    top = "tetra" if "tetra" in mesh.cells else "triangle"
    ne = len(mesh.cells[top])
    # graph build: one untimed call, then best of repeat
    graph = node_graph(mesh.cells, n)
    g_samples = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        graph = node_graph(mesh.cells, n)
        g_samples.append(time.perf_counter() - t0)
    before = matrix_stats(graph)
    rows = {t: {"samples_s": [], "cpu_samples_s": [], "error": None} for t in tools}
    # warm-up round: scipy's call; warpmesh's full mesh.renumber (kernels load, cross-check)
    for t in tools:
        try:
            if t == SCIPY:
                run_tool(t, graph)
            else:
                r = mesh.renumber(t)
                rows[t]["mesh_renumber"] = {k: r.info.get(k) for k in
                                            ("bandwidth", "profile", "profile_before", "renumber_time",
                                             "graph_time", "nodes_per_second")}
                del r
        except Exception as ex:  # noqa: BLE001 - report and go on
            rows[t]["error"] = f"{type(ex).__name__}: {ex}"
    for _ in range(repeat):
        for t in tools:
            if rows[t]["error"]:
                continue
            c0, t0 = time.process_time(), time.perf_counter()
            order = run_tool(t, graph)
            dt = time.perf_counter() - t0
            rows[t]["samples_s"].append(dt)
            rows[t]["cpu_samples_s"].append(time.process_time() - c0)  # both cores: CPU seconds of the process
            if "order" not in rows[t]:
                rows[t]["order"] = order
            elif not np.array_equal(rows[t]["order"], order):
                rows[t]["nondeterministic"] = True
    result = {"name": name, "np": n, "ne": ne, "nnz": int(graph.nnz), "graph_s": min(g_samples),
              "graph_samples_s": g_samples, "tools": {}}
    for t in tools:
        row = rows[t]
        out = {"np": n, "ne": ne, "bandwidth_before": before["bandwidth"], "profile_before": before["profile"],
               "profile_mean_before": before["profile_mean"], "error": row["error"],
               "samples_s": row["samples_s"], "cpu_samples_s": row["cpu_samples_s"]}
        if not row["error"]:
            order = np.asarray(row.pop("order"))
            ok = len(order) == n and np.array_equal(np.sort(order), np.arange(n))
            if not ok:
                out["error"] = "not a permutation"
            else:
                s = matrix_stats(graph, new_of(order))
                best = min(row["samples_s"])
                out.update(bandwidth=s["bandwidth"], profile=s["profile"], profile_mean=s["profile_mean"],
                           profile_ratio=before["profile"] / max(s["profile"], 1), time_s=best,
                           cpu_s=min(row["cpu_samples_s"]),
                           nodes_per_second=n / best if best > 0 else float("inf"),
                           nondeterministic=bool(row.get("nondeterministic")))
                if "mesh_renumber" in row:
                    out["mesh_renumber"] = row["mesh_renumber"]
                    mr = row["mesh_renumber"]
                    out["mesh_renumber_agrees"] = (mr.get("profile") == s["profile"]
                                                   and mr.get("bandwidth") == s["bandwidth"])
        result["tools"][t] = out
    ref = result["tools"].get(SCIPY)
    for t, out in result["tools"].items():
        if t == SCIPY or out.get("error") or not ref or ref.get("error"):
            continue
        out["profile_vs_scipy"] = out["profile"] / max(ref["profile"], 1)
        out["bandwidth_vs_scipy"] = out["bandwidth"] / max(ref["bandwidth"], 1)
        out["time_vs_scipy"] = out["time_s"] / ref["time_s"]
        out["cpu_vs_scipy"] = out["cpu_s"] / max(ref["cpu_s"], 1e-9)
    return result


# =============================================================================================
# printing
# =============================================================================================
def _fmt(v, spec):
    return "-" if v is None else spec.format(v)


def print_method_tables(results: list[dict], tools: list[str]):
    groups = []
    for r in results:
        if r["group"] not in groups:
            groups.append(r["group"])
    for t in tools:
        label = t if t == SCIPY else f"warpmesh {t}"
        for grp in groups:
            rs = [r for r in results if r["group"] == grp]
            cols = {r["name"]: r["tools"][t] for r in rs if not r["tools"][t].get("error")}
            print(f"\n{label} -- {GROUP_TITLES[grp]}")
            if cols:
                print(format_table(cols))
                # extra rows, aligned as format_table's (same widths: recompute from its output)
                extra = [("time s (best)", [_fmt(c.get("time_s"), "{:.3f}") for c in cols.values()]),
                         ("graph s", [_fmt(r["graph_s"], "{:.3f}") for r in rs if r["name"] in cols])]
                if t != SCIPY:
                    extra += [("pr / scipy pr", [_fmt(c.get("profile_vs_scipy"), "{:.3f}") for c in cols.values()]),
                              ("beta / scipy beta", [_fmt(c.get("bandwidth_vs_scipy"), "{:.3f}")
                                                     for c in cols.values()]),
                              ("time / scipy time", [_fmt(c.get("time_vs_scipy"), "{:.2f}") for c in cols.values()])]
                # right edges of format_table's columns, read off its header line (names right-justified)
                header, ends, pos = format_table(cols).splitlines()[0], [], 0
                for n in cols:
                    pos = header.index(n, pos) + len(n)
                    ends.append(pos)
                for lab, vals in extra:
                    line, prev = lab, len(lab)
                    for v, e in zip(vals, ends):
                        line += v.rjust(e - prev) if e - prev > len(v) else " " + v
                        prev = len(line)
                    print(line)
            for r in rs:
                o = r["tools"][t]
                notes = []
                if o.get("error"):
                    notes.append(f"FAILED: {o['error']}")
                if o.get("nondeterministic"):
                    notes.append("orders differ between runs")
                if o.get("mesh_renumber_agrees") is False:
                    notes.append(f"mesh.renumber info differs: {o.get('mesh_renumber')}")
                if notes:
                    print(f"  {r['name']}: " + "; ".join(notes))


def print_summary(results: list[dict]):
    hdr = ["mesh", "np", "ne", "graph s", "gibbs pr/scipy pr", "gibbs b/scipy b", "gibbs Mnodes/s",
           "scipy Mnodes/s", "b_init/b_gibbs", "pr ratio (gibbs)", "best pr"]
    rows = []
    for r in results:
        g, s = r["tools"].get("gibbs"), r["tools"].get(SCIPY)
        good = {t: o for t, o in r["tools"].items() if not o.get("error")}
        best = min(good, key=lambda t: good[t]["profile"]) if good else "-"
        ok_g = g is not None and not g.get("error")
        ok_s = s is not None and not s.get("error")
        rows.append([r["name"], f"{r['np']:,}", f"{r['ne']:,}", f"{r['graph_s']:.3f}",
                     _fmt(g.get("profile_vs_scipy") if ok_g else None, "{:.3f}"),
                     _fmt(g.get("bandwidth_vs_scipy") if ok_g else None, "{:.3f}"),
                     _fmt(g["nodes_per_second"] / 1e6 if ok_g else None, "{:.3f}"),
                     _fmt(s["nodes_per_second"] / 1e6 if ok_s else None, "{:.3f}"),
                     _fmt(g["bandwidth_before"] / max(g["bandwidth"], 1) if ok_g else None, "{:,.0f}"),
                     _fmt(g["profile_ratio"] if ok_g else None, "{:,.0f}"),
                     best])
    widths = [max(len(x) for x in col) for col in zip(hdr, *rows)]
    print("\nSummary (b = bandwidth beta; pr ratio = pr initial / pr final; best pr = tool with the smallest profile)")
    print("  ".join(h.ljust(w) if i == 0 else h.rjust(w) for i, (h, w) in enumerate(zip(hdr, widths))))
    for row in rows:
        print("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))))


def print_target(results: list[dict], min_nodes: int = 100_000):
    """Issue 22 target 5 on the meshes of at least ``min_nodes`` nodes: Gibbs at least scipy
    RCM's nodes per second (wall: best of the rounds; CPU: process seconds, both cores),
    with a profile no larger."""
    big = [r for r in results if r["np"] >= min_nodes and not r["tools"].get("gibbs", {"error": 1}).get("error")
           and not r["tools"][SCIPY].get("error")]
    if not big:
        return
    print(f"\nGibbs against scipy RCM on meshes of {min_nodes:,} nodes or more (speed ratio > 1: Gibbs faster; "
          "met: speed ratio >= 1 and profile ratio <= 1)")
    hdr = ["mesh", "np", "gibbs Mnodes/s", "scipy Mnodes/s", "speed ratio (wall)", "speed ratio (CPU)",
           "profile ratio", "met"]
    rows = []
    for r in big:
        g, s = r["tools"]["gibbs"], r["tools"][SCIPY]
        wall, cpu = s["time_s"] / g["time_s"], s["cpu_s"] / max(g["cpu_s"], 1e-9)
        rows.append([r["name"], f"{r['np']:,}", f"{g['nodes_per_second'] / 1e6:.3f}",
                     f"{s['nodes_per_second'] / 1e6:.3f}", f"{wall:.2f}", f"{cpu:.2f}",
                     f"{g['profile_vs_scipy']:.3f}", "yes" if wall >= 1 and g["profile_vs_scipy"] <= 1 else "no"])
    widths = [max(len(x) for x in col) for col in zip(hdr, *rows)]
    print("  ".join(h.ljust(w) if i == 0 else h.rjust(w) for i, (h, w) in enumerate(zip(hdr, widths))))
    for row in rows:
        print("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))))


def print_ratios(results: list[dict], tools: list[str]):
    wtools = [t for t in tools if t != SCIPY]
    if SCIPY not in tools or not wtools:
        return
    hdr = ["mesh"] + [f"{t} pr" for t in wtools] + [f"{t} time" for t in wtools]
    rows = []
    for r in results:
        rows.append([r["name"]] + [_fmt(r["tools"][t].get("profile_vs_scipy"), "{:.3f}") for t in wtools]
                    + [_fmt(r["tools"][t].get("time_vs_scipy"), "{:.2f}") for t in wtools])
    widths = [max(len(x) for x in col) for col in zip(hdr, *rows)]
    print("\nwarpmesh / scipy rcm, every method (profile ratio < 1: warpmesh's profile smaller; time ratio > 1: "
          "warpmesh slower)")
    print("  ".join(h.ljust(w) if i == 0 else h.rjust(w) for i, (h, w) in enumerate(zip(hdr, widths))))
    for row in rows:
        print("  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths))))


def environment():
    ver = _report.version
    try:  # read-only: which warpmesh was measured (another engineer may be editing the tree)
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        head = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip() or "?"
        dirty = subprocess.run(["git", "-C", root, "status", "--porcelain", "--", "warpmesh", "kernels"],
                               capture_output=True, text=True, timeout=10).stdout.split("\n")
        dirty = [ln[3:] for ln in dirty if ln.strip()]
        commit = head + (f" + uncommitted changes in {', '.join(dirty)}" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        commit = "?"
    return {"warpmesh commit": commit, "python": platform.python_version(), "cores": os.cpu_count(), "numpy": np.__version__,
            "scipy": scipy.__version__, "warp": wp.config.version, "tetgen": ver("tetgen"),
            "pyvista": ver("pyvista"),
            "malloc": "heap kept" if all(os.environ.get(k) == v for k, v in _report.MALLOC_ENV.items()) else "glibc default"}


# =============================================================================================
def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--meshes", default="default",
                   help="comma-separated mesh names and/or groups (plate, surface, frog, tet, all, default); "
                        "names: " + ", ".join(MESHES) + " (default: all but frog-all-surf)")
    p.add_argument("--methods", default=",".join(METHODS),
                   help=f"warpmesh methods, comma-separated subset of {','.join(METHODS)} (scipy RCM always runs)")
    p.add_argument("--repeat", type=int, default=3, help="timed rounds per tool, best taken (default 3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random node permutation of every mesh (default 0)")
    p.add_argument("--cache", default=None, help="directory to keep generated meshes in (default: none)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.repeat < 1:
        p.error("--repeat must be >= 1")
    names = []
    for item in (s.strip() for s in args.meshes.split(",") if s.strip()):
        if item in MESHES:
            sel = [item]
        elif item == "all":
            sel = list(MESHES)
        elif item == "default":
            sel = [n for n, (_, _, opt) in MESHES.items() if not opt]
        elif item in GROUP_TITLES:
            sel = [n for n, (g, _, opt) in MESHES.items() if g == item and not opt]
        else:
            p.error(f"unknown mesh or group {item!r}; pick from {list(MESHES)} or {list(GROUP_TITLES)}, all, default")
        names += [n for n in sel if n not in names]
    args.mesh_list = names
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS]
    if bad:
        p.error(f"unknown method(s) {bad}; pick from {list(METHODS)}")
    args.method_list = methods
    return args


def main(argv=None):
    args = parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    wp.init()
    t_start = time.perf_counter()
    env = environment()
    print("bench_renumber: " + ", ".join(f"{k} {v}" for k, v in env.items()))
    load0 = _report.load_banner(f"best of {args.repeat} round(s) per tool after 1 untimed round, round-robin; "
                                f"node permutation seed {args.seed}")
    print("np = nodes, ne = elements (triangles or tetrahedra); beta = bandwidth, pr = profile, pr_mean = pr / np, "
          "pr ratio = initial / final, v = np / best time")
    sys.stdout.flush()
    tools = [SCIPY] + args.method_list
    results, failures = [], []
    for name in args.mesh_list:
        group, params, _ = MESHES[name]
        try:
            base, info, from_cache = _meshes.cached(args.cache, params, lambda p=params: build_mesh(p))
        except Exception as ex:  # noqa: BLE001 - report and go on
            print(f"\n{name}: mesh generation FAILED ({type(ex).__name__}: {ex}); skipped")
            failures.append({"name": name, "params": params, "error": f"{type(ex).__name__}: {ex}"})
            continue
        mesh = _meshes.shuffled(base, args.seed)
        del base
        gen = "from cache" if from_cache else f"built in {info['build_s']:.1f} s"
        extra = (f" (surface {info['surface_s']:.1f} s, TetGen {info['tetgen_s']:.1f} s)"
                 if "tetgen_s" in info and not from_cache else "")
        print(f"\n{name}: {info['what']}; {mesh.n_points:,} nodes; {gen}{extra}")
        sys.stdout.flush()
        t0 = time.perf_counter()
        r = bench_mesh(name, mesh, tools, args.repeat)
        r.update(group=group, params=params, generation=info, from_cache=from_cache,
                 bench_s=time.perf_counter() - t0)
        s = r["tools"][SCIPY]
        line = [f"  graph {r['graph_s']:.3f} s ({r['nnz']:,} nonzeros)"]
        for t in tools:
            o = r["tools"][t]
            line.append(f"{t}: FAILED" if o.get("error") else
                        f"{t}: pr {o['profile']:,} beta {o['bandwidth']:,} {o['time_s']:.3f} s")
        print("; ".join(line) + f"  [initial pr {s['profile_before']:,}, beta {s['bandwidth_before']:,}]")
        sys.stdout.flush()
        results.append(r)
    if results:
        print_method_tables(results, tools)
        print_ratios(results, tools)
        print_summary(results)
        print_target(results)
    for f in failures:
        print(f"  {f['name']}: not measured (mesh generation failed: {f['error']})")
    _report.finish(t_start, load0, args.json,
                   {"environment": env, "args": vars(args), "meshes": results, "failures": failures})


if __name__ == "__main__":
    main()
