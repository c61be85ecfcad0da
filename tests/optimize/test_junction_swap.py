"""Edge swaps on a multi-material surface (warpmesh.optimize.junction_swap): an interface
edge flips, a cap against a junction edge snaps its apex onto the curve, junction curves
keep their place, every label's boundary stays closed and oriented, nothing crosses."""

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.cells.quality import triangle_quality
from warpmesh.optimize.junction_swap import snap_pass, swap_edges, swap_pass
from warpmesh.optimize.label_smoothing import classify_edges

from .test_label_smoothing import _check_closed_oriented, _labels
from .test_multimaterial import _label_volumes


def _boxes():
    """Two stacked boxes (labels 1 and 2) in label 0: a junction loop at z = 5.5 where the
    three meet, the raw staircase (every square split along a diagonal)."""
    vol = np.zeros((10, 10, 12), np.uint8)
    vol[2:8, 2:8, 2:6] = 1
    vol[2:8, 2:8, 6:10] = 2
    return wm.mesh_surface(vol, labels="all", interfaces="shared")


def _pinched(junction: bool):
    """The staircase with one interface vertex c moved to 3 % of the way from the midpoint
    of the opposite edge ab of one of its triangles back to c: a cap of Q_K 19-30. ab is a
    junction edge (three triangles) when ``junction``, else the diagonal of a square of the
    side wall with one end on the junction loop (the flip's case). c's triangles are
    coplanar and stay so, none inverted. Returns (mesh, the cap's face, c, a, b)."""
    m = _boxes()
    p, t = m.points.copy(), m.triangles.astype(np.int64)
    a_e, b_e, feature, kind = classify_edges(t, *_labels(m), m.n_points)
    is_feature = dict(zip((a_e * m.n_points + b_e).tolist(), feature.tolist()))
    nrm = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    for f in range(len(t)):
        for j in range(3):
            c, a, b = t[f, j], t[f, (j + 1) % 3], t[f, (j + 2) % 3]
            star = np.flatnonzero((t == c).any(axis=1))
            flat = np.all(np.abs(np.cross(nrm[star], nrm[f])).max(axis=1) < 1e-12)
            on_ab = is_feature[min(a, b) * m.n_points + max(a, b)]
            diagonal = abs(np.linalg.norm(p[a] - p[b]) - np.sqrt(2.0)) < 1e-12
            wanted = on_ab if junction else (not on_ab and diagonal and (kind[a] == 1) != (kind[b] == 1))
            if kind[c] != 2 or not flat or not wanted:
                continue
            q = p.copy()
            mid = 0.5 * (p[a] + p[b])
            q[c] = mid + 0.03 * (p[c] - mid)
            n2 = np.cross(q[t[star, 1]] - q[t[star, 0]], q[t[star, 2]] - q[t[star, 0]])
            if np.all(np.einsum("ij,ij->i", n2, nrm[star]) > 0):
                return type(m)(q, {"triangle": t}, cell_refs=m.cell_refs, cell_data=m.cell_data,
                               info=m.info), f, c, a, b
    raise AssertionError("no vertex to pinch")


def _junction_edges(m):
    a, b, feature, _ = classify_edges(m.triangles, *_labels(m), m.n_points)
    return {(int(x), int(y)) for x, y in zip(a[feature], b[feature])}


def _check_honest(before, after):
    """The claims every swap keeps: labels closed, oriented, no crossing, pairs and volumes."""
    _check_closed_oriented(after)
    assert len(wm.check(after)) == 0
    lower, upper = _labels(after)
    assert len(lower) == len(upper) == after.n_cells and np.all(lower < upper)
    pairs0 = set(zip(*(x.tolist() for x in _labels(before))))
    assert set(zip(lower.tolist(), upper.tolist())) <= pairs0
    t = after.triangles
    assert len(np.unique(np.sort(t, axis=1), axis=0)) == len(t)
    v0, v1 = _label_volumes(before), _label_volumes(after)  # c moves in its flat star: volumes kept
    assert v0.keys() == v1.keys() and all(abs(v1[k] - v0[k]) <= 1e-9 * abs(v0[k]) for k in v0)


def test_flip_removes_an_interface_cap_next_to_a_junction():
    m, f, c, a, b = _pinched(junction=False)
    q0 = triangle_quality(m.points, m.triangles)
    assert q0.argmax() == f and q0[f] > 20  # the cap is the worst
    out = swap_edges(m)
    info = out.info["swap"]
    assert info["flips"] >= 1 and info["snaps"] == 0
    q1 = triangle_quality(out.points, out.triangles)
    assert q1.max() < 3.0 and info["after"]["q_worst"] == pytest.approx(q1.max())
    assert info["before"]["q_worst"] == pytest.approx(q0[f])
    # the long edge ab is gone, c now joins the vertex across it; the junction untouched
    edges = {tuple(sorted(e)) for e in out.triangles[:, [[0, 1], [1, 2], [2, 0]]].reshape(-1, 2).tolist()}
    assert (min(a, b), max(a, b)) not in edges
    assert _junction_edges(out) == _junction_edges(m)
    assert np.array_equal(out.points, m.points)
    _check_honest(m, out)


def test_snap_puts_the_apex_of_a_junction_cap_on_the_junction():
    m, f, c, a, b = _pinched(junction=True)
    q0 = triangle_quality(m.points, m.triangles)
    assert q0.argmax() == f and q0[f] > 15
    # a flip may not touch the junction edge ab: the flips alone leave the cap
    t_flipped = swap_pass(m.points, m.triangles, *_labels(m))
    assert triangle_quality(m.points, t_flipped).max() == pytest.approx(q0[f])
    out = swap_edges(m)
    info = out.info["swap"]
    assert info["snaps"] == 1
    q1 = triangle_quality(out.points, out.triangles)
    assert q1.max() < 3.0 < q0.max()
    # c lies on ab now, which is replaced by ac and cb; every other junction edge and every
    # vertex but c is where it was
    seg = m.points[b] - m.points[a]
    s = np.dot(out.points[c] - m.points[a], seg) / np.dot(seg, seg)
    assert 0.0 < s < 1.0 and np.linalg.norm(m.points[a] + s * seg - out.points[c]) < 1e-12
    old, new = _junction_edges(m), _junction_edges(out)
    ab = (min(a, b), max(a, b))
    assert new == (old - {ab}) | {(min(a, c), max(a, c)), (min(b, c), max(b, c))}
    others = np.arange(m.n_points) != c
    assert np.array_equal(out.points[others], m.points[others])
    assert out.n_cells == m.n_cells + 1  # the cap goes, the two other faces on ab split
    _check_honest(m, out)


def _fold_case(e_z):
    """A sliver (0, 1, 2) of the interface (1, 2) and its neighbour (1, 0, 3): flipping 0-1 to
    2-3 would give (0, 3, 2), which folds onto the triangle (2, 0, 4) of the pair (0, 1)
    hanging from the junction edge 0-2 at a few degrees above the plane."""
    p = np.array([[0, 0, 0], [2, 0, 0], [1, 0.05, 0], [1, -1.5, 0], [0.6, -0.9, e_z]], float)
    t = np.array([[0, 1, 2], [1, 0, 3], [2, 0, 4]])
    return p, t, np.array([1, 1, 0]), np.array([2, 2, 1])


def test_flip_refused_where_it_would_fold_onto_a_junction_face():
    p, t, lower, upper = _fold_case(0.08)
    counts = {}
    out = swap_pass(p, t, lower, upper, counts=counts)
    assert np.array_equal(out, t) and counts["flips"] == 0 and counts["refused"] == 1
    # the same sliver without the face of the other pair flips (the refusal is the fold's)
    counts = {}
    out = swap_pass(p, t[:2], lower[:2], upper[:2], counts=counts)
    assert counts["flips"] == 1 and sorted(map(sorted, out.tolist())) == [[0, 2, 3], [1, 2, 3]]
    # far above the plane the face does not fold: the flip goes
    p2, t2, lo2, up2 = _fold_case(2.0)
    assert swap_pass(p2, t2, lo2, up2, counts={})[:2].tolist() == [[0, 3, 2], [3, 1, 2]]


def test_a_refused_flip_does_not_block_its_neighbour():
    """The worse sliver A (0, 1, 2) wins the first batch, fails (its flip folds onto the
    junction face (2, 0, 4)) and is refused; its neighbour B (1, 5, 7), which shares the
    vertex 1 and so could not be in A's batch, flips in the next batch. (The flip pass
    before junction_swap chose the same failing batch on every call: B never flipped.)"""
    p, t, lower, upper = _fold_case(0.08)
    p = np.concatenate([p, [[4, 0, 0], [3, 0.1, 0], [3, -1.5, 0]]])  # 5, 6, 7
    t = np.concatenate([t, [[1, 5, 6], [5, 1, 7]]])
    lower, upper = np.append(lower, [1, 1]), np.append(upper, [2, 2])
    q = triangle_quality(p, t)
    assert q[0] > q[3] > 10  # A is worse than B
    counts = {}
    one = swap_pass(p, t, lower, upper, rounds=1, counts=counts)
    assert np.array_equal(one, t) and counts["refused"] == 1
    counts = {}
    two = swap_pass(p, t, lower, upper, rounds=2, counts=counts)
    assert counts == {"flips": 1, "refused": 1, "rounds": 1}
    assert np.array_equal(two[:3], t[:3]) and two[3:].tolist() == [[1, 7, 6], [7, 5, 6]]
    assert triangle_quality(p, two).max() == pytest.approx(q[0])


def _junction_fan(x1):
    """A closed star of the interface (1, 2) round c = 2 (a cap (0, 1, 2) with c 0.05 off the
    junction edge 0-1), the faces (1, 0, x1) of the pair (1, 3) and (0, 1, 6) of (2, 3) on 0-1."""
    p = np.array([[0, 0, 0], [2, 0, 0], [1, 0.05, 0], [2, 1.5, 0], [0, 1.5, 0], x1, [1, -1, -1]], float)
    t = np.array([[0, 1, 2], [1, 3, 2], [3, 4, 2], [4, 0, 2], [1, 0, 5], [0, 1, 6]])
    return p, t, np.array([1, 1, 1, 1, 1, 2]), np.array([2, 2, 2, 2, 3, 3])


def test_snap_refused_where_it_would_fold():
    """The snap of c onto the junction edge is made when the faces of the other labels hang
    away from c's star, refused when one lies over it, a few degrees off: the face (1, 0, 5)
    would then fold onto (4, 0, 2) across their new common edge 0-2."""
    p, t, lower, upper = _junction_fan([1, -1, 1])
    counts = {}
    p2, t2, lo2, up2 = snap_pass(p, t, lower, upper, counts=counts)
    assert counts["snaps"] == 1 and p2[2].tolist() == [1.0, 0.0, 0.0] and len(t2) == len(t) + 1
    assert sorted(map(tuple, t2[lo2 == 1][-2:].tolist())) == [(1, 2, 5), (2, 0, 5)]
    p, t, lower, upper = _junction_fan([1, 1.2, 0.1])
    counts = {}
    p2, t2, _, _ = snap_pass(p, t, lower, upper, counts=counts)
    assert counts["snaps"] == 0 and counts["refused"] == 1
    assert np.array_equal(t2, t) and np.array_equal(p2, p)


def test_bad_input_names_the_argument():
    m = _boxes()
    with pytest.raises(ValueError, match="'rounds'"):
        swap_edges(m, rounds=0)
    with pytest.raises(ValueError, match="'tolerance'"):
        swap_edges(m, tolerance=-1.0)
    plain = wm.Mesh(m.points, {"triangle": m.triangles})
    with pytest.raises(ValueError, match="'mesh'"):
        swap_edges(plain)
    p, t, lower, upper = _fold_case(0.08)
    with pytest.raises(ValueError, match="'upper'"):
        swap_pass(p, t, lower, upper[:2])
    with pytest.raises(ValueError, match="'t'"):
        snap_pass(p, t[:, :2], lower, upper)
    with pytest.raises(ValueError, match="'t'"):
        swap_pass(p, t + 3, lower, upper)
    with pytest.raises(ValueError, match="'rounds'"):
        swap_pass(p, t, lower, upper, rounds=0)
