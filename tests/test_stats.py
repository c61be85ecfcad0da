"""Mesh.stats() and warpmesh.cells.topology.mesh_topology against straightforward
computations: a dict of edges, a walk around each vertex in Python, components by a
breadth-first search, areas and volumes face by face (no warpmesh code in the oracle)."""

from __future__ import annotations

import itertools
from collections import defaultdict, deque

import numpy as np
import pytest
import trimesh

from warpmesh.cells import topology as T
from warpmesh.cells.quality import quality_summary, triangle_quality
from warpmesh.mesh import Mesh


# ----------------------------------------------------------------------------- the oracle
def oracle_topology(faces) -> dict:
    faces = [tuple(int(x) for x in f) for f in np.asarray(faces).reshape(-1, 3)]
    directed = defaultdict(int)
    undirected = defaultdict(list)  # edge -> faces on it
    corners = defaultdict(list)  # vertex -> faces around it
    for fi, f in enumerate(faces):
        for j in range(3):
            a, b = f[j], f[(j + 1) % 3]
            directed[(a, b)] += 1
            undirected[(min(a, b), max(a, b))].append(fi)
        for v in set(f):
            corners[v].append(fi)
    counts = {e: len(fs) for e, fs in undirected.items()}
    bad = set()
    for v, fs in corners.items():  # fans: faces around v joined through edges through v
        if any(counts[(min(v, w), max(v, w))] > 2 for f in fs for w in faces[f] if w != v):
            bad.add(v)
            continue
        seen, todo = {fs[0]}, [fs[0]]
        while todo:
            f = todo.pop()
            for w in faces[f]:
                if w == v:
                    continue
                for g in undirected[(min(v, w), max(v, w))]:
                    if g not in seen:
                        seen.add(g)
                        todo.append(g)
        if len(seen) != len(set(fs)):
            bad.add(v)
    adjacency = defaultdict(set)  # faces sharing an edge
    for fs in undirected.values():
        for f, g in itertools.combinations(fs, 2):
            adjacency[f].add(g)
            adjacency[g].add(f)
    label, n_comp = {}, 0
    for start in range(len(faces)):
        if start in label:
            continue
        label[start] = n_comp
        queue = deque([start])
        while queue:
            f = queue.popleft()
            for g in adjacency[f]:
                if g not in label:
                    label[g] = n_comp
                    queue.append(g)
        n_comp += 1
    n_vertices = len({v for f in faces for v in f})
    return {
        "n_vertices": n_vertices,
        "n_edges": len(counts),
        "n_boundary_edges": sum(c == 1 for c in counts.values()),
        "n_nonmanifold_edges": sum(c > 2 for c in counts.values()),
        "watertight": bool(faces) and all(c == 2 for c in counts.values()),
        "edge_manifold": all(c <= 2 for c in counts.values()),
        "manifold": all(c <= 2 for c in counts.values()) and not bad,
        "oriented": all(c == 1 for c in directed.values()),
        "euler": n_vertices - len(counts) + len(faces),
        "components": n_comp,
    }


def oracle_measures(points, faces) -> tuple[float, float]:
    p = np.asarray(points, float)
    used = p[np.unique(np.asarray(faces))]
    centre = 0.5 * (used.min(axis=0) + used.max(axis=0))
    area = volume = 0.0
    for f in np.asarray(faces):
        a, b, c = (p[i] for i in f)
        if p.shape[1] == 2:
            area += 0.5 * abs((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0])
            continue
        area += 0.5 * float(np.sqrt(np.sum(np.cross(b - a, c - a) ** 2)))
        volume += float(np.dot(a - centre, np.cross(b - centre, c - centre))) / 6.0
    return area, volume


# ----------------------------------------------------------------------------- meshes
def _sphere():
    tm = trimesh.creation.icosphere(subdivisions=2)
    return np.asarray(tm.vertices), np.asarray(tm.faces)


def _cases() -> dict:
    pts, tri = _sphere()
    n = len(pts)
    flipped = tri.copy()
    flipped[[3, 17]] = flipped[[3, 17]][:, ::-1]
    two = (np.vstack([pts, pts + 3.0]), np.vstack([tri, tri + n]))
    apex = np.array([[0, 0, 0], [1, 0, 1], [0, 1, 1], [-1, -1, 1], [1, 0, -1], [0, 1, -1], [-1, -1, -1]], float)
    cones = [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2], [0, 5, 4], [0, 6, 5], [0, 4, 6], [4, 5, 6]]
    fin = np.vstack([pts, [[0.0, 0.0, 3.0]]])
    a, b = tri[0, 0], tri[0, 1]
    torus = trimesh.creation.torus(1.0, 0.3)
    return {
        "closed sphere": (pts, tri),
        "open sphere": (pts, tri[5:]),
        "flipped faces": (pts, flipped),
        "two spheres": two,
        "two cones at one apex": (apex, np.array(cones)),
        "three faces on an edge": (fin, np.vstack([tri, [[a, b, n]]])),
        "duplicate face": (pts, np.vstack([tri, tri[:1]])),
        "bowtie": (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.0]]),
                   np.array([[0, 1, 2], [0, 3, 4]])),
        "repeated vertex": (pts, np.vstack([tri, [[0, 0, 1]]])),
        "unused points": (np.vstack([pts, [[9.0, 9, 9]]]), tri),
        "torus": (np.asarray(torus.vertices), np.asarray(torus.faces)),
        "square 2D": (np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]]), np.array([[0, 1, 2], [0, 2, 3]])),
    }


CASES = _cases()


@pytest.mark.parametrize("name", list(CASES))
def test_mesh_topology_equals_the_oracle(name):
    points, faces = CASES[name]
    assert T.mesh_topology(faces, len(points)) == oracle_topology(faces)
    labelled = T.mesh_topology(faces, len(points), labels=True)  # + each face's component
    n, labels = T.connected_components(faces, len(points))
    np.testing.assert_array_equal(labelled.pop("labels"), labels)
    assert labelled == oracle_topology(faces) and labelled["components"] == n == len(set(labels.tolist()))


@pytest.mark.parametrize("seed", range(6))
def test_mesh_topology_of_random_soups(seed):
    """Random faces over few vertices: every kind of non-manifold and flipped edge."""
    rng = np.random.default_rng(seed)
    n = 12
    faces = np.array([rng.choice(n, 3, replace=False) for _ in range(30 + 10 * seed)])
    assert T.mesh_topology(faces, n) == oracle_topology(faces)


@pytest.mark.parametrize("seed", range(4))
def test_mesh_topology_of_pieces_of_a_sphere(seed):
    """A sphere with random faces removed, some flipped, renumbered at random."""
    pts, tri = _sphere()
    rng = np.random.default_rng(seed)
    keep = tri[rng.random(len(tri)) > 0.2]
    flip = rng.random(len(keep)) < 0.05
    keep[flip] = keep[flip][:, ::-1]
    perm = rng.permutation(len(pts))
    faces = perm[keep]
    assert T.mesh_topology(faces, len(pts)) == oracle_topology(faces)


def test_mesh_topology_agrees_with_the_one_figure_functions():
    for name, (points, faces) in CASES.items():
        t = T.mesh_topology(faces, len(points))
        _, _, counts = T.unique_edges(faces)
        assert t["n_edges"] == len(counts), name
        assert t["watertight"] == T.is_watertight(faces), name
        assert t["edge_manifold"] == T.is_edge_manifold(faces), name
        assert t["manifold"] == (T.is_edge_manifold(faces) and T.is_vertex_manifold(faces, len(points))), name
        assert t["oriented"] == T.is_consistently_oriented(faces), name
        assert t["euler"] == T.euler_characteristic(None, faces), name
        assert t["components"] == T.connected_components(faces)[0], name


def test_mesh_topology_without_faces():
    t = T.mesh_topology(np.zeros((0, 3), int))
    assert (t["watertight"], t["euler"], t["components"]) == (False, 0, 0)


@pytest.mark.parametrize("name", list(CASES))
def test_surface_measures_equal_the_oracle(name):
    points, faces = CASES[name]
    area, volume = T.surface_measures(points, faces)
    want_area, want_volume = oracle_measures(points, faces)
    assert area == pytest.approx(want_area, rel=1e-12)
    if np.shape(points)[1] == 3:
        assert volume == pytest.approx(want_volume, rel=1e-12, abs=1e-14)
    else:
        assert volume is None


@pytest.mark.parametrize("name", list(CASES))
def test_surface_figures_quality_equals_triangle_quality(name):
    """The kernel's Q_K per face (stats() uses it) against cells.quality's numpy one."""
    points, faces = CASES[name]
    area, _, q = T.surface_figures(points, faces)
    want = triangle_quality(points, faces)
    assert q.shape == want.shape and area == pytest.approx(T.surface_measures(points, faces)[0], rel=0)
    assert np.array_equal(np.isinf(q), np.isinf(want))
    assert np.allclose(q[np.isfinite(q)], want[np.isfinite(want)], rtol=1e-12, atol=0)


def test_surface_figures_quality_of_slivers_and_degenerate_faces():
    rng = np.random.default_rng(7)
    points = rng.normal(size=(3000, 3))
    faces = rng.integers(0, 3000, size=(5000, 3))
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    # slivers down to collinear: the third corner on the first edge, lifted by 10^-k of its length
    a, b = points[faces[:200, 0]], points[faces[:200, 1]]
    lift = np.cross(b - a, [0.3, 0.5, 0.7])
    points[faces[:200, 2]] = 0.5 * (a + b) + lift * (10.0 ** -np.arange(200) / 10)[:, None]
    points[faces[200, 2]] = points[faces[200, 0]]  # two corners at one place
    _, _, q = T.surface_figures(points, faces)
    want = triangle_quality(points, faces)
    degenerate = np.isinf(want)
    assert 0 < degenerate.sum() < 200 and np.array_equal(np.isinf(q), degenerate)
    assert np.allclose(q[~degenerate], want[~degenerate], rtol=1e-10, atol=0)
    right = T.surface_figures([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])[2]
    assert right[0] == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3), rel=1e-14)


@pytest.mark.parametrize("name", list(CASES))
def test_stats_quality_equals_quality_summary(name):
    points, faces = CASES[name]
    s, want = Mesh(points, {"triangle": faces}).stats(), quality_summary(points, faces)
    assert s["worst_q"] == pytest.approx(want["worst_q"], rel=1e-12)
    assert s["mean_q"] == pytest.approx(want["mean_q"], rel=1e-12)


def test_surface_measures_refuse_indices_beyond_the_points():
    with pytest.raises(ValueError, match="'faces'"):
        T.surface_measures(np.zeros((3, 3)), [[0, 1, 3]])


@pytest.mark.parametrize("name", list(CASES))
def test_stats_equal_the_oracle(name):
    points, faces = CASES[name]
    s = Mesh(points, {"triangle": faces}).stats()
    t = oracle_topology(faces)
    area, volume = oracle_measures(points, faces)
    for key in ("watertight", "manifold", "oriented", "euler", "components"):
        assert s[key] == t[key], key
    closed = t["watertight"] and t["manifold"] and t["oriented"]
    assert s["genus"] == ((2 * t["components"] - t["euler"]) // 2 if closed else None)
    assert s["area"] == pytest.approx(area, rel=1e-12)
    if t["watertight"] and np.shape(points)[1] == 3:
        assert s["volume"] == pytest.approx(volume, rel=1e-12, abs=1e-14)
    else:
        assert s["volume"] is None


def test_stats_of_tetrahedra_with_boundary_triangles():
    """Tetrahedra (volume from the cells) beside their closed boundary triangles."""
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    tets[1] = tets[1][[1, 0, 2, 3]] if np.linalg.det(pts[tets[1, 1:]] - pts[tets[1, 0]]) < 0 else tets[1]
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 4], [1, 4, 3], [2, 3, 4]])
    s = Mesh(pts, {"tetra": tets, "triangle": faces}).stats()
    t = oracle_topology(faces)
    assert (s["watertight"], s["manifold"], s["euler"], s["components"]) == (True, True, 2, 1) == (
        t["watertight"], t["manifold"], t["euler"], t["components"])
    assert s["oriented"] == t["oriented"]
    want = sum(abs(np.linalg.det(pts[k[1:]] - pts[k[0]])) / 6.0 for k in tets)
    assert s["volume"] == pytest.approx(want, rel=1e-12)
    assert s["ne"] == 2 and s["n_triangles"] == 6


def _boundary_by_dict(tets) -> np.ndarray:
    """The faces in one tetrahedron, oriented outward (the oracle: a dict of sorted corners)."""
    seen = defaultdict(list)
    for t in np.asarray(tets).tolist():
        for f in ((t[1], t[2], t[3]), (t[0], t[3], t[2]), (t[0], t[1], t[3]), (t[0], t[2], t[1])):
            seen[tuple(sorted(f))].append(f)
    return np.array([fs[0] for fs in seen.values() if len(fs) == 1])


def _two_region_blob():
    import warpmesh as wm

    labels = np.zeros((14, 12, 12), dtype=np.uint8)
    labels[2:9, 2:10, 2:10] = 1
    labels[7:12, 3:9, 3:9] = 2  # touches label 1: an interface, junction curves on the boundary
    return wm.mesh_domain(labels, labels="all", size=2.0)


def test_stats_of_a_volume_mesh_are_of_its_boundary(monkeypatch):
    """Topology and area of a tetrahedral mesh describe the boundary of its tetrahedra, not
    its triangle block: a two-region mesh's triangles hold the interface too (edges in three
    faces at the junction), its boundary is one closed sphere. The faces are matched once
    for the topology and the overlap check together."""
    from warpmesh.cells import intersections

    mesh = _two_region_blob()
    tets = mesh.cells["tetra"]
    assert len(set(mesh.cell_refs["tetra"].tolist())) == 2
    block = oracle_topology(mesh.cells["triangle"])
    assert not block["manifold"] and not block["watertight"]  # what stats() reported before
    calls = []
    real = intersections._matched_faces
    monkeypatch.setattr(intersections, "_matched_faces", lambda *a: calls.append(1) or real(*a))
    s = mesh.replace().stats()  # no cached statistics
    assert len(calls) == 1 and s["self_intersections"] == 0
    boundary = _boundary_by_dict(tets)
    t = oracle_topology(boundary)
    for key in ("watertight", "manifold", "oriented", "euler", "components"):
        assert s[key] == t[key], key
    assert (s["watertight"], s["oriented"], s["euler"], s["components"], s["genus"]) == (True, True, 2, 1, 0)
    assert s["area"] == pytest.approx(oracle_measures(mesh.points, boundary)[0], rel=1e-12)
    only = Mesh(mesh.points, {"tetra": tets}).stats()  # no triangle block: the same figures (were None)
    assert {k: only[k] for k in ("watertight", "euler", "genus", "area")} == \
        {k: s[k] for k in ("watertight", "euler", "genus", "area")}


def test_stats_of_tetrahedra_fall_back_to_the_triangles():
    """An empty tetra block, or tetrahedra beside other solid cells: the triangle block's
    figures, as before."""
    pts, tri = _sphere()
    empty = Mesh(pts, {"tetra": np.zeros((0, 4), np.int64), "triangle": tri}).stats()
    assert (empty["watertight"], empty["euler"]) == (True, 2)
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1.0]])
    mixed = Mesh(np.vstack([cube, [[0.5, 0.5, 2.0]]]),
                 {"hexahedron": [[0, 1, 2, 3, 4, 5, 6, 7]], "tetra": [[4, 5, 6, 8]],
                  "triangle": [[0, 1, 2]]}).stats()
    assert (mixed["watertight"], mixed["euler"], mixed["components"]) == (False, 1, 1)  # the one triangle


def test_tet_faces_equal_the_sorted_matching_and_the_oracle():
    """The kernel matching (buckets) against the sort and the dict oracle: the same boundary
    faces with the same orientation, and the same bad pairs (a duplicated tetrahedron)."""
    from warpmesh.cells.intersections import _tet_face_pairs_sorted, tet_faces

    mesh = _two_region_blob()
    tets = np.vstack([mesh.cells["tetra"], mesh.cells["tetra"][:3]])
    f = tet_faces(mesh.points, tets)
    once, boundary, pairs = _tet_face_pairs_sorted(tets)

    def rows(faces):
        r = np.asarray(faces)
        r = np.array([np.roll(x, -int(np.argmin(x))) for x in r])  # rotation kept: orientation compared
        return sorted(map(tuple, r.tolist()))

    assert rows(f.boundary) == rows(boundary) == rows(_boundary_by_dict(tets))
    assert sorted(f.once.tolist()) == sorted(once.tolist())
    assert sorted(map(tuple, np.sort(f.face_pairs, axis=1).tolist())) == \
        sorted(map(tuple, np.sort(pairs, axis=1).tolist())) and len(pairs) > 0
    with pytest.raises(ValueError, match="'tetra'"):
        tet_faces(mesh.points, tets[:, :3])
    with pytest.raises(ValueError, match="'tetra'"):
        tet_faces(mesh.points[:4], tets)


def test_cli_figures_are_what_the_mesh_carries(monkeypatch):
    """warpmesh renumber prints the renumbering's own figures: the same as stats() gives,
    read without computing the statistics."""
    from warpmesh.cli.report import mesh_figures

    pts, tri = _sphere()
    out = Mesh(pts, {"triangle": tri}).renumber("gibbs")
    keys = ["np", "ne", "n_cells", "bandwidth", "profile", "profile_before", "nodes_per_second"]
    want = {k: out.stats()[k] for k in keys}
    fresh = out.replace()  # no cached statistics

    def refuse(self):
        raise AssertionError("stats() computed")

    monkeypatch.setattr(Mesh, "stats", refuse)
    assert mesh_figures(fresh, keys) == want
    monkeypatch.undo()
    assert mesh_figures(fresh, ["np", "watertight"]) == {"np": len(pts), "watertight": True}  # stats() for the rest


def test_summarize_quality_names_a_wrong_shape_and_takes_empty_input():
    from warpmesh.cells.quality import summarize_quality

    with pytest.raises(ValueError, match="'q'"):
        summarize_quality(np.ones((2, 2)))
    s = summarize_quality([])
    assert s["n_elements"] == 0 and np.isnan(s["worst_q"]) and np.isnan(s["mean_q"])


def test_mesh_topology_split_across_workers_equals_the_oracle():
    """Over 2^15 vertices, so the matching's launches are split (one tally row each): a
    sphere with faces removed, flipped and repeated, renumbered at random."""
    sphere = trimesh.creation.icosphere(subdivisions=6)  # 40,962 vertices
    rng = np.random.default_rng(11)
    faces = np.asarray(sphere.faces)[rng.random(len(sphere.faces)) > 0.05]
    flip = rng.random(len(faces)) < 0.02
    faces[flip] = faces[flip][:, ::-1]
    faces = np.vstack([faces, faces[rng.choice(len(faces), 40)]])  # edges in three and four faces
    faces = rng.permutation(len(sphere.vertices))[faces]
    got = T.mesh_topology(faces, len(sphere.vertices), labels=True)
    n, labels = T.connected_components(faces, len(sphere.vertices))
    np.testing.assert_array_equal(got.pop("labels"), labels)
    assert got == oracle_topology(faces) and got["components"] == n
    assert got["n_nonmanifold_edges"] > 0 and not got["oriented"] and got["n_boundary_edges"] > 0


def test_face_volumes_equal_numpy_and_sum_to_each_groups_volume():
    """Per face about one centre or its group's: the numpy triple products to rounding; over
    a closed group the enclosed volume (a sphere and a shifted, inside-out copy)."""
    pts, tri = _sphere()
    shifted = pts + [3.0, 0.0, 0.0]
    points = np.vstack([pts, shifted])
    faces = np.vstack([tri, tri[:, ::-1] + len(pts)])
    labels = np.repeat([0, 1], len(tri))
    centres = np.array([[0.1, 0.0, 0.0], [3.0, 0.2, 0.0]])
    got = T.face_volumes(points, faces, centres, labels)
    c = centres[labels]
    p0, p1, p2 = (points[faces[:, j]] - c for j in range(3))
    np.testing.assert_allclose(got, np.einsum("ij,ij->i", p0, np.cross(p1, p2)) / 6.0, rtol=1e-12, atol=1e-15)
    sums = np.bincount(labels, got)
    assert sums[0] == pytest.approx(T.signed_volume(pts, tri), rel=1e-12) and sums[1] == pytest.approx(-sums[0])
    one = T.face_volumes(pts, tri, [0.0, 0.0, 0.0])
    assert one.sum() == pytest.approx(T.signed_volume(pts, tri), rel=1e-12)
    with pytest.raises(ValueError, match="'centres'"):
        T.face_volumes(points, faces, centres)  # (G, 3) without labels
    with pytest.raises(ValueError, match="'labels'"):
        T.face_volumes(points, faces, centres, labels + 1)
    with pytest.raises(ValueError, match="'faces'"):
        T.face_volumes(pts, tri + len(pts), [0.0, 0.0, 0.0])


def test_mesh_topology_of_a_large_fan_takes_the_functions(monkeypatch):
    """A fan of 6,000 faces about vertex 0 (the smallest index): its run of half-edges would
    cost 1.4e8 reads on one thread, so the kernels give up (None) and the sorting functions
    give the figures; the same as the oracle, labels included."""
    k = 6000
    ring = np.arange(1, k + 1)
    fan = np.column_stack([np.zeros(k, int), ring, np.r_[ring[1:], 1]])
    assert T._matched_half_edges(fan, k + 1) is None
    got = T.mesh_topology(fan, k + 1, labels=True)
    labels = got.pop("labels")
    assert got == oracle_topology(fan) and got["components"] == 1 and not got["watertight"]
    assert labels.tolist() == [0] * k
    assert T.connected_components(fan, k + 1)[0] == 1


def test_a_mesher_s_facts_are_not_reported_for_a_mesh_made_from_its_output():
    """A dilated surface's stats said signed_volume 4.13 beside volume 33.06; a refined one's
    vertices 822 beside np 3282: the mesher's facts about its own output, carried in info."""
    import warpmesh as wm

    shape, bounds = wm.example("sphere")
    s = wm.mesh_surface(shape, bounds=bounds, resolution=16)
    own = s.stats()
    assert own["vertices"] == s.n_points and own["signed_volume"] == pytest.approx(own["volume"], rel=1e-5)
    assert "facts_of" not in own
    renumbered = s.renumber("gibbs").stats()  # the same points and cells: the facts hold
    assert renumbered["vertices"] == s.n_points
    for made in (s.transform(wm.transforms.dilation(2, dim=3)), s.refine(2), s.to_order(2)):
        st = made.stats()
        assert not {"vertices", "triangles", "signed_volume", "grid"} & set(st), sorted(st)
        assert "signed_volume" in made.info  # still in info (the mesh's history), not in its stats
