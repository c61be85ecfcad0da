"""The host-side mesh: points, typed cell blocks, physical attributes and data.

A :class:`Mesh` checks itself on construction and is immutable (its arrays are
read-only); operations return new meshes (:meth:`Mesh.replace`). Derived connectivity
and statistics are cached.

Layout
    ``points`` (n, d) float64, d = 2 or 3. ``cells`` maps meshio cell-type names to
    (m, k) int64 blocks, one block per type, in insertion order. ``point_refs`` (n,)
    int and ``cell_refs`` {type: (m,) int} are the physical attributes of [FG §17.5]
    (a block without refs has ref 0). ``point_data`` {name: (n, ...)}; ``cell_data``
    {name: {type: (m, ...)}} with an entry for every block (meshio's layout is
    {name: [array per block]}; :meth:`Mesh.to_meshio` / :meth:`Mesh.from_meshio`
    convert). Refs travel as arrays named ``REF_KEY`` (``"medit:ref"``) in meshio,
    pyvista and trimesh objects, and as ``"gmsh:physical"`` in gmsh files. Refs that
    are all zero are read back as "no refs" (medit and gmsh always store one).
Compact storage
    ``Mesh(..., compact=True)`` (or :meth:`Mesh.compact`) keeps float32 points, int32
    cells and refs of 32 bits or fewer, about half the memory, while every accessor
    still gives float64 / int64 arrays (made on first use and kept):
    :attr:`Mesh.nbytes` counts what is held, :attr:`Mesh.compact_arrays` gives the kept
    arrays. Label-volume surfaces (``interfaces="shared"``) are returned compact (not
    with ``smoothing``, nor for a grid too far from the origin for float32).

Conversions live in :mod:`warpmesh.io.convert` and files in :mod:`warpmesh.io.files` (with the
table of what each format keeps); the methods below delegate to them.

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

from collections.abc import Mapping
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
import sys
from typing import TYPE_CHECKING, Literal

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.arrays import narrowest_int
from warpmesh.cells import topology as _topo
from warpmesh.cells.quality import summarize_quality, tetra_figures, tetra_quality, triangle_quality
from warpmesh.cells.types import CELL_TYPES, REF_KEY
from warpmesh.planar.polyline import components

if TYPE_CHECKING:  # annotations only; the operations behind the methods are imported when called
    import meshio

    from warpmesh.io.files import FileFormat

__all__ = ["Mesh", "load", "CELL_TYPES", "FILE_FORMATS", "REF_KEY"]  # noqa: F822 - FILE_FORMATS comes from __getattr__ (lazy)


def __getattr__(name: str):
    """``FILE_FORMATS`` of :mod:`warpmesh.io.files`, imported on first use (it imports meshio)."""
    if name == "FILE_FORMATS":
        from warpmesh.io.files import FILE_FORMATS

        return FILE_FORMATS
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: a mesher's facts about the mesh it returns (its extraction's counts and volume), not
#: reported by :meth:`Mesh.stats` for a mesh made from it (transformed, refined, converted)
OUTPUT_FACTS = ("vertices", "triangles", "signed_volume", "grid")
#: the ``info`` key of the fingerprint of the mesh those facts describe
FACTS_OF = "facts_of"


# ----------------------------------------------------------------------------- validation
def _same_fingerprint(a, b) -> bool:
    """Whether two fingerprints (:meth:`Mesh._fingerprint`, or one read back from a file)
    are of the same points and cells."""
    try:
        return a[0] == b[0] and [tuple(x) for x in a[1]] == [tuple(x) for x in b[1]] and \
            abs(float(a[2]) - float(b[2])) <= 1e-9 * (1.0 + abs(float(b[2])))
    except (TypeError, ValueError, IndexError):
        return False


def _frozen(arr: np.ndarray) -> np.ndarray:
    if arr.flags.owndata and not arr.flags.writeable:  # frozen already (another mesh's, or handed over): shared
        return arr
    arr = np.array(arr, copy=True)
    arr.setflags(write=False)
    return arr


def _int_array(value, name: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.size == 0 and arr.dtype.kind not in "iu":
        arr = arr.astype(INDEX_DTYPE)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"expected an integer array for {name}, got dtype {arr.dtype}")
    return arr


def _check_points(points, compact: bool = False) -> np.ndarray:
    arr = np.asarray(points)
    if arr.dtype.kind not in "iuf":
        raise TypeError(f"expected a float array for 'points', got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"expected 'points' of shape (n, 2) or (n, 3), got shape {arr.shape}")
    with np.errstate(over="ignore"):  # beyond float32: inf, refused below with the row
        out = arr.astype(np.float32 if compact else REAL_DTYPE, copy=False)
    bad = ~np.isfinite(out).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        within = " within float32's range (compact=True)" if compact and np.isfinite(arr[i]).all() else ""
        raise ValueError(
            f"expected finite coordinates{within} in 'points', got {arr[i].tolist()} at row {i} "
            f"({bad.sum()} bad rows)"
        )
    return out


def _check_cells(cells, n: int, d: int, index_dtype=INDEX_DTYPE) -> dict[str, np.ndarray]:
    if isinstance(cells, Mapping):
        pairs = list(cells.items())
    elif isinstance(cells, (list, tuple)):
        cell_block = getattr(sys.modules.get("meshio"), "CellBlock", ())  # none without meshio imported
        pairs = [(c.type, c.data) if isinstance(c, cell_block) else tuple(c) for c in cells]
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
        out[name] = _frozen(arr.astype(index_dtype, copy=False))
    return out


def _check_data(data, length: int, name: str, *, integer: bool = False, compact: bool = False) -> np.ndarray:
    arr = _int_array(data, name) if integer else np.asarray(data)
    if arr.ndim == 0 or arr.shape[0] != length:
        raise ValueError(f"expected {name} of length {length}, got shape {arr.shape}")
    if integer and arr.ndim != 1:
        raise ValueError(f"expected {name} of shape ({length},), got shape {arr.shape}")
    if integer and arr.size and arr.dtype == np.uint64 and int(arr.max()) > np.iinfo(INDEX_DTYPE).max:
        raise ValueError(f"expected {name} within int64, got {int(arr.max())}")
    if integer and compact:
        return _packed_ints(arr, int(arr.min(initial=0)), int(arr.max(initial=0)))
    return _frozen(arr.astype(INDEX_DTYPE, copy=False) if integer else arr)


def _check_key(key, name: str) -> str:
    """A data array's name: a non-empty string without control characters (a newline in a
    name made .msh files that no reader takes)."""
    if not isinstance(key, str) or not key or not key.isprintable():
        raise ValueError(f"expected {name} names that are non-empty printable strings, got {key!r}")
    return key


def _check_values(arr: np.ndarray, name: str) -> np.ndarray:
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"expected numbers (bool, int or float) in {name}, got {arr.dtype} values")
    return arr


def _check_mapping(value, name: str) -> Mapping:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise TypeError(f"expected a dict for '{name}', got {type(value).__name__}")
    return value


#: the most points a compact mesh numbers with int32 cells
_INT32_LIMIT = 2**31
def _packed_ints(arr: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """``arr`` (integers in [lo, hi]), read-only: as it is when its type has 32 bits or
    fewer (no copy of what a producer wrote compact), else in the narrowest type holding
    them."""
    return _frozen(arr if arr.dtype.itemsize <= 4 else arr.astype(narrowest_int(lo, hi)))


def _widened(arr: np.ndarray | None, dtype) -> np.ndarray | None:
    """A compact mesh's array in the package's host type, read-only (itself if it is already)."""
    if arr is None or arr.dtype == dtype:
        return arr
    out = arr.astype(dtype)
    out.setflags(write=False)
    return out


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
    compact : bool
        Keep the points as float32, the cells as int32 (int64 past 2**31 points) and the
        refs as given when of 32 bits or fewer, else in the narrowest integer type that
        holds them: about half the memory (what the label-volume surfaces of
        ``interfaces="shared"`` return). The accessors still give float64 and int64
        arrays (:attr:`points`, :attr:`cells`, ...), each made on its first use and kept;
        :meth:`save` and :meth:`to_meshio` work from float64 / int64 copies that the mesh
        does not keep. Coordinates are rounded to float32 (2**-24 relative; below
        float32's smallest normal, 1.2e-38, to its subnormal steps). Point and cell data
        keep their types. :meth:`replace` keeps it when only ``info`` changes; a mesh made
        with other changes (every operation's result) is not compact unless
        ``compact=True`` is passed.

    Raises
    ------
    TypeError
        Non-numeric points, non-integer indices or refs, wrong container types.
    ValueError
        Non-finite coordinates, wrong shapes, unknown cell type, wrong number of nodes
        per cell, negative or out-of-range indices, mismatched data lengths. A cell with
        a repeated vertex (a collapsed cell, as files carry them) is accepted; the
        operations that split or rebuild cells refuse it
        (:mod:`warpmesh.cells.collapsed` lists which).

    Examples
    --------
    >>> pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    >>> m = Mesh(pts, [("triangle", [[0, 1, 2]])], cell_refs={"triangle": [7]})
    >>> m.n_points, m.n_cells, m.dim, m.cell_refs["triangle"].tolist()
    (3, 1, 3, [7])
    >>> c = Mesh(pts, [("triangle", [[0, 1, 2]])], cell_refs={"triangle": [7]}, compact=True)
    >>> c.nbytes, c.compact_arrays["cells"]["triangle"].dtype.name, c.triangles.dtype.name
    (49, 'int32', 'int64')
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
        compact: bool = False,
    ):
        if not isinstance(compact, (bool, np.bool_)):
            raise TypeError(f"expected True or False for 'compact', got {compact!r}")
        pts = _check_points(points, compact)
        n, d = pts.shape
        blocks = _check_cells(cells, n, d, np.int32 if compact and n <= _INT32_LIMIT else INDEX_DTYPE)
        sizes = {t: len(c) for t, c in blocks.items()}
        prefs = (
            None if point_refs is None else _check_data(point_refs, n, "'point_refs'", integer=True, compact=compact)
        )
        crefs = _check_mapping(cell_refs, "cell_refs")
        for t in crefs:
            if t not in sizes:
                raise ValueError(
                    f"expected cell_refs keys among the cell types {list(sizes)}, got {t!r}"
                )
        crefs = {
            t: _check_data(r, sizes[t], f"cell_refs[{t!r}]", integer=True, compact=compact) for t, r in crefs.items()
        } or None  # an empty dict means no refs
        if compact:  # widened on first use (the cached properties below)
            self._packed = {"points": _frozen(pts), "cells": blocks, "point_refs": prefs, "cell_refs": crefs}
        else:
            self._packed = None
            self._points, self._cells, self._point_refs, self._cell_refs = _frozen(pts), blocks, prefs, crefs
        pdata = _check_mapping(point_data, "point_data")
        self._point_data = {_check_key(k, "point_data"): _check_values(_check_data(v, n, f"point_data[{k!r}]"),
                                                                         f"point_data[{k!r}]") for k, v in pdata.items()}
        self._cell_data = {}
        for key, per_type in _check_mapping(cell_data, "cell_data").items():
            _check_key(key, "cell_data")
            per_type = _check_mapping(per_type, f"cell_data[{key!r}]")
            if set(per_type) != set(sizes):
                raise ValueError(
                    f"expected cell_data[{key!r}] keys {list(sizes)} (one per block), "
                    f"got {list(per_type)}"
                )
            self._cell_data[key] = MappingProxyType(
                {t: _check_values(_check_data(per_type[t], sizes[t], f"cell_data[{key!r}][{t!r}]"),
                                  f"cell_data[{key!r}][{t!r}]") for t in sizes}
            )
        if REF_KEY in self._point_data or REF_KEY in self._cell_data:
            raise ValueError(
                f"expected no {REF_KEY!r} array in point_data/cell_data; "
                "pass it as point_refs/cell_refs"
            )
        self._info = dict(_check_mapping(info, "info"))
        if any(k in self._info for k in OUTPUT_FACTS) and FACTS_OF not in self._info:
            self._info[FACTS_OF] = self._fingerprint()  # the mesher's own output: its facts hold

    def _fingerprint(self) -> list:
        """Points, cells per type and the points' sum: what a mesher's facts about its output
        (:data:`OUTPUT_FACTS`) were measured on; a renumbering keeps it, a transform or a
        refinement does not."""
        return [self.n_points, sorted((t, len(c)) for t, c in self._stored("cells").items()),
                float(np.sum(self._stored("points"), dtype=np.float64))]

    # ---------------------------------------------------------------- storage
    def _stored(self, name: str):
        """``points``, ``cells``, ``point_refs`` or ``cell_refs`` as kept: compact or not,
        never widened for the asking (counts, shapes, the compact writers)."""
        return self._packed[name] if self._packed is not None else getattr(self, "_" + name)

    # a compact mesh's arrays in the host types, made on first use (a mesh that is not
    # compact sets these attributes in __init__, which hides the properties)
    _points = cached_property(lambda self: _widened(self._packed["points"], REAL_DTYPE))
    _cells = cached_property(lambda self: {t: _widened(c, INDEX_DTYPE) for t, c in self._packed["cells"].items()})
    _point_refs = cached_property(lambda self: _widened(self._packed["point_refs"], INDEX_DTYPE))
    _cell_refs = cached_property(lambda self: None if self._packed["cell_refs"] is None else
                                 {t: _widened(r, INDEX_DTYPE) for t, r in self._packed["cell_refs"].items()})

    @property
    def is_compact(self) -> bool:
        """Whether the mesh keeps compact arrays (``compact=True``, :meth:`compact`)."""
        return self._packed is not None

    @property
    def compact_arrays(self) -> dict:
        """The arrays as kept, without widening: ``points``, ``cells`` {type: array},
        ``point_refs`` and ``cell_refs`` (or None); float32 / int32 / narrow integers for a
        compact mesh, float64 / int64 otherwise. Read-only."""
        cells, crefs = self._stored("cells"), self._stored("cell_refs")
        return {"points": self._stored("points"), "cells": MappingProxyType(cells),
                "point_refs": self._stored("point_refs"),
                "cell_refs": None if crefs is None else MappingProxyType(crefs)}

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays this mesh holds now: points, cells, refs and data, the
        compact ones and any float64 / int64 copies made from them (not the caches of
        derived connectivity and statistics)."""
        arrays = [self._stored("points"), *self._stored("cells").values(), self._stored("point_refs"),
                  *(self._stored("cell_refs") or {}).values(), *self._point_data.values(),
                  *(a for per in self._cell_data.values() for a in per.values())]
        if self._packed is not None:  # the widened copies made so far
            made = self.__dict__
            arrays += [made.get("_points"), made.get("_point_refs"), *made.get("_cells", {}).values(),
                       *(made.get("_cell_refs") or {}).values()]
        seen, total = set(), 0
        for a in arrays:
            if a is not None and id(a) not in seen:
                seen.add(id(a))
                total += a.nbytes
        return total

    def compact(self) -> Mesh:
        """This mesh with compact arrays (``compact=True``): float32 points, int32 cells,
        the narrowest integer refs; itself if it is compact already.

        Examples
        --------
        >>> m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]})
        >>> m.nbytes, m.compact().nbytes, m.compact().points.dtype.name
        (96, 48, 'float64')
        """
        if self._packed is not None:
            return self
        new = self.replace(compact=True)
        if FACTS_OF in self._info and _same_fingerprint(self._info[FACTS_OF], self._fingerprint()):
            new._info[FACTS_OF] = new._fingerprint()  # the same mesh, rounded: the mesher's facts still hold
        return new

    # ---------------------------------------------------------------- accessors
    points = property(lambda self: self._points, doc="(n, d) float64, read-only (a compact mesh's: made on first use).")
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
    n_points = property(lambda self: len(self._stored("points")), doc="Number of points.")
    n_cells = property(
        lambda self: sum(len(c) for c in self._stored("cells").values()), doc="Number of cells, all blocks."
    )
    dim = property(lambda self: self._stored("points").shape[1], doc="Geometric dimension, 2 or 3.")

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
            points=self._stored("points"),
            cells=self._stored("cells"),
            point_data=self._point_data,
            cell_data=self._cell_data,
            point_refs=self._stored("point_refs"),
            cell_refs=self._stored("cell_refs"),
            info=self._info,
            compact=False,  # derived arrays keep their float64 (an operation's checks hold for them)
        )
        unknown = set(changes) - set(args)
        if unknown:
            raise TypeError(f"expected keywords among {sorted(args)}, got {sorted(unknown)}")
        if set(changes) <= {"info"}:  # the arrays are this mesh's, checked and frozen: not checked again
            new = Mesh.__new__(Mesh)
            new._packed = self._packed
            for name in ("_points", "_cells", "_point_refs", "_cell_refs", "_point_data", "_cell_data"):
                if name in self.__dict__:  # a compact mesh's widened copies, if made, are shared too
                    setattr(new, name, self.__dict__[name])
            new._info = dict(_check_mapping(changes.get("info", self._info), "info"))
            return new
        args.update(changes)
        return Mesh(args.pop("points"), args.pop("cells"), **args)

    def __reduce__(self):
        """Pickle as the constructor's arguments (the read-only views as plain dicts), so a
        mesh goes through ``pickle``, ``multiprocessing`` and Dask like its arrays.

        Examples
        --------
        >>> import pickle
        >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]},
        ...          cell_data={"q": {"triangle": [1.5]}}, info={"rows": {"a": 1}})
        >>> pickle.loads(pickle.dumps(m)).cell_data["q"]["triangle"].tolist()
        [1.5]
        """
        kwargs = {"point_data": self._point_data, "cell_data": {k: dict(v) for k, v in self._cell_data.items()},
                  "point_refs": self._stored("point_refs"), "cell_refs": self._stored("cell_refs"),
                  "info": _plain(self._info), "compact": self._packed is not None}
        return _unpickle_mesh, (self._stored("points"), self._stored("cells"), kwargs)

    def __repr__(self) -> str:
        blocks = ", ".join(f"{t}: {len(c)}" for t, c in self._stored("cells").items())
        extra = "".join(
            f", {k}"
            for k in ("point_refs", "cell_refs")
            if self._stored(k) is not None
        )
        compact = ", compact" if self._packed is not None else ""
        return f"Mesh(np={self.n_points}, dim={self.dim}, cells={{{blocks}}}{extra}{compact})"

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
            "self_intersections",
        ):
            s[key] = None
        tets = self._of_tetrahedra
        # the surface the topology describes: a volume mesh's boundary (the faces in one
        # tetrahedron, outward; a multi-region mesh's triangle block holds its interfaces too,
        # which meet at junctions: no closed surface), else the triangle block
        surface = self._tet_faces.boundary if tets else tri
        if len(surface):  # every topological figure from one pass over the half-edges
            t = _topo.mesh_topology(surface, self.n_points, labels=tets)
            if tets:  # the boundary's components, for the overlap check's nested shells
                self._boundary_components = (t["components"], t.pop("labels"))
            for key in ("watertight", "manifold", "oriented", "euler", "components"):
                s[key] = t[key]
            if s["watertight"] and s["manifold"] and s["oriented"]:
                s["genus"] = (2 * s["components"] - s["euler"]) // 2
            s["area"], volume, surface_q = _topo.surface_figures(self._points, surface, volume=s["watertight"])
            if s["watertight"] and self.dim == 3:
                s["volume"] = volume
        if self._is_shared_surface:  # one closed surface per label, meeting at junction edges
            from warpmesh.surface.multilabel import label_figures

            s["label_boundaries"] = label_figures(self)
        if not len(tri) and "line" in self._cells and top == 1:  # a polyline: its connected pieces
            s["components"] = components(self._cells["line"], self.n_points)[0]
        if len(tri) or ("line" in self._cells and self.dim == 2) or ("tetra" in self._cells and self.dim == 3):
            s["self_intersections"] = len(self._crossings)
        q, solid_volume = None, 0.0
        if "tetra" in self._cells:  # signed volumes and Q_K of the tetrahedra in one kernel pass
            solid_volume, q = tetra_figures(self._points, self._cells["tetra"])
        others = [t for t in ("hexahedron", "wedge", "pyramid") if t in self._cells]
        if others and self.dim == 3:  # signed, exact for the multilinear cells
            from warpmesh.cells.reference import cell_measures  # its Lagrange tables take 0.1 s to build

            solid_volume += float(sum(cell_measures(self._points, self._cells[t], t).sum() for t in others))
        if ("tetra" in self._cells or others) and self.dim == 3:
            s["volume"] = solid_volume
        if q is None:  # the triangles' Q_K came with their measures (one pass over the faces)
            q = summarize_quality(surface_q) if len(tri) else {}
        s["mean_q"], s["worst_q"] = q.get("mean_q"), q.get("worst_q")
        s["q_mean"], s["q_worst"] = s["mean_q"], s["worst_q"]  # the names of issue 6 / Table 16.1
        s["bounds"] = (
            _frozen(np.stack([self._points.min(axis=0), self._points.max(axis=0)]))
            if self.n_points
            else None
        )
        return s

    @cached_property
    def _crossings(self) -> np.ndarray:
        from warpmesh.cells.intersections import check, find_tet_overlaps

        if "tetra" in self._cells and self.dim == 3:  # the faces matched once for this and the topology
            return find_tet_overlaps(self._points, self._cells["tetra"], faces=self._tet_faces,
                                     components=self.__dict__.get("_boundary_components"))
        return check(self)

    @property
    def _is_shared_surface(self) -> bool:
        """Whether this is a multi-material surface of ``interfaces="shared"``: triangles only,
        with each triangle's lower label (``cell_refs``) and higher (``cell_data["label_above"]``)."""
        crefs = self._stored("cell_refs")
        return (set(self._stored("cells")) == {"triangle"} and crefs is not None and "triangle" in crefs
                and "triangle" in self._cell_data.get("label_above", {}))

    @property
    def _of_tetrahedra(self) -> bool:
        """Whether the topology figures are those of the tetrahedra's boundary (3D, a
        non-empty tetra block, no other solid cells)."""
        return self.dim == 3 and len(self._cells.get("tetra", ())) > 0 and not any(
            t in self._cells for t in ("hexahedron", "wedge", "pyramid"))

    @cached_property
    def _tet_faces(self):
        from warpmesh.cells.intersections import tet_faces

        return tet_faces(self._points, self._cells["tetra"])

    def check(self) -> np.ndarray:
        """The pairs of crossing cells (overlapping or inverted tetrahedra; else triangles,
        with the faces out of order about a junction edge of a labelled shared surface;
        segments of a planar polyline): :func:`warpmesh.cells.intersections.check`. Empty
        when the mesh is embedded.

        Examples
        --------
        >>> m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, -1], [0.2, 0.2, 1], [2, 2, 0]],
        ...          {"triangle": [[0, 1, 2], [3, 4, 5]]})
        >>> m.check().tolist()
        [[0, 1]]
        """
        out = self._crossings.copy()
        return out

    def stats(self) -> dict:
        """Counts, topology, measures and quality, merged over ``self.info``.

        Returns
        -------
        dict
            ``np``, ``ne`` (cells of the highest topological dimension), ``n_cells``,
            ``n_triangles``, ``n_tetra``; of the boundary of the tetrahedra (the faces in
            one tetrahedron, oriented outward) in a 3D mesh whose solid cells are
            tetrahedra (a non-empty ``"tetra"`` block), else of the triangle block (None
            without either):
            ``watertight`` (every edge in two faces), ``manifold`` (edge and vertex),
            ``oriented``, ``euler`` (V - E + F over referenced vertices), ``components``
            (edge-connected; for a mesh of lines only, the connected polylines), ``genus`` (total, ``(2 components - euler) / 2``, only when
            watertight, manifold and oriented), ``area``, ``volume`` (signed: of the
            closed 3D surface, or the sum of the volumes of the tetra, hexahedron, wedge
            and pyramid cells); ``self_intersections`` (pairs of overlapping tetrahedra,
            else of crossing triangles and of faces out of order about a junction edge of a
            labelled shared surface, or of crossing segments of a planar polyline:
            :meth:`check`; 0 for an embedded mesh); ``mean_q``, ``worst_q`` ([FG
            eq. 16.15] over tetra if any, else triangles); ``bounds`` (2, d); for a
            multi-material surface of ``interfaces="shared"`` (not a closed manifold as a
            whole: its interfaces meet at junction edges), ``label_boundaries``: label ->
            the figures of that label's boundary
            (:func:`warpmesh.surface.multilabel.label_figures`). Every key of
            ``self.info`` is included too; computed keys win on a clash.

        Examples
        --------
        >>> import trimesh
        >>> s = Mesh.from_trimesh(trimesh.creation.torus(1.0, 0.3)).stats()
        >>> s["watertight"], s["euler"], s["genus"]
        (True, 0, 1)
        """
        computed = self._stats
        hide = {FACTS_OF}
        if FACTS_OF in self._info and not _same_fingerprint(self._info[FACTS_OF], self._fingerprint()):
            hide.update(OUTPUT_FACTS)  # facts of the mesh this one was made from (transformed, refined, ...)
        return {**computed, **{k: v for k, v in self._info.items() if k not in computed and k not in hide}}

    # ---------------------------------------------------------------- quality and optimisation
    def quality(self) -> np.ndarray:
        """Q_K [FG eq. 16.15] of each element: the tetrahedra if any, else the triangles.

        Examples
        --------
        >>> Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).quality().round(4).tolist()
        [1.3938]
        """
        if "tetra" in self._cells:
            return tetra_quality(self._points, self._cells["tetra"])
        if "triangle" not in self._cells:
            raise ValueError(f"expected a 'triangle' or 'tetra' block, got {list(self._cells)}")
        return triangle_quality(self._points, self._cells["triangle"])

    def optimize(self, shape=None, *, bounds=None, size=None, tolerance: float | None = None,
                 features: bool | None = None, angle: float = 40.0, iterations: int = 8,
                 progress: bool = False) -> Mesh:
        """A new mesh optimised on the exact surface: :func:`warpmesh.optimize.remesh.optimize`
        (the same parameters)."""
        from warpmesh.optimize.remesh import optimize

        return optimize(self, shape, bounds=bounds, size=size, tolerance=tolerance, features=features, angle=angle,
                        iterations=iterations, progress=progress)

    def simplify(self, shape=None, *, tolerance: float | None = None, fraction: float | None = None,
                 bounds=None, features: bool | None = None, angle: float = 40.0, iterations: int = 8,
                 progress: bool = False) -> Mesh:
        """A new, decimated mesh within a tolerance: :func:`warpmesh.optimize.remesh.simplify`
        (the same parameters)."""
        from warpmesh.optimize.remesh import simplify

        return simplify(self, shape, tolerance=tolerance, fraction=fraction, bounds=bounds, features=features,
                        angle=angle, iterations=iterations, progress=progress)

    def to_order(self, order: int, shape=None, *, bounds=None, check: bool = True) -> Mesh:
        """The order-k Lagrange mesh of this P1 mesh [FG §17.3]: :func:`warpmesh.numbering.high_order.to_order`.

        Examples
        --------
        >>> Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_order(3).cells["triangle10"].shape
        (1, 10)
        """
        from warpmesh.numbering.high_order import to_order

        return to_order(self, order, shape, bounds=bounds, check=check, stacklevel=3)  # warnings name the caller

    # ---------------------------------------------------------------- numbering
    def renumber(self, method: str = "gibbs", *, reverse: bool | Literal["auto"] = "auto",
                 higher_order: Literal["ball", "graph"] = "ball", reduced: bool = False,
                 elements: bool = True) -> Mesh:
        """A copy with nodes and elements renumbered [FG §17.4]:
        :func:`warpmesh.numbering.renumber.renumber`; ``stats()`` then include ``bandwidth`` and
        ``profile`` (and their ``_before`` values).

        Examples
        --------
        >>> m = Mesh([[0, 0], [9, 9], [1, 0], [0, 1]], {"triangle": [[0, 2, 3], [2, 1, 3]]})
        >>> m.renumber("rcm").stats()["bandwidth"]
        2
        """
        from warpmesh.numbering.renumber import renumber

        return renumber(self, method, reverse=reverse, higher_order=higher_order, reduced=reduced, elements=elements)

    def color_elements(self, *, adjacency: Literal["face", "node"] = "face") -> Mesh:
        """A copy with elements in packets of one colour each [FG §17.4.4]:
        :func:`warpmesh.numbering.coloring.color_mesh`; ``cell_data["color"]``, ``stats()["n_colors"]``.

        Examples
        --------
        >>> m = Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], {"triangle": [[0, 1, 3], [0, 3, 2]]})
        >>> m.color_elements().cell_data["color"]["triangle"].tolist()
        [0, 1]
        """
        from warpmesh.numbering.coloring import color_mesh

        return color_mesh(self, adjacency=adjacency)

    # ---------------------------------------------------------------- modifications [FG ch. 17]
    def transform(self, matrix, *, vectors=()) -> Mesh:
        """The mesh mapped by a homogeneous matrix [FG §17.1.1]:
        :func:`warpmesh.modify.transforms.transform`; build matrices with ``wm.transforms``.

        Examples
        --------
        >>> import warpmesh as wm
        >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> m.transform(wm.transforms.symmetry((1, 0, 0))).cells["triangle"].tolist()
        [[0, 2, 1]]
        """
        from warpmesh.modify.transforms import transform

        return transform(self, matrix, vectors=vectors)

    def refine(self, n: int | None = None, shape=None, *, where=None, max_length=None, bounds=None,
               tetra_diagonal: Literal["shortest", "fixed"] = "shortest", max_rounds: int = 64) -> Mesh:
        """A refined mesh [FG §17.1.2]: every element split into n^d
        (:func:`warpmesh.modify.refine_uniform.refine_uniform`), or, with ``where`` (vertices or an element
        mask) or ``max_length`` (a size or a size function), longest-edge bisection of the
        elements concerned, kept conforming (:func:`warpmesh.modify.refine_local.refine_local`).
        With ``shape``, new boundary nodes are projected onto f = 0 (Remark 17.3).
        ``bounds`` and ``tetra_diagonal`` are the uniform refinement's, ``max_rounds`` the
        bisection's.

        Examples
        --------
        >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> m.refine(3).n_cells, m.refine(max_length=0.8).n_cells > 1
        (9, True)
        """
        if where is not None or max_length is not None:
            if n is not None:
                raise ValueError("expected either n (uniform refinement) or where/max_length (local "
                                 f"refinement), got n={n!r} and a local criterion")
            if bounds is not None or tetra_diagonal != "shortest":
                raise ValueError("'bounds' and 'tetra_diagonal' apply to uniform refinement (n), not to "
                                 "where/max_length")
            from warpmesh.modify.refine_local import refine_local

            return refine_local(self, where=where, max_length=max_length, shape=shape, max_rounds=max_rounds)
        if max_rounds != 64:
            raise ValueError("'max_rounds' applies to local refinement (where/max_length), not to n")
        from warpmesh.modify.refine_uniform import refine_uniform

        return refine_uniform(self, 2 if n is None else n, shape, bounds=bounds, tetra_diagonal=tetra_diagonal)

    def convert(self, target: str, *, quads: Literal["best", "min", 4] | None = None,
                hexes: Literal["auto", 5, 6] | None = None) -> Mesh:
        """The mesh with its elements split into another type [FG §17.1.3]:
        :func:`warpmesh.modify.convert_cells.convert_cells`.

        Examples
        --------
        >>> m = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
        >>> m.convert("triangle").cells["triangle"].shape
        (2, 3)
        """
        from warpmesh.modify.convert_cells import convert_cells

        return convert_cells(self, target, quads=quads, hexes=hexes)

    def merge(self, other: Mesh, tolerance: float | None = None, *, refs: bool = False,
              duplicates: Literal["merge", "keep", "drop"] = "merge",
              check: Literal["interface", "full", False] = "interface") -> Mesh:
        """This mesh and ``other`` merged along their common vertices, edges and faces
        [FG §17.2]: :func:`warpmesh.modify.merge.merge`.

        Examples
        --------
        >>> a = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> b = Mesh([[1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> a.merge(b).n_points
        4
        """
        from warpmesh.modify.merge import merge

        return merge(self, other, tolerance, refs=refs, duplicates=duplicates, check=check)

    def crack(self, facets=None, *, ref: int | None = None, side_refs: tuple[int, int] | None = None) -> Mesh:
        """The mesh cut open along interior facets [FG §17.5]: :func:`warpmesh.modify.crack.crack`
        (``facets`` (k, 2|3|4) vertex indices, or ``ref=R`` for the facet cells with that ref;
        ``side_refs=(r1, r2)`` tags the two lips; ``info["crack_pairs"]`` lists the copies).

        Examples
        --------
        >>> m = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"triangle": [[0, 1, 2], [0, 2, 3]]})
        >>> m.crack([[0, 2]]).n_points  # the crack crosses the square: both ends split
        6
        """
        from warpmesh.modify.crack import crack

        return crack(self, facets, ref=ref, side_refs=side_refs)

    def periodic(self, matrix, copies: int, tolerance: float | None = None, *, refs: bool = False,
                 duplicates: Literal["merge", "keep", "drop"] = "merge",
                 check: Literal["interface", "full", False] = "interface") -> Mesh:
        """A periodic mesh: this pattern and ``copies - 1`` images by ``matrix``, merged
        [FG §17.5]: :func:`warpmesh.modify.periodic.periodic`.

        Examples
        --------
        >>> import warpmesh as wm
        >>> m = Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
        >>> m.periodic(wm.transforms.translation((1, 0)), 3).n_points
        8
        """
        from warpmesh.modify.periodic import periodic

        return periodic(self, matrix, copies, tolerance, refs=refs, duplicates=duplicates, check=check)

    # ---------------------------------------------------------------- meshio
    def to_meshio(self) -> meshio.Mesh:
        """Convert to ``meshio.Mesh``, refs as ``"medit:ref"`` (:func:`warpmesh.io.convert.to_meshio`).

        Examples
        --------
        >>> Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_meshio().cells[0].type
        'triangle'
        """
        from warpmesh.io import convert as _convert

        return _convert.to_meshio(self)

    @classmethod
    def from_meshio(cls, m: meshio.Mesh, *, dim: Literal[2, 3] | None = None, info=None) -> Mesh:
        """Convert from ``meshio.Mesh`` (:func:`warpmesh.io.convert.from_meshio`).

        Examples
        --------
        >>> import meshio
        >>> m = meshio.Mesh([[0, 0], [1, 0], [0, 1]], [("triangle", [[0, 1, 2]])])
        >>> Mesh.from_meshio(m).n_cells
        1
        """
        from warpmesh.io import convert as _convert

        return _convert.from_meshio(m, mesh_type=cls, dim=dim, info=info)

    # ---------------------------------------------------------------- trimesh
    def to_trimesh(self):
        """Convert the triangle block to ``trimesh.Trimesh`` (:func:`warpmesh.io.convert.to_trimesh`).

        Examples
        --------
        >>> float(Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_trimesh().area)
        0.5
        """
        from warpmesh.io import convert as _convert

        return _convert.to_trimesh(self)

    @classmethod
    def from_trimesh(cls, tm, *, info=None) -> Mesh:
        """Convert from ``trimesh.Trimesh`` (:func:`warpmesh.io.convert.from_trimesh`).

        Examples
        --------
        >>> import trimesh
        >>> Mesh.from_trimesh(trimesh.creation.box()).n_cells
        12
        """
        from warpmesh.io import convert as _convert

        return _convert.from_trimesh(tm, mesh_type=cls, info=info)

    # ---------------------------------------------------------------- pyvista
    def to_pyvista(self):
        """Convert to a pyvista PolyData or UnstructuredGrid (:func:`warpmesh.io.convert.to_pyvista`).

        Examples
        --------
        >>> type(Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}).to_pyvista()).__name__
        'PolyData'
        """
        from warpmesh.io import convert as _convert

        return _convert.to_pyvista(self)

    @classmethod
    def from_pyvista(
        cls, obj, *, triangulate: bool = False, dim: Literal[2, 3] | None = None, info=None
    ) -> Mesh:
        """Convert from any ``pyvista.DataSet`` (:func:`warpmesh.io.convert.from_pyvista`).

        Examples
        --------
        >>> import pyvista as pv
        >>> Mesh.from_pyvista(pv.Cube()).cells["quad"].shape
        (6, 4)
        """
        from warpmesh.io import convert as _convert

        return _convert.from_pyvista(obj, mesh_type=cls, triangulate=triangulate, dim=dim, info=info)

    # ---------------------------------------------------------------- pictures
    def plot(self, path=None, *, window_size=(800, 600), show_edges: bool = False, camera=None, clip="auto",
             scalars: str | None = None):
        """An off-screen picture (pyvista/VTK, no display needed): shows itself in notebooks;
        or, with a ``.html`` path, a self-contained page with an interactive WebGL view.

        See :func:`warpmesh.preview.render.render_png`; ``path`` (a .png) also writes it.
        Curves are drawn as ribbons, 2D meshes from above, volume meshes cut through the
        middle (``clip``, :func:`warpmesh.preview.drawable.drawable`); ``scalars="ref"`` (or
        a cell_data name) colours a surface's triangles by value. A ``.html`` (or ``.htm``)
        ``path`` is written by :func:`warpmesh.preview.render.write_html` (atomically) and
        returned as a string; the page takes ``clip`` only (the viewer has its own camera).

        Examples
        --------
        >>> import os, tempfile, warpmesh as wm
        >>> ball = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=16)
        >>> img = ball.plot(window_size=(64, 48))
        >>> img.array.shape, bool((img.array < 200).any())   # the ball is drawn on a white background
        ((48, 64, 3), True)
        >>> page = ball.plot(os.path.join(tempfile.mkdtemp(), "ball.html"))
        >>> open(page).read().startswith("<!DOCTYPE html>")
        True
        """
        if path is not None and str(path).lower().endswith((".html", ".htm")):
            from warpmesh.preview.render import write_html

            given = [name for name, value, default in (("window_size", window_size, (800, 600)),
                                                       ("show_edges", show_edges, False), ("camera", camera, None),
                                                       ("scalars", scalars, None)) if value != default]
            if given:
                raise ValueError(f"an HTML page takes only 'clip' (its viewer has its own camera and size), "
                                 f"got {given}; drop them or give a .png 'path'")
            return write_html(self, path, clip=clip)
        if path is not None and not str(path).lower().endswith(".png"):
            raise ValueError(f"expected a .png or .html path for 'path', got {str(path)!r}")
        from warpmesh.preview.render import render_png

        return render_png(self, path, window_size=window_size, show_edges=show_edges, camera=camera, clip=clip,
                          scalars=scalars)

    def _repr_mimebundle_(self, include=None, exclude=None):
        """Jupyter: an interactive WebGL view (:func:`warpmesh.preview.render.mesh_mimebundle`)."""
        from warpmesh.preview.render import mesh_mimebundle

        return mesh_mimebundle(self)

    def _repr_html_(self):
        from warpmesh.preview.render import mesh_mimebundle

        return mesh_mimebundle(self).get("text/html")

    # ---------------------------------------------------------------- files
    def save(self, path, *, file_format: FileFormat | None = None, binary: bool | None = None) -> Path:
        """Write the mesh through meshio, atomically, and return ``path``.

        See :func:`warpmesh.io.files.save` for the parameters (``binary=False``: ascii for
        vtk, ply and stl) and what each format keeps.

        Examples
        --------
        >>> import tempfile, os
        >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
        >>> with tempfile.TemporaryDirectory() as d:
        ...     load(m.save(os.path.join(d, "t.vtu")), dim=2).n_cells
        1
        """
        from warpmesh.io import files as _io

        return _io.save_mesh(self, path, file_format, stacklevel=2, binary=binary)

    @classmethod
    def load(
        cls, path, *, file_format: FileFormat | None = None, dim: Literal[2, 3] | None = None
    ) -> Mesh:
        """Read a mesh file (:func:`warpmesh.io.files.load`)."""
        from warpmesh.io import files as _io

        return _io.load(path, mesh_type=cls, file_format=file_format, dim=dim)


def load(path, *, file_format: FileFormat | None = None, dim: Literal[2, 3] | None = None) -> Mesh:
    """Read a mesh file written by :meth:`Mesh.save` or another program.

    See :func:`warpmesh.io.files.load` for the parameters, the formats and the errors.

    Examples
    --------
    >>> load("no/such/file.vtu")
    Traceback (most recent call last):
    ...
    FileNotFoundError: [Errno 2] no such mesh file: 'no/such/file.vtu'
    """
    from warpmesh.io import files as _io

    return _io.load(path, mesh_type=Mesh, file_format=file_format, dim=dim)


def _plain(value):
    """``value`` with every read-only mapping view (``MappingProxyType``) made a dict, at any depth."""
    if isinstance(value, (dict, MappingProxyType)):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)) and any(isinstance(v, (dict, MappingProxyType, list, tuple)) for v in value):
        return type(value)(_plain(v) for v in value)
    return value


def _unpickle_mesh(points, cells, kwargs) -> Mesh:
    """A pickled :class:`Mesh` back (:meth:`Mesh.__reduce__`)."""
    return Mesh(points, cells, **kwargs)
