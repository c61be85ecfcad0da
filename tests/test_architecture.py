"""The package reads as its architecture: one subpackage per stage, no import cycle
(function-level imports counted), no private name taken from another subpackage, kernels
that import no host code, one public face.

The import graph is read from the source with ``ast`` (every ``import`` statement, at any
depth, ``TYPE_CHECKING`` blocks included), so a lazy import cannot hide a cycle.
"""

from __future__ import annotations

import ast
import builtins
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

import warpmesh as wm

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "warpmesh"
KERNELS = ROOT / "kernels"

#: the subpackages a user may reach as ``wm.<name>``, and the two top modules
SUBPACKAGES = {"frep", "surface", "planar", "solid", "optimize", "modify", "numbering", "cells", "io", "preview", "cli",
               "distributed", "kernels"}
TOP_MODULES = {"mesh", "errors"}
#: expression functions named like builtins: reachable as wm.min etc., kept out of __all__
BUILTIN_NAMES = {"abs", "min", "max"}


def _modules() -> dict[str, Path]:
    mods = {}
    for p in PKG.rglob("*.py"):
        name = ".".join(p.relative_to(ROOT).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = p
    for p in KERNELS.glob("*.py"):
        mods["warpmesh.kernels" + ("" if p.stem == "__init__" else "." + p.stem)] = p
    return mods


def _is_package(mods, name) -> bool:
    return mods[name].name == "__init__.py"


def _imports(mods):
    """{module: {(target module, imported name or None)}} for every warpmesh import."""
    out = defaultdict(set)
    for mod, path in mods.items():
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                for a in node.names:
                    out[mod].add((a.name, None))
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = mod.split(".") if _is_package(mods, mod) else mod.split(".")[:-1]
                    base = base[: len(base) - (node.level - 1)]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for a in node.names:
                    sub = f"{target}.{a.name}"
                    out[mod].add((sub, None) if sub in mods else (target, a.name))
    return out


def _owner(mods, name):
    while name and name not in mods:
        name = name.rpartition(".")[0]
    return name


def _graph():
    mods = _modules()
    edges = defaultdict(set)
    private = []
    for mod, targets in _imports(mods).items():
        for target, name in targets:
            tgt = _owner(mods, target)
            if not tgt.startswith("warpmesh") or tgt == mod:
                continue
            if not (mod.startswith(tgt + ".") and _is_package(mods, tgt)):  # a package's own parent
                edges[mod].add(tgt)
            a, b = mod.split("."), tgt.split(".")
            if name and name.startswith("_") and not name.startswith("__") and len(a) > 2 and len(b) > 2 \
                    and a[1] != b[1]:
                private.append(f"{mod} takes {name} from {tgt}")
    return mods, edges, private


def _cycles(edges) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in list(edges):
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_the_cycle_finder_finds_cycles():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_function_level_imports_counted():
    _, edges, _ = _graph()
    assert _cycles(edges) == []


def test_no_private_name_taken_from_another_subpackage():
    _, _, private = _graph()
    assert private == []


def test_kernels_import_no_host_code():
    """Kernels import kernels, and at most a leaf helper of ``_util`` that imports nothing of
    warpmesh (the cache-folder rule, shared with the host caches)."""
    mods, edges, _ = _graph()
    for mod in mods:
        if mod.startswith("warpmesh.kernels"):
            assert all(t.startswith("warpmesh.kernels") or (t.startswith("warpmesh._util.") and not edges.get(t))
                       for t in edges[mod]), (mod, edges[mod])


def test_cells_is_the_bottom_layer():
    """The cell vocabulary imports nothing above it (only conventions, helpers, kernels)."""
    mods, edges, _ = _graph()
    allowed = ("warpmesh.cells", "warpmesh._conventions", "warpmesh._util", "warpmesh.kernels", "warpmesh.errors")
    for mod in mods:
        if mod.startswith("warpmesh.cells"):
            assert all(t.startswith(allowed) for t in edges[mod]), (mod, edges[mod])


def test_a_handful_of_modules_directly_in_the_package():
    top = {p.stem for p in PKG.glob("*.py")}
    assert top == {"__init__", "__main__", "mesh", "errors", "_conventions"}  # (__main__: python -m warpmesh)
    assert {p.name for p in PKG.iterdir() if p.is_dir() and (p / "__init__.py").exists()} == \
        SUBPACKAGES - {"kernels"} | {"_util"}


def test_pyproject_lists_every_subpackage():
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in PKG.rglob("__init__.py")}
    assert found | {"warpmesh.kernels"} == listed


def test_public_face_is_all_plus_the_subpackages():
    public = {n for n in dir(wm) if not n.startswith("_")}
    extra = public - set(wm.__all__)
    assert extra <= SUBPACKAGES | TOP_MODULES | BUILTIN_NAMES, sorted(extra - SUBPACKAGES - TOP_MODULES - BUILTIN_NAMES)
    assert set(wm.__all__) <= public


def test_all_does_not_shadow_builtins():
    assert not set(wm.__all__) & set(dir(builtins))
    # the expression functions that share a builtin's name stay reachable
    x, _, _ = wm.coords()
    assert isinstance(wm.min(x, 1.0), wm.Expr) and isinstance(wm.abs(x), wm.Expr)


def test_star_import_is_all(tmp_path):
    ns: dict = {}
    exec("from warpmesh import *", ns)  # noqa: S102
    assert set(ns) - {"__builtins__"} == set(wm.__all__)
    assert ns.get("min") is None and min(3, 4) == 3


@pytest.mark.parametrize("name", sorted(SUBPACKAGES - {"kernels"}))
def test_every_subpackage_says_what_it_holds(name):
    mod = sys.modules.get(f"warpmesh.{name}") or __import__(f"warpmesh.{name}", fromlist=["_"])
    assert mod.__doc__ and len(mod.__doc__.split()) >= 5


@pytest.mark.parametrize("first", ["", "import warpmesh as wm; wm.optimize; ", "import warpmesh.optimize.remesh; "])
def test_import_as_of_an_optimize_submodule(first):
    """``wm.optimize`` is a function, yet ``import warpmesh.optimize.<sub> as x`` must work in
    a fresh process whatever was imported first (it was an ImportError: Python looks the
    submodule up on the function)."""
    code = (first + "import warpmesh.optimize.label_smoothing as a; import warpmesh.optimize.embedding as b; "
            "import warpmesh as wm; assert callable(wm.optimize) and wm.optimize.__name__ == 'optimize'; "
            "print(a.__name__, b.__name__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=os.path.dirname(__file__))
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["warpmesh.optimize.label_smoothing", "warpmesh.optimize.embedding"]
