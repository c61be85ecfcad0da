"""Flips of tetrahedral meshes that never lower the smallest dihedral angle [FG §16.4.3,
"topological modifications"]: 2-3 (two tetrahedra sharing an interior face become three
around the edge joining their opposite vertices) and 3-2 (the three tetrahedra around an
interior edge of degree 3 become two sharing the face of the ring).

Each round lists every candidate (all interior faces, all interior edges of degree 3),
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
>>> s["flips_23"] + s["flips_32"] > 0, s["dihedral_min"] >= s["dihedral_min_before_flips"]
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


def _candidates_32(pts, tets, boundary_keys):
    """Interior edges of degree 3: (old (k, 3) tet ids, new (k, 2, 4) tets)."""
    n = np.int64(len(pts))
    m = len(tets)
    e = np.sort(np.concatenate([tets[:, [i, j]] for i, j in TET_EDGES]), axis=1)
    tid = np.tile(np.arange(m), 6)
    key = e[:, 0] * n + e[:, 1]
    o = np.argsort(key, kind="stable")
    key, e, tid = key[o], e[o], tid[o]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    count = np.diff(np.r_[start, len(key)])
    three = start[(count == 3) & ~np.isin(key[start], boundary_keys)]
    old = np.stack([tid[three], tid[three + 1], tid[three + 2]], axis=1)
    ab = e[three]
    ring = tets[old].reshape(len(three), 12)
    ring = np.where((ring == ab[:, :1]) | (ring == ab[:, 1:]), -1, ring)
    ring = np.sort(ring, axis=1)
    # each ring vertex appears twice among the three tetrahedra: the distinct ones
    u = ring[:, 6:]  # the 6 non-(-1) entries, sorted: c c d d e e
    cde = u[:, ::2]
    ok = (u[:, 0] == u[:, 1]) & (u[:, 2] == u[:, 3]) & (u[:, 4] == u[:, 5])
    new = np.stack([np.concatenate([cde, ab[:, :1]], 1), np.concatenate([cde, ab[:, 1:]], 1)], axis=1)
    return old[ok], new[ok]


def flip_tets(points, tets, tris, *, rounds: int = MAX_ROUNDS, device="cpu"):
    """2-3 and 3-2 flips that raise the smallest dihedral angle where they act.

    Parameters
    ----------
    points : (n, 3) float64
    tets : (m, 4) int, positive
    tris : (k, 3) int, the boundary triangles (their edges are never removed)
    rounds : int

    Returns
    -------
    tets : (m', 4) int64, positive
    info : dict, ``flips_23``, ``flips_32``, ``flip_rounds``
    """
    pts = np.asarray(points, dtype=np.float64)
    tets = np.asarray(tets, dtype=np.int64).copy()
    n = np.int64(len(pts))
    be = unique_edges(tris, TRI_EDGES)
    boundary_keys = be[:, 0] * n + be[:, 1]
    q = tet_quality(pts, tets, device)
    ceiling = float(q[:, 1].max()) if len(q) else 180.0
    done23 = done32 = 0
    r = 0
    for r in range(1, rounds + 1):
        old23, new23 = _candidates_23(pts, tets, q)
        old32, new32 = _candidates_32(pts, tets, boundary_keys)
        olds = [old23, old32]
        news = [new23, new32]
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
        drop = np.zeros(len(tets), bool)
        add = []
        for old, new, idx in zip(olds, news, chosen):
            drop[old[idx].ravel()] = True
            add.append(new[idx].reshape(-1, 4))
        tets = np.concatenate([tets[~drop]] + add)
        q = tet_quality(pts, tets, device)
    return tets, {"flips_23": int(done23), "flips_32": int(done32), "flip_rounds": int(r)}
