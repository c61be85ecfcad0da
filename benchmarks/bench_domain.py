#!/usr/bin/env python3
"""Tetrahedral meshes of implicit domains (issue 20 part 8): warpmesh's isosurface stuffing
side by side with gmsh, TetGen, mmg3d's level-set mode (mmgpy) and fTetWild (pytetwild) on
the CPU, all in one run and one table.

Cases (``--cases``): the unit sphere, the torus (R = 1, r = 0.35), the CSG part (a plate with
four holes and a boss: sharp edges), ``gyroid_ball`` (the gyroid's solid network, period 1,
intersected with the unit ball: :func:`gyroid_ball`) and ``degree6`` (the degree-six solid of
``wm.example("degree6")`` clipped by its box [-3, 3]^3, closed by caps), each at about 100 k
tetrahedra (``--sizes 100k``, the default) and/or about 1 M (``--sizes 100k,1M``, or
``--large``). The 1 M class is not the default: the sphere alone with every peer took 956 s
wall at load 5 (fTetWild 590 s, mmg 147 s, gmsh 56 s), about an hour for the five cases;
the default run (100 k, variants on) took 1489 s wall at load 5-6. A peer that does not import prints why and its rows say "not installed"
(``pip install -e ".[bench]"`` brings mmgpy and pytetwild).

- warpmesh stuffing: ``wm.mesh_domain(shape, bounds, size=h)`` (lattice, cut points by a
  bracketed root search of the exact f, warp, stencils, crease recovery, boundary faces and
  statistics), best of ``--repeat`` warm runs; the reference row of the ratios.
- warpmesh variants (``--variants``, default on, classes up to 200 k, one run each):
  ``features=False``; ``smooth=2, flips=True``; ``size="curvature"`` (graded, its own count);
  ``method="delaunay"`` (its own size for about the same count).
- gmsh: the OpenCASCADE solid where one exists (sphere, torus, part: ``Mesh.MeshSizeMin/Max``
  calibrated for the count), else a surface loop of warpmesh's optimised surface; 3D Delaunay
  (``Mesh.Algorithm3D = 1``), one thread, timed from the model to the tetrahedra.
- warpmesh's optimised surface (the peers' input where they need a surface, not timed):
  ``wm.mesh_surface`` closed by caps on the bounds, then ``optimize`` on the exact shape with
  edges a = (6 sqrt(2) V / N)^(1/3), the regular tetrahedron's edge at the target count N.
- TetGen (``tetgen``) on that surface: ``minratio=1.5``, ``mindihedral=10``, a ``maxvolume``
  calibrated for the count (``fixedvolume=True``: tetgen 0.8 ignores ``maxvolume`` without it).
- mmg3d's level-set discretisation (mmgpy 0.17, ``MmgMesh3D.remesh_levelset``): the box cut in
  Kuhn tetrahedra of the stuffing's cube side h (f sampled as finely as stuffing's lattice),
  -f at their vertices (mmg's inside is negative), ``hsiz`` calibrated for the count and
  ``hausd = hsiz / 10``; mmg remeshes the whole box: the inside (ref 3) is counted, the time
  is the whole (background, f, remeshing). One run.
- fTetWild (pytetwild 0.4, ``tetrahedralize(edge_length_abs=...)``, one thread) on the same
  surface, the edge length calibrated for the count. One run.

Sizes are calibrated by one run per tool at an eighth of the count (count ~ size^-3).
Columns: tetrahedra, wall and CPU seconds (process CPU, all threads), tetrahedra per wall
second, smallest and largest dihedral angle (degrees), radius-edge ratio (largest / 99th
percentile: one sliver makes the largest huge), the volume error against the exact volume
(sphere, torus, and the part from its primitives) or a stratified 320^3-grid estimate
(gyroid_ball, degree6; the run prints the estimate's own error on the exact cases), the
boundary distance (largest |f| / |grad f| over the boundary vertices off the box's faces, in
units of the stuffing's h; first order, so it overstates near the edges of an R-function
intersection), and stuffing's tets/s over the tool's, by wall and by CPU (> 1: stuffing
faster). For the ball the run prints the issue's speed acceptance line (>= 10x gmsh's tets/s
at ~1 M with a better smallest dihedral angle).

Run:  pip install -e ".[bench]"
      python benchmarks/bench_domain.py [--sizes 100k,1M] [--repeat 3] [--no-variants]
                                        [--cases sphere,torus,part,gyroid_ball,degree6] [--peers gmsh,tetgen,mmgpy,pytetwild]
                                        [--json out.json]

Last measured (2026-12-02, 2-core Intel Xeon VM, no GPU, load average 4.6-6.3 from other jobs:
compare CPU seconds; stuffing, gmsh, TetGen best of 3 at 100 k, one run otherwise) by
``python benchmarks/bench_domain.py`` (1489 s wall with the variants; their rows and the
columns' full form: benchmarks/README.md) and, for the last two rows (the ball's speed
acceptance: 45x gmsh's tets per CPU second, 40.8x per wall second, 18.4 vs 12.7 degrees),
``--cases sphere --sizes 1M --peers gmsh``::

    case              tool        tets     CPU s  wall s  dihedral     re p99  volume  bdist/h  ratio CPU
    sphere 100 k      stuffing      95,712    0.09    0.24  20.4-150.5   1.41  -0.17%  2.9e-06  1
    sphere 100 k      gmsh OCC      86,937    1.41    7.42  11.6-156.8   1.04  -0.13%  7.3e-07  18.1x
    sphere 100 k      TetGen        98,921    0.75    2.26   1.8-176.9   1.07  -0.20%  0.013    8.5x
    sphere 100 k      mmg3d -ls     87,009    7.45   40.33  15.9-154.7   1.06  -0.46%  0.031    95.5x
    sphere 100 k      fTetWild      43,628    6.29   32.24  16.7-158.4   1.16  -0.32%  0.023    160.8x
    torus 100 k       stuffing      95,716    0.12    0.46  18.5-143.9   1.56  -0.32%  4.8e-06  1
    torus 100 k       gmsh OCC      93,883    2.09    5.18  11.3-157.7   1.08  -0.24%  2.2e-06  18.4x
    torus 100 k       TetGen        99,006    0.78    1.58   1.7-176.9   1.09  -0.38%  0.028    6.5x
    torus 100 k       mmg3d -ls     86,107   14.28   44.93  19.9-154.4   1.13  -0.85%  0.061    136.6x
    torus 100 k       fTetWild      72,747   21.96   56.87  23.8-139.5   1.05  -0.61%  0.04     248.5x
    part 100 k        stuffing      89,076    1.56    3.43  10.1-161.9   1.80  +0.08%  2.8e-06  1
    part 100 k        gmsh OCC      87,069    1.44    2.92  11.3-156.5   1.14  +0.07%  1.1e-06  0.9x
    part 100 k        TetGen        98,528    0.75    1.51   1.5-177.0   1.09  +0.11%  0.043    0.4x
    part 100 k        mmg3d -ls    149,669   19.78   44.74   6.0-162.1   1.22  -1.70%  0.73     7.6x
    part 100 k        fTetWild      86,910   46.44   62.70  22.1-142.4   1.11  +0.12%  0.04     30.6x
    gyroid_ball 100 k stuffing      91,503    2.37    3.49  10.0-162.9   1.67  -0.35%  0.0052   1
    gyroid_ball 100 k gmsh loop     56,530    0.84    2.56   3.3-173.7   1.47  -0.26%  0.72     0.6x
    gyroid_ball 100 k TetGen       101,524    0.99    3.05   0.5-177.4   1.58  -0.26%  0.95     0.4x
    gyroid_ball 100 k mmg3d -ls    171,737   25.49   35.52   0.1-178.9   1.48  -4.76%  3.5      5.7x
    gyroid_ball 100 k fTetWild      56,550   77.88   85.30  14.0-155.1   1.15  -0.46%  0.99     53.1x
    degree6 100 k     stuffing      91,440    0.55    0.55  12.0-158.8   1.94  -0.10%  0.099    1
    degree6 100 k     gmsh loop     55,802    0.66    0.66  12.9-156.6   1.10  -0.06%  2.1e-06  2.0x
    degree6 100 k     TetGen        97,942    0.62    0.62   1.7-176.9   1.12  -0.06%  0.068    1.0x
    degree6 100 k     mmg3d -ls    114,911    9.16    9.16   0.4-179.0   1.32  +1.45%  0.62     13.2x
    degree6 100 k     fTetWild      72,541   54.32   54.35  14.4-158.8   1.22  -0.06%  0.025    123.7x
    sphere 1 M        stuffing     983,808    0.63    2.11  18.4-143.4   1.29  -0.04%  6.4e-06  1
    sphere 1 M        gmsh OCC     979,101   28.21   85.66  12.7-160.6   0.98  -0.03%  1.6e-06  45.0x
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _report  # noqa: E402

_report.keep_freed_memory()

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

import warpmesh as wm  # noqa: E402
from warpmesh.frep.tape import tape_of, value_gradient_at  # noqa: E402
from warpmesh.optimize.remesh import optimize  # noqa: E402
from warpmesh.solid.dihedral import dihedral_angles, radius_edge_ratio, signed_volumes  # noqa: E402
from warpmesh.solid.features import example_edges, feature_distance  # noqa: E402
from warpmesh.solid.pipeline import boundary_faces  # noqa: E402

#: the peers: module, or the reason it is missing (its rows then say "not installed")
PEER_NAMES = ("gmsh", "tetgen", "mmgpy", "pytetwild")
PEERS, MISSING = {}, {}
for _name in PEER_NAMES:
    try:
        PEERS[_name] = __import__(_name)
    except ImportError as _exc:  # a missing peer is reported, never fatal
        MISSING[_name] = f"{type(_exc).__name__}: {_exc}"
        print(f"{_name} not installed ({MISSING[_name]}); its rows say 'not installed' "
              "(pip install -e '.[bench]')", flush=True)
gmsh, tetgen = PEERS.get("gmsh"), PEERS.get("tetgen")

CASES = ("sphere", "torus", "part", "gyroid_ball", "degree6")
#: the cases with an OpenCASCADE solid for gmsh; the others give gmsh warpmesh's optimised surface
OCC_CASES = ("sphere", "torus", "part")
#: exact volumes. The part's from its primitives: the plate 2 x 2 x 0.6, minus four cylinders of
#: radius 0.2 through it, plus the two caps (height 0.2) of the ball r = 0.5 standing out of it
#: (no hole meets the ball or the plate's sides)
EXACT_VOLUME = {"sphere": 4.0 / 3.0 * math.pi, "torus": 2 * math.pi**2 * 0.35**2,
                "part": 2.4 - 4 * math.pi * 0.2**2 * 0.6 + 2 * math.pi * 0.2**2 * (3 * 0.5 - 0.2) / 3}
#: cells per side of the grid of the fine-grid volume estimate (cases with no closed form)
GRID_VOLUME_N = 320
SIZE_CLASSES = {"100k": 100_000, "1M": 1_000_000}


def gyroid_ball(period: float = 1.0, radius: float = 1.0):
    """(shape, bounds): the gyroid's solid network, sin x cos y + sin y cos z + sin z cos x > 0
    with x, y, z scaled by 2 pi / ``period`` (and f by its inverse, so |grad f| is about 1 like
    the ball's), intersected with the ball of ``radius``: sharp edges where the two meet.

    >>> shape, bounds = gyroid_ball()
    >>> float(wm.evaluate(shape, np.array([[0.0, 0.0, 2.0]]))[0]) < 0   # outside the ball
    True
    """
    if not period > 0 or not radius > 0:
        raise ValueError(f"expected a positive 'period' and 'radius', got {period!r}, {radius!r}")
    x, y, z = wm.coords()
    k = 2 * math.pi / period
    g = wm.sin(k * x) * wm.cos(k * y) + wm.sin(k * y) * wm.cos(k * z) + wm.sin(k * z) * wm.cos(k * x)
    r = 1.1 * radius
    return wm.Shape(g * (1.0 / k)) & wm.sphere(radius), ((-r,) * 3, (r,) * 3)


def case_shape(name):
    """(shape, bounds) of a case: ``wm.example(name)``, or :func:`gyroid_ball`. 'degree6' is
    the degree-six solid clipped by its box [-3, 3]^3 (``mesh_domain`` closes it by caps)."""
    if name == "gyroid_ball":
        return gyroid_ball()
    return wm.example(name)


def grid_volume(shape, bounds, n: int = GRID_VOLUME_N) -> float:
    """Volume of {f > 0} in ``bounds`` from the sign of f at one random point in each cell of
    an n^3 grid (stratified sampling, seed 0: unbiased, where cell centres are biased by faces
    parallel to the grid); the reference of the cases with no closed form, checked on the exact
    ones in the run.

    >>> round(grid_volume(wm.sphere(1.0), ((-1.2,) * 3, (1.2,) * 3), 64) / (4 / 3 * math.pi), 2)
    1.0
    """
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    d = (hi - lo) / n
    ax = [lo[a] + (np.arange(n) + 0.5) * d[a] for a in range(3)]
    yz = np.stack(np.meshgrid(ax[1], ax[2], indexing="ij"), -1).reshape(-1, 2)
    inside, step, rng = 0, max(1, 2_000_000 // len(yz)), np.random.default_rng(0)
    for i in range(0, n, step):
        xs = ax[0][i:i + step]
        pts = np.concatenate([np.repeat(xs, len(yz))[:, None], np.tile(yz, (len(xs), 1))], axis=1)
        pts += (rng.random(pts.shape) - 0.5) * d
        inside += int((wm.evaluate(shape, pts) > 0).sum())
    return inside * float(np.prod(d))


def positive(points, tets):
    """(tets positive where the tool wound them the other way, count still not positive)."""
    tets = np.asarray(tets, dtype=np.int64)
    v = signed_volumes(points, tets)
    if (v < 0).sum() > len(v) // 2:  # a tool whose convention is the other winding (fTetWild)
        tets, v = tets[:, [0, 1, 3, 2]], -v
    return tets, int((v <= 0).sum())


def boundary_distance(shape, box, points, tets, h) -> float:
    """Largest |f| / |grad f| over the boundary vertices of ``tets`` off the box's faces (within
    0.1 h of one: fTetWild moves its vertices up to its envelope), / h."""
    idx = np.unique(boundary_faces(tets))
    p = np.asarray(points, dtype=np.float64)[idx]
    tol = 0.1 * h
    p = p[~((np.abs(p - box[0]) <= tol) | (np.abs(p - box[1]) <= tol)).any(axis=1)]
    if not len(p):
        return 0.0
    f, g = value_gradient_at(tape_of(shape), p)
    gn = np.linalg.norm(g, axis=1)
    return float(np.max(np.abs(f) / np.where(gn > 0, gn, np.inf))) / h


def quality(points, tets, shape=None, box=None, h=None, volume=None) -> dict:
    """Count, dihedral range (degrees), radius-edge max and 99th percentile, non-positive count
    and, given the case, the volume error against ``volume`` and the boundary distance / h."""
    tets, neg = positive(points, tets)
    ang = np.degrees(dihedral_angles(points, tets))
    re = radius_edge_ratio(points, tets)
    q = {"tets": len(tets), "dmin": float(ang.min()), "dmax": float(ang.max()), "re": float(re.max()),
         "re99": float(np.percentile(re, 99)), "neg": neg}
    if volume is not None:
        q["verr"] = float(signed_volumes(points, tets).sum() / volume - 1)
    if shape is not None:
        q["bdist"] = boundary_distance(shape, np.asarray(box, dtype=np.float64), points, tets, h)
    return q


def timed(fn):
    """(wall s, CPU s of the process, fn's result)."""
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return time.perf_counter() - w0, time.process_time() - c0, out


def best_of(fn, repeat):
    """The fastest (wall) of ``repeat`` timed runs of ``fn``: (wall, CPU, result)."""
    best = None
    for _ in range(max(1, repeat)):
        out = timed(fn)
        if best is None or out[0] < best[0]:
            best = out
    return best


# -- the tools --------------------------------------------------------------------------------------
def run_warpmesh(name, size, smooth=0, features=True, flips=False, method="stuffing"):
    """(wall s, points, tets, Mesh) of ``wm.mesh_domain`` on a case."""
    shape, bounds = case_shape(name)
    t0 = time.perf_counter()
    vol = wm.mesh_domain(shape, bounds=bounds, size=size, smooth=smooth, features=features, flips=flips,
                         method=method)
    dt = time.perf_counter() - t0
    return dt, vol.points, vol.cells["tetra"], vol


def optimised_surface(name, edge):
    """(points, triangles) of warpmesh's optimised surface of a case, edges about ``edge``:
    ``mesh_surface`` (closed by caps on the bounds) then ``optimize`` on the exact shape, as
    ``mesh_domain(method="tetgen")`` makes it. Fresh writable arrays (the native peers want them)."""
    shape, bounds = case_shape(name)
    box = np.asarray(bounds, dtype=np.float64)
    surf = wm.mesh_surface(shape, bounds=box, resolution=int(math.ceil(float(np.max(box[1] - box[0])) / edge)),
                           cap=True)
    surf = optimize(surf, shape, bounds=box, size=edge)
    return np.array(surf.points, dtype=np.float64), np.array(surf.cells["triangle"], dtype=np.int32)


def _gmsh_model(name, surface):
    if surface is not None:  # a surface loop from the triangles: gmsh fills it as given
        pts, tris = surface
        s = gmsh.model.addDiscreteEntity(2)
        gmsh.model.mesh.addNodes(2, s, np.arange(1, len(pts) + 1), pts.ravel())
        gmsh.model.mesh.addElementsByType(s, 2, [], (tris.astype(np.int64) + 1).ravel())
        gmsh.model.geo.addVolume([gmsh.model.geo.addSurfaceLoop([s])])
        gmsh.model.geo.synchronize()
        return
    occ = gmsh.model.occ
    if name == "sphere":
        occ.addSphere(0, 0, 0, 1.0)
    elif name == "torus":
        occ.addTorus(0, 0, 0, 1.0, 0.35)
    else:
        plate = occ.addBox(-1, -1, -0.3, 2, 2, 0.6)
        holes = [occ.addCylinder(sx * 0.6, sy * 0.6, -1, 0, 0, 2, 0.2) for sx in (-1, 1) for sy in (-1, 1)]
        cut, _ = occ.cut([(3, plate)], [(3, h) for h in holes])
        ball = occ.addSphere(0, 0, 0, 0.5)
        occ.fuse(cut, [(3, ball)])
    occ.synchronize()


def run_gmsh(name, size, surface=None):
    """(points, tets) of gmsh's 3D Delaunay on the OCC solid, or on ``surface`` (a surface loop)."""
    gmsh.initialize(["-nt", "1"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.add(name)
        _gmsh_model(name, surface)
        gmsh.option.setNumber("Mesh.MeshSizeMin", size)
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.model.mesh.generate(3)
        tags, coords, _ = gmsh.model.mesh.getNodes()
        pts = np.zeros((int(tags.max()) + 1, 3))
        pts[tags.astype(np.int64)] = coords.reshape(-1, 3)
        types, _, nodes = gmsh.model.mesh.getElements(3)
        tets = np.concatenate([n.reshape(-1, 4) for t, n in zip(types, nodes) if t == 4]).astype(np.int64)
    finally:
        gmsh.finalize()
    return pts, tets


def run_tetgen(surface_points, surface_tris, max_volume):
    """(points, tets) of TetGen on the surface, quality switches, ``maxvolume`` (with
    ``fixedvolume=True``, the -a switch: tetgen 0.8 ignores ``maxvolume`` without it)."""
    tg = tetgen.TetGen(surface_points, surface_tris.astype(np.int32))
    nodes, elems, *_ = tg.tetrahedralize(order=1, quality=True, minratio=1.5, mindihedral=10.0,
                                         maxvolume=max_volume, fixedvolume=True, steinerleft=10_000_000,
                                         quiet=True)
    return np.asarray(nodes), np.asarray(elems, dtype=np.int64)


def kuhn_box(box, spacing):
    """(points, tets) of a box cut into cubes of about ``spacing``, six Kuhn tetrahedra each
    (the background mesh of mmg's level-set mode), positive.

    >>> p, t = kuhn_box(np.array([[0.0] * 3, [1.0] * 3]), 0.5)
    >>> len(p), len(t), bool((signed_volumes(p, t) > 0).all())
    (27, 48, True)
    """
    lo, hi = box
    nn = np.maximum(1, np.round((hi - lo) / spacing).astype(np.int64))
    ax = [np.linspace(lo[a], hi[a], nn[a] + 1) for a in range(3)]
    pts = np.stack(np.meshgrid(*ax, indexing="ij"), -1).reshape(-1, 3)
    ids = np.arange(len(pts)).reshape(tuple(nn + 1))
    corner = np.stack([ids[i:i + nn[0], j:j + nn[1], k:k + nn[2]].ravel()
                       for i in (0, 1) for j in (0, 1) for k in (0, 1)], axis=1)  # corner (i, j, k) at 4i+2j+k
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):  # paths 0 -> 7
        step, path = [0, 0, 0], [0]
        for a in perm:
            step[a] = 1
            path.append(4 * step[0] + 2 * step[1] + step[2])
        tets.append(corner[:, path])
    tets = np.concatenate(tets)
    neg = signed_volumes(pts, tets) < 0
    tets[neg] = tets[neg][:, [0, 1, 3, 2]]
    return pts, tets


def run_mmg(name, hsiz, spacing):
    """(points, inside tets, all tets) of mmg3d's level-set mode (mmgpy): the box in Kuhn
    tetrahedra of cube side ``spacing``, -f at its vertices (mmg's inside is negative), then
    ``remesh_levelset(hsiz=hsiz, hausd=hsiz / 10)`` (mmg's default hausd 0.01 is absolute: far
    too fine on degree6's 6-wide box); the inside is ref 3. Timed from the box to the result."""
    shape, bounds = case_shape(name)
    pts, tets = kuhn_box(np.asarray(bounds, dtype=np.float64), spacing)
    f = wm.evaluate(shape, pts).astype(np.float64)
    mesh = PEERS["mmgpy"].MmgMesh3D(np.ascontiguousarray(pts), np.ascontiguousarray(tets, dtype=np.int32))
    mesh.remesh_levelset(np.ascontiguousarray(-f[:, None]), hsiz=hsiz, hausd=hsiz / 10, verbose=-1)
    out, refs = mesh.get_tetrahedra_with_refs()
    return mesh.get_vertices(), np.asarray(out[refs == 3], dtype=np.int64), len(out)


def run_tetwild(surface_points, surface_tris, edge):
    """(points, tets) of fTetWild (pytetwild) on the surface, ideal edge ``edge``, one thread."""
    v, t = PEERS["pytetwild"].tetrahedralize(surface_points, surface_tris, edge_length_abs=edge, num_threads=1,
                                             quiet=True)
    return np.asarray(v), np.asarray(t, dtype=np.int64)


# -- calibration --------------------------------------------------------------------------------------
def calibrate(count, size, target):
    """A size giving about ``target`` tetrahedra (count ~ size^-3) from one run of ``count``
    at twice ``size`` (an eighth of the work)."""
    n = count(2 * size)
    return 2 * size * (n / target) ** (1.0 / 3.0)


def reference_volume(name) -> tuple[float, str]:
    """(volume, where from): exact where known, else :func:`grid_volume`."""
    if name in EXACT_VOLUME:
        return EXACT_VOLUME[name], "exact"
    return grid_volume(*case_shape(name)), f"{GRID_VOLUME_N}^3-grid estimate"


COLUMNS = ("| case | tool | tets | wall s | CPU s | tets/s (wall) | dihedral min | dihedral max | radius-edge max "
           "/ p99 | volume error | boundary distance / h | stuffing's tets/s / tool's (wall; CPU) | notes |")


def emit(rows, case, tool, timing=None, q=None, stuffing=None, note=""):
    """Print and keep one row; ``timing`` (wall, CPU) and ``q`` (:func:`quality`) None: ``note`` says why."""
    if q is None:
        rows.append({"case": case, "tool": tool, "note": note})
        print(f"| {case} | {tool} | {note} |" + " - |" * 10, flush=True)
        return None
    wall, cpu = timing
    row = {"case": case, "tool": tool, "wall": wall, "cpu": cpu, **q, "tets_per_s": q["tets"] / wall, "note": note}
    if stuffing is not None:
        row["ratio_wall"] = stuffing["tets_per_s"] / row["tets_per_s"]
        row["ratio_cpu"] = (stuffing["tets"] / stuffing["cpu"]) / (q["tets"] / cpu)
    ratio = "1 (itself)" if stuffing is None else f"{row['ratio_wall']:.1f}x; {row['ratio_cpu']:.1f}x"
    neg = f"; {q['neg']} tets not positive" if q["neg"] else ""
    rows.append(row)
    print(f"| {case} | {tool} | {q['tets']:,} | {wall:.2f} | {cpu:.2f} | {row['tets_per_s'] / 1e3:,.0f} k | "
          f"{q['dmin']:.2f} | {q['dmax']:.2f} | {q['re']:.3g} / {q['re99']:.2f} | {q['verr']:+.3%} | "
          f"{q['bdist']:.2g} | {ratio} | {note}{neg} |", flush=True)
    return row


def run_case(name, target, repeat, rows, variants=True, peers=PEER_NAMES):
    """All the rows of one case at about ``target`` tetrahedra (the peers named in ``peers``)."""
    shape, bounds = case_shape(name)
    box = np.asarray(bounds, dtype=np.float64)
    vol0, vsrc = reference_volume(name)
    case = f"{name} ~{target / 1e6:g} M" if target >= 1e6 else f"{name} ~{target // 1000} k"
    edge = (6 * math.sqrt(2) * vol0 / target) ** (1 / 3)  # the regular tetrahedron's edge at the target count

    def measure(p, k, h):
        return quality(p, k, shape=shape, box=box, h=h, volume=vol0)

    def failed(tool, exc):
        print(f"{tool} failed on {case}: {type(exc).__name__}: {exc}", flush=True)
        emit(rows, case, tool, note=f"failed: {type(exc).__name__}: {str(exc)[:80]}")

    # warpmesh stuffing: the reference row (best of ``repeat`` warm runs)
    h_wm = calibrate(lambda h: len(run_warpmesh(name, h)[2]), (12 * vol0 / target) ** (1 / 3), target)
    run_warpmesh(name, h_wm)  # warm
    wall, cpu, (_, p_wm, k_wm, vol) = best_of(lambda: run_warpmesh(name, h_wm), repeat)
    s = vol.stats()
    edges = ""
    if name == "part":  # distance from the exact sharp edges to the nearest boundary edge, / size
        d = feature_distance(vol.points, vol.cells["triangle"], example_edges("part", 200)) / h_wm
        edges = f"; edge distance max {d.max():.3f} h, {100 * (d <= 0.05).mean():.1f} % within 0.05 h"
    stuffing = emit(rows, case, "warpmesh stuffing", (wall, cpu), measure(p_wm, k_wm, h_wm), None,
                    f"size h {h_wm:.4f}; evaluate {s['time_evaluate']:.2f} s, roots {s['time_roots']:.2f} s, fill "
                    f"{s['time_fill']:.2f} s, features {s.get('time_features', 0.0):.2f} s; volume {vsrc}{edges}")
    if variants:  # one run each
        w, c, (_, p, k, _) = timed(lambda: run_warpmesh(name, h_wm, features=False))
        emit(rows, case, "warpmesh stuffing, features=False", (w, c), measure(p, k, h_wm), stuffing,
             "no crease recovery")
        w, c, (_, p, k, _) = timed(lambda: run_warpmesh(name, h_wm, smooth=2, flips=True))
        emit(rows, case, "warpmesh stuffing + smooth=2 + flips", (w, c), measure(p, k, h_wm), stuffing,
             "smoothing and 2-3/3-2/4-4 flips never lower the smallest angle")
        w, c, (_, p, k, v) = timed(lambda: run_warpmesh(name, "curvature"))
        i = v.info
        emit(rows, case, "warpmesh stuffing, size='curvature' (graded)", (w, c), measure(p, k, h_wm), stuffing,
             f"its own count; sizes {i['size_smallest']:.4f}-{i['size_largest']:.4f}, background "
             f"{i['background_tets']:,} tets graded in {i['time_grade']:.2f} s")
        h_dl = calibrate(lambda h: len(run_warpmesh(name, h, method="delaunay")[2]), h_wm, target)
        w, c, (_, p, k, v) = timed(lambda: run_warpmesh(name, h_dl, method="delaunay"))
        i = v.stats()
        emit(rows, case, "warpmesh delaunay", (w, c), measure(p, k, h_wm), stuffing,
             f"size {h_dl:.4f}; points {i['time_points']:.2f} s, Qhull {i['time_delaunay']:.2f} s in "
             f"{i['delaunay_rounds']} rounds, optimise {i['time_optimise']:.2f} s")
    # gmsh: the OCC solid, calibrated; else a surface loop of warpmesh's optimised surface
    surface = []  # made once, when a peer first needs it

    def get_surface():
        if not surface:
            w, c, st = timed(lambda: optimised_surface(name, edge))
            surface.extend([st, f"warpmesh's optimised surface ({len(st[1]):,} triangles, edge {edge:.4f}, "
                                f"made in {w:.1f} s, not counted)"])
        return surface
    tool = "gmsh (OCC, Delaunay 3D)" if name in OCC_CASES else "gmsh (surface loop, Delaunay 3D)"
    if "gmsh" not in peers:
        pass
    elif "gmsh" in MISSING:
        emit(rows, case, tool, note=f"not installed ({MISSING['gmsh']})")
    else:
        try:
            if name in OCC_CASES:
                h_gm = calibrate(lambda h: len(run_gmsh(name, h)[1]), edge, target)
                w, c, (p, k) = best_of(lambda: run_gmsh(name, h_gm), repeat)
                note = f"mesh size {h_gm:.4f}, one thread"
            else:
                st, snote = get_surface()
                w, c, (p, k) = best_of(lambda: run_gmsh(name, edge, st), repeat)
                note = f"mesh size {edge:.4f}, one thread, on {snote}"
            gm = emit(rows, case, tool, (w, c), measure(p, k, h_wm), stuffing, note)
            if name == "sphere":
                print(f"speed acceptance, ball {case}: stuffing {gm['ratio_wall']:.1f}x gmsh's tets/s by wall, "
                      f"{gm['ratio_cpu']:.1f}x by CPU (target >= 10x at ~1 M); smallest dihedral "
                      f"{stuffing['dmin']:.2f} vs {gm['dmin']:.2f} deg (target: better)", flush=True)
        except Exception as exc:  # noqa: BLE001 - a peer refusing an input is a row, not the end of the run
            failed(tool, exc)
    # TetGen on the optimised surface: a maximum volume for about the same count (calibrated once)
    tool = "TetGen (on warpmesh's optimised surface)"
    if "tetgen" not in peers:
        pass
    elif "tetgen" in MISSING:
        emit(rows, case, tool, note=f"not installed ({MISSING['tetgen']})")
    else:
        try:
            st, snote = get_surface()
            a0 = vol0 / target
            a = a0 * len(run_tetgen(*st, a0)[1]) / target
            w, c, (p, k) = best_of(lambda: run_tetgen(*st, a), repeat)
            emit(rows, case, tool, (w, c), measure(p, k, h_wm), stuffing,
                 f"minratio 1.5, mindihedral 10, maxvolume {a:.2e}; on {snote}")
        except Exception as exc:  # noqa: BLE001
            failed(tool, exc)
    # mmg3d's level-set discretisation of f on a Kuhn background of the box (one run)
    tool = "mmg3d level-set (mmgpy)"
    if "mmgpy" not in peers:
        pass
    elif "mmgpy" in MISSING:
        emit(rows, case, tool, note=f"not installed ({MISSING['mmgpy']})")
    else:
        try:
            # the background samples f as finely as stuffing's lattice (h); calibrated at 2 h
            hs = calibrate(lambda h: len(run_mmg(name, h, h_wm * h / edge)[1]), edge, target)
            w, c, (p, k, total) = timed(lambda: run_mmg(name, hs, h_wm))
            emit(rows, case, tool, (w, c), measure(p, k, h_wm), stuffing,
                 f"hsiz {hs:.4f}, hausd hsiz / 10, on Kuhn cubes of side h, one run; the whole box remeshed: {total:,} tets, "
                 f"the {len(k):,} inside counted; timed from the background and f on it")
        except Exception as exc:  # noqa: BLE001
            failed(tool, exc)
    # fTetWild on the optimised surface (one run, one thread)
    tool = "fTetWild (pytetwild, on warpmesh's optimised surface)"
    if "pytetwild" not in peers:
        pass
    elif "pytetwild" in MISSING:
        emit(rows, case, tool, note=f"not installed ({MISSING['pytetwild']})")
    else:
        try:
            st, snote = get_surface()
            el = calibrate(lambda e: len(run_tetwild(*st, e)[1]), edge, target)
            w, c, (p, k) = timed(lambda: run_tetwild(*st, el))
            emit(rows, case, tool, (w, c), measure(p, k, h_wm), stuffing,
                 f"edge_length_abs {el:.4f}, one run, one thread; on {snote}")
        except Exception as exc:  # noqa: BLE001
            failed(tool, exc)


def _sizes(text: str) -> list[int]:
    out = []
    for item in text.split(","):
        item = item.strip()
        if item in SIZE_CLASSES:
            out.append(SIZE_CLASSES[item])
        elif item.isdigit() and int(item) >= 1000:
            out.append(int(item))
        else:
            raise argparse.ArgumentTypeError(f"expected size classes from {list(SIZE_CLASSES)} or tet counts "
                                             f">= 1000, comma-separated; got {item!r}")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=_sizes, default=[100_000],
                    help="size classes: 100k, 1M or tet counts, comma-separated (default 100k)")
    ap.add_argument("--large", action="store_true", help="add the 1M class (same as --sizes 100k,1M)")
    ap.add_argument("--repeat", type=int, default=3, help="warm runs of stuffing, gmsh and TetGen (best kept); "
                    "classes above 200 k run once")
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--variants", action=argparse.BooleanOptionalAction, default=True,
                    help="the warpmesh variant rows (features=False, smooth+flips, graded, delaunay), classes "
                    "up to 200 k only")
    ap.add_argument("--peers", default=",".join(PEER_NAMES),
                    help=f"the peers to run, comma-separated, from {','.join(PEER_NAMES)} (default all)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--default-malloc", action="store_true")
    args = ap.parse_args()
    peers = tuple(args.peers.split(",")) if args.peers else ()
    for peer in peers:
        if peer not in PEER_NAMES:
            raise SystemExit(f"unknown peer {peer!r} in '--peers'; pick from {PEER_NAMES}")
    names = args.cases.split(",")
    for name in names:
        if name not in CASES:
            raise SystemExit(f"unknown case {name!r} in '--cases'; pick from {CASES}")
    targets = sorted(set(args.sizes + ([1_000_000] if args.large else [])))
    t_start = time.perf_counter()
    load0 = _report.load_banner(
        f"bench_domain: warpmesh {wm.__version__}, gmsh {_report.version('gmsh')}, tetgen {_report.version('tetgen')}, "
        f"mmgpy {_report.version('mmgpy')}, pytetwild {_report.version('pytetwild')}, warp {wp.__version__}, "
        f"{os.cpu_count()} cores")
    if any(n not in EXACT_VOLUME for n in names):  # the fine-grid estimate's own error, where the answer is known
        print("fine-grid volume estimate against the exact volume: " + ", ".join(
            f"{n} {grid_volume(*case_shape(n)) / EXACT_VOLUME[n] - 1:+.4%}" for n in EXACT_VOLUME))
    rows = []
    print("\n" + COLUMNS)
    print("|" + " --- |" * (COLUMNS.count("|") - 1))
    for target in targets:
        for name in names:
            run_case(name, target, args.repeat if target <= 200_000 else 1, rows,
                     variants=args.variants and target <= 200_000, peers=peers)
    _report.finish(t_start, load0, args.json, {"rows": rows, "missing": MISSING})


if __name__ == "__main__":
    main()
