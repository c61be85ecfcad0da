"""The brick layout, the seam test on keys and the weld, without a cluster."""

import numpy as np
import pytest

from warpmesh.distributed.bricks import Brick, axis_cuts, check_bricking, layout, on_seams
from warpmesh.distributed.seams import BrickMesh, weld
from warpmesh.kernels import emit as KE


def test_bricks_tile_the_grid_on_block_boundaries():
    cells = (100, 37, 8)
    bricks = layout(cells, bricks=(3, 2, 1))
    assert len(bricks) == 6 and [b.index for b in bricks] == list(range(6))
    covered = np.zeros(cells, dtype=int)
    for b in bricks:
        covered[b.lo[0]:b.hi[0], b.lo[1]:b.hi[1], b.lo[2]:b.hi[2]] += 1
        assert all(v % 8 == 0 for v in b.lo)
    assert np.all(covered == 1)  # every cell in exactly one core
    assert axis_cuts(100, brick_cells=32) == [0, 32, 64, 96, 100]
    assert len(layout((256, 256, 256))) == 8  # the default: 128 cells a side


def test_seam_vertices_are_the_edges_in_shared_faces():
    cells = np.array([32, 32, 32])
    brick = Brick(0, (0, 0, 0), (0, 0, 0), (16, 32, 32))  # one seam: the plane x = 16
    nx, ny = 33, 33

    def key(i, j, k, t):
        return (i + nx * (j + ny * k)) * 8 + t

    keys = np.array([key(16, 3, 4, 1), key(16, 3, 4, 2), key(16, 3, 4, 0), key(15, 3, 4, 0), key(0, 3, 4, 1),
                     key(16, 3, 4, 5), key(16, 3, 4, 3), key(16, 3, 4, KE.CENTER)], dtype=np.int64)
    # y and z edges and the yz diagonal in x = 16 are on the seam; x edges, the grid's own face,
    # diagonals leaving the plane and interior vertices are not
    assert on_seams(keys, brick, cells).tolist() == [True, True, False, False, False, True, False, False]


def test_weld_joins_equal_keys_only_and_keeps_the_lower_brick():
    a = BrickMesh(np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]]), np.array([[0, 1, 2]]), np.array([1]),
                  np.array([1, 2]), np.array([7, 9]))
    b = BrickMesh(np.array([[1.0, 1, 0], [2, 0, 0], [1, 0, 0]]), np.array([[0, 2, 1]]), np.array([2]),
                  np.array([0, 2]), np.array([9, 7]))
    points, faces, refs = weld([a, b])
    assert len(points) == 4 and refs.tolist() == [1, 2]
    assert np.array_equal(points[faces[1]], [[1, 1, 0], [1, 0, 0], [2, 0, 0]])


@pytest.mark.parametrize("kwargs, match", [
    (dict(bricks=(2, 2)), "three positive ints"),
    (dict(bricks=(0, 1, 1)), "three positive ints"),
    (dict(bricks=(1.5, 1, 1)), "three positive ints"),
    (dict(brick_cells=12), "multiple of 8"),
    (dict(brick_cells=0), "multiple of 8"),
    (dict(brick_cells=True), "multiple of 8"),
    (dict(bricks=(1, 1, 1), brick_cells=16), "not both"),
])
def test_bad_bricking_is_refused_naming_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        check_bricking(kwargs.get("bricks"), kwargs.get("brick_cells"))


def test_more_bricks_than_blocks_is_refused():
    with pytest.raises(ValueError, match="at most 2 bricks.*'bricks'"):
        layout((16, 16, 16), bricks=(3, 1, 1))


def test_pieces_read_back_by_meshio_and_pyvista(tmp_path):
    """write_piece (warpmesh.io.vtu's writer): triangles with refs and tetrahedra, many zlib
    blocks and Int32 connectivity, read back equal by both readers; the .pvtu too."""
    meshio = pytest.importorskip("meshio")
    pv = pytest.importorskip("pyvista")
    from warpmesh.distributed.output import write_piece, write_pvtu

    rng = np.random.default_rng(5)
    points = rng.random((60_000, 3)) * 1e3 - 500.0  # 1.4 MB of Float64: 44 blocks
    for k, vtk in ((3, 5), (4, 10)):
        cells = rng.integers(0, len(points), (50_000, k))
        keys = rng.integers(0, 2**62, len(points))
        refs = rng.integers(-3, 9, len(cells)) if k == 3 else None
        path = write_piece(tmp_path / f"m{k}_brick00000.vtu", points, cells, refs, keys)
        m = meshio.read(path)
        assert np.array_equal(m.points, points) and np.array_equal(m.cells[0].data, cells)
        assert m.cells[0].type == ("triangle" if k == 3 else "tetra")
        assert np.array_equal(m.point_data["grid_edge_key"], keys)
        assert refs is None or np.array_equal(m.cell_data["ref"][0], refs)
        grid = pv.read(str(write_pvtu(tmp_path / f"m{k}.pvtu", [path.name], refs=refs is not None)))
        assert np.array_equal(np.asarray(grid.points), points) and np.array_equal(grid.cells_dict[vtk], cells)
        assert np.array_equal(grid.point_data["grid_edge_key"], keys)
        assert refs is None or np.array_equal(grid.cell_data["ref"], refs)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m3.pvtu", "m3_brick00000.vtu", "m4.pvtu",
                                                          "m4_brick00000.vtu"]  # no temporary left
