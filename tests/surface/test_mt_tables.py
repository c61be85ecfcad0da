"""Tests of the marching-tetrahedra tables (kernels/mt_tables.py) and of the exact
topology oracle of the piecewise-linear interpolant (tests/pl_oracle.py)."""

from __future__ import annotations

import itertools
from collections import Counter

import numpy as np
import pytest
from tests.helpers.meshcheck import check_mesh
from tests.helpers.pl_oracle import (
    KUHN_CHAINS,
    KUHN_STRUCTURE,
    kuhn_components,
    kuhn_euler,
    kuhn_label,
    kuhn_simplex_counts,
    kuhn_surface_euler,
)
from scipy.spatial import ConvexHull

from warpmesh.kernels import mc_tables as mc
from warpmesh.kernels import mt_tables as mt

CORNERS_F = mc.CORNERS.astype(np.float64)
ALL_CONFIGS = range(256)
#: frozenset of corners -> tetrahedron index
TET_OF = {frozenset(tet.tolist()): t for t, tet in enumerate(mt.TETS)}
#: number of tetrahedra holding each mt edge
TETS_PER_EDGE = np.bincount(mt.TET_MT_EDGES.ravel(), minlength=19)


def inside_mask(config: int) -> np.ndarray:
    return np.array([(config >> c) & 1 for c in range(8)], dtype=bool)


def crossing_edges(config: int) -> set[int]:
    ins = inside_mask(config)
    return {e for e, (a, b) in enumerate(mt.MT_EDGES) if ins[a] != ins[b]}


def tris_of(config: int) -> list[list[int]]:
    return mt.MT_TRIS[config, : mt.MT_TRI_COUNT[config]].tolist()


def quads_of(config: int) -> list[list[int]]:
    return mt.MT_QUADS[config, : mt.MT_QUAD_COUNT[config]].tolist()


def split_cell(config: int, choice) -> list[list[int]]:
    """Triangles of a cell, quad ``q`` split by ``QUAD_SPLITS[choice[q]]``."""
    out = tris_of(config)
    for q, quad in enumerate(quads_of(config)):
        out += [[quad[k] for k in tri] for tri in mt.QUAD_SPLITS[choice[q]].tolist()]
    return out


def split_choices(config: int, rng):
    n = mt.MT_QUAD_COUNT[config]
    yield [0] * n
    yield [1] * n
    for _ in range(2 if n else 0):
        yield rng.integers(0, 2, n).tolist()


def tet_of_polygon(poly) -> int:
    return TET_OF[frozenset(mt.MT_EDGES[poly].ravel().tolist())]


def face_triangles(face) -> list[tuple[int, int, int]]:
    """The two triangles of a cube face (corners counter-clockwise seen from outside the
    cube), split by the diagonal from its minimum to its maximum corner."""
    k = face.index(min(face))
    q = face[k:] + face[:k]
    assert q[2] == max(face)
    return [(q[0], q[1], q[2]), (q[2], q[3], q[0])]


def triangle_segment(config: int, tri) -> list[tuple[int, int]]:
    """The oriented boundary segment a cube-face triangle produces on its own: walking its
    corners counter-clockwise seen from outside, from the crossing entering the inside
    to the crossing leaving it (the mc_tables rule)."""
    ins = inside_mask(config)
    crossings = [(mt.MT_EDGE_OF[tri[k], tri[(k + 1) % 3]], ins[tri[k]]) for k in range(3)
                 if ins[tri[k]] != ins[tri[(k + 1) % 3]]]
    if not crossings:
        return []
    (e0, in0), (e1, _) = crossings
    return [(e0, e1)] if not in0 else [(e1, e0)]


FACE_SEGMENT = {}  # (config, face index) -> expected boundary segments on that face
for _c in ALL_CONFIGS:
    for _f, _face in enumerate(mc.FACES):
        FACE_SEGMENT[_c, _f] = {s for tri in face_triangles(list(_face)) for s in triangle_segment(_c, tri)}


def face_of_segment(a: int, b: int) -> int | None:
    """The cube face holding both mt edges, if any."""
    corners = set(mt.MT_EDGES[[a, b]].ravel().tolist())
    for f, face in enumerate(mc.FACES):
        if corners <= set(face):
            return f
    return None


# ----------------------------------------------------------------------------- layout


def test_shapes_and_dtypes():
    expected = {
        "EDGE_TYPE_DELTA": (7, 3),
        "MT_EDGES": (19, 2),
        "MT_EDGE_ORIGIN": (19, 4),
        "TETS": (6, 4),
        "TET_EDGES": (6, 2),
        "TET_MT_EDGES": (6, 6),
        "CANONICAL_TET": (4, 3),
        "TET_POLY_SIZE": (16,),
        "TET_POLYGONS": (16, 4),
        "MT_TRI_COUNT": (256,),
        "MT_TRIS": (256, mt.MAX_MT_TRIS, 3),
        "MT_QUAD_COUNT": (256,),
        "MT_QUADS": (256, mt.MAX_MT_QUADS, 4),
        "QUAD_SPLITS": (2, 2, 3),
    }
    for name, shape in expected.items():
        arr = getattr(mt, name)
        assert arr.shape == shape, name
        assert arr.dtype == np.int32, name
        assert arr.flags["C_CONTIGUOUS"], name
    assert isinstance(mt.MAX_MT_TRIS, int) and isinstance(mt.MAX_MT_QUADS, int)
    assert mt.MAX_MT_TRIS == mt.MT_TRI_COUNT.max() == 6  # corner 0 alone: one per tet
    assert mt.MAX_MT_QUADS == mt.MT_QUAD_COUNT.max() == 6  # corners 0 and 7 alone
    assert (mt.MT_TRI_COUNT + mt.MT_QUAD_COUNT).max() == 6  # at most one polygon per tet
    for c in ALL_CONFIGS:
        nt, nq = mt.MT_TRI_COUNT[c], mt.MT_QUAD_COUNT[c]
        assert np.all(mt.MT_TRIS[c, nt:] == -1) and np.all(mt.MT_QUADS[c, nq:] == -1), c
        assert np.all((mt.MT_TRIS[c, :nt] >= 0) & (mt.MT_TRIS[c, :nt] < 19)), c
        assert np.all((mt.MT_QUADS[c, :nq] >= 0) & (mt.MT_QUADS[c, :nq] < 19)), c
    for c in range(16):
        k = mt.TET_POLY_SIZE[c]
        assert np.all(mt.TET_POLYGONS[c, k:] == -1) and np.all(mt.TET_POLYGONS[c, :k] >= 0)


def test_mt_edge_conventions():
    assert mt.MT_EDGES[:12].tolist() == mc.EDGES.tolist()  # cube edges: mc numbering
    assert mt.MT_EDGE_ORIGIN[:12].tolist() == mc.EDGE_ORIGIN.tolist()  # type == mc axis
    assert mt.MT_EDGES[12:].tolist() == [[0, 3], [4, 7], [0, 5], [2, 7], [0, 6], [1, 7], [0, 7]]
    assert mt.EDGE_TYPE_DELTA.tolist() == [
        [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], [1, 1, 1]]
    assert mt.MT_EDGE_ORIGIN[12:, 3].tolist() == [3, 3, 4, 4, 5, 5, 6]
    for e, (a, b) in enumerate(mt.MT_EDGES.tolist()):
        dx, dy, dz, typ = mt.MT_EDGE_ORIGIN[e].tolist()
        assert [dx, dy, dz] == mc.CORNERS[a].tolist()  # a is the lower corner
        assert (mc.CORNERS[b] - mc.CORNERS[a]).tolist() == mt.EDGE_TYPE_DELTA[typ].tolist()
        assert mt.MT_EDGE_OF[a, b] == mt.MT_EDGE_OF[b, a] == e
    # the face diagonals run from each face's minimum corner to its maximum corner
    diagonals = {(min(f), max(f)) for f in mc.FACES}
    assert {tuple(e) for e in mt.MT_EDGES[12:18].tolist()} == diagonals
    assert len({tuple(e) for e in mt.MT_EDGES.tolist()}) == 19


def test_kuhn_tetrahedra():
    volumes = []
    for t, tet in enumerate(mt.TETS.tolist()):
        p = CORNERS_F[tet]
        volumes.append(np.linalg.det(p[1:] - p[0]) / 6.0)
        assert volumes[-1] > 0, t
        a, b, _ = list(itertools.permutations(range(3)))[t]
        assert set(tet) == {0, 1 << a, (1 << a) | (1 << b), 7}
        assert tet[0] == 0 and tet[3] == 7
        assert mt.TET_MT_EDGES[t].tolist() == [mt.MT_EDGE_OF[tet[i], tet[j]] for i, j in mt.TET_EDGES]
    assert np.allclose(volumes, 1.0 / 6.0)
    q = mt.CANONICAL_TET.astype(float)  # so the affine maps canonical -> tet keep orientation
    assert np.linalg.det(q[1:] - q[0]) > 0
    # the tets tile the cube: random points lie in exactly one of them
    pts = np.random.default_rng(7).random((2000, 3))
    hits = np.zeros(len(pts), dtype=int)
    for tet in mt.TETS.tolist():
        p = CORNERS_F[tet]
        bary = np.linalg.solve((p[1:] - p[0]).T, (pts - p[0]).T).T
        hits += (bary.min(axis=1) > 0) & (bary.sum(axis=1) < 1)
    assert np.all(hits == 1)
    # every mt edge is a tet edge; each cube face is split by its min-max diagonal
    assert set(mt.TET_MT_EDGES.ravel().tolist()) == set(range(19))
    assert TETS_PER_EDGE[18] == 6 and np.all(TETS_PER_EDGE[12:18] == 2)
    faces = Counter(frozenset(f) for tet in mt.TETS.tolist() for f in itertools.combinations(tet, 3))
    boundary = [f for f, n in faces.items() if n == 1]
    assert sorted(faces.values()) == [1] * 12 + [2] * 6  # 6 inner faces, each shared by 2 tets
    for face in mc.FACES:
        on_face = [f for f in boundary if f <= set(face)]
        assert len(on_face) == 2 and all({min(face), max(face)} <= f for f in on_face), face


# ----------------------------------------------------------------------------- canonical tet


def test_canonical_configurations():
    for c in range(16):
        n_in = bin(c).count("1")
        assert mt.TET_POLY_SIZE[c] == {0: 0, 1: 3, 2: 4, 3: 3, 4: 0}[n_in], c
        poly = mt.TET_POLYGONS[c, : mt.TET_POLY_SIZE[c]].tolist()
        assert poly == mt.canonical_polygon(c)
        crossing = {k for k, (a, b) in enumerate(mt.TET_EDGES.tolist()) if (c >> a & 1) != (c >> b & 1)}
        assert sorted(poly) == sorted(crossing), c
        for k in range(len(poly)):  # consecutive vertices lie on a common face
            assert len(set(mt.TET_EDGES[[poly[k], poly[(k + 1) % len(poly)]]].ravel().tolist())) == 3
    with pytest.raises(ValueError, match="0..15"):
        mt.canonical_polygon(16)


def linear_gradient(p: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Gradient of the linear function with values f at the 4 vertices p (4, 3)."""
    return np.linalg.solve(p[1:] - p[0], f[1:] - f[0])


def assert_normal_along_minus_gradient(p: np.ndarray, tris, grad: np.ndarray, what):
    for tri in tris:
        n = np.cross(p[tri[1]] - p[tri[0]], p[tri[2]] - p[tri[0]])
        scale = np.linalg.norm(n) * np.linalg.norm(grad)
        assert n @ grad < 0, what  # towards decreasing f: the outside
        assert np.linalg.norm(np.cross(n, grad)) <= 1e-9 * scale, what  # flat, f = 0 plane


def test_canonical_orientation_follows_the_gradient():
    """With vertices at the zero crossings of the linear interpolant, each polygon lies in
    the plane f = 0 and its normal points along -grad f (outside), for both quad splits."""
    rng = np.random.default_rng(3)
    p = mt.CANONICAL_TET.astype(np.float64)
    for _ in range(50):
        for c in range(1, 15):
            sign = np.array([1.0 if c >> k & 1 else -1.0 for k in range(4)])
            f = sign * rng.uniform(0.01, 1.0, 4)
            a, b = mt.TET_EDGES.T
            t = f[a] / (f[a] - f[b])
            pts = p[a] + t[:, None] * (p[b] - p[a])
            poly = mt.TET_POLYGONS[c, : mt.TET_POLY_SIZE[c]]
            tris = [poly] if len(poly) == 3 else [poly[s] for split in mt.QUAD_SPLITS for s in split]
            assert_normal_along_minus_gradient(pts, tris, linear_gradient(p, f), c)


# ----------------------------------------------------------------------------- cube tables


def test_tables_map_the_canonical_polygons():
    for c in ALL_CONFIGS:
        expected = []
        for t in range(6):
            tc = mt.tet_config(c, t)
            assert tc == sum(int(inside_mask(c)[corner]) << k for k, corner in enumerate(mt.TETS[t]))
            expected.append([int(mt.TET_MT_EDGES[t, k]) for k in mt.canonical_polygon(tc)])
        expected = [p for p in expected if p]
        assert mt.cell_polygons(c) == expected
        assert tris_of(c) == [p for p in expected if len(p) == 3]
        assert quads_of(c) == [p for p in expected if len(p) == 4]
        for poly in tris_of(c) + quads_of(c):
            tet_of_polygon(poly)  # every polygon lies in one tet


def test_every_crossing_edge_used_once_per_tet():
    for c in ALL_CONFIGS:
        used = Counter(e for poly in tris_of(c) + quads_of(c) for e in poly)
        crossing = crossing_edges(c)
        assert set(used) == crossing, c
        for e, n in used.items():  # each tet holding a crossing edge uses it once
            assert n == TETS_PER_EDGE[e], (c, e)
        for poly in tris_of(c) + quads_of(c):
            assert len(set(poly)) == len(poly), (c, poly)


def test_inner_faces_match_between_tets():
    """A polygon side inside the cube lies on a face shared by two tets, and the
    neighbouring tet's polygon has the same side reversed."""
    for c in ALL_CONFIGS:
        sides = {}
        for poly in tris_of(c) + quads_of(c):
            t = tet_of_polygon(poly)
            for k in range(len(poly)):
                side = (poly[k], poly[(k + 1) % len(poly)])
                assert side not in sides, (c, side)
                sides[side] = t
        for (a, b), t in sides.items():
            if face_of_segment(a, b) is not None:
                continue
            assert (b, a) in sides, (c, a, b)
            t2 = sides[b, a]
            shared = set(mt.TETS[t].tolist()) & set(mt.TETS[t2].tolist())
            assert t2 != t and len(shared) == 3, (c, a, b)
            assert set(mt.MT_EDGES[[a, b]].ravel().tolist()) <= shared, (c, a, b)


def check_patch(tris) -> set[tuple[int, int]]:
    """Assert oriented triangles form an oriented 2-manifold with boundary; return the
    directed boundary edges."""
    directed = [(t[k], t[(k + 1) % 3]) for t in tris for k in range(3)]
    dset = set(directed)
    assert len(dset) == len(directed), "directed edge used twice (orientation)"
    assert all(len(set(t)) == 3 for t in tris), "degenerate triangle"
    assert len({frozenset(t) for t in tris}) == len(tris), "duplicate triangle"
    link = {}
    for t in tris:
        for k in range(3):
            link.setdefault(t[k], {})[t[(k + 1) % 3]] = t[(k + 2) % 3]
    for v, nxt in link.items():  # link of v: one path (boundary vertex) or one cycle
        starts = set(nxt) - set(nxt.values())
        assert len(starts) <= 1, f"vertex {v}: link in several pieces"
        u, n = next(iter(starts)) if starts else next(iter(nxt)), 0
        first = u
        while u in nxt and n <= len(nxt):
            u, n = nxt[u], n + 1
            if u == first:
                break
        assert n == len(nxt), f"vertex {v}: link in several pieces"
    return {(a, b) for a, b in dset if (b, a) not in dset}


def test_cells_are_oriented_manifolds_bounded_on_the_faces():
    """For both quad splits (and random mixes): the cell's triangles form an oriented
    2-manifold with boundary; its boundary is on the cube faces and equals, face by face,
    what the face's two triangles produce on their own (so neighbours agree)."""
    rng = np.random.default_rng(11)
    for c in ALL_CONFIGS:
        expected = set().union(*(FACE_SEGMENT[c, f] for f in range(6)))
        for choice in split_choices(c, rng):
            boundary = check_patch(split_cell(c, choice))
            assert boundary == expected, (c, choice)
            for a, b in boundary:
                assert (a, b) in FACE_SEGMENT[c, face_of_segment(a, b)], (c, a, b)
        # boundary segments chain into closed loops
        nxt = dict(expected)
        assert len(nxt) == len(expected) and set(nxt) == set(nxt.values()), c


def test_opposite_faces_give_reversed_segments():
    """Cell faces x_a = 1 and the neighbour's x_a = 0 see the same nodes: with equal signs
    there, they produce the same segments (translated), in opposite directions."""
    for axis in range(3):
        f_lo = next(f for f, face in enumerate(mc.FACES) if all(not c >> axis & 1 for c in face))
        f_hi = next(f for f, face in enumerate(mc.FACES) if all(c >> axis & 1 for c in face))
        shift = {}  # mt edge on the high face -> the same grid edge as seen from the next cell
        for e in range(19):
            a, b = mt.MT_EDGES[e].tolist()
            if a >> axis & 1 and b >> axis & 1:
                shift[e] = mt.MT_EDGE_OF[a ^ (1 << axis), b ^ (1 << axis)]
                assert mt.MT_EDGE_ORIGIN[shift[e], 3] == mt.MT_EDGE_ORIGIN[e, 3]
        for c in ALL_CONFIGS:
            lo = 0
            for corner in range(8):
                if corner >> axis & 1 and c >> corner & 1:
                    lo |= 1 << (corner ^ (1 << axis))
            hi_segments = {(shift[a], shift[b]) for a, b in FACE_SEGMENT[c, f_hi]}
            assert hi_segments == {(b, a) for a, b in FACE_SEGMENT[lo, f_lo]}, (axis, c)


def test_orientation_with_arbitrary_edge_positions():
    """Local criterion (as for mc_tables): each triangle's normal has a positive component
    along inside -> outside of every edge carrying one of its vertices, wherever the
    vertices sit on their edges (root finding need not agree with linear interpolation),
    for both quad splits."""
    a, b = mt.MT_EDGES[:, 0], mt.MT_EDGES[:, 1]
    rng = np.random.default_rng(12345)
    positions = [np.full(19, 0.5)] + [rng.uniform(0.001, 0.999, 19) for _ in range(60)]
    positions += [rng.choice([0.001, 0.999], 19) for _ in range(20)]
    cells = {}
    for c in ALL_CONFIGS:
        ins = inside_mask(c)
        direction = np.where(ins[a][:, None], CORNERS_F[b] - CORNERS_F[a], CORNERS_F[a] - CORNERS_F[b])
        tris = np.array(split_cell(c, [0] * 6) + split_cell(c, [1] * 6), dtype=int).reshape(-1, 3)
        cells[c] = (tris, direction)
    for t in positions:
        p = CORNERS_F[a] * (1.0 - t[:, None]) + CORNERS_F[b] * t[:, None]
        for c, (tris, direction) in cells.items():
            if len(tris) == 0:
                continue
            n = np.cross(p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]])
            assert np.all(np.einsum("tj,tkj->tk", n, direction[tris]) > 0), c


def test_cell_orientation_follows_the_gradient():
    rng = np.random.default_rng(5)
    a, b = mt.MT_EDGES[:, 0], mt.MT_EDGES[:, 1]
    for _ in range(4):
        for c in range(1, 255):
            f = np.where(inside_mask(c), 1.0, -1.0) * rng.uniform(0.01, 1.0, 8)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = f[a] / (f[a] - f[b])
            pts = CORNERS_F[a] + t[:, None] * (CORNERS_F[b] - CORNERS_F[a])
            for poly in tris_of(c) + quads_of(c):
                tet = mt.TETS[tet_of_polygon(poly)]
                grad = linear_gradient(CORNERS_F[tet], f[tet])
                tris = [poly] if len(poly) == 3 else [[poly[k] for k in s] for sp in mt.QUAD_SPLITS for s in sp]
                assert_normal_along_minus_gradient(pts, tris, grad, (c, poly))


# ----------------------------------------------------------------------------- split_quad


def _min_angle(p: np.ndarray, tris) -> float:
    out = np.inf
    for tri in tris:
        for k in range(3):
            u, v = p[tri[(k + 1) % 3]] - p[tri[k]], p[tri[(k + 2) % 3]] - p[tri[k]]
            out = min(out, np.arccos(np.clip(u @ v / np.linalg.norm(u) / np.linalg.norm(v), -1, 1)))
    return out


def test_split_quad_known_answers():
    rhombus = np.array([[-2.0, 0.0, 0.0], [0.0, -1.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    assert mt.split_quad(rhombus).tolist() == [[0, 1, 3], [1, 2, 3]]  # short diagonal 1-3
    assert mt.split_quad(np.roll(rhombus, 1, axis=0)).tolist() == [[0, 1, 2], [0, 2, 3]]
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert mt.split_quad(square).tolist() == mt.QUAD_SPLITS[0].tolist()  # tie: diagonal 0-2
    assert mt.split_quad(square).dtype == np.int32
    for bad in (np.zeros((3, 3)), np.zeros(4)):
        with pytest.raises(ValueError, match=r"\(\.\.\., 4, d\)"):
            mt.split_quad(bad)


def test_split_quad_maximises_the_minimum_angle():
    rng = np.random.default_rng(9)
    # planar convex quads: the zero set of a random linear function in the canonical tet
    quads = []
    while len(quads) < 300:
        f = rng.normal(size=4)
        c = sum(1 << k for k in range(4) if f[k] > 0)
        if mt.TET_POLY_SIZE[c] != 4:
            continue
        p = mt.CANONICAL_TET.astype(float)
        a, b = mt.TET_EDGES.T
        t = f[a] / (f[a] - f[b])
        quads.append((p[a] + t[:, None] * (p[b] - p[a]))[mt.TET_POLYGONS[c]])
    quads = np.array(quads + list(rng.normal(size=(100, 4, 3))))  # and skew ones
    splits = mt.split_quad(quads)
    assert splits.shape == (len(quads), 2, 3)
    assert np.array_equal(mt.split_quad(quads.reshape(10, -1, 4, 3)).reshape(-1, 2, 3), splits)
    for q, s in zip(quads, splits):
        other = mt.QUAD_SPLITS[1 - int(s[0].tolist() == mt.QUAD_SPLITS[1, 0].tolist())]
        assert _min_angle(q, s) >= _min_angle(q, other) - 1e-12
    for q, s in zip(quads[:300], splits[:300]):  # same winding as the (planar) quad
        newell = np.cross(q, np.roll(q, -1, axis=0)).sum(axis=0)
        for tri in q[s]:
            assert np.cross(tri[1] - tri[0], tri[2] - tri[0]) @ newell > 0


def test_split_quad_degenerate_points():
    quad = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    with np.errstate(all="raise"):
        assert mt.split_quad(quad).tolist() in mt.QUAD_SPLITS.tolist()
        assert mt.split_quad(np.zeros((4, 3))).tolist() == mt.QUAD_SPLITS[0].tolist()


# ----------------------------------------------------------------------------- grids


def mesh_values(values: np.ndarray, split=None):
    """Global mesh of a node grid: shared vertices at the linear zero crossings, quads
    split by ``split_quad`` (``split=None``) or all by ``QUAD_SPLITS[split]``."""
    shape = values.shape
    cells = np.indices(np.array(shape) - 1).reshape(3, -1).T
    config = np.zeros(len(cells), dtype=np.int64)
    for c in range(8):
        node = cells + mc.CORNERS[c]
        config |= (values[node[:, 0], node[:, 1], node[:, 2]] > 0).astype(np.int64) << c

    def gather(count, table):
        n = count[config]
        cell = np.repeat(np.arange(len(cells)), n)
        slot = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
        ids = table[config[cell], slot]
        node = cells[cell][:, None, :] + mt.MT_EDGE_ORIGIN[ids][..., :3]
        return np.ravel_multi_index(tuple(np.moveaxis(node, -1, 0)), shape) * 7 + mt.MT_EDGE_ORIGIN[ids][..., 3]

    tri_keys, quad_keys = gather(mt.MT_TRI_COUNT, mt.MT_TRIS), gather(mt.MT_QUAD_COUNT, mt.MT_QUADS)
    uniq, inv = np.unique(np.concatenate([tri_keys.ravel(), quad_keys.ravel()]), return_inverse=True)
    inv = inv.ravel()
    nid, typ = np.divmod(uniq, 7)
    lo = np.stack(np.unravel_index(nid, shape), -1)
    step = mt.EDGE_TYPE_DELTA[typ]
    hi = lo + step
    fa, fb = values[tuple(lo.T)], values[tuple(hi.T)]
    pts = lo + (fa / (fa - fb))[:, None] * step
    tris = inv[: tri_keys.size].reshape(-1, 3)
    quads = inv[tri_keys.size :].reshape(-1, 4)
    local = mt.split_quad(pts[quads]) if split is None else np.broadcast_to(mt.QUAD_SPLITS[split], (len(quads), 2, 3))
    quad_tris = quads[np.arange(len(quads))[:, None, None], local].reshape(-1, 3)
    return pts, np.concatenate([tris, quad_tris])


def signed_volume(pts: np.ndarray, faces: np.ndarray) -> float:
    p = pts[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def pl_volume(values: np.ndarray) -> float:
    """Exact volume of {f > 0} for the linear interpolant on the Kuhn tets (convex hulls)."""
    cells = np.indices(np.array(values.shape) - 1).reshape(3, -1).T
    total = 0.0
    for tet in mt.TETS:
        node = cells[:, None, :] + mc.CORNERS[tet]  # (cells, 4, 3)
        f = values[node[..., 0], node[..., 1], node[..., 2]]
        n_in = (f > 0).sum(axis=1)
        total += np.count_nonzero(n_in == 4) / 6.0
        for p, fv in zip(node[(n_in > 0) & (n_in < 4)].astype(float), f[(n_in > 0) & (n_in < 4)]):
            keep = [p[i] for i in range(4) if fv[i] > 0]
            for i, j in itertools.combinations(range(4), 2):
                if (fv[i] > 0) != (fv[j] > 0):
                    keep.append(p[i] + fv[i] / (fv[i] - fv[j]) * (p[j] - p[i]))
            total += ConvexHull(np.array(keep)).volume
    return total


def pad_outside(values: np.ndarray) -> np.ndarray:
    v = values.copy()
    for axis in range(3):
        idx = [slice(None)] * 3
        for end in (0, -1):
            idx[axis] = end
            v[tuple(idx)] = -np.abs(v[tuple(idx)]) - 0.1
    return v


def surface_components(faces: np.ndarray) -> int:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    n = faces.max() + 1
    return connected_components(coo_matrix((np.ones(len(e)), tuple(e.T)), shape=(n, n)))[0]


def random_fields():
    rng = np.random.default_rng(2025)
    for _ in range(20):
        yield rng.normal(size=(7, 7, 7)) + rng.uniform(-0.5, 0.5)
    for _ in range(10):  # mostly inside: cavities
        yield rng.normal(size=(7, 7, 7)) + rng.uniform(0.8, 1.5)
    checker = np.where(np.indices((7, 7, 7)).sum(0) % 2 == 0, 1.0, -1.0)
    for k in range(10):  # checkerboard signs (every cell at its most ambiguous), a few flipped
        flip = np.where(rng.random((7, 7, 7)) < 0.1 * (k % 3), -1.0, 1.0)
        yield checker * flip * rng.uniform(0.05, 1.0, (7, 7, 7))
    x = np.indices((14, 14, 14)).astype(float)
    for _ in range(5):  # smooth blobs with handles and cavities
        f = -0.35 + sum(np.exp(-((x - rng.uniform(2, 12, (3, 1, 1, 1))) ** 2).sum(0) / rng.uniform(2, 8))
                        for _ in range(12))
        yield f + 0.05 * np.sin(x[0] * 1.7 + x[1] * 2.3)


def test_random_fields_give_closed_oriented_surfaces_with_oracle_topology():
    n = 0
    for values in random_fields():
        values = pad_outside(values)
        inside = values > 0
        if not inside.any():
            continue
        n += 1
        pts, faces = mesh_values(values)
        stats = check_mesh(pts, faces, closed=True, oriented=True)
        chi = stats["n_points"] - stats["n_edges"] + stats["n_faces"]
        assert chi == kuhn_surface_euler(inside)
        # one surface per pair of adjacent regions (inside components + outside ones - 1)
        assert surface_components(faces) == kuhn_components(inside) + kuhn_components(~inside) - 1
        # outward: the enclosed volume is exactly that of the PL region, with either split
        exact = pl_volume(values)
        assert signed_volume(pts, faces) == pytest.approx(exact, rel=1e-9, abs=1e-12)
        for split in (0, 1):
            assert signed_volume(*mesh_values(values, split)) == pytest.approx(exact, rel=1e-9, abs=1e-12)
    assert n >= 40


def test_single_inside_node_is_an_octahedron_like_closed_surface():
    values = np.full((3, 3, 3), -1.0)
    values[1, 1, 1] = 1.0
    pts, faces = mesh_values(values)
    check_mesh(pts, faces)
    # 14 Kuhn neighbours -> 14 vertices at the edge midpoints; 24 tets hold the node,
    # one triangle each; a sphere (14 - 36 + 24 = 2) of volume 24 * (1/6) / 8
    assert len(pts) == 14 and len(faces) == 24
    assert signed_volume(pts, faces) == pytest.approx(pl_volume(values)) == pytest.approx(24 / 6 / 8)


def test_checks_catch_broken_tables():
    values = pad_outside(np.random.default_rng(1).normal(size=(6, 6, 6)))
    pts, faces = mesh_values(values)
    check_mesh(pts, faces)
    with pytest.raises(AssertionError, match="orientation"):
        check_mesh(pts, np.concatenate([faces[:-1], faces[-1:, ::-1]]))
    with pytest.raises(AssertionError, match="not closed"):
        check_mesh(pts, faces[:-1])


# ----------------------------------------------------------------------------- oracle


def brute_force_counts(inside: np.ndarray) -> tuple[int, ...]:
    """(V, E, F, T) by listing every Kuhn tet of every cell and all their faces."""
    simplices = [set() for _ in range(4)]
    for cell in itertools.product(*(range(n - 1) for n in inside.shape)):
        for tet in mt.TETS.tolist():
            nodes = [tuple(np.add(cell, mc.CORNERS[c]).tolist()) for c in tet]
            for k in range(4):
                for s in itertools.combinations(nodes, k + 1):
                    if all(inside[v] for v in s):
                        simplices[k].add(frozenset(s))
    return tuple(len(s) for s in simplices)


def test_oracle_counts_match_the_kuhn_tetrahedra():
    assert [len(c) for c in KUHN_CHAINS] == [1, 7, 12, 6]
    # the chain types of the oracle are the Kuhn tets of mt_tables
    tets = {frozenset(int(np.dot(s, [1, 2, 4])) for s in chain) for chain in KUHN_CHAINS[3]}
    assert tets == {frozenset(t) for t in mt.TETS.tolist()}
    edges = {tuple(chain[1]) for chain in KUHN_CHAINS[1]}
    assert edges == {tuple(d) for d in mt.EDGE_TYPE_DELTA.tolist()}
    assert KUHN_STRUCTURE.sum() == 15 and np.array_equal(KUHN_STRUCTURE, KUHN_STRUCTURE[::-1, ::-1, ::-1])
    rng = np.random.default_rng(4)
    for shape in ((2, 2, 2), (3, 4, 3), (4, 4, 4), (2, 5, 2)):
        for density in (0.3, 0.6, 0.9, 1.0):
            inside = rng.random(shape) < density
            assert kuhn_simplex_counts(inside) == brute_force_counts(inside)
    n = 5
    assert kuhn_simplex_counts(np.ones((n, n, n), bool))[3] == 6 * (n - 1) ** 3
    assert kuhn_simplex_counts(np.ones((1, 3, 3), bool)) == (9, 16, 8, 0)  # a flat layer
    assert kuhn_euler(np.ones((n, n, n), bool)) == 1


def _box(shape, boxes, value=True):
    m = np.full(shape, not value)
    for lo, hi in boxes:
        m[lo[0] : hi[0], lo[1] : hi[1], lo[2] : hi[2]] = value
    return m


def _sampled(f, n=24):
    x = np.linspace(-1.0, 1.0, n)
    return f(x[:, None, None], x[None, :, None], x[None, None, :]) > 0


def _torus(x, y, z):
    return 0.25 - np.sqrt((np.sqrt(x * x + y * y) - 0.55) ** 2 + z * z)


def _shell(x, y, z):
    r = np.sqrt(x * x + y * y + z * z)
    return np.minimum(0.8 - r, r - 0.45)


def _ring(shape=(5, 5, 5)):
    m = np.zeros(shape, bool)
    m[1:4, 1:4, 2] = True
    m[2, 2, 2] = False
    return m


@pytest.mark.parametrize(
    "inside, chi, components",
    [
        (_box((3, 3, 3), [((1, 1, 1), (2, 2, 2))]), 1, 1),  # a single node
        (_box((6, 6, 6), [((1, 1, 1), (5, 5, 5))]), 1, 1),  # a solid block
        # a hollow box: a block with a closed cavity of 2x2x2 nodes: chi 2 (two spheres, 4)
        (_box((6, 6, 6), [((1, 1, 1), (5, 5, 5))]) & ~_box((6, 6, 6), [((2, 2, 2), (4, 4, 4))]), 2, 1),
        (_ring(), 0, 1),  # a ring of 8 nodes around an outside node: solid torus
        (_sampled(_torus), 0, 1),
        (_sampled(_shell), 2, 1),
        # Kuhn edges join (0,0,0)-(1,1,1) but not (1,0,0)-(0,1,0)
        (_box((4, 4, 4), [((1, 1, 1), (2, 2, 2)), ((2, 2, 2), (3, 3, 3))]), 1, 1),
        (_box((4, 4, 4), [((2, 1, 1), (3, 2, 2)), ((1, 2, 1), (2, 3, 2))]), 2, 2),
    ],
)
def test_oracle_on_known_shapes(inside, chi, components):
    assert kuhn_euler(inside) == chi
    assert kuhn_surface_euler(inside) == 2 * chi
    assert kuhn_components(inside) == components
    labels, count = kuhn_label(inside)
    assert count == components and np.array_equal(labels > 0, inside)


def test_oracle_cavities_and_betti_numbers():
    """Padded masks: b0 = components, b2 = cavities (outside components - 1) and
    b1 = b0 + b2 - chi must be >= 0; the hollow box has b2 = 1, the torus b1 = 1."""
    shell = _sampled(_shell)
    assert kuhn_components(~shell) - 1 == 1
    torus = _sampled(_torus)
    assert kuhn_components(torus) + kuhn_components(~torus) - 1 - kuhn_euler(torus) == 1
    rng = np.random.default_rng(8)
    for _ in range(50):
        inside = np.zeros((8, 8, 8), bool)
        inside[1:-1, 1:-1, 1:-1] = rng.random((6, 6, 6)) < rng.uniform(0.2, 0.8)
        b0, b2 = kuhn_components(inside), kuhn_components(~inside) - 1
        assert b0 + b2 - kuhn_euler(inside) >= 0


def test_oracle_rejects_bad_masks():
    with pytest.raises(ValueError, match="3D boolean"):
        kuhn_euler(np.ones((3, 3), bool))
    with pytest.raises(ValueError, match="3D boolean"):
        kuhn_components(np.ones((3, 3, 3)))
