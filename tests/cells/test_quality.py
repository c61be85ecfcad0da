"""The shape measure Q_K = alpha h_max / rho_K [FG eq. 16.15] on elements computed by hand."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from warpmesh._conventions import ALPHA_TRIANGLE
from warpmesh.cells.quality import ALPHA_TETRA, quality_summary, tetra_quality, triangle_quality

EQUILATERAL = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3.0) / 2.0]])
REGULAR_TET = np.array([[1.0, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]])


def test_alphas_normalise_the_regular_elements():
    assert ALPHA_TRIANGLE == pytest.approx(np.sqrt(3) / 6)
    assert ALPHA_TETRA == pytest.approx(np.sqrt(6) / 12)


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_equilateral_triangle_scores_one_in_2d_and_3d(scale):
    assert triangle_quality(EQUILATERAL * scale, [[0, 1, 2]])[0] == pytest.approx(1.0, rel=1e-14)
    pts3 = np.column_stack([EQUILATERAL, np.zeros(3)]) * scale
    pts3 = Rotation.from_euler("xyz", [0.3, -1.1, 2.0]).apply(pts3) + [4.0, -2.0, 7.0]
    assert triangle_quality(pts3, [[0, 1, 2]])[0] == pytest.approx(1.0, rel=1e-9)


def test_right_isosceles_triangle_by_hand():
    # legs 1: area 1/2, perimeter 2 + sqrt 2, inradius 2 area / perimeter, diameter sqrt 2
    rho = 2 * 0.5 / (2 + np.sqrt(2))
    expect = np.sqrt(3) / 6 * np.sqrt(2) / rho  # = (1 + sqrt 2) / sqrt 3 = 1.3938...
    q = triangle_quality([[0, 0], [1, 0], [0, 1]], [[0, 1, 2], [2, 1, 0]])
    np.testing.assert_allclose(q, [expect, expect], rtol=1e-14)
    assert expect == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3))


def test_degenerate_triangles_score_inf():
    pts = [[0, 0], [1, 0], [2, 0], [0, 1]]
    q = triangle_quality(pts, [[0, 1, 2], [0, 0, 3], [0, 1, 3]])
    assert np.isinf(q[:2]).all() and np.isfinite(q[2])


def test_random_triangles_score_at_least_one():
    rng = np.random.default_rng(0)
    pts = rng.normal(size=(300, 3))
    q = triangle_quality(pts, np.arange(300).reshape(-1, 3))
    assert np.all(q >= 1 - 1e-12)


def test_regular_tetrahedron_scores_one():
    assert tetra_quality(REGULAR_TET, [[0, 1, 2, 3]])[0] == pytest.approx(1.0, rel=1e-14)
    # orientation does not matter
    assert tetra_quality(REGULAR_TET, [[1, 0, 2, 3]])[0] == pytest.approx(1.0, rel=1e-14)


def test_corner_tetrahedron_by_hand():
    # volume 1/6; faces 3 x 1/2 + sqrt(3)/2; inradius 3 V / A = 1 / (3 + sqrt 3); diameter sqrt 2
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    expect = np.sqrt(6) / 12 * np.sqrt(2) * (3 + np.sqrt(3))  # = (1 + sqrt 3) / 2
    assert tetra_quality(pts, [[0, 1, 2, 3]])[0] == pytest.approx(expect, rel=1e-14)
    assert expect == pytest.approx((1 + np.sqrt(3)) / 2)


def test_flat_tetrahedron_scores_inf():
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    assert np.isinf(tetra_quality(pts, [[0, 1, 2, 3]])[0])


def test_quality_summary_of_triangles_and_tetra():
    pts = [[0, 0], [1, 0], [0, 1], [1, 1], [2, 0]]
    s = quality_summary(pts, np.array([[0, 1, 2], [1, 3, 2], [0, 1, 4]]))
    assert s["n_elements"] == 3 and s["n_degenerate"] == 1
    assert s["mean_q"] == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3))
    assert s["best_q"] == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3))
    assert s["worst_q"] == np.inf
    t = quality_summary(REGULAR_TET, {"triangle": [[0, 1, 2]], "tetra": [[0, 1, 2, 3]]})
    assert t["n_elements"] == 1 and t["worst_q"] == pytest.approx(1.0)


def test_quality_summary_of_nothing_is_nan():
    s = quality_summary(EQUILATERAL, np.zeros((0, 3), int))
    assert s["n_elements"] == 0 and np.isnan(s["mean_q"]) and np.isnan(s["worst_q"])


def test_bad_cell_shape_rejected():
    with pytest.raises(ValueError, match=r"shape \(m, 3\) or \(m, 4\)"):
        quality_summary(EQUILATERAL, np.zeros((2, 5), int))


def test_index_out_of_range_rejected():
    with pytest.raises(ValueError, match=r"indices in \[0, 3\)"):
        triangle_quality(EQUILATERAL, [[0, 1, 3]])


def test_tetra_need_3d_points():
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        tetra_quality(EQUILATERAL, [[0, 1, 2, 2]])


def test_float_indices_rejected():
    with pytest.raises(TypeError, match="integer array for 'triangles'"):
        triangle_quality(EQUILATERAL, [[0.0, 1.0, 2.0]])


def test_points_with_nan_or_infinity_are_refused():
    """(A NaN corner gave Q_K NaN, and quality_summary a mean of inf with a worst of NaN.)"""
    for bad in (np.nan, np.inf):
        tri = np.array([[0, 0, 0], [1, 0, 0], [0, bad, 0]], float)
        tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, bad]], float)
        with pytest.raises(ValueError, match="expected finite 'points', got NaN or infinity"):
            triangle_quality(tri, [[0, 1, 2]])
        with pytest.raises(ValueError, match="expected finite 'points'"):
            tetra_quality(tet, [[0, 1, 2, 3]])
        with pytest.raises(ValueError, match="expected finite 'points'"):
            quality_summary(tri, [[0, 1, 2]])


@pytest.mark.parametrize("scale", [1e-300, 1e-100, 1e-30, 1e30, 1e100, 1e300])
def test_quality_is_scale_free_at_any_scale(scale):
    """Products of 1e-100 lengths underflowed: a regular tetrahedron at 1e-100 got Q 0, a right
    triangle at 1e100 got 0, inf beyond 1e+-120. The points are scaled by a power of two first."""
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    assert tetra_quality(tet * scale, [[0, 1, 2, 3]])[0] == pytest.approx(1.0, rel=1e-12)
    assert triangle_quality(tri * scale, [[0, 1, 2]])[0] == pytest.approx((1 + np.sqrt(2)) / np.sqrt(3), rel=1e-12)
    exact = 2.0 ** round(np.log2(scale))  # a power of two: the same bits as at scale 1
    assert tetra_quality(tet * exact, [[0, 1, 2, 3]])[0] == tetra_quality(tet, [[0, 1, 2, 3]])[0]
