"""Operations estimate their output before allocating and refuse above the memory budget
(issue 19 items 4 and 6): a SizeError naming the argument and the size, within a second."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm
from warpmesh._util.budget import ENV, memory_budget
from warpmesh.errors import SizeError, WarpMeshError

BOX = ((-1, -1, -1), (1, 1, 1))


@pytest.fixture(scope="module")
def sphere():
    return wm.mesh_surface(wm.sphere(0.5), bounds=BOX, resolution=8)


REFUSED = {
    "refine n": (lambda m: m.refine(10**4), "'n'"),
    "refine max_length": (lambda m: m.refine(max_length=1e-7), "'max_length'"),
    "refine callable max_length": (lambda m: m.refine(max_length=lambda x: np.full(len(x), 1e-7)), "'max_length'"),
    "periodic copies": (lambda m: m.periodic(np.diag([2.0, 2.0, 2.0, 1.0]), 10**7), "'copies'"),
    "mesh_curve resolution": (lambda m: wm.mesh_curve(wm.circle(0.5), bounds=((-1, -1), (1, 1)), method="grid",
                                                      resolution=10**5), "'resolution'"),
}


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_too_large_is_refused_before_any_work(sphere, case):
    run, argument = REFUSED[case]
    with pytest.raises(SizeError, match=f"would need about .* GB.*budget.*{argument}") as info:
        run(sphere)
    assert isinstance(info.value, ValueError) and isinstance(info.value, WarpMeshError)


def test_the_budget_follows_the_environment(sphere, monkeypatch):
    monkeypatch.setenv(ENV, "200K")
    assert memory_budget() == 200 * 1024
    with pytest.raises(SizeError, match="refine"):
        sphere.refine(8)  # 104 * 64 triangles: ~1 MB with temporaries
    monkeypatch.setenv(ENV, "1G")
    assert sphere.refine(8).n_cells == 104 * 64
    monkeypatch.setenv(ENV, "lots")
    with pytest.raises(ValueError, match=ENV):
        memory_budget()


def test_default_budget_is_half_the_memory(monkeypatch):
    monkeypatch.delenv(ENV, raising=False)
    assert 2**28 <= memory_budget() <= 2**50


def test_sizes_within_the_budget_still_run(sphere):
    assert sphere.refine(2).n_cells == 4 * 104
    assert sphere.refine(max_length=0.1).n_cells > 104
    assert wm.mesh_curve(wm.circle(0.5), bounds=((-1, -1), (1, 1)), method="grid", resolution=64).n_cells > 0


def test_a_tiny_pattern_s_many_copies_are_refused_too():
    """A one-quad pattern's 10**7 copies passed a budget of their arrays alone (3 GB) and then
    ran for hours (about 1 ms a copy): each copy's Python objects count as well."""
    quad = wm.Mesh([[0, 0], [1, 0], [1, 1], [0, 1]], {"quad": [[0, 1, 2, 3]]})
    with pytest.raises(wm.SizeError, match="'copies'"):
        quad.periodic(wm.transforms.translation((1, 0)), 10**7)
    assert quad.periodic(wm.transforms.translation((1, 0)), 100).n_cells == 100
