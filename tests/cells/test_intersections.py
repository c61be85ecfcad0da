"""The self-intersection check: exact cases built by hand, random triangle soups against an
exact brute-force reference written here (edge-against-triangle in Python integers, a
formulation independent of the kernel's orientation-sign one), closed spheres, two
interpenetrating spheres against pymeshlab's face selection, and flat refined faces (fans
of coplanar triangles, rounded and rotated) whose neighbours only touch through what they
share."""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
import trimesh

from warpmesh.cells import intersections as wmi
from warpmesh.cells import rays
from warpmesh.cells.predicates import power_of_two_scaled
from warpmesh.cells.intersections import (
    find_tet_overlaps,
    count_self_intersecting_faces,
    find_degenerate_faces,
    find_self_intersections,
)
from warpmesh.mesh import Mesh

# -- exact reference: Python integers, every edge of one triangle against the other --------


def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def _exact(points) -> list[tuple[int, int, int]]:
    """float64 coordinates as Python integers on one common power-of-two scale (exact)."""
    fr = [[Fraction(float(x)) for x in row] for row in np.asarray(points, dtype=float)]
    den = max((x.denominator for row in fr for x in row), default=1)
    return [tuple(int(x * den) for x in row) for row in fr]


def _in_triangle(x, a, b, c, n) -> bool:
    """x (in the plane of a, b, c) in the closed triangle."""
    return all(_dot(_cross(_sub(w, u), _sub(x, u)), n) >= 0 for u, w in ((a, b), (b, c), (c, a)))


def _on_segment(x, a, b) -> bool:  # x collinear with a, b
    return _dot(_sub(x, a), _sub(x, b)) <= 0


def _segments_meet(p1, p2, p3, p4, n) -> bool:
    """Closed coplanar segments meet (normal n of their plane)."""
    def o(a, b, c):
        v = _dot(_cross(_sub(b, a), _sub(c, a)), n)
        return (v > 0) - (v < 0)
    o1, o2, o3, o4 = o(p1, p2, p3), o(p1, p2, p4), o(p3, p4, p1), o(p3, p4, p2)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return ((o1 == 0 and _on_segment(p3, p1, p2)) or (o2 == 0 and _on_segment(p4, p1, p2))
            or (o3 == 0 and _on_segment(p1, p3, p4)) or (o4 == 0 and _on_segment(p2, p3, p4)))


def _segment_meets_triangle(x, y, a, b, c) -> bool:
    """Closed segment [x, y] and closed non-degenerate triangle (a, b, c) share a point."""
    n = _cross(_sub(b, a), _sub(c, a))
    sx, sy = _dot(n, _sub(x, a)), _dot(n, _sub(y, a))
    if sx * sy > 0:
        return False
    if sx == 0 and sy == 0:  # in the plane
        return (_in_triangle(x, a, b, c, n) or _in_triangle(y, a, b, c, n)
                or any(_segments_meet(x, y, u, w, n) for u, w in ((a, b), (b, c), (c, a))))
    den = sx - sy  # the crossing point is z = big / den
    big = _sub(_scale(y, sx), _scale(x, sy))
    sign = 1 if den > 0 else -1
    return all(_dot(_cross(_sub(w, u), _sub(big, _scale(u, den))), n) * sign >= 0
               for u, w in ((a, b), (b, c), (c, a)))


def _ray_in_wedge(v, a, b, x) -> bool:
    """x - v lies in the closed wedge at v spanned by a - v and b - v (x in their plane)."""
    n = _cross(_sub(a, v), _sub(b, v))
    return (_dot(_cross(_sub(a, v), _sub(x, v)), n) >= 0 and _dot(_cross(_sub(x, v), _sub(b, v)), n) >= 0)


def _pair_reference(P, ip, Q, iq) -> bool:
    shared = set(ip) & set(iq)
    if len(shared) == 3:
        return True
    n1 = _cross(_sub(P[1], P[0]), _sub(P[2], P[0]))
    n2 = _cross(_sub(Q[1], Q[0]), _sub(Q[2], Q[0]))
    if len(shared) == 2:
        x = P[next(k for k in range(3) if ip[k] not in shared)]
        y = Q[next(k for k in range(3) if iq[k] not in shared)]
        u, w = (P[k] for k in range(3) if ip[k] in shared)
        if _dot(n1, _sub(y, P[0])) != 0:
            return False
        return _dot(_cross(_sub(w, u), _sub(x, u)), _cross(_sub(w, u), _sub(y, u))) > 0
    p_edges = [(P[a], P[(a + 1) % 3]) for a in range(3)]
    q_edges = [(Q[a], Q[(a + 1) % 3]) for a in range(3)]
    if not shared:
        return (any(_segment_meets_triangle(x, y, *Q) for x, y in p_edges)
                or any(_segment_meets_triangle(x, y, *P) for x, y in q_edges))
    (s,) = shared  # one vertex v: the opposite edges against the other triangle, or an
    v = P[ip.index(s)]  # edge at v lying in the other's plane, inside its wedge at v
    pa, pb = (P[k] for k in range(3) if ip[k] != s)
    qa, qb = (Q[k] for k in range(3) if iq[k] != s)
    if _segment_meets_triangle(pa, pb, *Q) or _segment_meets_triangle(qa, qb, *P):
        return True
    return (any(_dot(n2, _sub(x, v)) == 0 and _ray_in_wedge(v, qa, qb, x) for x in (pa, pb))
            or any(_dot(n1, _sub(x, v)) == 0 and _ray_in_wedge(v, pa, pb, x) for x in (qa, qb)))


def _degenerate_reference(pts, tris) -> list[int]:
    return [f for f, t in enumerate(tris)
            if len(set(t)) < 3 or _cross(_sub(pts[t[1]], pts[t[0]]), _sub(pts[t[2]], pts[t[0]])) == (0, 0, 0)]


def reference_pairs(points, triangles) -> np.ndarray:
    """O(m^2) exact reference: the intersecting pairs (i < j) of non-degenerate faces."""
    pts = _exact(points)
    tris = [tuple(int(i) for i in t) for t in np.asarray(triangles)]
    bad = set(_degenerate_reference(pts, tris))
    out = []
    for i, j in itertools.combinations(range(len(tris)), 2):
        if i in bad or j in bad:
            continue
        P, Q = [pts[k] for k in tris[i]], [pts[k] for k in tris[j]]
        if _pair_reference(P, list(tris[i]), Q, list(tris[j])):
            out.append((i, j))
    return np.array(out, dtype=np.int64).reshape(-1, 2)


def pairs_of(points, triangles, **kw) -> set:
    return {tuple(p) for p in find_self_intersections(np.asarray(points, float), triangles, **kw).tolist()}


# -- exact cases -----------------------------------------------------------------------------

TRI = [[0.0, 0, 0], [4, 0, 0], [0, 4, 0]]  # in z = 0, face 0 of every case below


@pytest.mark.parametrize("name, extra, expect", [
    ("crossing (X)", [[1, 1, -1], [1, 1, 1], [6, 6, 0]], True),
    ("above, no contact", [[1, 1, 1], [2, 1, 1], [1, 2, 2]], False),
    ("vertex on the face", [[1, 1, 0], [1, 1, 2], [2, 1, 2]], True),
    ("vertex on an edge", [[2, 0, 0], [2, 1, 2], [3, 1, 2]], True),
    ("vertex on a vertex", [[4, 0, 0], [5, 1, 2], [5, 0, 2]], True),
    ("edge across an edge, in the plane", [[1, -1, 0], [1, 1, 0], [1, 0, 3]], True),
    ("edge in the plane, outside", [[3, 3, 0], [5, 3, 0], [4, 4, 3]], False),
    ("edge just past a corner", [[4.5, -1, -1], [4.5, 1, 1], [6, 0, 0]], False),
    ("coplanar overlap", [[1, 1, 0], [5, 1, 0], [1, 5, 0]], True),
    ("coplanar, inside", [[1, 1, 0], [2, 1, 0], [1, 2, 0]], True),
    ("coplanar, touching at a vertex", [[4, 0, 0], [6, 0, 0], [5, 1, 0]], True),
    ("coplanar, disjoint", [[3, 3, 0], [5, 3, 0], [3, 5, 0]], False),
    ("parallel plane", [[0, 0, 1], [4, 0, 1], [0, 4, 1]], False),
])
def test_disjoint_index_pairs(name, extra, expect, device):
    pts = np.array(TRI + extra, float)
    assert find_self_intersections(pts, [[0, 1, 2], [3, 4, 5]], device=device).tolist() == ([[0, 1]] if expect else [])
    assert bool(len(reference_pairs(pts, [[0, 1, 2], [3, 4, 5]]))) == expect  # the reference agrees


@pytest.mark.parametrize("name, extra, expect", [
    ("edge through the face", [[1, 1, -1], [1, 1, 1]], True),  # (4,0,0) shared: edge 4-5 pierces
    ("edge along the face (coplanar, inside the wedge)", [[1, 1, 0], [2, 2, 3]], True),
    ("dihedral angle, apart", [[2, 2, 2], [1, 3, 2]], False),
    ("edge touching the far edge", [[0, 2, -1], [0, 2, 1]], True),
    ("coplanar, wedges overlap", [[1, 1, 0], [1, -1, 0]], True),
    ("coplanar, wedges apart", [[5, 1, 0], [5, -1, 0]], False),
    ("coplanar, wedges share a ray", [[2, 0, 0], [3, -1, 0]], True),  # collinear edges overlap
    ("coplanar, opposite ray", [[8, 0, 0], [7, -1, 0]], False),
])
def test_one_shared_vertex(name, extra, expect, device):
    # face 1 = (vertex 1 of face 0, 3, 4)
    pts = np.array(TRI + extra, float)
    tris = [[0, 1, 2], [1, 3, 4]]
    assert pairs_of(pts, tris, device=device) == ({(0, 1)} if expect else set())
    assert bool(len(reference_pairs(pts, tris))) == expect


@pytest.mark.parametrize("name, apex, expect", [
    ("folded flat onto each other", [1, 1, 0], True),
    ("folded, apex past the other", [3, 3, 0], True),
    ("at a dihedral angle", [1, 1, 1], False),
    ("nearly folded (10 degrees)", [1, 1, 0.17], False),
    ("flat, unfolded", [3, -1, 0], False),
])
def test_shared_edge(name, apex, expect, device):
    pts = np.array(TRI + [apex], float)
    for tris in ([[0, 1, 2], [0, 1, 3]], [[0, 1, 2], [1, 0, 3]], [[2, 0, 1], [3, 1, 0]]):
        assert pairs_of(pts, tris, device=device) == ({(0, 1)} if expect else set()), tris
    assert bool(len(reference_pairs(pts, [[0, 1, 2], [0, 1, 3]]))) == expect


#: coplanar triangles q against (0, 0), (1, 0), (0, 1) in z = 0, below its lower edge by a gap g
#: (the edge-edge tests of coplanar_overlap are skipped when the gap is certified above 2^-40)
COPLANAR_GAPS = {
    "parallel edges": lambda g: [[0, -g], [1, -g], [0.5, -1]],
    "vertex under the edge": lambda g: [[0.5, -g], [1, -1], [0, -1]],
    "vertex past the corner": lambda g: [[1 + g, -g], [2, -1], [2, 0]],
    "needle under the edge": lambda g: [[0.5, -g], [0.5 + 2.0**-20, -1], [0.5 - 2.0**-20, -1]],
    "needle along the edge line": lambda g: [[1 + g, 0], [2, 2.0**-20], [2, -(2.0**-20)]],
}


@pytest.mark.parametrize("shape", list(COPLANAR_GAPS))
@pytest.mark.parametrize("k", [None, 44, 41, 40, 39, 36, 20])
def test_coplanar_gaps_around_the_separation_shortcut(shape, k, device):
    # exact dyadic coordinates: every sign is the exact one, so the answer is the exact one on
    # both sides of the shortcut's threshold (k = None: touching, reported)
    g = 0.0 if k is None else 2.0**-k
    q = np.array(COPLANAR_GAPS[shape](g), float)
    pts = np.column_stack([np.vstack([[[0, 0], [1, 0], [0, 1]], q]), np.zeros(6)])
    for tris in ([[0, 1, 2], [3, 4, 5]], [[3, 4, 5], [0, 1, 2]], [[0, 1, 2], [5, 4, 3]]):
        expect = reference_pairs(pts, tris).tolist()
        assert expect == ([[0, 1]] if k is None else [])
        assert find_self_intersections(pts, tris, device=device).tolist() == expect, (shape, k, tris)


def test_duplicate_faces_are_reported(device):
    pts = np.array(TRI + [[0, 0, 5]], float)
    tris = [[0, 1, 2], [1, 2, 0], [2, 1, 0], [0, 1, 3]]
    assert pairs_of(pts, tris, device=device) == {(0, 1), (0, 2), (1, 2)}
    assert count_self_intersecting_faces(pts, tris, device=device) == 3


def test_degenerate_faces_are_listed_and_skipped(device):
    pts = np.array(TRI + [[2, 0, 0], [1, 1, -1], [1, 1, 1]], float)
    tris = [[0, 1, 2], [0, 3, 1], [4, 4, 5], [4, 5, 5], [0, 1, 3]]  # 1 and 4: collinear; 2, 3: repeated index
    assert find_degenerate_faces(pts, tris, device=device).tolist() == [1, 2, 3, 4]
    assert find_self_intersections(pts, tris, device=device).shape == (0, 2)
    assert find_degenerate_faces(pts, np.zeros((0, 3), int)).shape == (0,)


def test_empty_and_single_inputs():
    assert find_self_intersections(np.zeros((0, 3)), np.zeros((0, 3), int)).shape == (0, 2)
    assert find_self_intersections(TRI, [[0, 1, 2]]).dtype == np.int64


# -- meshes ----------------------------------------------------------------------------------


@pytest.mark.parametrize("subdivisions", [1, 5])
def test_closed_sphere_has_none(subdivisions, device):
    s = trimesh.creation.icosphere(subdivisions=subdivisions)
    assert find_self_intersections(s.vertices, s.faces, device=device).shape == (0, 2)


def test_sharp_but_embedded_surface_has_none(device):
    # a thin cone (sharp apex, nearly folded edges) and a closed flat box of coplanar fans
    cone = trimesh.creation.cone(radius=1e-3, height=10.0, sections=64)
    box = trimesh.creation.box(extents=[1, 1, 1e-6]).subdivide().subdivide()
    for m in (cone, box):
        assert find_self_intersections(m.vertices, m.faces, device=device).shape == (0, 2)


def _two_spheres(subdivisions: int, offset) -> trimesh.Trimesh:
    a = trimesh.creation.icosphere(subdivisions=subdivisions)
    b = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.8)
    b.apply_translation(offset)
    return trimesh.Trimesh(np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + len(a.vertices)]),
                           process=False)


def test_two_interpenetrating_spheres_agree_with_pymeshlab():
    pymeshlab = pytest.importorskip("pymeshlab")
    m = _two_spheres(4, [0.9, 0.13, 0.071])
    pairs = find_self_intersections(m.vertices, m.faces)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(m.vertices, m.faces))
    ms.compute_selection_by_self_intersections_per_face()
    selected = np.flatnonzero(ms.current_mesh().face_selection_array())
    assert len(pairs) > 100
    assert np.array_equal(np.unique(pairs), selected)
    na = len(m.faces) // 2  # every pair has one face from each sphere
    assert np.all((pairs[:, 0] < na) & (pairs[:, 1] >= na))
    assert count_self_intersecting_faces(m.vertices, m.faces) == len(selected)


def test_two_spheres_against_the_reference_on_the_candidates():
    # the O(m^2) reference on the faces near the crossing curve, plus a pair of far ones
    m = _two_spheres(2, [0.9, 0.13, 0.071])
    pairs = find_self_intersections(m.vertices, m.faces)
    near = np.unique(np.concatenate([pairs.ravel(), [0, len(m.faces) - 1]]))
    sub = np.searchsorted(near, pairs)
    ref = reference_pairs(m.vertices, m.faces[near])
    assert np.array_equal(sub, ref)


def test_every_pair_crossing_gives_long_sorted_segments(device):
    # 150 triangles through one axis (each holds the origin): all 11,175 pairs meet
    rng = np.random.default_rng(3)
    theta = rng.uniform(0, np.pi, 150)
    c, s = np.cos(theta), np.sin(theta)
    pts = np.column_stack([np.stack([2 * c, 2 * s, 0 * c], 1), np.stack([-2 * c, -2 * s, 0 * c], 1),
                           np.stack([0 * c, 0 * c, 1 + rng.uniform(0, 1, 150)], 1)]).reshape(-1, 3)
    tris = rng.permutation(np.arange(450).reshape(150, 3))
    expect = np.array(list(itertools.combinations(range(150), 2)))
    assert np.array_equal(find_self_intersections(pts, tris, device=device), expect)


# -- nearly coplanar neighbours: fans of coplanar triangles ----------------------------------
# A flat face split into sub-triangles is a fan of coplanar triangles around each vertex.
# With rounded coordinates (nodes at thirds, a rotation) their plane sides are rounding
# noise, and edges collinear through a shared vertex point opposite ways: neighbours that
# touch only through what they share, which must not be reported.


def _rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def _moved(points, seed: int, shift: float = 2.0) -> np.ndarray:
    """points under a random rotation and translation (rounded: no longer coplanar)."""
    return points @ _rotation(seed).T + np.random.default_rng(seed).uniform(-shift, shift, 3)


def _fan(k: int):
    """k triangles around vertex 0, the centre of a regular k-gon in z = 0."""
    t = 2 * np.pi * np.arange(k) / k
    pts = np.vstack([[0.0, 0.0, 0.0], np.column_stack([np.cos(t), np.sin(t), np.zeros(k)])])
    return pts, np.array([[0, 1 + i, 1 + (i + 1) % k] for i in range(k)])


def _kuhn_block(nc: int):
    """[0, 1]^3 as nc^3 cubes of 6 Kuhn tetrahedra each (the paths from a cube's lowest to
    its highest corner along the axes), positively oriented."""
    g = np.arange(nc + 1)
    pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3) / nc

    def idx(c):
        return (c[..., 0] * (nc + 1) + c[..., 1]) * (nc + 1) + c[..., 2]

    low = np.stack(np.meshgrid(*[np.arange(nc)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    tets = []
    for perm in itertools.permutations(range(3)):
        path, c = [idx(low)], low.copy()
        for ax in perm:
            c = c.copy()
            c[:, ax] += 1
            path.append(idx(c))
        tets.append(np.stack(path, axis=1))
    tets = np.concatenate(tets)
    x = pts[tets]
    neg = np.linalg.det(x[:, 1:] - x[:, :1]) < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return pts, tets


def _boundary_triangles(tets: np.ndarray) -> np.ndarray:
    """The faces used by one tetrahedron only."""
    faces = tets[:, [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]].reshape(-1, 3)
    _, inv, count = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True)
    return faces[count[inv.ravel()] == 1]


def test_coplanar_neighbours_touching_at_the_shared_vertex_only():
    # faces (117, 118, 478) and (478, 479, 477) of icosphere(1).refine(4): coplanar to
    # rounding; 117 - 478 - 477 collinear, 117 and 477 on opposite sides of 478
    pts = np.array([[-0.23176274578121053, 0.7381955238109938, 0.58766270208801],
                    [-0.1545084971874737, 0.6673740532470405, 0.6753254041760199],
                    [-0.07725424859373685, 0.738195523810994, 0.58766270208801],
                    [0.0, 0.6673740532470405, 0.6753254041760199],
                    [0.07725424859373685, 0.7381955238109938, 0.58766270208801]])
    tris = [[0, 1, 2], [2, 3, 4]]
    assert find_self_intersections(pts, tris).shape == (0, 2)
    assert reference_pairs(pts, tris).shape == (0, 2)  # exactly: only the shared vertex


def test_a_steep_face_whose_vertex_is_only_collinear_with_an_edge_does_not_touch_it():
    """Found by tests/test_fuzz_ops.py (seed 585: a refined low-resolution torus): face p
    has its edge (a, c) in face q's plane, q's vertex w lies on p's plane and on the line
    of (a, c) but 0.1 beyond a, and q stands vertical above a, so in the projection along
    p's dominant axis q's top edge passes within 2e-8 of a. The planes' common line
    separates them: p covers [a, c] on it, q only w. pymeshlab agrees (no intersection).
    Moving w onto the segment (a, c) makes them touch, and that is reported."""
    p = [[-1.0510880251725514, -0.7472331126530966, -0.1666666567325592],
         [-0.9399769107500712, -0.7222222089767456, -0.22727528711160025],
         [-0.9932987093925476, -0.8333333134651184, -0.1666666567325592]]
    q = [[-1.0510880053043365, -0.7472331126530966, -0.05555554231007894],
         [-1.1088773210843403, -0.6611329118410746, -0.05555554231007894],
         [-1.1088773409525554, -0.6611329118410746, -0.1666666567325592]]
    pts = np.array(p + q)
    assert find_self_intersections(pts, [[0, 1, 2], [3, 4, 5]]).shape == (0, 2)
    touching = pts.copy()
    touching[5] = 0.5 * (pts[0] + pts[2])  # w on the middle of (a, c): q touches p there
    touching[4, :2] = touching[5, :2] + (pts[4, :2] - pts[5, :2])  # q kept vertical above w
    assert find_self_intersections(touching, [[0, 1, 2], [3, 4, 5]]).tolist() == [[0, 1]]


@pytest.mark.parametrize("n", [2, 3, 4])
def test_refined_icosphere_has_none_and_agrees_with_pymeshlab(n, device):
    # flat subdivision: the n^2 sub-triangles of each face are coplanar
    m = Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=1)).refine(n)
    pts, tris = np.asarray(m.points, float), np.asarray(m.cells["triangle"])
    assert find_self_intersections(pts, tris, device=device).shape == (0, 2)
    try:
        import pymeshlab
    except ImportError:
        return
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(pts, tris))
    ms.compute_selection_by_self_intersections_per_face()
    assert not ms.current_mesh().face_selection_array().any()


@pytest.mark.parametrize("k", [3, 5, 6, 8, 12])
def test_refined_flat_fans_have_none(k, device):
    pts, tris = _fan(k)
    m = Mesh(pts, {"triangle": tris}).refine(3)  # nodes at thirds of the edges: rounded
    p, t = np.asarray(m.points, float), np.asarray(m.cells["triangle"])
    assert find_self_intersections(p, t, device=device).shape == (0, 2)  # in z = 0
    for seed in range(6):
        assert find_self_intersections(_moved(p, seed), t, device=device).shape == (0, 2), seed


@pytest.mark.parametrize("n", [3, 4])
def test_refined_planar_mesh_rotated_has_none(n):
    g = np.linspace(0.0, 1.0, 4)
    x, y = np.meshgrid(g, g, indexing="ij")
    a = (np.arange(3)[:, None] * 4 + np.arange(3)[None, :]).ravel()
    tris = np.concatenate([np.stack([a, a + 4, a + 5], 1), np.stack([a, a + 5, a + 1], 1)])
    m = Mesh(np.column_stack([x.ravel(), y.ravel()]), {"triangle": tris}).refine(n)
    p = np.column_stack([m.points, np.zeros(m.n_points)])
    for seed in range(10):
        assert find_self_intersections(_moved(p, seed), m.cells["triangle"]).shape == (0, 2), seed


@pytest.mark.parametrize("rotate", [False, True])
def test_refined_tetra_boundary_has_none(rotate, device):
    # the boundary of a refined Kuhn block: coplanar fans on each side of the cube, and
    # sides meeting at right angles along edges that lie in both planes
    pts, tets = _kuhn_block(2)
    m = Mesh(pts, {"tetra": tets}).refine(3)
    p, faces = np.asarray(m.points, float), _boundary_triangles(np.asarray(m.cells["tetra"]))
    assert len(faces) == 6 * (2 * 3) ** 2 * 2
    for seed in range(6) if rotate else [None]:
        q = p if seed is None else _moved(p, seed, shift=0.5)
        assert find_self_intersections(q, faces, device=device).shape == (0, 2), seed


def test_genuine_overlaps_in_a_fan_are_reported(device):
    # integer points of the tilted plane x + 2y + 3z = 0 (exact): a fan of 8 around vertex
    # 0, then rim vertex 2 pulled across the ray of vertex 3: face 1 turns over and folds
    # onto faces 0 and 2 (across the shared edges 0-2, 0-3), and face 0 overlaps face 2
    # beyond their one shared vertex 0; a 9th triangle through vertex 0 whose far edge
    # pierces face 7. Exact as given, and the same under rotations (rounded: no longer
    # coplanar).
    e1, e2, normal = np.array([2, -1, 0]), np.array([3, 0, -1]), np.array([1, 2, 3])
    rim = [(3, 0), (2, 2), (0, 3), (-2, 2), (-3, 0), (-2, -2), (0, -3), (2, -2)]
    ab = np.array([(0, 0)] + rim, float)
    tris = np.array([[0, 1 + i, 1 + (i + 1) % 8] for i in range(8)] + [[0, 9, 10]])
    centre = 1.5 * e1 - 0.5 * e2  # inside face 7 = (0, 8, 1)
    for folded, expect in ((False, {(7, 8)}), (True, {(0, 1), (0, 2), (1, 2), (7, 8)})):
        if folded:
            ab[2] = (-1, 3.5)
        pts = np.vstack([ab[:, :1] * e1 + ab[:, 1:] * e2, centre + normal, centre - normal])
        assert {tuple(x) for x in reference_pairs(pts, tris).tolist()} == expect
        assert pairs_of(pts, tris, device=device) == expect
        for seed in range(20):
            assert pairs_of(pts @ _rotation(seed).T, tris, device=device) == expect, (folded, seed)


# -- random soups against the reference ------------------------------------------------------


def _soup(rng, n_points, n_tris, grid):
    pts = rng.integers(0, grid + 1, size=(n_points, 3)).astype(float)
    tris = np.array([rng.choice(n_points, 3, replace=False) for _ in range(n_tris)])
    dup = tris[rng.choice(n_tris, 3, replace=False)]
    tris = np.vstack([tris, dup, np.roll(dup[:1], 1, axis=1)])  # duplicates, in order and rotated
    return pts, tris


@pytest.mark.parametrize("seed", range(4))
def test_integer_grid_soups_match_the_reference(seed):
    # small integer coordinates: every determinant exact in float64, so exact agreement;
    # few points, so many shared vertices and edges, coplanar and touching pairs
    rng = np.random.default_rng(seed)
    pts, tris = _soup(rng, n_points=30, n_tris=70, grid=3)
    got = find_self_intersections(pts, tris)
    ref = reference_pairs(pts, tris)
    assert np.array_equal(got, ref)
    assert find_degenerate_faces(pts, tris).tolist() == _degenerate_reference(_exact(pts), tris.tolist())
    # the same answer for any vertex order of each face and any face order
    perm = rng.permutation(len(tris))
    rolled = np.array([np.roll(t, k) if k < 3 else t[::-1] for t, k in zip(tris, rng.integers(0, 4, len(tris)))])
    again = np.sort(perm[find_self_intersections(pts, rolled[perm])], axis=1)
    assert np.array_equal(again[np.lexsort(again.T[::-1])], ref)


def _touching_apart(P, Q) -> bool:
    """The check's comparison-only shortcut (kernels.intersect._apart_on_touching_boxes),
    restated: boxes apart, or touching along an axis with the parts in that plane apart."""
    P, Q = np.asarray(P), np.asarray(Q)
    for k in range(3):
        if P[:, k].max() < Q[:, k].min() or Q[:, k].max() < P[:, k].min():
            return True
        for lo, hi in ((P, Q), (Q, P)):
            c = lo[:, k].max()
            if c == hi[:, k].min():
                a, b = lo[lo[:, k] == c][:, [(k + 1) % 3, (k + 2) % 3]], hi[hi[:, k] == c][:, [(k + 1) % 3, (k + 2) % 3]]
                if np.any(a.max(axis=0) < b.min(axis=0)) or np.any(b.max(axis=0) < a.min(axis=0)):
                    return True
    return False


@pytest.mark.parametrize("seed", range(3))
def test_cell_soups_touching_on_cell_sides_match_the_reference(seed):
    # each triangle inside one closed cell of a 3 x 3 x 3 block, its corners on the cell's
    # lattice {0, 1, 2}^3: neighbouring cells' triangles touch on the cells' common sides,
    # the pairs the comparison-only shortcut decides before any predicate; the exact
    # reference says every pair the shortcut calls apart is apart, and the check agrees
    rng = np.random.default_rng(300 + seed)
    cells = rng.integers(0, 3, size=(150, 3)) * 2
    pts = (cells[:, None, :] + rng.integers(0, 3, size=(150, 3, 3))).reshape(-1, 3).astype(float)
    pts, inverse = np.unique(pts, axis=0, return_inverse=True)  # shared lattice points: shared vertices
    tris = inverse.reshape(-1, 3)
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])]
    ref = reference_pairs(pts, tris)
    hit = {tuple(p) for p in ref.tolist()}
    decided = [(i, j) for i, j in itertools.combinations(range(len(tris)), 2)
               if _touching_apart(pts[tris[i]], pts[tris[j]])]
    boxes_touch = [(i, j) for i, j in decided
                   if not any(pts[tris[i]][:, k].max() < pts[tris[j]][:, k].min()
                              or pts[tris[j]][:, k].max() < pts[tris[i]][:, k].min() for k in range(3))]
    assert len(boxes_touch) > 100 and not hit & set(decided)
    assert len(ref) > 10 and np.array_equal(find_self_intersections(pts, tris), ref)
    assert np.array_equal(wmi._all_pairs(pts, tris, certify=False), ref)


@pytest.mark.parametrize("seed, noise", [(0, 0.3), (1, 0.05), (2, 1e-7), (3, 1e-7)])
def test_perturbed_soups_match_the_reference(seed, noise):
    # grid soups moved off the grid: generic (noise 0.3) to nearly degenerate (1e-7)
    rng = np.random.default_rng(100 + seed)
    pts, tris = _soup(rng, n_points=40, n_tris=90, grid=3)
    pts = pts + rng.uniform(-noise, noise, pts.shape)
    assert np.array_equal(find_self_intersections(pts, tris), reference_pairs(pts, tris))


def test_workers_and_ranges_give_the_same_pairs(monkeypatch):
    # many small launches from several threads at once, against one serial launch
    m = _two_spheres(3, [0.9, 0.13, 0.071])
    serial = find_self_intersections(m.vertices, m.faces, workers=1)
    monkeypatch.setattr(wmi, "_MIN_FACES_PER_WORKER", 16)
    for workers in (2, 3, 64):
        for _ in range(5):
            assert np.array_equal(find_self_intersections(m.vertices, m.faces, workers=workers), serial)


def test_scale_and_translation_do_not_matter():
    rng = np.random.default_rng(7)
    pts, tris = _soup(rng, n_points=30, n_tris=60, grid=3)
    base = find_self_intersections(pts, tris)
    for scale, shift in ((2.0**-600, 0.0), (2.0**600, 0.0), (1.0, 2.0**20)):
        assert np.array_equal(find_self_intersections(pts * scale + shift, tris), base)


# -- the candidate search against every pair -------------------------------------------------
# The BVH over groups of faces, the box screens and the split into chunks only choose which
# pairs reach the predicate: wmi._all_pairs tests every pair with the same predicate, so the
# two must agree exactly, above all on tie-heavy meshes (faces whose boxes touch exactly:
# grid-aligned flat regions, coplanar fans, touching at a vertex, duplicates).


def _tie_heavy_meshes():
    import warpmesh as wm

    part, bounds = wm.example("part")
    for res in (12, 16):  # grid-aligned flat regions: the plate's faces lie on grid planes
        m = wm.mesh_surface(part, bounds=bounds, resolution=res)
        yield f"part at {res}", np.asarray(m.points, float), np.asarray(m.cells["triangle"])
    # a box whose faces fall on grid nodes: vertices at nodes, exactly touching boxes, slivers
    m = wm.mesh_surface(wm.box(size=(1.0, 0.5, 0.75)), bounds=((-1, -1, -1), (1, 1, 1)), resolution=16)
    yield "box on grid nodes", np.asarray(m.points, float), np.asarray(m.cells["triangle"])
    pts, tets = _kuhn_block(2)  # coplanar fans meeting at right angles, straight and rotated
    k = Mesh(pts, {"tetra": tets}).refine(2)
    faces = _boundary_triangles(np.asarray(k.cells["tetra"]))
    yield "Kuhn block", np.asarray(k.points, float), faces
    yield "Kuhn block rotated", _moved(np.asarray(k.points, float), 3, shift=0.5), faces
    g = np.arange(13.0)  # a flat grid and a copy moved by half a cell: coplanar overlaps
    x, y = np.meshgrid(g, g, indexing="ij")
    a = (np.arange(12)[:, None] * 13 + np.arange(12)[None, :]).ravel()
    grid = np.concatenate([np.stack([a, a + 13, a + 14], 1), np.stack([a, a + 14, a + 1], 1)])
    flat = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    yield "two flat grids", np.vstack([flat, flat + [6.5, 0.5, 0.0]]), np.vstack([grid, grid + len(flat)])
    m = _two_spheres(2, [0.9, 0.13, 0.071])
    yield "two spheres", np.asarray(m.vertices), np.asarray(m.faces)
    for seed in range(3):  # integer soups: touching at vertices and edges, coplanar, duplicates
        rng = np.random.default_rng(500 + seed)
        pts, tris = _soup(rng, n_points=60, n_tris=400, grid=4)
        yield f"integer soup {seed}", pts, tris
        yield f"perturbed soup {seed}", pts + rng.uniform(-1e-9, 1e-9, pts.shape), tris


def test_candidate_search_finds_what_every_pair_finds(monkeypatch):
    names = []
    for name, pts, tris in _tie_heavy_meshes():
        names.append(name)
        _agrees_with_every_pair(name, pts, tris, monkeypatch)
    assert len(names) == 13


def _agrees_with_every_pair(name, pts, tris, monkeypatch):
    # both candidate searches: the cell grid (forced even where face sizes vary: larger
    # cells, the same pairs), the group tree, and the grid refused for a face spanning more
    # than two cells (cells made too small: the tree takes over)
    ref = wmi._all_pairs(pts, tris)
    for spread, scale in ((np.inf, wmi._GRID_CELL_SCALE), (0.0, wmi._GRID_CELL_SCALE), (np.inf, 0.3)):
        monkeypatch.setattr(wmi, "_GRID_SPREAD", spread)
        monkeypatch.setattr(wmi, "_GRID_CELL_SCALE", scale)
        monkeypatch.setattr(wmi, "_MIN_FACES_PER_WORKER", 1 << 13)
        assert np.array_equal(find_self_intersections(pts, tris, workers=1), ref), (name, spread, scale)
        monkeypatch.setattr(wmi, "_MIN_FACES_PER_WORKER", 16)  # many chunks, several threads
        assert np.array_equal(find_self_intersections(pts, tris, workers=3), ref), (name, spread, scale)
    monkeypatch.undo()
    if name.startswith(("integer", "two")):
        assert len(ref) > 0, name  # the tie-heavy cases with genuine crossings or touchings


@pytest.mark.parametrize("seed, turn", [(55, 0), (56, 2), (57, 2), (58, 0)])
def test_rotated_soups_agree_with_every_pair(seed, turn, monkeypatch):
    # integer soups under a rotation: some faces end collinear to within rounding but not
    # flagged degenerate, and the predicate alone says they "touch" faces far away (every
    # side a tie); the float64 box confirmation drops those meets, so every pair and the
    # walk agree (before it, every pair reported 13-89 more pairs on these four)
    rng = np.random.default_rng(900 + seed)
    pts, tris = _soup(rng, n_points=60, n_tris=400, grid=4)
    _agrees_with_every_pair(f"rotated soup {seed}", _moved(pts, turn + 7 * seed), tris, monkeypatch)


def test_bvh_coordinates_kernel_matches_the_numpy_map():
    # the float32 map behind the candidate search, bit for bit: (x - centre) / half in
    # float64, then rounded to float32 (monotone, so boxes that meet in float64 meet)
    import warp as wp

    rng = np.random.default_rng(11)
    grid = np.stack(np.meshgrid(*[np.arange(5.0)] * 3, indexing="ij"), -1).reshape(-1, 3)
    for pts in (rng.normal(size=(5000, 3)) * 3.7 + 1.1, grid / 3.0 - 0.2, np.ones((4, 3))):
        scaled = power_of_two_scaled(pts)
        got = wmi._bvh_coordinates(scaled, wp.array(scaled, dtype=wp.vec3d, device="cpu"), wp.get_device("cpu"))
        lo, hi = scaled.min(axis=0), scaled.max(axis=0)
        half = float(0.5 * (hi - lo).max()) or 1.0
        assert np.array_equal(got.numpy(), ((scaled - 0.5 * (lo + hi)) / half).astype(np.float32))


def _numpy_prepare(pts, tris):
    """The inputs of the pipeline as numpy makes them: the reference of _prepare's passes."""
    scaled = power_of_two_scaled(pts)
    lo, hi = scaled.min(axis=0), scaled.max(axis=0)
    half = float(0.5 * (hi - lo).max()) or 1.0
    points32 = ((scaled - 0.5 * (lo + hi)) / half).astype(np.float32)
    return scaled, tris.astype(np.int32).ravel(), points32


@pytest.mark.parametrize("case", ["normal", "huge range", "tiny", "zeros", "few points"])
def test_prepare_on_all_cores_gives_numpys_points_bit_for_bit(case):
    # _prepare's passes (bounds by runs, then scale and float32 map in one pass) against
    # numpy's seven: the same float64 and float32 points, the same int32 indices, at
    # scales where the power of two rounds (subnormal results) or cannot be one float64
    rng = np.random.default_rng(5)
    m = 2 * wmi._MIN_FACES_PER_WORKER + 3
    n = {"few points": 3}.get(case, 5000)
    pts = rng.normal(size=(n, 3)) * 3.7 + 1.1
    if case == "huge range":
        pts[:, 0] *= 1e300
        pts[:, 1] *= 1e-300  # scaled down by 2^-997: subnormal, rounded
    elif case == "tiny":
        pts *= 1e-310  # the scale 2^1030 is no float64: numpy's path
    elif case == "zeros":
        pts[:] = 0.0
    tris = rng.integers(0, n, size=(m, 3)).astype(np.int64)
    import warp as wp

    want64, want_tris, want32 = _numpy_prepare(pts, tris)
    box = want32[tris]
    side = (box.max(axis=1) - box.min(axis=1)).max(axis=1)  # each face's largest float32 box side
    for workers in (2, 64):  # 64: 512 runs of 33 faces, the last ones past the end (found by a review)
        points64, tris32, points32, sides = wmi._prepare(pts, tris, wp.get_device("cpu"), workers)
        assert np.array_equal(points64.numpy(), want64)
        assert np.array_equal(tris32.numpy(), want_tris)
        assert np.array_equal(points32.numpy(), want32)
        assert sides[0] == side.max() and sides[1] == pytest.approx(side.mean(dtype=np.float64), rel=1e-12)


@pytest.mark.parametrize("bad, match", [("nan", "'points'.*NaN.*row 4321"), ("inf", "'points'.*row 4321"),
                                        ("high", r"indices in \[0, 5000\).*got 5000"),
                                        ("negative", "'triangles'.*got -2")])
def test_prepare_on_all_cores_refuses_bad_values_naming_them(bad, match):
    # the values unchecked by _validate(values=False) are checked by _prepare's passes
    rng = np.random.default_rng(6)
    pts = rng.normal(size=(5000, 3))
    tris = rng.integers(0, 5000, size=(2 * wmi._MIN_FACES_PER_WORKER + 1, 3))
    if bad == "nan":
        pts[4321, 2] = np.nan
    elif bad == "inf":
        pts[4321, 0] = -np.inf
    elif bad == "high":
        tris[9999, 1] = 5000
    else:
        tris[17, 0] = -2
    with pytest.raises(ValueError, match=match):
        find_self_intersections(pts, tris)
    with pytest.raises(ValueError, match=match):
        wmi.profile_self_intersections(pts, tris)


def test_profile_reports_every_stage_and_the_same_pairs(monkeypatch):
    m = _two_spheres(2, [0.9, 0.13, 0.071])
    for spread, search in ((wmi._GRID_SPREAD, ["cells"]), (0.0, ["boxes", "tree"])):  # faces of one size: the grid
        monkeypatch.setattr(wmi, "_GRID_SPREAD", spread)
        prof = wmi.profile_self_intersections(m.vertices, m.faces, workers=1)
        stages = ["prepare", "order", "faces", "umbrellas", *search, "count walk", "scan", "write walk", "sort pairs"]
        assert list(prof["cpu"]) == stages and list(prof["wall"]) == stages
        assert all(v >= 0.0 for v in [*prof["cpu"].values(), *prof["wall"].values()])
        assert prof["pairs"] == len(find_self_intersections(m.vertices, m.faces)) > 0
    monkeypatch.setattr(wmi, "_GRID_SPREAD", np.inf)
    monkeypatch.setattr(wmi, "_GRID_CELL_SCALE", 0.3)  # faces span three cells: the grid is refused
    assert "tree" in wmi.profile_self_intersections(m.vertices, m.faces, workers=1)["cpu"]
    assert wmi.profile_self_intersections(TRI, [[0, 1, 2]])["pairs"] == 0
    with pytest.raises(ValueError, match="'workers'"):
        wmi.profile_self_intersections(TRI, GOOD_T, workers=0)


@pytest.mark.parametrize("spread", [0.0, np.inf])
def test_group_tree_and_cell_grid_of_any_size_and_with_empty_groups(spread, monkeypatch):
    # the tree over groups of 16 faces is padded to a power of two leaves, and groups of
    # degenerate faces only get empty boxes: face counts around powers of two of groups,
    # and a cluster of 40 degenerate faces (whole groups of them), against every pair; the
    # same inputs through the cell grid (a few cells, the degenerate faces in one)
    monkeypatch.setattr(wmi, "_GRID_SPREAD", spread)
    m = _two_spheres(2, [0.9, 0.13, 0.071])
    pairs = find_self_intersections(m.vertices, m.faces)
    near = np.unique(pairs)  # faces along the crossing curve
    rng = np.random.default_rng(5)
    line = np.array([[0.3, 0.2, 0.1], [0.4, 0.25, 0.1], [0.5, 0.3, 0.1]])  # collinear: degenerate faces
    pts = np.vstack([m.vertices, line])
    n = len(m.vertices)
    degenerate = np.tile([n, n + 1, n + 2], (40, 1))
    for k in (2, 16, 17, 33, 48, 65, len(near)):
        faces = m.faces[rng.choice(near, size=min(k, len(near)), replace=False)]
        for tris in (faces, np.vstack([faces, degenerate])):
            ref = wmi._all_pairs(pts, tris)
            assert np.array_equal(find_self_intersections(pts, tris, workers=1), ref), (k, len(tris))
    assert len(wmi._all_pairs(pts, faces)) > 0


def test_cell_grid_at_its_finest_and_at_its_edges(monkeypatch):
    # faces far smaller than the range: the finest grid (1022 cells per axis), clusters of
    # crossing faces at the corners of the range (the last cells, coordinates clamped),
    # across block boundaries and around the centre, against every pair; the grid is the
    # search taken (its profile stage)
    rng = np.random.default_rng(23)
    centres = np.vstack([np.array(list(itertools.product([-1.0, 1.0], repeat=3))),
                         rng.uniform(-1, 1, (8, 3)), [[0.0, 0.0, 0.0], [8 / 511 - 1, 16 / 511 - 1, 0.5]]])
    tris_pts = centres[rng.integers(0, len(centres), 700)][:, None, :] + rng.normal(0, 1e-4, (700, 3, 3))
    pts = np.clip(tris_pts.reshape(-1, 3), -1.0, 1.0)
    tris = np.arange(len(pts)).reshape(-1, 3)
    monkeypatch.setattr(wmi, "_GRID_SPREAD", np.inf)
    assert "cells" in wmi.profile_self_intersections(pts, tris, workers=1)["cpu"]
    ref = wmi._all_pairs(pts, tris)
    assert len(ref) > 20
    assert np.array_equal(find_self_intersections(pts, tris, workers=1), ref)


def _lower_corner_cells(pts, tris):
    """The grid cell of each face's box's lower corner, as the check computes it (the
    float32 map of ``_bvh_coordinates``, then floor((x + 1) / cell))."""
    import warp as wp

    scaled = power_of_two_scaled(np.asarray(pts, float))
    dev = wp.get_device("cpu")
    points64, tris32 = wmi._device_arrays(scaled, np.asarray(tris), dev)
    points32 = wmi._bvh_coordinates(scaled, points64, dev)
    inv_cell = wmi._grid_cell(points32, tris32, dev)
    lower = points32.numpy()[np.asarray(tris)].min(axis=1).astype(np.float64)
    return np.clip(((lower + 1.0) * np.float32(inv_cell)).astype(np.int64), 0, 1023)


def test_cell_grid_finds_pairs_across_every_neighbour_offset(monkeypatch):
    # the walk looks at a cell's 13 upper neighbours, skipping those its faces cannot reach
    # (the reach bits: along +1 axes its own faces', along -1 axes the neighbour's); a dense
    # soup of small crossing triangles, pairs in every offset class, against every pair;
    # on the finest grid the faces allow (cells as large as the largest face), where the
    # soup's pairs reach every class
    monkeypatch.setattr(wmi, "_GRID_CELL_SCALE", 1.0 + 2.0**-10)
    rng = np.random.default_rng(41)
    centres = rng.uniform(0.0, 1.0, (6000, 3))
    pts = (centres[:, None, :] + rng.uniform(-0.05, 0.05, (6000, 3, 3))).reshape(-1, 3)
    tris = np.arange(len(pts)).reshape(-1, 3)
    assert "cells" in wmi.profile_self_intersections(pts, tris, workers=1)["cpu"]
    ref = wmi._all_pairs(pts, tris)
    got = find_self_intersections(pts, tris, workers=1)
    assert np.array_equal(got, ref)
    cells = _lower_corner_cells(pts, tris)
    d = cells[ref[:, 1]] - cells[ref[:, 0]]
    flip = (d[:, 0] < 0) | ((d[:, 0] == 0) & (d[:, 1] < 0)) | ((d[:, 0] == 0) & (d[:, 1] == 0) & (d[:, 2] < 0))
    d[flip] *= -1  # each pair as the walk meets it: from the lower cell to an upper neighbour
    offsets = {tuple(x) for x in d.tolist()}
    upper = {o for o in itertools.product((-1, 0, 1), repeat=3) if o > (0, 0, 0)}
    assert offsets == upper | {(0, 0, 0)}, sorted(offsets ^ (upper | {(0, 0, 0)}))


@pytest.mark.parametrize("m", [2, 3, 17, 1000, 4097])
def test_grid_order_sorted_in_two_halves_is_the_one_sort(m, monkeypatch):
    # on two CPU threads the faces' keys are sorted by halves and the runs merged; the
    # result must be the one stable sort's, item for item: many faces share a cell (equal
    # keys, lower ids first), odd counts, halves of one face
    import warp as wp

    rng = np.random.default_rng(m)
    pts = rng.integers(0, 4, (3 * m, 3)).astype(float) + rng.uniform(0, 0.2, (3 * m, 3))
    tris = np.arange(3 * m).reshape(-1, 3)
    scaled = power_of_two_scaled(pts)
    dev = wp.get_device("cpu")
    points64, tris32 = wmi._device_arrays(scaled, tris, dev)
    points32 = wmi._bvh_coordinates(scaled, points64, dev)
    inv_cell = wmi._grid_cell(points32, tris32, dev)
    monkeypatch.setattr(wmi, "_MIN_FACES_PER_WORKER", 1)
    one = [a.numpy() for a in wmi._grid_order(points32, tris32, inv_cell, dev, 1)]
    two = [a.numpy() for a in wmi._grid_order(points32, tris32, inv_cell, dev, 2)]
    assert all(np.array_equal(a, b) for a, b in zip(one, two))
    order, _, keys = two
    assert np.array_equal(order, np.argsort(keys[np.argsort(order)], kind="stable"))
    assert len(np.unique(keys)) < m or m < 20  # equal keys: the merge's ties


def test_vertex_corner_table_on_two_threads_certifies_as_on_one(monkeypatch):
    # the umbrella certificate's vertex -> corners table, made by halves on two CPU threads
    # (each half counted and placed with arrays of its own), gives every corner the flag of
    # the one-launch table: a closed sphere (all certified), a crossing pair of spheres, a
    # soup with open fans, duplicate faces and unused vertices
    import warp as wp

    rng = np.random.default_rng(9)
    sphere = _two_spheres(2, [0.9, 0.13, 0.071])
    soup_pts, soup_tris = _soup(rng, n_points=60, n_tris=400, grid=4)
    ico = trimesh.creation.icosphere(subdivisions=3)
    cases = [(np.asarray(ico.vertices), np.asarray(ico.faces)), (np.asarray(sphere.vertices), np.asarray(sphere.faces)),
             (np.vstack([soup_pts, [[9.0, 9.0, 9.0]]]), np.vstack([soup_tris, soup_tris[:5]]))]
    dev = wp.get_device("cpu")
    monkeypatch.setattr(wmi, "_MIN_FACES_PER_WORKER", 1)
    flags = []
    for pts, tris in cases:
        points64, tris32 = wmi._device_arrays(power_of_two_scaled(pts), tris, dev)
        _, codes = wmi._classify_faces(points64, tris32, dev)
        one = wmi._umbrella_flags(codes, tris32, len(pts), dev, True, 1).numpy()
        two = wmi._umbrella_flags(codes, tris32, len(pts), dev, True, 2).numpy()
        assert np.array_equal(one, two)
        flags.append(two)
    assert flags[0].all() and flags[1].mean() > 0.9 and not flags[2].all()


def test_all_pairs_reference_refuses_large_meshes():
    with pytest.raises(ValueError, match="'triangles'"):
        wmi._all_pairs(np.zeros((3, 3)), np.zeros((10_001, 3), int))


# -- the umbrella certificate: pairs around a vertex that skip the exact test ---------------
# A vertex whose faces form one closed fan, every wedge strictly of one orientation in a
# coordinate projection and winding once about it, has faces that meet only where they
# share (kernels.intersect.umbrella_certified): pairs sharing it are not tested. What it
# skips must never be an intersection, and what it cannot prove must be left to the test.


def _ico_integer(scale: int = 16):
    """icosphere(1) scaled and rounded to integers: closed, embedded, exact predicates."""
    s = trimesh.creation.icosphere(subdivisions=1)
    return np.round(np.asarray(s.vertices) * scale), np.asarray(s.faces)


def _star_of(tris, v) -> np.ndarray:
    """The faces with vertex index v."""
    return np.flatnonzero((np.asarray(tris) == v).any(axis=1))


def test_closed_meshes_are_certified_almost_everywhere():
    import warpmesh as wm

    # measured: every vertex of the icospheres (1-3 subdivisions) and of the part meshed at
    # 16-128 and 512 (the crease vertices too: some coordinate projection of each fan is
    # one-to-one); any uncertified vertex here would be a fold, a pinch or valence > 16
    for sub in (1, 3):
        s = trimesh.creation.icosphere(subdivisions=sub)
        assert wmi._certified_vertices(s.vertices, s.faces).all()
    part, bounds = wm.example("part")
    m = wm.mesh_surface(part, bounds=bounds, resolution=32)
    cert = wmi._certified_vertices(m.points, m.triangles)
    assert len(cert) > 2500 and cert.mean() >= 0.999
    # flags are per vertex: every corner of a vertex agrees (face order and rotation free)
    rng = np.random.default_rng(4)
    faces = np.asarray(m.triangles)[rng.permutation(len(m.triangles))]
    faces = np.array([np.roll(f, k) for f, k in zip(faces, rng.integers(0, 3, len(faces)))])
    assert np.array_equal(wmi._certified_vertices(m.points, faces), cert)


def test_a_vertex_pushed_through_its_umbrella_is_not_certified_and_is_reported():
    pts, tris = _ico_integer()
    v = int(np.argmax(pts[:, 2]))  # (0, 0, 16): its fan projects along z around (0, 0)
    star = _star_of(tris, v)
    link = np.unique(tris[star])
    link = link[link != v]
    # pushed along its normal through the far side: its fan still projects one to one along
    # z, so it stays certified, and its faces' crossings with the far faces are reported
    # (they do not share v)
    deep = pts.copy()
    deep[v] = -1.5 * pts[v]
    assert wmi._certified_vertices(deep, tris)[v]
    got = find_self_intersections(deep, tris)
    assert len(got) > 0 and np.array_equal(got, reference_pairs(deep, tris))
    # a flat fan of 8 in the tilted plane x + 2y + 3z = 0 (integer points): its centre pushed
    # in the plane past a rim vertex folds the fan over itself: not certified, and pairs of
    # its own faces overlap (what the certificate would have skipped)
    e1, e2 = np.array([2, -1, 0]), np.array([3, 0, -1])
    rim = [(3, 0), (2, 2), (0, 3), (-2, 2), (-3, 0), (-2, -2), (0, -3), (2, -2)]
    fan = np.array([[0, 1 + i, 1 + (i + 1) % 8] for i in range(8)])
    # (on rim vertex 1: its two faces are degenerate, so not certified, and nothing crosses)
    for centre, certified, crossing in (((0, 0), True, False), ((1, 1), True, False), ((4, 1), False, True),
                                        ((3, 0), False, False)):
        ab = np.array([centre] + rim, float)
        flat = ab[:, :1] * e1 + ab[:, 1:] * e2
        assert wmi._certified_vertices(flat, fan)[0] == certified, centre
        got = find_self_intersections(flat, fan)
        assert np.array_equal(got, reference_pairs(flat, fan)), centre
        assert (len(got) > 0) == crossing, centre


def test_pinched_duplicate_folded_and_open_fans_are_not_certified():
    # two cones with one apex index (a pinched vertex: two cycles of wedges); touching only
    # at the apex: nothing to report
    apex = [[0, 0, 0]]
    up = [[3, 0, 2], [-2, 2, 2], [-2, -2, 2]]
    down = [[3, 0, -2], [-2, -2, -2], [-2, 2, -2]]
    pts = np.array(apex + up + down, float)
    tris = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2], [0, 4, 5], [0, 5, 6], [0, 6, 4], [4, 6, 5]])
    assert not wmi._certified_vertices(pts, tris)[0]
    assert find_self_intersections(pts, tris).shape == (0, 2) == reference_pairs(pts, tris).shape
    # a duplicate face (either orientation) on a closed sphere: its vertices are not certified
    # and the pair is reported
    p, t = _ico_integer()
    for dup in (t[5], t[5][::-1]):
        faces = np.vstack([t, dup])
        cert = wmi._certified_vertices(p, faces)
        assert np.flatnonzero(~cert).tolist() == sorted(t[5].tolist())
        assert [5, len(t)] in find_self_intersections(p, faces).tolist()
    # a flat fan whose link goes round twice (a pentagram, every wedge turning 144 degrees,
    # all counter-clockwise): the winding is 2, and its wedges overlap
    star = np.array([[0, 0, 0], [10, 0, 0], [-8, 6, 0], [3, -10, 0], [3, 10, 0], [-8, -6, 0]], float)
    fan = np.array([[0, 1 + i, 1 + (i + 1) % 5] for i in range(5)])
    assert not wmi._certified_vertices(star, fan).any()
    got = find_self_intersections(star, fan)
    assert len(got) > 0 and np.array_equal(got, reference_pairs(star, fan))
    # an open fan: the centre is certified, the rim (boundary vertices) is not; 12 faces take
    # the general loop (more than 8), 17 are past the cap
    for k, centre in ((6, True), (12, True), (16, True), (17, False)):
        p, t = _fan(k)
        cert = wmi._certified_vertices(p, t)
        assert cert[0] == centre and not cert[1:].any(), k
        assert find_self_intersections(p, t).shape == (0, 2)


# -- the block certificate: blocks of grid cells whose pairs the walk skips ----------------


def _block_levels(monkeypatch, pts, tris, blocks=True, spread=None):
    """The pairs found, and each occupied grid cell's certified block shift (0: none) as the
    walk sees them (``cell_reach`` >> ``LEVEL_BIT``), or None when the grid was not used
    (``spread``: the grid's ``_GRID_SPREAD``, np.inf to use it whatever the faces' sizes)."""
    seen = {}
    certify = wmi._certify_blocks

    def spy(*args, **kwargs):
        certify(*args, **kwargs)
        seen["levels"] = (args[7].numpy() >> wmi.K.LEVEL_BIT) & 7

    monkeypatch.setattr(wmi, "_certify_blocks", spy)
    monkeypatch.setattr(wmi, "_CERTIFY_BLOCKS", blocks)
    if spread is not None:
        monkeypatch.setattr(wmi, "_GRID_SPREAD", spread)
    pairs = find_self_intersections(pts, tris)
    monkeypatch.undo()
    return pairs, seen.get("levels")


def _ramp(lift: float, turns: float = 1.0 + 1.0 / 6.0, nr: int = 4, nt: int = 60):
    """An annulus r in [1, 2] wound ``turns`` times about the z axis as a ramp z = lift t (T -
    t) (t the angle, T = 2 pi turns): every face counter-clockwise seen from +z (the grid's
    quads split along (r_i, t_j) - (r_i+1, t_j+1)), the projection covering the first
    sixth twice; the end comes down through the start when lift > 0."""
    big_t = 2 * np.pi * turns
    r, t = np.meshgrid(np.linspace(1.0, 2.0, nr + 1), np.linspace(0.0, big_t, nt + 1), indexing="ij")
    pts = np.column_stack([(r * np.cos(t)).ravel(), (r * np.sin(t)).ravel(), (lift * t * (big_t - t)).ravel()])
    idx = np.arange((nr + 1) * (nt + 1)).reshape(nr + 1, nt + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    tris = np.vstack([np.column_stack([a.ravel(), b.ravel(), c.ravel()]),
                      np.column_stack([a.ravel(), c.ravel(), d.ravel()])])
    return pts, tris


def test_umbrella_partners_name_the_face_across_each_edge():
    import warp as wp

    s = trimesh.creation.icosphere(subdivisions=2)
    pts, tris = wmi._validate(s.vertices, s.faces)
    dev = wp.get_device("cpu")
    points64, tris32 = wmi._device_arrays(power_of_two_scaled(pts), tris, dev)
    _, codes = wmi._classify_faces(points64, tris32, dev)
    for workers in (1, 2):
        partners = wp.empty(tris32.shape[0], dtype=wp.int32, device=dev)
        wmi._umbrella_flags(codes, tris32, len(pts), dev, True, workers, partners)
        got = partners.numpy().reshape(-1, 3)
        for f, face in enumerate(tris):
            for r in range(3):
                u, v = face[r], face[(r + 1) % 3]
                g = tris[got[f, r]]
                assert any(g[q] == v and g[(q + 1) % 3] == u for q in range(3)), (f, r)
    # an open fan: the rim edges have no face across; a spoke held by three faces, or an
    # edge held twice the same way (a duplicate face), names none
    # and a closed fan of 18 (past the umbrella's cap): its spokes are still paired both ways
    for faces, expect, k in ((_fan(6)[1], None, 6), (np.vstack([_fan(6)[1], [[0, 2, 7]]]), "spoke", 6),
                             (np.vstack([_fan(6)[1], _fan(6)[1][:1]]), "duplicate", 6), (_fan(18)[1], "wide", 18)):
        p = np.vstack([_fan(k)[0], [[0.5, 0.5, 3.0]]])
        pts, tris = wmi._validate(p, faces)
        points64, tris32 = wmi._device_arrays(power_of_two_scaled(pts), tris, dev)
        _, codes = wmi._classify_faces(points64, tris32, dev)
        partners = wp.empty(tris32.shape[0], dtype=wp.int32, device=dev)
        wmi._umbrella_flags(codes, tris32, len(pts), dev, True, 1, partners)
        got = partners.numpy().reshape(-1, 3)
        for f, face in enumerate(tris):
            for r in range(3):
                u, v = face[r], face[(r + 1) % 3]
                forward = sum(any(h[q] == u and h[(q + 1) % 3] == v for q in range(3)) for h in tris)
                backward = [g for g, h in enumerate(tris) if any(h[q] == v and h[(q + 1) % 3] == u for q in range(3))]
                want = backward[0] if forward == 1 and len(backward) == 1 else -1
                assert got[f, r] == want, (expect, f, r)


def test_blocks_of_a_smooth_surface_are_certified_and_skip_only_pairs_that_do_not_meet(monkeypatch):
    import warpmesh as wm

    # a meshed sphere: nearly every cell lies in a certified block (measured: 0.99 of the
    # faces at 512, where a sixth of the blocks need the simple-polygon test, the star test
    # failing on their boundary's zigzags); the walk then finds what it finds without blocks
    m = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=64)
    pts, tris = np.asarray(m.points), np.asarray(m.triangles)
    got, levels = _block_levels(monkeypatch, pts, tris)
    assert got.shape == (0, 2) and levels is not None and (levels > 0).mean() >= 0.9
    assert set(np.unique(levels)) <= {0, *wmi.K.BLOCK_SHIFTS}
    # a second, smaller sphere through the first: the blocks where they cross are not
    # certified, the rest are, and the pairs are those of the walk without blocks
    m2 = wm.mesh_surface(wm.sphere(0.5), bounds=((-0.6,) * 3, (0.6,) * 3), resolution=40)
    both_pts = np.vstack([pts, np.asarray(m2.points) + [0.8, 0.1, 0.05]])
    both = np.vstack([tris, np.asarray(m2.triangles) + len(pts)])
    got, levels = _block_levels(monkeypatch, both_pts, both)
    without, _ = _block_levels(monkeypatch, both_pts, both, blocks=False)
    assert len(got) > 100 and np.array_equal(got, without)
    assert 0.3 < (levels > 0).mean() < 1.0


def _one_block_level(pts, tris, shift: int = 5) -> int:
    """The certified shift (0: none) of all the faces taken as one block of 2^shift cells per
    axis, in their own order (``certify_blocks_kernel`` on one block, one cell)."""
    import warp as wp

    pts, tris = wmi._validate(pts, tris)
    dev = wp.get_device("cpu")
    points64, tris32 = wmi._device_arrays(power_of_two_scaled(pts), tris, dev)
    degenerate, codes = wmi._classify_faces(points64, tris32, dev)
    partners = wp.empty(tris32.shape[0], dtype=wp.int32, device=dev)
    wmi._umbrella_flags(codes, tris32, len(pts), dev, True, 1, partners)
    cap = min(wmi.K.LOOP_CAP_PER_CELL << shift, 3 * len(tris))
    scratch = [wp.empty(len(tris), dtype=wp.int8, device=dev)]
    scratch += [wp.empty(cap, dtype=dtype, device=dev) for dtype in (wp.vec2i, wp.int32)]
    scratch.append(wp.empty(-(-cap // wmi.K.LOOP_RUN), dtype=wp.vec4d, device=dev))
    reach = wp.zeros(1, dtype=wp.int32, device=dev)
    one = wp.zeros(1, dtype=wp.int32, device=dev)
    bases = wp.zeros(1, dtype=wp.vec2i, device=dev)
    wp.launch(wmi.K.certify_blocks_kernel, dim=1,
              inputs=[0, one, one, shift, bases, points64, tris32, degenerate, codes, partners],
              outputs=[*scratch, reach], device=dev)
    return int(reach.numpy()[0]) >> wmi.K.LEVEL_BIT


def _sheet(n: int = 6):
    """An n x n grid of unit squares in z = 0, two faces each, counter-clockwise from +z."""
    g = np.arange(n + 1, dtype=float)
    x, y = np.meshgrid(g, g, indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    tris = np.vstack([np.column_stack([a.ravel(), b.ravel(), c.ravel()]),
                      np.column_stack([a.ravel(), c.ravel(), d.ravel()])])
    return pts, tris


def test_block_certificate_on_hand_made_blocks():
    # certified: one face; a sheet, tilted anyhow (its faces keep one orientation in some
    # coordinate projection); the sheet with a comb cut into a side (a boundary not star
    # shaped about its mean: the simple-polygon test); a ramp wound 5/6 of a turn
    pts, tris = _sheet()
    assert _one_block_level(pts, [[0, 7, 8]]) == 5
    tilt = pts @ np.array([[0.8, 0.1, 0.5], [-0.3, 0.9, 0.2], [0.1, -0.2, 0.7]])
    assert _one_block_level(pts, tris) == 5 and _one_block_level(tilt, tris) == 5
    teeth = [k + half for k in (5, 17, 29) for half in (0, 36)]  # squares (0, 5), (2, 5), (4, 5), both faces
    comb = np.delete(tris, teeth, axis=0)
    assert 0 < len(tris) - len(comb) and _one_block_level(pts, comb) == 5
    assert _one_block_level(*_ramp(0.05, turns=5.0 / 6.0)) == 5
    # not certified: the faces meet, or the test cannot tell: the ramp past one turn (two
    # layers over a sixth: crossing, flat, or apart as a helix), two sheets in one block,
    # crossing or apart, a sheet with a hole (two loops), a fold, a duplicate face
    for lift in (0.05, 0.0):
        assert _one_block_level(*_ramp(lift)) == 0, lift
    helix, htris = _ramp(0.0)
    helix[:, 2] = 0.3 * (np.arange(len(helix)) % 61) / 60  # z rising with the angle: the layers apart
    assert _one_block_level(helix, htris) == 0
    two = np.vstack([pts, pts + [0.5, 0.25, 0.0]])
    two[len(pts):, 2] = 0.4 * (two[len(pts):, 0] - 3.2)
    assert _one_block_level(two, np.vstack([tris, tris + len(pts)])) == 0
    assert _one_block_level(np.vstack([pts, pts + [0, 0, 3.0]]), np.vstack([tris, tris + len(pts)])) == 0
    holed = np.array([f for f in tris if not np.isin(f, [16, 17, 23, 24]).all()])  # the square at (2, 2)
    assert _one_block_level(pts, holed) == 0
    folded = pts.copy()
    folded[24] = [4.6, 3.4, 0.0]  # an inner vertex pushed past its neighbour: wedges turn back
    assert _one_block_level(folded, tris) == 0
    assert _one_block_level(pts, np.vstack([tris, tris[:1]])) == 0


def test_blocks_keep_pairs_that_touch_within_rounding(monkeypatch):
    # found by a review: a slit (a fan whose last spoke ends 2^-50 from its first rim vertex)
    # and a sliver between two faces: exactly, the faces meet only at the centre, but the
    # predicate reports them as touching within rounding (INPUT_TOL); blocks decide by a
    # margin too, so they are walked and reported as without blocks and by every pair
    slit = ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, -2.0**-50, 0]],
            [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]])
    sliver = ([[0, 0, 0], [1, -1, 0], [1, 0, 0], [1, 2.0**-49, 0], [1, 1, 0]], [[0, 1, 2], [0, 2, 3], [0, 3, 4]])
    for pts, tris in (slit, sliver):
        pts, tris = np.array(pts, float), np.array(tris)
        assert _one_block_level(pts, tris) == 0
        got, _ = _block_levels(monkeypatch, pts, tris)
        assert len(got) == 1 and np.array_equal(got, wmi._all_pairs(pts, tris))
        assert np.array_equal(got, _block_levels(monkeypatch, pts, tris, blocks=False)[0])
    # the same fan opened wide: certified
    wide = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, -0.25, 0]], float)
    assert _one_block_level(wide, slit[1]) == 5


def test_the_first_cell_block_is_tried_at_every_size(monkeypatch):
    # found by a review: the first occupied cell was marked as a block's first for three
    # sizes only, so its smallest block was never tried; a sheet there, a crossing pair in
    # the next larger block (so that block fails): the sheet's cells are certified in the
    # smallest
    pts, tris = _sheet(3)
    cross = np.array([[9, 0, -0.5], [10, 0, 0.5], [9, 1, 0], [9, 0.5, 0.5], [10, 0.5, -0.5], [10, 0.2, 0.3]])
    both = np.vstack([pts, cross])
    faces = np.vstack([tris, len(pts) + np.arange(6).reshape(2, 3)])
    got, levels = _block_levels(monkeypatch, both, faces)
    assert got.tolist() == [[len(tris), len(tris) + 1]]
    assert (levels == min(wmi.K.BLOCK_SHIFTS)).any() and (levels == 0).any()


def test_a_ramp_covering_its_projection_twice_is_walked_where_it_does(monkeypatch):
    # every face positive in the projection along z, yet two layers over the first sixth of
    # the annulus: the blocks holding both are walked, the crossings of the end through the
    # start (lift +-0.05), or of the coinciding layers (flat), reported as by every pair;
    # about half of the cells lie in certified blocks
    for lift in (0.05, 0.0, -0.05):
        pts, tris = _ramp(lift, nr=8, nt=120)
        got, levels = _block_levels(monkeypatch, pts, tris)
        assert levels is not None and 0.3 < (levels > 0).mean() < 1.0, lift
        assert len(got) > 0 and np.array_equal(got, wmi._all_pairs(pts, tris)), lift
        assert np.array_equal(got, _block_levels(monkeypatch, pts, tris, blocks=False)[0]), lift


def _swirled(name: str, resolution: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """A meshed sphere or torus with one to three patches twisted about their normal by up to
    4 radians at their centre, less towards their rim: the faces there fold over each
    other, keeping their size (so the grid is used)."""
    import warpmesh as wm

    shape, bounds = wm.example(name)
    m = wm.mesh_surface(shape, bounds=bounds, resolution=resolution)
    pts, tris = np.array(m.points), np.asarray(m.triangles)
    h = np.ptp(pts, axis=0).max() / resolution
    for _ in range(int(rng.integers(1, 4))):
        c = pts[rng.integers(len(pts))]
        if name == "sphere":
            n = c / np.linalg.norm(c)
        else:
            q = np.array([c[0], c[1], 0.0]) / np.hypot(c[0], c[1])
            n = (c - q) / np.linalg.norm(c - q)
        d = np.linalg.norm(pts - c, axis=1)
        rho = h * rng.uniform(2.0, 6.0)
        near = d < rho
        turn = rng.uniform(0.3, 4.0) * (1.0 - d[near] / rho)
        x = pts[near] - c
        along = (x @ n)[:, None] * n
        across = x - along
        pts[near] = c + along + across * np.cos(turn)[:, None] + np.cross(n, across) * np.sin(turn)[:, None]
    return pts, tris


def test_swirled_surfaces_give_the_same_pairs_with_and_without_blocks(monkeypatch):
    # twisted patches on meshed spheres and tori: crossings next to certified blocks; the
    # blocks change nothing (measured over 100 such surfaces, the grid forced: none
    # differing). The grid is forced (a twist stretches faces, which would send most of
    # them to the tree)
    rng = np.random.default_rng(5)
    crossing = mostly_certified = 0
    for k in range(24):
        pts, tris = _swirled(("sphere", "torus")[k % 2], int(rng.integers(40, 72)), rng)
        got, levels = _block_levels(monkeypatch, pts, tris, spread=np.inf)
        assert levels is not None
        crossing += int(len(got) > 0)
        mostly_certified += int((levels > 0).mean() > 0.5)
        assert np.array_equal(got, _block_levels(monkeypatch, pts, tris, blocks=False, spread=np.inf)[0]), k
        if k < 2:
            assert np.array_equal(got, find_self_intersections(pts, tris)), k  # the search chosen
    assert crossing >= 5 and mostly_certified >= 6, (crossing, mostly_certified)  # both paths exercised


def test_two_crossing_sheets_are_reported_as_by_every_pair(monkeypatch):
    pts, tris = _sheet()
    tilted = pts + [0.5, 0.25, 0.0]
    tilted[:, 2] = 0.4 * (tilted[:, 0] - 3.2)
    both, faces = np.vstack([pts, tilted]), np.vstack([tris, tris + len(pts)])
    got, levels = _block_levels(monkeypatch, both, faces)
    assert levels is not None and len(got) > 0
    assert np.array_equal(got, wmi._all_pairs(both, faces))
    assert np.array_equal(got, reference_pairs(both, faces))


@pytest.mark.parametrize("scale, noise", [(16, 0), (16, 2), (16, 4), (8, 3), (64, 16)])
def test_jittered_closed_meshes_walk_equals_every_pair_with_and_without_certificate(scale, noise):
    # closed spheres on an integer grid, vertices moved by integers up to `noise` (some fold):
    # every determinant is exact, so the answer is the exact one with the certificate, with
    # none (every pair tested) and by the Python reference
    rng = np.random.default_rng(scale + 7 * noise)
    base, tris = _ico_integer(scale)
    folded = 0
    for trial in range(8):
        pts = base + rng.integers(-noise, noise + 1, base.shape)
        got = find_self_intersections(pts, tris)
        assert np.array_equal(got, wmi._all_pairs(pts, tris)), trial
        assert np.array_equal(got, wmi._all_pairs(pts, tris, certify=False)), trial
        if trial < 2:
            assert np.array_equal(got, reference_pairs(pts, tris)), trial
        folded += int(not wmi._certified_vertices(pts, tris).all())
    assert (folded > 0) == (noise >= 3)  # the larger moves fold some umbrellas


@pytest.mark.parametrize("seed", range(3))
def test_jittered_float_meshes_lose_only_pairs_of_certified_umbrellas(seed):
    # rounded coordinates: the certificate may drop a pair the conservative predicate reports
    # within rounding, but only one that shares a certified vertex; the walk and every pair
    # (with the same certificate) agree exactly
    rng = np.random.default_rng(40 + seed)
    s = trimesh.creation.icosphere(subdivisions=2)
    tris = np.asarray(s.faces)
    for noise in (0.0, 0.02, 0.08):
        pts = _moved(np.asarray(s.vertices) + rng.normal(0.0, noise, s.vertices.shape), seed)
        got = find_self_intersections(pts, tris)
        assert np.array_equal(got, wmi._all_pairs(pts, tris)), noise
        every = wmi._all_pairs(pts, tris, certify=False)
        kept = {tuple(p) for p in got.tolist()}
        assert kept <= {tuple(p) for p in every.tolist()}
        cert = wmi._certified_vertices(pts, tris)
        for i, j in every.tolist():
            if (i, j) not in kept:
                assert cert[np.intersect1d(tris[i], tris[j])].any(), (noise, i, j)
        for scale in (2.0**-600, 2.0**600):  # tiny and huge coordinates: the same flags and pairs
            assert np.array_equal(wmi._certified_vertices(pts * scale, tris), cert)
            assert np.array_equal(find_self_intersections(pts * scale, tris), got)


def _random_fan(rng, mode):
    """A fan of 3-11 faces around vertex 0 (integer points, exact predicates): its link
    sorted by angle in the xy-plane with heights of either sign (one-to-one along z, folded
    in 3D; mode 3: going round twice), random points, or points near a line through 0
    (nearly collinear wedges); closed
    (one cycle) or any permutation (pinches, open fans), either orientation, faces rotated
    and shuffled; sometimes a face sharing only vertex 0, or a link vertex doubled (equal
    coordinates, another index) in one face."""
    d = int(rng.integers(3, 12))
    size = int(rng.choice([2, 3, 5, 20, 1000]))
    if mode in (0, 3):
        angle = np.sort(rng.uniform(0, (2 if mode == 0 else 4) * np.pi, d))
        r = rng.uniform(0.3, 1, d) * size
        link = np.column_stack([np.round(r * np.cos(angle)), np.round(r * np.sin(angle)),
                                rng.integers(-3 * size, 3 * size + 1, d)])
    elif mode == 1:
        link = rng.integers(-size, size + 1, (d, 3))
    else:
        t = rng.integers(-20, 21, d)
        link = np.column_stack([1000 * t + rng.integers(-2, 3, d), 999 * t + rng.integers(-2, 3, d),
                                rng.integers(-20, 21, d)])
    pts = np.vstack([np.zeros(3), link]).astype(float)
    perm = rng.permutation(d) if rng.random() < 0.2 else np.arange(d)
    nxt = rng.permutation(d) if rng.random() < 0.5 and perm[0] != 0 else np.roll(perm, -1)
    faces = np.array([[0, 1 + perm[i], 1 + nxt[i]] for i in range(d)])
    faces = faces[:, [0, 2, 1]] if rng.random() < 0.5 else faces
    faces = np.array([np.roll(f, k) for f, k in zip(faces, rng.integers(0, 3, d))])[rng.permutation(d)]
    if rng.random() < 0.1:
        pts = np.vstack([pts, rng.integers(-size, size + 1, (2, 3))])
        faces = np.vstack([faces, [0, len(pts) - 2, len(pts) - 1]])
    if rng.random() < 0.05:
        k = int(rng.integers(1, d + 1))
        pts = np.vstack([pts, pts[k]])
        f = faces[int(rng.integers(0, len(faces)))]
        f[f == k] = len(pts) - 1
    return pts, faces


def test_random_fans_certified_only_when_no_two_faces_meet(monkeypatch):
    # an adversarial search (48,000 such fans, 7,200 certified; 20,000 float fans with wedges
    # within 1e-12..1e-17 of straight) found nothing; kept small: 240 fans apart from each
    # other in one mesh, the certified walk = every pair without the certificate, and each
    # certified centre's faces meet only where they share by the exact Python reference
    rng = np.random.default_rng(11)
    fans = [_random_fan(rng, k % 4) for k in range(240)]
    pts = np.vstack([p + [1e7 * k, 0, 0] for k, (p, _) in enumerate(fans)])
    base = np.cumsum([0] + [len(p) for p, _ in fans])
    tris = np.vstack([f + b for (_, f), b in zip(fans, base)])
    got = find_self_intersections(pts, tris, workers=1)
    assert np.array_equal(got, wmi._all_pairs(pts, tris, certify=False))
    cert = wmi._certified_vertices(pts, tris)
    assert 30 < cert[base[:-1]].sum() < 200 and len(got) > 100
    for (p, f), b in zip(fans, base):
        if cert[b]:
            assert reference_pairs(p, f).shape == (0, 2), (p.tolist(), f.tolist())
    monkeypatch.setattr(wmi, "_MIN_FACES_PER_WORKER", 16)  # flags from several threads: the same
    assert np.array_equal(find_self_intersections(pts, tris, workers=3), got)
    # an octahedron with one face at a copy of its top vertex (touching there: reported), a
    # face using the top index twice, a face collinear with an edge: each top uncertified
    octa = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, 0, 1], [0.5, 0, 0.5]])
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])
    for extra, copy, want in (([], True, [[0, 1], [1, 2], [1, 3]]), ([[4, 4, 0]], False, []), ([[4, 7, 0]], False, [])):
        f = np.vstack([faces, np.reshape(extra, (-1, 3))]).astype(int)
        if copy:
            f[1, 2] = 6
        assert not wmi._certified_vertices(octa, f)[4]
        assert find_self_intersections(octa, f).tolist() == want == reference_pairs(octa, f).tolist()


# -- bad input: one pytest.raises each -------------------------------------------------------

GOOD_T = [[0, 1, 2]]


def test_nan_points():
    with pytest.raises(ValueError, match="'points'.*NaN"):
        find_self_intersections([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]], GOOD_T)


def test_infinite_points():
    with pytest.raises(ValueError, match="'points'"):
        find_self_intersections([[0, 0, 0], [1, 0, np.inf], [0, 1, 0]], GOOD_T)


def test_points_of_wrong_shape():
    with pytest.raises(ValueError, match=r"expected an \(n, 3\) array for 'points', got shape \(3, 2\)"):
        find_self_intersections([[0, 0], [1, 0], [0, 1]], GOOD_T)


def test_points_not_numbers():
    with pytest.raises(TypeError, match="'points'.*dtype"):
        find_self_intersections([["a", "b", "c"]] * 3, GOOD_T)


def test_triangles_not_integers():
    with pytest.raises(TypeError, match="expected integer indices for 'triangles', got .*float64"):
        find_self_intersections(TRI, [[0.0, 1.0, 2.0]])


def test_triangles_of_wrong_shape():
    with pytest.raises(ValueError, match=r"expected an \(m, 3\) array for 'triangles', got shape \(1, 4\)"):
        find_self_intersections(TRI, [[0, 1, 2, 0]])


def test_index_out_of_range():
    with pytest.raises(ValueError, match=r"indices in \[0, 3\) for 'triangles'.*got 3"):
        find_self_intersections(TRI, [[0, 1, 3]])


def test_negative_index():
    with pytest.raises(ValueError, match="'triangles'.*got -1"):
        find_degenerate_faces(TRI, [[0, -1, 2]])


def test_no_points_for_many_faces():
    # found by a review: with no points, the passes on all cores read before the check
    with pytest.raises(ValueError, match=r"indices in \[0, 0\) for 'triangles'.*got 0"):
        find_self_intersections(np.zeros((0, 3)), np.zeros((2 * wmi._MIN_FACES_PER_WORKER + 1, 3), int))


def test_unsigned_index_beyond_int64_is_named_as_given():
    # found by a review: converted to int64 first, 2^63 + 5 was reported as a negative index
    big = np.array([[0, 0, 0], [0, 2**63 + 5, 0], [0, 0, 0]], np.uint64)
    for check in (find_self_intersections, find_degenerate_faces):
        with pytest.raises(ValueError, match="got 9223372036854775813"):
            check(TRI, big)


def test_bad_workers():
    with pytest.raises(ValueError, match="'workers'"):
        find_self_intersections(TRI, GOOD_T, workers=0)


# -- integration (optional: skipped while the package does not import) -----------------------


def test_meshed_surface_is_embedded():
    wm = pytest.importorskip("warpmesh")
    try:
        shape, bounds = wm.example("part")
        mesh = wm.mesh_surface(shape, bounds=bounds, resolution=48)
    except (AttributeError, ImportError) as exc:  # the package mid-move
        pytest.skip(f"warpmesh.mesh_surface unavailable: {exc}")
    assert find_self_intersections(mesh.points, mesh.triangles).shape == (0, 2)


# -- tetrahedra: find_tet_overlaps ------------------------------------------------------------


def _overlap_depth(pts, t1, t2) -> float:
    """The largest d such that some point has every barycentric coordinate >= d in both
    tetrahedra (an LP, scipy's HiGHS): > 0 iff their interiors overlap, >= 0 iff they meet."""
    from scipy.optimize import linprog

    rows = []
    for t in (t1, t2):
        p = pts[t]
        inv = np.linalg.inv((p[1:] - p[0]).T)  # (l_1, l_2, l_3) = inv (x - p_0), l_0 = 1 - their sum
        a = np.vstack([-inv.sum(axis=0), inv])
        b = np.r_[1.0 + inv.sum(axis=0) @ p[0], -inv @ p[0]]
        rows.append((a, b))
    # maximise d subject to a x + b >= d for both: -a x + d <= b
    A = np.vstack([np.column_stack([-a, np.ones(4)]) for a, _ in rows])
    B = np.concatenate([b for _, b in rows])
    res = linprog(c=[0, 0, 0, -1], A_ub=A, b_ub=B, bounds=[(None, None)] * 3 + [(None, 1.0)], method="highs")
    assert res.status == 0
    return -res.fun


def _embedded_by_lp(pts, tets) -> bool:
    """Every tetrahedron non-flat and positive, and no two with overlapping interiors (all
    pairs whose boxes meet, by LP): the independent oracle of find_tet_overlaps."""
    p = pts[tets]
    vol = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    if (vol <= 1e-12).any():
        return False
    lo, hi = p.min(axis=1), p.max(axis=1)
    faces = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])
    for i in range(len(tets)):
        near = np.flatnonzero(np.all(lo[i] <= hi, axis=1) & np.all(lo <= hi[i], axis=1))
        for j in near[near > i]:
            # a face plane of either with the other's four vertices on its outer side
            # separates them (a shortcut only: the LP decides the rest)
            if any(_outside_a_face(p[a], p[b], faces) for a, b in ((i, j), (j, i))):
                continue
            if _overlap_depth(pts, tets[i], tets[j]) > 1e-9:
                return False
    return True


def _outside_a_face(t, other, faces) -> bool:
    f = t[faces]
    n = np.cross(f[:, 1] - f[:, 0], f[:, 2] - f[:, 0])
    side = np.einsum("fk,vfk->fv", n, other[:, None, :] - f[None, :, 0])
    return bool((side >= -1e-12).all(axis=1).any())


def test_embedded_volume_meshes_have_no_overlaps():
    import warpmesh as wm

    pts, tets = _kuhn_block(3)  # exact coordinates, coplanar boundary faces, shared diagonals
    assert find_tet_overlaps(pts, tets).shape == (0, 2)
    assert find_tet_overlaps(_moved(pts, 5), tets).shape == (0, 2)
    b = ((-1.2,) * 3, (1.2,) * 3)
    for m in (wm.mesh_domain(wm.torus(0.8, 0.3), bounds=b, size=0.15),
              wm.mesh_domain(wm.sphere(1.0) - wm.sphere(0.5), bounds=b, size=0.15),  # a cavity: two shells
              wm.mesh_domain(wm.sphere(1.0), bounds=b, size=0.3, method="delaunay")):
        assert m.check().shape == (0, 2)
        assert m.stats()["self_intersections"] == 0


def test_tetgen_meshes_have_no_overlaps():
    # a mesher no one here wrote: TetGen's quality tetrahedra of a trimesh icosphere
    tetgen = pytest.importorskip("tetgen")
    s = trimesh.creation.icosphere(2)
    pts, tets = tetgen.TetGen(s.vertices, s.faces).tetrahedralize(order=1, minratio=1.5)[:2]
    pts, tets = np.asarray(pts, float), np.asarray(tets, np.int64)
    p = pts[tets]
    vol = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
    if (vol < 0).all():  # TetGen's own orientation convention: the house's is the opposite one
        tets = tets[:, [0, 2, 1, 3]]
    assert len(tets) > 100 and find_tet_overlaps(pts, tets).shape == (0, 2)
    assert len(find_tet_overlaps(pts, tets[:, [0, 2, 1, 3]])) == len(tets)  # all inverted: (i, i) each


def test_bad_tetrahedra_are_reported_alone():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], float)
    cases = {"inverted": [0, 2, 1, 3], "flat": [0, 1, 2, 4], "repeated vertex": [0, 1, 1, 3]}
    for name, t in cases.items():
        got = find_tet_overlaps(pts, [[0, 1, 2, 3], t] if name != "inverted" else [t])
        want = [1, 1] if name != "inverted" else [0, 0]
        assert want in got.tolist(), name  # the flat one also shares face (0, 1, 2) on the same side
        assert len(got) <= 2, name
    # nearly flat but certified positive: not reported
    near = np.vstack([pts[:3], [[0.3, 0.3, 1e-12]]])
    assert find_tet_overlaps(near, [[0, 1, 2, 3]]).shape == (0, 2)


def test_faces_shared_the_wrong_way_are_reported():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.2, 0.2, 0.5], [0, 0, -1]], float)
    # the same face (0, 1, 2) with both tetrahedra above it; a duplicate; a face in three
    assert find_tet_overlaps(pts, [[0, 1, 2, 3], [0, 1, 2, 4]]).tolist() == [[0, 1]]
    assert find_tet_overlaps(pts, [[0, 1, 2, 3], [1, 2, 0, 3]]).tolist() == [[0, 1]]
    got = find_tet_overlaps(pts, [[0, 1, 2, 3], [0, 2, 1, 5], [0, 1, 2, 4]])
    assert {tuple(p) for p in got.tolist()} >= {(0, 2), (1, 2)}
    assert _embedded_by_lp(pts, np.array([[0, 1, 2, 3], [0, 2, 1, 5]]))
    assert not _embedded_by_lp(pts, np.array([[0, 1, 2, 3], [0, 1, 2, 4]]))


def test_overlapping_copies_and_nested_shells_are_reported():
    import warpmesh as wm

    b = ((-1.2,) * 3, (1.2,) * 3)
    ball = wm.mesh_domain(wm.sphere(1.0), bounds=b, size=0.35)
    small = wm.mesh_domain(wm.sphere(0.4), bounds=b, size=0.2)
    n, t = len(ball.points), ball.cells["tetra"]
    # a copy moved by half a radius: boundaries cross, every reported pair meets (LP)
    pts = np.vstack([ball.points, ball.points + [0.5, 0.0, 0.0]])
    got = find_tet_overlaps(pts, np.vstack([t, t + n]))
    assert len(got) > 0
    tets = np.vstack([t, t + n])
    assert all(_overlap_depth(pts, tets[i], tets[j]) >= -1e-12 for i, j in got[:40])
    # a small ball inside the big one: no boundary crosses, the winding number is 2 inside it
    pts = np.vstack([ball.points, small.points])
    tets = np.vstack([t, small.cells["tetra"] + n])
    got = find_tet_overlaps(pts, tets)
    assert len(got) > 0 and all(_overlap_depth(pts, tets[i], tets[j]) > 1e-9 for i, j in got)
    assert wm.Mesh(pts, {"tetra": tets}).stats()["self_intersections"] == len(got)


@pytest.mark.parametrize("seed", range(2))
def test_moved_vertices_agree_with_the_lp_oracle(seed):
    # the Kuhn block with interior vertices moved at random, some far enough to fold their
    # star: the check is empty exactly when the LP oracle finds the mesh embedded
    rng = np.random.default_rng(seed)
    pts, tets = _kuhn_block(3)
    inner = np.flatnonzero(np.all((pts > 0) & (pts < 1), axis=1))
    verdicts = set()
    for step in (0.05, 0.15, 0.3, 0.45):
        moved = pts.copy()
        moved[inner] += rng.uniform(-step, step, (len(inner), 3))
        empty = len(find_tet_overlaps(moved, tets)) == 0
        assert empty == _embedded_by_lp(moved, tets), step
        verdicts.add(empty)
    assert verdicts == {True, False}


def test_nested_shells_at_huge_and_tiny_scales():
    # condition (4) on unscaled coordinates overflowed (triple products past 1e308: a tet
    # inside another one passed at 1e103) and underflowed (two disjoint tets reported at
    # 1e-110); every other predicate runs on points scaled by a power of two
    unit = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tets = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    nested = np.vstack([8 * unit - 1, 0.5 * unit + 0.25])  # winding number 2 in the small one
    apart = np.vstack([unit, unit + [3, 0, 0]])
    for s in (1.0, 1e-110, 1e-200, 1e103, 1e120, 1e300, 2.0**-1000):
        assert find_tet_overlaps(nested * s, tets).tolist() == [[0, 1]], s
        assert find_tet_overlaps(apart * s, tets).tolist() == [], s


def test_tet_overlaps_refuse_bad_input():
    with pytest.raises(ValueError, match="'tetra'"):
        find_tet_overlaps(np.zeros((4, 3)), [[0, 1, 2]])
    with pytest.raises(ValueError, match="'tetra'"):
        find_tet_overlaps(np.zeros((4, 3)), [[0, 1, 2, 4]])
    with pytest.raises(TypeError, match="'tetra'"):
        find_tet_overlaps(np.zeros((4, 3)), [[0.0, 1.0, 2.0, 3.0]])
    with pytest.raises(ValueError, match="'points'"):
        find_tet_overlaps(np.full((4, 3), np.nan), [[0, 1, 2, 3]])
    assert find_tet_overlaps(np.zeros((0, 3)), np.zeros((0, 4), int)).shape == (0, 2)


def _kuhn_cells(nc: int, drop=()):
    """_kuhn_block(nc) without the tetrahedra of the cells (integer lower corners) in drop."""
    pts, tets = _kuhn_block(nc)
    cell = np.rint(pts[tets].min(axis=1) * nc).astype(int)
    keep = ~np.isin(cell @ [nc * nc, nc, 1], [c[0] * nc * nc + c[1] * nc + c[2] for c in drop])
    return pts, tets[keep]


@pytest.mark.parametrize("matching", ["kernel", "sorted"])
def test_shells_nested_three_deep_on_grid_planes(monkeypatch, matching):
    # grid-aligned cubes (rays through edges and vertices of projected faces: ties on every
    # axis, so solid angles decide): a hollow cube, a hollow cube in its cavity, a solid cube
    # in that one's cavity (five boundary components, windings 1 everywhere: embedded), then
    # with a cavity filled (winding 2 or 3: reported, every pair overlapping by the LP), and
    # a U-shaped solid whose box holds a cube lying in its notch (not nested: embedded)
    calls = []
    solid_angles = rays._solid_angle_windings
    monkeypatch.setattr(rays, "_solid_angle_windings", lambda f, x: calls.append(len(x)) or solid_angles(f, x))
    if matching == "sorted":  # the faces matched by a sort: the boundary by corners, whose first faces tie
        monkeypatch.setattr(wmi, "_tet_face_pairs", lambda *args: None)
    hollow = _kuhn_cells(3, drop=[(1, 1, 1)])
    solid = _kuhn_block(3)
    cube = _kuhn_block(1)

    def joined(*parts):
        pts, tets, n = [], [], 0
        for (p, t), scale, shift in parts:
            pts.append(p * scale + shift)
            tets.append(t + n)
            n += len(p)
        return np.vstack(pts), np.vstack(tets)

    for inner in ((cube, 0.5, 4.25), (cube, 0.375, [4.4375, 4.3125, 4.1875])):  # the second one ties
        for outer, middle, embedded in ((hollow, hollow, True), (solid, hollow, False), (hollow, solid, False),
                                        (solid, solid, False)):
            pts, tets = joined((outer, 9.0, 0.0), (middle, 2.25, 3.375), inner)
            got = find_tet_overlaps(pts, tets)
            assert (len(got) == 0) == embedded, (embedded, got[:4])
            assert all(_overlap_depth(pts, tets[i], tets[j]) > 1e-9 for i, j in got[:: max(1, len(got) // 6)])
    assert calls or matching == "kernel"  # which faces represent the shells depends on the boundary's order
    u_shape = _kuhn_cells(3, drop=[(1, 1, 0), (1, 2, 0), (1, 1, 1), (1, 2, 1), (1, 1, 2), (1, 2, 2)])
    for shift in ([1.25, 1.25, 0.25], [1.25, 2.25, 1.25], [1.0, 1.0, 1.0]):  # in the notch; the last touches
        pts, tets = joined((u_shape, 3.0, 0.0), (cube, 0.5, shift))
        got = find_tet_overlaps(pts, tets)
        assert (len(got) == 0) == (shift[0] != 1.0), shift


def test_shells_sharing_an_edge_that_overlap_there_are_reported():
    # boundary sheets joined by an edge of both (four boundary faces on it) were one component
    # for condition (4), its winding taken from its total volume, and faces sharing an edge
    # are not reported unless coplanar: two octahedra on one equator crossing each other
    # there (B's upper half outside A, its lower half inside A), and a tet inside a cube
    # resting on an edge of the cube's bottom passed as embedded. Now the tets around such an
    # edge are tested for overlapping wedges (exact orientations). Sheets touching along an
    # edge from outside stay embedded: cubes welded on an edge, a checkerboard of cells.
    equator = [[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]]
    pts = np.array(equator + [[0, 0, 1], [0, 0, -1], [0, 0, 2], [0, 0, -0.5]], float)

    def octahedron(top, bottom):
        tets = np.array([[top, bottom, i, (i + 1) % 4] for i in range(4)])
        neg = np.linalg.det(pts[tets[:, 1:]] - pts[tets[:, :1]]) < 0
        tets[neg] = tets[neg][:, [0, 1, 3, 2]]
        return tets

    cube, cube_tets = _kuhn_block(4)
    cube = 4.0 * cube
    v, w = (int(np.flatnonzero(np.all(cube == p, axis=1))[0]) for p in ([1, 2, 0], [2, 2, 0]))
    resting = np.vstack([cube, [[1.5, 2.25, 0.5], [1.5, 1.75, 0.5]]])
    small = np.array([v, w, len(cube), len(cube) + 1])
    small = small if np.linalg.det(resting[small[1:]] - resting[small[0]]) > 0 else small[[0, 1, 3, 2]]
    for p, tets in ((pts, np.vstack([octahedron(4, 5), octahedron(6, 7)])),
                    (resting, np.vstack([cube_tets, small]))):
        got = find_tet_overlaps(p, tets)
        assert len(got) > 0 and all(_overlap_depth(p, tets[i], tets[j]) > 1e-9 for i, j in got)
    assert not _embedded_by_lp(pts, np.vstack([octahedron(4, 5), octahedron(6, 7)]))
    assert find_tet_overlaps(pts, octahedron(4, 5)).shape == (0, 2)
    c, ct = _kuhn_block(1)
    moved = c + [1, 1, 0]
    weld = np.array([next(iter(np.flatnonzero(np.all(c == x, axis=1))), 8 + k) for k, x in enumerate(moved)])
    checker = _kuhn_cells(2, drop=[(0, 0, 1), (0, 1, 0), (1, 0, 0), (1, 1, 1)])
    for p, tets in ((np.vstack([c, moved]), np.vstack([ct, weld[ct]])), checker):
        assert find_tet_overlaps(p, tets).shape == (0, 2)


def _face_matching(tets):
    """Both matchings of the faces of ``tets`` (kernel, sort) as comparable sets."""
    import warp as wp

    tets = np.asarray(tets, dtype=np.int64)
    kernel = wmi._tet_face_pairs(tets, wp.array(tets.astype(np.int32).ravel(), dtype=wp.int32, device="cpu"),
                                 wp.get_device("cpu"))
    sort = wmi._tet_face_pairs_sorted(tets)
    return kernel, sort


def _as_sets(matched):
    once, corners, pairs = matched
    return (dict(zip(once.tolist(), map(tuple, corners.tolist()))),
            set(map(tuple, np.sort(pairs, axis=1).tolist())))


@pytest.mark.parametrize("case", ["block", "shuffled", "three_on_a_face", "same_side", "degenerate", "large"])
def test_tet_face_matching_kernel_equals_the_sort(case):
    pts, tets = _kuhn_block(30 if case == "large" else 5)  # large: 648,000 faces, sorted by two workers
    rng = np.random.default_rng(7)
    if case in ("shuffled", "large"):  # any numbering of points and tetrahedra, any rotation of each row's corners
        perm = rng.permutation(len(pts))
        tets = perm[tets][rng.permutation(len(tets))]
        rot = rng.integers(0, 3, len(tets))  # even permutations keep the orientation
        for r, order in ((1, [1, 2, 0, 3]), (2, [2, 0, 1, 3])):
            tets[rot == r] = tets[rot == r][:, order]
    elif case == "three_on_a_face":  # a face in three tetrahedra, and one with a repeated corner
        t = tets[0]
        tets = np.vstack([tets, [t[1], t[2], t[3], len(pts)], [t[0], t[0], t[1], t[2]]])
    elif case == "same_side":  # the second tetrahedron of an interior face turned over
        tets = tets.copy()
        tets[3] = tets[3][[1, 0, 2, 3]]
    elif case == "degenerate":
        tets = np.vstack([tets, [0, 0, 0, 0], [1, 1, 2, 2]])
    kernel, sort = _face_matching(tets)
    assert kernel is not None
    k_faces, k_pairs = _as_sets(kernel)
    s_faces, s_pairs = _as_sets(sort)
    assert k_faces == s_faces and k_pairs == s_pairs
    assert np.all(np.diff(kernel[0]) > 0)  # boundary faces by id
    if case in ("three_on_a_face", "same_side"):
        assert k_pairs
    if case == "block":  # the cube's 6 * 2 * 25 boundary triangles, no pair
        assert len(k_faces) == 300 and not k_pairs


def test_tet_face_matching_sorts_on_a_fan():
    # 2000 tetrahedra about vertex 0 and two apexes (a double cone): each apex is the largest
    # corner of 2000 faces, too many to scan, so the kernels give up (None) and
    # find_tet_overlaps sorts the faces; its verdicts are the same
    k = 1000
    ring = np.column_stack([np.arange(1, k + 1), np.r_[np.arange(2, k + 1), 1]])
    tets = np.vstack([np.column_stack([np.zeros(k, int), ring, np.full(k, k + 1)]),
                      np.column_stack([np.zeros(k, int), ring[:, ::-1], np.full(k, k + 2)])])
    angle = 2 * np.pi * np.arange(k) / k
    pts = np.vstack([[0, 0, 0], np.column_stack([np.cos(angle), np.sin(angle), np.zeros(k)]), [0, 0, 1], [0, 0, -1]])
    signs = np.einsum("ij,ij->i", np.cross(pts[tets[:, 1]] - pts[tets[:, 0]], pts[tets[:, 2]] - pts[tets[:, 0]]),
                      pts[tets[:, 3]] - pts[tets[:, 0]])
    tets[signs < 0] = tets[signs < 0][:, [1, 0, 2, 3]]
    kernel, _ = _face_matching(tets)
    assert kernel is None
    assert len(find_tet_overlaps(pts, tets)) == 0
    flipped = tets.copy()
    flipped[5] = flipped[5][[1, 0, 2, 3]]  # inverted: reported as (5, 5), and on the same side as its neighbours
    got = find_tet_overlaps(pts, flipped)
    assert [5, 5] in got.tolist() and len(got) > 1


def test_tet_face_matching_by_kernels_or_sort_gives_the_same_verdicts(monkeypatch):
    pts, tets = _kuhn_block(4)
    bad = tets.copy()
    bad[7] = bad[7][[1, 0, 2, 3]]  # inverted
    bad = np.vstack([bad, bad[20]])  # a tetrahedron twice: its faces in two on the same side
    verdicts, default = {}, wmi._BUCKET_READS
    for reads in (default, 0):  # 0: no scan allowed, the faces are sorted
        monkeypatch.setattr(wmi, "_BUCKET_READS", reads)
        assert (_face_matching(tets)[0] is None) == (reads == 0)
        verdicts[reads] = [find_tet_overlaps(pts, t).tolist() for t in (tets, bad)]
    assert verdicts[0] == verdicts[default]
    assert verdicts[0][0] == [] and [7, 7] in verdicts[0][1] and [20, len(bad) - 1] in verdicts[0][1]


def test_stats_share_the_boundary_components_with_the_nested_shell_test(monkeypatch):
    # Mesh.stats() labels the boundary's components once (mesh_topology(labels=True)) and the
    # overlap check's condition (4) reads them: no second matching of the half-edges, and
    # the same verdicts as find_tet_overlaps labelling them itself (embedded: a hollow cube,
    # a hollow cube in its cavity, a cube in that one's cavity; not embedded: the middle
    # one solid, so the innermost cube lies inside its tetrahedra)
    from warpmesh.cells import topology as wmt
    from warpmesh.mesh import Mesh

    hollow, solid, cube = _kuhn_cells(3, drop=[(1, 1, 1)]), _kuhn_block(3), _kuhn_block(1)
    calls = []
    real = wmt.connected_components
    monkeypatch.setattr(wmt, "connected_components", lambda *a, **k: calls.append(1) or real(*a, **k))
    for middle, embedded in ((hollow, True), (solid, False)):
        parts = ((hollow, 9.0, 0.0), (middle, 2.25, 3.375), (cube, 0.5, 4.25))
        pts = np.vstack([p * scale + shift for (p, _), scale, shift in parts])
        offsets = np.cumsum([0] + [len(p) for (p, _), _, _ in parts])
        tets = np.vstack([t + o for ((_, t), _, _), o in zip(parts, offsets)])
        calls.clear()
        direct = find_tet_overlaps(pts, tets)
        assert len(calls) == 1 and (len(direct) == 0) == embedded
        calls.clear()
        mesh = Mesh(pts, {"tetra": tets})
        s = mesh.stats()
        assert calls == [] and s["components"] == (5 if embedded else 4)
        assert s["self_intersections"] == len(direct)
        np.testing.assert_array_equal(mesh.check(), direct)
        labels = wmt.mesh_topology(mesh._tet_faces.boundary, len(pts), labels=True)["labels"]
        np.testing.assert_array_equal(labels, real(mesh._tet_faces.boundary, len(pts))[1])
