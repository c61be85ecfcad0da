"""The parallel counting sort equals numpy's stable argsort, on one worker or several."""

import numpy as np
import pytest

from warpmesh._util import counting_sort as cs
from warpmesh._util import parallel


@pytest.mark.parametrize("workers", [1, 2, 3])
@pytest.mark.parametrize("m, n_keys", [(0, 4), (1, 1), (17, 3), (300_001, 5), (600_000, 250_000)])
def test_counting_sort_is_numpy_stable_argsort(monkeypatch, workers, m, n_keys):
    monkeypatch.setattr(parallel, "n_workers", lambda device: workers)
    rng = np.random.default_rng(m + workers)
    keys = rng.integers(0, n_keys, m).astype(np.int32)
    if m > 1000:  # runs of one key across the workers' ranges
        keys[m // 3: 2 * m // 3] = n_keys - 1
    offsets, order = cs.counting_sort(keys, n_keys)
    assert offsets.dtype == order.dtype == np.int32
    np.testing.assert_array_equal(order, np.argsort(keys, kind="stable"))
    np.testing.assert_array_equal(offsets, np.r_[0, np.cumsum(np.bincount(keys, minlength=n_keys))])


def test_counting_sort_takes_other_integer_dtypes_and_refuses_too_many_keys():
    offsets, order = cs.counting_sort(np.array([3, 1, 3, 0], np.int64), 4)
    assert offsets.tolist() == [0, 1, 2, 2, 4] and order.tolist() == [3, 1, 0, 2]
    with pytest.raises(ValueError, match="counting_sort"):
        cs.counting_sort(np.zeros(3, np.int32), 2**31)


def test_counting_sort_refuses_keys_out_of_range_or_not_integers():
    for keys in (np.array([0, 4, 1], np.int32), np.array([-1, 0], np.int64)):
        with pytest.raises(ValueError, match="'keys' in \\[0, 4\\)"):
            cs.counting_sort(keys, 4)
    with pytest.raises(ValueError, match="'keys'"):
        cs.counting_sort(np.array([0.0, 1.0]), 4)
    with pytest.raises(ValueError, match="'keys'"):
        cs.counting_sort(np.zeros((2, 2), np.int32), 4)
