"""Surface mesh optimisation and simplification on the exact surface [FG §16.4.3].

:func:`optimize` turns a geometric mesh (marching cubes, octree) into a *unit* mesh of
a size field (Definition 16.4) with well-shaped triangles, every vertex on the exact
surface. Each iteration applies the operators of §16.4.3 in batches
(:mod:`warpmesh.optimize.local_ops`):

1. **split** edges longer than 4/3 h, the new vertex projected onto f = 0;
2. **collapse** edges shorter than 4/5 h when the link condition holds (the mesh stays
   manifold), no triangle turns over or gets much worse, no new edge is too long and the
   new triangles stay within ``tolerance`` of the surface;
3. **flip** edges towards valence 6 (topological: positions kept);
4. **relocate** vertices to the area-weighted centroid of their ball, in the tangent
   plane, then project onto f = 0 (metric: connectivity kept).

A final polishing phase flips for quality, moves the vertices of the worst triangles
to the best of a few candidate positions, and collapses needles. Sharp edges are
recovered on the exact surface and kept by every operator (:mod:`warpmesh.optimize.features`).

Every batch of splits, collapses, flips and moves is checked after the fact, locally, by
:mod:`warpmesh.optimize.embedding`: an operation whose new faces would cross a face
nearby, fold onto a neighbour or face inwards (against the exact normal) is undone and
the rest of the batch kept, so an embedded input stays embedded. The result is never
worse than the input: its worst Q_K is at most the input's, else the latest pass that
was is returned, else the input itself (``info["optimize"]["kept"]`` says which).

:func:`simplify` is the same driver with a size field from the curvature (h = sqrt(8
tolerance / κ), so the density follows the curvature as in Fig. 16.20) that never asks
for more vertices than the input has; ``fraction`` scales it to a target count. Its
result may be worse than a well-shaped input, up to worst Q_K = ``SIMPLIFY_Q``.

Examples
--------
>>> import warpmesh as wm
>>> shape, bounds = wm.example("sphere")
>>> mc = wm.mesh_surface(shape, bounds=bounds, resolution=32, method="mc")
>>> opt = wm.optimize(mc, shape, size=0.1)
>>> s = opt.stats()
>>> s["watertight"], s["euler"], s["q_worst"] < 2.0, s["q_mean"] < 1.15
(True, 2, True, True)
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from warpmesh.optimize.local_ops import CORNER, FREE, LINE, Surface, edge_key, gather, quality_of, select_independent, \
    splits_keep_faces, vertex_faces, vertex_neighbours
from warpmesh.optimize.embedding import face_violations, revert_violations, verified_collapse, verified_flip, \
    verified_split
from warpmesh.optimize.features import DEFAULT_ANGLE, FeatureLines, detect_features, feature_edges_of, insert_creases, snap_corners
from warpmesh.frep.projection import ImplicitTarget, VolumeField, FunctionTarget, as_target
from warpmesh._conventions import CAP_REF, SURFACE_REF
from warpmesh.cells.quality import quality_table
from warpmesh.cells.types import MeshLike, require_mesh
from warpmesh.optimize.sizing import GRADATION, graded, size_field
from warpmesh.cells.topology import degenerate_faces, is_edge_manifold
from warpmesh.errors import TopologyError
from warpmesh._util.budget import check_budget

__all__ = ["optimize", "simplify"]

SPLIT_ABOVE = 4.0 / 3.0
COLLAPSE_BELOW = 4.0 / 5.0
#: a collapse may not make a triangle worse than this (unless the ball was already worse)
COLLAPSE_Q = 3.0
#: the same while decimating (flips and relocation even the triangles out afterwards)
SIMPLIFY_COLLAPSE_Q = 6.0
#: the worst Q_K a decimation may end with when its input was better (a tenth of the
#: triangles of a well-shaped voxel surface cannot all stay as good within the tolerance)
SIMPLIFY_Q = SIMPLIFY_COLLAPSE_Q
#: above this a relocation may not make a face worse at all
SMOOTH_Q_CAP = 6.0
#: largest normal turn (degrees) accepted for a triangle moved by any operator
MAX_TURN = 45.0
#: selection-and-check rounds per collapse pass, Luby rounds per selection
COLLAPSE_ROUNDS = 4
LUBY_ROUNDS = 6
POLISH_PASSES = 6
#: extra local passes while the worst triangle is above RESCUE_Q
RESCUE_PASSES = 8
RESCUE_Q = 2.0
#: rescue passes between two searches for gaps in the crease chains
RESCUE_REFRESH = 4
#: largest turn (degrees) between the two faces of an edge flipped by the rescue passes
RESCUE_TURN = 100.0
POLISH_Q = 1.6
#: iterations after the first that look for crease gaps again
FEATURE_REFRESH = 2


@dataclass
class _Run:
    s: Surface
    target: object
    size: object
    tolerance: float
    angle: float
    lines: FeatureLines | None
    h: np.ndarray | None = None
    gradation: float = GRADATION
    rejected: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # removed * n + kept
    #: collapse into the kept end (simplification) instead of the midpoint of free edges
    half_edge: bool = False
    counts: dict | None = None

    # --------------------------------------------------------------- helpers
    def normals(self, pts):
        """Outward unit normals of the exact surface (the embedding checks' reference)."""
        return self.target.normals(pts)

    @property
    def check(self) -> dict:
        """Options of the embedding checks: a shape's normals are compared at the centroid,
        sampled ones (a voxel staircase turns within a face) averaged over the corners too."""
        return {"average": not isinstance(self.target, ImplicitTarget)}

    def _count_rejected(self, k: int) -> None:
        if self.counts is not None:
            self.counts["rejected"] = self.counts.get("rejected", 0) + int(k)

    def sizes(self):
        s = self.s
        h = self.size(s.points)
        topo = s.topology()
        feat = s.vclass != FREE
        if feat.any() and getattr(self.size, "from_curvature", False):
            # on a crease the Hessian sees the fold, not the surface on either side: take the
            # largest h of the free neighbours (none: keep it)
            e = topo.edges
            hf = np.zeros(len(h))
            for u, v in ((e[:, 0], e[:, 1]), (e[:, 1], e[:, 0])):
                m = feat[u] & ~feat[v]
                np.maximum.at(hf, u[m], h[v[m]])
            h = np.where(feat & (hf > 0), hf, h)
        self.h = graded(h, s.points, topo.edges, self.gradation)
        return topo

    def project_free(self, pts, max_step):
        return self.target.project(pts, max_step=max_step)

    def place(self, pts, feature, line_id, max_step):
        """Project new/moved points: feature points onto their polyline, others onto f = 0.
        A polyline point farther from the surface than the tolerance (a chord across a
        curved crease, or across a corner the creases do not reach yet) goes on onto f = 0:
        no vertex is placed outside the tolerance."""
        out = pts.copy()
        if (~feature).any():
            out[~feature] = self.project_free(pts[~feature], max_step[~feature])
        if feature.any() and self.lines is not None:
            on_line = self.lines.project(pts[feature], line_id[feature])
            near = np.flatnonzero(self.target.estimate(on_line) > 0.5 * self.tolerance)  # a filter
            off = near[self._distance(on_line[near]) > self.tolerance]
            on_line[off] = self.project_free(on_line[off], max_step[feature][off])
            out[feature] = on_line
        return out

    def _distance(self, pts):
        # one foot-point step: a slightly looser upper bound, at half the cost
        if isinstance(self.target, FunctionTarget):
            return self.target.distance(pts, refine=1)
        return self.target.distance(pts)

    def too_far(self, old: np.ndarray, new: np.ndarray) -> np.ndarray:
        """Which new (k, 3, 3) triangles leave the tolerance (centroid or an edge midpoint
        farther than it from the surface) and are farther than the old ones they replace."""
        bad = np.zeros(len(new), bool)
        if len(new) == 0:
            return bad
        # the first-order estimate only filters (it may underestimate): half the tolerance
        est = self.target.estimate(_face_samples(new).reshape(-1, 3)).reshape(-1, 4).max(1)
        far = np.flatnonzero(est > 0.5 * self.tolerance)
        if len(far):
            # one projection of both sample sets (each point's Newton steps are its own)
            d = self._distance(_face_samples(np.concatenate([new[far], old[far]])).reshape(-1, 3))
            d_new, d_old = np.split(d.reshape(-1, 4).max(1), 2)
            bad[far] = d_new > np.maximum(self.tolerance, d_old + 1e-12)
        return bad

    # --------------------------------------------------------------- split
    def split_pass(self) -> int:
        topo = self.s.topology()
        a, b = topo.edges[:, 0], topo.edges[:, 1]
        length = np.linalg.norm(self.s.points[a] - self.s.points[b], axis=1)
        return self._split_edges(topo, np.flatnonzero(length > SPLIT_ABOVE * 0.5 * (self.h[a] + self.h[b])))

    def _bad_triangles(self, q_limit: float):
        """(topology, triangles worse than ``q_limit``, their edge lengths (k, 3)); edge j
        runs from corner j to corner j + 1."""
        s = self.s
        topo = s.topology()
        p, t = s.points, s.triangles
        bad = np.flatnonzero(quality_of(p[t]) > q_limit)
        lens = np.stack([np.linalg.norm(p[t[bad, (j + 1) % 3]] - p[t[bad, j]], axis=1) for j in range(3)], 1)
        return topo, bad, lens

    def cap_pass(self, q_limit: float) -> int:
        """Split the longest edge of flat ("cap") triangles worse than ``q_limit``."""
        topo, bad, lens = self._bad_triangles(q_limit)
        if len(bad) == 0:
            return 0
        srt = np.sort(lens, axis=1)
        cap = srt[:, 2] ** 2 > srt[:, 0] ** 2 + srt[:, 1] ** 2 - srt[:, 0] * srt[:, 1]  # largest angle > 120
        edges = np.unique(topo.face_edges[bad[cap], lens[cap].argmax(1)])
        return self._split_edges(topo, edges)

    def error_pass(self) -> int:
        """Split edges whose midpoint, or the centroid of a face beside them, is farther from
        the surface than the tolerance (the new vertex goes onto the surface, a feature
        edge's onto its polyline, and onto f = 0 where that is farther than the tolerance:
        :meth:`place`)."""
        s = self.s
        topo = s.topology()
        p, t = s.points, s.triangles
        mid = 0.5 * (p[topo.edges[:, 0]] + p[topo.edges[:, 1]])
        cen = p[t].mean(axis=1)
        pts = np.concatenate([mid, cen])
        near = np.flatnonzero(self.target.estimate(pts) > 0.5 * self.tolerance)  # first order: a filter
        far = near[self.target.distance(pts[near]) > self.tolerance]
        edges = far[far < len(mid)]
        faces = far[far >= len(mid)] - len(mid)
        if len(faces):
            lens = np.stack([np.linalg.norm(p[t[faces, (j + 1) % 3]] - p[t[faces, j]], axis=1) for j in range(3)], 1)
            edges = np.concatenate([edges, topo.face_edges[faces, lens.argmax(1)]])
        return self._split_edges(topo, np.unique(edges))

    def _split_edges(self, topo, cand) -> int:
        s = self.s
        if len(cand) == 0:
            return 0
        a, b = topo.edges[cand, 0], topo.edges[cand, 1]
        length = np.linalg.norm(s.points[a] - s.points[b], axis=1)
        owner = np.concatenate([np.arange(len(cand))] * 2)
        faces = np.concatenate([topo.face0[cand], topo.face1[cand]])
        keep = faces >= 0
        pick = select_independent(len(cand), -length, faces[keep], owner[keep])
        win, length = cand[pick], length[pick]
        a, b = topo.edges[win, 0], topo.edges[win, 1]
        mid = 0.5 * (s.points[a] + s.points[b])
        feat = s.is_feature(topo)[win]
        lid = np.maximum(s.line_id[a], s.line_id[b])
        new = self.place(mid, feat, lid, 0.5 * length)
        ok = np.isin(win, splits_keep_faces(s, topo, win, new)[0])
        win, new, a, b = win[ok], new[ok], a[ok], b[ok]
        done = verified_split(s, topo, win, new, self.normals, **self.check)
        self._count_rejected(len(win) - len(done))
        self.h = np.concatenate([self.h, 0.5 * (self.h[a[done]] + self.h[b[done]])])
        return len(done)

    # --------------------------------------------------------------- collapse
    def collapse_pass(self, cand_mask=None, below: float = COLLAPSE_BELOW, limit_q: float = COLLAPSE_Q,
                      max_collapses: int | None = None) -> int:
        s = self.s
        topo = s.topology()
        p, n = s.points, len(s.points)
        a, b = topo.edges[:, 0], topo.edges[:, 1]
        length = np.linalg.norm(p[a] - p[b], axis=1)
        he = 0.5 * (self.h[a] + self.h[b])
        if cand_mask is None:
            cand = np.flatnonzero(length < below * he)
        else:
            cand = np.flatnonzero(cand_mask)
        if len(cand) == 0:
            return 0
        feat = s.is_feature(topo)[cand]
        a, b = a[cand], b[cand]
        ca, cb = s.vclass[a], s.vclass[b]
        # which end goes: a free end; on a feature edge, a line end (never a corner)
        tiny = length[cand] < 0.25 * he[cand]  # two corners this close are one corner
        # tiny edges between two feature vertices are one crease seen twice: merge them
        remove_b = np.where(feat, (cb == LINE) | (tiny & (cb == CORNER) & (ca == CORNER)),
                            (cb == FREE) | (tiny & (cb == LINE)))
        remove_a = np.where(feat, ca == LINE, (ca == FREE) | (tiny & (ca == LINE)))
        ok = remove_a | remove_b
        rem = np.where(remove_b, b, a)
        kp = np.where(remove_b, a, b)
        both_free = (ca == FREE) & (cb == FREE)
        cand, rem, kp, both_free, length_c = cand[ok], rem[ok], kp[ok], both_free[ok], length[cand][ok]
        if self.half_edge and both_free.any():
            # half-edge collapses (the kept end stays put, so only the ring of the removed
            # end is claimed): both directions of a free edge are candidates
            bf = np.flatnonzero(both_free)
            cand = np.concatenate([cand, cand[bf]])
            rem, kp = np.concatenate([rem, kp[bf]]), np.concatenate([kp, rem[bf]])
            length_c = np.concatenate([length_c, length_c[bf]])
            both_free = np.zeros(len(cand), bool)
        if len(cand) == 0:
            return 0
        nb_ptr, nb = vertex_neighbours(topo.edges, n)
        ok = ~np.isin(rem * n + kp, self.rejected)  # failed the geometric checks this round
        cand, rem, kp, both_free, length_c = cand[ok], rem[ok], kp[ok], both_free[ok], length_c[ok]
        if len(cand) == 0:
            return 0
        # independence first, so the geometric checks run on the winners only. A collapse
        # rewrites the faces around the removed end (and around the kept end when that one
        # moves): two winners whose closed rings are disjoint change disjoint faces and
        # cannot break each other's link condition. Losers of the checks free their rings
        # for another round of selection among the candidates left.
        # Each round takes the shortest live candidate of every removable vertex (its
        # claim is the same whichever edge it uses).
        taken = np.zeros(n, bool)
        accepted = []
        alive = np.ones(len(cand), bool)
        by_vertex = np.lexsort((length_c, rem))  # once: each round keeps its live part, in order
        vf_ptr, vf = vertex_faces(s.triangles, n)  # the faces change only after the last round
        for _ in range(COLLAPSE_ROUNDS):
            live = by_vertex[(alive & ~taken[rem] & ~taken[kp])[by_vertex]]
            if len(live) == 0:
                break
            live = live[np.r_[True, rem[live][1:] != rem[live][:-1]]]
            own_r, nr = gather(nb_ptr, nb, rem[live])
            moving = np.flatnonzero(both_free[live])
            own_k, nk = gather(nb_ptr, nb, kp[live[moving]])
            idx = np.arange(len(live))
            element = np.concatenate([nr, nk, rem[live], kp[live]])
            owner = np.concatenate([own_r, moving[own_k], idx, idx])
            pick = select_independent(len(live), length_c[live], element, owner, rounds=LUBY_ROUNDS, blocked=taken)
            if len(pick) == 0:
                break
            win = live[pick]
            alive[win] = False
            failed, pos = self._collapse_checks(topo, cand[win], rem[win], kp[win], both_free[win], length_c[win],
                                                limit_q, (vf_ptr, vf))
            failed |= ~_link_ok(rem[win], kp[win], topo.n_faces[cand[win]], nb_ptr, nb, n)
            self.rejected = np.concatenate([self.rejected, rem[win[failed]] * n + kp[win[failed]]])
            taken[element[np.isin(owner, pick[~failed])]] = True
            accepted.append((win[~failed], pos[~failed]))
            if failed.sum() < 0.1 * len(win):
                break
        good = np.concatenate([g for g, _ in accepted]) if accepted else np.zeros(0, np.int64)
        if len(good) == 0:
            return 0
        pos = np.concatenate([q for _, q in accepted])
        if max_collapses is not None and len(good) > max_collapses:  # the shortest edges go first
            first = np.argsort(length_c[good], kind="stable")[:max(int(max_collapses), 0)]
            good, pos = good[first], pos[first]
            if len(good) == 0:
                return 0
        gone = np.stack([topo.face0[cand[good]], topo.face1[cand[good]]], axis=1)
        done = verified_collapse(s, kp[good], rem[good], pos, gone, self.normals, **self.check)
        self._count_rejected(len(good) - done)
        return done

    def _collapse_checks(self, topo, cand, rem, kp, both_free, length_c, limit_q, faces_of):
        """(failed flags, new positions of the kept ends) of independent collapses;
        ``faces_of`` is ``vertex_faces`` of the current triangles."""
        s = self.s
        p = s.points
        pos = p[kp].copy()
        if both_free.any():
            mid = 0.5 * (p[rem[both_free]] + p[kp[both_free]])
            pos[both_free] = self.project_free(mid, 0.5 * length_c[both_free])
        # geometry of the new balls
        vf_ptr, vf = faces_of
        own1, f1 = gather(vf_ptr, vf, rem)
        own2, f2 = gather(vf_ptr, vf, kp)
        own = np.concatenate([own1, own2])
        fac = np.concatenate([f1, f2])
        tri = s.triangles[fac]
        has_r = (tri == rem[own][:, None]).any(1)
        has_k = (tri == kp[own][:, None]).any(1)
        stay = ~(has_r & has_k)  # the two faces of the edge go
        own, fac, tri = own[stay], fac[stay], tri[stay]
        old = p[tri]
        newtri = np.where(tri == rem[own][:, None], kp[own][:, None], tri)
        new = p[newtri]
        at_k = newtri == kp[own][:, None]
        new[at_k] = np.repeat(pos[own], at_k.sum(1), axis=0)
        q_old, q_new = quality_of(old), quality_of(new)
        n_old = np.cross(old[:, 1] - old[:, 0], old[:, 2] - old[:, 0])
        n_new = np.cross(new[:, 1] - new[:, 0], new[:, 2] - new[:, 0])
        cosang = np.einsum("ij,ij->i", n_old, n_new) / np.maximum(
            np.sqrt(np.einsum("ij,ij->i", n_old, n_old) * np.einsum("ij,ij->i", n_new, n_new)), 1e-300)
        worst_old = np.full(len(cand), 0.0)
        np.maximum.at(worst_old, own, np.where(np.isfinite(q_old), q_old, 0.0))
        # a degenerate new face is never accepted, even where the ball had one already
        bad = ~np.isfinite(q_new) | (cosang < np.cos(np.radians(MAX_TURN))) | (
            q_new > np.maximum(limit_q, worst_old[own]))
        # no new edge longer than the split threshold
        hk = self.h[kp][own]
        elen = np.sqrt(np.einsum("ijk,ijk->ij", new - np.roll(new, 1, axis=1), new - np.roll(new, 1, axis=1))).max(1)
        bad |= elen > SPLIT_ABOVE * np.maximum(hk, self.h[newtri].max(1))
        # geometric error of the new faces, unless the face was that far already
        check = np.flatnonzero(~bad)
        bad[check] = self.too_far(old[check], new[check])
        return np.bincount(own[bad], minlength=len(cand)) > 0, pos

    # --------------------------------------------------------------- flips
    def flip_pass(self, mode: str, turn: float | None = None) -> int:
        """Flip edges towards valence 6 (``mode="valence"``) or better triangles
        ("quality"), between faces turning by less than ``turn`` degrees (default: the
        feature angle)."""
        s = self.s
        topo = s.topology()
        turn = self.angle if turn is None else turn
        cand = s.flip_candidates_ok(topo, np.arange(len(topo.edges)), np.cos(np.radians(turn)))
        if len(cand) == 0:
            return 0
        p = s.points
        a, b, o0, o1 = topo.edges[cand, 0], topo.edges[cand, 1], topo.opp0[cand], topo.opp1[cand]
        q_old = np.maximum(quality_of(p[np.stack([a, b, o0], 1)]), quality_of(p[np.stack([b, a, o1], 1)]))
        q_new = np.maximum(quality_of(p[np.stack([a, o1, o0], 1)]), quality_of(p[np.stack([o1, b, o0], 1)]))
        if mode == "valence":
            deg = np.bincount(topo.edges.ravel(), minlength=len(p))
            bnd = np.zeros(len(p), bool)
            bnd[topo.edges[topo.n_faces == 1].ravel()] = True
            ideal = np.where(bnd, 4, 6)
            ideal = np.where(s.vclass == CORNER, deg, ideal)

            def cost(va, vb, vc, vd, da, db, dc, dd):
                return ((deg[va] + da - ideal[va]) ** 2 + (deg[vb] + db - ideal[vb]) ** 2
                        + (deg[vc] + dc - ideal[vc]) ** 2 + (deg[vd] + dd - ideal[vd]) ** 2)
            gain = cost(a, b, o0, o1, 0, 0, 0, 0) - cost(a, b, o0, o1, -1, -1, 1, 1)
            q_old, q_new = np.minimum(q_old, 1e300), np.minimum(q_new, 1e300)  # degenerate: finite, worst
            ok = (gain > 0) & (q_new <= np.maximum(q_old, POLISH_Q))
            prio = -gain.astype(float) + 1e-3 * (q_new - q_old)
        else:
            gain = np.minimum(q_old, 1e300) - np.minimum(q_new, 1e300)
            ok = gain > 1e-3
            prio = -gain
        cand, prio = cand[ok], prio[ok]
        if len(cand) == 0:
            return 0
        # two flips may not share a face, nor create the same new edge (two quads with the
        # same opposite pair would give an edge in four triangles)
        _, new_edge = np.unique(edge_key(topo.opp0[cand], topo.opp1[cand]), return_inverse=True)
        idx = np.arange(len(cand))
        element = np.concatenate([topo.face0[cand], topo.face1[cand], len(s.triangles) + new_edge])
        win = cand[select_independent(len(cand), prio, element, np.concatenate([idx, idx, idx]))]
        a, b, o0, o1 = topo.edges[win, 0], topo.edges[win, 1], topo.opp0[win], topo.opp1[win]
        old = np.concatenate([p[np.stack([a, b, o0], 1)], p[np.stack([b, a, o1], 1)]])
        new = np.concatenate([p[np.stack([a, o1, o0], 1)], p[np.stack([o1, b, o0], 1)]])
        far = self.too_far(old, new)
        win = win[~(far[:len(win)] | far[len(win):])]
        done = verified_flip(s, topo, win, self.normals, **self.check)
        self._count_rejected(len(win) - done)
        return done

    # --------------------------------------------------------------- relocation
    def smooth_pass(self, weight: float = 1.0, only=None) -> int:
        s = self.s
        p, t = s.points, s.triangles
        n = len(p)
        corners = p[t]
        area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
        cen = corners.mean(axis=1)
        wsum = np.bincount(t.ravel(), weights=np.repeat(area, 3), minlength=n)
        target_pt = np.stack([np.bincount(t.ravel(), weights=np.repeat(area * cen[:, k], 3), minlength=n)
                              for k in range(3)], axis=1) / np.maximum(wsum, 1e-300)[:, None]
        move = s.vclass == FREE
        if only is not None:
            move &= only
        newp = p.copy()
        free = np.flatnonzero(move)
        if len(free):
            nrm = self.target.normals(p[free])
            d = target_pt[free] - p[free]
            d -= np.einsum("ij,ij->i", d, nrm)[:, None] * nrm
            newp[free] = self.project_free(p[free] + weight * d, 0.5 * self.h[free])
        line = np.flatnonzero(s.vclass == LINE) if only is None else np.flatnonzero((s.vclass == LINE) & only)
        if len(line) and self.lines is not None:
            fe = feature_edges_of(s)
            fe = fe[(s.vclass[fe[:, 0]] >= LINE) & (s.vclass[fe[:, 1]] >= LINE)]
            acc = np.zeros((n, 3))
            cnt = np.bincount(fe.ravel(), minlength=n).astype(float)
            for k in range(3):
                acc[:, k] = np.bincount(fe[:, 0], weights=p[fe[:, 1], k], minlength=n) + np.bincount(
                    fe[:, 1], weights=p[fe[:, 0], k], minlength=n)
            good = line[cnt[line] == 2]
            mid = acc[good] / 2.0
            newp[good] = self.place(p[good] + weight * (mid - p[good]), np.ones(len(good), bool), s.line_id[good],
                                    0.5 * self.h[good])
        moved = np.flatnonzero(np.any(newp != p, axis=1))
        return self._commit(newp, moved)

    def _commit(self, newp, moved) -> int:
        """Accept moves, undoing those that turn a face over or make it much worse, leave
        the tolerance, or (:func:`warpmesh.optimize.embedding.face_violations`) make a face
        cross another one, fold or face inwards. Each round looks again at the faces
        around the vertices the last one moved back."""
        s = self.s
        p, t = s.points, s.triangles
        if len(moved) == 0:
            return 0
        shifted = np.zeros(len(p), bool)
        shifted[moved] = True
        faces = np.flatnonzero(shifted[t].any(1))
        q_old = quality_of(p[t[faces]])
        cos_turn = np.cos(np.radians(MAX_TURN))
        shifted = np.any(newp != p, axis=1)
        n_refused = 0  # vertices moved back by the embedding checks
        local, embed = np.ones(len(faces), bool), np.ones(len(faces), bool)  # still to check
        while True:  # each round undoes at least one vertex: ends at worst with none moved
            bad = np.zeros(len(faces), bool)
            sub = np.flatnonzero(local)
            local[:] = False
            old, new = p[t[faces[sub]]], newp[t[faces[sub]]]
            n_old = np.cross(old[:, 1] - old[:, 0], old[:, 2] - old[:, 0])
            n_new = np.cross(new[:, 1] - new[:, 0], new[:, 2] - new[:, 0])
            cosang = np.einsum("ij,ij->i", n_old, n_new) / np.maximum(
                np.linalg.norm(n_old, axis=1) * np.linalg.norm(n_new, axis=1), 1e-300)
            q_new, q0 = quality_of(new), q_old[sub]
            # no face turns over or gets much worse; none gets worse above SMOOTH_Q_CAP
            b = (cosang < cos_turn) | ((q_new > 2 * q0) & (q_new > COLLAPSE_Q)) | (q_new > np.maximum(q0, SMOOTH_Q_CAP))
            # nor leaves the tolerance (faces whose corners all went back are not looked at)
            live = np.flatnonzero(~b & np.any(new != old, axis=(1, 2)))
            b[live] = self.too_far(old[live], new[live])
            bad[sub] = b
            others = np.zeros(0, np.int64)
            embedding = not bad.any()
            if embedding:
                # the rest: no face crossing another one, folded or facing inwards (the
                # faces that went back too: they may meet a face that moved)
                chk = np.flatnonzero(embed)
                embed[:] = False
                bad[chk], others = face_violations(newp, t, faces[chk], self.normals, partners=True, **self.check)
            undo = np.unique(np.concatenate([t[faces[bad]].ravel(), t[others].ravel()]))
            undo = undo[shifted[undo]]
            if len(undo) == 0:  # all checked, or what fails was there before the moves
                break
            newp[undo] = p[undo]
            shifted[undo] = False
            n_refused += len(undo) if embedding else 0
            back = np.zeros(len(p), bool)
            back[undo] = True
            again = back[t[faces]].any(axis=1)
            local |= again
            embed |= again
        self._count_rejected(n_refused)
        s.points = newp
        return int(shifted.sum())

    def best_position_pass(self, q_limit: float) -> int:
        """Move vertices of bad triangles to the best of a few candidates (ball worst Q)."""
        s = self.s
        p, t = s.points, s.triangles
        n = len(p)
        q = quality_of(p[t])
        bad_v = np.zeros(n, bool)
        bad_v[t[q > q_limit].ravel()] = True
        verts = np.flatnonzero(bad_v & (s.vclass == FREE))
        if len(verts) == 0:
            return 0
        vf_ptr, vf = vertex_faces(t, n)
        own, fac = gather(vf_ptr, vf, verts)
        # independence: no two moved vertices share a face
        worst = np.zeros(len(verts))
        np.maximum.at(worst, own, q[fac])
        win = select_independent(len(verts), -worst, fac, own)
        verts = verts[win]
        own, fac = gather(vf_ptr, vf, verts)
        tri = t[fac]
        here = tri == verts[own][:, None]
        # candidate 1..: equilateral apexes of each face over its opposite edge, averaged
        pts = p[tri]
        rolled = np.argmax(here, axis=1)
        i1, i2 = (rolled + 1) % 3, (rolled + 2) % 3
        r = np.arange(len(tri))
        e1, e2 = pts[r, i1], pts[r, i2]
        nrm = np.cross(e1 - pts[r, rolled], e2 - pts[r, rolled])
        nrm /= np.maximum(np.linalg.norm(nrm, axis=1), 1e-300)[:, None]
        midpt = 0.5 * (e1 + e2)
        perp = np.cross(nrm, e2 - e1)
        apex = midpt + (np.sqrt(3.0) / 2.0) * perp
        nv = len(verts)
        cnt = np.bincount(own, minlength=nv)[:, None]
        ideal = np.stack([np.bincount(own, weights=apex[:, k], minlength=nv) for k in range(3)], 1) / cnt
        area = 0.5 * np.linalg.norm(np.cross(pts[:, 1] - pts[:, 0], pts[:, 2] - pts[:, 0]), axis=1)
        cen = pts.mean(axis=1)
        wsum = np.bincount(own, weights=area, minlength=nv)[:, None]
        cur = p[verts]
        centroid = np.stack([np.bincount(own, weights=area * cen[:, k], minlength=nv) for k in range(3)], 1)
        centroid = np.where(wsum > 0, centroid / np.maximum(wsum, 1e-300), cur)  # all faces flat: stay
        options = [cur]
        for base in (ideal, centroid):
            for w in (1.0, 0.5):
                options.append(cur + w * (base - cur))
        nrm_v = self.target.normals(cur)
        cand_pts = []
        for o in options[1:]:
            d = o - cur
            d -= np.einsum("ij,ij->i", d, nrm_v)[:, None] * nrm_v
            cand_pts.append(cur + d)
        stacked = np.concatenate(cand_pts)
        proj = self.project_free(stacked, np.tile(0.5 * self.h[verts], len(cand_pts)))
        choices = [cur] + np.split(proj, len(cand_pts))
        best_q = np.full(nv, np.inf)
        best = cur.copy()
        for c in choices:
            newpts = pts.copy()
            newpts[here] = c[own]
            qc = quality_of(newpts)
            n_new = np.cross(newpts[:, 1] - newpts[:, 0], newpts[:, 2] - newpts[:, 0])
            flip = np.einsum("ij,ij->i", n_new, nrm) <= 0
            qc[flip] = np.inf
            wq = np.zeros(nv)
            np.maximum.at(wq, own, qc)
            better = wq < best_q - 1e-9
            best_q[better] = wq[better]
            best[better] = c[better]
        newp = p.copy()
        newp[verts] = best
        return self._commit(newp, verts[np.any(best != cur, axis=1)])

    def needle_pass(self, q_limit: float) -> int:
        """Collapse the shortest edge of triangles worse than ``q_limit`` when it is short."""
        topo, bad, lens = self._bad_triangles(q_limit)
        if len(bad) == 0:
            return 0
        j = lens.argmin(1)
        short = lens[np.arange(len(bad)), j] < 0.6 * np.sort(lens, axis=1)[:, 1]
        mask = np.zeros(len(topo.edges), bool)
        mask[topo.face_edges[bad[short], j[short]]] = True
        return self.collapse_pass(cand_mask=mask, limit_q=q_limit)


#: the input's median distance to the target, in tolerances, beyond which the mesh is
#: taken for one of another shape
FAR_FROM_TARGET = 4.0


#: bytes optimize holds per output triangle (the surface, its topology, the checks' copies)
BYTES_PER_TRIANGLE = 1000


def _check_output_size(hfield, points: np.ndarray, area: float, size) -> None:
    """Refuse a size field whose unit mesh (about 4 area / (sqrt(3) h^2) triangles) would
    not fit the memory budget (:mod:`warpmesh._util.budget`)."""
    h = np.asarray(hfield(points), dtype=float)
    expected = 4.0 * area * float(np.mean(1.0 / h ** 2)) / np.sqrt(3.0) if np.all(h > 0) else np.inf
    check_budget(BYTES_PER_TRIANGLE * expected,
                 f"optimize with 'size' = {size!r} (about {expected:.3g} triangles for an area of {area:.3g})",
                 "pass a larger 'size'")


def _check_on_target(target, points: np.ndarray, tolerance: float, *, given: bool = True) -> None:
    """Refuse a mesh that does not lie on the target (a sphere's mesh given a torus):
    projecting it would not optimise it but replace it."""
    d = target.estimate(points)
    if not np.all(np.isfinite(d)):
        raise ValueError("expected a 'shape' defined at the mesh's vertices, got NaN or infinite values at "
                         f"{int((~np.isfinite(d)).sum())} of them")
    median = float(np.median(d))
    if median > FAR_FROM_TARGET * tolerance:
        raise ValueError(f"expected a mesh of 'shape': half its vertices lie farther than {median:.3g} from "
                         f"f = 0, {median / tolerance:.3g} tolerances "
                         f"({'' if given else 'the default, '}{tolerance:.3g}); pass the shape it was meshed from, "
                         "or a larger 'tolerance'")


#: the extent of a mesh that optimize and simplify take: Q_K squares squared lengths, which
#: must stay within float64's range (1e-308..1e308) for every edge of the mesh
SCALE_RANGE = (1e-60, 1e60)


def _check_scale(points: np.ndarray) -> None:
    """Refuse a mesh too small or too large for Q_K in float64 (scale it first)."""
    lo, hi = SCALE_RANGE
    extent = float(np.max(np.ptp(points, axis=0)))
    size = float(np.max(np.abs(points)))
    if not (lo <= extent and size <= hi):
        raise ValueError(f"expected a 'mesh' whose extent lies within [{lo:g}, {hi:g}], got extent {extent:.3g} and "
                         f"largest coordinate {size:.3g}; scale it into that range first (mesh.transform)")


def _run_setup(mesh: MeshLike, shape, bounds, size, tolerance, features, angle, fraction, simplifying):
    require_mesh(mesh)
    tri = mesh.triangles
    if len(tri) == 0 or mesh.dim != 3:
        raise ValueError("expected a 3D mesh with a 'triangle' block for 'mesh'")
    others = sorted(t for t in mesh.cells if t != "triangle")
    if others:  # the result holds triangles only: they would be dropped without a word
        raise ValueError(f"expected a triangle surface for 'mesh', got {others} cells too (surface operators "
                         "return triangles only); pass its surface: wm.Mesh(mesh.points, {'triangle': mesh.triangles})")
    if features is not None and not isinstance(features, bool):
        raise TypeError(f"expected True, False or None for 'features', got {features!r}")
    if not (0.0 < angle < 180.0):
        raise ValueError(f"expected 0 < 'angle' < 180 degrees, got {angle!r}")

    used = np.unique(tri)
    pts = mesh.points
    _check_scale(pts[used])
    # a repeated vertex or a zero area: no operator can shape such a triangle (and Mesh
    # accepts them: files carry collapsed cells)
    flat = degenerate_faces(pts, tri)
    if flat.any():
        i = int(np.flatnonzero(flat)[0])
        raise ValueError(f"expected triangles of non-zero area in 'mesh', got {int(flat.sum())} degenerate ones "
                         f"(the first: triangle {i}, vertices {tri[i].tolist()}); weld coincident points "
                         "(merge) and drop flat triangles first")
    if not is_edge_manifold(tri):
        raise TopologyError("expected an edge-manifold triangle mesh (no edge in more than two triangles)")
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    mean_edge = float(np.linalg.norm(pts[e[:, 0]] - pts[e[:, 1]], axis=1).mean())
    target = as_target(shape, bounds=bounds, reference=(pts, tri))
    area = float(np.linalg.norm(np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]]),
                                axis=1).sum() / 2)
    unit = np.sqrt(4.0 * area / (np.sqrt(3.0) * len(tri)))  # edge of a unit mesh with as many triangles
    tolerance_given = tolerance is not None
    if tolerance is None:
        if simplifying and isinstance(target, VolumeField):
            tolerance = float(target.spacing.min())  # a sampled surface is known to about a sample
        elif simplifying:
            tolerance = 0.05 * mean_edge
        elif size is None or (isinstance(size, (int, float, np.floating, np.integer)) and not isinstance(size, bool)
                              and np.isfinite(size) and size > 0):
            tolerance = 0.25 * (unit if size is None else float(size))
        else:
            tolerance = 0.1 * mean_edge
    if not np.isfinite(tolerance) or tolerance <= 0:
        raise ValueError(f"expected a positive 'tolerance', got {tolerance!r}")
    extent = float(np.linalg.norm(pts[used].max(0) - pts[used].min(0)))
    if simplifying:
        lo = mean_edge
        hfield = size_field("curvature", target, tolerance=tolerance, limits=(lo, 0.1 * extent))
        if fraction is not None:
            if not (0.0 < fraction <= 1.0):
                raise ValueError(f"expected 0 < 'fraction' <= 1, got {fraction!r}")
            hv = hfield(pts[used])
            # a unit mesh has about 4 area / (sqrt(3) h^2) triangles
            expected = 4.0 * area / (np.sqrt(3.0) * np.mean(hv) ** 2)
            hfield = _Scaled(hfield, np.sqrt(max(expected / (fraction * len(tri)), 1e-6)))
    else:
        # default: the edge length of a unit mesh with as many triangles as the input
        hfield = size_field(unit if size is None else size, target, tolerance=tolerance,
                            limits=(1e-3 * mean_edge, extent))
    if not simplifying:
        _check_output_size(hfield, pts[used], area, size)
    if isinstance(target, FunctionTarget):
        _check_on_target(target, pts[used], tolerance, given=tolerance_given)
    refs = None if mesh.cell_refs is None else mesh.cell_refs.get("triangle")
    if refs is not None and target.bounds is not None and set(np.unique(refs)) <= {SURFACE_REF, CAP_REF}:
        refs = None  # cap refs are recomputed on the recovered cap edges (see _cap_refs)
    s = Surface(pts, tri, refs=refs)
    return s, target, hfield, float(tolerance)


def _drive(mesh, shape, *, bounds, size, tolerance, features, angle, iterations, progress, fraction,
           simplifying) -> MeshLike:
    t0 = time.perf_counter()
    s, target, hfield, tol = _run_setup(mesh, shape, bounds, size, tolerance, features, angle, fraction,
                                        simplifying)
    counts = {"creases": 0, "splits": 0, "collapses": 0, "flips": 0, "moves": 0, "rejected": 0}
    start = s.copy()  # the input, kept if nothing better comes out
    q_input = _worst_q(s)
    # the worst Q_K the result may have: the input's (a decimation: up to SIMPLIFY_Q)
    allowed = max(q_input, SIMPLIFY_Q) if simplifying else q_input
    exact = isinstance(target, FunctionTarget)
    if exact:
        # onto the surface, except where a face would turn, fold or cross (later moves retry)
        on = target.project(s.points)
        s.points = revert_violations(s.points, on.copy(), s.triangles, target.normals,
                                     average=not isinstance(target, ImplicitTarget))
        counts["rejected"] += int(np.any(s.points != on, axis=1).sum())
    crease = None
    if features is None:
        # a sampled volume or a mesh has no exact sharp edges: a voxel staircase would read
        # as creases, so by default only an implicit shape's creases are recovered
        features = isinstance(target, ImplicitTarget)
    sharp = features and isinstance(target, ImplicitTarget)
    if sharp:
        crease = snap_corners(s, target, insert_creases(s, target, angle))
        counts["creases"] = int(crease.sum())
        detect_features(s, angle, target, crease)
    elif features:
        detect_features(s, angle)  # the mesh's own dihedral angles
    else:
        detect_features(s, 180.0 - 1e-9)  # boundaries and ref interfaces only
    run = _Run(s, target, hfield, tol, angle, FeatureLines(s), counts=counts, half_edge=simplifying)
    bar = _progress(iterations + POLISH_PASSES, progress, "simplify" if simplifying else "optimize")
    fallback = None  # (label, state): the latest state within the allowed worst Q_K

    def acceptable() -> bool:  # within the allowed worst Q_K; a decimation never ends with more triangles
        return _worst_q(s) <= allowed and not (simplifying and len(s.triangles) > len(start.triangles))

    def keep_if_no_worse(label):
        nonlocal fallback
        if acceptable():
            fallback = (label, s.copy())
    def refresh_creases():
        # close gaps in the crease chains, then re-detect
        crease = snap_corners(s, target, insert_creases(s, target, angle, crease=s.vclass > FREE))
        counts["creases"] += int(crease.sum() - (s.vclass > FREE).sum())
        detect_features(s, angle, target, crease)
        run.lines = FeatureLines(s)

    for it in range(iterations):
        if sharp and 0 < it <= FEATURE_REFRESH:
            refresh_creases()  # the mesh is cleaner now
        run.sizes()
        for _ in range(0 if simplifying else 8):  # decimation only coarsens
            k = run.split_pass()
            counts["splits"] += k
            if k == 0:
                break
        run.rejected = run.rejected[:0]
        for _ in range(40 if simplifying else 12):  # decimation removes most vertices: more passes
            # a collapse removes two triangles (one on a boundary): stop at the requested count
            room = None if fraction is None else (len(s.triangles) - fraction * len(mesh.triangles)) / 2
            k = run.collapse_pass(limit_q=SIMPLIFY_COLLAPSE_Q if simplifying else COLLAPSE_Q, max_collapses=room)
            counts["collapses"] += k
            if k <= 2e-3 * len(s.points):
                break
        s.compact()
        run.h = None
        run.sizes()
        for _ in range(3):
            counts["flips"] += run.flip_pass("valence")
        for _ in range(2):
            counts["moves"] += run.smooth_pass(0.8)
        if isinstance(hfield, _Scaled):
            # a unit mesh of the field has about the expected count; correct what is left
            hfield.scale *= float(np.clip(np.sqrt(len(s.triangles) / (fraction * len(mesh.triangles))), 1.0, 1.25))
        keep_if_no_worse(f"iteration {it + 1}")
        bar.update(1)
    for k in range(POLISH_PASSES):
        run.sizes()
        for _ in range(2):
            counts["flips"] += run.flip_pass("quality")
        run.rejected = run.rejected[:0]
        counts["collapses"] += run.needle_pass(2.0 * POLISH_Q)
        s.compact()
        run.sizes()
        counts["splits"] += run.cap_pass(2.0 * POLISH_Q)
        if k < POLISH_PASSES - 2:  # the last passes smooth what the error splits leave
            counts["splits"] += run.error_pass()
        run.sizes()
        counts["moves"] += run.smooth_pass(0.5)
        for _ in range(2):
            counts["moves"] += run.best_position_pass(POLISH_Q)
        keep_if_no_worse(f"polish {k + 1}")
        bar.update(1)
    # rescue: local quality operators only (no error splits, no smoothing) while a few
    # triangles stay above 2, or above the input's worst (a crease or corner nearby often
    # pins them)
    goal = min(RESCUE_Q, q_input)
    best, best_q = None, _worst_q(s)
    for k in range(RESCUE_PASSES if best_q > goal else 0):
        if best is None:
            best = s.copy()  # the passes may go through worse states: keep the best
        if sharp and k % RESCUE_REFRESH == 0:
            refresh_creases()  # bad triangles are often a gap in a crease chain
        run.sizes()
        # across bends too: the embedding checks and the tolerance still hold every flip
        counts["flips"] += run.flip_pass("quality", turn=RESCUE_TURN)
        run.rejected = run.rejected[:0]
        counts["collapses"] += run.needle_pass(goal)
        s.compact()
        run.sizes()
        counts["splits"] += run.cap_pass(goal)
        run.sizes()
        for _ in range(2):
            counts["moves"] += run.best_position_pass(POLISH_Q)
        s.compact()
        q = _worst_q(s)
        if q < best_q:
            best, best_q = s.copy(), q
        if q <= goal:
            break
    if best is not None:
        s = best
    bar.close()
    s.compact()
    # never worse than allowed: else the latest state that was not, else the input
    kept, reached = "final", _worst_q(s)
    grew = simplifying and len(s.triangles) > len(start.triangles)
    if not acceptable():
        kept, s = fallback if fallback is not None else ("input", start)
        s.compact()
    if kept == "input":  # no progress: say so, the result is no news
        why = (f"fewer triangles than the input's {len(start.triangles)}" if grew and reached <= allowed else
               f"a worst Q_K within {allowed:.3g} (the input's{' or SIMPLIFY_Q' if simplifying else ''}; "
               f"reached {reached:.3g})")
        warnings.warn(f"{'simplify' if simplifying else 'optimize'}: no pass ended with {why}: the input is "
                      "returned unchanged", UserWarning, stacklevel=3)
    before = quality_table(mesh.points, mesh.triangles)
    after = quality_table(s.points, s.triangles)
    info = dict(mesh.info)
    info.update({
        "optimize": {"before": before, "after": after, **counts, "kept": kept,
                     "q_worst_reached": reached, "tolerance": tol,
                     "iterations": iterations, "seconds": time.perf_counter() - t0,
                     "feature_edges": int(len(s.feature_keys)),
                     "corners": int((s.vclass == CORNER).sum())},
    })
    cell_refs = None if mesh.cell_refs is None else {"triangle": s.refs}
    if cell_refs is not None and not s.refs.any() and target.bounds is not None:  # no box: no caps
        cell_refs = {"triangle": _cap_refs(s.points, s.triangles, target.bounds, tol)}
    return type(mesh)(s.points, {"triangle": s.triangles}, cell_refs=cell_refs, info=info)


def _worst_q(s) -> float:
    """Worst Q_K of the working surface (inf if a triangle is degenerate)."""
    return float(quality_of(s.points[s.triangles]).max())


def _cap_refs(points, triangles, bounds, tol):
    """CAP_REF on triangles lying on the box faces (all three vertices on one face), else SURFACE_REF."""
    p = points[triangles]
    lo, hi = bounds
    on = np.zeros(len(triangles), bool)
    for k in range(3):
        for plane in (lo[k], hi[k]):
            on |= np.all(np.abs(p[:, :, k] - plane) <= 1e-3 * tol, axis=1)
    return np.where(on, CAP_REF, SURFACE_REF).astype(np.int64)


def _face_samples(tri: np.ndarray) -> np.ndarray:
    """(k, 4, 3) centroid and edge midpoints of (k, 3, 3) triangles (the corners are the
    vertices, which :meth:`_Run.place` puts within the tolerance)."""
    return np.stack([tri.mean(axis=1), 0.5 * (tri[:, 0] + tri[:, 1]), 0.5 * (tri[:, 1] + tri[:, 2]),
                     0.5 * (tri[:, 2] + tri[:, 0])], axis=1)


class _Scaled:
    """A size field times a scale the driver adjusts towards a triangle count."""

    def __init__(self, base, scale: float):
        self.base, self.scale = base, float(scale)
        self.from_curvature = getattr(base, "from_curvature", False)

    def __call__(self, x):
        return self.base(x) * self.scale


def _link_ok(rem, kp, n_faces, nb_ptr, nb, n) -> np.ndarray:
    """Link condition of the collapses rem -> kp: the ends share exactly the vertices
    opposite the edge (two inside, one on a boundary), so the mesh stays manifold; and
    the kept end is left with valence 3 or more."""
    own_r, nr = gather(nb_ptr, nb, rem)
    own_k, nk = gather(nb_ptr, nb, kp)
    pair = np.concatenate([own_r * n + nr, own_k * n + nk])
    u, c = np.unique(pair, return_counts=True)
    common = np.bincount(u[c == 2] // n, minlength=len(rem))
    deg = np.diff(nb_ptr)
    return (common == np.where(n_faces == 2, 2, 1)) & (deg[rem] + deg[kp] - 4 >= 3)


def _check_iterations(iterations):
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ValueError(f"expected a non-negative integer 'iterations', got {iterations!r}")


class _NoBar:
    def update(self, k):
        pass

    def close(self):
        pass


def _progress(total: int, progress: bool, label: str = "optimize"):
    if not progress:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=label, unit="pass", leave=False)


def optimize(mesh: MeshLike, shape=None, *, bounds=None, size=None, tolerance: float | None = None,
             features: bool | None = None, angle: float = DEFAULT_ANGLE, iterations: int = 8,
             progress: bool = False) -> MeshLike:
    """Optimise a surface mesh for finite elements, every vertex on the exact surface.

    Parameters
    ----------
    mesh : Mesh
        A 3D triangle mesh (closed or open, edge-manifold), without a triangle of zero
        area or with a repeated vertex, of an extent within ``SCALE_RANGE`` (1e-60..1e60:
        Q_K squares squared lengths), lying on ``shape`` (half its vertices within
        ``FAR_FROM_TARGET`` tolerances): each is refused with a ValueError naming it.
    shape : Shape, Expr, VolumeField or None
        The exact surface f = 0 (f > 0 inside). None: the input mesh itself is the
        reference (closest-point projection).
    bounds : box, optional
        The box the mesh was capped on (``mesh_surface(..., bounds=, cap=True)``): the
        surface is then the boundary of {f > 0} clipped to it.
    size : float, "curvature" or callable, optional
        Target edge length: constant (default: that of a unit mesh with as many triangles
        as the input), from
        the curvature so that the chord deviation stays below ``tolerance``, or
        ``h(points) -> (n,)``. A size whose unit mesh would not fit the memory budget
        (``BYTES_PER_TRIANGLE`` per triangle, :mod:`warpmesh._util.budget`) raises
        :class:`~warpmesh.errors.SizeError` before any work.
    tolerance : float, optional
        Largest distance from the surface (at face centroids and edge midpoints) that a
        collapse, flip or move may leave (default 0.25 x the target edge length; 0.1 x the
        mean input edge length with a curvature or callable ``size``).
    features : bool or None
        Keep sharp edges (dihedral above ``angle`` degrees): on an implicit shape they are
        recovered on the exact surface; on a :class:`VolumeField` or a reference mesh they
        are the mesh's own sharp edges. None (default): True for an implicit shape, False
        otherwise (a voxel staircase would read as creases). Open boundaries and region
        interfaces are always kept.
    iterations : int
        Remeshing iterations before the polishing passes.
    progress : bool
        Show a progress bar (tqdm).

    Returns
    -------
    Mesh
        ``info["optimize"]`` holds the before/after statistics (Table 16.1 style: ``np``,
        ``ne``, ``q_mean``, ``q_worst``, ``angle_min``, ...), the operator counts,
        ``rejected`` (operations undone by the embedding checks), ``kept`` ("final",
        the pass returned because the final worst Q_K was above the input's, or
        "input", which also warns: no progress) and ``q_worst_reached`` (the final worst Q_K, returned or not);
        ``stats()`` gives ``q_mean``, ``q_worst``. A shared multi-material surface
        (``interfaces="shared"``) without ``shape`` goes to :func:`warpmesh.optimize.
        label_remesh.optimize_labels` (``size``, ``tolerance``, ``iterations``; the other
        options are refused there, not ignored; junction vertices stay on their input curves).

    Examples
    --------
    >>> import warpmesh as wm
    >>> shape, bounds = wm.example("part")
    >>> mc = wm.mesh_surface(shape, bounds=bounds, resolution=40, method="mc")
    >>> opt = mc.optimize(shape, size=0.08)
    >>> opt.stats()["euler"], opt.stats()["q_worst"] < mc.stats()["q_worst"]
    (-6, True)
    """
    _check_iterations(iterations)
    _check_not_a_number(shape, "size")
    _check_no_shape_for_labels(mesh, shape, "optimize", "optimize_labels")
    if shape is None and "label_above" in getattr(mesh, "cell_data", {}):  # a shared multi-material surface
        from warpmesh.optimize.label_remesh import optimize_labels
        given = [name for name, ignored in (("bounds", bounds is not None), ("features", features is not None),
                                            ("angle", angle is not DEFAULT_ANGLE and angle != DEFAULT_ANGLE))
                 if ignored]
        if given:
            raise ValueError(f"a shared multi-material surface is optimised by optimize_labels, which takes "
                             f"'size', 'tolerance', 'iterations' and 'progress'; got "
                             f"{', '.join(repr(g) for g in given)} too")
        return optimize_labels(mesh, size, tolerance=tolerance, iterations=int(iterations), progress=progress)
    return _drive(mesh, shape, bounds=bounds, size=size, tolerance=tolerance, features=features, angle=angle,
                  iterations=int(iterations), progress=progress, fraction=None, simplifying=False)


def _check_no_shape_for_labels(mesh, shape, verb: str, labelled: str) -> None:
    """A shape given with a shared multi-material surface (``cell_data["label_above"]``) of more than
    one interface would pull every interface onto that shape's surface and drop the labels: refused,
    saying what to do (one interface, a label against the rest, is that shape's surface: allowed)."""
    if shape is None or "label_above" not in getattr(mesh, "cell_data", {}) or "triangle" not in mesh.cells:
        return
    pairs = np.unique(np.column_stack([mesh.cell_refs.get("triangle", np.zeros(len(mesh.cells["triangle"]), np.int64)),
                                       mesh.cell_data["label_above"]["triangle"]]), axis=0)
    if len(pairs) > 1:
        raise ValueError(
            f"this is a shared multi-material surface of {len(pairs)} interfaces (cell_data['label_above']): "
            f"{verb}() without a shape "
            f"runs {labelled}, which keeps every interface and junction curve; a 'shape' would move all its "
            f"interfaces onto one surface and lose the labels. Drop 'shape', or {verb} one label's boundary "
            f"(warpmesh.surface.multilabel.label_boundary(mesh, label)) against its shape")


def _check_not_a_number(shape, keyword: str) -> None:
    """A number given as ``shape`` (``mesh.simplify(0.3)``) is a misplaced keyword: say which."""
    if isinstance(shape, (int, float, np.number)) and not isinstance(shape, (bool, np.bool_)):
        raise TypeError(f"expected a Shape, an expression, a VolumeField or None for 'shape', got the number "
                        f"{shape!r}: give it by name, {keyword}={shape!r}")


def simplify(mesh: MeshLike, shape=None, *, tolerance: float | None = None, fraction: float | None = None,
             bounds=None, features: bool | None = None, angle: float = DEFAULT_ANGLE, iterations: int = 8,
             progress: bool = False) -> MeshLike:
    """Decimate a surface mesh, keeping it within ``tolerance`` of the surface.

    The size field follows the curvature, h = sqrt(8 tolerance / κ) (never below the
    input's mean edge length), so flat regions coarsen most [FG Fig. 16.20]. Edges
    shorter than 4/5 h collapse into one of their ends (half-edge collapses, a maximal
    independent set per pass), each checked for the link condition, quality and the
    tolerance (centroid and edge midpoints of the new faces); flips and tangential
    relocation then even the triangles out under the same checks. ``fraction`` (e.g.
    0.1) scales the field for that fraction of the input triangles and stops there (the
    tolerance may stop it earlier). With ``shape=None`` the error is measured to the
    input mesh. Default tolerance: 0.05 x the mean input edge, one sample spacing for a
    :class:`VolumeField`. What the tolerance holds: every vertex placed (a crease vertex
    too: where its polyline runs off the surface by more, it goes onto f = 0); every new
    face within it at its centroid and edge midpoints, or no farther than the faces it
    replaces, so where the input is farther (a marching-cubes chamfer across a sharp
    corner that the crease recovery does not reach) the output can be as well, never
    farther than the input there. As in :func:`optimize`, no operation may make faces cross,
    fold or face inwards; the result's worst Q_K is at most the input's or ``SIMPLIFY_Q``
    (6), whichever is larger (else the latest pass that was, else the input). A shared
    multi-material surface (``interfaces="shared"``) without ``shape`` goes to
    :func:`warpmesh.optimize.multimaterial.simplify_labels` (``fraction`` default 0.5).

    Examples
    --------
    >>> import warpmesh as wm
    >>> shape, bounds = wm.example("sphere")
    >>> mc = wm.mesh_surface(shape, bounds=bounds, resolution=48, method="mc")
    >>> small = mc.simplify(shape, tolerance=2e-3)
    >>> small.n_cells < 0.5 * mc.n_cells, wm.surface_error(small, shape)["max"] < 2e-3
    (True, True)
    """
    _check_iterations(iterations)
    if fraction is not None and (isinstance(fraction, bool) or not isinstance(fraction, (int, float, np.number))):
        raise TypeError(f"expected a number or None for 'fraction', got {type(fraction).__name__}")
    _check_not_a_number(shape, "fraction")
    _check_no_shape_for_labels(mesh, shape, "simplify", "simplify_labels")
    if shape is None and "label_above" in getattr(mesh, "cell_data", {}):  # a shared multi-material surface
        from warpmesh.optimize.multimaterial import simplify_labels
        given = [name for name, ignored in (("bounds", bounds is not None), ("features", features is not None),
                                            ("angle", angle is not DEFAULT_ANGLE and angle != DEFAULT_ANGLE),
                                            ("iterations", iterations != 8)) if ignored]
        if given:
            raise ValueError(f"a shared multi-material surface is simplified by simplify_labels, which takes "
                             f"'fraction', 'tolerance' and 'progress'; got {', '.join(repr(g) for g in given)} too")
        return simplify_labels(mesh, 0.5 if fraction is None else fraction, tolerance=tolerance, progress=progress)
    return _drive(mesh, shape, bounds=bounds, size=None, tolerance=tolerance, features=features, angle=angle,
                  iterations=int(iterations), progress=progress, fraction=fraction, simplifying=True)
