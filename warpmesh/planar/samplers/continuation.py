"""Continuation samplers of an implicit curve [FG §16.3.1]: progression and prediction-correction.

Both start from seed points (:func:`warpmesh.planar.samplers.seeds.find_seeds` by default, one or
more on every connected component) and follow the curve instead of enumerating a whole
grid:

* :func:`sample_progression` (in :mod:`warpmesh.planar.samplers.progression`, re-exported here) --
  *methods by progression*: cell tracking on a virtual
  regular grid. The covering-up grows from the cells holding the seeds to the neighbours
  across crossed edges (a sign change of f at the edge's ends), with a visited colouring,
  one frontier wave at a time; f is evaluated at the nodes of visited cells only. The
  visited cells are then segmented by marching squares
  (:mod:`warpmesh.planar.samplers.marching_squares`, ambiguous cells by the asymptotic decider) with roots
  found by bisection.
* :func:`sample_predictor_corrector` -- *methods by prediction-correction*: walkers step
  along the unit tangent t = (f_y, -f_x) / |grad f| (the domain f > 0 on the left; the
  book's H = (-f_y, f_x) of [FG eq. 16.11] is -t), M' = M + h t, and Newton steps (Remark 16.1)
  bring M' back onto f = 0. The step h adapts to the curvature so that the chord deviation
  stays below ``tolerance * h`` (h <= 8 tolerance rho); steps that would jump to another
  branch are rejected and halved.

Example
-------
>>> import warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
>>> pc = sample_predictor_corrector(field, tolerance=1e-2)
>>> pc.info["closed"], pc.info["failures"]
(1, [])
>>> pr = sample_progression(field, resolution=32)
>>> pr.info["evaluations"] < pr.info["grid_nodes"]
True
"""

from __future__ import annotations

import time

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.planar.samplers.seeds import check_count, check_field, check_positive, check_seeds, find_seeds, inside_box
from warpmesh.planar.samplers.progression import sample_progression  # noqa: F401  (re-exported: both continuation methods)
from warpmesh.planar.polyline import components

__all__ = ["sample_predictor_corrector", "sample_progression"]

_TINY = 1.0e-30
#: largest turn of the tangent over one step, whatever the tolerance
MAX_TURN = np.pi / 6
#: Newton iterations of one correction before the step counts as failed
NEWTON_MAX = 8
#: positions below this fraction of the box diagonal are float32 noise of the tape
NOISE = 1.0e-6


# =====================================================================================
# prediction-correction
# =====================================================================================

class _Tracer:
    """All walkers of the predictor-corrector and the polyline they write.

    Walker w sits at vertex ``last[w]`` (position ``pos[w]``) with the oriented unit
    tangent ``tan[w]`` there and travels along ``s[w] * tan[w]``; ``s`` flips from +1 to
    -1 when the walker passes straight through a crossing (a singular point), where the
    oriented tangent field reverses. Segments are written in the orientation of ``tan``
    (f > 0 on the left) whatever the travel direction.
    """

    def __init__(self, field: PlanarField, eps: float, hmin: float, hmax: float, max_points: int):
        self.field, self.eps, self.hmin, self.hmax, self.max_points = field, eps, hmin, hmax, max_points
        self.floor = NOISE * field.size
        self.pts: list[np.ndarray] = []
        self.segs: list[np.ndarray] = []
        self.n_points = 0
        self.singular = np.zeros((0, 2))
        self.singular_id = np.zeros(0, INDEX_DTYPE)
        self.info = {"steps": 0, "rejected": 0, "evaluations": 0, "closed": 0, "open_ends": 0,
                     "failures": [], "crossings": 0, "corners": 0, "joined": 0, "merged": 0,
                     "truncated": False}
        #: below this step, a large turn is taken as a corner of the curve (absolute deviation
        #: <= eps * hmax) instead of being halved down to hmin
        self.h_corner = max(2 * hmin, eps * hmax)
        #: open ends left by failed walkers: position, vertex id, travel sign of a walker
        #: that may join it (the one whose stored segment leaves / enters it)
        self.ends_pos, self.ends_id, self.ends_s = np.zeros((0, 2)), np.zeros(0, INDEX_DTYPE), np.zeros(0)
        #: polyline of the earlier rounds (a walker reaching it splices into it) and the
        #: splices made: (segment index, travel sign of the walker)
        self.prev_pts, self.prev_segs = np.zeros((0, 2)), np.zeros((0, 2), INDEX_DTYPE)
        self.prev_idx = np.zeros(0, INDEX_DTYPE)
        self.merges: list[tuple[int, float]] = []

    # -- evaluation helpers ---------------------------------------------------------------
    def vg(self, p):
        self.info["evaluations"] += len(p)
        return self.field.value_gradient(p)

    def hessian(self, p):
        """Gradient and FD Hessian (central differences of the exact gradient)."""
        d = self.field.fd_step
        off = np.array([[0, 0], [d, 0], [-d, 0], [0, d], [0, -d]])
        _, g = self.vg((p[:, None, :] + off[None]).reshape(-1, 2))
        g = g.reshape(len(p), 5, 2)
        hcol = np.stack([(g[:, 1] - g[:, 2]), (g[:, 3] - g[:, 4])], axis=2) / (2 * d)
        return g[:, 0], 0.5 * (hcol + np.transpose(hcol, (0, 2, 1)))

    def add_points(self, p) -> np.ndarray:
        ids = self.n_points + np.arange(len(p), dtype=INDEX_DTYPE)
        self.pts.append(np.asarray(p, REAL_DTYPE).reshape(-1, 2))
        self.n_points += len(p)
        return ids

    def add_segments(self, a, b, s):
        """Segments a -> b travelled in direction s: stored with f > 0 on the left."""
        a, b = np.asarray(a, INDEX_DTYPE), np.asarray(b, INDEX_DTYPE)
        keep = a != b
        fwd = np.asarray(s)[keep] > 0
        a, b = a[keep], b[keep]
        self.segs.append(np.column_stack([np.where(fwd, a, b), np.where(fwd, b, a)]))

    def polyline(self, alive: bool = False):
        """Points and segments so far; a segment of an earlier round that a walker has
        bypassed from both sides (joined at its end along t, left from its start against
        t: a feature narrower than the step, stepped over by the first walker) is dropped."""
        p = np.concatenate(self.pts) if self.pts else np.zeros((0, 2))
        s = np.concatenate(self.segs) if self.segs else np.zeros((0, 2), INDEX_DTYPE)
        keep = np.ones(len(s), bool)
        if self.merges:
            idx, sign = np.array(self.merges).T
            idx = idx.astype(INDEX_DTYPE)
            keep[np.intersect1d(idx[sign > 0], idx[sign < 0])] = False
        if alive:  # the points and the live mask over all segments written
            return p, keep
        return p, s[keep].astype(INDEX_DTYPE)

    # -- Newton correction (Remark 16.1) ------------------------------------------------
    def newton(self, x, anchor, cap, tol, normal=None, delta=None):
        """Points ``x`` moved onto f = 0, steps capped at ``cap`` (Remark 16.1).

        Each iteration also evaluates the midpoint of (anchor, x) and, when ``normal`` (the
        unit gradient direction near x) is given, the points x +- ``delta`` normal: the
        curve must separate them (f > 0 on the gradient side, f <= 0 on the other), which
        rules out a zero level with f < 0 on both sides (coincident CSG faces). Returns x,
        converged, f and grad at the last iterate and at the last midpoint, and the
        separation flag.
        """
        x = x.copy()
        n = len(x)
        conv, split = np.zeros(n, bool), np.ones(n, bool)
        fx, gx, fm, gm = np.zeros(n), np.zeros((n, 2)), np.zeros(n), np.zeros((n, 2))
        nrm = None if normal is None else normal.copy()
        act = np.arange(n)
        for _ in range(NEWTON_MAX):  # loop over Newton iterations, every walker at once
            if len(act) == 0:
                break
            k = len(act)
            parts = [x[act], 0.5 * (anchor[act] + x[act])]
            if nrm is not None:
                off = delta[act, None] * nrm[act]
                parts += [x[act] + off, x[act] - off]
            f, g = self.vg(np.vstack(parts))
            fx[act], gx[act], fm[act], gm[act] = f[:k], g[:k], f[k:2 * k], g[k:2 * k]
            if nrm is not None:
                split[act] = (f[2 * k:3 * k] > 0) & (f[3 * k:] <= 0)
                gl = np.linalg.norm(gx[act], axis=1)
                nrm[act] = np.where((gl > _TINY)[:, None], gx[act] / np.maximum(gl, _TINY)[:, None], nrm[act])
            g2 = np.einsum("ij,ij->i", gx[act], gx[act])
            step = np.where(g2 > _TINY, fx[act] / np.maximum(g2, _TINY), 0.0)[:, None] * gx[act]
            ln = np.linalg.norm(step, axis=1)
            step *= np.minimum(1.0, cap[act] / np.maximum(ln, _TINY))[:, None]
            x[act] -= step
            done = ln <= tol[act]
            conv[act[done]] = True
            act = act[~done]
        return x, conv, fx, gx, fm, gm, split

    def tangent(self, g):
        gn = np.linalg.norm(g, axis=1)
        return np.column_stack([g[:, 1], -g[:, 0]]) / np.maximum(gn, _TINY)[:, None], gn

    def initial_step(self, p, g):
        """h0 = min(hmax, 0.9 * 8 eps rho) with the curvature from an FD Hessian."""
        _, hess = self.hessian(p)
        t, gn = self.tangent(g)
        kappa = np.abs(np.einsum("ni,nij,nj->n", t, hess, t)) / np.maximum(gn, _TINY)
        h = 0.9 * min(8 * self.eps, MAX_TURN) / np.maximum(kappa, _TINY)
        return np.clip(h, self.hmin, self.hmax)

    # -- singular points ------------------------------------------------------------------
    def find_crossing(self, pos, dirn, h):
        """A crossing (node: grad f = 0, f = 0, indefinite Hessian) ahead of each walker,
        within 1.5 h along its travel line. Returns (found, O)."""
        n = len(pos)
        taus = np.linspace(0.25, 1.5, 6)
        line = pos[:, None, :] + (taus[None, :, None] * h[:, None, None]) * dirn[:, None, :]
        _, g = self.vg(line.reshape(-1, 2))
        best = np.argmin(np.linalg.norm(g, axis=1).reshape(n, -1), axis=1)
        o = line[np.arange(n), best]
        last = np.full(n, np.inf)
        for _ in range(6):  # Newton iterations on grad f = 0, every candidate at once
            g, hess = self.hessian(o)
            det = hess[:, 0, 0] * hess[:, 1, 1] - hess[:, 0, 1] ** 2
            safe = np.abs(det) > _TINY
            inv = np.stack([np.stack([hess[:, 1, 1], -hess[:, 0, 1]], 1),
                            np.stack([-hess[:, 1, 0], hess[:, 0, 0]], 1)], 1) / np.where(safe, det, 1.0)[:, None, None]
            step = np.where(safe[:, None], np.einsum("nij,nj->ni", inv, g), 0.0)
            ln = np.linalg.norm(step, axis=1)
            step *= np.minimum(1.0, 0.5 * h / np.maximum(ln, _TINY))[:, None]
            o = o - step
            last = ln
        _, hess = self.hessian(o)
        det = hess[:, 0, 0] * hess[:, 1, 1] - hess[:, 0, 1] ** 2
        # a node: four sign changes of f around a small circle (the two branches really cross
        # within r; two curves farther apart than r show none)
        r = 3 * self.field.fd_step
        ang = 2 * np.pi * np.arange(16) / 16
        ring = o[:, None, :] + r * np.stack([np.cos(ang), np.sin(ang)], axis=1)[None]
        self.info["evaluations"] += ring.shape[0] * 16
        sgn = self.field.values(ring.reshape(-1, 2)).reshape(n, 16) > 0
        changes = np.count_nonzero(sgn != np.roll(sgn, 1, axis=1), axis=1)
        rel = o - pos
        along = np.einsum("ij,ij->i", rel, dirn)
        lateral = np.abs(rel[:, 0] * dirn[:, 1] - rel[:, 1] * dirn[:, 0])
        found = ((det < 0) & (last <= np.maximum(1e-3 * h, self.floor)) & (along > -self.floor)
                 & (along <= 1.5 * h) & (lateral <= 0.25 * h + self.floor)
                 & (changes == 4))
        return found, o

    def singular_ids(self, o):
        """Vertex ids of crossing points, merged with known ones within the FD step."""
        ids = np.empty(len(o), INDEX_DTYPE)
        for k in range(len(o)):  # loop over crossing events (a few per curve)
            if len(self.singular):
                d = np.linalg.norm(self.singular - o[k], axis=1)
                if d.min() <= self.field.fd_step:
                    ids[k] = self.singular_id[np.argmin(d)]
                    continue
            ids[k] = self.add_points(o[k:k + 1])[0]
            self.singular = np.vstack([self.singular, o[k]])
            self.singular_id = np.append(self.singular_id, ids[k])
        return ids

    # -- the walk -----------------------------------------------------------------------
    def run(self, seeds: np.ndarray):
        """Trace the components through ``seeds`` (one walker each, all advanced at once)."""
        self.prev_pts, alive = self.polyline(alive=True)
        raw = np.concatenate(self.segs) if self.segs else np.zeros((0, 2), INDEX_DTYPE)
        self.prev_idx = np.flatnonzero(alive)  # raw index of each live segment
        self.prev_segs = raw[self.prev_idx]
        _, g0 = self.vg(seeds)
        t0, _ = self.tangent(g0)
        h0 = self.initial_step(seeds, g0)
        seed_id = self.add_points(seeds)
        W = {"pos": seeds.copy(), "tan": t0.copy(), "s": np.ones(len(seeds)), "h": h0.copy(),
             "start": seeds.copy(), "start_dir": t0.copy(), "start_id": seed_id.copy(), "last": seed_id.copy(),
             "gn": np.linalg.norm(g0, axis=1), "steps": np.zeros(len(seeds), INDEX_DTYPE),
             "backward": np.zeros(len(seeds), bool), "active": np.ones(len(seeds), bool),
             "seed_tan": t0.copy(), "seed_h": h0.copy()}
        self.W = W
        eps, floor = self.eps, self.floor
        cos_max = np.cos(MAX_TURN)
        turn_max = min(MAX_TURN, 8 * eps)
        while W["active"].any():  # loop over steps; every active walker advances at once
            if self.n_points > self.max_points:
                self.info["truncated"] = True
                break
            a = np.flatnonzero(W["active"])
            pos, tan, s, h = W["pos"][a], W["tan"][a], W["s"][a], W["h"][a]
            dirn = s[:, None] * tan
            # closing: back within h of the start, heading towards it
            d = W["start"][a] - pos
            dist = np.linalg.norm(d, axis=1)
            close = (~W["backward"][a] & (W["steps"][a] >= 2) & (dist <= h)
                     & (np.einsum("ij,ij->i", d, dirn) > 0.5 * dist)
                     & (np.einsum("ij,ij->i", W["start_dir"][a], dirn) > 0))
            if close.any():  # the closing chord must be as close to the curve as any other
                c = np.flatnonzero(close)
                fm, gm = self.vg(0.5 * (pos[c] + W["start"][a[c]]))
                dev = np.abs(fm) / np.maximum(np.linalg.norm(gm, axis=1), _TINY)
                close[c] = dev <= np.maximum(eps * dist[c], floor)
            if close.any():
                c = a[close]
                self.add_segments(W["last"][c], W["start_id"][c], W["s"][c])
                W["active"][c] = False
                self.info["closed"] += int(len(c))
                keep = ~close
                a, pos, tan, s, h, dirn = a[keep], pos[keep], tan[keep], s[keep], h[keep], dirn[keep]
                if len(a) == 0:
                    continue
            # joining an open end left by a failed walker (ahead, within h, right direction)
            if len(self.ends_id):
                d = self.ends_pos[None, :, :] - pos[:, None, :]
                dist = np.linalg.norm(d, axis=2)
                fit = ((dist <= h[:, None]) & (np.einsum("wej,wj->we", d, dirn) > 0.3 * dist)
                       & (self.ends_s[None, :] == s[:, None]) & (self.ends_id[None, :] != W["last"][a][:, None]))
                dist = np.where(fit, dist, np.inf)
                e = np.argmin(dist, axis=1)
                join = np.isfinite(dist[np.arange(len(a)), e])
                if join.any():
                    j, e = a[join], e[join]
                    _, first = np.unique(e, return_index=True)  # one walker per end
                    j, e = j[first], e[first]
                    self.add_segments(W["last"][j], self.ends_id[e], W["s"][j])
                    self.ends_s[e] = 0.0  # used
                    self.info["joined"] += int(len(j))
                    self.finish(j)
                    keep = W["active"][a]
                    a, pos, tan, s, h, dirn = a[keep], pos[keep], tan[keep], s[keep], h[keep], dirn[keep]
                    if len(a) == 0:
                        continue
            # predict, correct
            pred = pos + h[:, None] * dirn
            tol = np.maximum(0.01 * eps * h, floor)
            normal = np.column_stack([-tan[:, 1], tan[:, 0]])  # grad f / |grad f| at pos
            x, conv, _, gx, fm, gm, split = self.newton(pred, pos, 0.25 * h, tol, normal, 0.05 * h + 4 * floor)
            tnew, gn = self.tangent(gx)
            cosang = np.clip(np.einsum("ij,ij->i", tan, tnew), -1.0, 1.0)
            theta = np.arccos(cosang)
            chord = x - pos
            clen = np.linalg.norm(chord, axis=1)
            cdir = np.einsum("ij,ij->i", chord, dirn) / np.maximum(clen, _TINY)
            dev = np.abs(fm) / np.maximum(np.linalg.norm(gm, axis=1), _TINY)
            moved = np.linalg.norm(x - pred, axis=1)
            safe = conv & split & (gn > 1e-6 * W["gn"][a]) & (clen >= 0.25 * h)
            ok = (safe & (moved <= 0.5 * h) & (cosang > 0) & (theta <= turn_max) & (cdir >= cos_max)
                  & (dev <= np.maximum(eps * clen, floor)))
            # a corner (G1 discontinuity): a large turn that stays at the scale of a tiny step
            corner = (~ok & safe & (h <= self.h_corner) & (moved <= h) & (theta >= 0.5 * MAX_TURN)
                      & (theta <= np.pi - 0.5 * MAX_TURN) & (cdir > 0) & (dev <= eps * self.hmax))
            # crossings: straight on with the tangent flipped, |grad f| collapsing, or no convergence
            cross = np.zeros(len(a), bool)
            susp = np.flatnonzero(~ok & ~corner & ((~conv) | ((cdir >= cos_max) & (cosang < -cos_max)))
                                  | (gn < 0.25 * W["gn"][a]))
            if len(susp):
                found, o = self.find_crossing(pos[susp], dirn[susp], h[susp])
                if found.any():
                    cross[susp[found]] = self.cross(a[susp[found]], o[found])
            self.info["corners"] += int(np.count_nonzero(corner & ~cross))
            ok |= corner
            # accepted ordinary steps
            acc = ok & ~cross
            if acc.any():
                self.advance(a[acc], x[acc], tnew[acc], gn[acc], theta[acc], clen[acc], dev[acc], h[acc])
            # tiny rejected steps: look for the way on around a circle of radius h (a corner
            # the walker sits on, where Newton falls back onto the walker)
            rej = ~ok & ~cross
            small = np.flatnonzero(rej & (h <= self.h_corner))
            if len(small):
                rej[small[self.probe(a[small], h[small])]] = False
            # rejected steps: halve, give up below hmin
            if rej.any():
                r = a[rej]
                self.info["rejected"] += int(len(r))
                W["h"][r] *= 0.5
                fail = r[W["h"][r] < self.hmin]
                if len(fail):
                    self.info["failures"] += W["pos"][fail].tolist()
                    self.ends_pos = np.vstack([self.ends_pos, W["pos"][fail]])
                    self.ends_id = np.concatenate([self.ends_id, W["last"][fail]])
                    self.ends_s = np.concatenate([self.ends_s, -W["s"][fail]])
                    self.finish(fail)

    def probe(self, w, h) -> np.ndarray:
        """Corner steps: the curve's crossing of the circle of radius h around each walker
        that continues its way (f going from - to + counter-clockwise when travelling along
        t, the reverse against it), nearest to the travel direction, found by bisection on
        the arc. Accepted when the chord's midpoint is within eps * hmax of the curve.
        Returns success per walker."""
        W, n = self.W, 32
        pos, s = W["pos"][w], W["s"][w]
        dirn = s[:, None] * W["tan"][w]
        phi0 = np.arctan2(dirn[:, 1], dirn[:, 0])
        phi = phi0[:, None] + 2 * np.pi * np.arange(n + 1)[None] / n - np.pi  # from behind, round
        ring = pos[:, None, :] + h[:, None, None] * np.stack([np.cos(phi), np.sin(phi)], axis=2)
        self.info["evaluations"] += ring.shape[0] * ring.shape[1]
        inside = self.field.values(ring.reshape(-1, 2)).reshape(len(w), n + 1) > 0
        way = np.where(s[:, None] > 0, ~inside[:, :-1] & inside[:, 1:], inside[:, :-1] & ~inside[:, 1:])
        off = np.abs(np.arange(n) + 0.5 - n / 2)[None] + np.where(way, 0, n)  # angular distance to ahead
        k = np.argmin(off, axis=1)
        ok = way[np.arange(len(w)), k] & (off[np.arange(len(w)), k] < 0.4 * n)
        lo, hi = phi[np.arange(len(w)), k], phi[np.arange(len(w)), k + 1]
        in_lo = inside[np.arange(len(w)), k]
        for _ in range(12):  # bisection on the arc, every walker at once
            mid = 0.5 * (lo + hi)
            fm = self.field.values(pos + h[:, None] * np.column_stack([np.cos(mid), np.sin(mid)])) > 0
            self.info["evaluations"] += len(w)
            same = fm == in_lo
            lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
        mid = 0.5 * (lo + hi)
        q = pos + h[:, None] * np.column_stack([np.cos(mid), np.sin(mid)])
        fq, gq = self.vg(np.vstack([q, 0.5 * (pos + q)]))
        tq, gn = self.tangent(gq[: len(w)])
        dev = np.abs(fq[len(w):]) / np.maximum(np.linalg.norm(gq[len(w):], axis=1), _TINY)
        chord = q - pos
        clen = np.linalg.norm(chord, axis=1)
        ok &= (dev <= self.eps * self.hmax) & (s * np.einsum("ij,ij->i", tq, chord) > 0) & (gn > 0)
        if ok.any():
            theta = np.arccos(np.clip(np.einsum("ij,ij->i", W["tan"][w], tq), -1, 1))
            self.info["corners"] += int(ok.sum())
            self.advance(w[ok], q[ok], tq[ok], gn[ok], theta[ok], clen[ok], dev[ok], h[ok])
        return ok

    def advance(self, w, x, tnew, gn, theta, clen, dev, h):
        """Accept steps of walkers ``w`` to ``x``; stop at the box boundary."""
        W, eps = self.W, self.eps
        out = ~inside_box(x, self.field.bounds)
        if out.any():  # leave the box: end on its boundary
            wo = w[out]
            b = self.exit_point(W["pos"][wo], x[out], h[out])
            far = np.linalg.norm(b - W["pos"][wo], axis=1) > self.floor  # else it ends where it is
            bid = self.add_points(b[far])
            self.add_segments(W["last"][wo[far]], bid, W["s"][wo[far]])
            self.info["open_ends"] += int(out.sum())
            self.finish(wo)
        # a step that runs over the start of a closed chain closes it there
        pos = W["pos"][w]
        chord = x - pos
        rel = W["start"][w] - pos
        tau = np.einsum("ij,ij->i", rel, chord) / np.maximum(clen**2, _TINY)
        perp = np.abs(rel[:, 0] * chord[:, 1] - rel[:, 1] * chord[:, 0]) / np.maximum(clen, _TINY)
        over = (~out & ~W["backward"][w] & (W["steps"][w] >= 2) & (tau > 0) & (tau <= 1)
                & (perp <= np.maximum(eps * clen, self.floor) + self.floor))
        if over.any():
            self.add_segments(W["last"][w[over]], W["start_id"][w[over]], W["s"][w[over]])
            W["active"][w[over]] = False
            self.info["closed"] += int(over.sum())
        stay = ~out & ~over
        w, x, tnew, gn, theta, clen, dev, h = (v[stay] for v in (w, x, tnew, gn, theta, clen, dev, h))
        if len(w) == 0:
            return
        if len(self.prev_segs):  # reaching a polyline of an earlier round: splice into it
            hit = _traced_segment(x, tnew, self.prev_pts, self.prev_segs, self.floor, eps * self.hmax)
            m = hit >= 0
            if m.any():
                wm_, seg, sm = w[m], self.prev_segs[hit[m]], W["s"][w[m]]
                # travelling along t: join the segment's end; against t: leave from its start
                self.add_segments(W["last"][wm_], np.where(sm > 0, seg[:, 1], seg[:, 0]), sm)
                self.merges += list(zip(self.prev_idx[hit[m]].tolist(), sm.tolist()))
                self.info["merged"] += int(m.sum())
                self.finish(wm_)
                w, x, tnew, gn, theta, clen, dev, h = (v[~m] for v in (w, x, tnew, gn, theta, clen, dev, h))
                if len(w) == 0:
                    return
        ids = self.add_points(x)
        self.add_segments(W["last"][w], ids, W["s"][w])
        self.info["steps"] += int(len(w))
        kappa = theta / np.maximum(clen, _TINY)
        h_turn = 0.9 * min(8 * eps, MAX_TURN) / np.maximum(kappa, _TINY)
        h_dev = 0.9 * clen * np.sqrt(np.maximum(eps * clen, self.floor) / np.maximum(dev, _TINY))
        W["h"][w] = np.clip(np.minimum.reduce([2 * h, h_turn, h_dev]), self.hmin, self.hmax)
        W["pos"][w], W["tan"][w], W["gn"][w], W["last"][w] = x, tnew, gn, ids
        W["steps"][w] += 1

    def cross(self, w, o) -> np.ndarray:
        """Pass walkers ``w`` straight through the crossings ``o``: M -> O -> Q with Q one
        step beyond O on the branch continuing in the same direction; the travel sign s
        flips when the oriented tangent at Q points backwards. Returns success per walker."""
        W = self.W
        pos, h = W["pos"][w], W["h"][w]
        rel = o - pos
        ln = np.linalg.norm(rel, axis=1)
        d = np.where((ln > self.floor)[:, None], rel / np.maximum(ln, _TINY)[:, None], W["s"][w][:, None] * W["tan"][w])
        pred = o + h[:, None] * d
        q, conv, _, gq, _, _, _ = self.newton(pred, o, 0.25 * h, np.maximum(0.01 * self.eps * h, self.floor))
        tq, gn = self.tangent(gq)
        dq = q - o
        lq = np.linalg.norm(dq, axis=1)
        align = np.einsum("ij,ij->i", d, tq)
        ok = (conv & (np.linalg.norm(q - pred, axis=1) <= 0.5 * h) & (np.abs(align) >= np.cos(MAX_TURN))
              & (np.einsum("ij,ij->i", dq, d) >= np.cos(MAX_TURN) * lq) & (lq > 0.25 * h)
              & inside_box(q, self.field.bounds))
        if not ok.any():
            return ok
        w, o, q, tq, gn, align = w[ok], o[ok], q[ok], tq[ok], gn[ok], align[ok]
        oid = self.singular_ids(o)
        qid = self.add_points(q)
        s_new = np.where(align > 0, 1.0, -1.0)
        self.add_segments(W["last"][w], oid, W["s"][w])
        self.add_segments(oid, qid, s_new)
        W["pos"][w], W["tan"][w], W["gn"][w], W["last"][w], W["s"][w] = q, tq, gn, qid, s_new
        W["steps"][w] += 2
        self.info["crossings"] += int(len(w))
        self.info["steps"] += 2 * int(len(w))
        return ok

    def exit_point(self, pos, x, h):
        """Where the curve leaves the box between pos (inside) and x (outside): the chord's
        exit point, then Newton steps along the box side it crosses."""
        lo, hi = self.field.bounds
        d = x - pos
        with np.errstate(divide="ignore", invalid="ignore"):
            t_lo = np.where(x < lo, (lo - pos) / d, np.inf)
            t_hi = np.where(x > hi, (hi - pos) / d, np.inf)
        t_all = np.minimum(t_lo, t_hi)
        axis = np.argmin(t_all, axis=1)
        n = np.arange(len(pos))
        tau = np.clip(t_all[n, axis], 0.0, 1.0)
        b = pos + tau[:, None] * d
        side = np.where(t_lo[n, axis] <= t_hi[n, axis], lo[axis], hi[axis])
        b[n, axis] = side
        other = 1 - axis
        for _ in range(NEWTON_MAX):  # 1D Newton along the crossed side, every exit at once
            f, g = self.vg(b)
            gu = g[n, other]
            step = np.where(np.abs(gu) > _TINY, f / np.where(np.abs(gu) > _TINY, gu, 1.0), 0.0)
            step = np.clip(step, -0.25 * h, 0.25 * h)
            b[n, other] = np.clip(b[n, other] - step, lo[other], hi[other])
            if np.all(np.abs(step) <= self.floor):
                break
        return b

    def finish(self, w):
        """Walkers ``w`` stop; a forward walker hands over to a backward one from its seed."""
        W = self.W
        W["active"][w] = False
        fw = w[~W["backward"][w]]
        if len(fw) == 0:
            return
        new = {"pos": W["start"][fw], "tan": W["seed_tan"][fw], "s": -np.ones(len(fw)), "h": W["seed_h"][fw],
               "start": W["start"][fw], "start_dir": -W["seed_tan"][fw], "start_id": W["start_id"][fw],
               "last": W["start_id"][fw], "gn": W["gn"][fw] * 0 + np.inf, "steps": np.zeros(len(fw), INDEX_DTYPE),
               "backward": np.ones(len(fw), bool), "active": np.ones(len(fw), bool),
               "seed_tan": W["seed_tan"][fw], "seed_h": W["seed_h"][fw]}
        _, g = self.vg(new["pos"])
        new["gn"] = np.linalg.norm(g, axis=1)
        W["backward"][fw] = True  # the forward walker's backward twin is spawned once
        for k in W:
            W[k] = np.concatenate([W[k], new[k]])


def _traced_segment(q, tangents, points, segments, floor, slack) -> np.ndarray:
    """For each point ``q`` on the curve (oriented tangent ``tangents``), the index of a
    traced segment it lies on, or -1: within a tenth of the segment's length (or ``slack``,
    the absolute error allowed at corners) of a segment running the same way. Two different
    components facing each other run opposite ways (the domain lies between them, or
    outside both), so a point of a nearby component is not taken for a traced one."""
    from scipy.spatial import cKDTree

    out = np.full(len(q), -1, INDEX_DTYPE)
    if len(segments) == 0 or len(q) == 0:
        return out
    a, b = points[segments[:, 0]], points[segments[:, 1]]
    d = b - a
    ln = np.linalg.norm(d, axis=1)
    # candidate pairs: points within half the longest segment (plus the slack) of a midpoint
    reach = 0.6 * float(ln.max()) + slack + 4 * floor
    pairs = cKDTree(q).sparse_distance_matrix(cKDTree(0.5 * (a + b)), reach, output_type="ndarray")
    i, j = pairs["i"].astype(INDEX_DTYPE), pairs["j"].astype(INDEX_DTYPE)
    t = np.clip(np.einsum("nj,nj->n", q[i] - a[j], d[j]) / np.maximum(ln[j] ** 2, _TINY), 0.0, 1.0)
    dist = np.linalg.norm(q[i] - (a[j] + t[:, None] * d[j]), axis=1)
    same_way = np.einsum("nj,nj->n", d[j], tangents[i]) > 0.0
    hit = same_way & (dist <= np.maximum(0.1 * ln[j], slack) + 4 * floor)
    i, j, dist = i[hit], j[hit], dist[hit]
    order = np.argsort(-dist)  # the nearest segment written last
    out[i[order]] = j[order]
    return out


def sample_predictor_corrector(field: PlanarField, *, tolerance: float = 1e-3, seeds=None,
                               hmin: float | None = None, hmax: float | None = None,
                               max_points: int = 100_000) -> CurveSample:
    """Curve points by prediction-correction continuation [FG §16.3.1, eq. 16.11, Fig. 16.6].

    From each seed a walker predicts M' = M + h t(M) along the unit tangent
    t = (f_y, -f_x) / |grad f| (f > 0 on the left) and corrects M' by Newton steps
    (Remark 16.1, each capped at h / 4). A step is **rejected** and h halved when Newton
    does not converge in ``NEWTON_MAX`` iterations, the correction moves more than h / 2,
    the tangent turns by more than ``min(8 tolerance, 30 deg)``, the chord leaves the
    predicted direction by more than 30 deg, the new tangent is reversed (t_i . t_i+1 < 0:
    a jump to another branch), the chord's midpoint lies farther than ``tolerance``
    times the chord from the curve, or the curve does not separate x +- h/20 grad f/|grad f|
    (a zero level with f < 0 on both sides, as where CSG faces coincide). Accepted steps set the next h from the measured turn
    (h <= 8 tolerance rho, rho the radius of curvature: the chord deviation is then
    delta = h^2 / (8 rho) <= tolerance * h), at most doubling, within [hmin, hmax].

    Parameters
    ----------
    field : PlanarField
        The curve's function and box.
    tolerance : float
        Relative chord deviation eps: delta <= eps * h on every segment (down to the
        float32 noise of the tape, about 1e-6 of the box diagonal).
    seeds : (k, 2) array_like, optional
        Start points, projected onto the curve by Newton steps of at most hmax; those that
        do not reach it (|f| / |grad f| > 1e-4 of the box diagonal) or leave the box are
        dropped.
        Default: :func:`~warpmesh.planar.samplers.seeds.find_seeds`, whose clusters let walkers on
        different components run together.
    hmin, hmax : float, optional
        Step bounds; default 1e-6 and 1/32 of the box diagonal.
    max_points : int
        Stop (``info["truncated"]``) beyond this many points.

    Returns
    -------
    CurveSample
        Points in walking order per component, directed segments (f > 0 on the left).
        ``info``: ``"components"`` (of the polyline), ``"walkers"`` (started from seeds),
        ``"merged"`` (walkers that reached an earlier round's polyline and were spliced
        into it), ``"closed"``,
        ``"open_ends"`` (chains stopped on the box boundary), ``"failures"`` (points
        where h fell below hmin), ``"joined"`` (walkers that reached the open end a failed
        one left), ``"crossings"`` and ``"singular_points"`` (crossings passed straight
        through), ``"corners"``, ``"steps"``, ``"rejected"``, ``"evaluations"``,
        ``"rounds"``, ``"seeds"``, ``"seeds_skipped"``, ``"truncated"``, ``"hmin"``,
        ``"hmax"``, ``"time"``.

    Raises
    ------
    TypeError
        ``field`` is not a PlanarField.
    ValueError
        ``tolerance``, ``hmin`` or ``hmax`` not positive numbers, ``hmin >= hmax``,
        ``max_points`` not a positive integer, ``seeds`` not an (k, 2) array.

    Notes
    -----
    *Closing*: a walker that comes back within h of its start point, heading towards it
    (with the closing chord within ``tolerance`` of the curve), or whose step runs over its
    start point, closes its chain. *Corners* (G1 discontinuities of CSG curves): below a
    step of ``tolerance * hmax`` a turn of more than 15 deg is accepted as a corner, or the
    way on is found where the curve crosses a circle of radius h around the walker; such
    chords deviate by at most ``tolerance * hmax`` (absolute, not relative).
    *Failures*: a walker whose h falls below hmin stops (reported in ``"failures"``), its
    twin traces the other way, and later walkers that reach the open end join it.
    *Box boundary*: a walker leaving the box stops on the boundary (a
    Newton search along the side it crosses) and a second walker traces the other way from
    the seed, so an open component is one chain with both ends on the boundary.
    *Singular points*: when a step is rejected (or |grad f| collapses), a crossing ahead is
    looked for (Newton on grad f = 0 with an FD Hessian, an indefinite Hessian, and four
    sign changes of f around a circle of radius 3 ``fd_step``: branches closer than that
    count as crossing). The walker then passes straight through it,
    M -> O -> Q, keeping its travel direction; on a lemniscate the oriented tangent
    reverses there, so the walker travels the second lobe against t (``s = -1``) while its
    segments are still written with f > 0 on their left. The crossing O is one vertex with
    two segments in and two out: a closed figure-eight without self-intersection.
    *Components*: rounds start one walker per seed cluster (all advanced together: the
    Python loop is over steps, every active walker moving at once); seeds lying on a traced
    polyline (within a tenth of a segment of a segment running the same way) are skipped,
    so each component is traced once. User seeds form one cluster (one walker per round).
    A feature narrower than the step (a thin spike) can be stepped over by the first
    walker; its seeds then start a walker in a later round, which stops where it reaches
    the earlier polyline (running the same way) and splices into it: the segment bypassed
    from both sides is dropped.
    *Cost*: about (total turning) / (7 tolerance) steps per component when hmax does not
    bind (~900 for a convex closed curve at 1e-3), two or three tape evaluations per step.

    Examples
    --------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> two = wm.cassini(1.0, 0.95)
    >>> s = sample_predictor_corrector(PlanarField(two, ((-2, -1), (2, 1))), tolerance=1e-2)
    >>> s.info["components"], s.info["closed"]
    (2, 2)
    """
    t_start = time.perf_counter()
    field = check_field(field)
    eps = check_positive(tolerance, "tolerance")
    hmax = field.size / 32 if hmax is None else check_positive(hmax, "hmax")
    hmin = NOISE * field.size if hmin is None else check_positive(hmin, "hmin")
    if hmin >= hmax:
        raise ValueError(f"expected 'hmin' < 'hmax', got hmin={hmin!r}, hmax={hmax!r}")
    max_points = check_count(max_points, "max_points")
    if seeds is None:
        seeds, sinfo = find_seeds(field)
        cluster = sinfo["cluster"]
        seed_evals = sinfo["evaluations"]
    else:
        seeds = check_seeds(seeds, field)
        seeds = field.project(seeds, max_step=hmax)
        seeds = seeds[inside_box(seeds, field.bounds) & (field.estimate(seeds) <= 1e-4 * field.size)]
        cluster = np.zeros(len(seeds), INDEX_DTYPE)
        seed_evals = 0
    tracer = _Tracer(field, eps, hmin, hmax, max_points)
    info = tracer.info
    _, g = tracer.vg(seeds)
    tangents, gn = tracer.tangent(g)
    # well-conditioned seeds first in each cluster (away from singular points)
    usable = gn > 1e-3 * (np.median(gn) if len(gn) else 0.0)
    order = np.lexsort((-gn, cluster))
    order = order[usable[order]]
    remaining = order
    rounds, started, skipped = 0, 0, int(np.count_nonzero(~usable))
    while len(remaining) and not info["truncated"]:  # loop over rounds: one walker per cluster
        p, s = tracer.polyline()
        on = _traced_segment(seeds[remaining], tangents[remaining], p, s, tracer.floor, eps * hmax) >= 0
        skipped += int(np.count_nonzero(on))
        remaining = remaining[~on]
        if len(remaining) == 0:
            break
        _, first = np.unique(cluster[remaining], return_index=True)
        pick = remaining[first]
        tracer.run(seeds[pick])
        started += len(pick)
        rounds += 1
        remaining = remaining[~np.isin(remaining, pick)]  # keeps the order
    points, segments = tracer.polyline()
    info.update(components=components(segments, len(points))[0], walkers=int(started), rounds=rounds, seeds=int(len(seeds)), seeds_skipped=skipped,
                singular_points=tracer.singular.tolist(), hmin=hmin, hmax=hmax, seed_evaluations=seed_evals,
                time=time.perf_counter() - t_start)
    return CurveSample(points, segments, info)
