"""Triangle–triangle intersection tests for the self-intersection check of a surface
mesh; the host partner is :mod:`warpmesh.cells.intersections`.

Predicates run in float64 on the host's points; the group tree (a complete binary tree
of float32 boxes over groups of faces in Morton order, :func:`tree_next`) only proposes
candidates. Every sign comes from a determinant of three difference
vectors, compared with Shewchuk's static error bound (``errboundA``, doubled): a sign
within its bound counts as zero, so configurations within float64 rounding of touching
are decided as touching; a "touching" that rests on such a tie is confirmed in a 2D
projection, where nearly coplanar pairs are well conditioned (:func:`pair_intersects`).
With ``fuse_fp`` off the kernels round every operation on its own, which the bound
assumes.

Notation: O(a, b, c, d) = ((b - a) x (c - a)) . (d - a); a triangle's plane side of x is
O of its vertices and x. Two triangles share k vertex *indices* (k = 0..3); see
:func:`pair_intersects` for what counts as an intersection for each k. Pairs that share
a vertex whose faces are certified to meet only where they share
(:func:`umbrella_certified`) never reach the predicate.
"""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

_EPS = 2.0**-53
#: Shewchuk's orient3d / orient2d errboundA, doubled (FMA contraction is off; margin)
O3_BOUND = wp.constant(wp.float64(2.0 * (7.0 + 56.0 * _EPS) * _EPS))
O2_BOUND = wp.constant(wp.float64(2.0 * (3.0 + 16.0 * _EPS) * _EPS))
#: absolute floor of every bound: products below it may be subnormal
TINY = wp.constant(wp.float64(1.0e-290))
#: how far (absolute, per coordinate) the given points may be from the configuration they
#: stand for: a few ulps at 1, the points being scaled to max |x| < 1 (a rounded rotation,
#: an interpolated refinement node). Only certificates of separation use it (see
#: :func:`orient2d_margin`); the signs that decide "meet" do not.
INPUT_TOL = wp.constant(wp.float64(2.0**-48))


@wp.func
def _filtered_sign(det: wp.float64, perm: wp.float64, rel: wp.float64) -> int:
    bound = rel * perm + TINY
    if det > bound:
        return 1
    if det < -bound:
        return -1
    return 0


@wp.func
def _abs_cross(u: wp.vec3d, v: wp.vec3d) -> wp.vec3d:
    """The permanent companion of ``cross(u, v)``: |u_y v_z| + |u_z v_y|, ..."""
    return wp.vec3d(
        wp.abs(u[1] * v[2]) + wp.abs(u[2] * v[1]),
        wp.abs(u[2] * v[0]) + wp.abs(u[0] * v[2]),
        wp.abs(u[0] * v[1]) + wp.abs(u[1] * v[0]),
    )


@wp.func
def _abs3(u: wp.vec3d) -> wp.vec3d:
    return wp.vec3d(wp.abs(u[0]), wp.abs(u[1]), wp.abs(u[2]))


@wp.func
def plane_side(x: wp.vec3d, a: wp.vec3d, n: wp.vec3d, m: wp.vec3d) -> int:
    """Sign of O(a, b, c, x) for a triangle (a, b, c) with n = (b - a) x (c - a) and m its
    permanent companion (:func:`_abs_cross`)."""
    w = x - a
    return _filtered_sign(wp.dot(n, w), wp.dot(m, _abs3(w)), O3_BOUND)


@wp.func
def _side_unless(x: wp.vec3d, k: int, shared: int, a: wp.vec3d, n: wp.vec3d, m: wp.vec3d) -> int:
    """:func:`plane_side` of vertex k, x; exactly 0 for the shared vertex (k == shared)."""
    if k == shared:
        return 0
    return plane_side(x, a, n, m)


@wp.func
def orient3d(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, d: wp.vec3d) -> int:
    """Sign of O(a, b, c, d): positive when d is on the side of plane (a, b, c) that its
    right-hand normal points to."""
    u = b - a
    v = c - a
    return plane_side(d, a, wp.cross(u, v), _abs_cross(u, v))


@wp.func
def _det2d(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, i: int, j: int) -> wp.vec2d:
    """The 2D orientation determinant of (a, b, c) on coordinates (i, j) and its permanent
    (the sum of the two products' magnitudes, for the error bound)."""
    acx = a[i] - c[i]
    bcx = b[i] - c[i]
    acy = a[j] - c[j]
    bcy = b[j] - c[j]
    l = acx * bcy
    r = acy * bcx
    return wp.vec2d(l - r, wp.abs(l) + wp.abs(r))


@wp.func
def orient2d(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, i: int, j: int) -> int:
    """Sign of the 2D orientation of (a, b, c) on coordinates (i, j): positive when
    counter-clockwise."""
    d = _det2d(a, b, c, i, j)
    return _filtered_sign(d[0], d[1], O2_BOUND)


@wp.func
def _in_box_2d(a: wp.vec3d, b: wp.vec3d, x: wp.vec3d, i: int, j: int) -> bool:
    return (wp.min(a[i], b[i]) <= x[i] and x[i] <= wp.max(a[i], b[i])
            and wp.min(a[j], b[j]) <= x[j] and x[j] <= wp.max(a[j], b[j]))


@wp.func
def segments_meet_2d(o1: int, o2: int, o3: int, o4: int, p1: wp.vec3d, p2: wp.vec3d, p3: wp.vec3d,
                     p4: wp.vec3d, i: int, j: int) -> bool:
    """Closed segments [p1, p2] and [p3, p4] meet (coordinates i, j), given the orientations
    o1 = orient2d(p1, p2, p3), o2 = orient2d(p1, p2, p4), o3 = orient2d(p3, p4, p1) and
    o4 = orient2d(p3, p4, p2)."""
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    if o1 == 0 and _in_box_2d(p1, p2, p3, i, j):
        return True
    if o2 == 0 and _in_box_2d(p1, p2, p4, i, j):
        return True
    if o3 == 0 and _in_box_2d(p3, p4, p1, i, j):
        return True
    if o4 == 0 and _in_box_2d(p3, p4, p2, i, j):
        return True
    return False


@wp.func
def edge_sides_2d(u: wp.vec3d, w: wp.vec3d, t: wp.mat33d, i: int, j: int) -> wp.vec3i:
    """orient2d(u, w, t[c]) for the three rows c of t."""
    return wp.vec3i(orient2d(u, w, t[0], i, j), orient2d(u, w, t[1], i, j), orient2d(u, w, t[2], i, j))


@wp.func
def coplanar_edges_meet(p: wp.mat33d, q: wp.mat33d, i: int, j: int) -> bool:
    """Some edge of p meets some edge of q (rows, coordinates i, j). Each of the 18
    edge-vertex orientations is computed once: op[a, c] = orient2d(p[a], p[a + 1], q[c]),
    oq[b, c] = orient2d(q[b], q[b + 1], p[c])."""
    op = wp.matrix_from_rows(edge_sides_2d(p[0], p[1], q, i, j), edge_sides_2d(p[1], p[2], q, i, j),
                             edge_sides_2d(p[2], p[0], q, i, j))
    oq = wp.matrix_from_rows(edge_sides_2d(q[0], q[1], p, i, j), edge_sides_2d(q[1], q[2], p, i, j),
                             edge_sides_2d(q[2], q[0], p, i, j))
    for a in range(3):
        a1 = (a + 1) % 3
        for b in range(3):
            b1 = (b + 1) % 3
            if segments_meet_2d(op[a, b], op[a, b1], oq[b, a], oq[b, a1], p[a], p[a1], q[b], q[b1], i, j):
                return True
    return False


#: a distance (absolute, points scaled into [-1, 1]^3) that certifies two coplanar triangles'
#: projections apart for :func:`coplanar_overlap`'s edge tests, which only report a pair
#: that has a point within 8 O2_BOUND (< 1e-14) of the other triangle
SEPARATION_GAP = wp.constant(wp.float64(2.0**-40))


@wp.func
def edge_separates_2d(t: wp.mat33d, other: wp.mat33d, st: int, i: int, j: int) -> bool:
    """Some edge line of triangle t (rows; st != 0 its certified orientation on coordinates
    i, j) has the three vertices of ``other`` on its outer side, each at a distance
    certified above ``SEPARATION_GAP``: the determinant of :func:`orient2d` exceeds its
    error bound by the gap times twice the edge's L1 length (an upper bound of its
    length)."""
    for a in range(3):
        u = t[a]
        w = t[(a + 1) % 3]
        length = wp.float64(2.0) * (wp.abs(u[i] - w[i]) + wp.abs(u[j] - w[j]))
        out = int(0)
        for c in range(3):
            acx = u[i] - other[c][i]
            bcx = w[i] - other[c][i]
            acy = u[j] - other[c][j]
            bcy = w[j] - other[c][j]
            l = acx * bcy
            r = acy * bcx
            if -(l - r) * wp.float64(st) > O2_BOUND * (wp.abs(l) + wp.abs(r)) + TINY + SEPARATION_GAP * length:
                out += 1
        if out == 3:
            return True
    return False


@wp.func
def coplanar_overlap(p: wp.mat33d, q: wp.mat33d, i: int, j: int) -> bool:
    """Closed coplanar triangles p, q (rows) meet: some edges meet
    (:func:`coplanar_edges_meet`), or one holds a vertex of the other (then it holds all
    of it); a triangle that projects to a segment holds everything (conservative).

    The edge tests are skipped when an edge line of one has the other certified outside
    by ``SEPARATION_GAP`` (:func:`edge_separates_2d`), for then they are all false: a
    crossing with nonzero signs is a true crossing, and a tie with the vertex in the other
    segment's box puts the vertex within 8 O2_BOUND |segment| of it (the determinant's
    permanent is at most 2 |segment|^2 there, and the box holds the foot of the
    perpendicular), both impossible across a gap. The containment tests are the same
    signs either way, so the answer is the same with or without the shortcut."""
    sq = orient2d(q[0], q[1], q[2], i, j)
    sp = orient2d(p[0], p[1], p[2], i, j)
    if not ((sp != 0 and edge_separates_2d(p, q, sp, i, j)) or (sq != 0 and edge_separates_2d(q, p, sq, i, j))):
        if coplanar_edges_meet(p, q, i, j):
            return True
    if (orient2d(q[0], q[1], p[0], i, j) * sq >= 0 and orient2d(q[1], q[2], p[0], i, j) * sq >= 0
            and orient2d(q[2], q[0], p[0], i, j) * sq >= 0):
        return True  # p[0] in q
    return (orient2d(p[0], p[1], q[0], i, j) * sp >= 0 and orient2d(p[1], p[2], q[0], i, j) * sp >= 0
            and orient2d(p[2], p[0], q[0], i, j) * sp >= 0)  # q[0] in p


@wp.func
def orient2d_margin(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, i: int, j: int) -> int:
    """:func:`orient2d`'s sign when it holds by a margin: the same for every move of a, b, c
    by up to ``INPUT_TOL`` per coordinate (besides the rounding of the computation), else
    0. Moving the points by delta changes each difference by at most 2 delta, the
    determinant by at most 2 delta (|acx| + |acy| + |bcx| + |bcy|) + 8 delta^2."""
    acx = a[i] - c[i]
    bcx = b[i] - c[i]
    acy = a[j] - c[j]
    bcy = b[j] - c[j]
    l = acx * bcy
    r = acy * bcx
    lin = wp.abs(acx) + wp.abs(acy) + wp.abs(bcx) + wp.abs(bcy)
    moved = wp.float64(2.0) * INPUT_TOL * lin * (wp.float64(1.0) + O2_BOUND) + wp.float64(8.0) * INPUT_TOL * INPUT_TOL
    det = l - r
    bound = O2_BOUND * (wp.abs(l) + wp.abs(r)) + moved + TINY
    if det > bound:
        return 1
    if det < -bound:
        return -1
    return 0


@wp.func
def _ray_outside_wedge_2d(v: wp.vec3d, a: wp.vec3d, b: wp.vec3d, x: wp.vec3d, i: int, j: int) -> bool:
    """The ray from v through x is certified (:func:`orient2d_margin`) outside the closed
    convex wedge at v spanned by a and b: beyond one of its edge lines, or strictly on one
    side of both (outside whatever the wedge's orientation: a sliver's wedge)."""
    oa = orient2d_margin(v, a, x, i, j)
    ob = orient2d_margin(v, b, x, i, j)
    if oa != 0 and oa == ob:
        return True
    s = orient2d_margin(v, a, b, i, j)
    if s == 0:
        return False
    return oa * s < 0 or ob * s > 0  # x before a, or past b: orient(v, x, b) = -ob


@wp.func
def wedges_apart_2d(v: wp.vec3d, pa: wp.vec3d, pb: wp.vec3d, qa: wp.vec3d, qb: wp.vec3d, i: int, j: int) -> bool:
    """The wedges at v spanned by (pa, pb) and by (qa, qb) are certified to share no ray
    (coordinates i, j): each of the four edge rays is certified outside the other wedge
    (two convex wedges share a ray iff an edge ray of one lies in the other). Collinear
    edge rays pointing opposite ways are apart (the other edge of each wedge decides);
    pointing the same way they are never apart."""
    return (_ray_outside_wedge_2d(v, pa, pb, qa, i, j) and _ray_outside_wedge_2d(v, pa, pb, qb, i, j)
            and _ray_outside_wedge_2d(v, qa, qb, pa, i, j) and _ray_outside_wedge_2d(v, qa, qb, pb, i, j))


@wp.func
def _outside_edge_2d(t: wp.mat33d, other: wp.mat33d, i: int, j: int) -> bool:
    """Some edge line of triangle t has all of ``other`` certified on its outer side."""
    s = orient2d_margin(t[0], t[1], t[2], i, j)
    if s == 0:
        return False
    for a in range(3):
        u = t[a]
        w = t[(a + 1) % 3]
        if (orient2d_margin(u, w, other[0], i, j) * s < 0 and orient2d_margin(u, w, other[1], i, j) * s < 0
                and orient2d_margin(u, w, other[2], i, j) * s < 0):
            return True
    return False


@wp.func
def separated_2d(p: wp.mat33d, q: wp.mat33d, i: int, j: int) -> bool:
    """The closed triangles p, q (rows) are certified disjoint in the projection on
    coordinates (i, j), hence in space: an edge line of one has the other strictly
    outside, by a margin (two convex polygons are disjoint iff such an edge exists)."""
    return _outside_edge_2d(p, q, i, j) or _outside_edge_2d(q, p, i, j)


#: a gap (absolute, points scaled into [-1, 1]^3) along the planes' common line that certifies
#: two touching-within-rounding triangles apart (:func:`apart_on_line`)
LINE_GAP = wp.constant(wp.float64(2.0**-30))
#: below this sine of the angle between the planes their common line is not trusted
LINE_SIN = wp.constant(wp.float64(2.0**-10))


@wp.func
def _line_interval(t: wp.mat33d, s: wp.vec3i, a: wp.vec3d, n: wp.vec3d, u: wp.vec3d) -> wp.vec2d:
    """[lo, hi] along u of the part of triangle t on the plane (a, n): its vertices of
    side 0 and the crossings of its edges whose ends have strict opposite sides s."""
    lo = wp.float64(1.0e300)
    hi = wp.float64(-1.0e300)
    for k in range(3):
        if s[k] == 0:
            x = wp.dot(t[k], u)
            lo = wp.min(lo, x)
            hi = wp.max(hi, x)
        k2 = (k + 1) % 3
        if s[k] * s[k2] < 0:
            da = wp.dot(n, t[k] - a)
            db = wp.dot(n, t[k2] - a)
            x = wp.dot(t[k] + (t[k2] - t[k]) * (da / (da - db)), u)
            lo = wp.min(lo, x)
            hi = wp.max(hi, x)
    return wp.vec2d(lo, hi)


@wp.func
def apart_on_line(p: wp.mat33d, ds: wp.vec3i, n1: wp.vec3d, q: wp.mat33d, es: wp.vec3i, n2: wp.vec3d) -> bool:
    """Two triangles in planes that cross at a fair angle (ds: p's sides wrt q's plane, es:
    q's wrt p's) meet only on the planes' common line, where each covers one interval: they
    are certified apart when the intervals are ``LINE_GAP`` apart, far more than the
    rounding of the sides that were ties (a vertex within rounding of the other plane
    lies within rounding / sine of the line)."""
    u = wp.cross(n1, n2)
    lu = wp.length(u)
    if not lu > LINE_SIN * wp.length(n1) * wp.length(n2):
        return False
    u = u / lu
    ip = _line_interval(p, ds, q[0], n2, u)
    iq = _line_interval(q, es, p[0], n1, u)
    if ip[0] > ip[1] or iq[0] > iq[1]:
        return False  # no point found on the line (cannot happen past the early exits)
    return ip[0] > iq[1] + LINE_GAP or iq[0] > ip[1] + LINE_GAP


@wp.func
def drop_axis(n: wp.vec3d) -> int:
    """The axis along which the plane with normal n projects without degenerating."""
    ax = wp.abs(n[0])
    ay = wp.abs(n[1])
    az = wp.abs(n[2])
    if ax >= ay and ax >= az:
        return 0
    if ay >= az:
        return 1
    return 2


@wp.func
def canonical_order(s0: int, s1: int, s2: int):
    """For plane-side signs of a triangle's vertices, not all zero and not all of one
    strict sign: the vertex k alone on its side and the flip f = +-1 of the other plane
    such that f*s_k >= 0 >= f*s_(k+1), f*s_(k+2), with f*s_k > 0 unless both others
    are < 0 (Guigue–Devillers' canonical form)."""
    npos = int(0)
    nneg = int(0)
    kpos = int(0)
    kneg = int(0)
    kzero = int(0)
    if s0 > 0:
        npos += 1
        kpos = 0
    elif s0 < 0:
        nneg += 1
        kneg = 0
    else:
        kzero = 0
    if s1 > 0:
        npos += 1
        kpos = 1
    elif s1 < 0:
        nneg += 1
        kneg = 1
    else:
        kzero = 1
    if s2 > 0:
        npos += 1
        kpos = 2
    elif s2 < 0:
        nneg += 1
        kneg = 2
    else:
        kzero = 2
    if npos == 1:
        return kpos, 1
    if nneg == 1:
        return kneg, -1
    if npos == 2:  # (+, +, 0): the zero vertex, plane flipped
        return kzero, -1
    return kzero, 1  # (-, -, 0)


@wp.func
def pair_intersects(p: wp.mat33d, ip: wp.vec3i, n1: wp.vec3d, m1: wp.vec3d,
                    q: wp.mat33d, iq: wp.vec3i) -> bool:
    """Whether triangles p and q (rows: vertices; ip, iq: their vertex indices; n1, m1:
    p's normal and permanent companion) intersect other than through shared vertices:

    - no shared index: any common point (touching, coplanar overlap);
    - one shared vertex v: a common point other than v;
    - a shared edge: coplanar and folded onto each other (opposite vertices on the same
      side of the edge);
    - three shared indices (a duplicate face): always.

    Neither triangle may be degenerate. d and e are the sides of p's vertices wrt q's
    plane and of q's wrt p's; a *tie* is a side within rounding of 0 at a free vertex
    (not a shared one). When all of one triangle's free vertices tie, the pair is
    coplanar and decided in 2D (the projection along the dominant axis of that normal;
    one shared vertex: the wedges at it meet unless :func:`wedges_apart_2d`).
    Otherwise the 3D tests below take a tie as exactly 0: exact for exact inputs,
    conservative for touching ones. But a tie can also be rounding noise where the
    geometry is ill-conditioned (nearly coplanar neighbours: a fan of coplanar triangles
    around a vertex, flat parts of a refined surface; an edge lying in the other's plane)
    and then the other signs are noise too; so a "meet" that rests on a tie is confirmed
    in the projection along p's dominant normal axis: it is dropped when the projections
    are certified apart by more than rounding and ``INPUT_TOL`` (:func:`separated_2d`,
    :func:`wedges_apart_2d`). Projections of triangles that meet meet, so this never
    drops an exact intersection, and it keeps pairs that touch within rounding.

    No shared index, not coplanar: Guigue & Devillers (2003). In canonical order
    p = (a, b, c), q = (x, y, z) (:func:`canonical_order`: a alone on the positive side of
    q's plane, or on it with b, c strictly below; x likewise for p's plane; rotations
    keep a triangle's orientation, a swap of its last two vertices flips the other's
    plane), p and q cut the planes' common line L in [j, i] and [k, l] along n1 x n2
    (i on ab, j on ac, k on xy, l on xz), and k <= i iff O(a, b, x, y) <= 0, j <= l iff
    O(a, c, x, z) >= 0: O(a, b, x, y) is the signed distance i -> k times
    (d(b) - d(a)) (e(y) - e(x)) > 0.

    One shared vertex v, not coplanar: with p = (v, a, b) and q = (v, f, g) (rotated,
    orientation kept), the triangles meet beyond v iff their wedges at v share a ray; it
    lies on L, direction +-u with u = n1 x n2. u is in p's wedge iff d(a) >= 0 >= d(b)
    ((a x u) . n1 = |n1|^2 d(a) for a in p's plane), in q's iff e(f) <= 0 <= e(g); -u
    with the inequalities reversed. A tie meets both inequalities (it only adds "meet").
    """
    shared = int(0)
    pv = int(-1)
    qv = int(-1)
    for a in range(3):
        for b in range(3):
            if ip[a] == iq[b]:
                shared += 1
                pv = a
                qv = b
    if shared == 3:
        return True
    if shared == 2:
        # the vertices off the shared edge (u, w)
        px = int(0)
        for a in range(3):
            if ip[a] != iq[0] and ip[a] != iq[1] and ip[a] != iq[2]:
                px = a
        qy = int(0)
        for b in range(3):
            if iq[b] != ip[0] and iq[b] != ip[1] and iq[b] != ip[2]:
                qy = b
        if plane_side(q[qy], p[0], n1, m1) != 0:
            return False
        # coplanar: folded iff both apexes are strictly on the same side of the edge, in the
        # projection along p's dominant normal axis (which keeps sides); a tie is no fold:
        # coplanar triangles on opposite sides of the edge touch only along it
        k = drop_axis(n1)
        i = (k + 1) % 3
        j = (k + 2) % 3
        u = p[(px + 1) % 3]
        w = p[(px + 2) % 3]
        return orient2d(u, w, p[px], i, j) * orient2d(u, w, q[qy], i, j) > 0

    # e: sides of q's vertices wrt p's plane (the shared vertex: exactly 0)
    e0 = _side_unless(q[0], 0, qv, p[0], n1, m1)
    e1 = _side_unless(q[1], 1, qv, p[0], n1, m1)
    e2 = _side_unless(q[2], 2, qv, p[0], n1, m1)
    free = 3 - shared  # vertices that may leave the other plane
    epos = int(e0 > 0) + int(e1 > 0) + int(e2 > 0)
    eneg = int(e0 < 0) + int(e1 < 0) + int(e2 < 0)
    if epos == free or eneg == free:
        return False
    u2 = q[1] - q[0]
    v2 = q[2] - q[0]
    n2 = wp.cross(u2, v2)
    m2 = _abs_cross(u2, v2)
    d0 = _side_unless(p[0], 0, pv, q[0], n2, m2)
    d1 = _side_unless(p[1], 1, pv, q[0], n2, m2)
    d2 = _side_unless(p[2], 2, pv, q[0], n2, m2)
    dpos = int(d0 > 0) + int(d1 > 0) + int(d2 > 0)
    dneg = int(d0 < 0) + int(d1 < 0) + int(d2 < 0)
    if dpos == free or dneg == free:
        return False

    k = drop_axis(n1)
    if dpos + dneg == 0:
        k = drop_axis(n2)
    i = (k + 1) % 3
    j = (k + 2) % 3
    coplanar = dpos + dneg == 0 or epos + eneg == 0
    ties = dpos + dneg + epos + eneg < 2 * free

    if shared == 1:
        v = p[pv]
        pa = p[(pv + 1) % 3]
        pb = p[(pv + 2) % 3]
        qa = q[(qv + 1) % 3]
        qb = q[(qv + 2) % 3]
        if coplanar:
            return not wedges_apart_2d(v, pa, pb, qa, qb, i, j)
        ds = wp.vec3i(d0, d1, d2)
        es = wp.vec3i(e0, e1, e2)
        da = ds[(pv + 1) % 3]
        db = ds[(pv + 2) % 3]
        ef = es[(qv + 1) % 3]
        eg = es[(qv + 2) % 3]
        hit = ((da >= 0 and db <= 0 and ef <= 0 and eg >= 0)
               or (da <= 0 and db >= 0 and ef >= 0 and eg <= 0))
        if hit and ties:
            hit = not wedges_apart_2d(v, pa, pb, qa, qb, i, j)
        return hit

    if coplanar:  # 2D tests in the plane
        return coplanar_overlap(p, q, i, j)

    # canonical order: p rotated by k1 (q's plane flipped if f1 < 0: q's rows 1, 2 swap),
    # then q rotated by k2 (p's plane flipped if f2 < 0: p's rows b, c swap);
    # p = (ia, ib, ic), q = (jp, jq, jr) = (x, y, z) of the docstring
    k1, f1 = canonical_order(d0, d1, d2)
    qb0 = int(0)
    qb1 = int(1)
    qb2 = int(2)
    if f1 < 0:
        qb1 = 2
        qb2 = 1
    es = wp.vec3i(e0, e1, e2)
    k2, f2 = canonical_order(es[qb0], es[qb1], es[qb2])
    qbase = wp.vec3i(qb0, qb1, qb2)
    ia = k1
    ib = (k1 + 1) % 3
    ic = (k1 + 2) % 3
    if f2 < 0:
        ib = (k1 + 2) % 3
        ic = (k1 + 1) % 3
    jp = qbase[k2]
    jq = qbase[(k2 + 1) % 3]
    jr = qbase[(k2 + 2) % 3]
    o1 = orient3d(p[ia], p[ib], q[jp], q[jq])
    o2 = orient3d(p[ia], p[ic], q[jp], q[jr])
    hit = o1 <= 0 and o2 >= 0
    if hit and (ties or o1 == 0 or o2 == 0):
        # a meet resting on ties: dropped if certified apart in the projection, or along the
        # planes' common line (the projection cannot tell a steep triangle's edge from a
        # point of the other triangle straight above it)
        hit = not (separated_2d(p, q, i, j) or apart_on_line(p, wp.vec3i(d0, d1, d2), n1, q, es, n2))
    return hit


@wp.func
def load_triangle(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), f: int):
    i0 = tris[3 * f]
    i1 = tris[3 * f + 1]
    i2 = tris[3 * f + 2]
    return wp.matrix_from_rows(points[i0], points[i1], points[i2]), wp.vec3i(i0, i1, i2)


@wp.func
def _crossing_bits(t: wp.mat33d) -> int:
    """For each rotation r of the face (v, a, b) = (t[r], t[r + 1], t[r + 2]), bits 6 r + 2y
    and 6 r + 2y + 1 for each coordinate y: a[y] < v[y] <= b[y], and b[y] < v[y] <= a[y]
    (condition 4 of :func:`umbrella_certified`). All from the six strict comparisons of
    the three corners on each coordinate (x <= y is not y < x), branch-free: the
    comparisons are data-dependent (a third of the faces pass's time when made twelve a
    coordinate, once for each rotation)."""
    bits = int(0)
    for y in range(3):
        x0 = t[0][y]
        x1 = t[1][y]
        x2 = t[2][y]
        lt01 = int(x0 < x1)
        lt10 = int(x1 < x0)
        lt02 = int(x0 < x2)
        lt20 = int(x2 < x0)
        lt12 = int(x1 < x2)
        lt21 = int(x2 < x1)
        r0 = (lt10 & (1 - lt20)) | ((lt20 & (1 - lt10)) << 1)  # (v, a, b) = (t0, t1, t2)
        r1 = (lt21 & (1 - lt01)) | ((lt01 & (1 - lt21)) << 1)  # (t1, t2, t0)
        r2 = (lt02 & (1 - lt12)) | ((lt12 & (1 - lt02)) << 1)  # (t2, t0, t1)
        bits = bits | (r0 << (2 * y)) | (r1 << (6 + 2 * y)) | (r2 << (12 + 2 * y))
    return bits


@wp.kernel
def classify_faces_kernel(first: int, points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                          degenerate: wp.array(dtype=wp.int32), codes: wp.array(dtype=wp.int32)):
    """One thread per face f = first + tid: 1 in ``degenerate`` when its area is zero to within float64
    rounding (every 2D projection's orientation is filtered to 0; repeated indices
    included), else 0; and its code for :func:`umbrella_certified`: bit 2k (2k + 1) when
    its projection dropping coordinate k is certified counter-clockwise (clockwise) on the
    coordinates (k + 1, k + 2) (none for repeated indices), and in bits 6 to 23 the
    comparisons of its rotations (:func:`_crossing_bits`)."""
    f = first + wp.tid()
    flag, code = classify_face(points, tris, f)
    degenerate[f] = flag
    codes[f] = code


#: a bound on :func:`orient2d_margin`'s allowance for moves of the points for coordinates
#: in [-1, 1] (the scaled points): 2 ``INPUT_TOL`` lin (1 + ``O2_BOUND``) + 8
#: ``INPUT_TOL``^2 with lin, a sum of four differences, below 8: under 17 ``INPUT_TOL``
FACE_MOVED = wp.constant(wp.float64(32.0 * 2.0**-48))


@wp.func
def _orient2d_and_margin(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, i: int, j: int) -> wp.vec2i:
    """(:func:`orient2d`, a sign by a margin) of (a, b, c) on coordinates (i, j), from one
    evaluation of the determinant; the second is :func:`orient2d_margin`'s with its
    allowance for moves bounded by ``FACE_MOVED`` (points in [-1, 1]: never less
    conservative)."""
    d = _det2d(a, b, c, i, j)
    bound = O2_BOUND * d[1] + FACE_MOVED + TINY  # the exact sign's bound, and the moves'
    return wp.vec2i(_filtered_sign(d[0], d[1], O2_BOUND), int(d[0] > bound) - int(d[0] < -bound))


#: the bit where a face code's signs by a margin (:func:`orient2d_margin`) begin, laid out
#: as its exact ones (bits 0-5)
MARGIN_SIGNS = wp.constant(24)


@wp.func
def classify_face(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), f: int):
    """Face f's degenerate flag and umbrella code (:func:`classify_faces_kernel`)."""
    t, it = load_triangle(points, tris, f)
    flag = int(1)
    code = int(0)
    if it[0] != it[1] and it[1] != it[2] and it[0] != it[2]:
        for k in range(3):
            signs = _orient2d_and_margin(t[0], t[1], t[2], (k + 1) % 3, (k + 2) % 3)
            o = signs[0]
            if o != 0:
                flag = 0
            if o > 0:
                code = code | (1 << (2 * k))
            if o < 0:
                code = code | (2 << (2 * k))
            om = signs[1]
            if om > 0:
                code = code | (1 << (MARGIN_SIGNS + 2 * k))
            if om < 0:
                code = code | (2 << (MARGIN_SIGNS + 2 * k))
    return flag, code | (_crossing_bits(t) << 6)


@wp.kernel
def tet_signs_kernel(points: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.int32),
                     signs: wp.array(dtype=wp.int32)):
    """One thread per tetrahedron (a, b, c, d): the filtered sign of O(a, b, c, d), positive
    when d is on the side of (a, b, c) its right-hand normal points to (the house's
    positive orientation); 0 when flat to within rounding or a vertex repeats."""
    t = wp.tid()
    a = tets[4 * t]
    b = tets[4 * t + 1]
    c = tets[4 * t + 2]
    d = tets[4 * t + 3]
    sign = int(0)
    if a != b and a != c and a != d and b != c and b != d and c != d:
        sign = orient3d(points[a], points[b], points[c], points[d])
    signs[t] = sign


@wp.func
def tet_face(tets: wp.array(dtype=wp.int32), f: int) -> wp.vec3i:
    """Face f = 4 t + k of tetrahedron t (a, b, c, d): the corners other than corner k, in
    the order that makes its right-hand normal point away from corner k when O(a, b, c, d)
    > 0 (warpmesh.cells.intersections._TET_FACES: (b, c, d), (a, d, c), (a, b, d), (a, c, b))."""
    t = f // 4
    k = f - 4 * t
    a = tets[4 * t]
    b = tets[4 * t + 1]
    c = tets[4 * t + 2]
    d = tets[4 * t + 3]
    if k == 0:
        return wp.vec3i(b, c, d)
    if k == 1:
        return wp.vec3i(a, d, c)
    if k == 2:
        return wp.vec3i(a, b, d)
    return wp.vec3i(a, c, b)


@wp.func
def sorted3(v: wp.vec3i) -> wp.vec3i:
    """The three entries in ascending order."""
    a = wp.min(v[0], wp.min(v[1], v[2]))
    c = wp.max(v[0], wp.max(v[1], v[2]))
    return wp.vec3i(a, v[0] + v[1] + v[2] - a - c, c)


@wp.func
def odd3(v: wp.vec3i) -> int:
    """1 when sorting the entries takes an odd permutation (the face's cyclic order is the
    reverse of the ascending one), else 0; entries distinct."""
    n = int(0)
    if v[0] > v[1]:
        n += 1
    if v[0] > v[2]:
        n += 1
    if v[1] > v[2]:
        n += 1
    return n % 2


@wp.kernel
def tet_face_leads_kernel(first: int, tets: wp.array(dtype=wp.int32), lead: wp.array(dtype=wp.int32)):
    """One thread per face f = first + tid (face k of tetrahedron t is f = 4 t + k):
    ``lead[f]``, its largest corner, the key the faces are sorted by."""
    f = first + wp.tid()
    v = tet_face(tets, f)
    lead[f] = wp.max(v[0], wp.max(v[1], v[2]))


@wp.func
def face_key(s: wp.vec3i) -> wp.int64:
    """The two smaller sorted corners of a face (those it is not sorted by), packed:
    s[0] * 2^32 + s[1]."""
    return (wp.int64(s[0]) << wp.int64(32)) | wp.int64(s[1])


@wp.kernel
def gather_face_keys_kernel(first: int, tets: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                            keys: wp.array(dtype=wp.int64), odd: wp.array(dtype=wp.int8)):
    """One thread per slot k = first + tid of the faces sorted by lead corner: the
    :func:`face_key` of face ``order[k]`` and whether its corners are an odd permutation of
    their sorted order (:func:`odd3`), stored by slot, so that each lead corner's scan
    reads one contiguous run."""
    k = first + wp.tid()
    v = tet_face(tets, order[k])
    keys[k] = face_key(sorted3(v))
    odd[k] = wp.int8(odd3(v))


@wp.kernel
def match_faces_by_lead_kernel(first: int, offsets: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                               keys: wp.array(dtype=wp.int64), odd: wp.array(dtype=wp.int8),
                               mate: wp.array(dtype=wp.int32), same: wp.array(dtype=wp.int8)):
    """One thread per lead corner u = first + tid matches the faces whose largest corner is
    u among themselves (one contiguous run of the sorted faces; every face is in the run
    of exactly one corner, so each face is written once): for face f, ``mate[f]`` the one
    other face with its corners, -1 for none (a boundary face), -2 for two or more;
    ``same[f]`` 1 when that one other face has the same orientation (both tetrahedra on
    one side of it), else 0."""
    u = first + wp.tid()
    lo = offsets[u]
    hi = offsets[u + 1]
    for i in range(lo, hi):
        key = keys[i]
        found = int(-1)
        count = int(0)
        for j in range(lo, hi):
            if j != i and keys[j] == key:
                count += 1
                found = j
        f = order[i]
        flag = wp.int8(0)
        if count == 1:
            if odd[i] == odd[found]:
                flag = wp.int8(1)
            mate[f] = order[found]
        elif count == 0:
            mate[f] = -1
        else:
            mate[f] = -2
        same[f] = flag


@wp.kernel
def gather_tet_faces_kernel(first: int, tets: wp.array(dtype=wp.int32), ids: wp.array(dtype=wp.int32),
                            out: wp.array(dtype=wp.int32)):
    """One thread per row i = first + tid: the corners of face ``ids[i]``, outward, at
    ``out[3 i : 3 i + 3]``."""
    i = first + wp.tid()
    v = tet_face(tets, ids[i])
    out[3 * i] = v[0]
    out[3 * i + 1] = v[1]
    out[3 * i + 2] = v[2]


@wp.func
def bvh_coordinates(x: wp.vec3d, centre: wp.vec3d, half: wp.float64) -> wp.vec3:
    """((x - centre) / half) rounded to float32, coordinate by coordinate (each step rounded
    to nearest, as numpy's float64 arithmetic then ``astype(float32)``): a map monotone in
    each coordinate."""
    return wp.vec3(wp.float32((x[0] - centre[0]) / half), wp.float32((x[1] - centre[1]) / half),
                   wp.float32((x[2] - centre[2]) / half))


@wp.func
def largest_side(lo: wp.vec3, hi: wp.vec3) -> wp.float32:
    """The largest side of the float32 box [lo, hi] (what sizes the grid's cell:
    :func:`face_extents_kernel`, :func:`flat_faces_kernel`)."""
    e = hi - lo
    return wp.max(wp.max(e[0], e[1]), e[2])


@wp.kernel
def bvh_coordinates_kernel(first: int, points: wp.array(dtype=wp.vec3d), centre: wp.vec3d, half: wp.float64,
                           points32: wp.array(dtype=wp.vec3)):
    """One thread per point v = first + tid (the host splits a launch across the CPU cores,
    as for the kernels below that take ``first``): its :func:`bvh_coordinates`."""
    v = first + wp.tid()
    points32[v] = bvh_coordinates(points[v], centre, half)


@wp.kernel
def point_bounds_kernel(first: int, points: wp.array(dtype=wp.vec3d), per: int, lows: wp.array(dtype=wp.vec3d),
                        highs: wp.array(dtype=wp.vec3d), bad: wp.array(dtype=wp.int32)):
    """One thread per run t = first + tid of ``per`` points (the last one shorter): their
    smallest and largest coordinates, and 1 in ``bad[t]`` when one is NaN or infinite
    (else 0). A run past the end (fewer points than runs) gives the last point's bounds
    (the caller has at least one point)."""
    t = first + wp.tid()
    a = t * per
    b = wp.min(a + per, points.shape[0])
    lo = points[wp.min(a, points.shape[0] - 1)]
    hi = lo
    zero = wp.vec3d()  # x * 0 is 0, or NaN for a NaN or infinite x: the sum of them is NaN if any is
    for v in range(a, b):
        x = points[v]
        zero = zero + x * wp.float64(0.0)
        lo = wp.min(lo, x)
        hi = wp.max(hi, x)
    lows[t] = lo
    highs[t] = hi
    bad[t] = 1 - int(wp.isfinite(zero[0] + zero[1] + zero[2]))


@wp.kernel
def scaled_points_kernel(first: int, points: wp.array(dtype=wp.vec3d), scale: wp.float64, centre: wp.vec3d,
                         half: wp.float64, scaled: wp.array(dtype=wp.vec3d), points32: wp.array(dtype=wp.vec3)):
    """One thread per point v = first + tid: the point times ``scale`` (a power of two: as
    exact as ``np.ldexp``, the one rounding of the exact product) and the
    :func:`bvh_coordinates` of that."""
    v = first + wp.tid()
    x = points[v] * scale
    scaled[v] = x
    points32[v] = bvh_coordinates(x, centre, half)


@wp.kernel
def flat_faces_kernel(first: int, tris: wp.array(dtype=wp.int64), per: int, points32: wp.array(dtype=wp.vec3),
                      flat: wp.array(dtype=wp.int32), lows: wp.array(dtype=wp.int64),
                      highs: wp.array(dtype=wp.int64), largest: wp.array(dtype=wp.float32),
                      sums: wp.array(dtype=wp.float64)):
    """One thread per run t = first + tid of ``per`` faces (the last one shorter; a run past
    the end has no faces, its bounds the last face's first index, its sides 0): each face's indices (``tris``: the flat (m, 3) array) as
    int32 in ``flat``, the run's smallest and largest index in ``lows[t]`` and ``highs[t]``
    (the caller checks them before any kernel reads ``flat``), and the largest side of
    the faces' float32 boxes (:func:`face_extents_kernel`'s) in ``largest[t]``, their sum
    in ``sums[t]`` (the points read at indices clamped to the points, of which there is at
    least one: an index out of range reads some point, and is refused afterwards)."""
    t = first + wp.tid()
    m = tris.shape[0] / 3
    a = t * per
    b = wp.min(a + per, m)
    n = points32.shape[0]
    lo = tris[3 * wp.min(a, m - 1)]
    hi = lo
    big = wp.float32(0.0)
    total = wp.float64(0.0)
    for f in range(a, b):
        i0 = tris[3 * f]
        i1 = tris[3 * f + 1]
        i2 = tris[3 * f + 2]
        lo = wp.min(lo, wp.min(i0, wp.min(i1, i2)))
        hi = wp.max(hi, wp.max(i0, wp.max(i1, i2)))
        j0 = wp.int32(wp.clamp(i0, wp.int64(0), wp.int64(n - 1)))
        j1 = wp.int32(wp.clamp(i1, wp.int64(0), wp.int64(n - 1)))
        j2 = wp.int32(wp.clamp(i2, wp.int64(0), wp.int64(n - 1)))
        flat[3 * f] = wp.int32(i0)
        flat[3 * f + 1] = wp.int32(i1)
        flat[3 * f + 2] = wp.int32(i2)
        c0 = points32[j0]
        c1 = points32[j1]
        c2 = points32[j2]
        side = largest_side(wp.min(wp.min(c0, c1), c2), wp.max(wp.max(c0, c1), c2))
        big = wp.max(big, side)
        total = total + wp.float64(side)
    lows[t] = lo
    highs[t] = hi
    largest[t] = big
    sums[t] = total


@wp.func
def spread_bits(x: int) -> int:
    """The 10 low bits of x moved to every third bit (Morton interleave)."""
    x = (x | (x << 16)) & 0x030000FF
    x = (x | (x << 8)) & 0x0300F00F
    x = (x | (x << 4)) & 0x030C30C3
    return (x | (x << 2)) & 0x09249249


@wp.kernel
def morton_codes_kernel(first: int, points32: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.int32),
                        keys: wp.array(dtype=wp.int32), ids: wp.array(dtype=wp.int32)):
    """One thread per face f = first + tid: the 30-bit Morton code of its centroid (points in
    [-1, 1]^3) as the sort key, its index as the value."""
    f = first + wp.tid()
    c = (points32[tris[3 * f]] + points32[tris[3 * f + 1]] + points32[tris[3 * f + 2]]) / 3.0
    u = (c + wp.vec3(1.0, 1.0, 1.0)) * 511.5
    x = wp.clamp(int(u[0]), 0, 1023)
    y = wp.clamp(int(u[1]), 0, 1023)
    z = wp.clamp(int(u[2]), 0, 1023)
    keys[f] = (spread_bits(x) << 2) | (spread_bits(y) << 1) | spread_bits(z)
    ids[f] = f


@wp.kernel
def gather_faces_kernel(first: int, tris: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                        sorted_tris: wp.array(dtype=wp.int32)):
    """One thread per position s = first + tid of the face order: the vertex indices of face
    order[s]."""
    s = first + wp.tid()
    f = order[s]
    sorted_tris[3 * s] = tris[3 * f]
    sorted_tris[3 * s + 1] = tris[3 * f + 1]
    sorted_tris[3 * s + 2] = tris[3 * f + 2]


#: faces per leaf of the group tree: consecutive faces of the Morton order (a compact
#: patch), so the tree has m / GROUP leaves and one walk per group, not per face, finds the
#: groups near it; faces are then screened by their own float32 boxes (:func:`walk_group`).
#: 8 and 32 measured no faster on the part and the ball at 512 (with bit masks, and again
#: with slot lists).
GROUP = 16
#: the lower corner of an empty box (its upper corner is -EMPTY): far outside the BVH's
#: coordinates [-1, 1]^3, so it meets no box
EMPTY = wp.constant(8.0)


@wp.func
def face_box(points32: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.int32), s: int):
    """The float32 box of face position s (the BVH's coordinates)."""
    c0 = points32[tris[3 * s]]
    c1 = points32[tris[3 * s + 1]]
    c2 = points32[tris[3 * s + 2]]
    return wp.min(wp.min(c0, c1), c2), wp.max(wp.max(c0, c1), c2)


@wp.func
def padded_face_box(points32: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.int32), s: int, degenerate: int,
                    grow: float):
    """Face s's float32 box, its upper corner grown by ``grow`` (0 for the tree walk, which
    grows its query boxes; the grid walk compares lower corners with grown upper ones,
    :func:`grid_walk_cell`); an empty box (lower corner ``EMPTY`` above the upper one) for
    a degenerate face, so that it meets nothing."""
    lo, hi = face_box(points32, tris, s)
    hi = hi + wp.vec3(grow, grow, grow)
    if degenerate != 0:
        lo = wp.vec3(EMPTY, EMPTY, EMPTY)
        hi = -lo
    return lo, hi


@wp.kernel
def classify_and_box_kernel(first: int, points: wp.array(dtype=wp.vec3d), points32: wp.array(dtype=wp.vec3),
                            tris: wp.array(dtype=wp.int32), grow: float, degenerate: wp.array(dtype=wp.int32),
                            codes: wp.array(dtype=wp.int32), lowers: wp.array(dtype=wp.vec3),
                            uppers: wp.array(dtype=wp.vec3)):
    """One thread per face position s = first + tid: its degenerate flag and umbrella code
    (:func:`classify_face`) and its box (:func:`padded_face_box`), in one pass over the
    faces."""
    s = first + wp.tid()
    flag, code = classify_face(points, tris, s)
    degenerate[s] = flag
    codes[s] = code
    lo, hi = padded_face_box(points32, tris, s, flag, grow)
    lowers[s] = lo
    uppers[s] = hi


@wp.kernel
def group_boxes_kernel(face_lowers: wp.array(dtype=wp.vec3), face_uppers: wp.array(dtype=wp.vec3), m: int,
                       lowers: wp.array(dtype=wp.vec3), uppers: wp.array(dtype=wp.vec3)):
    """One thread per group g: the box of the faces at positions [GROUP g, GROUP g + GROUP);
    a group of degenerate faces only gets the point box at ``EMPTY``, which no face's box meets."""
    g = wp.tid()
    lo = face_lowers[GROUP * g]
    hi = face_uppers[GROUP * g]
    for s in range(GROUP * g + 1, wp.min(GROUP * g + GROUP, m)):
        lo = wp.min(lo, face_lowers[s])
        hi = wp.max(hi, face_uppers[s])
    if lo[0] > hi[0]:
        lo = wp.vec3(EMPTY, EMPTY, EMPTY)
        hi = lo
    lowers[g] = lo
    uppers[g] = hi


@wp.func
def boxes_meet(lo: wp.vec3, hi: wp.vec3, a: wp.vec3, b: wp.vec3) -> bool:
    return a[0] <= hi[0] and a[1] <= hi[1] and a[2] <= hi[2] and lo[0] <= b[0] and lo[1] <= b[1] and lo[2] <= b[2]


@wp.func
def _apart_on_touching_boxes(p: wp.mat33d, q: wp.mat33d) -> bool:
    """Whether triangles p and q are proved disjoint by coordinate comparisons alone (exact
    in float64, no rounding): their boxes are apart along an axis k, or they touch along it
    (max of p's coordinate k equal to min of q's, or the other way round: the plane
    x_k = c) and the parts of the two triangles in that plane are apart. A triangle on one
    side of the plane meets it in the hull of its vertices with x_k == c (a linear function
    on a triangle is largest on the face spanned by the vertices where it is largest), so
    the two parts are apart when the boxes of those vertices over the other two
    coordinates are, and every common point of p and q would lie in both parts.

    This decides, before any predicate, the pairs a grid mesher makes in neighbouring
    cells (each triangle inside its closed cell: boxes meet at most in the cells' common
    face), e.g. coplanar triangles of a flat, grid-aligned region touching only at a cell
    side with no vertex in common. Only a "disjoint" it proves is used; anything else goes
    to :func:`pair_intersects`."""
    for k in range(3):
        pmin = wp.min(wp.min(p[0, k], p[1, k]), p[2, k])
        pmax = wp.max(wp.max(p[0, k], p[1, k]), p[2, k])
        qmin = wp.min(wp.min(q[0, k], q[1, k]), q[2, k])
        qmax = wp.max(wp.max(q[0, k], q[1, k]), q[2, k])
        if pmax < qmin or qmax < pmin:
            return True
        touch = False
        c = pmax
        if pmax == qmin:
            touch = True
        elif qmax == pmin:
            touch = True
            c = qmax
        if touch:
            i = (k + 1) % 3
            j = (k + 2) % 3
            big = wp.float64(1.0e300)
            plo = wp.vec2d(big, big)
            phi = wp.vec2d(-big, -big)
            qlo = wp.vec2d(big, big)
            qhi = wp.vec2d(-big, -big)
            for a in range(3):
                if p[a, k] == c:
                    plo = wp.min(plo, wp.vec2d(p[a, i], p[a, j]))
                    phi = wp.max(phi, wp.vec2d(p[a, i], p[a, j]))
                if q[a, k] == c:
                    qlo = wp.min(qlo, wp.vec2d(q[a, i], q[a, j]))
                    qhi = wp.max(qhi, wp.vec2d(q[a, i], q[a, j]))
            if phi[0] < qlo[0] or qhi[0] < plo[0] or phi[1] < qlo[1] or qhi[1] < plo[1]:
                return True
    return False


@wp.func
def confirmed_pair_intersects(p: wp.mat33d, ip: wp.vec3i, n1: wp.vec3d, m1: wp.vec3d,
                              q: wp.mat33d, iq: wp.vec3i) -> bool:
    """:func:`pair_intersects`, unless the two faces are proved apart by coordinate
    comparisons first (:func:`_apart_on_touching_boxes`: float64 boxes disjoint, or
    touching along an axis with the faces' parts in that plane apart). The comparisons are
    exact, so this drops no intersection; it removes the predicate's false meets on a face
    that is collinear to within rounding but not flagged degenerate (its normal ~1e-16 of
    its edges after a rotation: every side is a tie, so it "touches" faces far from it),
    so the answer does not depend on which pairs a candidate search offers (the walks and
    :func:`all_pairs_kernel` agree), and it spares the predicate the pairs of neighbouring
    grid cells."""
    if _apart_on_touching_boxes(p, q):
        return False
    return pair_intersects(p, ip, n1, m1, q, iq)


@wp.func
def ordered_pair_intersects(t: wp.mat33d, it: wp.vec3i, n: wp.vec3d, na: wp.vec3d, f: int,
                            t2: wp.mat33d, it2: wp.vec3i, f2: int) -> bool:
    """:func:`pair_intersects` of faces f (vertices t, indices it, normal n and its permanent
    companion na) and f2, the one of the lower input index as p (the predicate's rounding
    is not symmetric: always the same order)."""
    if f < f2:
        return confirmed_pair_intersects(t, it, n, na, t2, it2)
    u = t2[1] - t2[0]
    v = t2[2] - t2[0]
    return confirmed_pair_intersects(t2, it2, wp.cross(u, v), _abs_cross(u, v), t, it)


@wp.kernel
def tree_leaves_kernel(group_lowers: wp.array(dtype=wp.vec3), group_uppers: wp.array(dtype=wp.vec3),
                       n_groups: int, leaves: int, lowers: wp.array(dtype=wp.vec3), uppers: wp.array(dtype=wp.vec3)):
    """One thread per leaf i of the group tree (node ``leaves + i``): group i's box; an
    inverted box (lower ``EMPTY``, upper -``EMPTY``), which meets nothing and leaves every
    union as it is, past the last group or for a group of degenerate faces only."""
    i = wp.tid()
    lo = wp.vec3(EMPTY, EMPTY, EMPTY)
    hi = -lo
    if i < n_groups:
        if group_lowers[i][0] < EMPTY:
            lo = group_lowers[i]
            hi = group_uppers[i]
    lowers[leaves + i] = lo
    uppers[leaves + i] = hi


@wp.kernel
def tree_level_kernel(first: int, lowers: wp.array(dtype=wp.vec3), uppers: wp.array(dtype=wp.vec3)):
    """One thread per node i = first + tid of one level: the union of its children's boxes
    (nodes 2i and 2i + 1, the level below, already done)."""
    i = wp.tid() + first
    lowers[i] = wp.min(lowers[2 * i], lowers[2 * i + 1])
    uppers[i] = wp.max(uppers[2 * i], uppers[2 * i + 1])


@wp.func
def tree_next(lowers: wp.array(dtype=wp.vec3), uppers: wp.array(dtype=wp.vec3), depth: int,
              qlo: wp.vec3, qhi: wp.vec3, g: int, node: int, shift: int):
    """The walk of the group tree (a complete binary tree in heap order: root 1, node i's
    children 2i and 2i + 1, leaves ``2**depth + h`` for the groups h in Morton order, each
    node's box the union of its leaves'), depth first from ``node`` (its leaves are
    ``shift`` levels down; node 0: the walk is over): the next group h >= g whose box meets
    the query box [qlo, qhi], and where to go on, (h, node, shift); h = -1 at the end.
    Subtrees of groups all below g are never entered: each pair of groups is met once."""
    leaves = 1 << depth
    while node != 0:
        enter = bool(False)
        if boxes_meet(qlo, qhi, lowers[node], uppers[node]):
            enter = ((node + 1) << shift) - 1 - leaves >= g  # its last leaf is not below g
        if enter and shift > 0:
            node = 2 * node
            shift -= 1
        else:
            found = int(-1)
            if enter:
                found = node - leaves
            while (node & 1) == 1:  # up while a right child; then to the right sibling
                node = node >> 1
                shift += 1
            if node != 0:
                node += 1
            if found >= 0:
                return found, node, shift
    return int(-1), int(0), int(0)


# -- the umbrella certificate: pairs around a vertex that need no exact test --------------------

#: faces around a vertex beyond which its umbrella is not certified (the part at 512 has at most 10)
UMBRELLA_CAP = 16
#: the link vertices a_i (or b_i) of the faces around one vertex (:func:`umbrella_certified`)
umbrella_ids = wp.types.vector(length=UMBRELLA_CAP, dtype=wp.int32)


@wp.kernel
def count_corners_kernel(first: int, tris: wp.array(dtype=wp.int32), counts: wp.array(dtype=wp.int32)):
    """One thread per corner c = first + tid (entry c of the flat face array): one more
    corner for its vertex (``counts`` zeroed beforehand; on the CPU each concurrent
    launch counts into its own array: an atomic is not atomic across them)."""
    c = first + wp.tid()
    wp.atomic_add(counts, tris[c], 1)


@wp.kernel
def fill_corners_kernel(first: int, tris: wp.array(dtype=wp.int32), ends: wp.array(dtype=wp.int32),
                        corners: wp.array(dtype=wp.int32)):
    """One thread per corner c = first + tid: c written into its vertex's range of
    ``corners``, from the end down (``ends``: the inclusive prefix sum of the counts, or
    for concurrent CPU launches each its own cursors, ending where the next launch's
    corners begin; afterwards each entry is where this launch's corners of the vertex
    start). The order within a range is whatever the atomics give:
    :func:`umbrella_certified` does not depend on it."""
    c = first + wp.tid()
    slot = wp.atomic_sub(ends, tris[c], 1) - 1
    corners[slot] = c


@wp.func
def _spread_bits6(x: int) -> int:
    """The 6 low bits of x moved to bits 0, 5, 10, ..., 25: six 5-bit counters to add to."""
    return ((x & 1) | ((x & 2) << 4) | ((x & 4) << 8) | ((x & 8) << 12) | ((x & 16) << 16)
            | ((x & 32) << 20))


@wp.func
def _winds_once(signs: int, counts: int, k: int) -> bool:
    """Conditions 3 and 4 of :func:`umbrella_certified` on axis k: every wedge certified
    counter-clockwise and one upward crossing on y = (k + 2) % 3, or every wedge clockwise
    and one crossing of the reversed wedges."""
    y = (k + 2) % 3
    up = (counts >> (10 * y)) & 31
    down = (counts >> (10 * y + 5)) & 31
    return ((signs >> (2 * k)) & 1 == 1 and up == 1) or ((signs >> (2 * k + 1)) & 1 == 1 and down == 1)


@wp.func
def umbrella_certified(codes: wp.array(dtype=wp.int32), tris: wp.array(dtype=wp.int32),
                       corners: wp.array(dtype=wp.int32), v: int, lo: int, d: int) -> bool:
    """Whether two faces around vertex v (its d corners at ``corners[lo:lo + d]``) can only
    meet in what they share, certified from F_v, the faces with index v, alone
    (``codes``: the faces' signs and crossings, :func:`classify_faces_kernel`).

    Each face of F_v is rotated to (v, a_i, b_i), orientation kept. Certified when:

    1. 3 <= d <= ``UMBRELLA_CAP`` and no a_i or b_i is v (a repeated index);
    2. a closed fan: a_i -> b_i is a permutation of the link (one or more cycles of
       wedges): each b_k equals exactly one a_l and each a_k exactly one b_l;
    3. for some coordinate axis k, in the projection dropping coordinate k (exact: it
       drops a coordinate), every wedge (v, a_i, b_i) has a certified strict
       :func:`orient2d` sign (the face's own, whichever vertex is first), all the same
       sign s;
    4. with the wedges made positive (for s < 0 each read as (v, b_i, a_i)), exactly one
       i has y(a_i) < y(v) <= y(b_i) (y the second kept coordinate, (k + 2) % 3; exact
       comparisons).

    Proof that then any two faces of F_v meet only in their shared vertex or edge (o, A,
    B: the projections of v, a, b; y measured from o). A positive wedge turns about o by
    an angle in (0, pi) from A_i to B_i = A_(sigma i), so each cycle of sigma is a closed
    polygon around o of winding number w >= 1 (a sum of turns in (0, pi), a multiple of 2
    pi). An edge from A (y < 0) to B (y >= 0) crosses y = 0 at x = (A_x B_y - A_y B_x) /
    (B_y - A_y) > 0 (its orientation is positive), an edge from y >= 0 to y < 0 at
    x < 0: so the upward crossings of condition 4 are exactly the crossings of the
    positive x-axis (points on it counted above), and their number is the total winding
    number about o (no vertex is o: the wedges are strict). Hence winding once: the
    wedges' angles follow each other round the circle and add up to 2 pi, and with each
    below pi (so d >= 3) two closed wedges share only o, or, when consecutive
    (b_i = a_j), the ray through B_i; a wedge holds its triangle's projection, which meets
    that ray in [o, B_i] only. A point x common to faces i and j projects into both
    projections: to o, or into [o, B_i]; each face projects one to one (its projection is
    a proper triangle), so x is v or on the edge [v, b_i], which both faces have. The
    faces of F_v are then non-degenerate, share exactly v or one edge (no two-cycle, no
    duplicate: the a_i are distinct), and a pair sharing only v has no other common
    point, a pair sharing an edge is not folded: neither intersects in the sense of
    :func:`pair_intersects`, in exact arithmetic. A duplicate face breaks the
    permutation; a fold inside F_v, a pinched vertex (two cones at v: two cycles) or a
    fan folded flat fails the signs or the winding; a boundary vertex fails condition 2.
    Nothing about other faces or their positions is assumed.
    """
    if d < 3 or d > UMBRELLA_CAP:
        return False
    a = umbrella_ids()
    b = umbrella_ids()
    signs = int(63)
    counts = int(0)
    for k in range(d):
        c = corners[lo + k]
        f = c // 3
        r = c - 3 * f
        ia = tris[3 * f + (r + 1) % 3]
        ib = tris[3 * f + (r + 2) % 3]
        if ia == v or ib == v:
            return False
        a[k] = ia
        b[k] = ib
        code = codes[f]
        signs = signs & code
        counts += _spread_bits6((code >> (6 + 6 * r)) & 63)
    if not (_winds_once(signs, counts, 0) or _winds_once(signs, counts, 1) or _winds_once(signs, counts, 2)):
        return False
    for k in range(d):
        row = int(0)
        col = int(0)
        for l in range(d):
            row += int(b[k] == a[l])
            col += int(a[k] == b[l])
        if row != 1 or col != 1:
            return False
    return True


@wp.func
def _pair_wide_umbrella(tris: wp.array(dtype=wp.int32), corners: wp.array(dtype=wp.int32), lo: int, hi: int,
                        partners: wp.array(dtype=wp.int32)):
    """The partners of :func:`certify_umbrellas_kernel` for a vertex of more than 8 faces:
    the same with loops over its faces, however many (past ``UMBRELLA_CAP`` too: the
    pairing is a property of the edge, which the other end's thread decides alike)."""
    for k in range(lo, hi):
        c = corners[k]
        f = c / 3
        ia = tris[3 * f + (c - 3 * f + 1) % 3]
        across = int(-1)
        back = int(0)
        same = int(0)
        for l in range(lo, hi):
            c2 = corners[l]
            g = c2 / 3
            if tris[3 * g + (c2 - 3 * g + 2) % 3] == ia:
                across = g
                back += 1
            if tris[3 * g + (c2 - 3 * g + 1) % 3] == ia:
                same += 1
        if back != 1 or same != 1:
            across = -1
        partners[c] = across


def _small_umbrella(size: int):
    """:func:`certify_umbrellas_kernel` for a vertex of at most ``size`` faces, a function
    of its own for each size (loops of a constant length, unrolled: a vertex of 6 faces
    costs 36 comparisons, not the 64 of the largest size; the sizes 5 to 8 cut the pass
    by a fifth on the ball and the part). Its faces read once: the flags of
    :func:`umbrella_certified` (the same conditions: d >= 3, no repeated index, the signs
    and the winding, a_i -> b_i one to one) and, with ``with_partners``, each corner's
    partner: face k's edge v -> a_k is reversed in face l when b_l = a_k, named when that
    face is the only one and face k the only one with v -> a_k (each corner's entry is
    written by its vertex's thread only)."""
    ids = wp.types.vector(length=size, dtype=wp.int32)

    @wp.func
    def one_to_one(a: ids, b: ids) -> bool:
        """Whether a_i -> b_i is a permutation: each b_k equals exactly one a_l and each a_k
        exactly one b_l (then a and b are each without repeats and hold the same values).
        The entries past the fan's size are a_k = b_k = -1 - k: distinct negative values,
        each matching only itself, so they pass and change nothing. Unrolled and
        branch-free: the comparisons cost less than a search whose branches are
        data-dependent."""
        ok = int(1)
        for k in range(size):
            row = int(0)
            col = int(0)
            for l in range(size):
                row += int(b[k] == a[l])
                col += int(a[k] == b[l])
            ok = ok & int(row == 1) & int(col == 1)
        return ok == 1

    @wp.func
    def umbrella(codes: wp.array(dtype=wp.int32), tris: wp.array(dtype=wp.int32), corners: wp.array(dtype=wp.int32),
                 v: int, lo: int, d: int, with_partners: int, certified: wp.array(dtype=wp.int8),
                 partners: wp.array(dtype=wp.int32)):
        fs = ids()
        rs = ids()
        a = ids()
        b = ids()
        signs = int(63)
        counts = int(0)
        repeated = int(0)
        for k in range(size):
            if k < d:
                c = corners[lo + k]
                f = c / 3
                r = c - 3 * f
                fs[k] = f
                rs[k] = r
                ia = tris[3 * f + (r + 1) % 3]
                ib = tris[3 * f + (r + 2) % 3]
                a[k] = ia
                b[k] = ib
                repeated = repeated | int(ia == v) | int(ib == v)
                code = codes[f]
                signs = signs & code
                counts += _spread_bits6((code >> (6 + 6 * r)) & 63)
            else:  # past d: a[k] = b[k] = -1 - k, fixed points of no index (see one_to_one)
                a[k] = -1 - k
                b[k] = -1 - k
        flag = wp.int8(0)
        if d >= 3 and repeated == 0:
            if _winds_once(signs, counts, 0) or _winds_once(signs, counts, 1) or _winds_once(signs, counts, 2):
                if one_to_one(a, b):
                    flag = wp.int8(1)
        for k in range(size):
            if k < d:
                certified[3 * fs[k] + rs[k]] = flag
        if with_partners == 0:
            return
        for k in range(size):
            if k < d:
                l = int(0)
                back = int(0)
                same = int(0)
                for m in range(size):
                    l += m * int(b[m] == a[k])
                    back += int(b[m] == a[k])
                    same += int(a[m] == a[k])
                across = int(-1)
                if back == 1 and same == 1:
                    across = fs[l]
                partners[3 * fs[k] + rs[k]] = across

    return umbrella


_umbrella_of_up_to_5 = _small_umbrella(5)
_umbrella_of_6 = _small_umbrella(6)
_umbrella_of_7 = _small_umbrella(7)
_umbrella_of_8 = _small_umbrella(8)


@wp.kernel
def certify_umbrellas_kernel(codes: wp.array(dtype=wp.int32), tris: wp.array(dtype=wp.int32),
                             starts: wp.array(dtype=wp.int32), corners: wp.array(dtype=wp.int32), first: int,
                             with_partners: int, certified: wp.array(dtype=wp.int8),
                             partners: wp.array(dtype=wp.int32)):
    """One thread per vertex v = first + tid (its corners at ``corners[starts[v]:starts[v +
    1]]``, the last vertex's up to the end): 1 in ``certified[c]`` for each of its corners
    c when :func:`umbrella_certified`, else 0 (every corner belongs to one vertex: each
    entry is written once). With ``with_partners``, also for each corner c = 3 f + r:
    ``partners[c]``, the face across face f's edge r (from its corner r to corner r + 1,
    u = v -> w) when exactly one face holds w -> v and f is the only one with v -> w, else
    -1 (a property of the edge: w's thread, looking at the reversed edge, finds f): the
    block certificate's pairing of edges (:func:`edge_paired`)."""
    v = wp.tid() + first
    lo = starts[v]
    hi = corners.shape[0]
    if v + 1 < starts.shape[0]:
        hi = starts[v + 1]
    d = hi - lo
    if d == 0:
        return
    if d <= 5:
        _umbrella_of_up_to_5(codes, tris, corners, v, lo, d, with_partners, certified, partners)
        return
    if d == 6:
        _umbrella_of_6(codes, tris, corners, v, lo, d, with_partners, certified, partners)
        return
    if d == 7:
        _umbrella_of_7(codes, tris, corners, v, lo, d, with_partners, certified, partners)
        return
    if d == 8:
        _umbrella_of_8(codes, tris, corners, v, lo, d, with_partners, certified, partners)
        return
    flag = wp.int8(0)
    if umbrella_certified(codes, tris, corners, v, lo, hi - lo):
        flag = wp.int8(1)
    for k in range(lo, hi):
        certified[corners[k]] = flag
    if with_partners != 0:
        _pair_wide_umbrella(tris, corners, lo, hi, partners)


@wp.func
def certified_indices(certified: wp.array(dtype=wp.int8), s: int, it: wp.vec3i) -> wp.vec3i:
    """The indices of face s whose umbrellas are certified (``certified`` by corner), -1
    for the others."""
    out = wp.vec3i(-1, -1, -1)
    for k in range(3):
        if certified[3 * s + k] != wp.int8(0):
            out[k] = it[k]
    return out


@wp.func
def shares_certified(cv: wp.vec3i, j0: int, j1: int, j2: int) -> bool:
    """Some index j of the other face is one of the certified indices cv (entries -1:
    none; indices are >= 0)."""
    hit = False
    for k in range(3):
        c = cv[k]
        if c >= 0 and (c == j0 or c == j1 or c == j2):
            hit = True
    return hit


@wp.func
def load_query(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), certified: wp.array(dtype=wp.int8),
               s: int):
    """Face s (sorted position) as the first face of :func:`test_candidate`: its points, indices,
    certified indices, normal and |u| x |v|."""
    t, it = load_triangle(points, tris, s)
    u = t[1] - t[0]
    v = t[2] - t[0]
    return t, it, certified_indices(certified, s, it), wp.cross(u, v), _abs_cross(u, v)


@wp.func
def test_candidate(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                   t: wp.mat33d, it: wp.vec3i, nt: wp.vec3d, na: wp.vec3d, f: int, cv: wp.vec3i, s2: int,
                   keys: wp.array(dtype=wp.int64), start: wp.int64, n: int, limit: int, m: int) -> int:
    """The exact test of face f (its points t, indices it, normal nt and |u| x |v| na, its
    certified indices cv) against the face at sorted position s2, whose box meets its own:
    skipped when they share a certified vertex (they then meet only where they share);
    when they intersect, the pair's key min(f, f2) m + max(f, f2) written at
    ``keys[start + n]`` if n < ``limit``. Returns n plus one per intersecting pair (the
    walks' count and write passes both call it)."""
    j0 = tris[3 * s2]
    j1 = tris[3 * s2 + 1]
    j2 = tris[3 * s2 + 2]
    if shares_certified(cv, j0, j1, j2):
        return n
    f2 = order[s2]
    t2 = wp.matrix_from_rows(points[j0], points[j1], points[j2])
    if not ordered_pair_intersects(t, it, nt, na, f, t2, wp.vec3i(j0, j1, j2), f2):
        return n
    if n < limit:
        keys[start + wp.int64(n)] = wp.int64(wp.min(f, f2)) * wp.int64(m) + wp.int64(wp.max(f, f2))
    return n + 1


#: the positions of the faces of one group that meet a query box, in order (:func:`walk_group`)
group_slots = wp.types.vector(length=GROUP, dtype=wp.int32)


@wp.func
def walk_group(tree_lowers: wp.array(dtype=wp.vec3), tree_uppers: wp.array(dtype=wp.vec3), depth: int, points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
               order: wp.array(dtype=wp.int32), face_lowers: wp.array(dtype=wp.vec3),
               face_uppers: wp.array(dtype=wp.vec3), group_lowers: wp.array(dtype=wp.vec3),
               group_uppers: wp.array(dtype=wp.vec3), pad: float, certified: wp.array(dtype=wp.int8), g: int,
               keys: wp.array(dtype=wp.int64), start: wp.int64, limit: int) -> int:
    """The intersecting pairs of group g with the groups h >= g (each unordered pair of faces
    once): one walk of the group tree (:func:`tree_next`) with g's box grown by ``pad``;
    for each group h >= g met, the faces of h whose boxes meet g's grown box are listed
    first (``group_slots``; all of them when h == g), then each face s of g whose box meets
    h's grown box is screened against the listed faces (only those after s when h == g)
    with its own grown box, and the faces that pass go to the exact test. A face that
    meets the grown box of a face of g meets g's grown box (rounding is monotone:
    s_hi + pad <= g_hi + pad), so the faces left off the list could not pass the face
    test: the same candidates as screening every face of h, 17 face-face box tests a face
    instead of 51 on the part at 512; a list, not a bit mask, so that the loop runs once
    per listed face. A pair that passes the face test but shares a vertex whose umbrella
    is certified (``certified``: by corner of the sorted faces, :func:`umbrella_certified`)
    is skipped before the second face's points are loaded: such faces meet only where
    they share. Returns how many pairs intersect; the first ``limit`` of them are
    written to ``keys[start:]`` as min(f, f2) m + max(f, f2) (f, f2 the input indices)."""
    m = order.shape[0]
    grow = wp.vec3(pad, pad, pad)
    first = GROUP * g
    last = wp.min(first + GROUP, m)
    n = int(0)
    gl = group_lowers[g] - grow
    gh = group_uppers[g] + grow
    h, node, shift = tree_next(tree_lowers, tree_uppers, depth, gl, gh, g, 1, depth)
    while h >= 0:  # every h >= g
        if h >= g:
            hl = group_lowers[h] - grow
            hh = group_uppers[h] + grow
            base = GROUP * h
            end = wp.min(base + GROUP, m)
            slots = group_slots()
            c = int(0)
            for s2 in range(base, end):
                if h == g or boxes_meet(gl, gh, face_lowers[s2], face_uppers[s2]):
                    slots[c] = s2
                    c += 1
            if c > 0:
                for s in range(first, last):
                    lo = face_lowers[s]
                    hi = face_uppers[s]
                    if boxes_meet(hl, hh, lo, hi):
                        lo = lo - grow
                        hi = hi + grow
                        k0 = int(0)
                        if h == g:
                            k0 = s - base + 1
                        f = order[s]
                        # face s loaded here, not at its first candidate: no zeroed placeholders
                        # and no flag (4-5 % of the walk on the part and the ball at 512)
                        t, it, cv, nt, na = load_query(points, tris, certified, s)
                        for k in range(k0, c):
                            s2 = slots[k]
                            if boxes_meet(lo, hi, face_lowers[s2], face_uppers[s2]):
                                n = test_candidate(points, tris, order, t, it, nt, na, f, cv, s2, keys, start, n,
                                                   limit, m)
        h, node, shift = tree_next(tree_lowers, tree_uppers, depth, gl, gh, g, node, shift)
    return n


@wp.kernel
def count_pairs_kernel(tree_lowers: wp.array(dtype=wp.vec3), tree_uppers: wp.array(dtype=wp.vec3), depth: int,
                       points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                       order: wp.array(dtype=wp.int32), face_lowers: wp.array(dtype=wp.vec3),
                       face_uppers: wp.array(dtype=wp.vec3), group_lowers: wp.array(dtype=wp.vec3),
                       group_uppers: wp.array(dtype=wp.vec3), pad: float, certified: wp.array(dtype=wp.int8),
                       first: int, unused: wp.array(dtype=wp.int64), counts: wp.array(dtype=wp.int64)):
    """One thread per group g = first + tid (``tris`` and ``order`` in the Morton order of
    the faces, ``order[s]`` the input index of position s): how many pairs of its faces with
    the faces of groups h >= g intersect (:func:`walk_group`, writing nothing)."""
    g = wp.tid() + first
    counts[g] = wp.int64(walk_group(tree_lowers, tree_uppers, depth, points, tris, order, face_lowers, face_uppers, group_lowers,
                                    group_uppers, pad, certified, g, unused, wp.int64(0), 0))


@wp.kernel
def write_pairs_kernel(tree_lowers: wp.array(dtype=wp.vec3), tree_uppers: wp.array(dtype=wp.vec3), depth: int,
                       points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                       order: wp.array(dtype=wp.int32), face_lowers: wp.array(dtype=wp.vec3),
                       face_uppers: wp.array(dtype=wp.vec3), group_lowers: wp.array(dtype=wp.vec3),
                       group_uppers: wp.array(dtype=wp.vec3), pad: float, certified: wp.array(dtype=wp.int8),
                       first: int, counts: wp.array(dtype=wp.int64), offsets: wp.array(dtype=wp.int64),
                       keys: wp.array(dtype=wp.int64)):
    """One thread per group g = first + tid with ``counts[g] > 0``: the walk of
    :func:`count_pairs_kernel` again, writing its pairs' keys to ``keys[offsets[g]:]``."""
    g = wp.tid() + first
    n = counts[g]
    if n == wp.int64(0):
        return
    walk_group(tree_lowers, tree_uppers, depth, points, tris, order, face_lowers, face_uppers, group_lowers, group_uppers, pad,
               certified, g, keys, offsets[g], int(n))


@wp.kernel
def all_pairs_kernel(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                     degenerate: wp.array(dtype=wp.int32), certified: wp.array(dtype=wp.int8),
                     hits: wp.array2d(dtype=wp.int8)):
    """The reference of the candidate search (small meshes only): one thread per (f, g),
    f < g input indices, both non-degenerate and sharing no vertex whose umbrella is
    certified (``certified`` by corner of the input faces, :func:`umbrella_certified`; all
    0 for none): :func:`pair_intersects` with no BVH and no box screen, 1 in
    ``hits[f, g]`` when they intersect (else left as it was: 0)."""
    f, g = wp.tid()
    if f < g and degenerate[f] == 0 and degenerate[g] == 0:
        p, ip = load_triangle(points, tris, f)
        q, iq = load_triangle(points, tris, g)
        if shares_certified(certified_indices(certified, f, ip), iq[0], iq[1], iq[2]):
            return
        u = p[1] - p[0]
        v = p[2] - p[0]
        if confirmed_pair_intersects(p, ip, wp.cross(u, v), _abs_cross(u, v), q, iq):
            hits[f, g] = wp.int8(1)


# -- the cell grid: the candidate search of surfaces whose faces are about one size ------------

#: cells per axis of the grid at most (10-bit coordinates: a 30-bit Morton key)
GRID_CELLS = 1024
#: cells per axis of a block of the two-level cell table (:func:`grid_cell_index`): 2^3, so
#: that a cell's place in its block is the low 9 bits of its Morton key
BLOCK = 8
#: the 64-bit words of a block's occupancy mask (BLOCK^3 = 512 bits, :func:`cell_masks_kernel`)
BLOCK_WORDS = 8
block_words = wp.types.vector(length=BLOCK_WORDS, dtype=wp.uint64)


@wp.func
def grid_coordinate(x: float, inv_cell: float) -> int:
    """The cell coordinate of a float32 BVH coordinate x (in about [-1, 1]): floor((x + 1)
    inv_cell), clamped to [0, ``GRID_CELLS``). Monotone in x (every step is), which is all
    the grid's soundness rests on (:func:`grid_walk_cell`)."""
    return wp.clamp(int((x + 1.0) * inv_cell), 0, GRID_CELLS - 1)


@wp.kernel
def face_extents_kernel(first: int, points32: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.int32),
                        extents: wp.array(dtype=wp.float32)):
    """One thread per face f = first + tid: the largest side of its float32 box."""
    f = first + wp.tid()
    lo, hi = face_box(points32, tris, f)
    extents[f] = largest_side(lo, hi)


@wp.kernel
def spread_table_kernel(table: wp.array(dtype=wp.int32)):
    """One thread per x in [0, ``GRID_CELLS``): :func:`spread_bits` of x (the grid keys'
    table: three reads of it cost less than three interleaves, 5 of the 16 ms of half the
    ball's keys)."""
    x = wp.tid()
    table[x] = spread_bits(x)


@wp.kernel
def grid_keys_kernel(first: int, points32: wp.array(dtype=wp.vec3), tris: wp.array(dtype=wp.int32), pad: float,
                     inv_cell: float, base: int, spread: wp.array(dtype=wp.int32), keys: wp.array(dtype=wp.int32),
                     ids: wp.array(dtype=wp.int32), wide: wp.array(dtype=wp.int32)):
    """One thread per face f = first + tid: the Morton key of the cell of its box's lower
    corner (the sort key, from ``spread``: :func:`spread_table_kernel`; f the value), at
    ``keys[f - base]`` and ``ids[f - base]`` (a base other than 0 puts a range of faces
    where its own sort wants it), and 1 in ``wide[0]`` (a plain store of a constant:
    no lost update matters when launches on two CPU threads both write it, where an
    atomic add is not atomic on the CPU) when the cell of its upper corner grown
    by ``pad`` is more than one cell past it along some axis (the grid then cannot be used:
    :func:`grid_walk_cell` needs every face within two cells per axis; the three axes
    tested without branches, a third of the pass's time with them)."""
    f = first + wp.tid()
    lo, hi = face_box(points32, tris, f)
    q = hi + wp.vec3(pad, pad, pad)
    x = grid_coordinate(lo[0], inv_cell)
    y = grid_coordinate(lo[1], inv_cell)
    z = grid_coordinate(lo[2], inv_cell)
    far = (int(grid_coordinate(q[0], inv_cell) > x + 1) | int(grid_coordinate(q[1], inv_cell) > y + 1)
           | int(grid_coordinate(q[2], inv_cell) > z + 1))
    if far != 0:
        wide[0] = 1
    keys[f - base] = (spread[x] << 2) | (spread[y] << 1) | spread[z]
    ids[f - base] = f


@wp.kernel
def merge_runs_kernel(first: int, keys: wp.array(dtype=wp.int32), ids: wp.array(dtype=wp.int32), a0: int, na: int,
                      b0: int, nb: int, chunk: int, out_keys: wp.array(dtype=wp.int32),
                      out_ids: wp.array(dtype=wp.int32)):
    """One thread per output chunk t = first + tid: positions [t chunk, (t + 1) chunk) of the
    stable merge of the sorted runs A = keys[a0:a0 + na] and B = keys[b0:b0 + nb] (their
    ids alongside), A's items first among equal keys (A holds the lower ids: the merge of
    two stably sorted halves is then the stable sort of the whole). The chunk's start on
    the merge path is found by a binary search: the number i of A's items among the first
    d outputs is the first i with A[i] > B[d - i - 1], a predicate true then false as i
    grows; then an ordinary merge."""
    t = first + wp.tid()
    d = t * chunk
    end = wp.min(d + chunk, na + nb)
    if d >= end:
        return
    lo = wp.max(0, d - nb)
    hi = wp.min(d, na)
    while lo < hi:
        mid = (lo + hi) / 2
        if keys[a0 + mid] <= keys[b0 + d - mid - 1]:
            lo = mid + 1
        else:
            hi = mid
    ia = lo
    ib = d - lo
    for k in range(d, end):
        take_a = ia < na
        if take_a and ib < nb:
            take_a = keys[a0 + ia] <= keys[b0 + ib]
        if take_a:
            out_keys[k] = keys[a0 + ia]
            out_ids[k] = ids[a0 + ia]
            ia += 1
        else:
            out_keys[k] = keys[b0 + ib]
            out_ids[k] = ids[b0 + ib]
            ib += 1


@wp.kernel
def cell_heads_kernel(first: int, keys: wp.array(dtype=wp.int32), heads: wp.array(dtype=wp.int32)):
    """One thread per position s = first + tid of the sorted keys: 1 when s starts a cell
    (its key differs from the one before), else 0."""
    s = first + wp.tid()
    head = int(1)
    if s > 0:
        if keys[s] == keys[s - 1]:
            head = 0
    heads[s] = head


@wp.func
def compact_bits(x: int) -> int:
    """Every third bit of x gathered into the 10 low bits (the inverse of :func:`spread_bits`)."""
    x = x & 0x09249249
    x = (x | (x >> 2)) & 0x030C30C3
    x = (x | (x >> 4)) & 0x0300F00F
    x = (x | (x >> 8)) & 0x030000FF
    return (x | (x >> 16)) & 0x000003FF


@wp.func
def table_block(p: wp.vec3i, blocks_per_axis: int) -> int:
    """The index of the table block (``BLOCK``^3 cells) of cell coordinates p, in the
    dense array of all blocks."""
    return ((p[0] / BLOCK) * blocks_per_axis + p[1] / BLOCK) * blocks_per_axis + p[2] / BLOCK


@wp.func
def place_in_block(x: int, y: int, z: int) -> int:
    """The place of cell (x, y, z) in its table block: the Morton interleave of its
    coordinates modulo ``BLOCK`` (the low 9 bits of its key), in [0, 512). The cells of a
    block are consecutive in Morton order and ascend in place."""
    return (spread_bits(x % BLOCK) << 2) | (spread_bits(y % BLOCK) << 1) | spread_bits(z % BLOCK)


@wp.func
def popcount64(x: wp.uint64) -> int:
    """The number of bits set in x (the classic SWAR sum: pairs, nibbles, bytes, then one
    multiply adds the bytes into the top one)."""
    x = x - ((x >> wp.uint64(1)) & wp.uint64(0x5555555555555555))
    x = (x & wp.uint64(0x3333333333333333)) + ((x >> wp.uint64(2)) & wp.uint64(0x3333333333333333))
    x = (x + (x >> wp.uint64(4))) & wp.uint64(0x0F0F0F0F0F0F0F0F)
    return int((x * wp.uint64(0x0101010101010101)) >> wp.uint64(56))


@wp.kernel
def cell_starts_kernel(first: int, keys: wp.array(dtype=wp.int32), heads: wp.array(dtype=wp.int32),
                       cell_of: wp.array(dtype=wp.int32), blocks_per_axis: int,
                       starts: wp.array(dtype=wp.int32), cells: wp.array(dtype=wp.vec3i),
                       block_used: wp.array(dtype=wp.int32)):
    """One thread per position s = first + tid that starts a cell (``cell_of``: the inclusive
    scan of the heads, so its cell is ``cell_of[s] - 1``): the cell's first position, its
    coordinates (from the key) and a mark on its block of ``BLOCK``^3 cells (a store of 1:
    threads on two cores may both write it)."""
    s = first + wp.tid()
    if heads[s] == 0:
        return
    c = cell_of[s] - 1
    k = keys[s]
    x = compact_bits(k >> 2)
    y = compact_bits(k >> 1)
    z = compact_bits(k)
    starts[c] = s
    cells[c] = wp.vec3i(x, y, z)
    block_used[table_block(wp.vec3i(x, y, z), blocks_per_axis)] = 1


@wp.kernel
def cell_masks_kernel(first: int, cells: wp.array(dtype=wp.vec3i), blocks_per_axis: int,
                      block_slot: wp.array(dtype=wp.int32), masks: wp.array(dtype=wp.uint64),
                      ranks: wp.array(dtype=wp.int32)):
    """One thread per occupied cell c = first + tid; the first cell of each used table block
    (its cells are consecutive: Morton order) walks the block's cells and writes, at the
    block's slot (``block_slot``: the exclusive scan of the used blocks), its ``BLOCK_WORDS``
    occupancy words (bit :func:`place_in_block` of each occupied cell) and before each word
    the index of the first cell it holds (c plus the bits below it): a cell's index is
    then its word's rank plus the bits set below it in the word (:func:`grid_cell_index`).
    8 bytes of mask and 4 of rank per 64 cells of a used block, against 4 bytes per cell
    for a table of indices: the table of a sphere at 512 is 1.2 MB instead of 26 MB (its
    fill was 12 ms of the check)."""
    c = first + wp.tid()
    p = cells[c]
    b = table_block(p, blocks_per_axis)
    if c > 0:
        if table_block(cells[c - 1], blocks_per_axis) == b:
            return
    words = block_words()
    n_cells = cells.shape[0]
    c2 = c
    while c2 < n_cells:
        q = cells[c2]
        if table_block(q, blocks_per_axis) != b:
            break
        place = place_in_block(q[0], q[1], q[2])
        words[place / 64] = words[place / 64] | (wp.uint64(1) << wp.uint64(place % 64))
        c2 += 1
    slot = block_slot[b] * BLOCK_WORDS
    rank = c
    for w in range(BLOCK_WORDS):
        masks[slot + w] = words[w]
        ranks[slot + w] = rank
        rank += popcount64(words[w])


@wp.kernel
def cell_reach_kernel(first: int, starts: wp.array(dtype=wp.int32), cells: wp.array(dtype=wp.vec3i),
                      face_uppers: wp.array(dtype=wp.vec3), inv_cell: float, reach: wp.array(dtype=wp.int32)):
    """One thread per occupied cell c = first + tid: the bits of the axes (x 4, y 2, z 1)
    along which some face of c reaches the next cell up (the cell of its grown upper
    corner is past c's, :func:`grid_coordinate`). A face of another cell can meet a face
    of c only along the axes where it lies one cell up from c if c's faces reach there,
    and along those where c lies one cell up from it if its own cell's faces reach
    there (:func:`grid_walk_cell`)."""
    c = first + wp.tid()
    s1 = face_uppers.shape[0]
    if c + 1 < starts.shape[0]:
        s1 = starts[c + 1]
    p = cells[c]
    bits = int(0)
    for s in range(starts[c], s1):
        bits = bits | reach_bits(face_uppers[s], p, inv_cell)
    reach[c] = bits


#: the block sizes tried, as shifts (blocks of 2^shift cells per axis), largest first: a
#: block that fails is tried again as its eight halves (:func:`certify_blocks_kernel`).
#: 128^3 down to 4^3 (with the grid's cell at twice the largest face side; 64^3 to 8^3,
#: the sizes before, leave the ball's walk 7.7 ms, the part's 34 ms; these 4.9 and 26)
BLOCK_SHIFT_TOP = 7
BLOCK_LEVELS = 6
BLOCK_SHIFTS = tuple(BLOCK_SHIFT_TOP - i for i in range(BLOCK_LEVELS))
#: ``cell_reach`` >> LEVEL_BIT (3 bits): the shift of the cell's certified block, 0 if none
LEVEL_BIT = wp.constant(3)


#: the most unpaired edges a block of 2^shift cells per axis may have for
#: :func:`_simple_loop` (its scratch per block): LOOP_CAP_PER_CELL << shift
LOOP_CAP_PER_CELL = 16


@wp.kernel
def block_heads_kernel(first: int, cells: wp.array(dtype=wp.vec3i), heads: wp.array(dtype=wp.int8)):
    """One thread per occupied cell c = first + tid (in Morton order, so the cells of a block
    of 2^shift per axis are consecutive): bit i set when c is the first of its block for
    the shift ``BLOCK_SHIFTS[i]``."""
    c = first + wp.tid()
    bits = (1 << BLOCK_LEVELS) - 1
    if c > 0:
        p = cells[c]
        q = cells[c - 1]
        bits = 0
        for i in range(BLOCK_LEVELS):
            shift = BLOCK_SHIFT_TOP - i
            if p[0] >> shift != q[0] >> shift or p[1] >> shift != q[1] >> shift or p[2] >> shift != q[2] >> shift:
                bits = bits | (1 << i)
    heads[c] = wp.int8(bits)


@wp.func
def edge_paired(degenerate: wp.array(dtype=wp.int32), partners: wp.array(dtype=wp.int32), f0: int, f1: int, s: int,
                r: int) -> bool:
    """Edge r of face s (from its corner r to corner r + 1, u -> v) is *paired* when the face
    g = ``partners[3 s + r]`` across it (:func:`certify_umbrellas_kernel`: the only face
    with v -> u, s the only one with u -> v) is a non-degenerate face at a position in
    [f0, f1). Symmetric among the non-degenerate faces there: g's edge v -> u names s (the
    same two facts, seen from v), so pairing matches edges with their reverses one to
    one."""
    g = partners[3 * s + r]
    if g < f0 or g >= f1:
        return False
    return degenerate[g] == 0


#: two coordinates differ "by a margin" when by more than this: 2 ``INPUT_TOL`` (each may move
#: by ``INPUT_TOL``)
APART = wp.constant(wp.float64(2.0**-47))


@wp.func
def _adjacent_edges_meet_once(ax: wp.float64, ay: wp.float64, bx: wp.float64, by: wp.float64, cx: wp.float64,
                              cy: wp.float64) -> bool:
    """Whether the segments [a, b] and [b, c] have only b in common, for every move of the
    points within ``INPUT_TOL``: a, b, c certified not collinear by a margin
    (:func:`orient2d_margin`), or strictly monotone along x or along y by more than
    ``APART`` a step (then every other point of [a, b] has that coordinate on one side
    of b's and every other point of [b, c] on the other)."""
    if ((bx - ax > APART and cx - bx > APART) or (ax - bx > APART and bx - cx > APART)
            or (by - ay > APART and cy - by > APART) or (ay - by > APART and by - cy > APART)):
        return True
    return orient2d_margin(wp.vec3d(ax, ay, wp.float64(0.0)), wp.vec3d(bx, by, wp.float64(0.0)),
                           wp.vec3d(cx, cy, wp.float64(0.0)), 0, 1) != 0


@wp.func
def _segments_apart(a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, d: wp.vec3d) -> bool:
    """Whether the closed segments [a, b] and [c, d] (coordinates 0 and 1) are certified
    disjoint for every move of the points within ``INPUT_TOL``: their boxes apart by more
    than ``APART``, or one's two ends on one side of the other's line by a margin
    (:func:`orient2d_margin`; 0, unknown, proves nothing)."""
    if (wp.min(c[0], d[0]) - wp.max(a[0], b[0]) > APART or wp.min(a[0], b[0]) - wp.max(c[0], d[0]) > APART
            or wp.min(c[1], d[1]) - wp.max(a[1], b[1]) > APART or wp.min(a[1], b[1]) - wp.max(c[1], d[1]) > APART):
        return True
    o1 = orient2d_margin(a, b, c, 0, 1)
    if o1 != 0 and o1 == orient2d_margin(a, b, d, 0, 1):
        return True
    o3 = orient2d_margin(c, d, a, 0, 1)
    return o3 != 0 and o3 == orient2d_margin(c, d, b, 0, 1)


@wp.func
def _star_loop(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), degenerate: wp.array(dtype=wp.int32),
               open_edges: wp.array(dtype=wp.int8), f0: int, f1: int, centre: wp.vec3d, k: int) -> bool:
    """Whether the unpaired edges of the faces at [f0, f1), projected with coordinates (i, j)
    kept (k / 2 the dropped one; read in the order that makes the faces with sign bit k
    of :func:`classify_face` positive), all turn counter-clockwise by a margin
    (:func:`orient2d_margin`) about the centre's projection and cross the ray from it
    along +i upwards once in all."""
    i = (k / 2 + 1) % 3
    j = (k / 2 + 2) % 3
    if k % 2 == 1:
        i = (k / 2 + 2) % 3
        j = (k / 2 + 1) % 3
    o = wp.vec3d(centre[i], centre[j], wp.float64(0.0))
    crossings = int(0)
    for s in range(f0, f1):
        if degenerate[s] != 0:
            continue
        for r in range(3):
            if (int(open_edges[s]) >> r) & 1 != 0:
                x = points[tris[3 * s + r]]
                y = points[tris[3 * s + (r + 1) % 3]]
                a = wp.vec3d(x[i], x[j], wp.float64(0.0))
                b = wp.vec3d(y[i], y[j], wp.float64(0.0))
                if orient2d_margin(o, a, b, 0, 1) <= 0:
                    return False
                if a[1] < o[1] and o[1] <= b[1]:
                    crossings += 1
    return crossings == 1


@wp.func
def _projected(points: wp.array(dtype=wp.vec3d), v: int, i: int, j: int) -> wp.vec3d:
    """Point v's coordinates i and j as the first two of a vector (the third 0)."""
    x = points[v]
    return wp.vec3d(x[i], x[j], wp.float64(0.0))


#: edges per run of :func:`_simple_loop`'s box screen
LOOP_RUN = 16


@wp.func
def _loop_edge_clear(points: wp.array(dtype=wp.vec3d), ids: wp.array(dtype=wp.vec2i), nexts: wp.array(dtype=wp.int32),
                     e: int, e0: int, e1: int, i: int, j: int) -> bool:
    """Edge e against the edges [e0, e1) of :func:`_simple_loop` (coordinates i, j): False
    when two leave or enter one vertex, when consecutive ones (recorded in ``nexts``)
    meet other than at their common end, or when others are not certified apart."""
    p = ids[e]
    a = _projected(points, p[0], i, j)
    b = _projected(points, p[1], i, j)
    lo_x = wp.min(a[0], b[0])
    hi_x = wp.max(a[0], b[0])
    lo_y = wp.min(a[1], b[1])
    hi_y = wp.max(a[1], b[1])
    for e2 in range(e0, e1):
        q = ids[e2]
        if p[0] == q[0] or p[1] == q[1]:
            return False  # two edges leave (or enter) one vertex
        if p[1] == q[0]:  # e then e2
            nexts[e] = e2
            c = _projected(points, q[1], i, j)
            if not _adjacent_edges_meet_once(a[0], a[1], b[0], b[1], c[0], c[1]):
                return False
        elif q[1] == p[0]:  # e2 then e
            nexts[e2] = e
            c = _projected(points, q[0], i, j)
            if not _adjacent_edges_meet_once(c[0], c[1], a[0], a[1], b[0], b[1]):
                return False
        else:
            c = _projected(points, q[0], i, j)
            d = _projected(points, q[1], i, j)
            if not (wp.max(c[0], d[0]) < lo_x or wp.min(c[0], d[0]) > hi_x or wp.max(c[1], d[1]) < lo_y
                    or wp.min(c[1], d[1]) > hi_y):
                if not _segments_apart(a, b, c, d):
                    return False
    return True


@wp.func
def _simple_loop(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), degenerate: wp.array(dtype=wp.int32),
                 open_edges: wp.array(dtype=wp.int8), f0: int, f1: int, k: int, n: int, ids: wp.array(dtype=wp.vec2i),
                 nexts: wp.array(dtype=wp.int32), base: int, runs: wp.array(dtype=wp.vec4d), run_base: int) -> bool:
    """Whether the n unpaired edges of the faces at [f0, f1), projected as in
    :func:`_star_loop`, form one closed loop whose projection is a simple polygon: no
    vertex is the tail (or the head) of two of them, each edge's successor is the one
    whose tail is its head, following successors from the first edge meets all n before
    coming back, consecutive segments have only their common end in common
    (:func:`_adjacent_edges_meet_once`) and any other two are certified disjoint
    (:func:`_segments_apart`). The edges' ends are written to ``ids``, their successors
    to ``nexts``, from ``base`` on, and the boxes of runs of ``LOOP_RUN`` of them to
    ``runs`` from ``run_base`` on (scratch: n at most the block's ``LOOP_CAP_PER_CELL <<
    shift``)."""
    i = (k / 2 + 1) % 3
    j = (k / 2 + 2) % 3
    if k % 2 == 1:
        i = (k / 2 + 2) % 3
        j = (k / 2 + 1) % 3
    e = base
    for s in range(f0, f1):
        if degenerate[s] != 0:
            continue
        for r in range(3):
            if (int(open_edges[s]) >> r) & 1 != 0:
                ids[e] = wp.vec2i(tris[3 * s + r], tris[3 * s + (r + 1) % 3])
                nexts[e] = -1
                e += 1
    # runs of LOOP_RUN edges in the faces' (Morton) order are compact: their boxes screen
    # the pairs (two segments that meet lie in two boxes that meet)
    n_runs = (n + LOOP_RUN - 1) / LOOP_RUN
    for t in range(n_runs):
        lo = wp.vec2d(wp.float64(1.0e300), wp.float64(1.0e300))
        hi = wp.vec2d(wp.float64(-1.0e300), wp.float64(-1.0e300))
        for e in range(base + t * LOOP_RUN, wp.min(base + n, base + (t + 1) * LOOP_RUN)):
            p = ids[e]
            a = _projected(points, p[0], i, j)
            b = _projected(points, p[1], i, j)
            lo = wp.vec2d(wp.min(lo[0], wp.min(a[0], b[0])), wp.min(lo[1], wp.min(a[1], b[1])))
            hi = wp.vec2d(wp.max(hi[0], wp.max(a[0], b[0])), wp.max(hi[1], wp.max(a[1], b[1])))
        runs[run_base + t] = wp.vec4d(lo[0], lo[1], hi[0], hi[1])
    for t in range(n_runs):
        box = runs[run_base + t]
        for t2 in range(t, n_runs):
            box2 = runs[run_base + t2]
            if box2[0] > box[2] or box[0] > box2[2] or box2[1] > box[3] or box[1] > box2[3]:
                continue
            for e in range(base + t * LOOP_RUN, wp.min(base + n, base + (t + 1) * LOOP_RUN)):
                if not _loop_edge_clear(points, ids, nexts, e, wp.max(e + 1, base + t2 * LOOP_RUN),
                                        wp.min(base + n, base + (t2 + 1) * LOOP_RUN), i, j):
                    return False
    e = base
    for step in range(1, n + 1):
        e = nexts[e]
        if e < 0 or (e == base and step < n):
            return False
    return e == base


@wp.func
def block_certified(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                    degenerate: wp.array(dtype=wp.int32), codes: wp.array(dtype=wp.int32),
                    partners: wp.array(dtype=wp.int32), f0: int, f1: int,
                    open_edges: wp.array(dtype=wp.int8), ids: wp.array(dtype=wp.vec2i),
                    nexts: wp.array(dtype=wp.int32), runs: wp.array(dtype=wp.vec4d), base: int, run_base: int,
                    cap: int) -> bool:
    """Whether no two faces at sorted positions [f0, f1) (a block's) meet other than in
    what they share (a vertex or an edge, by index), certified from those faces alone
    (and which faces hold each of their edges), so that the grid walk can skip every pair
    of them. Degenerate faces meet nothing and are left out; P is the rest.

    Certified when:

    1. some projection dropping a coordinate has every face of P strictly of one
       orientation by a margin (bit k of the faces' codes from ``MARGIN_SIGNS``,
       :func:`classify_face`), made positive by reading the two kept coordinates in the
       right order (:func:`_star_loop`);
    2. E, the edges of P's faces that are not *paired* (:func:`edge_paired`: the face
       across is the only one with the reversed edge, in the block and not degenerate,
       decided alike from either end of the edge, whatever its number of faces; pairing
       matches edges with their reverses one to one) is, projected, a simple closed
       polygon:
       either every edge of E turns strictly counter-clockwise about the mean of E's tails
       and the ray from it crosses E upwards once (:func:`_star_loop`: E is a closed
       chain, as the sum of the faces' boundaries less the pairs that cancel; each of
       its cycles winds at least once about the point, all of them once in all, so E is
       one cycle around it, each edge in its own sector), or, in the first projection
       that condition 1 allows, E is one loop of at most ``cap`` edges with consecutive
       segments meeting only at their common end and any other two certified disjoint
       (:func:`_simple_loop`).

    Proof. For a point y of the plane off every projected edge of P, let N(y) be the
    number of faces of P whose projection holds y. A positive triangle's boundary winds
    once about the points inside it and not about those outside, so N(y) is the winding
    number of the chain of all the faces' edges; paired edges cancel with their
    reverses, so N(y) is the winding number of E, a simple polygon: 0 or 1 (and not -1:
    N >= 0). Let x be a common point of faces f != g of P, y its projection. (a) y inside
    f's projection: a neighbourhood of y lies in it, and meets the inside of g's (g is
    proper, y in it): an open set where N >= 2. So y is on the boundary of both
    projections, and x (each face projects one to one) on an edge or a vertex of each.
    (b) x inside an edge e of f, e paired with f': the projections of f and f' lie on the
    two sides of e's (both positive, e reversed in f'), so they cover a neighbourhood of y
    and g overlaps one of them on an open set unless g = f', and then x, on e, is in what
    f and f' share. (c) x inside an edge e of f, e in E: f lies on one side of e's
    projection near y, where N = 1, so N = 0 on the other side (N changes by one across a
    polygon's side). If x is inside an edge of g: paired, (b) with g for f; in E, two
    sides of a simple polygon that meet inside one of them, unless they are one: then
    g = f. If x is a vertex of g, g's projection holds a sector at y, on f's side
    (N >= 2) or the other (N >= 1 where N = 0). (d) x a vertex v of f not in g: if x is
    inside an edge of g, (b) or (c) with g for f; else x is a vertex w != v of g (the
    same point). If every edge at v is paired, the faces at v form closed fans of
    positive wedges, which cover a neighbourhood of y (winding at least once), and g's
    sector at y overlaps them; so v is a vertex of the polygon, and so is w: two
    vertices of a simple polygon at one point, which it is not. So f and g meet only in
    what they share. Filtered signs of 0 fail the conditions.

    Every sign and comparison here holds by a margin (:func:`orient2d_margin`, ``APART``):
    for every move of the points within ``INPUT_TOL``, as the predicate's certificates of
    separation are made (:func:`pair_intersects`), so a pair that it reports as touching
    within rounding is never inside a certified block (exact signs certified a fan with
    a slit 2^-50 wide, whose two sides every pair reports)."""
    signs = int(63)
    n = int(0)
    sums = wp.vec3d()
    for s in range(f0, f1):
        if degenerate[s] != 0:
            continue
        signs = signs & (codes[s] >> MARGIN_SIGNS)
        if signs & 63 == 0:
            return False
        bits = int(0)
        for r in range(3):
            if not edge_paired(degenerate, partners, f0, f1, s, r):
                sums += points[tris[3 * s + r]]
                n += 1
                bits = bits | (1 << r)
        open_edges[s] = wp.int8(bits)
    if n < 3:
        return False
    first = int(-1)
    for k in range(6):
        if (signs >> k) & 1 != 0:
            if _star_loop(points, tris, degenerate, open_edges, f0, f1, sums / wp.float64(n), k):
                return True
            if first < 0:
                first = k
    if n > cap:
        return False
    return _simple_loop(points, tris, degenerate, open_edges, f0, f1, first, n, ids, nexts, base, runs, run_base)


@wp.kernel
def certify_blocks_kernel(first: int, firsts: wp.array(dtype=wp.int32), starts: wp.array(dtype=wp.int32), shift: int,
                          bases: wp.array(dtype=wp.vec2i), points: wp.array(dtype=wp.vec3d),
                          tris: wp.array(dtype=wp.int32), degenerate: wp.array(dtype=wp.int32),
                          codes: wp.array(dtype=wp.int32), partners: wp.array(dtype=wp.int32),
                          open_edges: wp.array(dtype=wp.int8), ids: wp.array(dtype=wp.vec2i),
                          nexts: wp.array(dtype=wp.int32), runs: wp.array(dtype=wp.vec4d),
                          reach: wp.array(dtype=wp.int32)):
    """One thread per block b = first + tid of 2^shift cells per axis (its cells from
    ``firsts[b]`` to the next block's first, its faces from the first cell's start to the
    next block's): the shift written in the bits ``LEVEL_BIT`` of ``reach`` of each of its
    cells when :func:`block_certified`. A block inside a larger certified one (its first
    cell has a level already) is skipped. Its scratch: ``ids`` and ``nexts`` from
    ``bases[b][0]`` (room for the smaller of ``LOOP_CAP_PER_CELL << shift`` and 3 edges a
    face), ``runs`` from ``bases[b][1]`` (one per ``LOOP_RUN`` of those)."""
    b = first + wp.tid()
    n_cells = starts.shape[0]
    c0 = firsts[b]
    if (reach[c0] >> LEVEL_BIT) & 7 != 0:
        return
    c1 = n_cells
    if b + 1 < firsts.shape[0]:
        c1 = firsts[b + 1]
    f1 = degenerate.shape[0]
    if c1 < n_cells:
        f1 = starts[c1]
    cap = wp.min(LOOP_CAP_PER_CELL << shift, 3 * (f1 - starts[c0]))
    if block_certified(points, tris, degenerate, codes, partners, starts[c0], f1, open_edges, ids, nexts,
                       runs, bases[b][0], bases[b][1], cap):
        for c in range(c0, c1):
            reach[c] = reach[c] | (shift << LEVEL_BIT)


@wp.func
def reach_bits(hi: wp.vec3, p: wp.vec3i, inv_cell: float) -> int:
    """The bits of the axes (x 4, y 2, z 1) along which a face of cell p whose grown upper
    corner is ``hi`` reaches the next cell up (:func:`grid_coordinate` past p's)."""
    bits = int(0)
    if grid_coordinate(hi[0], inv_cell) > p[0]:
        bits = bits | 4
    if grid_coordinate(hi[1], inv_cell) > p[1]:
        bits = bits | 2
    if grid_coordinate(hi[2], inv_cell) > p[2]:
        bits = bits | 1
    return bits


@wp.func
def grid_cell_index(x: int, y: int, z: int, blocks_per_axis: int, block_used: wp.array(dtype=wp.int32),
                    block_slot: wp.array(dtype=wp.int32), masks: wp.array(dtype=wp.uint64),
                    ranks: wp.array(dtype=wp.int32)) -> int:
    """The index of cell (x, y, z) among the occupied cells, or -1 when no face's lower
    corner is in it (or it is off the grid): the block's slot, then its occupancy word and
    that word's rank (:func:`cell_masks_kernel`), plus the occupied places below the cell's."""
    side = blocks_per_axis * BLOCK
    if x < 0 or y < 0 or z < 0 or x >= side or y >= side or z >= side:
        return -1
    b = table_block(wp.vec3i(x, y, z), blocks_per_axis)
    if block_used[b] == 0:
        return -1
    place = place_in_block(x, y, z)
    w = block_slot[b] * BLOCK_WORDS + place / 64
    word = masks[w]
    bit = wp.uint64(place % 64)
    if ((word >> bit) & wp.uint64(1)) == wp.uint64(0):
        return -1
    return ranks[w] + popcount64(word & ((wp.uint64(1) << bit) - wp.uint64(1)))


#: a cell and its occupied upper neighbours (:func:`grid_walk_cell`)
neighbour_cells = wp.types.vector(length=14, dtype=wp.int32)


@wp.func
def grid_walk_cell(cells: wp.array(dtype=wp.vec3i), starts: wp.array(dtype=wp.int32), blocks_per_axis: int,
                   block_used: wp.array(dtype=wp.int32), block_slot: wp.array(dtype=wp.int32),
                   masks: wp.array(dtype=wp.uint64), ranks: wp.array(dtype=wp.int32), inv_cell: float, points: wp.array(dtype=wp.vec3d),
                   tris: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                   face_lowers: wp.array(dtype=wp.vec3), face_uppers: wp.array(dtype=wp.vec3),
                   certified: wp.array(dtype=wp.int8), cell_reach: wp.array(dtype=wp.int32), c: int,
                   keys: wp.array(dtype=wp.int64), start: wp.int64, limit: int) -> int:
    """The intersecting pairs of the faces of cell c (positions ``starts[c]`` to the next
    cell's start: the faces whose box's lower corner is in it) with the faces of the same
    cell after them and with every face of the 13 neighbouring cells (dx, dy, dz) > (0, 0,
    0) in lexicographic order. Each unordered pair of faces is met once: the pair of their
    cells is one of these (c, c2) in exactly one order. The screen compares each face's
    lower corner with the other's upper corner grown by the padding (``face_uppers``, as
    :func:`padded_face_box` grew them: the same float32 sums as ``grid_keys_kernel``'s),
    which is symmetric in the two faces and conservative (float32 boxes of faces that meet
    meet before any growing). None is missed: the cell coordinate g
    (:func:`grid_coordinate`) is monotone, so lo_b <= up_a gives g(lo_b) <= g(up_a) <=
    g(lo_a) + 1 (``grid_keys_kernel`` refused the grid otherwise), and lo_a <= up_b gives
    g(lo_a) <= g(lo_b) + 1: the cells of two faces that pass are at most one apart along
    each axis. A face skips the neighbours one cell above it along an axis k when its
    grown upper corner stays in its own cell along k (g(up_a) = g(lo_a)): a face b there
    has g(lo_b) = g(lo_a) + 1 > g(up_a), so lo_b > up_a and the boxes cannot meet (about
    half the box screens on a grid mesher's surface); likewise a neighbour is skipped
    whole, before its faces are read (one up along every axis it lies on: before its
    index is even looked up), along the same argument per cell (``cell_reach``,
    :func:`cell_reach_kernel`: the union of its faces' reach bits): one up along k needs some face of c reaching k, one down along k (the
    neighbours (1, -1, *), (1, *, -1), (0, 1, -1)) needs some face of that neighbour
    reaching k into c (17 % of the walk on the ball at 512). When c's block of 2^level
    cells per axis is certified (``cell_reach`` >> ``LEVEL_BIT``, :func:`block_certified`),
    c itself and the neighbours in that block are skipped: no two of its faces meet but
    in what they share. A pair that passes is then
    skipped if it shares a certified vertex, else
    given the exact test in float64, as in :func:`walk_group`. Returns
    how many pairs intersect; the first ``limit`` are written to ``keys[start:]`` as
    min(f, f2) m + max(f, f2) (f, f2 the input indices)."""
    m = order.shape[0]
    n_cells = cells.shape[0]
    a0 = starts[c]
    a1 = m
    if c + 1 < n_cells:
        a1 = starts[c + 1]
    p = cells[c]
    near = neighbour_cells()  # c itself, then its occupied upper neighbours
    needs = neighbour_cells()  # bits of the axes (x 4, y 2, z 1) along which that neighbour is one cell up
    n_near = int(0)
    up = cell_reach[c]
    level = (up >> LEVEL_BIT) & 7  # c's certified block, 2^level cells per axis: its pairs in it are skipped
    whole = level != 0
    if not whole:
        near[0] = c
        needs[0] = 0
        n_near = 1
    for d in range(14, 27):  # the 3 x 3 x 3 neighbourhood numbered 9 (dx + 1) + 3 (dy + 1) + dz + 1
        dx = d / 9 - 1
        dy = (d / 3) % 3 - 1
        dz = d % 3 - 1
        need = int(0)  # the axes along which c's faces must reach up into c2
        down = int(0)  # those along which c2's faces must reach up into c
        if dx == 1:
            need = need | 4
        if dy == 1:
            need = need | 2
        elif dy == -1:
            down = down | 2
        if dz == 1:
            need = need | 1
        elif dz == -1:
            down = down | 1
        if whole:
            if (p[0] >> level == (p[0] + dx) >> level and p[1] >> level == (p[1] + dy) >> level
                    and p[2] >> level == (p[2] + dz) >> level):
                continue
        if (need & up) == need:
            c2 = grid_cell_index(p[0] + dx, p[1] + dy, p[2] + dz, blocks_per_axis, block_used, block_slot, masks,
                                 ranks)
            if c2 >= 0:
                if (down & cell_reach[c2]) == down:
                    near[n_near] = c2
                    needs[n_near] = need
                    n_near += 1
    n = int(0)
    if n_near == 0:
        return n
    for s in range(a0, a1):
        lo = face_lowers[s]
        hi = face_uppers[s]
        f = order[s]
        # face s loaded here, before its candidates: values set inside the loops would be
        # carried through every iteration (Warp's code selects and copies each of them,
        # a 72-byte matrix among them, on every pass of the box screen)
        t, it, cv, nt, na = load_query(points, tris, certified, s)
        reach = reach_bits(hi, p, inv_cell)  # the axes along which the face's grown box reaches the next cell up
        for k in range(n_near):
            if (needs[k] & reach) != needs[k]:
                continue
            c2 = near[k]
            b0 = starts[c2]
            if c2 == c:  # in c itself: the faces after s
                b0 = s + 1
            b1 = m
            if c2 + 1 < n_cells:
                b1 = starts[c2 + 1]
            for s2 in range(b0, b1):
                if boxes_meet(lo, hi, face_lowers[s2], face_uppers[s2]):
                    n = test_candidate(points, tris, order, t, it, nt, na, f, cv, s2, keys, start, n, limit, m)
    return n


@wp.kernel
def grid_count_pairs_kernel(cells: wp.array(dtype=wp.vec3i), starts: wp.array(dtype=wp.int32), blocks_per_axis: int,
                            block_used: wp.array(dtype=wp.int32), block_slot: wp.array(dtype=wp.int32),
                            masks: wp.array(dtype=wp.uint64), ranks: wp.array(dtype=wp.int32), inv_cell: float, points: wp.array(dtype=wp.vec3d),
                            tris: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                            face_lowers: wp.array(dtype=wp.vec3), face_uppers: wp.array(dtype=wp.vec3),
                            certified: wp.array(dtype=wp.int8), reach: wp.array(dtype=wp.int32), first: int,
                            unused: wp.array(dtype=wp.int64), counts: wp.array(dtype=wp.int64)):
    """One thread per occupied cell c = first + tid: how many pairs of its faces with the
    faces after them in it and in its 13 upper neighbours intersect (:func:`grid_walk_cell`,
    writing nothing)."""
    c = wp.tid() + first
    counts[c] = wp.int64(grid_walk_cell(cells, starts, blocks_per_axis, block_used, block_slot, masks, ranks, inv_cell,
                                        points, tris, order, face_lowers, face_uppers, certified, reach, c,
                                        unused, wp.int64(0), 0))


@wp.kernel
def grid_write_pairs_kernel(cells: wp.array(dtype=wp.vec3i), starts: wp.array(dtype=wp.int32), blocks_per_axis: int,
                            block_used: wp.array(dtype=wp.int32), block_slot: wp.array(dtype=wp.int32),
                            masks: wp.array(dtype=wp.uint64), ranks: wp.array(dtype=wp.int32), inv_cell: float, points: wp.array(dtype=wp.vec3d),
                            tris: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
                            face_lowers: wp.array(dtype=wp.vec3), face_uppers: wp.array(dtype=wp.vec3),
                            certified: wp.array(dtype=wp.int8), reach: wp.array(dtype=wp.int32), first: int,
                            counts: wp.array(dtype=wp.int64), offsets: wp.array(dtype=wp.int64),
                            keys: wp.array(dtype=wp.int64)):
    """One thread per occupied cell c = first + tid with ``counts[c] > 0``: the walk of
    :func:`grid_count_pairs_kernel` again, writing its pairs' keys to ``keys[offsets[c]:]``."""
    c = wp.tid() + first
    n = counts[c]
    if n == wp.int64(0):
        return
    grid_walk_cell(cells, starts, blocks_per_axis, block_used, block_slot, masks, ranks, inv_cell, points, tris, order,
                   face_lowers, face_uppers, certified, reach, c, keys, offsets[c], int(n))
