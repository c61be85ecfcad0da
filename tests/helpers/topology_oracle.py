"""Mesher-independent oracle for the topology of implicit solids.

The oracle samples ``f`` on a regular node grid, keeps the set ``S`` of nodes on the
requested side of the zero set, and computes topological invariants of the cubical
complex ``K(S)`` made of every grid cell (node, edge, square, cube) whose corners all
lie in ``S``. Nothing here knows about triangles or any warpmesh code, so the values
can be compared with what the mesher extracts.

Why ``K(S)`` is the right object
    ``K(S)`` is the "6-connected" digitisation of the region: two nodes of ``S`` are
    joined when they share a grid edge. When the grid resolves the region (every part
    and every neck/hole is several cells wide), ``K(S)`` is homotopy equivalent to the
    solid ``M = closure{side * f > 0} ∩ box``, so it has the same Euler characteristic
    and the same components. Thin features (a neck narrower than a cell) are where the
    digitisation can be wrong; check stability over several ``n`` (see
    ``DEGREE_SIX_EXPECTED`` for an example).

From solid to surface
    For a compact 3-manifold-with-boundary ``M``, ``chi(boundary M) = 2 chi(M)``
    (double ``M`` along its boundary: ``0 = chi(DM) = 2 chi(M) - chi(boundary M)``
    since closed odd-dimensional manifolds have ``chi = 0``). So a closed surface
    bounding the solid — the zero set closed up by the box faces where the region
    meets the box — has ``chi = 2 * solid_euler(...)``; each closed orientable
    component of genus g contributes ``2 - 2g``.
    If the mesher leaves the surface open at the box faces, the open surface
    ``Sigma = {f = 0} ∩ box`` satisfies ``chi(Sigma) = 2 chi(M) - chi(M ∩ box faces)``
    (``boundary M = Sigma ∪ (M ∩ box faces)``, glued along circles, chi 0):
    see ``open_surface_euler``.

Sign convention: f > 0 inside (warpmesh convention). ``side=+1`` is ``{f > 0}``;
``side=-1`` is ``{f < 0}`` (the same as ``side=+1`` applied to ``-f``). Nodes where
``f == 0`` belong to neither side (the mesher counts them as outside; this only matters
for shapes whose zero set passes exactly through grid nodes).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy import ndimage

__all__ = [
    "sample_mask",
    "mask_euler",
    "solid_euler",
    "surface_euler",
    "solid_components",
    "boundary_trace_euler",
    "open_surface_euler",
    "degree_six",
    "csg_part",
    "DEGREE_SIX_BOUNDS",
    "DEGREE_SIX_SMALL_BOUNDS",
    "DEGREE_SIX_EXPECTED",
    "CSG_PART_BOUNDS",
    "CSG_PART_EXPECTED",
]

Bounds = tuple[tuple[float, float, float], tuple[float, float, float]]

#: max number of grid nodes evaluated per call of ``f`` (bounds temporaries' memory)
_CHUNK_NODES = 4_000_000


def _resolution(n) -> tuple[int, int, int]:
    if np.ndim(n) == 0:
        n = (int(n),) * 3
    n = tuple(int(k) for k in n)
    if len(n) != 3 or min(n) < 2:
        raise ValueError(f"need 3 axis resolutions >= 2, got {n}")
    return n


def sample_mask(f: Callable, bounds: Bounds, n, side: int = 1) -> np.ndarray:
    """Boolean ``(nx, ny, nz)`` array: nodes of the closed box where ``side * f > 0``.

    ``f(x, y, z)`` is called with broadcastable arrays (slabs of ``x``, so memory stays
    bounded for ``n = 300`` and beyond). ``n`` is an int or a 3-tuple; the grid has
    ``n`` nodes per axis including both box faces.
    """
    if side not in (1, -1):
        raise ValueError("side must be +1 ({f > 0}) or -1 ({f < 0})")
    nx, ny, nz = _resolution(n)
    (x0, y0, z0), (x1, y1, z1) = bounds
    xs = np.linspace(x0, x1, nx)
    ys = np.linspace(y0, y1, ny)[None, :, None]
    zs = np.linspace(z0, z1, nz)[None, None, :]
    mask = np.empty((nx, ny, nz), dtype=bool)
    step = max(1, _CHUNK_NODES // (ny * nz))
    for i in range(0, nx, step):
        xi = xs[i : i + step, None, None]
        val = np.asarray(f(xi, ys, zs), dtype=np.float64)
        val = np.broadcast_to(val, (xi.shape[0], ny, nz))
        mask[i : i + step] = (val > 0.0) if side == 1 else (val < 0.0)
    return mask


def mask_euler(mask: np.ndarray) -> int:
    """Euler characteristic V - E + F - C of the cubical complex of a 3D boolean mask.

    Cells are grid nodes/edges/squares/cubes whose corners are all ``True``. A 2D mask
    gives V - E + F (the squares), a 1D mask V - E.
    """
    m = np.asarray(mask, dtype=bool)
    if m.ndim == 1:
        return int(np.count_nonzero(m)) - int(np.count_nonzero(m[1:] & m[:-1]))
    if m.ndim == 2:
        ex = m[1:, :] & m[:-1, :]
        ey = m[:, 1:] & m[:, :-1]
        sq = ex[:, 1:] & ex[:, :-1]
        return int(np.count_nonzero(m) - np.count_nonzero(ex) - np.count_nonzero(ey)
                   + np.count_nonzero(sq))
    if m.ndim != 3:
        raise ValueError("mask must be 1-, 2- or 3-dimensional")
    v = np.count_nonzero(m)
    ex = m[1:] & m[:-1]              # edges along x
    ey = m[:, 1:] & m[:, :-1]        # edges along y
    ez = m[:, :, 1:] & m[:, :, :-1]  # edges along z
    e = np.count_nonzero(ex) + np.count_nonzero(ey) + np.count_nonzero(ez)
    fxy = ex[:, 1:] & ex[:, :-1]
    del ex
    fyz = ey[:, :, 1:] & ey[:, :, :-1]
    del ey
    fxz = ez[1:] & ez[:-1]
    del ez
    c = np.count_nonzero(fxy[:, :, 1:] & fxy[:, :, :-1])
    faces = np.count_nonzero(fxy) + np.count_nonzero(fyz) + np.count_nonzero(fxz)
    return int(v - e + faces - c)


def solid_euler(f: Callable, bounds: Bounds, n, side: int = 1) -> int:
    """Euler characteristic of the solid ``{side * f > 0} ∩ box`` (cubical complex).

    Samples ``f`` on an ``n^3`` node grid over the closed box
    ``bounds = ((x0, y0, z0), (x1, y1, z1))``, takes the node set S where
    ``side * f > 0`` and returns ``V - E + F - C`` with V = nodes in S, E = grid edges
    with both ends in S, F = grid squares with 4 corners in S, C = grid cubes with 8
    corners in S. For a compact 3-manifold-with-boundary M, chi(boundary M) = 2 chi(M),
    so the expected Euler characteristic of the closed bounding surface (zero set
    closed by the box faces where the region meets the box) is ``2 * solid_euler``.
    Examples: ball 1, solid torus 0, ball with k through holes 1 - k, spherical shell
    2 (its boundary is two spheres), ``k`` disjoint balls ``k``.
    """
    return mask_euler(sample_mask(f, bounds, n, side))


def surface_euler(f: Callable, bounds: Bounds, n, side: int = 1) -> int:
    """Euler characteristic of the closed surface bounding the solid: ``2 * solid_euler``."""
    return 2 * solid_euler(f, bounds, n, side)


def solid_components(f: Callable, bounds: Bounds, n, side: int = 1) -> int:
    """Number of 6-connected components of the node set ``{side * f > 0}`` in the box."""
    _, count = ndimage.label(sample_mask(f, bounds, n, side))
    return int(count)


def _boundary_trace_euler_of_mask(m: np.ndarray) -> int:
    # chi of the union of the 6 face complexes = sum(faces) - sum(edges) + sum(corners)
    # (each box edge lies on 2 faces; each corner on 3 faces and 3 edges).
    faces = [m[0], m[-1], m[:, 0], m[:, -1], m[:, :, 0], m[:, :, -1]]
    edges = [m[i, j, :] for i in (0, -1) for j in (0, -1)]
    edges += [m[i, :, k] for i in (0, -1) for k in (0, -1)]
    edges += [m[:, j, k] for j in (0, -1) for k in (0, -1)]
    corners = [m[i, j, k] for i in (0, -1) for j in (0, -1) for k in (0, -1)]
    return int(sum(mask_euler(a) for a in faces) - sum(mask_euler(a) for a in edges)
               + sum(bool(c) for c in corners))


def boundary_trace_euler(f: Callable, bounds: Bounds, n, side: int = 1) -> int:
    """Euler characteristic of the trace ``M ∩ (box faces)`` of the solid on the box."""
    return _boundary_trace_euler_of_mask(sample_mask(f, bounds, n, side))


def open_surface_euler(f: Callable, bounds: Bounds, n, side: int = 1) -> int:
    """Euler characteristic of the open surface ``{f = 0} ∩ box`` (not closed by the box).

    ``chi(Sigma) = 2 chi(M) - chi(M ∩ box faces)``. Equals ``surface_euler`` when the
    region does not touch the box.
    """
    m = sample_mask(f, bounds, n, side)
    return 2 * mask_euler(m) - _boundary_trace_euler_of_mask(m)


# --------------------------------------------------------------------------------------
# Degree-six surface of Frey & George §16.4.5
# --------------------------------------------------------------------------------------

def degree_six(x, y, z):
    """(x^2+y^2-4)(x^2+z^2-4)(y^2+z^2-4) - 4.0078 (f > 0 inside)."""
    x2, y2, z2 = x * x, y * y, z * z
    return (x2 + y2 - 4.0) * (x2 + z2 - 4.0) * (y2 + z2 - 4.0) - 4.0078


DEGREE_SIX_BOUNDS: Bounds = ((-3.0, -3.0, -3.0), (3.0, 3.0, 3.0))

#: a smaller box with the same topology and comfortable margins (see below). Do NOT use
#: [-2.2, 2.2]^3: it is (to 5 digits) the critical box of this surface.
DEGREE_SIX_SMALL_BOUNDS: Bounds = ((-2.5, -2.5, -2.5), (2.5, 2.5, 2.5))

DEGREE_SIX_EXPECTED = {
    "inside": {"components": 1, "solid_euler": -4, "surface_euler": -8},
    "outside": {"components": 1, "solid_euler": 1, "surface_euler": 2},
}
"""Expected topology of f = P - c, P = a*b*d, a = x^2+y^2-4, b = x^2+z^2-4,
d = y^2+z^2-4, c = 4.0078 (Frey & George §16.4.5), in the closed box [-3, 3]^3
(``DEGREE_SIX_BOUNDS``); identical in [-2.5, 2.5]^3 (``DEGREE_SIX_SMALL_BOUNDS``).

=========================  ==========  =========  ===================================
region                     components  solid chi  closed surface chi (2 * solid chi)
=========================  ==========  =========  ===================================
"inside"  {f > 0} ∩ box    1           -4         -8  (one genus-5 surface)
"outside" {f < 0} ∩ box    1            1          2  (one sphere)
=========================  ==========  =========  ===================================

Both closed surfaces consist of the open surface Sigma = {f = 0} ∩ box plus the region's
trace on the box faces. The inside meets the box surface in a sphere minus 6 discs
(chi -4), the outside in the 6 discs (chi 6), so chi(Sigma) = -8 - (-4) = 2 - 6 = -4
(``open_surface_euler``): Sigma is a genus-5 surface with 6 holes.

Reasoning. a, b, d are the radius-2 cylinders about the z, y, x axes (negative inside).
P > 0 iff none or exactly two of the factors are negative.

* Exactly two negative (inside two cylinders, outside the third): 12 lens-shaped
  pieces around (±1.63, ±1.63, 0) and permutations. There P = a|b||d| <= max over
  p, q of (4-p-q) p q = 64/27 ≈ 2.370 (p = 4-x^2, q = 4-y^2; z = 0 is best, p = q = 4/3).
  These are the only nondegenerate local maxima of P; as c = 4.0078 > 64/27 the 12
  lenses vanish entirely.
* Where two factors vanish (P = 0, a degenerate critical set) the pieces of {P > 0}
  touch each other; any c > 0 separates them (f = -c there).
* Hence {f > 0} lies outside all three cylinders. In each closed octant of the box a, b,
  d > 0 grow with |x|, |y|, |z|, so P grows along segments to the box corner and
  {P > c} ∩ octant is star-shaped about that corner (contractible). Neighbouring octant
  pieces share the contractible patch {P > c, |u|, |v| > 2} of a coordinate plane;
  three never meet (P <= 0 on the axes). The nerve is the cube's edge graph:
  chi = 8 - 12 = -4, a thickened wire frame of the 12 box edges (genus-5 handlebody).
* {f < 0} = the union of the three cylinders (star-shaped about the origin) plus the
  collar {0 <= P < c} and the vanished lenses: one component, chi 1, a ball-like
  cross with 6 arms ending on the box faces. Check: chi(box) = 1 = -4 + 1 - (-4).
* Critical values: interior -64 (origin), 0 (degenerate), 64/27 (12 maxima); in the box
  [-L, L]^3 also face centres -4 (L^2-4)^2, box-edge midpoints (L^2-4)^2 (2L^2-4)
  (minimum of P along each box edge) and corners (2L^2-4)^3. For L = 3 these are -100,
  350, 2744: every c in (64/27, 350) gives the same topology, c = 4.0078 is safely
  inside. For L = 2.5: 43.0, so (64/27, 43) — also safe.
* Where c *does* matter: (L^2-4)^2 (2L^2-4) = 4.007808 at L = 2.2, i.e. c is P at the
  midpoints of the edges of [-2.2, 2.2]^3, rounded down by 8e-6. In that box the 12
  frame bars pinch to necks ~2e-7 wide at the box-edge midpoints: still chi -4 (the box
  edges stay in {f > 0}; the oracle agrees at every n) but degenerate, and for L = 2.19
  the frame falls apart into 8 corner blobs (chi 8). Do not test meshers on
  [-2.2, 2.2]^3.

Oracle (box [-3, 3]^3, n = 17, 33, 65, 97, 129, 193, 257): inside 1 component / chi -4,
outside 1 component / chi 1, box-face traces -4 and 6, at every n — stable from n = 17
(spacing 0.375): the thinnest feature, a frame bar ~0.8 thick along its diagonal, is
far above the spacing, and nothing near the zero set is thinner than a cell. Same
values for [-2.5, 2.5]^3 from n = 17. Reasoning and oracle agree.
"""


# --------------------------------------------------------------------------------------
# CSG part: plate with 4 through holes, united with a ball
# --------------------------------------------------------------------------------------

def csg_part(x, y, z):
    """(plate minus 4 z-cylinders) union ball, with min/max booleans (f > 0 inside).

    plate: box centred at the origin, sizes (2, 2, 0.6); holes: infinite z-cylinders of
    radius 0.2 about (±0.6, ±0.6); ball: radius 0.5 about the origin.
    """
    plate = np.minimum(np.minimum(1.0 - np.abs(x), 1.0 - np.abs(y)), 0.3 - np.abs(z))
    holes = np.full(np.broadcast_shapes(np.shape(x), np.shape(y)), -np.inf)
    for cx in (-0.6, 0.6):
        for cy in (-0.6, 0.6):
            holes = np.maximum(holes, 0.2 - np.sqrt((x - cx) ** 2 + (y - cy) ** 2))
    ball = 0.5 - np.sqrt(x * x + y * y + z * z)
    return np.maximum(np.minimum(plate, -holes), ball)


CSG_PART_BOUNDS: Bounds = ((-1.2, -1.2, -1.2), (1.2, 1.2, 1.2))

CSG_PART_EXPECTED = {"components": 1, "solid_euler": -3, "surface_euler": -6}
"""The plate with 4 through holes has chi 1 - 4 = -3. The ball (radius 0.5) misses the
holes (distance from the origin to a hole is 0.6*sqrt(2) - 0.2 ≈ 0.65 > 0.5) and meets
the plate in the convex set ball ∩ slab, so the union has chi -3 + 1 - 1 = -3: the ball
only adds two caps above and below the plate. Closed surface: one genus-4 surface,
chi -6. The part stays inside [-1.2, 1.2]^3; its complement in the box has chi -2.
Oracle: 1 component, chi -3 (complement -2) for every n from 17 to 257."""
