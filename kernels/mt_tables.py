"""Marching-tetrahedra tables on the Kuhn (Freudenthal) split of the cube.

Pure Python + numpy (no warp import): kernel modules import these arrays and upload them.
Corners, cube edges and the inside / winding conventions are those of
:mod:`warpmesh.kernels.mc_tables` (corner ``i`` at ``(i & 1, (i >> 1) & 1, (i >> 2) & 1)``,
inside when f > 0, triangles counter-clockwise seen from outside).

Kuhn split (Frey & George §16.4.1)
----------------------------------
The cube is cut into the 6 tetrahedra ``(0, e_a, e_a + e_b, 7)``, one per permutation
``(a, b, c)`` of the axes (``e_a`` is corner ``1 << a``): they all share the main diagonal
0-7. Each cube face is then cut by the diagonal from its minimum corner to its maximum
corner; that choice is the same in every cell, so neighbouring cells are conforming.
``TETS[t]`` lists the corners of tetrahedron ``t`` (permutations in ``itertools`` order),
ordered so that its volume is positive: ``(0, e_a, e_a + e_b, 7)`` for an even
permutation, ``(0, e_a + e_b, e_a, 7)`` for an odd one.

Mt edges
--------
The surface vertices lie on the 19 edges of the split ("mt edges")::

    0..11  the cube edges of mc_tables (same numbering and order)
    12 (0,3)  13 (4,7)   face diagonals +x+y  (type 3; 12 + side z)
    14 (0,5)  15 (2,7)   face diagonals +x+z  (type 4; 14 + side y)
    16 (0,6)  17 (1,7)   face diagonals +y+z  (type 5; 16 + side x)
    18 (0,7)             body diagonal +x+y+z (type 6)

``MT_EDGES[e]`` is (lower corner, upper corner). ``MT_EDGE_ORIGIN[e] = (dx, dy, dz, type)``:
the lower corner's offset from the cell origin and the direction class of the edge,
``EDGE_TYPE_DELTA[type]`` its step (types 0, 1, 2 are the axes, so for cube edges the type
is mc_tables' axis). A global grid edge is thus ``(node, type)``, owned by its lower node.

Orientation a priori (Frey & George §16.4.2, Fig. 16.16 / 16.17)
-----------------------------------------------------------------
The 16 sign configurations of one *canonical* positively oriented tetrahedron (vertices
0..3, volume ``det(v1 - v0, v2 - v0, v3 - v0) > 0``) are solved once, by the vertex
order alone: list the inside vertices, then the outside ones, swapping two vertices of
the same group if needed so that this order is an *even* permutation of (0, 1, 2, 3);
with ``(i) (o1, o2, o3)``, ``(i1, i2) (o1, o2)`` or ``(i1, i2, i3) (o)``, the polygon is

* one inside vertex:    triangle ``(i o1, i o2, i o3)``
* two inside vertices:  quad ``(i1 o1, i1 o2, i2 o2, i2 o1)``
* three inside vertices: triangle ``(i1 o, i2 o, i3 o)``

(``i o`` is the tet edge from ``i`` to ``o``). For the tet ``(0, e1, e2, e3)`` and the order
(0, 1, 2, 3) a direct computation shows that the normal ``(p1 - p0) x (p2 - p0)`` of each
polygon points from the inside vertices to the outside ones, whatever the positions of
the points on their edges; an even permutation of the vertices of a positively oriented
tetrahedron is again positively oriented, so the rule holds in every configuration. Each
tetrahedron ``TETS[t]`` is the image of the canonical one by an orientation-preserving
affine map (vertex ``k`` to corner ``TETS[t][k]``), so mapping tet edges to mt edges
keeps the winding. No normal is ever computed; the tests check the result geometrically.

Cube tables
-----------
For each cube configuration (bit ``i`` set when corner ``i`` is inside) the polygons of
the 6 tetrahedra, in tet order: ``MT_TRIS[config, :MT_TRI_COUNT[config]]`` triangles and
``MT_QUADS[config, :MT_QUAD_COUNT[config]]`` quads (mt edge ids, -1 padding). Quads are
kept whole: the zero set of the linear interpolant in a tetrahedron is planar and convex,
so either diagonal is valid, and the kernel picks the better one at run time from the
actual vertex positions (``split_quad`` is the reference of that choice).

Only signs enter the tables. A node value of exactly 0 counts as outside and puts the
vertices of its edges on the node itself: polygons may then collapse (and two tets on
either side of a face of zero nodes emit the same triangle, reversed); the kernel has
to weld or drop such degenerate output, as with marching cubes.

Examples
--------
>>> int(MT_TRI_COUNT[0b00000001]), int(MT_QUAD_COUNT[0b00000001])  # corner 0 alone
(6, 0)
>>> int(MT_TRI_COUNT[0b10000001]), int(MT_QUAD_COUNT[0b10000001])  # corners 0 and 7
(0, 6)
"""

from __future__ import annotations

import itertools

import numpy as np

from warpmesh.kernels import mc_tables as _mc_tables
from warpmesh.kernels.mc_tables import CORNERS, EDGES
from warpmesh.kernels.table_cache import cached

__all__ = [
    "EDGE_TYPE_DELTA",
    "MT_EDGES",
    "MT_EDGE_ORIGIN",
    "MT_EDGE_OF",
    "TETS",
    "TET_EDGES",
    "TET_MT_EDGES",
    "CANONICAL_TET",
    "TET_POLY_SIZE",
    "TET_POLYGONS",
    "MT_TRI_COUNT",
    "MT_TRIS",
    "MAX_MT_TRIS",
    "MT_QUAD_COUNT",
    "MT_QUADS",
    "MAX_MT_QUADS",
    "QUAD_SPLITS",
    "canonical_polygon",
    "tet_config",
    "cell_polygons",
    "split_quad",
]

#: (7, 3) step of each edge type: +x, +y, +z, +x+y, +x+z, +y+z, +x+y+z
EDGE_TYPE_DELTA = np.array(
    [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], [1, 1, 1]], dtype=np.int32
)


def _make_mt_edges() -> np.ndarray:
    edges = [tuple(e) for e in EDGES.tolist()]
    for step in EDGE_TYPE_DELTA[3:6]:  # face diagonals, ordered by the normal coordinate
        mask = int(step @ [1, 2, 4])
        normal = int(np.flatnonzero(step == 0)[0])
        for side in (0, 1):
            lo = side << normal
            edges.append((lo, lo | mask))
    edges.append((0, 7))
    return np.array(edges, dtype=np.int32)


MT_EDGES = _make_mt_edges()


def _edge_type(a: int, b: int) -> int:
    step = CORNERS[b] - CORNERS[a]
    return int(np.flatnonzero((EDGE_TYPE_DELTA == step).all(axis=1))[0])


MT_EDGE_ORIGIN = np.ascontiguousarray(
    np.column_stack([CORNERS[MT_EDGES[:, 0]], [_edge_type(a, b) for a, b in MT_EDGES.tolist()]]),
    dtype=np.int32,
)
#: (corner a, corner b) -> mt edge index, both orders
MT_EDGE_OF = {(int(a), int(b)): e for e, (a, b) in enumerate(MT_EDGES)}
MT_EDGE_OF.update({(b, a): e for (a, b), e in list(MT_EDGE_OF.items())})


def _volume6(points) -> float:
    p = np.asarray(points, dtype=np.float64)
    return float(np.linalg.det(p[1:] - p[0]))


def _make_tets() -> np.ndarray:
    tets = []
    for a, b, _ in itertools.permutations(range(3)):
        tet = [0, 1 << a, (1 << a) | (1 << b), 7]
        if _volume6(CORNERS[tet]) < 0:  # odd permutation
            tet[1], tet[2] = tet[2], tet[1]
        tets.append(tet)
    return np.array(tets, dtype=np.int32)


#: (6, 4) corners of the 6 Kuhn tetrahedra, each with positive volume
TETS = _make_tets()

#: (6, 2) vertex pairs of the 6 edges of a tetrahedron (local vertex ids 0..3)
TET_EDGES = np.array(list(itertools.combinations(range(4), 2)), dtype=np.int32)
_TET_EDGE_OF = {p: k for k, (a, b) in enumerate(TET_EDGES.tolist()) for p in ((a, b), (b, a))}

#: (6, 6) mt edge of local edge ``k`` of tetrahedron ``t``
TET_MT_EDGES = np.array(
    [[MT_EDGE_OF[int(tet[a]), int(tet[b])] for a, b in TET_EDGES] for tet in TETS], dtype=np.int32
)

#: (4, 3) the canonical tetrahedron (positively oriented), used by tests and docs only
CANONICAL_TET = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.int32)


def _is_odd(order) -> bool:
    return sum(order[i] > order[j] for i in range(4) for j in range(i + 1, 4)) % 2 == 1


def canonical_polygon(config: int) -> list[int]:
    """Oriented polygon of one canonical tetrahedron configuration, as local tet edges.

    Parameters
    ----------
    config : int
        0..15, bit ``k`` set when vertex ``k`` of the tetrahedron is inside.

    Returns
    -------
    list of int
        0, 3 or 4 indices into ``TET_EDGES``, counter-clockwise seen from outside (the
        a priori rule of the module docstring).

    Examples
    --------
    >>> [TET_EDGES[k].tolist() for k in canonical_polygon(0b0001)]
    [[0, 1], [0, 2], [0, 3]]
    """
    if not 0 <= config < 16:
        raise ValueError(f"expected a tetrahedron configuration in 0..15, got {config}")
    inside = [k for k in range(4) if (config >> k) & 1]
    outside = [k for k in range(4) if not (config >> k) & 1]
    if not inside or not outside:
        return []
    if _is_odd(inside + outside):  # swap two vertices of a group of >= 2 (same side)
        group = inside if len(inside) >= 2 else outside
        group[0], group[1] = group[1], group[0]
    if len(inside) == 1:
        pairs = [(inside[0], o) for o in outside]
    elif len(inside) == 3:
        pairs = [(i, outside[0]) for i in inside]
    else:
        (i1, i2), (o1, o2) = inside, outside
        pairs = [(i1, o1), (i1, o2), (i2, o2), (i2, o1)]
    return [_TET_EDGE_OF[p] for p in pairs]


def _make_tet_polygons():
    size = np.zeros(16, dtype=np.int32)
    table = np.full((16, 4), -1, dtype=np.int32)
    for c in range(16):
        poly = canonical_polygon(c)
        size[c] = len(poly)
        table[c, : len(poly)] = poly
    return size, table


#: (16,) polygon size (0, 3 or 4) and (16, 4) local tet edges of each tet configuration
TET_POLY_SIZE, TET_POLYGONS = _make_tet_polygons()


def tet_config(config: int, t: int) -> int:
    """Configuration (0..15) of tetrahedron ``t`` in cube configuration ``config``."""
    return sum(((config >> int(c)) & 1) << k for k, c in enumerate(TETS[t]))


def cell_polygons(config: int) -> list[list[int]]:
    """Oriented polygons (mt edge ids) of the 6 tetrahedra of a cube configuration."""
    polys = []
    for t in range(6):
        tc = tet_config(config, t)
        polys.append([int(TET_MT_EDGES[t, k]) for k in TET_POLYGONS[tc, : TET_POLY_SIZE[tc]]])
    return [p for p in polys if p]


def _build():
    polys = [cell_polygons(c) for c in range(256)]
    tri_count = np.array([sum(len(p) == 3 for p in ps) for ps in polys], dtype=np.int32)
    quad_count = np.array([sum(len(p) == 4 for p in ps) for ps in polys], dtype=np.int32)
    max_tris, max_quads = int(tri_count.max()), int(quad_count.max())
    tris = np.full((256, max_tris, 3), -1, dtype=np.int32)
    quads = np.full((256, max_quads, 4), -1, dtype=np.int32)
    for c, ps in enumerate(polys):
        t3 = [p for p in ps if len(p) == 3]
        t4 = [p for p in ps if len(p) == 4]
        if t3:
            tris[c, : len(t3)] = t3
        if t4:
            quads[c, : len(t4)] = t4
    return tri_count, tris, max_tris, quad_count, quads, max_quads


#: generated once per install (:mod:`warpmesh.kernels.table_cache`)
MT_TRI_COUNT, MT_TRIS, MAX_MT_TRIS, MT_QUAD_COUNT, MT_QUADS, MAX_MT_QUADS = cached(
    "mt", _build, __file__, _mc_tables.__file__)

#: (2, 2, 3) the two splits of a quad (0, 1, 2, 3): diagonal 0-2, then diagonal 1-3
QUAD_SPLITS = np.array([[[0, 1, 2], [0, 2, 3]], [[0, 1, 3], [1, 2, 3]]], dtype=np.int32)


def _worst_cosine(points: np.ndarray, split: np.ndarray) -> np.ndarray:
    """Largest angle cosine (smallest angle) over the two triangles of a split."""
    p = points[..., split, :]  # (..., 2, 3, dim)
    u = np.roll(p, -1, axis=-2) - p  # at each vertex: to the next and to the previous
    v = np.roll(p, 1, axis=-2) - p
    dot = np.einsum("...i,...i->...", u, v)
    norm2 = np.einsum("...i,...i->...", u, u) * np.einsum("...i,...i->...", v, v)
    cos = np.ones_like(dot)  # a zero-length side makes the worst possible angle
    np.divide(dot, np.sqrt(norm2), out=cos, where=norm2 > 0)
    return cos.max(axis=(-2, -1))


def split_quad(points) -> np.ndarray:
    """The two triangles of a quad, split by the diagonal giving the larger minimum angle.

    Reference of the run-time choice of the kernels. Both splits keep the quad's winding.
    The smallest of the 6 angles is compared through cosines (no ``arccos``): diagonal
    1-3 is chosen only when the largest angle cosine of its two triangles is strictly
    smaller than that of diagonal 0-2, so ties (a square) go to diagonal 0-2. A side of
    zero length counts as an angle of cosine 1. For the planar convex quads of marching
    tetrahedra this is the Delaunay choice (Lawson's max-min angle criterion).

    Parameters
    ----------
    points : (..., 4, d) float
        The quad's vertices in cyclic order (``d`` = 2 or 3).

    Returns
    -------
    (..., 2, 3) int32
        Local vertex indices (0..3) of the two triangles: ``QUAD_SPLITS[0]`` or
        ``QUAD_SPLITS[1]``.

    Raises
    ------
    ValueError
        When ``points`` is not of shape (..., 4, d).

    Examples
    --------
    >>> rhombus = [[-2.0, 0.0], [0.0, -1.0], [2.0, 0.0], [0.0, 1.0]]
    >>> split_quad(rhombus).tolist()  # the short diagonal 1-3
    [[0, 1, 3], [1, 2, 3]]
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim < 2 or p.shape[-2] != 4:
        raise ValueError(f"expected points of shape (..., 4, d), got {p.shape}")
    second = _worst_cosine(p, QUAD_SPLITS[1]) < _worst_cosine(p, QUAD_SPLITS[0])
    return QUAD_SPLITS[second.astype(np.intp)]
