"""The Euler check of a merge [FG §17.2, "Finding the common entities"]: the entities of
the top-dimension cells of each mesh, the interface complex seen from either side, and
the formula chi(T) = chi(T1) + chi(T2) - chi(T1 ∩ T2).

A facet with all its vertices common belongs to the interface when the other mesh has it
too, or when it lies on the other mesh's boundary (then the interfaces are meshed
differently and the formula fails); a facet that merely joins interface vertices (a chord
across a concave corner) does not.

Examples
--------
>>> import numpy as np
>>> from warpmesh.modify.merge_check import _euler
>>> _euler([4, 5, 2])  # V - E + F of two triangles sharing an edge
1
"""

from __future__ import annotations

import numpy as np

from warpmesh._util.arrays import sorted_unique
from warpmesh._conventions import INDEX_DTYPE
from warpmesh.cells.types import CELL_TYPES
from warpmesh.cells.reference import base_type, reference_cell


# ----------------------------------------------------------------------------- cell complexes
def _row_keys(rows: np.ndarray, n: int) -> np.ndarray:
    """(m,) int64 keys, equal iff the rows of the (m, k) int array (entries in [-1, n)) are
    equal: the rows packed base n + 1, compressed to dense ids when the key would overflow."""
    r = rows + 1
    base = n + 1
    key, span = r[:, 0].astype(np.int64), base
    for c in range(1, r.shape[1]):
        if span * base >= 2**62:  # compress to dense ids before the key overflows
            order = np.argsort(key)
            sk = key[order]
            new = np.ones(len(sk), dtype=np.int64)
            new[1:] = sk[1:] != sk[:-1]
            key = np.empty_like(key)
            key[order] = np.cumsum(new) - 1
            span = int(key.max(initial=0)) + 1
        key = key * base + r[:, c]
        span *= base
    return key


def _top_blocks(mesh) -> tuple[int, list[tuple[str, np.ndarray]]]:
    """(top topological dimension, [(P1 type, (m, nv) vertex columns)]) of the mesh."""
    tdims = {t: CELL_TYPES[t][1] for t in mesh.cells if len(mesh.cells[t])}
    top = max(tdims.values(), default=-1)
    out = []
    for t, c in mesh.cells.items():
        if tdims.get(t) == top:
            p1 = base_type(t)
            out.append((p1, c[:, : len(reference_cell(p1).vertices)]))
    return top, out


#: sorting networks (pairs of columns to compare-exchange) for short rows
_NETWORKS = {2: [(0, 1)], 3: [(0, 1), (1, 2), (0, 1)], 4: [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)]}


def _member(keys: np.ndarray, sorted_keys: np.ndarray) -> np.ndarray:
    """(m,) bool: keys found in a sorted array (``np.isin`` re-sorts, and numpy's hash
    unique is slow on millions of int64)."""
    if not len(sorted_keys):
        return np.zeros(len(keys), dtype=bool)
    i = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return sorted_keys[i] == keys


def _sort_rows(rows: np.ndarray) -> np.ndarray:
    """Each row sorted: min/max sorting networks for up to 4 columns (np.sort(axis=1) on
    short rows is several times slower), np.sort beyond."""
    if rows.shape[1] not in _NETWORKS:
        return np.sort(rows, axis=1)
    cols = [rows[:, k].copy() for k in range(rows.shape[1])]
    for i, j in _NETWORKS[rows.shape[1]]:
        lo = np.minimum(cols[i], cols[j])
        cols[j] = np.maximum(cols[i], cols[j])
        cols[i] = lo
    return np.stack(cols, axis=1)


def _all_flagged(flag: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(m,) bool: every entry of the row is flagged (column by column)."""
    out = flag[rows[:, 0]]
    for k in range(1, rows.shape[1]):
        out &= flag[rows[:, k]]
    return out


def _entities(top: int, blocks) -> list[np.ndarray]:
    """Sorted entity rows per dimension 1..top of the complex of the top cells, repeats
    included (padded with -1): edges (m, 2), faces (m, 4) in 3D, cells."""
    ents = []
    if top >= 2:
        e = np.concatenate([c[:, reference_cell(t).edges].reshape(-1, 2) for t, c in blocks])
        ents.append(_sort_rows(e))
    if top == 3:
        faces = []
        for t, c in blocks:
            for f in reference_cell(t).faces:
                rows = c[:, list(f)]
                faces.append(np.pad(rows, ((0, 0), (0, 4 - len(f))), constant_values=-1))
        ents.append(_sort_rows(np.concatenate(faces)))
    if top >= 1:
        width = max(c.shape[1] for _, c in blocks)
        cells = [np.pad(c, ((0, 0), (0, width - c.shape[1])), constant_values=-1) for _, c in blocks]
        ents.append(_sort_rows(np.concatenate(cells)))
    return ents


def _euler(counts) -> int:
    return int(sum((-1) ** k * c for k, c in enumerate(counts)))


def _euler_check_dims(a, b):
    top_a, blocks_a = _top_blocks(a)
    top_b, blocks_b = _top_blocks(b)
    if top_a != top_b:
        raise ValueError(
            f"expected two meshes whose highest-dimension cells have the same dimension, got "
            f"{top_a} and {top_b}; merge meshes of the same kind (e.g. two volume meshes)"
        )
    return top_a, blocks_a, blocks_b


def _facet_frame(points: np.ndarray, rows: np.ndarray):
    """(centroid (m, d), unit vector (m, d), diameter (m,)) of facets given as sorted vertex
    rows padded with -1: a segment's direction, a triangle's or quad's normal (a quad's
    plane from its first three vertices)."""
    rows = _padding_last(rows)
    valid = rows >= 0
    x = points[np.where(valid, rows, rows[:, :1])]
    centroid = (x * valid[..., None]).sum(axis=1) / valid.sum(axis=1, keepdims=True)
    if rows.shape[1] == 2:  # segments (in 2D or on a surface in 3D): their direction
        normal = x[:, 1] - x[:, 0]
    else:
        normal = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    diameter = np.linalg.norm(x - centroid[:, None], axis=2).max(axis=1) * 2
    return centroid, normal, diameter


def _padding_last(rows: np.ndarray) -> np.ndarray:
    """Rows with their -1 padding (sorted first by :func:`_sort_rows`) moved to the end."""
    big = np.iinfo(rows.dtype).max
    r = np.sort(np.where(rows < 0, big, rows), axis=1)
    return np.where(r == big, -1, r)


def _in_triangle(p, a, b, c, tol: float = 0.01) -> np.ndarray:
    """(m,) bool: p (m, d) projects into triangle abc (each (m, d)), barycentric >= -tol."""
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = (np.einsum("ij,ij->i", u, w) for u, w in ((v0, v0), (v0, v1), (v1, v1)))
    d20, d21 = np.einsum("ij,ij->i", v2, v0), np.einsum("ij,ij->i", v2, v1)
    den = np.maximum(d00 * d11 - d01 * d01, 1e-300)
    v, w = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
    return (v >= -tol) & (w >= -tol) & (v + w <= 1 + tol)


def _covers(points: np.ndarray, rows: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(m,) bool: p projects into the facet (sorted vertex rows padded with -1): within a
    segment, a triangle, or the convex hull of a quad (the union of the four triangles on
    its vertices, whatever their order)."""
    rows = _padding_last(rows)
    x = points[np.where(rows >= 0, rows, rows[:, :1])]
    if rows.shape[1] == 2:
        t = x[:, 1] - x[:, 0]
        u = np.einsum("ij,ij->i", p - x[:, 0], t) / np.maximum(np.einsum("ij,ij->i", t, t), 1e-300)
        return (u >= -0.01) & (u <= 1.01)
    out = _in_triangle(p, x[:, 0], x[:, 1], x[:, 2])
    quad = rows[:, 3] >= 0
    for i, j, k in ((0, 1, 3), (0, 2, 3), (1, 2, 3)):
        out |= quad & _in_triangle(p, x[:, i], x[:, j], x[:, k])
    return out


def _overlapping(points: np.ndarray, facets: np.ndarray, others: np.ndarray) -> np.ndarray:
    """(m,) bool: the facet lies on one of ``others`` that shares a vertex with it: nearly
    parallel, its centroid within a tenth of its size of that facet's line or plane and
    inside it (so a facet that merely continues another one on the same line or plane
    does not count)."""
    if not len(facets) or not len(others):
        return np.zeros(len(facets), dtype=bool)
    ov = others.ravel()
    order = np.argsort(ov, kind="stable")
    sv = ov[order]
    f_idx, g_idx = [], []
    for k in range(facets.shape[1]):  # candidates through each vertex of the facet
        v = facets[:, k]
        lo, hi = np.searchsorted(sv, v, "left"), np.searchsorted(sv, v, "right")
        hi = np.where(v >= 0, hi, lo)
        count = hi - lo
        f = np.repeat(np.arange(len(facets)), count)
        start = np.repeat(lo - np.cumsum(count) + count, count) + np.arange(count.sum())
        f_idx.append(f)
        g_idx.append(order[start] // others.shape[1])
    f, g = np.concatenate(f_idx), np.concatenate(g_idx)
    cf, nf, df = _facet_frame(points, facets)
    cg, ng, _ = _facet_frame(points, others)
    parallel = np.abs(np.einsum("ij,ij->i", nf[f], ng[g])) > 0.95
    gap = cf[f] - cg[g]
    along = np.einsum("ij,ij->i", gap, ng[g])
    if facets.shape[1] == 2:  # distance to the other segment's line
        off = np.linalg.norm(gap - along[:, None] * ng[g], axis=1)
    else:  # distance to the other facet's plane
        off = np.abs(along)
    near = (off <= 0.1 * df[f]) & _covers(points, others[g], cf[f])
    out = np.zeros(len(facets), dtype=bool)
    out[f[parallel & near]] = True
    return out


def _interface(points, ents, flag, other_keys, other_boundary, n_new) -> list[int]:
    """Counts per dimension of one side's interface complex ([FG §17.2] "Finding the common
    entities"): its facets whose vertices are all common and which are facets of the other
    mesh too, or lie on the other mesh's boundary (then the two interfaces are meshed
    differently, which the Euler check reveals); their edges; and the lower entities with
    all vertices common that the other mesh has as well. A boundary facet that merely joins
    interface vertices (a chord across a concave corner) is not part of the interface."""
    counts = []
    facet_rows = ents[-2] if len(ents) >= 2 else None
    kept_pairs = np.zeros(0, dtype=np.int64)
    if facet_rows is not None:
        sel = facet_rows[_all_flagged(flag, facet_rows)]
        keys = _row_keys(sel, n_new)
        keys, first = np.unique(keys, return_index=True)
        sel = sel[first]
        shared = _member(keys, other_keys[-2])
        shared[~shared] = _overlapping(points, sel[~shared], other_boundary)
        facet_rows = sel[shared]
        cols = [facet_rows[:, k] for k in range(facet_rows.shape[1])]
        pairs = [np.stack([cols[i], cols[j]], axis=1) for i in range(len(cols)) for j in range(i + 1, len(cols))]
        pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=INDEX_DTYPE)
        pairs = pairs[(pairs >= 0).all(axis=1)]
        kept_pairs = sorted_unique(_row_keys(_sort_rows(pairs), n_new))
    for k, rows in enumerate(ents[:-2] if facet_rows is not None else ents[:-1]):
        sel = rows[_all_flagged(flag, rows)]
        keys = sorted_unique(_row_keys(sel, n_new))
        keep = _member(keys, other_keys[k])
        if k == 0 and facet_rows is not None and rows.shape[1] == 2:
            keep |= _member(keys, kept_pairs)
        counts.append(int(keep.sum()))
    if facet_rows is not None:
        counts.append(len(facet_rows))
    return counts


def _boundary_facets(ents, n_new, flag) -> np.ndarray:
    """Facet rows (the next-to-last entity dimension) with a common vertex (``flag``) that
    one top cell only uses. Every copy of such a facet has that vertex, so counting among
    these rows alone is exact, and cheap."""
    rows = ents[-2]
    rows = rows[(flag[rows] & (rows >= 0)).any(axis=1)]
    keys = _row_keys(rows, n_new)
    order = np.argsort(keys, kind="stable")
    k = keys[order]
    start = np.ones(len(k), dtype=bool)
    start[1:] = k[1:] != k[:-1]
    first = np.flatnonzero(start)
    counts = np.diff(np.append(first, len(k)))
    return rows[order[first[counts == 1]]]


def _euler_check(top_a, blocks_a, blocks_b, bmap, common_a, n_new, points) -> dict:
    """The counts of [FG §17.2] 'Finding the common entities' and the Euler formula.

    Per dimension k: the distinct k-entities of each mesh's top cells (a's numbering is
    the merged one; b's is mapped) and those in both, so that |T_k| = |T1_k| + |T2_k| -
    |both_k|; and the interface complex seen from each side (:func:`_interface`). The
    check: chi(T) = chi(T1) + chi(T2) - chi(interface) with the interface counted from
    either side, which fails when the two sides mesh their common boundary differently."""
    if top_a < 0:  # no cells: nothing to count
        keys = ("n_common_vertices", "n_common_edges", "n_common_faces", "euler", "euler_a",
                "euler_b", "euler_interface", "euler_interface_b")
        return {"n_common_points": None, **dict.fromkeys(keys, 0), "n_common_cells": None,
                "euler_ok": True}
    n1 = len(common_a)
    flag_a = np.append(common_a, True)  # index -1 (padding) counts as common
    blocks_b = [(t, bmap[c]) for t, c in blocks_b]
    flag_b = np.append(np.arange(n_new) < n1, True)
    used_a, used_b = np.zeros(n_new, dtype=bool), np.zeros(n_new, dtype=bool)
    for used, blocks in ((used_a, blocks_a), (used_b, blocks_b)):
        for _, c in blocks:
            used[c.ravel()] = True
    ta, tb = [int(used_a.sum())], [int(used_b.sum())]  # vertices
    n_common = int((used_a & used_b)[:n1].sum())
    both = [n_common]
    ents_a, ents_b = _entities(top_a, blocks_a), _entities(top_a, blocks_b)
    keys_a, keys_b = [], []
    for ra, rb in zip(ents_a, ents_b):
        ua, ub = sorted_unique(_row_keys(ra, n_new)), sorted_unique(_row_keys(rb, n_new))
        keys_a.append(ua)
        keys_b.append(ub)
        ta.append(len(ua))
        tb.append(len(ub))
        both.append(len(np.intersect1d(ua, ub, assume_unique=True)))
    if top_a >= 2:
        bd_a, bd_b = _boundary_facets(ents_a, n_new, flag_a), _boundary_facets(ents_b, n_new, flag_b)
        ca = [n_common] + _interface(points, ents_a, flag_a, keys_b, bd_b, n_new)
        cb = [n_common] + _interface(points, ents_b, flag_b, keys_a, bd_a, n_new)
    else:  # curves: the interface is the common vertices and the common segments
        ca = cb = both
    ca += [0] * (len(ta) - len(ca))
    cb += [0] * (len(ta) - len(cb))
    if top_a >= 2:  # top cells in both meshes belong to the interface complex too (with their facets)
        ca[-1] = cb[-1] = both[-1]
    chi_a, chi_b, chi_i, chi_ib = _euler(ta), _euler(tb), _euler(ca), _euler(cb)
    chi = _euler([x + y - z for x, y, z in zip(ta, tb, both)])
    return {
        "n_common_points": None,  # set by the caller (all pairs)
        "n_common_vertices": ca[0],
        "n_common_edges": ca[1] if top_a >= 1 else 0,
        "n_common_faces": ca[2] if top_a >= 2 else 0,
        "n_common_cells": ca[3] if top_a == 3 else None,
        "euler": chi,
        "euler_a": chi_a,
        "euler_b": chi_b,
        "euler_interface": chi_i,
        "euler_interface_b": chi_ib,
        "euler_ok": bool(chi == chi_a + chi_b - chi_i and chi == chi_a + chi_b - chi_ib),
    }
