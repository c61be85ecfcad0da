"""The host-side mesh: points, typed cell blocks, physical attributes and data.

A :class:`Mesh` checks itself on construction and is immutable (its arrays are
read-only); operations return new meshes (:meth:`Mesh.replace`). Derived connectivity
and statistics are cached.

Layout
    ``points`` (n, d) float64, d = 2 or 3. ``cells`` maps meshio cell-type names to
    (m, k) int64 blocks, one block per type, in insertion order. ``point_refs`` (n,)
    int and ``cell_refs`` {type: (m,) int} are the physical attributes of seed §17.5
    (a block without refs has ref 0). ``point_data`` {name: (n, ...)}; ``cell_data``
    {name: {type: (m, ...)}} with an entry for every block (meshio's layout is
    {name: [array per block]}; :meth:`Mesh.to_meshio` / :meth:`Mesh.from_meshio`
    convert). Refs travel as arrays named ``REF_KEY`` (``"medit:ref"``) in meshio,
    pyvista and trimesh objects, and as ``"gmsh:physical"`` in gmsh files. Refs that
    are all zero are read back as "no refs" (medit and gmsh always store one).

Files (:meth:`Mesh.save`, :func:`load`), what each format keeps:

======  =======  =============================  ====================================
ext     format   cells                          besides points (precision) and cells
======  =======  =============================  ====================================
.vtu    vtu      all                            everything (float64)
.vtk    vtk      all                            everything (legacy binary, float64)
.msh    gmsh     all                            gmsh 2.2 binary: cell refs as
                                                gmsh:physical (= gmsh:geometrical),
                                                point refs and point data, cell data
                                                only with a single block
.mesh   medit    line tri quad tetra pyramid    point refs, cell refs (Medit ascii,
                 wedge hexahedron               17 digits); 2D kept 2D
.ply    ply      triangle quad                  point refs and point data (binary)
.obj    obj      triangle quad                  nothing else (17 digits)
.stl    stl      triangle                       nothing else (binary float32;
                                                points are merged and renumbered)
======  =======  =============================  ====================================

Every format but Medit stores 3D points; 2D meshes get z = 0 and come back 3D unless
``load(..., dim=2)``. Whatever a format cannot store is dropped with a ``UserWarning``.

Examples
--------
>>> import numpy as np
>>> from warpmesh.mesh import Mesh
>>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
>>> m
Mesh(np=3, dim=2, cells={triangle: 1})
>>> m.stats()["area"]
0.5
"""

from __future__ import annotations

import errno
import os
import uuid
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Literal

import meshio
import numpy as np

from . import topology as _topo
from ._conventions import INDEX_DTYPE, REAL_DTYPE
from .errors import ReadError
from .quality import quality_summary

__all__ = ["Mesh", "load", "CELL_TYPES", "FILE_FORMATS", "REF_KEY"]

#: meshio cell-type name -> (nodes per cell, topological dimension, VTK cell type id)
CELL_TYPES: Mapping[str, tuple[int, int, int]] = MappingProxyType(
    {
        "vertex": (1, 0, 1),
        "line": (2, 1, 3),
        "line3": (3, 1, 21),
        "triangle": (3, 2, 5),
        "triangle6": (6, 2, 22),
        "quad": (4, 2, 9),
        "quad8": (8, 2, 23),
        "quad9": (9, 2, 28),
        "tetra": (4, 3, 10),
        "tetra10": (10, 3, 24),
        "hexahedron": (8, 3, 12),
        "hexahedron20": (20, 3, 25),
        "hexahedron27": (27, 3, 29),
        "wedge": (6, 3, 13),
        "wedge15": (15, 3, 26),
        "pyramid": (5, 3, 14),
        "pyramid13": (13, 3, 27),
    }
)
_VTK_TO_NAME = {vtk: name for name, (_, _, vtk) in CELL_TYPES.items()}
#: VTK pixel/voxel -> quad/hexahedron node order. Other types share VTK's order: meshio's
#: wedge permutation (0 2 1 3 5 4, used by its vtu/vtk files) gives negative cell sizes in
#: VTK 9.x (pyvista compute_cell_sizes), so pyvista conversions keep wedges as they are.
_VTK_EXTRA = {8: ("quad", [0, 1, 3, 2]), 11: ("hexahedron", [0, 1, 3, 2, 4, 5, 7, 6])}
_POLY_TYPES = ("vertex", "line", "triangle", "quad")  # what a pyvista PolyData holds

#: name of the refs arrays in meshio, pyvista and trimesh objects
REF_KEY = "medit:ref"
_GMSH_REF, _GMSH_GEO = "gmsh:physical", "gmsh:geometrical"


@dataclass(frozen=True)
class _Format:
    name: str
    ext: str
    meshio_name: str
    write_kwargs: dict = field(default_factory=dict)
    cell_types: tuple[str, ...] | None = None  # None: every type
    keeps_2d: bool = False


_FORMATS = (
    _Format("vtu", ".vtu", "vtu", {"binary": True}),
    _Format("vtk", ".vtk", "vtk", {"binary": True}),
    _Format("gmsh", ".msh", "gmsh22", {"binary": True}),
    _Format(
        "medit",
        ".mesh",
        "medit",
        {},
        ("line", "triangle", "quad", "tetra", "pyramid", "wedge", "hexahedron"),
        True,
    ),
    _Format("ply", ".ply", "ply", {"binary": True}, ("triangle", "quad")),
    _Format("obj", ".obj", "obj", {}, ("triangle", "quad")),
    _Format("stl", ".stl", "stl", {"binary": True}, ("triangle",)),
)
#: file extension -> format name, as chosen by :meth:`Mesh.save` and :func:`load`
FILE_FORMATS: Mapping[str, str] = MappingProxyType({f.ext: f.name for f in _FORMATS})
FileFormat = Literal["vtu", "vtk", "gmsh", "medit", "ply", "obj", "stl"]


def _find_format(path: Path, file_format: str | None) -> _Format:
    if file_format is not None:
        for f in _FORMATS:
            if f.name == file_format:
                return f
        raise ValueError(
            f"unknown file_format {file_format!r}; expected one of {[f.name for f in _FORMATS]}"
        )
    for f in _FORMATS:
        if path.suffix.lower() == f.ext:
            return f
    raise ValueError(
        f"unknown mesh file extension {path.suffix!r} in {str(path)!r}; expected one of "
        f"{list(FILE_FORMATS)} or pass file_format= one of {[f.name for f in _FORMATS]}"
    )


# ----------------------------------------------------------------------------- validation
def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, copy=True)
    arr.setflags(write=False)
    return arr


def _native(value) -> np.ndarray:
    """``value`` as an array in native byte order (the VTK reader returns big-endian)."""
    arr = np.asarray(value)
    return arr.astype(arr.dtype.newbyteorder("=")) if arr.dtype.byteorder not in "=|" else arr


def _int_array(value, name: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.size == 0 and arr.dtype.kind not in "iu":
        arr = arr.astype(INDEX_DTYPE)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"expected an integer array for {name}, got dtype {arr.dtype}")
    return arr


def _check_points(points) -> np.ndarray:
    arr = np.asarray(points)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected a float array for 'points', got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"expected 'points' of shape (n, 2) or (n, 3), got shape {arr.shape}")
    arr = arr.astype(REAL_DTYPE, copy=False)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"expected finite coordinates in 'points', got {arr[i].tolist()} at row {i} "
            f"({bad.sum()} bad rows)"
        )
    return arr


def _check_cells(cells, n: int, d: int) -> dict[str, np.ndarray]:
    if isinstance(cells, Mapping):
        pairs = list(cells.items())
    elif isinstance(cells, (list, tuple)):
        pairs = [(c.type, c.data) if isinstance(c, meshio.CellBlock) else tuple(c) for c in cells]
        if any(len(p) != 2 for p in pairs):
            raise TypeError(
                "expected (type, array) pairs in the list 'cells', got an item of another length"
            )
    else:
        raise TypeError(
            f"expected a mapping {{cell type: (m, k) array}} or a list of (type, array) pairs "
            f"for 'cells', got {type(cells).__name__}; e.g. cells={{'triangle': faces}}"
        )
    out: dict[str, np.ndarray] = {}
    for name, block in pairs:
        if name not in CELL_TYPES:
            raise ValueError(
                f"unknown cell type {name!r} in 'cells'; expected one of {list(CELL_TYPES)}"
            )
        if name in out:
            raise ValueError(
                f"expected one block per cell type in 'cells', got {name!r} twice; concatenate them"
            )
        k, tdim, _ = CELL_TYPES[name]
        arr = _int_array(block, f"cells[{name!r}]")
        if arr.size == 0:
            arr = arr.reshape(0, k)
        if arr.ndim != 2 or arr.shape[1] != k:
            raise ValueError(
                f"expected cells[{name!r}] of shape (m, {k}) ({name} has {k} nodes), "
                f"got shape {arr.shape}"
            )
        if tdim > d:
            raise ValueError(f"expected {d}D cells for {d}D 'points', got {tdim}D {name!r} cells")
        if arr.size and arr.min() < 0:
            raise ValueError(f"expected non-negative indices in cells[{name!r}], got {arr.min()}")
        if arr.size and arr.max() >= n:
            raise ValueError(
                f"expected indices < n_points = {n} in cells[{name!r}], got {arr.max()}"
            )
        out[name] = _frozen(arr.astype(INDEX_DTYPE, copy=False))
    return out


def _check_data(data, length: int, name: str, *, integer: bool = False) -> np.ndarray:
    arr = _int_array(data, name) if integer else np.asarray(data)
    if arr.ndim == 0 or arr.shape[0] != length:
        raise ValueError(f"expected {name} of length {length}, got shape {arr.shape}")
    if integer and arr.ndim != 1:
        raise ValueError(f"expected {name} of shape ({length},), got shape {arr.shape}")
    return _frozen(arr.astype(INDEX_DTYPE) if integer else arr)


def _set_dim(points: np.ndarray, dim) -> np.ndarray:
    """Drop a zero z column (dim=2) or append one (dim=3); dim=None keeps ``points``."""
    if dim not in (None, 2, 3):
        raise ValueError(f"expected dim None, 2 or 3, got {dim!r}")
    if dim == 2 and points.ndim == 2 and points.shape[1] == 3:
        if np.any(points[:, 2] != 0):
            raise ValueError("expected z == 0 everywhere for dim=2, got non-zero z; keep dim=None")
        return points[:, :2]
    if dim == 3 and points.ndim == 2 and points.shape[1] == 2:
        return np.column_stack([points, np.zeros(len(points), dtype=points.dtype)])
    return points


def _check_mapping(value, name: str) -> Mapping:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"expected a dict for '{name}', got {type(value).__name__}")
    return value


# ----------------------------------------------------------------------------- Mesh
class Mesh:
    """An immutable unstructured mesh (see the module docstring for the layout).

    Parameters
    ----------
    points : (n, 2) or (n, 3) float
    cells : dict {str: (m, k) int} or list of (str, (m, k) int)
        Cell blocks keyed by meshio type name (:data:`CELL_TYPES`).
    point_data : dict {str: (n, ...) array}, optional
    cell_data : dict {str: {cell type: (m, ...) array}}, optional
        An entry for every block.
    point_refs : (n,) int, optional
    cell_refs : dict {cell type: (m,) int}, optional
        Blocks left out have ref 0.
    info : dict, optional
        Free-form facts from the producer (timings, counts, resolution), merged into
        :meth:`stats`.

    Raises
    ------
    TypeError
        Non-numeric points, non-integer indices or refs, wrong container types.
    ValueError
        Non-finite coordinates, wrong shapes, unknown cell type, wrong number of nodes
        per cell, negative or out-of-range indices, mismatched data lengths.

    Examples
    --------
    >>> pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    >>> m = Mesh(pts, [("triangle", [[0, 1, 2]])], cell_refs={"triangle": [7]})
    >>> m.n_points, m.n_cells, m.dim, m.cell_refs["triangle"].tolist()
    (3, 1, 3, [7])
    """

    def __init__(
        self,
        points,
        cells,
        *,
        point_data=None,
        cell_data=None,
        point_refs=None,
        cell_refs=None,
        info=None,
    ):
        pts = _check_points(points)
        n, d = pts.shape
        self._points = _frozen(pts)
        self._cells = _check_cells(cells, n, d)
        sizes = {t: len(c) for t, c in self._cells.items()}
        self._point_refs = (
            None if point_refs is None else _check_data(point_refs, n, "'point_refs'", integer=True)
        )
        crefs = _check_mapping(cell_refs, "cell_refs")
        for t in crefs:
            if t not in sizes:
                raise ValueError(
                    f"expected cell_refs keys among the cell types {list(sizes)}, got {t!r}"
                )
        self._cell_refs = {
            t: _check_data(r, sizes[t], f"cell_refs[{t!r}]", integer=True) for t, r in crefs.items()
        } or None  # an empty dict means no refs
        pdata = _check_mapping(point_data, "point_data")
        self._point_data = {k: _check_data(v, n, f"point_data[{k!r}]") for k, v in pdata.items()}
        self._cell_data = {}
        for key, per_type in _check_mapping(cell_data, "cell_data").items():
            per_type = _check_mapping(per_type, f"cell_data[{key!r}]")
            if set(per_type) != set(sizes):
                raise ValueError(
                    f"expected cell_data[{key!r}] keys {list(sizes)} (one per block), "
                    f"got {list(per_type)}"
                )
            self._cell_data[key] = MappingProxyType(
                {t: _check_data(per_type[t], sizes[t], f"cell_data[{key!r}][{t!r}]") for t in sizes}
            )
        if REF_KEY in self._point_data or REF_KEY in self._cell_data:
            raise ValueError(
                f"expected no {REF_KEY!r} array in point_data/cell_data; "
                "pass it as point_refs/cell_refs"
            )
        self._info = dict(_check_mapping(info, "info"))

    # ---------------------------------------------------------------- accessors
    points = property(lambda self: self._points, doc="(n, d) float64, read-only.")
    cells = property(
        lambda self: MappingProxyType(self._cells), doc="{type: (m, k) int64}, read-only."
    )
    point_refs = property(lambda self: self._point_refs, doc="(n,) int64 or None.")
    cell_refs = property(
        lambda self: None if self._cell_refs is None else MappingProxyType(self._cell_refs),
        doc="{type: (m,) int64} or None.",
    )
    point_data = property(lambda self: MappingProxyType(self._point_data), doc="{name: (n, ...)}.")
    cell_data = property(
        lambda self: MappingProxyType(self._cell_data), doc="{name: {type: (m, ...)}}."
    )
    info = property(
        lambda self: MappingProxyType(self._info), doc="Producer facts merged into stats()."
    )
    n_points = property(lambda self: len(self._points), doc="Number of points.")
    n_cells = property(
        lambda self: sum(len(c) for c in self._cells.values()), doc="Number of cells, all blocks."
    )
    dim = property(lambda self: self._points.shape[1], doc="Geometric dimension, 2 or 3.")

    @property
    def triangles(self) -> np.ndarray:
        """(m, 3) int64: the ``"triangle"`` block, or an empty (0, 3) array."""
        return self._cells.get("triangle", np.zeros((0, 3), dtype=INDEX_DTYPE))

    @cached_property
    def _edge_data(self):
        return _topo.unique_edges(self.triangles)

    @property
    def edges(self) -> np.ndarray:
        """(e, 2) int64: unique edges of the triangle block (cached)."""
        return self._edge_data[0]

    def replace(self, **changes) -> Mesh:
        """A new mesh with some constructor arguments changed (the others are kept).

        Examples
        --------
        >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> m.replace(point_refs=[1, 2, 3]).point_refs.tolist()
        [1, 2, 3]
        """
        args = dict(
            points=self._points,
            cells=self._cells,
            point_data=self._point_data,
            cell_data=self._cell_data,
            point_refs=self._point_refs,
            cell_refs=self._cell_refs,
            info=self._info,
        )
        unknown = set(changes) - set(args)
        if unknown:
            raise TypeError(f"expected keywords among {sorted(args)}, got {sorted(unknown)}")
        args.update(changes)
        return Mesh(args.pop("points"), args.pop("cells"), **args)

    def __repr__(self) -> str:
        blocks = ", ".join(f"{t}: {len(c)}" for t, c in self._cells.items())
        extra = "".join(
            f", {k}"
            for k, v in (("point_refs", self._point_refs), ("cell_refs", self._cell_refs))
            if v is not None
        )
        return f"Mesh(np={self.n_points}, dim={self.dim}, cells={{{blocks}}}{extra})"

    # ---------------------------------------------------------------- statistics
    @cached_property
    def _stats(self) -> dict:
        tri, tdims = self.triangles, [CELL_TYPES[t][1] for t in self._cells]
        top = max(tdims, default=-1)
        s: dict = {
            "np": self.n_points,
            "ne": sum(len(c) for t, c in self._cells.items() if CELL_TYPES[t][1] == top),
            "n_cells": self.n_cells,
            "n_triangles": len(tri),
            "n_tetra": len(self._cells.get("tetra", ())),
        }
        for key in (
            "watertight",
            "manifold",
            "oriented",
            "euler",
            "components",
            "genus",
            "area",
            "volume",
        ):
            s[key] = None
        if len(tri):
            counts = self._edge_data[2]
            s["watertight"] = bool(np.all(counts == 2))
            s["manifold"] = bool(np.all(counts <= 2)) and _topo.is_vertex_manifold(
                tri, self.n_points
            )
            s["oriented"] = _topo.is_consistently_oriented(tri)
            s["euler"] = _topo.euler_characteristic(None, tri)
            s["components"] = _topo.connected_components(tri)[0]
            if s["watertight"] and s["manifold"] and s["oriented"]:
                s["genus"] = (2 * s["components"] - s["euler"]) // 2
            s["area"] = float(_topo.face_areas(self._points, tri).sum())
            if s["watertight"] and self.dim == 3:
                s["volume"] = _topo.signed_volume(self._points, tri)
        if "tetra" in self._cells:
            p = self._points[self._cells["tetra"]]
            e1, e2, e3 = (p[:, j] - p[:, 0] for j in (1, 2, 3))
            s["volume"] = float(np.einsum("ij,ij->", e1, np.cross(e2, e3)) / 6.0)
        q = (
            quality_summary(self._points, self._cells)
            if ("tetra" in self._cells or len(tri))
            else {}
        )
        s["mean_q"], s["worst_q"] = q.get("mean_q"), q.get("worst_q")
        s["bounds"] = (
            _frozen(np.stack([self._points.min(axis=0), self._points.max(axis=0)]))
            if self.n_points
            else None
        )
        return s

    def stats(self) -> dict:
        """Counts, topology, measures and quality, merged over ``self.info``.

        Returns
        -------
        dict
            ``np``, ``ne`` (cells of the highest topological dimension), ``n_cells``,
            ``n_triangles``, ``n_tetra``; of the triangle block (None without one):
            ``watertight`` (every edge in two faces), ``manifold`` (edge and vertex),
            ``oriented``, ``euler`` (V - E + F over referenced vertices), ``components``
            (edge-connected), ``genus`` (total, ``(2 components - euler) / 2``, only when
            watertight, manifold and oriented), ``area``, ``volume`` (signed: of the
            closed 3D surface, or the sum of tetra volumes); ``mean_q``, ``worst_q`` (seed
            eq. 16.15 over tetra if any, else triangles); ``bounds`` (2, d). Every key of
            ``self.info`` is included too; computed keys win on a clash.

        Examples
        --------
        >>> import trimesh
        >>> s = Mesh.from_trimesh(trimesh.creation.torus(1.0, 0.3)).stats()
        >>> s["watertight"], s["euler"], s["genus"]
        (True, 0, 1)
        """
        return {**self._info, **self._stats}

    # ---------------------------------------------------------------- helpers
    def _points3(self) -> np.ndarray:
        if self.dim == 3:
            return np.asarray(self._points)
        return np.column_stack([self._points, np.zeros(self.n_points, dtype=REAL_DTYPE)])

    def _block_refs(self, t: str) -> np.ndarray:
        refs = None if self._cell_refs is None else self._cell_refs.get(t)
        return np.zeros(len(self._cells[t]), dtype=INDEX_DTYPE) if refs is None else refs

    @staticmethod
    def _from_parts(points, blocks, point_data, cell_data, dim, info) -> Mesh:
        """Build from blocks that may repeat a type; pull the refs out of the data arrays."""
        points = _set_dim(np.asarray(points, dtype=REAL_DTYPE), dim)
        names = list(dict.fromkeys(t for t, _ in blocks))
        cells = {t: np.concatenate([np.asarray(c) for u, c in blocks if u == t]) for t in names}
        point_data = {k: _native(v) for k, v in point_data.items()}
        cell_data = {
            k: {
                t: np.concatenate(
                    [_native(a) for (u, _), a in zip(blocks, v, strict=True) if u == t]
                )
                for t in names
            }
            for k, v in cell_data.items()
        }
        point_refs = point_data.pop(REF_KEY, None)
        if point_refs is not None and point_refs.dtype.kind == "f":
            if not np.all(point_refs == np.round(point_refs)):
                raise ValueError(
                    f"expected integer point refs {REF_KEY!r}, got non-integral values"
                )
            point_refs = point_refs.astype(INDEX_DTYPE)
        cell_refs = next((cell_data.pop(k) for k in (REF_KEY, _GMSH_REF) if k in cell_data), None)
        if cell_refs is not None and _GMSH_GEO in cell_data:
            if all(np.array_equal(cell_data[_GMSH_GEO][t], cell_refs[t]) for t in names):
                del cell_data[_GMSH_GEO]
        if point_refs is not None and not np.any(point_refs):
            point_refs = None
        if cell_refs is not None and not any(np.any(r) for r in cell_refs.values()):
            cell_refs = None
        return Mesh(
            points,
            cells,
            point_data=point_data,
            cell_data=cell_data,
            point_refs=point_refs,
            cell_refs=cell_refs,
            info=info,
        )

    # ---------------------------------------------------------------- meshio
    def to_meshio(self) -> meshio.Mesh:
        """Convert to ``meshio.Mesh``; refs go to point/cell data ``"medit:ref"``.

        Examples
        --------
        >>> Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_meshio().cells[0].type
        'triangle'
        """
        point_data = dict(self._point_data)
        cell_data = {k: [v[t] for t in self._cells] for k, v in self._cell_data.items()}
        if self._point_refs is not None:
            point_data[REF_KEY] = self._point_refs
        if self._cell_refs is not None:
            cell_data[REF_KEY] = [self._block_refs(t) for t in self._cells]
        return meshio.Mesh(
            self._points, list(self._cells.items()), point_data=point_data, cell_data=cell_data
        )

    @classmethod
    def from_meshio(cls, m: meshio.Mesh, *, dim: Literal[2, 3] | None = None, info=None) -> Mesh:
        """Convert from ``meshio.Mesh``.

        Blocks of the same type are concatenated. Refs are read from ``"medit:ref"``
        (points and cells) or ``"gmsh:physical"`` (cells); ``"gmsh:geometrical"`` is
        dropped when it equals the refs. ``cell_sets`` and ``field_data`` are ignored.
        ``dim=2`` drops a zero z column, ``dim=3`` pads 2D points with z = 0.

        Examples
        --------
        >>> import meshio
        >>> m = meshio.Mesh([[0, 0], [1, 0], [0, 1]], [("triangle", [[0, 1, 2]])])
        >>> Mesh.from_meshio(m).n_cells
        1
        """
        if not isinstance(m, meshio.Mesh):
            raise TypeError(f"expected a meshio.Mesh for 'm', got {type(m).__name__}")
        blocks = [(c.type, c.data) for c in m.cells]
        point_data = {k: v for k, v in m.point_data.items() if k != "gmsh:dim_tags"}
        return cls._from_parts(m.points, blocks, point_data, dict(m.cell_data), dim, info)

    # ---------------------------------------------------------------- trimesh
    def to_trimesh(self):
        """Convert the triangle block to ``trimesh.Trimesh`` (``process=False``: nothing merged).

        Other blocks are left out. Point data / refs become ``vertex_attributes``, the
        triangle block's cell data / refs ``face_attributes``; 2D points get z = 0.

        Raises
        ------
        ValueError
            The mesh has no ``"triangle"`` block.

        Examples
        --------
        >>> float(Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_trimesh().area)
        0.5
        """
        import trimesh

        if "triangle" not in self._cells:
            raise ValueError(
                f"expected a 'triangle' block for to_trimesh, got blocks {list(self._cells)}"
            )
        va = {k: np.asarray(v) for k, v in self._point_data.items()}
        fa = {k: np.asarray(v["triangle"]) for k, v in self._cell_data.items()}
        if self._point_refs is not None:
            va[REF_KEY] = np.asarray(self._point_refs)
        if self._cell_refs is not None:
            fa[REF_KEY] = np.asarray(self._block_refs("triangle"))
        return trimesh.Trimesh(
            self._points3(),
            np.asarray(self.triangles),
            process=False,
            validate=False,
            vertex_attributes=va,
            face_attributes=fa,
        )

    @classmethod
    def from_trimesh(cls, tm, *, info=None) -> Mesh:
        """Convert from ``trimesh.Trimesh`` (vertex/face attributes become point/cell data).

        Examples
        --------
        >>> import trimesh
        >>> Mesh.from_trimesh(trimesh.creation.box()).n_cells
        12
        """
        import trimesh

        if not isinstance(tm, trimesh.Trimesh):
            raise TypeError(f"expected a trimesh.Trimesh for 'tm', got {type(tm).__name__}")
        faces = np.asarray(tm.faces, dtype=INDEX_DTYPE)
        cell_data = {k: [v] for k, v in tm.face_attributes.items() if len(v) == len(faces)}
        point_data = {k: v for k, v in tm.vertex_attributes.items() if len(v) == len(tm.vertices)}
        return cls._from_parts(
            np.asarray(tm.vertices), [("triangle", faces)], point_data, cell_data, None, info
        )

    # ---------------------------------------------------------------- pyvista
    def to_pyvista(self):
        """Convert to ``pyvista.PolyData`` (vertex/line/triangle/quad cells only) or else
        ``pyvista.UnstructuredGrid``. Refs become arrays ``"medit:ref"``; 2D points get z = 0.

        Examples
        --------
        >>> type(Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_pyvista()).__name__
        'PolyData'
        """
        import pyvista as pv

        def flat(types):
            parts = [
                np.column_stack(
                    [np.full(len(self._cells[t]), CELL_TYPES[t][0]), self._cells[t]]
                ).ravel()
                for t in types
            ]
            return (
                np.concatenate(parts).astype(pv.ID_TYPE) if parts else np.zeros(0, dtype=pv.ID_TYPE)
            )

        if all(t in _POLY_TYPES for t in self._cells):
            order = [t for t in _POLY_TYPES if t in self._cells]  # VTK's order: verts, lines, polys
            out = pv.PolyData()
            out.points = self._points3()
            for attr, types in (
                ("verts", ["vertex"]),
                ("lines", ["line"]),
                ("faces", ["triangle", "quad"]),
            ):
                if any(t in self._cells for t in types):
                    setattr(out, attr, flat([t for t in types if t in self._cells]))
        else:
            order = list(self._cells)
            kinds = np.concatenate(
                [np.full(len(self._cells[t]), CELL_TYPES[t][2], dtype=np.uint8) for t in order]
            )
            out = pv.UnstructuredGrid(flat(order), kinds, self._points3())
        for k, v in self._point_data.items():
            out.point_data[k] = np.asarray(v)
        for k, v in self._cell_data.items():
            out.cell_data[k] = np.concatenate([v[t] for t in order])
        if self._point_refs is not None:
            out.point_data[REF_KEY] = np.asarray(self._point_refs)
        if self._cell_refs is not None:
            out.cell_data[REF_KEY] = np.concatenate([self._block_refs(t) for t in order])
        return out

    @classmethod
    def from_pyvista(
        cls, obj, *, triangulate: bool = False, dim: Literal[2, 3] | None = None, info=None
    ) -> Mesh:
        """Convert from any ``pyvista.DataSet`` (PolyData, UnstructuredGrid, ImageData, ...).

        Parameters
        ----------
        obj : pyvista.DataSet
        triangulate : bool
            Polygons with more than 4 vertices and triangle strips have no meshio cell
            type: by default they raise ValueError; with ``triangulate=True`` the whole
            dataset is first split into triangles / tetrahedra by ``obj.triangulate()``.
        dim : {None, 2, 3}
            ``2`` drops a zero z column.

        Examples
        --------
        >>> import pyvista as pv
        >>> Mesh.from_pyvista(pv.Cube()).cells["quad"].shape
        (6, 4)
        """
        import pyvista as pv

        if not isinstance(obj, pv.DataSet):
            raise TypeError(f"expected a pyvista.DataSet for 'obj', got {type(obj).__name__}")
        ug = obj if isinstance(obj, pv.UnstructuredGrid) else obj.cast_to_unstructured_grid()
        kinds = np.asarray(ug.celltypes)
        unsupported = sorted(set(np.unique(kinds).tolist()) - set(_VTK_TO_NAME) - set(_VTK_EXTRA))
        if unsupported:
            if not triangulate:
                names = [pv.CellType(k).name for k in unsupported]
                raise ValueError(
                    f"expected cells of types {list(CELL_TYPES)}, got VTK cell types {names}; "
                    "pass triangulate=True to split them into triangles/tetrahedra"
                )
            return cls.from_pyvista(obj.triangulate(), triangulate=False, dim=dim, info=info)
        conn, offsets = np.asarray(ug.cell_connectivity), np.asarray(ug.cell_offsets)[:-1]
        _, first = np.unique(kinds, return_index=True)
        blocks, masks = [], []
        for kind in kinds[np.sort(first)]:
            mask = kinds == kind
            name, order = _VTK_EXTRA.get(int(kind), (_VTK_TO_NAME.get(int(kind)), None))
            k = CELL_TYPES[name][0]
            cells = conn[offsets[mask][:, None] + np.arange(k)]
            blocks.append((name, cells if order is None else cells[:, order]))
            masks.append(mask)
        point_data = {k: np.asarray(v) for k, v in ug.point_data.items()}
        cell_data = {k: [np.asarray(v)[m] for m in masks] for k, v in ug.cell_data.items()}
        return cls._from_parts(np.asarray(ug.points), blocks, point_data, cell_data, dim, info)

    # ---------------------------------------------------------------- files
    def _meshio_for(self, fmt: _Format) -> meshio.Mesh:
        """The meshio object written for ``fmt``; warns about what the format drops."""
        if fmt.cell_types is not None:
            bad = [t for t in self._cells if t not in fmt.cell_types]
            if bad:
                raise ValueError(
                    f"{fmt.name} ({fmt.ext}) files store only {list(fmt.cell_types)} cells, "
                    f"got {bad}; save a mesh without them or pick vtu/vtk/gmsh"
                )
        m = self.to_meshio()
        pd, cd, dropped = dict(m.point_data), dict(m.cell_data), []
        if fmt.name == "medit":
            dropped += [k for k in [*pd, *cd] if k != REF_KEY]
            pd = {REF_KEY: pd.get(REF_KEY, np.zeros(self.n_points, dtype=INDEX_DTYPE))}
            cd = {REF_KEY: [self._block_refs(t) for t in self._cells]}
        elif fmt.name == "gmsh":
            if len(self._cells) > 1:
                dropped += [k for k in cd if k != REF_KEY]  # meshio cannot read them back
                cd = {}
            dropped += [k for k in cd if k in (_GMSH_REF, _GMSH_GEO)]  # replaced by the refs
            tags = [self._block_refs(t).astype(np.int32) for t in self._cells]
            cd = {
                **{k: v for k, v in cd.items() if k not in (REF_KEY, _GMSH_REF, _GMSH_GEO)},
                _GMSH_REF: tags,
                _GMSH_GEO: tags,
            }
        elif fmt.name == "ply":
            dropped += [*cd, *(k for k, v in pd.items() if v.ndim != 1)]  # scalars only
            pd = {k: v.astype(np.int32) if v.dtype.kind in "iu" else v for k, v in pd.items()}
            pd, cd = {k: v for k, v in pd.items() if v.ndim == 1}, {}
        elif fmt.name in ("obj", "stl"):
            dropped += [*pd, *cd]
            pd, cd = {}, {}
        if dropped:
            warnings.warn(
                f"{fmt.name} files cannot store {sorted(set(dropped))}; not saved",
                UserWarning,
                stacklevel=3,
            )
        points = np.asarray(self._points) if fmt.keeps_2d else self._points3()
        cells = [
            (t, c.astype(np.int32) if fmt.name == "ply" else c) for t, c in self._cells.items()
        ]
        return meshio.Mesh(points, cells, point_data=pd, cell_data=cd)

    def save(self, path, *, file_format: FileFormat | None = None) -> Path:
        """Write the mesh through meshio, atomically.

        The file is written to a temporary name in the same directory and renamed over
        ``path`` (``os.replace``), so a failure leaves neither a partial file nor a stale
        temporary. See the module docstring for what each format keeps.

        Parameters
        ----------
        path : str or os.PathLike
        file_format : {'vtu', 'vtk', 'gmsh', 'medit', 'ply', 'obj', 'stl'}, optional
            Default: from the extension (:data:`FILE_FORMATS`).

        Returns
        -------
        pathlib.Path
            ``path``.

        Raises
        ------
        ValueError
            Unknown extension or format, or cell types the format cannot store.

        Examples
        --------
        >>> import tempfile, os
        >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> with tempfile.TemporaryDirectory() as d:
        ...     load(m.save(os.path.join(d, "t.vtu")), dim=2).n_cells
        1
        """
        path = Path(path)
        fmt = _find_format(path, file_format)
        data = self._meshio_for(fmt)
        tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
        try:
            meshio.write(tmp, data, file_format=fmt.meshio_name, **fmt.write_kwargs)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(
        cls, path, *, file_format: FileFormat | None = None, dim: Literal[2, 3] | None = None
    ) -> Mesh:
        """Read a mesh file (see :func:`load`)."""
        return load(path, file_format=file_format, dim=dim)


def load(path, *, file_format: FileFormat | None = None, dim: Literal[2, 3] | None = None) -> Mesh:
    """Read a mesh file written by :meth:`Mesh.save` or another program.

    Parameters
    ----------
    path : str or os.PathLike
    file_format : {'vtu', 'vtk', 'gmsh', 'medit', 'ply', 'obj', 'stl'}, optional
        Default: from the extension.
    dim : {None, 2, 3}
        ``2`` drops a zero z column (formats other than Medit store 3D points).

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        Unknown extension or format, or ``dim=2`` with non-zero z.
    ReadError
        The file cannot be parsed, holds no points, or holds an invalid mesh.

    Examples
    --------
    >>> load("no/such/file.vtu")
    Traceback (most recent call last):
    ...
    FileNotFoundError: [Errno 2] no such mesh file: 'no/such/file.vtu'
    """
    path = Path(path)
    fmt = _find_format(path, file_format)
    _set_dim(np.zeros((0, 3)), dim)  # check the argument before reading
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, "no such mesh file", str(path))
    reader = getattr(
        meshio, fmt.name
    ).read  # the format's own reader: meshio.read calls sys.exit on failure
    try:
        with warnings.catch_warnings():
            warnings.simplefilter(
                "ignore", RuntimeWarning
            )  # meshio's binary-STL probe overflows on ascii files
            m = reader(str(path))
    except Exception as exc:  # meshio raises ReadError, ValueError, UnicodeError, IndexError, ...
        raise ReadError(
            f"could not read {str(path)!r} as {fmt.name}: {type(exc).__name__}: {exc}"
        ) from exc
    if fmt.name == "stl":  # meshio's derived normals and "no group" ids are not data
        m.cell_data.pop("facet_normals", None)
    if fmt.name == "obj" and all(np.all(g == -1) for g in m.cell_data.get("obj:group_ids", [])):
        m.cell_data.pop("obj:group_ids", None)
    if len(m.points) == 0:
        raise ReadError(f"could not read {str(path)!r} as {fmt.name}: the file holds no points")
    try:
        mesh = Mesh.from_meshio(m)
    except (ValueError, TypeError) as exc:
        raise ReadError(f"could not read {str(path)!r} as {fmt.name}: invalid mesh: {exc}") from exc
    return (
        mesh
        if dim in (None, mesh.dim)
        else mesh.replace(points=_set_dim(np.asarray(mesh.points), dim))
    )
