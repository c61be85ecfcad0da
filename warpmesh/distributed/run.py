"""Bricked meshing on a Dask cluster: :func:`mesh_bricks`, what ``mesh_surface(..., client=...)`` runs.

The global grid is cut into bricks on block boundaries (:mod:`warpmesh.distributed.bricks`).
For a shape, the client first proves bricks empty by one interval evaluation per brick
(the whole tape over the brick's box, at the grid's float32 node coordinates): an empty
brick never becomes a task. Each other brick is one task: a worker builds the block grid
of its brick as a window of the global grid (``BlockGrid(global_origin=...)``: its nodes
are sampled at the global coordinates, bit for bit), culls, samples and emits with the
same kernels as one process, keeps the triangles of its core cells, and returns (or
writes) its mesh with the global keys of its seam vertices, its positions measured from
the global grid's origin as one process measures them (so they are equal bit for bit).

A shape's brick samples its core's nodes and, where the vertex placement reads the nodes
around an edge's ends (the clearance's lonely-node test of "mc" and "mc33",
``block_grid.reads_neighbours``; "mt" reads none), the node plane beyond each lower seam:
the weld keeps the copy of a seam vertex from the brick that has every seam plane through
it as a lower face (the highest brick id), which thus sees all the vertex's neighbours.
A brick that writes a piece, whose seam copies must be the weld's, also samples the
node plane beyond each upper seam. A plane below lies in the block below the seam, which
gets a slot with only that plane sampled; a plane above in a block one cell thick (a
``BlockGrid`` window, ``block_grid.node_window``). A volume's brick is read from the array
(numpy, dask or zarr) on the worker with one node plane of overlap per seam; no worker
holds more than the brick it meshes.

Results come back as bricks finish (a tqdm bar over them, or a callback); the seams are
welded on the client in one pass over the seam vertices (:mod:`warpmesh.distributed.seams`).
A brick that fails on its data (NaN or infinity) fails the call with an error naming the
brick and its box; a worker that dies is replaced by Dask and its bricks recomputed,
which gives the same mesh (every brick is a pure function of its index range).

Example: :func:`mesh_bricks`.
"""

from __future__ import annotations

import time
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp

from warpmesh import _conventions as C
from warpmesh.distributed.bricks import BLOCK, Brick, layout, on_seams
from warpmesh.distributed.output import KEY_ARRAY, output_paths, piece_path, write_piece, write_pvtu
from warpmesh.distributed.seams import BrickMesh, weld
from warpmesh.errors import WarpMeshError
from warpmesh.frep.tape import eval_intervals, tape_of
from warpmesh.mesh import Mesh
from warpmesh.surface.block_grid import BlockGrid, drop_unused, node_window, reads_neighbours, refine_roots
from warpmesh.surface.options import GridOptions, VolumeOptions
from warpmesh.surface.volume import check_label_range, label_form

__all__ = ["BrickJob", "PartitionedMesh", "mesh_bricks"]


@dataclass(frozen=True)
class PartitionedMesh:
    """What a bricked run returns with ``gather=False``: the ``.pvtu`` file, its pieces
    (one VTU file per non-empty brick), and the counts summed over the pieces (seam
    vertices counted in every piece that holds them)."""

    path: Path
    pieces: tuple[Path, ...]
    n_points: int
    n_cells: int
    info: dict = field(default_factory=dict)


def mesh_bricks(source, options: GridOptions | VolumeOptions, *, client, bricks=None, brick_cells=None,
                gather: bool = True, output=None, progress=True, device: str = C.DEFAULT_DEVICE):
    """Mesh a shape on a grid, or a volume, brick by brick on a Dask cluster.

    Parameters
    ----------
    source : Shape, Expr, or (nx, ny, nz) numpy, dask or zarr array
        As :func:`warpmesh.mesh_surface`.
    options : GridOptions or VolumeOptions
        The options of the pipeline (``interfaces='shared'`` and ``normals`` are not bricked).
    client : dask.distributed.Client
        The cluster's client; every brick is one task.
    bricks : (3,) ints, optional
        Bricks per axis (cut on blocks of 8 cells).
    brick_cells : int, optional
        Cells per brick side, a multiple of 8 (default 128 when ``bricks`` is not given).
    gather : bool
        Return one :class:`~warpmesh.mesh.Mesh`, seams welded; False returns a
        :class:`PartitionedMesh` (needs ``output``), so no process holds the whole mesh.
    output : str or os.PathLike, optional
        A ``.pvtu`` path: the workers write one VTU piece per brick beside it as bricks
        finish (:mod:`warpmesh.distributed.output`); a run that fails removes the pieces and
        the ``.pvtu`` it wrote.
    progress : bool or callable
        A tqdm bar over the bricks (True), none (False), or ``progress(done, total)``
        called on the client as each brick finishes.
    device : str
        Warp device on the workers.

    Returns
    -------
    Mesh or PartitionedMesh

    Raises
    ------
    ValueError, TypeError
        Bad arguments, naming them; a brick's NaN or infinite values, naming the brick
        and its box.

    Examples
    --------
    ``mesh_surface(..., client=...)`` calls it; an in-process cluster here (threads), a
    ``LocalCluster(processes=True)`` or a remote scheduler alike:

    >>> import warpmesh as wm
    >>> from dask.distributed import Client, LocalCluster
    >>> cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    >>> client = Client(cluster)
    >>> part, bounds = wm.example("part")
    >>> mesh = wm.mesh_surface(part, bounds=bounds, resolution=48, client=client, brick_cells=16, progress=False)
    >>> one = wm.mesh_surface(part, bounds=bounds, resolution=48)
    >>> (mesh.n_points, mesh.n_cells) == (one.n_points, one.n_cells), mesh.info["bricks"]
    (True, 27)
    >>> client.close(); cluster.close()
    """
    where = check_run(client, gather, output, progress)
    t_start = time.perf_counter()
    if isinstance(options, GridOptions):
        job = _ShapeJob(source, options, str(wp.get_device(device)), bricks, brick_cells)
    elif isinstance(options, VolumeOptions):
        job = _VolumeJob(source, options, str(wp.get_device(device)), bricks, brick_cells, client)
    else:
        raise TypeError(f"bricks mesh a shape on a grid (GridOptions) or a volume (VolumeOptions), "
                        f"got {type(options).__name__} for 'options'")
    results, timings = run_job(client, job, where, gather, progress, t_start)
    return job.finish(results, where, gather, timings, t_start)


def check_run(client, gather, output, progress):
    """The arguments of a run on a cluster, checked; returns (directory, name) of ``output``
    or None."""
    from dask.distributed import Client

    if not isinstance(client, Client):
        raise TypeError(f"expected a dask.distributed.Client for 'client', got {type(client).__name__}")
    if not isinstance(gather, (bool, np.bool_)):
        raise TypeError(f"expected True or False for 'gather', got {gather!r}")
    if not (isinstance(progress, (bool, np.bool_)) or callable(progress)):
        raise TypeError(f"expected True, False or a callable progress(done, total) for 'progress', got {progress!r}")
    where = output_paths(output) if output is not None else None
    if not gather and where is None:
        raise ValueError("gather=False keeps the mesh in pieces on disk: give output='name.pvtu'")
    return where


def run_job(client, job, where, gather: bool, progress, t_start: float) -> tuple[dict, dict]:
    """Submit one task per brick ``job.bricks_to_mesh()`` gives (``job.task(brick, path, gather,
    *job.data)`` on a worker) and collect the results as they finish: ({brick id: result},
    timings)."""
    todo = job.bricks_to_mesh()
    token = uuid.uuid4().hex[:10]
    futures = {}
    for brick in todo:
        path = str(piece_path(*where, brick.index)) if where is not None else None
        fut = client.submit(job.task, brick, path, gather, *job.data, key=f"warpmesh-brick-{token}-{brick.index}",
                            pure=False)
        futures[fut] = brick
    results: dict = {}
    t_submitted = time.perf_counter()
    _collect(client, futures, results, where, job, progress)
    return results, {"layout": t_submitted - t_start, "bricks": time.perf_counter() - t_submitted}


def _collect(client, futures: dict, results: dict, where, job, progress) -> None:
    """Results as bricks finish: the progress bar or callback, the .pvtu rewritten, and the
    first brick error raised (the other bricks cancelled)."""
    from dask.distributed import as_completed
    from tqdm.auto import tqdm

    total = len(futures)
    bar = tqdm(total=total, unit="brick", desc="warpmesh bricks", disable=progress is not True)
    pieces: list[str] = []
    submitted = list(futures.items())
    try:
        for done, fut in enumerate(as_completed(list(futures)), start=1):
            try:
                res = fut.result()
            except BaseException:
                client.cancel(list(futures))
                if where is not None:
                    _remove_output(client, submitted, where)
                raise
            brick = futures.pop(fut)
            fut.release()  # the worker drops its copy now: it holds only the bricks in flight
            results[brick.index] = res
            if where is not None and res.info["cells"]:
                pieces.append(piece_path(*where, brick.index).name)
                write_pvtu(where[0] / f"{where[1]}.pvtu", sorted(pieces), refs=job.has_refs, key=job.key_array)
            bar.update(1)
            if callable(progress):
                progress(done, total)
    finally:
        bar.close()


def _remove_output(client, submitted: list, where, timeout: float = 60.0) -> None:
    """A failed partitioned run leaves no file behind: wait until no worker still holds a task
    of the run (a cancelled task that is already executing finishes, and writes its piece; the
    scheduler forgets it at once, the worker only when it ends), then remove every piece of the
    run and the ``.pvtu``."""
    keys = [fut.key for fut, _ in submitted]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            held = client.run(_held_keys, keys)
        except Exception:  # noqa: BLE001 - no worker answers: none is writing any more
            break
        if not any(held.values()):
            break
        time.sleep(0.05)
    for _, brick in submitted:
        piece_path(*where, brick.index).unlink(missing_ok=True)
    (where[0] / f"{where[1]}.pvtu").unlink(missing_ok=True)


def _held_keys(keys: list, dask_worker=None) -> list:
    """On a worker (``client.run``): which of ``keys`` it still holds (queued, executing, or
    cancelled while executing)."""
    tasks = dask_worker.state.tasks
    return [k for k in keys if k in tasks]


def brick_error(brick: Brick, origin, h, exc: Exception) -> ValueError:
    """``exc`` raised in ``brick``, as the error of the call: naming the brick and its box."""
    return ValueError(f"{brick.describe(origin, h)}: {exc}")


def _cap_mask(cap: bool, lo_node, hi_node, cells) -> int:
    """Cap bits of the faces of a brick's grid that are faces of the whole grid."""
    mask = 0
    if cap:
        for a in range(3):
            mask |= (1 << (2 * a)) if lo_node[a] == 0 else 0
            mask |= (1 << (2 * a + 1)) if hi_node[a] == cells[a] else 0
    return mask


def _core_cells(grid: BlockGrid, lo_node, brick: Brick) -> wp.array:
    """uint8 per slot cell: 1 for the cells of the brick's core (the halo's cells emit nothing)."""
    ns = grid.n_slots
    b = grid.slot_block.numpy()[:ns].astype(np.int64)
    nb = grid.nb
    bc = np.stack([b % nb[0], b // nb[0] % nb[1], b // (nb[0] * nb[1])], axis=1)
    ax = []
    for a in range(3):
        g = bc[:, a, None] * BLOCK + np.arange(BLOCK)[None] + lo_node[a]
        ax.append((g >= brick.lo[a]) & (g < brick.hi[a]))
    mask = ax[2][:, :, None, None] & ax[1][:, None, :, None] & ax[0][:, None, None, :]  # (slot, k, j, i)
    return wp.array(mask.reshape(-1).astype(np.uint8) if ns else np.zeros(BLOCK ** 3, np.uint8), dtype=wp.uint8,
                    device=grid.device)


def _brick_result(brick: Brick, cells, local, frame, faces, refs, keys, path, want: bool, info: dict,
                  centre) -> BrickMesh:
    """Write the piece (when asked) and package what the client needs (float32 positions from
    ``frame``, int32 triangles), with the brick's share of the enclosed volume about ``centre``,
    a point common to all bricks (the sum over a closed surface, which the gather checks; only
    a capped surface is closed: None skips it, as does a run that gathers nothing)."""
    if path is not None and len(faces):
        write_piece(path, local.astype(C.REAL_DTYPE) + frame, faces, refs, keys)
    vol = 0.0
    if want and centre is not None and len(faces):  # the gather checks the capped surface's orientation by it
        x, y, z = (local[:, a].astype(C.REAL_DTYPE) + (frame[a] - centre[a]) for a in range(3))
        for a in range(0, len(faces), 1 << 18):
            f0, f1, f2 = (faces[a:a + (1 << 18), j] for j in range(3))
            x1, y1, z1, x2, y2, z2 = x[f1], y[f1], z[f1], x[f2], y[f2], z[f2]
            vol += float(np.dot(x[f0], y1 * z2 - z1 * y2) + np.dot(y[f0], z1 * x2 - x1 * z2)
                         + np.dot(z[f0], x1 * y2 - y1 * x2)) / 6.0
    info.update(vertices=len(local), cells=len(faces), volume=vol)
    if not want:
        return BrickMesh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), None, np.zeros(0, np.int64),
                         np.zeros(0, np.int64), info)
    seam = np.flatnonzero(on_seams(keys, brick, cells))
    return BrickMesh(local, faces.astype(np.int32), refs, seam, keys[seam], info, np.asarray(frame, np.float64))


def _slack(b: np.ndarray) -> np.ndarray:
    """kernels.block_grid.rounding_slack: how far a float32 point value may stray past a bound."""
    return 1.0e-4 * np.abs(b) + 1.0e-7


def interval_signs(shape, box_lo: np.ndarray, box_hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(outside, inside) (k,) bool: the shape's interval over each box (float32 corners (k, 3))
    proves f < 0, or f > 0, everywhere in it (rounding slack allowed)."""
    iv = eval_intervals(tape_of(shape), wp.array(box_lo, dtype=wp.vec3), wp.array(box_hi, dtype=wp.vec3)).numpy()
    finite = np.isfinite(iv).all(axis=1)
    return finite & (iv[:, 1] < -_slack(iv[:, 1])), finite & (iv[:, 0] > _slack(iv[:, 0]))


_TAPES: dict[str, object] = {}  # on a worker: run token -> the tape of its shape (the last few runs)


def worker_tape(token: str, shape):
    """The tape of a run's shape, compiled once per worker process and run (every task
    unpickles its own copy of the shape, whose tape would otherwise be compiled anew)."""
    tape = _TAPES.get(token)
    if tape is None:
        tape = _TAPES[token] = tape_of(shape)
        while len(_TAPES) > 4:
            _TAPES.pop(next(iter(_TAPES)))
    return tape


class BrickJob:
    """Base of the jobs :func:`run_job` runs: every task pickles its job (the bound method
    ``job.task``), so what only the client reads (``bricks``, the whole layout: 25 KB of 35 KB
    per task at 1024^3 in bricks of 128^3) stays behind.

    >>> import pickle
    >>> job = BrickJob(); job.bricks, job.h = list(range(1000)), 0.5
    >>> sorted(vars(pickle.loads(pickle.dumps(job))))
    ['h']
    """

    client_only = ("bricks",)

    def __getstate__(self) -> dict:
        return {k: v for k, v in vars(self).items() if k not in self.client_only}


# -- a shape --------------------------------------------------------------------------------------
class _ShapeJob(BrickJob):
    """A shape on a grid: the layout, the client-side brick culling, the worker's task, the gather."""

    has_refs = False
    key_array = KEY_ARRAY  # the pieces' point array of global vertex keys
    data = ()  # task arguments that Dask resolves on the worker

    def __init__(self, shape, opts: GridOptions, device: str, bricks, brick_cells):
        self.shape, self.opts, self.device = shape, opts, device
        self.token = uuid.uuid4().hex  # this run: a worker compiles the shape's tape once per run
        self.lo, hi = (np.asarray(b, dtype=np.float64) for b in opts.bounds)
        self.cells = opts.cells
        self.h = (hi - self.lo) / self.cells  # as the single-process pipeline computes it
        self.bricks = layout(self.cells, bricks, brick_cells)
        self.has_refs = opts.cap

    def bricks_to_mesh(self) -> list[Brick]:
        """The bricks interval arithmetic cannot prove empty (one interval per brick, over its
        core's box at the grid's float32 node coordinates)."""
        t0 = time.perf_counter()
        o32, h32 = self.lo.astype(np.float32), self.h.astype(np.float32)
        lo = np.array([b.lo for b in self.bricks], dtype=np.float32)
        hi = np.array([b.hi for b in self.bricks], dtype=np.float32)
        box_lo, box_hi = o32 + lo * h32, o32 + hi * h32  # float32, rounded per operation as node_point
        outside, inside = interval_signs(self.shape, box_lo, box_hi)
        on_bounds = np.array([any(b.lo[a] == 0 or b.hi[a] == self.cells[a] for a in range(3)) for b in self.bricks])
        empty = outside | (inside & ~(on_bounds & self.opts.cap))  # inside and capped: the caps' triangles
        self.skipped = int(empty.sum())
        self.cull_time = time.perf_counter() - t0
        return [b for b, e in zip(self.bricks, empty) if not e]

    def task(self, brick: Brick, path, want: bool) -> BrickMesh:
        """On a worker: the brick's surface (its core cells) on the global grid."""
        t0 = time.perf_counter()
        opts, cells = self.opts, self.cells
        timings: dict[str, float] = {}
        dev = wp.get_device(self.device)
        tape = worker_tape(self.token, self.shape)
        lo_c, hi_c = np.array(brick.lo), np.array(brick.hi)
        # the node plane below each lower seam (the lonely-node test of the seam vertices the weld
        # keeps), and above each upper seam for a piece (whose seam copies must be the weld's): the
        # plane lies in the block below (a slot of that block, one plane of it sampled) or in a
        # block of one cell above; none where the placement reads no neighbour (module docstring)
        reads = reads_neighbours(opts.method, opts.clearance)
        below, above = (lo_c > 0) & reads, (hi_c < cells) & (path is not None) & reads
        lo_node = np.where(below, lo_c - BLOCK, lo_c)  # block-aligned: the brick's blocks are the grid's
        hi_node = np.where(above, hi_c + 1, hi_c)
        origin = self.lo + lo_node * self.h
        cap = _cap_mask(opts.cap, lo_node, hi_node, cells)
        grid = BlockGrid(hi_node - lo_node + 1, origin, self.h, dev, node_offset=lo_node, global_nodes=cells + 1,
                         global_origin=self.lo, window=node_window(lo_c - lo_node, hi_c - lo_node, below, above))
        try:
            grid.cull_shape(tape, opts.cull, cap, timings)
            grid.sample_shape(tape, opts.cull, opts.evaluator, timings)
            grid.finish_values(cap, timings)
        except ValueError as exc:
            raise brick_error(brick, self.lo, self.h, exc) from None
        verts, tris, edges = grid.extract(opts.method, cap, timings, _core_cells(grid, lo_node, brick),
                                          clearance=opts.clearance)
        verts, tris, edges = drop_unused(verts, tris, edges)
        local = np.zeros((0, 3), np.float32)
        if len(verts):
            # positions and edge ends come measured from the whole grid's node 0, as one process
            # has them (``BlockGrid.extract``), and a root finder evaluates f at the same points,
            # so positions are one process's bit for bit
            if opts.root != "linear":
                refine_roots(tape, verts, edges, wp.vec3(*self.lo.tolist()), opts.root, opts.root_iterations,
                             timings, opts.evaluator, opts.gradient, grid.h)
            local = verts.numpy().copy()  # sync point: results to the host
        frame = self.lo  # where the float32 positions are measured from
        faces = tris.numpy().astype(C.INDEX_DTYPE)
        if len(faces) and faces.min() < 0:
            raise WarpMeshError(f"{brick.describe(self.lo, self.h)}: a block culled as uniform holds a crossing "
                                "edge: the interval bound of the shape is wrong; mesh with cull=False")
        keys = edges["key"].numpy().copy()
        refs = None
        if opts.cap:
            capped = (edges["flags"].numpy() & 4) != 0
            refs = np.where(capped[faces].all(axis=1), C.CAP_REF, C.SURFACE_REF).astype(C.INDEX_DTYPE)
        info = {"evaluations": grid.info.get("evaluations", 0), "active_blocks": grid.info.get("active_blocks", 0),
                "evaluator": grid.info.get("evaluator"), "time": {**timings, "total": time.perf_counter() - t0}}
        return _brick_result(brick, cells, local, frame, faces, refs, keys, path, want, info,
                             self.lo + 0.5 * self.cells * self.h if opts.cap else None)

    def finish(self, results: dict, where, gather: bool, timings: dict, t_start: float):
        info = {"method": self.opts.method, "root": self.opts.root, "device": self.device,
                "grid": tuple(int(v) for v in self.cells + 1), "cell_size": tuple(float(v) for v in self.h),
                "bricks": len(self.bricks), "bricks_culled": self.skipped, "brick_cull_time": self.cull_time}
        return _finish(results, where, gather, timings, t_start, info, self.opts.cap)


# -- a volume -------------------------------------------------------------------------------------
class _Reader:
    """A brick's samples, read on the worker: slices of a dask array (computed there, in the
    task's thread) or of a numpy array scattered to the workers."""

    def __init__(self, array):
        self.array = array

    def read(self, lo, hi) -> np.ndarray:
        part = self.array[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1]
        if hasattr(part, "compute"):
            part = part.compute(scheduler="synchronous")
        return np.asarray(part)


class _VolumeJob(BrickJob):
    """A volume: every brick is read and meshed on a worker (no client-side culling: that
    needs the samples)."""

    key_array = KEY_ARRAY

    def __init__(self, source, opts: VolumeOptions, device: str, bricks, brick_cells, client):
        import dask.array as da

        if opts.interfaces == "shared":
            raise ValueError("interfaces='shared' is meshed on one host (surface nets over the whole volume); "
                             "bricks take interfaces='separate'")
        if not all(hasattr(source, a) for a in ("shape", "dtype", "ndim", "__getitem__")):
            raise TypeError(f"expected a 3D numpy, dask or zarr array for 'source', got {type(source).__name__}")
        if source.ndim != 3:
            raise ValueError(f"expected a 3D array for 'volume', but got {source.ndim}D with shape {source.shape}")
        dtype = np.dtype(source.dtype)
        if not (np.issubdtype(dtype, np.number) or dtype == np.bool_) or np.issubdtype(dtype, np.complexfloating):
            raise TypeError(f"expected a real numeric 'volume', got dtype {dtype}")
        shape = np.array(source.shape, dtype=np.int64)
        if shape.min() < (3 if opts.cap else 2):
            raise ValueError(f"expected at least {3 if opts.cap else 2} samples per axis in 'volume', got shape "
                             f"{tuple(source.shape)}")
        self.opts, self.device, self.dtype = opts, device, dtype
        self.cells = shape - 1
        self.n = shape
        self.h = np.asarray(opts.spacing, dtype=np.float64) * np.ones(3)
        self.lo = np.asarray(opts.origin, dtype=np.float64)
        self.bricks = layout(self.cells, bricks, brick_cells)
        self.data = ()  # task arguments that Dask resolves on the worker: a numpy volume, scattered once
        if isinstance(source, np.ndarray):
            self.reader, self.data = None, (client.scatter(source, broadcast=False, hash=False),)
        else:
            self.reader = _Reader(source if isinstance(source, da.Array) else da.from_array(source))
        self.labels = None
        if opts.labels is not None:
            if not (np.issubdtype(dtype, np.integer) or dtype == np.bool_):
                raise TypeError(f"expected an integer (label) 'volume' with 'labels', got dtype {dtype}")
            form = label_form(opts.labels)
            if isinstance(form, str):
                values = np.unique(source) if isinstance(source, np.ndarray) else \
                    np.asarray(da.unique(self.reader.array).compute())
                values = values[values != 0]
                if len(values) == 0:
                    raise ValueError("expected some non-zero labels in 'volume' with labels=\"all\", got only 0")
            else:
                values = np.asarray(form)
            check_label_range(values)
            self.labels = [int(v) for v in values]
        self.level = opts.level if opts.level is not None else \
            (0.5 if opts.labels is not None or dtype == np.bool_ else 0.0)
        self.sign = 1.0 if opts.inside == "above" else -1.0
        self.has_refs = opts.cap or self.labels is not None
        self.skipped, self.cull_time = 0, 0.0

    def bricks_to_mesh(self) -> list[Brick]:
        return list(self.bricks)

    def task(self, brick: Brick, path, want: bool, array=None) -> BrickMesh:
        """On a worker: read the brick's nodes (one shared plane per seam), mesh each field."""
        t0 = time.perf_counter()
        opts, cells = self.opts, self.cells
        part = (self.reader if array is None else _Reader(array)).read(brick.lo, brick.hi)
        timings: dict[str, float] = {"read": time.perf_counter() - t0}
        dev = wp.get_device(self.device)
        lo_node = np.array(brick.lo)
        origin = self.lo + lo_node * self.h
        cap = _cap_mask(opts.cap, brick.lo, brick.hi, cells)
        pts, tris, keys, refs, seam_keys = [], [], [], [], []
        ranges, n_verts, evaluations = [], 0, 0
        for idx, label in enumerate(self.labels if self.labels is not None else [None]):
            field_ = part if label is None else part == label
            grid = BlockGrid(np.array(part.shape), origin, self.h, dev, node_offset=lo_node, global_nodes=self.n)
            try:
                ranges.append(grid.cull_volume(field_, self.level, self.sign, opts.cull, cap, timings))
            except ValueError as exc:
                raise brick_error(brick, self.lo, self.h, exc) from None
            grid.finish_values(cap, timings)
            verts, faces, edges = grid.extract(opts.method, cap, timings, clearance=opts.clearance)
            p = verts.numpy().copy()  # float32, from the whole grid's node 0 (one process's positions)
            f = faces.numpy().astype(C.INDEX_DTYPE)
            k = edges["key"].numpy().copy()
            if label is None:
                capped = (edges["flags"].numpy() & 4) != 0
                r = np.where(capped[f].all(axis=1), C.CAP_REF, C.SURFACE_REF) if len(f) else np.zeros(0)
            else:
                r = np.full(len(f), label)
            pts.append(p)
            tris.append(f + n_verts)
            refs.append(r.astype(C.INDEX_DTYPE))
            keys.append(k)
            seam_keys.append(k | (np.int64(idx) << np.int64(56)))  # the same edge of another label is another vertex
            n_verts += len(p)
            del grid
        points, faces = np.concatenate(pts), np.concatenate(tris)
        key, tagged = np.concatenate(keys), np.concatenate(seam_keys)
        ref = np.concatenate(refs) if self.has_refs else None
        info = {"ranges": ranges, "evaluations": evaluations, "time": {**timings, "total": time.perf_counter() - t0}}
        result = _brick_result(brick, cells, points, self.lo, faces, ref, key, path, want, info,
                               self.lo + 0.5 * self.cells * self.h if opts.cap and self.labels is None else None)
        if want:
            result.seam_keys = tagged[result.seam]
        return result

    def finish(self, results: dict, where, gather: bool, timings: dict, t_start: float):
        fields = self.labels if self.labels is not None else [None]
        for idx, label in enumerate(fields):
            vmin = min(r.info["ranges"][idx][0] for r in results.values())
            vmax = max(r.info["ranges"][idx][1] for r in results.values())
            if label is None and vmin == vmax:
                raise ValueError(f"expected a non-constant 'volume', got every value equal to "
                                 f"{self.sign * vmin + self.level}")
            if label is None and not vmin <= 0.0 <= vmax:
                lo_v, hi_v = sorted((self.sign * vmin + self.level, self.sign * vmax + self.level))
                raise ValueError(f"expected 'level' within the volume's range [{lo_v}, {hi_v}], got {self.level}")
            if label is not None and vmax <= 0.0:
                raise ValueError(f"expected label {label} in 'volume', got no sample equal to it")
        info = {"method": self.opts.method, "root": "linear", "device": self.device,
                "grid": tuple(int(v) for v in self.n), "cell_size": tuple(float(v) for v in self.h),
                "bricks": len(self.bricks), "bricks_culled": 0}
        if self.labels is not None:
            info["labels"] = list(self.labels)
        return _finish(results, where, gather, timings, t_start, info, self.opts.cap, labels=self.labels is not None)


def summarize(results: dict, info: dict) -> list[dict]:
    """The bricks' counts summed into ``info``; returns the bricks' infos in brick order."""
    per = [results[i].info for i in sorted(results)]
    info["bricks_meshed"] = len(results)
    info["evaluations"] = int(sum(p.get("evaluations", 0) for p in per))
    info["brick_cpu_time"] = float(sum(p["time"]["total"] for p in per))
    used = {p.get("evaluator") for p in per} - {None}
    if used:
        info["evaluator"] = used.pop() if len(used) == 1 else "mixed"
    return per


def partitioned(results: dict, where, timings: dict, t_start: float, info: dict) -> PartitionedMesh:
    """What a run with ``gather=False`` returns: the pieces the bricks wrote and their counts."""
    per = [results[i].info for i in sorted(results)]
    pieces = tuple(piece_path(*where, i) for i in sorted(results) if results[i].info["cells"])
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return PartitionedMesh(where[0] / f"{where[1]}.pvtu", pieces, int(sum(p["vertices"] for p in per)),
                           int(sum(p["cells"] for p in per)), info)


def _finish(results: dict, where, gather: bool, timings: dict, t_start: float, info: dict, cap: bool,
            labels: bool = False):
    """The gathered Mesh (seams welded), or the partitioned file set."""
    order = sorted(results)
    per = summarize(results, info)
    t0 = time.perf_counter()
    if not gather:
        return partitioned(results, where, timings, t_start, info)
    points, faces, refs = weld([results[i] for i in order])
    info["seam_copies_welded"] = int(sum(p["vertices"] for p in per)) - len(points)
    if cap and not labels and len(faces):  # closed by the caps: the bricks' shares sum to the enclosed volume
        vol = float(sum(p["volume"] for p in per))
        if not vol > 0.0:
            raise WarpMeshError(f"the capped surface encloses a signed volume of {vol:g}: its triangles do not "
                                "face outward (an internal error: please report it)")
        info["enclosed_volume"] = vol
        info["orientation"] = "outward (closed, positive enclosed volume)"
    keep_refs = refs is not None and (labels or np.any(refs == C.CAP_REF))
    info["vertices"], info["triangles"] = len(points), len(faces)
    if where is not None:
        info["output"] = str(where[0] / f"{where[1]}.pvtu")
    if len(faces) == 0:
        warnings.warn("the surface does not cross the sampled grid: the mesh is empty", stacklevel=4)
    timings["weld"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return Mesh(points, {"triangle": faces}, cell_refs={"triangle": refs} if keep_refs else None, info=info)
