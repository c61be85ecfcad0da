"""Isosurface stuffing (Labelle & Shewchuk 2007): the host driver of one run.

Lattice -> f at every node (the shape's tape) clipped by the box -> signs -> cut points on
the sign-changing edges by a bracketed root search (Illinois regula falsi) of the exact
field (not a linear interpolant) -> warp
the violated nodes onto their nearest violating cut point -> stencils of every background
tetrahedron -> compact vertex ids. Every stage is a kernel of :mod:`warpmesh.kernels.stuffing`
launched by :class:`warpmesh.solid.lattice.Lattice`.

With the paper's parameters (``ALPHA_LONG``, ``ALPHA_SHORT``) and a smooth enough surface
(sampled finely against its curvature), every dihedral angle lies in [10.7°, 164.8°].

Example
-------
>>> import warpmesh as wm
>>> pts, tets, on_surface, info = stuff(wm.sphere(1.0), ((-1.1,) * 3, (1.1,) * 3), 0.25)
>>> tets.shape[1], bool(on_surface.any()), info["cut_edges"] > 0
(4, True, True)
"""

from __future__ import annotations

import math
import time

import numpy as np
import warp as wp

from warpmesh.frep.tape import eval_values, tape_of
from warpmesh.solid.lattice import Lattice

__all__ = ["ALPHA_LONG", "ALPHA_SHORT", "stuff"]

#: the violation thresholds of Labelle & Shewchuk (2007) that prove dihedral angles in
#: [10.7°, 164.8°]: a node is violated by a cut point closer than alpha times the edge
ALPHA_LONG = 0.24776
ALPHA_SHORT = 0.40630
#: steps of the bracketed root search (Illinois regula falsi: superlinear on smooth fields,
#: never leaving the bracket on kinks)
ROOT_ITERATIONS = 12


def lattice_for(bounds: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(dims, origin) of a lattice of cube side h covering bounds with one cube to spare on
    every side (its outer nodes lie outside the box, so the mesh closes on it)."""
    lo, hi = bounds
    n = np.ceil((hi - lo) / h).astype(np.int64)
    origin = lo - h - 0.5 * (n * h - (hi - lo))  # centred
    return n + 3, origin


def stuff(shape, bounds, h: float, *, alpha_long: float = ALPHA_LONG, alpha_short: float = ALPHA_SHORT,
          iterations: int = ROOT_ITERATIONS, device="cpu"):
    """Tetrahedra of {f > 0} inside ``bounds`` by isosurface stuffing on a BCC lattice of cube
    side ``h`` (already validated arguments; :func:`warpmesh.solid.pipeline.mesh_domain` is the
    public entry point).

    Returns
    -------
    points : (n, 3) float64
    tets : (m, 4) int64, positive volume
    on_surface : (n,) bool, the vertices on f = 0 or on the box (cut points, warped nodes)
    info : dict of counts and timings
    """
    timings = {}
    t0 = time.perf_counter()
    bounds = np.asarray(bounds, dtype=np.float64)
    tape = tape_of(shape)
    dims, origin = lattice_for(bounds, h)
    lat = Lattice(dims, origin, h, device)
    lo, hi = bounds[0].tolist(), bounds[1].tolist()

    def field(points: wp.array) -> wp.array:
        return lat.clip(points, eval_values(tape, points, device=device, evaluator="interpreter"), lo, hi)

    pts = lat.node_points()
    values = field(pts)
    n_bad = lat.classify(values)
    if n_bad:
        raise ValueError(f"the shape evaluates to NaN at {n_bad} lattice nodes inside 'bounds' (e.g. sqrt/log "
                         "of a negative or a division by zero); change the expression or the bounds")
    timings["evaluate"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    n_cuts = lat.cut_edges(values)
    lat.roots(field, iterations)
    timings["roots"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    n_warped = lat.warp(alpha_long, alpha_short)
    points, tets, on_surface = lat.fill()
    timings["fill"] = time.perf_counter() - t1
    points += origin
    info = {"lattice": tuple(int(d) for d in dims), "cube_size": float(h), "lattice_nodes": lat.n_nodes,
            "cut_edges": n_cuts, "warped_nodes": n_warped,
            "alpha_long": float(alpha_long), "alpha_short": float(alpha_short),
            "time_stuffing": time.perf_counter() - t0, **{f"time_{k}": v for k, v in timings.items()}}
    return points, tets, on_surface, info


def lattice_size(bounds: np.ndarray, size: float) -> float:
    """The cube side of the lattice for a target edge length (the long edges)."""
    return float(size) if math.isfinite(size) else float(np.min(bounds[1] - bounds[0]))
