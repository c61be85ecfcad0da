"""The body-centred cubic lattice of isosurface stuffing: its background tetrahedra as tables,
and the typed launch wrappers of :mod:`warpmesh.kernels.stuffing`.

The twelve background tetrahedra of a black node B(c) (``layout``), the lattice edge of each
of their local edges (``edge_slots``) and the parity bits of their long-edge faces
(``face_bits``) are generated here from the lattice's coordinates; the stencils come from
:mod:`warpmesh.solid.stencils`.

Example
-------
>>> lay, slots, bits = lattice_tables()
>>> lay.shape, slots.shape, bits.shape
((12, 4, 4), (12, 6, 4), (12,))
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import warp as wp

from warpmesh._util.parallel import launch_split
from warpmesh.kernels import stuffing as K
from warpmesh.solid.stencils import EDGES, LONG_FACES, ranked_stencil_tables, stencil_tables

__all__ = ["lattice_tables", "node_coordinates", "Lattice", "Background", "bracketed_roots"]


def node_coordinates(colour: int, offset) -> np.ndarray:
    """Doubled integer coordinates of a node: 2 offset (+1 per axis for a red node)."""
    return 2 * np.asarray(offset, dtype=np.int64) + colour


@lru_cache(maxsize=1)
def lattice_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(layout (12, 4, 4), edge_slots (12, 6, 4), face_bits (12,)) int32.

    ``layout[t, v]`` = (colour, dx, dy, dz) of local vertex v of background tetrahedron t of a
    black node, ordered (B0, B1, R0, R1) with positive volume; ``edge_slots[t, e]`` = (dx, dy,
    dz, d): the owner cell's offset and slot of local edge e (``stencils.EDGES``);
    ``face_bits[t]`` has bit f set when the parity rule splits the quadrilateral of long-edge
    face f (``stencils.LONG_FACES``) from the second end of its long edge.
    """
    layout = np.zeros((12, 4, 4), np.int32)
    slots = np.zeros((12, 6, 4), np.int32)
    bits = np.zeros(12, np.int32)
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        eb, ec, ea = np.eye(3, dtype=np.int64)[[b, c, a]]
        around = [0 * ea, eb, eb + ec, ec]  # the four cube centres around the edge, in turn
        for q in range(4):
            t = 4 * a + q
            verts = [(0, 0 * ea), (0, ea), (1, -around[q]), (1, -around[(q + 1) % 4])]
            pos = np.array([node_coordinates(col, off) / 2.0 for col, off in verts])
            if np.dot(np.cross(pos[1] - pos[0], pos[2] - pos[0]), pos[3] - pos[0]) < 0:
                verts[2], verts[3] = verts[3], verts[2]
            for v, (col, off) in enumerate(verts):
                layout[t, v] = (col, *off)
            for e, (i, j) in enumerate(EDGES):
                (ci, oi), (cj, oj) = verts[i], verts[j]
                if ci == cj:  # a long edge: owned by its lower end, slot = axis (+3 for red)
                    axis = int(np.flatnonzero(oi != oj)[0])
                    owner = np.minimum(oi, oj)
                    slots[t, e] = (*owner, axis + 3 * ci)
                else:  # a short edge: owned by the red end, slot 6 + corner of the black end
                    red, black = (oi, oj) if ci == 1 else (oj, oi)
                    corner = black - red
                    assert set(corner.tolist()) <= {0, 1}
                    slots[t, e] = (*red, 6 + corner[0] + 2 * corner[1] + 4 * corner[2])
            for f, (u, v, w) in enumerate(LONG_FACES):
                pu, pv, pw = (node_coordinates(*verts[x]) for x in (u, v, w))
                k = int(np.flatnonzero(pu != pv)[0])
                parity = int(verts[u][0] == 0) + int(pv[k] < pu[k]) + sum(int(pw[j] < pu[j]) for j in range(3) if j != k)
                bits[t] |= (parity & 1) << f
    for arr in (layout, slots, bits):
        arr.setflags(write=False)
    return layout, slots, bits


def bracketed_roots(n: int, p0: wp.array, p1: wp.array, f_lo: wp.array, f_hi: wp.array, worigin, field,
                    iterations: int, device) -> tuple[wp.array, wp.array]:
    """(t, cut positions (local)) of ``n`` cut edges p0 -> p1 (local; the field f_lo, f_hi at
    their ends) by regula falsi with the Illinois modification (superlinear, never leaves the
    bracket) on the exact field: ``field`` maps world points (wp.array of vec3, world = worigin
    + local) to values (float32). f_lo and f_hi are overwritten.

    Example
    -------
    The unit sphere's field 1 - |x|^2 on the edge (0, 0, 0) -> (2, 0, 0):

    >>> import numpy as np, warp as wp
    >>> edge = [wp.array([p], dtype=wp.vec3) for p in ((0.0, 0.0, 0.0), (2.0, 0.0, 0.0))]
    >>> field = lambda x: wp.array(1 - np.linalg.norm(x.numpy(), axis=1) ** 2, dtype=wp.float32)
    >>> ends = [wp.array([v], dtype=wp.float32) for v in (1.0, -3.0)]
    >>> t, pos = bracketed_roots(1, *edge, *ends, wp.vec3(0.0, 0.0, 0.0), field, 8, "cpu")
    >>> float(t.numpy()[0]), pos.numpy()[0].tolist()
    (0.5, [1.0, 0.0, 0.0])
    """
    t = wp.full(max(n, 1), 0.5, dtype=wp.float32, device=device)
    t_lo = wp.zeros(max(n, 1), dtype=wp.float32, device=device)
    t_hi = wp.ones(max(n, 1), dtype=wp.float32, device=device)
    side = wp.zeros(max(n, 1), dtype=wp.int32, device=device)
    world = wp.empty(max(n, 1), dtype=wp.vec3, device=device)
    if n:
        wp.launch(K.false_position_init_kernel, dim=n, inputs=[f_lo, f_hi], outputs=[t], device=device)
        for _ in range(iterations):
            wp.launch(K.edge_points_kernel, dim=n, inputs=[t, p0, p1, worigin], outputs=[world], device=device)
            values = field(world[:n])
            wp.launch(K.false_position_step_kernel, dim=n, inputs=[values],
                      outputs=[t_lo, t_hi, f_lo, f_hi, side, t], device=device)
    pos = wp.empty(max(n, 1), dtype=wp.vec3, device=device)
    if n:
        wp.launch(K.cut_positions_kernel, dim=n, inputs=[t, p0, p1], outputs=[pos], device=device)
    return t, pos


#: short edge / long edge of a BCC tetrahedron
_SHORT = float(np.sqrt(3.0) / 2.0)
_DEVICE_TABLES: dict[str, tuple] = {}


def _device_tables(device):
    key = str(device)
    if key not in _DEVICE_TABLES:
        layout, slots, bits = lattice_tables()
        count, tets = stencil_tables()
        _DEVICE_TABLES[key] = tuple(wp.array(np.ascontiguousarray(x), dtype=wp.int32, device=device)
                                    for x in (layout, slots, bits, count, tets))
    return _DEVICE_TABLES[key]


class Lattice:
    """The device arrays of one stuffing run over a BCC lattice, and its launches.

    Parameters
    ----------
    dims : (3,) int
        Black nodes per axis.
    origin : (3,) float
        World position of black node (0, 0, 0).
    h : float
        Cube side (the long edge).
    device : str
    offset : (3,) int, optional
        When this lattice is a window of a larger one: the global cell of its cell (0, 0, 0)
        (``origin`` stays the global lattice's). Positions are then the global nodes', bit for bit.
    own : ((3,) int, (3,) int), optional
        The window's cells ``lo <= c < hi`` whose tetrahedra :meth:`fill` emits (default: all).
    """

    def __init__(self, dims, origin, h: float, device, offset=(0, 0, 0), own=None):
        self.dims_np = np.asarray(dims, dtype=np.int64)
        self.offset_np = np.asarray(offset, dtype=np.int64)
        self.offset = wp.vec3i(*self.offset_np.tolist())
        own_lo, own_hi = own if own is not None else ((0, 0, 0), self.dims_np)
        self.own_np = tuple(np.asarray(v, dtype=np.int64) for v in (own_lo, own_hi))
        self.own = tuple(wp.vec3i(*v.tolist()) for v in self.own_np)
        self.n_cells = int(np.prod(self.dims_np))
        self.n_nodes = 2 * self.n_cells
        if self.n_cells * K.SLOTS >= 2**31 - 1:
            raise ValueError(f"a lattice of {self.dims_np.tolist()} cubes is too large to index (int32): "
                             "raise 'size'")
        self.dims = wp.vec3i(*self.dims_np.tolist())
        self.origin = np.asarray(origin, dtype=np.float64)
        self.worigin = wp.vec3(*self.origin.tolist())
        self.h = float(h)
        self.device = device
        wp.load_module(K, device=device)  # compile/load once here, not in worker threads
        (self.layout, self.edge_slot, self.face_bits, self.count, self.tets) = _device_tables(device)

    def _launch(self, kernel, dim, inputs, outputs=()):
        wp.launch(kernel, dim=dim, inputs=inputs, outputs=list(outputs), device=self.device)

    def _per_cell(self, kernel, inputs, outputs) -> None:
        """One thread per cell, split across CPU cores."""
        launch_split(kernel, self.n_cells, inputs, list(outputs), self.device, min_per_worker=4096)

    def _scan(self, counts: wp.array) -> tuple[wp.array, int]:
        offsets = wp.empty_like(counts)
        wp.utils.array_scan(counts, offsets, inclusive=False)
        total = int(offsets[-1:].numpy()[0] + counts[-1:].numpy()[0])  # sync point: output size
        return offsets, total

    # -- stages ------------------------------------------------------------------------------
    def node_points(self) -> wp.array:
        pts = wp.empty(self.n_nodes, dtype=wp.vec3, device=self.device)
        self._launch(K.lattice_points_kernel, self.n_nodes, [self.dims, self.offset, self.worigin, self.h], [pts])
        return pts

    def clip(self, points: wp.array, f: wp.array, lo, hi) -> wp.array:
        out = wp.empty(points.shape[0], dtype=wp.float32, device=self.device)
        if points.shape[0]:
            self._launch(K.clip_values_kernel, points.shape[0], [points, f, wp.vec3(*lo), wp.vec3(*hi)], [out])
        return out

    def classify(self, values: wp.array) -> int:
        """Node signs from the clipped values; returns the number of NaN values."""
        self.signs = wp.empty(self.n_nodes, dtype=wp.int8, device=self.device)
        bad = wp.zeros(1, dtype=wp.int32, device=self.device)
        self._launch(K.node_signs_kernel, self.n_nodes, [self.dims, values], [self.signs, bad])
        self.node_pos = wp.empty(self.n_nodes, dtype=wp.vec3, device=self.device)
        self._launch(K.lattice_points_kernel, self.n_nodes, [self.dims, self.offset, wp.vec3(0.0, 0.0, 0.0),
                                                             self.h], [self.node_pos])
        return int(bad.numpy()[0])  # sync point: validation

    def cut_edges(self, values: wp.array) -> int:
        """The edges joining a + and a - node: their bracket (p0, p1 local, the clipped field at
        both ends)."""
        counts = wp.empty(self.n_cells, dtype=wp.int32, device=self.device)
        self._per_cell(K.count_cuts_kernel, [self.dims, self.signs], [counts])
        offsets, n = self._scan(counts)
        self.n_cuts = n
        dev = self.device
        self.edge_cut = wp.empty(self.n_cells * K.SLOTS, dtype=wp.int32, device=dev)
        self.cut_slot = wp.empty(max(n, 1), dtype=wp.int32, device=dev)
        self.p0 = wp.empty(max(n, 1), dtype=wp.vec3, device=dev)
        self.p1 = wp.empty(max(n, 1), dtype=wp.vec3, device=dev)
        self.f_lo = wp.empty(max(n, 1), dtype=wp.float32, device=dev)
        self.f_hi = wp.empty(max(n, 1), dtype=wp.float32, device=dev)
        self._per_cell(K.write_cuts_kernel, [self.dims, self.offset, self.h, self.signs, values, offsets],
                       [self.edge_cut, self.cut_slot, self.p0, self.p1, self.f_lo, self.f_hi])
        return n

    def roots(self, field, iterations: int) -> None:
        """Cut points on every cut edge by a bracketed root search of the exact (clipped)
        field (:func:`bracketed_roots`). ``field`` maps world points (wp.array of vec3) to
        values (float32)."""
        self.cut_t, self.cut_pos = bracketed_roots(self.n_cuts, self.p0, self.p1, self.f_lo, self.f_hi,
                                                   self.worigin, field, iterations, self.device)

    def warp(self, alpha_long: float, alpha_short: float, order=(-1, 1)) -> int:
        """Move violated nodes onto their nearest violating cut point, outside nodes first
        (then inside nodes whose cut points survived); returns how many moved."""
        self.warped = warped = wp.zeros(self.n_nodes, dtype=wp.int32, device=self.device)
        if self.n_cuts:
            for which in order:
                launch_split(K.warp_nodes_kernel, self.n_nodes,
                             [int(which), self.dims, self.h, float(alpha_long), float(alpha_short), self.edge_cut,
                              self.cut_pos], [self.signs, self.node_pos, warped], self.device, min_per_worker=8192)
        return int(warped.numpy().sum())  # sync point: statistics

    def owned_counts(self) -> tuple[int, int]:
        """(cut edges, warped nodes) of the owned cells (an edge's owner cell, a node's cell):
        summed over windows whose owned cells tile the lattice, the whole lattice's counts."""
        d, (lo, hi) = self.dims_np, self.own_np

        def owned(cell: np.ndarray) -> int:
            c = np.stack([cell % d[0], cell // d[0] % d[1], cell // (d[0] * d[1])], axis=1)
            return int(((c >= lo) & (c < hi)).all(axis=1).sum())

        # sync point: statistics
        return (owned(self.cut_slot.numpy()[:self.n_cuts].astype(np.int64) // K.SLOTS),
                owned(np.flatnonzero(self.warped.numpy()) // 2))

    def fill(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The stencils of every background tetrahedron (of the owned cells): (local points
        (n, 3) float64, tetrahedra (m, 4) int64, on_surface (n,) bool)."""
        counts, used, tets, m = self._stencils()
        return _used_vertices(self, used, tets, m)

    def fill_keyed(self, global_dims) -> tuple[np.ndarray, ...]:
        """:meth:`fill`, and each vertex's key in the global lattice of ``global_dims`` black
        nodes per axis (n,) int64: a node ``2 cell + colour``, a cut point ``2 cells + 14 cell
        + slot`` (its lattice edge), so keys sort as the whole lattice numbers its vertices;
        and each tetrahedron's global black node (m,) int64, which orders them as the whole
        lattice does."""
        counts, used, tets, m = self._stencils()
        flags = used.numpy()[:self.n_nodes + self.n_cuts]  # sync point: the used keys, in vertex order
        points, tets, surf = _used_vertices(self, used, tets, m)
        local = np.flatnonzero(flags)
        gd = np.asarray(global_dims, dtype=np.int64)
        node = local < self.n_nodes
        keys = np.empty(len(local), dtype=np.int64)
        keys[node] = 2 * self._global_cell(local[node] // 2, gd) + local[node] % 2
        slot = self.cut_slot.numpy()[local[~node] - self.n_nodes].astype(np.int64)
        keys[~node] = 2 * int(np.prod(gd)) + K.SLOTS * self._global_cell(slot // K.SLOTS, gd) + slot % K.SLOTS
        owner = np.repeat(self._global_cell(np.arange(self.n_cells, dtype=np.int64), gd), counts.numpy())
        return points, tets, surf, keys, owner

    def _global_cell(self, cell: np.ndarray, global_dims: np.ndarray) -> np.ndarray:
        d = self.dims_np
        x, y, z = cell % d[0] + self.offset_np[0], cell // d[0] % d[1] + self.offset_np[1], \
            cell // (d[0] * d[1]) + self.offset_np[2]
        return x + global_dims[0] * (y + global_dims[1] * z)

    def _stencils(self):
        """Count, scan and write the owned cells' tetrahedra (as vertex keys): (counts per cell,
        used keys, tetrahedra, how many)."""
        dev = self.device
        counts = wp.empty(self.n_cells, dtype=wp.int32, device=dev)
        self._per_cell(K.count_tets_kernel, [self.dims, *self.own, self.layout, self.face_bits, self.signs,
                                             self.count], [counts])
        offsets, m = self._scan(counts)
        n_keys = self.n_nodes + self.n_cuts
        used = wp.zeros(n_keys, dtype=wp.int32, device=dev)
        tets = wp.empty(max(m, 1), dtype=wp.vec4i, device=dev)
        self._per_cell(K.write_tets_kernel, [self.dims, *self.own, self.n_nodes, self.layout, self.face_bits,
                                             self.edge_slot, self.signs, self.count, self.tets, self.edge_cut,
                                             offsets], [tets, used])
        return counts, used, tets, m


def _used_vertices(run, used: wp.array, tets: wp.array, m: int):
    """The vertices the ``m`` tetrahedra use (``used`` flags over nodes then cut points, of a
    :class:`Lattice` or :class:`Background` run), numbered compactly, and the tetrahedra
    renumbered: (points (nv, 3) float64, tets (m, 4) int64, on-surface flags (nv,) bool)."""
    ids, nv = run._scan(used)
    points = wp.empty(max(nv, 1), dtype=wp.vec3, device=run.device)
    surf = wp.zeros(max(nv, 1), dtype=wp.uint8, device=run.device)
    run._launch(K.gather_vertices_kernel, run.n_nodes + run.n_cuts, [run.n_nodes, used, ids, run.node_pos,
                                                                     run.cut_pos, run.signs], [points, surf])
    if m:
        run._launch(K.remap_tets_kernel, m, [ids], [tets])
    # sync point: the result to the host
    return (points.numpy()[:nv].astype(np.float64), tets.numpy()[:m].astype(np.int64),
            surf.numpy()[:nv].astype(bool))


class Background:
    """The device arrays of one stuffing run over an explicit (graded) background mesh, and
    its launches: the same stages as :class:`Lattice`, with nodes, edges and tetrahedra
    listed instead of implied by a lattice.

    Parameters
    ----------
    local : (n, 3) float
        Node positions relative to ``origin``.
    tets : (m, 4) int
        Background tetrahedra (any orientation; relisted here by increasing vertex id, the
        order :func:`warpmesh.solid.stencils.ranked_diagonal` needs).
    origin : (3,) float
    alpha_long, alpha_short : float
        The violation thresholds of the long and short edges of the BCC tetrahedra (the
        uniform regions); an edge of a transition tetrahedron (half, quarter, or any that is
        not a BCC tetrahedron) takes the smaller of the two (measured: 10.4°-158° on a graded
        sphere where the paper's pair by edge length gave 1.2°-176°).
    device : str
    """

    def __init__(self, local, tets, origin, alpha_long: float, alpha_short: float, device):
        local = np.asarray(local, dtype=np.float64)
        tets = np.sort(np.asarray(tets, dtype=np.int64), axis=1)
        n = len(local)
        if n >= 2**31 - 1 or len(tets) * 6 >= 2**31 - 1:
            raise ValueError(f"a background of {len(tets)} tetrahedra is too large to index (int32): raise 'size'")
        p = local[tets]
        vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0])
        a, b = tets[:, [e[0] for e in EDGES]], tets[:, [e[1] for e in EDGES]]  # a < b: sorted rows
        keys = a * n + b
        uniq, inv = np.unique(keys, return_inverse=True)
        inv = inv.reshape(-1, 6)
        edges = np.stack([uniq // n, uniq % n], axis=1)
        length = np.linalg.norm(local[edges[:, 0]] - local[edges[:, 1]], axis=1)
        tl = length[inv]
        top = tl.max(axis=1, keepdims=True)
        srt = np.sort(tl, axis=1) / top
        bcc = (np.abs(srt[:, 4:] - 1.0) < 1e-6).all(axis=1) & (np.abs(srt[:, :4] - _SHORT) < 1e-6).all(axis=1)
        short = np.zeros(len(uniq), bool)  # the short edges of BCC tetrahedra
        short[inv[bcc][tl[bcc] < top[bcc] * (1 - 1e-6)]] = True
        transition = np.zeros(len(uniq), bool)  # edges of a half, quarter or other non-BCC tetrahedron
        transition[inv[~bcc].ravel()] = True
        alpha = np.where(transition, min(alpha_long, alpha_short), np.where(short, alpha_short, alpha_long))
        ends = np.concatenate([edges[:, 0], edges[:, 1]])
        order = np.argsort(ends, kind="stable")
        star = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(ends, minlength=n), out=star[1:])
        self.n_nodes, self.n_tets, self.n_edges = n, len(tets), len(uniq)
        self.origin = np.asarray(origin, dtype=np.float64)
        self.worigin = wp.vec3(*self.origin.tolist())
        self.device = dev = device
        wp.load_module(K, device=device)

        def up(x, dtype):
            return wp.array(np.ascontiguousarray(x), dtype=dtype, device=dev)

        self.local = up(local.astype(np.float32), wp.vec3)
        self.tets = up(tets.astype(np.int32), wp.vec4i)
        self.tet_edges = up(inv.astype(np.int32), wp.int32)
        self.flip = up((vol < 0).astype(np.int32), wp.int32)
        self.edges = up(edges.astype(np.int32), wp.vec2i)
        self.edge_length = up(length.astype(np.float32), wp.float32)
        self.edge_alpha = up(alpha.astype(np.float32), wp.float32)
        self.star = up(star.astype(np.int32), wp.int32)
        self.star_edges = up((order % len(uniq)).astype(np.int32), wp.int32)
        count, table = ranked_stencil_tables()
        self.count, self.table = up(count, wp.int32), up(table, wp.int32)

    def _launch(self, kernel, dim, inputs, outputs=()):
        wp.launch(kernel, dim=dim, inputs=inputs, outputs=list(outputs), device=self.device)

    def _split(self, kernel, n, inputs, outputs, min_per_worker=4096) -> None:
        """A launch over [0, n) with ``first`` as its first input, split across CPU cores."""
        launch_split(kernel, n, inputs, list(outputs), self.device, min_per_worker=min_per_worker)

    def _scan(self, counts: wp.array) -> tuple[wp.array, int]:
        offsets = wp.empty_like(counts)
        wp.utils.array_scan(counts, offsets, inclusive=False)
        total = int(offsets[-1:].numpy()[0] + counts[-1:].numpy()[0])  # sync point: output size
        return offsets, total

    def node_points(self) -> wp.array:
        """World positions of the nodes."""
        pts = wp.empty(self.n_nodes, dtype=wp.vec3, device=self.device)
        self._launch(K.edge_points_kernel, self.n_nodes,
                     [wp.zeros(self.n_nodes, dtype=wp.float32, device=self.device), self.local, self.local,
                      self.worigin], [pts])
        return pts

    def classify(self, values: wp.array) -> int:
        """Node signs from the clipped values; returns the number of NaN values."""
        self.signs = wp.empty(self.n_nodes, dtype=wp.int8, device=self.device)
        bad = wp.zeros(1, dtype=wp.int32, device=self.device)
        self._launch(K.mesh_node_signs_kernel, self.n_nodes, [values], [self.signs, bad])
        self.node_pos = wp.clone(self.local)
        return int(bad.numpy()[0])  # sync point: validation

    def cut_edges(self, values: wp.array) -> int:
        """The edges joining a + and a - node: their bracket."""
        dev = self.device
        flags = wp.empty(self.n_edges, dtype=wp.int32, device=dev)
        self._launch(K.count_mesh_cuts_kernel, self.n_edges, [self.edges, self.signs], [flags])
        offsets, n = self._scan(flags)
        self.n_cuts = n
        self.edge_cut = wp.empty(self.n_edges, dtype=wp.int32, device=dev)
        self.p0, self.p1 = (wp.empty(max(n, 1), dtype=wp.vec3, device=dev) for _ in range(2))
        self.f_lo, self.f_hi = (wp.empty(max(n, 1), dtype=wp.float32, device=dev) for _ in range(2))
        self._launch(K.write_mesh_cuts_kernel, self.n_edges, [self.edges, self.local, values, flags, offsets],
                     [self.edge_cut, self.p0, self.p1, self.f_lo, self.f_hi])
        return n

    def roots(self, field, iterations: int) -> None:
        """Cut points by :func:`bracketed_roots` on the exact (clipped) field."""
        self.cut_t, self.cut_pos = bracketed_roots(self.n_cuts, self.p0, self.p1, self.f_lo, self.f_hi,
                                                   self.worigin, field, iterations, self.device)

    def warp(self, order=(-1, 1)) -> int:
        """Move violated nodes onto their nearest violating cut point, outside nodes first;
        returns how many moved."""
        warped = wp.zeros(self.n_nodes, dtype=wp.int32, device=self.device)
        if self.n_cuts:
            for which in order:
                self._split(K.warp_mesh_nodes_kernel, self.n_nodes,
                            [int(which), self.star, self.star_edges, self.edges, self.edge_length, self.edge_alpha,
                             self.edge_cut, self.cut_pos], [self.signs, self.node_pos, warped], 8192)
        return int(warped.numpy().sum())  # sync point: statistics

    def fill(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The stencils of every background tetrahedron: (local points (n, 3) float64,
        tetrahedra (m, 4) int64, on_surface (n,) bool)."""
        dev = self.device
        counts = wp.empty(self.n_tets, dtype=wp.int32, device=dev)
        self._split(K.count_mesh_tets_kernel, self.n_tets, [self.tets, self.signs, self.local, self.count], [counts])
        offsets, m = self._scan(counts)
        n_keys = self.n_nodes + self.n_cuts
        used = wp.zeros(n_keys, dtype=wp.int32, device=dev)
        tets = wp.empty(max(m, 1), dtype=wp.vec4i, device=dev)
        self._split(K.write_mesh_tets_kernel, self.n_tets,
                    [self.n_nodes, self.tets, self.tet_edges, self.flip, self.signs, self.local, self.count, self.table,
                     self.edge_cut, offsets], [tets, used])
        return _used_vertices(self, used, tets, m)
