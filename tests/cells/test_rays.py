"""warpmesh.cells.rays: winding numbers by signed ray crossings, against solid angles and
exact arithmetic; ties on grid-aligned input; candidates linear in faces + points."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
import trimesh

from warpmesh.cells import rays
from warpmesh.cells.rays import ray_windings

UNIT = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
TET = UNIT[[[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]]  # a positive tet's faces, outward


def _shells(rng, n_spheres, n_cubes):
    """Closed shells in one face list: icospheres of random centres and radii and integer
    cubes (grid-aligned faces: the rays' ties), some turned inside out."""
    pts, faces, label = [], [], []
    for k in range(n_spheres + n_cubes):
        if k < n_spheres:
            s = trimesh.creation.icosphere(1, radius=rng.uniform(0.3, 2.0))
            v, f = s.vertices + rng.uniform(-1.5, 1.5, 3), s.faces
        else:
            s = trimesh.creation.box(extents=rng.integers(1, 5, 3).astype(float))
            v, f = s.vertices + rng.integers(-2, 3, 3) + 0.5 * (rng.integers(1, 5, 3) % 2), s.faces
        if rng.random() < 0.3:
            f = f[:, ::-1]
        faces.append(f + sum(len(p) for p in pts))
        pts.append(v)
        label.append(np.full(len(f), k))
    pts, faces, label = np.vstack(pts), np.vstack(faces), np.concatenate(label)
    return pts[faces], label


def _dense(point, group, winding, n_points, n_groups):
    out = np.zeros((n_points, n_groups), dtype=np.int64)
    out[point, group] = winding
    return out


def _solid(corners, label, q, skip):
    """Every (point, group) winding number by rounded solid angles (the reference)."""
    n = int(label.max()) + 1
    want = np.rint([rays._solid_angle_windings(corners[label == g], q) for g in range(n)]).T.astype(np.int64)
    want[np.arange(len(q)), skip] = 0
    return want


@pytest.fixture(params=["coverage", "few points"])
def plan(request, monkeypatch):
    """Both plans of :func:`rays._plan`: per-point axes by coverage, and (as for a few
    points against many faces) x for all with each axis's faces found on demand."""
    monkeypatch.setattr(rays, "_FEW_POINTS", 0 if request.param == "coverage" else 10**9)
    return request.param


@pytest.mark.parametrize("seed", range(3))
def test_windings_equal_solid_angles_on_nested_overlapping_inside_out_shells(seed, plan):
    # icospheres and integer cubes (grid planes: ties), some inside out, overlapping or
    # nested; each point (a face centroid of one shell) against every other shell
    rng = np.random.default_rng(seed)
    ties = 0
    for _ in range(8):
        corners, label = _shells(rng, 4, 4)
        order = np.argsort(label, kind="stable")
        first = order[np.searchsorted(label[order], np.arange(8))]
        q, skip = corners[first].mean(axis=1), np.arange(8)
        point, group, winding, report = ray_windings(corners, label, q, skip=skip)
        assert np.array_equal(_dense(point, group, winding, 8, 8), _solid(corners, label, q, skip))
        assert np.all(np.diff(point * 8 + group) > 0)  # sorted, one row per pair
        ties += report["ties"][0]
    assert ties > 0  # the redo path ran


def test_every_axis_ties_then_solid_angles(plan):
    # integer cubes, queries on grid points: rays run through edges and vertices of the
    # projected faces. q = (0, 0, 0) is the centre of cube 1, on the diagonals splitting
    # its square faces: its rays along x, y and z all tie, solid angles decide
    rng = np.random.default_rng(7)
    lo0 = np.array([[5, 5, 5], [-2, -2, -2], [1, 1, 1], [-1, -1, 1], [6, 6, 6], [5, 0, 0], [0, 5, 0], [-5, -5, -5]], float)
    hi0 = lo0 + [[1, 1, 1], [4, 4, 4], [1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 1, 1], [9, 9, 9]]
    solid = 0
    for trial in range(6):
        lo = lo0 if trial == 0 else rng.integers(-3, 3, (8, 3)).astype(float)
        hi = hi0 if trial == 0 else lo + rng.integers(1, 4, (8, 3))
        corners, label = [], []
        for k in range(8):
            s = trimesh.creation.box(bounds=[lo[k], hi[k]])
            corners.append(s.vertices[s.faces] if k % 3 else s.vertices[s.faces[:, ::-1]])
            label.append(np.full(len(s.faces), k))
        corners, label = np.vstack(corners), np.concatenate(label)
        q = [] if trial else [np.zeros(3)]
        while len(q) < 8:  # grid points (half-integers on some axes), off every cube's surface
            x = rng.integers(-6, 12, 3) / (2.0 if len(q) % 2 else 1.0)
            inside = np.all((lo <= x) & (x <= hi), axis=1)
            if not (inside & np.any((x == lo) | (x == hi), axis=1)).any():
                q.append(x)
        q = np.array(q)
        skip = np.full(8, -1)
        point, group, winding, report = ray_windings(corners, label, q, skip=skip)
        want = np.array([[int(np.all((lo[g] < x) & (x < hi[g]))) * (1 if g % 3 else -1) for g in range(8)] for x in q])
        assert np.array_equal(_dense(point, group, winding, 8, 8), want)
        if trial == 0:
            assert report["solid_angles"] >= 1 and min(report["ties"]) >= 1
        solid += report["solid_angles"]
    assert solid >= 1


def test_solid_angles_in_blocks_equal_containment():
    # the fallback's batched windings, in blocks of a few pairs and in one block, against
    # containment in boxes (inside out: -1), for points of every block boundary
    rng = np.random.default_rng(3)
    for k in range(4):
        lo = rng.integers(-3, 3, 3).astype(float)
        hi = lo + rng.integers(1, 4, 3)
        s = trimesh.creation.box(bounds=[lo, hi])
        faces = s.vertices[s.faces] if k % 2 else s.vertices[s.faces[:, ::-1]]
        q = rng.integers(-8, 16, (101, 3)) / 2.0 + 0.25  # never on a box face
        want = np.all((lo < q) & (q < hi), axis=1).astype(np.int64) * (1 if k % 2 else -1)
        for pairs in (1, 5 * len(faces), 1 << 20):
            assert np.array_equal(np.rint(rays._solid_angle_windings(faces, q, pairs=pairs)).astype(np.int64), want)


def test_signs_are_exact_or_ties():
    # near-degenerate faces and points within rounding of their edges and planes: every
    # certain answer of the float64 filter (crossing, sign) equals exact rational
    # arithmetic; the bound on the plane side covers the rounding of the normal
    rng = np.random.default_rng(11)
    n = 3000
    t = rng.uniform(-1, 1, (n, 3, 3)) * rng.choice([1.0, 1e-8, 1e8], (n, 1, 1))
    t[: n // 3, 2] = t[: n // 3, 0] + rng.uniform(0, 1, (n // 3, 1)) * (t[: n // 3, 1] - t[: n // 3, 0])  # slivers
    ab = rng.uniform(0, 0.5, (n, 2))
    x = t[:, 0] + ab[:, :1] * (t[:, 1] - t[:, 0]) + ab[:, 1:] * (t[:, 2] - t[:, 0])  # on the plane, rounded
    x[::2] -= rng.choice([0.0, 1e-15, 1.0], (n // 2, 1)) * (t[::2].max(axis=1) - t[::2].min(axis=1))
    x[1::4, 1] = t[1::4, 0, 1]  # on an edge's end in (y, z)
    certain = 0
    for axis in range(3):
        sign, tie = rays._face_signs(t, x, axis)
        i, j = (axis + 1) % 3, (axis + 2) % 3
        for k in np.flatnonzero(~tie):
            tf = [[Fraction(float(c)) for c in p] for p in t[k]]
            xf = [Fraction(float(c)) for c in x[k]]
            o2 = [(v[i] - u[i]) * (xf[j] - u[j]) - (v[j] - u[j]) * (xf[i] - u[i])
                  for u, v in ((tf[0], tf[1]), (tf[1], tf[2]), (tf[2], tf[0]))]
            crossed = 0
            if all(o > 0 for o in o2) or all(o < 0 for o in o2):
                a, b, c = ([p[d] - xf[d] for d in range(3)] for p in tf)
                det = (a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2])
                       + a[2] * (b[0] * c[1] - b[1] * c[0]))
                assert det != 0  # a certain plane side
                crossed = (1 if o2[0] > 0 else -1) if det * o2[0] > 0 else 0
            if 0 in o2:  # certain only because two other sides differ: no crossing
                assert min(o2) < 0 < max(o2)
            assert sign[k] == crossed, (axis, k)
            certain += 1
    assert 0 < certain < 3 * n  # some answered, some ties


def test_many_nested_shells_make_linear_candidates():
    # the review's case scaled down: n small tetrahedra nested in a sphere of 5,120 faces
    # (a lattice turned off the axes), and tets in a row along y, along x and a cross of
    # three rows inside a big tet (one axis of candidates gave n^2 pairs there). Candidate
    # pairs stay within a few times faces + points (a lost candidate would lose a crossing):
    # every small shell has winding 1, the outer 0 at its own point
    sphere = trimesh.creation.icosphere(4, radius=1.0)
    outer = sphere.vertices[sphere.faces]
    turn = trimesh.transformations.random_rotation_matrix(np.random.default_rng(1).random(3))[:3, :3]
    for n in (1000, 8000):
        k = round(n ** (1 / 3))
        g = (np.arange(k) - (k - 1) / 2) / k
        centre = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3) @ turn.T
        corners = np.concatenate([outer, (0.3 / k * TET[None] + centre[:, None, None]).reshape(-1, 3, 3)])
        label = np.r_[np.zeros(len(outer), int), np.repeat(np.arange(1, len(centre) + 1), 4)]
        q = np.r_[outer[:1].mean(axis=1), (0.3 / k * TET[0].mean(axis=0) + centre)]
        point, group, winding, report = ray_windings(corners, label, q, skip=np.arange(len(q)))
        assert np.array_equal(point, np.arange(1, len(q))) and np.all(group == 0) and np.all(winding == 1)
        assert report["candidates"] < 2 * (len(corners) + len(q)), (n, report)
    n = 2000
    rows = [np.column_stack([2.0 * np.arange(n) * (k == a) for k in range(3)]) for a in (1, 0)]
    rows.append(np.column_stack([2.0 * (np.arange(n) % 3 == k) * (np.arange(n) // 3 + 1) for k in range(3)]))
    for offsets in rows:
        big = 3.0 * offsets.max() + 10.0
        corners = np.concatenate([(TET[None] + offsets[:, None, None]).reshape(-1, 3, 3), big * TET - 4.0])
        label = np.repeat(np.arange(n + 1), 4)
        q = corners[4 * np.arange(n + 1)].mean(axis=1)
        point, group, winding, report = ray_windings(corners, label, q, skip=np.arange(n + 1))
        assert np.array_equal(point, np.arange(n)) and np.all(group == n) and np.all(winding == 1)
        assert report["candidates"] < 4 * (len(corners) + len(q)), report  # n^2 = 4 M before


@pytest.mark.parametrize("scale", [2.0**-1000, 1e-200, 1.0, 1e300])
def test_scale_does_not_matter(scale):
    corners = np.concatenate([TET, 4.0 * TET - 1.0, TET[:, ::-1] + 5.0]) * scale
    q = np.array([[0.2, 0.2, 0.2], [0.1, 0.1, 0.5], [5.2, 5.2, 5.2]]) * scale
    point, group, winding, report = ray_windings(corners, np.repeat([0, 1, 2], 4), q, skip=[-1, 0, -1])
    assert (point.tolist(), group.tolist(), winding.tolist()) == ([0, 0, 1, 2], [0, 1, 1, 2], [1, 1, 1, -1])


def test_no_points_or_no_faces():
    p, g, w, report = ray_windings(np.zeros((0, 3, 3)), np.zeros(0, int), np.zeros((2, 3)))
    assert len(p) == len(g) == len(w) == 0 and report["candidates"] == 0
    p, g, w, report = ray_windings(TET, np.zeros(4, int), np.zeros((0, 3)))
    assert len(p) == 0


def test_bad_input_is_named():
    label = np.zeros(4, int)
    with pytest.raises(ValueError, match="finite coordinates in 'triangles'"):
        ray_windings(np.where(TET == 1, np.nan, TET), label, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="finite coordinates in 'points'"):
        ray_windings(TET, label, [[0.1, np.inf, 0.1]])
    with pytest.raises(ValueError, match=r"'triangles' of shape \(F, 3, 3\)"):
        ray_windings(TET[:, :2], label, np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"'points' of shape \(Q, 3\)"):
        ray_windings(TET, label, np.zeros(3))
    with pytest.raises(TypeError, match="float array for 'points'"):
        ray_windings(TET, label, [["a", "b", "c"]])
    with pytest.raises(ValueError, match=r"'label' of shape \(4,\)"):
        ray_windings(TET, label[:3], np.zeros((1, 3)))
    with pytest.raises(TypeError, match="integer array for 'label'"):
        ray_windings(TET, label + 0.5, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="labels >= 0 in 'label'"):
        ray_windings(TET, label - 1, np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"values in \[-1, 1\) in 'skip'"):
        ray_windings(TET, label, np.zeros((1, 3)), skip=[1])
    with pytest.raises(ValueError, match=r"'skip' of shape \(1,\)"):
        ray_windings(TET, label, np.zeros((1, 3)), skip=[0, 0])
