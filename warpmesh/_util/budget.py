"""The memory budget: operations estimate their output before allocating and refuse above it.

The budget is half of the machine's physical memory, or the environment variable
``WARPMESH_MEMORY_BUDGET`` (bytes, or a number with a K, M, G or T suffix: ``"8G"``).
A refusal is a :class:`~warpmesh.errors.SizeError` (a ``ValueError``) that names the
argument, the size it would need and the budget, before any work is done.

Example
-------
>>> from warpmesh._util.budget import check_budget
>>> check_budget(1024, "a test array", "lower 'n'")   # far below any budget: nothing happens
>>> check_budget(10**30, "refine(n=10**9)", "lower 'n'")
Traceback (most recent call last):
...
warpmesh.errors.SizeError: refine(n=10**9) would need about 1e+30 bytes (9.31e+20 GB), above the memory budget of ...
"""

from __future__ import annotations

import os
import re

from warpmesh.errors import SizeError

__all__ = ["memory_budget", "check_budget", "ENV"]

ENV = "WARPMESH_MEMORY_BUDGET"
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def _physical_memory() -> int:
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):  # not POSIX: a conservative 8 GB machine
        return 8 * 2**30


def memory_budget() -> int:
    """Bytes an operation may allocate: ``WARPMESH_MEMORY_BUDGET`` or half the physical memory."""
    text = os.environ.get(ENV, "").strip()
    if not text:
        return _physical_memory() // 2
    m = re.fullmatch(r"(\d+(?:\.\d*)?)\s*([KMGT]?)B?", text.upper())
    if m is None or float(m.group(1)) <= 0:
        raise ValueError(f"expected {ENV} as a positive number of bytes with an optional K, M, G or T "
                         f"suffix (e.g. '8G'), got {text!r}")
    return int(float(m.group(1)) * _UNITS[m.group(2)])


def check_budget(n_bytes: float, what: str, remedy: str) -> None:
    """Raise :class:`SizeError` when ``n_bytes`` (an estimate of what ``what`` would
    allocate) is above :func:`memory_budget`; ``remedy`` says which argument to change."""
    budget = memory_budget()
    if n_bytes > budget:
        raise SizeError(f"{what} would need about {n_bytes:.3g} bytes ({n_bytes / 2**30:.3g} GB), above the "
                        f"memory budget of {budget / 2**30:.3g} GB (half the machine's memory, or {ENV}); "
                        f"{remedy}")
