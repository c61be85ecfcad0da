"""Global refinement: every element split into n^d elements of its own type [FG §17.1.2].

Each element of type line, triangle, quad, tetra, hexahedron or wedge is cut along the
lattice of step 1/n of its reference cell [FG Fig. 17.2 for a triangle, n = 3]:

==========  ================================================  ============================
type        lattice node weights (integers)                   sub-elements (n^d)
==========  ================================================  ============================
line        barycentric (n - i, i)                            the n segments
triangle    barycentric (n - i - j, i, j)                     n(n+1)/2 "up" and n(n-1)/2
                                                              "down" lattice triangles
quad        bilinear (n - i)(n - j), i(n - j), ij, (n - i)j   the n^2 tensor cells
hexahedron  trilinear products                                the n^3 tensor cells
wedge       triangle barycentric x (n - k, k)                 lattice triangles x n layers
tetra       barycentric (n - y1, y1 - y2, y2 - y3, y3),       the n^3 Kuhn (Freudenthal)
            n >= y1 >= y2 >= y3 >= 0                          simplices of the lattice
==========  ================================================  ============================

Every lattice node is numbered by :func:`warpmesh.cells.reference.weighted_nodes` with
the weights brought to ONE common denominator (n, n^2 or n^3, the largest the blocks
need), so the node of an edge or face shared by any two elements, in any blocks (a
tetra and a wedge, a hex and its boundary quad), is created once: the result is
conforming by construction, with no merging afterwards. The templates are generated
in code; a sub-element whose reference measure comes out negative is mirrored, so all
children keep their parent's orientation (and surface cells their parent's normal).

Split triangles, quads, hexahedra and wedges are similar to their parent (when it is
affine); the Kuhn sub-tetrahedra are not (the book notes it): the octahedra inside the
lattice are split along one of their three diagonals, chosen by the order of the
parent's vertices (the diagonal joins the midpoints of edges 0-2 and 1-3). Each element
is re-ordered so that this is its SHORTEST diagonal (the choice discussed for "red"
refinement by Zhang and by Bey), which keeps the worst shape bounded under repeated
refinement (a TetGen ball, worst Q_K after 1, 2, 3 levels of n = 2: 6.3, 6.9, 6.9; with
the fixed diagonal 7.8, 17.6, 23.7). A face lattice has one triangulation, so conformity
holds whichever order each element picks.

Remark 17.3: with ``shape``, the new nodes on the boundary go onto f = 0 (the same
projection as :func:`warpmesh.to_order`).

Examples
--------
>>> import warpmesh as wm
>>> m = wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
>>> r = refine_uniform(m, 3)                  # [FG Fig. 17.2]
>>> r.cells["triangle"].shape, r.n_points
((9, 3), 10)
"""

from __future__ import annotations

import itertools
import time
import warnings
from functools import cache
from typing import Literal

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.arrays import unique_rows
from warpmesh._util.budget import check_budget
from warpmesh.cells.types import require_mesh
from warpmesh.cells.collapsed import reject_collapsed
from warpmesh.frep.projection import as_target, check_shape_dim, project_nodes
from warpmesh.cells.reference import (base_type, cell_measures, corner_jacobians, extend_point_values,
                                      reference_cell, weighted_nodes)
from warpmesh.cells.caps import cap_bounds

__all__ = ["refine_uniform", "REFINABLE_TYPES"]

#: the cell types :func:`refine_uniform` splits ("vertex" blocks are kept)
REFINABLE_TYPES = ("line", "triangle", "quad", "tetra", "hexahedron", "wedge")
#: degree of each type's weights in n (their sum is n ** degree)
_DEGREE = {"line": 1, "triangle": 1, "tetra": 1, "quad": 2, "wedge": 2, "hexahedron": 3}
#: the Kuhn template splits octahedra along the diagonal joining the midpoints of edges
#: 0-2 and 1-3; these vertex orders put there the original diagonals (0 2 | 1 3),
#: (0 1 | 2 3) and (0 3 | 1 2). The last two are odd: their children get mirrored.
_TENSOR_TYPES = {1: "line", 2: "quad", 3: "hexahedron"}
_TETRA_ORDERS = np.array([[0, 1, 2, 3], [0, 2, 1, 3], [0, 1, 3, 2]], dtype=INDEX_DTYPE)


# ----------------------------------------------------------------------------- templates
def _triangles(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Lattice (i, j), i + j <= n, as (L, 2) int, and the n^2 up/down triangles (local ids)."""
    ij = np.array([(i, j) for j in range(n + 1) for i in range(n + 1 - j)], dtype=INDEX_DTYPE)
    idx = np.full((n + 2, n + 2), -1, dtype=INDEX_DTYPE)
    idx[ij[:, 0], ij[:, 1]] = np.arange(len(ij))
    up = ij[ij.sum(axis=1) <= n - 1]
    down = ij[ij.sum(axis=1) <= n - 2]
    tri = np.concatenate([
        np.stack([idx[up[:, 0], up[:, 1]], idx[up[:, 0] + 1, up[:, 1]], idx[up[:, 0], up[:, 1] + 1]], 1),
        np.stack([idx[down[:, 0] + 1, down[:, 1]], idx[down[:, 0] + 1, down[:, 1] + 1],
                  idx[down[:, 0], down[:, 1] + 1]], 1),
    ])
    return ij, tri


def _tensor(n: int, dim: int) -> tuple[np.ndarray, np.ndarray]:
    """Lattice {0..n}^dim (L, dim) int, and its n^dim cells in VTK quad/hex corner order."""
    grid = np.stack(np.meshgrid(*[np.arange(n + 1)] * dim, indexing="ij"), -1).reshape(-1, dim)
    radix = (n + 1) ** np.arange(dim)[::-1]
    corners = reference_cell(_TENSOR_TYPES[dim]).vertices.astype(INDEX_DTYPE)
    low = grid[(grid < n).all(axis=1)]
    cells = ((low[:, None, :] + corners[None]) @ radix).astype(INDEX_DTYPE)
    return grid.astype(INDEX_DTYPE), cells


def _kuhn(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Lattice of the Kuhn simplex n >= y1 >= y2 >= y3 >= 0 (L, 3) int and its n^3 Kuhn
    sub-simplices: from a cube corner c, c + e_p0, c + e_p0 + e_p1, c + (1, 1, 1), for
    the permutations p whose simplex lies in the big one."""
    grid, _ = _tensor(n, 3)
    lat = grid[(grid[:, 0] >= grid[:, 1]) & (grid[:, 1] >= grid[:, 2])]
    radix = (n + 1) ** np.arange(3)[::-1]
    lookup = np.full((n + 1) ** 3, -1, dtype=INDEX_DTYPE)
    lookup[lat @ radix] = np.arange(len(lat))
    eye, out = np.eye(3, dtype=INDEX_DTYPE), []
    low = grid[(grid < n).all(axis=1)]
    for p in itertools.permutations(range(3)):  # 6 template entries
        steps = np.cumsum(np.concatenate([np.zeros((1, 3), INDEX_DTYPE), eye[list(p)]]), axis=0)
        v = low[:, None, :] + steps[None]  # (c, 4, 3)
        inside = ((v[..., 0] >= v[..., 1]) & (v[..., 1] >= v[..., 2])).all(axis=1)
        out.append(lookup[v[inside] @ radix])
    return lat, np.concatenate(out)


@cache
def _template(cell_type: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``weights`` (L, nv) int (rows sum to n ** _DEGREE[type]) and ``children`` (n^d, k)
    local lattice ids, positively oriented in the reference cell (checked)."""
    if cell_type in ("line", "quad", "hexahedron"):
        d = reference_cell(cell_type).tdim
        lat, children = _tensor(n, d)
        ref = reference_cell(cell_type).vertices.astype(INDEX_DTYPE)  # corners in {0, 1}^d
        w = np.prod(np.where(ref[None] == 1, lat[:, None, :], n - lat[:, None, :]), axis=2)
    elif cell_type == "triangle":
        lat, children = _triangles(n)
        w = np.stack([n - lat.sum(axis=1), lat[:, 0], lat[:, 1]], axis=1)
    elif cell_type == "wedge":
        tri_lat, tri = _triangles(n)
        q = len(tri_lat)
        k = np.arange(n + 1)
        bary = np.stack([n - tri_lat.sum(axis=1), tri_lat[:, 0], tri_lat[:, 1]], axis=1)
        w = np.concatenate([bary[None] * (n - k)[:, None, None], bary[None] * k[:, None, None]], axis=2)
        w = w.reshape(-1, 6)  # node (layer k, triangle node a) is k * q + a
        layers = np.arange(n)[:, None, None] * q
        children = np.concatenate([tri[None] + layers, tri[None] + layers + q], axis=2).reshape(-1, 6)
    elif cell_type == "tetra":
        lat, children = _kuhn(n)
        w = np.stack([n - lat[:, 0], lat[:, 0] - lat[:, 1], lat[:, 1] - lat[:, 2], lat[:, 2]], axis=1)
    else:
        raise ValueError(cell_type)
    w = w.astype(INDEX_DTYPE)
    ref = reference_cell(cell_type)
    x = (w / w.sum(axis=1, keepdims=True)) @ ref.vertices
    vol = cell_measures(x, children, cell_type)
    children = np.where((vol < 0)[:, None], children[:, ref.mirror], children)
    vol = np.abs(vol)
    assert len(children) == n ** ref.tdim and np.allclose(vol, vol[0]) and vol.min() > 0, cell_type
    for a in (w, children):
        a.setflags(write=False)
    return w, children


# ----------------------------------------------------------------------------- validation
def _check_n(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise TypeError(f"expected an int >= 1 for 'n', got {n!r} ({type(n).__name__})")
    if n < 1:
        raise ValueError(f"expected 'n' >= 1 (sub-divisions per edge), got {n}")
    return int(n)


def _check_blocks(mesh) -> list[str]:
    for t in mesh.cells:
        if t == "vertex" or t in REFINABLE_TYPES:
            continue
        if t == "pyramid":
            fix = "convert pyramids to tetra first (each splits into two tetrahedra)"
        elif base_type(t) != t:
            fix = f"refine the P1 ({base_type(t)}) mesh, then call to_order"
        else:
            fix = "drop or convert that block first"
        raise ValueError(f"expected blocks of {list(REFINABLE_TYPES)} (and 'vertex', kept) in "
                         f"'mesh', got {t!r} cells: {fix}")
    blocks = [t for t in mesh.cells if t in REFINABLE_TYPES]
    if not blocks:
        raise ValueError(f"expected a block of {list(REFINABLE_TYPES)} cells in 'mesh', "
                         f"got {list(mesh.cells)}")
    return blocks


# ----------------------------------------------------------------------------- pipeline
def _tetra_orders(points: np.ndarray, tet: np.ndarray, diagonal: str) -> np.ndarray:
    """(m,) index into _TETRA_ORDERS: the order whose octahedron diagonal is shortest."""
    if diagonal == "fixed":
        return np.zeros(len(tet), dtype=INDEX_DTYPE)
    p = points[tet]
    # midpoint(a, b) - midpoint(c, d), up to a factor 1/2, for the three pairings
    d = np.stack([p[:, 0] + p[:, 2] - p[:, 1] - p[:, 3], p[:, 0] + p[:, 1] - p[:, 2] - p[:, 3],
                  p[:, 0] + p[:, 3] - p[:, 1] - p[:, 2]], axis=1)
    return np.einsum("mkd,mkd->mk", d, d).argmin(axis=1)


def _corner_frames(points: np.ndarray, cells: np.ndarray, tdim: int) -> np.ndarray:
    """(m, k, 3|2): at each corner of lines/polygons, the tangent (lines) or the normal
    (next - x) x (prev - x) (triangles, quads, in their cyclic order)."""
    x = points[cells]
    if tdim == 1:
        return np.repeat((x[:, 1] - x[:, 0])[:, None], 2, axis=1)
    return np.cross(np.roll(x, -1, axis=1) - x, np.roll(x, 1, axis=1) - x)


def _inverted(before: np.ndarray, after: np.ndarray, cells: dict) -> int:
    """Cells inverted by the projection: a corner Jacobian <= 0 (cells of full dimension),
    or a corner normal (tangent) that turned by 90 degrees or more (surfaces, curves)."""
    dim, bad = after.shape[1], 0
    for t, c in cells.items():
        tdim = reference_cell(t).tdim
        if tdim == 0 or len(c) == 0:
            continue
        if tdim == dim:
            bad += int(np.count_nonzero((corner_jacobians(after, c, t) <= 0).any(axis=1)))
        else:
            dot = np.einsum("mkd,mkd->mk", _corner_frames(before, c, tdim), _corner_frames(after, c, tdim))
            bad += int(np.count_nonzero((dot <= 0).any(axis=1)))
    return bad


def _boundary_new_nodes(lattice: dict, k: int, n0: int, n: int, dim: int) -> np.ndarray:
    """New nodes to project (Remark 17.3): the lattice nodes on the facets (faces in 3D,
    edges in 2D) of the parent cells of top dimension that lie in one such cell; all new
    nodes of a curve or surface mesh."""

    top = max(reference_cell(t).tdim for t in lattice)
    if top < dim:
        return np.arange(n0, n, dtype=INDEX_DTYPE)
    found = []
    for size in ((2,) if top == 2 else (3, 4)):
        group = []  # (lattice ids (m, L), local facets (f, size), template weights)
        for t, ids in lattice.items():
            ref = reference_cell(t)
            local = ref.edges.tolist() if top == 2 else [f for f in ref.faces if len(f) == size]
            if ref.tdim == top and local:
                group.append((ids, np.array(local), _template(t, k)[0]))
        if not group:
            continue
        # the parents' facets, on their vertices as the lattice numbers them (the tetra
        # may be re-ordered): a vertex is the lattice node whose weight sits on it alone
        rows = [ids[:, np.argmax(w, axis=0)][:, f].reshape(-1, size) for ids, f, w in group]
        _, _, inverse, counts = unique_rows(np.sort(np.concatenate(rows), axis=1))
        once, start = counts[inverse] == 1, 0
        for (ids, facets, w), r in zip(group, rows, strict=True):
            b = once[start: start + len(r)].reshape(len(ids), len(facets))
            start += len(r)
            for j, f in enumerate(facets):  # loop over local facets: nodes on facet f
                on = np.flatnonzero(np.delete(w, f, axis=1).sum(axis=1) == 0)
                found.append(ids[b[:, j]][:, on].ravel())
    nodes = np.unique(np.concatenate(found)) if found else np.zeros(0, dtype=INDEX_DTYPE)
    return nodes[nodes >= n0]


def _project_nodes(target, points, nodes, cap):
    """Move ``nodes`` onto f = 0 in place; return max |f| after (box distance on caps)."""

    dim = points.shape[1]
    x = points[nodes]
    if dim == 2:
        x = np.column_stack([x, np.zeros(len(x))])
    y = project_nodes(target, x, cap)
    points[nodes] = y[:, :dim]
    if len(y) == 0:
        return 0.0
    shape = getattr(target, "shape", None)
    if shape is not None and hasattr(shape, "eval_numpy"):
        f = np.broadcast_to(np.asarray(shape.eval_numpy(y[:, 0], y[:, 1], y[:, 2]), REAL_DTYPE), (len(y),))
    else:
        f = target.value_gradient(y)[0]
    f = np.abs(f)
    if target.bounds is not None:
        lo, hi = target.bounds
        f = np.minimum(f, np.abs(np.concatenate([y - lo, hi - y], axis=1)).min(axis=1))
    return float(f.max())


def _split(mesh, types: list[str], k: int, diagonal: str):
    """Number the lattice nodes of every block in one :func:`weighted_nodes` call (one
    common denominator, so shared nodes are created once), then cut the cells.

    Returns the points (n0 + new, d), the new cell blocks (children of element e at
    ``e * k^d ... (e + 1) * k^d - 1``), the lattice node numbers of each refined block
    {type: (m, L)}, and the new nodes' ``(vertices, weights)`` support."""
    points0 = np.asarray(mesh.points)
    top = max(_DEGREE[t] for t in types)
    width = max(len(reference_cell(t).vertices) for t in types)
    rows_v, rows_w, plan = [], [], []
    for t in types:
        w, children = _template(t, k)
        cells = np.asarray(mesh.cells[t])
        flip = np.zeros(len(cells), dtype=bool)
        if t == "tetra" and k > 1:
            order = _tetra_orders(points0, cells, diagonal)
            cells = np.take_along_axis(cells, _TETRA_ORDERS[order], axis=1)
            flip = order > 0  # odd vertex permutations: mirror the children
        m, (nl, nv) = len(cells), w.shape
        v = np.zeros((m, nl, width), dtype=INDEX_DTYPE)
        ww = np.zeros((m, nl, width), dtype=INDEX_DTYPE)
        v[:, :, :nv] = cells[:, None, :]
        ww[:, :, :nv] = w * k ** (top - _DEGREE[t])
        rows_v.append(v.reshape(-1, width))
        rows_w.append(ww.reshape(-1, width))
        plan.append((t, m, nl, children, flip))
    ids, new_points, support = weighted_nodes(points0, np.concatenate(rows_v), np.concatenate(rows_w))
    lattice, new_cells, start = {}, {}, 0
    for t, m, nl, children, flip in plan:
        lattice[t] = ids[start: start + m * nl].reshape(m, nl)
        start += m * nl
        c = lattice[t][:, children]  # (m, s, kv)
        if flip.any():
            c[flip] = c[flip][:, :, reference_cell(t).mirror]
        new_cells[t] = c.reshape(-1, children.shape[1])
    cells = {t: new_cells.get(t, mesh.cells[t]) for t in mesh.cells}
    return np.concatenate([points0, new_points]), cells, lattice, support


def _project_boundary(target, mesh, k: int, points: np.ndarray, cells: dict, lattice: dict) -> dict:
    """Remark 17.3: move the new boundary nodes onto f = 0 (``points`` in place); return
    ``n_projected``, ``max_abs_f`` and ``n_inverted``."""
    nodes = _boundary_new_nodes(lattice, k, mesh.n_points, len(points), mesh.dim)
    cap = np.zeros(len(points))  # a Newton step stays below the longest edge of the parents
    for t, ids in lattice.items():
        c, e = np.asarray(mesh.cells[t]), reference_cell(t).edges
        h = np.linalg.norm(mesh.points[c[:, e[:, 0]]] - mesh.points[c[:, e[:, 1]]], axis=2).max(axis=1)
        np.maximum.at(cap, ids.ravel(), np.repeat(h, ids.shape[1]))
    straight = points.copy()
    max_f = _project_nodes(target, points, nodes, cap[nodes])
    return {"n_projected": len(nodes), "max_abs_f": max_f,
            "n_inverted": _inverted(straight, points, cells)}


# ----------------------------------------------------------------------------- public API
def refine_uniform(mesh, n: int = 2, shape=None, *, bounds=None,
                   tetra_diagonal: Literal["shortest", "fixed"] = "shortest"):
    """Split every element into n^d elements of its type [FG §17.1.2, Fig. 17.2].

    Lines, triangles, quads, tetrahedra, hexahedra and wedges, in any mix, in 2D or 3D
    (surface cells too), are cut on the lattice of step 1/n of their reference cell
    (module docstring). Nodes shared by elements of any blocks are created once, so a
    conforming mesh stays conforming; children keep their parent's orientation.

    With ``shape``, the new nodes on the boundary are projected onto f = 0 (seed Remark
    17.3): in a volume mesh those on faces of one 3D cell, in a planar mesh those on
    edges of one 2D cell, in a curve or surface mesh every new node. Other nodes stay
    where the lattice puts them, so elements along a strongly curved boundary may invert;
    they are counted (``info["n_inverted"]``) and a warning is issued.

    Attributes: every child inherits its parent's cell refs and cell data. A new node
    gets the point ref its supporting vertices (the edge's, the face's, the cell's) share,
    else 0; float point data are interpolated with the node's weights, other point data
    (integers, booleans) are treated like refs.

    Parameters
    ----------
    mesh : Mesh
        Blocks of the types above; ``vertex`` blocks are kept. Unused points keep their
        numbers.
    n : int
        Sub-divisions per edge, >= 1 (1 returns an equal mesh).
    shape : Shape, Expr, VolumeField or projection target, optional
        The exact geometry (f > 0 inside). 2D meshes are read at z = 0.
    bounds : ((x0, y0, z0), (x1, y1, z1)), optional
        The box the mesh was capped on (as in :func:`warpmesh.mesh_surface`); by default read
        from the mesh's cap faces (ref ``CAP_REF``: :func:`warpmesh.cells.caps.cap_bounds`), so
        their nodes stay on the box.
    tetra_diagonal : {"shortest", "fixed"}
        How each tetrahedron's inner octahedra are split: along their shortest diagonal
        (default), or along the one fixed by the local vertex order (0-2 | 1-3 midpoints),
        for comparison.

    Returns
    -------
    Mesh
        Points (n_points + new, d): the original points first, then the new nodes.
        ``info`` gains ``refine_n``, ``refine`` (``n_points_before``, ``n_points_after``,
        ``n_cells_before``, ``n_cells_after``, ``time``) and, with ``shape``,
        ``n_projected``, ``max_abs_f`` (over the projected nodes) and ``n_inverted``.

    Raises
    ------
    TypeError
        ``mesh`` not a Mesh, ``n`` not an int, ``shape`` not a shape.
    ValueError
        ``n`` < 1; pyramids or higher-order blocks (the message names the fix); no block
        to refine; ``bounds`` without ``shape``; an unknown ``tetra_diagonal``.

    Warns
    -----
    UserWarning
        With ``shape``, when the projection inverted some elements.

    Examples
    --------
    >>> import numpy as np, warpmesh as wm
    >>> cube = wm.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
    ...                 [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], {"hexahedron": [np.arange(8)]})
    >>> r = refine_uniform(cube, 2)
    >>> r.cells["hexahedron"].shape, r.n_points, r.info["refine_n"]
    ((8, 8), 27, 2)
    >>> sq = wm.Mesh([[1, 0], [0, 1], [-1, 0], [0, -1]], {"line": [[0, 1], [1, 2], [2, 3], [3, 0]]})
    >>> c = refine_uniform(sq, 4, wm.sphere(1.0))     # a circle: new nodes go onto it
    >>> c.info["n_projected"], bool(np.allclose(np.linalg.norm(c.points, axis=1), 1))
    (12, True)
    """
    t0 = time.perf_counter()
    require_mesh(mesh)
    reject_collapsed(mesh, 'refine')
    k = _check_n(n)
    if tetra_diagonal not in ("shortest", "fixed"):
        raise ValueError(f"expected 'tetra_diagonal' 'shortest' or 'fixed', got {tetra_diagonal!r}")
    if shape is None and bounds is not None:
        raise ValueError("expected a 'shape' with 'bounds' (the box caps that shape), got shape=None")
    types = _check_blocks(mesh)
    n_after = sum(len(mesh.cells[t]) * float(k) ** reference_cell(t).tdim for t in types)
    nv_max = max(mesh.cells[t].shape[1] for t in types)
    check_budget(3 * n_after * (8 * nv_max + 8 * mesh.dim), f"refine(n={k}) of {mesh.n_cells} cells "
                 f"({n_after:.3g} cells after)", "lower 'n', or refine where needed (where=..., max_length=...)")
    if shape is not None and bounds is None:  # a capped mesh: its cap faces stay on their box
        bounds = cap_bounds(mesh)
    target = None if shape is None else as_target(shape, bounds=bounds)
    if shape is not None:
        check_shape_dim(shape, mesh.points)
    n0 = mesh.n_points

    points, cells, lattice, support = _split(mesh, types, k, tetra_diagonal)
    info = {key: v for key, v in mesh.info.items() if key not in ("n_projected", "max_abs_f", "n_inverted")}
    info["refine_n"] = k
    if target is not None:
        info.update(_project_boundary(target, mesh, k, points, cells, lattice))
        if info["n_inverted"]:
            warnings.warn(f"{info['n_inverted']} elements are inverted after projecting the boundary "
                          f"nodes of the refinement (n={k}) onto the shape: the boundary moved by more "
                          "than the thickness of the first layer; refine in steps of n=2, projecting "
                          "each time", UserWarning, stacklevel=2)

    s = {t: k ** reference_cell(t).tdim for t in types}
    point_refs = None if mesh.point_refs is None else extend_point_values(mesh.point_refs, support)
    point_data = {key: extend_point_values(v, support) for key, v in mesh.point_data.items()}
    cell_refs = (None if mesh.cell_refs is None
                 else {t: np.repeat(r, s.get(t, 1)) for t, r in mesh.cell_refs.items()})
    cell_data = {key: {t: np.repeat(np.asarray(a), s.get(t, 1), axis=0) for t, a in v.items()}
                 for key, v in mesh.cell_data.items()}
    info["refine"] = {"n_points_before": n0, "n_points_after": len(points),
                      "n_cells_before": mesh.n_cells,
                      "n_cells_after": sum(len(c) for c in cells.values()),
                      "time": time.perf_counter() - t0}
    return type(mesh)(points, cells, point_data=point_data, cell_data=cell_data, point_refs=point_refs,
                cell_refs=cell_refs, info=info)
