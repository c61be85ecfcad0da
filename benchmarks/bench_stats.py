#!/usr/bin/env python3
"""Mesh statistics against the meshing that made the mesh, and against trimesh.

For ``wm.example("part")`` meshed by ``wm.mesh_surface`` at each ``--resolutions`` entry
(default 420 and 1024: about 1 M and 6 M triangles), in one run:

- ``mesh``: the ``wm.mesh_surface`` call (kernel cache warm: one small mesh first);
- ``stats()``: ``Mesh.stats()`` on a fresh Mesh of the same arrays (nothing cached), and
  its parts timed alone: ``topology`` (``warpmesh.cells.topology.mesh_topology``: watertight,
  manifold, oriented, Euler characteristic, components from one pass over the
  half-edges), ``measures`` (``surface_figures``: area, volume and each face's Q_K
  [FG eq. 16.15] in one kernel pass, what stats() calls), ``quality`` (``quality_summary``,
  numpy: what stats() called before) and ``self-intersections`` (``Mesh.check``);
- ``one figure per function``: the same topology from the one-figure functions of
  ``warpmesh.cells.topology`` (``unique_edges``, ``is_vertex_manifold``,
  ``is_consistently_oriented``, ``euler_characteristic``, ``connected_components``, each
  its own sort/unique: what ``stats()`` called before) plus ``face_areas().sum()`` and
  ``signed_volume`` — the figures are checked equal;
- ``trimesh``: ``trimesh.Trimesh(process=False)`` then ``is_watertight``,
  ``is_winding_consistent``, ``euler_number``, ``body_count``, ``area``, ``volume`` (its own
  cached edge sort), on the same arrays.

Every time is the best of ``--repeat`` rounds (one call per tool per round); ratios
are taken in this run. CPU seconds (process time, both cores) are given for stats().

Run:  python benchmarks/bench_stats.py [--resolutions 420,1024] [--repeat 2] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

if __name__ == "__main__":
    _report.keep_freed_memory()

import numpy as np  # noqa: E402

import warpmesh as wm  # noqa: E402
from warpmesh.cells import topology as T  # noqa: E402
from warpmesh.cells.quality import quality_summary  # noqa: E402


def _best(fn, repeat: int):
    """(best wall seconds, CPU seconds of that round, last result)."""
    best, cpu, out = float("inf"), 0.0, None
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        if dt < best:
            best, cpu = dt, time.process_time() - c0
    return best, cpu, out


def one_figure_functions(points, tri) -> dict:
    counts = T.unique_edges(tri)[2]
    return {"watertight": bool(np.all(counts == 2)),
            "manifold": bool(np.all(counts <= 2)) and T.is_vertex_manifold(tri, len(points)),
            "oriented": T.is_consistently_oriented(tri), "euler": T.euler_characteristic(None, tri),
            "components": T.connected_components(tri)[0], "area": float(T.face_areas(points, tri).sum()),
            "volume": T.signed_volume(points, tri)}


def with_trimesh(points, tri) -> dict:
    import trimesh

    tm = trimesh.Trimesh(points, tri, process=False)
    return {"watertight": tm.is_watertight, "oriented": tm.is_winding_consistent, "euler": tm.euler_number,
            "components": tm.body_count, "area": tm.area, "volume": tm.volume}


def bench(resolution: int, repeat: int) -> dict:
    shape, bounds = wm.example("part")
    t_mesh, _, mesh = _best(lambda: wm.mesh_surface(shape, bounds=bounds, resolution=resolution), repeat)
    pts, tri = mesh.points, mesh.triangles
    fresh = lambda: wm.Mesh(pts, {"triangle": tri})  # noqa: E731  (no cached figures)
    meshes = [fresh() for _ in range(repeat)]
    t_stats, cpu_stats, s = _best(lambda: meshes.pop().stats(), repeat)
    t_topo, _, topo = _best(lambda: T.mesh_topology(tri, len(pts)), repeat)
    t_meas, _, (area, volume, _) = _best(lambda: T.surface_figures(pts, tri), repeat)
    t_q, _, _ = _best(lambda: quality_summary(pts, {"triangle": tri}), repeat)  # what stats() called before
    t_x, _, _ = _best(lambda: fresh().check(), repeat)
    t_old, _, old = _best(lambda: one_figure_functions(pts, tri), repeat)
    t_tm, _, tm = _best(lambda: with_trimesh(pts, tri), repeat)
    same = all(old[k] == s[k] for k in ("watertight", "manifold", "oriented", "euler", "components"))
    same &= bool(np.isclose(old["area"], s["area"], rtol=1e-12) and np.isclose(old["volume"], s["volume"], rtol=1e-12))
    agree_tm = (tm["watertight"], tm["oriented"], tm["euler"], tm["components"]) == (
        s["watertight"], s["oriented"], s["euler"], s["components"])
    return {"resolution": resolution, "triangles": len(tri), "vertices": len(pts), "mesh_s": t_mesh,
            "stats_s": t_stats, "stats_cpu_s": cpu_stats, "topology_s": t_topo, "measures_s": t_meas,
            "quality_s": t_q, "self_intersections_s": t_x, "one_figure_functions_s": t_old, "trimesh_s": t_tm,
            "figures_equal_one_figure_functions": bool(same), "figures_equal_trimesh": bool(agree_tm),
            "stats_over_mesh": t_stats / t_mesh,
            "topology_measures_over_mesh": (t_topo + t_meas) / t_mesh,
            "one_figure_functions_over_topology_measures": t_old / (t_topo + t_meas),
            "trimesh_over_topology_measures": t_tm / (t_topo + t_meas)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--resolutions", default="420,1024", help="part resolutions (default 420,1024: ~1 M, ~6 M triangles)")
    p.add_argument("--repeat", type=int, default=2, help="timed rounds per tool, best taken (default 2)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    t_start = time.perf_counter()
    load0 = _report.load_banner(f"bench_stats: warpmesh {_report.version('warpmesh')}, "
                                f"trimesh {_report.version('trimesh')}, numpy {np.__version__}")
    shape, bounds = wm.example("part")
    wm.mesh_surface(shape, bounds=bounds, resolution=32).stats()  # kernels loaded (compiled on a new machine)
    rows = [bench(int(r), args.repeat) for r in args.resolutions.split(",")]
    keys = [("triangles", "{:,}"), ("vertices", "{:,}"), ("mesh_s", "{:.3f}"), ("stats_s", "{:.3f}"),
            ("stats_cpu_s", "{:.3f}"), ("topology_s", "{:.3f}"), ("measures_s", "{:.3f}"), ("quality_s", "{:.3f}"),
            ("self_intersections_s", "{:.3f}"), ("one_figure_functions_s", "{:.3f}"), ("trimesh_s", "{:.3f}"),
            ("stats_over_mesh", "{:.3f}"), ("topology_measures_over_mesh", "{:.3f}"),
            ("one_figure_functions_over_topology_measures", "{:.1f}"), ("trimesh_over_topology_measures", "{:.1f}"),
            ("figures_equal_one_figure_functions", "{}"), ("figures_equal_trimesh", "{}")]
    print(f"\n{'part, resolution':<46}" + "".join(f"{r['resolution']:>14}" for r in rows))
    for k, spec in keys:
        print(f"{k:<46}" + "".join(f"{spec.format(r[k]):>14}" for r in rows))
    _report.finish(t_start, load0, args.json, {"rows": rows})


if __name__ == "__main__":
    main()
