"""Reference cells: local vertices, edges, faces, mirror permutations, signed measures, and
nodes defined as weighted combinations of mesh vertices.

One table serves every mesh modification [FG ch. 17]: transformations permute local
vertices with :func:`mirror_permutation`; refinement and type conversion create nodes with
:func:`weighted_nodes`, which numbers a node shared by several elements (an edge midpoint,
a face centre) once; tests check orientation and conservation with :func:`cell_measures`.

Local numbering is VTK's (meshio's for every type here). A cell of full dimension has a
positive measure: 2D cells are counter-clockwise, 3D cells have positive volume, and the
faces listed for 3D cells are oriented outwards (right-hand rule).

Examples
--------
>>> import numpy as np
>>> from warpmesh.cells.reference import cell_measures, mirror_permutation
>>> mirror_permutation("triangle6").tolist()
[0, 2, 1, 5, 4, 3]
>>> pts = np.array([[0.0, 0], [1, 0], [0, 1]])
>>> cell_measures(pts, np.array([[0, 1, 2], [0, 2, 1]]), "triangle").tolist()
[0.5, -0.5]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from types import MappingProxyType

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.arrays import unique_rows
from warpmesh.cells.lagrange import reference_nodes
from warpmesh.cells.types import CELL_TYPES

__all__ = [
    "P1_TYPES",
    "RefCell",
    "reference_cell",
    "base_type",
    "mirror_permutation",
    "node_weights",
    "cell_measures",
    "corner_jacobians",
    "weighted_nodes",
    "extend_point_values",
]


@dataclass(frozen=True)
class RefCell:
    """A P1 reference cell: ``vertices`` (nv, tdim) float, ``edges`` (ne, 2) int, ``faces``
    tuple of local-vertex tuples (3D cells, outward; empty otherwise), ``mirror`` (nv,) int
    (a permutation that reverses the orientation), ``tdim``."""

    name: str
    vertices: np.ndarray
    edges: np.ndarray
    faces: tuple[tuple[int, ...], ...]
    mirror: np.ndarray
    tdim: int


def _ref(name, vertices, edges, faces, mirror) -> RefCell:
    v = np.array(vertices, dtype=REAL_DTYPE).reshape(len(vertices), -1)
    e, m = np.array(edges, dtype=INDEX_DTYPE).reshape(-1, 2), np.array(mirror, dtype=INDEX_DTYPE)
    for a in (v, e, m):
        a.setflags(write=False)
    return RefCell(name, v, e, tuple(tuple(f) for f in faces), m, v.shape[1] if name != "vertex" else 0)


_QUAD_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0)]
_CELLS: Mapping[str, RefCell] = MappingProxyType({
    "vertex": _ref("vertex", [[0.0]], [], [], [0]),
    "line": _ref("line", [[0.0], [1.0]], [(0, 1)], [], [1, 0]),
    "triangle": _ref("triangle", [[0, 0], [1, 0], [0, 1]], [(0, 1), (1, 2), (2, 0)], [], [0, 2, 1]),
    "quad": _ref("quad", [[0, 0], [1, 0], [1, 1], [0, 1]], _QUAD_EDGES, [], [0, 3, 2, 1]),
    "tetra": _ref(
        "tetra", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
        [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)],
        [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)], [0, 2, 1, 3]),
    "hexahedron": _ref(
        "hexahedron",
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
         (0, 4), (1, 5), (2, 6), (3, 7)],
        [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)],
        [0, 3, 2, 1, 4, 7, 6, 5]),
    "wedge": _ref(
        "wedge", [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]],
        [(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 3), (1, 4), (2, 5)],
        [(0, 2, 1), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (2, 0, 3, 5)], [0, 2, 1, 3, 5, 4]),
    "pyramid": _ref(
        "pyramid", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]],
        _QUAD_EDGES + [(0, 4), (1, 4), (2, 4), (3, 4)],
        [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)], [0, 3, 2, 1, 4]),
})
#: the P1 cell types (and "vertex")
P1_TYPES = tuple(_CELLS)
#: higher-order types whose extra nodes are the edge midpoints, in the P1 edge order
_SERENDIPITY = {"quad8": "quad", "hexahedron20": "hexahedron", "wedge15": "wedge",
                "pyramid13": "pyramid"}


def reference_cell(cell_type: str) -> RefCell:
    """The :class:`RefCell` of a P1 type.

    Examples
    --------
    >>> reference_cell("wedge").faces[:2]
    ((0, 2, 1), (3, 4, 5))
    """
    if cell_type not in _CELLS:
        raise ValueError(f"expected 'cell_type' among the P1 types {list(P1_TYPES)}, got {cell_type!r}")
    return _CELLS[cell_type]


def base_type(cell_type: str) -> str:
    """The P1 type of a (possibly higher-order) meshio cell type.

    Examples
    --------
    >>> base_type("tetra10"), base_type("quad8"), base_type("line")
    ('tetra', 'quad', 'line')
    """
    if cell_type not in CELL_TYPES:
        raise ValueError(f"expected a cell type among {list(CELL_TYPES)}, got {cell_type!r}")
    if cell_type in _CELLS:
        return cell_type
    if cell_type in _SERENDIPITY:
        return _SERENDIPITY[cell_type]
    return cell_type.rstrip("0123456789")


def _p1_shape(cell_type: str, xi: np.ndarray) -> np.ndarray:
    """(q, nv) P1 shape functions of the base type at reference points xi (q, tdim)."""
    x = [xi[:, j] for j in range(xi.shape[1])]
    if cell_type == "line":
        return np.stack([1 - x[0], x[0]], axis=1)
    if cell_type == "triangle":
        return np.stack([1 - x[0] - x[1], x[0], x[1]], axis=1)
    if cell_type == "tetra":
        return np.stack([1 - x[0] - x[1] - x[2], x[0], x[1], x[2]], axis=1)
    if cell_type == "quad":
        s, t = x
        return np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], axis=1)
    if cell_type == "hexahedron":
        s, t, u = x
        q = np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], axis=1)
        return np.concatenate([q * (1 - u)[:, None], q * u[:, None]], axis=1)
    if cell_type == "wedge":
        s, t, u = x
        tri = np.stack([1 - s - t, s, t], axis=1)
        return np.concatenate([tri * (1 - u)[:, None], tri * u[:, None]], axis=1)
    if cell_type == "pyramid":  # collapsed hexahedron: exact at the nodes used here
        s, t, u = x
        w = np.where(u < 1, 1 - u, 1.0)
        a, b = np.where(u < 1, (s - 0.5 * u) / w, 0.5), np.where(u < 1, (t - 0.5 * u) / w, 0.5)
        q = np.stack([(1 - a) * (1 - b), a * (1 - b), a * b, (1 - a) * b], axis=1) * (1 - u)[:, None]
        return np.concatenate([q, u[:, None]], axis=1)
    raise ValueError(f"no shape functions for {cell_type!r}")


@cache
def node_weights(cell_type: str) -> np.ndarray:
    """(n_nodes, n_vertices) float: each local node as a combination of the cell's vertices.

    Examples
    --------
    >>> node_weights("line3").tolist()
    [[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]]
    """
    base = base_type(cell_type)
    if cell_type == base:
        w = np.eye(len(_CELLS[base].vertices))
    elif cell_type in _SERENDIPITY:
        e = _CELLS[base].edges
        nv = len(_CELLS[base].vertices)
        mid = np.zeros((len(e), nv))
        mid[np.arange(len(e)), e[:, 0]] = mid[np.arange(len(e)), e[:, 1]] = 0.5
        w = np.concatenate([np.eye(nv), mid])
    else:
        w = _p1_shape(base, reference_nodes(cell_type))
    w.setflags(write=False)
    return w


@cache
def mirror_permutation(cell_type: str) -> np.ndarray:
    """(k,) int: the local-node permutation that reverses a cell's orientation.

    ``cells[:, perm]`` describes the same cell with the opposite orientation (a negative
    area or volume becomes positive). Higher-order nodes follow their vertices.

    Examples
    --------
    >>> mirror_permutation("hexahedron").tolist()
    [0, 3, 2, 1, 4, 7, 6, 5]
    """
    base = base_type(cell_type)
    if base not in _CELLS:
        raise ValueError(f"expected a cell type with a reference cell, got {cell_type!r}")
    m = _CELLS[base].mirror
    if cell_type == base:
        return m
    w = node_weights(cell_type)
    target = w[:, m]  # node i of the mirrored cell has the weights of node perm[i]
    d = np.abs(target[:, None, :] - w[None, :, :]).sum(axis=2)
    perm = d.argmin(axis=1).astype(INDEX_DTYPE)
    assert np.allclose(d[np.arange(len(perm)), perm], 0) and len(set(perm.tolist())) == len(perm)
    perm.setflags(write=False)
    return perm


# ----------------------------------------------------------------------------- measures
_GAUSS2 = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])
_TRI3 = (np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]]), np.full(3, 1 / 6))


def _quadrature(cell_type: str):
    """(points (q, tdim), weights (q,)) exact for the Jacobian determinant of the P1 map."""
    g = _GAUSS2
    if cell_type == "quad":
        s, t = np.meshgrid(g, g, indexing="ij")
        return np.stack([s.ravel(), t.ravel()], 1), np.full(4, 0.25)
    if cell_type == "hexahedron":
        s, t, u = np.meshgrid(g, g, g, indexing="ij")
        return np.stack([s.ravel(), t.ravel(), u.ravel()], 1), np.full(8, 0.125)
    if cell_type == "wedge":
        tri, tw = _TRI3
        pts = np.array([[a, b, c] for a, b in tri for c in g])
        return pts, np.repeat(tw, 2) * 0.5
    raise ValueError(cell_type)


def _gradients(cell_type: str, xi: np.ndarray, eps: float = 0.25) -> np.ndarray:
    """(q, nv, tdim) gradients of the multilinear P1 shape functions (quad, hexahedron,
    wedge): a central difference of any step is exact for a function of degree one in
    each variable, and a large step keeps rounding at 1e-16."""
    out = []
    for j in range(xi.shape[1]):
        h = np.zeros(xi.shape[1])
        h[j] = eps
        out.append((_p1_shape(cell_type, xi + h) - _p1_shape(cell_type, xi - h)) / (2 * eps))
    return np.stack(out, axis=2)


def _simplex_measure(x: np.ndarray) -> np.ndarray:
    """Signed measure of simplices x (m, tdim + 1, d); unsigned when tdim < d."""
    e = x[:, 1:] - x[:, :1]
    m, tdim, d = e.shape
    fact = float(np.prod(np.arange(1, tdim + 1)))
    if tdim == d:
        return np.linalg.det(e) / fact if tdim > 1 else e[:, 0, 0]
    return np.sqrt(np.abs(np.linalg.det(np.einsum("mid,mjd->mij", e, e)))) / fact


#: cells a chunk of :func:`cell_measures`
_ROW_CHUNK = 1 << 18


def cell_measures(points, cells, cell_type: str) -> np.ndarray:
    """(m,) float: length, area or volume of each cell of a P1 type, signed when the cell
    has the dimension of the points (negative = inverted), unsigned otherwise.

    Quads, hexahedra and wedges are integrated exactly over their multilinear map; a
    pyramid's volume is the mean of the two splits of its base (exact for a ruled base).

    Examples
    --------
    >>> import numpy as np
    >>> cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
    ...                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    >>> cell_measures(cube, np.arange(8)[None], "hexahedron").round(12).tolist()
    [1.0]
    """
    pts, c = np.asarray(points, REAL_DTYPE), np.asarray(cells)
    if len(c) > _ROW_CHUNK:  # by chunks: the (m, nv, d) corners of 12.7 M tetrahedra are 1.2 GB
        return np.concatenate([cell_measures(pts, c[lo:lo + _ROW_CHUNK], cell_type)
                               for lo in range(0, len(c), _ROW_CHUNK)])
    ref = reference_cell(cell_type)
    x = pts[c[:, : len(ref.vertices)]]
    if cell_type == "vertex":
        return np.zeros(len(c))
    if cell_type in ("line", "triangle", "tetra"):
        return _simplex_measure(x)
    if cell_type == "pyramid":
        a = _simplex_measure(x[:, [0, 1, 2, 4]]) + _simplex_measure(x[:, [0, 2, 3, 4]])
        b = _simplex_measure(x[:, [0, 1, 3, 4]]) + _simplex_measure(x[:, [1, 2, 3, 4]])
        return 0.5 * (a + b)
    if ref.tdim < pts.shape[1]:  # a quad in 3D: unsigned area
        q, w = _quadrature(cell_type)
        j = np.einsum("qvt,mvd->mqdt", _gradients(cell_type, q), x)
        g = np.einsum("mqdt,mqds->mqts", j, j)
        return np.sqrt(np.abs(np.linalg.det(g))) @ w
    q, w = _quadrature(cell_type)
    return np.linalg.det(np.einsum("qvt,mvd->mqdt", _gradients(cell_type, q), x)) @ w


def corner_jacobians(points, cells, cell_type: str) -> np.ndarray:
    """(m, nv) float: the Jacobian determinant of the P1 map at each vertex of full-dimension
    cells (all positive = valid, positively oriented; the pyramid apex uses the base corners'
    tetrahedra).

    Examples
    --------
    >>> import numpy as np
    >>> sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    >>> corner_jacobians(sq, np.array([[0, 1, 2, 3], [0, 3, 2, 1]]), "quad").tolist()
    [[1.0, 1.0, 1.0, 1.0], [-1.0, -1.0, -1.0, -1.0]]
    """
    pts, c = np.asarray(points, REAL_DTYPE), np.asarray(cells)
    ref = reference_cell(cell_type)
    if ref.tdim != pts.shape[1]:
        raise ValueError(f"expected {cell_type!r} cells of the points' dimension {pts.shape[1]}")
    x = pts[c[:, : len(ref.vertices)]]
    if cell_type == "pyramid":
        corners = [[0, 1, 3, 4], [1, 2, 0, 4], [2, 3, 1, 4], [3, 0, 2, 4], [0, 1, 2, 4]]
        return np.stack([6 * _simplex_measure(x[:, k]) for k in corners], axis=1)
    if cell_type in ("line", "triangle", "tetra"):
        f = float(np.prod(np.arange(1, ref.tdim + 1)))
        return np.repeat((f * _simplex_measure(x))[:, None], len(ref.vertices), axis=1)
    g = _gradients(cell_type, ref.vertices)
    return np.linalg.det(np.einsum("qvt,mvd->mqdt", g, x))


# ----------------------------------------------------------------------------- new nodes
#: compare-exchange networks sorting rows of up to 4 entries
_NETWORKS = {1: [], 2: [(0, 1)], 3: [(0, 1), (1, 2), (0, 1)], 4: [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)]}


def _sort_pairs(v: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row of ``v`` sorted, ``w`` permuted alike: column compare-exchanges for up to 4
    columns (several times faster than a per-row argsort), an argsort beyond."""
    k = v.shape[1]
    if k not in _NETWORKS:
        order = np.argsort(v, axis=1, kind="stable")
        return np.take_along_axis(v, order, 1), np.take_along_axis(w, order, 1)
    vc, wc = [v[:, j].copy() for j in range(k)], [w[:, j].copy() for j in range(k)]
    for i, j in _NETWORKS[k]:
        swap = vc[i] > vc[j]
        vc[i], vc[j] = np.where(swap, vc[j], vc[i]), np.where(swap, vc[i], vc[j])
        wc[i], wc[j] = np.where(swap, wc[j], wc[i]), np.where(swap, wc[i], wc[j])
    return np.stack(vc, axis=1), np.stack(wc, axis=1)


def weighted_nodes(points, vertices, weights, *, point_count: int | None = None):
    """Number nodes given as integer-weighted combinations of mesh vertices, once each.

    A node is ``sum_j weights[..., j] * points[vertices[..., j]] / sum_j weights[..., j]``.
    Two rows with the same set of (vertex, weight) pairs, in any order, are the same node,
    so the midpoint of an edge shared by two elements gets one number. A row whose weight
    sits on one vertex is that vertex. Weights may use any common denominator as long as
    every row of a call uses the same one.

    Parameters
    ----------
    points : (n, d) float
    vertices : (..., k) int
        Vertex indices per node (a zero weight makes its index irrelevant).
    weights : (..., k) int, non-negative, same shape
    point_count : int, optional
        Number of existing points (default ``len(points)``): new nodes are numbered from it.

    Returns
    -------
    ids : (...) int64
        Node number of each row.
    new_points : (u, d) float64
        Coordinates of the new nodes, numbered ``point_count + i``: by the number of
        vertices they depend on, then lexicographically.
    support : tuple of (u, k) int64 arrays
        ``(vertices, weights)`` of each new node, sorted by vertex, zero weights last
        (for interpolating data and inheriting refs).

    Examples
    --------
    >>> import numpy as np
    >>> pts = np.array([[0.0, 0], [2, 0], [0, 2]])
    >>> ids, new, _ = weighted_nodes(pts, [[0, 1], [1, 0], [2, 2]], [[1, 1], [1, 1], [5, 0]])
    >>> ids.tolist(), new.tolist()
    ([3, 3, 2], [[1.0, 0.0]])
    """
    pts = np.asarray(points, REAL_DTYPE)
    v, w = np.asarray(vertices, INDEX_DTYPE), np.asarray(weights, INDEX_DTYPE)
    if v.shape != w.shape or v.ndim < 1:
        raise ValueError(f"expected 'vertices' and 'weights' of one shape, got {v.shape} and {w.shape}")
    n0 = len(pts) if point_count is None else int(point_count)
    shape, k = v.shape[:-1], v.shape[-1]
    v, w = v.reshape(-1, k), w.reshape(-1, k)
    if len(v) == 0:
        return np.zeros(shape, INDEX_DTYPE), np.zeros((0, pts.shape[1])), (v, w)
    if w.min() < 0:
        raise ValueError("expected non-negative 'weights' with a positive sum per row")
    positive = w > 0
    support = positive.sum(axis=1)
    if support.min() == 0:
        raise ValueError("expected non-negative 'weights' with a positive sum per row")
    big = np.iinfo(INDEX_DTYPE).max
    ids = np.empty(len(v), INDEX_DTYPE)
    single = np.flatnonzero(support == 1)  # an existing vertex: no sorting, no search
    ids[single] = v[single, positive[single].argmax(axis=1)]
    multi = np.flatnonzero(support > 1)
    vv, ww = _sort_pairs(np.where(positive[multi], v[multi], big), w[multi])
    if len(multi):  # one group per support size: its rows pack into one int64 key more often
        support = support[multi]
        parts, start = [], n0
        for size in np.unique(support):
            sel = np.flatnonzero(support == size)
            uniq, _, inverse, _ = unique_rows(np.concatenate([vv[sel, :size], ww[sel, :size]], axis=1))
            ids[multi[sel]] = start + inverse
            start += len(uniq)
            pad = ((0, 0), (0, k - size))
            parts.append((np.pad(uniq[:, :size], pad, constant_values=big), np.pad(uniq[:, size:], pad)))
        uv, uw = np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
        safe = np.where(uw > 0, uv, 0)
        new = np.einsum("uk,ukd->ud", uw.astype(REAL_DTYPE), pts[safe]) / uw.sum(axis=1, keepdims=True)
        uv = np.where(uw > 0, uv, -1)
    else:
        new, uv, uw = np.zeros((0, pts.shape[1])), np.zeros((0, k), INDEX_DTYPE), np.zeros((0, k), INDEX_DTYPE)
    return ids.reshape(shape), new, (uv, uw)


def extend_point_values(values, support) -> np.ndarray:
    """Point values (n0, ...) extended to the new nodes of :func:`weighted_nodes`.

    Float and complex values are the weighted mean of the supporting vertices'; any other
    dtype (refs, ints, bools) keeps the value the supporting vertices share, else 0.

    Parameters
    ----------
    values : (n0, ...) array
    support : tuple of (u, k) int arrays
        The ``support`` returned by :func:`weighted_nodes` (vertex -1 where the weight is 0).

    Returns
    -------
    (n0 + u, ...) array of the same dtype

    Examples
    --------
    >>> import numpy as np
    >>> support = (np.array([[0, 1], [1, 2]]), np.array([[1, 1], [1, 1]]))
    >>> extend_point_values(np.array([0.0, 2.0, 4.0]), support).tolist()
    [0.0, 2.0, 4.0, 1.0, 3.0]
    >>> extend_point_values(np.array([7, 7, 5]), support).tolist()
    [7, 7, 5, 7, 0]
    """
    arr = np.asarray(values)
    uv, uw = support
    if len(uv) == 0:
        return arr
    vals = arr[np.where(uw > 0, uv, 0)]  # (u, k, ...)
    w = uw.reshape(*uw.shape, *(1,) * (arr.ndim - 1))
    if arr.dtype.kind in "fc":
        new = (w * vals).sum(axis=1) / w.sum(axis=1)
    else:
        first = vals[:, 0]
        agree = ((vals == first[:, None]) | (w == 0)).all(axis=1)
        new = np.where(agree, first, np.zeros_like(first))
    return np.concatenate([arr, new.astype(arr.dtype)])

