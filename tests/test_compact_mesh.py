"""Compact meshes (``Mesh(..., compact=True)``): float32 points, int32 cells and narrow refs
kept, float64 / int64 given by the accessors, never widened for counts, writes or pickles;
and the label-volume surfaces of ``interfaces="shared"``, which are returned compact."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import trimesh

import warpmesh as wm
from warpmesh.io.convert import host_arrays
from warpmesh.mesh import Mesh, narrowest_int


@pytest.fixture(scope="module")
def sphere() -> Mesh:
    tm = trimesh.creation.icosphere(subdivisions=2, radius=1.3)
    n, m = len(tm.vertices), len(tm.faces)
    return Mesh(tm.vertices + 0.1, {"triangle": tm.faces}, point_refs=np.arange(n) % 3,
                cell_refs={"triangle": np.arange(m) % 300 - 7}, cell_data={"q": {"triangle": np.ones(m)}})


def test_compact_keeps_narrow_arrays_and_gives_wide_ones(sphere):
    c = sphere.compact()
    kept = c.compact_arrays
    assert c.is_compact and not sphere.is_compact and c.compact() is c
    assert kept["points"].dtype == np.float32 and kept["cells"]["triangle"].dtype == np.int32
    assert kept["point_refs"].dtype == np.uint8 and kept["cell_refs"]["triangle"].dtype == np.int16
    n, m = sphere.n_points, len(sphere.triangles)
    expected = n * 12 + m * 12 + n + m * 2 + m * 8  # points, cells, refs, the float64 data as given
    assert c.nbytes == expected
    assert (c.n_points, c.n_cells, c.dim) == (sphere.n_points, sphere.n_cells, 3)
    assert "compact" in repr(c)
    assert c.nbytes == expected  # counts and repr made no float64 copies
    # the accessors: the host types, the float32-rounded coordinates, the same indices and refs
    assert c.points.dtype == np.float64 and c.triangles.dtype == np.int64
    assert np.array_equal(c.points, sphere.points.astype(np.float32).astype(np.float64))
    assert np.abs(c.points - sphere.points).max() <= 2.0**-23 * np.abs(sphere.points).max()
    assert np.array_equal(c.triangles, sphere.triangles)
    assert c.point_refs.dtype == np.int64 and np.array_equal(c.point_refs, sphere.point_refs)
    assert np.array_equal(c.cell_refs["triangle"], sphere.cell_refs["triangle"])
    assert c.points is c.points and not c.points.flags.writeable  # made once, read-only
    assert c.nbytes > expected  # now holding the copies too
    assert c.stats()["genus"] == 0 and c.stats()["self_intersections"] == 0


def test_narrowest_int_and_refs_of_32_bits_kept_as_given():
    assert [narrowest_int(*r).__name__ for r in [(0, 1), (-1, 1), (0, 60000), (-1, 60000), (0, 2**31)]] == \
        ["uint8", "int8", "uint16", "int32", "int64"]
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    refs = np.array([5], dtype=np.int32)
    c = Mesh(pts, {"triangle": [[0, 1, 2]]}, cell_refs={"triangle": refs}, compact=True)
    assert c.compact_arrays["cell_refs"]["triangle"].dtype == np.int32  # not narrowed: no copy of a producer's
    big = Mesh(pts, {"triangle": [[0, 1, 2]]}, cell_refs={"triangle": [2**40]}, compact=True)
    assert big.cell_refs["triangle"].tolist() == [2**40]


def test_replace_keeps_compact_only_for_info(sphere):
    c = sphere.compact()
    same = c.replace(info={"a": 1})
    assert same.is_compact and same.compact_arrays["points"] is c.compact_arrays["points"]
    moved = c.replace(points=c.points * 2)
    assert not moved.is_compact and np.array_equal(moved.points, c.points * 2)
    again = sphere.replace(compact=True)
    assert again.is_compact and np.array_equal(again.points, c.points)


def test_pickle_keeps_compact(sphere):
    c = sphere.compact()
    back = pickle.loads(pickle.dumps(c))
    assert back.is_compact and back.nbytes == c.nbytes
    assert np.array_equal(back.points, c.points) and np.array_equal(back.cell_refs["triangle"],
                                                                    c.cell_refs["triangle"])


@pytest.mark.parametrize("name", ["s.vtu", "s.mesh", "s.msh", "s.ply"])
def test_files_of_a_compact_mesh_leave_it_compact(sphere, tmp_path, name):
    c = sphere.compact()
    before = c.nbytes
    c.save(tmp_path / name)
    assert c.nbytes == before  # written from copies it does not keep
    p, cells, _, crefs = host_arrays(c)
    assert p.dtype == np.float64 and cells["triangle"].dtype == np.int64 and crefs["triangle"].dtype == np.int64
    assert c.nbytes == before
    back = wm.load(tmp_path / name)
    assert np.array_equal(p, c.points)
    assert np.allclose(back.points, c.points, rtol=0, atol=1e-6) and np.array_equal(back.triangles, c.triangles)
    if name != "s.ply":
        assert np.array_equal(back.cell_refs["triangle"], c.cell_refs["triangle"])


def test_compact_refuses_bad_input():
    tri = {"triangle": [[0, 1, 2]]}
    with pytest.raises(TypeError, match="'compact'"):
        Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], tri, compact="yes")
    with pytest.raises(ValueError, match=r"within float32's range \(compact=True\) in 'points'"):
        Mesh([[0, 0, 0], [1e300, 0, 0], [0, 1, 0]], tri, compact=True)
    with pytest.raises(ValueError, match="expected finite coordinates in 'points'"):
        Mesh([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]], tri, compact=True)
    with pytest.raises(ValueError, match="indices < n_points"):
        Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 3]]}, compact=True)


def _voronoi(n: int, k: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    seeds = rng.uniform(0, n, size=(k, 3))
    g = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    d = ((g[:, None, :] - seeds[None]) ** 2).sum(-1)
    return (np.argmin(d, axis=1) + 1).astype(np.uint8).reshape(n, n, n)


@pytest.mark.parametrize("dtype, origin, spacing", [(np.uint8, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)),
                                                    (np.int16, (-3.1, 0.7, 11.0), (0.3, 0.7, 1.1))])
def test_shared_label_surface_is_compact_and_exact(dtype, origin, spacing):
    vol = _voronoi(24, 9).astype(dtype)
    m = wm.mesh_surface(wm.Volume(vol, origin=origin, spacing=spacing), labels="all", interfaces="shared")
    kept = m.compact_arrays
    assert m.is_compact and kept["points"].dtype == np.float32 and kept["cells"]["triangle"].dtype == np.int32
    assert kept["cell_refs"]["triangle"].dtype == np.int16 and m.cell_data["label_above"]["triangle"].dtype == np.int16
    # 12 bytes a point and a triangle, 2 for each of its labels: what the kernels wrote, no copy
    assert m.nbytes == 12 * m.n_points + 16 * m.n_cells
    # every point the float32 rounding of its cube centre, computed here in float64
    o, h = np.asarray(origin), np.asarray(spacing)
    cube = np.floor((m.points - o) / h)
    assert np.array_equal(kept["points"], (o + (cube + 0.5) * h).astype(np.float32))
    s = m.stats()
    assert s["self_intersections"] == 0
    assert all(f["closed"] and f["oriented"] for f in s["label_boundaries"].values())
    lower, upper = m.cell_refs["triangle"], m.cell_data["label_above"]["triangle"]
    assert lower.dtype == np.int64 and np.all(lower < upper)
    # smoothing returns float64 points (what its fold checks proved), not compact
    smooth = wm.mesh_surface(wm.Volume(vol, origin=origin, spacing=spacing), labels="all", interfaces="shared",
                             smoothing=2)
    assert not smooth.is_compact and smooth.stats()["self_intersections"] == 0


def test_shared_label_surface_far_from_the_origin_keeps_float64():
    """Cube centres that float32 would blur (a grid at 1e6 with unit cells: float32's ulp
    there is 0.06) come out in float64, exact, and the mesh is not compact."""
    vol = _voronoi(10, 4)
    origin = (1.0e6, -2.0e6, 5.0)
    m = wm.mesh_surface(wm.Volume(vol, origin=origin, spacing=(1.0, 0.5, 1.0)), labels="all", interfaces="shared")
    assert not m.is_compact and m.compact_arrays["points"].dtype == np.float64
    cube = np.floor((m.points - origin) / (1.0, 0.5, 1.0))
    assert np.array_equal(m.points, origin + (cube + 0.5) * (1.0, 0.5, 1.0))
    near = wm.mesh_surface(vol, labels="all", interfaces="shared")
    assert np.array_equal(m.triangles, near.triangles) and m.stats()["self_intersections"] == 0


def test_conversions_and_checks_do_not_widen(sphere):
    """require_mesh (every operation's entry check) reads no accessor of a compact mesh; to_meshio
    works from copies the mesh does not keep."""
    c = sphere.compact()
    before = c.nbytes
    mm = c.to_meshio()
    assert c.nbytes == before
    assert mm.points.dtype == np.float64 and np.array_equal(mm.cells[0].data, sphere.triangles)


def test_compact_keeps_the_meshers_facts():
    ball = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=16)
    assert set(ball.stats()) == set(ball.compact().stats())
    assert ball.compact().stats()["vertices"] == ball.stats()["vertices"]


def test_refs_beyond_int64_refused():
    pts, tri = [[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]}
    for compact in (False, True):
        with pytest.raises(ValueError, match=r"cell_refs\['triangle'\] within int64"):
            Mesh(pts, tri, cell_refs={"triangle": np.array([2**63], np.uint64)}, compact=compact)
        with pytest.raises(ValueError, match="'point_refs' within int64"):
            Mesh(pts, tri, point_refs=np.array([0, 1, 2**64 - 1], np.uint64), compact=compact)


def test_points_beyond_float32_refused_without_a_warning():
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="float32's range"):
            Mesh([[0, 0, 0], [1e39, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]}, compact=True)


@pytest.mark.parametrize("origin, spacing", [((0.0, 0.0, 0.0), (10.0, 0.01, 0.1)),
                                             ((1e4, 0.0, 1e3), (100.0, 1.0, 10.0))])
def test_fortran_order_decides_compact_as_c_order(origin, spacing):
    v = np.random.default_rng(0).integers(0, 3, (4, 64, 16)).astype(np.uint8)
    c = wm.mesh_surface(wm.Volume(v, origin=origin, spacing=spacing), labels="all", interfaces="shared")
    f = wm.mesh_surface(wm.Volume(np.asfortranarray(v), origin=origin, spacing=spacing), labels="all",
                        interfaces="shared")
    assert c.is_compact == f.is_compact
    assert np.array_equal(np.unique(c.points, axis=0), np.unique(f.points, axis=0))


@pytest.mark.parametrize("dtype, top", [(np.int32, 100_000), (np.int64, 2**40), (np.float32, 70_000)])
def test_wide_label_values_use_compiled_overloads(dtype, top):
    """Wide volumes are coded by their count of regions (uint8 codes for a few), whatever their
    ids: every code type with every label type is compiled with the module, none at a launch."""
    import warpmesh.kernels.flying_edges as KF

    vol = _voronoi(12, 3).astype(dtype)
    vol[vol == 3] = top
    before = len(KF.emit_label_quads_kernel.overloads)
    m = wm.mesh_surface(vol, labels="all", interfaces="shared")
    assert len(KF.emit_label_quads_kernel.overloads) == before
    assert int(m.cell_data["label_above"]["triangle"].max()) == top
    assert m.cell_data["label_above"]["triangle"].dtype == (np.int64 if top > 2**31 else np.int32)
