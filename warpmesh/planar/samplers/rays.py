"""The naive ray-casting sampler of an implicit curve [FG §16.3.1, Fig 16.2].

The box is crossed by a beam of ``n_rays`` parallel lines at the centres of ``n_rays``
equal strips (no ray runs along the box boundary). On each line the 1D function is
sampled at ``samples_per_ray + 1`` evenly spaced points; every sign change (inside means
f > 0) brackets a root, refined by bisection to ``tolerance`` times the sample spacing
and a Newton polish, vectorised over all rays at once.

**Joining crossings, one family of rays** (``direction="x"``: rays along x, i.e. the
lines y = y_i; ``"y"``: rays along y). Along a ray the crossings cut it into runs where
f > 0 (a run open at the box side ends at a virtual crossing). In the strip between two
consecutive rays, runs of the two rays whose projections overlap are taken to belong to
one piece of the domain (the runs' overlap graph, computed as the union of their
intervals), and each group gives segments:

- runs on both rays: the leftmost run starts of the two rays are joined, so are the
  rightmost run ends (in order, where counts and sign patterns match: two circles
  crossing both rays give the in-order pairing); between two consecutive runs of one ray
  in the group, the gap's ends are joined on that ray (a turning point of a hole or dent
  between the rays);
- a run alone (no overlap across the strip): its two ends are joined on its ray (a
  turning point of the domain between the rays: a cap).

The outermost rays are capped as if an empty ray lay beyond them, so closed curves
inside the box come out closed; segments touching a virtual crossing are dropped (the
polyline stays open near the box side there). Caps lie on the rays: the part of the curve
between a ray and its turning point is cut flat.

**Both families** (``direction="both"``): rays along x and along y make a grid whose
corners are sample points of both families (so the signs agree); in each grid cell the
crossings on its four ray pieces are joined around its boundary like a quadtree leaf
(:func:`warpmesh.planar.samplers.quadtree.pair_around_cells`; with more than 2 crossings the
positive corners are connected through the cell when f > 0 at its centre). The margins
outside the outermost rays are not covered.

**Failure modes** ([FG §16.3.1]: no a-priori criterion fixes the rays): a component lying
between two rays is missed; a part crossing a ray over less than a sample spacing (near
tangency) is missed; a component crossing a single ray comes out as a flat loop of two
opposite segments on that ray; turning points are cut flat, so horizontal and vertical
rays sample the same curve differently (an ellipse's tips across vertical rays are capped
up to a ray spacing off) and may even join components that nearly touch (the overlap rule
connects runs across a strip). The sampler cannot know what it missed; the tests compare
with the exact curve.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.frep.planar_field import PlanarField
>>> s = sample_rays(PlanarField(wm.circle(1.0), ((-1.2, -1.2), (1.2, 1.2))), n_rays=32)
>>> s.info["components"], bool(np.allclose(np.linalg.norm(s.points, axis=1), 1.0, atol=1e-5))
(1, True)
"""

from __future__ import annotations

import time
from typing import Literal

import numpy as np

from warpmesh._conventions import INDEX_DTYPE, REAL_DTYPE
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.quadtree import edge_roots, pair_around_cells
from warpmesh.planar.samplers.sample import CurveSample
from warpmesh.planar.polyline import components

__all__ = ["sample_rays", "ray_crossings"]

DIRECTIONS = ("x", "y", "both")


def _check_args(field, n_rays, direction, tolerance, samples_per_ray):
    if not isinstance(field, PlanarField):
        raise TypeError(f"expected 'field' a PlanarField, got {type(field).__name__}")
    if direction not in DIRECTIONS:
        raise ValueError(f"Unknown 'direction' {direction!r}. Pick one of {list(DIRECTIONS)}")
    for name, v, low in (("n_rays", n_rays, 1), ("samples_per_ray", samples_per_ray, 2)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
            raise ValueError(f"expected '{name}' an integer >= {low}, got {v!r}")
    if direction == "both" and n_rays < 2:
        raise ValueError(f"expected 'n_rays' >= 2 with direction='both' (cells between rays), got {n_rays}")
    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 0.5):
        raise ValueError(f"expected 'tolerance' a number in (0, 0.5), got {tolerance!r}")


def _ray_positions(field, axis, n_rays):
    """Positions across the rays (the other coordinate) of a family of rays along ``axis``."""
    lo, hi = field.bounds[0, 1 - axis], field.bounds[1, 1 - axis]
    return lo + (np.arange(n_rays) + 0.5) * (hi - lo) / n_rays


def ray_crossings(field: PlanarField, axis: int, n_rays: int, samples_per_ray: int, tolerance: float,
                  extra=None, counter: dict | None = None):
    """Roots of f on a family of rays along ``axis`` (0: x, 1: y).

    Returns ``r`` (n_rays,) ray positions, ``ray`` (k,) int, ``s`` (k,) root coordinate
    along the ray, ``up`` (k,) bool (f goes from <= 0 to > 0 as s grows), ``points`` (k, 2),
    and ``ends`` (n_rays, 2) bool: f > 0 at the first and last sample of each ray.
    Rays are sampled at ``samples_per_ray + 1`` even positions plus the sorted ``extra``
    ones; crossings come out ordered by ray, then s.
    """
    r = _ray_positions(field, axis, n_rays)
    s = np.linspace(field.bounds[0, axis], field.bounds[1, axis], samples_per_ray + 1)
    if extra is not None:
        s = np.unique(np.concatenate([s, extra]))
    p = np.empty((n_rays, len(s), 2))
    p[..., axis] = s[None, :]
    p[..., 1 - axis] = r[:, None]
    f = field.values(p.reshape(-1, 2)).reshape(n_rays, len(s))
    if counter is not None:
        counter["evaluations"] = counter.get("evaluations", 0) + f.size
    inside = f > 0
    ray, k = np.nonzero(inside[:, 1:] != inside[:, :-1])
    a, b = p[ray, k], p[ray, k + 1]
    # bisection to tolerance x the sample spacing (the brackets are one spacing long)
    pts = edge_roots(field, a, b, f[ray, k], f[ray, k + 1], rel_tol=tolerance, counter=counter)
    return r, ray, pts[:, axis], ~inside[ray, k], pts, inside[:, [0, -1]]


def _runs(ray, s, ends, span):
    """Runs where f > 0 along each ray: (ray, s_lo, s_hi, point_lo, point_hi); a run open at
    a ray end has point -1 there."""
    npts = len(ray)
    r_start = np.flatnonzero(ends[:, 0])
    r_end = np.flatnonzero(ends[:, 1])
    b_ray = np.concatenate([ray, r_start, r_end])
    b_s = np.concatenate([s, np.full(len(r_start), span[0] - 1.0), np.full(len(r_end), span[1] + 1.0)])
    b_pt = np.concatenate([np.arange(npts), np.full(len(r_start) + len(r_end), -1)])
    order = np.lexsort((b_s, b_ray))
    b_ray, b_s, b_pt = b_ray[order], b_s[order], b_pt[order]
    # each ray holds an even number of boundaries, alternately opening and closing a run
    return b_ray[0::2], b_s[0::2], b_s[1::2], b_pt[0::2], b_pt[1::2]


def _join_strips(n_rays, runs, span):
    """Directed segments (in the rays' frame: s along, r across, r growing with the ray
    index) joining the runs of consecutive rays strip by strip (see the module notes)."""
    ray, s_lo, s_hi, p_lo, p_hi = runs
    if len(ray) == 0:
        return np.zeros((0, 2), INDEX_DTYPE)
    # each run appears as the lower side of strip `ray` and the upper side of strip `ray - 1`
    strip = np.concatenate([ray, ray - 1])
    upper = np.concatenate([np.zeros(len(ray), bool), np.ones(len(ray), bool)])
    lo, hi = np.tile(s_lo, 2), np.tile(s_hi, 2)
    plo, phi = np.tile(p_lo, 2), np.tile(p_hi, 2)
    length = (span[1] - span[0]) + 4.0
    key_lo, key_hi = (strip + 1) * length + lo, (strip + 1) * length + hi
    order = np.argsort(key_lo, kind="stable")
    strip, upper, lo, hi, plo, phi = strip[order], upper[order], lo[order], hi[order], plo[order], phi[order]
    key_lo, key_hi = key_lo[order], key_hi[order]
    reach = np.maximum.accumulate(key_hi)
    new = np.r_[True, key_lo[1:] > reach[:-1]]
    comp = np.cumsum(new) - 1
    size = np.bincount(comp)
    alone = size[comp] == 1
    segs = [np.column_stack([phi[alone & ~upper], plo[alone & ~upper]]),  # lower cap: domain below
            np.column_stack([plo[alone & upper], phi[alone & upper]])]  # upper cap: domain above
    # groups of several runs: order by (component, side, s)
    g = np.flatnonzero(~alone)
    g = g[np.lexsort((lo[g], upper[g], comp[g]))]
    key = comp[g] * 2 + upper[g]
    first = np.r_[True, key[1:] != key[:-1]]
    last = np.r_[key[1:] != key[:-1], True]
    f_low, f_up = g[first & ~upper[g]], g[first & upper[g]]  # one per component, same order
    l_low, l_up = g[last & ~upper[g]], g[last & upper[g]]
    segs.append(np.column_stack([plo[f_up], plo[f_low]]))  # leftmost starts: going down
    segs.append(np.column_stack([phi[l_low], phi[l_up]]))  # rightmost ends: going up
    nxt = ~last[:-1]  # consecutive runs of one side of one component
    a, b = g[:-1][nxt], g[1:][nxt]
    low = ~upper[a]
    segs.append(np.column_stack([phi[a[low]], plo[b[low]]]))  # gap on the lower ray: domain above
    segs.append(np.column_stack([plo[b[~low]], phi[a[~low]]]))  # gap on the upper ray: domain below
    out = np.concatenate(segs).astype(INDEX_DTYPE)
    return out[(out >= 0).all(axis=1) & (out[:, 0] != out[:, 1])]


def _one_family(field, axis, n_rays, samples_per_ray, tolerance, cnt):
    r, ray, s, up, pts, ends = ray_crossings(field, axis, n_rays, samples_per_ray, tolerance, counter=cnt)
    span = (field.bounds[0, axis], field.bounds[1, axis])
    segs = _join_strips(n_rays, _runs(ray, s, ends, span), span)
    if axis == 1:  # (x, y) = (r, s) mirrors the rays' frame: reverse to keep f > 0 on the left
        segs = segs[:, ::-1]
    return pts, segs, len(ray)


def _grid_of_rays(field, n_rays, samples_per_ray, tolerance, cnt):
    """Both families: crossings on the ray pieces around each cell of the grid of rays."""
    cx, cy = _ray_positions(field, 1, n_rays), _ray_positions(field, 0, n_rays)  # x of y-rays, y of x-rays
    _, hray, hs, hup, hpts, _ = ray_crossings(field, 0, n_rays, samples_per_ray, tolerance, extra=cx, counter=cnt)
    _, vray, vs, vup, vpts, _ = ray_crossings(field, 1, n_rays, samples_per_ray, tolerance, extra=cy, counter=cnt)
    m = n_rays - 1
    w, h = cx[1] - cx[0], cy[1] - cy[0]
    cell, perim, is_x, point = [], [], [], []
    # rays along x (y = cy[i]): bottom side of cell (j, i), top side of cell (j, i - 1)
    j = np.searchsorted(cx, hs) - 1
    ok = (j >= 0) & (j < m)
    for side_ok, row, pos, xflag in ((ok & (hray < m), hray, hs - cx[np.clip(j, 0, m)], ~hup),
                                     (ok & (hray > 0), hray - 1, w + h + (cx[np.clip(j + 1, 0, m)] - hs), hup)):
        cell.append(j[side_ok] * m + row[side_ok])
        perim.append(pos[side_ok])
        is_x.append(xflag[side_ok])
        point.append(np.flatnonzero(side_ok))
    # rays along y (x = cx[k]): right side of cell (k - 1, i), left side of cell (k, i)
    i = np.searchsorted(cy, vs) - 1
    ok = (i >= 0) & (i < m)
    n_h = len(hray)
    for side_ok, col, pos, xflag in ((ok & (vray > 0), vray - 1, w + (vs - cy[np.clip(i, 0, m)]), ~vup),
                                     (ok & (vray < m), vray, 2 * w + h + (cy[np.clip(i + 1, 0, m)] - vs), vup)):
        cell.append(col[side_ok] * m + i[side_ok])
        perim.append(pos[side_ok])
        is_x.append(xflag[side_ok])
        point.append(n_h + np.flatnonzero(side_ok))
    cell, perim, is_x, point = (np.concatenate(v) for v in (cell, perim, is_x, point))
    counts = np.bincount(cell, minlength=m * m)
    plus = np.zeros(m * m, bool)
    amb = np.flatnonzero(counts > 2)
    if len(amb):
        centre = np.column_stack([cx[amb // m] + 0.5 * w, cy[amb % m] + 0.5 * h])
        plus[amb] = field.values(centre) > 0
        cnt["evaluations"] += len(amb)
    segs = pair_around_cells(cell, perim, is_x, point, plus)
    boxes = np.column_stack([np.repeat(cx[:-1], m), np.tile(cy[:-1], m), np.repeat(cx[1:], m), np.tile(cy[1:], m)])
    return np.concatenate([hpts, vpts]), segs, n_h + len(vray), boxes[counts > 0], int(len(amb))


def sample_rays(field: PlanarField, *, n_rays: int = 64, direction: Literal["x", "y", "both"] = "x",
                tolerance: float = 1e-3, samples_per_ray: int = 256) -> CurveSample:
    """Sample f = 0 on a beam of parallel lines: the naive method of [FG §16.3.1].

    Parameters
    ----------
    field : PlanarField
        The curve's function over its box.
    n_rays : int
        Rays per family, at the centres of ``n_rays`` equal strips of the box.
    direction : {"x", "y", "both"}
        Rays along x (the lines y = y_i), along y, or both families (a grid of rays).
    tolerance : float
        Root accuracy relative to the sample spacing along a ray.
    samples_per_ray : int
        Sample intervals along each ray (sign changes between samples bracket the roots).

    Returns
    -------
    CurveSample
        Crossings and directed segments (f > 0 on the left); ``info``: "rays",
        "crossings", "components", "evaluations", "gradients", "ray_spacing",
        "sample_spacing", "ambiguous" (grid cells with more than 2 crossings, "both"),
        "seconds"; ``cells`` the grid cells holding crossings ("both" only).

    Raises
    ------
    TypeError
        ``field`` is not a PlanarField.
    ValueError
        ``n_rays``, ``direction``, ``tolerance`` or ``samples_per_ray`` invalid.

    Examples
    --------
    >>> import warpmesh as wm
    >>> from warpmesh.frep.planar_field import PlanarField
    >>> field = PlanarField(wm.circle(1.0) | wm.circle(0.01, (0.0, 1.05)), ((-1.2, -1.2), (1.2, 1.2)))
    >>> sample_rays(field, n_rays=64).info["components"]  # the small circle lies between two rays
    1
    """
    _check_args(field, n_rays, direction, tolerance, samples_per_ray)
    t0 = time.perf_counter()
    cnt = {"evaluations": 0, "gradients": 0}
    ext = field.bounds[1] - field.bounds[0]
    cells, amb = None, 0
    if direction == "both":
        pts, segs, n_cross, cells, amb = _grid_of_rays(field, n_rays, samples_per_ray, tolerance, cnt)
        spacing = (float(ext[1] / n_rays), float(ext[0] / n_rays))
    else:
        axis = 0 if direction == "x" else 1
        pts, segs, n_cross = _one_family(field, axis, n_rays, samples_per_ray, tolerance, cnt)
        spacing = float(ext[1 - axis] / n_rays)
    pts = np.asarray(pts, REAL_DTYPE).reshape(-1, 2)
    n_comp, _ = components(segs, len(pts))
    info = {"rays": n_rays * (2 if direction == "both" else 1), "crossings": n_cross, "components": n_comp,
            **cnt, "ray_spacing": spacing, "sample_spacing": ext / samples_per_ray, "ambiguous": amb,
            "seconds": time.perf_counter() - t0}
    return CurveSample(pts, segs, info, cells)
