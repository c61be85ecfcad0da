"""Raw surfaces as a tetrahedral mesher sees them: quality, crossings, and whether TetGen
and gmsh accept them, with the node clearance (the default) and without it.

Usage::

    python benchmarks/bench_validity.py                       # about 3 min on 2 cores
    python benchmarks/bench_validity.py --resolutions 64 --no-gmsh
    python benchmarks/bench_validity.py --json results.json

For the bundled part at its own bounds and each resolution (default 64, 96, 128), and
each ``clearance`` (0: the old placement, clamped to 1e-3 of the edge; 0.05: the
default), prints the triangle count, worst Q_K [FG eq. 16.15], smallest angle, longest /
shortest edge ratio, the faces that cross another one (warpmesh's check and, when
installed, pymeshlab's), and the result of TetGen (``mindihedral=10, minratio=1.5``) and
gmsh (merge + surface loop + ``generate(3)``), each in a subprocess (a crash is a result,
not the end of the run): the number of tetrahedra, or the last line of the error.

``--labels`` adds the two segmentations pyvista ships (``frog_tissues``, ``channels``; no
download): every label meshed with mc33 at once (``labels="all"``), then per label its
closed surface checked: crossing faces by warpmesh and by pymeshlab, which must agree.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

from _report import finish, keep_freed_memory, load_banner, version

keep_freed_memory()

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import warpmesh as wm  # noqa: E402
from warpmesh.cells.intersections import count_self_intersecting_faces  # noqa: E402
from warpmesh.cells.quality import triangle_angles, triangle_quality  # noqa: E402
from tests.helpers.mesher_clients import GMSH, TETGEN, run_client  # noqa: E402

def client(script: str, path: str) -> str:
    """A mesher's verdict on a file: "N tets", or why it failed."""
    n, why = run_client(script, path)
    return f"{n:,} tets" if n is not None else f"FAILED ({why[:80]})"


def pymeshlab_faces(points, faces) -> int | None:
    try:
        import pymeshlab
    except ImportError:
        return None
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(points, np.float64), np.asarray(faces, np.int32)))
    ms.compute_selection_by_self_intersections_per_face()
    return int(ms.current_mesh().face_selection_array().sum())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--resolutions", default="64,96,128")
    ap.add_argument("--clearances", default="0,0.05")
    ap.add_argument("--no-gmsh", action="store_true")
    ap.add_argument("--no-tetgen", action="store_true")
    ap.add_argument("--labels", action="store_true", help="also every label of frog_tissues and channels")
    ap.add_argument("--skip-part", action="store_true")
    ap.add_argument("--json")
    args = ap.parse_args()
    t_start, load0 = time.perf_counter(), load_banner("raw part surfaces: quality and mesher acceptance")
    print(f"warpmesh {version('warpmesh')}, tetgen {version('tetgen')}, gmsh {version('gmsh')}, "
          f"pymeshlab {version('pymeshlab')}")
    part, bounds = wm.example("part")
    rows = []
    head = f"{'res':>4} {'clear':>5} {'triangles':>9} {'worst Q':>8} {'min ang':>8} {'edge ratio':>10} " \
           f"{'crossing':>8} {'pymeshlab':>9}  {'TetGen':<28} gmsh"
    print(head)
    with tempfile.TemporaryDirectory() as tmp:
        for res in (() if args.skip_part else (int(r) for r in args.resolutions.split(","))):
            for clearance in (float(c) for c in args.clearances.split(",")):
                m = wm.mesh_surface(part, bounds=bounds, resolution=res, clearance=clearance)
                p, t = m.points, m.triangles
                e = np.linalg.norm(p[t] - p[np.roll(t, 1, axis=1)], axis=2)
                row = {"resolution": res, "clearance": clearance, "triangles": len(t),
                       "worst_q": float(triangle_quality(p, t).max()),
                       "min_angle": float(triangle_angles(p, t).min()),
                       "edge_ratio": float(e.max() / e.min()),
                       "crossing_faces": int(count_self_intersecting_faces(p, t)),
                       "pymeshlab_faces": pymeshlab_faces(p, t)}
                npz, stl = os.path.join(tmp, "part.npz"), os.path.join(tmp, "part.stl")
                np.savez(npz, points=p, faces=t)
                m.to_trimesh().export(stl)
                row["tetgen"] = "-" if args.no_tetgen else client(TETGEN, npz)
                row["gmsh"] = "-" if args.no_gmsh else client(GMSH, stl)
                rows.append(row)
                pm = "-" if row["pymeshlab_faces"] is None else row["pymeshlab_faces"]
                print(f"{res:>4} {clearance:>5.2f} {len(t):>9,} {row['worst_q']:>8.1f} {row['min_angle']:>8.3f} "
                      f"{row['edge_ratio']:>10.1f} {row['crossing_faces']:>8} {pm:>9}  {row['tetgen']:<28} "
                      f"{row['gmsh']}", flush=True)
    labels = segmentations() if args.labels else []
    finish(t_start, load0, args.json, {"rows": rows, "labels": labels})


def segmentations() -> list[dict]:
    """Every label of pyvista's frog_tissues and channels volumes: crossing faces per label."""
    from pyvista import examples
    out = []
    print(f"\n{'volume':<14} {'labels':>6} {'triangles':>10} {'seconds':>7} {'crossing (ours)':>15} "
          f"{'(pymeshlab)':>11}  labels with crossings")
    for name in ("frog_tissues", "channels"):
        image = getattr(examples, f"load_{name}")()
        data = np.asarray(image.active_scalars)
        dims = np.array(image.dimensions) - (data.size != np.prod(image.dimensions))  # point or cell data
        vol = np.ascontiguousarray(data.reshape(dims, order="F").astype(np.int32))
        t0 = time.perf_counter()
        m = wm.mesh_surface(vol, labels="all", spacing=image.spacing)
        seconds = time.perf_counter() - t0
        refs = m.cell_refs["triangle"]
        ours = theirs = 0
        bad = []
        for label in np.unique(refs):
            t = m.triangles[refs == label]
            used = np.unique(t)
            p, t = m.points[used], np.searchsorted(used, t)
            a, b = int(count_self_intersecting_faces(p, t)), pymeshlab_faces(p, t)
            ours, theirs = ours + a, None if b is None or theirs is None else theirs + b
            if a or b:
                bad.append(int(label))
        labels = len(np.unique(refs))
        print(f"{name:<14} {labels:>6} {len(m.triangles):>10,} {seconds:>7.1f} {ours:>15} "
              f"{'-' if theirs is None else theirs:>11}  {bad or 'none'}", flush=True)
        out.append({"volume": name, "labels": labels, "triangles": len(m.triangles), "seconds": seconds,
                    "crossing_faces": ours, "pymeshlab_faces": theirs, "labels_crossing": bad})
    return out


if __name__ == "__main__":
    main()
