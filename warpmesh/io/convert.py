"""Conversions between :class:`~warpmesh.mesh.Mesh` and meshio, trimesh and pyvista objects.

Plain functions over a mesh (the ``Mesh.to_*`` / ``Mesh.from_*`` methods delegate here).
The cell vocabulary is meshio's (:data:`CELL_TYPES`, with each type's VTK id). Refs
travel as arrays named :data:`REF_KEY` (``"medit:ref"``) in meshio, pyvista and trimesh
objects; on the way in ``"gmsh:physical"`` is read as cell refs too. Refs that are all
zero are read back as "no refs". meshio keeps one data array per block
({name: [array per block]}); a :class:`~warpmesh.mesh.Mesh` keeps {name: {type: array}}.

Examples
--------
>>> import trimesh
>>> from warpmesh.io.convert import from_trimesh, to_pyvista
>>> m = from_trimesh(trimesh.creation.box())
>>> m.cells["triangle"].shape, to_pyvista(m).n_cells
((12, 3), 12)
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING, Literal

import meshio
import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE

if TYPE_CHECKING:  # the Mesh class is imported where it is built: mesh.py imports this module
    from warpmesh.mesh import Mesh

__all__ = [
    "CELL_TYPES",
    "REF_KEY",
    "to_meshio",
    "from_meshio",
    "to_trimesh",
    "from_trimesh",
    "to_pyvista",
    "from_pyvista",
]

#: meshio cell-type name -> (nodes per cell, topological dimension, VTK cell type id).
#: line4/5, triangle10/15 and tetra20/35 have no VTK type of their own (meshio's vtu/vtk
#: writers refuse them; gmsh files keep them, in gmsh's node order): their id is VTK's
#: Lagrange cell (68 curve, 69 triangle, 71 tetrahedron), whose node order is gmsh's for
#: the curves and triangles but not for the tetrahedra (other edge and face order), so
#: :func:`to_pyvista` refuses tetra20/35 (:data:`_VTK_ORDER_DIFFERS`).
CELL_TYPES: Mapping[str, tuple[int, int, int]] = MappingProxyType(
    {
        "vertex": (1, 0, 1),
        "line": (2, 1, 3),
        "line3": (3, 1, 21),
        "line4": (4, 1, 68),
        "line5": (5, 1, 68),
        "triangle": (3, 2, 5),
        "triangle6": (6, 2, 22),
        "triangle10": (10, 2, 69),
        "triangle15": (15, 2, 69),
        "quad": (4, 2, 9),
        "quad8": (8, 2, 23),
        "quad9": (9, 2, 28),
        "tetra": (4, 3, 10),
        "tetra10": (10, 3, 24),
        "tetra20": (20, 3, 71),
        "tetra35": (35, 3, 71),
        "hexahedron": (8, 3, 12),
        "hexahedron20": (20, 3, 25),
        "hexahedron27": (27, 3, 29),
        "wedge": (6, 3, 13),
        "wedge15": (15, 3, 26),
        "pyramid": (5, 3, 14),
        "pyramid13": (13, 3, 27),
    }
)
#: VTK Lagrange cell id -> {nodes per cell: meshio name}, for the sizes whose VTK node
#: order is meshio's (checked against VTK's parametric coordinates in tests/test_nodes.py)
_VTK_LAGRANGE = {
    68: {3: "line3", 4: "line4", 5: "line5"},
    69: {6: "triangle6", 10: "triangle10", 15: "triangle15"},
    71: {10: "tetra10"},
}
#: types whose VTK id numbers the nodes differently from meshio: no pyvista conversion
_VTK_ORDER_DIFFERS = ("tetra20", "tetra35")
_VTK_TO_NAME = {vtk: name for name, (_, _, vtk) in CELL_TYPES.items() if vtk not in _VTK_LAGRANGE}
#: VTK pixel/voxel -> quad/hexahedron node order. Other types share VTK's order: meshio's
#: wedge permutation (0 2 1 3 5 4, used by its vtu/vtk files) gives negative cell sizes in
#: VTK 9.x (pyvista compute_cell_sizes), so pyvista conversions keep wedges as they are.
_VTK_EXTRA = {8: ("quad", [0, 1, 3, 2]), 11: ("hexahedron", [0, 1, 3, 2, 4, 5, 7, 6])}
_POLY_TYPES = ("vertex", "line", "triangle", "quad")  # what a pyvista PolyData holds

#: name of the refs arrays in meshio, pyvista and trimesh objects
REF_KEY = "medit:ref"
_GMSH_REF, _GMSH_GEO = "gmsh:physical", "gmsh:geometrical"


# ----------------------------------------------------------------------------- helpers
def _native(value) -> np.ndarray:
    """``value`` as an array in native byte order (the VTK reader returns big-endian)."""
    arr = np.asarray(value)
    return arr.astype(arr.dtype.newbyteorder("=")) if arr.dtype.byteorder not in "=|" else arr


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


def _check_mesh(mesh) -> None:
    from warpmesh.mesh import Mesh

    if not isinstance(mesh, Mesh):
        raise TypeError(f"expected a warpmesh Mesh for 'mesh', got {type(mesh).__name__}")


def _points3(mesh: Mesh) -> np.ndarray:
    """(n, 3) float64: the points, 2D ones with z = 0."""
    if mesh.dim == 3:
        return np.asarray(mesh.points)
    return np.column_stack([mesh.points, np.zeros(mesh.n_points, dtype=REAL_DTYPE)])


def _block_refs(mesh: Mesh, t: str) -> np.ndarray:
    """(m,) int64: the refs of block ``t``, zeros when it has none."""
    refs = None if mesh.cell_refs is None else mesh.cell_refs.get(t)
    return np.zeros(len(mesh.cells[t]), dtype=INDEX_DTYPE) if refs is None else refs


def _from_parts(points, blocks, point_data, cell_data, dim, info) -> Mesh:
    """Build from blocks that may repeat a type; pull the refs out of the data arrays."""
    from warpmesh.mesh import Mesh

    points = _set_dim(np.asarray(points, dtype=REAL_DTYPE), dim)
    names = list(dict.fromkeys(t for t, _ in blocks))
    cells = {t: np.concatenate([np.asarray(c) for u, c in blocks if u == t]) for t in names}
    point_data = {k: _native(v) for k, v in point_data.items()}
    cell_data = {
        k: {
            t: np.concatenate([_native(a) for (u, _), a in zip(blocks, v, strict=True) if u == t])
            for t in names
        }
        for k, v in cell_data.items()
    }
    point_refs = point_data.pop(REF_KEY, None)
    if point_refs is not None and point_refs.dtype.kind == "f":
        if not np.all(point_refs == np.round(point_refs)):
            raise ValueError(f"expected integer point refs {REF_KEY!r}, got non-integral values")
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


# ----------------------------------------------------------------------------- meshio
def to_meshio(mesh: Mesh) -> meshio.Mesh:
    """Convert to ``meshio.Mesh``; refs go to point/cell data ``"medit:ref"``.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    meshio.Mesh
        One block per cell type; cell data as {name: [array per block]}.

    Examples
    --------
    >>> from warpmesh.mesh import Mesh
    >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}, point_refs=[1, 2, 3])
    >>> mm = to_meshio(m)
    >>> mm.cells[0].type, mm.point_data["medit:ref"].tolist()
    ('triangle', [1, 2, 3])
    """
    _check_mesh(mesh)
    point_data = dict(mesh.point_data)
    cell_data = {k: [v[t] for t in mesh.cells] for k, v in mesh.cell_data.items()}
    if mesh.point_refs is not None:
        point_data[REF_KEY] = mesh.point_refs
    if mesh.cell_refs is not None:
        cell_data[REF_KEY] = [_block_refs(mesh, t) for t in mesh.cells]
    return meshio.Mesh(
        mesh.points, list(mesh.cells.items()), point_data=point_data, cell_data=cell_data
    )


def from_meshio(m: meshio.Mesh, *, dim: Literal[2, 3] | None = None, info=None) -> Mesh:
    """Convert from ``meshio.Mesh``.

    Blocks of the same type are concatenated. Refs are read from ``"medit:ref"``
    (points and cells) or ``"gmsh:physical"`` (cells); ``"gmsh:geometrical"`` is
    dropped when it equals the refs. ``cell_sets`` and ``field_data`` are ignored.

    Parameters
    ----------
    m : meshio.Mesh
    dim : {None, 2, 3}
        ``2`` drops a zero z column, ``3`` pads 2D points with z = 0.
    info : dict, optional
        Passed to the :class:`~warpmesh.mesh.Mesh` constructor.

    Raises
    ------
    TypeError
        ``m`` is not a ``meshio.Mesh``.
    ValueError
        Non-integral point refs, ``dim=2`` with non-zero z, or an invalid mesh.

    Examples
    --------
    >>> import meshio
    >>> m = meshio.Mesh([[0, 0], [1, 0], [0, 1]], [("triangle", [[0, 1, 2]])])
    >>> from_meshio(m).n_cells
    1
    """
    if not isinstance(m, meshio.Mesh):
        raise TypeError(f"expected a meshio.Mesh for 'm', got {type(m).__name__}")
    blocks = [(c.type, c.data) for c in m.cells]
    point_data = {k: v for k, v in m.point_data.items() if k != "gmsh:dim_tags"}
    return _from_parts(m.points, blocks, point_data, dict(m.cell_data), dim, info)


# ----------------------------------------------------------------------------- trimesh
def to_trimesh(mesh: Mesh):
    """Convert the triangle block to ``trimesh.Trimesh`` (``process=False``: nothing merged).

    Other blocks are left out. Point data / refs become ``vertex_attributes``, the
    triangle block's cell data / refs ``face_attributes``; 2D points get z = 0.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    trimesh.Trimesh

    Raises
    ------
    ValueError
        The mesh has no ``"triangle"`` block.

    Examples
    --------
    >>> from warpmesh.mesh import Mesh
    >>> float(to_trimesh(Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})).area)
    0.5
    """
    import trimesh

    _check_mesh(mesh)
    if "triangle" not in mesh.cells:
        raise ValueError(
            f"expected a 'triangle' block for to_trimesh, got blocks {list(mesh.cells)}"
        )
    va = {k: np.asarray(v) for k, v in mesh.point_data.items()}
    fa = {k: np.asarray(v["triangle"]) for k, v in mesh.cell_data.items()}
    if mesh.point_refs is not None:
        va[REF_KEY] = np.asarray(mesh.point_refs)
    if mesh.cell_refs is not None:
        fa[REF_KEY] = np.asarray(_block_refs(mesh, "triangle"))
    return trimesh.Trimesh(
        _points3(mesh),
        np.asarray(mesh.triangles),
        process=False,
        validate=False,
        vertex_attributes=va,
        face_attributes=fa,
    )


def from_trimesh(tm, *, info=None) -> Mesh:
    """Convert from ``trimesh.Trimesh`` (vertex/face attributes become point/cell data).

    Attributes whose length is not the number of vertices / faces are left out.

    Parameters
    ----------
    tm : trimesh.Trimesh
    info : dict, optional
        Passed to the :class:`~warpmesh.mesh.Mesh` constructor.

    Raises
    ------
    TypeError
        ``tm`` is not a ``trimesh.Trimesh``.

    Examples
    --------
    >>> import trimesh
    >>> from_trimesh(trimesh.creation.box()).n_cells
    12
    """
    import trimesh

    if not isinstance(tm, trimesh.Trimesh):
        raise TypeError(f"expected a trimesh.Trimesh for 'tm', got {type(tm).__name__}")
    faces = np.asarray(tm.faces, dtype=INDEX_DTYPE)
    cell_data = {k: [v] for k, v in tm.face_attributes.items() if len(v) == len(faces)}
    point_data = {k: v for k, v in tm.vertex_attributes.items() if len(v) == len(tm.vertices)}
    return _from_parts(
        np.asarray(tm.vertices), [("triangle", faces)], point_data, cell_data, None, info
    )


# ----------------------------------------------------------------------------- pyvista
def to_pyvista(mesh: Mesh):
    """Convert to ``pyvista.PolyData`` (vertex/line/triangle/quad cells only) or else
    ``pyvista.UnstructuredGrid``. Refs become arrays ``"medit:ref"``; 2D points get z = 0.

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    pyvista.PolyData or pyvista.UnstructuredGrid
        PolyData cells come in VTK's order (vertices, lines, then triangles and quads);
        UnstructuredGrid cells in the mesh's block order; line4/5 and triangle10/15
        become VTK Lagrange cells.

    Raises
    ------
    ValueError
        tetra20 or tetra35 cells: VTK's Lagrange tetrahedron orders their nodes otherwise.

    Examples
    --------
    >>> from warpmesh.mesh import Mesh
    >>> type(to_pyvista(Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}))).__name__
    'PolyData'
    """
    import pyvista as pv

    _check_mesh(mesh)
    cells = mesh.cells
    differ = [t for t in cells if t in _VTK_ORDER_DIFFERS]
    if differ:
        raise ValueError(
            f"expected cell types that VTK can hold, got {differ}: VTK's Lagrange tetrahedron "
            "numbers its edge and face nodes differently from gmsh/meshio; save such a mesh "
            "as .msh (gmsh) instead"
        )

    def flat(types):
        parts = [
            np.column_stack([np.full(len(cells[t]), CELL_TYPES[t][0]), cells[t]]).ravel()
            for t in types
        ]
        return np.concatenate(parts).astype(pv.ID_TYPE) if parts else np.zeros(0, dtype=pv.ID_TYPE)

    if all(t in _POLY_TYPES for t in cells):
        order = [t for t in _POLY_TYPES if t in cells]  # VTK's order: verts, lines, polys
        out = pv.PolyData()
        out.points = _points3(mesh)
        for attr, types in (
            ("verts", ["vertex"]),
            ("lines", ["line"]),
            ("faces", ["triangle", "quad"]),
        ):
            if any(t in cells for t in types):
                setattr(out, attr, flat([t for t in types if t in cells]))
    else:
        order = list(cells)
        kinds = np.concatenate(
            [np.full(len(cells[t]), CELL_TYPES[t][2], dtype=np.uint8) for t in order]
        )
        out = pv.UnstructuredGrid(flat(order), kinds, _points3(mesh))
    for k, v in mesh.point_data.items():
        out.point_data[k] = np.asarray(v)
    for k, v in mesh.cell_data.items():
        out.cell_data[k] = np.concatenate([v[t] for t in order])
    if mesh.point_refs is not None:
        out.point_data[REF_KEY] = np.asarray(mesh.point_refs)
    if mesh.cell_refs is not None:
        out.cell_data[REF_KEY] = np.concatenate([_block_refs(mesh, t) for t in order])
    return out


def from_pyvista(
    obj, *, triangulate: bool = False, dim: Literal[2, 3] | None = None, info=None
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
    info : dict, optional
        Passed to the :class:`~warpmesh.mesh.Mesh` constructor.

    Raises
    ------
    TypeError
        ``obj`` is not a ``pyvista.DataSet``.
    ValueError
        Cells without a meshio type and ``triangulate=False`` (VTK Lagrange cells have
        one for 3 to 5 curve nodes, 6, 10 or 15 triangle nodes, 10 tetrahedron nodes).

    Examples
    --------
    >>> import pyvista as pv
    >>> from_pyvista(pv.Cube()).cells["quad"].shape
    (6, 4)
    """
    import pyvista as pv

    if not isinstance(obj, pv.DataSet):
        raise TypeError(f"expected a pyvista.DataSet for 'obj', got {type(obj).__name__}")
    ug = obj if isinstance(obj, pv.UnstructuredGrid) else obj.cast_to_unstructured_grid()
    kinds = np.asarray(ug.celltypes).astype(np.int64)
    conn, offsets = np.asarray(ug.cell_connectivity), np.asarray(ug.cell_offsets)
    sizes, offsets = np.diff(offsets), offsets[:-1]
    keys = kinds << 32 | sizes  # a Lagrange cell's meshio type depends on its node count
    _, first = np.unique(keys, return_index=True)
    pairs = [(int(kinds[i]), int(sizes[i])) for i in np.sort(first)]

    def name_of(kind: int, size: int) -> tuple[str | None, list | None]:
        if kind in _VTK_EXTRA:
            return _VTK_EXTRA[kind]
        name = _VTK_LAGRANGE[kind].get(size) if kind in _VTK_LAGRANGE else _VTK_TO_NAME.get(kind)
        return name, None

    unsupported = [(k, n) for k, n in pairs if name_of(k, n)[0] is None]
    if unsupported:
        if not triangulate:
            names = sorted({pv.CellType(k).name + (f" of {n} nodes" if k in _VTK_LAGRANGE else "")
                            for k, n in unsupported})
            raise ValueError(
                f"expected cells of types {list(CELL_TYPES)}, got VTK cell types {names}; "
                "pass triangulate=True to split them into triangles/tetrahedra"
            )
        return from_pyvista(obj.triangulate(), triangulate=False, dim=dim, info=info)
    blocks, masks = [], []
    for kind, size in pairs:
        mask = (kinds == kind) & (sizes == size)
        name, order = name_of(kind, size)
        k = CELL_TYPES[name][0]
        cells = conn[offsets[mask][:, None] + np.arange(k)]
        blocks.append((name, cells if order is None else cells[:, order]))
        masks.append(mask)
    point_data = {k: np.asarray(v) for k, v in ug.point_data.items()}
    cell_data = {k: [np.asarray(v)[m] for m in masks] for k, v in ug.cell_data.items()}
    return _from_parts(np.asarray(ug.points), blocks, point_data, cell_data, dim, info)
