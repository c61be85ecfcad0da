"""warpmesh.modify.transforms: geometric transformations [FG §17.1.1, Remarks 17.1-17.2, §17.5]."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import pyvista as pv
import trimesh

import warpmesh as wm
from warpmesh.mesh import CELL_TYPES, Mesh
from warpmesh.numbering.high_order import jacobians
from warpmesh.cells.reference import (base_type, cell_measures, corner_jacobians, node_weights,
                                      reference_cell, weighted_nodes)
from warpmesh.modify.transforms import (compose, dilation, matrix, rotation, symmetry, transform,
                                 translation)

from tests.helpers.cellcheck import check_cells

RNG = np.random.default_rng(17)


# ----------------------------------------------------------------------------- closed forms
def rodrigues(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def apply(t, p):
    """Points (n, d) through a homogeneous matrix, written out as [FG eq. 17.1]."""
    p = np.atleast_2d(np.asarray(p, float))
    h = np.column_stack([p, np.ones(len(p))]) @ np.asarray(t).T
    return h[:, :-1]


def test_translation_closed_form():
    for v in ([2.0, -3.0], [1.5, -2.0, 4.0]):
        t = translation(v)
        d = len(v)
        expect = np.eye(d + 1)
        expect[:d, d] = v
        assert t.dtype == np.float64 and np.array_equal(t, expect)
        assert np.allclose(apply(t, [[1.0] * d]), np.add(1.0, v))


def test_dilation_closed_form():
    a, c = np.array([2.0, -0.5, 3.0]), np.array([1.0, 2.0, -1.0])
    t = dilation(a, center=c)
    expect = np.eye(4)
    expect[[0, 1, 2], [0, 1, 2]] = a
    expect[:3, 3] = c * (1 - a)  # the book's last column
    assert np.allclose(t, expect)
    assert np.allclose(apply(t, c), c)  # the centre is fixed
    p = RNG.normal(size=(5, 3))
    assert np.allclose(apply(t, p) - c, (p - c) * a)
    assert np.allclose(dilation(2.0, dim=2), np.diag([2.0, 2.0, 1.0]))
    assert np.allclose(dilation(3, center=[1, 1]), dilation([3, 3], center=[1, 1]))
    assert dilation(np.float32(2), dim=3).shape == (4, 4)


def test_rotation_2d_closed_form():
    for alpha in (0.3, -2.0, np.pi):
        r = rotation(alpha)
        c, s = np.cos(alpha), np.sin(alpha)
        assert np.allclose(r, [[c, -s, 0], [s, c, 0], [0, 0, 1]])
    p, alpha = np.array([2.0, -1.0]), 0.7
    r = rotation(alpha, center=p)
    assert np.allclose(apply(r, p), p)  # Remark 17.1: the centre is fixed
    q = RNG.normal(size=(4, 2))
    assert np.allclose(apply(r, q), (q - p) @ rotation(alpha)[:2, :2].T + p)
    assert np.allclose(apply(rotation(np.pi / 2), [1, 0]), [0, 1])  # counter-clockwise


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rotation_about_coordinate_axes_matches_seed(axis):
    alpha = 0.9
    c, s = np.cos(alpha), np.sin(alpha)
    seed = {0: [[1, 0, 0], [0, c, -s], [0, s, c]],  # the book's three matrices
            1: [[c, 0, s], [0, 1, 0], [-s, 0, c]],
            2: [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
    e = np.eye(3)[axis]
    assert np.allclose(rotation(alpha, axis=e)[:3, :3], seed)
    assert np.allclose(rotation(alpha, axis=-3 * e)[:3, :3], np.array(seed).T)  # turns back


def test_rotation_3d_matches_rodrigues():
    axes = np.concatenate([RNG.normal(size=(300, 3)), np.eye(3), -np.eye(3),
                           [[-1, -2, -3], [-1, 2, 0], [0, -1, 5], [3, 0, -1], [0, 0, 1e-9]]])
    angles = RNG.uniform(-2 * np.pi, 2 * np.pi, len(axes))
    for a, alpha in zip(axes, angles, strict=True):  # a loop over test cases
        r = rotation(alpha, axis=a)
        assert np.allclose(r[:3, :3], rodrigues(a, alpha), atol=1e-14), (a, alpha)
        assert np.array_equal(r[3], [0, 0, 0, 1]) and np.allclose(r[:3, 3], 0)
        assert np.isclose(np.linalg.det(r), 1.0)
    # about a point: T(P) R T(-P), the axis through P is fixed
    a, p, alpha = np.array([1.0, -2.0, 0.5]), np.array([0.3, 1.0, -2.0]), 1.1
    r = rotation(alpha, center=p, axis=a)
    line = p + np.linspace(-2, 2, 5)[:, None] * a
    assert np.allclose(apply(r, line), line)
    q = RNG.normal(size=(6, 3))
    assert np.allclose(apply(r, q), (q - p) @ rodrigues(a, alpha).T + p)


def test_symmetry_closed_form_involution_fixed_points():
    for coef in ([1.0, 2.0, -3.0], [2.0, -1.0, 0.5, 4.0], [0.0, 0.0, 1.0, -2.0]):
        t = symmetry(coef)
        n, k = np.array(coef[:-1]), coef[-1]
        f = -2.0 / (n @ n)
        d = len(n)
        expect = np.eye(d + 1)  # the book's matrix, entry by entry
        for i, j in itertools.product(range(d), range(d)):
            expect[i, j] = (i == j) + n[i] * n[j] * f
        expect[:d, d] = n * k * f
        assert np.allclose(t, expect)
        assert np.allclose(t @ t, np.eye(d + 1))  # an involution
        assert np.isclose(np.linalg.det(t), -1.0)
        # points of the line/plane are fixed; a point off it maps to the other side
        q = RNG.normal(size=(8, d))
        on = q - ((q @ n + k) / (n @ n))[:, None] * n
        assert np.allclose(apply(t, on), on)
        assert np.allclose(apply(t, q) @ n + k, -(q @ n + k))


def test_matrix_general():
    shear = [[1.0, 0.5], [0.0, 1.0]]
    m = matrix(shear)
    assert m.shape == (3, 3) and np.allclose(m[:2, :2], shear) and np.allclose(m[:2, 2], 0)
    h = rotation(0.4, axis=[1, 1, 0]) @ translation([1, 2, 3])
    assert np.allclose(matrix(h), h)
    assert np.allclose(matrix(np.diag([1, 2, 3]), dim=3), np.diag([1, 2, 3, 1]))
    assert np.allclose(matrix(translation([1, 2]), dim=2), translation([1, 2]))
    # an inverse from np.linalg.inv (last row within rounding) is accepted and undoes the map
    t = compose(rotation(0.3, axis=[1, -2, 2], center=[1, 0, 2]), dilation([1.0, 3.0, 0.5]),
                symmetry([1, 1, 1, -1]))
    inv = matrix(np.linalg.inv(t))
    assert np.array_equal(inv[3], [0, 0, 0, 1])
    mesh = make_mesh("tetra")
    back = transform(transform(mesh, t), inv)
    assert np.allclose(back.points, mesh.points)
    assert all(np.array_equal(back.cells[n], mesh.cells[n]) for n in mesh.cells)


def test_compose_order():
    t, r = translation([1.0, 0.0, 0.0]), rotation(np.pi / 2, axis=[0, 0, 1])
    p = RNG.normal(size=(5, 3))
    assert np.allclose(apply(compose(t, r), p), apply(r, apply(t, p)))  # t first
    assert np.allclose(apply(compose(r, t), p), apply(t, apply(r, p)))
    assert not np.allclose(compose(t, r), compose(r, t))
    s, d = symmetry([1, 1, 0, -1]), dilation([1, 2, 3])
    assert np.allclose(compose(t, r, s, d), d @ s @ r @ t)  # plain arrays: numpy @ composes
    assert np.allclose(compose(s), s)


# ----------------------------------------------------------------------------- meshes
def _grid(d: int, n: int = 3) -> np.ndarray:
    """(n^d, d) lattice points, jittered inside (so no cell is a symmetric special case)."""
    axes = np.meshgrid(*[np.arange(n, dtype=float)] * d, indexing="ij")
    pts = np.stack([a.ravel() for a in axes], axis=1)
    inner = ((pts > 0) & (pts < n - 1)).all(axis=1)
    pts[inner] += RNG.uniform(-0.2, 0.2, (inner.sum(), d))
    return pts * np.arange(1.0, d + 1.0)  # anisotropic box


def _corners(d: int, n: int = 3) -> np.ndarray:
    """(cubes, 2^d) lattice indices of each unit square/cube, bits (x, y[, z])."""
    idx = np.arange(n ** d).reshape((n,) * d)
    lo = np.stack(np.meshgrid(*[np.arange(n - 1)] * d, indexing="ij"), -1).reshape(-1, d)
    bits = np.array(list(itertools.product((0, 1), repeat=d)))
    return idx[tuple((lo[:, None, :] + bits[None]).transpose(2, 0, 1))], bits


def _p1_volume(kind: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Conforming P1 meshes of a jittered box: 2D triangle/quad, 3D tetra (Kuhn),
    hexahedron, wedge, pyramid (six per cube, apex at its centre)."""
    d = 2 if kind in ("triangle", "quad") else 3
    pts = _grid(d)
    c, bits = _corners(d)
    at = {tuple(b): i for i, b in enumerate(bits.tolist())}
    sq = c[:, [at[(0, 0)], at[(1, 0)], at[(1, 1)], at[(0, 1)]]] if d == 2 else None
    if kind == "quad":
        return pts, {"quad": sq}
    if kind == "triangle":
        return pts, {"triangle": np.concatenate([sq[:, [0, 1, 2]], sq[:, [0, 2, 3]]])}
    hexa = c[:, [at[b] for b in [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                                 (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]]]
    if kind == "hexahedron":
        return pts, {"hexahedron": hexa}
    if kind == "wedge":
        return pts, {"wedge": np.concatenate([hexa[:, [0, 1, 2, 4, 5, 6]], hexa[:, [0, 2, 3, 4, 6, 7]]])}
    if kind == "tetra":
        tets = []
        for perm in itertools.permutations(range(3)):
            step, path = np.zeros(3, int), [(0, 0, 0)]
            for a in perm:
                step[a] = 1
                path.append(tuple(step))
            t = c[:, [at[p] for p in path]]
            odd = np.linalg.det(np.eye(3)[list(perm)]) < 0
            tets.append(t[:, [0, 2, 1, 3]] if odd else t)
        return pts, {"tetra": np.concatenate(tets)}
    assert kind == "pyramid"
    centre = pts[hexa].mean(axis=1)
    apex = len(pts) + np.arange(len(hexa))
    faces = np.array(reference_cell("hexahedron").faces)[:, ::-1]  # inward: the apex above
    base = hexa[:, faces]  # (cubes, 6, 4)
    pyr = np.concatenate([base, np.repeat(apex[:, None, None], 6, axis=1)], axis=2)
    return np.concatenate([pts, centre]), {"pyramid": pyr.reshape(-1, 5)}


def _boundary(cells: dict[str, np.ndarray], d: int) -> dict[str, np.ndarray]:
    """Facets used once, oriented as in their cell (outward / domain on the left)."""
    rows = []
    for t, c in cells.items():
        ref = reference_cell(t)
        groups = [ref.edges] if d == 2 else [np.array([f for f in ref.faces if len(f) == k])
                                             for k in (3, 4)]
        rows += [c[:, g].reshape(-1, g.shape[1]) for g in groups if len(g)]
    keys = np.concatenate([np.pad(np.sort(r, 1), ((0, 0), (0, 4 - r.shape[1])), constant_values=-1)
                           for r in rows])
    _, inv, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    once = counts[inv.ravel()] == 1
    out, start = {}, 0
    for r in rows:
        b = r[once[start: start + len(r)]]
        start += len(r)
        out[{2: "line", 3: "triangle", 4: "quad"}[r.shape[1]]] = b
    return {t: b for t, b in out.items() if len(b)}


def _lift(points, cells: dict[str, np.ndarray], types: dict[str, str]):
    """Higher-order blocks (any meshio type) with straight nodes, numbered once across blocks."""
    vs, ws, sizes = [], [], []
    for t, c in cells.items():
        w = np.rint(node_weights(types[t]) * 24).astype(np.int64)  # every table is in 24ths
        m, (nn, nv) = len(c), w.shape
        vs.append(np.pad(np.repeat(c[:, None, :nv], nn, axis=1), ((0, 0), (0, 0), (0, 8 - nv))))
        ws.append(np.pad(np.broadcast_to(w, (m, nn, nv)), ((0, 0), (0, 0), (0, 8 - nv))))
        sizes.append((types[t], m * nn, nn))
    ids, new, _ = weighted_nodes(points, np.concatenate([v.reshape(-1, 8) for v in vs]),
                                 np.concatenate([w.reshape(-1, 8) for w in ws]))
    out, start = {}, 0
    for t, size, nn in sizes:
        out[t] = ids[start: start + size].reshape(-1, nn)
        start += size
    return np.concatenate([points, new]), out


#: volume type -> (P1 type, boundary P1 type -> its higher-order type)
HIGHER = {
    "triangle6": ("triangle", {"line": "line3"}), "triangle10": ("triangle", {"line": "line4"}),
    "triangle15": ("triangle", {"line": "line5"}), "quad8": ("quad", {"line": "line3"}),
    "quad9": ("quad", {"line": "line3"}), "tetra10": ("tetra", {"triangle": "triangle6"}),
    "tetra20": ("tetra", {"triangle": "triangle10"}), "tetra35": ("tetra", {"triangle": "triangle15"}),
    "hexahedron20": ("hexahedron", {"quad": "quad8"}), "hexahedron27": ("hexahedron", {"quad": "quad9"}),
    "wedge15": ("wedge", {"triangle": "triangle6", "quad": "quad8"}),
    "pyramid13": ("pyramid", {"quad": "quad8"}),
}
P1 = ["triangle", "quad", "tetra", "hexahedron", "wedge", "pyramid"]
ALL = P1 + list(HIGHER)
assert set(ALL) == {t for t in CELL_TYPES if CELL_TYPES[t][1] >= 2}  # every 2D/3D type


def make_mesh(kind: str) -> Mesh:
    """A conforming mesh of ``kind`` with its boundary block(s), refs, cell and point data;
    3D meshes also carry a line block and a vertex block (left alone by transform)."""
    base = HIGHER[kind][0] if kind in HIGHER else kind
    pts, vol = _p1_volume(base)
    d = pts.shape[1]
    cells = {**vol, **_boundary(vol, d)}
    if kind in HIGHER:
        pts, cells = _lift(pts, cells, {base: kind, **HIGHER[kind][1]})
    if d == 3:
        cells["line"], cells["vertex"] = np.array([[0, 1], [1, 4]]), np.array([[0], [2]])
    refs = {t: np.arange(len(c)) % 5 + 1 for t, c in cells.items()}
    data = {"id": {t: np.arange(len(c)) * 10 for t, c in cells.items()}}
    return Mesh(pts, cells, cell_refs=refs, cell_data=data, point_refs=np.arange(len(pts)) % 3,
                point_data={"x": pts[:, 0] ** 2}, info={"source": "test"})


def corner_mesh(mesh: Mesh) -> Mesh:
    """The P1 mesh of the cells' corners (what check_cells reads)."""
    blocks = {}
    for t, c in mesh.cells.items():
        b = base_type(t)
        blocks[b] = c[:, : len(reference_cell(b).vertices)]
    return Mesh(mesh.points, blocks)


def valid(mesh: Mesh) -> float:
    """check_cells on the corner mesh; its total measure. check_cells cannot yet join the
    triangle and quad faces of wedges and pyramids (np.concatenate of (f, 3) and (f, 4)
    rows), so for those the same orientation and conformity checks are made here (the
    closed boundary is checked by check_boundary_orientation)."""
    m = corner_mesh(mesh)
    if not {"wedge", "pyramid"} & set(m.cells):
        return check_cells(m)["measure"]
    total, keys = 0.0, []
    for t, c in m.cells.items():
        if t == "vertex" or reference_cell(t).tdim != m.dim:
            continue
        assert (corner_jacobians(m.points, c, t) > 0).all(), t
        total += float(cell_measures(m.points, c, t).sum())
        for f in reference_cell(t).faces:
            keys.append(np.pad(np.sort(c[:, list(f)], 1), ((0, 0), (0, 4 - len(f))), constant_values=-1))
    assert np.unique(np.concatenate(keys), axis=0, return_counts=True)[1].max() <= 2
    return total


def measures(mesh: Mesh) -> dict[str, np.ndarray]:
    m = corner_mesh(mesh)
    return {t: cell_measures(m.points, c, t) for t, c in m.cells.items()
            if t != "vertex" and reference_cell(t).tdim == m.dim}


def check_straight_nodes(mesh: Mesh) -> None:
    """Every node where its type's table puts it, relative to the cell's own corners: a node
    permuted differently from its vertices breaks this."""
    for t, c in mesh.cells.items():
        w = node_weights(t)
        x = mesh.points[c]
        assert np.allclose(x, np.einsum("nv,mvd->mnd", w, x[:, : w.shape[1]]), atol=1e-12), t


def check_boundary_orientation(mesh: Mesh) -> None:
    """Each boundary facet is, with its orientation, a facet of a cell: in 2D a directed cell
    edge (domain on the left), in 3D a cell face in the same cyclic order (outward)."""
    m, d = corner_mesh(mesh), mesh.dim
    vol = {t: c for t, c in m.cells.items() if t != "vertex" and reference_cell(t).tdim == d}
    bnd = {t: c for t, c in m.cells.items() if t != "vertex" and reference_cell(t).tdim == d - 1}
    assert bnd
    cell_facets = _facet_rows(vol, d)
    for t, b in bnd.items():
        k = b.shape[1]
        have = {tuple(r) for r in _cyclic_min(cell_facets[k]).tolist()}
        missing = [r for r in _cyclic_min(b).tolist() if tuple(r) not in have]
        assert not missing, f"{len(missing)} of {len(b)} {t} facets are mis-oriented: {missing[:3]}"


def _facet_rows(vol, d):
    rows: dict[int, list] = {}
    for t, c in vol.items():
        ref = reference_cell(t)
        facets = [tuple(e) for e in ref.edges.tolist()] if d == 2 else ref.faces
        for f in facets:
            rows.setdefault(len(f), []).append(c[:, list(f)])
    return {k: np.concatenate(v) for k, v in rows.items()}


def _cyclic_min(rows: np.ndarray) -> np.ndarray:
    """Rows rotated so the smallest index comes first (orientation kept); lines as they are."""
    if rows.shape[1] == 2:
        return rows
    k = rows.shape[1]
    shift = rows.argmin(axis=1)
    return np.take_along_axis(rows, (shift[:, None] + np.arange(k)) % k, axis=1)


def reflections(d: int):
    """Orientation-reversing maps: symmetries, and a non-isometric one."""
    if d == 2:
        return [symmetry([1.0, 2.0, -1.5]), compose(symmetry([0, 1, 0]), dilation([2.0, 0.5])),
                dilation([-1.0, 3.0], center=[1, 1])]
    return [symmetry([1.0, -2.0, 0.5, 0.3]), symmetry([0, 0, 1, 0]),
            dilation([-2.0, 1.0, 3.0], center=[1, 0, 0])]


@pytest.mark.parametrize("kind", ALL)
def test_orientation_reversing_maps_keep_every_type_valid(kind):
    mesh = make_mesh(kind)
    d = mesh.dim
    before, total = measures(mesh), valid(mesh)
    check_boundary_orientation(mesh)  # the fixture is right to begin with
    for t in reflections(d):
        det = abs(np.linalg.det(t[:d, :d]))
        out = transform(mesh, t)
        assert out.info["orientation_reversed"] is True
        assert np.allclose(out.info["transform"], t) and out.info["source"] == "test"
        assert np.allclose(out.points, apply(t, mesh.points))
        after = measures(out)
        for b in before:  # each cell keeps its (positive) measure, scaled by |det|
            assert (after[b] > 0).all() and np.allclose(after[b], det * before[b], rtol=1e-12)
        assert np.isclose(valid(out), det * total)
        check_boundary_orientation(out)
        check_straight_nodes(out)
        lagrange = {k: v for k, v in jacobians(out).items() if k != "line"} if kind not in (
            "wedge", "pyramid", "quad8", "hexahedron20", "wedge15", "pyramid13") else {}
        assert all((s > 0).all() for s in lagrange.values())
        for name, c in out.cells.items():  # which blocks were renumbered
            tdim = CELL_TYPES[name][1]
            if tdim >= d - 1:
                assert not np.array_equal(c, mesh.cells[name]) and np.array_equal(
                    np.sort(c, 1), np.sort(mesh.cells[name], 1)), name
            else:  # lines in 3D, vertices
                assert np.array_equal(c, mesh.cells[name]), name
        assert_attributes_carried(mesh, out)
        # applied twice with a symmetry: the original mesh back
        if np.allclose(t @ t, np.eye(d + 1)):
            back = transform(out, t)
            assert np.allclose(back.points, mesh.points)
            assert all(np.array_equal(back.cells[n], mesh.cells[n]) for n in mesh.cells)


def assert_attributes_carried(mesh: Mesh, out: Mesh) -> None:
    assert list(out.cells) == list(mesh.cells)
    for t in mesh.cells:
        assert np.array_equal(out.cell_refs[t], mesh.cell_refs[t])
        assert np.array_equal(out.cell_data["id"][t], mesh.cell_data["id"][t])
    assert np.array_equal(out.point_refs, mesh.point_refs)
    assert np.array_equal(out.point_data["x"], mesh.point_data["x"])


@pytest.mark.parametrize("kind", ALL)
def test_positive_maps_keep_connectivity_and_measures(kind):
    mesh = make_mesh(kind)
    d = mesh.dim
    before = measures(mesh)
    rigid = (compose(rotation(0.7, center=[1, -1]), translation([3.0, -2.0])) if d == 2 else
             compose(rotation(-2.1, center=[1, 2, 3], axis=[-1, 2, -0.5]), translation([3, -2, 1])))
    for t in (rigid, dilation([-1.0] * (d - 1) + [1.0] if d == 3 else [1.5, 2.0])):
        out = transform(mesh, t)
        assert out.info["orientation_reversed"] is False
        assert all(np.array_equal(out.cells[n], mesh.cells[n]) for n in mesh.cells)
        det = np.linalg.det(t[:d, :d])
        after = measures(out)
        assert all(np.allclose(after[b], det * before[b], rtol=1e-12) for b in before)
        assert np.isclose(valid(out), sum(a.sum() for a in after.values()))
        assert_attributes_carried(mesh, out)


def test_fig_17_14_side_attributes():
    """Fig. 17.14: a quad whose sides carry attributes 1, 2, 3, 4 (boundary lines with refs).
    After a translation the element's local sides read 1, 2, 3, 4; after a symmetry they read
    the attributes in the reversed cyclic order (the book's 1, 4, 3, 2 up to the starting
    side), while each ref stays on the image of its own side and the lines keep the domain on
    their left."""
    quad = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]],
                {"quad": [[0, 1, 2, 3]], "line": [[0, 1], [1, 2], [2, 3], [3, 0]]},
                cell_refs={"quad": [9], "line": [1, 2, 3, 4]})

    def side_refs(m):
        lines = {frozenset(r): ref for r, ref in zip(m.cells["line"].tolist(),
                                                       m.cell_refs["line"].tolist(), strict=True)}
        q = m.cells["quad"][0].tolist()
        return [lines[frozenset((q[i], q[(i + 1) % 4]))] for i in range(4)]

    moved = transform(quad, translation([5, 1]))
    assert side_refs(moved) == [1, 2, 3, 4]
    mirrored = transform(quad, symmetry([1, 0, 0]))  # about x = 0
    refs = side_refs(mirrored)
    assert refs != [1, 2, 3, 4] and any(refs == [1, 4, 3, 2][k:] + [1, 4, 3, 2][:k] for k in range(4))
    for m, t in ((moved, translation([5, 1])), (mirrored, symmetry([1, 0, 0]))):
        mid = m.points[m.cells["line"]].mean(axis=1)
        assert np.allclose(mid, apply(t, quad.points[quad.cells["line"]].mean(axis=1)))
        check_boundary_orientation(m)


def test_closed_surface_normals_stay_outward():
    sphere = wm.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions=2))
    v0 = sphere.stats()["volume"]
    assert v0 > 0
    for t in (symmetry([1, 2, -1, 0.5]), dilation([1, 1, -2]), rotation(1.0, axis=[1, 1, 1])):
        det = np.linalg.det(t[:3, :3])
        out = transform(sphere, t)
        s = out.stats()
        assert s["watertight"] and s["oriented"]
        assert s["volume"] > 0 and np.isclose(s["volume"], abs(det) * v0)
        # each face normal still points away from the centre (the sphere's image is centred
        # at t's image of the origin)
        tri = out.points[out.triangles]
        normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        centre = apply(t, np.zeros(3))[0]
        assert (np.einsum("ij,ij->i", normal, tri.mean(axis=1) - centre) > 0).all()


def test_surface_mesh_normals_map_as_vectors():
    """An open surface in 3D: after a symmetry the face normals are the mirrored normals."""
    tm = trimesh.creation.icosphere(subdivisions=1)
    patch = Mesh(tm.vertices, {"triangle": tm.faces[tm.vertices[tm.faces][:, :, 2].mean(1) > 0]})
    t = symmetry([1, 0, 0, -0.5])

    def normals(m):
        p = m.points[m.triangles]
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    assert np.allclose(normals(transform(patch, t)), normals(patch) @ t[:3, :3].T)


def test_real_hexbeam_reflected_stays_valid():
    beam = Mesh.from_pyvista(pv.examples.load_hexbeam())
    assert "hexahedron" in beam.cells
    before = check_cells(beam)
    out = transform(beam, symmetry([1.0, 0.3, -0.2, 0.7]))
    after = check_cells(out)
    assert np.isclose(after["measure"], before["measure"], rtol=1e-12) and after["measure"] > 0
    assert np.isclose(after["boundary_measure"], before["boundary_measure"], rtol=1e-12)


def test_vectors_option_maps_named_point_data():
    mesh = make_mesh("triangle")
    v = RNG.normal(size=(mesh.n_points, 2))
    mesh = mesh.replace(point_data={"x": mesh.point_data["x"], "v": v})
    for t in (rotation(0.8, center=[5, 5]), symmetry([1, 1, 3])):
        out = transform(mesh, t, vectors=("v",))
        assert np.allclose(out.point_data["v"], v @ t[:2, :2].T)  # no translation part
        assert np.array_equal(out.point_data["x"], mesh.point_data["x"])
    assert np.array_equal(transform(mesh, rotation(0.8)).point_data["v"], v)  # not by default


def test_info_records_matrix_and_replaces_previous():
    mesh = make_mesh("quad")
    t1, t2 = translation([1, 0]), symmetry([1, 0, 0])
    out = transform(transform(mesh, t1), t2)
    assert out.info["transform"] == t2.tolist() and out.info["orientation_reversed"] is True
    assert out.stats()["orientation_reversed"] is True  # info is merged into stats()


# ----------------------------------------------------------------------------- bad input
def test_bad_vectors():
    with pytest.raises(ValueError, match="finite"):
        translation([1.0, np.nan])
    with pytest.raises(ValueError, match="2 or 3 components"):
        translation([1.0, 2.0, 3.0, 4.0])
    with pytest.raises(TypeError, match="real numbers"):
        translation(["a", "b"])
    with pytest.raises(ValueError, match="2 or 3 components"):
        translation([[1.0, 2.0]])


def test_bad_dilation():
    with pytest.raises(ValueError, match="'dim'"):
        dilation(2.0)
    with pytest.raises(ValueError, match="non-zero"):
        dilation([1.0, 0.0])
    with pytest.raises(ValueError, match="'center'"):
        dilation([1.0, 2.0], center=[0, 0, 0])
    with pytest.raises(ValueError, match="dim 2 or 3"):
        dilation(2.0, dim=4)
    with pytest.raises(ValueError, match="3 factors"):
        dilation([1.0, 2.0], dim=3)
    with pytest.raises(TypeError, match="real number"):
        dilation(True, dim=2)


def test_bad_rotation():
    with pytest.raises(ValueError, match="non-zero 'axis'"):
        rotation(1.0, axis=[0, 0, 0])
    with pytest.raises(ValueError, match="3 components for 'axis'"):
        rotation(1.0, axis=[1, 0])
    with pytest.raises(ValueError, match="'axis'"):
        rotation(1.0, center=[0, 0, 0])
    with pytest.raises(ValueError, match="finite 'angle'"):
        rotation(np.nan)
    with pytest.raises(TypeError, match="'angle'"):
        rotation("90")
    with pytest.raises(ValueError, match="finite"):
        rotation(1.0, axis=[1, np.inf, 0])
    with pytest.raises(ValueError, match="3 components for 'center'"):
        rotation(1.0, axis=[0, 0, 1], center=[1, 2])


def test_bad_symmetry():
    with pytest.raises(ValueError, match="non-zero normal"):
        symmetry([0, 0, 0, 1])
    with pytest.raises(ValueError, match="non-zero normal"):
        symmetry([0, 0, 1])
    with pytest.raises(ValueError, match="3 or 4"):
        symmetry([1, 2])


def test_bad_matrix():
    with pytest.raises(ValueError, match="non-singular"):
        matrix([[1.0, 2.0], [2.0, 4.0]])
    with pytest.raises(ValueError, match="non-singular"):
        matrix(np.diag([1.0, 1e-20, 1.0, 1.0]))
    with pytest.raises(ValueError, match="last row"):
        matrix([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 0, 0, 1]])
    with pytest.raises(ValueError, match="finite"):
        matrix([[1.0, np.nan], [0.0, 1.0]])
    with pytest.raises(ValueError, match="dim=2"):
        matrix(np.eye(3))
    with pytest.raises(ValueError, match="shape"):
        matrix(np.eye(5))
    with pytest.raises(ValueError, match="dim=3"):
        matrix(np.eye(4), dim=2)
    with pytest.raises(TypeError, match="real matrix"):
        matrix([["a", "b"], ["c", "d"]])


def test_bad_compose():
    with pytest.raises(ValueError, match="at least one"):
        compose()
    with pytest.raises(ValueError, match="one dimension"):
        compose(translation([1, 2]), translation([1, 2, 3]))
    with pytest.raises(ValueError, match="last row"):
        compose(translation([1, 2]), np.ones((3, 3)))


def test_bad_transform():
    m3, m2 = make_mesh("tetra"), make_mesh("triangle")
    with pytest.raises(TypeError, match="Mesh"):
        transform(m3.points, translation([1, 2, 3]))
    with pytest.raises(ValueError, match=r"4x4 matrix .* 3x3 one \(a 2D transformation\); build it in 3D"):
        transform(m3, rotation(0.5))
    with pytest.raises(ValueError, match="3x3 matrix .* 2D mesh, got a 4x4"):
        transform(m2, translation([1, 2, 3]))
    with pytest.raises(ValueError, match="non-singular"):
        transform(m2, np.diag([1.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="shape"):
        transform(m2, np.eye(2))
    with pytest.raises(ValueError, match="point_data"):
        transform(m2, rotation(0.5), vectors=("nope",))
    with pytest.raises(ValueError, match=r"shape \(\d+, 2\)"):
        transform(m2, rotation(0.5), vectors=("x",))  # a scalar field
    with pytest.raises(TypeError, match="list or tuple"):
        transform(m2, rotation(0.5), vectors="x")
