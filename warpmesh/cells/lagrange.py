"""Lagrange elements of order k: node lattices, local node order, reference nodes and
shape functions, generated from each P1 cell's vertices, edges and faces.

==========  ==========================================  ==============================
P1 type     higher-order types (k = 2, 3, 4)            local node order
==========  ==========================================  ==============================
line        line3, line4, line5                         VTK = gmsh
triangle    triangle6, triangle10, triangle15           VTK = gmsh
tetra       tetra10, tetra20, tetra35                   VTK (tetra10), gmsh (20, 35)
quad        quad9 (k = 2 only)                          VTK
hexahedron  hexahedron27 (k = 2 only)                   VTK
==========  ==========================================  ==============================

The local order is the one meshio files carry: the vertices, then the nodes of each edge
from its first to its second vertex, then the nodes inside each face, then those inside
the cell [FG §17.3.4]. :func:`warpmesh.numbering.high_order.to_order` builds meshes of
these types.

Examples
--------
>>> from warpmesh.cells.lagrange import reference_nodes
>>> reference_nodes("line4").ravel().round(4).tolist()
[0.0, 1.0, 0.3333, 0.6667]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.cells.types import CELL_TYPES

__all__ = ["ORDERS", "ELEMENTS", "ELEMENT_BY_NAME", "HIGHER_TYPES", "LAGRANGE_NAMES", "P1_TOPOLOGY",
           "LagrangeElement", "reference_nodes"]

#: P1 type -> the orders :func:`to_order` builds for it
ORDERS: Mapping[str, tuple[int, ...]] = MappingProxyType({
    "line": (1, 2, 3, 4),
    "triangle": (1, 2, 3, 4),
    "tetra": (1, 2, 3, 4),
    "quad": (1, 2),
    "hexahedron": (1, 2),
})

# ----------------------------------------------------------------------------- tables
#: P1 type -> (reference vertices, edges, faces), local vertex indices in VTK's order.
#: The faces of a 2D cell are the cell itself; tetra faces are gmsh's (outward).
P1_TOPOLOGY = {
    "line": ([[0], [1]], [(0, 1)], []),
    "triangle": ([[0, 0], [1, 0], [0, 1]], [(0, 1), (1, 2), (2, 0)], [(0, 1, 2)]),
    "quad": ([[0, 0], [1, 0], [1, 1], [0, 1]], [(0, 1), (1, 2), (2, 3), (3, 0)], [(0, 1, 2, 3)]),
    "tetra": (
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
        [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)],
        [(0, 2, 1), (0, 1, 3), (0, 3, 2), (3, 1, 2)],
    ),
    "hexahedron": (
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
         (0, 4), (1, 5), (2, 6), (3, 7)],
        [(0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4), (3, 2, 6, 7), (0, 1, 2, 3), (4, 5, 6, 7)],
    ),
}
#: gmsh's tetra edges (tetra20, tetra35); VTK's (tetra10) differ in the last three
_GMSH_TETRA_EDGES = [(0, 1), (1, 2), (2, 0), (3, 0), (3, 2), (3, 1)]
LAGRANGE_NAMES = {
    ("line", 1): "line", ("line", 2): "line3", ("line", 3): "line4", ("line", 4): "line5",
    ("triangle", 1): "triangle", ("triangle", 2): "triangle6", ("triangle", 3): "triangle10",
    ("triangle", 4): "triangle15",
    ("tetra", 1): "tetra", ("tetra", 2): "tetra10", ("tetra", 3): "tetra20", ("tetra", 4): "tetra35",
    ("quad", 1): "quad", ("quad", 2): "quad9",
    ("hexahedron", 1): "hexahedron", ("hexahedron", 2): "hexahedron27",
}


def _triangle_lattice(k: int) -> np.ndarray:
    """(m, 3) int: gmsh's order-k triangle as integer barycentric weights (sum k).

    Vertices, edges (0 1), (1 2), (2 0), then the interior: an order k-3 triangle, each
    weight + 1 (recursively). Order 0 is the single centroid node.
    """
    if k < 0:
        return np.zeros((0, 3), dtype=int)
    if k == 0:
        return np.zeros((1, 3), dtype=int)
    rows = [k * np.eye(3, dtype=int)]
    t = np.arange(1, k)
    for a, b in P1_TOPOLOGY["triangle"][1]:
        r = np.zeros((k - 1, 3), dtype=int)
        r[:, a], r[:, b] = k - t, t
        rows.append(r)
    return np.concatenate([*rows, _triangle_lattice(k - 3) + 1])


def _tetra_lattice(k: int) -> np.ndarray:
    """(m, 4) int: gmsh's order-k tetrahedron as integer barycentric weights (sum k).

    Vertices, gmsh's edges, the inside of each gmsh face (an order k-3 triangle laid
    on the face's vertices, weights + 1), the inside (an order k-4 tetrahedron, + 1).
    """
    if k < 0:
        return np.zeros((0, 4), dtype=int)
    if k == 0:
        return np.zeros((1, 4), dtype=int)
    rows = [k * np.eye(4, dtype=int)]
    t = np.arange(1, k)
    for a, b in _GMSH_TETRA_EDGES:
        r = np.zeros((k - 1, 4), dtype=int)
        r[:, a], r[:, b] = k - t, t
        rows.append(r)
    inside = _triangle_lattice(k - 3) + 1
    for f in P1_TOPOLOGY["tetra"][2]:
        r = np.zeros((len(inside), 4), dtype=int)
        r[:, list(f)] = inside
        rows.append(r)
    return np.concatenate([*rows, _tetra_lattice(k - 4) + 1])


def _powers(xi: np.ndarray, exps: np.ndarray, d: int | None = None) -> np.ndarray:
    """(s, q): the monomials ``xi ** exps`` at the points xi (s, t), or their derivative in xi_d."""
    if d is None:
        return np.prod(xi[:, None, :] ** exps[None], axis=2)
    e = exps.copy()
    factor = e[:, d].astype(REAL_DTYPE)
    e[:, d] = np.maximum(e[:, d] - 1, 0)
    return factor[None] * np.prod(xi[:, None, :] ** e[None], axis=2)


@dataclass(frozen=True, eq=False)
class LagrangeElement:
    """One Lagrange element: its nodes' structure and its shape functions.

    ``weights`` (n, nv): node i of a straight element sits at ``weights[i] @ vertices``
    (barycentric for simplices; the bi/trilinear weights of a midpoint for quad/hex).
    ``edge_nodes`` (ne, k-1) lists the nodes of each local edge from its first vertex to
    its second; ``face_nodes`` (nf, q) those inside each face in the face's own layout
    ``face_layout`` (q, 3 or 4) (integer weights over the face's vertices);
    ``closure`` (nf, c) the non-vertex nodes on each face (its edges' and its own).
    """

    name: str
    base: str
    order: int
    lattice: np.ndarray
    coords: np.ndarray
    edges: np.ndarray
    edge_nodes: np.ndarray
    faces: np.ndarray
    face_nodes: np.ndarray
    face_layout: np.ndarray
    interior: np.ndarray
    closure: np.ndarray
    exps: np.ndarray
    coefficients: np.ndarray

    @property
    def weights(self) -> np.ndarray:
        return self.lattice / self.lattice.sum(axis=1, keepdims=True)

    @property
    def n_vertices(self) -> int:
        return len(self.lattice[0])

    @property
    def tdim(self) -> int:
        return self.coords.shape[1]

    def shape(self, xi: np.ndarray) -> np.ndarray:
        """(s, n): the shape functions at reference points xi (s, tdim)."""
        return _powers(xi, self.exps) @ self.coefficients

    def dshape(self, xi: np.ndarray) -> np.ndarray:
        """(s, n, tdim): their derivatives."""
        return np.stack([_powers(xi, self.exps, d) @ self.coefficients for d in range(self.tdim)],
                        axis=2)

    def samples(self) -> np.ndarray:
        """(s, tdim): where :func:`jacobians` looks: the nodes; for k >= 2 also the centroid
        and the points halfway between it and each vertex."""
        if self.order == 1:
            return self.coords
        v = self.coords[: self.n_vertices]
        c = v.mean(axis=0)
        return np.concatenate([self.coords, c[None], (v + c) / 2])


def _build(base: str, k: int) -> LagrangeElement:
    verts, edges, faces = P1_TOPOLOGY[base]
    simplex = base in ("line", "triangle", "tetra")
    if base == "tetra" and k >= 3:
        edges = _GMSH_TETRA_EDGES
    nv, nfv = len(verts), (len(faces[0]) if faces else 0)
    rows, count = [np.eye(nv, dtype=int)], nv
    edge_nodes, face_nodes = [], []
    t = np.arange(1, k)
    for a, b in edges:
        r = np.zeros((k - 1, nv), dtype=int)
        r[:, a], r[:, b] = k - t, t
        rows.append(r)
        edge_nodes.append(count + np.arange(k - 1))
        count += k - 1
    if nfv == 3:
        layout = _triangle_lattice(k - 3) + 1
    elif nfv == 4:
        layout = np.ones((1 if k == 2 else 0, 4), dtype=int)
    else:
        layout = np.zeros((0, 0), dtype=int)
    for f in faces:
        r = np.zeros((len(layout), nv), dtype=int)
        r[:, list(f)] = layout
        rows.append(r)
        face_nodes.append(count + np.arange(len(layout)))
        count += len(layout)
    if base == "tetra":
        inside = _tetra_lattice(k - 4) + 1
    elif base == "hexahedron" and k == 2:
        inside = np.ones((1, 8), dtype=int)
    else:
        inside = np.zeros((0, nv), dtype=int)
    rows.append(inside)
    lattice = np.concatenate(rows)
    n = len(lattice)
    coords = (lattice / lattice.sum(axis=1, keepdims=True)) @ np.asarray(verts, dtype=REAL_DTYPE)
    support = lattice > 0
    closure = [np.flatnonzero(~support[:, np.setdiff1d(np.arange(nv), f)].any(axis=1)
                              & (np.arange(n) >= nv)) for f in faces]
    tdim = coords.shape[1]
    grid = np.stack(np.meshgrid(*[np.arange(k + 1)] * tdim, indexing="ij"), -1).reshape(-1, tdim)
    exps = grid[grid.sum(axis=1) <= k] if simplex else grid  # P_k, or Q_k for quad/hex
    vandermonde = _powers(coords, exps)
    if vandermonde.shape != (n, n):  # a table that does not match its polynomial space
        raise AssertionError(f"{base} order {k}: {n} nodes for {len(exps)} monomials")
    return LagrangeElement(
        name=LAGRANGE_NAMES[base, k], base=base, order=k, lattice=lattice, coords=coords,
        edges=np.array(edges, dtype=INDEX_DTYPE),
        edge_nodes=np.array(edge_nodes, dtype=INDEX_DTYPE).reshape(len(edges), k - 1),
        faces=np.array(faces, dtype=INDEX_DTYPE).reshape(len(faces), nfv),
        face_nodes=np.array(face_nodes, dtype=INDEX_DTYPE).reshape(len(faces), len(layout)),
        face_layout=layout, interior=np.arange(n - len(inside), n, dtype=INDEX_DTYPE),
        closure=np.array(closure, dtype=INDEX_DTYPE).reshape(len(faces), -1 if faces else 0),
        exps=exps, coefficients=np.linalg.inv(vandermonde),
    )


ELEMENTS = {(b, k): _build(b, k) for b, orders in ORDERS.items() for k in orders}
ELEMENT_BY_NAME = {el.name: el for el in ELEMENTS.values()}
for _el in ELEMENT_BY_NAME.values():  # the tables agree with the meshio vocabulary
    assert CELL_TYPES[_el.name][:2] == (len(_el.lattice), _el.tdim), _el.name
HIGHER_TYPES = {t for t in CELL_TYPES if t not in P1_TOPOLOGY and t not in ("vertex", "wedge", "pyramid")}


def reference_nodes(cell_type: str) -> np.ndarray:
    """Reference coordinates of the local nodes of a Lagrange cell type, in local order.

    Parameters
    ----------
    cell_type : str
        A meshio name among the types of the module table (P1 types included).

    Returns
    -------
    (n, tdim) float64
        Coordinates in [0, 1] per axis (VTK's parametric space; gmsh's for simplices,
        its [-1, 1] mapped to [0, 1] for lines, quads and hexahedra).

    Raises
    ------
    ValueError
        An unknown or unsupported type.

    Examples
    --------
    >>> reference_nodes("triangle6").tolist()
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]]
    """
    if cell_type not in ELEMENT_BY_NAME:
        raise ValueError(f"expected 'cell_type' among {sorted(ELEMENT_BY_NAME)}, got {cell_type!r}")
    return ELEMENT_BY_NAME[cell_type].coords.copy()
