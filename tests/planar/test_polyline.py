"""Polyline assembly: chains by list ranking, components, orientation, intersections, weld."""

import numpy as np

from warpmesh.cells.intersections import find_segment_intersections
from warpmesh.planar.polyline import chain_segments, chains, components, orient_segments, weld

RNG = np.random.default_rng(11)


def _cycle(verts):
    v = np.asarray(verts)
    return np.column_stack([v, np.roll(v, -1)])


def test_chains_recover_shuffled_cycles_and_paths():
    a, b = RNG.permutation(500), 500 + RNG.permutation(300)
    path = np.arange(800, 810)
    segs = np.vstack([_cycle(a), _cycle(b), np.column_stack([path[:-1], path[1:]])])
    out = chains(segs[RNG.permutation(len(segs))], 810)
    assert sorted((len(c), closed) for c, closed in out) == [(10, False), (300, True), (500, True)]
    for c, closed in out:
        back = chain_segments(c, closed)
        assert {tuple(s) for s in back} <= {tuple(s) for s in segs}  # same directions, consecutive
        if closed:
            assert c[0] == c.min()
    path_chain = next(c for c, closed in out if not closed)
    assert path_chain.tolist() == path.tolist()


def test_chains_break_at_a_vertex_of_degree_four():
    # a figure eight through vertex 0: two loops 0-1-2-0 and 0-3-4-0
    segs = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [3, 4], [4, 0]])
    out = chains(segs, 5)
    assert all(not closed for _, closed in out)
    assert sum(len(c) - 1 for c, _ in out) == 6  # every segment used once
    assert components(segs, 5)[0] == 1


def test_components_count_and_labels():
    segs = np.vstack([_cycle([0, 1, 2]), _cycle([3, 4, 5, 6])])
    n, lab = components(segs, 9)
    assert n == 2 and lab[7] == -1 and lab[8] == -1 and lab[0] != lab[3]


def test_orient_segments_puts_the_domain_on_the_left():
    t = np.linspace(0, 2 * np.pi, 40, endpoint=False)
    pts = np.column_stack([np.cos(t), np.sin(t)])
    segs = _cycle(np.arange(40))
    flipped = segs.copy()
    flipped[::3] = flipped[::3, ::-1]
    mid = 0.5 * (pts[flipped[:, 0]] + pts[flipped[:, 1]])
    out = orient_segments(pts, flipped, -mid)  # f = 1 - |p|: grad f = -p / |p|, the disc inside
    assert np.array_equal(out, segs)  # counterclockwise around the disc


def test_segment_intersections_finds_crossings_only():
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    segs = _cycle(np.arange(200))
    assert len(find_segment_intersections(circle, segs)) == 0
    pts = np.vstack([circle, [[-2.0, 0.01], [2.0, 0.01]]])
    hits = find_segment_intersections(pts, np.vstack([segs, [[200, 201]]]))
    assert len(hits) == 2 and np.all(hits[:, 1] == 200)
    # a long segment spanning many buckets against many short ones
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert len(find_segment_intersections(square, np.array([[0, 2], [1, 3]]))) == 1


def test_weld_merges_close_points_and_drops_collapsed_segments():
    pts = np.array([[0, 0], [1, 0], [1 + 1e-12, 0], [2, 0]], float)
    p, s = weld(pts, np.array([[0, 1], [2, 3], [1, 2]]), 1e-9)
    assert len(p) == 3 and s.tolist() == [[0, 1], [1, 2]]
