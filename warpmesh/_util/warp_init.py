"""Warp's start-up, without the CUDA-driver warning on machines that have no GPU.

Warp's native library prints "Warp CUDA warning: Could not find or load the NVIDIA CUDA
driver" straight to file descriptor 2 when it initialises on a machine without a CUDA
driver: on every command, ``--help`` included, for a user who never asked for a GPU.
:func:`init_warp` runs ``wp.init()`` with descriptor 2 sent to a temporary file, then
writes back everything Warp printed except that line. A user who asks for a CUDA device
that is not there gets warpmesh's own error from the entry point instead.

Example
-------
>>> from warpmesh._util.warp_init import init_warp
>>> init_warp()  # idempotent
>>> import warp as wp
>>> wp.get_device("cpu").is_cpu
True
"""

from __future__ import annotations

import os
import sys
import tempfile

import warp as wp

#: the line Warp's native code prints when it finds no CUDA driver
NO_DRIVER = "Could not find or load the NVIDIA CUDA driver"

__all__ = ["init_warp", "NO_DRIVER"]


def init_warp() -> None:
    """Initialise Warp once, dropping its no-CUDA-driver warning (other output is kept)."""
    if getattr(wp._src.context, "runtime", None) is not None:  # already initialised
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no descriptor 2 to borrow: let it print
        wp.init()
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode("utf-8", errors="replace")
    kept = "".join(line for line in text.splitlines(True) if NO_DRIVER not in line)
    if kept:
        sys.stderr.write(kept)
