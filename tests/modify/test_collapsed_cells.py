"""Collapsed cells (a repeated vertex): Mesh and the mapping operations keep them, the
operations that split or rebuild cells refuse them with the first one named."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from tests.helpers.blocks import kuhn_block, tri_square
from warpmesh.cells.collapsed import collapsed_cells


def _with_collapsed():
    sq = tri_square(3)
    tri = wm.Mesh(sq.points, {"triangle": np.vstack([sq.triangles, [[0, 1, 0]]])})
    k = kuhn_block(1)
    tet = wm.Mesh(k.points, {"tetra": np.vstack([k.cells["tetra"], [[0, 1, 2, 1]]])})
    return tri, tet


def test_collapsed_cells_found_per_block():
    tri, tet = _with_collapsed()
    assert {t: c.tolist() for t, c in collapsed_cells(tri).items()} == {"triangle": [len(tri.triangles) - 1]}
    assert {t: c.tolist() for t, c in collapsed_cells(tet).items()} == {"tetra": [6]}
    assert collapsed_cells(tri_square(3)) == {}


@pytest.mark.parametrize("operation", ["refine", "refine local", "convert", "crack", "to_order"])
def test_operations_that_rebuild_cells_refuse_them(operation):
    for mesh in _with_collapsed():
        run = {"refine": lambda m: m.refine(2), "refine local": lambda m: m.refine(max_length=0.3),
               "convert": lambda m: m.convert("quad" if m.dim == 2 else "tetra"),
               "crack": lambda m: m.crack(m.cells[next(iter(m.cells))][:1, :m.dim]),
               "to_order": lambda m: m.to_order(2)}[operation]
        with pytest.raises(ValueError, match=r"repeated vertex in 'mesh'.*the first cells\[") as err:
            run(mesh)
        assert operation.split()[0] in str(err.value)


def test_mapping_operations_carry_them_unchanged():
    for mesh in _with_collapsed():
        shift = np.zeros(mesh.dim)
        shift[0] = 1.0
        t = wm.transforms.translation(shift)
        for out in (mesh.transform(t), mesh.renumber(), mesh.merge(mesh.transform(t), check=False),
                    mesh.periodic(t, 3, check=False)):
            assert sum(len(c) for c in collapsed_cells(out).values()) >= 1
