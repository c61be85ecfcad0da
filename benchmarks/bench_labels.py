#!/usr/bin/env python3
"""Multi-material surfaces of a label volume: warpmesh ``interfaces="shared"`` versus VTK's
surface nets (``pyvista.ImageData.contour_labels``) on pyvista's frog (25 labels, 500 x
470 x 136 samples, offline), in one run.

Rows (every tool gets the same ``pyvista.ImageData``, all labels, background 0, padded so
every label closes):

- warpmesh ``mesh_surface(frog, labels="all", interfaces="shared")``: surface nets, one
  vertex per cube at the mean of its crossing edges' midpoints, not smoothed;
- warpmesh ``labels="all"`` (the separate per-label surfaces, marching cubes): every
  interface twice;
- VTK ``contour_labels("all")`` (surface nets, 16 smoothing iterations, its default) and
  ``contour_labels("all", smoothing=False)`` (the staircase: vertices at cube centres).

For each: triangles, coincident faces (triangles with the same vertex set: an interface
meshed twice by one vertex set; the separate surfaces weld nothing, so theirs count
coincident *positions* instead), crossing pairs (``find_self_intersections``, warpmesh
rows), total area, and the time as the median of ``--repeat`` warm runs; the ratio is
tool time / warpmesh shared time (> 1: warpmesh faster) and area / warpmesh area.

A synthetic case (:func:`voronoi_rows`): a Voronoi partition of ``--synthetic`` ^3 samples
(default 512, uint8) among 50 random seeds, labels 1..50, made in the benchmark; warpmesh
shared against both ``contour_labels`` rows, wall and process CPU seconds.

Memory (:func:`memory_rows`, ``--no-memory`` to skip): each tool on the frog and on the
synthetic volume in a fresh process (:func:`memory_worker`): warmed up on a small volume,
the input loaded, the peak-RSS counter reset (``/proc/self/clear_refs``), one call; peak
extra = ``VmHWM`` after it - ``VmRSS`` before (the output alive, so it counts), with glibc's
``MALLOC_MMAP_THRESHOLD_=131072`` so that freed blocks leave the resident set. The target
of issue 23 (peak within 2x the input) is shown as peak / input, and as peak / (input +
output). warpmesh's output is counted as its mesh holds it (``Mesh.nbytes``: compact,
float32 points, int32 triangles, int16 labels), VTK's as its arrays.

A second table (:func:`smoothed_rows`) puts the smoothed shared surface (``smoothing=16``)
beside VTK's smoothed and staircase surfaces: area ratios, crossings, wall and CPU time.

Run:  python benchmarks/bench_labels.py [--repeat 3] [--no-crossings] [--smoothing 16] [--json out.json]
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import finish, keep_freed_memory, load_banner, median_run, version  # noqa: E402

if __name__ == "__main__":
    keep_freed_memory()

import numpy as np  # noqa: E402


def _timed(fn, repeat: int):
    """(output, median wall s) over ``repeat`` warm runs; the CPU s of each tool go to _CPU."""
    out, wall, cpu = _cpu_timed(fn, repeat)
    _CPU[wall] = cpu
    return out, wall


_CPU: dict = {}  # median wall s -> process CPU s of that run, for the frog table


def _cpu_timed(fn, repeat: int):
    """(output, median wall s, CPU s of that run) over ``repeat`` warm runs."""
    wall, cpu, out = median_run(fn, repeat)
    return out, wall, cpu


def voronoi_labels(n: int, n_labels: int = 50, seed: int = 0) -> np.ndarray:
    """(n, n, n) uint8: each sample labelled 1..n_labels by its nearest of n_labels random
    seeds (a Voronoi partition: convex cells, junction curves and corners), slab by slab."""
    rng = np.random.default_rng(seed)
    seeds = rng.random((n_labels, 3)).astype(np.float32) * n
    vol = np.empty((n, n, n), dtype=np.uint8)
    g = np.arange(n, dtype=np.float32)
    yz = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    half_norm = 0.5 * (seeds ** 2).sum(axis=1)
    for i in range(n):  # nearest seed: argmin of |s|^2 / 2 - x . s
        score = half_norm - i * seeds[:, 0] - yz @ seeds[:, 1:].T
        vol[i] = (np.argmin(score, axis=1) + 1).reshape(n, n)
    return vol


def _image_of(vol: np.ndarray):
    """A pyvista image of a C-order array without a copy: its axes reversed (x fastest)."""
    import pyvista as pv

    img = pv.ImageData(dimensions=vol.shape[::-1])
    img.point_data["labels"] = vol.reshape(-1)
    return img


def voronoi_rows(n: int, repeat: int) -> list[dict]:
    """warpmesh shared against VTK's contour_labels (smoothed and not) on the synthetic volume."""
    import warpmesh as wm

    vol = voronoi_labels(n)
    img = _image_of(vol)  # VTK reads the same memory (axes reversed: the same surface, mirrored)
    print(f"\nsynthetic: Voronoi partition of {n}^3 samples (uint8, {vol.nbytes / 2**20:.0f} MB) among 50 seeds, "
          f"repeat {repeat}")
    wm_mesh, w_wm, c_wm = _cpu_timed(lambda: wm.mesh_surface(vol, labels="all", interfaces="shared", progress=False),
                                     repeat)
    rows = [("warpmesh shared (surface nets)", wm_mesh.points, wm_mesh.triangles, w_wm, c_wm)]
    for name, kw in (("VTK contour_labels('all')", {}), ("VTK contour_labels('all', smoothing=False)",
                                                         {"smoothing": False, "output_mesh_type": "triangles"})):
        out, w, c = _cpu_timed(lambda kw=kw: img.contour_labels("all", **kw), repeat)
        rows.append((name, np.asarray(out.points, dtype=np.float64), out.regular_faces, w, c))
    a_ref = _area(wm_mesh.points, wm_mesh.triangles)
    print(f"{'tool':44s} {'triangles':>10s} {'area':>10s} {'area/wm':>8s} {'wall s':>7s} {'cpu s':>7s} "
          f"{'wall/wm':>8s} {'cpu/wm':>7s}")
    doc = []
    for name, pts, tris, w, c in rows:
        area = _area(pts, tris)
        print(f"{name:44s} {len(tris):10d} {area:10.0f} {area / a_ref:8.3f} {w:7.2f} {c:7.2f} {w / w_wm:8.2f} "
              f"{c / c_wm:7.2f}")
        doc.append({"tool": name, "triangles": len(tris), "area": area, "wall_s": w, "cpu_s": c,
                    "wall_ratio": w / w_wm, "cpu_ratio": c / c_wm})
    print("stages of warpmesh (s): " + ", ".join(f"{k} {v:.3f}" for k, v in wm_mesh.info["time"].items()))
    return doc


_WORKER_TAG = "@@bench-labels-memory "
_TOOLS = ("warpmesh shared", "VTK contour_labels", "VTK contour_labels smoothing=False")


def _run_tool(tool: str, source):
    """One call; (output bytes, triangles). ``source``: an array (warpmesh) or a pyvista image."""
    import warpmesh as wm

    if tool == "warpmesh shared":
        m = wm.mesh_surface(source, labels="all", interfaces="shared", progress=False)
        return m, m.nbytes, m.n_cells  # the arrays as kept (compact: float32 points, int32 triangles)
    kw = {} if tool == "VTK contour_labels" else {"smoothing": False, "output_mesh_type": "triangles"}
    out = source.contour_labels("all", **kw)
    arrays = [out.points, out.GetPolys().GetConnectivityArray(), out.GetPolys().GetOffsetsArray(),
              *[out.cell_data[k] for k in out.cell_data.keys()]]
    return out, sum(np.asarray(a).nbytes for a in arrays), out.n_cells


def memory_worker(spec: dict) -> dict:
    """One tool on one input in this (fresh) process: the peak extra resident memory of one call."""
    import pyvista as pv

    from _large_volume import _peak_kb, _reset_peak, _status_kb

    tool = spec["tool"]
    small = voronoi_labels(40, 8)
    _run_tool(tool, small if tool.startswith("warpmesh") else _image_of(small))  # warm-up: imports, kernels
    if spec["case"] == "frog":
        source = pv.examples.load_frog_tissues()
        input_bytes = source.active_scalars.nbytes
    else:
        vol = np.load(spec["path"])
        source, input_bytes = (vol if tool.startswith("warpmesh") else _image_of(vol)), vol.nbytes
    gc.collect()
    reset = _reset_peak()
    base = _status_kb("VmRSS") if reset else _peak_kb()
    t0 = time.perf_counter()
    out, out_bytes, triangles = _run_tool(tool, source)
    wall = time.perf_counter() - t0
    peak = (_peak_kb() - base) * 1024
    return {"case": spec["case"], "tool": tool, "peak_extra_mb": peak / 2**20, "input_mb": input_bytes / 2**20,
            "output_mb": out_bytes / 2**20, "triangles": int(triangles), "first_call_s": wall, "peak_reset": reset}


def memory_rows(n: int) -> list[dict]:
    """Every tool on the frog and on the synthetic volume, each in a fresh process."""
    from _large_volume import DROP_ENV, WORKER_ENV

    env = {k: v for k, v in os.environ.items() if k not in DROP_ENV}
    env.update(WORKER_ENV)
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "voronoi.npy")
        cases = ["frog"]
        if n:
            np.save(path, voronoi_labels(n))
            cases.append(f"voronoi {n}^3")
        for case in cases:
            for tool in _TOOLS:
                spec = {"case": case, "tool": tool, "path": path}
                proc = subprocess.run([sys.executable, os.path.abspath(__file__), "--memory-worker", json.dumps(spec)],
                                      env=env, capture_output=True, text=True)
                lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(_WORKER_TAG)]
                results.append(json.loads(lines[-1][len(_WORKER_TAG):]) if lines else
                               {"case": case, "tool": tool, "error": (proc.stderr.strip().splitlines() or ["?"])[-1]})
    print("\npeak extra memory of one call, each in a fresh process (MB; the output alive, so it counts)")
    print(f"{'case':14s} {'tool':36s} {'input':>7s} {'output':>7s} {'peak':>7s} {'peak/in':>8s} {'peak/(in+out)':>14s}")
    for r in results:
        if "error" in r:
            print(f"{r['case']:14s} {r['tool']:36s} failed: {r['error'][:100]}")
            continue
        print(f"{r['case']:14s} {r['tool']:36s} {r['input_mb']:7.1f} {r['output_mb']:7.1f} {r['peak_extra_mb']:7.1f} "
              f"{r['peak_extra_mb'] / r['input_mb']:8.2f} {r['peak_extra_mb'] / (r['input_mb'] + r['output_mb']):14.2f}"
              + ("" if r["peak_reset"] else "  (peak counter not reset: VmHWM growth, a lower bound)"))
    return results


def _area(points: np.ndarray, tris: np.ndarray) -> float:
    p = points[tris]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())


def _coincident_faces(tris: np.ndarray) -> int:
    s = np.sort(tris, axis=1)
    return len(s) - len(np.unique(s, axis=0))


def _coincident_positions(points: np.ndarray, tris: np.ndarray) -> tuple[int, int]:
    """Vertices sharing a position with another, triangles sharing their 3 positions with another."""
    q = np.round(points * 1e6).astype(np.int64)
    _, inverse, counts = np.unique(q, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    return int((counts[inverse] > 1).sum()), _coincident_faces(inverse[tris])


def smoothed_rows(frog, passes: int, repeat: int, crossings: bool) -> list[dict]:
    """The smoothed shared surface (``smoothing=passes``: every vertex in its cube, junctions
    along their curves, failing moves undone) against VTK's ``contour_labels('all')`` with its
    default smoothing (16 passes) and without (the staircase), in the same run: time (wall and
    process CPU, median of ``repeat``), area ratios, crossing pairs of both smoothed surfaces."""
    import warpmesh as wm
    from warpmesh.cells.intersections import find_self_intersections

    def cpu_timed(fn):
        return median_run(fn, repeat)

    w_raw, c_raw, raw = cpu_timed(lambda: wm.mesh_surface(frog, labels="all", interfaces="shared"))
    w_sm, c_sm, sm = cpu_timed(lambda: wm.mesh_surface(frog, labels="all", interfaces="shared", smoothing=passes))
    w_vtk, c_vtk, vtk = cpu_timed(lambda: frog.contour_labels("all"))
    w_st, c_st, stair = cpu_timed(lambda: frog.contour_labels("all", smoothing=False, output_mesh_type="triangles"))
    vtk_pts, vtk_tris = np.asarray(vtk.points, dtype=np.float64), vtk.regular_faces
    rows = [("warpmesh shared, raw", raw.points, raw.triangles, w_raw, c_raw),
            (f"warpmesh shared, smoothing={passes}", sm.points, sm.triangles, w_sm, c_sm),
            ("VTK contour_labels('all') (16 passes)", vtk_pts, vtk_tris, w_vtk, c_vtk),
            ("VTK contour_labels('all', smoothing=False)", np.asarray(stair.points, dtype=np.float64),
             stair.regular_faces, w_st, c_st)]
    a_vtk = _area(vtk_pts, vtk_tris)
    info = sm.info["smoothing"]
    print(f"\nsmoothing: {passes} passes, {info['surface']} surface / {info['curve']} curve / {info['fixed']} fixed "
          f"vertices, {info['reverted']} moves undone, largest move {info['moved_max']:.2f} spacing, "
          f"{info['time']:.2f} s wall in the smoothing")
    print(f"{'tool':44s} {'triangles':>10s} {'crossings':>9s} {'area':>10s} {'area/VTK':>9s} {'wall s':>7s} "
          f"{'cpu s':>7s} {'wall/VTK':>8s}")
    out = []
    for name, pts, tris, w, c in rows:
        cross = "-"
        if crossings and "raw" not in name and "False" not in name:
            cross = len(find_self_intersections(pts, tris))
        area = _area(pts, tris)
        print(f"{name:44s} {len(tris):10d} {cross!s:>9s} {area:10.0f} {area / a_vtk:9.3f} {w:7.2f} {c:7.2f} "
              f"{w / w_vtk:8.2f}")
        out.append({"tool": name, "triangles": len(tris), "crossings": cross, "area": area, "area_vs_vtk": area / a_vtk,
                    "wall_s": w, "cpu_s": c, "wall_vs_vtk": w / w_vtk})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--synthetic", type=int, default=512, help="side of the Voronoi volume (0: no such case)")
    ap.add_argument("--no-memory", action="store_true", help="skip the per-process memory measurements")
    ap.add_argument("--memory-worker", help=argparse.SUPPRESS)
    ap.add_argument("--no-crossings", action="store_true", help="skip the self-intersection checks")
    ap.add_argument("--json")
    ap.add_argument("--default-malloc", action="store_true", help="measure with the stock allocator")
    ap.add_argument("--smoothing", type=int, default=16, help="passes of the smoothed row (0: no such row)")
    args = ap.parse_args(argv)
    if args.memory_worker:
        print(_WORKER_TAG + json.dumps(memory_worker(json.loads(args.memory_worker))), flush=True)
        return 0

    import pyvista as pv

    import warpmesh as wm
    from warpmesh.cells.intersections import find_self_intersections

    t_start = time.perf_counter()
    load0 = load_banner(f"bench_labels: warpmesh {version('warpmesh')}, pyvista {pv.__version__}, "
                        f"vtk {version('vtk')}, numpy {np.__version__}, {os.cpu_count()} cores")
    frog = pv.examples.load_frog_tissues()
    values = frog.active_scalars
    print(f"frog: {frog.dimensions} samples, spacing {frog.spacing}, {len(np.unique(values))} values "
          f"(0 = background), repeat {args.repeat}\n")

    rows = []
    shared, t_shared = _timed(lambda: wm.mesh_surface(frog, labels="all", interfaces="shared", progress=False),
                              args.repeat)
    rows.append(("warpmesh shared (surface nets)", shared.points, shared.triangles, t_shared, "faces"))
    sep, t_sep = _timed(lambda: wm.mesh_surface(frog, labels="all"), max(1, args.repeat // 2))
    rows.append(("warpmesh separate (mc33, per label)", sep.points, sep.triangles, t_sep, "positions"))
    for name, kw in (("VTK contour_labels('all')", {}), ("VTK contour_labels('all', smoothing=False)",
                                                         {"smoothing": False, "output_mesh_type": "triangles"})):
        out, t = _timed(lambda kw=kw: frog.contour_labels("all", **kw), args.repeat)
        tris = out.regular_faces
        rows.append((name, np.asarray(out.points, dtype=np.float64), tris, t, "faces"))

    a_ref = _area(shared.points, shared.triangles)
    doc = {"rows": []}
    print(f"{'tool':44s} {'triangles':>10s} {'coincident':>11s} {'crossings':>9s} {'area':>10s} "
          f"{'area/wm':>8s} {'time s':>7s} {'time/wm':>8s} {'cpu s':>7s} {'cpu/wm':>7s}")
    for name, pts, tris, t, kind in rows:
        if kind == "faces":
            coincident = _coincident_faces(tris)
        else:
            coincident = _coincident_positions(pts, tris)[1]
        crossings = "-"
        if name.startswith("warpmesh shared") and not args.no_crossings:
            crossings = len(find_self_intersections(pts, tris))
        area = _area(pts, tris)
        print(f"{name:44s} {len(tris):10d} {coincident:11d} {crossings!s:>9s} {area:10.0f} {area / a_ref:8.3f} "
              f"{t:7.2f} {t / t_shared:8.2f} {_CPU[t]:7.2f} {_CPU[t] / _CPU[t_shared]:7.2f}")
        doc["rows"].append({"tool": name, "triangles": len(tris), "coincident": coincident,
                            "crossings": crossings, "area": area, "time_s": t, "time_ratio": t / t_shared,
                            "cpu_s": _CPU[t], "cpu_ratio": _CPU[t] / _CPU[t_shared]})
    lower = shared.cell_refs["triangle"]
    upper = shared.cell_data["label_above"]["triangle"]
    print(f"\nwarpmesh shared: {shared.info['interface_pairs']} label pairs, {shared.info['junction_vertices']} "
          f"junction vertices (3+ labels), labels {int(lower.min())}..{int(upper.max())}; stages "
          + ", ".join(f"{k} {v:.2f} s" for k, v in shared.info["time"].items()))
    print(f"time ratio contour_labels('all') / warpmesh shared: {rows[2][3] / t_shared:.2f}, "
          f"contour_labels('all', smoothing=False) / warpmesh shared: {rows[3][3] / t_shared:.2f}")
    if args.synthetic:
        doc["synthetic"] = voronoi_rows(args.synthetic, args.repeat)
    if not args.no_memory:
        doc["memory"] = memory_rows(args.synthetic)
    if args.smoothing:
        doc["smoothed"] = smoothed_rows(frog, args.smoothing, max(1, args.repeat // 2), not args.no_crossings)
    finish(t_start, load0, args.json, doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
