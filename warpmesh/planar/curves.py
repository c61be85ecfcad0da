"""Meshes of implicit curves and planar implicit domains: the public entry points.

:func:`mesh_curve` samples the curve f(x, y) = 0 with one of the methods of
[FG §16.3.1], then (by default) turns the samples into a geometric mesh (§16.2.2): edges whose
chord deviation stays below ``tolerance`` times their length, singular points and
curvature extrema as vertices, every component closed. :func:`mesh_domain` meshes
{f > 0} with triangles (§16.5.2): the geometric boundary mesh, interior points from a
graded covering-up, a boundary-conforming Delaunay triangulation and quality refinement.

=================  =============================================================  ============================
method             covering-up [FG §16.3.1]                                       module
=================  =============================================================  ============================
``continuation``   prediction-correction along the tangent (eq. 16.11), Newton    :mod:`~warpmesh.planar.samplers.continuation`
``progression``    cell tracking from seed cells with a stack                     :mod:`~warpmesh.planar.samplers.continuation`
``grid``           exhaustive enumeration, marching squares + asymptotic decider  :mod:`~warpmesh.planar.samplers.grid`
``freudenthal``    exhaustive enumeration on a Coxeter-Freudenthal triangulation  :mod:`~warpmesh.planar.samplers.grid`
``quadtree``       adaptive subdivision (planarity, curvature, crossing count)    :mod:`~warpmesh.planar.samplers.quadtree`
``rays``           the naive method: a family of parallel lines                   :mod:`~warpmesh.planar.samplers.rays`
=================  =============================================================  ============================

Example
-------
>>> import warpmesh as wm
>>> m = wm.mesh_curve(wm.ellipse((1.0, 0.5)), bounds=((-1.2, -0.7), (1.2, 0.7)), tolerance=1e-3)
>>> m.stats()["components"], m.cells["line"].shape[1]
(1, 2)
"""

from __future__ import annotations

import importlib
import inspect
import math
import time
import warnings
from typing import Literal

import numpy as np

from warpmesh._util.validate import check_device
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.mesh import Mesh
from warpmesh.planar.polyline import components
from warpmesh.planar.domain.pipeline import mesh_domain_from_boundary
from warpmesh.planar.geometric import geometric_mesh

__all__ = ["mesh_curve", "mesh_domain", "sample_curve", "boundary_edges", "CURVE_METHODS"]

CurveMethod = Literal["continuation", "progression", "grid", "freudenthal", "quadtree", "rays"]

#: method name -> (module, sampler function)
CURVE_METHODS = {
    "continuation": ("warpmesh.planar.samplers.continuation", "sample_predictor_corrector"),
    "progression": ("warpmesh.planar.samplers.progression", "sample_progression"),
    "grid": ("warpmesh.planar.samplers.grid", "sample_grid"),
    "freudenthal": ("warpmesh.planar.samplers.grid", "sample_freudenthal"),
    "quadtree": ("warpmesh.planar.samplers.quadtree", "sample_quadtree"),
    "rays": ("warpmesh.planar.samplers.rays", "sample_rays"),
}


def _sampler(method):
    if method not in CURVE_METHODS:
        raise ValueError(f"Unknown curve method {method!r}. Pick one of {list(CURVE_METHODS)}")
    module, name = CURVE_METHODS[method]
    return getattr(importlib.import_module(module), name)


def _check_options(func, options: dict, method: str) -> None:
    """Refuse options the sampler does not take, naming them and the ones it takes."""
    params = inspect.signature(func).parameters
    known = [p for p, v in params.items() if v.kind == v.KEYWORD_ONLY]
    unknown = [k for k in options if k not in known]
    if unknown:
        raise ValueError(f"unknown option {unknown[0]!r} for method {method!r}; it takes {known}")


#: the smallest relative tolerance: below, chord deviations drop under f's float32 resolution
#: (a circle at 3e-7 came out as 100 disconnected pieces)
MIN_TOLERANCE = 1e-6


def _check_tolerance(tolerance) -> float:
    t = float(tolerance) if isinstance(tolerance, (int, float, np.floating)) and not isinstance(tolerance, bool) \
        else math.nan
    if not (MIN_TOLERANCE <= t < 0.5):
        raise ValueError(f"expected a relative 'tolerance' in [{MIN_TOLERANCE:g}, 0.5) (chord deviation / edge "
                         f"length; below {MIN_TOLERANCE:g} the float32 evaluation of f cannot tell the deviations "
                         f"apart), got {tolerance!r}")
    return t


def sample_curve(shape, bounds, *, method: CurveMethod = "continuation", tolerance: float = 1e-2,
                 device: str = "cpu", **options) -> tuple[PlanarField, CurveSample]:
    """The raw samples of one method of [FG §16.3.1] (no geometric remeshing).

    Returns the :class:`~warpmesh.frep.planar_field.PlanarField` and the
    :class:`~warpmesh.planar.samplers.sample.CurveSample`; :func:`mesh_curve` wraps this.
    """
    tol = _check_tolerance(tolerance)
    func = _sampler(method)
    _check_options(func, options, method)
    field = PlanarField(shape, bounds, device=device)
    _check_finite(field)
    if "tolerance" in inspect.signature(func).parameters:
        options["tolerance"] = tol
    return field, func(field, **options)


#: nodes per side of the grid over the bounds at which a planar shape must be finite
FINITE_CHECK_NODES = 129


def _check_finite(field: PlanarField) -> None:
    """A ValueError naming 'shape' when f is NaN or infinite at nodes of a grid over the
    bounds (the samplers would return an empty or broken curve, the quadtree after minutes)."""
    n = FINITE_CHECK_NODES - 1
    values = field.grid(n, n)[2]
    bad = int((~np.isfinite(values)).sum())
    if bad:
        raise ValueError(f"the shape evaluates to NaN or infinity at {bad} of {values.size} grid nodes inside "
                         "'bounds' (e.g. sqrt/log of a negative or a division by zero); change the 'shape' or "
                         "the 'bounds'")


def _curve_mesh(points, segments, info) -> Mesh:
    n_comp, label = components(segments, len(points))
    refs = label[segments[:, 0]] + 1 if len(segments) else np.zeros(0, np.int64)
    return Mesh(points, {"line": segments}, cell_refs={"line": refs},
                info={**info, "components": n_comp})


def mesh_curve(shape, bounds, *, method: CurveMethod = "continuation", tolerance: float = 1e-2,
               geometric: bool = True, size=None, hmin: float | None = None, hmax: float | None = None,
               singular=None, device: str = "cpu", **options) -> Mesh:
    """Mesh the implicit curve f(x, y) = 0 of a planar shape with line segments.

    Parameters
    ----------
    shape : Shape or Expr
        A planar shape (``shape.dim == 2``: built from ``wm.coords(2)``, ``wm.circle``, ...).
    bounds : ((x0, y0), (x1, y1))
        The box; curves that leave it end on its sides (open chains).
    method : {'continuation', 'progression', 'grid', 'freudenthal', 'quadtree', 'rays'}
        The covering-up of [FG §16.3.1] (table in the module docstring). 'rays' is the naive
        method: it misses components between its lines (kept to show why).
    tolerance : float
        Relative chord deviation ε: every edge of length h stays within ε h of the curve
        (§16.2.2; h ≈ 8 ε ρ where the radius of curvature is ρ). Also the samplers' root
        tolerance, relative to their cell size.
    geometric : bool
        Remesh the samples into the geometric mesh (default). False returns the raw
        polyline of the method (its vertices are the sampler's points).
    size : float or callable, optional
        A size function h(x) ((n, 2) -> (n,)) intersected with the geometric size: the
        mesh is a unit mesh of the metric (Definition 16.4).
    hmin, hmax : float, optional
        Edge length limits (defaults: box diagonal × 1e-5 and / 10).
    singular : (k, 2) array_like, optional
        Singular points of the curve to keep as vertices (default: found by
        :func:`warpmesh.frep.geometry.singular_points`).
    device : str
        Warp device of the function evaluations.
    **options
        Options of the sampler (e.g. ``resolution`` for 'grid'; unknown names raise).

    Returns
    -------
    Mesh
        2D points and a ``"line"`` block oriented with the domain f > 0 on the left;
        ``cell_refs["line"]`` numbers the connected components from 1. ``stats()`` adds
        ``components``, ``method``, the sampler's counts (``sample_*``) and the geometric
        mesher's (``max_deviation``, ...), and timings.

    Raises
    ------
    ValueError
        A shape that reads z, bad bounds, an unknown method or option, a tolerance outside
        (0, 0.5).

    Example
    -------
    >>> import warpmesh as wm
    >>> shape, bounds = wm.example("lemniscate")
    >>> m = wm.mesh_curve(shape, bounds=bounds, method="grid", resolution=64)
    >>> m.stats()["components"]
    1
    """
    device = check_device(device)
    t0 = time.perf_counter()
    field, sample = sample_curve(shape, bounds, method=method, tolerance=tolerance, device=device, **options)
    t1 = time.perf_counter()
    info = {"method": method, "tolerance": float(tolerance), "time_sample": t1 - t0,
            **{f"sample_{k}": v for k, v in sample.info.items()}}
    if geometric and len(sample.segments):
        sample = geometric_mesh(field, sample, tolerance=float(tolerance), size=size, hmin=hmin, hmax=hmax,
                                singular=singular)
        info.update(sample.info)
        info["time_geometric"] = time.perf_counter() - t1
    failures = sample.info.get("failures")
    if failures is not None and len(failures):
        warnings.warn(f"method {method!r} could not follow the curve at {len(failures)} points (listed in "
                      "info['sample_failures']): the curve may be broken there; try method='quadtree'",
                      stacklevel=2)
    if not len(sample.segments):
        warnings.warn(f"method {method!r} found no curve f = 0 in 'bounds': the mesh is empty (check 'bounds', the "
                      "seeds or the resolution, and the sign convention f > 0 inside)", stacklevel=2)
    return _curve_mesh(sample.points, sample.segments, info)


def boundary_edges(triangles) -> np.ndarray:
    """Edges (k, 2) used by one triangle only, in that triangle's direction: for
    counterclockwise triangles, the domain lies on their left."""
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    e = t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.sort(e, axis=1)
    _, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return e[count[inv.ravel()] == 1]


def mesh_domain(shape, bounds, *, size: float | None = None, tolerance: float = 1e-2, min_angle: float = 28.0,
                method: Literal["global", "triangle"] = "global", boundary: CurveMethod = "quadtree",
                device: str = "cpu", **options) -> Mesh:
    """Mesh the planar domain {f > 0} with triangles [FG §16.5.2].

    The boundary is the geometric mesh of f = 0 (:func:`mesh_curve` with ``boundary`` as
    the covering-up, edges at most ``size``); then either the global approach of [FG §16.5.2]
    (interior points from a graded covering-up, Delaunay conforming to the boundary,
    refinement of the triangles below ``min_angle``, smoothing; :mod:`warpmesh.planar.domain.pipeline`)
    or, with ``method="triangle"``, the hierarchical approach handing the boundary to
    Shewchuk's Triangle (the optional ``triangle`` package) as a cross-check.

    Parameters
    ----------
    shape : Shape or Expr
        A planar shape; the domain is f > 0 inside ``bounds``.
    bounds : ((x0, y0), (x1, y1))
    size : float, optional
        Target edge length inside the domain (default: box diagonal / 20). The boundary
        edges are at most this long and shorter where the curvature asks for it.
    tolerance : float
        Relative chord deviation of the boundary edges (as in :func:`mesh_curve`).
    min_angle : float
        Smallest angle (degrees) the refinement aims at, in (0, 33].
    method : {'global', 'triangle'}
    boundary : str
        The curve method for the boundary (default 'quadtree': adaptive and rigorous).
    device : str
    **options
        Options of :func:`warpmesh.planar.domain.pipeline.mesh_domain_from_boundary` (unknown names raise).

    Returns
    -------
    Mesh
        2D points, a counterclockwise ``"triangle"`` block and the boundary ``"line"``
        block (domain on the left, ``cell_refs["line"]`` = boundary component from 1);
        ``stats()`` has ``min_angle``, ``mean_q``, ``worst_q`` (eq. 16.15) and the
        largest distance of a boundary vertex to the curve (``boundary_distance``).

    Example
    -------
    >>> import warpmesh as wm
    >>> m = wm.mesh_domain(wm.circle(1.0) - wm.circle(0.4), bounds=((-1.1, -1.1), (1.1, 1.1)), size=0.15)
    >>> s = m.stats()
    >>> round(s["area"], 1), s["min_angle"] >= 25
    (2.6, True)
    """
    _check_options(mesh_domain_from_boundary, options, "mesh_domain")
    device = check_device(device)
    field = PlanarField(shape, bounds, device=device)
    h = field.size / 20 if size is None else size
    if not (isinstance(h, (int, float, np.floating)) and not isinstance(h, bool) and h > 0 and math.isfinite(h)):
        raise ValueError(f"expected a positive finite 'size', got {size!r}")
    t0 = time.perf_counter()
    with warnings.catch_warnings():  # no curve is the ValueError below, not a warning first
        warnings.filterwarnings("ignore", message="method '.*' found no curve", category=UserWarning)
        curve = mesh_curve(shape, bounds, method=boundary, tolerance=tolerance, size=float(h), hmax=float(h),
                           device=device)
    t1 = time.perf_counter()
    if not len(curve.cells["line"]):
        raise ValueError("expected a 'shape' whose boundary f = 0 crosses 'bounds', found no curve")
    points, triangles, info = mesh_domain_from_boundary(field, np.asarray(curve.points), np.asarray(curve.cells["line"]),
                                                        size=float(h), min_angle=min_angle, method=method, **options)
    bseg = boundary_edges(triangles)
    info["boundary_distance"] = info.pop("boundary_distance_max")
    n_comp, label = components(bseg, len(points))
    info.update(boundary_method=boundary, boundary_components=n_comp, time_boundary=t1 - t0,
                time_domain=time.perf_counter() - t1)
    return Mesh(points, {"triangle": triangles, "line": bseg},
                cell_refs={"line": label[bseg[:, 0]] + 1}, info=info)
