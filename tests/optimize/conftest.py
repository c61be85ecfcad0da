"""Fixtures shared by the optimisation tests: the CSG part's raw surfaces and their
optimisation (size h = 2.4 / R, tolerance h / 4), computed once per session."""

import functools

import pytest

import warpmesh as wm


@functools.cache
def part_raw(resolution: int, method: str | None = None):
    """(shape, raw mesh) of the part marched at ``resolution``."""
    shape, bounds = wm.example("part")
    return shape, wm.mesh_surface(shape, bounds=bounds, resolution=resolution, method=method)


@functools.cache
def part_surfaces(resolution: int, method: str | None = None):
    """(shape, raw mesh, optimised mesh) of the part marched at ``resolution``."""
    shape, raw = part_raw(resolution, method)
    h = 2.4 / resolution
    return shape, raw, raw.optimize(shape, size=h, tolerance=h / 4)


@pytest.fixture(scope="session")
def part_opt():
    """The part marched at resolution 64 (marching cubes) and optimised to h = 0.0375."""
    return part_surfaces(64, "mc")
