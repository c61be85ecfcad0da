"""The documentation site (docs/) builds with warnings as errors and documents the public face.

One Sphinx build per session (about a minute on two busy cores), then: every name of
``warpmesh.__all__`` is on the API page and links to its description, every public
subpackage has its page, every sub-command of the ``warpmesh`` parser has a page with its
usage line, every notebook is a page of the user's guide. Runs where the ``docs`` extra is
installed (the ``test`` extra includes it).
"""

import argparse
import html
import json
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

import warpmesh

for _module in ("sphinx", "myst_nb", "sphinxarg"):
    pytest.importorskip(_module, reason="the docs extra is not installed: pip install -e '.[docs]'")

from warpmesh.cli.commands import _parser  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SUBPACKAGES = ["frep", "surface", "planar", "solid", "optimize", "modify", "numbering", "cells", "io", "preview"]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("docs")
    html_dir = out / "html"
    run = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(out / "doctrees"), str(ROOT / "docs"), str(html_dir)],
        capture_output=True, text=True, timeout=900, cwd=ROOT)
    assert run.returncode == 0, f"sphinx-build -W failed:\n{run.stdout[-4000:]}\n{run.stderr[-8000:]}"
    return html_dir


def _text(page: Path) -> str:
    """The page's text, tags removed (code is split into highlighted spans), entities decoded,
    white space collapsed."""
    return " ".join(html.unescape(re.sub(r"<[^>]+>", "", page.read_text())).split())


def _anchor(name: str) -> str:
    obj = getattr(warpmesh, name)
    if isinstance(obj, types.ModuleType):
        return f"module-{obj.__name__}"
    if hasattr(obj, "__qualname__") and hasattr(obj, "__module__"):
        return f"{obj.__module__}.{obj.__qualname__}"
    return f"warpmesh.{name}"  # tables (EXAMPLES): described on the API page itself


def test_build_passes_with_warnings_as_errors(site):
    assert (site / "index.html").is_file()
    assert (site / "architecture.html").is_file()
    assert "The rules the layout keeps" in _text(site / "architecture.html")


@pytest.mark.parametrize("name", warpmesh.__all__)
def test_api_page_links_every_public_name_to_its_description(site, name):
    api = site / "generated" / "api.html"
    page = api.read_text()
    anchor = _anchor(name)
    targets = [href.split("#")[0] for href in re.findall(r'href="([^"]*)"', page) if href.endswith("#" + anchor)]
    assert targets, f"{name} ({anchor}) is not linked from the API page"
    file = (api.parent / targets[0]).resolve() if targets[0] else api
    assert f'id="{anchor}"' in file.read_text(), f"{name}: {file.name} has no description {anchor}"
    assert name in _text(api)


@pytest.mark.parametrize("name", SUBPACKAGES + ["mesh", "errors"])
def test_every_public_subpackage_has_a_page(site, name):
    page = site / "generated" / "reference" / f"{name}.html"
    assert f'id="module-warpmesh.{name}"' in page.read_text()


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


@pytest.mark.parametrize("command", list(_subcommands()))
def test_every_subcommand_has_a_page_with_its_usage(site, command):
    usage = " ".join(_subcommands()[command].format_usage().split())
    assert usage.startswith(f"usage: warpmesh {command}")
    page = site / "generated" / "cli" / f"{command}.html"
    assert usage in _text(page), f"{page.name} lacks {usage!r}"
    assert f'href="{command}.html"' in (site / "generated" / "cli" / "index.html").read_text()


@pytest.mark.parametrize("notebook", sorted(p.name for p in (ROOT / "notebooks").glob("*.ipynb")))
def test_every_notebook_is_a_page_with_its_outputs(site, notebook):
    cells = json.loads((ROOT / "notebooks" / notebook).read_text())["cells"]
    images = sum("image/png" in o.get("data", {}) for c in cells for o in c.get("outputs", []))
    page = (site / "generated" / "notebooks" / notebook).with_suffix(".html").read_text()
    assert page.count("<img") >= images, f"{notebook}: {images} pictures in the notebook, fewer on its page"
