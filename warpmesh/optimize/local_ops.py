"""Vectorised local operators on oriented triangle meshes: edge split, collapse and flip.

The topological operators of [FG §16.4.3] (and Chapter 19), applied in batches: each
pass picks an *independent* set of candidate edges (no two share a triangle for splits
and flips, no two touch a common vertex ball for collapses) by a Luby-style rule — a
candidate wins when it has the best priority among every candidate it conflicts with —
and applies the whole set with array operations. Every operator keeps the winding of
the triangles (counter-clockwise seen from outside) and the per-triangle refs.

The working state is :class:`Surface`: points, triangles, per-triangle refs, per-vertex
feature class (0 free, 1 on a feature line, 2 corner), per-vertex feature-line id, and
the feature edges as sorted vertex-pair keys.

Examples
--------
>>> import numpy as np
>>> s = Surface(np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), np.array([[0, 1, 2], [0, 2, 3]]))
>>> topo = s.topology()
>>> e = int(np.flatnonzero(topo.n_faces == 2)[0])          # the diagonal 0-2
>>> s.flip(np.array([e]))
1
>>> sorted(map(sorted, s.triangles.tolist()))
[[0, 1, 3], [1, 2, 3]]
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.kernels import remesh as KR

__all__ = ["Surface", "Topology", "select_independent", "edge_key"]

FREE, LINE, CORNER = 0, 1, 2
_SHIFT = np.int64(1 << 31)


def edge_key(a, b) -> np.ndarray:
    """Order-independent int64 key of the vertex pairs (a, b)."""
    a, b = np.asarray(a, np.int64), np.asarray(b, np.int64)
    return np.minimum(a, b) * _SHIFT + np.maximum(a, b)


def select_independent(n_candidates: int, priority: np.ndarray, element: np.ndarray,
                       candidate: np.ndarray, rounds: int = 1, blocked: np.ndarray | None = None,
                       active: np.ndarray | None = None) -> np.ndarray:
    """Candidates that win every element they touch (lower priority wins, ties by a hash of the index).

    ``(element[k], candidate[k])`` lists which elements (faces, vertices) each candidate
    touches. Two winners never share an element. One round keeps the local minima;
    each further round adds the local minima among the candidates that touch no winner
    yet (``rounds`` large: a maximal independent set). Candidates touching an element
    flagged in ``blocked`` never win, nor do those with ``active`` False.

    Examples
    --------
    >>> import numpy as np
    >>> # a path of 4 candidate edges over vertices 0-1-2-3-4; candidate i touches i and i+1
    >>> el = np.array([0, 1, 1, 2, 2, 3, 3, 4]); cand = np.array([0, 0, 1, 1, 2, 2, 3, 3])
    >>> select_independent(4, np.array([1.0, 0.0, 2.0, 3.0]), el, cand).tolist()
    [1]
    >>> select_independent(4, np.array([1.0, 0.0, 2.0, 3.0]), el, cand, rounds=5).tolist()
    [1, 3]
    """
    if n_candidates == 0:
        return np.zeros(0, np.int64)
    if len(element) == 0:  # nothing shared: every allowed candidate wins
        return np.arange(n_candidates) if active is None else np.flatnonzero(active)
    # ties go by a scrambled index: by the plain index a chain of equal priorities (the
    # edges along a straight crease) would yield one winner per pass instead of a third
    tie = (np.arange(n_candidates, dtype=np.uint64) * np.uint64(0x9E3779B1)) & np.uint64(0xFFFFFFFF)
    # one rank per candidate, then the lowest rank on each element: no sort of the pairs
    rank = np.empty(n_candidates, np.int64)
    rank[np.lexsort((tie, priority))] = np.arange(n_candidates)
    n_el = int(element.max()) + 1
    taken = np.zeros(n_el, bool)
    if blocked is not None:
        m = min(len(blocked), n_el)
        taken[:m] = blocked[:m]
    alive = np.ones(n_candidates, bool) if active is None else np.asarray(active, bool).copy()
    won = np.zeros(n_candidates, bool)
    best = np.empty(n_el, np.int64)
    for _ in range(rounds):
        alive &= np.bincount(candidate[taken[element]], minlength=n_candidates) == 0
        sel = alive[candidate]
        if not sel.any():
            break
        el, c = element[sel], candidate[sel]
        r = rank[c]
        best.fill(n_candidates)
        np.minimum.at(best, el, r)
        new = alive & (np.bincount(c[best[el] != r], minlength=n_candidates) == 0)
        won |= new
        alive &= ~new
        taken[element[new[candidate]]] = True
    return np.flatnonzero(won)


#: a split child worse than this (and than ten times its parent) is refused
SPLIT_CHILD_Q = 1.0e3


def splits_keep_faces(s: Surface, topo, cand: np.ndarray, c: np.ndarray, turn: bool = True):
    """The splits of edges ``cand`` at ``c`` whose four new triangles are neither
    degenerate (Q above SPLIT_CHILD_Q and ten times their parent's) nor (with ``turn``)
    turned against the faces they replace."""
    p = s.points
    ok = np.ones(len(cand), bool)
    for face in (topo.face0[cand], topo.face1[cand]):
        has = face >= 0
        f = face[has]
        tri = p[s.triangles[f]]
        n_old = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        a, b = topo.edges[cand[has], 0], topo.edges[cand[has], 1]
        for end in (a, b):
            # the child keeping corner `end`: the other end of the edge moves to c
            other = np.where(end == a, b, a)
            new = tri.copy()
            at = s.triangles[f] == other[:, None]
            new[at] = c[has]
            n_new = np.cross(new[:, 1] - new[:, 0], new[:, 2] - new[:, 0])
            q_new = quality_of(new)
            good = np.isfinite(q_new) & ((q_new <= SPLIT_CHILD_Q) | (q_new <= 10 * quality_of(tri)))
            if turn:
                good &= np.einsum("ij,ij->i", n_old, n_new) > 0
            ok[np.flatnonzero(has)[~good]] = False
    return cand[ok], c[ok]


@dataclass
class Topology:
    """Edges of a triangle mesh with their one or two faces.

    ``edges[e] = (a, b)`` runs as in face ``face0[e]`` (corner ``local0[e]`` is a);
    ``face1[e]`` holds it as (b, a) at corner ``local1[e]``, or -1 on a boundary.
    ``opp0``/``opp1`` are the vertices opposite the edge in those faces.
    """

    edges: np.ndarray
    keys: np.ndarray
    face0: np.ndarray
    local0: np.ndarray
    face1: np.ndarray
    local1: np.ndarray
    opp0: np.ndarray
    opp1: np.ndarray
    n_faces: np.ndarray
    face_edges: np.ndarray  # (m, 3) edge of corner j -> j+1

    def has_edge(self, a, b) -> np.ndarray:
        k = edge_key(a, b)
        i = np.clip(np.searchsorted(self.keys, k), 0, len(self.keys) - 1)
        return self.keys[i] == k


def vertex_faces(triangles: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR (indptr, faces) of the faces around each vertex."""
    v = triangles.ravel()
    order = np.argsort(v, kind="stable")
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(v, minlength=n), out=indptr[1:])
    return indptr, order // 3


def vertex_neighbours(edges: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR (indptr, vertices) of the vertex adjacency given unique edges."""
    src = np.concatenate([edges[:, 0], edges[:, 1]])
    dst = np.concatenate([edges[:, 1], edges[:, 0]])
    order = np.argsort(src, kind="stable")
    indptr = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(src, minlength=n), out=indptr[1:])
    return indptr, dst[order]


def gather(indptr: np.ndarray, values: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Concatenated CSR rows: (row position in ``rows``, value) pairs."""
    counts = indptr[rows + 1] - indptr[rows]
    owner = np.repeat(np.arange(len(rows)), counts)
    start = np.repeat(indptr[rows] - np.cumsum(counts) + counts, counts)
    return owner, values[np.arange(counts.sum()) + start]


def quality_of(p: np.ndarray) -> np.ndarray:
    """Q_K of (k, 3, 3) triangles [FG eq. 16.15], inf when degenerate (twice the area at
    most 1e-14 x the longest edge squared); one Warp thread per triangle
    (:func:`warpmesh.kernels.remesh.triangle_quality_kernel`)."""
    corners = np.ascontiguousarray(p, dtype=np.float64).reshape(-1, 3, 3)
    if len(corners) == 0:
        return np.zeros(0)
    out = wp.empty(len(corners), dtype=wp.float64, device="cpu")  # the optimiser's arrays live on the host
    wp.launch(KR.triangle_quality_kernel, dim=len(corners),
              inputs=[wp.array(corners, dtype=wp.mat33d, device="cpu", copy=False)], outputs=[out], device="cpu")
    return out.numpy()


@dataclass
class Surface:
    """Working state of the optimiser (see the module docstring)."""

    points: np.ndarray
    triangles: np.ndarray
    refs: np.ndarray | None = None
    vclass: np.ndarray | None = None
    line_id: np.ndarray | None = None
    feature_keys: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def __post_init__(self):
        self.points = np.array(self.points, REAL_DTYPE)
        self.triangles = np.array(self.triangles, INDEX_DTYPE).reshape(-1, 3)
        n, m = len(self.points), len(self.triangles)
        self.refs = np.zeros(m, np.int64) if self.refs is None else np.array(self.refs, np.int64)
        self.vclass = np.zeros(n, np.int8) if self.vclass is None else np.array(self.vclass, np.int8)
        self.line_id = np.full(n, -1, np.int64) if self.line_id is None else np.array(self.line_id, np.int64)
        self.feature_keys = np.sort(np.asarray(self.feature_keys, np.int64))

    def copy(self) -> Surface:
        """An independent copy (arrays copied)."""
        return Surface(self.points.copy(), self.triangles.copy(), self.refs.copy(), self.vclass.copy(),
                       self.line_id.copy(), self.feature_keys.copy())

    def assign(self, other: Surface) -> None:
        """Take the state of ``other`` (a trial copy that passed its checks)."""
        self.points, self.triangles, self.refs = other.points, other.triangles, other.refs
        self.vclass, self.line_id, self.feature_keys = other.vclass, other.line_id, other.feature_keys

    # ------------------------------------------------------------------ topology
    def topology(self) -> Topology:
        t = self.triangles
        a, b = t.ravel(), t[:, [1, 2, 0]].ravel()
        key = edge_key(a, b)
        order = np.argsort(key, kind="stable")
        ks = key[order]
        first = np.ones(len(ks), bool)
        first[1:] = ks[1:] != ks[:-1]
        eid_sorted = np.cumsum(first) - 1
        eid = np.empty_like(eid_sorted)
        eid[order] = eid_sorted
        ne = int(first.sum())
        he0 = order[first]
        n_faces = np.bincount(eid, minlength=ne)
        he1 = np.full(ne, -1, np.int64)
        second = np.flatnonzero(~first)
        he1[eid_sorted[second]] = order[second]
        f0, l0 = he0 // 3, he0 % 3
        f1 = np.where(he1 >= 0, he1 // 3, -1)
        l1 = np.where(he1 >= 0, he1 % 3, 0)
        edges = np.stack([t[f0, l0], t[f0, (l0 + 1) % 3]], axis=1)
        opp0 = t[f0, (l0 + 2) % 3]
        opp1 = np.where(he1 >= 0, t[np.maximum(f1, 0), (l1 + 2) % 3], -1)
        return Topology(edges, ks[first], f0, l0, f1, l1, opp0, opp1, n_faces, eid.reshape(-1, 3))

    def is_feature(self, topo: Topology) -> np.ndarray:
        if len(self.feature_keys) == 0:
            return topo.n_faces == 1
        i = np.clip(np.searchsorted(self.feature_keys, topo.keys), 0, len(self.feature_keys) - 1)
        return (self.feature_keys[i] == topo.keys) | (topo.n_faces == 1)

    def _set_feature_keys(self, keys):
        self.feature_keys = np.unique(np.asarray(keys, np.int64))

    # ------------------------------------------------------------------ split
    def split(self, topo: Topology, chosen: np.ndarray, new_points: np.ndarray) -> int:
        """Split the chosen edges (no two in one face) at ``new_points``."""
        if len(chosen) == 0:
            return 0
        t = self.triangles
        n0 = len(self.points)
        mid = n0 + np.arange(len(chosen))
        a, b = topo.edges[chosen, 0], topo.edges[chosen, 1]
        f0, l0, o0 = topo.face0[chosen], topo.local0[chosen], topo.opp0[chosen]
        t[f0, (l0 + 1) % 3] = mid  # (a, b, o0) -> (a, m, o0)
        new = [np.stack([mid, b, o0], 1)]
        new_refs = [self.refs[f0]]
        two = topo.face1[chosen] >= 0
        f1, l1, o1 = topo.face1[chosen][two], topo.local1[chosen][two], topo.opp1[chosen][two]
        t[f1, (l1 + 1) % 3] = mid[two]  # (b, a, o1) -> (b, m, o1)
        new.append(np.stack([mid[two], a[two], o1], 1))
        new_refs.append(self.refs[f1])
        self.triangles = np.concatenate([t] + new)
        self.refs = np.concatenate([self.refs] + new_refs)
        self.points = np.concatenate([self.points, new_points])
        feat = self.is_feature(topo)[chosen]
        cls = np.where(feat, LINE, FREE).astype(np.int8)
        self.vclass = np.concatenate([self.vclass, cls])
        lid = np.where(feat, np.maximum(self.line_id[a], self.line_id[b]), -1)
        both = feat & (self.vclass[a] == LINE) & (self.vclass[b] == LINE)
        lid = np.where(both, self.line_id[a], lid)
        self.line_id = np.concatenate([self.line_id, lid])
        if feat.any():
            fk = edge_key(a[feat], b[feat])
            keep = ~np.isin(self.feature_keys, fk)
            self._set_feature_keys(np.concatenate([
                self.feature_keys[keep], edge_key(a[feat], mid[feat]), edge_key(mid[feat], b[feat])]))
        return len(chosen)

    # ------------------------------------------------------------------ flip
    def flip(self, chosen: np.ndarray, topo: Topology | None = None) -> int:
        """Flip the chosen interior edges (no two in one face): (a, b) -> (o0, o1)."""
        if len(chosen) == 0:
            return 0
        topo = self.topology() if topo is None else topo
        a, b = topo.edges[chosen, 0], topo.edges[chosen, 1]
        o0, o1 = topo.opp0[chosen], topo.opp1[chosen]
        f0, f1 = topo.face0[chosen], topo.face1[chosen]
        self.triangles[f0] = np.stack([a, o1, o0], 1)
        self.triangles[f1] = np.stack([o1, b, o0], 1)
        return len(chosen)

    def flip_candidates_ok(self, topo: Topology, cand: np.ndarray, max_turn_cos: float) -> np.ndarray:
        """Which candidate edges can flip: interior, not features, same ref on both sides,
        the new edge absent, both new triangles turning the same way as the old pair."""
        cand = cand[(topo.n_faces[cand] == 2) & ~self.is_feature(topo)[cand]]
        cand = cand[self.refs[topo.face0[cand]] == self.refs[np.maximum(topo.face1[cand], 0)]]
        o0, o1 = topo.opp0[cand], topo.opp1[cand]
        cand = cand[(o0 != o1) & ~topo.has_edge(o0, o1)]
        p = self.points
        a, b, o0, o1 = topo.edges[cand, 0], topo.edges[cand, 1], topo.opp0[cand], topo.opp1[cand]
        n_old0 = np.cross(p[b] - p[a], p[o0] - p[a])
        n_old1 = np.cross(p[a] - p[b], p[o1] - p[b])
        n_new0 = np.cross(p[o1] - p[a], p[o0] - p[a])
        n_new1 = np.cross(p[b] - p[o1], p[o0] - p[o1])

        def unit(v):
            return v / np.maximum(np.linalg.norm(v, axis=1), 1e-300)[:, None]

        n_old0, n_old1, n_new0, n_new1 = map(unit, (n_old0, n_old1, n_new0, n_new1))
        dot = lambda u, v: np.einsum("ij,ij->i", u, v)  # noqa: E731
        flat_enough = dot(n_old0, n_old1) > max_turn_cos
        ok = flat_enough & (dot(n_new0, n_new1) > max_turn_cos)
        avg = unit(n_old0 + n_old1)
        ok &= (dot(n_new0, avg) > 0.5) & (dot(n_new1, avg) > 0.5)
        return cand[ok]

    # ------------------------------------------------------------------ collapse
    def collapse(self, keep: np.ndarray, remove: np.ndarray, position: np.ndarray,
                 faces_gone: np.ndarray) -> int:
        """Merge each ``remove[i]`` into ``keep[i]`` placed at ``position[i]``; drop ``faces_gone``."""
        if len(keep) == 0:
            return 0
        self.points[keep] = position
        remap = np.arange(len(self.points))
        remap[remove] = keep
        self.triangles = remap[self.triangles]
        alive = np.ones(len(self.triangles), bool)
        alive[faces_gone] = False
        self.triangles, self.refs = self.triangles[alive], self.refs[alive]
        if len(self.feature_keys):
            hi = self.feature_keys % _SHIFT
            lo = self.feature_keys // _SHIFT
            lo, hi = remap[lo], remap[hi]
            k = edge_key(lo, hi)
            self._set_feature_keys(k[lo != hi])
        return len(keep)

    def compact(self) -> np.ndarray:
        """Drop unreferenced vertices; returns the old index of each kept vertex."""
        used = np.zeros(len(self.points), bool)
        used[self.triangles.ravel()] = True
        if used.all():
            return np.arange(len(self.points))
        old = np.flatnonzero(used)
        new = np.full(len(self.points), -1, np.int64)
        new[old] = np.arange(len(old))
        self.triangles = new[self.triangles]
        if len(self.feature_keys):
            lo, hi = new[self.feature_keys // _SHIFT], new[self.feature_keys % _SHIFT]
            ok = (lo >= 0) & (hi >= 0)
            self._set_feature_keys(edge_key(lo[ok], hi[ok]))
        self.points, self.vclass, self.line_id = self.points[old], self.vclass[old], self.line_id[old]
        return old
