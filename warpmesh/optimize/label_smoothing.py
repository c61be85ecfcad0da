"""Constrained smoothing of a multi-material surface that keeps every vertex in its voxel cube.

A shared surface from ``mesh_surface(volume, labels=..., interfaces="shared")`` (surface
nets, :mod:`warpmesh.surface.multilabel`) has one vertex per *cube* of the sampling grid
(2 x 2 x 2 samples) holding two labels or more. Its raw placement is a staircase; the
shape the segmentation samples is smoother. :func:`smooth_labels` moves the vertices
towards it while keeping what the labels say true:

* **each vertex stays in its cube** (shrunk by ``MARGIN`` of a spacing on every side,
  or as far out as the raw vertex already is): the cube is derived from the raw
  position, ``floor((p - origin) / spacing)``, so any raw placement inside the cube
  works (the mean of the crossing edges' midpoints, the cube centre). The cube's 8
  samples, hence the set of labels a vertex separates, are the same after smoothing;
* **interfaces and junction curves are smoothed on their own**: a *feature edge* is an
  edge not shared by exactly two triangles of the same interface (same label pair and,
  with ``cap``, the same face of the box): the junction curves where three labels meet,
  the rims where an interface meets a cap face of the box, open boundaries, and the
  edges where a label touches itself along a grid edge. A vertex on no feature edge
  moves towards the mean of its neighbours; a vertex on exactly two feature edges of the
  same curve (the same incident interfaces) towards the mean of its two neighbours along
  the curve; every other vertex (curve ends, corners where curves meet, 4 labels or
  more) is fixed. A vertex whose cube lies outside the volume (``cap``: the padding
  layer of the rest) keeps its coordinate across that face of the box, so caps stay
  planar and box edges straight;
* **the step** is Taubin's lambda/mu pair (lambda = ``relaxation``, mu from
  1/lambda + 1/mu = :data:`PASS_BAND`, -0.526 for lambda = 0.5): a plain Laplacian
  shrinks a closed interface towards its centre and the cube clamp then pins it to the
  inner faces of the cubes; the mu step pushes back (from the staircase, 1.52 times
  4 pi r^2, balls of radii 11 and 7 voxels end within 1.6 % and 3.7 % of it);
* **embedding**: after every :data:`CHECK_EVERY` passes (and the last) the triangles
  around moved vertices are checked (the
  batched checks of :func:`warpmesh.optimize.embedding.face_violations`: a crossing or
  touching with any face nearby, a degenerate face), together with two orientation-free
  checks that hold for the label orientation (lower to higher label, not one consistent
  manifold orientation at junctions): a triangle must still face along its grid edge
  the way it did (surface nets make each triangle from the quad around a grid edge; no
  triangle turns over), and two triangles sharing an edge must not fold onto each other
  (their wings closer than the fold angle of the embedding checks, unless they already
  were), and no triangle may end worse than :data:`SMOOTH_Q` unless it already was
  (the Q_K of the optimisers' bound). The moves of the vertices of failing triangles (and of those they cross) are
  undone (back to their places at the previous check), round by round, until none
  fails, so an embedded input gives an embedded output.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> vol = np.zeros((14, 14, 14), dtype=np.uint8)
>>> vol[3:11, 3:11, 3:7] = 1; vol[3:11, 3:11, 7:11] = 2
>>> raw = wm.mesh_surface(vol, labels="all", interfaces="shared")
>>> smooth = smooth_labels(raw, passes=8)
>>> smooth.info["smoothing"]["passes"], smooth.n_points == raw.n_points
(8, True)
>>> bool(smooth.stats()["area"] < raw.stats()["area"])
True
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from warpmesh._conventions import GRID_INFO
from warpmesh._util.arrays import sorted_unique
from warpmesh._util.progress import Progress, check_progress
from warpmesh.cells.quality import triangle_quality
from warpmesh.optimize.embedding import FOLD_COS, face_violations

__all__ = ["CHECK_EVERY", "DEFAULT_PASSES", "GRID_INFO", "MARGIN", "PASS_BAND", "box_sides", "classify_edges",
           "smooth_labels", "vertex_cubes", "wing_cos", "wing_pairs"]

#: a label whose enclosed volume the smoothing changes by more than this (relative) is named in a
#: UserWarning (small and thin regions shrink: on pyvista's frog at 16 passes, labels of tens to
#: hundreds of voxels lost 10-53 %)
VOLUME_WARNING = 0.025
#: passes when none is given: VTK's ``vtkSurfaceNets3D`` default of 16 smoothing iterations
DEFAULT_PASSES = 16
#: each vertex stays this fraction of a spacing inside its cube's faces (no two vertices meet)
MARGIN = 0.02
#: Taubin's pass-band frequency: mu follows lambda by 1/lambda + 1/mu = PASS_BAND
PASS_BAND = 0.1
#: the moves are checked (and the failing ones undone) after every CHECK_EVERY passes and
#: after the last: the first round of a check looks at nearly every face. On a 200 x 200 x 70
#: block of the frog (677 k triangles, 16 passes), checking every 2 / 4 / 8 / 16 passes took
#: 31 / 14.7 / 9.3 / 6.0 CPU s for areas of 297.6 / 298.4 / 300.7 / 303.4 k (raw 417.8 k)
CHECK_EVERY = 8
#: a move may not leave a triangle's Q_K [FG eq. 16.15] above this and above what it was at
#: the previous check (raw surface nets: at most about 1.5; the README's smoothing=8 on a
#: 40^3 five-label volume made 22-25, 100 passes 682, an angle of 0.1°)
SMOOTH_Q = 6.0
#: two triangles sharing an edge fold when their wings (the half-planes from the edge to the
#: opposite vertices) are closer than this cosine (the fold angle of the embedding checks)
_WING_COS = -FOLD_COS


def vertex_cubes(points, origin, spacing) -> np.ndarray:
    """The grid cube holding each point, as the index of its lowest sample.

    Parameters
    ----------
    points : (n, 3) float
    origin, spacing : (3,) float
        ``volume[i, j, k]`` sits at ``origin + (i, j, k) * spacing``.

    Returns
    -------
    (n, 3) int64
        ``floor((points - origin) / spacing)``; -1 for the padding layer before the
        first sample (``cap``).

    Example
    -------
    >>> vertex_cubes([[0.5, 1.5, -0.5]], (0, 0, 0), (1, 1, 1)).tolist()
    [[0, 1, -1]]
    """
    p = np.asarray(points, dtype=np.float64)
    return np.floor((p - np.asarray(origin, np.float64)) / np.asarray(spacing, np.float64)).astype(np.int64)


def smooth_labels(mesh, passes: int = DEFAULT_PASSES, *, grid: dict | None = None, relaxation: float = 0.5,
                  progress=False):
    """Constrained smoothing of a multi-material surface (module docstring): every vertex in
    its cube, junction curves along themselves, no triangle crossing, turning over or folding.

    Parameters
    ----------
    mesh : Mesh
        A shared surface (``mesh_surface(..., interfaces="shared")``): triangles with
        ``cell_refs["triangle"]`` (lower label) and ``cell_data["label_above"]``, its
        points at their raw surface-nets places (each strictly inside its cube).
    passes : int
        Smoothing passes (a lambda step and a mu step each), 0 or more.
    grid : dict, optional
        ``{"origin": (3,), "spacing": (3,), "shape": (3,)}`` of the label volume; by default
        ``mesh.info["grid"]``, which ``mesh_surface`` records. Without ``shape`` the caps
        are not recognised (their vertices move within their cubes like the others).
    relaxation : float
        Taubin's lambda, in (0, 1]; mu follows from :data:`PASS_BAND`.
    progress : bool or callable
        A bar over the passes (tqdm, shown once the call has taken a second), or
        ``progress(done, total)`` called after each pass.

    Returns
    -------
    Mesh
        The same triangles, labels and data with the moved points; ``info["smoothing"]``
        holds ``passes``, the counts of ``fixed``, ``curve`` and ``surface`` vertices,
        ``reverted`` (vertex moves undone by the checks over all passes), ``moved_max``
        (the largest distance from the raw point, in spacings), ``volume_change`` ({label:
        relative change of the volume its closed boundary encloses}; labels off by more than
        ``VOLUME_WARNING``, 2.5 %, are named in a UserWarning) and ``time``.

    Raises
    ------
    ValueError
        ``mesh`` without the two label arrays or without a grid, ``passes`` or
        ``relaxation`` out of range, or points that are not a surface-nets surface of
        the grid (three distinct cubes around one grid edge per triangle).

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((12, 12, 12), dtype=np.uint8); vol[2:10, 2:10, 2:10] = 1
    >>> m = smooth_labels(wm.mesh_surface(vol, labels="all", interfaces="shared"), passes=4)
    >>> m.info["smoothing"]["passes"], m.stats()["watertight"]
    (4, True)
    """
    from warpmesh.surface.multilabel import shared_labels

    t0 = time.perf_counter()
    if isinstance(passes, (bool, np.bool_)) or not isinstance(passes, (int, np.integer)) or passes < 0:
        raise ValueError(f"expected a non-negative integer for 'passes', got {passes!r}")
    if isinstance(relaxation, (bool, np.bool_)) or not isinstance(relaxation, (int, float, np.floating)) \
            or not 0.0 < float(relaxation) <= 1.0:
        raise ValueError(f"expected 'relaxation' in (0, 1], got {relaxation!r}")
    check_progress(progress)
    refs, above = shared_labels(mesh)
    origin, spacing, shape = _grid(mesh, grid)
    points = np.array(mesh.points, dtype=np.float64)
    tris = np.asarray(mesh.cells["triangle"], dtype=np.int64)
    cube = vertex_cubes(points, origin, spacing)
    axis, facing = _edge_axes(points, tris, cube, origin, spacing)
    lo = origin + (cube + MARGIN) * spacing
    hi = origin + (cube + 1.0 - MARGIN) * spacing
    lo, hi = np.minimum(lo, points), np.maximum(hi, points)  # a raw vertex nearer a face stays where it is
    frozen = np.zeros(points.shape, dtype=bool)
    side_bits = np.zeros(len(points), dtype=np.int64)
    if shape is not None:  # the padding layer of cap: cubes -1 and shape - 1 lie outside the samples
        side_bits = box_sides(cube, shape)
        for a in range(3):
            frozen[:, a] = (side_bits >> (2 * a) & 3) != 0
    table = _edge_table(tris, len(points))
    a, b, feature, kind = classify_edges(tris, refs, above, len(points), side_bits, table)
    weights = _neighbour_weights(a, b, feature, kind, len(points))
    free = ~frozen & (kind > 0)[:, None]
    pairs, pair_cos0 = _wing_pairs(points, tris, table)
    del table
    cells = _cube_index(cube)
    mu = -relaxation / (1.0 - PASS_BAND * relaxation)  # 1/lambda + 1/mu = PASS_BAND
    raw = points.copy()
    reverted = 0
    checked = points.copy()  # the last positions that passed the checks
    bar = Progress(progress, int(passes), "warpmesh label smoothing", "pass")
    for k in range(int(passes)):
        for step in (relaxation, mu):
            delta = weights @ points - points
            points = np.where(free, np.clip(points + step * delta, lo, hi), points)
        if (k + 1) % CHECK_EVERY == 0 or k + 1 == passes:
            reverted += _revert_failures(checked, points, tris, axis, facing, pairs, pair_cos0, cells)
            checked = points.copy()
        bar.update()
    bar.close()
    change = _volume_changes(raw, points, tris, refs, above)
    info = {**mesh.info, "smoothing": {
        "passes": int(passes), "relaxation": float(relaxation), "mu": float(mu),
        "fixed": int(np.count_nonzero(kind == 0)), "curve": int(np.count_nonzero(kind == 1)),
        "surface": int(np.count_nonzero(kind == 2)), "reverted": int(reverted),
        "moved_max": float(np.max(np.abs(points - raw) / spacing, initial=0.0)),
        "volume_change": change, "time": time.perf_counter() - t0}}
    off = {label: c for label, c in change.items() if abs(c) > VOLUME_WARNING}
    if off:
        listed = ", ".join(f"label {k}: {v:+.1%}" for k, v in sorted(off.items(), key=lambda kv: kv[1])[:8])
        warnings.warn(f"label smoothing ({passes} passes) changed {len(off)} label(s)' volume by more than "
                      f"{VOLUME_WARNING:.1%} ({listed}{', ...' if len(off) > 8 else ''}): small or thin regions "
                      "shrink; fewer passes keep them (info['smoothing']['volume_change'])", UserWarning,
                      stacklevel=3)
    return mesh.replace(points=points, info=info)


def _volume_changes(before, after, tris, refs, above) -> dict:
    """{label: relative change of the volume its boundary encloses}, for every label that is some
    triangle's upper side (the rest, below every label, is not one) and whose boundary is closed
    (its vector area zero to rounding: the enclosed volume does not depend on the origin)."""
    labels = np.unique(above)
    index = {"ref": np.searchsorted(labels, refs), "above": np.searchsorted(labels, above)}
    on_ref = (index["ref"] < len(labels)) & (labels[np.minimum(index["ref"], len(labels) - 1)] == refs)

    def per_label(points):
        p = points[tris] - points.mean(axis=0)
        cross = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        v6 = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])) / 6.0
        vol = np.bincount(index["ref"][on_ref], v6[on_ref], minlength=len(labels)) - \
            np.bincount(index["above"], v6, minlength=len(labels))
        area = np.bincount(index["above"], np.linalg.norm(cross, axis=1), minlength=len(labels))
        vec = np.stack([np.bincount(index["ref"][on_ref], cross[on_ref, k], minlength=len(labels)) -
                        np.bincount(index["above"], cross[:, k], minlength=len(labels)) for k in range(3)], axis=1)
        return vol, np.linalg.norm(vec, axis=1) <= 1e-9 * np.maximum(area, 1e-300)

    v0, closed0 = per_label(before)
    v1, closed1 = per_label(after)
    keep = closed0 & closed1 & (np.abs(v0) > 0)
    return {int(labels[i]): float(v1[i] / v0[i] - 1.0) for i in np.flatnonzero(keep)}


def _grid(mesh, grid):
    """(origin, spacing, shape or None) from ``grid`` or ``mesh.info["grid"]``, checked."""
    g = grid if grid is not None else mesh.info.get(GRID_INFO)
    if g is None:
        raise ValueError("expected 'grid' ({'origin', 'spacing', 'shape'} of the label volume) or a mesh from "
                         "mesh_surface(..., interfaces='shared') that records it in info['grid'], got neither")
    if not isinstance(g, dict) or not {"origin", "spacing"} <= set(g):
        raise ValueError(f"expected 'grid' as a dict with 'origin', 'spacing' (and 'shape'), got {g!r}")
    origin, spacing = np.asarray(g["origin"], np.float64), np.asarray(g["spacing"], np.float64)
    if origin.shape != (3,) or spacing.shape != (3,) or not np.all(np.isfinite(origin)) or np.any(~(spacing > 0)):
        raise ValueError(f"expected 'grid' with 3 finite origin values and 3 positive spacings, got {g!r}")
    shape = g.get("shape")
    if shape is not None:
        shape = np.asarray(shape, np.int64)
        if shape.shape != (3,) or np.any(shape < 2):
            raise ValueError(f"expected grid['shape'] as 3 sample counts of at least 2, got {g['shape']!r}")
    return origin, spacing, shape


def _edge_axes(points, tris, cube, origin, spacing):
    """Each triangle's grid-edge axis (the one axis along which its three cubes agree) and
    the sign it faces along it (+1 / -1, from the raw points). Surface nets make every
    triangle from 3 of the 4 cubes around a grid edge; anything else is refused."""
    c = cube[tris]  # (m, 3 corners, 3 axes)
    same = (c[:, 0] == c[:, 1]) & (c[:, 1] == c[:, 2])  # (m, 3)
    spread = c.max(axis=1) - c.min(axis=1)
    distinct = np.any(c[:, 0] != c[:, 1], axis=1) & np.any(c[:, 1] != c[:, 2], axis=1) & \
        np.any(c[:, 0] != c[:, 2], axis=1)
    ok = (same.sum(axis=1) == 1) & np.all(spread <= 1, axis=1) & distinct
    lo = cube.min(axis=0)
    span = cube.max(axis=0) - lo + 1
    key = ((cube[:, 0] - lo[0]) * span[1] + cube[:, 1] - lo[1]) * span[2] + cube[:, 2] - lo[2]
    inside = np.all((points - origin) / spacing > cube, axis=1)  # strictly inside, off the lower faces
    if len(np.unique(key)) < len(cube) or not inside.all():  # surface nets: one vertex per cube, inside it
        ok &= False
    if not ok.all():
        bad = int(np.flatnonzero(~ok)[0])
        raise ValueError(f"expected 'mesh' points at their surface-nets places on the grid (each triangle's three "
                         f"vertices in three cubes around one grid edge, one vertex per cube), got triangle {bad} "
                         f"in cubes {c[bad].tolist()}: pass the volume's grid (origin, spacing) and its "
                         "surface as meshed (or smoothed), not transformed")
    axis = np.argmax(same, axis=1)
    normal = _normals(points, tris)
    facing = np.sign(normal[np.arange(len(tris)), axis])
    return axis, facing


def _normals(points, tris):
    p = points[tris]
    return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])


def _edge_table(tris, n):
    """The 3 m face edges sorted by edge: (their (3m, 2) sorted ends, their faces, the start
    of each edge's run, its length, and each sorted entry's face edge 3 f + k: edge k of
    face f runs from corner k to corner k + 1)."""
    e = np.sort(np.stack([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    key = e[:, 0] * n + e[:, 1]
    order = np.argsort(key)
    key = key[order]
    starts = np.flatnonzero(np.concatenate([[True], key[1:] != key[:-1]]))
    count = np.diff(np.append(starts, len(key)))
    return e[order], order // 3, starts, count, order


def classify_edges(triangles, lower, upper, n: int, side_bits=None, table=None):
    """The edges of a shared surface, which are feature edges, and the kind of each vertex.

    A feature edge is not shared by exactly two triangles of one interface (one label
    pair and, with ``side_bits``, one face of the box): junction curves, cap rims, open
    boundaries, a label touching itself along a grid edge.

    Parameters
    ----------
    triangles : (m, 3) int
    lower, upper : (m,) int
        The two labels of each triangle.
    n : int
        The number of points.
    side_bits : (n,) int, optional
        Per vertex, bit 2a (2a + 1) set when its cube lies before (after) the samples
        along axis a.
    table : tuple, optional
        :func:`_edge_table` of the triangles, if already computed.

    Returns
    -------
    a, b : (e,) int64
        The ends of each edge, a < b.
    feature : (e,) bool
    kind : (n,) int
        0: fixed (a curve's end, a corner, 4 labels or more: not on exactly two feature
        edges of one curve), 1: on a curve (exactly two feature edges, incident to the
        same interfaces), 2: on one interface (no feature edge).

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((8, 8, 8), np.uint8); vol[2:6, 2:6, 2:4] = 1; vol[2:6, 2:6, 4:6] = 2
    >>> m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    >>> a, b, feature, kind = classify_edges(m.triangles, m.cell_refs["triangle"],
    ...                                      m.cell_data["label_above"]["triangle"], m.n_points)
    >>> int(feature.sum()), np.bincount(kind, minlength=3).tolist()  # one closed junction loop
    (16, [0, 16, 91])
    """
    tris = np.asarray(triangles, np.int64)
    ends, face, starts, count, order = _edge_table(tris, n) if table is None else table
    if side_bits is None:
        side_bits = np.zeros(n, np.int64)
    common = side_bits[tris[:, 0]] & side_bits[tris[:, 1]] & side_bits[tris[:, 2]]
    lowest_bit = np.array([0] + [(i & -i).bit_length() for i in range(1, 64)])
    cap_face = lowest_bit[common]  # 1 + the lowest face of the box all three vertices lie beyond, or 0
    ids = np.unique(np.concatenate([np.unique(lower), np.unique(upper)]))
    pair = np.searchsorted(ids, lower).astype(np.int64) * len(ids) + np.searchsorted(ids, upper)
    face_key = pair * 7 + cap_face  # one key per interface (label pair and face of the box)
    keys = face_key[face]
    kmin = np.minimum.reduceat(keys, starts)
    kmax = np.maximum.reduceat(keys, starts)
    ksum = np.add.reduceat(keys, starts)
    feature = (count != 2) | (kmin != kmax)
    a, b = ends[starts, 0], ends[starts, 1]
    _, signature = np.unique(np.column_stack([count, kmin, kmax, ksum])[feature], axis=0, return_inverse=True)
    fa, fb, fs = a[feature], b[feature], signature.ravel()
    degree = np.bincount(np.concatenate([fa, fb]), minlength=n)
    smin = np.full(n, np.iinfo(np.int64).max)
    smax = np.full(n, -1)
    for v in (fa, fb):
        np.minimum.at(smin, v, fs)
        np.maximum.at(smax, v, fs)
    kind = np.where(degree == 0, 2, np.where((degree == 2) & (smin == smax), 1, 0))
    # a vertex on no feature edge whose faces are not one fan (two cones touching at it, a label
    # meeting itself at a grid node, may carry two interfaces or one twice) is fixed too
    kind[(kind == 2) & (_fans(tris, n, (ends, face, starts, count, order)) != 1)] = 0
    return a, b, feature, kind


def _fans(tris, n, table=None):
    """How many fans (edge-connected groups of faces around it) each vertex has.

    The graph's nodes are the (edge, end) pairs, numbered from the edge table (2 e + 1 for
    the edge's larger end), and each corner links the two edges of its face that meet
    there; a component lies at one vertex, so a vertex's fans are the components there.

    >>> _fans(np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 6]]), 7).tolist()  # two fans at 0
    [2, 1, 1, 1, 1, 1, 1]
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    ends, _, starts, _, order = _edge_table(tris, n) if table is None else table
    head = np.zeros(len(order), np.int64)
    head[starts] = 1
    edge = np.empty(len(order), np.int64)
    edge[order] = np.cumsum(head) - 1  # face edge 3 f + k -> its edge
    edge = edge.reshape(-1, 3)
    low = ends[starts, 0]  # each edge's smaller end
    out_edge, in_edge = edge, edge[:, [2, 0, 1]]  # at corner k: edge k leaves it, edge k - 1 arrives
    node_out = 2 * out_edge + (tris != low[out_edge])
    node_in = 2 * in_edge + (tris != low[in_edge])
    n_nodes = 2 * len(starts)
    graph = coo_matrix((np.ones(node_out.size), (node_out.ravel(), node_in.ravel())), shape=(n_nodes, n_nodes))
    n_comp, comp = connected_components(graph, directed=False)
    vertex_of = np.full(n_comp, -1, np.int64)
    vertex_of[comp[node_out.ravel()]] = tris.ravel()
    return np.bincount(vertex_of[vertex_of >= 0], minlength=n)


def _neighbour_weights(a, b, feature, kind, n):
    """The smoothing operator: a row-normalised adjacency (scipy CSR), a surface vertex over
    all its edges, a curve vertex over its two feature edges, a fixed vertex the identity."""
    import scipy.sparse as sp

    use = np.where(feature, kind[a] == 1, kind[a] == 2), np.where(feature, kind[b] == 1, kind[b] == 2)
    rows = np.concatenate([a[use[0]], b[use[1]], np.flatnonzero(kind == 0)])
    cols = np.concatenate([b[use[0]], a[use[1]], np.flatnonzero(kind == 0)])
    deg = np.bincount(rows, minlength=n).astype(np.float64)
    return sp.csr_matrix((1.0 / deg[rows], (rows, cols)), shape=(n, n))


def _wing_pairs(points, tris, table):
    """:func:`wing_pairs` of every face from the edge table, and their wing cosines now."""
    pairs = _pairs_of(table)
    return pairs, wing_cos(points, tris, pairs)


def _pairs_of(table):
    ends, face, _, _, _ = table
    rows = []
    for lag in (1, 2, 3):  # up to 4 faces around an edge (a label touching itself along a grid edge)
        i = np.flatnonzero(np.all(ends[lag:] == ends[:-lag], axis=1))
        rows.append(np.column_stack([face[i], face[i + lag], ends[i, 0], ends[i, 1]]))
    return np.concatenate(rows)


def wing_pairs(triangles, faces=None) -> np.ndarray:
    """The pairs of triangles sharing an edge (every pair around an edge in 3 or 4).

    Parameters
    ----------
    triangles : (m, 3) int
    faces : (k,) int, optional
        Only the pairs with at least one of these faces.

    Returns
    -------
    (q, 4) int64
        Rows (face A, face B, shared vertex, shared vertex), for :func:`wing_cos`.

    Example
    -------
    >>> wing_pairs(np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])).tolist()
    [[0, 1, 0, 1], [1, 2, 0, 1], [0, 2, 0, 1]]
    """
    tris = np.asarray(triangles, np.int64)
    if len(tris) == 0:
        return np.zeros((0, 4), np.int64)
    pairs = _pairs_of(_edge_table(tris, int(tris.max()) + 1))
    if faces is not None:
        mark = np.zeros(len(tris), bool)
        mark[np.asarray(faces, np.int64)] = True
        pairs = pairs[mark[pairs[:, 0]] | mark[pairs[:, 1]]]
    return pairs


def box_sides(cube, shape) -> np.ndarray:
    """Per vertex, which faces of the sampled box its cube lies beyond (the padding layer
    of ``cap``): bit 2a for cube index -1 along axis a, bit 2a + 1 for ``shape[a] - 1``.

    Example
    -------
    >>> box_sides(np.array([[-1, 0, 3], [2, 2, 2]]), (5, 5, 4)).tolist()
    [33, 0]
    """
    cube = np.asarray(cube, np.int64)
    bits = np.zeros(len(cube), np.int64)
    for a in range(3):
        before, after = (cube[:, a] == -1).astype(np.int64), (cube[:, a] == shape[a] - 1).astype(np.int64)
        bits |= before << (2 * a) | after << (2 * a + 1)
    return bits


def wing_cos(points, tris, pairs):
    """Cosine of the angle between the two wings of each pair of triangles around their
    shared edge (1: folded flat onto each other, -1: flat), whatever their orientations.

    Parameters
    ----------
    points : (n, 3) float
    tris : (m, 3) int
    pairs : (k, 4) int
        Rows (face A, face B, shared vertex, shared vertex).

    Returns
    -------
    (k,) float

    Example
    -------
    >>> p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 1, 1e-3]], float)
    >>> t = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    >>> np.round(wing_cos(p, t, np.array([[0, 1, 0, 1], [0, 2, 0, 1]])), 3).tolist()
    [-1.0, 1.0]
    """
    if len(pairs) == 0:
        return np.zeros(0)
    fa, fb, e0, e1 = pairs.T
    opp_a = tris[fa].sum(axis=1) - e0 - e1
    opp_b = tris[fb].sum(axis=1) - e0 - e1
    p0 = points[e0]
    d = points[e1] - p0
    d /= np.maximum(np.linalg.norm(d, axis=1), 1e-300)[:, None]
    ua, ub = points[opp_a] - p0, points[opp_b] - p0
    ua -= np.einsum("ij,ij->i", ua, d)[:, None] * d
    ub -= np.einsum("ij,ij->i", ub, d)[:, None] * d
    den = np.maximum(np.linalg.norm(ua, axis=1) * np.linalg.norm(ub, axis=1), 1e-300)
    return np.einsum("ij,ij->i", ua, ub) / den


def _local_failures(points, tris, faces, axis, facing, pairs, pair_cos0, pending, q_old):
    """Faces (of ``faces``, plus partners) that turned over along their grid edge, fold
    onto a neighbour (orientation-free checks that hold at junctions) or became worse than
    ``SMOOTH_Q`` and than they were (``q_old``, every face's Q_K at the previous check)."""
    n_hat = _normals(points, tris[faces])
    turned = faces[n_hat[np.arange(len(faces)), axis[faces]] * facing[faces] <= 0.0]
    q = triangle_quality(points, tris[faces])
    worse = faces[(q > SMOOTH_Q) & (q > q_old[faces])]
    near = pending[pairs[:, 0]] | pending[pairs[:, 1]]
    sel = np.flatnonzero(near)
    cos = wing_cos(points, tris, pairs[sel])
    folded = sel[cos > np.maximum(_WING_COS, pair_cos0[sel] + 1e-9)]
    return np.concatenate([turned, worse, pairs[folded, 0], pairs[folded, 1]])


def _revert_failures(old, new, tris, axis, facing, pairs, pair_cos0, cells) -> int:
    """Undo (in ``new``) the moves of the vertices of failing faces, round by round, until
    no face around a moved vertex fails; returns the count of moves undone."""
    moved = np.any(new != old, axis=1)
    pending = moved[tris].any(axis=1)
    q_old = np.zeros(len(tris))  # Q_K at the previous check, of the faces the moves touch (the others never fail)
    q_old[pending] = triangle_quality(old, tris[pending])
    undone_total = 0
    while pending.any():
        faces = np.flatnonzero(pending)
        bad, others = _crossings(new, tris, faces, cells)
        failing = np.concatenate([faces[bad], others, _local_failures(new, tris, faces, axis, facing, pairs,
                                                                      pair_cos0, pending, q_old)])
        verts = np.unique(tris[failing].ravel())
        verts = verts[moved[verts]]
        if len(verts) == 0:  # what fails was there before the moves
            break
        new[verts] = old[verts]
        moved[verts] = False
        undone_total += len(verts)
        back = np.zeros(len(moved), bool)
        back[verts] = True
        pending = back[tris].any(axis=1)
    return undone_total


def _crossings(points, tris, faces, cells):
    """:func:`face_violations` of ``faces`` (crossings and degenerate faces; its fold test
    assumes one orientation and is off) with the failing faces' partners. A few faces are
    checked within the faces near them only: every vertex stays in its cube, so a face can
    meet only faces whose cubes lie within 2 of its own cubes' range along each axis (a
    triangle's cubes span 2 along each axis at most), hence within 3 of each of its cubes.
    ``cells`` is :func:`_cube_index`'s."""
    m = len(tris)
    if len(faces) * 8 > m:
        return face_violations(points, tris, faces, fold_cos=-2.0, partners=True)
    key, order, sorted_keys, stride = cells
    zone = sorted_unique(key[tris[faces]])
    for s in stride:  # the 7 x 7 x 7 block about each cube, one axis at a time (no key listed twice)
        zone = sorted_unique(zone[:, None] + s * np.arange(-3, 4)[None, :])
    pos = np.minimum(np.searchsorted(sorted_keys, zone), len(sorted_keys) - 1)
    marked = np.zeros(len(points), bool)
    marked[order[pos[sorted_keys[pos] == zone]]] = True
    keep = np.flatnonzero(marked[tris].any(axis=1))
    bad, others = face_violations(points, tris[keep], np.searchsorted(keep, faces), fold_cos=-2.0, partners=True)
    return bad, keep[others]


def _cube_index(cube):
    """Each vertex's cube as one integer key (linear in the cube, so offsets add; 3 cubes of
    padding on every side, so offsets within 3 cubes never wrap), the vertices in key order,
    the sorted keys and the key stride of each axis."""
    lo = cube.min(axis=0) - 3
    span = cube.max(axis=0) - lo + 4
    stride = np.array([span[1] * span[2], span[2], 1], dtype=np.int64)
    key = (cube - lo) @ stride
    order = np.argsort(key)
    return key, order, key[order], stride
