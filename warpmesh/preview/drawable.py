"""What a view draws: triangles for any mesh (surfaces, curves, planar domains, volume meshes).

The off-screen render and the WebGL viewer both draw triangles, so every kind of mesh is
first turned into triangles here, on the host:

- **triangle cells** (surfaces, planar domains) are drawn as they are;
- **curves** (``line`` cells, from :func:`warpmesh.mesh_curve` or any polyline) become
  ribbons: each segment a thin rectangle of two triangles, in the plane z = 0 for a 2D
  mesh, across the segment and the viewing direction's best guess (the axis the segment
  is least aligned with) in 3D; ``width`` is a fraction of the bounding box's diagonal;
- **volume meshes** (tetrahedra, hexahedra, wedges, pyramids) are cut by a plane: the
  cells whose centre lies on the kept side stay whole (a "crinkle" clip, so the cut shows
  the elements themselves) and their boundary faces are drawn, each triangle with its own
  three vertices so that the facets shade flat and the elements can be told apart.
  ``clip="auto"`` cuts through the centre of the bounding box across x; ``clip=None``
  draws the outer boundary only.

:class:`Drawable` says whether the mesh is planar (the camera then looks down the z axis).

Example
-------
>>> import warpmesh as wm
>>> from warpmesh.preview.drawable import drawable
>>> ball = wm.mesh_domain(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.4)
>>> cut, whole = drawable(ball), drawable(ball, clip=None)
>>> bool(cut.points[:, 0].max() < 0.6), cut.flat, whole.flat, len(whole.triangles) == len(ball.cells["triangle"])
(True, True, False, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warpmesh.cells.types import require_mesh

#: cells drawn as a volume (cut by the clip plane)
VOLUME_CELLS = ("tetra", "hexahedron", "wedge", "pyramid")
#: ribbon width of curves, as a fraction of the bounding-box diagonal
DEFAULT_LINE_WIDTH = 0.006


@dataclass(frozen=True)
class Drawable:
    """Triangles to draw: ``points`` (n, 3) float32, ``triangles`` (m, 3) uint32; ``planar``
    (a 2D mesh: look down z), ``flat`` (facets shade flat: vertices are not shared)."""

    points: np.ndarray
    triangles: np.ndarray
    planar: bool = False
    flat: bool = False


def _clip_plane(clip, lo: np.ndarray, hi: np.ndarray):
    """(unit normal, origin) of ``clip``: "auto", an axis name, or (normal, origin)."""
    centre = 0.5 * (lo + hi)
    if isinstance(clip, str):
        axes = {"auto": 0, "x": 0, "y": 1, "z": 2}
        if clip not in axes:
            raise ValueError(f"Unknown clip {clip!r}. Pick one of ['auto', 'x', 'y', 'z'], (normal, origin) or None")
        normal = np.zeros(3)
        normal[axes[clip]] = 1.0
        return normal, centre
    try:
        normal, origin = (np.asarray(v, dtype=np.float64) for v in clip)
    except (TypeError, ValueError):
        raise ValueError(f"expected 'auto', 'x', 'y', 'z', (normal, origin) or None for 'clip', got {clip!r}") from None
    if normal.shape != (3,) or origin.shape != (3,) or not np.all(np.isfinite(normal)) \
            or not np.all(np.isfinite(origin)) or not np.linalg.norm(normal) > 0:
        raise ValueError(f"expected a non-zero finite 3-vector normal and a finite 3-vector origin for 'clip', "
                         f"got {clip!r}")
    return normal / np.linalg.norm(normal), origin


def _volume_triangles(mesh, pts: np.ndarray, clip) -> tuple[np.ndarray, np.ndarray, bool]:
    """The boundary of the cells kept by the clip plane (crinkle), as triangles."""
    import pyvista as pv

    grid = mesh.to_pyvista()
    keep = np.nonzero(np.isin(np.asarray(grid.celltypes), [pv.CellType.TETRA, pv.CellType.HEXAHEDRON,
                                                           pv.CellType.WEDGE, pv.CellType.PYRAMID]))[0]
    flat = clip is not None and clip is not False
    if flat:
        normal, origin = _clip_plane(clip, pts.min(axis=0), pts.max(axis=0))
        centres = np.asarray(grid.cell_centers().points)[keep]
        keep = keep[(centres - origin) @ normal <= 0.0]
        if len(keep) == 0:
            return np.zeros((0, 3), np.float32), np.zeros((0, 3), np.uint32), True
    grid = grid.extract_cells(keep)  # the volume cells only: boundary triangles would be drawn twice
    surf = grid.extract_surface(algorithm="dataset_surface").triangulate()
    p = np.asarray(surf.points, dtype=np.float64)
    tri = np.asarray(surf.faces).reshape(-1, 4)[:, 1:]
    if flat:  # unshare: each facet its own vertices, so the viewers shade it flat
        p, tri = p[tri].reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3)
    return p, tri, flat


def _ribbons(pts: np.ndarray, lines: np.ndarray, planar: bool, width: float) -> tuple[np.ndarray, np.ndarray]:
    """Each segment [a, b] as a rectangle of half-width ``width / 2`` (two triangles)."""
    a, b = pts[lines[:, 0]], pts[lines[:, 1]]
    d = b - a
    if planar:
        across = np.column_stack([-d[:, 1], d[:, 0], np.zeros(len(d))])
    else:  # across the segment and the axis it is least aligned with
        axis = np.eye(3)[np.argmin(np.abs(d), axis=1)]
        across = np.cross(d, axis)
    norm = np.linalg.norm(across, axis=1, keepdims=True)
    across = np.divide(across, norm, out=np.zeros_like(across), where=norm > 0) * (0.5 * width)
    corners = np.stack([a - across, a + across, b + across, b - across], axis=1).reshape(-1, 3)
    base = 4 * np.arange(len(lines))[:, None]
    tri = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]], axis=1).reshape(-1, 3)
    return corners, tri


def drawable(mesh, *, clip="auto", width: float = DEFAULT_LINE_WIDTH) -> Drawable:
    """The triangles that show ``mesh`` (see the module docstring).

    Parameters
    ----------
    mesh : Mesh
    clip : "auto", "x", "y", "z", (normal, origin) or None
        For volume meshes: the plane whose far side (along ``normal``) is cut away; an
        axis name cuts through the bounding box's centre across that axis ("auto": x).
        None draws the outer boundary. Surfaces and curves ignore it.
    width : float
        Ribbon width of curves, as a fraction of the bounding-box diagonal.

    Returns
    -------
    Drawable
    """
    require_mesh(mesh)
    if isinstance(width, bool) or not isinstance(width, (int, float)) or not 0 < width < 1:
        raise ValueError(f"expected a fraction in (0, 1) for 'width', got {width!r}")
    if clip is not None and clip is not False:  # checked whatever the mesh (a surface ignores it)
        _clip_plane(clip, np.zeros(3), np.ones(3))
    pts = np.asarray(mesh.points, dtype=np.float64)
    planar = pts.shape[1] == 2
    if planar:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    flat = False
    if any(t in mesh.cells for t in VOLUME_CELLS):
        pts, tri, flat = _volume_triangles(mesh, pts, clip)
    elif "triangle" in mesh.cells:
        tri = np.asarray(mesh.cells["triangle"])
    elif "line" in mesh.cells:
        diagonal = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) if len(pts) else 0.0
        pts, tri = _ribbons(pts, np.asarray(mesh.cells["line"]), planar, width * (diagonal or 1.0))
    else:  # quads, polygons: pyvista triangulates the surface
        surf = mesh.to_pyvista().extract_surface(algorithm="dataset_surface").triangulate()
        pts, tri = np.asarray(surf.points, np.float64), np.asarray(surf.faces).reshape(-1, 4)[:, 1:]
    return Drawable(np.ascontiguousarray(pts, np.float32), np.ascontiguousarray(tri, np.uint32), planar, flat)
