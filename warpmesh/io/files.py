"""Mesh files: :func:`save` (atomic) and :func:`load`, through meshio.

Each format registers itself (:func:`_register_format`) with what it keeps; what a
format cannot store is dropped with a ``UserWarning``. What each format keeps:

======  =======  =============================  ====================================
ext     format   cells                          besides points (precision) and cells
======  =======  =============================  ====================================
.vtu    vtu      all but the gmsh-only types    everything (float64; read and
                                                written by :mod:`warpmesh.io.vtu`,
                                                zlib blocks on every core)
.pvtu   pvtu     all but the gmsh-only types    everything: one piece ``<stem>_0.vtu``
                                                beside it; read: every piece, points
                                                of one global id welded (a bricked
                                                run's output; :mod:`warpmesh.io.pvtu`)
.vtk    vtk      all but the gmsh-only types    everything (legacy binary, float64)
.msh    gmsh     all                            gmsh 2.2 binary: cell refs as
                                                gmsh:physical (= gmsh:geometrical),
                                                point refs and point data, cell data
                                                only with a single block; refs named
                                                (region_3, ref_2); surfaces of label
                                                interfaces: gmsh 4.1 binary with a
                                                group per label and per interface,
                                                refs only (:mod:`~warpmesh.io.gmsh_groups`)
.mesh   medit    line tri quad tetra pyramid    point refs, cell refs (Medit ascii,
                 wedge hexahedron               17 digits; :mod:`warpmesh.io.medit`:
                                                meshio's bytes, 4x faster, read with a
                                                kernel); 2D kept 2D
.ply    ply      triangle quad                  point and cell refs (``ref``), point and
                                                cell data of one value each, as vertex
                                                and face properties (binary;
                                                :mod:`warpmesh.io.ply`; meshio
                                                reads face properties from ascii
                                                only: ``binary=False``)
.obj    obj      triangle quad                  nothing else (17 digits)
.stl    stl      triangle                       nothing else (binary float32;
                                                points are merged and renumbered)
======  =======  =============================  ====================================

Every other format meshio reads and writes (Abaqus ``.inp``, Nastran ``.nas``/``.bdf``,
SU2, XDMF, MED, Exodus, Netgen ``.vol``, OFF, Permas, Tecplot, TetGen ``.node``/``.ele``,
...) works too, with what a probe of this installation found it round-trips
(:mod:`warpmesh.io.formats`): its cell types, its cell refs when they come back, no
other data (dropped with a warning). :func:`file_formats` lists every extension that
works here; XDMF, MED, CGNS and HMF need h5py and Exodus netCDF4 (the ``[formats]``
extra). Legacy ``.vtk`` files meshio cannot parse (64-bit ids) are read by VTK. Wedges
in ``.vtu`` and ``.vtk`` files keep their corners both ways, the orientation VTK measures
positive (meshio's own VTK writers and readers reverse them: :mod:`warpmesh.io.vtu`).

The gmsh-only types are line4, line5, triangle10, triangle15, tetra20 and tetra35: meshio's
vtu/vtk writers have no VTK type for them. Every format but Medit stores 3D points; 2D
meshes get z = 0 and come back 3D unless ``load(..., dim=2)``. Refs are written as
``"medit:ref"`` (Medit, vtu, vtk), ``ref`` (ply) or as ``"gmsh:physical"`` (gmsh); refs that are
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
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Literal

import meshio
import numpy as np

from warpmesh._util.atomic import atomic_path
from warpmesh._conventions import INDEX_DTYPE
from warpmesh.cells.types import REF_KEY, MeshLike, block_refs
from meshio._helpers import reader_map

from warpmesh.io.eof_guard import guarded_reader
from warpmesh.io.convert import GMSH_GEO, GMSH_REF, from_meshio, set_dim, to_meshio
from warpmesh.io.formats import format_support, meshio_extensions
from warpmesh.io.gmsh_groups import LABEL_ABOVE, ref_names, restore_refs, uses_groups, write_msh41
from warpmesh.io.medit import read_medit, write_medit
from warpmesh.io.ply import read_ply, write_ply
from warpmesh.io.pvtu import read_pvtu, write_pvtu
from warpmesh.io.vtu import VTK_CELL_TYPES, meshio_wedges, read_vtu, write_vtu
from warpmesh.errors import ReadError, WarpMeshError, WriteError


__all__ = ["save", "load", "file_formats", "FILE_FORMATS", "FileFormat"]

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
    #: on load: drop what meshio invents; may return a dict of info the file holds (a label volume's labels)
    tidy: Callable[[meshio.Mesh], dict | None] = _no_tidy
    folder: bool = False  # written in a temporary folder (writers that add side files: .h5, .ele)
    read: Callable[[str], meshio.Mesh] | None = None  # warpmesh's own reader (default: meshio's)
    write: Callable[..., object] | None = None  # warpmesh's own: (path, meshio.Mesh, mesh, **write_kwargs)
    mixed: bool = True  # a mesh of several cell types comes back (a meshio format: as its probe found)
    mixed_quadratic: bool = True  # the same with second-order cells


_FORMATS: dict[str, _Format] = {}  # name -> format, in registration order
_EXTENSIONS: dict[str, str] = {}
#: file extension -> format name, as chosen by :func:`save` and :func:`load`
FILE_FORMATS: Mapping[str, str] = MappingProxyType(_EXTENSIONS)
FileFormat = Literal["vtu", "pvtu", "vtk", "gmsh", "medit", "ply", "obj", "stl"]


def _register_format(name: str, ext: str, meshio_name: str, **options) -> None:
    """Make ``name`` (files ending in ``ext``) known to :func:`save` and :func:`load`."""
    _FORMATS[name] = _Format(name, ext, meshio_name, **options)
    _EXTENSIONS[ext] = name


def check_path(path, file_format: str | None = None) -> None:
    """Raise ValueError now if ``path`` (or ``file_format``) names no known format."""
    _find_format(Path(path), file_format)


def file_formats() -> dict[str, str]:
    """Every extension :func:`save` and :func:`load` take here -> its format: the curated
    :data:`FILE_FORMATS`, then meshio's other formats that round-trip at least one cell
    type on this installation (:func:`warpmesh.io.formats.format_support`, probed once
    per installation and cached).

    Example
    -------
    >>> from warpmesh.io.files import file_formats
    >>> file_formats()[".vtu"], file_formats()[".inp"]
    ('vtu', 'abaqus')
    """
    support = format_support()
    more = {ext: name for ext, name in meshio_extensions(exclude=tuple(FILE_FORMATS)).items()
            if name in support and support[name].cells}
    return {**FILE_FORMATS, **more}


def _meshio_format(name: str, ext: str) -> _Format:
    """A format of meshio's that warpmesh does not curate, as this installation's probe
    found it: the cell types that round-trip, refs if they come back, nothing else."""
    sup = format_support().get(name)
    if sup is None or not sup.cells:
        why = "meshio has no such format" if sup is None else sup.error
        raise ValueError(f"meshio's {name!r} format ({ext}) does not round-trip any mesh on this installation "
                         f"({why}); use one of {list(file_formats())}")
    return _Format(name, ext, name, cell_types=sup.cells, keep_data=_refs_as(sup.refs),
                   tidy=_refs_back(sup.refs), folder=True, mixed=sup.mixed, mixed_quadratic=sup.mixed_quadratic)


def _find_format(path: Path, file_format: str | None) -> _Format:
    if file_format is not None:
        if file_format in _FORMATS:
            return _FORMATS[file_format]
        if file_format in format_support():
            sup = format_support()[file_format]
            return _meshio_format(file_format, sup.extensions[0])
        raise ValueError(f"unknown file_format {file_format!r}; expected one of "
                         f"{sorted(set(_FORMATS) | set(format_support()))}")
    ext = path.suffix.lower()
    if ext in _EXTENSIONS:
        return _FORMATS[_EXTENSIONS[ext]]
    other = meshio_extensions(exclude=tuple(FILE_FORMATS))
    if ext in other:
        return _meshio_format(other[ext], ext)
    raise ValueError(
        f"unknown mesh file extension {ext!r} in {str(path)!r}; expected one of {list(file_formats())}"
    )


# ----------------------------------------------------------------------------- formats
def _medit_data(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    """Medit stores one ref per point and per cell, nothing else."""
    dropped = [k for k in [*pd, *cd] if k != REF_KEY]
    pd = {REF_KEY: pd.get(REF_KEY, np.zeros(mesh.n_points, dtype=INDEX_DTYPE))}
    cd = {REF_KEY: [block_refs(mesh, t) for t in mesh.cells]}
    return pd, cd, dropped


def _gmsh_data(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    """Cell refs become gmsh:physical = gmsh:geometrical; cell data only with one block. A
    mesh of labels, interfaces or regions (:func:`~warpmesh.io.gmsh_groups.uses_groups`)
    keeps its refs as named groups and nothing else."""
    if uses_groups(mesh):
        kept = (REF_KEY, LABEL_ABOVE)
        return {}, {k: v for k, v in cd.items() if k in kept}, [*pd, *(k for k in cd if k not in kept)]
    dropped = []
    if len(mesh.cells) > 1:
        dropped += [k for k in cd if k != REF_KEY]  # meshio cannot read them back
        cd = {}
    dropped += [k for k in cd if k in (GMSH_REF, GMSH_GEO)]  # replaced by the refs
    tags = [block_refs(mesh, t) for t in mesh.cells]
    big = [int(r[np.argmax(np.abs(r))]) for r in tags if len(r) and np.abs(r).max() > np.iinfo(np.int32).max]
    if big:  # physical tags are 32-bit: 2**31 came back as -2**31, 2**40 as no refs at all
        raise ValueError(f"gmsh (.msh) physical tags are 32-bit integers, got cell ref {big[0]}; number the refs "
                         "below 2**31 or save as .vtu")
    tags = [r.astype(np.int32) for r in tags]
    cd = {
        **{k: v for k, v in cd.items() if k not in (REF_KEY, GMSH_REF, GMSH_GEO)},
        GMSH_REF: tags,
        GMSH_GEO: tags,
    }
    return pd, cd, dropped


def _ply_data(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
    """PLY keeps one value per vertex and per face (vertex and face properties)."""
    def scalar(v) -> bool:
        return np.asarray(v).ndim == 1 or (np.asarray(v).ndim == 2 and np.asarray(v).shape[1] == 1)

    dropped = [k for k, v in pd.items() if not scalar(v)] + [k for k, v in cd.items() if not all(map(scalar, v))]
    return ({k: v for k, v in pd.items() if k not in dropped}, {k: v for k, v in cd.items() if k not in dropped},
            dropped)


def _write_gmsh(path, data: meshio.Mesh, mesh: MeshLike, **kwargs) -> None:
    """Named groups in gmsh 4.1 for meshes of labels and regions, else meshio's gmsh 2.2."""
    if uses_groups(mesh):
        write_msh41(path, mesh)
        return
    names = ref_names(mesh)
    if names:  # $PhysicalNames: a name per ref
        data = meshio.Mesh(data.points, data.cells, point_data=data.point_data, cell_data=data.cell_data,
                           field_data={k: np.array(v) for k, v in names.items()})
    _meshio_write(path, data, "gmsh22", **kwargs)


def _meshio_write(path, data: meshio.Mesh, file_format: str, **kwargs) -> None:
    """meshio's writer; its failures other than the file system's (assertions, KeyErrors,
    meshio's WriteError) become a WriteError naming the format (the atomic write around it
    leaves nothing on disk)."""
    try:
        meshio.write(path, data, file_format=file_format, **kwargs)
    except (OSError, WarpMeshError):
        raise
    except Exception as exc:  # noqa: BLE001 -- any meshio failure, named
        raise WriteError(f"meshio's {file_format} writer failed on this mesh: {type(exc).__name__}: {exc}") from exc


#: what meshio prints (to stderr, through rich, not the warnings module) on every ascii .vtk it
#: writes: the user asked for ascii (``binary=False``, the CLI's ``--ascii``), so it is not passed on
_VTK_ASCII_NOTICE = "VTK ASCII files are only meant for debugging."


def _write_vtk(path, data: meshio.Mesh, mesh: MeshLike, **kwargs) -> None:
    # meshio's writer reverses each wedge (io.vtu's module docstring): reversed first, the
    # file holds them as VTK measures them positive
    if kwargs.get("binary", True):
        _meshio_write(path, meshio_wedges(data), "vtk", **kwargs)
        return
    import contextlib
    import io
    import sys

    printed = io.StringIO()
    try:
        with contextlib.redirect_stderr(printed):
            _meshio_write(path, meshio_wedges(data), "vtk", **kwargs)
    finally:  # anything else meshio printed still reaches the user
        rest = "".join(line for line in printed.getvalue().splitlines(keepends=True) if _VTK_ASCII_NOTICE not in line)
        if rest:
            sys.stderr.write(rest)


def _write_ply(path, data: meshio.Mesh, mesh: MeshLike, **kwargs) -> None:
    write_ply(path, data, **kwargs)


def _tidy_stl(m: meshio.Mesh) -> None:
    m.cell_data.pop("facet_normals", None)  # derived by meshio, not data


def _refs_as(name: str | None) -> _DataFilter:
    """What a probed meshio format gets: the cell refs when they come back, nothing else."""
    def keep(mesh: MeshLike, pd: dict, cd: dict) -> tuple[dict, dict, list]:
        if name is None:
            return {}, {}, [*pd, *cd]
        return {}, {REF_KEY: [block_refs(mesh, t) for t in mesh.cells]}, [*pd, *(k for k in cd if k != REF_KEY)]
    return keep


def _refs_back(name: str | None) -> Callable[[meshio.Mesh], None]:
    """On load: the refs under the name the format gives them; other cell data dropped
    only when it is the refs' copy."""
    def tidy(m: meshio.Mesh) -> None:
        if name is None or name not in m.cell_data:
            return
        refs = m.cell_data.pop(name)
        # some formats store every array as floats (tecplot): whole numbers come back as refs
        if all(np.asarray(r).dtype.kind == "f" and np.all(np.asarray(r) == np.round(r)) for r in refs):
            refs = [np.asarray(r).astype(INDEX_DTYPE) for r in refs]
        m.cell_data[REF_KEY] = refs
    return tidy


def _tidy_pvtu(m: meshio.Mesh) -> None:
    # a bricked run's pieces name their refs "ref" (warpmesh.distributed.output)
    if REF_KEY not in m.cell_data and "ref" in m.cell_data:
        m.cell_data[REF_KEY] = m.cell_data.pop("ref")


def _tidy_obj(m: meshio.Mesh) -> None:
    if all(np.all(g == -1) for g in m.cell_data.get("obj:group_ids", [])):
        m.cell_data.pop("obj:group_ids", None)  # meshio's "no group"


_SURFACE = ("triangle", "quad")
_VTK_CELLS = tuple(VTK_CELL_TYPES)  # all but the gmsh-only types
_register_format("vtu", ".vtu", "vtu", cell_types=_VTK_CELLS, write=write_vtu, read=read_vtu)
_register_format("pvtu", ".pvtu", "vtu", cell_types=_VTK_CELLS, write=write_pvtu, read=read_pvtu, folder=True,
                 tidy=_tidy_pvtu)
_register_format("vtk", ".vtk", "vtk", write_kwargs={"binary": True}, cell_types=_VTK_CELLS, write=_write_vtk,
                 tidy=meshio_wedges)
_register_format("gmsh", ".msh", "gmsh22", write_kwargs={"binary": True}, keep_data=_gmsh_data,
                 write=_write_gmsh, tidy=restore_refs)
_register_format(
    "medit",
    ".mesh",
    "medit",
    cell_types=("line", "triangle", "quad", "tetra", "pyramid", "wedge", "hexahedron"),
    keeps_2d=True,
    keep_data=_medit_data,
    write=write_medit,
    read=read_medit,
)
_register_format(
    "ply",
    ".ply",
    "ply",
    write_kwargs={"binary": True},
    cell_types=_SURFACE,
    index_dtype=np.int32,
    keep_data=_ply_data,
    read=read_ply,
    write=_write_ply,
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
#: first-order cell types (a mesh with others is checked against a format's quadratic probe)
_FIRST_ORDER = ("vertex", "line", "triangle", "quad", "tetra", "hexahedron", "wedge", "pyramid")
#: the largest cell ref a Netgen file takes (its writer writes a line per index up to it: a
#: ref of 2**31 filled the disk)
NETGEN_MAX_REF = 10**6


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
    if fmt.name == "netgen" and mesh.cell_refs:  # meshio's writer lists every index up to the largest
        top = max((int(np.max(r)) for r in mesh.cell_refs.values() if len(r)), default=0)
        if top > NETGEN_MAX_REF:
            raise ValueError(f"netgen ({fmt.ext}) files list every index up to the largest cell ref, at most "
                             f"{NETGEN_MAX_REF} here, got {top}; number the refs 1, 2, ... or pick one of "
                             f"{list(FILE_FORMATS)}")
    quadratic = any(t not in _FIRST_ORDER for t in mesh.cells)
    if len(mesh.cells) > 1 and not (fmt.mixed_quadratic if quadratic else fmt.mixed):
        # (Tecplot wrote tetrahedra without their triangles; XDMF's reader fails on tetra10 + triangle6)
        raise ValueError(f"{fmt.name} ({fmt.ext}) files here do not bring a mesh of several cell types back (its "
                         f"probe: {'tetra10 and triangle6' if quadratic else 'tetrahedra and triangles'}), got "
                         f"{list(mesh.cells)}; save each type to a file of its own or pick one of "
                         f"{list(FILE_FORMATS)}")
    m = to_meshio(mesh)
    pd, cd, dropped = fmt.keep_data(mesh, dict(m.point_data), dict(m.cell_data))
    if dropped:
        warnings.warn(
            f"{fmt.name} files cannot store {sorted(set(dropped))}; not saved",
            UserWarning,
            stacklevel=stacklevel + 1,
        )
    points = m.points  # (a compact mesh's float64 copies, which it does not keep)
    if not fmt.keeps_2d and points.shape[1] == 2:
        points = np.column_stack([points, np.zeros(len(points), dtype=points.dtype)])
    cells = [(c.type, c.data.astype(fmt.index_dtype, copy=False)) for c in m.cells]
    return meshio.Mesh(points, cells, point_data=pd, cell_data=cd)


#: the formats written binary by default whose ascii encoding :func:`save` offers (``binary=False``)
TWO_ENCODINGS = ("vtk", "ply", "stl")


def save_mesh(mesh: MeshLike, path, file_format: str | None, stacklevel: int, binary: bool | None = None) -> Path:
    """:func:`save` with the stack level of its warnings (``Mesh.save`` passes its caller's)."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"expected a str or os.PathLike 'path', got {type(path).__name__}")
    if binary is not None and not isinstance(binary, (bool, np.bool_)):
        raise TypeError(f"expected True, False or None for 'binary', got {type(binary).__name__}")
    path = Path(path)
    if not path.parent.is_dir():  # (else the error names the temporary file)
        raise FileNotFoundError(errno.ENOENT, f"no folder {str(path.parent)!r} to save {path.name!r} in",
                                str(path.parent))
    if path.is_dir():  # (else the error names the temporary file)
        raise IsADirectoryError(errno.EISDIR, f"expected a file path to save to, got the folder {str(path)!r}",
                                str(path))
    fmt = _find_format(path, file_format)
    kwargs = dict(fmt.write_kwargs)
    if binary is not None:
        if fmt.name not in TWO_ENCODINGS:
            why = (" (meshio's ascii gmsh writer puts numpy 2's repr, 'np.float64(0.0)', in its data sections: "
                   "no reader takes them)" if fmt.name == "gmsh" else " (written in one encoding)")
            raise ValueError(f"expected binary=None for a {fmt.name} file{why}; 'binary' chooses between binary "
                             f"and ascii for {', '.join(TWO_ENCODINGS)}")
        kwargs["binary"] = bool(binary)
    if mesh.n_points == 0 or mesh.n_cells == 0:
        raise ValueError(f"expected a mesh with points and cells to save to {str(path)!r}, got an empty "
                         f"mesh ({mesh.n_points} points, {mesh.n_cells} cells): mesh files cannot hold it")
    if getattr(mesh, "is_compact", False):  # written from float64 / int64 copies that the mesh does not keep
        mesh = mesh.replace(compact=False)
    data = _meshio_for(mesh, fmt, stacklevel + 1)
    # through a symbolic link: its target is written (the rename would replace the link)
    dest = Path(os.path.realpath(path)) if path.is_symlink() else path
    if fmt.folder:
        _write_in_folder(data, mesh, dest, fmt)
        return path
    with atomic_path(dest) as tmp:
        _write(fmt, tmp, data, mesh, kwargs)
    return path


def _write(fmt: _Format, path: Path, data: meshio.Mesh, mesh: MeshLike, kwargs: Mapping | None = None) -> None:
    """The format's own writer, else meshio's (``kwargs``: the writer's keywords, default
    the format's)."""
    kwargs = fmt.write_kwargs if kwargs is None else kwargs
    if fmt.write is not None:
        fmt.write(path, data, mesh, **kwargs)
    else:
        _meshio_write(path, data, fmt.meshio_name, **kwargs)


def _write_in_folder(data: meshio.Mesh, mesh: MeshLike, path: Path, fmt: _Format) -> None:
    """Write with the final name inside a temporary folder next to ``path`` (side files,
    such as XDMF's .h5 or TetGen's .ele, keep the names the main file refers to), then
    move every file out, the main file last; on failure nothing is left."""
    with atomic_path(path, kind="tmpdir") as tmp:
        _write(fmt, tmp / path.name, data, mesh)


def save(mesh: MeshLike, path, *, file_format: FileFormat | None = None, binary: bool | None = None) -> Path:
    """Write ``mesh`` through meshio, atomically (also :meth:`Mesh.save <warpmesh.mesh.Mesh.save>`).

    The file is written to a temporary name in the same directory and renamed over
    ``path`` (``os.replace``), so a failure leaves neither a partial file nor a stale
    temporary. See the module docstring for what each format keeps; whatever it cannot
    store is dropped with a ``UserWarning``.

    Parameters
    ----------
    mesh : Mesh
    path : str or os.PathLike
    file_format : {'vtu', 'pvtu', 'vtk', 'gmsh', 'medit', 'ply', 'obj', 'stl'}, optional
        Default: from the extension (:data:`FILE_FORMATS`).
    binary : bool, optional
        For vtk, ply and stl, written binary by default: False writes ascii instead (e.g. a
        ``.ply`` with face properties for meshio, whose binary PLY reader cannot read them).
        None: the format's default. (gmsh stays binary: meshio's ascii gmsh writer puts
        numpy 2 scalar reprs in its data sections.)

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        Unknown extension or format, cell types the format cannot store, or ``binary``
        given for another format than vtk, ply and stl.
    TypeError
        ``binary`` not a bool or None.

    Examples
    --------
    >>> import tempfile, os
    >>> from warpmesh.mesh import Mesh
    >>> m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
    >>> with tempfile.TemporaryDirectory() as d:
    ...     load(save(m, os.path.join(d, "t.vtu")), mesh_type=Mesh, dim=2).n_cells
    1
    """
    return save_mesh(mesh, path, file_format, stacklevel=2, binary=binary)


def load(path, *, mesh_type: type[MeshLike], file_format: FileFormat | None = None,
         dim: Literal[2, 3] | None = None) -> MeshLike:
    """Read a mesh file written by :func:`save` or another program.

    Parameters
    ----------
    path : str or os.PathLike
    mesh_type : type
        The class to build, :class:`~warpmesh.mesh.Mesh` (``warpmesh.load`` and
        ``Mesh.load`` pass it: this module sits below ``mesh.py``).
    file_format : {'vtu', 'pvtu', 'vtk', 'gmsh', 'medit', 'ply', 'obj', 'stl'}, optional
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
    # the format's own reader, else meshio's (not meshio.read, which calls sys.exit), stopped
    # where it would read past the end of a cut file forever
    reader = fmt.read or guarded_reader(reader_map[fmt.name])
    _check_complete(path, fmt.name)
    try:
        with warnings.catch_warnings():
            # meshio's binary-STL probe overflows on ascii files
            warnings.simplefilter("ignore", RuntimeWarning)
            m = reader(str(path))
    except Exception as exc:  # meshio raises ReadError, ValueError, UnicodeError, IndexError, ...
        if isinstance(exc, ReadError) and fmt.read is not None:  # warpmesh's own readers name the file
            raise
        if fmt.name in ("vtk", "vtu") and not isinstance(exc, ReadError):
            # VTK's own reader knows what meshio's does not (64-bit ids); not a cut file (the guard's
            # ReadError), which VTK reads with a warning and values from the wrong bytes
            mesh = _read_with_vtk(path, mesh_type, exc)
            _check_cells(mesh, path, fmt.name)
            return mesh if dim in (None, mesh.dim) else mesh.replace(points=set_dim(np.asarray(mesh.points), dim))
        raise ReadError(
            f"could not read {str(path)!r} as {fmt.name}: {type(exc).__name__}: {exc}"
        ) from exc
    info = fmt.tidy(m)
    info = info if isinstance(info, dict) else None  # (some tidy functions return the meshio mesh they fixed)
    if len(m.points) == 0:
        raise ReadError(f"could not read {str(path)!r} as {fmt.name}: the file holds no points")
    try:
        mesh = from_meshio(m, mesh_type=mesh_type, info=info)
    except (ValueError, TypeError) as exc:
        raise ReadError(f"could not read {str(path)!r} as {fmt.name}: invalid mesh: {exc}") from exc
    _check_cells(mesh, path, fmt.name)
    if dim in (None, mesh.dim):
        return mesh
    return mesh.replace(points=set_dim(np.asarray(mesh.points), dim))


#: text formats read line by line whose writers end the file with a newline, and whose
#: readers stop at the end of the file without a word (a cut Abaqus file read as 181 of its
#: 648 tetrahedra): a last line without a newline is taken as a cut
_LINE_FORMATS = ("obj", "abaqus", "avsucd", "flac3d", "mdpa", "netgen", "off", "permas", "su2", "tecplot", "tetgen")


def _check_complete(path: Path, fmt_name: str) -> None:
    """A ReadError for a file of :data:`_LINE_FORMATS` whose last line has no newline: these
    formats have no terminator the readers check, so a file cut inside a line (``f 12 3`` of
    ``f 12 35 4``) would read as a smaller mesh or a wrong cell. A cut right after a newline is
    not seen. (PLY files are checked by :func:`warpmesh.io.ply.read_ply`.)"""
    if fmt_name in _LINE_FORMATS:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(size - 1, 0))
            last = f.read(1)
        if size and last not in (b"\n", b"\r"):
            raise ReadError(f"could not read {str(path)!r} as {fmt_name}: its last line has no newline, so it may "
                            "be cut (a truncated file?); if the file is whole, end it with a newline")


def _check_cells(mesh: MeshLike, path: Path, fmt_name: str) -> None:
    """A ReadError for points without cells: what a truncated file (OBJ, VTK, Gmsh cut after
    its vertices) reads as; warpmesh reads meshes, not point clouds."""
    if mesh.n_points and not mesh.n_cells:
        raise ReadError(f"could not read {str(path)!r} as {fmt_name}: the file holds {mesh.n_points} points "
                        "and no cells (a truncated file, or a point cloud: warpmesh reads meshes)")


def _read_with_vtk(path: Path, mesh_type, first: Exception) -> MeshLike:
    """A VTK file meshio cannot read (legacy files with 64-bit ids: 'vtktypeint64'), read
    by VTK through pyvista; the ReadError names both failures."""
    try:
        import pyvista

        from warpmesh.io.convert import from_pyvista

        data = pyvista.read(str(path))
        if data.n_points == 0:
            raise ValueError("the file holds no points")
        return from_pyvista(data, mesh_type=mesh_type)
    except Exception as exc:
        raise ReadError(f"could not read {str(path)!r} as {path.suffix[1:]}: meshio: {type(first).__name__}: "
                        f"{first}; VTK: {type(exc).__name__}: {exc}") from exc
