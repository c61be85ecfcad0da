"""Node graphs of meshes and breadth-first level structures [FG §17.4.1, Fig. 17.11].

Two nodes are *neighbours* when some element has both as nodes (Fig. 17.11 i): every
pair of an element's nodes interacts in the finite-element matrix). With
``reduced=True`` quadrilateral and hexahedral faces drop their diagonals (Fig. 17.11
iii): only the element's edges connect nodes. ``nodes="corners"`` keeps the vertices
of higher-order elements only (the P1 graph of a P2 mesh, seed "arbitrary meshes").

The graph is a symmetric ``scipy.sparse.csr_matrix`` (bool data, int32 indices, sorted
rows, no diagonal); :func:`levels` gives the *descent* of a node (its level structure
N_1(P), N_2(P), ...) and its depth d(P).

Examples
--------
>>> import numpy as np
>>> from warpmesh.numbering.graph import node_graph, levels
>>> g = node_graph({"triangle": np.array([[0, 1, 2], [1, 3, 2]])}, 4)
>>> g.indptr.tolist(), g.indices.tolist()
([0, 2, 5, 8, 10], [1, 2, 0, 2, 3, 0, 1, 3, 1, 2])
>>> levels(g, 0)[0].tolist()     # level of each node in the descent of node 0
[0, 1, 1, 2]
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Literal

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

from warpmesh.cells.types import CELL_TYPES

__all__ = ["node_graph", "corner_count", "levels", "degrees", "expand"]

#: local edges of the linear cells whose faces are not simplices (Fig. 17.11 iii)
_EDGES = {
    "quad": ((0, 1), (1, 2), (2, 3), (3, 0)),
    "hexahedron": ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                   (0, 4), (1, 5), (2, 6), (3, 7)),
    "wedge": ((0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)),
    "pyramid": ((0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 4), (2, 4), (3, 4)),
}


def corner_count(cell_type: str) -> int:
    """Number of vertices (corner nodes) of a meshio cell type: its linear type's nodes.

    Examples
    --------
    >>> corner_count("tetra10"), corner_count("quad9"), corner_count("triangle")
    (4, 4, 3)
    """
    base = cell_type.rstrip("0123456789")
    if base not in CELL_TYPES:
        raise ValueError(f"expected a cell type among {sorted(CELL_TYPES)}, got {cell_type!r}")
    return CELL_TYPES[base][0]


def _pairs(block: np.ndarray, cell_type: str, reduced: bool):
    """(lo, hi) int32 node pairs of one block, one per local pair (duplicates kept)."""
    k = block.shape[1]
    base = cell_type.rstrip("0123456789")
    if reduced and base in _EDGES and k == CELL_TYPES[base][0]:
        local = _EDGES[base]
    else:
        local = [(i, j) for i in range(k) for j in range(i + 1, k)]
    cols = np.ascontiguousarray(block.T, dtype=np.int32)
    lo = np.empty(len(local) * len(block), np.int32)
    hi = np.empty_like(lo)
    for p, (i, j) in enumerate(local):
        s = slice(p * len(block), (p + 1) * len(block))
        np.minimum(cols[i], cols[j], out=lo[s])
        np.maximum(cols[i], cols[j], out=hi[s])
    return lo, hi


def node_graph(
    cells: Mapping[str, np.ndarray],
    n: int,
    *,
    nodes: Literal["all", "corners"] = "all",
    reduced: bool = False,
) -> sp.csr_matrix:
    """The symmetric node-to-node graph of a mesh's cells.

    Parameters
    ----------
    cells : {cell type: (m, k) int}
        Cell blocks (``Mesh.cells``); "vertex" blocks add no pair.
    n : int
        Number of nodes (rows of the graph); nodes in no cell are isolated.
    nodes : {"all", "corners"}
        All nodes of every element, or only its vertices (the P1 graph).
    reduced : bool
        Connect quad/hexahedron/wedge/pyramid nodes along element edges only.

    Returns
    -------
    (n, n) csr_matrix, bool
        No diagonal, sorted rows, int32 indices.

    Examples
    --------
    >>> g = node_graph({"quad": np.array([[0, 1, 2, 3]])}, 4, reduced=True)
    >>> g.nnz, node_graph({"quad": np.array([[0, 1, 2, 3]])}, 4).nnz
    (8, 12)
    """
    if nodes not in ("all", "corners"):
        raise ValueError(f"expected nodes='all' or 'corners', got {nodes!r}")
    if n >= np.iinfo(np.int32).max:
        raise ValueError(f"expected fewer than 2**31 - 1 nodes, got n={n}")
    los, his = [], []
    for t, block in cells.items():
        block = np.asarray(block)
        if nodes == "corners":
            block = block[:, : corner_count(t)]
        if block.shape[1] < 2 or not len(block):
            continue
        lo, hi = _pairs(block, t, reduced)
        los.append(lo)
        his.append(hi)
    lo = np.concatenate(los) if los else np.zeros(0, np.int32)
    hi = np.concatenate(his) if his else np.zeros(0, np.int32)
    keep = lo != hi  # a cell that lists a node twice is no edge of it
    lo, hi = lo[keep], hi[keep]
    upper = sp.csr_matrix((np.ones(len(lo), bool), (lo, hi)), shape=(n, n))  # sums duplicates
    g = (upper + upper.T).tocsr()
    if g.nnz >= np.iinfo(np.int32).max:
        raise ValueError(f"expected fewer than 2**31 - 1 node pairs, got {g.nnz}: split the mesh")
    g.sort_indices()
    g.indices = g.indices.astype(np.int32, copy=False)
    g.indptr = g.indptr.astype(np.int32, copy=False)
    g.has_sorted_indices = True  # still sorted: only the index dtype changed
    return g


def degrees(graph: sp.csr_matrix) -> np.ndarray:
    """(n,) int64: number of neighbours of each node, deg(P)."""
    return np.diff(graph.indptr).astype(np.int64)


def expand(graph: sp.csr_matrix, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Neighbours of ``rows``, concatenated, and for each the position of its row.

    Returns
    -------
    neighbours : (s,) int
    source : (s,) int64
        ``neighbours[t]`` is a neighbour of ``rows[source[t]]``; rows come in order.

    Examples
    --------
    >>> g = node_graph({"triangle": np.array([[0, 1, 2]])}, 3)
    >>> [a.tolist() for a in expand(g, np.array([2, 0]))]
    [[0, 1, 1, 2], [0, 0, 1, 1]]
    """
    start = graph.indptr[rows].astype(np.int64)
    count = graph.indptr[rows + 1] - start
    total = int(count.sum())
    first = np.cumsum(count) - count
    offsets = np.repeat(start - first, count) + np.arange(total)
    return graph.indices[offsets], np.repeat(np.arange(len(rows)), count)


def levels(graph: sp.csr_matrix, root: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The descent D(P) of node ``root``: breadth-first levels N_0 = {P}, N_1(P), ...

    Returns
    -------
    level : (n,) int32
        Level of each node, -1 outside the root's connected component.
    order : (c,) int
        The component's nodes in breadth-first order (level by level).
    starts : (d + 1,) int64
        ``order[starts[k]:starts[k + 1]]`` is level k; d = depth d(P) = number of levels.

    Examples
    --------
    >>> g = node_graph({"line": np.array([[0, 1], [1, 2], [3, 4]])}, 5)
    >>> lv, order, starts = levels(g, 1)
    >>> lv.tolist(), starts.tolist()
    ([1, 0, 1, -1, -1], [0, 1, 3])
    """
    order, pred = breadth_first_order(graph, int(root), directed=True, return_predecessors=True)
    position = np.empty(graph.shape[0], np.int64)
    position[order] = np.arange(len(order))
    parent = position[pred[order[1:]]]  # nondecreasing: children follow their parents' order
    starts = [0, 1]
    while starts[-1] < len(order):
        starts.append(1 + int(np.searchsorted(parent, starts[-1], side="left")))
    starts = np.asarray(starts, np.int64)
    level = np.full(graph.shape[0], -1, np.int32)
    level[order] = np.repeat(np.arange(len(starts) - 1, dtype=np.int32), np.diff(starts))
    return level, order, starts
