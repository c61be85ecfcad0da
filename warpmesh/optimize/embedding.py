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
* **crossing**: any other common point with a face nearby (candidates from a BVH over
  the faces' boxes, grown by the touching distance, then their bounding spheres), with
  the rules of :func:`warpmesh.cells.intersections.find_self_intersections`: faces
  sharing a vertex may meet only there, faces sharing an edge only along it, a
  repeated vertex triple is always a crossing. Pairs sharing one vertex whose fan
  projects one-to-one onto its mean plane (every face positive, the corner angles
  summing to at most a full turn) cannot cross and are not tested.

The predicates run in float64 with a tolerance of a few float32 ulps of the coordinates
(the tape evaluates in float32), so touching counts as crossing: a conservative test.
They run in Warp, one thread per checked face (:mod:`warpmesh.kernels.remesh`); the
inversion test, which evaluates the target, and the fans run here.

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
import warp as wp

from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh.kernels import remesh as KR
from warpmesh.optimize.local_ops import gather, vertex_faces

__all__ = ["FOLD_COS", "NORMAL_COS", "apply_verified", "face_violations", "revert_violations",
           "verified_collapse", "verified_flip", "verified_split"]

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
#: the BVH's float32 boxes are grown by this fraction of the largest coordinate (rounding)
_BOX_PAD = 4.0 * 2.0**-24
#: checked faces per worker thread below which a CPU launch is not split
_MIN_FACES_PER_WORKER = 1 << 12
#: apply-check-retry rounds of :func:`apply_verified` before giving the batch up
VERIFY_ROUNDS = 6

_NEXT = np.array([1, 2, 0])
_PREV = np.array([2, 0, 1])


def _dot(u, v):
    return np.einsum("...j,...j->...", u, v)


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1), 1e-300)[..., None]


# ----------------------------------------------------------------------------- fans
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


def _fans_kernel(points, tris, verts, n, device):
    """:func:`_projectable_fans` in Warp: (n,) int32, 1 at the vertices ``verts`` whose
    fan is closed (the same next and previous vertices, compared by sums of 64-bit
    mixes), every projected corner positive and the angles summing to at most a turn."""
    want = np.zeros(n, np.int32)
    want[np.asarray(verts).ravel()] = 1
    want_w = wp.array(want, dtype=wp.int32, device=device)
    m = tris.shape[0] // 3
    normal_sum = wp.zeros(n, dtype=wp.vec3d, device=device)
    next_sum = wp.zeros(n, dtype=wp.uint64, device=device)
    prev_sum = wp.zeros(n, dtype=wp.uint64, device=device)
    angle_sum = wp.zeros(n, dtype=wp.float64, device=device)
    folded = wp.zeros(n, dtype=wp.int32, device=device)
    wp.launch(KR.fan_sums_kernel, dim=m, inputs=[points, tris, want_w], outputs=[normal_sum, next_sum, prev_sum],
              device=device)
    wp.launch(KR.fan_angles_kernel, dim=m, inputs=[points, tris, want_w, normal_sum], outputs=[angle_sum, folded],
              device=device)
    ok = (want != 0) & (folded.numpy() == 0) & (next_sum.numpy() == prev_sum.numpy())  # sync point
    ok &= angle_sum.numpy() <= 2.0 * np.pi + 1e-9
    return ok.astype(np.int32)


def _violations(p, t_all, faces, normals, fold_cos, normal_cos, average):
    """(bad flags of ``faces`` (unique), the unlisted faces of failing pairs).

    The inversion test runs here (it evaluates the target); the pair tests run in
    :func:`warpmesh.kernels.remesh.face_violations_kernel`, one thread per listed face
    against the faces of its BVH query."""
    m, k = len(t_all), len(faces)
    bad = np.zeros(k, bool)
    ulp = ULP_TOUCH * max(float(np.abs(p).max()), 1e-300)
    tri = t_all[faces]
    if normals is not None:
        corners = p[tri]
        n_hat = _unit(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
        cen = corners.mean(axis=1)
        exact = normals(np.concatenate([cen, corners.reshape(-1, 3)]) if average else cen)
        at_centroid = exact[:k]
        known = _dot(at_centroid, at_centroid) > 0.25  # where the gradient vanishes nothing is known
        bad |= known & (_dot(n_hat, at_centroid) <= normal_cos)
        if average:  # the centroid's and the corners' normals, averaged, must agree too
            mean = _unit(at_centroid + exact[k:].reshape(k, 3, 3).sum(axis=1))
            bad |= (_dot(mean, mean) > 0.25) & (_dot(n_hat, mean) <= normal_cos)
    listed = np.full(m, -1, np.int32)
    listed[faces] = np.arange(k, dtype=np.int32)
    device = "cpu"  # the optimiser's arrays live on the host
    points = wp.array(np.ascontiguousarray(p, np.float64), dtype=wp.vec3d, device=device)
    tris = wp.array(np.ascontiguousarray(t_all, np.int32).ravel(), dtype=wp.int32, device=device)
    # the fans of the listed faces' vertices (a pair sharing one vertex shares one of these)
    fan_ok = _fans_kernel(points, tris, tri, len(p), device)
    lowers = wp.empty(m, dtype=wp.vec3, device=device)
    uppers = wp.empty(m, dtype=wp.vec3, device=device)
    degenerate = wp.empty(m, dtype=wp.int32, device=device)
    keys = wp.empty(2 * m, dtype=wp.int32, device=device)  # the radix sort's scratch: 2m
    ids = wp.empty(2 * m, dtype=wp.int32, device=device)
    lo, hi = p.min(axis=0), p.max(axis=0)
    wp.launch(KR.face_boxes_kernel, dim=m,
              inputs=[points, tris, REL_TOUCH, ulp, _BOX_PAD * ulp / ULP_TOUCH, wp.vec3d(*lo),
                      1023.999 / max(float((hi - lo).max()), 1e-300)],
              outputs=[lowers, uppers, degenerate, keys, ids], device=device)
    wp.utils.radix_sort_pairs(keys, ids, m)  # the faces in Morton order: leaf groups are compact patches
    order = ids[:m]
    n_groups = (m + KR.GROUP - 1) // KR.GROUP
    group_lowers = wp.empty(n_groups, dtype=wp.vec3, device=device)
    group_uppers = wp.empty(n_groups, dtype=wp.vec3, device=device)
    wp.launch(KR.group_boxes_kernel, dim=n_groups, inputs=[order, lowers, uppers],
              outputs=[group_lowers, group_uppers], device=device)
    bvh = wp.Bvh(group_lowers, group_uppers)
    flags = wp.zeros(k, dtype=wp.int32, device=device)
    partner = wp.zeros(m, dtype=wp.int32, device=device)
    walk = [bvh.id, points, tris, order, wp.array(faces.astype(np.int32), dtype=wp.int32, device=device),
            wp.array(listed, dtype=wp.int32, device=device), degenerate,
            wp.array(fan_ok, dtype=wp.int32, device=device), lowers, uppers, REL_TOUCH, ulp, 2.0 * ulp, fold_cos]
    wp.load_module(KR, device=device)  # compiled/loaded once here, not by two worker threads at once
    run_parallel([lambda a=a, b=b: wp.launch(KR.face_violations_kernel, dim=b - a, inputs=[*walk, a],
                                              outputs=[flags, partner], device=device)
                  for a, b in parallel_ranges(k, device, _MIN_FACES_PER_WORKER)])
    bad |= flags.numpy() != 0  # sync point
    return bad, np.flatnonzero(partner.numpy())


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
