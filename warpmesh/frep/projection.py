"""Projection onto the exact surface: the targets that surface optimisation moves vertices to.

Every moved or inserted vertex of :mod:`warpmesh.optimize.remesh` goes back onto the surface
through one of these *targets*:

===================  =========================================================  ==========================
target               surface                                                    projection
===================  =========================================================  ==========================
``ImplicitTarget``   f = 0 of a shape (Warp tape, exact gradient); with         safeguarded Newton steps
                     ``bounds``, the boundary of {f > 0} clipped to the box     [FG Remark 16.1]
``VolumeField``      ``level`` iso-surface of the trilinear interpolant of a    the same Newton steps on
                     sampled volume                                             the trilinear function
``MeshTarget``       a reference triangle mesh (no function known)              closest point (VTK locator)
===================  =========================================================  ==========================

Each target gives ``project(points, max_step)``, ``distance(points)`` (after projection,
so an upper bound on the true distance to the surface), ``normals(points)`` (outward)
and ``curvature(points)`` (largest absolute principal curvature, for size fields).

Examples
--------
>>> import numpy as np, warpmesh as wm
>>> t = ImplicitTarget(wm.sphere(1.0))
>>> p = t.project(np.array([[0.0, 0.0, 1.3], [0.5, 0.0, 0.0]]))
>>> np.linalg.norm(p, axis=1).round(6).tolist()
[1.0, 1.0]
>>> float(t.curvature(p).round(3)[0])
1.0
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import REAL_DTYPE
from warpmesh.frep.planar_field import newton_project
from warpmesh.frep.tape import points_array, eval_gradients, tape_of
from warpmesh.kernels.block_grid import trilinear_value_gradient_kernel
from warpmesh.cells.topology import face_normals

__all__ = ["ImplicitTarget", "FunctionTarget", "VolumeField", "MeshTarget", "as_target", "check_shape_dim",
           "project_nodes", "surface_error"]

NEWTON_STEPS = 6
#: finite-difference step of the Hessian, relative to the size of the target's box
HESSIAN_STEP = 1.0e-4
_TINY = 1.0e-30
_TINY_G2 = 1.0e-300  # smallest |grad f|^2 a float64 Newton step divides by
#: Newton steps in float64 after the (float32-evaluated) projection of a shape target
POLISH_STEPS = 2


#: foot-point refinement steps of :meth:`FunctionTarget.distance`
FOOT_STEPS = 3


class FunctionTarget:
    """Shared Newton projection, normals and curvature for targets with a function f (f > 0 inside)."""

    bounds: np.ndarray | None = None
    fd_step: float = 1.0e-4
    #: longest Newton step (None: unbounded)
    newton_cap: float | None = None

    def value_gradient(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _clipped(self, points):
        f, g = self.value_gradient(points)
        if self.bounds is None:
            return f, g
        # compare in length units: f / |grad f| against the distance to the box faces,
        # else a steep f (the degree-six polynomial) loses to the box far from the cap
        gn = np.maximum(np.linalg.norm(g, axis=1), _TINY)
        f, g = f / gn, g / gn[:, None]
        lo, hi = self.bounds
        d = np.concatenate([points - lo, hi - points], axis=1)  # distance to the 6 faces, > 0 inside
        j = d.argmin(axis=1)
        dmin = d[np.arange(len(d)), j]
        use = dmin < f
        f = np.where(use, dmin, f)
        gb = np.zeros_like(g)
        gb[np.arange(len(d)), j % 3] = np.where(j < 3, 1.0, -1.0)
        g = np.where(use[:, None], gb, g)
        return f, g

    def project(self, points, max_step=None, steps: int = NEWTON_STEPS) -> np.ndarray:
        """Points moved onto the surface by Newton steps x -= f grad f / |grad f|^2.

        ``max_step`` (scalar or per point) caps each step, so a point never jumps to
        another sheet; points where the gradient vanishes stay put.
        """
        x = np.array(points, dtype=REAL_DTYPE, copy=True)
        if len(x) == 0:
            return x
        cap = None if max_step is None else np.broadcast_to(np.asarray(max_step, REAL_DTYPE), (len(x),))
        if self.newton_cap is not None:  # sampled fields: never more than a sample spacing per step
            cap = np.full(len(x), self.newton_cap) if cap is None else np.minimum(cap, self.newton_cap)
        return newton_project(self._clipped, x, cap, steps, 1e-9 * self.fd_step / HESSIAN_STEP)

    def distance(self, points, refine: int = FOOT_STEPS) -> np.ndarray:
        """Distance from each point to the surface: an upper bound, the nearest of the
        surface points found by Newton projection and ``refine`` foot-point steps (the point
        dropped onto the tangent plane at the last surface point, projected again).

        Plain Newton follows the gradient, which near a sharp edge or a strongly curved
        region is not the way to the nearest point; the foot-point steps close that gap.
        """
        p = np.asarray(points, dtype=REAL_DTYPE)
        y = self.project(p)
        best = np.linalg.norm(y - p, axis=1)
        for _ in range(refine):
            n = self.normals(y)
            z = p - np.einsum("ij,ij->i", p - y, n)[:, None] * n
            y = self.project(z)
            best = np.minimum(best, np.linalg.norm(y - p, axis=1))
        return best

    def estimate(self, points) -> np.ndarray:
        """First-order distance |f| / |grad f| [FG eq. 16.6]: one evaluation, for checks."""
        f, g = self._clipped(np.asarray(points, dtype=REAL_DTYPE))
        return np.abs(f) / np.maximum(np.linalg.norm(g, axis=1), _TINY)

    def normals(self, points) -> np.ndarray:
        """Outward unit normals -grad f / |grad f| (the box face normal where clipped)."""
        _, g = self._clipped(np.asarray(points, dtype=REAL_DTYPE))
        return -g / np.maximum(np.linalg.norm(g, axis=1), _TINY)[:, None]

    def curvature(self, points) -> np.ndarray:
        """Largest absolute principal curvature: eigenvalues of P H P / |grad f| [FG eq. 16.9].

        The Hessian H comes from central differences of the exact gradient; P projects
        onto the tangent plane. Planes and box caps give 0.
        """
        p = np.asarray(points, dtype=REAL_DTYPE)
        if len(p) == 0:
            return np.zeros(0)
        h = self.fd_step
        offs = np.concatenate([np.eye(3), -np.eye(3)]) * h
        grads = self.value_gradient((p[:, None, :] + offs[None]).reshape(-1, 3))[1].reshape(len(p), 6, 3)
        hess = (grads[:, :3] - grads[:, 3:]) / (2 * h)  # row i: d grad / d x_i
        hess = 0.5 * (hess + hess.transpose(0, 2, 1))
        _, g = self.value_gradient(p)
        gn = np.maximum(np.linalg.norm(g, axis=1), _TINY)
        n = g / gn[:, None]
        proj = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
        shape_op = proj @ hess @ proj / gn[:, None, None]
        kappa = np.abs(np.linalg.eigvalsh(shape_op)).max(axis=1)
        if self.bounds is not None:
            f, _ = self.value_gradient(p)
            lo, hi = self.bounds
            on_cap = np.concatenate([p - lo, hi - p], axis=1).min(axis=1) < np.abs(f) / gn
            kappa[on_cap] = 0.0
        return kappa


def _check_bounds(bounds):
    if bounds is None:
        return None
    b = np.asarray(bounds, dtype=REAL_DTYPE)
    if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"expected 'bounds' ((x0, y0, z0), (x1, y1, z1)) with x0 < x1 etc., got {bounds!r}")
    return b


class ImplicitTarget(FunctionTarget):
    """The surface f = 0 of a shape (f > 0 inside), optionally clipped to a box.

    Parameters
    ----------
    shape : Shape or Expr
    bounds : ((x0, y0, z0), (x1, y1, z1)), optional
        The mesh was capped on this box: the surface is the boundary of {f > 0} ∩ box.
    device : str
        Warp device for the tape evaluations.
    """

    def __init__(self, shape, bounds=None, device: str = "cpu"):
        self.tape = tape_of(shape)  # raises TypeError for anything that is not a shape
        self.shape, self.device = shape, device
        self.bounds = _check_bounds(bounds)
        if self.bounds is not None:
            self.fd_step = HESSIAN_STEP * float(np.linalg.norm(self.bounds[1] - self.bounds[0]))

    def value_gradient(self, points):
        if len(points) == 0:
            return np.zeros(0), np.zeros((0, 3))
        fg = eval_gradients(self.tape, points_array(points, self.device), device=self.device).numpy()
        fg = fg.astype(REAL_DTYPE)
        return fg[:, 0], fg[:, 1:]


class VolumeField(FunctionTarget):
    """The iso-surface of a sampled volume, trilinear between the samples.

    ``f(x) = s * (trilinear(values)(x) - level)`` with ``s = +1`` when values above the
    level are inside (``inside="above"``), -1 otherwise, so that f > 0 inside as
    everywhere in warpmesh.

    Parameters
    ----------
    values : (nx, ny, nz) float array
    spacing, origin : float or 3 floats
        ``values[i, j, k]`` sits at ``origin + (i, j, k) * spacing``.
    level : float
    inside : {'above', 'below'}
    bounds : optional, as for :class:`ImplicitTarget`.

    Examples
    --------
    >>> g = np.linspace(-1, 1, 21)
    >>> vol = 1 - np.sqrt(sum(c**2 for c in np.meshgrid(g, g, g, indexing="ij")))
    >>> t = VolumeField(vol, spacing=0.1, origin=-1.0, level=0.5)
    >>> r = float(np.linalg.norm(t.project(np.array([[0.0, 0.0, 0.8]]))))
    >>> abs(r - 0.5) < 0.01      # trilinear interpolation of a 0.1 grid
    True
    """

    def __init__(self, values, spacing=1.0, origin=0.0, level: float = 0.0, inside: str = "above", bounds=None):
        v = np.asarray(values)
        if v.ndim != 3 or min(v.shape) < 2:
            raise ValueError(f"expected a 3D array of at least 2 samples per axis for 'values', got shape {v.shape}")
        if not (np.issubdtype(v.dtype, np.number) or v.dtype == bool):
            raise TypeError(f"expected numeric 'values', got dtype {v.dtype}")
        v = v.astype(REAL_DTYPE)
        if not np.all(np.isfinite(v)):
            raise ValueError("expected finite 'values', got NaN or infinity")
        if inside not in ("above", "below"):
            raise ValueError(f"expected 'inside' in ('above', 'below'), got {inside!r}")
        sp = np.broadcast_to(np.asarray(spacing, REAL_DTYPE), (3,)).copy()
        if not np.all(np.isfinite(sp)) or np.any(sp <= 0):
            raise ValueError(f"expected positive 'spacing', got {spacing!r}")
        self.values = np.ascontiguousarray((1.0 if inside == "above" else -1.0) * (v - float(level)))
        self._wp_values = None  # the warp copy, made on first use
        self.spacing = sp
        self.origin = np.broadcast_to(np.asarray(origin, REAL_DTYPE), (3,)).copy()
        self.bounds = _check_bounds(bounds)
        self.fd_step = 0.5 * float(sp.min())
        self.newton_cap = float(sp.min())

    def value_gradient(self, points):
        import warp as wp


        p = np.ascontiguousarray(points, dtype=REAL_DTYPE).reshape(-1, 3)
        if len(p) == 0:
            return np.zeros(0), np.zeros((0, 3))
        if self._wp_values is None:  # on the host: the optimiser's data live there
            self._wp_values = wp.array(self.values, dtype=wp.float64, device="cpu")
        f = wp.empty(len(p), dtype=wp.float64, device="cpu")
        g = wp.empty(len(p), dtype=wp.vec3d, device="cpu")
        wp.launch(trilinear_value_gradient_kernel, dim=len(p),
                  inputs=[self._wp_values, wp.vec3d(*self.origin), wp.vec3d(*self.spacing),
                          wp.array(p, dtype=wp.vec3d, device="cpu"), f, g], device="cpu")
        return f.numpy(), g.numpy()


class MeshTarget:
    """A reference triangle mesh, for meshes whose function is unknown.

    Projection is the closest point on the reference (a VTK static cell locator);
    curvature is estimated per reference vertex from the turn of the normals along its
    edges and read at the nearest reference vertex.
    """

    bounds = None

    def __init__(self, points, triangles):
        import pyvista as pv
        from scipy.spatial import cKDTree


        self.points = np.asarray(points, REAL_DTYPE)
        self.triangles = np.asarray(triangles)
        faces = np.hstack([np.full((len(self.triangles), 1), 3), self.triangles]).ravel()
        self._poly = pv.PolyData(self.points, faces)
        self._face_normals = face_normals(self.points, self.triangles)
        vn = np.zeros_like(self.points)
        np.add.at(vn, self.triangles.ravel(), np.repeat(self._face_normals, 3, axis=0))
        vn /= np.maximum(np.linalg.norm(vn, axis=1), _TINY)[:, None]
        e = np.concatenate([self.triangles[:, [0, 1]], self.triangles[:, [1, 2]], self.triangles[:, [2, 0]]])
        turn = np.linalg.norm(vn[e[:, 0]] - vn[e[:, 1]], axis=1) / np.maximum(
            np.linalg.norm(self.points[e[:, 0]] - self.points[e[:, 1]], axis=1), _TINY)
        self._vertex_kappa = np.zeros(len(self.points))
        np.maximum.at(self._vertex_kappa, e.ravel(), np.repeat(turn, 2))
        self._tree = cKDTree(self.points)

    def _closest(self, points):
        p = np.asarray(points, REAL_DTYPE)
        if len(p) == 0:
            return np.zeros(0, np.int64), p.copy()
        cells, closest = self._poly.find_closest_cell(p, return_closest_point=True)
        return np.atleast_1d(cells), np.atleast_2d(closest)

    def project(self, points, max_step=None, steps: int = 1) -> np.ndarray:
        return self._closest(points)[1].astype(REAL_DTYPE)

    def distance(self, points) -> np.ndarray:
        p = np.asarray(points, REAL_DTYPE)
        return np.linalg.norm(self.project(p) - p, axis=1)

    estimate = distance

    def normals(self, points) -> np.ndarray:
        return self._face_normals[self._closest(points)[0]]

    def curvature(self, points) -> np.ndarray:
        return self._vertex_kappa[self._tree.query(np.asarray(points, REAL_DTYPE))[1]]


def as_target(shape=None, *, bounds=None, reference=None, device: str = "cpu"):
    """The target for ``shape``: a shape, a :class:`VolumeField`, an existing target, or
    None (then the reference mesh ``(points, triangles)`` itself)."""
    if shape is None:
        if reference is None:
            raise ValueError("expected a 'shape' (or a reference mesh) to project onto")
        return MeshTarget(*reference)
    if isinstance(shape, (FunctionTarget, MeshTarget)):
        if bounds is not None:
            shape.bounds = _check_bounds(bounds)
        return shape
    try:
        return ImplicitTarget(shape, bounds=bounds, device=device)
    except TypeError as exc:
        raise TypeError(
            f"expected a Shape, Expr or VolumeField for 'shape', got {type(shape).__name__}"
        ) from exc


def surface_sample_points(points, triangles) -> np.ndarray:
    """Vertices, edge midpoints and centroids of triangles: where the error is measured."""
    p = np.asarray(points, REAL_DTYPE)
    t = np.asarray(triangles)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    return np.concatenate([p[np.unique(t)], (a + b) / 2, (b + c) / 2, (c + a) / 2, (a + b + c) / 3])


def surface_error(mesh, shape=None, *, bounds=None, reference=None) -> dict:
    """Distance from a triangle mesh to the exact surface [FG §16.2.2], by Newton projection.

    Sampled at the vertices, edge midpoints and centroids of the triangles.

    Parameters
    ----------
    mesh : Mesh
    shape : Shape, Expr, VolumeField or target; or None with ``reference=(points, triangles)``
    bounds : box the mesh was capped on, if any

    Returns
    -------
    dict
        ``max``, ``mean`` (over the samples), ``vertex_max`` (vertices only).

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=24)
    >>> e = wm.surface_error(m, wm.sphere(1.0))
    >>> e["vertex_max"] < e["max"] < 0.01    # vertices lie on the sphere, chords cut inside
    True
    """
    if getattr(mesh, "dim", 3) != 3:
        raise ValueError(f"expected a 3D triangle surface for 'mesh', got a {mesh.dim}D mesh")
    target = as_target(shape, bounds=bounds, reference=reference)
    tri = mesh.triangles
    if len(tri) == 0:
        raise ValueError("expected a mesh with triangles for 'mesh', got none")
    samples = surface_sample_points(mesh.points, tri)
    d = target.distance(samples)
    nv = len(np.unique(tri))
    return {"max": float(d.max()), "mean": float(d.mean()), "vertex_max": float(d[:nv].max())}


def check_shape_dim(shape, points) -> None:
    """Refuse a planar shape for the nodes of a mesh off the plane z = 0: its f does not
    depend on z (a cylinder), so nodes would go onto a cylinder, not onto the shape. (A 3D
    shape on a planar mesh is its z = 0 slice, as intended.)

    >>> import numpy as np, warpmesh as wm
    >>> check_shape_dim(wm.circle(1.0), np.array([[0.0, 0.0, 0.5]]))
    Traceback (most recent call last):
    ...
    ValueError: expected a 3D 'shape' for the nodes of a 3D mesh (z from 0.5 to 0.5), got a 2D shape: its f is the same along z (a cylinder)
    """
    pts = np.asarray(points)
    if getattr(shape, "dim", 3) == 2 and pts.ndim == 2 and pts.shape[1] == 3 and len(pts) and np.any(pts[:, 2] != 0):
        raise ValueError(f"expected a 3D 'shape' for the nodes of a 3D mesh (z from {pts[:, 2].min():g} to "
                         f"{pts[:, 2].max():g}), got a 2D shape: its f is the same along z (a cylinder)")


def project_nodes(target, x: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """Newton projection onto f = 0, then float64 Newton steps on shapes.

    The tape evaluates f in float32 (about 1e-7 of the size); a shape also evaluates in
    float64 (``eval_numpy``), which brings the nodes to f = 0 within float64 rounding.
    Points on a cap of ``bounds`` (where the box is nearer than the surface) are exact.
    Used by every stage that places new nodes on the boundary (higher-order nodes,
    uniform and local refinement).

    Parameters
    ----------
    target : a projection target (:func:`as_target`)
    x : (n, 3) float64
        The points to project.
    cap : (n,) float64
        The longest move allowed for each point.

    Returns
    -------
    (n, 3) float64
    """
    y = target.project(x, max_step=cap)
    if not np.isfinite(y).all():  # (else the next evaluation blames 'points')
        bad = int((~np.isfinite(y).all(axis=1)).sum())
        raise ValueError(f"the shape evaluates to NaN or infinity near {bad} of the {len(y)} nodes to place on it: "
                         "check the 'shape' (e.g. sqrt/log of a negative) and that it is the mesh's")
    shape = getattr(target, "shape", None)
    if shape is None or not hasattr(shape, "eval_numpy") or len(y) == 0:
        return y
    for _ in range(POLISH_STEPS):
        f = np.broadcast_to(np.asarray(shape.eval_numpy(y[:, 0], y[:, 1], y[:, 2]), REAL_DTYPE),
                            (len(y),))
        g = target.value_gradient(y)[1]
        g2 = np.einsum("ij,ij->i", g, g)
        ok = np.isfinite(f) & (g2 > _TINY_G2)
        if target.bounds is not None:
            lo, hi = target.bounds
            box = np.concatenate([y - lo, hi - y], axis=1).min(axis=1)
            ok &= box >= np.abs(f) / np.sqrt(np.maximum(g2, _TINY_G2))
        step = np.where(ok, f / np.maximum(g2, _TINY_G2), 0.0)[:, None] * g
        y = y - np.where(np.linalg.norm(step, axis=1) <= cap, 1.0, 0.0)[:, None] * step
    return y
