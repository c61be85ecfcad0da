"""Meshes for the numbering and colouring tests, made in code (and pyvista's bundled
``hexbeam.vtk``, a mesh no one here made), and a random renumbering of any mesh."""

from __future__ import annotations

import functools
import os

import numpy as np
from scipy.spatial import Delaunay

import warpmesh as wm

HOLES = (((-1.0, 0.0), 0.5), ((0.8, 0.3), 0.4), ((1.4, -0.5), 0.25))


def plate(h: float, seed: int = 0) -> wm.Mesh:
    """A 2D triangle mesh of the 4 x 2 plate with three round holes: Delaunay of a
    jittered lattice and boundary points, triangles inside the holes dropped."""
    rng = np.random.default_rng(seed)
    xs, ys = np.arange(-2 + h, 2 - h / 2, h), np.arange(-1 + h, 1 - h / 2, h)
    p = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2) + rng.uniform(-0.3 * h, 0.3 * h, (len(xs) * len(ys), 2))
    keep = np.ones(len(p), bool)
    for c, r in HOLES:
        keep &= np.hypot(*(p - c).T) > r + 0.5 * h
    boundary = []
    for c, r in HOLES:
        t = np.linspace(0, 2 * np.pi, int(2 * np.pi * r / h), endpoint=False)
        boundary.append(np.c_[c[0] + r * np.cos(t), c[1] + r * np.sin(t)])
    for x in np.arange(-2, 2, h):
        boundary.append(np.array([[x, -1], [x + h, 1]]))
    for y in np.arange(-1, 1, h):
        boundary.append(np.array([[-2, y + h], [2, y]]))
    p = np.concatenate([p[keep]] + boundary)
    tri = Delaunay(p).simplices
    centre = p[tri].mean(axis=1)
    inside = np.ones(len(tri), bool)
    for c, r in HOLES:
        inside &= np.hypot(*(centre - c).T) > r
    tri = tri[inside]
    a, b, c = (p[tri[:, k]] for k in range(3))
    area = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    tri = tri[np.abs(area) > 1e-9 * h * h]  # Delaunay's flat triangles on collinear boundary points
    area = area[np.abs(area) > 1e-9 * h * h]
    tri[area < 0] = tri[area < 0][:, [0, 2, 1]]
    return wm.Mesh(p, {"triangle": tri})


@functools.cache
def sphere_surface(resolution: int = 40) -> wm.Mesh:
    """warpmesh's own marching-cubes mesh of the unit sphere."""
    return wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=resolution)


@functools.cache
def ball(subdivisions: int = 3) -> wm.Mesh:
    """Tetrahedra of the unit ball: TetGen (default quality) inside an icosphere
    (subdivisions 2, 3, 4: about 300, 1,500, 9,000 nodes)."""
    import tetgen
    import trimesh

    surface = wm.Mesh.from_trimesh(trimesh.creation.icosphere(subdivisions))
    nodes, elems = tetgen.TetGen(surface.to_pyvista()).tetrahedralize(order=1, quiet=True)[:2]
    return wm.Mesh(nodes, {"tetra": elems})


def hexbeam() -> wm.Mesh:
    """pyvista's bundled hexahedral beam (a real mesh: 99 points, 40 hexahedra)."""
    import pyvista as pv

    path = os.path.join(os.path.dirname(pv.__file__), "examples", "hexbeam.vtk")
    return wm.Mesh.from_pyvista(pv.read(path))


def shuffled(mesh: wm.Mesh, seed: int = 0) -> wm.Mesh:
    """The same mesh with its points in a random order (cells, refs and data follow)."""
    perm = np.random.default_rng(seed).permutation(mesh.n_points)  # new -> old
    new = np.empty_like(perm)
    new[perm] = np.arange(len(perm))
    return mesh.replace(
        points=mesh.points[perm],
        cells={t: new[c] for t, c in mesh.cells.items()},
        point_refs=None if mesh.point_refs is None else mesh.point_refs[perm],
        point_data={k: v[perm] for k, v in mesh.point_data.items()},
    )
