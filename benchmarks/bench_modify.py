#!/usr/bin/env python3
"""Mesh modifications (seed Frey & George §17.1): warpmesh against trimesh and pyvista (VTK)
on the same input in the same run, with ratios and a correctness check of every result.

Cases (``--cases``, default all):

- ``transform``: a closed triangle surface (trimesh icosphere, ``--subdivisions``, default
  8: 655,362 points) mirrored in the plane x = 0. warpmesh ``mesh.transform(symmetry)``
  (points mapped, every triangle's vertex list permuted), trimesh ``apply_transform`` (it
  also flips the winding of a reflection), pyvista ``transform(matrix, inplace=False)``.
  Checked: the enclosed volume stays positive (outward normals).
- ``subdivide``: the same surface, every triangle into 4 (n = 2). warpmesh
  ``mesh.refine(2)``, trimesh ``subdivide()``, pyvista ``subdivide(1, "linear")``.
  Checked: 4F triangles, V + E points (shared midpoints), watertight, area conserved.
- ``hex-to-tet``: a structured grid of ``--hexes``³ hexahedra (default 40: 64,000) with
  randomly permuted point numbers (so that no tool can rely on a structured numbering),
  split into tetrahedra. warpmesh ``mesh.convert("tetra")`` (min-index diagonals: 5 or 6
  tetrahedra per hexahedron), pyvista ``triangulate()`` (VTK's vtkDataSetTriangleFilter).
  Checked with ``tests/cellcheck.check_cells``: positive volumes, every face in at most two
  tetrahedra, closed boundary, volume and boundary area of the grid kept (a face cut along
  different diagonals from its two sides shows as extra boundary area); worst and mean Q_K
  [FG eq. 16.15, 1 = regular].

Times: one untimed round, then ``--repeat`` rounds, round-robin, best kept. Each tool's
input object is built once, outside the timer; the timer covers the operation and the
tool's own result object (warpmesh validates every new ``Mesh``).

Run:  python benchmarks/bench_modify.py [--repeat 3] [--json out.json]
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

_report.keep_freed_memory()

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # the project root: tests.helpers
from tests.helpers.cellcheck import check_cells  # noqa: E402

CASES = ("transform", "subdivide", "hex-to-tet")
TOOLS = {"transform": ("warpmesh", "trimesh", "pyvista"), "subdivide": ("warpmesh", "trimesh", "pyvista"),
         "hex-to-tet": ("warpmesh", "pyvista")}


def sphere(subdivisions: int):
    import trimesh

    return trimesh.creation.icosphere(subdivisions=subdivisions)


def hex_grid(n: int, seed: int = 0):
    import warpmesh as wm

    g = np.linspace(0.0, 1.0, n + 1)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    idx = np.arange(len(pts)).reshape(n + 1, n + 1, n + 1)
    c = idx[:-1, :-1, :-1].ravel()
    s1, s2, s3 = (n + 1) ** 2, n + 1, 1
    hexes = np.stack([c, c + s1, c + s1 + s2, c + s2, c + s3, c + s1 + s3, c + s1 + s2 + s3, c + s2 + s3], axis=1)
    perm = np.random.default_rng(seed).permutation(len(pts))
    inv = np.argsort(perm)
    return wm.Mesh(pts[perm], {"hexahedron": inv[hexes]})


def mirror_matrix():
    m = np.eye(4)
    m[0, 0] = -1.0
    return m


# ----------------------------------------------------------------------------- tools
def prepare(case, tool, data):
    """The tool's own input object (built outside the timer)."""
    import pyvista as pv

    import warpmesh as wm

    if case in ("transform", "subdivide"):
        tm = data
        if tool == "warpmesh":
            return wm.Mesh.from_trimesh(tm)
        if tool == "trimesh":
            return tm.copy()
        return pv.PolyData.from_regular_faces(np.asarray(tm.vertices), np.asarray(tm.faces))
    if tool == "warpmesh":
        return data
    return data.to_pyvista()


def run(case, tool, obj):
    """(seconds, result as (points, {type: cells}))."""
    import warpmesh as wm

    t0 = time.perf_counter()
    if case == "transform":
        if tool == "warpmesh":
            out = obj.transform(wm.transforms.symmetry((1, 0, 0, 0)))
        elif tool == "trimesh":
            out = obj.copy()
            out.apply_transform(mirror_matrix())
        else:
            out = obj.transform(mirror_matrix(), inplace=False)
    elif case == "subdivide":
        if tool == "warpmesh":
            out = obj.refine(2)
        elif tool == "trimesh":
            out = obj.subdivide()
        else:
            out = obj.subdivide(1, "linear")
    else:
        out = obj.convert("tetra") if tool == "warpmesh" else obj.triangulate()
    dt = time.perf_counter() - t0
    return dt, as_arrays(tool, out)


def as_arrays(tool, out):
    import pyvista as pv

    if tool == "warpmesh":
        return np.asarray(out.points), {t: np.asarray(c) for t, c in out.cells.items()}
    if tool == "trimesh":
        return np.asarray(out.vertices), {"triangle": np.asarray(out.faces)}
    if isinstance(out, pv.PolyData):
        return np.asarray(out.points), {"triangle": out.regular_faces}
    return np.asarray(out.points), {"tetra": out.cells_dict[pv.CellType.TETRA]}


# ----------------------------------------------------------------------------- checks
def check(case, data, result):
    import warpmesh as wm

    pts, cells = result
    if case in ("transform", "subdivide"):
        m = wm.Mesh(pts, {"triangle": cells["triangle"]})
        s = m.stats()
        out = {"np": m.n_points, "ne": len(cells["triangle"]), "watertight": s["watertight"],
               "volume": s["volume"], "area": s["area"]}
        if case == "subdivide":
            v, f = len(data.vertices), len(data.faces)
            out["expected np, ne"] = (v + len(data.edges_unique), 4 * f)
        return out
    m = wm.Mesh(pts, {"tetra": cells["tetra"]})
    try:
        got = check_cells(m)
        q = wm.tetra_quality(m.points, cells["tetra"])
        return {"np": m.n_points, "ne": len(cells["tetra"]), "valid": True,
                "volume": got["measure"], "boundary area": got["boundary_measure"],
                "worst Q": float(q.max()), "mean Q": float(q.mean())}
    except AssertionError as exc:
        return {"np": m.n_points, "ne": len(cells["tetra"]), "valid": False, "why": str(exc)[:120]}


def environment():
    v = _report.version
    return {"python": platform.python_version(), "cores": os.cpu_count(), "numpy": np.__version__,
            "trimesh": v("trimesh"), "pyvista": v("pyvista"), "vtk": v("vtk"),
            "malloc": "heap kept" if all(os.environ.get(k) == x for k, x in _report.MALLOC_ENV.items())
            else "glibc default"}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default=",".join(CASES), help=f"comma-separated subset of {','.join(CASES)}")
    p.add_argument("--subdivisions", type=int, default=8, help="icosphere subdivisions (default 8)")
    p.add_argument("--hexes", type=int, default=40, help="hexahedra per side of the grid (default 40)")
    p.add_argument("--repeat", type=int, default=3, help="timed rounds per tool, best kept (default 3)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", help="also write the results to this JSON file")
    args = p.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    bad = [c for c in cases if c not in CASES]
    if bad:
        p.error(f"unknown case(s) {bad}; expected among {list(CASES)}")
    t_start = time.perf_counter()
    env = environment()
    load0 = _report.load_banner("bench_modify: " + ", ".join(f"{k} {v}" for k, v in env.items()))
    print(f"best of {args.repeat} round(s) per tool after 1 untimed round, round-robin")
    import warpmesh as wm  # noqa: F401  (imported once before any timing)

    results = []
    for case in cases:
        data = sphere(args.subdivisions) if case != "hex-to-tet" else hex_grid(args.hexes)
        if case == "hex-to-tet":
            print(f"\n{case}: {data.n_cells:,} hexahedra, {data.n_points:,} points (random numbering)")
        else:
            print(f"\n{case}: icosphere, {len(data.vertices):,} points, {len(data.faces):,} triangles")
        objs = {t: prepare(case, t, data) for t in TOOLS[case]}
        times = {t: [] for t in TOOLS[case]}
        outs = {}
        for r in range(args.repeat + 1):
            for t in TOOLS[case]:
                dt, outs[t] = run(case, t, objs[t])
                if r:
                    times[t].append(dt)
        ref = min(times["warpmesh"])
        rows = {}
        print(f"  {'tool':10s} {'best s':>8s} {'ratio':>7s}  result")
        for t in TOOLS[case]:
            best = min(times[t])
            facts = check(case, data, outs[t])
            rows[t] = {"time_s": best, "times": times[t], "ratio_vs_warpmesh": best / ref, **facts}
            shown = ", ".join(f"{k} {v:.10g}" if isinstance(v, float) else f"{k} {v}" for k, v in facts.items())
            print(f"  {t:10s} {best:8.3f} {best / ref:7.2f}  {shown}")
        sys.stdout.flush()
        results.append({"case": case, "tools": rows})
    _report.finish(t_start, load0, args.json, {"environment": env, "args": vars(args), "results": results})


if __name__ == "__main__":
    main()
