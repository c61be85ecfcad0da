"""optimize and simplify refuse a mesh that does not lie on the shape they are given
(issue 24: a sphere's mesh optimised onto a torus succeeded silently)."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm


@pytest.fixture(scope="module")
def ball():
    return wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=16)


@pytest.mark.parametrize("op", ["optimize", "simplify"])
def test_a_mesh_of_another_shape_is_refused(ball, op):
    with pytest.raises(ValueError, match=r"expected a mesh of 'shape': half its vertices lie farther than"):
        getattr(ball, op)(wm.torus(1.0, 0.3))


def test_the_figures_of_the_refusal_are_right(ball):
    """The median distance reported is the median of |f| / |grad f| at the vertices."""
    torus = wm.torus(1.0, 0.3)
    fg = wm.evaluate(torus, ball.points, gradient=True).astype(np.float64)
    median = float(np.median(np.abs(fg[:, 0]) / np.linalg.norm(fg[:, 1:], axis=1)))
    with pytest.raises(ValueError, match=f"farther than {median:.3g} from"):
        ball.optimize(torus, tolerance=0.01)


def test_a_mesh_of_the_shape_passes_and_a_large_tolerance_lets_it_through(ball):
    assert ball.optimize(wm.sphere(1.0), iterations=1).n_cells > 0
    # the same ball half a unit off: 0.5 from f = 0 at most; a tolerance of 0.2 accepts it
    moved = ball.transform(wm.transforms.translation((0.1, 0.0, 0.0)))
    with pytest.raises(ValueError, match="'shape'"):
        moved.optimize(wm.sphere(1.0), tolerance=0.01, iterations=1)
    assert moved.optimize(wm.sphere(1.0), tolerance=0.2, iterations=1).n_cells > 0


def test_nan_at_the_vertices_is_refused(ball):
    x, y, z = wm.coords()
    with pytest.raises(ValueError, match="NaN or infinite values"):
        ball.optimize(wm.Shape(wm.log(x) + 1.0 - wm.sqrt(x * x + y * y + z * z)))
