"""Boundary tags for physics: ``mesh_surface(shape, refs="primitives")`` tags each triangle
with the CSG primitive it lies on; ``Shape.primitives`` lists them (issue 24 item 4)."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh._conventions import CAP_REF
from warpmesh.surface.primitive_refs import PRIMITIVE_REF0


def _distances(shape, points) -> np.ndarray:
    """(primitives, points): |f_k| / |grad f_k| of each primitive, evaluated here."""
    out = []
    for _, prim in shape.primitives:
        fg = wm.evaluate(prim, points, gradient=True).astype(np.float64)
        out.append(np.abs(fg[:, 0]) / np.linalg.norm(fg[:, 1:], axis=1))
    return np.array(out)


def _check_tags(shape, mesh, h: float, within: float) -> None:
    """Every tagged triangle has a vertex within ``within`` h of the primitive it names,
    and a triangle whose three vertices lie on one primitive only names that one."""
    refs, tris = mesh.cell_refs["triangle"], mesh.cells["triangle"]
    d = _distances(shape, mesh.points)  # (k, n)
    surf = refs != CAP_REF
    k = refs[surf] - PRIMITIVE_REF0
    assert np.all((k >= 0) & (k < len(shape.primitives)))
    nearest = d[:, tris[surf]].min(axis=2)  # (k, t)
    assert nearest[k, np.arange(len(k))].max() <= within * h
    on = d[:, tris[surf]] <= within * h  # (k, t, 3)
    alone = on.all(axis=2) & (on.any(axis=2).sum(axis=0) == 1)  # all three vertices on one primitive only
    owner = np.argmax(alone, axis=0)
    assert alone.any() and np.array_equal(k[alone.any(axis=0)], owner[alone.any(axis=0)])


def test_shape_lists_its_primitives_through_booleans_and_transforms():
    part, _ = wm.example("part")
    assert [n for n, _ in part.primitives] == ["box"] + ["cylinder"] * 4 + ["sphere"]
    moved = (wm.sphere(0.5) | wm.torus(1.0, 0.2)).translate((1.0, 0.0, 0.0)).rotate(0.3, (0, 0, 1))
    ball = moved.primitives[0][1]
    centre = np.array([[np.cos(0.3), np.sin(0.3), 0.0]])  # the ball's centre after the moves
    assert abs(float(wm.evaluate(ball, centre)[0]) - 0.5) < 1e-6
    assert [n for n, _ in (~wm.box() * 2.0).primitives] == ["box"]  # same zero set
    assert [n for n, _ in (wm.sphere(1.0) + 0.1).primitives] == ["field"]  # an offset is a new surface
    r = wm.param("r", 0.3, lo=0.1, hi=0.5)
    edited = (wm.box() - wm.cylinder(r)).with_params(r=0.2)
    assert abs(float(wm.evaluate(edited.primitives[1][1], [[0.0, 0.0, 0.0]])[0]) - 0.2) < 1e-6
    assert [n for n, _ in (wm.circle(1.0) - wm.rectangle((0.5, 0.5))).primitives] == ["circle", "rectangle"]


def test_the_part_carries_its_six_primitives():
    part, bounds = wm.example("part")
    m = wm.mesh_surface(part, bounds=bounds, resolution=48, root="newton", refs="primitives")
    assert sorted(set(m.cell_refs["triangle"].tolist())) == list(range(PRIMITIVE_REF0, PRIMITIVE_REF0 + 6))
    assert m.info["primitives"] == {11: "box", 12: "cylinder", 13: "cylinder", 14: "cylinder", 15: "cylinder",
                                    16: "sphere"}
    h = max(m.info["cell_size"])
    # Newton roots lie on f = 0, except where kept 1e-3 of an edge off a grid node (the
    # conventions' clamp) and float32 grid-local positions: 1.5e-3 h covers both
    _check_tags(part, m, h, 1.5e-3)
    assert m.info["primitive_distance"] <= 1.5e-3
    same = wm.mesh_surface(part, bounds=bounds, resolution=48, root="newton")
    assert np.array_equal(same.cells["triangle"], m.cells["triangle"])  # only the refs differ


@pytest.mark.parametrize("kind", ["continuation", "adaptive"])
def test_other_pipelines(kind):
    part, bounds = wm.example("part")
    if kind == "adaptive":
        m = wm.mesh_surface(part, bounds=bounds, adaptive=True, max_level=6, refs="primitives")
        h = float(np.max(m.info["finest_cell"]))
    else:
        m = wm.mesh_surface(part, bounds=bounds, resolution=40, covering="continuation", root="newton",
                            refs="primitives")
        h = max(m.info["cell_size"])
    assert len(set(m.cell_refs["triangle"].tolist())) == 6
    _check_tags(part, m, h, 3e-3)


def test_caps_keep_their_ref():
    """A box clips a ball: the caps are ref 2, the ball's surface its primitive's ref."""
    m = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2, -1.2, -0.5), (1.2, 1.2, 0.5)), resolution=32,
                        root="newton", refs="primitives")
    refs = m.cell_refs["triangle"]
    assert set(refs.tolist()) == {CAP_REF, PRIMITIVE_REF0}
    capped = m.points[m.cells["triangle"][refs == CAP_REF]]
    assert np.allclose(np.abs(capped[..., 2]), 0.5, atol=1e-3)  # on the box's faces z = +-0.5


def test_refs_survive_the_operations():
    shape = (wm.box((1.6, 1.6, 0.8)) - wm.cylinder(0.3)) | wm.sphere(0.45, center=(0, 0, 0.4))
    m = wm.mesh_surface(shape, bounds=((-1,) * 3, (1,) * 3), resolution=16, root="newton", refs="primitives")
    h = max(m.info["cell_size"])
    expected = {11, 12, 13}
    assert set(m.cell_refs["triangle"].tolist()) == expected
    opt = m.optimize(shape, size=h, tolerance=h / 4, iterations=2)
    assert set(opt.cell_refs["triangle"].tolist()) == expected
    _check_tags(shape, opt, h, 0.3)  # optimised vertices stay within the tolerance of f = 0
    moved = m.transform(wm.transforms.translation((3.0, 0.0, 0.0)))
    for out in (m.refine(max_length=h), moved, m.merge(moved)):
        assert set(out.cell_refs["triangle"].tolist()) == expected


def test_bad_refs():
    part, bounds = wm.example("part")
    with pytest.raises(ValueError, match="refs 'faces'. Pick one of"):
        wm.mesh_surface(part, bounds=bounds, resolution=16, refs="faces")
    with pytest.raises(ValueError, match="refs='primitives' tags the primitives of a shape"):
        wm.mesh_surface(np.random.default_rng(0).random((8, 8, 8)), level=0.5, refs="primitives")
