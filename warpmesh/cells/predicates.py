"""Exact orientation signs on the host, vectorised over rows of point indices.

Each predicate is the sign of a polynomial in the coordinates, decided in three steps:

1. float64 with a static error bound (Shewchuk's ``errboundA``, doubled): rows whose
   value exceeds the bound have the sign of the float value;
2. a row left undecided with a repeated point, or whose points share one coordinate
   exactly (all on one grid plane, or in 2D on one grid line: the staircases of the
   label surfaces), is exactly 0;
3. the rest in Python integers: the coordinates the rows use written over one
   power-of-two denominator (the largest of theirs: float64 values are dyadic), so the
   polynomial is evaluated without rounding.

The float filter needs points scaled by a power of two into [-1, 1)^3
(:func:`power_of_two_scaled`, exact), so that no product of three coordinates over- or
underflows past the bound's floor of 1e-290.

Examples
--------
>>> import numpy as np
>>> pts = power_of_two_scaled(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], float))
>>> orient3d_signs(pts, [0, 0], [1, 1], [2, 2], [3, 4]).tolist()  # above the plane z = 0, on it
[1, 0]
>>> orient2d_signs(pts, [0, 0], [1, 1], [2, 4], 2).tolist()  # in the xy projection
[1, 1]
"""

from __future__ import annotations

import numpy as np

__all__ = ["orient2d_signs", "orient3d_signs", "power_of_two_scaled"]

_EPS = 2.0**-53
#: Shewchuk's orient3d errboundA, doubled
_O3_BOUND = 2.0 * (7.0 + 56.0 * _EPS) * _EPS
#: Shewchuk's orient2d (ccw) errboundA, doubled
_O2_BOUND = 2.0 * (3.0 + 16.0 * _EPS) * _EPS
#: values at or below this go to the exact stage whatever the bound says (underflow)
_FLOOR = 1.0e-290


def power_of_two_scaled(points: np.ndarray) -> np.ndarray:
    """The points times a power of two (exact) so that max |x| is in [0.5, 1); unchanged when
    all are zero.

    >>> power_of_two_scaled(np.array([[3.0, -6.0, 0.5]])).tolist()
    [[0.375, -0.75, 0.0625]]
    """
    points = np.asarray(points, dtype=np.float64)
    big = float(np.abs(points).max()) if points.size else 0.0
    return np.ldexp(points, -np.frexp(big)[1]) if big > 0.0 else points


def orient3d_signs(points: np.ndarray, ia, ib, ic, id_) -> np.ndarray:
    """Exact signs of the orientation O(a, b, c, d) = (b - a) . ((c - a) x (d - a)) for rows of
    indices: +1 when d is on the side of the plane (a, b, c) that its right-hand normal
    points to.

    Parameters
    ----------
    points : (n, 3) float64
        Scaled by :func:`power_of_two_scaled`.
    ia, ib, ic, id_ : (k,) int
        Point indices of each row.

    Returns
    -------
    (k,) int64
        -1, 0 or 1.

    Examples
    --------
    >>> pts = np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0], [0, 0, 0.5]])
    >>> orient3d_signs(pts, [0, 0], [1, 2], [2, 1], [3, 3]).tolist()
    [1, -1]
    """
    ia, ib, ic, id_ = (np.asarray(x, dtype=np.int64) for x in (ia, ib, ic, id_))
    a = points[ia]
    u, v, w = points[ib] - a, points[ic] - a, points[id_] - a
    det = np.einsum("ij,ij->i", u, np.cross(v, w))
    perm = np.einsum("ij,ij->i", np.abs(u), np.abs(v[:, [1, 2, 0]] * w[:, [2, 0, 1]])
                     + np.abs(v[:, [2, 0, 1]] * w[:, [1, 2, 0]]))
    sure = np.abs(det) > _O3_BOUND * perm + _FLOOR
    out = np.where(sure, np.sign(det), 0.0).astype(np.int64)
    rest = np.flatnonzero(~sure)
    if len(rest):
        idx = [x[rest] for x in (ia, ib, ic, id_)]
        flat = ((idx[0] == idx[1]) | (idx[0] == idx[2]) | (idx[0] == idx[3]) | (idx[1] == idx[2])
                | (idx[1] == idx[3]) | (idx[2] == idx[3]))  # a repeated point
        for k in range(3):  # all four on one plane x_k = const: exactly 0
            col = points[idx[0], k]
            flat |= (points[idx[1], k] == col) & (points[idx[2], k] == col) & (points[idx[3], k] == col)
        left = np.flatnonzero(~flat)
        if len(left):
            ea, eb, ec, ed = _exact(points, [x[left] for x in idx])
            u, v, w = eb - ea, ec - ea, ed - ea
            det = (u[:, 0] * (v[:, 1] * w[:, 2] - v[:, 2] * w[:, 1]) + u[:, 1] * (v[:, 2] * w[:, 0] - v[:, 0] * w[:, 2])
                   + u[:, 2] * (v[:, 0] * w[:, 1] - v[:, 1] * w[:, 0]))
            out[rest[left]] = _sign(det)
    return out


def orient2d_signs(points: np.ndarray, ia, ib, ic, axis: int) -> np.ndarray:
    """Exact signs of the orientation of (a, b, c) projected along ``axis``: component ``axis``
    of (b - a) x (c - a), i.e. the 2D orientation in the coordinates (axis + 1, axis + 2)
    mod 3.

    Parameters
    ----------
    points : (n, 3) float64
        Scaled by :func:`power_of_two_scaled`.
    ia, ib, ic : (k,) int
        Point indices of each row.
    axis : {0, 1, 2}
        The coordinate dropped.

    Returns
    -------
    (k,) int64
        -1, 0 or 1; 0 in all three projections iff the three points are collinear.

    Examples
    --------
    >>> pts = np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0]])
    >>> [orient2d_signs(pts, [0], [1], [2], k).tolist() for k in range(3)]
    [[0], [0], [1]]
    """
    if axis not in (0, 1, 2):
        raise ValueError(f"expected 0, 1 or 2 for 'axis', got {axis!r}")
    i, j = (axis + 1) % 3, (axis + 2) % 3
    ia, ib, ic = (np.asarray(x, dtype=np.int64) for x in (ia, ib, ic))
    a, b, c = points[ia], points[ib], points[ic]
    left = (b[:, i] - a[:, i]) * (c[:, j] - a[:, j])
    right = (b[:, j] - a[:, j]) * (c[:, i] - a[:, i])
    det = left - right
    sure = np.abs(det) > _O2_BOUND * (np.abs(left) + np.abs(right)) + _FLOOR
    out = np.where(sure, np.sign(det), 0.0).astype(np.int64)
    rest = np.flatnonzero(~sure)
    if len(rest):
        a, b, c = a[rest], b[rest], c[rest]
        flat = (((a[:, i] == b[:, i]) & (a[:, i] == c[:, i])) | ((a[:, j] == b[:, j]) & (a[:, j] == c[:, j]))
                | (a == b).all(axis=1) | (a == c).all(axis=1) | (b == c).all(axis=1))
        todo = np.flatnonzero(~flat)
        if len(todo):
            ea, eb, ec = _exact(points, [x[rest[todo]] for x in (ia, ib, ic)])
            det = (eb[:, i] - ea[:, i]) * (ec[:, j] - ea[:, j]) - (eb[:, j] - ea[:, j]) * (ec[:, i] - ea[:, i])
            out[rest[todo]] = _sign(det)
    return out


def _exact(points: np.ndarray, index_rows: list) -> list:
    """The points of each index array as (k, 3) object arrays of Python integers, all over one
    power-of-two denominator (the largest among the points used: each divides it)."""
    used, inverse = np.unique(np.concatenate(index_rows), return_inverse=True)
    ratios = [x.as_integer_ratio() for x in points[used].ravel().tolist()]
    den = max(d for _, d in ratios)
    ints = np.array([num * (den // d) for num, d in ratios], dtype=object).reshape(-1, 3)
    return [ints[part] for part in np.split(inverse, len(index_rows))]


def _sign(values: np.ndarray) -> np.ndarray:
    """Signs of an object array of Python integers, as int64."""
    return (values > 0).astype(np.int64) - (values < 0).astype(np.int64)
