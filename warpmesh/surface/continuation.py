"""Spatial covering-up by continuation, progression type [FG §16.3.1, §16.4.1].

Starting from seed cells crossed by the surface, the covering-up grows "on the fly" by
adjacency: a crossed cell hands the surface on to the neighbour across each face whose
four corners are not all of one sign. Only crossed cells are ever touched, and f is
evaluated only at their corners (plus, for automatic seeds, along a sparse beam of grid
lines), so the cost follows the area of the surface rather than the volume of the grid.
This module is the host-side covering-up; the kernels that emit triangles take its cells.

Grid conventions
----------------
``n_nodes = (nx, ny, nz)`` grid nodes and ``(nx - 1, ny - 1, nz - 1)`` cells. Node
``(i, j, k)`` has the linear id ``i + nx * (j + ny * k)`` (i fastest, ``INDEX_DTYPE``),
cells likewise with the cell dimensions. Cell ``(i, j, k)`` has corner ``c`` at node
``(i + dx, j + dy, k + dz)`` with ``dx = c & 1``, ``dy = (c >> 1) & 1``, ``dz = (c >> 2) & 1``
(the corner numbering of ``kernels/mc_tables.py``). A node is *inside* when its float32
value, after capping, is > 0 (``warpmesh._conventions``). A cell is *crossed* when its 8
corners are neither all inside nor all outside; a face is *crossed* likewise with its 4.

Examples
--------
>>> import numpy as np
>>> from warpmesh.surface.continuation import crossed_cells_dense, grow_cells
>>> n = 33
>>> def ball(ids):  # f = 10 - distance to the grid centre, in cells
...     i, j, k = ids % n, ids // n % n, ids // (n * n)
...     return (10.0 - np.sqrt((i - 16.0)**2 + (j - 16.0)**2 + (k - 16.0)**2)).astype(np.float32)
>>> growth = grow_cells(ball, (n, n, n))
>>> growth.components, growth.evaluations < n**3 // 4
(1, True)
>>> dense = ball(np.arange(n**3)).reshape(n, n, n, order="F")  # values_grid[i, j, k]
>>> np.array_equal(growth.cells, crossed_cells_dense(dense))
True
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from warpmesh._conventions import INDEX_DTYPE
from warpmesh.errors import WarpMeshError

__all__ = ["Growth", "grow_cells", "crossed_cells_dense"]

#: bit mask of the 4 corners of face f = 2 * axis + side (the corners whose ``axis`` bit is ``side``)
_FACE_MASK = np.array([sum(1 << c for c in range(8) if (c >> (f // 2)) & 1 == f % 2) for f in range(6)],
                      dtype=np.uint8)
_CORNER_BITS = (1 << np.arange(8)).astype(np.uint8)


@dataclass(frozen=True)
class Growth:
    """The crossed cells found by :func:`grow_cells` and the node values it sampled.

    Attributes
    ----------
    cells : (n_cells,) int64
        Sorted linear ids of the crossed cells found.
    node_ids : (n_evaluated,) int64
        Sorted linear ids of every node evaluated (all corners of ``cells``, and the ray nodes).
    node_values : (n_evaluated,) float32
        f at ``node_ids``, capped (boundary nodes with f > 0 hold 0.0 when ``cap=True``).
    evaluations : int
        Calls of f in total, rays included; ``== len(node_ids)`` (each node is evaluated once).
    ray_evaluations : int
        Of those, the nodes evaluated by the seed rays (0 with user seeds).
    waves : int
        Frontiers processed, the seed frontier included (the BFS depth + 1).
    seeds : int
        Distinct seed cells of the first wave.
    components : int
        Connected components of ``cells`` under adjacency through crossed faces.
    """

    cells: np.ndarray
    node_ids: np.ndarray
    node_values: np.ndarray
    evaluations: int
    ray_evaluations: int
    waves: int
    seeds: int
    components: int


# -- evaluated nodes: a few sorted runs ----------------------------------------------------
class _NodeStore:
    """Node values evaluated so far, each node at most once, in sorted runs.

    A wave's new nodes form a sorted run; runs are merged like a binary counter (the last
    two whenever the newer is at least half the older), so there are O(log n) runs and
    each value is copied O(log n) times in all. Merging everything into one array every
    wave would cost O(n) per wave: O(n * waves) for a growth from a single seed.
    """

    def __init__(self, evaluate, dims, cap):
        self._evaluate, self._dims, self._cap = evaluate, dims, cap
        self._runs: list[tuple[np.ndarray, np.ndarray]] = []
        self.count = 0

    def _find(self, ids):
        """(found, values) of sorted unique ``ids`` in the runs."""
        found = np.zeros(len(ids), dtype=bool)
        vals = np.empty(len(ids), dtype=np.float32)
        for run_ids, run_vals in self._runs:
            hit, pos = _locate(run_ids, ids)
            found |= hit
            vals[hit] = run_vals[pos[hit]]
        return found, vals

    def values(self, ids: np.ndarray) -> np.ndarray:
        """f at ``ids`` (any shape), evaluating only the nodes not seen before."""
        uniq, inverse = np.unique(ids, return_inverse=True)
        found, vals = self._find(uniq)
        new = uniq[~found]
        if len(new):
            vals[~found] = new_vals = self._call(new)
            self._push(new, new_vals)
        return vals[inverse.reshape(ids.shape)]

    def _call(self, ids):
        out = np.asarray(self._evaluate(ids))
        if out.shape != ids.shape:
            raise ValueError(f"expected 'evaluate' to return one value per node id, shape {ids.shape}, "
                             f"got shape {out.shape}")
        if not np.issubdtype(out.dtype, np.number) or np.iscomplexobj(out):
            raise TypeError(f"expected real values from 'evaluate', got dtype {out.dtype}")
        out = out.astype(np.float32)
        bad = np.isnan(out)
        if bad.any():
            node = _unravel(ids[np.argmax(bad)], self._dims)
            raise ValueError(f"expected finite or infinite values from 'evaluate', got NaN at node {node}")
        if self._cap:
            ijk = _unravel(ids, self._dims)
            rim = ((ijk == 0) | (ijk == np.asarray(self._dims) - 1)).any(axis=1)
            out[rim & (out > 0)] = 0.0
        self.count += len(ids)
        return out

    def _merge_last(self):
        (a, av), (b, bv) = self._runs[-2], self._runs.pop()
        pos = np.searchsorted(a, b)  # disjoint sorted runs: inserting keeps the order
        self._runs[-1] = (np.insert(a, pos, b), np.insert(av, pos, bv))

    def _push(self, ids, vals):
        self._runs.append((ids, vals))
        while len(self._runs) > 1 and 2 * len(self._runs[-1][0]) >= len(self._runs[-2][0]):
            self._merge_last()

    def arrays(self):
        """All (ids, values), sorted by id."""
        if not self._runs:
            return np.empty(0, INDEX_DTYPE), np.empty(0, np.float32)
        while len(self._runs) > 1:
            self._merge_last()
        return self._runs[0]


# -- index helpers --------------------------------------------------------------------------
def _unravel(ids, dims) -> np.ndarray:
    """(..., 3) int64 (i, j, k) of linear ids (i fastest) in a grid of shape ``dims``."""
    ids = np.asarray(ids, dtype=INDEX_DTYPE)
    nx, ny = dims[0], dims[1]
    return np.stack([ids % nx, ids // nx % ny, ids // (nx * ny)], axis=-1)


def _ravel(i, j, k, dims):
    return i + dims[0] * (j + dims[1] * k)


def _corner_ids(cells, nodes, cell_dims) -> np.ndarray:
    """(n, 8) node ids of the corners of ``cells``, corner c in column c."""
    i, j, k = _unravel(cells, cell_dims).T
    base = _ravel(i, j, k, nodes)
    c = np.arange(8)
    offset = _ravel(c & 1, (c >> 1) & 1, (c >> 2) & 1, nodes).astype(INDEX_DTYPE)
    return base[:, None] + offset[None, :]


def _cases(values) -> np.ndarray:
    """(n,) uint8 inside-corner mask (bit c set when corner c is inside) of (n, 8) values."""
    return np.bitwise_or.reduce(np.where(values > 0, _CORNER_BITS, np.uint8(0)), axis=1).astype(np.uint8)


def _crossed_neighbours(cells, cases, cell_dims):
    """(row, dst): index in ``cells`` and id of the neighbours across crossed faces in the grid."""
    ijk = _unravel(cells, cell_dims)
    face = cases[:, None] & _FACE_MASK[None, :]
    go = (face != 0) & (face != _FACE_MASK[None, :])
    strides = np.array([1, cell_dims[0], cell_dims[0] * cell_dims[1]], dtype=INDEX_DTYPE)
    for axis in range(3):
        go[:, 2 * axis] &= ijk[:, axis] > 0
        go[:, 2 * axis + 1] &= ijk[:, axis] < cell_dims[axis] - 1
    step = np.stack([-strides, strides], axis=1).ravel()  # face order 2 * axis + side
    row, col = np.nonzero(go)
    return row, cells[row] + step[col]


def _locate(sorted_set, query):
    """(found, pos): which of ``query`` are in the sorted array ``sorted_set``, and where."""
    if len(sorted_set) == 0:
        return np.zeros(len(query), dtype=bool), np.zeros(len(query), dtype=INDEX_DTYPE)
    pos = np.minimum(np.searchsorted(sorted_set, query), len(sorted_set) - 1)
    return sorted_set[pos] == query, pos


# -- validation -----------------------------------------------------------------------------
def _check_dims(n_nodes) -> tuple[int, int, int]:
    try:
        dims = tuple(int(v) for v in n_nodes)
        ok = len(dims) == 3 and all(int(v) == v for v in n_nodes)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"expected 'n_nodes' as 3 integers (nx, ny, nz), got {n_nodes!r}")
    if min(dims) < 2:
        raise ValueError(f"expected at least 2 nodes per axis in 'n_nodes' (one cell), got {dims}")
    return dims


def _check_count(value, name, allow_none=True):
    if value is None and allow_none:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"expected a positive integer{' or None' if allow_none else ''} for "
                        f"'{name}', got {value!r}")
    if value < 1:
        raise ValueError(f"expected a positive integer for '{name}', got {value!r}")
    return int(value)


def _check_seeds(seeds, n_cells, cell_dims) -> np.ndarray:
    arr = np.asarray(seeds)
    if arr.size == 0:
        raise ValueError("expected at least one cell id in 'seeds', got none: pass seeds=None "
                         "to find them by ray casting")
    if arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"expected integer cell ids for 'seeds', got dtype {arr.dtype}")
    arr = np.unique(arr.astype(INDEX_DTYPE).ravel())
    bad = arr[(arr < 0) | (arr >= n_cells)]
    if len(bad):
        raise ValueError(f"expected 'seeds' in [0, {n_cells}) (cells {cell_dims}), got cell id {bad[0]}")
    return arr


# -- seeds by ray casting -------------------------------------------------------------------
def _ray_positions(n, stride, cap):
    """Node indices of the rays along one transverse axis: multiples of stride, plus the last
    (with cap, the first and last moved one node in)."""
    pos = np.r_[np.arange(0, n, stride), n - 1]
    if cap:  # a line in a face of the box is all outside: move it one node in, next to the caps
        pos = np.clip(pos, 1, n - 2) if n > 2 else pos[:0]
    return np.unique(pos).astype(INDEX_DTYPE)


def _ray_seeds(store, dims, cell_dims, stride, cap) -> np.ndarray:
    """Crossed cells around every sign change along the rays [FG §16.3.1, "naive" approach]."""
    found = []
    for axis in range(3):
        a, b = (x for x in range(3) if x != axis)
        pa, pb = np.meshgrid(_ray_positions(dims[a], stride, cap), _ray_positions(dims[b], stride, cap),
                             indexing="ij")
        pa, pb = pa.ravel(), pb.ravel()
        if len(pa) == 0:
            continue
        ijk = [None, None, None]
        ijk[axis] = np.arange(dims[axis], dtype=INDEX_DTYPE)[None, :]
        ijk[a], ijk[b] = pa[:, None], pb[:, None]
        inside = store.values(_ravel(*ijk, dims)) > 0  # (lines, nodes along the line)
        line, p = np.nonzero(inside[:, 1:] != inside[:, :-1])  # crossing edge (p, p + 1)
        for da in (-1, 0):  # the 4 cells around the edge
            for db in (-1, 0):
                ca, cb = pa[line] + da, pb[line] + db
                ok = (ca >= 0) & (ca < cell_dims[a]) & (cb >= 0) & (cb < cell_dims[b])
                cijk = [None, None, None]
                cijk[axis], cijk[a], cijk[b] = p[ok], ca[ok], cb[ok]
                found.append(_ravel(*cijk, cell_dims))
    return np.unique(np.concatenate(found)) if found else np.empty(0, INDEX_DTYPE)


# -- the progression ------------------------------------------------------------------------
def _progress(store, frontier, cases, dims, cell_dims, max_cells):
    """Breadth-first waves from ``frontier`` (sorted crossed cells, their corner masks ``cases``).

    Returns the sorted cells, their number of components, and the number of waves. In a
    breadth-first search a neighbour of wave d is in wave d - 1, d or d + 1, so "visited?"
    looks in the previous and current waves only. Each crossed face is recorded once, as an
    edge between positions in the concatenation of the waves: from the earlier wave, or
    from the lower id within one wave.
    """
    layers, edges, previous, offset = [], [], np.empty(0, INDEX_DTYPE), 0
    while len(frontier):
        if max_cells is not None and offset + len(frontier) > max_cells:
            raise WarpMeshError(f"grow_cells: more than max_cells={max_cells} crossed cells "
                                f"({offset + len(frontier)} after {len(layers) + 1} waves); raise "
                                "'max_cells' or use a coarser grid")
        row, dst = _crossed_neighbours(frontier, cases, cell_dims)
        in_wave, pos = _locate(frontier, dst)
        fresh = ~(in_wave | _locate(previous, dst)[0])
        new = np.unique(dst[fresh])  # crossed: they share a crossed face with the frontier
        same = in_wave & (frontier[row] < dst)
        nxt = offset + len(frontier)
        edge_dtype = np.int32 if nxt + len(new) < 2**31 else INDEX_DTYPE
        edges.append((np.r_[row[same], row[fresh]].astype(edge_dtype) + offset,
                      np.r_[offset + pos[same], nxt + np.searchsorted(new, dst[fresh])].astype(edge_dtype)))
        layers.append(frontier)
        previous, frontier, offset = frontier, new, nxt
        cases = _cases(store.values(_corner_ids(frontier, dims, cell_dims)))

    if not layers:
        return np.empty(0, INDEX_DTYPE), 0, 0
    a = np.concatenate([e[0] for e in edges])
    b = np.concatenate([e[1] for e in edges])
    from scipy.sparse import coo_matrix  # here, not at import: scipy.sparse is slow to import
    from scipy.sparse.csgraph import connected_components

    graph = coo_matrix((np.ones(len(a), dtype=np.int8), (a, b)), shape=(offset, offset))
    components = int(connected_components(graph, directed=False)[0])
    return np.sort(np.concatenate(layers)), components, len(layers)


def grow_cells(evaluate: Callable[[np.ndarray], np.ndarray], n_nodes, *, seeds=None,
               ray_stride: int | None = 8, cap: bool = True, max_cells: int | None = None) -> Growth:
    """The crossed cells reachable from seed cells by progression [FG §16.4.1].

    The book's progression pops one cell at a time from a stack and pushes its unvisited
    neighbours across the faces the surface crosses. Here the stack is replaced by its
    data-parallel form, a *wavefront*: the whole frontier (all cells discovered in the
    previous wave) is processed at once with array operations, its neighbours across
    crossed faces are found together, the already-visited ones dropped, and the rest -
    which are crossed, since they share a crossed face - have their corners evaluated and
    become the next frontier. The set of cells reached is the same as with the stack (the
    connected components of the seeds); only the visiting order differs (breadth-first).

    Representation: nothing is allocated per grid cell or node. The cells visited are kept
    as one sorted int64 array per wave; since a breadth-first wave only reaches cells of
    the previous, current or next wave, "visited?" is a sorted search in the last two
    waves only. Evaluated nodes are kept in a few sorted (id, value) runs merged like a
    binary counter. Memory is thus O(surface): 8 bytes per crossed cell, 12 per evaluated
    node, 8 per crossed face between two cells (the adjacency kept for the component count),
    plus temporaries for one wave. That is what makes 2048^3 grids affordable (8.6e9 cells:
    a dense visited mask is O(volume), 1 GiB even at one bit per cell). The rays are the
    one cost that grows with the volume (``3 / ray_stride**2`` of the nodes): raise
    ``ray_stride`` on large grids, or pass seeds.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(node_ids: (m,) int64) -> (m,) float`` values of f at those nodes (f > 0
        inside); converted to float32. It is called once per ray axis and once per wave,
        with sorted node ids never passed before.
    n_nodes : (3,) int
        Grid nodes ``(nx, ny, nz)``, at least 2 per axis.
    seeds : (s,) int, optional
        Linear cell ids to start from; each must be in range and crossed. Each seed only
        grows its own connected component. When given, no rays are cast.
    ray_stride : int or None
        With ``seeds=None``, seeds are found by casting rays along grid lines in the 3 axis
        directions: the lines through nodes whose two transverse indices are multiples of
        ``ray_stride`` (plus the last index); every sign change along a line seeds the 4
        cells around that edge. With ``cap=True`` the lines that would lie in a face of the
        box (all outside) are moved one node inward, where they meet the pieces of surface
        that the box cuts and the caps close. Costs about ``3 * n**3 / ray_stride**2`` evaluations, e.g.
        4.7% of the nodes at stride 8. ``None`` disables rays (then ``seeds`` is required).
    cap : bool
        Set boundary nodes with f > 0 to 0.0 (outside), so that every surface closes on the box.
    max_cells : int, optional
        Largest number of crossed cells allowed.

    Returns
    -------
    Growth
        Sorted cells, sorted evaluated node ids and their capped values, and counts.

    Raises
    ------
    ValueError
        Bad ``n_nodes``, ``seeds`` out of range or not crossed, no seeds and ``ray_stride=None``,
        or ``evaluate`` returning the wrong shape or NaN.
    TypeError
        Non-integer ``seeds``, ``ray_stride`` or ``max_cells``; non-real values from ``evaluate``.
    WarpMeshError
        More than ``max_cells`` crossed cells.

    Warns
    -----
    UserWarning
        When the rays find no sign change (the result is then empty).

    Notes
    -----
    Limit of automatic seeds: a component that no ray crosses - one that fits between
    grid lines ``ray_stride`` apart, e.g. a small ball, or a thin shell between rays - is
    missed ([FG §16.3.1]: "some lines ... can 'miss' some intersections"; remark 16.8:
    a seed is needed per component). Pass a seed inside it, or lower ``ray_stride``.

    Examples
    --------
    >>> import numpy as np
    >>> n = 17
    >>> def slab(ids):  # inside where x < 7.5: the plane crosses the 16 x 16 cells with i = 7
    ...     return (7.5 - ids % n).astype(np.float32)
    >>> g = grow_cells(slab, (n, n, n), seeds=[7 + 16 * (8 + 16 * 8)], cap=False)
    >>> len(g.cells), g.components, g.waves, g.evaluations == 2 * n * n
    (256, 1, 17, True)
    """
    dims = _check_dims(n_nodes)
    cell_dims = tuple(d - 1 for d in dims)
    n_cells = int(np.prod(cell_dims, dtype=INDEX_DTYPE))
    ray_stride = _check_count(ray_stride, "ray_stride")
    max_cells = _check_count(max_cells, "max_cells")
    if not callable(evaluate):
        raise TypeError(f"expected a callable 'evaluate', got {type(evaluate).__name__}")
    store = _NodeStore(evaluate, dims, bool(cap))

    if seeds is not None:
        frontier = _check_seeds(seeds, n_cells, cell_dims)
        ray_evaluations = 0
    elif ray_stride is None:
        raise ValueError("expected 'seeds' when ray_stride=None (no automatic seeds): pass cell ids, "
                         "or a ray_stride")
    else:
        frontier = _ray_seeds(store, dims, cell_dims, ray_stride, bool(cap))
        ray_evaluations = store.count
        if len(frontier) == 0:
            warnings.warn(f"grow_cells: no ray (ray_stride={ray_stride}) crosses the surface, the "
                          "result is empty: there is no surface, or every component fits between "
                          "rays; pass seeds or lower ray_stride", stacklevel=2)
    cases = _cases(store.values(_corner_ids(frontier, dims, cell_dims)))
    uniform = (cases == 0) | (cases == 255)
    if uniform.any():  # only user seeds can be: a ray's sign change crosses its 4 cells
        at = int(np.argmax(uniform))
        raise ValueError(f"expected crossed cells in 'seeds', got cell {int(frontier[at])} = "
                         f"{tuple(int(v) for v in _unravel(frontier[at], cell_dims))} with all 8 corners "
                         f"{'inside' if cases[at] == 255 else 'outside'}: seed a cell the surface crosses")
    n_seeds = len(frontier)

    cells, components, waves = _progress(store, frontier, cases, dims, cell_dims, max_cells)
    node_ids, node_values = store.arrays()
    return Growth(cells=cells, node_ids=node_ids, node_values=node_values, evaluations=store.count,
                  ray_evaluations=ray_evaluations, waves=waves, seeds=n_seeds, components=components)


# -- exhaustive reference -------------------------------------------------------------------
def crossed_cells_dense(values_grid, cap: bool = True) -> np.ndarray:
    """Every crossed cell of a fully sampled grid: exhaustive enumeration [FG §16.4.1].

    Parameters
    ----------
    values_grid : (nx, ny, nz) float
        f at every node, indexed ``values_grid[i, j, k]`` (from linear node values,
        ``values.reshape(nx, ny, nz, order="F")``). Compared as float32, like ``grow_cells``.
    cap : bool
        Boundary nodes with f > 0 count as outside.

    Returns
    -------
    (n_cells,) int64
        Sorted linear ids ``i + (nx - 1) * (j + (ny - 1) * k)`` of the crossed cells.

    Examples
    --------
    >>> import numpy as np
    >>> v = np.ones((3, 3, 3))  # all inside: crossed only through the capped boundary
    >>> crossed_cells_dense(v).tolist(), crossed_cells_dense(v, cap=False).tolist()
    ([0, 1, 2, 3, 4, 5, 6, 7], [])
    """
    v = np.asarray(values_grid)
    if v.ndim != 3:
        raise ValueError(f"expected a 3D array for 'values_grid', got {v.ndim}D with shape {v.shape}")
    if min(v.shape) < 2:
        raise ValueError(f"expected at least 2 nodes per axis in 'values_grid', got shape {v.shape}")
    inside = v.astype(np.float32) > 0
    if cap:
        inside[[0, -1], :, :] = inside[:, [0, -1], :] = inside[:, :, [0, -1]] = False
    count = sum(inside[dx:inside.shape[0] - 1 + dx, dy:inside.shape[1] - 1 + dy, dz:inside.shape[2] - 1 + dz]
                .astype(np.uint8) for dx in (0, 1) for dy in (0, 1) for dz in (0, 1))
    i, j, k = np.nonzero((count > 0) & (count < 8))
    cell_dims = tuple(s - 1 for s in v.shape)
    return np.sort(_ravel(i.astype(INDEX_DTYPE), j, k, cell_dims))
