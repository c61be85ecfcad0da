"""Sharp features of stuffed tetrahedral meshes: boundary vertices moved onto the creases
and corners of the exact surface, boundary edges split or flipped onto them [FG §16.4.3:
metric then topological modifications].

Isosurface stuffing puts every boundary vertex on f = 0 but knows nothing of the creases of
a CSG shape (where two primitives meet, or where the bounds cap it): the boundary cuts
across them. Here:

1. Exact outward normals at the boundary vertices (the clipped field of
   :class:`warpmesh.frep.projection.ImplicitTarget`: the active primitive's gradient, the box
   face's normal on a cap). A boundary edge whose end normals differ by more than
   ``FEATURE_ANGLE`` crosses a crease.
2. Corners: a vertex whose ring of boundary neighbours has normals spread in three
   directions gets the dual-contouring point of their tangent planes
   (:func:`warpmesh.surface.adaptive.qef.qef_points`, rank 3), kept when the same test
   passes a tenth of ``h`` around that point (a ring around a hole of radius 2 h sees the
   wall turn by tens of degrees; close to the rim only two directions remain); one vertex
   per corner.
3. Creases: an end of a crossing edge gets the point of the crease nearest to it: the
   tangent planes at both ends meet in a line; then, ``REFINE_STEPS`` times, each face is
   sampled a tenth of ``h`` beside the current point (on the side whose projection onto
   f = 0 keeps the face's normal; twice as far out where both samples fell on one face), and
   the two new tangent planes meet again (second order: 4e-7 h on the part's hole rims, 1e-3 h
   on its sphere of radius 6 h at size 0.08).
4. Moves in rounds of an independent set (no two moving vertices share a tetrahedron),
   closest target first; a move is kept only when every tetrahedron around the vertex stays
   positive with dihedral angles in [``floor``, ``ceiling``] (default 10° and 165°). A
   crossing edge is covered once one of its ends sits on the crease; the ends of uncovered
   edges are tried in the next round. The covered ends form the crease's polyline: in the
   strip of triangles the crease crosses, consecutive covered vertices share a triangle.
   A move refused alone is tried again with the interior vertices of the tetrahedra it
   spoils relocated first (a pattern search raising their worst dihedral margin), kept when
   every tetrahedron around them all is in range.
5. Crossing edges still open are split at the crease point nearest their midpoint (every
   tetrahedron around the edge halved; kept only in the same dihedral range); an open edge
   whose two boundary triangles end on crease vertices a, b is flipped onto a-b (the cap
   tetrahedron (u, w, a, b) removed, added outside, or the k tetrahedra around (u, w)
   replaced by cones from u and w over a fan of their ring closed by a-b; never a flip that
   folds the boundary). Splits and flips refused alone are tried with interior vertices
   relocated as moves are. Between passes the vertices near open edges are smoothed
   (:func:`warpmesh.solid.smoothing.smooth_tets`, crease vertices fixed). Chords of the
   crease that sag more than ``SAG`` h from it are split; a sagging chord that cuts a corner
   (from a crease vertex near the corner to the next crease) loses its end near the corner
   by an edge collapse into it; a last flip pass follows.
6. Moves are judged by the dihedral angles around them only: if boundary faces end up
   crossing (:func:`warpmesh.cells.intersections.find_self_intersections`), the whole
   recovery is undone and ``feature_undone`` counts the crossing pairs.

:func:`feature_distance` measures the result: the distance from points of the exact edges
to the nearest boundary edge of the mesh.

Example
-------
>>> import warpmesh as wm
>>> part, bounds = wm.example("part")
>>> vol = wm.mesh_domain(part, bounds=bounds, size=0.1)
>>> s = vol.stats()
>>> s["feature_vertices"] > 100, s["dihedral_min"] >= 10.0, s["dihedral_max"] <= 165.0
(True, True, True)
"""

from __future__ import annotations

import numpy as np

from warpmesh.cells.intersections import find_self_intersections
from warpmesh.solid.adjacency import TRI_EDGES, gather_rows, unique_edges, vertex_tets
from warpmesh.solid.dihedral import tet_quality
from warpmesh.solid.smoothing import smooth_tets
from warpmesh.surface.adaptive.qef import qef_points

__all__ = ["FEATURE_ANGLE", "DIHEDRAL_FLOOR", "DIHEDRAL_CEILING", "crease_points", "recover_features",
           "feature_distance", "example_edges"]

#: degrees between the exact normals at the ends of a boundary edge that mark a crease
FEATURE_ANGLE = 35.0
#: a feature move is kept only when every dihedral angle around the vertex stays in [floor, ceiling]
DIHEDRAL_FLOOR = 10.0
DIHEDRAL_CEILING = 165.0
#: smallest over largest eigenvalue of a ring's normal tensor for a corner
CORNER_SPREAD = 0.15
#: the same at the scale ``BESIDE * h`` (26 samples: a face hit by two of them gives about 0.04;
#: a rim of radius 2 h, two directions and the wall's turn of 3°, below 0.002)
CONFIRM_SPREAD = 0.02
#: crease point refinements (tangent planes sampled beside the point) and their offset / h
REFINE_STEPS = 4
BESIDE = 0.1
#: extra refinement steps in which a sample that fell on the wrong face is taken twice as far out
WIDEN_STEPS = 2
#: a crease point is kept when the faces' normals still differ by the feature angle this close
#: beside it (times h): at a crease they do at any distance, across a smooth bend tighter than
#: the samples (a thin ellipsoid's rim: radius 0.06 at h = 0.1) the difference shrinks with it
TIGHT = 0.05
#: the farthest a vertex moves onto a crease or corner, in units of h
MAX_MOVE = 0.75
ROUNDS = 10
#: rounds of (snap, split, smooth) while crossing edges stay open
PASSES = 3
#: crease chords farther than this (times h) from the crease at their midpoint are split
SAG = 0.02

def _unit(v):
    n = np.linalg.norm(v, axis=1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _planes_meet(na, pa, nb, pb, c):
    """The point of the line where planes (na, pa) and (nb, pb) meet nearest ``c`` (NaN when
    they are parallel)."""
    d = _unit(np.cross(na, nb))
    mat = np.stack([na, nb, d], axis=1)
    rhs = np.stack([np.einsum("ij,ij->i", na, pa), np.einsum("ij,ij->i", nb, pb), np.einsum("ij,ij->i", d, c)], 1)
    out = np.full_like(c, np.nan)
    ok = np.abs(np.linalg.det(mat)) > 1e-6
    out[ok] = np.linalg.solve(mat[ok], rhs[ok][..., None])[..., 0]
    return out


def crease_points(target, pa, pb, h: float, cos_angle: float, near=None) -> np.ndarray:
    """(k, 3) the crease point nearest each ``pa`` (or ``near``), between the face of ``pa``
    and the face of ``pb`` (both on the surface); NaN where the faces' normals stop differing.

    Tangent planes at both points meet in a line; then each face is sampled ``BESIDE * h``
    beside the current estimate (on the side whose projection keeps the face's normal),
    projected onto the surface, and the new tangent planes met
    again (``REFINE_STEPS`` times, and up to ``WIDEN_STEPS`` more: where both samples land on
    one face, the next samples are taken twice as far from the estimate).
    """
    na, nb = target.normals(pa), target.normals(pb)
    c = _planes_meet(na, pa, nb, pb, pa if near is None else near)
    qa, qb = pa.copy(), pb.copy()
    eps = np.full((len(c), 1), BESIDE * h)
    refined = np.zeros(len(c), bool)
    for _ in range(REFINE_STEPS + WIDEN_STEPS):
        good = np.all(np.isfinite(c), axis=1)
        if not good.any():
            break
        d = _unit(np.cross(na, nb))
        cc = np.where(good[:, None], c, pa)
        qa2, ma = _beside(target, cc, d, na, eps)
        qb2, mb = _beside(target, cc, d, nb, eps)
        new = _planes_meet(ma, qa2, mb, qb2, cc)
        ok = good & np.all(np.isfinite(new), axis=1) & (np.einsum("ij,ij->i", ma, mb) < cos_angle)
        ok &= np.linalg.norm(np.where(ok[:, None], new, cc) - cc, axis=1) < 0.5 * h
        refined |= ok
        # a sample that fell on the other face (the first estimate, from tangent planes of a
        # curved face, sits off the crease by about eps): the next step samples farther out
        eps = np.where(ok[:, None], BESIDE * h, np.minimum(2.0 * eps, BESIDE * h * 2**WIDEN_STEPS))
        c = np.where(ok[:, None], new, c)
        qa, qb = np.where(ok[:, None], qa2, qa), np.where(ok[:, None], qb2, qb)
        na, nb = np.where(ok[:, None], ma, na), np.where(ok[:, None], mb, nb)
    c[~refined] = np.nan  # never confirmed by samples on both faces: no crease point
    k = np.flatnonzero(refined)
    if len(k):  # a crease, not a bend: the normals still differ right beside it
        d = _unit(np.cross(na[k], nb[k]))
        tight = np.full((len(k), 1), TIGHT * h)
        _, ma = _beside(target, c[k], d, na[k], tight)
        _, mb = _beside(target, c[k], d, nb[k], tight)
        c[k[np.einsum("ij,ij->i", ma, mb) >= cos_angle]] = np.nan
    return c


def _beside(target, cc, d, nrm, eps):
    """(points, normals) on the surface ``eps`` (k, 1) beside the crease estimates ``cc``
    (direction ``d``) in the tangent planes of normal ``nrm``, on both sides: the sample whose
    normal is nearer ``nrm`` is on that face (the side of the face's own point fails when the
    point is within eps of the crease and the estimate lies beyond it)."""
    t = _unit(np.cross(d, nrm))
    x = np.concatenate([cc + eps * t, cc - eps * t])
    y = target.project(x, max_step=np.concatenate([eps[:, 0], eps[:, 0]]))
    m = target.normals(y)
    k = len(cc)
    first = np.einsum("ij,ij->i", m[:k], nrm) >= np.einsum("ij,ij->i", m[k:], nrm)
    return np.where(first[:, None], y[:k], y[k:]), np.where(first[:, None], m[:k], m[k:])


def _ring_corners(points, bverts, bedges, nrm, h):
    """Corner targets: (vertices, points) for rings whose normals span three directions."""
    ring_owner = np.concatenate([bverts, bedges[:, 0], bedges[:, 1]])
    ring_vert = np.concatenate([bverts, bedges[:, 1], bedges[:, 0]])
    n = len(points)
    tensor = np.zeros((n, 3, 3))
    for i in range(3):
        for j in range(3):
            tensor[:, i, j] = np.bincount(ring_owner, nrm[ring_vert, i] * nrm[ring_vert, j], n)
    lam = np.linalg.eigvalsh(tensor[bverts])
    spread = lam[:, 0] / np.maximum(lam[:, 2], 1e-300)
    cand = bverts[spread > CORNER_SPREAD]
    if not len(cand):
        return cand, np.zeros((0, 3))
    remap = np.full(n, -1)
    remap[cand] = np.arange(len(cand))
    sub = remap[ring_owner] >= 0
    x, rank = qef_points(remap[ring_owner[sub]], points[ring_vert[sub]], nrm[ring_vert[sub]], len(cand))
    dist = np.linalg.norm(x - points[cand], axis=1)
    ok = (rank == 3) & (dist < MAX_MOVE * h)
    cand, x, dist = cand[ok], x[ok], dist[ok]
    if len(cand) < 2:
        return cand, x
    # one vertex per corner: candidates whose corners lie within h / 2 of each other compete
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(x).query_pairs(0.5 * h, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(cand), len(cand)))
    _, comp = connected_components(graph, directed=False)
    order = np.lexsort((dist, comp))
    first = order[np.r_[True, comp[order][1:] != comp[order][:-1]]]
    return cand[first], x[first]


#: the 26 directions to the neighbours of a cube's centre, of unit length
_DIRS26 = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)],
                   dtype=np.float64)
_DIRS26 /= np.linalg.norm(_DIRS26, axis=1, keepdims=True)


def _confirm_corners(target, x, h):
    """(ok (k,) bool, refined x (k, 3)): the corner candidates ``x`` that are corners at the
    scale ``BESIDE * h``, not only at the ring's scale h. Points ``BESIDE * h`` around each
    candidate in 26 directions are projected onto the surface; their normals must still
    span three directions (spread > ``CONFIRM_SPREAD``) and meet, by their tangent planes, at
    a point within ``BESIDE * h`` of the candidate (which becomes the corner). A ring around
    a small hole's rim sees the wall's normals turn by tens of degrees and passes the ring
    test; close to the rim, the wall and the face give two directions only."""
    k = len(x)
    if not k:
        return np.zeros(0, bool), x
    eps = BESIDE * h
    q = target.project((x[:, None, :] + eps * _DIRS26[None]).reshape(-1, 3), max_step=eps)
    nq = target.normals(q)
    group = np.repeat(np.arange(k), len(_DIRS26))
    tensor = np.einsum("ni,nj->nij", nq, nq).reshape(k, len(_DIRS26), 3, 3).sum(axis=1)
    lam = np.linalg.eigvalsh(tensor)
    spread = lam[:, 0] / np.maximum(lam[:, 2], 1e-300)
    y, rank = qef_points(group, q, nq, k)
    ok = (spread > CONFIRM_SPREAD) & (rank == 3) & (np.linalg.norm(y - x, axis=1) < eps)
    return ok, np.where(ok[:, None], y, x)


def _try_moves(pts, tets, vt_ptr, vt_idx, verts, targets, floor, ceiling, device):
    """Move each of ``verts`` (no two in one tetrahedron) to its target when every
    tetrahedron around it stays positive with dihedral angles in [floor, ceiling]; returns
    the accepted mask."""
    owner, around = gather_rows(vt_ptr, vt_idx, verts)
    trial = pts.copy()
    trial[verts] = targets
    q = tet_quality(trial, tets[around], device)
    bad = (q[:, 0] < floor) | (q[:, 1] > ceiling) | (q[:, 3] <= 0) | ~np.isfinite(q[:, 0])
    return np.bincount(owner, bad, len(verts)) == 0


#: relocation of the interior neighbours of a refused move: rounds, and the pattern steps / h
RELAX_ROUNDS = 6
RELAX_STEPS = (0.2, 0.1, 0.05, 0.025)


def _margin(q, floor, ceiling):
    """(m,) how far each tetrahedron's dihedral angles stay inside [floor, ceiling] (degrees;
    negative outside, -inf when not positive)."""
    m = np.minimum(q[:, 0] - floor, ceiling - q[:, 1])
    return np.where((q[:, 3] > 0) & np.isfinite(m), m, -np.inf)


def _relaxed_moves(pts, tets, te, verts, targets, movable, h, floor, ceiling, device, rng):
    """Moves refused alone, tried again with their neighbours relocated: each of ``verts`` is
    put on its target, then the ``movable`` vertices of the tetrahedra that leave [floor,
    ceiling] hill-climb (pattern search of ``RELAX_STEPS`` h along 26 directions, one
    independent set at a time) to raise the worst margin of the tetrahedra around them. A
    move is kept with its relocations when every tetrahedron around the vertex and around the
    relocated ones is in range; else all of them stay. Only vertices at least four edges
    apart are tried together (their relocations touch no common tetrahedron): the others
    are left to another call.

    Returns (points, tried (k,) bool, accepted (k,) bool) over ``verts``."""
    n = len(pts)
    prio = np.full(n, -np.inf)
    prio[verts] = rng.random(len(verts))
    best = prio.copy()
    for _ in range(3):
        grown = best.copy()
        np.maximum.at(grown, te[:, 0], best[te[:, 1]])
        np.maximum.at(grown, te[:, 1], best[te[:, 0]])
        best = grown
    tried = prio[verts] >= best[verts]
    sel, tgt = verts[tried], targets[tried]
    zone = np.full(n, -1)  # the selected vertex whose ring each vertex is in
    ptr, idx = vertex_tets(tets, n)
    owner, around = gather_rows(ptr, idx, sel)
    zone[tets[around].ravel()] = np.repeat(owner, 4)
    trial = pts.copy()
    trial[sel] = tgt
    free = movable & (zone >= 0)
    free[sel] = False
    moved = np.zeros(n, bool)
    steps = np.array(RELAX_STEPS) * h
    cand_off = (steps[:, None, None] * _DIRS26[None]).reshape(-1, 3)
    for _ in range(RELAX_ROUNDS):
        # the free vertices of tetrahedra out of range around the moved vertices
        _, watch = gather_rows(ptr, idx, np.flatnonzero(moved))
        watch = np.unique(np.concatenate([around, watch]))
        bad = watch[_margin(tet_quality(trial, tets[watch], device), floor, ceiling) < 0]
        grow = np.zeros(n, bool)
        grow[tets[bad].ravel()] = True
        cand = np.flatnonzero(grow & free)
        if not len(cand):
            break
        p = np.full(n, -np.inf)
        p[cand] = rng.random(len(cand))
        b = p.copy()
        np.maximum.at(b, te[:, 0], p[te[:, 1]])
        np.maximum.at(b, te[:, 1], p[te[:, 0]])
        u = cand[p[cand] >= b[cand]]
        uo, ut = gather_rows(ptr, idx, u)
        k = len(cand_off) + 1
        # every candidate position of u as a new point; the tetrahedra around u with u replaced
        newp = np.concatenate([trial, (trial[u][:, None, :] + np.concatenate([np.zeros((1, 3)), cand_off])[None])
                               .reshape(-1, 3)])
        rep = np.repeat(tets[ut][None], k, axis=0)  # (k, t, 4)
        pid = n + uo[None, :] * k + np.arange(k)[:, None]  # (k, t)
        rep = np.where(rep == u[uo][None, :, None], pid[..., None], rep)
        score = _margin(tet_quality(newp, rep.reshape(-1, 4), device), floor, ceiling).reshape(k, len(ut))
        starts = np.flatnonzero(np.r_[True, uo[1:] != uo[:-1]])  # gather_rows keeps each row together
        worst = np.minimum.reduceat(score, starts, axis=1)
        pick = np.argmax(worst, axis=0)
        better = worst[pick, np.arange(len(u))] > worst[0]
        trial[u[better]] = newp[n + np.flatnonzero(better) * k + pick[better]]
        moved[u[better]] = True
    # keep each zone whose tetrahedra (around its vertex and its relocated ones) are all in range
    touched = np.zeros(n, bool)
    touched[sel] = True
    touched |= moved
    _, at = gather_rows(ptr, idx, np.flatnonzero(touched))
    at = np.unique(at)
    bad_t = at[_margin(tet_quality(trial, tets[at], device), floor, ceiling) < 0]
    zone_bad = np.zeros(len(sel), bool)
    zb = zone[tets[bad_t].ravel()]
    zone_bad[zb[zb >= 0]] = True
    ok_z = ~zone_bad
    keep = (zone >= 0) & touched
    keep[keep] = ok_z[zone[keep]]
    out = pts.copy()
    out[keep] = trial[keep]
    accepted = np.zeros(len(verts), bool)
    accepted[np.flatnonzero(tried)[ok_z]] = True
    return out, tried, accepted


def _split_edges(pts, tets, tris, edges, where, floor, ceiling, device, rng):
    """Split boundary edges at points of the crease: every tetrahedron (and the two boundary
    triangles) around edge (u, w) becomes two, with the new vertex m for u in one and for w
    in the other (orientation kept). Edges sharing a tetrahedron are split in different
    calls: here the ones of highest random priority. A split is kept only when all its new
    tetrahedra are positive with dihedral angles in [floor, ceiling].

    Returns (points, tets, tris, split (k,) bool over ``edges``)."""
    n = len(pts)
    ptr, idx = vertex_tets(tets, n)
    owner, cand = gather_rows(ptr, idx, edges[:, 0])
    has_w = (tets[cand] == edges[owner, 1][:, None]).any(axis=1)
    owner, around = owner[has_w], cand[has_w]
    prio = rng.random(len(edges))
    tet_best = np.full(len(tets), -1.0)
    np.maximum.at(tet_best, around, prio[owner])
    lose = np.zeros(len(edges), bool)
    lose[owner[tet_best[around] > prio[owner]]] = True
    sel = ~lose & (np.bincount(owner, minlength=len(edges)) > 0)
    keep = sel[owner]
    owner, around = owner[keep], around[keep]
    m_id = n + np.cumsum(sel) - 1  # the new vertex of each selected edge
    new_pts = np.concatenate([pts, where[sel]])
    u, w, m = edges[owner, 0][:, None], edges[owner, 1][:, None], m_id[owner][:, None]
    t1 = np.where(tets[around] == u, m, tets[around])
    t2 = np.where(tets[around] == w, m, tets[around])
    q = tet_quality(new_pts, np.concatenate([t1, t2]), device)
    bad = (q[:, 0] < floor) | (q[:, 1] > ceiling) | (q[:, 3] <= 0) | ~np.isfinite(q[:, 0])
    ok_edge = sel & (np.bincount(np.concatenate([owner, owner]), bad, len(edges)) == 0)
    if not ok_edge.any():
        return pts, tets, tris, ok_edge
    # renumber the new vertices of the kept splits only
    m_new = np.full(len(edges), -1)
    m_new[ok_edge] = n + np.arange(int(ok_edge.sum()))
    take = ok_edge[owner]
    owner, around = owner[take], around[take]
    u, w, m = edges[owner, 0][:, None], edges[owner, 1][:, None], m_new[owner][:, None]
    t1 = np.where(tets[around] == u, m, tets[around])
    t2 = np.where(tets[around] == w, m, tets[around])
    tets = tets.copy()
    tets[around] = t1
    tets = np.concatenate([tets, t2])
    # the boundary triangles holding a split edge
    ke = edges[ok_edge]
    km = m_new[ok_edge]
    big = np.int64(n + 1)
    key = np.minimum(ke[:, 0], ke[:, 1]) * big + np.maximum(ke[:, 0], ke[:, 1])
    order = np.argsort(key)
    key, ke, km = key[order], ke[order], km[order]
    add = []
    tris = tris.copy()
    for i, j in ((0, 1), (1, 2), (2, 0)):
        a, b = tris[:, i], tris[:, j]
        k = np.minimum(a, b) * big + np.maximum(a, b)
        pos = np.clip(np.searchsorted(key, k), 0, len(key) - 1)
        hit = np.flatnonzero(key[pos] == k)
        if not len(hit):
            continue
        first = tris[hit].copy()
        second = tris[hit].copy()
        first[:, j] = km[pos[hit]]
        second[:, i] = km[pos[hit]]
        tris[hit] = first
        add.append(second)
    if add:
        tris = np.concatenate([tris] + add)
    return np.concatenate([pts, where[ok_edge]]), tets, tris, ok_edge


def _crease_chords(pts, tris, crease, target, cos_a):
    """(edges (k, 2), third vertices (k, 2)): boundary edges with both ends on a crease
    whose two triangles lie on different faces (their third vertices' normals differ)."""
    e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    third = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    key = np.sort(e, axis=1)
    both = crease[key].all(axis=1)
    key, third = key[both], third[both]
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, third = key[order], third[order]
    pair = np.flatnonzero((key[1:] == key[:-1]).all(axis=1))
    edges, opp = key[pair], np.stack([third[pair], third[pair + 1]], axis=1)
    if not len(edges):
        return edges, opp
    na, nb = target.normals(pts[opp[:, 0]]), target.normals(pts[opp[:, 1]])
    sharp = np.einsum("ij,ij->i", na, nb) < cos_a
    return edges[sharp], opp[sharp]


#: the faces of a positive tetrahedron (a, b, c, d), counter-clockwise seen from outside
_FACES = ((1, 2, 3), (0, 3, 2), (0, 1, 3), (0, 2, 1))


def _signed(pts, t):
    """Six times the signed volume of tetrahedron t (> 0 when t[3] is on the outer side of
    the counter-clockwise face t[:3])."""
    p = pts[t]
    return float(np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p[3] - p[0]))


def _face_key(f, n):
    f = np.sort(f, axis=1)
    return (f[:, 0] * n + f[:, 1]) * n + f[:, 2]


def _with(pts, moves: dict):
    out = pts.copy()
    for r, x in moves.items():
        out[r] = x
    return out


def _climb(pts, r, rt, h, floor, ceiling, device):
    """(position, margin): the best of vertex r's position and the pattern around it
    (``RELAX_STEPS`` h along 26 directions) for the worst dihedral margin (:func:`_margin`)
    of its tetrahedra ``rt`` (t, 4)."""
    local, inv = np.unique(rt, return_inverse=True)
    inv = inv.reshape(rt.shape)
    j = int(np.searchsorted(local, r))
    off = np.concatenate([np.zeros((1, 3)), (np.array(RELAX_STEPS)[:, None, None] * h * _DIRS26[None]).reshape(-1, 3)])
    lp = np.concatenate([pts[local], pts[r] + off])
    rep = np.repeat(inv[None], len(off), axis=0)
    rep = np.where(rep == j, (len(local) + np.arange(len(off)))[:, None, None], rep)
    score = _margin(tet_quality(lp, rep.reshape(-1, 4), device), floor, ceiling).reshape(len(off), len(rt)).min(axis=1)
    best = int(np.argmax(score))
    return lp[len(local) + best], float(score[best])


def _relax_star(pts, star, free, h, floor, ceiling, device):
    """{vertex: position} for the ``free`` vertices (few) that bring every tetrahedron of
    ``star`` (all those around them, and the ones to mend) into [floor, ceiling], by rounds of
    :func:`_climb` one vertex at a time; None when some tetrahedron stays out of range."""
    trial = {}
    for _ in range(RELAX_ROUNDS):
        for r in free:
            trial[r], _ = _climb(_with(pts, trial), r, star[(star == r).any(axis=1)], h, floor, ceiling, device)
        if _margin(tet_quality(_with(pts, trial), star, device), floor, ceiling).min() >= 0:
            return trial
    return None


def _ring_flip(pts, tets, around, u, w, a, b, outside, v_cap, floor, ceiling, device, relax=None, busy=None):
    """The tetrahedra ``around`` the boundary edge (u, w), whose two boundary triangles end
    on a and b, replaced so that the boundary runs along the chord a-b: the ring of vertices
    around the edge (a, ..., b), closed by the chord, is triangulated by a fan from one of its
    vertices (the fan whose worst dihedral angle is largest), and each triangle coned from u
    and from w. Kept only when the new tetrahedra are positive, in [floor, ceiling], and fill
    the old ones with the cap (u, w, a, b) added (``outside``) or taken off.

    ``relax`` (vt_ptr, vt_idx, interior (n,) bool, h), optional: when no fan keeps the range,
    the interior ring vertices of the best filling fan are relocated (:func:`_relax_star`) and
    the flip kept, with the relocations returned, when every new tetrahedron and every one
    around them is in range.

    ``busy`` (n,) bool, optional: no flip when a ring vertex between a and b is busy (another flip's).

    Returns (ring vertices, new tetrahedra (2 (k - 1), 4) or None, new boundary faces (2, 3),
    relocations {vertex: position} to apply with the flip)."""
    others = np.array([[x for x in t if x != u and x != w] for t in tets[around]])
    if others.shape != (len(around), 2):
        return np.zeros(0, np.int64), None, None, {}
    ring = [a]
    left = list(range(len(others)))
    while ring[-1] != b and left:  # walk the chain of tetrahedra from a to b (k of them: a short loop)
        nxt = [j for j in left if ring[-1] in others[j]]
        if len(nxt) != 1:
            return np.array(ring), None, None, {}
        j = nxt[0]
        left.remove(j)
        ring.append(others[j][0] if others[j][1] == ring[-1] else others[j][1])
    ring = np.array(ring)
    if ring[-1] != b or left or len(np.unique(ring)) != len(ring) or (busy is not None and busy[ring[1:-1]].any()):
        return ring, None, None, {}
    k = len(ring)
    v_old = tet_quality(pts, tets[around], device)[:, 3].sum()
    v_new = v_old + (v_cap if outside else -v_cap)
    best, best_q = None, -np.inf
    near, near_q, moves = None, -np.inf, {}  # the best filling fan out of range
    for apex in range(k):  # fans of the closed ring polygon from each of its vertices
        poly = np.roll(ring, -apex)
        tri = np.stack([np.full(k - 2, poly[0]), poly[1:-1], poly[2:]], axis=1)
        cand = np.concatenate([np.column_stack([np.full(k - 2, u), tri]), np.column_stack([np.full(k - 2, w), tri])])
        vol = np.einsum("ij,ij->i", np.cross(pts[cand[:, 1]] - pts[cand[:, 0]], pts[cand[:, 2]] - pts[cand[:, 0]]),
                        pts[cand[:, 3]] - pts[cand[:, 0]])
        cand[vol < 0, 2:] = cand[vol < 0, 3:1:-1]
        q = tet_quality(pts, cand, device)
        fills = abs(q[:, 3].sum() - v_new) <= 1e-9 * max(v_old, 1e-300)
        if fills and (q[:, 3] > 0).all() and q[:, 0].min() >= floor and q[:, 1].max() <= ceiling \
                and q[:, 0].min() > best_q:
            best, best_q = cand, q[:, 0].min()
        m = _margin(q, floor, ceiling).min()
        if fills and best is None and np.isfinite(m) and m > near_q:
            near, near_q = cand, m
    if best is None and near is not None and relax is not None:
        vt_ptr, vt_idx, interior, h = relax
        free = [r for r in ring if interior[r]]
        if free:
            _, old_t = gather_rows(vt_ptr, vt_idx, np.array(free))
            old_t = np.setdiff1d(old_t, around)
            star = np.concatenate([tets[old_t], near])  # every tetrahedron a relocation changes
            moves = _relax_star(pts, star, free, h, floor, ceiling, device)
            if moves is not None:
                best = near
    if best is None:
        return ring, None, None, {}
    # the new boundary faces: (u, a, b) and (w, a, b), each the face of its tetrahedron off the fourth vertex
    faces = []
    for t in best:
        if a in t and b in t:
            off = [j for j in range(4) if t[j] not in (a, b) and t[j] not in (u, w)][0]
            faces.append(t[list(_FACES[off])])
    return ring, best, np.array(faces), moves if best is near else {}


def _collapse(pts, tets, tris, u, c, floor, ceiling, device):
    """Vertex u merged into its neighbour c (edge collapse): the tetrahedra and boundary
    triangles holding both go, u becomes c in the others. Kept only when the changed
    tetrahedra are positive with dihedral angles in [floor, ceiling], no tetrahedron or
    triangle appears twice, every face around c lies in at most two tetrahedra and the faces
    in one are exactly the boundary triangles around c.

    Returns (tets, tris) with u in none of them, or None."""
    has_u, has_c = (tets == u).any(axis=1), (tets == c).any(axis=1)
    changed = np.where(tets[has_u & ~has_c] == u, c, tets[has_u & ~has_c])
    q = tet_quality(pts, changed, device)
    if not len(changed) or _margin(q, floor, ceiling).min() < 0:
        return None
    new_tets = np.concatenate([tets[~has_u], changed])
    tu, tc = (tris == u).any(axis=1), (tris == c).any(axis=1)
    new_tris = np.concatenate([tris[~tu], np.where(tris[tu & ~tc] == u, c, tris[tu & ~tc])])
    star = new_tets[(new_tets == c).any(axis=1)]
    n = np.int64(len(pts))
    if len(np.unique(np.sort(star, axis=1), axis=0)) != len(star):
        return None
    faces = np.concatenate([star[:, list(f)] for f in _FACES])
    fk, cnt = np.unique(_face_key(faces, n), return_counts=True)
    if cnt.max() > 2:
        return None
    ring_tris = new_tris[(new_tris == c).any(axis=1)]
    rk = _face_key(ring_tris, n)
    outer = fk[cnt == 1]
    outer = outer[np.isin(outer, _face_key(faces[(faces == c).any(axis=1)], n))]  # the faces through c
    if len(np.unique(rk)) != len(rk) or not np.array_equal(np.sort(rk), outer):
        return None
    return new_tets, new_tris


def _flip_open_edges(pts, tets, tris, edges, crease, floor, ceiling, device, h=None):
    """Boundary edge flips onto the crease: for an open crossing edge (u, w) whose two
    boundary triangles (u, w, a), (w, u, b) have both third vertices on the crease, the
    boundary is moved from (u, w) to the crease chord (a, b) by removing the tetrahedron
    (u, w, a, b) when it is the only one around (u, w), or else by adding it outside (when
    positive, with dihedral angles in [floor, ceiling], and a-b no edge yet). One flip per
    tetrahedron neighbourhood per call (edges whose triangles overlap are skipped).

    Returns (tets, tris, flipped count)."""
    n = np.int64(len(pts))
    tri_e = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    third = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    tri_id = np.tile(np.arange(len(tris)), 3)
    ekey = np.minimum(tri_e[:, 0], tri_e[:, 1]) * n + np.maximum(tri_e[:, 0], tri_e[:, 1])
    order = np.argsort(ekey, kind="stable")
    ekey, third, tri_id, tri_e = ekey[order], third[order], tri_id[order], tri_e[order]
    want = np.minimum(edges[:, 0], edges[:, 1]) * n + np.maximum(edges[:, 0], edges[:, 1])
    pos = np.searchsorted(ekey, want)
    ok = (pos + 1 < len(ekey)) & (ekey[np.minimum(pos, len(ekey) - 1)] == want)
    pos, edges = pos[ok], edges[ok]
    ok = ekey[pos + 1] == ekey[pos]
    pos, edges = pos[ok], edges[ok]
    a, b = third[pos], third[pos + 1]
    t1, t2 = tri_id[pos], tri_id[pos + 1]
    ok = crease[a] & crease[b] & (a != b)
    # one flip per triangle: no two chosen edges share a boundary triangle
    used = np.zeros(len(tris), bool)
    pick = []
    for i in np.flatnonzero(ok):  # few open edges (tens): a loop over them is cheap
        if not used[t1[i]] and not used[t2[i]]:
            used[t1[i]] = used[t2[i]] = True
            pick.append(i)
    if not pick:
        return tets, tris, 0
    pick = np.array(pick)
    edges, a, b, t1, t2 = edges[pick], a[pick], b[pick], t1[pick], t2[pick]
    vt_ptr, vt_idx = vertex_tets(tets, len(pts))
    interior = np.ones(len(pts), bool)
    interior[tris.ravel()] = False
    relax = None if h is None else (vt_ptr, vt_idx, interior, h)
    bnd = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]])
    bkey = np.minimum(bnd[:, 0], bnd[:, 1]) * n + np.maximum(bnd[:, 0], bnd[:, 1])

    def tets_with(x, y):
        _, around = gather_rows(vt_ptr, vt_idx, np.array([x]))
        return around[(tets[around] == y).any(axis=1)]

    quad = np.stack([edges[:, 0], edges[:, 1], a, b], axis=1)
    directed = set((tris[:, [0, 1, 2]] * n + tris[:, [1, 2, 0]]).ravel().tolist())  # the boundary's directed edges

    def folds(faces, i):
        """Whether new boundary faces (k, 3) in place of triangles t1[i], t2[i] would run an edge
        the way another boundary triangle does (a fold: tetrahedra on one side of it twice);
        else the boundary's directed edges are updated."""
        gone = set((tris[[t1[i], t2[i]]][:, [0, 1, 2]] * n + tris[[t1[i], t2[i]]][:, [1, 2, 0]]).ravel().tolist())
        new = (faces[:, [0, 1, 2]] * n + faces[:, [1, 2, 0]]).ravel().tolist()
        if len(set(new)) != len(new) or any(k in directed and k not in gone for k in new):
            return True
        directed.difference_update(gone)
        directed.update(new)
        return False

    remove, add, drop_tris, new_tris = [], [], [], []
    busy = np.zeros(len(pts), bool)  # one flip per vertex and call: no two flips share an edge a-b
    for i in range(len(edges)):  # tens of edges
        u, w = edges[i]
        around = tets_with(u, w)
        if busy[quad[i]].any() or np.isin(around, remove).any():
            continue
        busy[quad[i]] = True
        ab = min(a[i], b[i]) * n + max(a[i], b[i])
        cap = around[np.isin(tets[around], quad[i]).all(axis=1)]
        if len(around) == 1 and len(cap) == 1:  # the cap tetrahedron: remove it, its two other faces become boundary
            t = tets[cap[0]]
            faces = t[list(_FACES)]
            onb = np.isin(_face_key(faces, n), _face_key(tris[[t1[i], t2[i]]], n))
            if onb.sum() != 2 or (bkey == ab).any() or folds(faces[~onb][:, ::-1], i):
                continue
            remove.append(cap[0])
            new_tris.append(faces[~onb][:, ::-1])
            drop_tris += [t1[i], t2[i]]
        elif len(cap) == 0 and not len(tets_with(a[i], b[i])):
            f1, f2 = tris[t1[i]], tris[t2[i]]
            outside = _signed(pts, np.array([*f1, b[i]])) > 0 and _signed(pts, np.array([*f2, a[i]])) > 0
            if len(around) >= 2:
                # a boundary edge flip: the tetrahedra around (u, w) -> cones from u and w over a
                # triangulation of their ring a .. b closed by the chord (2-2 with one ring vertex c)
                v_cap = abs(_signed(pts, quad[i])) / 6.0
                ring, new_t, faces, moves = _ring_flip(pts, tets, around, u, w, a[i], b[i], outside, v_cap, floor,
                                                       ceiling, device, relax, busy)
                if new_t is not None and not folds(faces, i):
                    for r, x in moves.items():
                        pts[r] = x
                    busy[ring] = True
                    remove += list(around)
                    add += list(new_t)
                    new_tris += [faces]
                    drop_tris += [t1[i], t2[i]]
                    continue
            # else the cap tetrahedron added outside
            if not outside:
                continue
            t = quad[i].copy()
            vol = np.dot(np.cross(pts[t[1]] - pts[t[0]], pts[t[2]] - pts[t[0]]), pts[t[3]] - pts[t[0]])
            if vol < 0:
                t[[2, 3]] = t[[3, 2]]
            q = tet_quality(pts, t[None], device)[0]
            if q[3] <= 0 or q[0] < floor or q[1] > ceiling:
                continue
            faces = t[list(_FACES)]
            onb = np.isin(_face_key(faces, n), _face_key(tris[[t1[i], t2[i]]], n))
            if onb.sum() != 2 or folds(faces[~onb], i):
                continue
            add.append(t)
            new_tris.append(faces[~onb])
            drop_tris += [t1[i], t2[i]]
    if not new_tris:
        return tets, tris, 0
    keep_t = np.ones(len(tets), bool)
    keep_t[remove] = False
    tets = np.concatenate([tets[keep_t]] + ([np.array(add)] if add else []))
    keep_f = np.ones(len(tris), bool)
    keep_f[drop_tris] = False
    tris = np.concatenate([tris[keep_f]] + new_tris)
    return tets, tris, len(new_tris)


def recover_features(points, tets, tris, target, h: float, *, floor: float = DIHEDRAL_FLOOR,
                     ceiling: float = DIHEDRAL_CEILING, angle: float = FEATURE_ANGLE, passes: int = PASSES,
                     device="cpu"):
    """Move boundary vertices onto the corners and creases of the exact surface, and split
    the boundary edges that still cross a crease (or sag from it) at a crease point.

    Parameters
    ----------
    points : (n, 3) float64
    tets : (m, 4) int, positive
    tris : (k, 3) int, the boundary triangles
    target : :class:`warpmesh.frep.projection.ImplicitTarget` of the shape, clipped by the bounds
    h : float, the lattice's cube side
    floor, ceiling : float, degrees: the dihedral range every accepted move or split keeps around it
    angle : float, degrees between end normals that make a boundary edge cross a crease
    passes : int, rounds of (snap, split, smooth the vertices off the creases) while edges stay open

    Returns
    -------
    points : (n', 3) float64, moved, with the split vertices appended
    tets : (m', 4) int64, positive
    tris : (k', 3) int64, the boundary triangles, outward
    crease : (n',) bool, the vertices on a crease or corner
    info : dict, ``feature_edges`` (boundary edges crossing a crease at the start),
        ``feature_open`` (crossing at the end with no end on the crease), ``feature_vertices``,
        ``feature_corners``, ``feature_splits``, ``feature_flips``, ``feature_rejected`` (snaps
        refused by the dihedral range alone), ``feature_relaxed`` (moves and splits kept with
        interior vertices relocated), ``feature_collapsed`` (crease vertices merged into a
        corner), ``feature_floor``, ``feature_ceiling``
    """
    pts = np.array(points, dtype=np.float64, copy=True)
    tets = tets_in = np.asarray(tets, dtype=np.int64)
    tris = tris_in = np.asarray(tris, dtype=np.int64)
    cos_a = float(np.cos(np.radians(angle)))
    rng = np.random.default_rng(0)
    crease = np.zeros(len(pts), bool)
    n_corners = n_split = n_flip = rejected = n_relaxed = n_collapsed = 0

    def normals_at_boundary():
        nrm = np.zeros((len(pts), 3))
        bv = np.unique(tris)
        nrm[bv] = target.normals(pts[bv])
        return bv, nrm

    def open_edges(nrm):
        be = unique_edges(tris, TRI_EDGES)
        cross = np.einsum("ij,ij->i", nrm[be[:, 0]], nrm[be[:, 1]]) < cos_a
        return be[cross & ~(crease[be[:, 0]] | crease[be[:, 1]])]

    def independent(cand, prio, te):
        """The candidates of highest priority among their neighbours (no shared tetrahedron)."""
        p = np.full(len(pts), -np.inf)
        p[cand] = prio + 1e-9 * rng.random(len(cand))
        best = p.copy()
        np.maximum.at(best, te[:, 0], p[te[:, 1]])
        np.maximum.at(best, te[:, 1], p[te[:, 0]])
        return p[cand] >= best[cand]

    def snap(verts, where, open_only=True):
        """Rounds of independent moves of ``verts`` onto ``where``; returns the accepted count.
        The moves refused alone are tried with relocations (only for ends of edges still open
        when ``open_only``)."""
        nonlocal rejected, n_relaxed
        if not len(verts):  # nothing to move (a smooth shape has no corner): skip the adjacency
            return 0
        vt_ptr, vt_idx = vertex_tets(tets, len(pts))
        te = unique_edges(tets)
        todo = np.ones(len(verts), bool)
        done = 0
        for _ in range(ROUNDS):
            todo &= ~crease[verts]
            if not todo.any():
                break
            idx = np.flatnonzero(todo)
            pick = idx[independent(verts[idx], -np.linalg.norm(where[idx] - pts[verts[idx]], axis=1), te)]
            ok = _try_moves(pts, tets, vt_ptr, vt_idx, verts[pick], where[pick], floor, ceiling, device)
            pts[verts[pick[ok]]] = where[pick[ok]]
            crease[verts[pick[ok]]] = True
            done += int(ok.sum())
            rejected += int((~ok).sum())
            todo[pick] = False
        # the moves refused alone: again, with the interior vertices around them relocated
        interior = np.ones(len(pts), bool)
        interior[tris.ravel()] = False
        rest = ~crease[verts]
        for _ in range(ROUNDS):
            if open_only:  # an end of an edge another move has covered need not move
                rest &= np.isin(verts, open_edges(normals_at_boundary()[1]).ravel())
            if not rest.any():
                break
            idx = np.flatnonzero(rest)
            out, tried, acc = _relaxed_moves(pts, tets, te, verts[idx], where[idx], interior, h, floor, ceiling,
                                             device, rng)
            pts[:] = out
            crease[verts[idx[acc]]] = True
            done += int(acc.sum())
            n_relaxed += int(acc.sum())
            rest[idx[tried]] = False
        return done

    def split(edges, a, b):
        """Split ``edges`` at the crease point between the faces of a and b nearest their midpoints."""
        nonlocal pts, tets, tris, crease, n_split, n_relaxed
        if not len(edges):
            return
        mid = 0.5 * (pts[edges[:, 0]] + pts[edges[:, 1]])
        c = crease_points(target, pts[a], pts[b], h, cos_a, near=mid)
        reach = np.all(np.isfinite(c), axis=1) & (np.linalg.norm(c - mid, axis=1) < MAX_MOVE * h)
        edges, c = edges[reach], c[reach]
        for _ in range(ROUNDS):
            if not len(edges):
                break
            n0 = len(pts)
            pts, tets, tris, done = _split_edges(pts, tets, tris, edges, c, floor, ceiling, device, rng)
            crease = np.concatenate([crease, np.ones(len(pts) - n0, bool)])
            n_split += int(done.sum())
            edges, c = edges[~done], c[~done]
            if not done.any():
                break
        # the splits refused alone: again, with the interior vertices around the new one relocated
        # (one edge at a time: tens of them)
        for e, x in zip(edges, c):
            p2, t2, f2, done = _split_edges(pts, tets, tris, e[None], x[None], -1.0, 181.0, device, rng)
            if not done[0]:
                continue
            m = len(p2) - 1
            interior = np.ones(len(p2), bool)
            interior[f2.ravel()] = False
            ring = np.unique(t2[(t2 == m).any(axis=1)])
            free = [r for r in ring if interior[r]]
            near = np.zeros(len(p2), bool)
            near[free] = True
            near[m] = True
            moves = _relax_star(p2, t2[near[t2].any(axis=1)], free, h, floor, ceiling, device) if free else None
            if moves is None:
                continue
            pts, tets, tris = _with(p2, moves), t2, f2
            crease = np.concatenate([crease, [True]])
            n_split += 1
            n_relaxed += 1

    def collapse_near_corners():
        nonlocal tets, tris
        chords, opp = _crease_chords(pts, tris, crease, target, cos_a)
        if not len(chords) or not len(corners):
            return 0
        mid = 0.5 * (pts[chords[:, 0]] + pts[chords[:, 1]])
        c = crease_points(target, pts[opp[:, 0]], pts[opp[:, 1]], h, cos_a, near=mid)
        sag = np.linalg.norm(c - mid, axis=1)
        chords = chords[np.isfinite(sag) & (sag > SAG * h)]
        is_corner = np.zeros(len(pts), bool)
        is_corner[corners] = True
        be = unique_edges(tris, TRI_EDGES)
        to_corner = be[is_corner[be[:, 0]] ^ is_corner[be[:, 1]]]
        to_corner = np.where(is_corner[to_corner[:, 0]][:, None], to_corner[:, ::-1], to_corner)  # (vertex, corner)
        done, gone = 0, np.zeros(len(pts), bool)
        for e in chords:  # few: a loop
            cand = to_corner[np.isin(to_corner[:, 0], e) & ~is_corner[to_corner[:, 0]]]
            if not len(cand):
                continue
            dist = np.linalg.norm(pts[cand[:, 0]] - pts[cand[:, 1]], axis=1)
            u, k = cand[np.argmin(dist)]
            if dist.min() >= MAX_MOVE * h or gone[u] or gone[k]:
                continue
            out = _collapse(pts, tets, tris, u, k, floor, ceiling, device)
            if out is not None:
                tets, tris = out
                gone[u] = True
                crease[u] = False
                done += 1
        return done

    bv, nrm = normals_at_boundary()
    n_cross = len(open_edges(nrm))
    # corners first: one vertex each
    c_verts, c_pts = _ring_corners(pts, bv, unique_edges(tris, TRI_EDGES), nrm, h)
    real, c_pts = _confirm_corners(target, c_pts, h)
    c_verts, c_pts = c_verts[real], c_pts[real]
    n_corners = snap(c_verts, c_pts, open_only=False)
    corners = np.flatnonzero(crease)
    for k in range(passes):
        # an end of every open crossing edge onto the crease nearest it (the nearer first)
        e = open_edges(nrm)
        if not len(e):
            break
        v, w = np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])
        cosv = np.einsum("ij,ij->i", nrm[v], nrm[w])
        o = np.lexsort((cosv, v))  # per vertex, the other end whose normal differs most
        first = o[np.r_[True, v[o][1:] != v[o][:-1]]]
        v, w = v[first], w[first]
        c = crease_points(target, pts[v], pts[w], h, cos_a)
        reach = np.all(np.isfinite(c), axis=1) & (np.linalg.norm(c - pts[v], axis=1) < MAX_MOVE * h)
        snap(v[reach], c[reach])
        # the crossing edges still open: split at the crease point nearest their midpoint
        e = open_edges(nrm)
        split(e, e[:, 0], e[:, 1])
        # the crossing edges still open between two crease vertices: flip the boundary onto them
        bv, nrm = normals_at_boundary()
        tets, tris, k_flip = _flip_open_edges(pts, tets, tris, open_edges(nrm), crease, floor, ceiling, device, h)
        n_flip += k_flip
        bv, nrm = normals_at_boundary()
        if k + 1 < passes and len(open_edges(nrm)):
            # room for the next pass: smooth the vertices off the creases (never lowering the
            # smallest dihedral angle); cap vertices stay
            lo, hi = target.bounds if target.bounds is not None else (np.full(3, -np.inf), np.full(3, np.inf))
            on_cap = (np.minimum(pts - lo, hi - pts).min(axis=1) <= 1e-4 * h)
            on_b = np.zeros(len(pts), bool)
            on_b[bv] = True
            near = np.zeros(len(pts), bool)  # two rings of tetrahedra around the open edges
            near[open_edges(nrm).ravel()] = True
            for _ in range(2):
                near[tets[near[tets].any(axis=1)].ravel()] = True
            # only the tetrahedra around the vertices that may move take part
            sub = tets[near[tets].any(axis=1)]
            pts, _ = smooth_tets(pts, sub, tris, on_b & ~crease & ~on_cap, crease | on_cap, target.tape,
                                 sweeps=2, device=device, only=near)
            bv, nrm = normals_at_boundary()
    # chords of the crease that sag more than ``SAG * h`` from it: split at the crease's midpoint
    chords, opp = _crease_chords(pts, tris, crease, target, cos_a)
    if len(chords):
        mid = 0.5 * (pts[chords[:, 0]] + pts[chords[:, 1]])
        c = crease_points(target, pts[opp[:, 0]], pts[opp[:, 1]], h, cos_a, near=mid)
        sag = np.linalg.norm(c - mid, axis=1)
        far = np.isfinite(sag) & (sag > SAG * h)
        split(chords[far], opp[far, 0], opp[far, 1])
        # chords still sagging that cut a corner: their end nearest a corner it neighbours
        # (within MAX_MOVE h) is merged into the corner
        n_collapsed += collapse_near_corners()
        # the new crease vertices may close open edges by a flip
        bv, nrm = normals_at_boundary()
        tets, tris, k_flip = _flip_open_edges(pts, tets, tris, open_edges(nrm), crease, floor, ceiling, device, h)
        n_flip += k_flip
    used = np.zeros(len(pts), bool)
    used[tets.ravel()] = True
    if not used.all():  # vertices merged into corners: renumbered away
        remap = np.cumsum(used) - 1
        pts, crease, tets, tris = pts[used], crease[used], remap[tets], remap[tris]
    bv, nrm = normals_at_boundary()
    # the moves are judged by the dihedral angles around them only: where boundary faces now
    # cross (an under-resolved surface near a crease), the whole recovery is undone
    crossing = len(find_self_intersections(pts, tris, device=device))
    if crossing:
        pts, tets, tris = np.array(points, dtype=np.float64), np.asarray(tets_in), np.asarray(tris_in)
        crease = np.zeros(len(pts), bool)
    info = {"feature_undone": int(crossing), "feature_edges": int(n_cross), "feature_open": int(len(open_edges(nrm))),
            "feature_vertices": int(crease.sum()), "feature_corners": n_corners, "feature_splits": n_split, "feature_flips": n_flip,
            "feature_relaxed": n_relaxed, "feature_collapsed": n_collapsed,
            "feature_rejected": rejected, "feature_floor": float(floor), "feature_ceiling": float(ceiling)}
    return pts, tets, tris, crease, info


def feature_distance(points, tris, samples) -> np.ndarray:
    """(s,) the distance from each sample point to the nearest edge of the triangles.

    Example
    -------
    >>> feature_distance(np.eye(3), np.array([[0, 1, 2]]), np.array([[0.5, 0.5, 0.0]])).round(6).tolist()
    [0.0]
    """
    from scipy.spatial import cKDTree

    e = unique_edges(np.asarray(tris, dtype=np.int64), TRI_EDGES)
    a, b = np.asarray(points)[e[:, 0]], np.asarray(points)[e[:, 1]]
    s = np.asarray(samples, dtype=np.float64).reshape(-1, 3)
    k = min(24, len(e))
    _, idx = cKDTree(0.5 * (a + b)).query(s, k=k)
    idx = np.asarray(idx).reshape(len(s), k)
    ab = b[idx] - a[idx]
    t = np.einsum("ijk,ijk->ij", s[:, None] - a[idx], ab) / np.maximum(np.einsum("ijk,ijk->ij", ab, ab), 1e-300)
    q = a[idx] + np.clip(t, 0.0, 1.0)[..., None] * ab
    return np.linalg.norm(q - s[:, None], axis=2).min(axis=1)


def example_edges(name: str = "part", n: int = 64) -> np.ndarray:
    """(s, 3) points on the exact sharp edges of ``wm.example(name)`` ('part' only), ``n``
    per curve: the box's twelve edges (no hole or boss reaches them), the holes' rims (circles
    r = 0.2 at z = ±0.3) and the boss's creases (the sphere r = 0.5 meets the plate's faces
    z = ±0.3 in circles of radius 0.4). The reference for :func:`feature_distance`.

    Example
    -------
    >>> example_edges("part", 8).shape  # 12 box edges, 8 rims, 2 boss creases
    (176, 3)
    """
    if name != "part":
        raise ValueError(f"expected 'part' for 'name' (the example with known edges), got {name!r}")
    t = (np.arange(n) + 0.5) / n
    out = []
    for a in range(3):  # box edges along axis a
        half = np.array([1.0, 1.0, 0.3])
        b, c = [k for k in range(3) if k != a]
        for sb in (-1, 1):
            for sc in (-1, 1):
                p = np.zeros((n, 3))
                p[:, a] = half[a] * (2 * t - 1)
                p[:, b], p[:, c] = sb * half[b], sc * half[c]
                out.append(p)
    ang = 2 * np.pi * t
    circle = np.stack([np.cos(ang), np.sin(ang), np.zeros(n)], axis=1)
    for z in (-0.3, 0.3):
        for sx in (-1, 1):
            for sy in (-1, 1):
                out.append(circle * 0.2 + [sx * 0.6, sy * 0.6, z])
        out.append(circle * 0.4 + [0.0, 0.0, z])
    return np.concatenate(out)
