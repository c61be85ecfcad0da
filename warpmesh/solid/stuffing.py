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

from warpmesh.frep.tape import eval_intervals, eval_values, tape_of
from warpmesh.kernels import stuffing as K
from warpmesh.solid.dihedral import tet_quality_summary
from warpmesh.solid.graded import refine_bcc, size_field
from warpmesh.solid.lattice import Background, Lattice

__all__ = ["ALPHA_LONG", "ALPHA_SHORT", "WINDOW_HALO", "stuff", "stuff_window"]

#: the violation thresholds of Labelle & Shewchuk (2007) that prove dihedral angles in
#: [10.7°, 164.8°]: a node is violated by a cut point closer than alpha times the edge
ALPHA_LONG = 0.24776
ALPHA_SHORT = 0.40630
#: steps of the bracketed root search (Illinois regula falsi: superlinear on smooth fields,
#: never leaving the bracket on kinks)
ROOT_ITERATIONS = 12
#: cells of lattice around a window's own black nodes (:func:`stuff_window`) for its tetrahedra
#: to be the whole lattice's: a tetrahedron of black node c has nodes in cells c - 1 to c + 1;
#: an inside node's warp reads its outside neighbours' signs (one edge: one cell further),
#: whose warp reads the cut points on their edges (one more)
WINDOW_HALO = 3


def lattice_for(bounds: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(dims, origin) of a lattice of cube side h covering bounds with one cube to spare on
    every side (its outer nodes lie outside the box, so the mesh closes on it)."""
    lo, hi = bounds
    n = np.maximum(np.ceil((hi - lo) / h - 1e-9), 1).astype(np.int64)  # 10.000000000000002 cubes are 10, not 11
    origin = lo - h - 0.5 * (n * h - (hi - lo))  # centred
    return n + 3, origin


def stuff(shape, bounds, h: float, *, alpha_long: float = ALPHA_LONG, alpha_short: float = ALPHA_SHORT,
          iterations: int = ROOT_ITERATIONS, grading=None, device="cpu"):
    """Tetrahedra of {f > 0} inside ``bounds`` by isosurface stuffing on a BCC lattice of cube
    side ``h`` (already validated arguments; :func:`warpmesh.solid.pipeline.mesh_domain` is the
    public entry point).

    ``grading``: a size function of position or ``"curvature"`` (see
    :mod:`warpmesh.solid.graded`): the lattice is then graded by longest-edge bisection to
    that size (``h`` unused) and the quadrilaterals are split by vertex ids; the dihedral
    bound is not proven there, ``info`` reports the range found (``graded_dihedral_min``,
    ``graded_dihedral_max``).

    Returns
    -------
    points : (n, 3) float64
    tets : (m, 4) int64, positive volume
    on_surface : (n,) bool, the vertices on f = 0 or on the box (cut points, warped nodes)
    info : dict of counts and timings
    """
    if grading is not None:
        return _stuff_graded(shape, bounds, grading, alpha_long, alpha_short, iterations, device)
    t0 = time.perf_counter()
    bounds = np.asarray(bounds, dtype=np.float64)
    dims, origin = lattice_for(bounds, h)
    lat = Lattice(dims, origin, h, device)
    info = _run_lattice(lat, tape_of(shape), bounds, alpha_long, alpha_short, iterations, device)
    t1 = time.perf_counter()
    points, tets, on_surface = lat.fill()
    info["time_fill"] += time.perf_counter() - t1
    points += origin
    info = {"lattice": tuple(int(d) for d in dims), "cube_size": float(h), "lattice_nodes": lat.n_nodes, **info,
            "time_stuffing": time.perf_counter() - t0}
    return points, tets, on_surface, info


def stuff_window(tape, bounds, h: float, lo, hi, *, alpha_long: float = ALPHA_LONG, alpha_short: float = ALPHA_SHORT,
                 iterations: int = ROOT_ITERATIONS, device="cpu"):
    """The tetrahedra :func:`stuff` makes from the black nodes ``lo <= c < hi`` (global cell
    indices, per axis) of its lattice, computed on a window of that lattice with a halo of
    :data:`WINDOW_HALO` cells: the same tetrahedra, their vertices at the same float32
    positions, keyed by their global lattice ids (a brick of a distributed run).

    Returns
    -------
    local : (n, 3) float64
        Positions relative to the global lattice's ``origin`` (float32 values: the world
        position is ``origin + local`` in float64, as :func:`stuff` adds it).
    tets : (m, 4) int64
        Into ``local``, in the order :func:`stuff` lists them within each black node.
    on_surface : (n,) bool
    keys : (n,) int64
        Global vertex keys (:meth:`warpmesh.solid.lattice.Lattice.fill_keyed`), increasing:
        sorted, the keys of all windows give :func:`stuff`'s vertex order.
    owner : (m,) int64
        Each tetrahedron's global black node, non-decreasing: a stable sort by it gives
        :func:`stuff`'s tetrahedron order.
    origin : (3,) float64
    info : dict of counts and timings: ``cut_edges`` and ``warped_nodes`` of the owned cells
        (summed over windows that tile the lattice: :func:`stuff`'s counts), the window's
        ``window_nodes`` and ``window_cut_edges``.

    Example
    -------
    Two windows give the tetrahedra of the whole lattice, at the same positions:

    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep.tape import tape_of
    >>> box, ball = np.array(((-1.1,) * 3, (1.1,) * 3)), wm.sphere(1.0)
    >>> pts, tets, _, _ = stuff(ball, box, 0.25)
    >>> dims, _ = lattice_for(box, 0.25)
    >>> halves = [stuff_window(tape_of(ball), box, 0.25, lo, hi) for lo, hi in
    ...           (((0, 0, 0), (6, dims[1], dims[2])), ((6, 0, 0), dims))]
    >>> sum(len(w[1]) for w in halves) == len(tets)
    True
    >>> whole = {tuple(sorted(map(tuple, t))) for t in pts[tets]}
    >>> parts = {tuple(sorted(map(tuple, t))) for w in halves for t in (w[0] + w[5])[w[1]]}
    >>> parts == whole
    True
    """
    t0 = time.perf_counter()
    bounds = np.asarray(bounds, dtype=np.float64)
    dims, origin = lattice_for(bounds, h)
    lo, hi = np.asarray(lo, dtype=np.int64), np.asarray(hi, dtype=np.int64)
    wlo, whi = np.maximum(lo - WINDOW_HALO, 0), np.minimum(hi + WINDOW_HALO, dims)
    lat = Lattice(whi - wlo, origin, h, device, offset=wlo, own=(lo - wlo, hi - wlo))
    info = _run_lattice(lat, tape, bounds, alpha_long, alpha_short, iterations, device)
    t1 = time.perf_counter()
    local, tets, on_surface, keys, owner = lat.fill_keyed(dims)
    info["time_fill"] += time.perf_counter() - t1
    cuts, warped = lat.owned_counts()
    info.update(window_nodes=lat.n_nodes, window_cut_edges=info["cut_edges"], cut_edges=cuts, warped_nodes=warped,
                time_stuffing=time.perf_counter() - t0)
    return local, tets, on_surface, keys, owner, origin, info


def _run_lattice(lat: Lattice, tape, bounds: np.ndarray, alpha_long, alpha_short, iterations, device) -> dict:
    """The stages up to the fill on a (window of a) lattice: f at the nodes clipped by the box,
    signs, cut edges, roots, warp. Returns counts and timings."""
    timings = {}
    t0 = time.perf_counter()
    lo, hi = bounds[0].tolist(), bounds[1].tolist()

    def field(points: wp.array) -> wp.array:
        return lat.clip(points, eval_values(tape, points, device=device, evaluator="interpreter"), lo, hi)

    values = field(lat.node_points())
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
    timings["fill"] = time.perf_counter() - t1
    return {"cut_edges": n_cuts, "warped_nodes": n_warped, "alpha_long": float(alpha_long),
            "alpha_short": float(alpha_short), **{f"time_{k}": v for k, v in timings.items()}}


def coarse_size(bounds: np.ndarray, smallest: float, largest: float) -> float:
    """The cube side of the coarse lattice a graded run refines: ``smallest`` times the
    largest power of two not above ``largest`` nor half the smallest side of the box (sizes
    above that half are clamped to it)."""
    cap = min(float(largest), 0.5 * float(np.min(bounds[1] - bounds[0])))
    smallest = min(float(smallest), cap)
    k = max(0, int(math.floor(math.log2(max(cap / smallest, 1.0)))))
    return smallest * 2.0**k


def _stuff_graded(shape, bounds, grading, alpha_long, alpha_short, iterations, device):
    """Isosurface stuffing on a graded background (see :func:`stuff`)."""
    timings = {}
    t0 = time.perf_counter()
    bounds = np.asarray(bounds, dtype=np.float64)
    field_size = size_field(grading, bounds, shape=shape, device=device)
    h0 = coarse_size(bounds, field_size.smallest, field_size.largest)
    dims, origin = lattice_for(bounds, h0)
    tape = tape_of(shape)

    def outside(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:  # the interval test of the octree
        away = (hi < bounds[0]).any(axis=1) | (lo > bounds[1]).any(axis=1)
        f = eval_intervals(tape, wp.array(lo.astype(np.float32), dtype=wp.vec3, device=device),
                           wp.array(hi.astype(np.float32), dtype=wp.vec3, device=device), device=device)
        return away | (f.numpy()[:, 1] < 0.0)  # sync point: the refinement decision

    coords, background, levels = refine_bcc(dims, h0, origin, field_size, outside=outside)
    timings["grade"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    bg = Background(coords * (0.5 * h0), background, origin, alpha_long, alpha_short, device)
    lo, hi = bounds[0].tolist(), bounds[1].tolist()
    wlo, whi = wp.vec3(*lo), wp.vec3(*hi)

    def field(points: wp.array) -> wp.array:
        f = eval_values(tape, points, device=device, evaluator="interpreter")
        out = wp.empty(points.shape[0], dtype=wp.float32, device=device)
        if points.shape[0]:
            wp.launch(K.clip_values_kernel, dim=points.shape[0], inputs=[points, f, wlo, whi], outputs=[out],
                      device=device)
        return out

    values = field(bg.node_points())
    n_bad = bg.classify(values)
    if n_bad:
        raise ValueError(f"the shape evaluates to NaN at {n_bad} lattice nodes inside 'bounds' (e.g. sqrt/log "
                         "of a negative or a division by zero); change the expression or the bounds")
    timings["evaluate"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    n_cuts = bg.cut_edges(values)
    bg.roots(field, iterations)
    timings["roots"] = time.perf_counter() - t1
    t1 = time.perf_counter()
    n_warped = bg.warp()
    points, tets, on_surface = bg.fill()
    timings["fill"] = time.perf_counter() - t1
    points += origin
    quality = tet_quality_summary(points, tets, device) if len(tets) else {"dihedral_min": float("nan"),
                                                                          "dihedral_max": float("nan")}
    info = {"graded": True, "lattice": tuple(int(d) for d in dims), "cube_size": float(h0),
            "size_smallest": field_size.smallest, "size_largest": field_size.largest,
            "background_tets": int(len(background)), "background_levels": int(levels.max(initial=0)),
            "lattice_nodes": bg.n_nodes, "cut_edges": n_cuts, "warped_nodes": n_warped,
            "alpha_long": float(alpha_long), "alpha_short": float(alpha_short),
            "graded_dihedral_min": quality["dihedral_min"], "graded_dihedral_max": quality["dihedral_max"],
            "time_stuffing": time.perf_counter() - t0, **{f"time_{k}": v for k, v in timings.items()}}
    return points, tets, on_surface, info


def lattice_size(bounds: np.ndarray, size: float) -> float:
    """The cube side of the lattice for a target edge length (the long edges)."""
    return float(size) if math.isfinite(size) else float(np.min(bounds[1] - bounds[0]))
