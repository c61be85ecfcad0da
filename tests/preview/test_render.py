"""Pictures and pages: Mesh.plot off-screen, the HTML export, the notebook bundle, ``warpmesh view``."""

from __future__ import annotations

import base64
import re

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.cli import main
from warpmesh.preview.render import mesh_html, mesh_mimebundle, surface_arrays

BOUNDS = ((-1.2,) * 3, (1.2,) * 3)


@pytest.fixture(scope="module")
def ball():
    return wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, resolution=16)


def test_plot_draws_the_mesh_off_screen(ball, tmp_path):
    img = ball.plot(tmp_path / "ball.png", window_size=(160, 120))
    assert img.array.shape == (120, 160, 3)
    mask = np.abs(img.array.astype(int) - 255).sum(axis=2) > 30
    assert mask[40:80, 60:100].all() and not mask[:5].any()  # the ball in the middle, white around
    assert (tmp_path / "ball.png").read_bytes() == img.png and img._repr_png_().startswith(b"\x89PNG")
    with pytest.raises(ValueError, match="'window_size'"):
        ball.plot(window_size=(0, 10))
    with pytest.raises(ValueError, match=".png"):
        img.save(tmp_path / "ball.jpg")


def test_html_holds_the_exact_buffers(ball):
    page = mesh_html(ball, title="a <ball>")
    pts, tri = surface_arrays(ball)
    blobs = re.findall(r'decode\("([A-Za-z0-9+/=]+)"', page)
    assert len(blobs) == 2
    np.testing.assert_array_equal(np.frombuffer(base64.b64decode(blobs[0]), "<f4").reshape(-1, 3), pts)
    np.testing.assert_array_equal(np.frombuffer(base64.b64decode(blobs[1]), "<u4").reshape(-1, 3), tri)
    assert "a &lt;ball&gt;" in page and "<ball>" not in page  # the title is escaped
    assert "src=" not in page and "http" not in page.split("<script>")[1]  # nothing fetched
    with pytest.raises(ValueError, match="'box'"):
        mesh_html(ball, box=((1, 1, 1), (0, 0, 0)))
    with pytest.raises(ValueError, match="'color'"):
        mesh_html(ball, color=(2, 0, 0))


def test_plot_writes_the_html_page_for_an_html_path(ball, tmp_path):
    page = ball.plot(tmp_path / "ball.html")
    assert page == str(tmp_path / "ball.html")
    assert open(page, encoding="utf-8").read() == mesh_html(ball)  # the page of the export, exactly
    assert ball.plot(tmp_path / "ball.HTM", clip=False) == str(tmp_path / "ball.HTM")
    with pytest.raises(ValueError, match=r"an HTML page takes only 'clip'.*\['show_edges', 'scalars'\]"):
        ball.plot(tmp_path / "other.html", show_edges=True, scalars="ref")
    with pytest.raises(ValueError, match="expected a .png or .html path for 'path', got '.*ball.jpg'"):
        ball.plot(tmp_path / "ball.jpg")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ball.HTM", "ball.html"]  # nothing else written


def test_notebook_bundles(ball):
    bundle = ball._repr_mimebundle_()
    assert bundle["text/plain"] == repr(ball) and "<iframe srcdoc=" in bundle["text/html"]
    assert ball._repr_html_() == bundle["text/html"]
    r = wm.param("r", 0.3, lo=0.1, hi=0.5)
    view = wm.Preview(wm.sphere(r), bounds=BOUNDS, resolution=12, evaluator="interpreter")
    data = view._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in data
    assert mesh_mimebundle(wm.Mesh(np.zeros((0, 3)), {"triangle": np.zeros((0, 3), int)})).keys() == {"text/plain"}


def test_widget_follows_updates():
    r = wm.param("r", 0.3, lo=0.1, hi=0.5)
    view = wm.Preview(wm.sphere(r), bounds=BOUNDS, resolution=12, evaluator="interpreter")
    box = view.widget()
    slider, mesh_view = box.children[0], box.children[1]
    assert (slider.min, slider.max, slider.value, slider.description) == (0.1, 0.5, 0.3, "r")
    slider.value = 0.45
    assert view.values == {"r": 0.45}
    view.update(r=0.2)  # from code: the view follows too
    assert mesh_view.version == 3
    pts = np.frombuffer(mesh_view.positions, "<f4").reshape(-1, 3)
    np.testing.assert_array_equal(pts, view.mesh.points.astype(np.float32))
    assert np.linalg.norm(pts, axis=1).max() == pytest.approx(0.2, abs=0.03)


def test_a_new_widget_closes_the_one_before():
    """Re-running the cell that shows a preview left every earlier view registered: each edit
    sent its mesh to all of them, and every status watcher stayed."""
    r = wm.param("r", 0.3, lo=0.1, hi=0.5)
    view = wm.Preview(wm.sphere(r), bounds=BOUNDS, resolution=12, evaluator="interpreter")
    first = view.widget()
    second = view.widget()
    old_view, new_view = first.children[1], second.children[1]
    assert first.comm is None and old_view.comm is None  # closed, parts included
    assert view._views == [new_view] and len(view._watchers) == 1
    before = old_view.version
    view.update(r=0.2)
    assert old_view.version == before and new_view.version == before + 1
    second.close()
    assert view._views == [] and view._watchers == [] and view._widget is None
    view.update(r=0.25)  # nothing shown: no idle refinement either
    assert view._timer is None and new_view.version == before + 1
    third = view.widget()  # a widget after a close works as the first
    third.children[0].value = 0.4
    assert view.values == {"r": 0.4} and third.children[1].version == 2


def test_cli_view(tmp_path, capsys):
    assert main(["view", "--example", "sphere", "--resolution", "16", "-o", str(tmp_path / "s.html")]) == 0
    assert "createWarpmeshViewer" in (tmp_path / "s.html").read_text()
    mesh = wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, resolution=12)
    mesh.save(tmp_path / "s.ply")
    assert main(["view", str(tmp_path / "s.ply"), "-o", str(tmp_path / "s.png"), "--window-size", "64", "48"]) == 0
    assert (tmp_path / "s.png").read_bytes().startswith(b"\x89PNG")
    assert "s.ply" in capsys.readouterr().out
    assert main(["view", "--example", "sphere", "-o", str(tmp_path / "s.stl")]) == 2
    assert "for -o/--output" in capsys.readouterr().err  # the flag named, before any rendering
    # --edges draws on the picture: with a page it was silently ignored
    assert main(["view", "--example", "sphere", "--edges", "-o", str(tmp_path / "e.html")]) == 2
    assert "--edges draws the triangle edges of a .png" in capsys.readouterr().err
    assert not (tmp_path / "e.html").exists()


def test_cli_view_cuts_a_tet_mesh_unless_told_not_to(tmp_path):
    shell = wm.mesh_domain(wm.sphere(1.0) - wm.sphere(0.5), bounds=BOUNDS, size=0.3)
    shell.save(tmp_path / "shell.vtu")
    sizes = {}
    for clip in ("auto", "none"):
        out = tmp_path / f"shell-{clip}.html"
        assert main(["view", str(tmp_path / "shell.vtu"), "--clip", clip, "-o", str(out)]) == 0
        sizes[clip] = len(out.read_text())
    assert sizes["auto"] != sizes["none"], "the cut page draws other triangles than the outside"


def test_plot_colours_a_surface_by_its_labels(tmp_path):
    vol = np.zeros((24, 24, 24), np.uint8)
    g = np.indices(vol.shape)
    ball = ((g - 12) ** 2).sum(0) < 80
    vol[ball] = 1
    vol[ball & (g[1] < 12)] = 2  # half the ball another label
    m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    plain = m.plot(window_size=(160, 160)).array.reshape(-1, 3)
    coloured = m.plot(window_size=(160, 160), scalars="label_above").array.reshape(-1, 3)
    hue = lambda px: np.unique((px[(np.abs(px.astype(int) - 255).sum(1) > 60)] // 64), axis=0)  # noqa: E731
    assert len(hue(coloured)) > len(hue(plain)), "two labels above: two colours"
    with pytest.raises(ValueError, match=r"Unknown scalars 'tissue'. Pick one of \['ref', 'label_above'\]"):
        m.plot(scalars="tissue")
    with pytest.raises(ValueError, match="no triangle refs"):
        wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, resolution=8).plot(scalars="ref")


def test_bad_plot_options_are_refused_naming_them(ball, tmp_path):
    """A window VTK cannot allocate aborted the process (std::bad_alloc, exit 134), not Python;
    a string size failed in int(); clip="w" passed on a surface; a missing folder was named
    by a temporary file."""
    for size, what in (((100000, 100000), "at most 67108864 pixels"), ("big", r"\(width, height\)"),
                       ((64,), r"\(width, height\)"), ((64.5, 48), "two positive integers"),
                       ((0, 48), "two positive integers"), ((True, 48), "two positive integers")):
        with pytest.raises(ValueError, match=f"'window_size'.*{what}|{what}.*'window_size'"):
            ball.plot(window_size=size)
    with pytest.raises(ValueError, match="Unknown clip 'w'"):
        ball.plot(clip="w", window_size=(32, 24))
    with pytest.raises(FileNotFoundError, match="no such folder for 'path'.*missing"):
        ball.plot(tmp_path / "missing" / "x.png", window_size=(32, 24))
    with pytest.raises(FileNotFoundError, match="no such folder for 'path'.*missing"):
        ball.plot(tmp_path / "missing" / "x.html")
    assert not list(tmp_path.iterdir())
    assert main(["view", "--example", "sphere", "-o", str(tmp_path / "v.png"), "--window-size", "100000",
                 "100000"]) == 2
