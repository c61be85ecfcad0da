"""Row-wise measures computed by chunks (``tetra_quality``, ``cell_measures``) equal the
one-chunk values to a few ulps, whatever the chunk size against the number of rows (numpy's
einsum and matmul may sum a short row in another order for some array sizes)."""

import numpy as np
import pytest

from warpmesh.cells import quality, reference


@pytest.mark.parametrize("chunk", [1, 7, 64, 1000])
def test_chunked_measures_equal_one_chunk(monkeypatch, chunk):
    rng = np.random.default_rng(chunk)
    pts = rng.random((300, 3))
    distinct = np.argsort(rng.random((500, 300)), axis=1)  # rows of distinct points
    cells = {"tetra": distinct[:, :4].copy(), "triangle": distinct[:333, :3], "hexahedron": distinct[:65, :8]}
    cells["tetra"][3] = [1, 1, 2, 3]  # degenerate: inf
    whole_q = quality.tetra_quality(pts, cells["tetra"])
    whole = {t: reference.cell_measures(pts, c, t) for t, c in cells.items()}
    monkeypatch.setattr(quality, "_ROW_CHUNK", chunk)
    monkeypatch.setattr(reference, "_ROW_CHUNK", chunk)
    np.testing.assert_allclose(quality.tetra_quality(pts, cells["tetra"]), whole_q, rtol=1e-11)  # flat ones amplify the rounding
    assert np.isinf(whole_q[3]) and np.isfinite(np.delete(whole_q, 3)).all()
    for t, c in cells.items():
        got = reference.cell_measures(pts, c, t)
        assert got.shape == (len(c),)
        np.testing.assert_allclose(got, whole[t], rtol=1e-13, atol=1e-17)


def _random_tets(seed):
    rng = np.random.default_rng(seed)
    pts = rng.random((400, 3))
    tets = np.argsort(rng.random((3000, 400)), axis=1)[:, :4].copy()
    tets[5] = [1, 1, 2, 3]  # repeats a vertex: inf
    pts[399] = 0.5 * (pts[tets[7, 0]] + pts[tets[7, 1]])  # a flat one: corner on an edge
    tets[7, 2] = 399
    tets[9] = tets[9, [1, 0, 2, 3]]  # orientations both ways
    return pts, tets


@pytest.mark.parametrize("chunk", [1, 37, 1 << 20])
def test_kernel_quality_and_volumes_equal_the_numpy_rows(monkeypatch, chunk):
    pts, tets = _random_tets(chunk)
    monkeypatch.setattr(quality, "_KERNEL_CHUNK", chunk)
    rows = quality._tetra_quality_rows(np.ascontiguousarray(pts.T), tets)
    got = quality.tetra_quality(pts, tets)
    assert np.isinf(got[5]) and np.isinf(got[7]) and np.isinf(rows[5]) and np.isinf(rows[7])
    np.testing.assert_allclose(got, rows, rtol=1e-12)
    volume, summary = quality.tetra_figures(pts, tets)
    expect = quality.summarize_quality(rows)
    assert summary["n_elements"] == expect["n_elements"] == len(tets)
    assert summary["n_degenerate"] == expect["n_degenerate"] >= 2
    assert summary["worst_q"] == np.inf
    for key in ("mean_q", "best_q"):
        assert summary[key] == pytest.approx(expect[key], rel=1e-12)
    assert volume == pytest.approx(reference.cell_measures(pts, tets, "tetra").sum(), rel=1e-12, abs=1e-14)


def test_figures_without_the_kernel_equal_the_kernel(monkeypatch):
    pts, tets = _random_tets(3)
    tets = np.delete(tets, [5, 7], axis=0)  # all finite
    volume, summary = quality.tetra_figures(pts, tets)
    monkeypatch.setattr(quality, "_kernel_applies", lambda *a: False)
    volume0, summary0 = quality.tetra_figures(pts, tets)
    assert summary0["worst_q"] < np.inf and summary0["n_degenerate"] == 0
    assert volume == pytest.approx(volume0, rel=1e-12, abs=1e-14)
    for key in ("mean_q", "worst_q", "best_q"):
        assert summary[key] == pytest.approx(summary0[key], rel=1e-12)
    np.testing.assert_allclose(quality.tetra_quality(pts, tets), quality._tetra_quality_rows(
        np.ascontiguousarray(pts.T), tets), rtol=1e-12)


def test_figures_refuse_bad_tetrahedra():
    pts, tets = _random_tets(4)
    with pytest.raises(ValueError, match="'tetra'"):
        quality.tetra_figures(pts, tets[:, :3])
    with pytest.raises(ValueError, match="'tetra'"):
        quality.tetra_figures(pts, tets + 400)
    with pytest.raises(TypeError, match="'tetra'"):
        quality.tetra_figures(pts, tets.astype(float))
    assert quality.tetra_figures(pts, np.zeros((0, 4), int))[0] == 0.0


def test_figures_refuse_nan_as_the_summary_does():
    """(Both gave NaN figures before; the kernel's and numpy's agreed on them.)"""
    pts, tets = _random_tets(6)
    pts[tets[3, 0]] = np.nan
    for figures in (quality.tetra_quality, quality.tetra_figures):
        with pytest.raises(ValueError, match="expected finite 'points', got NaN or infinity"):
            figures(pts, tets)

