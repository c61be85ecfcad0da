"""Continuation samplers [FG §16.3.1] and automatic seeds, checked against the exact curves.

Every polyline goes through tests/curvecheck.check_curve: no crossing segments, closed
(or open only on the box boundary), the component count, f > 0 on the left of every
regular segment, two-sided Hausdorff distance to the exact curve.
"""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from tests.helpers.curvecheck import check_curve
from warpmesh.planar.samplers.continuation import sample_predictor_corrector, sample_progression
from warpmesh.frep.planar_field import PlanarField
from warpmesh.planar.samplers.seeds import find_seeds
from warpmesh.mesh import Mesh

EPS = 5e-3  # relative chord deviation of the predictor-corrector in most tests

# name: (shape, bounds, components, closed)
CURVES = {
    "circle": (wm.circle(1.0), ((-2, -2), (2, 2)), 1, True),
    "ellipse": (wm.ellipse((1.0, 0.1)), ((-1.5, -0.5), (1.5, 0.5)), 1, True),
    "two_circles": (wm.circle(1.0, (-1.005, 0.0)) | wm.circle(1.0, (1.005, 0.0)), ((-2.5, -1.5), (2.5, 1.5)), 2, True),
    "cassini_095": (wm.cassini(1.0, 0.95), ((-1.6, -0.7), (1.6, 0.7)), 2, True),
    "cassini_105": (wm.cassini(1.0, 1.05), ((-1.6, -0.7), (1.6, 0.7)), 1, True),
    "island": (wm.circle(1.0) | wm.circle(0.03, (1.6, -1.5)), ((-2, -2), (2, 2)), 2, True),
    "open_arc": (wm.circle(1.0, (0.8, 0.0)), ((-1, -1), (1, 1)), 1, False),
}


def mesh_of(sample):
    return Mesh(sample.points, {"line": sample.segments})


def field_of(name):
    shape, bounds, _, _ = CURVES[name]
    return PlanarField(shape, bounds)


# -- seeds ------------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(CURVES))
def test_seeds_lie_on_every_component(name):
    shape, bounds, n_comp, _ = CURVES[name]
    field = PlanarField(shape, bounds)
    seeds, info = find_seeds(field)
    assert seeds.shape[1] == 2 and len(seeds) == len(info["cluster"])
    assert np.all((seeds >= field.bounds[0]) & (seeds <= field.bounds[1]))
    assert field.estimate(seeds).max() < 1e-5 * field.size
    # every component holds a seed: tracing from the seeds finds them all
    sample = sample_predictor_corrector(field, tolerance=2e-2, seeds=seeds)
    assert check_curve(mesh_of(sample), shape, bounds, closed=CURVES[name][3])["components"] == n_comp


def test_seeds_find_a_small_island_below_the_coarse_grid():
    shape, bounds, _, _ = CURVES["island"]
    seeds, info = find_seeds(PlanarField(shape, bounds), resolution=16)  # coarse cells 0.25 >> island 0.06
    near = np.linalg.norm(seeds - [1.6, -1.5], axis=1) < 0.05
    assert near.any() and info["levels"] > 2
    assert info["clusters"] == 2 and len(np.unique(info["cluster"][near])) == 1
    # without subdivision below the coarse cells it is missed
    seeds2, _ = find_seeds(PlanarField(shape, bounds), resolution=16, min_size=0.25)
    assert not (np.linalg.norm(seeds2 - [1.6, -1.5], axis=1) < 0.05).any()


def test_seed_clusters_separate_distant_components():
    _, info = find_seeds(field_of("cassini_095"))
    assert info["clusters"] == 2
    _, info = find_seeds(field_of("cassini_105"))
    assert info["clusters"] == 1


# -- predictor-corrector ----------------------------------------------------------------

@pytest.mark.parametrize("name", list(CURVES))
def test_predictor_corrector_curves(name):
    shape, bounds, n_comp, closed = CURVES[name]
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=EPS)
    info = sample.info
    assert info["failures"] == [] and not info["truncated"]
    assert info["components"] == n_comp
    assert info["closed"] == (n_comp if closed else 0)
    assert info["open_ends"] == (0 if closed else 2)
    # Hausdorff bound: chord deviation <= eps h <= eps hmax, plus float32 noise
    bound = EPS * info["hmax"] + 1e-5
    out = check_curve(mesh_of(sample), shape, bounds, n_components=n_comp, closed=closed, hausdorff=bound)
    assert out["max_length"] <= info["hmax"] * 1.01


def test_predictor_corrector_never_jumps_between_nearly_touching_circles():
    shape, bounds, _, _ = CURVES["two_circles"]
    field = PlanarField(shape, bounds)
    for eps in (2e-2, 5e-2):  # long steps: the predictor lands close to the other circle
        sample = sample_predictor_corrector(field, tolerance=eps)
        check_curve(mesh_of(sample), shape, bounds, n_components=2, hausdorff=eps * sample.info["hmax"] + 1e-5)
        # every segment joins two points of the same circle
        side = np.sign(sample.points[:, 0])
        assert np.all(side[sample.segments[:, 0]] == side[sample.segments[:, 1]])


@pytest.mark.parametrize("eps", [2e-2, 2e-3])
def test_predictor_corrector_chord_deviation_follows_tolerance(eps):
    shape, bounds, _, _ = CURVES["ellipse"]
    field = PlanarField(shape, bounds)
    sample = sample_predictor_corrector(field, tolerance=eps)
    p, s = sample.points, sample.segments
    h = np.linalg.norm(p[s[:, 1]] - p[s[:, 0]], axis=1)
    dev = field.distance(0.5 * (p[s[:, 0]] + p[s[:, 1]]))
    assert np.all(dev <= eps * h + 2e-6 * field.size)  # delta <= eps h on every segment
    # steps follow the curvature: short at the tips (rho = 0.01), long on the flanks (rho = 10)
    tip = np.abs(p[s[:, 0], 0]) > 0.99
    assert h[tip].max() < 0.2 * h[~tip].max()
    # about 2 pi / (8 eps) steps around a convex curve when hmax does not bind
    if eps == 2e-2:
        assert len(s) < 2.5 * 2 * np.pi / (8 * eps) + 30


def test_predictor_corrector_lemniscate_passes_through_the_crossing():
    shape, bounds = wm.cassini(1.0, 1.0), ((-1.6, -0.7), (1.6, 0.7))
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=EPS)
    info = sample.info
    assert info["crossings"] == 2 and info["closed"] == 1 and info["failures"] == []
    (o,) = np.asarray(info["singular_points"])
    assert np.linalg.norm(o) < 1e-4
    # the crossing is one vertex with two segments in and two out: a closed figure-eight
    k = int(np.argmin(np.linalg.norm(sample.points - o, axis=1)))
    assert np.count_nonzero(sample.segments[:, 0] == k) == 2 and np.count_nonzero(sample.segments[:, 1] == k) == 2
    check_curve(mesh_of(sample), shape, bounds, n_components=1, singular=[(0.0, 0.0)],
                hausdorff=EPS * info["hmax"] + 1e-5)


def test_predictor_corrector_moved_lemniscate():
    shape = wm.cassini(1.0, 1.0).rotate(0.3).translate((0.13, 0.07))
    bounds = ((-1.6, -1.0), (1.6, 1.0))
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=1e-2)
    (o,) = np.asarray(sample.info["singular_points"])
    assert np.linalg.norm(o - [0.13, 0.07]) < 1e-4
    check_curve(mesh_of(sample), shape, bounds, n_components=1, singular=[tuple(o)])


def test_predictor_corrector_splices_a_spike_narrower_than_the_step():
    """The first walker steps over a thin spike (width 0.008 < h); find_seeds puts seeds on
    it, a second-round walker traces it and splices into the first polyline."""
    shape, bounds = wm.circle(1.0) | wm.ellipse((0.06, 0.004), (1.04, 0.0)), ((-1.5, -1.5), (1.5, 1.5))
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=1e-2)
    assert sample.info["merged"] == 2 and sample.info["walkers"] == 2 and sample.info["components"] == 1
    check_curve(mesh_of(sample), shape, bounds, n_components=1, hausdorff=1e-2 * sample.info["hmax"] + 1e-5)


def test_predictor_corrector_orientation_domain_on_the_left():
    for shape, area in ((wm.circle(0.5), np.pi * 0.25), (wm.rectangle((3.0, 3.0)) - wm.circle(0.5), -np.pi * 0.25)):
        sample = sample_predictor_corrector(PlanarField(shape, ((-1, -1), (1, 1))), tolerance=1e-2)
        p, s = sample.points, sample.segments
        signed = 0.5 * np.sum(p[s[:, 0], 0] * p[s[:, 1], 1] - p[s[:, 1], 0] * p[s[:, 0], 1])
        assert signed == pytest.approx(area, rel=2e-3)  # counter-clockwise around f > 0


def test_predictor_corrector_user_seeds_trace_each_component_once():
    shape, bounds, _, _ = CURVES["cassini_095"]
    field = PlanarField(shape, bounds)
    seeds = [[1.2, 0.05], [-1.2, 0.0], [0.5, 0.3], [1.3, -0.1]]  # two on each oval, off the curve
    sample = sample_predictor_corrector(field, tolerance=1e-2, seeds=seeds)
    assert sample.info["walkers"] == 2 and sample.info["seeds_skipped"] >= 2
    check_curve(mesh_of(sample), shape, bounds, n_components=2)


def test_predictor_corrector_reports_failure_instead_of_looping():
    shape, bounds, _, _ = CURVES["ellipse"]
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=1e-3, hmin=0.02, hmax=0.05)
    assert len(sample.info["failures"]) >= 1  # the tips (rho = 0.01) need h < 8e-5
    assert sample.info["closed"] == 0 and len(sample.segments) > 0


def test_predictor_corrector_truncates_at_max_points():
    sample = sample_predictor_corrector(field_of("circle"), tolerance=1e-3, max_points=50)
    assert sample.info["truncated"] and len(sample.points) < 60


@pytest.mark.parametrize("shape, n_corners", [(wm.rectangle((1.0, 0.6)), 4), (wm.regular_polygon(6, 0.7), 6)])
def test_predictor_corrector_turns_corners(shape, n_corners):
    """G1 discontinuities: below a step of eps * hmax a large turn is a corner, passed with
    an absolute chord deviation <= eps * hmax (not the relative one)."""
    bounds = ((-1, -1), (1, 1))
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=1e-2)
    info = sample.info
    assert info["failures"] == [] and info["closed"] == 1 and info["corners"] >= n_corners
    check_curve(mesh_of(sample), shape, bounds, n_components=1, hausdorff=1e-2 * info["hmax"] + 1e-5)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["plate", "gear"])
def test_predictor_corrector_csg_corners(name):
    shape, bounds = wm.example(name)
    sample = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=2e-2)
    assert sample.info["failures"] == []
    assert sample.info["corners"] > 0 or name == "plate"  # the plate's corners are rounded (r = 0.1)
    check_curve(mesh_of(sample), shape, bounds, hausdorff=2e-2 * sample.info["hmax"] + 1e-5)


# -- progression --------------------------------------------------------------------------

@pytest.mark.parametrize("name", list(CURVES))
def test_progression_curves(name):
    shape, bounds, n_comp, closed = CURVES[name]
    field = PlanarField(shape, bounds)
    res = 256 if name == "island" else 128  # the island (diameter 0.06) needs cells below it
    sample = sample_progression(field, resolution=res, tolerance=1e-3)
    info = sample.info
    cell = max(info["cell"])
    # grid methods: the error is set by the cell, a chord of length up to sqrt(2) cell
    # on the smallest radius of curvature rho, deviating by (sqrt(2) cell)^2 / (8 rho)
    rho = {"ellipse": 0.01, "island": 0.03, "cassini_095": 0.25, "cassini_105": 0.39}.get(name, 1.0)
    bound = min(cell, cell**2 / (4 * rho)) + 1e-3 * cell
    check_curve(mesh_of(sample), shape, bounds, n_components=n_comp, closed=closed, hausdorff=bound)
    assert info["node_evaluations"] < info["grid_nodes"] / 4  # only nodes of visited cells
    assert sample.cells.shape == (info["cells_crossed"], 4)


def test_progression_ambiguous_cells_use_the_asymptotic_decider():
    x, y = wm.coords(2)
    shape = x * y + 0.001  # hyperbola branches in quadrants II and IV, inside across the origin
    bounds = ((-1.05, -1.05), (0.95, 0.95))  # the origin is a cell centre at resolution 20
    sample = sample_progression(PlanarField(shape, bounds), resolution=20)
    assert sample.info["ambiguous"] >= 1
    check_curve(mesh_of(sample), shape, bounds, n_components=2, closed=False, hausdorff=0.02)
    pc = sample_predictor_corrector(PlanarField(shape, bounds), tolerance=1e-2)
    check_curve(mesh_of(pc), shape, bounds, n_components=2, closed=False)


def test_progression_lemniscate_splits_at_the_crossing():
    """A grid cannot hold the crossing: the node at the origin has f = 0 (counted outside),
    so the lobes come out as two closed loops touching near the singular point."""
    shape, bounds = wm.cassini(1.0, 1.0), ((-1.6, -0.7), (1.6, 0.7))
    sample = sample_progression(PlanarField(shape, bounds), resolution=128)
    out = check_curve(mesh_of(sample), shape, bounds, singular=[(0.0, 0.0)], hausdorff=0.01)
    assert out["components"] == 2


def test_progression_counts_and_truncation():
    field = field_of("circle")
    sample = sample_progression(field, resolution=256)
    assert sample.info["node_evaluations"] < sample.info["grid_nodes"] / 20
    assert sample.info["evaluations"] < sample.info["grid_nodes"] / 4  # with the bisections
    cut = sample_progression(field, resolution=256, max_cells=100)
    assert cut.info["truncated"] and cut.info["cells_visited"] <= 100


# -- empty and bad input ------------------------------------------------------------------

def test_no_curve_in_the_box_gives_an_empty_sample():
    field = PlanarField(wm.circle(0.5, (5.0, 5.0)), ((-1, -1), (1, 1)))
    seeds, info = find_seeds(field)
    assert seeds.shape == (0, 2) and info["clusters"] == 0
    for sample in (sample_predictor_corrector(field), sample_progression(field)):
        assert sample.points.shape == (0, 2) and sample.segments.shape == (0, 2)
    assert sample_predictor_corrector(field).info["components"] == 0


@pytest.mark.parametrize("call, name", [
    (lambda f: sample_predictor_corrector(f, tolerance=-1e-3), "tolerance"),
    (lambda f: sample_predictor_corrector(f, tolerance="tight"), "tolerance"),
    (lambda f: sample_predictor_corrector(f, hmin=0.5, hmax=0.1), "hmin"),
    (lambda f: sample_predictor_corrector(f, hmax=0.0), "hmax"),
    (lambda f: sample_predictor_corrector(f, max_points=0), "max_points"),
    (lambda f: sample_predictor_corrector(f, seeds=[1.0, 2.0, 3.0]), "seeds"),
    (lambda f: sample_progression(f, tolerance=0.0), "tolerance"),
    (lambda f: sample_progression(f, resolution=0), "resolution"),
    (lambda f: sample_progression(f, resolution=2.5), "resolution"),
    (lambda f: sample_progression(f, max_cells=-3), "max_cells"),
    (lambda f: find_seeds(f, min_size=-1.0), "min_size"),
    (lambda f: find_seeds(f, resolution=True), "resolution"),
])
def test_bad_arguments_name_the_argument(call, name):
    with pytest.raises(ValueError, match=name):
        call(field_of("circle"))


def test_not_a_field():
    for fn in (find_seeds, sample_progression, sample_predictor_corrector):
        with pytest.raises(TypeError, match="PlanarField"):
            fn(wm.circle(1.0))
