"""A device that does not exist is refused at the entry point with an error naming 'device'
(issue 19 item 8: was a bare Warp RuntimeError after native CUDA error lines)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import warp as wp

import warpmesh as wm
from warpmesh._util.validate import check_device

SPHERE = wm.sphere(0.5)
BOX = ((-1, -1, -1), (1, 1, 1))
CIRCLE = wm.circle(0.5)
BOX2 = ((-1, -1), (1, 1))
TRIS = np.array([[0, 1, 2]])
PTS = np.eye(3)

ENTRY_POINTS = {
    "mesh_surface": lambda d: wm.mesh_surface(SPHERE, bounds=BOX, resolution=8, device=d),
    "mesh_domain": lambda d: wm.mesh_domain(SPHERE, bounds=BOX, size=0.5, device=d),
    "mesh_curve": lambda d: wm.mesh_curve(CIRCLE, bounds=BOX2, method="grid", resolution=16, device=d),
    "evaluate": lambda d: wm.evaluate(SPHERE, np.zeros((1, 3)), device=d),
    "evaluate_interval": lambda d: wm.evaluate_interval(SPHERE, -np.ones((1, 3)), np.ones((1, 3)), device=d),
    "Preview": lambda d: wm.Preview(SPHERE, bounds=BOX, resolution=8, device=d),
    "check": lambda d: wm.check(wm.Mesh(PTS, {"triangle": TRIS}), device=d),
}


@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_unknown_device_is_refused_naming_the_argument(name):
    with pytest.raises(ValueError, match="'device'.*'gpu0'"):
        ENTRY_POINTS[name]("gpu0")
    with pytest.raises(TypeError, match="'device'"):
        ENTRY_POINTS[name](3)


@pytest.mark.skipif(wp.is_cuda_available(), reason="this machine has a CUDA device: 'cuda' is valid here")
@pytest.mark.parametrize("name", sorted(ENTRY_POINTS))
def test_cuda_without_a_gpu_is_refused_naming_the_argument(name):
    with pytest.raises(ValueError, match="'device'.*no CUDA device"):
        ENTRY_POINTS[name]("cuda")


def test_cpu_and_device_objects_pass():
    assert str(check_device("cpu")) == "cpu"
    assert check_device(wp.get_device("cpu")) is wp.get_device("cpu")


@pytest.mark.skipif(wp.is_cuda_available(), reason="this machine has a CUDA device: 'cuda' is valid here")
def test_cli_cuda_without_a_gpu_prints_one_line_and_no_native_errors(tmp_path):
    run = subprocess.run([sys.executable, "-m", "warpmesh.cli", "mesh", "--example", "sphere", "--resolution", "8",
                          "--device", "cuda", "-o", str(tmp_path / "s.vtu")], capture_output=True, text=True)
    assert run.returncode != 0
    assert "--device" in run.stderr and "no CUDA device" in run.stderr
    assert "CUDA error" not in run.stderr and "Traceback" not in run.stderr
    assert not list(tmp_path.iterdir())
