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
``large``    (d) volumes of 320^3 = 32.8 M samples, a float32 field and a uint8 label
             volume: wall time and peak extra memory over the input of warpmesh (mc at
             each ``--slab-voxels`` size, the other methods at the first) and the peers,
             each measured in a fresh process (_large_volume.py).
``continuation``  (e) the shapes of (b) and (c) with covering="continuation", the culled
             grid (default) and the dense grid (cull=False): evaluations and time.

warpmesh rows run method="mc" unless they name another (the library's default is printed
in the header); in (a)-(d) every method of ``--methods`` (mt, mc33) gets a row too, and a
method missing from this build prints "not available in this build".

Every tool meshes the same nodes (``np.linspace(lo, hi, n)`` per axis). Times are
medians of ``--repeat`` warm runs after ``--warmup`` untimed runs per tool; "closed"
is one numpy test for every tool (each undirected edge in exactly two triangles).
The ratio column is tool total / warpmesh total (> 1: warpmesh is faster).

Run:  python benchmarks/bench_surface.py [--quick] [--repeat 3] [--cases sphere,part]
                                         [--methods mt,mc33] [--large-size 320]
                                         [--slab-voxels 16777216,4194304] [--json results.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import json
import os
import platform
import shutil
import statistics
import sys
import tempfile
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
from warpmesh.frep.tape import eval_values, tape_of  # noqa: E402
from warpmesh.surface.volume import SLAB_VOXELS  # noqa: E402

try:
    mesh_surface = wm.mesh_surface
except AttributeError:  # not yet re-exported at the top level
    from warpmesh.surface.pipeline import mesh_surface

import mcubes  # noqa: E402
import pyvista as pv  # noqa: E402
import skimage  # noqa: E402
import vtk  # noqa: E402
from skimage.measure import marching_cubes as sk_marching_cubes  # noqa: E402

import _large_volume as LV  # noqa: E402  (benchmarks/: the large volumes and their measuring processes)

DEVICE = "cpu"
CASE_NAMES = ("sphere", "degree6", "part", "large", "continuation")
CASE_ALIASES = {"a": "sphere", "b": "degree6", "c": "part", "d": "large", "e": "continuation"}
EXTRA_METHODS = ("mt", "mc33")


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
# warpmesh rows run method="mc" unless they name another (the same algorithm as the peers;
# the library's default method may differ: the header line prints it)
def warpmesh_volume(vol, lo, h, **kw):
    kw.setdefault("method", "mc")
    m = mesh_surface(vol, level=0.0, spacing=h, origin=tuple(lo), device=DEVICE, **kw)
    return _warpmesh_out(m)


def warpmesh_shape(shape, lo, hi, res, **kw):
    kw.setdefault("evaluator", "compiled")  # warm runs: the kernel generated for the tape (compiled in warm-up)
    kw.setdefault("method", "mc")
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
    r["engine"], r["slabs"] = info.get("engine"), info.get("slabs")  # a volume's: "rows" has no blocks
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


def unavailable_row(tool, message):
    """A table line for a warpmesh method that did not run (see method_entries)."""
    return {"tool": tool, "unavailable": message}


def method_entries(make, methods) -> tuple[dict, list]:
    """warpmesh entries for the extra extraction methods (``--methods``), ``make(method=m)``
    each. One probe call per method first: a method missing from this build (mc33 before its
    tables land) raises ImportError and gets a "not available" line instead of a row; one
    that raises anything else on this case gets a "failed" line with the error. The probe
    is retried in every case, so a method that lands is picked up without a change here."""
    entries, missing = {}, []
    for m in methods:
        fn = lambda m=m: make(method=m)  # noqa: E731
        try:
            fn()
        except ImportError:  # ModuleNotFoundError included
            missing.append(unavailable_row(f"warpmesh {m}", f"{m}: not available in this build"))
            continue
        except Exception as exc:  # noqa: BLE001 -- a method still under development: report it, go on
            missing.append(unavailable_row(f"warpmesh {m}", f"{m}: failed on this case ({type(exc).__name__}: "
                                                            f"{str(exc)[:120]})"))
            continue
        entries[f"warpmesh {m}"] = fn
    return entries, missing


METHOD_NOTE = ("warpmesh rows use method='mc' unless named; warpmesh mt / mc33: the same call with method='mt' "
               "(marching tetrahedra, Kuhn split: about 3x the triangles) or 'mc33' (marching cubes 33: the "
               "topology of the trilinear interpolant); ratio against warpmesh mc.")


def case_sphere(args):
    n_cells = args.size_sphere
    shape, (lo, hi) = wm.example("sphere")
    lo, hi = np.array(lo, float), np.array(hi, float)
    n = n_cells + 1
    vol = numpy_volume(shape, lo, hi, n)
    h = (hi[0] - lo[0]) / n_cells
    entries = {"warpmesh mc": lambda: warpmesh_volume(vol, lo, h)}
    methods, missing = method_entries(lambda **kw: warpmesh_volume(vol, lo, h, **kw), args.methods)
    entries.update(methods)
    entries.update(peer_entries(vol, lo, hi, n, ["scikit-image (Lewiner)", "VTK flying edges", "PyMCubes",
                                                 "Warp IsoSurfaceMarchingCubes"]))
    res = run_interleaved(entries, args.repeat, args.warmup)
    rows = []
    for name, (med, out) in res.items():
        if name.startswith("warpmesh"):
            r = warpmesh_row(name, med, out)
            r["evaluate_s"], r["extract_s"] = None, med["wall"]
        else:
            r = row(name, None, med["wall"], med["wall"], out, samples=med["samples"])
        rows.append(r)
    rows[len(methods) + 1:len(methods) + 1] = missing  # after the warpmesh rows
    return {"case": "sphere", "title": f"(a) sphere r=1 on [-1.2, 1.2]^3, {n_cells}^3 cells, float32 numpy volume "
                                       f"({n}^3 nodes) handed to every tool",
            "cells": n_cells, "rows": rows,
            "notes": ["evaluation: none (the volume is given); extraction = total wall time of each call, "
                      "including its output as numpy arrays.", METHOD_NOTE]}


NUMPY = "numpy evaluation"
SPARSE = "Warp sparse_marching_cubes (L=1)"


def case_from_shape(args, key, title, shape, lo, hi, n_cells, *, sparse=False, sparse_note="", extra_warpmesh=()):
    lo, hi = np.array(lo, float), np.array(hi, float)
    n = n_cells + 1
    vol = numpy_volume(shape, lo, hi, n)  # the grid every peer extracts from
    entries = {"warpmesh mc": lambda: warpmesh_shape(shape, lo, hi, n_cells),
               "warpmesh interpreter": lambda: warpmesh_shape(shape, lo, hi, n_cells, evaluator="interpreter")}
    notes_of = {"warpmesh interpreter": "the tape interpreter (what a first, cold evaluation uses)"}
    for label, kw, note in extra_warpmesh:
        entries[label] = lambda kw=kw: warpmesh_shape(shape, lo, hi, n_cells, **kw)
        notes_of[label] = note
    methods, missing = method_entries(lambda **kw: warpmesh_shape(shape, lo, hi, n_cells, **kw), args.methods)
    entries.update(methods)
    entries[NUMPY] = lambda: {"points": None, "faces": None, "vol": numpy_volume(shape, lo, hi, n)}
    entries.update(peer_entries(vol, lo, hi, n, ["scikit-image (Lewiner)", "VTK flying edges",
                                                 "Warp IsoSurfaceMarchingCubes"]))
    if sparse:
        entries[SPARSE] = lambda: warp_sparse_mc(shape, lo, hi, n)
    res = run_interleaved(entries, args.repeat, args.warmup)
    n_warpmesh = sum(name.startswith("warpmesh") for name in res)
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
    rows[n_warpmesh:n_warpmesh] = missing  # after the warpmesh rows
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


# -- (d) large volumes: time and peak memory, one fresh process per measurement -----------------
def large_specs(kind, path, args):
    """(row label, worker spec) of every tool on one large volume (see _large_volume.py)."""
    base = {"kind": kind, "path": path, "repeat": args.repeat, "vtk_backend": args.vtk_backend,
            "keep_freed": not args.default_malloc}
    specs = []
    for sv in args.slab_voxels:
        default = " (default)" if sv == SLAB_VOXELS else ""
        specs.append((f"warpmesh mc, slab {sv / 1e6:.1f} M samples{default}",
                      {**base, "tool": "warpmesh", "method": "mc", "slab_voxels": sv}))
    for m in args.methods:  # the other methods at the first slab size
        sv = args.slab_voxels[0]
        specs.append((f"warpmesh {m}, slab {sv / 1e6:.1f} M samples{' (default)' if sv == SLAB_VOXELS else ''}",
                      {**base, "tool": "warpmesh", "method": m, "slab_voxels": sv}))
    if kind == "scalar":
        specs += [("scikit-image (Lewiner)", {**base, "tool": "skimage"}),
                  ("VTK flying edges", {**base, "tool": "vtk-fe"})]
    else:
        specs += [("scikit-image (Lewiner), per label", {**base, "tool": "skimage"}),
                  ("VTK flying edges, per label", {**base, "tool": "vtk-fe"}),
                  ("VTK discrete flying edges, all labels", {**base, "tool": "vtk-dfe"})]
    return specs


def case_large(args):
    n = args.large_size
    voxels = n ** 3
    tmp = tempfile.mkdtemp(prefix="bench_surface_")
    results = []
    try:
        for kind in ("scalar", "labels"):
            vol = LV.BUILDERS[kind](n)
            path = os.path.join(tmp, f"{kind}.npy")
            np.save(path, vol)
            input_mb, labels = vol.nbytes / 2 ** 20, (np.unique(vol)[1:].tolist() if kind == "labels" else None)
            del vol
            gc.collect()
            rows = []
            for label, spec in large_specs(kind, path, args):
                r = LV.measure(spec)
                r["tool"] = label
                rows.append(r)
            float_mb = voxels * 4 / 2 ** 20
            if kind == "scalar":
                title = (f"(d) large float32 volume, {n}^3 = {voxels / 1e6:.1f} M samples ({input_mb:.0f} MB): "
                         f"min(blobs - 0.5, 0.5 - |gyroid|), level 0")
            else:
                title = (f"(d) large uint8 label volume, {n}^3 = {voxels / 1e6:.1f} M samples ({input_mb:.0f} MB, "
                         f"a float32 copy {float_mb:.0f} MB), labels {labels}: ball, box cutting into it, torus, "
                         "ball nested in the first")
            notes = [f"each row is a fresh process: the tool is imported and warmed up on a 40^3 volume, the "
                     f"volume loaded from .npy, then peak extra = VmHWM after the first call - VmRSS before it "
                     f"(the peak counter reset with /proc/self/clear_refs; the output is alive, so it counts), "
                     f"with glibc's MALLOC_MMAP_THRESHOLD_=131072 so that freed blocks leave the resident set; "
                     f"time = median of {args.repeat} call(s) after one more untimed, "
                     + ("with freed memory kept in the heap from then on, as elsewhere in this benchmark."
                        if not args.default_malloc else "with that allocator setting (--default-malloc)."),
                     f"float32 copy of the volume: {float_mb:.0f} MB; peak/(copy+out) = peak extra / (that copy + "
                     "the tool's own output): below 1 is under the target of the issue."]
            notes.append("warpmesh: mesh_surface(volume, " + ("labels='all'" if kind == "labels" else "level=0")
                         + ", slab_voxels=...): the volume is meshed in slabs along axis 0, welded on exact edge "
                           "keys.")
            if kind == "labels":
                notes.append("peers per label: scikit-image on the boolean (vol == label) at level 0.5 (it makes its "
                             "own float32 copy); VTK flying edges (pyvista contour) on a float32 indicator at 0.5; "
                             "VTK discrete flying edges = vtk.vtkDiscreteFlyingEdges3D on the uint8 image, every "
                             "label in one pass (pyvista does not wrap it; its contour_labels is surface nets). "
                             "Every tool closes each label's surface on its own: interfaces appear once per label.")
            results.append({"case": f"large-{kind}-{n}", "kind": "large", "title": title, "rows": rows,
                            "notes": notes, "input_mb": input_mb, "float32_copy_mb": float_mb, "samples": voxels})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return results


# -- (e) covering: continuation vs grid vs dense --------------------------------------------------
COVERINGS = (("grid, culled (default)", {}), ("continuation", {"covering": "continuation"}),
             ("dense grid (cull=False)", {"cull": False}))


def covering_shapes(args):
    """(key, title, shape, lo, hi, cells) of the shape cases of (b) and (c)."""
    d6, (lo6, hi6) = wm.example("degree6")
    part, (lo, hi) = wm.example("part")
    n = args.size_part
    out = [(f"degree6-{c}", f"degree-six surface, {c}^3 cells", d6, lo6, hi6, c) for c in args.sizes_degree6]
    out.append((f"part-rfunction-{n}", f"CSG part, R-function booleans, {n}^3 cells", part, lo, hi, n))
    out.append((f"part-minmax-{n}", f"CSG part, min/max booleans, {n}^3 cells", part_minmax(), lo, hi, n))
    return out


def case_continuation(args):
    results = []
    for key, title, shape, lo, hi, n_cells in covering_shapes(args):
        entries = {label: lambda kw=kw: warpmesh_shape(shape, lo, hi, n_cells, **kw) for label, kw in COVERINGS}
        res = run_interleaved(entries, args.repeat, args.warmup)
        dense = res[COVERINGS[-1][0]][1]["info"]["evaluations"]
        rows = []
        for name, (med, out) in res.items():
            r = warpmesh_row(name, med, out)
            info = out["info"]
            r.update(interval_evaluations=info.get("interval_evaluations") or 0,
                     ray_evaluations=info.get("ray_evaluations"), waves=info.get("waves"),
                     components_grown=info.get("components_grown"), evaluations_vs_dense=r["evaluations"] / dense)
            rows.append(r)
        notes = ["evaluations = point evaluations of f (mesh.info['evaluations']; continuation: rays included, "
                 "each node once); interval ev. = interval-arithmetic evaluations of the culling (one per 8^3 "
                 "block, plus one per sub-block of each block kept); ray ev. = of the evaluations, those of "
                 "continuation's seed rays; ratio = total time / grid, culled. Same triangles in all three."]
        tris = {r["tool"]: r["triangles"] for r in rows}
        if len(set(tris.values())) > 1:
            notes[0] = notes[0].replace(" Same triangles in all three.", "")
            notes.append(f"triangle counts differ: {tris} (continuation meshes only the components it reaches)")
        results.append({"case": f"covering-{key}", "kind": "covering", "title": f"(e) covering: {title}, "
                        "warpmesh method='mc', compiled evaluator", "rows": rows, "notes": notes})
    return results


# =============================================================================================
# printing
# =============================================================================================
def fmt_s(v):
    return "-" if v is None else f"{v:.3f}"


def print_case(c):
    rows = [r for r in c["rows"] if "unavailable" not in r]
    ref = rows[0]["total_s"]
    for r in rows:
        r["ratio"] = r["total_s"] / ref
    print()
    print(c["title"])
    hdr = f"  {'tool':<44} {'eval s':>8} {'extract s':>9} {'total s':>8} {'triangles':>10} {'closed':>16} {'ratio':>7}"
    print(hdr)
    print("  " + "-" * (len(hdr) - 2))
    for r in c["rows"]:
        if "unavailable" in r:
            print(f"  {r['tool']:<44} {r['unavailable']}")
            continue
        closed = "yes" if r["closed"] else f"no ({r['open_edges']:,} open)"
        print(f"  {r['tool']:<44} {fmt_s(r['evaluate_s']):>8} {fmt_s(r['extract_s']):>9} {r['total_s']:>8.3f} "
              f"{r['triangles']:>10,} {closed:>16} {r['ratio']:>6.2f}x")
    for r in rows:
        if "stages_s" in r:
            st = ", ".join(f"{k} {v:.3f}" for k, v in r["stages_s"].items() if k != "total")
            grid = (f"active blocks {r['active_blocks']:,}/{r['blocks']:,}" if r["blocks"] is not None
                    else f"volume engine {r.get('engine')} ({r.get('slabs')} slab(s) of launches)")
            print(f"  {r['tool']} stages (median s): {st}; outside the stages {r['outside_stages_s']:.3f}; "
                  f"{grid}, evaluations {r['evaluations']:,}")
            if r["note"]:
                print(f"    {r['tool']}: {r['note']}")
        elif r["note"]:
            print(f"  {r['tool']}: {r['note']}")
    for note in c["notes"]:
        print(f"  note: {note}")


def print_large(c):
    rows = c["rows"]
    ok = [r for r in rows if "error" not in r]
    ref = ok[0]["time_s"] if ok else None
    print()
    print(c["title"])
    hdr = (f"  {'tool':<44} {'time s':>7} {'ratio':>7} {'triangles':>10} {'closed':>7} {'peak extra MB':>13} "
           f"{'output MB':>9} {'peak/(copy+out)':>15}")
    print(hdr)
    print("  " + "-" * (len(hdr) - 2))
    for r in rows:
        if "error" in r:
            print(f"  {r['tool']:<44} {r['error']}")
            continue
        r["total_s"], r["ratio"] = r["time_s"], r["time_s"] / ref
        r["peak_vs_copy_plus_output"] = r["peak_extra_mb"] / (c["float32_copy_mb"] + r["output_mb"])
        closed = "yes" if r["closed"] else f"no ({r['open_edges']:,})"
        print(f"  {r['tool']:<44} {r['time_s']:>7.3f} {r['ratio']:>6.2f}x {r['triangles']:>10,} {closed:>7} "
              f"{r['peak_extra_mb']:>13.0f} {r['output_mb']:>9.0f} {r['peak_vs_copy_plus_output']:>15.2f}")
    for r in ok:
        if "stages_s" in r:
            st = ", ".join(f"{k} {v:.3f}" for k, v in r["stages_s"].items())
            print(f"  {r['tool']}: {r['slabs']} slab(s); stages of the last call (s): {st}")
        if not r["peak_reset"]:
            print(f"  {r['tool']}: the peak counter could not be reset: peak extra = VmHWM growth (a lower bound)")
    for note in c["notes"]:
        print(f"  note: {note}")


def print_covering(c):
    rows = c["rows"]
    ref = rows[0]["total_s"]
    print()
    print(c["title"])
    hdr = (f"  {'covering':<26} {'evaluations':>12} {'vs dense':>8} {'interval ev.':>12} {'ray ev.':>10} "
           f"{'waves':>5} {'total s':>8} {'ratio':>7} {'triangles':>10} {'closed':>7}")
    print(hdr)
    print("  " + "-" * (len(hdr) - 2))
    for r in rows:
        r["ratio"] = r["total_s"] / ref
        ray = "-" if r["ray_evaluations"] is None else f"{r['ray_evaluations']:,}"
        waves = "-" if r["waves"] is None else str(r["waves"])
        closed = "yes" if r["closed"] else f"no ({r['open_edges']:,})"
        print(f"  {r['tool']:<26} {r['evaluations']:>12,} {100 * r['evaluations_vs_dense']:>7.1f}% "
              f"{r['interval_evaluations']:>12,} {ray:>10} {waves:>5} {r['total_s']:>8.3f} {r['ratio']:>6.2f}x "
              f"{r['triangles']:>10,} {closed:>7}")
    for r in rows:
        st = ", ".join(f"{k} {v:.3f}" for k, v in r["stages_s"].items() if k != "total")
        print(f"  {r['tool']} stages (median s): {st}")
    for note in c["notes"]:
        print(f"  note: {note}")


PRINTERS = {"large": print_large, "covering": print_covering}


def print_any(c):
    PRINTERS.get(c.get("kind"), print_case)(c)


def _verdict(ratio):
    return f"{ratio:.1f}x faster" if ratio >= 1 else f"{1 / ratio:.1f}x slower"


def summary_line(c):
    rows = [r for r in c["rows"] if "unavailable" not in r and "error" not in r]
    if not rows:
        return f"{c['case']}: no results"
    if c.get("kind") == "covering":
        return f"{c['case']}: " + "; ".join(
            f"{r['tool']} {r['evaluations'] / 1e6:.2f} M evaluations ({100 * r['evaluations_vs_dense']:.1f}%), "
            f"{r['total_s']:.3f} s" for r in rows)
    wmt = rows[0]["total_s"]
    if c.get("kind") == "large":
        parts = [f"{r['tool']} {r['time_s']:.3f} s, peak +{r['peak_extra_mb']:.0f} MB" for r in rows]
        return f"{c['case']} (float32 copy {c['float32_copy_mb']:.0f} MB): " + "; ".join(parts)
    parts = []
    for r in rows[1:]:
        if r["tool"].startswith("warpmesh"):
            continue
        parts.append(f"vs {r['tool']} {r['total_s']:.3f} s: {_verdict(r['total_s'] / wmt)}")
    return f"{c['case']}: warpmesh {wmt:.3f} s " + "; ".join(parts)


def print_methods(results):
    """One line per case of (a)-(c): each extraction method's time and triangles, and the peers'."""
    cols = [("warpmesh mc", ("warpmesh mc",)), ("warpmesh mt", ("warpmesh mt",)),
            ("warpmesh mc33", ("warpmesh mc33",)),
            ("scikit-image", ("scikit-image (Lewiner)", "numpy + scikit-image (Lewiner)")),
            ("VTK flying edges", ("VTK flying edges", "numpy + VTK flying edges"))]
    cases = [c for c in results if "kind" not in c]
    if not cases:
        return
    print()
    print("Methods (total s / triangles; peers from the same grid, numpy evaluation included for shapes; "
          "warpmesh caps the degree-six surface on the box, the peers leave it open):")
    print(f"  {'case':<16}" + "".join(f" {name:>22}" for name, _ in cols))
    for c in cases:
        by_tool = {r["tool"]: r for r in c["rows"]}
        cells = []
        for _, names in cols:
            r = next((by_tool[nm] for nm in names if nm in by_tool), None)
            if r is None:
                cells.append("-")
            elif "unavailable" in r:
                cells.append("n/a")
            else:
                cells.append(f"{r['total_s']:.3f} / {r['triangles']:,}")
        print(f"  {c['case']:<16}" + "".join(f" {cell:>22}" for cell in cells))
    if any("unavailable" in r for c in cases for r in c["rows"]):
        print("  n/a: see the method's line in the case's table")


def environment():
    smp = vtk.vtkSMPTools()
    return {
        "python": platform.python_version(), "machine": platform.processor() or platform.machine(),
        "cores": os.cpu_count(), "numpy": np.__version__, "scikit-image": skimage.__version__,
        "pyvista": pv.__version__, "vtk": vtk.vtkVersion.GetVTKVersion(),
        "vtk_smp_backend": f"{smp.GetBackend()} ({smp.GetEstimatedNumberOfThreads()} threads)",
        "pymcubes": getattr(mcubes, "__version__", "?"), "warp": wp.config.version,
        "warpmesh default method": {f.name: f.default for f in dataclasses.fields(wm.GridOptions)}["method"],
        "malloc": "freed memory kept in the heap (MALLOC_MMAP_THRESHOLD_/MALLOC_TRIM_THRESHOLD_ 16 GiB)"
                  if all(os.environ.get(k) == v for k, v in _MALLOC_ENV.items()) else "glibc default",
    }


# =============================================================================================
def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cases", default=",".join(CASE_NAMES),
                   help=f"comma-separated subset of {','.join(CASE_NAMES)} (or a-e); default all")
    p.add_argument("--methods", default=",".join(EXTRA_METHODS),
                   help="warpmesh methods timed besides mc in (a)-(d), comma separated (default mt,mc33; '' for none)")
    p.add_argument("--large-size", type=int, default=None,
                   help="samples per axis of the large volumes of (d) (default 320: 32.8 M; 128 with --quick)")
    p.add_argument("--slab-voxels", default=None,
                   help="warpmesh slab sizes tried in (d), comma separated (default 16777216,4194304; "
                        "16777216,262144 with --quick)")
    p.add_argument("--repeat", type=int, default=None, help="timed warm runs per tool (median); default 3, 1 with --quick")
    p.add_argument("--warmup", type=int, default=1, help="untimed runs per tool before timing (default 1)")
    p.add_argument("--quick", action="store_true",
                   help="small grids (64^3; degree-six 32^3 and 64^3; large volumes 128^3): a smoke run")
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
    args.methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in args.methods if m not in EXTRA_METHODS]
    if bad:
        p.error(f"unknown method(s) {bad} in --methods; pick from {list(EXTRA_METHODS)} (mc always runs)")
    if args.large_size is None:
        args.large_size = 128 if args.quick else 320
    if args.large_size < 41:
        p.error(f"--large-size must be at least 41, got {args.large_size}")
    slabs = args.slab_voxels or (f"{SLAB_VOXELS},{1 << 18}" if args.quick else f"{SLAB_VOXELS},{1 << 22}")
    try:
        args.slab_voxels = [int(v) for v in slabs.split(",") if v.strip()]
    except ValueError:
        p.error(f"expected integers in --slab-voxels, got {slabs!r}")
    if not args.slab_voxels or min(args.slab_voxels) < 1:
        p.error(f"expected positive integers in --slab-voxels, got {slabs!r}")
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
                "part": lambda: case_part(args), "large": lambda: case_large(args),
                "continuation": lambda: case_continuation(args)}
    for name in args.case_list:
        for c in builders[name]():
            print_any(c)
            sys.stdout.flush()
            results.append(c)
    print()
    print("Summary (total seconds, medians):")
    for c in results:
        line = summary_line(c)
        c["summary"] = line
        print("  " + line)
    print_methods(results)
    elapsed = time.perf_counter() - t_start
    load1 = os.getloadavg()[0]
    print(f"\nbenchmark wall time {elapsed:.0f} s; load average (1 min) at the end: {load1:.2f}")
    if args.json:
        doc = {"environment": env, "load_average_start_end": [load0, load1], "repeat": args.repeat,
               "warmup": args.warmup, "quick": args.quick, "methods": args.methods,
               "large_size": args.large_size, "slab_voxels": args.slab_voxels,
               "wall_s": elapsed, "cases": results}
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(doc, fh, indent=1)
        os.replace(tmp, args.json)
        print(f"results written to {args.json}")


if __name__ == "__main__":
    main()
