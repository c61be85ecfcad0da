"""Batched checks of the surface optimiser; the host partner is
:mod:`warpmesh.optimize.embedding` (and :mod:`warpmesh.optimize.local_ops` for the quality).

Every candidate face of a batch of splits, collapses, flips or moves is checked by one
thread against the faces near it (a ``wp.Bvh`` over the faces' boxes, grown by the
touching distance), with the rules of :func:`warpmesh.optimize.embedding.face_violations`:

* a face is **degenerate** when its doubled area is at most 1e-14 x its longest edge
  squared, or it repeats a vertex; degenerate faces take part in no pair;
* two faces whose bounding spheres (centroid, farthest corner) are farther apart than
  ``pad`` never meet;
* sharing three vertices: a duplicate face (a crossing); sharing an edge: a **fold** when
  their unit normals' dot product is below ``fold_cos``; sharing one vertex v: unless v's
  fan projects one-to-one onto a plane (``fan_ok``, decided on the host), the edge of each
  face opposite v must miss the other face; sharing none: boxes grown by the touching
  distance must meet, and no separating axis among the two normals, the nine cross
  products of their edges and the six in-plane edge normals.

The predicates run in float64 and count touching, to within ``tol`` = ``rel`` x the longer
of the two faces' longest edges + ``ulp``, as meeting: a conservative test.
"""

import warp as wp

from warpmesh.kernels.intersect import load_triangle, spread_bits

wp.set_module_options({"enable_backward": False})

#: a face is degenerate when its doubled area is at most this times its longest edge squared
DEGENERATE_AREA = wp.constant(wp.float64(1.0e-14))
#: an axis of the separating-axis test is usable when longer than this times the longest
#: squared edge of the pair
AXIS_FLOOR = wp.constant(wp.float64(1.0e-9))
TINY = wp.constant(wp.float64(1.0e-300))
#: sqrt(3) / 6: Q_K of an equilateral triangle is 1
QUALITY_SCALE = wp.constant(wp.float64(0.28867513459481287))


@wp.func
def longest_edge(t: wp.mat33d) -> wp.float64:
    l0 = wp.length_sq(t[1] - t[0])
    l1 = wp.length_sq(t[2] - t[1])
    l2 = wp.length_sq(t[0] - t[2])
    return wp.sqrt(wp.max(wp.max(l0, l1), l2))


@wp.func
def is_degenerate(t: wp.mat33d, it: wp.vec3i) -> bool:
    if it[0] == it[1] or it[1] == it[2] or it[0] == it[2]:
        return True
    area2 = wp.length(wp.cross(t[1] - t[0], t[2] - t[0]))
    lmax = longest_edge(t)
    return area2 <= DEGENERATE_AREA * lmax * lmax


@wp.func
def unit_normal(t: wp.mat33d) -> wp.vec3d:
    n = wp.cross(t[1] - t[0], t[2] - t[0])
    return n / wp.max(wp.length(n), TINY)


@wp.func
def centroid(t: wp.mat33d) -> wp.vec3d:
    return (t[0] + t[1] + t[2]) / wp.float64(3.0)


@wp.func
def radius(t: wp.mat33d, c: wp.vec3d) -> wp.float64:
    return wp.sqrt(wp.max(wp.max(wp.length_sq(t[0] - c), wp.length_sq(t[1] - c)), wp.length_sq(t[2] - c)))


@wp.func
def edge_side(e0: wp.vec3d, e1: wp.vec3d, x: wp.vec3d, n_hat: wp.vec3d) -> wp.float64:
    """Signed distance of x (in the plane of normal n_hat) from the line e0 e1."""
    e = e1 - e0
    return wp.dot(wp.cross(e, x - e0), n_hat) / wp.max(wp.length(e), TINY)


@wp.func
def point_in_triangle(x: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d, n_hat: wp.vec3d,
                      tol: wp.float64) -> bool:
    """x (in the plane of a, b, c) inside the closed triangle grown by tol."""
    return edge_side(a, b, x, n_hat) >= -tol and edge_side(b, c, x, n_hat) >= -tol and edge_side(
        c, a, x, n_hat) >= -tol


@wp.func
def segments_meet_2d(p: wp.vec3d, q: wp.vec3d, e0: wp.vec3d, e1: wp.vec3d, n_hat: wp.vec3d,
                     tol: wp.float64) -> bool:
    """Coplanar segments pq and e0 e1 (plane normal n_hat) meet, within tol."""
    d1 = edge_side(p, q, e0, n_hat)
    d2 = edge_side(p, q, e1, n_hat)
    d3 = edge_side(e0, e1, p, n_hat)
    d4 = edge_side(e0, e1, q, n_hat)
    if (d1 > tol and d2 > tol) or (d1 < -tol and d2 < -tol):
        return False
    if (d3 > tol and d4 > tol) or (d3 < -tol and d4 < -tol):
        return False
    if wp.abs(d1) <= tol and wp.abs(d2) <= tol:  # collinear: the intervals along pq must overlap
        u = q - p
        lu = wp.max(wp.length(u), TINY)
        t0 = wp.dot(e0 - p, u) / lu
        t1 = wp.dot(e1 - p, u) / lu
        if wp.max(t0, t1) < -tol or wp.min(t0, t1) > lu + tol:
            return False
    return True


@wp.func
def segment_meets_triangle(p: wp.vec3d, q: wp.vec3d, a: wp.vec3d, b: wp.vec3d, c: wp.vec3d,
                           tol: wp.float64) -> bool:
    """The closed segment pq meets the closed triangle abc within tol (touching counts);
    a degenerate triangle never does."""
    n = wp.cross(b - a, c - a)
    nn = wp.length(n)
    if not (nn > TINY):
        return False
    n_hat = n / nn
    dp = wp.dot(p - a, n_hat)
    dq = wp.dot(q - a, n_hat)
    if (dp > tol and dq > tol) or (dp < -tol and dq < -tol):
        return False
    if wp.abs(dp) <= tol and wp.abs(dq) <= tol:  # in the plane: an end inside, or pq meeting an edge
        pp = p - dp * n_hat
        qq = q - dq * n_hat
        if point_in_triangle(pp, a, b, c, n_hat, tol) or point_in_triangle(qq, a, b, c, n_hat, tol):
            return True
        return (segments_meet_2d(pp, qq, a, b, n_hat, tol) or segments_meet_2d(pp, qq, b, c, n_hat, tol)
                or segments_meet_2d(pp, qq, c, a, n_hat, tol))
    den = dp - dq
    s = wp.float64(0.0)
    if wp.abs(den) > TINY:
        s = wp.clamp(dp / den, wp.float64(0.0), wp.float64(1.0))
    return point_in_triangle(p + s * (q - p), a, b, c, n_hat, tol)


@wp.func
def axis_separates(axis: wp.vec3d, A: wp.mat33d, B: wp.mat33d, floor: wp.float64, tol: wp.float64) -> bool:
    """The projections of A and B onto ``axis`` (unusable when not longer than floor) are
    more than tol apart."""
    length = wp.length(axis)
    if not (length > floor):
        return False
    u = axis / wp.max(length, TINY)
    a0 = wp.dot(u, A[0])
    a1 = wp.dot(u, A[1])
    a2 = wp.dot(u, A[2])
    b0 = wp.dot(u, B[0])
    b1 = wp.dot(u, B[1])
    b2 = wp.dot(u, B[2])
    gap = wp.max(wp.min(wp.min(b0, b1), b2) - wp.max(wp.max(a0, a1), a2),
                 wp.min(wp.min(a0, a1), a2) - wp.max(wp.max(b0, b1), b2))
    return gap > tol


@wp.func
def triangles_meet(A: wp.mat33d, B: wp.mat33d, tol: wp.float64) -> bool:
    """Triangles sharing no vertex meet within tol: no separating axis among the two
    normals, the nine cross products of their edges (complete when they are not
    coplanar) and the six in-plane edge normals (complete when they are)."""
    ea0 = A[1] - A[0]
    ea1 = A[2] - A[1]
    ea2 = A[0] - A[2]
    eb0 = B[1] - B[0]
    eb1 = B[2] - B[1]
    eb2 = B[0] - B[2]
    na = wp.cross(ea0, ea1)
    nb = wp.cross(eb0, eb1)
    scale = wp.max(wp.max(wp.max(wp.length_sq(ea0), wp.length_sq(ea1)), wp.length_sq(ea2)),
                   wp.max(wp.max(wp.length_sq(eb0), wp.length_sq(eb1)), wp.length_sq(eb2)))
    floor = AXIS_FLOOR * scale
    if axis_separates(na, A, B, floor, tol) or axis_separates(nb, A, B, floor, tol):
        return False
    for i in range(3):
        ea = ea0
        eb = eb0
        if i == 1:
            ea = ea1
            eb = eb1
        elif i == 2:
            ea = ea2
            eb = eb2
        if axis_separates(wp.cross(na, ea), A, B, floor, tol) or axis_separates(wp.cross(nb, eb), A, B, floor, tol):
            return False
        if (axis_separates(wp.cross(ea, eb0), A, B, floor, tol) or axis_separates(wp.cross(ea, eb1), A, B, floor, tol)
                or axis_separates(wp.cross(ea, eb2), A, B, floor, tol)):
            return False
    return True


@wp.func
def boxes_within(A: wp.mat33d, B: wp.mat33d, tol: wp.float64) -> bool:
    """The boxes of A and B, grown by tol, meet."""
    lo_a = wp.min(wp.min(A[0], A[1]), A[2])
    hi_a = wp.max(wp.max(A[0], A[1]), A[2])
    lo_b = wp.min(wp.min(B[0], B[1]), B[2])
    hi_b = wp.max(wp.max(B[0], B[1]), B[2])
    for k in range(3):
        if lo_a[k] > hi_b[k] + tol or lo_b[k] > hi_a[k] + tol:
            return False
    return True


@wp.func
def shared_pair_meets(A: wp.mat33d, ca: int, B: wp.mat33d, cb: int, tol: wp.float64) -> bool:
    """Faces sharing only the vertex at corner ca of A and cb of B: the edge of each
    opposite that vertex meets the other face."""
    for side in range(2):
        S = A
        T = B
        c = ca
        if side == 1:
            S = B
            T = A
            c = cb
        s0 = S[(c + 1) % 3]
        s1 = S[(c + 2) % 3]
        nt = unit_normal(T)
        d0 = wp.dot(s0 - T[0], nt)
        d1 = wp.dot(s1 - T[0], nt)
        if not ((d0 > tol and d1 > tol) or (d0 < -tol and d1 < -tol)):
            if segment_meets_triangle(s0, s1, T[0], T[1], T[2], tol):
                return True
    return False


@wp.func
def shared_corners(ia: wp.vec3i, ib: wp.vec3i):
    """(number of vertex indices A and B share, the corner of A and of B of the last one)."""
    shared = int(0)
    ca = int(0)
    cb = int(0)
    for x in range(3):
        for y in range(3):
            if ia[x] == ib[y]:
                shared += 1
                ca = x
                cb = y
    return shared, ca, cb


@wp.func
def pair_violates(A: wp.mat33d, center_a: wp.vec3d, radius_a: wp.float64, edge_a: wp.float64, B: wp.mat33d,
                  shared: int, ca: int, cb: int, rel: wp.float64, ulp: wp.float64, pad: wp.float64,
                  fold_cos: wp.float64) -> bool:
    """Two non-degenerate faces sharing ``shared`` vertices (the last at corners ca, cb;
    one shared vertex only when its fan does not project one-to-one) cross, touch or fold
    onto each other (module rules); A's centroid, radius and longest edge are given (the
    same for all its pairs)."""
    center_b = centroid(B)
    reach = radius_a + radius(B, center_b) + pad
    if wp.length_sq(center_a - center_b) > reach * reach:
        return False
    if shared == 3:
        return True
    if shared == 2:
        return wp.dot(unit_normal(A), unit_normal(B)) < fold_cos
    tol = rel * wp.max(edge_a, longest_edge(B)) + ulp
    if shared == 1:
        return shared_pair_meets(A, ca, B, cb, tol)
    if not boxes_within(A, B, tol):
        return False
    return triangles_meet(A, B, tol)


@wp.kernel
def face_boxes_kernel(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32), rel: wp.float64,
                      ulp: wp.float64, pad: wp.float64, origin: wp.vec3d, scale: wp.float64,
                      lowers: wp.array(dtype=wp.vec3), uppers: wp.array(dtype=wp.vec3),
                      degenerate: wp.array(dtype=wp.int32), keys: wp.array(dtype=wp.int32),
                      ids: wp.array(dtype=wp.int32)):
    """One thread per face: its box grown by its touching distance (``rel`` x its longest
    edge + ``ulp``) and ``pad`` (the rounding to float32), and whether it is degenerate
    (two faces within the touching distance of each other have grown boxes that meet);
    the 30-bit Morton code of its centroid, (centroid - origin) x scale in [0, 1024)^3,
    as the sort key, its index as the value."""
    f = wp.tid()
    t, it = load_triangle(points, tris, f)
    u = (centroid(t) - origin) * scale
    x = wp.clamp(int(u[0]), 0, 1023)
    y = wp.clamp(int(u[1]), 0, 1023)
    z = wp.clamp(int(u[2]), 0, 1023)
    keys[f] = (spread_bits(x) << 2) | (spread_bits(y) << 1) | spread_bits(z)
    ids[f] = f
    grow = rel * longest_edge(t) + ulp + pad
    g = wp.vec3d(grow, grow, grow)
    lo = wp.min(wp.min(t[0], t[1]), t[2]) - g
    hi = wp.max(wp.max(t[0], t[1]), t[2]) + g
    lowers[f] = wp.vec3(float(lo[0]), float(lo[1]), float(lo[2]))
    uppers[f] = wp.vec3(float(hi[0]), float(hi[1]), float(hi[2]))
    flag = int(0)
    if is_degenerate(t, it):
        flag = 1
    degenerate[f] = flag


@wp.func
def mix(x: int) -> wp.uint64:
    """A 64-bit mix of a vertex index (splitmix64's finaliser): sums of these over two
    multisets of indices agree when the multisets do (and almost never otherwise)."""
    z = wp.uint64(x) + wp.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> wp.uint64(30))) * wp.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> wp.uint64(27))) * wp.uint64(0x94D049BB133111EB)
    return z ^ (z >> wp.uint64(31))


@wp.kernel
def fan_sums_kernel(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                    want: wp.array(dtype=wp.int32), normal_sum: wp.array(dtype=wp.vec3d),
                    next_sum: wp.array(dtype=wp.uint64), prev_sum: wp.array(dtype=wp.uint64)):
    """One thread per face: for each corner at a wanted vertex v, the face's normal
    vector into v's sum, and the mixes of the next and previous vertices into v's sums
    (a closed fan has the same next and previous vertices)."""
    f = wp.tid()
    t, it = load_triangle(points, tris, f)
    n = wp.cross(t[1] - t[0], t[2] - t[0])
    for c in range(3):
        v = it[c]
        if want[v] != 0:
            wp.atomic_add(normal_sum, v, n)
            wp.atomic_add(next_sum, v, mix(it[(c + 1) % 3]))
            wp.atomic_add(prev_sum, v, mix(it[(c + 2) % 3]))


@wp.kernel
def fan_angles_kernel(points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                      want: wp.array(dtype=wp.int32), normal_sum: wp.array(dtype=wp.vec3d),
                      angle_sum: wp.array(dtype=wp.float64), folded: wp.array(dtype=wp.int32)):
    """One thread per face: for each corner at a wanted vertex v, the corner's angle
    projected onto the plane of v's mean normal into v's sum; 1 into ``folded[v]`` when
    the projected corner is not positive (1e-9 of its edges' lengths)."""
    f = wp.tid()
    t, it = load_triangle(points, tris, f)
    for c in range(3):
        v = it[c]
        if want[v] != 0:
            m = normal_sum[v]
            m = m / wp.max(wp.length(m), TINY)
            e1 = t[(c + 1) % 3] - t[c]
            e2 = t[(c + 2) % 3] - t[c]
            e1 = e1 - wp.dot(e1, m) * m
            e2 = e2 - wp.dot(e2, m) * m
            s = wp.dot(wp.cross(e1, e2), m)
            wp.atomic_add(angle_sum, v, wp.atan2(s, wp.dot(e1, e2)))
            if s <= wp.float64(1.0e-9) * wp.sqrt(wp.length_sq(e1) * wp.length_sq(e2)):
                folded[v] = 1


@wp.kernel
def triangle_quality_kernel(corners: wp.array(dtype=wp.mat33d), out: wp.array(dtype=wp.float64)):
    """One thread per triangle (its corners the rows): Q_K = (sqrt 3 / 6) h_max / rho with
    rho = 2 area / perimeter [FG eq. 16.15]; +inf when twice its area is at most 1e-14 x
    its longest edge squared."""
    k = wp.tid()
    t = corners[k]
    e0 = t[1] - t[0]
    e1 = t[2] - t[1]
    e2 = t[0] - t[2]
    n = wp.cross(e0, -e2)
    l0 = wp.sqrt(e0[0] * e0[0] + e0[1] * e0[1] + e0[2] * e0[2])
    l1 = wp.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
    l2 = wp.sqrt(e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2])
    hmax = wp.max(wp.max(l0, l1), l2)
    area2 = wp.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
    q = wp.float64(wp.inf)
    if area2 > DEGENERATE_AREA * hmax * hmax:
        q = QUALITY_SCALE * hmax * (l0 + l1 + l2) / area2
    out[k] = q


#: faces per leaf box of the BVH: consecutive faces of a spatial order (a compact patch), so
#: the tree has m / GROUP leaves and each leaf's faces are screened by their own boxes
GROUP = 8


@wp.kernel
def group_boxes_kernel(order: wp.array(dtype=wp.int32), lowers: wp.array(dtype=wp.vec3),
                       uppers: wp.array(dtype=wp.vec3), group_lowers: wp.array(dtype=wp.vec3),
                       group_uppers: wp.array(dtype=wp.vec3)):
    """One thread per group g: the box of the faces ``order[s]`` at positions
    [GROUP g, GROUP g + GROUP) of the spatial order."""
    g = wp.tid()
    m = order.shape[0]
    lo = lowers[order[GROUP * g]]
    hi = uppers[order[GROUP * g]]
    for s in range(GROUP * g + 1, wp.min(GROUP * g + GROUP, m)):
        lo = wp.min(lo, lowers[order[s]])
        hi = wp.max(hi, uppers[order[s]])
    group_lowers[g] = lo
    group_uppers[g] = hi


@wp.func
def boxes_meet(lo: wp.vec3, hi: wp.vec3, a: wp.vec3, b: wp.vec3) -> bool:
    return a[0] <= hi[0] and a[1] <= hi[1] and a[2] <= hi[2] and lo[0] <= b[0] and lo[1] <= b[1] and lo[2] <= b[2]


@wp.kernel
def face_violations_kernel(bvh: wp.uint64, points: wp.array(dtype=wp.vec3d), tris: wp.array(dtype=wp.int32),
                           order: wp.array(dtype=wp.int32), faces: wp.array(dtype=wp.int32), listed: wp.array(dtype=wp.int32),
                           degenerate: wp.array(dtype=wp.int32), fan_ok: wp.array(dtype=wp.int32),
                           lowers: wp.array(dtype=wp.vec3), uppers: wp.array(dtype=wp.vec3),
                           rel: wp.float64, ulp: wp.float64, pad: wp.float64, fold_cos: wp.float64, first: int,
                           bad: wp.array(dtype=wp.int32), partner: wp.array(dtype=wp.int32)):
    """One thread per listed face i = first + tid (``faces[i]``): 1 into ``bad[i]`` when it
    is degenerate or violates (:func:`pair_violates`) with a face g whose grown box
    (:func:`face_boxes_kernel`) meets its own, g among the faces of the BVH's leaf groups
    (``order``, :func:`group_boxes_kernel`) that the box meets; then 1 into ``bad[listed[g]]`` too, or ``partner[g]`` when g is not
    listed (``listed[g]`` = -1). A pair of two listed faces is tested by the thread of the
    first. Every write stores 1: threads may race on it."""
    i = wp.tid() + first
    f = faces[i]
    if degenerate[f] != 0:
        bad[i] = 1
        return
    A, ia = load_triangle(points, tris, f)
    center_a = centroid(A)
    radius_a = radius(A, center_a)
    edge_a = longest_edge(A)
    lo = lowers[f]
    hi = uppers[f]
    m = order.shape[0]
    query = wp.bvh_query_aabb(bvh, lo, hi)
    group = int(0)
    while wp.bvh_query_next(query, group):
        for s in range(GROUP * group, wp.min(GROUP * group + GROUP, m)):
            g = order[s]
            if not boxes_meet(lo, hi, lowers[g], uppers[g]):  # most of a group's faces: first, cheapest
                continue
            j = listed[g]
            if j <= i and j >= 0:  # itself, or a pair of listed faces tested by the other's thread
                continue
            ib = wp.vec3i(tris[3 * g], tris[3 * g + 1], tris[3 * g + 2])
            shared, ca, cb = shared_corners(ia, ib)
            if shared == 1 and fan_ok[ia[ca]] != 0:  # a fan that projects one-to-one: no crossing
                continue
            if degenerate[g] == 0:
                B, ib = load_triangle(points, tris, g)
                if pair_violates(A, center_a, radius_a, edge_a, B, shared, ca, cb, rel, ulp, pad, fold_cos):
                    bad[i] = 1
                    if j >= 0:
                        bad[j] = 1
                    else:
                        partner[g] = 1
