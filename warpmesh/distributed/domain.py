"""Bricked isosurface stuffing on a Dask cluster: what ``mesh_domain(..., client=...)`` runs.

The BCC lattice of :func:`warpmesh.solid.stuffing.stuff` is global, and so are its ids: a
node is ``2 cell + colour``, a lattice edge ``14 cell + slot``. Its black nodes are cut into
bricks (:func:`warpmesh.distributed.bricks.layout` over the lattice's black nodes per axis).
A brick owns the background tetrahedra of its black nodes; a worker runs every stage of
stuffing up to the fill (f at the nodes, signs, cut points, warp, stencils) on a window of
the global lattice with a halo of :data:`~warpmesh.solid.stuffing.WINDOW_HALO` cells, so each
owned tetrahedron sees the neighbours it has in the whole lattice, and emits the owned
tetrahedra only, at the global nodes' float32 positions, each vertex keyed by its global id
(:func:`warpmesh.solid.stuffing.stuff_window`). The client joins the copies by key (an exact
join on integers, no tolerance) and numbers the vertices and tetrahedra in key order, which
is the order one process gives: the gathered stuffing is the single-process one, array for
array, and the host stages after it (boundary, features, smoothing, flips) run on it as in
one process.

Bricks whose nodes the shape's interval over their box proves outside (f < 0), or that lie
outside the bounds, hold no tetrahedron and never become tasks.

Example: :func:`warpmesh.solid.pipeline.mesh_domain` with ``client``.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass, field

import numpy as np

from warpmesh.distributed.bricks import Brick, layout
from warpmesh.distributed.output import LATTICE_KEY_ARRAY, write_piece
from warpmesh.distributed.run import (BrickJob, brick_error, check_run, interval_signs, partitioned, run_job,
                                      summarize, worker_tape)
from warpmesh.solid.stuffing import lattice_for, stuff_window

__all__ = ["LatticeBrick", "stuff_bricks"]


@dataclass
class LatticeBrick:
    """One brick's tetrahedra: points (n, 3) float32 relative to the lattice's origin,
    tetrahedra (m, 4) int32 into them, the on-surface flags (n,) bool, the vertices' global
    keys (n,) int64 (increasing), and the tetrahedra's global black nodes as runs: the black
    nodes (k,) int64 (increasing) and how many tetrahedra each has (k,) int64, in the order of
    ``tets``; ``info`` the brick's counts and timings."""

    points: np.ndarray
    tets: np.ndarray
    on_surface: np.ndarray
    keys: np.ndarray
    cells: np.ndarray
    counts: np.ndarray
    info: dict = field(default_factory=dict)


def stuff_bricks(shape, box: np.ndarray, h: float, stuffing: dict, *, client, bricks=None, brick_cells=None,
                 gather: bool = True, output=None, progress=True, device: str = "cpu"):
    """Isosurface stuffing of ``shape`` in ``box`` (cube side ``h``), brick by brick on a Dask
    cluster (already validated arguments; :func:`warpmesh.solid.pipeline.mesh_domain` is the
    public entry point).

    ``stuffing``: ``alpha_long``, ``alpha_short``, ``iterations``. ``bricks`` / ``brick_cells``
    cut the lattice's black nodes (``brick_cells`` a multiple of 8).

    Returns
    -------
    (points (n, 3) float64, tets (m, 4) int64, on_surface (n,) bool, info) as
    :func:`warpmesh.solid.stuffing.stuff` returns them, the same arrays, with ``gather=True``;
    a :class:`~warpmesh.distributed.run.PartitionedMesh` of VTU pieces with ``gather=False``
    (each piece the tetrahedra of one brick, the point array ``lattice_key`` the vertices'
    global keys, equal in every piece that holds a vertex).
    """
    where = check_run(client, gather, output, progress)
    t_start = time.perf_counter()
    job = _DomainJob(shape, box, h, stuffing, device, bricks, brick_cells)
    results, timings = run_job(client, job, where, gather, progress, t_start)
    info = {"lattice": tuple(int(d) for d in job.dims), "cube_size": float(h),
            "lattice_nodes": 2 * int(np.prod(job.dims)), "alpha_long": float(stuffing["alpha_long"]),
            "alpha_short": float(stuffing["alpha_short"]), "bricks": len(job.bricks), "bricks_culled": job.skipped,
            "brick_cull_time": job.cull_time}
    per = summarize(results, info)
    info.update(cut_edges=sum(p["cut_edges"] for p in per), warped_nodes=sum(p["warped_nodes"] for p in per))
    if not gather:
        return partitioned(results, where, timings, t_start, info)
    t0 = time.perf_counter()
    points, tets, on_surface = gather_keyed([results[i] for i in sorted(results)], job.origin)
    info["seam_copies_welded"] = int(sum(p["vertices"] for p in per)) - len(points)
    timings["weld"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    info.update(time=timings, time_stuffing=timings["total"])
    return points, tets, on_surface, info


def gather_keyed(pieces: list[LatticeBrick], origin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One mesh from bricks whose every vertex carries its global key: the copies of a key
    joined, the vertices numbered by increasing key and the tetrahedra ordered by their black
    node (each node's in the order its brick gives), as the whole lattice orders them.
    Returns points (n, 3) float64 (``origin`` + the float32 offsets, added in float64),
    tetrahedra (m, 4) int64 and on-surface flags.

    >>> import numpy as np
    >>> a = LatticeBrick(np.zeros((4, 3), np.float32), np.array([[0, 1, 2, 3]]), np.ones(4, bool),
    ...                  np.array([2, 5, 7, 9]), np.array([4]), np.array([1]))
    >>> b = LatticeBrick(np.ones((4, 3), np.float32), np.array([[0, 1, 2, 3]]), np.ones(4, bool),
    ...                  np.array([1, 2, 5, 7]), np.array([3]), np.array([1]))
    >>> points, tets, _ = gather_keyed([a, b], np.zeros(3))
    >>> len(points), tets.tolist()
    (5, [[0, 1, 2, 3], [1, 2, 3, 4]])
    """
    starts = np.concatenate([[0], np.cumsum([len(p.keys) for p in pieces], dtype=np.int64)])
    keys = np.concatenate([p.keys for p in pieces] or [np.zeros(0, np.int64)])
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    points = np.concatenate([p.points for p in pieces] or [np.zeros((0, 3), np.float32)])[first].astype(np.float64)
    points += np.asarray(origin, dtype=np.float64)
    on_surface = np.concatenate([p.on_surface for p in pieces] or [np.zeros(0, bool)])[first]
    # runs of one black node, moved to the black nodes' order (a node's run is in one brick)
    cells = np.concatenate([p.cells for p in pieces] or [np.zeros(0, np.int64)])
    counts = np.concatenate([p.counts for p in pieces] or [np.zeros(0, np.int64)]).astype(np.int64)
    order = np.argsort(cells)
    at = np.concatenate([[0], np.cumsum(counts)])
    to = np.empty_like(counts)
    to[order] = np.concatenate([[0], np.cumsum(counts[order])])[:-1]
    shift = np.repeat(to - at[:-1], counts)  # per tetrahedron: where it goes - where it is
    tets = np.empty((int(at[-1]), 4), dtype=np.int64)
    done = 0
    for p, s in zip(pieces, starts):  # one piece at a time: no copy of all the tetrahedra but the result
        rows = np.arange(done, done + len(p.tets))
        tets[rows + shift[rows]] = inverse[p.tets + s]
        done += len(p.tets)
    return points, tets, on_surface


class _DomainJob(BrickJob):
    """Stuffing on bricks of the lattice: the layout, the client-side culling, the worker's task."""

    has_refs = False
    key_array = LATTICE_KEY_ARRAY
    data = ()

    def __init__(self, shape, box: np.ndarray, h: float, stuffing: dict, device: str, bricks, brick_cells):
        self.shape, self.box, self.h, self.stuffing = shape, np.asarray(box, np.float64), h, stuffing
        self.device = str(device)  # a name: a Warp device object does not pickle
        self.token = uuid.uuid4().hex
        self.dims, self.origin = lattice_for(self.box, h)
        self.bricks = layout(self.dims, bricks, brick_cells)

    def bricks_to_mesh(self) -> list[Brick]:
        """The bricks that may hold a tetrahedron: the nodes of their background tetrahedra
        (black nodes lo to hi, red ones lo - 1/2 to hi - 1/2; one cell of margin) are not all
        proven outside by the shape's interval, and their box meets the bounds."""
        t0 = time.perf_counter()
        lo = np.array([b.lo for b in self.bricks], dtype=np.float64) - 1.0
        hi = np.array([b.hi for b in self.bricks], dtype=np.float64) + 1.0
        box_lo, box_hi = self.origin + lo * self.h, self.origin + hi * self.h
        outside, _ = interval_signs(self.shape, box_lo.astype(np.float32), box_hi.astype(np.float32))
        away = (box_hi < self.box[0]).any(axis=1) | (box_lo > self.box[1]).any(axis=1)
        empty = outside | away
        self.skipped = int(empty.sum())
        self.cull_time = time.perf_counter() - t0
        return [b for b, e in zip(self.bricks, empty) if not e]

    def task(self, brick: Brick, path, want: bool) -> LatticeBrick:
        """On a worker: the tetrahedra of the brick's black nodes, on a window of the lattice."""
        t0 = time.perf_counter()
        tape = worker_tape(self.token, self.shape)
        s = self.stuffing
        try:
            local, tets, surf, keys, owner, origin, stats = stuff_window(
                tape, self.box, self.h, brick.lo, brick.hi, alpha_long=s["alpha_long"], alpha_short=s["alpha_short"],
                iterations=s["iterations"], device=self.device)
        except ValueError as exc:
            raise brick_error(brick, self.origin, self.h, exc) from None
        points = local.astype(np.float32)  # exact: the float32 positions of the lattice's kernels
        if path is not None and len(tets):
            write_piece(path, points + origin, tets, None, keys, key=LATTICE_KEY_ARRAY)
        info = {"vertices": len(points), "cells": len(tets),
                "evaluations": stats["window_nodes"] + s["iterations"] * stats["window_cut_edges"],
                "cut_edges": stats["cut_edges"], "warped_nodes": stats["warped_nodes"],
                "time": {"stuffing": stats["time_stuffing"], "total": time.perf_counter() - t0}}
        if not want:
            return LatticeBrick(np.zeros((0, 3), np.float32), np.zeros((0, 4), np.int32), np.zeros(0, bool),
                                np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64), info)
        cells, counts = np.unique(owner, return_counts=True)
        return LatticeBrick(points, tets.astype(np.int32), surf, keys, cells, counts, info)
