"""Pinch-free snapping of lattice cleaving's cut points (warpmesh/solid/snapping.py).

The oracle of a pinch is tests/solid/test_regions.py's ``pinched_vertices`` (the link of each
vertex of each label's boundary is one cycle), also run by ``check_regions`` on every
multi-region mesh of the suite. Each test here shows the edge-by-edge snapping pinching the
same volume, so the oracle can fail."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from tests.helpers.pinches import pinched_vertices
from tests.solid.test_pockets import NOISY_SPACING, _layer, _noisy
from tests.solid.test_regions import _balls, check_regions
from warpmesh.cells.topology import euler_characteristic
from warpmesh.solid import regions
from warpmesh.solid.snapping import PUSH_BEYOND, snap_cuts


def _edge_by_edge(T, L, cut_id, t, e_lo, e_hi, snap):
    """The snapping before warpmesh/solid/snapping.py: every cut within snap of a node, onto it."""
    return t, t < snap, t > 1.0 - snap, 0


def _pinches(m: wm.Mesh) -> dict[int, int]:
    return pinched_vertices(m.cells["triangle"], m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"])


CASES = {
    "ones": (lambda: np.ones((10, 10, 10), np.uint8), {}),
    "balls": (lambda: _balls(64, (25.0, 12.0)), {"size": 4.0}),
    "layer": (_layer, {"size": 3.0}),
    "noisy": (lambda: wm.Volume(_noisy(30), spacing=NOISY_SPACING), {}),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_no_region_boundary_is_pinched(name, monkeypatch):
    make, options = CASES[name]
    m = wm.mesh_domain(make(), labels="all", **options)
    check_regions(m, rest=0)  # (with the pinch oracle)
    assert m.info["pushed_cuts"] > 0
    monkeypatch.setattr(regions, "snap_cuts", _edge_by_edge)
    before = wm.mesh_domain(make(), labels="all", **options)
    assert _pinches(before), "the edge-by-edge snapping pinched these volumes (the oracle can fail)"


def test_a_cube_of_ones_is_a_sphere():
    """10^3 voxels of one label: a boundary of Euler characteristic 2 (-26 with the
    edge-by-edge snapping: 20 pinched vertices), for the label and for the rest."""
    m = wm.mesh_domain(np.ones((10, 10, 10), np.uint8), labels="all")
    tris, lower, upper = m.cells["triangle"], m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"]
    for label in (0, 1):
        assert euler_characteristic(None, tris[(lower == label) | (upper == label)]) == 2
    assert m.stats()["euler"] == 2 and m.stats()["manifold"]


@pytest.mark.parametrize("snap", [0.1, 0.3, 0.45])
@pytest.mark.parametrize("index", [5, 19, 37])
def test_noisy_volumes_at_every_snap(index, snap):
    """Lone voxels of five codes, anisotropic spacing, the uniform lattice and the default
    graded one: positive, conforming, no pinch, at any snap."""
    vol = wm.Volume(_noisy(index), spacing=NOISY_SPACING)
    for min_size in (None, 100.0):
        check_regions(wm.mesh_domain(vol, labels="all", snap=snap, min_size=min_size), rest=0)


def _star(cuts_onto_zero):
    """Node 0 (code 1) and tetrahedra (0, a, b, c) of code-0 nodes; the cuts on (0, x) for
    x in ``cuts_onto_zero`` at t = 0.1 (snapped onto node 0 at snap 0.3), the others at 0.5."""
    T = np.array([[0, 1, 2, 3], [0, 1, 3, 4], [0, 5, 6, 7]])
    L = np.array([[1, 0, 0, 0]] * 3)
    e_hi = np.arange(1, 8)
    cut_id = np.array([[0, 1, 2, -1, -1, -1], [0, 2, 3, -1, -1, -1], [4, 5, 6, -1, -1, -1]])
    t = np.where(np.isin(e_hi, cuts_onto_zero), 0.1, 0.5)
    return T, L, cut_id, t, np.zeros(7, np.int64), e_hi


def test_snap_cuts_keeps_one_cone_and_pushes_the_others():
    # cuts towards 1, 2 and 3 share faces (one cone); 5 lies in a tetrahedron of its own (a second cone)
    T, L, cut_id, t, e_lo, e_hi = _star([1, 2, 3, 5])
    t2, lo, hi, pushed = snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)
    assert pushed == 1 and not hi.any()
    assert lo.tolist() == [True, True, True, False, False, False, False]
    assert t2[4] == pytest.approx(0.3 + PUSH_BEYOND) and np.array_equal(np.delete(t2, 4), np.delete(t, 4))
    # one cone: nothing to push, and t is returned as it came
    T, L, cut_id, t, e_lo, e_hi = _star([1, 2, 3])
    t2, lo, hi, pushed = snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)
    assert pushed == 0 and t2 is t and lo.sum() == 3


def _octahedron(cuts_onto_zero, t_snapped=0.1):
    """Node 0 (code 1) inside the octahedron of nodes 1-6 (+x, -x, +y, -y, +z, -z, code 0):
    its eight tetrahedra, the cuts on (0, u) (id u - 1) at ``t_snapped`` for u in
    ``cuts_onto_zero``, the others at 0.5."""
    T = np.array([[0, x, y, z] for x in (1, 2) for y in (3, 4) for z in (5, 6)])
    L = np.array([[1, 0, 0, 0]] * 8)
    cut_id = np.column_stack([T[:, 1:] - 1, np.full((8, 3), -1)])
    e_hi = np.arange(1, 7)
    t = np.where(np.isin(e_hi, cuts_onto_zero), t_snapped, 0.5)
    return T, L, cut_id, t, np.zeros(6, np.int64), e_hi


def test_snap_cuts_pushes_an_annulus():
    """Cuts onto node 0 from the four nodes of the octahedron's equator: one connected set
    (a 4-cycle of the link), but of Euler characteristic 4 - 4 + 0 = 0: an annulus, node 0's
    own code would meet it in two cones (towards +z and -z). Far cuts (at least (snap + 0.1) / 2) are
    pushed first; near ones once the far ones are gone. Three of them (a path of the link,
    or with a pole: a disk) are kept."""
    for t_snapped in (0.2, 0.1):  # pushed in the "far" step, then in the last one
        T, L, cut_id, t, e_lo, e_hi = _octahedron([1, 2, 3, 4], t_snapped)
        t2, lo, hi, pushed = snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)
        assert pushed == 4 and not lo.any() and not hi.any()
        assert np.allclose(t2[:4], 0.3 + PUSH_BEYOND) and np.array_equal(t2[4:], t[4:])
    # the far one (+x at 0.2) first: the other three (-x, +y, -y: a path) are a disk, and stay snapped
    T, L, cut_id, t, e_lo, e_hi = _octahedron([1, 2, 3, 4])
    t[0] = 0.2
    t2, lo, hi, pushed = snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)
    assert pushed == 1 and lo.tolist() == [False, True, True, True, False, False]
    for kept in ([1, 3, 2], [1, 3, 5], [1, 2, 3, 4, 5], [1, 2, 3, 4, 5, 6]):
        T, L, cut_id, t, e_lo, e_hi = _octahedron(kept)
        assert snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)[3] == 0, kept
    # the two poles only: two cones
    T, L, cut_id, t, e_lo, e_hi = _octahedron([5, 6])
    assert snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)[3] == 1


def test_a_snapped_cut_outside_the_rows_given_is_its_own_group(monkeypatch):
    """The speck pass hands snap_cuts the tetrahedra around its regions with every cut: a snapped
    cut on no edge of those rows was grouped by np.empty's garbage (the mesh of a frog crop
    changed from run to run: 2,315,143 tetrahedra or 2,314,919). Here cut 3 (onto node 0, along an
    edge in no row) with the garbage made zeros would join node 0's link as a second piece and
    be pushed; it is its own group, nothing is pushed, and the answer does not depend on it."""
    T, L = np.array([[0, 1, 2, 3]]), np.array([[1, 0, 0, 0]])
    cut_id = np.array([[0, 1, 2, -1, -1, -1]])
    t, e_lo, e_hi = np.full(4, 0.1), np.zeros(4, np.int64), np.array([1, 2, 3, 4])
    real_empty = np.empty
    for fill in (0, 7):  # what a fresh allocation may hold
        monkeypatch.setattr(np, "empty", lambda shape, dtype=float, *a, fill=fill, **k: np.full(shape, fill, dtype))
        tt, lo, hi, pushed = snap_cuts(T, L, cut_id, t, e_lo, e_hi, 0.3)
        monkeypatch.setattr(np, "empty", real_empty)
        assert pushed == 0 and lo.tolist() == [True] * 4 and np.array_equal(tt, t)
