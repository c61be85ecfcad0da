"""Tests of the generated marching-squares / marching-triangles tables (warpmesh/marching_squares.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from warpmesh.planar.samplers import marching_squares as ms

SQUARE_EDGES = [(k, (k + 1) % 4) for k in range(4)]
TRIANGLE_EDGES = [(k, (k + 1) % 3) for k in range(3)]


def square_entry(config: int, variant: int) -> set[tuple[int, int]]:
    rows = ms.SEGMENT_TABLE[variant, config, : ms.SEGMENT_COUNT[config]]
    return {(int(a), int(b)) for a, b in rows}


def triangle_entry(config: int) -> set[tuple[int, int]]:
    if ms.TRIANGLE_SEGMENT_COUNT[config] == 0:
        return set()
    a, b = ms.TRIANGLE_SEGMENT_TABLE[config]
    return {(int(a), int(b))}


def signs(config: int, n: int) -> np.ndarray:
    return np.array([(config >> c) & 1 for c in range(n)], bool)


def config_of(inside) -> int:
    return int(sum(1 << c for c, v in enumerate(inside) if v))


# ----------------------------------------------------------------------------- layout


def test_sixteen_square_entries_and_eight_triangle_entries():
    assert ms.SEGMENT_TABLE.shape == (2, 16, 2, 2)
    assert ms.SEGMENT_COUNT.tolist() == [0, 1, 1, 1, 1, 2, 1, 1, 1, 1, 2, 1, 1, 1, 1, 0]
    assert ms.TRIANGLE_SEGMENT_TABLE.shape == (8, 2)
    assert ms.TRIANGLE_SEGMENT_COUNT.tolist() == [0, 1, 1, 1, 1, 1, 1, 0]
    assert ms.AMBIGUOUS == (5, 10)
    # unused slots are padded with -1, and only the ambiguous configs differ between variants
    for c in range(16):
        assert np.all(ms.SEGMENT_TABLE[:, c, ms.SEGMENT_COUNT[c]:] == -1)
        same = square_entry(c, ms.SEPARATED) == square_entry(c, ms.JOINED)
        assert same == (c not in ms.AMBIGUOUS), c


@pytest.mark.parametrize("n", [3, 4])
def test_every_crossing_edge_used_exactly_once(n):
    edges = SQUARE_EDGES if n == 4 else TRIANGLE_EDGES
    for config in range(1 << n):
        ins = signs(config, n)
        crossing = sorted(e for e, (a, b) in enumerate(edges) if ins[a] != ins[b])
        for variant in (ms.SEPARATED, ms.JOINED):
            entry = square_entry(config, variant) if n == 4 else triangle_entry(config)
            used = sorted(e for seg in entry for e in seg)
            assert used == crossing, (config, variant)


# ----------------------------------------------------------------------------- geometry

def _regions(corners, edges, entry, t_on_edge, px=161):
    """Rasterise the cell, draw the segments as walls, label the pieces. Returns the label
    function and the segment end points."""
    u = np.linspace(0, 1, px)
    gx, gy = np.meshgrid(u, u, indexing="ij")
    q = np.column_stack([gx.ravel(), gy.ravel()])
    # inside the polygon (convex, counter-clockwise)
    inpoly = np.ones(len(q), bool)
    for a, b in edges:
        d = corners[b] - corners[a]
        inpoly &= (-(d[1]) * (q[:, 0] - corners[a][0]) + d[0] * (q[:, 1] - corners[a][1])) >= -1e-9
    pts = {e: corners[a] + t_on_edge[e] * (corners[b] - corners[a]) for e, (a, b) in enumerate(edges)}
    wall = np.zeros(len(q), bool)
    for e0, e1 in entry:
        a, b = pts[e0], pts[e1]
        d = b - a
        t = np.clip(((q - a) @ d) / (d @ d), 0, 1)
        wall |= np.linalg.norm(q - (a + t[:, None] * d), axis=1) < 1.5 / (px - 1)
    labels, _ = ndimage.label((inpoly & ~wall).reshape(px, px))

    def label_at(p):
        i, j = np.round(np.asarray(p) * (px - 1)).astype(int)
        return labels[i, j]

    return label_at, pts


@pytest.mark.parametrize("n", [3, 4])
def test_segments_separate_inside_from_outside_corners_with_domain_on_left(n):
    """For every entry, with roots at random places on the edges: the segments cut the cell
    into pieces, corners in one piece have the same sign, corners of different signs are in
    different pieces, and the inside piece is on the left of every segment."""
    corners = ms.SQUARE_CORNERS if n == 4 else ms.TRIANGLE_CORNERS
    edges = SQUARE_EDGES if n == 4 else TRIANGLE_EDGES
    rng = np.random.default_rng(5)
    # pull corners slightly into the cell so that corner pixels are not on the boundary
    centre = corners.mean(axis=0)
    probe = corners + 0.03 * (centre - corners) / np.linalg.norm(centre - corners, axis=1)[:, None]
    for config in range(1 << n):
        ins = signs(config, n)
        for variant in (ms.SEPARATED, ms.JOINED):
            entry = square_entry(config, variant) if n == 4 else triangle_entry(config)
            for _ in range(3):
                label_at, pts = _regions(corners, edges, entry, rng.uniform(0.25, 0.75, n))
                lab = np.array([label_at(p) for p in probe])
                assert np.all(lab > 0)
                for a in range(n):
                    for b in range(n):
                        assert (lab[a] == lab[b]) == (ins[a] == ins[b]) or (
                            ins[a] == ins[b] and n == 4 and config in ms.AMBIGUOUS), (config, variant, a, b)
                if n == 4 and config in ms.AMBIGUOUS:
                    inside = np.flatnonzero(ins)
                    outside = np.flatnonzero(~ins)
                    joined = lab[inside[0]] == lab[inside[1]]
                    assert joined == (variant == ms.JOINED)
                    assert (lab[outside[0]] == lab[outside[1]]) == (variant == ms.SEPARATED)
                inside_labels = set(lab[ins].tolist())
                for e0, e1 in entry:
                    a, b = pts[e0], pts[e1]
                    d = b - a
                    left = np.array([-d[1], d[0]]) / np.linalg.norm(d)
                    m = 0.5 * (a + b)
                    assert label_at(m + 0.05 * left) in inside_labels, (config, variant)
                    assert label_at(m - 0.05 * left) not in inside_labels, (config, variant)


# ----------------------------------------------------------------------------- symmetry


def _rotate(config, entry, n, k):
    ins = signs(config, n)
    new = config_of([ins[(c - k) % n] for c in range(n)])  # corner c + k gets the sign of c
    return new, {((a + k) % n, (b + k) % n) for a, b in entry}


@pytest.mark.parametrize("n", [3, 4])
def test_rotating_corner_signs_rotates_segments(n):
    for config in range(1 << n):
        for variant in (ms.SEPARATED, ms.JOINED):
            entry = square_entry(config, variant) if n == 4 else triangle_entry(config)
            for k in range(1, n):
                new, segs = _rotate(config, entry, n, k)
                got = square_entry(new, variant) if n == 4 else triangle_entry(new)
                assert got == segs, (config, variant, k)


@pytest.mark.parametrize("n", [3, 4])
def test_complement_flips_orientation_and_swaps_variant(n):
    for config in range(1 << n):
        for variant in (ms.SEPARATED, ms.JOINED):
            entry = square_entry(config, variant) if n == 4 else triangle_entry(config)
            comp = (~config) & ((1 << n) - 1)
            got = square_entry(comp, 1 - variant) if n == 4 else triangle_entry(comp)
            assert got == {(b, a) for a, b in entry}, (config, variant)


def test_reflection_about_the_diagonal_reverses_segments():
    # mirror in the line x = y: corners 1 <-> 3, edges e0 <-> e3, e1 <-> e2
    corner = [0, 3, 2, 1]
    edge = [3, 2, 1, 0]
    for config in range(16):
        ins = signs(config, 4)
        new = config_of([ins[corner[c]] for c in range(4)])
        for variant in (ms.SEPARATED, ms.JOINED):
            mirrored = {(edge[b], edge[a]) for a, b in square_entry(config, variant)}
            assert square_entry(new, variant) == mirrored, (config, variant)


def test_generator_rejects_inconsistent_or_incomplete_base_cases():
    with pytest.raises(ValueError, match="inconsistent"):
        # corner 1 alone must be (e1, e0), the rotation of (e0, e3)
        ms.generate_table(4, [(1, 0, [(0, 3)]), (2, 0, [(0, 1)])])
    with pytest.raises(ValueError, match="missing"):
        ms.generate_table(4, [(0, 0, []), (0, 1, []), (1, 0, [(0, 3)]), (1, 1, [(0, 3)])])


# ----------------------------------------------------------------------------- configs


def test_square_and_triangle_configs_match_corner_numbering():
    rng = np.random.default_rng(1)
    inside = rng.random((6, 5)) > 0.5
    sq = ms.square_configs(inside)
    lo, up = ms.triangle_configs(inside)
    assert sq.shape == lo.shape == up.shape == (5, 4)
    for i, j in [(0, 0), (2, 3), (4, 1)]:
        c = [inside[i, j], inside[i + 1, j], inside[i + 1, j + 1], inside[i, j + 1]]
        assert sq[i, j] == config_of(c)
        assert lo[i, j] == config_of([c[0], c[1], c[2]])
        assert up[i, j] == config_of([c[0], c[2], c[3]])


# ----------------------------------------------------------------------------- decider


def _bilinear(f, u, v):
    f0, f1, f2, f3 = f
    return f0 * (1 - u) * (1 - v) + f1 * u * (1 - v) + f2 * u * v + f3 * (1 - u) * v


def test_saddle_value_is_the_stationary_value_of_the_bilinear_interpolant():
    rng = np.random.default_rng(2)
    f = rng.normal(size=(4, 200))
    # f = f0 + b u + c v + d uv: stationary point u* = -c / d, v* = -b / d
    b, c, d = f[1] - f[0], f[3] - f[0], f[0] - f[1] + f[2] - f[3]
    u, v = -c / d, -b / d
    assert np.allclose(ms.saddle_value(*f), _bilinear(f, u, v))


def test_asymptotic_decider_matches_connectivity_of_the_bilinear_inside_set():
    """On random ambiguous cells, the inside corners are joined in {bilinear > 0} (rasterised)
    exactly when the decider says JOINED."""
    rng = np.random.default_rng(3)
    px = 201
    uu, vv = np.meshgrid(np.linspace(0, 1, px), np.linspace(0, 1, px), indexing="ij")
    checked = 0
    for _ in range(60):
        mag = rng.uniform(0.1, 1.0, 4)
        sign = np.array([1, -1, 1, -1]) * (1 if rng.random() < 0.5 else -1)
        f = sign * mag
        s = ms.saddle_value(*f)
        if abs(s) < 0.02:  # too close to call on a raster
            continue
        labels, _ = ndimage.label(_bilinear(f, uu, vv) > 0)
        ins = np.flatnonzero(f > 0)
        corner_px = [(0, 0), (px - 1, 0), (px - 1, px - 1), (0, px - 1)]
        la, lb = (labels[corner_px[c]] for c in ins)
        assert bool(ms.asymptotic_decider(*f)) == (la == lb), f
        checked += 1
    assert checked > 30
