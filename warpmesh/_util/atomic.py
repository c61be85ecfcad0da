"""Atomic file writes: a temporary name next to the target, renamed over it when complete.

Nothing half-written is left on disk:

- an exception (or Ctrl-C) during the write removes the temporary;
- SIGTERM and SIGHUP during the write (main thread) are turned into ``SystemExit`` for its
  duration, so the same clean-up runs, and then the process exits with 128 + the signal;
- a SIGKILL cannot be caught: the temporary names carry the writer's process id, and the
  next write of the same path removes the temporaries of writers that are no longer alive.

Example
-------
>>> import pathlib, tempfile
>>> from warpmesh._util.atomic import atomic_path
>>> target = pathlib.Path(tempfile.mkdtemp()) / "out.txt"
>>> with atomic_path(target) as tmp:
...     _ = tmp.write_text("whole")
>>> target.read_text(), sorted(p.name for p in target.parent.iterdir())
('whole', ['out.txt'])
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import threading
import uuid
from collections.abc import Iterator
from pathlib import Path

__all__ = ["atomic_path", "temporary_name", "remove_stale", "exit_on_signals"]

#: signals turned into SystemExit while a write is in progress (the ones a user or a
#: scheduler sends to stop a process; SIGINT already raises KeyboardInterrupt)
SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


def temporary_name(path: Path, kind: str = "tmp") -> Path:
    """``.{name}.{pid}.{random}.{kind}`` next to ``path``: hidden, unique, owned by this process."""
    return path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:12]}.{kind}")


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):  # exists but belongs to someone else, or cannot tell
        return True
    return True


def remove_stale(path: Path) -> list[Path]:
    """Remove the temporaries of ``path`` left by writers that died (SIGKILL, power loss).

    Only names of :func:`temporary_name`'s form whose process id is not running are removed;
    another live process's write in progress is left alone. Returns what was removed.
    """
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.(\d+)\.[0-9a-f]{{12}}\.(tmp|tmpdir)$")
    removed = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return removed
    for p in siblings:
        m = pattern.match(p.name)
        if m is None or _alive(int(m.group(1))):
            continue
        with contextlib.suppress(OSError):
            shutil.rmtree(p) if p.is_dir() else p.unlink()
            removed.append(p)
    return removed


@contextlib.contextmanager
def exit_on_signals() -> Iterator[None]:
    """While inside, SIGTERM/SIGHUP raise ``SystemExit(128 + signal)`` in the main thread
    (so ``finally`` blocks run); the previous handlers come back on the way out. Elsewhere
    than the main thread (where handlers cannot be set) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []

    def handler(signum, frame):
        caught.append(signum)
        raise SystemExit(128 + signum)

    previous = {}
    for sig in SIGNALS:
        try:
            previous[sig] = signal.signal(sig, handler)
        except (ValueError, OSError):  # not settable here
            pass
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


@contextlib.contextmanager
def atomic_path(path, kind: str = "tmp") -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on normal exit rename it over ``path``,
    otherwise remove it. ``kind="tmpdir"`` yields a folder (created) whose files are moved
    next to ``path`` on success, the one named like ``path`` last.
    """
    path = Path(path)
    remove_stale(path)
    tmp = temporary_name(path, kind)
    with exit_on_signals():
        try:
            if kind == "tmpdir":
                tmp.mkdir()
            yield tmp
            if kind == "tmpdir":
                for f in sorted(tmp.iterdir(), key=lambda f: f.name == path.name):
                    os.replace(f, path.parent / f.name)
                tmp.rmdir()
            else:
                os.replace(tmp, path)
        finally:
            if tmp.is_dir():
                shutil.rmtree(tmp, ignore_errors=True)
            elif tmp.exists():
                tmp.unlink()
