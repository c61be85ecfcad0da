"""Element type conversion [FG §17.1.3, Fig. 17.6, Remarks 17.6 and 17.16].

:func:`convert_cells` splits every element of some types into elements of another type
without moving a point:

========================  =====================================================================
target                    what is split
========================  =====================================================================
``"triangle"``            quad -> 2 triangles (a chosen diagonal) or 4 (around the centroid)
``"quad"``                triangle -> 3 quads (vertex, two edge midpoints, centroid);
                          line -> 2 lines (the same midpoints)
``"tetra"``               hexahedron -> 5, 6 (or 12) tetrahedra, wedge -> 3, pyramid -> 2;
                          quad -> 2 triangles with the diagonals of the volume cells
``"hexahedron"``          tetrahedron -> 4 hexahedra (vertex, 3 edge midpoints, 3 face
                          centroids, centroid); triangle -> 3 quads; line -> 2 lines
========================  =====================================================================

Other blocks are kept as they are. New nodes are numbered once by
:func:`~warpmesh.cells.reference.weighted_nodes` (an edge midpoint or face centre shared by
two elements is one node), so a conforming mesh stays conforming, and a boundary block
turns into exactly the faces of the new volume cells.

Conformity of tetrahedral splits (Remark 17.16): every quad face is cut along the diagonal
through its vertex of smallest global number (Dompierre et al., 1999), so the two cells
sharing it agree. A wedge is rotated so that its smallest vertex is local 0; then one of two
3-tetrahedra templates fits. A hexahedron takes one of the 74 splits of
:mod:`warpmesh.modify.hex_splits` inducing its 6 diagonals (with this rule every configuration
that occurs has one; the centroid split into 12 tetrahedra remains for hexahedra too
distorted for every split of their configuration). ``hexes=5`` instead picks one of the two
5-tetrahedra splits per hexahedron so that neighbours agree, a 2-colouring solved over the
face-adjacency graph, which exists only when every cycle of hexahedra is even.

Templates are oriented once in the reference cell; every new cell of full dimension is
checked to have positive measure.

Examples
--------
>>> import numpy as np
>>> from warpmesh.mesh import Mesh
>>> from warpmesh.modify.convert_cells import convert_cells
>>> sq = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
>>> convert_cells(sq, "triangle", quads=4).cells["triangle"].shape
(4, 3)
"""

from __future__ import annotations

import warnings
from functools import cache
from typing import Literal

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from warpmesh._conventions import INDEX_DTYPE
from warpmesh.cells.types import require_mesh
from warpmesh.cells.collapsed import reject_collapsed
from warpmesh.errors import WarpMeshError
from warpmesh.cells.quality import tetra_quality, triangle_quality
from warpmesh.cells.reference import (
    P1_TYPES,
    cell_measures,
    extend_point_values,
    mirror_permutation,
    reference_cell,
    weighted_nodes,
)
from warpmesh.modify.hex_splits import hex_configurations, HEX_SPLIT_CONFIGS, HEX_SPLITS, steiner_split

__all__ = ["convert_cells", "TARGETS"]

Target = Literal["triangle", "quad", "tetra", "hexahedron"]
#: the target types and the block types each one splits
TARGETS = {
    "triangle": ("quad",),
    "quad": ("triangle", "line"),
    "tetra": ("hexahedron", "wedge", "pyramid", "quad"),
    "hexahedron": ("tetra", "triangle", "line"),
}
_K = 8  # widest node support: the hexahedron centre
_NONE = np.zeros((0, _K), INDEX_DTYPE)


# ----------------------------------------------------------------------------- templates
def _req(*supports) -> tuple[np.ndarray, np.ndarray]:
    """(q, K) local vertices and weights of new nodes, each the mean of a vertex tuple."""
    v, w = np.zeros((len(supports), _K), INDEX_DTYPE), np.zeros((len(supports), _K), INDEX_DTYPE)
    for i, s in enumerate(supports):
        v[i, : len(s)], w[i, : len(s)] = s, 1
    return v, w


@cache
def _oriented(parent: str, child: str, template: tuple, req_v: tuple, req_w: tuple) -> np.ndarray:
    """A template (nc, kc) of local indices into [parent vertices | new nodes], each child
    mirrored if it has negative measure in the reference cell (lines and faces of a 3D
    parent keep their order)."""
    t = np.array(template, INDEX_DTYPE)
    ref, sub = reference_cell(parent), reference_cell(child)
    if sub.tdim != ref.tdim:
        return t
    v, w = np.array(req_v, INDEX_DTYPE).reshape(-1, _K), np.array(req_w, float).reshape(-1, _K)
    x = np.concatenate([ref.vertices, (w[:, :, None] * ref.vertices[v]).sum(1) / w.sum(1)[:, None]])
    neg = cell_measures(x, t, child) < 0
    t[neg] = t[neg][:, mirror_permutation(child)]
    assert (cell_measures(x, t, child) > 0).all(), (parent, child, template)
    return t


def _piece(child, parent, idx, cells, template, req=(_NONE, _NONE)):
    """One group of parents split by one template: a dict the assembler reads."""
    v, w = req
    t = _oriented(parent, child, tuple(map(tuple, np.asarray(template).tolist())),
                  tuple(v.ravel().tolist()), tuple(w.ravel().tolist()))
    return dict(child=child, parent=parent, idx=np.asarray(idx, INDEX_DTYPE),
                cells=np.asarray(cells, INDEX_DTYPE), template=t, req=(v, w))


_TRI_REQ = _req((0, 1), (1, 2), (2, 0), (0, 1, 2))  # local 3, 4, 5: midpoints; 6: centroid
_TRI_QUADS = [(0, 3, 6, 5), (1, 4, 6, 3), (2, 5, 6, 4)]
_QUAD_DIAG = [(0, 1, 2), (0, 2, 3)]  # the diagonal 0-2
_QUAD_FAN = [(0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)]
_ROT_QUAD = np.array([1, 2, 3, 0])


def _tet_hex_template():
    """Tetrahedron -> 4 hexahedra: local 4..9 edge midpoints, 10..13 face centres, 14 centre."""
    edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    faces = [(0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3)]
    req = _req(*edges, *faces, (0, 1, 2, 3))
    mid = {frozenset(e): 4 + i for i, e in enumerate(edges)}
    face = {frozenset(f): 10 + i for i, f in enumerate(faces)}
    hexes = []
    for i, j, k, q in [(0, 1, 2, 3), (1, 0, 3, 2), (2, 0, 1, 3), (3, 0, 2, 1)]:  # even permutations
        m = lambda *a: mid[frozenset(a)] if len(a) == 2 else face[frozenset(a)]  # noqa: E731
        hexes.append((i, m(i, j), m(i, j, k), m(i, k), m(i, q), m(i, j, q), 14, m(i, k, q)))
    return hexes, req


_TET_HEXES, _TET_REQ = _tet_hex_template()
#: orientation-preserving relabellings of a wedge putting local vertex p at position 0
_WEDGE_ROT = np.array([[0, 1, 2, 3, 4, 5], [1, 2, 0, 4, 5, 3], [2, 0, 1, 5, 3, 4],
                       [3, 5, 4, 0, 2, 1], [4, 3, 5, 1, 0, 2], [5, 4, 3, 2, 1, 0]])
_WEDGE_TETS = ([(0, 1, 2, 5), (0, 1, 5, 4), (0, 4, 5, 3)],  # face 1-2-5-4 cut along 1-5
               [(0, 1, 2, 4), (0, 4, 2, 5), (0, 4, 5, 3)])  # ... along 2-4
_PYRAMID_TETS = [(0, 1, 2, 4), (0, 2, 3, 4)]
_ROT_PYRAMID = np.array([1, 2, 3, 0, 4])
_HEX_FACES = np.array(reference_cell("hexahedron").faces)


# ----------------------------------------------------------------------------- 2D splits
def _quad_pieces(cells, diag_bit):
    """Quads split along 0-2 (bit 0) or 1-3 (bit 1): rotate the bit-1 ones by one."""
    rot = np.where(diag_bit[:, None] == 1, cells[:, _ROT_QUAD], cells)
    return [_piece("triangle", "quad", np.arange(len(cells)), rot, _QUAD_DIAG)]


def _best_diagonal(points, cells) -> np.ndarray:
    """(m,) 0/1: the diagonal whose worse triangle has the smaller Q_K (in 2D, a diagonal
    giving an inverted triangle only when both do)."""
    worst, bad = [], []
    for b in (0, 1):
        c = cells if b == 0 else cells[:, _ROT_QUAD]
        tri = c[:, _QUAD_DIAG].reshape(-1, 3)
        worst.append(triangle_quality(points, tri).reshape(-1, 2).max(1))
        if points.shape[1] == 2:
            bad.append((cell_measures(points, tri, "triangle") <= 0).reshape(-1, 2).any(1))
        else:
            bad.append(np.zeros(len(c), bool))
    return np.where(bad[0] != bad[1], bad[0], worst[1] < worst[0]).astype(INDEX_DTYPE)


def _min_diagonal(cells) -> np.ndarray:
    """(m,) 0/1: cut each quad through its vertex of smallest number."""
    return cells.argmin(axis=1) % 2


# ----------------------------------------------------------------------------- 3D splits
def _face_keys(faces: np.ndarray) -> np.ndarray:
    return np.sort(faces, axis=1)


def _shared_faces(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (i, j) of rows of faces (r, 4) with the same vertex set."""
    _, inv = np.unique(_face_keys(faces), axis=0, return_inverse=True)
    order = np.argsort(inv.ravel(), kind="stable")
    same = np.flatnonzero(inv.ravel()[order][1:] == inv.ravel()[order][:-1])
    return order[same], order[same + 1]


def _hex5_variants(hexes: np.ndarray, others: list[np.ndarray]) -> np.ndarray:
    """(m,) 0/1: which 5-tetrahedra split each hexahedron takes so that neighbours agree and
    faces shared with wedges/pyramids (``others``, (r, 4) quad faces) keep the min-index
    diagonal. Parity constraints x_i ^ x_j = c over a doubled graph (node 2i + a means
    "x_i = a"); hexahedron m is a reference fixed to variant 0."""
    m = len(hexes)
    hf = hexes[:, _HEX_FACES].reshape(-1, 4)  # (6m, 4)
    b0 = np.tile((int(HEX_SPLIT_CONFIGS[0]) >> np.arange(6)) & 1, m)  # variant 0's cuts
    diag0 = np.sort(np.where(b0[:, None] == 0, hf[:, [0, 2]], hf[:, [1, 3]]), axis=1)
    owner = np.repeat(np.arange(m), 6)
    i, j = _shared_faces(np.concatenate([hf, *others]))
    hh = j < 6 * m  # i < j, so i is a hexahedron face whenever j is
    flip_hh = (diag0[i[hh]] != diag0[j[hh]]).any(1)
    k = i[(i < 6 * m) & ~hh]  # hexahedron faces shared with a wedge or pyramid
    flip_fixed = hf[k].argmin(1) % 2 != b0[k]
    ri = np.concatenate([owner[i[hh]], owner[k]])
    rj = np.concatenate([owner[j[hh]], np.full(len(k), m)])
    fl = np.concatenate([flip_hh, flip_fixed]).astype(INDEX_DTYPE)
    src = np.concatenate([2 * ri, 2 * ri + 1])
    dst = np.concatenate([2 * rj + fl, 2 * rj + 1 - fl])
    n = 2 * m + 2
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    bad = np.flatnonzero(label[0::2] == label[1::2])
    if len(bad):
        raise ValueError(
            "hexes=5 needs neighbouring hexahedra to alternate between the two 5-tetrahedra "
            "splits (and to keep the min-index cut on faces shared with wedges or pyramids); "
            f"this mesh has an odd cycle: hexahedron {int(bad[0])} would need both splits. "
            "Use hexes='auto' (the min-index rule, always conforming)")
    x = (label[0::2] > label[1::2]).astype(INDEX_DTYPE)
    return x[:m] ^ x[m]


def _hex_pieces(points, hexes, mode, others):
    """Pieces splitting hexahedra, the chosen split of each (index into HEX_SPLITS, -1 for
    the centroid split) and the counts of 5-, 6- and 12-tetrahedra hexahedra."""
    pieces, counts = [], {5: 0, 6: 0, 12: 0}
    config = hex_configurations(hexes)
    if mode == 5:
        choice = _hex5_variants(hexes, others)
    else:
        choice = np.full(len(hexes), -1, INDEX_DTYPE)
        for c in np.unique(config):  # a loop over the <= 64 configurations
            sel = np.flatnonzero(config == c)
            cand = [s for s in np.flatnonzero(HEX_SPLIT_CONFIGS == c)
                    if mode == "auto" or len(HEX_SPLITS[s]) == 6]
            if not cand:
                continue
            # (h, c, 6, 4): 5-tetrahedra splits padded with a repeat of their last one
            tets = np.stack([np.pad(hexes[sel][:, HEX_SPLITS[s]], ((0, 0), (0, 6 - len(HEX_SPLITS[s])),
                                                                  (0, 0)), mode="edge")
                             for s in cand], axis=1).reshape(-1, 4)
            ok = (cell_measures(points, tets, "tetra") > 0).reshape(len(sel), len(cand), 6).all(2)
            q = tetra_quality(points, tets).reshape(len(sel), len(cand), 6).max(2)
            score = np.where(ok, 0, 2) + np.array([len(HEX_SPLITS[s]) == 6 for s in cand])[None]
            finite = np.minimum(q, np.finfo(float).max)  # degenerate (inf) still beats "not allowed"
            q = np.where(score == score.min(1, keepdims=True), finite, np.inf)
            best = q.argmin(1)
            good = ok[np.arange(len(sel)), best]
            choice[sel[good]] = np.array(cand)[best[good]]
        steiner = np.flatnonzero(choice < 0)
        for c in np.unique(config[steiner]):
            s = steiner[config[steiner] == c]
            pieces.append(_piece("tetra", "hexahedron", s, hexes[s], steiner_split(c),
                                 _req(tuple(range(8)))))
        counts[12] = len(steiner)
    for s in np.unique(choice[choice >= 0]):
        sel = np.flatnonzero(choice == s)
        pieces.append(_piece("tetra", "hexahedron", sel, hexes[sel], HEX_SPLITS[s]))
        counts[len(HEX_SPLITS[s])] += len(sel)
    return pieces, choice, counts


def _wedge_pieces(cells):
    r = cells[np.arange(len(cells))[:, None], _WEDGE_ROT[cells.argmin(1)]]
    case = r[:, [1, 2, 5, 4]].argmin(1) % 2  # 0: min at 1 or 5 -> cut 1-5
    return [_piece("tetra", "wedge", np.flatnonzero(case == k), r[case == k], _WEDGE_TETS[k])
            for k in (0, 1)]


def _pyramid_pieces(cells):
    rot = np.where((cells[:, :4].argmin(1) % 2 == 1)[:, None], cells[:, _ROT_PYRAMID], cells)
    return [_piece("tetra", "pyramid", np.arange(len(cells)), rot, _PYRAMID_TETS)]


def _boundary_quad_bits(quads, hexes, choice, mode):
    """Cut of each quad of the quad block: the one its hexahedron makes (hexes=5), else the
    min-index diagonal."""
    bit = _min_diagonal(quads)
    if mode != 5 or not len(hexes) or not len(quads):
        return bit

    hf = hexes[:, _HEX_FACES].reshape(-1, 4)
    cfg = HEX_SPLIT_CONFIGS[choice]
    hb = ((cfg[:, None] >> np.arange(6)) & 1).ravel()
    diag = np.sort(np.where(hb[:, None] == 0, hf[:, [0, 2]], hf[:, [1, 3]]), axis=1)
    keys = _face_keys(np.concatenate([hf, quads]))
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    slot = np.full(inv.max() + 1, -1, INDEX_DTYPE)
    slot[inv[: len(hf)]] = np.arange(len(hf))
    hit = slot[inv[len(hf):]]
    on = hit >= 0
    q02 = np.sort(quads[on][:, [0, 2]], axis=1)
    bit[on] = (q02 != diag[hit[on]]).any(1).astype(INDEX_DTYPE)
    return bit


# ----------------------------------------------------------------------------- assembly
def _validate(mesh, target, quads, hexes):
    require_mesh(mesh)
    reject_collapsed(mesh, 'convert')
    if target not in TARGETS:
        raise ValueError(f"expected 'target' among {list(TARGETS)}, got {target!r}")
    if quads is not None and target != "triangle":
        raise ValueError(f"expected 'quads' only with target='triangle', got quads={quads!r} with "
                         f"target={target!r} (quads then follow the volume cells' diagonals)")
    if hexes is not None and target != "tetra":
        raise ValueError(f"expected 'hexes' only with target='tetra', got hexes={hexes!r}")
    quads = "best" if quads is None else quads
    hexes = "auto" if hexes is None else hexes
    if isinstance(quads, bool) or quads not in ("best", "min", 4):
        raise ValueError(f"expected 'quads' among ['best', 'min', 4], got {quads!r}")
    if isinstance(hexes, bool) or hexes not in ("auto", 5, 6):
        raise ValueError(f"expected 'hexes' among ['auto', 5, 6], got {hexes!r}")
    high = [t for t in mesh.cells if t not in P1_TYPES]
    if high:
        raise ValueError(f"expected P1 cell blocks, got higher-order {high}; convert the P1 mesh "
                         "first and raise the order afterwards (Mesh.to_order)")
    return quads, hexes


def convert_cells(mesh, target: Target, *, quads: Literal["best", "min", 4] | None = None,
                  hexes: Literal["auto", 5, 6] | None = None):
    """A new mesh whose elements of some types are split into elements of type ``target``.

    Parameters
    ----------
    mesh : Mesh
        P1 cell blocks (any higher-order block raises).
    target : {"triangle", "quad", "tetra", "hexahedron"}
        ``"triangle"``: quads -> triangles. ``"quad"``: triangles -> 3 quads, lines -> 2.
        ``"tetra"``: hexahedra, wedges (3), pyramids (2) -> tetrahedra; quads -> the 2
        triangles of the same cut. ``"hexahedron"``: tetrahedra -> 4 hexahedra,
        triangles -> 3 quads, lines -> 2. Other blocks are kept (so splitting the faces of
        kept volume cells, e.g. ``"triangle"`` on the quads bounding hexahedra, leaves
        them non-conforming: convert the volume too).
    quads : {"best", "min", 4}, optional (only with ``target="triangle"``; default "best")
        ``"best"``: the diagonal whose worse triangle has the smaller Q_K ([FG eq. 16.15];
        in 2D, a diagonal inverting a triangle of a non-convex quad is avoided);
        ``"min"``: the diagonal through the vertex of smallest number (matches what
        ``target="tetra"`` does to hexahedra faces); ``4``: 4 triangles around the centroid.
    hexes : {"auto", 5, 6}, optional (only with ``target="tetra"``; default "auto")
        ``"auto"``: per hexahedron, a split inducing the min-index diagonals, 5 tetrahedra
        when one does, else the 6-tetrahedra split of best worst Q_K (a split with an
        inverted tetrahedron is avoided; with none valid, 12 tetrahedra around the
        centroid). ``6``: the same without the 5-tetrahedra splits. ``5``: 5 tetrahedra
        each, alternating between neighbours (raises when the mesh has an odd cycle).

    Returns
    -------
    Mesh
        Children in blocks of their type (kept blocks first among blocks of one type),
        ``cell_refs``/``cell_data`` copied from the parents, new nodes appended with
        ``point_refs`` = the common ref of their support (else 0) and float
        ``point_data`` interpolated. ``info`` gains ``converted_to``, ``n_split``
        {type: parents}, ``n_new_points`` and, for hexahedra, ``n_hex5``, ``n_hex6``,
        ``n_hex12``.

    Raises
    ------
    TypeError
        ``mesh`` is not a :class:`~warpmesh.mesh.Mesh`.
    ValueError
        Unknown target or option value, an option for another target, higher-order
        blocks, ``hexes=5`` on a mesh that cannot alternate.
    WarpMeshError
        A new cell would be inverted (a non-convex parent cut the way conformity needs).

    Examples
    --------
    >>> import numpy as np
    >>> from warpmesh.mesh import Mesh
    >>> cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
    ...                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    >>> m = convert_cells(Mesh(cube, {"hexahedron": [[0, 1, 2, 3, 4, 5, 6, 7]]}), "tetra")
    >>> len(m.cells["tetra"]), m.info["n_hex6"]
    (6, 1)
    >>> tri = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
    >>> convert_cells(tri, "quad").cells["quad"].tolist()
    [[0, 3, 6, 4], [1, 5, 6, 3], [2, 4, 6, 5]]
    """
    quads, hexes = _validate(mesh, target, quads, hexes)
    pts, cells = mesh.points, dict(mesh.cells)
    pieces, info = {}, {}
    if target == "triangle" and "quad" in cells:
        q = cells["quad"]
        if quads == 4:
            pieces["quad"] = [_piece("triangle", "quad", np.arange(len(q)), q, _QUAD_FAN,
                                     _req((0, 1, 2, 3)))]
        else:
            bit = _best_diagonal(pts, q) if quads == "best" else _min_diagonal(q)
            pieces["quad"] = _quad_pieces(q, bit)
    elif target in ("quad", "hexahedron"):
        splits = {"line": ("line", [(0, 2), (2, 1)], _req((0, 1))),
                  "triangle": ("quad", _TRI_QUADS, _TRI_REQ),
                  "tetra": ("hexahedron", _TET_HEXES, _TET_REQ)}
        for t in TARGETS[target]:
            if t in cells:
                child, tmpl, req = splits[t]
                pieces[t] = [_piece(child, t, np.arange(len(cells[t])), cells[t], tmpl, req)]
    elif target == "tetra":
        h = cells.get("hexahedron", np.zeros((0, 8), INDEX_DTYPE))
        choice = np.zeros(0, INDEX_DTYPE)
        if len(h):
            others = [cells[t][:, [f for f in reference_cell(t).faces if len(f) == 4]].reshape(-1, 4)
                      for t in ("wedge", "pyramid") if t in cells]
            pieces["hexahedron"], choice, counts = _hex_pieces(pts, h, hexes, others)
            info.update({f"n_hex{k}": v for k, v in counts.items()})
        if "wedge" in cells:
            pieces["wedge"] = _wedge_pieces(cells["wedge"])
        if "pyramid" in cells:
            pieces["pyramid"] = _pyramid_pieces(cells["pyramid"])
        if "quad" in cells:
            q = cells["quad"]
            pieces["quad"] = _quad_pieces(q, _boundary_quad_bits(q, h, choice, hexes))
    if not pieces:  # (a 2D triangle mesh converted "to tetra" came back unchanged without a word)
        warnings.warn(f"convert to {target!r}: the mesh has no {' or '.join(repr(t) for t in TARGETS[target])} "
                      f"cells to split (it has {sorted(cells)}); it is returned as it is", UserWarning, stacklevel=3)
    return _assemble(mesh, pieces, target, info)


def _new_nodes(points, flat):
    """Number the nodes the pieces ask for, once each: one :func:`weighted_nodes` call per
    support size (nodes of different sizes cannot coincide), numbered after the points.
    Returns per-piece ids (mp, q), the new points and their (vertices, weights) (u, K)."""
    ids = [np.empty((len(p["cells"]), len(p["req"][0])), INDEX_DTYPE) for p in flat]
    size = [(p["req"][1] > 0).sum(1) for p in flat]
    n, new, sv, sw = len(points), [np.zeros((0, points.shape[1]))], [_NONE], [_NONE]
    for k in sorted({int(x) for s in size for x in s}):  # a loop over <= 4 support sizes
        rows = [(i, np.flatnonzero(s == k)) for i, s in enumerate(size)]
        rows = [(i, r) for i, r in rows if len(r)]
        v = np.concatenate([flat[i]["cells"][:, flat[i]["req"][0][r, :k]].reshape(-1, k)
                            for i, r in rows])
        w = np.concatenate([np.broadcast_to(flat[i]["req"][1][r, :k], (len(flat[i]["cells"]), len(r), k))
                            .reshape(-1, k) for i, r in rows])
        got, pts, (uv, uw) = weighted_nodes(points, v, w, point_count=n)
        start = 0
        for i, r in rows:
            ids[i][:, r] = got[start: start + len(flat[i]["cells"]) * len(r)].reshape(-1, len(r))
            start += len(flat[i]["cells"]) * len(r)
        n += len(pts)
        new.append(pts)
        sv.append(np.pad(uv, ((0, 0), (0, _K - k)), constant_values=-1))
        sw.append(np.pad(uw, ((0, 0), (0, _K - k))))
    return ids, np.concatenate(new), (np.concatenate(sv), np.concatenate(sw))


def _check_positive(points, children, child, parent):
    """Raise when a new cell of full dimension (or a simplex parent) is not positively
    oriented."""
    vol = cell_measures(points, children, child)
    if (vol <= 0).any():
        i = int(np.flatnonzero(vol <= 0)[0])
        hint = {"quad": "; try quads='best'", "hexahedron": ""}.get(parent, "")
        raise WarpMeshError(
            f"{int((vol <= 0).sum())} {child} cells split from {parent} cells would not be "
            f"positively oriented (first: {children[i].tolist()}); is the {parent} inverted, or "
            f"too distorted (non-convex) for the cut conformity needs?{hint}")


def _assemble(mesh, pieces, target, info):
    """Number the new nodes once, build the children, carry refs and data."""
    flat = [p for t in mesh.cells if t in pieces for p in pieces[t]]
    ids, new_pts, support = _new_nodes(mesh.points, flat)
    points = np.concatenate([mesh.points, new_pts])
    out = []  # (child type, cells, parent type, parent index) per group
    for t, c in mesh.cells.items():
        if t not in pieces:
            out.append((t, c, t, np.arange(len(c))))
            continue
        for p, pid in ((p, pid) for p, pid in zip(flat, ids) if p["parent"] == t):
            children = np.concatenate([p["cells"], pid], axis=1)[:, p["template"]]  # (mp, nc, kc)
            children = children.reshape(-1, children.shape[2])
            if reference_cell(p["child"]).tdim == mesh.dim:  # a simplex's children are its affine
                simplex = t in ("line", "triangle", "tetra")  # images: they share its sign
                _check_positive(points, p["cells"] if simplex else children, t if simplex else p["child"], t)
            out.append((p["child"], children, t, np.repeat(p["idx"], len(p["template"]))))
    blocks: dict[str, list] = {}
    for child, c, parent, idx in out:
        blocks.setdefault(child, []).append((c, parent, idx))
    new_cells = {t: np.concatenate([b[0] for b in bl]) for t, bl in blocks.items()}

    def gather(per_type, default_dtype):
        return {t: np.concatenate([per_type[p][idx] if p in per_type
                                   else np.zeros(len(idx), default_dtype) for _, p, idx in bl])
                for t, bl in blocks.items()}

    cell_refs = None if mesh.cell_refs is None else gather(mesh.cell_refs, INDEX_DTYPE)
    cell_data = {k: gather(v, next(iter(v.values())).dtype) for k, v in mesh.cell_data.items()}
    point_refs = None if mesh.point_refs is None else extend_point_values(mesh.point_refs, support)
    point_data = {k: extend_point_values(v, support) for k, v in mesh.point_data.items()}
    n_split = {t: int(len(mesh.cells[t])) for t in mesh.cells if t in pieces}
    info = {**mesh.info, "converted_to": target, "n_split": n_split,
            "n_new_points": int(len(new_pts)), **info}
    return mesh.replace(points=points, cells=new_cells, point_refs=point_refs,
                        point_data=point_data, cell_data=cell_data, cell_refs=cell_refs, info=info)
