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
    # 99.5 % within 0.05 h; where the boss meets the plate (a concave crease) a few boundary edges
    # stay open (no snap, split or flip keeps the dihedral angles in [10°, 165°]): 0.13 h there
    assert (d1 <= 0.05).mean() >= 0.995 and d1.max() <= 0.15, (d1.max(), (d1 > 0.05).mean())
    assert s["feature_open"] <= 8
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
