"""Which of meshio's other formats work here, found by trying them, not by a typed list.

:mod:`warpmesh.io.files` curates seven formats (vtu, vtk, gmsh, medit, ply, obj, stl)
with what each keeps. meshio knows about twenty more (Abaqus ``.inp``, Nastran, SU2,
XDMF, MED, Exodus, OFF, ...), but its writers and readers differ in which cell types
survive the round trip, some need packages that may be missing (h5py for XDMF, MED,
CGNS, H5M, HMF; netCDF4 for Exodus), and some do not work at all in a given meshio
release (a writer whose reader cannot read its file). So the table is measured:
:func:`format_support` writes one tiny mesh per cell type with each writer, reads it
back with the same format's reader and keeps the cell types whose points (at 17
significant digits, some in exponent notation) and connectivity come back equal, whether
cell refs (``"medit:ref"``) survive, and whether a mesh of two cell types (tetrahedra and
triangles) comes back with both.

The probe runs once per installation in a subprocess (a writer that loops cannot hang
the caller; each format gets :data:`PROBE_SECONDS`), and its result is cached on disk
in the cache folder (:func:`warpmesh._util.cache_dir.cache_root`), keyed by the versions of
meshio and of the optional packages. The extensions come from meshio's own table (``meshio.extension_to_filetypes``),
the curated formats' extensions winning.

Example
-------
>>> from warpmesh.io.formats import format_support
>>> "triangle" in format_support()["abaqus"].cells
True
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from warpmesh._util.cache_dir import cache_root, writable_cache_dir

__all__ = ["FormatSupport", "format_support", "meshio_extensions", "PROBE_CELLS", "PROBE_SECONDS"]

#: the cell types tried with every format (first and second order, every dimension)
PROBE_CELLS = ("line", "triangle", "quad", "tetra", "hexahedron", "wedge", "pyramid", "triangle6", "tetra10")
#: how long one cell type's round trip may take (tiny files: milliseconds; a reader that
#: loops is a failure); after one such failure the format's other types get 1 s
PROBE_SECONDS = 3
#: formats of meshio that are not meshes a solver reads (drawings, web viewers)
_NOT_MESHES = ("svg", "neuroglancer", "gmsh22", "vtk42", "vtk51")
#: the layout of the cached table (a new layout is probed again)
_SCHEMA = 4
#: the packages some of meshio's formats need: their versions key the cache
_OPTIONAL = ("meshio", "h5py", "netCDF4")


@dataclass(frozen=True)
class FormatSupport:
    """What one meshio format keeps in a round trip here: ``cells`` (the cell types that
    come back equal), ``refs`` (the cell-data name under which per-cell refs come back,
    None if they are lost), ``error`` (why nothing works, when ``cells`` is empty: e.g.
    a missing package), ``mixed`` (whether a mesh of tetrahedra and triangles comes back
    with both blocks)."""

    name: str
    extensions: tuple[str, ...]
    cells: tuple[str, ...]
    refs: str | None
    error: str | None = None
    #: a mesh of two cell types (tetrahedra and their boundary triangles) comes back equal
    mixed: bool = False
    #: the same for their second-order cells (tetra10 and triangle6)
    mixed_quadratic: bool = False


def meshio_extensions(exclude=()) -> dict[str, str]:
    """Extension -> meshio format name, from meshio's own table, without the extensions
    in ``exclude`` (the curated formats') nor the formats that are not solver meshes."""
    import meshio

    out = {}
    for ext, names in meshio.extension_to_filetypes.items():
        names = [n for n in names if n not in _NOT_MESHES]
        if ext in exclude or not names or ext.count(".") > 1:  # .vol.gz & co: the plain one is listed
            continue
        out[ext] = names[0]
    return out


def _versions() -> str:
    parts = []
    for name in _OPTIONAL:
        try:
            parts.append(f"{name}={importlib.metadata.version(name)}")
        except importlib.metadata.PackageNotFoundError:
            parts.append(f"{name}=none")
    return ",".join(parts)


def _cache_file() -> Path:
    root = cache_root()
    key = hashlib.sha256(f"{_SCHEMA};{_versions()};{','.join(PROBE_CELLS)}".encode()).hexdigest()[:16]
    return root / f"meshio-formats-{key}.json"


_MEMO: dict[str, FormatSupport] | None = None


def format_support(refresh: bool = False) -> dict[str, FormatSupport]:
    """The measured support of every meshio format, by meshio's name.

    Parameters
    ----------
    refresh : bool
        Probe again (else: the result of this process, then the disk cache).

    Raises
    ------
    RuntimeError
        The probe subprocess failed (its last line of error in the message).
    """
    global _MEMO
    if _MEMO is not None and not refresh:
        return _MEMO
    path = _cache_file()
    raw = None
    if not refresh and path.exists():
        try:
            raw = json.loads(path.read_text())
        except (OSError, ValueError):
            raw = None
    if raw is None:
        # once per installation (new meshio or h5py/netCDF4 versions): say why the first run waits
        print("warpmesh: measuring which file formats meshio reads and writes here, first run only "
              "(about 15 s)", file=sys.stderr, flush=True)
        run = subprocess.run([sys.executable, "-m", "warpmesh.io.formats"], capture_output=True, text=True,
                             timeout=PROBE_SECONDS * 40)
        if run.returncode != 0 or not run.stdout.strip():
            last = (run.stderr.strip().splitlines() or ["no output"])[-1]
            raise RuntimeError(f"probing meshio's formats failed: {last}")
        raw = json.loads(run.stdout.strip().splitlines()[-1])
        try:
            if writable_cache_dir() is None:  # warned once: probe again next time
                raise OSError("no cache folder")
            tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
            tmp.write_text(json.dumps(raw))
            os.replace(tmp, path)
        except OSError:  # a read-only home: probe again next time
            pass
    _MEMO = {name: FormatSupport(name, tuple(v["extensions"]), tuple(v["cells"]), v["refs"], v["error"],
                                 bool(v.get("mixed", False)), bool(v.get("mixed_quadratic", False)))
             for name, v in raw.items()}
    return _MEMO


# -- the probe (run as ``python -m warpmesh.io.formats``) -------------------------------------
def _probe_mesh(cell_type: str):
    """A tiny valid mesh of one cell type: its points, cells and refs."""
    from warpmesh.cells.reference import reference_cell

    base = {"triangle6": ("triangle", ((0, 1), (1, 2), (2, 0))),
            "tetra10": ("tetra", ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)))}  # VTK/meshio order
    linear, mids = base.get(cell_type, (cell_type, ()))
    pts = np.asarray(reference_cell(linear).vertices, dtype=np.float64)
    pts = np.column_stack([pts, np.zeros((len(pts), 3 - pts.shape[1]))]) if pts.shape[1] < 3 else pts
    pts = np.concatenate([pts, [0.5 * (pts[a] + pts[b]) for a, b in mids]]) if mids else pts
    n = len(pts)
    # two cells: the reference one and a translated copy (refs 7 and 9 tell them apart), at
    # coordinates a mesher writes: 17 significant digits, tiny ones (exponent notation)
    pts = pts * 0.7310000000000001 + [-0.2999999642372131, 4.77e-08, 1.5e-05]
    points = np.concatenate([pts, pts + [2.0, 0.5, -1.25e-06]])
    cells = np.array([np.arange(n), np.arange(n, 2 * n)])
    return points, cells, np.array([7, 9], dtype=np.int32)


def _round_trip(name: str, folder: str, label: str, points, blocks, refs):
    """meshio's write then read of ``blocks`` [(type, cells)] with ``refs`` per block: the
    mesh read back, or None when its points or blocks differ."""
    import meshio
    from meshio._helpers import reader_map

    ext = next(e for e, names in meshio.extension_to_filetypes.items() if name in names)
    path = os.path.join(folder, f"probe_{label}{ext}")
    meshio.write(path, meshio.Mesh(points, blocks, cell_data={"medit:ref": refs}), file_format=name)
    back = reader_map[name](path)
    got = sorted(((b.type, b.data) for b in back.cells if len(b.data)), key=lambda b: b[0])  # (in any order)
    want = sorted(blocks, key=lambda b: b[0])
    if len(got) != len(want) or any(t != u or not np.array_equal(c, d) for (t, c), (u, d) in zip(got, want)):
        return None
    if len(back.points) < len(points) or not np.allclose(np.asarray(back.points)[:len(points), :3], points,
                                                         rtol=1e-9, atol=1e-12):
        return None
    return back


def _probe_one(name: str, cell_type: str, folder: str) -> tuple[bool, str | None]:
    points, cells, refs = _probe_mesh(cell_type)
    back = _round_trip(name, folder, cell_type, points, [(cell_type, cells)], [refs])
    if back is None:
        return False, None
    kept = [k for k, v in back.cell_data.items() if len(v) == 1 and np.array_equal(np.ravel(v[0]), refs)]
    return True, kept[0] if kept else None


def _probe_mixed(name: str, folder: str, quadratic: bool = False) -> bool:
    """Whether tetrahedra and triangles (a volume mesh and its boundary; ``quadratic``: tetra10
    and triangle6) come back as both blocks."""
    if not quadratic:
        points, tets, refs = _probe_mesh("tetra")
        blocks = [("tetra", tets), ("triangle", tets[:, [0, 2, 1]])]  # a face of each tetrahedron
    else:  # the face (0, 1, 2) of each tetra10 with its mid-edge nodes (01, 12, 20)
        points, tets, refs = _probe_mesh("tetra10")
        blocks = [("tetra10", tets), ("triangle6", tets[:, [0, 1, 2, 4, 5, 6]])]
    label = "mixed2" if quadratic else "mixed"
    return _round_trip(name, folder, label, points, blocks, [refs, refs]) is not None


def _probe_all() -> dict:
    import contextlib
    import io
    import signal
    import warnings

    by_name: dict[str, list[str]] = {}
    for ext, name in meshio_extensions().items():  # the curated formats too (their own extensions)
        by_name.setdefault(name, []).append(ext)

    def alarm(signum, frame):
        raise TimeoutError(f"no answer in {PROBE_SECONDS} s")

    signal.signal(signal.SIGALRM, alarm)
    out = {}
    for name, exts in by_name.items():
        cells, names, error, seconds = [], set(), None, PROBE_SECONDS
        with tempfile.TemporaryDirectory() as folder:
            for cell_type in PROBE_CELLS:
                signal.alarm(seconds)
                try:
                    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
                        warnings.simplefilter("ignore")
                        ok, kept = _probe_one(name, cell_type, folder)
                except Exception as exc:  # a writer or reader that fails is what the probe measures
                    ok, kept = False, None
                    error = error or f"{type(exc).__name__}: {exc}"[:200]
                    seconds = 1 if isinstance(exc, TimeoutError) else seconds
                finally:
                    signal.alarm(0)
                if ok:
                    cells.append(cell_type)
                    names.add(kept)
            mixed = {False: False, True: False}
            for quadratic, types in ((False, {"tetra", "triangle"}), (True, {"tetra10", "triangle6"})):
                if not types <= set(cells):
                    continue
                signal.alarm(seconds)
                try:
                    with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
                        warnings.simplefilter("ignore")
                        mixed[quadratic] = _probe_mixed(name, folder, quadratic)
                except Exception:  # noqa: BLE001 -- a failing mixed round trip is what is measured
                    mixed[quadratic] = False
                finally:
                    signal.alarm(0)
        # refs count as kept when every cell type brought them back under one name
        refs = names.pop() if len(names) == 1 else None
        out[name] = {"extensions": exts, "cells": cells, "refs": refs, "mixed": mixed[False],
                     "mixed_quadratic": mixed[True],
                     "error": None if cells else (error or "no cell type comes back equal")}
    return out


if __name__ == "__main__":
    print(json.dumps(_probe_all()))
