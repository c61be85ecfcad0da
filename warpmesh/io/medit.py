"""Medit ``.mesh`` (ASCII) files written fast: the bytes meshio's writer gives, without its
loop of one Python ``format`` call per cell.

meshio writes every row of every block through ``str.format``: on the graded frog
(4.4 M points, 12.7 M tetrahedra, 7.7 M triangles) that is about a minute. Here the
integer rows (the cells' 1-based corners and their refs) are turned into digits by numpy
arithmetic a chunk of rows at a time: each number becomes a fixed-width row of bytes,
with NUL in place of leading zeros, a space or a newline after it, and the NULs are
dropped, which leaves exactly ``"%d %d ... %d\\n"``. The points keep meshio's own
``"{:.16e}"`` formatting (Python's correctly rounded repr digits), joined per chunk.
The result is byte for byte meshio's file (``tests/io/test_medit.py`` compares them).

:func:`read_medit` reads them back: the integer rows a line per thread in a Warp kernel,
the vertices by Python's correctly rounded ``float``; on the frog 8.5 s in a warm process
against meshio's 23 s (numpy's text scanner). Other Medit files go to meshio's reader.

Example
-------
>>> import os, tempfile, meshio, numpy as np
>>> m = meshio.Mesh(np.eye(4, 3), [("tetra", np.array([[0, 1, 2, 3]]))],
...                 point_data={"medit:ref": np.zeros(4, int)}, cell_data={"medit:ref": [np.array([7])]})
>>> with tempfile.TemporaryDirectory() as d:
...     write_medit(os.path.join(d, "t.mesh"), m)
...     text = open(os.path.join(d, "t.mesh")).read()
>>> text.split("Tetrahedra\\n")[1]
'1\\n1 2 3 4 7\\n\\nEnd\\n'
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import meshio
import meshio.medit._medit as meshio_medit
import numpy as np

from warpmesh.cells.types import REF_KEY
from warpmesh.errors import ReadError

__all__ = ["read_medit", "write_medit"]

#: Medit's block name and corner count of each meshio cell type it stores
MEDIT_BLOCKS = {"line": ("Edges", 2), "triangle": ("Triangles", 3), "quad": ("Quadrilaterals", 4),
                "tetra": ("Tetrahedra", 4), "wedge": ("Prisms", 6), "pyramid": ("Pyramids", 5),
                "hexahedron": ("Hexahedra", 8)}
#: rows formatted at a time (bounds the byte arrays of a chunk)
CHUNK_ROWS = 1 << 18


def write_medit(path, data, mesh=None, **kwargs) -> None:
    """Write ``data`` (a ``meshio.Mesh``) as an ASCII Medit file: the points with their refs
    (point data ``"medit:ref"``, else 1), then each block with its cell refs (cell data
    ``"medit:ref"``, else 1), corners 1-based. The signature of the format registry's
    writers (``mesh``, the warpmesh mesh, is not needed); ``kwargs`` must be empty.

    Raises
    ------
    ValueError
        An unknown keyword, or points of another dtype than float32 / float64.
    """
    if kwargs:
        raise ValueError(f"unknown options for Medit files: {sorted(kwargs)}")
    points = np.asarray(data.points)
    version = {np.dtype(np.float32): 1, np.dtype(np.float64): 2}.get(points.dtype)
    if version is None:
        raise ValueError(f"expected float32 or float64 'points' for a Medit file, got {points.dtype}")
    n, d = points.shape
    refs = data.point_data.get(REF_KEY)
    refs = np.ones(n, dtype=np.int64) if refs is None else np.asarray(refs)
    with open(path, "wb") as f:
        f.write(f"MeshVersionFormatted {version}\nDimension {d}\n\nVertices\n{n}\n".encode())
        line = " ".join(["{:.16e}"] * d) + " {:d}\n"
        for lo in range(0, n, CHUNK_ROWS):
            columns = [points[lo:lo + CHUNK_ROWS, j].tolist() for j in range(d)]
            f.write("".join(map(line.format, *columns, refs[lo:lo + CHUNK_ROWS].tolist())).encode())
        cell_refs = data.cell_data.get(REF_KEY)
        for k, block in enumerate(data.cells):
            if block.type not in MEDIT_BLOCKS:
                warnings.warn(f"Medit files have no {block.type} cells: not saved", stacklevel=2)
                continue
            name, corners = MEDIT_BLOCKS[block.type]
            cells = np.asarray(block.data)
            labels = np.ones(len(cells), dtype=np.int64) if cell_refs is None else np.asarray(cell_refs[k])
            f.write(f"\n{name}\n{len(cells)}\n".encode())
            for lo in range(0, len(cells), CHUNK_ROWS):
                rows = [cells[lo:lo + CHUNK_ROWS, j].astype(np.int64) + 1 for j in range(corners)]
                f.write(integer_rows([*rows, labels[lo:lo + CHUNK_ROWS]]))
        f.write(b"\nEnd\n")


def integer_rows(columns: list[np.ndarray]) -> bytes:
    """Equal-length integer columns as text, a row a line and a space between values (as
    ``%d`` writes them), by numpy arithmetic.

    >>> integer_rows([np.array([0, 12, -305]), np.array([7, -1, 4000000000])])
    b'0 7\\n12 -1\\n-305 4000000000\\n'
    """
    parts = []
    for j, column in enumerate(columns):
        parts.append(_digits(np.asarray(column, dtype=np.int64)))
        sep = np.full((len(column), 1), ord("\n") if j == len(columns) - 1 else ord(" "), dtype=np.uint8)
        parts.append(sep)
    block = np.concatenate(parts, axis=1)
    return block[block != 0].tobytes()


def _digits(values: np.ndarray) -> np.ndarray:
    """(m, 1 + w) uint8: each value's sign ('-' or NUL) and its w decimal digits, NUL in
    place of leading zeros (one digit for 0); w is the widest value's digit count."""
    magnitude = np.abs(values)  # (int64: |values| below 2^63)
    width = len(str(int(magnitude.max(initial=0))))
    out = np.zeros((len(values), 1 + width), dtype=np.uint8)
    out[values < 0, 0] = ord("-")
    rest = magnitude.copy()
    for k in range(width):  # the k-th digit from the right
        digit = (rest % 10).astype(np.uint8) + np.uint8(ord("0"))
        out[:, width - k] = digit if k == 0 else np.where(rest > 0, digit, np.uint8(0))
        rest //= 10
    return out


# ----------------------------------------------------------------------------- reading
#: meshio cell type and corner count of each Medit block read (Frey's and Dobrzynski's
#: spelling of hexahedra)
MEDIT_TYPES = {name.encode(): (t, k) for t, (name, k) in MEDIT_BLOCKS.items()} | {b"Hexaedra": ("hexahedron", 8)}
_WORD = re.compile(rb"[A-Za-z]+")
_COUNT = re.compile(rb"\s*(\d+)")


class _Unsupported(Exception):
    """A file the fast path does not read (comments, other keywords, rows over several
    lines, non-finite coordinates): meshio's reader takes it."""


def read_medit(path) -> meshio.Mesh:
    """Read an ASCII Medit ``.mesh`` file into a ``meshio.Mesh``: what meshio's reader
    returns (points with their refs as point data ``"medit:ref"``, blocks with theirs as
    cell data, corners 0-based), the integer rows parsed a line per thread by a Warp kernel
    (:func:`~warpmesh.kernels.text.parse_int_rows_kernel`) instead of numpy's text
    scanner.

    Files with comments, keywords beyond the vertices and the element blocks, or rows
    spread over several lines go to meshio's reader.

    Raises
    ------
    ReadError
        A file cut short or whose sections do not hold the rows they announce, naming it.

    Examples
    --------
    >>> import os, tempfile, numpy as np
    >>> m = meshio.Mesh(np.eye(4, 3), [("tetra", np.array([[0, 1, 2, 3]]))])
    >>> with tempfile.TemporaryDirectory() as d:
    ...     write_medit(os.path.join(d, "t.mesh"), m)
    ...     back = read_medit(os.path.join(d, "t.mesh"))
    >>> back.cells[0].data.tolist(), back.cell_data["medit:ref"][0].tolist()
    ([[0, 1, 2, 3]], [1])
    """
    raw = Path(path).read_bytes()
    try:
        return _read(raw)
    except _Unsupported:
        return meshio_medit.read(str(path))
    except (ValueError, IndexError) as exc:
        raise ReadError(f"could not read {str(path)!r} as medit: {type(exc).__name__}: {exc}") from exc


def _read(raw: bytes) -> meshio.Mesh:
    """The mesh of a file's bytes (:func:`read_medit`)."""
    if b"#" in raw:
        raise _Unsupported("comments")
    text = np.frombuffer(raw, dtype=np.uint8)
    dim = dtype = points = point_refs = None
    blocks, cell_refs = [], []
    at, ended = 0, False
    while (word := _WORD.search(raw, at)) is not None:
        if raw[at:word.start()].strip():
            raise _Unsupported("numbers outside a section")
        key, at = word.group(), word.end()
        if key == b"End":
            ended = True
            break
        if key in (b"MeshVersionFormatted", b"Dimension"):
            value, at = _count(raw, at, key)
            if key == b"Dimension":
                dim = value
            elif value in (1, 2):  # (3 and 4: 64-bit integers, binary .meshb only)
                dtype = np.float32 if value == 1 else np.float64
            else:
                raise _Unsupported(f"version {value}")
            continue
        if key != b"Vertices" and key not in MEDIT_TYPES:
            raise _Unsupported(key)
        n, at = _count(raw, at, key)
        starts = _row_starts(text, at, n)
        if key == b"Vertices":
            if dim is None or dtype is None:
                raise ValueError("Vertices before MeshVersionFormatted and Dimension")
            rows = _float_rows(raw[starts[0]:starts[-1]], n, dim + 1)
            points, point_refs = rows[:, :dim].astype(dtype), rows[:, dim].astype(np.int64)
        else:
            name, k = MEDIT_TYPES[key]
            rows = _int_rows(text, starts, k + 1)
            blocks.append((name, rows[:, :k] - 1))
            cell_refs.append(rows[:, k])
        at = int(starts[-1])
    if not ended:
        raise ValueError("no End keyword (a file cut short?)")
    if points is None:
        raise ValueError("no Vertices")
    if any(c.size and (c.min() < 0 or c.max() >= len(points)) for _, c in blocks):
        raise ValueError(f"cell corners outside the {len(points)} vertices")
    return meshio.Mesh(points, blocks, point_data={REF_KEY: point_refs}, cell_data={REF_KEY: cell_refs})


def _count(raw: bytes, at: int, key: bytes) -> tuple[int, int]:
    """The integer after a keyword (on its line or the next) and where it ends."""
    match = _COUNT.match(raw, at)
    if match is None:
        raise ValueError(f"no count after {key.decode()}")
    return int(match.group(1)), match.end()


def _row_starts(text: np.ndarray, at: int, n: int) -> np.ndarray:
    """(n + 1,) int64: where each of the n lines after the count line (which ends at
    ``at``) begins, and where the last of them ends (after its newline). The newlines are
    looked for in growing windows, so a section costs its own length, not the file's."""
    window = 64 * n + 1024
    while True:
        newlines = np.flatnonzero(text[at:at + window] == 10)
        if len(newlines) > n or at + window >= len(text):
            break
        window *= 2
    if len(newlines) < n:
        raise ValueError(f"expected {n} rows, found {max(len(newlines) - 1, 0)} lines")
    if n and text[at:at + newlines[0]].tobytes().strip():
        raise _Unsupported("a row on the count's line")
    starts = np.empty(n + 1, dtype=np.int64)
    starts[:n] = newlines[:n] + (at + 1)
    starts[n] = newlines[n] + at + 1 if len(newlines) > n else len(text)
    return starts


def _float_rows(body: bytes, n: int, columns: int) -> np.ndarray:
    """(n, columns) float64 of whitespace-separated numbers, by Python's correctly rounded
    ``float`` (numpy's parsers are no faster here)."""
    values = np.fromiter(map(float, body.split()), dtype=np.float64)
    if len(values) != n * columns:
        raise _Unsupported("vertices over several lines")
    if not np.all(np.isfinite(values)):
        raise _Unsupported("non-finite coordinates")
    return values.reshape(n, columns)


def _int_rows(text: np.ndarray, starts: np.ndarray, columns: int) -> np.ndarray:
    """(n, columns) int64 of the n lines beginning at ``starts[:n]``, a line per thread."""
    import warp as wp

    from warpmesh._util.parallel import cpu_view, launch_split
    from warpmesh.kernels import text as KX

    n = len(starts) - 1
    out = np.empty((n, columns), dtype=np.int64)
    bad = np.zeros(n, dtype=np.int8)
    if n:
        wp.load_module(KX, device="cpu")  # once here, not in the worker threads
        launch_split(KX.parse_int_rows_kernel, n, [cpu_view(text, wp.uint8), cpu_view(starts, wp.int64), columns],
                     [cpu_view(out, wp.int64), cpu_view(bad, wp.int8)])
        wp.synchronize_device("cpu")
    if bad.any():
        raise _Unsupported("rows that are not integers on a line each")
    return out
