"""The seed's second global variant in 3D [FG §16.5.2]: points from a simplicial covering-up,
elements by the Delaunay kernel, then boundary recovery on the exact surface.

1. *Covering-up*: the nodes of a body-centred cubic lattice of cube side ``h`` (the
   vertices of its tetrahedra, whose own Delaunay triangulation is that BCC covering)
   with a clipped signed distance ``d = min(f / |grad f|, distance to the box faces)``
   above ``CLEARANCE * h`` are the interior points.
2. *Points on f = 0*: jittered samples around the lattice nodes near the surface
   (``|d| < h``), moved onto the clipped surface by Newton steps along the gradient
   (capped at ``h``), then thinned to a Poisson-disk set ``SPACING * h`` apart (a maximal
   independent set of the closeness graph, chosen by random priorities).
3. *Delaunay kernel*: ``scipy.spatial.Delaunay`` (Qhull) on all points; a tetrahedron is
   kept when the clipped field is positive at its centroid.
4. *Boundary recovery*, in rounds: a kept tetrahedron that reaches more than
   ``TOLERANCE * h`` out of the domain at an edge midpoint, face centroid or its centroid (or
   a dropped one that reaches as far in), a boundary face with a vertex that is not on the
   surface, a boundary face whose centroid is more than ``TOLERANCE * h`` from the surface,
   an edge in more than two boundary faces or a vertex whose boundary faces form more than one
   fan gets the worst sample (or its faces' centroids) projected onto the surface as a new
   point; points closer than ``MIN_SPACING * h`` to a surface point are not inserted. The
   kernel is re-run until no problem is left; :class:`~warpmesh.errors.WarpMeshError` when
   ``MAX_ROUNDS`` pass, or when a round finds problems but can insert no point.
5. The caller (:func:`warpmesh.solid.pipeline.mesh_domain` with ``method="delaunay"``) then
   optimises as after stuffing: crease recovery, smoothing, flips; here, boundary slivers
   (a kept tetrahedron with two faces on the boundary, all four vertices on the surface,
   whose other two faces lie within ``TOLERANCE * h`` of it) are peeled off first
   (:func:`peel_slivers`).

Example
-------
>>> import warpmesh as wm
>>> pts, tets, on_surface, info = delaunay_tets(wm.sphere(1.0), ((-1.2,) * 3, (1.2,) * 3), 0.3)
>>> tets.shape[1], bool(on_surface.any()), info["delaunay_rounds"] >= 1
(4, True, True)
"""

from __future__ import annotations

import time

import numpy as np

from warpmesh.errors import WarpMeshError
from warpmesh.frep.tape import tape_of, value_gradient_at
from warpmesh.frep.projection import ImplicitTarget
from warpmesh.solid.dihedral import signed_volumes, tet_quality, tet_quality_summary
from warpmesh.solid.features import DIHEDRAL_CEILING, DIHEDRAL_FLOOR, FEATURE_ANGLE, crease_points, recover_features
from warpmesh.solid.flips import flip_tets
from warpmesh.solid.smoothing import smooth_tets

__all__ = ["mesh_delaunay", "delaunay_tets", "peel_slivers", "ClippedField", "CLEARANCE", "SPACING", "MIN_SPACING",
           "TOLERANCE", "MAX_ROUNDS", "SLIVER_ANGLE"]

#: lattice nodes kept as interior points: clipped distance above this times h
CLEARANCE = 0.7
#: surface points at least this times h apart (the Poisson-disk radius)
SPACING = 0.5
#: recovery inserts no point closer than this times h to a surface point
MIN_SPACING = 0.12
#: a tetrahedron or boundary face may stray this times h across the surface
TOLERANCE = 0.1
#: random offsets of the lattice points, times h (no cospherical octets)
JITTER = 0.02
#: recovery stops with an error when this many rounds in a row leave the same problems
STALL = 3
#: rounds of (Delaunay kernel, classification, recovery)
MAX_ROUNDS = 16
#: jittered surface candidates per lattice node near the surface
CANDIDATES = 8
#: surface samples this times h apart are paired to find the creases between them
CREASE_PAIRING = 0.2
#: Newton steps onto the surface
NEWTON_STEPS = 10
#: a vertex this times h from a face of the box lies on it (a cap), as in the pipeline
CAP_TOLERANCE = 1.0e-4
#: projected points this fraction of the box from a face are put on it; those also this
#: fraction from f = 0 (or ``RIM`` times h) go onto the cap's rim
CAP_SNAP = 1.0e-6
RIM_SNAP = 1.0e-3
RIM = 0.1
#: boundary vertices within this times h of the clipped surface (else feature recovery is undone)
ON_SURFACE = 1.0e-3
#: smoothing sweeps of the optimisation at least
SWEEPS = 2
#: smoothing and flips act around tetrahedra with a dihedral angle below this (degrees) or
#: above 180 minus it, ``REGION_RINGS`` rings of vertices wide
OPTIMISE_BELOW = 30.0
REGION_RINGS = 2
#: further (smoothing sweeps, flips) passes after the first
PASSES_AFTER = (1,)
#: boundary slivers with a dihedral angle below this (degrees) are peeled off
SLIVER_ANGLE = 20.0
#: the faces of a positive tetrahedron, outward, each opposite vertex 0, 1, 2, 3
_FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))
_EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))


class ClippedField:
    """The signed distance estimate of {f > 0} clipped by a box, in length units:
    ``min(f / |grad f|, distance to the nearest box face)``, with its unit gradient.

    Example
    -------
    >>> import warpmesh as wm
    >>> fld = ClippedField(wm.sphere(1.0), np.array([[-2.0] * 3, [2.0, 2.0, 0.5]]))
    >>> d, _ = fld(np.array([[0.0, 0.0, 0.0], [0.9, 0.0, 0.0]]))
    >>> d.round(6).tolist()
    [0.5, 0.1]
    >>> np.round(fld.project(np.array([[0.0, 0.0, 0.7]]))[0], 6).tolist()
    [[0.0, 0.0, 0.5]]
    """

    def __init__(self, shape, box: np.ndarray, device="cpu", rim: float = 0.0):
        self.tape, self.box, self.device = tape_of(shape), np.asarray(box, dtype=np.float64), device
        self.rim = float(rim)  # points this close to both a cap's plane and f = 0 go onto the rim

    def __call__(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=np.float64)
        f, g = value_gradient_at(self.tape, x, device=self.device)
        gn = np.linalg.norm(g, axis=1)
        ok = gn > 1e-30
        d = np.where(ok, f / np.where(ok, gn, 1.0), np.where(f > 0, np.inf, np.where(f < 0, -np.inf, 0.0)))
        n = np.where(ok[:, None], g / np.where(ok, gn, 1.0)[:, None], 0.0)
        lo, hi = self.box
        faces = np.concatenate([x - lo, hi - x], axis=1)
        j = faces.argmin(axis=1)
        db = faces[np.arange(len(x)), j]
        use = db < d
        nb = np.zeros_like(n)
        nb[np.arange(len(x)), j % 3] = np.where(j < 3, 1.0, -1.0)
        return np.where(use, db, d), np.where(use[:, None], nb, n)

    def project(self, x: np.ndarray, max_step: float = np.inf, steps: int = NEWTON_STEPS):
        """(points, distance moved): Newton steps x -= d * grad d, each at most ``max_step``."""
        x0 = np.array(x, dtype=np.float64, copy=True)
        y = x0.copy()
        for _ in range(steps):
            d, n = self(y)
            step = np.clip(np.nan_to_num(d, posinf=0.0, neginf=0.0), -max_step, max_step)
            y -= step[:, None] * n
        # points on a cap exactly on its plane, and those next to a cap's rim onto the rim (f = 0
        # in the plane): nearly coplanar cap points would make nearly flat tetrahedra
        lo, hi = self.box
        f, g = value_gradient_at(self.tape, y, device=self.device)
        rim = max(RIM_SNAP * float(np.abs(hi - lo).min()), self.rim)
        on_f = np.abs(f) <= rim * np.linalg.norm(g, axis=1)
        on_cap = (np.minimum(np.abs(y - lo), np.abs(hi - y)) <= CAP_SNAP * np.abs(hi - lo)).any(axis=1)
        tol = np.where((on_f | on_cap)[:, None], rim, CAP_SNAP * np.abs(hi - lo))  # near a 2nd plane: its edge
        at = np.where(np.abs(y - lo) <= tol, 0, np.where(np.abs(hi - y) <= tol, 1, -1))  # (n, 3)
        y = np.where(at == 0, lo, np.where(at == 1, hi, y))
        f, g = value_gradient_at(self.tape, y, device=self.device)
        idx = np.flatnonzero((at >= 0).any(axis=1) & ((np.abs(f) <= rim * np.linalg.norm(g, axis=1)) | (f < 0)))
        for _ in range(steps if len(idx) else 0):
            f, g = value_gradient_at(self.tape, y[idx], device=self.device)
            g = np.where(at[idx] >= 0, 0.0, g)  # in the cap's plane
            g2 = np.einsum("ij,ij->i", g, g)
            y[idx] -= np.where(g2 > 1e-30, f / np.where(g2 > 1e-30, g2, 1.0), 0.0)[:, None] * g
        return y, np.linalg.norm(y - x0, axis=1)


def _bcc_nodes(box: np.ndarray, h: float) -> np.ndarray:
    """The nodes of a BCC lattice of cube side h covering ``box`` with a cube to spare."""
    lo, hi = box
    n = np.ceil((hi - lo) / h).astype(np.int64) + 2
    origin = lo - 0.5 * (n * h - (hi - lo))
    axes = [origin[a] + h * np.arange(n[a] + 1) for a in range(3)]
    corners = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    centres = np.stack(np.meshgrid(*[a[:-1] + 0.5 * h for a in axes], indexing="ij"), axis=-1).reshape(-1, 3)
    return np.concatenate([corners, centres])


def _thin(points: np.ndarray, radius: float, rng, fixed: np.ndarray | None = None) -> np.ndarray:
    """(n,) bool: a maximal subset of ``points`` no two closer than ``radius`` (random
    priorities; each round keeps the points of highest priority among their live neighbours).
    ``fixed`` (m, 3): points already chosen; candidates closer to them are dropped first."""
    from scipy.spatial import cKDTree

    keep = np.zeros(len(points), bool)
    alive = np.ones(len(points), bool)
    if fixed is not None and len(fixed) and len(points):
        dist, _ = cKDTree(fixed).query(points, distance_upper_bound=radius)
        alive &= ~np.isfinite(dist)
    if not len(points):
        return keep
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    prio = rng.random(len(points))
    while alive.any():
        live = alive[pairs[:, 0]] & alive[pairs[:, 1]]
        p = pairs[live]
        best = np.where(alive, prio, -1.0)
        np.maximum.at(best, p[:, 0], prio[p[:, 1]])
        np.maximum.at(best, p[:, 1], prio[p[:, 0]])
        win = alive & (best <= prio)
        keep |= win
        alive &= ~win
        lose = np.zeros(len(points), bool)
        lose[p[win[p[:, 0]], 1]] = True
        lose[p[win[p[:, 1]], 0]] = True
        alive &= ~lose
    return keep


def _surface_points(field: ClippedField, target, nodes: np.ndarray, d: np.ndarray, h: float, rng):
    """Poisson-disk points on the clipped surface, the creases first: (points, on_crease)."""
    near = nodes[np.abs(d) < h]
    cand = (near[:, None, :] + rng.uniform(-0.5 * h, 0.5 * h, (len(near), CANDIDATES, 3))).reshape(-1, 3)
    y, moved = field.project(cand, max_step=0.5 * h)
    r, g = field(y)
    ok = (np.abs(r) < 1e-5 * h) & (moved < 1.5 * h)
    y, g = y[ok], g[ok]
    creases = _sample_creases(field, target, y, g, h, rng)
    y = y[_thin(y, SPACING * h, rng, fixed=creases)]
    return np.concatenate([creases, y]), len(creases)


def _sample_creases(field, target, y, g, h, rng):
    """Points on the creases of the clipped surface (where primitives meet, or the box caps
    the shape), at most ``SPACING * h`` apart: the crease point between close samples whose normals
    differ by more than ``FEATURE_ANGLE`` (:func:`warpmesh.solid.features.crease_points`),
    thinned at half that radius (a maximal set on a curve leaves gaps up to twice the radius)."""
    from scipy.spatial import cKDTree

    sub = _thin(y, CREASE_PAIRING * h, rng)
    y, g = y[sub], g[sub]
    pairs = cKDTree(y).query_pairs(2.5 * CREASE_PAIRING * h, output_type="ndarray")
    cos_a = float(np.cos(np.radians(FEATURE_ANGLE)))
    pairs = pairs[np.einsum("ij,ij->i", g[pairs[:, 0]], g[pairs[:, 1]]) < cos_a]
    if not len(pairs):
        return np.zeros((0, 3))
    a, b = y[pairs[:, 0]], y[pairs[:, 1]]
    c = crease_points(target, a, b, h, cos_a, near=0.5 * (a + b))
    c = c[np.isfinite(c).all(axis=1)]
    z, moved = field.project(c, max_step=0.1 * h)
    r, _ = field(z)
    z = z[(np.abs(r) < 1e-5 * h) & (moved < 1e-3 * h)]
    return z[_thin(z, 0.5 * SPACING * h, rng)]  # on a curve, neighbours are within twice the radius


def _positive(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    v = signed_volumes(points, tets)
    tets = tets.copy()
    tets[v < 0] = tets[v < 0][:, [0, 1, 3, 2]]
    return tets


def _face_key(f: np.ndarray, n: int) -> np.ndarray:
    s = np.sort(f, axis=1)
    return (s[:, 0] * n + s[:, 1]) * n + s[:, 2]


def _boundary(tets: np.ndarray, n: int) -> np.ndarray:
    """(k, 3) the faces of exactly one tetrahedron, outward."""
    faces = np.concatenate([tets[:, list(f)] for f in _FACES])
    _, inv, counts = np.unique(_face_key(faces, n), return_inverse=True, return_counts=True)
    return faces[counts[inv.ravel()] == 1]


def _nonmanifold(tris: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(faces on an edge of more than two boundary faces, vertices whose faces form more than
    one fan) of a closed triangle set."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    k = len(tris)
    if not k:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    a = tris.ravel()
    b = tris[:, [1, 2, 0]].ravel()
    ca = np.arange(3 * k).reshape(k, 3).ravel()
    cb = np.arange(3 * k).reshape(k, 3)[:, [1, 2, 0]].ravel()
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = lo * n + hi
    o = np.argsort(key, kind="stable")
    key_o = key[o]
    start = np.flatnonzero(np.r_[True, key_o[1:] != key_o[:-1]])
    count = np.diff(np.r_[start, len(key_o)])
    bad_edge = np.repeat(count != 2, count)
    bad_faces = np.unique(o[bad_edge] // 3)
    # two half-edges of one edge: join the corners of the same vertex
    pair = start[count == 2]
    h1, h2 = o[pair], o[pair + 1]
    same = a[h1] == a[h2]  # misoriented pair: corners match directly
    c1a, c1b = ca[h1], cb[h1]
    c2a = np.where(same, ca[h2], cb[h2])
    c2b = np.where(same, cb[h2], ca[h2])
    rows = np.concatenate([c1a, c1b])
    cols = np.concatenate([c2a, c2b])
    g = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * k, 3 * k))
    _, lab = connected_components(g, directed=False)
    vert = tris.ravel()
    vc = np.unique(vert * (3 * k) + lab)  # distinct (vertex, fan) pairs
    fans = np.bincount(vc // (3 * k), minlength=n)
    return bad_faces, np.flatnonzero(fans > 1)


def _samples(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """(m, 11, 3) edge midpoints, face centroids and centroid of each tetrahedron."""
    p = points[tets]
    mids = [(p[:, i] + p[:, j]) / 2 for i, j in _EDGES]
    cents = [p[:, list(f)].mean(axis=1) for f in _FACES]
    return np.stack(mids + cents + [p.mean(axis=1)], axis=1)


def _recovery_targets(field, points, tets, keep, on_surface, h):
    """Points to project onto the surface, and the problem counts of one round."""
    n = len(points)
    kept = tets[keep]
    targets = []
    counts = {}
    # tetrahedra straddling the surface (those with a vertex on it; the rest are lattice-deep)
    touch = np.flatnonzero(on_surface[tets].any(axis=1))
    s = _samples(points, tets[touch])
    d, _ = field(s.reshape(-1, 3))
    d = d.reshape(len(touch), -1)
    sign = np.where(keep[touch], 1.0, -1.0)[:, None]
    worst = np.argmin(sign * d, axis=1)
    stray = (sign[:, 0] * d[np.arange(len(touch)), worst]) < -TOLERANCE * h
    targets.append(s[np.flatnonzero(stray), worst[stray]])
    owners = [tets[touch[stray]]]
    counts["straddling"] = int(stray.sum())
    tris = _boundary(kept, n)
    c = points[tris].mean(axis=1)
    off = ~on_surface[tris].all(axis=1)
    dc, _ = field(c)
    far = np.abs(dc) > TOLERANCE * h
    bad_faces, bad_verts = _nonmanifold(tris, n)
    around = np.zeros(len(tris), bool)
    around[bad_faces] = True
    if len(bad_verts):
        mark = np.zeros(n, bool)
        mark[bad_verts] = True
        around |= mark[tris].any(axis=1)
    targets.append(c[off | far | around])
    owners.append(np.concatenate([tris[off | far | around], tris[off | far | around][:, :1]], axis=1))
    counts.update(off_surface=int(off.sum()), far_faces=int(far.sum()), nonmanifold_faces=int(len(bad_faces)),
                  nonmanifold_vertices=int(len(bad_verts)))
    return np.concatenate(targets), np.concatenate(owners), counts


def _crease_targets(target, field, points, on_surface, owners, near, h):
    """Crease points between the two surface vertices of each problem element (``owners``,
    (k, 4) vertex ids) whose normals differ most, where they differ by more than
    ``FEATURE_ANGLE`` (:func:`warpmesh.solid.features.crease_points`), nearest ``near``."""
    if not len(owners):
        return np.zeros((0, 3))
    _, g = field(points[owners].reshape(-1, 3))
    nrm = g.reshape(len(owners), 4, 3)
    best = np.full(len(owners), 2.0)
    pa = np.zeros(len(owners), np.int64)
    pb = np.zeros(len(owners), np.int64)
    for i, j in _EDGES:
        dot = np.einsum("ij,ij->i", nrm[:, i], nrm[:, j])
        dot = np.where(on_surface[owners[:, i]] & on_surface[owners[:, j]], dot, 2.0)
        better = dot < best
        best = np.where(better, dot, best)
        pa = np.where(better, owners[:, i], pa)
        pb = np.where(better, owners[:, j], pb)
    cos_a = float(np.cos(np.radians(FEATURE_ANGLE)))
    sel = best < cos_a
    if not sel.any():
        return np.zeros((0, 3))
    c = crease_points(target, points[pa[sel]], points[pb[sel]], h, cos_a, near=near[sel])
    return c[np.isfinite(c).all(axis=1)]


def delaunay_tets(shape, box, h: float, *, device="cpu", seed: int = 0, max_rounds: int = MAX_ROUNDS):
    """Tetrahedra of {f > 0} in ``box`` by the Delaunay kernel on lattice and surface points,
    with boundary recovery, before any optimisation (already validated arguments).

    Returns
    -------
    points : (n, 3) float64, the vertices used
    tets : (m, 4) int64, positive, Delaunay
    on_surface : (n,) bool, the vertices on the clipped surface
    info : dict, counts and timings: ``delaunay_rounds``, ``recovery_inserted``,
        ``surface_points``, ``interior_points``, ``time_delaunay``...

    Raises
    ------
    ValueError
        No lattice node inside: nothing to mesh.
    WarpMeshError
        Boundary recovery makes no progress, or ``max_rounds`` pass. On random CSG shapes
        (``tests.helpers.random_shapes``, sizes of a fifth to a twelfth of the box) this
        happened in 10 of 38 cases that stuffing meshes: thin parts and sharp concave
        edges the points on f = 0 do not resolve.
    """
    from scipy.spatial import Delaunay, cKDTree

    t0 = time.perf_counter()
    box = np.asarray(box, dtype=np.float64)
    rng = np.random.default_rng(seed)
    field = ClippedField(shape, box, device, rim=RIM * h)
    target = ImplicitTarget(shape, bounds=box, device=device)
    nodes = _bcc_nodes(box, h)
    d, _ = field(nodes)
    if np.isnan(d).any():
        raise ValueError(f"the shape evaluates to NaN at {int(np.isnan(d).sum())} lattice nodes inside 'bounds' "
                         "(e.g. sqrt/log of a negative or a division by zero); change the expression or the bounds")
    if not (d > 0).any():
        raise ValueError("expected a 'shape' with an inside (f > 0) in 'bounds', found no lattice node "
                         f"inside at size {h:g}; check the shape, move 'bounds' or lower 'size'")
    # jittered: a lattice with nodes removed near the surface has cospherical octets (flat tetrahedra)
    interior = nodes[d > CLEARANCE * h]
    interior = interior + rng.uniform(-JITTER * h, JITTER * h, interior.shape)
    surface, n_crease = _surface_points(field, target, nodes, d, h, rng)
    info = {"crease_points": int(n_crease), "interior_points": int(len(interior)), "surface_points": int(len(surface)),
            "cube_size": float(h), "time_points": time.perf_counter() - t0}
    t_kernel = 0.0
    inserted = moved_points = 0
    history = []
    for rnd in range(1, max_rounds + 1):
        points = np.concatenate([surface, interior])
        on_surface = np.zeros(len(points), bool)
        on_surface[: len(surface)] = True
        t1 = time.perf_counter()
        tets = _positive(points, np.asarray(Delaunay(points).simplices, dtype=np.int64))
        t_kernel += time.perf_counter() - t1
        vol = signed_volumes(points, tets)
        tets = tets[vol > 1e-12 * h**3]
        dc, _ = field(points[tets].mean(axis=1))
        keep = dc > 0
        if not keep.any():
            raise ValueError("expected a 'shape' with an inside (f > 0) in 'bounds', found no tetrahedron "
                             f"inside at size {h:g}; lower 'size'")
        cand, owners, counts = _recovery_targets(field, points, tets, keep, on_surface, h)
        history.append(counts)
        if not len(cand):
            break
        if len(history) > STALL and all(c == counts for c in history[-STALL - 1:-1]):
            raise WarpMeshError(f"boundary recovery made no progress in rounds {rnd - STALL}-{rnd}: the same "
                                f"problems {counts} each round; try another 'size'")
        creases = _crease_targets(target, field, points, on_surface, owners, cand, h)
        cand = np.concatenate([creases, cand])
        y, moved = field.project(cand, max_step=0.5 * h)
        r, _ = field(y)
        y = y[(np.abs(r) < 1e-5 * h) & (moved < 2 * h)]
        y = y[_thin(y, MIN_SPACING * h, rng)]
        # a new point next to a surface point off the creases takes its place (so recovery can
        # still move the boundary where the points are already close); the others are added
        dist, near = cKDTree(surface).query(y)
        close = dist < MIN_SPACING * h
        movable = np.flatnonzero(close & (near >= n_crease))
        _, first = np.unique(near[movable], return_index=True)
        moves = movable[first]
        if not len(moves) and close.all():
            raise WarpMeshError(f"boundary recovery made no progress in round {rnd}: {counts} problems left, "
                                f"every new point within {MIN_SPACING:g} size of a crease point; try another "
                                "'size'")
        surface = surface.copy()
        surface[near[moves]] = y[moves]
        moved_points += len(moves)
        y = y[~close]
        surface = np.concatenate([surface, y])
        # lattice points too near the new surface points would make slivers: drop them
        fresh = np.concatenate([y, surface[near[moves]]])
        dist, _ = cKDTree(fresh).query(interior, distance_upper_bound=CLEARANCE * h)
        interior = interior[~np.isfinite(dist)]
        inserted += len(y)
    else:
        raise WarpMeshError(f"boundary recovery did not finish in {max_rounds} rounds: {history[-1]} problems "
                            "left; try another 'size'")
    tets = tets[keep]
    used = np.zeros(len(points), bool)
    used[tets.ravel()] = True
    new_id = np.cumsum(used) - 1
    info.update(delaunay_rounds=rnd, recovery_inserted=int(inserted), recovery_moved=int(moved_points),
                recovery_history=history, time_delaunay=t_kernel, time_stuffing=time.perf_counter() - t0)
    return points[used], new_id[tets], on_surface[used], info


def peel_slivers(points, tets, on_surface, field: ClippedField, h: float, *, angle: float = SLIVER_ANGLE,
                 rounds: int = 40, device="cpu"):
    """Remove boundary slivers: tetrahedra with a face on the boundary, all four vertices on
    the surface and a dihedral angle below ``angle`` (Delaunay makes them of nearly coplanar
    surface points), when the faces they expose lie within ``TOLERANCE * h`` of the surface
    at their centroids. Removed in rounds, all candidates at once (then, once that keeps none,
    sets of tetrahedra sharing no vertex); a removal that leaves an edge in more than two
    boundary faces or a vertex with two fans is undone, so the boundary stays a closed
    2-manifold.

    Returns
    -------
    tets : (m', 4) int64
    removed : int

    Example
    -------
    >>> import warpmesh as wm
    >>> box = np.array([[-1.2] * 3, [1.2] * 3])
    >>> pts, tets, on, _ = delaunay_tets(wm.torus(1.0, 0.35), box, 0.15)
    >>> kept, removed = peel_slivers(pts, tets, on, ClippedField(wm.torus(1.0, 0.35), box), 0.15)
    >>> removed > 0, len(kept) == len(tets) - removed
    (True, True)
    """
    tets = np.asarray(tets, dtype=np.int64)
    n = len(points)
    rng = np.random.default_rng(0)
    removed = strikes = 0
    together = 1  # all candidates at once, until a round keeps none of them
    for _ in range(rounds):
        faces = np.concatenate([tets[:, list(f)] for f in _FACES])
        _, inv, cnt = np.unique(_face_key(faces, n), return_inverse=True, return_counts=True)
        on_b = (cnt[inv.ravel()] == 1).reshape(4, -1).T  # (m, 4): the face opposite vertex i is on the boundary
        q = tet_quality(points, tets, device)
        cand = np.flatnonzero(on_b.any(axis=1) & on_surface[tets].all(axis=1) & (q[:, 0] < angle))
        if not len(cand):
            break
        # the faces a removal exposes must lie on the surface
        fc = points[faces.reshape(4, -1, 3)[:, cand]].mean(axis=2)  # (4, k, 3) face centroids
        dc, _ = field(fc.reshape(-1, 3))
        near = (np.abs(dc).reshape(4, -1).T <= TOLERANCE * h) | on_b[cand]
        cand = cand[near.all(axis=1)]
        if together == 0:  # removals that pinch each other: rounds of tetrahedra sharing no vertex
            prio = rng.random(len(cand))
            best = np.full(n, -1.0)
            np.maximum.at(best, tets[cand].ravel(), np.repeat(prio, 4))
            cand = cand[(best[tets[cand]] == prio[:, None]).all(axis=1)]
        drop = np.zeros(len(tets), bool)
        drop[cand] = True
        while drop.any():  # undo the removals next to a non-manifold edge or vertex (ends: drop shrinks)
            tris = _boundary(tets[~drop], n)
            bad_faces, bad_verts = _nonmanifold(tris, n)
            mark = np.zeros(n, bool)
            mark[bad_verts] = True
            mark[tris[bad_faces].ravel()] = True
            undo = drop & mark[tets].any(axis=1)
            if not undo.any():
                break
            drop &= ~undo
        if not drop.any():
            if together:
                together = 0
            else:
                strikes += 1
                if strikes == 3:
                    break
            continue
        tets = tets[~drop]
        removed += int(drop.sum())
    return tets, removed


def _region(points, tets, device) -> np.ndarray:
    """(n,) bool: the vertices of the tetrahedra with a dihedral angle below ``OPTIMISE_BELOW``
    or above 180 minus it, and ``REGION_RINGS`` rings of neighbours around them."""
    q = tet_quality(points, tets, device)
    bad = (q[:, 0] < OPTIMISE_BELOW) | (q[:, 1] > 180.0 - OPTIMISE_BELOW)
    mark = np.zeros(len(points), bool)
    mark[tets[bad].ravel()] = True
    for _ in range(REGION_RINGS):
        mark[tets[mark[tets].any(axis=1)].ravel()] = True
    return mark


def mesh_delaunay(shape, box, h: float, *, smooth: int = 0, features: bool = True, floor: float = DIHEDRAL_FLOOR,
                  ceiling: float = DIHEDRAL_CEILING, angle: float = FEATURE_ANGLE, device="cpu", seed: int = 0):
    """The Delaunay variant with its optimisation (already validated arguments;
    :func:`warpmesh.solid.pipeline.mesh_domain` with ``method="delaunay"`` is the public entry
    point): :func:`delaunay_tets` -> :func:`peel_slivers` -> crease recovery
    (:func:`warpmesh.solid.features.recover_features`, if ``features``) -> ``max(smooth,
    SWEEPS)`` sweeps of :func:`warpmesh.solid.smoothing.smooth_tets` -> flips
    (:func:`warpmesh.solid.flips.flip_tets`) -> smoothing and flips once more. None of the
    smoothing or flip steps lowers the smallest dihedral angle.

    Returns
    -------
    points : (n, 3) float64
    tets : (m, 4) int64, positive
    tris : (k, 3) int64, the boundary triangles, outward
    on_f : (n,) bool, boundary vertices on f = 0 (not on a cap of the box)
    info : dict, counts, timings and ``quality_stages`` (the quality after each stage)

    Example
    -------
    >>> import warpmesh as wm
    >>> pts, tets, tris, on_f, info = mesh_delaunay(wm.sphere(1.0), ((-1.2,) * 3, (1.2,) * 3), 0.3)
    >>> [q["stage"] for q in info["quality_stages"]], info["dihedral_min"] > info["quality_stages"][0]["dihedral_min"]
    (['delaunay', 'peel', 'features', 'smooth+flips'], True)
    """
    box = np.asarray(box, dtype=np.float64)
    points, tets, on_surface, info = delaunay_tets(shape, box, h, device=device, seed=seed)
    field = ClippedField(shape, box, device)
    stages = [("delaunay", tet_quality_summary(points, tets, device))]
    t0 = time.perf_counter()
    tets, peeled = peel_slivers(points, tets, on_surface, field, h, device=device)
    info.update(slivers_peeled=peeled, time_peel=time.perf_counter() - t0)
    stages.append(("peel", tet_quality_summary(points, tets, device)))
    tris = _boundary(tets, len(points))
    crease = np.zeros(len(points), bool)
    if features:
        t0 = time.perf_counter()
        target = ImplicitTarget(shape, bounds=box, device=device)
        out = recover_features(points, tets, tris, target, h, floor=floor, ceiling=ceiling, angle=angle,
                               device=device)
        # kept only when every boundary vertex stays on the clipped surface (a crease of two
        # caps runs on outside the shape: a vertex moved along it would leave f = 0)
        d, _ = field(out[0][np.unique(out[2])])
        info["features_undone"] = bool(np.abs(d).max() > ON_SURFACE * h)
        if not info["features_undone"]:
            points, tets, tris, crease, finfo = out
            info.update(finfo)
        info["time_features"] = time.perf_counter() - t0
        stages.append(("features", tet_quality_summary(points, tets, device)))
    lo, hi = box
    on_cap = np.zeros(len(points), bool)
    bv = np.unique(tris)
    on_cap[bv] = np.concatenate([points[bv] - lo, hi - points[bv]], axis=1).min(axis=1) <= CAP_TOLERANCE * h
    on_f = np.zeros(len(points), bool)
    on_f[bv] = True
    on_f &= ~on_cap
    t0 = time.perf_counter()
    moved = 0
    flips = {"flips_23": 0, "flips_32": 0, "flips_44": 0}
    for sweeps in (max(int(smooth), SWEEPS),) + PASSES_AFTER:
        # only around the tetrahedra below OPTIMISE_BELOW (the lattice's inside is BCC already)
        region = _region(points, tets, device)
        if not region.any():  # nothing below OPTIMISE_BELOW is left
            break
        points, m = smooth_tets(points, tets, tris, on_f & ~crease, on_cap | crease, field.tape, sweeps=sweeps,
                                device=device, only=region)
        moved += m
        sub = region[tets].any(axis=1)
        # the region's own boundary (the true one and the cut) is kept by the flips
        new, fi = flip_tets(points, tets[sub], _boundary(tets[sub], len(points)), device=device)
        tets = np.concatenate([tets[~sub], new])
        flips = {k: flips[k] + fi[k] for k in flips}
    info.update(smooth_moved=moved, **flips, time_optimise=time.perf_counter() - t0)
    stages.append(("smooth+flips", tet_quality_summary(points, tets, device)))
    used = np.zeros(len(points), bool)
    used[tets.ravel()] = True
    if not used.all():  # vertices left without a tetrahedron (none expected): compact
        new_id = np.cumsum(used) - 1
        points, tets, tris, on_f = points[used], new_id[tets], new_id[tris], on_f[used]
    info.update(stages[-1][1])
    info["quality_stages"] = [{"stage": k, **v} for k, v in stages]
    return points, tets, tris, on_f, info
