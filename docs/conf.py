"""Sphinx configuration of the warpmesh documentation site.

Build: ``pip install -e ".[docs]"`` then ``sphinx-build -W --keep-going -b html docs docs/_build/html``.

Nothing here is typed twice: the pages under ``generated/`` are written on every build
from the code they describe (``warpmesh.__all__``, the subpackages' modules, the
``warpmesh`` argument parser) and the notebooks are copied in from ``notebooks/``, as
committed and executed (never run here).
"""

import argparse
import importlib
import logging
import os
import pkgutil
import re
import types
from pathlib import Path

import warpmesh
from warpmesh.cli.commands import _parser

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
GENERATED = HERE / "generated"

# The public subpackages, in the order of the pipeline (warpmesh/__init__.py's docstring).
SUBPACKAGES = ["frep", "surface", "planar", "solid", "optimize", "modify", "numbering", "cells", "io", "preview", "distributed"]
MODULES = ["mesh", "errors"]  # the top-level modules of the public face

project = "warpmesh"
author = "the warpmesh authors"
copyright = "the warpmesh authors"
release = version = warpmesh.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
    "myst_nb",  # MyST Markdown (docs/architecture.md) and the notebooks
]

smartquotes = False  # option names in help texts stay "--flag", not "–flag"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
templates_path = []
html_theme = "alabaster"
html_static_path = []

# numpy-style docstrings (STYLE.md rule 6)
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_default_options = {"members": True, "member-order": "bysource", "show-inheritance": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
autosummary_generate = True
autosummary_imported_members = False

# The notebooks are committed executed: render them as they are.
nb_execution_mode = "off"
myst_heading_anchors = 3


def _section(title: str, char: str = "=") -> str:
    return f"{title}\n{char * len(title)}\n"


def _api_page() -> str:
    """The page of ``warpmesh.__all__``: a table per defining module, each name linked to its
    description on that module's page (one description per object: no ambiguous targets)."""
    groups: dict[str, list[str]] = {}
    modules: list[str] = []
    data: list[str] = []
    for name in warpmesh.__all__:
        obj = getattr(warpmesh, name)
        if isinstance(obj, types.ModuleType):  # warpmesh's own type is a ModuleType subclass
            modules.append(name)
        elif getattr(obj, "__module__", None) is None or isinstance(obj, (dict, list, tuple)):
            data.append(name)
        else:
            groups.setdefault(obj.__module__, []).append(name)
    out = [_section("The ``warpmesh`` namespace"),
           "Every name in ``warpmesh.__all__`` (``import warpmesh as wm``; ``wm.mesh_surface`` ...), "
           "grouped by the module that defines it; each links to its description on that module's page.\n",
           ]
    for module, names in groups.items():
        out.append(_section(f"From :mod:`{module}`", "-"))
        out.append(".. autosummary::\n\n" + "".join(f"   ~{module}.{n}\n" for n in names))
    if data:
        out.append(_section("Tables", "-"))
        out.append(".. currentmodule:: warpmesh\n")
        for name in data:
            obj = getattr(warpmesh, name)
            out.append(f".. data:: {name}\n\n"
                       f"   A table of {len(obj)} entries: {', '.join(f'``{k}``' for k in obj)}.\n")
    if modules:
        out.append(_section("Modules", "-"))
        for name in modules:
            out.append(f"``warpmesh.{name}``\n   the module :mod:`{getattr(warpmesh, name).__name__}`.\n")
    return "\n".join(out)


def _public_modules(package: str) -> list[str]:
    pkg = importlib.import_module(package)
    return sorted(m.name for m in pkgutil.walk_packages(pkg.__path__, package + ".")
                  if not any(part.startswith("_") for part in m.name.split(".")))


def _subpackage_page(name: str) -> str:
    package = f"warpmesh.{name}"
    if name in MODULES:
        return "\n".join([_section(f"``{package}``"), f".. automodule:: {package}\n"])
    return "\n".join([
        _section(f"``{package}``"),
        f".. automodule:: {package}\n   :no-members:\n",
        _section("Modules", "-"),
        ".. autosummary::\n   :toctree: modules\n\n"
        + "".join(f"   {m.removeprefix(package + '.')}\n" for m in _public_modules(package)),
    ])


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _cli_pages() -> dict[str, str]:
    pages = {"index": "\n".join([
        _section("Command line"),
        "``warpmesh <command> --help`` prints these pages; one per sub-command.\n",
        ".. toctree::\n   :maxdepth: 1\n\n" + "".join(f"   {cmd}\n" for cmd in _subcommands()),
    ])}
    for cmd in _subcommands():
        pages[cmd] = "\n".join([
            _section(f"``warpmesh {cmd}``"),
            f".. argparse::\n   :module: warpmesh.cli.commands\n   :func: _parser\n   :prog: warpmesh\n"
            f"   :path: {cmd}\n",
        ])
    return pages


def _write(path: Path, data: bytes) -> None:
    """Write only what changed (incremental builds stay incremental), atomically (two builds
    of one checkout may run at once)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    if not path.exists() or path.read_bytes() != data:
        tmp = path.with_name(f".{path.name}.{os.getpid()}")
        tmp.write_bytes(data)
        os.replace(tmp, path)


def _prune(folder: Path, pattern: str, keep: set[str]) -> None:
    """Remove the pages of what no longer exists (a removed command, module or notebook),
    which Sphinx would otherwise report as documents in no toctree."""
    for path in folder.glob(pattern):
        if path.name not in keep:
            path.unlink(missing_ok=True)


def _generate() -> None:
    pages = {"api.rst": _api_page()}
    pages["reference/index.rst"] = "\n".join([
        _section("Subpackages"),
        "One page per stage of the pipeline, each listing its modules; a module's page documents "
        "every public function and class it defines.\n",
        ".. toctree::\n   :maxdepth: 1\n\n" + "".join(f"   {name}\n" for name in SUBPACKAGES + MODULES)])
    for name in SUBPACKAGES + MODULES:
        pages[f"reference/{name}.rst"] = _subpackage_page(name)
    for cmd, text in _cli_pages().items():
        pages[f"cli/{cmd}.rst"] = text
    for relative, text in pages.items():
        _write(GENERATED / relative, text.encode())
    notebooks = sorted((ROOT / "notebooks").glob("*.ipynb"))
    for notebook in notebooks:
        _write(GENERATED / "notebooks" / notebook.name, notebook.read_bytes())
    _prune(GENERATED / "notebooks", "*.ipynb", {p.name for p in notebooks})
    for folder in ("cli", "reference"):
        _prune(GENERATED / folder, "*.rst", {Path(r).name for r in pages if r.startswith(folder + "/")})
    modules = {m for name in SUBPACKAGES for m in _public_modules(f"warpmesh.{name}")}
    _prune(GENERATED / "reference" / "modules", "*.rst", {f"{m}.rst" for m in modules})


_LITERAL_SPAN = re.compile(r"(``.*?``|`[^`]*`)")


def _escape_pipes(app, what, name, obj, options, lines: list[str]) -> None:
    """Docstrings are read as plain text too (``help()``), where ``|x|`` is an absolute value
    or a norm; reST would take it for a substitution. Escape ``|`` in prose, leaving inline
    literals, doctest blocks and literal blocks (after ``::``) as they are."""
    literal_indent = None  # indentation of the paragraph that opened a literal block
    doctest = False
    for i, line in enumerate(lines):
        stripped = line.strip()
        indent = len(line) - len(line.lstrip())
        if literal_indent is not None:
            if not stripped or indent > literal_indent:
                continue
            literal_indent = None
        if stripped.startswith(">>>"):
            doctest = True
        if doctest:
            doctest = bool(stripped)
            continue
        if "|" in line:
            parts = _LITERAL_SPAN.split(line)
            lines[i] = "".join(p if k % 2 else p.replace("|", "\\|") for k, p in enumerate(parts))
        if stripped.endswith("::"):
            literal_indent = indent


class _ProseTypeFilter(logging.Filter):
    """Sphinx tries each word of a parameter's type as a cross-reference. In numpydoc types
    such as ``seeds : (m, 3) points, optional`` (warpmesh.surface.options) the word "points"
    is prose, yet two attributes bear that name (Mesh.points, CurveSample.points), so Sphinx
    reports an ambiguous target. Drop that one report: no docstring means either attribute."""

    PROSE_WORDS = {"points"}

    def filter(self, record: logging.LogRecord) -> bool:
        return not (str(record.msg).startswith("more than one target found for cross-reference")
                    and record.args and record.args[0] in self.PROSE_WORDS)


def setup(app):
    logging.getLogger("sphinx.sphinx.domains.python").addFilter(_ProseTypeFilter())
    app.connect("autodoc-process-docstring", _escape_pipes)


_generate()
