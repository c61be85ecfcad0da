"""The top-level kernels/ folder installs as warpmesh.kernels, editable or not."""

import subprocess
import sys
from pathlib import Path

import pytest

import warpmesh
import warpmesh.kernels.tape

ROOT = Path(__file__).resolve().parents[1]


def test_kernels_subpackage_maps_to_the_top_level_folder():
    # in this checkout (editable install) the subpackage is the repository's kernels/
    kernels_dir = Path(warpmesh.kernels.tape.__file__).resolve().parent
    if (ROOT / "kernels" / "tape.py").exists() and Path(warpmesh.__file__).resolve().is_relative_to(ROOT):
        assert kernels_dir == ROOT / "kernels"
    assert (kernels_dir / "mc_tables.py").exists()


@pytest.mark.slow
def test_regular_install_imports_the_kernels(tmp_path):
    """`pip install .` (no -e) puts kernels/ at warpmesh/kernels in site-packages."""
    target = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--quiet", "--target", str(target), str(ROOT)],
        capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert (target / "warpmesh" / "kernels" / "tape.py").exists()
    assert not (target / "kernels").exists()  # no top-level module named "kernels"
    code = ("import warpmesh, warpmesh.kernels.emit as k; "
            "print(warpmesh.__file__); print(k.__file__)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, env={"PYTHONPATH": str(target), "PATH": "/usr/bin:/bin"})
    assert run.returncode == 0, run.stderr
    assert all(str(target) in line for line in run.stdout.split())
