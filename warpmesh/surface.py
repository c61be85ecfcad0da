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
from warpmesh.block_grid import BlockGrid, refine_roots
from warpmesh.codegen import EVALUATORS, Evaluator
from warpmesh.errors import WarpMeshError
from warpmesh.expr import Expr
from warpmesh.kernels import marching_cubes as K
from warpmesh.mesh import Mesh
from warpmesh.shapes import Shape
from warpmesh.tape import eval_gradients, tape_of

RootMethod = Literal["linear", "bisection", "newton"]
_ROOTS = ("linear", "bisection", "newton")
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
    bounds=None,
    resolution: int | tuple[int, int, int] | None = None,
    level: float | None = None,
    inside: Literal["above", "below"] | None = None,
    spacing=None,
    origin=None,
    root: RootMethod = "linear",
    root_iterations: int | None = None,
    cap: bool = True,
    cull: bool = True,
    normals: bool = False,
    evaluator: Evaluator | None = None,
    device: str = C.DEFAULT_DEVICE,
) -> Mesh:
    """Triangulate the surface f = 0 of a shape, or an iso-surface of a sampled volume.

    Parameters
    ----------
    source : Shape, Expr or (nx, ny, nz) array
        A shape (f > 0 inside) or sampled values ``volume[i, j, k]`` at
        ``origin + (i, j, k) * spacing`` (trilinear in between).
    bounds : ((x0, y0, z0), (x1, y1, z1)), required for a shape
        The box sampled; the surface is closed (capped) on it when ``cap``.
    resolution : int or (3,) ints, shapes only
        Cells along the longest side of ``bounds`` (near-cubic cells), or per axis;
        default 128.
    level : float, volumes only
        The iso-level (default 0).
    inside : {'above', 'below'}, volumes only
        Whether values above (default) or below ``level`` are inside.
    spacing, origin : float or (3,) floats, volumes only
        The sample spacing (default 1) and the position of ``volume[0, 0, 0]`` (default 0).
    root : {'linear', 'bisection', 'newton'}
        Vertex placement on a crossing edge: linear interpolation (eq. 16.12), bisection
        or safeguarded Newton on the exact function (§16.3.3; shapes only).
    root_iterations : int, optional
        Iterations of bisection (default 12) or safeguarded Newton (default 10).
    cap : bool
        Treat the grid boundary as outside, so every surface is closed on the bounds.
    cull : bool
        Skip blocks of 8³ cells that cannot hold the surface (interval arithmetic for
        shapes, exact block ranges for volumes). The mesh is the same either way.
    normals : bool
        Shapes only: store outward unit normals (-∇f / |∇f|) as ``point_data["normals"]``.
    evaluator : {'auto', 'interpreter', 'compiled'}, shapes only
        Evaluate with the tape interpreter, or with a kernel generated for the shape's
        structure (2x faster; about 1.5 s to compile once per structure, cached on disk;
        constants can change freely). "auto" (default) never waits for a compile: it
        interprets until a background compile, started when a structure comes back for
        a second large run, is ready. ``mesh.info["evaluator"]`` says which ran.
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
    _check_choice(root, "root", _ROOTS)
    if evaluator is not None:
        _check_choice(evaluator, "evaluator", EVALUATORS)
    for name, flag in (("cap", cap), ("cull", cull), ("normals", normals)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"expected True or False for '{name}', got {flag!r}")
    if root_iterations is not None:
        if root == "linear":
            raise ValueError("'root_iterations' applies to root='bisection' or 'newton', not 'linear'")
        if isinstance(root_iterations, bool) or not isinstance(root_iterations, (int, np.integer)) \
                or not 1 <= root_iterations <= 64:
            raise ValueError(f"expected 1 <= 'root_iterations' <= 64, got {root_iterations!r}")
    device = wp.get_device(device)
    timings: dict[str, float] = {}
    info: dict = {"method": "mc", "root": root, "device": str(device)}

    if isinstance(source, (Shape, Expr)):
        _refuse(("level", level), ("inside", inside), ("spacing", spacing), ("origin", origin),
                source="a shape", hint="they describe sampled volumes")
        evaluator = evaluator or "auto"
        lo, hi = _check_bounds(bounds)
        cells = _check_resolution(128 if resolution is None else resolution, hi - lo, cap)
        h = (hi - lo) / cells
        tape = tape_of(source)
        timings["compile"] = time.perf_counter() - t_start
        grid = BlockGrid(cells + 1, lo, h, device)
        grid.cull_shape(tape, cull, cap, timings)
        grid.sample_shape(tape, cull, evaluator, timings)
        info["tape_length"] = len(tape)
    elif isinstance(source, np.ndarray) or hasattr(source, "__array__"):
        _refuse(("bounds", bounds), ("resolution", resolution), ("evaluator", evaluator), source="a volume",
                hint="a volume's grid is its samples, and there is no function to evaluate")
        if root != "linear":
            raise ValueError(f"root={root!r} needs the exact function of a shape; a volume's "
                             "trilinear field is linear along grid edges: use root='linear'")
        if normals:
            raise ValueError("normals=True needs a shape; compute them on the mesh for a volume")
        level = 0.0 if level is None else level
        inside = "above" if inside is None else inside
        _check_choice(inside, "inside", ("above", "below"))
        vol, sp, org = _check_volume(source, 1.0 if spacing is None else spacing,
                                     (0.0, 0.0, 0.0) if origin is None else origin)
        if not isinstance(level, (int, float, np.integer, np.floating)) or not math.isfinite(level):
            raise ValueError(f"expected a finite number for 'level', got {level!r}")
        if cap and min(vol.shape) < 3:
            raise ValueError(f"expected at least 3 samples per axis in 'volume' with cap=True (the "
                             f"boundary samples are outside), got shape {vol.shape}")
        grid = BlockGrid(np.array(vol.shape), org, sp, device)
        grid.cull_volume(vol, float(level), 1.0 if inside == "above" else -1.0, cull, cap, timings)
        tape = None
    else:
        raise TypeError(f"expected a Shape, an expression or a 3D array for 'source', got {type(source).__name__}")

    grid.finish_values(cap, timings)
    verts, tris, edges = grid.extract(timings)
    if tape is not None and root != "linear" and len(verts):
        refine_roots(tape, verts, edges, grid.worigin, root, root_iterations, timings, evaluator)

    t0 = time.perf_counter()
    point_data = {}
    if normals and tape is not None and len(verts):
        point_data["normals"] = _vertex_normals(tape, grid, verts, edges, cap)
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


def _vertex_normals(tape, grid: BlockGrid, verts, edges: dict, cap: bool) -> np.ndarray:
    """Outward unit normals: -grad f / |grad f| (forward mode) on the surface; on the caps,
    the outward normal of the bounds' face they close."""
    world = wp.empty_like(verts)
    wp.launch(K.edge_points_kernel, dim=len(verts), inputs=[edges["t"], edges["p0"], edges["p1"], grid.worigin],
              outputs=[world], device=grid.device)
    g = eval_gradients(tape, world, device=grid.device).numpy()[:, 1:].astype(np.float64)
    norm = np.linalg.norm(g, axis=1, keepdims=True)
    normals = -g / np.where(norm > 0, norm, 1.0)
    if cap:
        p0, p1 = edges["p0"].numpy(), edges["p1"].numpy()
        on_cap = (edges["flags"].numpy() & 4) != 0
        rows = np.arange(len(p0))
        axis = np.argmax(np.abs(p1 - p0), axis=1)
        at_low = p0[rows, axis] < 0.5 * grid.h[axis]  # grid-local coordinates: the low face is 0
        face_normal = np.zeros_like(normals)
        face_normal[rows, axis] = np.where(at_low, -1.0, 1.0)
        normals[on_cap] = face_normal[on_cap]
    return normals
