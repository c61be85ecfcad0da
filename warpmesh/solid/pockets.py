"""Pockets of the rest that lattice cleaving encloses inside the meshed regions, filled.

Cleaving (:mod:`warpmesh.solid.regions`) gives each lattice edge one cut point. Where the
edges do not resolve the labels (a channel of the rest thinner than the lattice, lone voxels
of the rest beside a region), the pieces of a region can close over a piece of the rest
that holds no rest sample. The mesh then has a cavity: a closed shell of boundary triangles,
inside the regions, around a volume the labels give to a region. A solver sees a tiny
traction-free hole.

Measured: pyvista's frog at the default size and grading, 64 such cavities (each under a
voxel); noisy label volumes at the frog's spacing (``tests/solid/test_pockets.py``), 1 or 2
in 5 of 40. Most cavities used to come from the snapping of cut points onto lattice nodes,
each joined to the outside at one node (12 in 2 of 12 random 4-box label volumes at h = 2
voxels): the snapping no longer pinches (:mod:`warpmesh.solid.snapping`), and those no longer form.

:func:`fill_pockets` finds them and fills them: the boundary triangles (those naming the
rest) are split into edge-connected shells, oriented out of the regions; a shell of
negative enclosed volume is a cavity. The rest pieces of the cleaved tetrahedra whose tet
points lie on a cavity's shell are made (the fans' segments of the rest, which cleaving
drops), joined through their shared faces; a set of them that the shell closes (every face
shared by two pieces, or by a piece and a shell triangle) and that holds no sample of the
rest (the labels say the cavity is not there: a cavity the labels do hold, a rest voxel
inside the tissue, is kept) becomes tetrahedra of the code whose triangles on its shell
have the most area (not a tie broken by the codes' order), and the
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
>>> m.info["filled_pockets"], m.info["kept_cavities"], m.stats()["components"], m.stats()["euler"]
(0, 0, 1, 2)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components as graph_components

from warpmesh.cells.topology import connected_components, face_volumes

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
    used, local = np.unique(faces, return_inverse=True)
    keys = np.sort(local.reshape(-1, 3), axis=1)
    n = np.int64(len(used))
    if n < 2**21:  # one int64 key per face (three 21-bit ids)
        _, group, count = np.unique((keys[:, 0] * n + keys[:, 1]) * n + keys[:, 2], return_inverse=True,
                                    return_counts=True)
    else:
        _, group, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
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
                 neighbours: Callable[[np.ndarray], np.ndarray], largest: float = np.inf):
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
        first, positive).
    holds_rest : callable
        (q, 4, 3) corners of a set of pieces -> whether a sample of the rest lies in them.
    neighbours : callable
        Vertex ids (f,) -> the tet points of the cleaved tetrahedra with those face points
        (ids that are no face point are ignored).
    largest : float
        The volume of the largest background tetrahedron: a cavity enclosing more than it
        is kept without examination (a pocket is a few pieces about one node or edge; on
        the graded frog a bound of six of them fills the same 44 pockets and leaves 7
        more cavities open).

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
        ``filled_pockets`` (count of shells filled), ``filled_volume``, ``kept_cavities``
        (cavity shells left: the labels hold the rest there, they are large, or their pieces
        do not close: ``kept_open`` of them).
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
    signed = face_volumes(corners, shell, corners.mean(axis=0))
    del corners, shell
    signed[lower[on] == rest] *= -1.0
    volume = 6.0 * np.bincount(shell_of, signed, n_shells)  # six times each shell's volume
    cavity = volume < 0.0
    n_cavities = int(cavity.sum())
    # a pocket is a few pieces about one node or edge: a cavity larger than ``largest`` is one
    # the labels hold (its whole tetrahedra of the rest were never cleaved), kept unexamined
    cavity &= volume >= -6.0 * largest  # (both sides six times a volume)
    if not cavity.any():
        return (*none[:6], {**none[6], "kept_cavities": n_cavities})
    in_cavity = cavity[shell_of]
    ctri = on[in_cavity]  # the cavities' triangles (ids into tris)
    cshell = shell_of[in_cavity]
    # the rest pieces of the rows whose tet points are on the cavities' shells, and of the rows
    # across their open lattice faces (a row of the rest only, inside a pocket), until closed
    tps = np.unique(tris[ctri, 0])
    for _ in range(FLOOD_ROUNDS):
        pieces = rest_pieces(tps)
        n_p, n_t, owner, group, count, set_of, n_sets, open_set = _sets(pieces, tris[ctri])
        # a piece's face on its lattice face (f, a, b), in one node, of a set holding a cavity
        on_face = (np.arange(len(owner)) < n_p) & (count[group] == 1)
        on_face &= np.isin(set_of[owner], set_of[n_p:])
        more = np.setdiff1d(neighbours(np.unique(pieces[owner[on_face], 1])), tps)
        if len(more) == 0:
            break
        tps = np.union1d(tps, more)
    piece_set, tri_set = set_of[:n_p], set_of[n_p:]
    # a set is filled when closed, holding whole cavities (all of their shells' triangles) and
    # no rest sample; its code: the one whose triangles on its shells have the most area
    other = np.where(lower[ctri] == rest, upper[ctri], lower[ctri])
    p = position(tris[ctri].reshape(-1)).reshape(-1, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    pair = np.unique(np.column_stack([cshell, tri_set]), axis=0)  # (shell, set) pairs
    split = np.bincount(pair[:, 0], minlength=n_shells) > 1  # shells whose triangles are in several sets
    broken = np.zeros(n_sets, bool)
    broken[pair[split[pair[:, 0]], 1]] = True
    t_order = np.argsort(tri_set, kind="stable")
    t_start = np.searchsorted(tri_set[t_order], np.arange(n_sets + 1))
    p_order = np.argsort(piece_set, kind="stable")
    p_start = np.searchsorted(piece_set[p_order], np.arange(n_sets + 1))
    fill_pieces, fill_codes, vol_sum = [], [], 0.0
    filled_shell, open_shell = np.zeros(n_shells, bool), np.zeros(n_shells, bool)
    for s_ in np.unique(tri_set):
        rows = t_order[t_start[s_]:t_start[s_ + 1]]  # this set's cavity triangles
        members = p_order[p_start[s_]:p_start[s_ + 1]]
        shells = np.unique(cshell[rows])
        if open_set[s_] or broken[s_] or len(members) == 0:
            open_shell[shells] = True
            continue
        pts = position(pieces[members].reshape(-1)).reshape(-1, 4, 3)
        if holds_rest(pts):
            continue
        codes, inverse = np.unique(other[rows], return_inverse=True)
        code = int(codes[np.argmax(np.bincount(inverse.reshape(-1), area[rows]))])
        fill_pieces.append(pieces[members])
        fill_codes.append(np.full(len(members), code, np.int64))
        filled_shell[shells] = True
        d1, d2, d3 = pts[:, 1] - pts[:, 0], pts[:, 2] - pts[:, 0], pts[:, 3] - pts[:, 0]
        vol_sum += float(np.einsum("ij,ij->i", d1, np.cross(d2, d3)).sum()) / 6.0
        t, o = ctri[rows], other[rows]
        pocket_was_lower = lower[t] == rest
        keep[t[o == code]] = False
        moved, o_moved = t[o != code], o[o != code]
        flip[moved] = pocket_was_lower[o != code] != (code < o_moved)
        lower[moved] = np.minimum(code, o_moved)
        upper[moved] = np.maximum(code, o_moved)
    filled = int(filled_shell.sum())
    info = {"filled_pockets": filled, "filled_volume": vol_sum, "kept_cavities": n_cavities - filled,
            "kept_open": int((open_shell & ~filled_shell).sum())}
    if not fill_pieces:
        return (*none[:6], info)
    return np.concatenate(fill_pieces), np.concatenate(fill_codes), keep, lower, upper, flip, info
