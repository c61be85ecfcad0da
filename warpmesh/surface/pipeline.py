"""Surface meshes of implicit shapes and sampled volumes (seed §16.4): the host pipeline.

validate -> build the grid -> cull blocks (interval arithmetic on the tape, or exact
block ranges of the volume) -> sample the surviving blocks -> marching cubes in kernels
(one vertex per crossing edge, welded by construction) -> optional root refinement on
the exact function -> host stage (numpy arrays, orientation check, statistics).

Example
-------
>>> import warpmesh as wm
>>> mesh = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=32)
>>> s = mesh.stats()
>>> s["watertight"], s["euler"]
(True, 2)
"""

from __future__ import annotations

import math
import time
import warnings
from typing import Literal

import numpy as np
import warp as wp

from warpmesh import _conventions as C
from warpmesh.surface.block_grid import GRADIENTS, METHODS, BlockGrid, gradients, refine_roots
from warpmesh.frep.codegen import EVALUATORS, Evaluator
from warpmesh.errors import WarpMeshError
from warpmesh.frep.expr import Expr
from warpmesh.kernels import block_grid as KB
from warpmesh.kernels import emit as KE
from warpmesh.mesh import Mesh
from warpmesh.frep.shapes import Shape
from warpmesh.frep.tape import tape_of
from warpmesh.surface.continuation import grow_cells
from warpmesh.surface.volume import SLAB_VOXELS, check_closed_outward, check_labels, extract_volume

Method = Literal["mc33", "mt", "mc"]
RootMethod = Literal["linear", "bisection", "newton"]
_ROOTS = ("linear", "bisection", "newton")
RAY_LINES = 32  # continuation's automatic seeds: rays along 32 grid lines per axis (every 8th at least)
MAX_RESOLUTION = 2048  # 2048^3 cells: 16.8 M blocks of 8^3, about 1 GB of block bookkeeping

def _check_bounds(bounds) -> tuple[np.ndarray, np.ndarray]:
    if bounds is None:
        raise ValueError("expected 'bounds' ((x0, y0, z0), (x1, y1, z1)) for a shape, got None")
    try:
        b = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"expected 'bounds' as ((x0, y0, z0), (x1, y1, z1)), got {bounds!r}") from None
    if b.shape != (2, 3):
        raise ValueError(f"expected 'bounds' of shape (2, 3), got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"expected finite 'bounds', got {b.tolist()}")
    if np.any(b[1] <= b[0]):
        raise ValueError(f"expected non-empty 'bounds' (lower < upper on every axis), got {b.tolist()}")
    return b[0], b[1]


def _check_resolution(resolution, extent: np.ndarray, cap: bool) -> np.ndarray:
    """Cells per axis: an int is the count along the longest side (cells near-cubic)."""
    cells = _cells(resolution, extent)
    if cap and np.any(cells < 2):
        raise ValueError(f"expected at least 2 cells per axis with cap=True (the boundary nodes are "
                         f"outside), got {cells.tolist()} from resolution={resolution!r}: raise "
                         "'resolution' or widen the thin side of 'bounds'")
    return cells


def _cells(resolution, extent: np.ndarray) -> np.ndarray:
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


def _refuse(*named, source: str, hint: str) -> None:
    """Options that do not apply to the source raise instead of being ignored."""
    given = [name for name, value in named if value is not None]
    if given:
        verb = "does" if len(given) == 1 else "do"
        raise ValueError(f"{', '.join(repr(g) for g in given)} {verb} not apply to {source} ({hint})")


def _check_choice(value, name: str, choices) -> None:
    if value not in choices:
        raise ValueError(f"Unknown {name} {value!r}. Pick one of {list(choices)}")


def _check_volume(volume, spacing, origin) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    vol = np.asarray(volume)
    if vol.ndim != 3:
        raise ValueError(f"expected a 3D array for 'volume', but got {vol.ndim}D with shape {vol.shape}")
    if min(vol.shape) < 2:
        raise ValueError(f"expected at least 2 samples per axis in 'volume', got shape {vol.shape}")
    if not (np.issubdtype(vol.dtype, np.number) or vol.dtype == np.bool_) or np.iscomplexobj(vol):
        raise TypeError(f"expected a real numeric 'volume', got dtype {vol.dtype}")
    sp = np.broadcast_to(np.asarray(spacing, dtype=np.float64), (3,)) if np.ndim(spacing) == 0 else \
        np.asarray(spacing, dtype=np.float64)
    if sp.shape != (3,) or not np.all(np.isfinite(sp)) or np.any(sp <= 0):
        raise ValueError(f"expected 'spacing' as a positive number or 3 positive numbers, got {spacing!r}")
    org = np.asarray(origin, dtype=np.float64)
    if org.shape != (3,) or not np.all(np.isfinite(org)):
        raise ValueError(f"expected 'origin' as 3 finite numbers, got {origin!r}")
    return vol, sp, org


# -- the pipeline -------------------------------------------------------------------------------
def mesh_surface(
    source,
    *,
    method: Method | None = None,
    covering: Literal["grid", "continuation"] = "grid",
    seeds=None,
    bounds=None,
    resolution: int | tuple[int, int, int] | None = None,
    level: float | None = None,
    inside: Literal["above", "below"] | None = None,
    labels=None,
    spacing=None,
    origin=None,
    root: RootMethod | None = None,
    root_iterations: int | None = None,
    gradient: Literal["exact", "central", "forward"] | None = None,
    cap: bool = True,
    cull: bool = True,
    slab_voxels: int | None = None,
    normals: bool = False,
    evaluator: Evaluator | None = None,
    adaptive: bool = False,
    max_level: int | None = None,
    min_level: int | None = None,
    tolerance: float | None = None,
    angles: tuple[float, float] | None = None,
    chord: float | None = None,
    bound: Literal["interval", "lipschitz"] | None = None,
    lipschitz: float | None = None,
    prune: bool | None = None,
    features: bool | None = None,
    device: str = C.DEFAULT_DEVICE,
) -> Mesh:
    """Triangulate the surface f = 0 of a shape, or an iso-surface of a sampled volume.

    Parameters
    ----------
    source : Shape, Expr or (nx, ny, nz) array
        A shape (f > 0 inside) or sampled values ``volume[i, j, k]`` at
        ``origin + (i, j, k) * spacing`` (trilinear in between).
    method : {'mc33', 'mt', 'mc'}, optional
        How each cell is triangulated (default "mc33"; not with ``adaptive``) (seed §16.4.2): "mc33" follows the topology of
        the trilinear interpolant of the corner values (asymptotic decider on faces,
        interior test for tunnels); "mt" splits every cube into 6 Kuhn tetrahedra
        (16 configurations, triangles and quadrilaterals split on shape: about 3x the
        triangles, the topology of the piecewise-linear interpolant); "mc" is the plain
        table (closed and manifold, but it separates the inside corners of every
        ambiguous face whatever the values say). All three give closed, 2-manifold,
        outward-oriented surfaces.
    covering : {'grid', 'continuation'}, shapes only
        "grid" samples every block that interval arithmetic cannot cull; "continuation"
        grows from seed cells across the cell faces the surface crosses and evaluates
        only the corners of crossed cells (plus rays to find seeds): the same triangles
        for every component it reaches, far fewer evaluations (``mesh.info``).
    seeds : (m, 3) points, continuation only
        Points in cells crossed by the surface to grow from. Default: found by casting
        rays along 32 grid lines per axis direction and transverse axis (every 8th line
        on grids up to 256 cells), which finds every component that one of those lines
        crosses; give a seed for smaller components.
    bounds : ((x0, y0, z0), (x1, y1, z1)), required for a shape
        The box sampled; the surface is closed (capped) on it when ``cap``.
    resolution : int or (3,) ints, shapes only
        Cells along the longest side of ``bounds`` (near-cubic cells), or per axis;
        default 128.
    level : float, volumes only
        The iso-level (default 0; 0.5 for a bool volume).
    inside : {'above', 'below'}, volumes only
        Whether values above (default) or below ``level`` are inside.
    labels : "all" or sequence of ints, integer volumes only
        Mesh the boundary of each label's region (the samples equal to it) instead of an
        iso-surface: "all" takes every value but 0. Each label's surface is closed on its
        own (with ``cap=True``) (interfaces between two labels appear once per label, with opposite
        windings); ``mesh.cell_refs["triangle"]`` holds the label of each triangle.
    spacing, origin : float or (3,) floats, volumes only
        The sample spacing (default 1) and the position of ``volume[0, 0, 0]`` (default 0).
    root : {'linear', 'bisection', 'newton'}, optional
        Vertex placement on a crossing edge: linear interpolation (eq. 16.12), bisection
        or safeguarded Newton on the exact function (§16.3.3; shapes only). Default
        "linear", and "newton" with ``adaptive`` (large leaves make linear roots poor).
    root_iterations : int, optional
        Iterations of bisection (default 12) or safeguarded Newton (default 10).
    gradient : {'exact', 'central', 'forward'}, optional
        How Newton (``root='newton'``) and ``normals`` get grad f: exact forward-mode
        differentiation of the tape (default), or finite differences of f alone with a
        step of 1/100 of the cell size, centred (eq. 16.14, error O(h^2), 6 extra
        evaluations per point) or forward (eq. 16.13, O(h), 3 extra).
    cap : bool
        Treat the grid boundary as outside, so every surface is closed on the bounds.
    cull : bool
        Skip blocks of 8³ cells that cannot hold the surface (interval arithmetic for
        shapes, exact block ranges for volumes). The mesh is the same either way.
    slab_voxels : int, volumes only
        Samples per slab: a volume is processed in slabs of about this many samples
        along its first axis (default 16 M), whose seams are welded exactly; peak memory
        grows with the slab, not with the volume.
    normals : bool
        Shapes only: store outward unit normals (-∇f / |∇f|) as ``point_data["normals"]``.
    evaluator : {'auto', 'interpreter', 'compiled'}, shapes only
        Evaluate with the tape interpreter, or with a kernel generated for the shape's
        structure (2x faster; about 1.5 s to compile once per structure, cached on disk;
        constants can change freely). "auto" (default) never waits for a compile: it
        interprets until a background compile, started when a structure comes back for
        a second large run, is ready. ``mesh.info["evaluator"]`` says which ran.
    adaptive : bool, shapes only
        Mesh on an adaptive octree (seed §16.4.1, :mod:`warpmesh.surface.adaptive.octree`): cells are
        culled by interval arithmetic on pruned per-cell tapes and refined where the
        surface is curved, so evaluations follow the surface and triangle sizes follow
        its curvature; the surface is crack-free across leaves of different sizes by
        construction, with sharp edges and corners placed by a quadratic error function
        (:mod:`warpmesh.surface.adaptive.contour`). ``mesh.info`` holds cells per level, tape
        lengths, ``evaluations`` and the dense grid's count, culled fraction, timings.
    max_level : int, adaptive only
        Finest level: 2**max_level cells along the longest side (the resolution
        equivalent; ``resolution=512`` means max_level=9). Default from ``resolution``
        (128).
    min_level : int, adaptive only
        Cells are refined at least to this level (default min(5, max_level)).
    tolerance : float, adaptive only
        The relative chord tolerance epsilon of §16.2.2 (delta <= epsilon h), default
        0.02: the planarity and divergence angles of the refinement are 4 epsilon.
    angles : (eps1, eps2), adaptive only
        The planarity and divergence angles in radians, instead of ``tolerance``.
    chord : float, adaptive only
        An absolute chord tolerance (in the units of ``bounds``) instead of the relative
        one: cells are refined while their chords may deviate more than this from the
        surface (element sizes then grow as the square root of the curvature radius:
        the fewest triangles for a given maximum distance). With ``tolerance`` too,
        both hold.
    bound : {'interval', 'lipschitz'}, adaptive only
        How a cell is proven free of the surface: interval arithmetic on the tape
        (default), or |f(centre)| > L * half-diagonal with ``lipschitz=L`` (for a field
        whose intervals are too loose; no tape pruning then).
    lipschitz : float, with bound='lipschitz'
        A Lipschitz constant of f over the bounds (|f(P) - f(Q)| <= L |P - Q|).
    prune : bool, adaptive only
        Evaluate each cell's pruned tape (default True); False evaluates the whole tape.
    features : bool, adaptive only
        Sharp edges and corners (default True); False places every loop vertex at its
        mass point projected onto the surface (smooth, chamfered edges).
    device : str
        Warp device ("cpu" or "cuda").

    Returns
    -------
    Mesh
        ``mesh.cells["triangle"]`` oriented outward (towards f < 0); where caps close
        the surface on the bounds, ``mesh.cell_refs["triangle"]`` is 2 on the caps and 1
        on the surface f = 0 (no refs when nothing was capped); ``mesh.info`` holds timings per stage and counts
        (``mesh.stats()`` shows them).

    Raises
    ------
    ValueError, TypeError
        Bad arguments, NaN / infinite values, a constant volume.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> g = np.linspace(-1, 1, 40)
    >>> vol = 0.8 - np.sqrt(g[:, None, None]**2 + g[None, :, None]**2 + g[None, None, :]**2)
    >>> m = wm.mesh_surface(vol, spacing=g[1] - g[0], origin=(-1, -1, -1))
    >>> m.stats()["euler"]
    2
    """
    t_start = time.perf_counter()
    if not isinstance(adaptive, (bool, np.bool_)):
        raise TypeError(f"expected True or False for 'adaptive', got {adaptive!r}")
    if adaptive:
        return _mesh_adaptive(source, locals(), t_start)
    _refuse(("max_level", max_level), ("min_level", min_level), ("tolerance", tolerance), ("angles", angles),
            ("chord", chord), ("bound", bound), ("lipschitz", lipschitz), ("prune", prune), ("features", features),
            source="a grid", hint="they configure adaptive=True")
    method = "mc33" if method is None else method
    root = "linear" if root is None else root
    _check_choice(method, "method", METHODS)
    _check_choice(covering, "covering", COVERINGS)
    if seeds is not None and covering != "continuation":
        raise ValueError(f"'seeds' applies to covering='continuation', got covering={covering!r}")
    _check_choice(root, "root", _ROOTS)
    if evaluator is not None:
        _check_choice(evaluator, "evaluator", EVALUATORS)
    for name, flag in (("cap", cap), ("cull", cull), ("normals", normals)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"expected True or False for '{name}', got {flag!r}")
    if gradient is not None:
        _check_choice(gradient, "gradient", GRADIENTS)
        if root != "newton" and not normals:
            raise ValueError(f"'gradient' applies to root='newton' or normals=True, got root={root!r} "
                             "and normals=False")
    gradient = gradient or "exact"
    if root_iterations is not None:
        if root == "linear":
            raise ValueError("'root_iterations' applies to root='bisection' or 'newton', not 'linear'")
        if isinstance(root_iterations, bool) or not isinstance(root_iterations, (int, np.integer)) \
                or not 1 <= root_iterations <= 64:
            raise ValueError(f"expected 1 <= 'root_iterations' <= 64, got {root_iterations!r}")
    device = wp.get_device(device)
    cap_mask = KB.ALL_FACES if cap else 0
    cell_mask = None
    timings: dict[str, float] = {}
    info: dict = {"method": method, "root": root, "device": str(device)}

    if isinstance(source, (Shape, Expr)):
        _refuse(("level", level), ("inside", inside), ("spacing", spacing), ("origin", origin),
                ("labels", labels), ("slab_voxels", slab_voxels), source="a shape",
                hint="they describe sampled volumes")
        evaluator = evaluator or "auto"
        lo, hi = _check_bounds(bounds)
        cells = _check_resolution(128 if resolution is None else resolution, hi - lo, cap)
        h = (hi - lo) / cells
        tape = tape_of(source)
        timings["compile"] = time.perf_counter() - t_start
        grid = BlockGrid(cells + 1, lo, h, device)
        if covering == "continuation":
            cell_mask = _grow(grid, tape, seeds, cap, evaluator, timings, info)
        else:
            grid.cull_shape(tape, cull, cap_mask, timings)
            grid.sample_shape(tape, cull, evaluator, timings)
        info["tape_length"] = len(tape)
    elif isinstance(source, np.ndarray) or hasattr(source, "__array__"):
        _refuse(("bounds", bounds), ("resolution", resolution), ("evaluator", evaluator), source="a volume",
                hint="a volume's grid is its samples, and there is no function to evaluate")
        if covering != "grid":
            raise ValueError("covering='continuation' saves evaluations of a shape's function; a volume's "
                             "samples are all given: use covering='grid'")
        if root != "linear":
            raise ValueError(f"root={root!r} needs the exact function of a shape; a volume's "
                             "trilinear field is linear along grid edges: use root='linear'")
        if normals:
            raise ValueError("normals=True needs a shape; compute them on the mesh for a volume")
        if labels is not None:
            _refuse(("level", level), ("inside", inside), source="labels",
                    hint="each label's surface bounds the samples equal to it")
            level, inside = 0.5, "above"
        if slab_voxels is not None and (isinstance(slab_voxels, bool) or not isinstance(
                slab_voxels, (int, np.integer)) or slab_voxels < 1):
            raise ValueError(f"expected a positive integer for 'slab_voxels', got {slab_voxels!r}")
        slab_voxels = SLAB_VOXELS if slab_voxels is None else int(slab_voxels)
        if level is None:  # a bool volume's surface sits halfway between False and True samples
            level = 0.5 if np.asarray(source).dtype == np.bool_ else 0.0
        inside = "above" if inside is None else inside
        _check_choice(inside, "inside", ("above", "below"))
        vol, sp, org = _check_volume(source, 1.0 if spacing is None else spacing,
                                     (0.0, 0.0, 0.0) if origin is None else origin)
        if isinstance(level, (bool, np.bool_)) or not isinstance(level, (int, float, np.integer, np.floating)) \
                or not math.isfinite(level):
            raise ValueError(f"expected a finite number for 'level', got {level!r}")
        if cap and min(vol.shape) < 3:
            raise ValueError(f"expected at least 3 samples per axis in 'volume' with cap=True (the "
                             f"boundary samples are outside), got shape {vol.shape}")
        return _mesh_volume(vol, org, sp, float(level), 1.0 if inside == "above" else -1.0, labels, method, cap,
                            cull, device, slab_voxels, timings, info, t_start)
    else:
        raise TypeError(f"expected a Shape, an expression or a 3D array for 'source', got {type(source).__name__}")

    grid.finish_values(cap_mask, timings)
    verts, tris, edges = grid.extract(method, cap_mask, timings, cell_mask)
    if cell_mask is not None:  # continuation: drop the vertices of edges on no grown cell first
        verts, tris, edges = _drop_unused(verts, tris, edges)
    if tape is not None and root != "linear" and len(verts):
        refine_roots(tape, verts, edges, grid.worigin, root, root_iterations, timings, evaluator,
                     gradient, grid.h)

    t0 = time.perf_counter()
    point_data = {}
    if normals and tape is not None and len(verts):
        point_data["normals"] = _vertex_normals(tape, grid, verts, edges, cap, gradient)
    points = verts.numpy().astype(C.REAL_DTYPE) + grid.origin  # sync point: results to the host
    faces = tris.numpy().astype(C.INDEX_DTYPE)
    if len(faces) and faces.min() < 0:
        raise WarpMeshError("a block culled as uniform holds a crossing edge: the interval bound "
                            "of the shape is wrong; mesh with cull=False and report the shape")
    if cap and len(faces):  # closed by construction: outward winding encloses a positive volume
        if not grid.info["signed_volume"] > 0.0:
            raise WarpMeshError(f"the capped surface encloses a signed volume of {grid.info['signed_volume']:g}: "
                                "its triangles do not face outward (an internal error: please report it)")
        info["orientation"] = "outward (closed, positive enclosed volume)"
    refs = _surface_refs(edges, faces) if cap and len(faces) else None
    cell_refs = {"triangle": refs} if refs is not None and np.any(refs == CAP_REF) else None
    info.update(grid.info)
    info["vertices"], info["triangles"] = len(points), len(faces)
    if len(faces) == 0:
        warnings.warn("the surface does not cross the sampled grid: the mesh is empty "
                      "(check 'bounds', 'level' and the sign convention f > 0 inside)", stacklevel=2)
    timings["host"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return Mesh(points, {"triangle": faces}, point_data=point_data or None, cell_refs=cell_refs, info=info)


SURFACE_REF, CAP_REF = 1, 2


def _surface_refs(edges: dict, faces: np.ndarray) -> np.ndarray:
    """Triangle refs: CAP_REF where all three vertices sit on edges ending at a capped
    grid-boundary node (the closing caps on the bounds), SURFACE_REF elsewhere."""
    capped = (edges["flags"].numpy() & 4) != 0
    return np.where(capped[faces].all(axis=1), CAP_REF, SURFACE_REF).astype(C.INDEX_DTYPE)


def _vertex_normals(tape, grid: BlockGrid, verts, edges: dict, cap: bool, gradient: str) -> np.ndarray:
    """Outward unit normals: -grad f / |grad f| on the surface; on the caps, the outward
    normal of the face of the bounds they close (the nearest one)."""
    world = wp.empty_like(verts)
    wp.launch(KE.edge_points_kernel, dim=len(verts), inputs=[edges["t"], edges["p0"], edges["p1"], grid.worigin],
              outputs=[world], device=grid.device)
    fg = wp.empty(len(verts), dtype=wp.vec4, device=grid.device)
    g = gradients(tape, world, fg, gradient, grid.h).numpy()[:, 1:].astype(np.float64)
    norm = np.linalg.norm(g, axis=1, keepdims=True)
    normals = -g / np.where(norm > 0, norm, 1.0)
    if cap:
        on_cap = (edges["flags"].numpy() & 4) != 0
        local = verts.numpy()[on_cap].astype(np.float64)  # grid-local: the box is [0, extent]
        extent = (grid.n - 1) * grid.h
        gap = np.minimum(local, extent - local) / grid.h
        axis = np.argmin(gap, axis=1)
        rows = np.arange(len(local))
        face_normal = np.zeros_like(local)
        face_normal[rows, axis] = np.where(local[rows, axis] < 0.5 * extent[axis], -1.0, 1.0)
        normals[on_cap] = face_normal
    return normals


def _mesh_volume(vol, org, sp, level, sign, labels, method, cap, cull, device, slab_voxels, timings, info,
                 t_start) -> Mesh:
    """The volume pipeline: one extraction per label (or one at ``level``), slab by slab."""
    fields = [None] if labels is None else list(check_labels(labels, vol))
    parts, n_verts = [], 0
    for label in fields:
        points, faces, flags, (vmin, vmax) = extract_volume(
            vol, org, sp, level=level, sign=sign, method=method, cap=cap, cull=cull, device=device,
            slab_voxels=slab_voxels, label=label, timings=timings, info=info)
        if label is None and vmin == vmax:
            raise ValueError(f"expected a non-constant 'volume', got every value equal to {sign * vmin + level}")
        if label is None and not vmin <= 0.0 <= vmax:
            lo_v, hi_v = sorted((sign * vmin + level, sign * vmax + level))
            raise ValueError(f"expected 'level' within the volume's range [{lo_v}, {hi_v}], got {level}")
        if label is not None and vmax <= 0.0:
            raise ValueError(f"expected label {label} in 'volume', got no sample equal to it")
        if cap and len(faces):
            info["enclosed_volume"] = info.get("enclosed_volume", 0.0) + check_closed_outward(points, faces)
            info["orientation"] = "outward (closed, positive enclosed volume)"
        capped = (flags & 4) != 0
        refs = np.where(capped[faces].all(axis=1), CAP_REF, SURFACE_REF) if label is None else \
            np.full(len(faces), label)
        faces += n_verts
        parts.append((points, faces, refs.astype(C.INDEX_DTYPE)))
        n_verts += len(points)
    if len(parts) == 1:  # no copy of the whole output
        points, faces, refs = parts.pop()
    else:
        points, faces, refs = (np.concatenate([p[k] for p in parts]) for k in range(3))
    keep_refs = labels is not None or (cap and np.any(refs == CAP_REF))
    info["evaluations"] = 0
    info["vertices"], info["triangles"] = len(points), len(faces)
    if labels is not None:
        info["labels"] = [int(v) for v in fields]
    if len(faces) == 0:
        warnings.warn("the surface does not cross the sampled grid: the mesh is empty "
                      "(check 'level' and 'inside')", stacklevel=3)
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return Mesh(points, {"triangle": faces}, cell_refs={"triangle": refs} if keep_refs else None, info=info)


COVERINGS = ("grid", "continuation")


def _grow(grid: BlockGrid, tape, seeds, cap: bool, evaluator, timings, info):
    """Continuation covering-up: grow the crossed cells from seeds (warpmesh.surface.continuation),
    then load them into the block grid. Returns the mask of the grown cells."""
    t0 = time.perf_counter()
    seed_cells = None
    if seeds is not None:
        seed_cells = _seed_cells(grid, tape, seeds, cap, evaluator)
    try:
        growth = grow_cells(lambda ids: grid.node_values(tape, ids, evaluator), tuple(int(v) for v in grid.n),
                            seeds=seed_cells, ray_stride=None if seeds is not None else _ray_stride(grid.n), cap=cap)
    except ValueError as exc:
        if "'evaluate'" in str(exc):  # the callback is ours: say what the user can change
            raise ValueError(NAN_MESSAGE) from None
        raise
    timings["evaluate"] = time.perf_counter() - t0
    mask = grid.load_cells(growth.cells, growth.node_ids, growth.node_values)
    info.update(evaluations=growth.evaluations, ray_evaluations=growth.ray_evaluations, waves=growth.waves,
                seed_cells=growth.seeds, grown_cells=len(growth.cells), components_grown=growth.components,
                interval_evaluations=0)
    timings["load"] = time.perf_counter() - t0 - timings["evaluate"]
    return mask


NAN_MESSAGE = ("the shape evaluates to NaN or infinity at grid nodes inside 'bounds' (e.g. sqrt/log of a "
               "negative or a division by zero); change the expression or the bounds")


def _seed_cells(grid: BlockGrid, tape, seeds, cap: bool, evaluator) -> np.ndarray:
    """The cells to grow from: per seed point, the crossed cells among those whose closure
    holds it (up to 8 when it lies on a cell face, edge or node)."""
    try:
        pts = np.asarray(seeds, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"expected 'seeds' as (m, 3) points, got {seeds!r}") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.all(np.isfinite(pts)):
        raise ValueError(f"expected 'seeds' as finite (m, 3) points, got shape {pts.shape}")
    lo, hi = grid.origin, grid.origin + (grid.n - 1) * grid.h
    outside = np.any((pts < lo) | (pts > hi), axis=1)
    if outside.any():
        raise ValueError(f"expected 'seeds' inside 'bounds', got {pts[outside][0].tolist()}")
    cells = grid.n - 1
    x = (pts - lo) / grid.h
    base = np.floor(x).astype(np.int64)
    on = x == base  # on a cell boundary along that axis: the cell below holds it too
    candidates = []
    for corner in range(8):
        d = np.array([(corner >> a) & 1 for a in range(3)])
        ijk = base - d
        ok = np.all((d == 0) | on, axis=1) & np.all((ijk >= 0) & (ijk < cells), axis=1)
        candidates.append(np.where(ok, ijk[:, 0] + cells[0] * (ijk[:, 1] + cells[1] * ijk[:, 2]), -1))
    cand = np.stack(candidates, axis=1)  # (m, 8), -1 where no cell
    flat = np.unique(cand[cand >= 0])
    ci = np.stack([flat % cells[0], flat // cells[0] % cells[1], flat // (cells[0] * cells[1])], axis=1)
    corner_ids = [(ci[:, 0] + (c & 1)) + grid.n[0] * ((ci[:, 1] + ((c >> 1) & 1)) + grid.n[1] *
                                                      (ci[:, 2] + ((c >> 2) & 1))) for c in range(8)]
    nodes = np.unique(np.concatenate(corner_ids))
    inside_node = grid.node_values(tape, nodes, evaluator) > 0
    if cap:  # capped: boundary nodes are outside
        g = np.stack([nodes % grid.n[0], nodes // grid.n[0] % grid.n[1], nodes // (grid.n[0] * grid.n[1])], axis=1)
        inside_node &= ~np.any((g == 0) | (g == grid.n - 1), axis=1)
    inside = np.stack([inside_node[np.searchsorted(nodes, ids)] for ids in corner_ids], axis=1)
    crossed = flat[inside.any(axis=1) & ~inside.all(axis=1)]
    hit = (cand >= 0) & np.isin(cand, crossed)
    if not hit.any(axis=1).all():
        bad = pts[~hit.any(axis=1)][0].tolist()
        raise ValueError(f"expected 'seeds' in cells crossed by the surface, got {bad}: no cell holding it "
                         "has corners on both sides; give a point on or next to the surface")
    return np.unique(cand[hit])


def _ray_stride(n_nodes) -> int:
    """Grid lines between seed rays: the rays cost O(n) evaluations per line family, below
    the O(n^2) of the surface itself."""
    return int(max(8, int(np.max(n_nodes)) // RAY_LINES))


def _drop_unused(verts, tris, edges):
    """Keep the vertices the triangles use (renumbered in order), before any root
    refinement or normal evaluation spends work on the others."""
    faces = tris.numpy()  # sync point
    kept = np.unique(faces)
    remap = np.full(verts.shape[0], -1, dtype=np.int32)
    remap[kept] = np.arange(len(kept), dtype=np.int32)
    dev = verts.device

    def sub(arr):
        return wp.array(arr.numpy()[kept], dtype=arr.dtype, device=dev)

    return sub(verts), wp.array(remap[faces], dtype=wp.vec3i, device=dev), {k: sub(v) for k, v in edges.items()}

def _positive_number(value, name: str) -> float:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise ValueError(f"expected a positive finite number for '{name}', got {value!r}")
    return float(value)


def _level(value, name: str, low: int, high: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
        raise ValueError(f"expected an integer {low} <= '{name}' <= {high}, got {value!r}")
    return int(value)


def _mesh_adaptive(source, a: dict, t_start: float) -> Mesh:
    """mesh_surface(adaptive=True): validate the options, run :func:`warpmesh.surface.adaptive.pipeline.mesh_adaptive`."""
    from warpmesh.surface.adaptive.pipeline import mesh_adaptive

    if not isinstance(source, (Shape, Expr)):
        raise TypeError(f"adaptive=True meshes a Shape or an expression (it evaluates the function where "
                        f"it needs it), got {type(source).__name__} for 'source'")
    _refuse(("method", a["method"]), ("seeds", a["seeds"]), ("level", a["level"]), ("inside", a["inside"]),
            ("labels", a["labels"]), ("spacing", a["spacing"]), ("origin", a["origin"]),
            ("slab_voxels", a["slab_voxels"]), ("evaluator", a["evaluator"]), source="adaptive=True",
            hint="the octree extracts its own faces and evaluates with pruned tapes")
    if a["covering"] != "grid":
        raise ValueError(f"adaptive=True is its own covering-up; got covering={a['covering']!r}")
    if a["normals"]:
        raise ValueError("normals=True is not available with adaptive=True (use mesh.to_trimesh().vertex_normals)")
    if not a["cull"]:
        raise ValueError("cull=False does not apply to adaptive=True (culling is what the octree does)")
    for name in ("cap", "prune", "features"):
        if a[name] is not None and not isinstance(a[name], (bool, np.bool_)):
            raise TypeError(f"expected True or False for '{name}', got {a[name]!r}")
    root = "newton" if a["root"] is None else a["root"]
    _check_choice(root, "root", _ROOTS)
    gradient = a["gradient"] or "exact"
    _check_choice(gradient, "gradient", GRADIENTS)
    iterations = a["root_iterations"]
    if iterations is not None and (root == "linear" or isinstance(iterations, bool)
                                   or not isinstance(iterations, (int, np.integer)) or not 1 <= iterations <= 64):
        raise ValueError(f"expected 1 <= 'root_iterations' <= 64 with root='bisection' or 'newton', "
                         f"got {iterations!r} with root={root!r}")
    lo, hi = _check_bounds(a["bounds"])
    if a["max_level"] is not None and a["resolution"] is not None:
        raise ValueError("give 'max_level' or 'resolution' (its equivalent, 2**max_level), not both")
    if a["max_level"] is None:
        res = 128 if a["resolution"] is None else a["resolution"]
        if np.ndim(res) != 0:
            raise ValueError(f"expected one integer 'resolution' with adaptive=True, got {res!r}")
        max_level = int(math.ceil(math.log2(int(_cells(res, hi - lo).max()))))
    else:
        max_level = a["max_level"]
    max_level = _level(max_level, "max_level", 1, 18)
    min_level = None if a["min_level"] is None else _level(a["min_level"], "min_level", 0, max_level)
    chord = None if a["chord"] is None else _positive_number(a["chord"], "chord")
    tolerance = (0.02 if chord is None and a["angles"] is None else None) if a["tolerance"] is None \
        else _positive_number(a["tolerance"], "tolerance")
    angles = a["angles"]
    if angles is not None:
        if a["tolerance"] is not None:
            raise ValueError("give 'tolerance' or 'angles', not both")
        if np.shape(angles) != (2,):
            raise ValueError(f"expected 'angles' as (eps1, eps2) in radians, got {angles!r}")
        angles = tuple(_positive_number(v, "angles") for v in angles)
    bound = "interval" if a["bound"] is None else a["bound"]
    _check_choice(bound, "bound", ("interval", "lipschitz"))
    lipschitz = a["lipschitz"]
    if bound == "lipschitz":
        lipschitz = _positive_number(lipschitz, "lipschitz")
    elif lipschitz is not None:
        raise ValueError("'lipschitz' applies to bound='lipschitz'")
    device = wp.get_device(a["device"])
    timings: dict[str, float] = {}
    info: dict = {"covering": "octree", "root": root, "device": str(device), "tolerance": tolerance, "chord": chord,
                  "bound": bound}
    tape = tape_of(source)
    info["tape_length"] = len(tape)
    points, faces, refs = mesh_adaptive(
        tape, lo, hi, max_level=max_level, min_level=min_level, tolerance=tolerance, angles=angles, chord=chord,
        bound=bound, lipschitz=lipschitz, cap=bool(a["cap"]), prune=a["prune"] is not False,
        features=a["features"] is not False, root=root, root_iterations=iterations, gradient=gradient,
        device=device, timings=timings, info=info)
    if len(faces) == 0:
        warnings.warn("the surface does not cross the bounds: the mesh is empty "
                      "(check 'bounds' and the sign convention f > 0 inside)", stacklevel=3)
    info["vertices"], info["triangles"] = len(points), len(faces)
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    cell_refs = {"triangle": refs} if refs is not None else None
    return Mesh(points.astype(C.REAL_DTYPE), {"triangle": faces.astype(C.INDEX_DTYPE)}, cell_refs=cell_refs,
                info=info)
