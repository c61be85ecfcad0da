"""Showing a mesh: an off-screen PNG (pyvista), a self-contained WebGL page, notebook output.

- :func:`render_png`: pyvista/VTK off-screen (EGL or OSMesa where there is no display;
  ``pyvista.OFF_SCREEN`` is set), returned as a :class:`RenderedImage` (PNG bytes, an
  RGB array, ``_repr_png_`` for notebooks).
- :func:`mesh_html` / :func:`write_html`: one HTML file holding the mesh (base64 float32
  points, uint32 triangles) and the WebGL viewer of :mod:`warpmesh.preview.viewer`; it
  fetches nothing, so it opens offline and in a headless browser. Why this route rather
  than pyvista's ``export_html`` (trame, vtk.js) is argued in that module's docstring.
- :func:`mesh_mimebundle`: what ``Mesh._repr_mimebundle_`` shows in Jupyter (the page in
  an iframe, so its script runs isolated), with a text fallback.

Example
-------
>>> import warpmesh as wm
>>> from warpmesh.preview.render import mesh_html
>>> page = mesh_html(wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=8))
>>> page.startswith("<!DOCTYPE html>"), "createWarpmeshViewer" in page, "http" in page.split("<script>")[1]
(True, True, False)
"""

from __future__ import annotations

import base64
import errno
import html
import io
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from warpmesh.preview.drawable import drawable
from warpmesh.preview.viewer import VIEWER_JS

#: above this many triangles the notebook shows text, not the page (it would be megabytes)
MAX_INLINE_TRIANGLES = 2_000_000
DEFAULT_COLOR = (0.55, 0.72, 0.9)


def surface_arrays(mesh, clip=None) -> tuple[np.ndarray, np.ndarray]:
    """(points (n, 3) float32, triangles (m, 3) uint32) to draw (see
    :func:`warpmesh.preview.drawable.drawable`; default: the outer boundary of volume
    meshes)."""
    d = drawable(mesh, clip=clip)
    return d.points, d.triangles


def _umask_mode() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def _b64(arr: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(arr).astype(arr.dtype.newbyteorder("<")).tobytes()).decode()


def mesh_html(mesh, *, title: str = "warpmesh", color=DEFAULT_COLOR, height: str = "100vh", box=None,
              label: bool = True, clip="auto") -> str:
    """A self-contained HTML page drawing ``mesh`` with WebGL.

    Parameters
    ----------
    mesh : Mesh
        Triangles are drawn as they are, curves as thin ribbons, volume meshes cut by
        ``clip`` (:func:`warpmesh.preview.drawable.drawable`); a 2D mesh is seen from above.
    title : str
        The page title, also shown in its corner.
    color : 3 floats in [0, 1]
        Surface colour.
    height : str
        CSS height of the view.
    box : ((x0, y0, z0), (x1, y1, z1)), optional
        The box the camera frames (default: the mesh's bounding box); pages of several
        edits of one preview framed by its bounds overlay exactly.
    label : bool
        Show the title and counts in the corner.
    clip : "auto", "x", "y", "z", (normal, origin) or None
        The cut of a volume mesh (see :func:`warpmesh.preview.drawable.drawable`).

    Returns
    -------
    str
        The page (about 16 bytes per triangle plus 7 KB).
    """
    shown = drawable(mesh, clip=clip)
    pts, tri = shown.points, shown.triangles
    col = [float(c) for c in color]
    if len(col) != 3 or not all(0.0 <= c <= 1.0 for c in col):
        raise ValueError(f"expected 3 values in [0, 1] for 'color', got {color!r}")
    esc = html.escape(title)
    opts = {"color": col, "top": shown.planar}
    if box is not None:
        b = np.asarray(box, dtype=np.float64)
        if b.shape != (2, 3) or not np.all(np.isfinite(b)) or np.any(b[0] >= b[1]):
            raise ValueError(f"expected ((x0, y0, z0), (x1, y1, z1)) with lo < hi for 'box', got {box!r}")
        opts["box"] = b.tolist()
    text = f"{esc} &middot; {mesh.n_points} points, {mesh.n_cells} cells" if label else ""
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>{esc}</title>
<style>html,body{{margin:0;height:100%;background:#fff;overflow:hidden}}
#view{{width:100%;height:{html.escape(height)};display:block}}
#label{{position:absolute;left:8px;top:6px;font:12px sans-serif;color:#555}}</style></head>
<body><canvas id="view"></canvas><div id="label">{text}</div>
<script>{VIEWER_JS}
(function () {{
  function decode(s, T) {{ const b = atob(s), u = new Uint8Array(b.length);
    for (let i = 0; i < b.length; i++) u[i] = b.charCodeAt(i); return new T(u.buffer); }}
  const viewer = createWarpmeshViewer(document.getElementById("view"), {json.dumps(opts)});
  viewer.setMesh(decode("{_b64(pts)}", Float32Array), decode("{_b64(tri)}", Uint32Array));
  window.warpmeshViewer = viewer;
}})();
</script></body></html>
"""


def write_html(mesh, path, *, title: str = "warpmesh", color=DEFAULT_COLOR, box=None, label: bool = True,
               clip="auto") -> str:
    """Write :func:`mesh_html` to ``path`` atomically (a temporary file, then a rename).

    Example
    -------
    >>> import os, tempfile, warpmesh as wm
    >>> mesh = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=8)
    >>> path = write_html(mesh, os.path.join(tempfile.mkdtemp(), "ball.html"))
    >>> os.path.getsize(path) > 1000
    True
    """
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ValueError(f"expected a .html path for 'path', got {str(path)!r}")
    if not path.parent.is_dir():
        raise FileNotFoundError(errno.ENOENT, "no such folder for 'path'", str(path.parent))
    text = mesh_html(mesh, title=title, color=color, box=box, label=label, clip=clip)
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, _umask_mode())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return str(path)


class RenderedImage:
    """An off-screen picture: ``png`` (bytes), ``array`` ((h, w, 3) uint8); shows itself in
    notebooks (``_repr_png_``); ``save(path)`` writes the PNG."""

    def __init__(self, array: np.ndarray):
        from PIL import Image

        self.array = np.ascontiguousarray(array[..., :3], dtype=np.uint8)
        buf = io.BytesIO()
        Image.fromarray(self.array).save(buf, format="PNG")
        self.png = buf.getvalue()

    def save(self, path) -> str:
        path = Path(path)
        if path.suffix.lower() != ".png":
            raise ValueError(f"expected a .png path for 'path', got {str(path)!r}")
        if not path.parent.is_dir():
            raise FileNotFoundError(errno.ENOENT, "no such folder for 'path'", str(path.parent))
        fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=f".{path.name}.")
        with os.fdopen(fd, "wb") as f:
            f.write(self.png)
        os.chmod(tmp, _umask_mode())
        os.replace(tmp, path)
        return str(path)

    def _repr_png_(self) -> bytes:
        return self.png

    def __repr__(self):
        h, w = self.array.shape[:2]
        return f"<RenderedImage {w}x{h} PNG, {len(self.png)} bytes>"


def _headless_vtk() -> None:
    """Off-screen rendering without an X display: VTK's EGL window (falls back to OSMesa)."""
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


#: the most pixels of a rendered image (8192 x 8192: 192 MB of RGB; VTK aborts the process,
#: not Python, when it cannot allocate a window)
MAX_PIXELS = 1 << 26


def check_window_size(window_size) -> tuple[int, int]:
    """(width, height) of ``window_size``: two positive integers, at most MAX_PIXELS in all.

    >>> check_window_size((800, 600))
    (800, 600)
    >>> check_window_size((100000, 100000))
    Traceback (most recent call last):
    ...
    ValueError: expected a 'window_size' of at most 67108864 pixels (8192 x 8192), got (100000, 100000)
    """
    try:
        w, h = window_size
    except (TypeError, ValueError):
        raise ValueError(f"expected (width, height) for 'window_size', got {window_size!r}") from None
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) and v > 0 for v in (w, h)):
        raise ValueError(f"expected two positive integers for 'window_size', got {window_size!r}")
    if int(w) * int(h) > MAX_PIXELS:
        raise ValueError(f"expected a 'window_size' of at most {MAX_PIXELS} pixels (8192 x 8192), got {window_size!r}")
    return int(w), int(h)


def render_png(mesh, path=None, *, window_size=(800, 600), color=DEFAULT_COLOR, show_edges: bool = False,
               camera=None, clip="auto", scalars: str | None = None) -> RenderedImage:
    """Render ``mesh`` off-screen with pyvista; write a PNG when ``path`` is given.

    Parameters
    ----------
    mesh : Mesh
    path : str or Path, optional
        A .png file to write (atomically).
    window_size : (int, int)
        Width and height in pixels.
    color : 3 floats in [0, 1]
    show_edges : bool
        Draw the triangle edges.
    camera : str or list, optional
        A pyvista camera position ("iso", "xy", ... or [(pos), (focus), (up)]); default: an
        isometric view of the mesh, from above ("xy") for a 2D mesh.
    clip : "auto", "x", "y", "z", (normal, origin) or None
        The cut of a volume mesh (see :func:`warpmesh.preview.drawable.drawable`).
    scalars : str, optional
        Colour a triangle surface by a per-triangle array, one colour per distinct value:
        "ref" (``cell_refs["triangle"]``) or the name of a ``cell_data`` array (e.g. the
        interfaces' ``"label_above"``).

    Returns
    -------
    RenderedImage
    """
    w, h = check_window_size(window_size)
    values = None if scalars is None else _triangle_values(mesh, scalars)
    shown = drawable(mesh, clip=clip)
    pts, tri = shown.points, shown.triangles
    _headless_vtk()
    import pyvista as pv

    pv.OFF_SCREEN = True
    surf = pv.PolyData(pts.astype(np.float64), np.column_stack([np.full(len(tri), 3), tri]).ravel())
    plotter = pv.Plotter(off_screen=True, window_size=(w, h))
    try:
        plotter.set_background("white")
        if values is None:
            plotter.add_mesh(surf, color=tuple(color), show_edges=show_edges, smooth_shading=not shown.flat)
        else:  # categories: value i of the sorted distinct values -> colour i of a qualitative map
            codes = np.unique(values, return_inverse=True)[1].astype(np.float64)
            surf.cell_data[scalars] = codes
            plotter.add_mesh(surf, scalars=scalars, cmap="tab20", clim=(0.0, max(float(codes.max()), 1.0)),
                             show_edges=show_edges, smooth_shading=not shown.flat, show_scalar_bar=False,
                             preference="cell")
        plotter.camera_position = camera or ("xy" if shown.planar else "iso")
        image = RenderedImage(plotter.screenshot(return_img=True))
    finally:
        plotter.close()
    if path is not None:
        image.save(path)
    return image


def _triangle_values(mesh, scalars) -> np.ndarray:
    """The per-triangle array ``scalars`` names ("ref" or a cell_data name)."""
    if "triangle" not in mesh.cells or any(t in mesh.cells for t in ("tetra", "hexahedron", "wedge", "pyramid")):
        raise ValueError("'scalars' colours the triangles of a surface mesh; this mesh has "
                         f"{sorted(mesh.cells)} cells")
    if scalars == "ref":
        refs = mesh.cell_refs.get("triangle") if mesh.cell_refs else None
        if refs is None:
            raise ValueError("scalars='ref': the mesh has no triangle refs")
        return np.asarray(refs)
    data = (mesh.cell_data or {}).get(scalars)
    if not isinstance(scalars, str) or data is None or "triangle" not in data:
        names = sorted((mesh.cell_data or {}))
        raise ValueError(f"Unknown scalars {scalars!r}. Pick one of {['ref', *names]}")
    return np.asarray(data["triangle"])


def _iframe(page: str, height: int = 420) -> str:
    return (f'<iframe srcdoc="{html.escape(page, quote=True)}" style="width:100%;height:{height}px;border:0" '
            'sandbox="allow-scripts"></iframe>')


def mesh_mimebundle(mesh) -> dict:
    """Jupyter's view of a mesh: the WebGL page in an iframe, and ``repr`` as text."""
    bundle = {"text/plain": repr(mesh)}
    n_tri = len(mesh.cells["triangle"]) if "triangle" in mesh.cells else 0
    if 0 < n_tri <= MAX_INLINE_TRIANGLES or (n_tri == 0 and mesh.n_cells):
        bundle["text/html"] = _iframe(mesh_html(mesh, height="400px"))
    return bundle


def preview_mimebundle(preview) -> dict:
    """Jupyter's view of a :class:`~warpmesh.preview.session.Preview`: the widget (sliders
    and the live view) when ipywidgets and anywidget are installed, else the current
    mesh's page."""
    try:
        widget = preview.widget()
    except ImportError:
        bundle = mesh_mimebundle(preview.mesh)
        bundle["text/plain"] = repr(preview)
        return bundle
    data = widget._repr_mimebundle_()
    return data[0] if isinstance(data, tuple) else data
