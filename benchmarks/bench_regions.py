#!/usr/bin/env python3
"""Multi-region tetrahedra of a label volume: warpmesh ``mesh_domain(volume, labels="all",
size=h)`` (lattice cleaving) against TetGen filling warpmesh's shared multi-material surface
with region attributes, in one run.

Cases: nested balls (a 128^3 synthetic volume, labels 1 box / 2 shell / 3 core) and pyvista's
frog (25 labels, 500 x 470 x 136, spacing (1, 1, 1.5), offline), at ``--voxels`` (default 4)
times the smallest spacing.

Rows per case:

- warpmesh cleaving with the defaults (snapping 0.3 of an edge; the lattice graded down to
  ``min_size`` = h / 2 where a region the uniform lattice gets more than 2.5 % wrong is
  thinner than the edges, :mod:`warpmesh.solid.thin`), then on the uniform lattice
  (``min_size=size``) with and without (snap=0) the snapping: the graded lattice's gain and
  cost, and the quality before and after the snapping;
- TetGen (the ``tetgen`` module, ``regionattrib``, one seed per label at its voxel deepest
  inside, ``quality`` with minratio 1.5, mindihedral 10, maxvolume the volume of a BCC
  tetrahedron of side h) on ``mesh_surface(volume, labels="all", interfaces="shared")``; its
  time is TetGen's alone (the surface's time is printed apart). Skipped where ``tetgen`` is
  missing or fails on the surface.

For each: tetrahedra, wall and process-CPU seconds (median of ``--repeat`` warm runs for
warpmesh, one run for TetGen), tetrahedra per second, dihedral min / max, the largest relative
error of a region's volume against its voxel volume among the regions of at least
``--min-voxels`` voxels, the regions beyond 5 %, the regions lost (no tetrahedron), the
vertices where a label's boundary is pinched (warpmesh rows; the tests' oracle,
``tests/helpers/pinches.py``), and the
time ratio tool / warpmesh (> 1: warpmesh faster); then each warpmesh row's per-region errors.

Run:  python benchmarks/bench_regions.py [--repeat 3] [--voxels 4] [--no-tetgen] [--json out.json]
``--fresh`` times only the graded frog's first call in a new process (after one uniform call):
wall, user and system CPU and peak memory, which the warm rows above do not show.
``--cli`` times only the command a user runs on the frog (``warpmesh domain --volume
frog_tissues.vti --size h -o frog.msh``), each run a new process, with and without the
program's allocator setting, and the saved mesh written again as ``.msh``, ``.vtu`` and Medit
``.mesh`` by warpmesh and by meshio (:func:`cli_runs`, :func:`save_again`); about 2.5 minutes a
run and 2.5 minutes for the files.
``--smoothing`` measures only the interface smoothing (``smooth=``, :mod:`warpmesh.solid.region_smoothing`)
on the nested balls and the frog: the cleaved mesh against ``smooth`` 8 and 16 passes (the frog: 8; the
smoothing's own seconds, interface area, dihedral range, worst region error, overlapping
tetrahedra by ``wm.check``), and the interface area of VTK's smoothed ``contour_labels("all")``
(16 passes, a surface) as the peer's figure for a smoothed interface (:func:`smoothing_rows`).
The graded frog at 4 voxels takes about 45 s a run: ``--repeat 1 --no-tetgen`` for a quick look
(about 2 minutes in all).

Measured here (``nice python benchmarks/bench_regions.py --repeat 1 --no-tetgen``, 2 cores, load
1.9-3.0, 2026-12-03 09:49 UTC), frog at 4 voxels: defaults (graded to 2 voxels for labels 1, 12,
13 and the ten specks under 1,000 voxels) 8,851,938 tets, 42.1 s CPU (12.0x the uniform's 3.5 s
in the same run; 90.6 s before c474cee; 005133b's code 50.8-63.0 s against this code's
40.2-41.1 s in one process, alternating, with bit-identical meshes), dihedral [9.28°, 167.00°],
worst region of >= 1,000 voxels 4.59 % (label 1), none lost; uniform 2,249,597 tets, 3.5 s,
[12.76°, 159.12°], 15.75 % (labels 1 -15.7 %, 12 -9.4 %), 2 lost (21, 27). Nested balls 128^3:
nothing to grade (every region within 0.2 %), the uniform mesh.

Since the speck zones (7308b0a, d0bae2a; ``mesh_domain(frog, labels="all", size=4.0)`` before (regions as of b18e689)
and after in one shell run, one after the other, niced, load 1-3, 2026-12-03 15:30 UTC): every
region within 5 %, the specks of 4 to 252 voxels included: the ten specks -0.85 % to +0.46 %
(0-57 % off before: 23 -56.8 %, 20 -48.6 %, 25 -43.9 %), label 1 -3.26 % (-4.59 %), worst -3.26 %;
12,721,664 tets (8,851,938), 68.8 s CPU (42.6 s: 1.61x; 36.0 s of it the graded background,
7.1 s moving the specks' interfaces), dihedral [7.08°, 166.95°] ([9.28°, 167.00°]), no
negative tetrahedron, ``wm.check`` empty (45 s), none lost.

Since the pinch-free snapping (:mod:`warpmesh.solid.snapping`; ``nice python
benchmarks/bench_regions.py --repeat 1 --no-tetgen`` at f15d4e7 and at d8621df, one after the
other, load 1.2-1.5, 2026-12-05 00:00 UTC): the frog's defaults 12,837,134 tets (12,722,424),
27.6 s wall / 31.7 s CPU (27.2 / 31.6), dihedral [7.07°, 167.58°] ([7.08°, 166.95°]), worst
region -3.20 % (-3.26 %), none lost; 21,776 of 555,672 snapped cuts pushed, and no vertex where
a region's boundary is pinched (15,249 vertex-label pinches before: tests/solid/test_regions.py's
``pinched_vertices``). Uniform frog [12.76°, 159.12°] (the same); nested balls 128^3 [16.06°,
149.96°] ([16.77°, 149.96°]), every region within 0.2 % (0.17 %). At d9d4a56 (after the review's
fixes; the same command, 2026-12-05, load 1.1, with the ``pinched`` column): frog defaults
12,867,822 tets, 30.5 s wall / 34.9 s CPU, [7.07°, 167.58°], worst -3.17 %, 0 pinched vertices in
every row (frog and balls, snap 0.3 and 0).

Since a sample on a voxel face is in the upper voxel (``VOXEL_TIE``; the frog's lattice nodes lie
on its voxels' faces along x and y, where ``np.rint``'s ties to even alternated between the two
voxels): the same command at 64f56cf, 2026-12-05 02:45 UTC, load 1.6 (a test run beside it): frog
defaults 13,043,568 tets, 30.2 s wall / 32.0 s CPU, dihedral [6.36°, 167.34°], worst region -3.16 %
(label 1), none lost, 0 pinched; uniform 2,311,253 tets, [13.12°, 156.92°], 14.48 % (labels 1 -14.5 %,
12 -8.8 %; before -15.7 %, -9.4 %), 4 lost (2 before: specks of 4-121 voxels, which only the
default graded pass meshes); nested balls unchanged (every region within 0.19 %, [16.06°, 149.96°]).
At 5b0d691 (the review's fixes: speck sizes and the meshed-cells lookup without rounding ties; the same
command, 03:30 UTC, load about 1): the same frog meshes, defaults 27.8 s wall / 31.7 s CPU.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(1, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from _report import MALLOC_ENV, finish, keep_freed_memory, load_banner, median_run, version  # noqa: E402

if __name__ == "__main__":
    keep_freed_memory()

import numpy as np  # noqa: E402
from tests.helpers.pinches import pinched_vertices  # noqa: E402


def nested_balls(n: int = 128) -> np.ndarray:
    g = np.indices((n, n, n), dtype=np.float32)
    r2 = ((g - (n - 1) / 2.0) ** 2).sum(axis=0)
    vol = np.ones((n, n, n), np.uint8)
    vol[r2 < (0.4 * n) ** 2] = 2
    vol[r2 < (0.2 * n) ** 2] = 3
    return vol


def _region_errors(values: np.ndarray, spacing, labels, tet_labels, vols, min_voxels: int):
    voxel = float(np.prod(spacing))
    counts = np.bincount(values.ravel(order="K").astype(np.int64))
    errors = {}
    for L in labels:
        vv = counts[L] * voxel
        errors[int(L)] = (float(vols[tet_labels == L].sum()) / vv - 1.0, int(counts[L]))
    big = {L: e for L, (e, n) in errors.items() if n >= min_voxels}
    return errors, max((abs(e) for e in big.values()), default=0.0), sorted(L for L, e in big.items() if abs(e) > 0.05)


def _tetgen_row(image, values, spacing, h: float):
    import tetgen
    from scipy.ndimage import distance_transform_edt

    import warpmesh as wm

    t0 = time.perf_counter()
    surf = wm.mesh_surface(image, labels="all", interfaces="shared")
    t_surf = time.perf_counter() - t0
    tg = tetgen.TetGen(surf.points, surf.cells["triangle"])
    for L in np.unique(values):
        if L == 0:
            continue
        idx = np.argwhere(values == L)
        lo, hi = idx.min(axis=0), idx.max(axis=0) + 1
        sub = np.pad(values[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] == L, 1)
        d = distance_transform_edt(sub, sampling=spacing)
        k = np.array(np.unravel_index(np.argmax(d), d.shape)) - 1 + lo
        tg.add_region(int(L), (k * np.asarray(spacing)).tolist())
    w0, c0 = time.perf_counter(), time.process_time()
    nodes, elems, attrib, _ = tg.tetrahedralize(regionattrib=True, quality=True, minratio=1.5, mindihedral=10.0,
                                                maxvolume=h ** 3 / 12.0, quiet=True)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    labels = np.asarray(attrib).reshape(-1).astype(np.int64) if attrib is not None else np.zeros(len(elems), int)
    return np.asarray(nodes, float), np.asarray(elems, np.int64), labels, wall, cpu, t_surf


def run_case(name: str, image, values: np.ndarray, spacing, h: float, repeat: int, use_tetgen: bool,
             min_voxels: int) -> list[dict]:
    import warpmesh as wm
    from warpmesh.solid.dihedral import signed_volumes, tet_quality_summary

    present = [int(v) for v in np.unique(values) if v != 0]
    print(f"\n== {name}: {values.shape} samples, spacing {tuple(spacing)}, {len(present)} labels, size {h:g} "
          f"({h / min(spacing):g} voxels)")
    rows = []
    pinched = {}  # tool -> vertices where a label's boundary is pinched (tests/helpers/pinches.py)
    w, c, m = median_run(lambda: wm.mesh_domain(image, labels="all", size=h), repeat)
    graded = f"graded to {m.info['min_size']:g}" if m.info["graded"] else "uniform: nothing to grade"
    rows.append((f"warpmesh cleaving (defaults, {graded})", m.points, m.cells["tetra"], m.cell_refs["tetra"], w, c))
    wu, cu, mu = median_run(lambda: wm.mesh_domain(image, labels="all", size=h, min_size=h), repeat)
    rows.append((f"warpmesh cleaving (uniform, snap {mu.info['snap']:g})", mu.points, mu.cells["tetra"],
                 mu.cell_refs["tetra"], wu, cu))
    w0, c0, m0 = median_run(lambda: wm.mesh_domain(image, labels="all", size=h, snap=0.0, min_size=h),
                            max(1, repeat // 2))
    rows.append(("warpmesh cleaving (uniform, snap 0)", m0.points, m0.cells["tetra"], m0.cell_refs["tetra"], w0, c0))
    for (tool, *_), mesh in zip(rows, (m, mu, m0)):
        pinched[tool] = sum(pinched_vertices(mesh.cells["triangle"], mesh.cell_refs["triangle"],
                                             mesh.cell_data["label_above"]["triangle"]).values())
    for what, mm in (("defaults", m), ("uniform", mu)):
        print(f"warpmesh stages ({what}): " + ", ".join(f"{k} {v:.2f} s" for k, v in mm.info["time"].items())
              + f"; {mm.info['cleaved_tets']} of {mm.info['background_tets']} background tets cleaved, "
              f"{mm.info['snapped_cuts']} of {mm.info['cut_edges']} cut points snapped"
              + (f"; refined for labels {mm.info.get('refined_labels')}, graded background "
                 f"{mm.info.get('graded_tets')} tets" if mm.info["graded"] else ""))
    if use_tetgen:
        try:
            pts, tets, labs, tw, tc, t_surf = _tetgen_row(image, values, spacing, h)
            rows.append(("TetGen on the shared surface (regions)", pts, tets, labs, tw, tc))
            print(f"(the shared surface for TetGen took {t_surf:.2f} s, not counted)")
        except Exception as exc:  # a peer that fails is reported, not fatal
            print(f"TetGen: failed ({type(exc).__name__}: {str(exc)[:200]})")
    print(f"{'tool':52s} {'tets':>9s} {'wall s':>7s} {'cpu s':>7s} {'tets/s':>9s} {'dih min':>8s} {'dih max':>8s} "
          f"{'max |err|':>9s} {'>5 %':>12s} {'lost':>5s} {'pinched':>8s} {'wall/wm':>8s}")
    out = []
    for tool, pts, tets, labs, wall, cpu in rows:
        q = tet_quality_summary(pts, tets)
        vols = np.abs(signed_volumes(pts, tets))
        errors, worst, beyond = _region_errors(values, spacing, present, labs, vols, min_voxels)
        lost = sorted(L for L, (e, n) in errors.items() if e == -1.0)
        print(f"{tool:52s} {len(tets):9d} {wall:7.2f} {cpu:7.2f} {len(tets) / wall:9.0f} {q['dihedral_min']:8.2f} "
              f"{q['dihedral_max']:8.2f} {100 * worst:8.2f}% {str(beyond):>12s} {len(lost):5d} "
              f"{pinched.get(tool, '-')!s:>8s} {wall / rows[0][4]:8.2f}")
        out.append({"case": name, "tool": tool, "tets": int(len(tets)), "wall_s": wall, "cpu_s": cpu,
                    "dihedral_min": q["dihedral_min"], "dihedral_max": q["dihedral_max"],
                    "negative": q["negative_tets"], "region_errors": errors, "max_error": worst,
                    "beyond_5pct": beyond, "lost": lost, "pinched_vertices": pinched.get(tool),
                    "wall_vs_warpmesh": wall / rows[0][4]})
    for row in out[:2]:
        errs = row["region_errors"]
        print(f"{row['tool']}: per-region volume error (label: % [voxels]): "
              + ", ".join(f"{L}: {100 * e:+.1f} [{n}]" for L, (e, n) in sorted(errs.items())))
    return out


def fresh_run(voxels: float) -> dict:
    """The graded frog's first call in this process (after one uniform call, which loads the
    kernels): wall, process CPU (user and system) and the peak resident memory it raised, the
    figures a user's first call sees (the rows above are warm runs, their memory reused)."""
    import resource

    import pyvista as pv

    import warpmesh as wm

    frog = pv.examples.load_frog_tissues()
    h = voxels * min(frog.spacing)
    wm.mesh_domain(frog, labels="all", size=h, min_size=h)
    r0, w0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    m = wm.mesh_domain(frog, labels="all", size=h)
    r1, wall = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter() - w0
    return {"tets": int(len(m.cells["tetra"])), "wall_s": wall, "user_s": r1.ru_utime - r0.ru_utime,
            "system_s": r1.ru_stime - r0.ru_stime, "peak_rss_gb": r1.ru_maxrss / 2**20,
            "stages": {k: round(v, 2) for k, v in m.info["time"].items()}}


def cli_runs(voxels: float, repeat: int) -> dict:
    """The whole command a user runs on the frog, each run a new process:
    ``warpmesh domain --volume frog_tissues.vti --size h -o frog.msh --json``, with the
    allocator setting the program makes (default) and without it
    (``WARPMESH_KEEP_FREED_MEMORY=0``), rounds alternating: wall, user and system CPU and
    peak memory of the child (``os.wait4``), and the stages the command prints. Then, in this
    process, the saved mesh written again by warpmesh and by meshio (:func:`save_again`)."""
    import json
    import subprocess
    import tempfile

    import pyvista as pv

    import warpmesh as wm

    path = os.path.join(os.path.dirname(pv.__file__), "examples", "frog_tissues.vti")
    if not os.path.exists(path):
        path = pv.examples.download_frog_tissues(load=False)
    h = voxels * min(pv.read(path).spacing)
    runs = {"keep freed memory (default)": [], "WARPMESH_KEEP_FREED_MEMORY=0": []}
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "frog.msh")
        cmd = [sys.executable, "-m", "warpmesh.cli", "domain", "--volume", path, "--size", str(h), "-o", out, "--json"]
        for _ in range(max(1, repeat)):
            for name in runs:
                env = dict(os.environ)
                for k in MALLOC_ENV:  # the benchmark's own allocator setting must not leak into the child
                    env.pop(k, None)
                if name.startswith("WARPMESH"):
                    env["WARPMESH_KEEP_FREED_MEMORY"] = "0"
                w0 = time.perf_counter()
                child = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
                text = child.stdout.read()
                _, status, usage = os.wait4(child.pid, 0)
                wall = time.perf_counter() - w0
                if status != 0:
                    raise RuntimeError(f"{' '.join(cmd)} failed with status {status}")
                doc = json.loads(text)
                runs[name].append({"wall_s": wall, "user_s": usage.ru_utime, "system_s": usage.ru_stime,
                                   "peak_rss_gb": usage.ru_maxrss / 2**20, "tets": doc["n_tetra"],
                                   "self_intersections": doc["self_intersections"],
                                   "stages": {k: round(v, 2) for k, v in doc["time"].items()}})
        saves = save_again(wm.load(out), tmp)
    for name, rows in runs.items():
        for r in rows:
            print(f"{name}: wall {r['wall_s']:.1f} s, user {r['user_s']:.1f} s, system {r['system_s']:.1f} s, "
                  f"peak RSS {r['peak_rss_gb']:.2f} GB, {r['tets']} tets, self-intersections "
                  f"{r['self_intersections']}; stages {r['stages']}")
    for (ext, tool), r in saves.items():
        mine = saves[ext, "warpmesh"]["wall_s"]
        print(f"save {ext} again, {tool}: {r['wall_s']:.2f} s, {r['mb']:.0f} MB"
              + (f" ({r['wall_s'] / mine:.2f}x warpmesh's time)" if tool != "warpmesh" else ""))
    return {"cli": runs, "save": {f"{ext} {tool}": r for (ext, tool), r in saves.items()}}


def save_again(mesh, tmp: str) -> dict:
    """The mesh written again in each solver format by warpmesh (``Mesh.save``) and by meshio
    (the same points, cells and cell refs; gmsh 2.2 binary with one physical tag per cell,
    .vtu binary with zlib, Medit ASCII): {(extension, tool): wall seconds and MB}."""
    import meshio

    refs = [mesh.cell_refs[t] for t in mesh.cells]
    peer = {".msh": ({"gmsh:physical": refs, "gmsh:geometrical": refs}, {"file_format": "gmsh22", "binary": True}),
            ".vtu": ({"medit:ref": refs}, {"file_format": "vtu", "binary": True}),
            ".mesh": ({"medit:ref": refs}, {"file_format": "medit"})}
    saves = {}
    for ext, (cell_data, kwargs) in peer.items():
        for tool in ("warpmesh", "meshio"):
            target = os.path.join(tmp, f"again_{tool}{ext}")
            w0 = time.perf_counter()
            if tool == "warpmesh":
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UserWarning)  # what a format drops
                    mesh.save(target)
            else:
                meshio.write(target, meshio.Mesh(mesh.points, list(mesh.cells.items()), cell_data=cell_data), **kwargs)
            saves[ext, tool] = {"wall_s": time.perf_counter() - w0, "mb": os.path.getsize(target) / 1e6}
            os.remove(target)
    return saves


def _interface_area(points, tris, vol) -> float:
    """The area of the interface triangles whose centroid lies more than a voxel inside the
    image's box: the box faces (where a region meets the box; kept as cleaved by the smoothing,
    and meshed by VTK's ``contour_labels`` too) left out."""
    p = np.asarray(points)[np.asarray(tris)]
    spacing, origin = np.asarray(vol.spacing, float), np.asarray(vol.origin, float)
    lo, hi = origin + 0.5 * spacing, origin + (np.asarray(vol.values.shape) - 1.5) * spacing
    c = p.mean(axis=1)
    inside = np.all((c > lo) & (c < hi), axis=1)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    return float(area[inside].sum())


def smoothing_rows(voxels: float, passes=(8, 16), frog_passes=(8,)) -> list[dict]:
    """The cleaved mesh against ``smooth`` passes, on the nested balls (128^3; the spheres' areas
    known) and the frog (``frog_passes``: 13 M tetrahedra, minutes a run); VTK's smoothed
    ``contour_labels("all")`` area beside them."""
    import pyvista as pv

    import warpmesh as wm

    frog = pv.examples.load_frog_tissues()
    cases = [("nested balls 128^3", wm.Volume(nested_balls()), pv.wrap(nested_balls()),
              4.0 * np.pi * ((0.4 * 128) ** 2 + (0.2 * 128) ** 2), passes),
             ("frog", wm.Volume(frog.active_scalars.reshape(frog.dimensions, order="F"), spacing=frog.spacing,
                                origin=frog.origin), frog, None, frog_passes)]
    rows = []
    print(f"interface smoothing (size {voxels:g} voxels): area = the interface triangles' more than a voxel "
          "inside the box (VTK's surface has no box faces); ref = the spheres' area, or VTK's")
    print(f"{'case':20s} {'mesh':28s} {'tets':>10s} {'smooth s':>9s} {'area':>12s} {'/ cleaved':>9s} "
          f"{'/ ref':>7s} {'dihedral':>15s} {'max |err|':>9s} {'overlaps':>8s}")
    for name, vol, image, sphere_area, case_passes in cases:
        h = voxels * float(np.min(vol.spacing))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            vtk = image.contour_labels("all") if hasattr(image, "contour_labels") else None
        vtk_area = None
        if vtk is not None:
            tri = vtk.triangulate()
            vtk_area = _interface_area(tri.points, tri.faces.reshape(-1, 4)[:, 1:], vol)
        ref = sphere_area if sphere_area is not None else vtk_area
        cleaved_area = None
        for k in (0, *case_passes):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                m = wm.mesh_domain(vol, labels="all", size=h, smooth=k, progress=False)
            area = _interface_area(m.points, m.cells["triangle"], vol)
            cleaved_area = area if k == 0 else cleaved_area
            row = {"case": name, "mesh": "cleaved" if k == 0 else f"smooth={k}", "tets": len(m.cells["tetra"]),
                   "smooth_s": m.info["time"].get("smoothing", 0.0), "area": area,
                   "dihedral": [m.info["dihedral_min"], m.info["dihedral_max"]],
                   "max_err": m.info["region_error_max"], "overlaps": len(wm.check(m))}
            rows.append(row)
            print(f"{name:20s} {row['mesh']:28s} {row['tets']:10d} {row['smooth_s']:9.2f} {area:12.1f} "
                  f"{area / cleaved_area:9.3f} {(area / ref if ref else float('nan')):7.3f} "
                  f"[{row['dihedral'][0]:5.1f}, {row['dihedral'][1]:5.1f}] {row['max_err']:9.4f} {row['overlaps']:8d}")
        if vtk is not None:
            rows.append({"case": name, "mesh": "VTK contour_labels (16 passes)", "area": vtk_area})
            print(f"{name:20s} {'VTK contour_labels, smoothed':28s} {'':>10s} {'':>9s} {vtk_area:12.1f} "
                  f"{vtk_area / cleaved_area:9.3f} {(vtk_area / ref if ref else float('nan')):7.3f}")
        if sphere_area is not None:
            print(f"{name:20s} {'the two spheres':28s} {'':>10s} {'':>9s} {sphere_area:12.1f} "
                  f"{sphere_area / cleaved_area:9.3f} {1.0:7.3f}")
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--voxels", type=float, default=4.0, help="size in voxels (of the smallest spacing)")
    ap.add_argument("--min-voxels", type=int, default=1000,
                    help="regions with fewer voxels are listed but left out of 'max |err|'")
    ap.add_argument("--no-tetgen", action="store_true")
    ap.add_argument("--no-frog", action="store_true")
    ap.add_argument("--json")
    ap.add_argument("--default-malloc", action="store_true", help="measure with the stock allocator")
    ap.add_argument("--fresh", action="store_true",
                    help="only the graded frog's first call in a fresh process (time, system time, peak memory)")
    ap.add_argument("--cli", action="store_true",
                    help="only the command line on the frog (warpmesh domain --volume ... -o frog.msh) in fresh "
                         "processes, with and without its allocator setting, and the .msh written again by "
                         "warpmesh and meshio")
    ap.add_argument("--smoothing", action="store_true",
                    help="only the interface smoothing (smooth=8, 16) against the cleaved mesh and VTK's smoothed "
                         "contour_labels area")
    args = ap.parse_args(argv)
    if args.smoothing:
        t_start = time.perf_counter()
        load0 = load_banner(f"bench_regions --smoothing: warpmesh {version('warpmesh')}, {os.cpu_count()} cores")
        finish(t_start, load0, args.json, {"rows": smoothing_rows(args.voxels)})
        return 0
    if args.cli:
        doc = cli_runs(args.voxels, args.repeat)
        if args.json:
            import json

            with open(args.json, "w") as fh:
                json.dump(doc, fh)
        return 0
    if args.fresh:
        r = fresh_run(args.voxels)
        print(f"graded frog, first call in a fresh process: {r['tets']} tets, wall {r['wall_s']:.2f} s, "
              f"user {r['user_s']:.2f} s, system {r['system_s']:.2f} s, peak RSS {r['peak_rss_gb']:.2f} GB "
              f"(the process's, kernels and volume included)\nstages (wall s): {r['stages']}")
        if args.json:
            import json

            with open(args.json, "w") as fh:
                json.dump(r, fh)
        return 0

    import pyvista as pv

    t_start = time.perf_counter()
    load0 = load_banner(f"bench_regions: warpmesh {version('warpmesh')}, tetgen {version('tetgen')}, "
                        f"numpy {np.__version__}, {os.cpu_count()} cores")
    doc = {"rows": []}
    balls = nested_balls()
    doc["rows"] += run_case("nested balls 128^3", balls, balls, (1.0, 1.0, 1.0), args.voxels, args.repeat,
                            not args.no_tetgen, args.min_voxels)
    if not args.no_frog:
        frog = pv.examples.load_frog_tissues()
        import warpmesh as wm

        vol = wm.Volume(frog.active_scalars.reshape(frog.dimensions, order="F"), spacing=frog.spacing,
                        origin=frog.origin)
        doc["rows"] += run_case("frog", frog, vol.values, frog.spacing, args.voxels * min(frog.spacing),
                                args.repeat, not args.no_tetgen, args.min_voxels)
    finish(t_start, load0, args.json, doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
