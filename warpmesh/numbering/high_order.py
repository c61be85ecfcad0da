"""Node creation for higher-order Lagrange elements, and their p-compatibility check.

[FG §17.3.2–§17.3.4]: :func:`to_order` builds the Pk mesh of a P1 mesh (edge
nodes, then face nodes, then interior nodes), places the nodes of boundary edges and
faces on the exact boundary f = 0 (the isoparametric elements of Fig. 17.10), and
:func:`jacobians` / :func:`inverted_elements` check Definition 17.3 (a mesh is
p-compatible when its degree-p elements are valid) through the Jacobian of each
element's isoparametric map.

The element types, their local node order and reference nodes are the tables of
:mod:`warpmesh.cells.lagrange` (P1 type -> order-k type, VTK's or gmsh's node order).

Global numbering (§17.3.4, vectorised): vertices keep their numbers 0..np-1; the j-th
unique edge (sorted endpoint pairs over every block, in lexicographic order) gets the
nodes ``np + (k-1) j + t``, t = 0..k-2, laid out from its lower-numbered to its
higher-numbered endpoint, and each element reads them in its own direction (reversed
when its local edge runs from the higher to the lower index). Then the nodes inside
faces (triangle faces for k >= 3, quad faces for k = 2), numbered per unique face, each
face's nodes laid out on its sorted vertex numbers so that every element sharing the
face reads the same node at the same place; then the nodes inside cells, block by block.

Examples
--------
>>> import warpmesh as wm
>>> m = wm.Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], {"triangle": [[0, 1, 2], [1, 3, 2]]})
>>> p2 = m.to_order(2)
>>> p2.cells["triangle6"].tolist()        # edge (1, 2) is node 6 in both triangles
[[0, 1, 2, 4, 6, 5], [1, 3, 2, 7, 8, 6]]
>>> p2.points[6].tolist(), p2.info["n_nodes"], p2.info["n_inverted"]
([0.5, 0.5], 9, 0)
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.arrays import unique_rows
from warpmesh.cells.lagrange import (ELEMENT_BY_NAME, ELEMENTS, HIGHER_TYPES, LAGRANGE_NAMES, ORDERS,
                                     P1_TOPOLOGY, LagrangeElement)
from warpmesh.cells.collapsed import reject_collapsed
from warpmesh.cells.types import require_mesh
from warpmesh.cells.caps import cap_bounds
from warpmesh.frep.projection import as_target, check_shape_dim, project_nodes

__all__ = ["to_order", "jacobians", "inverted_elements"]

#: cells per chunk of :func:`jacobians` (bounds its temporaries)
_CHUNK = 1 << 15


# ----------------------------------------------------------------------------- validation
def _check_order(order) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
        raise TypeError(f"expected an int for 'order' (1 to 4), got {order!r} "
                        f"({type(order).__name__})")
    if not 1 <= order <= 4:
        raise ValueError(f"expected 'order' 1, 2, 3 or 4, got {order}")
    return int(order)


def _plan(mesh, k: int) -> list[tuple[str, LagrangeElement | None]]:
    """(type, element) per block, element None for the blocks kept as they are."""
    plan = []
    for t in mesh.cells:
        if t == "vertex":
            plan.append((t, None))
        elif t in P1_TOPOLOGY:
            if k not in ORDERS[t]:
                raise ValueError(f"expected 'order' in {list(ORDERS[t])} for {t!r} cells "
                                 f"({LAGRANGE_NAMES[t, 2]} is the highest {t} type), got order={k}")
            plan.append((t, ELEMENTS[t, k]))
        else:
            why = "already higher-order" if t in HIGHER_TYPES else "not supported"
            raise ValueError(f"expected P1 cell blocks {list(P1_TOPOLOGY)} (and 'vertex', kept), got "
                             f"{t!r} cells ({why}); drop or split that block first")
    if all(el is None for _, el in plan):
        raise ValueError(f"expected a block of {list(P1_TOPOLOGY)} cells in 'mesh', got {list(mesh.cells)}")
    return plan


# ----------------------------------------------------------------------------- numbering
def _unique_sets(rows: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """(number of distinct vertex sets, inverse (r,), counts (u,)) of the rows, each row
    taken as a set (sorted within itself)."""
    uniq, _, inverse, counts = unique_rows(np.sort(rows, axis=1))
    return len(uniq), inverse, counts


def _number_faces(elements, conn, k: int, nfv: int, first: int) -> int:
    """Number the nodes inside the faces with ``nfv`` vertices; return the next free number.

    A face's q nodes get ``first + q f + slot``: f the unique face, slot the place of the
    node in the face layout laid on the face's sorted vertex numbers.
    """
    use = [(el, c) for el, c in zip(elements, conn, strict=True)
           if el.faces.shape[1] == nfv and el.face_nodes.size]
    if not use:
        return first
    occ = [c[:, el.faces] for el, c in use]  # (m, nf, nfv) global vertex numbers
    n_faces, inverse, _ = _unique_sets(np.concatenate([o.reshape(-1, nfv) for o in occ]))
    layout = use[0][0].face_layout
    q, radix = len(layout), (k + 1) ** np.arange(nfv)[::-1]
    lookup = np.full((k + 1) ** nfv, -1, dtype=INDEX_DTYPE)
    lookup[layout @ radix] = np.arange(q)
    start = 0
    for (el, c), o in zip(use, occ, strict=True):
        m, nf = o.shape[:2]
        f = inverse[start: start + m * nf].reshape(m, nf)
        start += m * nf
        sigma = np.argsort(o, axis=2, kind="stable")  # sorted vertex s of a face is its vertex sigma[s]
        for j in range(q):  # local face node j: its weights read on the sorted vertices
            c[:, el.face_nodes[:, j]] = first + q * f + lookup[layout[j][sigma] @ radix]
    return first + q * n_faces


def _numbering(blocks, n0: int, k: int):
    """Connectivity of every block (list of (m, n) int64), the edge numbering and the count."""
    conn = []
    for el, cells in blocks:
        c = np.full((len(cells), len(el.lattice)), -1, dtype=INDEX_DTYPE)
        c[:, : el.n_vertices] = cells
        conn.append(c)
    occ = [cells[:, el.edges] for el, cells in blocks]  # (m, ne, 2)
    n_edges, inverse, _ = _unique_sets(np.concatenate([o.reshape(-1, 2) for o in occ]))
    edge_ids, start, t = [], 0, np.arange(k - 1)
    for (el, _), o, c in zip(blocks, occ, conn, strict=True):
        m, ne = o.shape[:2]
        j = inverse[start: start + m * ne].reshape(m, ne)
        start += m * ne
        edge_ids.append(j)
        forward = (o[..., 0] < o[..., 1])[..., None]
        c[:, el.edge_nodes] = n0 + (k - 1) * j[..., None] + np.where(forward, t, k - 2 - t)
    first = n0 + (k - 1) * n_edges
    elements = [el for el, _ in blocks]
    after_tri = _number_faces(elements, conn, k, 3, first)
    after_quad = _number_faces(elements, conn, k, 4, after_tri)
    n = after_quad
    for (el, _), c in zip(blocks, conn, strict=True):
        ni = len(el.interior)
        c[:, el.interior] = n + np.arange(len(c) * ni).reshape(len(c), ni)
        n += len(c) * ni
    counts = {"n_edges": n_edges, "n_face_nodes": after_quad - first, "n_interior_nodes": n - after_quad}
    return conn, edge_ids, n, counts


def _boundary_nodes(blocks, conn, edge_ids, n0: int, n: int, dim: int) -> np.ndarray:
    """Global numbers of the new nodes to project (see :func:`to_order`)."""
    top = max(el.tdim for el, _ in blocks)
    if top < dim:  # a curve or a surface: every new node lies on it
        return np.arange(n0, n, dtype=INDEX_DTYPE)
    found = []
    if top == 2:  # planar mesh: the nodes of edges in one 2D cell
        both = [(el, c, j) for (el, _), c, j in zip(blocks, conn, edge_ids, strict=True) if el.tdim == 2]
        counts = np.bincount(np.concatenate([j.ravel() for _, _, j in both]))
        for el, c, j in both:
            found.append(c[:, el.edge_nodes][counts[j] == 1].ravel())
    else:  # volume mesh: the edge and face nodes of faces in one 3D cell
        vol = [(el, c) for el, c in zip([el for el, _ in blocks], conn, strict=True) if el.tdim == 3]
        for nfv in (3, 4):
            group = [(el, c) for el, c in vol if el.faces.shape[1] == nfv]
            if not group:
                continue
            occ = np.concatenate([c[:, el.faces].reshape(-1, nfv) for el, c in group])
            _, inverse, counts = _unique_sets(occ)
            start = 0
            for el, c in group:
                m, nf = len(c), len(el.faces)
                once = (counts[inverse[start: start + m * nf]] == 1).reshape(m, nf)
                start += m * nf
                found.append(c[:, el.closure][once].ravel())
    return np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=INDEX_DTYPE)


# ----------------------------------------------------------------------------- attributes
def _common(values: np.ndarray, support: np.ndarray) -> np.ndarray:
    """(m, q, ...): per node, the value its supporting vertices share, else zero."""
    q, nv = support.shape
    first = support.argmax(axis=1)
    v0 = values[:, first]
    rest = (1,) * (values.ndim - 2)
    agree = np.all((values[:, None] == v0[:, :, None]) | ~support.reshape(1, q, nv, *rest), axis=2)
    return np.where(agree, v0, np.zeros_like(v0))


def _node_values(arr: np.ndarray, blocks, conn, n: int) -> np.ndarray:
    """``arr`` (n0, ...) extended to all n nodes: float/complex interpolated by the straight
    element's weights, anything else (ints, refs, bools) kept where the supporting
    vertices agree, else zero."""
    out = np.zeros((n, *arr.shape[1:]), dtype=arr.dtype)
    out[: len(arr)] = arr
    for (el, cells), c in zip(blocks, conn, strict=True):
        new, vals = slice(el.n_vertices, None), arr[cells]
        if arr.dtype.kind in "fc":
            out[c[:, new]] = np.einsum("qv,mv...->mq...", el.weights[new], vals)
        else:
            out[c[:, new]] = _common(vals, el.lattice[new] > 0)
    return out


# ----------------------------------------------------------------------------- public API
def to_order(mesh, order: int, shape=None, *, bounds=None, check: bool = True, stacklevel: int = 2):
    """The Pk mesh of a P1 mesh: new nodes on edges, faces and inside cells.

    Every line, triangle, quad, tetra and hexahedron block becomes its order-k type (see
    the module table); nodes on an edge or face shared by several cells, in any blocks,
    are one global node (numbering in the module docstring). New nodes are placed
    straight (the affine / bi- / trilinear image of the reference nodes); with ``shape``,
    the nodes on the boundary are then projected onto f = 0 [FG Fig. 17.10]: in a
    curve or surface mesh (cells of lower dimension than the points) every new node; in a
    volume mesh the nodes on the edges and faces of boundary faces (faces of one cell);
    in a planar mesh the nodes of boundary edges (edges of one cell). Other nodes stay
    straight.

    Attributes: cell refs and cell data go to the new blocks unchanged. New nodes get
    the point ref shared by the vertices they lie between (the edge's two vertices, the
    face's, the cell's), else 0; float point data are interpolated by the straight
    element's weights (e.g. the mean of an edge's two values at a P2 midpoint); other
    point data (integers, booleans) are treated like refs.

    Parameters
    ----------
    mesh : Mesh
        P1 cells; ``vertex`` blocks are kept as they are. Unused points keep their numbers.
    order : int
        1 to 4 (1 returns ``mesh`` itself); 1 or 2 for quads and hexahedra.
    shape : Shape, Expr, VolumeField or projection target, optional
        The exact geometry (f > 0 inside, f = 0 on the boundary). 2D meshes are read at
        z = 0.
    bounds : ((x0, y0, z0), (x1, y1, z1)), optional
        The box the mesh was capped on (as in :func:`warpmesh.mesh_surface`); by default read
        from the mesh's cap faces (ref ``CAP_REF``: :func:`warpmesh.cells.caps.cap_bounds`), so
        their nodes stay on the box.
    check : bool
        Compute :func:`jacobians` of the result, store ``info["n_inverted"]`` and warn
        when some elements are inverted (the mesh is not k-compatible, Definition 17.3).
    stacklevel : int
        Whose line the warning names, as for ``warnings.warn``: 2, the caller of this
        function (:meth:`Mesh.to_order` passes 3, its own caller).

    Returns
    -------
    Mesh
        Points (n_nodes, d): the vertices first, then edge, face and cell nodes.
        ``info`` gains ``order``, ``n_nodes``, ``n_inverted`` (with ``check``) and
        ``to_order`` (``n_edges``, ``n_face_nodes``, ``n_interior_nodes``,
        ``n_projected``, ``time``).

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh, ``order`` not an int, ``check`` not a bool, ``shape``
        not a shape.
    ValueError
        ``order`` out of range (or above 2 with quads/hexahedra), a block that is not P1
        (wedge, pyramid, an already higher-order type), no P1 block, ``bounds`` without
        ``shape``.

    Warns
    -----
    UserWarning
        With ``check``, when some elements are inverted; :func:`inverted_elements` lists them.

    Examples
    --------
    >>> import numpy as np, warpmesh as wm
    >>> m = wm.Mesh([[1, 0], [0, 1], [-1, 0], [0, -1]], {"line": [[0, 1], [1, 2], [2, 3], [3, 0]]})
    >>> p3 = to_order(m, 3, wm.sphere(1.0))          # a circle: the nodes go onto it
    >>> p3.cells["line4"].shape, np.linalg.norm(p3.points, axis=1).round(12).tolist()[4:6]
    ((4, 4), [1.0, 1.0])
    """
    return _to_order(mesh, order, shape, bounds=bounds, check=check, stacklevel=stacklevel + 1)


def _to_order(mesh, order, shape=None, *, bounds=None, check=True, stacklevel: int = 2):
    t0 = time.perf_counter()
    require_mesh(mesh)
    k = _check_order(order)
    if not isinstance(check, bool):
        raise TypeError(f"expected a bool for 'check', got {type(check).__name__}")
    if shape is None and bounds is not None:
        raise ValueError("expected a 'shape' with 'bounds' (the box caps that shape), got shape=None")
    if shape is not None and bounds is None:  # a capped mesh: its cap faces stay on their box
        bounds = cap_bounds(mesh)
    target = None if shape is None else as_target(shape, bounds=bounds)
    if shape is not None:
        check_shape_dim(shape, mesh.points)
    if k == 1:
        return mesh
    reject_collapsed(mesh, "to_order")  # (a repeated corner only warned of an inverted element)
    plan = _plan(mesh, k)
    blocks = [(el, np.asarray(mesh.cells[t])) for t, el in plan if el is not None]
    n0, dim = mesh.n_points, mesh.dim
    conn, edge_ids, n, counts = _numbering(blocks, n0, k)

    points = np.zeros((n, dim), dtype=REAL_DTYPE)
    points[:n0] = mesh.points
    for (el, cells), c in zip(blocks, conn, strict=True):
        points[c[:, el.n_vertices:]] = el.weights[el.n_vertices:] @ mesh.points[cells]
    projected = np.zeros(0, dtype=INDEX_DTYPE)
    if target is not None:
        projected = _boundary_nodes(blocks, conn, edge_ids, n0, n, dim)
        cap = np.zeros(n)  # Newton steps stay below the longest edge of the node's cells
        for (el, cells), c in zip(blocks, conn, strict=True):
            x = mesh.points[cells]
            h = np.linalg.norm(x[:, el.edges[:, 0]] - x[:, el.edges[:, 1]], axis=2).max(axis=1)
            np.maximum.at(cap, c[:, el.n_vertices:].ravel(), np.repeat(h, c.shape[1] - el.n_vertices))
        x = points[projected]
        if dim == 2:
            x = np.column_stack([x, np.zeros(len(x))])
        points[projected] = project_nodes(target, x, cap[projected])[:, :dim]

    renamed = {t: (t if el is None else el.name) for t, el in plan}
    new_conn = iter(conn)
    cells = {renamed[t]: (mesh.cells[t] if el is None else next(new_conn)) for t, el in plan}
    point_refs = (None if mesh.point_refs is None
                  else _node_values(np.asarray(mesh.point_refs), blocks, conn, n))
    point_data = {key: _node_values(np.asarray(v), blocks, conn, n) for key, v in mesh.point_data.items()}
    cell_refs = None if mesh.cell_refs is None else {renamed[t]: r for t, r in mesh.cell_refs.items()}
    cell_data = {key: {renamed[t]: a for t, a in v.items()} for key, v in mesh.cell_data.items()}
    info = {**mesh.info, "order": k, "n_nodes": n,
            "to_order": {**counts, "n_projected": len(projected), "time": 0.0}}
    if check:
        scores = _jacobians(points, cells)
        bad = sum(int(np.count_nonzero(s <= 0)) for s in scores.values())
        info["n_inverted"] = bad
        if bad:
            per_block = ", ".join(f"{int(np.count_nonzero(s <= 0))} of {len(s)} {t}" for t, s in scores.items()
                                  if np.count_nonzero(s <= 0))
            warnings.warn(f"{bad} elements ({per_block}) are inverted after to_order(order={k}): the "
                          f"mesh is not {k}-compatible [FG Definition 17.3]; list them with "
                          "warpmesh.numbering.high_order.inverted_elements(mesh)", UserWarning, stacklevel=stacklevel)
    info["to_order"]["time"] = time.perf_counter() - t0
    return type(mesh)(points, cells, point_data=point_data, cell_data=cell_data, point_refs=point_refs,
                cell_refs=cell_refs, info=info)



def _jacobian(x: np.ndarray, dshape: np.ndarray) -> np.ndarray:
    """(d, t, m, s): J[i, q] = sum_n x_n,i dN_n/dxi_q at s points, cells x (m, n, d), dshape (s, n, t).

    One matrix product (BLAS), laid out so that each entry J[i, q] is a contiguous (m, s).
    """
    m, n, d = x.shape
    s, _, t = dshape.shape
    j = x.transpose(2, 0, 1).reshape(d * m, n) @ dshape.transpose(1, 2, 0).reshape(n, t * s)
    return np.ascontiguousarray(j.reshape(d, m, t, s).transpose(0, 2, 1, 3))


def _det(j: np.ndarray) -> np.ndarray:
    """Determinants of J (d, d, ...) in closed form, d = 2 or 3."""
    if len(j) == 2:
        return j[0, 0] * j[1, 1] - j[0, 1] * j[1, 0]
    (a, b, c), (d, e, f), (g, h, i) = j
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def _normal(j: np.ndarray) -> np.ndarray:
    """(d, ...): the normal J[:, 0] x J[:, 1] of a surface in 3D, or the tangent J[:, 0] of a curve."""
    if j.shape[1] == 1:
        return j[:, 0]
    (a, b), (c, d), (e, f) = j
    return np.stack([c * f - e * d, e * b - a * f, a * d - c * b])


def _scores(points: np.ndarray, cells: np.ndarray, el: LagrangeElement) -> np.ndarray:
    """(m,): the minimum scaled Jacobian of each cell (see :func:`jacobians`)."""
    xi = el.samples()
    d_k, d_1 = el.dshape(xi), ELEMENTS[el.base, 1].dshape(xi)  # (s, n, t), (s, nv, t)
    dim, out = points.shape[1], np.empty(len(cells))
    for a in range(0, len(cells), _CHUNK):
        x = points[cells[a: a + _CHUNK]]
        jk, j1 = _jacobian(x, d_k), _jacobian(x[:, : el.n_vertices], d_1)
        if el.tdim == dim:  # volume in 3D, planar in 2D: det J
            num, den = _det(jk), np.abs(_det(j1))
        else:  # a surface or a curve: |n| (|t|) signed by the straight normal (tangent)
            nk, n1 = _normal(jk), _normal(j1)
            num = np.sqrt((nk * nk).sum(axis=0)) * np.sign((nk * n1).sum(axis=0))
            den = np.sqrt((n1 * n1).sum(axis=0))
        ratio = np.divide(num, den, out=np.zeros_like(num), where=den > 0)  # degenerate: 0
        out[a: a + _CHUNK] = ratio.min(axis=1)
    return out


def _jacobians(points, cells) -> dict[str, np.ndarray]:
    points = np.asarray(points, dtype=REAL_DTYPE)
    out = {t: _scores(points, np.asarray(c), ELEMENT_BY_NAME[t]) for t, c in cells.items() if t in ELEMENT_BY_NAME}
    if not out:
        raise ValueError(f"expected a block of the types {sorted(ELEMENT_BY_NAME)} in 'mesh', "
                         f"got {list(cells)}")
    return out


def jacobians(mesh) -> dict[str, np.ndarray]:
    """Minimum scaled Jacobian of every cell: the p-compatibility check [FG Definition 17.3].

    For each cell, the Jacobian matrix J of its isoparametric map (the Lagrange shape
    functions of its type, from a monomial Vandermonde matrix) is sampled at the cell's
    own nodes and, for k >= 2, at its centroid and halfway between the centroid and each
    vertex, and divided by that of the straight (P1 / bi- / trilinear) cell at the same
    point, so that a straight cell scores 1 everywhere. Volume cells and planar cells in
    2D use det J; surface cells in 3D the length of the normal ``J[:, 0] x J[:, 1]``, and
    curves the length of the tangent, signed by the straight cell's normal (tangent). A
    score <= 0 means an inverted (or degenerate) cell; for P1 cells the score is the sign
    of the volume (area), +-1.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    dict {str: (m,) float64}
        Per block of a type of the module table (P1 or higher order); other blocks
        (vertex, wedge, pyramid, quad8, ...) are left out.

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh.
    ValueError
        No block of a type of the module table.

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [0, 1], [0.5, 0], [0.5, 0.5], [0, 0.5]],
    ...             {"triangle6": [[0, 1, 2, 3, 4, 5]]})
    >>> jacobians(m)["triangle6"].round(12).tolist()
    [1.0]
    >>> jacobians(m.replace(points=m.points * [1, -1]))["triangle6"].round(12).tolist()  # mirrored
    [-1.0]
    """
    require_mesh(mesh)
    return _jacobians(mesh.points, mesh.cells)


def inverted_elements(mesh) -> dict[str, np.ndarray]:
    """Cells whose :func:`jacobians` score is <= 0 (inverted or degenerate), per block.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    dict {str: (j,) int64}
        Indices into each block that has such cells; empty when the mesh is valid.

    Raises
    ------
    TypeError, ValueError
        As :func:`jacobians`.

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [0, 1], [0.5, 0], [0.6, 0.6], [0, 0.5]],
    ...             {"triangle6": [[0, 1, 2, 3, 4, 5]]})
    >>> inverted_elements(m)
    {}
    >>> bent = m.points.copy(); bent[4] = [-0.3, -0.3]          # midside node through the cell
    >>> {t: i.tolist() for t, i in inverted_elements(m.replace(points=bent)).items()}
    {'triangle6': [0]}
    """
    return {t: np.flatnonzero(s <= 0) for t, s in jacobians(mesh).items() if np.any(s <= 0)}
