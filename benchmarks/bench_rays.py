#!/usr/bin/env python3
"""Winding numbers by ray crossings (``warpmesh.cells.rays.ray_windings``, what
``orient_faces`` and ``find_tet_overlaps`` use) against trimesh's ``Trimesh.contains`` on
the same points, in one run.

Cases (``--cases``):

- ``sphere``: an icosphere of ``--peer-subdivisions`` (default 5: 20,480 faces) and
  ``--peer-points`` (default 1,000) random points in its box; one group. trimesh answers
  inside/outside, 200 points a call (without embree its ray test keeps every candidate:
  500 points about the 327,680-face sphere took 25 CPU s and 5.8 GB, 10,000 in one call
  were killed at 23 GB).
- ``shells``: an icosphere of ``--subdivisions`` (default 7: 327,680 faces) plus
  ``--shells`` (default 10,000) small inside-out icospheres (80 faces each)
  scattered in and around it, each shell's first face centroid queried against every other
  group (the nesting question of ``orient_faces``); warpmesh only (trimesh has no
  many-surface query), its candidates and ties reported.
- ``ties``: a box [-4, 4]^3 subdivided three times (768 faces, square faces split on
  their diagonals) and the 3,375 points of a half-unit grid inside it: every ray along
  x, y and z runs through an edge or a vertex, so every pair ties on all three axes and the
  solid-angle fallback decides. trimesh's agreement with the exact answer (inside: all) is
  reported next to its time.

Each figure is the median of ``--repeat`` runs after one warm-up (wall and CPU seconds);
ratios are trimesh / warpmesh in this run.

Run:  python benchmarks/bench_rays.py [--cases sphere,shells,ties] [--repeat 3] [--json out.json]
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
import trimesh  # noqa: E402

from warpmesh.cells.rays import ray_windings  # noqa: E402


def _inside(points, group, count, n) -> np.ndarray:
    """Per point: its winding number about group 0 (0 where no row)."""
    out = np.zeros(n, np.int64)
    sel = group == 0
    out[points[sel]] = count[sel]
    return out


def _contains(s, q, chunk: int = 200) -> np.ndarray:
    """trimesh's inside test of the points, ``chunk`` points a call (bounded memory)."""
    tm = trimesh.Trimesh(s.vertices, s.faces)
    return np.concatenate([tm.contains(q[i:i + chunk]) for i in range(0, len(q), chunk)])


def case_sphere(subdivisions: int, n_points: int, repeat: int) -> dict:
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    rng = np.random.default_rng(0)
    q = rng.uniform(-1.2, 1.2, (n_points, 3))
    corners = s.vertices[s.faces]
    label = np.zeros(len(corners), np.int64)
    wm_s, wm_cpu, (p, g, c, _) = _report.median_run(lambda: ray_windings(corners, label, q), repeat)
    tm_s, tm_cpu, inside = _report.median_run(lambda: _contains(s, q), repeat)
    ours = _inside(p, g, c, len(q)) == 1
    return {"case": "sphere", "faces": len(corners), "points": len(q), "warpmesh_s": wm_s, "warpmesh_cpu_s": wm_cpu,
            "trimesh_s": tm_s, "trimesh_cpu_s": tm_cpu, "trimesh_over_warpmesh": tm_s / wm_s,
            "agree": int(np.sum(ours == inside))}


def case_shells(subdivisions: int, n_shells: int, repeat: int) -> dict:
    big = trimesh.creation.icosphere(subdivisions=subdivisions)
    small = trimesh.creation.icosphere(subdivisions=1)
    rng = np.random.default_rng(1)
    centres = rng.uniform(-1.3, 1.3, (n_shells, 3))
    centres = centres[np.abs(np.linalg.norm(centres, axis=1) - 1.0) > 0.03]  # off the sphere
    parts = [big.vertices[big.faces]] + [(small.vertices * 0.01 + c)[small.faces[:, ::-1]] for c in centres]
    corners = np.concatenate(parts)
    label = np.repeat(np.arange(len(parts)), [len(x) for x in parts])
    first = np.r_[0, np.cumsum([len(x) for x in parts])[:-1]]
    q = corners[first].mean(axis=1)
    skip = np.arange(len(parts))
    wm_s, wm_cpu, (p, g, c, report) = _report.median_run(lambda: ray_windings(corners, label, q, skip=skip), repeat)
    inside = np.linalg.norm(q[1:], axis=1) < 1.0  # the big sphere, outward: winding 1
    got = _inside(p, g, c, len(q))[1:]
    return {"case": "shells", "faces": len(corners), "points": len(q), "warpmesh_s": wm_s, "warpmesh_cpu_s": wm_cpu,
            "candidates": report["candidates"], "ties": report["ties"], "solid_angles": report["solid_angles"],
            "agree": int(np.sum((got == 1) == inside)), "of": len(inside)}


def case_ties(repeat: int) -> dict:
    s = trimesh.creation.box(bounds=[[-4, -4, -4], [4, 4, 4]])
    for _ in range(3):
        s = s.subdivide()
    corners = s.vertices[s.faces]
    label = np.zeros(len(corners), np.int64)
    g = np.arange(-3.5, 4, 0.5)
    q = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    wm_s, wm_cpu, (p, gr, c, report) = _report.median_run(lambda: ray_windings(corners, label, q), repeat)
    tm_s, tm_cpu, inside = _report.median_run(lambda: _contains(s, q), repeat)
    ours = _inside(p, gr, c, len(q))
    return {"case": "ties", "faces": len(corners), "points": len(q), "warpmesh_s": wm_s, "warpmesh_cpu_s": wm_cpu,
            "trimesh_s": tm_s, "trimesh_cpu_s": tm_cpu, "trimesh_over_warpmesh": tm_s / wm_s,
            "ties": report["ties"], "solid_angles": report["solid_angles"],
            "warpmesh_right": int(np.sum(ours == 1)), "trimesh_right": int(np.sum(inside)), "of": len(q)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", default="sphere,shells,ties", help="comma-separated: sphere, shells, ties")
    p.add_argument("--subdivisions", type=int, default=7, help="the icosphere's subdivisions (default 7: 327,680 faces)")
    p.add_argument("--shells", type=int, default=10000, help="small shells of the shells case (default 10,000)")
    p.add_argument("--peer-subdivisions", type=int, default=5, help="the sphere case's icosphere (default 5: 20,480 faces)")
    p.add_argument("--peer-points", type=int, default=1000, help="the sphere case's points (default 1,000)")
    p.add_argument("--repeat", type=int, default=3, help="timed runs per tool, median taken (default 3)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = sorted(set(cases) - {"sphere", "shells", "ties"})
    if unknown:
        p.error(f"--cases: unknown case(s) {unknown}; choose from sphere, shells, ties")
    t_start = time.perf_counter()
    load0 = _report.load_banner(f"bench_rays: warpmesh {_report.version('warpmesh')}, "
                                f"trimesh {_report.version('trimesh')}, numpy {np.__version__}")
    rows = []
    for case in cases:
        if case == "sphere":
            rows.append(case_sphere(args.peer_subdivisions, args.peer_points, args.repeat))
        elif case == "shells":
            rows.append(case_shells(args.subdivisions, args.shells, args.repeat))
        else:
            rows.append(case_ties(args.repeat))
        print()
        for k, v in rows[-1].items():
            print(f"  {k:<24}{v:.3f}" if isinstance(v, float) else f"  {k:<24}{v}")
    _report.finish(t_start, load0, args.json, {"rows": rows})


if __name__ == "__main__":
    main()
