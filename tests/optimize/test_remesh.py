"""Surface optimisation and simplification on the exact surface (issue 6, [FG §16.4.3])."""

import warnings

import numpy as np
import pytest
import trimesh

import warpmesh as wm
from warpmesh.optimize.local_ops import CORNER, LINE, Surface, select_independent
from warpmesh.errors import TopologyError
from warpmesh.optimize.features import detect_features, insert_creases
from warpmesh.frep.projection import ImplicitTarget, MeshTarget, VolumeField, surface_sample_points
from warpmesh.cells.quality import edge_length_ratio, format_table, quality_histogram, quality_table, triangle_angles


@pytest.fixture(scope="module")
def sphere_mc():
    shape, bounds = wm.example("sphere")
    return shape, wm.mesh_surface(shape, bounds=bounds, resolution=32, method="mc")


def _closed_oriented(mesh):
    s = mesh.stats()
    return s["watertight"] and s["manifold"] and s["oriented"] and s["volume"] > 0


# ----------------------------------------------------------------------------- quality measures
def test_angles_ratio_histogram_table():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [3, 0, 0]], float)
    tri = np.array([[0, 1, 2], [0, 3, 2]])
    ang = triangle_angles(pts, tri)
    assert np.allclose(ang.sum(1), 180.0)
    assert np.allclose(ang[0], [90, 45, 45])
    assert np.allclose(edge_length_ratio(pts, tri), [np.sqrt(2), np.sqrt(10) / 1])
    hist = quality_histogram(pts, tri)
    assert sum(hist.values()) == 2
    row = quality_table(pts, tri)
    assert row["ne"] == 2 and row["np"] == 4 and row["q_worst"] == pytest.approx(wm.triangle_quality(pts, tri).max())
    assert "Q worst" in format_table({"x": row})


def test_mesh_quality_and_stats_keys(sphere_mc):
    _, mc = sphere_mc
    q = mc.quality()
    assert q.shape == (mc.n_cells,) and q.min() >= 1.0 - 1e-12
    s = mc.stats()
    assert s["q_worst"] == pytest.approx(q.max()) and s["q_mean"] == pytest.approx(q.mean())


# ----------------------------------------------------------------------------- projection targets
def test_implicit_projection_curvature_and_clip():
    t = ImplicitTarget(wm.sphere(2.0))
    rng = np.random.default_rng(0)
    p = rng.normal(size=(200, 3))
    proj = t.project(p * 2.5 / np.linalg.norm(p, axis=1)[:, None])
    assert np.allclose(np.linalg.norm(proj, axis=1), 2.0, atol=1e-5)
    assert np.allclose(t.curvature(proj), 0.5, rtol=1e-2)
    assert np.allclose(t.normals(proj), proj / 2.0, atol=1e-5)  # outward
    torus = ImplicitTarget(wm.torus(1.0, 0.25))
    outer = torus.project(np.array([[1.4, 0.0, 0.0]]))
    assert outer[0] == pytest.approx([1.25, 0, 0], abs=1e-5)
    assert torus.curvature(outer)[0] == pytest.approx(4.0, rel=1e-2)  # 1 / minor radius
    clipped = ImplicitTarget(wm.sphere(1.0), bounds=((-2, -2, -2), (2, 2, 0.5)))
    cap = clipped.project(np.array([[0.1, 0.0, 0.6]]))
    assert cap[0, 2] == pytest.approx(0.5) and clipped.normals(cap)[0] == pytest.approx([0, 0, 1])


def test_volume_field_is_trilinear():
    g = np.arange(5.0)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    vol = 2 * x - y + 0.5 * z  # linear: trilinear interpolation is exact
    t = VolumeField(vol, spacing=0.5, origin=(1, 2, 3), level=1.0)
    p = np.array([[1.3, 2.7, 3.2], [2.1, 3.3, 4.4]])
    f, grad = t.value_gradient(p)
    q = (p - (1, 2, 3)) / 0.5
    assert np.allclose(f, 2 * q[:, 0] - q[:, 1] + 0.5 * q[:, 2] - 1.0)
    assert np.allclose(grad, [[4, -2, 1]] * 2)
    below = VolumeField(vol, level=1.0, inside="below")
    inner = np.array([[1.3, 2.7, 3.2], [0.5, 3.5, 2.25]])
    assert np.allclose(below.value_gradient(inner)[0], -(inner @ [2, -1, 0.5] - 1.0))
    with pytest.raises(ValueError, match="'values'"):
        VolumeField(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="'values'"):
        VolumeField(np.full((3, 3, 3), np.nan))
    with pytest.raises(ValueError, match="'spacing'"):
        VolumeField(vol, spacing=0)
    with pytest.raises(ValueError, match="'inside'"):
        VolumeField(vol, inside="left")


def test_mesh_target_closest_point():
    box = trimesh.creation.box((2, 2, 2))
    t = MeshTarget(box.vertices, box.faces)
    p = t.project(np.array([[0.2, 0.3, 1.5], [3.0, 0.0, 0.0]]))
    assert np.allclose(p, [[0.2, 0.3, 1.0], [1.0, 0.0, 0.0]])
    assert np.allclose(t.distance(np.array([[0.2, 0.3, 1.5]])), 0.5)


# ----------------------------------------------------------------------------- operators
def test_independent_selection_never_shares_an_element():
    rng = np.random.default_rng(1)
    cand = rng.integers(0, 300, 2000)
    elem = rng.integers(0, 500, 2000)
    prio = rng.random(300)
    win = select_independent(300, prio, elem, cand)
    assert len(win)
    won = np.isin(cand, win)
    assert len(np.unique(elem[won])) == len(np.unique(np.stack([elem[won], cand[won]], 1), axis=0))
    # many rounds, some elements blocked, some candidates barred: still disjoint, and maximal
    blocked = rng.random(500) < 0.1
    active = rng.random(300) < 0.8
    win2 = select_independent(300, prio, elem, cand, rounds=50, blocked=blocked, active=active)
    assert len(win2) > len(win) and active[win2].all()
    won = np.isin(cand, win2)
    pairs = np.unique(np.stack([elem[won], cand[won]], 1), axis=0)
    assert len(np.unique(pairs[:, 0])) == len(pairs)  # no element with two winners
    assert not blocked[elem[won]].any()
    taken = blocked.copy()
    taken[elem[won]] = True
    touches = np.bincount(cand[taken[elem]], minlength=300) > 0
    others = np.setdiff1d(np.flatnonzero(active), win2)
    assert touches[others].all()  # every allowed loser touches a winner or a blocked element
    empty = np.zeros(0, np.int64)
    assert select_independent(3, np.zeros(3), empty, empty, active=np.array([True, False, True])).tolist() == [0, 2]


@pytest.mark.parametrize("op", ["split", "flip", "collapse"])
def test_operators_keep_a_closed_oriented_surface(op):
    ico = trimesh.creation.icosphere(3)
    s = Surface(ico.vertices, ico.faces)
    topo = s.topology()
    n0, m0 = len(s.points), len(s.triangles)
    owner = np.concatenate([np.arange(len(topo.edges))] * 2)
    faces = np.concatenate([topo.face0, topo.face1])
    rng = np.random.default_rng(2)
    win = select_independent(len(topo.edges), rng.random(len(topo.edges)), faces, owner)
    if op == "split":
        mid = 0.5 * (s.points[topo.edges[win, 0]] + s.points[topo.edges[win, 1]])
        assert s.split(topo, win, mid) == len(win)
        assert len(s.points) == n0 + len(win) and len(s.triangles) == m0 + 2 * len(win)
    elif op == "flip":
        ok = s.flip_candidates_ok(topo, win, np.cos(np.radians(40)))
        assert len(ok) == len(win)  # all interior, smooth, new edges absent
        s.flip(ok, topo)
    else:
        e = win[:10]
        # far apart collapses: vertices of distinct edges never neighbours (checked by the driver)
        a, b = topo.edges[e, 0], topo.edges[e, 1]
        keep = np.ones(len(e), bool)
        used = set()
        for i, (u, v) in enumerate(zip(a, b)):
            near = set(ico.vertex_neighbors[u]) | set(ico.vertex_neighbors[v]) | {u, v}
            keep[i] = not (near & used)
            used |= near
        e, a, b = e[keep], a[keep], b[keep]
        gone = np.concatenate([topo.face0[e], topo.face1[e]])
        s.collapse(a, b, 0.5 * (s.points[a] + s.points[b]), gone)
        s.compact()
        assert len(s.points) == n0 - len(e) and len(s.triangles) == m0 - 2 * len(e)
    m = wm.Mesh(s.points, {"triangle": s.triangles})
    assert _closed_oriented(m) and m.stats()["euler"] == 2


# ----------------------------------------------------------------------------- features
def test_box_features_from_triangles():
    box = trimesh.creation.box((1, 1, 1))
    s = Surface(box.vertices, box.faces)
    detect_features(s, angle=40.0)
    assert (s.vclass == CORNER).sum() == 8 and len(s.feature_keys) == 12


def test_creases_recovered_on_the_exact_function():
    shape = wm.box((1.0, 1.0, 1.0)) & wm.sphere(0.8)  # planes cut by a sphere: circles and box edges
    mc = wm.mesh_surface(shape, bounds=((-0.7,) * 3, (0.7,) * 3), resolution=28, method="mc")
    t = ImplicitTarget(shape)
    s = Surface(t.project(mc.points), mc.triangles)
    crease = insert_creases(s, t, 40.0)
    detect_features(s, 40.0, t, crease)
    line = s.vclass >= LINE
    assert line.sum() > 50
    # every feature vertex sits where two of the faces meet: on |x|, |y| or |z| = 0.5 twice,
    # or on one plane and the sphere
    p = np.abs(s.points[line])
    on_plane = np.abs(p - 0.5) < 2.5e-3  # 5% of the cell
    on_sphere = np.abs(np.linalg.norm(s.points[line], axis=1) - 0.8) < 2.5e-3
    assert np.all(on_plane.sum(1) + on_sphere >= 2)


# ----------------------------------------------------------------------------- optimize
def test_optimize_sphere_reaches_a_unit_mesh(sphere_mc):
    shape, mc = sphere_mc
    h = 0.1
    opt = mc.optimize(shape, size=h, tolerance=0.02)
    s = opt.stats()
    assert _closed_oriented(opt) and s["euler"] == 2 and s["components"] == 1
    assert s["q_worst"] < 2.0 and s["q_mean"] < 1.15 and s["q_worst"] < mc.stats()["q_worst"]
    assert triangle_angles(opt.points, opt.triangles).min() > 30.0
    err = wm.surface_error(opt, shape)
    # the centroid of an equilateral triangle of side L sits L^2 / (6 r) inside the sphere; L <= 4h/3
    assert err["vertex_max"] < 1e-5 and err["max"] < (4 * h / 3) ** 2 / 6
    edges = opt.points[opt.edges]
    length = np.linalg.norm(edges[:, 0] - edges[:, 1], axis=1)
    assert 0.8 * h < np.median(length) < 1.2 * h
    info = opt.info["optimize"]
    assert info["before"]["ne"] == mc.n_cells and info["after"]["ne"] == opt.n_cells


def test_optimize_part_keeps_topology_and_sharp_edges(part_opt):
    shape, mc, opt = part_opt
    s = opt.stats()
    assert _closed_oriented(opt) and s["euler"] == mc.stats()["euler"] == -6
    assert s["q_worst"] <= 2.0 and s["q_mean"] <= 1.15
    assert wm.surface_error(opt, shape)["vertex_max"] < opt.info["optimize"]["tolerance"]
    info = opt.info["optimize"]
    assert info["feature_edges"] > 300
    # sharp: edges in the plate's top plane with a dihedral near 90 degrees (box edges and
    # hole rims); marching cubes chamfers them
    assert _sharp_top_edges(opt) > 200 and _sharp_top_edges(opt) > 10 * _sharp_top_edges(mc)


def _sharp_top_edges(mesh):
    from warpmesh.cells.topology import face_normals, unique_edges

    nrm = face_normals(mesh.points, mesh.triangles)
    edges, face_edge, _ = unique_edges(mesh.triangles)
    pairs = (np.argsort(face_edge.ravel(), kind="stable") // 3).reshape(-1, 2)
    cos = np.einsum("ij,ij->i", nrm[pairs[:, 0]], nrm[pairs[:, 1]])
    on_top = (np.abs(mesh.points[edges][:, :, 2] - 0.3) < 1e-6).all(1)
    return int((on_top & (cos < 0.2)).sum())


def test_optimize_capped_degree6_recomputes_cap_refs():
    shape, bounds = wm.example("degree6")
    mc = wm.mesh_surface(shape, bounds=bounds, resolution=40, method="mc")
    opt = wm.optimize(mc, shape, bounds=bounds)
    s = opt.stats()
    assert _closed_oriented(opt) and s["euler"] == mc.stats()["euler"] == -8
    refs = opt.cell_refs["triangle"]
    assert set(np.unique(refs)) == {1, 2}
    cen = opt.points[opt.triangles[refs == 2]].mean(1)
    assert np.all(np.abs(np.abs(cen).max(1) - 3.0) < 1e-4)  # caps on the box faces
    assert s["q_worst"] < 2.5 and s["q_mean"] < 1.15


def test_optimize_volume_field():
    g = np.linspace(-1.2, 1.2, 49)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    vol = np.sqrt(x**2 + y**2 + z**2)
    field = wm.VolumeField(vol, spacing=g[1] - g[0], origin=-1.2, level=1.0, inside="below")
    mc = wm.mesh_surface(vol, spacing=g[1] - g[0], origin=(-1.2,) * 3, level=1.0, inside="below", method="mc")
    opt = mc.optimize(field, size=0.08)
    assert _closed_oriented(opt) and opt.stats()["euler"] == 2
    assert opt.stats()["q_worst"] < 2.0
    assert np.abs(np.linalg.norm(opt.points, axis=1) - 1.0).max() < 2e-3  # trilinear error of the samples


def test_optimize_without_function_stays_on_the_input():
    tm = trimesh.creation.torus(1.0, 0.3, major_sections=48, minor_sections=24)
    mesh = wm.Mesh.from_trimesh(tm)
    opt = mesh.optimize(size=0.1)
    assert _closed_oriented(opt) and opt.stats()["euler"] == 0
    assert opt.stats()["q_worst"] < mesh.stats()["q_worst"]
    assert MeshTarget(tm.vertices, tm.faces).distance(opt.points).max() < 1e-9


def test_optimize_keeps_label_refs_and_open_boundaries():
    vol = np.zeros((24, 24, 24), np.int32)
    vol[4:20, 4:12, 4:20] = 1
    vol[4:20, 12:20, 4:20] = 2
    mc = wm.mesh_surface(vol, labels=[1, 2], method="mc")
    opt = mc.optimize(wm.VolumeField(vol > 0, level=0.5), size=1.5)
    assert set(np.unique(opt.cell_refs["triangle"])) == {1, 2}
    grid = trimesh.creation.box((2, 2, 0.0001))
    top = grid.faces[grid.triangles_center[:, 2] > 0]  # an open square: two triangles
    flat = wm.Mesh(grid.vertices, {"triangle": top}).optimize(size=0.3)
    bnd = np.abs(np.abs(flat.points[:, :2]).max(1) - 1.0) < 1e-9
    assert flat.n_cells > 20 and bnd.sum() >= 8  # boundary kept, refined along it
    assert np.allclose(np.sort(np.unique(np.round(flat.points[bnd][:, :2], 9))), np.sort(np.unique(
        np.round(flat.points[bnd][:, :2], 9))))


# ----------------------------------------------------------------------------- simplify
def test_simplify_follows_curvature_within_tolerance():
    shape = wm.ellipsoid((1.0, 0.5, 0.5))
    mc = wm.mesh_surface(shape, bounds=((-1.1, -0.6, -0.6), (1.1, 0.6, 0.6)), resolution=64, method="mc")
    tol = 2e-3
    small = mc.simplify(shape, tolerance=tol)
    assert small.n_cells < 0.5 * mc.n_cells and _closed_oriented(small)
    assert small.stats()["euler"] == 2 and small.stats()["q_worst"] < 5
    err = wm.surface_error(small, shape)
    assert err["max"] < 2 * tol and err["mean"] < tol
    # density follows curvature: the tips (|x| > 0.9, curvature 4) are finer than the waist
    tri = small.triangles
    area = wm.cells.topology.face_areas(small.points, tri)
    cx = small.points[tri].mean(1)[:, 0]
    assert np.median(area[np.abs(cx) > 0.9]) < 0.8 * np.median(area[np.abs(cx) < 0.3])


def test_simplify_places_every_vertex_within_tolerance_on_sharp_edges():
    """The part's hole rims and box edges: a crease vertex slid along its polyline, or the
    midpoint of a feature edge split there, lies on a chord of the crease; where the chord is
    farther from the surface than the tolerance it goes onto f = 0 (before: vertices 3x the
    tolerance away, 0.0060 for 0.002). Faces across a corner the creases do not reach keep
    at most the input's distance."""
    shape, bounds = wm.example("part")
    mc = wm.mesh_surface(shape, bounds=bounds, resolution=64, method="mc")
    tol = 0.002
    before = wm.surface_error(mc, shape)
    small = mc.simplify(shape, tolerance=tol)
    err = wm.surface_error(small, shape)
    assert err["vertex_max"] <= tol * (1 + 1e-6)
    assert err["max"] < before["max"] and err["mean"] < before["mean"]
    assert small.n_cells < 0.3 * mc.n_cells and _closed_oriented(small)
    assert small.stats()["self_intersections"] == 0


def test_simplify_to_a_fraction():
    shape, bounds = wm.example("sphere")
    mc = wm.mesh_surface(shape, bounds=bounds, resolution=64, method="mc")
    small = mc.simplify(shape, fraction=0.1, tolerance=0.01)
    assert 0.09 * mc.n_cells < small.n_cells < 0.11 * mc.n_cells
    assert _closed_oriented(small) and small.stats()["q_worst"] < 2.0
    assert wm.surface_error(small, shape)["max"] <= 0.01 * (1 + 1e-6)


def _labels_two_bodies(n=40):
    """A 0/1/2 label volume: a torus-like ring (label 1, genus 1) and an ellipsoid (label 2)."""
    g = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    lab = np.zeros((n, n, n), np.uint8)
    lab[(np.hypot(np.hypot(x + 0.35, y) - 0.35, z) < 0.2)] = 1
    lab[((x - 0.55) / 0.3) ** 2 + (y / 0.5) ** 2 + (z / 0.4) ** 2 < 1] = 2
    return lab, 2.0 / (n - 1)


def test_simplify_labelled_volume_stays_manifold_and_within_tolerance():
    # a segmentation's staircase: MC of the 0/1 indicator, decimated against its trilinear field
    lab, h = _labels_two_bodies()
    mc = wm.mesh_surface(lab, labels=[1], spacing=(h,) * 3, origin=(-1.0,) * 3, method="mc")
    field = wm.VolumeField((lab == 1).astype(np.float32), spacing=h, origin=-1.0, level=0.5)
    small = wm.simplify(mc, field, tolerance=h, fraction=0.1)
    s = small.stats()
    assert 0.08 * mc.n_cells < small.n_cells < 0.12 * mc.n_cells
    assert _closed_oriented(small) and s["euler"] == mc.stats()["euler"] == 0
    assert np.isfinite(small.quality()).all() and s["q_worst"] < 10
    err = wm.surface_error(small, field)
    assert err["vertex_max"] < 0.05 * h and err["max"] <= h * (1 + 1e-6)
    # with no function: the input mesh is the reference
    ref = wm.simplify(mc, None, tolerance=h, fraction=0.2)
    assert _closed_oriented(ref) and ref.stats()["euler"] == 0 and ref.n_cells < 0.25 * mc.n_cells
    assert wm.surface_error(ref, reference=(mc.points, mc.triangles))["vertex_max"] < 1e-6


# ----------------------------------------------------------------------------- bad input
def test_bad_input_is_named(sphere_mc):
    shape, mc = sphere_mc
    with pytest.raises(TypeError, match="'mesh'"):
        wm.optimize(mc.points, shape)
    with pytest.raises(ValueError, match="'mesh'"):
        wm.optimize(wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}), shape)
    tets = wm.mesh_domain(shape, bounds=((-1.2,) * 3, (1.2,) * 3), size=0.5)  # (the tetra were dropped silently)
    for op in (wm.optimize, wm.simplify):
        with pytest.raises(ValueError, match=r"expected a triangle surface for 'mesh', got \['tetra'\] cells too"):
            op(tets, shape)
    with pytest.raises(ValueError, match="'size'"):
        wm.optimize(mc, shape, size=-1.0)
    with pytest.raises(ValueError, match="'size'"):
        wm.optimize(mc, shape, size="fine")
    with pytest.raises(ValueError, match="'tolerance'"):
        wm.optimize(mc, shape, tolerance=0.0)
    with pytest.raises(ValueError, match="'iterations'"):
        wm.optimize(mc, shape, iterations=-2)
    with pytest.raises(TypeError, match="'features'"):
        wm.optimize(mc, shape, features="yes")
    with pytest.raises(TypeError, match="'shape'"):
        wm.optimize(mc, "sphere")
    with pytest.raises(ValueError, match="'fraction'"):
        wm.simplify(mc, shape, fraction=0.0)
    with pytest.raises(ValueError, match="'fraction'"):
        wm.simplify(mc, shape, fraction=float("nan"))
    with pytest.raises(TypeError, match="'fraction'"):
        wm.simplify(mc, shape, fraction="0.1")
    with pytest.raises(ValueError, match="'iterations'"):
        wm.simplify(mc, shape, iterations=2.5)
    with pytest.raises(ValueError, match="'tolerance'"):
        wm.simplify(mc, shape, tolerance=float("inf"))
    with pytest.raises(TypeError, match="'features'"):
        wm.simplify(mc, shape, features=1)
    with pytest.raises(ValueError, match="'values'"):
        wm.VolumeField(np.full((4, 4, 4), np.nan))
    with pytest.raises(ValueError, match="'values'"):
        wm.VolumeField(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="'bounds'"):
        wm.optimize(mc, shape, bounds=((1, 1, 1), (0, 0, 0)))
    fan = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]],
                  {"triangle": [[0, 1, 2], [0, 1, 3], [0, 1, 4]]})
    with pytest.raises(TopologyError, match="edge-manifold"):
        wm.optimize(fan, shape)


def test_degenerate_far_and_out_of_range_input_is_refused_in_seconds(sphere_mc):
    """Issue 19 item 5: inputs that hung optimize or simplify get a clear error naming the
    argument (each call here takes about a second)."""
    shape, bounds = wm.example("sphere")
    small = wm.mesh_surface(shape, bounds=bounds, resolution=8, method="mc")  # 440 triangles
    pts, tri = small.points, small.triangles
    for run in (wm.optimize, wm.simplify):
        # a cell with a repeated vertex, which Mesh accepts (files carry collapsed cells)
        with pytest.raises(ValueError, match="'mesh'.*triangle 440, vertices \\[0, 1, 0\\]"):
            run(wm.Mesh(pts, {"triangle": np.vstack([tri, [[0, 1, 0]]])}), shape)
        with pytest.raises(ValueError, match="non-zero area"):
            run(wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 0]]}))
        # many points moved onto one: flat triangles
        p = pts.copy()
        p[: len(p) // 3] = p[0]
        with pytest.raises(ValueError, match="non-zero area"):
            run(wm.Mesh(p, {"triangle": tri}), shape)
        for scale in (1e-150, 1e150):
            with pytest.raises(ValueError, match="'mesh' whose extent"):
                run(small.transform(wm.transforms.dilation(scale, dim=3)))
        # a strip far from the shape: refused by the distance check, naming the default tolerance
        strip = wm.Mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]]) + 100,
                        {"triangle": [[0, 1, 2], [1, 3, 2]]})
        with pytest.raises(ValueError, match="'shape'.*the default"):
            run(strip, shape)
    # a size whose unit mesh would not fit in memory
    with pytest.raises(wm.SizeError, match="'size'"):
        wm.optimize(small, shape, size=1e-6)
    # the limits are the range's ends: 1e-50 still works
    tiny = wm.optimize(small.transform(wm.transforms.dilation(1e-50, dim=3)), iterations=1)
    assert tiny.stats()["watertight"] and tiny.stats()["q_worst"] < small.stats()["q_worst"]


def test_surface_sample_points_cover_vertices_midpoints_centroids():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    s = surface_sample_points(pts, np.array([[0, 1, 2]]))
    assert len(s) == 7 and np.allclose(s[-1], [1 / 3, 1 / 3, 0])


def test_simplify_never_returns_more_triangles_than_its_input():
    """The CLI's `warpmesh mesh --example sphere --resolution 8 --simplify 0.1` returned 722
    triangles from 440: the polish passes' error splits outgrew the decimation. A decimation
    now ends with at most the input's count (else the latest pass that did, else the input,
    with a warning saying why)."""
    shape, bounds = wm.example("sphere")
    for resolution in (8, 12):
        m = wm.mesh_surface(shape, bounds=bounds, resolution=resolution)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = m.simplify(shape, fraction=0.1)
        assert out.n_cells <= m.n_cells, (resolution, out.n_cells, m.n_cells)
        assert out.stats()["watertight"]


def test_the_progress_bar_says_which_operation_runs(capsys):
    """(simplify's bar said "optimize".)"""
    shape, bounds = wm.example("sphere")
    mc = wm.mesh_surface(shape, bounds=bounds, resolution=16, method="mc")
    mc.simplify(shape, fraction=0.5, iterations=1, progress=True)
    err = capsys.readouterr().err
    assert "simplify:" in err and "optimize:" not in err
    mc.optimize(shape, iterations=1, progress=True)
    assert "optimize:" in capsys.readouterr().err
