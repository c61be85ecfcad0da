"""Local embedding checks: the new faces of a batch of local operations against their neighbours.

A local operator of [FG §16.4.3] (split, collapse, flip, relocation) passes the
combinatorial checks (link condition, manifoldness) and still may leave a surface that
is not *embedded*: a new face crossing a face of the other side of a concave crease,
two adjacent faces folded onto each other, a face turned against the surface. This
module decides, for the faces a batch of operations creates, whether they do, looking
only at the faces nearby:

* **inverted**: the face normal against the exact outward normal at the centroid
  (``normals(centroid)``, -grad f of the target; with ``average=True`` also against the
  mean of the normals at the centroid and the corners) by more than ``NORMAL_COS`` allows;
* **folded**: two faces sharing an edge, the surface turning by more than
  ``FOLD_COS`` allows across it (a coplanar fold, which the self-intersection check
  counts as a crossing, is the extreme case);
* **crossing**: any other common point with a face nearby (candidates from the
  bounding spheres of the faces, one k-d tree per size class, then their boxes), with
  the rules of :func:`warpmesh.cells.intersections.find_self_intersections`: faces
  sharing a vertex may meet only there, faces sharing an edge only along it, a
  repeated vertex triple is always a crossing. Pairs sharing one vertex whose fan
  projects one-to-one onto its mean plane (every face positive, the corner angles
  summing to at most a full turn) cannot cross and are not tested.

The predicates run in float64 with a tolerance of a few float32 ulps of the coordinates
(the tape evaluates in float32), so touching counts as crossing: a conservative test.

:func:`apply_verified` applies a batch, checks its new faces in the resulting mesh and
applies it again without the operations whose faces fail, until none does: faces
created by two independent operations are checked against each other, and a failed
operation's old faces stay in place for the others to be checked against.

Examples
--------
>>> import numpy as np
>>> p = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 1], [1.5, 1.5, 0]], float)
>>> face_violations(p, np.array([[0, 1, 2], [3, 4, 5]]), np.array([1])).tolist()
[True]
>>> face_violations(p, np.array([[0, 1, 2], [3, 5, 1]]), np.array([1])).tolist()
[False]
"""

from __future__ import annotations

import numpy as np

from warpmesh.optimize.local_ops import gather, vertex_faces

__all__ = ["FOLD_COS", "NORMAL_COS", "apply_verified", "face_violations", "revert_violations",
           "segment_meets_triangle", "verified_collapse", "verified_flip", "verified_split"]

#: a new face whose unit normal has a dot product with the exact normal at its centroid
#: at or below this is inverted
NORMAL_COS = 0.0
#: two faces sharing an edge fold when their unit normals' dot product is below this
#: (the surface turning by more than 150 degrees across the edge)
FOLD_COS = -np.cos(np.radians(30.0))
#: touching tolerance: this fraction of the longest edge of the pair, plus a few float32
#: ulps of the coordinates
REL_TOUCH = 1.0e-6
ULP_TOUCH = 4.0 * 2.0**-24
#: apply-check-retry rounds of :func:`apply_verified` before giving the batch up
VERIFY_ROUNDS = 6

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


def _projectable_fans(p, t, verts):
    """Which of the vertices ``verts`` (bool per point: True where ``verts`` says and the
    fan in ``t`` is one closed cycle of faces projecting one-to-one onto the plane of
    their mean normal: every face positive, the corner angles summing to one turn). A fan
    cut off by ``t`` fails."""
    n = len(p)
    want = np.zeros(n, bool)
    want[verts] = True
    corner = np.flatnonzero(want[t.ravel()])  # corner c of face f: vertex t[f, c], then the next and previous
    own = t.ravel()[corner].astype(np.int64)
    nxt, prv = t[:, _NEXT].ravel()[corner], t[:, _PREV].ravel()[corner]
    v0, v1, v2 = p[own], p[nxt], p[prv]
    e1, e2 = v1 - v0, v2 - v0
    nrm = np.cross(e1, e2)
    mean = np.stack([np.bincount(own, weights=nrm[:, d], minlength=n) for d in range(3)], axis=1)
    mean = _unit(mean)[own]
    e1 -= _dot(e1, mean)[:, None] * mean
    e2 -= _dot(e2, mean)[:, None] * mean
    s = _dot(np.cross(e1, e2), mean)
    angle = np.arctan2(s, _dot(e1, e2))
    ok = np.ones(n, bool)
    ok[own[s <= 1e-9 * np.sqrt(_dot(e1, e1) * _dot(e2, e2))]] = False
    # a closed fan: the next vertices are the previous ones, each once
    kn, kp = np.sort(own * n + nxt), np.sort(own * n + prv)
    cycle = kn == kp
    cycle[1:] &= kn[1:] != kn[:-1]
    ok[kn[~cycle] // n] = False
    ok[kp[~cycle] // n] = False
    total = np.bincount(own, weights=angle, minlength=n)
    return want & ok & (total <= 2.0 * np.pi + 1e-9)


def _shared_corners(fa, fb):
    """(corner of fa shared with fb (q, 3) bool, same for fb, number shared)."""
    eq = [[fa[:, x] == fb[:, y] for y in range(3)] for x in range(3)]
    sa = np.stack([eq[x][0] | eq[x][1] | eq[x][2] for x in range(3)], axis=1)
    sb = np.stack([eq[0][y] | eq[1][y] | eq[2][y] for y in range(3)], axis=1)
    return sa, sb, sa[:, 0].astype(np.int8) + sa[:, 1] + sa[:, 2]


def face_violations(points, triangles, faces, normals=None, *, fold_cos: float = FOLD_COS,
                    normal_cos: float = NORMAL_COS, average: bool = False, partners: bool = False):
    """Which of the faces ``faces`` are degenerate, inverted, folded or crossing a face nearby.

    Parameters
    ----------
    points : (n, 3) float
    triangles : (m, 3) int
        The mesh after the operations.
    faces : (k,) int
        The faces the operations created or moved (indices into ``triangles``).
    normals : callable, optional
        ``normals(points) -> (q, 3)`` outward unit normals of the exact surface; None
        skips the inversion test.
    fold_cos, normal_cos : float
        The thresholds of the fold and inversion tests (module constants by default).
    average : bool
        Compare with the mean of the normals at the centroid and the corners too, not
        only with the centroid's: for surfaces the faces do not resolve (a voxel
        staircase, whose normals turn within a face).
    partners : bool
        Also return the faces not in ``faces`` that a failing face crosses or folds onto.

    Returns
    -------
    (k,) bool, and with ``partners`` a (j,) int array of face indices
    """
    p, t_all = np.asarray(points, np.float64), np.asarray(triangles)
    listed, inverse = np.unique(np.asarray(faces, np.int64), return_inverse=True)
    if len(listed) == 0:
        return (np.zeros(0, bool), np.zeros(0, np.int64)) if partners else np.zeros(0, bool)
    bad, others = _violations(p, t_all, listed, normals, fold_cos, normal_cos, average)
    return (bad[inverse], others) if partners else bad[inverse]


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


# ----------------------------------------------------------------------------- batches
def apply_verified(s, apply, n_ops: int, normals=None, **check):
    """Apply the operations 0..n_ops-1 to a copy of ``s``, dropping those whose new faces
    fail :func:`face_violations`, and commit the result into ``s``.

    ``apply(trial, ops) -> (faces, owner)`` applies the operations ``ops`` (indices) to
    the copy ``trial`` and returns the faces they created or changed with, for each, the
    position in ``ops`` of the operation that did (a face may be listed once per
    operation). Returns the indices of the operations applied.
    """
    ops = np.arange(n_ops)
    for _ in range(VERIFY_ROUNDS):
        if len(ops) == 0:
            return ops
        trial = s.copy()
        faces, owner = apply(trial, ops)
        bad = face_violations(trial.points, trial.triangles, faces, normals, **check)
        failed = np.zeros(len(ops), bool)
        failed[owner[bad]] = True
        if not failed.any():
            s.assign(trial)
            return ops
        ops = ops[~failed]
    return np.zeros(0, np.int64)


def verified_split(s, topo, chosen, new_points, normals=None, **check) -> np.ndarray:
    """:meth:`Surface.split` of the edges ``chosen`` (no two in one face) at
    ``new_points``, without the splits whose four faces fail the checks; returns the
    positions in ``chosen`` of the splits made (the new vertices are appended in that order)."""
    chosen, new_points = np.asarray(chosen), np.asarray(new_points)
    m0 = len(s.triangles)

    def apply(trial, ops):
        c = chosen[ops]
        trial.split(topo, c, new_points[ops])
        two = np.flatnonzero(topo.face1[c] >= 0)
        k = len(c)
        faces = np.concatenate([topo.face0[c], topo.face1[c[two]], m0 + np.arange(k), m0 + k + np.arange(len(two))])
        return faces, np.concatenate([np.arange(k), two, np.arange(k), two])

    return apply_verified(s, apply, len(chosen), normals, **check)


def verified_flip(s, topo, chosen, normals=None, **check) -> int:
    """:meth:`Surface.flip` of the edges ``chosen``, without the flips whose two faces fail."""
    chosen = np.asarray(chosen)

    def apply(trial, ops):
        c = chosen[ops]
        trial.flip(c, topo)
        k = np.arange(len(c))
        return np.concatenate([topo.face0[c], topo.face1[c]]), np.concatenate([k, k])

    return len(apply_verified(s, apply, len(chosen), normals, **check))


def verified_collapse(s, keep, remove, position, faces_gone, normals=None, **check) -> int:
    """:meth:`Surface.collapse` of ``remove[i]`` into ``keep[i]`` at ``position[i]``
    (independent collapses; ``faces_gone[i]`` the one or two faces of the edge, -1 for
    none), without the collapses whose new faces fail the checks."""
    keep, remove, position = np.asarray(keep), np.asarray(remove), np.asarray(position)
    faces_gone = np.asarray(faces_gone).reshape(len(keep), -1)
    n, m = len(s.points), len(s.triangles)
    ptr, vf = vertex_faces(s.triangles, n)
    moved = np.any(position != s.points[keep], axis=1)

    def apply(trial, ops):
        gone = faces_gone[ops].ravel()
        gone = gone[gone >= 0]
        alive = np.ones(m, bool)
        alive[gone] = False
        index = np.cumsum(alive) - 1
        own_r, f_r = gather(ptr, vf, remove[ops])
        mv = np.flatnonzero(moved[ops])
        own_k, f_k = gather(ptr, vf, keep[ops[mv]])
        own, fac = np.concatenate([own_r, mv[own_k]]), np.concatenate([f_r, f_k])
        live = alive[fac]
        trial.collapse(keep[ops], remove[ops], position[ops], gone)
        return index[fac[live]], own[live]

    return len(apply_verified(s, apply, len(keep), normals, **check))


def revert_violations(old_points, new_points, triangles, normals=None, **check) -> np.ndarray:
    """Undo vertex moves (``new_points`` against ``old_points``, in place) until no face
    around a moved vertex fails :func:`face_violations`: round by round, the moved
    vertices of failing faces and of the faces they cross go back, and the faces around
    them are checked again. Returns ``new_points``."""
    t = np.asarray(triangles)
    moved = np.any(new_points != old_points, axis=1)
    pending = moved[t].any(axis=1)
    while pending.any():
        faces = np.flatnonzero(pending)
        bad, others = face_violations(new_points, t, faces, normals, partners=True, **check)
        verts = np.unique(np.concatenate([t[faces[bad]].ravel(), t[others].ravel()]))
        verts = verts[moved[verts]]
        if len(verts) == 0:  # what fails was there before the moves
            break
        new_points[verts] = old_points[verts]
        moved[verts] = False
        undone = np.zeros(len(moved), bool)
        undone[verts] = True
        pending = undone[t].any(axis=1)
    return new_points
