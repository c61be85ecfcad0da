"""Pockets of the rest that lattice cleaving encloses inside the meshed regions, filled.

Cleaving (:mod:`warpmesh.solid.regions`) gives each lattice edge one cut point. Where an
edge crosses three codes (a layer thinner than the edge between a region and the rest,
say), the middle code's share goes half to each end, so a piece of that layer near a node
of the rest becomes rest; where the edges around that node have their cut points snapped
onto it, the pieces of the layer close over that piece. The mesh then has a cavity: a
closed shell of boundary triangles, inside the regions, joined to the outer boundary at
one vertex at most, around a volume the labels give to a region (measured: 12 such
cavities in 2 of 12 random 4-box label volumes at h = 2 voxels; the two-region block of
``tests/solid/test_pockets.py``, a volume of 0.0133 voxel each). A solver sees a tiny
traction-free hole, and the boundary is not a manifold where the cavity touches it.

:func:`fill_pockets` finds them and fills them: the boundary triangles (those naming the
rest) are split into edge-connected shells, oriented out of the regions; a shell of
negative enclosed volume is a cavity. The rest pieces of the cleaved tetrahedra whose tet
points lie on a cavity's shell are made (the fans' segments of the rest, which cleaving
drops), joined through their shared faces; a set of them that the shell closes (every face
shared by two pieces, or by a piece and a shell triangle) and that holds no sample of the
rest (the labels say the cavity is not there: a cavity the labels do hold, a rest voxel
inside the tissue, is kept) becomes tetrahedra of the code most of its shell faces, and the
shell's triangles become interior (that code on both sides: dropped) or interfaces with
the other codes around it (re-oriented from the lower code's side). Pieces of a positive
tetrahedron's fan are positive, so the filled mesh stays positive and conforming.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> labels = np.zeros((14, 12, 12), dtype=np.uint8)
>>> labels[2:9, 2:10, 2:10] = 1
>>> labels[7:12, 3:9, 3:9] = 2
>>> m = wm.mesh_domain(labels, labels="all", size=2.0)
>>> m.info["filled_pockets"], m.stats()["components"], m.stats()["euler"]
(12, 1, 2)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components as graph_components

from warpmesh.cells.topology import connected_components

__all__ = ["fill_pockets"]

#: the faces of a piece (t, f, a, b) as given by the fans: any three of its corners
_PIECE_FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))


#: rounds of growing a pocket's rows across its open lattice faces
FLOOD_ROUNDS = 8


def _sets(pieces: np.ndarray, shell: np.ndarray):
    """Pieces and shell triangles as the nodes of a graph, joined where a face is shared by
    two of them: (n_p, n_t, owner of each face, its group, the groups' sizes, each node's
    set, the number of sets, which sets are open: a face in one node, or in three or more)."""
    n_p, n_t = len(pieces), len(shell)
    faces = np.concatenate([pieces[:, list(f)] for f in _PIECE_FACES] + [shell])
    owner = np.concatenate([np.tile(np.arange(n_p), 4), n_p + np.arange(n_t)])
    used, local = np.unique(faces, return_inverse=True)  # few vertices: one int64 key per face
    keys = np.sort(local.reshape(-1, 3), axis=1)
    n = np.int64(len(used))
    _, group, count = np.unique((keys[:, 0] * n + keys[:, 1]) * n + keys[:, 2], return_inverse=True,
                                return_counts=True)
    group = group.reshape(-1)
    order = np.argsort(group, kind="stable")
    pair_at = np.flatnonzero(count[group[order]] == 2)
    pair_at = pair_at[::2]  # the first member of each group of two (a group's members are adjacent)
    u, v = owner[order[pair_at]], owner[order[pair_at + 1]]
    n = n_p + n_t
    n_sets, set_of = graph_components(coo_matrix((np.ones(len(u)), (u, v)), shape=(n, n)), directed=False)
    open_set = np.zeros(n_sets, bool)
    open_set[set_of[owner[count[group] != 2]]] = True
    return n_p, n_t, owner, group, count, set_of, n_sets, open_set


def fill_pockets(tris: np.ndarray, lower: np.ndarray, upper: np.ndarray, rest: int,
                 position: Callable[[np.ndarray], np.ndarray],
                 rest_pieces: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                 holds_rest: Callable[[np.ndarray], bool],
                 neighbours: Callable[[np.ndarray], np.ndarray]):
    """The rest pockets of one cleaving, filled (module docstring).

    Parameters
    ----------
    tris : (k, 3) int64
        Interface triangles (tet point first), each oriented from its ``lower`` code's side
        to its ``upper`` code's.
    lower, upper : (k,) int64
    rest : int
        The code of the rest (not meshed).
    position : callable
        Vertex ids (n,) -> their (n, 3) positions.
    rest_pieces : callable
        Tet points (r,) -> the (p, 4) rest pieces of their cleaved tetrahedra (tet point
        first, positive) and (p,) the tet point of each.
    holds_rest : callable
        (q, 4, 3) corners of a set of pieces -> whether a sample of the rest lies in them.
    neighbours : callable
        Face points (f,) -> the tet points of the cleaved tetrahedra with those faces.

    Returns
    -------
    pieces : (p, 4) int64
        The tetrahedra filling the pockets.
    piece_codes : (p,) int64
    keep : (k,) bool
        The triangles still interfaces.
    lower, upper : (k,) int64
        Their codes after filling (copies).
    flip : (k,) bool
        The triangles to turn over (two vertices swapped).
    info : dict
        ``filled_pockets`` (count), ``filled_volume``, ``kept_cavities`` (closed shells left:
        the labels hold the rest there, or their pieces do not close).
    """
    k = len(tris)
    lower, upper = lower.copy(), upper.copy()
    keep, flip = np.ones(k, bool), np.zeros(k, bool)
    none = (np.zeros((0, 4), np.int64), np.zeros(0, np.int64), keep, lower, upper, flip,
            {"filled_pockets": 0, "filled_volume": 0.0, "kept_cavities": 0, "kept_open": 0})
    on = np.flatnonzero((lower == rest) | (upper == rest))
    if len(on) == 0:
        return none
    mark = np.zeros(int(tris.max()) + 1, bool)  # the vertices numbered compactly (no sort), int32
    for j in range(3):
        mark[tris[on, j]] = True
    used = np.flatnonzero(mark)
    compact = np.cumsum(mark, dtype=np.int32) - 1
    del mark
    shell = np.empty((len(on), 3), np.int32)
    for j in range(3):
        shell[:, j] = compact[tris[on, j]]
    del compact
    n_shells, shell_of = connected_components(shell, len(used))
    # each shell's volume, oriented out of the regions (a triangle naming the rest as its lower
    # code points into them), about a common centre: negative for a cavity
    corners = position(used)
    corners -= corners.mean(axis=0)
    six = np.empty(len(shell))
    for i in range(0, len(shell), 1 << 20):  # a chunk at a time: three (k, 3) gathers, not (m, 3)
        a, b, c = (corners[shell[i:i + (1 << 20), j]] for j in range(3))
        six[i:i + (1 << 20)] = np.einsum("ij,ij->i", a, np.cross(b, c))
    del corners, shell
    six[lower[on] == rest] *= -1.0
    volume = np.bincount(shell_of, six, n_shells)
    cavity = volume < 0.0
    if not cavity.any():
        return none
    in_cavity = cavity[shell_of]
    ctri = on[in_cavity]  # the cavities' triangles (ids into tris)
    cshell = shell_of[in_cavity]
    # the rest pieces of the rows whose tet points are on the cavities' shells, and of the rows
    # across their open lattice faces (a row of the rest only, inside a pocket), until closed
    tps = np.unique(tris[ctri, 0])
    for _ in range(FLOOD_ROUNDS):
        pieces = rest_pieces(tps)[0]
        n_p, n_t, owner, group, count, set_of, n_sets, open_set = _sets(pieces, tris[ctri])
        # a piece's face on its lattice face (f, a, b), in one node, of a set holding a cavity
        on_face = (np.arange(len(owner)) < n_p) & (count[group] == 1)
        on_face &= np.isin(set_of[owner], set_of[n_p:])
        fps = np.unique(pieces[owner[on_face], 1])
        more = np.setdiff1d(neighbours(fps), tps) if len(fps) else fps
        if len(more) == 0:
            break
        tps = np.union1d(tps, more)
    piece_set, tri_set = set_of[:n_p], set_of[n_p:]
    # a set is filled when closed, holding a whole cavity (all of its shell's triangles) and
    # no rest sample; its code: the one most of its shell's triangles name besides the rest
    other = np.where(lower[ctri] == rest, upper[ctri], lower[ctri])
    fill_pieces, fill_codes, filled, vol_sum, kept, kept_open = [], [], 0, 0.0, 0, 0
    for s in np.unique(tri_set):
        shells = np.unique(cshell[tri_set == s])
        whole = all(np.all(tri_set[cshell == sh] == s) for sh in shells)
        members = np.flatnonzero(piece_set == s)
        if open_set[s] or not whole or len(members) == 0:
            kept += len(shells)
            kept_open += len(shells)
            continue
        pts = position(pieces[members].reshape(-1)).reshape(-1, 4, 3)
        if holds_rest(pts):
            kept += len(shells)
            continue
        codes, votes = np.unique(other[tri_set == s], return_counts=True)
        code = int(codes[np.argmax(votes)])
        fill_pieces.append(pieces[members])
        fill_codes.append(np.full(len(members), code, np.int64))
        filled += len(shells)
        d1, d2, d3 = pts[:, 1] - pts[:, 0], pts[:, 2] - pts[:, 0], pts[:, 3] - pts[:, 0]
        vol_sum += float(np.einsum("ij,ij->i", d1, np.cross(d2, d3)).sum()) / 6.0
        t = ctri[tri_set == s]
        o = other[tri_set == s]
        pocket_was_lower = lower[t] == rest
        keep[t[o == code]] = False
        moved = t[o != code]
        flip[moved] = pocket_was_lower[o != code] != (code < o[o != code])
        lower[moved] = np.minimum(code, o[o != code])
        upper[moved] = np.maximum(code, o[o != code])
    if not fill_pieces:
        return (*none[:6], {"filled_pockets": 0, "filled_volume": 0.0, "kept_cavities": kept,
                            "kept_open": kept_open})
    return (np.concatenate(fill_pieces), np.concatenate(fill_codes), keep, lower, upper, flip,
            {"filled_pockets": filled, "filled_volume": vol_sum, "kept_cavities": kept, "kept_open": kept_open})
