#!/usr/bin/env python3
"""Edit latency of a real-time preview: warpmesh's Preview against numpy + scikit-image and numpy + VTK.

The CSG part of issue 21 (a plate with four through-holes of radius ``r`` and a boss of
radius ``boss``, R-function booleans) is edited 50 times: both parameters drawn at random
in their ranges (one seeded sequence, the same for every tool). For each resolution:

- warpmesh: ``wm.Preview(part, bounds, resolution)`` set up once (timed apart), then
  ``update(r=..., boss=...)``: the tape's constants change, the compiled evaluator is
  reused; Warp module loads and compiles during the edits are counted
  (:func:`warpmesh.preview.instrument.count_module_loads`; must be 0).
- numpy + scikit-image: the edited shape evaluated with numpy on the same nodes
  (float64, broadcast open axes, cast to float32) and ``skimage.measure.marching_cubes``
  (Lewiner) on the volume: what a preview without warpmesh would do per edit.
- numpy + VTK: the same numpy volume contoured by VTK's flying edges
  (``pyvista.ImageData.contour(method="flying_edges")``, multithreaded).
- adaptive (``--adaptive 8``): ``wm.Preview(part, adaptive=True, max_level=8)``, the
  octree re-meshed per edit (its finest cells are those of the grid at 2^8 = 256).

Printed per resolution: set-up time, p50 / p95 / max edit latency, triangles, and the
ratio of the peer's p50 to warpmesh's. Acceptance (issue 21): p95 < 100 ms at 128³ on two
cores; the banner prints the load average, since other processes skew every figure.

With ``--bursts GAP``: only the edits GAP seconds apart to a watched preview whose idle
refinement each edit overtakes, the refinements cancelled at the pipeline's next stage
(the default) against run to their end (``bench_bursts``).

Run:  python benchmarks/bench_preview.py [--resolutions 64,128,256] [--edits 50] [--adaptive 8]
                                          [--evaluator compiled] [--no-peer] [--json out.json]
      python benchmarks/bench_preview.py --bursts 0.12 --resolutions 128 --edits 40
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

if __name__ == "__main__":
    _report.keep_freed_memory()

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

BOUNDS = ((-1.2,) * 3, (1.2,) * 3)
RANGES = {"r": (0.05, 0.28), "boss": (0.3, 0.7)}


def make_part(wm, r, boss):
    holes = [wm.cylinder(r, axis="z").translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
    return (wm.box((2, 2, 0.6)) - wm.union(*holes)) | wm.sphere(boss)


def edits(n: int, seed: int = 21) -> list[dict]:
    rng = np.random.default_rng(seed)
    return [{k: float(rng.uniform(*RANGES[k])) for k in RANGES} for _ in range(n)]


def percentiles(times, cpu) -> dict:
    """Wall-time percentiles, and the median CPU time of the process per edit (all threads:
    less sensitive to other processes than wall time; on an idle machine, wall time is
    about CPU time / cores used)."""
    t = np.asarray(times) * 1000.0
    return {"p50_ms": float(np.percentile(t, 50)), "p95_ms": float(np.percentile(t, 95)), "max_ms": float(t.max()),
            "cpu_p50_ms": float(np.percentile(np.asarray(cpu) * 1000.0, 50))}


def bench_warpmesh(wm, part, res, values, evaluator, max_level=None) -> dict:
    from warpmesh.preview.instrument import count_module_loads

    t0 = time.perf_counter()
    if max_level:
        view = wm.Preview(part, bounds=BOUNDS, resolution=None, adaptive=True, max_level=max_level)
    else:
        view = wm.Preview(part, bounds=BOUNDS, resolution=res, evaluator=evaluator)
    setup = time.perf_counter() - t0
    times, cpu, tris = [], [], []
    with count_module_loads() as counts:
        for v in values:
            t, c = time.perf_counter(), time.process_time()
            mesh = view.update(**v)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            tris.append(mesh.n_cells)
    return {"setup_s": setup, **percentiles(times, cpu), "triangles_mean": float(np.mean(tris)),
            "warp_module_loads": counts.loads, "warp_compiles": counts.compiles}


def bench_bursts(wm, part, res, values, gap: float, idle: float, cancelling: bool) -> dict:
    """Edits ``gap`` seconds apart to a watched preview (as the notebook widget is): each edit's
    idle refinement (twice the resolution) starts ``idle`` s after it and is still running
    when the next edit comes. With ``cancelling`` the edit stops it at the pipeline's next
    stage (``warpmesh._util.cancel``); without, its checkpoints are made no-ops, so it runs to
    its end on a core the edit needs (the behaviour before the cancellation)."""
    from warpmesh._util import cancel

    original = cancel.checkpoint
    cancel.checkpoint = original if cancelling else (lambda: None)
    try:
        view = wm.Preview(part, bounds=BOUNDS, resolution=res, idle=idle)
        view.watch(lambda mesh, kind: None)
        times, cpu = [], []
        c0 = time.process_time()
        for v in values:
            t, c = time.perf_counter(), time.process_time()
            view.update(**v)
            times.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            time.sleep(gap)
        time.sleep(max(1.0, 10 * gap))  # the last refinement lands
        cpu_total = time.process_time() - c0  # every thread's: the edits and the refinements
    finally:
        cancel.checkpoint = original
    return {**percentiles(times, cpu), "cpu_total_s": cpu_total, "dropped": view.dropped,
            "cancelled": view.cancelled}


def bench_numpy_peer(part, res, values, contour) -> dict:
    """numpy evaluation of each edit on the grid's nodes, then ``contour(vol, spacing)``
    (which returns the triangle count)."""
    n = res + 1
    axes = [np.linspace(BOUNDS[0][i], BOUNDS[1][i], n) for i in range(3)]
    spacing = tuple(float(a[1] - a[0]) for a in axes)
    times, cpu, tris = [], [], []
    for v in values:
        t, c = time.perf_counter(), time.process_time()
        shape = part.with_params(v)
        f = shape.eval_numpy(axes[0][:, None, None], axes[1][None, :, None], axes[2][None, None, :])
        vol = np.ascontiguousarray(np.broadcast_to(f, (n, n, n)), dtype=np.float32)
        tris.append(contour(vol, spacing))
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return {**percentiles(times, cpu), "triangles_mean": float(np.mean(tris))}


def skimage_contour(vol, spacing) -> int:
    from skimage.measure import marching_cubes

    return len(marching_cubes(vol, level=0.0, spacing=spacing)[1])


def vtk_contour(vol, spacing) -> int:
    import pyvista as pv

    grid = pv.ImageData(dimensions=vol.shape, spacing=spacing, origin=BOUNDS[0])
    grid.point_data["f"] = vol.ravel(order="F")
    return grid.contour([0.0], scalars="f", method="flying_edges").n_cells


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolutions", default="64,128,256")
    p.add_argument("--edits", type=int, default=50)
    p.add_argument("--evaluator", choices=["compiled", "interpreter"], default="compiled")
    p.add_argument("--adaptive", type=int, default=8, help="max_level of the adaptive row (0: none)")
    p.add_argument("--no-peer", action="store_true", help="skip the numpy + scikit-image / VTK peers")
    p.add_argument("--json", help="write the results to this file")
    p.add_argument("--default-malloc", action="store_true", help="measure with glibc's stock allocator")
    p.add_argument("--bursts", type=float, default=0.0, metavar="GAP",
                   help="only the edits GAP s apart to a watched preview, its idle refinements cancelled or not")
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    load0 = _report.load_banner(f"bench_preview: {args.edits} edits of r and boss, CPU count {os.cpu_count()}")
    import warpmesh as wm

    part = make_part(wm, wm.param("r", 0.2, lo=RANGES["r"][0], hi=RANGES["r"][1]),
                     wm.param("boss", 0.5, lo=RANGES["boss"][0], hi=RANGES["boss"][1]))
    values = edits(args.edits)
    rows = []
    if args.bursts:
        print(f"\nedits {args.bursts:.2f} s apart, a watched preview (idle 0.05 s): each refinement overtaken")
        for res in (int(r) for r in args.resolutions.split(",")):
            for rep_ in range(2):  # interleaved, twice: the same load for both
                for cancelling in (False, True):
                    b = bench_bursts(wm, part, res, values, args.bursts, 0.05, cancelling)
                    rows.append({"resolution": res, "cancelling": cancelling, **b})
                    print(f"{res:>5} | refinements {'cancelled' if cancelling else 'run to their end':<17} | "
                          f"p50 {b['p50_ms']:6.1f}ms | p95 {b['p95_ms']:6.1f}ms | max {b['max_ms']:6.1f}ms | "
                          f"process CPU {b['cpu_total_s']:5.2f} s | dropped {b['dropped']}, cancelled {b['cancelled']}")
        _report.finish(t_start, load0, args.json, {"rows": rows, "edits": args.edits})
        return 0
    print(f"\n{'res':>5} | {'tool':<26} | {'set-up':>7} | {'p50':>8} | {'p95':>8} | {'max':>8} | "
          f"{'cpu p50':>8} | {'triangles':>9} | loads | p50 ratio")
    for res in (int(r) for r in args.resolutions.split(",")):
        w = bench_warpmesh(wm, part, res, values, args.evaluator)
        rows.append({"resolution": res, "tool": f"warpmesh Preview ({args.evaluator})", **w})
        print(f"{res:>5} | {rows[-1]['tool']:<26} | {w['setup_s']:6.2f}s | {w['p50_ms']:6.1f}ms | "
              f"{w['p95_ms']:6.1f}ms | {w['max_ms']:6.1f}ms | {w['cpu_p50_ms']:6.1f}ms | {w['triangles_mean']:9.0f} | "
              f"{w['warp_module_loads']:>5} |")
        if not args.no_peer:
            for tool, contour in (("numpy + scikit-image", skimage_contour), ("numpy + VTK flying edges", vtk_contour)):
                s = bench_numpy_peer(part, res, values, contour)
                rows.append({"resolution": res, "tool": tool, **s})
                print(f"{res:>5} | {tool:<26} | {'-':>7} | {s['p50_ms']:6.1f}ms | "
                      f"{s['p95_ms']:6.1f}ms | {s['max_ms']:6.1f}ms | {s['cpu_p50_ms']:6.1f}ms | "
                      f"{s['triangles_mean']:9.0f} |     - | {s['p50_ms'] / w['p50_ms']:.1f}x")
    if args.adaptive:
        w = bench_warpmesh(wm, part, None, values, args.evaluator, max_level=args.adaptive)
        rows.append({"resolution": f"L{args.adaptive}", "tool": "warpmesh Preview (adaptive)", **w})
        print(f"{'L' + str(args.adaptive):>5} | {rows[-1]['tool']:<26} | {w['setup_s']:6.2f}s | {w['p50_ms']:6.1f}ms | "
              f"{w['p95_ms']:6.1f}ms | {w['max_ms']:6.1f}ms | {w['cpu_p50_ms']:6.1f}ms | {w['triangles_mean']:9.0f} | "
              f"{w['warp_module_loads']:>5} |")
    _report.finish(t_start, load0, args.json, {"rows": rows, "edits": args.edits, "evaluator": args.evaluator,
                                               "versions": {k: _report.version(k) for k in
                                                            ("warp-lang", "scikit-image", "numpy", "vtk")}})
    return 0


if __name__ == "__main__":
    sys.exit(main())
