"""Every docstring example in the package runs and gives the printed result."""

import doctest
import importlib
import pkgutil

import pytest

import warpmesh

import warpmesh.kernels  # noqa: E402  (installed from the top-level kernels/ folder)

MODULES = sorted(m.name for m in pkgutil.walk_packages(warpmesh.__path__, "warpmesh.")) + sorted(
    m.name for m in pkgutil.walk_packages(warpmesh.kernels.__path__, "warpmesh.kernels."))


@pytest.mark.parametrize("name", ["warpmesh", *MODULES])
def test_docstring_examples(name):
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples failed in {name}"
