"""The C allocator setting of the ``warpmesh`` program: keep freed memory for reuse.

With glibc's defaults every block above 32 MB is a fresh ``mmap``, given back to the system
when freed; numpy's large temporaries are such blocks, so a long pipeline pays the kernel
zeroing fresh pages again and again (on a 2-core VM about 8 s per GB, most of a fresh
process's time on large label volumes: ``benchmarks/README.md``, stop 38). Raising glibc's
mmap and trim thresholds makes large blocks come from the heap, where freed ones are reused.

This changes the whole process's allocator, so only the command line calls it (its process
ends with the command); a library call never does. Opt out with ``WARPMESH_KEEP_FREED_MEMORY=0``.

Example
-------
>>> from warpmesh._util.allocator import keep_freed_memory
>>> keep_freed_memory(environ={"WARPMESH_KEEP_FREED_MEMORY": "0"})
False
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["keep_freed_memory", "ENV", "THRESHOLD"]

ENV = "WARPMESH_KEEP_FREED_MEMORY"
#: bytes; blocks below it come from the heap, and the heap's top is not trimmed below it
THRESHOLD = 2**31 - 1  # the largest value glibc's mallopt takes (an int)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # <malloc.h>


def keep_freed_memory(environ=None) -> bool:
    """Set glibc's ``M_MMAP_THRESHOLD`` and ``M_TRIM_THRESHOLD`` to :data:`THRESHOLD`.

    Returns True when both were set; False on other platforms or C libraries (musl, macOS,
    Windows), when the environment variable :data:`ENV` is ``0`` (or ``no``, ``false``,
    ``off``), or when glibc refuses the value.
    """
    environ = os.environ if environ is None else environ
    if environ.get(ENV, "1").strip().lower() in {"0", "no", "false", "off"}:
        return False
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)  # the process's own symbols, the C library's among them (no ldconfig run)
        mallopt = libc.mallopt
        # musl and other C libraries lack gnu_get_libc_version (and mallopt's semantics)
        libc.gnu_get_libc_version  # noqa: B018 - the attribute lookup is the test
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = (ctypes.c_int, ctypes.c_int), ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, THRESHOLD)) and bool(mallopt(_M_TRIM_THRESHOLD, THRESHOLD))
