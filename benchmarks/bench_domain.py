#!/usr/bin/env python3
"""Tetrahedral meshes of implicit domains: warpmesh's isosurface stuffing side by side with
gmsh and TetGen on the CPU, in one run.

Cases: the unit sphere, the torus (R = 1, r = 0.35) and the CSG part (a plate with four
holes and a boss: sharp edges), each at about ``--tets`` tetrahedra (default 100 k; add
``--large`` for about 1 M too).

- warpmesh: ``wm.mesh_domain(shape, bounds, size=h)`` from the shape (lattice, cut points
  by a bracketed root search (Illinois) of the exact f, warp, stencils; boundary faces and statistics included).
- gmsh: the same solids built with OpenCASCADE (``addSphere``, ``addTorus``, box minus
  cylinders fused with a sphere), ``Mesh.MeshSizeMin/Max`` set so the count is close, 3D
  Delaunay (``Mesh.Algorithm3D = 1``) with gmsh's default optimisation; timed from the
  model to the tetrahedra (geometry, surface and volume meshing).
- TetGen (``tetgen`` package) on warpmesh's own boundary surface (the same triangles),
  quality switches ``minratio=1.5``, ``mindihedral=10`` and a maximum volume giving a
  similar count.
- warpmesh with ``features=False`` (one run): stuffing without the crease recovery (on the
  part, the distance from the exact edges to the nearest boundary edge, in units of size).
- warpmesh with ``method="delaunay"`` (one run, its own size for a similar count): lattice
  and surface points, scipy's Delaunay kernel, boundary recovery, sliver peeling, smoothing
  and flips (:mod:`warpmesh.solid.delaunay`); ``time / warpmesh`` is against stuffing.
- warpmesh with ``smooth=2, flips=True`` (one run): the smoothing and the 2-3/3-2 flips that
  never lower the smallest dihedral angle.
- warpmesh with ``size="curvature"`` (one run, its own count): the lattice graded by
  longest-edge bisection to angle / curvature on the surface, coarser inside
  (:mod:`warpmesh.solid.graded`); the dihedral bound is not proven there, the row measures it.

Sizes are calibrated once per case by a small run of each tool (count proportional to
size^-3). Times are the best of ``--repeat`` warm runs. Columns: tetrahedra, seconds,
tetrahedra per second, smallest and largest dihedral angle (degrees), largest
radius-edge ratio, and the ratio of the tool's time to warpmesh's (> 1: warpmesh faster).

Run:  python benchmarks/bench_domain.py [--tets 100000] [--large] [--repeat 3] [--cases sphere,torus,part]
                                        [--json results.json]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

_report.keep_freed_memory()

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

import gmsh  # noqa: E402
import tetgen  # noqa: E402

import warpmesh as wm  # noqa: E402
from warpmesh.solid.dihedral import dihedral_angles, radius_edge_ratio, signed_volumes  # noqa: E402
from warpmesh.solid.features import example_edges, feature_distance  # noqa: E402

CASES = ("sphere", "torus", "part")
VOLUME = {"sphere": 4.0 / 3.0 * math.pi, "torus": 2 * math.pi**2 * 0.35**2, "part": 2.2}


def quality(points, tets) -> dict:
    ang = np.degrees(dihedral_angles(points, tets))
    return {"tets": len(tets), "dmin": float(ang.min()), "dmax": float(ang.max()),
            "re": float(radius_edge_ratio(points, tets).max()), "neg": int((signed_volumes(points, tets) <= 0).sum())}


# -- the tools --------------------------------------------------------------------------------------
def run_warpmesh(name, size, smooth=0, features=True, flips=False, method="stuffing"):
    shape, bounds = wm.example(name)
    t0 = time.perf_counter()
    vol = wm.mesh_domain(shape, bounds=bounds, size=size, smooth=smooth, features=features, flips=flips,
                         method=method)
    dt = time.perf_counter() - t0
    return dt, vol.points, vol.cells["tetra"], vol


def _gmsh_model(name):
    occ = gmsh.model.occ
    if name == "sphere":
        occ.addSphere(0, 0, 0, 1.0)
    elif name == "torus":
        occ.addTorus(0, 0, 0, 1.0, 0.35)
    else:
        plate = occ.addBox(-1, -1, -0.3, 2, 2, 0.6)
        holes = [occ.addCylinder(sx * 0.6, sy * 0.6, -1, 0, 0, 2, 0.2) for sx in (-1, 1) for sy in (-1, 1)]
        cut, _ = occ.cut([(3, plate)], [(3, h) for h in holes])
        ball = occ.addSphere(0, 0, 0, 0.5)
        occ.fuse(cut, [(3, ball)])
    occ.synchronize()


def run_gmsh(name, size):
    gmsh.initialize(["-nt", "1"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        t0 = time.perf_counter()
        gmsh.model.add(name)
        _gmsh_model(name)
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.model.mesh.generate(3)
        dt = time.perf_counter() - t0
        tags, coords, _ = gmsh.model.mesh.getNodes()
        pts = np.zeros((int(tags.max()) + 1, 3))
        pts[tags.astype(np.int64)] = coords.reshape(-1, 3)
        types, _, nodes = gmsh.model.mesh.getElements(3)
        tets = np.concatenate([n.reshape(-1, 4) for t, n in zip(types, nodes) if t == 4]).astype(np.int64)
    finally:
        gmsh.finalize()
    return dt, pts, tets


def run_tetgen(surface_points, surface_tris, max_volume):
    t0 = time.perf_counter()
    tg = tetgen.TetGen(surface_points, surface_tris.astype(np.int32))
    nodes, elems, *_ = tg.tetrahedralize(order=1, quality=True, minratio=1.5, mindihedral=10.0,
                                         maxvolume=max_volume, steinerleft=10_000_000)
    dt = time.perf_counter() - t0
    return dt, np.asarray(nodes), np.asarray(elems, dtype=np.int64)


# -- calibration --------------------------------------------------------------------------------------
def calibrate(fn, guess, target):
    """A size giving about ``target`` tetrahedra (count ~ size^-3), from one run at ``guess``."""
    n = fn(guess)
    return guess * (n / target) ** (1.0 / 3.0)


def best_of(fn, repeat):
    best = None
    for _ in range(repeat):
        out = fn()
        if best is None or out[0] < best[0]:
            best = out
    return best


def run_case(name, target, repeat, rows):
    vol0 = VOLUME[name]
    h_wm = calibrate(lambda h: len(run_warpmesh(name, h)[2]), (12 * vol0 / (target / 8)) ** (1 / 3), target)
    h_gm = calibrate(lambda h: len(run_gmsh(name, h)[2]), (6 * math.sqrt(2) * vol0 / (target / 8)) ** (1 / 3),
                     target)
    run_warpmesh(name, h_wm)  # warm
    t_wm, p_wm, k_wm, vol = best_of(lambda: run_warpmesh(name, h_wm), repeat)
    q_wm = quality(p_wm, k_wm)
    surface = vol.points, vol.cells["triangle"]
    t_gm, p_gm, k_gm = best_of(lambda: run_gmsh(name, h_gm), repeat)
    q_gm = quality(p_gm, k_gm)
    # TetGen: a maximum volume for about the same count (calibrated once)
    a0 = vol0 / target
    n0 = len(run_tetgen(*surface, a0)[2])
    a = a0 * n0 / target
    t_tg, p_tg, k_tg = best_of(lambda: run_tetgen(*surface, a), repeat)
    q_tg = quality(p_tg, k_tg)
    s = vol.stats()
    t_sm, p_sm, k_sm, _ = run_warpmesh(name, h_wm, smooth=2, flips=True)
    q_sm = quality(p_sm, k_sm)
    t_nf, p_nf, k_nf, vol_nf = run_warpmesh(name, h_wm, features=False)
    q_nf = quality(p_nf, k_nf)
    t_gr, p_gr, k_gr, vol_gr = run_warpmesh(name, "curvature")
    q_gr = quality(p_gr, k_gr)
    i_gr = vol_gr.info
    # the Delaunay variant: its own size for about the same count (calibrated at 1/8 of it), one run
    h_dl = calibrate(lambda h: len(run_warpmesh(name, h, method="delaunay")[2]), 2 * h_wm, target / 8) / 2
    t_dl, p_dl, k_dl, vol_dl = run_warpmesh(name, h_dl, method="delaunay")
    q_dl = quality(p_dl, k_dl)
    s_dl = vol_dl.stats()
    edges, edges_nf = "", ""
    if name == "part":  # distance from the exact sharp edges to the nearest boundary edge, / size
        samples = example_edges("part", 200)
        d = feature_distance(vol.points, vol.cells["triangle"], samples) / h_wm
        d0 = feature_distance(vol_nf.points, vol_nf.cells["triangle"], samples) / h_wm
        edges = f", edge distance max {d.max():.3f} h, {100 * (d <= 0.05).mean():.1f} % within 0.05 h"
        edges_nf = f", edge distance max {d0.max():.3f} h, {100 * (d0 <= 0.05).mean():.1f} % within 0.05 h"
    for tool, t, q, note in (("warpmesh stuffing", t_wm, q_wm, f"size {h_wm:.4f}, evaluate "
                              f"{s['time_evaluate']:.3f} s, roots {s['time_roots']:.3f} s, fill {s['time_fill']:.3f} s, "
                              f"features {s.get('time_features', 0.0):.3f} s{edges}"),
                             ("warpmesh stuffing, features=False", t_nf, q_nf, f"no crease recovery{edges_nf}"),
                             ("warpmesh delaunay", t_dl, q_dl,
                              f"size {h_dl:.4f}, one run: points {s_dl['time_points']:.2f} s, Qhull "
                              f"{s_dl['time_delaunay']:.2f} s in {s_dl['delaunay_rounds']} rounds, optimise "
                              f"{s_dl['time_optimise']:.2f} s; volume error {s_dl['volume'] / vol0 - 1:+.2%}"),
                             ("warpmesh stuffing + smooth=2 + flips", t_sm, q_sm,
                              "smoothing and 2-3/3-2 flips never lower the smallest angle"),
                             ("warpmesh stuffing, size='curvature' (graded)", t_gr, q_gr,
                              f"one run, sizes {i_gr['size_smallest']:.4f}-{i_gr['size_largest']:.4f}, background "
                              f"{i_gr['background_tets']:,} tets graded in {i_gr['time_grade']:.2f} s; volume error "
                              f"{vol_gr.stats()['volume'] / vol0 - 1:+.2%}"),
                             ("gmsh (OCC, Delaunay 3D)", t_gm, q_gm, f"mesh size {h_gm:.4f}"),
                             ("TetGen (on warpmesh's surface)", t_tg, q_tg, f"maxvolume {a:.2e}")):
        rows.append({"case": name, "tool": tool, "time": t, **q, "ratio": t / t_wm, "note": note})
        print(f"| {name} | {tool} | {q['tets']:,} | {t:.3f} | {q['tets'] / t / 1e3:,.0f} k | {q['dmin']:.2f} | "
              f"{q['dmax']:.2f} | {q['re']:.2f} | {t / t_wm:.1f}x | {note} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tets", type=int, default=100_000)
    ap.add_argument("--large", action="store_true", help="also about 1 M tetrahedra")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--json", default=None)
    ap.add_argument("--default-malloc", action="store_true")
    args = ap.parse_args()
    t_start = time.perf_counter()
    load0 = _report.load_banner(f"bench_domain: warpmesh {wm.__version__}, gmsh {_report.version('gmsh')}, "
                                f"tetgen {_report.version('tetgen')}, warp {wp.__version__}, {os.cpu_count()} cores")
    rows = []
    print("\n| case | tool | tets | seconds | tets/s | dihedral min | dihedral max | radius-edge max | "
          "time / warpmesh | notes |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    targets = [args.tets] + ([1_000_000] if args.large else [])
    for target in targets:
        for name in args.cases.split(","):
            if name not in CASES:
                raise SystemExit(f"unknown case {name!r}; pick from {CASES}")
            run_case(name, target, args.repeat if target <= 200_000 else 1, rows)
    _report.finish(t_start, load0, args.json, {"rows": rows})


if __name__ == "__main__":
    main()
