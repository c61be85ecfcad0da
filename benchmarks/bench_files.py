"""``.vtu`` and Medit ``.mesh`` files written and read by warpmesh, meshio and VTK, the same
mesh in one run.

Writers: warpmesh (``Mesh.save``: :mod:`warpmesh.io.vtu`, zlib level 1 on every core,
inline base64), meshio (``meshio.write``, zlib at its default level, inline base64) and
VTK (``vtkXMLUnstructuredGridWriter``, appended raw data with zlib: ParaView's default
layout). Readers: warpmesh (``wm.load``: :func:`warpmesh.io.vtu.read_vtu`, then the Mesh),
meshio (``meshio.read``) and VTK (``pyvista.read``), each on each file. Every row is the
median of ``--repeat`` runs after one untimed run; the ratio is tool / warpmesh (> 1:
warpmesh faster). Each file read back is checked equal to the mesh written. Medit
(``--formats vtu,mesh``): warpmesh (:mod:`warpmesh.io.medit`: meshio's bytes by numpy digit
arithmetic; read with the integer rows parsed by a Warp kernel) against meshio.

Run:  python benchmarks/bench_files.py [--resolution 512] [--repeat 3] [--frog] [--formats vtu,mesh]
      [--json out.json]
``--frog`` uses the graded frog of ``bench_regions.py`` (all labels, 4 voxels: 4.4 M points,
12.7 M tetrahedra, 7.7 M triangles; about 45 s to make) instead of the part's surface;
meshio reads VTK's appended file of it in about 5 minutes, so that row is run once.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(__file__))
from _report import finish, keep_freed_memory, load_banner, median_run, version  # noqa: E402

keep_freed_memory()

import numpy as np  # noqa: E402


def make_mesh(resolution: int, frog: bool):
    import warpmesh as wm

    if frog:
        import pyvista as pv

        path = os.path.join(os.path.dirname(pv.__file__), "examples", "frog_tissues.vti")
        if not os.path.exists(path):
            path = pv.examples.download_frog_tissues(load=False)
        image = wm.load_volume(path)
        return "frog, all labels, 4 voxels", wm.mesh_domain(image, labels="all", size=4.0 * min(image.spacing))
    shape, bounds = wm.example("part")
    return f"part surface at {resolution}", wm.mesh_surface(shape, bounds=bounds, resolution=resolution)


def medit_writers(mesh, refs):
    import meshio

    def by_warpmesh(path):
        mesh.save(path)

    def by_meshio(path):
        meshio.write(path, meshio.Mesh(mesh.points, list(mesh.cells.items()), cell_data={"medit:ref": refs}),
                     file_format="medit")

    return {"warpmesh": by_warpmesh, "meshio": by_meshio}


def medit_readers():
    import meshio

    import warpmesh as wm

    return {"warpmesh": lambda p: wm.load(p), "meshio": lambda p: meshio.read(p, file_format="medit")}


def writers(mesh, refs):
    import meshio
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    from warpmesh.io.convert import to_pyvista

    def by_warpmesh(path):
        mesh.save(path)

    def by_meshio(path):
        meshio.write(path, meshio.Mesh(mesh.points, list(mesh.cells.items()), cell_data={"medit:ref": refs}),
                     file_format="vtu", binary=True)

    grid = to_pyvista(mesh)
    grid = grid if grid.GetDataObjectType() == 4 else grid.cast_to_unstructured_grid()  # 4: VTK_UNSTRUCTURED_GRID

    def by_vtk(path):
        w = vtkXMLUnstructuredGridWriter()
        w.SetFileName(path)
        w.SetInputData(grid)
        w.SetDataModeToAppended()
        w.SetEncodeAppendedData(False)
        w.SetCompressorTypeToZLib()
        if w.Write() != 1:
            raise RuntimeError(f"VTK could not write {path}")

    return {"warpmesh": by_warpmesh, "meshio": by_meshio, "VTK": by_vtk}


def readers():
    import meshio
    import pyvista as pv

    import warpmesh as wm

    return {"warpmesh": lambda p: wm.load(p), "meshio": lambda p: meshio.read(p), "VTK": lambda p: pv.read(p)}


def check(tool: str, back, mesh) -> None:
    """The mesh read back has the points and cells written (each reader's own type)."""
    if tool == "warpmesh":
        points, cells = back.points, dict(back.cells)
    elif tool == "meshio":
        points, cells = back.points, {c.type: c.data for c in back.cells}
    else:
        points, cells = back.points, {t: back.cells_dict[v] for t, v in (("tetra", 10), ("triangle", 5))
                                      if v in back.cells_dict}
    assert np.array_equal(points, mesh.points), tool
    for t, c in mesh.cells.items():
        assert np.array_equal(cells[t], c), (tool, t)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--resolution", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--frog", action="store_true")
    ap.add_argument("--formats", default="vtu,mesh", help="comma-separated: vtu, mesh")
    ap.add_argument("--default-malloc", action="store_true", help="glibc's default allocator setting")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    load0 = load_banner(f"bench_files: meshio {version('meshio')}, VTK (pyvista {version('pyvista')})")
    name, mesh = make_mesh(args.resolution, args.frog)
    refs = [np.asarray(mesh.cell_refs[t]) if mesh.cell_refs and t in mesh.cell_refs else np.zeros(len(c), np.int64)
            for t, c in mesh.cells.items()]
    print(f"{name}: {mesh.n_points} points, " + ", ".join(f"{len(c)} {t}" for t, c in mesh.cells.items()))
    rows = {}
    kinds = {"vtu": (writers, readers), "mesh": (medit_writers, medit_readers)}
    for ext in args.formats.split(","):
        if ext not in kinds:
            raise SystemExit(f"unknown format {ext!r} in --formats: pick from {sorted(kinds)}")
        make_writers, make_readers = kinds[ext]
        with tempfile.TemporaryDirectory() as tmp:
            files = {}
            for tool, write in make_writers(mesh, refs).items():
                path = os.path.join(tmp, f"{tool}.{ext}")
                wall, cpu, _ = median_run(lambda: write(path), args.repeat)
                files[tool] = path
                rows[f"{ext}: write {tool}"] = {"wall_s": wall, "cpu_s": cpu, "mb": os.path.getsize(path) / 1e6}
            for writer, path in files.items():
                for tool, read in make_readers().items():
                    if args.frog and tool == "meshio" and writer == "VTK":  # minutes: one run
                        w0, c0 = time.perf_counter(), time.process_time()
                        back = read(path)
                        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
                    else:
                        wall, cpu, back = median_run(lambda: read(path), args.repeat)
                    check(tool, back, mesh)
                    rows[f"{ext}: read {writer}'s file, {tool}"] = {"wall_s": wall, "cpu_s": cpu}
                    del back
    for key, r in rows.items():
        ext = key.split(":")[0]
        base = rows[(key.rsplit(",", 1)[0] + ", warpmesh") if ": read" in key else f"{ext}: write warpmesh"]["wall_s"]
        size = f", {r['mb']:.0f} MB" if "mb" in r else ""
        print(f"{key:40s} {r['wall_s']:8.2f} s (CPU {r['cpu_s']:.2f} s){size}  {r['wall_s'] / base:6.2f}x warpmesh's")
    finish(t_start, load0, args.json, {"mesh": name, "rows": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
