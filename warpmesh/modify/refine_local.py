"""Local refinement by longest-edge bisection, kept conforming ([FG §17.1.2], Remarks 17.4
and 17.5; Rivara's algorithm).

:func:`refine_local` splits the elements around a list of vertices (the book's "list of
vertices around which a refinement is expected"), a mask of elements, or every element
with an edge longer than a size ``h`` (the book's "edges judged too long"), in a mesh of
lines, triangles (planar or on a surface) and tetrahedra.

The algorithm, vectorised in rounds
    A table of split edges maps each split edge (its sorted vertex pair, one int64 key)
    to its midpoint. In a round, every element that is marked, or that has an edge in
    the table (a hanging node), is bisected across its own longest edge: the midpoint
    m of that edge (i, j) is looked up or created, and the element becomes two, with m
    in place of vertex j, and m in place of vertex i. Ties between equally long edges
    are broken by the edge key, so every element sharing an edge ranks it the same way.
    Rounds repeat until no element is marked and none has a hanging node.

Why it is conforming
    The longest edge of a tetrahedron is the longest edge of every face containing it,
    so the faces are themselves split by longest-edge bisection: each face of the mesh
    is cut along one binary tree, whichever element (a tetrahedron on either side, a
    boundary triangle) does it. Two different cuts of a face differ at a leaf that one
    side has split and the other has not, and then that side holds a split edge. So when
    no element holds a split edge, all of them agree: the mesh is conforming, and the
    lower-dimensional blocks (boundary lines, boundary or interface triangles) are
    exactly edges and faces of the elements of higher dimension.

Why it stops (Rivara)
    Each element split because of a hanging edge E splits its longest edge L, and
    L ranks above E (or is E): a chain of new midpoints climbs a total order over the
    finitely many edges (Rivara's longest-edge propagation path). For triangles,
    bisection by the longest edge also keeps at least half of the smallest angle
    (Rosenberg & Stenger), which the tests check; for tetrahedra no such bound is
    proven and the tests report the quality measured. ``max_rounds`` guards anyway.

Boundary
    With a ``shape``, midpoints of boundary edges are projected onto f = 0 as they are
    created. Boundary edges are known without a conforming mesh at hand: at the start
    (edges of one triangle, or of the faces of one tetrahedron), then the halves of a
    boundary edge, and in 3D the edges that a split draws across a boundary face
    (tetrahedra carry a flag per face, triangles of other blocks one flag each).

Children keep their parent's orientation (replacing one end of an edge by its midpoint
halves the signed measure), refs and cell data. Element ``i`` of the input is still
row ``i`` of the output when untouched; a split element's first child takes its row and
the second child is appended.

Examples
--------
>>> import warpmesh as wm
>>> m = wm.Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
>>> r = refine_local(m, where=[1])                  # the triangle around vertex 1
>>> r.cells["triangle"].tolist()                    # the shared diagonal (0, 2) is split
[[4, 1, 2], [0, 4, 3], [0, 1, 4], [4, 2, 3]]
>>> r.points[4].tolist(), r.info["rounds"], r.info["n_bisections"]   # round 2: the closure
([0.5, 0.5], 2, 2)
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.budget import check_budget
from warpmesh.cells.types import CELL_TYPES, require_mesh
from warpmesh.cells.collapsed import reject_collapsed
from warpmesh.cells.caps import cap_bounds
from warpmesh.frep.projection import as_target, check_shape_dim, project_nodes
from warpmesh.errors import WarpMeshError
from warpmesh.cells.quality import tetra_quality, triangle_quality
from warpmesh.cells.reference import cell_measures, reference_cell

__all__ = ["refine_local", "SIMPLEX_TYPES"]

#: the cell types :func:`refine_local` splits, with their topological dimension
SIMPLEX_TYPES = {"line": 1, "triangle": 2, "tetra": 3}
_EDGES = {t: reference_cell(t).edges for t in SIMPLEX_TYPES}
#: tetra edge e (local (i, j)) -> the two other local vertices (k, l), k < l
_TET_OTHERS = np.array([sorted(set(range(4)) - set(e)) for e in _EDGES["tetra"].tolist()])
_SHIFT = 32  # edge key = lo << 32 | hi
_MAX_POINTS = 1 << 31


# ----------------------------------------------------------------------------- validation
def _check_types(mesh) -> list[str]:
    bad = [t for t in mesh.cells if t not in SIMPLEX_TYPES and t != "vertex"]
    if bad:
        hint = "tetra" if any(CELL_TYPES[t][1] == 3 for t in bad) else "triangle"
        raise ValueError(f"expected only (P1) line, triangle and tetra cells (and 'vertex', kept), "
                         f"got {bad}; convert to triangles/tetra first: mesh.convert({hint!r})")
    types = [t for t in mesh.cells if t in SIMPLEX_TYPES]
    if not types:
        raise ValueError(f"expected a line, triangle or tetra block in 'mesh', got {list(mesh.cells)}")
    return types


def _check_where(mesh, where, types: list[str]) -> dict[str, np.ndarray]:
    """Per block: the elements marked once, (m,) bool."""
    marks = {t: np.zeros(len(mesh.cells[t]), bool) for t in types}
    if where is None:
        return marks
    top = max(types, key=SIMPLEX_TYPES.get)
    if isinstance(where, Mapping):
        for t, mask in where.items():
            if t not in marks:
                raise ValueError(f"expected 'where' keys among the blocks {types}, got {t!r}")
            marks[t] = _check_mask(mask, len(marks[t]), f"where[{t!r}]")
        return marks
    arr = np.asarray(where)
    if arr.dtype == bool:
        marks[top] = _check_mask(arr, len(marks[top]), "where")
        return marks
    if arr.size == 0:
        return marks
    if arr.dtype.kind not in "iu":
        raise TypeError(f"expected vertex indices (int) or a mask (bool) for 'where', got dtype {arr.dtype}")
    arr = arr.ravel()
    if arr.min() < 0 or arr.max() >= mesh.n_points:
        raise ValueError(f"expected vertex indices in [0, {mesh.n_points}) in 'where', "
                         f"got [{arr.min()}, {arr.max()}]")
    chosen = np.zeros(mesh.n_points, bool)
    chosen[arr] = True
    marks[top] = chosen[mesh.cells[top]].any(axis=1)
    return marks


def _check_mask(mask, m: int, name: str) -> np.ndarray:
    arr = np.asarray(mask)
    if arr.dtype != bool:
        raise TypeError(f"expected a bool mask for {name!r}, got dtype {arr.dtype}")
    if arr.shape != (m,):
        raise ValueError(f"expected {name!r} of shape ({m},) (one flag per element), got shape {arr.shape}")
    return arr.copy()


def _check_size(max_length) -> Callable | None:
    if max_length is None:
        return None
    if callable(max_length):
        return max_length
    if isinstance(max_length, bool) or not isinstance(max_length, (int, float, np.integer, np.floating)):
        raise TypeError(f"expected a float or a callable h(points) for 'max_length', "
                        f"got {type(max_length).__name__}")
    h = float(max_length)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"expected a positive finite 'max_length', got {max_length}")
    return lambda x: np.full(len(x), h)


def _check_output_size(mesh, types, size: Callable) -> float:
    """Refuse (SizeError) before any work when ``max_length`` would make more cells than the
    memory budget holds: each simplex becomes about (longest edge / h(centroid))^d of them.
    Returns the estimated cell count."""
    points = np.asarray(mesh.points, REAL_DTYPE)
    total, nv_max = 0.0, 2
    for t in types:
        c = np.asarray(mesh.cells[t])
        if not len(c):
            continue
        p = points[c]
        longest = np.max([np.linalg.norm(p[:, i] - p[:, j], axis=1) for i, j in _EDGES[t].tolist()], axis=0)
        ratio = np.maximum(1.0, longest / _sizes(size, p.mean(axis=1)))
        total += float(np.sum(ratio ** SIMPLEX_TYPES[t]))
        nv_max = max(nv_max, c.shape[1])
    check_budget(3 * total * (8 * nv_max + 8 * mesh.dim), f"refine(max_length=...) of {mesh.n_cells} cells "
                 f"(about {total:.3g} cells after)", "raise 'max_length'")
    return total


def _sizes(size: Callable, x: np.ndarray) -> np.ndarray:
    h = np.asarray(size(x), dtype=REAL_DTYPE)
    if h.shape != (len(x),):
        raise ValueError(f"expected max_length(points) of shape ({len(x)},), got shape {h.shape}")
    bad = ~(np.isfinite(h) & (h > 0))
    if bad.any():
        raise ValueError(f"expected positive finite sizes from 'max_length', got {h[bad][0]} "
                         f"at {x[bad][0].tolist()}")
    return h


# ----------------------------------------------------------------------------- tables
def _keys(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return (lo << _SHIFT) | hi


def _lookup(table: np.ndarray, keys: np.ndarray):
    """(hit, position) of each key in the sorted ``table``."""
    if len(table) == 0:
        return np.zeros(keys.shape, bool), np.zeros(keys.shape, INDEX_DTYPE)
    pos = np.minimum(np.searchsorted(table, keys), len(table) - 1)
    return table[pos] == keys, pos


def _insert(table: np.ndarray, values: np.ndarray, keys: np.ndarray, vals: np.ndarray):
    """``table`` (sorted, unique) with the new sorted unique ``keys`` merged in."""
    at = np.searchsorted(table, keys)
    return np.insert(table, at, keys), np.insert(values, at, vals)


def _edge_lengths2(pts: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Squared lengths, computed the same way for an edge whichever element holds it."""
    d = pts[hi] - pts[lo]
    out = d[..., 0] * d[..., 0]
    for k in range(1, pts.shape[1]):
        out = out + d[..., k] * d[..., k]
    return out


def _face_keys(faces: np.ndarray, n: int) -> np.ndarray:
    """(f,) keys of triangles (f, 3), any vertex order: rows of the sorted triple."""
    s = np.sort(faces, axis=1)
    if n < (1 << 21):
        return (s[:, 0] << 42) | (s[:, 1] << 21) | s[:, 2]
    return np.unique(s, axis=0, return_inverse=True)[1].ravel()  # pragma: no cover - huge meshes


def _boundary_setup(mesh, types):
    """Boundary edge keys (sorted) and per-element boundary flags, for projecting midpoints.

    Planar mesh: the edges of one triangle. Tetra mesh: the edges of the faces of one
    tetra; flags per tetra face (opposite each vertex) and per triangle of other blocks
    say which lie on that boundary, so that new edges drawn across them are known too.
    """
    cells, n = mesh.cells, mesh.n_points
    flags: dict[str, np.ndarray] = {}
    if "tetra" in types:
        tet = np.asarray(cells["tetra"])
        opp = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])  # face opposite vertex k
        keys = _face_keys(tet[:, opp].reshape(-1, 3), n)
        uniq, inv, counts = np.unique(keys, return_inverse=True, return_counts=True)
        once = counts[inv.ravel()] == 1
        flags["tetra"] = once.reshape(-1, 4)
        faces = tet[:, opp].reshape(-1, 3)[once]
        edges = faces[:, [[0, 1], [1, 2], [0, 2]]].reshape(-1, 2)
        if "triangle" in types:
            flags["triangle"] = np.isin(_face_keys(np.asarray(cells["triangle"]), n), uniq[counts == 1])
    else:
        tri = np.asarray(cells["triangle"])
        e = np.sort(tri[:, _EDGES["triangle"]].reshape(-1, 2), axis=1)
        k, counts = np.unique(_keys(e[:, 0], e[:, 1]), return_counts=True)
        return k[counts == 1], flags
    e = np.sort(edges, axis=1)
    return np.unique(_keys(e[:, 0], e[:, 1])), flags


# ----------------------------------------------------------------------------- attributes
def _extend(values: np.ndarray, parents: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Values at every point: floats averaged over the two ends of the split edge, anything
    else (refs, ints, bools) kept where the two ends agree, else zero; in creation order."""
    total = len(values) + sum(len(a) for a, _ in parents)
    out = np.zeros((total, *values.shape[1:]), values.dtype)
    out[: len(values)] = values
    start = len(values)
    for a, b in parents:
        va, vb = out[a], out[b]
        out[start: start + len(a)] = (0.5 * (va + vb) if values.dtype.kind in "fc"
                                      else np.where(va == vb, va, np.zeros_like(va)))
        start += len(a)
    return out


def _quality_type(cells: Mapping) -> str | None:
    """The block whose Q_K is reported (as :func:`warpmesh.cells.quality.quality_summary`)."""
    return "tetra" if "tetra" in cells else "triangle" if "triangle" in cells else None


def _select(t, c, rows, marks, fresh, points, table, size):
    """(rows, local edge, edge key) of the candidate elements ``rows`` of block t that split
    this round (marked, holding a split edge, or fresh and too long), or None."""
    e = c[rows][:, _EDGES[t]]
    lo, hi = e.min(axis=2), e.max(axis=2)
    key = _keys(lo, hi)
    todo = marks[rows] | _lookup(table, key)[0].any(axis=1)
    if size is not None:
        f = np.flatnonzero(fresh[rows] & ~todo)
        if len(f):
            mid = 0.5 * (points[lo[f]] + points[hi[f]])
            h = _sizes(size, mid.reshape(-1, points.shape[1])).reshape(len(f), e.shape[1])
            todo[f] |= (_edge_lengths2(points, lo[f], hi[f]) > h * h).any(axis=1)
    if not todo.any():
        return None
    rows, key = rows[todo], key[todo]
    len2 = _edge_lengths2(points, lo[todo], hi[todo])
    score = np.where(len2 == len2.max(axis=1, keepdims=True), key, -1)  # ties: the larger key
    best = np.argmax(score, axis=1)
    return rows, best, key[np.arange(len(rows)), best]


def _new_boundary_edges(t, flags, rows, par, best, m_ids):
    """Keys of the edges drawn across boundary faces by splitting ``par`` (rows of block t
    with boundary flags), and the flags of the block after the split."""
    ar = np.arange(len(rows))
    i_col, j_col = _EDGES[t][best, 0], _EDGES[t][best, 1]
    edge = lambda v, on: _keys(np.minimum(m_ids, v)[on], np.maximum(m_ids, v)[on])  # noqa: E731
    if t == "triangle":  # a boundary triangle of a tetra mesh: its new edge (m, v_k)
        on = flags[rows]
        return edge(par[ar, 3 - i_col - j_col], on), np.concatenate([flags, on])
    k, q = _TET_OTHERS[best, 0], _TET_OTHERS[best, 1]  # edge (m, v_k) lies in face (i, j, k)
    add = np.concatenate([edge(par[ar, k], flags[rows, q]), edge(par[ar, q], flags[rows, k])])
    f1, f2 = flags[rows].copy(), flags[rows].copy()
    f1[ar, i_col], f2[ar, j_col] = False, False  # the new inner face (m, v_k, v_l)
    flags[rows] = f1
    return add, np.concatenate([flags, f2])


def _worst_q(points, cells, t: str | None, changed: np.ndarray, q0: np.ndarray | None):
    """Worst Q_K of block t: the untouched elements' from before, the others computed."""
    if t is None:
        return None
    q = (triangle_quality if t == "triangle" else tetra_quality)(points, cells[changed])
    return float(max(q.max(initial=-np.inf), q0[~changed[: len(q0)]].max(initial=-np.inf)))


# ----------------------------------------------------------------------------- public API
def refine_local(mesh, *, where=None, max_length=None, shape=None, max_rounds: int = 64):
    """Refine a simplex mesh locally by Rivara's longest-edge bisection, kept conforming.

    See the module docstring for the algorithm. Every line, triangle and tetra block is
    refined; triangles and lines lying on the faces and edges of elements of higher
    dimension (boundary or interface blocks, feature lines) are split with them and stay
    exactly their faces and edges. ``vertex`` blocks are kept.

    Parameters
    ----------
    mesh : Mesh
        Lines, triangles (planar or a surface in 3D), tetrahedra; conforming.
    where : int array, bool array or dict {str: (m,) bool}, optional
        Vertex indices: bisect (once) every element of the highest dimension containing
        one of them. A bool mask (m,) over the elements of the highest dimension, or per
        block: bisect those elements once. The closure then splits their neighbours.
    max_length : float or callable, optional
        A size h, or h(points (k, d)) -> (k,) sizes: bisect repeatedly until no edge is
        longer than h at its midpoint. With ``where`` too, the union of both.
    shape : Shape, Expr, VolumeField or projection target, optional
        The exact geometry (f = 0 on the boundary): midpoints of boundary edges are
        projected onto f = 0 as they are created (every midpoint of a curve or surface
        mesh; of boundary edges in planar and tetra meshes). 2D meshes are read at z = 0.
    max_rounds : int
        Guard on the number of rounds of bisection.

    Returns
    -------
    Mesh
        New points (midpoints) appended after the old ones; untouched elements keep
        their rows. Point refs of a midpoint: the common ref of the edge's two ends, else
        0; float point data are interpolated (the mean of the two ends), other point
        data treated like refs; cell refs and cell data go to both children. ``info``
        gains ``q_worst_before``, ``q_worst_after`` (seed Q_K, eq. 16.15, of the
        tetrahedra, else the triangles; None for lines), ``n_bisections``, ``rounds``,
        ``n_split_edges``, ``n_projected``, ``refine_time`` (s) and, with ``shape`` in a planar or
        volume mesh, ``n_inverted`` (elements folded by the projection, expected 0 when
        the boundary is resolved by the mesh).

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh; ``where`` neither ints nor bools; ``max_length`` neither
        a number nor a callable; ``max_rounds`` not an int.
    ValueError
        Cell types other than line, triangle, tetra, vertex (convert first:
        ``mesh.convert('tetra')`` or ``mesh.convert('triangle')``); neither ``where`` nor
        ``max_length``; vertex indices out of range; a mask of the wrong length or for an
        unknown block; a non-positive or non-finite size; ``max_rounds`` < 1.
    WarpMeshError
        The refinement did not finish within ``max_rounds`` rounds.

    Examples
    --------
    >>> import numpy as np, warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}, point_refs=[1, 1, 2])
    >>> r = refine_local(m, max_length=0.5)
    >>> len(r.cells["triangle"]), r.info["rounds"], round(r.stats()["area"], 12)
    (8, 3, 0.5)
    >>> r.point_refs.tolist()            # a midpoint has the common ref of its edge's ends, else 0
    [1, 1, 2, 0, 1, 0, 0, 0, 0]
    """
    t0 = time.perf_counter()
    require_mesh(mesh)
    reject_collapsed(mesh, 'refine')
    types = _check_types(mesh)
    marks = _check_where(mesh, where, types)
    size = _check_size(max_length)
    if where is None and size is None:
        raise ValueError("expected 'where' (vertices or an element mask) or 'max_length', got neither")
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, (int, np.integer)):
        raise TypeError(f"expected an int for 'max_rounds', got {type(max_rounds).__name__}")
    if max_rounds < 1:
        raise ValueError(f"expected 'max_rounds' >= 1, got {max_rounds}")
    # a capped mesh: the midpoints of its cap faces stay on the box (read from those faces)
    target = None if shape is None else as_target(shape, bounds=cap_bounds(mesh))
    if shape is not None:
        check_shape_dim(shape, mesh.points)
    if size is not None:
        _check_output_size(mesh, types, size)

    dim, n0 = mesh.dim, mesh.n_points
    top_dim = max(SIMPLEX_TYPES[t] for t in types)
    surface = top_dim < dim  # a curve or a surface: every midpoint is on the shape
    bkeys, bflags = (_boundary_setup(mesh, types) if target is not None and not surface
                     else (np.zeros(0, INDEX_DTYPE), {}))
    cells = {t: np.array(mesh.cells[t], dtype=INDEX_DTYPE) for t in types}
    src = {t: np.arange(len(c), dtype=INDEX_DTYPE) for t, c in cells.items()}
    fresh = {t: np.full(len(c), size is not None) for t, c in cells.items()}  # to size-check
    changed = {t: np.zeros(len(c), bool) for t, c in cells.items()}
    points, n = np.asarray(mesh.points, REAL_DTYPE), n0
    table, mids = np.zeros(0, INDEX_DTYPE), np.zeros(0, INDEX_DTYPE)
    touched = None
    parents: list[tuple[np.ndarray, np.ndarray]] = []
    n_bisect, n_projected, rounds = 0, 0, 0

    while True:
        # 1. which elements split this round, and across which edge
        plan = {}
        for t, c in cells.items():
            cand = marks[t] | fresh[t]
            if touched is not None:
                cand |= touched[c].any(axis=1)
            chosen = _select(t, c, np.flatnonzero(cand), marks[t], fresh[t], points, table, size)
            if chosen is not None:
                plan[t] = chosen
        if not plan:
            break
        if rounds == max_rounds:
            raise WarpMeshError(f"refine_local did not finish in max_rounds={max_rounds} rounds "
                                f"({n_bisect} bisections so far); raise 'max_rounds' or check 'max_length'")
        rounds += 1

        # 2. the midpoints: look them up, or create them (once each)
        chosen = np.concatenate([p[2] for p in plan.values()])
        hit, _ = _lookup(table, chosen)
        new = np.unique(chosen[~hit])
        lo, hi = new >> _SHIFT, new & ((1 << _SHIFT) - 1)
        ids = n + np.arange(len(new), dtype=INDEX_DTYPE)
        xm = 0.5 * (points[lo] + points[hi])
        if target is not None and len(new):
            on = np.ones(len(new), bool) if surface else _lookup(bkeys, new)[0]
            if on.any():
                x = xm[on] if dim == 3 else np.column_stack([xm[on], np.zeros(on.sum())])
                cap = np.sqrt(_edge_lengths2(points, lo[on], hi[on]))
                xm[on] = project_nodes(target, x, cap)[:, :dim]
                n_projected += int(on.sum())
                if not surface:  # the halves of a boundary edge are on the boundary
                    halves = np.concatenate([_keys(lo[on], ids[on]), _keys(hi[on], ids[on])])
                    bkeys = np.union1d(bkeys, halves)
        table, mids = _insert(table, mids, new, ids)
        n += len(new)
        if n >= _MAX_POINTS:
            raise WarpMeshError(f"refine_local would create {n} points, more than {_MAX_POINTS - 1}")
        points = np.concatenate([points, xm])
        parents.append((lo, hi))

        # 3. split: the first child takes the parent's row, the second is appended
        for t, (rows, best, key) in plan.items():
            c = cells[t]
            m_ids = mids[_lookup(table, key)[1]]
            i_col, j_col = _EDGES[t][best, 0], _EDGES[t][best, 1]
            ar = np.arange(len(rows))
            par = c[rows]
            c1, c2 = par.copy(), par.copy()
            c1[ar, j_col] = m_ids
            c2[ar, i_col] = m_ids
            if t in bflags:
                add, bflags[t] = _new_boundary_edges(t, bflags[t], rows, par, best, m_ids)
                bkeys = np.union1d(bkeys, add)
            c[rows] = c1
            cells[t] = np.concatenate([c, c2])
            src[t] = np.concatenate([src[t], src[t][rows]])
            fresh[t] = np.zeros(len(cells[t]), bool)
            fresh[t][rows] = True
            fresh[t][len(c):] = True
            changed[t] = np.concatenate([changed[t], np.ones(len(rows), bool)])
            changed[t][rows] = True
            n_bisect += len(rows)
        for t in cells:
            if t not in plan:
                fresh[t][:] = False
            marks[t] = np.zeros(len(cells[t]), bool)  # a mark asks for one bisection
        touched = np.zeros(n, bool)
        touched[lo] = True  # every element holding a new split edge holds its end lo

    out_cells = {t: (cells[t] if t in cells else np.asarray(c)) for t, c in mesh.cells.items()}
    qt = _quality_type(mesh.cells)
    q0 = None if qt is None else (triangle_quality if qt == "triangle" else tetra_quality)(
        mesh.points, mesh.cells[qt])
    keep = lambda t, a: a[src[t]] if t in src else a  # noqa: E731
    cell_refs = (None if mesh.cell_refs is None
                 else {t: keep(t, np.asarray(r)) for t, r in mesh.cell_refs.items()})
    cell_data = {k: {t: keep(t, np.asarray(a)) for t, a in v.items()} for k, v in mesh.cell_data.items()}
    point_refs = None if mesh.point_refs is None else _extend(np.asarray(mesh.point_refs), parents)
    point_data = {k: _extend(np.asarray(v), parents) for k, v in mesh.point_data.items()}
    info = {**mesh.info,
            "q_worst_before": None if qt is None else float(q0.max(initial=-np.inf)),
            "q_worst_after": _worst_q(points, out_cells[qt] if qt else None, qt,
                                      changed.get(qt), q0),
            "n_bisections": n_bisect, "rounds": rounds, "n_split_edges": len(table),
            "n_projected": n_projected, "refine_time": time.perf_counter() - t0}
    top = max(types, key=SIMPLEX_TYPES.get)
    if target is not None and not surface:  # projected midpoints may fold thin elements
        moved = cells[top][changed[top]]
        info["n_inverted"] = int(np.count_nonzero(cell_measures(points, moved, top) <= 0))
    return type(mesh)(points, out_cells, point_data=point_data, cell_data=cell_data,
                point_refs=point_refs, cell_refs=cell_refs, info=info)
