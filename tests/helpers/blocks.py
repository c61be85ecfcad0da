"""Small structured meshes built in code: jittered Delaunay squares, Kuhn tetrahedra and
hexahedra of the unit cube."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

from warpmesh.cells.reference import cell_measures, reference_cell
from warpmesh.mesh import Mesh


def positive(points, cells, t):
    """cells with the negatively oriented ones mirrored."""
    neg = cell_measures(points, cells, t) < 0
    cells = cells.copy()
    cells[neg] = cells[neg][:, reference_cell(t).mirror]
    return cells


def tri_square(n=12, jitter=0.3, seed=0):
    """Delaunay triangles of a jittered n x n grid of [0, 1]^2 (boundary nodes on the sides)."""
    g = np.linspace(0, 1, n)
    x, y = np.meshgrid(g, g, indexing="ij")
    p = np.stack([x.ravel(), y.ravel()], axis=1)
    inner = ((p > 0) & (p < 1)).all(axis=1)
    p[inner] += np.random.default_rng(seed).uniform(-jitter, jitter, (inner.sum(), 2)) / (n - 1)
    t = Delaunay(p).simplices
    return Mesh(p, {"triangle": positive(p, t, "triangle")})


def kuhn_block(n=5):
    """n^3 cubes of [0, 1]^3, each split into the 6 Kuhn tetrahedra."""
    g = np.arange(n + 1)
    idx = lambda i, j, k: (i * (n + 1) + j) * (n + 1) + k  # noqa: E731
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1) / n
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
    tets = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        c = np.stack([i, j, k], axis=1)
        path = [c.copy()]
        for ax in perm:
            c = c.copy()
            c[:, ax] += 1
            path.append(c)
        tets.append(np.stack([idx(*q.T) for q in path], axis=1))
    t = np.concatenate(tets)
    return Mesh(pts, {"tetra": positive(pts, t, "tetra")})


def hex_block(n=4, shape=(1.0, 1.0, 1.0)):
    g = np.arange(n + 1)
    idx = lambda i, j, k: (i * (n + 1) + j) * (n + 1) + k  # noqa: E731
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1) / n * np.array(shape)
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij"))
    h = np.stack([idx(i, j, k), idx(i + 1, j, k), idx(i + 1, j + 1, k), idx(i, j + 1, k),
                  idx(i, j, k + 1), idx(i + 1, j, k + 1), idx(i + 1, j + 1, k + 1), idx(i, j + 1, k + 1)], axis=1)
    return Mesh(pts, {"hexahedron": h})
