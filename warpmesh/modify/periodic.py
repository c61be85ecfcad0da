"""Periodic meshes [FG §17.5, Remark 17.16]: pairs of nodes related by a transformation,
and a mesh built from a pattern and its transformed copies.

A transformation is a homogeneous (d+1) x (d+1) matrix acting on column vectors
``[x, 1]`` (the matrices of :mod:`warpmesh.modify.transforms`): last row ``[0, ..., 0, 1]``.
The book's requirement for a periodic mesh is that the two zones put in correspondence
are meshed the same way; :func:`periodic_pairs` finds the node pairs, by the hashing of
:func:`warpmesh.modify.merge.match_points`, and :func:`periodic` merges the copies with
:func:`warpmesh.modify.merge.merge`, half with half (each merge checks the Euler formula).

Examples
--------
>>> import numpy as np
>>> from warpmesh.mesh import Mesh
>>> from warpmesh.modify.periodic import periodic
>>> square = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
>>> shift = np.array([[1.0, 0, 1], [0, 1, 0], [0, 0, 1]])
>>> strip = periodic(square, shift, 3)
>>> strip.n_points, len(strip.cells["quad"]), strip.info["periodic_pairs"].tolist()
(8, 3, [[0, 6], [3, 7]])
"""

from __future__ import annotations

import numbers
import warnings
from typing import Literal

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.budget import check_budget
from warpmesh.cells.types import CELL_TYPES, require_mesh
from warpmesh.modify.merge import _check_tolerance, _match, _merge, default_tolerance
from warpmesh.cells.reference import mirror_permutation

__all__ = ["periodic_pairs", "periodic"]


def _check_matrix(matrix, d: int) -> np.ndarray:
    arr = np.asarray(matrix)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected a float array for 'matrix', got dtype {arr.dtype}")
    if arr.shape != (d + 1, d + 1):
        raise ValueError(
            f"expected a homogeneous 'matrix' of shape ({d + 1}, {d + 1}) for a {d}D mesh, "
            f"got shape {arr.shape}"
        )
    arr = arr.astype(REAL_DTYPE)
    if not np.isfinite(arr).all():
        raise ValueError("expected a finite 'matrix', got NaN or inf")
    last = np.zeros(d + 1)
    last[-1] = 1.0
    if not np.allclose(arr[-1], last, rtol=0, atol=1e-12):
        raise ValueError(
            f"expected an affine 'matrix' (last row {last.tolist()}), got last row {arr[-1].tolist()}"
        )
    det = np.linalg.det(arr[:d, :d])
    if not abs(det) > 1e-12 * max(np.abs(arr[:d, :d]).max(), 1e-300) ** d:
        raise ValueError(f"expected an invertible 'matrix', got determinant {det:g}")
    if np.allclose(arr, np.eye(d + 1), rtol=0, atol=1e-12):
        raise ValueError("expected a 'matrix' that moves the mesh, got the identity (every copy would be the "
                         "pattern itself)")
    return arr


def _apply(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    d = points.shape[1]
    return points @ matrix[:d, :d].T + matrix[:d, d]


def _transformed(mesh, matrix: np.ndarray):
    """``mesh`` with points mapped by ``matrix``; cells of dimension d and d - 1 mirrored
    when the matrix reverses orientation (so volumes stay positive, normals outward)."""
    pts = _apply(matrix, mesh.points)
    if np.linalg.det(matrix[:-1, :-1]) > 0:
        return mesh.replace(points=pts, info={})
    d = mesh.dim
    cells = {
        t: (c[:, mirror_permutation(t)] if CELL_TYPES[t][1] in (d, d - 1) and t != "vertex" else c)
        for t, c in mesh.cells.items()
    }
    return mesh.replace(points=pts, cells=cells, info={})


def _check_copies(copies) -> int:
    if isinstance(copies, bool) or not isinstance(copies, numbers.Integral):
        raise TypeError(f"expected an int for 'copies', got {type(copies).__name__}")
    if copies < 1:
        raise ValueError(f"expected 'copies' >= 1, got {copies}")
    return int(copies)


def _merge_range(parts, lo: int, hi: int, tol: float, options: dict):
    """(the copies ``parts[lo:hi]`` merged, the new index of each point of the last one).

    Halves merged with each other, recursively: every level of the recursion handles
    every point once, so the work grows as copies × log2(copies), where merging each
    copy into everything before it grew as copies². The numbering is the same: a
    merge keeps its first mesh's points and appends the second's free points in their
    order, so the points come out pattern first, then each copy's new points in turn;
    the cells, per type, copy after copy.
    """
    if hi - lo == 1:
        part = parts[lo]
        return part.replace(info={}), np.arange(part.n_points, dtype=INDEX_DTYPE)
    mid = (lo + hi + 1) // 2
    left, _ = _merge_range(parts, lo, mid, tol, options)
    right, last = _merge_range(parts, mid, hi, tol, options)
    merged, bmap = _merge(left, right, tol, stacklevel=5, overlaps=False, **options)  # (the result is checked)
    return merged, bmap[last]


def periodic_pairs(mesh, matrix, tolerance: float | None = None) -> np.ndarray:
    """Pairs of nodes (i, j) with T(x_i) ≈ x_j: the node pairs of periodic boundary
    conditions [FG §17.5].

    Found by :func:`warpmesh.modify.merge.match_points` between the transformed points and the
    points (one-to-one, nearest both ways); a node mapped onto itself (on a rotation axis,
    a symmetry plane) is not a pair.

    Parameters
    ----------
    mesh : Mesh
    matrix : (d+1, d+1) float
        Homogeneous affine transformation T, invertible.
    tolerance : float, optional
        Absolute; default ``RELATIVE_TOLERANCE × Δ`` (2.4e-7) of the mesh and its image (:func:`default_tolerance`).

    Returns
    -------
    (k, 2) int64
        Sorted by i.

    Raises
    ------
    TypeError
        ``mesh`` not a Mesh, non-numeric matrix.
    ValueError
        Matrix of the wrong shape, not affine, singular or not finite; tolerance <= 0.

    Examples
    --------
    >>> import numpy as np
    >>> from warpmesh.mesh import Mesh
    >>> m = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
    >>> periodic_pairs(m, np.array([[1.0, 0, 1], [0, 1, 0], [0, 0, 1]])).tolist()
    [[0, 1], [3, 2]]
    """
    require_mesh(mesh)
    t = _check_matrix(matrix, mesh.dim)
    image = _apply(t, mesh.points)
    tol = default_tolerance(mesh.points, image) if tolerance is None else _check_tolerance(tolerance)
    pairs = _match(image, mesh.points, tol)[0]
    return pairs[pairs[:, 0] != pairs[:, 1]]


#: bytes of Python objects a copy holds besides its arrays (a Mesh, its dicts and array headers:
#: a 4-point quad's 10**7 copies took about 1 ms each to make and would not fit, yet passed a
#: budget of its arrays alone)
COPY_OVERHEAD = 4096

def periodic(mesh, matrix, copies: int, tolerance: float | None = None, *, refs: bool = False,
             duplicates: Literal["merge", "keep", "drop"] = "merge",
             check: Literal["interface", "full", False] = "interface"):
    """The pattern ``mesh`` and its images by T, T², ..., T^(copies-1), merged
    [FG §17.5, "Periodic mesh"].

    The copies are merged in halves, recursively (:func:`warpmesh.modify.merge.merge`,
    with its Euler check at every merge): the first half of the copies with the second,
    so each copy meets every copy before it, and a last copy that comes back onto the
    first (a rotation by 2π/copies) merges with it as well: the result closes up. The
    work grows as copies × log(copies). A matrix with a negative
    determinant reverses each odd copy: its cells of dimension d and d - 1 are permuted
    with :func:`~warpmesh.cells.reference.mirror_permutation`, so volumes stay positive
    and boundary faces outward. The two sides of the pattern must be meshed alike (for
    hexahedra or wedges split into tetrahedra, split the faces compatibly, Remark 17.16),
    else the merge fails its Euler check.

    Parameters
    ----------
    mesh : Mesh
        The pattern.
    matrix : (d+1, d+1) float
        Homogeneous affine transformation T, invertible.
    copies : int
        Number of copies, the pattern included (>= 1).
    tolerance : float, optional
        Absolute; default ``1e-8 × Δ``, Δ the largest side of the box of all copies.
    refs, duplicates, check
        As :func:`warpmesh.modify.merge.merge`, for every merge of a copy. Unless ``check``
        is False, the result's triangles or tetrahedra are also checked for crossings
        (:meth:`Mesh.check <warpmesh.mesh.Mesh.check>`): copies that overlap give a
        ``UserWarning``.

    Returns
    -------
    Mesh
        The pattern's points keep their numbers; every copy carries the pattern's refs and
        data unchanged (vector data are not rotated). ``info["periodic_pairs"]`` (k, 2) int64:
        pairs (i, j) with T^copies(x_i) ≈ x_j between the first pattern and the last
        copy: the periodic boundary conditions of the whole; empty when the copies close
        up. Also ``copies`` and the last merge's counts (``euler``, ...).

    Raises
    ------
    TypeError
        ``mesh`` not a Mesh, non-numeric matrix, non-integer ``copies``, unknown option.
    ValueError
        Bad matrix (shape, not affine, singular, not finite, the identity), ``copies`` < 1.
    warpmesh.modify.merge.MergeError
        A merge fails its Euler check (sides meshed differently or tolerance too large).

    Examples
    --------
    >>> import numpy as np
    >>> from warpmesh.mesh import Mesh
    >>> tri = Mesh([[0, 0], [1, 0], [0.5, 3**0.5 / 2]], {"triangle": [[0, 1, 2]]})
    >>> c, s = np.cos(np.pi / 3), np.sin(np.pi / 3)
    >>> hexagon = periodic(tri, np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]), 6)
    >>> hexagon.n_points, len(hexagon.cells["triangle"]), len(hexagon.info["periodic_pairs"])
    (7, 6, 0)
    """
    require_mesh(mesh)
    t = _check_matrix(matrix, mesh.dim)
    n = _check_copies(copies)
    # each copy is a Mesh of its own until merged: its arrays and its Python objects
    pattern_bytes = mesh.points.nbytes + sum(c.nbytes for c in mesh.cells.values()) + COPY_OVERHEAD
    check_budget(3.0 * n * pattern_bytes, f"periodic(copies={n}) of a {mesh.n_cells}-cell pattern",
                 "lower 'copies'")
    options = {"refs": refs, "duplicates": duplicates, "check": check}
    powers = [np.eye(mesh.dim + 1)]
    for _ in range(n):
        powers.append(t @ powers[-1])
    parts = [mesh] + [_transformed(mesh, p) for p in powers[1:n]]
    if tolerance is None:
        tol = default_tolerance(*(p.points for p in parts))
    else:
        tol = _check_tolerance(tolerance)
    result, last = _merge_range(parts, 0, n, tol, options)
    # T^copies maps the pattern's free side onto the last copy's free side
    image = _apply(powers[n], mesh.points)
    pairs = _match(image, result.points[last], tol)[0]
    pairs = np.stack([pairs[:, 0], last[pairs[:, 1]]], axis=1).astype(INDEX_DTYPE)
    pairs = pairs[pairs[:, 0] != pairs[:, 1]]
    out = result.replace(info={**result.info, "copies": n, "periodic_pairs": pairs})
    if check is not False and n > 1:
        _warn_if_copies_overlap(out, mesh, t, tol)
    return out


def _warn_if_copies_overlap(mesh, pattern, matrix: np.ndarray, tol: float) -> None:
    """A UserWarning when cells of the result cross: merged, they are no mesh a solver can
    take, and the Euler check does not see it. Triangles and tetrahedra only. Two causes
    are told apart for triangles: interiors that overlap (the copies moved by less than the
    pattern's extent, or a rotation that turns them onto each other), and copies that only
    touch along a seam where their vertices differ (the pattern's two sides sampled
    differently: the copies are then not connected), found by shrinking the crossing
    triangles a little about their centroids (:func:`_only_touching`)."""
    if not any(t in mesh.cells for t in ("triangle", "tetra")):
        return
    crossing = mesh.check()
    if not len(crossing):
        return
    if "tetra" not in mesh.cells and _only_touching(mesh, crossing, tol):
        matched = len(periodic_pairs(pattern, matrix, tol))
        warnings.warn(f"periodic: the copies touch along their seams without sharing vertices there "
                      f"({len(crossing)} pairs of cells touch, e.g. cells {crossing[0].tolist()}): the pattern's two "
                      f"sides are sampled differently ({matched} node pairs match under the transform), so the "
                      "copies are not joined along the seam; mesh the two sides with the same boundary nodes, as periodic "
                      "conditions need", UserWarning, stacklevel=3)
        return
    warnings.warn(f"periodic: the copies overlap ({len(crossing)} pairs of cells cross, e.g. cells "
                  f"{crossing[0].tolist()}): the transform moves the pattern by less than its extent",
                  UserWarning, stacklevel=3)


def _only_touching(mesh, crossing: np.ndarray, tol: float) -> bool:
    """Whether the crossing triangle pairs only touch: each shrunk about its centroid so its
    corners move by a quarter of the merge tolerance ``tol`` (at most a millionth of its
    size), on vertices of its own, none of them crosses any more. An overlap deeper than
    that is one (closer points the merge would have welded)."""
    from warpmesh.cells.intersections import find_self_intersections

    cells = np.unique(crossing.ravel())
    p = np.asarray(mesh.points, dtype=REAL_DTYPE)
    if p.shape[1] == 2:
        p = np.column_stack([p, np.zeros(len(p))])
    corners = p[mesh.cells["triangle"][cells]]  # (k, 3, 3)
    centroid = corners.mean(axis=1, keepdims=True)
    reach = np.linalg.norm(corners - centroid, axis=2).max(axis=1)[:, None, None]
    shrink = np.minimum(0.25 * tol / np.maximum(reach, 1e-300), 1.0e-6)
    shrunk = centroid + (corners - centroid) * (1.0 - shrink)
    own = np.arange(3 * len(cells)).reshape(-1, 3)
    return len(find_self_intersections(shrunk.reshape(-1, 3), own)) == 0
