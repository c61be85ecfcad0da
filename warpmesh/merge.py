"""Merging two meshes that share an interface (seed §17.2, Figs. 17.7-17.9, Remarks 17.7-17.10).

Three sub-problems, as in the seed:

1. *Common vertices* (:func:`match_points`): hashing on a virtual grid, vectorised (sorted
   keys + ``searchsorted``), restricted to the intersection of the two bounding boxes
   (Remark 17.7), with the seed's shifted keys (Fig. 17.8) so that pairs straddling a
   grid-cell border are found, and symmetric pairing (Remark 17.9): a pair is kept only
   when each point is the other's nearest. Optional physical attributes (refs): only
   points with equal refs match ("more sophisticated merging", cracks).
2. *Vertex numbering*: the vertices of the first mesh keep their numbers, the interface
   vertices of the second take their partner's number, its other vertices follow from
   ``n1`` in their order (Remark 17.10: not optimal; renumber afterwards, §17.4).
3. *Element numbering*: the first mesh's cells, then the second's, per cell type.

The common edges and faces (those of the top-dimension cells whose vertices are all
common) give a check of the Euler formula χ(T) = χ(T1) + χ(T2) − χ(T1 ∩ T2).

Examples
--------
>>> import numpy as np
>>> from warpmesh.mesh import Mesh
>>> from warpmesh.merge import merge
>>> left = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
>>> right = Mesh([[1, 0], [2, 0], [2, 1], [1, 1 + 1e-12]], {"quad": [[0, 1, 2, 3]]})
>>> m = merge(left, right)
>>> m.n_points, m.cells["quad"].tolist(), m.info["euler_ok"]
(6, [[0, 1, 2, 3], [1, 4, 5, 2]], True)
"""

from __future__ import annotations

import numbers
import warnings
from typing import Literal

import numpy as np

from ._conventions import INDEX_DTYPE, REAL_DTYPE
from .convert import CELL_TYPES, _block_refs
from .errors import WarpMeshError
from .reference_cells import base_type, reference_cell

__all__ = ["match_points", "merge", "default_tolerance", "MergeError", "DUPLICATES"]

#: the default tolerance, relative to the largest side of the box enclosing both meshes
#: (the seed's δ = 2εΔ: a resolution relative to the box)
RELATIVE_TOLERANCE = 1.0e-8
#: the virtual grid's step, in shifts s (s = tolerance + a few ulps): any value >= 2 finds
#: every pair; 4 makes floor((x - s)/h) == floor((x + s)/h) on half of the axes, so a point
#: looks up (3/2)^d keys on average instead of 2^d, with few points per cell
CELL_FACTOR = 4.0
#: what :func:`merge` does with cells present in both meshes (same type, same vertex set)
DUPLICATES = ("merge", "keep", "drop")


class MergeError(WarpMeshError):
    """The merged mesh fails the Euler check: the interfaces do not match."""


# ----------------------------------------------------------------------------- validation
def _check_points(x, name: str) -> np.ndarray:
    arr = np.asarray(x)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected a float array for {name!r}, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in (1, 2, 3):
        raise ValueError(f"expected {name!r} of shape (n, 1|2|3), got shape {arr.shape}")
    arr = arr.astype(REAL_DTYPE, copy=False)
    if not np.isfinite(arr).all():
        raise ValueError(f"expected finite coordinates in {name!r}, got NaN or inf")
    return arr


def _check_tolerance(tolerance) -> float:
    if isinstance(tolerance, bool) or not isinstance(tolerance, numbers.Real):
        raise TypeError(f"expected a real number for 'tolerance', got {type(tolerance).__name__}")
    tol = float(tolerance)
    if not np.isfinite(tol) or tol <= 0:
        raise ValueError(f"expected a finite 'tolerance' > 0, got {tolerance!r}")
    return tol


def _check_refs(refs, n: int, name: str) -> np.ndarray | None:
    if refs is None:
        return None
    arr = np.asarray(refs)
    if arr.dtype.kind not in "iub":
        raise TypeError(f"expected an integer array for {name!r}, got dtype {arr.dtype}")
    if arr.shape != (n,):
        raise ValueError(f"expected {name!r} of shape ({n},), got shape {arr.shape}")
    return arr.astype(INDEX_DTYPE, copy=False)


def default_tolerance(*point_sets) -> float:
    """``RELATIVE_TOLERANCE`` × Δ, Δ the largest side of the box enclosing all the points
    (the seed's δ = 2εΔ idea: a tolerance relative to the size of the problem).

    Examples
    --------
    >>> float(default_tolerance([[0.0, 0.0], [2.0, 1.0]], [[4.0, 0.0]]) / 1e-8)
    4.0
    """
    pts = np.concatenate([np.asarray(p, dtype=REAL_DTYPE).reshape(len(p), -1) for p in point_sets])
    if len(pts) == 0:
        return RELATIVE_TOLERANCE
    delta = float((pts.max(axis=0) - pts.min(axis=0)).max())
    if delta == 0.0:  # one point (or all coincident): relative to the coordinates' size
        delta = max(float(np.abs(pts).max()), 1.0)
    return RELATIVE_TOLERANCE * delta


# ----------------------------------------------------------------------------- hashing
def _grid(a: np.ndarray, b: np.ndarray, tol: float):
    """(lo, hi, origin, h, shift): the box of Remark 17.7 and the virtual grid.

    The shift ``s`` is ``tol`` enlarged by a relative 1e-7 and by 8 ulps of the largest
    coordinate, so that the float roundings of ``x ± s`` cannot lose a pair; ``h = CELL_FACTOR s``.
    """
    bounds = np.stack([a.min(axis=0), a.max(axis=0), b.min(axis=0), b.max(axis=0)])
    lo, hi = np.maximum(bounds[0], bounds[2]), np.minimum(bounds[1], bounds[3])
    scale = max(float(np.abs(bounds).max()), 1e-300)
    s = tol * (1 + 1e-7) + 8 * np.finfo(REAL_DTYPE).eps * scale
    h = CELL_FACTOR * s
    lo, hi = lo - s, hi + s
    origin = lo - 2 * h  # so that every lower cell index is >= 1
    return lo, hi, origin, h, s


def _inside(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    mask = (x[:, 0] >= lo[0]) & (x[:, 0] <= hi[0])
    for k in range(1, x.shape[1]):  # a loop over axes: reductions over a short axis are slow
        mask &= (x[:, k] >= lo[k]) & (x[:, k] <= hi[k])
    return np.flatnonzero(mask)


def _splitmix(x: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser on uint64 arrays (wrapping arithmetic)."""
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def _hasher(spans: np.ndarray):
    """A function (m, d) non-negative cell indices -> (m,) uint64 hashes, well mixed in the
    high bits: the cell's exact linear index through splitmix64 when the grid's cell count
    fits in 62 bits, else splitmix64 chained over the axes. Equal cells have equal hashes;
    a collision of different cells only adds candidates, which the distance test removes.
    Also returns the strides of the linear index (None when it does not fit)."""
    if float(np.prod(spans.astype(float))) < 2.0**62:
        strides = [int(x) for x in np.cumprod(np.concatenate([[1], spans[:-1]]))]

        def linear(cells):
            key = cells[:, 0] * strides[0]
            for k in range(1, cells.shape[1]):
                key = key + cells[:, k] * strides[k]
            return key

        return (lambda cells: _splitmix(linear(cells).astype(np.uint64))), linear, strides

    def chained(cells):
        key = np.zeros(len(cells), dtype=np.uint64)
        for k in range(cells.shape[1]):
            key = _splitmix(key ^ cells[:, k].astype(np.uint64))
        return key

    return chained, None, None


def _candidates(a, b, ia, ib, origin, h, s, spans):
    """Pairs (i, j) of a[ia] x b[ib] sharing a hash key: a's points are keyed by their
    cell, b's by the distinct cells among floor((x ± s)/h) per axis (at most 2^d)."""
    d = a.shape[1]
    hasher, linear, strides = _hasher(spans)
    ka = hasher(np.floor((a[ia] - origin) / h).astype(np.int64))
    xb = b[ib] - origin
    lower = np.floor((xb - s) / h).astype(np.int64)
    straddle = np.floor((xb + s) / h).astype(np.int64) != lower  # upper = lower + 1 (h >= 2 s)
    base = None if linear is None else linear(lower)
    qb, kb = [], []
    for o in range(2**d):  # a loop over the 2^d shifted keys, not over points
        bits = [(o >> k) & 1 for k in range(d)]
        mask = np.ones(len(lower), dtype=bool)
        for k in range(d):
            if bits[k]:
                mask &= straddle[:, k]
        idx = np.flatnonzero(mask)
        if base is not None:
            kb.append(_splitmix((base[idx] + sum(b_ * s_ for b_, s_ in zip(bits, strides))).astype(np.uint64)))
        else:
            kb.append(hasher(lower[idx] + np.array(bits, dtype=np.int64)))
        qb.append(idx)
    qb, kb = np.concatenate(qb), np.concatenate(kb)
    # One sort of plain integers (SIMD, ~10x faster than an argsort): the top bits of each
    # hash above its position in [ka, kb]; in each run of equal hashes a's points come first.
    na, total = len(ka), len(ka) + len(kb)
    pbits = max(int(total - 1).bit_length(), 1)
    packed = np.concatenate([ka, kb]) >> np.uint64(64 - (63 - pbits))
    packed = ((packed << np.uint64(pbits)) | np.arange(total, dtype=np.uint64)).view(np.int64)
    packed.sort()
    order = packed & ((1 << pbits) - 1)
    sk = packed >> pbits
    new = np.ones(total, dtype=bool)
    new[1:] = sk[1:] != sk[:-1]
    gid = np.cumsum(new) - 1
    gstart = np.flatnonzero(new)
    from_a = order < na
    n_a = np.bincount(gid[from_a], minlength=len(gstart))
    qpos = np.flatnonzero(~from_a)
    count = n_a[gid[qpos]]
    hit = count > 0  # most queried cells are empty: drop them before the gathers
    qpos, count = qpos[hit], count[hit]
    n_pairs = int(count.sum())
    rep = np.repeat(np.arange(len(qpos)), count)
    within = np.arange(n_pairs) - np.repeat(np.cumsum(count) - count, count)
    pos_a = gstart[gid[qpos]][rep] + within
    return ia[order[pos_a]], ib[qb[order[qpos[rep]] - na]]


def _mutual_nearest(i: np.ndarray, j: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Mask of the candidate pairs where j is i's nearest and i is j's nearest (ties to
    the smallest index), Remark 17.9."""
    keep = np.zeros(len(i), dtype=bool)
    if len(i) == 0:
        return keep
    if np.bincount(i).max() == 1 and np.bincount(j).max() == 1:
        return ~keep  # every point in one candidate pair: all are mutual
    best = []
    for own, other in ((i, j), (j, i)):
        o = np.lexsort((other, dist, own))  # by own, then distance, then the other index
        first = np.ones(len(o), dtype=bool)
        first[1:] = own[o][1:] != own[o][:-1]
        mask = np.zeros(len(i), dtype=bool)
        mask[o[first]] = True
        best.append(mask)
    return best[0] & best[1]


def _match(a, b, tol, a_refs=None, b_refs=None):
    """(pairs (k, 2), stats dict); inputs already validated."""
    empty = np.zeros((0, 2), dtype=INDEX_DTYPE)
    stats = {"n_box_a": 0, "n_box_b": 0, "n_candidates": 0}
    if len(a) == 0 or len(b) == 0:
        return empty, stats
    lo, hi, origin, h, s = _grid(a, b, tol)
    if (lo > hi).any():  # the (dilated) boxes do not meet
        return empty, stats
    ia, ib = _inside(a, lo, hi), _inside(b, lo, hi)
    stats.update(n_box_a=len(ia), n_box_b=len(ib))
    if len(ia) == 0 or len(ib) == 0:
        return empty, stats
    spans = (np.floor((hi - origin) / h).astype(np.int64) + 3)
    if len(ia) < len(ib):  # hash the larger set, query with the smaller one's shifted keys
        j, i = _candidates(b, a, ib, ia, origin, h, s, spans)
    else:
        i, j = _candidates(a, b, ia, ib, origin, h, s, spans)
    stats["n_candidates"] = len(i)
    diff = a[i] - b[j]
    dist = np.sqrt(np.einsum("ij,ij->i", diff, diff))
    ok = dist <= tol
    if a_refs is not None:
        ok &= a_refs[i] == b_refs[j]
    i, j, dist = i[ok], j[ok], dist[ok]
    keep = _mutual_nearest(i, j, dist)
    partner = np.full(len(a), -1, dtype=INDEX_DTYPE)  # one-to-one: sort by i with a scatter
    partner[i[keep]] = j[keep]
    first = np.flatnonzero(partner >= 0)
    return np.stack([first, partner[first]], axis=1).astype(INDEX_DTYPE), stats


def match_points(a, b, tolerance, *, a_refs=None, b_refs=None) -> np.ndarray:
    """One-to-one pairs of points of ``a`` and ``b`` closer than ``tolerance`` (seed §17.2).

    Hashing on a virtual grid of step ``h = 4 s`` (``s`` = ``tolerance`` plus a relative
    1e-7 and 8 ulps of the largest coordinate, Fig. 17.7), vectorised: the points of one
    set are keyed by their cell; each point of the other set gets the keys of the cells of
    its shifted points (Fig. 17.8); one sort of all the keys (hashes packed with their
    positions into plain integers) puts equal keys together, and the candidates are then
    tested by Euclidean distance. Only points inside the
    intersection of the two bounding boxes dilated by ``s`` take part (Remark 17.7):
    meshes touching along an interface hash only the interface region.

    **Why no pair is missed.** Per axis, let x be the querying point's coordinate and y
    the other's, with |y - x| <= tolerance < s. floor is monotone, so
    floor((x - s)/h) <= floor(y/h) <= floor((x + s)/h); the arguments of the two bounds
    differ by 2s/h <= 1 (any h >= 2s will do), so the bounds are equal or consecutive and
    y's cell is one of the two cells floor((x ± s)/h) of the seed's shifted points. A pair
    closer than ``tolerance`` in Euclidean norm is that close on every axis, so y's cell
    is one of the (at most 2^d, distinct) keys formed per axis from these two cells,
    whatever cell borders the pair straddles. The margin of ``s`` over ``tolerance``
    absorbs the rounding of ``x ± s`` (float rounding is monotone too). The final test
    keeps exactly the pairs at distance <= ``tolerance``; hashing only adds candidates.

    **Symmetric pairing** (Remark 17.9, Fig. 17.9): a candidate (i, j) is kept only when j
    is the nearest point of ``b`` to ``a[i]`` and i the nearest of ``a`` to ``b[j]`` (ties go
    to the smaller index), so the pairing is one-to-one.

    Parameters
    ----------
    a : (n1, d) float
    b : (n2, d) float
        d = 1, 2 or 3, the same for both.
    tolerance : float
        Absolute distance, > 0.
    a_refs : (n1,) int, optional
    b_refs : (n2,) int, optional
        Physical attributes: only points with equal refs match. Give both or neither.

    Returns
    -------
    (k, 2) int64
        Pairs (i in ``a``, j in ``b``), sorted by i; each i and each j at most once.

    Raises
    ------
    TypeError
        Non-numeric points, non-real tolerance, non-integer refs.
    ValueError
        Wrong shapes, different dimensions, NaN/inf coordinates, tolerance <= 0, only one
        of the refs.

    Examples
    --------
    >>> a = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]
    >>> b = [[1.0 + 1e-9, 0.0], [0.0, 1e-9], [5.0, 5.0]]
    >>> match_points(a, b, 1e-6).tolist()
    [[0, 1], [1, 0]]
    >>> match_points(a, b, 1e-6, a_refs=[1, 2, 3], b_refs=[2, 9, 0]).tolist()
    [[1, 0]]
    """
    a, b = _check_points(a, "a"), _check_points(b, "b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"expected 'a' and 'b' of the same dimension, got {a.shape[1]} and {b.shape[1]}")
    tol = _check_tolerance(tolerance)
    if (a_refs is None) != (b_refs is None):
        raise ValueError("expected both 'a_refs' and 'b_refs' or neither, got only one")
    ra, rb = _check_refs(a_refs, len(a), "a_refs"), _check_refs(b_refs, len(b), "b_refs")
    return _match(a, b, tol, ra, rb)[0]


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


def _sorted_unique(keys: np.ndarray) -> np.ndarray:
    """np.unique by sorting (numpy >= 2.3's hash-based np.unique is slower on large int64)."""
    k = np.sort(keys)
    keep = np.ones(len(k), dtype=bool)
    keep[1:] = k[1:] != k[:-1]
    return k[keep]


#: sorting networks (pairs of columns to compare-exchange) for short rows
_NETWORKS = {2: [(0, 1)], 3: [(0, 1), (1, 2), (0, 1)], 4: [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)]}


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
    """Counts per dimension of one side's interface complex (seed §17.2 "Finding the common
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
        shared = np.isin(keys, other_keys[-2])
        shared[~shared] = _overlapping(points, sel[~shared], other_boundary)
        facet_rows = sel[shared]
        cols = [facet_rows[:, k] for k in range(facet_rows.shape[1])]
        pairs = [np.stack([cols[i], cols[j]], axis=1) for i in range(len(cols)) for j in range(i + 1, len(cols))]
        pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), dtype=INDEX_DTYPE)
        pairs = pairs[(pairs >= 0).all(axis=1)]
        kept_pairs = _sorted_unique(_row_keys(_sort_rows(pairs), n_new))
    for k, rows in enumerate(ents[:-2] if facet_rows is not None else ents[:-1]):
        sel = rows[_all_flagged(flag, rows)]
        keys = _sorted_unique(_row_keys(sel, n_new))
        keep = np.isin(keys, other_keys[k])
        if k == 0 and facet_rows is not None and rows.shape[1] == 2:
            keep |= np.isin(keys, kept_pairs)
        counts.append(int(keep.sum()))
    if facet_rows is not None:
        counts.append(len(facet_rows))
    return counts


def _boundary_facets(ents, n_new) -> np.ndarray:
    """Facet rows (the next-to-last entity dimension) used by one top cell only."""
    rows = ents[-2]
    keys = _row_keys(rows, n_new)
    uniq, first, counts = np.unique(keys, return_index=True, return_counts=True)
    return rows[first[counts == 1]]


def _euler_check(top_a, blocks_a, blocks_b, bmap, common_a, n_new, points) -> dict:
    """The counts of seed §17.2 'Finding the common entities' and the Euler formula.

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
        ua, ub = _sorted_unique(_row_keys(ra, n_new)), _sorted_unique(_row_keys(rb, n_new))
        keys_a.append(ua)
        keys_b.append(ub)
        ta.append(len(ua))
        tb.append(len(ub))
        both.append(len(np.intersect1d(ua, ub, assume_unique=True)))
    if top_a >= 2:
        bd_a, bd_b = _boundary_facets(ents_a, n_new), _boundary_facets(ents_b, n_new)
        ca = [n_common] + _interface(points, ents_a, flag_a, keys_b, bd_b, n_new)
        cb = [n_common] + _interface(points, ents_b, flag_b, keys_a, bd_a, n_new)
    else:  # curves: the interface is the common vertices and the common segments
        ca = cb = both
    ca += [0] * (len(ta) - len(ca))
    cb += [0] * (len(ta) - len(cb))
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


def _check_mesh(m, name: str):
    from .mesh import Mesh

    if not isinstance(m, Mesh):
        raise TypeError(f"expected a warpmesh Mesh for {name!r}, got {type(m).__name__}; "
                        "convert with Mesh.from_meshio / from_pyvista / from_trimesh")


def _merge(a, b, tolerance=None, *, refs: bool = False, duplicates: str = "merge",
           check: bool = True, stacklevel: int = 3):
    """(merged Mesh, bmap (n2,) int64: new index of each vertex of b)."""
    from .mesh import Mesh

    _check_mesh(a, "a")
    _check_mesh(b, "b")
    if a.dim != b.dim:
        raise ValueError(f"expected meshes of the same dimension, got {a.dim}D 'a' and {b.dim}D 'b'")
    if duplicates not in DUPLICATES:
        raise ValueError(f"expected 'duplicates' among {list(DUPLICATES)}, got {duplicates!r}")
    if not isinstance(refs, (bool, np.bool_)):
        raise TypeError(f"expected a bool for 'refs', got {type(refs).__name__}")
    tol = default_tolerance(a.points, b.points) if tolerance is None else _check_tolerance(tolerance)
    top, blocks_a, blocks_b = _euler_check_dims(a, b)
    n1, n2 = a.n_points, b.n_points
    ra = rb = None
    if refs:
        ra = a.point_refs if a.point_refs is not None else np.zeros(n1, dtype=INDEX_DTYPE)
        rb = b.point_refs if b.point_refs is not None else np.zeros(n2, dtype=INDEX_DTYPE)
    pairs, stats = _match(a.points, b.points, tol, ra, rb)

    # numbering (seed §17.2, 'Numbering issues')
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
        cell_refs = per_type(lambda t: _block_refs(a, t), lambda t: _block_refs(b, t))
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
        euler = _euler_check(top, blocks_a, blocks_b, bmap, interface_a, n_new, points)
        euler["n_common_points"] = len(pairs)
        info.update(euler)
    if check and not euler["euler_ok"]:
        raise MergeError(
            f"Euler check failed: χ(T) = {euler['euler']} but χ(T1) + χ(T2) − χ(T1∩T2) = "
            f"{euler['euler_a']} + {euler['euler_b']} − {euler['euler_interface']} (interface seen "
            f"from 'a'; {euler['euler_interface_b']} seen from 'b'). The two interfaces do not "
            f"match: probably they are meshed differently (other vertices, or quads split "
            f"along other diagonals, seed Remark 17.16), or 'tolerance' = {tol:g} is too large "
            f"and merged vertices that are not on the interface; pass check=False to merge anyway"
        )
    mesh = Mesh(points, cells, point_data=point_data, cell_data=cell_data,
                point_refs=point_refs, cell_refs=cell_refs, info=info)
    return mesh, bmap


def merge(a, b, tolerance: float | None = None, *, refs: bool = False,
          duplicates: Literal["merge", "keep", "drop"] = "merge", check: bool = True):
    """Merge two meshes that share an interface (seed §17.2).

    Parameters
    ----------
    a, b : Mesh
        Same dimension; any cell types. Their interfaces are assumed meshed identically
        (up to round-off).
    tolerance : float, optional
        Absolute distance under which a vertex of ``b`` and one of ``a`` are the same
        (:func:`match_points`). Default ``1e-8 × Δ``, Δ the largest side of the box
        enclosing both meshes.
    refs : bool
        Only vertices with equal ``point_refs`` merge (missing refs are 0): coincident
        vertices of different refs stay apart, e.g. a crack (seed §17.2, §17.5).
    duplicates : {"merge", "keep", "drop"}
        Cells of the same type present in both meshes with the same vertex set (e.g. the
        interface's boundary triangles or lines): keep one (the first mesh's), keep both,
        or remove both (the interface then disappears as a boundary).
    check : bool
        Count the common entities, check the Euler formula and raise :class:`MergeError`
        when it fails. ``check=False`` skips both (faster: no edge or face is built; the
        ``euler*`` and ``n_common_edges/faces`` keys are then absent from ``info``).

    Returns
    -------
    Mesh
        Points: ``a``'s (numbers kept), then ``b``'s non-interface points in order. Cells:
        per type, ``a``'s block then ``b``'s (types only in ``b`` after ``a``'s). Refs,
        common ``point_data`` (interface points take ``a``'s values) and common
        ``cell_data`` carried; keys in only one mesh are dropped with a warning.
        ``info``: ``merge_tolerance``, ``n_common_points`` (pairs merged),
        ``n_common_vertices``, ``n_common_edges``, ``n_common_faces`` (entities of ``a``'s
        top-dimension cells whose vertices are all common), ``euler`` (χ = V − E + F (− T)
        of the top-dimension cells of the result, duplicates counted once), ``euler_a``,
        ``euler_b``, ``euler_interface`` (of the common entities, from ``a``),
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
        The Euler formula fails (interfaces meshed differently, or tolerance too large).

    Examples
    --------
    >>> from warpmesh.mesh import Mesh
    >>> a = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]], "line": [[1, 2]]})
    >>> b = Mesh([[1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2]], "line": [[2, 0]]})
    >>> m = merge(a, b)
    >>> m.cells["triangle"].tolist(), m.cells["line"].tolist(), m.info["euler"]
    ([[0, 1, 2], [1, 3, 2]], [[1, 2]], 1)
    >>> len(merge(a, b, duplicates="drop").cells["line"])
    0
    """
    return _merge(a, b, tolerance, refs=refs, duplicates=duplicates, check=check)[0]
