"""Iso-surfaces and label surfaces of sampled volumes, in bounded memory.

Two engines give the same triangles (tests/surface/test_volume_rows.py):

*Rows* (:func:`extract_rows`, "mc" and "mc33" on float32, uint8 and bool volumes, and
labels of any integer volume): flying edges over the array read in place
(:mod:`warpmesh.kernels.flying_edges`). One pass reads every sample and keeps each
node's class as a bit; the counting pass, the prefix sums and the emission work on those
bits and read values only where an edge crosses, one vertex per crossing edge, so there
is nothing to weld. Extra memory: one bit per sample and a few integers per row (a
label of a volume that is not uint8 adds its one-byte indicator). The launches go over
the rows slab by slab (``slab_voxels`` samples each), split across cores.

*Slabs* (:func:`extract_slabs`, every other case: "mt", float64 or integer values): the
volume is processed in slabs along its first axis (contiguous in a C-order array): each
slab of ``s + 1`` node planes is converted to float32 on its own (a label volume becomes
the indicator field of one label), culled, sampled and emitted by the block grid
pipeline, and its output kept on the host. Consecutive slabs share one node plane; the
vertices on it are emitted by both with identical values, and every vertex carries the
key ``node * 8 + type`` of its grid edge in the *whole* grid, so welding the seams is an
exact join on keys (no position tolerance). Only the grid faces that are faces of the
whole volume are capped. Peak memory is one slab's float32 copy and block arrays plus the
output, instead of a float copy of the whole volume.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> labels = np.zeros((40, 30, 30), dtype=np.uint8)
>>> labels[5:15, 5:25, 5:25] = 1
>>> labels[20:35, 5:25, 5:25] = 2
>>> m = wm.mesh_surface(labels, labels="all", slab_voxels=20_000)
>>> sorted(set(m.cell_refs["triangle"].tolist())), m.stats()["components"]
([1, 2], 2)
"""

from __future__ import annotations

import time

import numpy as np

import warp as wp

from warpmesh import _conventions as C
from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh.errors import WarpMeshError
from warpmesh.kernels import block_grid as KB
from warpmesh.kernels import emit as KE
from warpmesh.surface.block_grid import BlockGrid, check_clearance, method_tables

#: default slab size: 16 M samples (64 MB as float32) per pass
SLAB_VOXELS = 1 << 24
CHUNK = 1 << 18  # rows per step of the host-side passes over the whole output


def slab_ranges(n0: int, plane: int, slab_voxels: int) -> list[tuple[int, int]]:
    """Node ranges [a, b] (inclusive) along axis 0, consecutive slabs sharing node b.

    Each slab holds a multiple of the block size of cells (at least one block), about
    ``slab_voxels`` samples in all (``plane`` samples per node plane).

    >>> slab_ranges(20, 100, 1000)
    [(0, 8), (8, 16), (16, 19)]
    """
    step = max(KB.BLOCK, (slab_voxels // max(plane, 1)) // KB.BLOCK * KB.BLOCK)
    return [(a, min(a + step, n0 - 1)) for a in range(0, n0 - 1, step)]


def check_labels(labels, vol: np.ndarray) -> np.ndarray:
    """The label values to mesh: "all" (every value but 0) or a sequence of values."""
    if not (np.issubdtype(vol.dtype, np.integer) or vol.dtype == np.bool_):
        raise TypeError(f"expected an integer (label) 'volume' with 'labels', got dtype {vol.dtype}")
    labels = label_form(labels)
    if isinstance(labels, str):
        values = np.unique(np.concatenate([np.unique(vol[a:a + 64]) for a in range(0, len(vol), 64)]))
        values = values[values != 0]  # (slab by slab: no sorted copy of the whole volume)
        if len(values) == 0:
            raise ValueError("expected some non-zero labels in 'volume' with labels=\"all\", got only 0")
        check_label_range(values)
        return values
    values = np.asarray(labels)
    check_label_range(values)
    return values


def label_form(labels) -> str | tuple[int, ...]:
    """``"all"``, or the label values as distinct Python ints; the checks of the form of
    ``labels`` that need no volume (``VolumeOptions`` and :func:`check_labels` share them).

    Examples
    --------
    >>> label_form([3, 1]), label_form("all")
    ((3, 1), 'all')
    """
    if isinstance(labels, str):
        if labels != "all":
            raise ValueError(f"expected 'labels' as \"all\" or a sequence of label values, got {labels!r}")
        return labels
    values = np.asarray(labels)
    if values.ndim != 1 or len(values) == 0 or not np.issubdtype(values.dtype, np.integer):
        raise ValueError(f"expected 'labels' as \"all\" or a non-empty sequence of integers, got {labels!r}")
    if len(np.unique(values)) != len(values):
        raise ValueError(f"expected distinct values in 'labels', got {values.tolist()}")
    return tuple(int(v) for v in values.tolist())


def check_label_range(values: np.ndarray) -> None:
    """Labels become int64 triangle refs."""
    if values.dtype == np.uint64 and np.any(values > np.iinfo(np.int64).max):
        big = values[values > np.iinfo(np.int64).max][0]
        raise ValueError(f"expected labels that fit int64 triangle refs, got {big}")


#: the dtypes the row pass reads in place (others go through float32 copies, slab by slab)
ROW_DTYPES = (np.dtype(np.float32), np.dtype(np.uint8), np.dtype(np.bool_))
ENGINES = ("auto", "rows", "slabs")


def extract_volume(vol: np.ndarray, origin, spacing, *, level: float, sign: float, method: str, cap: bool,
                   cull: bool, device, slab_voxels: int, label=None, timings: dict, info: dict,
                   clearance: float = C.NODE_CLEARANCE, engine: str = "auto", rows_with=None):
    """Points (float64), triangles, per-vertex edge flags and the value range of one
    field of the volume (the indicator of ``label`` when given); ``clearance`` as
    :meth:`BlockGrid.extract`.

    ``engine`` "rows" (:func:`extract_rows`: flying edges over the array read in place,
    for "mc" and "mc33") or "slabs" (:func:`extract_slabs`: the block grid on float32
    copies of slabs, welded); "auto" takes "rows" wherever it applies: "mc" or "mc33" on
    a float32, uint8 or bool volume, or a label of an integer volume (its indicator as
    uint8), of fewer than 2^29 samples (Warp's int32 offsets). Both give the same
    triangles and vertices (tests/surface/test_volume_rows.py). ``rows_with``: see
    :func:`extract_fields`.
    """
    if engine not in ENGINES:
        raise ValueError(f"expected 'engine' in {list(ENGINES)}, got {engine!r}")
    # Warp indexes an array with int32 byte offsets: the row pass reads the whole array at once
    rows = method in ("mc", "mc33") and (vol.dtype in ROW_DTYPES or label is not None) and vol.size * 4 < 2**31
    if engine == "rows" and not rows:
        raise ValueError(f"the row pass meshes \"mc\" and \"mc33\" on float32, uint8 or bool volumes (or "
                         f"labels) of fewer than 2^29 samples, got method {method!r} on dtype {vol.dtype}, "
                         f"{vol.size} samples")
    if engine == "slabs" or not rows:
        return extract_slabs(vol, origin, spacing, level=level, sign=sign, method=method, cap=cap, cull=cull,
                             device=device, slab_voxels=slab_voxels, label=label, timings=timings, info=info,
                             clearance=clearance)
    return extract_rows(vol, origin, spacing, level=level, sign=sign, method=method, cap=cap, device=device,
                        slab_voxels=slab_voxels, label=label, timings=timings, info=info, clearance=clearance,
                        rows_with=rows_with)


def extract_fields(vol: np.ndarray, origin, spacing, fields, **options):
    """:func:`extract_volume` of each of ``fields`` in turn (None: the level set of the
    volume; a value: that label's surface), as a generator. Labels of a uint8 volume
    meshed by the row pass share one pass that lists the labels of each row
    (:func:`label_rows`, 64 labels at a time): each label's classification then reads
    only the rows holding it, not the whole volume."""
    fields = list(fields)
    shared = (vol.dtype == np.uint8 and len(fields) > 1 and options.get("engine", "auto") != "slabs"
              and options["method"] in ("mc", "mc33") and vol.size * 4 < 2**31)
    batch, present = -1, None
    for idx, label in enumerate(fields):
        rows_with = None
        if shared and label is not None and 0 <= int(label) <= 255:
            if idx // 64 != batch:  # 64 labels per word of row bits
                batch = idx // 64
                present = label_rows(vol, fields[64 * batch:64 * batch + 64], options["device"])
            rows_with = (present, idx % 64)
        yield extract_volume(vol, origin, spacing, label=label, rows_with=rows_with, **options)


def label_rows(vol: np.ndarray, values, device) -> wp.array:
    """Per row ``(i, j)`` of a uint8 label volume (``r = i * n1 + j``), bit q set when the
    row holds ``values[q]`` (at most 64 values; None or values beyond uint8 get no bit).

    >>> import numpy as np
    >>> vol = np.zeros((2, 2, 3), np.uint8); vol[1, 0, 2] = 7; vol[0, 1, 0] = 3
    >>> label_rows(vol, [3, 7], "cpu").numpy().tolist()
    [0, 1, 2, 0]
    """
    from warpmesh.kernels import flying_edges as KF  # as in extract_rows: only where volumes are meshed

    if len(values) > KF.WORD_BITS:
        raise ValueError(f"expected at most {KF.WORD_BITS} label values, got {len(values)}")
    dev = wp.get_device(device)
    wp.load_module(KF, device=dev)
    slot = np.full(256, -1, dtype=np.int32)
    for q, v in enumerate(values):
        if v is not None and 0 <= int(v) <= 255:
            slot[int(v)] = q
    host = np.ascontiguousarray(vol)
    vu = wp.array(host, dtype=wp.uint8, device=dev, copy=not dev.is_cpu)
    n = tuple(int(v) for v in vol.shape)
    present = wp.empty(n[0] * n[1], dtype=wp.uint64, device=dev)
    wslot = wp.array(slot, dtype=wp.int32, device=dev)
    run_parallel([lambda lo=lo, hi=hi: wp.launch(KF.label_rows_kernel, dim=hi - lo, inputs=[lo, vu, wslot, wp.vec3i(*n)],
                                                 outputs=[present], device=dev)
                  for lo, hi in parallel_ranges(n[0] * n[1], dev, min_per_worker=64)])
    return present


def extract_rows(vol: np.ndarray, origin, spacing, *, level: float, sign: float, method: str, cap: bool, device,
                 slab_voxels: int, label=None, timings: dict, info: dict, clearance: float = C.NODE_CLEARANCE,
                 rows_with=None):
    """:func:`extract_volume` by flying edges (:mod:`warpmesh.kernels.flying_edges`): the
    array read in place (a copy only when it is not C-contiguous, or a label's uint8
    indicator for a volume of another integer dtype), every pass a launch over rows
    split across cores, slab by slab of ``slab_voxels`` samples; one vertex per crossing
    edge, so nothing is welded. ``rows_with`` (uint8 labels: the rows' label bits of
    :func:`label_rows` and this label's bit) skips the rows without the label. Sync
    points: the rows' value ranges (validation) and the output sizes."""
    from warpmesh.kernels import flying_edges as KF  # here: a shape's mesh need not define these kernels

    clearance = check_clearance(clearance)
    t0 = time.perf_counter()
    wp.load_module(KF, device=device)  # compile/load once here, not in worker threads
    dev = wp.get_device(device)
    n = tuple(int(v) for v in vol.shape)
    mode, lab = KF.MODE_FLOAT, -1
    if label is not None and vol.dtype != np.uint8:  # the indicator of the label, one byte a sample
        vol, label = np.equal(vol, label).view(np.uint8), None
    if vol.dtype == np.float32:
        host_f, host_u = np.ascontiguousarray(vol), np.zeros((1, 1, 1), np.uint8)
    else:
        mode = KF.MODE_UINT8 if label is None else KF.MODE_LABEL
        lab = int(label) if label is not None and 0 <= int(label) <= 255 else -1  # -1: never equal
        host_f, host_u = np.zeros((1, 1, 1), np.float32), np.ascontiguousarray(vol).view(np.uint8)
    # on the CPU Warp reads the numpy buffers in place; elsewhere they are uploaded once
    vf = wp.array(host_f, dtype=wp.float32, device=dev, copy=not dev.is_cpu)
    vu = wp.array(host_u, dtype=wp.uint8, device=dev, copy=not dev.is_cpu)
    timings["upload"] = timings.get("upload", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    n_rows = n[0] * n[1]
    wn = wp.vec3i(*n)
    cap_mask = KB.ALL_FACES if cap else 0
    common = [vf, vu, mode, lab, float(level), float(sign), cap_mask, wn]
    ints = {k: wp.empty(n_rows, dtype=wp.int32, device=dev) for k in
            ("bad", "count_i", "count_j", "vcount", "tcount", "ccount", "moved")}
    ranges = wp.empty(n_rows, dtype=wp.vec2, device=dev)
    words = -(-n[2] // KF.WORD_BITS)
    classes = wp.empty(n_rows * words, dtype=wp.uint64, device=dev)  # the nodes' classes, a bit each
    planes = [(a, b if b < n[0] - 1 else n[0]) for a, b in slab_ranges(n[0], n[1] * n[2], slab_voxels)]

    def per_row(kernel, inputs, outputs):  # planes [a, b) (the last slab takes plane n0 - 1), split across cores
        for a, b in planes:
            run_parallel([lambda lo=lo, hi=hi: wp.launch(kernel, dim=hi - lo, inputs=[lo, *inputs],
                                                         outputs=outputs, device=dev)
                          for lo, hi in parallel_ranges((b - a) * n[1], dev, min_per_worker=64)
                          for lo, hi in [(lo + a * n[1], hi + a * n[1])]])

    present, bit = wp.zeros(1, dtype=wp.uint64, device=dev), wp.uint64(0)
    if rows_with is not None and mode == KF.MODE_LABEL:
        present, bit = rows_with[0], wp.uint64(1 << rows_with[1])
    per_row(KF.classify_rows_kernel, [*common, words, present, bit], [classes, ranges, ints["bad"]])
    if int(ints["bad"].numpy().sum()):  # sync point: validation
        raise ValueError("expected finite values in 'volume', got NaN or infinity (or values beyond "
                         "float32's range, where the volume is converted to float32)")
    rr = ranges.numpy()
    lo_hi = np.float32(sign) * (np.array([rr[:, 0].min(), rr[:, 1].max()], np.float32) - np.float32(level))
    vmin, vmax = float(lo_hi.min()), float(lo_hi.max())  # of sign * (volume - level)
    timings["cull"] = timings.get("cull", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    tab = method_tables(method, dev)
    mid = KE.METHOD_MC33 if method == "mc33" else KE.METHOD_MC
    per_row(KF.count_rows_kernel, [*common, words, mid, tab, classes],
            [ints["count_i"], ints["count_j"], ints["vcount"], ints["tcount"], ints["ccount"]])
    offsets = {}
    totals = {}
    for key in ("vcount", "tcount", "ccount"):
        totals[key] = int(ints[key].numpy().sum(dtype=np.int64))  # sync point: output sizes
        offsets[key] = wp.empty(n_rows, dtype=wp.int32, device=dev)
        wp.utils.array_scan(ints[key], offsets[key], inclusive=False)
    nv_edges, nt, nc = totals["vcount"], totals["tcount"], totals["ccount"]
    if nv_edges + nc >= 2**31 or nt >= 2**31:
        raise WarpMeshError(f"the surface has {nv_edges + nc} vertices and {nt} triangles, more than int32 "
                            "ids can number: mesh a coarser volume or parts of it")
    # the output in its host form (float64 points, int64 rows): on the CPU the kernels write
    # into numpy arrays that the mesh keeps, with no conversion pass
    points = np.empty((nv_edges + nc, 3), dtype=C.REAL_DTYPE)
    faces = np.empty((nt, 3), dtype=C.INDEX_DTYPE)
    verts = wp.array(points, dtype=wp.vec3d, device=dev, copy=not dev.is_cpu)
    tris = wp.array(faces.reshape(-1), dtype=wp.int64, device=dev, copy=not dev.is_cpu)
    flags = wp.empty(nv_edges + nc, dtype=wp.int32, device=dev)
    row_volume = wp.empty(n_rows, dtype=wp.float64, device=dev)
    h = np.asarray(spacing, dtype=np.float64)
    wh, t_min = wp.vec3(*h.tolist()), float(C.EDGE_T_MIN)
    if nt:
        worigin = wp.vec3d(*np.asarray(origin, dtype=np.float64).tolist())
        per_row(KF.emit_row_vertices_kernel, [*common, words, wh, t_min, clearance, classes, offsets["vcount"]],
                [worigin, verts, flags, ints["moved"]])
        centre = wp.vec3d(*(np.asarray(origin, dtype=np.float64) + 0.5 * (np.array(n) - 1) * h).tolist())
        per_row(KF.emit_row_triangles_kernel,
                [*common, words, wh, t_min, clearance, mid, tab, centre, classes, ints["count_i"], ints["count_j"],
                 offsets["vcount"], offsets["tcount"], offsets["ccount"], nv_edges],
                [worigin, verts, flags, tris, row_volume])
    timings["extract"] = timings.get("extract", 0.0) + time.perf_counter() - t0
    t0 = time.perf_counter()
    if not dev.is_cpu:  # sync point: the output to the host
        points, faces = verts.numpy().reshape(-1, 3), tris.numpy().reshape(-1, 3)
    flag = flags.numpy().copy()
    info["interior_vertices"] = info.get("interior_vertices", 0) + nc
    info["clearance_moved"] = info.get("clearance_moved", 0) + (int(ints["moved"].numpy().sum()) if nt else 0)
    if cap and nt:  # the enclosed volume of this field's closed surface, for check_closed_outward
        info["signed_volume"] = float(row_volume.numpy().sum()) / 6.0
    info["slabs"], info["engine"], info["clearance"] = len(planes), "rows", float(clearance)
    timings["host"] = timings.get("host", 0.0) + time.perf_counter() - t0
    return points, faces, flag, (vmin, vmax)


def extract_slabs(vol: np.ndarray, origin, spacing, *, level: float, sign: float, method: str, cap: bool,
                  cull: bool, device, slab_voxels: int, label=None, timings: dict, info: dict,
                  clearance: float = C.NODE_CLEARANCE):
    """:func:`extract_volume` by the block grid, slab by slab: each slab of ``s + 1`` node
    planes converted to float32 on its own, culled, sampled and emitted, the seams welded
    on the vertices' edge keys."""
    n = np.array(vol.shape, dtype=np.int64)
    origin = np.asarray(origin, dtype=np.float64)
    slabs = slab_ranges(int(n[0]), int(n[1] * n[2]), slab_voxels)
    full = KB.ALL_FACES if cap else 0
    pts, tris, keys, flags = [], [], [], []
    vmin, vmax, n_verts, n_blocks = np.inf, -np.inf, 0, 0
    for idx, (a, b) in enumerate(slabs):
        mask = full & ~(0b01 if idx > 0 else 0) & ~(0b10 if idx < len(slabs) - 1 else 0)
        part = vol[a:b + 1]
        if label is not None:
            part = part == label
        grid = BlockGrid(np.array([b - a + 1, n[1], n[2]]), origin + np.array([a, 0, 0]) * spacing, spacing,
                         device, node_offset=(a, 0, 0), global_nodes=n)
        lo, hi = grid.cull_volume(part, level, sign, cull, mask, timings)
        vmin, vmax = min(vmin, lo), max(vmax, hi)
        grid.finish_values(mask, timings)
        verts, faces, edges = grid.extract(method, mask, timings, clearance=clearance)
        t0 = time.perf_counter()
        # sync point: copies (a CPU array's .numpy() is a view of memory freed with the slab);
        # float32 points from the volume's node (0, 0, 0) (the emission measures them in the
        # whole grid: the rows engine's positions, bit for bit) and int32 slab-local ids:
        # half the memory of the result's
        pts.append((verts.numpy().copy(), origin))
        tris.append((faces.numpy().copy(), n_verts))
        keys.append(edges["key"].numpy().copy())
        flags.append(edges["flags"].numpy().copy())
        n_verts += len(pts[-1][0])
        # summed over slabs and labels (a seam vertex moved off a node counts in both slabs)
        for k in ("active_blocks", "interior_vertices", "clearance_moved"):
            info[k] = info.get(k, 0) + grid.info[k]
        n_blocks += grid.info["blocks"]
        timings["host"] = timings.get("host", 0.0) + time.perf_counter() - t0
        del grid, part  # one slab's device arrays at a time
    t0 = time.perf_counter()
    points = _concatenate(pts, C.REAL_DTYPE)  # float64 = local + slab origin; the lists are emptied
    faces = _concatenate(tris, C.INDEX_DTYPE)  # int64 = slab-local id + the slab's first vertex
    key, flag = _concatenate(keys), _concatenate(flags)
    if len(slabs) > 1 and len(points):
        points, faces, flag = _weld_seams(points, faces, flag, key, [b for _, b in slabs[:-1]], int(n[0]))
    info["slabs"], info["blocks"], info["clearance"] = len(slabs), n_blocks, float(clearance)
    info["engine"] = "slabs"  # of the grid (the same for every label)
    timings["weld"] = timings.get("weld", 0.0) + time.perf_counter() - t0
    return points, faces, flag, (vmin, vmax)


def _weld_seams(points, faces, flags, keys, seams: list[int], nx: int):
    """Merge the vertices that two slabs emitted for one grid edge of a seam plane (equal
    keys); only vertices on the seams are looked at."""
    on_seam = np.flatnonzero(np.isin((keys >> 3) % nx, seams))
    _, first, inverse = np.unique(keys[on_seam], return_index=True, return_inverse=True)
    remap = np.arange(len(points), dtype=C.INDEX_DTYPE)
    remap[on_seam] = on_seam[first][inverse]
    keep = remap == np.arange(len(points))
    new_index = np.cumsum(keep, dtype=C.INDEX_DTYPE) - 1
    for a in range(0, len(faces), CHUNK):  # in place, a chunk at a time: no second copy of the faces
        faces[a:a + CHUNK] = new_index[remap[faces[a:a + CHUNK]]]
    return points[keep], faces, flags[keep]


def _concatenate(pieces: list, dtype=None) -> np.ndarray:
    """np.concatenate that frees each piece once copied (peak: the result plus one piece).
    Pieces may be (array, offset) pairs, added on the way in ``dtype``."""
    pairs = [p if isinstance(p, tuple) else (p, 0) for p in pieces]
    pieces.clear()
    first = pairs[0][0]
    out = np.empty((sum(len(a) for a, _ in pairs),) + first.shape[1:], dtype=dtype or first.dtype)
    start = 0
    while pairs:
        piece, offset = pairs.pop(0)
        out[start:start + len(piece)] = piece
        out[start:start + len(piece)] += offset
        start += len(piece)
    return out


def check_closed_outward(points: np.ndarray, faces: np.ndarray, signed_volume: float | None = None,
                         chunk: int = 1 << 18) -> float:
    """The enclosed volume of a capped surface, which must be positive (outward winding);
    summed in chunks of triangles (about a common centre) so the check adds little to the
    peak memory, unless the extraction already summed it (``signed_volume``, as
    :func:`extract_rows` reports it in ``info["signed_volume"]``)."""
    if signed_volume is not None:
        vol = float(signed_volume)
    else:
        centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
        vol = 0.0
        for a in range(0, len(faces), chunk):
            p0, p1, p2 = (points[faces[a:a + chunk, j]] - centre for j in range(3))
            vol += float(np.einsum("ij,ij->", p0, np.cross(p1, p2))) / 6.0
    if not vol > 0.0:
        raise WarpMeshError(f"the capped surface encloses a signed volume of {vol:g}: its triangles do "
                            "not face outward (an internal error: please report it)")
    return vol
