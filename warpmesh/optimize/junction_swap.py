"""Edge swaps on a multi-material surface: interface edges flip, junction curves keep theirs.

On a shared surface (``mesh_surface(volume, labels=..., interfaces="shared")``) an edge
may carry three triangles or more (a junction curve where three labels meet) and every
triangle carries two labels. :func:`swap_pass` flips an edge ab of the triangles
(a, b, c) and (b, a, d) to the edge cd, giving (a, d, c) and (d, b, c), when:

* ab is an **interface edge**: exactly two triangles, of the same label pair (and the same
  face of the box for a cap), ab in opposite directions in them (one orientation), which
  is what :func:`warpmesh.optimize.label_smoothing.classify_edges` calls a non-feature
  edge. Junction edges (three triangles or more, or a change of label pair) are never
  removed nor created: the junction curves keep their edges and every vertex keeps its
  class, so each label's boundary stays closed and oriented;
* the two old triangles are near-coplanar (their unit normals turn by at most
  ``MAX_TURN``; ``RESCUE_TURN`` when the pair's worse Q_K is above ``RESCUE_Q``), as are
  the two new ones, and each new normal is within ``MAX_TURN`` of the old pair's
  area-weighted normal (the rule of the single-material flips,
  :meth:`warpmesh.optimize.local_ops.Surface.flip_candidates_ok`);
* cd is not an edge already (no duplicate edge, no duplicate triangle);
* the worse Q_K of the pair drops (by ``MIN_GAIN`` relative) and stays at most ``q_cap``;
* the midpoint of cd lies within ``tolerance`` of the reference surface (``distance``);
* in the mesh after the batch, no new triangle crosses or touches another
  (:func:`warpmesh.optimize.embedding.face_violations`, the rules of
  :func:`warpmesh.cells.intersections.find_self_intersections`) and none folds onto a
  triangle sharing an edge with it (:func:`warpmesh.optimize.label_smoothing.wing_cos`).

Why a pass of several rounds, and why vertex-disjoint batches. The flips of one batch
share no vertex, so a new triangle of one flip never shares an edge with one of another
flip: a flip that fails the checks in a batch fails them alone too (bar a crossing
between two new triangles, rare, refused the same), and is refused for the rest of the
pass instead of being chosen again. The candidates that cannot pass the geometric tests
(turn, gain, tolerance) are dropped *before* the batch is chosen, so they never block a
neighbour. The flip pass of :mod:`warpmesh.optimize.label_remesh` before this module chose
its batch first (by gain, two flips not sharing a triangle) and tested afterwards: on a
crop of pyvista's frog 441 flips were chosen, 435 failed (323 of them turning by more
than 45 degrees), and the same batch was chosen again on every call, so a sliver of Q_K
18.9 whose flip passes every check alone (new worst 1.68) was never flipped; on the
whole frog the last sliver of Q_K 1066 stayed so (its flip passes every check on the
smoothed input).

A cap whose large angle faces a **junction** edge cannot be flipped (the edge must stay):
:func:`snap_pass` moves its apex, an interface vertex, onto that edge instead (the split
of the junction edge at the apex's foot followed by the collapse of the apex into it), so
the curve keeps its place and gains a vertex. A cap whose apex is itself a curve vertex
between two curve edges goes by a collapse along the curve
(:func:`warpmesh.optimize.label_remesh.optimize_labels`' rescue collapses).

What is left, and why: on the frog crops and the 40^3 blobs of the tests, the worst
triangle after ``optimize`` is a cap of Q_K 18.9 at a junction of four triangles per edge
(a label touching itself diagonally across a voxel edge), apex a curve vertex between two
fixed ones: its flip folds the new triangle to 26-28 degrees from a triangle of the
other pair around the junction edge, the collapses of the apex to 22-28 degrees (the
fold limit is 30, :data:`warpmesh.optimize.embedding.FOLD_COS`). Moving a fixed vertex
would be needed, which the optimiser does not do. On the whole frog (``optimize``, 2
iterations) the worst goes from 1066 to 13.0 (the module docstring of
:mod:`warpmesh.optimize.label_remesh` has the run).

Example
-------
>>> import numpy as np, warpmesh as wm
>>> vol = np.zeros((10, 10, 10), np.uint8); vol[2:8, 2:8, 2:5] = 1; vol[2:8, 2:8, 5:8] = 2
>>> m = wm.mesh_surface(vol, labels="all", interfaces="shared", smoothing=8)
>>> out = swap_edges(m)
>>> s = out.info["swap"]
>>> bool(s["after"]["q_worst"] <= s["before"]["q_worst"]), s["flips"] >= 0
(True, True)
"""

from __future__ import annotations

import time

import numpy as np

from warpmesh.optimize.embedding import FOLD_COS, face_violations
from warpmesh.optimize.label_smoothing import GRID_INFO, box_sides, classify_edges, vertex_cubes, wing_cos, \
    wing_pairs
from warpmesh.optimize.local_ops import gather, quality_of, select_independent, vertex_faces

__all__ = ["MAX_TURN", "MIN_GAIN", "RESCUE_Q", "RESCUE_TURN", "ROUNDS", "snap_pass", "swap_edges", "swap_pass"]

#: largest turn (degrees) between the two old triangles, the two new ones, and a new one
#: and the old pair's area-weighted normal
MAX_TURN = 45.0
#: a pair whose worse Q_K is above this may flip across a bend of up to ``RESCUE_TURN``
#: degrees between its two old triangles (a sliver's normal tilts with its apex); the new
#: pair and the tolerance still hold it, as the rescue flips of :mod:`warpmesh.optimize.remesh`
RESCUE_Q = 3.0
#: largest turn (degrees) between the two old triangles of a pair worse than ``RESCUE_Q``
RESCUE_TURN = 100.0
#: a flip must lower the worse Q_K of its pair by this fraction at least
MIN_GAIN = 1.0e-3
#: batches of flips per pass (a pass stops earlier when a batch flips nothing)
ROUNDS = 6


def swap_edges(mesh, *, tolerance: float | None = None, rounds: int = ROUNDS):
    """Flip the interface edges of a multi-material surface that improve its triangles
    (module docstring), then snap the caps against junction edges (:func:`snap_pass`).

    Parameters
    ----------
    mesh : Mesh
        A shared surface: triangles with ``cell_refs["triangle"]`` (lower label) and
        ``cell_data["label_above"]["triangle"]`` (higher label).
    tolerance : float, optional
        Largest distance of a new edge's midpoint from the input surface; default half
        the smallest grid spacing (``mesh.info["grid"]``), else a quarter of the mean edge
        length.
    rounds : int
        Batches of flips, 1 or more.

    Returns
    -------
    Mesh
        The same points (a snapped vertex moved onto its junction edge), the new triangles
        and their labels; ``info["swap"]`` holds ``flips``, ``snaps``, ``refused``
        (operations failing the checks), ``rounds`` (flip batches that flipped), ``before``
        and ``after`` (``q_worst``, ``q_mean``) and ``time``.

    Raises
    ------
    ValueError
        ``mesh`` without the two label arrays, ``tolerance`` or ``rounds`` out of range.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> p = np.array([[0, 0, 0], [2, 0, 0], [1, 0.05, 0], [1, -1.5, 0]], float)
    >>> m = wm.Mesh(p, {"triangle": [[0, 1, 2], [1, 0, 3]]}, cell_refs={"triangle": [0, 0]},
    ...             cell_data={"label_above": {"triangle": [1, 1]}})
    >>> swap_edges(m, tolerance=1.0).triangles.tolist()  # the sliver's long edge 0-1 goes
    [[0, 3, 2], [3, 1, 2]]
    """
    from warpmesh.frep.projection import MeshTarget
    from warpmesh.surface.multilabel import LABEL_ABOVE, shared_labels

    t_start = time.perf_counter()
    if isinstance(rounds, (bool, np.bool_)) or not isinstance(rounds, (int, np.integer)) or rounds < 1:
        raise ValueError(f"expected a positive integer for 'rounds', got {rounds!r}")
    refs, above = shared_labels(mesh)
    p = np.asarray(mesh.points, np.float64)
    if p.shape[1:] != (3,):
        raise ValueError(f"expected 3D points in 'mesh', got shape {p.shape}")
    t = np.asarray(mesh.cells["triangle"], np.int64)
    grid = mesh.info.get(GRID_INFO)
    bits = None
    if grid is not None and grid.get("shape") is not None:
        bits = box_sides(vertex_cubes(p, grid["origin"], grid["spacing"]), grid["shape"])
    if tolerance is None:
        tolerance = 0.5 * float(np.min(grid["spacing"])) if grid is not None else \
            0.25 * float(np.linalg.norm(p[t[:, [1, 2, 0]]] - p[t], axis=2).mean()) if len(t) else 1.0
    if isinstance(tolerance, (bool, np.bool_)) or not isinstance(tolerance, (int, float, np.floating)) \
            or not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"expected a positive 'tolerance', got {tolerance!r}")
    q0 = quality_of(p[t]) if len(t) else np.zeros(0)
    counts = {"flips": 0, "snaps": 0, "refused": 0, "rounds": 0}
    lower, upper = np.asarray(refs), np.asarray(above)
    if len(t):
        distance = MeshTarget(p, t).distance
        t = swap_pass(p, t, lower, upper, side_bits=bits, distance=distance, tolerance=float(tolerance),
                      rounds=int(rounds), counts=counts)
        for _ in range(int(rounds)):
            done = counts["snaps"]
            p, t, lower, upper = snap_pass(p, t, lower, upper, side_bits=bits, distance=distance,
                                           tolerance=float(tolerance), counts=counts)
            if counts["snaps"] == done:
                break
    q1 = quality_of(p[t]) if len(t) else np.zeros(0)

    def summary(q):
        return {"q_worst": float(q.max()) if len(q) else 0.0, "q_mean": float(q.mean()) if len(q) else 0.0}

    info = {**mesh.info, "swap": {**counts, "before": summary(q0), "after": summary(q1),
                                  "tolerance": float(tolerance), "time": time.perf_counter() - t_start}}
    return type(mesh)(p, {"triangle": t}, cell_refs={"triangle": lower},
                      cell_data={LABEL_ABOVE: {"triangle": upper}}, info=info)


def swap_pass(p, t, lower, upper, *, side_bits=None, distance=None, tolerance: float = np.inf,
              q_cap: float = np.inf, rounds: int = ROUNDS, counts: dict | None = None):
    """Up to ``rounds`` batches of vertex-disjoint interface-edge flips (module docstring).

    Parameters
    ----------
    p : (n, 3) float
    t : (m, 3) int
    lower, upper : (m,) int
        The triangles' two labels (flips keep them: both faces of a flip carry the same pair).
    side_bits : (n,) int, optional
        :func:`warpmesh.optimize.label_smoothing.box_sides` of the vertices (caps).
    distance : callable, optional
        ``distance(points) -> (k,)`` to the reference surface; None skips the tolerance test.
    tolerance : float
        Largest ``distance`` of a new edge's midpoint.
    q_cap : float
        No new triangle's Q_K above this.
    rounds : int
    counts : dict, optional
        ``flips``, ``refused`` and ``rounds`` are incremented here.

    Returns
    -------
    (m, 3) int64
        The triangles after the flips (a new array; face i keeps its labels).

    Example
    -------
    >>> import numpy as np
    >>> p = np.array([[0, 0, 0], [2, 0, 0], [1, 0.05, 0], [1, -1.5, 0]], float)
    >>> swap_pass(p, np.array([[0, 1, 2], [1, 0, 3]]), np.zeros(2, int), np.ones(2, int)).tolist()
    [[0, 3, 2], [3, 1, 2]]
    """
    p, t, lower, upper = _checked(p, t, lower, upper)
    if isinstance(rounds, (bool, np.bool_)) or not isinstance(rounds, (int, np.integer)) or rounds < 1:
        raise ValueError(f"expected a positive integer for 'rounds', got {rounds!r}")
    n = len(p)
    counts = {} if counts is None else counts
    for key in ("flips", "refused", "rounds"):
        counts.setdefault(key, 0)
    if len(t) == 0:
        return t
    bits = np.zeros(n, np.int64) if side_bits is None else np.asarray(side_bits, np.int64)
    # flips never make nor remove a feature edge: the classification holds for the whole pass
    ea, eb, feature, _ = classify_edges(t, lower, upper, n, bits)
    feature_keys = ea[feature] * n + eb[feature]  # sorted (classify_edges sorts its edges)
    refused = np.zeros(0, np.int64)  # a * n + b of the edges whose flip failed a check
    for _ in range(int(rounds)):
        cand = _candidates(p, t, feature_keys, bits, n, q_cap)
        f1, f2, a, b, c, d, q_old = cand
        keep = ~np.isin(np.minimum(a, b) * n + np.maximum(a, b), refused)
        if distance is not None and np.isfinite(tolerance) and keep.any():
            far = np.zeros(len(a), bool)
            far[keep] = np.asarray(distance(0.5 * (p[c[keep]] + p[d[keep]]))) > tolerance
            keep &= ~far
        f1, f2, a, b, c, d, q_old = (x[keep] for x in cand)
        if len(f1) == 0:
            break
        # the worst pairs first; winners share no vertex
        k = len(f1)
        chosen = select_independent(k, -q_old, np.concatenate([a, b, c, d]), np.tile(np.arange(k), 4), rounds=16)
        done = 0
        while len(chosen):
            t2 = t.copy()
            t2[f1[chosen]] = np.column_stack([a[chosen], d[chosen], c[chosen]])
            t2[f2[chosen]] = np.column_stack([d[chosen], b[chosen], c[chosen]])
            failed = _embedding_failures(p, t2, f1[chosen], f2[chosen])
            if not failed.any():
                t, done = t2, len(chosen)
                break
            bad = chosen[failed]
            refused = np.union1d(refused, np.minimum(a[bad], b[bad]) * n + np.maximum(a[bad], b[bad]))
            counts["refused"] += int(failed.sum())
            chosen = chosen[~failed]
        if done == 0:
            continue  # every winner failed and is refused: the next batch chooses among the others
        counts["flips"] += done
        counts["rounds"] += 1
    return t


def _checked(p, t, lower, upper):
    """The arrays as float64 (n, 3) points, a new int64 (m, 3) triangles and (m,) labels."""
    p = np.asarray(p, np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"expected (n, 3) points for 'p', got shape {p.shape}")
    t = np.array(t, np.int64)
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"expected (m, 3) triangles for 't', got shape {t.shape}")
    if len(t) and (t.min() < 0 or t.max() >= len(p)):
        raise ValueError(f"expected indices in [0, {len(p)}) in 't', got {t.min()}..{t.max()}")
    lower, upper = np.asarray(lower), np.asarray(upper)
    for name, a in (("lower", lower), ("upper", upper)):
        if a.shape != (len(t),):
            raise ValueError(f"expected {len(t)} labels in {name!r} (one per triangle), got shape {a.shape}")
    return p, t, lower, upper


def _candidates(p, t, feature_keys, bits, n, q_cap):
    """The interface edges whose flip passes the tests that need no other flip: returns
    (face with ab, face with ba, a, b, c, d, worse Q_K of the old pair)."""
    e = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    key = e[:, 0] * n + e[:, 1]
    order = np.argsort(key, kind="stable")
    skey = key[order]
    starts = np.flatnonzero(np.concatenate([[True], skey[1:] != skey[:-1]]))
    edge_keys = skey[starts]
    feature = np.isin(edge_keys, feature_keys, assume_unique=True)
    two = np.diff(np.append(starts, len(skey))) == 2
    inner = starts[~feature & two]  # exactly two faces of one interface
    fe1, fe2 = order[inner], order[inner + 1]
    f1, f2 = fe1 // 3, fe2 // 3
    j1, j2 = fe1 % 3, fe2 % 3
    a, b, c = t[f1, j1], t[f1, (j1 + 1) % 3], t[f1, (j1 + 2) % 3]
    d = t[f2].sum(axis=1) - a - b
    ok = (t[f2, j2] == b) & (t[f2, (j2 + 1) % 3] == a) & (c != d)  # f1 holds a -> b, f2 b -> a
    lo, hi = np.minimum(c, d), np.maximum(c, d)
    pos = np.minimum(np.searchsorted(skey, lo * n + hi), len(skey) - 1)
    ok &= skey[pos] != lo * n + hi  # cd is not an edge yet
    # the new faces lie on the same face of the box as the old ones (caps keep their class)
    common = bits[a] & bits[b] & bits[c]
    ok &= ((bits[a] & bits[d] & bits[c]) == common) & ((bits[d] & bits[b] & bits[c]) == common)
    f1, f2, a, b, c, d = (x[ok] for x in (f1, f2, a, b, c, d))
    q_old = np.maximum(quality_of(p[t[f1]]), quality_of(p[t[f2]]))
    n1, n2 = np.column_stack([a, d, c]), np.column_stack([d, b, c])
    q_new = np.maximum(quality_of(p[n1]), quality_of(p[n2]))
    ok = (q_new < q_old * (1.0 - MIN_GAIN)) & (q_new <= q_cap)  # first: most edges stop here
    f1, f2, a, b, c, d, q_old, n1, n2 = (x[ok] for x in (f1, f2, a, b, c, d, q_old, n1, n2))
    cos = np.cos(np.radians(MAX_TURN))
    raw0, raw1 = _normals(p, t[f1]), _normals(p, t[f2])
    u0, u1, v0, v1 = _unit(raw0), _unit(raw1), _unit(_normals(p, n1)), _unit(_normals(p, n2))
    avg = _unit(raw0 + raw1)
    bend = np.where(q_old > RESCUE_Q, np.cos(np.radians(RESCUE_TURN)), cos)
    ok = (_dot(u0, u1) > bend) & (_dot(v0, v1) > cos) & (_dot(v0, avg) > cos) & (_dot(v1, avg) > cos)
    return tuple(x[ok] for x in (f1, f2, a, b, c, d, q_old))


def _embedding_failures(p, t2, f1, f2):
    """Which flips (new faces f1[k], f2[k] in ``t2``) cross or touch a face, degenerate, or
    fold onto a face sharing an edge."""
    k = len(f1)
    return _faces_fail(p, t2, np.concatenate([f1, f2]), np.tile(np.arange(k), 2), k)


def _faces_fail(p, t2, faces, owner, k):
    """Which of k operations (owner[i] made face faces[i] of ``t2``) have a face that crosses
    or touches a face, degenerates, or folds onto a face sharing an edge with it."""
    bad, _ = face_violations(p, t2, faces, fold_cos=-2.0, partners=True)  # crossings: orientation-free
    failed = np.zeros(k, bool)
    failed[owner[bad]] = True
    # folds: only the faces around the operations' vertices can share an edge with a new face
    mark = np.zeros(len(p), bool)
    mark[t2[faces].ravel()] = True
    near = np.flatnonzero(mark[t2].any(axis=1))
    pairs = wing_pairs(t2[near])
    if len(pairs):
        listed = np.full(len(t2), -1)
        listed[faces] = owner
        pairs = pairs.copy()
        pairs[:, :2] = near[pairs[:, :2]]
        folded = wing_cos(p, t2, pairs) > -FOLD_COS
        for col in (0, 1):
            o = listed[pairs[folded, col]]
            failed[o[o >= 0]] = True
    return failed


def _normals(p, t):
    c = p[t]
    return np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]


def _dot(u, v):
    return np.einsum("ij,ij->i", u, v)


def snap_pass(p, t, lower, upper, *, side_bits=None, project=None, distance=None, tolerance: float = np.inf,
              q_cap: float = np.inf, counts: dict | None = None, pinned=None):
    """One batch of junction snaps: a cap whose large angle sits at an interface vertex c
    opposite a feature edge ab (a junction curve) loses it by c going onto the curve.

    The flip cannot remove such a triangle (ab must keep its edge). Instead c moves to the
    foot w of its perpendicular on ab (``project(w, a, b)`` then places it on the curve,
    e.g. the input's), the triangle (a, b, c) goes, and every other triangle (a, b, x) on
    ab is split at c into (a, c, x) and (c, b, x), keeping its orientation and labels. The
    curve's polyline gains c on its own segment ab (with the default placement the curve
    does not move at all) and ca, cb carry as many triangles as ab did: the split of ab at
    w followed by the collapse of c into w. Allowed when c is an interface vertex (on no
    feature edge), off the box's caps, none of the x is a neighbour of c (no duplicate
    edge), and, in the mesh after the batch, the worst Q_K of the triangles around c and
    on ab drops (by ``MIN_GAIN`` relative, to at most ``q_cap``), no triangle turns by more
    than ``MAX_TURN`` or degenerates, their centroids lie within ``tolerance`` of the
    reference (``distance``), and no triangle crosses, touches or folds onto another.
    Snaps of one batch share no vertex of their triangles.

    Parameters
    ----------
    p : (n, 3) float
    t : (m, 3) int
    lower, upper : (m,) int
    side_bits : (n,) int, optional
        :func:`warpmesh.optimize.label_smoothing.box_sides` of the vertices.
    project : callable, optional
        ``project(points, a, b) -> (points, found)``: the points on the curve of the edges
        (a[k], b[k]); a snap whose point is not found is not made. Default: the foot on ab.
    distance : callable, optional
        ``distance(points) -> (k,)`` to the reference surface.
    tolerance, q_cap : float
    counts : dict, optional
        ``snaps`` and ``refused`` are incremented here.
    pinned : (n,) bool, optional
        Vertices that never move.

    Returns
    -------
    (points, triangles, lower, upper)
        New arrays; the vertex count is unchanged (c keeps its index), each snap removes
        one triangle and adds as many as ab had minus one.

    Example
    -------
    >>> import numpy as np
    >>> # a fan of three labels round the junction edge 0-1; vertex 2 (label pair (1, 2))
    >>> # nearly on it: the cap (0, 1, 2) goes, 2 lands on the junction edge
    >>> p = np.array([[0, 0, 0], [2, 0, 0], [1, 0.02, 0], [1, 1.5, 0], [1, -1, 1], [1, -1, -1]], float)
    >>> t = np.array([[0, 1, 2], [2, 1, 3], [0, 2, 3], [1, 0, 4], [0, 1, 5]])
    >>> lower, upper = np.array([1, 1, 1, 1, 2]), np.array([2, 2, 2, 3, 3])
    >>> q, tt, lo, up = snap_pass(p, t, lower, upper)
    >>> q[2].tolist(), len(tt), sorted(tt[lo == 1].tolist())
    ([1.0, 0.0, 0.0], 6, [[0, 2, 3], [1, 2, 4], [2, 0, 4], [2, 1, 3]])
    """
    p, t, lower, upper = _checked(p, t, lower, upper)
    n = len(p)
    counts = {} if counts is None else counts
    for key in ("snaps", "refused"):
        counts.setdefault(key, 0)
    bits = np.zeros(n, np.int64) if side_bits is None else np.asarray(side_bits, np.int64)
    unchanged = (p, t, lower, upper)
    if len(t) == 0:
        return unchanged
    q = quality_of(p[t])
    bad = np.flatnonzero(q > RESCUE_Q)
    if len(bad) == 0:
        return unchanged
    _, _, feature, kind = classify_edges(t, lower, upper, n, bits)
    # the largest angle of each bad face: its corner j, the opposite edge (a, b) = (j+1, j+2)
    c3 = p[t[bad]]
    ang = np.stack([_dot(_unit(c3[:, (j + 1) % 3] - c3[:, j]), _unit(c3[:, (j + 2) % 3] - c3[:, j]))
                    for j in range(3)], axis=1)
    j = np.argmin(ang, axis=1)  # the smallest cosine
    r = np.arange(len(bad))
    c, a, b = t[bad, j], t[bad, (j + 1) % 3], t[bad, (j + 2) % 3]
    # the edges of the mesh, sorted, as classify_edges has them
    e = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    key = e[:, 0] * n + e[:, 1]
    order = np.argsort(key, kind="stable")
    skey = key[order]
    starts = np.flatnonzero(np.concatenate([[True], skey[1:] != skey[:-1]]))
    ends = np.append(starts[1:], len(skey))
    eab = np.searchsorted(skey[starts], np.minimum(a, b) * n + np.maximum(a, b))
    if pinned is not None:
        kind = np.where(pinned, 0, kind)
    ok = (kind[c] == 2) & feature[eab] & ((bits[a] | bits[b] | bits[c]) == 0) & (ang[r, j] < 0.0)
    f, a, b, c, eab = bad[ok], a[ok], b[ok], c[ok], eab[ok]
    if len(f) == 0:
        return unchanged
    s = np.clip(_dot(p[c] - p[a], p[b] - p[a]) / np.maximum(_dot(p[b] - p[a], p[b] - p[a]), 1e-300), 0.0, 1.0)
    w = p[a] + s[:, None] * (p[b] - p[a])
    found = np.ones(len(f), bool)
    if project is not None:
        w, found = project(w, a, b)
        w, found = np.asarray(w, np.float64), np.asarray(found, bool)
    # the other faces on ab: (op, face)
    size = ends[eab] - starts[eab]
    op_g = np.repeat(np.arange(len(f)), size)
    g = order[np.repeat(starts[eab], size) + np.arange(size.sum()) - np.repeat(np.cumsum(size) - size, size)] // 3
    other = g != f[op_g]
    op_g, g = op_g[other], g[other]
    x = t[g].sum(axis=1) - a[op_g] - b[op_g]
    # no x among c's neighbours (the new edges cx are new)
    vptr, vfaces = vertex_faces(t, n)
    op_c, fc = gather(vptr, vfaces, c)
    ring = np.unique(np.repeat(op_c, 3) * n + t[fc].ravel())
    found &= np.bincount(op_g[np.isin(op_g * n + x, ring)], minlength=len(f)) == 0
    # winners share no vertex of the faces they change (so no edge of their new faces)
    verts = np.concatenate([np.repeat(op_c, 3), op_g]), np.concatenate([t[fc].ravel(), x])
    chosen = select_independent(len(f), -q[f], verts[1], verts[0], rounds=16, active=found)
    old_q = np.zeros(len(f))
    np.maximum.at(old_q, op_c, q[fc])
    np.maximum.at(old_q, op_g, q[g])
    cos = np.cos(np.radians(MAX_TURN))
    while len(chosen):
        pick = np.zeros(len(f), bool)
        pick[chosen] = True
        p2 = p.copy()
        p2[c[chosen]] = w[chosen]
        t2 = t.copy()
        sel = pick[op_g]
        gg, xx, oo = g[sel], x[sel], op_g[sel]
        # face gg holds a -> b or b -> a: keep (start, c, x) in place, add (c, end, x)
        fwd = np.any((t[gg] == a[oo][:, None]) & (t[gg][:, [1, 2, 0]] == b[oo][:, None]), axis=1)
        u, v = np.where(fwd, a[oo], b[oo]), np.where(fwd, b[oo], a[oo])
        t2[gg] = np.column_stack([u, c[oo], xx])
        keep = np.ones(len(t), bool)
        keep[f[chosen]] = False
        t2 = np.concatenate([t2[keep], np.column_stack([c[oo], v, xx])])
        lo2 = np.concatenate([lower[keep], lower[gg]])
        up2 = np.concatenate([upper[keep], upper[gg]])
        parent = np.concatenate([np.flatnonzero(keep), gg])
        owner_v = np.full(n, -1)
        owner_v[c[chosen]] = chosen
        owner = owner_v[t2].max(axis=1)  # every changed face holds its snap's c
        faces = np.flatnonzero(owner >= 0)
        fo = owner[faces]
        failed = np.zeros(len(f), bool)
        q_new = quality_of(p2[t2[faces]])
        worst = np.zeros(len(f))
        np.maximum.at(worst, fo, q_new)
        failed |= ~((worst < old_q * (1.0 - MIN_GAIN)) & (worst <= q_cap))
        n_new, n_old = _normals(p2, t2[faces]), _normals(p, t[parent[faces]])
        flat = np.linalg.norm(n_new, axis=1) <= 1e-12 * np.einsum("ij,ij->i", n_old, n_old) ** 0.5 + 1e-300
        turned = _dot(_unit(n_new), _unit(n_old)) <= cos
        failed[fo[turned | flat]] = True
        if distance is not None and np.isfinite(tolerance):
            failed[fo[np.asarray(distance(p2[t2[faces]].mean(axis=1))) > tolerance]] = True
        failed[chosen] |= _faces_fail(p2, t2, faces, fo, len(f))[chosen]
        failed &= pick
        if not failed.any():
            counts["snaps"] += len(chosen)
            return p2, t2, lo2, up2
        counts["refused"] += int(failed.sum())
        chosen = chosen[~failed[chosen]]
    return unchanged
