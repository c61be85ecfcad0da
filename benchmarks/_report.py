"""Shared start and end of a benchmark run: the load-average banner, the wall time and
the atomically written ``--json`` document."""

from __future__ import annotations

import json
import os
import time


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
