"""Partitioned VTK unstructured grids (``.pvtu``): a small XML file that names its pieces,
``.vtu`` files beside it, and declares the arrays they share.

Reading (:func:`read_pvtu`) joins the pieces (each read by :func:`warpmesh.io.vtu.read_vtu`)
in the order the file lists them. When the file names a point array as the points'
global ids (``<PPointData GlobalIds="...">``, VTK's own attribute, which warpmesh's
bricked runs give their ``grid_edge_key`` and ``lattice_key`` arrays), the points that
carry one id are one point: a seam's copies are welded, each to its copy in the last
piece that has it, as the gathered mesh of a bricked run keeps it. Without global ids the
pieces are joined as VTK's reader joins them, points and all.

Writing (:func:`write_pvtu`, what ``Mesh.save("m.pvtu")`` calls) stores the mesh as one
piece, ``m_0.vtu`` (VTK's naming), and the ``.pvtu`` declaring its arrays.

Example
-------
>>> import os, tempfile, numpy as np
>>> square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
>>> with tempfile.TemporaryDirectory() as d:  # two triangles sharing the points of ids 1 and 2
...     for k, corners in enumerate(([0, 1, 2], [1, 3, 2])):
...         write_grid(os.path.join(d, f"m_{k}.vtu"), square[corners], [("triangle", np.array([[0, 1, 2]]))],
...                    {"id": np.array(corners)}, global_ids="id")
...     with open(os.path.join(d, "m.pvtu"), "w") as f:
...         _ = f.write(pvtu_text(["m_0.vtu", "m_1.vtu"], [("id", "Int64", 1)], [], global_ids="id"))
...     joined = read_pvtu(os.path.join(d, "m.pvtu"))
>>> len(joined.points), [c.data.tolist() for c in joined.cells]
(4, [[[0, 1, 3]], [[1, 2, 3]]])
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from xml.sax.saxutils import quoteattr

import meshio
import numpy as np

from warpmesh.errors import ReadError
from warpmesh.io.vtu import VTK_DTYPES, read_vtu, write_grid

__all__ = ["read_pvtu", "write_pvtu", "pvtu_text", "join_pieces", "piece_name"]

#: the largest distance between two copies of one global id, in units of the mesh's extent
#: (a bricked run's copies are equal bit for bit)
COPY_TOLERANCE = 1e-9


def piece_name(path, index: int) -> str:
    """The file name of piece ``index`` of ``path`` (VTK's ``<stem>_<index>.vtu``)."""
    return f"{Path(path).stem}_{index}.vtu"


def pvtu_text(pieces: list[str], point_arrays: list[tuple[str, str, int]], cell_arrays: list[tuple[str, str, int]],
              *, global_ids: str | None = None, points_type: str = "Float64") -> str:
    """The ``.pvtu`` XML naming ``pieces`` (file names relative to it) whose point and cell
    arrays are ``(name, VTK type, components)``; ``global_ids``, one of the point arrays'
    names, is declared as the points' global ids.

    Examples
    --------
    >>> print(pvtu_text(["m_0.vtu"], [("key", "Int64", 1)], [], global_ids="key"))  # doctest: +ELLIPSIS
    <?xml version="1.0"?>
    <VTKFile type="PUnstructuredGrid" ...>
      <PUnstructuredGrid GhostLevel="0">
        <PPointData GlobalIds="key">
          <PDataArray type="Int64" Name="key" NumberOfComponents="1"/>
        </PPointData>
    ...
    """
    if global_ids is not None and global_ids not in [name for name, _, _ in point_arrays]:
        raise ValueError(f"expected the name of a point array for 'global_ids', got {global_ids!r}")

    def section(tag: str, arrays, attributes: str = "") -> str:
        if not arrays:
            return ""
        rows = "".join(f'      <PDataArray type="{kind}" Name={quoteattr(name)} NumberOfComponents="{k}"/>\n'
                       for name, kind, k in arrays)
        return f"    <{tag}{attributes}>\n{rows}    </{tag}>\n"

    ids = "" if global_ids is None else f" GlobalIds={quoteattr(global_ids)}"
    return ('<?xml version="1.0"?>\n'
            '<VTKFile type="PUnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n'
            '  <PUnstructuredGrid GhostLevel="0">\n'
            + section("PPointData", point_arrays, ids) + section("PCellData", cell_arrays)
            + f'    <PPoints>\n      <PDataArray type="{points_type}" NumberOfComponents="3"/>\n    </PPoints>\n'
            + "".join(f"    <Piece Source={quoteattr(name)}/>\n" for name in pieces)
            + "  </PUnstructuredGrid>\n</VTKFile>\n")


def _declared(name: str, values: np.ndarray) -> tuple[str, str, int]:
    values = np.asarray(values)
    kind = VTK_DTYPES.get(values.dtype.newbyteorder("="))
    if kind is None:
        raise ValueError(f".vtu files cannot hold {values.dtype} data: {name!r}")
    return name, kind, int(np.prod(values.shape[1:], dtype=np.int64))


def write_pvtu(path, data: meshio.Mesh, mesh=None, *, level: int = 1, **kwargs) -> None:
    """Write ``data`` (a ``meshio.Mesh``) as ``path`` (``.pvtu``) and one piece beside it,
    :func:`piece_name` ``(path, 0)``, written by :func:`warpmesh.io.vtu.write_grid`. The
    signature of the format registry's writers (``mesh`` is not needed); the registry
    writes both files in a temporary folder and moves them out, the ``.pvtu`` last.

    Raises
    ------
    ValueError
        An unknown keyword, or what :func:`~warpmesh.io.vtu.write_grid` refuses.
    """
    if kwargs:
        raise ValueError(f"unknown options for .pvtu files: {sorted(kwargs)}")
    path = Path(path)
    piece = piece_name(path, 0)
    write_grid(path.parent / piece, data.points, [(b.type, b.data) for b in data.cells], data.point_data,
               data.cell_data, level=level)
    points = [_declared(name, v) for name, v in data.point_data.items()]
    cells = [_declared(name, np.concatenate([np.asarray(v) for v in per_block])) for name, per_block in
             data.cell_data.items()]
    path.write_text(pvtu_text([piece], points, cells))


def read_pvtu(path) -> meshio.Mesh:
    """Read a ``.pvtu`` file and its pieces into one ``meshio.Mesh`` (:func:`join_pieces`),
    the points that share a global id welded.

    Raises
    ------
    ReadError
        A file that is not a partitioned unstructured grid, lists no piece, names a piece
        that is missing or unreadable, or whose copies of a global id lie apart.

    Examples
    --------
    >>> read_pvtu("no/such.pvtu")
    Traceback (most recent call last):
    ...
    warpmesh.errors.ReadError: could not read 'no/such.pvtu' as pvtu: ...
    """
    path = Path(path)

    def fail(why: str) -> ReadError:
        return ReadError(f"could not read {str(path)!r} as pvtu: {why}")

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise fail(f"{type(exc).__name__}: {exc}") from exc
    grid = root.find("PUnstructuredGrid")
    if root.tag != "VTKFile" or root.get("type") != "PUnstructuredGrid" or grid is None:
        raise fail(f"expected a VTKFile of type PUnstructuredGrid, got {root.tag} of type {root.get('type')!r}")
    sources = [piece.get("Source") for piece in grid.findall("Piece")]
    if not sources or not all(sources):
        raise fail("it lists no pieces (<Piece Source=...>)" if not sources else "a <Piece> without a Source")
    declared = grid.find("PPointData")
    global_ids = None if declared is None else declared.get("GlobalIds")
    pieces = []
    for source in sources:
        piece = path.parent / source
        if not piece.is_file():
            raise fail(f"its piece {source!r} is missing (no file {str(piece)!r})")
        try:
            pieces.append(read_vtu(piece))
        except ReadError as exc:
            raise fail(f"its piece {source!r}: {exc}") from exc
    try:
        return join_pieces(pieces, global_ids)
    except ValueError as exc:
        raise fail(str(exc)) from exc


def join_pieces(pieces: list[meshio.Mesh], global_ids: str | None = None) -> meshio.Mesh:
    """One mesh of ``pieces``: their points in order (each piece's cells renumbered), their
    cell blocks in order, the point and cell arrays every piece has, the first piece's
    field data. With ``global_ids`` (a point array every piece has), points of one id are
    one point, the copy of the last piece that has it, at the place of that copy.

    Raises
    ------
    ValueError
        Copies of one global id that lie further apart than :data:`COPY_TOLERANCE` times the
        mesh's extent (ids that are not global).

    Examples
    --------
    >>> a = meshio.Mesh(np.eye(3), [("triangle", np.array([[0, 1, 2]]))], point_data={"id": np.array([5, 6, 7])})
    >>> b = meshio.Mesh(np.eye(3), [("triangle", np.array([[0, 2, 1]]))], point_data={"id": np.array([5, 6, 7])})
    >>> [c.data.tolist() for c in join_pieces([a, b], "id").cells]
    [[[0, 1, 2]], [[0, 2, 1]]]
    """
    starts = np.cumsum([0] + [len(p.points) for p in pieces])
    points = np.concatenate([np.asarray(p.points) for p in pieces])
    cells = [(b.type, np.asarray(b.data) + start) for p, start in zip(pieces, starts) for b in p.cells]
    point_data = {name: np.concatenate([np.asarray(p.point_data[name]) for p in pieces])
                  for name in pieces[0].point_data if all(name in p.point_data for p in pieces)}
    cell_data = {name: [np.asarray(v) for p in pieces for v in p.cell_data[name]]
                 for name in pieces[0].cell_data if all(name in p.cell_data for p in pieces)}
    if global_ids is not None and global_ids in point_data:
        ids = point_data[global_ids].reshape(len(points), -1)[:, 0]
        # each point -> the last copy of its id: the first of the reversed ids
        _, first, inverse = np.unique(ids[::-1], return_index=True, return_inverse=True)
        to_copy = (len(ids) - 1 - first)[inverse.reshape(-1)[::-1]]
        apart = float(np.abs(points - points[to_copy]).max(initial=0.0))
        extent = float(np.ptp(points, axis=0).max(initial=0.0)) if len(points) else 0.0
        if apart > COPY_TOLERANCE * max(extent, np.finfo(float).tiny):
            raise ValueError(f"points with one global id ({global_ids!r}) lie {apart:.3g} apart (the mesh's "
                             f"extent is {extent:.3g}): the ids are not global")
        keep = to_copy == np.arange(len(ids))
        number = np.cumsum(keep) - 1
        renumber = number[to_copy]
        points = points[keep]
        point_data = {name: v[keep] for name, v in point_data.items()}
        cells = [(t, renumber[c]) for t, c in cells]
    return meshio.Mesh(points, cells, point_data=point_data, cell_data=cell_data,
                       field_data=dict(pieces[0].field_data))
