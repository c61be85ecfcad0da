"""Smoothing of the interfaces of multi-region tetrahedra: ``mesh_domain(volume, labels=..., smooth=n)``.

Lattice cleaving (:mod:`warpmesh.solid.regions`) puts each interface where the labels change
along the lattice's edges: it follows the voxels' staircase, as the raw shared surface
(``mesh_surface(volume, labels=..., interfaces="shared")``) does, and has about its area (on
nested voxel balls of radii 15 and 8, 40^3, size 2-4 voxels: 1.41-1.52 times the spheres'
areas, the raw surface 1.52-1.55). The shape the segmentation samples is smoother. ``smooth``
passes move the interface vertices towards it, by the rules of the surfaces' smoothing
(:mod:`warpmesh.optimize.label_smoothing`) where they carry over, with the tetrahedra as the
judge of every move:

* **interfaces and junction curves on their own**: the interface triangles' edges are
  classified by :func:`~warpmesh.optimize.label_smoothing.classify_edges`; a vertex on one
  interface moves towards the mean of its neighbours on it, a vertex on a junction curve
  (where three regions meet) towards the mean of its two neighbours along the curve, and the
  others (curve ends, corners, four regions or more) stay. So do the vertices of the
  boundary against the rest within a voxel of the image's box: where a region meets the
  box, its faces stay as cleaved (a Laplacian would round the box's edges and corners);
* **Taubin's steps**: lambda = 0.5 then mu (1/lambda + 1/mu = ``PASS_BAND``, -0.526), so a
  closed interface does not shrink; the pair's net move is the vertex's target (the two
  steps taken as separate moves, a rejected lambda step left its mu step alone, which
  inflates: on nested balls the interfaces' area grew by up to 24 %). Every target is
  clamped to ``REACH`` voxels per axis from the vertex's cleaved position, so an interface
  stays within that of where the labels put it;
* **each move is judged by the tetrahedra around the vertex**: kept only when all stay
  positive, none gets a dihedral angle below the smallest of what it had, ``MIN_DIHEDRAL``
  (10°) and the cleaved mesh's smallest, nor above the largest of what it had,
  ``MAX_DIHEDRAL`` (160°) and the cleaved mesh's largest. The full step, half and a quarter
  are tried and the longest that passes is kept; the vertices move in rounds of an
  independent set (no two in one tetrahedron), so each move is judged alone. So the mesh
  keeps its dihedral angles within [min(10°, cleaved), max(160°, cleaved)] (10° is TetGen's
  ``mindihedral`` the tests ask of a mesh a solver takes), and its connectivity is the
  cleaved one: conforming, every tetrahedron its label. Keeping the cleaved range instead
  (16.5°-150° on 64^3 nested balls at size 4) stopped the smoothing half way: interface
  area 1.42 -> 1.27 times the spheres' at 8 passes, against 1.15 with these bounds (1.13 with
  [10°, 170°], 1.10 with [5°, 175°]);
* then the vertices on no interface next to a moved one are smoothed by
  :func:`~warpmesh.solid.smoothing.smooth_tets` (moves that raise the local smallest angle),
  on the tetrahedra around them only: the rest of each region is the lattice's;
* last, the whole mesh is checked for overlapping tetrahedra
  (:func:`~warpmesh.cells.intersections.find_tet_overlaps`): a region's boundary pushed
  across a thin gap of the rest into another region is not seen by the tetrahedra around the
  moved vertex (11 pairs on pyvista's frog at 8 passes); the vertices of such tetrahedra go
  back to their cleaved places, round by round, with those of tetrahedra that a return leaves
  outside their dihedral bounds, until none overlaps or leaves them (``info["reverted"]``).

Measured (``python benchmarks/bench_regions.py --smoothing``, 2 cores, load 1.8-3.7): nested
balls 128^3 (radii 51 and 26 voxels, size 4 voxels, 1.0 M tetrahedra): interface area 1.40 ->
1.14 times the spheres' at 8 passes (11 s), 1.13 at 16 (16 s), VTK's smoothed
``contour_labels`` surface 1.00; regions within 0.3 %; no overlap. pyvista's frog (13.0 M
tetrahedra, graded): area 0.78 of the cleaved mesh's (VTK's smoothed surface 0.53), dihedral
angles kept in the cleaved [6.4°, 167.3°], no overlap, the worst region 4.4 % off (3.2 %
cleaved: the small ones shrink), 617 s of smoothing (numpy rounds over 13 M tetrahedra: slow).

Example
-------
>>> import numpy as np, warpmesh as wm
>>> z, y, x = np.mgrid[:24, :24, :24]
>>> vol = (((x - 11.5) ** 2 + (y - 11.5) ** 2 + (z - 11.5) ** 2) < 8.0 ** 2).astype(np.uint8) + 1
>>> raw = wm.mesh_domain(vol, labels=[2], size=2.0)
>>> smooth = wm.mesh_domain(vol, labels=[2], size=2.0, smooth=4)
>>> def area(m):
...     p, t = m.points, m.cells["triangle"]
...     return 0.5 * np.linalg.norm(np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]]), axis=1).sum()
>>> bool(area(smooth) < area(raw)), smooth.info["negative_tets"], smooth.info["smoothing"]["passes"]
(True, 0, 4)
"""

from __future__ import annotations

import numpy as np

from warpmesh.optimize.label_smoothing import PASS_BAND, classify_edges
from warpmesh.solid.adjacency import Neighbours, gather_rows, unique_edges, vertex_tets
from warpmesh.solid.dihedral import tet_quality
from warpmesh.solid.smoothing import smooth_tets

__all__ = ["smooth_regions", "VertexMover", "revert_overlaps", "REACH", "MIN_DIHEDRAL", "MAX_DIHEDRAL", "RELAXATION", "STEPS", "MAX_ROUNDS"]

#: a vertex moves at most this many voxels (spacings) along each axis from its cleaved position
REACH = 1.0
#: no move makes a dihedral angle smaller than this (degrees), or than the cleaved mesh's smallest
#: if that is smaller: TetGen's and the tests' bar for a mesh a solver takes (mindihedral 10)
MIN_DIHEDRAL = 10.0
#: nor one larger than this, or than the cleaved mesh's largest if that is larger
MAX_DIHEDRAL = 160.0
#: Taubin's lambda; mu follows from PASS_BAND as for the surfaces
RELAXATION = 0.5
#: fractions of a vertex's move tried, the longest that passes kept
STEPS = (1.0, 0.5, 0.25)
#: rounds of independent sets per pass (a vertex not reached in them waits for the next pass)
MAX_ROUNDS = 32
#: rounds of putting back the vertices of overlapping tetrahedra before every move is undone
REVERT_ROUNDS = 8
#: sweeps of the interior smoothing after the interfaces'
INTERIOR_SWEEPS = 2


def smooth_regions(points, tets, tris, lower, upper, *, passes: int, spacing, shape, rest: int,
                   device: str = "cpu", seed: int = 0) -> tuple[np.ndarray, dict]:
    """Smooth the interfaces of cleaved multi-region tetrahedra (module docstring).

    Parameters
    ----------
    points : (n, 3) float
        In the volume's index frame scaled by ``spacing`` (sample ``(i, j, k)`` at
        ``(i, j, k) * spacing``), as :func:`warpmesh.solid.regions.cleave` gives them.
    tets : (m, 4) int, positive
    tris : (k, 3) int
        The interface triangles (faces of ``tets``).
    lower, upper : (k,) int
        The two region codes of each triangle.
    passes : int
        Taubin pairs (a lambda step and a mu step); 0 returns the points unchanged.
    spacing : (3,) float
    shape : (3,) int
        The volume's samples per axis (its box is [-spacing / 2, (shape - 1 / 2) spacing]).
    rest : int
        The code of the rest (the outside of the box among it).
    device : str
    seed : int
        Of the independent sets' random priorities.

    Returns
    -------
    points : (n, 3) float64
    info : dict
        ``passes``, ``movable`` (interface vertices that may move), ``moved`` (moves kept, over
        all passes), ``interior_moved``, ``fixed`` (interface vertices that stay),
        ``max_move`` (an interface vertex's largest displacement along an axis, in voxels),
        ``reverted`` (vertices put back where tetrahedra overlapped), and
        ``dihedral_before`` / ``dihedral_after`` ([min, max] degrees).

    Raises
    ------
    ValueError
        ``passes`` not a non-negative integer.
    """
    if isinstance(passes, bool) or not isinstance(passes, (int, np.integer)) or passes < 0:
        raise ValueError(f"expected a non-negative integer for 'smooth' (Taubin passes), got {passes!r}")
    pts = np.array(points, dtype=np.float64, copy=True)
    tets = np.asarray(tets, dtype=np.int64)
    tris = np.asarray(tris, dtype=np.int64)
    spacing = np.asarray(spacing, dtype=np.float64)
    n = len(pts)
    q = tet_quality(pts, tets, device)
    t_min, t_max = q[:, 0].copy(), q[:, 1].copy()
    before = [float(t_min.min()), float(t_max.max())]
    floor, ceiling = min(before[0], MIN_DIHEDRAL), max(before[1], MAX_DIHEDRAL)
    info = {"passes": int(passes), "moved": 0, "interior_moved": 0, "fixed": 0, "max_move": 0.0,
            "dihedral_before": before, "dihedral_after": before}
    if passes == 0 or not len(tris):
        return pts, info

    raw = pts.copy()
    on_face = np.zeros(n, bool)
    on_face[tris.ravel()] = True
    a, b, feature, kind = classify_edges(tris, lower, upper, n)
    kind = np.where(on_face, kind, 0)
    # the boundary against the rest within a voxel of the box stays as cleaved
    lo, hi = -0.5 * spacing, (np.asarray(shape) - 0.5) * spacing
    near_box = ((pts < lo + spacing) | (pts > hi - spacing)).any(axis=1)
    at_rest = np.zeros(n, bool)
    at_rest[tris[(np.asarray(lower) == rest) | (np.asarray(upper) == rest)].ravel()] = True
    kind[near_box & at_rest] = 0
    movable = kind > 0
    info["fixed"] = int((on_face & ~movable).sum())
    info["movable"] = int(movable.sum())
    # the neighbours each vertex averages: all its edges on one interface, its feature edges on a curve
    use_a = (kind[a] == 2) | ((kind[a] == 1) & feature)
    use_b = (kind[b] == 2) | ((kind[b] == 1) & feature)
    count = (np.bincount(a[use_a], minlength=n) + np.bincount(b[use_b], minlength=n)).astype(np.float64)
    movable &= count > 0

    mover = VertexMover(pts, tets, movable, t_min, t_max, floor, ceiling, seed, device)
    mu = 1.0 / (PASS_BAND - 1.0 / RELAXATION)
    reach = REACH * spacing
    interior, none = ~on_face, np.zeros(n, bool)  # (none: no vertex on f = 0 nor on a cap)
    to = np.concatenate([a[use_a], b[use_b]])  # each vertex's averaged neighbours: (to, of) pairs
    of = np.concatenate([b[use_a], a[use_b]])

    def laplacian(x):
        mean = np.stack([np.bincount(to, x[of, k], minlength=n) for k in range(3)], axis=1) / np.maximum(count, 1.0)[:, None]
        return np.where(movable[:, None], mean - x, 0.0)

    for _ in range(passes):
        # the pair's net move as the target: a rejected lambda step must not leave its mu step alone
        # (which inflates: it amplifies the staircase instead of smoothing it)
        half = pts + RELAXATION * laplacian(pts)
        target = np.clip(half + mu * laplacian(half), raw - reach, raw + reach)
        target[~movable] = pts[~movable]
        info["moved"] += mover.move(target)
    # the vertices on no interface that share a tetrahedron with a moved one, smoothed on the
    # tetrahedra around them only (the rest of each region is the lattice's, untouched)
    ring = np.zeros(n, bool)
    ring[mover.tets.ravel()] = True
    ring &= interior
    if ring.any():
        around = tets[ring[tets].any(axis=1)]
        local, flat = np.unique(around, return_inverse=True)
        moved_pts, moved = smooth_tets(pts[local], flat.reshape(-1, 4), np.zeros((0, 3), np.int64),
                                       none[local], none[local], None, sweeps=INTERIOR_SWEEPS, device=device,
                                       seed=seed, only=ring[local])
        pts[local] = moved_pts
        info["interior_moved"] = int(moved)
    # each tetrahedron within [min(floor, its cleaved smallest), max(ceiling, its cleaved largest)]
    info["reverted"] = revert_overlaps(pts, raw, tets, device,
                                       bounds=(np.minimum(q[:, 0], floor) - 1e-9, np.maximum(q[:, 1], ceiling) + 1e-9))
    q = tet_quality(pts, tets, device)
    info["dihedral_after"] = [float(q[:, 0].min()), float(q[:, 1].max())]
    info["max_move"] = float((np.abs(pts - raw)[on_face] / spacing).max())
    return pts, info


def revert_overlaps(pts, raw, tets, device="cpu", bounds=None) -> int:
    """Put back (in place) the vertices of tetrahedra that overlap others or turned over, until
    none does (:func:`~warpmesh.cells.intersections.find_tet_overlaps`): the moves are judged
    by the tetrahedra around each vertex, which do not see a region's boundary pushed across a
    thin gap of the rest into another region (11 pairs on pyvista's frog at 8 passes). A vertex
    put back next to moved ones makes tetrahedra no move was judged on: with ``bounds`` those
    whose dihedral angles leave them go back too (a 171.1° angle on the frog, beyond the
    cleaved 167.3°). With ``raw`` a mesh without overlap and within the bounds, the rounds end
    (at the latest with every vertex back).

    Parameters
    ----------
    pts : (n, 3) float64, moved back in place
    raw : (n, 3) float
        The positions without overlap.
    tets : (m, 4) int
    device : str
    bounds : ((m,) float, (m,) float), optional
        Per tetrahedron, the smallest and largest dihedral angle (degrees) it may have.

    Returns
    -------
    int
        The number of vertices put back.

    Examples
    --------
    >>> raw = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [3, 0, 0], [4, 0, 0], [3, 1, 0], [3, 0, 1.0]])
    >>> tets = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    >>> pts = raw.copy(); pts[4] = [0.1, 0.1, 0.1]  # the second tetrahedron reaches into the first
    >>> revert_overlaps(pts, raw, tets), pts[4].tolist()
    (1, [3.0, 0.0, 0.0])
    """
    from warpmesh.cells.intersections import find_tet_overlaps  # (the check's kernels: loaded only here)

    reverted = 0
    for _ in range(REVERT_ROUNDS):
        pairs = find_tet_overlaps(pts, tets, device=device)
        bad = np.unique(pairs)
        if bounds is not None:
            q = tet_quality(pts, tets, device)
            bad = np.union1d(bad, np.flatnonzero((q[:, 0] < bounds[0]) | (q[:, 1] > bounds[1])))
        if not len(bad):
            return reverted
        verts = np.unique(tets[bad])
        verts = verts[np.any(pts[verts] != raw[verts], axis=1)]
        if not len(verts):
            break
        pts[verts] = raw[verts]
        reverted += len(verts)
    moved = np.any(pts != raw, axis=1)
    pts[moved] = raw[moved]  # (not reached on the meshes measured: every move undone)
    return reverted + int(moved.sum())


class VertexMover:
    """Moves of chosen vertices of a tetrahedral mesh towards targets, each kept only when the
    tetrahedra around the vertex stay positive with dihedral angles within [``floor``,
    ``ceiling``] or no worse than they were (the full move, half, a quarter: ``STEPS``; the
    longest that passes), in rounds of an independent set (no two in one tetrahedron: each
    move judged alone). Works on the tetrahedra around the ``movable`` vertices only; ``pts``
    is moved in place.

    Parameters
    ----------
    pts : (n, 3) float64, moved in place
    tets : (m, 4) int
    movable : (n,) bool
    t_min, t_max : (m,) float
        Each tetrahedron's smallest and largest dihedral angle (degrees) at ``pts``.
    floor, ceiling : float
    seed : int
    device : str

    Examples
    --------
    >>> pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    >>> q = tet_quality(pts, [[0, 1, 2, 3]])
    >>> mover = VertexMover(pts, np.array([[0, 1, 2, 3]]), np.array([False, False, False, True]),
    ...                     q[:, 0], q[:, 1], 10.0, 160.0, 0, "cpu")
    >>> mover.move(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, -4.0]]))  # through the base, even a quarter
    0
    >>> mover.move(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.3, 0.3, 0.8]])), pts[3].tolist()
    (1, [0.3, 0.3, 0.8])
    """

    def __init__(self, pts, tets, movable, t_min, t_max, floor: float, ceiling: float, seed: int, device):
        n = len(pts)
        near = np.flatnonzero(np.asarray(movable)[tets].any(axis=1))
        self.pts, self.movable, self.floor, self.ceiling, self.device = pts, np.asarray(movable), floor, ceiling, device
        self.tets = tets[near]  # the tetrahedra a move can change
        self.graph = Neighbours(unique_edges(self.tets), n)  # two vertices of one tetrahedron: not one set
        self.rows = vertex_tets(self.tets, n)
        self.t_min, self.t_max = np.asarray(t_min)[near].copy(), np.asarray(t_max)[near].copy()
        self.rng = np.random.default_rng(seed)

    def move(self, target) -> int:
        """Move the movable vertices towards ``target`` ((n, 3)); the number of moves kept."""
        pts, tets, n = self.pts, self.tets, len(self.pts)
        ptr, idx = self.rows
        todo = self.movable & np.any(target != pts, axis=1)
        kept = 0
        for _ in range(MAX_ROUNDS):
            if not todo.any():
                break
            prio = np.where(todo, self.rng.random(n), -1.0)
            sel = todo & (prio >= self.graph.max_of(prio))
            todo &= ~sel
            verts = np.flatnonzero(sel)
            counts = ptr[verts + 1] - ptr[verts]
            verts, counts = verts[counts > 0], counts[counts > 0]
            if not len(verts):
                continue
            owner, around = gather_rows(ptr, idx, verts)  # each tetrahedron has one selected vertex: its owner
            starts = np.r_[0, np.cumsum(counts)[:-1]]
            low = np.minimum(np.minimum.reduceat(self.t_min[around], starts), self.floor)
            high = np.maximum(np.maximum.reduceat(self.t_max[around], starts), self.ceiling)
            corner = tets[around]
            slot = corner == verts[owner][:, None]  # the owner's corner of each tetrahedron
            base = pts[corner]  # (k, 4, 3): each tetrahedron's own copy of its corners (no unique, no sort)
            local = np.arange(base.shape[0] * 4).reshape(-1, 4)
            move = target[verts] - pts[verts]
            done = np.zeros(len(verts), bool)
            for step in STEPS:
                trial = base.copy()
                trial[slot] = pts[verts[owner]] + step * move[owner]
                q = tet_quality(trial.reshape(-1, 3), local, self.device)
                after_min = np.minimum.reduceat(np.where(q[:, 3] > 0, q[:, 0], -np.inf), starts)
                after_max = np.maximum.reduceat(q[:, 1], starts)
                ok = ~done & (after_min >= low) & (after_max <= high)
                if ok.any():
                    pts[verts[ok]] = pts[verts[ok]] + step * move[ok]
                    take = ok[owner]
                    self.t_min[around[take]] = q[take, 0]
                    self.t_max[around[take]] = q[take, 1]
                    done |= ok
            kept += int(done.sum())
        return kept
