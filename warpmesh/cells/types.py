"""The cell vocabulary: cell-type names, their node counts, dimensions and VTK ids; the
name of the refs arrays in files; what every operation accepts as a mesh.

This is the bottom layer: it imports nothing of warpmesh but the conventions, so every
stage (and :class:`warpmesh.mesh.Mesh`, which offers the operations as methods) can use it.

Examples
--------
>>> from warpmesh.cells.types import CELL_TYPES
>>> CELL_TYPES["tetra10"]          # (nodes per cell, topological dimension, VTK id)
(10, 3, 24)
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Protocol, runtime_checkable

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE

__all__ = ["CELL_TYPES", "REF_KEY", "MeshLike", "require_mesh", "block_refs", "points3"]

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

#: name of the refs arrays in meshio, pyvista and trimesh objects
REF_KEY = "medit:ref"


@runtime_checkable
class MeshLike(Protocol):
    """What an operation needs of a mesh: :class:`warpmesh.mesh.Mesh` has it.

    Operations take and return meshes without importing the ``Mesh`` class (which
    imports them): they build results with ``type(mesh)(...)`` or ``mesh.replace(...)``.
    """

    points: np.ndarray
    cells: Mapping
    point_refs: np.ndarray | None
    cell_refs: Mapping | None
    point_data: Mapping
    cell_data: Mapping

    def replace(self, **changes): ...


_MESH_ATTRIBUTES = ("points", "cells", "point_refs", "cell_refs", "point_data", "cell_data", "replace")


def require_mesh(mesh, name: str = "mesh") -> None:
    """Raise TypeError unless ``mesh`` is a warpmesh Mesh (anything with its attributes).

    Examples
    --------
    >>> require_mesh([[0, 0, 0]])
    Traceback (most recent call last):
    ...
    TypeError: expected a warpmesh Mesh for 'mesh', got list; convert with Mesh.from_meshio / from_pyvista / from_trimesh
    """
    if all(hasattr(type(mesh), a) for a in _MESH_ATTRIBUTES):  # declared by its class: no property evaluated
        return  # (a compact Mesh makes float64 / int64 copies when its accessors are read)
    if not isinstance(mesh, MeshLike):
        raise TypeError(f"expected a warpmesh Mesh for {name!r}, got {type(mesh).__name__}; "
                        "convert with Mesh.from_meshio / from_pyvista / from_trimesh")


def points3(mesh) -> np.ndarray:
    """(n, 3) float64: the points, 2D ones with z = 0."""
    if mesh.dim == 3:
        return np.asarray(mesh.points)
    return np.column_stack([mesh.points, np.zeros(mesh.n_points, dtype=REAL_DTYPE)])


def block_refs(mesh, t: str) -> np.ndarray:
    """(m,) int64: the refs of the cell block ``t``, zeros when it has none (of a compact
    mesh, :attr:`~warpmesh.mesh.Mesh.is_compact`: a copy, which the mesh does not keep)."""
    kept = mesh.compact_arrays if getattr(mesh, "is_compact", False) else None
    crefs, cells = (mesh.cell_refs, mesh.cells) if kept is None else (kept["cell_refs"], kept["cells"])
    refs = None if crefs is None else crefs.get(t)
    return np.zeros(len(cells[t]), dtype=INDEX_DTYPE) if refs is None else refs.astype(INDEX_DTYPE, copy=False)
