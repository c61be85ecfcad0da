"""Shared fixtures: ``check_mesh`` (see ``tests/helpers/meshcheck.py``) and ``device``.

``device`` runs a test on "cpu" and, when Warp reports a CUDA device, on "cuda" too.
Warp is imported only when a collected test asks for ``device``.
"""

from __future__ import annotations

import functools

import pytest

from tests.helpers.meshcheck import check_mesh as _check_mesh


@functools.cache
def _devices() -> tuple[str, ...]:
    try:
        import warp as wp
    except ImportError:
        return ("cpu",)
    wp.config.quiet = True
    wp.init()
    return ("cpu", "cuda") if wp.get_cuda_device_count() > 0 else ("cpu",)


def _names(mark) -> list[str]:
    names = mark.args[0] if mark.args else mark.kwargs.get("argnames", ())
    return [n.strip() for n in names.split(",")] if isinstance(names, str) else list(names)


def pytest_generate_tests(metafunc):
    explicit = any("device" in _names(m) for m in metafunc.definition.iter_markers("parametrize"))
    if "device" in metafunc.fixturenames and not explicit:  # a test's own list wins
        metafunc.parametrize("device", _devices(), indirect=True)


@pytest.fixture
def device(request) -> str:
    """The Warp device to run on: "cpu", and "cuda" where present."""
    return request.param


@pytest.fixture
def check_mesh():
    """The ``check_mesh(mesh_or_points, faces=None, *, closed=True, oriented=True)`` helper."""
    return _check_mesh
