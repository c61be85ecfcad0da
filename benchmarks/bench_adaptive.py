#!/usr/bin/env python3
"""Adaptive (octree) surface meshing of a shape: warpmesh against its peers on the CPU.

For each shape (the CSG part ``wm.example("part")`` and the degree-six surface
``wm.example("degree6")``) and each size N of ``--sizes`` (cells along the longest side
of the bounds, a power of two; default 256 512), on the same bounds and the same finest
resolution:

- ``warpmesh adaptive``: ``wm.mesh_surface(shape, bounds=bounds, adaptive=True,
  max_level=log2(N), tolerance=...)`` (the reference of the ratio columns); if it fails,
  its row says why and the peers still run.
- ``warpmesh grid``: ``wm.mesh_surface(shape, bounds=bounds, resolution=N)``, the default
  method and covering (culled block grid), for reference.
- ``numpy + scikit-image``: f evaluated with numpy on the (N+1)^3 nodes (the expression
  oracle ``Shape.eval_numpy`` on open 1-D axes, float64, in slabs along x, cast to
  float32), then ``skimage.measure.marching_cubes`` (Lewiner); each timed on its own and
  summed.
- ``Warp sparse_marching_cubes``: ``warp.geometry.sparse_marching_cubes`` (Lipschitz
  octree + marching cubes on the kept cells), fed by a Warp kernel over hand-written
  ``@wp.func`` fields (checked against ``wm.evaluate`` at start). The part uses min/max
  booleans (same surface, 1-Lipschitz: bound 1); the degree-six polynomial uses
  ``--lipschitz-safety`` x the largest |grad f| over a 65^3 node sample of the box. On
  the degree-six surface it runs only at N <= 256 unless ``--all`` (at 256^3 on this
  2-core VM about 4 s per warm call, 14 s cold, keeping 83 % of the cells at a peak of
  5.3 GB; at 512^3 it needs ~40 GB and is skipped where memory is short, with or
  without ``--all``).

Times are the best of ``--repeat`` warm runs (one untimed run first; tools run
round-robin); a tool whose timed runs add up to more than ``--budget`` seconds stops
early. Ratio columns: tool / warpmesh adaptive (time: the adaptive mesher's speed-up).

Run:  python benchmarks/bench_adaptive.py [--quick] [--sizes 256 512] [--shapes part,degree6]
                                          [--repeat 3] [--tolerance 0.02] [--all] [--json out.json]
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import platform
import sys
import time
import warnings

# Memory (see README.md): a page touched for the first time costs ~2 ms/MB of kernel time in
# this VM, so the benchmark re-runs itself with glibc keeping freed memory in the heap (the
# same for every tool); --default-malloc keeps the stock allocator.
_MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": str(16 << 30), "MALLOC_TRIM_THRESHOLD_": str(16 << 30)}
if __name__ == "__main__" and "--default-malloc" not in sys.argv[1:] and "-h" not in sys.argv[1:] \
        and "--help" not in sys.argv[1:] and any(k not in os.environ for k in _MALLOC_ENV) \
        and sys.platform.startswith("linux"):
    os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **_MALLOC_ENV})

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING  # no init banner / module-load lines in the tables
import warp.geometry as wpg  # noqa: E402

import skimage  # noqa: E402
from skimage.measure import marching_cubes as sk_marching_cubes  # noqa: E402

import warpmesh as wm  # noqa: E402

DEVICE = "cpu"
SHAPES = ("part", "degree6")
#: (shape, tool) pairs too slow above 256^3 cells: run there only with --all
SLOW_ABOVE_256 = {("degree6", "sparse")}
#: peak memory of Warp's sparse_marching_cubes per kept cell (measured: 5.3 GB peak RSS for the 14.0 M
#: cells it keeps of the degree-six surface at 256^3), and the share of the cells it keeps when no
#: smaller size of this run measured it (83 % on the degree-six surface at 256^3, 2 % on the part)
SPARSE_BYTES_PER_CELL = 380
SPARSE_KEPT_PRIOR = {"degree6": 0.83, "part": 0.02}


def mem_available() -> float | None:
    """MemAvailable of /proc/meminfo in bytes (None where there is none)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return None


# =============================================================================================
# the fields written directly in Warp (for sparse_marching_cubes): same formulas as shapes.py
# =============================================================================================
@wp.func
def _sd_box(p: wp.vec3, h: wp.vec3):
    # warpmesh.frep.shapes.box: -(|max(q, 0)| + min(max(q), 0)), q = |p| - h
    q = wp.vec3(wp.abs(p[0]) - h[0], wp.abs(p[1]) - h[1], wp.abs(p[2]) - h[2])
    mx = wp.max(q[0], 0.0)
    my = wp.max(q[1], 0.0)
    mz = wp.max(q[2], 0.0)
    outside = wp.sqrt(mx * mx + my * my + mz * mz)
    inside = wp.min(wp.max(wp.max(q[0], q[1]), q[2]), 0.0)
    return -(outside + inside)


@wp.func
def part_minmax_field(p: wp.vec3):
    """The CSG part with min/max booleans: max(min(box, -max(holes)), ball) (f > 0 inside)."""
    plate = _sd_box(p, wp.vec3(1.0, 1.0, 0.3))  # box((2, 2, 0.6))
    holes = float(-1.0e30)
    for sx in range(2):  # cylinder(0.2) at (+-0.6, +-0.6)
        for sy in range(2):
            dx = p[0] - 0.6 * float(2 * sx - 1)
            dy = p[1] - 0.6 * float(2 * sy - 1)
            holes = wp.max(holes, 0.2 - wp.sqrt(dx * dx + dy * dy))
    ball = 0.5 - wp.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])  # sphere(0.5)
    return wp.max(wp.min(plate, -holes), ball)


@wp.func
def degree6_field(p: wp.vec3):
    """(x^2 + y^2 - 4)(x^2 + z^2 - 4)(y^2 + z^2 - 4) - 4.0078 (wm.example('degree6'))."""
    x2 = p[0] * p[0]
    y2 = p[1] * p[1]
    z2 = p[2] * p[2]
    return (x2 + y2 - 4.0) * (x2 + z2 - 4.0) * (y2 + z2 - 4.0) - 4.0078


@wp.kernel
def _part_minmax_kernel(points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.float32)):
    i = wp.tid()
    out[i] = part_minmax_field(points[i])


@wp.kernel
def _degree6_kernel(points: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.float32)):
    i = wp.tid()
    out[i] = degree6_field(points[i])


WARP_KERNELS = {"part": _part_minmax_kernel, "degree6": _degree6_kernel}


def warp_field(kernel, clock: list):
    """The batched callable sparse_marching_cubes wants: points (wp.array of vec3) ->
    values (wp.array of float32), one launch of ``kernel``; time spent added to clock[0]."""
    def field(points: wp.array) -> wp.array:
        t0 = time.perf_counter()
        out = wp.empty(points.shape[0], dtype=wp.float32, device=points.device)
        wp.launch(kernel, dim=points.shape[0], inputs=[points], outputs=[out], device=points.device)
        clock[0] += time.perf_counter() - t0
        return out
    return field


def part_minmax_shape():
    """wm.example('part') with min/max booleans (the same surface, a 1-Lipschitz field)."""
    holes = [wm.cylinder(0.2).translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
    return wm.union(wm.difference(wm.box((2, 2, 0.6)), *holes, method="minmax"), wm.sphere(0.5), method="minmax")


def check_warp_fields(shapes: dict, n: int = 100_000, seed: int = 0) -> list[str]:
    """The hand-written Warp fields against wm.evaluate (warpmesh's tape) at random points of
    the bounds: |difference| <= 1e-5 * max(1, |f|); raises if not."""
    lines = []
    rng = np.random.default_rng(seed)
    for name, (shape, lo, hi) in shapes.items():
        pts = rng.uniform(lo, hi, (n, 3)).astype(np.float32)
        ref = wm.evaluate(shape, pts)
        got = warp_field(WARP_KERNELS[name], [0.0])(wp.array(pts, dtype=wp.vec3, device=DEVICE)).numpy()
        err = float(np.max(np.abs(got - ref) / np.maximum(1.0, np.abs(ref))))
        if not err <= 1e-5:
            raise SystemExit(f"bench_adaptive: the Warp field of {name} disagrees with wm.evaluate "
                             f"(max relative difference {err:.2e} at {n} random points)")
        lines.append(f"{name}: max |warp - wm.evaluate| / max(1, |f|) = {err:.1e} at {n:,} random points")
    return lines


def sampled_max_gradient(shape, lo, hi, n: int = 65) -> float:
    """max |grad f| over the n^3 nodes of the box (corners included), exact forward-mode
    gradients from warpmesh's tape (wm.evaluate(..., gradient=True))."""
    axes = [np.linspace(lo[i], hi[i], n) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    fg = wm.evaluate(shape, pts, gradient=True)
    return float(np.sqrt((fg[:, 1:].astype(np.float64) ** 2).sum(axis=1)).max())


# =============================================================================================
# the tools: each call returns {'points', 'faces', optional 't_eval' / 't_extract', 'info', ...}
# =============================================================================================
def numpy_volume(shape, lo, hi, n, slab_points) -> np.ndarray:
    """f at the n^3 nodes (np.linspace per axis) with numpy: the expression oracle
    (Shape.eval_numpy, float64) on open 1-D axes, slab by slab along x (about
    ``slab_points`` nodes each: its intermediates stay small), cast to float32."""
    x, y, z = (np.linspace(lo[i], hi[i], n) for i in range(3))
    out = np.empty((n, n, n), dtype=np.float32)
    step = max(1, slab_points // (n * n))
    for a in range(0, n, step):
        b = min(n, a + step)
        out[a:b] = shape.eval_numpy(x[a:b, None, None], y[None, :, None], z[None, None, :])
    return out


def skimage_mc(vol, lo, hi):
    n = vol.shape[0]
    h = tuple((hi[i] - lo[i]) / (n - 1) for i in range(3))
    verts, faces, _normals, _values = sk_marching_cubes(vol, level=0.0, spacing=h, method="lewiner")
    verts += np.asarray(lo, dtype=verts.dtype)
    return {"points": verts, "faces": faces}


def warp_sparse_mc(name, lo, hi, n, lipschitz):
    clock = [0.0]
    field = warp_field(WARP_KERNELS[name], clock)
    t0 = time.perf_counter()
    verts, indices, stats = wpg.sparse_marching_cubes(field, n, n, n, lower=wp.vec3(*lo), upper=wp.vec3(*hi),
                                                      threshold=0.0, lipschitz_bound=float(lipschitz),
                                                      device=DEVICE, return_stats=True)
    points, faces = verts.numpy(), indices.numpy().reshape(-1, 3)
    total = time.perf_counter() - t0
    return {"points": points, "faces": faces, "stats": stats, "evaluations": stats["field_evaluations"],
            "t_eval": clock[0], "t_extract": total - clock[0]}


def _mesh_out(m):
    t = m.info.get("time", {})
    out = {"points": m.points, "faces": m.cells["triangle"], "info": m.info, "mesh": m,
           "evaluations": m.info.get("evaluations"), "stages": dict(t)}
    if "evaluate" in t:
        out["t_eval"] = t.get("cull", 0.0) + t["evaluate"]
        out["t_extract"] = sum(v for k, v in t.items() if k not in ("total", "compile", "cull", "evaluate"))
    return out


def warpmesh_grid(shape, lo, hi, n_cells):
    m = wm.mesh_surface(shape, bounds=(tuple(lo), tuple(hi)), resolution=n_cells, evaluator="compiled",
                        device=DEVICE)
    return _mesh_out(m)


class Adaptive:
    """warpmesh's adaptive mesher: mesh_surface(..., adaptive=True, max_level=, tolerance=),
    probed once per shape (the probe doubles as its warm-up); a failure is reported in its
    row and the peers still run."""

    def __init__(self, tolerance):
        self.tolerance = tolerance
        self.failure = None  # why the last probe failed, when it did

    def missing(self) -> str:
        """The table line when the adaptive mesher did not run."""
        return f"warpmesh adaptive: {self.failure}"

    def call(self, shape, lo, hi, max_level):
        m = wm.mesh_surface(shape, bounds=(tuple(lo), tuple(hi)), adaptive=True, max_level=max_level,
                            tolerance=self.tolerance, device=DEVICE)
        return _mesh_out(m)

    def probe(self, shape, lo, hi, max_level):
        """True when the adaptive mesher runs on this shape."""
        try:
            self.call(shape, lo, hi, max_level)
        except Exception as exc:  # noqa: BLE001 -- reported in the table, the peers still run
            self.failure = f"failed ({type(exc).__name__}: {str(exc)[:200]})"
            return False
        self.failure = None
        return True


# =============================================================================================
# timing: warm-up, then round-robin best of N
# =============================================================================================
def _no_warmup():
    """The warm-up of a tool whose probe call already was one."""


def run_tools(entries: dict, repeat: int, budget: float) -> dict:
    """entries: name -> (call, warm-up call or None for the same call). One untimed warm-up
    each, then ``repeat`` rounds calling each tool once (load from other processes falls on
    all alike); a tool whose timed runs add up to more than ``budget`` s sits the later
    rounds out. Returns name -> {'best', 'samples', 'out' (output of the best run)}."""
    res = {name: {"samples": [], "best": math.inf, "out": None, "warmup": None} for name in entries}
    for name, (call, warm) in entries.items():
        t0 = time.perf_counter()
        (warm or call)()
        res[name]["warmup"] = None if warm is _no_warmup else time.perf_counter() - t0
        gc.collect()
    for r in range(repeat):
        for name, (call, _warm) in entries.items():
            rr = res[name]
            if r > 0 and sum(rr["samples"]) > budget:
                continue
            gc.collect()
            gc.disable()
            try:
                t0 = time.perf_counter()
                out = call()
                wall = time.perf_counter() - t0
            finally:
                gc.enable()
            rr["samples"].append(wall)
            if wall < rr["best"]:
                rr["best"], rr["out"] = wall, out
            else:
                del out
    return res


# =============================================================================================
# checks on the outputs (outside the timings)
# =============================================================================================
def open_edges(faces: np.ndarray) -> int:
    """Number of undirected edges not shared by exactly two triangles (0 = closed)."""
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        return 0
    e = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    e.sort(axis=1)
    key = e[:, 0] * (int(f.max()) + 1) + e[:, 1]
    _, counts = np.unique(key, return_counts=True)
    return int(np.count_nonzero(counts != 2))


def surface_area(points, faces) -> float:
    p = np.asarray(points, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        return 0.0
    return float(0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1).sum())


ADAPTIVE_STATS = ("watertight", "manifold", "oriented", "components", "euler", "genus", "mean_q", "worst_q")


# =============================================================================================
# one case: a shape at one size
# =============================================================================================
def run_case(args, name, n_cells, adaptive: Adaptive, consts) -> dict:
    shape, lo, hi = consts["shapes"][name]
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    n = n_cells + 1
    level = int(round(math.log2(n_cells)))
    h = float((hi - lo).max()) / n_cells
    notes = []
    rows_meta = {}  # name -> dict(kind=..., label=...)
    entries = {}

    # warpmesh adaptive (reference of the ratios)
    ad_name = "warpmesh adaptive"
    ad_missing = None
    if adaptive.probe(shape, lo, hi, level):
        entries[ad_name] = (lambda: adaptive.call(shape, lo, hi, level), _no_warmup)  # the probe warmed it up
        rows_meta[ad_name] = {"kind": "warpmesh"}
        if name == "part":
            mm = consts["part_minmax"]
            lbl = "warpmesh adaptive, min/max booleans"
            try:
                adaptive.call(mm, lo, hi, level)
                entries[lbl] = (lambda: adaptive.call(mm, lo, hi, level), _no_warmup)  # that call was the warm-up
                rows_meta[lbl] = {"kind": "warpmesh", "note": "the part with min/max booleans (the field Warp's "
                                                              "sparse marching cubes meshes)"}
            except Exception as exc:  # noqa: BLE001
                notes.append(f"{lbl}: failed ({type(exc).__name__}: {str(exc)[:160]})")
    else:
        ad_missing = adaptive.missing()

    gname = "warpmesh grid (default, culled)"
    entries[gname] = (lambda: warpmesh_grid(shape, lo, hi, n_cells), None)
    rows_meta[gname] = {"kind": "warpmesh"}

    # numpy evaluation, then scikit-image on that volume: two tools, one row
    grid = {"vol": numpy_volume(shape, lo, hi, n, args.numpy_slab)}  # the volume scikit-image meshes
    entries["numpy evaluation"] = (lambda: {"nodes": numpy_volume(shape, lo, hi, n, args.numpy_slab).size}, None)
    entries["scikit-image marching_cubes"] = (lambda: skimage_mc(grid["vol"], lo, hi), None)

    # Warp sparse marching cubes
    lip = consts["lipschitz"][name]
    sname = f"Warp sparse_marching_cubes (L={lip:.4g})"
    sparse_skip = None
    if (name, "sparse") in SLOW_ABOVE_256 and n_cells > 256 and not args.all:
        seen = consts["sparse_times"].get((name, 256))
        at256 = (f"{seen[0]:.1f} s warm, {seen[1]:.1f} s cold at 256^3 in this run" if seen else
                 "about 4 s warm, 13 s cold at 256^3 on this 2-core VM")
        sparse_skip = (f"{sname}: skipped at {n_cells}^3 ({at256}; its bound keeps most of the box's cells, so "
                       f"expect roughly {(n_cells // 256) ** 3}x that, and ~{SPARSE_BYTES_PER_CELL} B of memory per "
                       f"kept cell); --all runs it where memory allows")
    else:
        kept = consts["sparse_kept"].get(name, SPARSE_KEPT_PRIOR[name])
        need, avail = SPARSE_BYTES_PER_CELL * kept * n_cells ** 3, mem_available()
        if avail is not None and need > 0.8 * avail:
            sparse_skip = (f"{sname}: skipped at {n_cells}^3: it would need about {need / 1e9:.0f} GB (it keeps "
                           f"~{100 * kept:.0f} % of the cells, ~{SPARSE_BYTES_PER_CELL} B each at its peak), "
                           f"{avail / 1e9:.0f} GB are available (a run here was killed for memory)")
        else:
            entries[sname] = (lambda: warp_sparse_mc(name, lo, hi, n, lip), None)
            rows_meta[sname] = {"kind": "sparse"}

    res = run_tools(entries, args.repeat, args.budget)
    if sname in res:
        consts["sparse_times"][(name, n_cells)] = (res[sname]["best"], res[sname]["warmup"])
        consts["sparse_kept"][name] = res[sname]["out"]["stats"]["leaf_cells"] / n_cells ** 3

    # -- rows -----------------------------------------------------------------------------
    rows = []
    dense_evals = n ** 3
    for tname, r in res.items():
        if tname in ("numpy evaluation", "scikit-image marching_cubes"):
            continue
        out = r["out"]
        meta = rows_meta[tname]
        row = {"tool": tname, "time_s": r["best"], "eval_s": out.get("t_eval"), "extract_s": out.get("t_extract"),
               "evaluations": out.get("evaluations"), "samples_s": r["samples"], "warmup_s": r["warmup"],
               "note": meta.get("note", "")}
        if meta["kind"] == "warpmesh":
            row["stages_s"] = out["stages"]
            row["info"] = {k: v for k, v in out["info"].items()
                           if k != "time" and isinstance(v, (int, float, str, bool)) and not isinstance(v, np.ndarray)}
            if tname.startswith("warpmesh adaptive"):
                st = out["mesh"].stats()
                row["stats"] = {k: st[k] for k in ADAPTIVE_STATS if k in st}
        if meta["kind"] == "sparse":
            st = out["stats"]
            row["note"] = (f"keeps {st['leaf_cells']:,} of {n_cells ** 3:,} cells "
                           f"({100 * st['leaf_cells'] / n_cells ** 3:.1f} %)")
            row["sparse_stats"] = {k: (list(v) if isinstance(v, tuple) else v) for k, v in st.items()}
        _finish_row(row, out)
        rows.append(row)
    rn, rs = res["numpy evaluation"], res["scikit-image marching_cubes"]
    row = {"tool": "numpy + scikit-image marching_cubes", "time_s": rn["best"] + rs["best"],
           "eval_s": rn["best"], "extract_s": rs["best"], "evaluations": dense_evals,
           "samples_s": {"numpy": rn["samples"], "skimage": rs["samples"]},
           "warmup_s": {"numpy": rn["warmup"], "skimage": rs["warmup"]}, "note": ""}
    _finish_row(row, rs["out"])
    rows.insert(len([r for r in rows if r["tool"].startswith("warpmesh")]), row)
    grid.clear()
    del res, entries
    gc.collect()

    ref = rows[0] if rows[0]["tool"].startswith("warpmesh adaptive") else None
    for r in rows:
        r["speedup"] = r["time_s"] / ref["time_s"] if ref else None
        r["evals_ratio"] = (r["evaluations"] / ref["evaluations"]
                            if ref and r["evaluations"] and ref["evaluations"] else None)

    if sname in rows_meta:
        notes.append(f"Warp sparse_marching_cubes: {consts['lipschitz_note'][name]}.")
    if name == "degree6":
        notes.append("The degree-six surface meets the box: warpmesh caps it there (closed; the caps are left out of "
                     "'area f=0'), scikit-image and Warp leave it open, so their triangle counts differ.")
    title = (f"{consts['titles'][name]}, {n_cells}^3 cells ({n}^3 nodes, finest cell {h:.4g}); warpmesh adaptive: "
             f"max_level={level}, tolerance={args.tolerance:g}")
    return {"case": f"{name}-{n_cells}", "shape": name, "cells": n_cells, "title": title, "rows": rows,
            "adaptive_missing": ad_missing, "sparse_skipped": sparse_skip, "notes": notes}


def _finish_row(row, out):
    faces = out["faces"]
    row["triangles"] = int(len(faces))
    row["open_edges"] = open_edges(faces)
    refs = (out["mesh"].cell_refs or {}).get("triangle") if "mesh" in out else None
    row["area"] = surface_area(out["points"], faces if refs is None else np.asarray(faces)[np.asarray(refs) != 2])


# =============================================================================================
# printing
# =============================================================================================
def _f(v, fmt="{:.3f}"):
    return "-" if v is None else fmt.format(v)


def print_case(c):
    print()
    print(c["title"])
    hdr = (f"  {'tool':<40} {'time s':>8} {'eval s':>7} {'extract s':>9} {'evaluations':>12} {'triangles':>10} "
           f"{'closed':>14} {'area f=0':>9} {'speed-up':>8} {'evals x':>7}")
    print(hdr)
    print("  " + "-" * (len(hdr) - 2))
    if c["adaptive_missing"]:
        print(f"  {c['adaptive_missing']}")
    for r in c["rows"]:
        closed = "yes" if r["open_edges"] == 0 and r["triangles"] else f"no ({r['open_edges']:,})"
        print(f"  {r['tool']:<40} {r['time_s']:>8.3f} {_f(r['eval_s']):>7} {_f(r['extract_s']):>9} "
              f"{_f(r['evaluations'], '{:,}'):>12} {r['triangles']:>10,} {closed:>14} {r['area']:>9.3f} "
              f"{_f(r['speedup'], '{:.2f}x'):>8} {_f(r['evals_ratio'], '{:.1f}x'):>7}")
    if c["sparse_skipped"]:
        print(f"  {c['sparse_skipped']}")
    for r in c["rows"]:
        if "stages_s" in r:
            st = ", ".join(f"{k} {v:.3f}" for k, v in r["stages_s"].items())
            print(f"  {r['tool']}: stages of the best run (s): {st}")
        if "stats" in r:
            print(f"  {r['tool']}: mesh.stats(): " + ", ".join(
                f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in r["stats"].items()))
            info = {k: v for k, v in r["info"].items() if k not in ("device", "orientation")}
            print(f"  {r['tool']}: info: " + ", ".join(f"{k} {v:,}" if isinstance(v, int) and not isinstance(v, bool)
                                                        else f"{k} {v}" for k, v in info.items()))
        if r["note"]:
            print(f"  {r['tool']}: {r['note']}")
        w = r["warmup_s"]
        if not isinstance(r["samples_s"], dict):
            print(f"  {r['tool']}: timed runs (s): {_rounded(r['samples_s'])}"
                  + ("" if w is None else f" after an untimed {w:.3f}") + ("" if w is not None else
                                                                           " (its probe call was the warm-up)"))
        else:
            print(f"  {r['tool']}: timed runs (s): numpy {_rounded(r['samples_s']['numpy'])} after an untimed "
                  f"{w['numpy']:.3f}, scikit-image {_rounded(r['samples_s']['skimage'])} after {w['skimage']:.3f}")
    for note in c["notes"]:
        print(f"  note: {note}")


def _rounded(xs):
    return "[" + ", ".join(f"{x:.3f}" for x in xs) + "]"


def environment():
    return {"python": platform.python_version(), "machine": platform.processor() or platform.machine(),
            "cores": os.cpu_count(), "numpy": np.__version__, "scikit-image": skimage.__version__,
            "warp": wp.config.version, "warpmesh": getattr(wm, "__version__", "?"),
            "malloc": "freed memory kept in the heap (MALLOC_MMAP_THRESHOLD_/MALLOC_TRIM_THRESHOLD_ 16 GiB)"
                      if all(os.environ.get(k) == v for k, v in _MALLOC_ENV.items()) else "glibc default"}


def legend(args):
    for line in (
        "columns: time s = best of the timed runs (wall); eval s / extract s = its split where the tool has one; "
        "evaluations = point evaluations of f; closed = every edge in two triangles (else the number of other "
        "edges); area f=0 = area of the surface f = 0 (warpmesh's caps on the box, cell ref 2, left out; where the "
        "grid's capped surface meets the box it bends onto the cap within the last cell, so on degree6 its area runs "
        "a little above the open peers'; the adaptive mesh's rim is sharp); speed-up = tool time / warpmesh adaptive time (> 1: the adaptive mesher is "
        "faster); evals x = tool evaluations / the adaptive mesher's.",
        "warpmesh adaptive: mesh_surface(shape, bounds=..., adaptive=True, max_level=log2(N), tolerance=...) "
        "(its default root, covering and evaluator); its first call on each shape probes it and is its warm-up.",
        "warpmesh grid: mesh_surface(shape, bounds=..., resolution=N), the library's default method and covering "
        "(interval-culled 8^3 blocks), evaluator='compiled'; eval = its cull + evaluate stages, extract = the rest.",
        f"numpy + scikit-image: eval = Shape.eval_numpy (the float64 expression oracle, on open 1-D axes, in slabs "
        f"of ~{args.numpy_slab / 1e6:.1f} M nodes along x) into a float32 volume of (N+1)^3 nodes, extract = "
        "skimage.measure.marching_cubes (Lewiner) on it; each the best of its own runs, time = their sum; "
        "evaluations = (N+1)^3.",
        "Warp sparse_marching_cubes: warp.geometry.sparse_marching_cubes(field, N+1, N+1, N+1, lower=, upper=, "
        "lipschitz_bound=L), field = one launch of a Warp kernel over hand-written @wp.func fields; eval = time "
        "inside that callback, extract = the rest (octree pruning, corner de-duplication, marching cubes, output to "
        "numpy); evaluations = its stats['field_evaluations'] (cell centres of the octree + unique corners).",
    ):
        print("legend: " + line)


def summary(results):
    print()
    print("Summary (best-of-N seconds; speed-up = tool / warpmesh adaptive):")
    for c in results:
        parts = []
        for r in c["rows"]:
            s = f"{r['tool'].split(' (')[0]} {r['time_s']:.3f} s"
            if r["speedup"] is not None and r["tool"] != "warpmesh adaptive":
                s += f" ({r['speedup']:.1f}x)"
            parts.append(s)
        if c["sparse_skipped"]:
            parts.append("Warp sparse MC skipped")
        if c["adaptive_missing"]:
            parts.insert(0, "warpmesh adaptive n/a")
        print(f"  {c['case']}: " + "; ".join(parts))


# =============================================================================================
def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=None,
                   help="cells along the longest side (powers of two; max_level = log2); default 256 512, "
                        "32 64 with --quick")
    p.add_argument("--shapes", default=",".join(SHAPES), help=f"comma-separated subset of {','.join(SHAPES)}")
    p.add_argument("--quick", action="store_true", help="small sizes (32 64) and 2 runs per tool: a smoke run")
    p.add_argument("--repeat", type=int, default=None, help="timed warm runs per tool, best taken (default 3; "
                                                             "2 with --quick)")
    p.add_argument("--budget", type=float, default=20.0,
                   help="a tool whose timed runs add up to more than this many seconds runs no more (default 20)")
    p.add_argument("--tolerance", type=float, default=0.02, help="tolerance= of the adaptive mesher (default 0.02)")
    p.add_argument("--all", action="store_true",
                   help="also run the slow peers above 256^3 (Warp sparse_marching_cubes on the degree-six surface)")
    p.add_argument("--lipschitz-safety", type=float, default=1.05,
                   help="Lipschitz bound of the degree-six field for sparse MC = this x the sampled max |grad f| "
                        "(default 1.05)")
    p.add_argument("--numpy-slab", type=int, default=1 << 23, help="nodes per slab of the numpy evaluation "
                                                                     "(default 8388608)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.sizes is None:
        args.sizes = [32, 64] if args.quick else [256, 512]
    bad = [s for s in args.sizes if s < 4 or s & (s - 1)]
    if bad:
        p.error(f"--sizes must be powers of two >= 4 (max_level = log2(size)), got {bad}")
    if args.repeat is None:
        args.repeat = 2 if args.quick else 3
    if args.repeat < 1:
        p.error("--repeat must be >= 1")
    if args.lipschitz_safety < 1.0:
        p.error("--lipschitz-safety must be >= 1 (a bound below the sampled max is not a bound)")
    args.shape_list = [s.strip() for s in args.shapes.split(",") if s.strip()]
    bad = [s for s in args.shape_list if s not in SHAPES]
    if bad:
        p.error(f"unknown shape(s) {bad}; pick from {list(SHAPES)}")
    return args


def main(argv=None):
    args = parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    wp.init()
    t_start = time.perf_counter()
    env = environment()
    print("bench_adaptive: " + ", ".join(f"{k} {v}" for k, v in env.items()))
    load0 = os.getloadavg()[0]
    print(f"best of {args.repeat} warm run(s) per tool after 1 untimed, round-robin (a tool stops once its timed runs "
          f"exceed {args.budget:g} s); load average (1 min) at start: {load0:.2f}"
          + ("  -- WARNING: other processes are using the CPU; timings will be noisy" if load0 > 0.7 else ""))

    part, pb = wm.example("part")
    d6, db = wm.example("degree6")
    mm = part_minmax_shape()
    consts = {"shapes": {"part": (part, *pb), "degree6": (d6, *db)}, "part_minmax": mm,
              "sparse_times": {}, "sparse_kept": {},
              "titles": {"part": "CSG part wm.example('part') (R-function booleans) on [-1.2, 1.2]^3",
                         "degree6": "degree-six surface wm.example('degree6') on [-3, 3]^3"}}
    for line in check_warp_fields({"part": (mm, pb[0], pb[1]), "degree6": (d6, db[0], db[1])}):
        print("Warp fields: " + line)
    g_mm, g_rf, g_d6 = (sampled_max_gradient(s, *b) for s, b in ((mm, pb), (part, pb), (d6, db)))
    # |df/dx| = |2x (y^2+z^2-4)(2x^2+y^2+z^2-8)| <= 2*3*14*28 on [-3, 3]^3 (equality at the corners), same for y, z
    analytic = 2 * 3 * 14 * 28 * math.sqrt(3)
    lip_d6 = args.lipschitz_safety * g_d6
    consts["lipschitz"] = {"part": 1.0, "degree6": lip_d6}
    consts["lipschitz_note"] = {
        "part": f"Lipschitz bound 1 on the min/max part (exact distances of box, cylinders, ball, combined with "
                f"min/max; sampled max |grad f| {g_mm:.4f} over 65^3 nodes; the R-function part's is {g_rf:.3f}, "
                f"so bound 1 would not be safe for it: same surface, min/max field)",
        "degree6": f"Lipschitz bound {lip_d6:.1f} = {args.lipschitz_safety:g} x the largest |grad f| over 65^3 nodes "
                   f"of the box, {g_d6:.1f} (at the corners; analytic max sqrt(3)*2*3*14*28 = {analytic:.1f})",
    }
    print(f"Lipschitz bounds for Warp sparse_marching_cubes: part (min/max) 1 (sampled max |grad f| {g_mm:.4f}); "
          f"degree6 {lip_d6:.1f} = {args.lipschitz_safety:g} x sampled max |grad f| {g_d6:.1f} over 65^3 nodes "
          f"(analytic max {analytic:.1f})")
    legend(args)
    sys.stdout.flush()

    adaptive = Adaptive(args.tolerance)
    results = []
    for name in args.shape_list:
        for n_cells in args.sizes:
            c = run_case(args, name, n_cells, adaptive, consts)
            print_case(c)
            sys.stdout.flush()
            results.append(c)
    summary(results)
    if adaptive.failure:
        print(adaptive.missing())
    elapsed = time.perf_counter() - t_start
    load1 = os.getloadavg()[0]
    print(f"\nbenchmark wall time {elapsed:.0f} s; load average (1 min) at the end: {load1:.2f}")
    if args.json:
        doc = {"environment": env, "args": {k: v for k, v in vars(args).items()}, "load_average_start_end":
               [load0, load1], "lipschitz": consts["lipschitz"], "wall_s": elapsed, "cases": results}
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(doc, fh, indent=1, default=str)
        os.replace(tmp, args.json)
        print(f"results written to {args.json}")


if __name__ == "__main__":
    main()
