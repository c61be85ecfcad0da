"""Gibbs renumbering against scipy's reverse Cuthill-McKee on randomly numbered meshes:
the profile [FG Table 17.1] is never larger on meshes with ends (plates, the CSG part,
the degree-six surface, a ball of tetrahedra), for several random numberings each.

On closed round surfaces (sphere, torus) every node is alike up to the discretisation and
the profile of either method moves by several per cent with where its search starts
(measured: Gibbs / scipy 0.97-1.08 on the sphere at 40 and 64, 0.80-1.005 on the torus at
64, over three numberings): there the bound is 1.10, as in test_renumber.py."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse.csgraph import reverse_cuthill_mckee

import warpmesh as wm
from tests.helpers.numbering_meshes import ball, plate, shuffled, sphere_surface
from warpmesh.numbering.graph import node_graph
from warpmesh.numbering.renumber import matrix_stats, renumber_graph


def _surface(name: str, resolution: int) -> wm.Mesh:
    shape, bounds = wm.example(name)
    return wm.mesh_surface(shape, bounds=bounds, resolution=resolution)


MESHES = {
    "plate-h0.02": (lambda: plate(0.02), 1.0),
    "part-64": (lambda: _surface("part", 64), 1.0),
    "degree6-48": (lambda: _surface("degree6", 48), 1.0),
    "ball-tetra": (lambda: ball(4), 1.0),
    "torus-64": (lambda: _surface("torus", 64), 1.10),
    "sphere-40": (lambda: sphere_surface(40), 1.10),
}
_CACHE: dict[str, wm.Mesh] = {}


def _new(order: np.ndarray) -> np.ndarray:
    new = np.empty(len(order), np.int64)
    new[order] = np.arange(len(order))
    return new


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", list(MESHES))
def test_gibbs_profile_at_most_scipy_rcm(name, seed):
    build, bound = MESHES[name]
    if name not in _CACHE:
        _CACHE[name] = build()
    mesh = shuffled(_CACHE[name], seed)
    graph = node_graph(mesh.cells, mesh.n_points)
    gibbs = renumber_graph(graph, "gibbs")
    assert np.array_equal(np.sort(gibbs), np.arange(mesh.n_points))
    ours = matrix_stats(graph, _new(gibbs))["profile"]
    theirs = matrix_stats(graph, _new(reverse_cuthill_mckee(graph, symmetric_mode=True)))["profile"]
    assert ours <= bound * theirs

