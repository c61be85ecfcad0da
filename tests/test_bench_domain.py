"""The measuring helpers of ``benchmarks/bench_domain.py``: the Kuhn background of the mmg
peer, the stratified grid volume (and the part's exact volume it is checked against), the
orientation fix and the boundary distance. Nothing is timed; small inputs (a few CPU s)."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_domain.py"


@pytest.fixture(scope="module")
def bd():
    sys.path.insert(0, str(_PATH.parent))  # the script imports its sibling _report
    try:
        with pytest.MonkeyPatch.context() as mp:
            import _report

            for k, v in _report.MALLOC_ENV.items():  # so the script does not re-exec the process
                mp.setenv(k, v)
            spec = importlib.util.spec_from_file_location("bench_domain", _PATH)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(_PATH.parent))
    return mod


def test_kuhn_box_fills_the_box_conformingly(bd):
    box = np.array([[-1.0, 0.0, 0.5], [1.0, 1.5, 2.0]])
    pts, tets = bd.kuhn_box(box, 0.5)
    vol = bd.signed_volumes(pts, tets)
    assert (vol > 0).all()
    assert vol.sum() == pytest.approx(2.0 * 1.5 * 1.5, rel=1e-12)
    faces = np.sort(np.concatenate([tets[:, f] for f in ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))]), axis=1)
    _, counts = np.unique(faces, axis=0, return_counts=True)
    assert counts.max() == 2  # each face in one or two tetrahedra
    _, inv, counts = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
    outer = pts[faces[counts[inv.ravel()] == 1]]  # (k, 3 vertices, 3 coordinates)
    on_plane = (np.isclose(outer, box[0]) | np.isclose(outer, box[1])).all(axis=1)
    assert on_plane.any(axis=1).all()  # the faces of one tetrahedron lie in a face of the box


def test_grid_volume_matches_the_exact_volumes(bd):
    import warpmesh as wm

    for name in ("sphere", "part"):  # the part's exact value is the benchmark's own formula
        est = bd.grid_volume(*wm.example(name), n=128)
        assert est == pytest.approx(bd.EXACT_VOLUME[name], rel=5e-4), name
    # a face parallel to the grid, off the cell boundaries: cell centres would be biased by 1/6 cell
    box = wm.box((1.0, 1.0, 1.0))
    assert bd.grid_volume(box, ((-0.61,) * 3, (0.61,) * 3), n=48) == pytest.approx(1.0, rel=2e-3)


def test_positive_flips_the_other_winding_and_counts_flat(bd):
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    tets[bd.signed_volumes(pts, tets) > 0] = tets[bd.signed_volumes(pts, tets) > 0][:, [0, 1, 3, 2]]
    assert (bd.signed_volumes(pts, tets) < 0).all()  # both wound the other way
    out, bad = bd.positive(pts, tets)
    assert bad == 0 and (bd.signed_volumes(pts, out) > 0).all()
    flat = np.array([[0, 1, 2, 3], [0, 1, 2, 2]])
    assert bd.positive(pts, flat)[1] == 1


def test_boundary_distance_measures_an_offset_in_units_of_h(bd):
    import warpmesh as wm

    shape, bounds = wm.example("sphere")
    vol = wm.mesh_domain(shape, bounds=bounds, size=0.3)
    box = np.asarray(bounds, dtype=np.float64)
    tets = vol.cells["tetra"]
    assert bd.boundary_distance(shape, box, vol.points, tets, 0.3) < 1e-3
    # scaled by 1.01 about the centre: boundary vertices 0.01 off the unit sphere = 0.01 / 0.3 h
    assert bd.boundary_distance(shape, box, vol.points * 1.01, tets, 0.3) == pytest.approx(0.01 / 0.3, rel=0.02)


def test_gyroid_ball_is_the_gyroid_inside_the_ball(bd):
    import warpmesh as wm

    shape, bounds = bd.gyroid_ball(period=1.0, radius=1.0)
    k = 2 * math.pi
    p = np.array([[0.1, 0.2, 0.05], [0.3, -0.2, 0.1], [0.0, 0.0, 1.05]])
    g = np.sin(k * p[:, 0]) * np.cos(k * p[:, 1]) + np.sin(k * p[:, 1]) * np.cos(k * p[:, 2]) \
        + np.sin(k * p[:, 2]) * np.cos(k * p[:, 0])
    inside = (g > 0) & (np.linalg.norm(p, axis=1) < 1.0)
    assert ((wm.evaluate(shape, p) > 0) == inside).all()
    with pytest.raises(ValueError, match="period"):
        bd.gyroid_ball(period=0.0)
