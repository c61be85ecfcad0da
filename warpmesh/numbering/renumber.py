"""Vertex (node) renumbering for small bandwidth and profile [FG §17.4.1, §17.4.4].

The walks whose order depends on the walk so far (breadth-first searches, the
Cuthill–McKee numbering of each level, the components of Step 2) run as one-thread Warp
kernels in :mod:`warpmesh.kernels.numbering`, on all connected components at once. Each
component is first relabelled in the order of a search, so that on a randomly numbered
mesh the later walks read memory nearly in order.

Methods (each takes the symmetric node graph of :func:`warpmesh.numbering.graph.node_graph` and
returns ``order``: the old node indices in their new order)

``"gibbs"``
    The Gibbs method of [FG §17.4]: Step 1, a pseudo-diameter PQ by the George–Liu
    search (start at a node of minimal degree, go to the node of minimal degree of the
    last level while the depth grows); Step 2, the level structure that combines the
    descents D(P) and D(Q) — pairs (i, j), nodes with i = j fixed, the remaining
    connected components placed, largest first, on the side (i or j) that keeps the
    widest level smaller (ties: the rooted structure of smaller width); Step 3,
    Cuthill–McKee numbering level by level from the end of lower degree, neighbours
    within a level first, then the next level in order of the numbered parent and by
    increasing degree.
``"rcm"``
    Reverse Cuthill–McKee from a George–Liu pseudo-peripheral node.
``"frontal"``
    The naive frontal method (Table 17.2): the front starts at a node of minimal
    degree; each front F_k numbers its new neighbours V_i in order of the numbered
    node they touch first and by increasing ``nbneigh`` — here the number of their
    neighbours that enter the next front (the greedy choice).
``"frontal-diameter"``
    The same front grown from the end of the pseudo-diameter (Table 17.3).

Every method handles several connected components (each numbered in turn, in the order
of its smallest old index; nodes in no element go last). ``reverse="auto"`` keeps
the numbering or its reverse, whichever has the smaller profile (both are measured,
O(nnz)); the book decides the reversal in advance from the degrees of P and Q and the
side chosen for the first component — measuring is as cheap and never worse.

Statistics (:func:`matrix_stats`, Table 17.1): bandwidth β = max_i (i − j_i), profile
pr = Σ_i (i − j_i) where j_i is the first column of row i holding a neighbour (or i),
mean profile pr / n.

Examples
--------
>>> import numpy as np
>>> from warpmesh.numbering.graph import node_graph
>>> from warpmesh.numbering.renumber import renumber_graph, matrix_stats
>>> tri = np.array([[0, 5, 1], [1, 5, 4], [1, 4, 2], [2, 4, 3]])   # a strip, badly numbered
>>> g = node_graph({"triangle": tri}, 6)
>>> matrix_stats(g)["bandwidth"]
5
>>> order = renumber_graph(g, "gibbs")
>>> new = np.empty(6, int); new[order] = np.arange(6)
>>> matrix_stats(g, new)["bandwidth"]
2
"""

from __future__ import annotations

import functools
import time
from typing import Literal

import numpy as np
import scipy.sparse as sp
import warp as wp

from warpmesh.kernels import numbering as KN

from warpmesh.numbering.graph import corner_count, degrees, node_graph
from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh.cells.types import require_mesh

__all__ = ["METHODS", "renumber", "renumber_graph", "matrix_stats", "profile_stats", "element_order"]

Method = Literal["gibbs", "rcm", "frontal", "frontal-diameter"]
METHODS: tuple[str, ...] = ("gibbs", "rcm", "frontal", "frontal-diameter")
#: components up to this size keep their old relative order (numbered in one go)
SMALL_COMPONENT = 2


# ----------------------------------------------------------------------------- kernels
_as_wp = functools.partial(wp.array, dtype=wp.int32, device="cpu", copy=False)  # views of int32 numpy arrays


def _per_node(kernel, n: int, inputs: list, outputs: list) -> None:
    """Launch a one-thread-per-node kernel (first argument ``first``) over [0, n),
    split across the CPU cores; returns when done."""
    wp.load_module(KN, device="cpu")  # load once here, not in the worker threads
    run_parallel(lambda a=a, b=b: wp.launch(kernel, dim=b - a, inputs=[a, *inputs], outputs=outputs,
                                            device="cpu")
                 for a, b in parallel_ranges(n, "cpu"))
    wp.synchronize_device("cpu")


# ----------------------------------------------------------------------------- statistics
def matrix_stats(graph: sp.csr_matrix, new: np.ndarray | None = None) -> dict:
    """Bandwidth and profile of the matrix of ``graph`` with nodes numbered ``new``.

    Parameters
    ----------
    graph : (n, n) csr_matrix
        Symmetric node graph.
    new : (n,) int, optional
        New number of each node (a permutation of 0..n-1); default the identity.

    Returns
    -------
    dict
        ``bandwidth`` β, ``profile`` pr, ``profile_mean`` pr / n, and the same three for
        the reversed numbering (``bandwidth_reversed``, ...).

    Examples
    --------
    >>> from warpmesh.numbering.graph import node_graph
    >>> g = node_graph({"line": np.array([[0, 2], [2, 1]])}, 3)
    >>> s = matrix_stats(g); s["bandwidth"], s["profile"]
    (2, 2)
    """
    n = graph.shape[0]
    new = np.arange(n) if new is None else np.asarray(new)
    if new.shape != (n,):
        raise ValueError(f"expected 'new' of shape ({n},), got {new.shape}")
    g = sp.csr_matrix(graph)
    delta = wp.empty(n, dtype=wp.int32, device="cpu")
    delta_rev = wp.empty(n, dtype=wp.int32, device="cpu")
    inputs = [_as_wp(g.indptr.astype(np.int32, copy=False)), _as_wp(g.indices.astype(np.int32, copy=False)),
              _as_wp(new.astype(np.int32, copy=False))]
    _per_node(KN.profile_kernel, n, inputs, [delta, delta_rev])
    return _delta_stats(delta.numpy(), delta_rev.numpy())  # sync points


def _delta_stats(delta: np.ndarray, delta_reversed: np.ndarray) -> dict:
    """:func:`matrix_stats`' figures from each row's i - j_i, both ways."""
    n, out = len(delta), {}
    for suffix, d in (("", delta), ("_reversed", delta_reversed)):
        out["bandwidth" + suffix] = int(d.max(initial=0))
        out["profile" + suffix] = int(d.sum(dtype=np.int64))
        out["profile_mean" + suffix] = out["profile" + suffix] / n if n else 0.0
    return out


def element_order(cells: np.ndarray, new: np.ndarray) -> np.ndarray:
    """Element renumbering of [FG §17.4.2] in linear time.

    Elements are numbered by their node of smallest new number (a vertex, for P1
    elements), then by their old index — the order the book's double loop ("for each vertex, the elements containing
    it not yet numbered") gives, found by one counting sort instead of O(n²) work.

    Parameters
    ----------
    cells : (m, k) int
    new : (n,) int
        New number of each node.

    Returns
    -------
    (m,) int: old element indices in their new order.

    Examples
    --------
    >>> element_order(np.array([[2, 3], [0, 1], [1, 2]]), np.arange(4)).tolist()
    [1, 2, 0]
    """
    m = len(cells)
    if not m:
        return np.zeros(0, np.int64)
    key = new[cells].min(axis=1)
    # a CSR matrix built from (key, element) pairs lists each row's elements in input
    # order: scipy's coo -> csr conversion is a stable counting sort, O(m + n)
    csr = sp.csr_matrix(
        (np.ones(m, bool), (key, np.arange(m))), shape=(int(key.max()) + 1, m)
    )
    return csr.indices.astype(np.int64)


# ----------------------------------------------------------------------------- numbering
def _min_index(nodes: np.ndarray, key: np.ndarray) -> int:
    """The node of smallest key, ties to the smallest index."""
    k = key[nodes]
    cand = nodes[k == k.min()]
    return int(cand.min())


def _order_by(*columns) -> np.ndarray:
    """Indices sorting by the first column, then the second, ... (non-negative ints),
    ties left in input order (a stable sort: a trailing column of positions is never
    needed), in linear time where the keys allow. The columns are combined into one key;
    up to 16 bits numpy sorts it by radix; up to a few times the length, a counting sort
    (scipy's coo -> csr conversion is one, stable); else one stable int64 argsort
    (np.lexsort is several times slower on large arrays)."""
    m = len(columns[0])
    spans = [int(c.max(initial=0)) + 1 for c in columns]
    total = float(np.prod([float(s) for s in spans]))
    if total >= 2.0**62:
        return np.lexsort(columns[::-1])
    combined = columns[0].astype(np.int64)
    for c, s in zip(columns[1:], spans[1:]):
        combined *= s
        combined += c
    if total <= 2.0**16:
        return np.argsort(combined.astype(np.uint16), kind="stable")
    if total <= 4.0 * m:
        csr = sp.csr_matrix((np.ones(m, bool), (combined, np.arange(m))), shape=(int(total), m))
        return csr.indices.astype(np.int64)
    return np.argsort(combined, kind="stable")


class _Graph:
    """A relabelled graph whose connected components are the contiguous label ranges
    ``bounds[c]:bounds[c + 1]``, with the Warp views and scratch arrays of its walks
    (kernels/numbering.py); every method works on all components at once. With
    ``check``, the first walk also checks the graph for symmetry (as
    :func:`_check_graph`: ValueError) before anything else reads it."""

    def __init__(self, graph: sp.csr_matrix, bounds, check: bool = False):
        self.graph = graph
        self.check = check
        self.n = n = graph.shape[0]
        self.bounds = np.asarray(bounds, np.int64)
        self.n_comp = len(self.bounds) - 1
        self.comp = (np.zeros(n, np.int32) if self.n_comp == 1 else
                     np.repeat(np.arange(self.n_comp, dtype=np.int32), np.diff(self.bounds)))
        self.deg = np.diff(graph.indptr).astype(np.int32, copy=False)  # deg(P), as degrees() but int32
        self.max_deg = int(self.deg.max(initial=0))
        self.indptr = _as_wp(graph.indptr.astype(np.int32, copy=False))
        self.indices = _as_wp(graph.indices.astype(np.int32, copy=False))
        self.queue = wp.empty(n + 1, dtype=wp.int32, device="cpu")  # a spare slot for the branch-free walks
        self.comp_wp = _as_wp(self.comp)
        self.deg_wp = _as_wp(self.deg)
        self.scratch = np.zeros(n, np.int32)  # column counts nobody reads (from 0: no overflow)

    def _columns_counted(self, columns: np.ndarray) -> None:
        """The pending symmetry check, on each node's entries per column."""
        self.check = False
        if not np.array_equal(columns, self.deg):
            raise ValueError(_NOT_SYMMETRIC)

    def check_symmetry(self) -> None:
        """The pending symmetry check (if any) by a pass of its own."""
        if self.check:
            columns = np.zeros(self.n, np.int32)
            wp.launch(KN.count_columns_kernel, dim=self.graph.nnz, inputs=[self.indices], outputs=[_as_wp(columns)],
                      device="cpu")  # atomic counts: one launch, never split across threads
            wp.synchronize_device("cpu")
            self._columns_counted(columns)

    def first_per_component(self, nodes: np.ndarray, *keys) -> np.ndarray:
        """For each component, the one of ``nodes`` (some in each, grouped by ascending
        component) smallest by ``keys`` (non-negative arrays over all nodes), ties by
        index."""
        if self.n_comp == 1 and len(keys) == 1:  # one component: the first minimum
            return nodes[np.argmin(keys[0][nodes])][None]
        cn = self.comp[nodes]
        spans = [int(k.max(initial=0)) + 1 for k in keys]
        if float(np.prod([float(s) for s in spans])) * self.n >= 2.0**62:  # no room for one key
            nodes = nodes[_order_by(cn, *(k[nodes] for k in keys))]
            return nodes[np.searchsorted(self.comp[nodes], np.arange(self.n_comp))]
        combined = np.zeros(len(nodes), np.int64)  # (keys..., node) as one int64: a minimum per run
        for k, span in zip(keys, spans):
            combined = combined * span + k[nodes]
        combined = combined * self.n + nodes
        runs = np.flatnonzero(np.r_[True, cn[1:] != cn[:-1]])  # nodes come by ascending component
        return np.minimum.reduceat(combined, runs) % self.n

    def descent(self, sources: np.ndarray) -> np.ndarray:
        """Each node's level in the descent of its component's source (one source per
        component, any components): (n,) int32, -1 in the components without one."""
        return self.search(sources)[0]

    def search(self, sources: np.ndarray):
        """The descents of ``sources`` (one per component, any components), as
        :meth:`descent`, with for each component c (indexing arrays of length n_comp,
        meaningful for the components searched only) its number of levels and the node
        of smallest (degree, index) of its last level."""
        level = np.full(self.n, -1, np.int32)
        depth, last = np.full(self.n_comp, -1, np.int32), np.zeros(self.n_comp, np.int32)
        check = self.check and len(sources) == self.n_comp  # every node reached: every entry counted
        columns = np.zeros(self.n, np.int32) if check else self.scratch
        wp.launch(KN.descent_kernel, dim=1,
                  inputs=[self.indptr, self.indices, _as_wp(np.asarray(sources, np.int32)), self.comp_wp, self.deg_wp],
                  outputs=[_as_wp(level), self.queue, _as_wp(depth), _as_wp(last),
                           _as_wp(np.zeros(self.n_comp, np.int32)), _as_wp(columns)], device="cpu")
        wp.synchronize_device("cpu")
        if check:
            self._columns_counted(columns)
        return level, depth.astype(np.int64) + 1, last.astype(np.int64)

    def depths(self, level: np.ndarray) -> np.ndarray:
        """Number of levels of each component's descent (``level`` over all nodes)."""
        return np.maximum.reduceat(level, self.bounds[:-1]).astype(np.int64) + 1

    def components(self, label: np.ndarray):
        """The connected components of the subgraph induced by the nodes where ``label``
        ((n,) int32, overwritten) is -1 (elsewhere: another negative value), labelled in
        the order of each one's smallest node.

        Returns where each starts in the next (int32, one more than there are components)
        and their nodes (int32), component after component (each in the order of a
        search from its smallest node)."""
        nodes = np.flatnonzero(label == -1).astype(np.int32)
        grouped, starts = np.empty(len(nodes) + 1, np.int32), np.empty(len(nodes) + 1, np.int32)  # spare slots
        count = wp.zeros(1, dtype=wp.int32, device="cpu")
        wp.launch(KN.label_components_kernel, dim=1,
                  inputs=[self.indptr, self.indices, _as_wp(nodes)],
                  outputs=[_as_wp(label), _as_wp(grouped), _as_wp(starts), count], device="cpu")
        return starts[: int(count.numpy()[0]) + 1], grouped[: len(nodes)]  # sync point

    def number(self, level: np.ndarray, start: np.ndarray, key: np.ndarray) -> np.ndarray:
        """Step 3 on every component: ``level`` (n,) per node, numbering from ``start``
        (one per component) with neighbours by increasing ``key``. Component c gets the
        numbers ``bounds[c]:bounds[c + 1]``. Returns ``out`` (number -> node, int32); the
        inverse (node -> number) is kept as ``self.numbers``, and the numbering's
        :func:`matrix_stats` as ``self.stats`` when ``level`` is a level structure (the
        kernel measures it on the way; else None)."""
        depth = self.depths(level)
        first_level = np.concatenate([[0], np.cumsum(depth)])
        # a global index for every (component, level)
        flat = (level if self.n_comp == 1 else first_level[self.comp] + level).astype(np.int32)  # a copy: overwritten
        n_levels = int(first_level[-1])
        key_wp = self.deg_wp if key is self.deg else _as_wp(key.astype(np.int32))
        span = self.max_deg + 1 if key is self.deg else int(key.max(initial=0)) + 1
        if n_levels * span <= 4 * self.n + 4096:  # a counting sort over (level, key) buckets, in a kernel
            members, bounds = np.empty(self.n, np.int32), np.empty(n_levels + 1, np.int32)
            count = np.zeros(n_levels * span + 1, np.int32)
            wp.launch(KN.sort_levels_kernel, dim=1, inputs=[_as_wp(flat), key_wp, span],
                      outputs=[_as_wp(count), _as_wp(members), _as_wp(bounds)], device="cpu")
        else:
            members = _order_by(flat, key).astype(np.int32)
            bounds = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=n_levels))]).astype(np.int32)
        num, out = np.full(self.n, -1, np.int32), np.full(self.n, -1, np.int32)
        buf = wp.empty(max(self.max_deg, 1), dtype=wp.int32, device="cpu")
        delta, delta_rev, stray = np.empty(self.n, np.int32), np.empty(self.n, np.int32), np.zeros(1, np.int32)
        wp.launch(KN.number_levels_kernel, dim=1,
                  inputs=[self.indptr, self.indices, _as_wp(flat), key_wp, _as_wp(members), _as_wp(bounds),
                          _as_wp(start.astype(np.int32)), _as_wp(first_level.astype(np.int32)),
                          _as_wp(self.bounds[:-1].astype(np.int32))],
                  outputs=[_as_wp(num), _as_wp(out), buf, _as_wp(delta), _as_wp(delta_rev), _as_wp(stray)],
                  device="cpu")
        wp.synchronize_device("cpu")
        self.numbers = num  # node -> number, as ``out`` inverted
        self.stats = _delta_stats(delta, delta_rev) if stray[0] == 0 else None
        return out


def _pseudo_diameters(g: _Graph, start: np.ndarray, start_level: np.ndarray):
    """[FG §17.4] Step 1 (George–Liu) in every component: from ``start`` (whose descents are
    ``start_level``), Q is the node of minimal degree of the last level (ties: smallest
    index); while D(Q) is deeper than D(P), Q becomes P and the search goes on. Each
    round works on the components still going only.

    Returns P, D(P), Q, D(Q) (per component / per node), d(Q) = d(P) everywhere.
    """
    p, p_lv = start.copy(), start_level
    q, q_lv = np.zeros_like(p), None
    depth = g.depths(p_lv)
    cand = g.first_per_component(np.flatnonzero(p_lv == (depth[0] if g.n_comp == 1 else depth[g.comp]) - 1), g.deg)
    active = np.arange(g.n_comp)
    sizes = np.diff(g.bounds)
    while len(active):
        lv, new_depth, last = g.search(cand)
        deeper = new_depth[active] > depth[active]
        q[active[~deeper]] = cand[~deeper]
        go = active[deeper]
        if len(active) == g.n_comp and not len(go):  # every component done (the usual end)
            q_lv = lv
        elif len(active) == g.n_comp and len(go) == g.n_comp:  # every component goes on
            p_lv = lv
        else:  # merge per component: lv holds -1 outside the active ones
            flag = np.zeros(g.n_comp, np.int8)
            flag[active] = np.where(deeper, 1, 2)
            per_node = np.repeat(flag, sizes)
            p_lv = np.where(per_node == 1, lv, p_lv)
            q_lv = np.where(per_node == 2, lv, np.full(g.n, -1, np.int32) if q_lv is None else q_lv)
        p[go], depth[go] = cand[deeper], new_depth[go]
        cand, active = last[go], go
    return p, p_lv, q, q_lv


def _gibbs_levels(g: _Graph, p_lv: np.ndarray, q_lv: np.ndarray) -> np.ndarray:
    """Step 2 in every component: pairs (i, j), nodes with i = j fixed, the other
    nodes' connected components placed, largest first, on the side that keeps the widest
    level smaller (ties: the rooted structure of smaller width). Returns the levels.

    Levels are counted in one array over every (component, level), indexed by the
    component's first level + the level ("flat" levels); the pieces are placed by one
    kernel thread, each component's largest first (pieces of different components never
    share a flat level)."""
    depth = g.depths(p_lv)
    first_level = np.concatenate([[0], np.cumsum(depth)])
    size = int(first_level[-1])
    one = g.n_comp == 1
    fi, fj, label = (np.empty(g.n, np.int32) for _ in range(3))
    counts, hist_p, hist_q = (np.zeros(size, np.int32) for _ in range(3))
    wp.launch(KN.pair_levels_kernel, dim=g.n,  # atomic counts: one launch, never split across threads
              inputs=[_as_wp(p_lv.astype(np.int32, copy=False)), _as_wp(q_lv.astype(np.int32, copy=False)),
                      g.comp_wp, _as_wp(first_level.astype(np.int32)), _as_wp(depth.astype(np.int32))],
              outputs=[_as_wp(a) for a in (fi, fj, label, counts, hist_p, hist_q)], device="cpu")
    wp.synchronize_device("cpu")
    if counts.sum() == g.n:  # every node fixed
        return p_lv.copy()
    width_p = np.maximum.reduceat(hist_p, first_level[:-1])
    width_q = np.maximum.reduceat(hist_q, first_level[:-1])
    starts, grouped = g.components(label)  # the pieces, each contiguous in ``grouped``
    sizes = np.diff(starts)
    owner = np.zeros(len(sizes), np.int32) if one else g.comp[grouped[starts[:-1]]]
    by_size = _order_by(owner, sizes.max() - sizes)  # per component, largest first (ties: label)
    flat = fi  # the fixed nodes' flat level; the others' is set by the kernel
    ci, cj = np.zeros(size, np.int32), np.zeros(size, np.int32)
    wp.launch(KN.place_pieces_kernel, dim=1,
              inputs=[_as_wp(grouped), _as_wp(starts), _as_wp(by_size.astype(np.int32)), _as_wp(owner), _as_wp(fi),
                      _as_wp(fj), _as_wp(width_p), _as_wp(width_q)],
              outputs=[_as_wp(counts), _as_wp(flat), _as_wp(ci), _as_wp(cj)], device="cpu")
    wp.synchronize_device("cpu")
    return flat if one else flat - first_level[g.comp]


def _number_components(g: _Graph, method: str, start_level=None) -> np.ndarray:
    """The order (new -> old label) of the graph by ``method``, component by component;
    ``start_level`` is the descent of each component's node of minimal degree, if known."""
    start = np.argmin(g.deg)[None] if g.n_comp == 1 else g.first_per_component(np.arange(g.n), g.deg)
    lv = g.descent(start) if start_level is None else start_level
    if method == "frontal":
        g.check_symmetry()
        return g.number(lv, start, _forward_degree(g.graph, lv))
    p, p_lv, q, q_lv = _pseudo_diameters(g, start, lv)
    from_q = g.deg[q] < g.deg[p]  # start from the end of lower degree
    if method == "gibbs":
        level = _gibbs_levels(g, p_lv, q_lv)
        depth = g.depths(p_lv)
        if g.n_comp == 1:
            level = depth[0] - 1 - level if from_q[0] else level
        else:
            level = np.where(from_q[g.comp], depth[g.comp] - 1 - level, level)
        return g.number(level, np.where(from_q, q, p), g.deg)
    lv = np.where(from_q[g.comp], q_lv, p_lv)
    key = g.deg if method == "rcm" else _forward_degree(g.graph, lv)
    return g.number(lv, np.where(from_q, q, p), key)


def _forward_degree(graph, level_of):
    """Number of neighbours one level further: what a node brings into the next front."""
    n = graph.shape[0]
    rows = np.repeat(np.arange(n), np.diff(graph.indptr))
    ahead = level_of[graph.indices] == level_of[rows] + 1
    return np.bincount(rows[ahead], minlength=n)


def _relabel(graph: sp.csr_matrix, seq: np.ndarray, size: int) -> sp.csr_matrix:
    """The subgraph of nodes ``seq[:size]`` (closed under adjacency), node ``seq[r]``
    relabelled r, rows sorted, in csgraph format (a kernel: scipy's two-sided fancy
    indexing plus sorting costs several times more)."""
    n = graph.shape[0]
    new_of_old = np.full(n, -1, np.int32)
    new_of_old[seq[:size]] = np.arange(size, dtype=np.int32)
    indptr = np.zeros(size + 1, np.int32)
    np.cumsum(np.diff(graph.indptr)[seq[:size]], out=indptr[1:])
    indices = np.empty(int(indptr[-1]), np.int32)
    _per_node(KN.relabel_rows_kernel, size,
              [_as_wp(graph.indptr), _as_wp(graph.indices), _as_wp(seq[:size].astype(np.int32)),
               _as_wp(new_of_old), _as_wp(indptr)], [_as_wp(indices)])
    g = sp.csr_matrix((np.ones(len(indices), bool), indices, indptr), shape=(size, size))
    g.has_sorted_indices = True
    return g


def _search_relabel(graph: sp.csr_matrix, start: int):
    """Breadth-first search from ``start`` that relabels as it goes (one kernel pass).

    Returns the nodes reached in search order, the subgraph they span relabelled by
    that order (csgraph format, but rows unsorted), the level of each label, and
    whether the pass met no diagonal entry (the symmetry check comes with the first
    descent: :class:`_Graph`)."""
    n = graph.shape[0]
    new_of_old = np.full(n, -1, np.int32)
    old_of_new, level = np.empty(n, np.int32), np.empty(n, np.int32)
    indptr, indices = np.zeros(n + 1, np.int32), np.empty(graph.nnz, np.int32)
    count = wp.zeros(2, dtype=wp.int32, device="cpu")
    wp.launch(KN.search_relabel_kernel, dim=1,
              inputs=[_as_wp(graph.indptr), _as_wp(graph.indices), int(start)],
              outputs=[_as_wp(a) for a in (new_of_old, old_of_new, level, indptr, indices)] + [count], device="cpu")
    c, diagonal = (int(x) for x in count.numpy())  # sync point
    ok = diagonal == 0
    local = sp.csr_matrix((np.ones(int(indptr[c]), bool), indices[: indptr[c]], indptr[: c + 1]), shape=(c, c))
    local.has_sorted_indices = False  # rows in the input's order: the walks that follow need no order
    return old_of_new[:c].astype(np.int64), local, level[:c], ok


def _layout(graph, deg, check: bool = False):
    """A relabelling that makes every connected component a contiguous range.

    Returns ``seq`` (new label -> node: the components with more than SMALL_COMPONENT
    nodes, then the smaller ones, then isolated nodes), the sizes of the large
    components, the number of nodes in small components and (the large components'
    relabelled graph, each label's level in the descent of its component's node of
    minimal degree, when the graph is connected, else None; and whether the symmetry
    check is still to be made by the walks). Each large component is
    laid out in the breadth-first order of a search, so that the walks that follow
    read memory nearly in order: on a randomly numbered mesh that alone makes them ~3x
    faster.

    With ``check``, ``graph`` (CSR, int32, canonical) is also checked for a diagonal
    (None is returned when it has one) and for symmetry (:func:`_check_graph`:
    ValueError), here or, when it is connected, by the first descent of its walks.
    """
    n = graph.shape[0]
    isolated = np.flatnonzero(deg == 0)
    n_used = n - len(isolated)
    if not n_used:
        return isolated, [], 0, None
    start = int(np.argmin(deg)) if not len(isolated) else _min_index(np.flatnonzero(deg), deg)
    reached, local, level, ok = _search_relabel(graph, start)
    if check and (not ok or len(reached) != n_used):  # the search saw part of it, or a fault
        if not _check_graph(graph):
            return None
    if len(reached) == n_used:
        seq = np.concatenate([reached, isolated]) if len(isolated) else reached
        if n_used <= SMALL_COMPONENT:
            if check and not np.array_equal(np.bincount(local.indices, minlength=n_used), np.diff(local.indptr)):
                raise ValueError(_NOT_SYMMETRIC)
            return seq, [], n_used, None
        return seq, [n_used], 0, (local, level, check)
    # several components: one search labels them all, each laid out contiguously in the
    # order of its search (from its smallest node; components by smallest node)
    label, queue, starts = np.full(n, -1, np.int32), np.empty(n + 1, np.int32), np.empty(n + 1, np.int32)
    count = wp.zeros(1, dtype=wp.int32, device="cpu")
    wp.launch(KN.label_components_kernel, dim=1,
              inputs=[_as_wp(graph.indptr), _as_wp(graph.indices), _as_wp(np.arange(n, dtype=np.int32))],
              outputs=[_as_wp(label), _as_wp(queue), _as_wp(starts), count], device="cpu")
    queue = queue[:n]
    sizes = np.diff(starts[: int(count.numpy()[0]) + 1])  # sync point
    kind = np.where(sizes > SMALL_COMPONENT, 0, np.where(sizes > 1, 1, 2))
    seq = queue.astype(np.int64)[_order_by(kind[label[queue]])]
    total = int(sizes[kind == 0].sum())
    local = (_relabel(graph, seq, total), None, False) if total else None
    return seq, sizes[kind == 0].tolist(), int(sizes[kind == 1].sum()), local


_NOT_SYMMETRIC = ("expected a symmetric 'graph' (every entry (i, j) with its (j, i)); "
                  "use g + g.T, or warpmesh.numbering.graph.node_graph")


def _is_canonical(graph) -> bool:
    """True for a CSR matrix with int32 indices and sorted rows without duplicates."""
    if type(graph) is not sp.csr_matrix or graph.indices.dtype != np.int32 or graph.indptr.dtype != np.int32:
        return False
    return bool(graph.has_canonical_format)  # scipy checks the rows once and remembers


def _check_graph(graph) -> bool:
    """For a canonical ``graph``: ValueError when some node has more entries in its row
    than in its column (it cannot be symmetric); else whether it has no diagonal entry."""
    if not np.array_equal(np.diff(graph.indptr), np.bincount(graph.indices, minlength=graph.shape[0])):
        raise ValueError(_NOT_SYMMETRIC)
    rows = np.repeat(np.arange(graph.shape[0], dtype=np.int32), np.diff(graph.indptr))
    return not bool(np.any(graph.indices == rows))


def _as_csgraph(graph, *, check: bool = True) -> sp.csr_matrix:
    """The structure of ``graph`` as CSR with int32 indices, sorted rows, no duplicates
    and no diagonal: ``graph`` itself when it is so already (its values are never read),
    else a float64 copy. With ``check=False`` a canonical int32 ``graph`` is returned
    unchecked for symmetry and a diagonal (the caller checks on the way: :func:`_layout`).

    Raises ValueError for a graph that cannot be symmetric (a node with more entries in
    its row than in its column) or too large for int32 indices."""
    if _is_canonical(graph) and (not check or _check_graph(graph)):  # node_graph's output
        return graph
    g = sp.csr_matrix(graph, dtype=np.float64, copy=True)
    g.sum_duplicates()  # also sorts the rows
    if g.nnz >= np.iinfo(np.int32).max:
        raise ValueError(f"expected fewer than 2**31 - 1 entries in 'graph', got {g.nnz}")
    g.data[:] = 1.0  # explicit zeros are entries too
    if g.nnz and g.diagonal().any():
        g.setdiag(0)
        g.eliminate_zeros()
    if not np.array_equal(np.diff(g.indptr), np.bincount(g.indices, minlength=g.shape[0])):
        raise ValueError(_NOT_SYMMETRIC)
    g.indices = g.indices.astype(np.int32)
    g.indptr = g.indptr.astype(np.int32)
    g.has_sorted_indices = True
    return g


def renumber_graph(
    graph: sp.csr_matrix,
    method: Method = "gibbs",
    *,
    reverse: bool | Literal["auto"] = "auto",
) -> np.ndarray:
    """A new numbering of the nodes of ``graph`` (see the module docstring for methods).

    Parameters
    ----------
    graph : (n, n) csr_matrix
        Symmetric, no diagonal (:func:`warpmesh.numbering.graph.node_graph`).
    method : {"gibbs", "rcm", "frontal", "frontal-diameter"}
    reverse : bool or "auto"
        Reverse the numbering; "auto" (default) keeps the direction of smaller profile.
        "rcm" is reversed by definition unless ``reverse=False`` is given.

    Returns
    -------
    (n,) int64
        ``order[new] = old``.

    Raises
    ------
    ValueError
        Unknown method or reverse option, non-square graph.

    Examples
    --------
    >>> from warpmesh.numbering.graph import node_graph
    >>> g = node_graph({"line": np.array([[0, 3], [3, 1], [1, 2]])}, 4)
    >>> renumber_graph(g, "rcm").tolist()
    [2, 1, 3, 0]
    """
    if method not in METHODS:
        raise ValueError(f"expected method among {list(METHODS)}, got {method!r}")
    if reverse not in (True, False, "auto"):
        raise ValueError(f"expected reverse=True, False or 'auto', got {reverse!r}")
    if not sp.issparse(graph) or graph.shape[0] != graph.shape[1]:
        raise ValueError(f"expected a square sparse 'graph', got {type(graph).__name__}")
    g = _as_csgraph(graph, check=False)
    layout = _layout(g, degrees(g), check=g is graph)  # diagonal and symmetry checked on the way
    if layout is None:  # a diagonal: drop it, and lay the graph out again
        g = _as_csgraph(g)
        layout = _layout(g, degrees(g))
    seq, sizes, n_small, connected = layout
    offset = sum(sizes)  # the large components come first, each a contiguous range
    order = None if offset and offset == len(seq) else seq.copy()  # small components, isolated nodes keep their places
    if offset:
        local, start_level, pending = connected
        walks = _Graph(local, np.concatenate([[0], np.cumsum(sizes)]), check=pending)
        out = _number_components(walks, method, start_level)
        if order is None:
            order = seq[out]
        else:
            order[:offset] = seq[out]
    used = offset + n_small  # nodes in some element
    if reverse == "auto" and method != "rcm":
        # measured on the relabelled large components (memory read nearly in order): the
        # small components' profile is the same both ways
        flip = False
        if offset:
            s = walks.stats or matrix_stats(local, walks.numbers)  # measured by Step 3's kernel
            flip = (s["profile_reversed"], s["bandwidth_reversed"]) < (s["profile"], s["bandwidth"])
    else:
        flip = bool(reverse) if method != "rcm" else reverse != False  # noqa: E712
    if flip:  # isolated nodes stay last
        order[:used] = order[:used][::-1].copy()
    return order


# ----------------------------------------------------------------------------- meshes
def _is_higher_order(mesh) -> bool:
    return any(c.shape[1] > corner_count(t) for t, c in mesh.cells.items())


def profile_stats(mesh, *, reduced: bool = False) -> dict:
    """Bandwidth and profile of the finite-element matrix of ``mesh`` as numbered now.

    Every pair of nodes of an element is a coefficient ([FG Fig. 17.11] i/ii; with
    ``reduced``, quads and hexahedra connect along edges only, Fig. 17.11 iii).

    Returns
    -------
    dict
        ``bandwidth``, ``profile``, ``profile_mean`` (see :func:`matrix_stats`).

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], {"triangle": [[0, 1, 3], [0, 3, 2]]})
    >>> profile_stats(m)
    {'bandwidth': 3, 'profile': 6, 'profile_mean': 1.5}
    """
    s = matrix_stats(node_graph(mesh.cells, mesh.n_points, reduced=reduced))
    return {k: s[k] for k in ("bandwidth", "profile", "profile_mean")}


#: facts of ``Mesh.info`` that an element renumbering makes stale (colour packets)
_ELEMENT_ORDER_FACTS = ("n_colors", "packet_sizes", "color_adjacency")


def _inverse(order: np.ndarray) -> np.ndarray:
    """``new[old]`` from ``order[new] = old``."""
    new = np.empty(len(order), np.int64)
    new[order] = np.arange(len(order))
    return new


def _ball_order(mesh, corner_order: np.ndarray):
    """Seed's rule for arbitrary meshes: walk the vertices in their new order and number
    the not yet numbered nodes of the elements of each one's ball, element by element
    (by old index), in local order. Elements are numbered in the order the walk first
    meets them: by (first vertex of the element in the walk, old index). Vectorised: a
    node's place is the smallest (first vertex, element, local index) over its
    occurrences.

    Returns the node order (new -> old) and {cell type: element order}.
    """
    n = mesh.n_points
    vnum = np.empty(n, np.int64)
    vnum[corner_order] = np.arange(n)
    best = np.full(n, np.iinfo(np.int64).max)
    total = sum(len(c) for c in mesh.cells.values())
    width = max(c.shape[1] for c in mesh.cells.values())
    if float(n) * total * width >= 2.0**62:
        raise ValueError(f"expected a mesh small enough for int64 keys, got {n} nodes")
    offset, elements = 0, {}
    for t, cells in mesh.cells.items():
        m, k = cells.shape
        first = vnum[cells[:, : corner_count(t)]].min(axis=1)
        key = (first[:, None] * total + offset + np.arange(m)[:, None]) * width + np.arange(k)
        np.minimum.at(best, cells.ravel(), key.ravel())
        elements[t] = _order_by(first)
        offset += m
    return np.argsort(best, kind="stable"), elements


def renumber(
    mesh,
    method: Method = "gibbs",
    *,
    reverse: bool | Literal["auto"] = "auto",
    higher_order: Literal["ball", "graph"] = "ball",
    reduced: bool = False,
    elements: bool = True,
):
    """A copy of ``mesh`` with its nodes (and elements) renumbered [FG §17.4].

    Parameters
    ----------
    mesh : Mesh
    method : {"gibbs", "rcm", "frontal", "frontal-diameter"}
        See the module docstring.
    reverse : bool or "auto"
        See :func:`renumber_graph`; with the ball rule it applies to the whole numbering
        (the walk run backwards), "auto" measuring it on every node.
    higher_order : {"ball", "graph"}
        For meshes with nodes other than vertices (P2, ...): number the vertices
        first and the other nodes by the book's ball rule (default), or run the method
        on the full node graph (Remark 17.13: better, more work).
    reduced : bool
        Number on the reduced graph: quads/hexahedra connect along their edges only (Fig.
        17.11 iii). The statistics always count every pair of an element's nodes.
    elements : bool
        Also renumber the elements of each block after their new vertices (§17.4.2).

    Returns
    -------
    Mesh
        Points, refs and data permuted; ``info`` (and so ``stats()``) gains
        ``bandwidth``, ``profile``, ``profile_mean``, the same with ``_before``,
        ``profile_ratio`` (before / after), ``renumber_method``, ``renumber_time``
        (seconds, the method on the graph), ``graph_time`` and ``nodes_per_second``
        (nodes / renumber_time, the book's v), ``renumber_kept_input`` (True when the
        method's numbering had a larger profile, or the same and a larger bandwidth, than
        the input's, which is then kept: a structured grid numbered row by row).

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh.
    ValueError
        Unknown method or option.

    Examples
    --------
    >>> import numpy as np, warpmesh as wm
    >>> pts = np.array([[x, y] for x in range(30) for y in range(3)], float)
    >>> grid = wm.Mesh(pts, {"triangle": [[3 * x + y, 3 * x + y + 3, 3 * x + y + 4]
    ...                                  for x in range(29) for y in range(2)]})
    >>> shuffled = grid.replace(points=pts[::-1], cells={"triangle": 89 - grid.cells["triangle"]})
    >>> r = wm.renumber(shuffled, "gibbs")
    >>> r.stats()["bandwidth"], r.stats()["profile_before"] > r.stats()["profile"]
    (4, True)
    """
    require_mesh(mesh)
    if method not in METHODS:
        raise ValueError(f"expected method among {list(METHODS)}, got {method!r}")
    if higher_order not in ("ball", "graph"):
        raise ValueError(f"expected higher_order='ball' or 'graph', got {higher_order!r}")
    for name, value in (("reduced", reduced), ("elements", elements)):  # (a truthy "no" renumbered the elements)
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"expected True or False for '{name}', got {value!r}")
    if not (isinstance(reverse, (bool, np.bool_)) or reverse == "auto"):
        raise TypeError(f"expected True, False or 'auto' for 'reverse', got {reverse!r}")
    n = mesh.n_points
    wp.load_module(KN, device="cpu")  # compiled once per machine, loaded once per process: not timed
    t0 = time.perf_counter()
    graph = node_graph(mesh.cells, n, reduced=reduced)
    t1 = time.perf_counter()
    walk = None
    if _is_higher_order(mesh) and higher_order == "ball":
        corners = node_graph(mesh.cells, n, nodes="corners", reduced=reduced)
        t1b = time.perf_counter()
        order, walk = _ball_order(mesh, renumber_graph(corners, method, reverse=False))
        if reverse == "auto" or method == "rcm" and reverse != False:  # noqa: E712
            s = matrix_stats(graph, _inverse(order))  # direction of the whole numbering
            flip = method == "rcm" if reverse != "auto" else (
                (s["profile_reversed"], s["bandwidth_reversed"]) < (s["profile"], s["bandwidth"]))
        else:
            flip = bool(reverse)
        if flip:  # the walk run backwards: nodes and elements
            used = np.isin(np.arange(n), np.concatenate([c.ravel() for c in mesh.cells.values()]))
            k = int(used.sum())
            order = np.concatenate([order[:k][::-1], order[k:]])
            walk = {t: w[::-1] for t, w in walk.items()}
        graph_time = (t1 - t0) + (t1b - t1)
        t1 = t1b
    else:
        order = renumber_graph(graph, method, reverse=reverse)
        graph_time = t1 - t0
    elapsed = time.perf_counter() - t1
    new = _inverse(order)
    full = graph if not reduced else node_graph(mesh.cells, n)  # statistics: every coefficient
    before, after = matrix_stats(full), matrix_stats(full, new)
    kept = (after["profile"], after["bandwidth"]) > (before["profile"], before["bandwidth"])
    if kept:  # the input's numbering is better (a structured grid numbered row by row): keep it
        order, new, after, walk = np.arange(n), np.arange(n), before, None
    cells, cell_refs, cell_data = {}, {}, {k: {} for k in mesh.cell_data}
    for t, block in mesh.cells.items():
        block = new[block]
        if not elements:
            keep = np.arange(len(block))
        else:  # the ball walk's order, or by first vertex ([FG §17.4.2])
            keep = walk[t] if walk is not None else element_order(block, np.arange(n))
        cells[t] = block[keep]
        if mesh.cell_refs is not None and t in mesh.cell_refs:
            cell_refs[t] = mesh.cell_refs[t][keep]
        for k in mesh.cell_data:
            cell_data[k][t] = mesh.cell_data[k][t][keep]
    info = {k: v for k, v in mesh.info.items() if k not in _ELEMENT_ORDER_FACTS}
    for k in ("bandwidth", "profile", "profile_mean"):
        info[k], info[k + "_before"] = after[k], before[k]
    info.update(
        profile_ratio=before["profile"] / max(after["profile"], 1),
        renumber_method=method,
        renumber_kept_input=bool(kept),
        renumber_time=elapsed,
        graph_time=graph_time,
        nodes_per_second=n / elapsed if elapsed > 0 else float("inf"),
    )
    return type(mesh)(
        mesh.points[order],
        cells,
        point_data={k: v[order] for k, v in mesh.point_data.items()},
        cell_data=cell_data,
        point_refs=None if mesh.point_refs is None else mesh.point_refs[order],
        cell_refs=cell_refs or None,
        info=info,
    )


#: rows of the statistics table, after [FG Table 17.1]: (label, stats key, format)
TABLE_ROWS = (
    ("np", "np", "{:,}"),
    ("ne", "ne", "{:,}"),
    ("beta (initial)", "bandwidth_before", "{:,}"),
    ("pr (initial)", "profile_before", "{:,}"),
    ("pr_mean (initial)", "profile_mean_before", "{:,.0f}"),
    ("beta (final)", "bandwidth", "{:,}"),
    ("pr (final)", "profile", "{:,}"),
    ("pr_mean (final)", "profile_mean", "{:,.0f}"),
    ("pr ratio", "profile_ratio", "{:,.2f}"),
    ("v (nodes/s)", "nodes_per_second", "{:,.0f}"),
)


def format_table(columns: dict[str, dict]) -> str:
    """The statistics of renumbered meshes as [FG Table 17.1]: one column per mesh.

    Parameters
    ----------
    columns : {name: stats}
        ``Mesh.stats()`` of renumbered meshes (or any dicts with the keys of
        :data:`TABLE_ROWS`; missing ones print "-").

    Examples
    --------
    >>> print(format_table({"a": {"np": 1200, "bandwidth": 30}}).splitlines()[1])
    np                    1,200
    """
    names = list(columns)
    cells = [[label] + [fmt.format(columns[m][key]) if columns[m].get(key) is not None else "-"
                        for m in names] for label, key, fmt in TABLE_ROWS]
    header = ["mesh"] + names
    widths = [max(len(r[i]) for r in [header] + cells) for i in range(len(header))]
    widths[0] = max(widths[0], 20)

    def line(row):
        return "  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(row, widths)))

    return "\n".join([line(header)] + [line(r) for r in cells])
