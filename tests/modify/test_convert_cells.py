"""warpmesh.modify.convert_cells and warpmesh.modify.hex_splits: element type conversion ([FG §17.1.3],
Remark 17.6, Exercise 17.1, Remark 17.16)."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest
import pyvista as pv
from tests.helpers.cellcheck import check_cells
from scipy.spatial import Delaunay

from warpmesh.errors import WarpMeshError
from warpmesh.modify.hex_splits import (
    HEX_SPLIT_CONFIGS,
    HEX_SPLITS,
    HEX_TETRAHEDRA,
    hex_configurations,
    steiner_split,
)
from warpmesh.mesh import Mesh
from warpmesh.cells.quality import triangle_quality
from warpmesh.cells.reference import cell_measures, corner_jacobians, reference_cell
from warpmesh.modify.convert_cells import convert_cells

CUBE = reference_cell("hexahedron").vertices
HEX_FACES = np.array(reference_cell("hexahedron").faces)


# ----------------------------------------------------------------------------- helpers
def renumber(mesh: Mesh, rng) -> Mesh:
    """The same mesh with its points in a random order (so min-index choices vary)."""
    perm = rng.permutation(mesh.n_points)
    inv = np.argsort(perm)
    return mesh.replace(points=mesh.points[perm], cells={t: inv[c] for t, c in mesh.cells.items()},
                        point_refs=None if mesh.point_refs is None else mesh.point_refs[perm],
                        point_data={k: v[perm] for k, v in mesh.point_data.items()})


def faces_of(cells: np.ndarray, cell_type: str) -> list[np.ndarray]:
    """Outward faces of 3D cells, grouped by size."""
    f = reference_cell(cell_type).faces
    return [cells[:, [x for x in f if len(x) == k]].reshape(-1, k) for k in (3, 4)
            if any(len(x) == k for x in f)]


def boundary(cells: dict) -> dict:
    """The faces used once by the 3D cells, outward: {"triangle": ..., "quad": ...}."""
    groups = [f for t, c in cells.items() for f in faces_of(c, t)]
    rows = [np.pad(np.sort(g, 1), ((0, 0), (0, 4 - g.shape[1])), constant_values=-1) for g in groups]
    _, inv, cnt = np.unique(np.concatenate(rows), axis=0, return_inverse=True, return_counts=True)
    once, out, start = cnt[inv.ravel()] == 1, {}, 0
    for g in groups:
        name = "triangle" if g.shape[1] == 3 else "quad"
        prev = out.get(name, np.zeros((0, g.shape[1]), int))
        out[name] = np.concatenate([prev, g[once[start:start + len(g)]]])
        start += len(g)
    return out


def canonical(rows: np.ndarray) -> set:
    """Oriented faces as a set: each rotated to start at its smallest vertex."""
    r = np.asarray(rows)
    shift = r.argmin(1)
    idx = (shift[:, None] + np.arange(r.shape[1])) % r.shape[1]
    return set(map(tuple, np.take_along_axis(r, idx, 1).tolist()))


def assert_faces_of_volume(m: Mesh):
    """Every triangle/quad of a 3D mesh is an (outward) face of its 3D cells."""
    if m.dim == 2:
        return
    faces = set()
    for t, c in m.cells.items():
        if reference_cell(t).tdim == 3:
            for f in faces_of(c, t):
                faces |= canonical(f)
    for t in ("triangle", "quad"):
        if t in m.cells:
            missing = canonical(m.cells[t]) - faces
            assert not missing, f"{len(missing)} {t} cells are not faces of the volume cells"


def assert_conversion(before: Mesh, after: Mesh, children: dict):
    """Measure, boundary measure and conformity kept; each child's ref = its parent's index
    (set by the caller), and children measures add up per parent."""
    a, b = reference_measures(before), check_cells(after)
    assert np.isclose(b["measure"], a["measure"], rtol=1e-12, atol=0)
    # a non-conforming cut of an interior face would show up as extra boundary
    assert np.isclose(b["boundary_measure"], a["boundary_measure"], rtol=1e-12, atol=0)
    for child in set(children.values()):  # refs are unique over all blocks (with_refs)
        vol = cell_measures(after.points, after.cells[child], child)
        parents = [t for t, c in children.items() if c == child]
        kept = after.cells[child][: len(before.cells[child])] if child in before.cells else None
        if kept is not None:
            vol = vol[len(kept):]
        refs = after.cell_refs[child][len(after.cells[child]) - len(vol):]
        per = np.bincount(refs, weights=vol, minlength=before.n_cells)
        want = np.zeros(before.n_cells)
        for t in parents:
            want[before.cell_refs[t]] = cell_measures(before.points, before.cells[t], t)
        assert np.allclose(per, want, rtol=1e-12, atol=1e-15 * np.abs(want).max())
    assert_faces_of_volume(after)


def reference_measures(m: Mesh) -> dict:
    """Total measure and boundary measure of a mesh before conversion, computed here
    (check_cells cannot mix triangle and quad faces yet)."""
    vol = sum(cell_measures(m.points, c, t).sum() for t, c in m.cells.items()
              if reference_cell(t).tdim == m.dim)
    if m.dim == 2:
        return check_cells(m)
    b = boundary({t: c for t, c in m.cells.items() if reference_cell(t).tdim == 3})
    area = sum(cell_measures(m.points, c, t).sum() for t, c in b.items())
    return {"measure": vol, "boundary_measure": area}


def with_refs(mesh: Mesh) -> Mesh:
    """Cell refs = a number unique over all blocks (so children can be traced), an int and
    a float cell field."""
    start = np.cumsum([0] + [len(c) for c in mesh.cells.values()])
    refs = {t: s + np.arange(len(c)) for (t, c), s in zip(mesh.cells.items(), start)}
    data = {"id": {t: r * 10 for t, r in refs.items()}, "w": {t: r + 0.5 for t, r in refs.items()}}
    return mesh.replace(cell_refs=refs, cell_data=data)


def hex_grid(n: int, rng, *, shear=True) -> Mesh:
    """n**3 hexahedra of a rectilinear grid mapped by an affine shear (planar faces, so
    any split conserves the volume exactly), points randomly numbered, boundary quads."""
    axes = [np.cumsum(np.r_[0, rng.uniform(0.5, 1.5, n)]) for _ in range(3)]
    x, y, z = np.meshgrid(*axes, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    if shear:
        pts = pts @ np.array([[1, 0.2, 0.1], [0, 1, 0.3], [0, 0, 1.0]]).T
    idx = np.arange((n + 1) ** 3).reshape((n + 1,) * 3)
    i, j, k = (a.ravel() for a in np.meshgrid(*[np.arange(n)] * 3, indexing="ij"))
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    hexes = np.stack([idx[i + a, j + b, k + c] for a, b, c in corners], 1)
    cells = {"hexahedron": hexes}
    cells["quad"] = boundary(cells)["quad"]
    return renumber(Mesh(pts, cells), rng)


def extruded(tri2d: np.ndarray, pts2d: np.ndarray, layers: int, quads2d=None) -> Mesh:
    """Wedges (and hexahedra from quads) by extruding a 2D mesh, plus the boundary faces."""
    n = len(pts2d)
    z = np.linspace(0, 1, layers + 1)
    pts = np.concatenate([np.c_[pts2d, np.full(n, h)] for h in z])
    cells = {}
    off = np.arange(layers)[:, None, None] * n
    if quads2d is not None:
        cells["hexahedron"] = (np.concatenate([quads2d, quads2d + n], 1)[None] + off).reshape(-1, 8)
    cells["wedge"] = (np.concatenate([tri2d, tri2d + n], 1)[None] + off).reshape(-1, 6)
    b = boundary(cells)
    cells.update(triangle=b["triangle"], quad=b["quad"])
    return Mesh(pts, cells)


def delaunay2d(rng, n=60):
    pts = np.concatenate([rng.uniform(0, 1, (n, 2)), [[0, 0], [1, 0], [1, 1], [0, 1]]])
    tri = Delaunay(pts).simplices
    a = cell_measures(pts, tri, "triangle")
    tri[a < 0] = tri[a < 0][:, [0, 2, 1]]
    return pts, tri


# ----------------------------------------------------------------------------- hex_splits
def test_hex_tetrahedra_and_74_splits():
    assert len(HEX_TETRAHEDRA) == 58  # Exercise 17.1
    assert (cell_measures(CUBE, HEX_TETRAHEDRA, "tetra") > 0).all()
    sizes = [len(s) for s in HEX_SPLITS]
    assert len(HEX_SPLITS) == 74 and sizes.count(5) == 2 and sizes.count(6) == 72  # Remark 17.6
    assert len({frozenset(map(tuple, np.sort(s, 1).tolist())) for s in HEX_SPLITS}) == 74
    for s, cfg in zip(HEX_SPLITS, HEX_SPLIT_CONFIGS):
        m = Mesh(CUBE, {"tetra": s})
        r = check_cells(m)  # positive, face-to-face, closed
        assert np.isclose(r["measure"], 1.0, rtol=1e-12) and np.isclose(r["boundary_measure"], 6.0)
        edges = {frozenset(e) for t in s.tolist() for e in itertools.combinations(t, 2)}
        bits = [frozenset(f[[1, 3]].tolist()) in edges for f in HEX_FACES]
        assert all(b != (frozenset(f[[0, 2]].tolist()) in edges) for b, f in zip(bits, HEX_FACES))
        assert cfg == sum(int(b) << i for i, b in enumerate(bits))


def test_min_index_rule_always_has_a_split():
    """Over all 8! numberings of a hexahedron, the min-index configuration has a split."""
    perms = np.array(list(itertools.permutations(range(8))))
    pos = perms[:, HEX_FACES].argmin(2) % 2  # recomputed here: face cut through its min vertex
    cfg = (pos << np.arange(6)).sum(1)
    assert (cfg == hex_configurations(perms)).all()
    assert np.isin(cfg, HEX_SPLIT_CONFIGS).all()
    assert len(np.unique(cfg)) == 42 and len(np.unique(HEX_SPLIT_CONFIGS)) == 46


def test_steiner_split_every_configuration():
    x = np.concatenate([CUBE, [[0.5, 0.5, 0.5]]])
    for c in range(64):
        s = steiner_split(c)
        r = check_cells(Mesh(x, {"tetra": s}))  # positive, face-to-face, closed
        assert np.isclose(r["measure"], 1.0, rtol=1e-12) and np.isclose(r["boundary_measure"], 6.0)
        diagonals = {frozenset(e) for t in s.tolist() for e in itertools.combinations(t[:3], 2)}
        cut = [frozenset(f[[1, 3]].tolist()) in diagonals for f in HEX_FACES]
        assert sum(int(b) << i for i, b in enumerate(cut)) == c


def test_hex_splits_bad_inputs():
    with pytest.raises(ValueError, match="'config'"):
        steiner_split(64)
    with pytest.raises(ValueError, match="'hexes'"):
        hex_configurations(np.zeros((2, 6), int))


def test_both_five_tet_variants():
    five = [s for s in HEX_SPLITS if len(s) == 5]
    c = [HEX_SPLIT_CONFIGS[i] for i, s in enumerate(HEX_SPLITS) if len(s) == 5]
    assert c[0] ^ c[1] == 63  # they cut every face the other way
    a = np.array([[1, 0.3, 0.2], [0.1, 1.2, 0.1], [0.2, -0.1, 0.9]])
    x = CUBE @ a.T + 1.5
    for s in five:
        r = check_cells(Mesh(x, {"tetra": s}))
        assert np.isclose(r["measure"], np.linalg.det(a), rtol=1e-12)
        # one central tetrahedron of a third of the volume, four corners of a sixth
        v = np.sort(cell_measures(CUBE, s, "tetra"))
        assert np.allclose(v, [1 / 6] * 4 + [1 / 3])


# ----------------------------------------------------------------------------- single cells
@pytest.mark.parametrize("cell_type, target, counts", [
    ("wedge", "tetra", {3}), ("pyramid", "tetra", {2}), ("hexahedron", "tetra", {5, 6}),
    ("tetra", "hexahedron", {4}), ("triangle", "quad", {3}), ("quad", "triangle", {2})])
def test_single_cell_random_numberings(cell_type, target, counts):
    """One reference cell (affinely distorted) under 40 random numberings of its vertices:
    children positive, measure kept, count as stated."""
    ref = reference_cell(cell_type)
    a = np.array([[1.0, 0.3, 0.2], [0.1, 1.2, 0.1], [0.2, -0.1, 0.9]])[: ref.tdim, : ref.tdim]
    x = ref.vertices @ a.T
    rng = np.random.default_rng(9)
    for _ in range(40):
        perm = rng.permutation(len(x))  # point i of the mesh is reference vertex perm[i]
        m = Mesh(x[perm], {cell_type: [np.argsort(perm)]})
        out = convert_cells(m, target)
        assert len(out.cells[target]) in counts
        r = check_cells(out)
        assert np.isclose(r["measure"], cell_measures(x, np.arange(len(x))[None], cell_type)[0], rtol=1e-12)


# ----------------------------------------------------------------------------- 2D
def quad_grid(rng, n=8, jitter=0.25):
    x, y = np.meshgrid(np.arange(n + 1.0), np.arange(n + 1.0), indexing="ij")
    pts = np.stack([x.ravel(), y.ravel()], 1)
    inner = (pts > 0).all(1) & (pts < n).all(1)
    pts[inner] += rng.uniform(-jitter, jitter, (inner.sum(), 2))
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    quads = np.stack([idx[i, j], idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]], 1)
    e = np.concatenate([quads[:, [0, 1]], quads[:, [1, 2]], quads[:, [2, 3]], quads[:, [3, 0]]])
    key, cnt = np.unique(np.sort(e, 1), axis=0, return_counts=True)
    return Mesh(pts, {"quad": quads, "line": key[cnt == 1]})


@pytest.mark.parametrize("quads", ["best", "min", 4])
def test_quad_to_triangle_2d(quads):
    rng = np.random.default_rng(1)
    m = with_refs(renumber(quad_grid(rng), rng))
    m = m.replace(point_data={"f": m.points @ [2.0, -1.0] + 3}, point_refs=(m.points[:, 0] == 0) * 5)
    out = convert_cells(m, "triangle", quads=quads)
    k = 4 if quads == 4 else 2
    assert len(out.cells["triangle"]) == k * len(m.cells["quad"])
    assert (out.cells["line"] == m.cells["line"]).all()
    assert (out.cell_refs["line"] == m.cell_refs["line"]).all()
    assert_conversion(m, out, {"quad": "triangle"})
    parent = out.cell_refs["triangle"]
    assert (out.cell_data["id"]["triangle"] == 10 * parent).all()
    assert (out.cell_data["w"]["triangle"] == parent + 0.5).all()
    assert np.allclose(out.point_data["f"], out.points @ [2.0, -1.0] + 3, rtol=1e-14)
    assert ((out.point_refs == 5) == (out.points[:, 0] == 0)).all()
    assert out.n_points == m.n_points + (len(m.cells["quad"]) if quads == 4 else 0)
    if quads == "best":  # the worse triangle is no worse than the other diagonal's
        q = m.cells["quad"]
        w = [triangle_quality(m.points, c[:, [[0, 1, 2], [0, 2, 3]]].reshape(-1, 3)).reshape(-1, 2).max(1)
             for c in (q, q[:, [1, 2, 3, 0]])]
        got = triangle_quality(out.points, out.cells["triangle"]).reshape(-1, 2).max(1)
        assert np.allclose(got, np.minimum(*w), rtol=1e-12)
    if quads == "min":
        tri = out.cells["triangle"].reshape(-1, 2, 3)
        low = m.cells["quad"].min(1)[:, None]
        assert ((tri[:, 0] == low).any(1) & (tri[:, 1] == low).any(1)).all()  # the cut goes through it


def test_nonconvex_quad():
    dart = Mesh([[0, 0], [2, 1], [0, 2], [0.5, 1]], {"quad": [[0, 1, 2, 3]]})  # reflex at 3
    with pytest.raises(WarpMeshError, match="quads='best'"):
        convert_cells(dart, "triangle", quads="min")
    out = convert_cells(dart, "triangle")
    assert np.isclose(check_cells(out)["measure"], cell_measures(dart.points, dart.cells["quad"], "quad")[0],
                      rtol=1e-12)


def test_triangle_to_quad_2d():
    rng = np.random.default_rng(2)
    pts, tri = delaunay2d(rng)
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    key, cnt = np.unique(np.sort(e, 1), axis=0, return_counts=True)
    m = with_refs(Mesh(pts, {"triangle": tri, "line": key[cnt == 1]}))
    m = m.replace(point_data={"f": pts @ [1.0, 4.0], "tag": (pts[:, 1] == 0).astype(np.int64)},
                  point_refs=np.where(pts[:, 1] == 0, 3, 1))
    out = convert_cells(m, "quad")
    nt, nl = len(tri), len(m.cells["line"])
    assert len(out.cells["quad"]) == 3 * nt and len(out.cells["line"]) == 2 * nl
    n_edges = len(key)
    assert out.n_points == m.n_points + n_edges + nt  # one midpoint per edge, one centroid each
    assert_conversion(m, out, {"triangle": "quad"})
    # the split lines are exactly the quads' boundary edges
    q = out.cells["quad"]
    qe = np.concatenate([q[:, [j, (j + 1) % 4]] for j in range(4)])
    k2, c2 = np.unique(np.sort(qe, 1), axis=0, return_counts=True)
    assert canonical(np.sort(out.cells["line"], 1)) == canonical(k2[c2 == 1])
    assert (out.cell_refs["line"] == np.repeat(m.cell_refs["line"], 2)).all()
    assert np.allclose(out.point_data["f"], out.points @ [1.0, 4.0], rtol=1e-14)
    on = out.points[:, 1] == 0
    assert ((out.point_refs == 3) == on).all() and (out.point_refs[: m.n_points] == m.point_refs).all()
    assert np.isin(out.point_refs[~on], [0, 1]).all()  # 1 between two interior vertices, else 0
    assert (out.point_data["tag"] == on).all()


# ----------------------------------------------------------------------------- 3D -> tetra
@pytest.mark.parametrize("hexes", ["auto", 6, 5])
def test_hex_grid_to_tetra(hexes):
    rng = np.random.default_rng(3)
    m = with_refs(hex_grid(10, rng))
    m = m.replace(point_data={"f": m.points @ [1.0, 2.0, 3.0]})
    out = convert_cells(m, "tetra", hexes=hexes)
    nh = len(m.cells["hexahedron"])
    n5, n6, n12 = (out.info[f"n_hex{k}"] for k in (5, 6, 12))
    assert n5 + n6 + n12 == nh and len(out.cells["tetra"]) == 5 * n5 + 6 * n6 + 12 * n12
    assert len(out.cells["triangle"]) == 2 * len(m.cells["quad"]) and out.n_points == m.n_points
    h = m.cells["hexahedron"]
    cfg = ((h[:, HEX_FACES].argmin(2) % 2) << np.arange(6)).sum(1)
    five = np.isin(cfg, [c for c, s in zip(HEX_SPLIT_CONFIGS, HEX_SPLITS) if len(s) == 5])
    expected = {"auto": (five.sum(), nh - five.sum(), 0), 6: (0, nh, 0), 5: (nh, 0, 0)}[hexes]
    assert (n5, n6, n12) == expected
    assert_conversion(m, out, {"hexahedron": "tetra", "quad": "triangle"})
    tets, parent = out.cells["tetra"], out.cell_refs["tetra"]
    assert (tets[:, :, None] == h[parent][:, None, :]).any(2).all()  # children use parents' vertices
    assert (out.cell_data["w"]["tetra"] == parent + 0.5).all()
    if hexes == 5:  # one central tetrahedron (a third of the volume) per hexahedron, both variants
        share = cell_measures(out.points, tets, "tetra") / cell_measures(m.points, h, "hexahedron")[parent]
        central = np.isclose(share, 1 / 3, rtol=1e-9)
        assert np.isclose(share[~central], 1 / 6, rtol=1e-9).all() and central.sum() == nh
        local = np.sort((tets[central][:, :, None] == h[parent[central]][:, None, :]).argmax(2), 1)
        variants = {tuple(r) for r in local.tolist()}
        assert variants == {(0, 2, 5, 7), (1, 3, 4, 6)}


def test_hexbeam_to_tetra():
    m = Mesh.from_pyvista(pv.examples.load_hexbeam())
    m = with_refs(m.replace(cells={**m.cells, "quad": boundary(m.cells)["quad"]}, cell_data={}))
    for hexes in ("auto", 5):
        out = convert_cells(m, "tetra", hexes=hexes)
        assert_conversion(m, out, {"hexahedron": "tetra", "quad": "triangle"})
        for name, arr in m.point_data.items():
            assert np.array_equal(out.point_data[name], arr)  # no new points
    # quads="min" on the surface alone cuts the quads as the tetrahedral conversion does
    surface = Mesh(m.points, {"quad": m.cells["quad"]})
    tri = convert_cells(surface, "triangle", quads="min").cells["triangle"]
    assert canonical(tri) == canonical(convert_cells(m, "tetra").cells["triangle"])
    best = convert_cells(surface, "triangle").cells["triangle"]
    assert np.isclose(cell_measures(m.points, best, "triangle").sum(),
                      cell_measures(m.points, m.cells["quad"], "quad").sum(), rtol=1e-12)


def test_odd_cycle_hexes5_raises_auto_works():
    """Three hexahedra around a triangular hole: an odd cycle, so no alternating 5-split."""
    ang = np.pi / 2 + np.arange(3) * 2 * np.pi / 3
    ring = np.concatenate([np.c_[np.cos(ang), np.sin(ang)], 3 * np.c_[np.cos(ang), np.sin(ang)]])
    quads = np.array([[i, (i + 1) % 3, 3 + (i + 1) % 3, 3 + i] for i in range(3)])
    pts = np.concatenate([np.c_[ring, np.zeros(6)], np.c_[ring, np.ones(6)]])
    hexes = np.concatenate([quads, quads + 6], 1)
    neg = cell_measures(pts, hexes, "hexahedron") < 0
    hexes[neg] = hexes[neg][:, [0, 3, 2, 1, 4, 7, 6, 5]]
    m = with_refs(Mesh(pts, {"hexahedron": hexes}))
    with pytest.raises(ValueError, match="hexes='auto'"):
        convert_cells(m, "tetra", hexes=5)
    out = convert_cells(m, "tetra")
    assert_conversion(m, out, {"hexahedron": "tetra"})


def test_wedges_to_tetra():
    rng = np.random.default_rng(4)
    pts, tri = delaunay2d(rng, 80)
    m = with_refs(renumber(extruded(tri, pts, 4), rng))
    out = convert_cells(m, "tetra")
    assert len(out.cells["tetra"]) == 3 * len(m.cells["wedge"])
    assert (out.cells["triangle"][: len(m.cells["triangle"])] == m.cells["triangle"]).all()  # kept
    assert len(out.cells["triangle"]) == len(m.cells["triangle"]) + 2 * len(m.cells["quad"])
    assert_conversion(m, out, {"wedge": "tetra", "quad": "triangle"})


def test_mixed_hex_wedge_pyramid():
    rng = np.random.default_rng(5)
    # quads and triangles in 2D: a grid whose last column of squares is cut in two
    g = quad_grid(rng, n=4, jitter=0.0)
    q = g.cells["quad"]
    last = g.points[q].mean(1)[:, 0] > 3
    tri = np.concatenate([q[last][:, [0, 1, 2]], q[last][:, [0, 2, 3]]])
    hw = extruded(tri, g.points, 3, quads2d=q[~last])
    # a cube of 6 pyramids (apex at its centre) glued to one hexahedron
    cube2 = np.concatenate([CUBE, CUBE + [1, 0, 0], [[1.5, 0.5, 0.5]]])
    pyr = np.array([[f[0] + 8, f[1] + 8, f[2] + 8, f[3] + 8, 16] for f in HEX_FACES[:, ::-1].tolist()])
    neg = cell_measures(cube2, pyr, "pyramid") < 0
    pyr[neg] = pyr[neg][:, [0, 3, 2, 1, 4]]
    # glue: points of the second cube that coincide with the first's
    _, ids = np.unique(cube2.round(9), axis=0, return_inverse=True)
    uniq, first = np.unique(ids.ravel(), return_index=True)
    remap = np.searchsorted(uniq, ids.ravel())
    pts = cube2[first]
    cells = {"hexahedron": remap[np.arange(8)][None], "pyramid": remap[pyr]}
    cells["quad"] = boundary(cells)["quad"]
    cells["triangle"] = boundary(cells)["triangle"]
    hp = Mesh(pts, cells)
    for mesh, seed in ((hw, 6), (hp, 7)):
        for s in range(3):
            m = with_refs(renumber(mesh, np.random.default_rng(seed * 10 + s)))
            out = convert_cells(m, "tetra")
            volume = {t: "tetra" for t in ("hexahedron", "wedge", "pyramid") if t in m.cells}
            assert_conversion(m, out, {"quad": "triangle", **volume})
    m = with_refs(renumber(hp, rng))
    out = convert_cells(m, "tetra", hexes=5)  # the face shared with a pyramid fixes the variant
    assert out.info["n_hex5"] == 1
    assert_conversion(m, out, {"hexahedron": "tetra", "pyramid": "tetra"})


def test_steiner_fallback_for_distorted_hex():
    """A valid but distorted hexahedron whose every min-index split inverts a tetrahedron
    gets 12 tetrahedra around its centroid, still conforming with a regular neighbour glued
    on its face 1-2-6-5 and with the boundary quads."""
    rng = np.random.default_rng(0)
    h = np.array([[0, 1, 2, 3, 4, 5, 6, 7], [1, 8, 9, 2, 5, 10, 11, 6]])
    cand = [HEX_SPLITS[i] for i in np.flatnonzero(HEX_SPLIT_CONFIGS == hex_configurations(h)[0])]
    steiner = steiner_split(hex_configurations(h)[0])
    steiner[steiner == 8] = 12  # the centre, appended below
    for _ in range(2000):
        x = CUBE + rng.normal(0, 0.3, CUBE.shape)
        x = np.concatenate([x, x[[1, 2, 5, 6]] + [1.5, 0, 0], x.mean(0, keepdims=True)])
        if ((corner_jacobians(x, h, "hexahedron") > 0).all()
                and all((cell_measures(x, s, "tetra") <= 0).any() for s in cand)
                and (cell_measures(x, steiner, "tetra") > 0).all()):
            break
    else:
        pytest.fail("no distorted hexahedron found")
    x = x[:12]
    m = Mesh(x, {"hexahedron": h, "quad": boundary({"hexahedron": h})["quad"]})
    out = convert_cells(m, "tetra")
    assert out.info["n_hex12"] >= 1 and out.n_points == 12 + out.info["n_hex12"]
    assert np.allclose(out.points[12], x[:8].mean(0))
    assert len(out.cells["tetra"]) == sum(k * out.info[f"n_hex{k}"] for k in (5, 6, 12))
    r = check_cells(out)  # the tetrahedra's boundary is exactly the triangles the quads became
    assert r["n_boundary"] == len(out.cells["triangle"]) == 2 * len(m.cells["quad"])
    area = cell_measures(out.points, out.cells["triangle"], "triangle").sum()
    assert np.isclose(r["boundary_measure"], area, rtol=1e-12)
    assert_faces_of_volume(out)


# ----------------------------------------------------------------------------- tetra -> hexahedron
@pytest.fixture(scope="module")
def box_tets() -> Mesh:
    tetgen = pytest.importorskip("tetgen")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # tetgen reads a deprecated pyvista array
        nodes, elems = tetgen.TetGen(pv.Cube().triangulate().subdivide(2)).tetrahedralize(
            order=1, mindihedral=15, minratio=1.5)[:2]
    cells = {"tetra": elems.astype(np.int64)}
    cells["triangle"] = boundary(cells)["triangle"]
    return Mesh(nodes, cells)


def test_tetra_to_hexahedron(box_tets):
    rng = np.random.default_rng(8)
    m = with_refs(renumber(box_tets, rng))
    low = np.isclose(m.points[:, 0], -0.5)
    m = m.replace(point_refs=np.where(low, 7, 2), point_data={"f": m.points @ [1.0, -2.0, 0.5]})
    out = convert_cells(m, "hexahedron")
    nt = len(m.cells["tetra"])
    assert len(out.cells["hexahedron"]) == 4 * nt and len(out.cells["quad"]) == 3 * len(m.cells["triangle"])
    e = np.unique(np.sort(m.cells["tetra"][:, reference_cell("tetra").edges].reshape(-1, 2), 1), axis=0)
    tet_faces = np.array(reference_cell("tetra").faces)
    f = np.unique(np.sort(m.cells["tetra"][:, tet_faces].reshape(-1, 3), 1), axis=0)
    assert out.n_points == m.n_points + len(e) + len(f) + nt
    assert_conversion(m, out, {"tetra": "hexahedron", "triangle": "quad"})
    assert np.allclose(out.point_data["f"], out.points @ [1.0, -2.0, 0.5], atol=1e-14)
    on = np.isclose(out.points[:, 0], -0.5, atol=1e-14)
    assert ((out.point_refs == 7) == on).all()
    assert np.isin(out.point_refs[~on], [0, 2]).all() and (out.point_refs[: m.n_points][~low] == 2).all()
    # each hexahedron lies in its parent tetrahedron (barycentric coordinates of its centre)
    x = m.points[m.cells["tetra"][out.cell_refs["hexahedron"]]]
    c = out.points[out.cells["hexahedron"]].mean(1)
    lam = np.linalg.solve(np.transpose(x[:, 1:] - x[:, :1], (0, 2, 1)), (c - x[:, 0])[..., None])[..., 0]
    assert (lam > 0).all() and (lam.sum(1) < 1).all()


def test_tetra_to_hex_to_tetra_roundtrip(box_tets):
    out = convert_cells(convert_cells(box_tets, "hexahedron"), "tetra")
    assert np.isclose(check_cells(out)["measure"], check_cells(box_tets)["measure"], rtol=1e-12)
    assert_faces_of_volume(out)


# ----------------------------------------------------------------------------- bad inputs
def test_bad_inputs():
    tri = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
    with pytest.raises(ValueError, match="'target'"):
        convert_cells(tri, "polygon")
    with pytest.raises(ValueError, match="'quads'"):
        convert_cells(tri, "triangle", quads=3)
    with pytest.raises(ValueError, match="'hexes'"):
        convert_cells(tri, "tetra", hexes=7)
    with pytest.raises(ValueError, match="only with target='triangle'"):
        convert_cells(tri, "tetra", quads=4)
    with pytest.raises(ValueError, match="higher-order"):
        convert_cells(tri.to_order(2), "quad")
    with pytest.raises(TypeError, match="Mesh"):
        convert_cells(tri.points, "quad")


def test_kept_blocks_and_inverted_parent():
    """A tetra block already there comes first in the tetra block; an inverted parent raises."""
    cube = Mesh(CUBE, {"hexahedron": [np.arange(8)]})
    tet = np.array([[0.0, 0, 2], [1, 0, 2], [0, 1, 2], [0, 0, 3]])
    m = Mesh(np.concatenate([CUBE, tet]), {"tetra": [[8, 9, 10, 11]], "hexahedron": [np.arange(8)],
                                           "vertex": [[11]]}, cell_refs={"tetra": [4], "hexahedron": [9]})
    out = convert_cells(m, "tetra")
    assert list(out.cells) == ["tetra", "vertex"] and out.cells["tetra"][0].tolist() == [8, 9, 10, 11]
    assert out.cell_refs["tetra"].tolist() == [4] + [9] * (len(out.cells["tetra"]) - 1)
    assert out.cell_refs["vertex"].tolist() == [0]
    assert np.isclose(check_cells(out)["measure"], 1 + 1 / 6, rtol=1e-12)
    assert out.info["n_split"] == {"hexahedron": 1} and check_cells(convert_cells(cube, "tetra"))
    inverted = Mesh(tet, {"tetra": [[0, 2, 1, 3]]})
    with pytest.raises(WarpMeshError, match="positively oriented"):
        convert_cells(inverted, "hexahedron")


def test_nothing_to_split_says_so():
    """(A 2D triangle mesh converted "to tetra" came back unchanged without a word.)"""
    square = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
    with pytest.warns(UserWarning, match=r"convert to 'tetra': the mesh has no 'hexahedron' .* cells to split"):
        same = square.convert("tetra")
    assert same.cells["triangle"].tolist() == square.cells["triangle"].tolist()
