#!/usr/bin/env python3
"""Merging two meshes (seed Frey & George §17.2): warpmesh against trimesh and pyvista (VTK).

Two triangulated surface patches of ``--size`` x ``--size`` vertices each (default 1000:
1 M vertices and 2 M triangles each) on the wavy surface z = 0.05 sin(3x) cos(2y), their
grid columns jittered so coordinates are not round numbers; the interface rows of the
second mesh get a uniform jitter of ``--jitter`` (default 1e-10) per coordinate, so no
interface point is exactly its partner. Cases (``--cases``):

- ``seam``: patch A on y in [0, 1], patch B on y in [1, 2], sharing one row (``--size``
  points). The bounding boxes meet along the seam only (Remark 17.7 applies).
- ``comb``: one patch of ``--size`` x 2 ``--size`` rows dealt out in bands of ``--band``
  rows alternately to A and B (neighbouring bands share a row): both bounding boxes are
  the whole patch, so every point is hashed (Remark 17.7 does not help).

Every tool gets the same two meshes and the same absolute tolerance ``--tolerance``
(default 1e-8; the exact answer merges every interface pair, at distance <= sqrt(3) x
jitter, and nothing else, the grid spacing being ~1e-3):

- ``warpmesh match_points``: ``warpmesh.modify.merge.match_points(A.points, B.points, tol)``
  (the pairs only);
- ``warpmesh merge``: ``warpmesh.modify.merge.merge(A, B, tol)``: pairs, the book's numbering,
  cells, duplicates, the common edges/faces and the Euler check on the cells around the
  interface (the default ``check="interface"``), a new ``Mesh``;
- ``warpmesh merge check=full``: the same with the Euler check counting every edge and face
  of both meshes (the meshes' own characteristics);
- ``warpmesh merge check=False``: the same without the common edges/faces and the Euler
  check (the scope of the two other tools: points merged, cells renumbered);
- ``trimesh``: ``trimesh.Trimesh(vstack(points), vstack(faces), process=False)`` then
  ``merge_vertices()``. trimesh does not take a distance: it multiplies the coordinates by
  10^digits_vertex (default from ``trimesh.tol.merge`` = 1e-8: 8 digits), rounds them to
  integers and merges equal rows. Two points at 1e-10 of each other that straddle a
  rounding border (x 10^8 close to k + 1/2) are kept apart: those are its misses;
- ``pyvista``: ``A.merge(B, merge_points=False)`` (vtkAppendPolyData) then
  ``clean(tolerance=tol, absolute=True, lines_to_points=False, polys_to_lines=False,
  strips_to_polys=False)`` (vtkCleanPolyData with a point locator and an absolute
  tolerance). ``pv.merge(..., merge_points=True)`` merges exactly coincident points only.

Correctness, per tool: the old -> new vertex map (read from the faces, whose order every
tool keeps), compared with the exact partition: ``missed`` = interface pairs left apart,
``wrong`` = merges of points that are not partners. Times: one untimed round, then
``--repeat`` rounds (round-robin), best kept; ratios are tool time / ``warpmesh merge``.

Run:  python benchmarks/bench_merge.py [--size 1000] [--cases seam,comb] [--repeat 3]
                                       [--tolerance 1e-8] [--jitter 1e-10] [--band 50]
                                       [--tools warpmesh,trimesh,pyvista] [--json out.json]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

if __name__ == "__main__":  # memory as the other benchmarks (README.md): freed memory stays in the heap
    _report.keep_freed_memory()

import numpy as np  # noqa: E402

import warpmesh as wm  # noqa: E402
from warpmesh.modify.merge import match_points, merge  # noqa: E402

TOOLS = ("warpmesh match_points", "warpmesh merge", "warpmesh merge check=full", "warpmesh merge check=False",
         "trimesh", "pyvista")
REFERENCE = "warpmesh merge"


# ============================================================================================
# meshes
# ============================================================================================
def _grid_triangles(nx: int, ny: int) -> np.ndarray:
    """(2 (nx-1)(ny-1), 3) counter-clockwise triangles of an nx x ny vertex grid (row-major in y)."""
    i, j = (a.ravel() for a in np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="ij"))
    v = lambda a, b: b * nx + a  # noqa: E731
    return np.concatenate([np.stack([v(i, j), v(i + 1, j), v(i + 1, j + 1)], axis=1),
                           np.stack([v(i, j), v(i + 1, j + 1), v(i, j + 1)], axis=1)])


def _surface(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(len(y) * len(x), 3) points of the wavy surface, row-major in y."""
    xx, yy = np.meshgrid(x, y, indexing="xy")
    return np.stack([xx.ravel(), yy.ravel(), 0.05 * np.sin(3 * xx.ravel()) * np.cos(2 * yy.ravel())], axis=1)


def make_case(case: str, n: int, jitter: float, band: int, seed: int = 0):
    """(A points, A faces, B points, B faces, pairs (k, 2) exact interface partners)."""
    rng = np.random.default_rng(seed)
    x = (np.arange(n) + rng.uniform(-0.3, 0.3, n)) / (n - 1)
    if case == "seam":
        ya = (np.arange(n) + np.r_[0, rng.uniform(-0.3, 0.3, n - 2), 0]) / (n - 1)
        yb = 1.0 + ya
        pa, pb = _surface(x, ya), _surface(x, yb)
        pb[:n] = pa[-n:]  # the shared row, bit for bit before the jitter
        fa = fb = _grid_triangles(n, n)
        pairs = np.stack([np.arange(n * n - n, n * n), np.arange(n)], axis=1)
    elif case == "comb":
        rows = 2 * n
        y = (np.arange(rows) + rng.uniform(-0.3, 0.3, rows)) / (n - 1)
        starts = np.arange(0, rows - 1, band)  # band k: rows starts[k] .. starts[k] + band (shared)
        owner = np.arange(len(starts)) % 2
        parts = {0: [], 1: []}
        for k, s in enumerate(starts):  # a loop over bands
            parts[owner[k]].append(np.arange(s, min(s + band, rows - 1) + 1))
        meshes, first = [], {}
        for o in (0, 1):
            pts, faces, off, row_index = [], [], 0, {}
            for r in parts[o]:
                pts.append(_surface(x, y[r]))
                faces.append(_grid_triangles(n, len(r)) + off)
                row_index[int(r[0])], row_index[int(r[-1])] = off, off + (len(r) - 1) * n
                off += len(r) * n
            meshes.append((np.concatenate(pts), np.concatenate(faces)))
            first[o] = row_index
        (pa, fa), (pb, fb) = meshes
        shared = [int(s) for s in starts[1:]]  # rows shared by a band and its predecessor
        ia = np.concatenate([first[0][r] + np.arange(n) for r in shared])
        ib = np.concatenate([first[1][r] + np.arange(n) for r in shared])
        pb = pb.copy()
        pb[ib] = pa[ia]
        pairs = np.stack([ia, ib], axis=1)
    else:
        raise ValueError(f"unknown case {case!r}")
    pb = pb.copy()
    pb[pairs[:, 1]] += rng.uniform(-jitter, jitter, (len(pairs), 3))
    return pa, fa, pb, fb, pairs


# ============================================================================================
# tools: each returns the old -> new vertex map of A's and B's vertices (from the faces)
# ============================================================================================
def _map_from_faces(old_faces: np.ndarray, new_faces: np.ndarray, n_old: int) -> np.ndarray:
    m = np.full(n_old, -1, dtype=np.int64)
    m[old_faces.ravel()] = new_faces.ravel()
    return m


def run_tool(tool, A, B, tol):
    pa, fa, pb, fb = A.points, A.cells["triangle"], B.points, B.cells["triangle"]
    old = np.concatenate([fa, fb + len(pa)])
    if tool == "warpmesh match_points":
        t0 = time.perf_counter()
        pairs = match_points(pa, pb, tol)
        dt = time.perf_counter() - t0
        new = np.concatenate([np.arange(len(pa)), len(pa) + np.arange(len(pb))])
        new[len(pa) + pairs[:, 1]] = pairs[:, 0]
        return dt, new, {}
    if tool == "warpmesh merge check=False":
        t0 = time.perf_counter()
        m = merge(A, B, tol, check=False)
        dt = time.perf_counter() - t0
        return dt, _map_from_faces(old, m.cells["triangle"], len(pa) + len(pb)), {}
    if tool in ("warpmesh merge", "warpmesh merge check=full"):
        full = tool.endswith("full")
        t0 = time.perf_counter()
        m = merge(A, B, tol, check="full" if full else "interface")
        dt = time.perf_counter() - t0
        star = "" if full else "_star"
        extra = {k: m.info[k.replace("euler", "euler" + star, 1) if k in ("euler", "euler_a", "euler_b") else k]
                 for k in ("euler", "euler_a", "euler_b", "euler_interface", "euler_ok",
                           "n_common_edges", "n_hashed_a", "n_hashed_b", "n_candidates")}
        return dt, _map_from_faces(old, m.cells["triangle"], len(pa) + len(pb)), extra
    if tool == "trimesh":
        import trimesh

        t0 = time.perf_counter()
        tm = trimesh.Trimesh(vertices=np.concatenate([pa, pb]), faces=old, process=False)
        tm.merge_vertices()
        dt = time.perf_counter() - t0
        assert len(tm.faces) == len(old)
        return dt, _map_from_faces(old, np.asarray(tm.faces), len(pa) + len(pb)), {}
    if tool == "pyvista":
        import pyvista as pv

        a = pv.PolyData.from_regular_faces(pa, fa)
        b = pv.PolyData.from_regular_faces(pb, fb)
        t0 = time.perf_counter()
        c = a.merge(b, merge_points=False).clean(tolerance=tol, absolute=True, lines_to_points=False,
                                                 polys_to_lines=False, strips_to_polys=False)
        dt = time.perf_counter() - t0
        faces = c.regular_faces
        assert len(faces) == len(old)
        return dt, _map_from_faces(old, faces, len(pa) + len(pb)), {}
    raise ValueError(tool)


def score(new: np.ndarray, exact: np.ndarray) -> dict:
    """Compare two partitions of the vertices: ``missed`` = exact merges not made,
    ``wrong`` = merges made that are not exact ones."""
    k = len(np.unique(np.stack([exact, new], axis=1), axis=0))
    return {"n_points": int(len(np.unique(new))), "missed": k - len(np.unique(exact)),
            "wrong": k - len(np.unique(new))}


# ============================================================================================
def environment():
    ver = _report.version
    return {"python": platform.python_version(), "cores": os.cpu_count(), "numpy": np.__version__,
            "trimesh": ver("trimesh"), "pyvista": ver("pyvista"), "vtk": ver("vtk"),
            "malloc": "heap kept" if all(os.environ.get(k) == v for k, v in _report.MALLOC_ENV.items()) else "glibc default"}


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--size", type=int, default=1000, help="vertices per side of each patch (default 1000: 1 M each)")
    p.add_argument("--cases", default="seam,comb", help="comma-separated subset of seam,comb")
    p.add_argument("--tools", default="warpmesh,trimesh,pyvista", help="subset of warpmesh,trimesh,pyvista")
    p.add_argument("--repeat", type=int, default=3, help="timed rounds per tool, best kept (default 3)")
    p.add_argument("--tolerance", type=float, default=1e-8, help="absolute merge tolerance (default 1e-8)")
    p.add_argument("--jitter", type=float, default=1e-10, help="uniform jitter per coordinate of B's interface")
    p.add_argument("--band", type=int, default=50, help="rows per band in the comb case (default 50)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.repeat < 1 or args.size < 3:
        p.error("--repeat must be >= 1 and --size >= 3")
    args.case_list = [c.strip() for c in args.cases.split(",") if c.strip()]
    bad = [c for c in args.case_list if c not in ("seam", "comb")]
    if bad:
        p.error(f"unknown case(s) {bad}; pick from ['seam', 'comb']")
    tools = [t.strip() for t in args.tools.split(",") if t.strip()]
    if any(t not in ("warpmesh", "trimesh", "pyvista") for t in tools):
        p.error(f"unknown tool in {tools}; pick from ['warpmesh', 'trimesh', 'pyvista']")
    args.tool_list = [t for t in TOOLS if t.split()[0] in tools]
    if np.sqrt(3) * args.jitter >= args.tolerance:
        p.error("expected sqrt(3) * --jitter < --tolerance (else the exact answer is not 'merge every pair')")
    return args


def main(argv=None):
    args = parse_args(argv)
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    t_start = time.perf_counter()
    env = environment()
    print("bench_merge: " + ", ".join(f"{k} {v}" for k, v in env.items()))
    load0 = _report.load_banner(f"best of {args.repeat} round(s) per tool after 1 untimed round, round-robin; "
                                f"tolerance {args.tolerance:g}, interface jitter {args.jitter:g}")
    results = []
    for case in args.case_list:
        pa, fa, pb, fb, pairs = make_case(case, args.size, args.jitter, args.band)
        A = wm.Mesh(pa, {"triangle": fa})
        B = wm.Mesh(pb, {"triangle": fb})
        exact = np.arange(len(pa) + len(pb))
        exact[len(pa) + pairs[:, 1]] = pairs[:, 0]
        n_exact = len(pa) + len(pb) - len(pairs)
        print(f"\n{case}: A {len(pa):,} points / {len(fa):,} triangles, B {len(pb):,} / {len(fb):,}; "
              f"{len(pairs):,} interface pairs; exact merged point count {n_exact:,}")
        sys.stdout.flush()
        rows = {t: {"times": []} for t in args.tool_list}
        for rnd in range(args.repeat + 1):  # round 0 untimed
            for t in args.tool_list:
                dt, new, extra = run_tool(t, A, B, args.tolerance)
                if rnd == 0:
                    rows[t].update(score(new, exact), **extra)
                else:
                    rows[t]["times"].append(dt)
        ref = min(rows[REFERENCE]["times"]) if REFERENCE in rows else None
        print(f"  {'tool':27s} {'best s':>8s} {'ratio':>7s} {'points':>11s} {'missed':>7s} {'wrong':>6s}")
        for t, r in rows.items():
            r["time_s"] = min(r["times"])
            r["ratio_vs_warpmesh_merge"] = r["time_s"] / ref if ref else None
            ratio = f"{r['ratio_vs_warpmesh_merge']:.2f}" if ref else "-"
            print(f"  {t:27s} {r['time_s']:8.3f} {ratio:>7s} {r['n_points']:>11,} {r['missed']:>7,} {r['wrong']:>6,}")
        for name, what in (("warpmesh merge", "cells around the interface"), ("warpmesh merge check=full", "meshes")):
            if name in rows:
                w = rows[name]
                print(f"  {name}: points hashed A {w['n_hashed_a']:,}, B {w['n_hashed_b']:,} "
                      f"(Remark 17.7), candidates {w['n_candidates']:,}; Euler of the {what}: {w['euler']} = "
                      f"{w['euler_a']} + {w['euler_b']} - {w['euler_interface']} ({'ok' if w['euler_ok'] else 'FAILED'})")
        sys.stdout.flush()
        results.append({"case": case, "n_a": len(pa), "n_b": len(pb), "n_pairs": len(pairs),
                        "n_exact": n_exact, "tools": rows})
    _report.finish(t_start, load0, args.json, {"environment": env, "args": vars(args), "cases": results})


if __name__ == "__main__":
    main()
