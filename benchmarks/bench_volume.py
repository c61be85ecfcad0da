#!/usr/bin/env python3
"""Dense extraction of sampled volumes (issue 22, target 1): warpmesh beside VTK flying
edges (2 threads) and scikit-image on the same arrays, in one run.

Inputs (``--sizes``, default 257 and 320 samples a side), each handed to every tool as
the same C-order numpy array:

``sphere``  float32, a ball's distance field (1 - r on [-1.2, 1.2]^3), level 0;
``gyroid``  float32, sin x cos y + sin y cos z + sin z cos x over two periods, level 0
            (a dense surface: millions of triangles);
``labels``  uint8, the gyroid's positive side as label 1 (0 elsewhere): warpmesh
            ``labels=[1]``, VTK flying edges and scikit-image at 0.5 on the uint8 array.
``labels25``  uint8, 25 labels: the Voronoi cells of 25 seeds inside a ball (0 outside):
            warpmesh ``labels="all"`` (each label's closed surface) beside VTK's discrete
            flying edges (``vtkDiscreteFlyingEdges3D``, every label in one filter); the
            "per-label passes" row is warpmesh with each label classified from the
            whole volume (before ``extract_fields`` shared one listing of the rows'
            labels), scikit-image is left out.

warpmesh runs ``method="mc33"`` (its default) and ``"mc"`` through ``mesh_surface`` with
its defaults (caps closed on the volume's faces, the full host stage: orientation check,
refs, the Mesh); VTK is ``pyvista``'s ``contour(method="flying_edges")`` with the SMP
backend STDThread on 2 threads (the array handed over without a copy by reversing the
axes); scikit-image is ``measure.marching_cubes`` (Lewiner). The peers leave their
surfaces open on the volume's faces; the triangle counts are printed beside the times.

Times are medians of ``--repeat`` round-robin rounds after one untimed warm-up per tool
(load from other processes falls on every tool alike); "cpu" is the process CPU time of
the same calls (both threads). The ratio column is tool time / warpmesh mc33 time (> 1:
warpmesh is faster); the summary prints warpmesh / VTK flying edges, the target being <= 1.

Run:  python benchmarks/bench_volume.py [--sizes 257,320] [--repeat 3] [--cases sphere,gyroid,labels]
                                        [--json out.json]
"""

from __future__ import annotations

import argparse
import gc
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import finish, keep_freed_memory, load_banner, version  # noqa: E402

if __name__ == "__main__":
    keep_freed_memory()

import numpy as np  # noqa: E402

import warpmesh as wm  # noqa: E402

CASES = ("sphere", "gyroid", "labels", "labels25")


def make_input(case: str, n: int) -> tuple[np.ndarray, float, float]:
    """(array, level, spacing) of a case at n samples a side, on [-1.2, 1.2]^3 or [0, 4 pi]^3."""
    if case == "sphere":
        x = np.linspace(-1.2, 1.2, n, dtype=np.float32)
        vol = 1.0 - np.sqrt(x[:, None, None] ** 2 + x[None, :, None] ** 2 + x[None, None, :] ** 2)
        return np.ascontiguousarray(vol, dtype=np.float32), 0.0, float(x[1] - x[0])
    if case == "labels25":
        rng = np.random.default_rng(25)
        seeds = rng.uniform(-0.7, 0.7, (25, 3)).astype(np.float32)
        x = np.linspace(-1.0, 1.0, n, dtype=np.float32)
        best = np.full((n, n, n), np.inf, np.float32)
        vol = np.zeros((n, n, n), np.uint8)
        for q, (a, b, c) in enumerate(seeds):  # nearest seed, plane by plane of distance
            d = (x[:, None, None] - a) ** 2 + (x[None, :, None] - b) ** 2 + (x[None, None, :] - c) ** 2
            closer = d < best
            best[closer] = d[closer]
            vol[closer] = q + 1
        vol[(x[:, None, None] ** 2 + x[None, :, None] ** 2 + x[None, None, :] ** 2) > 0.81] = 0
        return vol, 0.5, float(x[1] - x[0])
    x = np.linspace(0.0, 4.0 * np.pi, n, dtype=np.float32)
    sx, cx = np.sin(x), np.cos(x)
    g = sx[:, None, None] * cx[None, :, None] + sx[None, :, None] * cx[None, None, :] \
        + sx[None, None, :] * cx[:, None, None]
    if case == "gyroid":
        return np.ascontiguousarray(g, dtype=np.float32), 0.0, float(x[1] - x[0])
    return (g > 0).astype(np.uint8), 0.5, float(x[1] - x[0])


def warpmesh_tool(vol, level, h, method, labels=None):
    if labels is not None:
        m = wm.mesh_surface(vol, labels=labels, spacing=h, method=method)
    elif vol.dtype == np.uint8:
        m = wm.mesh_surface(vol, labels=[1], spacing=h, method=method)
    else:
        m = wm.mesh_surface(vol, level=level, spacing=h, method=method)
    return len(m.cells["triangle"]), m.info["time"]


def vtk_tool(vol, level, h):
    import pyvista as pv

    # pyvista images are x-fastest: a C-order (i, j, k) array is the same memory as an
    # x-fastest image of axes (k, j, i); no copy
    img = pv.ImageData(dimensions=vol.shape[::-1], spacing=(h, h, h))
    img.point_data["f"] = vol.reshape(-1)
    surf = img.contour([level], scalars="f", method="flying_edges", compute_scalars=False)
    return surf.n_cells, {}


def per_label_passes(vol, h, method):
    """warpmesh's extraction of every label, each classified from the whole volume (the
    label loop as it was before the rows' label listing was shared); no Mesh built."""
    import warp as wp

    from warpmesh.surface.volume import extract_volume

    n_tris, timings = 0, {}
    for label in np.unique(vol)[1:]:
        _p, faces, _f, _r = extract_volume(vol, (0.0, 0.0, 0.0), np.full(3, h), level=0.5, sign=1.0, method=method,
                                           cap=True, cull=True, device=wp.get_device("cpu"), slab_voxels=1 << 24,
                                           label=int(label), timings=timings, info={}, engine="rows")
        n_tris += len(faces)
    return n_tris, timings


def vtk_discrete_tool(vol, h):
    import pyvista as pv
    import vtk

    img = pv.ImageData(dimensions=vol.shape[::-1], spacing=(h, h, h))
    img.point_data["labels"] = vol.reshape(-1)
    alg = vtk.vtkDiscreteFlyingEdges3D()
    alg.SetInputData(img)
    alg.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "labels")
    for i, label in enumerate(np.unique(vol)[1:]):
        alg.SetValue(i, int(label))
    alg.ComputeNormalsOff()
    alg.ComputeGradientsOff()
    alg.ComputeScalarsOff()
    alg.Update()
    return alg.GetOutput().GetNumberOfCells(), {}


def skimage_tool(vol, level, h):
    from skimage.measure import marching_cubes

    _verts, faces, _normals, _values = marching_cubes(vol, level=level, spacing=(h, h, h), method="lewiner")
    return len(faces), {}


def time_round_robin(entries: dict, repeat: int) -> dict:
    """{name: (median wall, median cpu, triangles, last stage times)}; one warm-up each."""
    for fn in entries.values():
        fn()
        gc.collect()
    walls = {k: [] for k in entries}
    cpus = {k: [] for k in entries}
    out = {}
    for _ in range(repeat):
        for name, fn in entries.items():
            gc.collect()
            gc.disable()
            try:
                c0, t0 = time.process_time(), time.perf_counter()
                out[name] = fn()
                walls[name].append(time.perf_counter() - t0)
                cpus[name].append(time.process_time() - c0)
            finally:
                gc.enable()
    return {k: (statistics.median(walls[k]), statistics.median(cpus[k]), *out[k]) for k in entries}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="257,320", help="samples a side, comma separated (default 257,320)")
    p.add_argument("--cases", default=",".join(CASES), help=f"comma separated, from {list(CASES)}")
    p.add_argument("--repeat", type=int, default=3, help="timed rounds (median; default 3)")
    p.add_argument("--threads", type=int, default=2, help="VTK SMP threads (default 2, like warpmesh on 2 cores)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    bad = [c for c in cases if c not in CASES]
    if bad or args.repeat < 1 or not sizes or min(sizes) < 8:
        p.error(f"expected cases from {list(CASES)}, --repeat >= 1 and sizes >= 8; got {bad}, {args.repeat}, {sizes}")
    import vtk

    vtk.vtkSMPTools.SetBackend("STDThread")
    vtk.vtkSMPTools.Initialize(args.threads)
    t_start = time.perf_counter()
    load0 = load_banner(f"bench_volume: warpmesh {version('warpmesh')}, VTK {vtk.vtkVersion.GetVTKVersion()} "
                        f"({vtk.vtkSMPTools.GetBackend()}, {args.threads} threads), scikit-image "
                        f"{version('scikit-image')}, {os.cpu_count()} cores")
    rows = []
    for n in sizes:
        for case in cases:
            vol, level, h = make_input(case, n)
            if case == "labels25":
                entries = {
                    "warpmesh mc33": lambda: warpmesh_tool(vol, level, h, "mc33", labels="all"),
                    "warpmesh mc": lambda: warpmesh_tool(vol, level, h, "mc", labels="all"),
                    "per-label passes": lambda: per_label_passes(vol, h, "mc33"),
                    "VTK flying edges": lambda: vtk_discrete_tool(vol, h),  # discrete: every label at once
                }
            else:
                entries = {
                    "warpmesh mc33": lambda: warpmesh_tool(vol, level, h, "mc33"),
                    "warpmesh mc": lambda: warpmesh_tool(vol, level, h, "mc"),
                    "VTK flying edges": lambda: vtk_tool(vol, level, h),
                    "scikit-image": lambda: skimage_tool(vol, level, h),
                }
            res = time_round_robin(entries, args.repeat)
            ref = res["warpmesh mc33"][0]
            print(f"\n{case} {n}^3 ({vol.dtype}, {vol.nbytes / 1e6:.0f} MB), level {level}")
            print(f"  {'tool':<18} {'wall s':>8} {'cpu s':>8} {'triangles':>11} {'ratio':>7}  stages (warpmesh)")
            for name, (wall, cpu, tris, stages) in res.items():
                st = " ".join(f"{k} {v:.3f}" for k, v in stages.items() if k != "total" and v >= 0.0005)
                print(f"  {name:<18} {wall:8.3f} {cpu:8.3f} {tris:11,d} {wall / ref:7.2f}  {st}")
            fe = res["VTK flying edges"][0]
            for method in ("mc33", "mc"):
                w = res[f"warpmesh {method}"][0]
                rows.append({"case": case, "n": n, "method": method, "warpmesh_s": w, "vtk_fe_s": fe,
                             "skimage_s": res.get("scikit-image", (float("nan"),))[0], "warpmesh_over_vtk": w / fe,
                             "warpmesh_cpu_s": res[f"warpmesh {method}"][1], "vtk_cpu_s": res["VTK flying edges"][1]})
            vol = entries = None  # free the volume before the next size (the lambdas are done)
    print("\nsummary: warpmesh time / VTK flying edges time (target <= 1), same run")
    for r in rows:
        print(f"  {r['case']:<7} {r['n']}^3 {r['method']:<5} {r['warpmesh_s']:.3f} s / {r['vtk_fe_s']:.3f} s = "
              f"{r['warpmesh_over_vtk']:.2f}  (cpu {r['warpmesh_cpu_s']:.3f} / {r['vtk_cpu_s']:.3f}; "
              f"scikit-image {r['skimage_s']:.3f} s)")
    finish(t_start, load0, args.json, {"rows": rows})


if __name__ == "__main__":
    main()
