"""Graded isosurface stuffing (issue 20 part 2): ``size`` a function of position or
``"curvature"``.

The background (the BCC lattice under conforming longest-edge bisection) is checked on its
own: positive, conforming (no hanging node: its boundary is the coarse lattice's), four
similarity classes, every tetrahedron no longer than the size asked. The meshes: positive,
conforming, boundary closed, manifold, outward and embedded with the true Euler
characteristic, boundary vertices on f = 0, the exact volume within 1 %, local edge lengths
following the size, fewer tetrahedra than the uniform lattice at the smallest size, and the
measured dihedral range in ``info``. Sizes are coarse so the whole file runs in seconds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import warpmesh as wm
from tests.helpers.cellcheck import check_cells
from tests.helpers.fuzz_settings import seeded
from tests.helpers.meshcheck import check_mesh
from warpmesh.solid.dihedral import dihedral_angles, signed_volumes
from warpmesh.solid.graded import curvature_size, refine_bcc, size_field, tet_edges
from warpmesh.solid.stencils import EDGES, REFERENCE_TET, ranked_stencil_tables, sign_code, stencil

SPHERE = (wm.sphere(1.0), ((-1.2,) * 3, (1.2,) * 3), 4.0 / 3.0 * math.pi, 2)
TORUS = (wm.torus(1.0, 0.35), ((-1.5, -1.5, -0.5), (1.5, 1.5, 0.5)), 2 * math.pi**2 * 0.35**2, 0)


def ramp(lo: float, hi: float, axis: int, a: float, b: float):
    """A size growing linearly from ``lo`` (coordinate ``a`` of ``axis``) to ``hi`` (``b``)."""
    return lambda p: lo + (hi - lo) * np.clip((p[:, axis] - a) / (b - a), 0.0, 1.0)


def _edge_lengths(points, tets):
    e = np.array(EDGES)
    return np.linalg.norm(points[tets[:, e[:, 0]]] - points[tets[:, e[:, 1]]], axis=2)


def _check_graded(vol: wm.Mesh, euler: int) -> dict:
    tets, tris = vol.cells["tetra"], vol.cells["triangle"]
    cells = check_cells(wm.Mesh(vol.points, {"tetra": tets}))  # positive, conforming, closed, embedded
    surf = check_mesh(vol.points, tris)  # closed, manifold, oriented, embedded
    assert surf["n_faces"] == cells["n_boundary"] == len(tris)
    s = vol.stats()
    assert s["euler"] == euler and s["watertight"] and s["manifold"] and s["oriented"]
    vols = signed_volumes(vol.points, tets)
    assert (vols > 0).all()
    enclosed = wm.Mesh(vol.points, {"triangle": tris}).stats()["volume"]
    assert vols.sum() == pytest.approx(enclosed, rel=1e-9)
    info = vol.info
    assert info["graded"] and info["background_tets"] > 0
    # the measured dihedral range of the stuffed mesh is reported, and the final one too
    assert 0.0 < info["graded_dihedral_min"] <= info["graded_dihedral_max"] < 180.0
    ang = np.degrees(dihedral_angles(vol.points, tets))
    assert s["dihedral_min"] == pytest.approx(ang.min()) and s["dihedral_max"] == pytest.approx(ang.max())
    # boundary vertices on f = 0: within 1e-3 of the smallest size (so of the local size too)
    assert s["boundary_distance"] <= 1e-3
    return s


def test_background_conforms_with_four_similarity_classes():
    box = np.array([[-1.0] * 3, [1.0] * 3])
    size = ramp(0.1, 1.0, 0, -1.0, 1.0)
    field = size_field(size, box)
    coords, tets, levels = refine_bcc(np.array([5, 5, 5]), 0.8, np.full(3, -1.2), field)
    assert levels.max() >= 6 and (levels == 0).any()
    vols = signed_volumes(coords, tets)
    assert (vols > 0).all()
    coarse, ctets, _ = refine_bcc(np.array([5, 5, 5]), 0.8, np.full(3, -1.2), size_field(lambda p: 1.0 + 0 * p[:, 0], box))
    assert vols.sum() == pytest.approx(signed_volumes(coarse, ctets).sum(), rel=1e-12)
    faces = np.concatenate([np.sort(tets[:, list(f)], axis=1) for f in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))])
    _, counts = np.unique(faces, axis=0, return_counts=True)
    assert counts.max() == 2
    # no hanging vertex: the faces in one tetrahedron are the coarse lattice's boundary, same area

    def boundary_area(c, t):
        f = np.concatenate([np.sort(t[:, list(x)], axis=1) for x in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))])
        u, k = np.unique(f, axis=0, return_counts=True)
        b = c[u[k == 1]]
        return 0.5 * np.linalg.norm(np.cross(b[:, 1] - b[:, 0], b[:, 2] - b[:, 0]), axis=1).sum()

    assert boundary_area(coords, tets) == pytest.approx(boundary_area(coarse, ctets), rel=1e-12)
    # four similarity classes, by their sorted edge-length ratios: the BCC tetrahedra left
    # whole, and the cycle of three (half, quarter = Kuhn, third) of the bisected ones
    lengths = np.sort(_edge_lengths(coords, tets), axis=1)
    ratios = np.round(lengths / lengths[:, -1:], 9)
    assert len(np.unique(ratios, axis=0)) == 4
    r3 = math.sqrt(3) / 2
    assert np.allclose(ratios[levels == 0], [r3, r3, r3, r3, 1, 1])
    for k in range(3):  # a bisected tetrahedron's class is its level modulo 3
        assert len(np.unique(ratios[(levels > 0) & (levels % 3 == k)], axis=0)) == 1
    ang = np.degrees(dihedral_angles(coords, tets))
    assert ang.min() == pytest.approx(45.0) and ang.max() == pytest.approx(120.0)
    # every tetrahedron no longer than the size at its centroid (half-cube units: h0 / 2 = 0.4)
    centroid = np.full(3, -1.2) + coords[tets].mean(axis=1) * 0.4
    assert (lengths[:, -1] * 0.4 <= size(centroid) * (1 + 1e-9)).all()
    # edges shared: every tetrahedron lists each of its six edges once
    assert (np.diff(np.sort(tet_edges(tets), axis=1), axis=1) > 0).all()


def _face_bits(order, signs, pos) -> int:
    """The fill kernel's face bits of a tetrahedron listing nodes ``order`` (by id): bit o when
    the face off local vertex o has inside p < q and outside n, and q is closer to n."""
    bits = 0
    for o in range(4):
        face = [v for v in range(4) if v != o]
        plus = [v for v in face if signs[order[v]] > 0]
        minus = [v for v in face if signs[order[v]] < 0]
        if len(plus) == 2 and len(minus) == 1:
            (p, q), n = plus, minus[0]
            dp = np.sum((pos[order[p]] - pos[order[n]]) ** 2)
            dq = np.sum((pos[order[q]] - pos[order[n]]) ** 2)
            bits |= int(dq < dp) << o
    return bits


def test_ranked_stencils_are_positive_and_split_shared_faces_alike():
    """Every sign pattern and face bits on random tetrahedra with random cut points: positive
    pieces (bits that would make a prism's diagonals cyclic are marked -1: no total order
    gives them); and two tetrahedra sharing a face (vertices listed by global id, bits from
    the distances) cut that face into the same triangles."""
    rng = np.random.default_rng(3)
    count, table = ranked_stencil_tables()
    assert (count >= -1).all() and (count <= 3).all() and (count == -1).sum() < 32
    for signs in np.array(np.meshgrid(*[[-1, 0, 1]] * 4, indexing="ij")).reshape(4, -1).T:
        for bits in range(16):
            case = sign_code(signs) * 16 + bits
            if count[case] < 0:
                continue
            assert count[case] == len(stencil(signs, bits, ranked=True))
            for _ in range(3):
                tet = REFERENCE_TET + rng.uniform(-0.2, 0.2, (4, 3))
                t = rng.uniform(0.05, 0.95, 6)
                pos = np.vstack([tet, [tet[a] + t[k] * (tet[b] - tet[a]) for k, (a, b) in enumerate(EDGES)]])
                pieces = table[case, :count[case]]
                if len(pieces):
                    assert (signed_volumes(pos, pieces) > 0).all(), (signs, bits)
    # shared faces: five random nodes ranked by a random id; tetrahedra (0..3), (1..4) share (1, 2, 3)
    for _ in range(400):
        ids = rng.permutation(5)
        s = rng.integers(-1, 2, 5)
        pos = rng.normal(size=(5, 3))

        def face_triangles(nodes):
            order = sorted(nodes, key=lambda v: ids[v])
            bits = _face_bits(order, s, pos)
            case = sign_code([s[v] for v in order]) * 16 + bits
            assert count[case] >= 0, "bits from distances are never cyclic"
            out = set()
            for piece in stencil([s[v] for v in order], bits, ranked=True):
                names = []
                for r in piece:
                    if r < 4:
                        names.append(("node", order[r]))
                    else:
                        a, b = EDGES[r - 4]
                        names.append(("cut", frozenset((order[a], order[b]))))
                for drop in range(4):
                    tri = [x for k, x in enumerate(names) if k != drop]
                    on_face = all((x[0] == "node" and x[1] in (1, 2, 3)) or (x[0] == "cut" and x[1] <= {1, 2, 3})
                                  for x in tri)
                    if on_face:
                        out.add(frozenset(tri))
            return out

        a, b = face_triangles([0, 1, 2, 3]), face_triangles([1, 2, 3, 4])
        if a and b:
            assert a == b, (ids, s)
        else:  # a face covered from one side only lies on f = 0: no inside node on it
            assert all(s[v] <= 0 for v in (1, 2, 3)) and all(x[0] == "node" for t in a | b for x in t), (ids, s)


@pytest.mark.parametrize("case", ["sphere", "torus"])
def test_graded_smooth_shapes(case):
    shape, bounds, exact, euler = {"sphere": SPHERE, "torus": TORUS}[case]
    lo, hi = (0.1, 0.3) if case == "sphere" else (0.07, 0.2)
    size = ramp(lo, hi, 0, bounds[0][0] + 0.2, bounds[1][0] - 0.2)
    vol = wm.mesh_domain(shape, bounds=bounds, size=size, features=False)  # smooth: no creases
    s = _check_graded(vol, euler)
    assert s["volume"] == pytest.approx(exact, rel=0.01)
    # fewer tetrahedra than the uniform lattice at the smallest size
    assert vol.info["size_smallest"] == pytest.approx(lo)
    uniform = wm.mesh_domain(shape, bounds=bounds, size=lo, features=False)
    assert len(vol.cells["tetra"]) < 0.85 * len(uniform.cells["tetra"])
    # local edge lengths follow the size: the median edge of the tetrahedra in a slab
    pts, tets = vol.points, vol.cells["tetra"]
    cen = pts[tets].mean(axis=1)
    lengths = _edge_lengths(pts, tets)
    for x0 in (bounds[0][0] + 0.3, 0.0, bounds[1][0] - 0.5):
        slab = np.abs(cen[:, 0] - x0) < 0.15
        assert slab.sum() > 50
        ratio = np.median(lengths[slab]) / np.median(size(cen[slab]))
        assert 0.5 <= ratio <= 2.0, (x0, ratio)
    left = np.median(lengths[cen[:, 0] < -0.6])
    right = np.median(lengths[cen[:, 0] > 0.6])
    assert right > 1.5 * left


def test_graded_part_keeps_its_topology_and_volume():
    """The CSG part (no feature recovery here: it costs ~10 s; the optimisation test runs it on
    a graded mesh): topology, and the volume of the uniform lattice at the smallest size."""
    part, bounds = wm.example("part")
    size = ramp(0.08, 0.3, 0, bounds[0][0], bounds[1][0])
    vol = wm.mesh_domain(part, bounds=bounds, size=size, features=False)
    _check_graded(vol, -6)
    uniform = wm.mesh_domain(part, bounds=bounds, size=0.08, features=False)
    assert len(vol.cells["tetra"]) < 0.7 * len(uniform.cells["tetra"])
    assert vol.stats()["volume"] == pytest.approx(uniform.stats()["volume"], rel=0.01)
    # and a Monte Carlo estimate (1 M points, 0.1 % standard error): the unrecovered sharp
    # edges are cut off, so the mesh holds a little less (1 %) at these sizes
    assert 0.975 * _part_volume() < vol.stats()["volume"] < _part_volume()


@pytest.mark.slow
def test_graded_part_with_sharp_features_has_its_volume():
    """Feature recovery on a graded mesh (~10 CPU s): the volume within 1 % of the estimate."""
    part, bounds = wm.example("part")
    vol = wm.mesh_domain(part, bounds=bounds, size=ramp(0.08, 0.3, 0, bounds[0][0], bounds[1][0]))
    _check_graded(vol, -6)
    assert vol.info["feature_vertices"] > 0
    assert vol.stats()["volume"] == pytest.approx(_part_volume(), rel=0.01)


def _part_volume() -> float:
    part, bounds = wm.example("part")
    lo, hi = np.array(bounds[0]), np.array(bounds[1])
    p = lo + np.random.default_rng(0).random((1_000_000, 3)) * (hi - lo)
    return float((wm.evaluate(part, p) > 0).mean() * np.prod(hi - lo))


def test_curvature_size_is_small_where_the_surface_curves():
    shape = wm.ellipsoid((1.0, 0.45, 0.45))
    bounds = ((-1.2, -0.8, -0.8), (1.2, 0.8, 0.8))  # sizes in [1.6 / 40, 1.6 / 6]
    vol = wm.mesh_domain(shape, bounds=bounds, size="curvature", features=False)
    _check_graded(vol, 2)
    exact = 4.0 / 3.0 * math.pi * 1.0 * 0.45 * 0.45
    assert vol.stats()["volume"] == pytest.approx(exact, rel=0.01)
    tris, pts = vol.cells["triangle"], vol.points
    e = np.linalg.norm(pts[tris] - pts[np.roll(tris, 1, axis=1)], axis=2)
    cx = np.abs(pts[tris].mean(axis=1)[:, 0])
    tips, middle = np.median(e[cx > 0.85]), np.median(e[cx < 0.3])
    assert tips < 0.75 * middle, (tips, middle)  # curvature 1/0.2 at the tips, 1/0.45 around the middle
    # the size function itself: angle / curvature on the surface, growing with the distance
    s = curvature_size(shape, 0.01, 1.0)
    on = s(np.array([[1.0, 0.0, 0.0], [0.0, 0.45, 0.0]]))
    assert on == pytest.approx([0.2 * 0.45**2, 0.2 * 0.45], rel=0.02)
    off = s(np.array([[0.0, 0.65, 0.0]]))
    assert off[0] > on[1]


def test_optimisation_stages_work_on_graded_meshes():
    shape, bounds, exact, euler = SPHERE
    size = ramp(0.15, 0.4, 2, -1.0, 1.0)
    vol = wm.mesh_domain(shape, bounds=bounds, size=size, smooth=1, flips=True)
    s = _check_graded(vol, euler)
    stages = {q["stage"]: q for q in vol.info["quality_stages"]}
    assert list(stages) == ["stuffing", "features", "smooth", "flips"]
    assert stages["smooth"]["dihedral_min"] >= stages["features"]["dihedral_min"] - 1e-9
    assert stages["flips"]["dihedral_min"] >= stages["smooth"]["dihedral_min"] - 1e-9
    assert vol.info["smooth_moved"] > 0
    assert s["volume"] == pytest.approx(exact, rel=0.03)


@pytest.mark.parametrize("size, match", [
    (lambda p: np.full(len(p), np.nan), "size"),
    (lambda p: np.zeros(len(p)), "size"),
    (lambda p: -np.ones(len(p)), "size"),
    (lambda p: 0.2, "size"),  # one number, not one per point
    (lambda p: np.full((len(p), 1), 0.2), "size"),
    (lambda p, q: 0.2, "size"),  # takes the wrong arguments
    ("fine", "size"),
    ([0.2], "size"),
])
def test_bad_sizes_name_the_argument(size, match):
    with pytest.raises(ValueError, match=match):
        wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=size)


def test_a_size_that_fails_away_from_the_samples_is_caught_while_grading():
    def size(p):  # NaN only in a thin slab the 9³ validation grid misses
        return np.where(np.abs(p[:, 0] - 0.15) < 0.06, np.nan, 0.3)

    with pytest.raises(ValueError, match="size"):
        wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=size)


@seeded(3)
@given(seed=st.integers(0, 2**31 - 1))
def test_random_size_functions_give_valid_meshes(seed):
    rng = np.random.default_rng(seed)
    base, amp = rng.uniform(0.14, 0.2), rng.uniform(0.05, 0.25)
    k, phase = rng.normal(size=3) * 2.0, rng.uniform(0, 2 * math.pi)

    def size(p):
        return base + amp * np.abs(np.sin(p @ k + phase))

    centre = rng.uniform(-0.1, 0.1, 3)
    radius = rng.uniform(0.8, 1.0)
    shape = wm.sphere(radius, center=tuple(centre))
    vol = wm.mesh_domain(shape, bounds=((-1.2,) * 3, (1.2,) * 3), size=size, features=False)
    s = _check_graded(vol, 2)
    assert s["volume"] == pytest.approx(4.0 / 3.0 * math.pi * radius**3, rel=0.03)
    assert vol.info["graded_dihedral_min"] > 5.0 and vol.info["graded_dihedral_max"] < 175.0
