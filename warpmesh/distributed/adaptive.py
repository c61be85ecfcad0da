"""Adaptive meshing on bricks: the octree of ``mesh_surface(shape, adaptive=True, client=...)``.

What runs where. The octree covering-up (:func:`warpmesh.surface.adaptive.octree.build_octree`:
intervals, pruned tapes, corner values, refinement criteria) and the first half of the
contouring (face units, boundary cycles with their hanging nodes, crossings, Newton roots on
the exact f, normals) run on the workers, brick by brick; the client joins them and runs what
needs the whole surface: the loops (and the two-sheet rounds they decide), fans, feature
flips and untangle.

- **Bricks** are boxes of the octree's cells at one level ``b`` (``brick_level``): the
  smallest level at or below the base level whose cells cut the domain into ``bricks`` per
  axis, or whose cells divide ``brick_cells`` finest cells.
- **The client** builds the levels up to ``b`` itself (``build_octree(last_level=b)``: few
  cells). A brick none of whose level-``b`` cells is refined or a leaf holds no leaf it owns:
  it never becomes a task (the intervals of its ancestors or of its own cells culled it).
- **A worker** builds the tree restricted to its brick and the brick's one-cell collar
  (``build_octree(window=..., collar=True)``: the cells that meet the brick or whose closed box
  touches it, each decided by its own interval, corners and ``force`` membership, so they are
  the whole tree's cells, with the same node values bit for bit). The collar holds every leaf
  across a face, edge or corner of the brick's leaves, so the face units of the leaves the
  brick owns (those at level ``b`` or deeper inside it, :func:`owned_leaves`) and their hanging
  nodes are the whole tree's: the worker computes them, their crossings, roots and normals
  (:func:`contour_window`). It returns its own cells below level ``b`` (not the collar's, not
  the node values: the client needs none) and the contouring, keyed (:class:`CrossingPiece`).
- **Leaves above the brick level** (cap leaves, leaves above ``min_level``) may span bricks:
  the client contours them, each level's on one window of those cells and their collar
  (``window=(level, cells)``); they are few (``info["coarse_leaves"]``).
- **The gather** joins the bricks' cells (disjoint) with the client's levels and numbers the
  leaves in the order one process gives (level by level, breadth first from the base cells);
  :func:`join_crossings` sorts the face units by (direction, owner leaf) as
  :func:`~warpmesh.surface.adaptive.contour.face_units` makes them, numbers the crossings by
  their two node keys as :func:`~warpmesh.surface.adaptive.contour.unit_segments` does (a crossing
  on a seam, found by two bricks, must be the same point: a root is a function of its edge)
  and the segments by unit in cycle order: the single-process arrays, so the mesh is the
  single-process mesh.
- **Two-sheet rounds** (``force``): after each round the client finds the leaves with two
  loops as one process does; the next round re-submits only the bricks that one of the new
  forced cells touches (its cells or its collar's: the hanging nodes of its leaves); the other
  bricks' results are kept.

Measured (``python benchmarks/bench_distributed.py --cases adaptive``, the part at max_level
10, bricks of 512 finest cells: 8 tasks, 315,472 triangles, three runs 2026-12-03 09:41-09:42
UTC, load average 3.6 to 4.1 on the 2 cores from other engineers' jobs): the client spends
1.36-1.43 CPU s, 0.58-0.71 of one process's 1.99-2.34 (it was 1.7-2.2 CPU s with the contouring
on the client), the workers 1.44-1.56 CPU s; 0.27-0.28 GB per worker against 0.49 GB for one
process. The wall times under that load say little (0.71x-1.08x one process's): the client's
share is serial, mostly untangle's global intersection check (0.9-1.1 s) and the fans.
Not distributed (yet): the loops, fans, feature flips and untangle (they read the whole
surface; a brick could run them on the loops of its own leaves, with its neighbours' triangles
for the intersection check); ``gather=False`` and ``output`` are refused.

Example: :func:`warpmesh.mesh_surface` with ``adaptive=True`` and ``client``;
:func:`brick_grid` for the layout.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass, field

import numpy as np

from warpmesh.distributed.bricks import DEFAULT_BRICK_CELLS, Brick, bricks_of_cuts, check_bricking
from warpmesh.distributed.run import brick_error, run_job, worker_tape
from warpmesh.errors import WarpMeshError
from warpmesh.surface.adaptive import contour as OC
from warpmesh.surface.adaptive.octree import (CELL_BITS, LEAF, INTERNAL, NodeStore, Octree, build_octree, cell_keys,
                                              finest_cells, in_window, search)
from warpmesh.surface.adaptive.pipeline import crossing_roots

__all__ = ["OctreePiece", "CrossingPiece", "BrickedOctree", "brick_grid", "merge_pieces", "breadth_first_order",
           "contour_window", "join_crossings"]


@dataclass
class CrossingPiece:
    """The contouring of the leaves one window owns, keyed for the single-process order.

    Face units (u,): ``direction`` (2 axis + (side > 0), the order :func:`~warpmesh.surface.adaptive.contour.face_units`
    makes them in), ``owner`` (cell key of the leaf whose whole face the unit is), ``minus``
    and ``plus`` (cell keys of the leaves on its sides). Crossings (v,): ``vertex_keys``
    (v, 2) their edge's two node keys, smaller first, ``points`` and ``normals`` (v, 3)
    float64, ``cap_vertex``. ``segments`` (s, 3): local unit, start and end crossing, in
    the order of the units' boundary cycles. ``evaluations``: the root finding's."""

    direction: np.ndarray
    owner: np.ndarray
    minus: np.ndarray
    plus: np.ndarray
    vertex_keys: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    cap_vertex: np.ndarray
    segments: np.ndarray
    evaluations: int = 0


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
    crossings: CrossingPiece | None = None
    order: np.ndarray | None = None  # the cells' breadth-first keys (:func:`breadth_first_order`), if sent


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
    return level, bricks_of_cuts(cuts)


def owned_leaves(tree: Octree, window) -> np.ndarray:
    """Which leaves of ``tree`` a window ``(level, lo, hi)`` (or ``(level, cells)``,
    :func:`~warpmesh.surface.adaptive.octree.in_window`) owns: those at its level or deeper
    that lie in it (a coarser leaf may span windows: none owns it).

    >>> from warpmesh.surface.adaptive.octree import Octree
    >>> t = Octree(None, None, None, 5, 3, True, np.array([3, 4, 5]), np.array([[1, 0, 0], [1, 0, 0], [9, 0, 0]]),
    ...            (), None, None)
    >>> owned_leaves(t, (4, (0, 0, 0), (2, 2, 2))).tolist()
    [False, True, False]
    """
    out = np.zeros(len(tree.leaf_level), bool)
    for level in np.unique(tree.leaf_level[tree.leaf_level >= window[0]]):
        sel = np.flatnonzero(tree.leaf_level == level)
        out[sel] = in_window(int(level), tree.leaf_ijk[sel], window)
    return out


def contour_window(tape, tree: Octree, window, roots: dict, device="cpu") -> CrossingPiece:
    """The face units, crossings, roots and normals of the leaves a window owns
    (:func:`owned_leaves`), on a tree built with ``collar=True`` for that window (so every
    leaf across their faces, edges and corners is there: their units and hanging nodes are
    the whole tree's). ``roots``: the root options (root, root_iterations, gradient).

    Each face unit is computed by the leaf whose whole face it is, and each crossing is a
    function of its edge, so the pieces of all windows joined by key
    (:func:`join_crossings`) are the single-process arrays.

    Example
    -------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.tape import tape_of
    >>> lo, hi, w = np.full(3, -1.2), np.full(3, 1.2), (3, (0, 0, 0), (2, 8, 8))  # x from -1.2 to -0.6
    >>> t = build_octree(tape_of(wm.sphere(1.0)), lo, hi, max_level=5, min_level=None, tolerance=None, window=w,
    ...                  collar=True)
    >>> p = contour_window(tape_of(wm.sphere(1.0)), t, w, dict(root="newton", root_iterations=None, gradient="exact"))
    >>> bool(np.all(p.points[:, 0] <= -0.6 + 1e-6)), len(p.segments) > 0
    (True, True)
    """
    axis, origin, size, minus, plus, owner, side = OC.face_units(tree)
    sel = np.flatnonzero(owned_leaves(tree, window)[owner])
    axis, origin, size, minus, plus, owner, side = (a[sel] for a in (axis, origin, size, minus, plus, owner, side))
    key = lambda leaf: cell_keys(tree.leaf_level[leaf], tree.leaf_ijk[leaf])  # noqa: E731
    node_of, ptr, node_keys = OC.boundary_cycles(tree, axis, owner, side)
    values, capped, vnodes, segments = OC.unit_segments(tree, axis, origin, size, node_of, ptr, node_keys)
    evaluations = tree.field.counts["evaluations"]
    if len(vnodes):
        points, fg, _ = crossing_roots(tape, tree, vnodes, node_keys, values, capped, device=device, timings={},
                                       **roots)
        normals, cap_vertex = OC.vertex_normals(tree, points, vnodes, node_keys, capped, fg)
    else:
        points, normals, cap_vertex = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, bool)
    return CrossingPiece((2 * axis + (side > 0)).astype(np.int8), key(owner), key(minus), key(plus),
                         node_keys[vnodes], points, normals, cap_vertex, segments,
                         tree.field.counts["evaluations"] - evaluations)


def join_crossings(tree: Octree, pieces: list[CrossingPiece]):
    """The windows' contourings joined into the single-process arrays of ``tree`` (the
    merged tree: its leaf numbering): units sorted by (direction, owner leaf), crossings by
    their two node keys (a crossing found by two windows must be the same point), segments
    by unit, in cycle order. Returns (minus, plus (u,) leaf indices, segments (s, 3), u,
    points, normals, cap_vertex, root evaluations)."""
    keys, status, leaf_of = tree.status
    if not pieces:
        pieces = [CrossingPiece(*(np.zeros(0, np.int64),) * 4, np.zeros((0, 2), np.int64), np.zeros((0, 3)),
                                np.zeros((0, 3)), np.zeros(0, bool), np.zeros((0, 3), np.int64))]
    cat = lambda name: np.concatenate([getattr(p, name) for p in pieces])  # noqa: E731

    def leaf(cells):
        pos = np.minimum(search(keys, cells), len(keys) - 1)
        if not np.all((keys[pos] == cells) & (status[pos] == LEAF)):
            raise WarpMeshError("a brick's face unit names a cell that is no leaf of the tree (an internal error)")
        return leaf_of[pos]

    owner = leaf(cat("owner"))
    order = np.argsort(cat("direction").astype(np.int64) * max(len(tree.leaf_level), 1) + owner, kind="stable")
    unit_key = (cat("direction").astype(np.int64) * max(len(tree.leaf_level), 1) + owner)[order]
    if len(unit_key) > 1 and np.any(unit_key[1:] == unit_key[:-1]):
        raise WarpMeshError("two bricks contoured one face unit (an internal error)")
    unit_rank = np.empty(len(order), np.int64)
    unit_rank[order] = np.arange(len(order))
    vk = np.concatenate([p.vertex_keys for p in pieces]).reshape(-1, 2)
    vo = np.lexsort((vk[:, 1], vk[:, 0]))
    new = np.ones(len(vo), bool)
    new[1:] = np.any(vk[vo][1:] != vk[vo][:-1], axis=1)
    vid = np.empty(len(vo), np.int64)
    vid[vo] = np.cumsum(new) - 1
    first = vo[new]
    all_points = np.concatenate([p.points for p in pieces]).reshape(-1, 3)
    points = all_points[first]
    if not np.array_equal(all_points, points[vid]):
        raise WarpMeshError("two bricks found different roots on one crossing edge (an internal error)")
    normals = np.concatenate([p.normals for p in pieces]).reshape(-1, 3)[first]
    cap_vertex = cat("cap_vertex")[first]
    segs, u_off, v_off = [], 0, 0
    for p in pieces:
        segs.append(p.segments.reshape(-1, 3) + np.array([u_off, v_off, v_off]))
        u_off, v_off = u_off + len(p.owner), v_off + len(p.points)
    seg = np.concatenate(segs) if segs else np.zeros((0, 3), np.int64)
    seg = np.stack([unit_rank[seg[:, 0]], vid[seg[:, 1]], vid[seg[:, 2]]], axis=1)
    seg = seg[np.argsort(seg[:, 0], kind="stable")]
    plus_side = (cat("direction") % 2 == 1)[order]  # the owner is the minus leaf of a unit on its + side
    other = leaf(np.where(plus_side, cat("plus")[order], cat("minus")[order]))
    mine = owner[order]
    return (np.where(plus_side, mine, other), np.where(plus_side, other, mine), seg, len(order), points, normals,
            cap_vertex, int(sum(p.evaluations for p in pieces)))


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

    def __call__(self, tape, lo, hi, *, force=None, device="cpu", roots=None, **build) -> Octree:
        """One round's tree; with ``roots`` (the root options) each task also contours the leaves
        its brick owns (:func:`contour_window`, on its brick and the brick's collar), and the
        leaves above the brick level are contoured here, each on its own window:
        :meth:`join_crossings` then gives the round's face units, crossings and roots."""
        t0 = time.perf_counter()
        settings = (tuple(np.asarray(lo, np.float64).tolist()), tuple(np.asarray(hi, np.float64).tolist()),
                    repr(sorted(build.items())), str(device), repr(roots))
        if settings != getattr(self, "_settings", None):  # other settings: the kept results would differ
            self.results = {}
        self._settings = settings
        self.lo, self.hi, self.build_kw, self.device, self.roots = lo, hi, build, str(device), roots
        force = np.zeros(0, np.int64) if force is None else np.asarray(force, np.int64)
        self.force = force  # the last round's forced cells
        coarse = build_octree(tape, lo, hi, **build, force=force, last_level=self.level, device=device)
        keys, status, _ = coarse.status
        lv, ijk = split_keys(keys)
        # cells refined below the brick level; contouring, also the brick level's leaves (a brick owns them)
        open_cells = ijk[(lv == self.level) & ((status == INTERNAL) | ((status == LEAF) & (roots is not None)))]
        f_level, f_ijk = split_keys(force)

        def forced_in(window):  # the forced cells that meet the window (with a collar: touch it)
            mine = np.zeros(len(force), bool)
            for lvl in np.unique(f_level):
                sel = f_level == lvl
                mine[sel] = in_window(int(lvl), f_ijk[sel], window, closed=roots is not None)
            return force[mine]

        todo, kept = [], []
        for brick in self.bricks:
            window = (self.level, brick.lo, brick.hi)
            if not in_window(self.level, open_cells, window).any():
                continue
            forced = forced_in(window)
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
        self.crossing_pieces = [p.crossings for p in pieces]
        if roots is not None:  # leaves above the brick level (cap leaves, min_level < b) may span bricks:
            # each is contoured here on its own window (the leaf and its collar); they are few
            # each level's together on one window of those leaves (the leaves and their collar); they are few
            coarse_leaf = (lv < self.level) & (status == LEAF)
            t1 = time.perf_counter()
            for level in np.unique(lv[coarse_leaf]):
                cells = ijk[coarse_leaf & (lv == level)]
                own = Brick(-1 - int(level), (0, 0, 0), tuple(cells.min(axis=0).tolist()),
                            tuple((cells.max(axis=0) + 1).tolist()))  # (the box of its cells: for errors)
                job.windows[own.index] = (int(level), cells)
                job.force[own.index] = forced_in((int(level), cells))
                self.crossing_pieces.append(job.task(own, None, True).crossings)
            self.info["coarse_leaves"] = self.info.get("coarse_leaves", 0) + int(coarse_leaf.sum())
            self.info["coarse_leaf_time"] = self.info.get("coarse_leaf_time", 0.0) + time.perf_counter() - t1
        self.info["brick_tasks"] += len(results)
        self.info["brick_cpu_time"] += float(sum(p.info["time"] for p in results.values()))
        counts = coarse.field.counts
        for p in pieces:  # the evaluations of this tree's bricks (coarse cells of their windows included)
            for k in counts:
                counts[k] += p.info["counts"][k]
        return merge_pieces(coarse, pieces, self.level)

    def join_crossings(self, tree: Octree, timings: dict):
        """The last round's contouring, joined (:func:`join_crossings`): (minus, plus, segments,
        units, points, normals, cap_vertex) for :func:`warpmesh.surface.adaptive.pipeline.mesh_adaptive`;
        the root evaluations are added to the tree's counts."""
        t0 = time.perf_counter()
        *out, evaluations = join_crossings(tree, self.crossing_pieces)
        tree.field.counts["evaluations"] += evaluations
        timings["join_crossings"] = timings.get("join_crossings", 0.0) + time.perf_counter() - t0
        return tuple(out)


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
        self.roots = owner.roots
        self.windows: dict = {}  # task id -> its window, where not its brick's: (level, cells)

    def bricks_to_mesh(self) -> list[Brick]:
        return self.todo

    def task(self, brick: Brick, path, want: bool) -> OctreePiece:
        """On a worker: the octree restricted to the brick, its cells below the brick level; when
        contouring (``roots``), built with the brick's collar, and the contouring of the leaves
        the brick owns (the node values then stay on the worker: the client needs none)."""
        t0 = time.perf_counter()
        tape = worker_tape(self.token, self.shape)
        window = self.windows.get(brick.index, (self.level, brick.lo, brick.hi))
        wl = window[0]
        try:
            tree = build_octree(tape, self.lo, self.hi, **self.build_kw, force=self.force[brick.index],
                                window=window, collar=self.roots is not None, device=self.device)
        except ValueError as exc:
            raise brick_error(brick, self.lo, self.h_level * (1 << (self.level - wl)), exc) from None
        keys, status, _ = tree.status
        lv, ijk = split_keys(keys)
        deep = np.flatnonzero(lv > self.level)
        if self.roots is not None:  # the brick's own cells, not its collar's
            own = np.zeros(len(deep), bool)
            for level in np.unique(lv[deep]):
                sel = lv[deep] == level
                own[sel] = in_window(int(level), ijk[deep[sel]], window)
            deep = deep[own]
        levels = [lv_ for lv_ in tree.levels if lv_["level"] > self.level]
        info = {"cells": len(deep), "leaves": int(owned_leaves(tree, window).sum()),
                "counts": dict(tree.field.counts)}
        crossings = None
        if self.roots is not None:
            try:
                crossings = contour_window(tape, tree, window, self.roots, self.device)
            except ValueError as exc:
                raise brick_error(brick, self.lo, self.h_level * (1 << (self.level - wl)), exc) from None
            nodes = (np.zeros(0, np.int64), np.zeros(0, np.float32))
        else:  # every node the brick evaluated (sorted already; sorting out its leaves' corners costs more
            nodes = (tree.nodes.keys, tree.nodes.values)  # than sending the rest)
        # the leaves' breadth-first keys (their order in the merged tree): worked out here, not on the client
        order = np.full(len(deep), -1, np.int64)
        leaf = status[deep] == LEAF
        order[leaf] = breadth_first_order(lv[deep[leaf]], ijk[deep[leaf]], tree.base_level,
                                          tree.n_finest >> (tree.max_level - tree.base_level))
        info["time"] = time.perf_counter() - t0
        return OctreePiece(keys[deep], status[deep], *nodes, levels, info, crossings, order)


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
    if pieces and all(p.order is not None for p in pieces):  # the bricks sent their leaves' keys
        c_lv, c_ijk = split_keys(ck)
        bfo = np.concatenate([breadth_first_order(c_lv, c_ijk, coarse.base_level, n0)] +
                             [p.order for p in pieces])[order][leaf]
    else:
        bfo = breadth_first_order(lv, ijk, coarse.base_level, n0)
    rank = np.lexsort((bfo, lv))
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
