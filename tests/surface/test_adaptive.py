"""Adaptive octree meshes (mesh_surface(adaptive=True)): crack-free, right topology, on the
surface, sharp where the shape is sharp, sparse in evaluations, dense where curved."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep import expr as E
from warpmesh.surface.adaptive.octree import ONE_SHEET, Octree, _cap_loses
from tests.helpers.random_shapes import random_shape
from tests.helpers.topology_oracle import CSG_PART_EXPECTED, DEGREE_SIX_EXPECTED

EXPECTED = {"sphere": (2, 1), "torus": (0, 1), "part": (CSG_PART_EXPECTED["surface_euler"], 1),
            "degree6": (DEGREE_SIX_EXPECTED["inside"]["surface_euler"], 1)}


def _distance(shape, points):
    fg = wm.evaluate(shape, points, gradient=True).astype(np.float64)
    return np.abs(fg[:, 0]) / np.linalg.norm(fg[:, 1:], axis=1)


@pytest.mark.parametrize("name", sorted(EXPECTED))
@pytest.mark.parametrize("features", [True, False])
def test_examples_closed_with_the_right_topology(name, features, check_mesh):
    shape, bounds = wm.example(name)
    m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=7, features=features)
    check_mesh(m)
    s = m.stats()
    assert (s["euler"], s["components"]) == EXPECTED[name], (name, s["euler"], s["components"])
    assert s["volume"] > 0  # outward


def test_sphere_volume_and_vertices_on_the_surface():
    m = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), adaptive=True, max_level=7)
    assert abs(m.stats()["volume"] - 4 / 3 * np.pi) < 0.01 * 4 / 3 * np.pi
    assert _distance(wm.sphere(1.0), m.points).max() < 1e-5  # Newton roots and projected fan vertices


@pytest.mark.parametrize("seed", range(12))
def test_random_shapes_are_closed_manifold_and_oriented(seed, check_mesh):
    """Property test: any shape, any refinement pattern: no crack, no non-manifold edge, no
    crossing (seeds 6 and 7 crossed before the untangling step: 24 and 8 pairs)."""
    shape = random_shape(np.random.default_rng(seed), 3)
    for features in (True, False):
        m = wm.mesh_surface(shape, bounds=((-1.5,) * 3, (1.5,) * 3), adaptive=True, max_level=5, min_level=3,
                            tolerance=0.01, features=features)
        if m.n_cells:
            check_mesh(m)
            assert m.stats()["volume"] > 0


def test_crack_free_across_three_levels(check_mesh):
    """A small bump on a flat face forces leaves of very different sizes side by side."""
    shape = wm.box((2, 2, 1)) | wm.sphere(0.12, center=(0.3, 0.2, 0.5))
    m = wm.mesh_surface(shape, bounds=((-1.3,) * 3, (1.3,) * 3), adaptive=True, max_level=8, min_level=3)
    check_mesh(m)
    levels = m.info["leaf_levels"]
    assert max(levels) - min(levels) >= 3, levels
    assert (m.stats()["euler"], m.stats()["components"]) == (2, 1)


def test_part_at_512_evaluations_tolerance_and_stats():
    shape, bounds = wm.example("part")
    m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=9)
    s = m.stats()
    assert s["watertight"] and s["oriented"] and (s["euler"], s["components"]) == EXPECTED["part"]
    assert s["dense_evaluations"] == 513 ** 3
    assert s["evaluations"] * 10 <= s["dense_evaluations"], s["evaluations"]
    h = m.info["finest_cell"][0]
    d = _distance(shape, m.points)
    assert d.max() < 0.1 * h, (d.max(), h)  # every vertex within a tenth of the finest cell
    for key in ("levels", "culled_fraction", "interval_evaluations", "gradient_evaluations", "time"):
        assert key in s
    assert 0.5 < s["culled_fraction"] < 1
    assert {"octree", "faces", "root", "fans"} <= set(s["time"])
    assert [lv["level"] for lv in s["levels"]] == list(range(3, 10))
    assert all(lv["mean_tape_length"] <= s["tape_length"] for lv in s["levels"])


def _edge_samples():
    """Points on the sharp edges of the part: plate rims and hole rims, away from the ball."""
    t = np.linspace(-0.9, 0.9, 37)
    rims = [np.stack([np.full_like(t, sx), t, np.full_like(t, sz)], 1) for sx in (-1, 1) for sz in (-0.3, 0.3)]
    a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    holes = [np.stack([cx + 0.2 * np.cos(a), cy + 0.2 * np.sin(a), np.full_like(a, z)], 1)
             for cx in (-0.6, 0.6) for cy in (-0.6, 0.6) for z in (-0.3, 0.3)]
    return np.concatenate(rims + holes)


def test_sharp_edges_are_reproduced():
    """With features, mesh edges run along the part's edges: the distance from the true
    edges to the mesh is a small fraction of the finest cell; without, they are chamfered."""
    shape, bounds = wm.example("part")
    pts = _edge_samples()
    err = {}
    for features in (True, False):
        m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=8, features=features)
        _, closest = m.to_pyvista().find_closest_cell(pts, return_closest_point=True)
        dist = np.linalg.norm(closest - pts, axis=1)
        err[features] = dist / m.info["finest_cell"][0]
    assert np.median(err[True]) < 0.05 and err[True].max() < 0.25, err[True]
    assert np.median(err[False]) > 3 * np.median(err[True])


@pytest.mark.parametrize("option", [{"tolerance": 0.02}, {"chord": 3e-4}])
def test_density_follows_curvature(option):
    """Ellipsoid (1, 0.5, 0.25): shorter edges at the tips than on the flat sides, and
    fewer than half the triangles of the coarsest uniform grid (mc33) whose largest chord
    error (centroid to surface) is no larger."""
    shape = wm.ellipsoid((1.0, 0.5, 0.25))
    bounds = ((-1.1, -0.6, -0.35), (1.1, 0.6, 0.35))
    m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=8, **option)
    p, t = m.points, m.cells["triangle"]
    length = np.linalg.norm(p[t] - p[np.roll(t, 1, axis=1)], axis=2).mean(axis=1)
    c = p[t].mean(axis=1)
    tips = np.abs(c[:, 0]) > 0.95
    flat = (np.abs(c[:, 0]) < 0.3) & (np.abs(c[:, 1]) < 0.15)
    assert np.median(length[tips]) < 0.6 * np.median(length[flat])

    def chord(mesh):  # largest distance from a triangle's centroid to the surface
        return _distance(shape, mesh.points[mesh.cells["triangle"]].mean(axis=1)).max()

    target = chord(m)
    if "tolerance" in option:  # relative: the chord error allowed grows with the cell (delta <= eps h)
        return
    for res in (32, 64, 96, 128, 192, 256, 384):
        u = wm.mesh_surface(shape, bounds=bounds, resolution=res)
        if chord(u) <= target:
            break
    assert chord(u) <= target, "no uniform grid up to 384 reaches the adaptive chord error"
    assert len(t) < 0.5 * u.n_cells, (len(t), u.n_cells, res)


def test_tolerance_controls_chord_error():
    shape = wm.torus(1.0, 0.35)
    bounds = ((-1.5, -1.5, -0.5), (1.5, 1.5, 0.5))
    out = []
    for tol in (0.04, 0.01):
        m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=8, tolerance=tol)
        p, t = m.points, m.cells["triangle"]
        h = np.linalg.norm(p[t] - p[np.roll(t, 1, axis=1)], axis=2).max(axis=1)
        delta = _distance(shape, p[t].mean(axis=1))
        out.append((len(t), np.percentile(delta / h, 99)))
    assert out[1][0] > out[0][0] and out[1][1] < out[0][1], out
    assert out[1][1] < 0.01, out  # delta <= epsilon h (99th percentile; slivers aside)


def _minmax_part():
    holes = [wm.cylinder(0.2).translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
    plate = wm.difference(wm.box((2, 2, 0.6)), wm.union(*holes, method="minmax"), method="minmax")
    return wm.union(plate, wm.sphere(0.5), method="minmax")


def test_pruned_tapes_give_the_same_mesh():
    shape, bounds = _minmax_part(), wm.example("part")[1]
    a = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=7, prune=True)
    b = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=7, prune=False)
    assert a.cells["triangle"].shape == b.cells["triangle"].shape
    assert np.abs(a.points - b.points).max() < 1e-4
    lengths = [lv["mean_tape_length"] for lv in a.info["levels"]]
    assert max(lengths[2:]) < 0.6 * lengths[0], lengths  # deeper cells evaluate shorter tapes
    # R-function booleans are smooth: nothing to prune, so the octree stops trying
    r = wm.mesh_surface(wm.example("part")[0], bounds=bounds, adaptive=True, max_level=7)
    assert [lv["mean_tape_length"] for lv in r.info["levels"]][2:] == [r.info["tape_length"]] * 3


def test_lipschitz_bound(check_mesh):
    shape = wm.sphere(0.8) | wm.sphere(0.5, center=(0.8, 0, 0))  # R-function union: |grad f| <= 2
    bounds = ((-1.2, -1.0, -1.0), (1.5, 1.0, 1.0))
    m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6, bound="lipschitz", lipschitz=2.0)
    check_mesh(m)
    assert (m.stats()["euler"], m.stats()["components"]) == (2, 1)
    i = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6)
    assert m.info["interval_evaluations"] == 0 and i.info["interval_evaluations"] > 0


def test_one_sheet_table():
    assert ONE_SHEET[0] and ONE_SHEET[255] and ONE_SHEET[1] and ONE_SHEET[0b11]
    assert not ONE_SHEET[0b1001]  # two corners on a face diagonal: two sheets
    assert not ONE_SHEET[0b10000001]  # opposite corners
    assert ONE_SHEET.sum() == ONE_SHEET[255 - np.arange(256)].sum()  # symmetric in the sign


@pytest.mark.parametrize("kwargs, err, match", [
    ({"max_level": 9, "resolution": 512}, ValueError, "not both"),
    ({"max_level": 0}, ValueError, "max_level"),
    ({"max_level": 5, "min_level": 6}, ValueError, "min_level"),
    ({"tolerance": -1.0}, ValueError, "tolerance"),
    ({"tolerance": float("nan")}, ValueError, "tolerance"),
    ({"angles": (0.1,)}, ValueError, "angles"),
    ({"bound": "hull"}, ValueError, "bound"),
    ({"bound": "lipschitz"}, ValueError, "lipschitz"),
    ({"lipschitz": 1.0}, ValueError, "lipschitz"),
    ({"method": "mt"}, ValueError, "method"),
    ({"covering": "continuation"}, ValueError, "covering"),
    ({"prune": 1}, TypeError, "prune"),
    ({"root": "secant"}, ValueError, "root"),
])
def test_bad_options(kwargs, err, match):
    shape, bounds = wm.example("sphere")
    with pytest.raises(err, match=match):
        wm.mesh_surface(shape, bounds=bounds, adaptive=True, **{"max_level": 4, **kwargs})


def test_adaptive_options_need_adaptive_and_a_shape():
    shape, bounds = wm.example("sphere")
    with pytest.raises(ValueError, match="tolerance"):
        wm.mesh_surface(shape, bounds=bounds, tolerance=0.1)
    with pytest.raises(TypeError, match="Shape"):
        wm.mesh_surface(np.zeros((4, 4, 4)), adaptive=True)
    with pytest.raises(TypeError, match="adaptive"):
        wm.mesh_surface(shape, bounds=bounds, adaptive="yes")


def test_nan_field_is_refused():
    x, _, _ = E.coords()
    with pytest.raises(ValueError, match="NaN"):
        wm.mesh_surface(wm.Shape(E.log(x)), bounds=((-1,) * 3, (1,) * 3), adaptive=True, max_level=4)


def test_empty_surface_warns():
    with pytest.warns(UserWarning, match="empty"):
        m = wm.mesh_surface(wm.sphere(0.1, center=(5, 5, 5)), bounds=((-1,) * 3, (1,) * 3), adaptive=True,
                            max_level=4)
    assert m.n_cells == 0


def test_closure_check_catches_holes_repeats_and_flips():
    from warpmesh.errors import WarpMeshError
    from warpmesh.surface.adaptive.contour import check_closed

    faces = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=12).cells["triangle"]
    check_closed(faces)
    for bad in (faces[1:], np.concatenate([faces, faces[:1]]), np.concatenate([faces[:1, ::-1], faces[1:]])):
        with pytest.raises(WarpMeshError):
            check_closed(bad)


def test_sorted_search_matches_searchsorted():
    from warpmesh.surface.adaptive.octree import search

    rng = np.random.default_rng(1)
    keys = np.sort(rng.integers(0, 1 << 40, 20000))
    for n in (10, 50000):
        q = np.concatenate([rng.choice(keys, n // 2), rng.integers(0, 1 << 40, n - n // 2)])
        assert np.array_equal(search(keys, q), np.searchsorted(keys, q))


def test_refined_to_the_finest_level_at_a_singular_point(check_mesh):
    """The double cone z^2 = x^2 + y^2 has grad f = 0 at its apex: the leaves there are the
    finest, while the flanks stay coarse; f = 0 counts as outside, so the two nappes are two
    closed components."""
    x, y, z = E.coords()
    m = wm.mesh_surface(wm.Shape(z * z - x * x - y * y), bounds=((-1,) * 3, (1,) * 3), adaptive=True,
                        max_level=7)
    check_mesh(m)
    assert (m.stats()["euler"], m.stats()["components"]) == (4, 2)
    p, t = m.points, m.cells["triangle"]
    centre = p[t].mean(axis=1)
    length = np.linalg.norm(p[t] - p[np.roll(t, 1, axis=1)], axis=2).mean(axis=1) / m.info["finest_cell"][0]
    assert length[np.linalg.norm(centre, axis=1) < 0.05].mean() < 1.2
    assert length[np.abs(np.abs(centre[:, 2]) - 0.7) < 0.05].mean() > 2.5


def test_caps_carry_their_ref():
    shape, bounds = wm.example("degree6")  # meets the box: closed by caps on it
    m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6)
    refs = m.cell_refs["triangle"]
    assert set(np.unique(refs)) == {1, 2}
    c = m.points[m.cells["triangle"][refs == 2]].mean(axis=1)
    assert np.all(np.abs(np.abs(c).max(axis=1) - 3.0) < 0.1)  # cap triangles lie on the box


@pytest.mark.parametrize("expr", ["zero", "min(x, 0)"])
def test_a_field_zero_on_whole_cells_is_not_refined(expr):
    """f = 0 on a cell is outside (as on the grid): such cells are culled, not refined 8x a
    level down to max_level (an identically zero field took 19 s at level 7) [issue 19 item 3]."""
    x, y, z = wm.coords()
    shape = wm.Shape(x * 0.0) if expr == "zero" else wm.Shape(wm.min(x, 0.0))
    bounds = ((-1, -1, -1), (1, 1, 1))
    with pytest.warns(UserWarning, match="empty"):
        m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=9)
    assert m.n_cells == 0
    assert sum(level["cells"] for level in m.info["levels"]) <= 8**4  # not 8**9: only cells at x = 0 refine
    with pytest.warns(UserWarning, match="empty"):
        assert wm.mesh_surface(shape, bounds=bounds, resolution=32).n_cells == 0  # the grid agrees


def test_a_field_zero_outside_a_ball_meshes_the_ball():
    x, y, z = wm.coords()
    ball = wm.Shape(wm.max(0.5 - wm.sqrt(x * x + y * y + z * z), 0.0))
    m = wm.mesh_surface(ball, bounds=((-1, -1, -1), (1, 1, 1)), adaptive=True, max_level=6)
    grid = wm.mesh_surface(ball, bounds=((-1, -1, -1), (1, 1, 1)), resolution=64)
    s = m.stats()  # f's linear roots sit on the outer nodes (f = 0 there): the grid's volume, not pi/6
    assert s["watertight"] and s["euler"] == 2 and abs(s["volume"] - grid.stats()["volume"]) < 0.01


@pytest.mark.parametrize("thickness", [0.05, 0.25, 0.4])
def test_thin_bounds_give_the_grids_volume_and_topology(thickness):
    """Bounds far from cube-like (one base cell across was the bug: half the volume, chi 0)."""
    bounds = ((-1.5, -1.5, -thickness), (1.5, 1.5, thickness))
    m = wm.mesh_surface(wm.sphere(1.0), bounds=bounds, adaptive=True, max_level=6)
    grid = wm.mesh_surface(wm.sphere(1.0), bounds=bounds, resolution=64)
    s, g = m.stats(), grid.stats()
    assert s["watertight"] and s["oriented"] and s["euler"] == g["euler"] == 2
    exact = np.pi * (2 * thickness - 2 * thickness**3 / 3)  # the unit ball between z = -t and t
    assert abs(s["volume"] - exact) < 0.01 * exact + 0.01 and abs(g["volume"] - exact) < 0.01 * exact + 0.01


@pytest.mark.parametrize("seed", range(8))
def test_random_bounds_match_the_grid(seed):
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-1.0, -0.2, 3)
    bounds = (tuple(lo), tuple(lo + rng.uniform(0.3, 2.0, 3)))
    ball = wm.sphere(float(rng.uniform(0.3, 0.7)), center=tuple(rng.uniform(-0.2, 0.2, 3)))
    m = wm.mesh_surface(ball, bounds=bounds, adaptive=True, max_level=6)
    grid = wm.mesh_surface(ball, bounds=bounds, resolution=64)
    s, g = m.stats(), grid.stats()
    assert s["watertight"] and s["euler"] == g["euler"]
    h = float(np.max(np.subtract(bounds[1], bounds[0]))) / 64  # a finest cell: the surfaces differ by a fraction
    assert abs(s["volume"] - g["volume"]) < 0.03 * g["volume"] + 0.5 * g["area"] * h
    assert np.all(m.points >= np.array(bounds[0])) and np.all(m.points <= np.array(bounds[1]))


@pytest.mark.parametrize("normal", [(0.3, 0.5, 0.8), (0.7, -0.2, 0.1)])
def test_no_vertex_outside_the_bounds(normal):
    """A slanted plane's feature vertices at the bounds were up to 1.7 finest cells outside."""
    m = wm.mesh_surface(wm.halfspace(normal=normal, point=(0.1, 0.2, 0.05)), bounds=((-1, -1, -1), (1, 1, 1)),
                        adaptive=True, max_level=8)
    assert np.all(np.abs(m.points) <= 1.0)
    s = m.stats()
    assert s["watertight"] and s["euler"] == 2 and len(wm.check(m)) == 0


def test_without_caps_the_surface_ends_on_the_bounds():
    """cap=False raised an internal error (a leaf's loops did not close) wherever the shape
    left the box; it is now the capped surface less its caps, open on the bounds."""
    bounds = ((-1.5, -1.5, -0.25), (1.5, 1.5, 0.25))
    capped = wm.mesh_surface(wm.sphere(1.0), bounds=bounds, adaptive=True, max_level=5)
    band = wm.mesh_surface(wm.sphere(1.0), bounds=bounds, adaptive=True, max_level=5, cap=False)
    s = band.stats()
    assert not s["watertight"] and s["euler"] == 0 and s["components"] == 1  # a band: two boundary loops
    assert band.n_cells == int(np.sum(capped.cell_refs["triangle"] == 1))
    edges = np.sort(band.cells["triangle"][:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    open_ends = band.points[uniq[count == 1].ravel()]
    assert len(open_ends) and np.allclose(np.abs(open_ends[:, 2]), 0.25, atol=1e-3)  # cap vertices sit 1e-3 cell off
    assert len(wm.check(band)) == 0


def test_a_thin_solid_against_the_bounds_is_kept():
    """A solid thinner than a coarse leaf, pressed against the bounds, vanished under the cap
    (its only inside corners were on the bounds): the octree refines such cells."""
    bounds = ((-1.2, -1.2, -1.2), (-0.94, 1.2, 1.2))  # the ball's cap x < -0.94: 0.06 thick
    m = wm.mesh_surface(wm.sphere(1.0), bounds=bounds, adaptive=True, max_level=7)
    g = wm.mesh_surface(wm.sphere(1.0), bounds=bounds, resolution=128)
    s = m.stats()
    exact = np.pi * 0.06 ** 2 * (3 - 0.06) / 3  # the cap of height 0.06 of the unit ball
    assert s["watertight"] and s["euler"] == g.stats()["euler"] == 2 and s["components"] == 1
    assert abs(s["volume"] - exact) < 0.1 * exact


def _corner_values(inside_corners) -> np.ndarray:
    return np.array([[1.0 if k in inside_corners else -1.0 for k in range(8)]], np.float32)


@pytest.mark.parametrize("inside, refine", [
    ({0, 1, 2, 3, 4, 5}, True),  # a slab on z = 0 whose top crosses the cell: the cap hides its edge 2-6 crossing
    ({0, 1, 2, 3}, True),  # a slab thinner than the cell: nothing left above the cap
    ({0, 1, 4, 5}, False),  # a wall standing on the bounds: every crossing is still seen
    (set(range(8)), False),  # solid through the whole cell: the cap only closes it
    ({4, 5}, False),  # nothing inside on the bounds: the cap changes nothing
])
def test_cap_refines_the_cells_whose_crossings_it_hides(inside, refine):
    """A cell on the bounds z = 0 (corners 0-3; corner k at (k & 1, k >> 1 & 1, k >> 2)): the cap
    counts its corners there as outside, so an edge from an inside corner on the bounds to an
    outside one off them loses its crossing (seed 102141 of the topology fuzz: a slab under
    coarse leaves lost its part below the leaves' corners, and the solid gained a handle)."""
    tree = Octree(np.zeros(3), np.full(3, 0.1), np.array([16, 16, 16]), 4, 1, True, None, None, (), None, None)
    assert _cap_loses(tree, 2, np.array([[1, 1, 0]]), _corner_values(inside))[0] == refine


def test_a_rod_beside_a_plane_in_coarse_leaves_is_kept():
    """Two sheets in one coarse leaf that its corners do not show: a slab's flat top and, above
    it in the same level-3 cells, a rod (0.06 across) between two balls. The rod runs along the
    middle of the cells, so it shifts their four top corners' values alike: the crossings stay
    coplanar and the cells pass every criterion as leaves. Only the balls' cells are refined,
    and their finer nodes show the rod on a coarse leaf's face: that leaf's boundary holds the
    slab's loop and the rod's. Fanning each loop on its own (no rebuild) caps the rod where it
    enters the coarse leaves and loses it in them: the balls come apart, (6, 3). The rebuild
    refines those leaves, which shows the rod to the next coarse leaves along it: a third
    octree round, and the grid's (4, 2)."""
    slab = wm.box((2.4, 2.4, 1.0), center=(0.0, 0.0, -0.42))  # top at z = 0.08, in the cells 0 < z < 0.25
    rod = wm.capsule((-0.65, 0.125, 0.21), (0.65, 0.125, 0.21), 0.03)  # the middle of the cells 0 < y < 0.25
    balls = [wm.sphere(0.12, center=(x, 0.125, 0.3)) for x in (-0.65, 0.65)]
    shape = wm.union(slab, rod, *balls, method="minmax")
    bounds = ((-1.0,) * 3, (1.0,) * 3)
    m = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=7, min_level=3)
    grid = wm.mesh_surface(shape, bounds=bounds, resolution=128).stats()
    s = m.stats()
    assert m.info["octree_rounds"] == 3, m.info["octree_rounds"]
    assert (s["euler"], s["components"]) == (grid["euler"], grid["components"]) == (4, 2)
    assert s["watertight"] and s["oriented"] and len(wm.check(m)) == 0


def test_a_lipschitz_bound_below_the_slope_is_a_clear_error():
    """The part's R-function field has slope up to 5.24 (lipschitz_bound): L = 1 culls cells
    the surface crosses, which raised "a leaf's segments do not close into loops (an internal
    error)"."""
    part, bounds = wm.example("part")
    with pytest.raises(ValueError, match="lipschitz=1.0: a bound below the field's largest slope"):
        wm.mesh_surface(part, bounds=bounds, adaptive=True, bound="lipschitz", lipschitz=1.0, max_level=6)
    ok = wm.mesh_surface(part, bounds=bounds, adaptive=True, bound="lipschitz", lipschitz=6.0, max_level=6)
    assert ok.stats()["watertight"]
