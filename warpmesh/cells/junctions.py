"""Sheets crossing along a junction edge: the cyclic order of the faces around each edge of
three faces or more.

:func:`warpmesh.cells.intersections.find_self_intersections` tests pairs of triangles, and two
triangles that share an edge meet only along it unless folded flat, so it says nothing
about them. Around a *non-manifold* edge (three faces or more: the junction curves of a
multi-material surface, ``mesh_surface(volume, labels=..., interfaces="shared")``), two
sheets can still cross each other along the edge with no pair of triangles crossing: the
faces' cyclic order about the edge is wrong. With labels it is checkable, exactly:

- each face separates two regions, its *back* side (``lower``: the side its right-hand
  normal points away from) and its *front* side (``upper``), as the shared surfaces of
  :mod:`warpmesh.surface.multilabel` are oriented from the lower label to the higher;
- sort the faces of an edge ab (a < b) by their angle about the axis b - a (counter-
  clockwise seen from b); a face that runs a -> b has its normal on its counter-clockwise
  side, one that runs b -> a on its clockwise side;
- the surface is embedded around the edge iff between each two consecutive faces there is
  one region: the label on the side of face i that faces the gap equals the label on the
  side of face i + 1 that faces it, for every gap (cyclically), and no two faces lie in
  one half-plane (they would overlap).

Each gap is then a wedge of one region and the wedges are disjoint, so the sheets do not
cross there; conversely, an embedded surface whose faces are labelled by the regions they
separate has one region in each gap. The check never reports such a surface, whatever
its geometry; it reports a face turned into the wrong gap even where no two triangles
cross.

Without labels (``lower = upper = None``) each face separates its inside (back) from its
outside (front), the house orientation: the rule says the faces around the edge alternate
outward and inward, i.e. the surface locally bounds a solid (winding number 0 or 1 in
every gap). Two closed surfaces welded along an edge side by side pass; interleaved, they
are reported. So is one touching the inside of another along an edge with the same
orientation (winding number 2 inside it): from the faces around the edge alone the two
cannot be told apart (which faces belong to one sheet is not known), so this variant
answers "does the surface bound a solid here", not "do two sheets cross", and the mesh's
check (:func:`warpmesh.cells.intersections.check`) uses only the labelled rule.

Exactness: the angular order comes from orientation signs relative to the edge, no
angle is computed. For an edge ab and two apexes c, d, O(a, b, c, d) > 0 iff d is
counter-clockwise from c by less than a half turn; with the first face's apex c0 as the
reference, a face is in the first half turn [0, pi) iff O(a, b, c0, c) > 0 or it is on
c0's side of the line ab in their common plane (for O = 0: the sign of the 2D orientation
of (a, b, c) over that of (a, b, c0), in a coordinate projection where the latter is not
0). Within a half turn the order is O's sign, and O = 0 there means the same half-plane.
Every sign is exact (:mod:`warpmesh.cells.predicates`), so coplanar faces, opposite
(a flat sheet through a junction) or coincident, are decided exactly.

Not decided (returned as ``undecided``): an edge with a degenerate face (its third vertex
exactly on the edge's line, or a repeated index: it has no angle), and an edge where no
order can satisfy the rule because some label lies more often on the counter-clockwise
sides of the faces than on the clockwise ones (that label's boundary is open or
inconsistently oriented there: the per-label closed/oriented checks see it; e.g. where a
surface without caps meets the box). Edges of two faces are not looked at: any two
faces are in a valid cyclic order, and their labels agreeing is the combinatorial
orientation check.

Cost: one sort of the edge keys, then exact signs for the faces about the non-manifold
edges and for the pairs of faces about each. The whole unsmoothed frog of pyvista
(``frog_tissues``, 25 labels, 1,583,774 triangles, 36,642 junction edges of 3 or 4 faces,
every tie settled by the shared-coordinate rule) takes 0.6 CPU s, against 2.3 for
:func:`~warpmesh.cells.intersections.find_self_intersections` in the same run; smoothed (16
passes), 0.5 s, 36,043 rows left to the integer stage.

Example
-------
Three slabs of labels 1, 2, 3 meeting along the z axis (a junction edge), their
interfaces in the right order, then one interface turned into the wrong gap:

>>> import numpy as np
>>> pts = np.array([[0, 0, 0], [0, 0, 1], [1, 0, 0], [-1, 1, 0], [-1, -1, 0], [1, -1, 0]], float)
>>> lower, upper = [1, 1, 2], [3, 2, 3]  # 1 | 3 at angle 0, 1 | 2 at 135 degrees, 2 | 3 at 225
>>> tris = [[1, 0, 2], [0, 1, 3], [0, 1, 4]]  # normals: clockwise (into 3), counter-clockwise, ccw
>>> find_junction_misorders(pts, tris, lower, upper).edges.tolist()
[]
>>> r = find_junction_misorders(pts, [[1, 0, 2], [0, 1, 5], [0, 1, 4]], lower, upper)  # 1 | 2 at 315
>>> r.edges.tolist(), r.pairs.tolist()
([[0, 1]], [[0, 1], [0, 2], [1, 2]])
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from warpmesh._conventions import INDEX_DTYPE
from warpmesh.cells.predicates import orient2d_signs, orient3d_signs, power_of_two_scaled

__all__ = ["JunctionMisorders", "LABEL_ABOVE", "LABEL_BELOW", "find_junction_misorders", "with_junction_misorders"]

#: the cell-data array of a shared surface holding each triangle's higher label
#: (:data:`warpmesh.surface.multilabel.LABEL_ABOVE`, which sits above this layer; the tests
#: check the two are equal)
LABEL_ABOVE = "label_above"
#: the cell-data array holding the lower label when the cell refs hold something else (one ref
#: per interface: :func:`warpmesh.surface.multilabel.interface_refs`)
LABEL_BELOW = "label_below"
_INT32_MAX = np.iinfo(np.int32).max


class JunctionMisorders(NamedTuple):
    """What :func:`find_junction_misorders` found: three int64 arrays, ``edges`` and
    ``pairs`` empty for an embedded surface.

    - ``edges`` (k, 2): the edges (a, b), a < b, around which the faces are out of order,
      sorted;
    - ``pairs`` (p, 2): pairs (i, j), i < j, sorted, of faces consecutive about such an edge
      with different regions on the sides facing the gap between them, and of faces in one
      half-plane (they overlap; about such an edge only these are listed, the order among
      them being undefined);
    - ``undecided`` (u, 2): edges of three faces or more not judged, for a degenerate face
      there or labels no order can satisfy.
    """

    edges: np.ndarray
    pairs: np.ndarray
    undecided: np.ndarray


def find_junction_misorders(points, triangles, lower=None, upper=None) -> JunctionMisorders:
    """The edges of three faces or more around which the faces' cyclic order contradicts their
    labels: sheets crossing along a junction edge, which no pair of triangles shows.

    The rule and its exactness are in the module docstring: about each such edge, between
    two consecutive faces, the label on the side of the one equals the label on the side of
    the other, and no two faces share a half-plane.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Vertex coordinates, finite.
    triangles : (m, 3) array_like of int
        Vertex indices in [0, n).
    lower, upper : (m,) array_like of int, optional
        The label on each face's back side (its normal points away from it) and on its
        front side: for a shared surface ``cell_refs["triangle"]`` and
        ``cell_data["label_above"]["triangle"]``. Both or neither; without them each face
        separates inside (back) from outside (front).

    Returns
    -------
    JunctionMisorders
        ``edges``, ``pairs`` and ``undecided`` (k, 2) int64 arrays; the first two empty
        for an embedded surface.

    Raises
    ------
    TypeError
        ``points`` not real numbers; ``triangles``, ``lower`` or ``upper`` not integers.
    ValueError
        Wrong shapes, NaN or infinite coordinates, indices out of range, only one of
        ``lower`` and ``upper``.

    Examples
    --------
    Two unit cubes of labels 1 and 2 in a background 0 touching along the edge x = y = 1
    (vertices 8, 9): four faces about it, each normal pointing into its cube (from the
    lower label to the higher); a duplicate face is reported with its original:

    >>> import numpy as np
    >>> g = np.array([[x, y, z] for x in range(3) for y in range(3) for z in range(2)], float)
    >>> v = lambda x, y, z: 6 * x + 2 * y + z
    >>> tris = [[v(1, 1, 1), v(1, 1, 0), v(1, 0, 0)], [v(1, 1, 0), v(1, 1, 1), v(0, 1, 1)],
    ...         [v(1, 1, 0), v(1, 2, 0), v(1, 1, 1)], [v(2, 1, 0), v(1, 1, 0), v(1, 1, 1)]]
    >>> r = find_junction_misorders(g, tris, [0, 0, 0, 0], [1, 1, 2, 2])
    >>> r.edges.tolist(), r.undecided.tolist()
    ([], [])
    >>> r = find_junction_misorders(g, tris + [tris[0]], [0] * 5, [1, 1, 2, 2, 1])
    >>> r.edges.tolist(), r.pairs.tolist()
    ([[8, 9]], [[0, 4]])
    """
    pts, tris, back, front = _validate(points, triangles, lower, upper)
    empty = np.zeros((0, 2), dtype=INDEX_DTYPE)
    rows = _junction_rows(tris, len(pts))
    if rows is None:
        return JunctionMisorders(empty, empty, empty)
    group, face, a, b, apex, forward, starts, sizes = rows
    pts = power_of_two_scaled(pts)
    n_groups = len(starts)

    # degenerate faces: the apex on the edge's line (every projection's orientation 0)
    proj = np.stack([orient2d_signs(pts, a, b, apex, k) for k in range(3)], axis=1)  # (r, 3)
    flat = np.zeros(n_groups, dtype=bool)
    flat[group[~proj.any(axis=1)]] = True

    # half turn of each face about its edge, relative to the group's first face
    ref = starts[group]
    sigma = np.zeros(len(group), dtype=np.int64)
    other = np.flatnonzero(ref != np.arange(len(group)))
    sigma[other] = orient3d_signs(pts, a[other], b[other], apex[ref[other]], apex[other])
    axis = np.argmax(proj[starts] != 0, axis=1)[group]  # a projection where the reference is not flat
    beta = proj[np.arange(len(group)), axis] * proj[ref, axis]
    half = np.where((sigma > 0) | ((sigma == 0) & (beta > 0)), 0, 1)

    # every pair of faces about each edge: which comes first, and which coincide
    first, second = _pairs_within(starts, sizes)
    tau = orient3d_signs(pts, a[first], b[first], apex[first], apex[second])
    same = half[first] == half[second]
    before = (half[first] < half[second]) | (same & (tau > 0))  # first's angle below second's
    after = (half[first] > half[second]) | (same & (tau < 0))
    coincide = same & (tau == 0)
    rank = (np.bincount(second, weights=before, minlength=len(group))
            + np.bincount(first, weights=after, minlength=len(group))).astype(np.int64)
    tied = np.zeros(n_groups, dtype=bool)
    tied[group[first[coincide]]] = True

    # the sides facing the gaps, in angular order; a gap is bad when they differ
    order = np.lexsort((rank, group))
    ccw = np.where(forward, front[face], back[face])[order]  # the side towards the next face
    cw = np.where(forward, back[face], front[face])[order]  # the side towards the previous one
    nxt = np.arange(len(order)) + 1
    ends = starts + sizes - 1
    nxt[ends] = starts  # cyclic
    bad_gap = ccw != cw[nxt]
    balanced = _balanced(group, ccw, cw, n_groups)
    wrong = np.zeros(n_groups, dtype=bool)
    wrong[group[bad_gap]] = True
    tied &= ~flat  # coincident faces overlap whatever the labels; a flat face has no angle
    judged = ~flat & balanced & ~tied
    misordered = tied | (judged & wrong)

    gap_pairs = bad_gap & judged[group]
    i, j = face[order][gap_pairs], face[order][nxt][gap_pairs]
    keep = coincide & tied[group[first]]
    i, j = np.r_[i, face[first][keep]], np.r_[j, face[second][keep]]
    pairs = _sorted_pairs(np.minimum(i, j), np.maximum(i, j), len(tris))
    edge = np.column_stack([a[starts], b[starts]]).astype(INDEX_DTYPE)
    return JunctionMisorders(edge[misordered], pairs, edge[(flat | ~balanced) & ~tied])


def with_junction_misorders(mesh, pairs: np.ndarray) -> np.ndarray:
    """``pairs`` (crossing triangles of ``mesh``) with the pairs of
    :func:`find_junction_misorders` added when ``mesh`` is a labelled shared surface in 3D
    (its ``"triangle"`` block has the lower labels, as cell refs or ``cell_data["label_below"]``,
    and the higher ones, ``cell_data["label_above"]``);
    ``pairs`` unchanged otherwise (labels read from a file as whole-number floats count as
    labels; fractional ones do not). The mesh's check (:func:`warpmesh.cells.intersections.check`)
    reports both: faces out of order about a junction edge mean sheets crossing there.

    Parameters
    ----------
    mesh : Mesh
    pairs : (k, 2) int
        Sorted pairs (i, j), i < j, of triangle indices.

    Returns
    -------
    (k', 2) int64
        The union, sorted, no pair twice.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> vol = np.zeros((6, 6, 6), np.uint8); vol[1:3, 1:5, 1:5] = 1; vol[3:5, 1:5, 1:5] = 2
    >>> m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    >>> with_junction_misorders(m, np.zeros((0, 2), np.int64)).tolist()
    []
    """
    tris = mesh.cells.get("triangle")
    refs = None if mesh.cell_refs is None else mesh.cell_refs.get("triangle")
    above = mesh.cell_data.get(LABEL_ABOVE, {}).get("triangle")
    refs = mesh.cell_data.get(LABEL_BELOW, {}).get("triangle", refs)
    pairs = np.asarray(pairs, dtype=INDEX_DTYPE).reshape(-1, 2)
    if tris is None or refs is None or above is None or mesh.points.shape[1] != 3:
        return pairs
    refs, above = _as_labels(refs), _as_labels(above)
    if refs is None or above is None:  # not labels (fractional values): nothing to order by
        return pairs
    found = find_junction_misorders(mesh.points, tris, refs, above).pairs
    if not len(found):
        return pairs
    both = np.concatenate([pairs, found])
    return _sorted_pairs(both[:, 0], both[:, 1], len(tris))


def _as_labels(values) -> np.ndarray | None:
    """Integer labels as they are, whole-number floats (a file's cell data) as int64, else None."""
    values = np.asarray(values)
    if values.dtype.kind in "iub":
        return values
    if values.dtype.kind == "f" and np.isfinite(values).all() and np.array_equal(values, np.round(values)):
        return values.astype(INDEX_DTYPE)
    return None


# -- pipeline ------------------------------------------------------------------------------


def _junction_rows(tris: np.ndarray, n: int):
    """The half-edges of the edges in three faces or more, grouped by edge (a < b): (group,
    face, a, b, apex, forward, starts, sizes), ``forward`` where the face runs a -> b; None
    when there are none. Half-edges of a repeated index (a, a) are left out.

    One sort of the m x 3 edge keys (no argsort: half the time) finds the keys of three or
    more; the half-edges with such a key are then found among those whose two ends lie on
    such an edge (a mark per vertex), by a binary search in the few keys. On pyvista's frog
    (1.58 M triangles, 36,642 junction edges) 0.2 CPU s against 0.7 for one argsort of all
    the half-edges and the gathers it needs."""
    nxt = tris[:, [1, 2, 0]]
    key = (np.minimum(tris, nxt) * n + np.maximum(tris, nxt)).ravel()  # half-edge h = 3 f + k
    key[(tris == nxt).ravel()] = -1
    s = np.sort(key)
    start = np.flatnonzero(np.r_[True, s[1:] != s[:-1]])
    size = np.diff(np.r_[start, len(s)])
    big = s[start[size >= 3]]
    big = big[big >= 0]
    if not len(big):
        return None
    mark = np.zeros(n, dtype=bool)
    mark[big // n] = True
    mark[big % n] = True
    ends = mark[tris]
    h = np.flatnonzero((ends & ends[:, [1, 2, 0]]).ravel())
    at = np.searchsorted(big, key[h])
    at[at == len(big)] = 0
    h = h[big[at] == key[h]]
    h = h[np.argsort(key[h], kind="stable")]
    k = key[h]
    first = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    sizes = np.diff(np.r_[first, len(k)])
    face, corner = h // 3, h % 3
    u, v, c = tris[face, corner], tris[face, (corner + 1) % 3], tris[face, (corner + 2) % 3]
    group = np.repeat(np.arange(len(sizes)), sizes)
    return group, face, np.minimum(u, v), np.maximum(u, v), c, u < v, first, sizes


def _pairs_within(starts: np.ndarray, sizes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row indices (i, j), i < j, of every pair of rows within each group, one pass per group
    size."""
    first, second = [], []
    for k in np.unique(sizes):
        i, j = np.triu_indices(int(k), 1)
        s = starts[sizes == k]
        first.append((s[:, None] + i[None]).ravel())
        second.append((s[:, None] + j[None]).ravel())
    return np.concatenate(first), np.concatenate(second)


def _balanced(group: np.ndarray, ccw: np.ndarray, cw: np.ndarray, n_groups: int) -> np.ndarray:
    """Per group, whether every label is as often on a counter-clockwise side as on a clockwise
    one (the same multisets): else no order of the faces can put one label in each gap."""
    one, two = np.lexsort((ccw, group)), np.lexsort((cw, group))
    ok = np.ones(n_groups, dtype=bool)
    ok[group[one[ccw[one] != cw[two]]]] = False
    return ok


def _sorted_pairs(i: np.ndarray, j: np.ndarray, m: int) -> np.ndarray:
    """Distinct pairs (i, j), i < j < m, sorted lexicographically."""
    key = np.unique(np.asarray(i, dtype=INDEX_DTYPE) * m + np.asarray(j, dtype=INDEX_DTYPE))
    return np.column_stack([key // m, key % m]).astype(INDEX_DTYPE)


def _validate(points, triangles, lower, upper):
    """(n, 3) float64 points, (m, 3) int64 triangles and the (m,) back and front labels (0 and
    1 without labels), or a TypeError / ValueError naming the argument."""
    pts = np.asarray(points)
    if pts.dtype.kind not in "iuf":
        raise TypeError(f"expected real numbers for 'points', got an array of dtype {pts.dtype}")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"expected an (n, 3) array for 'points', got shape {pts.shape}")
    pts = np.asarray(pts, dtype=np.float64)
    if not np.isfinite(pts).all():
        raise ValueError("expected finite coordinates in 'points', got NaN or infinity")
    tris = np.asarray(triangles)
    if tris.size == 0:
        tris = tris.astype(INDEX_DTYPE).reshape(0, 3)
    if tris.dtype.kind not in "iu":
        raise TypeError(f"expected integer indices for 'triangles', got an array of dtype {tris.dtype}")
    if tris.ndim != 2 or tris.shape[1] != 3:
        raise ValueError(f"expected an (m, 3) array for 'triangles', got shape {tris.shape}")
    if len(pts) > _INT32_MAX:
        raise ValueError(f"expected fewer than 2**31 points, got {len(pts)}")
    if tris.size and (tris.min() < 0 or tris.max() >= len(pts)):
        bad = tris.min() if tris.min() < 0 else tris.max()
        raise ValueError(f"expected indices in [0, {len(pts)}) for 'triangles' (the number of points), got {int(bad)}")
    tris = tris.astype(INDEX_DTYPE, copy=False)
    if (lower is None) != (upper is None):
        raise ValueError("expected both 'lower' and 'upper' labels or neither, got "
                         f"{'lower' if upper is None else 'upper'} alone")
    if lower is None:
        return pts, tris, np.zeros(len(tris), dtype=INDEX_DTYPE), np.ones(len(tris), dtype=INDEX_DTYPE)
    labels = []
    for name, x in (("lower", lower), ("upper", upper)):
        x = np.asarray(x)
        if x.size == 0:
            x = x.astype(INDEX_DTYPE)
        if x.dtype.kind not in "iub":
            raise TypeError(f"expected integer labels for {name!r}, got an array of dtype {x.dtype}")
        if x.shape != (len(tris),):
            raise ValueError(f"expected one label per triangle for {name!r}, shape ({len(tris)},), got shape {x.shape}")
        labels.append(x.astype(INDEX_DTYPE, copy=False))
    return pts, tris, labels[0], labels[1]
