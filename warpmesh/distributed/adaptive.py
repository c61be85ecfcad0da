"""Adaptive meshing on bricks: the octree of ``mesh_surface(shape, adaptive=True, client=...)``.

What runs where. The octree covering-up (:func:`warpmesh.surface.adaptive.octree.build_octree`:
intervals, pruned tapes, corner values, refinement criteria) is built on the workers, brick
by brick; the contouring (face units, crossings, roots, loops, fans, feature flips,
untangle) runs on the client, on the gathered tree, as in one process.

- **Bricks** are boxes of the octree's cells at one level ``b`` (``brick_level``): the
  smallest level at or below the base level whose cells cut the domain into ``bricks`` per
  axis, or whose cells divide ``brick_cells`` finest cells.
- **The client** builds the levels up to ``b`` itself (``build_octree(last_level=b)``: few
  cells). A brick none of whose level-``b`` cells is refined holds no deeper cell: it never
  becomes a task (the intervals of its ancestors or of its own cells culled it).
- **A worker** builds the tree restricted to its brick (``build_octree(window=...)``): the
  cells that meet the brick, each decided by its own interval, corners and ``force``
  membership, so they are the whole tree's cells, with the same node values bit for bit.
  It returns the status of its cells below level ``b`` and f at the nodes it evaluated.
- **The gather** joins the bricks' cells (disjoint) with the client's levels, numbers the
  leaves in the order one process gives (level by level, breadth first from the base
  cells) and unions the node values: the tree is the single-process tree, array for array,
  and so is the mesh contoured from it.
- **Two-sheet rounds** (``force``): after each round the client finds the leaves with two
  loops as one process does; the next round re-submits only the bricks that one of the new
  forced cells meets (or whose coarse cells changed); the other bricks' results are kept.

Not distributed (yet): the faces, roots and fans of the owned leaves (1.3 of 1.9 s for the
part at max_level 10 in one process) run on the client after the gather; ``gather=False``
and ``output`` are refused (untangle and the feature flips need the whole surface). The
next step: a worker also builds the one-cell collar of its brick (the cells whose closed box
touches the brick's: every neighbour across a face, edge or corner of its leaves, so their
hanging nodes) and returns the face units its leaves own, keyed (direction, owner leaf's
cell key, cycle position) for the one-process unit order, with their crossings keyed by
their two node keys (the one-process vertex order) and roots; the leaves at or above the
brick level (one coarse leaf may span bricks) need an owner brick whose window covers them.

Example: :func:`warpmesh.mesh_surface` with ``adaptive=True`` and ``client``;
:func:`brick_grid` for the layout.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass, field

import numpy as np

from warpmesh.distributed.bricks import DEFAULT_BRICK_CELLS, Brick, check_bricking
from warpmesh.distributed.run import brick_error, run_job, worker_tape
from warpmesh.errors import WarpMeshError
from warpmesh.surface.adaptive.octree import (CELL_BITS, LEAF, INTERNAL, NodeStore, Octree, build_octree, finest_cells,
                                              in_window)

__all__ = ["OctreePiece", "BrickedOctree", "brick_grid", "merge_pieces", "breadth_first_order"]


@dataclass
class OctreePiece:
    """One brick's part of the octree below the brick level: its cells' keys (sorted,
    :func:`~warpmesh.surface.adaptive.octree.cell_keys`) and status, f at the nodes it
    evaluated (sorted node keys, float32 values), the per-level statistics of its cells, and
    ``info`` (counts, timings)."""

    keys: np.ndarray
    status: np.ndarray
    node_keys: np.ndarray
    node_values: np.ndarray
    levels: list
    info: dict = field(default_factory=dict)


def split_keys(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(level (n,), ijk (n, 3)) of cell keys.

    >>> from warpmesh.surface.adaptive.octree import cell_keys
    >>> lv, ijk = split_keys(cell_keys(np.array([4]), np.array([[3, 5, 7]])))
    >>> lv.tolist(), ijk.tolist()
    ([4], [[3, 5, 7]])
    """
    keys = np.asarray(keys, dtype=np.int64)
    mask = (1 << CELL_BITS) - 1
    ijk = np.stack([(keys >> (2 * CELL_BITS)) & mask, (keys >> CELL_BITS) & mask, keys & mask], axis=1)
    return keys >> (3 * CELL_BITS), ijk


def breadth_first_order(level: np.ndarray, ijk: np.ndarray, base: int, n0) -> np.ndarray:
    """Each cell's rank key within its level in the order :func:`build_octree` makes a level:
    the base cells row-major (x slowest), then each parent's 8 children in corner order
    (x + 2 y + 4 z), parents in their own order.

    >>> breadth_first_order(np.array([4, 4, 4]), np.array([[1, 0, 0], [0, 1, 0], [0, 0, 2]]), 3, (2, 2, 2)).tolist()
    [1, 2, 8]
    >>> breadth_first_order(np.array([5, 5]), np.array([[2, 1, 0], [1, 2, 0]]), 3, (2, 2, 2)).tolist()
    [10, 17]
    """
    level = np.asarray(level, dtype=np.int64)
    ijk = np.asarray(ijk, dtype=np.int64)
    n0 = np.asarray(n0, dtype=np.int64)
    depth = level - base
    root = ijk >> depth[:, None]
    key = (root[:, 0] * n0[1] + root[:, 1]) * n0[2] + root[:, 2]
    for d in range(1, int(depth.max()) + 1 if len(depth) else 1):  # the refinements from the base down
        here = depth >= d
        bit = (ijk[here] >> (depth[here] - d)[:, None]) & 1
        key[here] = key[here] * 8 + bit[:, 0] + 2 * bit[:, 1] + 4 * bit[:, 2]
    return key


def brick_grid(n_base, base: int, max_level: int, bricks=None, brick_cells=None):
    """The brick level ``b`` and the bricks (:class:`~warpmesh.distributed.bricks.Brick`,
    ``lo``/``hi`` in level-``b`` cells, ids x fastest) of an octree with ``n_base`` base cells
    per axis at level ``base``.

    ``bricks``: bricks per axis (the smallest level with at least that many cells per axis);
    ``brick_cells``: finest cells per brick side (the smallest level whose cells divide it;
    default 128).

    >>> b, bs = brick_grid((8, 8, 2), 3, 7, bricks=(2, 2, 1))
    >>> b, len(bs), bs[1].lo, bs[1].hi
    (3, 4, (4, 0, 0), (8, 4, 2))
    >>> brick_grid((8, 8, 2), 3, 7, brick_cells=32)[0], brick_grid((8, 8, 2), 3, 7, brick_cells=8)[0]
    (3, 4)
    """
    if bricks is not None and brick_cells is not None:
        check_bricking(bricks, brick_cells)  # raises: not both
    bricks, _ = check_bricking(bricks, None)
    n_base = np.asarray(n_base, dtype=np.int64)
    if brick_cells is not None:
        if isinstance(brick_cells, (bool, np.bool_)) or not isinstance(brick_cells, (int, np.integer)) \
                or brick_cells < 1:
            raise ValueError(f"expected 'brick_cells' as a positive int (finest cells per brick side), "
                             f"got {brick_cells!r}")
    elif bricks is None:
        brick_cells = DEFAULT_BRICK_CELLS
    if bricks is not None:
        level = next((lv for lv in range(base, max_level) if np.all(n_base << (lv - base) >= bricks)), None)
        if level is None:
            raise ValueError(f"expected at most {(n_base << (max_level - 1 - base)).tolist()} bricks per axis in "
                             f"'bricks' (cells one level above max_level={max_level}), got {bricks}")
        n = n_base << (level - base)
        cuts = [np.round(np.linspace(0, n[a], bricks[a] + 1)).astype(np.int64).tolist() for a in range(3)]
    else:
        level = next((lv for lv in range(base, max_level) if brick_cells % (1 << (max_level - lv)) == 0), None)
        if level is None:
            raise ValueError(f"expected 'brick_cells' as a multiple of 2 finest cells (a brick is a box of cells "
                             f"above the finest level), got {brick_cells}")
        n = n_base << (level - base)
        side = brick_cells >> (max_level - level)
        cuts = [list(range(0, int(n[a]), side)) + [int(n[a])] for a in range(3)]
    out = []
    for k in range(len(cuts[2]) - 1):
        for j in range(len(cuts[1]) - 1):
            for i in range(len(cuts[0]) - 1):
                out.append(Brick(len(out), (i, j, k), (cuts[0][i], cuts[1][j], cuts[2][k]),
                                 (cuts[0][i + 1], cuts[1][j + 1], cuts[2][k + 1])))
    return level, out


class BrickedOctree:
    """A drop-in for :func:`build_octree` in :func:`warpmesh.surface.adaptive.pipeline.mesh_adaptive`
    (``build=``): each call (one round) builds the levels down to the brick level on the
    client and the deeper ones on the cluster, brick by brick, merged into the single-process
    tree. ``info`` counts the bricks, tasks and rounds. With ``client=None`` the bricks' tasks
    run in this process, one after another (the same tree: a check of the merge)."""

    def __init__(self, shape, lo, hi, max_level: int, *, client, bricks, brick_cells, progress):
        self.shape, self.client, self.progress = shape, client, progress
        self.base, n_base, _ = finest_cells(np.asarray(lo, np.float64), np.asarray(hi, np.float64), max_level)
        self.level, self.bricks = brick_grid(n_base, self.base, max_level, bricks, brick_cells)
        self.n_level = np.asarray(n_base, np.int64) << (self.level - self.base)  # cells per axis at the brick level
        self.token = uuid.uuid4().hex
        self.results: dict = {}  # brick id -> (its force keys, OctreePiece) of the latest round that built it
        self.info = {"brick_level": self.level, "bricks": len(self.bricks), "bricks_culled": 0,
                     "brick_tasks": 0, "brick_cpu_time": 0.0, "bricks_per_round": []}

    def __call__(self, tape, lo, hi, *, force=None, device="cpu", **build) -> Octree:
        t0 = time.perf_counter()
        self.lo, self.hi, self.build_kw, self.device = lo, hi, build, str(device)
        force = np.zeros(0, np.int64) if force is None else np.asarray(force, np.int64)
        coarse = build_octree(tape, lo, hi, **build, force=force, last_level=self.level, device=device)
        keys, status, _ = coarse.status
        lv, ijk = split_keys(keys)
        open_cells = ijk[(lv == self.level) & (status == INTERNAL)]  # cells refined below the brick level
        f_level, f_ijk = split_keys(force)
        todo, kept = [], []
        for brick in self.bricks:
            window = (self.level, brick.lo, brick.hi)
            if not in_window(self.level, open_cells, window).any():
                continue
            mine = np.zeros(len(force), bool)
            for lvl in np.unique(f_level):
                sel = f_level == lvl
                mine[sel] = in_window(int(lvl), f_ijk[sel], window)
            forced = force[mine]
            old = self.results.get(brick.index)
            if old is not None and np.array_equal(old[0], forced):
                kept.append(brick.index)
            else:
                todo.append((brick, forced))
        if not self.info["bricks_per_round"]:
            self.info["bricks_culled"] = len(self.bricks) - len(todo)
        self.info["bricks_per_round"].append(len(todo))
        job = _OctreeJob(self, dict(todo))
        if self.client is None or not todo:  # in this process, brick after brick (the tests' check of the merge)
            results = {b.index: job.task(b, None, True) for b in job.bricks_to_mesh()}
        else:
            results, _ = run_job(self.client, job, None, True, self.progress, t0)
        for index, piece in results.items():
            self.results[index] = (job.force[index], piece)
        pieces = [self.results[i][1] for i in sorted(set(kept) | set(results))]
        self.info["brick_tasks"] += len(results)
        self.info["brick_cpu_time"] += float(sum(p.info["time"] for p in results.values()))
        counts = coarse.field.counts
        for p in pieces:  # the evaluations of this tree's bricks (coarse cells of their windows included)
            for k in counts:
                counts[k] += p.info["counts"][k]
        return merge_pieces(coarse, pieces, self.level)


class _OctreeJob:
    """One round's bricks for :func:`warpmesh.distributed.run.run_job`: the worker's task."""

    has_refs = False
    key_array = None
    data = ()

    def __init__(self, owner: BrickedOctree, todo: dict):
        self.shape, self.token, self.device = owner.shape, owner.token, owner.device
        self.lo, self.hi, self.build_kw, self.level = owner.lo, owner.hi, owner.build_kw, owner.level
        self.h_level = (owner.hi - owner.lo) / owner.n_level  # the size of the brick level's cells
        self.todo = list(todo)
        self.force = {b.index: f for b, f in todo.items()}

    def bricks_to_mesh(self) -> list[Brick]:
        return self.todo

    def task(self, brick: Brick, path, want: bool) -> OctreePiece:
        """On a worker: the octree restricted to the brick, its cells below the brick level."""
        t0 = time.perf_counter()
        tape = worker_tape(self.token, self.shape)
        try:
            tree = build_octree(tape, self.lo, self.hi, **self.build_kw, force=self.force[brick.index],
                                window=(self.level, brick.lo, brick.hi), device=self.device)
        except ValueError as exc:
            raise brick_error(brick, self.lo, self.h_level, exc) from None
        keys, status, _ = tree.status
        deep = (keys >> (3 * CELL_BITS)) > self.level
        levels = [lv for lv in tree.levels if lv["level"] > self.level]
        info = {"cells": int(deep.sum()), "leaves": int((tree.leaf_level > self.level).sum()),
                "counts": dict(tree.field.counts), "time": time.perf_counter() - t0}
        # every node the brick evaluated (sorted already; sorting out its leaves' corners costs more
        # than sending the rest)
        return OctreePiece(keys[deep], status[deep], tree.nodes.keys, tree.nodes.values, levels, info)


def merge_pieces(coarse: Octree, pieces: list[OctreePiece], level: int) -> Octree:
    """The whole tree from the client's levels up to ``level`` (``coarse``) and the bricks'
    deeper cells: cells joined (each cell in one piece), leaves numbered level by level in
    breadth-first order (:func:`breadth_first_order`), as :func:`build_octree` numbers them,
    node values unioned (a node held by several pieces must have one value)."""
    ck, cs, _ = coarse.status
    keys = np.concatenate([ck] + [p.keys for p in pieces])
    status = np.concatenate([cs] + [p.status for p in pieces])
    order = np.argsort(keys)
    keys, status = keys[order], status[order]
    if len(keys) > 1 and np.any(keys[1:] == keys[:-1]):
        raise WarpMeshError("two bricks built one octree cell (an internal error)")
    leaf = np.flatnonzero(status == LEAF)
    lv, ijk = split_keys(keys[leaf])
    n0 = coarse.n_finest >> (coarse.max_level - coarse.base_level)
    rank = np.lexsort((breadth_first_order(lv, ijk, coarse.base_level, n0), lv))
    leaf_of = np.full(len(keys), -1, np.int64)
    leaf_of[leaf[rank]] = np.arange(len(leaf))
    nk = np.concatenate([coarse.nodes.keys] + [p.node_keys for p in pieces])
    nv = np.concatenate([coarse.nodes.values] + [p.node_values for p in pieces])
    uniq, first, inverse = np.unique(nk, return_index=True, return_inverse=True)
    if not np.array_equal(nv, nv[first][inverse.reshape(-1)]):
        raise WarpMeshError("two bricks evaluated f differently at one node (an internal error)")
    nodes = NodeStore()
    nodes.keys, nodes.values = uniq, nv[first]
    levels = [dict(lv_) for lv_ in coarse.levels if lv_["level"] <= level]
    deeper: dict = {}
    for p in pieces:
        for lv_ in p.levels:
            acc = deeper.setdefault(lv_["level"], {k: 0 for k in lv_})
            for k, v in lv_.items():
                if k == "mean_tape_length":  # weighted by cells
                    acc[k] += v * lv_["cells"]
                elif k != "level":
                    acc[k] += v
    for lvl in sorted(deeper):
        acc = deeper[lvl]
        acc["level"], acc["mean_tape_length"] = lvl, round(acc["mean_tape_length"] / max(acc["cells"], 1), 2)
        levels.append(acc)
    return Octree(coarse.origin, coarse.h, coarse.n_finest, coarse.max_level, coarse.base_level, coarse.cap,
                  lv[rank], ijk[rank], (keys, status, leaf_of), nodes, coarse.field, levels)
