"""Shared start and end of a benchmark run: the allocator setting, the load-average
banner, the wall time and the atomically written ``--json`` document."""

from __future__ import annotations

import json
import os
import sys
import time

#: glibc keeps freed memory in the heap (the same for every tool; README.md)
MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": str(16 << 30), "MALLOC_TRIM_THRESHOLD_": str(16 << 30)}


def version(package: str) -> str:
    """The installed version of a distribution, or "?"."""
    from importlib import metadata

    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "?"


def keep_freed_memory() -> None:
    """Re-run this script with :data:`MALLOC_ENV` unless it is set, ``--default-malloc``
    or ``--help`` is given, or the platform is not Linux. Call before importing numpy."""
    flags = sys.argv[1:]
    if ("--default-malloc" in flags or "-h" in flags or "--help" in flags
            or all(k in os.environ for k in MALLOC_ENV) or not sys.platform.startswith("linux")):
        return
    os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **MALLOC_ENV})


def median_run(fn, repeat: int):
    """(wall s, process CPU s, output) of the median-wall run among ``repeat`` runs of
    ``fn``, after one untimed warm-up call (imports, kernel loads)."""
    fn()
    runs = []
    for _ in range(max(1, int(repeat))):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        runs.append((time.perf_counter() - w0, time.process_time() - c0, out))
    runs.sort(key=lambda r: r[0])
    return runs[len(runs) // 2]


def load_banner(what: str) -> float:
    """Print ``what`` and the 1-minute load average (with a warning when the CPU is busy);
    return the load average."""
    load = os.getloadavg()[0]
    print(f"{what}; load average (1 min) at start: {load:.2f}"
          + ("  -- WARNING: other processes are using the CPU; timings will be noisy" if load > 0.7 else ""))
    return load


def finish(t_start: float, load0: float, json_path: str | None, doc: dict) -> None:
    """Print the wall time and end load; write ``doc`` (plus both) to ``json_path`` atomically."""
    elapsed = time.perf_counter() - t_start
    load1 = os.getloadavg()[0]
    print(f"\nbenchmark wall time {elapsed:.0f} s; load average (1 min) at the end: {load1:.2f}")
    if json_path:
        doc = {**doc, "load_average_start_end": [load0, load1], "wall_s": elapsed}
        tmp = json_path + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(doc, fh, indent=1, default=str)
        os.replace(tmp, json_path)
        print(f"results written to {json_path}")
