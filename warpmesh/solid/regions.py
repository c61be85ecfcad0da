"""Multi-region tetrahedra of a label volume by lattice cleaving: ``mesh_domain(volume, labels=..., size=h)``.

The approach, and why
---------------------
A label volume is piecewise constant: the region of label ``L`` is the union of the voxel
boxes (centred on the samples) holding ``L``. Its tetrahedra come from the body-centred
cubic lattice of isosurface stuffing (:func:`warpmesh.solid.lattice.lattice_tables`, cube
side ``h``), cleaved by the labels (after Bronson, Levine & Whitaker's lattice cleaving):

1. every lattice node takes the label of the voxel it lies in (the rest outside the box);
   a background tetrahedron with one label stays whole, one of the rest is dropped;
2. on each lattice edge whose two ends differ, one *cut point* where the label changes:
   the labels are sampled along the edge (4 samples per voxel) and the cut sits at
   ``(n_first + n_other / 2) / n`` of the edge (``n_first`` samples of the first end's
   label, ``n_other`` of neither end's), so a single change lands within 1/8 voxel of the
   voxel face and the volume between the two ends is shared as the samples say;
3. a cut point within ``snap`` of the edge's length from a node is *snapped* onto that node
   (the vertex-snapping half of lattice cleaving's warp): it removes the sliver the cut
   would make, and the edge then belongs wholly to its other end's label. Where the snaps
   onto a node would pinch a region's boundary there (two cones of a label touching at the
   node), some of them are pushed off it instead (:mod:`warpmesh.solid.snapping`;
   ``info["pushed_cuts"]``), so every region's boundary is a manifold;
4. every lattice face with two or three labels gets a *face point*, every cleaved
   tetrahedron a *tet point*: the mean of its cut points, pulled towards the face's
   (tetrahedron's) centroid until every barycentric weight is at least ``INTERIOR`` (so
   the point is strictly inside, even when cut points are snapped onto nodes);
5. the sub-tetrahedra of a cleaved tetrahedron: a star from the tet point over its faces,
   a mixed face triangulated as a fan from its face point over the polygon of nodes and cut
   points (a face of one label stays one triangle). Each sub-tetrahedron takes the label of
   the lattice node of its polygon segment; those of the rest are dropped, degenerate ones
   (a segment snapped to a point) too.

6. where the edges do not resolve the labels, the pieces of a region can close over a piece
   of the rest: a cavity the labels do not hold.
   Such pockets are filled with the label around them (:mod:`warpmesh.solid.pockets`; a
   cavity that holds a sample of the rest is kept); ``info`` counts them.

Everything in steps 2-5 is decided per edge and per face from that edge's or face's own
nodes and labels (and the vertices are named by their edge and face), so the two
tetrahedra on either side of a face cut it the same way: the mesh is conforming by
construction, and every interface between two regions is a set of triangles shared by the
tetrahedra of both. Every sub-tetrahedron is positive: the tet point is strictly inside,
the face point strictly inside its face, and the polygon segments are non-degenerate
pieces of the face's edges, in the face's counter-clockwise order.

What is lost on the uniform lattice: a region thinner than about ``h`` that no lattice node
lies in and that no edge changes label across (a label met only *between* two nodes of one
other label) is missed; where an edge crosses three labels it gets one cut point, so the
middle label's share goes half to each end.

Graded lattice (``min_size``, default ``h / 2``): when a region's volume on the uniform
lattice is off by more than ``REFINE_ERROR`` (2.5 %) or the region is lost, the volume is
cleaved again on the BCC lattice refined by conforming longest-edge bisection
(:func:`warpmesh.solid.graded.refine_tets`) where an edge crosses that region's labels more
than once (:mod:`warpmesh.solid.thin`), down to edges of ``min_size``. Cleaving needs nothing
of the lattice but conforming positive tetrahedra and vertices named by their nodes, edges
and faces, so steps 1-5 run unchanged on it. Measured (``python benchmarks/bench_regions.py
--repeat 1 --no-tetgen``): pyvista's frog at h = 4 voxels, labels 1 and 12 (2-3 voxels thick)
-15.7 % and -9.4 % -> -4.6 % and -2.0 %, every label of 3,891 voxels or more within 5 %, no
label lost (2 before), 8.85 M tetrahedra instead of 2.25 M, 29.8 s of CPU instead of 2.9 s
in the same run (10.2x, load 1.0; 16.4 s of it the graded background: its bisection, and about
5 s sampling its edges against the labels in :mod:`warpmesh.solid.thin`), dihedral angles
[9.3°, 167.0°] instead of [12.8°, 159.1°] (where the small ones are: Quality, below). What is
still lost: a layer thinner than about twice ``min_size`` (a 1-voxel layer at ``min_size`` 1
voxel: +32 %, the cut points' snapping and the pulled face and tet points are a fraction of an
edge). ``info["region_volumes"]`` reports each region's volume against its voxel volume, so a
user sees what was missed.

Specks (regions whose every connected component is at most ``SPECK_CUBES`` lattice cubes: the
frog's labels of 4 to 252 voxels, scattered in up to 49 pieces of 1 to 120 voxels). Refining
where edges do not resolve the labels does not make them right: once a node lies in a speck its
edges resolve it, and a region one or two edges across is chamfered, mostly by the pull of its
face and tet points towards the centroids (``INTERIOR``), an error of the first order in the
edge (a lone voxel at edges of 0.5 / 0.25 voxel: -20 % / -10 %; with ``INTERIOR`` 0.02, -5 %,
but dihedral angles of 0.02°). So, in the graded pass:

- the lattice is asked, over each speck voxel, edges of ``SPECK_THICKNESS`` times its
  component's thickness (2 volume / area of its voxels' boundary), from ``SPECK_SIZE`` = 0.5
  voxel for a lone voxel up to ``size / 2`` (:class:`warpmesh.solid.thin.Specks`);
- the lattice is shifted by ``LATTICE_SHIFT`` = 0.1 voxel: at the default size (a power of two
  of the spacing) the refined nodes otherwise lie on the voxels' faces, where a speck's cut
  points are already at the far ends of their edges (a lone voxel at -20 % whatever is done);
- each speck region's cut points are moved along their edges by one distance per region (at
  most ``MAX_OFFSET`` = 0.5 voxel, found by false position on the cleaved tetrahedra touching
  it only) until its volume is its voxel volume: the interface stays within that distance of
  where the labels put it, and conformity and positivity are untouched (a cut point anywhere
  inside its edge keeps every sub-tetrahedron positive; ``info["speck_offsets"]``, world units).

Measured (pyvista's frog at the default size 4, ``benchmarks/bench_regions.py``'s docstring):
the ten specks from 0-57 % off to within 0.9 %, every region within 3.3 %, 12.7 M tetrahedra
instead of 8.85 M and 68.8 s of CPU instead of 42.6 s in one run (1.6x), dihedral angles
[7.1°, 167.0°]. Measured on 13 specks of 1 to 30 voxels (``tests/solid/test_regions_graded.py``, lone, touching
another label or each other, on the volume's edge) at sizes 3, 3.7, 4 and 5 voxels and spacings
(1, 1, 1), (1, 1, 1.5), (0.7, 0.9, 1.3): every region within 3.5 % (before: 20-57 % off, lone
voxels lost). Refining to 0.71 voxel instead left one lone voxel at 19 % (no node inside it
moves far enough), and to 1 voxel 20 %.

Quality: a cut point near a node makes a sliver, and so does a face or tet point near the
boundary of its face or tetrahedron. Two knobs trade them against the interface's accuracy:
``snap`` (default ``SNAP`` = 0.3 of the edge) moves the interface by at most that fraction of an
edge where it snaps; ``INTERIOR`` = 0.2 pulls face and tet points towards the centroid (a tet
point then stays near the middle of its tetrahedron: the interface bends there, on both sides
alike). Measured here (``/tmp`` scripts, then ``benchmarks/bench_regions.py``): nested balls
64^3 (radii 25 and 12, h = 4), snap 0 and INTERIOR 0.05: dihedral angles [0.2°, 178.5°],
core volume -5.5 %; snap 0.3 and INTERIOR 0.2: [18.1°, 149.3°], core -4.2 %; pyvista's frog
at h = 4: [0.06°, 178.5°] -> [12.8°, 159.1°], the large regions' volumes no worse. snap 0.35
moved a plane interface (two 10 x 20 x 20 slabs, h = 3) by 7 % of a slab's volume, so the
default stays at 0.3. Nothing here bounds the angles: they are measured, and ``info`` reports
them. On the graded lattice (frog at h = 4 voxels, [9.3°, 167.0°]) every tetrahedron below the
uniform mesh's 12.8° (235,161 of 8.85 M) is a piece of a cleaved background tetrahedron of the
bisection's classes whose own smallest dihedral angle is 45° (none of a BCC one's, which is 60°;
none a whole tetrahedron): not the transition between sizes as such, nor the snapping, but
the fan (node, node, face point, tet point) of a face point and a tet point pulled only to
``INTERIOR`` inside a flatter tetrahedron (46,385 of the 46,932 below 11°). Pulling further
(face points 0.3, tet points 0.225) lifts the graded frog to [14.3°, 157.3°] (its worst large
region 4.6 % -> 3.1 %) and uniform lattices from [16.8°, 150.0°] (nested balls 64^3) and
[15.6°, 153.0°] (the frog's labels at unit spacing) to [24.0°, 137.0°], but a 2-voxel layer
between two labels (``thin``'s example) goes from -0.1 % to +2.6 % and the balls' core from
+0.02 % to +0.84 %: measured (``/tmp`` scripts), not taken for now.

Conventions (those of ``mesh_surface(..., interfaces="shared")``, :mod:`warpmesh.surface.multilabel`)
-----------------------------------------------------------------------------------------------------
- ``cell_refs["tetra"]``: the label of each tetrahedron (positive volume);
- ``cells["triangle"]``: every triangle between two different regions (between two
  labels, or a label and the rest, which is ``REST`` = 0 unless 0 is meshed, then
  ``min(labels) - 1``); ``cell_refs["triangle"]`` the lower label,
  ``cell_data["label_above"]["triangle"]`` the higher; each triangle's normal points from
  the lower label's side to the higher's (so the boundary of the meshed domain, where the
  rest is the lower label, points inward: flip the triangles naming ``L`` as the higher
  label to get ``L``'s outward boundary, as :func:`warpmesh.surface.multilabel.label_boundary`
  does for surfaces).

Example
-------
>>> import numpy as np, warpmesh as wm
>>> vol = np.zeros((20, 20, 20), dtype=np.uint8)
>>> vol[3:10, 3:17, 3:17] = 1
>>> vol[10:17, 3:17, 3:17] = 2
>>> m = wm.mesh_domain(vol, labels="all", size=3.0)
>>> sorted(set(m.cell_refs["tetra"].tolist())), m.info["negative_tets"]
([1, 2], 0)
>>> [abs(r["error"]) < 0.05 for r in m.info["region_volumes"].values()]  # volume / voxel volume - 1
[True, True]
"""

from __future__ import annotations

import math
import os
import time
import warnings

import numpy as np
import warp as wp

from warpmesh._util.parallel import cpu_view, launch_split
from warpmesh._util.progress import Progress
from warpmesh._util.validate import check_device
from warpmesh.io.images import Volume, as_volume
from warpmesh.kernels import stuffing as K
from warpmesh.mesh import Mesh
from warpmesh.solid.dihedral import signed_volumes, tet_quality_summary
from warpmesh.solid.lattice import lattice_tables
from warpmesh.solid.pockets import fill_pockets
from warpmesh.solid.region_smoothing import smooth_regions
from warpmesh.solid.snapping import snap_cuts
from warpmesh.solid.stuffing import lattice_for
from warpmesh.solid.thin import Specks, VoxelLabels, graded_background, labels_at, speck_voxels
from warpmesh.surface.multilabel import LABEL_ABOVE, label_codes
from warpmesh.surface.options import FLOAT32_RANGE

__all__ = ["mesh_regions", "SNAP", "REFINE_ERROR", "INTERIOR", "SAMPLES_PER_VOXEL"]

#: a cut point within this fraction of its edge's length from a node is snapped onto the node
SNAP = 0.3
#: face and tet points keep every barycentric weight at least this (strictly inside)
INTERIOR = 0.2
#: label samples per voxel along a cut edge
SAMPLES_PER_VOXEL = 4
#: a region whose volume on the uniform lattice is off by more than this (relative) is
#: meshed again on a lattice graded where its edges do not resolve that region's labels
REFINE_ERROR = 0.025
#: the longest edge asked of the lattice over a speck's voxels, in voxels (of the smallest spacing)
SPECK_SIZE = 0.5
#: over a speck of thickness (2 volume / area) t, the lattice is asked edges of about this times t
#: (SPECK_SIZE voxels at least, size / 2 at most)
SPECK_THICKNESS = 1.5
#: a component of a region off by more than REFINE_ERROR is a speck when its volume is at most
#: this many lattice cubes
SPECK_CUBES = 4.0
#: a region of at most this many lattice cubes is searched for specks even when within REFINE_ERROR
SPECK_TOTAL = 16.0
#: a speck region's interface is moved by at most this (voxels) to meet its voxel volume
MAX_OFFSET = 0.5
#: the false-position steps of that move, and the relative volume error they stop at
OFFSET_STEPS = 10
OFFSET_TOLERANCE = 0.01
#: the snapping of the cut points of a speck region's edges
SPECK_SNAP = 0.3
#: the lattice is shifted by this fraction of a voxel along each axis (not a dyadic fraction):
#: with the default size, a power of two times the spacing, the nodes of the lattice and of its
#: refinements would otherwise lie on the voxels' faces (their labels a tie), and a speck's
#: interface could not be moved past them to meet its volume
LATTICE_SHIFT = 0.1
#: the default size, in voxels (of the smallest spacing)
DEFAULT_VOXELS = 4.0

_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
_EDGE_OF = {frozenset(e): k for k, e in enumerate(_EDGES)}
#: faces of a positive tetrahedron, counter-clockwise seen from outside
_FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))


def mesh_regions(volume, bounds=None, *, labels="all", size=None, snap: float = SNAP, min_size=None,
                 smooth: int = 0, device: str = "cpu", progress=False, **refused) -> Mesh:
    """Conforming tetrahedra of the regions of a label volume (lattice cleaving).

    What :func:`warpmesh.mesh_domain` runs when its first argument is a volume.

    Parameters
    ----------
    volume : (nx, ny, nz) integer array, Volume, pyvista ImageData, str or os.PathLike
        Labels; ``volume[i, j, k]`` fills the voxel box centred on ``origin + (i, j, k) *
        spacing`` (a :class:`~warpmesh.io.images.Volume`, an image or a file brings its
        spacing, origin and direction; a bare array has spacing 1 and origin 0). Floats are
        taken when every value is a whole number.
    bounds : None
        A volume's extent is its samples; only shapes take bounds.
    labels : "all" or sequence of int
        The regions to mesh: "all" meshes every value but 0; a sequence meshes those values
        (0 included when listed). The other samples and the outside of the box are the rest
        (not meshed).
    size : float, optional
        The lattice's cube side (the long edges; short edges are sqrt(3)/2 of it), in world
        units. Default: 4 times the smallest spacing, halved until it is below the volume's
        smallest extent (a thin slab).
    snap : float
        Cut points within ``snap`` times their edge's length of a node are snapped onto it,
        in [0, 0.5); 0 keeps every cut where the labels put it. Where the snaps onto a node
        would pinch a region's boundary there, some are pushed to ``snap + PUSH_BEYOND`` from
        it instead (:mod:`warpmesh.solid.snapping`): every region's boundary is a manifold.
    min_size : float, optional
        The smallest longest edge of a graded lattice (world units; default ``size / 2``, one
        level of refinement). When a region's volume on the uniform lattice is off its voxel
        volume by more than ``REFINE_ERROR`` (2.5 %), or the region is lost, the volume is
        meshed again on a lattice refined by conforming longest-edge bisection where its
        edges cross that region's labels more than once (:mod:`warpmesh.solid.thin`: thin
        layers, small regions), down to ``min_size``; elsewhere the cube side stays ``size``.
        Each halving costs about 4 times the tetrahedra along the interfaces it refines.
        Any value above ``size / 2`` (e.g. ``min_size=size``) keeps the lattice uniform; so
        does a volume whose every region is within ``REFINE_ERROR`` (the uniform mesh, bit
        for bit). The regions made only of specks (components of at most ``SPECK_CUBES``
        lattice cubes) are refined to about half a voxel and have their interfaces moved to
        their voxel volumes (the module docstring). A region still off by more than
        ``REFINE_ERROR`` (a blocky one a few cubes across, whose edges cross its labels once:
        nothing to refine, and the snapped cut points move its faces) is named in a
        UserWarning. A graded mesh whose worst refined region is farther off than on the
        uniform lattice (layers about as thin as ``min_size``) is not kept: the uniform mesh
        is returned, with ``info["graded_rejected"]`` (both worst errors). ``info``:
        ``graded``, ``refined_labels`` (when graded),
        ``graded_tets``, ``speck_offsets`` (label: the distance its interface moved, world units).
    smooth : int
        Passes of interface smoothing (:mod:`warpmesh.solid.region_smoothing`; default 0, the
        cleaved staircase): each interface and junction curve smoothed on its own, every
        vertex within ``REACH`` (1) voxel of its cleaved position, each move kept only when
        the tetrahedra around it stay positive and within the mesh's dihedral range, then the
        vertices on no interface smoothed for quality. ``info["smoothing"]`` reports it;
        ``region_volumes`` are those of the smoothed mesh.
    device : str
    progress : bool or callable
        A bar over the stages (tqdm, shown once the call has taken a second; ``mesh_domain``
        passes its own, default True), or ``progress(done, total)`` called as each stage ends
        (stages skipped count as done at the end).

    Returns
    -------
    Mesh
        ``cells["tetra"]`` positive, ``cell_refs["tetra"]`` their labels; ``cells["triangle"]``
        the interfaces and the domain's boundary with ``cell_refs["triangle"]`` (lower label)
        and ``cell_data["label_above"]["triangle"]`` (higher label; for ``"tetra"`` the tetrahedron's own
        label, as the Mesh wants one array per block), oriented from the lower
        label's side to the higher's (the module docstring). ``info``: counts
        (``snapped_cuts``, ``pushed_cuts``, ...),
        ``region_volumes`` (per label: ``volume``, ``voxel_volume``, ``error`` relative),
        the dihedral range, timings.

    Raises
    ------
    ValueError
        A volume that is not 3D or holds non-integer values, ``labels`` not present,
        ``size`` not positive or not below the volume's extent, ``snap`` outside [0, 0.5),
        ``bounds`` or a shape-only option given.
    TypeError
        ``volume`` is not an array, a Volume, an image or a path.

    Example
    -------
    >>> import numpy as np
    >>> vol = np.zeros((16, 16, 16), dtype=np.int16)
    >>> vol[4:12, 4:12, 4:12] = 7
    >>> m = mesh_regions(vol, size=2.0)
    >>> set(m.cell_refs["tetra"].tolist()), set(m.cell_refs["triangle"].tolist()), round(m.stats()["volume"])
    ({7}, {0}, 512)
    """
    t_start = time.perf_counter()
    if refused:
        name = sorted(refused)[0]
        if name in _IMAGE_KEYWORDS:
            raise ValueError(f"{name!r} belongs to the image: wrap the array, mesh_domain(wm.Volume(array, "
                             f"{name}=...), labels=...); a label volume takes 'labels', 'size', 'snap', "
                             "'min_size' and 'smooth'")
        raise ValueError(f"{name!r} is not an option of a label volume's regions (a shape's domain takes it, if "
                         "any); a label volume takes 'labels', 'size', 'snap', 'min_size' and 'smooth'")
    image = _as_image(volume)
    if image.values.ndim == 3 and 0 in image.values.shape:
        raise ValueError(f"expected a 3D label array for 'volume' with samples along every axis, got shape "
                         f"{image.values.shape}")
    if bounds is not None:
        raise ValueError(f"expected no 'bounds' with a label volume (its extent is its samples), got {bounds!r}")
    device = check_device(device)
    if isinstance(snap, bool) or not isinstance(snap, (int, float, np.integer, np.floating)) or not 0 <= snap < 0.5:
        raise ValueError(f"expected 0 <= 'snap' < 0.5 (a fraction of the edge), got {snap!r}")
    if isinstance(smooth, bool) or not isinstance(smooth, (int, np.integer)) or smooth < 0:
        raise ValueError(f"expected a non-negative integer for 'smooth' (passes of interface smoothing), got {smooth!r}")
    codes, ids, rest = label_codes(image.values, labels)
    spacing = np.asarray(image.spacing, dtype=np.float64)
    h = _check_size(size, image.values.shape, spacing)
    smallest = _check_min_size(min_size, spacing, h)
    timings: dict[str, float] = {}
    bar = Progress(progress, _STAGES, "warpmesh mesh_domain (labels)", "stage")
    bar.stage("lattice", 0)
    try:
        mesh = _mesh_regions(image, codes, ids, rest, spacing, h, float(snap), smallest, int(smooth), timings,
                             bar.stage, t_start, device)
        bar.finish()
    finally:
        bar.close()
    return mesh


#: keywords of the image (wm.Volume), not of the meshing: a bare array given with them is told to wrap itself
_IMAGE_KEYWORDS = ("spacing", "origin", "direction")

#: the stages of the progress bar: the uniform pass's, the graded pass's, the smoothing, the quality
_STAGES = 4 + 6 + 1 + 1


def _mesh_regions(image, codes, ids, rest, spacing, h, snap, smallest, smooth, timings, tick, t_start,
                  device) -> Mesh:
    """:func:`mesh_regions` after its checks (``tick(stage)`` as each stage ends)."""
    points, tets, tet_codes, tris, lower, upper, info = cleave(codes, rest, spacing, h, snap, timings, tick=tick)
    info.update(graded=False, min_size=smallest)
    counts = np.zeros(len(ids), np.int64)
    for plane in codes:  # a plane at a time: no int64 copy of the whole volume
        counts += np.bincount(plane.ravel(), minlength=len(ids))
    voxel = float(np.prod(spacing))
    meshed = _region_volumes(points, tets, tet_codes, len(ids))
    if smallest <= 0.5 * h:  # the regions the uniform lattice misses by more than REFINE_ERROR: grade for them
        error = meshed / np.maximum(counts * voxel, 1e-300) - 1.0
        focus = (np.abs(error) > REFINE_ERROR) & (counts > 0)
        focus[rest] = False
        if focus.any():
            timings["uniform_pass"] = time.perf_counter() - t_start
            more = {}
            specks, targets = _specks(codes, focus, spacing, h, counts * voxel, rest)
            del points, tets, tet_codes, tris, lower, upper  # (freed for the graded pass's peak)
            graded = cleave(codes, rest, spacing, h, snap, more, min_size=smallest, focus=focus, specks=specks,
                            targets=targets, tick=tick)
            refined = graded is not None
            if not refined:  # nothing to refine after all (no edge crosses the labels twice): the uniform mesh again
                graded = cleave(codes, rest, spacing, h, snap, more, tick=tick)
                graded[-1].update(graded=False, min_size=smallest)
            points, tets, tet_codes, tris, lower, upper, info = graded
            timings.update(more)
            meshed = _region_volumes(points, tets, tet_codes, len(ids))
            worst = (np.max(np.abs(error[focus])), np.max(np.abs(meshed / np.maximum(counts * voxel, 1e-300) - 1.0)[focus]))
            # the graded pass did worse (layers about as thin as min_size); a tie in rounding is not worse
            if refined and worst[1] > worst[0] + 1e-9:
                del graded, points, tets, tet_codes, tris, lower, upper
                points, tets, tet_codes, tris, lower, upper, info = cleave(codes, rest, spacing, h, snap, more)
                info.update(graded=False, min_size=smallest, graded_rejected={
                    "uniform_error": float(worst[0]), "graded_error": float(worst[1])})
                meshed = _region_volumes(points, tets, tet_codes, len(ids))
                refined = False
            if refined:
                info["refined_labels"] = [int(v) for v in ids[focus]]
            if "speck_offsets" in info:
                info["speck_offsets"] = {int(ids[c]): d for c, d in info["speck_offsets"].items()}
    if not len(tets):
        raise ValueError(f"no lattice node at size {h:g} lies in a region of 'labels' {ids[ids != ids[rest]].tolist()[:20]}"
                         ": the regions are thinner than the lattice; lower 'size'")
    if smooth:
        t0 = time.perf_counter()
        tick("smoothing", 0)
        points, info["smoothing"] = smooth_regions(points, tets, tris, lower, upper, passes=smooth, spacing=spacing,
                                                   shape=image.values.shape, rest=rest, device=device)
        meshed = _region_volumes(points, tets, tet_codes, len(ids))
        tick("")
        timings["smoothing"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    tick("quality", 0)
    quality = tet_quality_summary(points, tets, device)
    tick("")
    timings["quality"] = time.perf_counter() - t0
    region = {}
    for c, label in enumerate(ids.tolist()):
        if c == rest:
            continue
        vv = float(counts[c]) * voxel
        region[int(label)] = {"volume": float(meshed[c]), "voxel_volume": vv,
                              "error": float(meshed[c] / vv - 1.0) if vv else math.nan}
    # placement: world = origin + direction @ local
    d = np.asarray(image.direction, dtype=np.float64)
    points = points @ d.T
    points += np.asarray(image.origin)
    if np.linalg.det(d) < 0:  # a reflection turns every cell over: swap two vertices back
        tets[:, [1, 2]] = tets[:, [2, 1]]
        tris[:, [1, 2]] = tris[:, [2, 1]]
    timings["total"] = time.perf_counter() - t_start
    info.update(quality, method="cleaving", size=h, snap=float(snap), labels=[int(v) for v in ids if v != ids[rest]],
                rest=int(ids[rest]), region_volumes=region, time=timings, space=image.space,
                region_error_max=max((abs(r["error"]) for r in region.values()), default=0.0))
    _warn_unresolved(region, h, float(snap))
    tet_labels, lower, upper = ids[tet_codes], ids[lower], ids[upper]
    for a in (points, tets, tris, tet_labels, lower, upper):  # made here, handed over: the Mesh keeps them, no copy
        a.setflags(write=False)
    return Mesh(points, {"tetra": tets, "triangle": tris}, cell_refs={"tetra": tet_labels, "triangle": lower},
                cell_data={LABEL_ABOVE: {"tetra": tet_labels, "triangle": upper}}, info=info)


def _warn_unresolved(region: dict, h: float, snap: float) -> None:
    """One UserWarning naming the regions still off their voxel volume by more than
    REFINE_ERROR after the graded pass (or where it found no edge crossing the labels twice:
    a blocky region a few lattice cubes across, whose cut points the snapping moves onto
    lattice nodes)."""
    off = {label: r["error"] for label, r in region.items() if abs(r["error"]) > REFINE_ERROR}
    if not off:
        return
    listed = ", ".join(f"label {k}: {v:+.2%}" for k, v in list(off.items())[:8]) + (", ..." if len(off) > 8 else "")
    hint = "a smaller 'size'" + (", or 'snap' 0.1 (cut points kept off the lattice nodes; smaller angles)," if snap > 0.1
                                 else "")
    warnings.warn(f"mesh_domain: {len(off)} region(s) off their voxel volume by more than {REFINE_ERROR:.1%} at "
                  f"size {h:g}, snap {snap:g} ({listed}): {hint} meshes them closer", UserWarning, stacklevel=5)


# ----------------------------------------------------------------------------------- validation
def _as_image(volume) -> Volume:
    if isinstance(volume, (str, os.PathLike)) and not os.path.exists(volume):
        raise TypeError(f"expected a Shape or an expression for 'shape', or a label volume (an array, a wm.Volume, "
                        f"a pyvista ImageData or an image path), got {volume!r}, which names no file")
    image = None if isinstance(volume, np.ndarray) else as_volume(volume)  # (an image file is read here)
    if image is None:
        if not (isinstance(volume, np.ndarray) or hasattr(volume, "__array__")):
            raise TypeError("expected a label volume for 'volume' (an integer array, a wm.Volume, a pyvista "
                            f"ImageData or an image path) or a Shape, got {type(volume).__name__}")
        values = np.asarray(volume)
        if values.ndim != 3:
            raise ValueError(f"expected a 3D label array for 'volume', got {values.ndim}D with shape {values.shape}")
        image = Volume(values)
    if not (np.issubdtype(image.values.dtype, np.number) or image.values.dtype == np.bool_):
        raise TypeError(f"expected integer labels in 'volume', got dtype {image.values.dtype}")
    sp, org = np.asarray(image.spacing, dtype=np.float64), np.asarray(image.origin, dtype=np.float64)
    if np.any(sp < FLOAT32_RANGE[0]) or np.any(sp > FLOAT32_RANGE[1]):  # (the same bounds as mesh_surface's)
        raise ValueError(f"expected the 'volume' spacing between {FLOAT32_RANGE[0]:g} and {FLOAT32_RANGE[1]:g} "
                         f"(tetrahedron volumes must stay normal numbers), got {sp.tolist()}: give the spacing "
                         "in other units")
    if not np.all(np.isfinite(org)) or np.any(sp < 2.0**-36 * np.abs(org)):  # points: origin + local, in float64
        raise ValueError(f"expected a 'volume' origin that float64 resolves at its spacing (|origin| below 2**36 "
                         f"spacings), got origin {org.tolist()} with spacing {sp.tolist()}: move the origin")
    try:
        return image.as_labels()
    except ValueError as exc:
        raise ValueError(f"mesh_domain meshes the regions of a label 'volume': {exc}") from None


def _check_size(size, shape, spacing: np.ndarray) -> float:
    extent = float(np.min(np.asarray(shape) * spacing))
    if size is None:  # DEFAULT_VOXELS voxels, halved (still a power of two) below a thin volume's extent
        size = DEFAULT_VOXELS * float(spacing.min())
        while size >= extent:
            size *= 0.5
    ok = isinstance(size, (int, float, np.integer, np.floating)) and not isinstance(size, bool) \
        and math.isfinite(size) and size > 0
    if not ok:
        raise ValueError(f"expected a positive finite 'size' (the lattice's cube side, world units), got {size!r}")
    if size >= extent:
        raise ValueError(f"expected 'size' below the volume's smallest extent ({extent:g}), got {size!r}")
    n = np.ceil(np.asarray(shape) * spacing / size) + 3
    if 2 * np.prod(n) >= 2**31:
        raise ValueError(f"a lattice of {n.astype(int).tolist()} cubes is too large to index: raise 'size' "
                         f"(got {size!r})")
    return float(size)


def _specks(codes: np.ndarray, focus: np.ndarray, spacing: np.ndarray, h: float, volumes: np.ndarray, rest: int):
    """The speck zones of the regions in ``focus`` and of those of at most ``SPECK_TOTAL``
    lattice cubes in all (their components of at most ``SPECK_CUBES`` lattice cubes, asked a
    size of ``SPECK_SIZE`` voxels; None when there is none) and the volume targets ((c,) the
    voxel volume of each region made only of specks, NaN elsewhere; None when there is none).
    (The small regions not in focus are taken too: the graded lattice is shifted, so their
    cleaving changes.)"""
    look = (focus | (volumes <= SPECK_TOTAL * h ** 3)) & (volumes > 0)
    look[rest] = False
    voxels, thickness, whole = speck_voxels(codes, look, spacing, SPECK_CUBES * h ** 3)
    keep = np.isin(codes[tuple(voxels.T)], whole)  # the regions made only of specks
    voxels, thickness = voxels[keep], thickness[keep]
    if not len(voxels):
        return None, None
    # SPECK_SIZE voxels for the thinnest (a lone voxel), doubling with the thickness (a few levels)
    floor = SPECK_SIZE * float(spacing.min())
    ratio = np.maximum(SPECK_THICKNESS * thickness / floor, 1.0)
    size = np.minimum(floor * 2.0 ** np.floor(np.log2(ratio) + 1e-9), max(floor, 0.5 * h))  # (2 - 4e-16 is 2)
    targets = np.full(len(volumes), np.nan)
    targets[whole] = volumes[whole]
    return Specks(voxels, size, codes.shape, spacing, h), targets if whole else None


def _region_volumes(points: np.ndarray, tets: np.ndarray, tet_codes: np.ndarray, n_codes: int) -> np.ndarray:
    """(n_codes,) the volume of the tetrahedra of each code."""
    return np.bincount(tet_codes, weights=signed_volumes(points, tets), minlength=n_codes)


def _check_min_size(min_size, spacing: np.ndarray, h: float) -> float:
    if min_size is None:
        return 0.5 * h
    ok = isinstance(min_size, (int, float, np.integer, np.floating)) and not isinstance(min_size, bool) \
        and math.isfinite(min_size) and min_size > 0
    if not ok:
        raise ValueError(f"expected a positive finite 'min_size' (the smallest cube side where regions are thin, "
                         f"world units; above size / 2 for a uniform lattice), got {min_size!r}")
    if min_size < 0.25 * float(spacing.min()):
        raise ValueError(f"expected 'min_size' of at least a quarter voxel ({0.25 * float(spacing.min()):g}): "
                         f"finer cubes resolve nothing the labels hold; got {min_size!r}")
    return float(min_size)


# ----------------------------------------------------------------------------------- the lattice
def _node_positions(dims: np.ndarray, origin: np.ndarray, h: float, nodes: np.ndarray) -> np.ndarray:
    cell, colour = nodes // 2, nodes % 2
    c = np.stack([cell % dims[0], (cell // dims[0]) % dims[1], cell // (dims[0] * dims[1])], axis=1)
    return origin + h * (c + 0.5 * colour[:, None])


def _background_tets(dims: np.ndarray, node_code: np.ndarray, rest: int, chunk: int = 32768):
    """The background tetrahedra holding a node of a meshed label: (m, 4) node ids, positive."""
    from scipy.ndimage import binary_dilation

    layout = lattice_tables()[0].astype(np.int64)  # (12, 4, (colour, dx, dy, dz))
    colour, off = layout[:, :, 0], layout[:, :, 1:]
    # the tetrahedra of black node B(c) have their nodes in the cells c + {-1, 0, 1}^3: only the
    # cells next to a meshed node are visited
    grid = (node_code.reshape(-1, 2) != rest).any(axis=1).reshape(dims[::-1])
    cells = np.flatnonzero(binary_dilation(grid, structure=np.ones((3, 3, 3), bool)).ravel())
    out = []
    for a in range(0, len(cells), chunk):  # a loop over batches of cells, not over tetrahedra
        cell = cells[a:a + chunk]
        c = np.stack([cell % dims[0], (cell // dims[0]) % dims[1], cell // (dims[0] * dims[1])], axis=1)
        cc = c[:, None, None, :] + off[None]  # (k, 12, 4, 3)
        limit = dims[None, None, None, :] - colour[None, :, :, None]
        ok = np.all((cc >= 0) & (cc < limit), axis=(2, 3))
        ids = 2 * (cc[..., 0] + dims[0] * (cc[..., 1] + dims[1] * cc[..., 2])) + colour[None]
        ids = ids[ok]
        keep = np.any(node_code[ids] != rest, axis=1)
        out.append(ids[keep])
    return np.concatenate(out) if out else np.zeros((0, 4), np.int64)


def _cut_edges(T: np.ndarray, L: np.ndarray, n_nodes: int):
    """The edges of the tetrahedra ``T`` (M, 4) whose ends' codes ``L`` differ, each once:
    their ends (e_lo < e_hi) and (M, 6) the edge of each local edge (order ``_EDGES``), -1 where
    uncut."""
    ei = np.array([e[0] for e in _EDGES]), np.array([e[1] for e in _EDGES])
    a_, b_ = T[:, ei[0]], T[:, ei[1]]  # (M, 6)
    cut = L[:, ei[0]] != L[:, ei[1]]
    keys, edge_of = np.unique((np.minimum(a_, b_) * n_nodes + np.maximum(a_, b_))[cut], return_inverse=True)
    cut_id = np.full((len(T), 6), -1, np.int64)
    cut_id[cut] = edge_of.ravel()
    return keys // n_nodes, keys % n_nodes, cut_id


def _edge_cuts(codes, rest, spacing, p_lo, p_hi, c_lo, c_hi, chunk: int = 65536) -> np.ndarray:
    """(e,) the parameter of the label change along each edge p_lo -> p_hi."""
    n = max(4, int(math.ceil(SAMPLES_PER_VOXEL * np.max(np.linalg.norm(p_hi - p_lo, axis=1), initial=0.0)
                             / float(spacing.min()) - 1e-9)))  # 4 voxels' edge at spacing 0.7: 16, not 17
    s = (np.arange(n) + 0.5) / n
    t = np.empty(len(p_lo))
    for a in range(0, len(p_lo), chunk):
        lo, hi = p_lo[a:a + chunk], p_hi[a:a + chunk]
        pts = lo[:, None, :] + s[None, :, None] * (hi - lo)[:, None, :]
        lab = labels_at(codes, pts.reshape(-1, 3), spacing, rest).reshape(len(lo), n)
        first = (lab == c_lo[a:a + chunk, None]).sum(axis=1)
        last = (lab == c_hi[a:a + chunk, None]).sum(axis=1)
        t[a:a + chunk] = (first + 0.5 * (n - first - last)) / n
    return np.clip(t, 0.5 / n, 1.0 - 0.5 / n)


def _interior(w: np.ndarray) -> np.ndarray:
    """Barycentric weights (k, m) pulled towards the centroid until each is >= INTERIOR."""
    m = w.shape[1]
    low = w.min(axis=1, keepdims=True)
    gap = 1.0 / m - low
    lam = np.clip((INTERIOR - low) / np.where(gap > 0, gap, 1.0), 0.0, 1.0)
    return (1.0 - lam) * w + lam / m


def _sub_tets(T, L, cut_id, t, e_lo, e_hi, node_pos, n_nodes, snap, rest, timings, lead=None, kernel=True,
              holds_rest=None, largest=np.inf):
    """Steps 3-5 on the cleaved background tetrahedra ``T`` (M, 4) with node codes ``L``: the
    snapped cut points (``t`` along each cut edge e_lo -> e_hi, ``cut_id`` (M, 6) the cut of each
    local edge or -1), face and tet points, sub-tetrahedra (one (k, 4) array, ``lead``'s (tets,
    codes) first when given) and interface triangles (:func:`_fans`; ``kernel=False`` its numpy
    reference). Vertex ids: nodes, then cuts (n_nodes + cut), face points, tet points (one per row).
    With ``holds_rest`` ((q, 4, 3) local corners -> whether a rest sample lies in them), the rest
    pockets the cleaving encloses are filled (:func:`warpmesh.solid.pockets.fill_pockets`,
    ``largest`` the largest background tetrahedron's volume; its info in
    ``timings["pockets_info"]``)."""
    t0 = time.perf_counter()
    # (a function of its own: its (M, 6) and (M, 4, 3) temporaries are freed before the fans)
    cut_vertex, face_vertex, cut_pos, face_pos, tet_pos, n_snapped = _cleave_points(
        T, L, cut_id, t, e_lo, e_hi, node_pos, n_nodes, snap)
    n_faces = len(face_pos)
    timings["points"] = time.perf_counter() - t0

    # -- sub-tetrahedra: star from the tet point over the faces, fans from the face points
    t0 = time.perf_counter()
    tet_base = n_nodes + len(t) + n_faces
    sub, sub_code, tris, lower, upper = (_fans if kernel else _fans_numpy)(
        T, L, cut_id, cut_vertex, face_vertex, tet_base, rest, lead)
    timings["cleave"] = time.perf_counter() - t0
    if holds_rest is not None:
        t0 = time.perf_counter()
        bounds = np.cumsum([0, n_nodes, len(cut_pos), n_faces, len(tet_pos)])
        blocks = (node_pos, cut_pos, face_pos, tet_pos)

        def position(ids):
            out = np.empty((len(ids), 3))
            block = np.searchsorted(bounds, ids, side="right") - 1
            for q in np.unique(block):
                at = block == q
                out[at] = blocks[q][ids[at] - bounds[q]]
            return out

        def rest_pieces(tps):
            rows = tps - tet_base
            pieces = _fans_numpy(T[rows], L[rows], cut_id[rows], cut_vertex, face_vertex[rows], tet_base, rest,
                                 pieces_of="rest")[0]
            pieces[:, 0] = tet_base + rows[pieces[:, 0] - tet_base]  # the subset's tet points are the rows'
            return pieces

        def neighbours(ids):
            fps = ids[(ids >= n_nodes + len(t)) & (ids < tet_base)]  # the face points among them
            if len(fps) == 0:
                return np.zeros(0, np.int64)
            rows = np.flatnonzero(np.isin(face_vertex, fps, kind="table").any(axis=1))  # (a table: no sort)
            return tet_base + rows

        pieces, piece_codes, keep, lower, upper, flip, info = fill_pockets(
            tris, lower, upper, rest, position, rest_pieces, holds_rest, neighbours, largest)
        if len(pieces):
            sub, sub_code = np.concatenate([sub, pieces]), np.concatenate([sub_code, piece_codes])
            tris[flip] = tris[flip][:, [0, 2, 1]]
            tris, lower, upper = tris[keep], lower[keep], upper[keep]
        timings["pockets"] = time.perf_counter() - t0
        timings["pockets_info"] = info
    return cut_pos, face_pos, tet_pos, sub, sub_code, tris, lower, upper, n_snapped, n_faces


def _cleave_points(T, L, cut_id, t, e_lo, e_hi, node_pos, n_nodes, snap):
    """Step 3 of :func:`_sub_tets`: each cut's vertex id (its node where snapped), each row's
    face points ((M, 4) ids, -1 where the face has one code; one per face, named by its nodes),
    and the positions of the cuts, face points and tet points (means of the snapped cuts,
    pulled inside); the numbers of cuts snapped and pushed (a snap that would pinch a region's
    boundary at its node, pushed off it instead: :mod:`warpmesh.solid.snapping`)."""
    M = len(T)
    t, snapped_lo, snapped_hi, pushed = snap_cuts(T, L, cut_id, t, e_lo, e_hi, snap)
    ts = np.where(snapped_lo, 0.0, np.where(snapped_hi, 1.0, t))
    cut_vertex = np.where(snapped_lo, e_lo, np.where(snapped_hi, e_hi, n_nodes + np.arange(len(t))))

    # -- face points (named by the face's nodes) and tet points: means of the (snapped) cuts, inside
    n_cuts = len(t)

    # each local edge's share of its two ends (its cut's parameter from local i to local j; 0
    # where uncut), once: a face's and the tet's weights sum them
    on_edge, to_i, to_j = [], [], []
    for k, (i, j) in enumerate(_EDGES):
        e = cut_id[:, k]
        on = e >= 0
        te = np.where(on, ts[np.maximum(e, 0)], 0.0)
        # ts is along lo -> hi; local i is lo when its node id is the smaller
        t_j = np.where(T[:, i] < T[:, j], te, 1.0 - te)
        on_edge.append(on)
        to_i.append(np.where(on, 1.0 - t_j, 0.0))
        to_j.append(np.where(on, t_j, 0.0))

    def weights_on(corners, edges, rows=slice(None)):
        """Barycentric weights over ``corners`` (local vertex indices) of the mean of the cuts on
        ``edges`` (local edge indices) of each of ``rows``."""
        n_rows = M if isinstance(rows, slice) else len(rows)
        w = np.zeros((n_rows, len(corners)))
        n = np.zeros((n_rows, 1))
        for k in edges:
            i, j = _EDGES[k]
            w[:, corners.index(i)] += to_i[k][rows]
            w[:, corners.index(j)] += to_j[k][rows]
            n[:, 0] += on_edge[k][rows]
        return _interior(w / np.maximum(n, 1.0))

    face_vertex = np.full((M, 4), -1, np.int64)
    face_keys = []
    for f, face in enumerate(_FACES):
        fl = L[:, list(face)]
        fm = np.any(fl != fl[:, :1], axis=1)
        s = np.sort(T[:, list(face)], axis=1)
        face_keys.append(np.where(fm[:, None], s, -1))
    fk = np.stack(face_keys, axis=1)  # (M, 4, 3)
    del face_keys
    mixed_face = fk[..., 0] >= 0
    rows = fk[mixed_face]
    if len(rows):
        if n_nodes < 2**21:
            _, first, inv = np.unique((rows[:, 0] * n_nodes + rows[:, 1]) * n_nodes + rows[:, 2],
                                      return_index=True, return_inverse=True)
        else:
            _, first, inv = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    else:
        first, inv = np.zeros(0, np.int64), np.zeros(0, np.int64)
    face_vertex[mixed_face] = n_nodes + n_cuts + inv.ravel()
    # one representative (row, face) per face point: its weights and nodes, face by face
    at = np.flatnonzero(mixed_face.ravel())[first]
    rep_row, rep_face = at // 4, at % 4
    fw, fn = np.empty((len(at), 3)), np.empty((len(at), 3), np.int64)
    for f, face in enumerate(_FACES):
        on = rep_face == f
        edges = [_EDGE_OF[frozenset((face[q], face[(q + 1) % 3]))] for q in range(3)]
        fw[on], fn[on] = weights_on(list(face), edges, rep_row[on]), T[rep_row[on]][:, list(face)]
    face_pos = np.einsum("kv,kvd->kd", fw, node_pos[fn])
    tw = weights_on([0, 1, 2, 3], range(6))
    tet_pos = np.einsum("kv,kvd->kd", tw, node_pos[T])
    cut_pos = (1.0 - t)[:, None] * node_pos[e_lo] + t[:, None] * node_pos[e_hi]
    return cut_vertex, face_vertex, cut_pos, face_pos, tet_pos, (int(snapped_lo.sum() + snapped_hi.sum()), pushed)


def _holds_rest(codes: np.ndarray, spacing: np.ndarray, rest: int, corners: np.ndarray) -> bool:
    """Whether a sample of code ``rest`` (sample i at i * spacing) lies in one of the
    tetrahedra ``corners`` (q, 4, 3) (its boundary included), or the tetrahedra reach outside
    the volume's samples."""
    lo = np.ceil(corners.reshape(-1, 3).min(axis=0) / spacing - 1e-9).astype(np.int64)
    hi = np.floor(corners.reshape(-1, 3).max(axis=0) / spacing + 1e-9).astype(np.int64)
    if np.any(lo < 0) or np.any(hi >= codes.shape):
        return True
    box = codes[lo[0]:hi[0] + 1, lo[1]:hi[1] + 1, lo[2]:hi[2] + 1]
    at = np.argwhere(box == rest)
    if len(at) == 0:
        return False
    x = (at + lo) * spacing  # (s, 3) the rest samples in the box
    base = corners[:, 0]
    edges = np.stack([corners[:, 1] - base, corners[:, 2] - base, corners[:, 3] - base], axis=2)  # (q, 3, 3)
    det = np.linalg.det(edges)
    if not np.all(det > 0.0):  # (pieces of positive tetrahedra are positive: only a flat one in rounding)
        return True
    inv = np.linalg.inv(edges)
    tol = 1e-9
    step = max(1, (1 << 22) // (3 * len(corners)))  # samples a chunk: (step, q, 3) at most 2^22 values
    for i in range(0, len(x), step):
        w = np.einsum("qij,sqj->sqi", inv, x[i:i + step, None, :] - base[None])  # barycentric weights 1..3
        if np.any((w >= -tol).all(axis=2) & (w.sum(axis=2) <= 1.0 + tol)):
            return True
    return False


def _fan_tables() -> tuple[np.ndarray, np.ndarray]:
    """The tables of :func:`~warpmesh.kernels.stuffing.cleave_fans_kernel`: the faces' local
    corners (4 * 3) and the local edge of each pair of corners (4 * 4, -1 on the diagonal)."""
    edge_of = np.full((4, 4), -1, np.int32)
    for k, (i, j) in enumerate(_EDGES):
        edge_of[i, j] = edge_of[j, i] = k
    return np.array(_FACES, np.int32).ravel(), edge_of.ravel()


def _fans(T, L, cut_id, cut_vertex, face_vertex, tet_base, rest, lead=None):
    """The sub-tetrahedra (k, 4) and their codes (k,), the interface triangles (j, 3) and their
    lower and upper codes of the cleaved tetrahedra ``T`` (M, 4) (codes ``L``, ``cut_id`` (M, 6),
    ``face_vertex`` (M, 4) -1 or the face's point, tet points ``tet_base + row``), by
    :func:`~warpmesh.kernels.stuffing.cleave_fans_kernel` (count, prefix sums, write) over the
    CPU cores; the same arrays, in the same order, as :func:`_fans_numpy`. ``lead``: optional
    (tets, codes) placed first in the outputs (no copy of the two afterwards)."""
    M = len(T)
    faces, edge_of = _fan_tables()
    lead_tets, lead_codes = lead if lead is not None else (np.zeros((0, 4), np.int64), np.zeros(0, np.int64))
    base = len(lead_tets)
    ins = [M, cpu_view(np.ascontiguousarray(T, np.int64).reshape(-1), wp.int64),
           cpu_view(np.ascontiguousarray(L, np.int32).reshape(-1), wp.int32),
           cpu_view(np.ascontiguousarray(cut_id, np.int64).reshape(-1), wp.int64),
           cpu_view(np.ascontiguousarray(cut_vertex, np.int64), wp.int64),
           cpu_view(np.ascontiguousarray(face_vertex, np.int64).reshape(-1), wp.int64),
           wp.int64(tet_base), int(rest), cpu_view(faces, wp.int32), cpu_view(edge_of, wp.int32)]
    tet_at, tri_at = np.empty(8 * M, np.int64), np.empty(4 * M, np.int64)
    empty = cpu_view(np.empty(0, np.int64), wp.int64)
    launch_split(K.cleave_fans_kernel, M, [0, *ins],
                 [cpu_view(tet_at, wp.int64), cpu_view(tri_at, wp.int64), empty, empty, empty, empty, empty])
    n_tets, n_tris = int(tet_at.sum()), int(tri_at.sum())
    tet_at = np.cumsum(tet_at) - tet_at + base  # exclusive prefix sums
    tri_at = np.cumsum(tri_at) - tri_at
    tets, codes = np.empty((base + n_tets, 4), np.int64), np.empty(base + n_tets, np.int64)
    tets[:base], codes[:base] = lead_tets, lead_codes
    tris, lower, upper = np.empty((n_tris, 3), np.int64), np.empty(n_tris, np.int64), np.empty(n_tris, np.int64)
    launch_split(K.cleave_fans_kernel, M, [1, *ins],
                 [cpu_view(tet_at, wp.int64), cpu_view(tri_at, wp.int64), cpu_view(tets.reshape(-1), wp.int64),
                  cpu_view(codes, wp.int64), cpu_view(tris.reshape(-1), wp.int64), cpu_view(lower, wp.int64),
                  cpu_view(upper, wp.int64)])
    return tets, codes, tris, lower, upper


def _fans_numpy(T, L, cut_id, cut_vertex, face_vertex, tet_base, rest, lead=None, pieces_of="meshed"):
    """:func:`_fans` in numpy, face by face (the reference its kernel is tested against);
    ``pieces_of="rest"``: the sub-tetrahedra of the rest instead, which cleaving drops (the
    pockets that :mod:`warpmesh.solid.pockets` fills; the triangles are the same)."""
    mine = (lambda code: code == rest) if pieces_of == "rest" else (lambda code: code != rest)
    tet_vertex = tet_base + np.arange(len(T))
    sub, sub_code, tris, tri_lo, tri_hi = [], [], [], [], []
    if lead is not None:
        sub.append(lead[0])
        sub_code.append(lead[1])
    for f, face in enumerate(_FACES):
        fv = face_vertex[:, f]
        uni = fv < 0
        one = uni & mine(L[:, face[0]])  # a face of one meshed label (those of the rest are dropped)
        sub.append(np.column_stack([tet_vertex[one], T[one][:, list(face)]]))
        sub_code.append(L[one, face[0]])
        mx = np.flatnonzero(~uni)
        # the face's polygon as 6 segment slots, counter-clockwise: (k, x) and (x, k') per edge k -> k',
        # x the edge's cut point (a node when snapped or uncut); each labelled by its lattice node
        start, end, code = (np.empty((len(mx), 6), np.int64) for _ in range(3))
        for q in range(3):
            k, k2 = face[q], face[(q + 1) % 3]
            e = cut_id[mx, _EDGE_OF[frozenset((k, k2))]]
            x = np.where(e >= 0, cut_vertex[np.maximum(e, 0)], T[mx, k2])
            start[:, 2 * q], end[:, 2 * q], code[:, 2 * q] = T[mx, k], x, L[mx, k]
            start[:, 2 * q + 1], end[:, 2 * q + 1], code[:, 2 * q + 1] = x, T[mx, k2], L[mx, k2]
        valid = start != end  # a segment snapped to a point is no segment
        tp, fp = tet_vertex[mx], fv[mx]
        # the sub-tetrahedra of the meshed labels only (those of the rest are dropped)
        slot = np.flatnonzero(valid & mine(code))
        r = slot // 6
        fan = np.empty((len(slot), 4), np.int64)
        fan[:, 0], fan[:, 1] = tp[r], fp[r]
        fan[:, 2], fan[:, 3] = start.ravel()[slot], end.ravel()[slot]
        sub.append(fan)
        sub_code.append(code.ravel()[slot])
        # the next valid slot after each (cyclically): where their codes differ, the triangle
        # (tet point, face point, shared point) lies between two regions
        nxt = np.zeros_like(start)
        for d in range(5, 0, -1):
            cols = (np.arange(6) + d) % 6
            nxt = np.where(valid[:, cols], cols[None, :], nxt)
        cn = np.take_along_axis(code, nxt, axis=1)
        r, c = np.nonzero(valid & (code != cn))
        lower_first = code[r, c] < cn[r, c]
        # (tp, fp, end) is the outward face of the slot's sub-tetrahedron (tp, fp, start, end)
        tris.append(np.where(lower_first[:, None], np.column_stack([tp[r], fp[r], end[r, c]]),
                             np.column_stack([tp[r], end[r, c], fp[r]])))
        tri_lo.append(np.minimum(code[r, c], cn[r, c]))
        tri_hi.append(np.maximum(code[r, c], cn[r, c]))
    return (np.concatenate(sub).astype(np.int64, copy=False), np.concatenate(sub_code).astype(np.int64),
            np.concatenate(tris).astype(np.int64, copy=False), np.concatenate(tri_lo).astype(np.int64),
            np.concatenate(tri_hi).astype(np.int64))


def _offset_cuts(T, L, cut_id, t, e_lo, e_hi, node_pos, node_code, snap, rest, targets, whole, voxel):
    """The cut parameters of the edges with an end of a code ``c`` whose ``targets[c]`` is
    finite (a speck region), and their snapping: such a cut is not snapped but kept within
    ``[SPECK_CLAMP, 1 - SPECK_CLAMP]`` of its edge (the volume is then a continuous,
    non-decreasing function of the move below), and moved along its edge, away from c's node,
    by one distance per code (negative: towards it; at most ``MAX_OFFSET`` voxels), found by
    false position (Illinois) so that c's volume (``whole[c]``, its uncleaved tetrahedra, plus
    its pieces of the cleaved ones) meets ``targets[c]`` (the end of the range nearer it when it
    cannot). Only the cleaved tetrahedra with a node of such a code are cleaved again at each
    step. Returns (t, snap per edge, {code: distance})."""
    sel = np.isfinite(targets)
    rows = sel[L].any(axis=1)
    # and every cleaved tetrahedron around their nodes: the snapping of a cut sees its nodes'
    # whole links (:mod:`warpmesh.solid.snapping`), so the fit meshes what the final pass meshes
    # (the added tetrahedra hold no speck code: the volumes are unchanged)
    near = np.zeros(int(T.max()) + 1, bool)
    near[T[rows].ravel()] = True
    rows = np.flatnonzero(near[T].any(axis=1))
    c_lo, c_hi = node_code[e_lo], node_code[e_hi]
    edge = sel[c_lo] | sel[c_hi]
    length = np.linalg.norm(node_pos[e_hi] - node_pos[e_lo], axis=1)
    snaps = np.where(edge, SPECK_SNAP, snap)
    codes = np.flatnonzero(sel)
    T, L, cut_id = T[rows], L[rows], cut_id[rows]
    n_nodes = len(node_pos)

    def moved(d):
        shift = np.where(sel[c_lo], d[c_lo], 0.0) - np.where(sel[c_hi], d[c_hi], 0.0)
        return np.where(edge, np.clip(t + shift / length, 1e-3, 1.0 - 1e-3), t)

    def error(x):
        d = np.zeros(len(targets))
        d[codes] = x
        cut_pos, face_pos, tet_pos, sub, sub_code, *_ = _sub_tets(T, L, cut_id, moved(d), e_lo, e_hi, node_pos,
                                                                  n_nodes, snaps, rest, {})
        pos = np.concatenate([node_pos, cut_pos, face_pos, tet_pos])
        vol = np.bincount(sub_code, signed_volumes(pos, sub), len(targets)) + whole
        return vol[codes] / targets[codes] - 1.0

    limit = MAX_OFFSET * voxel
    a = np.zeros(len(codes))
    ea = error(a)
    best, best_e = a.copy(), ea.copy()
    b = -np.sign(ea) * 0.05 * voxel  # a first step, then secant steps until the error changes sign,
    bracket = np.zeros(len(codes), bool)  # then false position (Illinois) inside [a, b]
    side = np.zeros(len(codes), np.int64)
    eb = ea
    for step in range(OFFSET_STEPS):
        todo = np.abs(best_e) > OFFSET_TOLERANCE
        if not todo.any():
            break
        if step:
            den = np.where(eb != ea, eb - ea, 1.0)
            secant = np.where(eb != ea, b - eb * (b - a) / den, b + (b - a))
            slope_ok = (eb - ea) * (b - a) > 0  # more distance, more volume
            reach = 4.0 * np.abs(b - a)  # an extrapolation goes at most 4 steps
            c = np.where(bracket, np.clip(secant, np.minimum(a, b), np.maximum(a, b)),
                         np.where(slope_ok, b + np.clip(secant - b, -reach, reach), b + 2.0 * (b - a)))
            c = np.where(todo, np.clip(c, -limit, limit), best)
        else:
            c = np.where(todo, b, best)
        ec = error(c)
        better = todo & (np.abs(ec) < np.abs(best_e))
        best[better], best_e[better] = c[better], ec[better]
        if not step:
            b, eb = c, ec
            bracket = todo & (np.sign(eb) != np.sign(ea))
            continue
        same = np.sign(ec) == np.sign(eb)
        in_b = todo & bracket & same  # c replaces b; a kept (Illinois: halve ea when kept twice)
        in_a = todo & bracket & ~same  # c replaces a; b kept
        ea = np.where(in_b & (side == 1), 0.5 * ea, ea)
        eb = np.where(in_a & (side == -1), 0.5 * eb, eb)
        side = np.where(in_b, 1, np.where(in_a, -1, side))
        free = todo & ~bracket  # not bracketed yet: the last two points
        a, ea = np.where(free, b, np.where(in_a, c, a)), np.where(free, eb, np.where(in_a, ec, ea))
        turned = free & ~same
        b, eb = np.where(free | in_b, c, b), np.where(free | in_b, ec, eb)
        bracket = bracket | turned
    d = np.zeros(len(targets))
    d[codes] = best
    return moved(d), snaps, {int(c): float(x) for c, x in zip(codes, best)}


# ----------------------------------------------------------------------------------- cleaving
def cleave(codes: np.ndarray, rest: int, spacing, h: float, snap: float, timings: dict | None = None,
           min_size: float | None = None, focus=None, specks=None, targets=None, fill: bool = True, tick=None):
    """Tetrahedra of every region of ``codes`` but ``rest`` (local coordinates: sample i at i * spacing).

    ``tick``: optional, called with the next stage's name as each stage ends (a progress bar).

    ``fill``: fill the pockets of the rest that the cleaving encloses and the labels do not
    hold (:mod:`warpmesh.solid.pockets`; ``filled_pockets``, ``filled_volume`` and
    ``kept_cavities`` in the info).

    ``min_size``: None keeps the lattice uniform; a size refines it where its edges do not
    resolve the labels (of the codes where ``focus``, (c,) bool, is True, when given), down to
    that size (:mod:`warpmesh.solid.thin`), and None is returned when nothing needs it.

    Returns
    -------
    points : (n, 3) float64
    tets : (m, 4) int64, positive
    tet_codes : (m,) the code of each tetrahedron
    triangles : (k, 3) int64, oriented from the lower code's side to the higher's
    lower, upper : (k,) codes on either side
    info : dict of counts
    """
    timings = {} if timings is None else timings
    tick = tick or (lambda name: None)
    spacing = np.asarray(spacing, dtype=np.float64)
    t0 = time.perf_counter()
    shape = np.asarray(codes.shape)
    box = np.array([-0.5 * spacing, (shape - 0.5) * spacing])
    dims, origin = lattice_for(box, h)
    if specks is not None:
        origin = origin - LATTICE_SHIFT * spacing
    graded = {"graded": False, "min_size": min_size}
    found = None
    if min_size is not None:
        found = graded_background(codes, rest, spacing, dims, origin, h, min_size,
                                  VoxelLabels(codes, spacing, rest), SAMPLES_PER_VOXEL, focus, specks)
        if found is None:
            return None
        tick("lattice")
    timings["grade"] = time.perf_counter() - t0
    if found is None:  # the uniform lattice (nothing to refine, or min_size None)
        n_nodes = 2 * int(np.prod(dims))
        node_pos = _node_positions(dims, origin, h, np.arange(n_nodes))
        node_code = labels_at(codes, node_pos, spacing, rest)
        bg = _background_tets(dims, node_code, rest)
    else:
        node_pos, node_code, bg, more = found
        graded.update(more, graded=True)
        n_nodes = len(node_pos)
    timings["lattice"] = time.perf_counter() - t0 - timings["grade"]
    t0 = time.perf_counter()
    lab = node_code[bg]
    mixed = np.any(lab != lab[:, :1], axis=1)
    whole, whole_code = bg[~mixed], lab[~mixed, 0]
    T, L = bg[mixed], lab[mixed]
    n_bg = len(bg)
    del bg, lab, mixed, found  # (the background is in whole and T now: freed for the cleaving's peak)
    timings["lattice"] += time.perf_counter() - t0
    tick("cut points")

    # -- cut points, one per edge with two labels (named by the edge)
    t0 = time.perf_counter()
    e_lo, e_hi, cut_id = _cut_edges(T, L, n_nodes)
    t = _edge_cuts(codes, rest, spacing, node_pos[e_lo], node_pos[e_hi], node_code[e_lo], node_code[e_hi])
    timings["cuts"] = time.perf_counter() - t0
    tick("speck interfaces" if targets is not None else "cleaving")
    n_cuts = len(e_lo)
    if targets is not None:  # the specks' interfaces moved until their volumes are their voxel volumes
        t, snap, moved = _offset_cuts(T, L, cut_id, t, e_lo, e_hi, node_pos, node_code, snap, rest, targets,
                                np.bincount(whole_code, signed_volumes(node_pos, whole), len(targets)),
                                float(np.min(spacing)))
        graded["speck_offsets"] = moved
        timings["offsets"] = time.perf_counter() - t0
        tick("cleaving")
    cut_pos, face_pos, tet_pos, tets, tet_codes, triangles, lower, upper, n_snapped, n_faces = _sub_tets(
        T, L, cut_id, t, e_lo, e_hi, node_pos, n_nodes, snap, rest, timings, lead=(whole, whole_code),
        holds_rest=(lambda corners: _holds_rest(codes, spacing, rest, corners)) if fill else None,
        largest=h ** 3 / 12.0)  # (a BCC tetrahedron; bisection only makes smaller ones)
    pockets = timings.pop("pockets_info", {})
    tick("compacting")

    # -- compact the vertex ids
    t0 = time.perf_counter()
    all_pos = np.concatenate([node_pos, cut_pos, face_pos, tet_pos])
    used = np.zeros(len(all_pos), bool)
    used[tets.ravel()] = True
    used[triangles.ravel()] = True
    new_id = np.cumsum(used) - 1
    points = all_pos[used]
    tets_out = np.take(new_id, tets, out=tets, mode="clip")  # in place ("clip": unbuffered; all ids are in range)
    tris_out = np.take(new_id, triangles, out=triangles, mode="clip")
    timings["compact"] = time.perf_counter() - t0
    tick("")
    info = {"lattice": tuple(int(x) for x in dims), "background_tets": n_bg, "whole_tets": int(len(whole)),
            "cleaved_tets": int(len(T)), "cut_edges": int(n_cuts), "snapped_cuts": n_snapped[0],
            "pushed_cuts": n_snapped[1],
            "face_points": int(n_faces), "n_interface_triangles": int(len(tris_out)), **pockets, **graded}
    return points, tets_out, tet_codes, tris_out, lower, upper, info
