"""Triangle meshes of planar implicit domains {f > 0} [FG §16.5.2]: global approach and
the `triangle` cross-check.

Boundaries are built here, independently of the curve samplers: exact parametrisations
of circles and rectangles, and for the CSG examples a marching-squares-like polyline
(sign changes of ``field.grid``, one vertex per crossing edge projected onto f = 0).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.domain.delaunay import classify, delaunay, min_angles
from warpmesh.planar.domain.pipeline import mesh_domain_from_boundary
from warpmesh.planar.domain.smoothing import smooth
from warpmesh.errors import WarpMeshError
from warpmesh.cells.intersections import find_segment_intersections
from warpmesh.planar.polyline import components, weld
from warpmesh.cells.quality import triangle_quality


# -- boundaries ---------------------------------------------------------------------------
def loop(pts: np.ndarray, offset: int = 0) -> np.ndarray:
    idx = np.arange(len(pts)) + offset
    return np.column_stack([idx, np.roll(idx, -1)])


def circle_pts(r, n, center=(0.0, 0.0), clockwise=False):
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    if clockwise:
        t = -t
    return np.column_stack([center[0] + r * np.cos(t), center[1] + r * np.sin(t)])


def square_pts(half, per_side):
    s = np.linspace(-half, half, per_side + 1)[:-1]
    return np.concatenate([np.column_stack([s, np.full_like(s, -half)]),
                           np.column_stack([np.full_like(s, half), s]),
                           np.column_stack([-s, np.full_like(s, half)]),
                           np.column_stack([np.full_like(s, -half), -s])])


def grid_boundary(field: PlanarField, n: int):
    """Closed polyline of f = 0 from the sign changes of an n-cell grid (longer side): a
    vertex per crossing edge (linear root, then Newton projection), a segment per pair of
    crossings in a cell (saddles paired by f at the centre), the inside on the left."""
    ext = field.bounds[1] - field.bounds[0]
    step = ext.max() / n
    nx, ny = int(np.ceil(ext[0] / step)), int(np.ceil(ext[1] / step))
    xs, ys, f = field.grid(nx, ny)
    ins = f > 0
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)

    def crossings(fa, fb, pa, pb, ia, ib):
        cross = ia != ib
        t = np.clip(fa / np.where(cross, fa - fb, 1.0), 1e-3, 1 - 1e-3)
        return cross, pa + t[..., None] * (pb - pa), np.where(ia[..., None], pa, pb)

    cx, vx, inx = crossings(f[:-1], f[1:], grid[:-1], grid[1:], ins[:-1], ins[1:])
    cy, vy, iny = crossings(f[:, :-1], f[:, 1:], grid[:, :-1], grid[:, 1:], ins[:, :-1], ins[:, 1:])
    idx_x = np.full(cx.shape, -1)
    idx_x[cx] = np.arange(cx.sum())
    idx_y = np.full(cy.shape, -1)
    idx_y[cy] = np.arange(cy.sum()) + cx.sum()
    verts = np.concatenate([vx[cx], vy[cy]])
    inner_end = np.concatenate([inx[cx], iny[cy]])
    # cell edges in order bottom, right, top, left
    cell = np.stack([idx_x[:, :-1], idx_y[1:, :], idx_x[:, 1:], idx_y[:-1, :]], axis=-1).reshape(-1, 4)
    count = (cell >= 0).sum(axis=1)
    segs = [np.sort(cell[count == 2], axis=1)[:, 2:]]
    four = np.flatnonzero(count == 4)
    if len(four):
        ci, cj = np.unravel_index(four, (nx, ny))
        centre = field.values(np.column_stack([0.5 * (xs[ci] + xs[ci + 1]), 0.5 * (ys[cj] + ys[cj + 1])])) > 0
        e = cell[four]
        joined = (ins[ci, cj] == centre)[:, None]  # bottom-left corner joined to the centre
        pairs = np.where(joined, e[:, [0, 3, 1, 2]], e[:, [0, 1, 2, 3]])
        segs += [pairs[:, :2], pairs[:, 2:]]
    s = np.concatenate(segs)
    a, b = verts[s[:, 0]], verts[s[:, 1]]
    ref = 0.5 * (inner_end[s[:, 0]] + inner_end[s[:, 1]]) - a
    d = b - a
    s = np.where(((d[:, 0] * ref[:, 1] - d[:, 1] * ref[:, 0]) > 0)[:, None], s, s[:, ::-1])
    pts, s = weld(verts, s, 0.1 * step)
    return field.project(pts, max_step=step), s


# -- checks ----------------------------------------------------------------------------
def check_domain_mesh(p, tris, holes: int):
    """Positive areas, conforming (interior edges in two triangles, once each way;
    boundary edges in one), every vertex used, Euler V - E + F = 1 - holes and as many
    boundary loops as 1 + holes. Returns the boundary vertex indices."""
    assert np.all(np.isfinite(p)) and tris.min() >= 0 and tris.max() < len(p)
    u, v = p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]
    area2 = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    assert np.all(area2 > 0), "every triangle counter-clockwise"
    assert len(np.unique(tris)) == len(p), "every vertex used"
    n = len(p)
    a, b = tris.ravel(), tris[:, [1, 2, 0]].ravel()
    directed = a * n + b
    assert len(np.unique(directed)) == len(directed), "no directed edge twice (consistent, manifold)"
    key = np.minimum(a, b) * n + np.maximum(a, b)
    uniq, count = np.unique(key, return_counts=True)
    assert set(np.unique(count)) <= {1, 2}
    assert len(p) - len(uniq) + len(tris) == 1 - holes, "Euler characteristic"
    once = np.isin(key, uniq[count == 1])
    bseg = np.column_stack([a[once], b[once]])
    loops, _ = components(bseg, n)
    assert loops == 1 + holes
    return np.unique(bseg)


def bad_angle(p, tris):
    return float(min_angles(p, tris)[0].min())


# -- the global approach ------------------------------------------------------------------
def test_disc_area_positive_boundary_on_circle():
    r, c = 0.8, (0.1, -0.2)
    field = PlanarField(wm.circle(r, c), ((-1, -1.1), (1.2, 0.9)))
    bp = circle_pts(r, 96, c)
    p, tris, info = mesh_domain_from_boundary(field, bp, loop(bp))
    bnd = check_domain_mesh(p, tris, holes=0)
    assert abs(info["area"] - np.pi * r * r) < 2e-3 * np.pi * r * r
    assert np.max(np.abs(np.linalg.norm(p[bnd] - c, axis=1) - r)) < 1e-5
    assert info["min_angle"] >= 28.0 and info["min_angle"] == pytest.approx(bad_angle(p, tris))
    assert info["np"] == len(p) and info["ne"] == len(tris) and info["converged"]
    q = triangle_quality(p, tris)
    assert info["worst_q"] == pytest.approx(q.max()) and 1.0 <= info["mean_q"] < 1.3
    assert info["boundary_distance_max"] < 1e-5


def test_square_with_hole():
    field = PlanarField(wm.rectangle((2.0, 2.0)) - wm.circle(0.45), ((-1.1, -1.1), (1.1, 1.1)))
    outer = square_pts(1.0, 16)
    hole = circle_pts(0.45, 40, clockwise=True)
    pts = np.concatenate([outer, hole])
    segs = np.concatenate([loop(outer), loop(hole, len(outer))])
    p, tris, info = mesh_domain_from_boundary(field, pts, segs, size=0.2)
    bnd = check_domain_mesh(p, tris, holes=1)
    assert info["min_angle"] >= 28.0
    # between the exact area and that of the square minus the inscribed 40-gon
    exact, polygon = 4.0 - np.pi * 0.45**2, 4.0 - 20 * 0.45**2 * np.sin(2 * np.pi / 40)
    assert exact - 1e-9 < info["area"] < polygon + 1e-9
    on_hole = np.abs(np.linalg.norm(p[bnd], axis=1) - 0.45) < 1e-5
    on_square = np.abs(np.abs(p[bnd]).max(axis=1) - 1.0) < 1e-9
    assert np.all(on_hole | on_square)
    assert info["boundary_distance_max"] < 1e-5
    assert np.all(np.abs(p).max(axis=1) <= 1.0 + 1e-12)


@pytest.mark.parametrize("name, n, holes", [("plate", 140, 5), ("gear", 160, 6)])
def test_csg_domains(name, n, holes):
    shape, bounds = wm.example(name)
    field = PlanarField(shape, bounds)
    bp, bs = grid_boundary(field, n)
    assert len(find_segment_intersections(bp, bs)) == 0
    p, tris, info = mesh_domain_from_boundary(field, bp, bs)
    bnd = check_domain_mesh(p, tris, holes=holes)
    assert info["min_angle"] >= 28.0  # acceptance: >= 25
    assert info["worst_q"] < 2.5 and info["mean_q"] < 1.3
    assert field.distance(p[bnd]).max() < 1e-5 and field.estimate(p[bnd]).max() < 1e-5
    assert info["boundary_distance_max"] < 1e-5
    # no vertex outside the domain (f >= 0 up to the boundary tolerance)
    assert np.all(field.values(p) > -1e-5)


def test_graded_size_finer_near_boundary():
    r = 1.0
    field = PlanarField(wm.circle(r), ((-1.1, -1.1), (1.1, 1.1)))
    bp = circle_pts(r, 400)
    h_b = 2 * np.pi * r / 400
    p, tris, info = mesh_domain_from_boundary(field, bp, loop(bp), size=0.3, gradation=1.5)
    check_domain_mesh(p, tris, holes=0)
    e = np.linalg.norm(p[tris[:, [1, 2, 0]]] - p[tris], axis=2).mean(axis=1)
    radius = np.linalg.norm(p[tris].mean(axis=1), axis=1)
    near, centre = e[radius > 0.97], e[radius < 0.4]
    assert near.mean() < 1.5 * h_b
    assert centre.mean() > 6 * near.mean()
    assert centre.max() <= 1.5 * 0.3  # capped by size
    uniform = np.pi * r * r / (np.sqrt(3) / 4 * h_b**2)  # triangles of a uniform mesh at h_b
    assert info["ne"] < uniform / 4
    assert info["min_angle"] >= 28.0


def test_smoothing_never_lowers_min_angle():
    field = PlanarField(wm.ellipse((1.0, 0.5)), ((-1.2, -0.7), (1.2, 0.7)))
    t = np.linspace(0, 2 * np.pi, 120, endpoint=False)
    bp = field.project(np.column_stack([np.cos(t), 0.5 * np.sin(t)]))
    p0, t0, i0 = mesh_domain_from_boundary(field, bp, loop(bp), optimize=False)
    p1, t1, i1 = mesh_domain_from_boundary(field, bp, loop(bp), optimize=True)
    assert np.array_equal(t0, t1) and i1["smoothing_moves"] > 0
    assert i1["min_angle"] >= i0["min_angle"] and i1["mean_q"] < i0["mean_q"]
    assert np.array_equal(p0[~np.isin(np.arange(len(p0)), t0)], p1[~np.isin(np.arange(len(p1)), t1)])


def test_smooth_fixes_boundary_and_keeps_orientation():
    rng = np.random.default_rng(3)
    g = np.stack(np.meshgrid(np.linspace(0, 1, 8), np.linspace(0, 1, 8)), -1).reshape(-1, 2)
    inner = (g.min(axis=1) > 0) & (g.max(axis=1) < 1)
    g[inner] += rng.uniform(-0.05, 0.05, (inner.sum(), 2))
    tris, _ = delaunay(g)
    new = smooth(g, tris, inner)
    assert np.array_equal(new[~inner], g[~inner])
    assert bad_angle(new, tris) >= bad_angle(g, tris)


def test_classify_nested_loops():
    # square, square hole, island inside the hole: the island is inside
    outer, hole, island = square_pts(1.0, 2), square_pts(0.6, 2)[::-1], square_pts(0.3, 2)
    pts = np.concatenate([outer, hole, island])
    segs = np.concatenate([loop(outer), loop(hole, 8), loop(island, 16)])
    tris, _ = delaunay(pts)
    inside = classify(tris, segs, len(pts))
    c = pts[tris].mean(axis=1)
    ring = np.abs(c).max(axis=1)
    assert np.array_equal(inside, (ring > 0.6) | (ring < 0.3))
    with pytest.raises(WarpMeshError, match="oriented"):
        classify(tris, np.concatenate([loop(outer), loop(hole, 8)[:, ::-1], loop(island, 16)]), len(pts))


def test_clockwise_only_boundary_is_an_error():
    field = PlanarField(wm.circle(1.0), ((-1.1, -1.1), (1.1, 1.1)))
    bp = circle_pts(1.0, 40, clockwise=True)
    with pytest.raises(WarpMeshError, match="LEFT"):
        mesh_domain_from_boundary(field, bp, loop(bp))


# -- the triangle cross-check ---------------------------------------------------------------
@pytest.mark.parametrize("name, n, holes", [("plate", 120, 5), ("gear", 140, 6)])
def test_triangle_cross_check(name, n, holes):
    pytest.importorskip("triangle")
    shape, bounds = wm.example(name)
    field = PlanarField(shape, bounds)
    bp, bs = grid_boundary(field, n)
    pg, tg, ig = mesh_domain_from_boundary(field, bp, bs, method="global")
    pt, tt, it = mesh_domain_from_boundary(field, bp, bs, method="triangle", min_angle=28.0)
    bnd = check_domain_mesh(pt, tt, holes=holes)
    assert it["min_angle"] >= 28.0 and it["converged"]
    assert abs(ig["area"] - it["area"]) < 0.01 * it["area"]
    assert field.distance(pt[bnd]).max() < 1e-5
    assert it["holes"] >= holes


def test_triangle_disc_area_and_steiner_projection():
    pytest.importorskip("triangle")
    field = PlanarField(wm.circle(1.0), ((-1.1, -1.1), (1.1, 1.1)))
    bp = circle_pts(1.0, 24)  # coarse: Triangle splits boundary segments, we project
    p, tris, info = mesh_domain_from_boundary(field, bp, loop(bp), method="triangle", size=0.1)
    bnd = check_domain_mesh(p, tris, holes=0)
    assert info["steiner_projected"] > 0 and len(bnd) > 24
    assert np.max(np.abs(np.linalg.norm(p[bnd], axis=1) - 1.0)) < 1e-5
    assert abs(info["area"] - np.pi) < 0.01 * np.pi and info["min_angle"] >= 28.0


def test_triangle_missing_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "triangle", None)
    field = PlanarField(wm.circle(1.0), ((-1.1, -1.1), (1.1, 1.1)))
    bp = circle_pts(1.0, 24)
    with pytest.raises(ImportError, match="pip install triangle"):
        mesh_domain_from_boundary(field, bp, loop(bp), method="triangle")


# -- bad input ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def disc():
    field = PlanarField(wm.circle(1.0), ((-1.1, -1.1), (1.1, 1.1)))
    bp = circle_pts(1.0, 24)
    return field, bp, loop(bp)


@pytest.mark.parametrize("kwargs, match", [
    (dict(size=0.0), "size"), (dict(size=-1.0), "size"), (dict(size=float("nan")), "size"),
    (dict(min_angle=0.0), "min_angle"), (dict(min_angle=34.0), "min_angle"),
    (dict(gradation=1.0), "gradation"), (dict(max_points=10), "max_points"),
    (dict(method="advancing-front"), "method"),
])
def test_bad_options(disc, kwargs, match):
    field, bp, bs = disc
    with pytest.raises(ValueError, match=match):
        mesh_domain_from_boundary(field, bp, bs, **kwargs)


def test_bad_boundary(disc):
    field, bp, bs = disc
    with pytest.raises(ValueError, match="segments"):
        mesh_domain_from_boundary(field, bp, np.zeros((0, 2), int))
    with pytest.raises(ValueError, match="points"):
        mesh_domain_from_boundary(field, np.zeros((0, 2)), bs)
    with pytest.raises(ValueError, match="segments"):
        mesh_domain_from_boundary(field, bp, bs[:-1])  # open chain
    with pytest.raises(ValueError, match="segments"):
        mesh_domain_from_boundary(field, bp, bs + 1)  # index out of range
    with pytest.raises(TypeError, match="segments"):
        mesh_domain_from_boundary(field, bp, bs.astype(float))


def test_covering_up_respects_max_points(disc):
    field, bp, bs = disc
    with pytest.raises(WarpMeshError, match="max_points"):
        mesh_domain_from_boundary(field, circle_pts(1.0, 2000), loop(circle_pts(1.0, 2000)), max_points=2100)


def test_boundary_off_the_curve(disc):
    field, bp, bs = disc
    with pytest.raises(ValueError, match="on the curve"):
        mesh_domain_from_boundary(field, 0.5 * bp, bs)


def test_sharp_corner_is_left_alone():
    # a 20-degree sector: its corner angle cannot be improved; refinement still ends
    a = np.radians(20.0)
    field = PlanarField(wm.circle(1.0) & wm.halfplane((0.0, -1.0)) & wm.halfplane((-np.sin(a), np.cos(a))),
                        ((-0.1, -0.1), (1.1, 0.5)))
    t = np.linspace(0, a, 31)
    r = np.linspace(0, 1, 21)[1:-1]
    pts = np.concatenate([[[0.0, 0.0]], np.column_stack([r, 0 * r]), np.column_stack([np.cos(t), np.sin(t)]),
                          np.column_stack([r[::-1] * np.cos(a), r[::-1] * np.sin(a)])])
    p, tris, info = mesh_domain_from_boundary(field, pts, loop(pts), size=0.1)
    check_domain_mesh(p, tris, holes=0)
    assert info["converged"] and info["min_angle"] == pytest.approx(20.0, abs=1e-6)
    ang = min_angles(p, tris)[0]
    at_corner = np.any(np.linalg.norm(p[tris], axis=2) < 1e-12, axis=1)
    assert ang[~at_corner].min() >= 28.0


def test_gear_from_the_curve_mesher():
    # the pipeline's own boundary: the geometric mesh of the quadtree covering-up
    shape, bounds = wm.example("gear")
    field = PlanarField(shape, bounds)
    curve = wm.mesh_curve(shape, bounds, method="quadtree", tolerance=1e-2, size=0.1, hmax=0.1)
    p, tris, info = mesh_domain_from_boundary(field, np.asarray(curve.points), np.asarray(curve.cells["line"]),
                                              size=0.1)
    bnd = check_domain_mesh(p, tris, holes=6)
    assert info["min_angle"] >= 28.0 and info["converged"]
    assert field.distance(p[bnd]).max() < 1e-5
