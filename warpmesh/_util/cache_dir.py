"""The one rule for where warpmesh keeps its on-disk caches.

Three caches live under one folder: the generated marching-cubes tables
(``tables/``, :mod:`warpmesh.kernels.table_cache`), the generated tape kernels
(:mod:`warpmesh.frep.codegen`) and the probe of meshio's formats
(:mod:`warpmesh.io.formats`). The folder is, first match wins:

1. ``$WARPMESH_CACHE_DIR`` when set and not empty;
2. ``$XDG_CACHE_HOME/warpmesh`` when ``XDG_CACHE_HOME`` is set and not empty;
3. ``~/.cache/warpmesh``.

A folder that cannot be created or written is not an error: :func:`writable_cache_dir`
returns None and warns once per process and folder, and the callers work without a cache
(tables are generated and the formats probed in every process); only the compiled tape
evaluator, which must import a file, then refuses with a message naming
``WARPMESH_CACHE_DIR``.

Example
-------
>>> from warpmesh._util.cache_dir import cache_root, writable_cache_dir
>>> cache_root("tables") == cache_root() / "tables"
True
>>> folder = writable_cache_dir()  # None (and one warning) if it cannot be written
>>> folder is None or folder.is_dir()
True
"""

from __future__ import annotations

import os
import threading
import uuid
import warnings
from pathlib import Path

__all__ = ["ENV_VAR", "cache_root", "writable_cache_dir"]

#: the environment variable that overrides every other rule
ENV_VAR = "WARPMESH_CACHE_DIR"

_warned: set[str] = set()
_checked: dict[str, bool] = {}
_lock = threading.Lock()


def cache_root(sub: str | None = None) -> Path:
    """The cache folder by the rule of this module (not created, not checked).

    Parameters
    ----------
    sub : str, optional
        A sub-folder name (``"tables"``); None for the folder itself.

    Returns
    -------
    pathlib.Path

    Example
    -------
    >>> import os
    >>> from warpmesh._util.cache_dir import cache_root
    >>> saved = {k: os.environ.pop(k, None) for k in ("WARPMESH_CACHE_DIR", "XDG_CACHE_HOME")}
    >>> os.environ["XDG_CACHE_HOME"] = "/tmp/xdg"
    >>> str(cache_root())
    '/tmp/xdg/warpmesh'
    >>> _ = [os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v) for k, v in saved.items()]
    """
    own = os.environ.get(ENV_VAR)
    if own:
        root = Path(own).expanduser()
    else:
        xdg = os.environ.get("XDG_CACHE_HOME")
        root = (Path(xdg).expanduser() if xdg else Path.home() / ".cache") / "warpmesh"
    return root / sub if sub else root


def writable_cache_dir(sub: str | None = None) -> Path | None:
    """:func:`cache_root` created and checked writable, or None (no cache) with one
    ``RuntimeWarning`` per process and folder that says why and names ``WARPMESH_CACHE_DIR``.

    Parameters
    ----------
    sub : str, optional
        A sub-folder name; None for the folder itself.

    Returns
    -------
    pathlib.Path or None

    Example
    -------
    >>> import os, tempfile
    >>> from warpmesh._util.cache_dir import writable_cache_dir
    >>> saved = os.environ.get("WARPMESH_CACHE_DIR")
    >>> os.environ["WARPMESH_CACHE_DIR"] = tempfile.mkdtemp()
    >>> writable_cache_dir("tables").name
    'tables'
    >>> _ = os.environ.pop("WARPMESH_CACHE_DIR") if saved is None else os.environ.__setitem__("WARPMESH_CACHE_DIR", saved)
    """
    folder = cache_root(sub)
    key = str(folder)
    with _lock:
        ok = _checked.get(key)
        if ok is None:
            ok, why = _try_write(folder)
            _checked[key] = ok
            if not ok and key not in _warned:
                _warned.add(key)
                warnings.warn(f"warpmesh: cannot write the cache folder {key!r} ({why}); working without a "
                              f"cache (slower starts); set {ENV_VAR} to a writable folder", RuntimeWarning,
                              stacklevel=3)
    return folder if ok else None


def _try_write(folder: Path) -> tuple[bool, str]:
    """Create ``folder`` and write then remove a probe file in it."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = folder / f".probe.{os.getpid()}.{uuid.uuid4().hex[:8]}.tmp"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        return False, f"{type(exc).__name__}: {exc.strerror or exc}"
    return True, ""
