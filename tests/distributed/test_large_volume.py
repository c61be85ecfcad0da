"""The issue's 1024 x 512 x 512 volume, read from a zarr store brick by brick, gives the
single-process mesh.

The volume is a truncated signed distance (a TSDF, as depth-camera fusion and level-set
codes store them) of five balls of radii 60-140 voxels, clipped to +-3 voxels: 1 GiB of
float32 in memory, a few MB on disk (the constant chunks compress to nothing), 1.8 M
triangles. It is written chunk by chunk, so the test process never builds it whole before
the single-process reference reads it back. The bricked run reads only its bricks
(128^3 cells each, 128 bricks) on the two worker processes of the cluster.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import sparse
from scipy.sparse import csgraph

import warpmesh as wm
from tests.distributed.test_cluster import assert_same_mesh
from tests.helpers.meshcheck import check_mesh

distributed = pytest.importorskip("dask.distributed")
dask = pytest.importorskip("dask")
da = pytest.importorskip("dask.array")
zarr = pytest.importorskip("zarr")

SHAPE = (1024, 512, 512)
CHUNK = 128
#: (centre, radius) in voxels; three balls reach across brick seams on every axis
BALLS = (((200, 150, 260), 90), ((520, 330, 240), 140), ((830, 250, 300), 110), ((420, 160, 120), 60),
         ((700, 400, 420), 70))
TRUNCATION = np.float32(3.0)


def _tsdf(block: np.ndarray, block_info=None) -> np.ndarray:
    """The truncated distance to the union of the balls on the block's voxels."""
    (x0, x1), (y0, y1), (z0, z1) = block_info[0]["array-location"]
    i = np.arange(x0, x1, dtype=np.float32)[:, None, None]
    j = np.arange(y0, y1, dtype=np.float32)[None, :, None]
    k = np.arange(z0, z1, dtype=np.float32)[None, None, :]
    out = np.full(block.shape, -TRUNCATION, np.float32)
    for (cx, cy, cz), r in BALLS:
        np.maximum(out, np.float32(r) - np.sqrt((i - cx) ** 2 + (j - cy) ** 2 + (k - cz) ** 2), out=out)
    return np.clip(out, -TRUNCATION, TRUNCATION)


def test_1024x512x512_zarr_volume_is_the_single_process_mesh(client, tmp_path):
    path = str(tmp_path / "tsdf.zarr")
    lazy = da.zeros(SHAPE, chunks=CHUNK, dtype=np.float32).map_blocks(_tsdf, dtype=np.float32)
    with dask.config.set(scheduler="threads"):  # written by the test process, not the cluster
        lazy.to_zarr(path)
    source = da.from_zarr(path)
    assert source.shape == SHAPE and source.dtype == np.float32

    bricked = wm.mesh_surface(source, spacing=0.25, origin=(-1.0, 0.0, 2.0), client=client, progress=False)
    assert bricked.info["bricks"] == (1023 // CHUNK + 1) * (511 // CHUNK + 1) ** 2

    volume = source.compute(scheduler="threads")
    single = wm.mesh_surface(volume, spacing=0.25, origin=(-1.0, 0.0, 2.0))
    del volume
    assert single.n_cells > 1_000_000
    assert_same_mesh(single, bricked)
    # five separate balls, each closed and inside the box: 5 components of genus 0 (chi 10)
    counts = check_mesh(bricked)
    assert counts["n_points"] - counts["n_edges"] + counts["n_faces"] == 2 * len(BALLS)
    tris = bricked.triangles
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]]])
    graph = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(bricked.n_points,) * 2)
    assert csgraph.connected_components(graph, directed=False)[0] == len(BALLS)
