"""The options of :func:`warpmesh.mesh_surface`: one frozen, self-checking group per pipeline.

A shape (f > 0 inside) is meshed by one of three pipelines and a sampled volume by a
fourth [FG §16.4]; each pipeline's options are one group, checked when it is built:

=============================  ===================================================  =============================
group                          pipeline                                             chosen by
=============================  ===================================================  =============================
:class:`GridOptions`           the blocks of a grid that interval arithmetic        a shape (``covering="grid"``)
                               cannot cull are sampled, then marching cubes
:class:`ContinuationOptions`   cells grown from seeds across the faces the          ``covering="continuation"``
                               surface crosses; only their corners are evaluated
:class:`AdaptiveOptions`       an adaptive octree, sharp features by a QEF          ``adaptive=True``
:class:`VolumeOptions`         the samples of an array, slab by slab                an array
=============================  ===================================================  =============================

``mesh_surface(source, **keywords)`` builds the chosen group from its keywords;
``mesh_surface(source, options=group)`` takes one built beforehand. Groups are values:
comparable, hashable, changed with :func:`dataclasses.replace` (which checks again).
Fields hold the value given (normalised to tuples of Python numbers); ``None`` means
"automatic" where the default depends on other fields, as documented per field.

Example
-------
>>> import dataclasses, warpmesh as wm
>>> from warpmesh.surface.options import GridOptions
>>> opts = GridOptions(bounds=((-1.2,) * 3, (1.2,) * 3), resolution=32, method="mt")
>>> wm.mesh_surface(wm.sphere(1.0), options=opts).stats()["euler"]
2
>>> dataclasses.replace(opts, method="dual")
Traceback (most recent call last):
...
ValueError: Unknown method 'dual'. Pick one of ['mc33', 'mt', 'mc']
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from warpmesh.frep.codegen import EVALUATORS, Evaluator
from warpmesh._conventions import NODE_CLEARANCE
from warpmesh.surface.block_grid import check_clearance, GRADIENTS, METHODS
from warpmesh.surface.multilabel import INTERFACES
from warpmesh.surface.volume import SLAB_VOXELS, label_form

__all__ = ["AdaptiveOptions", "ContinuationOptions", "GridOptions", "SurfaceOptions", "VolumeOptions"]

Method = Literal["mc33", "mt", "mc"]
RootMethod = Literal["linear", "bisection", "newton"]
Gradient = Literal["exact", "central", "forward"]
Bound = Literal["interval", "lipschitz"]
Inside = Literal["above", "below"]
ROOTS = ("linear", "bisection", "newton")
BOUNDS = ("interval", "lipschitz")
INSIDES = ("above", "below")
MAX_RESOLUTION = 2048  # 2048^3 cells: 16.8 M blocks of 8^3, about 1 GB of block bookkeeping
MAX_ROOT_ITERATIONS = 64
MAX_LEVEL = 18  # 2**18 cells along the longest side
DEFAULT_RESOLUTION = 128
DEFAULT_TOLERANCE = 0.02


# -- one check per kind of value: "expected X for 'name', got Y" ---------------------------------
def check_choice(value, name: str, choices) -> str:
    if not isinstance(value, str) or value not in choices:
        raise ValueError(f"Unknown {name} {value!r}. Pick one of {list(choices)}")
    return value


def _flag(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"expected True or False for '{name}', got {value!r}")
    return bool(value)


def _is_number(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _positive(value, name: str) -> float:
    if not _is_number(value) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"expected a positive finite number for '{name}', got {value!r}")
    return float(value)


def _integer(value, name: str, low: int, high: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise ValueError(f"expected an integer {low} <= '{name}' <= {high}, got {value!r}")
    return int(value)


def _vector(value, name: str, what: str) -> np.ndarray:
    """A float64 array of the value, or the error naming what was expected."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"expected '{name}' as {what}, got {value!r}") from None


def _bounds(bounds) -> tuple[tuple[float, ...], tuple[float, ...]]:
    if bounds is None:
        raise ValueError("expected 'bounds' ((x0, y0, z0), (x1, y1, z1)) for a shape, got None")
    b = _vector(bounds, "bounds", "((x0, y0, z0), (x1, y1, z1))")
    if b.shape != (2, 3):
        raise ValueError(f"expected 'bounds' of shape (2, 3), got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"expected finite 'bounds', got {b.tolist()}")
    if np.any(b[1] <= b[0]):
        raise ValueError(f"expected non-empty 'bounds' (lower < upper on every axis), got {b.tolist()}")
    return tuple(b[0].tolist()), tuple(b[1].tolist())


#: a grid's cell must span this fraction of its coordinates' size at least: the kernels
#: place nodes and vertices in float32 (24-bit mantissa), so 2**-16 leaves 256 steps a cell
MIN_RELATIVE_CELL = 2.0**-16
#: cells and coordinates in this range keep f's squares and cubes normal float32 numbers
FLOAT32_RANGE = (1e-12, 1e12)


def check_float32_grid(bounds, cells, name: str = "bounds") -> None:
    """A ValueError naming ``name`` when a grid over ``bounds`` with ``cells`` cells per axis
    cannot be sampled in float32: cells below float32's resolution at those coordinates
    (a box far from the origin), or sizes outside :data:`FLOAT32_RANGE`."""
    lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
    h = (hi - lo) / np.asarray(cells, dtype=np.float64)
    scale = np.maximum(np.abs(lo), np.abs(hi))
    if np.any(scale > FLOAT32_RANGE[1]) or np.any(h < FLOAT32_RANGE[0]):
        raise ValueError(f"expected '{name}' with coordinates up to {FLOAT32_RANGE[1]:g} and cells of at least "
                         f"{FLOAT32_RANGE[0]:g} (f is evaluated in float32), got {np.asarray(bounds).tolist()} with "
                         f"cells of {h.tolist()}: rescale the shape")
    worst = int(np.argmin(h / np.maximum(scale, 1e-300)))
    if h[worst] < MIN_RELATIVE_CELL * scale[worst]:
        raise ValueError(f"expected '{name}' whose cells float32 can resolve: cells of {h[worst]:.3g} at coordinates "
                         f"of {scale[worst]:.3g} on axis {worst} are below {MIN_RELATIVE_CELL:.3g} of them (f is "
                         "evaluated in float32); translate the shape nearer the origin, or lower the resolution")


def cells_of(resolution, extent: np.ndarray) -> np.ndarray:
    """Cells per axis of a grid over a box of this extent: an int is the count along the
    longest side (cells near-cubic), 3 ints are the counts per axis."""
    if isinstance(resolution, (bool, np.bool_)):
        raise TypeError(f"expected an integer 'resolution', got {resolution!r}")
    if np.ndim(resolution) == 0:
        if not isinstance(resolution, (int, np.integer)):
            raise TypeError(f"expected an integer 'resolution', got {type(resolution).__name__}")
        r = int(resolution)
        if not 1 <= r <= MAX_RESOLUTION:
            raise ValueError(f"expected 1 <= 'resolution' <= {MAX_RESOLUTION}, got {r}")
        h = extent.max() / r
        return np.maximum(1, np.round(extent / h)).astype(np.int64)
    cells = np.asarray(resolution)
    if cells.shape != (3,) or not np.issubdtype(cells.dtype, np.integer):
        raise ValueError(f"expected an int or 3 ints for 'resolution', got {resolution!r}")
    if np.any(cells < 1) or np.any(cells > MAX_RESOLUTION):
        raise ValueError(f"expected 1 <= 'resolution' <= {MAX_RESOLUTION} per axis, got {cells.tolist()}")
    return cells.astype(np.int64)


def _extent(bounds) -> np.ndarray:
    return np.subtract(bounds[1], bounds[0])


def _roots(root: str, iterations, gradient: str, normals: bool | None) -> int | None:
    """The root finder's options: iterations only for an iterative root, a gradient
    other than the exact one only where something uses it (``normals`` is None where
    the pipeline has no normals)."""
    check_choice(root, "root", ROOTS)
    check_choice(gradient, "gradient", GRADIENTS)
    if gradient != "exact" and root != "newton" and not normals:
        users = "root='newton'" if normals is None else "root='newton' or normals=True"
        got = f"root={root!r}" if normals is None else f"root={root!r} and normals=False"
        raise ValueError(f"'gradient' applies to {users}, got {got}")
    if iterations is None:
        return None
    if root == "linear":
        raise ValueError("'root_iterations' applies to root='bisection' or 'newton', not 'linear'")
    if isinstance(iterations, (bool, np.bool_)) or not isinstance(iterations, (int, np.integer)) \
            or not 1 <= iterations <= MAX_ROOT_ITERATIONS:
        raise ValueError(f"expected 1 <= 'root_iterations' <= {MAX_ROOT_ITERATIONS}, got {iterations!r}")
    return int(iterations)


# -- the documentation of every field, written once ------------------------------------------------
# name -> (type, description); a group's docstring lists its fields in order, with their defaults
_FIELDS: dict[str, tuple[str, str]] = {
    "bounds": ("((x0, y0, z0), (x1, y1, z1))", """
        The box sampled (required); the surface is closed (capped) on it when ``cap``."""),
    "resolution": ("int or (3,) ints", """
        Cells along the longest side of ``bounds`` (near-cubic cells), or per axis; at most
        2048."""),
    "method": ("{'mc33', 'mt', 'mc'}", """
        How each cell is triangulated [FG §16.4.2]: "mc33" follows the topology of the
        trilinear interpolant of the corner values (asymptotic decider on faces, interior
        test for tunnels); "mt" splits every cube into 6 Kuhn tetrahedra (about 3x the
        triangles, the topology of the piecewise-linear interpolant); "mc" is the plain
        table (it separates the inside corners of every ambiguous face whatever the values
        say). All three give closed, 2-manifold, outward-oriented surfaces."""),
    "root": ("{'linear', 'bisection', 'newton'}", """
        Vertex placement on a crossing edge: linear interpolation (eq. 16.12), bisection or
        safeguarded Newton on the exact function [FG §16.3.3]. The octree defaults to
        "newton" (its large leaves make linear roots poor)."""),
    "root_iterations": ("int, optional", """
        Iterations of bisection (default 12) or safeguarded Newton (default 10 on a grid, 4
        from the linear estimate in the octree), 1 to 64; not with root='linear'."""),
    "gradient": ("{'exact', 'central', 'forward'}", """
        How Newton (``root='newton'``) and ``normals`` get grad f: exact forward-mode
        differentiation of the tape, or finite differences of f alone with a step of 1/100
        of the cell size, centred (eq. 16.14, error O(h^2), 6 extra evaluations per point)
        or forward (eq. 16.13, O(h), 3 extra). A finite difference where nothing uses the
        gradient is refused."""),
    "normals": ("bool", """
        Store outward unit normals (-grad f / |grad f|; on the caps, the normal of the face
        of the bounds they close) as ``point_data["normals"]``."""),
    "cap": ("bool", """
        Treat the grid boundary as outside, so every surface is closed on the sampled box;
        ``cell_refs["triangle"]`` is then 2 on the caps and 1 on the surface."""),
    "evaluator": ("{'auto', 'interpreter', 'compiled'}", """
        Evaluate with the tape interpreter, or with a kernel generated for the shape's
        structure (2x faster; about 1.5 s to compile once per structure, cached on disk;
        constants can change freely). "auto" never waits for a compile: it interprets
        until a background compile, started when a structure comes back for a second
        large run, is ready. ``mesh.info["evaluator"]`` says which ran."""),
    "cull": ("bool", """
        Skip blocks of 8^3 cells that cannot hold the surface (interval arithmetic for a
        shape, exact block ranges for a volume). The mesh is the same either way."""),
    "seeds": ("(m, 3) points, optional", """
        Points in cells crossed by the surface to grow from; only their components are
        meshed. Default: every component the grid finds. Rays along 32 grid lines per
        axis direction and transverse axis (every 8th line on grids up to 256 cells) seed
        the components they cross; then intervals of f over the blocks, halved down to
        single cells, list the cells that may be crossed, and those not grown yet are
        evaluated and seed the rest (``info["seed_search_cells"]``)."""),
    "max_level": ("int, optional", """
        Finest level: 2**max_level cells along the longest side of ``bounds``, 1 to 18.
        Default from ``resolution`` (7 when neither is given)."""),
    "min_level": ("int, optional", """
        Cells are refined at least to this level, 0 to ``max_level`` (default
        min(5, max_level))."""),
    "tolerance": ("float, optional", """
        The relative chord tolerance epsilon of [FG §16.2.2] (delta <= epsilon h): the
        planarity and divergence angles of the refinement are 4 epsilon. Default 0.02
        when neither ``chord`` nor ``angles`` is given."""),
    "angles": ("(eps1, eps2), optional", """
        The planarity and divergence angles in radians, instead of ``tolerance``."""),
    "chord": ("float, optional", """
        An absolute chord tolerance (in the units of ``bounds``): cells are refined while
        their chords may deviate more than this from the surface (element sizes then grow
        as the square root of the curvature radius). With ``tolerance`` too, both hold."""),
    "bound": ("{'interval', 'lipschitz'}", """
        How a cell is proven free of the surface: interval arithmetic on the tape, or
        |f(centre)| > L * half-diagonal with ``lipschitz=L`` (for a field whose intervals
        are too loose; no tape pruning then)."""),
    "lipschitz": ("float, optional", """
        A Lipschitz constant of f over the bounds (|f(P) - f(Q)| <= L |P - Q|): required
        with bound='lipschitz', refused otherwise."""),
    "prune": ("bool", """
        Evaluate each cell's pruned tape; False evaluates the whole tape."""),
    "features": ("bool", """
        Sharp edges and corners placed by a quadratic error function; False places every
        loop vertex at its mass point projected onto the surface (smooth, chamfered)."""),
    "level": ("float, optional", """
        The iso-level: default 0, 0.5 for a bool volume; not with ``labels``."""),
    "inside": ("{'above', 'below'}", """
        Whether the samples above or below ``level`` are inside; 'above' with ``labels``."""),
    "labels": ('"all" or sequence of ints, optional', """
        Mesh the boundary of each label's region (the samples equal to it) instead of an
        iso-surface, for an integer volume: "all" takes every value but 0. Each label's
        surface is closed on its own (with ``cap``), interfaces between two labels appear
        once per label with opposite windings, and ``cell_refs["triangle"]`` holds the
        label of each triangle."""),
    "interfaces": ("{'separate', 'shared'}, optional", """
        With ``labels``: "separate" (default) gives each label its own closed surface;
        "shared" gives one surface (surface nets, :mod:`warpmesh.surface.multilabel`) in
        which each interface between two labels is meshed once, ``cell_refs["triangle"]``
        holding the lower label and ``cell_data["label_above"]["triangle"]`` the higher,
        each normal pointing from the lower label's side to the higher's; the samples not
        meshed (and, with ``cap``, the outside) are the rest, id 0, or min(labels) - 1
        when 0 is among ``labels`` (-1 for labels=[0, 3]). "shared" alone implies labels="all"; ``method`` and ``clearance`` are
        for marching cubes and do not apply to it."""),
    "smoothing": ("int", """
        With interfaces="shared": passes of constrained smoothing
        (:func:`warpmesh.optimize.label_smoothing.smooth_labels`): every vertex kept in
        its voxel cube, junction curves smoothed along themselves, no triangle crossing,
        turning over or folding. 0 (default) keeps the raw surface-nets vertices;
        VTK's ``contour_labels`` smooths with 16 by default."""),
    "spacing": ("float or (3,) floats", """
        The sample spacing: ``volume[i, j, k]`` sits at ``origin + (i, j, k) * spacing``
        (trilinear in between)."""),
    "origin": ("(3,) floats", """
        The position of ``volume[0, 0, 0]``."""),
    "clearance": ("float", """
        Linearly placed vertices are kept at least this fraction of their edge off the
        grid nodes, in [0, 0.5] (default 0.05): the surface is "dilated" off the nodes
        [FG §16.4.2] so no sliver appears where it passes near one. The connectivity does
        not change; a vertex moves at most ``clearance`` times its edge. The worst Q_K is
        then about 0.82 / clearance for "mc"/"mc33" and 1.1 / clearance for "mt" (16.4
        and 23.5 at 0.05, on cubic cells). 0 keeps only a 1e-3 clamp (slivers of any
        shape, vertices exactly on the interpolant). Roots refined by bisection or Newton
        stay on f = 0 and are not moved."""),
    "slab_voxels": ("int", """
        Samples per slab: the volume is processed in slabs of about this many samples
        along its first axis. "mc" and "mc33" on float32, uint8 and bool volumes (and
        labels) read the array in place, one bit per sample, the slabs cutting only the
        launches; other methods and dtypes convert each slab to float32 and weld the
        seams exactly, so their peak memory grows with the slab, not with the volume."""),
}
_ADAPTIVE_RESOLUTION = ("int, optional", """
        The finest level as a resolution, ``max_level = ceil(log2(resolution))``
        (``resolution=512`` means max_level=9); give this or ``max_level``, not both.""")


def _documented(cls):
    """Fill the class docstring's ``{parameters}`` with its fields, in order, and their defaults."""
    lines = []
    for f in dataclasses.fields(cls):
        kind, text = _ADAPTIVE_RESOLUTION if (cls.__name__, f.name) == ("AdaptiveOptions", "resolution") \
            else _FIELDS[f.name]
        default = "" if f.default is dataclasses.MISSING or f.default is None else f", default {f.default!r}"
        lines.append(f"    {f.name} : {kind}{default}")
        lines.extend("        " + line.strip() for line in text.strip("\n").splitlines())
    cls.__doc__ = cls.__doc__.replace("{parameters}", "\n".join(lines).strip())
    return cls


# -- the groups ------------------------------------------------------------------------------------
@dataclass(frozen=True, kw_only=True)
class _ShapeGrid:
    """The options of both pipelines that sample a shape on a uniform grid."""

    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    resolution: int | tuple[int, int, int] = DEFAULT_RESOLUTION
    method: Method = "mc33"
    root: RootMethod = "linear"
    root_iterations: int | None = None
    gradient: Gradient = "exact"
    normals: bool = False
    cap: bool = True
    evaluator: Evaluator = "auto"
    clearance: float = NODE_CLEARANCE

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "bounds", _bounds(self.bounds))
        set_(self, "clearance", check_clearance(self.clearance))
        check_choice(self.method, "method", METHODS)
        check_choice(self.evaluator, "evaluator", EVALUATORS)
        for name in ("cap", "normals"):
            set_(self, name, _flag(getattr(self, name), name))
        set_(self, "root_iterations", _roots(self.root, self.root_iterations, self.gradient, self.normals))
        cells = cells_of(self.resolution, _extent(self.bounds))
        check_float32_grid(self.bounds, cells)
        if self.cap and np.any(cells < 2):
            raise ValueError(f"expected at least 2 cells per axis to cap the surface (the boundary nodes are "
                             f"outside), got {cells.tolist()} from resolution={self.resolution!r}: raise "
                             "'resolution' or widen the thin side of 'bounds' (cap=False leaves the surface open)")
        set_(self, "resolution", int(self.resolution) if np.ndim(self.resolution) == 0 else
             tuple(int(v) for v in self.resolution))

    @property
    def cells(self) -> np.ndarray:
        """(3,) int64: cells per axis."""
        return cells_of(self.resolution, _extent(self.bounds))


@_documented
@dataclass(frozen=True, kw_only=True)
class GridOptions(_ShapeGrid):
    """Options of a shape meshed on a grid (``mesh_surface(shape, covering="grid")``, the default).

    Every block of 8^3 cells that interval arithmetic on the tape cannot cull is sampled,
    then triangulated cell by cell (one vertex per crossing edge, welded by construction).

    Parameters
    ----------
    {parameters}

    Raises
    ------
    ValueError, TypeError
        A value out of range or of the wrong type, naming the field; an option that the
        others make meaningless (``root_iterations`` with root='linear').

    Example
    -------
    >>> from warpmesh.surface.options import GridOptions
    >>> GridOptions(bounds=((-1, -1, -1), (1, 1, 1)), resolution=64, root="newton").cells.tolist()
    [64, 64, 64]
    """

    cull: bool = True

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "cull", _flag(self.cull, "cull"))


@_documented
@dataclass(frozen=True, kw_only=True)
class ContinuationOptions(_ShapeGrid):
    """Options of a shape meshed by continuation (``mesh_surface(shape, covering="continuation")``).

    The cells the surface crosses are grown from seed cells across the cell faces it
    crosses, and only their corners are evaluated (plus rays and intervals to find seeds):
    the same triangles as on the grid, far fewer evaluations
    (``mesh.info``). There is nothing to cull: it always runs as cull=True.

    Parameters
    ----------
    {parameters}

    Raises
    ------
    ValueError, TypeError
        As :class:`GridOptions`, and seeds that are not finite (m, 3) points.

    Example
    -------
    >>> from warpmesh.surface.options import ContinuationOptions
    >>> ContinuationOptions(bounds=((-1, -1, -1), (1, 1, 1)), seeds=[(0.5, 0, 0)]).seeds
    ((0.5, 0.0, 0.0),)
    """

    seeds: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self):
        super().__post_init__()
        if self.seeds is not None:
            pts = _vector(self.seeds, "seeds", "(m, 3) points")
            if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
                raise ValueError(f"expected 'seeds' as finite (m, 3) points, got shape {pts.shape}")
            object.__setattr__(self, "seeds", tuple(tuple(p) for p in pts.tolist()))


@_documented
@dataclass(frozen=True, kw_only=True)
class AdaptiveOptions:
    """Options of a shape meshed on an adaptive octree (``mesh_surface(shape, adaptive=True)``).

    Cells are culled by interval arithmetic on pruned per-cell tapes and refined where
    the surface is curved [FG §16.4.1], so evaluations follow the surface and triangle
    sizes its curvature; the surface is crack-free across leaves of different sizes by
    construction, with sharp edges and corners placed by a quadratic error function
    (:mod:`warpmesh.surface.adaptive.contour`). The octree extracts its own faces (no
    ``method``), evaluates with pruned tapes (no ``evaluator``), always culls, and
    stores no normals (``mesh.to_trimesh().vertex_normals`` gives them).

    Parameters
    ----------
    {parameters}

    Raises
    ------
    ValueError, TypeError
        A value out of range or of the wrong type, naming the field; two fields that say
        the same thing (``max_level`` and ``resolution``, ``tolerance`` and ``angles``).

    Example
    -------
    >>> from warpmesh.surface.options import AdaptiveOptions
    >>> a = AdaptiveOptions(bounds=((-1, -1, -1), (1, 1, 1)), resolution=512)
    >>> a.finest_level, a.relative_tolerance
    (9, 0.02)
    """

    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    max_level: int | None = None
    resolution: int | None = None
    min_level: int | None = None
    tolerance: float | None = None
    angles: tuple[float, float] | None = None
    chord: float | None = None
    bound: Bound = "interval"
    lipschitz: float | None = None
    root: RootMethod = "newton"
    root_iterations: int | None = None
    gradient: Gradient = "exact"
    cap: bool = True
    prune: bool = True
    features: bool = True

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "bounds", _bounds(self.bounds))
        for name in ("cap", "prune", "features"):
            set_(self, name, _flag(getattr(self, name), name))
        set_(self, "root_iterations", _roots(self.root, self.root_iterations, self.gradient, None))
        if self.max_level is not None and self.resolution is not None:
            raise ValueError("give 'max_level' or 'resolution' (its equivalent, 2**max_level), not both")
        if self.resolution is not None:
            if np.ndim(self.resolution) != 0:
                raise ValueError(f"expected one integer 'resolution' with adaptive=True, got {self.resolution!r}")
            cells_of(self.resolution, _extent(self.bounds))
            set_(self, "resolution", int(self.resolution))
        if self.max_level is not None:
            set_(self, "max_level", _integer(self.max_level, "max_level", 1, MAX_LEVEL))
        _integer(self.finest_level, "max_level", 1, MAX_LEVEL)  # from a resolution of 1
        ext = _extent(self.bounds)  # the finest cells: cubes, 2**finest_level along the longest side
        check_float32_grid(self.bounds, ext * 2.0**self.finest_level / ext.max())
        if self.min_level is not None:
            set_(self, "min_level", _integer(self.min_level, "min_level", 0, self.finest_level))
        if self.chord is not None:
            set_(self, "chord", _positive(self.chord, "chord"))
        if self.tolerance is not None:
            set_(self, "tolerance", _positive(self.tolerance, "tolerance"))
        if self.angles is not None:
            if self.tolerance is not None:
                raise ValueError("give 'tolerance' or 'angles', not both")
            if np.shape(self.angles) != (2,):
                raise ValueError(f"expected 'angles' as (eps1, eps2) in radians, got {self.angles!r}")
            set_(self, "angles", tuple(_positive(v, "angles") for v in self.angles))
        check_choice(self.bound, "bound", BOUNDS)
        if self.bound == "lipschitz":
            set_(self, "lipschitz", _positive(self.lipschitz, "lipschitz"))
        elif self.lipschitz is not None:
            raise ValueError("'lipschitz' applies to bound='lipschitz'")

    @property
    def finest_level(self) -> int:
        """``max_level``, or the level of ``resolution`` (of 128 when neither is given)."""
        if self.max_level is not None:
            return self.max_level
        res = DEFAULT_RESOLUTION if self.resolution is None else self.resolution
        return math.ceil(math.log2(int(cells_of(res, _extent(self.bounds)).max())))

    @property
    def relative_tolerance(self) -> float | None:
        """``tolerance``, or 0.02 when no tolerance of any kind is given."""
        if self.tolerance is None and self.chord is None and self.angles is None:
            return DEFAULT_TOLERANCE
        return self.tolerance


@_documented
@dataclass(frozen=True, kw_only=True)
class VolumeOptions:
    """Options of a sampled volume (``mesh_surface(array)``): an iso-surface or label surfaces.

    The samples ``volume[i, j, k]`` sit at ``origin + (i, j, k) * spacing``, trilinear in
    between; the volume is extracted slab by slab with exact block culling. Vertices are
    always placed by linear interpolation (the trilinear field is linear along grid
    edges: root='linear'), and there is no function to evaluate (no ``evaluator``, no
    ``normals``: compute them on the mesh).

    Parameters
    ----------
    {parameters}

    Raises
    ------
    ValueError, TypeError
        A value out of range or of the wrong type, naming the field; ``level`` or
        inside='below' with ``labels``. What depends on the array (its dtype, shape,
        values, the labels it holds) is checked by :func:`warpmesh.mesh_surface`.

    Example
    -------
    >>> from warpmesh.surface.options import VolumeOptions
    >>> VolumeOptions(spacing=0.5, labels=[3, 1]).spacing, VolumeOptions(labels=[3, 1]).labels
    ((0.5, 0.5, 0.5), (3, 1))
    """

    level: float | None = None
    inside: Inside = "above"
    labels: Literal["all"] | tuple[int, ...] | None = None
    interfaces: Literal["separate", "shared"] | None = None
    spacing: float | tuple[float, float, float] = 1.0
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    method: Method = "mc33"
    cap: bool = True
    cull: bool = True
    slab_voxels: int = SLAB_VOXELS
    clearance: float = NODE_CLEARANCE
    smoothing: int = 0

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "clearance", check_clearance(self.clearance))
        check_choice(self.method, "method", METHODS)
        if isinstance(self.smoothing, (bool, np.bool_)) or not isinstance(self.smoothing, (int, np.integer)) \
                or self.smoothing < 0:
            raise ValueError(f"expected a non-negative integer for 'smoothing', got {self.smoothing!r}")
        set_(self, "smoothing", int(self.smoothing))
        for name in ("cap", "cull"):
            set_(self, name, _flag(getattr(self, name), name))
        check_choice(self.inside, "inside", INSIDES)
        if self.level is not None:
            if not _is_number(self.level) or not math.isfinite(self.level):
                raise ValueError(f"expected a finite number for 'level', got {self.level!r}")
            set_(self, "level", float(self.level))
        if self.labels is not None:
            set_(self, "labels", label_form(self.labels))
            if self.level is not None or self.inside != "above":
                given = "'level'" if self.level is not None else f"inside={self.inside!r}"
                raise ValueError(f"{given} does not apply with 'labels' (each label's surface bounds the "
                                 "samples equal to it)")
        if self.interfaces is not None:
            check_choice(self.interfaces, "interfaces", INTERFACES)
            if self.labels is None and self.interfaces == "shared":
                if self.level is not None or self.inside != "above":
                    given = "'level'" if self.level is not None else f"inside={self.inside!r}"
                    raise ValueError(f"{given} does not apply with interfaces='shared' (it meshes the regions of "
                                     "a label volume)")
                set_(self, "labels", "all")
            elif self.labels is None:
                raise ValueError(f"'interfaces' applies with 'labels', got interfaces={self.interfaces!r} "
                                 "and no 'labels'")
        if self.interfaces == "shared":  # surface nets: marching cubes' options would be dropped unseen
            given = [f"{n}={getattr(self, n)!r}" for n in ("method", "clearance")
                     if getattr(self, n) != getattr(VolumeOptions, n)]
            if given:
                raise ValueError(f"{' and '.join(given)} {'does' if len(given) == 1 else 'do'} not apply with "
                                 "interfaces='shared' (surface nets, not marching cubes)")
        if self.smoothing and self.interfaces != "shared":
            raise ValueError(f"'smoothing' applies with interfaces='shared', got smoothing={self.smoothing} and "
                             f"interfaces={self.interfaces!r}")
        sp = _vector(self.spacing, "spacing", "a positive number or 3 positive numbers")
        sp = np.broadcast_to(sp, (3,)) if sp.ndim == 0 else sp
        if sp.shape != (3,) or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
            raise ValueError(f"expected 'spacing' as a positive number or 3 positive numbers, got {self.spacing!r}")
        if np.any(sp < FLOAT32_RANGE[0]) or np.any(sp > FLOAT32_RANGE[1]):
            raise ValueError(f"expected 'spacing' between {FLOAT32_RANGE[0]:g} and {FLOAT32_RANGE[1]:g} (cell volumes "
                             f"must stay normal numbers), got {self.spacing!r}: give the spacing in other units")
        set_(self, "spacing", tuple(sp.tolist()))
        org = _vector(self.origin, "origin", "3 finite numbers")
        if org.shape != (3,) or not np.all(np.isfinite(org)):
            raise ValueError(f"expected 'origin' as 3 finite numbers, got {self.origin!r}")
        if np.any(sp < 2.0**-36 * np.abs(org)):  # points are origin + index * spacing in float64
            raise ValueError(f"expected an 'origin' that float64 resolves at this spacing (|origin| below 2**36 "
                             f"spacings), got origin {org.tolist()} with spacing {sp.tolist()}: move the origin")
        set_(self, "origin", tuple(org.tolist()))
        if isinstance(self.slab_voxels, (bool, np.bool_)) or not isinstance(self.slab_voxels, (int, np.integer)) \
                or self.slab_voxels < 1:
            raise ValueError(f"expected a positive integer for 'slab_voxels', got {self.slab_voxels!r}")
        set_(self, "slab_voxels", int(self.slab_voxels))


#: any one of the groups: what ``mesh_surface(options=...)`` takes
SurfaceOptions = GridOptions | ContinuationOptions | AdaptiveOptions | VolumeOptions
