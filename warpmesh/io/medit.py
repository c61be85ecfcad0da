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

import warnings

import numpy as np

from warpmesh.cells.types import REF_KEY

__all__ = ["write_medit"]

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
