"""The brick layout of a bricked run: index ranges of the global grid, cut on block boundaries.

A grid of ``cells = (cx, cy, cz)`` cells is cut into bricks whose cores are ranges of
whole blocks (``kernels.block_grid.BLOCK`` = 8 cells a side), so a brick's blocks are
the global grid's blocks: culled, sampled and emitted exactly as one process would. Two
neighbouring bricks share the node plane between them (the seam); a vertex on an edge
lying in a seam plane is emitted by every brick around it with the same global key
``node * 8 + type`` (:mod:`warpmesh.distributed.seams` welds them).

Example
-------
>>> from warpmesh.distributed.bricks import layout
>>> [b.lo for b in layout((20, 16, 8), bricks=(2, 1, 1))]
[(0, 0, 0), (16, 0, 0)]
>>> [b.hi for b in layout((20, 16, 8), brick_cells=8)][:3]
[(8, 8, 8), (16, 8, 8), (20, 8, 8)]
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warpmesh.kernels import block_grid as KB
from warpmesh.kernels import emit as KE

BLOCK = KB.BLOCK
#: default brick size in cells per side: 128^3 cells, about 9 MB of float32 samples per brick
DEFAULT_BRICK_CELLS = 128


@dataclass(frozen=True)
class Brick:
    """One brick: its id (x fastest), its position in the brick grid, and its core, the
    global cells ``lo <= c < hi`` (its nodes: ``lo`` to ``hi`` inclusive)."""

    index: int
    ijk: tuple[int, int, int]
    lo: tuple[int, int, int]
    hi: tuple[int, int, int]

    def box(self, origin, h) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """The brick's core as a box in world coordinates (float64)."""
        o, s = np.asarray(origin, dtype=np.float64), np.asarray(h, dtype=np.float64)
        return (tuple((o + np.array(self.lo) * s).tolist()), tuple((o + np.array(self.hi) * s).tolist()))

    def describe(self, origin, h) -> str:
        """'brick 3 (1, 1, 0): cells [64:128, 64:128, 0:64], box (x0, y0, z0)-(x1, y1, z1)'."""
        lo, hi = self.box(origin, h)
        cells = ", ".join(f"{a}:{b}" for a, b in zip(self.lo, self.hi))
        return (f"brick {self.index} {self.ijk}: cells [{cells}], box "
                f"({', '.join(f'{v:.6g}' for v in lo)})-({', '.join(f'{v:.6g}' for v in hi)})")


def check_bricking(bricks, brick_cells) -> tuple:
    """The bricking arguments, checked: at most one of them; ``bricks`` three positive ints,
    ``brick_cells`` a positive multiple of the block size."""
    if bricks is not None and brick_cells is not None:
        raise ValueError(f"give 'bricks' or 'brick_cells', not both: got bricks={bricks!r}, "
                         f"brick_cells={brick_cells!r}")
    if bricks is not None:
        try:
            b = np.asarray(bricks)
        except (TypeError, ValueError):
            b = np.asarray([None])
        if b.shape != (3,) or not np.issubdtype(b.dtype, np.integer) or np.any(b < 1):
            raise ValueError(f"expected 'bricks' as three positive ints (bricks per axis), got {bricks!r}")
        bricks = tuple(int(v) for v in b)
    if brick_cells is not None:
        if isinstance(brick_cells, (bool, np.bool_)) or not isinstance(brick_cells, (int, np.integer)) \
                or brick_cells < BLOCK or brick_cells % BLOCK:
            raise ValueError(f"expected 'brick_cells' as a positive multiple of {BLOCK} (bricks are cut on the "
                             f"blocks of {BLOCK}^3 cells), got {brick_cells!r}")
        brick_cells = int(brick_cells)
    return bricks, brick_cells


def refuse_bricking(**given) -> None:
    """The bricking keywords (``bricks``, ``brick_cells``, ``gather``, ``output``, ``progress``)
    mean nothing without a cluster: refuse any that is not its default (``progress=False``,
    no bar, is never wrong: it passes)."""
    defaults = {"bricks": None, "brick_cells": None, "gather": True, "output": None, "progress": True}
    for name, value in given.items():
        if name == "progress" and isinstance(value, (bool, np.bool_)):
            continue
        if value is not defaults[name] and not (isinstance(value, bool) and value == defaults[name]):
            raise ValueError(f"{name!r} applies to a run on a Dask cluster (client=...), got {name}={value!r} "
                             "without 'client'")


def axis_cuts(cells: int, bricks: int | None = None, brick_cells: int | None = None) -> list[int]:
    """Cell indices where the bricks of one axis start, and ``cells`` at the end; every cut
    on a block boundary.

    >>> axis_cuts(100, bricks=3), axis_cuts(100, brick_cells=32)
    ([0, 32, 72, 100], [0, 32, 64, 96, 100])
    """
    if brick_cells is not None:
        return list(range(0, cells, brick_cells)) + [cells]
    nb = -(-cells // BLOCK)
    if bricks > nb:
        raise ValueError(f"expected at most {nb} bricks along an axis of {cells} cells (one block of {BLOCK} "
                         f"cells each) in 'bricks', got {bricks}")
    cuts = [int(v) * BLOCK for v in np.round(np.linspace(0, nb, bricks + 1)).astype(np.int64)]
    cuts[-1] = cells
    return cuts


def layout(cells, bricks=None, brick_cells=None) -> list[Brick]:
    """The bricks of a grid of ``cells`` (3 ints), from bricks per axis or a brick size in
    cells (default :data:`DEFAULT_BRICK_CELLS`), ids x fastest."""
    bricks, brick_cells = check_bricking(bricks, brick_cells)
    if bricks is None and brick_cells is None:
        brick_cells = DEFAULT_BRICK_CELLS
    return bricks_of_cuts([axis_cuts(int(c), None if bricks is None else bricks[a], brick_cells)
                           for a, c in enumerate(cells)])


def bricks_of_cuts(cuts) -> list[Brick]:
    """The bricks between consecutive cuts on each axis (three increasing lists), ids x fastest.

    >>> [b.lo for b in bricks_of_cuts([[0, 2, 4], [0, 3], [0, 1]])]
    [(0, 0, 0), (2, 0, 0)]
    """
    out = []
    for k in range(len(cuts[2]) - 1):
        for j in range(len(cuts[1]) - 1):
            for i in range(len(cuts[0]) - 1):
                out.append(Brick(len(out), (i, j, k), (cuts[0][i], cuts[1][j], cuts[2][k]),
                                 (cuts[0][i + 1], cuts[1][j + 1], cuts[2][k + 1])))
    return out


def key_nodes(keys: np.ndarray, cells) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The global node (m, 3) and direction (m, 3) of each vertex's grid edge, from its key
    ``node * 8 + type``, and which vertices are interior ones (type ``CENTER``, no edge)."""
    cells = np.asarray(cells, dtype=np.int64)
    nx, ny = cells[0] + 1, cells[1] + 1
    kind = keys & 7
    node = (keys >> 3) & ((1 << 53) - 1)  # bits 56 and up: the slot of an interior vertex
    g = np.stack([node % nx, node // nx % ny, node // (nx * ny)], axis=1)
    return g, KE.TYPE_DELTA[kind].astype(np.int64), kind == KE.CENTER


def on_seams(keys: np.ndarray, brick: Brick, cells) -> np.ndarray:
    """Which vertices (by global key ``node * 8 + type``) lie on an edge in a seam plane of
    the brick: a face of its core that is not a face of the whole grid. Interior vertices
    (type ``CENTER``) never do."""
    cells = np.asarray(cells, dtype=np.int64)
    g, delta, interior = key_nodes(keys, cells)
    seam = np.zeros(len(keys), dtype=bool)
    for a in range(3):
        flat = delta[:, a] == 0  # the edge lies in a plane normal to axis a
        for plane in (brick.lo[a], brick.hi[a]):
            if 0 < plane < cells[a]:
                seam |= flat & (g[:, a] == plane)
    return seam & ~interior
