"""The edit loop of a real-time preview: set up once, then every parameter edit re-meshed.

A :class:`Preview` holds a shape with parameters (:func:`warpmesh.param`), the meshing
options, and the current values. Set-up pays everything that is paid once: the tape
compile, the Warp module loads of every stage, and (``evaluator="compiled"``, the
default) the kernel generated for the shape's structure. An edit (:meth:`Preview.update`)
then changes the tape's constant array only: no tape rebuild, no Warp compile
(:func:`warpmesh.preview.instrument.count_module_loads` counts none over an edit loop),
and its mesh is the one a fresh :func:`warpmesh.mesh_surface` of the same shape built
with plain numbers gives (the same triangles).

Example
-------
>>> import warpmesh as wm
>>> r = wm.param("r", 0.2, lo=0.05, hi=0.28)
>>> part = wm.box((2, 2, 0.6)) - wm.cylinder(r)
>>> view = wm.Preview(part, bounds=((-1.2,) * 3, (1.2,) * 3), resolution=32, evaluator="interpreter")
>>> mesh = view.update(r=0.15)
>>> view.values, mesh.stats()["euler"]
({'r': 0.15}, 0)
"""

from __future__ import annotations

import time

from warpmesh._util.validate import check_device
from warpmesh import _conventions as C
from warpmesh.frep.expr import check_values
from warpmesh.frep.shapes import as_shape
from warpmesh.surface.pipeline import mesh_surface


class Preview:
    """A shape re-meshed on every parameter edit; shows itself in notebooks.

    Parameters
    ----------
    shape : Shape or Expr
        The shape, usually with parameters (:func:`warpmesh.param`); without any, a
        preview only shows it.
    bounds : ((x0, y0, z0), (x1, y1, z1))
        The meshing box.
    resolution : int
        Cells along the longest side of the box.
    method : {'mc33', 'mt', 'mc'}
        Cell triangulation (see :func:`warpmesh.mesh_surface`; not with ``adaptive=True``).
    evaluator : {'compiled', 'interpreter'}
        "compiled" (default) compiles the kernel generated for the shape's structure at
        set-up (about 1.5 s the first time, then read from Warp's cache) and evaluates
        every edit with it; "interpreter" never compiles. ("auto" is refused: it would
        start a compile in the middle of the edit loop.)
    device : str
        Warp device.
    **options
        Other keywords of :func:`warpmesh.mesh_surface` (``cap``, ``root``, ``covering``,
        ``adaptive=True`` with its ``max_level``, ``tolerance``, ...).

    Attributes
    ----------
    mesh : Mesh
        The mesh of the current values.
    values : dict of str to float
        The current parameter values.
    params : dict of str to Param
        The shape's parameters (names, ranges).
    timings : list of float
        Seconds per update, in order.

    Examples
    --------
    >>> import warpmesh as wm
    >>> boss = wm.param("boss", 0.5, lo=0.3, hi=0.7)
    >>> view = wm.Preview(wm.box((2, 2, 0.6)) | wm.sphere(boss), bounds=((-1.2,) * 3, (1.2,) * 3),
    ...                   resolution=24, evaluator="interpreter")
    >>> view.update(boss=0.9)
    Traceback (most recent call last):
    ...
    ValueError: expected a value in [0.3, 0.7] for parameter 'boss' in 'values', got 0.9
    """

    def __init__(self, shape, bounds, resolution: int = 128, *, method: str = "mc33",
                 evaluator: str = "compiled", device: str = C.DEFAULT_DEVICE, **options):
        if evaluator not in ("compiled", "interpreter"):
            raise ValueError(f"Unknown evaluator {evaluator!r} for a preview. Pick one of ['compiled', 'interpreter'] "
                             "('auto' would compile in the middle of the edit loop)")
        self.shape = as_shape(shape)
        self.params = dict(self.shape.params)
        self.values = {name: p.value for name, p in self.params.items()}
        self.device = check_device(device)
        self._options = dict(bounds=bounds, resolution=resolution, **options)
        if not options.get("adaptive"):  # the octree evaluates pruned tapes: no method, no evaluator
            self._options.update(method=method, evaluator=evaluator)
        self.timings: list[float] = []
        self._views: list = []
        self.mesh = self._mesh(self.values)  # set-up: tape, module loads, the generated kernel

    @property
    def bounds(self):
        """The meshing box."""
        return self._options["bounds"]

    def _mesh(self, values):
        return mesh_surface(self.shape, params=values, device=self.device, **self._options)

    def update(self, **values):
        """Set parameter values (keywords) and re-mesh; shown views refresh.

        Parameters
        ----------
        **values : float
            New values of some parameters, each within its [lo, hi].

        Returns
        -------
        Mesh
            The mesh of the new values (also ``self.mesh``).

        Raises
        ------
        ValueError
            An unknown parameter name or a value outside its range (naming it).
        """
        checked = check_values(self.params, values, "values")
        t0 = time.perf_counter()
        new = {**self.values, **checked}
        mesh = self._mesh(new)
        self.values, self.mesh = new, mesh
        for view in list(self._views):
            view.show_mesh(mesh)
        self.timings.append(time.perf_counter() - t0)
        return mesh

    # -- showing -----------------------------------------------------------------------
    def widget(self):
        """The Jupyter widget: a slider per parameter above the 3D view (ipywidgets,
        anywidget); moving a slider calls :meth:`update`, the view's buffers are
        replaced in place and its camera kept."""
        from warpmesh.preview.widget import preview_widget

        return preview_widget(self)

    def export_html(self, path, *, label: bool = True) -> str:
        """Write the current mesh as a self-contained WebGL page framed by the preview's
        bounds (pages of several edits overlay), see :func:`warpmesh.preview.render.write_html`;
        returns the path."""
        from warpmesh.preview.render import write_html

        return write_html(self.mesh, path, title=self._title(), box=self.bounds, label=label)

    def plot(self, path=None, **kwargs):
        """An off-screen picture of the current mesh (see :meth:`warpmesh.Mesh.plot`)."""
        return self.mesh.plot(path, **kwargs)

    def _title(self) -> str:
        vals = ", ".join(f"{n} = {v:.4g}" for n, v in self.values.items())
        return f"warpmesh preview ({vals})" if vals else "warpmesh preview"

    def _repr_mimebundle_(self, include=None, exclude=None):
        from warpmesh.preview.render import preview_mimebundle

        return preview_mimebundle(self)

    def __repr__(self):
        vals = ", ".join(f"{n}={v:.4g}" for n, v in self.values.items())
        return (f"<Preview ({vals}) {self.mesh.n_points} points, {self.mesh.n_cells} triangles, "
                f"resolution {self._options['resolution']}>")
