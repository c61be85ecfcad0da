"""A fuzz of the surface pipelines (issue 19 item 7): random CSG trees x methods x coverings
x resolutions x bounds, each result checked by independent means.

Checks per case: closed, 2-manifold, oriented and embedded (tests/helpers/meshcheck.py,
whose crossing test is cross-checked against pymeshlab); culling changes nothing (the
grid's triangles equal cull=False's); continuation finds the grid's triangles; the enclosed
volume agrees with a Monte-Carlo estimate of {f > 0} within the box (4 standard errors plus
half a cell times the area, the discretisation's reach).

A bounded, derandomised slice runs in the normal suite; ``-m slow`` runs a longer one; a
long run is ``WARPMESH_FUZZ_EXAMPLES=5000 python -m pytest tests/test_fuzz.py -m slow``.
The octree's topology is also checked against the grid's (:func:`check_topology_case`).
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import warpmesh as wm
from tests.helpers.fuzz_settings import seeded
from tests.helpers.meshcheck import check_mesh
from tests.helpers.random_shapes import random_shape
from warpmesh.surface.adaptive.octree import finest_cells

MC_POINTS = 20_000


def _case(seed: int):
    """(shape, bounds, resolution, method, covering) drawn from one seed."""
    rng = np.random.default_rng(seed)
    shape = random_shape(rng, int(rng.integers(1, 4)))
    lo = rng.uniform(-1.6, -0.4, 3)
    hi = lo + rng.uniform(0.6, 3.0, 3)
    resolution = int(rng.integers(8, 41))
    method = ("mc", "mc33", "mt")[int(rng.integers(3))]
    covering = ("grid", "continuation", "adaptive")[int(rng.integers(3))]
    return shape, (tuple(lo), tuple(hi)), resolution, method, covering


def _mesh(shape, bounds, resolution, method, covering, **extra):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # empty meshes and far-off shapes warn
        if covering == "adaptive":
            level = max(3, int(np.ceil(np.log2(resolution))))
            return wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=level, **extra)
        cov = {"covering": "continuation"} if covering == "continuation" else {}
        return wm.mesh_surface(shape, bounds=bounds, resolution=resolution, method=method, **cov, **extra)


def _triangles(m) -> set:
    return {tuple(sorted(map(tuple, t))) for t in m.points[m.cells["triangle"]].tolist()}


def _monte_carlo_volume(shape, bounds, seed: int) -> tuple[float, float]:
    lo, hi = np.asarray(bounds[0]), np.asarray(bounds[1])
    pts = np.random.default_rng(seed).uniform(lo, hi, (MC_POINTS, 3))
    inside = wm.evaluate(shape, pts) > 0
    box = float(np.prod(hi - lo))
    p = float(inside.mean())
    return box * p, box * np.sqrt(max(p * (1 - p), 1.0 / MC_POINTS) / MC_POINTS)


def check_case(seed: int) -> None:
    shape, bounds, resolution, method, covering = _case(seed)
    try:
        m = _mesh(shape, bounds, resolution, method, covering)
    except ValueError as error:  # only a clear refusal of the input is acceptable
        assert "NaN" in str(error) or "'bounds'" in str(error), error
        return
    where = f"seed {seed}: {covering} {method} at {resolution} in {np.round(bounds, 3).tolist()}"
    area = volume_mesh = 0.0
    if m.n_cells:
        try:
            check_mesh(m)
        except AssertionError as error:
            raise AssertionError(f"{where}: {error}") from None
        stats = m.stats()
        area, volume_mesh = stats["area"], stats["volume"]
        if covering == "grid":
            assert _triangles(m) == _triangles(_mesh(shape, bounds, resolution, method, covering, cull=False)), where
        if covering == "continuation":
            assert _triangles(m) == _triangles(_mesh(shape, bounds, resolution, method, "grid")), where
    volume, sigma = _monte_carlo_volume(shape, bounds, seed)
    h = float(np.max(np.subtract(bounds[1], bounds[0]))) / resolution
    reach = 4 * sigma + 0.5 * h * area
    if abs(volume_mesh - volume) > reach:  # parts thinner than a cell are lost: their area on a finer grid
        fine_resolution = min(4 * resolution, 192)
        fine = _mesh(shape, bounds, fine_resolution, "mc", "grid")
        fine_area, fine_volume = (fine.stats()["area"], fine.stats()["volume"]) if fine.n_cells else (0.0, 0.0)
        h_fine = h * resolution / fine_resolution
        if abs(fine_volume - volume) > 4 * sigma + 0.5 * h_fine * fine_area:
            return  # features thinner than the finer grid's cells too: no grid can be checked against MC here
        reach = 4 * sigma + 0.5 * h * max(area, fine_area)
    assert abs(volume_mesh - volume) <= reach, f"{where}: volume {volume_mesh:.4g}, MC {volume:.4g} +- {reach:.3g}"


def _topology(m) -> tuple:
    s = m.stats()
    return s["euler"], s["components"]


def _regular(shape, points: np.ndarray, step: float) -> bool:
    """Whether |grad f| (central differences) stays above 1 % of its median on these points
    of f = 0: else the zero set is not a manifold there (two sheets cross or touch) and its
    topology is not defined."""
    grad = np.stack([wm.evaluate(shape, points + step * e) - wm.evaluate(shape, points - step * e)
                     for e in np.eye(3)], axis=1) / (2 * step)
    norm = np.linalg.norm(grad, axis=1)
    return bool(norm.min() > 0.01 * np.median(norm))


def _settled(shape, bounds, topology, level: int, surface, h: float) -> bool:
    """Whether the grid settles ``topology`` for the octree too (beyond agreeing from 51 to 128
    cells and a regular gradient at its vertices):

    - the grid on the octree's own finest cells (:func:`finest_cells`: up to 1.25x longer than
      the longest side's on the other axes, another phase), with mc and mc33, finds it too:
      else a feature at the scale of a cell comes and goes with the sampling (seeds 101656,
      102728, 102766: the octree agrees with that grid);
    - it holds for the level sets f = +-delta on the grid at 128, delta = 2 % of its cell ``h``
      times the median |grad f| on the vertices of ``surface``: else f = 0 lies within 2 % of a cell of a critical level
      (two sheets that touch, f >= 0 on both sides with a zero between them; the gradient test
      on the vertices misses it: seeds 101083, 101845, 102308, 102391)."""
    n = tuple(int(v) for v in finest_cells(bounds[0], bounds[1], level)[2])
    if any(_topology(_mesh(shape, bounds, n, method, "grid")) != topology for method in ("mc", "mc33")):
        return False
    step = 1e-3 * h
    grad = np.stack([wm.evaluate(shape, surface.points + step * e) - wm.evaluate(shape, surface.points - step * e)
                     for e in np.eye(3)], axis=1) / (2 * step)
    delta = 0.02 * h * float(np.median(np.linalg.norm(grad, axis=1)))
    return all(_topology(_mesh(shape + d, bounds, 128, "mc", "grid")) == topology for d in (delta, -delta))


def check_topology_case(seed: int) -> None:
    """The octree's Euler characteristic and components equal the grid's wherever the grid
    settles them: the grid agrees with itself from 51 to 128 cells, the zero set is regular
    (issue 19 item 2: thin parts pressed against the bounds were split by the octree), and,
    checked only when the octree disagrees (the same verdicts for less time), the grid on the
    octree's own finest cells and on the level sets near 0 agree too (:func:`_settled`)."""
    shape, bounds, *_ = _case(seed)
    grids = [_mesh(shape, bounds, r, "mc", "grid") for r in (51, 64, 128)]
    if not grids[-1].n_cells or len({_topology(g) for g in grids}) > 1:
        return  # nothing in the box, or features finer than a cell of a coarser grid
    h = float(np.max(np.subtract(bounds[1], bounds[0]))) / 128
    if not _regular(shape, grids[1].points, 1e-3 * h):
        return
    m = _mesh(shape, bounds, 64, "mc", "adaptive")
    if m.n_cells and _topology(m) == _topology(grids[1]):
        return
    if not _settled(shape, bounds, _topology(grids[1]), 6, grids[1], h):
        return
    where = f"seed {seed}: adaptive at max_level 6 in {np.round(bounds, 3).tolist()}"
    assert m.n_cells and _topology(m) == _topology(grids[1]), f"{where}: {_topology(m)} against {_topology(grids[1])}"


def check_volume_case(seed: int) -> None:
    """A random volume (floats with ties, or labels), level, method, spacing and cap: closed,
    manifold, oriented, embedded, and the same triangles with and without culling."""
    rng = np.random.default_rng(seed)
    shape = tuple(int(v) for v in rng.integers(2, 14, 3))
    if rng.random() < 0.5:
        vol = rng.integers(0, 3, shape).astype(np.float32)  # ties at the level: the hard case
        level = float(rng.choice([0.5, 1.0, 1.5]))
    else:
        vol = rng.normal(size=shape).astype(np.float32)
        level = float(rng.uniform(-0.5, 0.5))
    method = ("mc", "mc33", "mt")[int(rng.integers(3))]
    options = dict(level=level, method=method, spacing=tuple(rng.uniform(0.2, 2.0, 3)), cap=bool(rng.random() < 0.8))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            m = wm.mesh_surface(vol, **options)
        except ValueError as error:  # too few samples for a capped grid, say: a clear refusal
            assert "expected" in str(error), error
            return
        dense = wm.mesh_surface(vol, cull=False, **options)
    where = f"volume seed {seed}: {shape} {options}"
    assert _triangles(m) == _triangles(dense), where
    if m.n_cells:
        try:
            check_mesh(m, closed=options["cap"])
        except AssertionError as error:
            raise AssertionError(f"{where}: {error}") from None


FAST = seeded(24)
LONG = seeded(int(os.environ.get("WARPMESH_FUZZ_EXAMPLES", 120)))
LONG_TOPOLOGY = seeded(int(os.environ.get("WARPMESH_FUZZ_EXAMPLES", 40)))  # three meshes a case


@FAST
@given(st.integers(min_value=0, max_value=2**31 - 1))
def test_fuzz_surfaces(seed):
    check_case(seed)


@pytest.mark.slow
@LONG
@given(st.integers(min_value=2**31, max_value=2**32 - 1))
def test_fuzz_surfaces_long(seed):
    check_case(seed)


@pytest.mark.parametrize("seed", [1863, 1888, 102141, 102757])
def test_octree_topology_regressions(seed):
    """Seeds where the octree gave another Euler characteristic or component count than the grid;
    each fails again with a part of the octree's cap refinement (``octree._cap_loses``) patched out:

    - 1863, 1888: a solid thinner than a leaf pressed against the bounds vanished or split under
      the cap (without ``_cap_loses``: (4, 2) against the grid's (0, 1), (0, 1) against (2, 1));
      its test of cells the cap empties, or of crossings the cap hides, keeps them alone;
    - 102757: a solid lying along the bounds lost its part under coarse leaves whose crossings
      the cap hid (an inside corner on the bounds, an outside one off them): (4, 2) against
      (2, 1) without the hidden-crossing test, whatever else ``_cap_loses`` refines;
    - 102141: the same, (0, 1) against (2, 1) without the hidden-crossing test alone (with
      the whole of ``_cap_loses`` out, its tree happens to come out right).

    None needs the rebuild of coarse leaves with two sheets (``_leaves_with_two_sheets``, one
    octree round each here): 1814, 1881 and 1929, listed for it before, pass with both fixes
    patched out and were dropped. Random shapes at max_level 6 rarely need it (with min_level 5
    only level-5 leaves can hold two sheets: of seeds 0-2999, 62 took a second round, none with
    another topology without it); its case is tests/surface/test_adaptive.py's rod beside a slab."""
    check_topology_case(seed)


@pytest.mark.parametrize("seed, settled", [(102141, True), (101083, False), (102728, False)])
def test_topology_check_knows_when_the_grid_settles_it(seed, settled):
    """The check's own filter: 102141 is settled (the octree must match); 101083's two solids
    touch (f >= 0 on both sides of a zero: its topology changes with f +- 2 % of a cell);
    102728's handle count changes on the grid with the octree's own finest cells."""
    shape, bounds, *_ = _case(seed)
    grid = _mesh(shape, bounds, 64, "mc", "grid")
    h = float(np.max(np.subtract(bounds[1], bounds[0]))) / 128
    assert _settled(shape, bounds, _topology(grid), 6, grid, h) == settled


@seeded(4)
@given(st.integers(min_value=0, max_value=2**31 - 1))
def test_fuzz_octree_topology(seed):
    check_topology_case(seed)


@pytest.mark.slow
@LONG_TOPOLOGY
@given(st.integers(min_value=2**31, max_value=2**32 - 1))
def test_fuzz_octree_topology_long(seed):
    check_topology_case(seed)


@FAST
@given(st.integers(min_value=0, max_value=2**31 - 1))
def test_fuzz_volumes(seed):
    check_volume_case(seed)


@pytest.mark.slow
@LONG
@given(st.integers(min_value=2**31, max_value=2**32 - 1))
def test_fuzz_volumes_long(seed):
    check_volume_case(seed)
