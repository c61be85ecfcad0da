"""Which cut points lattice cleaving snaps onto lattice nodes, so that no region's boundary is pinched.

Cleaving (:mod:`warpmesh.solid.regions`) snaps a cut point within ``snap`` of its edge's length
from a node onto that node: the sliver the cut would make is gone, and the node then lies on
the interface. Snapping edge by edge pinches regions: where two cut points on edges towards
label ``B`` are snapped onto a node ``v`` of label ``A`` and the two edges share no face, ``B``
reaches ``v`` in two cones that touch only at ``v``, and ``B``'s boundary is not a manifold
there (two cones meeting at their apex). Measured before this module: a cube of ones (10^3
voxels, the default size) had 20 such vertices and a boundary of Euler characteristic -26 (a
cube's is 2); nested balls (64^3, size 4) 198; pyvista's frog about 8,500 in its 25 labels. A
solver takes such a mesh, but a region's surface taken from it is not a closed manifold, and
its topology is not the labels'.

When is a node pinched? Near a node ``v`` the cleaved mesh is a cone over ``v``'s link (the
triangulated sphere of its lattice neighbours ``u``), and every piece of the link (the link's
barycentric subdivision: a corner of a link triangle, half an edge, its centre) takes the code
of the neighbour at its corner, ``λ(u)``: ``u``'s code when the cut on ``(v, u)`` is snapped onto
``v``, ``v``'s otherwise. Each region near ``v`` is then the cone over the union of the closed
dual cells of a set ``S`` of link vertices, and a union of dual cells is homotopy equivalent to
the subcomplex the set spans (the nerve theorem: cells meet where their vertices share a
simplex). A subsurface of a sphere is a disk exactly when it is connected and its Euler
characteristic is 1 (2: the whole sphere). So ``v`` is pinch-free exactly when

- for each code ``B`` other than ``v``'s, the snapped neighbours of code ``B`` span a connected
  subcomplex of Euler characteristic 1 or 2 (``B`` meets ``v`` in one cone), and
- all snapped neighbours together do too (so ``v``'s own code, the complement, is one cone).

Without snapping no node is on an interface, and the cleaved regions are manifold by the same
argument one dimension up (a lattice face has three nodes, a tetrahedron four: no two pieces
of one code meet around a face or tetrahedron point without a third between them).

Where a node fails, some of its snapped cut points are *pushed* instead: a cut at ``t < snap``
of its edge from the node goes to ``snap + PUSH_BEYOND`` (at most the edge's middle), where it
is not snapped. First those outside the largest connected set of the node's snapped cuts (the
other cones), then, if the node still fails, those at least half the push target from it
(``(snap + PUSH_BEYOND) / 2``: pushing them moves the interface no more than snapping them
does), then the rest; the node is checked again
before each step. Pushing only changes the links of the nodes it pushes from (``λ`` at another
node depends only on the cuts snapped onto that node), so every node ends pinch-free.

Why ``PUSH_BEYOND``: pushed exactly to ``snap``, a node's cuts all sit at one distance from it
and make flatter pieces than the spread of cuts the snapping leaves elsewhere (pyvista's frog
at a uniform lattice of 4 voxels: smallest dihedral angle 12.76° -> 10.22°; 12.14° at 0.05
beyond, 12.76° at 0.1, as before). Measured on the frog at the default size and grading
(``benchmarks/bench_regions.py``): no pinched vertex left (15,249 vertex-label pinches
before), 21,776 of about 555,000 snapped cuts pushed, dihedral angles [7.07°, 167.6°]
(before [7.08°, 167.0°]), the worst region 3.2 % off its voxel volume (3.3 %). What it
costs: the interface moves by up to ``snap + PUSH_BEYOND`` of an edge at those nodes (a
snap moves it by up to ``snap``, the other way): nested balls at ``snap`` 0.45 put their
core 4.5 % off its voxel volume instead of 2.5 %; at the default 0.3, the same as before.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> m = wm.mesh_domain(np.ones((10, 10, 10), np.uint8), labels="all")
>>> m.info["pushed_cuts"] > 0, m.stats()["euler"]
(True, 2)
"""

from __future__ import annotations

import numpy as np

__all__ = ["PUSH_BEYOND", "snap_cuts"]

#: a pushed cut point goes this fraction of its edge beyond ``snap`` from its node (at most to
#: the edge's middle)
PUSH_BEYOND = 0.1

_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))


def snap_cuts(T: np.ndarray, L: np.ndarray, cut_id: np.ndarray, t: np.ndarray, e_lo: np.ndarray, e_hi: np.ndarray,
              snap) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The cut points snapped onto a lattice node, pushed where a snap would pinch a region.

    Parameters
    ----------
    T, L : (M, 4) int
        The cleaved tetrahedra (every tetrahedron with a cut edge) and their nodes' codes.
    cut_id : (M, 6) int
        The cut of each local edge (order ``(0,1), (0,2), (0,3), (1,2), (1,3), (2,3)``), -1 where uncut.
    t : (e,) float
        Each cut's parameter along its edge ``e_lo -> e_hi`` (node ids).
    snap : float or (e,) float
        A cut within ``snap`` of an end is snapped onto it (0 <= snap < 0.5).

    Returns
    -------
    t : (e,) float
        The parameters, those pushed to ``snap`` (``1 - snap``) from their node; a new array
        when any is pushed, else ``t``.
    snapped_lo, snapped_hi : (e,) bool
        The cuts snapped onto ``e_lo`` / ``e_hi``.
    pushed : int
        How many cuts were pushed (at how many nodes: the module docstring).

    Example
    -------
    >>> T = np.array([[0, 1, 2, 3], [0, 1, 2, 4]]); L = np.array([[1, 0, 0, 0], [1, 0, 0, 0]])
    >>> cut_id = np.array([[0, 1, 2, -1, -1, -1], [0, 1, 3, -1, -1, -1]])
    >>> e_lo, e_hi = np.zeros(4, int), np.array([1, 2, 3, 4])
    >>> t, lo, hi, pushed = snap_cuts(T, L, cut_id, np.array([0.1, 0.1, 0.5, 0.5]), e_lo, e_hi, 0.3)
    >>> lo.tolist(), pushed  # two cuts onto node 0 across a shared face: one cone, no pinch
    ([True, True, False, False], 0)
    """
    snap_e = np.broadcast_to(np.asarray(snap, dtype=np.float64), t.shape)
    lo, hi = t < snap_e, t > 1.0 - snap_e
    snapped = np.flatnonzero(lo | hi)
    if not len(snapped):
        return t, lo, hi, 0
    pushed = np.zeros(len(t), bool)
    bad = np.zeros(0, np.int64)
    # at a pinched node, first the cuts outside the largest connected set of its snapped cuts
    # (the other cones), then those at least half the push target from it (pushing them moves
    # the interface less than snapping does), then the rest: the node is checked again before
    # each step
    for step in ("cones", "far", "all"):
        target = np.where(lo, e_lo, np.where(hi, e_hi, -1))
        snapped = np.flatnonzero(lo | hi)
        if step != "cones":  # a node's check sees only its own cuts: those of the nodes still pinched
            snapped = snapped[np.isin(target[snapped], bad)]
        bad, main = _pinched_nodes(T, L, cut_id, target, snapped) if len(snapped) else (bad[:0], None)
        if not len(bad):
            break
        which = np.ones(len(t), bool)
        if step == "cones":
            which[snapped[main]] = False
        elif step == "far":  # pushed, they move less than snapped: snap + PUSH_BEYOND - t <= t
            which = np.minimum(t, 1.0 - t) >= 0.5 * np.minimum(snap_e + PUSH_BEYOND, 0.5)
        push_lo = lo & which & np.isin(e_lo, bad)
        push_hi = hi & which & np.isin(e_hi, bad)
        lo, hi = lo & ~push_lo, hi & ~push_hi
        pushed |= push_lo | push_hi
        to = np.minimum(snap_e + PUSH_BEYOND, 0.5)
        t = np.where(push_lo, to, np.where(push_hi, 1.0 - to, t))
    return t, lo, hi, int(pushed.sum())

def _pinched_nodes(T, L, cut_id, target, snapped) -> tuple[np.ndarray, np.ndarray]:
    """The nodes whose snapped cuts (``target`` (e,) the node each cut is snapped onto, -1
    where none; ``snapped`` their ids) span, per code and all together, anything but a disk or
    the whole link (the module docstring); and (len(snapped),) whether each of those cuts is in
    the largest connected set of its node's snapped cuts."""
    from scipy import (
        sparse,  # here, not at import: scipy.sparse costs 0.3 s of every start
    )
    from scipy.sparse import csgraph

    n = len(snapped)
    index = np.full(len(target), -1, np.int32)
    index[snapped] = np.arange(n, dtype=np.int32)
    # the rows with a snapped cut; per local edge (i, j), the (compact) snapped cut on it when it
    # is snapped onto T[row, i] (onto[i, j]) or T[row, j] (onto[j, i]), else -1
    rows = np.flatnonzero((index[np.maximum(cut_id, 0)] >= 0).any(axis=1))
    Tr, Lr, Cr = T[rows], L[rows], cut_id[rows]
    onto = {}
    # the code of the end a cut is not snapped onto, and the node it is snapped onto; a snapped cut
    # on no edge of these rows (the speck pass hands over the tetrahedra around its regions with
    # every cut) is a group of its own, never pinched: it was left as np.empty's garbage, which
    # grouped it with any node and made the pushes, and the mesh, change from run to run
    code_of = np.zeros(n, np.int64)
    node_of = -1 - np.arange(n, dtype=np.int64)
    for k, (i, j) in enumerate(_EDGES):
        e = Cr[:, k]
        c = np.where(e >= 0, index[np.maximum(e, 0)], -1)
        tg = target[np.maximum(e, 0)]
        at_i, at_j = (c >= 0) & (tg == Tr[:, i]), (c >= 0) & (tg == Tr[:, j])
        onto[i, j], onto[j, i] = np.where(at_i, c, -1), np.where(at_j, c, -1)
        code_of[c[at_i]], code_of[c[at_j]] = Lr[at_i, j], Lr[at_j, i]
        node_of[c[at_i]], node_of[c[at_j]] = Tr[at_i, i], Tr[at_j, j]
    del Tr, Lr, Cr
    # link edges (two snapped cuts at one node across a lattice face; each face in two rows)
    # and link triangles (three across a tetrahedron)
    ea, eb, tri_all, tri_same_code = [], [], [], []
    for i in range(4):
        o = [j for j in range(4) if j != i]
        for x in range(3):
            for y in range(x + 1, 3):
                a, b = onto[i, o[x]], onto[i, o[y]]
                both = (a >= 0) & (b >= 0)
                ea.append(np.minimum(a, b)[both])
                eb.append(np.maximum(a, b)[both])
        full = (onto[i, o[0]] >= 0) & (onto[i, o[1]] >= 0) & (onto[i, o[2]] >= 0)
        c3 = np.stack([onto[i, j][full] for j in o], axis=1)
        tri_all.append(c3[:, 0])
        codes3 = code_of[c3]
        tri_same_code.append(c3[(codes3 == codes3[:, :1]).all(axis=1), 0])
    key = np.unique(np.concatenate(ea).astype(np.int64) * n + np.concatenate(eb))
    ea, eb = key // n, key % n
    same = code_of[ea] == code_of[eb]
    tri_all, tri_same_code = np.concatenate(tri_all), np.concatenate(tri_same_code)

    bad, main = [], None
    # all snapped cuts of a node together, then those of one code: a group per node (and code);
    # a link edge joins two cuts of one group, so each connected component lies in one group
    for group, edges, tris in ((node_of, np.ones(len(ea), bool), tri_all),
                               (node_of * (int(code_of.max()) + 1) + code_of, same, tri_same_code)):
        _, g = np.unique(group, return_inverse=True)
        n_groups = int(g.max()) + 1
        chi = (np.bincount(g, minlength=n_groups) - np.bincount(g[ea[edges]], minlength=n_groups)
               + np.bincount(g[tris], minlength=n_groups))
        graph = sparse.coo_matrix((np.ones(int(edges.sum()), np.int8), (ea[edges], eb[edges])), shape=(n, n))
        n_comp, comp = csgraph.connected_components(graph, directed=False)
        group_of = np.empty(n_comp, np.int64)
        group_of[comp] = g
        pieces = np.bincount(group_of, minlength=n_groups)
        wrong = (pieces != 1) | (chi < 1)
        bad.append(node_of[wrong[g]])
        if main is None:  # (the first pass: all the snapped cuts of a node) its largest component
            size = np.bincount(comp, minlength=n_comp)
            order = np.lexsort((-size, group_of))  # by group, the largest first
            first = np.ones(n_comp, bool)
            first[1:] = group_of[order][1:] != group_of[order][:-1]
            largest = np.empty(n_groups, np.int64)
            largest[group_of[order][first]] = order[first]
            main = comp == largest[g]
    bad = np.unique(np.concatenate(bad))
    return bad[bad >= 0], main
