"""Surface meshes of implicit shapes and sampled volumes [FG §16.4]: the host pipeline.

validate (one options group per pipeline, :mod:`warpmesh.surface.options`) -> build the
grid -> cull blocks (interval arithmetic on the tape, or exact block ranges of the
volume) -> sample the surviving blocks -> marching cubes in kernels (one vertex per
crossing edge, welded by construction) -> optional root refinement on the exact
function -> host stage (numpy arrays, orientation check, statistics).

Example
-------
>>> import warpmesh as wm
>>> mesh = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=32)
>>> s = mesh.stats()
>>> s["watertight"], s["euler"]
(True, 2)
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from typing import Literal

import numpy as np
import warp as wp

from warpmesh import _conventions as C
from warpmesh._util import cancel
from warpmesh._util.validate import check_device
from warpmesh.distributed.bricks import refuse_bricking
from warpmesh.errors import WarpMeshError
from warpmesh.frep.expr import Expr
from warpmesh.frep.shapes import Shape, as_shape
from warpmesh.frep.tape import tape_of
from warpmesh.io.images import Volume, as_volume
from warpmesh.kernels import block_grid as KB
from warpmesh.kernels import emit as KE
from warpmesh.mesh import Mesh
from warpmesh.surface.primitive_refs import primitive_refs, REFS
from warpmesh.surface.block_grid import BlockGrid, drop_unused, gradients, refine_roots
from warpmesh.surface.continuation import Growth, grow_cells
from warpmesh.surface.options import (AdaptiveOptions, ContinuationOptions, GridOptions, SurfaceOptions,
                                      VolumeOptions, check_choice)
from warpmesh.surface.multilabel import LABEL_ABOVE, shared_surface
from warpmesh.surface.volume import check_closed_outward, check_labels, extract_fields

RAY_LINES = 32  # continuation's automatic seeds: rays along 32 grid lines per axis (every 8th at least)
COVERINGS = ("grid", "continuation")

# -- which pipeline takes which keywords --------------------------------------------------------
#: per options group: the pipeline as errors name it, and the keywords it does not take
#: because it always runs with these values (given with that value, they are accepted)
_PIPELINES: dict[type, tuple[str, dict]] = {
    GridOptions: ("a shape on a grid", {}),
    ContinuationOptions: ("a shape with covering='continuation'", {"cull": True}),
    AdaptiveOptions: ("a shape with adaptive=True", {"cull": True, "normals": False}),
    VolumeOptions: ("a volume", {"root": "linear", "normals": False}),
}
_SHAPE_GROUPS = (GridOptions, ContinuationOptions, AdaptiveOptions)


def _names(group: type) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(group))


_KEYWORDS = {name for group in _PIPELINES for name in _names(group)}


def mesh_surface(
    source,
    *,
    options: SurfaceOptions | None = None,
    covering: Literal["grid", "continuation"] | None = None,
    adaptive: bool = False,
    device: str = C.DEFAULT_DEVICE,
    params: dict | None = None,
    refs: Literal["surface", "primitives"] = "surface",
    client=None,
    bricks: tuple[int, int, int] | None = None,
    brick_cells: int | None = None,
    gather: bool = True,
    output=None,
    progress=True,
    **keywords,
) -> Mesh:
    """Triangulate the surface f = 0 of a shape, or an iso-surface of a sampled volume.

    Four pipelines, each with one options group (:mod:`warpmesh.surface.options`
    documents every option):

    - a shape: :class:`~warpmesh.surface.options.GridOptions` (bounds, resolution,
      method, root, root_iterations, gradient, normals, cap, evaluator, cull);
    - a shape with ``covering="continuation"``:
      :class:`~warpmesh.surface.options.ContinuationOptions` (the same without cull,
      plus seeds);
    - a shape with ``adaptive=True``: :class:`~warpmesh.surface.options.AdaptiveOptions`
      (bounds, max_level, resolution, min_level, tolerance, angles, chord, bound,
      lipschitz, root, root_iterations, gradient, cap, prune, features);
    - an array: :class:`~warpmesh.surface.options.VolumeOptions` (level, inside, labels,
      interfaces, spacing, origin, method, cap, cull, slab_voxels, smoothing);
      ``interfaces="shared"`` gives one surface in which each interface between two labels
      is meshed once (:mod:`warpmesh.surface.multilabel`), ``smoothing=N`` smooths it
      (:mod:`warpmesh.optimize.label_smoothing`).

    Give the options as keywords (the group is built from them), or as one group
    built beforehand with ``options=``; not both.

    Parameters
    ----------
    source : Shape, Expr, (nx, ny, nz) array, Volume, pyvista ImageData, str or os.PathLike
        A shape (f > 0 inside), or sampled values ``volume[i, j, k]`` at
        ``origin + (i, j, k) * spacing`` (trilinear in between), or an image that carries
        its spacing, origin and direction: a :class:`~warpmesh.io.images.Volume`, a
        pyvista ``ImageData`` or an image file (:func:`warpmesh.load_volume`); its mesh is
        in the image's world coordinates (``info["space"]``: 'RAS', 'LPS' or None).
    options : GridOptions, ContinuationOptions, AdaptiveOptions or VolumeOptions, optional
        All the options of one pipeline; the group's type chooses the pipeline.
    covering : {'grid', 'continuation'}, optional
        For a shape, with keywords: "grid" (default) samples every block that interval
        arithmetic cannot cull; "continuation" grows from seed cells across the cell
        faces the surface crosses and evaluates only the corners of crossed cells: the
        same triangles for every component it reaches, far fewer evaluations.
    adaptive : bool
        For a shape, with keywords: mesh on an adaptive octree [FG §16.4.1], so
        evaluations follow the surface and triangle sizes its curvature, with sharp
        edges and corners.
    device : str
        Warp device ("cpu" or "cuda").
    refs : {'surface', 'primitives'}
        For a shape: "surface" gives the caps ref 2 and the rest ref 1 (no refs when
        nothing is capped); "primitives" gives each triangle on f = 0 the ref of the CSG
        primitive it lies on, 11, 12, ... in the order of ``shape.primitives``
        (``info["primitives"]`` names them; :mod:`warpmesh.surface.primitive_refs`), the
        caps keeping ref 2.
    params : dict of str to float, optional
        For a shape: values of its parameters (:func:`warpmesh.param`) for this run;
        the tape's constants change, not its structure (no compile). An unknown name
        or a value outside the parameter's [lo, hi] raises ValueError.
    client : dask.distributed.Client, optional
        Mesh brick by brick on this Dask cluster (:mod:`warpmesh.distributed`): a shape on
        a grid or a volume (numpy, dask or zarr array, read brick by brick); the same
        mesh as one process makes, seams welded on global grid-edge keys. With
        ``adaptive=True`` the octree is built brick by brick on the workers and contoured on
        the client (:mod:`warpmesh.distributed.adaptive`; ``gather=False`` and ``output``
        refused), the same mesh too.
    bricks, brick_cells : (3,) ints or int, optional
        With ``client``: bricks per axis, or cells per brick side (a multiple of 8;
        default 128; with ``adaptive=True`` finest cells, a multiple of some level's cells).
    gather : bool
        With ``client``: return one Mesh (default), or, with False, a
        :class:`~warpmesh.distributed.run.PartitionedMesh` of the pieces on disk.
    output : str or os.PathLike, optional
        With ``client``: a ``.pvtu`` path; one VTU piece per brick is written beside it as
        bricks finish.
    progress : bool or callable
        With ``client``: a progress bar over the bricks, or ``progress(done, total)``; with
        ``interfaces="shared"``: a bar over the grid's rows, then one over the smoothing's
        passes (tqdm, shown once the run has taken a second), or ``progress(done, total)``
        called for each.
    **keywords
        The fields of the chosen pipeline's group, by name. A keyword given as None
        takes its default. A keyword of another pipeline raises one ValueError that
        names the pipeline and the keywords it takes; a name no pipeline knows raises
        TypeError.

    Returns
    -------
    Mesh
        ``mesh.cells["triangle"]`` oriented outward (towards f < 0); where caps close
        the surface on the bounds, ``mesh.cell_refs["triangle"]`` is 2 on the caps and 1
        on the surface f = 0 (no refs when nothing was capped; the label of each
        triangle with ``labels``; the lower of its two labels with interfaces="shared",
        the higher in ``mesh.cell_data["label_above"]["triangle"]``); ``mesh.info`` holds timings per stage and counts
        (``mesh.stats()`` shows them).

    Raises
    ------
    ValueError, TypeError
        Bad options (from the group, naming the option), options of another pipeline,
        NaN / infinite values, a constant volume.

    Examples
    --------
    Keywords, for each pipeline:

    >>> import numpy as np, warpmesh as wm
    >>> part, bounds = wm.example("part")
    >>> grid = wm.mesh_surface(part, bounds=bounds, resolution=32, method="mt")
    >>> grown = wm.mesh_surface(part, bounds=bounds, resolution=32, covering="continuation")
    >>> octree = wm.mesh_surface(part, bounds=bounds, adaptive=True, max_level=5, tolerance=0.05)
    >>> g = np.linspace(-1, 1, 40)
    >>> vol = 0.8 - np.sqrt(g[:, None, None]**2 + g[None, :, None]**2 + g[None, None, :]**2)
    >>> ball = wm.mesh_surface(vol, spacing=g[1] - g[0], origin=(-1, -1, -1))
    >>> [m.stats()["euler"] for m in (grid, grown, octree, ball)]
    [-6, -6, -6, 2]

    The same, with a group built beforehand:

    >>> from warpmesh.surface.options import GridOptions, VolumeOptions
    >>> opts = GridOptions(bounds=bounds, resolution=32, method="mt")
    >>> np.array_equal(wm.mesh_surface(part, options=opts).triangles, grid.triangles)
    True
    >>> wm.mesh_surface(vol, options=VolumeOptions(spacing=g[1] - g[0], origin=(-1, -1, -1))).n_cells == ball.n_cells
    True

    An option of another pipeline is refused once, with what this one takes:

    >>> wm.mesh_surface(part, bounds=bounds, level=0.1)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: 'level' does not apply to a shape on a grid ('level' is an option of a volume); GridOptions ...
    """
    t_start = time.perf_counter()
    if params is not None:
        if not isinstance(source, (Shape, Expr)):
            raise TypeError(f"'params' sets the parameters of a shape, got {type(source).__name__} for 'source'")
        source = source.with_params(params)
    if client is not None:
        return _mesh_bricked(source, options, covering, adaptive, device, refs, keywords, t_start, client=client,
                             bricks=bricks, brick_cells=brick_cells, gather=gather, output=output, progress=progress)
    refuse_bricking(bricks=bricks, brick_cells=brick_cells, gather=gather, output=output)
    image = as_volume(source)  # a Volume, an image file or a pyvista ImageData; None for arrays and shapes
    if image is not None:
        return _mesh_image(image, options, covering, adaptive, device, keywords, progress)
    if options is None:
        options = _options_from_keywords(source, covering, adaptive, keywords)
    else:
        _check_options(source, options, covering, adaptive, keywords)
    device = check_device(device)
    check_choice(refs, "refs", REFS)
    if isinstance(options, VolumeOptions):
        if refs != "surface":
            raise ValueError(f"refs={refs!r} tags the primitives of a shape; a volume's triangles carry its "
                             "labels (labels=...)")
        return _mesh_volume(source, options, device, t_start, progress)
    if isinstance(options, AdaptiveOptions):
        mesh = _mesh_adaptive(source, options, device, t_start)
    else:
        mesh = _mesh_grid(source, options, device, t_start)
    return _tag_primitives(as_shape(source), mesh) if refs == "primitives" and mesh.n_cells else mesh


def surface_options(source, *, covering=None, adaptive: bool = False, **keywords) -> SurfaceOptions:
    """The options :func:`mesh_surface` builds from these keywords, checked, without meshing:
    for a caller that keeps keywords for later (the live preview's idle refinement) and
    wants their errors now.

    Raises
    ------
    TypeError, ValueError
        As :func:`mesh_surface` for the same keywords.

    Examples
    --------
    >>> import warpmesh as wm
    >>> surface_options(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=40).resolution
    40
    >>> surface_options(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=-3)
    Traceback (most recent call last):
    ...
    ValueError: expected 1 <= 'resolution' <= 2048, got -3
    """
    return _options_from_keywords(source, covering, adaptive, keywords)


def _mesh_bricked(source, options, covering, adaptive, device, refs, keywords: dict, t_start: float, **run):
    """``client=``: the options group as for one process, then :func:`warpmesh.distributed.run.mesh_bricks`."""
    from warpmesh.distributed.run import mesh_bricks

    if not (isinstance(source, (Shape, Expr)) or all(hasattr(source, a) for a in ("shape", "dtype", "ndim"))):
        raise TypeError(f"with 'client', expected a Shape, an expression or a 3D numpy, dask or zarr array for "
                        f"'source', got {type(source).__name__} (for an image, pass its values with spacing and "
                        "origin)")
    if covering == "continuation" or isinstance(options, ContinuationOptions):
        raise ValueError("'client' meshes a shape on the grid (covering='grid') or on an octree (adaptive=True), "
                         "or a volume; covering='continuation' is not bricked")
    if options is None:
        options = _options_from_keywords(source, covering, adaptive, keywords)
    else:
        _check_options(source, options, covering, adaptive, keywords)
    check_choice(refs, "refs", REFS)
    if isinstance(options, AdaptiveOptions):  # the octree on the workers, the contouring on the client
        from warpmesh.distributed.run import check_run

        check_run(run["client"], run["gather"], run["output"], run["progress"])
        if not run["gather"] or run["output"] is not None:
            raise ValueError("adaptive=True with 'client' returns the gathered mesh (its surface is contoured and "
                             "untangled on the client): drop gather=False and 'output' (mesh.write the result)")
        bricked = {k: run[k] for k in ("client", "bricks", "brick_cells", "progress")}
        mesh = _mesh_adaptive(source, options, check_device(device), t_start, bricked=bricked)
        return _tag_primitives(as_shape(source), mesh) if refs == "primitives" and mesh.n_cells else mesh
    if isinstance(options, VolumeOptions) and refs != "surface":
        raise ValueError(f"refs={refs!r} tags the primitives of a shape; a volume's triangles carry its "
                         "labels (labels=...)")
    if refs == "primitives" and run["gather"] is False:
        raise ValueError("refs='primitives' tags the gathered mesh: give gather=True with 'client'")
    if isinstance(options, GridOptions) and options.normals:
        raise ValueError("normals=True is not computed on bricks: with 'client' use normals=False (the gathered "
                         "mesh's to_trimesh().vertex_normals gives them)")
    mesh = mesh_bricks(source, options, device=device, **run)
    return _tag_primitives(as_shape(source), mesh) if refs == "primitives" and mesh.n_cells else mesh


def _tag_primitives(shape: Shape, mesh: Mesh) -> Mesh:
    """The mesh with each triangle's ref the primitive it lies on (caps kept)."""
    t0 = time.perf_counter()
    h = float(np.max(mesh.info.get("finest_cell", mesh.info.get("cell_size"))))
    refs, extra = primitive_refs(shape, mesh.points, mesh.cells["triangle"],
                                 mesh.cell_refs.get("triangle") if mesh.cell_refs else None, h)
    timings = {**mesh.info.get("timings", {}), "primitive_refs": time.perf_counter() - t0}
    return mesh.replace(cell_refs={"triangle": refs}, info={**mesh.info, **extra, "timings": timings})


def _mesh_image(image: Volume, options, covering, adaptive, device, keywords: dict, progress=True) -> Mesh:
    """An image's values meshed with its spacing, then placed by its direction and origin.

    With a rotated (or reflected) ``direction`` the array pipeline runs at origin 0 and
    the mesh is mapped by ``image.placement`` (``Mesh.transform``, which keeps triangles
    outward under a reflection); an x-fastest array is meshed as its transpose (no copy)
    and mapped back the same way. ``info["space"]`` is the image's world frame.
    """
    labels = keywords.get("labels") if options is None else getattr(options, "labels", None)
    given = [n for n in ("spacing", "origin") if keywords.get(n) is not None or
             (isinstance(options, VolumeOptions) and getattr(options, n) != getattr(VolumeOptions(), n))]
    if given:
        raise ValueError(f"{' and '.join(map(repr, given))} come with the image given as 'source' (spacing "
                         f"{image.spacing}, origin {image.origin}); to change them pass "
                         f"source=volume.replace({given[0]}=...)")
    if labels is not None:
        image = image.as_labels()
    values, spacing, placement = image.values, image.spacing, image.placement
    shared = (keywords.get("interfaces") if options is None else getattr(options, "interfaces", None)) == "shared"
    if values.flags.f_contiguous and not values.flags.c_contiguous and not shared:  # (shared: swaps its own axes)
        # x fastest (VTK, NIfTI, ITK): mesh the C-order view values.T, whose slabs along the first axis are
        # contiguous (frog, 25 labels: 2.5 s of slab uploads instead of 10.9 s), then swap the axes back
        values, spacing = values.T, spacing[::-1]
        placement = placement @ _REVERSE_AXES
    moved = not np.array_equal(placement[:3, :3], np.eye(3))
    place = {"spacing": spacing, "origin": (0.0, 0.0, 0.0) if moved else image.origin}
    if isinstance(options, VolumeOptions):
        options = dataclasses.replace(options, **place)
    else:
        keywords = {**keywords, **place} if options is None else keywords
    mesh = mesh_surface(values, options=options, covering=covering, adaptive=adaptive, device=device,
                        progress=progress, **keywords)
    if moved and mesh.n_points:
        mesh = mesh.transform(placement)
        mesh = mesh.replace(info={k: v for k, v in mesh.info.items() if k != C.GRID_INFO})  # not the world's grid
    return mesh.replace(info={**mesh.info, "space": image.space})


_REVERSE_AXES = np.array([[0.0, 0, 1, 0], [0, 1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 1]])  # (k, j, i) -> (i, j, k)


# -- keywords -> the options group ---------------------------------------------------------------
def _is_shape(source) -> bool:
    """True for a shape, False for a volume (anything an array can be made of)."""
    if isinstance(source, (Shape, Expr)):
        return True
    if isinstance(source, np.ndarray) or hasattr(source, "__array__"):
        return False
    raise TypeError(f"expected a Shape, an expression or a 3D array for 'source', got {type(source).__name__}")


def _group_of(source, covering, adaptive) -> type:
    """The options group, hence the pipeline, of the source and the two selectors."""
    if not isinstance(adaptive, (bool, np.bool_)):
        raise TypeError(f"expected True or False for 'adaptive', got {adaptive!r}")
    if covering is not None:
        check_choice(covering, "covering", COVERINGS)
    if adaptive:
        if not isinstance(source, (Shape, Expr)):
            raise TypeError(f"adaptive=True meshes a Shape or an expression (it evaluates the function where "
                            f"it needs it), got {type(source).__name__} for 'source'")
        if covering == "continuation":
            raise ValueError(f"adaptive=True is its own covering-up; got covering={covering!r}")
        return AdaptiveOptions
    if not _is_shape(source):
        if covering == "continuation":
            raise ValueError("covering='continuation' saves evaluations of a shape's function; a volume's "
                             "samples are all given: use covering='grid'")
        return VolumeOptions
    return ContinuationOptions if covering == "continuation" else GridOptions


def _check_names(keywords: dict, takes: str) -> None:
    unknown = [name for name in keywords if name not in _KEYWORDS]
    if unknown:
        s = "s" if len(unknown) > 1 else ""
        raise TypeError(f"mesh_surface() got an unexpected keyword argument{s} {', '.join(map(repr, unknown))}; "
                        f"{takes}")


def _options_from_keywords(source, covering, adaptive, keywords: dict) -> SurfaceOptions:
    """Build the chosen pipeline's group from the keywords (None: not given); refuse, in
    one error, the keywords of other pipelines."""
    group = _group_of(source, covering, adaptive)
    names = _names(group)
    what, fixed = _PIPELINES[group]
    _check_names(keywords, f"{what} takes {', '.join(names)}")
    given = {name: value for name, value in keywords.items() if value is not None}
    refused = [name for name, value in given.items() if name not in names and not _fixed(value, fixed, name)]
    if refused:
        raise ValueError(_refusal(group, refused))
    args = {name: value for name, value in given.items() if name in names}
    if "bounds" in names:
        args.setdefault("bounds", None)  # required: the group says what is missing
    return group(**args)


def _fixed(value, fixed: dict, name: str) -> bool:
    """Whether a keyword the pipeline does not take holds the value it always runs with."""
    return name in fixed and isinstance(value, (bool, np.bool_, str)) and value == fixed[name]


def _refusal(group: type, refused: list[str]) -> str:
    """One message for the keywords a pipeline does not take: where each belongs, what it takes."""
    what, fixed = _PIPELINES[group]
    owners: dict[str, list[str]] = {}  # where the keywords belong -> those keywords
    for name in refused:
        if name not in fixed:
            groups = [g for g in _PIPELINES if name in _names(g)]
            labels = [_PIPELINES[g][0] for g in groups]
            if groups == list(_SHAPE_GROUPS):
                where = "every shape pipeline"
            else:
                where = labels[0] if len(labels) == 1 else ", ".join(labels[:-1]) + " and " + labels[-1]
            owners.setdefault(where, []).append(name)
    parts = [f"{', '.join(map(repr, names))} {'is an option' if len(names) == 1 else 'are options'} of {where}"
             for where, names in owners.items()]
    always = [f"{name}={fixed[name]!r}" for name in refused if name in fixed]
    if always:
        parts.append(f"this pipeline always runs with {', '.join(always)}")
    verb = "does" if len(refused) == 1 else "do"
    return (f"{', '.join(map(repr, refused))} {verb} not apply to {what} ({'; '.join(parts)}); "
            f"{group.__name__} takes {', '.join(_names(group))}")


def _check_options(source, options, covering, adaptive, keywords: dict) -> None:
    """``options=``: one of the groups, matching the source, and no option keyword besides."""
    if not isinstance(options, tuple(_PIPELINES)):
        raise TypeError(f"expected {', '.join(g.__name__ for g in _PIPELINES)} for 'options', "
                        f"got {type(options).__name__}")
    _check_names(keywords, "with options=, give only 'source', 'options' and 'device'")
    mixed = [name for name, value in keywords.items() if value is not None]
    mixed += (["covering"] if covering is not None else []) + (["adaptive"] if adaptive is not False else [])
    if mixed:
        raise ValueError(f"give the options as options={type(options).__name__}(...) or as keywords, not both: "
                         f"got {', '.join(map(repr, mixed))} too")
    if _is_shape(source) != isinstance(options, _SHAPE_GROUPS):
        what = _PIPELINES[type(options)][0]
        expected = "a Shape or an expression" if isinstance(options, _SHAPE_GROUPS) else "a 3D array"
        raise TypeError(f"{type(options).__name__} meshes {what}: expected {expected} for 'source', "
                        f"got {type(source).__name__}")


# -- the shape pipelines on a uniform grid (covering 'grid' and 'continuation') -------------------
def _mesh_grid(source, opts: GridOptions | ContinuationOptions, device, t_start: float) -> Mesh:
    """Cull and sample (grid) or grow (continuation) -> extract -> roots -> host stage."""
    cap_mask = KB.ALL_FACES if opts.cap else 0
    cell_mask = None
    timings: dict[str, float] = {}
    info: dict = {"method": opts.method, "root": opts.root, "device": str(device)}
    lo, hi = (np.asarray(b, dtype=np.float64) for b in opts.bounds)
    cells = opts.cells
    h = (hi - lo) / cells
    tape = tape_of(source)
    timings["compile"] = time.perf_counter() - t_start
    grid = BlockGrid(cells + 1, lo, h, device)
    if isinstance(opts, ContinuationOptions):
        cell_mask = _grow(grid, tape, opts.seeds, opts.cap, opts.evaluator, timings, info)
    else:
        grid.cull_shape(tape, opts.cull, cap_mask, timings)
        cancel.checkpoint()  # a stale run (the preview's refinement after a newer edit) stops between stages
        grid.sample_shape(tape, opts.cull, opts.evaluator, timings)
    info["tape_length"] = len(tape)

    cancel.checkpoint()
    grid.finish_values(cap_mask, timings)
    verts, tris, edges = grid.extract(opts.method, cap_mask, timings, cell_mask, clearance=opts.clearance)
    cancel.checkpoint()
    if cell_mask is not None:  # continuation: drop the vertices of edges on no grown cell first
        verts, tris, edges = drop_unused(verts, tris, edges)
    if opts.root != "linear" and len(verts):
        refine_roots(tape, verts, edges, grid.worigin, opts.root, opts.root_iterations, timings, opts.evaluator,
                     opts.gradient, grid.h)
        cancel.checkpoint()

    t0 = time.perf_counter()
    point_data = {}
    if opts.normals and len(verts):
        point_data["normals"] = _vertex_normals(tape, grid, verts, edges, opts.cap, opts.gradient)
    points = verts.numpy().astype(C.REAL_DTYPE) + grid.origin  # sync point: results to the host
    faces = tris.numpy().astype(C.INDEX_DTYPE)
    if len(faces) and faces.min() < 0:
        raise WarpMeshError("a block culled as uniform holds a crossing edge: the interval bound "
                            "of the shape is wrong; mesh with cull=False and report the shape")
    if opts.cap and len(faces):  # closed by construction: outward winding encloses a positive volume
        if not grid.info["signed_volume"] > 0.0:
            raise WarpMeshError(f"the capped surface encloses a signed volume of {grid.info['signed_volume']:g}: "
                                "its triangles do not face outward (an internal error: please report it)")
        info["orientation"] = "outward (closed, positive enclosed volume)"
    refs = _surface_refs(edges, faces) if opts.cap and len(faces) else None
    cell_refs = {"triangle": refs} if refs is not None and np.any(refs == CAP_REF) else None
    info.update(grid.info)
    info["vertices"], info["triangles"] = len(points), len(faces)
    if len(faces) == 0:
        warnings.warn("the surface does not cross the sampled grid: the mesh is empty "
                      "(check 'bounds', 'level' and the sign convention f > 0 inside)", stacklevel=3)
    timings["host"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return Mesh(points, {"triangle": faces}, point_data=point_data or None, cell_refs=cell_refs, info=info)


SURFACE_REF, CAP_REF = C.SURFACE_REF, C.CAP_REF


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


def _mesh_volume(source, opts: VolumeOptions, device, t_start: float, progress=True) -> Mesh:
    """The volume pipeline: one extraction per label (or one at ``level``), slab by slab;
    with interfaces='shared', one surface of every interface (:mod:`warpmesh.surface.multilabel`)."""
    vol = _check_volume(source)
    if opts.interfaces == "shared":
        return _mesh_shared(vol, opts, device, t_start, progress)
    if opts.labels is not None and np.issubdtype(vol.dtype, np.floating):  # whole-number floats are labels
        try:  # (as interfaces="shared" and mesh_domain take them)
            vol = Volume(vol).as_labels().values
        except ValueError as exc:
            raise ValueError(f"'labels' meshes the regions of a label 'volume': {exc}") from None
    if opts.cap and min(vol.shape) < 3:
        raise ValueError(f"expected at least 3 samples per axis in 'volume' to cap the surface (the "
                         f"boundary samples are outside), got shape {vol.shape} (cap=False leaves the surface open)")
    if opts.level is not None:
        level = opts.level
    else:  # a bool or label volume's surface sits halfway between False and True samples
        level = 0.5 if opts.labels is not None or vol.dtype == np.bool_ else 0.0
    sign = 1.0 if opts.inside == "above" else -1.0
    org, sp = np.asarray(opts.origin, dtype=np.float64), np.asarray(opts.spacing, dtype=np.float64)
    labels, cap = opts.labels, opts.cap
    timings: dict[str, float] = {}
    info: dict = {"method": opts.method, "root": "linear", "device": str(device)}
    fields = [None] if labels is None else list(check_labels(labels, vol))
    parts, n_verts = [], 0
    for label, (points, faces, flags, (vmin, vmax)) in zip(fields, extract_fields(
            vol, org, sp, fields, level=level, sign=sign, method=opts.method, cap=cap, cull=opts.cull, device=device,
            slab_voxels=opts.slab_voxels, timings=timings, info=info, clearance=opts.clearance)):
        if label is None and vmin == vmax:
            raise ValueError(f"expected a non-constant 'volume', got every value equal to {sign * vmin + level}")
        if label is None and not vmin <= 0.0 <= vmax:
            lo_v, hi_v = sorted((sign * vmin + level, sign * vmax + level))
            raise ValueError(f"expected 'level' within the volume's range [{lo_v}, {hi_v}], got {level}")
        if label is not None and vmax <= 0.0:
            raise ValueError(f"expected label {label} in 'volume', got no sample equal to it")
        if cap and len(faces):
            info["enclosed_volume"] = info.get("enclosed_volume", 0.0) + check_closed_outward(
                points, faces, info.pop("signed_volume", None))
            info["orientation"] = "outward (closed, positive enclosed volume)"
        capped = (flags & 4) != 0
        refs = np.where(capped[faces[:, 0]] & capped[faces[:, 1]] & capped[faces[:, 2]], CAP_REF, SURFACE_REF) \
            if label is None else \
            np.full(len(faces), label)
        if n_verts:  # (a pass over every row: not for the first field)
            faces += n_verts
        parts.append((points, faces, refs.astype(C.INDEX_DTYPE, copy=False)))
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



def _mesh_shared(vol: np.ndarray, opts: VolumeOptions, device, t_start: float, progress=True) -> Mesh:
    """One surface with each interface between two labels meshed once (surface nets)."""
    timings: dict[str, float] = {}
    points, faces, lower, upper, info = shared_surface(vol, opts.labels, origin=opts.origin, spacing=opts.spacing,
                                                       cap=opts.cap, device=device, progress=progress, timings=timings)
    info.update({"method": "surface nets", "interfaces": "shared", "device": str(device), "evaluations": 0,
                 "vertices": len(points), "triangles": len(faces), "interface_pairs": info.pop("interfaces"),
                 C.GRID_INFO: {"origin": list(opts.origin), "spacing": list(opts.spacing), "shape": list(vol.shape)}})
    if opts.cap:
        info["orientation"] = "from the lower label to the higher (cell_refs: lower, cell_data['label_above'])"
    mesh = Mesh(points, {"triangle": faces}, cell_refs={"triangle": lower},  # compact: the arrays as written
                cell_data={LABEL_ABOVE: {"triangle": upper}}, info=info, compact=points.dtype == np.float32)
    if opts.smoothing:
        # imported when asked for: its fold checks load the remeshing and intersection
        # kernels (84 ms of a fresh process that only extracts)
        from warpmesh.optimize.label_smoothing import smooth_labels

        # float64 points, not compact: float32 rounding could undo what its checks proved
        # (every vertex within its cube's margin, no fold)
        mesh = smooth_labels(mesh, opts.smoothing, progress=progress)
        timings["smoothing"] = mesh.info["smoothing"]["time"]
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    return mesh.replace(info={**mesh.info, "time": timings})


def _check_volume(source) -> np.ndarray:
    vol = np.asarray(source)
    if vol.ndim != 3:
        raise ValueError(f"expected a 3D array for 'volume', but got {vol.ndim}D with shape {vol.shape}")
    if min(vol.shape) < 2:
        raise ValueError(f"expected at least 2 samples per axis in 'volume', got shape {vol.shape}")
    if not (np.issubdtype(vol.dtype, np.number) or vol.dtype == np.bool_) or np.iscomplexobj(vol):
        raise TypeError(f"expected a real numeric 'volume', got dtype {vol.dtype}")
    return vol


def _grow(grid: BlockGrid, tape, seeds, cap: bool, evaluator, timings, info):
    """Continuation covering-up: grow the crossed cells from seeds (warpmesh.surface.continuation),
    then load them into the block grid. Returns the mask of the grown cells."""
    t0 = time.perf_counter()
    seed_cells = None
    if seeds is not None:
        seed_cells = _seed_cells(grid, tape, seeds, cap, evaluator)
    def grow(seed_cells, ray_stride):
        try:
            return grow_cells(lambda ids: grid.node_values(tape, ids, evaluator), tuple(int(v) for v in grid.n),
                              seeds=seed_cells, ray_stride=ray_stride, cap=cap)
        except ValueError as exc:
            if "'evaluate'" in str(exc):  # the callback is ours: say what the user can change
                raise ValueError(NAN_MESSAGE) from None
            raise

    if seeds is not None:
        growth = grow(seed_cells, None)
        block_info = {}
        grid.info["interval_evaluations"] = 0
    else:
        with warnings.catch_warnings():  # no ray seed is not the end: the blocks are searched next
            warnings.filterwarnings("ignore", message="grow_cells: no ray")
            growth = grow(None, _ray_stride(grid.n))
        extra, block_info = _block_seeds(grid, tape, cap, evaluator, growth.cells)
        if len(extra):
            more = grow(extra, None)
            ids = np.concatenate([growth.node_ids, more.node_ids])
            ids, first = np.unique(ids, return_index=True)
            growth = Growth(cells=np.union1d(growth.cells, more.cells), node_ids=ids,
                            node_values=np.concatenate([growth.node_values, more.node_values])[first],
                            evaluations=growth.evaluations + more.evaluations,
                            ray_evaluations=growth.ray_evaluations, waves=max(growth.waves, more.waves),
                            seeds=growth.seeds + more.seeds, components=growth.components + more.components)
    timings["evaluate"] = time.perf_counter() - t0
    mask = grid.load_cells(growth.cells, growth.node_ids, growth.node_values)
    info.update(evaluations=growth.evaluations + block_info.get("seed_search_evaluations", 0),
                ray_evaluations=growth.ray_evaluations, waves=growth.waves,
                seed_cells=growth.seeds, grown_cells=len(growth.cells), components_grown=growth.components,
                **block_info)
    timings["load"] = time.perf_counter() - t0 - timings["evaluate"]
    return mask


NAN_MESSAGE = ("the shape evaluates to NaN or infinity at grid nodes inside 'bounds' (e.g. sqrt/log of a "
               "negative or a division by zero); change the expression or the bounds")


def _seed_cells(grid: BlockGrid, tape, seeds, cap: bool, evaluator) -> np.ndarray:
    """The cells to grow from: per seed point, the crossed cells among those whose closure
    holds it (up to 8 when it lies on a cell face, edge or node)."""
    pts = np.asarray(seeds, dtype=np.float64)  # finite (m, 3): ContinuationOptions checked them
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
    crossed, _ = _crossed_cells(grid, tape, np.unique(cand[cand >= 0]), cap, evaluator)
    hit = (cand >= 0) & np.isin(cand, crossed)
    if not hit.any(axis=1).all():
        bad = pts[~hit.any(axis=1)][0].tolist()
        raise ValueError(f"expected 'seeds' in cells crossed by the surface, got {bad}: no cell holding it "
                         "has corners on both sides; give a point on or next to the surface")
    return np.unique(cand[hit])


def _crossed_cells(grid: BlockGrid, tape, flat: np.ndarray, cap: bool, evaluator) -> tuple[np.ndarray, int]:
    """(the crossed cells among the sorted cell ids ``flat``, nodes evaluated), from f at
    their corners (boundary nodes outside when capped, as the grid caps them)."""
    cells = grid.n - 1
    ci = np.stack([flat % cells[0], flat // cells[0] % cells[1], flat // (cells[0] * cells[1])], axis=1)
    corner_ids = [(ci[:, 0] + (c & 1)) + grid.n[0] * ((ci[:, 1] + ((c >> 1) & 1)) + grid.n[1] *
                                                      (ci[:, 2] + ((c >> 2) & 1))) for c in range(8)]
    nodes = np.unique(np.concatenate(corner_ids))
    values = grid.node_values(tape, nodes, evaluator)
    if not np.all(np.isfinite(values)):
        raise ValueError(NAN_MESSAGE)
    inside_node = values > 0
    if cap:  # capped: boundary nodes are outside
        g = np.stack([nodes % grid.n[0], nodes // grid.n[0] % grid.n[1], nodes // (grid.n[0] * grid.n[1])], axis=1)
        inside_node &= ~np.any((g == 0) | (g == grid.n - 1), axis=1)
    inside = np.stack([inside_node[np.searchsorted(nodes, ids)] for ids in corner_ids], axis=1)
    return flat[inside.any(axis=1) & ~inside.all(axis=1)], len(nodes)


def _block_seeds(grid: BlockGrid, tape, cap: bool, evaluator, grown: np.ndarray) -> tuple[np.ndarray, dict]:
    """Seeds for the components the rays missed [issue 19 item 7]: the crossed cells among
    those that intervals of f cannot prove uncrossed (blocks, then boxes halved down to
    single cells) and that were not grown. Sound intervals make this complete: every cell
    the grid finds crossed is such a candidate, so every component is seeded. Returns
    (seed cells, counts for ``info``)."""
    states = grid.block_states(tape, KB.ALL_FACES if cap else 0).numpy()
    blocks = np.flatnonzero(states != int(KB.CULLED))
    candidates, n_intervals = grid.candidate_cells(tape, blocks, cap)
    todo = np.setdiff1d(candidates, grown, assume_unique=True)
    crossed, n_nodes = _crossed_cells(grid, tape, todo, cap, evaluator) if len(todo) else (todo, 0)
    grid.info["interval_evaluations"] += n_intervals  # the blocks' are counted by block_states
    return crossed, {"seed_search_cells": len(todo),
                     "seed_search_evaluations": n_nodes, "seed_search_crossed": len(crossed)}


def _ray_stride(n_nodes) -> int:
    """Grid lines between seed rays: the rays cost O(n) evaluations per line family, below
    the O(n^2) of the surface itself."""
    return int(max(8, int(np.max(n_nodes)) // RAY_LINES))


def _mesh_adaptive(source, opts: AdaptiveOptions, device, t_start: float, bricked: dict | None = None) -> Mesh:
    """The octree pipeline: :func:`warpmesh.surface.adaptive.pipeline.mesh_adaptive`, then the host stage.
    ``bricked`` (client, bricks, brick_cells, progress): the octree built on a Dask cluster
    (:mod:`warpmesh.distributed.adaptive`)."""
    from warpmesh.surface.adaptive.pipeline import mesh_adaptive

    lo, hi = (np.asarray(b, dtype=np.float64) for b in opts.bounds)
    tolerance = opts.relative_tolerance
    timings: dict[str, float] = {}
    info: dict = {"covering": "octree", "root": opts.root, "device": str(device), "tolerance": tolerance,
                  "chord": opts.chord, "bound": opts.bound}
    tape = tape_of(source)
    info["tape_length"] = len(tape)
    build = None
    if bricked is not None:
        from warpmesh.distributed.adaptive import BrickedOctree

        build = BrickedOctree(source, lo, hi, opts.finest_level, **bricked)
    points, faces, refs = mesh_adaptive(
        tape, lo, hi, max_level=opts.finest_level, min_level=opts.min_level, tolerance=tolerance,
        angles=opts.angles, chord=opts.chord, bound=opts.bound, lipschitz=opts.lipschitz, cap=opts.cap,
        prune=opts.prune, features=opts.features, root=opts.root, root_iterations=opts.root_iterations,
        gradient=opts.gradient, device=device, timings=timings, info=info, build=build)
    if build is not None:
        info.update(build.info)
    if len(faces) == 0:
        warnings.warn("the surface does not cross the bounds: the mesh is empty "
                      "(check 'bounds' and the sign convention f > 0 inside)", stacklevel=3)
    info["vertices"], info["triangles"] = len(points), len(faces)
    timings["total"] = time.perf_counter() - t_start
    info["time"] = timings
    cell_refs = {"triangle": refs} if refs is not None else None
    return Mesh(points.astype(C.REAL_DTYPE), {"triangle": faces.astype(C.INDEX_DTYPE)}, cell_refs=cell_refs,
                info=info)
