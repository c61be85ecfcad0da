"""PLY files, read and written here: face properties (refs, labels) kept, which meshio's
PLY reader and writer do not.

What is read
    ``format ascii 1.0``, ``binary_little_endian 1.0`` and ``binary_big_endian 1.0``; every
    PLY scalar type (``char uchar short ushort int uint float double`` and their ``int8`` ...
    ``float64`` spellings, and the ``int64``/``uint64`` trimesh writes). The ``vertex`` element gives the points (``x y z``) and one
    point-data array per other scalar property; the ``face`` element gives triangles and
    quads from its ``vertex_indices`` (or ``vertex_index``) list, split into one block per
    type as meshio does (triangles first), and one cell-data array per scalar property.
    A property named ``ref`` (or meshio's ``medit:ref``) is read as the refs
    (:data:`~warpmesh.cells.types.REF_KEY`). Other elements (``edge``, ``material``, ...)
    are skipped with a warning.
What is refused, with a :class:`~warpmesh.errors.ReadError` naming the file
    A header without ``end_header``, a file that ends early (a cut file) or has bytes
    beyond its elements, tokens that are not numbers, faces of fewer than 3 or more than
    4 vertices (polygons: triangulate them first), indices out of range, a second list
    property in an element (per-face texture coordinates).
What is written
    Binary little endian by default (``binary=False``: ascii with 17 significant digits),
    ``double x y z``, each 1-D point-data array as a vertex property, the faces as
    ``property list uchar int vertex_indices`` (``uint`` past 2^31 points) followed by
    each 1-D cell-data array as a face property; the refs as ``int ref``. Integer data
    are written as the smallest PLY type that holds their values (int64 data past 32 bits
    are refused: PLY has no 64-bit integers); booleans as ``uchar``.

Other readers
    trimesh reads every property into ``metadata["_ply_raw"]`` (not into its face or
    vertex attributes); VTK (pyvista) reads the geometry and drops the vertex and face
    properties. meshio (5.3) reads the face properties of an ascii file only: its binary
    reader takes a face element with scalar properties as one list block followed by one
    value per property (not the interleaved rows of the PLY format) and fails, so it
    cannot read a binary ``.ply`` with refs or cell data. For meshio, save ascii
    (``mesh.save(path, binary=False)``) or ``.vtu`` (refs as ``medit:ref``, every
    cell-data array).

Binary faces are read one run of equal vertex counts at a time (the rows of a run are a
fixed-size record), so an all-triangle or all-quad file is one vectorised read; a file
alternating triangles and quads costs one step per run.

Example
-------
>>> import os, tempfile, meshio, numpy as np
>>> from warpmesh.io.ply import read_ply, write_ply
>>> m = meshio.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [("triangle", [[0, 1, 2], [1, 3, 2]])],
...                 cell_data={"medit:ref": [np.array([4, 7])]})
>>> with tempfile.TemporaryDirectory() as d:
...     back = read_ply(write_ply(os.path.join(d, "t.ply"), m))
>>> back.cells[0].data.tolist(), back.cell_data["medit:ref"][0].tolist()
([[0, 1, 2], [1, 3, 2]], [4, 7])
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import meshio
import numpy as np

from warpmesh.cells.types import REF_KEY
from warpmesh.errors import ReadError

__all__ = ["HEADER_BYTES", "PLY_TYPES", "read_ply", "write_ply"]

#: PLY scalar type names -> numpy kinds + sizes (both spellings of the 1.0 spec)
PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
    "int64": "i8", "uint64": "u8",  # not in the 1.0 spec, but trimesh writes them (read only)
}
#: numpy dtype string -> the PLY name written
_WRITE_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint",
                "f4": "float", "f8": "double"}
#: bytes searched for the end of the header (headers are a few hundred bytes)
HEADER_BYTES = 1 << 16
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_INDEX_NAMES = ("vertex_indices", "vertex_index")
_REF_NAMES = ("ref", REF_KEY)
_NAME = re.compile(r"^[^\s]+$")


@dataclass
class _Property:
    name: str
    kind: str  # numpy kind+size of the value ('i4', 'f8', ...)
    count: str | None = None  # numpy kind+size of a list's count; None for a scalar


@dataclass
class _Element:
    name: str
    n: int
    props: list


# ----------------------------------------------------------------------------- header
def _header(path: Path, head: bytes) -> tuple[str | None, list[_Element], int]:
    """(byte order or None for ascii, elements, offset of the body)."""
    def bad(why: str) -> ReadError:
        return ReadError(f"could not read {str(path)!r} as ply: {why}")

    if not head.startswith(b"ply"):
        raise bad("it does not start with 'ply'")
    end = re.search(rb"end_header[ \t]*\r?\n", head)
    if end is None:
        raise bad(f"the header has no 'end_header' line in its first {len(head)} bytes (a truncated file? "
                  "it may be cut)")
    try:
        lines = head[: end.start()].decode("ascii").splitlines()
    except UnicodeDecodeError as exc:
        raise bad(f"the header is not ascii text ({exc})") from exc
    order, elements = "missing", []
    for number, line in enumerate(lines[1:], start=2):
        words = line.split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        try:
            if words[0] == "format":
                if words[1] not in _FORMATS or words[2] != "1.0":
                    raise ValueError(f"unknown format {' '.join(words[1:])!r}")
                order = _FORMATS[words[1]]
            elif words[0] == "element":
                elements.append(_Element(words[1], int(words[2]), []))
                if elements[-1].n < 0:
                    raise ValueError("a negative count")
            elif words[0] == "property":
                if not elements:
                    raise ValueError("a property before any element")
                if words[1] == "list":
                    prop = _Property(words[4], PLY_TYPES[words[3]], PLY_TYPES[words[2]])
                    if prop.count[0] == "f":
                        raise ValueError("a list counted by a float")
                else:
                    prop = _Property(words[2], PLY_TYPES[words[1]])
                elements[-1].props.append(prop)
            else:
                raise ValueError(f"unknown keyword {words[0]!r}")
        except (IndexError, KeyError, ValueError) as exc:
            raise bad(f"header line {number} {line!r}: {exc}") from exc
    if order == "missing":
        raise bad("the header has no 'format' line")
    return order, elements, end.end()


# ----------------------------------------------------------------------------- body
class _Body:
    """The body of the file, read element by element: binary records or ascii tokens."""

    def __init__(self, path: Path, data: memoryview, order: str | None):
        self.path, self.order, self.at = path, order, 0
        if order is None:
            try:
                self.tokens = np.array(bytes(data).split(), dtype=np.float64)
            except ValueError as exc:
                raise ReadError(f"could not read {str(path)!r} as ply: a token of the ascii body is not a "
                                f"number ({exc})") from exc
            self.size = len(self.tokens)
        else:
            self.data = data
            self.size = len(data)

    def cut(self, element: str) -> ReadError:
        return ReadError(f"could not read {str(self.path)!r} as ply: the file ends inside its {element!r} "
                         "element (a truncated file? it may be cut)")

    def scalars(self, el: _Element, props: list, n: int) -> dict:
        """``n`` rows of scalar properties only."""
        if self.order is None:
            width = len(props)
            if self.at + n * width > self.size:
                raise self.cut(el.name)
            rows = self.tokens[self.at: self.at + n * width].reshape(n, width)
            self.at += n * width
            return {p.name: _exact(rows[:, i], p.kind, self.path) for i, p in enumerate(props)}
        dtype = np.dtype([(f"f{i}", self.order + p.kind) for i, p in enumerate(props)])
        if self.at + n * dtype.itemsize > self.size:
            raise self.cut(el.name)
        rows = np.frombuffer(self.data, dtype=dtype, count=n, offset=self.at)
        self.at += n * dtype.itemsize
        return {p.name: rows[f"f{i}"].astype(p.kind) for i, p in enumerate(props)}

    def with_list(self, el: _Element) -> list[tuple[int, dict]]:
        """The rows of an element with one list property, as runs (list length, {name: array}),
        the list as an (n, length) array."""
        lists = [i for i, p in enumerate(el.props) if p.count is not None]
        if len(lists) > 1:
            raise ReadError(f"could not read {str(self.path)!r} as ply: element {el.name!r} has "
                            f"{len(lists)} list properties; warpmesh reads one (the vertex indices)")
        j = lists[0]
        before, lst, after = el.props[:j], el.props[j], el.props[j + 1:]
        runs, left, window = [], el.n, 1024
        while left:
            k = self._peek_count(el, before, lst)
            props = [*before, _Property(lst.count, lst.count), *(_Property(f"{lst.name}.{q}", lst.kind)
                                                                 for q in range(k)), *after]
            props[len(before)].name = "#count"
            counts = self._peek_counts(props, len(before), min(left, window))
            differ = np.flatnonzero(counts != k)
            take = max(int(differ[0]) if len(differ) else len(counts), 1)  # the first row: a cut file
            rows = self.scalars(el, props, take)
            rows[lst.name] = np.column_stack([rows.pop(f"{lst.name}.{q}") for q in range(k)]) if k else \
                np.zeros((take, 0), dtype=lst.kind)
            rows.pop("#count")
            runs.append((k, rows))
            left -= take
            window = min(max(2 * take, 1024), 1 << 22)
        return runs

    def _peek_count(self, el: _Element, before: list, lst: _Property) -> int:
        """The list length of the next row (not consumed)."""
        start = self.at
        row = self.scalars(el, [*before, _Property("#count", lst.count)], 1)
        self.at = start
        k = int(row["#count"][0])
        if k < 0 or k > 1 << 16:
            raise ReadError(f"could not read {str(self.path)!r} as ply: a {el.name!r} row lists {k} items "
                            "(a garbage file?)")
        return k

    def _peek_counts(self, props: list, position: int, m: int) -> np.ndarray:
        """The field ``position`` (the list count) of up to ``m`` rows of fixed layout
        ``props``, as far as the file goes (not consumed, not checked: rows past the run are
        misaligned and only compared)."""
        if self.order is None:
            width = len(props)
            m = max(1, min(m, (self.size - self.at) // width))
            return self.tokens[self.at + position: self.at + m * width: width]
        dtype = np.dtype([(f"f{i}", self.order + p.kind) for i, p in enumerate(props)])
        m = max(1, min(m, (self.size - self.at) // dtype.itemsize))
        if self.at + m * dtype.itemsize > self.size:
            return np.zeros(0)
        return np.frombuffer(self.data, dtype=dtype, count=m, offset=self.at)[f"f{position}"]

    def finish(self) -> None:
        rest = self.size - self.at
        if self.order is None and rest:
            raise ReadError(f"could not read {str(self.path)!r} as ply: {rest} numbers after the last element")
        if self.order is not None and bytes(self.data[self.at:]).strip():
            raise ReadError(f"could not read {str(self.path)!r} as ply: {rest} bytes after the last element")


def _exact(column: np.ndarray, kind: str, path: Path) -> np.ndarray:
    """An ascii column as its declared type; integers must be whole numbers in range."""
    if kind[0] == "f":
        return column.astype(kind)
    info = np.iinfo(kind)
    if not np.all((column == np.round(column)) & (column >= info.min) & (column <= info.max)):
        raise ReadError(f"could not read {str(path)!r} as ply: an integer property holds non-integer or "
                        f"out-of-range values for {kind}")
    return column.astype(kind)


def read_ply(path) -> meshio.Mesh:
    """Read a PLY file (see the module docstring for what is kept and what is refused).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    meshio.Mesh
        Points (n, 3) float64, one ``triangle`` and/or ``quad`` block; point data and cell
        data per property, the refs as ``"medit:ref"``.

    Raises
    ------
    ReadError
        The file is not a PLY mesh warpmesh reads (the message names the file and why).

    Example
    -------
    >>> import os, tempfile
    >>> from warpmesh.io.ply import read_ply
    >>> text = b"ply\\nformat ascii 1.0\\nelement vertex 3\\nproperty float x\\nproperty float y\\n" \\
    ...        b"property float z\\nelement face 1\\nproperty list uchar int vertex_indices\\n" \\
    ...        b"property int ref\\nend_header\\n0 0 0\\n1 0 0\\n0 1 0\\n3 0 1 2 5\\n"
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = os.path.join(d, "t.ply"); _ = open(p, "wb").write(text)
    ...     m = read_ply(p)
    >>> m.cells[0].type, m.cell_data["medit:ref"][0].tolist()
    ('triangle', [5])
    """
    path = Path(path)
    raw = path.read_bytes()
    order, elements, start = _header(path, raw[:HEADER_BYTES])
    body = _Body(path, memoryview(raw)[start:], order)  # binary records are read in place
    points, point_data, blocks, cell_data = None, {}, [], {}
    for el in elements:
        if el.name == "vertex":
            if any(p.count is not None for p in el.props):
                raise ReadError(f"could not read {str(path)!r} as ply: the vertex element has a list property")
            values = body.scalars(el, el.props, el.n)
            if not all(c in values for c in "xyz"):
                raise ReadError(f"could not read {str(path)!r} as ply: the vertex element lacks x, y or z "
                                f"(has {[p.name for p in el.props]})")
            points = np.column_stack([values.pop(c).astype(np.float64) for c in "xyz"])
            point_data = {_data_name(k): v for k, v in values.items()}
        elif el.name == "face":
            names = [p.name for p in el.props if p.count is not None]
            if not names or names[0] not in _INDEX_NAMES:
                raise ReadError(f"could not read {str(path)!r} as ply: the face element has no "
                                f"'vertex_indices' list (has {[p.name for p in el.props]})")
            runs = body.with_list(el)
            blocks, cell_data = _face_blocks(path, runs, names[0])
        else:
            if any(p.count is not None for p in el.props):
                body.with_list(el)
            else:
                body.scalars(el, el.props, el.n)
            warnings.warn(f"{str(path)!r}: PLY element {el.name!r} ({el.n} rows) is not read", UserWarning,
                          stacklevel=2)
    body.finish()
    if points is None:
        raise ReadError(f"could not read {str(path)!r} as ply: the file has no vertex element")
    for t, c in blocks:
        if c.size and (c.min() < 0 or c.max() >= len(points)):
            raise ReadError(f"could not read {str(path)!r} as ply: a face refers to a vertex outside "
                            f"0..{len(points) - 1}")
    return meshio.Mesh(points, blocks, point_data=point_data, cell_data=cell_data)


def _data_name(name: str) -> str:
    return REF_KEY if name in _REF_NAMES else name


def _face_blocks(path: Path, runs: list, index_name: str) -> tuple[list, dict]:
    """Runs of faces -> one triangle and one quad block, cell data in the same order."""
    bad = sorted({k for k, _ in runs if k not in (3, 4)})
    if bad:
        raise ReadError(f"could not read {str(path)!r} as ply: faces of {bad} vertices; warpmesh reads "
                        "triangles and quads (triangulate polygons first)")
    blocks, data = [], {}
    for k, t in ((3, "triangle"), (4, "quad")):
        mine = [rows for kk, rows in runs if kk == k]
        if not mine:
            continue
        blocks.append((t, np.concatenate([r[index_name] for r in mine]).astype(np.int64)))
        for name in mine[0]:
            if name != index_name:
                data.setdefault(_data_name(name), []).append(np.concatenate([r[name] for r in mine]))
    return blocks, data


# ----------------------------------------------------------------------------- writing
def _ply_kind(name: str, values: np.ndarray) -> str:
    """The numpy kind+size written for a property (the smallest PLY type holding integers)."""
    if values.dtype == bool:
        return "u1"
    if values.dtype.kind == "f":
        return "f4" if values.dtype.itemsize <= 4 else "f8"
    if values.dtype.kind not in "iu":
        raise ValueError(f"expected numeric data for PLY property {name!r}, got dtype {values.dtype}")
    if values.dtype.itemsize <= 4:
        return values.dtype.str[1:]
    lo, hi = (int(values.min()), int(values.max())) if values.size else (0, 0)
    for kind in ("i4", "u4"):
        if np.iinfo(kind).min <= lo and hi <= np.iinfo(kind).max:
            return kind
    raise ValueError(f"PLY property {name!r} holds integers beyond 32 bits ({lo}..{hi}); PLY has no 64-bit "
                     "integers: store them as floats or drop them")


def _prop_name(name: str) -> str:
    if name == REF_KEY:
        return "ref"
    if not _NAME.match(name) or name in ("x", "y", "z", *_INDEX_NAMES):
        raise ValueError(f"expected a PLY property name without spaces and other than x, y, z and "
                         f"vertex_indices, got {name!r}; rename the data array")
    return name


def write_ply(path, mesh: meshio.Mesh, *, binary: bool = True) -> Path:
    """Write ``mesh`` (triangle and quad blocks, 1-D point and cell data) as PLY to ``path``.

    Not atomic by itself: :func:`warpmesh.io.files.save` writes to a temporary name.

    Parameters
    ----------
    path : str or os.PathLike
    mesh : meshio.Mesh
        Points (n, 2 or 3); blocks ``triangle`` / ``quad`` only; point data and cell data
        of one value per point / cell (``"medit:ref"`` is written as ``ref``).
    binary : bool
        Binary little endian (default) or ascii.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    ValueError
        Other cell types, data of several values per point or cell, integers past 32 bits,
        names that are not PLY tokens.

    Example
    -------
    >>> import os, tempfile, meshio
    >>> from warpmesh.io.ply import write_ply
    >>> m = meshio.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [("triangle", [[0, 1, 2]])])
    >>> with tempfile.TemporaryDirectory() as d:
    ...     print(write_ply(os.path.join(d, "t.ply"), m, binary=False).read_text().splitlines()[-1])
    3 0 1 2
    """
    path = Path(path)
    bad = [c.type for c in mesh.cells if c.type not in ("triangle", "quad")]
    if bad:
        raise ValueError(f"PLY files store triangle and quad faces, got {bad}; save those cells in another format")
    points = np.asarray(mesh.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"expected points of shape (n, 2) or (n, 3), got {points.shape}")
    if points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points))])
    vertex = [("x", points[:, 0]), ("y", points[:, 1]), ("z", points[:, 2])]
    for name, v in mesh.point_data.items():
        vertex.append((_prop_name(name), _one_column(name, v, len(points))))
    faces = [np.asarray(c.data) for c in mesh.cells]
    index_kind = "i4" if len(points) < 2**31 else "u4"
    face = []
    for name, per_block in mesh.cell_data.items():
        column = np.concatenate([np.asarray(a).reshape(len(f), -1) if np.asarray(a).ndim > 1 else np.asarray(a)
                                 for a, f in zip(per_block, faces, strict=True)])
        face.append((_prop_name(name), _one_column(name, column, sum(len(f) for f in faces))))
    vkinds = [("x", "f8"), ("y", "f8"), ("z", "f8"), *((n, _ply_kind(n, v)) for n, v in vertex[3:])]
    fkinds = [(n, _ply_kind(n, v)) for n, v in face]
    head = ["ply", f"format {'binary_little_endian' if binary else 'ascii'} 1.0", "comment written by warpmesh",
            f"element vertex {len(points)}", *(f"property {_WRITE_NAMES[k]} {n}" for n, k in vkinds),
            f"element face {sum(len(f) for f in faces)}",
            f"property list uchar {_WRITE_NAMES[index_kind]} vertex_indices",
            *(f"property {_WRITE_NAMES[k]} {n}" for n, k in fkinds), "end_header"]
    with open(path, "wb") as out:
        out.write(("\n".join(head) + "\n").encode("ascii"))
        _write_rows(out, [v for _, v in vertex], [k for _, k in vkinds], binary)
        offset = 0
        for f in faces:
            k = f.shape[1]
            cols = [np.full(len(f), k), *f.T, *(v[offset: offset + len(f)] for _, v in face)]
            kinds = ["u1", *[index_kind] * k, *(kk for _, kk in fkinds)]
            _write_rows(out, cols, kinds, binary)
            offset += len(f)
    return path


def _one_column(name: str, values, n: int) -> np.ndarray:
    v = np.asarray(values)
    if v.ndim == 2 and v.shape[1] == 1:
        v = v[:, 0]
    if v.shape != (n,):
        raise ValueError(f"PLY properties hold one value per vertex or face; {name!r} has shape {v.shape}")
    return v


def _write_rows(out, columns: list, kinds: list, binary: bool) -> None:
    n = len(columns[0])
    if binary:
        rows = np.empty(n, dtype=[(f"f{i}", "<" + k) for i, k in enumerate(kinds)])
        for i, c in enumerate(columns):
            rows[f"f{i}"] = c
        out.write(rows.tobytes())
        return
    fmts = ["%.17g" if k[0] == "f" else "%d" for k in kinds]
    table = np.empty((n, len(columns)), dtype=object)
    for i, (c, k) in enumerate(zip(columns, kinds, strict=True)):
        table[:, i] = np.asarray(c).astype(k)
    np.savetxt(out, table, fmt=fmts, delimiter=" ")
