"""Exhaustive enumeration samplers of an implicit curve [FG §16.3.1 - §16.3.3].

Both samplers cover the box with a regular grid, evaluate f at every node, and treat every
cell (or Freudenthal triangle) whose corners do not all have the same sign:

* :func:`sample_grid` - marching squares on the grid cells, the 16 patterns of
  :mod:`warpmesh.planar.samplers.marching_squares`; the two ambiguous patterns (diagonal corners of the
  same sign, [FG Fig. 16.8, Exercise 16.1]) are resolved by the asymptotic decider (the
  sign of the bilinear interpolant at its saddle) or by the sign of f at the cell centre.
* :func:`sample_freudenthal` - each cell split by its diagonal (i, j) -> (i+1, j+1) into
  two triangles (Coxeter-Freudenthal); a crossed triangle gives exactly one segment, so no
  ambiguity arises, at the price of a slightly less accurate, more jagged polyline.

Conventions, written once here:

* Sign: a node is inside when f > 0; f == 0 counts as outside (as in all of warpmesh).
  This is the book's "modified" binary search of Figure 16.9: when f vanishes at a node, or
  on a piece of an edge, the root found is the end of the zero piece next to the positive
  end, never the node itself.
* Roots: one point per crossing edge, shared by the two cells of the edge, so the output is
  welded by construction. ``"linear"`` interpolates the node values (eq. 16.12);
  ``"bisection"`` halves the bracket ceil(log2(1 / tolerance)) times, so the root is within
  ``tolerance * edge length / 2`` of a sign change of f; ``"newton"`` runs Newton steps
  along the edge from the linear guess, falling back to the bisection midpoint whenever a
  step leaves the current bracket. Root parameters are kept at least ``EDGE_T_MIN`` (linear)
  or ``tolerance / 4`` of an edge away from its nodes, so segments never have zero length.
* Orientation: every segment has the domain f > 0 on its left.
* Box: the grid spans exactly the box; a curve leaving the box gives open chains whose
  ends lie on the box boundary (on its boundary edges).
* Topology: what the samplers reproduce is the zero set of the grid's interpolant
  (bilinear per cell with the asymptotic decider, linear per triangle otherwise). Features
  thinner than a cell (a gap between two close components, a component that no node sees)
  are lost or kept depending on where the nodes fall; a finer grid resolves them.

Accuracy (h = cell size, kappa = curvature): every output point is a root of the edge
interpolant; segments are chords of the curve across one cell (length <= sqrt(2) h), so the
Hausdorff distance is about kappa h^2 / 4 (the chord sagitta) plus the root error:
``tolerance * h / 2`` for bisection and Newton, O(h^2 |f''| / |grad f|) for linear.

Example
-------
>>> import warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> field = PlanarField(wm.circle(1.0), ((-1.5, -1.5), (1.5, 1.5)))
>>> s = sample_grid(field, resolution=32)
>>> len(s.points) == len(s.segments), s.info["ambiguous"]
(True, 0)
>>> bool(abs(np.linalg.norm(s.points, axis=1) - 1).max() < 1e-3)
True
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from warpmesh.planar.samplers import marching_squares as ms
from warpmesh._conventions import EDGE_T_MIN, INDEX_DTYPE, REAL_DTYPE
from warpmesh._util.budget import check_budget
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.sample import CurveSample

__all__ = ["sample_grid", "sample_freudenthal", "edge_roots", "ROOT_METHODS", "DECIDERS"]

ROOT_METHODS = ("linear", "bisection", "newton")
DECIDERS = ("asymptotic", "center")
_TINY = 1.0e-30

# ------------------------------------------------------------------ validation


def _check_common(field, resolution, tolerance, root) -> tuple[int, int, float]:
    if not isinstance(field, PlanarField):
        raise TypeError(f"expected 'field' a warpmesh.frep.planar_field.PlanarField, got {type(field).__name__}; "
                        "build one with PlanarField(shape, bounds)")
    if root not in ROOT_METHODS:
        raise ValueError(f"Unknown 'root' {root!r}. Pick one of {list(ROOT_METHODS)}")
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.integer, np.floating)) \
            or not 0.0 < float(tolerance) < 1.0:
        raise ValueError(f"expected 'tolerance' a number in (0, 1) (a fraction of the cell size), got {tolerance!r}")
    nx, ny = _grid_shape(field.bounds, resolution)
    # per node: its point, value, sign and index arrays (about 64 bytes with temporaries)
    check_budget(64.0 * (nx + 1) * (ny + 1), f"a {nx} x {ny}-cell grid (resolution={resolution!r})",
                 "lower 'resolution'")
    return nx, ny, float(tolerance)


def _is_count(v) -> bool:
    return not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, np.integer)) and v >= 1


def _grid_shape(bounds: np.ndarray, resolution) -> tuple[int, int]:
    """(nx, ny): an int gives that many cells along the longer side and ceil(ext / h) along
    the other (cells as square as the box allows, never larger than h); a pair is taken as is."""
    if isinstance(resolution, (tuple, list)) and len(resolution) == 2 and all(map(_is_count, resolution)):
        return int(resolution[0]), int(resolution[1])
    if not _is_count(resolution):
        raise ValueError(f"expected 'resolution' a positive integer or a pair (nx, ny) of them, got {resolution!r}")
    ext = bounds[1] - bounds[0]
    h = ext.max() / int(resolution)
    n = np.maximum(1, np.ceil(ext / h * (1.0 - 1e-12))).astype(int)
    return int(n[0]), int(n[1])


# ------------------------------------------------------------------ roots on edges


def edge_roots(field: PlanarField, a: np.ndarray, b: np.ndarray, fa: np.ndarray, fb: np.ndarray,
                root: str, tolerance: float) -> tuple[np.ndarray, int, int]:
    """Roots on crossing edges (m, 2) from node a to node b; returns (points, evaluations,
    edges left unconverged by Newton). f > 0 at exactly one end of every edge."""
    swap = fa > 0  # make a the outside end (f <= 0) and b the inside end (f > 0)
    a, b = np.where(swap[:, None], b, a), np.where(swap[:, None], a, b)
    fa, fb = np.where(swap, fb, fa), np.where(swap, fa, fb)
    d = b - a
    evaluations, unconverged = 0, 0
    if root == "linear":
        t = fa / (fa - fb)  # eq. 16.12, fa <= 0 < fb
        t_min = EDGE_T_MIN
    elif root == "bisection":
        lo, hi = np.zeros(len(a)), np.ones(len(a))
        for _ in range(math.ceil(math.log2(1.0 / tolerance))):  # loop over halvings, all edges at once
            mid = 0.5 * (lo + hi)
            inside = field.values(a + mid[:, None] * d) > 0
            evaluations += len(a)
            lo, hi = np.where(inside, lo, mid), np.where(inside, mid, hi)
        t = 0.5 * (lo + hi)
        t_min = min(EDGE_T_MIN, 0.25 * tolerance)
    else:
        t, evaluations, unconverged = _newton_on_edges(field, a, d, fa, fb, tolerance)
        t_min = min(EDGE_T_MIN, 0.25 * tolerance)
    t = np.clip(t, t_min, 1.0 - t_min)
    return a + t[:, None] * d, evaluations, unconverged


def _newton_on_edges(field, a, d, fa, fb, tolerance) -> tuple[np.ndarray, int, int]:
    """Safeguarded Newton on g(t) = f(a + t d), bracket [lo, hi] with g(lo) <= 0 < g(hi)."""
    m = len(a)
    lo, hi = np.zeros(m), np.ones(m)
    t = np.clip(fa / (fa - fb), 0.25 * tolerance, 1.0 - 0.25 * tolerance)  # linear start
    active = np.arange(m)
    evaluations = 0
    for _ in range(2 * math.ceil(math.log2(1.0 / tolerance)) + 8):  # loop over iterations
        if len(active) == 0:
            break
        ta = t[active]
        g, grad = field.value_gradient(a[active] + ta[:, None] * d[active])
        evaluations += len(active)
        dg = np.einsum("ij,ij->i", grad, d[active])
        inside = g > 0
        lo[active] = np.where(inside, lo[active], ta)
        hi[active] = np.where(inside, ta, hi[active])
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(np.abs(dg) > _TINY, g / dg, np.nan)
        new = ta - step
        bad = ~np.isfinite(new) | (new <= lo[active]) | (new >= hi[active])
        new = np.where(bad, 0.5 * (lo[active] + hi[active]), new)
        t[active] = new
        done = (np.abs(new - ta) <= 0.5 * tolerance) | (hi[active] - lo[active] <= tolerance)
        active = active[~done]
    return t, evaluations, len(active)


# ------------------------------------------------------------------ grid edges


class _Edges:
    """Global numbering of the grid edges: horizontal (i, j)-(i+1, j), then vertical
    (i, j)-(i, j+1), then diagonal (i, j)-(i+1, j+1)."""

    def __init__(self, nx: int, ny: int):
        self.nx, self.ny = nx, ny
        self.n_h, self.n_v = nx * (ny + 1), (nx + 1) * ny

    def h(self, i, j):
        return i * (self.ny + 1) + j

    def v(self, i, j):
        return self.n_h + i * self.ny + j

    def d(self, i, j):
        return self.n_h + self.n_v + i * self.ny + j


def _crossing_edges(edges: _Edges, inside: np.ndarray, diagonals: bool):
    """Global ids (m,) and node index pairs (m, 2, 2) of the edges whose ends differ in sign."""
    ids, ends = [], []
    families = [((1, 0), edges.h), ((0, 1), edges.v)] + ([((1, 1), edges.d)] if diagonals else [])
    for (di, dj), number in families:  # loop over the 2 or 3 edge families
        n0, n1 = inside.shape[0] - di, inside.shape[1] - dj
        i, j = np.nonzero(inside[:n0, :n1] != inside[di:, dj:])
        ids.append(number(i, j))
        ends.append(np.stack([np.column_stack([i, j]), np.column_stack([i + di, j + dj])], axis=1))
    return np.concatenate(ids), np.concatenate(ends)


def _sample_points(field, xs, ys, f, inside, edges, diagonals, root, tolerance):
    """One root per crossing edge: (points, lookup global edge id -> point index, evals, unconverged)."""
    ids, ends = _crossing_edges(edges, inside, diagonals)
    nodes = np.stack([xs[ends[..., 0]], ys[ends[..., 1]]], axis=-1)  # (m, 2 ends, 2)
    values = f[ends[..., 0], ends[..., 1]]
    points, evals, unconverged = edge_roots(field, nodes[:, 0], nodes[:, 1], values[:, 0], values[:, 1],
                                             root, tolerance)
    lookup = np.full(edges.n_h + edges.n_v + (edges.nx * edges.ny if diagonals else 0), -1, INDEX_DTYPE)
    lookup[ids] = np.arange(len(ids))
    return points, lookup, evals, unconverged


def _emit(table: np.ndarray, count: np.ndarray, configs: np.ndarray, cell_edges: np.ndarray,
          lookup: np.ndarray) -> np.ndarray:
    """Directed segments (point indices) of cells with ``configs`` (k,), local edge -> global
    edge ids ``cell_edges`` (k, n), per-cell table rows ``table`` (k, slots, 2)."""
    slots = table.shape[1]
    keep = (np.arange(slots)[None, :] < count[configs][:, None]).ravel()
    local = table.reshape(-1, 2)[keep].astype(INDEX_DTYPE)
    cell = np.repeat(np.arange(len(configs)), slots)[keep]
    segs = lookup[cell_edges[cell[:, None], local]]
    if np.any(segs < 0):  # pragma: no cover - a table entry naming a non-crossing edge
        raise AssertionError("a segment ends on an edge without a sign change")
    return segs


def _empty(info: dict, inside: np.ndarray) -> CurveSample:
    side = "inside (f > 0)" if inside.all() else "outside (f <= 0)"
    info.update(empty=True, cells=0, ambiguous=0,
                message=f"no sign change of f on the grid nodes: every node is {side}; "
                        "the curve misses the box or is finer than the grid")
    return CurveSample(np.zeros((0, 2), REAL_DTYPE), np.zeros((0, 2), INDEX_DTYPE), info, np.zeros((0, 4)))


# ------------------------------------------------------------------ public samplers


def sample_grid(field: PlanarField, *, resolution: int | tuple = 64, tolerance: float = 1e-3,
                root: Literal["linear", "bisection", "newton"] = "bisection",
                decider: Literal["asymptotic", "center"] = "asymptotic") -> CurveSample:
    """Sample f = 0 by marching squares on a regular grid [FG §16.3.1, exhaustive enumeration].

    Parameters
    ----------
    field : PlanarField
        The function and the box.
    resolution : int or (int, int)
        Cells along the longer side of the box (the other side gets ceil(ext / h) cells, so
        cells are square up to rounding), or ``(nx, ny)``.
    tolerance : float
        Root accuracy of ``"bisection"`` / ``"newton"`` as a fraction of the edge length, in (0, 1).
    root : {'linear', 'bisection', 'newton'}
        Root finder on crossing edges (module docstring).
    decider : {'asymptotic', 'center'}
        How the ambiguous cells (diagonal corners of the same sign) are connected: the sign of
        the bilinear interpolant at its saddle, or the sign of f evaluated at the cell centre
        (one more evaluation per ambiguous cell; wrong when the saddle is off-centre).

    Returns
    -------
    CurveSample
        Points (one per crossing edge), directed segments (f > 0 on the left), ``cells`` the
        crossed cells (k, 4) as (x0, y0, x1, y1), and ``info``: "cells" (crossed cells),
        "ambiguous", "joined" (ambiguous cells whose inside corners were connected),
        "evaluations" (points where f was evaluated), "resolution" (nx, ny), "cell_size",
        "root", "decider", "unconverged" (Newton), "empty" (+ "message" when no crossing).

    Raises
    ------
    TypeError
        ``field`` is not a PlanarField.
    ValueError
        ``resolution``, ``tolerance``, ``root`` or ``decider`` is not valid.

    Examples
    --------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> field = PlanarField(wm.cassini(1.0, 0.95), ((-1.6, -0.7), (1.6, 0.7)))
    >>> s = sample_grid(field, resolution=64)
    >>> from warpmesh.planar.polyline import components
    >>> components(s.segments, len(s.points))[0], s.info["resolution"]
    (2, (64, 28))
    """
    nx, ny, tol = _check_common(field, resolution, tolerance, root)
    if decider not in DECIDERS:
        raise ValueError(f"Unknown 'decider' {decider!r}. Pick one of {list(DECIDERS)}")
    xs, ys, f = field.grid(nx, ny)
    inside = f > 0
    info = {"resolution": (nx, ny), "cell_size": (float(xs[1] - xs[0]), float(ys[1] - ys[0])),
            "root": root, "decider": decider, "tolerance": tol, "evaluations": f.size, "unconverged": 0,
            "empty": False}
    config = ms.square_configs(inside)
    ci, cj = np.nonzero((config != 0) & (config != 15))
    if len(ci) == 0:
        return _empty(info, inside)
    config = config[ci, cj].astype(INDEX_DTYPE)

    # ambiguous cells: choose the variant
    variant = np.full(len(ci), ms.SEPARATED, INDEX_DTYPE)
    amb = np.flatnonzero(np.isin(config, ms.AMBIGUOUS))
    if len(amb):
        i, j = ci[amb], cj[amb]
        if decider == "asymptotic":
            joined = ms.asymptotic_decider(f[i, j], f[i + 1, j], f[i + 1, j + 1], f[i, j + 1])
        else:
            centre = np.column_stack([0.5 * (xs[i] + xs[i + 1]), 0.5 * (ys[j] + ys[j + 1])])
            joined = field.values(centre) > 0
            info["evaluations"] += len(amb)
        variant[amb] = np.where(joined, ms.JOINED, ms.SEPARATED)

    edges = _Edges(nx, ny)
    points, lookup, evals, unconverged = _sample_points(field, xs, ys, f, inside, edges, False, root, tol)
    cell_edges = np.column_stack([edges.h(ci, cj), edges.v(ci + 1, cj), edges.h(ci, cj + 1), edges.v(ci, cj)])
    segments = _emit(ms.SEGMENT_TABLE[variant, config], ms.SEGMENT_COUNT, config, cell_edges, lookup)
    info.update(cells=len(ci), ambiguous=len(amb), joined=int(np.count_nonzero(variant == ms.JOINED)),
                unconverged=unconverged)
    info["evaluations"] += evals
    boxes = np.column_stack([xs[ci], ys[cj], xs[ci + 1], ys[cj + 1]])
    return CurveSample(points, segments, info, boxes)


def sample_freudenthal(field: PlanarField, *, resolution: int | tuple = 64, tolerance: float = 1e-3,
                       root: Literal["linear", "bisection", "newton"] = "bisection") -> CurveSample:
    """Sample f = 0 on the Coxeter-Freudenthal triangulation of a regular grid [FG §16.3.1].

    Every grid cell is split by its diagonal from node (i, j) to (i+1, j+1) into two
    triangles; f is linear on each for the purpose of the topology, so a crossed triangle
    holds exactly one segment between the roots on its two crossing edges (diagonals
    included). No pattern is ambiguous: the diagonal decides.

    Parameters
    ----------
    field, resolution, tolerance, root
        As in :func:`sample_grid`.

    Returns
    -------
    CurveSample
        As :func:`sample_grid`; ``info["cells"]`` counts crossed triangles, ``cells`` holds
        the bounding boxes of the grid cells they belong to (one row per crossed triangle).

    Raises
    ------
    TypeError, ValueError
        As :func:`sample_grid`.

    Examples
    --------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> s = sample_freudenthal(PlanarField(wm.circle(1.0), ((-1.5, -1.5), (1.5, 1.5))), resolution=32)
    >>> s.info["cells"] == len(s.segments), s.info["ambiguous"]
    (True, 0)
    """
    nx, ny, tol = _check_common(field, resolution, tolerance, root)
    xs, ys, f = field.grid(nx, ny)
    inside = f > 0
    info = {"resolution": (nx, ny), "cell_size": (float(xs[1] - xs[0]), float(ys[1] - ys[0])),
            "root": root, "decider": None, "tolerance": tol, "evaluations": f.size, "unconverged": 0,
            "empty": False, "ambiguous": 0}
    lower, upper = ms.triangle_configs(inside)
    crossed = [np.nonzero((c != 0) & (c != 7)) for c in (lower, upper)]
    if sum(len(c[0]) for c in crossed) == 0:
        return _empty(info, inside)
    edges = _Edges(nx, ny)
    points, lookup, evals, unconverged = _sample_points(field, xs, ys, f, inside, edges, True, root, tol)
    segs, boxes = [], []
    for (i, j), configs, local in zip(crossed, (lower, upper), ("lower", "upper")):  # the 2 triangles
        config = configs[i, j].astype(INDEX_DTYPE)
        if local == "lower":  # corners (i,j), (i+1,j), (i+1,j+1)
            cell_edges = np.column_stack([edges.h(i, j), edges.v(i + 1, j), edges.d(i, j)])
        else:  # corners (i,j), (i+1,j+1), (i,j+1)
            cell_edges = np.column_stack([edges.d(i, j), edges.h(i, j + 1), edges.v(i, j)])
        table = ms.TRIANGLE_SEGMENT_TABLE[config][:, None, :]
        segs.append(_emit(table, ms.TRIANGLE_SEGMENT_COUNT, config, cell_edges, lookup))
        boxes.append(np.column_stack([xs[i], ys[j], xs[i + 1], ys[j + 1]]))
    segments = np.concatenate(segs)
    info.update(cells=len(segments), unconverged=unconverged)
    info["evaluations"] += evals
    return CurveSample(points, segments, info, np.concatenate(boxes))
