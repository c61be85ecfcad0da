"""Vertex placement from points and normals: the quadratic error function of dual
contouring (Ju et al. 2002), batched over groups.

For a group of points p_i with unit normals n_i, the QEF point minimises
sum_i <n_i, x - p_i>^2. Written about the group's mass point m, the normal equations are
A (x - m) = b with A = sum n_i n_i^T and b = sum n_i <n_i, p_i - m>; directions whose
eigenvalue of A is below ``RANK_TOL`` times the largest are dropped (the pseudo-inverse
of the truncated A), so a flat patch keeps x on the plane through m, an edge puts x on
the edge line nearest m, a corner on the corner. The kept rank says which: 1 smooth,
2 edge, 3 corner.

Example
-------
>>> import numpy as np
>>> p = np.array([[1, 0.2, 0], [1, 0.5, 0], [0.2, 1, 0], [0.5, 1, 0.0]])
>>> n = np.array([[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0.0]])
>>> x, rank = qef_points(np.zeros(4, int), p, n, 1)
>>> np.round(x, 6).tolist(), rank.tolist()  # the corner of the two planes x = 1, y = 1
([[1.0, 1.0, 0.0]], [2])
"""

from __future__ import annotations

import numpy as np

RANK_TOL = 0.04  # eigenvalue ratio: normals spread over less than about 11 degrees count as one plane


def qef_points(group: np.ndarray, points: np.ndarray, normals: np.ndarray, n_groups: int):
    """QEF minimisers of each group: (x (n_groups, 3), rank (n_groups,)).

    Parameters
    ----------
    group : (n,) int, the group of each point (every group non-empty)
    points, normals : (n, 3) floats; normals of unit length (zero rows are ignored)
    n_groups : int
    """
    group = np.asarray(group, dtype=np.int64)
    points = np.asarray(points, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    if np.any(np.bincount(group, minlength=n_groups) == 0):
        raise ValueError("expected every group to hold at least one point")
    mass = mass_points(group, points, n_groups)
    rel = points - mass[group]
    a = np.empty((n_groups, 3, 3))
    for i in range(3):
        for j in range(i, 3):
            a[:, i, j] = a[:, j, i] = np.bincount(group, normals[:, i] * normals[:, j], n_groups)
    proj = np.einsum("nk,nk->n", normals, rel)
    b = np.stack([np.bincount(group, normals[:, k] * proj, n_groups) for k in range(3)], axis=1)
    lam, vec = np.linalg.eigh(a)  # ascending eigenvalues
    keep = lam > RANK_TOL * np.maximum(lam[:, -1:], 1e-300)
    inv = np.where(keep, 1.0 / np.where(keep, lam, 1.0), 0.0)
    coef = np.einsum("nki,nk->ni", vec, b) * inv  # components along the eigenvectors
    x = mass + np.einsum("nki,ni->nk", vec, coef)
    return x, keep.sum(axis=1)


def mass_points(group: np.ndarray, points: np.ndarray, n_groups: int) -> np.ndarray:
    """The mean point of each group."""
    count = np.bincount(group, minlength=n_groups).astype(np.float64)
    return np.stack([np.bincount(group, points[:, k], n_groups) for k in range(3)], axis=1) / count[:, None]
