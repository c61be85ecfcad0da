"""Size fields for surface optimisation: the target edge length h(x) of a unit mesh.

[FG §16.2.2]: a mesh is *unit* (Definition 16.4) when its edge lengths measured in the
metric of the size field are close to 1, and *geometric* when the chord deviation of
every edge stays below the tolerance. An edge of length h on a curve of curvature κ
deviates by the sagitta δ ≈ h² κ / 8, so ``δ ≤ tolerance`` gives
``h ≤ sqrt(8 tolerance / κ)`` (the relative form δ ≤ εh of the book is
``h ≤ 8 ε / κ``, ``relative=True``).

A size field here is any callable ``h(points) -> (n,) float``; :func:`size_field` builds
one from the user's ``size`` argument.

Examples
--------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.frep.projection import ImplicitTarget
>>> h = size_field("curvature", ImplicitTarget(wm.sphere(2.0)), tolerance=1e-3, limits=(0.01, 1.0))
>>> float(h(np.array([[0.0, 0.0, 2.0]]))[0].round(4))           # sqrt(8e-3 * 2)
0.1265
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["size_field", "graded", "GRADATION"]

#: largest growth of h per unit length between neighbouring vertices
GRADATION = 0.3


def size_field(size, target=None, *, tolerance: float | None = None, limits=(0.0, np.inf),
               relative: bool = False) -> Callable[[np.ndarray], np.ndarray]:
    """A size field from ``size``: a positive float (constant), "curvature" (from the
    target's curvature and ``tolerance``), or a callable ``h(points)``; clipped to ``limits``."""
    lo, hi = float(limits[0]), float(limits[1])
    if callable(size):
        def user(points):
            h = np.asarray(size(points), dtype=np.float64).reshape(-1)
            if h.shape != (len(points),) or not np.all(np.isfinite(h)) or np.any(h <= 0):
                raise ValueError(f"expected the 'size' callable to return {len(points)} positive finite values")
            return np.clip(h, lo, hi)
        return user
    if isinstance(size, str):
        if size != "curvature":
            raise ValueError(f"expected 'size' to be a positive number, 'curvature' or a callable, got {size!r}")
        if target is None or tolerance is None or tolerance <= 0:
            raise ValueError("expected a target and a positive 'tolerance' for size='curvature'")

        def curvature(points):
            kappa = np.maximum(target.curvature(points), 1e-12)
            h = 8.0 * tolerance / kappa if relative else np.sqrt(8.0 * tolerance / kappa)
            return np.clip(h, lo, hi)
        curvature.from_curvature = True  # read by the optimiser (crease vertices)
        return curvature
    if isinstance(size, bool) or not isinstance(size, (int, float, np.floating, np.integer)):
        raise TypeError(f"expected 'size' to be a number, 'curvature' or a callable, got {type(size).__name__}")
    if not np.isfinite(size) or size <= 0:
        raise ValueError(f"expected a positive finite 'size', got {size!r}")
    value = float(size)
    return lambda points: np.full(len(points), value)


def graded(h: np.ndarray, points: np.ndarray, edges: np.ndarray, beta: float = GRADATION,
           sweeps: int = 6) -> np.ndarray:
    """Limit the growth of h between neighbours: h_v <= h_u + beta |uv| (a few Jacobi sweeps)."""
    h = h.copy()
    a, b = edges[:, 0], edges[:, 1]
    length = np.linalg.norm(points[a] - points[b], axis=1)
    for _ in range(sweeps):
        before = h.copy()
        np.minimum.at(h, a, h[b] + beta * length)
        np.minimum.at(h, b, h[a] + beta * length)
        if np.array_equal(h, before):
            break
    return h
