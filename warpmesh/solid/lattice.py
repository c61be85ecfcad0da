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

from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh.kernels import stuffing as K
from warpmesh.solid.stencils import EDGES, LONG_FACES, stencil_tables

__all__ = ["lattice_tables", "node_coordinates", "Lattice"]


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
    """

    def __init__(self, dims, origin, h: float, device):
        self.dims_np = np.asarray(dims, dtype=np.int64)
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
        run_parallel([lambda a=a, b=b: self._launch(kernel, b - a, [a, *inputs], outputs)
                      for a, b in parallel_ranges(self.n_cells, self.device, min_per_worker=4096)])

    def _scan(self, counts: wp.array) -> tuple[wp.array, int]:
        offsets = wp.empty_like(counts)
        wp.utils.array_scan(counts, offsets, inclusive=False)
        total = int(offsets[-1:].numpy()[0] + counts[-1:].numpy()[0])  # sync point: output size
        return offsets, total

    # -- stages ------------------------------------------------------------------------------
    def node_points(self) -> wp.array:
        pts = wp.empty(self.n_nodes, dtype=wp.vec3, device=self.device)
        self._launch(K.lattice_points_kernel, self.n_nodes, [self.dims, self.worigin, self.h], [pts])
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
        self._launch(K.lattice_points_kernel, self.n_nodes, [self.dims, wp.vec3(0.0, 0.0, 0.0), self.h],
                     [self.node_pos])
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
        self._per_cell(K.write_cuts_kernel, [self.dims, self.h, self.signs, values, offsets],
                       [self.edge_cut, self.cut_slot, self.p0, self.p1, self.f_lo, self.f_hi])
        return n

    def roots(self, field, iterations: int) -> None:
        """Cut points on every cut edge by a bracketed root search of the exact (clipped)
        field: regula falsi with the Illinois modification (superlinear, never leaves the
        bracket). ``field`` maps world points (wp.array of vec3) to values (float32)."""
        n, dev = self.n_cuts, self.device
        t = wp.full(max(n, 1), 0.5, dtype=wp.float32, device=dev)
        t_lo = wp.zeros(max(n, 1), dtype=wp.float32, device=dev)
        t_hi = wp.ones(max(n, 1), dtype=wp.float32, device=dev)
        side = wp.zeros(max(n, 1), dtype=wp.int32, device=dev)
        world = wp.empty(max(n, 1), dtype=wp.vec3, device=dev)
        if n:
            self._launch(K.false_position_init_kernel, n, [self.f_lo, self.f_hi], [t])
            for _ in range(iterations):
                self._launch(K.edge_points_kernel, n, [t, self.p0, self.p1, self.worigin], [world])
                values = field(world[:n])
                self._launch(K.false_position_step_kernel, n, [values], [t_lo, t_hi, self.f_lo, self.f_hi, side, t])
        self.cut_t = t
        self.cut_pos = wp.empty(max(n, 1), dtype=wp.vec3, device=dev)
        if n:
            self._launch(K.cut_positions_kernel, n, [t, self.p0, self.p1], [self.cut_pos])

    def warp(self, alpha_long: float, alpha_short: float, order=(-1, 1)) -> int:
        """Move violated nodes onto their nearest violating cut point, outside nodes first
        (then inside nodes whose cut points survived); returns how many moved."""
        warped = wp.zeros(self.n_nodes, dtype=wp.int32, device=self.device)
        if self.n_cuts:
            for which in order:
                jobs = [lambda a=a, b=b, w=which: self._launch(
                    K.warp_nodes_kernel, b - a,
                    [a, int(w), self.dims, self.h, float(alpha_long), float(alpha_short), self.edge_cut,
                     self.cut_pos], [self.signs, self.node_pos, warped])
                    for a, b in parallel_ranges(self.n_nodes, self.device, min_per_worker=8192)]
                run_parallel(jobs)
        return int(warped.numpy().sum())  # sync point: statistics

    def fill(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The stencils of every background tetrahedron: (local points (n, 3) float64, tetrahedra
        (m, 4) int64, on_surface (n,) bool)."""
        dev = self.device
        counts = wp.empty(self.n_cells, dtype=wp.int32, device=dev)
        self._per_cell(K.count_tets_kernel, [self.dims, self.layout, self.face_bits, self.signs, self.count],
                       [counts])
        offsets, m = self._scan(counts)
        n_keys = self.n_nodes + self.n_cuts
        used = wp.zeros(n_keys, dtype=wp.int32, device=dev)
        tets = wp.empty(max(m, 1), dtype=wp.vec4i, device=dev)
        self._per_cell(K.write_tets_kernel, [self.dims, self.n_nodes, self.layout, self.face_bits, self.edge_slot,
                                             self.signs, self.count, self.tets, self.edge_cut,
                                             offsets], [tets, used])
        ids, nv = self._scan(used)
        points = wp.empty(max(nv, 1), dtype=wp.vec3, device=dev)
        surf = wp.zeros(max(nv, 1), dtype=wp.uint8, device=dev)
        self._launch(K.gather_vertices_kernel, n_keys, [self.n_nodes, used, ids, self.node_pos, self.cut_pos,
                                                        self.signs], [points, surf])
        if m:
            self._launch(K.remap_tets_kernel, m, [ids], [tets])
        # sync point: the result to the host
        return (points.numpy()[:nv].astype(np.float64), tets.numpy()[:m].astype(np.int64),
                surf.numpy()[:nv].astype(bool))
