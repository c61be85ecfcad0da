"""Image volumes in: :func:`load_volume` and the :class:`Volume` it returns.

A :class:`Volume` holds sampled values ``values[i, j, k]`` (the axis order
:func:`warpmesh.mesh_surface` meshes) and where each sample sits in the world::

    x(i, j, k) = origin + direction @ ((i, j, k) * spacing)         (= affine @ (i, j, k, 1))

``direction`` is a 3 x 3 matrix whose columns are the world directions of the axes i, j
and k (unit columns; a rotation, possibly with a reflection). This is ITK's, VTK's and
DICOM's formula, and NIfTI's affine factored into columns.

**World frame.** A volume stays in its file's own world frame; :attr:`Volume.space`
says which. ``"RAS"`` is NIfTI's scanner frame (x increases to the patient's right, y
to anterior, z to superior: "RAS+"); ``"LPS"`` is the DICOM / ITK frame (x to the left,
y to posterior, z to superior) of every file read through SimpleITK (DICOM series,
NRRD, MetaImage: ITK turns an NRRD in RAS space into LPS). ``space`` is None where the
file names no anatomical frame (VTK images, numpy files). :meth:`Volume.to_space`
converts between the two (x and y change sign), so a NIfTI file read here gives RAS
coordinates and ``.to_space("LPS")`` gives what SimpleITK would report.

Which reader for which file (each registered by :func:`_register_reader`; the readers
of medical formats are the optional extra ``pip install 'warpmesh[images]'``):

===================  ===========  ======================================================
file                 reader       what comes back
===================  ===========  ======================================================
.vti .vtk            pyvista      point data (VTK's x-fastest order as a Fortran view, no
                                  copy); cell data as samples at the cell centres;
                                  VTK's origin, spacing and direction matrix; space None
.nii .nii.gz         nibabel      a memory map of the file where it is uncompressed and
                                  unscaled; the affine (sform, else qform); space "RAS"
.nrrd .nhdr .mha     SimpleITK    a view of ITK's buffer (no copy); origin, spacing and
.mhd                              direction in LPS
DICOM folder         SimpleITK    one series (``name=`` its series ID when the folder
                                  holds several), rescaled as GDCM does; LPS
.npy .npz            numpy        .npy memory-mapped; .npz: its one 3D array or ``name=``,
                                  with optional arrays "spacing", "origin", "direction"
===================  ===========  ======================================================

Examples
--------
>>> import os, tempfile
>>> import numpy as np
>>> from warpmesh.io.images import load_volume
>>> with tempfile.TemporaryDirectory() as d:
...     np.savez(os.path.join(d, "v.npz"), values=np.zeros((4, 5, 6)), spacing=[1, 1, 2])
...     v = load_volume(os.path.join(d, "v.npz"))
>>> v.shape, v.spacing, v.affine[:3, 3].tolist()
((4, 5, 6), (1.0, 1.0, 2.0), [0.0, 0.0, 0.0])
"""

from __future__ import annotations

import dataclasses
import errno
import importlib
import logging
import os
import threading
import warnings
from collections.abc import Callable, Mapping
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Literal

import numpy as np

from warpmesh.errors import ReadError

__all__ = ["Volume", "load_volume", "as_volume", "IMAGE_FORMATS", "EXTRA"]

#: the optional extra that installs the image readers
EXTRA = "images"
Space = Literal["RAS", "LPS"]
_SPACES = ("RAS", "LPS")
_FLIP_XY = np.diag([-1.0, -1.0, 1.0])  # RAS <-> LPS


# ----------------------------------------------------------------------------- the volume
@dataclass(frozen=True, eq=False, repr=False)
class Volume:
    """Sampled values on a regular grid, placed in the world (returned by :func:`load_volume`).

    The sample ``values[i, j, k]`` sits at ``origin + direction @ ((i, j, k) * spacing)``,
    i.e. at ``affine @ (i, j, k, 1)``. :func:`warpmesh.mesh_surface` takes a Volume as its
    ``source`` and returns the mesh in these world coordinates.

    Parameters
    ----------
    values : (nx, ny, nz) array
        Kept as given (a memory map or a view of a reader's buffer stays one).
    spacing : float or 3 floats
        Positive sample spacing along i, j, k.
    origin : 3 floats
        World position of ``values[0, 0, 0]``.
    direction : (3, 3) float, optional
        Columns: the world directions of the axes i, j, k (normalised here). Default identity.
    space : {'RAS', 'LPS', None}
        The anatomical frame of the world coordinates (see the module docstring), or None.

    Raises
    ------
    ValueError, TypeError
        A field of the wrong shape, type or range, naming it.

    Examples
    --------
    >>> import numpy as np
    >>> v = Volume(np.zeros((2, 3, 4)), spacing=0.5, origin=(1, 0, 0), direction=[[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> v.world([[1, 0, 0], [0, 1, 0]]).tolist()
    [[1.0, 0.5, 0.0], [0.5, 0.0, 0.0]]
    >>> v.axis_aligned, v.replace(direction=np.eye(3)).axis_aligned
    (False, True)
    """

    values: np.ndarray
    spacing: float | tuple[float, float, float] = 1.0
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: np.ndarray | None = None
    space: Space | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        values = self.values if isinstance(self.values, np.ndarray) else np.asarray(self.values)
        if values.ndim != 3:
            raise ValueError(f"expected a 3D array for 'values', got {values.ndim}D with shape {values.shape}")
        if not (np.issubdtype(values.dtype, np.number) or values.dtype == np.bool_) or np.iscomplexobj(values):
            raise TypeError(f"expected real numbers for 'values', got dtype {values.dtype}")
        set_(self, "values", values)
        sp = np.broadcast_to(_floats(self.spacing, "spacing"), (3,)) if np.ndim(self.spacing) == 0 else \
            _floats(self.spacing, "spacing")
        if sp.shape != (3,) or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
            raise ValueError(f"expected 'spacing' as a positive number or 3 positive numbers, got {self.spacing!r}")
        set_(self, "spacing", tuple(sp.tolist()))
        org = _floats(self.origin, "origin")
        if org.shape != (3,) or not np.all(np.isfinite(org)):
            raise ValueError(f"expected 'origin' as 3 finite numbers, got {self.origin!r}")
        set_(self, "origin", tuple(org.tolist()))
        d = np.eye(3) if self.direction is None else _floats(self.direction, "direction")
        if d.shape != (3, 3) or not np.all(np.isfinite(d)):
            raise ValueError(f"expected a 3 x 3 finite matrix for 'direction', got {self.direction!r}")
        norms = np.linalg.norm(d, axis=0)
        if np.any(norms == 0) or abs(np.linalg.det(d / norms)) < 1e-6:
            raise ValueError(f"expected a non-singular 'direction' (columns: the directions of axes i, j, k), "
                             f"got {d.tolist()}")
        d = d / norms
        d.flags.writeable = False
        set_(self, "direction", d)
        if self.space not in (None, *_SPACES):
            raise ValueError(f"expected 'space' one of {[*_SPACES, None]}, got {self.space!r}")

    def __repr__(self) -> str:
        """One line: the shape and dtype, never the samples.

        >>> import numpy as np
        >>> Volume(np.zeros((2, 3, 4), dtype=np.int16), spacing=(1, 1, 2.5))
        Volume(shape=(2, 3, 4), dtype=int16, spacing=(1.0, 1.0, 2.5), origin=(0.0, 0.0, 0.0), axis_aligned=True, space=None)
        """
        return (f"Volume(shape={self.shape}, dtype={self.values.dtype}, spacing={self.spacing}, origin={self.origin}, "
                f"axis_aligned={self.axis_aligned}, space={self.space!r})")

    # -- derived ------------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int, int]:
        """``values.shape``: samples along i, j, k."""
        return self.values.shape

    @property
    def affine(self) -> np.ndarray:
        """(4, 4) float: world = affine @ (i, j, k, 1) (NIfTI's affine, in :attr:`space`)."""
        a = np.eye(4)
        a[:3, :3] = self.direction * np.asarray(self.spacing)
        a[:3, 3] = self.origin
        return a

    @property
    def axis_aligned(self) -> bool:
        """Whether ``direction`` is the identity (world = origin + (i, j, k) * spacing)."""
        return bool(np.array_equal(self.direction, np.eye(3)))

    @property
    def placement(self) -> np.ndarray:
        """(4, 4) float: world = placement @ (p, 1) for p = (i, j, k) * spacing (direction, origin)."""
        a = np.eye(4)
        a[:3, :3] = self.direction
        a[:3, 3] = self.origin
        return a

    def world(self, ijk) -> np.ndarray:
        """(n, 3) float: the world positions of (n, 3) (fractional) indices ``ijk``."""
        ijk = np.asarray(ijk, dtype=np.float64)
        return ijk * np.asarray(self.spacing) @ self.direction.T + np.asarray(self.origin)

    def replace(self, **changes) -> Volume:
        """A new volume with some fields changed (checked again)."""
        return dataclasses.replace(self, **changes)

    def to_space(self, space: Space) -> Volume:
        """The same samples with world coordinates in ``space`` ('RAS' or 'LPS'; x and y flip sign).

        >>> import numpy as np
        >>> Volume(np.zeros((2, 2, 2)), origin=(1, 2, 3), space="RAS").to_space("LPS").origin
        (-1.0, -2.0, 3.0)
        """
        if space not in _SPACES:
            raise ValueError(f"expected 'space' one of {list(_SPACES)}, got {space!r}")
        if self.space is None:
            raise ValueError("this volume's world frame is unknown (space=None): set it first with "
                             "volume.replace(space='RAS' or 'LPS')")
        if space == self.space:
            return self
        return self.replace(origin=_FLIP_XY @ np.asarray(self.origin), direction=_FLIP_XY @ self.direction,
                            space=space)

    def as_labels(self) -> Volume:
        """The volume with integer values, for ``labels=``: integer and bool values as they are,
        floats that are all whole numbers cast to the smallest integer type that holds them.

        Raises
        ------
        ValueError
            Values that are not whole numbers (a label volume must hold integers).

        >>> import numpy as np
        >>> Volume(np.array([0.0, 2.0] * 4).reshape(2, 2, 2)).as_labels().values.dtype
        dtype('uint8')
        """
        v = self.values
        if np.issubdtype(v.dtype, np.integer) or v.dtype == np.bool_:
            return self
        bad = ~np.isfinite(v) | (v != np.round(v))
        if bad.any():
            raise ValueError(f"expected whole-number label values in the volume for 'labels', got "
                             f"{float(v[bad].ravel()[0]):g} (and {int(bad.sum()) - 1} more non-integer samples); "
                             "mesh an iso-surface at a 'level' instead, or round the values")
        lo, hi = int(v.min()), int(v.max())
        dtype = np.result_type(np.min_scalar_type(lo), np.min_scalar_type(hi))
        return self.replace(values=v.astype(dtype))


def _floats(value, name: str) -> np.ndarray:
    try:
        return np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise TypeError(f"expected numbers for {name!r}, got {value!r}") from None


# ----------------------------------------------------------------------------- readers
@dataclass(frozen=True)
class _Reader:
    name: str  # as messages name the format
    read: Callable[[Path, str | None], Volume]  # (path, name) -> Volume; imports its package with _need


_READERS: dict[str, _Reader] = {}  # extension -> reader
_EXTENSIONS: dict[str, str] = {}
#: file extension -> format name, as :func:`load_volume` chooses the reader (a DICOM series is a folder)
IMAGE_FORMATS: Mapping[str, str] = MappingProxyType(_EXTENSIONS)


def _register_reader(name: str, exts: tuple[str, ...], read) -> None:
    """Make files ending in ``exts`` known to :func:`load_volume`."""
    for ext in exts:
        _READERS[ext] = _Reader(name, read)
        _EXTENSIONS[ext] = name


def _need(module: str, what: str):
    """Import an optional reader, or say which extra installs it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise ImportError(f"reading {what} needs the optional package {module.split('.')[0]!r}: "
                          f"pip install 'warpmesh[{EXTRA}]'") from exc


def _extension(path: Path) -> str:
    name = path.name.lower()
    return ".nii.gz" if name.endswith(".nii.gz") else path.suffix.lower()


def _pick(names: list[str], name: str | None, what: str, path: Path) -> str:
    """The array (or series) to read: ``name``, or the only candidate."""
    if name is not None:
        if name not in names:
            raise ValueError(f"expected 'name' one of {names} in {str(path)!r}, got {name!r}")
        return name
    if len(names) == 1:
        return names[0]
    if not names:
        raise ReadError(f"could not read {str(path)!r}: it holds no {what}")
    several = what if what.endswith("series") else what + "s"
    raise ValueError(f"{str(path)!r} holds several {several} {names}: choose one with name= (the CLI's --array)")


# -- numpy -----------------------------------------------------------------------------------------
def _read_npy(path: Path, name: str | None) -> Volume:
    if name is not None:
        raise ValueError(f"a .npy file holds one array: 'name' does not apply, got {name!r}")
    try:
        values = np.load(path, mmap_mode="r", allow_pickle=False)
    except ValueError as exc:  # not an .npy file, or one of Python objects
        raise ReadError(f"could not read {str(path)!r} as numpy: {exc}") from exc
    return Volume(_check_3d(values, path))


def _read_npz(path: Path, name: str | None) -> Volume:
    place = ("spacing", "origin", "direction")
    try:
        archive = np.load(path, allow_pickle=False)
    except ValueError as exc:
        raise ReadError(f"could not read {str(path)!r} as a numpy archive: {exc}") from exc
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise ReadError(f"could not read {str(path)!r} as a numpy archive: it holds one array (an .npy file)")
    with archive as z:
        key = _pick([k for k in z.files if k not in place], name, "array", path)
        extra = {k: z[k] for k in place if k in z.files}
        return Volume(_check_3d(z[key], path), **extra)


# -- VTK images (pyvista) ----------------------------------------------------------------------
class _KeepLogged(logging.Filter):
    """Keeps the messages logged from one thread in ``messages`` instead of passing them on."""

    def __init__(self) -> None:
        super().__init__()
        self.thread = threading.get_ident()
        self.messages: list[str] = []

    def filter(self, record: logging.LogRecord) -> bool:
        if record.thread != self.thread:
            return True
        self.messages.append(record.getMessage())
        return False


#: one quiet VTK read at a time: VTK's verbosity and the root logger's filters and handlers are
#: process-wide, and overlapping reads would leave them changed
_QUIET_READ = threading.Lock()


@contextmanager
def _quiet_vtk_read(pv):
    """VTK reads quietly meanwhile (yielded: the messages pyvista logged from this thread).

    pyvista logs each VTK read error on the root logger (a page for a file cut short), which
    also gives a root logger without handlers a stderr handler (``logging.basicConfig``) that
    then prints the application's own warnings; the messages are kept here instead, the
    handlers the read added removed, and VTK's own log turned off (where pyvista can)."""
    verbosity = getattr(pv, "vtk_verbosity", None)  # (pyvista >= 0.45)
    with _QUIET_READ, (verbosity("off") if verbosity is not None else nullcontext()):
        keep = _KeepLogged()
        root = logging.getLogger()
        handlers = list(root.handlers)
        root.addFilter(keep)
        try:
            yield keep.messages
        finally:
            root.removeFilter(keep)
            for handler in [h for h in root.handlers if h not in handlers]:
                root.removeHandler(handler)


#: how a VTK file starts: XML (``.vti``, after an optional declaration) or the legacy header (``.vtk``)
_VTK_STARTS = (b"<VTKFile", b"# vtk DataFile")


def _read_vtk(path: Path, name: str | None) -> Volume:
    import pyvista as pv

    try:
        with open(path, "rb") as f:
            head = f.read(512)
    except OSError as exc:
        raise ReadError(f"could not read {str(path)!r} as a VTK image: {exc}") from None
    body = head.lstrip().removeprefix(b"\xef\xbb\xbf").lstrip()  # (a UTF-8 byte order mark, which VTK reads past)
    if body.startswith(b"<?xml"):
        body = body[body.find(b"?>") + 2:].lstrip() if b"?>" in body else b""
    if not body.startswith(_VTK_STARTS):  # VTK's reader would print a page of errors before failing
        raise ReadError(f"could not read {str(path)!r} as a VTK image: it does not start as a VTK file "
                        f"(an XML '<VTKFile' or a legacy '# vtk DataFile' header)")
    with _quiet_vtk_read(pv) as logged, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # pyvista turns VTK's read errors into warnings (and root-log lines)
        obj = pv.read(path)
    if caught and (obj is None or obj.n_points == 0):
        reason = logged[0].strip().splitlines()[0] if logged else str(caught[0].message).strip()  # (the first error)
        raise ReadError(f"could not read {str(path)!r} as a VTK image: {reason}")
    if not isinstance(obj, pv.ImageData):
        raise ValueError(f"expected an image (ImageData) in {str(path)!r}, got a {type(obj).__name__}: "
                         "load a mesh file with warpmesh.load")
    return from_image(obj, name=name, path=path)


def from_image(image, *, name: str | None = None, path: Path | None = None) -> Volume:
    """A :class:`Volume` of a pyvista ``ImageData`` (or a ``vtkImageData``), without a copy.

    Point data (x fastest, reshaped in Fortran order: a view) gives samples at the points;
    cell data gives samples at the cell centres (origin moved by half a cell). The array is
    ``name``, else the active scalars, else the only array.

    Examples
    --------
    >>> import pyvista as pv, numpy as np
    >>> img = pv.ImageData(dimensions=(3, 4, 5), spacing=(1, 2, 3), origin=(0, 0, 1))
    >>> img.point_data["f"] = np.arange(60.0)
    >>> v = from_image(img)
    >>> int(v.values[1, 2, 3]), v.spacing, np.shares_memory(v.values, img["f"])  # sample 1 + 3 * (2 + 4 * 3)
    (43, (1.0, 2.0, 3.0), True)
    """
    import pyvista as pv

    img = image if isinstance(image, pv.DataSet) else pv.wrap(image)
    where = repr(str(path)) if path is not None else "the image"
    if not isinstance(img, pv.ImageData):
        raise TypeError(f"expected a pyvista ImageData, got {type(image).__name__}")
    point, cell = list(img.point_data.keys()), list(img.cell_data.keys())
    if name is None and img.active_scalars_name in point + cell:
        name = img.active_scalars_name
    on_cells = name in cell and name not in point if name is not None else not point
    names = cell if on_cells else point
    if name is None and not names:
        raise ReadError(f"could not read {where}: it holds no point or cell data array")
    key = _pick(names if name is None else point + cell, name, "data array", path or Path("image"))
    dims = np.asarray(img.dimensions) - (1 if on_cells else 0)
    if len(dims) != 3 or np.any(dims < 2):
        raise ValueError(f"expected a 3D image in {where}, got {'cell' if on_cells else 'point'} dimensions "
                         f"{tuple(dims.tolist())} (a 2D image or a single slice)")
    data = (img.cell_data if on_cells else img.point_data)[key]
    if data.ndim != 1:
        raise ValueError(f"expected a scalar array {key!r} in {where}, got {data.shape[1]} components per sample")
    values = np.asarray(data).reshape(tuple(dims.tolist()), order="F")  # x fastest: a view
    direction = np.asarray(getattr(img, "direction_matrix", np.eye(3)), dtype=np.float64)
    spacing = np.asarray(img.spacing, dtype=np.float64)
    origin = np.asarray(img.origin, dtype=np.float64)
    if on_cells:
        origin = origin + direction @ (spacing / 2)
    return Volume(values, spacing=spacing, origin=origin, direction=direction)


# -- NIfTI (nibabel) -------------------------------------------------------------------------------
def _read_nifti(path: Path, name: str | None) -> Volume:
    nib = _need("nibabel", "NIfTI files")
    if name is not None:
        raise ValueError(f"a NIfTI file holds one image: 'name' does not apply, got {name!r}")
    try:
        img = nib.load(path)
        shape = img.shape
    except Exception as exc:  # nibabel raises ImageFileError, EOFError, gzip errors, ...
        raise ReadError(f"could not read {str(path)!r} as NIfTI: {type(exc).__name__}: {exc}") from exc
    while len(shape) > 3 and shape[-1] == 1:  # (x, y, z, 1): one frame
        shape = shape[:-1]
    _check_dims(shape, path)
    values = np.asanyarray(img.dataobj)  # a memory map where the file allows it
    values = values.reshape(shape) if values.shape != shape else values
    a = np.asarray(img.affine, dtype=np.float64)
    spacing = np.linalg.norm(a[:3, :3], axis=0)
    return Volume(values, spacing=spacing, origin=a[:3, 3], direction=a[:3, :3] / spacing, space="RAS")


# -- ITK formats and DICOM (SimpleITK) ---------------------------------------------------------------
class _Keep:
    """Exposes an array's buffer and holds the object that owns it (a SimpleITK image):
    ``np.asarray(_Keep(view, image))`` is the view, alive as long as the array is."""

    def __init__(self, view: np.ndarray, owner):
        self.__array_interface__ = view.__array_interface__
        self._view, self._owner = view, owner


def _from_sitk(sitk, img, path: Path) -> Volume:
    if img.GetNumberOfComponentsPerPixel() != 1:
        raise ValueError(f"expected scalar samples in {str(path)!r}, got "
                         f"{img.GetNumberOfComponentsPerPixel()} components per pixel")
    _check_dims(img.GetSize(), path)
    view = sitk.GetArrayViewFromImage(img)  # (k, j, i), ITK's buffer: valid while img lives
    values = np.asarray(_Keep(view, img)).T  # (i, j, k), still no copy
    direction = np.asarray(img.GetDirection(), dtype=np.float64).reshape(3, 3)  # row-major, columns = axes
    return Volume(values, spacing=img.GetSpacing(), origin=img.GetOrigin(), direction=direction, space="LPS")


def _read_itk(path: Path, name: str | None) -> Volume:
    sitk = _need("SimpleITK", f"{_extension(path)} files")
    if name is not None:
        raise ValueError(f"a {_extension(path)} file holds one image: 'name' does not apply, got {name!r}")
    try:
        img = sitk.ReadImage(str(path))
    except RuntimeError as exc:
        raise ReadError(f"could not read {str(path)!r} as {_READERS[_extension(path)].name}: "
                        f"{str(exc).strip().splitlines()[-1]}") from exc
    return _from_sitk(sitk, img, path)


def _read_dicom(path: Path, name: str | None) -> Volume:
    sitk = _need("SimpleITK", "DICOM series")
    ids = list(sitk.ImageSeriesReader.GetGDCMSeriesIDs(str(path)))
    if not ids:
        raise ReadError(f"could not read the folder {str(path)!r} as a DICOM series: no DICOM series in it")
    series = _pick(ids, name, "DICOM series", path)
    reader = sitk.ImageSeriesReader()
    reader.SetFileNames(sitk.ImageSeriesReader.GetGDCMSeriesFileNames(str(path), series))
    try:
        img = reader.Execute()
    except RuntimeError as exc:
        raise ReadError(f"could not read the DICOM series {series!r} in {str(path)!r}: "
                        f"{str(exc).strip().splitlines()[-1]}") from exc
    return _from_sitk(sitk, img, path)


def _check_dims(shape, path: Path) -> None:
    if len(shape) != 3 or min(shape) < 2:
        raise ValueError(f"expected a 3D image in {str(path)!r}, got {len(shape)}D with shape {tuple(shape)}"
                         + (" (a 2D image or a single slice)" if len(shape) < 3 or min(shape) < 2 else ""))


def _check_3d(values: np.ndarray, path: Path) -> np.ndarray:
    _check_dims(values.shape, path)
    return values


_register_reader("VTK image", (".vti", ".vtk"), _read_vtk)
_register_reader("NIfTI", (".nii", ".nii.gz"), _read_nifti)
_register_reader("NRRD", (".nrrd", ".nhdr"), _read_itk)
_register_reader("MetaImage", (".mha", ".mhd"), _read_itk)
_register_reader("numpy", (".npy",), _read_npy)
_register_reader("numpy archive", (".npz",), _read_npz)


# ----------------------------------------------------------------------------- public entry
def load_volume(path, *, name: str | None = None) -> Volume:
    """Read a 3D image: VTK (.vti, .vtk), NIfTI (.nii, .nii.gz), NRRD (.nrrd, .nhdr),
    MetaImage (.mha, .mhd), a DICOM series folder, or numpy (.npy, .npz).

    The values come back in the order :func:`warpmesh.mesh_surface` meshes
    (``values[i, j, k]`` at ``origin + direction @ ((i, j, k) * spacing)``), without a copy
    where the format allows it (see the module docstring for each format, and for the
    world frame: the file's own, RAS for NIfTI, LPS for what SimpleITK reads).

    Parameters
    ----------
    path : str or os.PathLike
        An image file, or a folder holding a DICOM series.
    name : str, optional
        Which array (VTK point or cell array, .npz key) or DICOM series ID to read when the
        file holds several.

    Returns
    -------
    Volume

    Raises
    ------
    FileNotFoundError
        ``path`` does not exist.
    ValueError
        An extension no reader knows, an image that is not 3D (2D, one slice, 4D) or not
        scalar, a missing or ambiguous ``name``.
    ReadError
        The file exists but cannot be parsed (a ``ValueError`` too).
    ImportError
        The reader of the format is not installed; the message names the extra.

    Examples
    --------
    >>> import os, tempfile
    >>> import numpy as np, pyvista as pv
    >>> img = pv.ImageData(dimensions=(4, 5, 6), spacing=(0.5, 0.5, 1.0), origin=(1, 2, 3))
    >>> img.point_data["ct"] = np.arange(120, dtype=np.int16)
    >>> with tempfile.TemporaryDirectory() as d:
    ...     img.save(os.path.join(d, "ct.vti"))
    ...     v = load_volume(os.path.join(d, "ct.vti"))
    >>> v.shape, v.spacing, v.origin, int(v.values[1, 0, 0])
    ((4, 5, 6), (0.5, 0.5, 1.0), (1.0, 2.0, 3.0), 1)
    >>> load_volume("no/such/ct.nii")
    Traceback (most recent call last):
    ...
    FileNotFoundError: [Errno 2] no such image file or DICOM folder: 'no/such/ct.nii'
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"expected a file name (str or os.PathLike) for 'path', got {type(path).__name__}")
    path = Path(path)
    if name is not None and not isinstance(name, str):
        raise TypeError(f"expected a str for 'name', got {type(name).__name__}")
    if not path.exists():
        raise FileNotFoundError(errno.ENOENT, "no such image file or DICOM folder", str(path))
    if path.is_dir():
        return _read_dicom(path, name)
    ext = _extension(path)
    if ext == ".dcm":
        raise ValueError(f"expected for 'path' the folder holding the DICOM series, got the file {str(path)!r}: "
                         f"pass {str(path.parent)!r}")
    if ext not in _READERS:
        raise ValueError(f"expected for 'path' an image file or a DICOM folder, got {str(path)!r} with the unknown "
                         f"extension {ext!r}; known: "
                         f"{list(IMAGE_FORMATS)}")
    reader = _READERS[ext]
    try:
        return reader.read(path, name)
    except (ReadError, ValueError, TypeError, ImportError, MemoryError):
        raise
    except Exception as exc:  # a parser's own failure (zip, XML, VTK, ...): name the file and format
        raise ReadError(f"could not read {str(path)!r} as {reader.name}: {type(exc).__name__}: {exc}") from exc


def as_volume(source) -> Volume | None:
    """``source`` as a :class:`Volume` if it is one, an image path or a pyvista image; else None.

    What :func:`warpmesh.mesh_surface` calls on its ``source``: arrays and shapes give None.

    >>> import numpy as np
    >>> as_volume(np.zeros((2, 2, 2))) is None, type(as_volume(Volume(np.zeros((2, 2, 2))))).__name__
    (True, 'Volume')
    """
    if isinstance(source, Volume):
        return source
    if isinstance(source, (str, os.PathLike)):
        return load_volume(source)
    module = type(source).__module__ or ""
    if module.startswith(("pyvista", "vtkmodules")) and any(c.__name__.endswith("ImageData") for c in type(source).__mro__):
        return from_image(source)
    return None
