"""A fresh process says nothing it was not asked: no CUDA-driver warning on machines
without a GPU, other output of Warp's start-up kept."""

from __future__ import annotations

import subprocess
import sys

import pytest

from warpmesh._util.warp_init import NO_DRIVER


def _stderr(code: str) -> str:
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    return run.stderr


@pytest.mark.parametrize("code", ["import warpmesh",
                                  "import sys; sys.argv = ['warpmesh', '--help']\n"
                                  "from warpmesh.cli import main\ntry:\n    main()\nexcept SystemExit:\n    pass",
                                  "import warpmesh as wm; wm.mesh_surface(wm.sphere(1), bounds=((-1.2,)*3, (1.2,)*3), "
                                  "resolution=8)"])
def test_no_cuda_warning_without_cuda(code):
    assert NO_DRIVER not in _stderr(code)


def test_other_start_up_output_is_kept(monkeypatch, capfd):
    """The filter drops the one line only: what else start-up prints still shows."""
    import os

    import warp as wp

    from warpmesh._util import warp_init

    def fake_init():
        os.write(2, f"Warp CUDA warning: {NO_DRIVER}. GPU execution will not be available.\n".encode())
        os.write(2, b"Warp: something else worth seeing\n")
        monkeypatch.setattr(wp._src.context, "runtime", object())

    monkeypatch.setattr(wp._src.context, "runtime", None)
    monkeypatch.setattr(warp_init.wp, "init", fake_init)
    warp_init.init_warp()
    err = capfd.readouterr().err
    assert NO_DRIVER not in err and "something else worth seeing" in err
    warp_init.init_warp()  # initialised: nothing runs twice
    assert capfd.readouterr().err == ""
