"""Sheets out of order about a junction edge (warpmesh.cells.junctions): fans built by hand
(right order, swapped, flat sheets through the junction, coplanar near-ties decided by the
exact stage, coincident and degenerate faces), random fans against a reference written
here with angles (atan2 in a frame of the edge, well-separated angles), multi-material
surfaces from the mesher, the smoothing, the simplifier and the optimiser clean, and the
mesh's check seeing a turned face that no pair of triangles shows."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.cells import predicates
from warpmesh.cells.intersections import find_self_intersections
from warpmesh.cells.junctions import LABEL_ABOVE, LABEL_BELOW, find_junction_misorders

from tests.optimize.test_label_smoothing import _blobs, _noise
from tests.surface.test_multilabel import _random_tiles


def _labels(m):
    return m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"]


def _misorders(m):
    return find_junction_misorders(m.points, m.cells["triangle"], *_labels(m))


def _junction_edges(tris) -> int:
    """How many edges lie in three faces or more."""
    t = np.asarray(tris, dtype=np.int64)
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e[:, 0] * (t.max() + 1) + e[:, 1], return_counts=True)
    return int((counts >= 3).sum())


# -- a fan: faces about the edge (0, 1), apexes given, labels from the gaps ----------------


def _fan(apexes, gaps, forward, edge=((0, 0, 0), (0, 0, 1))):
    """Points, triangles and (lower, upper) of faces about the edge 0 -> 1, face i with apex
    ``apexes[i]`` lying between gap i - 1 (clockwise) and gap i (counter-clockwise) of
    labels ``gaps``; ``forward[i]``: face i runs 0 -> 1 (its normal counter-clockwise, so its
    front, the upper label, is gap i), else 1 -> 0."""
    pts = np.array([*edge, *apexes], dtype=float)
    tris, lower, upper = [], [], []
    for i, fw in enumerate(forward):
        cw, ccw = gaps[i - 1], gaps[i]
        tris.append([0, 1, i + 2] if fw else [1, 0, i + 2])
        lower.append(cw if fw else ccw)
        upper.append(ccw if fw else cw)
    return pts, np.array(tris), np.array(lower), np.array(upper)


def test_three_sheets_in_order_clean_and_reversed_reported():
    apexes = [(1, 0, 0), (-1, 1, 0), (-1, -1, 0)]  # 0, 135, 225 degrees about +z
    pts, tris, lower, upper = _fan(apexes, [1, 2, 3], [True, False, True])
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.edges.size == r.pairs.size == r.undecided.size == 0
    # the second face turned into the other gap (315 degrees): every gap wrong
    pts[3] = (1, -1, 0)
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.edges.tolist() == [[0, 1]] and r.pairs.tolist() == [[0, 1], [0, 2], [1, 2]]
    assert len(find_self_intersections(pts, tris)) == 0  # no pair of triangles shows it


def test_two_of_four_swapped():
    """Four sheets (labels 1..4 in the gaps); faces 1 and 2 exchanging their places breaks
    three gaps: the pairs named are the faces now next to each other across them."""
    apexes = [(1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0)]
    pts, tris, lower, upper = _fan(apexes, [1, 2, 3, 4], [True, True, False, True])
    assert find_junction_misorders(pts, tris, lower, upper).edges.size == 0
    pts[[3, 4]] = pts[[4, 3]]
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.edges.tolist() == [[0, 1]]
    assert r.pairs.tolist() == [[0, 2], [1, 2], [1, 3]]  # order now 0, 2, 1, 3; gap 3 -> 0 still right


def test_flat_sheet_through_the_junction_exact():
    """Faces at exactly 0 and 180 degrees (one plane) about an edge off the axes (no shared
    coordinate: the exact integer stage decides the ties), a third at 90 degrees: clean with
    the labels of that order; the same faces and labels with the third at 270: reported."""
    e = np.array([1, 2, 3])
    p = np.array([3, 0, -1])  # p . e = 0
    q = np.cross(e, p)  # 90 degrees from p about e
    pts, tris, lower, upper = _fan([p, q + e, -p + 2 * e], [5, 6, 7], [True, True, False], edge=((0, 0, 0), e))
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.edges.size == r.undecided.size == 0
    pts[3] = -q - e
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.edges.tolist() == [[0, 1]] and r.undecided.size == 0


@pytest.mark.parametrize("sign", [1, -1])
def test_coplanar_near_tie_decided_exactly(sign, monkeypatch):
    """A face at exactly 180 degrees and another 2^-31 (relative 1e-15) to one side of it:
    which side decides the cyclic order, and the float filter cannot (the exact stage runs)."""
    big = 2.0**20
    e = big * np.array([1.0, 2.0, 3.0])
    p = big * np.array([3.0, 0.0, -1.0])
    w = np.cross([1.0, 2.0, 3.0], [3.0, 0.0, -1.0])  # counter-clockwise from p about e
    flat = -p + 0.5 * e  # exactly 180 degrees
    near = -p + 0.25 * e + sign * 2.0**-31 * w  # just before 180 degrees (sign 1) or just after
    assert np.array_equal(near - (-p + 0.25 * e), sign * 2.0**-31 * w)  # representable
    calls = []
    exact = predicates._exact
    monkeypatch.setattr(predicates, "_exact", lambda *a: calls.append(1) or exact(*a))
    # gaps: 1 from 0 to the near face, 2 to the flat one, 3 back to 0 (valid for sign 1)
    pts, tris, lower, upper = _fan([p, near, flat], [1, 2, 3], [True, True, False], edge=((0, 0, 0), e))
    r = find_junction_misorders(pts, tris, lower, upper)
    assert calls
    assert len(r.edges) == (0 if sign == 1 else 1)


def test_coincident_faces_reported():
    """Two faces in one half-plane overlap: reported as a pair whatever the labels; a face
    on the opposite half-plane of the same plane is not."""
    apexes = [(1, 0, 0), (2, 0, 0.5), (0, 1, 0), (-1, 0, 0)]
    pts, tris, lower, upper = _fan(apexes, [1, 2, 3, 4], [True, True, True, True])
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.edges.tolist() == [[0, 1]] and r.pairs.tolist() == [[0, 1]]
    assert [0, 1] in find_self_intersections(pts, tris).tolist()  # folded onto each other


def test_degenerate_face_undecided():
    """A face whose apex is on the edge's line has no angle: the edge is returned as
    undecided and no pair is reported; a repeated index the same."""
    apexes = [(1, 0, 0), (0, 0, 3), (-1, 1, 0)]
    pts, tris, lower, upper = _fan(apexes, [1, 2, 3], [True, True, True])
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.undecided.tolist() == [[0, 1]] and r.edges.size == 0 and r.pairs.size == 0
    tris[1] = [0, 1, 1]
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.undecided.tolist() == [[0, 1]] and r.edges.size == 0 and r.pairs.size == 0


def test_labels_no_order_satisfies_undecided():
    """A label on more counter-clockwise sides than clockwise ones (an open boundary): no
    order can be right, the edge is undecided, not reported."""
    pts, tris, lower, upper = _fan([(1, 0, 0), (-1, 1, 0), (-1, -1, 0)], [1, 2, 3], [True, True, True])
    upper[0] = 9
    r = find_junction_misorders(pts, tris, lower, upper)
    assert r.undecided.tolist() == [[0, 1]] and r.edges.size == 0


def _reference(pts, tris, lower, upper):
    """Edges of 3+ faces whose gaps disagree, by atan2 angles in a frame of each edge."""
    out = set()
    edges = {}
    for f, t in enumerate(tris.tolist()):
        for k in range(3):
            u, v, c = t[k], t[(k + 1) % 3], t[(k + 2) % 3]
            edges.setdefault((min(u, v), max(u, v)), []).append((f, c, u < v))
    for (a, b), faces in edges.items():
        if len(faces) < 3:
            continue
        e = pts[b] - pts[a]
        x = pts[faces[0][1]] - pts[a]
        x = x - e * (x @ e) / (e @ e)
        y = np.cross(e / np.linalg.norm(e), x)
        ang = [np.arctan2((pts[c] - pts[a]) @ y, (pts[c] - pts[a]) @ x) % (2 * np.pi) for _, c, _ in faces]
        s = [faces[i] for i in np.argsort(ang)]
        ccw = [upper[f] if fw else lower[f] for f, _, fw in s]
        cw = [lower[f] if fw else upper[f] for f, _, fw in s]
        if any(ccw[i] != cw[(i + 1) % len(s)] for i in range(len(s))):
            out.add((a, b))
    return out


def test_random_fans_against_angles():
    """200 fans of 3 to 7 faces in one mesh (random edge directions and vertex numbers,
    random face directions), labelled right for their angles, then half of them with
    their apexes permuted: the edges reported are the reference's, and only those."""
    rng = np.random.default_rng(7)
    pts, tris, lower, upper = [], [], [], []
    for k in range(200):
        d = int(rng.integers(3, 8))
        e = rng.normal(size=3)
        x = np.cross(e, rng.normal(size=3))
        x /= np.linalg.norm(x)
        y = np.cross(e / np.linalg.norm(e), x)
        ang = np.sort(rng.choice(np.arange(36), d, replace=False)) * (2 * np.pi / 36)  # 10 degrees apart at least
        apexes = [rng.uniform(0.5, 2) * (np.cos(t) * x + np.sin(t) * y) + rng.uniform(-1, 2) * e for t in ang]
        gaps = [int(g) for g in rng.integers(0, 4, d)]
        for i in range(d):  # neighbouring gaps of different labels
            if gaps[i] == gaps[i - 1]:
                gaps[i] = gaps[i - 1] + 10
        fp, ft, fl, fu = _fan(apexes, gaps, rng.random(d) < 0.5, edge=((0, 0, 0), e))
        if k % 2:
            fp[2:] = fp[2 + rng.permutation(d)]
        base = sum(len(q) for q in pts)
        pts.append(fp + rng.normal(size=3))
        tris.append(ft + base)
        lower.append(fl)
        upper.append(fu)
    pts, tris, lower, upper = np.concatenate(pts), np.concatenate(tris), np.concatenate(lower), np.concatenate(upper)
    perm = rng.permutation(len(pts))  # vertex numbers shuffled: edges run either way
    pts, tris = pts[np.argsort(perm)], perm[tris]
    order = rng.permutation(len(tris))
    tris, lower, upper = tris[order], lower[order], upper[order]
    ref = _reference(pts, tris, lower, upper)
    r = find_junction_misorders(pts, tris, lower, upper)
    assert {tuple(x) for x in r.edges.tolist()} == ref
    assert 40 < len(ref) < 100 and r.undecided.size == 0
    # each reported pair: two faces of a reported edge
    assert all(len(set(tris[i]) & set(tris[j])) >= 2 for i, j in r.pairs.tolist())


def test_unlabelled_two_cubes_on_an_edge():
    """Without labels each face separates inside (back) from outside: two unit cubes
    touching along an edge side by side alternate out, in, out, in: clean; the faces of
    one cube's wedge swapped into the other's (interleaved): reported."""
    # cube A in the quadrant x < 0, y < 0 about the z axis, cube B in x > 0, y > 0; normals out
    apexes = [(1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0)]
    # faces at 0 (B's bottom wall: normal -y, clockwise), 90 (B's, ccw), 180 (A's, cw), 270 (A's, ccw)
    pts, tris, _, _ = _fan(apexes, [0, 0, 0, 0], [False, True, False, True])
    assert find_junction_misorders(pts, tris).edges.size == 0
    pts[[3, 4]] = pts[[4, 3]]  # B's second wall at 180, A's first at 90
    assert find_junction_misorders(pts, tris).edges.tolist() == [[0, 1]]


# -- surfaces the package makes --------------------------------------------------------------


def test_random_label_tiles_clean():
    """40 random 5^3 label tiles (0 to 4 labels each) meshed as one shared surface: junction
    edges by the thousand, none out of order, none undecided; without caps the only undecided
    edges are where the open surface meets the box."""
    vol = _random_tiles(seed=3, n_tiles=40)
    m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    assert _junction_edges(m.cells["triangle"]) > 1000
    r = _misorders(m)
    assert r.edges.size == r.pairs.size == r.undecided.size == 0
    m = wm.mesh_surface(vol, labels="all", interfaces="shared", cap=False, spacing=(1.0, 0.7, 1.9))
    r = _misorders(m)
    assert r.edges.size == 0 and len(r.undecided)
    lo, hi = m.points.min(axis=0), m.points.max(axis=0)
    ends = m.points[r.undecided]  # (u, 2, 3)
    assert np.all(((ends == lo) | (ends == hi)).any(axis=2))


def test_smoothed_simplified_optimized_clean():
    """A 3-label blob volume smoothed (16 passes), then optimised (one iteration), and a
    noise volume simplified to half: no junction edge out of order, through the mesh's
    check too."""
    raw = wm.mesh_surface(_blobs(0, 3, shape=(10, 11, 12)), labels="all", interfaces="shared")
    from warpmesh.optimize.label_remesh import optimize_labels
    from warpmesh.optimize.label_smoothing import smooth_labels
    from warpmesh.optimize.multimaterial import simplify_labels

    smooth = smooth_labels(raw, 16)
    noisy = wm.mesh_surface(_noise(3, 3, shape=(6, 7, 8)), labels="all", interfaces="shared")
    for m in (smooth, optimize_labels(smooth, size=None, iterations=1), simplify_labels(noisy, 0.5)):
        assert _junction_edges(m.cells["triangle"]) > 50
        r = _misorders(m)
        assert r.edges.size == r.undecided.size == 0
        assert len(wm.check(m)) == 0


def _turned_face_mesh():
    """Two boxes (labels 1 below, 2 above) in a background 0, and the copy where the 1 | 2
    face at one junction edge of the outer wall is turned outward (a new apex a tenth of a
    voxel away, in the background), labels and direction kept."""
    vol = np.zeros((6, 6, 6), np.uint8)
    vol[1:5, 1:5, 1:3] = 1
    vol[1:5, 1:5, 3:5] = 2
    m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    lower, upper = _labels(m)
    tris = m.cells["triangle"]
    mid = np.flatnonzero((lower == 1) & (upper == 2))
    pts = m.points
    for f in mid:  # a 1 | 2 face with an edge on the outer wall (x = 0.5)
        on = pts[tris[f], 0] == pts[tris[mid].ravel(), 0].min()
        if on.sum() == 2:
            break
    k = int(np.flatnonzero(~on)[0])
    a, b = tris[f][on]
    apex = pts[tris[f][k]]
    foot = 0.5 * (pts[a] + pts[b])
    new = foot + 0.1 * (foot - apex) / np.linalg.norm(foot - apex)  # mirrored, near the edge
    assert new[0] < pts[a][0]  # outside the wall
    turned = tris.copy()
    turned[f, k] = len(pts)
    return m, m.replace(points=np.vstack([pts, new]), cells={"triangle": turned}), f


def test_check_sees_a_turned_face_the_pairwise_check_does_not():
    m, bad, f = _turned_face_mesh()
    assert len(m.check()) == 0 and m.stats()["self_intersections"] == 0
    tris = bad.cells["triangle"]
    assert len(find_self_intersections(bad.points, tris)) == 0  # no two triangles cross ...
    pairs = wm.check(bad)  # ... but the sheets do, along the edge: three faces, every gap wrong
    assert len(pairs) == 3 and sum(f in p for p in pairs.tolist()) == 2
    assert np.array_equal(bad.check(), pairs) and bad.stats()["self_intersections"] == len(pairs)
    r = _misorders(bad)
    assert len(r.edges) == 1 and set(r.edges[0].tolist()) <= set(tris[f].tolist())
    # one ref per interface, the lower labels in cell data (as for a .msh file): the same pairs
    from warpmesh.surface.multilabel import interface_refs

    assert np.array_equal(wm.check(interface_refs(bad)), pairs)
    # labels read back from a file as whole-number floats are labels; fractional ones are not
    above = bad.cell_data["label_above"]["triangle"]
    assert np.array_equal(wm.check(bad.replace(cell_data={"label_above": {"triangle": above * 1.0}})), pairs)
    assert len(wm.check(bad.replace(cell_data={"label_above": {"triangle": above + 0.5}}))) == 0
    # without the label arrays the mesh's check is the pairwise one
    plain = bad.replace(cell_refs=None, cell_data={})
    assert len(wm.check(plain)) == 0


def test_label_array_names_are_the_mesher_s():
    from warpmesh.surface.multilabel import LABEL_ABOVE as mesher
    from warpmesh.surface.multilabel import interface_refs

    assert LABEL_ABOVE == mesher
    vol = np.zeros((4, 4, 4), np.uint8)
    vol[1:3, 1:3, 1:3] = 1
    assert LABEL_BELOW in interface_refs(wm.mesh_surface(vol, labels="all", interfaces="shared")).cell_data


def test_bad_input_names_the_argument():
    pts, tris, lower, upper = _fan([(1, 0, 0), (-1, 1, 0), (-1, -1, 0)], [1, 2, 3], [True] * 3)
    with pytest.raises(TypeError, match="'points'"):
        find_junction_misorders(pts.astype(str), tris)
    with pytest.raises(ValueError, match="'points'"):
        find_junction_misorders(pts[:, :2], tris)
    with pytest.raises(ValueError, match="'points'"):
        find_junction_misorders(np.where(pts == 1, np.nan, pts), tris)
    with pytest.raises(TypeError, match="'triangles'"):
        find_junction_misorders(pts, tris.astype(float))
    with pytest.raises(ValueError, match="'triangles'"):
        find_junction_misorders(pts, tris[:, :2])
    with pytest.raises(ValueError, match="'triangles'"):
        find_junction_misorders(pts, tris + 3)
    with pytest.raises(ValueError, match="'lower'"):
        find_junction_misorders(pts, tris, lower=lower)
    with pytest.raises(ValueError, match="'upper'"):
        find_junction_misorders(pts, tris, lower, upper[:2])
    with pytest.raises(TypeError, match="'lower'"):
        find_junction_misorders(pts, tris, lower + 0.5, upper)
    with pytest.raises(ValueError, match="'axis'"):
        predicates.orient2d_signs(pts, [0], [1], [2], 3)


def test_predicates_exact_against_fractions():
    """Signs on random rows with near-ties (points on a plane and a line, nudged by an ulp) and
    exact ties off the axes, against Fractions."""
    rng = np.random.default_rng(1)
    base = rng.integers(-8, 9, size=(40, 3)).astype(float)
    e, f = rng.integers(-5, 6, size=(2, 3)).astype(float)
    plane = base[:20, :1] * e + base[:20, 1:2] * f  # on the plane through 0 spanned by e, f
    line = base[20:, :1] * e  # on a line
    pts = np.vstack([plane, line, np.nextafter(plane[:10], np.inf)]) * 0.37
    pts = predicates.power_of_two_scaled(pts)
    fr = [[Fraction(x) for x in row] for row in pts.tolist()]

    def o3(a, b, c, d):
        u, v, w = ([fr[i][k] - fr[a][k] for k in range(3)] for i in (b, c, d))
        return (u[0] * (v[1] * w[2] - v[2] * w[1]) + u[1] * (v[2] * w[0] - v[0] * w[2])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))

    def o2(a, b, c, k):
        i, j = (k + 1) % 3, (k + 2) % 3
        return (fr[b][i] - fr[a][i]) * (fr[c][j] - fr[a][j]) - (fr[b][j] - fr[a][j]) * (fr[c][i] - fr[a][i])

    rows = rng.integers(0, len(pts), size=(600, 4))
    got = predicates.orient3d_signs(pts, *rows.T)
    want = [int(np.sign(o3(*r))) for r in rows.tolist()]
    assert got.tolist() == want and 0 in want and len(set(want)) == 3
    for k in range(3):
        got = predicates.orient2d_signs(pts, *rows[:, :3].T, k)
        assert got.tolist() == [int(np.sign(o2(*r[:3], k))) for r in rows.tolist()]
