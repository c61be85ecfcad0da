#!/usr/bin/env python3
"""Bricked meshing on Dask (issue 25): speed-up over one process, per-worker memory, and
the parameters of the scaling model of docs/distributed.md, in one run.

Cases:

``part``    the CSG part (``wm.example("part")``) at ``--resolution`` cells (default 1024):
            one process (``mesh_surface`` in a fresh interpreter, its own two threads per
            launch), then ``mesh_surface(..., client=...)`` on a LocalCluster of 1 and of 2
            worker processes (one thread each; each launch still splits over the cores),
            gathered into one Mesh; and on 2 workers with ``gather=False, output=...``
            (the workers write VTU pieces, nothing comes back).
``volume``  a gyroid (float32, ``--volume`` samples, default 512,256,256) in a zarr store
            (chunks 128^3): one process from the numpy array, 2 workers from
            ``dask.array.from_zarr`` (each brick read on its worker).
``scheduler`` 400 no-op tasks on the 2-worker cluster: the scheduler's cost per task.
``adaptive`` the part on an adaptive octree at ``--adaptive-level`` (default 10), bricks of
            ``--adaptive-brick-cells`` finest cells (default 512): one process (fresh
            interpreter) against ``mesh_surface(..., adaptive=True, client=...)`` on 2 workers
            (the octree, face units, crossings and roots on the workers; the join, loops, fans,
            flips and untangle on the client), with the stages' times.
``domain``  the part's tetrahedral domain by isosurface stuffing at ``--domain-size`` (default
            0.03: about 1 M tetrahedra), ``features=False`` (the stuffing alone; the stages
            after it run on the client's gathered mesh as in one process): one process,
            then ``mesh_domain(..., client=...)`` on 2 workers, bricks of
            ``--domain-brick-cells`` black nodes (default 32), gathered.
``serial``  the bricks' own work: every meshed brick's task of a gathered run of the part at
            ``--pin-resolutions`` in bricks of ``--pin-brick-cells``, one after the other in one
            process pinned to core 0 (no cluster), then one process's mesh on the same core;
            their CPU, evaluations and active blocks (what the halos cost, without Dask or
            contention between workers). ``--rounds`` rounds, medians.
``pinned``  one core per process (this machine's one process already uses both cores, so "2
            workers against one process" cannot show scaling here): one process pinned to core 0
            (``os.sched_setaffinity``, warpmesh's launches on one thread, one thread for the
            numeric libraries) against a LocalCluster of 2 single-threaded workers pinned to cores
            0 and 1, ``gather=False`` (VTU pieces) and ``gather=True``, for the part at
            ``--pin-resolutions`` (768,1024) in bricks of ``--pin-brick-cells`` (128,256) and the
            part's domain at ``--pin-domain-sizes`` (0.03,0.015; ``features=False``, bricks of
            ``--domain-brick-cells``). ``--rounds`` rounds (3), the two configurations alternating
            (ABBA), medians. The gathered mesh is compared with the one-process mesh once per case
            (triangle by triangle, positions within float32 rounding; tetrahedra bit for bit). It
            prints each worker's CPU, peak memory and time inside brick tasks (Dask's task stream),
            the client process's CPU (client and scheduler), the scheduler's cost per brick, the idle
            tail (one worker done, the other still busy), the tasks' time after meshing (the piece
            written, the result packed) and the gather. The client is not pinned: on two one-core
            machines it would share one of them, as it shares both cores here. This is the speed-up
            two one-core machines give over one, not a 2-machine figure.

The shape is evaluated by ``--evaluator`` in every run (default "compiled": the kernel
generated for the part, loaded from Warp's disk cache by each process's warm-up; with
"auto" a worker may compile it in the background during the timed run, which one process
meshing once never does).

Every cluster is new (its workers warmed up by a 64^3 run that loads Warp's cached
kernels, and started with the allocator setting of this run, see benchmarks/README.md)
and its workers' peak resident memory is reset (``/proc/self/clear_refs``) before the
timed run, so "peak" is the run's own. "cpu" sums the worker processes' CPU
time (their threads too); the one-process figures come from its own process. The single
process mesh and the bricked one are compared by counts here (the tests compare them
triangle by triangle). The model's parameters are printed at the end with the prediction
for 8192^3 on N machines.

Run:  python benchmarks/bench_distributed.py [--resolution 1024] [--brick-cells 128]
                                             [--volume 512,256,256] [--cases part,volume,scheduler]
                                             [--domain-size 0.03] [--domain-brick-cells 32]
                                             [--adaptive-level 10] [--adaptive-brick-cells 512]
                                             [--pin-resolutions 768,1024] [--pin-brick-cells 128,256]
                                             [--pin-domain-sizes 0.03,0.015] [--rounds 3]
                                             [--json out.json]
      python benchmarks/bench_distributed.py --cases pinned   (one core per process)
      python benchmarks/bench_distributed.py --cases serial --pin-resolutions 1024   (the bricks' own work)
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _report import MALLOC_ENV, finish, keep_freed_memory, load_banner, version  # noqa: E402

if __name__ == "__main__":
    keep_freed_memory()

import numpy as np  # noqa: E402

import warpmesh as wm  # noqa: E402

CORES = os.cpu_count() or 1


# -- measurements inside a process ------------------------------------------------------------------
def _reset_peak() -> int:
    """Reset this process's peak resident size; return the current one (bytes)."""
    with open("/proc/self/clear_refs", "w") as fh:
        fh.write("5")
    return _status("VmRSS")


def _status(field: str) -> int:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return 0


def _cpu() -> float:
    return time.process_time()


#: one thread for the numeric libraries of a process pinned to one core (Warp's CPU launches
#: are single-threaded; warpmesh's per-core split is set by :func:`pin_to_core`)
PIN_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def pin_to_core(core: int) -> set:
    """This process on ``core`` alone, as on a one-core machine: its affinity (warpmesh's CPU
    launches then run on one thread: ``warpmesh._util.parallel.n_workers`` counts the cores of
    the affinity). Returns the affinity."""
    os.sched_setaffinity(0, {core})
    return os.sched_getaffinity(0)


def gyroid(shape) -> np.ndarray:
    """sin x cos y + sin y cos z + sin z cos x, 0.11 rad per sample (a dense sheet), float32."""
    i, j, k = (np.arange(n, dtype=np.float32) * np.float32(0.11) for n in shape)
    return (np.sin(i)[:, None, None] * np.cos(j)[None, :, None] + np.sin(j)[None, :, None] * np.cos(k)[None, None, :]
            + np.sin(k)[None, None, :] * np.cos(i)[:, None, None]).astype(np.float32)


def single_process(case: str, resolution: int, volume_path: str | None, evaluator: str = "compiled",
                   size: float = 0.0, pin: int | None = None, save: str | None = None) -> dict:
    """One process: warm up, reset the peak, mesh once; wall, CPU, peak RSS, counts. ``pin``: on
    that core alone (:func:`pin_to_core`); ``save``: an .npz path for the mesh's arrays."""
    if pin is not None:
        pin_to_core(pin)
    fn = wm.mesh_surface
    if case == "domain":
        part, bounds = wm.example("part")
        wm.mesh_domain(part, bounds=bounds, size=0.2, features=False)
        fn, source, kw = wm.mesh_domain, part, dict(bounds=bounds, size=size, features=False)
    elif case == "adaptive":
        part, bounds = wm.example("part")
        wm.mesh_surface(part, bounds=bounds, adaptive=True, max_level=6)
        source, kw = part, dict(bounds=bounds, adaptive=True, max_level=resolution)
    elif case == "part":
        part, bounds = wm.example("part")
        wm.mesh_surface(part, bounds=bounds, resolution=64, evaluator=evaluator)
        source, kw = part, dict(bounds=bounds, resolution=resolution, evaluator=evaluator)
    else:
        source = np.load(volume_path, mmap_mode=None)
        wm.mesh_surface(gyroid((40, 40, 40)), level=0.2)
        kw = dict(level=0.2)
    base = _reset_peak()
    t, c = time.perf_counter(), _cpu()
    mesh = fn(source, **kw)
    wall, cpu = time.perf_counter() - t, _cpu() - c
    out = {"wall": wall, "cpu": cpu, "peak_extra": _status("VmHWM") - base, "peak": _status("VmHWM"),
           **_counts(mesh)}
    if save:
        np.savez(save, points=mesh.points, **{k: v for k, v in mesh.cells.items()})
    if case == "adaptive":  # the stages, to set against the bricked run's
        out["time"] = {k: round(float(v), 3) for k, v in mesh.info["time"].items() if k in ADAPTIVE_STAGES}
    return out


ADAPTIVE_STAGES = ("octree", "faces", "root", "untangle", "fans", "join_crossings", "total")


def _counts(mesh) -> dict:
    out = {"points": mesh.n_points, "triangles": len(mesh.cells.get("triangle", ()))}
    if "tetra" in mesh.cells:
        out["tets"] = len(mesh.cells["tetra"])
    return out


def run_in_fresh_process(case: str, resolution: int, volume_path: str | None, evaluator: str = "compiled",
                         size: float = 0.0, pin: int | None = None, save: str | None = None) -> dict:
    code = (f"import sys; sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r}); "
            f"import json, bench_distributed as b; "
            f"print('RESULT', json.dumps(b.single_process({case!r}, {resolution}, {volume_path!r}, {evaluator!r}, "
            f"{size!r}, {pin!r}, {save!r})))")
    env = {**os.environ, **(PIN_ENV if pin is not None else {})}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=3600, env=env)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")]
    if not line:
        raise RuntimeError(out.stderr[-3000:])
    return json.loads(line[0][7:])


# -- on a cluster ------------------------------------------------------------------------------------
def cluster(n_workers: int, evaluator: str = "compiled"):
    from dask.distributed import Client, LocalCluster

    # the workers get this run's allocator setting too (Dask's nanny would set MALLOC_TRIM_THRESHOLD_=65536,
    # returning freed memory at once: in this VM every page touched anew then costs kernel time again)
    env = {k: os.environ[k] for k in MALLOC_ENV if k in os.environ}
    lc = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      memory_limit=0, silence_logs=50, env=env)
    client = Client(lc)
    part, bounds = wm.example("part")
    wm.mesh_surface(part, bounds=bounds, resolution=64, client=client, brick_cells=32, progress=False,
                    evaluator=evaluator)  # warm-up: loads Warp's cached kernels on every worker
    return lc, client


def bricked(client, source, kw: dict, fn=wm.mesh_surface) -> dict:
    """One timed bricked run: wall, the workers' CPU and peak RSS, the mesh's counts and info."""
    client.run(_reset_peak)
    cpu0 = client.run(_cpu)
    t = time.perf_counter()
    result = fn(source, client=client, progress=False, **kw)
    wall = time.perf_counter() - t
    cpu1 = client.run(_cpu)
    peaks = client.run(_status, "VmHWM")
    info = result.info
    counts = _counts(result) if isinstance(result, wm.Mesh) else {"points": result.n_points,
                                                                  "triangles": result.n_cells}
    return {"wall": wall, "cpu": sum(cpu1[w] - cpu0[w] for w in cpu1), "peak_per_worker": sorted(peaks.values()),
            **counts, "bricks": info["bricks"], "bricks_meshed": info["bricks_meshed"],
            "bricks_culled": info.get("bricks_culled", 0), "brick_cpu": info["brick_cpu_time"],
            "time": info["time"], "seam_copies": info.get("seam_copies_welded")}


def scheduler_cost(client, n: int = 400) -> float:
    """Seconds per no-op task, submitted and gathered as a bricked run does."""
    from dask.distributed import as_completed

    t = time.perf_counter()
    futures = [client.submit(int, i, pure=False) for i in range(n)]
    for f in as_completed(futures):
        f.result()
    return (time.perf_counter() - t) / n


def _gb(b) -> str:
    return f"{b / 1e9:.2f} GB" if b >= 1e8 else f"{b / 1e6:.1f} MB"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--brick-cells", type=int, default=128)
    ap.add_argument("--volume", default="512,256,256")
    ap.add_argument("--cases", default="part,volume,scheduler")
    ap.add_argument("--domain-size", type=float, default=0.03)
    ap.add_argument("--domain-brick-cells", type=int, default=32)
    ap.add_argument("--adaptive-level", type=int, default=10)
    ap.add_argument("--adaptive-brick-cells", type=int, default=512)
    ap.add_argument("--pin-resolutions", default="768,1024", help="case pinned: the part's resolutions")
    ap.add_argument("--pin-brick-cells", default="128,256", help="case pinned: the part's brick sizes")
    ap.add_argument("--pin-domain-sizes", default="0.03,0.015", help="case pinned: the domain's sizes ('' for none)")
    ap.add_argument("--rounds", type=int, default=3, help="case pinned: rounds, the configurations alternating")
    ap.add_argument("--evaluator", default="compiled", choices=("compiled", "interpreter", "auto"),
                    help="the shape's evaluator, the same in every run (default: the generated kernel, loaded "
                         "from Warp's cache in the warm-ups, so no compile falls in a timed run)")
    ap.add_argument("--json")
    args = ap.parse_args()
    cases = args.cases.split(",")
    t_start = time.perf_counter()
    load0 = load_banner(f"bench_distributed: warpmesh bricks on dask {version('distributed')}, {CORES} cores")
    doc: dict = {"resolution": args.resolution, "brick_cells": args.brick_cells, "cores": CORES,
                 "evaluator": args.evaluator}
    ev = args.evaluator
    part, bounds = wm.example("part")
    R, B = args.resolution, args.brick_cells

    if "part" in cases:
        print(f"\n(a) part at {R}^3 cells, bricks of {B}^3 cells")
        one = run_in_fresh_process("part", R, None, ev)
        print(f"  one process        wall {one['wall']:7.2f} s  cpu {one['cpu']:7.2f} s  peak {_gb(one['peak'])} "
              f"(+{_gb(one['peak_extra'])})  {one['triangles']:,} triangles")
        rows = {"one": one}
        for n in (1, 2):
            lc, client = cluster(n, ev)
            try:
                r = bricked(client, part, dict(bounds=bounds, resolution=R, brick_cells=B, evaluator=ev))
                rows[f"{n}w"] = r
                print(f"  {n} worker{'s' if n > 1 else ' '}          wall {r['wall']:7.2f} s  cpu {r['cpu']:7.2f} s  "
                      f"peak/worker {', '.join(_gb(p) for p in r['peak_per_worker'])}  {r['triangles']:,} triangles, "
                      f"{r['bricks_meshed']} of {r['bricks']} bricks meshed, weld {r['time']['weld']:.2f} s "
                      f"({r['seam_copies']:,} seam copies)")
                if n == 2:
                    with tempfile.TemporaryDirectory() as d:
                        p = bricked(client, part, dict(bounds=bounds, resolution=R, brick_cells=B, evaluator=ev,
                                                       gather=False, output=os.path.join(d, "part.pvtu")))
                        size = sum(os.path.getsize(os.path.join(d, f)) for f in os.listdir(d))
                    p["bytes_on_disk"] = size
                    rows["2w_pieces"] = p
                    print(f"  2 workers, pieces  wall {p['wall']:7.2f} s  cpu {p['cpu']:7.2f} s  peak/worker "
                          f"{', '.join(_gb(q) for q in p['peak_per_worker'])}  {p['triangles']:,} triangles in "
                          f"{p['bricks_meshed']} VTU pieces, {_gb(size)} on disk")
                    if "scheduler" in cases:
                        doc["scheduler_s_per_task"] = scheduler_cost(client)
                        print(f"\n(c) scheduler: {doc['scheduler_s_per_task'] * 1e3:.2f} ms per no-op task "
                              "(submit + as_completed + result)")
            finally:
                client.close()
                lc.close()
        same = rows["1w"]["triangles"] == rows["2w"]["triangles"] == one["triangles"] and \
            rows["1w"]["points"] == rows["2w"]["points"] == one["points"]
        print(f"  same counts in the three runs: {same}")
        print(f"  speed-up, 2 workers over one process: {one['wall'] / rows['2w']['wall']:.2f}x (wall); "
              f"over 1 worker: {rows['1w']['wall'] / rows['2w']['wall']:.2f}x; "
              f"CPU 2 workers / one process: {rows['2w']['cpu'] / one['cpu']:.2f}")
        doc["part"] = rows

    if "volume" in cases:
        shape = tuple(int(v) for v in args.volume.split(","))
        print(f"\n(b) gyroid volume {shape[0]}x{shape[1]}x{shape[2]} from zarr, bricks of {B}^3 cells")
        import dask.array as da
        import zarr

        with tempfile.TemporaryDirectory() as d:
            vol = gyroid(shape)
            np.save(os.path.join(d, "v.npy"), vol)
            store = zarr.create_array(store=os.path.join(d, "v.zarr"), shape=shape, chunks=(128, 128, 128),
                                      dtype=np.float32)
            store[:] = vol
            del vol
            one = run_in_fresh_process("volume", 0, os.path.join(d, "v.npy"))
            print(f"  one process (numpy) wall {one['wall']:7.2f} s  cpu {one['cpu']:7.2f} s  peak "
                  f"{_gb(one['peak'])} (+{_gb(one['peak_extra'])}, input included)  {one['triangles']:,} triangles")
            lc, client = cluster(2, ev)
            try:  # warm-up: the workers import dask.array and zarr on their first volume brick
                small = zarr.create_array(store=os.path.join(d, "w.zarr"), shape=(40, 40, 40), chunks=(20, 20, 20),
                                          dtype=np.float32)
                small[:] = gyroid((40, 40, 40))
                wm.mesh_surface(da.from_zarr(os.path.join(d, "w.zarr")), level=0.2, brick_cells=16, client=client,
                                progress=False)
                r = bricked(client, da.from_zarr(os.path.join(d, "v.zarr")), dict(level=0.2, brick_cells=B))
            finally:
                client.close()
                lc.close()
            print(f"  2 workers (zarr)   wall {r['wall']:7.2f} s  cpu {r['cpu']:7.2f} s  peak/worker "
                  f"{', '.join(_gb(p) for p in r['peak_per_worker'])}  {r['triangles']:,} triangles, "
                  f"same counts: {(r['triangles'], r['points']) == (one['triangles'], one['points'])}")
            print(f"  speed-up, 2 workers over one process: {one['wall'] / r['wall']:.2f}x (wall)")
            doc["volume"] = {"shape": shape, "one": one, "2w": r}

    if "domain" in cases:
        domain(doc, args.domain_size, args.domain_brick_cells, ev)
    if "adaptive" in cases:
        adaptive(doc, args.adaptive_level, args.adaptive_brick_cells, ev)
    if "pinned" in cases:
        pinned(doc, [int(v) for v in args.pin_resolutions.split(",") if v],
               [int(v) for v in args.pin_brick_cells.split(",") if v],
               [float(v) for v in args.pin_domain_sizes.split(",") if v], args.domain_brick_cells, args.rounds, ev)
    if "serial" in cases:
        serial(doc, [int(v) for v in args.pin_resolutions.split(",") if v],
               [int(v) for v in args.pin_brick_cells.split(",") if v], args.rounds, ev)
    if "part" in cases:
        model(doc, R, B)
    finish(t_start, load0, args.json, doc)


# -- the bricks' own work (--cases serial) -----------------------------------------------------------
def _serial_round(R: int, B: int, ev: str) -> dict:
    """In a fresh process pinned to core 0: every meshed brick's task of a gathered run, one after
    the other in this process (no cluster: the bricks' work alone), then one process's mesh."""
    code = (
        "import json, os, sys, time; os.sched_setaffinity(0, {0})\n"
        "import warpmesh as wm\n"
        "from warpmesh.distributed.run import _ShapeJob\n"
        "from warpmesh.surface.options import GridOptions\n"
        f"R, B, ev = {R}, {B}, {ev!r}\n"
        "part, bounds = wm.example('part')\n"
        "wm.mesh_surface(part, bounds=bounds, resolution=64, evaluator=ev)\n"
        "job = _ShapeJob(part, GridOptions(bounds=bounds, resolution=R, evaluator=ev), 'cpu', None, B)\n"
        "todo = job.bricks_to_mesh(); t0 = time.process_time(); ev_n = blocks = 0\n"
        "for b in todo:\n"
        "    r = job.task(b, None, True); ev_n += r.info['evaluations']; blocks += r.info['active_blocks']\n"
        "cpu = time.process_time() - t0; t0 = time.process_time()\n"
        "one = wm.mesh_surface(part, bounds=bounds, resolution=R, evaluator=ev)\n"
        "print(json.dumps(dict(bricks=len(todo), bricks_cpu=cpu, one_cpu=time.process_time() - t0, "
        "evaluations=ev_n, one_evaluations=one.info['evaluations'], active_blocks=blocks, "
        "one_active_blocks=one.info['active_blocks'])))\n")
    env = dict(os.environ, **{k: "1" for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")})
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def serial(doc: dict, resolutions: list[int], brick_cells: list[int], rounds: int, ev: str) -> None:
    """The bricks' CPU against one process's, both on one core in one process (no Dask): what the
    halos and the per-brick work cost, without the cluster's contention."""
    print("\n(h) the bricks' work: every meshed brick's task of a gathered run, serial in one process "
          "pinned to core 0, then one process's mesh on the same core; medians of the rounds")
    doc["serial"] = {}
    for R in resolutions:
        for B in brick_cells:
            rows = [_serial_round(R, B, ev) for _ in range(rounds)]
            med = {k: float(np.median([r[k] for r in rows])) for k in ("bricks_cpu", "one_cpu")}
            r0 = rows[0]
            per_round = ", ".join(f"{r['bricks_cpu'] / r['one_cpu']:.2f}" for r in rows)
            print(f"  part {R}^3, bricks of {B}^3 ({r0['bricks']} meshed): bricks {med['bricks_cpu']:.2f} CPU s, "
                  f"one process {med['one_cpu']:.2f} CPU s ({med['bricks_cpu'] / med['one_cpu']:.2f}x; per round "
                  f"{per_round}); evaluations "
                  f"{r0['evaluations']:,} against {r0['one_evaluations']:,} "
                  f"({r0['evaluations'] / r0['one_evaluations']:.2f}x), active blocks {r0['active_blocks']:,} "
                  f"against {r0['one_active_blocks']:,}")
            doc["serial"][f"part {R}^3, bricks {B}^3"] = {"rounds": rows, **med}


def domain(doc: dict, size: float, brick_cells: int, ev: str) -> None:
    """The part's tetrahedra by stuffing: one process against 2 workers, gathered."""
    print(f"\n(e) part's domain, stuffing at size {size:g} (features=False), bricks of {brick_cells}^3 black nodes")
    one = run_in_fresh_process("domain", 0, None, ev, size)
    print(f"  one process        wall {one['wall']:7.2f} s  cpu {one['cpu']:7.2f} s  peak {_gb(one['peak'])}  "
          f"{one['tets']:,} tetrahedra")
    part, bounds = wm.example("part")
    lc, client = cluster(2, ev)
    try:
        kw = dict(bounds=bounds, features=False)
        wm.mesh_domain(part, size=0.2, brick_cells=8, client=client, progress=False, **kw)  # warm-up
        r = bricked(client, part, dict(size=size, brick_cells=brick_cells, **kw), fn=wm.mesh_domain)
    finally:
        client.close()
        lc.close()
    same = (r["tets"], r["points"]) == (one["tets"], one["points"])
    print(f"  2 workers          wall {r['wall']:7.2f} s  cpu {r['cpu']:7.2f} s  peak/worker "
          f"{', '.join(_gb(p) for p in r['peak_per_worker'])}  {r['tets']:,} tetrahedra, {r['bricks_meshed']} of "
          f"{r['bricks']} bricks meshed; bricks done after {r['time']['bricks']:.2f} s, gather {r['time']['weld']:.2f} s "
          f"({r['seam_copies']:,} copies joined), the client's stages after it {r['wall'] - r['time']['total']:.2f} s; "
          f"same counts: {same}")
    print(f"  speed-up, 2 workers over one process: {one['wall'] / r['wall']:.2f}x (wall); "
          f"CPU 2 workers / one process: {r['cpu'] / one['cpu']:.2f}")
    doc["domain"] = {"size": size, "brick_cells": brick_cells, "one": one, "2w": r}


def adaptive(doc: dict, level: int, brick_cells: int, ev: str) -> None:
    """The part on an adaptive octree: one process against 2 workers (octree on the workers)."""
    print(f"\n(f) part, adaptive octree at max_level {level}, bricks of {brick_cells} finest cells a side")
    one = run_in_fresh_process("adaptive", level, None, ev)
    print(f"  one process        wall {one['wall']:7.2f} s  cpu {one['cpu']:7.2f} s  peak {_gb(one['peak'])}  "
          f"{one['triangles']:,} triangles")
    part, bounds = wm.example("part")
    lc, client = cluster(2, ev)
    try:
        kw = dict(bounds=bounds, adaptive=True)
        wm.mesh_surface(part, max_level=6, client=client, progress=False, **kw)  # warm-up: the octree's kernels
        client.run(_reset_peak)
        cpu0, c0 = client.run(_cpu), _cpu()
        t = time.perf_counter()
        mesh = wm.mesh_surface(part, max_level=level, brick_cells=brick_cells, client=client, progress=False, **kw)
        wall, client_cpu = time.perf_counter() - t, _cpu() - c0
        cpu1, peaks = client.run(_cpu), client.run(_status, "VmHWM")
    finally:
        client.close()
        lc.close()
    info, tm = mesh.info, mesh.info["time"]
    r = {"wall": wall, "client_cpu": client_cpu, "cpu": sum(cpu1[w] - cpu0[w] for w in cpu1),
         "peak_per_worker": sorted(peaks.values()), **_counts(mesh),
         **{k: info[k] for k in ("brick_level", "bricks", "bricks_culled", "brick_tasks", "bricks_per_round",
                                 "brick_cpu_time", "octree_rounds")},
         "time": {k: round(float(tm[k]), 3) for k in ADAPTIVE_STAGES if k in tm}}
    same = (r["triangles"], r["points"]) == (one["triangles"], one["points"])
    print(f"  2 workers          wall {wall:7.2f} s  cpu {r['cpu']:7.2f} s (workers) + {client_cpu:.2f} s (client)  "
          f"peak/worker {', '.join(_gb(p) for p in r['peak_per_worker'])}  {r['triangles']:,} triangles; "
          f"{r['brick_tasks']} tasks of {r['bricks']} bricks (level {r['brick_level']}, {r['bricks_culled']} culled), "
          f"rounds {r['bricks_per_round']}; same counts: {same}")
    print(f"  stages of one process (s): {one.get('time')}")
    print(f"  stages of the 2-worker run (s): {r['time']} (octree: the bricks' trees and contouring on the "
          f"workers, the merge; faces: the join of their crossings)")
    print(f"  speed-up, 2 workers over one process: {one['wall'] / wall:.2f}x (wall); client CPU "
          f"{client_cpu / one['cpu']:.2f} of one process's, workers + client {(r['cpu'] + client_cpu) / one['cpu']:.2f}")
    doc["adaptive"] = {"max_level": level, "brick_cells": brick_cells, "one": one, "2w": r}


# -- one core per worker (--cases pinned) ------------------------------------------------------------
def _pin_worker(dask_worker=None) -> list:
    """On a worker (``client.run``): pin it to the core of its name (LocalCluster names 0, 1, ...)."""
    return sorted(pin_to_core(int(dask_worker.name) % CORES))


def pinned_cluster(n_workers: int, evaluator: str = "compiled"):
    """A LocalCluster of ``n_workers`` single-threaded worker processes, each pinned to its own
    core (with warpmesh's launches on one thread), warmed up as :func:`cluster`'s."""
    from dask.distributed import Client, LocalCluster

    env = {**{k: os.environ[k] for k in MALLOC_ENV if k in os.environ}, **PIN_ENV}
    lc = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      memory_limit=0, silence_logs=50, env=env)
    client = Client(lc)
    cores = client.run(_pin_worker)
    if len({tuple(c) for c in cores.values()}) != n_workers or any(len(c) != 1 for c in cores.values()):
        raise RuntimeError(f"expected each worker on a core of its own, got {cores}")
    part, bounds = wm.example("part")
    wm.mesh_surface(part, bounds=bounds, resolution=64, client=client, brick_cells=32, progress=False,
                    evaluator=evaluator)  # warm-up: loads Warp's cached kernels on every worker
    wm.mesh_domain(part, bounds=bounds, size=0.2, features=False, brick_cells=8, client=client, progress=False)
    return lc, client


def pinned_bricked(client, source, kw: dict, fn=wm.mesh_surface) -> tuple[dict, object]:
    """One timed bricked run on a pinned cluster: (figures, the result). Beyond :func:`bricked`'s:
    the client process's CPU (the client and, in a LocalCluster, the scheduler's thread), each
    worker's CPU and time inside brick tasks (Dask's task stream), and where the wall time goes:
    the client's layout and culling, the bricks (until the last result is in), the gather."""
    from dask.distributed import get_task_stream

    client.run(_reset_peak)
    cpu0, c0 = client.run(_cpu), _cpu()
    t = time.perf_counter()
    with get_task_stream(client) as ts:
        result = fn(source, client=client, progress=False, **kw)
    wall, client_cpu = time.perf_counter() - t, _cpu() - c0
    cpu1, peaks = client.run(_cpu), client.run(_status, "VmHWM")
    busy: dict = {}
    for task in ts.data:
        if "warpmesh" in str(task["key"]):  # the run's brick tasks
            for ss in task["startstops"]:
                if ss["action"] == "compute":
                    w = busy.setdefault(task["worker"], [0.0, 0, np.inf, -np.inf])
                    w[0] += ss["stop"] - ss["start"]
                    w[1] += 1
                    w[2], w[3] = min(w[2], ss["start"]), max(w[3], ss["stop"])
    info, tm = result.info, result.info["time"]
    counts = _counts(result) if isinstance(result, wm.Mesh) else {"points": result.n_points,
                                                                  "triangles": result.n_cells}
    ends = sorted(v[3] for v in busy.values())
    out = {"wall": wall, "client_cpu": client_cpu, "cpu_per_worker": sorted(cpu1[w] - cpu0[w] for w in cpu1),
           "peak_per_worker": sorted(peaks.values()), **counts, "bricks": info["bricks"],
           "bricks_meshed": info["bricks_meshed"], "brick_cpu": info["brick_cpu_time"],
           "task_seconds_per_worker": sorted(v[0] for v in busy.values()),
           "tasks_per_worker": sorted(v[1] for v in busy.values()),
           "tail": ends[-1] - ends[0] if len(ends) > 1 else 0.0,  # one worker idle at the end: imbalance
           # in the tasks after the bricks' own meshing: the piece written (gather=False), the result packed
           "after_meshing": sum(v[0] for v in busy.values()) - info["brick_cpu_time"],
           "time": {k: round(float(v), 3) for k, v in tm.items()}}
    return out, result


def same_surface(path: str, mesh) -> tuple[bool, float]:
    """Whether the gathered ``mesh`` is the one-process mesh saved at ``path``: the same triangles
    (vertices matched one to one by position) and positions within float32 rounding of the box
    (as tests/distributed compare them); and the largest distance over the box's size."""
    from scipy.spatial import cKDTree

    one = np.load(path)
    pts, tri = one["points"], one["triangle"]
    if (len(pts), len(tri)) != (mesh.n_points, mesh.n_cells):
        return False, float("inf")
    scale = float(np.abs(pts).max())
    dist, match = cKDTree(pts).query(mesh.points)
    if len(np.unique(match)) != len(match):
        return False, float(dist.max()) / scale

    def canonical(f):
        f = np.asarray(f, dtype=np.int64)
        f = np.take_along_axis(f, (np.argmin(f, axis=1)[:, None] + np.arange(3)[None]) % 3, axis=1)  # winding kept
        return f[np.lexsort(f.T[::-1])]

    same = np.array_equal(canonical(tri), canonical(match[mesh.cells["triangle"]]))
    return bool(same and dist.max() <= 4 * np.finfo(np.float32).eps * scale), float(dist.max()) / scale


def same_domain(path: str, mesh) -> bool:
    """Whether the gathered tetrahedra are the one-process ones saved at ``path``: the same
    points, bit for bit, and the same tetrahedra as sets of points (as tests/distributed)."""
    one = np.load(path)
    if one["points"].shape != mesh.points.shape or one["tetra"].shape != mesh.cells["tetra"].shape:
        return False

    def canonical(points, tets):
        order = np.lexsort(points.T[::-1])
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        t = np.sort(rank[tets], axis=1)
        return points[order], t[np.lexsort(t.T[::-1])]

    a, b = canonical(one["points"], one["tetra"]), canonical(mesh.points, mesh.cells["tetra"])
    return bool(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]))


def _median(rows: list, key: str) -> float:
    return float(np.median([r[key] for r in rows]))


def pinned(doc: dict, resolutions: list[int], brick_cells: list[int], sizes: list[float], domain_brick_cells: int,
           rounds: int, ev: str) -> None:
    """One process on one core against 2 workers on a core each (gather=False and True), the
    configurations alternating round by round: the speed-up two one-core machines give over one."""
    print(f"\n(g) one core per process: one process pinned to core 0 against 2 workers pinned to cores 0 "
          f"and 1 (one thread each, warpmesh's launches unsplit); {rounds} rounds, the configurations "
          "alternating; medians")
    lc, client = pinned_cluster(2, ev)
    doc["pinned"] = {"rounds": rounds, "brick_cells": brick_cells, "domain_brick_cells": domain_brick_cells,
                     "cases": {}}
    try:
        doc["pinned"]["scheduler_s_per_task"] = sched = scheduler_cost(client)
        print(f"  scheduler: {sched * 1e3:.2f} ms per no-op task on the pinned cluster")
        part, bounds = wm.example("part")
        jobs = [(f"part {R}^3, bricks {B}^3", "part", R, 0.0, dict(bounds=bounds, resolution=R, brick_cells=B,
                                                                  evaluator=ev), wm.mesh_surface)
                for R in resolutions for B in brick_cells]
        jobs += [(f"domain size {s:g}", "domain", 0, s, dict(bounds=bounds, size=s, features=False,
                                                            brick_cells=domain_brick_cells), wm.mesh_domain)
                 for s in sizes]
        for name, case, R, size, kw, fn in jobs:
            doc["pinned"]["cases"][name] = _pinned_case(client, name, case, R, size, kw, fn, part, rounds, ev, sched)
    finally:
        client.close()
        lc.close()


def _pinned_case(client, name, case, R, size, kw, fn, part, rounds, ev, sched) -> dict:
    print(f"\n  {name}, bricks of {kw['brick_cells']}^3 {'cells' if case == 'part' else 'black nodes'}")
    rows: dict = {"one": [], "pieces": [], "gathered": []}
    same = None
    with tempfile.TemporaryDirectory() as d:
        saved = os.path.join(d, "one.npz")
        for r in range(rounds):
            for cfg in (("one", "2w") if r % 2 == 0 else ("2w", "one")):
                if cfg == "one":
                    one = run_in_fresh_process(case, R, None, ev, size, pin=0, save=saved if r == 0 else None)
                    rows["one"].append(one)
                    print(f"  round {r}: one process, 1 core   wall {one['wall']:7.2f} s  cpu {one['cpu']:7.2f} s  "
                          f"peak {_gb(one['peak'])}")
                    continue
                out = os.path.join(d, "pieces")
                os.makedirs(out, exist_ok=True)
                p, _ = pinned_bricked(client, part, dict(kw, gather=False, output=os.path.join(out, "m.pvtu")), fn)
                p["bytes_on_disk"] = sum(os.path.getsize(os.path.join(out, f)) for f in os.listdir(out))
                shutil.rmtree(out)
                g, mesh = pinned_bricked(client, part, kw, fn)
                rows["pieces"].append(p)
                rows["gathered"].append(g)
                if same is None and os.path.exists(saved):  # once: the one-process mesh of the first round
                    same = same_surface(saved, mesh) if case == "part" else (same_domain(saved, mesh), 0.0)
                    print(f"  the gathered mesh is the one-process mesh: {same[0]} (largest position difference "
                          f"{same[1]:.2g} of the box)")
                del mesh
                for label, q in (("pieces  ", p), ("gathered", g)):
                    print(f"  round {r}: 2 workers, {label}     wall {q['wall']:7.2f} s  cpu/worker "
                          f"{', '.join(f'{c:.2f}' for c in q['cpu_per_worker'])} s  client {q['client_cpu']:.2f} s  "
                          f"peak/worker {', '.join(_gb(m) for m in q['peak_per_worker'])}  in tasks "
                          f"{', '.join(f'{c:.2f}' for c in q['task_seconds_per_worker'])} s "
                          f"({'/'.join(str(c) for c in q['tasks_per_worker'])} tasks; of which writing/packing "
                          f"{q['after_meshing']:.2f} s), one worker idle at the end "
                          f"{q['tail']:.2f} s; client: layout {q['time'].get('layout', 0):.2f} s, bricks "
                          f"{q['time'].get('bricks', 0):.2f} s, gather {q['time'].get('weld', 0):.2f} s")
    one_wall = _median(rows["one"], "wall")
    summary = {"one_wall": one_wall, "one_cpu": _median(rows["one"], "cpu"), "same_mesh": same[0] if same else None}
    unit = "triangles" if case == "part" else "tets"
    print(f"  {rows['one'][0].get(unit, rows['one'][0]['triangles']):,} {unit}; "
          f"{rows['gathered'][0]['bricks_meshed']} of {rows['gathered'][0]['bricks']} bricks meshed")
    for label in ("pieces", "gathered"):
        rs = rows[label]
        wall = _median(rs, "wall")
        ratio = float(np.median([o["wall"] / q["wall"] for o, q in zip(rows["one"], rs)]))
        work = float(np.median([sum(q["cpu_per_worker"]) for q in rs]))
        per_task = float(np.median([sum(q["task_seconds_per_worker"]) for q in rs])) / rs[0]["bricks_meshed"]
        # the speed-up the CPU seconds allow with nothing else on the cores: the busier worker, or the
        # workers and the client (who shares the two cores) together, whichever bounds the wall time
        bound = float(np.median([o["cpu"] / max(max(q["cpu_per_worker"]),
                                                (sum(q["cpu_per_worker"]) + q["client_cpu"]) / 2)
                                 for o, q in zip(rows["one"], rs)]))
        summary[label] = {"wall": wall, "speedup": one_wall / wall, "speedup_same_round": ratio, "cpu_bound": bound,
                          "workers_cpu": work, "client_cpu": _median(rs, "client_cpu"),
                          "tail": _median(rs, "tail"), "peak_per_worker": max(max(q["peak_per_worker"]) for q in rs),
                          "task_s_per_brick": per_task, "after_meshing": _median(rs, "after_meshing"),
                          "gather": float(np.median([q["time"].get("weld", 0.0) for q in rs])),
                          "layout": float(np.median([q["time"].get("layout", 0.0) for q in rs]))}
        s = summary[label]
        print(f"  2 workers, {label}: speed-up over one core {s['speedup']:.2f}x (medians; per round "
              f"{s['speedup_same_round']:.2f}x; CPU-time bound {s['cpu_bound']:.2f}x); workers' CPU {work:.2f} s = "
              f"{work / summary['one_cpu']:.2f} of one "
              f"process's; client+scheduler CPU {s['client_cpu']:.2f} s; scheduler {rs[0]['bricks_meshed']} bricks x "
              f"{sched * 1e3:.2f} ms = {rs[0]['bricks_meshed'] * sched:.2f} s; in tasks after meshing (piece "
              f"written, result packed) {s['after_meshing']:.2f} s; idle tail {s['tail']:.2f} s; "
              f"gather {s['gather']:.2f} s; client layout {s['layout']:.2f} s; peak per worker "
              f"{_gb(s['peak_per_worker'])}")
    return {"rows": rows, "summary": summary}


def model(doc: dict, R: int, B: int) -> None:
    """The scaling model's parameters from this run, and its prediction for 8192^3."""
    rows = doc["part"]
    two, one = rows["2w"], rows["one"]
    cpu_per_brick = two["cpu"] / two["bricks_meshed"]
    eff = one["cpu"] / max(two["cpu"], 1e-9)  # work bricked vs one process
    sched = doc.get("scheduler_s_per_task", 1e-3)
    peak = max(rows["2w_pieces"]["peak_per_worker"])
    bytes_per_tri = rows["2w_pieces"]["bytes_on_disk"] / max(rows["2w_pieces"]["triangles"], 1)
    print(f"\n(d) model parameters (docs/distributed.md): {cpu_per_brick:.3f} s of worker time per meshed brick "
          f"of {B}^3 cells at {R}^3; one-process CPU / bricked CPU {eff:.2f}; scheduler {sched * 1e3:.2f} ms per "
          f"task; peak per worker {_gb(peak)} (writing pieces); {bytes_per_tri:.0f} bytes per triangle on disk")
    target = 8192
    scale = (target / R) ** 2  # the part's surface: meshed bricks, triangles and work grow as R^2
    bricks = two["bricks_meshed"] * scale
    work = two["cpu"] * scale  # CPU seconds of the workers (their wall time inside tasks waits on a busy machine)
    tris = two["triangles"] * scale
    print(f"    8192^3: {bricks:,.0f} meshed bricks, {tris / 1e6:,.0f} M triangles, {work / 3600:.1f} worker-hours, "
          f"{_gb(tris * bytes_per_tri)} of pieces")
    doc["model"] = {"cpu_per_brick": cpu_per_brick, "scheduler_s": sched, "peak_per_worker": peak,
                    "bytes_per_triangle": bytes_per_tri, "predictions": {}}
    for machines in (1, 8, 64):
        workers = machines * CORES
        t = work / workers + sched * bricks
        doc["model"]["predictions"][machines] = t
        print(f"    on {machines:3d} machine(s) of {CORES} cores: {t / 60:8.1f} min "
              f"(work {work / workers / 60:.1f} min + scheduler {sched * bricks / 60:.2f} min)")


if __name__ == "__main__":
    main()
