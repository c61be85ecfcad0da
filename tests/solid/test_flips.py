"""2-3, 3-2 and 4-4 flips after smoothing (issue 20, part 4): the smallest dihedral angle never
drops, the largest never rises, the mesh stays conforming, positive, embedded, with the same
boundary and volume."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from tests.solid.test_stuffing import _check_volume_mesh
from warpmesh.solid.dihedral import dihedral_angles, signed_volumes
from warpmesh.solid.flips import flip_tets
from warpmesh.solid.pipeline import boundary_faces


def test_three_tetrahedra_around_a_long_edge_become_two():
    ang = 2 * np.pi * np.arange(3) / 3
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros(3)], axis=1)
    pts = np.vstack([[0, 0, 1.0], [0, 0, -1.0], ring])  # a = 0, b = 1, ring c d e = 2 3 4: 39° -> 63°
    tets = np.array([[0, 1, 2, 3], [0, 1, 3, 4], [0, 1, 4, 2]])
    tets[signed_volumes(pts, tets) < 0] = tets[signed_volumes(pts, tets) < 0][:, [0, 1, 3, 2]]
    tris = boundary_faces(tets)
    new, info = flip_tets(pts, tets, tris)
    assert info["flips_32"] == 1 and len(new) == 2
    assert sorted(map(sorted, new.tolist())) == [[0, 2, 3, 4], [1, 2, 3, 4]]
    assert (signed_volumes(pts, new) > 0).all()
    assert signed_volumes(pts, new).sum() == pytest.approx(signed_volumes(pts, tets).sum())
    assert dihedral_angles(pts, new).min() > dihedral_angles(pts, tets).min()
    assert set(map(frozenset, boundary_faces(new).tolist())) == set(map(frozenset, tris.tolist()))


def test_four_tetrahedra_around_an_edge_take_the_better_diagonal_of_their_ring():
    """Random octahedra (an axis and a ring of 4): where a 4-4 flip is made it raises the
    smallest angle, keeps the volume and the 8 outer faces, and gives positive tetrahedra
    around a diagonal of the ring; where none is made, no diagonal would have raised the
    smallest angle without raising the largest above the mesh's."""
    rng = np.random.default_rng(44)
    flipped = 0
    for _ in range(200):
        ang = 2 * np.pi * np.arange(4) / 4 + rng.uniform(-0.3, 0.3, 4)
        ring = np.stack([np.cos(ang), np.sin(ang), rng.uniform(-0.4, 0.4, 4)], axis=1)
        pts = np.vstack([[0, 0, rng.uniform(0.3, 1.5)], [0, 0, -rng.uniform(0.3, 1.5)], ring])
        tets = np.array([[0, 1, 2 + i, 2 + (i + 1) % 4] for i in range(4)])
        vol = signed_volumes(pts, tets)
        tets[vol < 0] = tets[vol < 0][:, [0, 1, 3, 2]]
        if (np.abs(vol) < 1e-3).any():
            continue
        tris = boundary_faces(tets)
        new, info = flip_tets(pts, tets, tris)
        before, after = dihedral_angles(pts, tets).min(), dihedral_angles(pts, new).min()
        assert after >= before and (signed_volumes(pts, new) > 0).all()
        assert signed_volumes(pts, new).sum() == pytest.approx(signed_volumes(pts, tets).sum())
        assert set(map(frozenset, boundary_faces(new).tolist())) == set(map(frozenset, tris.tolist()))
        if info["flips_44"]:
            flipped += 1
            assert after > before
            axis = {frozenset(e) for t in new.tolist() for e in ((t[0], t[1]),)}
            edges = {frozenset((t[i], t[j])) for t in new.tolist() for i in range(4) for j in range(i + 1, 4)}
            assert frozenset((0, 1)) not in edges, "the old axis is gone"
            assert axis and {frozenset((2, 4)), frozenset((3, 5))} & edges, "a diagonal of the ring is the new axis"
        else:
            for d in ((2, 4, 3, 5), (3, 5, 2, 4)):  # both diagonals, by hand
                p, q, r, s_ = d
                alt = np.array([[p, q, r, 0], [p, q, r, 1], [p, q, s_, 0], [p, q, s_, 1]])
                v = signed_volumes(pts, alt)
                alt[v < 0] = alt[v < 0][:, [0, 1, 3, 2]]
                fills = abs(np.abs(v).sum() - np.abs(signed_volumes(pts, tets)).sum()) < 1e-9
                if fills and info["flips_23"] + info["flips_32"] == 0:  # the flip rule: min up, max not above
                    ang = dihedral_angles(pts, alt)
                    assert ang.min() <= before + 1e-6 or ang.max() > dihedral_angles(pts, tets).max()
    assert flipped > 10


@pytest.mark.parametrize("name, smooth, euler", [("sphere", 2, 2), ("part", 2, -6)])
def test_flips_never_lower_the_smallest_angle(name, smooth, euler, capsys):
    shape, bounds = wm.example(name)
    vol = wm.mesh_domain(shape, bounds=bounds, size=0.08, smooth=smooth, flips=True)
    s = _check_volume_mesh(vol, euler)
    st = {q["stage"]: q for q in s["quality_stages"]}
    assert list(st) == ["stuffing", "features", "smooth", "flips"]
    assert st["flips"]["dihedral_min"] >= st["smooth"]["dihedral_min"]
    assert st["flips"]["dihedral_max"] <= st["smooth"]["dihedral_max"]
    ang = np.degrees(dihedral_angles(vol.points, vol.cells["tetra"]))
    assert ang.min() == pytest.approx(s["dihedral_min"]) and ang.min() >= 10.0
    if name == "sphere":  # the smoothed sphere has faces whose 2-3 flip helps
        assert s["flips_23"] > 0 and st["flips"]["dihedral_max"] < st["smooth"]["dihedral_max"]
    with capsys.disabled():
        print(f"\n{name}, size 0.08, smooth={smooth}, flips: " + ", ".join(
            f"{k} {v['dihedral_min']:.2f}..{v['dihedral_max']:.2f}" for k, v in st.items())
            + f" deg; {s['flips_23']} 2-3, {s['flips_32']} 3-2 and {s['flips_44']} 4-4 flips")


def test_flips_must_be_a_bool():
    with pytest.raises(ValueError, match="flips"):
        wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.3, flips=1)
