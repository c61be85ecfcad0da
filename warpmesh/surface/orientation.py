"""Consistent orientation of triangle surfaces, a posteriori [FG §16.4.4].

"The polygons are oriented by adjacency in a consistent way, in each connected
component": two faces sharing an edge must traverse it in opposite directions. The
pipeline, vectorised with numpy/scipy (Python loops run only over pointer-jumping
rounds and memory chunks, never over faces or edges):

1. half-edges sorted by undirected key: every edge shared by two faces links them, with
   a *parity* of 1 when both traverse it the same way (one of them must flip); an edge
   in three or more faces is non-manifold and raises;
2. components through those links, a spanning forest (one breadth-first search from a
   virtual node tied to each component's first face) and, by pointer jumping, each
   face's flip relative to its component's first face;
3. every link is checked against those flips: a contradiction means the component is
   not orientable (Möbius strip, Klein bottle) and raises;
4. each component's orientation is chosen: a closed component (no boundary edge) of a
   3D mesh encloses a region and is oriented outward (:mod:`warpmesh._conventions`:
   normals towards f < 0), unless it lies inside an odd number of other closed
   components, where it bounds a cavity and points into it (the inner wall of a hollow
   sphere). Open components, and every component when ``outward=False``, keep the
   orientation of the majority of their input faces (the fewest flips). In 2D,
   ``outward=True`` makes each component's signed area positive.

A flipped face ``(a, b, c)`` becomes ``(a, c, b)``: its first vertex and its row stay.

Examples
--------
>>> import trimesh
>>> import warpmesh as wm
>>> from warpmesh.surface.orientation import orient
>>> tm = trimesh.creation.icosphere(subdivisions=1)
>>> faces = tm.faces.copy()
>>> faces[::3] = faces[::3, [0, 2, 1]]  # every third face inverted
>>> bad = wm.Mesh(tm.vertices, {"triangle": faces})
>>> bad.stats()["oriented"]
False
>>> good = orient(bad)
>>> good.stats()["oriented"], good.stats()["volume"] > 0, bool((good.triangles == tm.faces).all())
(True, True, True)
>>> good.info["orient"]["flipped"], good.info["orientation"]
(27, 'outward (closed components; cavity walls inward, open ones by majority): 27 of 80 faces flipped')
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.cells.rays import ray_windings
from warpmesh.errors import TopologyError
from warpmesh.mesh import Mesh

__all__ = ["orient", "orient_faces"]

# ----------------------------------------------------------------------------- validation
def _check_input(points, faces) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(points, faces)`` as float64 (n, 2|3) and int64 (m, 3) arrays, or raise."""
    pts = np.asarray(points)
    if pts.dtype.kind not in "iuf":
        raise TypeError(f"expected a float array for 'points', got dtype {pts.dtype}")
    if pts.ndim != 2 or pts.shape[1] not in (2, 3):
        raise ValueError(f"expected 'points' of shape (n, 2) or (n, 3), got shape {pts.shape}")
    arr = np.asarray(faces)
    if arr.size and arr.dtype.kind not in "iu":
        raise TypeError(f"expected an integer array for 'faces', got dtype {arr.dtype}")
    if arr.size == 0:
        raise ValueError(
            f"expected at least one face in 'faces', got shape {arr.shape}; there is nothing "
            "to orient"
        )
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"expected 'faces' of shape (m, 3), got shape {arr.shape}")
    arr = arr.astype(INDEX_DTYPE, copy=False)
    n = len(pts)
    out = ((arr < 0) | (arr >= n)).any(axis=1)
    if out.any():
        f = int(np.flatnonzero(out)[0])
        raise ValueError(
            f"expected indices in [0, {n}) in 'faces', got face {f} = {arr[f].tolist()} "
            f"({int(out.sum())} such faces)"
        )
    rep = (arr[:, 0] == arr[:, 1]) | (arr[:, 1] == arr[:, 2]) | (arr[:, 2] == arr[:, 0])
    if rep.any():
        f = int(np.flatnonzero(rep)[0])
        raise ValueError(
            f"expected three distinct vertices per face, got face {f} = {arr[f].tolist()} "
            f"({int(rep.sum())} degenerate faces); remove them first, e.g. "
            "faces[~warpmesh.cells.topology.degenerate_faces(points, faces)]"
        )
    return pts.astype(REAL_DTYPE, copy=False), arr


# ----------------------------------------------------------------------------- adjacency
def _links(faces: np.ndarray, n: int):
    """Face links across manifold edges, and the faces on the boundary.

    Returns ``f1, f2, parity`` (one entry per edge in exactly two faces; parity True when
    both faces run the edge the same way) and ``boundary`` (the face of every edge in one
    face). Raises TopologyError at an edge in three or more faces.
    """
    m = len(faces)
    u = faces.ravel()
    v = faces[:, [1, 2, 0]].ravel()  # half-edge h = 3 f + j runs u[h] -> v[h]
    key = np.minimum(u, v) * n + np.maximum(u, v)
    order = np.argsort(key)
    ks = key[order]
    starts = np.flatnonzero(np.concatenate([[True], ks[1:] != ks[:-1]]))
    counts = np.diff(np.append(starts, 3 * m))
    heavy = counts > 2
    if heavy.any():
        s, c = int(starts[heavy][0]), int(counts[heavy][0])
        a, b = divmod(int(ks[s]), n)
        raise TopologyError(
            f"edge ({a}, {b}) is shared by {c} faces {sorted((order[s : s + c] // 3).tolist())} "
            f"({int(heavy.sum())} non-manifold edges): orientation is undefined where more "
            "than two faces meet; remove the extra faces or split the sheets apart "
            "(duplicate the edge's vertices per sheet) before orienting"
        )
    pair = starts[counts == 2]
    h1, h2 = order[pair], order[pair + 1]
    boundary = order[starts[counts == 1]] // 3
    return h1 // 3, h2 // 3, u[h1] == u[h2], boundary


def _relative_flips(m: int, f1, f2, parity):
    """Components, and each face's flip relative to its component's first face.

    Returns ``n_comp``, ``comp`` (m,) numbered by first appearance, ``roots`` (n_comp,)
    the first face of each component, and ``flip`` (m,) bool.
    """
    from scipy import sparse
    from scipy.sparse import csgraph

    graph = sparse.coo_matrix((np.ones(len(f1), np.int8), (f1, f2)), shape=(m, m)).tocsr()
    _, labels = csgraph.connected_components(graph, directed=False)
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(len(first), dtype=INDEX_DTYPE)
    rank[np.argsort(first)] = np.arange(len(first))
    comp, roots = rank[labels], np.sort(first)

    # spanning forest: one BFS from a virtual node m linked to every component's root
    rows = np.concatenate([f1, np.full(len(roots), m)])
    cols = np.concatenate([f2, roots])
    forest = sparse.coo_matrix(
        (np.ones(len(rows), np.int8), (rows, cols)), shape=(m + 1, m + 1)
    ).tocsr()
    _, pred = csgraph.breadth_first_order(forest, m, directed=False, return_predecessors=True)
    ptr = pred[:m].astype(INDEX_DTYPE)
    ptr[roots] = roots

    # parity of each tree link (ptr[f], f), looked up among the sorted links
    lo, hi = np.minimum(f1, f2), np.maximum(f1, f2)
    link_key = lo * m + hi
    by_key = np.argsort(link_key)
    tree_key = np.minimum(ptr, np.arange(m)) * m + np.maximum(ptr, np.arange(m))
    at = np.searchsorted(link_key[by_key], tree_key).clip(max=max(len(by_key) - 1, 0))
    flip = parity[by_key][at] if len(by_key) else np.zeros(m, dtype=bool)
    flip[roots] = False

    # pointer jumping: flip[f] is the parity from f to ptr[f]; O(log depth) rounds
    while True:
        nxt = ptr[ptr]
        if np.array_equal(nxt, ptr):
            break
        flip ^= flip[ptr]
        ptr = nxt
    return len(roots), comp, roots, flip


def _raise_non_orientable(bad, f1, f2, comp, roots, faces) -> None:
    """Raise TopologyError for the first contradictory link (``bad`` mask over links)."""
    k = int(np.flatnonzero(bad)[0])
    a, b = int(f1[k]), int(f2[k])
    c = int(comp[a])
    shared = sorted(set(faces[a].tolist()) & set(faces[b].tolist()))
    n_bad = len(np.unique(comp[f1[bad]]))
    raise TopologyError(
        f"component {c} (first face {int(roots[c])}, {int(np.sum(comp == c))} faces) is not "
        f"orientable, like a Moebius strip or a Klein bottle: the winding carried from face "
        f"{int(roots[c])} through its neighbours reaches faces {a} and {b} with opposite "
        f"senses across their shared edge {tuple(shared)} ({n_bad} such components). No "
        "consistent winding exists; cut the surface open along a curve through that edge, "
        "or rebuild it as the boundary of a solid"
    )


# ----------------------------------------------------------------------------- nesting
def _nesting_depth(points, rel, comp, closed_ids, roots) -> np.ndarray:
    """For each closed component, the number of other closed components around it.

    ``rel`` are the faces oriented like their component's first face. A point of each
    component (its first face's centroid) is tested against every other closed component
    by :func:`warpmesh.cells.rays.ray_windings` (signed crossings of an axis-parallel ray,
    candidates from a 2D grid of buckets, ties redone along another axis, then solid
    angles): it is inside when the winding number is odd.
    """
    k = len(closed_ids)
    if k < 2:
        return np.zeros(k, dtype=INDEX_DTYPE)
    local = np.full(int(comp.max()) + 1, -1, dtype=INDEX_DTYPE)
    local[closed_ids] = np.arange(k)
    sel = np.flatnonzero(local[comp] >= 0)
    corners = points[rel[sel]]
    if not np.isfinite(corners).all():
        f = int(sel[np.flatnonzero(~np.isfinite(corners).all(axis=(1, 2)))[0]])
        raise ValueError(f"expected finite coordinates in 'points', got NaN or inf at a vertex of face {f} "
                         f"{rel[f].tolist()}; the nesting of closed components is undefined there")
    q = points[rel[roots[closed_ids]]].mean(axis=1)  # (k, 3) one point per component
    point, _, winding, _ = ray_windings(corners, local[comp[sel]], q, skip=np.arange(k))
    return np.bincount(point[winding % 2 == 1], minlength=k).astype(INDEX_DTYPE)


# ----------------------------------------------------------------------------- public API
def orient_faces(points, faces, *, outward: bool = True) -> tuple[np.ndarray, dict]:
    """Orient a triangle surface consistently in each connected component.

    Parameters
    ----------
    points : (n, 3) or (n, 2) float
        Vertex coordinates (used only to choose each component's side).
    faces : (m, 3) int
        Triangle vertex indices, three distinct ones per face.
    outward : bool
        True (default): a closed component of a 3D mesh gets normals out of the region
        it encloses (positive signed volume), or into its cavity when it lies inside an
        odd number of other closed components (negative signed volume); in 2D, every
        component gets a positive signed area. Open components, and all components when
        False, keep the orientation of the majority of their input faces (ties: that of
        their first face).

    Returns
    -------
    faces : (m, 3) int64
        The same rows, each either unchanged or flipped from ``(a, b, c)`` to ``(a, c, b)``.
    report : dict
        ``components`` (edge-connected), ``closed`` and ``open`` (components without /
        with boundary edges), ``inward`` (closed components oriented into a cavity),
        ``flipped`` (faces whose winding changed), ``non_orientable`` (always 0: such a
        component raises), ``outward`` (the option).

    Raises
    ------
    TypeError
        Non-numeric points or non-integer faces.
    ValueError
        Wrong shapes, no faces, indices out of range, a face with a repeated vertex.
    TopologyError
        An edge shared by more than two faces, or a non-orientable component.

    Examples
    --------
    >>> pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    >>> fixed, report = orient_faces(pts, [[0, 1, 2], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    >>> fixed.tolist()
    [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]
    >>> report["closed"], report["flipped"]
    (1, 1)
    """
    if not isinstance(outward, (bool, np.bool_)):
        raise TypeError(f"expected a bool for 'outward', got {type(outward).__name__}")
    points, faces = _check_input(points, faces)
    m = len(faces)
    f1, f2, parity, boundary = _links(faces, len(points))
    n_comp, comp, roots, flip = _relative_flips(m, f1, f2, parity)
    bad = (flip[f1] ^ flip[f2]) != parity
    if bad.any():
        _raise_non_orientable(bad, f1, f2, comp, roots, faces)

    size = np.bincount(comp, minlength=n_comp)
    n_rel = np.bincount(comp, weights=flip, minlength=n_comp)
    turn = n_rel > size - n_rel  # majority rule: most faces keep their input winding
    closed = np.ones(n_comp, dtype=bool)
    closed[comp[boundary]] = False
    inner = np.zeros(n_comp, dtype=bool)
    if outward:
        rel = np.where(flip[:, None], faces[:, [0, 2, 1]], faces)  # oriented like the roots
        centre = np.stack(
            [np.bincount(comp, points[faces, d].mean(axis=1), n_comp) for d in
             range(points.shape[1])], axis=1) / size[:, None]
        p0, p1, p2 = (points[rel[:, j]] - centre[comp] for j in range(3))
        if points.shape[1] == 3:
            measure = np.einsum("ij,ij->i", p0, np.cross(p1 - p0, p2 - p0))  # 6 x volume
            decide = closed.copy()
            ids = np.flatnonzero(closed)
            inner[ids] = _nesting_depth(points, rel, comp, ids, roots) % 2 == 1
        else:
            d1, d2 = p1 - p0, p2 - p0
            measure = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]  # 2 x area
            decide = np.ones(n_comp, dtype=bool)
        total = np.bincount(comp, measure, n_comp)
        want = np.where(inner, -1.0, 1.0)
        decide &= total != 0  # a flat closed component (zero volume) keeps the majority rule
        turn = np.where(decide, np.sign(total) != want, turn)
    final = flip ^ turn[comp]
    out = np.where(final[:, None], faces[:, [0, 2, 1]], faces)
    report = {
        "components": int(n_comp),
        "closed": int(closed.sum()),
        "open": int(n_comp - closed.sum()),
        "inward": int(inner.sum()),
        "flipped": int(final.sum()),
        "non_orientable": 0,
        "outward": bool(outward),
    }
    return out, report


def orient(mesh: Mesh, *, outward: bool = True) -> Mesh:
    """Orient the triangle block of a mesh consistently (see :func:`orient_faces`).

    Parameters
    ----------
    mesh : Mesh
        A mesh with a non-empty ``"triangle"`` block; other blocks are copied unchanged.
    outward : bool
        Closed components outward (cavity walls inward), open ones by majority; False:
        every component by majority. See :func:`orient_faces`.

    Returns
    -------
    Mesh
        A new mesh: triangle rows in the same order (refs and cell data still match), only
        the vertex order within rows changed; ``info["orient"]`` holds the report of
        :func:`orient_faces` and ``info["orientation"]`` says the rule applied in words (a
        string, as the meshers' ``info["orientation"]`` is). The input mesh is untouched.

    Raises
    ------
    TypeError
        ``mesh`` is not a :class:`~warpmesh.mesh.Mesh`.
    ValueError
        ``mesh`` has no triangles, or a triangle with a repeated vertex.
    TopologyError
        A non-manifold edge, or a non-orientable component.

    Examples
    --------
    >>> import warpmesh as wm
    >>> strip = wm.Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], {"triangle": [[0, 1, 2], [1, 2, 3]]})
    >>> out = orient(strip)
    >>> out.triangles.tolist(), out.info["orient"]["open"]
    ([[0, 1, 2], [1, 3, 2]], 1)
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(
            f"expected a warpmesh Mesh for 'mesh', got {type(mesh).__name__}; for arrays use "
            "orient_faces(points, faces)"
        )
    if "triangle" not in mesh.cells:
        raise ValueError(
            f"expected a 'triangle' block in 'mesh', got cell blocks {list(mesh.cells)}; "
            "only triangle surfaces are oriented"
        )
    if len(mesh.triangles) == 0:
        raise ValueError("expected at least one triangle in 'mesh', got an empty 'triangle' block")
    faces, report = orient_faces(mesh.points, mesh.triangles, outward=outward)
    if not outward:
        rule = "by majority in each component"
    elif mesh.dim == 2:
        rule = "counter-clockwise (each component's signed area positive)"
    else:
        rule = "outward (closed components; cavity walls inward, open ones by majority)"
    words = f"{rule}: {report['flipped']} of {len(faces)} faces flipped"
    return mesh.replace(
        cells={**mesh.cells, "triangle": faces}, info={**mesh.info, "orientation": words, "orient": report}
    )
