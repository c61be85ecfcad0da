"""Self-intersection check: warpmesh against pymeshlab on the same meshes, in one run.

Usage::

    python benchmarks/bench_intersections.py                  # about 3 min on 2 cores
    python benchmarks/bench_intersections.py --cases part,ball --resolution 512   # check / meshing
    python benchmarks/bench_intersections.py --cases sphere7,spheres7 --repeat 1   # smoke run
    python benchmarks/bench_intersections.py --json results.json
    python benchmarks/bench_intersections.py --cases part --profile   # CPU s per stage

Cases (``--cases``, comma-separated; default ``sphere7,sphere8,spheres7,spheres8,part,ball,part-tets``):

- ``sphere7`` / ``sphere8``: a closed icosphere (``trimesh.creation.icosphere``) with 7 / 8
  subdivisions: 327,680 / 1,310,720 triangles, no crossing;
- ``spheres7`` / ``spheres8``: two such spheres (radii 1 and 0.8, the second moved by
  (0.9, 0.13, 0.071)) in one mesh: 655,360 / 2,621,440 triangles, crossing along a curve;
- ``part`` / ``ball``: warpmesh's own output, ``wm.mesh_surface`` of ``wm.example("part")``
  at its bounds / of ``wm.sphere(1.0)`` in [-1.2, 1.2]^3, at ``--resolution`` (default 512:
  about 1.5 M / 1.7 M triangles; the part has large grid-aligned flat regions, the ties
  of the check). These cases add a row ``meshing``: the ``mesh_surface`` call that made the
  mesh, timed in the same rounds, and the table's last columns give each tool's time
  divided by the meshing time (CPU seconds, and wall).

- ``part-tets``: the part's tetrahedra (``wm.mesh_domain(..., features=False)`` at
  ``--tet-size``, default 0.03: about 1 M tetrahedra; without the crease recovery, the
  fastest meshing and so the hardest ratio): ``find_tet_overlaps`` against the meshing
  call, same rounds (no
  peer: pymeshlab checks triangles only); the run fails if a pair is reported.

Tools: warpmesh ``find_self_intersections`` (all cores, and ``workers=1``), which takes
numpy arrays (its time includes validation and upload); pymeshlab
``compute_selection_by_self_intersections_per_face`` on a ``MeshSet`` loaded beforehand
(its time is the filter alone). Round-robin: one untimed call each (Warp loads its
cached kernels), then ``--repeat`` rounds of one call per tool; the table gives the
median. Offending faces: the distinct faces in warpmesh's pairs, and pymeshlab's
selection; the run fails if the two sets differ. Columns: median wall seconds, ratio to
warpmesh with all workers (> 1: warpmesh faster), median CPU seconds of the process
(all threads: CPU / wall shows how much of the second core a tool used; on a busy
machine, CPU seconds are the steadier figure), offending faces.

Figures (2026-12-02, 2 cores, load average 3.5-6: wall times inflated, read the CPU
columns), ``--cases part,ball --resolution 512 --repeat 3``, CPU s of warpmesh (2 workers)
/ pymeshlab / meshing, and warpmesh / meshing:

- before the group walk (commit 234eb9f): part 2.79 / 1.52 / 0.96 (2.91x), ball 2.63 /
  2.27 / 0.76 (3.47x);
- after (commit 711d59b): part 1.75 / 1.58 / 0.97 (1.80x), ball 1.54 / 2.32 / 0.75 (2.05x).

The part at resolution 1024 (6.0 M triangles), one script, min of 2: meshing 8.1 CPU s,
the check 11.9 before, 7.4 after (0.91x the meshing).

Second round (2026-12-02, the same command; CPU s of warpmesh with 2 workers / 1 worker
/ pymeshlab / meshing, warpmesh (2) / meshing):

- at commit b9f0bda, load 0.7-1.8: part 1.67 / 1.66 / 1.48 / 0.92 (1.81x), ball 1.49 /
  1.48 / 2.21 / 0.71 (2.09x);
- group tree instead of ``wp.Bvh``, masked face screen, float32 coordinates by a kernel
  and the points' bounds column by column (commit ccbe8fd), load 0.9-1.1: part 1.49 /
  1.42 / 1.43 / 0.89 (1.67x), ball 1.26 / 1.25 / 2.16 / 0.68 (1.86x). Alternating
  b9f0bda's pipeline and this one in one process (``workers=1``, 7 rounds, load about 1):
  new / old CPU 0.90 (part), 0.89 (ball). The part at 1024 at commit 3f1d6ba
  (``--repeat 2``, load 3-4): warpmesh 6.5, pymeshlab 6.1, meshing 3.8 CPU s (1.73x; the
  meshing is faster than in the first round's figure).

Third round (2026-12-03, the same command; CPU s of warpmesh with 2 workers / 1 worker /
pymeshlab / meshing, warpmesh (2) / meshing):

- at commit cd59f11, load about 1: part 1.55 / 1.54 / 1.49 / 0.93 (1.67x), ball 1.30 /
  1.29 / 2.21 / 0.72 (1.80x);
- slot lists in the walk and the separation shortcut of the coplanar test (commit
  ec89004), load 1.9-3.0: part 1.48 / 1.46 / 1.52 / 0.95 (1.56x), ball 1.29 / 1.28 /
  2.25 / 0.73 (1.76x);
- and face s loaded eagerly in the walk (commit 5b45499), load 2.2-2.7: part 1.41 / 1.41
  / 1.50 / 0.95 (1.49x), ball 1.24 / 1.24 / 2.25 / 0.75 (1.66x). The part at 1024
  (``--cases part --resolution 1024 --repeat 2``, load 2.0-2.4): warpmesh 5.76 CPU s (3.92
  wall with 2 workers), pymeshlab 6.27, meshing 3.91 CPU s (2.91 wall): 1.47x the
  meshing's CPU time, 1.35x its wall time.

Alternating cd59f11's count walk and 5b45499's in one process (``workers=1``, 3-5 rounds,
load about 2.4): new / old CPU 0.91 (part at 512, 1.414 -> 1.283 s), 0.94 (ball, 1.154 ->
1.084), 0.90 (part at 1024, 5.81 -> 5.24). The meshing is now twice as fast as in the
first round (8.1 CPU s at 1024), so the check's earlier ratio at 1024 (0.91x) no longer
holds; the target (well under the meshing's time) is not met at 512 or 1024.

Fourth round (2026-12-03): the umbrella certificate (pairs sharing a vertex whose faces
provably meet only where they share skip the exact test; commits 1e594e4-bc93429). The
same commands, CPU s of warpmesh with 2 workers / 1 worker / pymeshlab / meshing, warpmesh
(2) / meshing:

- at commit 19f0c5b (before), load 1.4-2.8: part 1.46 / 1.52 / 1.49 / 0.93 (1.56x), ball
  1.29 / 1.32 / 2.24 / 0.73 (1.77x); the part at 1024 (``--repeat 2``, load 2.8-3.3):
  warpmesh 6.01, pymeshlab 6.29, meshing 3.92 (1.53x);
- at commit bc93429 (after), load 2.7-3.2: part 1.07 / 1.07 / 1.50 / 0.94 (1.14x), ball
  1.11 / 1.10 / 2.25 / 0.73 (1.53x); the part at 1024 (load 1.8-3.4): warpmesh 4.37
  (4.73 s wall with 2 workers), pymeshlab 6.32, meshing 3.93 (5.51 wall): 1.11x the
  meshing's CPU time, 0.86x its wall time.

Alternating 19f0c5b's ``find_self_intersections`` and bc93429's in one process
(``workers=1``, load 2.4-2.8, /tmp scripts importing the old kernels under another
module name): new / old CPU 0.714 (part at 512, 1.546 -> 1.104 s, 5 rounds, each round
0.706-0.716), 0.832 (ball, 1.366 -> 1.136), 0.755 (part at 1024, 6.24 -> 4.71, 3
rounds); the same pairs (none). Every vertex of the part and the ball is certified; the
certificate costs 0.09-0.11 s of it and the walk drops from 1.36 to 0.84 (part) and 1.14
to 0.81 (ball). The check is still above the meshing's CPU time (the target is well
under it); what is left is the face-level box screen (about 0.5 s on the part) and the
exact tests of the 2.2 pairs a face that share no vertex.

Fifth round (2026-12-03): the cell grid as the candidate search of surfaces whose faces are
about one size (commit 006662e; the tree stays for the others). The same commands, load
3.3-7.3, CPU s of warpmesh with 2 workers / 1 worker / pymeshlab / meshing, warpmesh (2) /
meshing: part 0.74 / 0.76 / 1.58 / 0.95 (0.78x), ball 0.78 / 0.76 / 2.33 / 0.76 (1.04x);
the part at 1024 (``--repeat 2``): 3.06 / 2.99 / 6.70 / 4.13 (0.74x; 0.66x the meshing's
wall time). Alternating the grid and the tree in one process (``workers=1``, 3 rounds,
load 4.4-5.0, the same pairs): grid / tree CPU 0.65 (part at 512, 1.13 -> 0.74 s), 0.67
(ball, 1.19 -> 0.80). The icospheres and the crossing icospheres (7 and 8 subdivisions)
still agree with pymeshlab. The target, at most half the meshing's CPU time, is not met
(see benchmarks/README.md).

Sixth round (2026-12-05, stop 50, commits 3000866-70edce3: neighbour cells skipped by reach bits, the
query face loaded eagerly, faces classified and boxed in one pass, keys and the vertex -> corner table
made by halves on two threads, numpy scratch), ``--cases part,ball --resolution 512 --repeat 5``, load
about 1, wall s with 2 workers before (f5c4c9b) / after, and after / meshing wall: part 0.359 / 0.280
(0.52x), ball 0.406 / 0.333 (0.88x); at 1024 (``--repeat 2``): part 1.130 s, 0.49x; ball 1.321 s, 0.81x.

Seventh round (2026-12-05, stop 51: the block certificate, blocks of grid cells whose pairs the walk
skips), ``--cases part,ball --resolution 512 --repeat 5``, stop 50's code in a venv of its own and this
one run alternately, load about 1.1, wall s with 2 workers before / after, and after / meshing wall:
part 0.290, 0.286 / 0.202, 0.238 (0.36x, 0.39x), ball 0.332, 0.333 / 0.264, 0.324 (0.66x, 0.71x); at
1024 (``--repeat 2``, after): part 0.773 s, 0.35x; ball 0.937 s, 0.64x.

Eighth round (2026-12-05, stop 52: the passes before the walk: a coarser grid with blocks of
128^3 to 4^3 cells, the inputs prepared on both cores, the keys from a table, an umbrella function
per fan size, six comparisons a coordinate for the crossing bits, dead scratch reused),
``--cases part,ball --resolution 512 --repeat 5``, stop 51's code in a venv of its own and this
one run alternately, load about 1.0, wall s with 2 workers before / after, and after / meshing
wall (CPU): part 0.215, 0.213 / 0.181, 0.181 (0.33x, 0.34x; CPU 0.34x), ball 0.239, 0.244 /
0.193, 0.189 (0.49x, 0.48x; CPU 0.53x, 0.55x); at 1024 (``--repeat 3``, after): part 0.660 s,
0.29x; ball 0.698 s, 0.47x (CPU 0.51x); pymeshlab 5.6 / 9.4 s.

Tetrahedra (2026-12-03, commit 3926e0f + find_tet_overlaps, load 2.5, ``--cases part-tets
--repeat 3``): 1,031,312 tetrahedra, find_tet_overlaps 0.50 CPU s (0.75 s wall) against the
``features=False`` stuffing's 0.89 CPU s (1.36 wall): 0.56x the meshing; the face sort and
the numpy passes over the 4 M faces are most of it, the boundary's triangle check ~0.1 s.

``--profile`` (before the certificate): the walk with its exact tests was 89-92 % of the
check (part at 512: 1.38 of 1.49 CPU s; prepare 0.03, order 0.05, degenerate flags 0.02,
boxes 0.02, tree 0.001); with it, about 77 % (0.84 of 1.10, umbrellas 0.09); see the
module docstring of ``warpmesh.cells.intersections`` for where the walk's time goes and
what was tried.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from _report import finish, keep_freed_memory, load_banner, version

keep_freed_memory()

import numpy as np  # noqa: E402
import pymeshlab  # noqa: E402
import trimesh  # noqa: E402

from warpmesh.cells.intersections import (  # noqa: E402
    find_self_intersections,
    find_tet_overlaps,
    profile_self_intersections,
)

CASES = {
    "sphere7": ("icosphere, 7 subdivisions", 7, False),
    "sphere8": ("icosphere, 8 subdivisions", 8, False),
    "spheres7": ("two crossing icospheres, 7 subdivisions", 7, True),
    "spheres8": ("two crossing icospheres, 8 subdivisions", 8, True),
    "part": ("wm.mesh_surface of the bundled part", "part", None),
    "ball": ("wm.mesh_surface of a unit sphere", "ball", None),
    "part-tets": ("wm.mesh_domain of the bundled part (tetrahedra)", "part", "tets"),
}


def mesher(key: str, resolution: int):
    """The ``mesh_surface`` call of a meshed case, as a function returning the mesh."""
    import warpmesh as wm

    if key == "part":
        shape, bounds = wm.example("part")
    else:
        shape, bounds = wm.sphere(1.0), ((-1.2, -1.2, -1.2), (1.2, 1.2, 1.2))
    return lambda: wm.mesh_surface(shape, bounds=bounds, resolution=resolution)


def make_mesh(subdivisions: int, two: bool) -> tuple[np.ndarray, np.ndarray]:
    a = trimesh.creation.icosphere(subdivisions=subdivisions)
    if not two:
        return np.asarray(a.vertices), np.asarray(a.faces)
    b = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.8)
    b.apply_translation([0.9, 0.13, 0.071])
    return (np.vstack([a.vertices, b.vertices]),
            np.vstack([a.faces, np.asarray(b.faces) + len(a.vertices)]))


def profile_case(points, faces, repeat: int) -> list[dict]:
    """``profile_self_intersections`` (all workers) ``repeat`` times after a warm-up: the
    median CPU and wall seconds of each stage, printed as a table and returned as rows."""
    profile_self_intersections(points, faces)
    runs = [profile_self_intersections(points, faces) for _ in range(max(1, repeat))]
    rows = [{"stage": st, "cpu_seconds": statistics.median(r["cpu"].get(st, 0.0) for r in runs),
             "wall_seconds": statistics.median(r["wall"].get(st, 0.0) for r in runs)} for st in runs[0]["cpu"]]
    total = sum(r["cpu_seconds"] for r in rows) or 1.0
    print("| stage | cpu s | share | wall s |")
    print("| --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['stage']} | {r['cpu_seconds']:.3f} | {100 * r['cpu_seconds'] / total:.0f} % | "
              f"{r['wall_seconds']:.3f} |")
    return rows


def timed_rounds(tools: dict, repeat: int) -> tuple[dict, dict]:
    """One untimed call of each tool (Warp loads its cached kernels), then ``repeat``
    rounds of one call per tool: (wall seconds, CPU seconds) lists by tool."""
    for fn in tools.values():
        fn()
    times = {t: [] for t in tools}
    cpu = {t: [] for t in tools}
    for _ in range(repeat):
        for tool, fn in tools.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            times[tool].append(time.perf_counter() - t0)
            cpu[tool].append(time.process_time() - c0)
    return times, cpu


def run_tet_case(key: str, repeat: int, size: float) -> dict:
    """``find_tet_overlaps`` on the stuffed part against the ``mesh_domain`` call that made
    it, in the same rounds (no peer checks tetrahedra: the row is the ratio to meshing)."""
    import warpmesh as wm

    shape, bounds = wm.example("part")
    mesh = wm.mesh_domain(shape, bounds=bounds, size=size, features=False)
    points, tets = np.asarray(mesh.points), np.asarray(mesh.cells["tetra"])
    out = {}
    tools = {"find_tet_overlaps": lambda: out.update(pairs=find_tet_overlaps(points, tets)),
             "meshing": lambda: wm.mesh_domain(shape, bounds=bounds, size=size, features=False)}
    times, cpu = timed_rounds(tools, repeat)
    med = {t: statistics.median(v) for t, v in times.items()}
    mcpu = {t: statistics.median(v) for t, v in cpu.items()}
    rows = [{"tool": t, "seconds": med[t], "cpu_seconds": mcpu[t], "wall_per_meshing": med[t] / med["meshing"],
             "cpu_per_meshing": mcpu[t] / mcpu["meshing"], "samples": times[t], "cpu_samples": cpu[t]} for t in tools]
    print(f"\n{CASES[key][0]}, size {size}: {len(tets):,} tetrahedra, {len(out['pairs']):,} overlapping pairs")
    print("| tool | seconds | cpu s | cpu / meshing cpu | wall / meshing wall |")
    print("| --- | --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['tool']} | {r['seconds']:.3f} | {r['cpu_seconds']:.3f} | {r['cpu_per_meshing']:.2f} | "
              f"{r['wall_per_meshing']:.2f} |")
    return {"case": key, "name": CASES[key][0], "tetrahedra": len(tets), "pairs": len(out["pairs"]), "rows": rows,
            "agree": len(out["pairs"]) == 0}


def run_case(key: str, repeat: int, resolution: int = 512, profile: bool = False) -> dict:
    name, subdivisions, two = CASES[key]
    meshing = None
    if two is None:  # a meshed case: its mesher is timed too
        meshing = mesher(subdivisions, resolution)
        mesh = meshing()
        points, faces = np.asarray(mesh.points, float), np.asarray(mesh.cells["triangle"])
        name = f"{name} at resolution {resolution}"
    else:
        points, faces = make_mesh(subdivisions, two)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(points, faces))
    out = {}

    def warpmesh_all():
        out["warpmesh"] = find_self_intersections(points, faces)

    def warpmesh_one():
        out["warpmesh 1"] = find_self_intersections(points, faces, workers=1)

    def meshlab():
        ms.compute_selection_by_self_intersections_per_face()

    tools = {f"warpmesh ({os.cpu_count()} workers)": warpmesh_all, "warpmesh (workers=1)": warpmesh_one,
             "pymeshlab": meshlab}
    if meshing is not None:
        tools["meshing"] = meshing
    times, cpu = timed_rounds(tools, repeat)

    ours = np.unique(out["warpmesh"])
    theirs = np.flatnonzero(ms.current_mesh().face_selection_array())
    agree = np.array_equal(ours, theirs) and np.array_equal(out["warpmesh"], out["warpmesh 1"])
    med = {t: statistics.median(v) for t, v in times.items()}
    ref = med[next(iter(tools))]
    mcpu = {t: statistics.median(v) for t, v in cpu.items()}
    rows = [{"tool": t, "seconds": med[t], "ratio": med[t] / ref, "cpu_seconds": mcpu[t],
             "samples": times[t], "cpu_samples": cpu[t],
             "faces": None if t == "meshing" else len(theirs) if t == "pymeshlab" else len(ours)} for t in tools]
    if meshing is not None:  # time / meshing time, CPU and wall
        for r in rows:
            r["cpu_per_meshing"] = mcpu[r["tool"]] / mcpu["meshing"]
            r["wall_per_meshing"] = med[r["tool"]] / med["meshing"]
    print(f"\n{name}: {len(faces):,} triangles, {len(out['warpmesh']):,} crossing pairs")
    extra = " cpu / meshing cpu | wall / meshing wall |" if meshing is not None else ""
    print("| tool | seconds | ratio | cpu s | offending faces |" + extra)
    print("| --- | --- | --- | --- | --- |" + (" --- | --- |" if extra else ""))
    for r in rows:
        faces_col = "" if r["faces"] is None else f"{r['faces']:,}"
        line = f"| {r['tool']} | {r['seconds']:.3f} | {r['ratio']:.2f}x | {r['cpu_seconds']:.3f} | {faces_col} |"
        if extra:
            line += f" {r['cpu_per_meshing']:.2f} | {r['wall_per_meshing']:.2f} |"
        print(line)
    print(f"offending faces agree (warpmesh = pymeshlab, and for any workers): {'yes' if agree else 'NO'}")
    result = {"case": key, "name": name, "triangles": len(faces), "pairs": len(out["warpmesh"]), "rows": rows,
              "agree": bool(agree)}
    if profile:
        print(f"warpmesh ({os.cpu_count()} workers) by stage, median of {repeat}, the device synchronised after each:")
        result["profile"] = profile_case(points, faces, repeat)
    return result


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", default=",".join(CASES), help=f"comma-separated subset of {list(CASES)}")
    p.add_argument("--repeat", type=int, default=3, help="timed rounds (median; default 3)")
    p.add_argument("--resolution", type=int, default=512, help="resolution of the meshed cases (default 512)")
    p.add_argument("--json", default=None, help="write every row and sample to this file")
    p.add_argument("--tet-size", type=float, default=0.03,
                   help="lattice size h of the part-tets case (default 0.03: about 1 M tetrahedra)")
    p.add_argument("--profile", action="store_true", help="also print warpmesh's CPU seconds per pipeline stage")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator (see README)")
    a = p.parse_args(argv)
    cases = [c.strip() for c in a.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        p.error(f"unknown case(s) {unknown}. Pick from {list(CASES)}")
    t_start = time.perf_counter()
    load0 = load_banner(f"self-intersections: {os.cpu_count()} cores, python {sys.version.split()[0]}, "
                        f"warp-lang {version('warp-lang')}, pymeshlab {version('pymeshlab')}, "
                        f"trimesh {version('trimesh')}")
    if a.resolution < 8:
        p.error(f"expected --resolution >= 8, got {a.resolution}")
    results = [run_tet_case(c, a.repeat, a.tet_size) if CASES[c][2] == "tets" else
               run_case(c, a.repeat, a.resolution, a.profile) for c in cases]
    finish(t_start, load0, a.json, {"results": results})
    return 0 if all(r["agree"] for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
