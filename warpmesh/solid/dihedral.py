"""Quality of tetrahedra: dihedral angles and the radius-edge ratio, vectorised numpy.

Example
-------
>>> import numpy as np
>>> pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
>>> np.degrees(dihedral_angles(pts, [[0, 1, 2, 3]])).round(2).tolist()
[[90.0, 90.0, 90.0, 54.74, 54.74, 54.74]]
>>> {k: round(v, 2) for k, v in tet_quality_summary(pts, [[0, 1, 2, 3]]).items()}
{'dihedral_min': 54.74, 'dihedral_max': 90.0, 'radius_edge_max': 0.87, 'radius_edge_mean': 0.87, 'min_volume': 0.17, 'negative_tets': 0}
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpmesh._util.parallel import cpu_view, launch_split
from warpmesh.kernels import stuffing as K

SUMMARY_CHUNK = 1 << 20  # tetrahedra per chunk of tet_quality_summary

__all__ = ["dihedral_angles", "radius_edge_ratio", "signed_volumes", "tet_quality", "tet_quality_summary"]

#: local edges (i, j) of a tetrahedron and the two vertices (k, l) off each
_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
_OFF = ((2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1))


def signed_volumes(points, tets) -> np.ndarray:
    """(m,) signed volumes det(b - a, c - a, d - a) / 6, float64.

    Computed in a Warp kernel split across the CPU cores, with numpy's operations in numpy's
    order (``np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6``, the same numbers bit
    for bit), with no (m, 4, 3) gather: 0.1 s instead of 1.7 s on 12.7 M tetrahedra.

    Raises
    ------
    ValueError
        ``points`` not (n, 3), ``tets`` not (m, 4), or an index of ``tets`` outside the points.

    Examples
    --------
    >>> signed_volumes([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 1, 2, 3], [0, 2, 1, 3]]).tolist()
    [0.16666666666666666, -0.16666666666666666]
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    t = np.ascontiguousarray(tets, dtype=np.int64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"expected 'points' of shape (n, 3), got {pts.shape}")
    if t.ndim != 2 or t.shape[1] != 4:
        raise ValueError(f"expected 'tets' of shape (m, 4), got {t.shape}")
    out = np.empty(len(t))
    if not len(t):
        return out
    _check_indices(t, len(pts))
    launch_split(K.signed_volumes_kernel, len(t),
                 [cpu_view(pts, wp.vec3d), cpu_view(t.reshape(-1), wp.int64)], [cpu_view(out, wp.float64)])
    return out


def dihedral_angles(points, tets) -> np.ndarray:
    """(m, 6) interior dihedral angles (radians) at the edges (01, 02, 03, 12, 13, 23).

    The angle at edge ij is between the two faces holding it: pi minus the angle of their
    outward normals. A flat tetrahedron has angles 0 and pi; orientation does not matter.
    """
    p = np.asarray(points, dtype=np.float64)[np.asarray(tets, dtype=np.int64)]
    out = np.empty((len(p), 6))
    for e, ((i, j), (k, l)) in enumerate(zip(_EDGES, _OFF)):
        a = p[:, j] - p[:, i]
        # components of the edges to k and l orthogonal to the edge ij
        aa = np.einsum("ij,ij->i", a, a)[:, None]
        aa = np.where(aa > 0, aa, 1.0)
        u = p[:, k] - p[:, i]
        v = p[:, l] - p[:, i]
        u = u - np.einsum("ij,ij->i", u, a)[:, None] / aa * a
        v = v - np.einsum("ij,ij->i", v, a)[:, None] / aa * a
        nu = np.linalg.norm(u, axis=1)
        nv = np.linalg.norm(v, axis=1)
        cos = np.einsum("ij,ij->i", u, v) / np.where(nu * nv > 0, nu * nv, 1.0)
        out[:, e] = np.arccos(np.clip(cos, -1.0, 1.0))
    return out


def radius_edge_ratio(points, tets) -> np.ndarray:
    """(m,) circumradius / shortest edge (sqrt(6)/4 = 0.612 for the regular tetrahedron;
    infinite for a flat one)."""
    p = np.asarray(points, dtype=np.float64)[np.asarray(tets, dtype=np.int64)]
    a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    num = (np.einsum("ij,ij->i", a, a)[:, None] * np.cross(b, c) + np.einsum("ij,ij->i", b, b)[:, None]
           * np.cross(c, a) + np.einsum("ij,ij->i", c, c)[:, None] * np.cross(a, b))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.linalg.norm(num, axis=1) / np.abs(2.0 * det)
    lengths = np.stack([np.linalg.norm(p[:, j] - p[:, i], axis=1) for i, j in _EDGES], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(det != 0, r / lengths.min(axis=1), np.inf)


def _check_indices(tets: np.ndarray, n: int) -> None:
    """A kernel reads ``points[tets]`` unchecked: refuse an index outside [0, n) by name."""
    if tets.size and (int(tets.min()) < 0 or int(tets.max()) >= n):
        raise ValueError(f"'tets' holds indices outside [0, {n}) (the points)")


def tet_quality(points, tets, device="cpu") -> np.ndarray:
    """(m, 4) float64 per tetrahedron, computed in a Warp kernel (split across the CPU cores): smallest and largest
    dihedral angle (degrees), radius-edge ratio, signed volume. A ValueError names ``tets``
    when an index lies outside the points."""
    wpts = _device_points(points, device)
    tets = np.asarray(tets)
    _check_indices(tets, wpts.shape[0])
    tets = np.ascontiguousarray(tets, dtype=np.int32).reshape(-1, 4)
    if not len(tets):
        return np.zeros((0, 4))
    q = _quality(wpts, tets, device)
    q[:, :2] = np.degrees(q[:, :2])
    return q


def _device_points(points, device) -> wp.array:
    """``points`` as float64 vectors on ``device``: the host memory itself on the CPU (no copy
    when already contiguous float64)."""
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    return cpu_view(pts, wp.vec3d) if wp.get_device(device).is_cpu else wp.array(pts, dtype=wp.vec3d, device=device)


def _quality(wpts: wp.array, tets: np.ndarray, device, out: np.ndarray | None = None) -> np.ndarray:
    """:func:`tet_quality` of ``tets`` ((m, 4) int32, contiguous) with the angles in radians,
    into ``out`` ((m, 4) float64) when given."""
    out = np.empty((len(tets), 4)) if out is None else out
    if wp.get_device(device).is_cpu:
        launch_split(K.tet_quality_kernel, len(tets), [wpts, cpu_view(tets, wp.vec4i)], [cpu_view(out, wp.vec4d)],
                     device)
    else:
        q = wp.empty(len(tets), dtype=wp.vec4d, device=device)
        launch_split(K.tet_quality_kernel, len(tets), [wpts, wp.array(tets, dtype=wp.vec4i, device=device)], [q],
                     device)
        out[:] = q.numpy()  # sync point
    return out


def tet_quality_summary(points, tets, device="cpu") -> dict:
    """Dihedral range (degrees), radius-edge ratio and volumes of a tetrahedral mesh
    (:func:`tet_quality`; :func:`dihedral_angles` is the numpy reference).

    Returns
    -------
    dict
        ``dihedral_min``, ``dihedral_max`` (degrees), ``radius_edge_max``, ``radius_edge_mean``,
        ``min_volume``, ``negative_tets`` (count of tetrahedra with volume <= 0).
    """
    if not len(tets):
        return {"dihedral_min": None, "dihedral_max": None, "radius_edge_max": None, "radius_edge_mean": None,
                "min_volume": None, "negative_tets": 0}
    # chunk by chunk, each reduced at once: no (m, 4) array of the whole mesh (a big mesh's
    # quality would otherwise be its largest allocation)
    wpts, tets = _device_points(points, device), np.asarray(tets)
    _check_indices(tets, wpts.shape[0])
    m = len(tets)
    step = min(m, SUMMARY_CHUNK)
    buffer = np.empty((step, 4))
    lo, hi, re_max, re_sum, v_min, negative = np.inf, -np.inf, -np.inf, 0.0, np.inf, 0
    for a in range(0, m, step):
        chunk = np.ascontiguousarray(tets[a:a + step], dtype=np.int32).reshape(-1, 4)
        q = _quality(wpts, chunk, device, buffer[:len(chunk)])
        lo, hi = min(lo, float(q[:, 0].min())), max(hi, float(q[:, 1].max()))
        re_max, re_sum = max(re_max, float(q[:, 2].max())), re_sum + float(q[:, 2].sum())
        v_min, negative = min(v_min, float(q[:, 3].min())), negative + int((q[:, 3] <= 0).sum())
    # (degrees of the extreme radians: the conversion is monotone, so these are the extremes in degrees)
    return {"dihedral_min": float(np.degrees(lo)), "dihedral_max": float(np.degrees(hi)),
            "radius_edge_max": re_max, "radius_edge_mean": re_sum / m, "min_volume": v_min, "negative_tets": negative}
