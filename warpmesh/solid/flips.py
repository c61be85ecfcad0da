"""Flips of tetrahedral meshes that never lower the smallest dihedral angle [FG §16.4.3,
"topological modifications"]: 2-3 (two tetrahedra sharing an interior face become three
around the edge joining their opposite vertices), 3-2 (the three tetrahedra around an
interior edge of degree 3 become two sharing the face of the ring) and 4-4 (the four
tetrahedra around an interior edge of degree 4 fill an octahedron whose axis is that edge;
they become the four around one of the two diagonals of the ring instead, whichever
gains more).

Each round lists every candidate (all interior faces, all interior edges of degree 3 and 4),
keeps those whose new tetrahedra are positive, fill the same volume (so the new edge or face
crosses the old one), raise the smallest dihedral angle among the tetrahedra they replace
and keep the largest below the mesh's largest; then applies, per tetrahedron, only the
candidate of largest gain (no two applied flips share a tetrahedron). The boundary is not
touched. Rounds repeat until none is left or ``MAX_ROUNDS``.

Example
-------
>>> import warpmesh as wm
>>> vol = wm.mesh_domain(wm.example("part")[0], bounds=wm.example("part")[1], size=0.12, flips=True)
>>> s = vol.stats()
>>> s["flips_23"] + s["flips_32"] + s["flips_44"] > 0, s["dihedral_min"] >= s["dihedral_min_before_flips"]
(True, True)
"""

from __future__ import annotations

import numpy as np

from warpmesh.solid.adjacency import TET_EDGES, TRI_EDGES, unique_edges
from warpmesh.solid.dihedral import tet_quality

__all__ = ["flip_tets", "MAX_ROUNDS"]

MAX_ROUNDS = 8
#: the faces of a tetrahedron (opposite vertex 0, 1, 2, 3)
_FACES = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))
_GAIN = 1e-6  # degrees: a flip must raise the local smallest angle by more than this


def _positive(pts, t):
    """Tetrahedra (k, 4) with the last two vertices swapped where the volume is negative;
    returns (tets, |6 volume|)."""
    p = pts[t]
    v = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
    t = t.copy()
    t[v < 0] = t[v < 0][:, [0, 1, 3, 2]]
    return t, np.abs(v)


def _candidates_23(pts, tets, q):
    """Interior faces: (old (k, 2) tet ids, new (k, 3, 4) tets)."""
    m = len(tets)
    n = np.int64(len(pts))
    f = np.concatenate([tets[:, list(fc)] for fc in _FACES])
    opp = np.concatenate([tets[:, k] for k in range(4)])
    tid = np.tile(np.arange(m), 4)
    s = np.sort(f, axis=1)
    key = (s[:, 0] * n + s[:, 1]) * n + s[:, 2]
    o = np.argsort(key, kind="stable")
    key, s, opp, tid = key[o], s[o], opp[o], tid[o]
    pair = np.flatnonzero(key[1:] == key[:-1])
    a, b, c = s[pair, 0], s[pair, 1], s[pair, 2]
    d, e = opp[pair], opp[pair + 1]
    new = np.stack([np.stack([a, b, d, e], 1), np.stack([b, c, d, e], 1), np.stack([c, a, d, e], 1)], axis=1)
    return np.stack([tid[pair], tid[pair + 1]], axis=1), new


def _edge_fans(tets, n, boundary_keys, degree: int):
    """Interior edges in exactly ``degree`` tetrahedra: (edge (k, 2), tet ids (k, degree))."""
    m = len(tets)
    e = np.sort(np.concatenate([tets[:, [i, j]] for i, j in TET_EDGES]), axis=1)
    tid = np.tile(np.arange(m), 6)
    key = e[:, 0] * n + e[:, 1]
    o = np.argsort(key, kind="stable")
    key, e, tid = key[o], e[o], tid[o]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    count = np.diff(np.r_[start, len(key)])
    first = start[(count == degree) & ~np.isin(key[start], boundary_keys)]
    return e[first], np.stack([tid[first + i] for i in range(degree)], axis=1)


def _ring(tets, old, ab):
    """The vertices other than the edge's, each tetrahedron's pair: (k, degree, 2)."""
    ring = tets[old]  # (k, degree, 4)
    off = (ring != ab[:, None, :1]) & (ring != ab[:, None, 1:])
    return np.sort(np.where(off, ring, -1), axis=2)[:, :, 2:]


def _candidates_32(pts, tets, boundary_keys):
    """Interior edges of degree 3: (old (k, 3) tet ids, new (k, 2, 4) tets)."""
    ab, old = _edge_fans(tets, np.int64(len(pts)), boundary_keys, 3)
    u = np.sort(_ring(tets, old, ab).reshape(len(old), 6), axis=1)
    # each ring vertex appears twice among the three tetrahedra: c c d d e e
    cde = u[:, ::2]
    ok = (u[:, 0] == u[:, 1]) & (u[:, 2] == u[:, 3]) & (u[:, 4] == u[:, 5]) & (u[:, 0] >= 0)
    new = np.stack([np.concatenate([cde, ab[:, :1]], 1), np.concatenate([cde, ab[:, 1:]], 1)], axis=1)
    return old[ok], new[ok]


def _candidates_44(pts, tets, boundary_keys):
    """Interior edges of degree 4: (old (2k, 4) tet ids, new (2k, 4, 4) tets), the two
    diagonals of each edge's ring as two candidates (at most one is applied: they share
    their tetrahedra)."""
    n = np.int64(len(pts))
    ab, old = _edge_fans(tets, n, boundary_keys, 4)
    pairs = _ring(tets, old, ab)  # (k, 4, 2): the ring's edges
    u = np.sort(pairs.reshape(len(old), 8), axis=1)
    # a closed ring of 4: each vertex twice, c c d d e e f f
    ok = (u[:, 0] == u[:, 1]) & (u[:, 2] == u[:, 3]) & (u[:, 4] == u[:, 5]) & (u[:, 6] == u[:, 7]) & (u[:, 0] >= 0)
    ab, old, pairs, v = ab[ok], old[ok], pairs[ok], u[ok][:, ::2]
    ring_keys = pairs[..., 0] * n + pairs[..., 1]
    # the diagonals: the pairing of the 4 vertices none of whose pairs is a ring edge
    choices = (((0, 1), (2, 3)), ((0, 2), (1, 3)), ((0, 3), (1, 2)))
    diag = np.zeros((len(old), 2, 2), np.int64)
    found = np.zeros(len(old), bool)
    for (i, j), (k, l) in choices:
        hit = ~((ring_keys == (v[:, i] * n + v[:, j])[:, None]).any(1) | (ring_keys == (v[:, k] * n + v[:, l])[:, None]).any(1))
        sel = hit & ~found
        diag[sel] = np.stack([v[sel][:, [i, j]], v[sel][:, [k, l]]], axis=1)
        found |= hit
    ab, old, diag = ab[found], old[found], diag[found]
    a, b = ab[:, :1], ab[:, 1:]
    news = []
    for d in (0, 1):  # new axis diag[d], the other diagonal's ends around it
        p, q = diag[:, d, :1], diag[:, d, 1:]
        r, s = diag[:, 1 - d, :1], diag[:, 1 - d, 1:]
        news.append(np.stack([np.concatenate(c, 1) for c in ((p, q, r, a), (p, q, r, b), (p, q, s, a), (p, q, s, b))],
                             axis=1))
    return np.concatenate([old, old]), np.concatenate(news)


def flip_tets(points, tets, tris, *, rounds: int = MAX_ROUNDS, device="cpu"):
    """2-3, 3-2 and 4-4 flips that raise the smallest dihedral angle where they act.

    Parameters
    ----------
    points : (n, 3) float64
    tets : (m, 4) int, positive
    tris : (k, 3) int, the boundary triangles (their edges are never removed)
    rounds : int

    Returns
    -------
    tets : (m', 4) int64, positive
    info : dict, ``flips_23``, ``flips_32``, ``flips_44``, ``flip_rounds``
    """
    pts = np.asarray(points, dtype=np.float64)
    tets = np.asarray(tets, dtype=np.int64).copy()
    if not len(tets):  # nothing to flip (e.g. a region of bad tetrahedra that came out empty)
        return tets.reshape(0, 4), {"flips_23": 0, "flips_32": 0, "flips_44": 0, "flip_rounds": 0}
    n = np.int64(len(pts))
    be = unique_edges(tris, TRI_EDGES)
    boundary_keys = be[:, 0] * n + be[:, 1]
    q = tet_quality(pts, tets, device)
    ceiling = float(q[:, 1].max()) if len(q) else 180.0
    done23 = done32 = done44 = 0
    r = 0
    for r in range(1, rounds + 1):
        old23, new23 = _candidates_23(pts, tets, q)
        old32, new32 = _candidates_32(pts, tets, boundary_keys)
        old44, new44 = _candidates_44(pts, tets, boundary_keys)
        olds = [old23, old32, old44]
        news = [new23, new32, new44]
        gains, keep = [], []
        for old, new in zip(olds, news):
            k = new.shape[1]
            flat, vol = _positive(pts, new.reshape(-1, 4))
            qn = tet_quality(pts, flat, device).reshape(len(new), k, 4)
            new[:] = flat.reshape(len(new), k, 4)
            p = pts[tets[old.ravel()]]
            vo = np.abs(np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                                  p[:, 3] - p[:, 0])).reshape(len(old), old.shape[1]).sum(axis=1)
            fills = np.abs(vol.reshape(len(new), k).sum(axis=1) - vo) <= 1e-9 * np.maximum(vo, 1e-300)
            before = q[old, 0].min(axis=1)
            after = qn[..., 0].min(axis=1)
            ok = fills & (qn[..., 3] > 0).all(axis=1) & (qn[..., 1].max(axis=1) <= ceiling) & (after > before + _GAIN)
            gains.append(np.where(ok, after - before, -np.inf))
            keep.append(ok)
        # per tetrahedron, the candidate of largest gain
        best = np.full(len(tets), -np.inf)
        for old, g in zip(olds, gains):
            np.maximum.at(best, old.ravel(), np.repeat(g, old.shape[1]))
        chosen = []
        taken = np.zeros(len(tets), bool)
        for old, g, ok in zip(olds, gains, keep):
            sel = ok & (best[old] == g[:, None]).all(axis=1)
            # ties between candidates of equal gain: first come (in order), no tetrahedron twice
            idx = np.flatnonzero(sel)
            order = np.argsort(old[idx].min(axis=1), kind="stable")
            idx = idx[order]
            flat = old[idx].ravel()
            first = np.zeros(len(flat), bool)
            _, pos = np.unique(flat, return_index=True)
            first[pos] = True
            fine = first.reshape(len(idx), old.shape[1]).all(axis=1) & ~taken[old[idx]].any(axis=1)
            idx = idx[fine]
            taken[old[idx].ravel()] = True
            chosen.append(idx)
        if not sum(len(c) for c in chosen):
            break
        done23 += len(chosen[0])
        done32 += len(chosen[1])
        done44 += len(chosen[2])
        drop = np.zeros(len(tets), bool)
        add = []
        for old, new, idx in zip(olds, news, chosen):
            drop[old[idx].ravel()] = True
            add.append(new[idx].reshape(-1, 4))
        tets = np.concatenate([tets[~drop]] + add)
        q = tet_quality(pts, tets, device)
    return tets, {"flips_23": int(done23), "flips_32": int(done32), "flips_44": int(done44), "flip_rounds": int(r)}
