#!/usr/bin/env python3
"""Surface optimization and simplification: warpmesh against its peers on the CPU.

(1) Optimization (isotropic remeshing). For each shape (``wm.example`` "sphere",
"degree6", "part") the marching-cubes mesh at ``--resolution`` (default 64, method "mc")
is remeshed to a constant target edge length h = ``--size`` x the MC cell size
(bounds extent / resolution), with surface tolerance ``--tolerance`` x h:

- ``warpmesh optimize``: ``wm.optimize(mesh, shape, bounds=..., size=h, tolerance=tol,
  features=True, iterations=--iterations)`` (projects onto the exact surface f = 0;
  ``bounds`` only where the MC mesh was capped on the box: degree6);
- ``pymeshlab remesh``: ``MeshSet.meshing_isotropic_explicit_remeshing(iterations=,
  adaptive=False, targetlen=PureValue(h), featuredeg=D, checksurfdist=True,
  maxsurfdist=PureValue(tol), split/collapse/swap/smooth/reproject all True)`` for each
  feature angle D of ``--featuredeg`` (default 30 and 60; it reprojects onto the input
  MC mesh, not the exact surface).

(2) Simplification to about 10 % of the triangles (``--reduction 0.9``) of the MC meshes
at ``--simplify-resolution`` (default 128) and of one label of pyvista's bundled frog
segmentation (``pyvista/examples/frog_tissues.vti``, read from the package directory,
no download; ``--label``, default 10):

- ``warpmesh simplify``: ``wm.simplify(mesh, shape, tolerance=--simplify-tolerance x cell,
  fraction=1 - --reduction)`` (``bounds=`` where capped; the volume: ``wm.VolumeField`` of
  the label's 0/1 indicator at level 0.5 and tolerance ``--frog-tolerance`` x its smallest
  spacing; ``--tolerance-only`` passes no ``fraction=``);
- ``fast-simplification``: ``fast_simplification.simplify(points, faces, target_reduction=0.9)``
  (left out when the package is not installed);
- ``pymeshlab quadric``: ``meshing_decimation_quadric_edge_collapse(targetfacenum=10 %)``
  (other parameters at their defaults).
  When warpmesh's triangle count is more than 10 % off the 10 % target, both peers are
  run again at warpmesh's count (rows marked "= warpmesh count").

Measured on every output with the same numpy code (independent of warpmesh's
optimizer): vertices np, triangles ne, mean / worst quality Q (``wm.quality.
triangle_quality``, 1 = equilateral), smallest angle, closed (every edge in exactly two
triangles), Euler characteristic V - E + F, and the distance to the surface: samples at
the vertices, the edge midpoints (per triangle) and the centroids, projected onto the
exact surface by Newton steps on f (``wm.evaluate(shape, x, gradient=True)``); on a mesh
capped on the box on g = min(f, distance to the box faces) (``exact_surface_distance``).
For the frog label the reference is the original MC mesh (pyvista ``find_closest_cell``).
``wm.surface_error``'s figures are printed next to these as a cross-check.

(3) ``--sections embedding`` (issue 18, item 4: optimisation and simplification never
fold): warpmesh alone, one run per case, on the default-method surfaces: the part at
``--embedding-resolutions`` (default 64,96,128,256) optimised to h = one cell (2.4 / R)
with tolerance h / 4; frog label ``--label`` (the 0/1 indicator of the cropped label as a
``wm.VolumeField`` at level 0.5, its surface from ``wm.mesh_surface(indicator, level=0.5)``)
optimised with size 1.5, tolerance 0.3; simplified to 10 %: the part at 96, the sphere
and the degree-six surface at 64 (tolerance a quarter cell; degree6 capped on its box),
the frog label (default tolerance, one spacing). Columns: triangles, worst Q and smallest
angle before -> after, crossing faces (``count_self_intersecting_faces``, warpmesh's
global check), inward faces (normal against the target's outward normal -grad f at the
centroid, the box's where capped; not counted where a sampled gradient vanishes), which
state was returned (``info["optimize"]["kept"]``, with the worst Q of the last pass), time.

Times are the best of ``--repeat`` runs, wall and CPU seconds of the process (every
thread; steadier than wall time on a shared machine) (tools round-robin after ``--warmup`` untimed
rounds; a tool stops once its timed runs pass ``--budget`` s, and a warm-up call longer
than that is its only, cold, run); ratio = tool time / warpmesh time (> 1: warpmesh
faster). ``--peers-only`` skips warpmesh's optimize / simplify (its rows print "n/a").

Run:  python benchmarks/bench_optimize.py [--quick] [--repeat 3] [--shapes sphere,degree6,part]
                                          [--size 1.0] [--tolerance 0.25] [--iterations 10]
                                          [--featuredeg 30,60] [--no-frog] [--peers-only] [--json out.json]
      python benchmarks/bench_optimize.py --sections embedding [--embedding-resolutions 64,96,128,256]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
import warnings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

# Memory: as bench_surface.py / bench_adaptive.py (see README.md), re-run with glibc keeping
# freed memory in the heap (the same for every tool); --default-malloc keeps the stock allocator.
_MALLOC_ENV = {"MALLOC_MMAP_THRESHOLD_": str(16 << 30), "MALLOC_TRIM_THRESHOLD_": str(16 << 30)}
if __name__ == "__main__" and "--default-malloc" not in sys.argv[1:] and "-h" not in sys.argv[1:] \
        and "--help" not in sys.argv[1:] and any(k not in os.environ for k in _MALLOC_ENV) \
        and sys.platform.startswith("linux"):
    os.execve(sys.executable, [sys.executable, *sys.argv], {**os.environ, **_MALLOC_ENV})

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING
try:  # optional peer: its rows are left out where it is not installed
    import fast_simplification  # noqa: E402
except ImportError:
    fast_simplification = None
import pymeshlab  # noqa: E402
import pyvista as pv  # noqa: E402

import warpmesh as wm  # noqa: E402

SHAPES = ("sphere", "degree6", "part")
FROG_FILE = os.path.join(os.path.dirname(pv.__file__), "examples", "frog_tissues.vti")
#: absolute values for pymeshlab's length parameters (PureValue since 2022.2, AbsoluteValue before)
ABSOLUTE = getattr(pymeshlab, "PureValue", None) or getattr(pymeshlab, "AbsoluteValue")

# Guards while the optimizer / simplifier are being written (remove once they land).
# warpmesh rows run unless --peers-only
HAVE_OPTIMIZE = HAVE_SIMPLIFY = HAVE_SURFACE_ERROR = True


# =============================================================================================
# mesh measures (one numpy implementation for every tool)
# =============================================================================================
def edge_counts(tris: np.ndarray) -> tuple[int, int, int]:
    """(undirected edges, edges in one triangle (open), edges in three or more (non-manifold))."""
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return len(counts), int(np.count_nonzero(counts == 1)), int(np.count_nonzero(counts > 2))


def min_angles_deg(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Smallest interior angle of each triangle in degrees (0 for a degenerate one)."""
    a, b, c = (points[tris[:, i]] for i in range(3))

    def angle(u, v):
        nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.arccos(np.clip((u * v).sum(1) / (nu * nv), -1.0, 1.0))

    A, B = angle(b - a, c - a), angle(a - b, c - b)
    ang = np.minimum(np.minimum(A, B), np.pi - A - B)
    return np.degrees(np.clip(np.nan_to_num(ang, nan=0.0), 0.0, None))


def mesh_measures(points, tris) -> dict:
    points = np.asarray(points, np.float64)
    tris = np.asarray(tris, np.int64)
    n_edges, open_edges, nonmanifold = edge_counts(tris)
    used = len(np.unique(tris))
    q = np.asarray(wm.triangle_quality(points, tris), np.float64)
    q = np.where(np.isfinite(q), q, np.inf)
    return {"np": int(len(points)), "unreferenced": int(len(points) - used), "ne": int(len(tris)),
            "mean_q": float(q.mean()), "worst_q": float(q.max()), "min_angle": float(min_angles_deg(points, tris).min()),
            "degenerate": int(np.count_nonzero(~np.isfinite(q))), "open_edges": open_edges,
            "nonmanifold_edges": nonmanifold, "bad_edges": open_edges + nonmanifold,
            "euler": int(used - n_edges + len(tris))}


# =============================================================================================
# distance to the exact surface (independent of warpmesh's optimizer; written once here so
# that wm.surface_error can be checked against it)
# =============================================================================================
def sample_points(points, tris) -> np.ndarray:
    """The vertices (once each), the three edge midpoints and the centroid of every triangle."""
    p = np.asarray(points, np.float64)
    t = np.asarray(tris)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    return np.concatenate([p[np.unique(t)], (a + b) / 2, (b + c) / 2, (c + a) / 2, (a + b + c) / 3])


def capped_field(shape, x: np.ndarray, box=None) -> tuple[np.ndarray, np.ndarray]:
    """g and grad g at x: g = f (f > 0 inside), or with a box g = min(f, signed distance to the
    box faces, positive inside): the solid {f > 0} cut by the box, as a capped mesh bounds it.

    With a box the piece is picked by first-order distance, f / |grad f| against the box
    distance (same sign and zero set as f): f itself is no distance (on degree6 |grad f| is in
    the hundreds), and comparing its value with a length picks the box face for points that
    lie 100x closer to f = 0."""
    fg = np.asarray(wm.evaluate(shape, x, gradient=True), np.float64)
    g, grad = fg[:, 0].copy(), fg[:, 1:4].copy()
    if box is not None:
        lo, hi = np.asarray(box[0], np.float64), np.asarray(box[1], np.float64)
        d = np.concatenate([x - lo, hi - x], axis=1)  # (n, 6), each face's plane distance
        j = d.argmin(axis=1)
        db = d[np.arange(len(x)), j]
        use = db < g / np.maximum(np.linalg.norm(grad, axis=1), 1e-30)
        face_grad = np.zeros((len(x), 3))
        face_grad[np.arange(len(x)), j % 3] = np.where(j < 3, 1.0, -1.0)
        g = np.where(use, db, g)
        grad = np.where(use[:, None], face_grad, grad)
    return g, grad


def _newton_onto_f(shape, x0, steps, max_step):
    """``steps`` Newton steps x <- x - f grad f / |grad f|^2 (each at most ``max_step`` long)."""
    x = x0.copy()
    for _ in range(steps):
        fg = np.asarray(wm.evaluate(shape, x, gradient=True), np.float64)
        f, grad = fg[:, 0], fg[:, 1:4]
        step = -(f / np.maximum((grad * grad).sum(1), 1e-30))[:, None] * grad
        if max_step is not None:
            length = np.linalg.norm(step, axis=1)
            step *= np.minimum(1.0, max_step / np.maximum(length, 1e-300))[:, None]
        x += step
    return x


def _refine_foot_points(shape, x0, y, steps, max_step, rounds: int = 3):
    """Move foot points y (on f = 0) towards the nearest point of f = 0 to x0: project x0 onto
    the tangent plane at y, Newton back onto f = 0, keep the result where it is nearer and
    converged. Newton alone follows the gradient line, which at a sharp edge of an R-function
    (the part) is the bisector: it lands on the edge, up to sqrt(2) x the distance to the face."""
    d = np.linalg.norm(y - x0, axis=1)
    scale = float(np.abs(x0).max()) + 1.0
    for _ in range(rounds):
        fg = np.asarray(wm.evaluate(shape, y, gradient=True), np.float64)
        nrm = fg[:, 1:4] / np.maximum(np.linalg.norm(fg[:, 1:4], axis=1), 1e-30)[:, None]
        z = x0 - ((x0 - y) * nrm).sum(1)[:, None] * nrm
        y2 = _newton_onto_f(shape, z, steps, max_step)
        fg2 = np.asarray(wm.evaluate(shape, y2, gradient=True), np.float64)
        ok = np.abs(fg2[:, 0]) <= 1e-6 * scale * np.linalg.norm(fg2[:, 1:4], axis=1)
        d2 = np.linalg.norm(y2 - x0, axis=1)
        better = ok & (d2 < d)
        if not better.any():
            break
        y = np.where(better[:, None], y2, y)
        d = np.where(better, d2, d)
    return y


def _project_capped(shape, x0, box, steps, max_step):
    """Nearest point of the boundary of {f > 0} cut by the box, (f = 0 in the box) U (box faces
    where f >= 0), as the nearest of three candidates: (a) Newton onto f = 0, kept where it lands
    in the box; (b) each box face (the projection clipped to the face), kept where f >= 0 there;
    (c) the crease of f = 0 with the nearest face plane (least-norm steps towards the sample
    point on both linearised constraints), kept where it converged and could be nearer."""
    lo, hi = np.asarray(box[0], np.float64), np.asarray(box[1], np.float64)
    eps = 1e-9 * float((hi - lo).max())
    n = len(x0)
    yf = _refine_foot_points(shape, x0, _newton_onto_f(shape, x0, steps, max_step), steps, max_step)
    in_box = np.all((yf >= lo - eps) & (yf <= hi + eps), axis=1)
    best = np.where(in_box, np.linalg.norm(yf - x0, axis=1), np.inf)
    y = yf.copy()
    for axis in range(3):
        for plane in (lo[axis], hi[axis]):
            yb = np.clip(x0, lo, hi)
            yb[:, axis] = plane
            db = np.linalg.norm(yb - x0, axis=1)
            cand = np.flatnonzero(db < best)
            if len(cand):
                ok = np.asarray(wm.evaluate(shape, yb[cand]), np.float64) >= 0.0
                cand = cand[ok]
                best[cand], y[cand] = db[cand], yb[cand]
    # (c) the crease of f = 0 with the nearest face plane, wherever that could be nearer
    dface = np.concatenate([x0 - lo, hi - x0], axis=1)
    j = np.abs(dface).argmin(axis=1)
    out = np.flatnonzero(np.abs(dface[np.arange(n), j]) < best)
    if len(out):
        j = j[out]
        axis, plane = j % 3, np.where(j < 3, lo[j % 3], hi[j % 3])
        e = np.zeros((len(out), 3))
        e[np.arange(len(out)), axis] = 1.0
        xo = x0[out]
        yc = np.clip(np.where(in_box[out, None], xo, yf[out]), lo, hi)
        yc[np.arange(len(out)), axis] = plane
        ok = np.ones(len(out), bool)
        for _ in range(2 * steps):
            fg = np.asarray(wm.evaluate(shape, yc, gradient=True), np.float64)
            f, grad = fg[:, 0], fg[:, 1:4]
            # minimise |y - x0| subject to f + grad.(y - yc) = 0 and y[axis] = plane
            A = np.stack([grad, e], axis=1)  # (m, 2, 3)
            r = np.stack([(grad * (xo - yc)).sum(1) + f, xo[np.arange(len(out)), axis] - plane], axis=1)
            M = A @ A.transpose(0, 2, 1)
            det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] * M[:, 1, 0]
            ok &= np.abs(det) > 1e-12 * np.maximum(M[:, 0, 0] * M[:, 1, 1], 1e-300)
            safe = np.where(ok, det, 1.0)
            lam = np.stack([(M[:, 1, 1] * r[:, 0] - M[:, 0, 1] * r[:, 1]) / safe,
                            (M[:, 0, 0] * r[:, 1] - M[:, 1, 0] * r[:, 0]) / safe], axis=1)
            step = xo - (A.transpose(0, 2, 1) @ lam[:, :, None])[:, :, 0] - yc
            if max_step is not None:  # damped: at most max_step per step
                length = np.linalg.norm(step, axis=1)
                step *= np.minimum(1.0, max_step / np.maximum(length, 1e-300))[:, None]
            yc = np.where(ok[:, None], yc + step, yc)
        fg = np.asarray(wm.evaluate(shape, yc, gradient=True), np.float64)
        ok &= np.abs(fg[:, 0]) <= 1e-6 * float((hi - lo).max()) * np.linalg.norm(fg[:, 1:4], axis=1)
        ok &= np.all((yc >= lo - eps) & (yc <= hi + eps), axis=1)
        dc = np.linalg.norm(yc - xo, axis=1)
        better = ok & (dc < best[out])
        best[out[better]], y[out[better]] = dc[better], yc[better]
    lost = ~np.isfinite(best)  # no candidate: keep (a)
    best[lost], y[lost] = np.linalg.norm(yf[lost] - x0[lost], axis=1), yf[lost]
    return y, best


def exact_surface_distance(shape, points, tris, box=None, *, steps: int = 8, max_step: float | None = None) -> dict:
    """Distance of the sample points of the triangles (``sample_points``) to the exact surface:
    f = 0, or with a box the boundary of {f > 0} cut by the box, i.e. g = 0 for g = min(f, signed
    distance to the box faces) (``capped_field``). The nearest point is found by ``steps``
    Newton steps on f (each at most ``max_step`` long), refined towards the foot point
    (``_refine_foot_points``) and, with a box, the candidates of ``_project_capped``;
    distance = |x_projected - x|. ``residual`` = the largest first-order
    distance min(f / |grad f|, box distance) left at the projected points (0 when converged)."""
    x0 = sample_points(points, tris)
    if box is None:
        y = _refine_foot_points(shape, x0, _newton_onto_f(shape, x0, steps, max_step), steps, max_step)
        d = np.linalg.norm(y - x0, axis=1)
    else:
        y, d = _project_capped(shape, x0, box, steps, max_step)
    g, grad = capped_field(shape, y, box)
    residual = np.abs(g) / np.maximum(np.linalg.norm(grad, axis=1), 1e-30)
    return {"max": float(d.max()), "mean": float(d.mean()), "residual": float(residual.max())}


def mesh_distance(reference: pv.PolyData, points, tris) -> dict:
    """Distance of the same sample points to a reference triangle mesh (pyvista find_closest_cell)."""
    x = sample_points(points, tris)
    _, closest = reference.find_closest_cell(x, return_closest_point=True)
    d = np.linalg.norm(closest - x, axis=1)
    return {"max": float(d.max()), "mean": float(d.mean()), "residual": 0.0}


def _box(lo, hi) -> str:
    return "[" + ", ".join(f"{a:g}..{b:g}" for a, b in zip(lo, hi)) + "]"


def touches_box(points, bounds, tol) -> bool:
    lo, hi = np.asarray(bounds[0]), np.asarray(bounds[1])
    return bool(np.any(np.abs(points - lo) < tol) or np.any(np.abs(points - hi) < tol))


# =============================================================================================
# the tools: each returns (points, triangles, mesh or None)
# =============================================================================================
def _meshset(points, tris):
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertex_matrix=np.asarray(points, np.float64),
                               face_matrix=np.asarray(tris, np.int32)))
    return ms


def pymeshlab_remesh(points, tris, h, tol, iterations, featuredeg):
    ms = _meshset(points, tris)
    ms.meshing_isotropic_explicit_remeshing(
        iterations=iterations, adaptive=False, selectedonly=False, targetlen=ABSOLUTE(h), featuredeg=featuredeg,
        checksurfdist=True, maxsurfdist=ABSOLUTE(tol), splitflag=True, collapseflag=True, swapflag=True,
        smoothflag=True, reprojectflag=True)
    m = ms.current_mesh()
    return m.vertex_matrix(), m.face_matrix(), None


def pymeshlab_decimate(points, tris, target):
    ms = _meshset(points, tris)
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=int(target))
    m = ms.current_mesh()
    return m.vertex_matrix(), m.face_matrix(), None


def fast_simplify(points, tris, reduction):
    # copies: fast_simplification's nanobind loader refuses read-only arrays (wm.Mesh's are)
    p, f = fast_simplification.simplify(np.array(points, np.float64), np.array(tris, np.int64),
                                        target_reduction=reduction)
    return p, f, None


def fast_simplify_count(points, tris, count):
    p, f = fast_simplification.simplify(np.array(points, np.float64), np.array(tris, np.int64),
                                        target_count=int(count))
    return p, f, None


def wm_optimize(mesh, shape, bounds, h, tol, iterations):
    kw = {} if iterations is None else {"iterations": iterations}
    m = wm.optimize(mesh, shape, bounds=bounds, size=h, tolerance=tol, features=True, **kw)
    return m.points, m.triangles, m


def wm_simplify(mesh, shape, tol, bounds=None, fraction=None):
    kw = {} if bounds is None else {"bounds": bounds}
    if fraction is not None:
        kw["fraction"] = fraction
    m = wm.simplify(mesh, shape, tolerance=tol, **kw)
    return m.points, m.triangles, m


# =============================================================================================
# timing: round-robin, best of N
# =============================================================================================
def run_round_robin(tools: dict, repeat: int, warmup: int, budget: float) -> dict:
    """``warmup`` untimed rounds, then ``repeat`` timed rounds, one call per tool each; a tool
    whose timed runs exceed ``budget`` s runs no more, and a warm-up call longer than ``budget``
    counts as that tool's only (cold) timed run."""
    res = {name: {"samples": [], "cpu": [], "warmup": [], "out": None} for name in tools}
    for _ in range(warmup):
        for name, fn in tools.items():
            if res[name]["samples"]:
                continue
            t0, c0 = time.perf_counter(), time.process_time()
            res[name]["out"] = fn()
            dt = time.perf_counter() - t0
            res[name]["warmup"].append(dt)
            if dt > budget:
                res[name]["samples"].append(dt)
                res[name]["cpu"].append(time.process_time() - c0)
    for _ in range(repeat):
        for name, fn in tools.items():
            if sum(res[name]["samples"]) > budget:
                continue
            res[name]["out"] = None  # free the previous output first
            t0, c0 = time.perf_counter(), time.process_time()
            out = fn()
            res[name]["samples"].append(time.perf_counter() - t0)
            res[name]["cpu"].append(time.process_time() - c0)
            res[name]["out"] = out
    for r in res.values():
        r["best"] = min(r["samples"])
        r["best_cpu"] = min(r["cpu"])  # CPU seconds of the process (every thread): steadier on a loaded machine
    return res


def measure(res_entry, distance_fn, surface_error_fn=None) -> dict:
    p, t, mesh = res_entry["out"]
    row = mesh_measures(p, t)
    row.update({"dist_" + k: v for k, v in distance_fn(p, t).items()})
    row["time_s"] = res_entry["best"]
    row["cpu_s"] = res_entry["best_cpu"]
    row["samples_s"] = res_entry["samples"]
    row["warmup_s"] = res_entry["warmup"]
    if surface_error_fn is not None:
        row["wm_surface_error"] = surface_error_fn(p, t, mesh)
    return row


def _wm_mesh(p, t, mesh):
    return mesh if mesh is not None else wm.Mesh(np.asarray(p, np.float64), {"triangle": np.asarray(t, np.int64)})


# =============================================================================================
# (1) optimization
# =============================================================================================
def optimize_case(args, name) -> dict:
    shape, bounds = wm.example(name)
    lo, hi = np.asarray(bounds[0], float), np.asarray(bounds[1], float)
    cell = float((hi - lo).max()) / args.resolution
    h, tol = args.size * cell, args.tolerance * args.size * cell
    t0 = time.perf_counter()
    mc = wm.mesh_surface(shape, bounds=bounds, resolution=args.resolution, method="mc")
    t_mc = time.perf_counter() - t0
    capped = touches_box(mc.points, bounds, 0.01 * cell)
    box = bounds if capped else None
    p0, t0_ = mc.points, mc.triangles

    tools = {}
    if HAVE_OPTIMIZE:
        it = None if args.wm_default_iterations else args.iterations
        tools["warpmesh optimize"] = lambda: wm_optimize(mc, shape, box, h, tol, it)
    for deg in args.featuredeg:
        tools[f"pymeshlab remesh, featuredeg {deg:g}"] = (
            lambda deg=deg: pymeshlab_remesh(p0, t0_, h, tol, args.iterations, deg))
    res = run_round_robin(tools, args.repeat, args.warmup, args.budget)

    def dist(p, t):
        return exact_surface_distance(shape, p, t, box, max_step=2 * cell)

    def cross(p, t, mesh):
        e = wm.surface_error(_wm_mesh(p, t, mesh), shape, bounds=box)
        return {"max": float(e["max"]), "mean": float(e["mean"])}

    se = cross if HAVE_SURFACE_ERROR else None
    rows = [{"tool": f"input: MC {args.resolution}^3", **mesh_measures(p0, t0_),
             **{"dist_" + k: v for k, v in dist(p0, t0_).items()}, "time_s": t_mc, "input": True}]
    if se:
        rows[0]["wm_surface_error"] = se(p0, t0_, mc)
    for tname, r in res.items():
        rows.append({"tool": tname, **measure(r, dist, se)})
    ref = res.get("warpmesh optimize")
    for r in rows:
        r["ratio"] = r["time_s"] / ref["best"] if ref and not r.get("input") else None
        r["cpu_ratio"] = r["cpu_s"] / ref["best_cpu"] if ref and not r.get("input") else None
    title = (f"(1) optimize: {name} on {_box(lo, hi)}, MC {args.resolution}^3 (cell {cell:.4g}), "
             f"h = {h:.4g} ({args.size:g} cell), tolerance {tol:.4g} ({args.tolerance:g} h), "
             f"{args.iterations} iterations" + (", capped on the box (distance to min(f, box))" if capped else ""))
    return {"section": "optimize", "case": name, "title": title, "rows": rows, "h": h, "tolerance": tol,
            "capped": capped, "missing": None if HAVE_OPTIMIZE else "warpmesh: n/a (--peers-only)"}


# =============================================================================================
# (2) simplification
# =============================================================================================
def load_frog(label: int):
    """The label's region of pyvista's bundled frog segmentation, cropped to its bounding box
    plus 2 samples (clipped to the volume), as (uint8 volume (nx, ny, nz), spacing, origin, info)."""
    img = pv.read(FROG_FILE)
    nx, ny, nz = img.dimensions
    name = img.point_data.keys()[0]
    # VTK point data run x fastest: Fortran order gives vol[i, j, k] at origin + (i, j, k) * spacing
    vol = np.asarray(img.point_data[name]).reshape((nx, ny, nz), order="F")
    labels, counts = np.unique(vol, return_counts=True)
    idx = np.argwhere(vol == label)
    if len(idx) == 0:
        raise SystemExit(f"label {label} not in {FROG_FILE} (labels {labels.tolist()})")
    a = np.maximum(idx.min(0) - 2, 0)
    b = np.minimum(idx.max(0) + 3, vol.shape)
    crop = np.ascontiguousarray(vol[a[0]:b[0], a[1]:b[1], a[2]:b[2]])
    spacing = tuple(float(s) for s in img.spacing)
    origin = tuple(float(o) + ai * s for o, ai, s in zip(img.origin, a, spacing))
    info = {"dims": (nx, ny, nz), "spacing": spacing, "origin": tuple(float(o) for o in img.origin),
            "dtype": str(vol.dtype), "labels": {int(k): int(c) for k, c in zip(labels, counts)},
            "crop": tuple(int(n) for n in crop.shape)}
    return crop, spacing, origin, info


def simplify_case(args, name, frog=None) -> dict:
    if frog is None:
        shape, bounds = wm.example(name)
        lo, hi = np.asarray(bounds[0], float), np.asarray(bounds[1], float)
        cell = float((hi - lo).max()) / args.simplify_resolution
        t0 = time.perf_counter()
        mc = wm.mesh_surface(shape, bounds=bounds, resolution=args.simplify_resolution, method="mc")
        t_mc = time.perf_counter() - t0
        capped = touches_box(mc.points, bounds, 0.01 * cell)
        box = bounds if capped else None
        target_shape = shape

        def dist(p, t):
            return exact_surface_distance(shape, p, t, box, max_step=2 * cell)

        what = (f"{name}, MC {args.simplify_resolution}^3 (cell {cell:.4g})"
                + (", capped on the box" if capped else "") + "; distance to the exact surface")
    else:
        vol, spacing, origin, info = frog
        cell = min(spacing)
        t0 = time.perf_counter()
        mc = wm.mesh_surface(vol, labels=[args.label], spacing=spacing, origin=origin, method="mc")
        t_mc = time.perf_counter() - t0
        box = None
        target_shape = wm.VolumeField((vol == args.label).astype(np.float32), spacing=spacing, origin=origin,
                                      level=0.5, inside="above") if HAVE_SIMPLIFY else None
        reference = pv.PolyData.from_regular_faces(np.asarray(mc.points, np.float64), np.asarray(mc.triangles))

        def dist(p, t):
            return mesh_distance(reference, p, t)

        what = (f"frog_tissues.vti label {args.label} (crop {info['crop']} of {info['dims']}, spacing {spacing}), "
                f"MC of the label; distance to that MC mesh")
    p0, t0_ = mc.points, mc.triangles
    n_in = len(t0_)
    target = int(round(n_in * (1.0 - args.reduction)))
    tol = (args.frog_tolerance if frog is not None else args.simplify_tolerance) * cell

    tools = {}
    if HAVE_SIMPLIFY:
        tools["warpmesh simplify"] = lambda: wm_simplify(mc, target_shape, tol, box, args.wm_fraction)
    if fast_simplification is not None:
        tools[f"fast-simplification, target_reduction {args.reduction:g}"] = (
            lambda: fast_simplify(p0, t0_, args.reduction))
    tools[f"pymeshlab quadric, targetfacenum {target:,}"] = lambda: pymeshlab_decimate(p0, t0_, target)
    res = run_round_robin(tools, args.repeat, args.warmup, args.budget)
    ref = res.get("warpmesh simplify")
    if ref is not None:
        n_wm = len(ref["out"][1])
        if abs(n_wm - target) > 0.1 * target and n_wm > 0:
            more = {f"pymeshlab quadric, targetfacenum {n_wm:,} (= warpmesh count)":
                    lambda: pymeshlab_decimate(p0, t0_, n_wm)}
            if fast_simplification is not None:
                more[f"fast-simplification, target_count {n_wm:,} (= warpmesh count)"] = (
                    lambda: fast_simplify_count(p0, t0_, n_wm))
            res.update(run_round_robin(more, args.repeat, args.warmup, args.budget))

    def cross(p, t, mesh):
        if frog is None:
            e = wm.surface_error(_wm_mesh(p, t, mesh), target_shape, bounds=box)
        else:
            e = wm.surface_error(_wm_mesh(p, t, mesh), reference=(mc.points, mc.triangles))
        return {"max": float(e["max"]), "mean": float(e["mean"])}

    se = cross if HAVE_SURFACE_ERROR else None
    rows = [{"tool": "input: " + ("MC of the label" if frog else f"MC {args.simplify_resolution}^3"),
             **mesh_measures(p0, t0_), **{"dist_" + k: v for k, v in dist(p0, t0_).items()},
             "time_s": t_mc, "input": True}]
    for tname, r in res.items():
        rows.append({"tool": tname, **measure(r, dist, se)})
    for r in rows:
        r["ratio"] = r["time_s"] / ref["best"] if ref and not r.get("input") else None
        r["cpu_ratio"] = r["cpu_s"] / ref["best_cpu"] if ref and not r.get("input") else None
    title = (f"(2) simplify: {what}; {n_in:,} -> ~{target:,} triangles"
             + (f", warpmesh tolerance {tol:.4g} ({tol / cell:g} cell)" if HAVE_SIMPLIFY else "")
             + (f", fraction {args.wm_fraction:g}" if HAVE_SIMPLIFY and args.wm_fraction else ""))
    return {"section": "simplify", "case": "frog" if frog else name, "title": title, "rows": rows,
            "missing": None if HAVE_SIMPLIFY else "warpmesh: n/a (--peers-only)"}


# =============================================================================================
# printing
# =============================================================================================
# =============================================================================================
# (3) embedding: no crossing, no inward face, never worse (issue 18 item 4)
# =============================================================================================
def inward_faces(points, tris, target) -> int:
    """Faces whose normal points against the target's outward normal at the centroid
    (where a sampled field's gradient vanishes nothing is known: not counted)."""
    p, t = np.asarray(points, np.float64), np.asarray(tris)
    nrm = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    out = target.normals(p[t].mean(axis=1))
    known = np.einsum("ij,ij->i", out, out) > 0.25
    return int(((np.einsum("ij,ij->i", nrm, out) <= 0) & known).sum())


def embedding_row(name, raw, out, target, seconds) -> dict:
    from warpmesh.cells.intersections import count_self_intersecting_faces

    before, after = mesh_measures(raw.points, raw.triangles), mesh_measures(out.points, out.triangles)
    info = out.info.get("optimize", {})
    s = out.stats()
    row = {"case": name, "ne": (before["ne"], after["ne"]), "worst_q": (before["worst_q"], after["worst_q"]),
           "min_angle": (before["min_angle"], after["min_angle"]),
           "crossing": (count_self_intersecting_faces(raw.points, raw.triangles),
                        count_self_intersecting_faces(out.points, out.triangles)),
           "inward": (inward_faces(raw.points, raw.triangles, target), inward_faces(out.points, out.triangles, target)),
           "closed": bool(s["watertight"] and s["manifold"] and s["oriented"]), "euler": int(s["euler"]),
           "kept": info.get("kept"), "q_last": info.get("q_worst_reached"), "seconds": seconds}
    print(f"| {name} | {row['ne'][0]} -> {row['ne'][1]} | {row['worst_q'][0]:.3f} -> {row['worst_q'][1]:.3f} | "
          f"{row['min_angle'][0]:.2f} -> {row['min_angle'][1]:.2f} | {row['crossing'][0]} -> {row['crossing'][1]} | "
          f"{row['inward'][0]} -> {row['inward'][1]} | {'closed' if row['closed'] else 'NOT CLOSED'}, euler "
          f"{row['euler']} | {row['kept']} ({row['q_last']:.3f}) | {seconds:.1f} |", flush=True)
    return row


def embedding_section(args) -> dict:
    from warpmesh.frep.projection import as_target

    print("\n(3) embedding (issue 18 item 4): default-method surfaces, one run each")
    print("| case | triangles | worst Q | min angle (deg) | crossing faces | inward faces | mesh "
          "| kept (worst Q of the last pass) | time (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = []
    shape, bounds = wm.example("part")
    part = as_target(shape)
    for r in args.embedding_resolution_list:
        raw = wm.mesh_surface(shape, bounds=bounds, resolution=r)
        h = 2.4 / r
        t0 = time.perf_counter()
        out = raw.optimize(shape, size=h, tolerance=h / 4)
        rows.append(embedding_row(f"part {r} optimize", raw, out, part, time.perf_counter() - t0))
    frog_raw = frog_field = None
    if not args.no_frog:
        vol, spacing, origin, _ = load_frog(args.label)
        ind = (vol == args.label).astype(np.float32)
        frog_field = wm.VolumeField(ind, spacing=spacing, origin=origin, level=0.5)
        frog_raw = wm.mesh_surface(ind, level=0.5, spacing=spacing, origin=origin)
        t0 = time.perf_counter()
        out = frog_raw.optimize(frog_field, size=1.5, tolerance=0.3)
        rows.append(embedding_row(f"frog label {args.label} optimize", frog_raw, out, frog_field,
                                  time.perf_counter() - t0))
    for name, r in (("part", 96), ("sphere", 64), ("degree6", 64)):
        shp, bnd = wm.example(name)
        capped = bnd if name == "degree6" else None  # the degree-six surface is unbounded
        raw = wm.mesh_surface(shp, bounds=bnd, resolution=r)
        h = (bnd[1][0] - bnd[0][0]) / r
        t0 = time.perf_counter()
        out = raw.simplify(shp, tolerance=h / 4, fraction=0.1, bounds=capped)
        rows.append(embedding_row(f"{name} {r} simplify 10 %", raw, out, as_target(shp, bounds=capped),
                                  time.perf_counter() - t0))
    if frog_raw is not None:
        t0 = time.perf_counter()
        out = frog_raw.simplify(frog_field, fraction=0.1)
        rows.append(embedding_row(f"frog label {args.label} simplify 10 %", frog_raw, out, frog_field,
                                  time.perf_counter() - t0))
    return {"section": "embedding", "rows": rows}


def _g(v, fmt="{:.3g}"):
    return "-" if v is None else ("inf" if v == np.inf else fmt.format(v))


def print_case(c):
    print()
    print(c["title"])
    hdr = (f"  {'tool':<58} {'np':>8} {'ne':>8} {'mean Q':>7} {'worst Q':>8} {'min ang':>7} {'max dist':>9} "
           f"{'mean dist':>9} {'closed':>10} {'euler':>6} {'time s':>8} {'ratio':>7}")
    print(hdr)
    print("  " + "-" * (len(hdr) - 2))
    if c["missing"]:
        print(f"  {c['missing']}")
    for r in c["rows"]:
        closed = "yes" if r["bad_edges"] == 0 else f"no ({r['bad_edges']:,})"
        print(f"  {r['tool']:<58} {r['np']:>8,} {r['ne']:>8,} {r['mean_q']:>7.3f} {_g(r['worst_q'], '{:.2f}'):>8} "
              f"{r['min_angle']:>7.2f} {r['dist_max']:>9.2e} {r['dist_mean']:>9.2e} {closed:>10} {r['euler']:>6} "
              f"{r['time_s']:>8.3f} {_g(r['ratio'], '{:.3g}x'):>7}")
    for r in c["rows"]:
        notes = []
        if r.get("unreferenced"):
            notes.append(f"{r['unreferenced']:,} unreferenced vertices")
        if r["bad_edges"]:
            notes.append(f"not closed: {r['open_edges']:,} open edges, {r['nonmanifold_edges']:,} in 3+ triangles")
        if r["degenerate"]:
            notes.append(f"{r['degenerate']:,} degenerate (zero-area, Q inf) triangles")
        if r.get("samples_s") and r["warmup_s"] and r["samples_s"] == r["warmup_s"][-1:]:
            notes.append(f"one cold call ({r['samples_s'][0]:.3f} s, over --budget)")
        elif r.get("samples_s"):
            notes.append("timed runs (s) [" + ", ".join(f"{x:.3f}" for x in r["samples_s"]) + "]"
                         + (f" after untimed [{', '.join(f'{x:.3f}' for x in r['warmup_s'])}]" if r["warmup_s"] else ""))
        if r.get("input"):
            notes.append(f"extraction {r['time_s']:.3f} s (first call, not compared)")
        if r.get("dist_residual", 0) > 1e-2 * max(r["dist_mean"], 1e-12):
            notes.append(f"projection residual {r['dist_residual']:.2e} (distance not converged)")
        if "wm_surface_error" in r:
            e = r["wm_surface_error"]
            notes.append(f"wm.surface_error max {e['max']:.3e} / mean {e['mean']:.3e} "
                         f"(here {r['dist_max']:.3e} / {r['dist_mean']:.3e})")
        if notes:
            print(f"  {r['tool']}: " + "; ".join(notes))


def summary(cases):
    print()
    print("Summary (time s, ratio = tool / warpmesh; CPU s of the process, ratio; max distance; worst Q):")
    for c in cases:
        parts = [] if not c["missing"] else ["warpmesh n/a"]
        for r in c["rows"]:
            if r.get("input"):
                continue
            s = f"{r['tool']} {r['time_s']:.3f} s"
            if r["ratio"] is not None and not r["tool"].startswith("warpmesh"):
                s += f" ({r['ratio']:.3g}x)"
            s += f", CPU {r['cpu_s']:.3f} s"
            if r.get("cpu_ratio") is not None and not r["tool"].startswith("warpmesh"):
                s += f" ({r['cpu_ratio']:.3g}x)"
            s += f", {r['ne']:,} tri, max d {r['dist_max']:.2e}, worst Q {_g(r['worst_q'], '{:.2f}')}"
            parts.append(s)
        print(f"  {c['section']} {c['case']}: " + "; ".join(parts))


def environment():
    ver = _report.version
    return {"python": platform.python_version(), "cores": os.cpu_count(), "numpy": np.__version__,
            "warp": wp.config.version, "pymeshlab": ver("pymeshlab"),
            "fast-simplification": ver("fast-simplification"), "pyvista": pv.__version__, "vtk": ver("vtk"),
            "malloc": "heap kept" if all(os.environ.get(k) == v for k, v in _MALLOC_ENV.items()) else "glibc default",
            "warpmesh optimize": HAVE_OPTIMIZE, "warpmesh simplify": HAVE_SIMPLIFY}


# =============================================================================================
def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--shapes", default=",".join(SHAPES), help=f"comma-separated subset of {','.join(SHAPES)}")
    p.add_argument("--quick", action="store_true",
                   help="smoke run: 1 timed run, no warm-up, featuredeg 30 only, simplification at 64^3")
    p.add_argument("--repeat", type=int, default=None, help="timed runs per tool, best taken (default 3, 1 with --quick)")
    p.add_argument("--warmup", type=int, default=None, help="untimed rounds first (default 1, 0 with --quick)")
    p.add_argument("--budget", type=float, default=20.0,
                   help="a tool whose timed runs add up to more than this many seconds runs no more (default 20)")
    p.add_argument("--resolution", type=int, default=64, help="MC resolution of the meshes to optimize (default 64)")
    p.add_argument("--size", type=float, default=1.0,
                   help="target edge length h in MC cells (extent / resolution) (default 1.0)")
    p.add_argument("--tolerance", type=float, default=0.25, help="surface tolerance in units of h (default 0.25)")
    p.add_argument("--iterations", type=int, default=10,
                   help="remeshing iterations, pymeshlab and warpmesh (default 10, pymeshlab's default)")
    p.add_argument("--wm-default-iterations", action="store_true",
                   help="pass no iterations= to wm.optimize (its own default) instead of --iterations")
    p.add_argument("--featuredeg", default=None,
                   help="pymeshlab feature angles (degrees), one row each (default 30,60; 30 with --quick)")
    p.add_argument("--simplify-resolution", type=int, default=None,
                   help="MC resolution of the meshes to simplify (default 128, 64 with --quick)")
    p.add_argument("--reduction", type=float, default=0.9, help="peers' target reduction (default 0.9: keep 10 %%)")
    p.add_argument("--simplify-tolerance", type=float, default=0.5,
                   help="warpmesh simplify tolerance in MC cells (the frog: in its smallest spacing) (default 0.5)")
    p.add_argument("--wm-fraction", type=float, default=None,
                   help="fraction= passed to wm.simplify (default: 1 - --reduction, the peers' target)")
    p.add_argument("--tolerance-only", action="store_true",
                   help="pass no fraction= to wm.simplify: decimate as far as the tolerance allows")
    p.add_argument("--frog-tolerance", type=float, default=1.0,
                   help="warpmesh simplify tolerance for the frog, in its smallest spacing (default 1.0)")
    p.add_argument("--label", type=int, default=10, help="frog_tissues label to simplify (default 10)")
    p.add_argument("--no-frog", action="store_true", help="skip the frog volume")
    p.add_argument("--sections", default="optimize,simplify",
                   help="comma-separated subset of optimize,simplify,embedding (default optimize,simplify)")
    p.add_argument("--embedding-resolutions", default="64,96,128,256",
                   help="resolutions of the part in the embedding section (default 64,96,128,256)")
    p.add_argument("--peers-only", action="store_true", help="run no warpmesh optimize / simplify (the peers' figures)")
    p.add_argument("--default-malloc", action="store_true", help="keep glibc's default allocator")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    args = p.parse_args(argv)
    if args.repeat is None:
        args.repeat = 1 if args.quick else 3
    if args.warmup is None:
        args.warmup = 0 if args.quick else 1
    if args.repeat < 1 or args.warmup < 0:
        p.error("--repeat must be >= 1 and --warmup >= 0")
    if args.featuredeg is None:
        args.featuredeg = "30" if args.quick else "30,60"
    args.featuredeg = [float(x) for x in args.featuredeg.split(",") if x.strip()]
    if args.simplify_resolution is None:
        args.simplify_resolution = 64 if args.quick else 128
    if not 0.0 < args.reduction < 1.0:
        p.error("--reduction must be in (0, 1)")
    if args.wm_fraction is None and not args.tolerance_only:
        args.wm_fraction = 1.0 - args.reduction
    if args.tolerance_only:
        args.wm_fraction = None
    args.shape_list = [s.strip() for s in args.shapes.split(",") if s.strip()]
    bad = [s for s in args.shape_list if s not in SHAPES]
    if bad:
        p.error(f"unknown shape(s) {bad}; pick from {list(SHAPES)}")
    args.section_list = [s.strip() for s in args.sections.split(",") if s.strip()]
    if any(s not in ("optimize", "simplify", "embedding") for s in args.section_list):
        p.error("--sections takes optimize, simplify and/or embedding")
    args.embedding_resolution_list = [int(x) for x in args.embedding_resolutions.split(",") if x.strip()]
    return args


def main(argv=None):
    global HAVE_OPTIMIZE, HAVE_SIMPLIFY
    args = parse_args(argv)
    if args.peers_only:
        HAVE_OPTIMIZE = HAVE_SIMPLIFY = False
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    wp.init()
    t_start = time.perf_counter()
    env = environment()
    print("bench_optimize: " + ", ".join(f"{k} {v}" for k, v in env.items()))
    load0 = os.getloadavg()[0]
    print(f"best of {args.repeat} run(s) per tool after {args.warmup} untimed round(s), round-robin; "
          f"load average (1 min) at start: {load0:.2f}"
          + ("  -- WARNING: other processes are using the CPU; timings will be noisy" if load0 > 0.7 else ""))
    print("columns: np/ne = vertices/triangles; Q = (sqrt 3/6) h_max/rho (1 equilateral); min ang = smallest angle "
          "(deg); max/mean dist = over samples at vertices, edge midpoints, centroids; closed = every edge in two "
          "triangles (else how many are not); euler = V - E + F; ratio = time / warpmesh time (> 1: warpmesh faster)")
    if not HAVE_OPTIMIZE:
        print("warpmesh: n/a (--peers-only; peers only)")
    if not HAVE_SIMPLIFY:
        print("warpmesh: n/a (--peers-only; peers only)")
    sys.stdout.flush()

    cases = []
    if "optimize" in args.section_list:
        for name in args.shape_list:
            c = optimize_case(args, name)
            print_case(c)
            sys.stdout.flush()
            cases.append(c)
    frog_info = None
    if "simplify" in args.section_list:
        for name in args.shape_list:
            c = simplify_case(args, name)
            print_case(c)
            sys.stdout.flush()
            cases.append(c)
        if not args.no_frog:
            frog = load_frog(args.label)
            frog_info = frog[3]
            print(f"\nfrog_tissues.vti: dims {frog_info['dims']}, spacing {frog_info['spacing']}, origin "
                  f"{frog_info['origin']}, {frog_info['dtype']}; samples per label: "
                  + ", ".join(f"{k}: {v:,}" for k, v in frog_info["labels"].items()))
            c = simplify_case(args, "frog", frog)
            print_case(c)
            cases.append(c)
    embedding = embedding_section(args) if "embedding" in args.section_list else None
    summary(cases)
    elapsed = time.perf_counter() - t_start
    load1 = os.getloadavg()[0]
    print(f"\nbenchmark wall time {elapsed:.0f} s; load average (1 min) at the end: {load1:.2f}")
    if args.json:
        doc = {"environment": env, "args": vars(args), "load_average_start_end": [load0, load1], "wall_s": elapsed,
               "frog": frog_info, "cases": cases, "embedding": embedding}
        tmp = args.json + ".tmp"
        with open(tmp, "w") as fh:
            json.dump(doc, fh, indent=1, default=str)
        os.replace(tmp, args.json)
        print(f"results written to {args.json}")


if __name__ == "__main__":
    main()
