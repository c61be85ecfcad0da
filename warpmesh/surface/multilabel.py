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

Vertex placement: the mean of the midpoints of the cube's crossing edges (the "centre
of the cube's transitions"). A cube's crossing edges never lie all in one face (an
edge cut of the cube's graph that avoids one axis' edges repeats on the opposite face),
so the vertex lies strictly inside its cube: distinct cubes give distinct vertices. Each
quad is split along the diagonal whose two triangles both face along the edge's
direction (projected on the plane across the edge, the quad has one vertex per open
quadrant around the edge, in order, so at least one diagonal works; of two, the
shorter). The surface is not smoothed: the tests check on random label volumes and on
pyvista's frog that no two triangles cross (:func:`warpmesh.cells.intersections.
find_self_intersections`).

Measured on pyvista's frog (25 labels, 500 x 470 x 136, ``benchmarks/bench_labels.py``):
the same 1,583,774 triangles as ``contour_labels("all")``, no triangle twice, no crossing
pair; 1.0 to 2.0 s against 0.7 to 1.7 s for ``contour_labels("all")`` (its default 16
smoothing passes, multithreaded) over four runs on a loaded 2-core machine (time ratio
VTK / warpmesh 0.56 to 1.22). Not smoothed, the area lies between the peer's two: 1.31x
its smoothed surface, 0.69x its staircase (vertices at cube centres). 16 Laplacian passes
clamped to each vertex's cube (junction vertices along junctions only) gave 3,748
crossing pairs on the frog (unit spacing), so none is applied: smooth the result where a
smaller area matters more than embedding.

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
[(True, True, 183.9), (True, True, 183.9)]
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np

from warpmesh import _conventions as C
from warpmesh._util.parallel import run_parallel
from warpmesh.io.images import Volume

__all__ = ["LABEL_ABOVE", "INTERFACES", "REST", "interface_refs", "label_boundary", "label_codes", "shared_surface"]

#: the cell-data array holding each triangle's higher label
LABEL_ABOVE = "label_above"
#: values of ``interfaces``: per-label closed surfaces (each interface twice), or one shared surface
INTERFACES = ("separate", "shared")
#: the id of the rest (unmeshed samples and, with ``cap``, the outside) when 0 is not meshed
REST = 0

# the 4 cubes around an edge along axis a, as offsets (in units of the strides) of the
# edge's first sample, in counter-clockwise order seen from the edge's + direction:
# around x in the (y, z) plane, around y in (z, x), around z in (x, y)
_AROUND = {0: ((0, -1, -1), (0, 0, -1), (0, 0, 0), (0, -1, 0)),
           1: ((-1, 0, -1), (-1, 0, 0), (0, 0, 0), (0, 0, -1)),
           2: ((-1, -1, 0), (0, -1, 0), (0, 0, 0), (-1, 0, 0))}
#: a cube's 8 samples (offsets from its lowest), its 12 edges (pairs of those) and their midpoints
_CORNERS = np.array([(c & 1, c >> 1 & 1, c >> 2 & 1) for c in range(8)])
_CUBE_EDGES = [(i, j) for i in range(8) for j in range(i + 1, 8) if np.abs(_CORNERS[i] - _CORNERS[j]).sum() == 1]
_EDGE_MIDPOINTS = np.array([0.5 * (_CORNERS[i] + _CORNERS[j]) for i, j in _CUBE_EDGES])


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
    from warpmesh.surface.volume import check_label_range, check_labels  # shared label checks

    if vol.flags.f_contiguous and not vol.flags.c_contiguous:  # x fastest: slabs of the C-order view
        codes, ids, rest = label_codes(vol.T, labels)
        return codes.T, ids, rest

    present = _present(vol)
    if isinstance(labels, str):
        chosen = check_labels(labels, vol[:0]) if labels != "all" else present[present != 0]
        if len(chosen) == 0:
            raise ValueError("expected some non-zero labels in 'volume' with labels=\"all\", got only 0")
        check_label_range(chosen)
        chosen = chosen.astype(np.int64)
    else:
        chosen = np.asarray(check_labels(labels, vol[:0])).astype(np.int64)
    missing = chosen[~np.isin(chosen, present.astype(np.int64))]
    if len(missing):
        raise ValueError(f"expected 'labels' present in 'volume', got {missing.tolist()} with no sample "
                         f"equal to it (the volume holds {present.tolist()[:20]}): drop it from 'labels'")
    rest_id = REST if REST not in chosen else int(chosen.min()) - 1
    ids = np.unique(np.append(chosen, rest_id))
    rest = int(np.searchsorted(ids, rest_id))
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


def shared_surface(vol: np.ndarray, labels, *, origin, spacing, cap: bool = True,
                   timings: dict | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
    """One surface with each interface between two regions meshed once (surface nets).

    Parameters
    ----------
    vol : (nx, ny, nz) integer array
        Labels; ``vol[i, j, k]`` sits at ``origin + (i, j, k) * spacing``. Floats are
        taken when every value is a whole number.
    labels : "all" or sequence of int
        As :func:`label_codes`.
    origin, spacing : (3,) float
    cap : bool
        The outside of the box is the rest, so every label's boundary is closed; False
        leaves the surfaces open where they meet the box.
    timings : dict, optional
        Filled with the seconds per stage.

    Returns
    -------
    points : (n, 3) float64
    triangles : (m, 3) int64
        Oriented from the lower label's side to the higher's.
    lower, upper : (m,) int64
        The two labels of each triangle, ``lower < upper``.
    info : dict
        ``labels`` (meshed), ``rest`` (its id), ``interfaces`` (count of label pairs),
        ``junction_vertices`` (vertices of cubes holding 3 labels or more).

    Example
    -------
    >>> import numpy as np
    >>> vol = np.zeros((4, 4, 4), dtype=np.int16)
    >>> vol[1:3, 1:3, 1:3] = 5
    >>> points, tris, lower, upper, info = shared_surface(vol, "all", origin=(0, 0, 0), spacing=(1, 1, 1))
    >>> len(points), len(tris), set(lower.tolist()), set(upper.tolist())
    (26, 48, {0}, {5})
    """
    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    vol = _as_label_volume(np.asarray(vol))
    codes, ids, rest = label_codes(vol, labels)
    origin, spacing = np.asarray(origin, dtype=np.float64), np.asarray(spacing, dtype=np.float64)
    reverse = codes.flags.f_contiguous and not codes.flags.c_contiguous
    if reverse:  # x fastest (VTK, NIfTI): mesh the C-order view codes.T, then swap the axes back
        codes, origin, spacing = codes.T, origin[::-1], spacing[::-1]
    if cap:  # one layer of the rest around the box: every region closes on it
        codes = np.pad(codes, 1, constant_values=rest)
        origin = origin - spacing
    timings["codes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    shape = np.array(codes.shape, dtype=np.int64)
    strides = np.array([shape[1] * shape[2], shape[2], 1], dtype=np.int64)
    flat = codes.ravel()
    firsts, cubes = [None] * 3, [None] * 3

    def crossing_edges(a: int) -> None:  # consecutive samples along axis a with different codes
        s = int(strides[a])
        first = np.flatnonzero(flat[:-s] != flat[s:])
        if not cap:  # keep the edges with 4 cubes around them (off the faces of the box along the
            # other axes), and drop the pairs that wrap to the next row; with cap, both samples of
            # such a pair are in the padding layer of the rest, so no crossing edge is among them
            keep = np.ones(len(first), dtype=bool)
            for b in range(3):
                at = first // strides[b] % shape[b]
                keep &= (at <= shape[b] - 2) & ((at >= 1) | (b == a))
            first = first[keep]
        firsts[a] = first
        # the 4 cubes around each edge (a cube is named by its lowest sample), counter-clockwise about +a
        cubes[a] = (np.array(_AROUND[a]) @ strides)[:, None] + first  # (4, q): each row sorted

    run_parallel([partial(crossing_edges, a) for a in range(3)])  # numpy releases the GIL: one axis a thread
    timings["edges"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    mark = np.zeros(flat.size, dtype=bool)  # the cubes that get a vertex, in grid order
    for c in cubes:
        mark[c] = True
    cube_ids = np.flatnonzero(mark)
    del mark
    corners = np.stack([flat[cube_ids + np.dot(corner, strides)] for corner in _CORNERS])  # (8, n)
    points = _cube_vertices(corners, cube_ids, shape, strides)
    points = origin + points * spacing
    timings["vertices"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    columns = [np.ascontiguousarray(points[:, d]) for d in range(3)]
    tris, lo_codes, hi_codes = [None] * 3, [None] * 3, [None] * 3

    def triangles(a: int) -> None:
        quads = np.ascontiguousarray(np.searchsorted(cube_ids, cubes[a]).T)  # sorted keys: fast search
        code0, code1 = flat[firsts[a]], flat[firsts[a] + strides[a]]
        flip = code0 > code1  # lower -> higher runs along -a: reverse the winding
        quads[flip] = quads[flip][:, ::-1]
        tris[a] = _split_quads(columns, quads, a, flip)
        lo_codes[a], hi_codes[a] = np.minimum(code0, code1), np.maximum(code0, code1)

    run_parallel([partial(triangles, a) for a in range(3)])
    tris = np.concatenate(tris)
    lo_code, hi_code = np.concatenate(lo_codes), np.concatenate(hi_codes)
    lower, upper = ids[np.repeat(lo_code, 2)], ids[np.repeat(hi_code, 2)]
    timings["triangles"] = time.perf_counter() - t0

    corners.sort(axis=0)
    labels_in_cube = 1 + np.count_nonzero(corners[1:] != corners[:-1], axis=0)
    info = {"labels": [int(v) for v in ids if v != ids[rest]], "rest": int(ids[rest]),
            "interfaces": int(len(np.unique(lo_code.astype(np.int64) * len(ids) + hi_code))),
            "junction_vertices": int(np.count_nonzero(labels_in_cube >= 3)), "cubes": int(len(points))}
    if reverse:  # (k, j, i) -> (i, j, k) is a reflection: the windings turn over with it
        points, tris = np.ascontiguousarray(points[:, ::-1]), np.ascontiguousarray(tris[:, ::-1])
    return points.astype(C.REAL_DTYPE, copy=False), tris.astype(C.INDEX_DTYPE, copy=False), lower, upper, info


def _cube_vertices(corners: np.ndarray, cube_ids: np.ndarray, shape: np.ndarray, strides: np.ndarray) -> np.ndarray:
    """Each cube's vertex in sample units: its lowest sample plus the mean of the midpoints
    of its crossing edges (edges whose two samples differ), from its (8, n) corner codes.
    The sums are exact in float32 (at most 12 halves); the mean is taken in float64."""
    crossing = np.empty((len(_CUBE_EDGES), corners.shape[1]), dtype=np.float32)
    for e, (i, j) in enumerate(_CUBE_EDGES):
        np.not_equal(corners[i], corners[j], out=crossing[e], casting="unsafe")
    offset = (_EDGE_MIDPOINTS.T.astype(np.float32) @ crossing) / crossing.sum(axis=0, dtype=np.float64)  # (3, n)
    base = np.stack([cube_ids // strides[0], cube_ids // strides[1] % shape[1], cube_ids % shape[2]], axis=1)
    return base + offset.T


def _split_quads(columns: list, quads: np.ndarray, axis: int, flip: np.ndarray) -> np.ndarray:
    """Two triangles per quad around edges along ``axis``, split along the diagonal whose
    triangles both face the quad's direction (``+axis``, or ``-axis`` where ``flip``); the
    shorter one when both do. ``columns`` are the points' x, y, z arrays."""
    u, v = (axis + 1) % 3, (axis + 2) % 3  # the plane across the edge, (u, v, axis) right-handed
    pu, pv = columns[u][quads], columns[v][quads]  # (q, 4) projected corners
    sign = np.where(flip, -1.0, 1.0)

    def facing(i, j, k):  # twice the projected area of triangle (i, j, k), along the quad's direction
        return ((pu[:, j] - pu[:, i]) * (pv[:, k] - pv[:, i]) - (pv[:, j] - pv[:, i]) * (pu[:, k] - pu[:, i])) * sign

    good02 = np.minimum(facing(0, 1, 2), facing(0, 2, 3))
    good13 = np.minimum(facing(1, 2, 3), facing(1, 3, 0))
    pa = columns[axis][quads]
    d02 = (pu[:, 2] - pu[:, 0]) ** 2 + (pv[:, 2] - pv[:, 0]) ** 2 + (pa[:, 2] - pa[:, 0]) ** 2
    d13 = (pu[:, 3] - pu[:, 1]) ** 2 + (pv[:, 3] - pv[:, 1]) ** 2 + (pa[:, 3] - pa[:, 1]) ** 2
    use02 = (good02 > 0) & ((good13 <= 0) | (d02 <= d13))
    tris = np.empty((len(quads), 2, 3), dtype=C.INDEX_DTYPE)
    tris[:, 0] = np.where(use02[:, None], quads[:, [0, 1, 2]], quads[:, [1, 2, 3]])
    tris[:, 1] = np.where(use02[:, None], quads[:, [0, 2, 3]], quads[:, [1, 3, 0]])
    return tris.reshape(-1, 3)


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
    refs = None if mesh.cell_refs is None else mesh.cell_refs.get("triangle")
    above = mesh.cell_data.get(LABEL_ABOVE, {}).get("triangle")
    if refs is None or above is None:
        raise ValueError(f"expected a mesh from interfaces='shared' (cell refs and cell_data[{LABEL_ABOVE!r}]), "
                         "got a mesh without them")
    tris = mesh.cells["triangle"]
    below, over = refs == label, above == label
    if not (below.any() or over.any()):
        named = np.unique(np.concatenate([refs, above])).tolist()
        raise ValueError(f"expected 'label' among the labels of the surface {named}, got {label!r}")
    keep = below | over
    faces = np.where(over[keep, None], tris[keep][:, ::-1], tris[keep])
    other = np.where(over[keep], refs[keep], above[keep])
    used, faces = np.unique(faces, return_inverse=True)
    return type(mesh)(mesh.points[used], {"triangle": faces.reshape(-1, 3)}, cell_refs={"triangle": other},
                      info={"label": int(label)})


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
    refs = None if mesh.cell_refs is None else mesh.cell_refs.get("triangle")
    above = mesh.cell_data.get(LABEL_ABOVE, {}).get("triangle")
    if refs is None or above is None:
        raise ValueError(f"expected a mesh from interfaces='shared' (cell refs and cell_data[{LABEL_ABOVE!r}]), "
                         "got a mesh without them")
    pairs, which = np.unique(np.column_stack([refs, above]), axis=0, return_inverse=True)
    table = {k + 1: (int(lo), int(hi)) for k, (lo, hi) in enumerate(pairs.tolist())}
    data = {**{k: dict(v) for k, v in mesh.cell_data.items()}, "label_below": {"triangle": refs.copy()}}
    return mesh.replace(cell_refs={"triangle": (which.ravel() + 1).astype(C.INDEX_DTYPE)}, cell_data=data,
                        info={**mesh.info, "interfaces": table})

