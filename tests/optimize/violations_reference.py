"""The optimiser's local embedding checks as they were written in numpy, pair by pair
(k-d trees of bounding spheres, vectorised predicates): the reference that the Warp
kernel behind :func:`warpmesh.optimize.embedding.face_violations`
(:mod:`warpmesh.kernels.remesh`) is compared with in test_violations_kernel.py."""

import numpy as np

from warpmesh.optimize.embedding import FOLD_COS, NORMAL_COS, REL_TOUCH, ULP_TOUCH, _projectable_fans

_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


def _dot(u, v):
    return np.einsum("...j,...j->...", u, v)


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1), 1e-300)[..., None]


# ----------------------------------------------------------------------------- predicates
def _point_in_triangle(x, a, b, c, n_hat, tol):
    """x (in the plane of a, b, c, within tol) inside the closed triangle grown by tol."""
    inside = np.ones(len(x), bool)
    for e0, e1 in ((a, b), (b, c), (c, a)):
        e = e1 - e0
        d = _dot(np.cross(e, x - e0), n_hat) / np.maximum(np.linalg.norm(e, axis=1), 1e-300)
        inside &= d >= -tol
    return inside


def _segments_meet_2d(p, q, e0, e1, n_hat, tol):
    """Coplanar segments pq and e0e1 (3D points, plane normal n_hat) meet, within tol."""
    def side(a, b, x):  # signed distance of x from the line ab, in the plane
        ab = b - a
        return _dot(np.cross(ab, x - a), n_hat) / np.maximum(np.linalg.norm(ab, axis=1), 1e-300)

    d1, d2 = side(p, q, e0), side(p, q, e1)
    d3, d4 = side(e0, e1, p), side(e0, e1, q)
    apart = ((d1 > tol) & (d2 > tol)) | ((d1 < -tol) & (d2 < -tol))
    apart |= ((d3 > tol) & (d4 > tol)) | ((d3 < -tol) & (d4 < -tol))
    # collinear: the intervals along pq must overlap
    col = (np.abs(d1) <= tol) & (np.abs(d2) <= tol)
    u = q - p
    lu = np.maximum(np.linalg.norm(u, axis=1), 1e-300)
    t0, t1 = _dot(e0 - p, u) / lu, _dot(e1 - p, u) / lu
    disjoint = (np.maximum(t0, t1) < -tol) | (np.minimum(t0, t1) > lu + tol)
    return ~apart & ~(col & disjoint)


def segment_meets_triangle(p, q, a, b, c, tol):
    """Closed segments pq against closed triangles abc, (k, 3) each; ``tol`` (k,) the
    touching distance (touching counts). Degenerate triangles never meet."""
    n = np.cross(b - a, c - a)
    nn = np.linalg.norm(n, axis=1)
    good = nn > 1e-300
    n_hat = n / np.maximum(nn, 1e-300)[:, None]
    dp, dq = _dot(p - a, n_hat), _dot(q - a, n_hat)
    out = np.zeros(len(p), bool)
    apart = ((dp > tol) & (dq > tol)) | ((dp < -tol) & (dq < -tol)) | ~good
    flat = ~apart & (np.abs(dp) <= tol) & (np.abs(dq) <= tol)
    cross = ~apart & ~flat
    if cross.any():
        i = np.flatnonzero(cross)
        den = dp[i] - dq[i]
        t = np.clip(np.where(np.abs(den) > 1e-300, dp[i] / np.where(den == 0, 1.0, den), 0.0), 0.0, 1.0)
        x = p[i] + t[:, None] * (q[i] - p[i])
        out[i] = _point_in_triangle(x, a[i], b[i], c[i], n_hat[i], tol[i])
    if flat.any():
        i = np.flatnonzero(flat)
        pp, qq, aa, bb, cc, nh, tt = p[i], q[i], a[i], b[i], c[i], n_hat[i], tol[i]
        # project onto the plane, then: an end inside, or pq meeting an edge
        pp = pp - _dot(pp - aa, nh)[:, None] * nh
        qq = qq - _dot(qq - aa, nh)[:, None] * nh
        hit = _point_in_triangle(pp, aa, bb, cc, nh, tt) | _point_in_triangle(qq, aa, bb, cc, nh, tt)
        for e0, e1 in ((aa, bb), (bb, cc), (cc, aa)):
            hit |= _segments_meet_2d(pp, qq, e0, e1, nh, tt)
        out[i] = hit
    return out


def _min3(x):
    return np.minimum(np.minimum(x[..., 0], x[..., 1]), x[..., 2])


def _max3(x):
    return np.maximum(np.maximum(x[..., 0], x[..., 1]), x[..., 2])


def _triangles_meet(A, B, tol):
    """Triangles (k, 3, 3) that share no vertex meet within ``tol``: no separating axis
    among the two normals, the nine cross products of their edges (complete when they
    are not coplanar) and the six in-plane edge normals (complete when they are)."""
    ea, eb = A[:, _NEXT] - A, B[:, _NEXT] - B
    na, nb = np.cross(ea[:, 0], ea[:, 1]), np.cross(eb[:, 0], eb[:, 1])
    axes = np.concatenate([na[:, None], nb[:, None], np.cross(ea[:, :, None], eb[:, None, :]).reshape(-1, 9, 3),
                           np.cross(na[:, None], ea), np.cross(nb[:, None], eb)], axis=1)  # (k, 17, 3)
    length = np.sqrt(np.einsum("ijk,ijk->ij", axes, axes))
    scale = np.maximum(_max3(np.einsum("ijk,ijk->ij", ea, ea)), _max3(np.einsum("ijk,ijk->ij", eb, eb)))
    usable = length > 1e-9 * scale[:, None]
    axes /= np.maximum(length, 1e-300)[:, :, None]
    pa, pb = np.matmul(axes, A.transpose(0, 2, 1)), np.matmul(axes, B.transpose(0, 2, 1))
    gap = np.maximum(_min3(pb) - _max3(pa), _min3(pa) - _max3(pb))
    return ~np.any(usable & (gap > tol[:, None]), axis=1)


# ----------------------------------------------------------------------------- neighbours
def _spheres(p, t):
    corners = p[t]
    cen = (corners[:, 0] + corners[:, 1] + corners[:, 2]) / 3.0
    d = corners - cen[:, None]
    rad = np.sqrt(_max3(np.einsum("ijk,ijk->ij", d, d)))
    return corners, cen, rad


def _nearby_faces(p, t, faces, pad):
    """The faces ``faces`` first, then every other face whose bounding sphere may meet
    one of theirs (centroids in the grid cells around theirs, cells as wide as the
    largest two radii)."""
    if 4 * len(faces) > len(t):
        rest = np.ones(len(t), bool)
        rest[faces] = False
        return np.concatenate([faces, np.flatnonzero(rest)])
    _, cen, rad = _spheres(p, t)
    width = float(rad[faces].max() + rad.max()) + pad
    lo = cen.min(axis=0)
    cell = np.floor((cen - lo) / width).astype(np.int64) + 1
    dims = cell.max(axis=0) + 2

    def key(c):
        return (c[..., 0] * dims[1] + c[..., 1]) * dims[2] + c[..., 2]

    offsets = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    around = np.unique(key(cell[faces][:, None, :] + offsets[None]))
    near = np.isin(key(cell), around)
    near[faces] = False
    return np.concatenate([faces, np.flatnonzero(near)])


def _tree(x):
    from scipy.spatial import cKDTree

    return cKDTree(x, balanced_tree=False, compact_nodes=False)


def _near_pairs(cen, rad, new, pad):
    """Unordered pairs (a, b) of faces, a listed in ``new`` (bool per face), whose
    bounding spheres meet; each pair once.

    The faces are sorted into size classes (the radius over twice the median: class 0,
    then one class per doubling), one k-d tree each, so that a few large faces do not
    widen every query.
    """
    med = max(float(np.median(rad)), 1e-300)
    cls = np.clip(np.ceil(np.log2(np.maximum(rad, med) / (2.0 * med))), 0, 30).astype(np.int64)
    groups = {}
    for c in np.unique(cls):
        idx = np.flatnonzero(cls == c)
        groups[int(c)] = (idx, float(rad[idx].max()), new[idx])
    out_a, out_b = [], []
    keys = sorted(groups)
    for x, cx in enumerate(keys):
        ix, rx, nx = groups[cx]
        if nx.sum() > 0.25 * len(ix):  # many new faces: every pair of the class, then filter
            pr = _tree(cen[ix]).query_pairs(2 * rx + pad, output_type="ndarray")
            a, b = ix[pr[:, 0]], ix[pr[:, 1]]
            a, b = a[new[a] | new[b]], b[new[a] | new[b]]
        elif nx.any():
            sub = ix[nx]
            pr = _tree(cen[sub]).sparse_distance_matrix(_tree(cen[ix]), 2 * rx + pad, output_type="ndarray")
            a, b = sub[pr["i"]], ix[pr["j"]]
            a, b = a[(a < b) | ~new[b]], b[(a < b) | ~new[b]]  # a pair of two new faces once
        else:
            a = b = np.zeros(0, np.int64)
        out_a.append(a)
        out_b.append(b)
        for cy in keys[x + 1:]:  # the larger classes
            iy, ry, ny = groups[cy]
            for (i1, n1), (i2, n2) in (((ix, nx), (iy, ny)), ((iy, ny), (ix, nx))):
                if not n1.any():
                    continue
                sub = i1[n1]
                pr = _tree(cen[sub]).sparse_distance_matrix(_tree(cen[i2]), rx + ry + pad, output_type="ndarray")
                a, b = sub[pr["i"]], i2[pr["j"]]
                if i1 is iy:  # a pair of two new faces of the two classes: from the first side only
                    a, b = a[~new[b]], b[~new[b]]
                out_a.append(a)
                out_b.append(b)
    a, b = np.concatenate(out_a), np.concatenate(out_b)
    swap = ~new[a]
    if swap.any():
        a, b = np.where(swap, b, a), np.where(swap, a, b)
    d = cen[a] - cen[b]
    reach = rad[a] + rad[b] + pad
    keep = np.einsum("ij,ij->i", d, d) <= reach * reach
    return a[keep], b[keep]



def _shared_corners(fa, fb):
    """(corner of fa shared with fb (q, 3) bool, same for fb, number shared)."""
    eq = [[fa[:, x] == fb[:, y] for y in range(3)] for x in range(3)]
    sa = np.stack([eq[x][0] | eq[x][1] | eq[x][2] for x in range(3)], axis=1)
    sb = np.stack([eq[0][y] | eq[1][y] | eq[2][y] for y in range(3)], axis=1)
    return sa, sb, sa[:, 0].astype(np.int8) + sa[:, 1] + sa[:, 2]



def _violations(p, t_all, faces, normals, fold_cos, normal_cos, average):
    """(bad flags of ``faces``, the unlisted faces of failing pairs)."""
    bad = np.zeros(len(faces), bool)
    ulp = ULP_TOUCH * max(float(np.abs(p).max()), 1e-300)
    # only the faces near the listed ones take part (renumbered: listed ones first)
    near = _nearby_faces(p, t_all, faces, 2 * ulp)
    t = t_all[near].astype(np.int32) if len(p) < 2**31 else t_all[near]
    faces = np.arange(len(faces))
    corners, cen, rad = _spheres(p, t)
    nrm = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    area2 = np.sqrt(_dot(nrm, nrm))
    lmax = np.sqrt(_max3(np.einsum("ijk,ijk->ij", corners - corners[:, _NEXT], corners - corners[:, _NEXT])))
    degenerate = (area2 <= 1e-14 * lmax**2) | (t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 0] == t[:, 2])
    bad |= degenerate[faces]
    n_hat = nrm / np.maximum(area2, 1e-300)[:, None]
    if normals is not None:
        k = len(faces)
        exact = normals(np.concatenate([cen[faces], corners[faces].reshape(-1, 3)]) if average else cen[faces])
        at_centroid = exact[:k]
        known = _dot(at_centroid, at_centroid) > 0.25  # where the gradient vanishes nothing is known
        bad |= known & (_dot(n_hat[faces], at_centroid) <= normal_cos)
        if average:  # the centroid's and the corners' normals, averaged, must agree too
            mean = _unit(at_centroid + exact[k:].reshape(k, 3, 3).sum(axis=1))
            bad |= (_dot(mean, mean) > 0.25) & (_dot(n_hat[faces], mean) <= normal_cos)
    new = np.zeros(len(t), bool)
    new[faces] = True
    a, b = _near_pairs(cen, rad, new, 2 * ulp)
    live = ~degenerate[a] & ~degenerate[b]
    a, b = a[live], b[live]
    if len(a) == 0:
        return bad, np.zeros(0, np.int64)
    fa, fb = t[a], t[b]
    sa, sb, k = _shared_corners(fa, fb)
    hit = np.zeros(len(a), bool)
    hit[k == 3] = True  # a repeated vertex triple: a duplicate face
    two = np.flatnonzero(k == 2)  # a shared edge: a fold
    hit[two] = _dot(n_hat[a[two]], n_hat[b[two]]) < fold_cos
    tol = REL_TOUCH * np.maximum(lmax[a], lmax[b]) + ulp
    # a shared vertex: the edges opposite it against the other face, unless its fan is flat
    one = np.flatnonzero(k == 1)
    if len(one):
        ca = np.where(sa[one, 0], 0, np.where(sa[one, 1], 1, 2))
        cb = np.where(sb[one, 0], 0, np.where(sb[one, 1], 1, 2))
        shared = fa[one, ca]
        curved = ~_projectable_fans(p, t, shared)[shared]
        test, ca, cb = one[curved], ca[curved], cb[curved]
        if len(test):
            A, B = p[fa[test]], p[fb[test]]
            r = np.arange(len(test))
            tt = tol[test]
            h = np.zeros(len(test), bool)
            for s0, s1, T, nt in ((A[r, _NEXT[ca]], A[r, _PREV[ca]], B, n_hat[b[test]]),
                                  (B[r, _NEXT[cb]], B[r, _PREV[cb]], A, n_hat[a[test]])):
                d0, d1 = _dot(s0 - T[:, 0], nt), _dot(s1 - T[:, 0], nt)
                close = np.flatnonzero(~h & ~(((d0 > tt) & (d1 > tt)) | ((d0 < -tt) & (d1 < -tt))))
                h[close] = segment_meets_triangle(s0[close], s1[close], T[close, 0], T[close, 1], T[close, 2], tt[close])
            hit[test] = h
    # no vertex shared: boxes, then separating axes
    zero = np.flatnonzero(k == 0)
    if len(zero):
        A, B = corners[a[zero]], corners[b[zero]]
        pad = tol[zero][:, None]
        At, Bt = A.transpose(0, 2, 1), B.transpose(0, 2, 1)
        keep = np.all((_min3(At) <= _max3(Bt) + pad) & (_min3(Bt) <= _max3(At) + pad), axis=1)
        zero, A, B = zero[keep], A[keep], B[keep]
        hit[zero] = _triangles_meet(A, B, tol[zero])
    bad[a[hit]] = True
    other = b[hit]
    bad[other[other < len(faces)]] = True
    return bad, np.unique(near[other[other >= len(faces)]])




def reference_violations(points, triangles, faces, normals=None, *, fold_cos=FOLD_COS, normal_cos=NORMAL_COS,
                         average=False):
    """(bad flags of the unique sorted ``faces``, unlisted partner faces), as face_violations."""
    p, t_all = np.asarray(points, np.float64), np.asarray(triangles)
    listed = np.unique(np.asarray(faces, np.int64))
    return _violations(p, t_all, listed, normals, fold_cos, normal_cos, average)
