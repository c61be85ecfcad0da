"""Atomic saves (issue 19 item 6): a write stopped by an exception, SIGTERM or SIGKILL leaves
no half-written file; a SIGKILL leftover is removed by the next write of the same path."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import numpy as np
import pytest

import warpmesh as wm
from warpmesh._util.atomic import atomic_path, remove_stale, temporary_name

# a save that blocks inside meshio's writer (.vtk, .obj) until it is killed: the temporary exists meanwhile
SLOW_SAVE = """
import sys, time, numpy as np, meshio
import warpmesh as wm
real = meshio.write
def slow(path, *a, **k):
    real(path, *a, **k)
    print("writing", flush=True)
    time.sleep(60)
meshio.write = slow
m = wm.Mesh(np.eye(3), {"triangle": np.array([[0, 1, 2]])})
m.save(sys.argv[1])
"""


def _start_slow_save(path):
    proc = subprocess.Popen([sys.executable, "-c", SLOW_SAVE, str(path)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "writing"
    assert any(p.name.endswith(".tmp") for p in path.parent.iterdir())  # the write is in progress
    return proc


@pytest.mark.skipif(not hasattr(signal, "SIGTERM") or os.name == "nt", reason="POSIX signals")
@pytest.mark.parametrize("ext", [".vtk", ".obj"])
def test_sigterm_during_a_save_leaves_nothing(tmp_path, ext):
    path = tmp_path / f"out{ext}"
    proc = _start_slow_save(path)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 128 + signal.SIGTERM
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.name == "nt", reason="POSIX signals")
def test_sigkill_leftover_is_removed_by_the_next_save(tmp_path):
    path = tmp_path / "out.vtk"
    proc = _start_slow_save(path)
    proc.kill()
    proc.wait(timeout=60)
    left = [p for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].name.startswith(".out.vtk.") and left[0].name.endswith(".tmp")
    wm.Mesh(np.eye(3), {"triangle": np.array([[0, 1, 2]])}).save(path)
    assert [p.name for p in tmp_path.iterdir()] == ["out.vtk"]
    assert wm.load(path).n_cells == 1


def test_a_live_writers_temporary_is_left_alone(tmp_path):
    path = tmp_path / "x.txt"
    mine = temporary_name(path)
    mine.write_text("in progress")
    dead = path.with_name(f".x.txt.{2**22 + 12345}.{'0' * 12}.tmp")  # above pid_max's default
    dead.write_text("left by a killed writer")
    other = path.with_name(".x.txt.unrelated.tmp")
    other.write_text("not ours")
    assert remove_stale(path) == [dead]
    assert mine.exists() and other.exists() and not dead.exists()


def test_an_exception_removes_the_temporary_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "y.txt"
    path.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk full")
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["y.txt"]


def test_a_folder_write_moves_every_file_and_leaves_no_folder(tmp_path):
    path = tmp_path / "z.main"
    with atomic_path(path, kind="tmpdir") as tmp:
        (tmp / "z.main").write_text("main")
        (tmp / "z.side").write_text("side")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["z.main", "z.side"]


def test_save_through_a_symbolic_link_writes_its_target(tmp_path):
    """os.replace over the link's name replaced the link with a file; the target kept its old
    contents."""
    import warpmesh as wm

    mesh = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]})
    (tmp_path / "data").mkdir()
    target = tmp_path / "data" / "real.vtu"
    target.write_text("old")
    link = tmp_path / "link.vtu"
    link.symlink_to(target)
    assert mesh.save(link) == link
    assert link.is_symlink() and wm.load(target).n_cells == 1
    assert sorted(p.name for p in (tmp_path / "data").iterdir()) == ["real.vtu"]
