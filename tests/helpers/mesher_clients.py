"""TetGen and gmsh as clients of a surface: each run in a subprocess on a file, so a crash
(TetGen segfaults on some invalid surfaces) is a result, not the end of the caller.

``run_client(TETGEN, "s.npz")`` reads ``points``/``faces`` from an .npz and tetrahedralises
with the quality bounds 10 degrees / radius-edge 1.5; ``run_client(GMSH, "s.stl")`` merges
the surface, closes it with a surface loop and meshes the volume.
"""

from __future__ import annotations

import subprocess
import sys

__all__ = ["TETGEN", "GMSH", "run_client"]

TETGEN = """
import sys, numpy as np, tetgen
d = np.load(sys.argv[1])
tet = tetgen.TetGen(d["points"], d["faces"])
tet.tetrahedralize(order=1, mindihedral=10, minratio=1.5, quiet=True)
print("TETRAHEDRA", tet.grid.n_cells)
"""

GMSH = """
import sys, gmsh
gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.merge(sys.argv[1])
gmsh.model.mesh.createTopology()
loop = gmsh.model.geo.addSurfaceLoop([tag for _, tag in gmsh.model.getEntities(2)])
gmsh.model.geo.addVolume([loop])
gmsh.model.geo.synchronize()
gmsh.model.mesh.generate(3)
print("TETRAHEDRA", sum(len(t) for t in gmsh.model.mesh.getElements(3)[1]))
gmsh.finalize()
"""


def run_client(script: str, path, timeout: float = 900) -> tuple[int | None, str]:
    """(number of tetrahedra, "") when the mesher succeeds, else (None, why: its exit code
    and last line of error, or the timeout)."""
    try:
        run = subprocess.run([sys.executable, "-c", script, str(path)], check=False, capture_output=True,
                             text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, f"no answer in {timeout:g} s"
    if run.returncode == 0 and "TETRAHEDRA" in run.stdout:
        return int(run.stdout.split("TETRAHEDRA")[1].split()[0]), ""
    last = (run.stderr.strip().splitlines() or run.stdout.strip().splitlines() or [""])[-1]
    return None, f"exit code {run.returncode}: {last}"
