"""Geometric transformations of meshes [FG §17.1.1, Remarks 17.1-17.2, §17.5 Fig. 17.14].

Every transformation is a homogeneous (d+1, d+1) float64 matrix ``T`` [FG eq. 17.1]: a
point ``p`` maps to ``T @ [p, 1]``. The builders return plain numpy arrays, so they
combine with ``@`` (``T2 @ T1`` applies ``T1`` first) or with :func:`compose` (which
takes them in the order they apply). :func:`transform` maps a mesh by such a matrix and,
when the map reverses orientation (a negative isometry, or any map with a negative
determinant), permutes the local vertices of the cells so that areas and volumes stay
positive and boundary normals stay outward.

=================  ===================================================================
builder            matrix
=================  ===================================================================
translation(v)     translation of vector v (2 or 3 components)
dilation(a, c)     isotropic (scalar a, ``dim=``) or anisotropic (a per axis) about c
rotation(t, ...)   angle t (radians, counter-clockwise / right-hand rule) about a point
                   (2D) or about an axis through a point (3D)
symmetry(coefs)    reflection about the line Ax + By + C = 0 or the plane
                   Ax + By + Cz + D = 0
matrix(m)          a general d x d linear or (d+1) x (d+1) homogeneous matrix, checked
``compose(*ms)``   the product, first argument applied first
=================  ===================================================================

Examples
--------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.modify.transforms import compose, rotation, symmetry, transform, translation
>>> m = wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
>>> t = compose(translation([1, 0]), rotation(np.pi / 2))   # shift, then turn
>>> transform(m, t).points.round(12).tolist()
[[0.0, 1.0], [0.0, 2.0], [-1.0, 1.0]]
>>> r = transform(m, symmetry([1, 0, 0]))                   # mirror in the y axis
>>> r.cells["triangle"].tolist(), r.stats()["area"], r.info["orientation_reversed"]
([[0, 2, 1]], 0.5, True)
"""

from __future__ import annotations

import numbers

import numpy as np

from warpmesh._conventions import REAL_DTYPE, REL_TOL
from warpmesh.cells.types import CELL_TYPES, require_mesh
from warpmesh.cells.reference import mirror_permutation

__all__ = ["translation", "dilation", "rotation", "symmetry", "matrix", "compose", "transform"]


# ----------------------------------------------------------------------------- validation
def _vector(value, name: str, sizes=(2, 3)) -> np.ndarray:
    """A finite float vector whose length is in ``sizes``."""
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected real numbers for {name!r}, got {arr.dtype} values {value!r}")
    arr = arr.astype(REAL_DTYPE)
    if arr.ndim != 1 or len(arr) not in sizes:
        want = " or ".join(str(s) for s in sizes)
        raise ValueError(f"expected {want} components for {name!r}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"expected finite values for {name!r}, got {arr.tolist()}")
    return arr


def _scalar(value, name: str) -> float:
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"expected a real number for {name!r}, got {type(value).__name__} {value!r}")
    if not np.isfinite(value):
        raise ValueError(f"expected a finite {name!r}, got {value}")
    return float(value)


def _center(center, d: int) -> np.ndarray:
    if center is None:
        return np.zeros(d)
    c = _vector(center, "center")
    if len(c) != d:
        raise ValueError(f"expected {d} components for 'center' (a {d}D transformation), got {len(c)}")
    return c


def _singular(linear: np.ndarray) -> bool:
    """Numerical rank below d: the smallest singular value is at most REL_TOL times the
    largest (such a map flattens the mesh to rounding level in some direction)."""
    sv = np.linalg.svd(linear, compute_uv=False)
    return not sv[-1] > REL_TOL * sv[0]


def _checked(m, name: str) -> np.ndarray:
    """A new (d+1, d+1) homogeneous matrix, d = 2 or 3: finite, last row 0..0 1 (to within
    REL_TOL, then set exactly), non-singular."""
    arr = np.asarray(m)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected a real matrix for {name!r}, got dtype {arr.dtype}")
    arr = arr.astype(REAL_DTYPE)
    if arr.shape not in ((3, 3), (4, 4)):
        raise ValueError(f"expected a 3x3 (2D) or 4x4 (3D) homogeneous matrix for {name!r}, "
                         f"got shape {arr.shape}; lift a d x d linear map with matrix(m)")
    if not np.isfinite(arr).all():
        raise ValueError(f"expected finite entries in {name!r}, got {arr.tolist()}")
    last = np.zeros(len(arr))
    last[-1] = 1.0
    if not np.allclose(arr[-1], last, rtol=0.0, atol=REL_TOL):  # rounding (np.linalg.inv) is fine
        raise ValueError(f"expected the last row of the homogeneous matrix {name!r} to be "
                         f"{last.tolist()}, got {arr[-1].tolist()}")
    arr[-1] = last
    if _singular(arr[:-1, :-1]):
        raise ValueError(f"expected a non-singular transformation for {name!r}, got a linear part "
                         f"with singular values {np.linalg.svd(arr[:-1, :-1], compute_uv=False)}: "
                         "it would flatten the mesh")
    return arr


def _affine(linear: np.ndarray, shift: np.ndarray) -> np.ndarray:
    d = len(linear)
    out = np.eye(d + 1)
    out[:d, :d], out[:d, d] = linear, shift
    return out


def _about(linear: np.ndarray, center: np.ndarray) -> np.ndarray:
    """T(c) L T(-c): the linear map ``linear`` with the fixed point ``center`` (Remark 17.1)."""
    return _affine(linear, center - linear @ center)


# ----------------------------------------------------------------------------- builders
def translation(vector) -> np.ndarray:
    """The translation of a vector [FG §17.1.1].

    Parameters
    ----------
    vector : (2,) or (3,) float
        (T_x, T_y[, T_z]); its length sets the dimension.

    Returns
    -------
    (d+1, d+1) float64

    Raises
    ------
    TypeError
        Non-numeric components.
    ValueError
        Not 2 or 3 components, or a non-finite one.

    Examples
    --------
    >>> translation([2, 3]).tolist()
    [[1.0, 0.0, 2.0], [0.0, 1.0, 3.0], [0.0, 0.0, 1.0]]
    """
    v = _vector(vector, "vector")
    return _affine(np.eye(len(v)), v)


def dilation(factors, center=None, *, dim: int | None = None) -> np.ndarray:
    """An isotropic or anisotropic dilation (scaling) about a centre [FG §17.1.1].

    The book's matrix: diagonal (alpha_x, alpha_y[, alpha_z]), last column
    ``C_i (1 - alpha_i)``, so the centre C is fixed. A negative factor mirrors that axis
    (:func:`transform` then restores the orientation of the cells).

    Parameters
    ----------
    factors : float or (d,) float
        One factor for every axis (isotropic; give ``dim`` or ``center``), or one per axis.
        Non-zero.
    center : (d,) float, optional
        The fixed point; the origin by default.
    dim : {2, 3}, optional
        Dimension of an isotropic dilation without ``center``.

    Returns
    -------
    (d+1, d+1) float64

    Raises
    ------
    TypeError
        Non-numeric factors or centre.
    ValueError
        A zero or non-finite factor, a scalar factor without ``dim`` or ``center``, or
        lengths that disagree.

    Examples
    --------
    >>> dilation([2, 3], center=[1, 1]).tolist()
    [[2.0, 0.0, -1.0], [0.0, 3.0, -2.0], [0.0, 0.0, 1.0]]
    >>> dilation(0.5, dim=3).diagonal().tolist()
    [0.5, 0.5, 0.5, 1.0]
    """
    if dim is not None and dim not in (2, 3):
        raise ValueError(f"expected dim 2 or 3, got {dim!r}")
    if np.ndim(factors) == 0:
        a = _scalar(factors, "factors")
        d = dim if dim is not None else (None if center is None else len(_vector(center, "center")))
        if d is None:
            raise ValueError("expected 'dim' (2 or 3) or a 'center' with an isotropic (scalar) "
                             f"factor, got factors={a} alone; e.g. dilation({a}, dim=3)")
        alpha = np.full(d, a)
    else:
        alpha = _vector(factors, "factors")
        if dim is not None and dim != len(alpha):
            raise ValueError(f"expected {dim} factors for dim={dim}, got {len(alpha)}")
    if (alpha == 0).any():
        raise ValueError(f"expected non-zero dilation factors, got {alpha.tolist()}: a zero "
                         "factor flattens the mesh")
    return _about(np.diag(alpha), _center(center, len(alpha)))


def _rz(c: float, s: float) -> np.ndarray:
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(c: float, s: float) -> np.ndarray:
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rx(c: float, s: float) -> np.ndarray:
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _axis_rotation(alpha: float, axis: np.ndarray) -> np.ndarray:
    """(3, 3): rotation of ``alpha`` about ``axis`` as the book's product
    T(phi, Z) T(theta, Y) T(alpha, X) T(-theta, Y) T(-phi, Z).

    C, S, C2, S2 come from the axis components directly (Remark 17.2), so no arctangent
    and no ambiguity modulo pi: with r = |(A_x, A_y)| and n = |A|, C = A_x / r,
    S = A_y / r, C2 = r / n, S2 = -A_z / n. Then T(phi, Z) T(theta, Y) maps the x axis
    onto A / n itself, and the product turns by +alpha about A (right-hand rule). (With
    the book's theta = arctan(A_z / r), S2 = +A_z / n and T(theta, Y), as printed, sends
    the x axis to (A_x, A_y, -A_z) / n: the sign of S2 is what makes the axis A.) An
    axis along z (r = 0) takes phi = 0: C = 1, S = 0, C2 = 0, S2 = -sign(A_z).
    """
    n, r = np.linalg.norm(axis), np.hypot(axis[0], axis[1])
    c, s = (axis[0] / r, axis[1] / r) if r > 0 else (1.0, 0.0)
    c2, s2 = r / n, -axis[2] / n
    t1, t2 = _rz(c, s), _ry(c2, s2)
    return t1 @ t2 @ _rx(np.cos(alpha), np.sin(alpha)) @ t2.T @ t1.T


def rotation(angle, *, center=None, axis=None) -> np.ndarray:
    """A rotation about a point (2D) or about an axis through a point (3D) [FG §17.1.1].

    In 2D (``axis`` None) the matrix turns counter-clockwise about ``center``; in 3D it
    turns by the right-hand rule about the line through ``center`` along ``axis``. The
    centre is handled as in Remark 17.1: T(P) R T(-P) (the book's 2D matrix with P in its
    last column is the first factor of that product; P - R P is the whole). The 3D
    linear part is the book's product of five rotations about the coordinate axes, with
    its sines and cosines taken from the axis components directly (Remark 17.2); see
    :func:`_axis_rotation` for the sign convention.

    Parameters
    ----------
    angle : float
        In radians (``np.radians(deg)`` converts).
    center : (2,) or (3,) float, optional
        A fixed point; the origin by default. Three components need ``axis``.
    axis : (3,) float, optional
        Direction of the 3D axis, any non-zero length; None for a 2D rotation.

    Returns
    -------
    (3, 3) or (4, 4) float64

    Raises
    ------
    TypeError
        A non-numeric angle, centre or axis.
    ValueError
        A non-finite value, a zero axis, an axis without 3 components, a 3D centre
        without an axis.

    Examples
    --------
    >>> import numpy as np
    >>> (rotation(np.pi / 2, center=[1, 0]) @ [0, 0, 1]).round(12).tolist()
    [1.0, -1.0, 1.0]
    >>> (rotation(np.pi / 2, axis=[0, 0, 2]) @ [1, 0, 0, 1]).round(12).tolist()
    [0.0, 1.0, 0.0, 1.0]
    """
    alpha = _scalar(angle, "angle")
    if axis is None:
        if center is not None and np.size(center) == 3:
            raise ValueError("expected an 'axis' with a 3D 'center' (a 3D rotation turns about a "
                             "line), got axis=None; e.g. rotation(angle, center=c, axis=(0, 0, 1))")
        return _about(_rz(np.cos(alpha), np.sin(alpha))[:2, :2], _center(center, 2))
    a = _vector(axis, "axis", sizes=(3,))
    if not np.linalg.norm(a) > 0:
        raise ValueError(f"expected a non-zero 'axis', got {a.tolist()}")
    return _about(_axis_rotation(alpha, a), _center(center, 3))


def symmetry(coefficients) -> np.ndarray:
    """The reflection about a line (2D) or a plane (3D) [FG §17.1.1].

    The book's matrix: ``I + F n n^T`` in the linear part and ``F n K`` in the last
    column, with n the normal (A, B[, C]), K the constant term and F = -2 / |n|^2. It is
    an involution (T @ T = I) with determinant -1; points of the line/plane are fixed.

    Parameters
    ----------
    coefficients : (3,) or (4,) float
        (A, B, C) for the line Ax + By + C = 0, (A, B, C, D) for the plane
        Ax + By + Cz + D = 0; the normal part must be non-zero.

    Returns
    -------
    (3, 3) or (4, 4) float64

    Raises
    ------
    TypeError
        Non-numeric coefficients.
    ValueError
        Not 3 or 4 coefficients, a non-finite one, or a zero normal.

    Examples
    --------
    >>> symmetry([1, 0, -1]).tolist()          # the line x = 1
    [[-1.0, 0.0, 2.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    """
    c = _vector(coefficients, "coefficients", sizes=(3, 4))
    normal, k = c[:-1], c[-1]
    nn = float(normal @ normal)
    if not nn > 0:
        raise ValueError(f"expected a non-zero normal (the first {len(normal)} coefficients), "
                         f"got {c.tolist()}")
    f = -2.0 / nn
    return _affine(np.eye(len(normal)) + f * np.outer(normal, normal), f * normal * k)


def matrix(m, *, dim: int | None = None) -> np.ndarray:
    """A general transformation given by its matrix [FG §17.1.1], checked.

    Parameters
    ----------
    m : (d, d) or (d+1, d+1) float
        A linear map (2x2 in 2D, 3x3 in 3D) or a homogeneous matrix (3x3 in 2D, 4x4 in
        3D, last row 0 .. 0 1). A 3x3 matrix is either, so it needs ``dim``.
    dim : {2, 3}, optional
        The dimension; required for a 3x3 ``m`` (2: homogeneous, 3: linear).

    Returns
    -------
    (d+1, d+1) float64

    Raises
    ------
    TypeError
        Non-numeric entries.
    ValueError
        Another shape, a non-finite entry, a wrong last row, a singular linear part, a
        3x3 matrix without ``dim``, a ``dim`` that does not fit the shape.

    Examples
    --------
    >>> matrix([[1, 1], [0, 1]]).tolist()              # a shear
    [[1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    >>> matrix(np.diag([1, 2, 3]), dim=3).shape
    (4, 4)
    """
    arr = np.asarray(m)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected a real matrix for 'm', got dtype {arr.dtype}")
    if dim is not None and dim not in (2, 3):
        raise ValueError(f"expected dim 2 or 3, got {dim!r}")
    sizes = {(2, 2): 2, (4, 4): 3}
    if arr.shape == (3, 3):
        if dim is None:
            raise ValueError("expected dim=2 (a 2D homogeneous matrix) or dim=3 (a 3D linear map) "
                             "with a 3x3 'm', got dim=None")
    elif arr.shape in sizes:
        if dim is not None and dim != sizes[arr.shape]:
            raise ValueError(f"expected dim={sizes[arr.shape]} for a {arr.shape} matrix, got dim={dim}")
        dim = sizes[arr.shape]
    else:
        raise ValueError(f"expected 'm' of shape (d, d) or (d+1, d+1) with d = 2 or 3, got {arr.shape}")
    if len(arr) == dim:
        if not np.isfinite(arr.astype(REAL_DTYPE)).all():
            raise ValueError(f"expected finite entries in 'm', got {arr.tolist()}")
        arr = _affine(arr.astype(REAL_DTYPE), np.zeros(dim))
    return _checked(arr, "m")


def compose(*matrices) -> np.ndarray:
    """The transformation that applies ``matrices[0]`` first, then ``matrices[1]``, ...

    ``compose(a, b, c)`` is ``c @ b @ a`` (the book's product T_1 T_2 ... applies the
    rightmost factor first; here the arguments read in the order they act).

    Parameters
    ----------
    *matrices : (d+1, d+1) float
        Homogeneous matrices of one dimension, e.g. from the builders of this module.

    Returns
    -------
    (d+1, d+1) float64

    Raises
    ------
    TypeError, ValueError
        No matrix, a matrix that is not a valid homogeneous one, mixed dimensions.

    Examples
    --------
    >>> import numpy as np
    >>> p = [1, 0, 1]
    >>> (compose(translation([1, 0]), dilation(2, dim=2)) @ p).tolist()   # (1 + 1) * 2
    [4.0, 0.0, 1.0]
    >>> (compose(dilation(2, dim=2), translation([1, 0])) @ p).tolist()   # 1 * 2 + 1
    [3.0, 0.0, 1.0]
    """
    if not matrices:
        raise ValueError("expected at least one matrix, got none")
    checked = [_checked(m, f"matrices[{i}]") for i, m in enumerate(matrices)]
    if len({len(m) for m in checked}) > 1:
        raise ValueError(f"expected matrices of one dimension, got shapes {[m.shape for m in checked]}")
    out = checked[0]
    for m in checked[1:]:  # a loop over the few factors
        out = m @ out
    return out


# ----------------------------------------------------------------------------- meshes
def transform(mesh, matrix, *, vectors=()):
    """The image of a mesh by a transformation [FG §17.1.1, §17.5].

    Points map as ``p' = L p + t`` (``matrix = [[L, t], [0, 1]]``); L must be
    non-singular (smallest singular value above 1e-12 times the largest). When ``det L > 0``
    (a positive isometry, a dilation, a shear) nothing else changes: the connectivity and
    the numbering are kept. When ``det L < 0`` (a symmetry, an odd number of negative
    dilation factors, any orientation-reversing map) every cell of topological dimension
    d (triangles, quads in 2D; tetrahedra, hexahedra, wedges, pyramids in 3D) and d-1
    (boundary lines in 2D, boundary triangles and quads in 3D) is renumbered with
    :func:`~warpmesh.cells.reference.mirror_permutation` (e.g. triangle (1, 2, 3) ->
    (1, 3, 2)), higher-order nodes following their vertices (triangle6, tetra10,
    hexahedron27, wedge15, ...). So areas and volumes stay positive, a boundary curve
    keeps the domain on its left and a boundary surface keeps its normals outwards (the
    normal of a surface patch maps like the vector L n). Lines in 3D and vertices keep
    their node order (they have no orientation to restore, or it is a curve's direction).

    Attributes (Fig. 17.14). Rows are never reordered: ``cell_refs``, ``cell_data``,
    ``point_refs`` and ``point_data`` stay attached to the same cells and points. In
    Fig. 17.14 the attributes of an element's sides must be permuted after a symmetry
    (1, 2, 3, 4 -> 1, 4, 3, 2) because they are stored per local side; in a Mesh a side's
    attribute is the ref of a cell of the boundary block (a line in 2D, a triangle or quad
    in 3D), which names its vertices globally, so it travels with its facet unchanged, and
    the facet is itself re-oriented. Arrays in ``cell_data`` whose columns are per local
    node or per local side are not permuted: their meaning is the user's.

    Vector fields: ``point_data`` arrays are copied as they are (the mesh cannot know
    which are vectors), except the names listed in ``vectors``, (n, d) arrays of
    displacement-like vectors, which map by the linear part: ``v' = L v`` (a rotation
    turns them, a symmetry mirrors them; normals of a non-orthogonal map would need
    ``L^-T`` instead).

    Parameters
    ----------
    mesh : Mesh
    matrix : (d+1, d+1) float
        A homogeneous matrix of the mesh's dimension d, from the builders of this module
        (:func:`matrix` lifts a d x d linear map). Checked: finite, last row 0 .. 0 1,
        non-singular.
    vectors : sequence of str, optional
        Names of (n, d) float ``point_data`` arrays to map by the linear part.

    Returns
    -------
    Mesh
        ``info`` gains ``transform`` (this call's matrix as nested lists, replacing an
        earlier one) and ``orientation_reversed`` (bool); other info is kept.

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh, non-numeric matrix, ``vectors`` not a sequence of names.
    ValueError
        A matrix of the other dimension (with the fix), an invalid or singular matrix,
        an unknown or misshaped vector field.

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]], "line": [[0, 1]]},
    ...             cell_refs={"line": [7]})
    >>> r = transform(m, dilation([-1, 2]))
    >>> r.cells["quad"].tolist(), r.cells["line"].tolist(), r.cell_refs["line"].tolist()
    ([[0, 3, 2, 1]], [[1, 0]], [7])
    """
    require_mesh(mesh)
    d = mesh.dim
    arr = np.asarray(matrix)
    if arr.ndim == 2 and arr.shape[0] == arr.shape[1] and len(arr) in (3, 4) and len(arr) != d + 1:
        other = len(arr) - 1
        fix = ("build it in 3D (e.g. rotation(angle, axis=(0, 0, 1)), translation([x, y, 0])), or "
               "lift a 3x3 linear map with matrix(m, dim=3)" if d == 3 else
               "build it in 2D (e.g. rotation(angle), translation([x, y]))")
        raise ValueError(f"expected a {d + 1}x{d + 1} matrix (a {d}D transformation) for a {d}D "
                         f"mesh, got a {len(arr)}x{len(arr)} one (a {other}D transformation); {fix}")
    t = _checked(arr, "matrix")
    linear, shift = t[:d, :d], t[:d, d]
    names = _vector_names(mesh, vectors)

    points = mesh.points @ linear.T + shift
    reversed_ = bool(np.linalg.det(linear) < 0)
    cells = dict(mesh.cells)
    if reversed_:
        for name, block in cells.items():  # a loop over blocks
            if CELL_TYPES[name][1] in (d, d - 1):
                cells[name] = block[:, mirror_permutation(name)]
    point_data = dict(mesh.point_data)
    for name in names:
        point_data[name] = np.asarray(point_data[name], dtype=REAL_DTYPE) @ linear.T
    info = {**mesh.info, "transform": t.tolist(), "orientation_reversed": reversed_}
    return mesh.replace(points=points, cells=cells, point_data=point_data, info=info)


def _vector_names(mesh, vectors) -> tuple[str, ...]:
    if isinstance(vectors, str) or not isinstance(vectors, (list, tuple)):
        raise TypeError(f"expected a list or tuple of point_data names for 'vectors', "
                        f"got {type(vectors).__name__} {vectors!r}")
    for name in vectors:
        if name not in mesh.point_data:
            raise ValueError(f"expected names of point_data arrays in 'vectors' "
                             f"(have {list(mesh.point_data)}), got {name!r}")
        a = np.asarray(mesh.point_data[name])
        if a.shape != (mesh.n_points, mesh.dim) or a.dtype.kind not in "iuf":
            raise ValueError(f"expected point_data[{name!r}] of shape ({mesh.n_points}, {mesh.dim}) "
                             f"and real values to map it as vectors, got shape {a.shape}, dtype {a.dtype}")
    return tuple(vectors)
