"""Preview: the edit loop pays its set-up once; each update is a fresh mesh_surface's mesh."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.preview.instrument import count_module_loads
from tests.preview.test_params import BOUNDS, part_of


@pytest.fixture(scope="module")
def preview():
    r, boss = wm.param("r", 0.2, lo=0.05, hi=0.28), wm.param("boss", 0.5, lo=0.3, hi=0.7)
    return wm.Preview(part_of(r, boss), bounds=BOUNDS, resolution=48)


def test_fifty_edits_load_no_warp_module(preview):
    rng = np.random.default_rng(7)
    with count_module_loads() as counts:
        for _ in range(50):
            preview.update(r=float(rng.uniform(0.05, 0.28)), boss=float(rng.uniform(0.3, 0.7)))
    assert (counts.loads, counts.compiles) == (0, 0), counts.modules
    assert preview.mesh.info["evaluator"] == "compiled"  # the generated kernel, reused by every edit
    assert len(preview.timings) >= 50


def test_the_counter_sees_a_load():
    import warp as wp

    from tests.preview import _counted_kernels as K

    with count_module_loads() as counts:
        out = wp.zeros(4, dtype=wp.float32, device="cpu")
        wp.launch(K.fill_kernel, dim=4, inputs=[2.5], outputs=[out], device="cpu")
    assert counts.loads == 1 and counts.modules == [K.__name__], counts
    assert out.numpy().tolist() == [2.5] * 4


@pytest.mark.parametrize("values", [{"r": 0.09, "boss": 0.66}, {"r": 0.27}, {"boss": 0.31}])
def test_update_equals_a_fresh_mesh_of_plain_numbers(preview, values):
    mesh = preview.update(**values)
    current = dict(preview.values)
    fresh = wm.mesh_surface(part_of(current["r"], current["boss"]), bounds=BOUNDS, resolution=48,
                            evaluator="interpreter")
    np.testing.assert_array_equal(mesh.triangles, fresh.triangles)
    np.testing.assert_array_equal(mesh.points, fresh.points)
    assert mesh is preview.mesh and mesh.stats()["euler"] == -6


def test_update_changes_the_mesh_where_the_shape_changed(preview):
    small = preview.update(r=0.06, boss=0.35)
    big = preview.update(r=0.27, boss=0.69)
    # the boss top moves from z = 0.35 to z = 0.69
    assert small.points[:, 2].max() == pytest.approx(0.35, abs=0.06)
    assert big.points[:, 2].max() == pytest.approx(0.69, abs=0.06)


def test_bad_updates_are_named(preview):
    before = dict(preview.values)
    with pytest.raises(ValueError, match="Unknown parameter 'radius' in 'values'"):
        preview.update(radius=0.1)
    with pytest.raises(ValueError, match=r"expected a value in \[0.3, 0.7\] for parameter 'boss'"):
        preview.update(boss=0.8)
    assert preview.values == before
    with pytest.raises(ValueError, match="Unknown evaluator 'auto'"):
        wm.Preview(wm.sphere(1.0), bounds=BOUNDS, resolution=8, evaluator="auto")


def test_other_pipelines_and_no_parameters():
    r = wm.param("r", 0.2, lo=0.05, hi=0.28)
    plate = wm.box((2, 2, 0.6)) - wm.cylinder(r)
    octree = wm.Preview(plate, bounds=BOUNDS, resolution=None, adaptive=True, max_level=5, tolerance=0.05)
    assert octree.update(r=0.1).stats()["euler"] == 0
    grown = wm.Preview(plate, bounds=BOUNDS, resolution=24, covering="continuation", evaluator="interpreter")
    fresh = wm.mesh_surface(wm.box((2, 2, 0.6)) - wm.cylinder(0.1), bounds=BOUNDS, resolution=24,
                            covering="continuation")
    np.testing.assert_array_equal(grown.update(r=0.1).triangles, fresh.triangles)
    still = wm.Preview(wm.sphere(1.0), bounds=BOUNDS, resolution=16, evaluator="interpreter")
    assert still.params == {} and still.update().stats()["euler"] == 2
    with pytest.raises(ValueError, match="Unknown parameter 'r' in 'values'. Pick one of none"):
        still.update(r=0.1)


# ---------------------------------------------------------------- idle refinement
def _small_preview(**kw):
    boss = wm.param("boss", 0.5, lo=0.3, hi=0.7)
    return wm.Preview(wm.box((2, 2, 0.6)) | wm.sphere(boss), bounds=BOUNDS, resolution=16,
                      evaluator="interpreter", **kw)


def _fresh(boss, resolution):
    return wm.mesh_surface(wm.box((2, 2, 0.6)) | wm.sphere(boss), bounds=BOUNDS, resolution=resolution)


def test_refined_is_a_fresh_mesh_at_twice_the_resolution():
    view = _small_preview()
    assert view.refine_options == {"resolution": 32}
    view.update(boss=0.6)
    fine = view.refined()
    np.testing.assert_array_equal(fine.triangles, _fresh(0.6, 32).triangles)
    assert view.refined() is fine, "made once per edit"
    view.update(boss=0.4)
    assert view.refined_mesh is None, "an edit makes the refinement stale"
    np.testing.assert_array_equal(view.refined().triangles, _fresh(0.4, 32).triangles)


def test_a_watched_preview_refines_when_idle_and_drops_stale_work():
    view = _small_preview(idle=0.05)
    seen, landed = [], threading.Event()

    def watcher(mesh, kind):
        seen.append((kind, mesh.n_cells))
        if kind == "refined":
            landed.set()

    view.watch(watcher)
    for boss in (0.35, 0.45, 0.55):  # edits faster than the idle delay: only the last refines
        view.update(boss=boss)
    assert landed.wait(60), "no refinement landed"
    assert [k for k, _ in seen] == ["update"] * 3 + ["refined"]
    np.testing.assert_array_equal(view.refined_mesh.triangles, _fresh(0.55, 32).triangles)
    assert view.refined() is view.refined_mesh

    slow = _small_preview(idle=0.0)  # the refinement starts at once: an edit while it runs drops it
    gate, entered = threading.Event(), threading.Event()
    kinds = []
    slow.watch(lambda mesh, kind: kinds.append(kind))
    original = slow._mesh

    def held(values, finer=False):
        if finer:
            entered.set()
            gate.wait(30)
        return original(values, finer)

    slow._mesh = held
    slow.update(boss=0.4)
    # wait until the 0.4 refinement is inside `held` (on a loaded machine its thread may not have
    # started before the next edit, and then there is nothing stale to drop)
    assert entered.wait(30), "the refinement never started"
    slow.update(boss=0.6)  # the 0.4 refinement is waiting in `held`: it will be stale
    gate.set()
    deadline = time.monotonic() + 60
    while slow.refined_mesh is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert slow.dropped >= 1
    np.testing.assert_array_equal(slow.refined_mesh.triangles, _fresh(0.6, 32).triangles)
    assert kinds.count("refined") == 1


def test_a_newer_edit_cancels_a_running_refinement(monkeypatch):
    """The stale refinement stops at the pipeline's next checkpoint instead of running to its
    end: the first checkpoint of the 0.4 refinement is held until the 0.6 edit has come."""
    from warpmesh._util import cancel

    view = _small_preview(idle=0.0)
    view.watch(lambda mesh, kind: None)
    gate, entered = threading.Event(), threading.Event()
    original = cancel.checkpoint
    held = []

    def checkpoint():
        if threading.current_thread() is not threading.main_thread() and not held:
            held.append(1)
            entered.set()
            gate.wait(30)
        original()

    monkeypatch.setattr(cancel, "checkpoint", checkpoint)
    view.update(boss=0.4)
    assert entered.wait(30), "the refinement never reached a checkpoint"
    view.update(boss=0.6)
    gate.set()
    deadline = time.monotonic() + 60
    while view.refined_mesh is None and time.monotonic() < deadline:
        time.sleep(0.02)
    assert view.cancelled == 1 and view.dropped >= 1
    np.testing.assert_array_equal(view.refined_mesh.triangles, _fresh(0.6, 32).triangles)


def test_a_refinement_whose_show_comes_after_a_newer_edit_is_not_shown():
    """The race: a refinement passes its staleness check, then its thread is held before it
    draws; an edit meshes and shows meanwhile. The late show must not replace the edit's
    mesh (it was shown over it before), and a watcher may edit from its callback."""
    before = set(threading.enumerate())
    view = _small_preview(idle=0.0)
    shown = []
    view.watch(lambda mesh, kind: shown.append((kind, mesh)))
    held, release = threading.Event(), threading.Event()

    class HoldingLock:  # holds the refinement's thread just before it takes the show lock
        def __init__(self, lock):
            self.lock = lock

        def __enter__(self):
            if threading.current_thread() is not threading.main_thread() and not held.is_set():
                held.set()
                release.wait(30)
            return self.lock.__enter__()

        def __exit__(self, *exc):
            return self.lock.__exit__(*exc)

    view._show_lock = HoldingLock(view._show_lock)
    view.update(boss=0.4)
    assert held.wait(60), "the 0.4 refinement never came to show"
    latest = view.update(boss=0.6)  # meshes and shows while the 0.4 refinement waits to draw
    release.set()
    deadline = time.monotonic() + 60
    while view.refined_mesh is None or view.dropped == 0:
        assert time.monotonic() < deadline, "neither the stale show was dropped nor the 0.6 refinement landed"
        time.sleep(0.02)
    kinds = [k for k, _ in shown]
    assert kinds[:2] == ["update", "update"] and shown[1][1] is latest
    refined = [m for k, m in shown if k == "refined"]  # only the 0.6 refinement, if it landed yet
    assert all(np.array_equal(m.triangles, _fresh(0.6, 32).triangles) for m in refined)
    for thread in set(threading.enumerate()) - before:  # the refinements' threads end with the test
        thread.join(60)

    again = _small_preview(idle=0.0, refine=None)  # a watcher that edits from its callback: no deadlock
    edits = []

    def editor(mesh, kind):
        if kind == "update" and not edits:
            edits.append(1)
            again.update(boss=0.5)

    again.watch(editor)
    worker = threading.Thread(target=again.update, kwargs={"boss": 0.4}, daemon=True)
    worker.start()
    worker.join(60)
    assert not worker.is_alive(), "an edit from a watcher's callback deadlocked on the show lock"
    assert again.values == {"boss": 0.5}


def test_a_headless_preview_starts_no_thread():
    view = _small_preview(idle=0.0)
    before = threading.active_count()
    view.update(boss=0.5)
    assert threading.active_count() == before and view.refined_mesh is None


def test_refine_options_and_bad_values():
    assert _small_preview(refine=None).refine_options == {}
    assert _small_preview(refine=20).refine_options == {"resolution": 20}
    octree = wm.Preview(wm.sphere(1.0), bounds=BOUNDS, resolution=None, adaptive=True, max_level=5)
    assert octree.refine_options == {"max_level": 6}
    # as the docstring shows it: max_level alone (resolution's default left out, not passed with it)
    octree = wm.Preview(wm.sphere(1.0), bounds=BOUNDS, adaptive=True, max_level=5, tolerance=1e-4)
    assert octree.refine_options == {"max_level": 6} and "max_level 5" in repr(octree)
    assert octree.refined().n_cells > octree.mesh.n_cells
    # adaptive with neither: resolution 128's level, refined to twice it
    assert wm.Preview(wm.sphere(1.0), bounds=BOUNDS, adaptive=True).refine_options == {"resolution": 256}
    with pytest.raises(ValueError, match="not both"):
        wm.Preview(wm.sphere(1.0), bounds=BOUNDS, resolution=32, adaptive=True, max_level=5)
    with pytest.raises(ValueError, match="no refinement"):
        _small_preview(refine=None).refined()
    with pytest.raises(ValueError, match="'refine'"):
        _small_preview(refine=0)
    with pytest.raises(ValueError, match="Unknown refine 'fast'"):
        _small_preview(refine="fast")
    with pytest.raises(ValueError, match="'idle'"):
        _small_preview(idle=-1)
    with pytest.raises(TypeError, match="'callback'"):
        _small_preview().watch(3)


# -- found by a new-user probe (stop 50): watchers that edit or raise, edits from two threads, refine options


def _sphere_preview(**kw):
    r = wm.param("r", 0.5, lo=0.3, hi=0.7)
    return wm.Preview(wm.sphere(r), bounds=((-1,) * 3, (1,) * 3), resolution=16, evaluator="interpreter", **kw)


def test_a_watcher_that_edits_leaves_every_watcher_with_the_final_mesh():
    view = _sphere_preview(refine=None)
    seen = []
    view.watch(lambda mesh, kind: view.update(r=0.6) if view.values["r"] == 0.4 else None)
    view.watch(lambda mesh, kind: seen.append(mesh))
    view.update(r=0.4)
    assert view.values == {"r": 0.6}
    assert seen[-1] is view.mesh, "the older edit's show went on after the watcher's own edit"
    fresh = wm.mesh_surface(wm.sphere(0.6), bounds=((-1,) * 3, (1,) * 3), resolution=16)
    np.testing.assert_array_equal(seen[-1].triangles, fresh.triangles)


def test_edits_from_two_threads_keep_both_and_the_newest_mesh():
    r, h = wm.param("r", 0.5, lo=0.3, hi=0.7), wm.param("h", 0.5, lo=0.2, hi=0.9)
    shape = wm.sphere(r) | wm.box((0.4, 0.4, 1.0)).translate((0.0, 0.0, h))
    bounds = ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.5))
    view = wm.Preview(shape, bounds=bounds, resolution=12, evaluator="interpreter", refine=None)
    shown = []
    view.watch(lambda mesh, kind: shown.append(mesh))
    rs, hs = np.linspace(0.3, 0.7, 12), np.linspace(0.9, 0.2, 12)
    threads = [threading.Thread(target=lambda: [view.update(r=float(x)) for x in rs]),
               threading.Thread(target=lambda: [view.update(h=float(x)) for x in hs])]
    for t in threads:
        t.start()
    for t in threads:
        t.join(120)
    assert view.values == {"r": float(rs[-1]), "h": float(hs[-1])}, "an edit from one thread was lost"
    fresh = wm.mesh_surface(shape, bounds=bounds, resolution=12, params=view.values)
    np.testing.assert_array_equal(view.mesh.triangles, fresh.triangles)
    assert shown[-1] is view.mesh


def test_a_watcher_that_raises_does_not_stop_the_others_or_the_refinement():
    view = _sphere_preview(idle=0.0)
    good, landed = [], threading.Event()

    def bad(mesh, kind):
        if kind == "update":
            raise RuntimeError("watcher failed")

    def note(mesh, kind):
        good.append(kind)
        if kind == "refined":
            landed.set()

    view.watch(bad)
    view.watch(note)
    with pytest.raises(RuntimeError, match="watcher failed"):
        view.update(r=0.4)
    assert view.values == {"r": 0.4} and good[0] == "update"
    assert len(view.errors) == 1 and isinstance(view.errors[0], RuntimeError)
    assert landed.wait(60), "no refinement after the watcher's error"


def test_refine_options_are_checked_at_set_up_and_background_failures_are_kept():
    with pytest.raises(ValueError, match="'refine'.*'resolution'"):
        _sphere_preview(refine={"resolution": -3})
    with pytest.raises(ValueError, match="'refine'.*resolutoin"):
        _sphere_preview(refine={"resolutoin": 3})
    view = _sphere_preview(idle=0.0)
    original = view._mesh

    def failing(values, finer=False):
        if finer:
            raise MemoryError("refinement ran out of memory")
        return original(values, finer)

    view._mesh = failing
    view.watch(lambda mesh, kind: None)
    view.update(r=0.45)
    deadline = time.monotonic() + 60
    while not view.errors:
        assert time.monotonic() < deadline, "the refinement's failure was swallowed"
        time.sleep(0.02)
    assert isinstance(view.errors[0], MemoryError) and view.refined_mesh is None
