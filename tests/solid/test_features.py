"""Sharp features of stuffed meshes (issue 20, part 3): boundary vertices moved onto the
creases and corners of the exact surface, boundary edges split or flipped onto them, every
change kept only with dihedral angles in [10°, 165°] around it. Measured by the distance from
points of the exact edges to the nearest boundary edge of the mesh."""

from __future__ import annotations

import math

import numpy as np
import pytest

import warpmesh as wm
from tests.solid.test_stuffing import _check_volume_mesh
from warpmesh.solid.dihedral import dihedral_angles
from warpmesh.solid.features import example_edges, feature_distance

#: the part's exact volume: plate 2 x 2 x 0.6, four holes r = 0.2, the ball r = 0.5's two caps
#: beyond |z| = 0.3
PART_VOLUME = 2.4 - 4 * math.pi * 0.04 * 0.6 + (4 / 3 * math.pi * 0.125 - math.pi * (0.25 * 0.6 - 2 * 0.3**3 / 3))


def test_part_volume_constant_is_a_fine_grid_estimate():
    part, _ = wm.example("part")
    n = 100  # cell centres of a 100^3 grid over the part's box
    ax = (np.arange(n) + 0.5) / n
    x, y, z = np.meshgrid(2 * ax - 1, 2 * ax - 1, 1.0 * ax - 0.5, indexing="ij")
    inside = part.eval_numpy(x.ravel(), y.ravel(), z.ravel()) > 0
    assert inside.mean() * 4.0 == pytest.approx(PART_VOLUME, rel=5e-3)


def test_part_edges_are_sharp_with_dihedral_angles_in_10_165(capsys):
    part, bounds = wm.example("part")
    h = 0.08
    plain = wm.mesh_domain(part, bounds=bounds, size=h, features=False)
    vol = wm.mesh_domain(part, bounds=bounds, size=h)
    s = _check_volume_mesh(vol, -6)  # positive, conforming, closed, oriented, embedded, Euler -6
    ang = np.degrees(dihedral_angles(vol.points, vol.cells["tetra"]))
    assert ang.min() >= 10.0 and ang.max() <= 165.0, (ang.min(), ang.max())
    assert s["volume"] == pytest.approx(PART_VOLUME, rel=0.01)
    samples = example_edges("part", 200)
    d0 = feature_distance(plain.points, plain.cells["triangle"], samples) / h
    d1 = feature_distance(vol.points, vol.cells["triangle"], samples) / h
    assert d0.max() > 0.3 and (d0 > 0.05).mean() > 0.5  # stuffing alone cuts across the edges
    # every box edge, hole rim and the boss's concave crease within 0.05 h
    assert d1.max() <= 0.05, (d1.max(), (d1 > 0.05).mean())
    assert s["feature_undone"] == 0 and s["feature_corners"] == 8 and s["feature_vertices"] > 400
    stages = {q["stage"]: q for q in s["quality_stages"]}
    assert stages["features"]["dihedral_min"] >= 10.0 and stages["features"]["negative_tets"] == 0
    with capsys.disabled():
        print(f"\npart, size {h}: dihedral {stages['stuffing']['dihedral_min']:.2f}..{stages['stuffing']['dihedral_max']:.2f}"
              f" -> {s['dihedral_min']:.2f}..{s['dihedral_max']:.2f} deg; edge distance / h max {d0.max():.3f} -> "
              f"{d1.max():.4f}, beyond 0.05 h {100 * (d0 > 0.05).mean():.1f} % -> {100 * (d1 > 0.05).mean():.2f} %; "
              f"volume {s['volume']:.4f} (exact {PART_VOLUME:.4f}); {s['feature_vertices']} crease vertices, "
              f"{s['feature_splits']} splits, {s['feature_flips']} flips, {s['feature_open']} edges open")


def test_cap_edges_are_sharp_where_the_bounds_clip_a_sphere():
    h = 0.1
    vol = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2, -1.2, -1.2), (1.2, 1.2, 0.6)), size=h)
    s = _check_volume_mesh(vol, 2)
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    circle = np.stack([0.8 * np.cos(t), 0.8 * np.sin(t), np.full_like(t, 0.6)], axis=1)  # r = sqrt(1 - 0.36)
    d = feature_distance(vol.points, vol.cells["triangle"], circle) / h
    assert d.max() <= 0.05, d.max()
    assert s["dihedral_min"] >= 10.0 and s["dihedral_max"] <= 165.0
    assert s["volume"] == pytest.approx(math.pi * (2 / 3 + 0.6 - 0.6**3 / 3), rel=0.01)
    caps = vol.points[vol.cells["triangle"][vol.cell_refs["triangle"] == wm._conventions.CAP_REF]]
    assert np.allclose(caps[..., 2], 0.6, atol=1e-6)  # cap triangles still in their plane


def test_feature_distance_of_an_edge_on_a_segment():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
    d = feature_distance(pts, np.array([[0, 1, 2], [1, 3, 2]]), np.array([[0.5, -0.2, 0.0], [0.5, 0.5, 0.3]]))
    assert d.tolist() == pytest.approx([0.2, 0.3])


@pytest.mark.parametrize("bad", [{"feature_floor": -1.0}, {"feature_ceiling": 100.0}, {"feature_angle": "x"}])
def test_feature_options_are_checked(bad):
    with pytest.raises(ValueError, match=next(iter(bad))):
        wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.3, **bad)


def test_features_must_be_a_bool():
    with pytest.raises(ValueError, match="features"):
        wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.3, features="yes")


def _sharp_within(vol, samples, h, euler):
    """The exact-edge samples' distance / h to the mesh's edges; the mesh checked whole on the way."""
    s = _check_volume_mesh(vol, euler)
    ang = np.degrees(dihedral_angles(vol.points, vol.cells["tetra"]))
    assert ang.min() >= 10.0 and ang.max() <= 165.0, (ang.min(), ang.max())
    assert s["feature_undone"] == 0
    return feature_distance(vol.points, vol.cells["triangle"], samples) / h, s


@pytest.mark.parametrize("h", [0.16, pytest.param(0.12, marks=pytest.mark.slow)])
def test_part_edges_within_a_twentieth_of_h_at_coarse_sizes(h):
    # at 0.16 a hole is 2.5 h across: ring normals turn by tens of degrees there, which once made
    # false rim "corners" (56 at 0.16); samples beside a crease point that fell on the other face
    # of a curved wall left rim vertices without a crease point
    part, bounds = wm.example("part")
    d, s = _sharp_within(wm.mesh_domain(part, bounds=bounds, size=h), example_edges("part", 100), h, -6)
    assert d.max() <= 0.05, (d.max(), (d > 0.05).mean())
    assert s["feature_corners"] == 8  # the plate's, and no other


@pytest.mark.slow
@pytest.mark.parametrize("h", [0.06, 0.05])
def test_part_edges_within_a_twentieth_of_h_at_fine_sizes(h):
    part, bounds = wm.example("part")
    d, s = _sharp_within(wm.mesh_domain(part, bounds=bounds, size=h), example_edges("part", 200), h, -6)
    assert d.max() <= 0.05, (d.max(), (d > 0.05).mean())
    assert s["volume"] == pytest.approx(PART_VOLUME, rel=0.01)


def _circle(c, r, z, n=400):
    t = 2 * np.pi * (np.arange(n) + 0.5) / n
    return np.stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t), np.full(n, z)], axis=1)


def _box_edges(lo, hi, n=100):
    t = (np.arange(n) + 0.5) / n
    out = []
    for a in range(3):
        b, c = [k for k in range(3) if k != a]
        for vb in (lo[b], hi[b]):
            for vc in (lo[c], hi[c]):
                p = np.zeros((n, 3))
                p[:, a], p[:, b], p[:, c] = lo[a] + t * (hi[a] - lo[a]), vb, vc
                out.append(p)
    return np.concatenate(out)


def test_concave_circle_of_a_cylinder_standing_on_a_plate_is_sharp_but_in_one_place():
    # a second shape with a concave crease, off the lattice: the cylinder meets the plate's top
    # face in a concave circle (z = 0.3) and ends in a convex rim (z = 0.7). One boundary edge
    # stays open: from a wall vertex 0.5 h above the circle (refused there, with or without its
    # interior neighbours relocated) across the valley; the crease point lies 0.48 h off the
    # edge (no split) and the cap under it is not the two tetrahedra's (no flip). Stuffing alone:
    # 25 % of the samples within 0.05 h; features before this test: 97.8 %, 3 edges open
    h, c, r = 0.12, (0.17, -0.11), 0.33
    shape = wm.box((2, 2, 0.6)) | wm.cylinder(r, 1.0, center=(c[0], c[1], 0.2))
    vol = wm.mesh_domain(shape, bounds=((-1.2,) * 3, (1.2,) * 3), size=h)
    samples = np.concatenate([_box_edges((-1, -1, -0.3), (1, 1, 0.3)), _circle(c, r, 0.3), _circle(c, r, 0.7)])
    d, s = _sharp_within(vol, samples, h, 2)
    assert (d <= 0.05).mean() >= 0.99 and s["feature_open"] <= 1, (d.max(), (d > 0.05).mean())
    circles = np.linalg.norm(samples[:, :2] - c, axis=1) < r + 1e-9
    assert d[~circles].max() <= 0.05 and np.median(d[circles]) <= 0.02
    assert s["feature_corners"] == 8
    exact = 2.4 + math.pi * r * r * 0.4
    assert s["volume"] == pytest.approx(exact, rel=0.01)


def test_concave_square_of_two_boxes_is_sharp_but_near_its_corners():
    # a box standing on the plate: concave edges where it meets the plate's top, meeting its
    # convex vertical edges at four corners of three faces. Away from those corners every edge is
    # within 0.05 h; at them a crease vertex of one edge can link the corner to the next crease
    # (a chord across two creases), merged into the corner only when within 0.75 h of it
    h = 0.12
    lo, hi = np.array([-0.22, -0.52, -0.1]), np.array([0.48, 0.38, 0.7])
    shape = wm.box((2, 2, 0.6)) | wm.box(hi - lo, center=(lo + hi) / 2)
    vol = wm.mesh_domain(shape, bounds=((-1.2,) * 3, (1.2,) * 3), size=h)
    small = _box_edges(lo, hi)
    small = small[small[:, 2] >= 0.3 - 1e-9]  # the small box's edges above the plate
    concave = _box_edges(np.r_[lo[:2], 0.3], np.r_[hi[:2], 0.3])
    concave = concave[np.abs(concave[:, 2] - 0.3) < 1e-9]
    samples = np.concatenate([_box_edges((-1, -1, -0.3), (1, 1, 0.3)), small, concave])
    d, s = _sharp_within(vol, samples, h, 2)
    corner = np.array([[x, y, 0.3] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    near = np.linalg.norm(samples[:, None] - corner[None], axis=2).min(axis=1) < h
    assert d[~near].max() <= 0.05, d[~near].max()
    # near them: 0.23 h at this size, 0.11 h at 0.08 (stuffing alone: 0.48 h); 98.9 % of the
    # samples within 0.05 h (99.0 % before the tight check of crease points, TIGHT: it refuses
    # the 5 estimates that sit off the creases within 0.33 h of these corners)
    assert d.max() <= 0.25 and (d <= 0.05).mean() >= 0.985, (d.max(), (d > 0.05).mean())
    assert s["feature_corners"] == 16


def test_corners_are_confirmed_at_a_tenth_of_h():
    # the plate's corners are corners at any scale; points beside a hole's rim (where a ring of
    # h sees the wall turn) are not
    from warpmesh.frep.projection import ImplicitTarget
    from warpmesh.solid.features import _confirm_corners

    part, bounds = wm.example("part")
    target = ImplicitTarget(part, bounds=bounds)
    h = 0.12
    rng = np.random.default_rng(3)
    true = np.array([[sx, sy, sz * 0.3] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    ang = rng.uniform(0, 2 * np.pi, 8)
    rim = np.stack([0.6 + 0.215 * np.cos(ang), 0.6 + 0.215 * np.sin(ang), np.full(8, 0.3)], axis=1)
    ok, x = _confirm_corners(target, np.concatenate([true + rng.normal(0, 0.02 * h, true.shape), rim]), h)
    assert ok.tolist() == [True] * 8 + [False] * 8
    assert np.abs(x[:8] - true).max() < 1e-6  # refined onto the exact corners


def test_crease_points_on_the_exact_creases_from_points_near_them():
    # pairs whose first point lies within a tenth of h of the crease, on curved faces: a hole's
    # rim (plate / wall) and the boss's concave crease (plate / sphere)
    from warpmesh.frep.projection import ImplicitTarget
    from warpmesh.solid.features import crease_points

    part, bounds = wm.example("part")
    target = ImplicitTarget(part, bounds=bounds)
    h = 0.08
    pa = target.project(np.array([[-0.55, 0.812, -0.3], [0.38, 0.14, -0.3]]))
    pb = target.project(np.array([[-0.501, 0.774, -0.268], [0.346, 0.106, -0.346]]))
    c = crease_points(target, pa, pb, h, math.cos(math.radians(35)), near=0.5 * (pa + pb))
    assert np.isfinite(c).all()
    r_rim = np.hypot(c[0, 0] + 0.6, c[0, 1] - 0.6)
    r_boss = np.hypot(c[1, 0], c[1, 1])
    # second order in the samples' offset (0.1 h): 4e-7 h on the rim, 1e-3 h on the sphere of radius 6 h
    assert abs(r_rim - 0.2) < 1e-3 * h and abs(r_boss - 0.4) < 3e-3 * h, (r_rim, r_boss)
    assert np.allclose(c[:, 2], -0.3, atol=1e-6)


def test_a_tight_smooth_bend_is_not_a_crease():
    """A thin ellipsoid's rim (radius of curvature 0.0625 at h = 0.1) turns the normal by more
    than the feature angle across the crease samples: its "creases" moved the boundary 0.107
    off the surface, with dihedral angles down to 10.04 deg. Beside a crease point the normals
    must still differ TIGHT h away: a bend's do not."""
    shape = wm.ellipsoid((1.0, 0.5, 0.25))
    vol = wm.mesh_domain(shape, bounds=((-1.2,) * 3, (1.2,) * 3), size=0.1)
    s = vol.stats()
    assert s["boundary_distance"] < 1e-4 and s["dihedral_min"] > 15.0, (s["boundary_distance"], s["dihedral_min"])
