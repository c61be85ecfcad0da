"""Conversions between :class:`~warpmesh.mesh.Mesh` and meshio, trimesh and pyvista objects.

Plain functions over a mesh (the ``Mesh.to_*`` / ``Mesh.from_*`` methods delegate here).
The cell vocabulary is meshio's (:data:`warpmesh.cells.types.CELL_TYPES`, with each type's
VTK id). Refs travel as arrays named :data:`~warpmesh.cells.types.REF_KEY` (``"medit:ref"``) in meshio, pyvista and trimesh
objects; on the way in ``"gmsh:physical"`` is read as cell refs too. Refs that are all
zero are read back as "no refs". meshio keeps one data array per block
({name: [array per block]}); a :class:`~warpmesh.mesh.Mesh` keeps {name: {type: array}}.

Examples
--------
>>> import trimesh
>>> from warpmesh.io.convert import from_trimesh, to_pyvista
>>> from warpmesh.mesh import Mesh
>>> m = from_trimesh(trimesh.creation.box(), mesh_type=Mesh)
>>> m.cells["triangle"].shape, to_pyvista(m).n_cells
((12, 3), 12)
"""

from __future__ import annotations

from typing import Literal

import meshio
import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.cells.types import CELL_TYPES, REF_KEY, MeshLike, block_refs, points3, require_mesh
from warpmesh.io.vtu import VTK_CELL_TYPES


__all__ = [
    "host_arrays",
    "to_meshio",
    "from_meshio",
    "to_trimesh",
    "from_trimesh",
    "to_pyvista",
    "from_pyvista",
]

#: VTK Lagrange cell id -> {nodes per cell: meshio name}, for the sizes whose VTK node
#: order is meshio's (checked against VTK's parametric coordinates in tests/test_nodes.py)
_VTK_LAGRANGE = {
    68: {3: "line3", 4: "line4", 5: "line5"},
    69: {6: "triangle6", 10: "triangle10", 15: "triangle15"},
    71: {10: "tetra10"},
}
#: types whose VTK id numbers the nodes differently from meshio: no pyvista conversion
_VTK_ORDER_DIFFERS = ("tetra20", "tetra35")
_VTK_TO_NAME = {vtk: name for name, vtk in VTK_CELL_TYPES.items()}
#: VTK pixel/voxel -> quad/hexahedron node order. Other types share VTK's order, wedges too:
#: VTK 9 measures warpmesh's wedges positive (meshio's VTK files reverse them: io.vtu).
_VTK_EXTRA = {8: ("quad", [0, 1, 3, 2]), 11: ("hexahedron", [0, 1, 3, 2, 4, 5, 7, 6])}
_POLY_TYPES = ("vertex", "line", "triangle", "quad")  # what a pyvista PolyData holds

GMSH_REF, GMSH_GEO = "gmsh:physical", "gmsh:geometrical"


# ----------------------------------------------------------------------------- helpers
def _native(value) -> np.ndarray:
    """``value`` as an array in native byte order (the VTK reader returns big-endian)."""
    arr = np.asarray(value)
    return arr.astype(arr.dtype.newbyteorder("=")) if arr.dtype.byteorder not in "=|" else arr


def set_dim(points: np.ndarray, dim) -> np.ndarray:
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


def _joined(parts: list[np.ndarray]) -> np.ndarray:
    """The parts concatenated; a single part as it is (no copy of a large block)."""
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


def _from_parts(mesh_type, points, blocks, point_data, cell_data, dim, info) -> MeshLike:
    """Build a ``mesh_type`` from blocks that may repeat a type; pull the refs out of the
    data arrays."""
    points = set_dim(np.asarray(points, dtype=REAL_DTYPE), dim)
    names = list(dict.fromkeys(t for t, _ in blocks))
    cells = {t: _joined([np.asarray(c) for u, c in blocks if u == t]) for t in names}
    point_data = {k: _native(v) for k, v in point_data.items()}
    cell_data = {
        k: {t: _joined([_native(a) for (u, _), a in zip(blocks, v, strict=True) if u == t]) for t in names}
        for k, v in cell_data.items()
    }
    point_refs = point_data.pop(REF_KEY, None)
    if point_refs is not None and point_refs.dtype.kind == "f":
        if not np.all(point_refs == np.round(point_refs)):
            raise ValueError(f"expected integer point refs {REF_KEY!r}, got non-integral values")
        point_refs = point_refs.astype(INDEX_DTYPE)
    cell_refs = next((cell_data.pop(k) for k in (REF_KEY, GMSH_REF) if k in cell_data), None)
    if cell_refs is not None and GMSH_GEO in cell_data:
        if all(np.array_equal(cell_data[GMSH_GEO][t], cell_refs[t]) for t in names):
            del cell_data[GMSH_GEO]
    if point_refs is not None and not np.any(point_refs):
        point_refs = None
    if cell_refs is not None and not any(np.any(r) for r in cell_refs.values()):
        cell_refs = None
    return mesh_type(
        points,
        cells,
        point_data=point_data,
        cell_data=cell_data,
        point_refs=point_refs,
        cell_refs=cell_refs,
        info=info,
    )


# ----------------------------------------------------------------------------- meshio
def to_meshio(mesh: MeshLike) -> meshio.Mesh:
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
    require_mesh(mesh)
    points, cells, point_refs, cell_refs = host_arrays(mesh)
    point_data = dict(mesh.point_data)
    cell_data = {k: [v[t] for t in cells] for k, v in mesh.cell_data.items()}
    if point_refs is not None:
        point_data[REF_KEY] = point_refs
    if cell_refs is not None:
        cell_data[REF_KEY] = [block_refs(mesh, t) for t in cells]
    return meshio.Mesh(points, list(cells.items()), point_data=point_data, cell_data=cell_data)


def host_arrays(mesh: MeshLike) -> tuple:
    """(points, cells, point_refs, cell_refs) in float64 / int64: the mesh's own, or for a
    compact mesh (:attr:`~warpmesh.mesh.Mesh.is_compact`) copies made for the caller that
    the mesh does not keep (a file written from a large compact mesh does not leave its
    float64 copies behind).

    >>> from warpmesh.mesh import Mesh
    >>> m = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]}, compact=True)
    >>> p, c, _, _ = host_arrays(m)
    >>> p.dtype.name, c["triangle"].dtype.name, m.nbytes
    ('float64', 'int64', 48)
    """
    if not getattr(mesh, "is_compact", False):
        return mesh.points, dict(mesh.cells), mesh.point_refs, mesh.cell_refs
    kept = mesh.compact_arrays

    def wide(a, dtype):
        return None if a is None else a.astype(dtype)

    crefs = kept["cell_refs"]
    return (kept["points"].astype(np.float64), {t: c.astype(np.int64) for t, c in kept["cells"].items()},
            wide(kept["point_refs"], np.int64), None if crefs is None else {t: wide(r, np.int64) for t, r in crefs.items()})


def from_meshio(m: meshio.Mesh, *, mesh_type: type[MeshLike], dim: Literal[2, 3] | None = None,
                info=None) -> MeshLike:
    """Convert from ``meshio.Mesh``.

    Blocks of the same type are concatenated. Refs are read from ``"medit:ref"``
    (points and cells) or ``"gmsh:physical"`` (cells); ``"gmsh:geometrical"`` is
    dropped when it equals the refs. ``cell_sets`` and ``field_data`` are ignored.

    Parameters
    ----------
    m : meshio.Mesh
    mesh_type : type
        The class to build, :class:`~warpmesh.mesh.Mesh` (``Mesh.from_*`` pass their own
        class: this module sits below ``mesh.py`` and does not import it).
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
    >>> from warpmesh.mesh import Mesh
    >>> from_meshio(m, mesh_type=Mesh).n_cells
    1
    """
    if not isinstance(m, meshio.Mesh):
        raise TypeError(f"expected a meshio.Mesh for 'm', got {type(m).__name__}")
    blocks = [(c.type, c.data) for c in m.cells]
    point_data = {k: v for k, v in m.point_data.items() if k != "gmsh:dim_tags"}
    return _from_parts(mesh_type, m.points, blocks, point_data, dict(m.cell_data), dim, info)


# ----------------------------------------------------------------------------- trimesh
def to_trimesh(mesh: MeshLike):
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

    require_mesh(mesh)
    if "triangle" not in mesh.cells:
        raise ValueError(
            f"expected a 'triangle' block for to_trimesh, got blocks {list(mesh.cells)}"
        )
    va = {k: np.asarray(v) for k, v in mesh.point_data.items()}
    fa = {k: np.asarray(v["triangle"]) for k, v in mesh.cell_data.items()}
    if mesh.point_refs is not None:
        va[REF_KEY] = np.asarray(mesh.point_refs)
    if mesh.cell_refs is not None:
        fa[REF_KEY] = np.asarray(block_refs(mesh, "triangle"))
    return trimesh.Trimesh(
        points3(mesh),
        np.asarray(mesh.triangles),
        process=False,
        validate=False,
        vertex_attributes=va,
        face_attributes=fa,
    )


def from_trimesh(tm, *, mesh_type: type[MeshLike], info=None) -> MeshLike:
    """Convert from ``trimesh.Trimesh`` (vertex/face attributes become point/cell data).

    Attributes whose length is not the number of vertices / faces are left out.

    Parameters
    ----------
    tm : trimesh.Trimesh
    mesh_type : type
        The class to build, :class:`~warpmesh.mesh.Mesh` (``Mesh.from_*`` pass their own
        class: this module sits below ``mesh.py`` and does not import it).
    info : dict, optional
        Passed to the :class:`~warpmesh.mesh.Mesh` constructor.

    Raises
    ------
    TypeError
        ``tm`` is not a ``trimesh.Trimesh``.

    Examples
    --------
    >>> import trimesh
    >>> from warpmesh.mesh import Mesh
    >>> from_trimesh(trimesh.creation.box(), mesh_type=Mesh).n_cells
    12
    """
    import trimesh

    if not isinstance(tm, trimesh.Trimesh):
        raise TypeError(f"expected a trimesh.Trimesh for 'tm', got {type(tm).__name__}")
    faces = np.asarray(tm.faces, dtype=INDEX_DTYPE)
    cell_data = {k: [v] for k, v in tm.face_attributes.items() if len(v) == len(faces)}
    point_data = {k: v for k, v in tm.vertex_attributes.items() if len(v) == len(tm.vertices)}
    return _from_parts(
        mesh_type, np.asarray(tm.vertices), [("triangle", faces)], point_data, cell_data, None, info
    )


# ----------------------------------------------------------------------------- pyvista
def to_pyvista(mesh: MeshLike):
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

    require_mesh(mesh)
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
        out.points = points3(mesh)
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
        out = pv.UnstructuredGrid(flat(order), kinds, points3(mesh))
    for k, v in mesh.point_data.items():
        out.point_data[k] = np.asarray(v)
    for k, v in mesh.cell_data.items():
        out.cell_data[k] = np.concatenate([v[t] for t in order])
    if mesh.point_refs is not None:
        out.point_data[REF_KEY] = np.asarray(mesh.point_refs)
    if mesh.cell_refs is not None:
        out.cell_data[REF_KEY] = np.concatenate([block_refs(mesh, t) for t in order])
    return out


def from_pyvista(
    obj, *, mesh_type: type[MeshLike], triangulate: bool = False, dim: Literal[2, 3] | None = None, info=None
) -> MeshLike:
    """Convert from any ``pyvista.DataSet`` (PolyData, UnstructuredGrid, ImageData, ...).

    Parameters
    ----------
    obj : pyvista.DataSet
    mesh_type : type
        The class to build, :class:`~warpmesh.mesh.Mesh` (``Mesh.from_*`` pass their own
        class: this module sits below ``mesh.py`` and does not import it).
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
    >>> from warpmesh.mesh import Mesh
    >>> from_pyvista(pv.Cube(), mesh_type=Mesh).cells["quad"].shape
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
        return from_pyvista(obj.triangulate(), mesh_type=mesh_type, triangulate=False, dim=dim, info=info)
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
    return _from_parts(mesh_type, np.asarray(ug.points), blocks, point_data, cell_data, dim, info)
