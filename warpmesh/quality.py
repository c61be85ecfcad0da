"""Element shape quality, the measure of seed eq. 16.15.

``Q_K = alpha * h_max / rho_K``: ``h_max`` is the element diameter (its longest edge),
``rho_K`` the radius of the inscribed circle or sphere, and ``alpha`` normalises the
regular element to exactly 1. Larger is worse; a degenerate element (zero area or
volume, up to ``REL_TOL * h_max**d``) scores ``inf``.

=========  ======================================  ===========================
element    rho_K                                   alpha
=========  ======================================  ===========================
triangle   2 * area / perimeter                    ``ALPHA_TRIANGLE`` = sqrt(3)/6
tetra      3 * volume / (sum of the 4 face areas)  ``ALPHA_TETRA`` = sqrt(6)/12
=========  ======================================  ===========================

Examples
--------
>>> import numpy as np
>>> from warpmesh.quality import triangle_quality
>>> triangle_quality([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]], [[0, 1, 2]]).round(12).tolist()
[1.0]
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ._conventions import ALPHA_TETRA, ALPHA_TRIANGLE, INDEX_DTYPE, REAL_DTYPE, REL_TOL
from .topology import face_areas

__all__ = ["ALPHA_TETRA", "triangle_quality", "tetra_quality", "quality_summary"]

_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def _validate(points, cells, k: int, dims: tuple[int, ...], name: str):
    pts = np.asarray(points, dtype=REAL_DTYPE)
    if pts.ndim != 2 or pts.shape[1] not in dims:
        want = " or ".join(f"(n, {d})" for d in dims)
        raise ValueError(f"expected 'points' of shape {want}, got shape {pts.shape}")
    arr = np.asarray(cells)
    if arr.size == 0:
        return pts, np.zeros((0, k), dtype=INDEX_DTYPE)
    if not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"expected an integer array for '{name}', got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != k:
        raise ValueError(f"expected '{name}' of shape (m, {k}), got shape {arr.shape}")
    if arr.min() < 0 or arr.max() >= len(pts):
        raise ValueError(
            f"expected indices in [0, {len(pts)}) in '{name}', got [{arr.min()}, {arr.max()}]"
        )
    return pts, arr.astype(INDEX_DTYPE, copy=False)


def _ratio(alpha: float, h_max: np.ndarray, rho: np.ndarray, degenerate: np.ndarray) -> np.ndarray:
    q = np.full(len(h_max), np.inf)
    ok = ~degenerate
    q[ok] = alpha * h_max[ok] / rho[ok]
    return q


def triangle_quality(points, triangles) -> np.ndarray:
    """Shape measure ``Q_K`` of triangles in 2D or 3D.

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
    triangles : (m, 3) int

    Returns
    -------
    (m,) float64
        1 for an equilateral triangle, larger is worse, ``inf`` when degenerate.

    Examples
    --------
    >>> q = triangle_quality([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]])  # right isosceles
    >>> bool(np.isclose(q[0], (1 + np.sqrt(2)) / np.sqrt(3)))
    True
    """
    pts, tri = _validate(points, triangles, 3, (2, 3), "triangles")
    p = pts[tri]
    lengths = np.stack(
        [np.linalg.norm(p[:, (j + 1) % 3] - p[:, j], axis=1) for j in range(3)], axis=1
    )
    h_max = lengths.max(axis=1) if len(tri) else np.zeros(0)
    area = face_areas(pts, tri)
    rho = 2.0 * area / np.maximum(lengths.sum(axis=1), np.finfo(REAL_DTYPE).tiny)
    return _ratio(ALPHA_TRIANGLE, h_max, rho, area <= REL_TOL * h_max**2)


def tetra_quality(points, tetra) -> np.ndarray:
    """Shape measure ``Q_K`` of tetrahedra.

    Parameters
    ----------
    points : (n, 3) float
    tetra : (m, 4) int

    Returns
    -------
    (m,) float64
        1 for a regular tetrahedron, larger is worse, ``inf`` when degenerate. The
        orientation (sign of the volume) is ignored.

    Examples
    --------
    >>> pts = [[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]
    >>> tetra_quality(pts, [[0, 1, 2, 3]]).round(12).tolist()
    [1.0]
    """
    pts, tet = _validate(points, tetra, 4, (3,), "tetra")
    p = pts[tet]
    edges = p[:, _TET_EDGES[:, 1]] - p[:, _TET_EDGES[:, 0]]
    h_max = np.linalg.norm(edges, axis=2).max(axis=1) if len(tet) else np.zeros(0)
    volume = np.abs(np.einsum("ij,ij->i", edges[:, 0], np.cross(edges[:, 1], edges[:, 2]))) / 6.0
    faces = tet[:, _TET_FACES].reshape(-1, 3)
    total_area = face_areas(pts, faces).reshape(-1, 4).sum(axis=1)
    rho = 3.0 * volume / np.maximum(total_area, np.finfo(REAL_DTYPE).tiny)
    return _ratio(ALPHA_TETRA, h_max, rho, volume <= REL_TOL * h_max**3)


def quality_summary(points, cells) -> dict:
    """Quality figures of a triangle or tetrahedron mesh, as in Table 16.1 of the seed.

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
    cells : (m, 3) int triangles, (m, 4) int tetrahedra, or a mapping with a
        ``"tetra"`` or ``"triangle"`` block (tetrahedra are used when present).

    Returns
    -------
    dict
        ``n_elements``; ``mean_q`` (mean over non-degenerate elements), ``worst_q``
        (max, ``inf`` if any element is degenerate), ``best_q`` (min), ``n_degenerate``.
        With no elements the three Q figures are NaN.

    Examples
    --------
    >>> s = quality_summary([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]], [[0, 1, 2]])
    >>> s["n_elements"], round(s["worst_q"], 12)
    (1, 1.0)
    """
    if isinstance(cells, Mapping):
        name = "tetra" if "tetra" in cells else "triangle"
        if name not in cells:
            raise ValueError(
                f"expected a 'triangle' or 'tetra' block in 'cells', got {sorted(cells)}"
            )
        cells = cells[name]
    k = np.shape(cells)[1] if np.ndim(cells) == 2 else 0
    if k not in (3, 4):
        raise ValueError(f"expected 'cells' of shape (m, 3) or (m, 4), got shape {np.shape(cells)}")
    q = triangle_quality(points, cells) if k == 3 else tetra_quality(points, cells)
    finite = q[np.isfinite(q)]
    empty = len(q) == 0
    return {
        "n_elements": int(len(q)),
        "mean_q": float("nan") if empty else float(finite.mean()) if len(finite) else float("inf"),
        "worst_q": float("nan") if empty else float(q.max()),
        "best_q": float("nan") if empty else float(q.min()),
        "n_degenerate": int(len(q) - len(finite)),
    }
