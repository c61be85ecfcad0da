"""Per-cell tape pruning, measured: the adaptive mesher with and without pruned tapes.

Usage: ``python benchmarks/bench_prune.py [--holes 8] [--max-level 9] [--repeat 2]``

A plate with holes x holes cylindrical holes (min/max booleans, so intervals decide
branches) and the bundled R-function part (nothing to prune): warm best-of-N times with
``prune=True`` and ``prune=False``, the mean tape length per level, and the ratio.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import warpmesh as wm


def plate(holes: int):
    centres = np.linspace(-0.8, 0.8, holes)
    cylinders = [wm.cylinder(0.4 / holes).translate((x, y, 0)) for x in centres for y in centres]
    return wm.difference(wm.box((2, 2, 0.6)), wm.union(*cylinders, method="minmax"), method="minmax")


def best(shape, bounds, max_level, prune, repeat):
    wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=max_level, prune=prune)  # warm-up
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=max_level, prune=prune)
        runs.append(time.perf_counter() - t)
    return min(runs), m


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--holes", type=int, default=8, help="holes per side of the plate (default 8: 64 holes)")
    p.add_argument("--max-level", type=int, default=9)
    p.add_argument("--repeat", type=int, default=2)
    a = p.parse_args(argv)
    bounds = ((-1.2,) * 3, (1.2,) * 3)
    cases = [(f"plate with {a.holes ** 2} holes, min/max", plate(a.holes)), ("part, R-functions", wm.example("part")[0])]
    for name, shape in cases:
        (t_on, m_on), (t_off, m_off) = (best(shape, bounds, a.max_level, pr, a.repeat) for pr in (True, False))
        assert m_on.n_cells == m_off.n_cells, "pruned and whole tapes gave different meshes"
        print(f"{name}, max_level {a.max_level}: tape {m_on.info['tape_length']} instructions; mean per level "
              f"{[lv['mean_tape_length'] for lv in m_on.info['levels']]}")
        print(f"  prune=True {t_on:.3f} s (octree {m_on.info['time']['octree']:.3f} s), prune=False {t_off:.3f} s "
              f"(octree {m_off.info['time']['octree']:.3f} s): whole / pruned = {t_off / t_on:.2f}x; "
              f"{m_on.n_cells} triangles, euler {m_on.stats()['euler']}")


if __name__ == "__main__":
    main()
