"""Warp's start-up for warpmesh's device code: once per process, before the first kernel use.

The package ``warpmesh.kernels`` runs :func:`start` when it is first imported, and every
host module that launches a kernel imports its kernels from that package, so every path
to a launch goes through here (``import warpmesh`` alone does not import Warp at all).
:func:`start` does three things, once:

1. Warp's log level is raised to warnings, so its banner and its per-module load lines
   do not drown warpmesh's results (a level the user set higher is kept).
2. ``wp.init()`` runs with file descriptor 2 sent to a temporary file, and everything
   Warp printed is written back except the line "Could not find or load the NVIDIA CUDA
   driver": Warp's native library prints it on every machine without a GPU, to a user
   who never asked for one (asking for a CUDA device that is not there gets warpmesh's
   own error from the entry point instead).
3. A compile of a warpmesh kernel module (a Warp kernel cache without it: a new machine,
   a new Warp version, edited kernels) prints one line on stderr before it starts::

       warpmesh: compiling Warp kernels, first run only (about 40 s)

   once per process, and only when a compile actually happens: a warm cache prints
   nothing. The estimate adds :data:`COMPILE_SECONDS` (measured on a 2-core 2.5 GHz
   Xeon) over the warpmesh kernel modules imported so far whose cache folder is missing.
   :func:`compile_seconds` is the wall time spent compiling them in this process (the
   command line shows it as its own stage).
4. :func:`freeze_at_exit` is registered with :mod:`atexit`: at interpreter exit it collects
   the garbage once (:func:`gc.collect`: unreachable reference cycles are finalised, their
   ``__del__`` run, as Python's first exit collection would) and then moves every object
   still alive out of the reach of the later collections of Python's finalisation
   (:func:`gc.freeze`). Those run over every object still alive; Warp alone leaves about
   93,000 (its builtins' tables), warpmesh's kernel modules add about 37,000, and they made
   up most of the 0.1 s a process spent exiting after its first mesh
   (``benchmarks/bench_startup.py``). What changes: a reference cycle that is still
   reachable at exit (from a module's globals) and only becomes garbage as the modules are
   cleared is not collected, so its ``__del__`` does not run; Python never promises to run
   ``__del__`` for objects alive at exit. Exit handlers registered after warpmesh started
   run before it, with the collector untouched; a program that needs the exit's
   collections back calls ``atexit.unregister(freeze_at_exit)``.

Warp compiles a module inside ``Module.load``, from its private ``Module._compile``,
which returns whether it compiled; that method is wrapped here to see a compile coming
(the binary it is about to write is missing). If a later Warp changes it, the wrapper
steps aside: no message, no error.

Example
-------
>>> from warpmesh.kernels.startup import start, compile_seconds
>>> start()  # idempotent; importing warpmesh.kernels already ran it
>>> import warp as wp
>>> wp.get_device("cpu").is_cpu, compile_seconds() >= 0.0
(True, True)
"""

from __future__ import annotations

import atexit
import functools
import gc
import os
import sys
import tempfile
import threading
import time

import warp as wp

#: the line Warp's native code prints when it finds no CUDA driver
NO_DRIVER = "Could not find or load the NVIDIA CUDA driver"
#: the one line printed when warpmesh's kernels compile ({seconds}: the estimate)
COMPILE_NOTICE = "warpmesh: compiling Warp kernels, first run only (about {seconds} s)"
#: Warp modules of warpmesh's kernels are named after their Python modules
KERNEL_PREFIX = "warpmesh.kernels."
#: compile seconds of each kernel module on the CPU (2-core Xeon 2.5 GHz, Warp 1.19, measured
#: one module at a time into an empty cache); a module missing here counts DEFAULT_COMPILE_SECONDS
COMPILE_SECONDS = {"tape": 4.4, "block_grid": 11.5, "emit": 7.6, "intersect": 2.0, "numbering": 0.6, "octree": 2.9,
                   "stuffing": 4.9}
DEFAULT_COMPILE_SECONDS = 5.0

__all__ = ["start", "init_warp", "compile_seconds", "freeze_at_exit", "NO_DRIVER", "COMPILE_NOTICE",
           "COMPILE_SECONDS"]

_lock = threading.Lock()
_state = {"started": False, "announced": False, "active": 0, "since": 0.0, "seconds": 0.0}


def start() -> None:
    """Warp's start-up for warpmesh, once per process (log level, quiet init, compile notice, quick exit)."""
    with _lock:
        if _state["started"]:
            return
        _state["started"] = True
    atexit.register(freeze_at_exit)
    if wp.config.log_level < wp.LOG_WARNING:  # Warp's banner and module-load lines would drown the results
        wp.config.log_level = wp.LOG_WARNING
    _watch_compiles()
    init_warp()


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


def freeze_at_exit() -> None:
    """At interpreter exit: collect the garbage once, then keep what is alive out of the exit's
    later garbage collections.

    Registered by :func:`start` (see the module docstring, point 4); calling it earlier would
    also exempt the live objects from every later collection, so it is meant for exit only.

    Example
    -------
    >>> import atexit
    >>> from warpmesh.kernels.startup import freeze_at_exit
    >>> atexit.unregister(freeze_at_exit)  # this program wants Python's full collections at exit
    """
    gc.collect()
    gc.freeze()


def compile_seconds() -> float:
    """Wall seconds this process has spent compiling warpmesh's kernel modules (0.0 with a warm cache)."""
    with _lock:
        extra = time.perf_counter() - _state["since"] if _state["active"] else 0.0
        return _state["seconds"] + extra


def _estimate() -> int:
    """Seconds the compiles ahead should take: the imported kernel modules not in the cache."""
    total = 0.0
    for name, module in list(wp._src.context.user_modules.items()):
        if not name.startswith(KERNEL_PREFIX) or not module.kernels:
            continue
        try:
            cached = os.path.isdir(os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier()))
        except Exception:  # noqa: BLE001  (an estimate only: count the module)
            cached = False
        if not cached:
            total += COMPILE_SECONDS.get(name[len(KERNEL_PREFIX):], DEFAULT_COMPILE_SECONDS)
    return max(1, round(total / 5.0) * 5 if total >= 10 else round(total))  # to 5 s above 10 s


def _watch_compiles() -> None:
    module_cls = getattr(wp._src.context, "Module", None)
    original = getattr(module_cls, "_compile", None)
    if original is None or getattr(original, "_warpmesh_watch", False):
        return

    @functools.wraps(original)
    def _compile(self, device=None, output_dir=None, output_name=None, *args, **kwargs):
        try:
            ours = str(self.name).startswith(KERNEL_PREFIX) and bool(output_dir) and bool(output_name)
            fresh = ours and not os.path.exists(os.path.join(output_dir, output_name))
        except Exception:  # noqa: BLE001  (never stand in Warp's way)
            fresh = False
        if not fresh:
            return original(self, device, output_dir, output_name, *args, **kwargs)
        with _lock:
            announce = not _state["announced"]
            _state["announced"] = True
        if announce:
            sys.stderr.write(COMPILE_NOTICE.format(seconds=_estimate()) + "\n")
            sys.stderr.flush()
        with _lock:
            if _state["active"] == 0:
                _state["since"] = time.perf_counter()
            _state["active"] += 1
        try:
            return original(self, device, output_dir, output_name, *args, **kwargs)
        finally:
            with _lock:
                _state["active"] -= 1
                if _state["active"] == 0:
                    _state["seconds"] += time.perf_counter() - _state["since"]

    _compile._warpmesh_watch = True
    module_cls._compile = _compile
