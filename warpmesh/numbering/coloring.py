"""Element colouring [FG §17.4.4]: packets of elements in which no two are neighbours.

Two elements are *neighbours* when they share a facet (``adjacency="face"``: an edge of
2D elements, a face of 3D elements — the book's element adjacency, where structured
grids need only two colours, "red–black") or any node (``adjacency="node"``: the
packets a vector or multi-threaded assembly can process without write conflicts).

The colouring is the greedy one in largest-first order (elements of more neighbours
first, ties by index; a one-thread kernel), then improved by iterated greedy passes that recolour one colour class
at a time (Culberson: never more colours), and replaced by the two colours of the
breadth-first levels when the element graph is bipartite.

Examples
--------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.numbering.coloring import element_colors, is_valid_coloring
>>> pts = np.array([[x, y] for x in range(5) for y in range(5)], float)
>>> quads = [[5 * x + y, 5 * x + y + 5, 5 * x + y + 6, 5 * x + y + 1]
...          for x in range(4) for y in range(4)]
>>> m = wm.Mesh(pts, {"quad": quads})
>>> c = element_colors(m)                 # faces: red-black
>>> int(c["quad"].max()) + 1, is_valid_coloring(m, c)
(2, True)
>>> int(element_colors(m, adjacency="node")["quad"].max()) + 1
4
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import scipy.sparse as sp
import warp as wp
from scipy.sparse.csgraph import connected_components

from warpmesh.kernels import numbering as KN

from warpmesh.cells.types import CELL_TYPES, require_mesh
from warpmesh.numbering.graph import corner_count, expand, levels
from warpmesh.numbering.renumber import _as_wp, _order_by

__all__ = ["element_graph", "element_colors", "is_valid_coloring", "color_mesh"]

Adjacency = Literal["face", "node"]

#: local facets of the linear cells (faces in 3D, edges in 2D), on corner nodes
_FACETS = {
    "line": ((0,), (1,)),
    "triangle": ((0, 1), (1, 2), (2, 0)),
    "quad": ((0, 1), (1, 2), (2, 3), (3, 0)),
    "tetra": ((0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3)),
    "hexahedron": ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6),
                   (3, 0, 4, 7)),
    "wedge": ((0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)),
    "pyramid": ((0, 1, 2, 3), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)),
}
#: iterated-greedy passes after the largest-first colouring
GREEDY_PASSES = 6


def _elements(mesh) -> list[str]:
    """The blocks of the highest topological dimension: the mesh's elements."""
    dims = {t: CELL_TYPES[t][1] for t in mesh.cells}
    top = max(dims.values(), default=-1)
    if top < 1:
        raise ValueError(f"expected a mesh with elements (lines or higher), got blocks {list(dims)}")
    return [t for t in mesh.cells if dims[t] == top]


def element_graph(mesh, adjacency: Adjacency = "face") -> tuple[sp.csr_matrix, list[str]]:
    """The element-to-element graph of the mesh's top-dimensional blocks.

    Returns
    -------
    graph : (ne, ne) csr_matrix, bool
        Symmetric, no diagonal; elements numbered block after block.
    types : list of str
        The blocks, in that order.

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], {"triangle": [[0, 1, 3], [0, 3, 2]]})
    >>> element_graph(m)[0].nnz
    2
    """
    if adjacency not in ("face", "node"):
        raise ValueError(f"expected adjacency='face' or 'node', got {adjacency!r}")
    types = _elements(mesh)
    blocks = [mesh.cells[t] for t in types]
    ne = sum(len(b) for b in blocks)
    offsets = np.cumsum([0] + [len(b) for b in blocks])
    if adjacency == "node":
        rows = np.concatenate([np.repeat(np.arange(len(b)) + o, b.shape[1])
                               for b, o in zip(blocks, offsets)])
        cols = np.concatenate([b.ravel() for b in blocks])
        inc = sp.csr_matrix((np.ones(len(rows), np.int32), (rows, cols)),
                            shape=(ne, mesh.n_points))
        graph = (inc @ inc.T).tocsr()
        graph.setdiag(0)
        graph.eliminate_zeros()
    else:
        keys, owners = [], []
        for t, b, o in zip(types, blocks, offsets):
            base = t.rstrip("0123456789")
            corners = b[:, : corner_count(t)]
            for local in _FACETS[base]:
                f = np.sort(corners[:, local], axis=1)
                keys.append(np.pad(f, ((0, 0), (0, 4 - f.shape[1])), constant_values=-1))
                owners.append(np.arange(len(b)) + o)
        keys, owners = np.concatenate(keys), np.concatenate(owners)
        base = mesh.n_points + 1
        if float(base) ** 4 < 2.0**62:  # one int64 per facet
            keys = (((keys[:, 0] + 1) * base + keys[:, 1] + 1) * base + keys[:, 2] + 1) * base + keys[:, 3] + 1
            _, facet, count = np.unique(keys, return_inverse=True, return_counts=True)
        else:
            _, facet, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        facet = facet.ravel()
        order = np.argsort(facet, kind="stable")
        facet, owners = facet[order], owners[order]
        # every two owners of a facet are neighbours (more than two on a non-manifold edge)
        rows, cols = [], []
        for k in range(1, int(count.max(initial=1))):
            same = facet[k:] == facet[:-k]
            rows += [owners[:-k][same], owners[k:][same]]
            cols += [owners[k:][same], owners[:-k][same]]
        rows = np.concatenate(rows) if rows else np.zeros(0, np.int64)
        cols = np.concatenate(cols) if cols else np.zeros(0, np.int64)
        rows, cols = rows[rows != cols], cols[rows != cols]  # a degenerate cell lists a facet twice
        graph = sp.csr_matrix((np.ones(len(rows), bool), (rows, cols)), shape=(ne, ne))
    graph = graph.astype(bool).tocsr()
    graph.sort_indices()
    return graph, types


def _smallest_free(graph, rows, color) -> np.ndarray:
    """For each of ``rows``, the smallest colour no coloured neighbour has."""
    nb, src = expand(graph, rows)
    c = color[nb]
    src, c = src[c >= 0], c[c >= 0]
    result = np.full(len(rows), -1, np.int64)
    base = 0
    while (result < 0).any():  # 64 colours per word
        inword = (c >= base) & (c < base + 64)
        used = np.zeros(len(rows), np.uint64)
        np.bitwise_or.at(used, src[inword], np.left_shift(np.uint64(1), (c[inword] - base).astype(np.uint64)))
        free = ~used
        low = free & (~free + np.uint64(1))  # lowest free bit
        todo = (result < 0) & (free != 0)
        result[todo] = base + np.log2(low[todo].astype(np.float64)).astype(np.int64)
        base += 64
    return result


def _largest_first(graph) -> np.ndarray:
    """The greedy colouring in largest-first order (ties: smaller index first, as
    networkx's ``greedy_color(strategy="largest_first")``): one element at a time, the
    smallest colour none of its neighbours already has (a one-thread kernel, O(edges))."""
    ne = graph.shape[0]
    if not ne:
        return np.zeros(0, np.int64)
    deg = np.diff(graph.indptr).astype(np.int64)
    order = _order_by(deg.max() - deg, np.arange(ne))
    color = np.full(ne, -1, np.int32)
    wp.launch(KN.greedy_color_kernel, dim=1,
              inputs=[_as_wp(graph.indptr.astype(np.int32)), _as_wp(graph.indices.astype(np.int32)),
                      _as_wp(order.astype(np.int32))],
              outputs=[_as_wp(color, copy=False), _as_wp(np.full(int(deg.max()) + 2, -1, np.int32))],
              device="cpu")
    wp.synchronize_device("cpu")
    return color.astype(np.int64)


def _iterated_greedy(graph, color, order: str) -> np.ndarray:
    """Recolour class by class (members of a class are independent): never more colours."""
    sizes = np.bincount(color)
    classes = np.argsort(-sizes, kind="stable") if order == "largest" else np.arange(len(sizes))[::-1]
    new = np.full(len(color), -1, np.int64)
    by_color = np.argsort(color, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    for c in classes:
        members = by_color[bounds[c]: bounds[c + 1]]
        if len(members):
            new[members] = _smallest_free(graph, members, new)
    return new


def _two_coloring(graph) -> np.ndarray | None:
    """Parity of the breadth-first levels, if that is a valid colouring (bipartite)."""
    ne = graph.shape[0]
    _, label = connected_components(graph, directed=True, connection="strong")
    roots = np.unique(label, return_index=True)[1]
    # one search from a virtual node joined to a root of every component
    link = sp.csr_matrix((np.ones(2 * len(roots), bool),
                          (np.r_[np.full(len(roots), ne), roots], np.r_[roots, np.full(len(roots), ne)])),
                         shape=(ne + 1, ne + 1))
    augmented = sp.bmat([[graph, None], [None, sp.csr_matrix((1, 1), dtype=bool)]]).tocsr() + link
    color = (levels(augmented.tocsr(), ne)[0][:ne] % 2).astype(np.int64)
    rows = np.repeat(np.arange(ne), np.diff(graph.indptr))
    return None if (color[rows] == color[graph.indices]).any() else color


def element_colors(mesh, *, adjacency: Adjacency = "face") -> dict[str, np.ndarray]:
    """A colour for every element of the mesh's top-dimensional blocks.

    Parameters
    ----------
    mesh : Mesh
    adjacency : {"face", "node"}
        Neighbours share a facet, or any node (see the module docstring).

    Returns
    -------
    dict {cell type: (m,) int64}
        Colours 0..k-1, one array per top-dimensional block.

    Raises
    ------
    ValueError
        Unknown adjacency, a mesh without elements.
    """
    graph, types = element_graph(mesh, adjacency)
    color = _largest_first(graph)
    best = color.max(initial=-1) + 1
    for p in range(GREEDY_PASSES):
        color = _iterated_greedy(graph, color, "largest" if p % 2 else "reverse")
        k = color.max(initial=-1) + 1
        if k == best and p:
            break
        best = min(best, k)
    if best > 2 and graph.nnz:
        two = _two_coloring(graph)
        color = color if two is None else two
    sizes = np.cumsum([0] + [len(mesh.cells[t]) for t in types])
    return {t: color[sizes[i]: sizes[i + 1]] for i, t in enumerate(types)}


def is_valid_coloring(mesh, colors: dict, *, adjacency: Adjacency = "face") -> bool:
    """True if no two neighbouring elements share a colour (and every element has one)."""
    graph, types = element_graph(mesh, adjacency)
    if set(colors) != set(types):
        return False
    color = np.concatenate([np.asarray(colors[t]) for t in types])
    if len(color) != graph.shape[0] or (color < 0).any():
        return False
    rows = np.repeat(np.arange(graph.shape[0]), np.diff(graph.indptr))
    return not (color[rows] == color[graph.indices]).any()


def color_mesh(mesh, *, adjacency: Adjacency = "face"):
    """A copy of ``mesh`` whose elements are renumbered into packets, one per colour.

    Each top-dimensional block is sorted by colour (stable: the old order within a
    packet); ``cell_data["color"]`` holds the colours (-1 on lower-dimensional blocks),
    and ``info`` (so ``stats()``) ``n_colors``, ``packet_sizes`` (elements per colour)
    and ``color_adjacency``.

    Examples
    --------
    >>> import trimesh, warpmesh as wm
    >>> m = wm.Mesh.from_trimesh(trimesh.creation.icosphere(2)).color_elements()
    >>> m.stats()["n_colors"] <= 4, sum(m.stats()["packet_sizes"]) == m.n_cells
    (True, True)
    """
    require_mesh(mesh)
    colors = element_colors(mesh, adjacency=adjacency)
    cells, refs, data = {}, {}, {k: {} for k in mesh.cell_data}
    data["color"] = {}
    for t, block in mesh.cells.items():
        keep = np.argsort(colors[t], kind="stable") if t in colors else np.arange(len(block))
        cells[t] = block[keep]
        data["color"][t] = colors[t][keep] if t in colors else np.full(len(block), -1)
        if mesh.cell_refs is not None and t in mesh.cell_refs:
            refs[t] = mesh.cell_refs[t][keep]
        for k in mesh.cell_data:
            data[k][t] = mesh.cell_data[k][t][keep]
    allc = np.concatenate(list(colors.values()))
    sizes = np.bincount(allc)
    info = dict(mesh.info, n_colors=len(sizes), packet_sizes=sizes.tolist(),
                color_adjacency=adjacency)
    return mesh.replace(cells=cells, cell_refs=refs or None, cell_data=data, info=info)
