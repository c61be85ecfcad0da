"""Meshes for bench_renumber.py: 2D plates, warpmesh's own surfaces, the frog segmentation,
TetGen tetrahedra inside those surfaces, a random node permutation, and an optional
on-disk cache keyed by the generator's parameters.

``plate`` and ``shuffled`` are the test suite's own (tests/numbering_meshes.py), so the
benchmark measures the meshes the tests check.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import warnings

import sys

import numpy as np

import warpmesh as wm

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))  # the project root: tests.helpers
from tests.helpers.numbering_meshes import plate, shuffled  # noqa: E402,F401  (re-exported for bench_renumber)

SPHERE_BOUNDS = ((-1.2,) * 3, (1.2,) * 3)
#: bump when a generator changes, so that cached meshes of the old one are not reused
CACHE_VERSION = 1


def shape_surface(shape_name: str, resolution: int, method: str | None = None) -> wm.Mesh:
    """warpmesh's surface of ``wm.example(shape_name)`` ("sphere": ``wm.sphere(1.0)`` on
    [-1.2, 1.2]^3) at ``resolution``, the library's default method unless given."""
    if shape_name == "sphere":
        shape, bounds = wm.sphere(1.0), SPHERE_BOUNDS
    else:
        shape, bounds = wm.example(shape_name)
    kw = {} if method is None else {"method": method}
    return wm.mesh_surface(shape, bounds=bounds, resolution=resolution, **kw)


def frog_surface(label, method: str | None = None) -> tuple[wm.Mesh, dict]:
    """The frog segmentation's surface: one label (int; its bounding box plus 2 samples, as
    bench_optimize.load_frog) or every tissue label ("all"; the whole volume,
    ``labels="all"``: each label closed on its own, interfaces once per label)."""
    from bench_optimize import FROG_FILE, load_frog

    kw = {} if method is None else {"method": method}
    if label == "all":
        import pyvista as pv

        img = pv.read(FROG_FILE)
        nx, ny, nz = img.dimensions
        vol = np.asarray(img.point_data[img.point_data.keys()[0]]).reshape((nx, ny, nz), order="F")
        spacing, origin = tuple(float(s) for s in img.spacing), tuple(float(o) for o in img.origin)
        info = {"dims": (nx, ny, nz), "spacing": spacing, "labels": "all (every value but 0)"}
        return wm.mesh_surface(np.ascontiguousarray(vol), labels="all", spacing=spacing, origin=origin, **kw), info
    vol, spacing, origin, info = load_frog(int(label))
    return wm.mesh_surface(vol, labels=[int(label)], spacing=spacing, origin=origin, **kw), info


def tetrahedralize(surface: wm.Mesh, **options) -> wm.Mesh:
    """TetGen tetrahedra inside a closed triangle surface:
    ``tetgen.TetGen(surface.to_pyvista()).tetrahedralize(order=1, quiet=True, **options)``."""
    import tetgen

    with warnings.catch_warnings():  # tetgen 0.8 calls a pyvista attribute deprecated in 0.49
        warnings.simplefilter("ignore")
        nodes, elems = tetgen.TetGen(surface.to_pyvista()).tetrahedralize(order=1, quiet=True, **options)[:2]
    return wm.Mesh(np.asarray(nodes, np.float64), {"tetra": np.asarray(elems, np.int64)})


# --------------------------------------------------------------------------------- cache
def cache_key(params: dict) -> str:
    text = json.dumps({"version": CACHE_VERSION, **params}, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def cached(cache_dir: str | None, params: dict, build) -> tuple[wm.Mesh, dict, bool]:
    """``build()`` -> (Mesh, info dict), stored as ``<cache_dir>/<key>.npz`` (points and cell
    blocks) + ``.json`` (params and info) when ``cache_dir`` is given, and read back from
    there on later runs. Returns (mesh, info, from_cache); a missing or unreadable cache
    file just means building again."""
    path = None
    if cache_dir:
        os.makedirs(cache_dir, exist_ok=True)
        path = os.path.join(cache_dir, cache_key(params))
        try:
            with np.load(path + ".npz") as z, open(path + ".json") as fh:
                meta = json.load(fh)
                cells = {k[len("cells_"):]: z[k] for k in z.files if k.startswith("cells_")}
                return wm.Mesh(z["points"], cells), meta["info"], True
        except (OSError, ValueError, KeyError):
            pass
    t0 = time.perf_counter()
    mesh, info = build()
    info = {**info, "build_s": time.perf_counter() - t0}
    if path:
        tmp = path + ".tmp.npz"
        np.savez(tmp, points=np.asarray(mesh.points), **{f"cells_{t}": np.asarray(c) for t, c in mesh.cells.items()})
        os.replace(tmp, path + ".npz")
        with open(path + ".json.tmp", "w") as fh:
            json.dump({"params": params, "info": info}, fh, indent=1, default=str)
        os.replace(path + ".json.tmp", path + ".json")
    return mesh, info, False
