#!/usr/bin/env python3
"""Implicit curves and planar domains (seed Frey & George §16.3, §16.5.2): warpmesh against
scikit-image, contourpy (matplotlib's contouring engine), VTK through pyvista and Shewchuk's
Triangle on the same input in the same run, with ratios and a check of every result.

Cases (``--cases``, default all):

- ``contour``: the zero curve of the bundled gear (a CSG tree of 20 primitives with
  R-function booleans) on an N x N grid (``--resolution``, default 1024) over its box.
  warpmesh ``sample_curve(method="grid", root="linear")`` (tape evaluation on the Warp CPU
  backend + vectorised marching squares with the asymptotic decider), against numpy
  evaluation of the same expression (``Expr.eval_numpy`` on broadcast open axes) followed by
  ``skimage.measure.find_contours``, ``contourpy.contour_generator(...).lines(0)`` and
  pyvista ``ImageData.contour([0])`` (VTK). Checked: the number of closed curves (the gear
  has 7 boundary components) and the largest distance of an output vertex to the exact
  curve (Newton projection, warpmesh.frep.planar_field.PlanarField.distance).
- ``geometric``: the ellipse with semi-axes 1 and 0.1 at relative tolerance eps: vertices of
  the geometric mesh (warpmesh ``mesh_curve``) against the uniform polylines (equal edges)
  with the same largest chord deviation, absolute (the factor of issue 5's acceptance) and
  relative to the edge length (the criterion delta <= eps h of [FG §16.2.2]).
- ``domain``: the plate with holes and the gear meshed with triangles at edge size
  ``--size`` (default 0.04): warpmesh ``mesh_domain`` (global approach) against the same
  boundary handed to Triangle (``method="triangle"``, quality switch q28). Checked: min
  angle, mean and worst Q_K (eq. 16.15), area, boundary distance.

Times: one untimed round, then ``--repeat`` rounds, best kept.

Run:  python benchmarks/bench_curves.py [--repeat 3] [--resolution 1024] [--json out.json]
"""

from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

_report.keep_freed_memory()

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

CASES = ("contour", "geometric", "domain")


def _best(fn, repeat):
    fn()  # untimed warm-up (kernel load, caches)
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


# ----------------------------------------------------------------------------- contour
def contour_tools(shape, bounds, n):
    """{tool: () -> list of (k, 2) polylines or (points, segments)} on the same grid."""
    import contourpy
    import pyvista as pv
    from skimage import measure

    from warpmesh.planar.curves import sample_curve

    (x0, y0), (x1, y1) = bounds
    xs, ys = np.linspace(x0, x1, n + 1), np.linspace(y0, y1, n + 1)
    hx, hy = xs[1] - xs[0], ys[1] - ys[0]

    def values():
        return np.asarray(shape.eval_numpy(xs[:, None], ys[None, :]), dtype=np.float64)  # [i, j]

    def warpmesh_grid():
        _, s = sample_curve(shape, bounds, method="grid", resolution=n, root="linear")
        return s.points, s.segments

    def skimage_contours():
        lines = measure.find_contours(values(), 0.0)
        return [np.column_stack([x0 + c[:, 0] * hx, y0 + c[:, 1] * hy]) for c in lines]

    def contourpy_lines():
        f = values()
        gen = contourpy.contour_generator(xs, ys, f.T, line_type="Separate")
        return list(gen.lines(0.0))

    def vtk_contour():
        img = pv.ImageData(dimensions=(n + 1, n + 1, 1), spacing=(hx, hy, 1.0), origin=(x0, y0, 0.0))
        img.point_data["f"] = values().ravel(order="F")
        out = img.contour([0.0], scalars="f")
        lines = out.lines.reshape(-1, 3)[:, 1:]
        return np.asarray(out.points)[:, :2], lines

    return {"warpmesh": warpmesh_grid, "scikit-image": skimage_contours, "contourpy": contourpy_lines,
            "pyvista (VTK)": vtk_contour, "numpy values only": values}


def _as_points_segments(result):
    if isinstance(result, tuple):
        return result
    pts, segs, base = [], [], 0
    for line in result:
        k = len(line)
        closed = k > 2 and np.allclose(line[0], line[-1])
        body = line[:-1] if closed else line
        idx = np.arange(len(body)) + base
        segs.append(np.column_stack([idx, np.roll(idx, -1)]) if closed else np.column_stack([idx[:-1], idx[1:]]))
        pts.append(body)
        base += len(body)
    return np.concatenate(pts), np.concatenate(segs)


def run_contour(args, doc):
    import warpmesh as wm
    from warpmesh.frep.planar_field import PlanarField
    from warpmesh.planar.polyline import components, weld

    shape, bounds = wm.example("gear")
    field = PlanarField(shape, bounds)
    n = args.resolution
    print(f"\n== contour: gear zero curve on a {n} x {n} grid ==")
    print(f"{'tool':>16} {'seconds':>9} {'ratio':>7} {'points':>9} {'segments':>9} {'curves':>7} {'max dist':>10}")
    rows, base = {}, None
    for tool, fn in contour_tools(shape, bounds, n).items():
        t, out = _best(fn, args.repeat)
        if tool == "numpy values only":  # the part of every peer's time spent evaluating f
            rows[tool] = {"seconds": t}
            print(f"{tool:>16} {t:>9.3f} {t / base:>7.2f}   (the evaluation inside each peer's time)")
            continue
        p, s = _as_points_segments(out)
        p, s = weld(p, s, 1e-9 * field.size)  # scikit-image and VTK repeat points between pieces
        n_curves = components(s, len(p))[0]
        dist = float(field.distance(p).max())
        base = t if tool == "warpmesh" else base
        rows[tool] = {"seconds": t, "points": len(p), "segments": len(s), "curves": n_curves, "max_distance": dist}
        print(f"{tool:>16} {t:>9.3f} {t / base:>7.2f} {len(p):>9} {len(s):>9} {n_curves:>7} {dist:>10.2e}")
    doc["contour"] = rows


# ----------------------------------------------------------------------------- geometric
def _ellipse_arc(a, b, n=400001):
    t = np.linspace(0, 2 * np.pi, n)
    pts = np.column_stack([a * np.cos(t), b * np.sin(t)])
    return pts, np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])


def uniform_deviation(pts, s, k):
    """Worst absolute chord deviation of the polyline of k equal arc-length edges on the
    densely sampled closed curve ``pts`` (arc length ``s``)."""
    idx = np.searchsorted(s, np.linspace(0, s[-1], k + 1)).clip(0, len(s) - 1)
    a, b = pts[idx[:-1]], pts[idx[1:]]
    d = b - a
    ln = np.linalg.norm(d, axis=1)
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / ln[:, None]
    edge = (np.searchsorted(idx, np.arange(len(pts)), side="right") - 1).clip(0, k - 1)
    dev = np.abs(np.einsum("ij,ij->i", pts - a[edge], nrm[edge]))
    return float(dev.max())


def uniform_vertices(pts, s, target):
    """Fewest equal edges whose worst absolute deviation is at most ``target`` (doubling,
    then bisection)."""
    lo, hi = 4, 8
    while uniform_deviation(pts, s, hi) > target:
        lo, hi = hi, hi * 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if uniform_deviation(pts, s, mid) > target else (lo, mid)
    return hi


def run_geometric(args, doc):
    import warpmesh as wm
    from warpmesh.frep.planar_field import PlanarField
    from warpmesh.planar.metric import chord_size

    print("\n== geometric: ellipse 1 x 0.1, geometric mesh vs uniform polylines of the same chord error ==")
    print("   (uniform abs: equal edges, the same worst absolute deviation; uniform rel: worst deviation / h <= eps)")
    print(f"{'tolerance':>10} {'geometric np':>13} {'max dev':>10} {'max dev/h':>10} {'uniform abs':>12} "
          f"{'factor':>7} {'uniform rel':>12} {'factor':>7} {'seconds':>8}")
    rows = []
    shape, bounds = wm.ellipse((1.0, 0.1)), ((-1.2, -0.3), (1.2, 0.3))
    field = PlanarField(shape, bounds)
    arc, s = _ellipse_arc(1.0, 0.1)
    for eps in (1e-2, 1e-3, 1e-4):
        t, mesh = _best(lambda eps=eps: wm.mesh_curve(shape, bounds, tolerance=eps, hmax=1.0), args.repeat)
        p, sg = mesh.points, mesh.cells["line"]
        tt = np.linspace(0, 1, 33)[1:-1]
        samples = p[sg[:, 0], None] * (1 - tt)[None, :, None] + p[sg[:, 1], None] * tt[None, :, None]
        dist = field.distance(samples.reshape(-1, 2)).reshape(len(sg), -1).max(axis=1)
        dev = float(dist.max())
        # dev / h as the mesher measures it (above the float32 floor of the tape, ~1e-7 here: at the
        # tips edges are ~1e-4 long, where a plain distance / h would show the float32 noise)
        rel = float(mesh.stats()["max_relative_deviation"])
        # equal edges meeting dev / h <= eps everywhere must meet it at the tips (rho = b^2 / a = 0.01):
        # the longest chord of relative deviation eps on that circle (curve_metric.chord_size)
        k_abs, k_rel = uniform_vertices(arc, s, dev), int(np.ceil(s[-1] / chord_size(0.01, eps)))
        n = mesh.n_points
        rows.append({"tolerance": eps, "geometric": n, "max_deviation": dev, "max_relative_deviation": rel,
                     "uniform_same_absolute": k_abs, "factor_absolute": k_abs / n,
                     "uniform_same_relative": k_rel, "factor_relative": k_rel / n, "seconds": t})
        print(f"{eps:>10.0e} {n:>13} {dev:>10.2e} {rel:>10.2e} {k_abs:>12} {k_abs / n:>7.2f} {k_rel:>12} "
              f"{k_rel / n:>7.1f} {t:>8.3f}")
    doc["geometric"] = rows


# ----------------------------------------------------------------------------- domain
def run_domain(args, doc):
    import warpmesh as wm

    print(f"\n== domain: triangle meshes at size {args.size} ==")
    print(f"{'shape':>6} {'tool':>10} {'seconds':>8} {'ratio':>6} {'np':>7} {'ne':>7} {'min angle':>9} "
          f"{'mean Q':>7} {'worst Q':>8} {'area':>8} {'bnd dist':>9}")
    rows = {}
    for name in ("plate", "gear"):
        shape, bounds = wm.example(name)
        base = None
        for tool, method in (("warpmesh", "global"), ("Triangle", "triangle")):
            t, m = _best(lambda method=method: wm.mesh_domain(shape, bounds, size=args.size, method=method),
                         args.repeat)
            s = m.stats()
            base = t if base is None else base
            rows[f"{name}/{tool}"] = {k: s.get(k) for k in ("np", "ne", "min_angle", "mean_q", "worst_q", "area",
                                                              "boundary_distance")} | {"seconds": t}
            print(f"{name:>6} {tool:>10} {t:>8.3f} {t / base:>6.2f} {s['np']:>7} {s['ne']:>7} {s['min_angle']:>9.2f} "
                  f"{s['mean_q']:>7.3f} {s['worst_q']:>8.3f} {s['area']:>8.4f} {s['boundary_distance']:>9.1e}")
    doc["domain"] = rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", nargs="+", choices=CASES, default=list(CASES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--resolution", type=int, default=1024)
    ap.add_argument("--size", type=float, default=0.04)
    ap.add_argument("--json")
    ap.add_argument("--default-malloc", action="store_true", help="keep glibc's default malloc thresholds")
    args = ap.parse_args()
    t0 = time.perf_counter()
    load0 = _report.load_banner("bench_curves")
    doc = {"versions": {p: _report.version(p) for p in ("warpmesh", "warp-lang", "scikit-image", "contourpy",
                                                          "pyvista", "vtk", "triangle")}}
    print("versions: " + ", ".join(f"{k} {v}" for k, v in doc["versions"].items()))
    for case in args.cases:
        {"contour": run_contour, "geometric": run_geometric, "domain": run_domain}[case](args, doc)
    _report.finish(t0, load0, args.json, doc)


if __name__ == "__main__":
    main()
