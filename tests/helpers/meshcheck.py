"""``check_mesh``: the one validity check every mesher test runs on its output.

The combinatorial checks are plain numpy/scipy, independent of ``warpmesh.cells.topology``,
so a bug there cannot hide a bug in a mesher; the geometric check (no two faces cross) is
warpmesh's own, cross-checked against pymeshlab in ``tests/cells/test_intersections.py``.
Import it (``from tests.helpers.meshcheck import check_mesh``) or use the ``check_mesh``
fixture of ``conftest.py``.
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph

from warpmesh.cells.intersections import find_self_intersections

__all__ = ["check_mesh"]


def _split(mesh_or_points, faces):
    if faces is not None:
        return np.asarray(mesh_or_points), np.asarray(faces)
    if hasattr(mesh_or_points, "triangles") and hasattr(mesh_or_points, "points"):  # warpmesh.Mesh
        return np.asarray(mesh_or_points.points), np.asarray(mesh_or_points.triangles)
    if hasattr(mesh_or_points, "vertices") and hasattr(mesh_or_points, "faces"):  # trimesh.Trimesh
        return np.asarray(mesh_or_points.vertices), np.asarray(mesh_or_points.faces)
    raise TypeError(
        f"expected a Mesh, a Trimesh or (points, faces), got {type(mesh_or_points).__name__}"
    )


def _require(bad: np.ndarray, what: str, first) -> None:
    """Raise AssertionError "<count> <what>, first: <first(i)>" when ``bad`` has a True."""
    if bad.any():
        raise AssertionError(
            f"{int(bad.sum())} {what}, first: {first(int(np.flatnonzero(bad)[0]))}"
        )


def check_mesh(mesh_or_points, faces=None, *, closed: bool = True, oriented: bool = True,
               embedded: bool = True) -> dict:
    """Assert that a triangle mesh is valid; return a few counts.

    Checks, in order: points (n, 2|3) finite; faces (m, 3) integer with indices in
    range; no face with a repeated vertex or zero area; no duplicate face (either
    winding); no edge in more than two faces, and every edge in exactly two when
    ``closed``; no directed edge twice (consistent orientation) when ``oriented``;
    every vertex's link a single path or cycle (vertex-manifold); no two faces crossing
    when ``embedded`` (the geometric check of :func:`warpmesh.cells.intersections.
    find_self_intersections`, itself cross-checked against pymeshlab in
    tests/cells/test_intersections.py: a closed, manifold, oriented surface can still
    pass through itself).

    Parameters
    ----------
    mesh_or_points : Mesh, trimesh.Trimesh or (n, 3) float
    faces : (m, 3) int, optional
        Required when the first argument is a points array.
    closed, oriented, embedded : bool

    Returns
    -------
    dict
        ``n_points``, ``n_faces``, ``n_edges``, ``n_boundary_edges``.

    Raises
    ------
    AssertionError
        With a message naming the first offending face, edge or vertex.
    """
    points, faces = _split(mesh_or_points, faces)
    assert points.ndim == 2 and points.shape[1] in (2, 3), (
        f"points: expected shape (n, 2|3), got {points.shape}"
    )
    _require(
        ~np.isfinite(points).all(axis=1), "non-finite points", lambda i: f"point {i} = {points[i]}"
    )
    assert faces.ndim == 2 and faces.shape[1] == 3, f"faces: expected (m, 3), got {faces.shape}"
    assert np.issubdtype(faces.dtype, np.integer), f"faces: expected integers, got {faces.dtype}"
    n, m = len(points), len(faces)
    assert m > 0, "mesh has no faces"
    face = lambda i: f"face {i} = {faces[i]}"  # noqa: E731
    _require(((faces < 0) | (faces >= n)).any(axis=1), f"faces index outside [0, {n})", face)

    p = points[faces].astype(np.float64)
    if p.shape[2] == 2:
        p = np.concatenate([p, np.zeros(p.shape[:2] + (1,))], axis=2)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    s = np.sort(faces, axis=1)
    bad = (s[:, 0] == s[:, 1]) | (s[:, 1] == s[:, 2]) | ~(area > 0)
    _require(bad, "degenerate faces (repeated vertex or zero area)", face)
    order = np.lexsort(s.T[::-1])
    bad = np.zeros(m, dtype=bool)
    bad[order[1:][np.all(s[order[1:]] == s[order[:-1]], axis=1)]] = True
    _require(bad, "duplicated faces", face)

    u, v = faces.ravel().astype(np.int64), np.roll(faces, -1, axis=1).ravel()  # half-edges
    keys, counts = np.unique(np.minimum(u, v) * n + np.maximum(u, v), return_counts=True)
    edge = lambda i: f"edge ({keys[i] // n}, {keys[i] % n}) in {counts[i]} face(s)"  # noqa: E731
    _require(counts > 2, "edges in more than two faces", edge)
    if closed:
        _require(counts != 2, "boundary edges (in one face): not closed", edge)
    if oriented:
        directed, where, dcount = np.unique(u * n + v, return_index=True, return_counts=True)
        _require(
            dcount > 1,
            "edges traversed twice in the same direction: inconsistent orientation",
            lambda i: f"edge ({directed[i] // n}, {directed[i] % n}) of face {where[i] // 3}",
        )

    # vertex-manifold: nodes are directed edges (v -> w) = "w in the link of v"; face
    # (a, b, c) joins link nodes (a->b, a->c), (b->c, b->a), (c->a, c->b). Each vertex
    # must own exactly one connected piece of that graph.
    a, b, c = faces.astype(np.int64).T
    nodes, node = np.unique(
        np.concatenate([a, b, c, a, b, c]) * n + np.concatenate([b, c, a, c, a, b]),
        return_inverse=True,
    )
    node = node.ravel()
    graph = sparse.coo_matrix(
        (np.ones(3 * m), (node[: 3 * m], node[3 * m :])), shape=(len(nodes), len(nodes))
    )
    n_comp, labels = csgraph.connected_components(graph, directed=False)
    pieces = np.unique(nodes // n * n_comp + labels, return_counts=True)[0] // n_comp
    fans = np.bincount(pieces, minlength=n)
    _require(fans > 1, "non-manifold vertices (link not one fan)", lambda i: f"{i}: {fans[i]} fans")
    if embedded:
        p3 = np.column_stack([points, np.zeros(n)]) if points.shape[1] == 2 else points
        pairs = find_self_intersections(p3, faces)
        _require(np.isin(np.arange(m), pairs.ravel()), f"faces crossing another ({len(pairs)} pairs)",
                 lambda i: f"{face(i)} crosses face(s) {pairs[(pairs == i).any(axis=1)].ravel()[:6].tolist()}")
    return {
        "n_points": n,
        "n_faces": m,
        "n_edges": len(keys),
        "n_boundary_edges": int((counts == 1).sum()),
    }
