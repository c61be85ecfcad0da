"""Raw surfaces without slivers: the clearance of linearly placed vertices off the grid nodes.

A root that linear interpolation puts closer than ``delta = NODE_CLEARANCE`` (a fraction of
the edge) to a grid node is moved out to ``delta`` [FG §16.4.2, "dilating"]; nothing else
changes (same classification, same triangles). Every table triangle then has its vertices
inside three distinct edges with t in [delta, 1 - delta], where no triangle can flatten, so
Q_K [FG eq. 16.15] is bounded: the bound is computed here from the tables themselves, then
checked on meshes of every method, covering and on sampled volumes, and the bundled part
goes into TetGen and gmsh as it comes out of ``mesh_surface``.
"""

from __future__ import annotations


import numpy as np
import pytest
import warp as wp
from scipy.spatial import cKDTree
from warpmesh.kernels import block_grid as KB
from warpmesh.kernels.emit import TYPE_DELTA

import warpmesh as wm
from tests.helpers.mesher_clients import GMSH as _GMSH, TETGEN as _TETGEN, run_client
from warpmesh import _conventions as C
from warpmesh.cells.intersections import count_self_intersecting_faces
from warpmesh.cells.quality import triangle_angles, triangle_quality
from warpmesh.frep.tape import tape_of
from warpmesh.surface.block_grid import BlockGrid, check_clearance, method_tables

DELTA = C.NODE_CLEARANCE
#: worst Q_K and smallest angle (degrees) of the tables' triangles over t in [0.05, 0.95] on
#: cubic cells (maximised on a 41^3 grid of each triangle's edge parameters, then by
#: L-BFGS-B; "mt" quads on a 21^4 grid, split as the kernel splits them): about 0.82 / delta
#: and 1.1 / delta. "mc", "mc33": with t free down to EDGE_T_MIN at a lonely node (the same
#: worst Q; the smallest angle 2.379 instead of 2.418). "mc33": its edge triangles (the
#: interior vertices of tunnels are placed otherwise).
BOUND_Q = {"mc": 16.4, "mc33": 16.4, "mt": 23.5}
BOUND_ANGLE = {"mc": 2.37, "mc33": 2.37, "mt": 1.4}


# -- helpers ---------------------------------------------------------------------------------
def _quality(mesh_or_points, faces=None):
    p, f = (mesh_or_points.points, mesh_or_points.triangles) if faces is None else (mesh_or_points, faces)
    return float(triangle_quality(p, f).max()), float(triangle_angles(p, f).min())


def _self_intersecting_faces(points, faces) -> int:
    return int(count_self_intersecting_faces(points, faces))


def _distance_over_h(shape, points, h) -> float:
    fg = wm.evaluate(shape, points, gradient=True).astype(np.float64)
    return float(np.max(np.abs(fg[:, 0]) / np.linalg.norm(fg[:, 1:], axis=1)) / h)


def _extract(shape, bounds, resolution: int, method: str = "mc33", clearance: float = DELTA):
    """The host launch layer as mesh_surface drives it (cubic bounds, a capped grid):
    (points, triangles, edges, grid)."""
    lo, hi = np.asarray(bounds, dtype=np.float64)
    cells = np.full(3, resolution, dtype=np.int64)
    grid = BlockGrid(cells + 1, lo, (hi - lo) / cells, wp.get_device("cpu"))
    tape, timings = tape_of(shape), {}
    grid.cull_shape(tape, True, KB.ALL_FACES, timings)
    grid.sample_shape(tape, True, "interpreter", timings)
    grid.finish_values(KB.ALL_FACES, timings)
    verts, tris, edges = grid.extract(method, KB.ALL_FACES, timings, clearance=clearance)
    return verts.numpy().astype(np.float64) + lo, tris.numpy(), {k: v.numpy() for k, v in edges.items()}, grid


def _run_client(script: str, path) -> int:
    """The number of tetrahedra the mesher made (it must succeed)."""
    n, why = run_client(script, path)
    assert n is not None, why
    return n


# -- the bound, from the tables --------------------------------------------------------------
def _q(a, b, c):
    la, lb, lc = (np.linalg.norm(u - w, axis=-1) for u, w in ((b, c), (c, a), (a, b)))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=-1)
    return C.ALPHA_TRIANGLE * np.maximum(la, np.maximum(lb, lc)) * (la + lb + lc) / (2.0 * area)


def _table_worst_q(method: str, delta: float, n: int = 9) -> float:
    """Worst Q_K of the method's edge triangles over a grid of t in [delta, 1 - delta] per
    vertex ("mt" quads: the better split, as the kernel picks it). "mc", "mc33": an end of
    a vertex's edge that no other edge of the triangle shares may be lonely, so t goes down
    to EDGE_T_MIN there (a superset of what the kernels allow: an upper bound)."""
    tables = method_tables(method, "cpu")
    tab = {name: getattr(tables, name).numpy() for name in ("origin", "tri_count", "tris", "quad_count", "quads")}
    origin = tab["origin"]

    def point(v, t):  # local vertex v at parameter t on its edge, in cell units
        return origin[v, :3][None].astype(np.float64) + t[:, None] * TYPE_DELTA[origin[v, 3]][None]

    def ends(v):
        return tuple(origin[v, :3]), tuple(origin[v, :3] + TYPE_DELTA[origin[v, 3]])

    tris, quads = set(), set()
    for case in range(len(tab["tri_count"])):
        for k in range(tab["tri_count"][case]):
            tri = tuple(int(v) for v in tab["tris"][case, 3 * k:3 * k + 3])
            if max(tri) < 12 or method == "mt":  # "mc33": vertices 12 and up are interior
                tris.add(tri)
        for k in range(tab["quad_count"][case]):
            quads.add(tuple(int(v) for v in tab["quads"][case, 4 * k:4 * k + 4]))
    worst = 0.0
    for tri in tris:
        axes = []
        for i, v in enumerate(tri):
            lo, hi = delta, 1 - delta
            if method != "mt":
                others = {e for j, w in enumerate(tri) if j != i for e in ends(w)}
                lo = lo if ends(v)[0] in others else C.EDGE_T_MIN
                hi = hi if ends(v)[1] in others else 1 - C.EDGE_T_MIN
            axes.append(np.unique(np.r_[np.linspace(lo, hi, n), np.linspace(delta, 1 - delta, n)]))
        t3 = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        worst = max(worst, float(_q(*(point(v, t3[:, i]) for i, v in enumerate(tri))).max()))
    g = np.linspace(delta, 1 - delta, n)
    t4 = np.stack(np.meshgrid(g, g, g, g, indexing="ij"), -1).reshape(-1, 4)
    for quad in quads:
        a, b, c, d = (point(v, t4[:, i]) for i, v in enumerate(quad))
        split = np.minimum(np.maximum(_q(a, b, c), _q(a, c, d)), np.maximum(_q(a, b, d), _q(b, c, d)))
        worst = max(worst, float(split.max()))
    return worst


@pytest.mark.parametrize("method", ["mc", "mc33", "mt"])
def test_tables_give_the_stated_bound(method):
    """Over the tables the worst triangle reaches the bound (within the sampling) and grows
    as 1 / delta; at EDGE_T_MIN alone it is a sliver."""
    worst = _table_worst_q(method, DELTA)
    assert 0.97 * BOUND_Q[method] < worst <= BOUND_Q[method]
    assert _table_worst_q(method, 2 * DELTA, n=5) < 0.6 * worst  # ~ 1 / delta
    assert _table_worst_q(method, C.EDGE_T_MIN, n=3) > 500  # 0.83 / EDGE_T_MIN


def test_clearance_is_checked():
    assert check_clearance(0) == 0.0 and check_clearance(np.float32(0.25)) == 0.25
    for bad in (-0.01, 0.51, float("nan"), True, "0.1", None):
        with pytest.raises(ValueError, match="'clearance'"):
            check_clearance(bad)


# -- the bundled part at its own bounds: quality, validity, topology, accuracy ----------------
@pytest.mark.parametrize("resolution", [64, 96, pytest.param(128, marks=pytest.mark.slow)])
def test_raw_part_has_no_slivers(resolution, check_mesh):
    part, bounds = wm.example("part")
    mesh = wm.mesh_surface(part, bounds=bounds, resolution=resolution)
    check_mesh(mesh)
    worst_q, min_angle = _quality(mesh)
    assert worst_q <= BOUND_Q["mc33"] and min_angle >= BOUND_ANGLE["mc33"]
    assert mesh.info["interior_vertices"] == 0  # no tunnel cell: the bound covers every triangle
    assert mesh.info["clearance_moved"] > 0  # the plate's faces lie on grid nodes
    assert _self_intersecting_faces(mesh.points, mesh.triangles) == 0
    assert mesh.stats()["euler"] == -6  # genus 4: the plate's four holes and the boss
    h = max(mesh.info["cell_size"])
    assert _distance_over_h(part, mesh.points, h) < 0.2  # linear placement's accuracy


@pytest.mark.parametrize("resolution", [64, 96, pytest.param(128, marks=pytest.mark.slow)])
def test_tetgen_and_gmsh_mesh_the_raw_part(resolution, tmp_path):
    """TetGen (quality bounds 10 degrees / radius-edge 1.5) failed at 96 ("Internal TetGen
    error within add_steinerpt_to_repair") on the surface with slivers."""
    pytest.importorskip("tetgen")
    pytest.importorskip("gmsh")
    part, bounds = wm.example("part")
    mesh = wm.mesh_surface(part, bounds=bounds, resolution=resolution)
    np.savez(tmp_path / "part.npz", points=mesh.points, faces=mesh.triangles)
    assert _run_client(_TETGEN, tmp_path / "part.npz") > len(mesh.triangles)
    mesh.to_trimesh().export(tmp_path / "part.stl")
    assert _run_client(_GMSH, tmp_path / "part.stl") > len(mesh.triangles) // 4


# -- every method, covering and sampled volumes -----------------------------------------------
@pytest.mark.parametrize("method", ["mc33", "mc", "mt"])
@pytest.mark.parametrize("covering", ["grid", "continuation"])
def test_every_method_and_covering(method, covering, check_mesh):
    part, bounds = wm.example("part")
    mesh = wm.mesh_surface(part, bounds=bounds, resolution=64, method=method, covering=covering)
    check_mesh(mesh)
    worst_q, min_angle = _quality(mesh)
    assert worst_q <= BOUND_Q[method] and min_angle >= BOUND_ANGLE[method]
    assert mesh.stats()["euler"] == -6
    assert _self_intersecting_faces(mesh.points, mesh.triangles) == 0


def _integer_ball(n: int = 24, radius: float = 8.3):
    """An integer field with the iso-level at sample values: a plane of exact zeros through
    the ball ("dilating", [FG §16.4.2]: a zero node is outside) and many more on its rim."""
    g = np.indices((n, n, n)) - (n - 1) / 2
    ball = np.round(4 * (radius - np.sqrt((g**2).sum(axis=0)))).astype(np.int32)
    return np.where(np.abs(g[2]) < 0.6, np.minimum(ball, 0), ball)


@pytest.mark.parametrize("method", ["mc33", "mc", "mt"])
def test_sampled_volume_with_exact_zeros(method, check_mesh):
    vol = _integer_ball()
    assert np.count_nonzero(vol == 0) > 100
    one = wm.mesh_surface(vol, method=method)
    check_mesh(one)
    worst_q, min_angle = _quality(one)
    assert worst_q <= BOUND_Q[method] and min_angle >= BOUND_ANGLE[method]
    assert _self_intersecting_faces(one.points, one.triangles) == 0
    slabs = wm.mesh_surface(vol, method=method, slab_voxels=24 * 24 * 9)  # seams weld exactly
    assert slabs.info["slabs"] > 1
    d, idx = cKDTree(one.points).query(slabs.points)  # the same vertices, up to the slab frames
    assert d.max() < 1e-5 and len(np.unique(idx)) == len(one.points) == len(slabs.points)
    assert {tuple(t) for t in np.sort(one.triangles, axis=1).tolist()} == \
        {tuple(t) for t in np.sort(idx[slabs.triangles], axis=1).tolist()}


# -- what the clearance changes, and what it keeps --------------------------------------------
@pytest.mark.parametrize("method", ["mc33", "mt"])
def test_clearance_moves_vertices_along_their_edges_only(method):
    """The same vertices (edge keys) and triangles as without it ("mt" may split a quad
    along its other diagonal, chosen by shape); each vertex moves along its own edge, at
    most delta of the edge, off the node it was next to. clearance=0 is the placement
    before it (slivers on the part)."""
    part, bounds = wm.example("part")
    p0, t0, e0, g0 = _extract(part, bounds, 48, method, clearance=0.0)
    p1, t1, e1, g1 = _extract(part, bounds, 48, method)
    assert np.array_equal(e0["key"], e1["key"]) and len(t0) == len(t1)
    if method != "mt":
        assert np.array_equal(t0, t1)
    else:  # rows that differ are both halves of a quad split along its other diagonal
        diff = np.flatnonzero(np.any(t0 != t1, axis=1))
        starts = diff[np.r_[True, np.diff(diff) > 1]]
        runs = np.diff(np.r_[np.flatnonzero(np.r_[True, np.diff(diff) > 1]), len(diff)])
        assert np.all(runs % 2 == 0)
        first = np.concatenate([a + np.arange(0, r, 2) for a, r in zip(starts, runs)]).astype(int)
        quads = [[frozenset(t[i]) | frozenset(t[i + 1]) for i in first] for t in (t0, t1)]
        assert quads[0] == quads[1] and all(len(q) == 4 for q in quads[0])
    assert g0.info["clearance_moved"] == 0 < g1.info["clearance_moved"]
    moved = e0["t"] != e1["t"]
    assert np.count_nonzero(moved) == g1.info["clearance_moved"]
    gap0, gap1 = np.minimum(e0["t"], 1 - e0["t"]), np.minimum(e1["t"], 1 - e1["t"])
    assert np.all(gap0[moved] < DELTA) and np.allclose(gap1[moved], DELTA)  # out to delta, no further
    capped = (e1["flags"] & 4) != 0
    kept = ~moved & (gap1 < DELTA) & ~capped  # "mc33": vertices next to a lonely node
    assert np.count_nonzero(kept) == 0 if method == "mt" else np.count_nonzero(kept) > 0
    edge = np.linalg.norm(e1["p1"] - e1["p0"], axis=1)
    assert np.all(np.linalg.norm(p1 - p0, axis=1) <= DELTA * edge * (1 + 1e-5))
    assert _quality(p0, t0)[0] > 100 > BOUND_Q[method] >= _quality(p1, t1)[0]


def test_distance_to_the_surface_grows_by_at_most_the_clearance():
    """On true distances the clearance adds at most delta h to |f| / |grad f|."""
    for name in ("sphere", "torus"):
        shape, bounds = wm.example(name)
        lo, hi = np.asarray(bounds, dtype=np.float64)
        h = float(np.max(hi - lo)) / 40
        d = {c: _distance_over_h(shape, _extract(shape, (lo, lo + 40 * h), 40, clearance=c)[0], h)
             for c in (0.0, DELTA)}
        assert d[0.0] < d[DELTA] <= d[0.0] + DELTA + 1e-3


def test_caps_stay_on_the_bounds_for_the_axis_methods():
    """A node on a capped face ends one crossing edge at most ("mc", "mc33"): its vertex keeps
    EDGE_T_MIN, so the caps lie on the bounds; "mt" (diagonal edges) moves them in by delta."""
    shape = wm.sphere(1.0)
    bounds = ((-0.8,) * 3, (0.8,) * 3)
    for method, gap in (("mc33", C.EDGE_T_MIN), ("mc", C.EDGE_T_MIN), ("mt", DELTA)):
        mesh = wm.mesh_surface(shape, bounds=bounds, resolution=32, method=method)
        caps = np.unique(mesh.triangles[mesh.cell_refs["triangle"] == C.CAP_REF])
        depth = 0.8 - np.abs(mesh.points[caps]).max(axis=1)
        assert np.allclose(depth, gap * 1.6 / 32, rtol=1e-3, atol=1e-6), method
        worst_q, min_angle = _quality(mesh)
        assert worst_q <= BOUND_Q[method] and min_angle >= BOUND_ANGLE[method]


def test_planes_through_grid_nodes_stay_on_them(check_mesh):
    """A box whose faces pass through grid nodes (f exactly 0 there, outside): every face
    node ends one crossing edge, so "mc33" keeps its vertices EDGE_T_MIN off the face, while
    "mt" (diagonal edges: no lonely node) moves them out to delta."""
    shape = wm.box((1.0, 1.0, 1.0))
    for method, gap in (("mc33", C.EDGE_T_MIN), ("mt", DELTA)):
        mesh = wm.mesh_surface(shape, bounds=((-1.0,) * 3, (1.0,) * 3), resolution=16, method=method)
        check_mesh(mesh)
        assert np.abs(wm.evaluate(shape, mesh.points)).max() == pytest.approx(gap * 0.125, rel=1e-3)
        worst_q, min_angle = _quality(mesh)
        assert worst_q <= BOUND_Q[method] and min_angle >= BOUND_ANGLE[method]


@pytest.mark.parametrize("root", ["bisection", "newton"])
def test_refined_roots_stay_on_the_surface(root):
    """Roots refined on the exact function keep EDGE_T_MIN, exact zeros at (crowded) nodes
    included: an octahedron |x| + |y| + |z| = 1/2 through many grid nodes."""
    x, y, z = wm.coords()
    shape = 0.5 - (wm.abs(x) + wm.abs(y) + wm.abs(z))
    bounds, h = ((-1.0,) * 3, (1.0,) * 3), 0.125
    linear = wm.mesh_surface(shape, bounds=bounds, resolution=16)
    assert np.abs(wm.evaluate(shape, linear.points)).max() == pytest.approx(DELTA * h, rel=1e-3)
    mesh = wm.mesh_surface(shape, bounds=bounds, resolution=16, root=root)
    assert np.array_equal(mesh.triangles, linear.triangles)
    assert np.abs(wm.evaluate(shape, mesh.points)).max() <= 1.01 * C.EDGE_T_MIN * h


def test_clearance_option_of_mesh_surface():
    part, bounds = wm.example("part")
    default = wm.mesh_surface(part, bounds=bounds, resolution=48)
    old = wm.mesh_surface(part, bounds=bounds, resolution=48, clearance=0.0)
    assert np.array_equal(default.triangles, old.triangles)
    assert _quality(old)[0] > 100 > BOUND_Q["mc33"] >= _quality(default)[0]
    assert default.info["clearance"] == 0.05 and old.info["clearance"] == 0.0
    with pytest.raises(ValueError, match="'clearance'"):
        wm.mesh_surface(part, bounds=bounds, resolution=48, clearance=0.7)


def test_clearance_option_of_sampled_volumes():
    """A binary volume puts every vertex at t = 0.5: nothing to move; a smooth field with
    samples near the level does move some, and only along their edges."""
    x = np.linspace(-1, 1, 24)
    vol = np.sqrt(sum(g ** 2 for g in np.meshgrid(x, x, x, indexing="ij"))).astype(np.float32)
    vol[np.abs(vol - 0.6) < 0.02] = 0.6 + 1e-4  # samples just off the level
    near = wm.mesh_surface(vol, level=0.6, inside="below")
    raw = wm.mesh_surface(vol, level=0.6, inside="below", clearance=0.0)
    assert near.info["clearance_moved"] > 0 and raw.info["clearance_moved"] == 0
    assert np.array_equal(near.triangles, raw.triangles)
    assert _quality(near)[0] < _quality(raw)[0]
