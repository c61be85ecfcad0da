"""Smoothing that never lowers the smallest dihedral angle: same connectivity, positive
tetrahedra, boundary vertices still on f = 0, cap vertices fixed, and a before/after table."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.solid.dihedral import dihedral_angles, signed_volumes


@pytest.mark.parametrize("name, size, bounds", [
    ("sphere", 0.15, None), ("torus", 0.1, None), ("part", 0.1, None),
    ("sphere", 0.12, ((-0.8, -0.8, -0.8), (0.8, 0.8, 0.7))),  # clipped: caps
])
def test_smoothing_never_lowers_the_smallest_dihedral_angle(name, size, bounds, capsys):
    shape, default = wm.example(name)
    bounds = bounds or default
    before = wm.mesh_domain(shape, bounds=bounds, size=size)
    after = wm.mesh_domain(shape, bounds=bounds, size=size, smooth=2)
    assert np.array_equal(before.cells["tetra"], after.cells["tetra"])
    a0 = np.degrees(dihedral_angles(before.points, before.cells["tetra"]))
    a1 = np.degrees(dihedral_angles(after.points, after.cells["tetra"]))
    assert a1.min() >= a0.min() and a1.max() <= a0.max()
    assert (signed_volumes(after.points, after.cells["tetra"]) > 0).all()
    s0, s1 = before.stats(), after.stats()
    assert s1["smooth_moved"] > 0 and s1["dihedral_min_before"] == pytest.approx(s0["dihedral_min"])
    tris, refs = after.cells["triangle"], after.cell_refs["triangle"]
    cap = np.unique(tris[refs == wm._conventions.CAP_REF])
    assert np.array_equal(after.points[cap], before.points[cap])  # cap vertices do not move
    assert s1["boundary_distance"] <= 1e-3
    with capsys.disabled():
        print(f"\n{name:7s} size {size}: dihedral min {s0['dihedral_min']:.2f} -> {s1['dihedral_min']:.2f}, "
              f"max {s0['dihedral_max']:.2f} -> {s1['dihedral_max']:.2f}, radius-edge max "
              f"{s0['radius_edge_max']:.2f} -> {s1['radius_edge_max']:.2f}, mean Q {s0['mean_q']:.3f} -> "
              f"{s1['mean_q']:.3f}, moved {s1['smooth_moved']}")
