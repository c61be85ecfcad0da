"""Typed launch wrappers of the block-sparse grid [FG §16.4.1-16.4.2, §16.3.3].

:class:`BlockGrid` owns the device arrays of one extraction and launches the kernels of
:mod:`warpmesh.kernels.block_grid` (block culling and compaction: count -> prefix sum ->
allocate -> write; sampling a shape's tape or a volume's samples; capping) and of
:mod:`warpmesh.kernels.emit` (the two-pass emission of vertices and triangles by
"mc33", "mt" or "mc"); :func:`refine_roots` moves vertices onto the exact surface. Launches over slots are split across CPU cores from Python threads.
"""

from __future__ import annotations

import time

import numpy as np
import warp as wp

from warpmesh import _conventions as C
from warpmesh.frep import codegen
from warpmesh.errors import WarpMeshError
from warpmesh.kernels import block_grid as K
from warpmesh.kernels import emit as KE
from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh.frep.tape import eval_gradients, eval_intervals, eval_values

_TABLE_CACHE: dict[tuple[str, str], KE.Tables] = {}
METHODS = ("mc33", "mt", "mc")
#: method -> (kernel method id, vertex types per node: the grid-edge directions it uses)
_METHOD_IDS = {"mc": (KE.METHOD_MC, 3), "mc33": (KE.METHOD_MC33, 3), "mt": (KE.METHOD_MT, 7)}


def _host_tables(method: str) -> dict[str, np.ndarray]:
    """A method's tables as int32 numpy arrays, in the layout of ``kernels.emit.Tables``."""
    from warpmesh.kernels import mc_tables as MC

    one = np.zeros(1, np.int32)
    tabs = {"corners": MC.CORNERS, "type_delta": KE.TYPE_DELTA, "case_offset": one, "interior_test": one,
            "test_corners": np.zeros((1, 1), np.int32),
            "face_corners": np.array(MC.FACES, dtype=np.int32)}
    if method == "mc":
        tabs.update(origin=MC.EDGE_ORIGIN, tri_count=MC.TRI_COUNT, tris=MC.TRI_TABLE.reshape(256, -1),
                    quad_count=np.zeros(256, np.int32), quads=np.zeros((256, 4), np.int32),
                    center=np.zeros(256, np.int32))
    elif method == "mt":
        from warpmesh.kernels import mt_tables as MT

        assert np.array_equal(MT.EDGE_TYPE_DELTA, KE.TYPE_DELTA[:7]), "vertex types disagree with kernels.emit"
        tabs.update(origin=MT.MT_EDGE_ORIGIN, tri_count=MT.MT_TRI_COUNT, tris=MT.MT_TRIS.reshape(256, -1),
                    quad_count=MT.MT_QUAD_COUNT, quads=MT.MT_QUADS.reshape(256, -1),
                    center=np.zeros(256, np.int32))
    else:
        from warpmesh.kernels import mc33_tables as M33

        tabs.update(M33.kernel_tables())
    tabs = {k: np.ascontiguousarray(v, dtype=np.int32) for k, v in tabs.items()}
    # kernels.emit.count_crossings_kernel skips the uncrossed configurations 0 and 255
    rows = [tabs["case_offset"][ci * 64] for ci in (0, 255)] if method == "mc33" else [0, 255]
    assert all(tabs["tri_count"][r] == tabs["quad_count"][r] == tabs["center"][r] == 0 for r in rows) \
        and (method != "mc33" or tabs["interior_test"][0] < 0 and tabs["interior_test"][255 * 64] < 0), \
        "an uncrossed cell has polygons in the tables"
    return tabs


def method_tables(method: str, device) -> KE.Tables:
    """The tables of an extraction method as a ``kernels.emit.Tables`` struct, uploaded
    once per device."""
    key = (method, str(device))
    if key not in _TABLE_CACHE:
        tab = KE.Tables()
        for name, arr in _host_tables(method).items():
            setattr(tab, name, wp.array(arr, dtype=wp.int32, device=device))
        _TABLE_CACHE[key] = tab
    return _TABLE_CACHE[key]


# -- the grid ----------------------------------------------------------------------------------
class BlockGrid:
    """The block-sparse grid of one extraction: its device arrays and the kernel launches
    (allocation, prefix sums, per-core splits), so that :func:`mesh_surface` reads as a pipeline."""

    def __init__(self, n_nodes, origin, h, device, node_offset=(0, 0, 0), global_nodes=None, global_origin=None,
                 window=None):
        self.n = np.asarray(n_nodes, dtype=np.int64)
        # a window, (k, 2, 3) inclusive node boxes, the first one the nodes of the cells that are
        # emitted: only blocks owning a window node get a slot; a block meshing cells of the first
        # box samples its copies of every window node, another block only the window nodes it
        # owns (which the others read); a copy not sampled holds a sampled one's value, not f's
        # (a brick: its core, and the node planes beyond its seams that the lonely-node test
        # reads, see node_window and kernels.block_grid.window_range)
        self.window = None if window is None else \
            wp.array(np.asarray(window, dtype=np.int32).reshape(-1, 3), dtype=wp.vec3i, device=device)
        # a slab of a larger grid: where its first node sits, and the whole grid's size
        # (vertex keys are node ids of the whole grid, so slabs weld exactly)
        self.wgoff = wp.vec3i(*[int(v) for v in node_offset])
        # with the whole grid's origin, a shape is sampled at the whole grid's node coordinates
        # (global_origin + (node_offset + g) h, bit for bit: bricks of warpmesh.distributed)
        self.sample_at = (wp.vec3(*np.asarray(origin, dtype=np.float64).tolist()), wp.vec3i(0, 0, 0)) \
            if global_origin is None else \
            (wp.vec3(*np.asarray(global_origin, dtype=np.float64).tolist()), self.wgoff)
        self.wgn = wp.vec3i(*[int(v) for v in (self.n if global_nodes is None else global_nodes)])
        self.nb = np.maximum(1, -(-(self.n - 1) // K.BLOCK))
        self.n_blocks = int(np.prod(self.nb))
        self.origin = np.asarray(origin, dtype=np.float64)
        self.h = np.asarray(h, dtype=np.float64)
        self.device = device
        wp.load_module(K, device=device)  # compile/load once here, not in worker threads
        wp.load_module(KE, device=device)
        self.wn = wp.vec3i(*self.n.tolist())
        self.wnb = wp.vec3i(*self.nb.tolist())
        self.worigin = wp.vec3(*self.origin.tolist())
        self.wh = wp.vec3(*self.h.tolist())
        self.info = {"grid": tuple(int(v) for v in self.n), "cell_size": tuple(float(v) for v in self.h),
                     "blocks": self.n_blocks}
        # the clearance's lonely-node exemption reads the neighbours of every node; a volume's
        # grid may be one slab of several, whose seam planes lack them (cull_volume turns it off)
        self.lonely_nodes = True
        self.known = None  # continuation: which slot nodes hold evaluated values (load_cells)

    def _launch(self, kernel, dim, inputs, outputs=()):
        wp.launch(kernel, dim=dim, inputs=inputs, outputs=list(outputs), device=self.device)

    def _compact(self, state: wp.array) -> None:
        """Slots for the surviving blocks: EVALUATE ones first, then INSIDE ones."""
        counts = []
        offsets = []
        for which in (K.EVALUATE, K.INSIDE):
            flags = wp.empty_like(state)
            self._launch(K.flag_state_kernel, self.n_blocks, [state, int(which)], [flags])
            off = wp.empty_like(state)
            wp.utils.array_scan(flags, off, inclusive=False)
            offsets.append(off)
            counts.append(int(off.numpy()[-1] + flags.numpy()[-1]))  # sync point: slot counts
        self.n_evaluate, n_inside = counts
        self.n_slots = self.n_evaluate + n_inside
        self._check_slots()
        self.slot_block = wp.empty(max(self.n_slots, 1), dtype=wp.int32, device=self.device)
        self.block_slot = wp.empty(self.n_blocks, dtype=wp.int32, device=self.device)
        self._launch(K.compact_blocks_kernel, self.n_blocks, [state, offsets[0], offsets[1], self.n_evaluate],
                     [self.slot_block, self.block_slot])
        self.info["active_blocks"] = self.n_slots
        self.info["inside_blocks"] = n_inside

    def _check_slots(self) -> None:
        if self.n_slots * K.NODES * 7 >= 2**31:
            raise WarpMeshError(
                f"{self.n_slots} blocks of {K.BLOCK}^3 cells would be sampled, more than one pass can "
                "index (int32): keep cull=True, or lower 'resolution'")

    def block_states(self, tape, cap: int) -> wp.array:
        """Per block (x fastest), what an interval of f over it proves: CULLED (no crossing),
        INSIDE (crossed only by the cap), or EVALUATE (may be crossed)."""
        state = wp.full(self.n_blocks, int(K.EVALUATE), dtype=wp.int32, device=self.device)
        lo = wp.empty(self.n_blocks, dtype=wp.vec3, device=self.device)
        hi = wp.empty(self.n_blocks, dtype=wp.vec3, device=self.device)
        self._launch(K.block_boxes_kernel, self.n_blocks, [self.wnb, self.wn, self.sample_at[0], self.wh,
                                                           self.sample_at[1]], [lo, hi])
        intervals = eval_intervals(tape, lo, hi, device=self.device)
        self._launch(K.cull_blocks_kernel, self.n_blocks, [self.wnb, self.wn, int(cap), intervals], [state])
        self.info["interval_evaluations"] = self.info.get("interval_evaluations", 0) + self.n_blocks
        return state

    def cull_shape(self, tape, cull: bool, cap: int, timings) -> None:
        t0 = time.perf_counter()
        self.info["interval_evaluations"] = 0
        if cull:
            state = self.block_states(tape, cap)
        else:
            state = wp.full(self.n_blocks, int(K.EVALUATE), dtype=wp.int32, device=self.device)
        if self.window is not None:
            self._launch(K.window_blocks_kernel, self.n_blocks, [self.wnb, self.wn, self.window], [state])
        self._compact(state)
        timings["cull"] = time.perf_counter() - t0

    def block_cells(self, blocks: np.ndarray) -> np.ndarray:
        """Linear ids (i + cx (j + cy k)) of the cells of the given blocks, sorted."""
        cells = self.n - 1
        b = np.asarray(blocks, dtype=np.int64)
        bc = np.stack([b % self.nb[0], b // self.nb[0] % self.nb[1], b // (self.nb[0] * self.nb[1])], axis=1)
        r = np.arange(K.BLOCK, dtype=np.int64)
        local = np.stack(np.meshgrid(r, r, r, indexing="ij"), axis=-1).reshape(-1, 3)
        ijk = (bc[:, None, :] * K.BLOCK + local[None, :, :]).reshape(-1, 3)
        ijk = ijk[np.all(ijk < cells, axis=1)]
        return np.sort(ijk[:, 0] + cells[0] * (ijk[:, 1] + cells[1] * ijk[:, 2]))

    def candidate_cells(self, tape, blocks: np.ndarray, cap: bool) -> tuple[np.ndarray, int]:
        """(sorted ids of the cells of ``blocks`` that an interval of f cannot prove uncrossed,
        interval evaluations): boxes halved level by level (8, 4, 2, 1 cells a side), a box
        kept when its interval holds 0 within the cull's rounding slack, is not finite, or
        is inside and touches a capped grid face."""
        cells = self.n - 1
        b = np.asarray(blocks, dtype=np.int64)
        lo = np.stack([b % self.nb[0], b // self.nb[0] % self.nb[1], b // (self.nb[0] * self.nb[1])], axis=1) * K.BLOCK
        size, n_intervals = K.BLOCK, 0
        children = np.array([[(c >> a) & 1 for a in range(3)] for c in range(8)], dtype=np.int64)
        while size > 1 and len(lo):
            size //= 2
            lo = (lo[:, None, :] + children[None, :, :] * size).reshape(-1, 3)
            lo = lo[np.all(lo < cells, axis=1)]
            hi = np.minimum(lo + size, cells)
            wlo = wp.array((self.origin + lo * self.h).astype(np.float32), dtype=wp.vec3, device=self.device)
            whi = wp.array((self.origin + hi * self.h).astype(np.float32), dtype=wp.vec3, device=self.device)
            iv = eval_intervals(tape, wlo, whi, device=self.device).numpy().astype(np.float64)
            n_intervals += len(lo)
            ilo, ihi = iv[:, 0], iv[:, 1]
            slack_lo, slack_hi = 1e-4 * np.abs(ilo) + 1e-7, 1e-4 * np.abs(ihi) + 1e-7
            keep = ~(np.isfinite(ilo) & np.isfinite(ihi)) | ((ilo <= slack_lo) & (ihi >= -slack_hi))
            if cap:
                keep |= (ihi >= -slack_hi) & np.any((lo == 0) | (hi == cells), axis=1)
            lo = lo[keep]
        return np.sort(lo[:, 0] + cells[0] * (lo[:, 1] + cells[1] * lo[:, 2])), n_intervals

    def cell_blocks(self, cell_ids: np.ndarray) -> np.ndarray:
        """The block id of each cell (linear ids as in :meth:`block_cells`)."""
        cells = self.n - 1
        c = np.asarray(cell_ids, dtype=np.int64)
        ijk = np.stack([c % cells[0], c // cells[0] % cells[1], c // (cells[0] * cells[1])], axis=1) // K.BLOCK
        return ijk[:, 0] + self.nb[0] * (ijk[:, 1] + self.nb[1] * ijk[:, 2])

    def sample_shape(self, tape, cull: bool, evaluator, timings) -> None:
        """f at the nodes of the EVALUATE slots that a sub-block interval cannot settle
        (the others get the sign it proves); +1 (inside) at the nodes of INSIDE slots."""
        t0 = time.perf_counter()
        dev, ne = self.device, self.n_evaluate
        n_nodes = ne * K.NODES
        self.values = wp.empty(max(self.n_slots * K.NODES, 1), dtype=wp.float32, device=dev)
        n_pts = 0
        if ne:
            needs = wp.ones(n_nodes, dtype=wp.int8, device=dev)
            need_count = wp.full(ne, K.NODES, dtype=wp.int32, device=dev)
            if cull:
                lo = wp.empty(ne * K.SUBS, dtype=wp.vec3, device=dev)
                hi = wp.empty(ne * K.SUBS, dtype=wp.vec3, device=dev)
                self._launch(K.sub_boxes_kernel, (ne, K.SUBS), [self.slot_block, self.wnb, self.wn,
                                                                self.sample_at[0], self.wh, self.sample_at[1]],
                             [lo, hi])
                intervals = eval_intervals(tape, lo, hi, device=dev)
                states = wp.empty(ne * K.SUBS, dtype=wp.int32, device=dev)
                self._per_slot(K.node_needs_kernel, [intervals], [states, self.values, needs, need_count], ne)
                self.info["interval_evaluations"] += ne * K.SUBS
            if self.window is not None:  # which node copies each slot samples (window_needs_kernel)
                sampled = wp.empty(n_nodes, dtype=wp.int8, device=dev)
                self._per_slot(K.window_needs_kernel, [self.slot_block, self.wnb, self.wn, self.window, -1.0],
                               [needs, self.values, need_count, sampled], ne)
            need_offset = wp.empty_like(need_count)
            wp.utils.array_scan(need_count, need_offset, inclusive=False)
            n_pts = int(need_offset[ne - 1:].numpy()[0] + need_count[ne - 1:].numpy()[0])  # sync point
            pts = wp.empty(max(n_pts, 1), dtype=wp.vec3, device=dev)
            self._per_slot(K.needed_points_kernel, [self.slot_block, self.wnb, self.wn, self.sample_at[0], self.wh,
                                                    self.sample_at[1], needs, need_offset], [pts], ne)
            # choose once (and count this as one large run of the structure under "auto")
            used = "compiled" if codegen.generated_kernel(tape, dev, evaluator, n_pts) else "interpreter"
            self.info["evaluator"] = used
            compact = eval_values(tape, pts[:n_pts], device=dev, evaluator=used)
            self._per_slot(K.scatter_values_kernel, [needs, need_offset, compact], [self.values], ne)
            if self.window is not None:  # the copies not sampled, from ones that are
                self._per_slot(K.window_fill_kernel, [self.slot_block, self.wnb, self.wn, self.window, sampled],
                               [self.values], ne)
        if self.n_slots > ne:
            self._launch(K.fill_values_kernel, (self.n_slots - ne) * K.NODES, [ne, 1.0], [self.values])
        self.info["evaluations"] = n_pts
        timings["evaluate"] = time.perf_counter() - t0

    def cull_volume(self, vol, level, sign, cull, cap, timings) -> tuple[float, float]:
        """Exact value ranges per block (also the volume's validation: NaN / infinity
        raise), then the samples of the surviving blocks. Returns the range of
        sign * (vol - level) over the grid, which the caller checks against 0."""
        t0 = time.perf_counter()
        self.lonely_nodes = False  # every slab size must give the same mesh: seams lack a neighbour plane
        host = np.ascontiguousarray(vol, dtype=np.float32)  # no copy for a C-order float32 volume
        # on the CPU Warp reads the numpy buffer in place; elsewhere it is uploaded once
        wvol = wp.array(host, dtype=wp.float32, device=self.device, copy=not self.device.is_cpu)
        self._volume_refs = (host, wvol)  # keep the borrowed buffer alive while kernels read it
        timings["upload"] = timings.get("upload", 0.0) + time.perf_counter() - t0
        t0 = time.perf_counter()
        intervals = wp.empty(self.n_blocks, dtype=wp.vec2, device=self.device)
        bad = wp.zeros(self.n_blocks, dtype=wp.int32, device=self.device)
        run_parallel([lambda a=a, b=b: self._launch(K.volume_block_range_kernel, b - a,
                                                     [a, self.wnb, wvol, level, sign], [intervals, bad])
                      for a, b in parallel_ranges(self.n_blocks, self.device, min_per_worker=64)])
        n_bad = int(bad.numpy().sum())  # sync point: validation (samples on block faces count twice)
        if n_bad:
            raise ValueError("expected finite values in 'volume', got NaN or infinity (or values beyond "
                             "float32's range, where the volume is converted to float32)")
        ranges = intervals.numpy()
        vmin, vmax = float(ranges[:, 0].min()), float(ranges[:, 1].max())  # of sign * (volume - level)
        state = wp.full(self.n_blocks, int(K.EVALUATE), dtype=wp.int32, device=self.device)
        if cull:
            self._launch(K.cull_blocks_kernel, self.n_blocks, [self.wnb, self.wn, int(cap), intervals], [state])
        self._compact(state)
        timings["cull"] = timings.get("cull", 0.0) + time.perf_counter() - t0
        t0 = time.perf_counter()
        self.values = wp.empty(max(self.n_slots * K.NODES, 1), dtype=wp.float32, device=self.device)
        if self.n_slots:
            self._per_slot(K.gather_volume_kernel, [self.slot_block, self.wnb, wvol, level, sign], [self.values])
        self.info["evaluations"] = 0
        timings["evaluate"] = timings.get("evaluate", 0.0) + time.perf_counter() - t0
        return vmin, vmax

    def node_values(self, tape, ids: np.ndarray, evaluator) -> np.ndarray:
        """f at grid nodes given by linear id (i + nx (j + ny k)), with the coordinates
        computed exactly as the sampling kernels do (continuation matches the grid)."""
        wids = wp.array(np.ascontiguousarray(ids, dtype=np.int64), dtype=wp.int64, device=self.device)
        pts = wp.empty(len(ids), dtype=wp.vec3, device=self.device)
        self._launch(K.node_points_kernel, len(ids), [wids, self.wn, self.worigin, self.wh], [pts])
        used = "compiled" if codegen.generated_kernel(tape, self.device, evaluator, len(ids)) else "interpreter"
        self.info["evaluator"] = used
        return eval_values(tape, pts, device=self.device, evaluator=used).numpy()  # sync point

    def load_cells(self, cells: np.ndarray, node_ids: np.ndarray, node_values: np.ndarray) -> wp.array:
        """Slots for a given set of cells (continuation): every block owning a vertex of one
        of them, filled with the known node values (-1, outside, elsewhere: the vertices
        that creates are on no marked cell and are dropped). Returns the cell mask."""
        n = self.n
        cdim = n - 1
        ci = np.stack([cells % cdim[0], cells // cdim[0] % cdim[1], cells // (cdim[0] * cdim[1])], axis=1)
        owners = []
        for corner in range(8):  # the blocks owning the corners' edges
            g = ci + np.array([corner & 1, (corner >> 1) & 1, (corner >> 2) & 1])
            ob = np.minimum(g // K.BLOCK, self.nb - 1)
            owners.append(ob[:, 0] + self.nb[0] * (ob[:, 1] + self.nb[1] * ob[:, 2]))
        blocks = np.unique(np.concatenate(owners))
        del owners
        self.n_slots = self.n_evaluate = len(blocks)
        self._check_slots()
        block_slot = np.full(self.n_blocks, -1, dtype=np.int32)
        block_slot[blocks] = np.arange(len(blocks), dtype=np.int32)
        side = np.arange(K.SIDE)
        lk, lj, li = np.meshgrid(side, side, side, indexing="ij")  # local_index: i fastest
        local = np.stack([li.ravel(), lj.ravel(), lk.ravel()], axis=1)  # (NODES, 3)
        values = np.empty(len(blocks) * K.NODES, dtype=np.float32)
        loaded = np.zeros(len(blocks) * K.NODES, dtype=np.uint8)
        for first in range(0, len(blocks), 1024):  # bounded temporaries: 1024 blocks at a time
            part = blocks[first:first + 1024]
            bc = np.stack([part % self.nb[0], part // self.nb[0] % self.nb[1], part // (self.nb[0] * self.nb[1])],
                          axis=1)
            g = np.minimum(bc[:, None, :] * K.BLOCK + local[None], n - 1)  # clamped, as node_point
            gid = (g[..., 0] + n[0] * (g[..., 1] + n[1] * g[..., 2])).ravel()
            pos = np.clip(np.searchsorted(node_ids, gid), 0, max(len(node_ids) - 1, 0))
            known = node_ids[pos] == gid if len(node_ids) else np.zeros(len(gid), bool)
            values[first * K.NODES:(first + len(part)) * K.NODES] = \
                np.where(known, node_values[pos] if len(node_ids) else 0.0, -1.0)
            loaded[first * K.NODES:(first + len(part)) * K.NODES] = known
        cb = ci // K.BLOCK
        slot = block_slot[cb[:, 0] + self.nb[0] * (cb[:, 1] + self.nb[1] * cb[:, 2])]
        lc = ci - cb * K.BLOCK
        mask = np.zeros(max(len(blocks), 1) * K.CELLS, dtype=np.uint8)
        mask[slot * K.CELLS + lc[:, 0] + K.BLOCK * (lc[:, 1] + K.BLOCK * lc[:, 2])] = 1
        dev = self.device
        self.values = wp.array(values if len(values) else np.zeros(1, np.float32), dtype=wp.float32, device=dev)
        self.slot_block = wp.array(np.maximum(blocks, 0).astype(np.int32) if len(blocks) else np.zeros(1, np.int32),
                                   dtype=wp.int32, device=dev)
        self.block_slot = wp.array(block_slot, dtype=wp.int32, device=dev)
        self.known = wp.array(loaded if len(loaded) else np.ones(2, np.uint8), dtype=wp.uint8, device=dev)
        self.info["active_blocks"] = self.n_slots
        self.info["inside_blocks"] = 0
        return wp.array(mask, dtype=wp.uint8, device=dev)

    def finish_values(self, cap: int, timings) -> None:
        t0 = time.perf_counter()
        bad = wp.zeros(max(self.n_slots, 1), dtype=wp.int32, device=self.device)
        if self.n_slots:
            self._per_slot(K.check_cap_values_kernel, [self.slot_block, self.wnb, self.wn, int(cap)],
                           [self.values, bad])
        if int(bad.numpy().sum()):  # sync point
            raise ValueError("the shape evaluates to NaN or infinity at grid nodes inside 'bounds' "
                             "(e.g. log of a negative or zero, a division by zero; NaN propagates "
                             "through min and max); change the expression or the bounds")
        timings["cap"] = timings.get("cap", 0.0) + time.perf_counter() - t0

    def _per_slot(self, kernel, inputs, outputs, count: int | None = None) -> None:
        """Launch a one-thread-per-slot kernel over slots [0, count), split across CPU cores."""
        count = self.n_slots if count is None else count
        jobs = [lambda a=a, b=b: self._launch(kernel, b - a, [a, *inputs], outputs)
                for a, b in parallel_ranges(count, self.device, min_per_worker=32)]
        run_parallel(jobs)

    def extract(self, method: str, cap: int, timings, cell_mask: wp.array | None = None,
                clearance: float = C.NODE_CLEARANCE):
        """Emit the surface with ``method`` ("mc", "mc33" or "mt"); ``cell_mask`` (uint8 per
        slot cell, optional) restricts the triangles to the cells it marks (continuation).
        ``clearance`` keeps every vertex at least that fraction of its edge off the grid
        nodes (``_conventions.NODE_CLEARANCE``, which states the triangles' shape bound; 0
        keeps only EDGE_T_MIN: slivers where the surface passes near nodes), except where no
        triangle can have two vertices next to the node ("mc", "mc33": a capped node, and
        on a shape's grid a node ending no other crossing edge that shares a cell with the
        vertex's edge); it moves vertices along their edges, never changes the connectivity
        (``info["clearance_moved"]`` counts them). Returns (vertices, triangles, edges):
        float32 positions, vec3i triangles, and per vertex its edge (t, p0, p1,
        flags, key) for root refinement. Positions and edge ends are measured from the
        *whole* grid's node (0, 0, 0), ``origin - node_offset * h`` (a slab or brick of a
        grid places its vertices as one pass over the whole grid does, bit for bit)."""
        clearance = check_clearance(clearance)
        t0 = time.perf_counter()
        dev, ns = self.device, self.n_slots
        tab = method_tables(method, dev)
        mid, n_types = _METHOD_IDS[method]
        mask = cell_mask if cell_mask is not None else wp.zeros(1, dtype=wp.uint8, device=dev)
        vcount, tcount, ccount = (wp.zeros(max(ns, 1), dtype=wp.int32, device=dev) for _ in range(3))
        voff, toff, coff = (wp.zeros(max(ns, 1), dtype=wp.int32, device=dev) for _ in range(3))
        cases = wp.empty(max(ns, 1) * K.CELLS, dtype=wp.int32, device=dev)
        if ns:
            self._per_slot(KE.count_crossings_kernel, [self.slot_block, self.wnb, self.wn, mid, n_types,
                                                       self.values, tab, mask], [vcount, tcount, ccount, cases])
            for count, off in ((vcount, voff), (tcount, toff), (ccount, coff)):
                wp.utils.array_scan(count, off, inclusive=False)
        # sync point: output sizes
        nv_edges, nt, nc = ((int(off.numpy()[-1] + count.numpy()[-1]) if ns else 0)
                            for count, off in ((vcount, voff), (tcount, toff), (ccount, coff)))
        nv = nv_edges + nc
        verts = wp.empty(nv, dtype=wp.vec3, device=dev)
        tris = wp.empty(nt, dtype=wp.vec3i, device=dev)
        edges = {"t": wp.empty(nv, dtype=wp.float32, device=dev), "p0": wp.empty(nv, dtype=wp.vec3, device=dev),
                 "p1": wp.empty(nv, dtype=wp.vec3, device=dev), "flags": wp.empty(nv, dtype=wp.int32, device=dev),
                 "key": wp.empty(nv, dtype=wp.int64, device=dev)}
        slot_volume = wp.zeros(max(ns, 1), dtype=wp.float64, device=dev)
        moved = wp.zeros(max(ns, 1), dtype=wp.int32, device=dev)
        if nv:
            eid = wp.full(ns * K.NODES * n_types, -1, dtype=wp.int32, device=dev)
            # positions relative to the whole grid's node (0, 0, 0) (``node_offset`` added: a
            # window of the grid places its vertices as the whole grid does, bit for bit):
            # float32 keeps its precision far from 0; the host adds the origin in float64
            local, t_min = wp.vec3(0.0), float(C.EDGE_T_MIN)
            # the lonely-node exemption (kernels.emit.lonely), looked at per vertex where it
            # can change the clamp; ``known``: one entry = every slot node known
            crowding = int(self.lonely_nodes and reads_neighbours(method, clearance))
            known = self.known if self.known is not None else wp.zeros(1, dtype=wp.uint8, device=dev)
            self._per_slot(KE.emit_vertices_kernel, [self.slot_block, self.wnb, self.wn, n_types, int(cap), local,
                                                     self.wh, t_min, clearance, self.wgoff, self.wgn, tab,
                                                     self.values, self.block_slot, known, crowding, vcount,
                                                     voff],
                           [eid, verts, edges["t"], edges["p0"], edges["p1"], edges["flags"], edges["key"], moved])
            if nc:  # interior vertices after the edge vertices
                wp.launch(KE.add_offset_kernel, dim=ns, inputs=[nv_edges], outputs=[coff], device=dev)
            self._per_slot(KE.emit_triangles_kernel,
                           [self.slot_block, self.block_slot, self.wnb, self.wn, n_types, int(cap), local, self.wh,
                            t_min, clearance, self.wgoff, self.wgn, tab, self.values, known, crowding, cases, toff,
                            coff, eid],
                           [verts, edges["t"], edges["p0"], edges["p1"], edges["flags"], edges["key"], tris,
                            slot_volume])
        self.info["signed_volume"] = float(slot_volume.numpy().sum()) / 6.0  # linear placement
        self.info["interior_vertices"] = nc
        self.info["clearance"] = clearance
        self.info["clearance_moved"] = int(moved.numpy().sum())  # vertices moved off a node by it
        timings["extract"] = timings.get("extract", 0.0) + time.perf_counter() - t0
        return verts, tris, edges


def reads_neighbours(method: str, clearance: float) -> bool:
    """Whether a shape's vertex placement reads the nodes around a crossing edge's ends (the
    lonely-node exemption of ``kernels.emit.clamped_t``): with the axis edges alone ("mc",
    "mc33") and a clearance above ``EDGE_T_MIN``. Otherwise a vertex is a function of its
    edge's two end values, and a window of the grid needs no node beyond its cells'.

    >>> reads_neighbours("mc33", 0.1), reads_neighbours("mt", 0.1), reads_neighbours("mc", 0.0)
    (True, False, False)
    """
    return _METHOD_IDS[method][1] == 3 and clearance > C.EDGE_T_MIN


def node_window(lo, hi, below, above) -> np.ndarray:
    """The window (k, 2, 3) of a grid's cells ``lo <= c < hi`` (grid-local, per axis): their
    nodes ``lo`` to ``hi``, and the node plane ``lo - 1`` on each axis where ``below`` (the
    plane ``hi + 1`` where ``above``), over the range ``lo`` to ``hi`` on the other axes:
    the neighbours across a face that ``reads_neighbours`` reads, no edge or corner beyond.

    >>> node_window((8, 0, 0), (16, 8, 8), (True, False, False), (False, False, False)).tolist()
    [[[8, 0, 0], [16, 8, 8]], [[7, 0, 0], [7, 8, 8]]]
    """
    lo, hi = np.asarray(lo, dtype=np.int64), np.asarray(hi, dtype=np.int64)
    boxes = [(lo, hi)]
    for a in range(3):
        for flag, plane in ((below[a], lo[a] - 1), (above[a], hi[a] + 1)):
            if flag:
                b0, b1 = lo.copy(), hi.copy()
                b0[a] = b1[a] = plane
                boxes.append((b0, b1))
    return np.array(boxes, dtype=np.int64)


def check_clearance(clearance) -> float:
    """The clearance of vertices off the grid nodes, as a float in [0, 0.5] (a fraction of
    the edge; ``_conventions.NODE_CLEARANCE`` by default, 0 for the unclamped placement)."""
    if isinstance(clearance, (bool, np.bool_)) or not isinstance(clearance, (int, float, np.integer, np.floating)) \
            or not 0.0 <= clearance <= 0.5:
        raise ValueError(f"expected 0 <= 'clearance' <= 0.5 (a fraction of the edge; default "
                         f"{C.NODE_CLEARANCE}, 0 to turn it off), got {clearance!r}")
    return float(clearance)


GRADIENTS = ("exact", "central", "forward")
FD_STEP = 1.0e-2  # finite-difference step, as a fraction of the cell size (seed: "a fraction of the cell size")


def gradients(tape, points: wp.array, out: wp.array, scheme: str, h, evaluator="interpreter") -> wp.array:
    """(f, grad f) at points: exact forward mode, or finite differences of f alone ([FG
    eq. 16.13] forward, 16.14 centred) with steps ``FD_STEP * h`` per axis."""
    if scheme == "exact":
        return eval_gradients(tape, points, out, device=points.device)
    dev, n = points.device, points.shape[0]
    central = int(scheme == "central")
    per = 4 + 3 * central
    step = wp.vec3(*(FD_STEP * np.asarray(h, dtype=np.float64)).tolist())
    shifted = wp.empty(n * per, dtype=wp.vec3, device=dev)
    wp.launch(KE.fd_points_kernel, dim=n, inputs=[points, step, central], outputs=[shifted], device=dev)
    values = eval_values(tape, shifted, device=dev, evaluator=evaluator)
    wp.launch(KE.fd_gradient_kernel, dim=n, inputs=[values, step, central], outputs=[out], device=dev)
    return out


def refine_roots(tape, verts, edges, origin, root, iterations, timings, evaluator="auto",
                 gradient: str = "exact", h=(1.0, 1.0, 1.0), fg_out=None) -> None:
    """Move each vertex to the root of f on its edge (bisection or safeguarded Newton, with
    the exact or a finite-difference gradient); f is evaluated at origin + the grid-local
    positions. Interior vertices ("mc33", flagged as zero ends) and cap vertices stay where
    they are; an exact root at a node goes back to EDGE_T_MIN from it. Refined roots are
    clamped to [EDGE_T_MIN, 1 - EDGE_T_MIN], not to the emission's clearance: they stay on
    f = 0, so the clearance's shape bound holds for linear placement only.
    With Newton, ``fg_out`` (vec4 per vertex) receives (f, grad f) of the last step."""
    t0 = time.perf_counter()
    dev = verts.device
    nv = verts.shape[0]
    world = wp.empty(nv, dtype=wp.vec3, device=dev)
    if evaluator == "auto":  # the bisection steps use what is ready; they start no compile
        evaluator = "compiled" if codegen.is_loaded(tape, dev) else "interpreter"
    t, flags, p0, p1 = edges["t"], edges["flags"], edges["p0"], edges["p1"]
    t_lo = wp.empty(nv, dtype=wp.float32, device=dev)
    t_hi = wp.empty(nv, dtype=wp.float32, device=dev)
    bisect = root == "bisection"
    wp.launch(KE.bracket_init_kernel, dim=nv, inputs=[flags, int(bisect), float(C.EDGE_T_MIN)],
              outputs=[t_lo, t_hi, t], device=dev)
    if bisect:
        f_mid = wp.empty(nv, dtype=wp.float32, device=dev)
        for _ in range(iterations or 12):
            wp.launch(KE.edge_points_kernel, dim=nv, inputs=[t, p0, p1, origin], outputs=[world], device=dev)
            eval_values(tape, world, f_mid, device=dev, evaluator=evaluator)
            wp.launch(KE.bisection_step_kernel, dim=nv, inputs=[flags, f_mid], outputs=[t_lo, t_hi, t], device=dev)
    else:
        fg = wp.empty(nv, dtype=wp.vec4, device=dev)
        f_prev = wp.full(nv, 3.0e38, dtype=wp.float32, device=dev)  # |f| one step back
        for _ in range(iterations or 10):
            wp.launch(KE.edge_points_kernel, dim=nv, inputs=[t, p0, p1, origin], outputs=[world], device=dev)
            gradients(tape, world, fg, gradient, h, evaluator)
            wp.launch(KE.newton_step_kernel, dim=nv, inputs=[flags, fg, p0, p1],
                      outputs=[t_lo, t_hi, f_prev, t], device=dev)
        if fg_out is not None:
            wp.copy(fg_out, fg)
    wp.launch(KE.clamp_edge_t_kernel, dim=nv, inputs=[float(C.EDGE_T_MIN)], outputs=[t], device=dev)
    wp.launch(KE.edge_points_kernel, dim=nv, inputs=[t, p0, p1, wp.vec3(0.0)], outputs=[verts], device=dev)
    timings["root"] = time.perf_counter() - t0


def drop_unused(verts: wp.array, tris: wp.array, edges: dict) -> tuple[wp.array, wp.array, dict]:
    """Keep the vertices the triangles use (renumbered in order) and remap the triangles,
    before any root refinement or normal evaluation spends work on the others (continuation's
    grown cells, a brick's halo)."""
    faces = tris.numpy()  # sync point
    used = np.zeros(verts.shape[0], dtype=bool)
    used[faces.reshape(-1)] = True
    kept = np.flatnonzero(used)
    remap = np.full(verts.shape[0], -1, dtype=np.int32)
    remap[kept] = np.arange(len(kept), dtype=np.int32)
    dev = verts.device

    def sub(arr):
        return wp.array(arr.numpy()[kept], dtype=arr.dtype, device=dev)

    return sub(verts), wp.array(remap[faces], dtype=wp.vec3i, device=dev), {k: sub(v) for k, v in edges.items()}
