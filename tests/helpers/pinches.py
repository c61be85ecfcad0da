"""The pinch oracle of multi-region meshes: vertices where a label's boundary is not a manifold.

Used by tests/solid/test_regions.py's ``check_regions`` (every multi-region mesh of the suite)
and by benchmarks/bench_regions.py. Written apart from warpmesh's own topology code.
"""

from __future__ import annotations

import numpy as np


def pinched_vertices(tris: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> dict[int, int]:
    """{label: the number of vertices where its boundary (the triangles naming it) is not a
    manifold}, labels with none left out. At a vertex v of a closed manifold surface, the
    edges (a, b) opposite v of its triangles form one cycle: every a has two of them, and they
    are connected (scipy's graph search over the (label, v, a) nodes)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    lab = np.concatenate([lower, upper])
    t = np.concatenate([tris, tris])
    n = int(tris.max()) + 1
    codes, lab = np.unique(lab, return_inverse=True)
    # per corner (label, v) the link edge (a, b)
    v = np.concatenate([t[:, 0], t[:, 1], t[:, 2]])
    a = np.concatenate([t[:, 1], t[:, 2], t[:, 0]])
    b = np.concatenate([t[:, 2], t[:, 0], t[:, 1]])
    lv = np.tile(lab, 3) * n + v  # (label, v)
    ends, node = np.unique(np.concatenate([lv * n + a, lv * n + b]), return_inverse=True)
    k = len(v)
    degree = np.bincount(node, minlength=len(ends))
    graph = coo_matrix((np.ones(k), (node[:k], node[k:])), shape=(len(ends),) * 2)
    _, comp = connected_components(graph, directed=False)
    owner = ends // n  # the (label, v) of each link node
    cycles = np.unique(np.column_stack([owner, comp]), axis=0)[:, 0]
    wrong = np.unique(np.concatenate([owner[degree != 2], cycles[np.r_[cycles[1:] == cycles[:-1], False]]]))
    counts = np.bincount(wrong // n, minlength=len(codes))
    return {int(codes[c]): int(counts[c]) for c in np.flatnonzero(counts)}
