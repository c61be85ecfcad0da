"""Every kind of mesh shows: curves as ribbons, 2D meshes from above, volume meshes cut open."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.preview.drawable import Drawable, drawable
from warpmesh.preview.render import mesh_html, render_png

BOX2 = ((-1.2, -1.2), (1.2, 1.2))
BOX3 = ((-1.2,) * 3, (1.2,) * 3)


@pytest.fixture(scope="module")
def curve():
    return wm.mesh_curve(wm.circle(1.0), bounds=BOX2)


@pytest.fixture(scope="module")
def shell():
    return wm.mesh_domain(wm.sphere(1.0) - wm.sphere(0.5), bounds=BOX3, size=0.25)


def _boundary_faces(tets: np.ndarray) -> set:
    """Faces lying in one tetrahedron only, as sorted vertex triples (an oracle of our own)."""
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]], tets[:, [0, 1, 2]]])
    keys, counts = np.unique(np.sort(faces, axis=1), axis=0, return_counts=True)
    return {tuple(k) for k in keys[counts == 1]}


def _as_keys(points: np.ndarray, d: Drawable) -> set:
    """The drawn triangles as sorted triples of the mesh's point ids (found by position)."""
    lookup = {tuple(p): i for i, p in enumerate(points.astype(np.float32))}
    return {tuple(sorted(lookup[tuple(p)] for p in d.points[t])) for t in d.triangles}


def test_a_curve_becomes_ribbons_along_its_segments(curve):
    d = drawable(curve)
    segs = curve.cells["line"]
    assert d.planar and not d.flat
    assert d.triangles.shape == (2 * len(segs), 3) and np.all(d.points[:, 2] == 0)
    diagonal = np.linalg.norm(np.ptp(curve.points, axis=0))
    # every ribbon corner lies half a width across its segment's end
    a = np.repeat(curve.points[segs[:, 0]], 2, axis=0)
    b = np.repeat(curve.points[segs[:, 1]], 2, axis=0)
    corners = d.points[:, :2].reshape(-1, 4, 2)
    ends = np.stack([a[::2], a[::2], b[::2], b[::2]], axis=1)
    np.testing.assert_allclose(np.linalg.norm(corners - ends, axis=2), 0.003 * diagonal, rtol=1e-4)
    wide = drawable(curve, width=0.02)
    assert np.linalg.norm(wide.points[0, :2] - curve.points[segs[0, 0]]) > 3 * np.linalg.norm(
        d.points[0, :2] - curve.points[segs[0, 0]])


def test_a_curve_renders_as_a_ring_seen_from_above(curve):
    img = render_png(curve, window_size=(200, 200)).array.astype(int)
    drawn = np.abs(img - 255).sum(axis=2) > 60
    ys, xs = np.nonzero(drawn)
    assert len(xs) > 100, "the circle is not drawn"
    r = np.hypot(xs - xs.mean(), ys - ys.mean())
    assert r.std() < 0.1 * r.mean(), "the drawn pixels do not form a ring"
    assert not drawn[90:110, 90:110].any(), "the inside of the circle is background"


def test_a_volume_mesh_shows_the_cells_its_clip_keeps(shell):
    tets = shell.cells["tetra"]
    whole = drawable(shell, clip=None)
    assert not whole.flat and _as_keys(shell.points, whole) == _boundary_faces(tets)
    for clip, axis in (("auto", 0), ("y", 1), (((0, 0, -1), (0, 0, 0.2)), 2)):
        d = drawable(shell, clip=clip)
        assert d.flat and len(d.points) == 3 * len(d.triangles), "facets have their own vertices (flat shading)"
        centres = shell.points[tets].mean(axis=1)
        if axis == 2:
            kept = tets[centres[:, 2] >= 0.2]
        else:
            kept = tets[centres[:, axis] <= 0.5 * (shell.points[:, axis].min() + shell.points[:, axis].max())]
        assert 0 < len(kept) < len(tets)
        assert _as_keys(shell.points, d) == _boundary_faces(kept), clip
    assert len(drawable(shell, clip=((1, 0, 0), (-5, 0, 0))).triangles) == 0, "everything cut away"


def test_a_planar_domain_is_seen_from_above():
    disk = wm.mesh_domain(wm.circle(1.0), bounds=BOX2, size=0.2)
    d = drawable(disk)
    assert d.planar and len(d.triangles) == len(disk.cells["triangle"])
    opts = json.loads(re.search(r"createWarpmeshViewer\([^,]+, (\{.*?\})\);", mesh_html(disk)).group(1))
    assert opts["top"] is True
    img = render_png(disk, window_size=(160, 160)).array.astype(int)
    assert (np.abs(img[70:90, 70:90] - 255).sum(axis=2) > 30).all(), "a disk seen from above fills the centre"


@pytest.mark.parametrize("clip, message", [("w", "Unknown clip 'w'"), (((0, 0, 0), (0, 0, 0)), "non-zero"),
                                           ((1, 2), "'clip'"), (((np.nan, 0, 1), (0, 0, 0)), "'clip'")])
def test_bad_clips_are_named(shell, clip, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        drawable(shell, clip=clip)


def test_bad_width_is_named(curve):
    for width in (0, 1.5, True, "thin"):
        with pytest.raises(ValueError, match="'width'"):
            drawable(curve, width=width)
