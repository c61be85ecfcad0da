"""The exported WebGL page in a real browser: headless Chromium draws the mesh, and an
edit's page differs where the shape changed.

The module's fixture installs Chromium when it is missing and this is possible (root and
apt-get, Debian's ``chromium`` package), else the tests skip and print why.
"""

from __future__ import annotations

import os
import subprocess

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.preview.render import write_html
from tests.helpers.chromium import NO_CHROMIUM, SOFTWARE_GL, find_or_install_chromium
from tests.preview.test_params import BOUNDS, part_of

SIZE = (640, 480)


@pytest.fixture(scope="module")
def chromium():
    path = find_or_install_chromium()
    if path is None:
        print(NO_CHROMIUM)
        pytest.skip(NO_CHROMIUM)
    return path


def screenshot(chromium, page, png, profile) -> np.ndarray:
    """Open ``page`` in headless Chromium (software WebGL) and read the screenshot back."""
    from PIL import Image

    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           *SOFTWARE_GL,
           f"--user-data-dir={profile}", f"--screenshot={png}", f"--window-size={SIZE[0]},{SIZE[1]}",
           "--virtual-time-budget=5000", f"file://{page}"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert os.path.exists(png), f"Chromium wrote no screenshot (exit {run.returncode}): {run.stderr[-2000:]}"
    return np.asarray(Image.open(png).convert("RGB")).astype(np.int16)


def drawn(img) -> np.ndarray:
    """Pixels that are not the white background."""
    return np.abs(img - 255).sum(axis=2) > 30


@pytest.fixture(scope="module")
def pages(chromium, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("browser")
    r, boss = wm.param("r", 0.2, lo=0.05, hi=0.28), wm.param("boss", 0.5, lo=0.3, hi=0.7)
    view = wm.Preview(part_of(r, boss), bounds=BOUNDS, resolution=48, evaluator="interpreter")
    shots = {}
    for key, values in (("first", {}), ("again", {}), ("edited", {"boss": 0.7})):
        view.update(**values)
        page = view.export_html(tmp / f"{key}.html", label=False)
        shots[key] = screenshot(chromium, page, tmp / f"{key}.png", tmp / f"profile-{key}")
    return shots


def test_the_page_draws_the_mesh(pages):
    img = pages["first"]
    assert img.shape == (SIZE[1], SIZE[0], 3)
    mask = drawn(img)
    h, w = mask.shape
    centre = mask[h // 3: 2 * h // 3, w // 3: 2 * w // 3]
    assert centre.mean() > 0.9, "the part (framed at the centre) is not drawn"
    assert mask[:10].sum() == 0 and mask[:, :10].sum() == 0, "background expected at the border"
    assert 0.15 < mask.mean() < 0.9
    # shaded, not flat: several grey levels on the surface
    assert len(np.unique(img[mask].sum(axis=1) // 16)) > 5


def test_an_edit_differs_where_the_shape_changed(pages):
    same = np.abs(pages["first"] - pages["again"]).sum(axis=2) > 30
    assert same.sum() == 0, "the same mesh must give the same picture"
    diff = np.abs(pages["first"] - pages["edited"]).sum(axis=2) > 30
    part = drawn(pages["first"]) | drawn(pages["edited"])
    assert diff.sum() > 500, "the boss grew from 0.5 to 0.7: the picture must change"
    assert diff.sum() < 0.5 * part.sum(), "most of the plate did not change"
    # the boss sits at the origin, the centre of the framed bounds, so of the picture
    ys, xs = np.nonzero(diff)
    h, w = diff.shape
    assert abs(xs.mean() - w / 2) < 0.15 * w and abs(ys.mean() - h / 2) < 0.2 * h


def test_a_curve_page_draws_a_ring_from_above_and_a_tet_page_its_cut(chromium, tmp_path):
    curve = wm.mesh_curve(wm.circle(1.0), bounds=((-1.2, -1.2), (1.2, 1.2)))
    page = write_html(curve, tmp_path / "curve.html", label=False)
    ring = drawn(screenshot(chromium, page, tmp_path / "curve.png", tmp_path / "profile-curve"))
    ys, xs = np.nonzero(ring)
    assert len(xs) > 200, "the circle is not drawn"
    r = np.hypot(xs - xs.mean(), ys - ys.mean())
    assert r.std() < 0.1 * r.mean(), "seen from above, the circle is a ring"
    shell = wm.mesh_domain(wm.sphere(1.0) - wm.sphere(0.5), bounds=((-1.2,) * 3, (1.2,) * 3), size=0.25)
    shots = {}
    for clip in ("auto", None):
        page = write_html(shell, tmp_path / f"shell-{clip}.html", label=False, clip=clip)
        shots[clip] = screenshot(chromium, page, tmp_path / f"shell-{clip}.png", tmp_path / f"profile-{clip}")
    assert drawn(shots["auto"]).mean() > 0.05 and drawn(shots[None]).mean() > 0.05
    assert (np.abs(shots["auto"] - shots[None]).sum(axis=2) > 30).mean() > 0.02, "the cut shows"
