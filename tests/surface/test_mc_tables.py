"""Tests of the generated marching-cubes tables (kernels/mc_tables.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

try:
    from warpmesh.kernels import mc_tables as mc
except ImportError:  # package not installed: load the module from the source tree
    _path = Path(__file__).resolve().parents[1] / "kernels" / "mc_tables.py"
    _spec = importlib.util.spec_from_file_location("_mc_tables_under_test", _path)
    mc = importlib.util.module_from_spec(_spec)
    _spec.loader.exec_module(mc)

CORNERS_F = mc.CORNERS.astype(np.float64)
ALL_CONFIGS = range(256)


def inside_mask(config: int) -> np.ndarray:
    return np.array([(config >> c) & 1 for c in range(8)], dtype=bool)


def crossing_edges(config: int) -> set[int]:
    ins = inside_mask(config)
    return {e for e, (a, b) in enumerate(mc.EDGES) if ins[a] != ins[b]}


def triangles(config: int) -> np.ndarray:
    return mc.TRI_TABLE[config, : mc.TRI_COUNT[config]]


def boundary_loops(tris) -> list[list[int]]:
    """Loops bounding a set of oriented triangles (interior diagonals cancel out)."""
    directed = {(int(t[k]), int(t[(k + 1) % 3])) for t in tris for k in range(3)}
    nxt = {}
    for a, b in directed:
        if (b, a) not in directed:
            assert a not in nxt, "boundary vertex with two outgoing edges"
            nxt[a] = b
    return mc.chain_loops(nxt)


# ----------------------------------------------------------------------------- layout


def test_shapes_and_dtypes():
    expected = {
        "CORNERS": (8, 3),
        "EDGES": (12, 2),
        "EDGE_ORIGIN": (12, 4),
        "TRI_COUNT": (256,),
        "TRI_TABLE": (256, mc.MAX_TRIS, 3),
    }
    for name, shape in expected.items():
        arr = getattr(mc, name)
        assert arr.shape == shape, name
        assert arr.dtype == np.int32, name
        assert arr.flags["C_CONTIGUOUS"], name
    assert isinstance(mc.MAX_TRIS, int)
    assert mc.MAX_TRIS == mc.TRI_COUNT.max() == 5
    assert mc.TRI_COUNT[0] == 0 and mc.TRI_COUNT[255] == 0
    for c in ALL_CONFIGS:
        n = mc.TRI_COUNT[c]
        assert np.all(mc.TRI_TABLE[c, n:] == -1), c
        assert np.all((mc.TRI_TABLE[c, :n] >= 0) & (mc.TRI_TABLE[c, :n] < 12)), c


def test_cube_conventions():
    for i in range(8):
        assert tuple(mc.CORNERS[i]) == (i & 1, (i >> 1) & 1, (i >> 2) & 1)
    # documented edge order: x edges, then y edges, then z edges
    assert mc.EDGES.tolist() == [
        [0, 1], [2, 3], [4, 5], [6, 7],
        [0, 2], [1, 3], [4, 6], [5, 7],
        [0, 4], [1, 5], [2, 6], [3, 7],
    ]  # fmt: skip
    for e, (a, b) in enumerate(mc.EDGES):
        step = mc.CORNERS[b] - mc.CORNERS[a]
        axis = e // 4
        assert step.tolist() == np.eye(3, dtype=int)[axis].tolist()  # a is the lower corner
        assert mc.EDGE_ORIGIN[e].tolist() == [*mc.CORNERS[a].tolist(), axis]
    assert len({tuple(sorted(e)) for e in mc.EDGES.tolist()}) == 12


def test_symmetry_group():
    perms = {tuple(p) for p in mc.SYM_CORNERS.tolist()}
    assert len(perms) == 48
    assert sorted(mc.SYM_CORNERS[0].tolist()) == list(range(8))
    assert (mc.SYM_DET == 1).sum() == 24
    for s in range(48):
        p = mc.SYM_CORNERS[s]
        # an affine map of the cube: solve corner images for the linear part
        origin = CORNERS_F[p[0]]
        lin = np.column_stack([CORNERS_F[p[1 << a]] - origin for a in range(3)])
        for c in range(8):
            assert np.allclose(origin + lin @ CORNERS_F[c], CORNERS_F[p[c]])
        assert round(np.linalg.det(lin)) == mc.SYM_DET[s]
        for e, (a, b) in enumerate(mc.EDGES):  # induced edge permutation
            assert sorted(mc.EDGES[mc.SYM_EDGES[s, e]].tolist()) == sorted([p[a], p[b]])


def test_base_configurations_are_orbit_representatives():
    assert len(mc.BASE_CONFIGS) == 22
    orbits = {}
    for c in ALL_CONFIGS:
        orbit = frozenset(mc.apply_symmetry_to_config(s, c) for s in range(48))
        orbits[min(orbit)] = orbit
    assert sorted(orbits) == mc.BASE_CONFIGS.tolist()
    assert sum(len(o) for o in orbits.values()) == 256
    # complementation is not a symmetry: c and ~c are often in orbits of different shape
    assert mc.TRI_COUNT[0b1001] == 2 and mc.TRI_COUNT[0xFF ^ 0b1001] == 4


# ----------------------------------------------------------------------------- content


def test_no_repeated_edge_in_triangle():
    for c in ALL_CONFIGS:
        for t in triangles(c):
            assert len(set(t.tolist())) == 3, (c, t)


def test_referenced_edges_are_exactly_the_crossing_edges():
    for c in ALL_CONFIGS:
        used = set(triangles(c).ravel().tolist())
        assert used == crossing_edges(c), c


def test_no_triangle_flat_in_a_cube_face():
    for c in ALL_CONFIGS:
        for t in triangles(c):
            assert not mc.on_one_face(t), (c, t)


def test_table_matches_direct_tracing():
    for c in ALL_CONFIGS:
        traced = mc.trace_polygons(c)
        tris = triangles(c)
        assert mc.TRI_COUNT[c] == sum(len(lp) - 2 for lp in traced), c
        assert mc.canonical_loops(boundary_loops(tris)) == mc.canonical_loops(traced), c
        # each triangle lies within one loop
        loop_of = {e: i for i, lp in enumerate(traced) for e in lp}
        assert all(len({loop_of[e] for e in t.tolist()}) == 1 for t in tris), c


def test_symmetry_images_trace_the_same_surface():
    for c in ALL_CONFIGS:
        loops = mc.trace_polygons(c)
        for s in range(48):
            image = mc.trace_polygons(mc.apply_symmetry_to_config(s, c))
            assert mc.canonical_loops(image) == mc.canonical_loops(mc.apply_symmetry_to_loops(s, loops))


def test_traced_segments_follow_faces_and_separate_inside_corners():
    face_edges = [{mc.EDGE_OF[f[k], f[(k + 1) % 4]] for k in range(4)} for f in mc.FACES]
    for c in ALL_CONFIGS:
        ins = inside_mask(c)
        segments = {(lp[k], lp[(k + 1) % len(lp)]) for lp in mc.trace_polygons(c) for k in range(len(lp))}
        for a, b in segments:  # consecutive loop vertices share a face
            assert any(a in fe and b in fe for fe in face_edges), (c, a, b)
        for f, fe in zip(mc.FACES, face_edges):
            on_face = {(a, b) for a, b in segments if a in fe and b in fe}
            assert len(on_face) == len(fe & crossing_edges(c)) // 2, (c, f)
            if [ins[x] for x in f] in ([True, False, True, False], [False, True, False, True]):
                # ambiguous face: each segment cuts off a single inside corner
                for a, b in on_face:
                    shared = set(mc.EDGES[a].tolist()) & set(mc.EDGES[b].tolist())
                    assert len(shared) == 1 and ins[shared.pop()], (c, f, a, b)


def edge_points(t: np.ndarray) -> np.ndarray:
    """Vertex on each edge at fraction t (from the lower corner)."""
    a, b = mc.EDGES[:, 0], mc.EDGES[:, 1]
    return CORNERS_F[a] * (1.0 - t[:, None]) + CORNERS_F[b] * t[:, None]


def _edge_positions():
    rng = np.random.default_rng(12345)
    yield np.full(12, 0.5)
    for _ in range(100):
        yield rng.uniform(0.001, 0.999, 12)
    for _ in range(20):
        yield rng.choice([0.001, 0.999], 12)


def test_orientation_in_single_cube():
    """Each triangle's normal has a positive component along the inside->outside
    direction of every edge carrying one of its vertices: f decreases from the inside to
    the outside corner, so the outward surface normal where the surface crosses that edge
    must point along it; a flipped (or folded) triangle fails for some vertex. This is a
    local criterion, valid also when the cube holds several surface components (unlike
    mean outside corner - mean inside corner, which vanishes e.g. for config 0b10000001).
    """
    a, b = mc.EDGES[:, 0], mc.EDGES[:, 1]
    directions = {}
    for c in ALL_CONFIGS:
        ins = inside_mask(c)
        directions[c] = np.where(ins[a][:, None], CORNERS_F[b] - CORNERS_F[a], CORNERS_F[a] - CORNERS_F[b])
    for t in _edge_positions():
        p = edge_points(t)
        for c in ALL_CONFIGS:
            tris = triangles(c)
            if len(tris) == 0:
                continue
            n = np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]])
            assert np.all(np.einsum("tj,tkj->tk", n, directions[c][tris]) > 0), c


# ----------------------------------------------------------------------------- grids


def mesh_grid(inside: np.ndarray, table: np.ndarray = mc.TRI_TABLE, count: np.ndarray = mc.TRI_COUNT):
    """Assemble the global mesh of a boolean node grid; vertices at edge midpoints."""
    nx, ny, nz = inside.shape
    cells = np.stack(np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), np.arange(nz - 1), indexing="ij"), -1)
    cells = cells.reshape(-1, 3)
    config = np.zeros(len(cells), dtype=np.int64)
    for c in range(8):
        node = cells + mc.CORNERS[c]
        config |= inside[node[:, 0], node[:, 1], node[:, 2]].astype(np.int64) << c
    tri_cell = np.repeat(np.arange(len(cells)), count[config])
    tri_edges = np.concatenate([table[c, : count[c]] for c in config] + [np.zeros((0, 3), np.int32)])
    node = cells[tri_cell][:, None, :] + mc.EDGE_ORIGIN[tri_edges][..., :3]  # (T, 3, 3)
    node_id = (node[..., 0] * ny + node[..., 1]) * nz + node[..., 2]
    keys = node_id * 3 + mc.EDGE_ORIGIN[tri_edges][..., 3]
    uniq, faces = np.unique(keys, return_inverse=True)
    faces = faces.reshape(-1, 3)
    nid, axis = np.divmod(uniq, 3)
    pts = np.stack([nid // (ny * nz), (nid // nz) % ny, nid % nz], -1).astype(np.float64)
    pts[np.arange(len(uniq)), axis] += 0.5
    return pts, faces


def check_closed_oriented_manifold(pts: np.ndarray, faces: np.ndarray) -> int:
    """Assert the mesh is a closed, consistently oriented 2-manifold; return chi."""
    f = faces.tolist()
    assert all(len(set(t)) == 3 for t in f), "degenerate triangle"
    assert len({tuple(sorted(t)) for t in f}) == len(f), "duplicate triangle"
    directed = [(t[k], t[(k + 1) % 3]) for t in f for k in range(3)]
    directed_set = set(directed)
    assert len(directed_set) == len(directed), "directed edge used twice (orientation)"
    assert all((b, a) in directed_set for a, b in directed), "boundary edge (hole)"
    # every undirected edge: exactly the two opposite directed edges
    link = {}
    for t in f:
        for k in range(3):
            link.setdefault(t[k], {})[t[(k + 1) % 3]] = t[(k + 2) % 3]
    for v, nxt in link.items():  # the link of v is a single cycle
        start = next(iter(nxt))
        u, n = nxt[start], 1
        while u != start:
            u, n = nxt[u], n + 1
            assert n <= len(nxt)
        assert n == len(nxt), f"vertex {v} is not a manifold vertex"
    assert len(link) == len(pts), "unreferenced vertex"
    n_edges = len(directed) // 2
    return len(pts) - n_edges + len(f)


def signed_volume(pts: np.ndarray, faces: np.ndarray) -> float:
    p = pts[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def random_grids():
    rng = np.random.default_rng(2024)
    shape = (5, 5, 5)
    idx = np.indices(shape).sum(0)
    for density in (0.2, 0.35, 0.5, 0.65, 0.8):
        for _ in range(40):
            yield rng.random(shape) < density
    for parity in (0, 1):
        checker = idx % 2 == parity
        yield checker
        for _ in range(20):
            yield checker ^ (rng.random(shape) < 0.15)
    for _ in range(10):  # larger grids
        yield rng.random((7, 6, 8)) < 0.5


def _pad_outside(inside):
    inside = inside.copy()
    inside[[0, -1]] = inside[:, [0, -1]] = inside[:, :, [0, -1]] = False
    return inside


def test_random_grids_are_closed_manifolds():
    n_nonempty = 0
    for inside in random_grids():
        inside = _pad_outside(inside)
        pts, faces = mesh_grid(inside)
        if not inside.any():
            assert len(faces) == 0
            continue
        n_nonempty += 1
        chi = check_closed_oriented_manifold(pts, faces)
        assert chi % 2 == 0
        assert signed_volume(pts, faces) > 0
    assert n_nonempty > 200


def _grid(nodes, shape=(5, 5, 5), value=True):
    g = np.full(shape, not value)
    for n in nodes:
        g[n] = value
    return _pad_outside(g)


@pytest.mark.parametrize(
    "inside, chi, volume",
    [
        # one inside node: an octahedron of volume (4/3) 0.5^3
        (_grid([(2, 2, 2)]), 2, 1.0 / 6.0),
        # a 6-connected ring of 8 nodes around an outside node: a torus
        (_grid([(i, j, 2) for i in (1, 2, 3) for j in (1, 2, 3) if (i, j) != (2, 2)]), 0, None),
        # inside nodes across a face / body diagonal are separated (rule 1): two spheres
        (_grid([(1, 1, 2), (2, 2, 2)]), 4, 2.0 / 6.0),
        (_grid([(1, 1, 1), (2, 2, 2)]), 4, 2.0 / 6.0),
        # outside nodes across a face diagonal connect: block with one (merged) cavity
        (_grid([(2, 2, 2), (3, 3, 2)], (6, 6, 6), value=False), 4, None),
        # ... but not across a body diagonal (outside is 18-connected): two cavities
        (_grid([(2, 2, 2), (3, 3, 3)], (6, 6, 6), value=False), 6, None),
    ],
)
def test_euler_characteristic(inside, chi, volume):
    pts, faces = mesh_grid(inside)
    assert check_closed_oriented_manifold(pts, faces) == chi
    vol = signed_volume(pts, faces)
    assert vol > 0
    if volume is not None:
        assert vol == pytest.approx(volume)


def test_closedness_checks_catch_broken_tables():
    """The grid checks must fail for a table that breaks rule 1 in one configuration
    (config 0b1001 joining its two inside corners across face z=0, as a complement-
    symmetric table does) and for a missing or flipped triangle."""
    inside = _grid([(1, 1, 2), (2, 2, 2)])  # cell (1, 1, 2) sees config 0b1001
    pts, faces = mesh_grid(inside)
    check_closed_oriented_manifold(pts, faces)
    table, count = mc.TRI_TABLE.copy(), mc.TRI_COUNT.copy()
    joined = mc.TRI_TABLE[0xFF ^ 0b1001, : mc.TRI_COUNT[0xFF ^ 0b1001], ::-1]
    table[0b1001] = -1
    table[0b1001, : len(joined)] = joined
    count[0b1001] = len(joined)
    assert crossing_edges(0b1001) == set(joined.ravel().tolist())
    with pytest.raises(AssertionError, match="hole"):
        check_closed_oriented_manifold(*mesh_grid(inside, table, count))
    with pytest.raises(AssertionError, match="hole"):
        check_closed_oriented_manifold(pts, faces[:-1])
    with pytest.raises(AssertionError, match="orientation"):
        check_closed_oriented_manifold(pts, np.concatenate([faces[:-1], faces[-1:, ::-1]]))
