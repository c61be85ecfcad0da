"""method="delaunay": the seed's second global variant [FG §16.5.2] (lattice and surface points,
the Delaunay kernel, boundary recovery, optimisation), with the output checks of stuffing:
positive, conforming, closed, manifold, outward, embedded, the true Euler characteristic,
boundary vertices on the clipped surface, refs, and the volume of the shape."""

from __future__ import annotations

import math

import numpy as np
import pytest

import warpmesh as wm
from tests.solid.test_stuffing import _check_volume_mesh
from warpmesh.errors import WarpMeshError
from warpmesh.solid.delaunay import ClippedField, _nonmanifold, _thin, delaunay_tets, peel_slivers
from warpmesh.solid.dihedral import dihedral_angles


def _on_surface(vol, shape, box, h):
    """Largest distance estimate |d| / h of a boundary vertex from the clipped surface (float64)."""
    b = np.unique(vol.cells["triangle"])
    p = vol.points[b]
    f = shape.eval_numpy(p[:, 0], p[:, 1], p[:, 2])
    g = wm.evaluate(shape, p, gradient=True)[:, 1:]
    d = f / np.linalg.norm(g, axis=1)
    lo, hi = np.asarray(box, float)
    d = np.minimum(d, np.concatenate([p - lo, hi - p], axis=1).min(axis=1))
    return float(np.abs(d).max()) / h


def _report(capsys, name, vol):
    s = vol.stats()
    with capsys.disabled():
        stages = ", ".join(f"{q['stage']} {q['dihedral_min']:.2f}..{q['dihedral_max']:.2f}"
                           for q in s["quality_stages"])
        print(f"\ndelaunay {name}: {s['n_tetra']} tets, {s['delaunay_rounds']} rounds, "
              f"{s['recovery_inserted']} inserted; dihedral {stages}")


def test_sphere_checks_volume_and_surface(capsys):
    shape, box = wm.example("sphere")
    h = 0.2
    vol = wm.mesh_domain(shape, bounds=box, size=h, method="delaunay")
    s = _check_volume_mesh(vol, 2)  # positive, conforming, closed, manifold, outward, embedded, volumes add up
    assert s["method"] == "delaunay" and s["negative_tets"] == 0
    assert s["volume"] == pytest.approx(4 / 3 * math.pi, rel=0.01)
    assert _on_surface(vol, shape, box, h) <= 1e-3 and s["boundary_distance"] <= 1e-3
    assert set(vol.cell_refs["triangle"].tolist()) == {wm._conventions.SURFACE_REF}
    assert set(vol.cell_refs["tetra"].tolist()) == {1}
    ang = np.degrees(dihedral_angles(vol.points, vol.cells["tetra"]))
    assert ang.min() == pytest.approx(s["dihedral_min"]) and ang.min() > 0
    # the optimisation never lowers the smallest angle it starts from
    stages = [q["dihedral_min"] for q in s["quality_stages"]]
    assert stages[-1] >= stages[0]
    _report(capsys, "sphere 0.2", vol)


def test_torus_genus(capsys):
    shape, box = wm.example("torus")
    h = 0.15
    vol = wm.mesh_domain(shape, bounds=box, size=h, method="delaunay")
    s = _check_volume_mesh(vol, 0)
    assert s["volume"] == pytest.approx(2 * math.pi**2 * 0.35**2, rel=0.015)  # 1 % from size 0.12 (slow test)
    assert _on_surface(vol, shape, box, h) <= 1e-3
    _report(capsys, "torus 0.15", vol)


@pytest.mark.slow
def test_torus_volume_within_one_percent():
    shape, box = wm.example("torus")
    vol = wm.mesh_domain(shape, bounds=box, size=0.12, method="delaunay")
    s = _check_volume_mesh(vol, 0)
    assert s["volume"] == pytest.approx(2 * math.pi**2 * 0.35**2, rel=0.01)


def test_part_euler_and_creases(capsys):
    shape, box = wm.example("part")
    h = 0.12
    vol = wm.mesh_domain(shape, bounds=box, size=h, method="delaunay")
    s = _check_volume_mesh(vol, -6)
    assert s["crease_points"] > 0 and s["feature_vertices"] > 0
    assert _on_surface(vol, shape, box, h) <= 1e-3
    _report(capsys, "part 0.12", vol)


@pytest.mark.parametrize("radius", [0.26, 0.35, 0.46])
def test_small_spheres_with_nothing_left_to_optimise(radius):
    """A coarse size on a small sphere: the first smoothing and flips leave no tetrahedron
    below the optimisation threshold, so the second pass has nothing to do (it used to call
    the flips with no tetrahedra and stop with an IndexError)."""
    vol = wm.mesh_domain(wm.sphere(radius), bounds=((-1,) * 3, (1,) * 3), size=0.3, method="delaunay")
    s = _check_volume_mesh(vol, 2)
    assert s["volume"] == pytest.approx(4 / 3 * math.pi * radius**3, rel=0.2)  # a coarse inscribed polytope: 0.87-0.92


def test_flips_of_no_tetrahedra_are_no_flips():
    from warpmesh.solid.flips import flip_tets

    tets, info = flip_tets(np.zeros((3, 3)), np.zeros((0, 4), np.int64), np.zeros((0, 3), np.int64))
    assert tets.shape == (0, 4) and info["flips_23"] == info["flips_32"] == info["flips_44"] == 0


def test_caps_where_the_bounds_clip_the_shape():
    box = ((-0.7, -0.7, -0.7), (0.7, 0.7, 0.6))
    h = 0.2
    vol = wm.mesh_domain(wm.sphere(1.0), bounds=box, size=h, method="delaunay")
    s = _check_volume_mesh(vol, 2)
    refs = vol.cell_refs["triangle"]
    assert set(refs.tolist()) == {wm._conventions.SURFACE_REF, wm._conventions.CAP_REF}
    lo, hi = np.array(box)
    caps = vol.points[vol.cells["triangle"][refs == wm._conventions.CAP_REF]]  # (k, 3, 3)
    on_plane = ((np.abs(caps - lo) < 1e-9).all(axis=1) | (np.abs(caps - hi) < 1e-9).all(axis=1)).any(axis=1)
    assert on_plane.all()
    assert _on_surface(vol, wm.sphere(1.0), box, h) <= 1e-3
    rng = np.random.default_rng(1)  # the clipped volume by Monte Carlo on a fixed sample
    q = rng.uniform(lo, hi, (400_000, 3))
    assert s["volume"] == pytest.approx((np.einsum("ij,ij->i", q, q) < 1.0).mean() * np.prod(hi - lo), rel=0.01)


def test_recovery_gives_up_with_a_clear_error():
    shape, box = wm.example("part")
    pts, tets, on, info = delaunay_tets(shape, np.array(box, float), 0.2)
    assert info["delaunay_rounds"] > 1 and info["recovery_inserted"] > 0  # it needs recovery here...
    with pytest.raises(WarpMeshError, match="boundary recovery did not finish in 1 rounds"):
        delaunay_tets(shape, np.array(box, float), 0.2, max_rounds=1)  # ... so one round is not enough


def test_recovery_stops_when_rounds_repeat(monkeypatch):
    """A problem that new points never fix: the same counts three rounds in a row end it."""
    import warpmesh.solid.delaunay as D

    def stuck(field, points, tets, keep, on_surface, h):
        return np.array([[0.0, 0.0, 1.0]]), tets[:1], {"far_faces": 1}
    monkeypatch.setattr(D, "_recovery_targets", stuck)
    with pytest.raises(WarpMeshError, match="no progress"):
        delaunay_tets(wm.sphere(1.0), np.array([[-1.2] * 3, [1.2] * 3]), 0.3)


def test_thin_is_a_maximal_separated_subset():
    rng = np.random.default_rng(3)
    p = rng.uniform(0, 1, (2000, 3))
    keep = _thin(p, 0.1, rng)
    from scipy.spatial import cKDTree

    assert len(cKDTree(p[keep]).query_pairs(0.1)) == 0  # separated
    d, _ = cKDTree(p[keep]).query(p[~keep])
    assert d.max() < 0.1  # maximal: every dropped point has a kept one within the radius


def test_nonmanifold_finds_a_pinched_vertex_and_a_fin():
    # two tetrahedra sharing one vertex: their boundary pinches there
    tris = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    both = np.concatenate([tris, tris + 3])  # vertex 3 is in both
    faces, verts = _nonmanifold(both, 7)
    assert len(faces) == 0 and verts.tolist() == [3]
    # three faces on one edge
    fin = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    faces, _ = _nonmanifold(fin, 5)
    assert sorted(faces.tolist()) == [0, 1, 2]


def test_clipped_field_puts_rim_points_on_the_rim():
    box = np.array([[-2.0, -2.0, -2.0], [2.0, 2.0, 0.5]])
    fld = ClippedField(wm.sphere(1.0), box, rim=0.05)
    y, _ = fld.project(np.array([[0.9, 0.0, 0.5 - 1e-4], [0.0, 0.3, 0.7]]))
    assert y[0, 2] == 0.5 and abs(np.linalg.norm(y[0]) - 1.0) < 1e-6  # on the plane and the sphere
    assert y[1].tolist() == [0.0, 0.3, 0.5]  # inside the sphere: on the cap


def test_peel_keeps_the_boundary_manifold():
    shape, box = wm.example("torus")
    box = np.array(box, float)
    pts, tets, on, _ = delaunay_tets(shape, box, 0.2)
    kept, removed = peel_slivers(pts, tets, on, ClippedField(shape, box), 0.2)
    assert removed > 0 and len(kept) == len(tets) - removed
    from warpmesh.solid.pipeline import boundary_faces

    faces, verts = _nonmanifold(boundary_faces(kept), len(pts))
    assert len(faces) == 0 and len(verts) == 0


@pytest.mark.parametrize("kwargs, match", [
    ({"shape": wm.sphere(0.3, center=(5, 5, 5))}, "inside"),
    ({"size": 0.0}, "size"),
    ({"size": 3.0}, "size"),
    ({"bounds": ((float("nan"), 0, 0), (1, 1, 1))}, "bounds"),
    ({"alpha_long": 0.3}, "alpha_long"),
    ({"smooth": -1}, "smooth"),
    ({"feature_floor": 70}, "feature_floor"),
    ({"size": "curvature"}, "method='delaunay' takes a number 'size'; a graded 'size' \\('curvature'\\)"),
    ({"size": lambda p: np.full(len(p), 0.3)}, "graded 'size'.*use method='stuffing'"),
])
def test_bad_input_names_the_argument(kwargs, match):
    args = {"shape": wm.sphere(1.0), "bounds": ((-1.2,) * 3, (1.2,) * 3), "size": 0.3, "method": "delaunay",
            **kwargs}
    with pytest.raises(ValueError, match=match):
        wm.mesh_domain(args.pop("shape"), **args)


def test_command_line_domain_delaunay(capsys):
    from warpmesh.cli.commands import main

    assert main(["domain", "--example", "sphere", "--size", "0.3", "--method", "delaunay", "--json"]) == 0
    facts = __import__("json").loads(capsys.readouterr().out)
    assert facts["euler"] == 2 and facts["method"] == "delaunay" and facts["negative_tets"] == 0
