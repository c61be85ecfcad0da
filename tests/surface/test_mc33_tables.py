"""Tests of the marching-cubes-33 tables (kernels/mc33_tables.py).

The rows are checked combinatorially (every row a 2-manifold bounded by the decided face
segments, no triangle edge in a cube face besides them), against the plain table, for
symmetry and complementation, on whole grids (closed oriented manifolds), and cell by
cell against a topology oracle of the trilinear interpolant (tests/trilinear_oracle.py)
that samples the function and knows nothing about tables. Ties and self-intersections:
tests/surface/test_mc33_ties.py.
"""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from tests.helpers import trilinear_oracle as oracle
from tests.helpers.meshcheck import check_mesh
from scipy.optimize import linprog

from warpmesh.kernels import mc33_tables as m33
from warpmesh.kernels import mc_tables as mc

CORNERS_F = mc.CORNERS.astype(np.float64)
ALL_CONFIGS = range(256)
#: (6, 4) face corners, and each face's outward normal
FACES = [tuple(f) for f in m33.FACE_CORNERS.tolist()]
NORMALS = np.array([np.eye(3)[q // 2] * (2 * (q % 2) - 1) for q in range(6)])
#: per cube edge, the faces holding it
EDGE_FACES = [{q for q, f in enumerate(FACES) if set(mc.EDGES[e].tolist()) <= set(f)} for e in range(12)]
#: base entries whose interior test allows a merge that never occurs in sampling (see
#: test_interior_test_classes): the tests stay, exact and harmless
NEVER_MERGING = {(105, 5), (105, 23)}


def inside(config: int) -> np.ndarray:
    return np.array([(config >> c) & 1 for c in range(8)], dtype=bool)


def crossing_edges(config: int) -> set[int]:
    ins = inside(config)
    return {e for e, (a, b) in enumerate(mc.EDGES) if ins[a] != ins[b]}


def ambiguous(config: int, q: int) -> bool:
    s = inside(config)[list(FACES[q])]
    return bool(s[0] == s[2] and s[1] == s[3] and s[0] != s[1])


def valid_entries():
    """(config, bits) with bits only on ambiguous faces."""
    for c in ALL_CONFIGS:
        amb = [q for q in range(6) if ambiguous(c, q)]
        for sub in range(1 << len(amb)):
            yield c, sum(1 << amb[k] for k in range(len(amb)) if (sub >> k) & 1)


def entry_rows(c: int, b: int) -> list[int]:
    e = c * 64 + b
    n = 3 if m33.INTERIOR_TEST[e] >= 0 else 1
    return [int(m33.CASE_OFFSET[e]) + k for k in range(n)]


def row_tris(row: int) -> list[tuple[int, int, int]]:
    return [tuple(t) for t in m33.CASE_TRIS[row, : m33.CASE_TRI_COUNT[row]].tolist()]


def boundary_loops(tris) -> list[list[int]]:
    """Loops bounding a set of oriented triangles (interior edges cancel out)."""
    directed = {(t[k], t[(k + 1) % 3]) for t in tris for k in range(3)}
    nxt = {}
    for a, b in directed:
        if (b, a) not in directed:
            assert a not in nxt, "boundary vertex with two outgoing edges"
            nxt[a] = b
    return mc.chain_loops(nxt)


def components(tris) -> list[list[tuple[int, int, int]]]:
    """Triangles grouped by connected component (through shared vertices)."""
    parent = {}

    def find(x):
        while parent.setdefault(x, x) != x:
            x = parent[x]
        return x

    for t in tris:
        for v in t[1:]:
            parent[find(v)] = find(t[0])
    groups = {}
    for t in tris:
        groups.setdefault(find(t[0]), []).append(t)
    return list(groups.values())


def check_surface(tris) -> None:
    """Assert: no repeated directed edge, no degenerate triangle, every vertex a disk or
    half-disk (its fan is one chain or one cycle)."""
    directed = [(t[k], t[(k + 1) % 3]) for t in tris for k in range(3)]
    assert len(set(directed)) == len(directed), "directed edge used twice"
    assert all(len(set(t)) == 3 for t in tris), "degenerate triangle"
    fans = {}
    for t in tris:
        for k in range(3):
            fans.setdefault(t[k], {})[t[(k + 1) % 3]] = t[(k + 2) % 3]
    for v, nxt in fans.items():
        heads = [a for a in nxt if a not in set(nxt.values())]
        assert len(heads) <= 1, f"vertex {v} has several fans"
        start = heads[0] if heads else min(nxt)
        a, n = start, 0
        while a in nxt and n <= len(nxt):
            a, n = nxt[a], n + 1
            if a == start:
                break
        assert n == len(nxt), f"vertex {v} is not a manifold vertex"


def mesh_partition(config: int, tris) -> frozenset:
    """Corners grouped by the region of the cell they lie in, read off the triangles.

    Corners joined by a cube edge without a vertex share a region, so do the two
    corners of an ambiguous face left uncut by its two boundary segments, and so do the
    inside (outside) corners of the edges of all the loops of one surface component.
    """
    ins = inside(config)
    parent = list(range(8))

    def find(x):
        while parent[x] != x:
            x = parent[x]
        return x

    def join(x, y):
        parent[find(x)] = find(y)

    used = {v for t in tris for v in t}
    for e, (a, b) in enumerate(mc.EDGES.tolist()):
        if e not in used:
            assert ins[a] == ins[b]
            join(a, b)
    loops = boundary_loops(tris)
    segments = [(lp[k], lp[(k + 1) % len(lp)]) for lp in loops for k in range(len(lp))]
    for q, face in enumerate(FACES):
        on_face = [(p, r) for p, r in segments if q in EDGE_FACES[p] & EDGE_FACES[r]]
        if len(on_face) == 2:
            cut = {(set(mc.EDGES[p].tolist()) & set(mc.EDGES[r].tolist())).pop() for p, r in on_face}
            free = [x for x in face if x not in cut]
            assert len(free) == 2 and ins[free[0]] == ins[free[1]]
            join(*free)
    for comp in components(tris):
        verts = {v for t in comp for v in t}
        sides = {True: [], False: []}
        for lp in loops:
            if lp[0] in verts:
                for e in lp:
                    a, b = mc.EDGES[e].tolist()
                    sides[bool(ins[a])].append(a)
                    sides[bool(ins[b])].append(b)
        for group in sides.values():
            for x in group[1:]:
                join(group[0], x)
    groups = {}
    for x in range(8):
        groups.setdefault(find(x), set()).add(x)
    return frozenset(frozenset(g) for g in groups.values())


def random_values(config: int, rng, n: int, low: float = 0.05) -> np.ndarray:
    """(n, 8) values with the signs of ``config``, magnitudes uniform in [low, 1]."""
    sign = np.where(inside(config), 1.0, -1.0)
    return sign * rng.uniform(low, 1.0, (n, 8))


# ----------------------------------------------------------------------------- layout


def test_layout_and_dtypes():
    rows = len(m33.CASE_TRI_COUNT)
    expected = {
        "CASE_OFFSET": (16384,), "INTERIOR_TEST": (16384,), "CASE_FEASIBLE": (16384,),
        "CASE_TRI_COUNT": (rows,), "CASE_TRIS": (rows, m33.MAX33, 3), "CASE_INTERIOR": (rows,),
        "TEST_CORNERS": (6, 8), "FACE_CORNERS": (6, 4), "VERTEX_ORIGIN": (21, 4), "AMBIGUOUS_FACES": (256,),
    }  # fmt: skip
    for name, shape in expected.items():
        arr = getattr(m33, name)
        assert arr.shape == shape and arr.dtype == np.int32 and arr.flags["C_CONTIGUOUS"], name
    assert isinstance(m33.MAX33, int) and m33.MAX33 == m33.CASE_TRI_COUNT.max()
    assert m33.VERTEX_ORIGIN[:12].tolist() == mc.EDGE_ORIGIN.tolist()
    assert m33.VERTEX_ORIGIN[12].tolist() == [0, 0, 0, m33.CENTER_TYPE]
    assert m33.VERTEX_ORIGIN[13:].tolist() == [[*c, m33.CENTER_TYPE] for c in mc.CORNERS.tolist()]
    for r in range(rows):
        n = m33.CASE_TRI_COUNT[r]
        assert np.all(m33.CASE_TRIS[r, n:] == -1)
        assert np.all((m33.CASE_TRIS[r, :n] >= 0) & (m33.CASE_TRIS[r, :n] <= 20))
        used = set(m33.CASE_TRIS[r, :n].ravel().tolist())
        assert m33.CASE_INTERIOR[r] == sum(1 << (v - 12) for v in used if v >= 12)
        assert not (12 in used and used & set(range(13, 21)))  # a fan or a hub, never both
    assert set(m33.kernel_tables()) >= {"origin", "tris", "tri_count", "center", "case_offset", "interior_test",
                                        "test_corners", "face_corners"}


def test_every_valid_entry_has_rows_and_no_other_does():
    valid = set(valid_entries())
    referenced = set()
    for c, b in itertools.product(ALL_CONFIGS, range(64)):
        e = c * 64 + b
        if (c, b) in valid:
            assert m33.CASE_OFFSET[e] >= 0, (c, b)
            referenced.update(entry_rows(c, b))
        else:
            assert m33.CASE_OFFSET[e] == -1 and m33.INTERIOR_TEST[e] == -1 and not m33.CASE_FEASIBLE[e]
        assert m33.INTERIOR_TEST[e] < 6
        if m33.INTERIOR_TEST[e] >= 0:
            assert m33.CASE_FEASIBLE[e]
    assert referenced == set(range(len(m33.CASE_TRI_COUNT)))  # no unused row
    assert m33.AMBIGUOUS_FACES.tolist() == [sum(ambiguous(c, q) << q for q in range(6)) for c in ALL_CONFIGS]


def test_test_corners_are_diagonal_edges_along_the_axis():
    for k, row in enumerate(m33.TEST_CORNERS.tolist()):
        axis = k // 2
        edges = [row[2 * i: 2 * i + 2] for i in range(4)]
        for lo, hi in edges:
            assert (CORNERS_F[hi] - CORNERS_F[lo]).tolist() == np.eye(3)[axis].tolist()
        (a, _), (c, _), (b, _), (d, _) = edges
        assert np.abs(CORNERS_F[a] - CORNERS_F[c]).sum() == 2 and np.abs(CORNERS_F[b] - CORNERS_F[d]).sum() == 2
        assert {a, b, c, d} == {x for x in range(8) if not (x >> axis) & 1}
        assert ((a >> ((axis + 1) % 3)) & 1) ^ ((a >> ((axis + 2) % 3)) & 1) == k % 2  # diagonal 0: (0,0)-(1,1)


# ----------------------------------------------------------------------------- face bits


def test_face_bits_agree_with_sampled_faces():
    rng = np.random.default_rng(7)
    values = rng.uniform(-1, 1, (3000, 8))
    bits = m33.face_bits_of(values)
    checked = 0
    for v, b in zip(values, bits):
        c = m33.config_of(v)
        for q, (p0, p1, p2, p3) in enumerate(FACES):
            if not ambiguous(c, q):
                assert not (b >> q) & 1
                continue
            first = (p0, p1, p2, p3) if v[p0] > 0 else (p1, p2, p3, p0)  # inside diagonal first
            saddle = (v[first[0]] * v[first[2]] - v[first[1]] * v[first[3]]) / (v[p0] - v[p1] + v[p2] - v[p3])
            if abs(saddle) < 1e-3:
                continue
            assert (b >> q) & 1 == oracle.face_joined(v, first), (v, q)
            checked += 1
    assert checked > 2000


def _mirror(values: np.ndarray, q: int) -> np.ndarray:
    """Values of the neighbour across face q, mirrored (it shares face q's 4 values)."""
    axis = q // 2
    return values[[c ^ (1 << axis) for c in range(8)]]


def test_face_bits_are_the_same_in_both_cells_of_a_face():
    rng = np.random.default_rng(8)
    ties = np.array([[1, -1, -1, 1, -2, 2, 2, -2], [0.5, -2, -0.25, 4, -1, 1, 1, -1]], dtype=np.float64)
    values = np.concatenate([rng.uniform(-1, 1, (2000, 8)), ties,
                             rng.choice([-2.0, -1.0, -0.5, 0.5, 1.0, 2.0], (2000, 8))])  # many exact ties
    for v in values:
        bits = m33.face_bits_of(v)
        for q in range(6):
            other = m33.face_bits_of(_mirror(v, q))
            assert (bits >> q) & 1 == (other >> (q ^ 1)) & 1, (v, q)
    assert m33.face_bits_of(ties[0]) == 0  # every face a tie: inside corners separated


def _lp_feasible(c: int, b: int):
    """(feasible, integer log-magnitudes or None) of the face-bit pattern, by LP."""
    rows, rhs = [], []
    for q, (p0, p1, p2, p3) in enumerate(FACES):
        if not ambiguous(c, q):
            continue
        f = np.zeros(8)
        s = 1.0 if inside(c)[p0] else -1.0
        f[[p0, p2]], f[[p1, p3]] = s, -s
        if (b >> q) & 1:  # f.x >= 1 (strict, scale-free)
            rows.append(-f)
            rhs.append(-1.0)
        else:  # f.x <= 0
            rows.append(f)
            rhs.append(0.0)
    if not rows:
        return True, np.zeros(8)
    res = linprog(np.zeros(8), A_ub=np.array(rows), b_ub=np.array(rhs), bounds=[(-8, 8)] * 8, method="highs")
    if res.status != 0:
        return False, None
    for scale in range(1, 7):  # an integer solution: exact ties with powers of two
        x = np.round(res.x * scale)
        if np.all(np.array(rows) @ x <= np.array(rhs) * scale + 1e-9):
            return True, x
    return True, None


def test_feasible_entries_by_lp_and_witnesses():
    """CASE_FEASIBLE matches an LP, and every feasible entry is reached by values
    ``±2^k`` (exact products, so ties are exact)."""
    for c, b in valid_entries():
        ok, x = _lp_feasible(c, b)
        assert bool(m33.CASE_FEASIBLE[c * 64 + b]) == ok, (c, b)
        if ok:
            assert x is not None, (c, b)
            v = np.where(inside(c), 1.0, -1.0) * np.exp2(x)
            assert m33.config_of(v) == c and m33.face_bits_of(v) == b, (c, b)
    assert sum(not m33.CASE_FEASIBLE[c * 64 + b] for c, b in valid_entries()) > 0


def test_random_values_only_reach_feasible_entries():
    rng = np.random.default_rng(9)
    for low in (1e-3, 0.05):
        values = rng.choice([-1.0, 1.0], (200000, 8)) * np.exp(rng.uniform(np.log(low), 0, (200000, 8)))
        entries = m33.config_of(values) * 64 + m33.face_bits_of(values)
        assert np.all(m33.CASE_FEASIBLE[entries] == 1)


# ----------------------------------------------------------------------------- rows


def expected_segments(c: int, b: int, q: int) -> set[tuple[int, int]]:
    """Oriented segments of face q: rule 1 (bit 0) or its complement's, reversed (bit 1)."""
    face = FACES[q]
    if (b >> q) & 1:
        return {(y, x) for x, y in mc.face_segments(c ^ 0xFF, face)}
    return set(mc.face_segments(c, face))


def test_rows_are_surfaces_bounded_by_the_decided_face_segments():
    segment_sign = set()
    for c, b in valid_entries():
        cross = crossing_edges(c)
        for row in entry_rows(c, b):
            tris = row_tris(row)
            used = {v for t in tris for v in t}
            assert {v for v in used if v < 12} == cross, (c, b, row)
            check_surface(tris)
            for t in tris:
                assert max(t) >= 12 or not mc.on_one_face(t), (c, b, t)  # no triangle lies in a face
            segments = {(lp[k], lp[(k + 1) % len(lp)]) for lp in boundary_loops(tris) for k in range(len(lp))}
            assert all(v < 12 for s in segments for v in s)
            for q in range(6):
                on_face = {(x, y) for x, y in segments if q in EDGE_FACES[x] & EDGE_FACES[y]}
                assert on_face == expected_segments(c, b, q), (c, b, q)
                for x, y in on_face:  # the side of each segment the inside corners lie on
                    p, r = mc.EDGE_MIDPOINTS[x], mc.EDGE_MIDPOINTS[y]
                    for e in (x, y):
                        k = [z for z in mc.EDGES[e].tolist() if inside(c)[z]][0]
                        segment_sign.add(bool(np.cross(r - p, CORNERS_F[k] - p) @ NORMALS[q] > 0))
                    if ambiguous(c, q):  # bit 1 cuts off outside corners, bit 0 inside ones
                        k = (set(mc.EDGES[x].tolist()) & set(mc.EDGES[y].tolist())).pop()
                        assert bool(inside(c)[k]) != bool((b >> q) & 1)
            assert len(segments) == sum(len(expected_segments(c, b, q)) for q in range(6))
    assert len(segment_sign) == 1  # one orientation rule for every segment of every row


def test_components_are_disks_and_tubes_of_genus_zero():
    n_tubes = 0
    for c, b in valid_entries():
        for row in entry_rows(c, b):
            for comp in components(row_tris(row)):
                loops = boundary_loops(comp)
                verts = {v for t in comp for v in t}
                edges = {frozenset((t[k], t[(k + 1) % 3])) for t in comp for k in range(3)}
                assert len(verts) - len(edges) + len(comp) == 2 - len(loops)  # genus 0
                assert len(loops) in (1, 2)
                n_tubes += len(loops) == 2
            assert sum(12 in {v for t in comp for v in t} for comp in components(row_tris(row))) <= 1
    assert n_tubes > 0


def test_no_row_has_a_chord():
    """No triangle edge lies in a cube face except the face segments: the cell across a
    face never shares an edge with this one besides them, so the global surface is a
    2-manifold, and the two cells' triangles meet only along the segments."""
    for c, b in valid_entries():
        for row in entry_rows(c, b):
            tris = row_tris(row)
            segments = {frozenset((lp[k], lp[(k + 1) % len(lp)])) for lp in boundary_loops(tris)
                        for k in range(len(lp))}
            edges = {frozenset((t[k], t[(k + 1) % 3])) for t in tris for k in range(3)} - segments
            assert not [e for e in edges if max(e) < 12 and mc.on_one_face(list(e))], (c, b, row)


def test_plain_entries_trace_the_loops_of_mc_tables():
    for c in ALL_CONFIGS:
        e = c * 64
        tris = row_tris(int(m33.CASE_OFFSET[e]))
        assert mc.canonical_loops(boundary_loops(tris)) == mc.canonical_loops(mc.trace_polygons(c)), c
        if m33.INTERIOR_TEST[e] < 0:
            assert all(len(boundary_loops(comp)) == 1 for comp in components(tris)), c  # all disks


def test_interior_value_is_the_slice_connection():
    """The closed-form test against a brute-force scan of the slices ``t`` for every
    tested entry: value 1 iff some slice has A, C > 0 and P > 0, 2 iff A, C < 0 and
    P > 0 (for the values that can merge patches; skipping samples whose best slice is
    within 1e-6 of a decision)."""
    rng = np.random.default_rng(10)
    t = np.linspace(0.0, 1.0, 4001)[:, None]
    checked = 0
    for c, b in m33.BASE_CASES.tolist():
        test = int(m33.INTERIOR_TEST[c * 64 + b])
        if test < 0:
            continue
        values = np.where(inside(c), 1.0, -1.0) * np.exp(rng.uniform(-4, 0, (40000, 8)))
        values = values[m33.face_bits_of(values) == b][:300]
        got = m33.interior_value(values, test)
        a0, a1, c0, c1, b0, b1, d0, d1 = (values[:, k] for k in m33.TEST_CORNERS[test])
        A, C, B, D = (lo + t * (hi - lo) for lo, hi in ((a0, a1), (c0, c1), (b0, b1), (d0, d1)))
        P = A * C - B * D
        inside_hit = np.max(np.where((A > 0) & (C > 0), P, -np.inf), axis=0)
        outside_hit = np.max(np.where((A < 0) & (C < 0), P, -np.inf), axis=0)
        rows = entry_rows(c, b)
        for k, hit in ((1, inside_hit), (2, outside_hit)):
            if _topology(row_tris(rows[k])) == _topology(row_tris(rows[0])):
                continue  # that connection cannot merge patches: the shortcut need not match
            clear = np.abs(hit) > 1e-6
            assert np.array_equal((got == k)[clear], (hit > 0)[clear]), (c, b, k)
            checked += clear.sum()
    assert checked > 2000


# ----------------------------------------------------------------------------- symmetry


def _topology(tris) -> frozenset:
    return frozenset(mc.canonical_loops(boundary_loops(comp)) for comp in components(tris))


def _map_vertex(s: int, x: int) -> int:
    """Local vertex x moved by symmetry s: an edge, the centre, or the spoke of a corner."""
    if x < 12:
        return int(mc.SYM_EDGES[s][x])
    return x if x == 12 else 13 + int(mc.SYM_CORNERS[s][x - 13])


def test_symmetric_values_give_symmetric_surfaces():
    rng = np.random.default_rng(11)
    for c in ALL_CONFIGS:
        for v in random_values(c, rng, 3, low=0.01):
            tris = [tuple(t) for t in m33.polygonize(v).tolist()]
            for s in rng.choice(48, 4, replace=False):
                image = np.empty(8)
                image[mc.SYM_CORNERS[s]] = v  # corner k moves to SYM_CORNERS[s][k]
                mapped = [tuple(_map_vertex(s, x) for x in t) for t in tris]
                if mc.SYM_DET[s] < 0:
                    mapped = [t[::-1] for t in mapped]
                got = [tuple(t) for t in m33.polygonize(image).tolist()]
                assert _topology(got) == _topology(mapped), (c, v, s)


def test_complement_reverses_the_surface():
    """F -> -F swaps inside and outside: same surface, opposite orientation."""
    rng = np.random.default_rng(12)
    for c in ALL_CONFIGS:
        for v in random_values(c, rng, 4, low=0.01):
            tris = [tuple(t) for t in m33.polygonize(v).tolist()]
            flipped = [tuple(t[::-1]) for t in m33.polygonize(-v).tolist()]
            assert _topology(tris) == _topology(flipped), (c, v)


# ----------------------------------------------------------------------------- oracle


def _oracle_sweep(per_config: int, resolutions, seed: int):
    rng = np.random.default_rng(seed)
    samples = [(c, v) for c in ALL_CONFIGS for v in random_values(c, rng, per_config)]
    # the oracle's lattice labelling releases the GIL: both cores (pytest runs on one)
    with ThreadPoolExecutor(2) as pool:
        truths = list(pool.map(lambda cv: oracle.decided_partition(cv[1], resolutions), samples))
    decided = undecided = 0
    for (c, v), truth in zip(samples, truths):
        if truth is None:
            undecided += 1
            continue
        decided += 1
        tris = [tuple(t) for t in m33.polygonize(v).tolist()]
        assert mesh_partition(c, tris) == truth, (c, v.tolist())
    return decided, undecided


def test_oracle_all_configs():
    """256 configs x 20 value sets (magnitudes uniform in [0.05, 1]): the row's regions
    are those of the trilinear interpolant, sampled on 32^3 and 48^3 lattices."""
    decided, undecided = _oracle_sweep(20, (32, 48), seed=2024)
    assert undecided < 0.02 * (decided + undecided)


@pytest.mark.slow
def test_oracle_all_configs_fine():
    decided, undecided = _oracle_sweep(40, (48, 64), seed=2025)
    assert undecided < 0.02 * (decided + undecided)


def _class_samples(c: int, b: int, rng, want: int, count: int):
    """Up to ``count`` values of entry (c, b) whose interior test gives ``want``."""
    test = int(m33.INTERIOR_TEST[c * 64 + b])
    found = []
    for _ in range(40):
        values = np.where(inside(c), 1.0, -1.0) * np.exp(rng.uniform(-4, 0, (50000, 8)))
        values = values[m33.face_bits_of(values) == b]
        found += list(values[m33.interior_value(values, test) == want])
        if len(found) >= count:
            break
    return found[:count]


def test_interior_test_classes():
    """Every base entry with an interior test: its topologies all occur, and the oracle
    (48^3 and 64^3 lattices) agrees with the row picked by the test. For the entries of
    NEVER_MERGING the merge allowed by the cube faces never shows (an optimiser finds
    no values either); their test stays, exact and harmless."""
    rng = np.random.default_rng(13)
    n_classes = 0
    for c, b in m33.BASE_CASES.tolist():
        e = c * 64 + b
        if m33.INTERIOR_TEST[e] < 0:
            continue
        rows = entry_rows(c, b)
        plain = _topology(row_tris(rows[0]))
        meaningful = [k for k in (1, 2) if _topology(row_tris(rows[k])) != plain]
        assert meaningful, (c, b)
        for want in [0, *meaningful]:
            samples = _class_samples(c, b, rng, want, 40)
            if (c, b) in NEVER_MERGING and want:
                assert not samples, (c, b, want)
                continue
            assert samples, f"entry {(c, b)}: no values give interior value {want}"
            decided = 0
            for v in samples:
                truth = oracle.decided_partition(v, (48, 64))
                if truth is not None:
                    decided += 1
                    assert mesh_partition(c, row_tris(rows[want])) == truth, (c, b, want, v.tolist())
                    if decided == 3:
                        break
            assert decided == 3, (c, b, want)
        n_classes += (c, b) not in NEVER_MERGING
    assert n_classes == 11


def test_documented_tunnels():
    """Corners 0 and 7 at 1, the others at -0.1: a tube of inside joins them (case 4.1.2);
    at -1 instead, two separate corners (4.1.1)."""
    tube = np.array([1.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 1.0])
    apart = np.where(tube > 0, 1.0, -1.0)
    assert oracle.decided_partition(tube) == frozenset({frozenset({0, 7}), frozenset(range(1, 7))})
    assert oracle.decided_partition(apart) == frozenset({frozenset({0}), frozenset({7}), frozenset(range(1, 7))})
    assert len(components([tuple(t) for t in m33.polygonize(tube).tolist()])) == 1
    assert len(components([tuple(t) for t in m33.polygonize(apart).tolist()])) == 2


def test_plain_table_fails_the_oracle_where_mc33_does_not():
    cases = [
        np.array([1.0, -0.1, -0.1, 1.0, -1.0, -1.0, -1.0, -1.0]),  # face z = 0: saddle inside
        np.array([1.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 1.0]),  # tunnel between 0 and 7
        np.array([-1.0, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, -1.0]),  # tunnel of outside
    ]
    for v in cases:
        truth = oracle.decided_partition(v)
        c = m33.config_of(v)
        plain = [tuple(t) for t in mc.TRI_TABLE[c, : mc.TRI_COUNT[c]].tolist()]
        assert mesh_partition(c, plain) != truth
        assert mesh_partition(c, [tuple(t) for t in m33.polygonize(v).tolist()]) == truth


# ----------------------------------------------------------------------------- grids


def mesh_grid(values: np.ndarray, clearance: float = 0.0):
    """Global mesh of a node grid of values, the vertices of each cell placed by
    ``mc33_tables.vertex_positions`` (the emit kernels' rule), edge vertices shared."""
    nx, ny, nz = values.shape
    keys, points, faces = {}, [], []

    def vertex(key, point):
        if key not in keys:
            keys[key] = len(points)
            points.append(point)
        return keys[key]

    for i, j, k in itertools.product(range(nx - 1), range(ny - 1), range(nz - 1)):
        v = np.array([values[i + x, j + y, k + z] for x, y, z in mc.CORNERS.tolist()])
        row = m33.case_row(v)
        tris = m33.CASE_TRIS[row, : m33.CASE_TRI_COUNT[row]]
        if len(tris) == 0:
            continue
        where = m33.vertex_positions(v, clearance=clearance, row=row) + np.array([i, j, k])
        local = {}
        for x in set(tris.ravel().tolist()):
            if x < 12:  # an edge vertex: keyed by its grid edge
                key = tuple(int(o) for o in np.array([i, j, k]) + mc.EDGE_ORIGIN[x, :3]) + (int(mc.EDGE_ORIGIN[x, 3]),)
            else:
                key = (i, j, k, "interior", x)
            local[x] = vertex(key, where[x])
        faces += [[local[x] for x in t] for t in tris.tolist()]
    return np.array(points), np.array(faces, dtype=np.int64)


def signed_volume(pts: np.ndarray, faces: np.ndarray) -> float:
    p = pts[faces]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def random_grids():
    rng = np.random.default_rng(2026)
    for shape in [(5, 5, 5)] * 30 + [(6, 5, 7)] * 10:
        yield rng.uniform(-1, 1, shape)
    idx = np.indices((6, 6, 6)).sum(0)
    for _ in range(20):  # checkerboards: every face ambiguous
        yield np.where(idx % 2 == 0, 1.0, -1.0) * rng.uniform(0.05, 1.0, (6, 6, 6))
    for _ in range(10):  # tunnels: saddle-rich values near +-0.1 and +-1
        yield rng.choice([-1.0, -0.1, 0.1, 1.0], (6, 6, 6)) * rng.uniform(0.9, 1.1, (6, 6, 6))
    for c, b in m33.BASE_CASES.tolist():  # a cell of each tube (and chord) row amid random cells
        if m33.INTERIOR_TEST[c * 64 + b] >= 0:
            for want in (1, 2):
                for v in _class_samples(c, b, rng, want, 3):
                    grid = rng.uniform(-1, 1, (6, 6, 6))
                    for k, (x, y, z) in enumerate(mc.CORNERS.tolist()):
                        grid[2 + x, 2 + y, 2 + z] = v[k]
                    yield grid


def test_random_grids_are_closed_oriented_manifolds():
    """Random values (padded with -1), checkerboards, saddle-rich values and a cell of
    each tube row amid random cells: closed oriented 2-manifolds enclosing f > 0."""
    n_cells_with_tests = 0
    for values in random_grids():
        values[[0, -1]] = values[:, [0, -1]] = values[:, :, [0, -1]] = -1.0  # closed surface
        pts, faces = mesh_grid(values)
        if len(faces) == 0:
            continue
        check_mesh(pts, faces, closed=True, oriented=True)
        assert signed_volume(pts, faces) > 0
        for i, j, k in itertools.product(*[range(n - 1) for n in values.shape]):
            v = np.array([values[i + x, j + y, k + z] for x, y, z in mc.CORNERS.tolist()])
            n_cells_with_tests += m33.INTERIOR_TEST[m33.config_of(v) * 64 + m33.face_bits_of(v)] >= 0
    assert n_cells_with_tests > 50
