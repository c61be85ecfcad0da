"""Partitioned output of a bricked run: one VTU piece per brick and a ``.pvtu`` listing them.

Each worker writes the piece of the brick it meshed (``<name>_brick<id>.vtu``, atomically:
a temporary file renamed, so a worker killed while writing leaves nothing half-written and
the retried brick writes it again); the ``.pvtu`` is rewritten (atomically too) as bricks
finish, so a reader sees the pieces done so far. Every piece carries the point array
``grid_edge_key``: the vertex's grid-edge key ``node * 8 + type`` in the whole grid, a
global vertex id that needs no coordination, equal in the pieces on both sides of a seam,
declared as the points' VTK global ids (``GlobalIds``), so any reader can weld them, as
:func:`warpmesh.distributed.seams.weld` does and ``wm.load("name.pvtu")``
(:mod:`warpmesh.io.pvtu`); triangle refs go into the cell array ``ref``. The directory
must be visible to every worker (a shared file system on a real cluster).

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

import os
import uuid
from pathlib import Path

import numpy as np

from warpmesh.io.pvtu import pvtu_text
from warpmesh.io.vtu import write_grid

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
    """One brick's triangles (faces (t, 3)) or tetrahedra ((t, 4)) as a VTU file
    (:func:`warpmesh.io.vtu.write_grid`), written atomically; ``keys``
    the point array named ``key``, ``refs`` (t,) the cell array ``ref`` or None."""
    path = Path(path)
    faces = np.asarray(faces)
    k = faces.shape[1]
    point_data = {key: np.asarray(keys, dtype=np.int64)}
    cell_data = {REF_ARRAY: [np.asarray(refs, dtype=np.int64)]} if refs is not None else {}
    cell_type = {3: "triangle", 4: "tetra"}[k]
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        write_grid(tmp, np.asarray(points, dtype=np.float64), [(cell_type, faces)], point_data, cell_data,
                   global_ids=key)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def write_pvtu(path, pieces: list[str], refs: bool, key: str = KEY_ARRAY) -> Path:
    """The ``.pvtu`` listing ``pieces`` (file names relative to it), written atomically;
    ``key`` declared as the points' global ids (``wm.load`` welds the pieces by it)."""
    path = Path(path)
    text = pvtu_text(pieces, [(key, "Int64", 1)], [(REF_ARRAY, "Int64", 1)] if refs else [], global_ids=key)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
