"""Count Warp module loads and compiles: the check that an edit loop never waits on Warp.

Warp builds a module (C++ for the CPU, PTX for CUDA) when one of its kernels is first
launched on a device, or again when the module's hash changed (a kernel redefined). Both
go through ``Module.load``; a load that does work creates a new ``ModuleExec`` in the
module's ``execs`` table, and a compile goes through ``Module._compile``. This module
wraps those two methods for the duration of a ``with`` block and counts what happened.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.preview.instrument import count_module_loads
>>> ball = wm.sphere(1.0)
>>> _ = wm.evaluate(ball, np.zeros((4, 3)))            # loads the interpreter once
>>> with count_module_loads() as counts:
...     _ = wm.evaluate(ball, np.ones((4, 3)))
>>> counts.loads, counts.compiles
(0, 0)
"""

from __future__ import annotations

import contextlib
import threading
from dataclasses import dataclass, field

import warp as wp

_lock = threading.Lock()


def _module_class():
    """Warp's Module class (``warp._src.context`` since 1.10, ``warp.context`` before)."""
    src = getattr(wp, "_src", None)
    ctx = getattr(src, "context", None) if src is not None else None
    module = getattr(ctx, "Module", None) or getattr(getattr(wp, "context", None), "Module", None)
    if module is None or not hasattr(module, "load"):
        raise RuntimeError("cannot find warp's Module class to count module loads "
                           f"(warp {wp.__version__}); this check needs warp >= 1.9")
    return module


@dataclass
class LoadCounts:
    """What Warp did inside a :func:`count_module_loads` block.

    ``loads``: modules made executable on a device (built or read from Warp's kernel
    cache); ``compiles``: of those, the ones compiled from source; ``modules``: their names.
    """

    loads: int = 0
    compiles: int = 0
    modules: list = field(default_factory=list)


@contextlib.contextmanager
def count_module_loads():
    """Count Warp module loads and compiles in the block (all threads).

    Yields
    ------
    LoadCounts
        Filled in while the block runs.
    """
    module_cls = _module_class()
    counts = LoadCounts()
    load, compile_ = module_cls.load, getattr(module_cls, "_compile", None)

    def counted_load(self, *args, **kwargs):
        before = {id(e) for e in self.execs.values()}
        result = load(self, *args, **kwargs)
        if any(id(e) not in before for e in self.execs.values()):
            with _lock:
                counts.loads += 1
                counts.modules.append(self.name)
        return result

    def counted_compile(self, *args, **kwargs):
        with _lock:
            counts.compiles += 1
        return compile_(self, *args, **kwargs)

    module_cls.load = counted_load
    if compile_ is not None:
        module_cls._compile = counted_compile
    try:
        yield counts
    finally:
        module_cls.load = load
        if compile_ is not None:
            module_cls._compile = compile_
