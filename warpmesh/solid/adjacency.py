"""Adjacency of tetrahedral meshes, vectorised numpy: unique edges, the tetrahedra around
each vertex (CSR) and the gathering of CSR rows.

Example
-------
>>> import numpy as np
>>> tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
>>> len(unique_edges(tets)), vertex_tets(tets, 5)[0].tolist()
(9, [0, 1, 3, 5, 7, 8])
"""

from __future__ import annotations

import numpy as np

from warpmesh._util.arrays import run_ranks

__all__ = ["TET_EDGES", "TRI_EDGES", "unique_edges", "vertex_tets", "gather_rows"]

#: local vertex pairs of the edges of a tetrahedron and of a triangle
TET_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
TRI_EDGES = ((0, 1), (1, 2), (0, 2))


def unique_edges(cells, pairs=TET_EDGES) -> np.ndarray:
    """(k, 2) int64 the sorted unique vertex pairs of ``cells`` at local ``pairs``, in
    lexicographic order.

    >>> unique_edges(np.array([[0, 1, 2]]), TRI_EDGES).tolist()
    [[0, 1], [0, 2], [1, 2]]
    """
    cells = np.asarray(cells, dtype=np.int64)
    if not len(cells):
        return np.zeros((0, 2), np.int64)
    e = np.sort(np.concatenate([cells[:, [i, j]] for i, j in pairs]), axis=1)
    n = np.int64(cells.max() + 1)
    key = np.unique(e[:, 0] * n + e[:, 1])  # int64 keys: far faster than unique rows
    return np.stack([key // n, key % n], axis=1)


def vertex_tets(tets, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(ptr (n + 1,), idx): the tetrahedra around vertex v are ``idx[ptr[v]:ptr[v + 1]]``."""
    flat = np.asarray(tets, dtype=np.int64).ravel()
    idx = np.argsort(flat, kind="stable") // 4
    ptr = np.zeros(n + 1, np.int64)
    ptr[1:] = np.cumsum(np.bincount(flat, minlength=n))
    return ptr, idx


def gather_rows(ptr, idx, rows) -> tuple[np.ndarray, np.ndarray]:
    """(owner, items): the CSR rows ``rows`` flattened, with the position in ``rows`` each
    item came from.

    >>> gather_rows(np.array([0, 2, 3]), np.array([7, 8, 9]), np.array([1, 0]))
    (array([0, 1, 1]), array([9, 7, 8]))
    """
    rows = np.asarray(rows, dtype=np.int64)
    counts = ptr[rows + 1] - ptr[rows]
    owner = np.repeat(np.arange(len(rows)), counts)
    local = run_ranks(counts)
    return owner, idx[np.repeat(ptr[rows], counts) + local]
