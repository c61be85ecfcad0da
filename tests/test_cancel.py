"""Cooperative cancellation (warpmesh._util.cancel): the pipelines stop at their next stage."""

from __future__ import annotations

import threading

import pytest

import warpmesh as wm
from warpmesh._util import cancel

BOUNDS = ((-1.2,) * 3, (1.2,) * 3)


@pytest.mark.parametrize("options", [dict(resolution=24), dict(resolution=24, method="mc33", cull=False),
                                     dict(adaptive=True, max_level=5)])
def test_a_stale_run_stops_at_a_checkpoint(options):
    calls = []

    def stale():
        calls.append(1)
        return len(calls) >= 2  # fresh at the first checkpoint, stale at the second

    with cancel.cancellable(stale), pytest.raises(cancel.Cancelled, match="cancelled"):
        wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, **options)
    assert len(calls) == 2
    # never stale: the same run completes, as outside
    with cancel.cancellable(lambda: False):
        inside = wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, **options)
    assert inside.n_cells == wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, **options).n_cells > 0


def test_the_check_is_per_thread():
    results = {}

    def other():
        results["mesh"] = wm.mesh_surface(wm.sphere(1.0), bounds=BOUNDS, resolution=16)

    with cancel.cancellable(lambda: True):
        t = threading.Thread(target=other)
        t.start()
        t.join(60)
    assert results["mesh"].n_cells > 0
    with pytest.raises(TypeError, match="'stale'"):
        with cancel.cancellable(True):
            pass
