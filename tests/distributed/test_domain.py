"""Bricked isosurface stuffing on a LocalCluster of two worker processes gives the single-process mesh.

The stuffed tetrahedra of the bricks, joined by their global lattice keys, are the ones one
process makes (the same tetrahedra as sets of vertex positions, the positions bit for bit,
and here even the same numbering); the host stages after stuffing (crease recovery) run on
the gathered mesh and give the same mesh too. Small lattices cut in bricks of 8 black nodes:
many seams, a few seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.distributed.run import PartitionedMesh

pytest.importorskip("dask.distributed")


def _domain(name):
    if name == "sphere":
        return wm.sphere(1.0), ((-1.2,) * 3, (1.2,) * 3), 0.12
    shape, bounds = wm.example(name)
    return shape, bounds, {"torus": 0.1, "part": 0.08}[name]


def tet_positions(mesh: wm.Mesh) -> np.ndarray:
    """(m, 12) the tetrahedra as sets of vertex positions: each one's four points sorted,
    the rows sorted."""
    p = mesh.points[mesh.cells["tetra"]]  # (m, 4, 3)
    p = np.take_along_axis(p, np.lexsort(p.transpose(2, 0, 1)[::-1])[..., None], axis=1).reshape(len(p), 12)
    return p[np.lexsort(p.T[::-1])]


def assert_same_domain(single: wm.Mesh, bricked: wm.Mesh) -> None:
    assert np.array_equal(tet_positions(single), tet_positions(bricked))  # float64, bit for bit
    # the vertices match one to one by position, exactly, and so do the boundary triangles
    order = [np.lexsort(m.points.T[::-1]) for m in (single, bricked)]
    assert np.array_equal(single.points[order[0]], bricked.points[order[1]])
    rank = [np.empty_like(o) for o in order]
    for r, o in zip(rank, order):
        r[o] = np.arange(len(o))
    tris = [np.sort(r[m.cells["triangle"]], axis=1) for r, m in zip(rank, (single, bricked))]
    assert np.array_equal(*(t[np.lexsort(t.T[::-1])] for t in tris))
    assert np.array_equal(single.cell_refs["triangle"][np.lexsort(tris[0].T[::-1])],
                          bricked.cell_refs["triangle"][np.lexsort(tris[1].T[::-1])])


@pytest.mark.parametrize("name", ["sphere", "torus", "part"])
@pytest.mark.parametrize("features", [False, True])
def test_domain_is_the_single_process_mesh(client, name, features):
    shape, bounds, size = _domain(name)
    single = wm.mesh_domain(shape, bounds=bounds, size=size, features=features)
    bricked = wm.mesh_domain(shape, bounds=bounds, size=size, features=features, client=client, brick_cells=8,
                             progress=False)
    assert_same_domain(single, bricked)
    # the gathered stuffing is numbered as one process numbers it, so the stages after it agree too
    assert np.array_equal(single.points, bricked.points)
    assert np.array_equal(single.cells["tetra"], bricked.cells["tetra"])
    info = bricked.info
    assert info["bricks_meshed"] + info["bricks_culled"] == info["bricks"] > 8
    assert info["seam_copies_welded"] > 0
    assert (info["cut_edges"], info["warped_nodes"]) == (single.info["cut_edges"], single.info["warped_nodes"])
    if features:
        assert info["feature_vertices"] == single.info["feature_vertices"]  # > 0 for the part


def test_flips_and_smoothing_run_on_the_gathered_mesh(client):
    shape, bounds, size = _domain("torus")
    kw = dict(bounds=bounds, size=size, smooth=1, flips=True)
    single = wm.mesh_domain(shape, **kw)
    bricked = wm.mesh_domain(shape, **kw, client=client, bricks=(3, 3, 2), progress=False)
    assert_same_domain(single, bricked)
    assert [s["stage"] for s in bricked.info["quality_stages"]] == ["stuffing", "features", "smooth", "flips"]


def test_killed_worker_is_retried_and_the_domain_is_identical(client, killer):
    shape, bounds, _ = _domain("part")
    single = wm.mesh_domain(shape, bounds=bounds, size=0.05, features=False)
    kill_one, killed = killer
    bricked = wm.mesh_domain(shape, bounds=bounds, size=0.05, features=False, client=client, brick_cells=8,
                             progress=kill_one)
    assert killed and bricked.info["bricks_meshed"] > 10
    assert np.array_equal(single.points, bricked.points)
    assert np.array_equal(single.cells["tetra"], bricked.cells["tetra"])
    assert killed[0] not in client.scheduler_info()["workers"]


def test_empty_bricks_are_never_tasks(client):
    ball = wm.sphere(0.3)
    bounds = ((-1.0,) * 3, (1.0,) * 3)
    done = []
    bricked = wm.mesh_domain(ball, bounds=bounds, size=0.1, features=False, client=client, brick_cells=8,
                             progress=lambda d, total: done.append(total))
    info = bricked.info
    # 27 bricks of 8^3 black nodes; the ball's interval is < 0 over the corner and edge bricks' nodes
    assert info["bricks"] == 27 and info["bricks_culled"] == 20
    assert info["bricks_meshed"] == 7 and done == [7] * 7
    assert_same_domain(wm.mesh_domain(ball, bounds=bounds, size=0.1, features=False), bricked)


def test_partitioned_output_writes_tet_pieces_and_a_pvtu(client, tmp_path):
    import meshio
    import pyvista as pv

    shape, bounds, size = _domain("part")
    single = wm.mesh_domain(shape, bounds=bounds, size=size, features=False)
    result = wm.mesh_domain(shape, bounds=bounds, size=size, features=False, client=client, brick_cells=16,
                            gather=False, output=tmp_path / "part.pvtu", progress=False)
    assert isinstance(result, PartitionedMesh)
    assert len(result.pieces) == len(list(tmp_path.glob("part_brick*.vtu"))) == result.info["bricks_meshed"] > 1
    assert result.n_cells == len(single.cells["tetra"])
    pieces = [meshio.read(p) for p in result.pieces]
    assert sum(len(m.cells_dict["tetra"]) for m in pieces) == result.n_cells
    grid = pv.read(str(result.path))
    assert (grid.n_points, grid.n_cells) == (result.n_points, result.n_cells)
    assert set(np.unique(grid.celltypes).tolist()) == {pv.CellType.TETRA}
    # the pieces' global lattice keys weld them to the single-process mesh's vertices
    keys = grid.point_data["lattice_key"]
    assert len(np.unique(keys)) == single.n_points
    assert np.isclose(grid.volume, single.stats()["volume"], rtol=1e-9)
    assert not list(tmp_path.glob(".*tmp"))
    loaded = wm.load(result.path)  # welded by the lattice keys: the single-process tetrahedra
    assert loaded.n_points == single.n_points and len(loaded.cells["tetra"]) == len(single.cells["tetra"])
    np.testing.assert_array_equal(np.unique(loaded.points, axis=0), np.unique(single.points, axis=0))
    assert np.isclose(loaded.stats()["volume"], single.stats()["volume"], rtol=1e-9)


def test_what_is_not_bricked_is_refused_naming_it(client, tmp_path):
    shape, bounds, size = _domain("sphere")
    base = dict(bounds=bounds, size=size, client=client, progress=False)
    pieces = dict(gather=False, output=tmp_path / "m.pvtu")
    cases = [
        (dict(**pieces), "'features'"),
        (dict(**pieces, features=False, smooth=2), "'smooth'"),
        (dict(**pieces, features=False, flips=True), "'flips'"),
        (dict(method="delaunay"), "method='delaunay'"),
        (dict(method="tetgen"), "method='tetgen'"),
        (dict(size=lambda p: np.full(len(p), 0.2)), "graded 'size'"),
        (dict(size="curvature"), "graded 'size'"),
        (dict(gather=False, features=False), "output="),
        (dict(brick_cells=12), "'brick_cells'"),
    ]
    for kwargs, match in cases:
        with pytest.raises(ValueError, match=match):
            wm.mesh_domain(shape, **{**base, **kwargs})
    with pytest.raises(ValueError, match="label volume.*drop 'client'"):
        wm.mesh_domain(np.ones((8, 8, 8), np.uint8), client=client)
    with pytest.raises(ValueError, match="planar domain.*drop 'client'"):
        wm.mesh_domain(wm.circle(1.0), ((-2, -2), (2, 2)), client=client)
    with pytest.raises(TypeError, match="'client'"):
        wm.mesh_domain(shape, bounds=bounds, client="tcp://here")
    with pytest.raises(ValueError, match="'bricks' applies to a run on a Dask cluster"):
        wm.mesh_domain(shape, bounds=bounds, bricks=(2, 2, 2))
    # no bar asked for without a cluster is never wrong (the CLI passes progress=False when
    # stderr is not a terminal)
    assert wm.mesh_domain(shape, bounds=bounds, size=0.5, progress=False).n_cells > 0
    assert wm.mesh_surface(shape, bounds=bounds, resolution=16, progress=False).n_cells > 0


def test_numpy_false_gather_refuses_the_whole_mesh_stages_too(client, tmp_path):
    # check_run takes a numpy bool for 'gather'; gather=np.False_ once skipped the refusal of
    # features/smooth/flips and returned the pieces without running them, in silence
    shape, bounds, size = _domain("sphere")
    base = dict(bounds=bounds, size=size, client=client, progress=False, gather=np.False_,
                output=tmp_path / "m.pvtu")
    for kwargs, match in [({}, "'features'"), (dict(features=False, smooth=2), "'smooth'"),
                          (dict(features=False, flips=True), "'flips'")]:
        with pytest.raises(ValueError, match=match):
            wm.mesh_domain(shape, **base, **kwargs)
    with pytest.raises(TypeError, match="'gather'"):  # not a bool: the type error, not a stage refused
        wm.mesh_domain(shape, **{**base, "gather": 0})
    assert isinstance(wm.mesh_domain(shape, **base, features=False), PartitionedMesh)


def test_windows_see_a_thin_gap_at_a_seam_as_the_whole_lattice():
    """Two slabs a gap of 0.9 h apart, the gap just past the seam of black node 8: an inside
    node's warp there depends on its outside neighbour's warp, which reads a cut point two
    edges further: a halo of 2 cells gives other tetrahedra (sphere, torus and part pass with
    2), the halo of WINDOW_HALO = 3 the whole lattice's. No cluster: the windows one by one."""
    from warpmesh.distributed.bricks import layout
    from warpmesh.distributed.domain import LatticeBrick, gather_keyed
    from warpmesh.frep.tape import tape_of
    from warpmesh.solid.stuffing import lattice_for, stuff, stuff_window

    box, h, gap = np.array([(-1.0,) * 3, (1.0,) * 3]), 0.1, 0.09
    dims, origin = lattice_for(box, h)
    x = origin[0] + 8.6 * h
    shape = wm.union(wm.box((x + 0.9 - gap / 2, 1.6, 1.6), center=((x - gap / 2 - 0.9) / 2, 0.0, 0.0)),
                     wm.box((0.9 - x - gap / 2, 1.6, 1.6), center=((x + gap / 2 + 0.9) / 2, 0.05, 0.0)))
    points, tets, on_surface, _ = stuff(shape, box, h)
    pieces = []
    for brick in layout(dims, brick_cells=8):
        local, t, surf, keys, owner, _, _ = stuff_window(tape_of(shape), box, h, brick.lo, brick.hi)
        cells, counts = np.unique(owner, return_counts=True)
        pieces.append(LatticeBrick(local.astype(np.float32), t.astype(np.int32), surf, keys, cells, counts))
    gathered = gather_keyed(pieces, origin)
    for a, b in zip((points, tets, on_surface), gathered):
        assert np.array_equal(a, b)
