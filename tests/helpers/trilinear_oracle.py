"""Mesher-independent oracle for the topology of the trilinear interpolant in one cell.

The 8 corner values (corner ``i`` at ``(i & 1, (i >> 1) & 1, (i >> 2) & 1)``) define
``F(x, y, z)`` on the unit cube. The oracle samples ``F`` on a lattice of ``n^3`` nodes
(both cube faces included), labels the 6-connected components of ``{F > 0}`` and of
``{F <= 0}`` and reports which corners share a component: the *corner partition*.
Every component of either set holds a corner (``F`` is harmonic, so it has no interior
extremum, and on a face or an edge the same holds), so the partition names all the
regions of the cell; the surface components are the pairs of adjacent regions. Nothing
here knows about tables or triangles.

A lattice resolves the regions when their necks are several nodes wide. Necks are thin
only near a critical value: a corner value, the saddle value of a face, or the value of
``F`` at a critical point inside the cube (at most two for a trilinear function).
``decided_partition`` therefore calls a sample *undecided* when any of these values is
within ``margin`` of 0, or when two lattice resolutions disagree.

Sign convention: inside is ``F > 0``, outside ``F <= 0`` (warpmesh).
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = [
    "CORNER_OFFSETS",
    "FACE_CORNERS",
    "sample",
    "corner_partition",
    "face_saddles",
    "body_critical_points",
    "critical_values",
    "decided_partition",
    "face_joined",
]

#: (8, 3) corner positions
CORNER_OFFSETS = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)])
#: the 6 faces as 4 corners in cyclic order (any orientation): x = 0, 1, y = 0, 1, z = 0, 1
FACE_CORNERS = [(0, 2, 6, 4), (1, 3, 7, 5), (0, 1, 5, 4), (2, 3, 7, 6), (0, 1, 3, 2), (4, 5, 7, 6)]


def sample(values, n: int) -> np.ndarray:
    """``(n, n, n)`` array of ``F`` at the nodes ``(i, j, k) / (n - 1)``, indexed [x, y, z]."""
    v = np.asarray(values, dtype=np.float64)
    t = np.linspace(0.0, 1.0, n)
    s = 1.0 - t
    rows = [v[k] * s + v[k + 1] * t for k in (0, 2, 4, 6)]  # along x at (y, z) = 00, 10, 01, 11
    bottom = rows[0][:, None] * s + rows[1][:, None] * t  # [x, y] at z = 0
    top = rows[2][:, None] * s + rows[3][:, None] * t
    return bottom[:, :, None] * s + top[:, :, None] * t


def corner_partition(values, n: int) -> frozenset:
    """Corners grouped by the lattice component of their side, as a frozenset of frozensets."""
    f = sample(values, n)
    labels = [ndimage.label(f > 0)[0], ndimage.label(f <= 0)[0]]
    groups = {}
    for i, (x, y, z) in enumerate(CORNER_OFFSETS * (n - 1)):
        side = 0 if values[i] > 0 else 1
        groups.setdefault((side, int(labels[side][x, y, z])), set()).add(i)
    return frozenset(frozenset(g) for g in groups.values())


def face_saddles(values) -> list[float]:
    """Saddle values of the bilinear interpolant on each face whose saddle lies in the face."""
    out = []
    for a, b, c, d in FACE_CORNERS:
        va, vb, vc, vd = (float(values[k]) for k in (a, b, c, d))
        den = va - vb + vc - vd
        if den == 0.0:
            continue
        s, t = (va - vd) / den, (va - vb) / den  # saddle in the face's (b - a, d - a) frame
        if 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0:
            out.append((va * vc - vb * vd) / den)
    return out


def _coefficients(values):
    """F = a + b x + c y + d z + e xy + f yz + g xz + h xyz."""
    v = np.asarray(values, dtype=np.float64)
    return (v[0], v[1] - v[0], v[2] - v[0], v[4] - v[0], v[3] - v[2] - v[1] + v[0],
            v[6] - v[4] - v[2] + v[0], v[5] - v[4] - v[1] + v[0],
            v[7] - v[6] - v[5] - v[3] + v[4] + v[2] + v[1] - v[0])


def _gradient(coef, p) -> np.ndarray:
    a, b, c, d, e, f, g, h = coef
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return np.stack([b + e * y + g * z + h * y * z, c + e * x + f * z + h * x * z, d + f * y + g * x + h * x * y], -1)


def body_critical_points(values) -> np.ndarray:
    """(k, 3) critical points of F in the closed cube, in closed form.

    Eliminating y and z from ``F_y = F_z = 0`` (``y = -(d + g x) / (f + h x)``,
    ``z = -(c + e x) / (f + h x)``) leaves ``F_x = 0`` as the quadratic
    ``h (b h - e g) x^2 + 2 f (b h - e g) x + b f^2 - d e f - c f g + c d h = 0``. The
    same is done with the roles of the axes rotated (so that a vanishing ``f + h x`` in
    one frame is covered by another) and every candidate is checked.
    """
    a, b, c, d, e, f, g, h = _coefficients(values)
    # (linear x, y, z), (xy, yz, xz) per rotation of the axes, and how to put x, y, z back
    frames = [((b, c, d), (e, f, g), (0, 1, 2)), ((c, d, b), (f, g, e), (2, 0, 1)), ((d, b, c), (g, e, f), (1, 2, 0))]
    found = []
    for (lb, lc, ld), (pe, pf, pg), back in frames:
        k = lb * h - pe * pg
        for x in np.roots([h * k, 2 * pf * k, lb * pf * pf - ld * pe * pf - lc * pf * pg + lc * ld * h]):
            if abs(x.imag) > 1e-12 or abs(pf + h * x.real) < 1e-14:
                continue
            x = x.real
            m = pf + h * x
            q = (x, -(ld + pg * x) / m, -(lc + pe * x) / m)
            found.append([q[back[0]], q[back[1]], q[back[2]]])
    pts = np.array(found, dtype=np.float64).reshape(-1, 3)
    scale = max(1.0, float(np.max(np.abs(values))))
    keep = (np.linalg.norm(_gradient((a, b, c, d, e, f, g, h), pts), axis=-1) < 1e-9 * scale) & np.all(
        (pts >= -1e-9) & (pts <= 1 + 1e-9), axis=-1)
    return np.unique(np.round(pts[keep], 9), axis=0) if keep.any() else pts[:0]


def _evaluate(values, p) -> np.ndarray:
    a, b, c, d, e, f, g, h = _coefficients(values)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    return a + b * x + c * y + d * z + e * x * y + f * y * z + g * x * z + h * x * y * z


def critical_values(values) -> np.ndarray:
    """Corner values, face saddle values and values at critical points inside the cube."""
    body = _evaluate(values, body_critical_points(values))
    return np.concatenate([np.asarray(values, dtype=np.float64), face_saddles(values), body])


def decided_partition(values, resolutions=(48, 64), margin: float = 1e-3):
    """The corner partition, or None when the sample is undecided (see module doc).

    >>> sorted(sorted(g) for g in decided_partition([1, -1, -1, -1, -1, -1, -1, 1], (16, 24)))
    [[0], [1, 2, 3, 4, 5, 6], [7]]
    """
    if np.any(np.abs(critical_values(values)) < margin):
        return None
    parts = {corner_partition(values, n) for n in resolutions}
    return parts.pop() if len(parts) == 1 else None


def face_joined(values, face, n: int = 65) -> bool:
    """Whether the two diagonal corners ``face[0]`` and ``face[2]`` of a face (4 corners,
    cyclic) are in one component of their side of the sampled bilinear interpolant."""
    a, b, c, d = (float(values[k]) for k in face)
    s = np.linspace(0.0, 1.0, n)
    u, w = s[:, None], s[None, :]
    f = a * (1 - u) * (1 - w) + b * u * (1 - w) + c * u * w + d * (1 - u) * w
    mask = f > 0 if a > 0 else f <= 0
    lab = ndimage.label(mask)[0]
    return bool(lab[0, 0] == lab[-1, -1] != 0)
