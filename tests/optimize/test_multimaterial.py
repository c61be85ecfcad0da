"""Simplification of multi-material surfaces (warpmesh.optimize.multimaterial, issue 23 part 3):
fewer triangles, every label's boundary closed and oriented, no crossing, every remaining vertex
at an input position, junction vertices on their input curves separating the same labels."""

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.cells.intersections import find_self_intersections
from warpmesh.optimize.label_smoothing import classify_edges
from warpmesh.optimize.multimaterial import simplify_labels

from .test_label_smoothing import _blobs, _check_closed_oriented, _labels, _noise, _vertex_label_sets


def _check_simplified(before, after, fraction_reached=None):
    assert after.n_cells < before.n_cells
    if fraction_reached is not None:
        assert after.n_cells <= fraction_reached * before.n_cells
    _check_closed_oriented(after)
    assert len(find_self_intersections(after.points, after.cells["triangle"])) == 0
    # every vertex at an input position, separating a subset of the labels it separated there
    pos = {tuple(q): k for k, q in enumerate(np.round(before.points, 9).tolist())}
    where = np.array([pos[tuple(q)] for q in np.round(after.points, 9).tolist()])
    old_sets, new_sets = _vertex_label_sets(before), _vertex_label_sets(after)
    assert all(set(new_sets[k]) <= set(old_sets[where[k]]) for k in range(after.n_points))
    # junction vertices (3 labels or more) keep their label sets exactly: they stay on their curve
    junction = [k for k in range(after.n_points) if len(new_sets[k]) >= 3]
    assert junction and all(new_sets[k] == old_sets[where[k]] for k in junction)
    # a vertex on a feature edge (junction curve, open boundary) of the result was on one in the input
    lower, upper = _labels(after)
    a, b, feature, _ = classify_edges(after.cells["triangle"], lower, upper, after.n_points)
    lower0, upper0 = _labels(before)
    _, _, _, kind0 = classify_edges(before.cells["triangle"], lower0, upper0, before.n_points)
    on_feature = np.unique(np.concatenate([a[feature], b[feature]]))
    assert len(on_feature) and np.all(kind0[where[on_feature]] != 2)


@pytest.mark.parametrize("seed, n_labels", [(0, 3), (2, 5)])
def test_smoothed_blobs_to_half(seed, n_labels):
    smooth = wm.mesh_surface(_blobs(seed, n_labels), labels="all", interfaces="shared", smoothing=16)
    half = simplify_labels(smooth, 0.5)
    _check_simplified(smooth, half, fraction_reached=0.55)
    info = half.info["simplify"]
    assert info["collapses"] > 0 and info["triangles"] == (smooth.n_cells, half.n_cells)


def test_within_tolerance_of_the_input():
    """Every output vertex is an input vertex, and the output's centroids lie within the
    tolerance of the input surface."""
    smooth = wm.mesh_surface(_blobs(1, 4), labels="all", interfaces="shared", smoothing=16)
    tol = 0.3
    fewer = simplify_labels(smooth, 0.3, tolerance=tol)
    _check_simplified(smooth, fewer)
    pv = pytest.importorskip("pyvista")
    t = smooth.cells["triangle"]
    ref = pv.PolyData(smooth.points, np.hstack([np.full((len(t), 1), 3), t]).ravel())
    cen = fewer.points[fewer.cells["triangle"]].mean(axis=1)
    _, closest = ref.find_closest_cell(cen, return_closest_point=True)
    assert np.linalg.norm(closest - cen, axis=1).max() <= tol * (1 + 1e-9)


def test_noise_volume_many_junctions():
    raw = wm.mesh_surface(_noise(3, 3), labels="all", interfaces="shared")
    _check_simplified(raw, simplify_labels(raw, 0.5))


def test_two_boxes_keep_their_junction_loop():
    vol = np.zeros((14, 14, 14), np.uint8)
    vol[3:11, 3:11, 3:7] = 1
    vol[3:11, 3:11, 7:11] = 2
    raw = wm.mesh_surface(vol, labels="all", interfaces="shared")
    fewer = simplify_labels(raw, 0.2)
    _check_simplified(raw, fewer, fraction_reached=0.25)
    sets = _vertex_label_sets(fewer)
    on_loop = np.array([s == (0, 1, 2) for s in sets])
    assert on_loop.sum() >= 4  # the square loop keeps at least its corners ...
    assert np.ptp(fewer.points[on_loop, 2]) < 1e-12  # ... in its plane


def test_bad_input_names_the_argument():
    raw = wm.mesh_surface(_blobs(0, 3), labels="all", interfaces="shared")
    for bad in (0.0, 1.5, True):
        with pytest.raises(ValueError, match="'fraction'"):
            simplify_labels(raw, bad)
    with pytest.raises(ValueError, match="'tolerance'"):
        simplify_labels(raw, 0.5, tolerance=-1.0)
    with pytest.raises(ValueError, match="interfaces='shared' in 'mesh'"):
        simplify_labels(wm.mesh_surface(_blobs(0, 3), labels="all"), 0.5)


def test_simplify_dispatches_shared_surfaces():
    """``wm.simplify`` / ``Mesh.simplify`` of a shared surface without a shape is simplify_labels."""
    smooth = wm.mesh_surface(_blobs(3, 3), labels="all", interfaces="shared", smoothing=8)
    direct = simplify_labels(smooth, 0.4)
    via = smooth.simplify(fraction=0.4)
    assert np.array_equal(via.points, direct.points) and np.array_equal(via.triangles, direct.triangles)
    assert np.array_equal(via.cell_data["label_above"]["triangle"], direct.cell_data["label_above"]["triangle"])
