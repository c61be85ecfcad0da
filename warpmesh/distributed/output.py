"""Partitioned output of a bricked run: one VTU piece per brick and a ``.pvtu`` listing them.

Each worker writes the piece of the brick it meshed (``<name>_brick<id>.vtu``, atomically:
a temporary file renamed, so a worker killed while writing leaves nothing half-written and
the retried brick writes it again); the ``.pvtu`` is rewritten (atomically too) as bricks
finish, so a reader sees the pieces done so far. Every piece carries the point array
``grid_edge_key``: the vertex's grid-edge key ``node * 8 + type`` in the whole grid, a
global vertex id that needs no coordination, equal in the pieces on both sides of a seam
(so any reader can weld them, as :func:`warpmesh.distributed.seams.weld` does); triangle
refs go into the cell array ``ref``. The directory must be visible to every worker (a
shared file system on a real cluster).

Example
-------
>>> import numpy as np, pyvista as pv, tempfile, pathlib
>>> from warpmesh.distributed.output import write_piece, write_pvtu
>>> d = pathlib.Path(tempfile.mkdtemp())
>>> piece = write_piece(d / "m_brick0.vtu", np.eye(3), np.array([[0, 1, 2]]), None, np.array([8, 16, 24]))
>>> grid = pv.read(write_pvtu(d / "m.pvtu", [piece.name], refs=False))
>>> grid.n_points, grid.n_cells
(3, 1)
"""

from __future__ import annotations

import base64
import os
import uuid
import zlib
from pathlib import Path

import numpy as np

KEY_ARRAY = "grid_edge_key"
#: the point array of a tetrahedral domain's pieces: the vertex's key in the global lattice
#: (:meth:`warpmesh.solid.lattice.Lattice.fill_keyed`)
LATTICE_KEY_ARRAY = "lattice_key"
REF_ARRAY = "ref"


def output_paths(output) -> tuple[Path, str]:
    """(directory, name) of ``output``, a ``.pvtu`` path whose directory exists."""
    if not isinstance(output, (str, os.PathLike)):
        raise TypeError(f"expected a path ending in .pvtu for 'output', got {type(output).__name__}")
    path = Path(output)
    if path.suffix != ".pvtu":
        raise ValueError(f"expected a path ending in .pvtu for 'output' (the pieces go beside it), got {str(output)!r}")
    if not path.parent.is_dir():
        raise ValueError(f"expected an existing directory for 'output', got {str(path.parent)!r}")
    return path.parent, path.stem


def piece_path(directory: Path, name: str, index: int) -> Path:
    return Path(directory) / f"{name}_brick{index:05d}.vtu"


def write_piece(path, points, faces, refs, keys, key: str = KEY_ARRAY) -> Path:
    """One brick's triangles (faces (t, 3)) or tetrahedra ((t, 4)) as a VTU file (binary,
    zlib-compressed, inline base64 as meshio and VTK read it), written atomically; ``keys``
    the point array named ``key``, ``refs`` (t,) the cell array ``ref`` or None."""
    path = Path(path)
    faces = np.asarray(faces)
    n, k = len(points), faces.shape[1]
    index = np.int32 if n < 2**31 and len(faces) * k < 2**31 else np.int64
    point_data = [(key, np.asarray(keys, dtype=np.int64))]
    cell_data = [(REF_ARRAY, np.asarray(refs, dtype=np.int64))] if refs is not None else []
    cells = [("connectivity", faces.astype(index, copy=False).reshape(-1)),
             ("offsets", np.arange(k, k * len(faces) + 1, k, dtype=index)),
             ("types", np.full(len(faces), _VTK_TYPES[k], dtype=np.uint8))]
    parts = ['<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" '
             'header_type="UInt64" compressor="vtkZLibDataCompressor">\n<UnstructuredGrid>\n'
             f'<Piece NumberOfPoints="{n}" NumberOfCells="{len(faces)}">\n'.encode()]
    for tag, arrays in (("PointData", point_data), ("CellData", cell_data),
                        ("Points", [(None, np.asarray(points, dtype=np.float64))]), ("Cells", cells)):
        parts.append(f"<{tag}>\n".encode())
        parts += [_data_array(name, a) for name, a in arrays]
        parts.append(f"</{tag}>\n".encode())
    parts.append(b"</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        tmp.write_bytes(b"".join(parts))
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


_VTK_TYPES = {3: 5, 4: 10}  # VTK_TRIANGLE, VTK_TETRA
_VTU_NAMES = {np.dtype(np.float64): "Float64", np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32",
              np.dtype(np.uint8): "UInt8"}
_BLOCK_BYTES = 1 << 20  # uncompressed bytes per zlib block


def _data_array(name: str | None, a: np.ndarray) -> bytes:
    """One DataArray element, its values little-endian, zlib-compressed in blocks (level 1: four
    times faster than zlib's default here, files about 10 % larger), base64 encoded: the header
    (blocks, block size, last block's size, each block's compressed size; UInt64) then the blocks."""
    a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
    raw = a.tobytes()
    blocks = [zlib.compress(raw[i:i + _BLOCK_BYTES], 1) for i in range(0, len(raw), _BLOCK_BYTES)] or \
        [zlib.compress(b"", 1)]
    last = len(raw) - (len(blocks) - 1) * _BLOCK_BYTES if raw else 0
    header = np.array([len(blocks), _BLOCK_BYTES, last] + [len(b) for b in blocks], dtype="<u8")
    attrs = f' Name="{name}"' if name is not None else ""
    attrs += f' NumberOfComponents="{a.shape[1]}"' if a.ndim == 2 else ""
    return (f'<DataArray type="{_VTU_NAMES[np.dtype(a.dtype.newbyteorder("="))]}"{attrs} format="binary">'.encode()
            + base64.b64encode(header.tobytes()) + base64.b64encode(b"".join(blocks)) + b"</DataArray>\n")


def write_pvtu(path, pieces: list[str], refs: bool, key: str = KEY_ARRAY) -> Path:
    """The ``.pvtu`` listing ``pieces`` (file names relative to it), written atomically."""
    path = Path(path)
    cell = f'    <PCellData>\n      <PDataArray type="Int64" Name="{REF_ARRAY}"/>\n    </PCellData>\n' if refs else ""
    text = ('<?xml version="1.0"?>\n'
            '<VTKFile type="PUnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n'
            '  <PUnstructuredGrid GhostLevel="0">\n'
            f'    <PPointData>\n      <PDataArray type="Int64" Name="{key}"/>\n    </PPointData>\n'
            f'{cell}'
            '    <PPoints>\n      <PDataArray type="Float64" NumberOfComponents="3"/>\n    </PPoints>\n'
            + "".join(f'    <Piece Source="{name}"/>\n' for name in pieces) +
            '  </PUnstructuredGrid>\n</VTKFile>\n')
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
