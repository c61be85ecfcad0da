"""The merge hash [FG §17.2, Figs. 17.7-17.8, Remarks 17.7-17.9]: pairs of coincident
points of two point sets, found by hashing on a virtual grid.

Vectorised: every key is packed into an integer with its point's position and sorted
once; the second set's points look up the book's shifted keys (Fig. 17.8) with
``searchsorted``, so a pair straddling a grid-cell border is found; only points inside the
intersection of the two bounding boxes take part (Remark 17.7); a pair is kept when each
point is the other's nearest (symmetric pairing, Remark 17.9); with refs, only equal refs
match. :func:`warpmesh.modify.merge.merge` builds on :func:`match_points`.

Examples
--------
>>> import numpy as np
>>> from warpmesh.modify.merge_hash import match_points
>>> a = np.array([[0.0, 0.0], [1.0, 0.0]])
>>> b = np.array([[1.0 + 1e-12, 0.0], [5.0, 5.0]])
>>> match_points(a, b, 1e-9).tolist()
[[1, 0]]
"""

from __future__ import annotations

import numbers

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE

__all__ = ["match_points", "default_tolerance", "RELATIVE_TOLERANCE", "CELL_FACTOR"]

#: the default tolerance, relative to the largest side of the box enclosing both meshes
#: (the book's δ = 2εΔ: a resolution relative to the box), with ε float32's: the meshers
#: compute their nodes in float32, so a mesh and its translate by the box's width have their
#: common face's nodes up to a few float32 ulps apart (1.00000005 against 1.0). At 1e-8 (float64's
#: scale) 81 of a stuffed box's 221 face nodes were left unwelded, silently.
RELATIVE_TOLERANCE = 2.0 * float(2.0**-23)
#: the virtual grid's step, in shifts s (s = tolerance + a few ulps): any value >= 2 finds
#: every pair; 4 makes floor((x - s)/h) == floor((x + s)/h) on half of the axes, so a point
#: looks up (3/2)^d keys on average instead of 2^d, with few points per cell
CELL_FACTOR = 4.0


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
    (the book's δ = 2εΔ idea: a tolerance relative to the size of the problem).

    Examples
    --------
    >>> float(default_tolerance([[0.0, 0.0], [2.0, 1.0]], [[4.0, 0.0]]) / RELATIVE_TOLERANCE)
    4.0
    """
    sets = [np.asarray(p, dtype=REAL_DTYPE) for p in point_sets]
    sets = [p.reshape(len(p), -1) for p in sets if p.size]  # an empty set adds nothing to the box
    if not sets:
        return RELATIVE_TOLERANCE
    pts = np.concatenate(sets)
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
    """One-to-one pairs of points of ``a`` and ``b`` closer than ``tolerance`` [FG §17.2].

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
    y's cell is one of the two cells floor((x ± s)/h) of the book's shifted points. A pair
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
