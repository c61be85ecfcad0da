"""Graded backgrounds for isosurface stuffing: a BCC lattice refined by conforming
longest-edge bisection to a size field.

Labelle & Shewchuk (2007) grade their lattice with a balanced octree whose uniform cells hold
BCC tetrahedra and whose size transitions hold bisected ("half") and twice-bisected
("quarter") BCC tetrahedra. This module builds an equivalent sound construction: the
coarse BCC lattice (cube side ``h0``), whose tetrahedra are bisected at their longest edge
(Rivara's refinement with conformity closure) until every one is no longer than the size
asked where it lies. A BCC tetrahedron bisects into two half tetrahedra, a half into two
quarters (a Kuhn tetrahedron of half the cube), a quarter into a third class, which bisects
into half tetrahedra of the half-size lattice: the background's tetrahedra fall into four
similarity classes (the BCC one, and the cycle of three that bisection runs through), with
dihedral angles in [45°, 120°] (``tests/solid/test_graded.py`` counts them). Unlike the
paper's octree, a refined region is not a finer BCC lattice (longest-edge bisection does
not return to it), so the stencils' proof does not carry over: the dihedral range of every
graded mesh is measured and reported. Ties between equally long edges are broken by
the edges' global vertex ids, so every tetrahedron holding an edge sees the same order and
the refinement conforms (no hanging vertex): each face of the background lies in one or two
tetrahedra. Conforming and of four shapes, neighbours share whole faces, so their sizes
differ by a bounded factor: the grading is balanced, as the paper's octree is.

The bisection is Rivara's, as :func:`warpmesh.modify.refine_local.refine_local` does it for
any simplex mesh; it is kept here because the background needs what that general routine
does not give: exact ties (the coordinates below), the interval test that leaves the
outside of the domain coarse (a tetrahedron is refined only where its grown bounding box
may hold f >= 0, the octree's culling), the size sampled once per node, and the bisection
level of every tetrahedron.

Coordinates are kept in half-cube units (black nodes even, red nodes odd integers, as
:func:`warpmesh.solid.lattice.node_coordinates`), so every midpoint is an exact dyadic
float and equal lengths compare equal.

Size fields: ``size`` is a number (uniform; the uniform path does not come here), a callable
of position (takes an (n, 3) float64 array, returns n positive sizes), or ``"curvature"``
(:func:`curvature_size` with its defaults). A size is the longest edge asked of a
background tetrahedron (the cube side of a BCC one, as the uniform ``size``).

Example
-------
>>> import numpy as np
>>> field = size_field(lambda p: 0.2 + 0.2 * (p[:, 0] > 0), np.array([[-1.0] * 3, [1.0] * 3]))
>>> round(field.smallest, 2), round(field.largest, 2)
(0.2, 0.4)
>>> coords, tets, levels = refine_bcc(np.zeros(3, np.int64) + 4, 0.8, np.zeros(3), field)
>>> tets.shape[1], bool((levels > 0).any())
(4, True)
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from warpmesh._util.parallel import cpu_view, launch_split, n_workers
from warpmesh.kernels import stuffing as K
from warpmesh.solid.lattice import lattice_tables, node_coordinates

__all__ = ["CURVATURE_ANGLE", "CURVATURE_GRADING", "SizeField", "curvature_size", "size_field", "smallest_size",
           "refine_bcc", "refine_tets", "bcc_tetrahedra", "tet_edges", "EDGE_KEY", "MAX_BACKGROUND_TETS"]

#: the angle (radians) one boundary edge may subtend on the surface: size = angle / curvature
CURVATURE_ANGLE = 0.2
#: how fast the curvature size grows with the distance from the surface
CURVATURE_GRADING = 0.5
#: a background larger than this is refused (raise the sizes)
MAX_BACKGROUND_TETS = 8_000_000
#: edge keys a * EDGE_KEY + b (a < b), those of :func:`tet_edges`
EDGE_KEY = np.int64(1) << np.int64(31)
#: samples per axis used to validate a size callable over the box
_SAMPLES = 9


class SizeField:
    """A validated size field: ``field(points)`` gives (n,) positive float64 sizes.

    Parameters
    ----------
    function : callable
        (n, 3) float64 -> (n,) positive sizes.
    smallest, largest : float
        The extremes seen on a grid of samples over the box (``curvature_size`` states its own).
    """

    def __init__(self, function, smallest: float, largest: float):
        self.function = function
        self.smallest = float(smallest)
        self.largest = float(largest)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return checked_sizes(self.function, np.asarray(points, dtype=np.float64))


def checked_sizes(function, points: np.ndarray) -> np.ndarray:
    """The sizes of ``function`` at (n, 3) points, as (n,) float64, or a ValueError naming
    'size' (wrong shape, NaN, infinite, not positive)."""
    try:
        out = np.asarray(function(points), dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"a 'size' function must take an (n, 3) float array and return n sizes; it raised {exc!r}") from exc
    if out.shape != (len(points),):
        raise ValueError(f"expected a 'size' function to return an array of shape ({len(points)},) for "
                         f"{len(points)} points, got shape {out.shape}")
    bad = ~np.isfinite(out) | (out <= 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"expected positive finite sizes from the 'size' function, got {out[i]!r} at "
                         f"{points[i].tolist()} ({int(bad.sum())} bad of {len(out)})")
    return out


def curvature_size(shape, smallest: float, largest: float, *, angle: float = CURVATURE_ANGLE,
                   grading: float = CURVATURE_GRADING, device="cpu"):
    """A size function small where the surface curves and growing away from it.

    At a point x at distance d = |f|/|grad f| from the surface, with kappa the largest
    principal curvature (in absolute value) of the level set at x's projection onto f = 0
    (two Newton steps), the size is ``clip(clip(angle / kappa, smallest, largest) + grading d,
    smallest, largest)``. Curvatures come from the exact gradient and central differences of it.

    Parameters
    ----------
    shape : Shape or Expr
    smallest, largest : float
        The bounds of the size (positive, smallest <= largest).
    angle : float
        Radians an edge may subtend on a curve of the surface (default 0.2, about 11°).
    grading : float
        Growth of the size per unit of distance from the surface (default 0.5).

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> s = curvature_size(wm.torus(1.0, 0.3), 0.02, 0.5)
    >>> np.round(s(np.array([[1.3, 0.0, 0.0], [0.0, 0.0, 1.0]])), 3).tolist()
    [0.06, 0.5]
    """
    from warpmesh.frep.tape import tape_of, value_gradient_at

    for name, v in (("smallest", smallest), ("largest", largest), ("angle", angle), ("grading", grading)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v) \
                or v < 0 or (v == 0 and name != "grading"):
            raise ValueError(f"expected a positive finite {name!r} for the curvature 'size', got {v!r}")
    if smallest > largest:
        raise ValueError(f"expected 'smallest' <= 'largest' for the curvature 'size', got {smallest!r} > {largest!r}")
    tape = tape_of(shape)
    step = 1e-3 * float(smallest)

    def size(points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, dtype=np.float64)
        f, g = value_gradient_at(tape, p, device=device)
        g2 = np.einsum("ij,ij->i", g, g)
        dist = np.abs(f) / np.sqrt(np.where(g2 > 0, g2, np.inf))
        out = np.full(len(p), float(largest))
        near = np.flatnonzero(dist < largest / max(grading, 1e-12))
        if len(near):
            q, fq, gq = p[near], f[near], g[near]
            for _ in range(2):  # Newton steps onto f = 0
                n2 = np.einsum("ij,ij->i", gq, gq)
                q = q - (fq / np.where(n2 > 0, n2, np.inf))[:, None] * gq
                fq, gq = value_gradient_at(tape, q, device=device)
            hess = np.empty((len(q), 3, 3))
            for a in range(3):
                e = np.zeros(3)
                e[a] = step
                hess[:, :, a] = (value_gradient_at(tape, q + e, device=device)[1]
                                 - value_gradient_at(tape, q - e, device=device)[1]) / (2 * step)
            hess = 0.5 * (hess + hess.transpose(0, 2, 1))
            gn = np.linalg.norm(gq, axis=1)
            nrm = gq / np.where(gn > 0, gn, np.inf)[:, None]
            proj = np.eye(3) - nrm[:, :, None] * nrm[:, None, :]
            shape_op = proj @ hess @ proj / np.where(gn > 0, gn, np.inf)[:, None, None]
            # eigenvalues (k1, k2, 0): k1 + k2 = trace, k1^2 + k2^2 = |S|_F^2
            tr = np.trace(shape_op, axis1=1, axis2=2)
            fro = np.einsum("kij,kij->k", shape_op, shape_op)
            kappa = 0.5 * (np.abs(tr) + np.sqrt(np.maximum(2.0 * fro - tr * tr, 0.0)))
            kappa = np.where(np.isfinite(kappa), kappa, 0.0)
            s = np.clip(angle / np.maximum(kappa, 1e-300), smallest, largest)
            out[near] = np.clip(s + grading * dist[near], smallest, largest)
        return out

    return size


def smallest_size(size, box: np.ndarray) -> float:
    """The smallest size of a graded ``size`` over ``box``, validated (a ValueError naming
    'size' otherwise): ``"curvature"``'s ``smallest``, or a callable's least sample on a 9³ grid
    (at most half the smallest side of the box: larger sizes are clamped to that).

    Example
    -------
    >>> smallest_size("curvature", np.array([[0.0] * 3, [2.0] * 3]))
    0.05
    """
    extent = float(np.min(np.asarray(box)[1] - np.asarray(box)[0]))
    if isinstance(size, str):
        _check_name(size)
        return extent / 40.0
    return min(size_field(size, box).smallest, 0.5 * extent)  # larger sizes are clamped


def _check_name(size: str) -> None:
    if size != "curvature":
        raise ValueError(f"unknown 'size' {size!r}: expected a number, a function of position or 'curvature'")


def size_field(size, box: np.ndarray, shape=None, device="cpu") -> SizeField:
    """Validate a graded ``size`` (a callable or ``"curvature"``) over ``box`` (2, 3).

    ``"curvature"`` is :func:`curvature_size` with ``smallest`` = the smallest side of the box
    / 40, ``largest`` = that side / 6; a callable is sampled on a 9³ grid of the box (sizes
    NaN, not positive, or of the wrong shape raise ValueError naming 'size').
    """
    box = np.asarray(box, dtype=np.float64)
    extent = float(np.min(box[1] - box[0]))
    if isinstance(size, str):
        _check_name(size)
        if shape is None:
            raise ValueError("'size'='curvature' needs the shape")
        lo, hi = extent / 40.0, extent / 6.0
        return SizeField(curvature_size(shape, lo, hi, device=device), lo, hi)
    if not callable(size):
        raise ValueError(f"expected a number, a function of position or 'curvature' for 'size', got {size!r}")
    axes = [np.linspace(box[0, a], box[1, a], _SAMPLES) for a in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    s = checked_sizes(size, grid)
    return SizeField(size, float(s.min()), float(s.max()))


def bcc_tetrahedra(dims) -> tuple[np.ndarray, np.ndarray]:
    """The BCC background of a lattice of ``dims`` black nodes per axis, explicitly.

    Returns
    -------
    coords : (n, 3) float64, the nodes in half-cube units (black even, red odd)
    tets : (m, 4) int64, positive, every tetrahedron whose four nodes exist
    """
    dims = np.asarray(dims, dtype=np.int64)
    layout = lattice_tables()[0].astype(np.int64)
    cells = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), axis=-1).reshape(-1, 3)
    ids = np.full(tuple(dims) + (2,), -1, np.int64)
    black = cells
    red = cells[(cells < dims - 1).all(axis=1)]
    coords = np.concatenate([node_coordinates(0, black), node_coordinates(1, red)]).astype(np.float64)
    ids[tuple(black.T) + (0,)] = np.arange(len(black))
    ids[tuple(red.T) + (1,)] = len(black) + np.arange(len(red))
    tets = []
    for t in range(12):
        ends = black[:, None, :] + layout[t, :, 1:][None]  # (cells, 4, 3)
        colour = layout[t, :, 0]
        ok = ((ends >= 0) & (ends < dims - colour[:, None])).all(axis=(1, 2))
        e = ends[ok]
        tets.append(ids[e[..., 0], e[..., 1], e[..., 2], colour[None, :].repeat(len(e), 0)])
    return coords, np.concatenate(tets)


def tet_edges(tets: np.ndarray) -> np.ndarray:
    """(m, 6) int64: the key a * 2^31 + b (a < b) of each local edge (order ``stencils.EDGES``),
    by a Warp kernel over the CPU cores (:func:`~warpmesh.kernels.stuffing.tet_edge_keys_kernel`).

    >>> tet_edges(np.array([[3, 1, 2, 0]])).tolist() == [[1 * 2**31 + 3, 2 * 2**31 + 3, 3, 2**31 + 2, 1, 2]]
    True
    """
    t = np.ascontiguousarray(tets, dtype=np.int64).reshape(-1, 4)
    keys = np.empty((len(t), 6), np.int64)
    launch_split(K.tet_edge_keys_kernel, len(t), [cpu_view(t.reshape(-1), wp.int64), wp.int64(EDGE_KEY)],
                 [cpu_view(keys.reshape(-1), wp.int64)])
    return keys


def _longest(coords: np.ndarray, tets: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(m,) the key and length of each tetrahedron's longest edge, ties to the smallest key (a
    total order of edges, so tetrahedra sharing an edge agree); a Warp kernel over the CPU
    cores (:func:`~warpmesh.kernels.stuffing.longest_edges_kernel`)."""
    m = len(tets)
    lkey = np.empty(m, np.int64)
    llen = np.empty(m, np.float64)
    if m:
        launch_split(K.longest_edges_kernel, m,
                     [cpu_view(np.asarray(coords, np.float64), wp.vec3d), cpu_view(tets.reshape(-1), wp.int64),
                      cpu_view(keys.reshape(-1), wp.int64)],
                     [cpu_view(lkey, wp.int64), cpu_view(llen, wp.float64)])
    return lkey, llen


class _Rows:
    """A growable array (capacity doubles): ``append`` is amortised O(rows added)."""

    def __init__(self, a: np.ndarray):
        self.a = a
        self.n = len(a)

    def append(self, b: np.ndarray) -> None:
        need = self.n + len(b)
        if need > len(self.a):
            grown = np.empty((max(need, 2 * len(self.a)),) + self.a.shape[1:], self.a.dtype)
            grown[:self.n] = self.a[:self.n]
            self.a = grown
        self.a[self.n:need] = b
        self.n = need

    def view(self) -> np.ndarray:
        return self.a[:self.n]


def _entries(sorted_flat: np.ndarray, order: np.ndarray, keys: np.ndarray) -> np.ndarray:
    """The flat positions (``order``) of the entries of ``sorted_flat`` equal to any of ``keys``."""
    a = np.searchsorted(sorted_flat, keys, "left")
    b = np.searchsorted(sorted_flat, keys, "right")
    n = b - a
    total = int(n.sum())
    if not total:
        return np.empty(0, order.dtype)
    idx = np.repeat(a - np.concatenate([[0], np.cumsum(n)[:-1]]), n) + np.arange(total)
    return order[idx]


def _merged(sorted_flat: np.ndarray, order: np.ndarray, add: np.ndarray, where: np.ndarray):
    """The index (``sorted_flat``, ``order``) with the sorted keys ``add`` at flat positions
    ``where`` merged in (``add`` goes before equal keys of the index), in time linear in its
    size: the merge path split into runs, each merged by one thread
    (:func:`~warpmesh.kernels.stuffing.merge_sorted_kernel`)."""
    n = len(add) + len(sorted_flat)
    keys = np.empty(n, np.int64)
    values = np.empty(n, np.int64)
    if not len(add) or not len(sorted_flat):
        keys[:len(add)], values[:len(add)] = add, where
        keys[len(add):], values[len(add):] = sorted_flat, order
        return keys, values
    runs = 8 * n_workers("cpu")
    per_run = -(-n // runs)
    launch_split(K.merge_sorted_kernel, -(-n // per_run),
                 [per_run, cpu_view(add.astype(np.int64, copy=False), wp.int64),
                  cpu_view(where.astype(np.int64, copy=False), wp.int64),
                  cpu_view(sorted_flat.astype(np.int64, copy=False), wp.int64),
                  cpu_view(order.astype(np.int64, copy=False), wp.int64)],
                 [cpu_view(keys, wp.int64), cpu_view(values, wp.int64)], min_per_worker=1)
    return keys, values


class _Bisection:
    """A conforming tetrahedral mesh under longest-edge bisection: nodes (half-cube units),
    tetrahedra, their longest edge (key, length) and bisection level (their edge keys are held
    only in the two indices below).

    Tetrahedra are append-only: a bisected one stays, marked dead (``alive``), its children
    go after all others, so the living ones in order are the mesh's order. The edge keys of
    all of them are kept sorted in two indices (sorted keys, flat positions tet * 6 + local
    edge): the main one, sorted once, and a recent one the children's keys are merged into
    (linear, no re-sort); the recent one is merged into the main one (dropping the dead)
    when it reaches half its size."""

    def __init__(self, coords: np.ndarray, tets: np.ndarray):
        keys = tet_edges(tets)
        lkey, llen = _longest(coords, tets, keys)
        self.nodes = _Rows(coords)
        self._tets, self._lkey, self._llen = _Rows(tets), _Rows(lkey), _Rows(llen)
        self._levels = _Rows(np.zeros(len(tets), np.int64))
        self._fresh = _Rows(np.ones(len(tets), bool))  # living, not yet checked against the size field
        self._alive = _Rows(np.ones(len(tets), bool))
        self.count = len(tets)  # living tetrahedra
        flat = keys.ravel()
        order = np.argsort(flat)
        self.main = (flat[order], order)
        self.recent = (np.empty(0, np.int64), np.empty(0, np.int64))

    tets = property(lambda self: self._tets.view())
    lkey = property(lambda self: self._lkey.view())
    llen = property(lambda self: self._llen.view())
    fresh = property(lambda self: self._fresh.view())
    alive = property(lambda self: self._alive.view())

    @property
    def n(self) -> int:
        return self.nodes.n

    def coords(self) -> np.ndarray:
        return self.nodes.view()

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(coords, tets, levels) of the living tetrahedra."""
        al = self.alive
        return self.coords(), self.tets[al], self._levels.view()[al]

    def _holding(self, keys) -> np.ndarray:
        """The living tetrahedra holding any of ``keys`` (sorted unique)."""
        t = np.concatenate([_entries(*self.main, keys), _entries(*self.recent, keys)]) // 6
        hit = np.zeros(self._alive.n, bool)  # a mask, not a sort: the living ones, in order
        hit[t] = True
        return np.flatnonzero(hit & self.alive)

    def bisect(self, split: np.ndarray) -> None:
        """Bisect the edges ``split`` (keys) and every longest edge the conformity closure
        needs (a tetrahedron holding an edge to split is bisected at its own longest edge),
        until no tetrahedron holds an edge to split."""
        pending = np.empty(0, np.int64)
        mids = np.empty(0, np.int64)
        frontier = np.unique(split)
        # the living tetrahedra holding a key of pending, gathered as keys join it: the others
        # holding older keys were bisected, and their children are checked as they are made
        holders = []
        while True:
            while len(frontier):  # closure: the longest edges of the tetrahedra holding new keys
                new = np.setdiff1d(frontier, pending, assume_unique=True)
                if not len(new):
                    break
                c = self.coords()
                a, b = new // EDGE_KEY, new % EDGE_KEY
                ids = self.n + np.arange(len(new))
                self.nodes.append(0.5 * (c[a] + c[b]))
                k = np.concatenate([pending, new])
                o = np.argsort(k)
                pending, mids = k[o], np.concatenate([mids, ids])[o]
                holders.append(self._holding(new))
                frontier = np.unique(self.lkey[holders[-1]])
            cut = np.unique(np.concatenate(holders)) if holders else np.empty(0, np.int64)
            if not len(cut):
                break
            # bisect the tetrahedra cut at their longest edges: two children each, appended
            lk = self.lkey[cut]
            mid = mids[np.searchsorted(pending, lk)]
            t = self.tets[cut]
            a, b = lk // EDGE_KEY, lk % EDGE_KEY
            rows = np.arange(len(t))
            c1, c2 = t.copy(), t.copy()
            ia = np.argmax(t == a[:, None], axis=1)
            ib = np.argmax(t == b[:, None], axis=1)
            c1[rows, ia] = mid  # replacing one end of the bisected edge by its midpoint keeps the sign
            c2[rows, ib] = mid
            children = np.concatenate([c1, c2])
            ck = tet_edges(children)
            cl, cn = _longest(self.coords(), children, ck)
            lv = np.tile(self._levels.a[cut] + 1, 2)
            m = self._tets.n
            self.alive[cut] = False
            self.fresh[cut] = False
            self.count += len(cut)  # one out, two in
            for rows_, add in ((self._tets, children), (self._lkey, cl), (self._llen, cn),
                               (self._levels, lv), (self._fresh, np.ones(len(children), bool)),
                               (self._alive, np.ones(len(children), bool))):
                rows_.append(add)
            flat = ck.ravel()
            o = np.argsort(flat)
            self.recent = _merged(*self.recent, flat[o], 6 * m + o)
            # children still holding a key to split: their longest edges join the closure
            pos = np.clip(np.searchsorted(pending, ck), 0, len(pending) - 1)
            holds = (pending[pos] == ck).any(axis=1)
            holders = [m + np.flatnonzero(holds)]
            frontier = np.unique(cl[holds])
        if 2 * len(self.recent[0]) > len(self.main[0]):  # the dead dropped first: less to merge
            kept = []
            for index in ("main", "recent"):  # each old index let go once filtered: a lower peak
                sf, od = getattr(self, index)
                setattr(self, index, None)
                live = self.alive[od // 6]
                kept.append((sf[live], od[live]))
                del sf, od, live
            self.main = _merged(*kept[0], *kept[1])
            self.recent = (np.empty(0, np.int64), np.empty(0, np.int64))


def refine_bcc(dims, h0: float, origin: np.ndarray, field: SizeField, *, outside=None, max_rounds: int = 64):
    """Bisect the BCC lattice (``dims`` black nodes, cube side ``h0``, black node 0 at
    ``origin``) at longest edges until no tetrahedron's longest edge exceeds the smallest size
    of ``field`` at its vertices and centroid; conforming at every step.

    ``outside(lo, hi)``, optional: (k,) bool, True where the boxes (k, 3) (world) certainly
    hold no point of the domain (an interval test); a tetrahedron whose bounding box grown
    by its longest edge is outside is not refined for its size (only for conformity).

    Returns
    -------
    coords : (n, 3) float64, half-cube units (world = origin + coords * h0 / 2)
    tets : (m, 4) int64, positive
    levels : (m,) int64, the bisections each tetrahedron went through
    """
    coords, tets = bcc_tetrahedra(dims)
    return refine_tets(coords, tets, h0, origin, field, outside=outside, max_rounds=max_rounds)


def refine_tets(coords: np.ndarray, tets: np.ndarray, h0: float, origin: np.ndarray, field: SizeField, *,
                outside=None, tet_size=None, max_rounds: int = 64):
    """:func:`refine_bcc` from a given part of the BCC lattice: ``coords`` (n, 3) in half-cube
    units, ``tets`` (m, 4) positive, a subset of :func:`bcc_tetrahedra`'s (or any mesh whose
    equal edge lengths are exact). A face in one tetrahedron of ``tets`` is a boundary: the
    refinement may split it, so a caller keeping a part of the lattice keeps a margin where
    that does no harm (:mod:`warpmesh.solid.regions` keeps two cubes of the rest).

    ``tet_size(nodes, tets)``, optional: (n, 3) world positions of the nodes and (k, 4) node
    ids -> (k,) the size asked of each of those tetrahedra, in place of ``field``'s smallest at
    their vertices and centroids (``field`` then only names the smallest size: sizes below
    ``field.smallest`` raise ValueError, and a tetrahedron no longer than it is not asked).
    ``tet_size`` may rely on this (:class:`warpmesh.solid.thin._Resolution` does, to test only
    new edges): each tetrahedron is asked once; nodes are only appended; and an edge of a
    tetrahedron asked whose two ends existed at the previous call was an edge of a tetrahedron
    asked before (bisection makes new edges only at new midpoints, and every tetrahedron
    bisected is longer than ``field.smallest``, so was asked when it was made).

    Returns (coords, tets, levels) as :func:`refine_bcc`; the first n nodes are ``coords``.
    """
    mesh = _Bisection(np.asarray(coords, dtype=np.float64), np.asarray(tets, dtype=np.int64))
    unit = 0.5 * float(h0)
    node_size = np.empty(0)  # the size at every node, evaluated once
    floor = field.smallest / unit
    for _ in range(max_rounds):
        idx = np.flatnonzero(mesh.fresh)
        mesh.fresh[:] = False
        coords = mesh.coords()
        pts = coords[mesh.tets[idx]] if tet_size is None or outside is not None else None
        if tet_size is not None:
            # a tetrahedron no longer than the smallest size is never bisected for its size: not asked
            want = np.full(len(idx), floor)
            ask = np.flatnonzero(mesh.llen[idx] > floor * (1 + 1e-9))
            if len(ask):
                want[ask] = np.asarray(tet_size(origin + coords * unit, mesh.tets[idx[ask]]), dtype=np.float64) / unit
                if (want[ask] < floor).any():
                    raise ValueError(f"expected 'tet_size' to give sizes of at least the field's smallest "
                                     f"({field.smallest:g}), got {float(want[ask].min() * unit):g}")
        else:
            if len(node_size) < len(coords):
                node_size = np.concatenate([node_size, field(origin + coords[len(node_size):] * unit)])
            want = np.minimum(node_size[mesh.tets[idx]].min(axis=1), field(origin + pts.mean(axis=1) * unit)) / unit
        marked = mesh.llen[idx] > want * (1 + 1e-9)
        if outside is not None and marked.any():
            grow = mesh.llen[idx[marked]][:, None]
            lo = origin + (pts[marked].min(axis=1) - grow) * unit
            hi = origin + (pts[marked].max(axis=1) + grow) * unit
            marked[np.flatnonzero(marked)[np.asarray(outside(lo, hi), bool)]] = False
        if not marked.any():
            return mesh.result()
        mesh.bisect(mesh.lkey[idx[marked]])
        if mesh.count > MAX_BACKGROUND_TETS:
            raise ValueError(f"the graded background grew past {MAX_BACKGROUND_TETS} tetrahedra; raise 'size' "
                             f"(smallest asked {field.smallest:g})")
    raise ValueError(f"the 'size' field asked for more than {max_rounds} rounds of bisection; raise 'size'")
