"""A planar shape's field f(x, y) on the Warp tape: values, exact gradients, Newton steps.

Every 2D module (curve sampling, geometric meshes, domain meshes) reads the function
through a :class:`PlanarField`: it checks the shape and the box once, evaluates the
shape's tape at z = 0 (values, or values with the forward-mode gradient, batched in the
tape kernels) and returns float64 numpy arrays of 2D quantities.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> field = PlanarField(wm.circle(1.0), ((-2, -2), (2, 2)))
>>> p = field.project(np.array([[0.3, 0.4], [2.0, 0.0]]))
>>> np.linalg.norm(p, axis=1).round(6).tolist()
[1.0, 1.0]
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import REAL_DTYPE
from warpmesh.frep.expr import depends_on
from warpmesh.frep.tape import points_array, eval_gradients, eval_intervals, eval_values, tape_of

__all__ = ["PlanarField", "check_bounds2d", "newton_project"]

_TINY = 1.0e-30
#: Newton steps of :meth:`PlanarField.project` [FG Remark 16.1]
NEWTON_STEPS = 8


def check_bounds2d(bounds, name: str = "bounds") -> np.ndarray:
    """((x0, y0), (x1, y1)) as a (2, 2) float64 array with x0 < x1 and y0 < y1."""
    try:
        b = np.asarray(bounds, dtype=REAL_DTYPE)
    except (TypeError, ValueError):
        raise ValueError(f"expected '{name}' ((x0, y0), (x1, y1)) of numbers, got {bounds!r}") from None
    if b.shape != (2, 2) or not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"expected '{name}' ((x0, y0), (x1, y1)) with x0 < x1 and y0 < y1, got {bounds!r}")
    return b


def newton_project(value_gradient, x: np.ndarray, max_step, steps: int, stop) -> np.ndarray:
    """Newton steps x -= f grad f / |grad f|² in place on (n, d) points x [FG Remark 16.1].

    ``value_gradient(points) -> (f, grad f)``; ``max_step`` (None, scalar or (n,)) caps each
    step; a point stops once its step is below ``stop`` (a scalar, or a function of the
    moving points giving one threshold each). Points where the gradient vanishes stay put.
    """
    cap = None if max_step is None else np.broadcast_to(np.asarray(max_step, REAL_DTYPE), (len(x),))
    active = np.arange(len(x))
    for _ in range(steps):  # a loop over Newton iterations, every point at once
        if len(active) == 0:
            break
        f, g = value_gradient(x[active])
        g2 = np.einsum("ij,ij->i", g, g)
        step = np.where(g2 > _TINY, f / np.maximum(g2, _TINY), 0.0)[:, None] * g
        if cap is not None:
            ln = np.linalg.norm(step, axis=1)
            step *= np.minimum(1.0, cap[active] / np.maximum(ln, _TINY))[:, None]
        x[active] -= step
        threshold = stop(x[active]) if callable(stop) else stop
        active = active[np.linalg.norm(step, axis=1) > threshold]
    return x


class PlanarField:
    """f(x, y) of a planar shape (f > 0 inside) over a box, evaluated by the Warp tape.

    Parameters
    ----------
    shape : Shape or Expr
        A planar shape (its field must not read z: ``shape.dim == 2``).
    bounds : ((x0, y0), (x1, y1))
        The box the curve is meshed in.
    device : str
        Warp device of the tape evaluations ("cpu" or "cuda").

    Raises
    ------
    TypeError
        ``shape`` is not a shape or an expression.
    ValueError
        ``shape`` reads z, or ``bounds`` is not a proper box.
    """

    def __init__(self, shape, bounds, device: str = "cpu"):
        self.tape = tape_of(shape)  # raises TypeError for anything that is not a shape
        field = getattr(shape, "field", shape)
        if depends_on(field, 2):
            raise ValueError("expected a planar 'shape' (a field of x and y, from wm.coords(2), wm.circle, "
                             "wm.rectangle, ...), got one that depends on z")
        self.shape, self.device = shape, device
        self.bounds = check_bounds2d(bounds)
        self.size = float(np.linalg.norm(self.bounds[1] - self.bounds[0]))
        #: finite-difference step of Hessians (relative 1e-4 of the box diagonal)
        self.fd_step = 1.0e-4 * self.size

    # -- evaluation -----------------------------------------------------------------
    def _pts3(self, points):
        p = np.asarray(points, dtype=REAL_DTYPE).reshape(-1, 2)
        return points_array(np.column_stack([p, np.zeros(len(p))]), self.device)

    def values(self, points) -> np.ndarray:
        """f at (n, 2) points, (n,) float64."""
        p = np.asarray(points, dtype=REAL_DTYPE).reshape(-1, 2)
        if len(p) == 0:
            return np.zeros(0)
        return eval_values(self.tape, self._pts3(p), device=self.device).numpy().astype(REAL_DTYPE)

    def value_gradient(self, points) -> tuple[np.ndarray, np.ndarray]:
        """f (n,) and its exact gradient (n, 2) at (n, 2) points (forward mode)."""
        p = np.asarray(points, dtype=REAL_DTYPE).reshape(-1, 2)
        if len(p) == 0:
            return np.zeros(0), np.zeros((0, 2))
        fg = eval_gradients(self.tape, self._pts3(p), device=self.device).numpy().astype(REAL_DTYPE)
        return fg[:, 0], fg[:, 1:3]

    def grid(self, nx: int, ny: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f on the (nx + 1) x (ny + 1) nodes of a regular grid over the box.

        Returns ``xs`` (nx + 1,), ``ys`` (ny + 1,) and ``values`` (nx + 1, ny + 1), indexed [i, j].
        """
        (x0, y0), (x1, y1) = self.bounds
        xs, ys = np.linspace(x0, x1, nx + 1), np.linspace(y0, y1, ny + 1)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        return xs, ys, self.values(np.column_stack([gx.ravel(), gy.ravel()])).reshape(nx + 1, ny + 1)

    def intervals(self, lo, hi) -> np.ndarray:
        """Intervals (m, 2) enclosing f over boxes [lo_i, hi_i] ((m, 2) each): interval
        arithmetic on the tape, so f has no zero in a box whose interval excludes 0."""
        lo, hi = np.asarray(lo, REAL_DTYPE).reshape(-1, 2), np.asarray(hi, REAL_DTYPE).reshape(-1, 2)
        if len(lo) == 0:
            return np.zeros((0, 2))
        z = np.zeros((len(lo), 1))
        out = eval_intervals(self.tape, points_array(np.hstack([lo, z]), self.device),
                             points_array(np.hstack([hi, z]), self.device), device=self.device)
        return out.numpy().astype(REAL_DTYPE)

    # -- Newton projection [FG Remark 16.1] ----------------------------------------
    def project(self, points, max_step=None, steps: int = NEWTON_STEPS) -> np.ndarray:
        """Points moved onto f = 0 by Newton steps P -= f grad f / |grad f|² (Remark 16.1).

        ``max_step`` (scalar or per point) caps each step, so a point never jumps to
        another branch; points where the gradient vanishes stay put.
        """
        x = np.array(points, dtype=REAL_DTYPE, copy=True).reshape(-1, 2)
        return newton_project(self.value_gradient, x, max_step, steps, 1e-7 * self.fd_step)

    def distance(self, points, refine: int = 3) -> np.ndarray:
        """Distance from each point to the curve: an upper bound, the nearest curve point
        found by Newton projection and ``refine`` foot-point steps (drop the point onto the
        tangent at the last curve point, project again)."""
        p = np.asarray(points, dtype=REAL_DTYPE).reshape(-1, 2)
        y = self.project(p)
        best = np.linalg.norm(y - p, axis=1)
        for _ in range(refine):
            _, g = self.value_gradient(y)
            n = g / np.maximum(np.linalg.norm(g, axis=1), _TINY)[:, None]
            z = p - np.einsum("ij,ij->i", p - y, n)[:, None] * n
            y = self.project(z)
            best = np.minimum(best, np.linalg.norm(y - p, axis=1))
        return best

    def estimate(self, points) -> np.ndarray:
        """First-order distance |f| / |grad f| [FG eq. 16.6]."""
        f, g = self.value_gradient(points)
        return np.abs(f) / np.maximum(np.linalg.norm(g, axis=1), _TINY)
