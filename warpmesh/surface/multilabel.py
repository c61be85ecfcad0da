"""Multi-material surfaces of label volumes: every interface between two labels meshed once.

``mesh_surface(volume, labels=..., interfaces="shared")`` gives ONE surface whose
triangles each lie between two labels. The convention, written once here:

- ``mesh.cell_refs["triangle"]`` holds the *lower* label of the two sides and
  ``mesh.cell_data["label_above"]["triangle"]`` the *higher* one;
- every triangle's normal (right-hand rule) points from the lower label's side to the
  higher label's side;
- the samples whose label is not meshed (not in ``labels``; every value but 0 for
  ``labels="all"``), and with ``cap`` the outside of the sampled box, form one more
  region, the *rest*, whose id is :data:`REST` = 0 when 0 is not meshed, and
  ``min(labels) - 1`` (-1 for non-negative labels) when it is: label 0 is a label like
  any other when asked for (``labels=[0, 3]``);
- the boundary of one label ``L`` is the set of triangles naming it, those where ``L``
  is the higher label flipped: :func:`label_boundary` returns it, closed (with ``cap``)
  and oriented outward, away from ``L`` (the house convention: normals point out of the
  domain).

Why surface nets (a dual method) rather than a multi-label marching cubes
----------------------------------------------------------------------------
A multi-label marching cubes needs a case table over the label patterns of a cube (up
to 8 labels: thousands of cases, with junction vertices inside cubes and faces to
split between them) and per-edge vertices that several interfaces share. The dual
method needs no table and is shared *by construction*: one vertex per grid cube (2x2x2
samples) holding two labels or more, and for each grid edge joining two samples of
different labels one quad joining the vertices of the 4 cubes around that edge, carrying
those two labels. An interface is made of the quads of the edges crossing it, so it is
meshed once; where three labels meet, the quads of the different interfaces share the
vertices of the cubes that hold the three (the junction curves). Each label's boundary
is the boundary of the union of the dual cells (cubes centred on the samples) of its
samples, deformed: it is closed, and oriented as that union is. It is the method of
VTK's ``vtkSurfaceNets3D`` (pyvista's ``ImageData.contour_labels``), the peer.

Vertex placement: the centre of the cube, ``origin + (c + 1/2) * spacing`` for the cube
whose lowest sample is ``c`` (-1 to n - 1 per axis with ``cap``): the staircase, VTK's
surface nets before smoothing (``contour_labels(smoothing=False)``), the same positions
and the same area. The staircase is the boundary of the union of the samples' voxels: it
encloses each label's voxels exactly (a label's boundary encloses as many voxel volumes
as it has samples), and it is embedded by construction: each quad is the square face of
the dual grid across its edge, distinct edges give distinct squares, and two squares
meet along a whole side, at a corner, or not at all; each square is split along its
first diagonal into two coplanar triangles. Coplanar neighbours therefore only share
edges, and :func:`warpmesh.cells.intersections.find_self_intersections` reports no pair
on random label volumes and a block of pyvista's frog (tested), and on the whole
frog (the benchmark). ``floor((point - origin) / spacing)`` recovers each vertex's
cube exactly (the points sit half a spacing off the grid lines): the constrained smoothing (``smoothing=N``,
:mod:`warpmesh.optimize.label_smoothing`, with ``info["grid"]``) keeps every vertex in
that cube. An earlier placement, the mean of the crossing edges' midpoints, cut the
staircase's corners (area 0.69x the staircase on the frog) but is neither the peer's
unsmoothed surface nor the shape, so the smoothing starts from the staircase instead.

How it runs (:mod:`warpmesh.kernels.flying_edges`, surface nets section): the samples
are read in place (8- and 16-bit labels through a table from each value to its code;
wider ones coded first), the cap layer is read as the rest's code, never stored. One
thread per grid row (i, j) walks k over rows (i, j), (i + 1, j), (i, j + 1), (i + 1, j
+ 1): a bit per cube that gets a vertex, the quads of the crossing edges starting on the
row, the codes met. Prefix sums give each row its first vertex and quad; a second pass
writes the quads' triangles, numbering a cube's vertex by the bits before it in its row
(popcounts, no cube-to-vertex map), and the cube centres, in the output's dtypes and axis
order (x-fastest images are meshed as their C-order transposes and written back). Rows
are split over the cores, in chunks for the progress bar. Beyond the input and the output
it holds a bit per cube (1/8 of a uint8 input) and a few int32 per row.

Measured (``python benchmarks/bench_labels.py --repeat 7 --smoothing 0``, 2 cores, load
average 1.3-1.5; wall s / process CPU s, medians): pyvista's frog (25 labels, 500 x 470 x
136): the same 1,583,774 triangles and area 976,259 as ``contour_labels("all",
smoothing=False)``, no triangle twice, no crossing pair; 0.16 / 0.25 against 0.45 / 0.46
for VTK unsmoothed and 0.60 / 0.61 for ``contour_labels("all")`` (16 smoothing passes):
time ratios VTK / warpmesh 2.90 and 3.88 (CPU 1.87 and 2.49). A 512^3 Voronoi partition
(50 labels, uint8): 9,536,054 triangles, the same area as VTK's staircase, 0.53 / 0.91
against 2.65 / 2.70 and 3.94 / 3.99 (ratios 4.96 and 7.37). On the loaded machine (load
5-10, other runs) wall times swing: the frog's ratio to VTK unsmoothed went from 0.83 to
1.93 while the CPU ratio stayed 1.4-1.7. With the compact output (below; same command,
``--repeat 5``, load 1.4-1.6): the frog 0.14 / 0.25 against 0.35 / 0.36 and 0.52 / 0.54
(ratios 2.47 and 3.68), the Voronoi volume 0.64 / 1.15 against 2.16 / 2.21 and 3.45 /
3.50 (3.36 and 5.37).

Memory: the output is written compact, as the kernels compute it (float32 points, int32
triangles, the labels in int16 while the ids fit), and handed to a ``Mesh(...,
compact=True)`` without a copy: 12 bytes a vertex and 16 a triangle, against 24 and 40 in
float64 / int64 (its accessors still give float64 / int64, made on first use). Peak extra
memory of one call in a fresh process, the output alive (``python
benchmarks/bench_labels.py --repeat 5 --smoothing 0``, 2 cores): 39.6 MB on the frog
(input 30.5 MB, output 32.9 MB: 1.30x the input) and 227.5 MB on the 512^3 Voronoi
volume (input 128 MB, output 199.8 MB: 1.78x), against 16x the input for VTK (488 MB and
2,048 MB, its output 218 MB); with float64 / int64 output they were 85 MB and 500 MB
(2.79x and 3.91x). Beyond the output the call holds a bit per cube and a few int32 per
row. The bound holds while the output is smaller than the input, as for these two: a
surface has O(n^2) triangles for O(n^3) samples, so a coarse volume cut into many small
regions can have more (the Voronoi partition at 256^3: 49.8 MB of output, 3.1x its
16 MB input; VTK's output is as large).

Manifoldness: two samples of one label touching only along a grid edge or at a node (a
face of a cube with the label on one diagonal) make that label's boundary pass twice
through the cube's vertex, and a dual edge may then lie in 4 of its triangles. What is
guaranteed, and tested, for every label's boundary: every edge lies in an even number of
its triangles, as often in each direction (closed and consistently oriented), and no
two triangles cross (embedded); 2-manifold wherever no such contact occurs.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> vol = np.zeros((12, 12, 12), dtype=np.uint8)
>>> vol[2:6, 2:9, 2:9] = 1
>>> vol[6:10, 2:9, 2:9] = 2
>>> m = wm.mesh_surface(vol, labels="all", interfaces="shared")
>>> pairs = np.unique(np.column_stack([m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"]]), axis=0)
>>> pairs.tolist()  # interfaces 0|1, 0|2 and 1|2, the last meshed once
[[0, 1], [0, 2], [1, 2]]
>>> from warpmesh.surface.multilabel import label_boundary
>>> [(s["watertight"], s["oriented"], round(s["volume"], 1)) for s in (label_boundary(m, v).stats() for v in (1, 2))]
[(True, True, 196.0), (True, True, 196.0)]
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np

from warpmesh import _conventions as C
from warpmesh._util.arrays import narrowest_int
from warpmesh._util.parallel import parallel_ranges, run_parallel
from warpmesh._util.progress import Progress
from warpmesh.io.images import Volume

__all__ = ["LABEL_ABOVE", "INTERFACES", "REST", "interface_refs", "label_boundary", "label_codes", "label_figures",
           "shared_surface"]

#: the cell-data array holding each triangle's higher label
LABEL_ABOVE = "label_above"
#: values of ``interfaces``: per-label closed surfaces (each interface twice), or one shared surface
INTERFACES = ("separate", "shared")
#: the id of the rest (unmeshed samples and, with ``cap``, the outside) when 0 is not meshed
REST = 0


def label_codes(vol: np.ndarray, labels) -> tuple[np.ndarray, np.ndarray, int]:
    """The volume as small integer codes, in the order of the region ids.

    Parameters
    ----------
    vol : (nx, ny, nz) integer or bool array
    labels : "all" or sequence of int
        "all" meshes every value but 0 (0 is then the rest); a sequence meshes those
        values, each of which must occur in ``vol``.

    Returns
    -------
    codes : (nx, ny, nz) uint8 or uint16 or int32
        ``ids[codes]`` is the region id of each sample.
    ids : (k,) int64
        Region ids in increasing order: the meshed labels and the rest's id.
    rest : int
        The code of the rest.

    Raises
    ------
    ValueError
        A label of ``labels`` that no sample holds, or no label at all to mesh.

    Example
    -------
    >>> import numpy as np
    >>> codes, ids, rest = label_codes(np.array([0, 3, 7, 3]).reshape(1, 2, 2), [0, 3])
    >>> codes.ravel().tolist(), ids.tolist(), rest
    ([1, 2, 0, 2], [-1, 0, 3], 0)
    """
    if vol.dtype == np.bool_:  # as 0/1 bytes (a bool array would index the table as a mask)
        vol = vol.view(np.uint8)
    if vol.flags.f_contiguous and not vol.flags.c_contiguous:  # x fastest: slabs of the C-order view
        codes, ids, rest = label_codes(vol.T, labels)
        return codes.T, ids, rest

    chosen, ids, rest = _choose(_present(vol), labels)
    dtype = np.uint8 if len(ids) <= 256 else np.uint16 if len(ids) <= 65536 else np.int32
    if vol.dtype.itemsize <= 2 and (vol.dtype == np.bool_ or np.issubdtype(vol.dtype, np.integer)):
        lo = int(np.iinfo(vol.dtype).min) if vol.dtype != np.bool_ else 0
        table = np.full(1 << (8 * vol.dtype.itemsize), rest, dtype=dtype)
        table[chosen - lo] = np.searchsorted(ids, chosen)
        codes = table[vol.astype(np.int64) - lo] if lo else table[vol]
    else:
        codes = np.empty(vol.shape, dtype=dtype)
        for a in range(0, len(vol), 64):  # slab by slab: no int64 copy of the whole volume
            part = vol[a:a + 64].astype(np.int64)
            pos = np.minimum(np.searchsorted(ids, part), len(ids) - 1)
            codes[a:a + 64] = np.where((ids[pos] == part) & np.isin(part, chosen), pos, rest)
    return codes, ids, rest


def _present(vol: np.ndarray) -> np.ndarray:
    """The distinct values of the volume, slab by slab (a histogram for 8- and 16-bit values)."""
    small = vol.dtype.itemsize <= 2 and (vol.dtype == np.bool_ or np.issubdtype(vol.dtype, np.integer))
    if not small:
        return np.unique(np.concatenate([np.unique(vol[a:a + 64]) for a in range(0, len(vol), 64)]))
    lo = 0 if vol.dtype == np.bool_ else int(np.iinfo(vol.dtype).min)
    counts = np.zeros(1 << (8 * vol.dtype.itemsize), dtype=np.int64)
    for a in range(0, len(vol), 64):
        part = vol[a:a + 64].reshape(-1)
        counts += np.bincount(part.astype(np.intp) - lo if lo else part, minlength=len(counts))
    return (np.flatnonzero(counts) + lo).astype(vol.dtype)


def _as_label_volume(vol: np.ndarray) -> np.ndarray:
    """Integer values as they are; floats only when every value is a whole number."""
    if np.issubdtype(vol.dtype, np.integer) or vol.dtype == np.bool_:
        return vol
    if not np.issubdtype(vol.dtype, np.floating):
        raise TypeError(f"expected an integer label 'volume' with interfaces='shared', got dtype {vol.dtype}")
    try:
        return Volume(vol).as_labels().values
    except ValueError as exc:
        raise ValueError(f"interfaces='shared' meshes the regions of a label volume: {exc}") from None


def shared_surface(vol: np.ndarray, labels, *, origin, spacing, cap: bool = True, device="cpu", progress=False,
                   timings: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """One surface with each interface between two regions meshed once (surface nets).

    Parameters
    ----------
    vol : (nx, ny, nz) integer array
        Labels; ``vol[i, j, k]`` sits at ``origin + (i, j, k) * spacing``. Floats are
        taken when every value is a whole number. Read in place when C- or
        F-contiguous with 8- or 16-bit values.
    labels : "all" or sequence of int
        As :func:`label_codes`.
    origin, spacing : (3,) float
    cap : bool
        The outside of the box is the rest, so every label's boundary is closed; False
        leaves the surfaces open where they meet the box.
    device : str
        Warp device of the kernels.
    progress : bool or callable
        A progress bar (tqdm, shown once the run has taken a second), or
        ``progress(done, total)`` called as rows of the grid are done.
    timings : dict, optional
        Filled with the seconds per stage.

    Returns
    -------
    points : (n, 3) float32, or float64 far from the origin
        Each at the centre of its cube (the 2 x 2 x 2 samples from its lowest, ``c``):
        ``origin + (c + 1/2) * spacing`` rounded to float32, so ``floor((point - origin) /
        spacing)`` is ``c``, -1 to n - 1 per axis (-1 and n - 1: cubes reaching into the
        cap). Read-only, as the other arrays: all of them compact (a
        :class:`~warpmesh.mesh.Mesh` with ``compact=True`` keeps them without a copy).
        float64 when float32 cannot hold the centres to :data:`FLOAT32_CELL_ERROR` of a
        cell (:func:`float32_cube_centres`: a grid far from the origin for its spacing).
    triangles : (m, 3) int32
        Oriented from the lower label's side to the higher's.
    lower, upper : (m,) int16, int32 or int64
        The two labels of each triangle, ``lower < upper``, in the narrowest of those
        types that holds every region id (:func:`label_array_dtype`).
    info : dict
        ``labels`` (meshed), ``rest`` (its id), ``interfaces`` (count of label pairs),
        ``junction_vertices`` (vertices of cubes holding 3 labels or more), ``cubes``
        (vertices).

    Example
    -------
    >>> import numpy as np
    >>> vol = np.zeros((4, 4, 4), dtype=np.int16)
    >>> vol[1:3, 1:3, 1:3] = 5
    >>> points, tris, lower, upper, info = shared_surface(vol, "all", origin=(0, 0, 0), spacing=(1, 1, 1))
    >>> len(points), len(tris), set(lower.tolist()), set(upper.tolist())
    (26, 48, {0}, {5})
    """
    import warp as wp

    import warpmesh.kernels.flying_edges as KF

    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    vol = _as_label_volume(np.asarray(vol))
    origin, spacing = np.asarray(origin, dtype=np.float64), np.asarray(spacing, dtype=np.float64)
    user_origin, user_spacing, user_shape = origin, spacing, vol.shape
    reverse = vol.flags.f_contiguous and not vol.flags.c_contiguous
    if reverse:  # x fastest (VTK, NIfTI): mesh the C-order view vol.T; the kernels write the axes back
        vol, origin, spacing = vol.T, origin[::-1], spacing[::-1]
    if (vol.shape[0] + 2) * (vol.shape[1] + 2) * (vol.shape[2] + 2) >= 2**31:  # int32 sample indices in the kernels
        raise ValueError(f"expected fewer than 2**31 samples in 'volume' with interfaces='shared', got shape "
                         f"{vol.shape}: mesh it in parts")
    vol = np.ascontiguousarray(vol)
    source, table, ids, rest, chosen = _label_source(vol, labels)
    timings["codes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    dev = wp.get_device(device)
    pad = 1 if cap else 0  # one layer of the rest around the box, read, never stored: every region closes on it
    n = np.array(vol.shape, dtype=np.int64)
    p = n + 2 * pad
    n_rows, words = int(p[0] * p[1]), int((p[2] - 2) // 64 + 1)  # p[2] - 1 cubes a row
    grid = [wp.array(source, dtype=wp.dtype_from_numpy(source.dtype), device=dev, copy=not dev.is_cpu),
            wp.array(table, dtype=wp.int32, device=dev), rest, pad, wp.vec3i(*n.tolist()), wp.vec3i(*p.tolist()), words]
    bits = wp.zeros(n_rows * words, dtype=wp.uint64, device=dev)
    counts = {key: wp.empty(n_rows, dtype=wp.int32, device=dev) for key in ("vertex", "quad", "junction")}
    seen = wp.zeros(max(len(ids), len(table)), dtype=wp.uint8, device=dev)
    bar = Progress(progress, 2 * n_rows, "warpmesh surface nets", "row")
    _launch_rows(KF.count_label_rows_kernel, n_rows, grid + [bits, counts["vertex"], counts["quad"],
                                                              counts["junction"], seen], dev, bar)
    meshed = _present_labels(seen.numpy(), ids, rest, chosen)  # sync point: the labels met
    vertex_count, quad_count = counts["vertex"].numpy(), counts["quad"].numpy()  # sync point: output sizes
    n_vertices, n_quads = int(vertex_count.sum(dtype=np.int64)), int(quad_count.sum(dtype=np.int64))
    if n_vertices >= 2**31 or 6 * n_quads >= 2**31:  # the kernels number vertices and triangle rows in int32
        raise ValueError(f"expected fewer than 2**31 vertices and 2**31 / 3 triangles, got {n_vertices} and "
                         f"{2 * n_quads} for 'volume' of shape {vol.shape}: mesh it in parts")
    vertex_first = np.zeros(n_rows, dtype=np.int32)
    np.cumsum(vertex_count[:-1], out=vertex_first[1:])
    quad_first = np.zeros(n_rows, dtype=np.int64)
    np.cumsum(quad_count[:-1], out=quad_first[1:])
    timings["cubes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    # written compact (the kernels' own types): float32 points, int32 triangles, the labels in
    # the narrowest of int16 / int32 / int64 that holds the ids (KF.LABEL_OUT_DTYPES)
    label_dtype = label_array_dtype(ids)
    # world coordinates when float32 holds every cube centre to FLOAT32_CELL_ERROR of a cell,
    # else the cube indices (exact in float32), made world coordinates in float64 below
    far = not float32_cube_centres(user_origin, user_spacing, user_shape)
    world = ((np.full(3, -float(pad)), np.ones(3)) if far else (origin - pad * spacing, spacing))
    points = np.empty((n_vertices, 3), dtype=np.float32)
    tris = np.empty((2 * n_quads, 3), dtype=np.int32)
    lower, upper = np.empty(2 * n_quads, dtype=label_dtype), np.empty(2 * n_quads, dtype=label_dtype)
    out = {name: wp.array(a.reshape(-1), dtype=wp.dtype_from_numpy(a.dtype), device=dev, copy=not dev.is_cpu)
           for name, a in (("points", points), ("tris", tris), ("lower", lower), ("upper", upper))}
    seen_size = len(ids) ** 2 if len(ids) <= 2048 else 1  # a flag per pair of codes (4 MB at most)
    pair_seen = wp.zeros(seen_size, dtype=wp.uint8, device=dev)
    w_vertex_first = wp.array(vertex_first, dtype=wp.int32, device=dev)
    _launch_rows(KF.emit_label_quads_kernel, n_rows, grid + [
        bits, w_vertex_first, counts["quad"], wp.array(quad_first, dtype=wp.int64, device=dev),
        wp.array(ids.astype(label_dtype), dtype=wp.dtype_from_numpy(label_dtype), device=dev), int(reverse), pair_seen, len(ids) if seen_size > 1 else 0,
        out["tris"], out["lower"], out["upper"]], dev, bar,
        extra=(KF.emit_label_points_kernel, [wp.vec3i(*p.tolist()), words, bits, w_vertex_first,
                                             wp.vec3d(*world[0]), wp.vec3d(*world[1]), int(reverse),
                                             out["points"]]))
    if not dev.is_cpu:  # sync point: the results back to the host
        points[:], tris[:] = out["points"].numpy().reshape(-1, 3), out["tris"].numpy().reshape(-1, 3)
        lower[:], upper[:] = out["lower"].numpy(), out["upper"].numpy()
    bar.close()
    timings["triangles"] = time.perf_counter() - t0

    if seen_size > 1:  # sync point: the label pairs met
        n_pairs = int(np.count_nonzero(pair_seen.numpy()))
    else:
        n_pairs = len(np.unique(np.column_stack([lower[::2], upper[::2]]), axis=0))
    info = {"labels": [int(v) for v in meshed], "rest": int(ids[rest]), "interfaces": n_pairs,
            "junction_vertices": int(counts["junction"].numpy().sum(dtype=np.int64)), "cubes": n_vertices}
    if far:  # float64 world coordinates from the exact float32 indices (not compact)
        points = user_origin + points * user_spacing
    for a in (points, tris, lower, upper):  # handed to the Mesh, which keeps read-only arrays without a copy
        a.setflags(write=False)
    return points, tris, lower, upper, info


#: the largest error of a float32 cube centre, in cells, for the compact points of
#: :func:`shared_surface` (else float64)
FLOAT32_CELL_ERROR = 2.0**-10


def float32_cube_centres(origin, spacing, shape) -> bool:
    """Whether float32 holds the cube centres ``origin + (c + 1/2) * spacing`` of a grid of
    ``shape`` samples (c from -1 to n, the cap's included) to :data:`FLOAT32_CELL_ERROR`
    of a cell: half a float32 ulp (2**-24 relative) of the largest coordinate, over the
    smallest spacing.

    >>> float32_cube_centres((0, 0, 0), (1, 1, 1), (512, 512, 512)), float32_cube_centres((1e6, 0, 0), (1, 1, 1), (8, 8, 8))
    (True, False)
    """
    o, h = np.asarray(origin, dtype=np.float64), np.asarray(spacing, dtype=np.float64)
    far = np.maximum(np.abs(o - h), np.abs(o + (np.asarray(shape) + 1) * h)).max()
    return bool(far * 2.0**-24 <= FLOAT32_CELL_ERROR * np.abs(h).min())


def label_array_dtype(ids: np.ndarray) -> type:
    """The type of the triangles' labels for these region ids: the narrowest of int16,
    int32 and int64 that holds them all (the emit kernel's overloads).

    >>> label_array_dtype(np.array([0, 1, 255])).__name__, label_array_dtype(np.array([-1, 70000])).__name__
    ('int16', 'int32')
    """
    return narrowest_int(int(ids.min()), int(ids.max()), (np.int16, np.int32, np.int64))


def _launch_rows(kernel, n_rows: int, inputs: list, dev, bar: Progress, extra=None) -> None:
    """Launch a row kernel over [0, n_rows) from one thread per core, in chunks (for the bar);
    ``extra`` (kernel, inputs) runs over the same rows, chunk by chunk after the first."""
    chunk = max(4096, n_rows // 64)

    def work(lo: int, hi: int) -> None:
        for a in range(lo, hi, chunk):
            b = min(hi, a + chunk)
            wp.launch(kernel, dim=b - a, inputs=[a, *inputs], device=dev)
            if extra is not None:
                wp.launch(extra[0], dim=b - a, inputs=[a, *extra[1]], device=dev)
            bar.update(b - a)

    import warp as wp

    run_parallel([partial(work, lo, hi) for lo, hi in parallel_ranges(n_rows, dev, min_per_worker=1024)])


def _choose(present: np.ndarray, labels) -> tuple[np.ndarray, np.ndarray, int]:
    """The meshed labels, the region ids (meshed labels and the rest's id, increasing) and the
    rest's code, from the values present."""
    from warpmesh.surface.volume import check_label_range, check_labels  # shared label checks

    if isinstance(labels, str):
        chosen = check_labels(labels, present[:0]) if labels != "all" else present[present != 0]
        if len(chosen) == 0:
            raise ValueError("expected some non-zero labels in 'volume' with labels=\"all\", got only 0")
        check_label_range(chosen)
        chosen = chosen.astype(np.int64)
    else:
        chosen = np.asarray(check_labels(labels, present[:0])).astype(np.int64)
    missing = chosen[~np.isin(chosen, present.astype(np.int64))]
    if len(missing):
        raise ValueError(f"expected 'labels' present in 'volume', got {missing.tolist()} with no sample "
                         f"equal to it (the volume holds {present.tolist()[:20]}): drop it from 'labels'")
    rest_id = REST if REST not in chosen else int(chosen.min()) - 1
    ids = np.unique(np.append(chosen, rest_id))
    return chosen, ids, int(np.searchsorted(ids, rest_id))


def _label_source(vol: np.ndarray, labels):
    """What the kernels read: (flat samples, table, ids, rest, chosen). 8- and 16-bit values
    are read in place (as uint8 / uint16) through a table from each bit pattern to its code,
    made from ``labels`` alone (with "all", every value of the dtype is a region id;
    ``chosen`` is None and the values present are known after the first pass); wider values
    are coded first (:func:`label_codes`, which checks ``labels`` against the volume)."""
    from warpmesh.surface.volume import check_label_range, check_labels  # shared label checks

    small = vol.dtype.itemsize <= 2 and (vol.dtype == np.bool_ or np.issubdtype(vol.dtype, np.integer))
    if not small:
        codes, ids, rest = label_codes(vol, labels)
        chosen = ids[np.arange(len(ids)) != rest]
        identity = np.arange(len(ids) if codes.dtype == np.int32 else 1 << (8 * codes.dtype.itemsize), dtype=np.int32)
        return codes.reshape(-1), identity, ids, rest, chosen
    unsigned = np.uint8 if vol.dtype.itemsize == 1 else np.uint16
    values = np.arange(1 << (8 * vol.dtype.itemsize)).astype(unsigned).view(
        vol.dtype if vol.dtype != np.bool_ else np.uint8).astype(np.int64)  # the value of each bit pattern
    if isinstance(labels, str) and labels == "all":
        ids = np.sort(values)
        return vol.view(unsigned).reshape(-1), np.searchsorted(ids, values).astype(np.int32), ids, \
            int(np.searchsorted(ids, 0)), None
    chosen = np.asarray(check_labels(labels, vol[:0])).astype(np.int64)
    check_label_range(chosen)
    rest_id = REST if REST not in chosen else int(chosen.min()) - 1
    ids = np.unique(np.append(chosen, rest_id))
    rest = int(np.searchsorted(ids, rest_id))
    table = np.full(len(values), rest, dtype=np.int32)
    meshed = np.isin(values, chosen)
    table[meshed] = np.searchsorted(ids, values[meshed])
    return vol.view(unsigned).reshape(-1), table, ids, rest, chosen


def _present_labels(seen: np.ndarray, ids: np.ndarray, rest: int, chosen) -> np.ndarray:
    """The meshed labels, from the codes the first pass met; the errors of :func:`label_codes`."""
    met = ids[np.flatnonzero(seen[:len(ids)])]
    if chosen is None:  # labels="all"
        labels = met[met != ids[rest]]
        if len(labels) == 0:
            raise ValueError("expected some non-zero labels in 'volume' with labels=\"all\", got only 0")
        return labels
    missing = chosen[~np.isin(chosen, met)]
    if len(missing):
        raise ValueError(f"expected 'labels' present in 'volume', got {missing.tolist()} with no sample "
                         f"equal to it (the volume holds {met[met != ids[rest]].tolist()[:20]} among the labels "
                         "asked for): drop it from 'labels'")
    return chosen


def shared_labels(mesh, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """(lower, higher) label of every triangle of a surface from ``interfaces="shared"``
    (``cell_refs["triangle"]`` and ``cell_data["label_above"]["triangle"]``); a ValueError
    naming ``name`` for any other mesh.

    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((6, 6, 6), np.uint8); vol[1:3, 1:5, 1:5] = 1; vol[3:5, 1:5, 1:5] = 2
    >>> lower, upper = shared_labels(wm.mesh_surface(vol, labels="all", interfaces="shared"))
    >>> sorted(set(zip(lower.tolist(), upper.tolist())))
    [(0, 1), (0, 2), (1, 2)]
    """
    refs = None if mesh.cell_refs is None else mesh.cell_refs.get("triangle")
    above = mesh.cell_data.get(LABEL_ABOVE, {}).get("triangle")
    if refs is None or above is None or set(mesh.cells) != {"triangle"}:
        raise ValueError(f"expected a surface from interfaces='shared' in {name!r} (triangles only, cell refs and "
                         f"cell_data[{LABEL_ABOVE!r}]), got one without them")
    refs, above = np.asarray(refs), np.asarray(above)
    if above.dtype.kind in "iu" and above.dtype.itemsize < 8:  # a compact mesh's int16: widened for arithmetic
        above = above.astype(C.INDEX_DTYPE)
    return refs, above


def label_boundary(mesh, label: int):
    """The closed boundary of one label's region in a shared surface, oriented outward.

    Parameters
    ----------
    mesh : Mesh
        From ``mesh_surface(..., interfaces="shared")``.
    label : int
        A meshed label, or the rest's id (``mesh.info["rest"]``).

    Returns
    -------
    Mesh
        The triangles naming ``label`` (those where it is the higher label flipped)
        and their points; ``cell_refs["triangle"]`` holds the label across each one.

    Raises
    ------
    ValueError
        ``mesh`` without the two label arrays, or a label no triangle names.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((6, 6, 6), dtype=np.uint8); vol[1:5, 1:5, 1:3] = 1; vol[1:5, 1:5, 3:5] = 2
    >>> m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    >>> b = label_boundary(m, 1)
    >>> sorted(set(b.cell_refs["triangle"].tolist())), b.stats()["watertight"]
    ([0, 2], True)
    """
    refs, above = shared_labels(mesh)
    faces, other = _label_faces(mesh.cells["triangle"], refs, above, label)
    if not len(faces):
        named = np.unique(np.concatenate([refs, above])).tolist()
        raise ValueError(f"expected 'label' among the labels of the surface {named}, got {label!r}")
    used, faces = np.unique(faces, return_inverse=True)
    return type(mesh)(mesh.points[used], {"triangle": faces.reshape(-1, 3)}, cell_refs={"triangle": other},
                      info={"label": int(label)})


def _label_faces(tris: np.ndarray, refs: np.ndarray, above: np.ndarray, label: int):
    """The faces naming ``label``, turned to face out of it, and the label across each."""
    below, over = refs == label, above == label
    keep = below | over
    return np.where(over[keep, None], tris[keep][:, ::-1], tris[keep]), np.where(over[keep], refs[keep], above[keep])


def label_figures(mesh) -> dict[int, dict]:
    """Each label's boundary in a shared surface: closed, oriented outward, and its volume.

    The surface as a whole is not a closed manifold (its interfaces meet at junction edges,
    three or more faces about one edge), so ``Mesh.stats()`` of a shared surface reports
    these per label under ``label_boundaries``. A label's boundary may touch itself (two
    voxels of the label meeting along an edge only: four of its faces about one edge), so it
    is *closed* when every edge lies in an even number of its faces and *oriented* when its
    faces, turned out of the label, cross every edge as often one way as the other.

    Both are decided for every label in one pass over the faces, without matching edges: each
    edge gets a 64-bit hash of its two ends, each face the exclusive-or of its edges' hashes
    and their sum signed by direction (modulo 2^64); a label's boundary is closed when the
    exclusive-or over its faces is zero and oriented when the signed sum is (a face seen
    from its upper label counts negated). An open or misoriented boundary passes only if
    its unmatched edges' hashes cancel, with probability about 2^-64.

    Parameters
    ----------
    mesh : Mesh
        A multi-material surface (``mesh_surface(..., interfaces="shared")``, or one read
        back from a file that kept both label arrays).

    Returns
    -------
    dict
        label (the rest's id included) -> ``triangles`` (of its boundary), ``closed``,
        ``oriented`` and ``volume`` (signed, enclosed by the boundary turned outward:
        positive for a meshed label; the rest's, which holds the outside of the box, is
        minus the sum of the others').

    Raises
    ------
    ValueError
        Without the two label arrays (not a shared surface).

    Example
    -------
    Two blocks of 3 x 3 x 2 and 3 x 3 x 3 voxels, one on the other (the staircase surface
    encloses exactly their voxels):

    >>> import numpy as np, warpmesh as wm
    >>> blocks = np.zeros((5, 5, 7), dtype=np.uint8)
    >>> blocks[1:4, 1:4, 1:3], blocks[1:4, 1:4, 3:6] = 1, 3
    >>> f = label_figures(wm.mesh_surface(blocks, labels="all", interfaces="shared"))
    >>> {label: (f[label]["closed"], f[label]["oriented"], round(f[label]["volume"], 6)) for label in sorted(f)}
    {0: (True, True, -45.0), 1: (True, True, 18.0), 3: (True, True, 27.0)}
    """
    refs, above = shared_labels(mesh)
    tris, points = np.asarray(mesh.cells["triangle"], np.int64), mesh.points
    if not len(tris):
        return {}
    m = len(tris)
    xor = np.zeros(m, np.uint64)
    turn = np.zeros(m, np.uint64)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        u, v = tris[:, a], tris[:, b]
        h = _mix64(np.minimum(u, v).astype(np.uint64) * np.uint64(max(len(points), 1)) + np.maximum(u, v).astype(np.uint64))
        xor ^= h
        turn += np.where(u < v, h, np.uint64(0) - h)  # (wraps modulo 2^64)
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0)) if len(points) else np.zeros(3)
    p0, p1, p2 = (points[tris[:, k]] - centre for k in range(3))  # (about the box's centre: no cancellation)
    volume = np.einsum("ij,ij->i", p0, np.cross(p1, p2)) / 6.0
    # each face twice: as its lower label's (as it is) and its upper label's (turned: negated),
    # grouped by label with one sort
    both = np.concatenate([refs, above])
    order = np.argsort(both, kind="stable")
    grouped = both[order]
    starts = np.flatnonzero(np.r_[True, grouped[1:] != grouped[:-1]])
    face = order % m
    seen_from_upper = order >= m
    xors = np.bitwise_xor.reduceat(xor[face], starts)
    turns = np.add.reduceat(np.where(seen_from_upper, np.uint64(0) - turn[face], turn[face]), starts)
    volumes = np.add.reduceat(np.where(seen_from_upper, -volume[face], volume[face]), starts)
    counts = np.diff(np.r_[starts, len(order)])
    return {int(grouped[s]): {"triangles": int(c), "closed": bool(x == 0), "oriented": bool(t == 0),
                              "volume": float(vol)}
            for s, c, x, t, vol in zip(starts, counts, xors, turns, volumes)}


def _mix64(x: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser: a well-mixed 64-bit hash of each uint64 (wrapping arithmetic)."""
    with np.errstate(over="ignore"):
        x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return x ^ (x >> np.uint64(31))


def interface_refs(mesh):
    """The shared surface with one ref per interface (label pair), for formats that keep one
    physical group per element (gmsh ``.msh``: one physical surface per interface).

    Parameters
    ----------
    mesh : Mesh
        From ``mesh_surface(..., interfaces="shared")``.

    Returns
    -------
    Mesh
        The same points and triangles; ``cell_refs["triangle"]`` numbers the interfaces
        1, 2, ... in the order of their (lower, upper) pairs, which
        ``info["interfaces"]`` lists as ``{ref: (lower, upper)}``; the two label arrays
        stay as ``cell_data["label_below"]`` and ``cell_data["label_above"]``.

    Raises
    ------
    ValueError
        ``mesh`` without the two label arrays.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((6, 6, 6), dtype=np.uint8); vol[1:5, 1:5, 1:3] = 1; vol[1:5, 1:5, 3:5] = 2
    >>> m = interface_refs(wm.mesh_surface(vol, labels="all", interfaces="shared"))
    >>> m.info["interfaces"], sorted(set(m.cell_refs["triangle"].tolist()))
    ({1: (0, 1), 2: (0, 2), 3: (1, 2)}, [1, 2, 3])
    """
    refs, above = shared_labels(mesh)
    pairs, which = np.unique(np.column_stack([refs, above]), axis=0, return_inverse=True)
    table = {k + 1: (int(lo), int(hi)) for k, (lo, hi) in enumerate(pairs.tolist())}
    data = {**{k: dict(v) for k, v in mesh.cell_data.items()}, "label_below": {"triangle": refs.copy()}}
    return mesh.replace(cell_refs={"triangle": (which.ravel() + 1).astype(C.INDEX_DTYPE)}, cell_data=data,
                        info={**mesh.info, "interfaces": table})

