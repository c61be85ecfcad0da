"""The Jupyter widget of a :class:`~warpmesh.preview.session.Preview`: sliders and a live 3D view.

:class:`MeshView` is an anywidget: its JavaScript (the WebGL viewer of
:mod:`warpmesh.preview.viewer`) is sent once; afterwards a new mesh travels as two binary
buffers (float32 points, uint32 triangles) that replace the GPU buffers in place, so the
camera stays where the user left it. :func:`preview_widget` puts one ipywidgets slider
per parameter (its [lo, hi]; unbounded parameters get a range around their value) above
the view; moving a slider calls ``Preview.update`` and the view follows.

Needs ``ipywidgets`` and ``anywidget`` (the ``notebooks`` extra).

Example
-------
>>> import warpmesh as wm
>>> r = wm.param("r", 0.2, lo=0.05, hi=0.28)
>>> view = wm.Preview(wm.box((2, 2, 0.6)) - wm.cylinder(r), bounds=((-1.2,) * 3, (1.2,) * 3),
...                   resolution=16, evaluator="interpreter")
>>> box = view.widget()                  # the slider of r, the view, a status line
>>> box.children[0].value = 0.1          # what a drag does: update(r=0.1), new buffers sent
>>> view.values, box.children[1].version
({'r': 0.1}, 2)
"""

from __future__ import annotations

import math

import anywidget
import ipywidgets
import traitlets

from warpmesh.preview.drawable import drawable
from warpmesh.preview.viewer import WIDGET_ESM


class MeshView(anywidget.AnyWidget):
    """A WebGL view of a triangle mesh; :meth:`show_mesh` swaps its buffers, keeping the camera."""

    _esm = WIDGET_ESM
    positions = traitlets.Bytes(b"").tag(sync=True)
    indices = traitlets.Bytes(b"").tag(sync=True)
    version = traitlets.Int(0).tag(sync=True)
    height = traitlets.Int(420).tag(sync=True)
    box = traitlets.List([]).tag(sync=True)  # [lo, hi] framed by the camera; empty: the first mesh

    def show_mesh(self, mesh) -> None:
        """Send ``mesh``'s points and triangles (one message, then ``version`` bumped)."""
        shown = drawable(mesh)
        pts, tri = shown.points, shown.triangles
        with self.hold_sync():
            self.positions = pts.astype("<f4").tobytes()
            self.indices = tri.astype("<u4").tobytes()
            self.version += 1


def _slider_range(p) -> tuple[float, float]:
    lo, hi = p.lo, p.hi
    span = max(abs(p.value), 1.0)
    if not math.isfinite(lo):
        lo = p.value - span if not math.isfinite(hi) else min(p.value, hi) - span
    if not math.isfinite(hi):
        hi = p.value + span
    return lo, hi


def status_line(preview, mesh, kind: str = "update") -> str:
    """What the widget shows under the view: points, triangles, Euler characteristic, the
    resolution and what made the mesh (the last edit, with its time, or the refinement).

    >>> import warpmesh as wm
    >>> view = wm.Preview(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=8, evaluator="interpreter")
    >>> status_line(view, view.update())
    '... points, ... triangles, χ 2, resolution 8, last update ... ms'
    """
    from warpmesh.cells.topology import euler_characteristic

    tri = mesh.cells.get("triangle")
    chi = euler_characteristic(None, tri) if tri is not None and len(tri) else 0
    options = {**preview.options, **(preview.refine_options if kind == "refined" else {})}
    where = (f"max level {options.get('max_level')}" if options.get("adaptive")
             else f"resolution {options.get('resolution')}")
    done = ("refined while idle" if kind == "refined"
            else f"last update {1000 * preview.timings[-1]:.0f} ms" if preview.timings else "first mesh")
    return f"{mesh.n_points} points, {mesh.n_cells} triangles, χ {chi}, {where}, {done}"


class PreviewBox(ipywidgets.VBox):
    """The sliders, view and status line of one preview; :meth:`close` detaches the view and
    the status watcher from the preview (no more meshes sent to it) and closes the parts."""

    def __init__(self, children, detach):
        super().__init__(children)
        self._detach = detach

    def close(self):
        detach, self._detach = self._detach, None
        if detach is not None:
            detach()
            for child in self.children:
                child.close()
        super().close()


def preview_widget(preview, *, height: int = 420):
    """A :class:`PreviewBox`: one FloatSlider per parameter, then the :class:`MeshView` of
    ``preview``, then a status line.

    The view is registered with the preview, so ``preview.update(...)`` from code also
    refreshes it. The widget made before for the same preview is closed first: re-running a
    cell left every earlier view registered, each sent every new mesh.
    """
    before = getattr(preview, "_widget", None)
    if before is not None:
        before.close()
    view = MeshView(height=height, box=[list(map(float, preview.bounds[0])), list(map(float, preview.bounds[1]))])
    view.show_mesh(preview.mesh)
    preview._views.append(view)
    status = ipywidgets.HTML()

    def show_status(mesh=None, kind="update"):
        mesh = preview.mesh if mesh is None else mesh
        status.value = f"<small>{status_line(preview, mesh, kind)}</small>"

    preview.watch(show_status)

    sliders = []
    for name, p in preview.params.items():
        lo, hi = _slider_range(p)
        s = ipywidgets.FloatSlider(value=preview.values[name], min=lo, max=hi, step=(hi - lo) / 200,
                                   description=name, continuous_update=True, readout_format=".3g")

        def changed(change, name=name):
            preview.update(**{name: change["new"]})  # the watcher writes the status

        s.observe(changed, names="value")
        sliders.append(s)
    show_status()

    def detach():
        if view in preview._views:
            preview._views.remove(view)
        preview.unwatch(show_status)
        if getattr(preview, "_widget", None) is box:
            preview._widget = None

    box = PreviewBox([*sliders, view, status], detach)
    preview._widget = box
    return box
