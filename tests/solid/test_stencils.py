"""The stencil tables of isosurface stuffing, checked pattern by pattern: positive volumes for
any cut positions, the inside and outside stencils tiling the tetrahedron, quadrilateral
diagonals that depend on the lattice face alone, and the lattice layout."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from warpmesh.solid.lattice import lattice_tables, node_coordinates
from warpmesh.solid.stencils import EDGES, REFERENCE_TET, sign_code, stencil, stencil_tables

PATTERNS = list(itertools.product((-1, 0, 1), repeat=4))
RNG = np.random.default_rng(7)


def _positions(tet: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(10, 3): the 4 vertices and a cut point at fraction t[e] along each edge."""
    return np.vstack([tet, [tet[a] + t[e] * (tet[b] - tet[a]) for e, (a, b) in enumerate(EDGES)]])


def _volume(pos: np.ndarray, tets) -> np.ndarray:
    p = pos[np.asarray(tets, dtype=np.int64)]
    return np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6.0


def _expected_count(signs) -> int:
    plus, zero, minus = (sum(1 for s in signs if s == v) for v in (1, 0, -1))
    if not plus:
        return 0
    if not minus or plus == 1:
        return 1
    return 2 if (plus, zero) == (2, 1) else 3


def test_tables_are_the_stencils_and_count_by_pattern():
    count, tets = stencil_tables()
    assert count.shape == (81 * 16,) and tets.shape == (81 * 16, 3, 4)
    for signs in PATTERNS:
        for bits in range(16):
            case = sign_code(signs) * 16 + bits
            out = stencil(signs, bits)
            assert count[case] == len(out) == _expected_count(signs), (signs, bits)
            assert tets[case, :len(out)].tolist() == [list(t) for t in out]


@pytest.mark.parametrize("signs", [s for s in PATTERNS if 1 in s])
def test_every_stencil_tetrahedron_is_positive_for_any_cut_positions(signs):
    count, tets = stencil_tables()
    for bits in range(16):
        case = sign_code(signs) * 16 + bits
        for _ in range(20):
            pos = _positions(REFERENCE_TET, RNG.uniform(0.02, 0.98, 6))
            vol = _volume(pos, tets[case, :count[case]])
            assert (vol > 0).all(), (signs, bits, vol)
            for ref in tets[case, :count[case]].ravel():  # only cut points of sign-changing edges
                if ref >= 4:
                    a, b = EDGES[ref - 4]
                    assert signs[a] * signs[b] < 0, (signs, ref)


@pytest.mark.parametrize("signs", [s for s in PATTERNS if 1 in s and -1 in s])
def test_inside_and_outside_stencils_tile_the_tetrahedron(signs):
    """With a linear field (planar cuts), the stencil of the pattern and of its negation
    fill the tetrahedron exactly: no gap, no overlap, whatever the diagonals."""
    count, tets = stencil_tables()
    whole = _volume(REFERENCE_TET, [[0, 1, 2, 3]])[0]
    neg = tuple(-s for s in signs)
    for bits in range(16):
        for _ in range(10):
            f = np.where(np.array(signs) == 0, 0.0, np.array(signs) * RNG.uniform(0.05, 1.0, 4))
            t = np.array([f[a] / (f[a] - f[b]) if f[a] * f[b] < 0 else 0.5 for a, b in EDGES])
            pos = _positions(REFERENCE_TET, t)
            total = 0.0
            for s in (signs, neg):
                case = sign_code(s) * 16 + bits
                total += _volume(pos, tets[case, :count[case]]).sum()
            assert total == pytest.approx(whole, rel=1e-12, abs=1e-14), (signs, bits)


def test_layout_tetrahedra_are_the_bcc_lattice():
    layout, slots, bits = lattice_tables()
    vols = []
    for t in range(12):
        pos = np.array([node_coordinates(c, o) / 2.0 for c, *o in layout[t]])
        lengths = {frozenset(e): np.linalg.norm(pos[e[0]] - pos[e[1]]) for e in EDGES}
        assert lengths[frozenset((0, 1))] == pytest.approx(1.0) and lengths[frozenset((2, 3))] == pytest.approx(1.0)
        assert sorted(round(v, 9) for v in lengths.values()) == [0.866025404] * 4 + [1.0] * 2
        vols.append(_volume(pos, [[0, 1, 2, 3]])[0])
        for e, (a, b) in enumerate(EDGES):  # the slot's owner and second end are the edge's ends
            dx, dy, dz, d = slots[t, e]
            owner = np.array([dx, dy, dz])
            start = node_coordinates(0 if d < 3 else 1, owner)
            if d < 3:
                end = node_coordinates(0, owner + np.eye(3, dtype=int)[d])
            elif d < 6:
                end = node_coordinates(1, owner + np.eye(3, dtype=int)[d - 3])
            else:
                k = d - 6
                end = node_coordinates(0, owner + np.array([k & 1, (k >> 1) & 1, (k >> 2) & 1]))
            ends = {tuple(node_coordinates(layout[t, v, 0], layout[t, v, 1:])) for v in (a, b)}
            assert {tuple(start), tuple(end)} == ends
    assert np.allclose(vols, 1.0 / 12.0)  # 12 tetrahedra of volume h^3 / 12 fill one cube per black node


def _diagonal_end(t: int, f: int, shift) -> tuple:
    """The lattice node (doubled coordinates) the quadrilateral of long-edge face f of layout t
    is split from, for the black node at ``shift``."""
    from warpmesh.solid.stencils import LONG_FACES

    layout, _, bits = lattice_tables()
    u, v, _w = LONG_FACES[f]
    end = v if (bits[t] >> f) & 1 else u
    return tuple(node_coordinates(layout[t, end, 0], layout[t, end, 1:] + shift))


def test_the_parity_rule_splits_each_lattice_face_the_same_way_from_both_sides():
    from warpmesh.solid.stencils import LONG_FACES

    layout, _, _ = lattice_tables()
    seen: dict = {}
    times: dict = {}
    for shift in itertools.product((-1, 0, 1), repeat=3):
        for t in range(12):
            for f, face in enumerate(LONG_FACES):
                key = frozenset(tuple(node_coordinates(layout[t, x, 0], layout[t, x, 1:] + shift)) for x in face)
                seen.setdefault(key, set()).add(_diagonal_end(t, f, shift))
                times[key] = times.get(key, 0) + 1
    assert sum(1 for k in times if times[k] == 2) > 500  # faces seen from both of their tetrahedra
    assert all(len(v) == 1 for v in seen.values()), "a face split two ways"
