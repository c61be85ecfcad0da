"""Marching-cubes-33 tables: per cell, the topology of the trilinear interpolant.

Pure Python + numpy (no warp import): kernel modules import these arrays and upload them.
Corners, edges, faces, symmetries, the inside / winding conventions and the loop tracing
are those of :mod:`warpmesh.kernels.mc_tables`: corner ``i`` at
``(i & 1, (i >> 1) & 1, (i >> 2) & 1)`` is *inside* when its value ``v_i > 0``
(``v <= 0`` is outside), triangles are counter-clockwise seen from outside
(``(p1 - p0) x (p2 - p0)`` points towards ``v <= 0``), local vertices ``0..11`` are the
cube edges. Local vertex ``12`` (``CENTER_VERTEX``) is an optional vertex inside the cell,
placed by the kernel at the mean of the cell's edge vertices.

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
4. Triangles ``CASE_TRIS[row, :CASE_TRI_COUNT[row]]``; ``CASE_NEEDS_CENTER[row]`` is 1
   when they use vertex 12.

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

    hit = alpha < 0 and 0 < beta < -2 alpha and beta^2 - 4 alpha gamma > 0
    sa  = -2 alpha v[a0] + (v[a1] - v[a0]) beta      # sign of A(t*)
    sc  = -2 alpha v[c0] + (v[c1] - v[c0]) beta      # sign of C(t*)
    value = 1 if hit and sa > 0 and sc > 0 else 2 if hit and sa < 0 and sc < 0 else 0

(a few multiplies, no division, no square root). ``hit`` says that the concave
quadratic ``P`` has its vertex ``t*`` in (0, 1) with ``P(t*) > 0``.

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
row for that value is the same as for 0. Ties (``P(t*) = 0``, a singular surface) give 0.
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
(an annulus; never more in a trilinear cell). Triangulations maximise the minimum
angle (vertices at edge midpoints) with the dynamic programme of
``mc_tables.triangulate`` and one more rule: a triangle edge lying in a cube face that
is not a face segment (a *chord*) is avoided, as the neighbouring cell could use the
same edge. A disk without a chord-free triangulation becomes a fan around vertex 12. A
tube is cut open along a rung between its loops, or along a path through vertex 12,
and triangulated as a polygon. The tubes of cases 7.4.2, 10.1.2, 12.1.2 and 13.5.2 have
no chord-free triangulation even with vertex 12 (each loop edge needs a third vertex
off its faces); they use the chords allowed by ``face_chords``, a rule that keeps the
two cells of a face from ever sharing one. At most one component of a row uses
vertex 12 (two fans on one vertex would pinch).

Generation
----------
Table entries are pairs (config, face bits) with bits only on ambiguous faces. Only
orbit representatives under the 48 cube symmetries are solved (``BASE_CASES``); every
entry is then filled by mapping edges, faces and the test's corners through a symmetry
(winding reversed for a reflection), asserting that all symmetries reaching an entry
agree on its loops, components and test outcomes, and that the mapped loops are those
traced directly. Rows with chords depend on which faces are lower ones: they are
triangulated again for each of the 8 reflections and mapped by axis permutations,
which keep the chord rule. Complementation (inside <-> outside, face bits flipped, values 1 <-> 2)
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
>>> len(polygonize(v)), len(polygonize(np.where(v > 0, 0.2, -1.0)))  # tube, two triangles
(6, 2)
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np

from warpmesh.kernels.mc_tables import (
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
    "CENTER_TYPE",
    "VERTEX_ORIGIN",
    "FACE_CORNERS",
    "AMBIGUOUS_FACES",
    "TEST_CORNERS",
    "INTERIOR_TEST",
    "CASE_OFFSET",
    "CASE_FEASIBLE",
    "CASE_TRI_COUNT",
    "CASE_TRIS",
    "CASE_NEEDS_CENTER",
    "MAX33",
    "BASE_CASES",
    "config_of",
    "face_bits_of",
    "interior_value",
    "case_row",
    "polygonize",
    "kernel_tables",
    "trace_loops",
    "patch_labels",
    "case_surfaces",
]

#: local id of the optional vertex inside the cell
CENTER_VERTEX = 12
#: vertex type of that vertex in the emit kernels (``warpmesh.kernels.emit.CENTER``)
CENTER_TYPE = 7
#: (13, 4) local vertex -> (dx, dy, dz, type): the 12 cube edges, then the cell centre
VERTEX_ORIGIN = np.ascontiguousarray(np.vstack([EDGE_ORIGIN, [[0, 0, 0, CENTER_TYPE]]]), dtype=np.int32)
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
    """Whether the segment between the vertices of edges a and b lies in a cube face."""
    return a != CENTER_VERTEX and b != CENTER_VERTEX and bool(_SHARE_FACE[a, b])


def face_chords(config: int, bits: int) -> tuple[frozenset, list[tuple[frozenset, frozenset]]]:
    """Chords (edges lying in a cube face) a row of this entry may use, when it must.

    On an ambiguous face the two face segments cut off two corners; the other two
    (*band*) corners are joined across the face. Four chords join the two segments: a
    *short* one at each band corner (its two face edges) and two *long* ones (two
    opposite face edges), which cross. The cell above a face (for which it is a lower
    face, ``x, y`` or ``z = 0``) may use the short chords, the cell below it the long
    ones, one per face: the two cells never share a chord (so the global surface stays
    a 2-manifold) and their chords meet only at mesh vertices.

    Returns the short chords and, per upper ambiguous face, its two long chords.
    """
    shorts, longs = set(), []
    for q, face in enumerate(FACES):
        if not (AMBIGUOUS_FACES[config] >> q) & 1:
            continue
        band = _inside(config, face[0]) == (bits >> q) & 1  # face[0], face[2] are joined
        m1, k1, m2, k2 = face if band else face[1:] + face[:1]
        e = {(x, y): EDGE_OF[x, y] for x, y in ((m1, k1), (k1, m2), (m2, k2), (k2, m1))}
        if q % 2 == 0:
            shorts |= {frozenset((e[k2, m1], e[m1, k1])), frozenset((e[k1, m2], e[m2, k2]))}
        else:
            longs.append((frozenset((e[m1, k1], e[m2, k2])), frozenset((e[k1, m2], e[k2, m1]))))
    return frozenset(shorts), longs


def triangulate_polygon(poly: list[int], angles, forbidden=frozenset(), allowed=frozenset(),
                        forbidden_pos=frozenset()):
    """Best triangulation of a polygon of vertex ids, or None.

    Returns ``((-chords, min angle), triangles as ids, triangles as positions)``;
    ``angles`` is ``_angles(config)``.

    ``poly`` runs counter-clockwise seen from outside (a loop, or a tube cut open, in
    which some ids appear twice). The same dynamic programme as
    ``mc_tables.triangulate``, maximising first minus the number of diagonals lying in
    a cube face (only those of ``allowed`` may), then the minimum angle (vertices at
    edge midpoints). A diagonal must join two different ids and not be an edge of
    ``forbidden`` (frozensets of 2 ids: the loop segments and the cut) nor a pair of
    positions in ``forbidden_pos``. With repeated ids the result may use one edge
    twice; ``triangulate_tube`` checks and searches on.
    """
    n = len(poly)
    cost = [[0] * n for _ in range(n)]  # per position pair: chords added, or None
    for i in range(n):
        for j in range(i + 2, n):
            a, b = poly[i], poly[j]
            if a == b or frozenset((a, b)) in forbidden or (i, j) in forbidden_pos:
                cost[i][j] = None
            elif _in_face(a, b):
                cost[i][j] = 1 if frozenset((a, b)) in allowed else None
    # best sub-polygon i..j: chords used, minimum angle, split vertex (None: impossible)
    chords = [[None] * n for _ in range(n)]
    angle = [[0.0] * n for _ in range(n)]
    split = [[-1] * n for _ in range(n)]
    for i in range(n - 1):
        chords[i][i + 1], angle[i][i + 1] = 0, np.inf
    for length in range(2, n):
        for i in range(n - length):
            j = i + length
            a, c = poly[i], poly[j]
            row_a = angles[a]
            best_c, best_a, best_k = None, -1.0, -1
            for k in range(i + 1, j):
                cl, cr, ci, cj = chords[i][k], chords[k][j], cost[i][k], cost[k][j]
                if cl is None or cr is None or ci is None or cj is None:
                    continue
                b = poly[k]
                if a == b or b == c or a == c:
                    continue
                total = cl + cr + ci + cj
                worst = min(angle[i][k], angle[k][j], row_a[b][c])
                if best_c is None or total < best_c or (total == best_c and worst > best_a):
                    best_c, best_a, best_k = total, worst, k
            chords[i][j], angle[i][j], split[i][j] = best_c, best_a, best_k
    if chords[0][n - 1] is None or angle[0][n - 1] <= 0:
        return None
    tris, stack = [], [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i >= 2:
            k = split[i][j]
            tris.append((i, k, j))
            stack += [(k, j), (i, k)]
    score = (-chords[0][n - 1], angle[0][n - 1])
    return score, [(poly[i], poly[k], poly[j]) for i, k, j in tris], tris


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


def fan(loop: list[int]) -> list[tuple[int, int, int]]:
    """Triangles joining each segment of a loop to vertex 12."""
    return [(loop[k], loop[(k + 1) % len(loop)], CENTER_VERTEX) for k in range(len(loop))]


def _tube_polygons(a: list[int], b: list[int], center: bool):
    """The annulus between loops a and b cut open: (polygon, cut edges) per cut.

    The cut is a rung ``a_i - b_j`` or, with ``center``, the path ``a_i - 12 - b_j``
    (vertex 12 then lies inside the tube); the polygon runs along ``a``, down the cut,
    along ``b`` (both in their own direction) and back up the cut. Shortest rungs
    first (vertices at edge midpoints), so that good tubes are found early.
    """
    cuts = sorted(itertools.product(range(len(a)), range(len(b))),
                  key=lambda ij: (round(float(np.sum((EDGE_MIDPOINTS[a[ij[0]]] - EDGE_MIDPOINTS[b[ij[1]]]) ** 2)), 9), ij))
    for i, j in cuts:
        ra, rb = a[i:] + a[:i] + a[i:i + 1], b[j:] + b[:j] + b[j:j + 1]
        if center:
            yield ra + [CENTER_VERTEX] + rb + [CENTER_VERTEX], {(a[i], CENTER_VERTEX), (CENTER_VERTEX, b[j])}
        else:
            yield ra + rb, {(a[i], b[j])}


def _crosses(tris, longs) -> bool:
    """Whether triangles use both (crossing) long chords of some face."""
    edges = {frozenset((t[k], t[(k + 1) % 3])) for t in tris for k in range(3)}
    return any(la in edges and lb in edges for la, lb in longs)


def _repeated_diagonals(poly, tris_pos):
    """Position pairs of diagonals that join the same two ids as another diagonal."""
    seen = {}
    for t in tris_pos:
        for k in range(3):
            i, j = sorted((t[k], t[(k + 1) % 3]))
            if (j - i) % len(poly) not in (1, len(poly) - 1):  # a diagonal, not a side
                seen.setdefault(frozenset((poly[i], poly[j])), set()).add((i, j))
    return [pairs for pairs in seen.values() if len(pairs) > 1]


def triangulate_tube(a: list[int], b: list[int], angles, *, center: bool,
                     allowed=frozenset(), longs=(), max_runs: int = 8):
    """Best ``(score, triangles)`` of the annulus between loops a and b, or None.

    Every cut of ``_tube_polygons`` is triangulated by ``triangulate_polygon`` (a cut
    rung lying in a face counts as a chord). When the result joins two ids twice (an
    id repeated in the polygon), the search branches, forbidding in turn each position
    pair of that diagonal (at most ``max_runs`` runs per cut). The best result that
    forms an annulus and uses at most one long chord per face wins.
    """
    best = None
    for poly, cut in _tube_polygons(a, b, center):
        if any(_in_face(*c) and frozenset(c) not in allowed for c in cut):
            continue
        chords = sum(_in_face(*c) for c in cut)
        forbidden = _segments([a, b]) | {frozenset(c) for c in cut}
        todo, runs = [frozenset()], 0
        while todo and runs < max_runs:
            pos, runs = todo.pop(), runs + 1
            found = triangulate_polygon(poly, angles, forbidden, allowed, pos)
            if found is None:
                continue
            score = (found[0][0] - chords, found[0][1])
            if best is not None and score <= best[0]:
                continue  # branching only removes options: no better result down here
            repeated = _repeated_diagonals(poly, found[2])
            if repeated:
                todo += [pos | {pair} for pair in sorted(repeated[0])]
            elif is_surface(found[1], [a, b]) and not _crosses(found[1], longs):
                best = (score, found[1])
    return best


def _component_options(loops, angles, allowed=frozenset(), longs=()):
    """Ways to triangulate one component: [(chords, uses 12, min angle, triangles)]."""
    options = []
    if len(loops) == 1:
        found = triangulate_polygon(loops[0], angles, _segments(loops), allowed)
        if found:
            options.append((-found[0][0], False, found[0][1], found[1]))
        if not allowed:
            options.append((0, True, min(angles[a][b][c] for a, b, c in fan(loops[0])), fan(loops[0])))
        return options
    for center in (False, True):  # through 12 only when it may win (fewer chords)
        if center and options and (not allowed or options[0][0] <= 1):
            break
        found = triangulate_tube(*loops, angles, center=center, allowed=allowed, longs=longs)
        if found:
            options.append((-found[0][0], center, found[0][1], found[1]))
    return options


def triangulate_case(config: int, bits: int, surfaces, *, chord_free_tubes: bool = True
                     ) -> tuple[list[tuple[int, int, int]], bool, int]:
    """Triangles of one row, whether they use vertex 12, and how many chords.

    Each component gets its options (a disk or tube without chords, through vertex 12
    or not; only if that fails, with the chords of ``face_chords``); the combination
    with at most one component on vertex 12 wins by fewest chords, then fewest uses of
    12, then largest minimum angle. ``chord_free_tubes=False`` skips the search for
    tubes without chords (known to fail, e.g. in a symmetric image of a solved row).
    """
    angles = _angles(config)
    options = [_component_options(loops, angles) if chord_free_tubes or len(loops) == 1 else []
               for loops in surfaces]
    if _pick(options) is None:
        shorts, longs = face_chords(config, bits)
        allowed = shorts | {c for pair in longs for c in pair}
        options = [opts + _component_options(loops, angles, allowed, longs) for opts, loops in zip(options, surfaces)]
    choice = _pick(options)
    assert choice is not None, f"config {config} bits {bits}: no triangulation of {surfaces}"
    return [t for opt in choice for t in opt[3]], any(opt[1] for opt in choice), sum(opt[0] for opt in choice)


def _pick(options):
    """Best combination of one option per component, at most one using vertex 12."""
    best, best_key = None, None
    for combo in itertools.product(*options):
        if sum(opt[1] for opt in combo) > 1:
            continue
        key = (-sum(opt[0] for opt in combo), -sum(opt[1] for opt in combo), min([opt[2] for opt in combo] or [0]))
        if best_key is None or key > best_key:
            best, best_key = combo, key
    return best


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
    edge = list(SYM_EDGES[s].tolist()) + [CENTER_VERTEX]
    out = [tuple(edge[v] for v in t) for t in tris]
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
    """Solve the base entries, fill the others by symmetry (see the module docstring).

    A row with chords in cube faces depends on which faces are upper ones
    (``face_chords``), which a reflection changes: such rows are triangulated again in
    each image by reflections, from the mapped surfaces, then permuted.
    """
    entries = [(c, b) for c in range(256) for b in range(64) if not b & ~int(AMBIGUOUS_FACES[c])]
    orbit_rep = {e: min((apply_symmetry_to_config(s, e[0]), _map_bits(s, e[1])) for s in range(48))
                 for e in entries}
    base = sorted(set(orbit_rep.values()))
    filled = {}
    for c, b in base:
        test, surfaces, ok = _solve_base(c, b)
        rows = [triangulate_case(c, b, surf) for surf in surfaces]
        flipped = {}
        for s in range(48):
            key = (apply_symmetry_to_config(s, c), _map_bits(s, b))
            sig = tuple(_signature(s, surf) for surf in surfaces)
            if key in filled:
                if filled[key][1] != sig:
                    raise AssertionError(f"inconsistent symmetry images for entry {key} (base {(c, b)})")
                continue
            traced = canonical_loops(trace_loops(*key))
            assert traced == frozenset().union(*sig[0]), f"mapped loops differ from tracing {key}"
            mapped = []
            for r, ((tris, center, chords), surf) in enumerate(zip(rows, surfaces)):
                if chords:  # the chord rule is invariant under axis permutations only
                    flip, perm = s % 8, s - s % 8  # s = (permutation of axes) o (flips)
                    if (r, flip) not in flipped:
                        image = (apply_symmetry_to_config(flip, c), _map_bits(flip, b))
                        flipped[r, flip] = triangulate_case(*image, [_map_loops(flip, lp) for lp in surf],
                                                            chord_free_tubes=False)
                    tris, center, _ = flipped[r, flip]
                    tris = _map_tris(perm, tris)
                else:
                    tris = _map_tris(s, tris)
                mapped.append((tris, center))
            filled[key] = (_map_test(s, test), sig, mapped, ok)
    assert len(filled) == len(entries), "some entries not reached"

    row_index, row_list = {}, []
    case_offset = np.full(256 * 64, -1, dtype=np.int32)
    interior = np.full(256 * 64, -1, dtype=np.int32)
    feasible_mask = np.zeros(256 * 64, dtype=np.int32)
    for (c, b), (test, _, mapped, ok) in sorted(filled.items()):
        key = tuple(tuple(t) for t, _ in mapped)
        if key not in row_index:
            row_index[key] = len(row_list)
            row_list += mapped
        case_offset[c * 64 + b] = row_index[key]
        interior[c * 64 + b] = test
        feasible_mask[c * 64 + b] = int(ok)
    counts = np.array([len(t) for t, _ in row_list], dtype=np.int32)
    max_tris = int(counts.max())
    tris = np.full((len(row_list), max_tris, 3), -1, dtype=np.int32)
    for r, (t, _) in enumerate(row_list):
        if t:
            tris[r, : len(t)] = t
    center = np.array([int(cu) for _, cu in row_list], dtype=np.int32)
    return np.array(base, dtype=np.int32), case_offset, interior, feasible_mask, counts, max_tris, tris, center


#: (n, 2) orbit representatives (config, face bits) under the 48 cube symmetries
#: (16384,) entry -> first row (-1: bits on a non-ambiguous face), test id or -1,
#: 1 when the entry's face bits occur in exact arithmetic
#: (rows,) triangles per row, (rows, MAX33, 3) triangles (-1 padded), uses of vertex 12
(BASE_CASES, CASE_OFFSET, INTERIOR_TEST, CASE_FEASIBLE, CASE_TRI_COUNT, MAX33, CASE_TRIS,
 CASE_NEEDS_CENTER) = _build()


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

    See the module docstring for the formula and why it is exact.
    """
    v = np.asarray(values, dtype=np.float64)
    a0, a1, c0, c1, b0, b1, d0, d1 = (v[..., k] for k in TEST_CORNERS[test])
    da, dc, db, dd = a1 - a0, c1 - c0, b1 - b0, d1 - d0
    alpha = da * dc - db * dd
    beta = a0 * dc + c0 * da - b0 * dd - d0 * db
    gamma = a0 * c0 - b0 * d0
    hit = (alpha < 0) & (beta > 0) & (beta < -2 * alpha) & (beta * beta - 4 * alpha * gamma > 0)
    sa = -2 * alpha * a0 + da * beta
    sc = -2 * alpha * c0 + dc * beta
    out = np.where(hit & (sa > 0) & (sc > 0), 1, np.where(hit & (sa < 0) & (sc < 0), 2, 0))
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
    """Triangles of one cell as local vertex ids (0..11 edges, 12 the centre).

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


def kernel_tables() -> dict[str, np.ndarray]:
    """The int32 arrays of ``warpmesh.kernels.emit.Tables`` for method "mc33"."""
    rows = len(CASE_TRI_COUNT)
    return {
        "origin": VERTEX_ORIGIN,
        "tri_count": CASE_TRI_COUNT,
        "tris": CASE_TRIS.reshape(rows, -1),
        "quad_count": np.zeros(rows, np.int32),
        "quads": np.zeros((rows, 4), np.int32),
        "center": CASE_NEEDS_CENTER,
        "case_offset": CASE_OFFSET,
        "interior_test": INTERIOR_TEST,
        "test_corners": TEST_CORNERS,
        "face_corners": FACE_CORNERS,
    }
