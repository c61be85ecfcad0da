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

Specks (small components, :class:`Specks`): the lattice is asked a size over their voxels,
whatever its edges resolve (the regions module says why and how fine).

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
>>> round(uniform.info["region_volumes"][2]["error"], 2), abs(graded.info["region_volumes"][2]["error"]) < 0.02
(-0.31, True)
>>> graded.info["refined_labels"], graded.info["graded"]
([1, 2, 3], True)
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warpmesh._util.arrays import sorted_unique
from warpmesh._util.parallel import cpu_view, launch_split
from warpmesh.errors import WarpMeshError
from warpmesh.kernels import stuffing as K
from warpmesh.solid.graded import EDGE_KEY, SizeField, refine_tets, tet_edges
from warpmesh.solid.lattice import lattice_tables, node_coordinates

__all__ = ["MARGIN", "MIN_RUN", "Specks", "VoxelLabels", "graded_background", "labels_at", "speck_voxels",
           "unresolved_edges"]

#: cubes of the BCC lattice kept around the meshed voxels
MARGIN = 2
#: a run of labels shorter than this (voxels) inside an edge is not a region the edge crosses:
#: a layer one voxel thick gives a run of about one voxel at any angle, a voxel's corner less
MIN_RUN = 0.75


def labels_at(codes: np.ndarray, local: np.ndarray, spacing: np.ndarray, rest: int) -> np.ndarray:
    """The code of the voxel holding each local point (voxel i at i * spacing, the nearest),
    ``rest`` outside the box. A point on a face between two voxels, or within
    ``VOXEL_TIE`` = 2^-20 of a voxel of it, is in the upper one: the lattice's nodes and
    samples lie on the faces at the default size, and their positions are computed, so a
    tie broken by the rounding of the position (as ``np.rint``'s ties to even did) made the
    mesh depend on the unit of the spacing (1e-9 of a voxel moved a region's volume by 8 %).

    (Called on every sample of every edge the graded lattice tests: one flat gather from the
    volume's memory where it is contiguous, one unsigned compare for both bounds.)

    >>> labels_at(np.arange(8, dtype=np.uint8).reshape(2, 2, 2),
    ...           np.array([[0.0, 0, 0], [2.4, 0, 0.6], [1.0, 0.5, 0.5 - 1e-9], [9, 0, 0]]), np.array([2.0, 1, 1]),
    ...           255).tolist()
    [0, 5, 7, 255]
    """
    ijk = np.rint(local / spacing + K.VOXEL_TIE).astype(np.int64)
    ok = ijk.view(np.uint64) < np.asarray(codes.shape, np.uint64)  # a negative index wraps to a huge one
    inside = ok[:, 0] & ok[:, 1] & ok[:, 2]
    if codes.flags.f_contiguous or codes.flags.c_contiguous:
        flat = np.ravel_multi_index(ijk.T, codes.shape, mode="clip", order="F" if codes.flags.f_contiguous else "C")
        out = codes.ravel(order="A")[flat]  # (a copy: fancy indexing)
        out[~inside] = rest
        return out
    out = np.full(len(local), rest, dtype=codes.dtype)
    ii = ijk[inside]
    out[inside] = codes[ii[:, 0], ii[:, 1], ii[:, 2]]
    return out


class VoxelLabels:
    """:func:`labels_at` of one code volume as a callable (n, 3) local points -> (n,) codes,
    the ``labels_at`` :func:`graded_background` takes; :func:`unresolved_edges` samples its
    edges in a Warp kernel when handed one (codes uint8, uint16 or int32, contiguous).

    >>> VoxelLabels(np.zeros((2, 2, 2), np.uint8), [1.0, 1, 1], 9)(np.array([[0.2, 0, 0], [5.0, 0, 0]])).tolist()
    [0, 9]
    """

    def __init__(self, codes: np.ndarray, spacing, rest: int):
        self.codes, self.spacing, self.rest = codes, np.asarray(spacing, np.float64), int(rest)

    def __call__(self, local: np.ndarray) -> np.ndarray:
        return labels_at(self.codes, local, self.spacing, self.rest)

    def kernel_codes(self):
        """(flat Warp view of the codes, element strides) for the kernel, or None when the
        codes' dtype or layout has no kernel."""
        c = self.codes
        if c.ndim != 3 or c.dtype not in (np.uint8, np.uint16, np.int32) or not (
                c.flags.c_contiguous or c.flags.f_contiguous):
            return None
        flat = c.ravel(order="A")  # a view
        return cpu_view(flat, wp.dtype_from_numpy(c.dtype)), wp.vec3l(*(int(st) // c.itemsize for st in c.strides))


def unresolved_edges(labels_at, a: np.ndarray, b: np.ndarray, spacing: np.ndarray, per_voxel: int,
                     min_run: int | None = None, focus=None, chunk: int = 1 << 21, kernel: bool = True) -> np.ndarray:
    """(e,) bool: True where the labels along the segment a -> b (local positions (e, 3))
    change more than once, sampled ``per_voxel`` times per voxel of the smallest spacing, the
    ends included; a run of fewer than ``min_run`` samples between two others (default
    ``MIN_RUN`` voxels' worth) does not count (an edge clipping a voxel's corner). ``focus``,
    optional: (c,) bool by code, an edge counts only when one of its runs is of a code in focus.

    With a :class:`VoxelLabels` (and ``kernel``) the edges are sampled in a Warp kernel over
    the CPU cores, one pass per edge with no sample stored
    (:func:`~warpmesh.kernels.stuffing.unresolved_edges_kernel`); otherwise numpy, in chunks of
    ``chunk`` samples. Both give the same answer (tested)."""
    min_run = max(1, int(round(MIN_RUN * per_voxel))) if min_run is None else int(min_run)
    out = np.zeros(len(a), bool)
    if not len(a):
        return out
    length = np.linalg.norm(b - a, axis=1)
    n = np.maximum(4, np.ceil(per_voxel * length / float(np.min(spacing)) - 1e-9).astype(np.int64))  # (not a rounding's +1)
    view = labels_at.kernel_codes() if kernel and isinstance(labels_at, VoxelLabels) else None
    if view is not None:
        flags = np.zeros(len(a), np.int8)
        use = focus is not None
        fo = np.ascontiguousarray(focus, dtype=np.int8) if use else np.zeros(1, np.int8)
        shape = wp.vec3i(*(int(x) for x in labels_at.codes.shape))
        launch_split(K.unresolved_edges_kernel, len(a),
                     [cpu_view(np.asarray(a, np.float64), wp.vec3d), cpu_view(np.asarray(b, np.float64), wp.vec3d),
                      cpu_view(n.astype(np.int32), wp.int32),
                      view[0], wp.vec3d(*labels_at.spacing.tolist()), shape, view[1], labels_at.rest, min_run,
                      cpu_view(fo, wp.int8), int(use)], [cpu_view(flags, wp.int8)], min_per_worker=1 << 10)
        return flags.astype(bool)
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

    def __init__(self, labels_at, spacing, h: float, min_size: float, per_voxel: int, focus, specks=None):
        self.labels_at, self.spacing, self.h, self.min_size = labels_at, spacing, h, min_size
        self.per_voxel, self.focus, self.specks = per_voxel, focus, specks
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
        size = np.where(unresolved, self.min_size, self.h)
        if self.specks is not None:
            np.minimum(size, self.specks.size_of(nodes, tets), out=size)
        return size


class Specks:
    """The voxels of the small components of some regions (specks), and the size the lattice
    is asked to have over them: ``size_of(nodes, tets)`` is that size for a tetrahedron whose
    bounding box meets a speck's voxel, ``inf`` elsewhere.

    The test is exact at voxel granularity for small tetrahedra and conservative for large
    ones: a tetrahedron whose bounding box spans at most 2^k voxels along every axis is tested
    against the blocks of 2^k voxels holding a speck voxel (8 look-ups in sorted keys), so a
    large tetrahedron is refined when it is within its own size of a speck, and its children are
    tested again; a coarse dense mask of blocks first leaves out the tetrahedra nowhere near.

    Parameters
    ----------
    voxels : (m, 3) int, the speck voxels' indices
    sizes : (m,) float, the size asked over each (world units)
    shape : (3,) the volume's shape
    spacing : (3,) float
    largest : float, the longest edge a tetrahedron asked may have (world units)
    """

    def __init__(self, voxels: np.ndarray, sizes: np.ndarray, shape, spacing: np.ndarray, largest: float):
        self.shape = np.asarray(shape, np.int64)
        self.spacing = np.asarray(spacing, np.float64)
        voxels = np.asarray(voxels, np.int64).reshape(-1, 3)
        sizes = np.asarray(sizes, np.float64)
        self.levels = sorted(set(sizes.tolist()))  # a few distinct sizes
        span = max(1.0, float(largest) / float(self.spacing.min()))
        self.top = int(np.ceil(np.log2(span))) + 1  # block 2^top voxels >= any bounding box
        self.keys = {}  # (size, k) -> sorted block keys of the voxels asking that size or less
        for size in self.levels:
            v = voxels[sizes <= size]
            for k in range(self.top + 1):
                self.keys[size, k] = sorted_unique(self._key(v >> k, k))
        b = voxels >> self.top
        coarse = np.zeros(tuple((self.shape >> self.top) + 3), bool)  # one block of margin each side
        for d in np.ndindex(3, 3, 3):
            coarse[tuple((b + np.array(d)).T)] = True  # dilated by one block
        self.coarse = coarse
        # the same, packed for the kernel: every (size, k) run of keys in one array, size-major
        runs = [self.keys[size, k] for size in self.levels for k in range(self.top + 1)]
        self._packed = np.concatenate(runs + [np.zeros(0, np.int64)]).astype(np.int64)
        self._offsets = np.concatenate([[0], np.cumsum([len(r) for r in runs], dtype=np.int64)]).astype(np.int32)

    def _key(self, cells: np.ndarray, k: int) -> np.ndarray:
        n = (self.shape >> k) + 1
        return cells[:, 0] + n[0] * (cells[:, 1] + n[1] * cells[:, 2])

    def size_of(self, nodes: np.ndarray, tets: np.ndarray, kernel: bool = True) -> np.ndarray:
        """(k,) the size asked of each tetrahedron (``inf`` where no speck is near): one thread
        per tetrahedron (:func:`~warpmesh.kernels.stuffing.speck_sizes_kernel`), or with
        ``kernel=False`` numpy, by levels of block size (the reference; both are tested equal)."""
        out = np.full(len(tets), np.inf)
        if not len(tets) or not self.levels:
            return out
        if kernel:
            launch_split(K.speck_sizes_kernel, len(tets),
                         [cpu_view(np.asarray(nodes, np.float64), wp.vec3d),
                          cpu_view(np.asarray(tets, np.int64).reshape(-1), wp.int64),
                          wp.vec3d(*self.spacing.tolist()), wp.vec3i(*(int(x) for x in self.shape)), int(self.top),
                          cpu_view(self.coarse.view(np.uint8).reshape(-1), wp.uint8),
                          wp.vec3i(*self.coarse.shape), cpu_view(self._packed, wp.int64),
                          cpu_view(self._offsets, wp.int32), cpu_view(np.asarray(self.levels, np.float64), wp.float64)],
                         [cpu_view(out, wp.float64)])
            return out
        p = nodes[tets] / self.spacing  # voxel units: voxel i covers [i - 1/2, i + 1/2)
        lo = np.floor(p.min(axis=1) + 0.5 + K.VOXEL_TIE).astype(np.int64)  # (labels_at's voxels)
        hi = np.floor(p.max(axis=1) + 0.5 + K.VOXEL_TIE).astype(np.int64)
        inside = np.all((hi >= 0) & (lo < self.shape), axis=1)
        lo, hi = np.maximum(lo, 0), np.minimum(hi, self.shape - 1)
        centre = (lo + hi) >> 1
        cand = np.flatnonzero(inside)
        cand = cand[self.coarse[tuple(((centre[cand] >> self.top) + 1).T)]]
        if not len(cand):
            return out
        lo, hi = lo[cand], hi[cand]
        span = (hi - lo).max(axis=1)
        k = np.ceil(np.log2(np.maximum(span, 1))).astype(np.int64)
        got = np.full(len(cand), np.inf)
        for kk in np.unique(k):
            r = np.flatnonzero(k == kk)
            a, b = lo[r] >> kk, hi[r] >> kk
            corners = [self._key(np.where(np.array(c, bool), b, a), int(kk)) for c in np.ndindex(2, 2, 2)]
            for size in reversed(self.levels):  # the largest first: the smallest hit wins
                keys = self.keys[size, int(kk)]
                if not len(keys):
                    continue
                hit = np.zeros(len(r), bool)
                for key in corners:
                    pos = np.minimum(np.searchsorted(keys, key), len(keys) - 1)
                    hit |= keys[pos] == key
                got[r[hit]] = size
        out[cand] = got
        return out


def speck_voxels(codes: np.ndarray, focus: np.ndarray, spacing: np.ndarray, most: float):
    """The voxels of the connected components (26-connected) of the codes in ``focus`` whose
    volume is at most ``most`` (world units): (m, 3) int64 indices, (m,) float64 the thickness
    of each one's component (2 volume / area of its voxels' boundary, world units: 1/3 of a
    voxel's side for a lone voxel of a cube, 1 for a layer 2 voxels thick), and the codes whose
    every component is that small (a list).

    Example
    -------
    >>> vol = np.ones((6, 6, 6), np.uint8)
    >>> vol[1, 1, 1] = 2
    >>> vol[3:5, 3:5, 3:5] = 2
    >>> focus = np.array([False, False, True])
    >>> voxels, thickness, whole = speck_voxels(vol, focus, np.ones(3), 8.0)
    >>> len(voxels), sorted(set(np.round(thickness, 2).tolist())), whole
    (9, [0.33, 0.67], [2])
    """
    from scipy.ndimage import find_objects, label

    voxel = float(np.prod(spacing))
    found, count, all_small = [np.zeros((0, 3), np.int64)], [np.zeros(0)], []
    boxes = find_objects(codes)
    for c in np.flatnonzero(focus):
        box = boxes[c - 1] if 0 < c <= len(boxes) else tuple(slice(0, n) for n in codes.shape)
        if box is None:
            continue
        comp, n = label(codes[box] == c, structure=np.ones((3, 3, 3), bool))
        if not n:
            continue
        sizes = np.bincount(comp[comp > 0], minlength=n + 1)  # (the component voxels only: no int64 copy of the box)
        small = (sizes * voxel <= most)
        small[0] = False
        if not small.any():
            continue
        if small[1:].all():
            all_small.append(int(c))
        ijk = np.argwhere(small[comp])
        found.append(ijk + np.array([b.start for b in box]))
        area = np.zeros(n + 1)
        padded = np.pad(comp, 1)
        for a in range(3):  # the faces between a component's voxel and any other voxel, per component
            lo = padded[tuple(slice(0, -1) if k == a else slice(None) for k in range(3))]
            hi = padded[tuple(slice(1, None) if k == a else slice(None) for k in range(3))]
            diff = lo != hi
            face = voxel / float(spacing[a])
            area += face * (np.bincount(lo[diff], minlength=n + 1) + np.bincount(hi[diff], minlength=n + 1))
        count.append((2.0 * sizes * voxel / np.maximum(area, 1e-300))[comp[tuple(ijk.T)]])
    return np.concatenate(found), np.concatenate(count), all_small


def _meshed_cells(codes: np.ndarray, rest: int, spacing: np.ndarray, dims: np.ndarray, origin: np.ndarray,
                  h: float) -> np.ndarray:
    """(dims) bool: the cubes [origin + h c, origin + h (c + 1)) holding a meshed voxel's centre."""
    m = codes != rest
    for a in range(3):
        cell = np.floor((np.arange(codes.shape[a]) * spacing[a] - origin[a]) / h + K.VOXEL_TIE).astype(np.int64)
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
                      min_size: float, labels_at, per_voxel: int = 4, focus=None, specks=None):
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
    del ends, col, uid, ok  # (not held through the refinement)
    cell = used // 2
    ijk = np.stack([cell % dims[0], (cell // dims[0]) % dims[1], cell // (dims[0] * dims[1])], axis=1)
    coords = node_coordinates((used % 2)[:, None], ijk).astype(np.float64)  # half-cube units
    resolution = _Resolution(labels_at, spacing, h, min_size, per_voxel, focus, specks)
    smallest = min([min_size] + (list(specks.levels) if specks is not None else []))
    field = SizeField(lambda p: np.full(len(p), h), smallest, h)  # (names the smallest size in errors)
    try:
        coords, tets, levels = refine_tets(coords, tets, h, origin, field, tet_size=resolution)
    except ValueError as exc:  # the background's size limit
        raise ValueError(f"{exc}; for a label volume raise 'min_size' (got {min_size:g})") from None
    if not levels.any():
        return None
    node_pos = origin + coords * (0.5 * h)
    node_code = labels_at(node_pos)
    _check_boundary(node_pos, tets, node_code, rest)
    keep = np.any(node_code[tets] != rest, axis=1)
    info = {"graded_tets": int(len(tets)), "graded_levels": int(levels.max(initial=0)),
            "graded_edges_sampled": int(resolution.sampled)}
    return node_pos, node_code, tets[keep], info


def _check_boundary(points: np.ndarray, tets: np.ndarray, node_code: np.ndarray, rest: int) -> None:
    """The faces in one tetrahedron (the part's own boundary) must have their nodes in the
    rest (the faces matched by :func:`~warpmesh.cells.intersections.tet_faces`' kernels:
    4.4 M tetrahedra 1.5 -> 0.5 s against a sort of their faces)."""
    from warpmesh.cells.intersections import tet_faces

    boundary = tet_faces(points, tets).boundary
    wrong = np.any(node_code[boundary] != rest, axis=1)
    if wrong.any():
        raise WarpMeshError(f"{int(wrong.sum())} faces of the graded background with a meshed node "
                            "lie on its boundary; this is a bug (please report the volume), and 'min_size' "
                            "above size / 2 avoids it")
