"""Marching-cubes-33 tables: per cell, the topology of the trilinear interpolant.

Pure Python + numpy (no warp import): kernel modules import these arrays and upload them.
Corners, edges, faces, symmetries, the inside / winding conventions and the loop tracing
are those of :mod:`warpmesh.kernels.mc_tables`: corner ``i`` at
``(i & 1, (i >> 1) & 1, (i >> 2) & 1)`` is *inside* when its value ``v_i > 0``
(``v <= 0`` is outside), triangles are counter-clockwise seen from outside
(``(p1 - p0) x (p2 - p0)`` points towards ``v <= 0``), local vertices ``0..11`` are the
cube edges. Local vertex ``12`` (``CENTER_VERTEX``) is an optional vertex inside the cell
(the apex of a disk's fan), placed by the kernel at the mean of the cell's edge vertices;
local vertex ``13 + k`` (``SPOKE_VERTEX + k``) lies on the *spoke* from the cell's hub to
corner ``k`` (the rows with a tube, see "Surfaces").

Run time (one cell, values ``v[0..7]``)
---------------------------------------
1. ``config = sum((v[i] > 0) << i)``.
2. Face bits. Face ``q`` (corners ``FACE_CORNERS[q] = (a, b, c, d)``, cyclic) is
   *ambiguous* when ``a, c`` are on one side and ``b, d`` on the other. Its bit is 1 when
   the two inside corners are connected across the face (the saddle of the bilinear
   interpolant is inside), 0 otherwise (mc_tables' rule 1). For inside corners ``a, c``
   the saddle value is ``(v_a v_c - v_b v_d) / (v_a + v_c - v_b - v_d)`` with a positive
   denominator, so the bit is ``v_a * v_c > v_b * v_d``; for inside ``b, d`` it is
   ``v_b * v_d > v_a * v_c``. Products are compared, never subtracted: the two cells of
   a face compute the same two rounded products and agree bit for bit; a tie gives 0.
   Non-ambiguous faces have bit 0. ``face_bits = sum(bit_q << q)``.
3. ``i = config * 64 + face_bits``; ``row = CASE_OFFSET[i]`` (never -1 for the bits of
   step 2); when ``INTERIOR_TEST[i] = k >= 0``, ``row += interior_value(v, k)``.
4. Triangles ``CASE_TRIS[row, :CASE_TRI_COUNT[row]]``; bit ``j`` of
   ``CASE_INTERIOR[row]`` is set when they use the interior vertex ``12 + j``.
5. Vertices (``vertex_positions``, the kernels' rule): an edge vertex by linear
   interpolation; vertex 12 at the mean of the edge vertices; for a row with spokes,
   the hub (``hub_point``: the saddle of the slice where the interior test found the
   connection, so the interpolant has the tube's side there; kept ``HUB_MARGIN`` off the
   faces) and on each spoke the root of the trilinear interpolant, by bisection.

Ties
----
One rule resolves every tie: the level belongs to the outside, as ``v <= 0`` says for a
corner. So a corner value equal to the level is outside; a face whose saddle value
equals the level keeps its inside corners apart (bit 0, the plain table's choice: the
outside corners meet at the saddle; both cells of the face compute the same two
products, so they agree bit for bit); an interior test whose slice saddle lies on the
level (``P(t*) = 0``) joins ``A`` and ``C`` when they are outside (value 2) and not when
they are inside (no tunnel of inside); a vertex ``t*`` on a face (``beta = 0`` or
``-2 alpha``) leaves the decision to that face (value 0). Each decision is thus the one
``v - epsilon`` makes for a small enough ``epsilon > 0`` (whose level set is not
singular), and neighbours agree on every face. Ties are where the true surface is
singular (it pinches at a saddle); ``v - epsilon`` is one of its two smoothings. A tie
never costs embeddedness: no row's triangles cross, for any vertex positions (see
"Surfaces"). Binary and label volumes (0/1 samples at level 0.5) make every ambiguous
face a tie; with five corners inside and three tied faces around the sixth (the
complement of case 7) the interior test finds a tunnel of inside (``P(t*) > 0``, no
tie), as ``v - epsilon`` has it.

Interior test ``k`` (``interior_value``), 6 kinds: ``k = 2 * axis + diagonal``
--------------------------------------------------------------------------------
Slice the cell by planes ``x_axis = t``. ``TEST_CORNERS[k] = (a0, a1, c0, c1, b0, b1, d0,
d1)`` are the lower and upper corners of the 4 cell edges along ``axis``; ``A`` and
``C`` are diagonally opposite in the slice (``diagonal`` 0: the edges at other
coordinates (0, 0) and (1, 1); 1: (1, 0) and (0, 1)). In slice ``t`` the corner values
``A(t) = v[a0] + t (v[a1] - v[a0])``, ... are linear and the slice is bilinear, with

    P(t) = A(t) C(t) - B(t) D(t) = alpha t^2 + beta t + gamma
    alpha = (v[a1] - v[a0]) (v[c1] - v[c0]) - (v[b1] - v[b0]) (v[d1] - v[d0])
    beta  = v[a0] (v[c1] - v[c0]) + v[c0] (v[a1] - v[a0]) - v[b0] (v[d1] - v[d0]) - v[d0] (v[b1] - v[b0])
    gamma = v[a0] v[c0] - v[b0] v[d0]

The result is 1 ("A and C are connected through the inside of a slice"), 2 ("connected
through the outside") or 0, with ``t* = -beta / (2 alpha)``::

    vertex = alpha < 0 and 0 < beta < -2 alpha
    disc = beta^2 - 4 alpha gamma                     # sign of P(t*)
    sa  = -2 alpha v[a0] + (v[a1] - v[a0]) beta      # sign of A(t*)
    sc  = -2 alpha v[c0] + (v[c1] - v[c0]) beta      # sign of C(t*)
    value = 1 if vertex and disc > 0 and sa > 0 and sc > 0
       else 2 if vertex and disc >= 0 and sa <= 0 and sc <= 0 else 0

(a few multiplies, no division, no square root): the concave quadratic ``P`` has its
vertex ``t*`` in (0, 1) with ``P(t*) > 0`` (``>= 0`` for the outside: see "Ties").

Why this is exact. Each connected piece of ``{F > 0}`` in a slice holds a corner of the
slice (the bilinear interpolant is harmonic), so a component of ``{F > 0}`` in the cell
is a union of slice pieces hanging on the 4 edges along the axis. Two of these edges
adjacent in the slice are joined along a cell face; a diagonal pair (``A``, ``C``) is
joined in slice ``t`` exactly when ``A, C > 0 >= B, D`` and the slice's saddle is inside,
i.e. ``P(t) > 0``. So everything beyond what the cube faces show is a diagonal
connection in some slice. The generator checks, per table entry and on each of the 3
axes, which diagonal connections could join two *different* boundary patches (the
pieces of the cube surface cut by the face curves); a join must show on all 3 axes.
The test uses an axis where only one diagonal can matter. There, on the interval
``I = {t: A(t), C(t) > 0}`` the other two edges are ``<= 0`` (else ``A`` and ``C`` would be
joined on the faces), so ``P <= 0`` at both ends of ``I`` (``-B D`` where ``A`` or ``C``
vanishes, the face's own saddle numerator at ``t = 0, 1``), and ``P > 0`` somewhere on
``I`` iff ``P`` is concave with its vertex in ``I`` and positive there; the same holds
for the outside with ``A, C < 0``. The two intervals are disjoint, so at most one of
the two connections exists. ``value`` picks the row: 0 no connection, 1 the inside
patches of ``A`` and ``C`` merge (a tube of inside), 2 the outside ones do. When a
connection cannot change the topology (its two parts already lie in one patch) the
row for that value is the same as for 0. A tie (``P(t*) = 0``, a singular surface: the
slice saddle on the level) joins the outside corners, not the inside ones (see "Ties").
When the value is not 0, the slice ``t* = -beta / (2 alpha)`` is in ``(0, 1)`` and its
bilinear saddle has the sign of ``A`` and ``C``: ``hub_point``.
Tested entries: 188 of the 16384, in 13 orbits: 11 where the merge occurs (cases 4.1,
6.1, 7.4, 10.1, 12.1, 13.5 and their complements) and 2 of case 13.3 (config 105 with
bits 5 or 23) where the faces allow a merge that neither sampling nor an optimiser ever
produced; their tests stay, being exact.

Surfaces
--------
On the cube surface the face curves cut out *patches*; each patch, and each region of
the cell, holds a corner. The loops (traced as in mc_tables, with the decided face
segments) are the edges of the tree of patches. Merging patches into regions (the
interior connection of a test, or none), the loops with the same (inside region,
outside region) pair bound one surface component: one loop is a disk, two loops a tube
(an annulus; never more in a trilinear cell). No triangle edge lies in a cube face
except the face segments (a *chord* could be the neighbouring cell's edge too, and its
triangles would meet the neighbour's off the segments).

Disks (rows without a tube): the triangulation of each loop that maximises the minimum
angle (vertices at edge midpoints; the dynamic programme of ``mc_tables.triangulate``)
without chords, or, where none exists, a fan around vertex 12; at most one fan per row
(two fans on one vertex would pinch).

Tubes: the *hub construction*. A tube joins the two patches of one side (two inside
patches for interior value 1, two outside ones for 2; in every tested entry that side
has exactly two patches). Take a point, the hub, strictly inside the cube, and the
*spokes* from it to the 8 corners; the spoke of each corner on the other side carries a
vertex. The cube is the union of 6 pyramids from the hub over its faces. In the pyramid
over a face the surface is bounded by the face's segments and by one segment on each
side triangle (hub, p, r) of the pyramid: from the vertex of the cube edge ``pr`` to the
spoke vertex of its corner on the other side, or between the spoke vertices of ``p`` and
``r`` when both are on the other side. These close into polygons: a triangle, a
quadrilateral, a pentagon (three corners on the other side) or a hexagon (an ambiguous
face whose hub-side corners are apart); a pentagon or hexagon is cut along the segment
between the spoke vertices of two diagonal corners of the face (it lies in the plane
through the hub and that diagonal, which halves the pyramid into two tetrahedra), the
rest are triangles and quadrilaterals (either diagonal). This is the surface of a
function that is "on the hub's side" along the hub's spokes to that side: every corner
of the hub's side joins the hub's region, every patch of the other side stays apart,
which is the tube's topology exactly (checked against ``surfaces`` for every row). It is
embedded for *any* hub inside the cube, edge vertices inside their edges and spoke
vertices inside their spokes: each piece lies in its pyramid (or tetrahedron); two
pyramids meet in a side triangle, where each piece has only the segment it shares with
the other; the pieces of one pyramid are apart. So the triangles of a tube never cross,
whatever the values, their ties, or a root finder's later moves of the edge vertices.
(Triangulating the annulus between the two loops alone, as the first tables did, is
not: with the vertices where linear interpolation puts them, 483 of the 569 tube cells
among 100000 cells of uniform random values crossed themselves, and 6 of the 8 of 0/1
values, issue 18.)

Generation
----------
Table entries are pairs (config, face bits) with bits only on ambiguous faces. Only
orbit representatives under the 48 cube symmetries are solved (``BASE_CASES``); every
entry is then filled by mapping edges, faces and the test's corners through a symmetry
(winding reversed for a reflection), asserting that all symmetries reaching an entry
agree on its loops, components and test outcomes, and that the mapped loops are those
traced directly; a spoke vertex maps with its corner. Complementation (inside <-> outside,
face bits flipped, values 1 <-> 2)
is also a symmetry of the trilinear topology; it is not used to generate, the tests
check it. Some bit patterns cannot occur: face bits compare sums of ``log|v|`` (linear
functionals), and e.g. for the checkerboard configurations the three pairs of opposite
faces have equal sums. ``CASE_FEASIBLE`` marks the entries reachable in exact arithmetic
(a transposition theorem on the circuits of those functionals); the others still have a
row (disks on the traced loops, no test) so that rounding can never index an empty row.

Examples
--------
>>> import numpy as np
>>> v = np.array([1.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 1.0])  # corners 0 and 7
>>> face_bits_of(v), int(INTERIOR_TEST[0b10000001 * 64])
(0, 0)
>>> interior_value(v, 0)  # a tube of inside joins the corners
1
>>> len(polygonize(v)), len(polygonize(np.where(v > 0, 0.2, -1.0)))  # tube on the hub, two triangles
(18, 2)
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np

from warpmesh.kernels import mc_tables as _mc_tables
from warpmesh.kernels.table_cache import cached
from warpmesh.kernels.mc_tables import (
    CORNERS,
    EDGE_MIDPOINTS,
    EDGE_OF,
    EDGE_ORIGIN,
    EDGES,
    FACES,
    SYM_CORNERS,
    SYM_DET,
    SYM_EDGES,
    apply_symmetry_to_config,
    canonical_loops,
    chain_loops,
    face_segments,
    on_one_face,
)

__all__ = [
    "CENTER_VERTEX",
    "SPOKE_VERTEX",
    "CENTER_TYPE",
    "HUB_MARGIN",
    "VERTEX_ORIGIN",
    "FACE_CORNERS",
    "AMBIGUOUS_FACES",
    "TEST_CORNERS",
    "INTERIOR_TEST",
    "CASE_OFFSET",
    "CASE_FEASIBLE",
    "CASE_TRI_COUNT",
    "CASE_TRIS",
    "CASE_INTERIOR",
    "MAX33",
    "BASE_CASES",
    "config_of",
    "face_bits_of",
    "interior_value",
    "case_row",
    "polygonize",
    "trilinear",
    "hub_point",
    "vertex_positions",
    "kernel_tables",
    "trace_loops",
    "patch_labels",
    "case_surfaces",
    "hub_triangulation",
    "triangulate_case",
]

#: local id of the optional vertex inside the cell (a disk's fan)
CENTER_VERTEX = 12
#: local id of the vertex on the spoke from the hub to corner 0 (corner k: ``SPOKE_VERTEX + k``)
SPOKE_VERTEX = 13
#: vertex type of the interior vertices in the emit kernels (``warpmesh.kernels.emit.CENTER``)
CENTER_TYPE = 7
#: (21, 4) local vertex -> (dx, dy, dz, type): the 12 cube edges, the cell centre, then
#: the spokes, with the offset of their corner
VERTEX_ORIGIN = np.ascontiguousarray(
    np.vstack([EDGE_ORIGIN, [[0, 0, 0, CENTER_TYPE]], np.column_stack([CORNERS, np.full(8, CENTER_TYPE)])]),
    dtype=np.int32)
#: the hub stays this far (in cell sizes) from the cube faces
HUB_MARGIN = 0.05
#: (6, 4) corners of each face, counter-clockwise seen from outside (mc_tables.FACES)
FACE_CORNERS = np.array(FACES, dtype=np.int32)


# ----------------------------------------------------------------------------- faces


def _inside(config: int, corner) -> int:
    return (config >> int(corner)) & 1


def _ambiguous_mask(config: int) -> int:
    mask = 0
    for q, (a, b, c, d) in enumerate(FACES):
        sa, sb, sc, sd = (_inside(config, x) for x in (a, b, c, d))
        mask |= int(sa == sc and sb == sd and sa != sb) << q
    return mask


#: (256,) bit q set when face q is ambiguous under the configuration
AMBIGUOUS_FACES = np.array([_ambiguous_mask(c) for c in range(256)], dtype=np.int32)


def face_segments33(config: int, q: int, bit: int) -> list[tuple[int, int]]:
    """Oriented surface segments (edge, edge) on face ``q`` for its decided bit.

    Bit 0 is mc_tables' rule 1 (inside corners separated). Bit 1 joins the inside
    corners, i.e. separates the outside ones: the segments of the complementary
    configuration, reversed so that the inside stays on the same side.
    """
    if bit:
        return [(b, a) for a, b in face_segments(config ^ 0xFF, FACES[q])]
    return face_segments(config, FACES[q])


def trace_loops(config: int, bits: int) -> list[list[int]]:
    """Oriented loops (edge ids) of a configuration under the given face bits.

    Loops start at their smallest edge and are sorted, as ``mc_tables.trace_polygons``
    (which is the case ``bits = 0``).

    >>> trace_loops(0b1001, 0), trace_loops(0b1001, 1 << 4)  # face z = 0 ambiguous
    ([[0, 4, 8], [1, 5, 11]], [[0, 5, 11, 1, 4, 8]])
    """
    nxt = {}
    for q in range(6):
        for a, b in face_segments33(config, q, (bits >> q) & 1):
            assert a not in nxt, "crossing edge is the start of two segments"
            nxt[a] = b
    return chain_loops(nxt)


def patch_labels(config: int, bits: int) -> tuple[int, ...]:
    """Patch of each corner on the cube surface: the smallest corner of its patch.

    Corners of one sign sharing an edge are in one patch; across an ambiguous face the
    inside diagonal is joined when the face bit is 1, the outside diagonal when it is 0.
    """
    label = list(range(8))

    def find(x):
        while label[x] != x:
            x = label[x]
        return x

    def join(x, y):
        x, y = find(x), find(y)
        label[max(x, y)] = min(x, y)

    for a, b in EDGES.tolist():
        if _inside(config, a) == _inside(config, b):
            join(a, b)
    for q, (a, b, c, d) in enumerate(FACES):
        if (AMBIGUOUS_FACES[config] >> q) & 1:
            joined_inside = (bits >> q) & 1
            join(*((a, c) if _inside(config, a) == joined_inside else (b, d)))
    return tuple(find(x) for x in range(8))


def _loop_sides(config: int, patches, loop) -> tuple[int, int]:
    """(inside patch, outside patch) on the two sides of a loop."""
    sides = set()
    for e in loop:
        a, b = EDGES[e].tolist()
        if not _inside(config, a):
            a, b = b, a
        sides.add((patches[a], patches[b]))
    assert len(sides) == 1, "a loop must separate one inside patch from one outside patch"
    return sides.pop()


# ----------------------------------------------------------------------------- interior tests


def _vertical_edge(axis: int, du: int, dw: int) -> tuple[int, int]:
    u, w = (a for a in range(3) if a != axis)
    lo = (du << u) | (dw << w)
    return lo, lo | (1 << axis)


def _make_test_corners() -> np.ndarray:
    rows = []
    for axis in range(3):
        for diagonal in range(2):
            a, c, b, d = ((0, 0), (1, 1), (1, 0), (0, 1)) if diagonal == 0 else ((1, 0), (0, 1), (0, 0), (1, 1))
            rows.append([x for e in (a, c, b, d) for x in _vertical_edge(axis, *e)])
    return np.array(rows, dtype=np.int32)


#: (6, 8) test k = 2 * axis + diagonal: lower, upper corner of the edges A, C, B, D
TEST_CORNERS = _make_test_corners()


def _test_of_edge(lo: int, hi: int) -> int:
    """Test id whose edge A (or C) joins corners lo and hi."""
    axis = int(lo ^ hi).bit_length() - 1
    lo = min(lo, hi)
    u, w = (a for a in range(3) if a != axis)
    return 2 * axis + int(((lo >> u) & 1) != ((lo >> w) & 1))


def _slice_merges(config: int, patches, test: int) -> dict[int, tuple[int, int] | None]:
    """Patches a diagonal connection of ``test`` could merge: {1: inside, 2: outside}."""
    a0, a1, c0, c1 = TEST_CORNERS[test, :4].tolist()
    out = {}
    for value, side in ((1, 1), (2, 0)):
        pa = {patches[x] for x in (a0, a1) if _inside(config, x) == side}
        pc = {patches[x] for x in (c0, c1) if _inside(config, x) == side}
        assert len(pa) <= 1 and len(pc) <= 1
        out[value] = (pa.pop(), pc.pop()) if pa and pc and pa != pc else None
    return out


def _regions(patches, merges) -> dict[int, int]:
    """Patch -> region (smallest patch id of the region) after merging patch pairs."""
    region = {p: p for p in set(patches)}
    for a, b in merges:
        old, new = sorted((region[a], region[b]), reverse=True)
        region = {p: new if r == old else r for p, r in region.items()}
    return region


def _partition(region) -> frozenset:
    groups = {}
    for p, r in region.items():
        groups.setdefault(r, set()).add(p)
    return frozenset(frozenset(g) for g in groups.values())


def _possible_partitions(config: int, patches) -> set:
    """Region partitions of the patches that every axis allows (see module docstring)."""
    result = None
    for axis in range(3):
        pairs = [m for k in (2 * axis, 2 * axis + 1) for m in _slice_merges(config, patches, k).values() if m]
        allowed = {_partition(_regions(patches, sub)) for n in range(len(pairs) + 1)
                   for sub in itertools.combinations(pairs, n)}
        result = allowed if result is None else result & allowed
    return result


def _choose_test(config: int, patches) -> int:
    """Test for a table entry, -1 when its topology is fixed by the cube faces.

    The first test (axis, diagonal) that can merge patches while the other diagonal of
    its axis cannot; its outcomes must cover every single merge any axis allows.
    """
    possible = _possible_partitions(config, patches)
    if len(possible) == 1:
        return -1
    for axis in range(3):
        live = [k for k in (2 * axis, 2 * axis + 1) if any(_slice_merges(config, patches, k).values())]
        if len(live) == 1:
            outcomes = {_partition(_regions(patches, [m] if m else [])) for m in
                        [None, *_slice_merges(config, patches, live[0]).values()]}
            assert outcomes <= possible, f"test {live[0]} of config {config} allows an impossible merge"
            singles = {p for p in possible if len(p) >= len(set(patches)) - 1}
            assert singles <= outcomes, f"config {config}: a merge escapes test {live[0]}"
            return live[0]
    raise AssertionError(f"no single interior test decides config {config} patches {patches}")


# ----------------------------------------------------------------------------- surfaces


def case_surfaces(config: int, bits: int, merges=()) -> list[list[list[int]]]:
    """Surface components of an entry after merging patch pairs: lists of loops.

    One loop bounds a disk, two loops a tube; loops with the same (inside region,
    outside region) pair form one component.

    >>> case_surfaces(0b10000001, 0), case_surfaces(0b10000001, 0, [(0, 7)])
    ([[[0, 4, 8]], [[3, 11, 7]]], [[[0, 4, 8], [3, 11, 7]]])
    """
    loops = trace_loops(config, bits)
    patches = patch_labels(config, bits)
    region = _regions(patches, merges)
    groups = {}
    for loop in loops:
        p_in, p_out = _loop_sides(config, patches, loop)
        groups.setdefault((region[p_in], region[p_out]), []).append(loop)
    n_regions = len(set(region.values()))
    assert len(groups) + 1 == n_regions, "surfaces and regions do not form a tree"
    assert all(len(g) <= 2 for g in groups.values()), "more than two loops on one surface"
    return sorted(groups.values())


def _points(config: int) -> np.ndarray:
    """(13, 3) edge midpoints and the mean of the crossing ones (vertex 12)."""
    cross = [e for e, (a, b) in enumerate(EDGES.tolist()) if _inside(config, a) != _inside(config, b)]
    centre = EDGE_MIDPOINTS[cross].mean(axis=0) if cross else np.full(3, 0.5)
    return np.vstack([EDGE_MIDPOINTS, centre])


@lru_cache(maxsize=None)
def _angles(config: int) -> list:
    """Nested (13, 13, 13) list: smallest angle of each triangle of vertex ids, rounded (ties by order)."""
    p = _points(config)
    tri = np.stack(np.meshgrid(*[np.arange(13)] * 3, indexing="ij"), -1).reshape(-1, 3)
    worst = np.full(len(tri), -1.0)
    for k in range(3):
        u, v = p[tri[:, (k + 1) % 3]] - p[tri[:, k]], p[tri[:, (k + 2) % 3]] - p[tri[:, k]]
        with np.errstate(invalid="ignore", divide="ignore"):
            cos = np.einsum("ij,ij->i", u, v) / np.sqrt(np.einsum("ij,ij->i", u, u) * np.einsum("ij,ij->i", v, v))
        worst = np.maximum(worst, np.nan_to_num(cos, nan=1.0))
    return np.round(np.arccos(np.clip(worst, -1.0, 1.0)), 9).reshape(13, 13, 13).tolist()


#: (12, 12) True where two cube edges lie on a common face
_SHARE_FACE = np.array([[a != b and on_one_face((a, b)) for b in range(12)] for a in range(12)])


def _in_face(a: int, b: int) -> bool:
    """Whether the segment between local vertices a and b lies in a cube face (both on edges)."""
    return a < 12 and b < 12 and bool(_SHARE_FACE[a, b])


def triangulate_polygon(poly: list[int], angles, forbidden=frozenset()):
    """Max-min-angle triangulation of a polygon of vertex ids, or None.

    Returns ``(min angle, triangles)``; ``angles`` is ``_angles(config)``. ``poly`` runs
    counter-clockwise seen from outside. The dynamic programme of
    ``mc_tables.triangulate`` (vertices at edge midpoints, ties to the first candidate);
    a diagonal must not lie in a cube face (a *chord*: the neighbouring cell could use the
    same edge) nor be an edge of ``forbidden`` (frozensets of 2 ids: the loop segments).
    """
    n = len(poly)
    ok = [[True] * n for _ in range(n)]  # per position pair: may it be a side of a triangle
    for i in range(n):
        for j in range(i + 2, n):
            a, b = poly[i], poly[j]
            ok[i][j] = not (a == b or frozenset((a, b)) in forbidden or _in_face(a, b))
    # best sub-polygon i..j: minimum angle and split vertex (-1: impossible)
    angle = [[-1.0] * n for _ in range(n)]
    split = [[-1] * n for _ in range(n)]
    for i in range(n - 1):
        angle[i][i + 1] = np.inf
    for length in range(2, n):
        for i in range(n - length):
            j = i + length
            a, c = poly[i], poly[j]
            row_a = angles[a]
            best_a, best_k = -1.0, -1
            for k in range(i + 1, j):
                if angle[i][k] < 0 or angle[k][j] < 0 or not ok[i][k] or not ok[k][j]:
                    continue
                worst = min(angle[i][k], angle[k][j], row_a[poly[k]][c])
                if best_k < 0 or worst > best_a:
                    best_a, best_k = worst, k
            angle[i][j], split[i][j] = (best_a, best_k) if best_k >= 0 else (-1.0, -1)
    if split[0][n - 1] < 0 or angle[0][n - 1] <= 0:
        return None
    tris, stack = [], [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i >= 2:
            k = split[i][j]
            tris.append((poly[i], poly[k], poly[j]))
            stack += [(k, j), (i, k)]
    return angle[0][n - 1], tris


def _segments(loops) -> frozenset:
    return frozenset(frozenset((lp[k], lp[(k + 1) % len(lp)])) for lp in loops for k in range(len(lp)))


def is_surface(tris, loops) -> bool:
    """Whether oriented triangles form a 2-manifold whose boundary is exactly ``loops``.

    Every directed edge is used once; an edge without its reverse is a loop segment
    (in the loop's direction) and every segment is such an edge; the triangles around
    each vertex form a single fan (a disk, or a half-disk at a loop vertex).
    """
    directed = [(t[k], t[(k + 1) % 3]) for t in tris for k in range(3)]
    if len(set(directed)) != len(directed) or any(len(set(t)) < 3 for t in tris):
        return False
    boundary = {(a, b) for a, b in directed if (b, a) not in set(directed)}
    if boundary != {(lp[k], lp[(k + 1) % len(lp)]) for lp in loops for k in range(len(lp))}:
        return False
    around = {}
    for t in tris:
        for k in range(3):
            around.setdefault(t[k], {})[t[(k + 1) % 3]] = t[(k + 2) % 3]
    for nxt in around.values():  # walk the fan of a vertex: one chain (or cycle) through all
        starts = [a for a in nxt if a not in nxt.values()] or [next(iter(nxt))]
        if len(starts) != 1:
            return False
        a, steps = starts[0], 0
        while a in nxt and steps <= len(nxt):
            a, steps = nxt[a], steps + 1
            if a == starts[0]:
                break
        if steps != len(nxt):
            return False
    return True


def surface_signature(tris) -> frozenset:
    """The components of a row's triangles, each as the set of its canonical boundary loops."""
    parent: dict[int, int] = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            x = parent[x]
        return x

    for t in tris:
        for v in t[1:]:
            parent[find(v)] = find(t[0])
    directed = {(t[k], t[(k + 1) % 3]) for t in tris for k in range(3)}
    groups: dict[int, list[list[int]]] = {}
    for loop in chain_loops({a: b for a, b in directed if (b, a) not in directed}):
        groups.setdefault(find(loop[0]), []).append(loop)
    return frozenset(canonical_loops(g) for g in groups.values())


def fan(loop: list[int]) -> list[tuple[int, int, int]]:
    """Triangles joining each segment of a loop to vertex 12."""
    return [(loop[k], loop[(k + 1) % len(loop)], CENTER_VERTEX) for k in range(len(loop))]


def _disk_options(loop: list[int], angles) -> list[tuple[bool, float, list]]:
    """Ways to triangulate a disk: [(uses 12, min angle, triangles)]: chord-free, or a fan."""
    options = []
    found = triangulate_polygon(loop, angles, _segments([loop]))
    if found:
        options.append((False, found[0], found[1]))
    options.append((True, min(angles[a][b][c] for a, b, c in fan(loop)), fan(loop)))
    return options


def _pick(options):
    """Best combination of one option per disk: at most one fan (two fans on vertex 12
    would pinch), then fewest fans, then the largest minimum angle."""
    best, best_key = None, None
    for combo in itertools.product(*options):
        if sum(opt[0] for opt in combo) > 1:
            continue
        key = (-sum(opt[0] for opt in combo), min([opt[1] for opt in combo] or [0]))
        if best_key is None or key > best_key:
            best, best_key = combo, key
    return best


# ----------------------------------------------------------------------------- tubes: the hub


#: (21, 3) reference positions of the local vertices: edge midpoints, the cell centre,
#: and the spoke vertices halfway from the centre to their corners
_HUB_POINTS = np.vstack([EDGE_MIDPOINTS, np.full((1, 3), 0.5), 0.5 + 0.5 * (CORNERS - 0.5)])


def _min_angle(p: np.ndarray) -> float:
    """Smallest angle of the triangle with corners p (3, 3), rounded (ties by order)."""
    cos = [(p[(k + 1) % 3] - p[k]) @ (p[(k + 2) % 3] - p[k])
           / np.linalg.norm(p[(k + 1) % 3] - p[k]) / np.linalg.norm(p[(k + 2) % 3] - p[k]) for k in range(3)]
    return round(float(np.arccos(np.clip(max(cos), -1.0, 1.0))), 9)


def _hub_side(config: int, bits: int, tube) -> bool:
    """Whether the two loops of a tube join two inside patches (else two outside ones)."""
    patches = patch_labels(config, bits)
    (in_a, out_a), (in_b, out_b) = (_loop_sides(config, patches, loop) for loop in tube)
    assert (in_a != in_b) != (out_a != out_b), "a tube joins two patches of one side"
    return in_a != in_b


def _pyramid_polygons(config: int, bits: int, q: int, hub_inside: bool) -> list[list[int]]:
    """Oriented polygons of the hub construction in the pyramid from the hub over face q."""
    face = FACES[q]
    segments = face_segments33(config, q, (bits >> q) & 1)
    nbrs: dict[int, list[int]] = {}

    def link(a, b):
        nbrs.setdefault(a, []).append(b)
        nbrs.setdefault(b, []).append(a)

    for a, b in segments:
        link(a, b)
    for p, r in zip(face, face[1:] + face[:1]):  # the side triangle (hub, p, r)
        ip, ir = _inside(config, p), _inside(config, r)
        if ip != ir:  # its cube edge's vertex -> the spoke of the corner off the hub's side
            link(EDGE_OF[p, r], SPOKE_VERTEX + (p if ip != hub_inside else r))
        elif ip != hub_inside:
            link(SPOKE_VERTEX + p, SPOKE_VERTEX + r)
    assert all(len(v) == 2 for v in nbrs.values()), "every vertex of a pyramid lies on two of its segments"
    spokes = [SPOKE_VERTEX + c for c in face]
    polygons, seen = [], set()
    for start in sorted(nbrs):
        if start in seen:
            continue
        poly, prev, cur = [start], start, nbrs[start][0]
        while cur != start:
            poly.append(cur)
            a, b = nbrs[cur]
            prev, cur = cur, b if a == prev else a
        seen.update(poly)
        sides = set(zip(poly, poly[1:] + poly[:1]))
        if sides & {(b, a) for a, b in segments}:  # face segments keep their direction
            poly.reverse()
        elif not sides & set(segments):  # 4 spokes: in the face's order (outwards) when the hub is inside
            k = poly.index(spokes[0])
            if (poly[k:] + poly[:k] == spokes) != hub_inside:
                poly.reverse()
        polygons.append(poly)
    return polygons


def _split_pyramid_polygon(poly: list[int], face) -> list[tuple[int, int, int]]:
    """Triangles of one polygon of a pyramid: cut along the spokes of two diagonal corners
    of the face (the plane through the hub and that diagonal) when both are on it, then
    triangles and quadrilaterals (the better minimum angle of the two diagonals)."""
    n = len(poly)
    if n == 3:
        return [tuple(poly)]
    for x, y in ((face[0], face[2]), (face[1], face[3])):
        if SPOKE_VERTEX + x in poly and SPOKE_VERTEX + y in poly:
            i, j = sorted((poly.index(SPOKE_VERTEX + x), poly.index(SPOKE_VERTEX + y)))
            if 1 < j - i < n - 1:
                return (_split_pyramid_polygon(poly[i:j + 1], face)
                        + _split_pyramid_polygon(poly[j:] + poly[:i + 1], face))
    assert n == 4, f"pyramid polygon {poly} of face {face}"
    options = []
    for k in (0, 1):
        assert not _in_face(poly[k], poly[k + 2]), "a quadrilateral diagonal would be a chord"
        options.append([(poly[k], poly[k + 1], poly[(k + 2) % 4]), (poly[(k + 2) % 4], poly[(k + 3) % 4], poly[k])])
    return max(options, key=lambda tris: min(_min_angle(_HUB_POINTS[list(t)]) for t in tris))


def hub_triangulation(config: int, bits: int, hub_inside: bool) -> list[tuple[int, int, int]]:
    """Triangles of a row with a tube: the hub construction (see the module docstring).

    ``hub_inside``: the tube joins the two inside patches (interior value 1), else the
    two outside ones (value 2); every corner on the other side gets a spoke vertex.

    >>> len(hub_triangulation(0b10000001, 0, True))  # corners 0 and 7: 6 faces x 3 triangles
    18
    """
    return [t for q in range(6) for poly in _pyramid_polygons(config, bits, q, hub_inside)
            for t in _split_pyramid_polygon(poly, FACES[q])]


def triangulate_case(config: int, bits: int, surfaces) -> list[tuple[int, int, int]]:
    """Triangles of one row from its surface components (lists of loops).

    A row with a tube is built by ``hub_triangulation`` (its topology is checked against
    ``surfaces``). Otherwise every component is a disk: the max-min-angle triangulation
    without chords, or a fan around vertex 12; at most one fan per row, then fewest fans,
    then the largest minimum angle.
    """
    tubes = [loops for loops in surfaces if len(loops) == 2]
    if tubes:
        tris = hub_triangulation(config, bits, _hub_side(config, bits, tubes[0]))
        assert is_surface(tris, [lp for loops in surfaces for lp in loops]), (config, bits)
        assert surface_signature(tris) == frozenset(canonical_loops(lps) for lps in surfaces), (config, bits)
        return tris
    angles = _angles(config)
    choice = _pick([_disk_options(loops[0], angles) for loops in surfaces])
    assert choice is not None, f"config {config} bits {bits}: no triangulation of {surfaces}"
    return [t for opt in choice for t in opt[2]]


# ----------------------------------------------------------------------------- feasibility


def _face_functional(config: int, q: int) -> np.ndarray:
    """(8,) log-magnitude functional of face q: bit 1 iff its value is > 0."""
    f = np.zeros(8)
    a, b, c, d = FACES[q]
    s = 1.0 if _inside(config, a) else -1.0
    f[[a, c]], f[[b, d]] = s, -s
    return f


@lru_cache(maxsize=None)
def _circuits(config: int) -> tuple[tuple[tuple[int, ...], tuple[int, ...]], ...]:
    """Minimal linearly dependent sets of face functionals, with the null vector's signs."""
    faces = [q for q in range(6) if (AMBIGUOUS_FACES[config] >> q) & 1]
    out = []
    for n in range(2, len(faces) + 1):
        for sub in itertools.combinations(faces, n):
            m = np.array([_face_functional(config, q) for q in sub])
            if np.linalg.matrix_rank(m) != n - 1:
                continue
            lam = np.linalg.svd(m.T)[2][-1]
            if np.all(np.abs(lam) > 1e-9):  # full support: a circuit
                out.append((sub, tuple(int(np.sign(x)) for x in lam)))
    return tuple(out)


def feasible(config: int, bits: int) -> bool:
    """Whether some values with signs ``config`` give exactly these face bits.

    With ``x = log|v|`` face q's bit is ``f_q . x > 0`` (a tie gives 0). By Motzkin's
    transposition theorem the system {f_q . x > 0 (bit 1), -f_q . x >= 0 (bit 0)} has no
    solution iff a non-negative combination of its rows vanishes with weight on a strict
    row, iff some circuit of the functionals has null-vector signs ``sign_q`` such that
    ``sign_q * (2 bit_q - 1)`` is constant and one of its faces has bit 1.
    (A corner value 0 only pushes the bits of its faces to 1, which small magnitudes
    also do.)
    """
    if bits & ~int(AMBIGUOUS_FACES[config]):
        return False
    for faces, signs in _circuits(config):
        oriented = {s * (2 * ((bits >> q) & 1) - 1) for q, s in zip(faces, signs)}
        if len(oriented) == 1 and any((bits >> q) & 1 for q in faces):
            return False
    return True


# ----------------------------------------------------------------------------- symmetry + build


def _make_sym_faces() -> np.ndarray:
    index = {frozenset(f): q for q, f in enumerate(FACES)}
    return np.array([[index[frozenset(SYM_CORNERS[s][list(f)].tolist())] for f in FACES] for s in range(48)],
                    dtype=np.int32)


#: (48, 6) face permutation of each symmetry
SYM_FACES = _make_sym_faces()


def _map_bits(s: int, bits: int) -> int:
    return sum(1 << int(SYM_FACES[s][q]) for q in range(6) if (bits >> q) & 1)


def _map_tris(s: int, tris):
    vertex = SYM_EDGES[s].tolist() + [CENTER_VERTEX] + [SPOKE_VERTEX + int(c) for c in SYM_CORNERS[s]]
    out = [tuple(vertex[v] for v in t) for t in tris]
    return [t[::-1] for t in out] if SYM_DET[s] < 0 else out


def _map_test(s: int, test: int) -> int:
    if test < 0:
        return test
    a0, a1 = TEST_CORNERS[test, :2].tolist()
    return _test_of_edge(int(SYM_CORNERS[s][a0]), int(SYM_CORNERS[s][a1]))


def _signature(s: int, surfaces) -> frozenset:
    """Components as sets of canonical loops, mapped through symmetry s."""
    return frozenset(canonical_loops(_map_loops(s, loops)) for loops in surfaces)


def _solve_base(config: int, bits: int):
    """(test, [surfaces for value 0, 1, 2 (or just 0)], feasible) of one entry."""
    patches = patch_labels(config, bits)
    ok = feasible(config, bits)
    test = _choose_test(config, patches) if ok else -1
    if test < 0:
        return test, [case_surfaces(config, bits)], ok
    merges = _slice_merges(config, patches, test)
    return test, [case_surfaces(config, bits, [m] if m else []) for m in (None, merges[1], merges[2])], ok


def _map_loops(s: int, loops):
    edge = SYM_EDGES[s].tolist()
    mapped = [[edge[e] for e in lp] for lp in loops]
    return [lp[::-1] if SYM_DET[s] < 0 else lp for lp in mapped]


def _build():
    """Solve the base entries, fill the others by symmetry (see the module docstring)."""
    entries = [(c, b) for c in range(256) for b in range(64) if not b & ~int(AMBIGUOUS_FACES[c])]
    orbit_rep = {e: min((apply_symmetry_to_config(s, e[0]), _map_bits(s, e[1])) for s in range(48))
                 for e in entries}
    base = sorted(set(orbit_rep.values()))
    filled = {}
    for c, b in base:
        test, surfaces, ok = _solve_base(c, b)
        rows = [triangulate_case(c, b, surf) for surf in surfaces]
        for s in range(48):
            key = (apply_symmetry_to_config(s, c), _map_bits(s, b))
            sig = tuple(_signature(s, surf) for surf in surfaces)
            if key in filled:
                if filled[key][1] != sig:
                    raise AssertionError(f"inconsistent symmetry images for entry {key} (base {(c, b)})")
                continue
            traced = canonical_loops(trace_loops(*key))
            assert traced == frozenset().union(*sig[0]), f"mapped loops differ from tracing {key}"
            filled[key] = (_map_test(s, test), sig, [_map_tris(s, tris) for tris in rows], ok)
    assert len(filled) == len(entries), "some entries not reached"

    row_index, row_list = {}, []
    case_offset = np.full(256 * 64, -1, dtype=np.int32)
    interior = np.full(256 * 64, -1, dtype=np.int32)
    feasible_mask = np.zeros(256 * 64, dtype=np.int32)
    for (c, b), (test, _, mapped, ok) in sorted(filled.items()):
        key = tuple(tuple(t) for t in mapped)
        if key not in row_index:
            row_index[key] = len(row_list)
            row_list += mapped
        case_offset[c * 64 + b] = row_index[key]
        interior[c * 64 + b] = test
        feasible_mask[c * 64 + b] = int(ok)
    counts = np.array([len(t) for t in row_list], dtype=np.int32)
    max_tris = int(counts.max())
    tris = np.full((len(row_list), max_tris, 3), -1, dtype=np.int32)
    for r, t in enumerate(row_list):
        if t:
            tris[r, : len(t)] = t
    used = [{v for tri in t for v in tri if v >= CENTER_VERTEX} for t in row_list]
    mask = np.array([sum(1 << (v - CENTER_VERTEX) for v in u) for u in used], dtype=np.int32)
    return np.array(base, dtype=np.int32), case_offset, interior, feasible_mask, counts, max_tris, tris, mask


#: (n, 2) orbit representatives (config, face bits) under the 48 cube symmetries
#: (16384,) entry -> first row (-1: bits on a non-ambiguous face), test id or -1,
#: 1 when the entry's face bits occur in exact arithmetic
#: (rows,) triangles per row, (rows, MAX33, 3) triangles (-1 padded), and the interior
#: vertices each row uses (bit j: local vertex 12 + j)
#: (generated once per install, 0.5 s: :mod:`warpmesh.kernels.table_cache`)
(BASE_CASES, CASE_OFFSET, INTERIOR_TEST, CASE_FEASIBLE, CASE_TRI_COUNT, MAX33, CASE_TRIS,
 CASE_INTERIOR) = cached("mc33", _build, __file__, _mc_tables.__file__)


# ----------------------------------------------------------------------------- run time


def config_of(values) -> np.ndarray | int:
    """Configuration of ``(..., 8)`` corner values: bit i set when ``v_i > 0``."""
    v = np.asarray(values, dtype=np.float64)
    out = ((v > 0) << np.arange(8)).sum(axis=-1)
    return int(out) if out.ndim == 0 else out


def face_bits_of(values) -> np.ndarray | int:
    """Asymptotic-decider bits of ``(..., 8)`` corner values (step 2 of the module doc).

    >>> face_bits_of([1.0, -1.0, -1.0, 2.0, -1.0, -1.0, -1.0, -1.0])  # 1 * 2 > 1: joined
    16
    """
    v = np.asarray(values, dtype=np.float64)
    bits = np.zeros(v.shape[:-1], dtype=np.int64)
    for q, (a, b, c, d) in enumerate(FACES):
        ia, ib, ic, id_ = (v[..., x] > 0 for x in (a, b, c, d))
        ambiguous = (ia == ic) & (ib == id_) & (ia != ib)
        pac, pbd = v[..., a] * v[..., c], v[..., b] * v[..., d]
        joined = np.where(ia, pac > pbd, pbd > pac)
        bits |= (ambiguous & joined).astype(np.int64) << q
    return int(bits) if bits.ndim == 0 else bits


def interior_value(values, test: int) -> np.ndarray | int:
    """Interior test ``test`` on ``(..., 8)`` corner values: 0, 1 (inside) or 2 (outside).

    See the module docstring for the formula, why it is exact, and its ties.
    """
    v = np.asarray(values, dtype=np.float64)
    a0, a1, c0, c1, b0, b1, d0, d1 = (v[..., k] for k in TEST_CORNERS[test])
    da, dc, db, dd = a1 - a0, c1 - c0, b1 - b0, d1 - d0
    alpha = da * dc - db * dd
    beta = a0 * dc + c0 * da - b0 * dd - d0 * db
    gamma = a0 * c0 - b0 * d0
    vertex = (alpha < 0) & (beta > 0) & (beta < -2 * alpha)  # t* inside (0, 1), P concave
    disc = beta * beta - 4 * alpha * gamma  # the sign of P(t*)
    sa = -2 * alpha * a0 + da * beta
    sc = -2 * alpha * c0 + dc * beta
    inside = vertex & (disc > 0) & (sa > 0) & (sc > 0)
    outside = vertex & (disc >= 0) & (sa <= 0) & (sc <= 0)  # the level is outside: a tie joins
    out = np.where(inside, 1, np.where(outside, 2, 0))
    return int(out) if out.ndim == 0 else out


def case_row(values) -> int:
    """Row of ``CASE_TRIS`` for one cell's 8 corner values (steps 1-3)."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (8,):
        raise ValueError(f"expected 8 corner values, got shape {v.shape}")
    entry = config_of(v) * 64 + face_bits_of(v)
    row, test = int(CASE_OFFSET[entry]), int(INTERIOR_TEST[entry])
    return row + (interior_value(v, test) if test >= 0 else 0)


def polygonize(values) -> np.ndarray:
    """Triangles of one cell as local vertex ids (0..11 edges, 12 the centre, 13 + k the
    spoke to corner k; positions: ``vertex_positions``).

    Parameters
    ----------
    values : (8,) float
        Corner values, corner i at ``(i & 1, (i >> 1) & 1, (i >> 2) & 1)``; inside > 0.

    Returns
    -------
    (k, 3) int32
        Triangles, counter-clockwise seen from outside.

    Examples
    --------
    >>> polygonize([1.0, -1, -1, -1, -1, -1, -1, -1]).tolist()
    [[0, 4, 8]]
    """
    row = case_row(values)
    return CASE_TRIS[row, : CASE_TRI_COUNT[row]]


def trilinear(values, point) -> float:
    """The trilinear interpolant of 8 corner values at a point of the unit cube.

    >>> trilinear([0, 1, 0, 1, 0, 1, 0, 1], (0.25, 0.5, 0.5))  # f = x
    0.25
    """
    v = [float(a) for a in values]
    x, y, z = (float(a) for a in point)
    bottom = (v[0] + x * (v[1] - v[0])) * (1.0 - y) + (v[2] + x * (v[3] - v[2])) * y
    top = (v[4] + x * (v[5] - v[4])) * (1.0 - y) + (v[6] + x * (v[7] - v[6])) * y
    return bottom * (1.0 - z) + top * z


def hub_point(values, test: int) -> np.ndarray:
    """(3,) the hub of a cell whose interior test ``test`` found a connection.

    The saddle of the slice ``t*`` along the test's axis (where ``P`` peaks): there the
    trilinear interpolant has the sign of the connected corners ``A`` and ``C``. Each
    coordinate is kept within ``HUB_MARGIN`` of the faces (then the sign may differ and
    ``vertex_positions`` falls back to the spokes' midpoints).
    """
    v = np.asarray(values, dtype=np.float64)
    a0, a1, c0, c1, b0, b1, d0, d1 = (v[k] for k in TEST_CORNERS[test])
    da, dc, db, dd = a1 - a0, c1 - c0, b1 - b0, d1 - d0
    alpha = da * dc - db * dd
    beta = a0 * dc + c0 * da - b0 * dd - d0 * db
    axis = test // 2
    u, w = (x for x in range(3) if x != axis)
    t = -beta / (2.0 * alpha)
    s = [[v[(du << u) | (dw << w)] + t * (v[(du << u) | (dw << w) | (1 << axis)] - v[(du << u) | (dw << w)])
          for dw in (0, 1)] for du in (0, 1)]  # s[du][dw]: the slice's corner values
    e = s[1][1] - s[1][0] - s[0][1] + s[0][0]
    hub = np.empty(3)
    hub[axis], hub[u], hub[w] = t, (s[0][0] - s[0][1]) / e, (s[0][0] - s[1][0]) / e
    return np.clip(hub, HUB_MARGIN, 1.0 - HUB_MARGIN)


def vertex_positions(values, t_min: float = 1.0e-3, clearance: float = 0.0, *, row: int | None = None,
                     iterations: int = 30) -> np.ndarray:
    """(21, 3) positions in the unit cube of the local vertices of a cell's row (NaN unused).

    The reference for the emit kernels (away from capped faces): an edge vertex by linear
    interpolation, its parameter clamped to ``[gap, 1 - gap]``, ``gap = max(t_min,
    clearance)``; vertex 12 at the mean of the edge vertices; spoke vertex ``13 + k`` at
    the root of the trilinear interpolant on the segment from the hub (``hub_point``) to
    corner ``k``, by bisection, its parameter clamped likewise (the midpoint when the
    hub's value does not have the sign of the connection). ``row``: the cell's
    ``case_row``, when known.

    >>> p = vertex_positions([1.0, -1, -1, -1, -1, -1, -1, -1])
    >>> p[[0, 4, 8]].tolist()
    [[0.5, 0.0, 0.0], [0.0, 0.5, 0.0], [0.0, 0.0, 0.5]]
    """
    v = [float(x) for x in values]
    gap = max(t_min, clearance)
    out = np.full((21, 3), np.nan)
    cross = []
    for e, (a, b) in enumerate(EDGES.tolist()):
        if (v[a] > 0) != (v[b] > 0):
            t = min(max(v[a] / (v[a] - v[b]), gap), 1.0 - gap)
            out[e] = CORNERS[a] + t * (CORNERS[b] - CORNERS[a])
            cross.append(e)
    if cross:
        out[CENTER_VERTEX] = out[cross].mean(axis=0)
    row = case_row(v) if row is None else row
    spokes = [k for k in range(8) if (CASE_INTERIOR[row] >> (1 + k)) & 1]
    if spokes:
        hub = hub_point(v, int(INTERIOR_TEST[config_of(v) * 64 + face_bits_of(v)]))
        f_hub = trilinear(v, hub)
        for k in spokes:
            tau = 0.5
            if (f_hub > 0) != (v[k] > 0):
                lo, hi = 0.0, 1.0
                d = [float(c) - h for c, h in zip(CORNERS[k], hub)]
                for _ in range(iterations):
                    mid = 0.5 * (lo + hi)
                    if (trilinear(v, [h + mid * e for h, e in zip(hub, d)]) > 0) == (f_hub > 0):
                        lo = mid
                    else:
                        hi = mid
                tau = 0.5 * (lo + hi)
            out[SPOKE_VERTEX + k] = hub + min(max(tau, gap), 1.0 - gap) * (CORNERS[k] - hub)
    return out


def kernel_tables() -> dict[str, np.ndarray]:
    """The int32 arrays of ``warpmesh.kernels.emit.Tables`` for method "mc33"."""
    rows = len(CASE_TRI_COUNT)
    return {
        "origin": VERTEX_ORIGIN,
        "tri_count": CASE_TRI_COUNT,
        "tris": CASE_TRIS.reshape(rows, -1),
        "quad_count": np.zeros(rows, np.int32),
        "quads": np.zeros((rows, 4), np.int32),
        "center": CASE_INTERIOR,
        "case_offset": CASE_OFFSET,
        "interior_test": INTERIOR_TEST,
        "test_corners": TEST_CORNERS,
        "face_corners": FACE_CORNERS,
    }
