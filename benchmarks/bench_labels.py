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

Run:  python benchmarks/bench_labels.py [--repeat 3] [--no-crossings] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import finish, keep_freed_memory, load_banner, version  # noqa: E402

if __name__ == "__main__":
    keep_freed_memory()

import numpy as np  # noqa: E402


def _timed(fn, repeat: int):
    fn()  # warm: imports, caches
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-crossings", action="store_true", help="skip the self-intersection checks")
    ap.add_argument("--json")
    ap.add_argument("--default-malloc", action="store_true", help="measure with the stock allocator")
    args = ap.parse_args(argv)

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
    shared, t_shared = _timed(lambda: wm.mesh_surface(frog, labels="all", interfaces="shared"), args.repeat)
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
          f"{'area/wm':>8s} {'time s':>7s} {'time/wm':>8s}")
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
              f"{t:7.2f} {t / t_shared:8.2f}")
        doc["rows"].append({"tool": name, "triangles": len(tris), "coincident": coincident,
                            "crossings": crossings, "area": area, "time_s": t, "time_ratio": t / t_shared})
    lower = shared.cell_refs["triangle"]
    upper = shared.cell_data["label_above"]["triangle"]
    print(f"\nwarpmesh shared: {shared.info['interface_pairs']} label pairs, {shared.info['junction_vertices']} "
          f"junction vertices (3+ labels), labels {int(lower.min())}..{int(upper.max())}; stages "
          + ", ".join(f"{k} {v:.2f} s" for k, v in shared.info["time"].items()))
    print(f"time ratio contour_labels('all') / warpmesh shared: {rows[2][3] / t_shared:.2f}")
    finish(t_start, load0, args.json, doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
