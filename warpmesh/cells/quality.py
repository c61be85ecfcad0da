"""Element shape quality, the measure of [FG eq. 16.15].

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
>>> from warpmesh.cells.quality import triangle_quality
>>> triangle_quality([[0, 0], [1, 0], [0.5, np.sqrt(3) / 2]], [[0, 1, 2]]).round(12).tolist()
[1.0]
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from warpmesh.cells.predicates import power_of_two_scaled
from warpmesh._conventions import ALPHA_TETRA, ALPHA_TRIANGLE, INDEX_DTYPE, REAL_DTYPE, REL_TOL

__all__ = ["ALPHA_TETRA", "triangle_quality", "tetra_quality", "tetra_figures", "quality_summary", "summarize_quality",
           "triangle_angles",
           "edge_length_ratio", "quality_table", "quality_histogram", "format_table"]

_TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def _validate(points, cells, k: int, dims: tuple[int, ...], name: str):
    pts = np.asarray(points, dtype=REAL_DTYPE)
    if pts.ndim != 2 or pts.shape[1] not in dims:
        want = " or ".join(f"(n, {d})" for d in dims)
        raise ValueError(f"expected 'points' of shape {want}, got shape {pts.shape}")
    if not np.isfinite(pts).all():  # (NaN Q_K otherwise, and an inconsistent summary)
        raise ValueError("expected finite 'points', got NaN or infinity")
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
    if not len(tri):
        return np.zeros(0)
    pts = power_of_two_scaled(pts)  # exact; Q_K is scale-free and products of 1e-100 lengths underflow
    # coordinates as rows: each gather and each product runs over contiguous (m,) arrays
    # (2.2x faster than (m, 3) rows with np.linalg.norm and np.cross, the same bits)
    x = np.ascontiguousarray(pts.T)
    a, b, c = (x[:, tri[:, j]] for j in range(3))
    u, v, w, d = b - a, c - b, a - c, c - a
    lengths = np.sqrt(np.stack([np.einsum("ij,ij->j", e, e) for e in (u, v, w)]))
    if len(x) == 3:
        cross = _cross_rows(u, d)
        area = 0.5 * np.sqrt(np.einsum("ij,ij->j", cross, cross))
    else:
        area = 0.5 * np.abs(u[0] * d[1] - u[1] * d[0])
    h_max = lengths.max(axis=0)
    rho = 2.0 * area / np.maximum(lengths.sum(axis=0), np.finfo(REAL_DTYPE).tiny)
    return _ratio(ALPHA_TRIANGLE, h_max, rho, area <= REL_TOL * h_max**2)


#: tetrahedra a chunk of :func:`tetra_quality` (numpy) and :func:`tetra_figures` (kernel)
_ROW_CHUNK = 1 << 18
_KERNEL_CHUNK = 1 << 20


def tetra_quality(points, tetra) -> np.ndarray:
    """Shape measure ``Q_K`` of tetrahedra.

    3D points take one Warp kernel split across the CPU cores
    (:func:`~warpmesh.kernels.topology.tet_measures_kernel`: 12.7 M tetrahedra in about
    0.3 s, against 5.5 s for the numpy rows, which agree to a few ulps and remain the
    path of meshes beyond int32 indexing).

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
    if not len(tet):
        return np.zeros(0)
    pts = power_of_two_scaled(pts)  # exact; Q_K is scale-free and products of 1e-100 lengths underflow
    out = np.empty(len(tet))
    if _kernel_applies(pts, tet):
        for lo, _, q in _tetra_chunks(pts, tet):
            out[lo:lo + len(q)] = q
        return out
    # coordinates as rows, as triangle_quality: 1.9 M tets 6.0 -> 1.0 s (equal to a few ulps)
    x = np.ascontiguousarray(pts.T)
    # by chunks of rows: the temporaries (some 20 arrays of 24 bytes a tetrahedron) stay in
    # memory the process already has (12.7 M tetrahedra: 22.8 -> 3.9 s); the same values to
    # a few ulps (numpy's einsum may sum a short row in another order for some sizes)
    for lo in range(0, len(tet), _ROW_CHUNK):
        out[lo:lo + _ROW_CHUNK] = _tetra_quality_rows(x, tet[lo:lo + _ROW_CHUNK])
    return out


def tetra_figures(points, tetra) -> tuple[float, dict]:
    """The total signed volume of tetrahedra and the :func:`summarize_quality` figures of
    their ``Q_K``, in one pass (what ``Mesh.stats()`` reports for a volume mesh): a Warp
    kernel over chunks of 2^20 tetrahedra whose buffers are reused, so no array of the
    whole mesh is made; the numpy rows beyond int32 indexing.

    Parameters
    ----------
    points : (n, 3) float
    tetra : (m, 4) int

    Returns
    -------
    volume : float
        Sum of det(p1 - p0, p2 - p0, p3 - p0) / 6 (positive for positively oriented
        tetrahedra).
    summary : dict
        ``n_elements``, ``mean_q``, ``worst_q``, ``best_q``, ``n_degenerate`` as
        :func:`summarize_quality` (the mean summed by chunks: equal to a few ulps).

    Examples
    --------
    >>> pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]
    >>> volume, s = tetra_figures(pts, [[0, 1, 2, 3], [1, 2, 3, 4]])
    >>> round(volume, 12), s["n_elements"], round(s["best_q"], 12)
    (0.5, 2, 1.0)
    """
    pts, tet = _validate(points, tetra, 4, (3,), "tetra")
    if not len(tet):
        return 0.0, summarize_quality(np.zeros(0))
    if not _kernel_applies(pts, tet):
        p = [pts[tet[:, j]] for j in range(4)]
        volume = float(np.einsum("ij,ij->i", p[1] - p[0], np.cross(p[2] - p[0], p[3] - p[0])).sum() / 6.0)
        return volume, summarize_quality(tetra_quality(pts, tet))
    volume6, total, count, worst, best = 0.0, 0.0, 0, -np.inf, np.inf
    for _, v6, q in _tetra_chunks(pts, tet):
        volume6 += float(v6.sum())
        finite = q[np.isfinite(q)]
        total, count = total + float(finite.sum()), count + len(finite)
        worst, best = float(np.maximum(worst, q.max())), float(np.minimum(best, q.min()))  # (NaN kept)
    m = len(tet)
    return volume6 / 6.0, {"n_elements": m, "mean_q": total / count if count else float("inf"),
                           "worst_q": worst, "best_q": best, "n_degenerate": m - count}


def _kernel_applies(pts: np.ndarray, tet: np.ndarray) -> bool:
    """Whether :func:`_tetra_chunks` takes these tetrahedra: corner slots and points within int32."""
    limit = np.iinfo(np.int32).max
    return 4 * len(tet) < limit and len(pts) < limit


def _tetra_chunks(pts: np.ndarray, tet: np.ndarray):
    """Yield (first row, six times the signed volumes, Q_K with inf when degenerate) of
    the tetrahedra chunk by chunk (:data:`_KERNEL_CHUNK` rows), from
    :func:`~warpmesh.kernels.topology.tet_measures_kernel`; the yielded arrays are
    overwritten by the next chunk."""
    import warp as wp

    from warpmesh._util.parallel import cpu_view, launch_split
    from warpmesh.kernels import topology as KT

    wp.load_module(KT, device="cpu")  # once here, not in the worker threads
    step = min(len(tet), _KERNEL_CHUNK)
    corners, v6, q = np.empty((step, 4), np.int32), np.empty(step), np.empty(step)
    points = cpu_view(np.ascontiguousarray(pts), wp.vec3d)
    for lo in range(0, len(tet), step):
        k = min(step, len(tet) - lo)
        corners[:k] = tet[lo:lo + k]
        launch_split(KT.tet_measures_kernel, k,
                     [points, cpu_view(corners[:k].reshape(-1), wp.int32), float(ALPHA_TETRA), float(REL_TOL)],
                     [cpu_view(v6[:k], wp.float64), cpu_view(q[:k], wp.float64)])
        wp.synchronize_device("cpu")
        qk = q[:k]
        qk[qk < 0.0] = np.inf
        yield lo, v6[:k], qk


def _tetra_quality_rows(x: np.ndarray, tet: np.ndarray) -> np.ndarray:
    """:func:`tetra_quality` of ``tet`` with the points' coordinates as rows ``x`` (3, n)."""
    p = [x[:, tet[:, j]] for j in range(4)]
    edges = [p[j] - p[i] for i, j in _TET_EDGES]
    h_max = np.sqrt(np.stack([np.einsum("ij,ij->j", e, e) for e in edges])).max(axis=0)
    volume = np.abs(np.einsum("ij,ij->j", edges[0], _cross_rows(edges[1], edges[2]))) / 6.0
    total_area = np.zeros(len(tet))
    for i, j, k in _TET_FACES:
        c = _cross_rows(p[j] - p[i], p[k] - p[i])
        total_area += 0.5 * np.sqrt(np.einsum("ij,ij->j", c, c))
    rho = 3.0 * volume / np.maximum(total_area, np.finfo(REAL_DTYPE).tiny)
    return _ratio(ALPHA_TETRA, h_max, rho, volume <= REL_TOL * h_max**3)


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of (3, m) arrays of column vectors."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def quality_summary(points, cells) -> dict:
    """Quality figures of a triangle or tetrahedron mesh, as in [FG Table 16.1].

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
    return summarize_quality(triangle_quality(points, cells) if k == 3 else tetra_quality(points, cells))


def summarize_quality(q) -> dict:
    """The figures of :func:`quality_summary` from given per-element ``Q_K`` values
    (``inf`` for a degenerate element), e.g. those of
    :func:`warpmesh.cells.topology.surface_figures`.

    Examples
    --------
    >>> s = summarize_quality([1.0, 1.5, np.inf])
    >>> s["mean_q"], s["worst_q"], s["best_q"], s["n_degenerate"]
    (1.25, inf, 1.0, 1)
    """
    q = np.asarray(q, dtype=np.float64)
    if q.ndim != 1:
        raise ValueError(f"expected 'q' of shape (m,), got shape {q.shape}")
    finite = q[np.isfinite(q)]
    empty = len(q) == 0
    return {
        "n_elements": int(len(q)),
        "mean_q": float("nan") if empty else float(finite.mean()) if len(finite) else float("inf"),
        "worst_q": float("nan") if empty else float(q.max()),
        "best_q": float("nan") if empty else float(q.min()),
        "n_degenerate": int(len(q) - len(finite)),
    }


def triangle_angles(points, triangles) -> np.ndarray:
    """(m, 3) interior angles in degrees, at each corner of each triangle.

    Examples
    --------
    >>> triangle_angles([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]]).round(6).tolist()
    [[90.0, 45.0, 45.0]]
    """
    pts, tri = _validate(points, triangles, 3, (2, 3), "triangles")
    p = pts[tri]
    out = np.empty((len(tri), 3))
    for j in range(3):
        u = p[:, (j + 1) % 3] - p[:, j]
        v = p[:, (j + 2) % 3] - p[:, j]
        cos = np.einsum("ij,ij->i", u, v) / np.maximum(
            np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1), np.finfo(REAL_DTYPE).tiny)
        out[:, j] = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    return out


def edge_length_ratio(points, triangles) -> np.ndarray:
    """(m,) longest over shortest edge of each triangle (1 for an equilateral one, inf if an edge is 0)."""
    pts, tri = _validate(points, triangles, 3, (2, 3), "triangles")
    p = pts[tri]
    lens = np.stack([np.linalg.norm(p[:, (j + 1) % 3] - p[:, j], axis=1) for j in range(3)], axis=1)
    with np.errstate(divide="ignore"):
        return np.where(lens.min(1) > 0, lens.max(1) / np.where(lens.min(1) > 0, lens.min(1), 1.0), np.inf)


#: the bins of :func:`quality_histogram` (Q_K), open at the top
Q_BINS = (1.0, 1.1, 1.25, 1.5, 2.0, 3.0, 5.0, 10.0, 100.0, np.inf)


def quality_histogram(points, triangles, bins=Q_BINS) -> dict:
    """Counts of triangles per Q_K bin: ``{"1-1.1": k, ...}`` (degenerate ones in the last bin)."""
    q = triangle_quality(points, triangles)
    counts, _ = np.histogram(np.minimum(q, np.finfo(REAL_DTYPE).max), bins=np.asarray(bins, float))
    label = lambda lo, hi: f"{lo:g}-{hi:g}" if np.isfinite(hi) else f">{lo:g}"  # noqa: E731
    return {label(lo, hi): int(c) for lo, hi, c in zip(bins[:-1], bins[1:], counts)}


def quality_table(points, triangles) -> dict:
    """One row of a Table 16.1-style statistics table of a triangle mesh.

    Returns
    -------
    dict
        ``np`` (vertices used), ``ne``, ``q_mean``, ``q_worst``, ``angle_min``,
        ``angle_max`` (degrees), ``edge_ratio_max``, ``histogram``.

    Examples
    --------
    >>> row = quality_table([[0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]], [[0, 1, 2]])
    >>> row["np"], row["ne"], round(row["q_worst"], 9), round(row["angle_min"], 6)
    (3, 1, 1.0, 60.0)
    """
    pts, tri = _validate(points, triangles, 3, (2, 3), "triangles")
    if len(tri) == 0:
        raise ValueError("expected at least one triangle in 'triangles'")
    q = triangle_quality(pts, tri)
    ang = triangle_angles(pts, tri)
    finite = q[np.isfinite(q)]
    return {
        "np": int(len(np.unique(tri))),
        "ne": int(len(tri)),
        "q_mean": float(finite.mean()) if len(finite) else float("inf"),
        "q_worst": float(q.max()),
        "angle_min": float(ang.min()),
        "angle_max": float(ang.max()),
        "edge_ratio_max": float(edge_length_ratio(pts, tri).max()),
        "histogram": quality_histogram(pts, tri),
    }


def format_table(rows: Mapping[str, Mapping]) -> str:
    """Text table of :func:`quality_table` rows keyed by a label (e.g. "before", "after").

    Examples
    --------
    >>> row = quality_table([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> print(format_table({"mesh": row}).splitlines()[0])
    |        |  np |  ne | Q mean | Q worst | angle min | angle max | distance max |
    """
    head = ["", "np", "ne", "Q mean", "Q worst", "angle min", "angle max", "distance max"]
    body = []
    for name, r in rows.items():
        dist = r.get("distance_max")
        body.append([name, f"{r['np']:,}", f"{r['ne']:,}", f"{r['q_mean']:.3f}", f"{r['q_worst']:.2f}",
                     f"{r['angle_min']:.1f}", f"{r['angle_max']:.1f}",
                     "" if dist is None else f"{dist:.2e}"])
    width = [max(len(h), *(len(b[i]) for b in body)) for i, h in enumerate(head)]
    line = lambda cells: "| " + " | ".join(c.rjust(w) for c, w in zip(cells, width)) + " |"  # noqa: E731
    return "\n".join([line(head), "|" + "|".join("-" * (w + 2) for w in width) + "|", *map(line, body)])
