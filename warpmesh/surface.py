"""Surface meshes of implicit shapes and sampled volumes (seed §16.4): the host pipeline.

validate -> build the grid -> cull blocks (interval arithmetic on the tape, or exact
block ranges of the volume) -> sample the surviving blocks -> marching cubes in kernels
(one vertex per crossing edge, welded by construction) -> optional root refinement on
the exact function -> host stage (numpy arrays, orientation check, statistics).

Example
-------
>>> import warpmesh as wm
>>> mesh = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=32)
>>> s = mesh.stats()
>>> s["watertight"], s["euler"]
(True, 2)
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Literal

import numpy as np
import warp as wp

from warpmesh import _conventions as C
from warpmesh.errors import WarpMeshError
from warpmesh.expr import Expr
from warpmesh.kernels import marching_cubes as K
from warpmesh.mesh import Mesh
from warpmesh.shapes import Shape
from warpmesh.tape import (eval_gradients, eval_intervals, eval_values, parallel_ranges, run_parallel,
                           tape_of)

RootMethod = Literal["linear", "bisection", "newton"]
_ROOTS = ("linear", "bisection", "newton")
MAX_RESOLUTION = 2048  # 2048^3 cells: 16.8 M blocks of 8^3, about 1 GB of block bookkeeping

_TABLE_CACHE: dict[str, dict] = {}


def _tables(device) -> dict:
    """The marching-cubes tables as Warp arrays, uploaded once per device."""
    key = str(device)
    if key not in _TABLE_CACHE:
        _TABLE_CACHE[key] = {k: wp.array(v, dtype=wp.int32, device=device)
                             for k, v in K.TABLE_ARRAYS.items()}
    return _TABLE_CACHE[key]


# -- validation -----------------------------------------------------------------------------
def _check_bounds(bounds) -> tuple[np.ndarray, np.ndarray]:
    if bounds is None:
        raise ValueError("expected 'bounds' ((x0, y0, z0), (x1, y1, z1)) for a shape, got None")
    try:
        b = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"expected 'bounds' as ((x0, y0, z0), (x1, y1, z1)), got {bounds!r}") from None
    if b.shape != (2, 3):
        raise ValueError(f"expected 'bounds' of shape (2, 3), got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"expected finite 'bounds', got {b.tolist()}")
    if np.any(b[1] <= b[0]):
        raise ValueError(f"expected non-empty 'bounds' (lower < upper on every axis), got {b.tolist()}")
    return b[0], b[1]


def _check_resolution(resolution, extent: np.ndarray, cap: bool) -> np.ndarray:
    """Cells per axis: an int is the count along the longest side (cells near-cubic)."""
    cells = _cells(resolution, extent)
    if cap and np.any(cells < 2):
        raise ValueError(f"expected at least 2 cells per axis with cap=True (the boundary nodes are "
                         f"outside), got {cells.tolist()} from resolution={resolution!r}: raise "
                         "'resolution' or widen the thin side of 'bounds'")
    return cells


def _cells(resolution, extent: np.ndarray) -> np.ndarray:
    if isinstance(resolution, (bool, np.bool_)):
        raise TypeError(f"expected an integer 'resolution', got {resolution!r}")
    if np.ndim(resolution) == 0:
        if not isinstance(resolution, (int, np.integer)):
            raise TypeError(f"expected an integer 'resolution', got {type(resolution).__name__}")
        r = int(resolution)
        if not 1 <= r <= MAX_RESOLUTION:
            raise ValueError(f"expected 1 <= 'resolution' <= {MAX_RESOLUTION}, got {r}")
        h = extent.max() / r
        return np.maximum(1, np.round(extent / h)).astype(np.int64)
    cells = np.asarray(resolution)
    if cells.shape != (3,) or not np.issubdtype(cells.dtype, np.integer):
        raise ValueError(f"expected an int or 3 ints for 'resolution', got {resolution!r}")
    if np.any(cells < 1) or np.any(cells > MAX_RESOLUTION):
        raise ValueError(f"expected 1 <= 'resolution' <= {MAX_RESOLUTION} per axis, got {cells.tolist()}")
    return cells.astype(np.int64)


def _refuse(*named, source: str, hint: str) -> None:
    """Options that do not apply to the source raise instead of being ignored."""
    given = [name for name, value in named if value is not None]
    if given:
        raise ValueError(f"{', '.join(repr(g) for g in given)} do not apply to {source} ({hint})")


def _check_choice(value, name: str, choices) -> None:
    if value not in choices:
        raise ValueError(f"Unknown {name} {value!r}. Pick one of {list(choices)}")


def _check_volume(volume, spacing, origin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    vol = np.asarray(volume)
    if vol.ndim != 3:
        raise ValueError(f"expected a 3D array for 'volume', but got {vol.ndim}D with shape {vol.shape}")
    if min(vol.shape) < 2:
        raise ValueError(f"expected at least 2 samples per axis in 'volume', got shape {vol.shape}")
    if not (np.issubdtype(vol.dtype, np.number) or vol.dtype == np.bool_) or np.iscomplexobj(vol):
        raise TypeError(f"expected a real numeric 'volume', got dtype {vol.dtype}")
    sp = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,)) if np.ndim(spacing) == 0 else \
        np.asarray(spacing, dtype=np.float64)
    if sp.shape != (3,) or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
        raise ValueError(f"expected 'spacing' as a positive number or 3 positive numbers, got {spacing!r}")
    org = np.asarray(origin, dtype=np.float64)
    if org.shape != (3,) or not np.all(np.isfinite(org)):
        raise ValueError(f"expected 'origin' as 3 finite numbers, got {origin!r}")
    return vol, sp, org


# -- the pipeline -------------------------------------------------------------------------------
def mesh_surface(
    source,
    *,
    bounds=None,
    resolution: int | tuple[int, int, int] | None = None,
    level: float | None = None,
    inside: Literal["above", "below"] | None = None,
    spacing=None,
    origin=None,
    root: RootMethod = "linear",
    root_iterations: int | None = None,
    cap: bool = True,
    cull: bool = True,
    normals: bool = False,
    device: str = C.DEFAULT_DEVICE,
) -> Mesh:
    """Triangulate the surface f = 0 of a shape, or an iso-surface of a sampled volume.

    Parameters
    ----------
    source : Shape, Expr or (nx, ny, nz) array
        A shape (f > 0 inside) or sampled values ``volume[i, j, k]`` at
        ``origin + (i, j, k) * spacing`` (trilinear in between).
    bounds : ((x0, y0, z0), (x1, y1, z1)), required for a shape
        The box sampled; the surface is closed (capped) on it when ``cap``.
    resolution : int or (3,) ints, shapes only
        Cells along the longest side of ``bounds`` (near-cubic cells), or per axis;
        default 128.
    level : float, volumes only
        The iso-level (default 0).
    inside : {'above', 'below'}, volumes only
        Whether values above (default) or below ``level`` are inside.
    spacing, origin : float or (3,) floats, volumes only
        The sample spacing (default 1) and the position of ``volume[0, 0, 0]`` (default 0).
    root : {'linear', 'bisection', 'newton'}
        Vertex placement on a crossing edge: linear interpolation (eq. 16.12), bisection
        or safeguarded Newton on the exact function (§16.3.3; shapes only).
    root_iterations : int, optional
        Iterations of bisection (default 12) or safeguarded Newton (default 10).
    cap : bool
        Treat the grid boundary as outside, so every surface is closed on the bounds.
    cull : bool
        Skip blocks of 8³ cells that cannot hold the surface (interval arithmetic for
        shapes, exact block ranges for volumes). The mesh is the same either way.
    normals : bool
        Shapes only: store outward unit normals (-∇f / |∇f|) as ``point_data["normals"]``.
    device : str
        Warp device ("cpu" or "cuda").

    Returns
    -------
    Mesh
        ``mesh.cells["triangle"]`` oriented outward (towards f < 0); where caps close
        the surface on the bounds, ``mesh.cell_refs["triangle"]`` is 2 on the caps and 1
        on the surface f = 0 (no refs when nothing was capped); ``mesh.info`` holds timings per stage and counts
        (``mesh.stats()`` shows them).

    Raises
    ------
    ValueError, TypeError
        Bad arguments, NaN / infinite values, a constant volume.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> g = np.linspace(-1, 1, 40)
    >>> vol = 0.8 - np.sqrt(g[:, None, None]**2 + g[None, :, None]**2 + g[None, None, :]**2)
    >>> m = wm.mesh_surface(vol, spacing=g[1] - g[0], origin=(-1, -1, -1))
    >>> m.stats()["euler"]
    2
    """
    t_start = time.perf_counter()
    _check_choice(root, "root", _ROOTS)
    for name, flag in (("cap", cap), ("cull", cull), ("normals", normals)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"expected True or False for '{name}', got {flag!r}")
    if root_iterations is not None:
        if root == "linear":
            raise ValueError("'root_iterations' applies to root='bisection' or 'newton', not 'linear'")
        if isinstance(root_iterations, bool) or not isinstance(root_iterations, (int, np.integer)) \
                or not 1 <= root_iterations <= 64:
            raise ValueError(f"expected 1 <= 'root_iterations' <= 64, got {root_iterations!r}")
    device = wp.get_device(device)
    timings: dict[str, float] = {}
    info: dict = {"method": "mc", "root": root, "device": str(device)}

    if isinstance(source, (Shape, Expr)):
        _refuse(("level", level), ("inside", inside), ("spacing", spacing), ("origin", origin),
                source="a shape", hint="they describe sampled volumes")
        lo, hi = _check_bounds(bounds)
        cells = _check_resolution(128 if resolution is None else resolution, hi - lo, cap)
        h = (hi - lo) / cells
        tape = tape_of(source)
        timings["compile"] = time.perf_counter() - t_start
        grid = _Grid(cells + 1, lo, h, device)
        grid.cull_shape(tape, cull, cap, timings)
        grid.sample_shape(tape, cull, timings)
        info["tape_length"] = len(tape)
    elif isinstance(source, np.ndarray) or hasattr(source, "__array__"):
        _refuse(("bounds", bounds), ("resolution", resolution), source="a volume",
                hint="a volume's grid is its samples: use 'spacing' and 'origin'")
        if root != "linear":
            raise ValueError(f"root={root!r} needs the exact function of a shape; a volume's "
                             "trilinear field is linear along grid edges: use root='linear'")
        if normals:
            raise ValueError("normals=True needs a shape; compute them on the mesh for a volume")
        level = 0.0 if level is None else level
        inside = "above" if inside is None else inside
        _check_choice(inside, "inside", ("above", "below"))
        vol, sp, org = _check_volume(source, 1.0 if spacing is None else spacing,
                                     (0.0, 0.0, 0.0) if origin is None else origin)
        if not isinstance(level, (int, float, np.integer, np.floating)) or not math.isfinite(level):
            raise ValueError(f"expected a finite number for 'level', got {level!r}")
        if cap and min(vol.shape) < 3:
            raise ValueError(f"expected at least 3 samples per axis in 'volume' with cap=True (the "
                             f"boundary samples are outside), got shape {vol.shape}")
        grid = _Grid(np.array(vol.shape), org, sp, device)
        grid.cull_volume(vol, float(level), 1.0 if inside == "above" else -1.0, cull, cap, timings)
        tape = None
    else:
        raise TypeError(f"expected a Shape, an expression or a 3D array for 'source', got {type(source).__name__}")

    grid.finish_values(cap, timings)
    verts, tris, edges = grid.extract(timings)
    if tape is not None and root != "linear" and len(verts):
        _refine_roots(tape, verts, edges, grid.worigin, root, root_iterations, timings)

    t0 = time.perf_counter()
    point_data = {}
    if normals and tape is not None and len(verts):
        world = wp.empty_like(verts)
        wp.launch(K.edge_points_kernel, dim=len(verts), inputs=[edges["t"], edges["p0"], edges["p1"], grid.worigin],
                  outputs=[world], device=device)
        fg = eval_gradients(tape, world, device=device).numpy()
        g = fg[:, 1:].astype(np.float64)
        norm = np.linalg.norm(g, axis=1, keepdims=True)
        normals = -g / np.where(norm > 0, norm, 1.0)
        if cap:  # cap vertices: the outward normal of the bounds' face they close
            p0, p1 = edges["p0"].numpy(), edges["p1"].numpy()
            on_cap = (edges["flags"].numpy() & 4) != 0
            axis = np.argmax(np.abs(p1 - p0), axis=1)
            at_low = p0[np.arange(len(p0)), axis] < 0.5 * grid.h[axis]  # grid-local: the low face is 0
            face_normal = np.zeros_like(normals)
            face_normal[np.arange(len(p0)), axis] = np.where(at_low, -1.0, 1.0)
            normals[on_cap] = face_normal[on_cap]
        point_data["normals"] = normals
    points = verts.numpy().astype(C.REAL_DTYPE) + grid.origin  # sync point: results to the host
    faces = tris.numpy().astype(C.INDEX_DTYPE)
    if len(faces) and faces.min() < 0:
        raise WarpMeshError("a block culled as uniform holds a crossing edge: the interval bound "
                            "of the shape is wrong; mesh with cull=False and report the shape")
    if cap and len(faces):  # closed by construction: outward winding encloses a positive volume
        if not grid.info["signed_volume"] > 0.0:
            raise WarpMeshError(f"the capped surface encloses a signed volume of {grid.info['signed_volume']:g}: "
                                "its triangles do not face outward (an internal error: please report it)")
        info["orientation"] = "outward (closed, positive enclosed volume)"
    refs = _surface_refs(edges, faces) if cap and len(faces) else None
    cell_refs = {"triangle": refs} if refs is not None and np.any(refs == CAP_REF) else None
    info.update(grid.info)
    info["vertices"], info["triangles"] = len(points), len(faces)
    if len(faces) == 0:
        warnings.warn("the surface does not cross the sampled grid: the mesh is empty "
                      "(check 'bounds', 'level' and the sign convention f > 0 inside)", stacklevel=2)
    timings["host"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return Mesh(points, {"triangle": faces}, point_data=point_data or None, cell_refs=cell_refs, info=info)


SURFACE_REF, CAP_REF = 1, 2


def _surface_refs(edges: dict, faces: np.ndarray) -> np.ndarray:
    """Triangle refs: CAP_REF where all three vertices sit on edges ending at a capped
    grid-boundary node (the closing caps on the bounds), SURFACE_REF elsewhere."""
    capped = (edges["flags"].numpy() & 4) != 0
    return np.where(capped[faces].all(axis=1), CAP_REF, SURFACE_REF).astype(C.INDEX_DTYPE)


class _Grid:
    """The block-sparse grid of one extraction: device arrays and the kernel launches."""

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

    def sample_shape(self, tape, cull: bool, timings) -> None:
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
            compact = eval_values(tape, pts[:n_pts], device=dev)
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


def _refine_roots(tape, verts, edges, origin, root, iterations, timings) -> None:
    """Move each vertex to the root of f on its edge (bisection or safeguarded Newton);
    f is evaluated at origin + the grid-local positions."""
    t0 = time.perf_counter()
    dev = verts.device
    nv = verts.shape[0]
    world = wp.empty(nv, dtype=wp.vec3, device=dev)
    t, flags, p0, p1 = edges["t"], edges["flags"], edges["p0"], edges["p1"]
    t_lo = wp.empty(nv, dtype=wp.float32, device=dev)
    t_hi = wp.empty(nv, dtype=wp.float32, device=dev)
    bisect = root == "bisection"
    wp.launch(K.bracket_init_kernel, dim=nv, inputs=[flags, int(bisect)], outputs=[t_lo, t_hi, t], device=dev)
    if bisect:
        f_mid = wp.empty(nv, dtype=wp.float32, device=dev)
        for _ in range(iterations or 12):
            wp.launch(K.edge_points_kernel, dim=nv, inputs=[t, p0, p1, origin], outputs=[world], device=dev)
            eval_values(tape, world, f_mid, device=dev)
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
