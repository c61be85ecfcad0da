"""Merging two meshes that share an interface [FG §17.2, Figs. 17.7-17.9, Remarks 17.7-17.10].

Three sub-problems, as in [FG §17.2]:

1. *Common vertices* (:func:`match_points`, in :mod:`warpmesh.modify.merge_hash`): hashing on a virtual grid, vectorised (sorted
   keys + ``searchsorted``), restricted to the intersection of the two bounding boxes
   (Remark 17.7), with the book's shifted keys (Fig. 17.8) so that pairs straddling a
   grid-cell border are found, and symmetric pairing (Remark 17.9): a pair is kept only
   when each point is the other's nearest. Optional physical attributes (refs): only
   points with equal refs match ("more sophisticated merging", cracks).
2. *Vertex numbering*: the vertices of the first mesh keep their numbers, the interface
   vertices of the second take their partner's number, its other vertices follow from
   ``n1`` in their order (Remark 17.10: not optimal; renumber afterwards, §17.4).
3. *Element numbering*: the first mesh's cells, then the second's, per cell type.

The common edges and faces give a check of the Euler formula χ(T) = χ(T1) + χ(T2) −
χ(T1 ∩ T2) (:mod:`warpmesh.modify.merge_check`).

Examples
--------
>>> import numpy as np
>>> from warpmesh.mesh import Mesh
>>> from warpmesh.modify.merge import merge
>>> left = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
>>> right = Mesh([[1, 0], [2, 0], [2, 1], [1, 1 + 1e-12]], {"quad": [[0, 1, 2, 3]]})
>>> m = merge(left, right)
>>> m.n_points, m.cells["quad"].tolist(), m.info["euler_ok"]
(6, [[0, 1, 2, 3], [1, 4, 5, 2]], True)
"""

from __future__ import annotations

import warnings
from typing import Literal

import numpy as np

from warpmesh._conventions import INDEX_DTYPE
from warpmesh.cells.types import block_refs, require_mesh
from warpmesh.errors import MergeError
from warpmesh.modify.merge_check import _euler_check, _euler_check_dims, _sort_rows
from warpmesh.modify.merge_hash import _check_tolerance, _match, default_tolerance, match_points  # noqa: F401

__all__ = ["match_points", "merge", "default_tolerance", "DUPLICATES"]

#: what :func:`merge` does with cells present in both meshes (same type, same vertex set)
DUPLICATES = ("merge", "keep", "drop")
#: how :func:`merge` checks the Euler formula
CHECKS = ("interface", "full", False)


# ----------------------------------------------------------------------------- merge
def _duplicate_masks(ca: np.ndarray, cb: np.ndarray, interface_a: np.ndarray, n1: int):
    """Masks of the cells of ``ca`` and of ``cb`` (merged numbering) that have the same
    vertex set as a cell of the other block."""
    da, db = np.zeros(len(ca), dtype=bool), np.zeros(len(cb), dtype=bool)
    sa = np.flatnonzero(interface_a[ca].all(axis=1))
    sb = np.flatnonzero((cb < n1).all(axis=1))
    if len(sa) == 0 or len(sb) == 0:
        return da, db
    rows = _sort_rows(np.concatenate([ca[sa], cb[sb]]))
    _, inv = np.unique(rows, axis=0, return_inverse=True)
    inv = inv.ravel()
    ia, ib = inv[: len(sa)], inv[len(sa):]
    da[sa] = np.isin(ia, ib)
    db[sb] = np.isin(ib, ia)
    return da, db


def _merge(a, b, tolerance=None, *, refs: bool = False, duplicates: str = "merge",
           check: bool | str = "interface", stacklevel: int = 3, overlaps: bool = True):
    """(merged Mesh, bmap (n2,) int64: new index of each vertex of b); ``overlaps=False``
    leaves the crossing check of ``check="full"`` to the caller (periodic checks its result)."""
    require_mesh(a, "a")
    require_mesh(b, "b")
    if a.dim != b.dim:
        raise ValueError(f"expected meshes of the same dimension, got {a.dim}D 'a' and {b.dim}D 'b'")
    if duplicates not in DUPLICATES:
        raise ValueError(f"expected 'duplicates' among {list(DUPLICATES)}, got {duplicates!r}")
    if not isinstance(refs, (bool, np.bool_)):
        raise TypeError(f"expected a bool for 'refs', got {type(refs).__name__}")
    if check is True:
        check = "interface"
    if check not in CHECKS:
        raise ValueError(f"expected 'check' among {list(CHECKS)}, got {check!r}")
    tol = default_tolerance(a.points, b.points) if tolerance is None else _check_tolerance(tolerance)
    if b.n_points == 0:  # an empty mesh is merge's identity: nothing to match, nothing to add
        return a, np.zeros(0, dtype=INDEX_DTYPE)
    if a.n_points == 0:
        return b, np.arange(b.n_points, dtype=INDEX_DTYPE)
    top, blocks_a, blocks_b = _euler_check_dims(a, b)
    n1, n2 = a.n_points, b.n_points
    ra = rb = None
    if refs:
        ra = a.point_refs if a.point_refs is not None else np.zeros(n1, dtype=INDEX_DTYPE)
        rb = b.point_refs if b.point_refs is not None else np.zeros(n2, dtype=INDEX_DTYPE)
    pairs, stats = _match(a.points, b.points, tol, ra, rb)

    # numbering [FG §17.2, 'Numbering issues']
    bmap = np.full(n2, -1, dtype=INDEX_DTYPE)
    bmap[pairs[:, 1]] = pairs[:, 0]
    free = bmap < 0
    bmap[free] = n1 + np.arange(int(free.sum()), dtype=INDEX_DTYPE)
    interface_a = np.zeros(n1, dtype=bool)
    interface_a[pairs[:, 0]] = True
    n_new = n1 + int(free.sum())
    points = np.concatenate([a.points, b.points[free]])

    # cells: a's blocks, then b's, per type; duplicates
    types = list(a.cells) + [t for t in b.cells if t not in a.cells]
    keep_a, keep_b, cells = {}, {}, {}
    n_dup = 0
    for t in types:
        ca = a.cells.get(t)
        cb = bmap[b.cells[t]] if t in b.cells else None
        ka = np.ones(0 if ca is None else len(ca), dtype=bool)
        kb = np.ones(0 if cb is None else len(cb), dtype=bool)
        if ca is not None and cb is not None and duplicates != "keep":
            da, db = _duplicate_masks(ca, cb, interface_a, n1)
            n_dup += int(db.sum())
            kb &= ~db
            if duplicates == "drop":
                ka &= ~da
        keep_a[t], keep_b[t] = ka, kb
        parts = ([ca[ka]] if ca is not None else []) + ([cb[kb]] if cb is not None else [])
        cells[t] = np.concatenate(parts)

    def per_type(get_a, get_b):
        out = {}
        for t in types:
            parts = []
            if t in a.cells:
                parts.append(get_a(t)[keep_a[t]])
            if t in b.cells:
                parts.append(get_b(t)[keep_b[t]])
            out[t] = np.concatenate(parts)
        return out

    cell_refs = None
    if a.cell_refs is not None or b.cell_refs is not None:  # blocks without refs: 0
        cell_refs = per_type(lambda t: block_refs(a, t), lambda t: block_refs(b, t))
    point_refs = None
    if a.point_refs is not None or b.point_refs is not None:
        pa = a.point_refs if a.point_refs is not None else np.zeros(n1, dtype=INDEX_DTYPE)
        pb = b.point_refs if b.point_refs is not None else np.zeros(n2, dtype=INDEX_DTYPE)
        point_refs = np.concatenate([pa, pb[free]])

    dropped = []
    cell_data = {}
    for key in dict.fromkeys(list(a.cell_data) + list(b.cell_data)):
        if key not in a.cell_data or key not in b.cell_data:
            dropped.append(f"cell_data[{key!r}]")
            continue
        try:
            cell_data[key] = per_type(lambda t: a.cell_data[key][t], lambda t: b.cell_data[key][t])
        except ValueError:  # trailing shapes differ
            dropped.append(f"cell_data[{key!r}] (shapes differ)")
    point_data = {}
    for key in dict.fromkeys(list(a.point_data) + list(b.point_data)):
        if key not in a.point_data or key not in b.point_data:
            dropped.append(f"point_data[{key!r}]")
            continue
        va, vb = a.point_data[key], b.point_data[key]
        if va.shape[1:] != vb.shape[1:]:
            dropped.append(f"point_data[{key!r}] (shapes differ)")
            continue
        point_data[key] = np.concatenate([va, vb[free]])
    if dropped:
        warnings.warn(f"merge: {', '.join(dropped)} not in both meshes (or of different shapes); dropped",
                      UserWarning, stacklevel=stacklevel)

    info = {"merge_tolerance": tol, "n_points_a": n1, "n_points_b": n2,
            "n_common_points": len(pairs), "n_duplicates": n_dup, "duplicates": duplicates,
            "n_hashed_a": stats["n_box_a"], "n_hashed_b": stats["n_box_b"],
            "n_candidates": stats["n_candidates"]}
    if check:
        if check == "interface":  # the cells around the interface: the rest cancels out
            blocks_a = [(t, c[interface_a[c].any(axis=1)]) for t, c in blocks_a]
            blocks_b = [(t, c[(bmap[c] < n1).any(axis=1)]) for t, c in blocks_b]
        euler = _euler_check(top, blocks_a, blocks_b, bmap, interface_a, n_new, points)
        euler["n_common_points"] = len(pairs)
        euler["euler_check"] = check
        if check == "interface":  # χ of the interface's neighbourhoods, not of the meshes
            for key in ("euler", "euler_a", "euler_b"):
                euler[key.replace("euler", "euler_star")] = euler.pop(key)
        info.update(euler)
    if check and not euler["euler_ok"]:
        star = "_star" if check == "interface" else ""
        raise MergeError(
            f"Euler check failed: χ(T{star}) = {euler['euler' + star]} but χ(T1) + χ(T2) − χ(T1∩T2) = "
            f"{euler['euler' + star + '_a']} + {euler['euler' + star + '_b']} − {euler['euler_interface']} "
            f"(interface seen from 'a'; {euler['euler_interface_b']} seen from 'b'{'; T* = the cells around the interface' if star else ''}). The two interfaces do not "
            f"match: probably they are meshed differently (other vertices, or quads split "
            f"along other diagonals, [FG Remark 17.16]), or 'tolerance' = {tol:g} is too large "
            f"and merged vertices that are not on the interface; pass check=False to merge anyway"
        )
    mesh = type(a)(points, cells, point_data=point_data, cell_data=cell_data,
                point_refs=point_refs, cell_refs=cell_refs, info=info)
    if check == "full" and overlaps and _checkable(mesh):
        # the Euler formula counts, it does not place: two triangulations of one square merge
        # into a valid complex whose triangles overlap
        from warpmesh.cells.intersections import check as crossing_pairs

        crossing = crossing_pairs(mesh)
        if len(crossing):
            raise MergeError(f"the merged cells overlap: {len(crossing)} pair(s), e.g. cells "
                             f"{crossing[0].tolist()} (the meshes cover a common region, not only an "
                             "interface); pass check='interface' or False to merge anyway")
    return mesh, bmap


def _checkable(mesh) -> bool:
    """Whether :func:`warpmesh.cells.intersections.check` decides all of this mesh: tetrahedra
    in 3D and no other solid cells; else triangles and no quads or solids; else a planar
    polyline alone. (It checks one block: a mixed mesh would be decided in part.)"""
    types = set(mesh.cells)
    solids = {"tetra", "hexahedron", "wedge", "pyramid"}
    if mesh.dim == 3 and "tetra" in types:
        return not (types & (solids - {"tetra"}))
    if "triangle" in types:
        return not (types & (solids | {"quad"}))
    return mesh.dim == 2 and types == {"line"}


def merge(a, b, tolerance: float | None = None, *, refs: bool = False,
          duplicates: Literal["merge", "keep", "drop"] = "merge",
          check: Literal["interface", "full", False] = "interface"):
    """Merge two meshes that share an interface [FG §17.2].

    Parameters
    ----------
    a, b : Mesh
        Same dimension; any cell types. Their interfaces are assumed meshed identically
        (up to round-off).
    tolerance : float, optional
        Absolute distance under which a vertex of ``b`` and one of ``a`` are the same
        (:func:`match_points`). Default ``RELATIVE_TOLERANCE`` (2.4e-7, twice float32's epsilon) ``× Δ``, Δ the largest side of the box
        enclosing both meshes.
    refs : bool
        Only vertices with equal ``point_refs`` merge (missing refs are 0): coincident
        vertices of different refs stay apart, e.g. a crack [FG §17.2, §17.5].
    duplicates : {"merge", "keep", "drop"}
        Cells of the same type present in both meshes with the same vertex set (e.g. the
        interface's boundary triangles or lines): keep one (the first mesh's), keep both,
        or remove both (the interface then disappears as a boundary).
    check : {"interface", "full", False}
        Count the common entities, check the Euler formula χ(T) = χ(T1) + χ(T2) −
        χ(T1 ∩ T2) and raise :class:`MergeError` when it fails. ``"interface"`` (default;
        ``True`` means it too) applies the formula to the cells that touch a common vertex
        (T*, T1*, T2*): everything else is counted alike on both sides and cancels out, so
        the check is the same at a fraction of the cost; ``info`` then has ``euler_star``,
        ``euler_star_a``, ``euler_star_b``. ``"full"`` counts every entity of both meshes
        (``euler``, ``euler_a``, ``euler_b``: the meshes' own characteristics) and also checks
        that no two cells of the result overlap (:func:`warpmesh.cells.intersections.check`,
        for tetrahedra, triangles or a planar polyline: the formula counts, it does not
        place, so two triangulations of one square pass it). ``False``
        skips both (no edge or face is built; the ``euler*`` and ``n_common_edges/faces``
        keys are then absent from ``info``).

    Returns
    -------
    Mesh
        Points: ``a``'s (numbers kept), then ``b``'s non-interface points in order. Cells:
        per type, ``a``'s block then ``b``'s (types only in ``b`` after ``a``'s). Refs,
        common ``point_data`` (interface points take ``a``'s values) and common
        ``cell_data`` carried; keys in only one mesh are dropped with a warning.
        ``info``: ``merge_tolerance``, ``n_common_points`` (pairs merged),
        ``n_common_vertices``, ``n_common_edges``, ``n_common_faces`` (entities of ``a``'s
        top-dimension cells whose vertices are all common and on the interface), ``euler``
        (χ = V − E + F (− T) of the top-dimension cells of the result, duplicates counted
        once; ``check="full"``), ``euler_a``, ``euler_b`` (or the ``euler_star*`` values),
        ``euler_check``, ``euler_interface`` (of the common entities, from ``a``),
        ``euler_interface_b`` (from ``b``), ``euler_ok``, ``n_duplicates``,
        ``n_hashed_a``/``n_hashed_b`` (points in the box of Remark 17.7), ``n_candidates``.

    Raises
    ------
    TypeError
        ``a`` or ``b`` not a Mesh, non-real tolerance, non-bool ``refs``.
    ValueError
        Different dimensions, tolerance <= 0, unknown ``duplicates``, top-dimension cells
        of different dimensions.
    MergeError
        The Euler formula fails (interfaces meshed differently, or tolerance too large), or
        with ``check="full"`` cells of the result overlap.

    Examples
    --------
    >>> from warpmesh.mesh import Mesh
    >>> a = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]], "line": [[1, 2]]})
    >>> b = Mesh([[1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2]], "line": [[2, 0]]})
    >>> m = merge(a, b)
    >>> m.cells["triangle"].tolist(), m.cells["line"].tolist(), m.info["euler_ok"]
    ([[0, 1, 2], [1, 3, 2]], [[1, 2]], True)
    >>> merge(a, b, check="full").info["euler"]  # the merged square: V - E + F = 4 - 5 + 2
    1
    >>> len(merge(a, b, duplicates="drop").cells["line"])
    0
    """
    return _merge(a, b, tolerance, refs=refs, duplicates=duplicates, check=check)[0]
