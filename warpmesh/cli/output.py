"""Mesh files named on the command line: checked before any work, read and written with
messages that name the user's path and the CLI flag (never a temporary file or a Python
argument).

The extensions come from :data:`warpmesh.io.files.FILE_FORMATS`; which of them store a
given cell type is asked of the writers themselves (a one-cell mesh saved per format into
a temporary folder, once per process), so the help and the checks follow the formats
:mod:`warpmesh.io.files` registers. meshio's other formats that round-trip a mesh on this
installation (:func:`warpmesh.io.files.file_formats`, probed once) are taken too, as
``wm.load`` and ``Mesh.save`` take them (.off, .inp, .xdmf, ...), with the cell types their
probe found.

Examples
--------
>>> from warpmesh.cli.output import output_extensions
>>> ".stl" in output_extensions(("triangle",)), ".stl" in output_extensions(("line",))
(True, False)
"""

from __future__ import annotations

import os
import tempfile
import warnings
from functools import lru_cache
from pathlib import Path

__all__ = ["output_extensions", "check_output", "check_folder", "save_output", "read_mesh", "add_ascii_argument"]

#: a one-cell mesh of each probed type, on the corners of the unit tetrahedron
_PROBE_POINTS = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_PROBE_CELLS = {"line": (0, 1), "triangle": (0, 1, 2), "tetra": (0, 1, 2, 3)}


@lru_cache(maxsize=None)
def output_extensions(cells: tuple[str, ...]) -> tuple[str, ...]:
    """The extensions of :data:`~warpmesh.io.files.FILE_FORMATS` whose writer stores all of ``cells``.

    Parameters
    ----------
    cells : tuple of str
        Cell types among 'line', 'triangle', 'tetra'; ``()`` gives every extension.
    """
    from warpmesh.io.files import FILE_FORMATS, save
    from warpmesh.mesh import Mesh

    if not cells:
        return tuple(FILE_FORMATS)
    probe = Mesh(_PROBE_POINTS, {t: [_PROBE_CELLS[t]] for t in cells})
    found = []
    with tempfile.TemporaryDirectory(prefix="warpmesh-formats-") as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for ext in FILE_FORMATS:
            try:
                save(probe, Path(folder) / f"probe{ext}")
            except ValueError:  # the format does not store these cells
                continue
            found.append(ext)
    return tuple(found)


def extensions_text(cells: tuple[str, ...]) -> str:
    """``".vtu .vtk ..."`` for a help string.

    Examples
    --------
    >>> extensions_text(("tetra",))
    '.vtu .pvtu .vtk .msh .mesh'
    """
    return " ".join(output_extensions(cells))


def check_folder(path, flag: str) -> Path:
    """Raise ValueError unless a file can be created at ``path`` (its folder exists and takes a new file).

    A probe file is created in the folder and removed at once: the only test that holds
    for every user, root included, and for read-only file systems.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise ValueError(f"expected a file name for {flag}, got the folder {str(path)!r}")
    if not folder.exists():
        raise ValueError(f"cannot write {flag} {str(path)!r}: the folder {str(folder)!r} does not exist")
    if not folder.is_dir():
        raise ValueError(f"cannot write {flag} {str(path)!r}: {str(folder)!r} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".check", dir=folder)
    except OSError as exc:
        raise ValueError(f"cannot write {flag} {str(path)!r}: no new file can be made in the folder "
                         f"{str(folder)!r} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)
    return path


def check_output(path, *, cells: tuple[str, ...] = (), flag: str = "-o/--output", ascii: bool = False) -> Path | None:
    """Raise ValueError now, before any work, if the mesh cannot be written to ``path``.

    Checks the extension (known, storing ``cells``, and with an ascii encoding when
    ``ascii``: ``--ascii``), that the folder exists and that a file can be created in it.
    ``path`` None (a command whose output is optional, run without it): nothing to check,
    unless ``ascii`` asks for an encoding of a file that will not be written.

    Examples
    --------
    >>> check_output("part.xyz", cells=("triangle",))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: unknown extension '.xyz' for -o/--output 'part.xyz'; expected one of .vtu .pvtu .vtk .msh .mesh .ply .obj .stl (or another format meshio reads and writes: ... .off ...)
    """
    from warpmesh.io.files import FILE_FORMATS, TWO_ENCODINGS

    if path is None:
        if ascii:
            raise ValueError(f"--ascii sets the encoding of the file written with {flag}; give {flag} too")
        return None
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"expected a file name for {flag}, got the folder {str(path)!r}")
    ext = path.suffix.lower()
    able = output_extensions(tuple(cells))
    if ext not in FILE_FORMATS:
        _check_meshio_extension(ext, cells, flag, path, able, ascii)
        return check_folder(path, flag)
    if ext not in able:
        raise ValueError(f"{ext} files cannot store {' and '.join(cells)} cells ({flag} {str(path)!r}); "
                         f"expected one of {' '.join(able)}")
    if ascii and FILE_FORMATS[ext] not in TWO_ENCODINGS:
        exts = " ".join(e for e, name in FILE_FORMATS.items() if name in TWO_ENCODINGS)
        raise ValueError(f"--ascii applies to {exts} files (written binary by default); got {flag} {str(path)!r}")
    return check_folder(path, flag)


def add_ascii_argument(parser) -> None:
    """The ``--ascii`` flag of a command that writes a mesh file (:func:`save_output`)."""
    parser.add_argument("--ascii", action="store_true",
                        help="write .vtk, .ply or .stl as ascii instead of binary (e.g. a .ply with labels "
                             "for meshio, whose binary PLY reader cannot read face properties)")


def save_output(mesh, path, flag: str = "-o/--output", ascii: bool = False) -> Path:
    """``mesh.save(path)`` (atomic; ``ascii``: ``binary=False``), with OS errors reported for
    ``path`` and ``flag``."""
    try:
        return mesh.save(path, binary=False if ascii else None)
    except OSError as exc:
        raise ValueError(f"cannot write {flag} {str(path)!r}: {exc.strerror or exc}") from None


def read_mesh(path, flag: str = "input"):
    """``warpmesh.load(path)`` with an unknown extension reported for ``flag`` and ``path``."""
    import warpmesh as wm
    from warpmesh.io.files import FILE_FORMATS

    ext = Path(path).suffix.lower()
    if Path(path).is_dir():
        raise ValueError(f"{flag} {str(path)!r} is a folder; expected a mesh file")
    if ext not in FILE_FORMATS:
        _check_meshio_extension(ext, (), flag, Path(path), tuple(FILE_FORMATS), False)
    return wm.load(path)


def _check_meshio_extension(ext: str, cells: tuple[str, ...], flag: str, path: Path, able: tuple, ascii: bool) -> None:
    """An extension of meshio's other formats (:func:`warpmesh.io.files.file_formats`: those that
    round-trip a mesh on this installation, probed once): known, storing ``cells``, and with no
    ``--ascii`` (their encoding is meshio's choice); else a ValueError naming ``flag``."""
    from warpmesh.io.files import file_formats
    from warpmesh.io.formats import format_support

    name = file_formats().get(ext)
    if name is None:
        raise ValueError(f"unknown extension {ext!r} for {flag} {str(path)!r}; expected one of {' '.join(able)} "
                         f"(or another format meshio reads and writes: {' '.join(e for e in file_formats() if e not in able)})")
    missing = [c for c in cells if c not in format_support()[name].cells]
    if missing:
        raise ValueError(f"{ext} files ({name}) cannot store {' and '.join(missing)} cells ({flag} {str(path)!r}); "
                         f"expected one of {' '.join(able)}")
    if ascii:
        raise ValueError(f"--ascii applies to the .vtk .ply .stl files warpmesh writes; got {flag} {str(path)!r}")
