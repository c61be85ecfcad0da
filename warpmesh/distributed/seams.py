"""Welding the bricks' meshes across their seams by global grid-edge keys, in one pass.

Every brick numbers its own vertices; those on a seam (an edge lying in a face of the
brick's core shared with a neighbour) carry the key ``node * 8 + type`` of their edge in
the whole grid, the same in every brick that emits them. The weld keeps the last copy of
each key in brick order (the highest brick id, so the result does not depend on which
brick finished first: the brick that has every seam plane through the vertex as a lower
face, which :mod:`warpmesh.distributed.run` relies on), renumbers the kept vertices in
order and remaps the triangles: an exact join on integers, no position tolerance, touching
only the seam vertices.

Example
-------
>>> import numpy as np
>>> from warpmesh.distributed.seams import BrickMesh, weld
>>> a = BrickMesh(np.zeros((3, 3)), np.array([[0, 1, 2]]), None, np.array([1, 2]), np.array([10, 11]))
>>> b = BrickMesh(np.ones((3, 3)), np.array([[0, 2, 1]]), None, np.array([0, 1]), np.array([11, 10]))
>>> points, faces, refs = weld([a, b])
>>> len(points), faces.tolist()
(4, [[0, 2, 1], [1, 3, 2]])
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from warpmesh import _conventions as C


@dataclass
class BrickMesh:
    """One brick's surface: points (m, 3) as float32 offsets from ``origin`` (float64; the
    world position is ``origin + points``, added in float64), triangles (t, 3) int32 into
    them, triangle refs (t,) or None, the local ids of its seam vertices and their global
    keys; ``info`` the brick's counts and timings. (float32 and int32: half the bytes
    sent from the worker.)"""

    points: np.ndarray
    faces: np.ndarray
    refs: np.ndarray | None
    seam: np.ndarray
    seam_keys: np.ndarray
    info: dict = field(default_factory=dict)
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))


def weld(pieces: list[BrickMesh]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One mesh from the bricks' meshes (in the order given), seams welded by key.

    Returns points (n, 3) float64, triangles (t, 3) int64 and triangle refs (t,) int64
    (None when no piece has refs).
    """
    sizes = np.array([len(p.points) for p in pieces], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    n = int(starts[-1])
    seam = np.concatenate([p.seam.astype(np.int64) + s for p, s in zip(pieces, starts)] or [np.zeros(0, np.int64)])
    keys = np.concatenate([p.seam_keys.astype(np.int64) for p in pieces] or [np.zeros(0, np.int64)])
    remap = np.arange(n, dtype=C.INDEX_DTYPE)
    if len(keys):  # every copy of a key -> its last copy (highest brick id): the first of the reversed keys
        _, first, inverse = np.unique(keys[::-1], return_index=True, return_inverse=True)
        remap[seam] = seam[len(keys) - 1 - first][inverse.reshape(-1)[::-1]]
    keep = remap == np.arange(n)
    new_index = np.cumsum(keep, dtype=C.INDEX_DTYPE) - 1
    points = np.empty((int(keep.sum()), 3), dtype=C.REAL_DTYPE)
    at = 0
    for p, s in zip(pieces, starts):  # float64 = float32 offset + the brick's origin, one piece at a time
        mine = p.points[keep[s:s + len(p.points)]]
        points[at:at + len(mine)] = mine
        points[at:at + len(mine)] += p.origin
        at += len(mine)
    faces = np.concatenate([p.faces.astype(C.INDEX_DTYPE) + s for p, s in zip(pieces, starts)]
                           or [np.zeros((0, 3), C.INDEX_DTYPE)])
    faces = new_index[remap[faces]]
    refs = None
    if any(p.refs is not None for p in pieces):
        refs = np.concatenate([p.refs if p.refs is not None else np.full(len(p.faces), C.SURFACE_REF)
                               for p in pieces]).astype(C.INDEX_DTYPE)
    return points, faces, refs
