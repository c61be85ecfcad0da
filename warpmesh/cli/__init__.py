"""The warpmesh command line: ``warpmesh mesh | curve | domain | info | transform | ...``.

:func:`main` is the console script's entry point. It imports the commands (and numpy with
them) only when called, after a Ctrl-C handler is in place: an interrupt in the first
fraction of a second ends with the same one line and status 130 as a later one, not with
an import's traceback. Run as the program (``argv`` None), it first sets the C allocator to
keep freed memory for reuse (:func:`warpmesh._util.allocator.keep_freed_memory`; opt out
with ``WARPMESH_KEEP_FREED_MEMORY=0``): the process ends with the command, and large jobs
no longer pay the system for fresh pages again and again.
"""

from __future__ import annotations

import os
import signal
import sys
import threading

__all__ = ["main"]


def _interrupted_while_starting(signum, frame) -> None:
    sys.stderr.write("warpmesh: interrupted\n")
    sys.stderr.flush()
    os._exit(130)  # nothing is written yet: the modules were still loading


def main(argv: list[str] | None = None) -> int:
    """Run the ``warpmesh`` command: :func:`warpmesh.cli.commands.main` (its docs have the
    exit statuses), loaded behind a quiet Ctrl-C handler when run as the program."""
    early = argv is None and threading.current_thread() is threading.main_thread()
    if argv is None:
        from warpmesh._util.allocator import keep_freed_memory

        keep_freed_memory()
    previous = signal.signal(signal.SIGINT, _interrupted_while_starting) if early else None
    try:
        from warpmesh.cli.commands import main as run
    finally:
        if early:
            signal.signal(signal.SIGINT, previous)
    return run(argv)
