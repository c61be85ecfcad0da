"""Cooperative cancellation of a meshing run from the thread that asked for it.

A caller that may find its run stale (the live preview's idle refinement, once a newer edit
came) runs it inside :func:`cancellable` with a check; the pipelines call
:func:`checkpoint` between their stages (the grid's cull, sampling, extraction, roots; each
octree level), which raises :class:`Cancelled` when the check says so. The check is per
thread (a ``threading.local``), so other threads' runs are untouched, and outside
:func:`cancellable` a checkpoint costs an attribute lookup.

Example
-------
>>> stale = False
>>> with cancellable(lambda: stale):
...     checkpoint()          # not stale: goes on
...     stale = True
...     try:
...         checkpoint()
...     except Cancelled as exc:
...         print(exc)
the run was cancelled: its result is no longer wanted
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import contextmanager

from warpmesh.errors import WarpMeshError

__all__ = ["Cancelled", "cancellable", "checkpoint"]

_local = threading.local()


class Cancelled(WarpMeshError):
    """Raised at a :func:`checkpoint` of a run whose :func:`cancellable` check turned true."""


@contextmanager
def cancellable(stale: Callable[[], bool]):
    """Run the body with ``stale()`` asked at every :func:`checkpoint` of this thread."""
    if not callable(stale):
        raise TypeError(f"expected a callable for 'stale', got {type(stale).__name__}")
    before = getattr(_local, "stale", None)
    _local.stale = stale
    try:
        yield
    finally:
        _local.stale = before


def checkpoint() -> None:
    """Raise :class:`Cancelled` if this thread's run is inside :func:`cancellable` and stale."""
    stale = getattr(_local, "stale", None)
    if stale is not None and stale():
        raise Cancelled("the run was cancelled: its result is no longer wanted")
