"""Self-intersection check of triangle surfaces: which pairs of triangles cross.

Closed-and-manifold checks pass on surfaces whose triangles cross each other, so the
validity checks run this geometric one too. The pipeline (kernels in
:mod:`warpmesh.kernels.intersect`):

1. validate, convert once: points float64 scaled by a power of two (exact: no product
   of the predicates over- or underflows), float32 copies in [-1, 1]^3 for the BVH,
   triangles int32;
2. the candidate search chosen (:func:`_grid_cell`): a cell grid when the faces are about
   one size (the largest side of a face's float32 box at most ``_GRID_SPREAD`` = 2 times
   the mean: the grid methods' surfaces, icospheres), else a tree over groups of faces
   (adaptive meshes, a few large faces among small ones); faces sorted (radix sort; for
   the grid on two CPU threads, by halves then merged: :func:`_split_sort`) by the
   Morton key of the grid cell of their box's lower corner, or for the tree of their
   centroid; then in one pass degenerate faces flagged and given an empty box (they
   meet nothing), each face's float32 box stored once;
3. the umbrella certificate: vertex -> corners on the device (counts by atomic add,
   ``wp.utils.array_scan``, fill), then one thread per vertex v decides from F_v, its
   faces, alone whether any two of them can meet other than in what they share
   (:func:`~warpmesh.kernels.intersect.umbrella_certified`: one closed fan whose wedges
   are all strictly of one orientation in some coordinate projection and wind once
   about v; the proof is in its docstring), from per-face codes of orientation signs and
   coordinate comparisons made with the degenerate flags; a flag per corner; for the
   grid, in the same pass, the face across each corner's outgoing edge when it is the
   only face with the reversed edge and the corner's face the only one with the edge
   (``partners``: the pairing of edges the block certificate uses);
4. the grid: the cell side is twice the largest box side, and the padding (each face's
   box then spans at most two cells per axis; a face that spans more, by rounding, would
   send the check to the tree), at most 1022 cells per axis; the occupied
   cells are the runs of equal keys (heads, scan), and a two-level table (blocks of 8^3
   cells, a slot for each used block) maps cell coordinates to cells; each cell keeps
   the axes along which its faces reach the next cell up (``cell_reach``). Then the
   block certificate (:func:`_certify_blocks`,
   :func:`~warpmesh.kernels.intersect.block_certified`): blocks of 64, 32, 16, then 8
   cells per axis (consecutive cells in Morton order), one thread each, certified when
   their faces keep one strict orientation in some coordinate projection and the edges
   not paired inside the block project to a simple polygon (every edge turning strictly
   counter-clockwise about their mean with one crossing of a ray from it, else tested
   pair by pair), every sign and comparison holding by a margin (``INPUT_TOL``, as the
   predicate's certificates of separation: a pair it reports as touching within
   rounding is never in a certified block); no two faces of such a block meet other
   than in what they share (the proof is in its docstring), and each cell records the
   size of its certified block. A block inside a certified larger one is not tried.
   The tree: a
   complete binary tree over groups of ``GROUP`` = 16 consecutive faces (compact
   patches) in heap order, leaves padded to a power of two with empty boxes, nodes
   holding the union of their leaves' float32 boxes, built bottom up, one launch per
   level;
5. the grid walk (:func:`~warpmesh.kernels.intersect.grid_walk_cell`): one thread per
   occupied cell, its faces against the later faces of the cell and every face of those
   of its 13 upper neighbours that the two cells' faces can reach, less the cells of its
   certified block, itself included (each unordered pair
   once; none missed, the cell coordinate being
   a monotone function of the float32 coordinate: boxes that meet have lower corners at
   most one cell apart per axis), each face screened by its own grown box; or one
   thread per group g: a depth-first walk of the tree with g's box
   (:func:`~warpmesh.kernels.intersect.tree_next`) that never enters a subtree of groups
   all before g, so it meets only the groups h >= g; for each, the faces of g whose boxes
   meet h's, against the faces of h whose boxes meet theirs (only later ones when h == g):
   so each unordered pair of faces is screened and tested once, exactly in float64 with
   the face of the lower input index as the predicate's first triangle, unless the two
   share a vertex whose umbrella is certified (then they meet only in what they share:
   skipped after the box test, before their points are loaded); count per cell or
   group, prefix sum (``wp.utils.array_scan``), then a second walk, only for those with
   hits, writes each pair as the key min(f, g) m + max(f, g) at its offset; a
   radix sort of the keys on the device gives the output sorted, with no host sort
   (count -> scan -> allocate -> write).

Stop 51, the block certificate (``--cases part,ball --resolution 512 --repeat 5``, 2
workers, stop 50's code (60ec228, installed in a venv of its own) and this one run
alternately, twice each, load about 1.1): the ball's check 0.332 / 0.333 -> 0.264 /
0.324 s wall, 0.606 / 0.620 -> 0.456 / 0.512 CPU s (0.81 / 0.78 -> 0.66 / 0.71x its
meshing's wall time); the part's 0.290 / 0.286 -> 0.202 / 0.238 wall, 0.544 / 0.532 ->
0.365 / 0.402 CPU (0.53 / 0.50 -> 0.36 / 0.39x). Of the ball's occupied cells 99.95 % lie
in certified blocks (most at 64^3), of the part's 94 %. Profile of the ball (wall s,
stop 50 -> 51): walk 0.155 -> 0.014, cells 0.021 -> 0.050 (the blocks' 0.03: a pass over
the faces, the star test, the pair-by-pair polygon test where that fails), umbrellas
0.063 -> 0.072 (the pairing, made in the same read of each vertex's faces). Tried:
blocks of one size, 8^3 (walk 0.065), 16^3 (0.038), 32^3 (0.024, but the part's
certified share falls to 72 %): hence the sizes tried largest first (after a review,
every decision of the certificate holds by a margin; measured after it, load 1.7: part
0.225 s, ball 0.281 s, the same cells certified; the faces' signs by a margin cost
the faces pass 0.033 -> 0.044 s on the ball, 0.037 once taken from the same
determinant as the exact ones with a constant allowance for moves, ``FACE_MOVED``);
the simple-polygon test pair by pair without the run boxes (the ball's blocks 48 -> 32 ms with them), with
float64 segments in the scratch (44 bytes an edge: fresh pages, 25-78 ms on the part
from one call to the next, against 21-24 ms with 12 bytes); the pairing made at
certified vertices only, then at both ends (no block of an open surface could be
certified: its boundary vertices are never certified); the umbrella's permutation test
and the pairing's counts in one 8 x 8 loop (no faster: the pass is memory bound).

Stop 52, the passes before the walk (``--cases part,ball --resolution 512 --repeat 5``, 2
workers, stop 51's code (3983e1f, in a venv of its own) and this one run alternately,
twice each, load about 1.0): the ball's check 0.239 / 0.244 -> 0.193 / 0.189 s wall,
0.428 / 0.441 -> 0.341 / 0.348 CPU s (0.59 / 0.61 -> 0.49 / 0.48x its meshing's wall
time, 0.64 / 0.68 -> 0.53 / 0.55x its CPU time); the part's 0.215 / 0.213 -> 0.181 /
0.181 wall, 0.382 / 0.383 -> 0.331 / 0.334 CPU (0.40 / 0.39 -> 0.33 / 0.34x). At 1024
(``--repeat 3``): the ball 0.698 s, 0.47x (stop 51: 0.64x), the part 0.660 s, 0.29x. What
did it, each measured alone (wall ms on the ball unless said): the grid's cell twice the
largest face side and blocks of 128^3 down to 4^3 cells (``_GRID_CELL_SCALE``,
``BLOCK_SHIFTS``: fewer cells, so fewer passes per cell, while the blocks keep the
candidates away; profile total 242 -> 211, the part 225 -> 210); the inputs prepared in
three passes on both cores (:func:`_prepare`, 15 -> 9, with the faces' box sides for the
grid taken in its pass over the faces: order 51 -> 42); the grid keys' interleave from
a table and their width test branch-free (half the ball's keys 16 -> 10 on one thread);
a function per umbrella size (5 to 8 faces: loops of constant length; the pass -10 to
-25 %); the crossing bits of the three rotations from six comparisons a coordinate (the
faces pass on one thread 31 -> 24); numpy's cumsum replaced by Warp's scan in the corner
table; dead arrays reused for the sorted faces, the corner table and the cell table's
heads (269 -> 214 MB of fresh pages a call: the system time, 25-130 ms a call from the
kernel zeroing and compacting huge pages, falls to about 40). The cell table keeps a
512-bit mask and 8 ranks per used block of 8^3 cells (1.2 MB on the ball, was 26 MB of
cell indices; no faster). Profile of the ball now (wall ms): prepare 14, order 36, faces
33, corner table 13, umbrellas 51, cells and blocks 34, walk 5. Tried and not kept: the
umbrella flags computed after the blocks, for the vertices of cells the walk visits only
(the ball -7 to -9 ms, but 48 % of the part's vertices are in such cells: +3 to +17 there);
the faces gathered in the classifying pass (the random reads move, no gain); the float32
boxes computed from the float64 points in that pass (-2 ms); a radix sort of our own on
both cores (3 passes of 9 bits: 40 ms against Warp's 33 on one core for 1.7 M keys); the
corner table holding each corner's two other vertices and code (16 bytes a slot: fresh
pages, 77 against 73 ms); the permutation test and the partners from one set of
comparisons; a branch-free classification; ``-O3``.

Where the time goes (:func:`profile_self_intersections`, ``workers=1``, CPU s, medians
of 5, load about 1; the bundled part at resolution 512, 1.5 M triangles with large
grid-aligned flat regions / a ball at 512, 1.7 M; both take the grid): prepare 0.013 /
0.018, order 0.068 / 0.090, faces (flags, codes, boxes) 0.050 / 0.061, umbrellas 0.082 /
0.102, cells 0.025 / 0.029, the walk 0.262 / 0.296: 0.50 / 0.60 in all (stop 49: 0.80 /
0.78 before its walk tuning, then about 0.60 / 0.69). The ball's walk, per face: 12 box
tests, 7.5 pass, 6.2 of those share a certified vertex and skip the exact test, 1.3 get
it; measured by cutting the walk short, the neighbour lookups cost 0.05 CPU s, the box
screen with the query faces' loads 0.14, the shared-vertex skips 0.06, the exact tests
0.05. Stop 50's changes, same-run A/B on the ball (walk CPU s, 2 workers): whole
neighbour cells skipped by their faces' reach bits (``cell_reach``) 0.418 -> 0.349; the
query face loaded before its candidates, not at its first one (a value set inside the
loops is carried through every iteration by Warp's code: a select and a copy of a
72-byte matrix, and more, on each box test) 0.351 -> 0.303 (part 0.307 -> 0.268); the
grid keys sorted by halves on two threads and merged, the order stage 53 -> 40 ms wall;
scratch from numpy (huge pages: a fresh 40 MB array's first touch 8 ms against Warp's
allocator's 20 ms). Tried and not kept: the box passes gathered branch-free into a list
first (0.30 -> 0.35: the list is carried through the loop), the shared-vertex test
inlined before the candidate call (0.35 -> 0.40), the plane sides of the second face
before the box confirmation (slower on both), vertices renumbered in the faces' order for
the umbrellas (5 %), ``counting_sort`` for the vertex -> corner table (31 ms against the
atomics' 19 ms on one thread). Not met at stop 50: the check at half the meshing's time
on the ball (its meshing, a sphere's field, is the cheapest there is); the walk alone was
about 0.4x of it. Earlier measurements: the tree walk costs 1.4-2x the grid's on these surfaces
(46 face-face box tests a face against 10-20); the grid on an adaptive surface (the part
adaptive at 256, 92 k faces, largest side 4.5 x the mean) 0.136 CPU s against the tree's
0.067, hence ``_GRID_SPREAD``; faces whose boxes only *touch* along an axis are decided
before the predicate (:func:`~warpmesh.kernels.intersect._apart_on_touching_boxes`:
their parts in the common plane compared; the pairs of neighbouring grid cells), the
part's walk 0.89 -> 0.60 CPU s at stop 36. Estimated in numpy on the part (box tests a
face): cells of one face side with each face in every cell it meets, 15.5, but 4.2
entries a face to sort; lower-corner cells, taken, 10.4 at 1x the largest side, 16.8 at
1.25x, 43 at 2x.
Tried on the tree walk and not kept (same-run ratios 0.99-1.10): the plane sides of the
second face taken first and passed to the predicate; the predicate's plane-side exits in
a function of their own; one call site of the predicate; both normals passed in or read
from per-face arrays; a shortcut to the 2D tests for faces of one grid plane;
branch-free signs and box tests; half-group boxes; -O3; groups of 8 or 32; vertices
renumbered in the faces' order; the sharing pairs skipped before the box test (1.07);
certificate variants (the dominant normal axis only: 304 of the part's 752,262 vertices
left uncertified, and slower). :func:`_all_pairs`, every pair with the same predicate
and no candidate search, is the tests' reference; pairs proved apart by the faces'
exact float64 coordinates never reach the predicate (``confirmed_pair_intersects``: a
face collinear to within rounding but not flagged degenerate "touches" faces far from it
by ties alone), so the two agree whatever pairs a search offers.

Warp's CPU backend runs a launch on one thread, so on the CPU launches are split into
ranges of groups (``_CHUNKS`` per worker, dealt round-robin) run from Python threads
(launches release the GIL); every group's result depends on the one tree only, so the
answer does not depend on ``workers``.

The float32 tree loses no candidate: the map float64 -> float32 behind both the tree's
boxes and the query boxes is monotone in each coordinate, so boxes that meet in float64
meet in float32; the query boxes are grown by a few float32 ulps besides (the grid's
faces carry upper corners grown so, and each face's lower corner is compared with the
other's grown upper corner: symmetric, which the grid's neighbourhood argument needs).
"""

from __future__ import annotations

import itertools
import time
from typing import NamedTuple

import numpy as np
import warp as wp

from warpmesh._util.validate import check_device
from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.parallel import cpu_view, device_empty, device_zeros, run_parallel, usable_cores
from warpmesh.cells.rays import ray_windings
from warpmesh.cells.predicates import orient3d_signs, power_of_two_scaled
from warpmesh.cells.types import points3, require_mesh
from warpmesh.kernels import intersect as K

__all__ = ["check", "find_self_intersections", "count_self_intersecting_faces", "find_degenerate_faces",
           "find_segment_intersections", "find_tet_overlaps", "profile_self_intersections", "tet_faces",
           "TetFaces"]

#: query boxes are grown by this much, in BVH coordinates (points in [-1, 1]^3): 4 float32 ulps at 1
_QUERY_PAD = 4.0 * 2.0**-24
#: faces per worker below which a CPU launch is not split
_MIN_FACES_PER_WORKER = 1 << 13
#: ranges of groups per CPU worker
_CHUNKS = 8
_INT32_MAX = np.iinfo(np.int32).max
#: let the grid walk skip the pairs inside blocks of cells certified whole (the kernels'
#: ``block_certified``); off only to measure or test the check without it
_CERTIFY_BLOCKS = True
#: skip the pairs that share a vertex whose umbrella is certified (the kernels'
#: ``umbrella_certified``); off only to measure or test the check without it
_CERTIFY = True
#: the cell grid is the candidate search when the largest face box side is at most this
#: times the mean one (:func:`_grid_cell`), else the group tree
_GRID_SPREAD = 2.0
#: the grid's cell side over the largest face box side (at least 1 and a margin for the
#: rounding of the cell coordinates: :func:`_grid_order` falls back to the tree if a face
#: spans more than two cells). Twice: with the blocks certified, the passes per cell cost
#: more than the candidates per face (wall ms, the ball / the part at 512, with blocks of
#: 128^3 to 4^3 cells: 1.5x 230 / 235, 2x 211 / 210, 2.5x 209 / 202; with 64^3 to 8^3,
#: 1.001x 242 / 225, 2x 220 / 218, 3x 280 / 226)
_GRID_CELL_SCALE = 2.0
_TINY_LENGTH = 1.0e-30


def find_self_intersections(points, triangles, *, device: str = "cpu", workers: int | None = None) -> np.ndarray:
    """The pairs of triangles that intersect other than through shared vertices.

    What counts, for two non-degenerate triangles sharing k vertex *indices*:

    - k = 0: any common point (crossing, touching at a point or along a segment,
      coplanar overlap);
    - k = 1: a common point other than the shared vertex (an edge piercing the other
      triangle, coplanar overlap beyond the vertex);
    - k = 2 (a shared edge): both in one plane and folded onto each other (the opposite
      vertices on the same side of the edge), as a bad edge collapse leaves them;
    - k = 3 (the same vertex triple in any order, a duplicate face): always.

    Points with equal coordinates but different indices are different vertices: two
    triangles meeting there touch (k = 0). Degenerate faces (zero area to within
    float64 rounding, or a repeated index) are skipped; :func:`find_degenerate_faces`
    lists them.

    The predicates run in float64 on the given coordinates with a static error bound;
    a configuration within rounding of touching (relative 1e-15) is decided as touching,
    i.e. reported. Exact for coordinates on which the determinants are computed exactly
    (e.g. small integers). Nearly coplanar neighbours are not reported for touching
    only through what they share: a "touching" that rests on a sign within rounding is
    kept only if the pair's projection on the plane is not certified apart (by more
    than rounding and a few ulps of the coordinates), so collinear edges pointing
    opposite ways from a shared vertex meet only there, and coplanar triangles on
    opposite sides of a shared edge do not fold (a fan of coplanar triangles, the flat
    parts of a refined surface). This never drops an exact intersection.

    Pairs that share a vertex whose umbrella is certified are decided without the
    predicate: when the faces with that vertex index form one closed fan whose wedges,
    projected on some coordinate plane, are all strictly of one orientation and wind once
    about it, any two of them meet only in what they share (proved in
    :func:`~warpmesh.kernels.intersect.umbrella_certified`), so such pairs are never
    reported, not even when the predicate alone would call them touching within
    rounding. The answer with the certificate is the exact one wherever the predicate's
    is (it only drops pairs that do not intersect exactly); near-tie reports can come
    only from pairs around uncertified vertices (a fold, a pinch, a duplicate face, a
    boundary, more than 16 faces) or sharing no vertex. On the closed surfaces the
    package produces, every vertex is typically certified.

    Parameters
    ----------
    points : (n, 3) array_like of float
        Vertex coordinates, finite.
    triangles : (m, 3) array_like of int
        Vertex indices of each triangle, in [0, n).
    device : str
        Warp device, "cpu" (default) or "cuda".
    workers : int, optional
        CPU threads for the BVH walks (default: the machine's cores); ignored on CUDA.

    Returns
    -------
    (k, 2) ndarray of int64
        Pairs (i, j), i < j, of intersecting triangles, sorted lexicographically.

    Raises
    ------
    TypeError
        ``points`` not real numbers, ``triangles`` not integers.
    ValueError
        Wrong shapes, NaN or infinite coordinates, indices out of range, ``workers`` < 1.

    Examples
    --------
    Two triangles crossing each other, and one far away:

    >>> import numpy as np
    >>> from warpmesh.cells.intersections import find_self_intersections
    >>> points = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0],
    ...                    [0.5, 0.5, -1], [0.5, 0.5, 1], [1.5, 1.5, 0],
    ...                    [9, 9, 9], [10, 9, 9], [9, 10, 9]], dtype=float)
    >>> find_self_intersections(points, [[0, 1, 2], [3, 4, 5], [6, 7, 8]])
    array([[0, 1]])
    """
    pts, tris = _validate(points, triangles, values=False)  # the values: checked by _prepare, on all cores
    n_workers = _check_workers(workers)
    device = check_device(device)
    if len(tris) < 2:
        _check_values(pts, tris)
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    with wp.ScopedDevice(device):
        return _find_pairs(pts, tris, wp.get_device(device), n_workers)


def count_self_intersecting_faces(points, triangles, *, device: str = "cpu", workers: int | None = None) -> int:
    """How many triangles intersect some other triangle (what a face selection by
    self-intersection selects); the rules are those of :func:`find_self_intersections`.

    Parameters
    ----------
    points : (n, 3) array_like of float
    triangles : (m, 3) array_like of int
    device : str
    workers : int, optional

    Returns
    -------
    int
        The number of distinct triangles that appear in the pairs.

    Raises
    ------
    TypeError, ValueError
        As :func:`find_self_intersections`.

    Examples
    --------
    A square of two triangles and a copy of one of them (a duplicate face):

    >>> from warpmesh.cells.intersections import count_self_intersecting_faces
    >>> square = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    >>> count_self_intersecting_faces(square, [[0, 1, 2], [0, 2, 3], [2, 0, 1]])
    2
    """
    pairs = find_self_intersections(points, triangles, device=device, workers=workers)
    return int(np.unique(pairs).size)


def profile_self_intersections(points, triangles, *, device: str = "cpu", workers: int | None = None) -> dict:
    """Where :func:`find_self_intersections` spends its time: the same call, with the
    device synchronised after each stage and the clocks read there.

    Stages: ``prepare`` (validation, scaling, upload, float32 BVH coordinates), ``order``
    (the choice of search, Morton keys, radix sort, gather), ``faces`` (the faces'
    degenerate flags, codes and boxes), ``umbrellas`` (the umbrella certificate), then
    ``cells`` (the grid's cell table and reach bits), or ``boxes`` and ``tree`` (the
    group boxes and the group tree's build), ``count walk`` (the walk with every exact
    test), ``scan``, and
    when there are pairs ``write walk`` and ``sort pairs``. The synchronisations cost a
    little: the stages add up to slightly more than an unprofiled call.

    Parameters
    ----------
    points, triangles, device, workers
        As :func:`find_self_intersections`.

    Returns
    -------
    dict
        ``"cpu"``: {stage: process CPU seconds (every thread)}, ``"wall"``: {stage: wall
        seconds}, in pipeline order, and ``"pairs"``: the number of intersecting pairs.

    Raises
    ------
    TypeError, ValueError
        As :func:`find_self_intersections`.

    Examples
    --------
    >>> from warpmesh.cells.intersections import profile_self_intersections
    >>> square = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    >>> prof = profile_self_intersections(square, [[0, 1, 2], [0, 2, 3]])
    >>> list(prof["cpu"]), prof["pairs"]
    (['prepare', 'order', 'faces', 'umbrellas', 'cells', 'count walk', 'scan'], 0)
    """
    cpu: dict[str, float] = {}
    wall: dict[str, float] = {}
    clock = [time.process_time(), time.perf_counter()]
    pts, tris = _validate(points, triangles, values=False)  # as find_self_intersections
    n_workers = _check_workers(workers)
    device = check_device(device)
    if len(tris) < 2:
        _check_values(pts, tris)
        return {"cpu": cpu, "wall": wall, "pairs": 0}
    with wp.ScopedDevice(device):
        dev = wp.get_device(device)

        def mark(stage):
            wp.synchronize_device(dev)
            now = [time.process_time(), time.perf_counter()]
            cpu[stage] = now[0] - clock[0]
            wall[stage] = now[1] - clock[1]
            clock[:] = now

        pairs = _find_pairs(pts, tris, dev, n_workers, mark)
    return {"cpu": cpu, "wall": wall, "pairs": len(pairs)}


def find_degenerate_faces(points, triangles, *, device: str = "cpu") -> np.ndarray:
    """The triangles of zero area, which :func:`find_self_intersections` skips.

    A face is degenerate when two of its indices are equal or its three points are
    collinear to within float64 rounding (every 2D projection's orientation is within
    Shewchuk's error bound of zero).

    Parameters
    ----------
    points : (n, 3) array_like of float
    triangles : (m, 3) array_like of int
    device : str

    Returns
    -------
    (d,) ndarray of int64
        Indices of the degenerate triangles, increasing.

    Raises
    ------
    TypeError, ValueError
        As :func:`find_self_intersections`.

    Examples
    --------
    >>> from warpmesh.cells.intersections import find_degenerate_faces
    >>> points = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0]]
    >>> find_degenerate_faces(points, [[0, 1, 3], [0, 1, 2], [0, 0, 3]])
    array([1, 2])
    """
    pts, tris = _validate(points, triangles)
    device = check_device(device)
    if len(tris) == 0:
        return np.zeros(0, dtype=INDEX_DTYPE)
    with wp.ScopedDevice(device):
        dev = wp.get_device(device)
        points64, tris32 = _device_arrays(power_of_two_scaled(pts), tris, dev)
        flags, _ = _classify_faces(points64, tris32, dev)
        return np.flatnonzero(flags.numpy()).astype(INDEX_DTYPE)  # sync point


def check(mesh, *, device: str = "cpu") -> np.ndarray:
    """The pairs of cells of a mesh that cross: is the mesh embedded?

    Closed, manifold and oriented meshes can still have triangles that pass through each
    other; this is the geometric check. It tests the ``"tetra"`` block of a volume mesh
    (:func:`find_tet_overlaps`), else the ``"triangle"`` block (a surface, or a planar
    triangle mesh at z = 0: overlapping planar triangles are reported), else the
    ``"line"`` block of a planar polyline. A labelled multi-material surface (cell refs
    and ``cell_data["label_above"]`` on its triangles, ``interfaces="shared"``) is also
    checked about its junction edges: faces consecutive about an edge of three faces or
    more whose labels disagree across the gap between them (sheets crossing along the
    edge, which no pair of triangles shows) are reported as pairs too
    (:func:`warpmesh.cells.junctions.find_junction_misorders`).

    Parameters
    ----------
    mesh : Mesh
    device : str
        Warp device of the triangle check.

    Returns
    -------
    (k, 2) int64
        Pairs (i, j), i < j, of cell indices in the block tested; empty when embedded.

    Raises
    ------
    TypeError
        ``mesh`` is not a Mesh.
    ValueError
        No ``"tetra"`` block in 3D, no ``"triangle"`` block, and no ``"line"`` block of 2D points.

    Examples
    --------
    >>> import warpmesh as wm
    >>> part, bounds = wm.example("part")
    >>> len(wm.check(wm.mesh_surface(part, bounds=bounds, resolution=32)))
    0
    """
    require_mesh(mesh)
    if "tetra" in mesh.cells and mesh.dim == 3:
        return find_tet_overlaps(mesh.points, mesh.cells["tetra"], device=device)
    if "triangle" in mesh.cells:
        from warpmesh.cells.junctions import with_junction_misorders  # which imports nothing of this module

        tris = mesh.cells["triangle"]
        pairs = find_self_intersections(points3(mesh), tris, device=device)
        if len(pairs) and mesh.dim == 2:
            # a planar mesh's question is the one of tetrahedra (do interiors overlap?): the two
            # lips of a crack touch along it, decided on the points welded
            uniq, inverse = np.unique(np.asarray(mesh.points), axis=0, return_inverse=True)
            if len(uniq) < mesh.n_points:
                pairs = find_self_intersections(np.column_stack([uniq, np.zeros(len(uniq))]),
                                                inverse.reshape(-1)[tris], device=device)
        return with_junction_misorders(mesh, pairs)
    if "line" in mesh.cells and mesh.dim == 2:
        return find_segment_intersections(mesh.points, mesh.cells["line"])
    raise ValueError(f"expected a 'tetra' or 'triangle' block, or a 'line' block of 2D points, got blocks "
                     f"{list(mesh.cells)} in {mesh.dim}D")


#: the four faces of a tetrahedron (a, b, c, d), each oriented outward when O(a, b, c, d) > 0
_TET_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


def find_tet_overlaps(points, tetra, *, device: str = "cpu", faces: TetFaces | None = None,
                      components: tuple[int, np.ndarray] | None = None) -> np.ndarray:
    """The pairs of tetrahedra whose interiors overlap, and the tetrahedra that are flat or
    inverted: is a volume mesh embedded?

    Not one test per pair of tetrahedra (an interior tetrahedron's box meets some 90
    others), but a certificate in O(m) plus the triangle check of the boundary. With the
    four-tuple (a, b, c, d) counted positive when d is on the side of (a, b, c) its
    right-hand normal points to, the tetrahedra, as a 3-chain, cover each point x not on
    the boundary ``deg(x)`` times, and ``deg`` equals the winding number of the chain's
    boundary around x when (1) every tetrahedron is positive and (2) every face is in at
    most two tetrahedra, which induce opposite orientations on it (the chain's boundary
    is then the faces in one tetrahedron). The mesh is embedded iff deg <= 1 everywhere,
    which, given (1) and (2), holds iff (3) no two boundary faces cross or touch
    (:func:`find_self_intersections`) and (4) just inside each boundary component the
    winding number is 1 (it is 2 inside a shell nested in another one with the same
    orientation: a ball meshed inside a ball, say, whose boundaries never cross).
    What is reported:

    - (i, i) for a tetrahedron i that is inverted, flat to within float64 rounding
      (filtered orientation test) or repeats a vertex;
    - (i, j) for the tetrahedra of a face in three or more of them, or in two with the same
      orientation (then both lie on one side of it);
    - (i, j) for the tetrahedra of two boundary faces that cross or touch;
    - (i, j) for two tetrahedra around a boundary edge of more than two boundary faces
      (boundary sheets joined along an edge, which the triangle check does not report:
      faces sharing an edge meet there) whose interiors overlap there
      (:func:`_overlapping_fans`);
    - (i, j) for a tetrahedron i inside a boundary component where (4) fails and each
      tetrahedron j that contains its centroid as well (winding numbers of the other
      components by signed ray crossings, :func:`~warpmesh.cells.rays.ray_windings`:
      candidates from 2D buckets, ties redone on another axis, solid angles where every
      axis ties; 1.5 M boundary faces in 492 components of pyvista's frog in about 1 s).

    Parameters
    ----------
    points : (n, 3) float
    tetra : (m, 4) int
    device : str
        Warp device of the orientation tests and the boundary check.
    faces : TetFaces, optional
        :func:`tet_faces` of the same ``tetra``, when the caller has it (``Mesh.stats()``
        shares it with the boundary's topology): the faces are not matched again.
    components : (int, (B,) int), optional
        The count and per-face labels of the edge-connected components of
        ``faces.boundary`` (as :func:`~warpmesh.cells.topology.connected_components` or
        ``mesh_topology(..., labels=True)`` give them), when the caller has them: not
        labelled again. Only with ``faces``.

    Returns
    -------
    (k, 2) int64
        Sorted pairs (i <= j) of tetrahedron indices; empty when the mesh is embedded.

    Raises
    ------
    ValueError, TypeError
        Bad ``points`` or ``tetra`` (shape, dtype, NaN, indices out of range).

    Examples
    --------
    >>> pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [0.2, 0.2, 0.2]]
    >>> find_tet_overlaps(pts, [[0, 1, 2, 3], [1, 2, 3, 4]]).tolist()  # two tets sharing a face
    []
    >>> find_tet_overlaps(pts, [[0, 1, 2, 3], [0, 1, 2, 5]]).tolist()  # both above face (0, 1, 2)
    [[0, 1]]
    >>> find_tet_overlaps(pts, [[0, 1, 2, 3], [1, 2, 3, 5]]).tolist()  # the second is inverted
    [[1, 1]]
    """
    pts, tets = _validate(points, tetra, 4, "tetra")
    device = check_device(device)
    m = len(tets)
    if m == 0:
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    with wp.ScopedDevice(device):
        dev = wp.get_device(device)
        points64, tets32 = _device_arrays(power_of_two_scaled(pts), tets, dev)
        signs = device_empty(m, wp.int32, dev)
        wp.launch(K.tet_signs_kernel, dim=m, inputs=[points64, tets32], outputs=[signs], device=dev)
        bad = np.flatnonzero(signs.numpy() <= 0).astype(INDEX_DTYPE)
        pairs = [np.column_stack([bad, bad])]
        if faces is None:
            faces, components = _matched_faces(tets, tets32, dev), None
    once, boundary = faces.once, faces.boundary
    pairs.append(faces.face_pairs)
    crossing = find_self_intersections(pts, boundary, device=device)
    pairs.append(once[crossing] // 4)
    if not any(len(p) for p in pairs):  # scaled by a power of two (exact): no triple product over- or underflows
        scaled = power_of_two_scaled(pts)
        pairs.append(_overlapping_fans(scaled, tets, boundary))
        if not len(pairs[-1]):
            pairs.append(_nested_shells(scaled, tets, boundary, once // 4, components))
    out = np.sort(np.concatenate(pairs).astype(INDEX_DTYPE), axis=1)
    out = np.unique(out, axis=0) if len(out) else out.reshape(0, 2)
    if len(out) and not np.any(out[:, 0] == out[:, 1]):
        # a crack (crack(), or any seam of coincident points) has coincident boundary faces
        # that touch, and interiors that do not overlap: decided on the points welded
        uniq, inverse = np.unique(pts, axis=0, return_inverse=True)
        if len(uniq) < len(pts):
            return find_tet_overlaps(uniq, inverse.reshape(-1)[tets], device=device)
    return out


class TetFaces(NamedTuple):
    """The faces of a tetrahedral mesh matched by their corners (:func:`tet_faces`)."""

    #: (B,) int64 ids ``4 t + k`` (face k of tetrahedron t) of the faces in one tetrahedron
    once: np.ndarray
    #: (B, 3) int64 their corners, oriented outward from their tetrahedron
    boundary: np.ndarray
    #: (k, 2) int64 tetrahedra of a face in two with the same orientation, or in three or more
    face_pairs: np.ndarray


def tet_faces(points, tetra, *, device: str = "cpu") -> TetFaces:
    """The boundary of a tetrahedral mesh (the faces in exactly one tetrahedron, oriented
    outward) and the tetrahedra whose faces do not pair up as in a conforming, oriented
    mesh, from one matching of the 4 m faces by their corners (Warp kernels over the faces
    sorted by largest corner, or a comparison sort when a fan makes a run too long). What :func:`find_tet_overlaps` starts
    from; ``Mesh.stats()`` reports the boundary's topology from it.

    Parameters
    ----------
    points : (n, 3) float
        Only checked (the indices must be below ``n``): the matching is combinatorial.
    tetra : (m, 4) int
    device : str

    Returns
    -------
    TetFaces

    Raises
    ------
    ValueError, TypeError
        Bad ``points`` or ``tetra`` (shape, dtype, NaN, indices out of range).

    Examples
    --------
    >>> pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]
    >>> f = tet_faces(pts, [[0, 1, 2, 3], [1, 2, 3, 4]])  # two tetrahedra sharing face (1, 2, 3)
    >>> len(f.boundary), 0 in f.once, 7 in f.once, len(f.face_pairs)  # faces 4 * 0 + 0 and 4 * 1 + 3: shared
    (6, False, False, 0)
    """
    _, tets = _validate(points, tetra, 4, "tetra")
    device = check_device(device)
    if len(tets) == 0:
        empty = np.zeros(0, dtype=INDEX_DTYPE)
        return TetFaces(empty, empty.reshape(0, 3), empty.reshape(0, 2))
    with wp.ScopedDevice(device):
        dev = wp.get_device(device)
        return _matched_faces(tets, wp.array(tets.astype(np.int32).reshape(-1), dtype=wp.int32, device=dev), dev)


def _matched_faces(tets: np.ndarray, tets32: wp.array, device) -> TetFaces:
    matched = _tet_face_pairs(tets, tets32, device)
    if matched is None:  # buckets too full for a linear scan: sort instead
        matched = _tet_face_pairs_sorted(tets)
    return TetFaces(*matched)


#: the kernel matching of tet faces scans the faces of each lead corner: used while the scans
#: total at most this many key reads a face (sum of squared run lengths / faces)
_BUCKET_READS = 64


def _tet_face_pairs(tets: np.ndarray, tets32: wp.array, device):
    """The faces of the tetrahedra matched by their corners (kernels, no comparison sort):
    (the boundary faces' ids 4 t + k ascending, their (B, 3) corners oriented outward, the
    (k, 2) pairs of tetrahedra of a face in two with the same orientation or in three or
    more); None when the runs are too long (below).

    The faces are sorted by their largest corner (:func:`~warpmesh._util.counting_sort.counting_sort`,
    split across the cores), each slot then holds its face's two other corners, packed, and
    its orientation's parity
    (:func:`~warpmesh.kernels.intersect.gather_face_keys_kernel`), and one thread per
    corner matches the faces of its run among themselves
    (:func:`~warpmesh.kernels.intersect.match_faces_by_lead_kernel`): the scans read
    contiguous memory the thread has in cache. On the graded frog (12.7 M tetrahedra, runs
    of 11.6 faces on average) :func:`tet_faces` takes 3.6-3.9 s; before, the faces were
    filed in 8 hashed buckets per corner by a serial scatter and each face scanned its
    bucket far in memory from the previous face's (10.0 s). A run of length d costs d^2 key reads;
    above :data:`_BUCKET_READS` a face in total (many faces about one corner: a fan) the
    caller sorts instead, so the work stays linear. Runs on the CPU (``device`` a CUDA
    device: the tetrahedra are read from the host copy)."""
    from warpmesh._util.counting_sort import counting_sort

    n_faces = 4 * len(tets)
    n_points = int(tets.max()) + 1
    if n_faces >= _INT32_MAX or n_points >= _INT32_MAX:
        return None
    cpu = wp.get_device("cpu")
    wp.load_module(K, device=cpu)  # once here, not in the worker threads (a module's load takes no lock)
    if not device.is_cpu:
        tets32 = wp.array(tets.astype(np.int32).reshape(-1), dtype=wp.int32, device=cpu)
    lead = np.empty(n_faces, np.int32)
    _each(K.tet_face_leads_kernel, n_faces, [tets32], [cpu_view(lead, wp.int32)], cpu, usable_cores())
    offsets, order = counting_sort(lead, n_points)
    del lead
    runs = np.diff(offsets).astype(np.float64)
    if float(runs @ runs) > _BUCKET_READS * n_faces:
        return None
    del runs
    keys, odd = np.empty(n_faces, np.int64), np.empty(n_faces, np.int8)
    worder = cpu_view(order, wp.int32)
    _each(K.gather_face_keys_kernel, n_faces, [tets32, worder], [cpu_view(keys, wp.int64), cpu_view(odd, wp.int8)],
          cpu, usable_cores())
    mate, same = np.empty(n_faces, np.int32), np.empty(n_faces, np.int8)
    _each(K.match_faces_by_lead_kernel, n_points, [cpu_view(offsets, wp.int32), worder, cpu_view(keys, wp.int64),
                                                   cpu_view(odd, wp.int8)],
          [cpu_view(mate, wp.int32), cpu_view(same, wp.int8)], cpu, usable_cores())
    wp.synchronize_device(cpu)
    del keys, odd, order, worder
    once = np.flatnonzero(mate == -1).astype(np.int32)
    corners = np.empty(3 * len(once), np.int32)
    _each(K.gather_tet_faces_kernel, len(once), [tets32, cpu_view(once, wp.int32)], [cpu_view(corners, wp.int32)],
          cpu, usable_cores())
    wp.synchronize_device(cpu)
    one = np.flatnonzero(same)
    one = one[one < mate[one]]  # each pair of faces once
    pairs = [np.column_stack([one // 4, mate[one] // 4])]
    many = np.flatnonzero(mate == -2)
    if len(many):  # faces in three or more tetrahedra: every pair of them
        trip = np.sort(np.take_along_axis(tets[many // 4], _TET_FACES[many % 4], axis=1), axis=1)
        order = np.lexsort((trip[:, 2], trip[:, 1], trip[:, 0]))
        pairs.append(_pairs_in_groups(trip[order], many[order] // 4))
    return (once.astype(INDEX_DTYPE), corners.reshape(-1, 3).astype(INDEX_DTYPE),
            np.concatenate(pairs).astype(INDEX_DTYPE))


def _pairs_in_groups(keys: np.ndarray, owners: np.ndarray) -> np.ndarray:
    """Every pair of ``owners`` within each run of equal rows of ``keys`` (sorted)."""
    start = np.flatnonzero(np.r_[True, (keys[1:] != keys[:-1]).any(axis=1)])
    counts = np.diff(np.r_[start, len(keys)])
    out = [np.zeros((0, 2), dtype=INDEX_DTYPE)]
    for first, count in zip(start[counts > 1], counts[counts > 1]):
        a, b = np.triu_indices(int(count), 1)
        group = owners[first:first + count]
        out.append(np.column_stack([group[a], group[b]]))
    return np.concatenate(out)


def _tet_face_pairs_sorted(tets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_tet_face_pairs` by a sort of all faces (numpy): any bucket sizes, and the
    tests' reference. The boundary faces come in the order of their sorted corners."""
    faces = np.empty((len(tets), 4, 3), dtype=tets.dtype)  # column copies: fancy indexing on axis 1 is slow
    for k in range(4):
        for j in range(3):
            faces[:, k, j] = tets[:, _TET_FACES[k, j]]
    faces = faces.reshape(-1, 3)  # row 4 t + k: face k of tetrahedron t, outward
    srt = np.sort(faces, axis=1)
    odd = ((faces[:, 0] > faces[:, 1]).astype(np.int8) + (faces[:, 0] > faces[:, 2]) + (faces[:, 1] > faces[:, 2])) & 1
    if srt.size == 0 or srt.max() < 1 << 21:  # one int64 key per face: one sort instead of a lexsort
        key = (srt[:, 0] << 42) | (srt[:, 1] << 21) | srt[:, 2]
        order = np.argsort(key, kind="stable")
        key = key[order]
        start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    else:
        order = np.lexsort((srt[:, 2], srt[:, 1], srt[:, 0]))
        s = srt[order]
        start = np.flatnonzero(np.r_[True, (s[1:] != s[:-1]).any(axis=1)])
    counts = np.diff(np.r_[start, len(faces)])
    owner = order // 4  # the tetrahedron of each sorted face row
    # faces in two tetrahedra with the same orientation, or in three or more: every pair of them
    two = start[counts == 2]
    same = two[odd[order[two]] == odd[order[two + 1]]]
    pairs = [np.column_stack([owner[same], owner[same + 1]])]
    for first, count in zip(start[counts > 2], counts[counts > 2]):
        group = owner[first:first + count]
        a, b = np.triu_indices(count, 1)
        pairs.append(np.column_stack([group[a], group[b]]))
    once = order[start[counts == 1]]  # boundary face rows, oriented outward, by their corners
    return once.astype(INDEX_DTYPE), faces[once], np.concatenate(pairs).astype(INDEX_DTYPE)


def _tet_edge_table() -> np.ndarray:
    """(6, 4) rows (i, j, k, l): each edge (i, j) of a tetrahedron and its two other corners in
    the order that makes (i, j, k, l) an even permutation of (0, 1, 2, 3), so that
    O(t_i, t_j, t_k, t_l) = O(t_0, t_1, t_2, t_3)."""
    rows = []
    for i, j in itertools.combinations(range(4), 2):
        k, l = (x for x in range(4) if x not in (i, j))
        perm = (i, j, k, l)
        odd = sum(perm[a] > perm[b] for a in range(4) for b in range(a + 1, 4)) % 2
        rows.append((i, j, l, k) if odd else perm)
    return np.array(rows)


#: every edge of a tetrahedron with its other corners in positive order (:func:`_tet_edge_table`)
_TET_EDGES = _tet_edge_table()


def _overlapping_fans(pts: np.ndarray, tets: np.ndarray, boundary: np.ndarray) -> np.ndarray:
    """The pairs of tetrahedra whose interiors overlap around a boundary edge in more than
    two boundary faces (``pts`` scaled by
    :func:`~warpmesh.cells.predicates.power_of_two_scaled`; ``tets`` positive).

    There boundary sheets meet along an edge of both: the triangle check does not see them
    cross (faces sharing an edge only meet there unless folded flat), and condition (4)
    takes them as one component. Two tetrahedra with a common edge (a, b) overlap iff their
    open wedges about it do: each tetrahedron as (a, b, c, d) with O(a, b, c, d) > 0 has the
    wedge O(a, b, c, x) > 0 > O(a, b, d, x); two such wedges (each under pi) overlap iff an
    edge ray of one lies inside the other or they are the same wedge. With X = O(a, b, c1,
    c2), Y = O(a, b, c1, d2), Z = O(a, b, d1, c2), W = O(a, b, d1, d2), exact:
    c2 in 1: X > 0 > Z; d2 in 1: Y > 0 > W; c1 in 2: X < 0 < Y; d1 in 2: Z < 0 < W; the same:
    X = W = 0 > Z, Y > 0. Every tetrahedron around such an edge is paired with every other
    (a few). Sheets meeting only at vertices are separate components of condition (4).

    >>> cube = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    >>> pts = np.vstack([cube, [[0.2, 0.2, 0.5], [0.2, -0.5, 0.2]]])
    >>> tets = np.array([[0, 1, 2, 3], [0, 1, 4, 5]])  # (0, 1) an edge of both, 4 inside the first
    >>> _overlapping_fans(pts, tets, np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1],
    ...                                         [1, 4, 5], [0, 5, 4], [0, 1, 5], [0, 4, 1]])).tolist()
    [[0, 1]]
    """
    n = len(pts)
    b0, b1, b2 = boundary[:, 0], boundary[:, 1], boundary[:, 2]  # column by column: no (F, 3, 2) fancy index
    key = np.concatenate([np.minimum(u, v) * n + np.maximum(u, v) for u, v in ((b0, b1), (b1, b2), (b2, b0))])
    key.sort()
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    shared = key[first[np.diff(np.r_[first, len(key)]) > 2]]  # boundary edges of 4, 6, ... faces
    if not len(shared):
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    near = np.flatnonzero(np.isin(tets, np.r_[shared // n, shared % n]).sum(axis=1) >= 2)  # may hold one
    quads = tets[near][:, _TET_EDGES]  # (k, 6, 4)
    ends = np.sort(quads[:, :, :2], axis=2)
    tkey = ends[..., 0] * n + ends[..., 1]
    t_id, e_id = np.nonzero(np.isin(tkey, shared))
    quad = quads[t_id, e_id]
    flip = quad[:, 0] > quad[:, 1]  # (b, a, c, d) even iff (a, b, d, c) is
    quad[flip] = quad[flip][:, [1, 0, 3, 2]]
    order = np.argsort(tkey[t_id, e_id], kind="stable")
    quad, t_id, ek = quad[order], t_id[order], tkey[t_id, e_id][order]
    start = np.flatnonzero(np.r_[True, ek[1:] != ek[:-1]])
    size = np.diff(np.r_[start, len(ek)])
    one, two = [], []
    for k in np.unique(size[size > 1]):  # every pair of tetrahedra around each edge, by group size
        i, j = np.triu_indices(int(k), 1)
        s = start[size == k]
        one.append((s[:, None] + i[None]).ravel())
        two.append((s[:, None] + j[None]).ravel())
    if not one:
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    one, two = np.concatenate(one), np.concatenate(two)
    a, b, c1, d1 = (quad[one, k] for k in range(4))
    c2, d2 = quad[two, 2], quad[two, 3]
    x, y, z, w = (orient3d_signs(pts, a, b, p, q) for p, q in ((c1, c2), (c1, d2), (d1, c2), (d1, d2)))
    hit = (((x > 0) & (z < 0)) | ((y > 0) & (w < 0)) | ((x < 0) & (y > 0)) | ((z < 0) & (w > 0))
           | ((x == 0) & (w == 0) & (z < 0) & (y > 0)))
    return np.column_stack([near[t_id[one[hit]]], near[t_id[two[hit]]]]).astype(INDEX_DTYPE)


def _nested_shells(pts: np.ndarray, tets: np.ndarray, boundary: np.ndarray, owners: np.ndarray,
                   components: tuple | None = None) -> np.ndarray:
    """Condition (4) of :func:`find_tet_overlaps` on a mesh that meets (1)-(3): for each
    boundary component c, the winding number of the whole boundary just inside it (its own
    1 when it bounds its tetrahedra from outside, 0 when from inside, plus the other
    components' winding number at a point q_c of c, :func:`~warpmesh.cells.rays.ray_windings`) must be 1;
    where it is not, the pairs of tetrahedra containing the centroid of one of its
    tetrahedra. The components do not touch (condition 3), so the others' winding number is
    the same at q_c as just inside c. ``pts`` must be scaled
    (:func:`~warpmesh.cells.predicates.power_of_two_scaled`): the signed volumes, ray
    signs and solid angles are products of up to three coordinates. ``components``: the
    boundary's (count, labels) when the caller has them."""
    from warpmesh.cells.topology import connected_components, face_volumes

    if not len(boundary):
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    n_comp, label = connected_components(boundary, len(pts)) if components is None else components
    if n_comp < 2:
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    label = np.asarray(label, INDEX_DTYPE)
    order = np.argsort(label, kind="stable")
    first = order[np.searchsorted(label[order], np.arange(n_comp))]  # a face of each component
    corners = pts[boundary]  # (F, 3, 3)
    q = corners[first].mean(axis=1)  # on component c, off the others
    # own orientation: the signed volume of each component, about its own point (no cancellation)
    own = np.bincount(label, face_volumes(pts, boundary, q, label), minlength=n_comp)
    point, _, others, _ = ray_windings(corners, label, q, skip=np.arange(n_comp))
    winding = (own > 0.0).astype(REAL_DTYPE) + np.bincount(point, weights=others, minlength=n_comp)
    out = []
    for c in np.flatnonzero(np.round(winding) != 1):
        t = int(owners[first[c]])
        hits = _tets_containing(pts, tets, pts[tets[t]].mean(axis=0))
        hits = hits[hits != t]
        out.append(np.column_stack([np.full(len(hits), t), hits]))
    return np.concatenate(out) if out else np.zeros((0, 2), dtype=INDEX_DTYPE)


#: faces per numpy pass of the nested-shell test (bounds its temporary arrays)
_CHUNK_FACES = 1 << 18
def _tets_containing(pts: np.ndarray, tets: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The tetrahedra (positive ones) whose closed interior holds x, by the signs of the
    four sub-volumes (float64; a failure path only)."""
    p = [pts[tets[:, k]] - x for k in range(4)]
    vol = [np.einsum("ij,ij->i", p[i], np.cross(p[j], p[k])) for i, j, k in ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))]
    return np.flatnonzero(np.all(np.stack(vol) >= 0.0, axis=0)).astype(INDEX_DTYPE)


def find_segment_intersections(points, segments) -> np.ndarray:
    """The pairs of segments of a planar polyline that cross or touch, other than
    neighbours through their shared vertex.

    Candidates come from a uniform bucket grid of the segments' boxes (cell of the mean
    segment length), then an orientation test on each pair in float64.

    Parameters
    ----------
    points : (n, 2) float
    segments : (m, 2) int

    Returns
    -------
    (k, 2) int64
        Pairs (i, j) of segment indices, i < j.

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    >>> find_segment_intersections(square, np.array([[0, 2], [1, 3], [0, 1]])).tolist()  # the diagonals
    [[0, 1]]
    """
    p = np.asarray(points, REAL_DTYPE)
    s = np.asarray(segments, INDEX_DTYPE).reshape(-1, 2)
    if len(s) < 2:
        return np.zeros((0, 2), INDEX_DTYPE)
    a, b = p[s[:, 0]], p[s[:, 1]]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    cell = max(float(np.linalg.norm(b - a, axis=1).mean()), _TINY_LENGTH)
    origin = lo.min(axis=0)
    ilo = np.floor((lo - origin) / cell).astype(np.int64)
    ihi = np.floor((hi - origin) / cell).astype(np.int64)
    span = ihi - ilo + 1
    reps = span[:, 0] * span[:, 1]
    seg_id = np.repeat(np.arange(len(s)), reps)
    start = np.repeat(np.cumsum(reps) - reps, reps)
    k = np.arange(len(seg_id)) - start
    cx = ilo[seg_id, 0] + k // span[seg_id, 1]
    cy = ilo[seg_id, 1] + k % span[seg_id, 1]
    key = cx * (int(ihi[:, 1].max()) + 2) + cy
    order = np.argsort(key, kind="stable")
    key, seg_id = key[order], seg_id[order]
    brk = np.flatnonzero(np.diff(key)) + 1
    starts = np.concatenate([[0], brk])
    counts = np.diff(np.concatenate([starts, [len(key)]]))
    pairs = []
    for c in np.unique(counts[counts > 1]):  # one vectorised pass per bucket size
        st = starts[counts == c]
        iu, ju = np.triu_indices(int(c), 1)
        pairs.append(np.column_stack([seg_id[st[:, None] + iu[None]].ravel(), seg_id[st[:, None] + ju[None]].ravel()]))
    if not pairs:
        return np.zeros((0, 2), INDEX_DTYPE)
    pr = np.unique(np.sort(np.concatenate(pairs), axis=1), axis=0)
    i, j = pr[:, 0], pr[:, 1]
    share = (s[i, :, None] == s[j, None, :]).any(axis=(1, 2))
    i, j = i[~share], j[~share]

    def orient(p0, p1, q):
        d1, d2 = p1 - p0, q - p0
        return d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]

    o1, o2 = orient(a[i], b[i], a[j]), orient(a[i], b[i], b[j])
    o3, o4 = orient(a[j], b[j], a[i]), orient(a[j], b[j], b[i])
    hit = (o1 * o2 <= 0) & (o3 * o4 <= 0)
    # collinear pairs pass the sign test; keep them only when their boxes overlap
    col = (o1 == 0) & (o2 == 0)
    overlap = np.all((np.maximum(lo[i], lo[j]) <= np.minimum(hi[i], hi[j])), axis=1)
    hit &= ~col | overlap
    return np.column_stack([i[hit], j[hit]]).astype(INDEX_DTYPE)


def _all_pairs(points, triangles, *, device: str = "cpu", certify: bool = True) -> np.ndarray:
    """What :func:`find_self_intersections` returns, by testing every pair of faces with the
    same predicate (no BVH, no box screen, no Morton order): the tests' reference for the
    candidate search. O(m^2) time and memory: small meshes only (m <= 10,000).

    With ``certify`` (the default) it skips the same pairs as the walk, those sharing a
    vertex whose umbrella is certified, computed here on the input order, so the two agree
    exactly even where the predicate alone reports a pair touching within rounding;
    ``certify=False`` tests every pair, which on exactly representable inputs (small
    integers) must give the same answer, the certificate dropping only pairs that do not
    intersect exactly (both are tested).

    >>> _all_pairs([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0.5, 0.5, -1], [0.5, 0.5, 1], [1.5, 1.5, 0]],
    ...            [[0, 1, 2], [3, 4, 5]]).tolist()
    [[0, 1]]
    """
    pts, tris = _validate(points, triangles)
    device = check_device(device)
    m = len(tris)
    if m > 10_000:
        raise ValueError(f"expected at most 10,000 'triangles' for the O(m^2) reference, got {m}")
    if m < 2:
        return np.zeros((0, 2), dtype=INDEX_DTYPE)
    with wp.ScopedDevice(device):
        dev = wp.get_device(device)
        points64, tris32 = _device_arrays(power_of_two_scaled(pts), tris, dev)
        degenerate, codes = _classify_faces(points64, tris32, dev)
        certified = _umbrella_flags(codes, tris32, len(pts), dev, certify)
        hits = wp.zeros((m, m), dtype=wp.int8, device=dev)
        wp.launch(K.all_pairs_kernel, dim=(m, m), inputs=[points64, tris32, degenerate, certified], outputs=[hits],
                  device=dev)
        return np.argwhere(hits.numpy()).astype(INDEX_DTYPE)  # sync point


def _certified_vertices(points, triangles, *, device: str = "cpu") -> np.ndarray:
    """Which vertices have a certified umbrella (the pairs of faces around them are not
    tested: :func:`~warpmesh.kernels.intersect.umbrella_certified`); False for vertices in
    no face. For tests and measurements.

    An octahedron (each fan projects one to one along its vertex's axis), then its upper
    half alone (the rim is a boundary):

    >>> octa = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
    >>> faces = [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]]
    >>> _certified_vertices(octa, faces).tolist()
    [True, True, True, True, True, True]
    >>> _certified_vertices(octa, faces[:4]).tolist()
    [False, False, False, False, True, False]
    """
    pts, tris = _validate(points, triangles)
    device = check_device(device)
    out = np.zeros(len(pts), dtype=bool)
    if len(tris) == 0:
        return out
    with wp.ScopedDevice(device):
        dev = wp.get_device(device)
        points64, tris32 = _device_arrays(power_of_two_scaled(pts), tris, dev)
        _, codes = _classify_faces(points64, tris32, dev)
        corners = _umbrella_flags(codes, tris32, len(pts), dev).numpy()  # sync point
    out[tris.ravel()] = corners.astype(bool)
    return out


# -- pipeline ------------------------------------------------------------------------------


def _find_pairs(pts: np.ndarray, tris: np.ndarray, device, n_workers: int, mark=None) -> np.ndarray:
    """The pipeline; ``mark(stage)``, when given, is called at the end of each stage (the
    profile's stopwatch: :func:`profile_self_intersections`)."""
    if mark is None:
        def mark(stage):
            return None
    m = len(tris)
    points64, tris32, points32, sides = _prepare(pts, tris, device, n_workers)
    mark("prepare")
    inv_cell = _grid_cell(points32, tris32, device, n_workers, sides)
    grid = None if inv_cell is None else _grid_order(points32, tris32, inv_cell, device, n_workers)
    order, sorted_tris = grid[:2] if grid is not None else _spatial_order(points32, tris32, device, n_workers)
    mark("order")
    degenerate = device_empty(m, wp.int32, device)
    codes = device_empty(m, wp.int32, device)
    face_lowers = device_empty(m, wp.vec3, device)
    face_uppers = device_empty(m, wp.vec3, device)
    # the grid compares lower corners with upper ones grown by the padding, the tree grows its queries
    grow = 0.0 if grid is None else _QUERY_PAD
    _each(K.classify_and_box_kernel, m, [points64, points32, sorted_tris, grow],
          [degenerate, codes, face_lowers, face_uppers], device, n_workers)
    mark("faces")
    partners = device_empty(3 * m, wp.int32, device) if grid is not None else None
    # the input order's faces are no longer read: their array holds the vertex -> corners table
    certified = _umbrella_flags(codes, sorted_tris, len(pts), device, _CERTIFY, n_workers, partners, tris32)
    mark("umbrellas")
    faces = [points64, sorted_tris, order, face_lowers, face_uppers, _QUERY_PAD, certified]
    if grid is not None:  # one thread per occupied cell (K.grid_walk_cell)
        table = _cell_table(grid[2], inv_cell, device, n_workers, tris32)  # the corner table is read no more
        reach = device_empty(table[0].shape[0], wp.int32, device)
        _each(K.cell_reach_kernel, reach.shape[0], [table[1], table[0], face_uppers, inv_cell], [reach], device,
              n_workers)
        if _CERTIFY_BLOCKS:
            _certify_blocks(table[0], table[1], points64, sorted_tris, degenerate, codes, partners, reach, device,
                            n_workers)
        walk = [*table, inv_cell, *faces[:5], certified, reach]
        count_kernel, write_kernel = K.grid_count_pairs_kernel, K.grid_write_pairs_kernel
        n_threads = walk[0].shape[0]
        mark("cells")
    else:  # one thread per group of GROUP faces (K.walk_group)
        n_groups = (m + K.GROUP - 1) // K.GROUP
        lowers = device_empty(n_groups, wp.vec3, device)
        uppers = device_empty(n_groups, wp.vec3, device)
        wp.launch(K.group_boxes_kernel, dim=n_groups, inputs=[face_lowers, face_uppers, m], outputs=[lowers, uppers],
                  device=device)
        mark("boxes")
        tree_lowers, tree_uppers, depth = _group_tree(lowers, uppers, device)
        walk = [tree_lowers, tree_uppers, depth, *faces[:5], lowers, uppers, *faces[5:]]
        count_kernel, write_kernel = K.count_pairs_kernel, K.write_pairs_kernel
        n_threads = n_groups
        mark("tree")
    split = _split(n_threads, m, device, n_workers)

    wp.load_module(K, device=device)  # compiled/loaded once here, not by two worker threads at once
    counts = device_empty(n_threads, wp.int64, device)
    unused = device_empty(1, wp.int64, device)
    split(lambda a, b: wp.launch(count_kernel, dim=b - a, inputs=[*walk, a, unused], outputs=[counts],
                                 device=device))
    mark("count walk")
    offsets = device_empty(n_threads, wp.int64, device)
    wp.utils.array_scan(counts, offsets, inclusive=False)
    total = int(offsets[n_threads - 1:].numpy()[0] + counts[n_threads - 1:].numpy()[0])  # sync point: output size
    mark("scan")
    if total == 0:
        return np.zeros((0, 2), dtype=INDEX_DTYPE)

    keys = device_empty(2 * total, wp.int64, device)  # radix sort's scratch: 2 total
    split(lambda a, b: wp.launch(write_kernel, dim=b - a, inputs=[*walk, a, counts, offsets],
                                 outputs=[keys], device=device))
    mark("write walk")
    values = device_empty(2 * total, wp.int32, device)
    wp.utils.radix_sort_pairs(keys, values, total, end_bit=max(1, (m * m - 1).bit_length()))
    k = keys[:total].numpy()  # sync point
    first = k // m
    pairs = np.column_stack([first, k - first * m]).astype(INDEX_DTYPE)
    mark("sort pairs")
    return pairs


def _spatial_order(points32: wp.array, tris32: wp.array, device, n_workers: int = 1) -> tuple[wp.array, wp.array]:
    """Faces sorted by the Morton code of their centroid (stable): ``order[s]`` is the
    face at position s, and the faces' indices in that order. Neighbouring positions are
    neighbours in space, so a range of positions is a compact region (one BVH each) and
    the walks stay in cache."""
    m = tris32.shape[0] // 3
    keys = device_empty(2 * m, wp.int32, device)  # radix sort's scratch: 2m
    ids = device_empty(2 * m, wp.int32, device)
    _each(K.morton_codes_kernel, m, [points32, tris32], [keys, ids], device, n_workers)
    wp.utils.radix_sort_pairs(keys, ids, m)
    order = ids[:m]
    sorted_tris = device_empty(3 * m, wp.int32, device)
    _each(K.gather_faces_kernel, m, [tris32, order], [sorted_tris], device, n_workers)
    return order, sorted_tris


def _grid_cell(points32: wp.array, tris32: wp.array, device, n_workers: int = 1,
               sides: tuple[float, float] | None = None) -> float | None:
    """The cell grid's inverse cell size (BVH coordinates), or None for the group tree: the
    grid when the faces are about one size (the largest face box side at most
    ``_GRID_SPREAD`` times the mean one), its cell the largest side times
    ``_GRID_CELL_SCALE`` and the padding, and at least 2 / (``K.GRID_CELLS`` - 2) (the coordinates span [-1, 1]: at most
    1022 cells a side). ``sides``: (largest, mean) side when known (:func:`_prepare`)."""
    if sides is None:
        m = tris32.shape[0] // 3
        extents = device_empty(m, wp.float32, device)
        _each(K.face_extents_kernel, m, [points32, tris32], [extents], device, n_workers)
        ext = extents.numpy()  # sync point: the grid's cell size
        sides = float(ext.max()), float(ext.mean(dtype=np.float64))
    largest, mean = sides
    if largest > _GRID_SPREAD * mean:
        return None
    cell = max(largest * _GRID_CELL_SCALE + 4.0 * _QUERY_PAD, 2.0 / (K.GRID_CELLS - 2))
    return float(np.float32(1.0 / cell))


def _grid_order(points32: wp.array, tris32: wp.array, inv_cell: float, device, n_workers: int = 1):
    """Faces sorted by the Morton key of the grid cell of their box's lower corner
    (:func:`~warpmesh.kernels.intersect.grid_keys_kernel`): (order, sorted faces, sorted
    keys), or None when some face's box spans more than two cells along an axis (the
    grid's walk would miss its pairs: the group tree is used then)."""
    m = tris32.shape[0] // 3
    scratch = device_empty(4 * m, wp.int32, device)  # the keys and ids, 2m each (the radix sort's scratch)
    keys, ids = scratch[:2 * m], scratch[2 * m:]
    wide = device_zeros(1, wp.int32, device)
    side = min(K.GRID_CELLS, int(2.0 * 1.001 * inv_cell) + 2)  # every cell coordinate is below it
    # the keys' bits: fewer is less work (1.7 M keys on one thread: 32 bits 29 ms, 24 bits 25, 16 bits 18)
    end_bit = 3 * max(1, (side - 1).bit_length())
    spread = device_empty(K.GRID_CELLS, wp.int32, device)
    wp.launch(K.spread_table_kernel, dim=K.GRID_CELLS, inputs=[], outputs=[spread], device=device)
    if device.is_cuda or n_workers < 2 or m < 2 * _MIN_FACES_PER_WORKER:
        _each(K.grid_keys_kernel, m, [points32, tris32, _QUERY_PAD, inv_cell, 0, spread], [keys, ids, wide], device,
              n_workers)
        if int(wide.numpy()[0]):  # sync point: the grid cannot hold these faces
            return None
        wp.utils.radix_sort_pairs(keys, ids, m, end_bit=end_bit)
        keys, order = keys[:m], ids[:m]
        sorted_tris = device_empty(3 * m, wp.int32, device)
    else:
        keys, order = _split_sort(points32, tris32, inv_cell, end_bit, spread, keys, ids, wide, device, n_workers)
        if int(wide.numpy()[0]):
            return None
        sorted_tris = scratch[:3 * m]  # the merge's output is elsewhere: the scratch is free (no fresh pages)
    _each(K.gather_faces_kernel, m, [tris32, order], [sorted_tris], device, n_workers)
    return order, sorted_tris, keys


def _split_sort(points32: wp.array, tris32: wp.array, inv_cell: float, end_bit: int, spread: wp.array,
                keys: wp.array, ids: wp.array, wide: wp.array, device, n_workers: int) -> tuple[wp.array, wp.array]:
    """The grid keys of the faces sorted on two CPU threads (Warp's radix sort runs on
    one): each thread computes the keys of one half of the faces into its own half of
    ``keys`` and ``ids`` (2m each: its data, then the sort's scratch) and sorts them, then
    the two sorted runs are merged stably (:func:`~warpmesh.kernels.intersect.merge_runs_kernel`),
    so the result is the one sort's, item for item. Returns (sorted keys, ids)."""
    m = tris32.shape[0] // 3
    half = m // 2
    # part 0's keys at [0, half), part 1's at [2 half, 2 half + m - half): each region twice its count
    parts = [(0, half, 0), (half, m, -half)]

    def part(a, b, base):
        wp.launch(K.grid_keys_kernel, dim=b - a, inputs=[a, points32, tris32, _QUERY_PAD, inv_cell, base, spread],
                  outputs=[keys, ids, wide], device=device)
        region = slice(a - base, a - base + 2 * (b - a))
        wp.utils.radix_sort_pairs(keys[region], ids[region], b - a, end_bit=end_bit)

    run_parallel([lambda a=a, b=b, base=base: part(a, b, base) for a, b, base in parts])
    out_keys = device_empty(m, wp.int32, device)
    out_ids = device_empty(m, wp.int32, device)
    n_chunks = _CHUNKS * n_workers
    chunk = (m + n_chunks - 1) // n_chunks
    _split(n_chunks, m, device, n_workers)(
        lambda a, b: wp.launch(K.merge_runs_kernel, dim=b - a, inputs=[a, keys, ids, 0, half, 2 * half, m - half,
                                                                       chunk], outputs=[out_keys, out_ids],
                               device=device))
    return out_keys, out_ids


def _cell_table(keys: wp.array, inv_cell: float, device, n_workers: int = 1, spare: wp.array | None = None) -> list:
    """The occupied cells of the sorted keys (:func:`_grid_order`) and a two-level table
    from cell coordinates to cell index (blocks of ``K.BLOCK``^3 cells, a slot for each
    used block, holding the block's occupancy mask and ranks:
    :func:`~warpmesh.kernels.intersect.cell_masks_kernel`): [cells' coordinates, first
    positions, blocks per axis, used blocks, block slots, masks, ranks], the grid walk's
    first arguments (its next one is the inverse cell size,
    :func:`~warpmesh.kernels.intersect.grid_walk_cell`). Count -> scan -> write twice.
    ``spare``: an int32 array of at least 2 m entries the caller no longer needs, for the
    heads and their scan (memory already touched: no fresh pages)."""
    m = keys.shape[0]
    if spare is not None and spare.shape[0] >= 2 * m:
        heads, cell_of = spare[:m], spare[m:2 * m]
    else:
        heads, cell_of = device_empty(m, wp.int32, device), device_empty(m, wp.int32, device)
    _each(K.cell_heads_kernel, m, [keys], [heads], device, n_workers)
    wp.utils.array_scan(heads, cell_of, inclusive=True)
    n_cells = int(cell_of[m - 1:].numpy()[0])  # sync point: the number of cells
    side = min(K.GRID_CELLS, int(2.0 * 1.001 * inv_cell) + 2)  # every cell coordinate is below it
    per_axis = (side + K.BLOCK - 1) // K.BLOCK
    starts = device_empty(n_cells, wp.int32, device)
    cells = device_empty(n_cells, wp.vec3i, device)
    used = device_zeros(per_axis**3, wp.int32, device)
    _each(K.cell_starts_kernel, m, [keys, heads, cell_of, per_axis], [starts, cells, used], device, n_workers)
    slots = device_empty(per_axis**3, wp.int32, device)
    wp.utils.array_scan(used, slots, inclusive=False)
    n_blocks = int(slots[-1:].numpy()[0] + used[-1:].numpy()[0])  # sync point: the table's size
    masks = device_empty(n_blocks * K.BLOCK_WORDS, wp.uint64, device)
    ranks = device_empty(n_blocks * K.BLOCK_WORDS, wp.int32, device)
    _each(K.cell_masks_kernel, n_cells, [cells, per_axis, slots], [masks, ranks], device, n_workers)
    return [cells, starts, per_axis, used, slots, masks, ranks]


def _group_tree(lowers: wp.array, uppers: wp.array, device) -> tuple[wp.array, wp.array, int]:
    """The boxes of a complete binary tree over the groups in their (Morton) order, in heap
    order (:func:`~warpmesh.kernels.intersect.tree_next`): the leaves padded to a power of
    two with empty boxes, then one launch per level, bottom up. Returns (lowers, uppers,
    depth)."""
    n_groups = lowers.shape[0]
    depth = max(0, (n_groups - 1).bit_length())
    leaves = 1 << depth
    tree_lowers = device_empty(2 * leaves, wp.vec3, device)
    tree_uppers = device_empty(2 * leaves, wp.vec3, device)
    wp.launch(K.tree_leaves_kernel, dim=leaves, inputs=[lowers, uppers, n_groups, leaves],
              outputs=[tree_lowers, tree_uppers], device=device)
    level = leaves // 2
    while level >= 1:
        wp.launch(K.tree_level_kernel, dim=level, inputs=[level], outputs=[tree_lowers, tree_uppers], device=device)
        level //= 2
    return tree_lowers, tree_uppers, depth


def _device_arrays(scaled: np.ndarray, tris: np.ndarray, device) -> tuple[wp.array, wp.array]:
    """The points as vec3d; the triangles as one flat int32 array (on the CPU, views of
    host arrays: no copy; the kernels only read them)."""
    flat = tris.astype(np.int32).ravel()
    if device.is_cpu:
        return cpu_view(scaled, wp.vec3d), cpu_view(flat, wp.int32)
    return wp.array(scaled, dtype=wp.vec3d, device=device), wp.array(flat, dtype=wp.int32, device=device)


def _prepare(pts: np.ndarray, tris: np.ndarray, device,
             n_workers: int = 1) -> tuple[wp.array, wp.array, wp.array, tuple[float, float] | None]:
    """The pipeline's inputs from :func:`_validate`'s arrays (``values=False``): the points
    scaled by a power of two (:func:`~warpmesh.cells.predicates.power_of_two_scaled`) as
    vec3d, the triangles as one flat int32 array, the float32 BVH coordinates
    (:func:`_bvh_coordinates`), and (largest, mean) of the faces' float32 box sides (for
    :func:`_grid_cell`; None when not made here); the ValueError of :func:`_check_values`
    for a NaN, infinite or out-of-range value. On the CPU, for many faces, in three passes
    split across the cores (each point's bounds and finiteness by runs; the scaled and the
    float32 points; each face's int32 indices, their range and its box side), where numpy
    would take seven passes on one core and the box sides one more (15 + 8 ms of the
    1.7 M-face sphere's check)."""
    n = len(pts)
    if not device.is_cpu or n_workers < 2 or len(tris) < 2 * _MIN_FACES_PER_WORKER or n == 0:
        _check_values(pts, tris)
        scaled = power_of_two_scaled(pts)
        points64, tris32 = _device_arrays(scaled, tris, device)
        return points64, tris32, _bvh_coordinates(scaled, points64, device, n_workers), None
    runs = _CHUNKS * n_workers
    wpts = cpu_view(pts, wp.vec3d)
    lows = device_empty(runs, wp.vec3d, device)
    highs = device_empty(runs, wp.vec3d, device)
    bad = device_empty(runs, wp.int32, device)
    split = _split(runs, len(tris), device, n_workers)  # runs of points (faces), each worker every k-th
    split(lambda a, b: wp.launch(K.point_bounds_kernel, dim=b - a, inputs=[a, wpts, (n + runs - 1) // runs],
                                 outputs=[lows, highs, bad], device=device))
    if bad.numpy().any():
        _check_values(pts, tris)  # raises, naming the row
    lo = lows.numpy().min(axis=0)
    hi = highs.numpy().max(axis=0)
    big = float(max(np.abs(lo).max(), np.abs(hi).max()))
    exponent = int(np.frexp(big)[1])
    if big == 0.0 or not -1074 <= -exponent <= 1023:  # all zero, or a scale 2^-exponent that is no float64
        scaled = power_of_two_scaled(pts)
        points64 = cpu_view(scaled, wp.vec3d)
        points32 = _bvh_coordinates(scaled, points64, device, n_workers)
    else:
        scale = float(np.ldexp(1.0, -exponent))
        lo, hi = np.ldexp(lo, -exponent), np.ldexp(hi, -exponent)  # the scaled bounds (rounding is monotone)
        centre = 0.5 * (lo + hi)
        half = float(0.5 * (hi - lo).max())
        points64 = device_empty(n, wp.vec3d, device)
        points32 = device_empty(n, wp.vec3, device)
        _each(K.scaled_points_kernel, n, [wpts, scale, wp.vec3d(*centre.tolist()), half if half > 0.0 else 1.0],
              [points64, points32], device, n_workers)
    tris32 = device_empty(3 * len(tris), wp.int32, device)
    ilows = device_empty(runs, wp.int64, device)
    ihighs = device_empty(runs, wp.int64, device)
    largest = device_empty(runs, wp.float32, device)
    sums = device_empty(runs, wp.float64, device)
    split(lambda a, b: wp.launch(K.flat_faces_kernel, dim=b - a,
                                 inputs=[a, cpu_view(tris.reshape(-1), wp.int64), (len(tris) + runs - 1) // runs,
                                         points32],
                                 outputs=[tris32, ilows, ihighs, largest, sums], device=device))
    if ilows.numpy().min() < 0 or ihighs.numpy().max() >= n:
        _check_values(pts, tris)  # raises, naming the index
    return points64, tris32, points32, (float(largest.numpy().max()), float(sums.numpy().sum()) / len(tris))


def _bvh_coordinates(scaled: np.ndarray, points64: wp.array, device, n_workers: int = 1) -> wp.array:
    """float32 points in [-1, 1]^3 for the BVH, by a map that is monotone in each
    coordinate (centre, divide, round: :func:`~warpmesh.kernels.intersect.bvh_coordinates_kernel`),
    so boxes that meet in float64 meet in float32."""
    # column by column: numpy's reduction over axis 0 of an (n, 3) array is 7x slower
    lo = np.array([scaled[:, k].min() for k in range(3)])
    hi = np.array([scaled[:, k].max() for k in range(3)])
    centre = 0.5 * (lo + hi)
    half = float(0.5 * (hi - lo).max())
    points32 = device_empty(len(scaled), wp.vec3, device)
    _each(K.bvh_coordinates_kernel, len(scaled), [points64, wp.vec3d(*centre.tolist()), half if half > 0.0 else 1.0],
          [points32], device, n_workers)
    return points32


def _certify_blocks(cells: wp.array, starts: wp.array, points64: wp.array, tris32: wp.array, degenerate: wp.array,
                    codes: wp.array, partners: wp.array, reach: wp.array, device, n_workers: int = 1) -> None:
    """The grid's blocks whose faces are certified to meet only in what they share
    (:func:`~warpmesh.kernels.intersect.block_certified`) get their size in ``reach``
    (bits ``K.LEVEL_BIT``: blocks of 2^shift cells per axis): the walk skips the pairs
    inside them. Tried for each shift of ``K.BLOCK_SHIFTS``, largest first, in the blocks
    not inside a certified one. The cells of a block are consecutive (Morton order): a
    pass marks the first cell of each block of each size, then one thread per block."""
    n_cells = cells.shape[0]
    m = degenerate.shape[0]
    heads = device_empty(n_cells, wp.int8, device)
    _each(K.block_heads_kernel, n_cells, [cells], [heads], device, n_workers)
    heads = heads.numpy()  # sync point (a view on the CPU)
    any_first = np.flatnonzero(heads)  # the first cells of some block: one scan of all cells, not one a size
    any_heads = heads[any_first]
    face_starts = np.append(starts.numpy(), m)  # each cell's first face, then the end
    open_edges = device_empty(m, wp.int8, device)  # each face's unpaired edges, by its block
    for i, shift in enumerate(K.BLOCK_SHIFTS):
        first_cells = any_first[(any_heads & (1 << i)) != 0]
        n_blocks = len(first_cells)
        firsts = wp.array(first_cells.astype(np.int32), dtype=wp.int32, device=device)
        # scratch: each block room for min(cap, 3 edges a face) edges, and their runs' boxes
        n_faces = np.diff(face_starts[np.append(first_cells, n_cells)])
        room = np.minimum(K.LOOP_CAP_PER_CELL << shift, 3 * n_faces)
        runs = (room + K.LOOP_RUN - 1) // K.LOOP_RUN
        bases = np.column_stack([np.cumsum(room) - room, np.cumsum(runs) - runs]).astype(np.int32)
        scratch = [device_empty(max(1, int(room.sum())), dtype, device) for dtype in (wp.vec2i, wp.int32)]
        scratch.append(device_empty(max(1, int(runs.sum())), wp.vec4d, device))
        inputs = [firsts, starts, shift, wp.array(bases, dtype=wp.vec2i, device=device), points64, tris32, degenerate,
                  codes, partners]
        _split(n_blocks, m, device, n_workers)(  # split by faces: blocks are few
            lambda a, b: wp.launch(K.certify_blocks_kernel, dim=b - a, inputs=[a, *inputs],
                                   outputs=[open_edges, *scratch, reach], device=device))


def _umbrella_flags(codes: wp.array, tris32: wp.array, n: int, device, certify: bool = True,
                    n_workers: int = 1, partners: wp.array | None = None,
                    spare: wp.array | None = None) -> wp.array:
    """1 for each corner (entry of the flat face array) whose vertex has a certified
    umbrella (:func:`~warpmesh.kernels.intersect.umbrella_certified`; ``codes`` from
    :func:`_classify_faces`, n points), else 0; all 0 when not ``certify``. Vertex ->
    corners on the device: counts by atomic add, inclusive scan, fill from the ends down
    (count -> scan -> write), then one thread per vertex (split over ``n_workers`` CPU
    threads like the walk: each writes its own vertices' corners only). ``partners``, when
    given (one entry per corner), receives the face across each corner's outgoing edge
    when that face is the only one with the reversed edge and the corner's face the only
    one with the edge, else -1 (:func:`~warpmesh.kernels.intersect.edge_paired`). ``spare``:
    an int32 array of one entry per corner that the caller no longer needs, for the
    vertex -> corners table (memory already touched: no fresh pages)."""
    if not certify or n == 0:
        if partners is not None:
            partners.fill_(-1)
        return device_zeros(tris32.shape[0], wp.int8, device)
    certified = device_empty(tris32.shape[0], wp.int8, device)  # every corner is some vertex's
    corners = spare if spare is not None else device_empty(tris32.shape[0], wp.int32, device)
    c = tris32.shape[0]
    if device.is_cuda or n_workers < 2 or c < 6 * _MIN_FACES_PER_WORKER:
        counts = device_zeros(n, wp.int32, device)
        wp.launch(K.count_corners_kernel, dim=c, inputs=[0, tris32], outputs=[counts], device=device)
        starts = device_empty(n, wp.int32, device)
        wp.utils.array_scan(counts, starts, inclusive=True)
        wp.launch(K.fill_corners_kernel, dim=c, inputs=[0, tris32, starts], outputs=[corners], device=device)
    else:  # two CPU threads, each counting and placing the corners of its half in arrays of its own
        starts = _split_corner_table(tris32, n, corners, device)
    certified_partners = partners if partners is not None else device_empty(1, wp.int32, device)
    _split(n, tris32.shape[0] // 3, device, n_workers)(
        lambda a, b: wp.launch(K.certify_umbrellas_kernel, dim=b - a,
                               inputs=[codes, tris32, starts, corners, a, int(partners is not None)],
                               outputs=[certified, certified_partners], device=device))
    return certified


def _split_corner_table(tris32: wp.array, n: int, corners: wp.array, device) -> wp.array:
    """The vertex -> corners table of :func:`_umbrella_flags` made on two CPU threads (the
    atomics of one launch are only atomic within it): each half of the corners counted
    into its own counts, the ends from their sum, and each half placed from its own
    cursors, the second half's at the ends, the first's where the second's begin.
    Returns each vertex's first slot in ``corners`` (filled here)."""
    c = tris32.shape[0]
    half = c // 2
    counts = [device_zeros(n, wp.int32, device), device_zeros(n, wp.int32, device)]
    run_parallel([lambda a=a, b=b, out=out: wp.launch(K.count_corners_kernel, dim=b - a, inputs=[a, tris32],
                                                      outputs=[out], device=device)
                  for (a, b), out in zip(((0, half), (half, c)), counts)])
    both, second = counts[0].numpy(), counts[1].numpy()  # sync point (views: no copy)
    np.add(both, second, out=both)
    ends = device_empty(n, wp.int32, device)
    wp.utils.array_scan(counts[0], ends, inclusive=True)  # (numpy's cumsum: 4 ms of 1.7 M faces' check, this 1)
    np.subtract(ends.numpy(), second, out=second)
    cursors = [counts[1], ends]
    run_parallel([lambda a=a, b=b, cur=cur: wp.launch(K.fill_corners_kernel, dim=b - a, inputs=[a, tris32, cur],
                                                      outputs=[corners], device=device)
                  for (a, b), cur in zip(((0, half), (half, c)), cursors)])
    return cursors[0]


def _classify_faces(points64: wp.array, tris32: wp.array, device, n_workers: int = 1) -> tuple[wp.array, wp.array]:
    """Per face: the degenerate flag, and the code of its orientation signs and crossings
    for the umbrella certificate (:func:`~warpmesh.kernels.intersect.classify_faces_kernel`)."""
    flags = device_empty(tris32.shape[0] // 3, wp.int32, device)
    codes = device_empty(tris32.shape[0] // 3, wp.int32, device)
    _each(K.classify_faces_kernel, flags.shape[0], [points64, tris32], [flags, codes], device, n_workers)
    return flags, codes


def _each(kernel, n: int, inputs: list, outputs: list, device, n_workers: int) -> None:
    """Launch a kernel whose first argument is ``first`` over [0, n), in the ranges of
    :func:`_split` (one launch on CUDA or for small n). The kernels so launched write only
    their own items' entries, or constants (so no atomic is needed: on the CPU an atomic
    add is not atomic across threads)."""
    if n > 0:
        _split(n, n, device, n_workers)(lambda a, b: wp.launch(kernel, dim=b - a, inputs=[a, *inputs],
                                                               outputs=outputs, device=device))


def _split(n_groups: int, m: int, device, n_workers: int):
    """A runner of ``launch(a, b)`` over [0, n_groups): one launch on CUDA or for few faces,
    else ``_CHUNKS`` ranges per CPU worker, each worker taking every k-th range (so a
    worker does not wait for one whose region was dense in candidates)."""
    k = 1 if device.is_cuda else max(1, min(n_workers, m // _MIN_FACES_PER_WORKER))
    if k == 1:
        return lambda launch: launch(0, n_groups)
    edges = np.linspace(0, n_groups, k * _CHUNKS + 1).astype(int)
    chunks = [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]

    def run(launch):
        run_parallel([lambda w=w: [launch(a, b) for a, b in chunks[w::k]] for w in range(k)])
    return run


def _validate(points, triangles, k: int = 3, name: str = "triangles", *,
              values: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """points as (n, 3) float64, triangles (``name``) as (m, k) int64, or a ValueError/TypeError
    naming the argument. With ``values=False`` the finiteness of the points and the range
    of the indices are the caller's to check (:func:`_check_values`; :func:`_prepare`
    checks them in its passes on all cores)."""
    pts = np.asarray(points)
    if pts.dtype.kind not in "iuf":
        raise TypeError(f"expected real numbers for 'points', got an array of dtype {pts.dtype}")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"expected an (n, 3) array for 'points', got shape {pts.shape}")
    pts = np.ascontiguousarray(pts, dtype=REAL_DTYPE)
    if values:
        _check_finite(pts)
    tris = np.asarray(triangles)
    if tris.size == 0 and tris.dtype.kind == "f":  # an empty list: no triangles
        tris = tris.astype(INDEX_DTYPE)
    if tris.dtype.kind not in "iu":
        raise TypeError(f"expected integer indices for '{name}', got an array of dtype {tris.dtype}")
    if tris.size == 0:
        tris = tris.reshape(0, k)
    if tris.ndim != 2 or tris.shape[1] != k:
        raise ValueError(f"expected an (m, {k}) array for '{name}', got shape {tris.shape}")
    if len(pts) > _INT32_MAX or k * len(tris) > _INT32_MAX:
        raise ValueError(f"expected fewer than 2**31 points and 2**31 / {k} cells, got {len(pts)} points "
                         f"and {len(tris)} {name}")
    if values or (tris.dtype.kind == "u" and tris.dtype.itemsize >= 8):  # (as int64 those would wrap)
        _check_indices(pts, tris, name)
    return pts, np.ascontiguousarray(tris, dtype=INDEX_DTYPE)


def _check_values(pts: np.ndarray, tris: np.ndarray, name: str = "triangles") -> None:
    """The ValueError of :func:`_validate` for a NaN or infinite coordinate (naming its
    row) or an index out of range (naming it), if any."""
    _check_finite(pts)
    _check_indices(pts, tris, name)


def _check_finite(pts: np.ndarray) -> None:
    if not np.isfinite(pts).all():
        raise ValueError("expected finite coordinates in 'points', got NaN or infinity "
                         f"in row {int(np.flatnonzero(~np.isfinite(pts).all(axis=1))[0])}")


def _check_indices(pts: np.ndarray, tris: np.ndarray, name: str) -> None:
    if tris.size and (tris.min() < 0 or tris.max() >= len(pts)):
        bad = tris.min() if tris.min() < 0 else tris.max()
        raise ValueError(f"expected indices in [0, {len(pts)}) for '{name}' (the number of points), "
                         f"got {int(bad)}")


def _check_workers(workers: int | None) -> int:
    if workers is None:
        return usable_cores()
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"expected a positive integer for 'workers', got {workers!r}")
    return int(workers)
