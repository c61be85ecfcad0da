"""One cache-folder rule for every on-disk cache (:mod:`warpmesh._util.cache_dir`):
WARPMESH_CACHE_DIR, else XDG_CACHE_HOME/warpmesh, else ~/.cache/warpmesh; an unwritable
folder means no cache and one warning."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from warpmesh._util import cache_dir
from warpmesh._util.cache_dir import cache_root, writable_cache_dir


@pytest.fixture
def clean_env(monkeypatch):
    monkeypatch.delenv("WARPMESH_CACHE_DIR", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setattr(cache_dir, "_warned", set())
    monkeypatch.setattr(cache_dir, "_checked", {})
    return monkeypatch


def test_the_rule_in_its_order(clean_env, tmp_path):
    clean_env.setenv("HOME", str(tmp_path / "home"))
    assert cache_root() == tmp_path / "home" / ".cache" / "warpmesh"
    clean_env.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "warpmesh"
    clean_env.setenv("WARPMESH_CACHE_DIR", str(tmp_path / "own"))
    assert cache_root() == tmp_path / "own"  # no "warpmesh" appended: the user named the folder
    assert cache_root("tables") == tmp_path / "own" / "tables"
    clean_env.setenv("WARPMESH_CACHE_DIR", "")  # empty counts as unset
    assert cache_root() == tmp_path / "xdg" / "warpmesh"


def test_every_cache_follows_the_rule(clean_env, tmp_path):
    from warpmesh.kernels import table_cache

    from warpmesh.frep import codegen
    from warpmesh.io import formats

    clean_env.setenv("XDG_CACHE_HOME", str(tmp_path))
    root = tmp_path / "warpmesh"
    assert table_cache.table_dir() == root / "tables"
    assert codegen.cache_dir() == root
    assert formats._cache_file().parent == root
    clean_env.setenv("WARPMESH_CACHE_DIR", str(tmp_path / "own"))
    assert table_cache.table_dir() == tmp_path / "own" / "tables"
    assert codegen.cache_dir() == tmp_path / "own"
    assert formats._cache_file().parent == tmp_path / "own"


def test_writable_folder_is_created(clean_env, tmp_path):
    clean_env.setenv("WARPMESH_CACHE_DIR", str(tmp_path / "a" / "b"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert writable_cache_dir("tables") == tmp_path / "a" / "b" / "tables"
    assert (tmp_path / "a" / "b" / "tables").is_dir()
    assert list((tmp_path / "a" / "b" / "tables").iterdir()) == []  # the probe file is gone


def test_unwritable_folder_means_no_cache_and_one_warning(clean_env, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    clean_env.setenv("WARPMESH_CACHE_DIR", str(blocker / "cache"))
    with pytest.warns(RuntimeWarning, match="WARPMESH_CACHE_DIR") as record:
        assert writable_cache_dir() is None
        assert writable_cache_dir() is None
    assert len([w for w in record if "cache folder" in str(w.message)]) == 1
    assert str(blocker / "cache") in str(record[0].message)


def test_tables_without_a_cache_are_generated_with_one_warning(clean_env, tmp_path):
    from warpmesh.kernels import table_cache

    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    clean_env.setenv("WARPMESH_CACHE_DIR", str(blocker))
    src = tmp_path / "gen.py"
    src.write_text("# generator")
    calls = []

    def build():
        calls.append(1)
        return np.arange(3), 7

    with pytest.warns(RuntimeWarning, match="cannot write the cache folder") as record:
        for _ in range(2):
            values, n = table_cache.cached("t", build, src)
            assert values.tolist() == [0, 1, 2] and n == 7
    assert len(calls) == 2  # nothing stored: generated each time
    assert len(record) == 1


def test_formats_probe_uses_warpmesh_cache_dir(tmp_path):
    """The meshio probe's table lands under WARPMESH_CACHE_DIR (it used XDG_CACHE_HOME alone)."""
    env = {**os.environ, "WARPMESH_CACHE_DIR": str(tmp_path / "own"), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    code = "from warpmesh.io.formats import format_support, _cache_file; format_support(); print(_cache_file())"
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert run.returncode == 0, run.stderr
    path = Path(run.stdout.strip().splitlines()[-1])
    assert path.parent == tmp_path / "own" and path.exists()
    assert not (tmp_path / "xdg").exists()
