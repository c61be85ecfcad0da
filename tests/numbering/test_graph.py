"""Node graphs and level structures [FG §17.4.1, Fig. 17.11] against brute force."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from tests.helpers.numbering_meshes import hexbeam, plate
from scipy.sparse.csgraph import shortest_path

import warpmesh as wm
from warpmesh.numbering.graph import corner_count, degrees, expand, levels, node_graph


def pairs_brute_force(cells, nodes=None):
    out = set()
    for t, block in cells.items():
        k = corner_count(t) if nodes == "corners" else block.shape[1]
        for c in block[:, :k]:
            out |= {(a, b) for a, b in itertools.permutations(c.tolist(), 2) if a != b}
    return out


def as_pairs(g):
    rows = np.repeat(np.arange(g.shape[0]), np.diff(g.indptr))
    return set(zip(rows.tolist(), g.indices.tolist()))


def test_node_graph_is_every_pair_of_an_element():
    m = plate(0.4).to_order(2)
    cells = {"triangle6": m.cells["triangle6"], "line": np.array([[0, 1], [5, 9]])}
    g = node_graph(cells, m.n_points)
    assert as_pairs(g) == pairs_brute_force(cells)
    assert g.has_sorted_indices and g.indices.dtype == np.int32
    corners = node_graph(cells, m.n_points, nodes="corners")
    assert as_pairs(corners) == pairs_brute_force(cells, "corners")
    assert np.array_equal(degrees(g), np.diff(g.indptr))


def test_reduced_graph_keeps_element_edges_only():
    m = hexbeam()
    full, reduced = node_graph(m.cells, m.n_points), node_graph(m.cells, m.n_points, reduced=True)
    assert full.nnz == len(pairs_brute_force(m.cells))
    edges = {tuple(sorted(e)) for c in m.cells["hexahedron"]
             for e in [(c[a], c[b]) for a, b in ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6),
                                                  (6, 7), (7, 4), (0, 4), (1, 5), (2, 6), (3, 7))]}
    assert {tuple(sorted(p)) for p in as_pairs(reduced)} == edges
    assert reduced.nnz == 2 * len(edges)


def test_levels_are_breadth_first_distances():
    m = plate(0.3)
    g = node_graph(m.cells, m.n_points)
    dist = shortest_path(g, unweighted=True, indices=[7])[0]
    lv, order, starts = levels(g, 7)
    assert np.array_equal(lv, np.where(np.isinf(dist), -1, dist).astype(int))
    assert np.array_equal(np.sort(order), np.flatnonzero(lv >= 0))
    for k in range(len(starts) - 1):
        assert set(order[starts[k]: starts[k + 1]].tolist()) == set(np.flatnonzero(lv == k).tolist())


def test_expand_lists_neighbours_in_row_order():
    g = node_graph(plate(0.4).cells, plate(0.4).n_points)
    rows = np.array([5, 2, 5])
    nb, src = expand(g, rows)
    ref = np.concatenate([g.indices[g.indptr[r]: g.indptr[r + 1]] for r in rows])
    assert np.array_equal(nb, ref) and np.array_equal(rows[src], np.repeat(rows, np.diff(g.indptr)[rows]))


def test_a_node_listed_twice_is_no_self_edge():
    g = node_graph({"triangle": np.array([[0, 0, 1]])}, 2)
    assert not g.diagonal().any() and g.nnz == 2


def test_bad_input():
    with pytest.raises(ValueError, match="nodes"):
        node_graph({"triangle": np.array([[0, 1, 2]])}, 3, nodes="vertices")
    with pytest.raises(ValueError, match="cell type"):
        corner_count("hexagon")
    assert node_graph({}, 4).nnz == 0
    assert node_graph({"vertex": np.array([[0], [2]])}, 3).nnz == 0
    assert isinstance(wm.Mesh([[0, 0]], {"vertex": [[0]]}), wm.Mesh)
