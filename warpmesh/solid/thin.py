"""Where a label volume's regions are thinner than the lattice: the graded background of
lattice cleaving (:mod:`warpmesh.solid.regions`, ``min_size=``).

Cleaving puts one cut point on a lattice edge whose two ends differ, and none on an edge whose
ends agree. So an edge *resolves* the labels along it when they change at most once between
its ends; where they change more often (a layer thinner than the edge between two nodes of
one label, or an edge crossing three labels) the region in the middle loses volume or
vanishes. That is the refinement test: every edge of the background is sampled
(``per_voxel`` = :data:`warpmesh.solid.regions.SAMPLES_PER_VOXEL` samples per voxel, the
ends being its nodes' labels; a run shorter than ``MIN_RUN`` voxel between two others is an
edge clipping a voxel's corner and does not count; with ``focus``, only edges with a run of
a region in focus count), and a tetrahedron with an unresolved edge is bisected at its longest edge (conforming longest-edge
bisection, :func:`warpmesh.solid.graded.refine_tets`), again and again until its edges resolve
the labels or its longest edge is ``min_size`` or less. Elsewhere the lattice keeps its cube
side ``h``: the refinement follows thin layers, small regions and the lines where three labels
meet, and nothing else.

The background is the BCC lattice's tetrahedra (cube side ``h``) of the cubes within
``MARGIN`` cubes of a meshed voxel. Its own boundary, where a face has no tetrahedron beyond
it and the refinement may split that face, then lies in the rest, where cleaving makes
nothing (a face whose three nodes are of the rest stays whole, and its sub-tetrahedron is
dropped): this is checked, and a violation raises :class:`~warpmesh.errors.WarpMeshError`.

What it does not see: a region that no background edge passes through (a speck of a voxel or
two inside one tetrahedron, away from its edges) is not found; one that needs edges below
``min_size`` keeps the uniform lattice's losses there; and edges that resolve the labels do
not make the volume right by themselves (a layer about as thin as ``min_size``, a region one
or two edges across: the measurements are in :mod:`warpmesh.solid.regions`).

Example
-------
>>> import numpy as np
>>> from warpmesh.solid.regions import mesh_regions
>>> vol = np.zeros((24, 24, 24), np.uint8)
>>> vol[4:20, 4:20, 4:11] = 1
>>> vol[4:20, 4:20, 11:13] = 2          # a layer 2 voxels thick
>>> vol[4:20, 4:20, 13:20] = 3
>>> uniform = mesh_regions(vol, size=4.0, min_size=4.0)
>>> graded = mesh_regions(vol, size=4.0)
>>> round(uniform.info["region_volumes"][2]["error"], 2), abs(graded.info["region_volumes"][2]["error"]) < 0.01
(-0.33, True)
>>> graded.info["refined_labels"], graded.info["graded"]
([1, 2, 3], True)
"""

from __future__ import annotations

import numpy as np

from warpmesh._util.arrays import sorted_unique
from warpmesh.errors import WarpMeshError
from warpmesh.solid.graded import EDGE_KEY, SizeField, refine_tets, tet_edges
from warpmesh.solid.lattice import lattice_tables, node_coordinates

__all__ = ["MARGIN", "MIN_RUN", "graded_background", "unresolved_edges"]

#: cubes of the BCC lattice kept around the meshed voxels
MARGIN = 2
#: a run of labels shorter than this (voxels) inside an edge is not a region the edge crosses:
#: a layer one voxel thick gives a run of about one voxel at any angle, a voxel's corner less
MIN_RUN = 0.75


def unresolved_edges(labels_at, a: np.ndarray, b: np.ndarray, spacing: np.ndarray, per_voxel: int,
                     min_run: int | None = None, focus=None, chunk: int = 1 << 21) -> np.ndarray:
    """(e,) bool: True where the labels along the segment a -> b (local positions (e, 3))
    change more than once, sampled ``per_voxel`` times per voxel of the smallest spacing, the
    ends included; a run of fewer than ``min_run`` samples between two others (default
    ``MIN_RUN`` voxels' worth) does not count (an edge clipping a voxel's corner). ``focus``,
    optional: (c,) bool by code, an edge counts only when one of its runs is of a code in focus."""
    min_run = max(1, int(round(MIN_RUN * per_voxel))) if min_run is None else int(min_run)
    out = np.zeros(len(a), bool)
    if not len(a):
        return out
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(4, np.ceil(per_voxel * length / float(np.min(spacing))).astype(np.int64))
    for m in np.unique(n):  # a few lengths in a graded lattice: one batch each
        rows = np.flatnonzero(n == m)
        s = np.concatenate([[0.0], (np.arange(m) + 0.5) / m, [1.0]])
        step = max(1, chunk // (m + 2))
        for i in range(0, len(rows), step):
            r = rows[i:i + step]
            pts = a[r, None, :] + s[None, :, None] * (b[r] - a[r])[:, None, :]
            lab = labels_at(pts.reshape(-1, 3)).reshape(len(r), m + 2)
            lab = _merge_short_runs(lab, min_run)
            hit = (lab[:, 1:] != lab[:, :-1]).sum(axis=1) > 1
            if focus is not None:
                hit &= focus[lab].any(axis=1)
            out[r] = hit
    return out


def _merge_short_runs(lab: np.ndarray, min_run: int) -> np.ndarray:
    """``lab`` (k, w) with the runs shorter than ``min_run`` samples along a row, but the
    first and the last, merged into the run before them."""
    k, w = lab.shape
    run = np.zeros((k, w), np.int64)
    np.cumsum(lab[:, 1:] != lab[:, :-1], axis=1, out=run[:, 1:])
    flat = run + (np.arange(k) * w)[:, None]
    length = np.bincount(flat.ravel(), minlength=k * w)[flat]
    short = (length < min_run) & (run > 0) & (run < run[:, -1:])
    if short.any():
        idx = np.where(short, 0, np.arange(w)[None, :])
        np.maximum.accumulate(idx, axis=1, out=idx)
        lab = np.take_along_axis(lab, idx, axis=1)
    return lab


class _Resolution:
    """The size refine_tets asks of a tetrahedron: ``min_size`` while one of its edges is
    unresolved, else ``h``.

    Each edge is sampled once, when it first comes: with the contract of
    :func:`~warpmesh.solid.graded.refine_tets` (nodes only appended; an edge of an asked
    tetrahedron whose two ends existed at the previous call was an edge of a tetrahedron asked
    before), the edges to sample are those with an end added since the previous call, and no
    search of the edges seen is needed. Only the unresolved edges are remembered (sorted keys,
    and a flag on their ends so that most edges are cleared without a search)."""

    def __init__(self, labels_at, spacing, h: float, min_size: float, per_voxel: int, focus):
        self.labels_at, self.spacing, self.h, self.min_size = labels_at, spacing, h, min_size
        self.per_voxel, self.focus = per_voxel, focus
        self.known = 0  # nodes seen at the previous call: an edge with an end at or past it is new
        self.bad_keys = np.zeros(0, np.int64)  # sorted keys of the unresolved edges
        self.bad_node = np.zeros(0, bool)  # True on an end of an unresolved edge
        self.sampled = 0

    def __call__(self, nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
        keys = tet_edges(tets)
        lo, hi = keys // EDGE_KEY, keys % EDGE_KEY
        new = sorted_unique(keys[hi >= self.known])
        if len(self.bad_node) < len(nodes):
            self.bad_node = np.concatenate([self.bad_node, np.zeros(len(nodes) - len(self.bad_node), bool)])
        self.known = max(self.known, len(nodes))
        if len(new):
            bad = new[unresolved_edges(self.labels_at, nodes[new // EDGE_KEY], nodes[new % EDGE_KEY], self.spacing,
                                       self.per_voxel, focus=self.focus)]
            self.sampled += len(new)
            if len(bad):
                self.bad_keys = np.sort(np.concatenate([self.bad_keys, bad]))
                self.bad_node[bad // EDGE_KEY] = True
                self.bad_node[bad % EDGE_KEY] = True
        cand = np.flatnonzero((self.bad_node[lo] & self.bad_node[hi]).any(axis=1))
        unresolved = np.zeros(len(tets), bool)
        if len(cand) and len(self.bad_keys):
            k = keys[cand]
            pos = np.minimum(np.searchsorted(self.bad_keys, k), len(self.bad_keys) - 1)
            unresolved[cand] = (self.bad_keys[pos] == k).any(axis=1)
        return np.where(unresolved, self.min_size, self.h)


def _meshed_cells(codes: np.ndarray, rest: int, spacing: np.ndarray, dims: np.ndarray, origin: np.ndarray,
                  h: float) -> np.ndarray:
    """(dims) bool: the cubes [origin + h c, origin + h (c + 1)) holding a meshed voxel's centre."""
    m = codes != rest
    for a in range(3):
        cell = np.floor((np.arange(codes.shape[a]) * spacing[a] - origin[a]) / h).astype(np.int64)
        starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
        red = np.logical_or.reduceat(m, starts, axis=a)
        shape = list(red.shape)
        shape[a] = int(dims[a])
        full = np.zeros(shape, bool)
        idx = [slice(None)] * 3
        idx[a] = cell[starts]
        full[tuple(idx)] = red
        m = full
    return m


def graded_background(codes: np.ndarray, rest: int, spacing, dims: np.ndarray, origin: np.ndarray, h: float,
                      min_size: float, labels_at, per_voxel: int = 4, focus=None):
    """The BCC lattice near the meshed voxels, refined where its edges do not resolve the labels.

    Parameters
    ----------
    codes : (nx, ny, nz) integer array, ``rest`` the code not meshed
    spacing : (3,) float
    dims, origin, h : the uniform lattice (:func:`warpmesh.solid.stuffing.lattice_for`)
    min_size : float, no tetrahedron whose longest edge is at most this is bisected
    labels_at : callable (n, 3) local points -> (n,) codes
    per_voxel : int, samples per voxel along an edge
    focus : (c,) bool by code, optional: only edges crossing a code in focus are refined

    Returns
    -------
    None when no edge of the lattice needs refining, else
    node_pos : (n, 3) float64, local coordinates
    node_code : (n,) codes
    tets : (m, 4) int64, positive, those with a meshed node
    info : dict (``graded_tets`` the whole refined part, ``graded_levels`` the most bisections
    of one tetrahedron, ``graded_edges_sampled``)
    """
    from scipy.ndimage import binary_dilation

    spacing = np.asarray(spacing, dtype=np.float64)
    cells = _meshed_cells(codes, rest, spacing, dims, origin, h)
    cells = binary_dilation(cells, structure=np.ones((3, 3, 3), bool), iterations=MARGIN)
    black = np.argwhere(cells)
    layout = lattice_tables()[0].astype(np.int64)  # (12, 4, (colour, dx, dy, dz))
    colour, off = layout[:, :, 0], layout[:, :, 1:]
    ends = black[:, None, None, :] + off[None]  # (k, 12, 4, 3)
    ok = np.all((ends >= 0) & (ends < dims[None, None, None, :] - colour[None, :, :, None]), axis=(2, 3))
    ends = ends[ok]  # (m, 4, 3)
    col = np.broadcast_to(colour[None], ok.shape + (4,))[ok]
    uid = 2 * (ends[..., 0] + dims[0] * (ends[..., 1] + dims[1] * ends[..., 2])) + col
    used, tets = np.unique(uid, return_inverse=True)
    tets = tets.reshape(-1, 4)
    cell = used // 2
    ijk = np.stack([cell % dims[0], (cell // dims[0]) % dims[1], cell // (dims[0] * dims[1])], axis=1)
    coords = node_coordinates((used % 2)[:, None], ijk).astype(np.float64)  # half-cube units
    resolution = _Resolution(labels_at, spacing, h, min_size, per_voxel, focus)
    field = SizeField(lambda p: np.full(len(p), h), min_size, h)  # (names the smallest size in errors)
    try:
        coords, tets, levels = refine_tets(coords, tets, h, origin, field, tet_size=resolution)
    except ValueError as exc:  # the background's size limit
        raise ValueError(f"{exc}; for a label volume raise 'min_size' (got {min_size:g})") from None
    if not levels.any():
        return None
    node_pos = origin + coords * (0.5 * h)
    node_code = labels_at(node_pos)
    _check_boundary(tets, node_code, rest)
    keep = np.any(node_code[tets] != rest, axis=1)
    info = {"graded_tets": int(len(tets)), "graded_levels": int(levels.max(initial=0)),
            "graded_edges_sampled": int(resolution.sampled)}
    return node_pos, node_code, tets[keep], info


def _check_boundary(tets: np.ndarray, node_code: np.ndarray, rest: int) -> None:
    """The faces in one tetrahedron (the part's own boundary) must have their nodes in the rest."""
    near = np.any(node_code[tets] != rest, axis=1)  # a face with a meshed node is a face of these
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    faces = np.sort(faces, axis=1)
    meshed = np.any(node_code[faces] != rest, axis=1)
    faces = faces[meshed]
    n = np.int64(len(node_code))
    if n < 2**21:
        _, counts = np.unique((faces[:, 0] * n + faces[:, 1]) * n + faces[:, 2], return_counts=True)
    else:
        _, counts = np.unique(faces, axis=0, return_counts=True)
    if (counts == 1).any() and near.any():
        raise WarpMeshError(f"{int((counts == 1).sum())} faces of the graded background with a meshed node "
                            "lie on its boundary; this is a bug (please report the volume), and 'min_size' "
                            "above size / 2 avoids it")
