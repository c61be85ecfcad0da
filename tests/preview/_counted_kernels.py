"""A kernel module loaded by one test only: the load counter must see its load."""

import warp as wp


@wp.kernel
def fill_kernel(value: float, out: wp.array(dtype=wp.float32)):
    """One thread: out[tid] = value."""
    out[wp.tid()] = value
