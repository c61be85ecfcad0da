"""Simplification of a multi-material surface: fewer triangles, the same labels, junctions on their curves.

:func:`simplify_labels` decimates a shared surface (``mesh_surface(volume, labels=...,
interfaces="shared")``, smoothed or not) by *half-edge collapses*: a vertex goes into
a neighbour, which does not move, so every remaining vertex keeps its position and the
surface never leaves the input's vertices. Which collapses are allowed follows the
classification of :func:`warpmesh.optimize.label_smoothing.classify_edges`:

* a vertex inside one interface (no feature edge) goes into any neighbour;
* a vertex on a junction curve (or a cap rim, an open boundary) goes only into one of
  its two neighbours along that curve, so a curve keeps a subset of its vertices, in
  order: a junction never leaves its curve, and every remaining vertex separates the
  labels it separated;
* a fixed vertex (a curve's end, a corner, 4 labels or more) never goes.

A collapse u -> v is made when the *link condition* holds (u and v have as many
common neighbours as triangles on the edge uv: 2 inside an interface, 3 or more along
a junction, so no edge or triangle is duplicated and each label's boundary stays
closed and consistently oriented), and its triangles pass, in the mesh after the batch,
the checks: no triangle turns by more than ``MAX_TURN`` degrees or degenerates, none
gets a Q_K above ``Q_LIMIT`` (6) unless it was worse before (the result's worst Q_K is
at most the input's or 6, whichever is larger), every
new triangle's centroid and edge midpoints stay within ``tolerance`` of the input
surface (the reference, :class:`warpmesh.frep.projection.MeshTarget`), no triangle
crosses or touches another (:func:`warpmesh.optimize.embedding.face_violations`) and no
two triangles sharing an edge fold onto each other (:func:`warpmesh.optimize.
label_smoothing.wing_cos`). Batches of collapses with disjoint stars (shortest edges
first) are made until the triangle count reaches ``fraction`` of the input's or no
collapse passes.

Remeshing towards a size with splits, flips and relocation as well (the ``optimize`` of
[FG §16.4.3]) is :func:`warpmesh.optimize.label_remesh.optimize_labels`, which makes its
collapses with :func:`collapse_round` (``shorter``, ``longest``, ``q_limit``);
:func:`warpmesh.optimize.remesh.optimize` hands shared surfaces to it.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> vol = np.zeros((14, 14, 14), dtype=np.uint8)
>>> vol[3:11, 3:11, 3:7] = 1; vol[3:11, 3:11, 7:11] = 2
>>> raw = wm.mesh_surface(vol, labels="all", interfaces="shared", smoothing=8)
>>> fewer = simplify_labels(raw, fraction=0.5)
>>> bool(fewer.n_cells <= 0.6 * raw.n_cells), fewer.info["simplify"]["rounds"] > 0
(True, True)
"""

from __future__ import annotations

import time

import numpy as np

from warpmesh._util.progress import Progress
from warpmesh.optimize.embedding import FOLD_COS, face_violations
from warpmesh.optimize.label_smoothing import GRID_INFO, box_sides, classify_edges, vertex_cubes, wing_cos, wing_pairs
from warpmesh.optimize.local_ops import quality_of, select_independent

__all__ = ["MAX_TURN", "collapse_round", "simplify_labels"]

#: largest turn (degrees) of a triangle's normal in a collapse
MAX_TURN = 60.0
#: collapse batches (each a maximal set of collapses with disjoint stars) before giving up
MAX_ROUNDS = 60
#: check-and-retry rounds per batch
RETRIES = 8
#: a collapse may not make a face worse than this, unless the face was worse already (so the
#: result's worst Q_K is at most max(Q_LIMIT, the input's), as :func:`warpmesh.simplify`'s:
#: the same value as its ``SIMPLIFY_Q``)
Q_LIMIT = 6.0


def simplify_labels(mesh, fraction: float = 0.5, *, tolerance: float | None = None, progress=False):
    """Decimate a multi-material surface by half-edge collapses (module docstring).

    Parameters
    ----------
    mesh : Mesh
        A shared surface: triangles with ``cell_refs["triangle"]`` (lower label) and
        ``cell_data["label_above"]`` (higher label).
    fraction : float
        The triangle count to reach, as a fraction of the input's, in (0, 1].
    tolerance : float, optional
        Largest distance of a new triangle's centroid and edge midpoints from the input
        surface; default half the smallest grid spacing (``mesh.info["grid"]``), else a
        quarter of the mean edge length.
    progress : bool or callable
        A bar over the triangles to remove (tqdm, shown once the call has taken a second),
        or ``progress(done, total)`` after each round of collapses (the end counts as done).

    Returns
    -------
    Mesh
        The remaining vertices (at their input positions) and triangles, with their
        labels; ``info["simplify"]`` holds ``rounds``, ``collapses``, ``rejected``,
        ``tolerance``, ``triangles`` (before, after) and ``time``.

    Raises
    ------
    ValueError
        ``mesh`` without the two label arrays, ``fraction`` or ``tolerance`` out of range.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((12, 12, 12), dtype=np.uint8); vol[2:10, 2:10, 2:10] = 1
    >>> m = simplify_labels(wm.mesh_surface(vol, labels="all", interfaces="shared"), 0.3)
    >>> m.stats()["watertight"], bool(m.n_cells < 0.4 * 6 * 8 * 8 * 2)
    (True, True)
    """
    from warpmesh.frep.projection import MeshTarget
    from warpmesh.surface.multilabel import LABEL_ABOVE, shared_labels

    t_start = time.perf_counter()
    if isinstance(fraction, (bool, np.bool_)) or not isinstance(fraction, (int, float, np.floating)) \
            or not 0.0 < float(fraction) <= 1.0:
        raise ValueError(f"expected 'fraction' in (0, 1], got {fraction!r}")
    refs, above = shared_labels(mesh)
    p = np.asarray(mesh.points, np.float64)
    t = np.asarray(mesh.cells["triangle"], np.int64).copy()
    lower, upper = np.asarray(refs).copy(), np.asarray(above).copy()
    grid = mesh.info.get(GRID_INFO)
    bits = None
    if grid is not None and grid.get("shape") is not None:
        bits = box_sides(vertex_cubes(p, grid["origin"], grid["spacing"]), grid["shape"])
    if tolerance is None:
        if grid is not None:
            tolerance = 0.5 * float(np.min(grid["spacing"]))
        else:
            e = p[t[:, [1, 2, 0]]] - p[t]
            tolerance = 0.25 * float(np.linalg.norm(e, axis=2).mean())
    if isinstance(tolerance, (bool, np.bool_)) or not isinstance(tolerance, (int, float, np.floating)) \
            or not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"expected a positive 'tolerance', got {tolerance!r}")
    reference = MeshTarget(p, t)
    m0, goal = len(t), float(fraction) * len(t)
    counts = {"rounds": 0, "collapses": 0, "rejected": 0}
    refused = np.zeros(0, np.int64)  # u * n + v of the collapses that failed a check: not tried again
    bar = Progress(progress, max(int(m0 - goal), 0), "warpmesh simplify (labels)", "triangle")
    for _ in range(MAX_ROUNDS):
        if len(t) <= goal:
            break
        done, refused = collapse_round(p, t, lower, upper, bits, reference, float(tolerance), counts,
                                       room=int((len(t) - goal) // 2) + 1, refused=refused, q_limit=Q_LIMIT)
        if done is None:
            break
        bar.update(min(len(t) - len(done[0]), bar.total - bar.done))
        t, lower, upper = done
        counts["rounds"] += 1
    bar.finish()
    used = np.unique(t)
    index = np.full(len(p), -1, np.int64)
    index[used] = np.arange(len(used))
    info = {**mesh.info, "simplify": {**counts, "tolerance": float(tolerance), "triangles": (m0, len(t)),
                                      "time": time.perf_counter() - t_start}}
    data = {LABEL_ABOVE: {"triangle": upper}}
    return type(mesh)(p[used], {"triangle": index[t]}, cell_refs={"triangle": lower}, cell_data=data, info=info)


def collapse_round(p, t, lower, upper, bits, reference, tol, counts, room, refused, *, shorter=None,
                   longest=None, q_limit=None, pinned=None, only=None):
    """One batch of independent half-edge collapses u -> v that pass the checks (module
    docstring), not among the ``refused`` ones (keys u * n + v).

    Parameters
    ----------
    p : (n, 3) float
    t : (m, 3) int
    lower, upper : (m,) int
        The triangles' two labels.
    bits : (n,) int or None
        :func:`warpmesh.optimize.label_smoothing.box_sides` of the vertices (caps), or None.
    reference : MeshTarget
        The surface the new faces must stay within ``tol`` of.
    counts : dict
        ``collapses`` and ``rejected`` are incremented here.
    room : int
        At most this many collapses.
    refused : (r,) int64
        Keys u * n + v not to try.
    shorter : (n,) float, optional
        Only edges shorter than ``shorter`` at both ends collapse (the remeshing of
        :mod:`warpmesh.optimize.label_remesh`); by default any edge.
    longest : (n,) float, optional
        A new edge may not be longer than ``longest`` at its ends, unless the edge it
        replaces (u x for v x) was at least as long.
    q_limit : float, optional
        A new face's Q_K may not exceed ``max(q_limit, its Q_K before)``.
    pinned : (n,) bool, optional
        Vertices that never go, whatever their class.
    only : (k,) int64, optional
        Keys u * n + v of the only collapses to consider (those the classes allow), e.g.
        the edges of the worst triangles (:func:`warpmesh.optimize.label_remesh.
        optimize_labels`' rescue of the slivers along junction curves).

    Returns
    -------
    ((triangles, lower, upper) or None when no collapse passes, refused keys with this
    batch's failures added)

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep.projection import MeshTarget
    >>> vol = np.zeros((8, 8, 8), np.uint8); vol[2:6, 2:6, 2:6] = 1
    >>> m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    >>> t, lo, up = m.triangles, m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"]
    >>> counts = {"collapses": 0, "rejected": 0}
    >>> done, _ = collapse_round(m.points, t, lo, up, None, MeshTarget(m.points, t), 0.5, counts, 10,
    ...                          np.zeros(0, np.int64))
    >>> len(done[0]) < len(t), counts["collapses"] > 0
    (True, True)
    """
    n = len(p)
    a, b, feature, kind = classify_edges(t, lower, upper, n, bits)
    u, v, along = np.concatenate([a, b]), np.concatenate([b, a]), np.concatenate([feature, feature])
    ok = ((kind[u] == 2) & ~along) | ((kind[u] == 1) & along)
    if pinned is not None:
        ok &= ~pinned[u]
    if only is not None:
        ok &= np.isin(u * n + v, only)
    if shorter is not None:
        ok &= np.linalg.norm(p[u] - p[v], axis=1) < np.minimum(shorter[u], shorter[v])
    u, v = u[ok], v[ok]
    fresh = ~np.isin(u * n + v, refused)
    u, v = u[fresh], v[fresh]
    if len(u) == 0:
        return None, refused
    # link condition: as many common neighbours as triangles on the edge
    nb_u, nb_v = np.concatenate([a, b]), np.concatenate([b, a])  # every directed edge
    order = np.argsort(nb_u, kind="stable")
    nb_u, nb_v = nb_u[order], nb_v[order]
    ptr = np.concatenate([[0], np.cumsum(np.bincount(nb_u, minlength=n))])
    key_edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    ek, on_edge = np.unique(key_edges[:, 0] * n + key_edges[:, 1], return_counts=True)
    lo, hi = np.minimum(u, v), np.maximum(u, v)
    faces_on = on_edge[np.searchsorted(ek, lo * n + hi)]
    common = _common_neighbours(ptr, nb_v, u, v, n)
    link = common == faces_on
    u, v = u[link], v[link]
    if len(u) == 0:
        return None, refused
    length = np.linalg.norm(p[u] - p[v], axis=1)
    # a collapse claims u and its neighbours: winners have disjoint stars
    size = ptr[u + 1] - ptr[u] + 1
    cand = np.repeat(np.arange(len(u)), size)
    offs = np.arange(len(cand)) - np.repeat(np.cumsum(size) - size, size)  # 0: u itself, then its neighbours
    element = np.where(offs == 0, np.repeat(u, size),
                       nb_v[np.minimum(np.repeat(ptr[u], size) + offs - 1, len(nb_v) - 1)])
    chosen = select_independent(len(u), length, element, cand, rounds=8)
    if len(chosen) > room:
        chosen = chosen[np.argsort(length[chosen], kind="stable")[:room]]
    for _ in range(RETRIES):
        if len(chosen) == 0:
            break
        trial, faces, owner, keep = _apply(t, u[chosen], v[chosen], n)
        failed = _failing(p, t, trial, faces, owner, keep, reference, tol, len(chosen), longest, q_limit)
        if not failed.any():
            counts["collapses"] += len(chosen)
            return (trial, lower[keep], upper[keep]), refused
        counts["rejected"] += int(failed.sum())
        refused = np.union1d(refused, u[chosen[failed]] * n + v[chosen[failed]])
        chosen = chosen[~failed]
    return ((t, lower, upper) if len(refused) else None), refused


def _common_neighbours(ptr, nbrs, u, v, n):
    """How many neighbours u[k] and v[k] share (CSR adjacency ``ptr``, ``nbrs``)."""
    deg_u, deg_v = ptr[u + 1] - ptr[u], ptr[v + 1] - ptr[v]
    k = np.arange(len(u))
    idx_u = np.repeat(ptr[u], deg_u) + np.arange(deg_u.sum()) - np.repeat(np.cumsum(deg_u) - deg_u, deg_u)
    idx_v = np.repeat(ptr[v], deg_v) + np.arange(deg_v.sum()) - np.repeat(np.cumsum(deg_v) - deg_v, deg_v)
    pairs = np.concatenate([np.repeat(k, deg_u) * n + nbrs[idx_u], np.repeat(k, deg_v) * n + nbrs[idx_v]])
    values, c = np.unique(pairs, return_counts=True)
    return np.bincount(values[c == 2] // n, minlength=len(u))


def _apply(t, u, v, n):
    """The triangles after the collapses u[k] -> v[k] (disjoint stars): the faces on an
    edge uv go, u becomes v elsewhere. Returns (triangles, indices of the changed faces in
    them, the collapse of each, the kept input faces)."""
    target = np.arange(n)
    target[u] = v
    which = np.full(n, -1)
    which[u] = np.arange(len(u))
    has_u = which[t]  # (m, 3): the collapse whose u is at that corner, or -1
    k = has_u.max(axis=1)
    moved = target[t]
    gone = (k >= 0) & ((moved[:, 0] == moved[:, 1]) | (moved[:, 1] == moved[:, 2]) | (moved[:, 0] == moved[:, 2]))
    keep = np.flatnonzero(~gone)
    trial = moved[keep]
    changed = np.flatnonzero(k[keep] >= 0)
    return trial, changed, k[keep][changed], keep


def _failing(p, t_old, trial, faces, owner, keep, reference, tol, n_ops, longest=None, q_limit=None):
    """Which collapses fail a check (module docstring), as a (n_ops,) bool array."""
    failed = np.zeros(n_ops, bool)
    new, old = p[trial[faces]], p[t_old[keep[faces]]]
    if longest is not None:
        tf = trial[faces]
        # an edge longer than the limit is refused unless it replaces one at least as long (the
        # edge u x of a needle's collapse u -> v: without this, a needle among long edges stays)
        limit = np.maximum(np.minimum(longest[tf], longest[tf[:, [1, 2, 0]]]),
                           np.linalg.norm(old[:, [1, 2, 0]] - old, axis=2))
        too_long = np.linalg.norm(new[:, [1, 2, 0]] - new, axis=2) > limit
        failed[owner[too_long.any(axis=1)]] = True
    if q_limit is not None:
        failed[owner[quality_of(new) > np.maximum(q_limit, quality_of(old))]] = True
    n_new = np.cross(new[:, 1] - new[:, 0], new[:, 2] - new[:, 0])
    n_old = np.cross(old[:, 1] - old[:, 0], old[:, 2] - old[:, 0])
    len_new, len_old = np.linalg.norm(n_new, axis=1), np.linalg.norm(n_old, axis=1)
    turned = np.einsum("ij,ij->i", n_new, n_old) <= np.cos(np.radians(MAX_TURN)) * len_new * len_old
    edges = np.linalg.norm(new[:, [1, 2, 0]] - new, axis=2).max(axis=1)
    flat = len_new <= 1e-9 * edges ** 2
    failed[owner[turned | flat]] = True
    samples = np.concatenate([new.mean(axis=1), 0.5 * (new + new[:, [1, 2, 0]]).reshape(-1, 3)])
    far = reference.distance(samples) > tol
    far_face = far[:len(faces)] | far[len(faces):].reshape(-1, 3).any(axis=1)
    failed[owner[far_face]] = True
    bad, _ = face_violations(p, trial, faces, fold_cos=-2.0, partners=True)  # crossings: orientation-free
    failed[owner[bad]] = True
    # folds across the edges of the changed faces, whatever the two faces' orientations
    pairs = wing_pairs(trial, faces)
    if len(pairs):
        folded = wing_cos(p, trial, pairs) > -FOLD_COS
        listed = np.full(len(trial), -1)
        listed[faces] = owner
        for col in (0, 1):
            o = listed[pairs[folded, col]]
            failed[o[o >= 0]] = True
    return failed
