"""meshio readers stopped where they would read past the end of a file forever.

Some of meshio's readers loop ``while True: line = f.readline()`` until they find a
keyword; on a file that is cut before it (a truncated Tecplot ``.dat`` or Kratos
``.mdpa``) or empty (a TetGen ``.node``) they never return, as ``readline`` returns ``""``
at the end of a file, again and again. :func:`guarded_reader` runs a reader with the
files it opens wrapped (the module's ``open`` and meshio's ``open_file``) so that asking
for lines past the end more than :data:`EMPTY_READS` times in a row raises
:class:`~warpmesh.errors.ReadError`; a reader that reaches the end once, or a few times,
is not affected. The wrapped files are real file objects (``numpy.fromfile`` reads them).

Binary readers (meshio's legacy VTK, gmsh) read arrays with ``numpy.fromfile(f, count=n)``,
which returns fewer values, silently, when the file ends first: a cut ``.vtk`` loaded with
refs read from the wrong bytes. For the call, the reader's package's modules see a numpy
whose ``fromfile`` raises :class:`~warpmesh.errors.ReadError` on such a short read.

Example
-------
>>> import os, tempfile
>>> def stubborn(path):  # a reader that waits for a keyword the file does not have
...     with open(path) as f:
...         while "End" not in f.readline():
...             pass
>>> path = os.path.join(tempfile.mkdtemp(), "cut.txt")
>>> _ = open(path, "w").write("Begin\\n1 2 3\\n")
>>> guarded_reader(stubborn, globals())(path)
Traceback (most recent call last):
...
warpmesh.errors.ReadError: the file ends before the reader found what it looks for (a cut or empty file?)
"""

from __future__ import annotations

import builtins
import io
import os
import sys
import threading
from collections.abc import Callable

from warpmesh.errors import ReadError

__all__ = ["guarded_reader", "guarded_open", "EMPTY_READS"]

#: reads past the end of a file in a row that count as a reader that will never stop
EMPTY_READS = 1000
_PATCH_LOCK = threading.RLock()
_MESSAGE = "the file ends before the reader found what it looks for (a cut or empty file?)"


class _Count:
    """Consecutive empty lines read; raises past :data:`EMPTY_READS`."""

    def _seen(self, line):
        if line:
            self._empty = 0
        else:
            self._empty = getattr(self, "_empty", 0) + 1
            if self._empty > EMPTY_READS:
                raise ReadError(_MESSAGE)
        return line


class _GuardedBinary(_Count, io.BufferedReader):
    def readline(self, size=-1):
        return self._seen(super().readline(size))


class _GuardedText(_Count, io.TextIOWrapper):
    def readline(self, size=-1):
        return self._seen(super().readline(size))


def guarded_open(file, mode="r", buffering=-1, encoding=None, errors=None, newline=None, *args, **kwargs):
    """``open``, with files opened for reading by path wrapped (see the module docstring)."""
    reading = set(mode) <= set("rbt") and "r" in mode
    if not reading or args or kwargs or not isinstance(file, (str, bytes, os.PathLike)):
        return builtins.open(file, mode, buffering, encoding, errors, newline, *args, **kwargs)
    raw = _GuardedBinary(io.FileIO(file, "r"), buffer_size=io.DEFAULT_BUFFER_SIZE if buffering in (-1, 0, 1)
                         else buffering)
    if "b" in mode:
        return raw
    return _GuardedText(raw, encoding=encoding, errors=errors, newline=newline)


class _StrictNumpy:
    """numpy, but ``fromfile`` with a ``count`` raises :class:`ReadError` when the file holds
    fewer values (the end of a cut file)."""

    def __init__(self, module):
        self._np = module

    def __getattr__(self, name):
        return getattr(self._np, name)

    def fromfile(self, file, *args, **kwargs):
        out = self._np.fromfile(file, *args, **kwargs)
        count = kwargs.get("count", args[1] if len(args) > 1 else -1)
        if count is not None and int(count) >= 0 and out.size < int(count):
            raise ReadError(f"the file ends inside an array of {int(count)} values, after {out.size} (a cut file?)")
        return out


def guarded_reader(reader: Callable, namespace: dict | None = None) -> Callable:
    """``reader`` run with ``open`` in its module (or in ``namespace``) and in
    ``meshio._files`` replaced by :func:`guarded_open`, and ``np`` in the modules of its
    package by a numpy whose ``fromfile`` refuses short reads, for the call."""

    def read(*args, **kwargs):
        spaces = [namespace if namespace is not None else vars(sys.modules[reader.__module__])]
        files = sys.modules.get("meshio._files")
        if files is not None:
            spaces.append(vars(files))
        package = reader.__module__.rpartition(".")[0] or reader.__module__
        numpy = sys.modules["numpy"]
        users = [vars(m) for name, m in list(sys.modules.items())
                 if m is not None and (name == package or name.startswith(package + "."))
                 and vars(m).get("np") is numpy]
        with _PATCH_LOCK:
            saved = [(ns, "open", ns.get("open", _MISSING)) for ns in spaces]
            saved += [(ns, "np", numpy) for ns in users]
            try:
                for ns in spaces:
                    ns["open"] = guarded_open
                strict = _StrictNumpy(numpy)
                for ns in users:
                    ns["np"] = strict
                return reader(*args, **kwargs)
            finally:
                for ns, name, old in reversed(saved):
                    if old is _MISSING:
                        ns.pop(name, None)
                    else:
                        ns[name] = old

    return read


_MISSING = object()
