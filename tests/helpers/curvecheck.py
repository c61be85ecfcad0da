"""check_curve: the shared correctness check of a polyline mesh of an implicit curve.

Everything is measured against the exact function through :class:`PlanarField`:
distances by Newton projection with foot-point steps, the reference curve as the sign
changes of a fine grid (``ref_resolution`` cells along the longer side) projected onto
f = 0. Used by every test of the 2D curve methods.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from warpmesh.frep.planar_field import PlanarField
from warpmesh.cells.intersections import find_segment_intersections
from warpmesh.planar.polyline import components


def reference_points(field: PlanarField, resolution: int = 1024) -> np.ndarray:
    """Points on f = 0: crossings of the edges of a fine grid, projected by Newton steps."""
    (x0, y0), (x1, y1) = field.bounds
    ext = field.bounds[1] - field.bounds[0]
    step = ext.max() / resolution
    nx, ny = int(np.ceil(ext[0] / step)), int(np.ceil(ext[1] / step))
    xs, ys, f = field.grid(nx, ny)
    pts = []
    for axis in (0, 1):
        a = f[:-1, :] if axis == 0 else f[:, :-1]
        b = f[1:, :] if axis == 0 else f[:, 1:]
        i, j = np.nonzero((a > 0) != (b > 0))
        t = a[i, j] / (a[i, j] - b[i, j])
        px = xs[i] + (t * (xs[1] - xs[0]) if axis == 0 else 0.0)
        py = ys[j] + (t * (ys[1] - ys[0]) if axis == 1 else 0.0)
        pts.append(np.column_stack([px, py]))
    p = np.concatenate(pts)
    return field.project(p, max_step=2 * step)


def point_segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    t = np.clip(np.einsum("ij,ij->i", q - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
    return np.linalg.norm(q - (a + t[:, None] * d), axis=1)


def distance_to_polyline(q: np.ndarray, points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Exact distance from each query point to the nearest of ``segments``.

    A segment of length <= L whose midpoint is farther than d0 + L / 2 from q (d0: the
    distance to the nearest midpoint, an upper bound of the answer) cannot be the nearest,
    so only the segments with midpoints within that radius are measured.
    """
    a, b = points[segments[:, 0]], points[segments[:, 1]]
    mid, half = 0.5 * (a + b), 0.5 * float(np.linalg.norm(b - a, axis=1).max())
    tree = cKDTree(mid)
    d0, _ = tree.query(q)
    cand = tree.query_ball_point(q, d0 + half + 1e-12)
    counts = np.array([len(c) for c in cand])
    seg = np.concatenate([np.asarray(c, dtype=np.int64) for c in cand])
    qi = np.repeat(np.arange(len(q)), counts)
    d = point_segment_distance(q[qi], a[seg], b[seg])
    out = np.full(len(q), np.inf)
    np.minimum.at(out, qi, d)
    return out


def check_curve(mesh, shape, bounds, *, n_components: int | None = None, hausdorff: float | None = None,
                closed: bool | None = True, oriented: bool = True, ref_resolution: int = 1024,
                singular=()) -> dict:
    """Assert that ``mesh`` (line cells) is a valid polyline of f = 0 and return its measures.

    Checks: 2D points, a "line" block with valid indices and no zero-length segment; no two
    segments crossing; in-degree = out-degree at every vertex when ``closed`` (open ends only
    on the box boundary otherwise); ``n_components``; the domain on the left of every segment
    whose midpoint is regular (farther than 2 segment lengths from the points ``singular``);
    the two-sided Hausdorff distance to the exact curve below ``hausdorff``.
    """
    field = PlanarField(shape, bounds)
    assert mesh.dim == 2, f"expected 2D points, got dim {mesh.dim}"
    assert set(mesh.cells) == {"line"}, f"expected only line cells, got {list(mesh.cells)}"
    p, s = np.asarray(mesh.points), np.asarray(mesh.cells["line"])
    assert len(s) > 0 and s.min() >= 0 and s.max() < len(p)
    length = np.linalg.norm(p[s[:, 1]] - p[s[:, 0]], axis=1)
    assert length.min() > 0, "zero-length segment"
    crossing = find_segment_intersections(p, s)
    assert len(crossing) == 0, f"{len(crossing)} pairs of segments intersect, e.g. {crossing[:3].tolist()}"
    indeg, outdeg = np.bincount(s[:, 1], minlength=len(p)), np.bincount(s[:, 0], minlength=len(p))
    ends = np.flatnonzero(indeg != outdeg)
    if closed:
        assert len(ends) == 0, f"{len(ends)} vertices where the polyline is not closed"
    else:
        lo, hi = field.bounds
        gap = np.minimum(np.abs(p[ends] - lo), np.abs(p[ends] - hi)).min(axis=1)
        assert np.all(gap < 1e-6 * field.size), "an open end inside the box"
    n_comp, _ = components(s, len(p))
    if n_components is not None:
        assert n_comp == n_components, f"expected {n_components} components, got {n_comp}"
    mid = 0.5 * (p[s[:, 0]] + p[s[:, 1]])
    _, g = field.value_gradient(mid)
    d = p[s[:, 1]] - p[s[:, 0]]
    left = -d[:, 1] * g[:, 0] + d[:, 0] * g[:, 1]
    regular = np.ones(len(s), bool)
    for q in np.asarray(singular, float).reshape(-1, 2):
        regular &= np.linalg.norm(mid - q, axis=1) > 2 * length.max()
    wrong = int(np.count_nonzero(left[regular] <= 0))
    if oriented:
        assert wrong == 0, f"{wrong} segments with the domain on their right"
    # Hausdorff: mesh -> curve on 5 points per segment, curve -> mesh on the reference points
    t = np.linspace(0, 1, 5)
    samples = (p[s[:, 0], None] * (1 - t)[None, :, None] + p[s[:, 1], None] * t[None, :, None]).reshape(-1, 2)
    d_mesh = float(field.distance(samples).max())
    ref = reference_points(field, ref_resolution)
    d_curve = float(distance_to_polyline(ref, p, s).max()) if len(ref) else 0.0
    out = {"components": n_comp, "to_curve": d_mesh, "from_curve": d_curve, "hausdorff": max(d_mesh, d_curve),
           "wrong_orientation": wrong, "n_vertices": len(np.unique(s)), "n_segments": len(s),
           "max_length": float(length.max()), "min_length": float(length.min())}
    if hausdorff is not None:
        assert out["hausdorff"] <= hausdorff, f"Hausdorff distance {out['hausdorff']:.3g} > {hausdorff:.3g}"
    return out
