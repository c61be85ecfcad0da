"""Element colouring [FG §17.4.4]: valid packets, no more colours than the sequential
largest-first greedy colouring (networkx), red-black where two colours suffice."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest
import trimesh
from tests.helpers.numbering_meshes import ball, hexbeam, plate, sphere_surface

import warpmesh as wm
from warpmesh.numbering.coloring import (
    _largest_first,
    element_colors,
    element_graph,
    is_valid_coloring,
)


def quad_grid(nx_: int = 6, ny: int = 4) -> wm.Mesh:
    pts = np.array([[x, y] for x in range(nx_ + 1) for y in range(ny + 1)], float)
    quads = [[(ny + 1) * x + y, (ny + 1) * (x + 1) + y, (ny + 1) * (x + 1) + y + 1, (ny + 1) * x + y + 1]
             for x in range(nx_) for y in range(ny)]
    return wm.Mesh(pts, {"quad": quads})


MESHES = {
    "plate": lambda: plate(0.1),
    "sphere": lambda: sphere_surface(16),
    "ball": lambda: ball(3),
    "hexbeam": hexbeam,
    "quads": quad_grid,
    "p2-plate": lambda: plate(0.3).to_order(2),
}


def greedy_largest_first(mesh, adjacency) -> int:
    graph, _ = element_graph(mesh, adjacency)
    g = nx.from_scipy_sparse_array(graph)
    return max(nx.greedy_color(g, strategy="largest_first").values(), default=-1) + 1


@pytest.mark.parametrize("adjacency", ["face", "node"])
@pytest.mark.parametrize("name", list(MESHES))
def test_valid_and_no_worse_than_greedy_largest_first(name, adjacency):
    m = MESHES[name]()
    colors = element_colors(m, adjacency=adjacency)
    assert is_valid_coloring(m, colors, adjacency=adjacency)
    k = int(max(c.max() for c in colors.values())) + 1
    assert k <= greedy_largest_first(m, adjacency)
    # brute force: no neighbours share a colour
    graph, types = element_graph(m, adjacency)
    flat = np.concatenate([colors[t] for t in types])
    rows = np.repeat(np.arange(graph.shape[0]), np.diff(graph.indptr))
    assert not np.any(flat[rows] == flat[graph.indices])


@pytest.mark.parametrize("name", ["plate", "hexbeam", "quads"])
def test_rounds_give_networkx_largest_first(name):
    graph, _ = element_graph(MESHES[name](), "node")
    g = nx.from_scipy_sparse_array(graph)
    ref = nx.greedy_color(g, strategy="largest_first")  # one element at a time
    assert _largest_first(graph).tolist() == [ref[e] for e in range(graph.shape[0])]


def test_red_black_where_two_colours_suffice():
    for m in (quad_grid(), hexbeam()):
        colors = element_colors(m)
        assert max(int(c.max()) for c in colors.values()) == 1
        assert is_valid_coloring(m, colors)
    assert max(int(c.max()) for c in element_colors(quad_grid(), adjacency="node").values()) == 3


def test_non_manifold_edges_make_every_owner_a_neighbour():
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]]
    m = wm.Mesh(pts, {"triangle": [[0, 1, 2], [0, 1, 3], [0, 1, 4]]})  # three on edge 0-1
    graph, _ = element_graph(m)
    assert graph.nnz == 6
    assert sorted(element_colors(m)["triangle"].tolist()) == [0, 1, 2]


def test_element_graph_neighbours():
    m = wm.Mesh.from_trimesh(trimesh.creation.icosphere(1))
    face, _ = element_graph(m, "face")
    assert np.all(np.diff(face.indptr) == 3)  # a closed surface: three edge neighbours each
    node, _ = element_graph(m, "node")
    assert np.all(np.diff(node.indptr) >= 9)


def test_color_elements_packets_and_attributes():
    m = plate(0.15)
    m = m.replace(cell_refs={"triangle": np.arange(len(m.triangles)) % 4},
                  cell_data={"id": {"triangle": np.arange(len(m.triangles))}})
    c = m.color_elements(adjacency="node")
    color = c.cell_data["color"]["triangle"]
    assert np.all(np.diff(color) >= 0)  # packets are contiguous
    s = c.stats()
    assert s["n_colors"] == color.max() + 1 and s["packet_sizes"] == np.bincount(color).tolist()
    ids = c.cell_data["id"]["triangle"]
    assert np.array_equal(c.cells["triangle"], m.cells["triangle"][ids])
    assert np.array_equal(c.cell_refs["triangle"], ids % 4)
    assert is_valid_coloring(c, {"triangle": color}, adjacency="node")


def test_lower_dimensional_blocks_are_not_coloured():
    m = plate(0.3)
    edges = m.triangles[:, :2]
    c = m.replace(cells={"triangle": m.triangles, "line": edges}).color_elements()
    assert np.all(c.cell_data["color"]["line"] == -1)
    assert (c.cell_data["color"]["triangle"] >= 0).all()


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda m: element_colors(m, adjacency="edge"), "adjacency"),
        (lambda m: element_colors(wm.Mesh([[0, 0], [1, 1]], {"vertex": [[0], [1]]})), "elements"),
        (lambda m: wm.numbering.coloring.color_mesh(m.points), "mesh"),
    ],
)
def test_bad_input(call, match):
    import warpmesh.numbering.coloring  # noqa: F401

    with pytest.raises((ValueError, TypeError), match=match):
        call(plate(0.5))


def test_degenerate_and_empty_blocks():
    pts = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], float)
    m = wm.Mesh(pts, {"triangle": [[0, 1, 2], [1, 3, 2], [3, 3, 1]]})  # the last is degenerate
    for adjacency in ("face", "node"):
        colors = element_colors(m, adjacency=adjacency)
        assert is_valid_coloring(m, colors, adjacency=adjacency)
    empty = wm.Mesh(pts, {"triangle": np.zeros((0, 3), int)})
    assert element_colors(empty)["triangle"].shape == (0,)
