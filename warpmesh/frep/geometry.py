"""Differential geometry of implicit curves f(x, y) = 0 and surfaces f(x, y, z) = 0 [FG §16.1.2].

Every function takes a shape (:class:`~warpmesh.frep.shapes.Shape` or
:class:`~warpmesh.frep.expr.Expr`, f > 0 inside) and points ``(n, 2)`` or ``(n, 3)``: the
dimension is the points' second axis, and 2D points are evaluated at z = 0. Values and
gradients are exact (forward mode on the Warp tape, float32 inside, returned as float64);
second derivatives are central differences of the exact gradient (:func:`hessian`).

Conventions (f > 0 inside, :mod:`warpmesh._conventions`):

* :func:`normal` is grad f / |grad f|, the book's principal normal: it points INTO the
  domain (towards f > 0), i.e. it is the inward normal.
* :func:`tangent` (2D) is (f_y, -f_x) / |grad f|: walking along it keeps the domain on
  the LEFT, the orientation of every warpmesh polyline. The book's H = (-f_y, f_x)
  (eq. 16.11) is minus this vector.
* curvatures are positive where the domain is locally convex: the circle f = r - |p|
  has kappa = +1/r, the ball f = r - |p| has k1 = k2 = +1/r.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh import geometry as geo
>>> p = np.array([[2.0, 0.0], [0.0, 1.0]])
>>> geo.curvature(wm.ellipse((2.0, 1.0)), p).round(3).tolist()   # a / b² and b / a²
[2.0, 0.25]
>>> (geo.tangent(wm.circle(1.0), np.array([[1.0, 0.0]])) + 0.0).round(6).tolist()   # counter-clockwise
[[0.0, 1.0]]
"""

from __future__ import annotations

import itertools

import numpy as np

from warpmesh._conventions import REAL_DTYPE
from warpmesh.frep.planar_field import newton_project
from warpmesh._util.validate import check_box
from warpmesh.frep.lipschitz import lipschitz_bound
from warpmesh.frep.tape import tape_of, value_gradient_at
from warpmesh.frep.expr import as_expr, depends_on

__all__ = ["gradient", "normal", "tangent", "hessian", "inflection_function", "curvature",
           "radius_of_curvature", "principal_curvatures", "distance_estimate", "project",
           "critical_points", "singular_points", "inflection_points", "lipschitz_bound", "HESSIAN_STEP"]

_TINY = 1.0e-30
_EPS32 = float(np.finfo(np.float32).eps)
#: Central differences of the float32 gradient: the offsets are formed in float32 and
#: divided by their realised spacing, so rounding enters only through the gradient's
#: relative error eps32 ~ 1.2e-7, and the error of a curvature is about
#: eps32 R / h (rounding) + (h / R)² (truncation) for a level set of local length scale
#: R = |grad f| / |Hess f|. :func:`hessian` therefore takes two passes: a first estimate with
#: the absolute step ``HESSIAN_STEP``, then the step ``HESSIAN_REL_STEP`` * R (at most
#: ``HESSIAN_MAX_STEP``, and at least ``HESSIAN_ULPS`` float32 ulps of |p|, so p ± h stay
#: distinct). Measured worst relative curvature errors (tests/test_geometry.py cases: circles
#: and ellipses of radii 1e-3 to 50, near and far from the origin, a quadratic's Hessian
#: for |p| <= 3, spheres, tori): one pass with h = 1e-4: 1.1e-2, 3e-4: 4.2e-2, 1e-3: 0.29,
#: 1e-2: 0.9 (the fixed steps fail on the circle of radius 1e-3 or on large features); two
#: passes with h = 5e-3 R: 6.7e-5 (5e-5 on the 1e-3 circle, at most 1.7e-5 on unit-sized
#: features).
HESSIAN_STEP = 1.0e-3
HESSIAN_REL_STEP = 5.0e-3
HESSIAN_MAX_STEP = 1.0e-2
#: near a critical point |grad f| / |Hess f| is small without any small feature, and the
#: gradient's rounding is relative to its intermediate terms, not to |grad f|: the second
#: pass never goes below this step (pass ``step`` for features under ~2e-3)
HESSIAN_MIN_STEP = 1.0e-5
HESSIAN_ULPS = 32
#: Newton iterations of :func:`critical_points` (degenerate points converge linearly)
CRITICAL_NEWTON_STEPS = 40
#: an eigenvalue is zero (kind "degenerate") below this fraction of the Hessian scale
DEGENERATE_RTOL = 1.0e-3
#: an inflection's curvature half a cell away must exceed this over the box diagonal: a
#: radius of curvature of a thousand boxes is straight (the Hessian's noise is ~1e-5)
INFLECTION_KAPPA_TOL = 1.0e-3
#: default singular point tolerance: the curve passes within this fraction of a grid cell
SINGULAR_RTOL = 1.0e-3


# -- validation and evaluation ------------------------------------------------------------
def _tape_of(shape):
    try:
        return tape_of(shape)
    except TypeError:
        raise TypeError(f"expected a Shape or an Expr for 'shape', got {type(shape).__name__}") from None


def _reads_z(shape) -> bool:
    return depends_on(as_expr(shape), 2)


def _setup(shape, points, dims=(2, 3)):
    """(tape, points as an (n, d) float64 array) after checking both."""
    tape = _tape_of(shape)
    p = np.asarray(points)
    if not (np.issubdtype(p.dtype, np.number) or p.dtype == bool):
        raise TypeError(f"expected numeric 'points', got dtype {p.dtype}")
    p = p.astype(REAL_DTYPE)
    want = " or ".join(f"(n, {d})" for d in dims)
    if p.ndim != 2 or p.shape[1] not in dims:
        raise ValueError(f"expected an {want} array for 'points', got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("expected finite values in 'points', got NaN or infinity")
    if p.shape[1] == 2 and _reads_z(shape):
        raise ValueError("expected (n, 3) 'points' for a shape that depends on z, got (n, 2) points")
    return tape, p


def _floor_steps(p):
    """The smallest useful step at each point: HESSIAN_ULPS float32 ulps of |p|."""
    return np.maximum(HESSIAN_ULPS * _EPS32 * np.abs(p).max(axis=1, initial=0.0), 1e-10)


def _steps(p, step):
    """Per-point finite-difference steps (n,) of the first pass (or the given ``step``)."""
    if step is None:
        return np.maximum(HESSIAN_STEP, _floor_steps(p))
    h = np.broadcast_to(np.asarray(step, REAL_DTYPE), (len(p),))
    if not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ValueError(f"expected a positive finite 'step', got {step!r}")
    return h


def _fd_hessian(tape, p, device, h):
    """f, grad f and the symmetrised central-difference Hessian (n, d, d) at p (n, d), steps h (n,).

    The offset points are formed in float32, the precision the tape reads, and each
    difference quotient divides by the realised float32 spacing, so the rounding of
    p ± h is not mistaken for a change of the gradient."""
    n, d = p.shape
    p32 = p.astype(np.float32)
    offs = np.eye(d, dtype=np.float32)[None] * h.astype(np.float32)[:, None, None]  # (n, d, d)
    plus, minus = p32[:, None, :] + offs, p32[:, None, :] - offs  # float32 sums
    spacing = (plus.astype(REAL_DTYPE) - minus.astype(REAL_DTYPE))[:, np.arange(d), np.arange(d)]  # (n, d)
    allp = np.concatenate([p32, plus.reshape(-1, d), minus.reshape(-1, d)])
    f, g = value_gradient_at(tape, allp, device)
    gp, gm = g[n:n + n * d].reshape(n, d, d), g[n + n * d:].reshape(n, d, d)
    hess = (gp - gm) / spacing[:, :, None]  # row i: d grad / d x_i
    hess = 0.5 * (hess + hess.transpose(0, 2, 1))
    return f[:n], g[:n], hess


def _value_gradient_hessian(tape, p, device, step=None):
    """f, grad f and the Hessian at p: with ``step`` given, one pass; else two passes,
    the second with a step proportional to the local length scale |grad f| / |Hess f|."""
    h1 = _steps(p, step)
    f, g, hess = _fd_hessian(tape, p, device, h1)
    if step is not None or len(p) == 0:
        return f, g, hess
    gn, hn = np.linalg.norm(g, axis=1), np.linalg.norm(hess, axis=(1, 2))
    ok = (gn > _TINY) & (hn > _TINY)
    scale = gn / np.where(ok, hn, 1.0)
    h2 = np.where(ok, np.clip(HESSIAN_REL_STEP * scale, np.maximum(_floor_steps(p), HESSIAN_MIN_STEP),
                              HESSIAN_MAX_STEP), h1)
    redo = ok & (np.abs(h2 - h1) > 0.1 * h1)
    if redo.any():
        _, _, hess[redo] = _fd_hessian(tape, p[redo], device, h2[redo])
    return f, g, hess


# -- first order ---------------------------------------------------------------------------
def gradient(shape, points, *, device: str = "cpu") -> np.ndarray:
    """The exact gradient of f (forward mode on the tape).

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) or (n, 3) array_like
        2D points are evaluated at z = 0 (the shape must not read z).
    device : str
        Warp device of the tape evaluations.

    Returns
    -------
    (n, d) float64 array

    Raises
    ------
    TypeError
        ``shape`` is not a shape or an expression, or ``points`` is not numeric.
    ValueError
        ``points`` is not (n, 2) or (n, 3), is not finite, or is 2D for a shape reading z.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> gradient(wm.circle(1.0), np.array([[3.0, 4.0]])).round(6).tolist()
    [[-0.6, -0.8]]
    """
    tape, p = _setup(shape, points)
    return value_gradient_at(tape, p, device)[1]


def normal(shape, points, *, device: str = "cpu") -> np.ndarray:
    """The unit normal grad f / |grad f| (the book's principal normal).

    Since f > 0 inside, it points INTO the domain (the inward normal); the outward normal
    is its opposite. Zero where the gradient vanishes.

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) or (n, 3) array_like
    device : str

    Returns
    -------
    (n, d) float64 array of unit vectors (zero rows at critical points)

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> (normal(wm.sphere(1.0), np.array([[0.0, 0.0, 2.0]])) + 0.0).round(6).tolist()   # inward
    [[0.0, 0.0, -1.0]]
    """
    g = gradient(shape, points, device=device)
    gn = np.linalg.norm(g, axis=1)
    return g / np.where(gn > _TINY, gn, 1.0)[:, None]


def tangent(shape, points, *, device: str = "cpu") -> np.ndarray:
    """The unit tangent (f_y, -f_x) / |grad f| of a curve: the domain f > 0 is on its LEFT.

    This is the orientation of warpmesh polylines (counter-clockwise around a disc). The
    book's tangent H = (-f_y, f_x) of [FG eq. 16.11] is minus this vector.

    Parameters
    ----------
    shape : Shape or Expr
        A planar shape.
    points : (n, 2) array_like
    device : str

    Returns
    -------
    (n, 2) float64 array (zero rows at critical points)

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`; also for 3D points.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> (tangent(wm.circle(1.0), np.array([[0.0, 1.0]])) + 0.0).round(6).tolist()
    [[-1.0, 0.0]]
    """
    tape, p = _setup(shape, points, dims=(2,))
    g = value_gradient_at(tape, p, device)[1]
    gn = np.linalg.norm(g, axis=1)
    return np.column_stack([g[:, 1], -g[:, 0]]) / np.where(gn > _TINY, gn, 1.0)[:, None]


def distance_estimate(shape, points, *, device: str = "cpu") -> np.ndarray:
    """First-order distance to f = 0: |f| / |grad f| [FG eq. 16.6].

    Exact for a signed distance; for a general f an estimate, valid near a regular part
    of the zero set (a rigorous lower bound is |f| / :func:`lipschitz_bound`).

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) or (n, 3) array_like
    device : str

    Returns
    -------
    (n,) float64 array (inf where the gradient vanishes and f != 0)

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> x, y = wm.coords(2)
    >>> distance_estimate(1 - x * x - y * y, np.array([[2.0, 0.0]])).round(6).tolist()   # 3 / 4
    [0.75]
    """
    tape, p = _setup(shape, points)
    f, g = value_gradient_at(tape, p, device)
    gn = np.linalg.norm(g, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(gn > _TINY, np.abs(f) / np.where(gn > _TINY, gn, 1.0), np.where(f == 0, 0.0, np.inf))


def project(shape, points, max_step=None, steps: int = 8, *, device: str = "cpu") -> np.ndarray:
    """Points moved onto f = 0 by Newton steps p -= f grad f / |grad f|² [FG Remark 16.1].

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) or (n, 3) array_like
    max_step : float or (n,) array_like, optional
        Cap on each step's length, so a point never jumps to another branch.
    steps : int
        Newton iterations (quadratic convergence: a few suffice near the curve).
    device : str

    Returns
    -------
    (n, d) float64 array. Points where the gradient vanishes stay put; the accuracy is that
    of the float32 tape (~1e-7 relative).

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`; also a negative or non-finite ``max_step``, or ``steps`` < 1.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> q = project(wm.torus(1.0, 0.25), np.array([[1.5, 0.0, 0.1]]))
    >>> float(np.hypot(np.hypot(q[0, 0], q[0, 1]) - 1.0, q[0, 2]).round(6))
    0.25
    """
    tape, x = _setup(shape, points)
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ValueError(f"expected a positive integer 'steps', got {steps!r}")
    cap = None
    if max_step is not None:
        cap = np.broadcast_to(np.asarray(max_step, REAL_DTYPE), (len(x),))
        if not np.all(np.isfinite(cap)) or np.any(cap <= 0):
            raise ValueError(f"expected a positive finite 'max_step', got {max_step!r}")
    return newton_project(lambda q: value_gradient_at(tape, q, device), x.copy(), cap, steps,
                          lambda q: 1e-9 * np.maximum(1.0, np.abs(q).max(axis=1)))


# -- second order --------------------------------------------------------------------------
def hessian(shape, points, *, step=None, device: str = "cpu") -> np.ndarray:
    """The Hessian of f: central differences of the exact gradient, symmetrised.

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) or (n, 3) array_like
    step : float or (n,) array_like, optional
        Absolute difference step (one pass). Default: two passes, the second with the
        step 5e-3 |grad f| / |Hess f| (within [1e-5, 1e-2]) estimated by the first with
        1e-3 (see ``HESSIAN_REL_STEP``: the float32 tape makes smaller steps amplify
        rounding, larger ones truncate). Pass a step for features under ~2e-3.
    device : str

    Returns
    -------
    (n, d, d) float64 array, symmetric

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`; also a non-positive ``step``.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> x, y = wm.coords(2)
    >>> hessian(x * x + 3 * x * y - y * y, np.array([[0.5, -0.2]])).round(4).tolist()
    [[[2.0, 3.0], [3.0, -2.0]]]
    """
    tape, p = _setup(shape, points)
    return _value_gradient_hessian(tape, p, device, step)[2]


def _h_of(g, hess):
    fx, fy = g[:, 0], g[:, 1]
    return fy**2 * hess[:, 0, 0] - 2 * fx * fy * hess[:, 0, 1] + fx**2 * hess[:, 1, 1]


def inflection_function(shape, points, *, step=None, device: str = "cpu") -> np.ndarray:
    """The book's H = f_y² f_xx - 2 f_x f_y f_xy + f_x² f_yy of a planar curve.

    It vanishes at the inflection points of the curve (and at its singular points); its
    sign is the opposite of the curvature's (:func:`curvature` is -H / |grad f|³).

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) array_like
    step : float or (n,) array_like, optional
        Hessian difference step (:func:`hessian`).
    device : str

    Returns
    -------
    (n,) float64 array

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`; also for 3D points.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> inflection_function(wm.circle(2.0), np.array([[2.0, 0.0]])).round(4).tolist()   # -1 / r
    [-0.5]
    """
    tape, p = _setup(shape, points, dims=(2,))
    _, g, hess = _value_gradient_hessian(tape, p, device, step)
    return _h_of(g, hess)


def curvature(shape, points, *, step=None, device: str = "cpu") -> np.ndarray:
    """Signed curvature kappa = -H / |grad f|³ of the curve through each point (level set of f).

    Positive where the domain f > 0 is locally convex (the circle f = r - |p| has +1/r),
    negative where it is concave; 0 at inflections; NaN where the gradient vanishes.

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 2) array_like
    step : float or (n,) array_like, optional
        Hessian difference step (:func:`hessian`).
    device : str

    Returns
    -------
    (n,) float64 array

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`; also for 3D points.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> ring = wm.circle(2.0) - wm.circle(1.0)
    >>> curvature(ring, np.array([[2.0, 0.0], [0.0, -1.0]])).round(4).tolist()
    [0.5, -1.0]
    """
    tape, p = _setup(shape, points, dims=(2,))
    _, g, hess = _value_gradient_hessian(tape, p, device, step)
    gn = np.linalg.norm(g, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(gn > _TINY, -_h_of(g, hess) / np.where(gn > _TINY, gn, 1.0) ** 3, np.nan)


def radius_of_curvature(shape, points, *, step=None, device: str = "cpu") -> np.ndarray:
    """1 / |kappa| of the curve through each point (inf where kappa = 0, NaN at critical points).

    Parameters, Raises: as :func:`curvature`.

    Returns
    -------
    (n,) float64 array

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> radius_of_curvature(wm.circle(0.5, center=(1.0, 1.0)), np.array([[1.5, 1.0]])).round(4).tolist()
    [0.5]
    """
    k = np.abs(curvature(shape, points, step=step, device=device))
    with np.errstate(divide="ignore"):
        return np.where(k > 0, 1.0 / np.where(k > 0, k, 1.0), np.where(np.isnan(k), np.nan, np.inf))


def _tangent_frame(n):
    """Two unit vectors (n, 3) each completing unit normals n (n, 3) to orthonormal frames."""
    a = np.zeros_like(n)
    a[np.arange(len(n)), np.abs(n).argmin(axis=1)] = 1.0
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return e1, np.cross(n, e1)


def principal_curvatures(shape, points, *, step=None, device: str = "cpu"):
    """Principal curvatures and directions of the level surface through each point [FG eq. 16.9].

    The shape operator is -P Hess(f) P / |grad f| restricted to the tangent plane (P the
    projector orthogonal to grad f): its eigenvalues are the principal curvatures, signed
    as :func:`curvature` (the ball f = r - |p| gives k1 = k2 = +1/r).

    Parameters
    ----------
    shape : Shape or Expr
    points : (n, 3) array_like
    step : float or (n,) array_like, optional
        Hessian difference step (:func:`hessian`).
    device : str

    Returns
    -------
    k1, k2 : (n,) float64 arrays
        k1 >= k2 (NaN where the gradient vanishes).
    d1, d2 : (n, 3) float64 arrays
        Unit principal directions, tangent to the surface and orthogonal to each other.

    Raises
    ------
    TypeError, ValueError
        As :func:`gradient`; also for 2D points.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> k1, k2, d1, d2 = principal_curvatures(wm.torus(1.0, 0.25), np.array([[1.25, 0.0, 0.0]]))
    >>> k1.round(3).tolist(), k2.round(3).tolist(), np.abs(d1).round(3).tolist()   # 1/r, 1/(R + r)
    ([4.0], [0.8], [[0.0, 0.0, 1.0]])
    """
    tape, p = _setup(shape, points, dims=(3,))
    _, g, hess = _value_gradient_hessian(tape, p, device, step)
    gn = np.linalg.norm(g, axis=1)
    ok = gn > _TINY
    nrm = np.where(ok[:, None], g / np.where(ok, gn, 1.0)[:, None], np.array([0.0, 0.0, 1.0]))
    e1, e2 = _tangent_frame(nrm)
    frame = np.stack([e1, e2], axis=2)  # (n, 3, 2)
    shape_op = -np.einsum("nia,nij,njb->nab", frame, hess, frame) / np.where(ok, gn, 1.0)[:, None, None]
    lam, vec = np.linalg.eigh(shape_op)  # ascending
    k1, k2 = np.where(ok, lam[:, 1], np.nan), np.where(ok, lam[:, 0], np.nan)
    d1 = np.einsum("nia,na->ni", frame, vec[:, :, 1])
    d2 = np.einsum("nia,na->ni", frame, vec[:, :, 0])
    return k1, k2, d1, d2


# -- critical and singular points ------------------------------------------------------------
def _grid_nodes(box, resolution):
    d = box.shape[1]
    axes = [np.linspace(box[0, k], box[1, k], resolution + 1) for k in range(d)]
    mesh = np.meshgrid(*axes, indexing="ij")
    return axes, np.stack([m.ravel() for m in mesh], axis=1)


def _seeds(nodes, g, box, resolution):
    """Cell centres where every gradient component changes sign over the cell's corners,
    and grid nodes that are strict local minima of |grad f| among their axis neighbours."""
    d = box.shape[1]
    shp = (resolution + 1,) * d
    gg = g.reshape(*shp, d)
    corners = [gg[tuple(slice(o, o + resolution) for o in off)] for off in itertools.product((0, 1), repeat=d)]
    stack = np.stack(corners)  # (2^d, r, .., r, d)
    mn, mx = stack.min(axis=0), stack.max(axis=0)
    change = np.all((mn <= 0) & (mx >= 0) & (mx > mn), axis=-1)
    idx = np.argwhere(change)
    cell = (box[1] - box[0]) / resolution
    centres = box[0] + (idx + 0.5) * cell
    gn = np.linalg.norm(gg, axis=-1)
    pad = np.pad(gn, 1, constant_values=np.inf)
    core = tuple(slice(1, -1) for _ in range(d))
    neigh = np.full(shp, np.inf)
    for k in range(d):
        for s in (-1, 1):
            sl = list(core)
            sl[k] = slice(1 + s, pad.shape[k] - 1 + s)
            neigh = np.minimum(neigh, pad[tuple(sl)])
    minima = nodes[(gn < (1.0 - 1e-3) * neigh).ravel()]
    return np.concatenate([centres, minima])


def _dedupe(points, keys, radius):
    """One representative (smallest key) per cluster of points closer than ``radius``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    if len(points) < 2:
        return np.arange(len(points))
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    adj = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
    _, label = connected_components(adj, directed=False)
    order = np.lexsort((keys, label))
    first = np.ones(len(order), bool)
    first[1:] = label[order[1:]] != label[order[:-1]]
    return np.sort(order[first])


def _check_resolution(resolution):
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise ValueError(f"expected an integer 'resolution' >= 2, got {resolution!r}")
    return int(resolution)


def _critical(shape, bounds, resolution, device):
    """Critical points with their Hessian eigenvalues, and the grid's scales."""
    tape = _tape_of(shape)
    box = check_box(bounds)
    d = box.shape[1]
    if d == 2 and _reads_z(shape):
        raise ValueError("expected 3D 'bounds' ((x0, y0, z0), (x1, y1, z1)) for a shape that depends on z, "
                         "got 2D bounds")
    res = _check_resolution(resolution)
    cell = (box[1] - box[0]) / res
    _, nodes = _grid_nodes(box, res)
    fgrid, ggrid = value_gradient_at(tape, nodes, device)
    size = float(np.linalg.norm(box[1] - box[0]))
    gscale = max(float(np.linalg.norm(ggrid, axis=1).max()), _TINY)
    fscale = max(float(np.abs(fgrid).max()), _TINY)
    hscale = gscale / size  # the natural Hessian scale of f over the box
    x = _seeds(nodes, ggrid, box, res)
    step_cap = float(np.linalg.norm(cell))
    # absolute difference step: relative to the box, never above a tenth of a cell
    fd = np.minimum(_steps(x, None), 0.1 * float(cell.min()))
    last = np.full(len(x), np.inf)
    active = np.arange(len(x))
    for _ in range(CRITICAL_NEWTON_STEPS):
        if len(active) == 0:
            break
        _, g, hess = _value_gradient_hessian(tape, x[active], device, fd[active])
        step = np.einsum("nij,nj->ni", np.linalg.pinv(hess, rcond=1e-10), g)
        ln = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, step_cap / np.maximum(ln, _TINY))[:, None]
        x[active] -= step
        last[active] = np.minimum(ln, step_cap)
        inside = np.all((x[active] >= box[0] - cell) & (x[active] <= box[1] + cell), axis=1)
        active = active[(ln > 1e-9 * size) & inside]
    f, g, hess = _value_gradient_hessian(tape, x, device, fd) if len(x) else (
        np.zeros(0), np.zeros((0, d)), np.zeros((0, d, d)))
    gn = np.linalg.norm(g, axis=1)
    margin = 1e-9 * size
    keep = ((last <= 1e-4 * float(cell.min())) & (gn <= 1e-4 * gscale)
            & np.all((x >= box[0] - margin) & (x <= box[1] + margin), axis=1))
    x, f, g, hess, gn = x[keep], f[keep], g[keep], hess[keep], gn[keep]
    k = _dedupe(x, gn, 1e-2 * float(cell.min()))
    x, hess = x[k], hess[k]
    f = np.asarray(as_expr(shape).eval_numpy(*[x[:, i] for i in range(d)]), REAL_DTYPE) * np.ones(len(x))
    lam = np.linalg.eigvalsh(hess) if len(x) else np.zeros((0, d))
    zero = np.abs(lam) <= np.maximum(DEGENERATE_RTOL * np.abs(lam).max(axis=1, initial=0.0),
                                     DEGENERATE_RTOL * 0.1 * hscale)[:, None]
    kind = np.where(zero.any(axis=1), "degenerate",
                    np.where(np.all(lam > 0, axis=1), "minimum",
                             np.where(np.all(lam < 0, axis=1), "maximum", "saddle")))
    order = np.lexsort(x.T[::-1])
    out = {"points": x[order], "values": f[order], "kind": [str(s) for s in kind[order]],
           "hessian": hess[order]}
    return out, lam[order], float(cell.min()), fscale, size


def critical_points(shape, bounds, resolution: int = 64, *, device: str = "cpu") -> dict:
    """Isolated critical points of f (grad f = 0) in a box, classified by their Hessian.

    Seeds are the cells of a regular grid over which every gradient component changes
    sign, and the grid nodes that are strict local minima of |grad f|; each seed runs
    Newton's method on grad f = 0 with the central-difference Hessian (pseudo-inverse,
    steps capped at a cell diagonal). Converged points (|grad f| <= 1e-4 of the largest
    gradient on the grid) inside the box are merged when closer than 1e-2 cell.

    The kind follows the Hessian eigenvalues [FG §16.1.2: det < 0 is a saddle in 2D]:
    all positive "minimum", all negative "maximum", mixed signs "saddle", any eigenvalue
    below ``DEGENERATE_RTOL`` of the Hessian scale "degenerate".

    Parameters
    ----------
    shape : Shape or Expr
    bounds : ((x0, y0), (x1, y1)) or ((x0, y0, z0), (x1, y1, z1))
        The box; its dimension is that of the search.
    resolution : int
        Grid cells per axis; critical points closer than about a cell may be missed.
    device : str

    Returns
    -------
    dict
        ``points`` (k, d), ``values`` (k,) f at them, ``kind`` list of k strings,
        ``hessian`` (k, d, d); sorted by coordinates. The values are evaluated in float64
        (:meth:`~warpmesh.frep.expr.Expr.eval_numpy`).

    Raises
    ------
    TypeError
        ``shape`` is not a shape or an expression.
    ValueError
        Bad ``bounds`` or ``resolution``, or 2D bounds for a shape reading z.

    Notes
    -----
    Critical points where f is not twice differentiable (a cone's apex, the kinks of
    min / max) are found only where Newton lands on them exactly; non-isolated critical
    sets (a circle of minima) come out as several "degenerate" points along them.

    Example
    -------
    >>> import warpmesh as wm
    >>> x, y = wm.coords(2)
    >>> cp = critical_points((x * x - 1) ** 2 + y * y, ((-2, -1), (2, 1)))
    >>> cp["points"].round(5).tolist(), cp["kind"]
    ([[-1.0, 0.0], [0.0, 0.0], [1.0, 0.0]], ['minimum', 'saddle', 'minimum'])
    """
    return _critical(shape, bounds, resolution, device)[0]


def singular_points(shape, bounds, resolution: int = 64, tolerance=None, *, device: str = "cpu") -> dict:
    """The singular points of the curve or surface f = 0 [FG Def. 16.1]: critical points on it.

    Parameters
    ----------
    shape : Shape or Expr
    bounds : ((x0, y0), (x1, y1)) or ((x0, y0, z0), (x1, y1, z1))
    resolution : int
        Grid cells per axis of the critical point search (:func:`critical_points`).
    tolerance : float, optional
        Keep critical points with |f| <= tolerance (f in float64). Default, per point:
        0.5 |lambda|_max delta², the value a quadratic with the point's largest Hessian
        eigenvalue reaches at delta = max(1e-3 h, 8 eps32 max(|p|, box diagonal)) (h the
        grid step): the curve passes within a thousandth of a grid cell, or within the
        float32 precision of the Newton iterates. Thin necks (two branches a fraction of a
        cell apart) are thereby not singular; the lemniscate's node is.
    device : str

    Returns
    -------
    dict
        As :func:`critical_points`, restricted to the singular points.

    Raises
    ------
    TypeError, ValueError
        As :func:`critical_points`; also a negative or non-finite ``tolerance``.

    Example
    -------
    >>> import warpmesh as wm
    >>> sp = singular_points(wm.cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6)))   # the lemniscate
    >>> (sp["points"].round(6) + 0.0).tolist(), sp["kind"]
    ([[0.0, 0.0]], ['saddle'])
    """
    if tolerance is not None:
        try:
            tol = float(tolerance)
        except (TypeError, ValueError):
            tol = np.nan
        if not np.isfinite(tol) or tol < 0:
            raise ValueError(f"expected a non-negative finite 'tolerance', got {tolerance!r}")
    cp, lam, h, fscale, size = _critical(shape, bounds, resolution, device)
    if tolerance is None:
        pts = cp["points"]
        delta = np.maximum(SINGULAR_RTOL * h, 8 * _EPS32 * np.maximum(np.abs(pts).max(axis=1, initial=0.0), size))
        tol = 0.5 * np.abs(lam).max(axis=1, initial=0.0) * delta**2 + 1e-12 * fscale
    on = np.abs(cp["values"]) <= tol
    return {"points": cp["points"][on], "values": cp["values"][on],
            "kind": [k for k, o in zip(cp["kind"], on) if o], "hessian": cp["hessian"][on]}


def inflection_points(shape, bounds, resolution: int = 64, *, device: str = "cpu") -> dict:
    """Inflection points of a planar curve f = 0: where the book's H (:func:`inflection_function`)
    vanishes and changes sign along the curve, at a regular point (grad f != 0).

    Seeds are the cells of a regular grid over which both f and H change sign; Newton's
    method solves f = H = 0 from each (the Jacobian rows grad f and a central difference
    of H), and converged points inside the box are merged when closer than 1e-2 cell.

    Parameters
    ----------
    shape : Shape or Expr
        A planar shape.
    bounds : ((x0, y0), (x1, y1))
    resolution : int
        Grid cells per axis; two inflections within about a cell may be missed.
    device : str

    Returns
    -------
    dict
        ``points`` (k, 2) sorted by coordinates, ``curvature_slope`` (k,) the derivative
        of the signed curvature along :func:`tangent` over half a cell either way (> 0:
        concave to convex). Kept only where the curvature half a cell away changes sign
        and exceeds ``INFLECTION_KAPPA_TOL`` / (box diagonal), but stays below 1 / (half a
        cell): straight segments (kappa = 0), CSG corners and points within two cells of
        a singular point (where H vanishes to high order; the lemniscate's branches
        inflect at its node, reported by :func:`singular_points`) are left out.

    Raises
    ------
    TypeError
        ``shape`` is not a shape or an expression.
    ValueError
        Bad ``bounds`` or ``resolution``, 3D bounds, or a shape reading z.

    Example
    -------
    >>> import warpmesh as wm
    >>> x, y = wm.coords(2)
    >>> ip = inflection_points(y - wm.sin(x), ((-4, -2), (4, 2)))   # the curve y = sin x
    >>> (ip["points"].round(5) + 0.0).tolist()
    [[-3.14159, 0.0], [0.0, 0.0], [3.14159, 0.0]]
    """
    tape = _tape_of(shape)
    box = check_box(bounds)
    if box.shape[1] != 2:
        raise ValueError(f"expected 2D 'bounds' ((x0, y0), (x1, y1)) for a curve, got shape {box.shape}")
    if _reads_z(shape):
        raise ValueError("expected a planar 'shape' (a field of x and y), got one that depends on z")
    res = _check_resolution(resolution)
    cell = (box[1] - box[0]) / res
    h = float(cell.min())
    _, nodes = _grid_nodes(box, res)
    fd = np.minimum(_steps(nodes, None), 0.1 * h)
    fgrid, ggrid, hgrid = _fd_hessian(tape, nodes, device, fd)
    hf = _h_of(ggrid, hgrid)
    corners = [(slice(0, res), slice(0, res)), (slice(1, None), slice(0, res)),
               (slice(0, res), slice(1, None)), (slice(1, None), slice(1, None))]
    fs = np.stack([fgrid.reshape(res + 1, res + 1)[c] for c in corners])
    hs = np.stack([hf.reshape(res + 1, res + 1)[c] for c in corners])
    seed = (fs.min(0) <= 0) & (fs.max(0) >= 0) & (hs.min(0) <= 0) & (hs.max(0) >= 0) & (hs.max(0) > hs.min(0))
    x = box[0] + (np.argwhere(seed) + 0.5) * cell
    step_fd = 0.05 * h

    def residual(p, full=False):
        f, g, hess = _value_gradient_hessian(tape, p, device)
        return (f, g, _h_of(g, hess), hess) if full else (f, g, _h_of(g, hess))

    active = np.arange(len(x))
    for _ in range(CRITICAL_NEWTON_STEPS):
        if len(active) == 0:
            break
        p = x[active]
        f, g, hv = residual(p)
        offs = np.concatenate([p + [step_fd, 0], p - [step_fd, 0], p + [0, step_fd], p - [0, step_fd]])
        hn = residual(offs)[2].reshape(4, len(p))
        jac = np.stack([g, np.column_stack([hn[0] - hn[1], hn[2] - hn[3]]) / (2 * step_fd)], axis=1)
        step = np.einsum("nij,nj->ni", np.linalg.pinv(jac, rcond=1e-10), np.column_stack([f, hv]))
        ln = np.linalg.norm(step, axis=1)
        step *= np.minimum(1.0, h / np.maximum(ln, _TINY))[:, None]
        x[active] -= step
        inside = np.all((x[active] >= box[0] - cell) & (x[active] <= box[1] + cell), axis=1)
        active = active[(ln > 1e-9 * float(np.linalg.norm(box[1] - box[0]))) & inside]
    if len(x) == 0:
        return {"points": np.zeros((0, 2)), "curvature_slope": np.zeros(0)}
    f, g, hv, hess = residual(x, full=True)
    gn = np.linalg.norm(g, axis=1)
    hscale = max(float(np.abs(hf).max()), _TINY)
    # |grad f| / |Hess f| estimates the distance to the nearest critical point: within two
    # cells of a singular point H vanishes to high order and its zeros are noise
    far = gn > 2 * h * np.linalg.norm(hess, ord=2, axis=(1, 2))
    keep = (far & (np.abs(f) <= 1e-5 * h * gn) & (np.abs(hv) <= 1e-4 * hscale)
            & np.all((x >= box[0]) & (x <= box[1]), axis=1))
    x = x[keep]
    x = x[_dedupe(x, np.zeros(len(x)), 1e-2 * h)]
    x = x[np.lexsort(x.T[::-1])]
    # the curvature half a cell either way along the curve must change sign, above its noise
    t = tangent(shape, x, device=device)
    ds = 0.5 * h
    ends = project(shape, np.concatenate([x + ds * t, x - ds * t]), max_step=ds, device=device)
    k = curvature(shape, ends, device=device) if len(x) else np.zeros(0)
    kp, km = k[:len(x)], k[len(x):]
    size = float(np.linalg.norm(box[1] - box[0]))
    keep = ((kp * km < 0) & (np.minimum(np.abs(kp), np.abs(km)) > INFLECTION_KAPPA_TOL / size)
            & (np.maximum(np.abs(kp), np.abs(km)) < 1.0 / ds))  # no corner within the cell
    return {"points": x[keep], "curvature_slope": ((kp - km) / (2 * ds))[keep]}
