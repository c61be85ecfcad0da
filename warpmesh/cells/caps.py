"""The box a capped mesh was cut by, read back from its cap faces.

``mesh_surface`` and ``mesh_domain`` close a shape that reaches past ``bounds`` with flat faces
on the box, ref ``CAP_REF`` (2; the shape's own surface is ``SURFACE_REF``, 1). Operations that
project new boundary nodes onto f = 0 (``refine(n, shape)``, ``to_order(k, shape)``) must keep
the nodes of those faces on the box instead; they take ``bounds=``, and without it the box is
read here from the cap faces themselves: each lies in a plane x_a = c at the mesh's smallest or
largest coordinate along a (to within float32 rounding). Axes without a cap get a box side
well beyond the mesh.

Example
-------
>>> import warpmesh as wm
>>> m = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2, -1.2, -1.2), (1.2, 1.2, 0.5)), size=0.3)
>>> float(cap_bounds(m)[1][2])  # the cut at z = 0.5; the other sides lie beyond the ball
0.5
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import CAP_REF

__all__ = ["cap_bounds", "CAP_TOLERANCE"]

#: a cap face lies in a plane of the box to within this fraction of the mesh's extent (the meshers
#: compute in float32: a cap at z = 0.5 has nodes at 0.49999998)
CAP_TOLERANCE = 1e-6


def cap_bounds(mesh) -> np.ndarray | None:
    """((x0, y0, z0), (x1, y1, z1)) of the box a 3D mesh's cap faces lie on, or None without cap
    faces (no ``"triangle"`` block with ref ``CAP_REF``, or caps in no face of the bounding box).

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    (2, 3) float64 or None
    """
    refs = mesh.cell_refs or {}  # (None: a mesh without refs)
    if mesh.dim != 3 or "triangle" not in mesh.cells or "triangle" not in refs:
        return None
    caps = np.asarray(mesh.cells["triangle"])[np.asarray(refs["triangle"]) == CAP_REF]
    if not len(caps):
        return None
    pts = np.asarray(mesh.points, dtype=np.float64)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    far = 1.0 + (hi - lo).max()  # a side no node is near
    box = np.array([lo - far, hi + far])
    p = pts[caps]  # (k, 3, 3)
    tol = CAP_TOLERANCE * float((hi - lo).max())  # the meshers' float32 coordinates: 0.49999998 for 0.5
    found = False
    for a in range(3):
        flat = np.ptp(p[:, :, a], axis=1) <= tol
        for side, extreme in ((0, lo[a]), (1, hi[a])):
            if np.any(flat & (np.abs(p[:, :, a] - extreme).max(axis=1) <= tol)):
                box[side, a] = extreme
                found = True
    return box if found else None
