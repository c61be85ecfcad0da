"""Remeshing of a multi-material surface towards a size: junctions on their curves, no fold.

:func:`optimize_labels` is the ``optimize`` of [FG §16.4.3] (split, collapse, flip,
relocate, in batches) for a shared surface (``mesh_surface(volume, labels=...,
interfaces="shared")``, smoothed or not), where an edge may carry three triangles or
more (a junction curve where three labels meet) and every triangle carries two labels.
The reference surface is the input (closest points, :class:`warpmesh.frep.projection.
MeshTarget`); the vertex classes are those of :func:`warpmesh.optimize.label_smoothing.
classify_edges`:

* an **interface** vertex (no feature edge) moves tangentially (to the area-weighted
  centroid of its ball, in its tangent plane) and is projected back onto the input
  triangles of *its* interface (the same label pair), never onto a neighbouring one;
* a **curve** vertex (on a junction curve, a cap rim) moves only along its curve: to the
  midpoint of its two neighbours along it, projected onto the input's feature edges
  with the same labels around them (the same curve), so it never leaves that curve;
* a **fixed** vertex (a curve's end, a corner, 4 labels or more) never moves.

The operators, each iteration:

1. **split** every edge longer than ``SPLIT_ABOVE`` x size (the longest first, no two in
   one triangle): an interface edge at its midpoint projected onto its interface, a
   feature edge at its midpoint projected onto its curve; every triangle around the edge
   is split (two on an interface edge, three or more along a junction), each half
   keeping the triangle's orientation and both labels;
2. **collapse** edges shorter than ``COLLAPSE_BELOW`` x size by the half-edge collapses of
   :func:`warpmesh.optimize.multimaterial.collapse_round` (the link condition; interface
   vertices into any neighbour, curve vertices only along their curve, fixed vertices
   never), no new edge above ``SPLIT_ABOVE`` x size (unless the edge it replaces was as
   long: a needle among long edges), no new triangle above ``COLLAPSE_Q``
   (unless it was already worse), the new faces within ``tolerance`` of the input;
3. **flip** an edge inside one interface (exactly two triangles, the same label pair,
   opposite directions: never a feature edge) when it lowers the worse Q_K of the two,
   the new edge is not an edge already and its midpoint lies within ``tolerance`` of
   the input: :func:`warpmesh.optimize.junction_swap.swap_pass` (vertex-disjoint batches,
   the candidates that cannot pass left out before a batch is chosen); then
   **snap** the apex of a cap (Q_K above ``RESCUE_Q``) whose large angle faces a junction
   edge onto that edge, on the input's curve (:func:`warpmesh.optimize.junction_swap.
   snap_pass`), and **rescue** the triangles still above ``RESCUE_Q`` by collapses of their
   own edges whatever their lengths (``RESCUE_TIERS``) (a cap whose apex is a curve vertex between two curve
   edges goes by the collapse of the apex along its curve, which no flip may do);
4. **relocate** the interface and curve vertices as above; a move that makes a triangle
   worse than ``max(SMOOTH_Q, its Q_K before)`` is undone.

Every batch is checked after the fact and its failing operations undone: no triangle
crosses or touches another (:func:`warpmesh.optimize.embedding.face_violations`), no two
triangles sharing an edge fold onto each other (:func:`warpmesh.optimize.label_smoothing.
wing_cos`, the fold angle of the embedding checks), no triangle turns by more than
``MAX_TURN`` degrees or degenerates. Each label's boundary therefore stays closed and
oriented. The result is never worse than the input: if the last iteration's worst Q_K is
above the input's, the best iteration that was not is returned, else the input (with a
warning); ``info["optimize"]`` says which (``kept``).

Measured on pyvista's frog (25 labels, ``smoothing=16``, 1.58 M triangles, default size
0.998, 2 iterations, 2 cores shared with other jobs, load 1-4): 1.85 M triangles; mean
Q_K 1.55 -> 1.154, mean ``|log(length / size)|`` 0.20 -> 0.13, worst Q_K 1066 -> 13.0,
smallest angle 0.062 -> 2.63 degrees, triangles above Q_K 10: 2176 -> 17, no crossing, every
label's boundary closed and oriented; 630 CPU s. Before the junction-aware operations
(the flips of :mod:`warpmesh.optimize.junction_swap`, the snaps, the rescue collapses) a
run gave worst Q_K 1066 (a sliver whose flip passes every check on the input, never
chosen again after its batch failed), 80 triangles above 10, mean 1.149, in 509 CPU s
(load 4-6). The worst left (Q_K 12-13) are needles whose short edge (0.06) joins two
vertices of a junction curve, their collapses refused.

What is not here: a size field from the curvature (``size="curvature"``), the polishing
passes of :func:`warpmesh.optimize.remesh.optimize` (best-position moves, needle
collapses), moving fixed vertices (a curve end stays where the input has it), and so the
repair of a sliver whose flip and collapses all fold at a junction of four triangles per
edge (Q_K 18.9 on crops of the frog and the 40^3 blobs of the tests).

Example
-------
>>> import numpy as np, warpmesh as wm
>>> vol = np.zeros((14, 14, 14), dtype=np.uint8)
>>> vol[3:11, 3:11, 3:7] = 1; vol[3:11, 3:11, 7:11] = 2
>>> smooth = wm.mesh_surface(vol, labels="all", interfaces="shared", smoothing=16)
>>> opt = optimize_labels(smooth, size=1.5, iterations=3)
>>> info = opt.info["optimize"]
>>> bool(info["after"]["q_worst"] < info["before"]["q_worst"]), info["kept"]
(True, 'final')
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from warpmesh._util.progress import Progress
from warpmesh.optimize.embedding import FOLD_COS, face_violations
from warpmesh.optimize.junction_swap import RESCUE_Q, snap_pass, swap_pass
from warpmesh.optimize.label_smoothing import GRID_INFO, box_sides, classify_edges, vertex_cubes, wing_cos, \
    wing_pairs
from warpmesh.optimize.local_ops import quality_of, select_independent
from warpmesh.optimize.multimaterial import collapse_round

__all__ = ["COLLAPSE_BELOW", "COLLAPSE_Q", "MAX_TURN", "SMOOTH_Q", "SPLIT_ABOVE", "optimize_labels"]

#: edges longer than this times the size are split [FG §16.4.3]
SPLIT_ABOVE = 4.0 / 3.0
#: edges shorter than this times the size are collapsed
COLLAPSE_BELOW = 4.0 / 5.0
#: a collapse may not make a triangle worse than this Q_K (unless it already was)
COLLAPSE_Q = 3.0
#: a relocation may not make a triangle worse than this Q_K (unless it already was)
SMOOTH_Q = 2.0
#: largest turn (degrees) of a triangle's normal in any operation
MAX_TURN = 45.0
#: check-and-retry rounds per batch
RETRIES = 6
#: collapse batches per iteration
COLLAPSE_ROUNDS = 4
#: the rescue collapses: (the triangles above this Q_K, whose edges collapse whatever their
#: lengths, the largest Q_K of a new triangle unless its parent was worse): a collapse
#: removes its edge's triangles, so each one past the first tier at least halves the worst
#: Q_K it touches (the frog's needles of Q_K 534 and 21.5, whose collapses make triangles of
#: 3.4 and 8.3, stayed with the first tier alone)
RESCUE_TIERS = ((RESCUE_Q, COLLAPSE_Q), (10.0, 5.0), (20.0, 10.0))
#: flip batches per flip pass (three passes per iteration)
FLIP_ROUNDS = 2
#: relocation passes per iteration
SMOOTH_PASSES = 2
#: nearest feature segments of the same curve looked at when projecting onto a curve
_CURVE_NEIGHBOURS = 8
#: the flag, in a vertex's box-side bits, of a vertex fixed in the input: it stays fixed
#: even where the operations around it would make it look like a curve vertex
_PINNED = np.int64(1) << np.int64(40)


def _sides(bits):
    """The box-side bits of :func:`warpmesh.optimize.label_smoothing.box_sides`, without the pin."""
    return bits & (_PINNED - 1)


def optimize_labels(mesh, size=None, *, tolerance: float | None = None, iterations: int = 6, progress=False):
    """Remesh a multi-material surface towards ``size`` (module docstring).

    Parameters
    ----------
    mesh : Mesh
        A shared surface: triangles with ``cell_refs["triangle"]`` (lower label) and
        ``cell_data["label_above"]`` (higher label).
    size : float or callable, optional
        Target edge length, or ``size(points) -> (n,)`` positive lengths; default the
        edge length of an equilateral mesh with as many triangles as the input's area.
    tolerance : float, optional
        Largest distance from the input surface of a collapsed or flipped triangle's
        centroid and edge midpoints; default half the smallest grid spacing
        (``mesh.info["grid"]``), else a quarter of the mean edge length.
    iterations : int
        Split / collapse / flip / relocate iterations, 0 or more.
    progress : bool or callable
        A bar over the iterations (tqdm, shown once the call has taken a second), or
        ``progress(done, total)`` after each (a run started again adds its iterations).

    Returns
    -------
    Mesh
        The remeshed surface with its two label arrays. ``info["optimize"]`` holds
        ``before`` and ``after`` (``q_worst``, ``q_mean``, ``angle_min``, ``triangles``,
        ``edge_error``: the mean of ``|log(length / size)|``), the operator counts of
        the state returned (``splits``, ``collapses``, ``flips``, ``moves``),
        ``rejected`` (operations undone by the checks), ``discarded`` (operations of the
        iterations or runs thrown away), ``kept`` ("final"; "best": an earlier iteration, the last
        one's worst Q_K being above the input's; "strict": the iterations run again from
        the input with no operation making a triangle worse than the input's worst, when
        no iteration was as good; "input", with a warning), ``q_worst_reached`` (the first
        run's last worst Q_K), ``size`` (the median), ``tolerance`` and ``time``.

    Raises
    ------
    ValueError
        ``mesh`` without the two label arrays, ``size``, ``tolerance`` or ``iterations``
        out of range.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((12, 12, 12), dtype=np.uint8); vol[2:10, 2:10, 2:10] = 1
    >>> m = optimize_labels(wm.mesh_surface(vol, labels="all", interfaces="shared"), size=2.0)
    >>> m.stats()["watertight"], m.info["optimize"]["splits"] >= 0
    (True, True)
    """
    from warpmesh.surface.multilabel import LABEL_ABOVE, shared_labels

    t_start = time.perf_counter()
    if isinstance(iterations, (bool, np.bool_)) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ValueError(f"expected a non-negative integer for 'iterations', got {iterations!r}")
    refs, above = shared_labels(mesh)
    if not len(refs):
        raise ValueError("expected a 'mesh' with triangles, got a shared surface of none")
    p = np.array(mesh.points, np.float64)
    t = np.asarray(mesh.cells["triangle"], np.int64).copy()
    lower, upper = np.asarray(refs).copy(), np.asarray(above).copy()
    grid = mesh.info.get(GRID_INFO)
    bits = np.zeros(len(p), np.int64)
    if grid is not None and grid.get("shape") is not None:
        bits = box_sides(vertex_cubes(p, grid["origin"], grid["spacing"]), grid["shape"])
    h_of = _size_function(size, p, t)
    if tolerance is None:
        tolerance = 0.5 * float(np.min(grid["spacing"])) if grid is not None else \
            0.25 * float(np.linalg.norm(p[t[:, [1, 2, 0]]] - p[t], axis=2).mean())
    if isinstance(tolerance, (bool, np.bool_)) or not isinstance(tolerance, (int, float, np.floating)) \
            or not (np.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"expected a positive 'tolerance', got {tolerance!r}")
    tol = float(tolerance)
    ref = _Reference(p, t, lower, upper, bits)
    _, _, _, kind = classify_edges(t, lower, upper, len(p), bits)
    bits = bits | np.where(kind == 0, _PINNED, 0)  # the input's fixed vertices stay fixed whatever happens around
    before = _summary(p, t, h_of)
    start = (p, t, lower, upper, bits)
    bar = Progress(progress, int(iterations), "warpmesh optimize (labels)", "pass")
    state, best, final, counts = _iterate(start, h_of, ref, tol, int(iterations), before, q_cap=np.inf, bar=bar)
    kept, runs = "final", [counts]
    if final["q_worst"] > before["q_worst"]:
        if best is not None:
            kept, state, counts = "best", best[2], best[3]
        else:  # again from the input, no operation making a triangle worse than the input's worst
            kept = "strict"
            bar.extend(int(iterations))
            state, _, strict, counts = _iterate(start, h_of, ref, tol, int(iterations), before,
                                                q_cap=before["q_worst"], bar=bar)
            runs.append(counts)
            if strict["q_worst"] > before["q_worst"]:
                kept, state, counts = "input", start, dict.fromkeys(counts, 0)
                warnings.warn(f"optimize_labels: no pass kept the worst Q_K at or below the input's "
                              f"({before['q_worst']:.3g}, reached {strict['q_worst']:.3g}); returning the input",
                              stacklevel=2)
    bar.close()
    # the counts are the kept state's; the operations of the runs (or iterations) thrown away apart
    discarded = sum(sum(r[k] for k in _OPERATIONS) for r in runs) - sum(counts[k] for k in _OPERATIONS)
    p, t, lower, upper, _ = state
    used = np.unique(t)
    index = np.full(len(p), -1, np.int64)
    index[used] = np.arange(len(used))
    p, t = p[used], index[t]
    info = {**mesh.info, "optimize": {**counts, "discarded": int(discarded), "before": before,
                                      "after": _summary(p, t, h_of),
                                      "q_worst_reached": final["q_worst"], "kept": kept,
                                      "size": float(np.median(h_of(p))), "tolerance": tol,
                                      "iterations": int(iterations), "time": time.perf_counter() - t_start}}
    data = {LABEL_ABOVE: {"triangle": np.asarray(upper)}}
    return type(mesh)(p, {"triangle": t}, cell_refs={"triangle": np.asarray(lower)}, cell_data=data, info=info)


#: the operations counted in ``info["optimize"]``
_OPERATIONS = ("splits", "collapses", "flips", "snaps", "moves")


def _iterate(state, h_of, ref, tol, iterations, before, q_cap, bar=None):
    """The iterations from ``state``; returns (last state, the best state not worse than the
    input as (q_worst, -angle_min, state, its operation counts) or None, the last state's
    summary, the last state's operation counts). ``q_cap`` bounds every operation's
    triangles (inf: the operators' own limits)."""
    p, t, lower, upper, bits = state
    counts = {"splits": 0, "collapses": 0, "flips": 0, "snaps": 0, "moves": 0, "rejected": 0}
    best, s = None, before
    for _ in range(iterations):
        p, t, lower, upper, bits = _split_pass(p, t, lower, upper, bits, h_of, ref, min(COLLAPSE_Q, q_cap), counts)
        p, t, lower, upper, bits = _collapse_pass(p, t, lower, upper, bits, h_of, ref, tol,
                                                  min(COLLAPSE_Q, q_cap), counts)
        t = _flip_pass(p, t, lower, upper, bits, ref, tol, counts)
        p, t, lower, upper = _snap_pass(p, t, lower, upper, bits, ref, tol, q_cap, counts)
        for above, q_limit in RESCUE_TIERS:
            p, t, lower, upper, bits = _collapse_pass(p, t, lower, upper, bits, h_of, ref, tol,
                                                      min(q_limit, q_cap), counts, rescue=above)
        for _ in range(SMOOTH_PASSES):
            p = _relocate_pass(p, t, lower, upper, bits, ref, min(SMOOTH_Q, q_cap), counts)
            t = _flip_pass(p, t, lower, upper, bits, ref, tol, counts)
        s = _summary(p, t, h_of)
        if s["q_worst"] <= before["q_worst"] and (best is None or (s["q_worst"], -s["angle_min"]) <= best[:2]):
            best = (s["q_worst"], -s["angle_min"], (p, t, lower, upper, bits), dict(counts))
        if bar is not None:
            bar.update()
    return (p, t, lower, upper, bits), best, s, counts


# ----------------------------------------------------------------------------- set-up
def _size_function(size, p, t):
    """``h(points) -> (n,)`` from ``size`` (checked)."""
    if size is None:
        c = p[t]
        area = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1).sum()
        size = float(np.sqrt(4.0 * area / (np.sqrt(3.0) * max(len(t), 1))))
    if callable(size):
        fn = size

        def h_of(x):
            out = np.asarray(fn(np.asarray(x, np.float64)), np.float64).reshape(-1)
            if out.shape != (len(x),) or not np.all(np.isfinite(out) & (out > 0)):
                raise ValueError(f"expected 'size' to return {len(x)} positive finite lengths, got shape "
                                 f"{out.shape} (min {out.min() if out.size else None!r})")
            return out
        h_of(p[:1])
        return h_of
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, (int, float, np.floating, np.integer)) \
            or not (np.isfinite(size) and size > 0):
        raise ValueError(f"expected a positive 'size' (an edge length) or a callable size(points), got {size!r}")
    value = float(size)
    return lambda x: np.full(len(x), value)


def _mix(x):
    """A 64-bit mix of non-negative integers (splitmix64's finaliser)."""
    z = np.asarray(x, np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    with np.errstate(over="ignore"):
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def _pair_keys(lower, upper):
    lo, hi = np.asarray(lower, np.int64), np.asarray(upper, np.int64)
    return (lo << np.int64(32)) + hi


def _edges(t, n):
    """Every face edge: (sorted ends (3m, 2), its face, edge id per face edge, unique keys)."""
    e = np.sort(np.stack([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    keys, inverse = np.unique(e[:, 0] * n + e[:, 1], return_inverse=True)
    return e, np.repeat(np.arange(len(t)), 3), inverse.ravel(), keys


def _edge_signatures(t, lower, upper, n, a, b):
    """Per edge (a[k], b[k]), a key of the set of label pairs around it (the same on the
    input and the remeshed surface for the same curve)."""
    a, b = np.minimum(a, b), np.maximum(a, b)
    e, face, eid, keys = _edges(t, n)
    pk = _pair_keys(lower, upper)[face]
    uniq = np.unique(np.column_stack([eid, pk]), axis=0)
    sig = np.zeros(len(keys), np.uint64)
    with np.errstate(over="ignore"):
        np.add.at(sig, uniq[:, 0], _mix(uniq[:, 1].astype(np.uint64)))
    return sig[np.searchsorted(keys, a * n + b)]


class _Reference:
    """The input surface: its interfaces (one closest-point target per label pair) and its
    feature curves (segments grouped by the labels around them)."""

    def __init__(self, p, t, lower, upper, bits):
        self.p, self.t = p.copy(), t.copy()
        self.face_key = _pair_keys(lower, upper)
        self._targets = {}
        a, b, feature, _ = classify_edges(t, lower, upper, len(p), bits)
        a, b = a[feature], b[feature]
        sig = _edge_signatures(t, lower, upper, len(p), a, b)
        order = np.argsort(sig, kind="stable")
        self.seg_a, self.seg_b, self.seg_sig = p[a[order]], p[b[order]], sig[order]
        self._trees = {}

    def project_surface(self, x, keys):
        """Closest points of ``x`` on the input triangles with label-pair key ``keys``."""
        from warpmesh.frep.projection import MeshTarget

        out = np.array(x, np.float64)
        for key in np.unique(keys).tolist():
            sel = np.flatnonzero(keys == key)
            if key not in self._targets:
                self._targets[key] = MeshTarget(self.p, self.t[self.face_key == key])
            out[sel] = self._targets[key].project(x[sel])
        return out

    def project_curve(self, x, sigs):
        """Closest points of ``x`` on the input's feature segments with signature ``sigs``,
        and whether such a segment exists."""
        from scipy.spatial import cKDTree

        out, found = np.array(x, np.float64), np.zeros(len(x), bool)
        for s in np.unique(sigs).tolist():
            lo, hi = np.searchsorted(self.seg_sig, [s, s], side="left")[0], np.searchsorted(self.seg_sig, s, "right")
            if hi == lo:
                continue
            sel = np.flatnonzero(sigs == s)
            if s not in self._trees:
                self._trees[s] = cKDTree(0.5 * (self.seg_a[lo:hi] + self.seg_b[lo:hi]))
            k = min(_CURVE_NEIGHBOURS, hi - lo)
            _, idx = self._trees[s].query(x[sel], k=k)
            idx = lo + np.asarray(idx).reshape(len(sel), k)
            s0, d = self.seg_a[idx], self.seg_b[idx] - self.seg_a[idx]
            w = np.clip(np.einsum("ikj,ikj->ik", x[sel][:, None] - s0, d) /
                        np.maximum(np.einsum("ikj,ikj->ik", d, d), 1e-300), 0.0, 1.0)
            q = s0 + w[..., None] * d
            best = np.argmin(np.linalg.norm(q - x[sel][:, None], axis=2), axis=1)
            out[sel] = q[np.arange(len(sel)), best]
            found[sel] = True
        return out, found

    def distance(self, x):
        from warpmesh.frep.projection import MeshTarget

        if "all" not in self._targets:
            self._targets["all"] = MeshTarget(self.p, self.t)
        return self._targets["all"].distance(x)


def _summary(p, t, h_of) -> dict:
    from warpmesh.cells.quality import triangle_angles

    q = quality_of(p[t])
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    e = np.unique(e, axis=0)
    length = np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1)
    h = h_of(0.5 * (p[e[:, 0]] + p[e[:, 1]]))
    return {"triangles": int(len(t)), "q_worst": float(q.max()), "q_mean": float(q.mean()),
            "angle_min": float(triangle_angles(p, t).min()),
            "edge_error": float(np.abs(np.log(length / h)).mean())}


def _normals(p, t):
    c = p[t]
    return np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])


def _turned(n_new, n_old):
    """Triangles whose normal turned by more than MAX_TURN or that degenerated."""
    ln, lo = np.linalg.norm(n_new, axis=1), np.linalg.norm(n_old, axis=1)
    return np.einsum("ij,ij->i", n_new, n_old) <= np.cos(np.radians(MAX_TURN)) * ln * lo


def _embedding_failures(p, t, faces, pair_cos0=None):
    """Which of ``faces`` (indices into t) cross or touch a face, degenerate, or fold onto
    a face sharing an edge (unless that pair already was as folded: ``pair_cos0``)."""
    bad, _ = face_violations(p, t, faces, fold_cos=-2.0, partners=True)  # orientation-free
    out = np.zeros(len(t), bool)
    out[faces[bad]] = True
    pairs = wing_pairs(t, faces)
    if len(pairs):
        folded = wing_cos(p, t, pairs) > -FOLD_COS
        out[pairs[folded, 0]] = True
        out[pairs[folded, 1]] = True
    return out


def _vertex_keys(t, lower, upper, n):
    """The label-pair key of one face at each vertex (one interface at interface vertices)."""
    keys = np.zeros(n, np.int64)
    keys[t.ravel()] = np.repeat(_pair_keys(lower, upper), 3)
    return keys


# ----------------------------------------------------------------------------- splits
def _split_pass(p, t, lower, upper, bits, h_of, ref, q_limit, counts):
    n = len(p)
    e, face, eid, keys = _edges(t, n)
    a, b = keys // n, keys % n
    length = np.linalg.norm(p[a] - p[b], axis=1)
    long_ = length > SPLIT_ABOVE * h_of(0.5 * (p[a] + p[b]))
    if not long_.any():
        return p, t, lower, upper, bits
    _, _, feature, _ = classify_edges(t, lower, upper, n, _sides(bits))  # same edge order (sorted keys)
    cand = np.flatnonzero(long_)
    rank = np.full(len(keys), -1)
    rank[cand] = np.arange(len(cand))
    on = rank[eid] >= 0
    chosen = select_independent(len(cand), -length[cand], face[on], rank[eid[on]], rounds=8)
    edges = cand[chosen]
    mid = 0.5 * (p[a[edges]] + p[b[edges]])
    feat = feature[edges]
    new = mid.copy()
    ok = np.ones(len(edges), bool)
    if (~feat).any():
        a_face = np.zeros(len(keys), np.int64)
        a_face[eid] = face  # one face on each edge
        new[~feat] = ref.project_surface(mid[~feat], _pair_keys(lower, upper)[a_face[edges[~feat]]])
    if feat.any():
        sig = _edge_signatures(t, lower, upper, n, a[edges[feat]], b[edges[feat]])
        new[feat], found = ref.project_curve(mid[feat], sig)
        ok[np.flatnonzero(feat)[~found]] = False
    edges, new = edges[ok], new[ok]
    for _ in range(RETRIES):
        if len(edges) == 0:
            break
        p2, t2, lo2, up2, owner, parent = _apply_splits(p, t, lower, upper, eid, edges, new, n)
        changed = np.flatnonzero(owner >= 0)
        fail_face = _embedding_failures(p2, t2, changed)
        fail_face[changed] |= _turned(_normals(p2, t2[changed]), _normals(p, t[parent[changed]])) | \
            (quality_of(p2[t2[changed]]) > np.maximum(q_limit, quality_of(p[t[parent[changed]]])))
        failed = np.zeros(len(edges), bool)
        failed[owner[fail_face & (owner >= 0)]] = True
        if not failed.any():
            counts["splits"] += len(edges)
            b2 = np.concatenate([bits, bits[a[edges]] & bits[b[edges]] & ~_PINNED])
            return p2, t2, lo2, up2, b2
        counts["rejected"] += int(failed.sum())
        edges, new = edges[~failed], new[~failed]
    return p, t, lower, upper, bits


def _apply_splits(p, t, lower, upper, eid, edges, new, n):
    """Split the ``edges`` (no two in one face) at ``new``: returns (points, triangles,
    lower, upper, the split of each face or -1, the input face of each face)."""
    slot = np.full(eid.max() + 1, -1)
    slot[edges] = np.arange(len(edges))
    which = slot[eid].reshape(-1, 3)  # the split of each face edge (j: corners j, j+1)
    hit = np.flatnonzero((which >= 0).any(axis=1))
    j = np.argmax(which[hit] >= 0, axis=1)
    k = which[hit, j]
    w = n + k
    f = t[hit]
    r = np.arange(len(hit))
    c0, c1, c2 = f[r, j], f[r, (j + 1) % 3], f[r, (j + 2) % 3]
    t2 = t.copy()
    t2[hit] = np.column_stack([c0, w, c2])
    t2 = np.concatenate([t2, np.column_stack([w, c1, c2])])
    parent = np.concatenate([np.arange(len(t)), hit])
    owner = np.full(len(t2), -1)
    owner[hit] = k
    owner[len(t):] = k
    return (np.concatenate([p, new]), t2, np.concatenate([lower, lower[hit]]),
            np.concatenate([upper, upper[hit]]), owner, parent)


# ----------------------------------------------------------------------------- collapses
def _collapse_pass(p, t, lower, upper, bits, h_of, ref, tol, q_limit, counts, rescue=None):
    """Collapses of the edges shorter than ``COLLAPSE_BELOW`` x size; with ``rescue``, of
    the edges of the triangles worse than ``rescue`` instead, whatever their lengths
    (a cap whose apex is a curve vertex between its two curve edges, which no flip may
    remove, goes by the collapse of the apex along its curve)."""
    h = h_of(p)
    refused = np.zeros(0, np.int64)
    sub = {"collapses": 0, "rejected": 0}
    shorter, longest, only = COLLAPSE_BELOW * h, SPLIT_ABOVE * h, None
    if rescue is not None:
        bad = t[quality_of(p[t]) > rescue]
        if len(bad) == 0:
            return p, t, lower, upper, bits
        u, v = bad.ravel(), bad[:, [1, 2, 0]].ravel()
        shorter, longest, only = None, None, np.unique(np.concatenate([u * len(p) + v, v * len(p) + u]))
    for _ in range(COLLAPSE_ROUNDS):
        done, refused = collapse_round(p, t, lower, upper, _sides(bits), ref, tol, sub, room=len(t),
                                       refused=refused, shorter=shorter, longest=longest,
                                       q_limit=q_limit, pinned=(bits & _PINNED) != 0, only=only)
        if done is None:
            break
        t, lower, upper = done
    counts["collapses"] += sub["collapses"]
    counts["rejected"] += sub["rejected"]
    used = np.unique(t)  # drop the vertices collapsed away
    index = np.full(len(p), -1, np.int64)
    index[used] = np.arange(len(used))
    return p[used], index[t], lower, upper, bits[used]


# ----------------------------------------------------------------------------- flips
def _flip_pass(p, t, lower, upper, bits, ref, tol, counts):
    """The interface-edge flips of :func:`warpmesh.optimize.junction_swap.swap_pass`
    (vertex-disjoint batches, the refused candidates left out of the next ones)."""
    sub = {"flips": 0, "refused": 0}
    t = swap_pass(p, t, lower, upper, side_bits=_sides(bits), distance=ref.distance, tolerance=tol, counts=sub,
                  rounds=FLIP_ROUNDS)
    counts["flips"] += sub["flips"]
    counts["rejected"] += sub["refused"]
    return t


def _snap_pass(p, t, lower, upper, bits, ref, tol, q_cap, counts):
    """The junction snaps of :func:`warpmesh.optimize.junction_swap.snap_pass`, the snapped
    vertex placed on the input's curve of its edge (the same signature)."""
    n = len(p)

    def project(x, a, b):
        return ref.project_curve(x, _edge_signatures(t, lower, upper, n, a, b))

    sub = {"snaps": 0, "refused": 0}
    pinned = (bits & _PINNED) != 0
    p2, t2, lo2, up2 = snap_pass(p, t, lower, upper, side_bits=_sides(bits), project=project,
                                 distance=ref.distance, tolerance=tol, q_cap=q_cap, counts=sub, pinned=pinned)
    counts["snaps"] += sub["snaps"]
    counts["rejected"] += sub["refused"]
    return p2, t2, lo2, up2


# ----------------------------------------------------------------------------- relocation
def _relocate_pass(p, t, lower, upper, bits, ref, q_limit, counts):
    n = len(p)
    a, b, feature, kind = classify_edges(t, lower, upper, n, _sides(bits))
    kind = np.where((bits & _PINNED) != 0, 0, kind)
    target = p.copy()
    # interface vertices: area-weighted centroid of the ball, in the tangent plane
    nrm = _normals(p, t)
    area = 0.5 * np.linalg.norm(nrm, axis=1)
    cen = p[t].mean(axis=1)
    acc = np.zeros((n, 3))
    wsum = np.zeros(n)
    vn = np.zeros((n, 3))
    for j in range(3):
        np.add.at(acc, t[:, j], area[:, None] * cen)
        np.add.at(wsum, t[:, j], area)
        np.add.at(vn, t[:, j], nrm)
    surf = np.flatnonzero((kind == 2) & (wsum > 0))
    c = acc[surf] / wsum[surf, None]
    vn_s = vn[surf] / np.maximum(np.linalg.norm(vn[surf], axis=1), 1e-300)[:, None]
    step = c - p[surf]
    step -= np.einsum("ij,ij->i", step, vn_s)[:, None] * vn_s
    target[surf] = ref.project_surface(p[surf] + step, _vertex_keys(t, lower, upper, n)[surf])
    # curve vertices: the midpoint of their two curve neighbours, on the input curve
    fa, fb = a[feature], b[feature]
    ends = np.concatenate([fa, fb])
    other = np.concatenate([fb, fa])
    on_curve = kind[ends] == 1
    mid = np.zeros((n, 3))
    np.add.at(mid, ends[on_curve], 0.5 * p[other[on_curve]])
    curve = np.flatnonzero(kind == 1)
    if len(curve):
        sig = _edge_signatures(t, lower, upper, n, np.concatenate([fa, fb]), np.concatenate([fb, fa]))
        vsig = np.zeros(n, np.uint64)
        vsig[ends] = sig
        moved, found = ref.project_curve(mid[curve], vsig[curve])
        target[curve[found]] = moved[found]
    moving = np.flatnonzero(np.any(target != p, axis=1))
    if len(moving) == 0:
        return p
    new = p.copy()
    new[moving] = target[moving]
    undone = _revert(p, new, t, q_limit)
    counts["moves"] += len(moving) - undone
    counts["rejected"] += undone
    return new


def _revert(old, new, t, q_limit) -> int:
    """Undo (in ``new``) the moves of the vertices of failing faces, round by round, until
    no face around a moved vertex fails; returns how many moves were undone."""
    moved = np.any(new != old, axis=1)
    pending = np.flatnonzero(moved[t].any(axis=1))
    q_old_all = None
    undone = 0
    while len(pending):
        fail = _embedding_failures(new, t, pending)
        if q_old_all is None:
            q_old_all = quality_of(old[t])
        q_new = quality_of(new[t[pending]])
        fail[pending] |= (q_new > np.maximum(q_limit, q_old_all[pending])) | \
            _turned(_normals(new, t[pending]), _normals(old, t[pending]))
        verts = np.unique(t[np.flatnonzero(fail)].ravel())
        verts = verts[moved[verts]]
        if len(verts) == 0:
            break
        new[verts] = old[verts]
        moved[verts] = False
        undone += len(verts)
        back = np.zeros(len(moved), bool)
        back[verts] = True
        pending = np.flatnonzero(back[t].any(axis=1))
    return undone
