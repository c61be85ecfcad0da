"""Numbering [FG §17.4]: node renumbering, element colouring, node graphs, higher-order nodes.

The modules load on first use, also as attributes (``wm.numbering.high_order.jacobians``
after ``import warpmesh as wm``): importing them all here would load their Warp kernels at
every start.
"""

import importlib

_MODULES = ("coloring", "graph", "high_order", "renumber")


def __getattr__(name):
    if name in _MODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *_MODULES])
