"""A stable counting sort of int32 keys, split across the CPU cores.

Each worker counts the keys of its own range of items into its own row (no atomics: on
the CPU an atomic add is not atomic across launches on two threads), one prefix sum over
(key, worker) gives each worker where its items of each key start, and each worker places
its items (:func:`~warpmesh.kernels.topology.count_keys_kernel`,
:func:`~warpmesh.kernels.topology.scatter_keys_kernel`). The items of a key keep their
order, as in ``np.argsort(keys, kind="stable")``; the work is linear in the items and the
keys.

Example
-------
>>> import numpy as np
>>> offsets, order = counting_sort(np.array([2, 0, 2, 1, 0], np.int32), 4)
>>> offsets.tolist(), order.tolist()
([0, 2, 3, 5, 5], [1, 4, 3, 0, 2])
"""

from __future__ import annotations

import numpy as np

__all__ = ["counting_sort"]


def counting_sort(keys: np.ndarray, n_keys: int) -> tuple[np.ndarray, np.ndarray]:
    """Sort items by key, stably.

    Parameters
    ----------
    keys : (m,) int
        Each item's key, in [0, n_keys).
    n_keys : int

    Returns
    -------
    offsets : (n_keys + 1,) int32
        Key k's items are ``order[offsets[k]:offsets[k + 1]]``.
    order : (m,) int32
        The items, by key, ascending within a key.
    """
    import warp as wp

    from warpmesh._util.parallel import cpu_view, parallel_ranges, run_parallel
    from warpmesh.kernels import topology as KT

    keys = np.asarray(keys)
    m = len(keys)
    if m >= np.iinfo(np.int32).max or n_keys >= np.iinfo(np.int32).max:
        raise ValueError(f"counting_sort takes fewer than 2^31 - 1 items and keys, got {m} and {n_keys}")
    if keys.ndim != 1 or not np.issubdtype(keys.dtype, np.integer):
        raise ValueError(f"expected 'keys' of integers of shape (m,), got {keys.dtype} {keys.shape}")
    if m == 0:
        return np.zeros(n_keys + 1, np.int32), np.zeros(0, np.int32)
    if int(keys.min()) < 0 or int(keys.max()) >= n_keys:  # (the kernels index by key unchecked)
        raise ValueError(f"expected 'keys' in [0, {n_keys}), got [{int(keys.min())}, {int(keys.max())}]")
    keys = np.ascontiguousarray(keys, dtype=np.int32)
    wp.load_module(KT, device="cpu")  # once here, not in the worker threads
    ranges = parallel_ranges(m, "cpu", min_per_worker=1 << 18)
    counts = np.zeros((len(ranges), n_keys), np.int32)
    wkeys = cpu_view(keys, wp.int32)
    run_parallel([lambda a=a, b=b, row=row: wp.launch(KT.count_keys_kernel, dim=1, inputs=[a, b, wkeys],
                                                      outputs=[cpu_view(row, wp.int32)], device="cpu")
                  for row, (a, b) in zip(counts, ranges)])
    offsets = np.zeros(n_keys + 1, np.int32)
    before = np.cumsum(counts, axis=0, dtype=np.int32)  # each worker's items of a key, up to and with it
    np.cumsum(before[-1], out=offsets[1:])
    before -= counts
    before += offsets[:-1]  # where each worker's items of each key start
    del counts
    order = np.empty(m, np.int32)
    worder = cpu_view(order, wp.int32)
    run_parallel([lambda a=a, b=b, row=row: wp.launch(KT.scatter_keys_kernel, dim=1, inputs=[a, b, wkeys],
                                                      outputs=[cpu_view(row, wp.int32), worder], device="cpu")
                  for row, (a, b) in zip(before, ranges)])
    wp.synchronize_device("cpu")
    return offsets, order
