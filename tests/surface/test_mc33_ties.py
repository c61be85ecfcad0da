"""Ties and embedding of "mc33" (issue 18): binary and label volumes, where every ambiguous
face is an exact tie of the face decider, and tunnels.

The tie rule (kernels/mc33_tables.py, "Ties"): the level belongs to the outside. A corner
value equal to the level is outside, a face whose saddle value equals the level keeps its
inside corners apart (the two cells of the face compute the same two products), and an
interior test whose slice saddle lies on the level joins outside corners, never inside
ones: every decision is that of ``v - epsilon``. Whatever the decisions, the rows are
embedded: a tube is built by the hub construction, whose triangles cannot cross for any
vertex positions on the cell's edges and spokes.

Checked here: every cell of small integer values (ties of every kind) against the
crossing check and its neighbours; the hub rows under arbitrary vertex positions; the
emit kernels against the table reference; random binary, continuous and label volumes
with every method; the two segmentations pyvista ships.
"""

from __future__ import annotations

import functools
import itertools

import numpy as np
import pytest

import warpmesh as wm
from warpmesh import _conventions as C
from tests.helpers import trilinear_oracle as oracle
from tests.helpers.meshcheck import check_mesh
from tests.surface.test_mc33_tables import mesh_partition, row_tris
from warpmesh.cells.intersections import find_self_intersections
from warpmesh.kernels import mc33_tables as m33
from warpmesh.kernels import mc_tables as mc

CORNERS = mc.CORNERS.astype(np.float64)
#: the issue's cell: five corners inside, three faces tied, a tunnel of inside (as corner
#: values here; the issue's ``reshape(2, 2, 2)`` puts them on its mirror image, x <-> z)
ISSUE_CELL = np.array([1, 1, 0, 1, 0, 1, 1, 0], dtype=np.float32)
#: corner values from small integer sets, minus the level: (values, level)
TIE_SETS = {
    "binary": ([0, 1], 0.5),  # every ambiguous face a tie (0.5 * 0.5 = 0.5 * 0.5)
    "at the level": ([0, 1, 2], 1.0),  # corners on the surface (outside), and face ties
    "four levels": ([0, 1, 2, 3], 1.5),  # ties such as 0.5 * 1.5 = 1.5 * 0.5
    "saddles at the level": ([-2, -1, 1, 2], 0.0),  # 1 * 2 = 2 * 1, interior ties
}


def all_cells(values, level) -> np.ndarray:
    """(k^8, 8) every assignment of the values to the 8 corners, minus the level."""
    return np.array(list(itertools.product(values, repeat=8)), dtype=np.float64) - level


def representatives(v: np.ndarray) -> np.ndarray:
    """One cell per orbit of the 48 cube symmetries (the tables are the symmetric images
    of their base cases, and the vertex placement commutes with the symmetries)."""
    levels, digits = np.unique(v, return_inverse=True)
    digits = digits.reshape(v.shape)
    inverse = np.argsort(mc.SYM_CORNERS, axis=1)  # value of image corner c = value of corner inverse[s][c]
    codes = np.stack([(digits[:, inverse[s]] * len(levels) ** np.arange(8)).sum(axis=1) for s in range(48)])
    _, first = np.unique(codes.min(axis=0), return_index=True)
    return v[np.sort(first)]


def rows_of(v: np.ndarray) -> np.ndarray:
    """(n,) ``case_row`` of (n, 8) corner values, vectorised."""
    entry = m33.config_of(v) * 64 + m33.face_bits_of(v)
    rows = m33.CASE_OFFSET[entry].astype(np.int64)
    tests = m33.INTERIOR_TEST[entry]
    for k in range(6):
        sel = tests == k
        if sel.any():
            rows[sel] += m33.interior_value(v[sel], k)
    return rows


def cell_vertices(v: np.ndarray, rows: np.ndarray, clearance: float) -> np.ndarray:
    """(n, 21, 3) vertex positions of (n, 8) cells, as ``mc33_tables.vertex_positions``
    (vectorised for the edges and vertex 12)."""
    gap = max(1.0e-3, clearance)
    a, b = mc.EDGES[:, 0], mc.EDGES[:, 1]
    va, vb = v[:, a], v[:, b]
    cross = (va > 0) != (vb > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.where(cross, va / (va - vb), 0.5), gap, 1.0 - gap)[..., None]
    p = np.full((len(v), 21, 3), np.nan)
    p[:, :12] = CORNERS[a] * (1.0 - t) + CORNERS[b] * t
    w = cross[..., None]
    p[:, 12] = (p[:, :12] * w).sum(axis=1) / np.maximum(w.sum(axis=1), 1)
    for i in np.flatnonzero(m33.CASE_INTERIOR[rows] > 1):  # rows with spokes
        p[i, 13:] = m33.vertex_positions(v[i], clearance=clearance, row=int(rows[i]))[13:]
    return p


def crossing_cells(rows: np.ndarray, points: np.ndarray) -> list[int]:
    """Cells whose triangles cross each other: one crossing check over all the cells,
    each moved to its own place on a lattice of spacing 2 (distinct cells never meet)."""
    keep = np.flatnonzero(m33.CASE_TRI_COUNT[rows] >= 2)
    side = int(np.ceil(len(keep) ** (1 / 3))) + 1
    shift = 2.0 * np.stack(np.unravel_index(np.arange(len(keep)), (side,) * 3), axis=1)
    tris, owner = [], []
    for slot, i in enumerate(keep):
        t = m33.CASE_TRIS[rows[i], : m33.CASE_TRI_COUNT[rows[i]]]
        tris.append(t + 21 * slot)
        owner += [i] * len(t)
    # positions on a dyadic grid of 2^-30 first, so that the shifts are exact: every
    # cell is checked as it would be on its own
    local = np.round(np.nan_to_num(points[keep]) * 2.0**30) / 2.0**30  # NaN: unused vertices
    pts = (local + shift[:, None, :]).reshape(-1, 3)
    pairs = find_self_intersections(pts, np.concatenate(tris))
    owner = np.array(owner)
    assert np.all(owner[pairs[:, 0]] == owner[pairs[:, 1]]), "two cells met: the lattice is too tight"
    return sorted(set(owner[pairs[:, 0]].tolist()))


def unique_cells(v: np.ndarray, rows: np.ndarray, points: np.ndarray):
    """The cells with distinct (row, vertex positions): ties repeat a few geometries."""
    key = np.concatenate([rows[:, None].astype(np.float64), np.nan_to_num(points, nan=-1).reshape(len(v), -1)],
                         axis=1)
    _, first = np.unique(np.round(key, 12), axis=0, return_index=True)
    return v[first], rows[first], points[first]


# ----------------------------------------------------------------------------- tie rules


def test_the_issue_cell_decides_its_ties_and_is_embedded():
    """Values 0/1 at level 0.5: the three ambiguous faces tie (kept apart, bit 0), the
    interior test finds the tunnel of inside (P(t*) > 0, no tie), the row is a tube built
    on the hub, and the mesh is closed, oriented and embedded."""
    v = ISSUE_CELL.astype(np.float64) - 0.5
    c = m33.config_of(v)
    assert m33.AMBIGUOUS_FACES[c] != 0 and m33.face_bits_of(v) == 0
    test = int(m33.INTERIOR_TEST[c * 64])
    assert test >= 0 and m33.interior_value(v, test) == 1
    row = m33.case_row(v)
    assert m33.CASE_INTERIOR[row] > 1  # spokes: the hub construction
    assert crossing_cells(np.array([row]), cell_vertices(v[None], np.array([row]), 0.0)) == []
    m = wm.mesh_surface(np.pad(ISSUE_CELL.reshape(2, 2, 2), 1), level=0.5)
    check_mesh(m)  # closed, manifold, oriented, embedded
    assert len(find_self_intersections(m.points, m.triangles)) == 0
    assert m.stats()["components"] == 1 and m.stats()["volume"] > 0


def test_face_ties_are_decided_alike_in_both_cells():
    """Every face of every cell of every tie set: the bit of the cell below equals the
    bit of the cell above (the mirrored values), and a tie keeps the inside corners apart."""
    for values, level in TIE_SETS.values():
        v = all_cells(values, level)
        bits = m33.face_bits_of(v)
        for q, (a, b, c, d) in enumerate(m33.FACE_CORNERS.tolist()):
            mirrored = v[:, [k ^ (1 << (q // 2)) for k in range(8)]]
            assert np.array_equal((bits >> q) & 1, (m33.face_bits_of(mirrored) >> (q ^ 1)) & 1)
            tie = (v[:, a] * v[:, c] == v[:, b] * v[:, d]) & ((m33.AMBIGUOUS_FACES[m33.config_of(v)] >> q) & 1 == 1)
            assert tie.any() and not ((bits >> q) & 1)[tie].any()


def test_interior_ties_count_the_level_as_outside():
    """Exact ties of the interior test, for every test and every cell of the tie sets that
    has one: a slice saddle on the level (P(t*) = 0) joins A and C when they are outside
    (value 2) and never when they are inside; a vertex t* on a face leaves it to the face
    (value 0). As for corners (v <= 0) and face saddles, the level belongs to the outside."""
    counts = {"inside": 0, "outside": 0, "on a face": 0}
    for values, level in TIE_SETS.values():
        v = all_cells(values, level)
        tests = m33.INTERIOR_TEST[m33.config_of(v) * 64 + m33.face_bits_of(v)]
        for k in range(6):
            w = v[tests == k]
            a0, a1, c0, c1, b0, b1, d0, d1 = (w[:, x] for x in m33.TEST_CORNERS[k])
            alpha = (a1 - a0) * (c1 - c0) - (b1 - b0) * (d1 - d0)
            beta = a0 * (c1 - c0) + c0 * (a1 - a0) - b0 * (d1 - d0) - d0 * (b1 - b0)
            gamma = a0 * c0 - b0 * d0
            vertex = (alpha < 0) & (beta > 0) & (beta < -2 * alpha)
            tie = vertex & (beta * beta == 4 * alpha * gamma)  # P(t*) = 0
            t = np.where(vertex, -beta / np.where(alpha < 0, 2 * alpha, -1.0), 0.5)
            a_t, c_t = a0 + t * (a1 - a0), c0 + t * (c1 - c0)
            got = m33.interior_value(w, k)
            inside, outside = tie & (a_t > 0) & (c_t > 0), tie & (a_t <= 0) & (c_t <= 0)
            on_face = (alpha < 0) & ((beta == 0) | (beta == -2 * alpha))
            assert np.all(got[inside] == 0) and np.all(got[outside] == 2) and np.all(got[on_face] == 0)
            for name, sel in (("inside", inside), ("outside", outside), ("on a face", on_face)):
                counts[name] += int(sel.sum())
    assert min(counts.values()) >= 8, counts


def _has_tie(v: np.ndarray) -> np.ndarray:
    """(n,) cells with a tied ambiguous face or an interior test (where ties decide)."""
    config = m33.config_of(v)
    out = m33.INTERIOR_TEST[config * 64 + m33.face_bits_of(v)] >= 0
    for q, (a, b, c, d) in enumerate(m33.FACE_CORNERS.tolist()):
        out |= ((m33.AMBIGUOUS_FACES[config] >> q) & 1 == 1) & (v[:, a] * v[:, c] == v[:, b] * v[:, d])
    return out


@pytest.mark.parametrize("name", list(TIE_SETS))
def test_ties_have_the_topology_of_the_level_raised_slightly(name):
    """The oracle of the trilinear interpolant (tests/helpers/trilinear_oracle.py, which
    knows nothing of tables) on ``v - epsilon``, where nothing ties any more (epsilon
    below half the smallest other critical value), against the regions of the row chosen
    for ``v`` itself: the symmetry orbits with a tie, 60 of each set at most."""
    v = representatives(all_cells(*TIE_SETS[name]))
    v = v[_has_tie(v)]
    if len(v) > 60:
        v = v[np.random.default_rng(21).choice(len(v), 60, replace=False)]
    rows = rows_of(v)
    decided = 0
    for cell, row in zip(v, rows):
        critical = np.abs(oracle.critical_values(cell))
        eps = min(0.01, 0.5 * critical[critical > 1e-9].min())
        truth = oracle.decided_partition(cell - eps, (32, 48), margin=0.5 * eps)
        if truth is not None:
            decided += 1
            assert mesh_partition(m33.config_of(cell), row_tris(int(row))) == truth, cell.tolist()
    assert decided >= 0.8 * len(v) and decided > 10


# ----------------------------------------------------------------------------- embedded cells


@pytest.mark.parametrize("name", list(TIE_SETS))
def test_every_cell_of_a_tie_set_is_embedded(name):
    """Every assignment of the set's values to the 8 corners (every configuration with
    every tie pattern), one per symmetry orbit: the row (a 2-manifold bounded by its face
    segments, see the table tests) has no two triangles crossing, with the clearance of
    the emission and without it."""
    v = representatives(all_cells(*TIE_SETS[name]))
    rows = rows_of(v)
    orbits = {min(mc.apply_symmetry_to_config(k, c) for k in range(48)) for c in m33.config_of(v).tolist()}
    assert len(orbits) == 22  # every orbit of sign patterns
    assert (m33.CASE_INTERIOR[rows] > 1).any()  # tunnels among them
    for clearance in (0.0, 0.1):
        cells, cell_rows, points = unique_cells(v, rows, cell_vertices(v, rows, clearance))
        bad = crossing_cells(cell_rows, points)
        assert not bad, f"{len(bad)} crossing cells, first {cells[bad[0]].tolist()} (row {cell_rows[bad[0]]})"


def test_cells_of_random_values_are_embedded():
    """Values of both signs, magnitudes log-uniform over 8 decades: every configuration
    (the clearance of the emission only moves vertices, which the tie sets cover)."""
    rng = np.random.default_rng(18)
    v = rng.choice([-1.0, 1.0], (20000, 8)) * np.exp(rng.uniform(-18, 0, (20000, 8)))
    rows = rows_of(v)
    assert (m33.CASE_INTERIOR[rows] > 1).sum() > 100  # tunnels among them
    assert crossing_cells(rows, cell_vertices(v, rows, 0.0)) == []


def test_hub_rows_are_embedded_for_any_vertex_positions():
    """The hub construction does not depend on where the vertices sit: every row with
    spokes, edge vertices anywhere inside their edges, the hub anywhere inside the
    margin, spoke vertices anywhere inside their spokes."""
    rng = np.random.default_rng(19)
    hub_rows = np.flatnonzero(m33.CASE_INTERIOR > 1)
    assert len(hub_rows) > 100
    rows = np.repeat(hub_rows, 40)
    n = len(rows)
    t = rng.uniform(0.001, 0.999, (n, 12, 1))
    p = np.full((n, 21, 3), np.nan)
    p[:, :12] = CORNERS[mc.EDGES[:, 0]] * (1 - t) + CORNERS[mc.EDGES[:, 1]] * t
    hub = rng.uniform(m33.HUB_MARGIN, 1 - m33.HUB_MARGIN, (n, 1, 3))
    tau = rng.uniform(0.001, 0.999, (n, 8, 1))
    p[:, 13:] = hub + tau * (CORNERS - hub)
    assert crossing_cells(rows, p) == []


@functools.lru_cache(maxsize=None)
def _face_segments(row: int, q: int) -> frozenset:
    """The boundary segments of a row on face q, as edges of the cell above that face."""
    tris = m33.CASE_TRIS[row, : m33.CASE_TRI_COUNT[row]].tolist()
    directed = {(x[k], x[(k + 1) % 3]) for x in tris for k in range(3)}
    face = set(m33.FACE_CORNERS[q].tolist())
    shift = (1 << (q // 2)) if q % 2 else 0
    return frozenset(frozenset(mc.EDGE_OF[int(mc.EDGES[x][0]) ^ shift, int(mc.EDGES[x][1]) ^ shift] for x in (a, b))
                     for a, b in directed if (b, a) not in directed and max(a, b) < 12
                     and set(mc.EDGES[a].tolist()) | set(mc.EDGES[b].tolist()) <= face)


def test_rows_agree_with_their_neighbours_on_every_tied_face():
    """For every face pattern of the tie sets, the cell below the face and the cell above
    it leave the same segments on it (whatever their other corners): the surface closes."""
    seen: dict[tuple, frozenset] = {}
    for name, (values, level) in TIE_SETS.items():
        v = all_cells(values, level)
        digits = np.searchsorted(np.asarray(values, dtype=np.float64) - level, v)
        rows = rows_of(v)
        for q in range(6):
            shift = (1 << (q // 2)) if q % 2 else 0
            face = sorted(m33.FACE_CORNERS[q].tolist(), key=lambda k: k ^ shift)  # in the upper cell's frame
            code = (digits[:, face] * len(values) ** np.arange(4)).sum(axis=1)
            for pair in np.unique(code * 4096 + rows).tolist():
                key, row = (name, q // 2, pair // 4096), pair % 4096
                assert seen.setdefault(key, _face_segments(row, q)) == _face_segments(row, q), key
    assert len(seen) > 500


# ----------------------------------------------------------------------------- emission


def _labels(points: np.ndarray) -> list:
    """Cell-local points as vertex labels: the cube edge a point lies on, else its
    position rounded (interior vertices)."""
    out = []
    for p in points:
        on = np.isclose(p, 0.0, atol=1e-6) | np.isclose(p, 1.0, atol=1e-6)
        if on.sum() >= 2:
            axis = int(np.flatnonzero(~on)[0]) if on.sum() == 2 else 0
            lo = np.round(p).astype(int)
            lo[axis] = 0
            out.append(("edge", mc.EDGE_OF[int(lo @ [1, 2, 4]), int(lo @ [1, 2, 4]) | (1 << axis)]))
        else:
            out.append(("interior",) + tuple(np.round(p, 4).tolist()))
    return out


def _oriented(triangles) -> list:
    """Triangles of labels, each rotated to start at its smallest label, sorted."""
    return sorted(min(t[k:] + t[:k] for k in range(3)) for t in (tuple(x) for x in triangles))


def test_the_kernel_places_vertices_as_the_reference():
    """Single cells through ``mesh_surface`` (the emit kernels): the triangles of the cell
    are those of ``polygonize``, with the interior vertices (hub rows: one per spoke, in
    the order of their local ids) where ``vertex_positions`` puts them."""
    rng = np.random.default_rng(20)
    n_hub = 0
    for _ in range(4000):
        v = (rng.choice([-1.0, 1.0], 8) * np.exp(rng.uniform(-3, 0, 8))).astype(np.float32)
        row = m33.case_row(v)
        if m33.CASE_INTERIOR[row] <= 1:
            continue
        n_hub += 1
        vol = np.full((4, 4, 4), -1.0, np.float32)
        vol[1:3, 1:3, 1:3] = v.reshape(2, 2, 2, order="F")  # corner k at (k & 1, k >> 1 & 1, k >> 2)
        m = wm.mesh_surface(vol, level=0.0)
        check_mesh(m)
        tri = m.points[m.triangles] - 1.0
        inner = np.all((tri > -1e-6) & (tri < 1 + 1e-6), axis=(1, 2))
        got = _oriented(np.array(_labels(tri[inner].reshape(-1, 3)), dtype=object).reshape(-1, 3).tolist())
        wanted = []  # the spokes' clamp is the emission's clearance off the nodes, if it has one
        for clearance in {0.0, m.info.get("clearance", 0.0), getattr(C, "NODE_CLEARANCE", 0.0)}:
            where = m33.vertex_positions(v, clearance=clearance, row=row)
            labels = [("edge", x) if x < 12 else ("interior",) + tuple(np.round(where[x], 4).tolist())
                      for x in range(21)]
            wanted.append(_oriented([[labels[x] for x in t] for t in m33.polygonize(v).tolist()]))
        assert got in wanted, v.tolist()
        if n_hub == 12:
            break
    assert n_hub == 12


def _tiled(volumes) -> np.ndarray:
    """The volumes side by side in one array, two zero layers apart: meshing it meshes
    each volume on its own (no cell sees two of them)."""
    size = max(max(v.shape) for v in volumes) + 2
    side = int(np.ceil(len(volumes) ** (1 / 3)))
    out = np.zeros((side * size,) * 3, dtype=volumes[0].dtype)
    for n, vol in enumerate(volumes):
        i, j, k = np.unravel_index(n, (side,) * 3)
        out[i * size + 1: i * size + 1 + vol.shape[0], j * size + 1: j * size + 1 + vol.shape[1],
            k * size + 1: k * size + 1 + vol.shape[2]] = vol
    return out


def _random_volumes(kind: str, count: int = 200, seed: int = 18):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        shape = tuple(rng.integers(3, 9, 3))
        if kind == "binary":
            yield rng.integers(0, 2, shape).astype(np.float32)
        elif kind == "labels":
            yield rng.integers(0, 4, shape).astype(np.uint8)
        else:
            yield rng.uniform(0.0, 1.0, shape).astype(np.float32)


@pytest.mark.parametrize("method", ["mc33", "mc", "mt"])
@pytest.mark.parametrize("kind", ["binary", "continuous"])
def test_random_volumes_are_closed_oriented_and_embedded(kind, method):
    """200 random padded volumes of 3 to 8 samples a side at level 0.5: binary ones (every
    ambiguous face a tie) and continuous ones, with every method."""
    m = wm.mesh_surface(_tiled(list(_random_volumes(kind))), level=0.5, method=method)
    check_mesh(m)  # closed, manifold, oriented and embedded (find_self_intersections)
    assert m.info["enclosed_volume"] > 0
    if method == "mc33":
        assert m.info["interior_vertices"] > 0  # tunnels among them


def _check_labels(m) -> None:
    """Each label's surface closed, oriented, embedded (two labels share their interface)."""
    refs = m.cell_refs["triangle"]
    for label in np.unique(refs):
        check_mesh(m.points, m.triangles[refs == label])


@pytest.mark.parametrize("method", ["mc33", "mc", "mt"])
def test_random_label_volumes(method):
    """200 random volumes of labels 0 to 3 (0 the background), every label meshed."""
    m = wm.mesh_surface(_tiled(list(_random_volumes("labels"))), labels="all", method=method)
    assert set(np.unique(m.cell_refs["triangle"]).tolist()) == {1, 2, 3}
    _check_labels(m)


@pytest.mark.parametrize("loader, box", [("load_frog_tissues", (slice(200, 264), slice(180, 244), slice(40, 88))),
                                         ("load_channels", (slice(60, 124), slice(60, 124), slice(20, 68)))])
def test_real_segmentations(loader, box):
    """The two label volumes pyvista ships (no download): a block of each, every label."""
    examples = pytest.importorskip("pyvista.examples")
    if not hasattr(examples, loader):
        pytest.skip(f"this pyvista has no examples.{loader}")
    image = getattr(examples, loader)()
    data = np.asarray(image.active_scalars)
    shape = np.array(image.dimensions) - (data.size != np.prod(image.dimensions))  # point or cell data
    labels = data.reshape(shape, order="F")[box]
    assert len(np.unique(labels)) > 2
    m = wm.mesh_surface(np.ascontiguousarray(labels.astype(np.int32)), labels="all", spacing=image.spacing)
    _check_labels(m)


def test_the_oracle_still_decides_the_documented_tunnel_cells():
    """The hub rows keep the topology of the trilinear interpolant where the oracle decides
    it (the full sweep is in test_mc33_tables.py)."""
    tube = np.array([1.0, -0.1, -0.1, -0.1, -0.1, -0.1, -0.1, 1.0])
    truth = oracle.decided_partition(tube)
    assert truth == frozenset({frozenset({0, 7}), frozenset(range(1, 7))})
    tris = m33.polygonize(tube)
    assert m33.CASE_INTERIOR[m33.case_row(tube)] > 1
    p = cell_vertices(tube[None], np.array([m33.case_row(tube)]), 0.0)[0]
    assert crossing_cells(np.array([m33.case_row(tube)]), p[None]) == []
    assert len(tris) == 18
