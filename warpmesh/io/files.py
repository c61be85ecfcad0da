"""Mesh files: :func:`save` (atomic) and :func:`load`, through meshio.

Each format registers itself (:func:`_register_format`) with what it keeps; what a
format cannot store is dropped with a ``UserWarning``. What each format keeps:

======  =======  =============================  ====================================
ext     format   cells                          besides points (precision) and cells
======  =======  =============================  ====================================
.vtu    vtu      all but the gmsh-only types    everything (float64)
.vtk    vtk      all but the gmsh-only types    everything (legacy binary, float64)
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

The gmsh-only types are line4, line5, triangle10, triangle15, tetra20 and tetra35: meshio's
vtu/vtk writers have no VTK type for them. Every format but Medit stores 3D points; 2D
meshes get z = 0 and come back 3D unless ``load(..., dim=2)``. Refs are written as
``"medit:ref"`` (Medit, vtu, vtk, ply) or as ``"gmsh:physical"`` (gmsh); refs that are
all zero are read back as "no refs" (Medit and gmsh always store one).

Examples
--------
>>> import os, tempfile
>>> from warpmesh.mesh import Mesh
>>> from warpmesh.io.files import load, save
>>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}, cell_refs={"triangle": [4]})
>>> with tempfile.TemporaryDirectory() as d:
...     load(save(m, os.path.join(d, "t.mesh")), mesh_type=Mesh).cell_refs["triangle"].tolist()
[4]
"""

from __future__ import annotations

import errno
import os
import uuid
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Literal

import meshio
import numpy as np

from warpmesh._conventions import INDEX_DTYPE
from warpmesh.cells.types import CELL_TYPES, REF_KEY, MeshLike, block_refs, points3
from warpmesh.io.convert import GMSH_GEO, GMSH_REF, from_meshio, set_dim, to_meshio
from warpmesh.errors import ReadError


__all__ = ["save", "load", "FILE_FORMATS", "FileFormat"]

#: what a format keeps of the point data and cell data ({name: [array per block]}):
#: ``(mesh, point_data, cell_data) -> (point_data, cell_data, names dropped)``
_DataFilter = Callable[[MeshLike, dict, dict], tuple[dict, dict, list]]


def _keep_all(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    return pd, cd, []


def _keep_nothing(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    return {}, {}, [*pd, *cd]


def _no_tidy(m: meshio.Mesh) -> None:
    pass


@dataclass(frozen=True)
class _Format:
    name: str  # also the meshio submodule whose reader load() calls
    ext: str
    meshio_name: str  # meshio's writer name
    write_kwargs: Mapping = field(default_factory=dict)
    cell_types: tuple[str, ...] | None = None  # None: every type
    keeps_2d: bool = False
    index_dtype: type = INDEX_DTYPE  # of the cells written
    keep_data: _DataFilter = _keep_all  # on save: which arrays the file gets
    tidy: Callable[[meshio.Mesh], None] = _no_tidy  # on load: drop what meshio invents


_FORMATS: dict[str, _Format] = {}  # name -> format, in registration order
_EXTENSIONS: dict[str, str] = {}
#: file extension -> format name, as chosen by :func:`save` and :func:`load`
FILE_FORMATS: Mapping[str, str] = MappingProxyType(_EXTENSIONS)
FileFormat = Literal["vtu", "vtk", "gmsh", "medit", "ply", "obj", "stl"]


def _register_format(name: str, ext: str, meshio_name: str, **options) -> None:
    """Make ``name`` (files ending in ``ext``) known to :func:`save` and :func:`load`."""
    _FORMATS[name] = _Format(name, ext, meshio_name, **options)
    _EXTENSIONS[ext] = name


def check_path(path, file_format: str | None = None) -> None:
    """Raise ValueError now if ``path`` (or ``file_format``) names no known format."""
    _find_format(Path(path), file_format)


def _find_format(path: Path, file_format: str | None) -> _Format:
    if file_format is not None:
        if file_format in _FORMATS:
            return _FORMATS[file_format]
        raise ValueError(f"unknown file_format {file_format!r}; expected one of {list(_FORMATS)}")
    if path.suffix.lower() in _EXTENSIONS:
        return _FORMATS[_EXTENSIONS[path.suffix.lower()]]
    raise ValueError(
        f"unknown mesh file extension {path.suffix!r} in {str(path)!r}; expected one of "
        f"{list(FILE_FORMATS)} or pass file_format= one of {list(_FORMATS)}"
    )


# ----------------------------------------------------------------------------- formats
def _medit_data(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    """Medit stores one ref per point and per cell, nothing else."""
    dropped = [k for k in [*pd, *cd] if k != REF_KEY]
    pd = {REF_KEY: pd.get(REF_KEY, np.zeros(mesh.n_points, dtype=INDEX_DTYPE))}
    cd = {REF_KEY: [block_refs(mesh, t) for t in mesh.cells]}
    return pd, cd, dropped


def _gmsh_data(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    """Cell refs become gmsh:physical = gmsh:geometrical; cell data only with one block."""
    dropped = []
    if len(mesh.cells) > 1:
        dropped += [k for k in cd if k != REF_KEY]  # meshio cannot read them back
        cd = {}
    dropped += [k for k in cd if k in (GMSH_REF, GMSH_GEO)]  # replaced by the refs
    tags = [block_refs(mesh, t).astype(np.int32) for t in mesh.cells]
    cd = {
        **{k: v for k, v in cd.items() if k not in (REF_KEY, GMSH_REF, GMSH_GEO)},
        GMSH_REF: tags,
        GMSH_GEO: tags,
    }
    return pd, cd, dropped


def _ply_data(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    """PLY keeps scalar point data only (integers as int32)."""
    dropped = [*cd, *(k for k, v in pd.items() if v.ndim != 1)]
    pd = {k: v.astype(np.int32) if v.dtype.kind in "iu" else v for k, v in pd.items()}
    return {k: v for k, v in pd.items() if v.ndim == 1}, {}, dropped


def _tidy_stl(m: meshio.Mesh) -> None:
    m.cell_data.pop("facet_normals", None)  # derived by meshio, not data


def _tidy_obj(m: meshio.Mesh) -> None:
    if all(np.all(g == -1) for g in m.cell_data.get("obj:group_ids", [])):
        m.cell_data.pop("obj:group_ids", None)  # meshio's "no group"


_SURFACE = ("triangle", "quad")
_GMSH_ONLY = ("line4", "line5", "triangle10", "triangle15", "tetra20", "tetra35")
_VTK_CELLS = tuple(t for t in CELL_TYPES if t not in _GMSH_ONLY)
_register_format("vtu", ".vtu", "vtu", write_kwargs={"binary": True}, cell_types=_VTK_CELLS)
_register_format("vtk", ".vtk", "vtk", write_kwargs={"binary": True}, cell_types=_VTK_CELLS)
_register_format("gmsh", ".msh", "gmsh22", write_kwargs={"binary": True}, keep_data=_gmsh_data)
_register_format(
    "medit",
    ".mesh",
    "medit",
    cell_types=("line", "triangle", "quad", "tetra", "pyramid", "wedge", "hexahedron"),
    keeps_2d=True,
    keep_data=_medit_data,
)
_register_format(
    "ply",
    ".ply",
    "ply",
    write_kwargs={"binary": True},
    cell_types=_SURFACE,
    index_dtype=np.int32,
    keep_data=_ply_data,
)
_register_format("obj", ".obj", "obj", cell_types=_SURFACE, keep_data=_keep_nothing, tidy=_tidy_obj)
_register_format(
    "stl",
    ".stl",
    "stl",
    write_kwargs={"binary": True},
    cell_types=("triangle",),
    keep_data=_keep_nothing,
    tidy=_tidy_stl,
)


# ----------------------------------------------------------------------------- save / load
def _meshio_for(mesh: MeshLike, fmt: _Format, stacklevel: int) -> meshio.Mesh:
    """The meshio object written for ``fmt``; warns about what the format drops.

    ``stacklevel`` counts frames as ``warnings.warn`` would from the caller (here and in
    :func:`_save`), so the warning names the line that asked for the file.
    """
    if fmt.cell_types is not None:
        bad = [t for t in mesh.cells if t not in fmt.cell_types]
        if bad:
            able = [f.name for f in _FORMATS.values()
                    if f.cell_types is None or all(t in f.cell_types for t in mesh.cells)]
            raise ValueError(
                f"{fmt.name} ({fmt.ext}) files store only {list(fmt.cell_types)} cells, "
                f"got {bad}; save a mesh without them or pick one of {able}"
            )
    m = to_meshio(mesh)
    pd, cd, dropped = fmt.keep_data(mesh, dict(m.point_data), dict(m.cell_data))
    if dropped:
        warnings.warn(
            f"{fmt.name} files cannot store {sorted(set(dropped))}; not saved",
            UserWarning,
            stacklevel=stacklevel + 1,
        )
    points = np.asarray(mesh.points) if fmt.keeps_2d else points3(mesh)
    cells = [(t, c.astype(fmt.index_dtype, copy=False)) for t, c in mesh.cells.items()]
    return meshio.Mesh(points, cells, point_data=pd, cell_data=cd)


def save_mesh(mesh: MeshLike, path, file_format: str | None, stacklevel: int) -> Path:
    """:func:`save` with the stack level of its warnings (``Mesh.save`` passes its caller's)."""
    path = Path(path)
    fmt = _find_format(path, file_format)
    if mesh.n_points == 0 or mesh.n_cells == 0:
        raise ValueError(f"expected a mesh with points and cells to save to {str(path)!r}, got an empty "
                         f"mesh ({mesh.n_points} points, {mesh.n_cells} cells): mesh files cannot hold it")
    data = _meshio_for(mesh, fmt, stacklevel + 1)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        meshio.write(tmp, data, file_format=fmt.meshio_name, **fmt.write_kwargs)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def save(mesh: MeshLike, path, *, file_format: FileFormat | None = None) -> Path:
    """Write ``mesh`` through meshio, atomically (also :meth:`Mesh.save <warpmesh.mesh.Mesh.save>`).

    The file is written to a temporary name in the same directory and renamed over
    ``path`` (``os.replace``), so a failure leaves neither a partial file nor a stale
    temporary. See the module docstring for what each format keeps; whatever it cannot
    store is dropped with a ``UserWarning``.

    Parameters
    ----------
    mesh : Mesh
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
    >>> from warpmesh.mesh import Mesh
    >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
    >>> with tempfile.TemporaryDirectory() as d:
    ...     load(save(m, os.path.join(d, "t.vtu")), mesh_type=Mesh, dim=2).n_cells
    1
    """
    return save_mesh(mesh, path, file_format, stacklevel=2)


def load(path, *, mesh_type: type[MeshLike], file_format: FileFormat | None = None,
         dim: Literal[2, 3] | None = None) -> MeshLike:
    """Read a mesh file written by :func:`save` or another program.

    Parameters
    ----------
    path : str or os.PathLike
    mesh_type : type
        The class to build, :class:`~warpmesh.mesh.Mesh` (``warpmesh.load`` and
        ``Mesh.load`` pass it: this module sits below ``mesh.py``).
    file_format : {'vtu', 'vtk', 'gmsh', 'medit', 'ply', 'obj', 'stl'}, optional
        Default: from the extension.
    dim : {None, 2, 3}
        ``2`` drops a zero z column (formats other than Medit store 3D points).

    Returns
    -------
    Mesh

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
    >>> from warpmesh.mesh import Mesh
    >>> load("no/such/file.vtu", mesh_type=Mesh)
    Traceback (most recent call last):
    ...
    FileNotFoundError: [Errno 2] no such mesh file: 'no/such/file.vtu'
    """
    path = Path(path)
    fmt = _find_format(path, file_format)
    set_dim(np.zeros((0, 3)), dim)  # check the argument before reading
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, "no such mesh file", str(path))
    reader = getattr(meshio, fmt.name).read  # the format's own: meshio.read calls sys.exit
    try:
        with warnings.catch_warnings():
            # meshio's binary-STL probe overflows on ascii files
            warnings.simplefilter("ignore", RuntimeWarning)
            m = reader(str(path))
    except Exception as exc:  # meshio raises ReadError, ValueError, UnicodeError, IndexError, ...
        raise ReadError(
            f"could not read {str(path)!r} as {fmt.name}: {type(exc).__name__}: {exc}"
        ) from exc
    fmt.tidy(m)
    if len(m.points) == 0:
        raise ReadError(f"could not read {str(path)!r} as {fmt.name}: the file holds no points")
    try:
        mesh = from_meshio(m, mesh_type=mesh_type)
    except (ValueError, TypeError) as exc:
        raise ReadError(f"could not read {str(path)!r} as {fmt.name}: invalid mesh: {exc}") from exc
    if dim in (None, mesh.dim):
        return mesh
    return mesh.replace(points=set_dim(np.asarray(mesh.points), dim))
