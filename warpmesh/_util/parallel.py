"""CPU launches split across cores from Python threads.

Warp's CPU backend runs one launch on one thread; its launches release the GIL, so a 1-D
launch cut into per-core ranges and launched from Python threads uses every core
(measured: 1.5x on 2 cores, results identical to one serial launch). On CUDA a launch
is already parallel: one range.
"""

from __future__ import annotations

import os
import threading

import numpy as np
import warp as wp

__all__ = ["cpu_view", "device_empty", "device_full", "device_zeros", "launch_split", "n_workers",
           "parallel_ranges", "run_parallel"]


def n_workers(device) -> int:
    """Threads to launch CPU kernels from: the cores this process may run on (its CPU
    affinity where the platform has one, so a process pinned to one core, a container's
    or a Dask worker's share, launches one thread), at most 8; 1 on CUDA."""
    return max(1, min(usable_cores(), 8)) if wp.get_device(device).is_cpu else 1


def usable_cores() -> int:
    """The cores this process may run on: its affinity mask (Linux), else ``os.cpu_count()``.

    Examples
    --------
    >>> 1 <= usable_cores() <= (os.cpu_count() or 1)
    True
    """
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def parallel_ranges(n: int, device, min_per_worker: int = 1 << 14) -> list[tuple[int, int]]:
    """Split [0, n) into per-core ranges for CPU launches (one range on CUDA).

    Examples
    --------
    >>> parallel_ranges(10, "cpu")   # too small to split
    [(0, 10)]
    """
    k = n_workers(device) if n >= 2 * min_per_worker else 1
    k = max(1, min(k, n // max(min_per_worker, 1)))
    edges = np.linspace(0, n, k + 1).astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def run_parallel(jobs) -> None:
    """Run callables concurrently from Python threads; the first exception is re-raised on
    the calling thread after every job has ended.

    Examples
    --------
    >>> out = []
    >>> run_parallel([lambda: out.append(1), lambda: out.append(2)])
    >>> sorted(out)
    [1, 2]
    """
    jobs = list(jobs)
    if len(jobs) == 1:
        jobs[0]()
        return
    errors = []

    def wrap(job):
        try:
            job()
        except BaseException as exc:  # re-raised below, on the calling thread
            errors.append(exc)

    threads = [threading.Thread(target=wrap, args=(j,)) for j in jobs]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    if errors:
        raise errors[0]


def launch_split(kernel, n: int, inputs: list, outputs: list, device="cpu", min_per_worker: int = 1 << 14) -> None:
    """Launch ``kernel`` over [0, n), its first input ``first`` (each thread's item is
    ``first + tid``), in the ranges of :func:`parallel_ranges` from :func:`run_parallel`'s
    threads (one launch on CUDA or for small n). The kernel must write only its own items'
    entries: on the CPU an atomic is not atomic across launches on two threads.

    Examples
    --------
    >>> import numpy as np
    >>> @wp.kernel
    ... def _double(first: int, x: wp.array(dtype=float), y: wp.array(dtype=float)):
    ...     i = first + wp.tid()
    ...     y[i] = 2.0 * x[i]
    >>> y = wp.zeros(5, dtype=float, device="cpu")
    >>> launch_split(_double, 5, [wp.array(np.arange(5.0), dtype=float, device="cpu")], [y])
    >>> y.numpy().tolist()
    [0.0, 2.0, 4.0, 6.0, 8.0]
    """
    if n <= 0:
        return
    run_parallel([lambda a=a, b=b: wp.launch(kernel, dim=b - a, inputs=[a, *inputs], outputs=outputs, device=device)
                  for a, b in parallel_ranges(n, device, min_per_worker=min_per_worker)])


def cpu_view(a: np.ndarray, dtype) -> wp.array:
    """A Warp CPU array of ``dtype`` over the memory of host array ``a`` (made contiguous
    first when it is not), no copy: for :func:`launch_split`'s inputs and outputs (an output
    must be contiguous already, or the kernel writes into a copy).

    >>> out = np.zeros(3, np.int32)
    >>> cpu_view(out, wp.int32).fill_(7)
    >>> out.tolist()
    [7, 7, 7]
    """
    return wp.array(np.ascontiguousarray(a), dtype=dtype, device="cpu", copy=False)


def device_empty(n: int, dtype, device) -> wp.array:
    """``wp.empty(n, dtype, device)`` for a Warp scalar or vector ``dtype``, but on the CPU
    in memory from numpy: numpy asks the
    kernel for transparent huge pages on large blocks, so a fresh array's first touch
    faults 512 times less often (a 40 MB array written once: 8 ms against 20 ms from
    Warp's own allocator on this project's 2-core VM). Pipelines that allocate a few
    hundred MB of scratch per call (the self-intersection check) spend that difference on
    every call.

    >>> a = device_empty(4, wp.vec3, "cpu")
    >>> a.shape, a.dtype is wp.vec3
    ((4,), True)
    """
    device = wp.get_device(device)
    if not device.is_cpu:
        return wp.empty(n, dtype=dtype, device=device)
    if wp.types.type_is_vector(dtype):
        host = np.empty((n, dtype._length_), dtype=wp.dtype_to_numpy(dtype._wp_scalar_type_))
    else:
        host = np.empty(n, dtype=wp.dtype_to_numpy(dtype))
    return wp.array(host, dtype=dtype, device="cpu", copy=False)


def device_full(n: int, value, dtype, device) -> wp.array:
    """:func:`device_empty` filled with ``value``.

    >>> device_full(3, -1, wp.int32, "cpu").numpy().tolist()
    [-1, -1, -1]
    """
    a = device_empty(n, dtype, device)
    a.fill_(value)
    return a


def device_zeros(n: int, dtype, device) -> wp.array:
    """:func:`device_empty` filled with zeros.

    >>> device_zeros(2, wp.int8, "cpu").numpy().tolist()
    [0, 0]
    """
    return device_full(n, 0, dtype, device)
