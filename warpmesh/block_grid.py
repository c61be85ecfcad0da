"""Typed launch wrappers of the block-sparse grid (seed §16.4.1-16.4.2, §16.3.3).

:class:`BlockGrid` owns the device arrays of one extraction and launches the kernels of
:mod:`warpmesh.kernels.marching_cubes`: block culling and compaction (count -> prefix sum ->
allocate -> write), sampling (a shape's tape or a volume's samples), capping, and the
two-pass emission of vertices and triangles; :func:`refine_roots` moves vertices onto the
exact surface. Launches over slots are split across CPU cores from Python threads.
"""

from __future__ import annotations

import time

import numpy as np
import warp as wp

from warpmesh import _conventions as C
from warpmesh import codegen
from warpmesh.errors import WarpMeshError
from warpmesh.kernels import marching_cubes as K
from warpmesh.tape import eval_gradients, eval_intervals, eval_values, parallel_ranges, run_parallel

_TABLE_CACHE: dict[str, dict] = {}


def _tables(device) -> dict:
    """The marching-cubes tables as Warp arrays, uploaded once per device."""
    key = str(device)
    if key not in _TABLE_CACHE:
        _TABLE_CACHE[key] = {k: wp.array(v, dtype=wp.int32, device=device)
                             for k, v in K.TABLE_ARRAYS.items()}
    return _TABLE_CACHE[key]


# -- validation -----------------------------------------------------------------------------
class BlockGrid:
    """The block-sparse grid of one extraction: its device arrays and the kernel launches
    (allocation, prefix sums, per-core splits), so that :func:`mesh_surface` reads as a pipeline."""

    def __init__(self, n_nodes, origin, h, device):
        self.n = np.asarray(n_nodes, dtype=np.int64)
        self.nb = np.maximum(1, -(-(self.n - 1) // K.BLOCK))
        self.n_blocks = int(np.prod(self.nb))
        self.origin = np.asarray(origin, dtype=np.float64)
        self.h = np.asarray(h, dtype=np.float64)
        self.device = device
        wp.load_module(K, device=device)  # compile/load once here, not in worker threads
        self.wn = wp.vec3i(*self.n.tolist())
        self.wnb = wp.vec3i(*self.nb.tolist())
        self.worigin = wp.vec3(*self.origin.tolist())
        self.wh = wp.vec3(*self.h.tolist())
        self.info = {"grid": tuple(int(v) for v in self.n), "cell_size": tuple(float(v) for v in self.h),
                     "blocks": self.n_blocks}

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
        if self.n_slots * K.EDGE_SLOTS >= 2**31:
            raise WarpMeshError(
                f"{self.n_slots} blocks of {K.BLOCK}^3 cells would be sampled, more than one pass can "
                "index (int32): keep cull=True, or lower 'resolution'")
        self.slot_block = wp.empty(max(self.n_slots, 1), dtype=wp.int32, device=self.device)
        self.block_slot = wp.empty(self.n_blocks, dtype=wp.int32, device=self.device)
        self._launch(K.compact_blocks_kernel, self.n_blocks, [state, offsets[0], offsets[1], self.n_evaluate],
                     [self.slot_block, self.block_slot])
        self.info["active_blocks"] = self.n_slots
        self.info["inside_blocks"] = n_inside

    def cull_shape(self, tape, cull: bool, cap: bool, timings) -> None:
        t0 = time.perf_counter()
        state = wp.full(self.n_blocks, int(K.EVALUATE), dtype=wp.int32, device=self.device)
        self.info["interval_evaluations"] = 0
        if cull:
            lo = wp.empty(self.n_blocks, dtype=wp.vec3, device=self.device)
            hi = wp.empty(self.n_blocks, dtype=wp.vec3, device=self.device)
            self._launch(K.block_boxes_kernel, self.n_blocks, [self.wnb, self.wn, self.worigin, self.wh], [lo, hi])
            intervals = eval_intervals(tape, lo, hi, device=self.device)
            self._launch(K.cull_blocks_kernel, self.n_blocks, [self.wnb, self.wn, int(cap), intervals], [state])
            self.info["interval_evaluations"] = self.n_blocks
        self._compact(state)
        timings["cull"] = time.perf_counter() - t0

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
                                                                self.worigin, self.wh], [lo, hi])
                intervals = eval_intervals(tape, lo, hi, device=dev)
                states = wp.empty(ne * K.SUBS, dtype=wp.int32, device=dev)
                self._per_slot(K.node_needs_kernel, [intervals], [states, self.values, needs, need_count], ne)
                self.info["interval_evaluations"] += ne * K.SUBS
            need_offset = wp.empty_like(need_count)
            wp.utils.array_scan(need_count, need_offset, inclusive=False)
            n_pts = int(need_offset[ne - 1:].numpy()[0] + need_count[ne - 1:].numpy()[0])  # sync point
            pts = wp.empty(max(n_pts, 1), dtype=wp.vec3, device=dev)
            self._per_slot(K.needed_points_kernel, [self.slot_block, self.wnb, self.wn, self.worigin, self.wh,
                                                    needs, need_offset], [pts], ne)
            # choose once (and count this as one large run of the structure under "auto")
            used = "compiled" if codegen.generated_kernel(tape, dev, evaluator, n_pts) else "interpreter"
            self.info["evaluator"] = used
            compact = eval_values(tape, pts[:n_pts], device=dev, evaluator=used)
            self._per_slot(K.scatter_values_kernel, [needs, need_offset, compact], [self.values], ne)
        if self.n_slots > ne:
            self._launch(K.fill_values_kernel, (self.n_slots - ne) * K.NODES, [ne, 1.0], [self.values])
        self.info["evaluations"] = n_pts
        timings["evaluate"] = time.perf_counter() - t0

    def cull_volume(self, vol, level, sign, cull, cap, timings) -> None:
        """Exact value ranges per block (also the volume's validation), then the samples
        of the surviving blocks."""
        t0 = time.perf_counter()
        host = np.ascontiguousarray(vol, dtype=np.float32)  # no copy for a C-order float32 volume
        # on the CPU Warp reads the numpy buffer in place; elsewhere it is uploaded once
        wvol = wp.array(host, dtype=wp.float32, device=self.device, copy=not self.device.is_cpu)
        self._volume_refs = (host, wvol)  # keep the borrowed buffer alive while kernels read it
        timings["upload"] = time.perf_counter() - t0
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
        if vmin == vmax:
            raise ValueError(f"expected a non-constant 'volume', got every value equal to {sign * vmin + level}")
        if not vmin <= 0.0 <= vmax:
            lo_v, hi_v = sorted((sign * vmin + level, sign * vmax + level))
            raise ValueError(f"expected 'level' within the volume's range [{lo_v}, {hi_v}], got {level}")
        state = wp.full(self.n_blocks, int(K.EVALUATE), dtype=wp.int32, device=self.device)
        if cull:
            self._launch(K.cull_blocks_kernel, self.n_blocks, [self.wnb, self.wn, int(cap), intervals], [state])
        self._compact(state)
        timings["cull"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        self.values = wp.empty(max(self.n_slots * K.NODES, 1), dtype=wp.float32, device=self.device)
        if self.n_slots:
            self._per_slot(K.gather_volume_kernel, [self.slot_block, self.wnb, wvol, level, sign], [self.values])
        self.info["evaluations"] = 0
        timings["evaluate"] = time.perf_counter() - t0

    def finish_values(self, cap: bool, timings) -> None:
        t0 = time.perf_counter()
        bad = wp.zeros(max(self.n_slots, 1), dtype=wp.int32, device=self.device)
        if self.n_slots:
            self._per_slot(K.check_cap_values_kernel, [self.slot_block, self.wnb, self.wn, int(cap)],
                           [self.values, bad])
        if int(bad.numpy().sum()):  # sync point
            raise ValueError("the shape evaluates to NaN or infinity at grid nodes inside 'bounds' "
                             "(e.g. sqrt/log of a negative or a division by zero); change the "
                             "expression or the bounds")
        timings["cap"] = time.perf_counter() - t0

    def _per_slot(self, kernel, inputs, outputs, count: int | None = None) -> None:
        """Launch a one-thread-per-slot kernel over slots [0, count), split across CPU cores."""
        count = self.n_slots if count is None else count
        jobs = [lambda a=a, b=b: self._launch(kernel, b - a, [a, *inputs], outputs)
                for a, b in parallel_ranges(count, self.device, min_per_worker=32)]
        run_parallel(jobs)

    def extract(self, timings):
        t0 = time.perf_counter()
        dev, tab, ns = self.device, _tables(self.device), self.n_slots
        vcount = wp.zeros(max(ns, 1), dtype=wp.int32, device=dev)
        tcount = wp.zeros(max(ns, 1), dtype=wp.int32, device=dev)
        voff = wp.zeros_like(vcount)
        toff = wp.zeros_like(tcount)
        cube_indices = wp.empty(max(ns, 1) * K.BLOCK**3, dtype=wp.uint8, device=dev)
        if ns:
            self._per_slot(K.count_crossings_kernel, [self.slot_block, self.wnb, self.wn, self.values,
                                            tab["corners"], tab["tri_count"]], [vcount, tcount, cube_indices])
            wp.utils.array_scan(vcount, voff, inclusive=False)
            wp.utils.array_scan(tcount, toff, inclusive=False)
        nv = int(voff.numpy()[-1] + vcount.numpy()[-1]) if ns else 0  # sync point: output sizes
        nt = int(toff.numpy()[-1] + tcount.numpy()[-1]) if ns else 0
        verts = wp.empty(nv, dtype=wp.vec3, device=dev)
        tris = wp.empty(nt, dtype=wp.vec3i, device=dev)
        edges = {"t": wp.empty(nv, dtype=wp.float32, device=dev), "p0": wp.empty(nv, dtype=wp.vec3, device=dev),
                 "p1": wp.empty(nv, dtype=wp.vec3, device=dev), "flags": wp.empty(nv, dtype=wp.int32, device=dev)}
        slot_volume = wp.zeros(max(ns, 1), dtype=wp.float64, device=dev)
        if nv:
            eid = wp.full(ns * K.EDGE_SLOTS, -1, dtype=wp.int32, device=dev)
            # positions relative to the grid origin: float32 keeps its precision far from 0;
            # the host adds the origin in float64
            self._per_slot(K.emit_vertices_kernel, [self.slot_block, self.wnb, self.wn, wp.vec3(0.0), self.wh,
                                               float(C.EDGE_T_MIN), self.values, voff],
                           [eid, verts, edges["t"], edges["p0"], edges["p1"], edges["flags"]])
            self._per_slot(K.emit_triangles_kernel, [self.slot_block, self.block_slot, self.wnb, self.wn, cube_indices,
                                                tab["edge_origin"], tab["tri_count"],
                                                tab["tri_table"], toff, eid, verts], [tris, slot_volume])
        self.info["signed_volume"] = float(slot_volume.numpy().sum()) / 6.0  # linear placement
        timings["extract"] = time.perf_counter() - t0
        return verts, tris, edges


def refine_roots(tape, verts, edges, origin, root, iterations, timings, evaluator="auto") -> None:
    """Move each vertex to the root of f on its edge (bisection or safeguarded Newton);
    f is evaluated at origin + the grid-local positions."""
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
    wp.launch(K.bracket_init_kernel, dim=nv, inputs=[flags, int(bisect)], outputs=[t_lo, t_hi, t], device=dev)
    if bisect:
        f_mid = wp.empty(nv, dtype=wp.float32, device=dev)
        for _ in range(iterations or 12):
            wp.launch(K.edge_points_kernel, dim=nv, inputs=[t, p0, p1, origin], outputs=[world], device=dev)
            eval_values(tape, world, f_mid, device=dev, evaluator=evaluator)
            wp.launch(K.bisection_step_kernel, dim=nv, inputs=[flags, f_mid], outputs=[t_lo, t_hi, t], device=dev)
    else:
        fg = wp.empty(nv, dtype=wp.vec4, device=dev)
        f_prev = wp.full(nv, 3.0e38, dtype=wp.float32, device=dev)  # |f| one step back
        for _ in range(iterations or 10):
            wp.launch(K.edge_points_kernel, dim=nv, inputs=[t, p0, p1, origin], outputs=[world], device=dev)
            eval_gradients(tape, world, fg, device=dev)
            wp.launch(K.newton_step_kernel, dim=nv, inputs=[flags, fg, p0, p1],
                      outputs=[t_lo, t_hi, f_prev, t], device=dev)
    wp.launch(K.clamp_edge_t_kernel, dim=nv, inputs=[float(C.EDGE_T_MIN)], outputs=[t], device=dev)
    wp.launch(K.edge_points_kernel, dim=nv, inputs=[t, p0, p1, wp.vec3(0.0)], outputs=[verts], device=dev)
    timings["root"] = time.perf_counter() - t0
