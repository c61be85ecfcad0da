"""Adaptive meshing on bricks (``mesh_surface(shape, adaptive=True, client=...)``) gives the
single-process mesh: the octree's deeper levels are built by the workers brick by brick
(:mod:`warpmesh.distributed.adaptive`), the client merges them into the one-process tree and
contours it, so the points and triangles are the same arrays, bit for bit. Small octrees
(max_level 6-7): a few seconds on the shared two-worker cluster.
"""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.distributed import adaptive as AD
from warpmesh.frep.tape import tape_of
from warpmesh.surface.adaptive.octree import LEAF, build_octree
from warpmesh.surface.adaptive.pipeline import mesh_adaptive

pytest.importorskip("dask.distributed")

SETTINGS = dict(min_level=None, tolerance=None, angles=None, chord=None, bound="interval", lipschitz=None, cap=True,
                prune=True)


def rod_beside_a_slab():
    """tests/surface/test_adaptive.py's two sheets in coarse leaves: a rod (x from -0.65 to
    0.65) above a slab's top; three octree rounds at max_level 6."""
    slab = wm.box((2.4, 2.4, 1.0), center=(0.0, 0.0, -0.42))
    rod = wm.capsule((-0.65, 0.125, 0.21), (0.65, 0.125, 0.21), 0.03)
    balls = [wm.sphere(0.12, center=(x, 0.125, 0.3)) for x in (-0.65, 0.65)]
    return wm.union(slab, rod, *balls, method="minmax"), ((-1.0,) * 3, (1.0,) * 3)


def assert_identical(single: wm.Mesh, bricked: wm.Mesh) -> None:
    assert np.array_equal(single.points, bricked.points)
    assert np.array_equal(single.triangles, bricked.triangles)
    refs = [m.cell_refs.get("triangle") if m.cell_refs else None for m in (single, bricked)]
    assert (refs[0] is None) == (refs[1] is None) and (refs[0] is None or np.array_equal(*refs))
    for key in ("leaves", "face_units", "crossings", "loops", "octree_rounds", "culled_fraction", "leaf_levels"):
        assert single.info[key] == bricked.info[key], key


@pytest.mark.parametrize("name, max_level, run", [
    ("part", 6, {"bricks": (2, 2, 1)}),
    ("degree6", 6, {"brick_cells": 32}),  # level-3 cells of 8 finest cells: 4 per brick side
    ("sphere", 6, {"bricks": (3, 1, 2), "features": False}),  # uneven cuts, another option group
])
def test_adaptive_bricks_are_the_single_process_mesh(client, name, max_level, run):
    shape, bounds = wm.example(name)
    extra = {k: v for k, v in run.items() if k == "features"}
    bricking = {k: v for k, v in run.items() if k != "features"}
    single = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=max_level, **extra)
    bricked = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=max_level, **extra, client=client,
                              progress=False, **bricking)
    assert_identical(single, bricked)
    assert bricked.info["brick_tasks"] >= 2 and bricked.info["brick_level"] >= 3
    assert len(wm.check(bricked)) == 0


def test_force_rounds_across_seams(client):
    """The rod's two-sheet leaves are found round after round along it, across the seams
    x = -0.5, 0, 0.5 of bricks=(4, 1, 1): three rounds as in one process, the same tree and
    mesh; a later round re-submits only the bricks that a new forced cell touches (it changes
    their cells or their collar's: the hanging nodes of their leaves), the others' results
    are kept."""
    shape, bounds = rod_beside_a_slab()
    single = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6, min_level=3)
    done = []
    bricked = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6, min_level=3, client=client,
                              bricks=(4, 1, 1), progress=lambda d, t: done.append((d, t)))
    assert single.info["octree_rounds"] == 3
    assert_identical(single, bricked)
    per_round = bricked.info["bricks_per_round"]
    assert len(per_round) == 3 and per_round[0] == 4 and 1 <= min(per_round[1:]) < 4, per_round
    assert sum(t for d, t in done if d == t) == bricked.info["brick_tasks"] == sum(per_round)
    s = bricked.stats()
    assert (s["euler"], s["components"]) == (4, 2) and len(wm.check(bricked)) == 0


def test_killed_worker_is_retried_and_the_adaptive_mesh_is_identical(client, killer):
    """A worker SIGKILLed once 3 of the part's bricks have finished: Dask re-runs its tasks on
    the other worker (each task depends only on its brick and the round's forced cells, so a
    re-run gives the same keyed arrays), and the joined mesh is the single-process one."""
    shape, bounds = wm.example("part")
    single = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6)
    kill_one, killed = killer
    bricked = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6, client=client, brick_cells=16,
                              progress=kill_one)
    assert killed and bricked.info["brick_tasks"] > 10
    assert_identical(single, bricked)
    assert killed[0] not in client.scheduler_info()["workers"]  # it is gone (its nanny starts a new one)


def test_culled_bricks_are_never_submitted(client):
    """A small ball around the common corner of 8 of 64 bricks: the other 56 hold no refined
    cell of the brick level (their cells' intervals culled them on the client) and never
    become tasks (the progress callback sees 8)."""
    shape, bounds = wm.sphere(0.3, center=(-0.5, -0.5, -0.5)), ((-1.0,) * 3, (1.0,) * 3)
    totals = set()
    bricked = wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6, client=client, bricks=(4, 4, 4),
                              progress=lambda d, t: totals.add(t))
    assert totals == {8} and bricked.info["bricks_culled"] == 56 and bricked.info["brick_tasks"] == 8
    assert_identical(wm.mesh_surface(shape, bounds=bounds, adaptive=True, max_level=6), bricked)


def test_windowed_builds_merge_into_the_whole_tree():
    """No cluster: the bricks' windowed builds (the workers' task, run here one by one), merged
    with the client's levels, are the whole tree array for array, with forced leaves too."""
    shape, bounds = rod_beside_a_slab()
    lo, hi = (np.asarray(b, np.float64) for b in bounds)
    tape = tape_of(shape)
    first = build_octree(tape, lo, hi, max_level=5, **SETTINGS, device="cpu")
    lv, _ = AD.split_keys(first.status[0])
    coarse_leaves = first.status[0][(first.status[1] == LEAF) & (lv < 5)]
    # some leaves forced, as a two-sheet round forces them; bricks of base cells, and of their children
    for force, bricks, level in ((None, (2, 3, 1), 3), (coarse_leaves[::3], (5, 10, 1), 4)):
        whole = build_octree(tape, lo, hi, max_level=5, **SETTINGS, force=force, device="cpu")
        bricked = AD.BrickedOctree(shape, lo, hi, 5, client=None, bricks=bricks, brick_cells=None, progress=False)
        merged = bricked(tape, lo, hi, max_level=5, **SETTINGS, force=force, device="cpu")
        assert bricked.level == level and bricked.info["brick_tasks"] > 1
        assert np.array_equal(merged.leaf_level, whole.leaf_level)
        assert np.array_equal(merged.leaf_ijk, whole.leaf_ijk)
        for a, b in zip(merged.status, whole.status):
            assert np.array_equal(a, b)
        assert np.array_equal(merged.nodes.values, whole.nodes.get(merged.nodes.keys))
    assert len(merged.leaf_level) > len(first.leaf_level)  # the forced leaves were refined


def test_workers_contour_their_leaves_on_uneven_bricks_with_brick_level_leaves(client):
    """The face units, crossings and roots of each brick's leaves are made on its worker (on the
    brick and its collar) and joined by key on the client: bricks=(3, 2, 1) cut the 8 base cells
    unevenly (3, 2, 3), min_level=3 keeps leaves at the brick level (the slab's cap leaves), and
    the forced rounds run across the seams; the mesh is the single-process one."""
    shape, bounds = rod_beside_a_slab()
    run = dict(bounds=bounds, adaptive=True, max_level=6, min_level=3)
    single = wm.mesh_surface(shape, **run)
    bricked = wm.mesh_surface(shape, **run, client=client, bricks=(3, 2, 1), progress=False)
    assert bricked.info["brick_level"] == 3 and single.info["leaf_levels"].get(3, 0) > 0
    assert single.info["octree_rounds"] > 1
    assert "join_crossings" in bricked.info["time"]  # the client joined the workers' crossings
    assert_identical(single, bricked)


def test_leaves_above_the_brick_level_are_contoured_on_their_own_window():
    """No cluster: bricks of level-4 cells (5, 10, 1) leave the slab's cap leaves at level 3
    spanning bricks; they are contoured together on one window of theirs, and the joined arrays
    (in any order of the pieces) are the one-process ones."""
    shape, bounds = rod_beside_a_slab()
    lo, hi = (np.asarray(b, np.float64) for b in bounds)
    opts = dict(SETTINGS, max_level=5, min_level=3, features=True, root="newton", root_iterations=None,
                gradient="exact", device="cpu")
    single = mesh_adaptive(tape_of(shape), lo, hi, **opts, timings={}, info={})
    build = AD.BrickedOctree(shape, lo, hi, 5, client=None, bricks=(5, 10, 1), brick_cells=None, progress=False)
    info: dict = {}
    bricked = mesh_adaptive(tape_of(shape), lo, hi, **opts, timings={}, info=info, build=build)
    assert build.level == 4 and build.info["coarse_leaves"] > 0 and info["octree_rounds"] > 1
    for a, b in zip(single, bricked):
        assert (a is None and b is None) or np.array_equal(a, b)
    # the last round again (its bricks kept): the tree and its crossing pieces
    tree = build(tape_of(shape), lo, hi, **dict(SETTINGS, min_level=3), max_level=5, device="cpu",
                 force=build.force, roots=dict(root="newton", root_iterations=None, gradient="exact"))
    joined = AD.join_crossings(tree, build.crossing_pieces)
    again = AD.join_crossings(tree, build.crossing_pieces[::-1])
    for a, b in zip(joined, again):
        assert np.array_equal(a, b)
    assert len(joined[2]) > 0


def test_bad_options_are_refused_naming_them(client, tmp_path):
    part, bounds = wm.example("part")
    run = dict(bounds=bounds, adaptive=True, max_level=6, client=client, progress=False)
    with pytest.raises(ValueError, match="gather=False"):
        wm.mesh_surface(part, **run, gather=False, output=tmp_path / "p.pvtu")
    with pytest.raises(ValueError, match="'output'"):
        wm.mesh_surface(part, **run, output=tmp_path / "p.pvtu")
    with pytest.raises(ValueError, match="'bricks'"):
        wm.mesh_surface(part, **run, bricks=(0, 1, 1))
    with pytest.raises(ValueError, match="'bricks'"):
        wm.mesh_surface(part, **run, bricks=(64, 1, 1))  # finer than the level above max_level
    with pytest.raises(ValueError, match="'brick_cells'"):
        wm.mesh_surface(part, **run, brick_cells=3)
    with pytest.raises(ValueError, match="'brick_cells'"):
        wm.mesh_surface(part, **run, brick_cells=0)
    with pytest.raises(ValueError, match="not both"):
        wm.mesh_surface(part, **run, bricks=(2, 2, 1), brick_cells=16)
    with pytest.raises(TypeError, match="'client'"):
        wm.mesh_surface(part, bounds=bounds, adaptive=True, max_level=6, client="tcp://nowhere:1")
    with pytest.raises(ValueError, match="continuation"):
        wm.mesh_surface(part, bounds=bounds, covering="continuation", client=client)


def test_nan_below_the_brick_level_fails_naming_the_brick_and_its_box(client):
    """NaN in a ball of radius 0.1 around (0.5, 0.5, 0.5), inside one level-3 cell: the client's
    levels do not see it, the worker of brick 7 does, and the call's error names that brick
    (its cells of the brick level) and its box."""
    x, y, z = wm.coords()
    nan_ball = wm.Shape(wm.log((x - 0.5) ** 2 + (y - 0.5) ** 2 + (z - 0.5) ** 2 - 0.01) - 10.0)
    named = r"brick 7 \(1, 1, 1\): cells \[4:8, 4:8, 4:8\], box \(0, 0, 0\)-\(1, 1, 1\): .*NaN"
    with pytest.raises(ValueError, match=named):
        wm.mesh_surface(wm.sphere(0.4) | nan_ball, bounds=((-1,) * 3, (1,) * 3), adaptive=True, max_level=5,
                        client=client, bricks=(2, 2, 2), progress=False)
