"""The edit loop of a real-time preview: set up once, then every parameter edit re-meshed.

A :class:`Preview` holds a shape with parameters (:func:`warpmesh.param`), the meshing
options, and the current values. Set-up pays everything that is paid once: the tape
compile, the Warp module loads of every stage, and (``evaluator="compiled"``, the
default) the kernel generated for the shape's structure. An edit (:meth:`Preview.update`)
then changes the tape's constant array only: no tape rebuild, no Warp compile
(:func:`warpmesh.preview.instrument.count_module_loads` counts none over an edit loop),
and its mesh is the one a fresh :func:`warpmesh.mesh_surface` of the same shape built
with plain numbers gives (the same triangles).

While a view is shown (the notebook widget, or any watcher added with
:meth:`Preview.watch`), a pause of ``idle`` seconds after the last edit starts a finer
mesh of the same values in a background thread (``refine``: twice the resolution by
default, one more octree level for ``adaptive=True``); it replaces the preview mesh in
the views when it is done, unless a newer edit arrived meanwhile, in which case it is
dropped (``Preview.dropped`` counts them; checked again under the lock every show holds,
so a refinement whose thread is delayed between its check and its drawing never lands
over a newer edit's mesh): a refinement still running stops at the
pipeline's next stage (``Preview.cancelled`` counts those; :mod:`warpmesh._util.cancel`)
instead of at its end; an edit makes it stale as it starts, so the refinement stops while
the edit meshes. Edits 0.12 s apart at 128^3 (``python benchmarks/bench_preview.py
--bursts 0.12 --resolutions 128 --edits 40``, two runs of two interleaved pairs): edit
latency p50 49-71 ms against 73-85 ms with the refinements run to their end, p95 80-89
against 81-104 ms, process CPU 8.8-10.7 s against 12.4-12.7 s. The stages are coarse
(about 0.1 s each at 256^3): a stale refinement still finishes the one it is in.
Headless code asks for it with
:meth:`Preview.refined`.

Edits may come from several threads: the newest lands, its values holding every edit
requested before it. A watcher may edit from its callback (the other watchers end with
that edit's mesh). A view or watcher that raises does not stop the others or the
refinement: :meth:`Preview.update` re-raises the first error afterwards, and
``Preview.errors`` keeps it, with any failure of a background refinement (no caller
sees that thread).

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

import threading
import time

from warpmesh._util import cancel
from warpmesh._util.validate import check_device
from warpmesh import _conventions as C
from warpmesh.frep.expr import check_values
from warpmesh.frep.shapes import as_shape
from warpmesh.surface.pipeline import mesh_surface, surface_options

#: the preview's grid resolution when none is given (and no max_level with adaptive=True)
DEFAULT_RESOLUTION = 128
#: the idle refinement of an adaptive preview stops at this level (2**10 cells a side)
MAX_LEVEL = 10


class Preview:
    """A shape re-meshed on every parameter edit; shows itself in notebooks.

    Parameters
    ----------
    shape : Shape or Expr
        The shape, usually with parameters (:func:`warpmesh.param`); without any, a
        preview only shows it.
    bounds : ((x0, y0, z0), (x1, y1, z1))
        The meshing box.
    resolution : int, optional
        Cells along the longest side of the box (default 128). With ``adaptive=True`` it is
        the equivalent of ``max_level`` (2**max_level): give one of them (default 128).
    method : {'mc33', 'mt', 'mc'}
        Cell triangulation (see :func:`warpmesh.mesh_surface`; not with ``adaptive=True``).
    evaluator : {'compiled', 'interpreter'}
        "compiled" (default) compiles the kernel generated for the shape's structure at
        set-up (about 1.5 s the first time, then read from Warp's cache) and evaluates
        every edit with it; "interpreter" never compiles. ("auto" is refused: it would
        start a compile in the middle of the edit loop.)
    device : str
        Warp device.
    refine : "auto", int, dict or None
        The finer mesh made while the user is idle: "auto" (default) is twice
        ``resolution`` (at most 512) on the grid, ``max_level + 1`` (at most 10) with
        ``adaptive=True``; an int is a grid resolution; a dict holds the
        :func:`warpmesh.mesh_surface` keywords that change (e.g. ``{"max_level": 9}``);
        None: no refinement.
    idle : float
        Seconds without an edit before the refinement starts (only while a view is shown).
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
    refined_mesh : Mesh or None
        The finer mesh of the current values, once made (None after every edit until then).
    dropped : int
        Background refinements whose result was thrown away because an edit came first.
    errors : list of Exception
        What went wrong where no caller could be told at once: a background refinement
        that failed, a view or watcher that raised (:meth:`update` re-raises the first of
        its own show's too).

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

    def __init__(self, shape, bounds, resolution: int | None = None, *, method: str = "mc33",
                 evaluator: str = "compiled", device: str = C.DEFAULT_DEVICE, refine="auto", idle: float = 0.4,
                 **options):
        if evaluator not in ("compiled", "interpreter"):
            raise ValueError(f"Unknown evaluator {evaluator!r} for a preview. Pick one of ['compiled', 'interpreter'] "
                             "('auto' would compile in the middle of the edit loop)")
        self.shape = as_shape(shape)
        self.params = dict(self.shape.params)
        self.values = {name: p.value for name, p in self.params.items()}
        self.device = check_device(device)
        if resolution is None and not (options.get("adaptive") and options.get("max_level") is not None):
            resolution = DEFAULT_RESOLUTION  # (adaptive with max_level: the level says it)
        self._options = dict(bounds=bounds, **options)
        if resolution is not None:
            self._options["resolution"] = resolution
        if not options.get("adaptive"):  # the octree evaluates pruned tapes: no method, no evaluator
            self._options.update(method=method, evaluator=evaluator)
        self._refine = _refine_options(refine, self._options)
        if self._refine:  # checked now: the refinement runs later, in a thread no caller sees
            try:
                surface_options(self.shape, **{**self._options, **self._refine})
            except (TypeError, ValueError) as exc:
                raise ValueError(f"expected mesh_surface keywords for 'refine', got {refine!r}: {exc}") from exc
        if isinstance(idle, bool) or not isinstance(idle, (int, float)) or not 0 <= idle < float("inf"):
            raise ValueError(f"expected a non-negative number of seconds for 'idle', got {idle!r}")
        self.idle = float(idle)
        self.timings: list[float] = []
        self._views: list = []
        self._watchers: list = []
        self._widget = None  # the live widget (warpmesh.preview.widget), at most one
        self._generation = 0
        self._lock = threading.Lock()
        self._show_lock = threading.RLock()  # held while the views draw (:meth:`_show`; a watcher may edit)
        self._timer: threading.Timer | None = None
        self.refined_mesh = None
        self.dropped = 0
        self.cancelled = 0
        self.errors: list[BaseException] = []
        self._wanted = dict(self.values)  # every edit requested so far (update)
        self._edits = 0  # edits requested, and the newest that landed
        self._landed = 0
        self.mesh = self._mesh(self.values)  # set-up: tape, module loads, the generated kernel

    @property
    def bounds(self):
        """The meshing box."""
        return self._options["bounds"]

    def _mesh(self, values, finer: bool = False):
        options = {**self._options, **self._refine} if finer else self._options
        return mesh_surface(self.shape, params=values, device=self.device, **options)

    @property
    def options(self) -> dict:
        """The :func:`warpmesh.mesh_surface` keywords of the preview mesh (bounds, resolution, ...)."""
        return dict(self._options)

    @property
    def refine_options(self) -> dict:
        """The :func:`warpmesh.mesh_surface` keywords of the idle refinement ({} when off)."""
        return dict(self._refine)

    def update(self, **values):
        """Set parameter values (keywords) and re-mesh; shown views refresh.

        Parameters
        ----------
        **values : float
            New values of some parameters, each within its [lo, hi].

        Returns
        -------
        Mesh
            The mesh of the new values (also ``self.mesh``, unless a newer edit from another
            thread has landed meanwhile: the newest edit's values and mesh are kept, and
            every edit's values hold all the edits requested before it).

        Raises
        ------
        ValueError
            An unknown parameter name or a value outside its range (naming it).
        Exception
            The first exception a watcher raised, re-raised once every view and watcher has
            had the mesh and the refinement is scheduled (the edit stays made; the error is
            in ``errors`` too).
        """
        checked = check_values(self.params, values, "values")
        t0 = time.perf_counter()
        with self._lock:  # what refines the old values is stale from now: it stops at its next checkpoint
            self._generation += 1
            self._edits += 1
            edit = self._edits
            self._wanted.update(checked)  # every edit so far, whichever thread made it
            new = dict(self._wanted)
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
        mesh = self._mesh(new)
        with self._lock:  # (again: a refined() begun while this meshed refines the old values)
            current = edit > self._landed  # a newer edit from another thread may have landed first
            if current:
                self._landed = edit
                self._generation += 1
                generation = self._generation
                self.values, self.mesh, self.refined_mesh = new, mesh, None
        self.timings.append(time.perf_counter() - t0)
        if not current:
            return mesh
        error = self._show(mesh, "update", generation)
        if self._refine and (self._views or self._watchers):
            timer = threading.Timer(self.idle, self._refine_in_background, args=(generation, new))
            timer.daemon = True
            with self._lock:
                if generation == self._generation:  # not if a watcher's own edit came meanwhile
                    self._timer = timer
                    timer.start()
        if error is not None:
            raise error
        return mesh

    def refined(self):
        """The finer mesh of the current values (see ``refine``): made now if no
        background refinement has made it yet.

        Examples
        --------
        >>> import warpmesh as wm
        >>> boss = wm.param("boss", 0.5, lo=0.3, hi=0.7)
        >>> view = wm.Preview(wm.box((2, 2, 0.6)) | wm.sphere(boss), bounds=((-1.2,) * 3, (1.2,) * 3),
        ...                   resolution=16, evaluator="interpreter")
        >>> view.refine_options, view.update(boss=0.6).n_cells < view.refined().n_cells
        ({'resolution': 32}, True)
        """
        if not self._refine:
            raise ValueError("this preview has no refinement: pass 'refine' (\"auto\", a resolution or options)")
        with self._lock:
            generation, values, done = self._generation, dict(self.values), self.refined_mesh
        if done is not None:
            return done
        mesh = self._mesh(values, finer=True)
        with self._lock:
            if generation == self._generation:
                self.refined_mesh = mesh
        return mesh

    def _refine_in_background(self, generation: int, values: dict) -> None:
        with self._lock:
            if generation != self._generation:
                self.dropped += 1
                return
        try:  # a newer edit stops it at the pipeline's next stage (cancel.checkpoint), not at its end
            with cancel.cancellable(lambda: generation != self._generation):
                mesh = self._mesh(values, finer=True)
        except cancel.Cancelled:
            with self._lock:
                self.dropped += 1
                self.cancelled += 1
            return
        except Exception as exc:  # noqa: BLE001 - no caller on this thread: kept in errors, the preview mesh stays
            with self._lock:
                self.errors.append(exc)
            return
        with self._lock:
            if generation != self._generation:  # an edit came while we meshed: stale
                self.dropped += 1
                return
            self.refined_mesh = mesh
        self._show(mesh, "refined", generation)  # a watcher's error is kept in errors: no caller here

    def watch(self, callback) -> None:
        """Call ``callback(mesh, kind)`` after every update (``kind`` "update") and when a
        background refinement lands ("refined"); a preview with a watcher refines when idle."""
        if not callable(callback):
            raise TypeError(f"expected a callable for 'callback', got {type(callback).__name__}")
        self._watchers.append(callback)

    def unwatch(self, callback) -> None:
        """Stop calling ``callback`` (added by :meth:`watch`); a preview left with no watcher
        and no view stops refining when idle. Unknown callbacks are ignored.

        Examples
        --------
        >>> import warpmesh as wm
        >>> view = wm.Preview(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=8,
        ...                   evaluator="interpreter", refine=None)
        >>> seen = []
        >>> def note(mesh, kind):
        ...     seen.append(kind)
        >>> view.watch(note); _ = view.update()
        >>> view.unwatch(note); _ = view.update()
        >>> seen
        ['update']
        """
        if callback in self._watchers:
            self._watchers.remove(callback)

    def _show(self, mesh, kind: str, generation: int):
        """Hand ``mesh`` to the views and watchers while it is still the current values' mesh
        (``generation`` is still the current one), checked under a lock that every show
        holds and again before each view and watcher: a refinement that passed its own check
        just before an edit, and whose show comes after the edit's, is dropped instead of
        replacing the newer mesh; a watcher that edits (its edit shown to everyone inside
        its call) ends this older show; two threads never draw at once. A view or watcher
        that raises does not stop the others: the first exception is returned (and kept in
        ``errors``), None when there was none."""
        first = None
        with self._show_lock:
            targets = [*(view.show_mesh for view in list(self._views)),
                       *(lambda m, w=w: w(m, kind) for w in list(self._watchers))]
            for k, target in enumerate(targets):
                with self._lock:
                    stale = generation != self._generation
                    if stale and k == 0 and kind == "refined":  # a refinement no one was shown
                        self.dropped += 1
                if stale:
                    break
                try:
                    target(mesh)
                except Exception as exc:  # noqa: BLE001 - the others still get the mesh; reported after
                    with self._lock:
                        self.errors.append(exc)
                    first = exc if first is None else first
        return first

    # -- showing -----------------------------------------------------------------------
    def widget(self):
        """The Jupyter widget: a slider per parameter above the 3D view (ipywidgets,
        anywidget); moving a slider calls :meth:`update`, the view's buffers are
        replaced in place and its camera kept. A preview drives one widget: a new one
        (the cell run again, the preview displayed again) closes the one before, which
        stops receiving meshes; ``close()`` on the widget detaches it too."""
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
                + (f"max_level {self._options['max_level']}>" if "resolution" not in self._options
                   else f"resolution {self._options['resolution']}>"))


def _refine_options(refine, options: dict) -> dict:
    """The mesh_surface keywords that differ for the idle refinement ({} for none)."""
    if refine is None or refine is False:
        return {}
    adaptive = bool(options.get("adaptive"))
    if isinstance(refine, str):
        if refine != "auto":
            raise ValueError(f"Unknown refine {refine!r}. Pick one of ['auto'], an int resolution, a dict or None")
        if adaptive:  # one level finer: max_level + 1, or twice the equivalent resolution
            level = options.get("max_level")
            if level is not None:
                return {"max_level": min(int(level) + 1, MAX_LEVEL)} if int(level) < MAX_LEVEL else {}
            res = options.get("resolution")
            finest = 2**MAX_LEVEL
            return {"resolution": min(2 * int(res), finest)} if isinstance(res, int) and res < finest else {}
        res = options.get("resolution")
        return {"resolution": min(2 * int(res), 512)} if isinstance(res, int) and res < 512 else {}
    if isinstance(refine, dict):
        return dict(refine)
    if isinstance(refine, bool) or not isinstance(refine, int) or refine < 1:
        raise ValueError(f"expected 'auto', a positive int resolution, a dict or None for 'refine', got {refine!r}")
    if adaptive:
        raise ValueError("an int 'refine' is a grid resolution; with adaptive=True pass a dict, e.g. {'max_level': 9}")
    return {"resolution": refine}
