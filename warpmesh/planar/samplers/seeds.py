"""Seed points on every connected component of an implicit curve, located automatically.

Continuation methods [FG §16.3.1] need "a starting point M_0 in each connected
component of Γ". :func:`find_seeds` finds them with an interval-arithmetic quadtree:

1. the box is tiled by a coarse grid of ``resolution`` cells along its longer side;
2. at every level, boxes whose interval enclosure of f (:meth:`PlanarField.intervals`)
   excludes 0 hold no curve and are dropped; f is sampled at the corners of the others;
3. a box with a sign change at its corners is *resolved*: the roots on its crossing
   edges (bisection, then a capped Newton projection, Remark 16.1) are seeds;
4. a box that may hold curve (0 in its interval) with no sign change at its corners is
   split in four, down to ``min_size``, so that a small closed component lying inside one
   coarse cell (an island far from the others) is still found.

Every level is processed as a whole with numpy (a loop over levels only).

Each seed carries a *cluster* label: the 8-connected groups of coarse cells whose interval
contains 0. A connected component of the curve only crosses such cells, so seeds of
different clusters lie on different components; continuation samplers trace one seed per
cluster at once.

Example
-------
>>> import warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> shape = wm.circle(1.0) | wm.circle(0.03, (1.5, 1.5))
>>> seeds, info = find_seeds(PlanarField(shape, ((-2, -2), (2, 2))))
>>> int(info["clusters"]), bool(info["levels"] > 1)
(2, True)
"""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.frep.planar_field import PlanarField

__all__ = ["find_seeds", "grid_cells", "check_field", "check_positive", "check_count"]

#: bisection steps on a crossing edge before the Newton polish (edge / 2^12)
_BISECTIONS = 12
#: guard against run-away subdivision (boxes held at one level)
_MAX_BOXES = 4_000_000


# -- argument checks shared by the continuation samplers ------------------------------

def check_field(field, name: str = "field") -> PlanarField:
    if not isinstance(field, PlanarField):
        raise TypeError(f"expected '{name}' a warpmesh.frep.planar_field.PlanarField (PlanarField(shape, bounds)), "
                        f"got {type(field).__name__}")
    return field


def check_positive(value, name: str, *, allow_none: bool = False):
    if value is None and allow_none:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"expected '{name}' a positive number, got {value!r}") from None
    if isinstance(value, bool) or not np.isfinite(v) or v <= 0:
        raise ValueError(f"expected '{name}' a positive finite number, got {value!r}")
    return v


def check_count(value, name: str, *, allow_none: bool = False, minimum: int = 1):
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"expected '{name}' an integer >= {minimum}, got {value!r}")
    return int(value)


# -- quadtree ---------------------------------------------------------------------------

def grid_cells(bounds: np.ndarray, resolution: int) -> tuple[int, int, np.ndarray]:
    """Cells of a grid tiling the box, as square as possible, ``resolution`` along the
    longer side: (nx, ny, cell size (2,))."""
    ext = bounds[1] - bounds[0]
    step = ext.max() / resolution
    n = np.maximum(1, np.ceil(ext / step - 1e-9)).astype(int)
    return int(n[0]), int(n[1]), ext / n


def check_seeds(seeds, field: PlanarField) -> np.ndarray:
    try:
        s = np.asarray(seeds, dtype=REAL_DTYPE)
    except (TypeError, ValueError):
        raise ValueError(f"expected 'seeds' an (k, 2) array of points, got {seeds!r}") from None
    if s.ndim != 2 or s.shape[1] != 2 or not np.all(np.isfinite(s)):
        raise ValueError(f"expected 'seeds' an (k, 2) array of finite points, got shape {s.shape}")
    return s


def inside_box(p: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    return np.all((p >= bounds[0]) & (p <= bounds[1]), axis=1)


def _clusters(ij: np.ndarray) -> np.ndarray:
    """Labels of the 8-connected groups of the (k, 2) integer cells ``ij``."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    k = len(ij)
    if k == 0:
        return np.zeros(0, INDEX_DTYPE)
    span = int(ij[:, 1].max()) + 3
    key = (ij[:, 0] + 1) * span + (ij[:, 1] + 1)
    order = np.argsort(key)
    skey = key[order]
    rows, cols = [], []
    for di, dj in ((1, -1), (1, 0), (1, 1), (0, 1)):  # half of the 8 neighbours, the graph is undirected
        nb = key + di * span + dj
        pos = np.clip(np.searchsorted(skey, nb), 0, k - 1)
        hit = skey[pos] == nb
        rows.append(np.flatnonzero(hit))
        cols.append(order[pos[hit]])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(k, k))
    return connected_components(graph, directed=False)[1].astype(INDEX_DTYPE)


def _edge_roots(field: PlanarField, a: np.ndarray, b: np.ndarray, fa: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """Roots on segments [a, b] whose ends have opposite signs: bisection, then Newton
    steps capped at ``cap`` (the edge length); a polish that leaves the edge's
    neighbourhood or the box is discarded for the bisection root."""
    inside_a = fa > 0
    lo, hi = a.copy(), b.copy()  # lo keeps a's side
    for _ in range(_BISECTIONS):  # loop over bisection steps, every edge at once
        mid = 0.5 * (lo + hi)
        same = (field.values(mid) > 0) == inside_a
        lo = np.where(same[:, None], mid, lo)
        hi = np.where(same[:, None], hi, mid)
    root = 0.5 * (lo + hi)
    polished = field.project(root, max_step=cap)
    (x0, y0), (x1, y1) = field.bounds
    ok = (np.linalg.norm(polished - root, axis=1) <= cap) & np.all(np.isfinite(polished), axis=1)
    ok &= (polished[:, 0] >= x0) & (polished[:, 0] <= x1) & (polished[:, 1] >= y0) & (polished[:, 1] <= y1)
    return np.where(ok[:, None], polished, root)


def find_seeds(field: PlanarField, *, resolution: int = 32, min_size: float | None = None
               ) -> tuple[np.ndarray, dict]:
    """Points on every connected component of f = 0 inside the box (interval quadtree).

    Parameters
    ----------
    field : PlanarField
        The curve's function and box.
    resolution : int
        Coarse cells along the longer side of the box. Every coarse cell with a sign change
        at its corners gives seeds, so a component gets about (its length / coarse cell)
        seeds.
    min_size : float, optional
        Smallest box of the subdivision (default: the longer side / 1024). A closed
        component that contains a grid node of this spacing is found.

    Returns
    -------
    seeds : (k, 2) float64
        Points on the curve (Newton-polished roots on crossing box edges), grouped by
        cluster.
    info : dict
        ``"cluster"`` (k,) labels (seeds of different clusters lie on different
        components), ``"clusters"``, ``"levels"``, ``"boxes"`` (kept boxes per level),
        ``"interval_evaluations"``, ``"evaluations"`` (point values), ``"unresolved"``
        (boxes of ``min_size`` that may hold curve but show no sign change: a component
        smaller than ``min_size``, a double root, or a curve through a box corner),
        ``"empty_clusters"`` (groups of kept coarse cells where no sign change was found),
        ``"min_size"``.

    Raises
    ------
    TypeError
        ``field`` is not a PlanarField.
    ValueError
        ``resolution`` is not a positive integer, or ``min_size`` not a positive number.

    Notes
    -----
    Boxes with a sign change at their corners are not split further: a second component
    lying wholly inside a coarse cell that the curve already crosses is missed (raise
    ``resolution``). Interval arithmetic is rigorous, so a component is never lost in a
    dropped box; the corners of the ``min_size`` boxes set the smallest island found.

    Examples
    --------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> seeds, info = find_seeds(PlanarField(wm.cassini(1.0, 0.95), ((-2, -1), (2, 1))))
    >>> int(info["clusters"]), bool(np.all(np.sign(seeds[:, 0]) != 0))
    (2, True)
    """
    field = check_field(field)
    resolution = check_count(resolution, "resolution")
    bounds = field.bounds
    ext = bounds[1] - bounds[0]
    min_size = ext.max() / 1024 if min_size is None else check_positive(min_size, "min_size")
    nx, ny, cell = grid_cells(bounds, resolution)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    ij = np.column_stack([i.ravel(), j.ravel()]).astype(INDEX_DTYPE)  # box index at the current level
    root = ij.copy()  # its coarse ancestor
    info = {"boxes": [], "interval_evaluations": 0, "evaluations": 0, "unresolved": 0, "min_size": float(min_size)}
    found_pts, found_root = [], []
    coarse_kept = np.zeros((0, 2), INDEX_DTYPE)
    level = 0
    corner = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], INDEX_DTYPE)  # counter-clockwise
    while len(ij):  # loop over quadtree levels, every box of the level at once
        size = cell / 2**level
        lo = bounds[0] + ij * size
        iv = field.intervals(lo, lo + size)
        info["interval_evaluations"] += len(ij)
        keep = (iv[:, 0] <= 0) & (iv[:, 1] >= 0)
        ij, root = ij[keep], root[keep]
        info["boxes"].append(int(len(ij)))
        if level == 0:
            coarse_kept = ij.copy()
        if len(ij) == 0:
            break
        # corner values, each node once
        nodes = (ij[:, None, :] + corner[None]).reshape(-1, 2)
        uniq, inv = np.unique(nodes, axis=0, return_inverse=True)
        fn = field.values(bounds[0] + uniq * size)
        info["evaluations"] += len(uniq)
        fc = fn[inv.ravel()].reshape(-1, 4)
        inside = fc > 0
        crossed = inside.any(axis=1) & ~inside.all(axis=1)
        # roots on the crossing edges of resolved boxes (edge k joins corner k to k + 1)
        b_idx, e_idx = np.nonzero((inside != np.roll(inside, -1, axis=1)) & crossed[:, None])
        if len(b_idx):
            ca, cb = corner[e_idx], corner[(e_idx + 1) % 4]
            na, nb = ij[b_idx] + ca, ij[b_idx] + cb
            stride = int(ij[:, 1].max()) + 2
            ka, kb = na[:, 0] * stride + na[:, 1], nb[:, 0] * stride + nb[:, 1]
            key = np.column_stack([np.minimum(ka, kb), np.maximum(ka, kb)])
            _, first = np.unique(key, axis=0, return_index=True)  # an edge shared by two boxes once
            b_idx, na, nb = b_idx[first], na[first], nb[first]
            a, b = bounds[0] + na * size, bounds[0] + nb * size
            fa = fc[b_idx, e_idx[first]]
            cap = np.full(len(a), float(np.linalg.norm(size)))
            found_pts.append(_edge_roots(field, a, b, fa, cap))
            found_root.append(root[b_idx])
            info["evaluations"] += len(a) * (_BISECTIONS + 2)
        # boxes that may hold a closed component with no sign change at their corners
        todo = ~crossed
        if size.max() <= min_size:
            info["unresolved"] += int(np.count_nonzero(todo))
            break
        ij, root = ij[todo], root[todo]
        if len(ij) * 4 > _MAX_BOXES:
            info["unresolved"] += int(len(ij))
            break
        ij = (2 * ij[:, None, :] + corner[None]).reshape(-1, 2)
        root = np.repeat(root, 4, axis=0)
        level += 1
    info["levels"] = len(info["boxes"])
    labels = _clusters(coarse_kept)
    info["clusters"] = int(labels.max()) + 1 if len(labels) else 0
    if not found_pts:
        info["cluster"] = np.zeros(0, INDEX_DTYPE)
        info["clusters"] = 0
        return np.zeros((0, 2), REAL_DTYPE), info
    pts, roots = np.concatenate(found_pts), np.concatenate(found_root)
    # cluster of each seed: the label of its coarse ancestor among the kept coarse cells
    span = ny + 1
    ckey = coarse_kept[:, 0] * span + coarse_kept[:, 1]
    order = np.argsort(ckey)
    pos = order[np.searchsorted(ckey[order], roots[:, 0] * span + roots[:, 1])]
    lab = labels[pos]
    used, lab = np.unique(lab, return_inverse=True)  # clusters with seeds, renumbered
    lab = lab.ravel().astype(INDEX_DTYPE)
    info["clusters"] = int(len(used))
    info["empty_clusters"] = int(labels.max()) + 1 - len(used)  # kept coarse groups without a sign change
    srt = np.argsort(lab, kind="stable")
    info["cluster"] = lab[srt]
    return pts[srt], info
