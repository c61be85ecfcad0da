#!/usr/bin/env python3
"""Large volumes for bench_surface.py: the inputs, the tools, and one measurement per process.

Section (d) of the benchmark meshes volumes of tens of millions of samples and reports,
for every tool, its wall time and its *peak extra memory over the input*. Each
measurement runs in a fresh interpreter (:func:`measure` starts this file with
``--worker``) so that no tool inherits another's heap:

1. import the tool and call it once on a small volume of the same kind (loads Warp's
   cached kernels, VTK's and scikit-image's code paths);
2. load the volume from an ``.npy`` file (no temporaries: the input alone);
3. reset the peak-RSS counter (``echo 5 > /proc/self/clear_refs``) and read the
   resident size: the baseline;
4. call the tool once; peak extra memory = ``VmHWM`` after the call - baseline (the
   output is alive at that point, so it counts);
5. switch glibc to keeping freed memory in the heap (as the parent benchmark does),
   call the tool once more untimed, then ``repeat`` times for the wall time (median).

Steps 2-4 run with glibc's ``MALLOC_MMAP_THRESHOLD_=131072`` (fixed, so not raised
dynamically): every block of 128 KiB or more is its own mapping, returned to the system
when freed, so the resident size tracks the memory actually in use (keeping freed memory
in the heap would hide a tool's temporaries behind pages already resident). The timed
calls of step 5 run like the rest of the benchmark instead: in this VM a freshly mapped
page costs up to ~2 ms/MB, which would make the times depend on how much each tool
allocates anew per call and on the host, not only on its algorithm.

Inputs, in voxel units (spacing 1, origin 0), nothing touching the boundary so every
tool's surface is closed:

``scalar``  float32: a gyroid sheet (6 periods across the box, ``0.5 - |G|``) clipped to
            a union of five Gaussian blobs (``B - 0.5``): ``min(B - 0.5, 0.5 - |G|)``,
            iso-level 0. A porous, scaffold-like surface of ~1.4 M triangles at 320^3.
``labels``  uint8, 4 labels: 1 a ball, 2 a box cutting into it (a shared interface),
            3 a torus, 4 a small ball inside the first (nested).
"""

from __future__ import annotations

import gc
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

RESULT_TAG = "@@bench-result "
WORKER_ENV = {"MALLOC_MMAP_THRESHOLD_": "131072"}
DROP_ENV = ("MALLOC_TRIM_THRESHOLD_",)


# =============================================================================================
# the inputs
# =============================================================================================
_BLOBS = [((0.38, 0.45, 0.50), 0.16, 1.0), ((0.62, 0.55, 0.45), 0.15, 1.0), ((0.50, 0.35, 0.65), 0.12, 0.9),
          ((0.50, 0.66, 0.36), 0.12, 0.9), ((0.45, 0.58, 0.62), 0.11, 0.8)]


def scalar_volume(n: int, chunk: int = 16) -> np.ndarray:
    """(n, n, n) float32: min(blobs - 0.5, 0.5 - |gyroid|), built a few planes at a time."""
    u = np.linspace(0.0, 1.0, n)
    y, z = u[None, :, None], u[None, None, :]
    k = 2.0 * np.pi * 6.0
    vol = np.empty((n, n, n), dtype=np.float32)
    for a in range(0, n, chunk):
        x = u[a:a + chunk, None, None]
        b = np.zeros((x.shape[0], n, n))
        for (cx, cy, cz), s, w in _BLOBS:
            b += w * np.exp(-((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / (2.0 * s * s))
        g = np.sin(k * x) * np.cos(k * y) + np.sin(k * y) * np.cos(k * z) + np.sin(k * z) * np.cos(k * x)
        vol[a:a + chunk] = np.minimum(b - 0.5, 0.5 - np.abs(g))
    return vol


def label_volume(n: int, chunk: int = 16) -> np.ndarray:
    """(n, n, n) uint8 with labels 1-4 (0 = background), built a few planes at a time."""
    u = np.linspace(0.0, 1.0, n)
    y, z = u[None, :, None], u[None, None, :]
    vol = np.zeros((n, n, n), dtype=np.uint8)
    for a in range(0, n, chunk):
        x = u[a:a + chunk, None, None]
        part = np.zeros((x.shape[0], n, n), dtype=np.uint8)
        part[(x - 0.40) ** 2 + (y - 0.50) ** 2 + (z - 0.45) ** 2 < 0.25 ** 2] = 1
        part[(np.abs(x - 0.68) < 0.16) & (np.abs(y - 0.50) < 0.18) & (np.abs(z - 0.45) < 0.14)] = 2
        ring = np.sqrt((x - 0.50) ** 2 + (y - 0.50) ** 2) - 0.22
        part[ring ** 2 + (z - 0.84) ** 2 < 0.06 ** 2] = 3
        part[(x - 0.33) ** 2 + (y - 0.50) ** 2 + (z - 0.45) ** 2 < 0.08 ** 2] = 4
        vol[a:a + chunk] = part
    return vol


BUILDERS = {"scalar": scalar_volume, "labels": label_volume}


# =============================================================================================
# the tools: each returns a list of (points, faces) arrays (one pair per label for the
# per-label peers) and a dict of extra information
# =============================================================================================
def _labels_of(vol):
    values = np.unique(vol)
    return values[values != 0]


def _image(shape):
    import pyvista as pv

    # a C-order (x, y, z) array is an x-fastest VTK image of axes (z, y, x): no copy
    return pv.ImageData(dimensions=shape[::-1])


def run_warpmesh(vol, spec):
    import warpmesh as wm

    kw = {"labels": "all"} if spec["kind"] == "labels" else {"level": 0.0}
    m = wm.mesh_surface(vol, method=spec.get("method", "mc"), slab_voxels=spec.get("slab_voxels"),
                        device="cpu", **kw)
    info = {"slabs": m.info.get("slabs"), "stages_s": {k: v for k, v in m.info["time"].items() if k != "total"},
            "extra_output_bytes": sum(r.nbytes for r in (m.cell_refs or {}).values())}
    return [(m.points, m.cells["triangle"])], info


def run_skimage(vol, spec):
    from skimage.measure import marching_cubes

    if spec["kind"] == "scalar":
        verts, faces, _n, _v = marching_cubes(vol, level=0.0, method="lewiner")
        return [(verts, faces)], {}
    out = []
    for label in _labels_of(vol):  # the boolean indicator; scikit-image makes its float32 copy
        verts, faces, _n, _v = marching_cubes(vol == label, level=0.5, method="lewiner")
        out.append((verts, faces))
    return out, {}


def run_vtk_flying_edges(vol, spec):
    img = _image(vol.shape)
    if spec["kind"] == "scalar":
        img.point_data["f"] = vol.reshape(-1)
        surf = img.contour([0.0], scalars="f", method="flying_edges", compute_scalars=False)
        return [(surf.points, surf.regular_faces)], {}
    out = []
    for label in _labels_of(vol):  # per label, on a float32 indicator
        img.point_data["f"] = (vol == label).astype(np.float32).reshape(-1)
        surf = img.contour([0.5], scalars="f", method="flying_edges", compute_scalars=False)
        out.append((surf.points, surf.regular_faces))
        img.point_data.remove("f")
    return out, {}


def run_vtk_discrete_flying_edges(vol, spec):
    """vtkDiscreteFlyingEdges3D on the label image itself, every label in one pass (pyvista
    does not wrap it: its contour_labels is surface nets)."""
    import pyvista as pv
    import vtk

    img = _image(vol.shape)
    img.point_data["labels"] = vol.reshape(-1)
    alg = vtk.vtkDiscreteFlyingEdges3D()
    alg.SetInputData(img)
    alg.SetInputArrayToProcess(0, 0, 0, vtk.vtkDataObject.FIELD_ASSOCIATION_POINTS, "labels")
    for i, label in enumerate(_labels_of(vol)):
        alg.SetValue(i, int(label))
    alg.ComputeNormalsOff()
    alg.ComputeGradientsOff()
    alg.ComputeScalarsOff()
    alg.Update()
    surf = pv.wrap(alg.GetOutput())
    return [(surf.points, surf.regular_faces)], {}


TOOLS = {"warpmesh": run_warpmesh, "skimage": run_skimage, "vtk-fe": run_vtk_flying_edges,
         "vtk-dfe": run_vtk_discrete_flying_edges}


# =============================================================================================
# the worker
# =============================================================================================
def _status_kb(field: str) -> int | None:
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


def _reset_peak() -> bool:
    """Set VmHWM to the current resident size (Linux >= 4.0); False where not allowed."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def _peak_kb() -> int:
    hwm = _status_kb("VmHWM")
    if hwm is None:
        import resource

        hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # kB on Linux
    return hwm


def _keep_freed_memory() -> bool:
    """glibc: serve blocks up to 1 GiB from the heap and never trim it (what the parent's
    MALLOC_MMAP_THRESHOLD_ / MALLOC_TRIM_THRESHOLD_ do), from now on."""
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3
        return bool(libc.mallopt(m_mmap_threshold, 1 << 30)) and bool(libc.mallopt(m_trim_threshold, 2 ** 31 - 1))
    except (OSError, AttributeError):
        return False


def _open_edges(meshes) -> int:
    """Edges not in exactly two triangles over all (points, faces) parts (vertex ids offset per part)."""
    keys, offset = [], 0
    for points, faces in meshes:
        f = np.asarray(faces, dtype=np.int64).reshape(-1, 3) + offset
        e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        keys.append(e[:, 0] * (1 << 32) + e[:, 1])
        offset += len(points)
    if not keys:
        return 0
    _, counts = np.unique(np.concatenate(keys), return_counts=True)
    return int(np.count_nonzero(counts != 2))


def worker(spec: dict) -> dict:
    """One measurement (see the module docstring); returns a JSON-able dict."""
    import warnings

    warnings.filterwarnings("ignore", category=DeprecationWarning)
    if spec["tool"] == "warpmesh":
        import warp as wp

        wp.config.log_level = wp.LOG_WARNING
        wp.init()
    if spec["tool"].startswith("vtk"):
        import vtk

        vtk.vtkSMPTools().SetBackend(spec.get("vtk_backend", "STDThread"))
    run = TOOLS[spec["tool"]]
    try:
        run(BUILDERS[spec["kind"]](40), spec)  # warm-up on a small volume of the same kind
    except ImportError:  # ModuleNotFoundError included: e.g. a warpmesh method not in this build
        return {"tool": spec["tool"], "error": f"{spec.get('method', spec['tool'])}: not available in this build"}
    gc.collect()
    vol = np.load(spec["path"])
    gc.collect()
    reset = _reset_peak()
    base_kb = _status_kb("VmRSS") if reset else _peak_kb()
    t0 = time.perf_counter()
    out, info = run(vol, spec)
    t_first = time.perf_counter() - t0
    peak_kb = _peak_kb() - base_kb
    out_bytes = sum(np.asarray(a).nbytes for pair in out for a in pair) + info.pop("extra_output_bytes", 0)
    triangles = sum(len(f) for _, f in out)
    vertices = sum(len(p) for p, _ in out)
    del out
    kept = _keep_freed_memory() if spec.get("keep_freed", True) else False
    out, _ = run(vol, spec)  # untimed: fills the heap that the timed calls reuse
    times = []
    for _ in range(spec["repeat"]):
        del out
        gc.collect()
        t0 = time.perf_counter()
        out, _ = run(vol, spec)
        times.append(time.perf_counter() - t0)
    open_edges = _open_edges(out)
    return {"tool": spec["tool"], "time_s": statistics.median(times), "first_call_s": t_first,
            "wall_samples_s": times, "timed_with_freed_memory_kept": kept, "peak_extra_mb": peak_kb / 1024.0,
            "peak_reset": reset,
            "output_mb": out_bytes / 2 ** 20, "input_mb": vol.nbytes / 2 ** 20, "triangles": int(triangles),
            "vertices": int(vertices), "parts": len(out), "open_edges": open_edges,
            "closed": bool(open_edges == 0 and triangles > 0), **info}


def measure(spec: dict, timeout: float = 900.0) -> dict:
    """Run one measurement in a fresh interpreter; the result dict, or {'error': ...}."""
    env = {k: v for k, v in os.environ.items() if k not in DROP_ENV}
    env.update(WORKER_ENV)
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", json.dumps(spec)]
    try:
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"error": f"failed: timed out after {timeout:.0f} s"}
    for line in reversed(proc.stdout.splitlines()):
        if line.startswith(RESULT_TAG):
            return json.loads(line[len(RESULT_TAG):])
    tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
    return {"error": f"failed: worker exited with status {proc.returncode}: {tail[:160]}"}


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] != "--worker":
        sys.exit(f"usage: {sys.argv[0]} --worker SPEC_JSON   (started by bench_surface.py)")
    print(RESULT_TAG + json.dumps(worker(json.loads(sys.argv[2]))), flush=True)
