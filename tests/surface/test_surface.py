"""The dense (block-sparse) surface pipeline: topology, orientation, accuracy, bad input.

Expected Euler characteristics come from ``topology_oracle`` (a cubical-complex count on
a sampled grid, independent of the mesher) and from the reasoning recorded there.
"""


import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

import warpmesh as wm
import warpmesh._util.parallel as parallel_module
from tests.helpers.meshcheck import check_mesh
from tests.helpers.topology_oracle import CSG_PART_EXPECTED, DEGREE_SIX_EXPECTED, surface_euler

from warpmesh.cells import topology as T


def _distance_over_h(shape, mesh, h, bounds=None):
    """max |f| / |grad f| over the vertices (eq. 16.6), in units of the cell size; with
    ``bounds``, the cap vertices (on the bounds' faces, where f != 0) are left out."""
    p = mesh.points
    if bounds is not None:
        lo, hi = np.asarray(bounds)
        p = p[np.all((p - lo > 0.01 * h) & (hi - p > 0.01 * h), axis=1)]
    fg = wm.evaluate(shape, p, gradient=True).astype(np.float64)
    return float(np.max(np.abs(fg[:, 0]) / np.linalg.norm(fg[:, 1:], axis=1)) / h)


def _triangle_set(mesh, decimals=5):
    tri = np.round(mesh.points[mesh.cells["triangle"]], decimals)
    return {tuple(sorted(map(tuple, t))) for t in tri}


def _numpy_euler(shape, bounds, n):
    return surface_euler(shape.eval_numpy, bounds, n)


# -- topology of known shapes ----------------------------------------------------------------
@pytest.mark.parametrize("resolution", [24, 48, 96])
@pytest.mark.parametrize("name, expected", [("sphere", 2), ("torus", 0), ("part", CSG_PART_EXPECTED["surface_euler"])])
def test_known_topology(name, expected, resolution, device):
    shape, bounds = wm.example(name)
    mesh = wm.mesh_surface(shape, bounds=bounds, resolution=resolution, device=device)
    check_mesh(mesh)
    s = mesh.stats()
    assert s["euler"] == expected
    assert s["components"] == 1
    assert s["volume"] > 0  # outward normals enclose a positive volume


@pytest.mark.parametrize("resolution", [32, 64, 128])
def test_degree_six_clipped_both_sides(resolution, device):
    shape, bounds = wm.example("degree6")
    for side, solid in (("inside", shape), ("outside", ~shape)):
        mesh = wm.mesh_surface(solid, bounds=bounds, resolution=resolution, device=device)
        check_mesh(mesh)
        s = mesh.stats()
        want = DEGREE_SIX_EXPECTED[side]
        assert s["euler"] == want["surface_euler"], side
        assert s["components"] == want["components"], side
        assert s["volume"] > 0


def test_oracle_agrees_with_mesher_on_random_blobs():
    """Sums of Gaussian blobs: whatever the topology, mesher and oracle agree."""
    rng = np.random.default_rng(7)
    x, y, z = wm.coords()
    bounds = ((-1.0,) * 3, (1.0,) * 3)
    for _ in range(4):
        centers = rng.uniform(-0.6, 0.6, (5, 3))
        f = -0.35
        for c in centers:
            f = f + wm.exp(-((x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2) * 12.0)
        mesh = wm.mesh_surface(f, bounds=bounds, resolution=48)
        check_mesh(mesh)
        assert mesh.stats()["euler"] == _numpy_euler(f, bounds, 193)


# -- orientation and accuracy ---------------------------------------------------------------------
@pytest.mark.parametrize("name, root", [("sphere", "linear"), ("torus", "newton"), ("part", "newton"),
                                        ("degree6", "newton")])
def test_every_triangle_faces_outward(name, root):
    """Consistent winding (check_mesh) and a positive volume in every closed component (none
    of these solids has a cavity) mean that every triangle faces out, towards f < 0."""
    shape, bounds = wm.example(name)
    for solid in ((shape, ~shape) if name == "degree6" else (shape,)):
        mesh = wm.mesh_surface(solid, bounds=bounds, resolution=40, root=root)
        check_mesh(mesh)
        faces = mesh.cells["triangle"]
        _, labels = T.connected_components(faces, len(mesh.points))
        p = mesh.points[faces]
        six_v = np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2]))
        assert np.all(np.bincount(labels, weights=six_v) > 0)
        assert mesh.info["signed_volume"] > 0 and mesh.info["orientation"].startswith("outward")


def test_every_triangle_faces_outward_on_a_smooth_shape():
    shape = wm.ellipsoid((1.0, 0.7, 0.5))
    mesh = wm.mesh_surface(shape, bounds=((-1.1,) * 3, (1.1,) * 3), resolution=40)
    tri = mesh.points[mesh.cells["triangle"]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    grad = wm.evaluate(shape, tri.mean(axis=1), gradient=True)[:, 1:]
    assert np.all(np.einsum("ij,ij->i", normal, -grad) > 0)  # towards f < 0


@pytest.mark.parametrize("root, bound", [("linear", 0.2), ("bisection", 2.5e-3), ("newton", 2.5e-3)])
@pytest.mark.parametrize("name", ["sphere", "torus", "part"])
def test_vertex_distance_to_exact_surface(name, root, bound):
    """Vertices lie within `bound` cell sizes of f = 0, measured with |f| / |grad f|."""
    shape, bounds = wm.example(name)
    mesh = wm.mesh_surface(shape, bounds=bounds, resolution=64, root=root)
    h = max(mesh.info["cell_size"])
    check_mesh(mesh)
    assert _distance_over_h(shape, mesh, h) < bound


@pytest.mark.parametrize("name", ["torus", "degree6"])
def test_newton_converges_on_smooth_surfaces(name):
    """Away from CSG kinks and surface nodes, safeguarded Newton reaches float32 noise."""
    shape, bounds = wm.example(name)
    mesh = wm.mesh_surface(shape, bounds=bounds, resolution=64, root="newton")
    assert _distance_over_h(shape, mesh, max(mesh.info["cell_size"]), bounds) < 1e-4


def test_root_finding_improves_on_linear_interpolation():
    shape, bounds = wm.example("torus")
    d = {r: _distance_over_h(shape, wm.mesh_surface(shape, bounds=bounds, resolution=32, root=r), 1.0)
         for r in ("linear", "bisection", "newton")}
    assert d["bisection"] < d["linear"] / 10 and d["newton"] < d["linear"] / 10


def test_normals_are_unit_and_outward():
    mesh = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.5,) * 3, (1.5,) * 3), resolution=24, normals=True)
    n = mesh.point_data["normals"]
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    radial = mesh.points / np.linalg.norm(mesh.points, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", n, radial) > 0.99)


def test_cap_vertices_get_the_normal_of_the_bounds_face():
    slab = wm.halfspace((0, 0, 1), (0, 0, 0.1))  # inside: z < 0.1, capped by the box
    mesh = wm.mesh_surface(slab, bounds=((-1.0,) * 3, (1.0,) * 3), resolution=10, normals=True)
    n, p = mesh.point_data["normals"], mesh.points
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    bottom = p[:, 2] < -1 + 1e-2  # vertices of the cap on the face z = -1
    assert bottom.any() and np.allclose(n[bottom], (0, 0, -1))
    top = np.abs(p[:, 2] - 0.1) < 1e-6  # the true surface: -grad f = +z
    interior = top & (np.abs(p[:, 0]) < 0.9) & (np.abs(p[:, 1]) < 0.9)
    assert interior.any() and np.allclose(n[interior], (0, 0, 1), atol=1e-6)


def test_far_from_the_origin_positions_keep_their_precision():
    """Vertices are computed relative to the grid origin; the origin is added in float64."""
    g = np.arange(-12, 13, 1.0)
    vol = 10 - np.sqrt(g[:, None, None] ** 2 + g[None, :, None] ** 2 + g[None, None, :] ** 2)
    near = wm.mesh_surface(vol, spacing=1.0, origin=(-12, -12, -12))
    shift = np.array([4e6, 5e5, 0.0])
    far = wm.mesh_surface(vol, spacing=1.0, origin=shift - 12)
    check_mesh(far)
    assert np.allclose(far.points - shift, near.points, atol=1e-6)


def test_cap_normals_with_bounds_not_representable_in_float32():
    lo = np.array([1000.1, -0.7, -0.7])
    mesh = wm.mesh_surface(wm.sphere(1.0, center=(1000.1 + 0.6, 0, 0)), bounds=(lo, lo + 1.4),
                           resolution=14, normals=True)
    low_face = mesh.points[:, 0] < lo[0] + 1e-3  # cap vertices on the face x = x0
    assert low_face.any() and np.allclose(mesh.point_data["normals"][low_face], (-1, 0, 0))


# -- culling, zeros, capping ------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["part", "degree6"])
def test_culling_changes_nothing_but_the_work(name):
    shape, bounds = wm.example(name)
    a = wm.mesh_surface(shape, bounds=bounds, resolution=48, cull=True)
    b = wm.mesh_surface(shape, bounds=bounds, resolution=48, cull=False)
    assert a.info["evaluations"] < b.info["evaluations"]
    assert _triangle_set(a) == _triangle_set(b)


def test_nodes_exactly_on_the_surface_give_no_degenerate_triangles():
    # radius 1 on a grid of spacing 0.25: many nodes have f == 0 exactly
    mesh = wm.mesh_surface(wm.sphere(1.0), bounds=((-2.0,) * 3, (2.0,) * 3), resolution=16)
    check_mesh(mesh)
    assert mesh.stats()["euler"] == 2
    vol = np.zeros((9, 9, 9), np.float32)
    vol[2:7, 2:7, 2:7] = 1.0  # values {0, 1}: level 0 leaves every outside node exactly on it
    mesh = wm.mesh_surface(vol, level=0.0)
    check_mesh(mesh)
    assert mesh.stats()["euler"] == 2


def test_capping_closes_an_unbounded_shape_and_can_be_turned_off():
    slab = wm.halfspace((0, 0, 1), (0, 0, 0.1))
    closed = wm.mesh_surface(slab, bounds=((-1.0,) * 3, (1.0,) * 3), resolution=20)
    check_mesh(closed)
    s = closed.stats()
    # marching cubes chamfers the capped edges: at most h^2 per unit of edge length is lost
    edge_length, h = 4 * 2 + 4 * 2 + 4 * 1.1, 0.1
    assert s["euler"] == 2 and 0 < 2 * 2 * 1.1 - s["volume"] < edge_length * h * h
    refs = closed.cell_refs["triangle"]
    tri = closed.points[closed.cells["triangle"]]
    near_plane = np.abs(tri[..., 2] - 0.1) < 1e-3  # vertices on the true surface z = 0.1
    assert np.all(refs[near_plane.all(axis=1)] == 1)  # the plane is surface
    assert np.all(refs[~near_plane.any(axis=1)] == 2)  # the rest of the box is cap
    assert 0 < np.count_nonzero(refs == 1) < len(refs)
    shape, bounds = wm.example("degree6")
    opened = wm.mesh_surface(shape, bounds=bounds, resolution=32, cap=False)
    assert opened.cell_refs is None
    check_mesh(opened, closed=False)
    assert not opened.stats()["watertight"]


# -- volume data ------------------------------------------------------------------------------------
def test_volume_matches_the_shape_on_the_same_grid():
    shape, bounds = wm.example("torus")
    mesh_a = wm.mesh_surface(shape, bounds=bounds, resolution=(30, 30, 10))
    n = np.array(mesh_a.info["grid"])
    axes = [np.linspace(lo, hi, k) for lo, hi, k in zip(bounds[0], bounds[1], n)]
    vol = shape.eval_numpy(axes[0][:, None, None], axes[1][None, :, None], axes[2][None, None, :])
    spacing = [a[1] - a[0] for a in axes]
    mesh_b = wm.mesh_surface(vol.astype(np.float32), spacing=spacing, origin=bounds[0])
    check_mesh(mesh_b)
    assert len(mesh_a.points) == len(mesh_b.points)
    assert len(mesh_a.cells["triangle"]) == len(mesh_b.cells["triangle"])
    dist, _ = cKDTree(mesh_a.points).query(mesh_b.points)
    assert dist.max() < 1e-4


def test_volume_level_inside_and_labels():
    g = np.linspace(-1, 1, 33)
    r = np.sqrt(g[:, None, None] ** 2 + g[None, :, None] ** 2 + g[None, None, :] ** 2)
    above = wm.mesh_surface(r, level=0.7, inside="below", spacing=g[1] - g[0], origin=(-1, -1, -1))
    check_mesh(above)
    assert abs(above.stats()["volume"] - 4 / 3 * np.pi * 0.7**3) < 0.03
    labels = (r < 0.5).astype(np.uint8) + (r < 0.25).astype(np.uint8)  # a segmentation: 0, 1, 2
    inner = wm.mesh_surface(labels, level=1.5)
    check_mesh(inner)
    assert inner.stats()["euler"] == 2
    both = wm.mesh_surface(labels, level=0.5)
    assert both.stats()["components"] == 1


# -- parallel launches are deterministic ----------------------------------------------------------
def test_parallel_chunks_match_serial_evaluation(monkeypatch):
    shape, bounds = wm.example("part")
    pts = np.random.default_rng(3).uniform(-1.2, 1.2, (200_000, 3))
    parallel = wm.evaluate(shape, pts)
    reference = wm.mesh_surface(shape, bounds=bounds, resolution=64)
    monkeypatch.setattr(parallel_module, "n_workers", lambda device: 1)
    serial = wm.evaluate(shape, pts)
    assert np.array_equal(parallel, serial)
    serial_mesh = wm.mesh_surface(shape, bounds=bounds, resolution=64)
    assert np.array_equal(serial_mesh.points, reference.points)
    assert np.array_equal(serial_mesh.cells["triangle"], reference.cells["triangle"])


@pytest.mark.slow
def test_many_threaded_runs_are_identical():
    """Stress: repeated two-thread chunked launches always give the same mesh."""
    shape, bounds = wm.example("part")
    first = wm.mesh_surface(shape, bounds=bounds, resolution=96)
    for _ in range(40):
        again = wm.mesh_surface(shape, bounds=bounds, resolution=96)
        assert np.array_equal(again.points, first.points)
        assert np.array_equal(again.cells["triangle"], first.cells["triangle"])


# -- statistics ----------------------------------------------------------------------------------------
def test_stats_report_counts_quality_and_timings():
    shape, bounds = wm.example("sphere")
    s = wm.mesh_surface(shape, bounds=bounds, resolution=32).stats()
    for key in ("np", "ne", "watertight", "euler", "mean_q", "worst_q"):
        assert key in s
    assert s["np"] > 0 and s["ne"] == 2 * s["np"] - 4  # closed genus-0 triangulation
    assert 1.0 <= s["mean_q"] <= s["worst_q"]
    for stage in ("compile", "cull", "evaluate", "extract", "host", "total"):
        assert s["time"][stage] >= 0
    assert s["evaluations"] > 0


# -- bad input ---------------------------------------------------------------------------------------------
BOUNDS = ((-1.0,) * 3, (1.0,) * 3)


@pytest.mark.parametrize("kwargs, match", [
    (dict(resolution=0), "resolution"),
    (dict(resolution=-3), "resolution"),
    (dict(resolution=100000), "resolution"),
    (dict(resolution=(4, 4)), "resolution"),
    (dict(bounds=((0, 0, 0), (0, 1, 1))), "bounds"),
    (dict(bounds=((0, 0, 0), (1, 1))), "bounds"),
    (dict(bounds=((0, 0, np.nan), (1, 1, 1))), "bounds"),
    (dict(bounds=None), "bounds"),
    (dict(root="secant"), "root"),
    (dict(root_iterations=0), "root_iterations"),
])
def test_bad_arguments_for_a_shape(kwargs, match):
    args = dict(bounds=BOUNDS, resolution=8)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        wm.mesh_surface(wm.sphere(0.5), **args)


@pytest.mark.parametrize("kwargs, match", [
    (dict(level=0.5), "'level' does not apply to a shape"),
    (dict(inside="below", spacing=0.1), "'inside', 'spacing'"),
    (dict(origin=(0, 0, 0)), "origin"),
    (dict(root_iterations=5), "root_iterations"),
    (dict(resolution=1), "at least 2 cells"),
    (dict(bounds=((0, 0, 0), (1, 1, 0.01)), resolution=20), "at least 2 cells"),
])
def test_options_that_do_not_apply_are_refused(kwargs, match):
    args = dict(bounds=BOUNDS, resolution=8)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        wm.mesh_surface(wm.sphere(0.5), **args)


def test_volume_refuses_grid_options_and_tiny_capped_volumes():
    vol = np.arange(64.0).reshape(4, 4, 4)
    with pytest.raises(ValueError, match="'resolution' does not apply to a volume"):
        wm.mesh_surface(vol, level=3.0, resolution=16)
    with pytest.raises(ValueError, match="'bounds'"):
        wm.mesh_surface(vol, level=3.0, bounds=BOUNDS)
    with pytest.raises(ValueError, match="at least 3 samples"):
        wm.mesh_surface(np.arange(18.0).reshape(2, 3, 3), level=3.0)
    assert len(wm.mesh_surface(np.arange(18.0).reshape(2, 3, 3), level=3.0, cap=False).points)


@pytest.mark.parametrize("flag", ["cap", "cull", "normals"])
def test_flags_must_be_booleans(flag):
    with pytest.raises(TypeError, match=flag):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOUNDS, resolution=8, **{flag: "no"})


def test_bad_types():
    with pytest.raises(TypeError, match="resolution"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOUNDS, resolution=8.5)
    with pytest.raises(FileNotFoundError, match="no such image file or DICOM folder: 'sphere'"):
        wm.mesh_surface("sphere", bounds=BOUNDS)  # a string is an image's path
    with pytest.raises(TypeError, match="source"):
        wm.mesh_surface(object(), bounds=BOUNDS)
    with pytest.raises(TypeError, match="unexpected keyword"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOUNDS, resolution=8, method_name="mc")


def test_shape_that_evaluates_to_nan_is_refused():
    x, _, _ = wm.coords()
    with pytest.raises(ValueError, match="NaN"):
        wm.mesh_surface(wm.log(x), bounds=BOUNDS, resolution=8)


@pytest.mark.parametrize("volume, kwargs, exc, match", [
    (np.full((4, 4, 4), np.nan), {}, ValueError, "finite"),
    (np.zeros((4, 4)), {}, ValueError, "3D"),
    (np.zeros((1, 4, 4)), {}, ValueError, "at least 2"),
    (np.ones((4, 4, 4)), {}, ValueError, "constant"),
    (np.arange(64.0).reshape(4, 4, 4), dict(level=1000.0), ValueError, "level"),
    (np.arange(64.0).reshape(4, 4, 4), dict(spacing=0.0), ValueError, "spacing"),
    (np.arange(64.0).reshape(4, 4, 4), dict(origin=(0, 0)), ValueError, "origin"),
    (np.arange(64.0).reshape(4, 4, 4), dict(root="newton", level=3.0), ValueError, "root"),
    (np.arange(64.0).reshape(4, 4, 4), dict(inside="left", level=3.0), ValueError, "inside"),
    (np.zeros((4, 4, 4), dtype=complex), {}, TypeError, "numeric"),
])
def test_bad_volumes(volume, kwargs, exc, match):
    with pytest.raises(exc, match=match):
        wm.mesh_surface(volume, **kwargs)


def test_no_surface_in_bounds_warns_and_returns_an_empty_mesh():
    with pytest.warns(UserWarning, match="does not cross"):
        mesh = wm.mesh_surface(wm.sphere(0.2, center=(5, 5, 5)), bounds=BOUNDS, resolution=8)
    assert len(mesh.cells["triangle"]) == 0


def _random_shape(rng, depth=0):
    """A random CSG tree of random primitives, booleans and transforms."""
    if depth >= 3 or rng.random() < 0.3:
        kind = rng.integers(6)
        r = rng.uniform(0.15, 0.6)
        shape = [wm.sphere(r), wm.box(rng.uniform(0.2, 1.0, 3)), wm.cylinder(r, rng.uniform(0.3, 1.2)),
                 wm.torus(r + 0.2, r * 0.4), wm.capsule((0, 0, -0.3), (0.2, 0.1, 0.3), r * 0.5),
                 wm.superquadric(rng.uniform(0.3, 0.7, 3), rng.uniform(0.3, 1.0), rng.uniform(0.3, 1.0))][kind]
        shape = shape.rotate(rng.uniform(0, 6.3), rng.normal(size=3) + 1e-3)
        return shape.translate(rng.uniform(-0.5, 0.5, 3))
    a, b = _random_shape(rng, depth + 1), _random_shape(rng, depth + 1)
    method = ["rfunction", "minmax", "smooth"][rng.integers(3)]
    op = rng.integers(3)
    if op == 0:
        return wm.union(a, b, method=method)
    if op == 1:
        return wm.intersection(a, b, method=method)
    return wm.difference(a, b, method=method)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:the surface does not cross")  # some random trees are empty
def test_random_csg_shapes_always_give_closed_oriented_manifolds():
    """Fuzz: whatever the tree, the mesh is watertight, 2-manifold, consistently oriented,
    encloses a positive volume, and culling does not change it."""
    rng = np.random.default_rng(2026)
    bounds = ((-1.1,) * 3, (1.1,) * 3)
    for trial in range(40):
        shape = _random_shape(rng)
        res = int(rng.integers(8, 48))
        mesh = wm.mesh_surface(shape, bounds=bounds, resolution=res,
                               root=["linear", "bisection", "newton"][trial % 3])
        if len(mesh.cells["triangle"]) == 0:
            continue
        check_mesh(mesh)
        assert mesh.info["signed_volume"] > 0, trial
        if trial % 4 == 0:
            dense = wm.mesh_surface(shape, bounds=bounds, resolution=res, cull=False)
            assert len(dense.cells["triangle"]) == len(mesh.cells["triangle"]), trial


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity on this platform")
def test_launch_threads_follow_the_cpu_affinity():
    """A process pinned to one core (a Dask worker's or a container's share) launches its CPU
    kernels from one thread, not from one per core of the machine."""
    code = ("import os; os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]}); "
            "from warpmesh._util.parallel import n_workers, parallel_ranges; "
            "from warpmesh.cells.intersections import _check_workers; "
            "print(n_workers('cpu'), len(parallel_ranges(1 << 20, 'cpu')), _check_workers(None))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["1", "1", "1"]
