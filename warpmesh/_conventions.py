"""Conventions that every warpmesh module keeps, defined once.

Sign
    f > 0 inside the domain, f = 0 on its boundary, f < 0 outside [FG eq. 16.16].
    A grid node is *inside* when its sampled value is strictly positive; a node with
    f == 0 is treated as outside, which dilates the surface locally [FG §16.4.2].
Winding
    Surface triangles are counter-clockwise seen from outside: the right-hand normal
    ``(p1 - p0) x (p2 - p0)`` points out of the domain, towards f < 0. Tetrahedra and
    planar triangles have positive volume / area.
Index dtype
    Host-side connectivity is ``INDEX_DTYPE`` (int64, as trimesh and meshio use);
    device-side connectivity is int32.
Coordinates
    Host-side points are ``REAL_DTYPE`` (float64); device-side points are float32.
"""

from __future__ import annotations

import numpy as np

INDEX_DTYPE = np.int64
REAL_DTYPE = np.float64

#: normalisation of the shape measure Q_K = ALPHA_TRIANGLE * h_max / rho_K [FG eq. 16.15]
#: so that an equilateral triangle scores exactly 1 (larger is worse).
ALPHA_TRIANGLE = np.sqrt(3.0) / 6.0

#: normalisation of Q_K for tetrahedra [FG eq. 16.15], ALPHA_TETRA * h_max / rho_K:
#: the regular tetrahedron scores exactly 1.
ALPHA_TETRA = np.sqrt(6.0) / 12.0

#: root positions along a crossing edge are clamped to [EDGE_T_MIN, 1 - EDGE_T_MIN] so
#: that a node lying exactly on the surface never yields coincident vertices or
#: zero-area triangles ("dilating", [FG §16.4.2]). Fraction of the edge length.
EDGE_T_MIN = 1.0e-3

#: relative tolerance for geometric predicates on the host (area, volume tests)
REL_TOL = 1.0e-12

DEFAULT_DEVICE = "cpu"

#: refs of the triangles of an extracted surface: on f = 0 (SURFACE_REF), and on the
#: caps that close it where it meets the bounds (CAP_REF)
SURFACE_REF = 1
CAP_REF = 2
