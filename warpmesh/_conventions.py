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
    A compact :class:`~warpmesh.mesh.Mesh` (``compact=True``: the label-volume surfaces
    of ``interfaces="shared"``) *keeps* float32 points, int32 cells and narrow refs, as
    the kernels wrote them, and still *gives* float64 / int64 through its accessors
    (copies made on first use), so no code sees an int32 index it could overflow; its
    cell data keeps its type (``label_above`` int16: read it with
    ``multilabel.shared_labels``, which gives int64).
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

#: the clearance delta of linearly placed vertices: a root that linear interpolation puts
#: closer than delta (a fraction of the edge) to a grid node is moved out to delta
#: ("dilating" the surface off the node, [FG §16.4.2]). Connectivity is that of delta = 0
#: (no classification changes); a vertex moves at most delta |edge| along its edge. Three
#: points inside three distinct edges of a cube or a tetrahedron are never collinear, so
#: with t in [delta, 1 - delta] no table triangle can flatten; maximising Q_K over the
#: tables gives, for cubic cells (times h_max / h_min otherwise), worst Q about 0.82 / delta
#: for "mc" and the edge triangles of "mc33" (16.4 at 0.05, 8.29 at 0.1) and 1.1 / delta for
#: "mt" (23.5 at 0.05, 11.2 at 0.1); smallest angle about 48 delta degrees for "mc", "mc33"
#: (2.37 at 0.05) and 29 delta for "mt" (1.4 at 0.05) (tests/surface/test_slivers.py).
#: "mc" and "mc33" keep EDGE_T_MIN at an end where no triangle can have a second vertex
#: next to the node: a capped node, and for shapes a node ending no other crossing edge
#: that shares a cell with the vertex's edge (a plane through grid nodes stays on them;
#: volumes, cut in slabs whose seams lack the neighbour plane, clamp there too). Roots
#: refined by bisection or Newton keep EDGE_T_MIN: they stay on f = 0, without the bound.
#: 0.05 trades a 50x better worst triangle than EDGE_T_MIN for at most 0.05 |edge| of
#: distance to f = 0 (first order in h where linear interpolation is second order: a finer
#: uniform grid must still reach the adaptive octree's chord error, test_adaptive.py).
NODE_CLEARANCE = 0.05

#: relative tolerance for geometric predicates on the host (area, volume tests)
REL_TOL = 1.0e-12

DEFAULT_DEVICE = "cpu"

#: refs of the triangles of an extracted surface: on f = 0 (SURFACE_REF), and on the
#: caps that close it where it meets the bounds (CAP_REF)
SURFACE_REF = 1
CAP_REF = 2

#: the key of ``mesh.info`` holding the sampling grid of a volume's surface (origin, spacing,
#: shape): written by the surface stage, read by the label smoothing and optimisation
GRID_INFO = "grid"
