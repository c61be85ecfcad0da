"""Edge sizes for curve meshes: the geometric metric of a chord tolerance and a user metric.

A geometric mesh of a curve [FG §16.2.2] wants every edge of length h to stay within
delta <= eps h of the curve. On a circle of radius rho an edge spanning the angle theta
has h = 2 rho sin(theta / 2) and delta / h = tan(theta / 4) / 2, so the largest edge
allowed where the radius of curvature is rho is

    h(rho) = 2 rho sin(2 atan(2 eps))   (~ 8 eps rho for small eps).

A user size field h_u(x) is a second (isotropic) metric; the mesh follows their
intersection (Chapter 10), min(h(rho), h_u(x)), clipped to [hmin, hmax]. An edge whose
metric length integral of ds / h is close to 1 is a unit edge (Definition 16.4).

Example
-------
>>> round(float(chord_size(1.0, 1e-3)), 6)    # ~ 8 eps rho
0.008
>>> sizes = SizeOption(None, ((-1, -1), (1, 1)))
>>> round(sizes.hmax, 6), round(sizes.hmin, 9)   # diagonal / 10, diagonal * 1e-5
(0.282843, 2.8284e-05)
"""

from __future__ import annotations

import numbers

import numpy as np

from warpmesh._conventions import REAL_DTYPE

__all__ = ["chord_size", "SizeOption", "check_tolerance"]

#: default hmax and hmin as fractions of the box diagonal
HMAX_FRACTION = 0.1
HMIN_FRACTION = 1.0e-5


def chord_size(radius, tolerance: float) -> np.ndarray:
    """Longest chord of a circle of ``radius`` whose deviation is at most ``tolerance`` times its length.

    Parameters
    ----------
    radius : float or (n,) array_like
        Radii of curvature (inf for straight parts).
    tolerance : float
        Relative chord deviation eps, 0 < eps < 0.5.

    Returns
    -------
    float64 array shaped like ``radius``: 2 rho sin(2 atan(2 eps)).

    Example
    -------
    >>> chord_size([1.0, np.inf], 0.1).round(4).tolist()
    [0.7692, inf]
    """
    return 2.0 * np.asarray(radius, REAL_DTYPE) * np.sin(2.0 * np.arctan(2.0 * tolerance))


def check_tolerance(tolerance) -> float:
    """The relative chord tolerance eps as a float in (0, 0.5), or a ValueError naming 'tolerance'."""
    if isinstance(tolerance, bool) or not isinstance(tolerance, numbers.Real) or not (0.0 < tolerance < 0.5):
        raise ValueError(f"expected 'tolerance' a relative chord deviation in (0, 0.5), got {tolerance!r}")
    return float(tolerance)


def _positive(value, name):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"expected '{name}' a positive finite number, got {value!r}")
    return float(value)


class SizeOption:
    """The size option of a curve mesh: None, a constant or a callable h(points) -> sizes.

    Parameters
    ----------
    size : None, float or callable
        A callable takes (n, 2) float64 points and returns (n,) positive sizes.
    bounds : ((x0, y0), (x1, y1))
        The meshing box; its diagonal sets the defaults of ``hmin`` and ``hmax``.
    hmin, hmax : float, optional
        Clip of every size; defaults diagonal * 1e-5 and diagonal / 10.

    Raises
    ------
    ValueError
        ``size`` <= 0 or not a number or callable; ``hmin`` / ``hmax`` not positive or
        hmin >= hmax. A callable returning a wrong shape or non-positive sizes raises
        when evaluated (:meth:`user`).
    """

    def __init__(self, size, bounds, hmin=None, hmax=None):
        b = np.asarray(bounds, REAL_DTYPE)
        diag = float(np.linalg.norm(b[1] - b[0]))
        self.hmax = diag * HMAX_FRACTION if hmax is None else _positive(hmax, "hmax")
        self.hmin = diag * HMIN_FRACTION if hmin is None else _positive(hmin, "hmin")
        if self.hmin >= self.hmax:
            raise ValueError(f"expected 'hmin' < 'hmax', got hmin={self.hmin!r} and hmax={self.hmax!r}")
        if size is None or callable(size):
            self.size = size
        else:
            self.size = _positive(size, "size")

    def user(self, points: np.ndarray) -> np.ndarray:
        """The user sizes at (n, 2) points (inf without a size option)."""
        n = len(points)
        if self.size is None:
            return np.full(n, np.inf)
        if not callable(self.size):
            return np.full(n, self.size)
        h = self.size(np.array(points, REAL_DTYPE))
        try:
            h = np.asarray(h, REAL_DTYPE)
        except (TypeError, ValueError):
            raise ValueError(f"expected 'size' to return an ({n},) array of numbers, got {type(h).__name__}") from None
        if h.shape != (n,):
            raise ValueError(f"expected 'size' to return an ({n},) array for ({n}, 2) points, got shape {h.shape}")
        if not np.all(np.isfinite(h) & (h > 0)):
            bad = h[~(np.isfinite(h) & (h > 0))][0]
            raise ValueError(f"expected 'size' to return positive finite sizes, got {float(bad)!r}")
        return h

    def sizes(self, points: np.ndarray, curvature: np.ndarray, tolerance: float,
              user: np.ndarray | None = None) -> np.ndarray:
        """min(chord_size(1 / |curvature|, tolerance), user size) clipped to [hmin, hmax], (n,).

        ``user`` passes sizes already evaluated at ``points`` (:meth:`user`)."""
        k = np.abs(np.asarray(curvature, REAL_DTYPE))
        with np.errstate(divide="ignore"):
            geo = chord_size(np.where(k > 0, 1.0 / np.where(k > 0, k, 1.0), np.inf), tolerance)
        u = self.user(points) if user is None else user
        return np.clip(np.minimum(geo, u), self.hmin, self.hmax)
