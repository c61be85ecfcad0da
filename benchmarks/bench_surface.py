#!/usr/bin/env python3
"""Surface meshing, warpmesh side by side with its peers on the CPU (one run, all cases).

Cases (``--cases``, comma separated; default all):

``sphere``   (a) a sphere field sampled as a float32 numpy volume, the same array
             handed to every tool: warpmesh ``mesh_surface(volume, ...)``, scikit-image
             ``marching_cubes`` (Lewiner), VTK flying edges (pyvista), PyMCubes, Warp
             ``warp.geometry.IsoSurfaceMarchingCubes`` (= ``wp.MarchingCubes``).
``degree6``  (b) the degree-six surface on [-3, 3]^3: warpmesh from the shape versus
             numpy evaluation (broadcast open axes) + scikit-image / VTK flying edges /
             Warp marching cubes on that grid.
``part``     (c) the CSG part, R-function and min/max booleans: as (b), plus Warp's
             ``warp.geometry.sparse_marching_cubes`` (Lipschitz octree, bound 1) on the
             min/max variant, fed by warpmesh's Warp tape evaluator.

Every tool meshes the same nodes (``np.linspace(lo, hi, n)`` per axis). Times are
medians of ``--repeat`` warm runs after ``--warmup`` untimed runs per tool; "closed"
is one numpy test for every tool (each undirected edge in exactly two triangles).
The ratio column is peer total / warpmesh total (> 1: warpmesh is faster).

Run:  python benchmarks/bench_surface.py [--quick] [--repeat 3] [--cases sphere,part]
                                         [--json results.json]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import statistics
import sys
import time
import warnings

# Memory: a page touched for the first time costs ~2 ms/MB of kernel time in this VM (freed
# memory goes back to the host), so whichever tool gets fresh pages from mmap pays far more
# than its algorithm: numpy's evaluation of the CSG part swung between 0.42 s and 3.7 s from
# run to run. By default the benchmark re-runs itself with glibc told to keep freed memory in
# the heap (the same for every tool); --default-malloc measures with the stock allocator.
_MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": str(16 << 30), "MALLOC_TRIM_THRESHOLD_": str(16 << 30)}
if __name__ == "__main__" and "--default-malloc" not in sys.argv[1:] and "-h" not in sys.argv[1:] \
        and "--help" not in sys.argv[1:] and any(k not in os.environ for k in _MALLOC_ENV) \
        and sys.platform.startswith("linux"):
    os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **_MALLOC_ENV})

import numpy as np  # noqa: E402

# -- the tools' imports (all required: this is the side-by-side benchmark) --------------------
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no init banner / module-load lines in the tables
import warp.geometry as wpg  # noqa: E402

import warpmesh as wm  # noqa: E402
from warpmesh.tape import eval_values, tape_of  # noqa: E402

try:
    mesh_surface = wm.mesh_surface
except AttributeError:  # not yet re-exported at the top level
    from warpmesh.surface import mesh_surface

import mcubes  # noqa: E402
import pyvista as pv  # noqa: E402
import skimage  # noqa: E402
import vtk  # noqa: E402
from skimage.measure import marching_cubes as sk_marching_cubes  # noqa: E402

DEVICE = "cpu"
CASE_NAMES = ("sphere", "degree6", "part")
CASE_ALIASES = {"a": "sphere", "b": "degree6", "c": "part"}


# =============================================================================================
# the common checks
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


def grid_axes(lo, hi, n):
    """The node coordinates of every tool: np.linspace(lo, hi, n) on each axis."""
    return [np.linspace(lo[i], hi[i], n) for i in range(3)]


def numpy_volume(shape, lo, hi, n) -> np.ndarray:
    """f at the grid nodes with numpy (float64, broadcast open axes) cast to float32."""
    x, y, z = grid_axes(lo, hi, n)
    f = shape.eval_numpy(x[:, None, None], y[None, :, None], z[None, None, :])
    return np.ascontiguousarray(np.broadcast_to(f, (n, n, n)), dtype=np.float32)


# =============================================================================================
# timing
# =============================================================================================
def _timed_call(fn):
    gc.collect()
    gc.disable()
    try:
        t0 = time.perf_counter()
        out = fn()
        wall = time.perf_counter() - t0
    finally:
        gc.enable()
    sample = {k: v for k, v in out.items() if k.startswith("t_")}
    sample["wall"] = wall
    return sample, out


def run_interleaved(entries: dict, repeat: int, warmup: int) -> dict:
    """Time every tool of a case: ``warmup`` untimed calls each, then ``repeat`` rounds
    calling every tool once per round (round-robin, so load from other processes on the
    machine falls on all tools alike). ``entries`` maps a name to a callable returning a
    dict with 'points', 'faces' and optional 't_*' stage times. Returns
    {name: (medians of the timed samples, output of the last call)}."""
    for fn in entries.values():
        for _ in range(warmup):
            fn()
            gc.collect()
    samples = {name: [] for name in entries}
    last = {}
    for _ in range(repeat):
        for name, fn in entries.items():
            last.pop(name, None)
            sample, last[name] = _timed_call(fn)
            samples[name].append(sample)
    res = {}
    for name, ss in samples.items():
        med = {k: statistics.median(s[k] for s in ss) for k in ss[0]}
        med["samples"] = [s["wall"] for s in ss]
        res[name] = (med, last[name])
    return res


# =============================================================================================
# the tools: each takes the inputs and returns {'points', 'faces', optional 't_*' stage times}
# =============================================================================================
def warpmesh_volume(vol, lo, h, **kw):
    m = mesh_surface(vol, level=0.0, spacing=h, origin=tuple(lo), device=DEVICE, **kw)
    return _warpmesh_out(m)


def warpmesh_shape(shape, lo, hi, res, **kw):
    kw.setdefault("evaluator", "compiled")  # warm runs: the kernel generated for the tape (compiled in warm-up)
    m = mesh_surface(shape, bounds=(tuple(lo), tuple(hi)), resolution=res, device=DEVICE, **kw)
    return _warpmesh_out(m)


def _warpmesh_out(m):
    t = m.info["time"]
    out = {"points": m.points, "faces": m.cells["triangle"], "info": m.info,
           "t_eval": t.get("cull", 0.0) + t.get("evaluate", 0.0),
           "t_extract": t.get("extract", 0.0) + t.get("cap", 0.0) + t.get("host", 0.0) + t.get("root", 0.0)}
    for k, v in t.items():
        out["t_stage_" + k] = v
    return out


def skimage_mc(vol, lo, h):
    verts, faces, _normals, _values = sk_marching_cubes(vol, level=0.0, spacing=(h, h, h), method="lewiner")
    verts += np.asarray(lo, dtype=verts.dtype)
    return {"points": verts, "faces": faces}


def vtk_flying_edges(vol, lo, h):
    # pyvista/VTK images are x-fastest (Fortran order); a C-order (x, y, z) array is the
    # same memory as an x-fastest image of axes (z, y, x): hand it over without a copy
    # and swap the point coordinates back.
    img = pv.ImageData(dimensions=vol.shape[::-1], spacing=(h, h, h), origin=tuple(lo[::-1]))
    img.point_data["f"] = vol.reshape(-1)
    surf = img.contour([0.0], scalars="f", method="flying_edges", compute_scalars=False)
    points = np.asarray(surf.points)[:, ::-1]
    return {"points": points, "faces": surf.regular_faces}


def pymcubes_mc(vol, lo, h):
    verts, faces = mcubes.marching_cubes(vol, 0.0)
    verts *= h
    verts += np.asarray(lo)
    return {"points": verts, "faces": faces}


def warp_mc(vol, lo, hi):
    field = wp.array(vol, dtype=wp.float32, device=DEVICE, copy=False)  # aliases the numpy array
    verts, indices = wpg.IsoSurfaceMarchingCubes.extract(field, 0.0, lower=wp.vec3(*lo), upper=wp.vec3(*hi))
    return {"points": verts.numpy(), "faces": indices.numpy().reshape(-1, 3)}


def warp_sparse_mc(shape, lo, hi, n):
    """Warp's Lipschitz-octree sparse marching cubes, f evaluated by warpmesh's tape
    interpreter in Warp (the same evaluator warpmesh's own pipeline runs)."""
    tape = tape_of(shape)
    t_eval = [0.0]

    def field(points):
        t0 = time.perf_counter()
        vals = eval_values(tape, points, device=DEVICE, evaluator="compiled")  # warpmesh's fastest evaluator
        t_eval[0] += time.perf_counter() - t0
        return vals

    t0 = time.perf_counter()
    verts, indices, stats = wpg.sparse_marching_cubes(field, n, n, n, lower=wp.vec3(*lo), upper=wp.vec3(*hi),
                                                      lipschitz_bound=1.0, device=DEVICE, return_stats=True)
    points, faces = verts.numpy(), indices.numpy().reshape(-1, 3)
    total = time.perf_counter() - t0
    return {"points": points, "faces": faces, "stats": stats, "t_eval": t_eval[0], "t_extract": total - t_eval[0]}


# =============================================================================================
# cases
# =============================================================================================
def row(tool, t_eval, t_extract, t_total, out, note="", samples=None):
    faces = out["faces"]
    bad = open_edges(faces)
    return {"tool": tool, "evaluate_s": t_eval, "extract_s": t_extract, "total_s": t_total,
            "triangles": int(len(faces)), "closed": bool(bad == 0 and len(faces) > 0), "open_edges": bad,
            "note": note, "wall_samples_s": samples}


def warpmesh_row(label, med, out, note=""):
    stages = {k[len("t_stage_"):]: v for k, v in med.items() if k.startswith("t_stage_")}
    r = row(label, med["t_eval"], med["t_extract"], med["wall"], out, note, med["samples"])
    r["stages_s"] = stages
    r["outside_stages_s"] = med["wall"] - sum(v for k, v in stages.items() if k != "total")
    info = out["info"]
    r["active_blocks"], r["blocks"], r["evaluations"] = (info.get("active_blocks"), info.get("blocks"),
                                                          info.get("evaluations"))
    return r


def peer_entries(vol, lo, hi, n, tools) -> dict:
    """Each peer's extraction from the same float32 volume."""
    h = (hi[0] - lo[0]) / (n - 1)
    runners = {
        "scikit-image (Lewiner)": lambda: skimage_mc(vol, lo, h),
        "VTK flying edges": lambda: vtk_flying_edges(vol, lo, h),
        "PyMCubes": lambda: pymcubes_mc(vol, lo, h),
        "Warp IsoSurfaceMarchingCubes": lambda: warp_mc(vol, lo, hi),
    }
    return {name: runners[name] for name in tools}


def case_sphere(args):
    n_cells = args.size_sphere
    shape, (lo, hi) = wm.example("sphere")
    lo, hi = np.array(lo, float), np.array(hi, float)
    n = n_cells + 1
    vol = numpy_volume(shape, lo, hi, n)
    h = (hi[0] - lo[0]) / n_cells
    entries = {"warpmesh": lambda: warpmesh_volume(vol, lo, h)}
    entries.update(peer_entries(vol, lo, hi, n, ["scikit-image (Lewiner)", "VTK flying edges", "PyMCubes",
                                                 "Warp IsoSurfaceMarchingCubes"]))
    res = run_interleaved(entries, args.repeat, args.warmup)
    rows = []
    for name, (med, out) in res.items():
        if name == "warpmesh":
            r = warpmesh_row(name, med, out)
            r["evaluate_s"], r["extract_s"] = None, med["wall"]
        else:
            r = row(name, None, med["wall"], med["wall"], out, samples=med["samples"])
        rows.append(r)
    return {"case": "sphere", "title": f"(a) sphere r=1 on [-1.2, 1.2]^3, {n_cells}^3 cells, float32 numpy volume "
                                       f"({n}^3 nodes) handed to every tool",
            "cells": n_cells, "rows": rows,
            "notes": ["evaluation: none (the volume is given); extraction = total wall time of each call, "
                      "including its output as numpy arrays."]}


NUMPY = "numpy evaluation"
SPARSE = "Warp sparse_marching_cubes (L=1)"


def case_from_shape(args, key, title, shape, lo, hi, n_cells, *, sparse=False, sparse_note="", extra_warpmesh=()):
    lo, hi = np.array(lo, float), np.array(hi, float)
    n = n_cells + 1
    vol = numpy_volume(shape, lo, hi, n)  # the grid every peer extracts from
    entries = {"warpmesh": lambda: warpmesh_shape(shape, lo, hi, n_cells),
               "warpmesh interpreter": lambda: warpmesh_shape(shape, lo, hi, n_cells, evaluator="interpreter")}
    notes_of = {"warpmesh interpreter": "the tape interpreter (what a first, cold evaluation uses)"}
    for label, kw, note in extra_warpmesh:
        entries[label] = lambda kw=kw: warpmesh_shape(shape, lo, hi, n_cells, **kw)
        notes_of[label] = note
    entries[NUMPY] = lambda: {"points": None, "faces": None, "vol": numpy_volume(shape, lo, hi, n)}
    entries.update(peer_entries(vol, lo, hi, n, ["scikit-image (Lewiner)", "VTK flying edges",
                                                 "Warp IsoSurfaceMarchingCubes"]))
    if sparse:
        entries[SPARSE] = lambda: warp_sparse_mc(shape, lo, hi, n)
    res = run_interleaved(entries, args.repeat, args.warmup)
    t_numpy = res[NUMPY][0]["wall"]
    numpy_samples = res[NUMPY][0]["samples"]
    rows = []
    for name, (med, out) in res.items():
        if name.startswith("warpmesh"):
            rows.append(warpmesh_row(name, med, out, notes_of.get(name, "")))
        elif name == SPARSE:
            st = out["stats"]
            rows.append(row(name, med["t_eval"], med["t_extract"], med["wall"], out,
                            f"keeps {st['leaf_cells']:,} of {n_cells ** 3:,} cells, "
                            f"{st['field_evaluations']:,} evaluations", med["samples"]))
        elif name != NUMPY:
            rows.append(row("numpy + " + name, t_numpy, med["wall"], t_numpy + med["wall"], out,
                            samples=med["samples"]))
    del vol, res
    gc.collect()
    notes = [f"numpy evaluation (eval_numpy on open 1-D axes, float64, cast to float32): {t_numpy:.3f} s, "
             "timed separately and added to each numpy + peer row.",
             "warpmesh: evaluation = its 'cull' + 'evaluate' stages, extraction = 'extract' + 'cap' + 'host'; "
             "total = wall time of mesh_surface; evaluator='compiled' (a kernel generated for the tape's "
             "structure, compiled during warm-up) unless the row says interpreter."]
    if sparse:
        notes.append("Warp sparse_marching_cubes: Lipschitz bound 1 (the min/max part is 1-Lipschitz: exact SDF "
                     "primitives combined with min/max), f by warpmesh's compiled tape kernel; evaluation = "
                     "time inside that callback, extraction = the rest.")
    elif sparse_note:
        notes.append(sparse_note)
    return {"case": key, "title": title, "cells": n_cells, "rows": rows, "notes": notes,
            "numpy_evaluation_samples_s": numpy_samples}


def case_degree6(args):
    shape, (lo, hi) = wm.example("degree6")
    results = []
    for n_cells in args.sizes_degree6:
        results.append(case_from_shape(
            args, f"degree6-{n_cells}",
            f"(b) degree-six surface on [-3, 3]^3, {n_cells}^3 cells ({n_cells + 1}^3 nodes)",
            shape, lo, hi, n_cells,
            extra_warpmesh=[("warpmesh cap=False", {"cap": False},
                             "like the peers: surface left open where it meets the box")],
            sparse_note="Warp sparse_marching_cubes: not run (needs a Lipschitz bound; this polynomial's is in "
                        "the thousands on [-3, 3]^3, PEERS.md measured 15.5 s at 256^3)."))
        results[-1]["notes"].append(
            "The surface meets the box (f > 0 at the corners): warpmesh caps it by default (closed), "
            "the peers leave it open; the 'warpmesh cap=False' row is the like-for-like one.")
    return results


def part_minmax():
    holes = [wm.cylinder(0.2).translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
    return wm.union(wm.difference(wm.box((2, 2, 0.6)), *holes, method="minmax"), wm.sphere(0.5), method="minmax")


def case_part(args):
    n_cells = args.size_part
    shape, (lo, hi) = wm.example("part")
    out = [case_from_shape(args, "part-rfunction",
                           f"(c) CSG part, R-function booleans (default), {n_cells}^3 cells on [-1.2, 1.2]^3",
                           shape, lo, hi, n_cells,
                           sparse_note="Warp sparse_marching_cubes: not run on the R-function part (its field is "
                                       "not 1-Lipschitz, so bound 1 could drop surface cells); see the min/max "
                                       "table.")]
    out.append(case_from_shape(args, "part-minmax",
                               f"(c) CSG part, min/max booleans, {n_cells}^3 cells on [-1.2, 1.2]^3",
                               part_minmax(), lo, hi, n_cells, sparse=True))
    return out


# =============================================================================================
# printing
# =============================================================================================
def fmt_s(v):
    return "-" if v is None else f"{v:.3f}"


def print_case(c):
    rows = c["rows"]
    ref = rows[0]["total_s"]
    for r in rows:
        r["ratio"] = r["total_s"] / ref
    print()
    print(c["title"])
    hdr = f"  {'tool':<44} {'eval s':>8} {'extract s':>9} {'total s':>8} {'triangles':>10} {'closed':>16} {'ratio':>7}"
    print(hdr)
    print("  " + "-" * (len(hdr) - 2))
    for r in rows:
        closed = "yes" if r["closed"] else f"no ({r['open_edges']:,} open)"
        print(f"  {r['tool']:<44} {fmt_s(r['evaluate_s']):>8} {fmt_s(r['extract_s']):>9} {r['total_s']:>8.3f} "
              f"{r['triangles']:>10,} {closed:>16} {r['ratio']:>6.2f}x")
    for r in rows:
        if "stages_s" in r:
            st = ", ".join(f"{k} {v:.3f}" for k, v in r["stages_s"].items() if k != "total")
            print(f"  {r['tool']} stages (median s): {st}; outside the stages {r['outside_stages_s']:.3f}; "
                  f"active blocks {r['active_blocks']:,}/{r['blocks']:,}, evaluations {r['evaluations']:,}")
            if r["note"]:
                print(f"    {r['tool']}: {r['note']}")
        elif r["note"]:
            print(f"  {r['tool']}: {r['note']}")
    for note in c["notes"]:
        print(f"  note: {note}")


def summary_line(c):
    rows = c["rows"]
    wmt = rows[0]["total_s"]
    parts = []
    for r in rows[1:]:
        if r["tool"].startswith("warpmesh"):
            continue
        ratio = r["total_s"] / wmt
        verdict = f"{ratio:.1f}x faster" if ratio >= 1 else f"{1 / ratio:.1f}x slower"
        parts.append(f"vs {r['tool']} {r['total_s']:.3f} s: {verdict}")
    return f"{c['case']}: warpmesh {wmt:.3f} s " + "; ".join(parts)


def environment():
    smp = vtk.vtkSMPTools()
    return {
        "python": platform.python_version(), "machine": platform.processor() or platform.machine(),
        "cores": os.cpu_count(), "numpy": np.__version__, "scikit-image": skimage.__version__,
        "pyvista": pv.__version__, "vtk": vtk.vtkVersion.GetVTKVersion(),
        "vtk_smp_backend": f"{smp.GetBackend()} ({smp.GetEstimatedNumberOfThreads()} threads)",
        "pymcubes": getattr(mcubes, "__version__", "?"), "warp": wp.config.version,
        "malloc": "freed memory kept in the heap (MALLOC_MMAP_THRESHOLD_/MALLOC_TRIM_THRESHOLD_ 16 GiB)"
                  if all(os.environ.get(k) == v for k, v in _MALLOC_ENV.items()) else "glibc default",
    }


# =============================================================================================
def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default="sphere,degree6,part",
                   help="comma-separated subset of sphere,degree6,part (or a,b,c); default all")
    p.add_argument("--repeat", type=int, default=None, help="timed warm runs per tool (median); default 3, 1 with --quick")
    p.add_argument("--warmup", type=int, default=1, help="untimed runs per tool before timing (default 1)")
    p.add_argument("--quick", action="store_true", help="small grids (64^3; degree-six 32^3 and 64^3): a smoke run")
    p.add_argument("--vtk-backend", default="STDThread", choices=("STDThread", "Sequential"),
                   help="VTK SMP backend for flying edges (default STDThread: threaded, like warpmesh)")
    p.add_argument("--default-malloc", action="store_true",
                   help="keep glibc's default allocator (fresh pages per large array: slow and noisy in this VM)")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.repeat is None:
        args.repeat = 1 if args.quick else 3
    if args.repeat < 1 or args.warmup < 0:
        p.error("--repeat must be >= 1 and --warmup >= 0")
    cases = [CASE_ALIASES.get(c.strip(), c.strip()) for c in args.cases.split(",") if c.strip()]
    bad = [c for c in cases if c not in CASE_NAMES]
    if bad:
        p.error(f"unknown case(s) {bad}; pick from {list(CASE_NAMES)}")
    args.case_list = cases
    args.size_sphere = 64 if args.quick else 256
    args.sizes_degree6 = (32, 64) if args.quick else (128, 256)
    args.size_part = 64 if args.quick else 256
    return args


def main(argv=None):
    args = parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    vtk.vtkSMPTools().SetBackend(args.vtk_backend)
    wp.init()
    env = environment()
    print("bench_surface: " + ", ".join(f"{k} {v}" for k, v in env.items()))
    print(f"medians of {args.repeat} timed run(s) after {args.warmup} warm-up run(s) per tool; "
          f"ratio = tool total / warpmesh total (> 1: warpmesh faster)")
    load0 = os.getloadavg()[0]
    print(f"load average (1 min) at start: {load0:.2f}" + (
        "  -- WARNING: other processes are using the CPU; timings will be noisy" if load0 > 0.7 else ""))
    t_start = time.perf_counter()
    results = []
    builders = {"sphere": lambda: [case_sphere(args)], "degree6": lambda: case_degree6(args),
                "part": lambda: case_part(args)}
    for name in args.case_list:
        for c in builders[name]():
            print_case(c)
            sys.stdout.flush()
            results.append(c)
    print()
    print("Summary (total seconds, medians):")
    for c in results:
        line = summary_line(c)
        c["summary"] = line
        print("  " + line)
    elapsed = time.perf_counter() - t_start
    load1 = os.getloadavg()[0]
    print(f"\nbenchmark wall time {elapsed:.0f} s; load average (1 min) at the end: {load1:.2f}")
    if args.json:
        doc = {"environment": env, "load_average_start_end": [load0, load1], "repeat": args.repeat, "warmup": args.warmup, "quick": args.quick,
               "wall_s": elapsed, "cases": results}
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(doc, fh, indent=1)
        os.replace(tmp, args.json)
        print(f"results written to {args.json}")


if __name__ == "__main__":
    main()
