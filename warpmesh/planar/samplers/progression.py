"""Continuation by progression [FG §16.3.1]: cell tracking on a virtual regular grid.

The covering-up grows from the cells holding the seeds (:func:`warpmesh.planar.samplers.seeds.find_seeds`
by default) to the neighbours across crossed edges (a sign change of f at the edge's ends),
with a visited colouring, one frontier wave at a time; f is evaluated at the nodes of
visited cells only. The visited cells are then segmented by marching squares
(:mod:`warpmesh.planar.samplers.marching_squares`, ambiguous cells by the asymptotic decider) with roots
found by bisection. The prediction-correction method is in
:mod:`warpmesh.planar.samplers.continuation`.

Example
-------
>>> import warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> pr = sample_progression(PlanarField(wm.circle(1.0), ((-2, -2), (2, 2))), resolution=32)
>>> pr.info["evaluations"] < pr.info["grid_nodes"]
True
"""

from __future__ import annotations

import time

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.grid import edge_roots
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.planar.samplers.seeds import check_count, check_field, check_positive, check_seeds, find_seeds, grid_cells, inside_box
from warpmesh.planar.samplers.marching_squares import AMBIGUOUS, JOINED, SEGMENT_COUNT, SEGMENT_TABLE, SEPARATED, asymptotic_decider

__all__ = ["sample_progression"]


# =====================================================================================
# progression: cell tracking on a virtual grid
# =====================================================================================

#: neighbour across edge e_k of a cell (e0 bottom, e1 right, e2 top, e3 left)
_ACROSS = np.array([[0, -1], [1, 0], [0, 1], [-1, 0]], INDEX_DTYPE)
#: corner offsets c0..c3, counter-clockwise
_CORNER = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], INDEX_DTYPE)


class _NodeCache:
    """f at grid nodes, evaluated on demand: sorted node keys and their values."""

    def __init__(self, field: PlanarField, origin, step, ny: int):
        self.field, self.origin, self.step, self.stride = field, origin, step, ny + 1
        self.keys, self.vals = np.zeros(0, INDEX_DTYPE), np.zeros(0, REAL_DTYPE)
        self.evaluations = 0

    def get(self, ij: np.ndarray) -> np.ndarray:
        key = ij[..., 0] * self.stride + ij[..., 1]
        flat = key.ravel()
        need = np.setdiff1d(flat, self.keys)  # sorted, unique
        if len(need):
            pts = self.origin + np.column_stack([need // self.stride, need % self.stride]) * self.step
            self.evaluations += len(need)
            keys = np.concatenate([self.keys, need])
            vals = np.concatenate([self.vals, self.field.values(pts)])
            order = np.argsort(keys, kind="stable")
            self.keys, self.vals = keys[order], vals[order]
        return self.vals[np.searchsorted(self.keys, flat)].reshape(key.shape)


def sample_progression(field: PlanarField, *, resolution: int = 64, tolerance: float = 1e-3,
                       seeds=None, max_cells: int | None = None) -> CurveSample:
    """Curve points by progression: cell tracking from seed cells [FG §16.3.1, Fig. 16.5].

    Parameters
    ----------
    field : PlanarField
        The curve's function and box.
    resolution : int
        Cells along the longer side of the box (cell size = longer side / resolution; the
        cells tile the box exactly, as square as possible).
    tolerance : float
        Roots on crossed edges are bracketed by bisection to ``tolerance`` times the edge.
    seeds : (k, 2) array_like, optional
        Points on the curve; default :func:`~warpmesh.planar.samplers.seeds.find_seeds`. Seeds outside
        the box are ignored.
    max_cells : int, optional
        Stop the tracking after this many visited cells (``info["truncated"]``).

    Returns
    -------
    CurveSample
        Points on the crossed edges of the visited cells (each edge's root once, so the
        polyline is welded), segments with f > 0 on their left, ``cells`` the crossed
        visited cells (x0, y0, x1, y1). ``info``: ``"evaluations"`` (f values: grid nodes
        and bisections), ``"node_evaluations"``, ``"grid_nodes"`` (the full grid's node
        count, for comparison), ``"cells_visited"``, ``"cells_crossed"``, ``"waves"``,
        ``"ambiguous"``, ``"seeds"``, ``"seeds_without_crossing"`` (seeds whose cell shows
        no sign change: a component below the grid resolution), ``"truncated"``,
        ``"marching_squares"`` (the table module used), ``"time"``.

    Raises
    ------
    TypeError
        ``field`` is not a PlanarField.
    ValueError
        ``resolution`` or ``max_cells`` not a positive integer, ``tolerance`` not a
        positive number, ``seeds`` not an (k, 2) array.

    Notes
    -----
    Every frontier wave is processed at once (a loop over waves only). As for any grid
    method, a component with no sign change on the grid's edges (smaller than a cell, or
    crossing one edge twice) is not tracked.

    Examples
    --------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> s = sample_progression(PlanarField(wm.circle(1.0), ((-2, -2), (2, 2))), resolution=40)
    >>> len(s.points) == len(s.segments), s.info["cells_crossed"] < 40 * 40 // 4
    (True, True)
    """
    t_start = time.perf_counter()
    field = check_field(field)
    resolution = check_count(resolution, "resolution")
    tolerance = check_positive(tolerance, "tolerance")
    max_cells = check_count(max_cells, "max_cells", allow_none=True)
    info: dict = {"marching_squares": "warpmesh.planar.samplers.marching_squares"}
    if seeds is None:
        seeds, sinfo = find_seeds(field)
        info["seed_evaluations"] = sinfo["evaluations"]
    seeds = check_seeds(seeds, field)
    bounds = field.bounds
    seeds = seeds[inside_box(seeds, bounds)]
    nx, ny, cell = grid_cells(bounds, resolution)
    info.update(grid_nodes=(nx + 1) * (ny + 1), seeds=int(len(seeds)), cell=cell.tolist())
    nodes = _NodeCache(field, bounds[0], cell, ny)
    # -- cell tracking, one frontier wave at a time -----------------------------------
    ij = np.clip(np.floor((seeds - bounds[0]) / cell).astype(INDEX_DTYPE), 0, [nx - 1, ny - 1])
    frontier = np.unique(ij[:, 0] * ny + ij[:, 1])
    visited = np.zeros(0, INDEX_DTYPE)
    waves, truncated = 0, False
    while len(frontier):  # loop over waves: the whole frontier at once
        if max_cells is not None and len(visited) + len(frontier) > max_cells:
            frontier, truncated = frontier[: max(0, max_cells - len(visited))], True
        visited = np.union1d(visited, frontier)
        waves += 1
        cij = np.column_stack([frontier // ny, frontier % ny])
        inside = nodes.get(cij[:, None, :] + _CORNER[None]) > 0
        crossed = inside != np.roll(inside, -1, axis=1)  # edge k joins corner k to k + 1
        c, e = np.nonzero(crossed)
        nb = cij[c] + _ACROSS[e]
        ok = (nb[:, 0] >= 0) & (nb[:, 0] < nx) & (nb[:, 1] >= 0) & (nb[:, 1] < ny)
        cand = np.unique(nb[ok, 0] * ny + nb[ok, 1])
        frontier = np.setdiff1d(cand, visited, assume_unique=True)
        if truncated:
            break
    info.update(waves=waves, cells_visited=int(len(visited)), truncated=truncated,
                node_evaluations=int(nodes.evaluations))
    # -- marching squares in the visited cells ----------------------------------------
    cij = np.column_stack([visited // ny, visited % ny])
    fc = nodes.get(cij[:, None, :] + _CORNER[None])
    inside = fc > 0
    config = (inside * (1 << np.arange(4))).sum(axis=1)
    active = SEGMENT_COUNT[config] > 0
    seed_cell = ij[:, 0] * ny + ij[:, 1]
    info["seeds_without_crossing"] = int(np.count_nonzero(~np.isin(seed_cell, visited[active])))
    cij, fc, config = cij[active], fc[active], config[active]
    info["cells_crossed"] = int(len(cij))
    ambiguous = np.isin(config, AMBIGUOUS)
    variant = np.full(len(cij), SEPARATED)
    variant[ambiguous] = np.where(asymptotic_decider(*fc[ambiguous].T), JOINED, SEPARATED)
    info["ambiguous"] = int(np.count_nonzero(ambiguous))
    rows = SEGMENT_TABLE[variant, config]  # (k, 2 slots, 2)
    cell_id, slot = np.nonzero(rows[:, :, 0] >= 0)
    e_from, e_to = rows[cell_id, slot, 0].astype(INDEX_DTYPE), rows[cell_id, slot, 1].astype(INDEX_DTYPE)

    # global edge key: edge k of cell (i, j) from corner k to corner k + 1, direction-free
    def edge_key(cells, e):
        a = cells + _CORNER[e]
        b = cells + _CORNER[(e + 1) % 4]
        lo = np.minimum(a, b)
        horizontal = a[:, 1] == b[:, 1]
        return 2 * (lo[:, 0] * (ny + 1) + lo[:, 1]) + (~horizontal)

    k_from, k_to = edge_key(cij[cell_id], e_from), edge_key(cij[cell_id], e_to)
    keys, first = np.unique(np.concatenate([k_from, k_to]), return_index=True)
    # the endpoints of each unique crossed edge and their values
    src_cell = np.concatenate([cell_id, cell_id])[first]
    src_edge = np.concatenate([e_from, e_to])[first]
    a = bounds[0] + (cij[src_cell] + _CORNER[src_edge]) * cell
    b = bounds[0] + (cij[src_cell] + _CORNER[(src_edge + 1) % 4]) * cell
    fa, fb = fc[src_cell, src_edge], fc[src_cell, (src_edge + 1) % 4]
    points, root_evals, _ = edge_roots(field, a, b, fa, fb, "bisection", tolerance)
    segments = np.column_stack([np.searchsorted(keys, k_from), np.searchsorted(keys, k_to)]).astype(INDEX_DTYPE)
    lo = bounds[0] + cij * cell
    info.update(root_evaluations=int(root_evals), evaluations=int(nodes.evaluations + root_evals),
                time=time.perf_counter() - t_start)
    return CurveSample(points, segments, info, cells=np.hstack([lo, lo + cell]))
