"""Sharp features of surface meshes: detection, recovery on the exact surface, feature lines.

* :func:`insert_creases` recovers the sharp edges that marching cubes chamfers: where
  the exact normals at the two ends of an edge turn by more than the feature angle, the
  edge is split at the crease point, the point of the line where the two tangent planes
  meet that lies abreast of the edge (the dual-contouring idea, applied to mesh edges).
  Two such splits in one triangle join along the crease, so the crease becomes a chain
  of mesh edges. A split or snap that would fold the surface, cross a face or turn one
  inwards is not made (:mod:`warpmesh.optimize.embedding`).
* :func:`detect_features` marks feature edges (dihedral angle above the threshold,
  open boundaries, edges between triangles of different refs) and classifies the
  vertices: free, on a feature line, or a corner (where the feature degree is not 2 or
  the line turns sharply).
* :class:`FeatureLines` keeps the feature polylines of the input so that vertices on
  them move only along them.

Examples
--------
>>> import numpy as np, trimesh
>>> from warpmesh.optimize.local_ops import Surface
>>> box = trimesh.creation.box((1, 1, 1))
>>> s = Surface(box.vertices, box.faces)
>>> detect_features(s, angle=45.0)
>>> int((s.vclass == 2).sum()), len(s.feature_keys)     # 8 corners, 12 box edges
(8, 12)
"""

from __future__ import annotations

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from warpmesh.optimize.local_ops import (CORNER, FREE, gather, LINE, quality_of, select_independent, SPLIT_CHILD_Q, splits_keep_faces, Surface, vertex_neighbours)
from warpmesh.optimize.embedding import revert_violations, verified_split
from warpmesh.surface.adaptive.qef import qef_points

__all__ = ["detect_features", "insert_creases", "FeatureLines", "DEFAULT_ANGLE", "CORNER_TURN"]

#: dihedral angle (degrees) above which an edge is a feature edge
DEFAULT_ANGLE = 40.0
#: a feature line turning by more than this (degrees) at a vertex makes it a corner
CORNER_TURN = 50.0


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1), 1e-300)[..., None]


def _face_normals(points, tri):
    p = points[tri]
    return _unit(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))


def exact_dihedral_cos(s: Surface, topo, target, offset: float = 0.2, which=None) -> np.ndarray:
    """Cosine of the exact surface's turn across each edge (``which``: those edges only,
    indices into ``topo.edges``; the others get 1, flat).

    Points beside the edge on either side (``offset`` of the edge length along the
    surface, perpendicular to the edge) are projected onto the surface, at a quarter and
    three quarters of its length, and their exact normals compared; the larger of the
    two cosines is returned, so an edge counts as sharp only when it follows the crease
    along its length (a chamfer edge crossing the crease does not). Boundary edges give -1.
    """
    p = s.points
    a, b = p[topo.edges[:, 0]], p[topo.edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    median = np.median(length)
    sel = np.arange(len(a)) if which is None else np.asarray(which)
    a, b, length = a[sel], b[sel], length[sel]
    inner = topo.n_faces[sel] == 2
    axis = _unit(b - a)
    length = np.maximum(length, 0.5 * median)  # tiny edges between crease points
    fn = _face_normals(p, s.triangles)
    up = _unit(fn[topo.face0[sel]] + fn[np.maximum(topo.face1[sel], 0)] + target.normals(a) + target.normals(b))
    side = _unit(np.cross(axis, up)) * (offset * length)[:, None]
    out = np.full(len(a), -1.0)
    for t in (0.25, 0.75):
        q = a + t * (b - a)
        pts = target.project(np.concatenate([q + side, q - side]), max_step=np.tile(offset * length, 2))
        n = target.normals(pts)
        c = np.einsum("ij,ij->i", n[: len(q)], n[len(q):])
        out = c if t == 0.25 else np.maximum(out, c)
    if which is None:
        return np.where(inner, out, -1.0)
    full = np.ones(len(topo.edges))
    full[sel] = np.where(inner, out, -1.0)
    return full


def detect_features(s: Surface, angle: float = DEFAULT_ANGLE, target=None, crease=None) -> None:
    """Mark feature edges and classify vertices of ``s`` in place (see module docstring).

    With a ``target`` that has exact normals the sharpness of an edge is measured on the
    exact surface (:func:`exact_dihedral_cos`), not on the triangles, whose normals are
    noise on a marching-cubes mesh.
    """
    topo = s.topology()
    inner = topo.n_faces == 2
    f1 = np.maximum(topo.face1, 0)
    if target is not None and crease is not None and crease.any():
        # only edges between two crease points can be features (below): the others' turn
        # is not needed
        cos = exact_dihedral_cos(s, topo, target, which=np.flatnonzero(inner & crease[topo.edges].all(axis=1)))
    elif target is not None:
        cos = exact_dihedral_cos(s, topo, target)
    else:
        nrm = _face_normals(s.points, s.triangles)
        cos = np.einsum("ij,ij->i", nrm[topo.face0], nrm[f1])
    feat = ~inner | (inner & (cos < np.cos(np.radians(angle))))
    if crease is not None and crease.any():  # recovered creases: only edges between crease points
        feat &= ~inner | crease[topo.edges].all(axis=1)
    feat |= inner & (s.refs[topo.face0] != s.refs[f1])
    e = topo.edges[feat]
    s.feature_keys = np.sort(topo.keys[feat])
    n = len(s.points)
    deg = np.bincount(e.ravel(), minlength=n)
    vclass = np.full(n, FREE, np.int8)
    vclass[(deg == 1) | (deg == 2)] = LINE  # a dangling end is noise more often than a corner
    vclass[deg >= 3] = CORNER
    # sharp turns of a line: the two feature edges at a LINE vertex
    line_v = np.flatnonzero(deg == 2)
    if len(line_v):
        src = np.concatenate([e[:, 0], e[:, 1]])
        dst = np.concatenate([e[:, 1], e[:, 0]])
        order = np.argsort(src, kind="stable")
        src, dst = src[order], dst[order]
        start = np.searchsorted(src, line_v)
        d0 = _unit(s.points[dst[start]] - s.points[line_v])
        d1 = _unit(s.points[dst[start + 1]] - s.points[line_v])
        turn = 180.0 - np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", d0, d1), -1, 1)))
        vclass[line_v[turn > CORNER_TURN]] = CORNER
    s.vclass = vclass
    # line ids: components of the feature graph restricted to LINE vertices
    both = (vclass[e[:, 0]] == LINE) & (vclass[e[:, 1]] == LINE)
    g = sparse.coo_matrix((np.ones(both.sum()), (e[both, 0], e[both, 1])), shape=(n, n))
    _, label = csgraph.connected_components(g, directed=False)
    s.line_id = np.where(vclass == LINE, label, -1).astype(np.int64)


def insert_creases(s: Surface, target, angle: float = DEFAULT_ANGLE, passes: int = 6,
                   crease: np.ndarray | None = None) -> np.ndarray:
    """Split edges that cross a crease of the exact surface at the crease point.

    Returns the crease flag of every vertex (inserted or snapped onto a crease).
    ``target`` must give exact ``normals`` (an implicit or volume target).
    """
    cos_a = np.cos(np.radians(angle))
    crease = np.zeros(len(s.points), bool) if crease is None else crease.copy()
    total = 0
    for _ in range(passes):
        topo = s.topology()
        if len(crease) < len(s.points):
            crease = np.concatenate([crease, np.zeros(len(s.points) - len(crease), bool)])
        p = s.points
        nv = target.normals(p)
        a, b = topo.edges[:, 0], topo.edges[:, 1]
        cand = np.flatnonzero((np.einsum("ij,ij->i", nv[a], nv[b]) < cos_a) & ~crease[a] & ~crease[b])
        if len(cand) == 0:
            break
        a, b = a[cand], b[cand]
        na, nb = nv[a], nv[b]
        d = np.cross(na, nb)
        m = 0.5 * (p[a] + p[b])
        mat = np.stack([na, nb, _unit(d)], axis=1)
        rhs = np.stack([np.einsum("ij,ij->i", na, p[a]), np.einsum("ij,ij->i", nb, p[b]),
                        np.einsum("ij,ij->i", _unit(d), m)], axis=1)
        ok = np.abs(np.linalg.det(mat)) > 1e-6
        c = np.full_like(m, np.nan)
        c[ok] = np.linalg.solve(mat[ok], rhs[ok][..., None])[..., 0]
        length = np.linalg.norm(p[a] - p[b], axis=1)
        c[ok] = _refine_crease(target, c[ok], p[a][ok], p[b][ok], length[ok], cos_a)
        off = np.linalg.norm(c - m, axis=1)
        da, db = np.linalg.norm(c - p[a], axis=1), np.linalg.norm(c - p[b], axis=1)
        ok &= off < 0.75 * length
        near = ok & (np.minimum(da, db) <= 0.15 * length)
        total += _snap(s, np.where(da <= db, a, b)[near], c[near], crease, normals=target.normals)
        ok &= ~near
        cand, c = cand[ok], c[ok]
        # a crease point lies off the edge: its children may turn away from their parent
        # (often a twisted chamfer) but never vanish, and (the embedding checks of
        # verified_split) never fold, cross a face or face inwards
        cand, c = splits_keep_faces(s, topo, cand, c, turn=False)
        if len(cand) == 0:
            continue
        face_cand = np.concatenate([np.arange(len(cand))] * 2)
        faces = np.concatenate([topo.face0[cand], topo.face1[cand]])
        keep = faces >= 0
        prio = -np.linalg.norm(np.cross(nv[topo.edges[cand, 0]], nv[topo.edges[cand, 1]]), axis=1)
        win = select_independent(len(cand), prio, faces[keep], face_cand[keep])
        n0 = len(s.points)
        total += len(verified_split(s, topo, cand[win], c[win], target.normals))
        crease = np.concatenate([crease, np.zeros(len(s.points) - n0, bool)])
        crease[n0:] = True
    if len(crease) < len(s.points):
        crease = np.concatenate([crease, np.zeros(len(s.points) - len(crease), bool)])
    return crease


#: smallest over largest eigenvalue of the normals' tensor over a vertex ring for a corner
CORNER_SPREAD = 0.15


def snap_corners(s: Surface, target, crease: np.ndarray) -> np.ndarray:
    """Move a vertex onto each corner where three or more faces of the exact surface meet.

    Around every vertex, the exact normals at its ring (the vertex and its neighbours)
    are checked for spread in all three directions (the normals' tensor has rank 3); the
    dual-contouring point of the ring's tangent planes (:func:`warpmesh.surface.adaptive.qef.qef_points`)
    is then the corner. One vertex per corner moves (the strongest spread among vertices
    two rings apart). Returns the crease flags with the snapped vertices set.
    """
    topo = s.topology()
    n = len(s.points)
    ptr, nb = vertex_neighbours(topo.edges, n)
    owner, ring = gather(ptr, nb, np.arange(n))
    group = np.concatenate([np.arange(n), owner])
    pts = s.points[np.concatenate([np.arange(n), ring])]
    nrm = target.normals(pts)
    tensor = np.zeros((n, 3, 3))
    for i in range(3):
        for j in range(3):
            tensor[:, i, j] = np.bincount(group, nrm[:, i] * nrm[:, j], n)
    lam = np.linalg.eigvalsh(tensor)
    spread = lam[:, 0] / np.maximum(lam[:, 2], 1e-300)
    cand = np.flatnonzero(spread > CORNER_SPREAD)
    if s.vclass is not None and (s.vclass == CORNER).any():  # corners found before stay the only ones
        near_corner = np.zeros(n, bool)
        near_corner[owner[s.vclass[ring] == CORNER]] = True
        near_corner |= s.vclass == CORNER
        grown = near_corner.copy()
        grown[owner[near_corner[ring]]] = True
        # ... but may themselves still move onto the exact corner
        cand = cand[~grown[cand] | (s.vclass[cand] == CORNER)]
    if len(cand) == 0:
        return crease
    sub = np.isin(group, cand)
    remap = np.full(n, -1)
    remap[cand] = np.arange(len(cand))
    x, rank = qef_points(remap[group[sub]], pts[sub], nrm[sub], len(cand))
    reach = np.zeros(n)
    np.maximum.at(reach, owner, np.linalg.norm(s.points[ring] - s.points[owner], axis=1))
    ok = (rank == 3) & (np.linalg.norm(x - s.points[cand], axis=1) < reach[cand])
    cand, x = cand[ok], x[ok]
    if len(cand) == 0:
        return crease
    # one vertex per corner: candidates conflict within two rings
    own1, r1 = gather(ptr, nb, cand)
    own2, r2 = gather(ptr, nb, r1)
    idx = np.arange(len(cand))
    win = select_independent(len(cand), -spread[cand], np.concatenate([r1, r2[:], cand]),
                             np.concatenate([own1, own1[own2], idx]))
    crease = crease.copy()
    _snap(s, cand[win], x[win], crease, force=True, normals=target.normals)
    return crease


def _planes_meet(na, pa, nb, pb, c):
    """The point of the line where two planes meet that is nearest ``c`` (NaN if parallel)."""
    d = _unit(np.cross(na, nb))
    mat = np.stack([na, nb, d], axis=1)
    rhs = np.stack([np.einsum("ij,ij->i", na, pa), np.einsum("ij,ij->i", nb, pb), np.einsum("ij,ij->i", d, c)], 1)
    out = np.full_like(c, np.nan)
    ok = np.abs(np.linalg.det(mat)) > 1e-6
    out[ok] = np.linalg.solve(mat[ok], rhs[ok][..., None])[..., 0]
    return out


def _refine_crease(target, c, pa, pb, length, cos_a, steps: int = 3):
    """Move crease points onto the true crease: tangent planes sampled on each face just
    beside the current point (a fifth of the edge away), intersected again."""
    for _ in range(steps):
        na, nb = target.normals(pa), target.normals(pb)
        d = _unit(np.cross(na, nb))

        def beside(p):
            w = p - c
            return c + 0.2 * length[:, None] * _unit(w - np.einsum("ij,ij->i", w, d)[:, None] * d)
        qa = target.project(beside(pa), max_step=0.2 * length)
        qb = target.project(beside(pb), max_step=0.2 * length)
        ma, mb = target.normals(qa), target.normals(qb)
        new = _planes_meet(ma, qa, mb, qb, c)
        good = (np.einsum("ij,ij->i", ma, mb) < cos_a) & np.all(np.isfinite(new), axis=1)
        good &= np.linalg.norm(new - c, axis=1) < 0.25 * length
        c = np.where(good[:, None], new, c)
        pa, pb = np.where(good[:, None], qa, pa), np.where(good[:, None], qb, pb)
    return c


def _snap(s: Surface, verts: np.ndarray, where: np.ndarray, crease: np.ndarray, force: bool = False,
          normals=None) -> int:
    """Move vertices onto nearby crease points (one move per vertex), unless a face would turn
    over, fold or cross another one (:func:`warpmesh.optimize.embedding.revert_violations`)."""
    verts, first = np.unique(verts, return_index=True)
    keep = np.ones(len(verts), bool) if force else ~crease[verts]
    verts, where = verts[keep], where[first][keep]
    if len(verts) == 0:
        return 0
    t = s.triangles
    moved = np.zeros(len(s.points), bool)
    moved[verts] = True
    faces = np.flatnonzero(moved[t].any(1))
    newp = s.points.copy()
    newp[verts] = where
    old_n = np.cross(*(s.points[t[faces, k]] - s.points[t[faces, 0]] for k in (1, 2)))
    new_n = np.cross(*(newp[t[faces, k]] - newp[t[faces, 0]] for k in (1, 2)))
    bad = np.einsum("ij,ij->i", old_n, new_n) <= 0.1 * np.linalg.norm(old_n, axis=1) * np.linalg.norm(new_n, axis=1)
    q_old, q_new = quality_of(s.points[t[faces]]), quality_of(newp[t[faces]])
    bad |= ~np.isfinite(q_new) | ((q_new > SPLIT_CHILD_Q) & (q_new > 10 * q_old))  # no sliver either
    undo = np.unique(t[faces[bad]])
    newp[undo] = s.points[undo]
    revert_violations(s.points, newp, t, normals)
    done = verts[np.all(newp[verts] == where, axis=1)]
    s.points = newp
    crease[done] = True
    return len(done)


class FeatureLines:
    """The feature polylines of a surface, to slide feature vertices along.

    Built from the feature edges of ``s`` (after :func:`detect_features`); each segment
    carries the line id of its LINE endpoint (-1 between two corners).
    """

    def __init__(self, s: Surface):
        keys = s.feature_keys
        a, b = keys // np.int64(1 << 31), keys % np.int64(1 << 31)
        self.a, self.b = s.points[a].copy(), s.points[b].copy()
        self.line = np.maximum(s.line_id[a], s.line_id[b])
        self.tree = cKDTree(0.5 * (self.a + self.b)) if len(keys) else None

    def project(self, points: np.ndarray, line_id: np.ndarray) -> np.ndarray:
        """Nearest points on segments of the same line (any line for id -1)."""
        if self.tree is None or len(points) == 0:
            return points.copy()
        k = min(12, len(self.a))
        _, idx = self.tree.query(points, k=k)
        idx = idx.reshape(len(points), k)
        a, b = self.a[idx], self.b[idx]
        ab = b - a
        t = np.einsum("ijk,ijk->ij", points[:, None] - a, ab) / np.maximum(np.einsum("ijk,ijk->ij", ab, ab), 1e-300)
        q = a + np.clip(t, 0, 1)[..., None] * ab
        dist = np.linalg.norm(q - points[:, None], axis=2)
        wrong = (line_id[:, None] >= 0) & (self.line[idx] >= 0) & (self.line[idx] != line_id[:, None])
        dist[wrong] = np.inf
        j = dist.argmin(axis=1)
        out = q[np.arange(len(points)), j]
        none = ~np.isfinite(dist[np.arange(len(points)), j])
        out[none] = points[none]
        return out


def feature_edges_of(s: Surface) -> np.ndarray:
    """(k, 2) vertex pairs of the feature edges."""
    keys = s.feature_keys
    return np.stack([keys // np.int64(1 << 31), keys % np.int64(1 << 31)], axis=1)
