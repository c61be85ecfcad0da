"""The result type every curve sampler of [FG §16.3.1] returns.

A sampler (grid, Freudenthal, continuation, quadtree, rays) turns a
:class:`~warpmesh.frep.planar_field.PlanarField` into points on the curve and directed
segments between them (the domain f > 0 on each segment's left), plus what it did.
:func:`warpmesh.mesh_curve` picks the sampler by name and optionally hands its polyline to
the geometric mesher (:mod:`warpmesh.planar.geometric`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CurveSample"]


@dataclass
class CurveSample:
    """Points on f = 0 and the directed segments joining them.

    Attributes
    ----------
    points : (n, 2) float64
        Sample points on (or within the root tolerance of) the curve.
    segments : (m, 2) int64
        Directed segments (a, b): the domain f > 0 lies on their left.
    info : dict
        Counts and timings of the sampler (``"evaluations"``, ``"cells"``, ...).
    cells : (k, 4) float64, optional
        The covering-up cells visited, as (x0, y0, x1, y1), for plots and domain meshing.
    """

    points: np.ndarray
    segments: np.ndarray
    info: dict = field(default_factory=dict)
    cells: np.ndarray | None = None
