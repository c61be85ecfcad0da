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
