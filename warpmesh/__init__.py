"""warpmesh: meshes from implicit geometry (F-Rep trees, sampled volumes) with Warp kernels.

It follows chapters 16 and 17 of Frey & George, *Mesh Generation* (cited as [FG §16.4]).

The public face is this module's ``__all__`` plus the subpackages, one per stage of the
pipeline (see ``docs/architecture.md``):

``frep``       expressions, shapes, examples, the tape and its evaluators, differential geometry
``surface``    surface meshes of shapes and sampled volumes (grid, continuation, adaptive octree)
``planar``     implicit curves and planar domains
``solid``      tetrahedral meshes of implicit domains (isosurface stuffing)
``optimize``   surface optimisation and simplification
``modify``     transforms, refinement, cell-type conversion, merge, periodic meshes, cracks
``numbering``  renumbering, colouring, node graphs, higher-order nodes
``cells``      the cell vocabulary: types, reference cells, topology, quality, validity checks
``io``         conversions (meshio, trimesh, pyvista), mesh files, image volumes in
``preview``    parameter edits re-meshed live: Preview, off-screen pictures, WebGL pages, widgets
``distributed`` bricked meshing of large grids on a Dask cluster
``cli``        the ``warpmesh`` command line
``kernels``    the Warp device code

plus the modules ``mesh`` (the :class:`Mesh` type) and ``errors``.

``import warpmesh`` imports none of them, nor Warp, scipy, pyvista, trimesh or meshio: each
public name is imported from its module on first use (PEP 562 ``__getattr__``), and Warp
starts (quietly) when the first module that launches kernels is imported
(:mod:`warpmesh.kernels.startup`).

Example
-------
>>> import warpmesh as wm
>>> part, bounds = wm.example("part")
>>> mesh = wm.mesh_surface(part, bounds=bounds, resolution=48)
>>> mesh.stats()["euler"]
-6
"""

import sys as _sys
from importlib import import_module as _import_module
from importlib.util import find_spec as _find_spec
from types import ModuleType as _ModuleType
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: module -> the public names it defines (imported on first use)
_EXPORTS = {
    "warpmesh.errors": ("MergeError", "ReadError", "SizeError", "TopologyError", "WarpMeshError", "WriteError"),
    "warpmesh.frep.expr": ("Expr", "abs", "coords", "cos", "exp", "log", "max", "param", "min", "sin", "sqrt"),
    "warpmesh.frep.projection": ("VolumeField", "surface_error"),
    "warpmesh.frep.examples": ("EXAMPLES", "EXAMPLES_2D", "example"),
    "warpmesh.frep.shapes": ("Shape", "box", "capsule", "complement", "cone", "cylinder", "difference", "ellipsoid",
                             "halfspace", "intersection", "sphere", "superquadric", "supertorus", "torus", "union"),
    "warpmesh.frep.shapes2d": ("cassini", "circle", "ellipse", "halfplane", "rectangle", "regular_polygon"),
    "warpmesh.frep.tape": ("Tape", "compile_tape", "evaluate", "evaluate_interval"),
    "warpmesh.cells.intersections": ("check",),
    "warpmesh.cells.quality": ("quality_summary", "tetra_quality", "triangle_quality"),
    "warpmesh.io.images": ("Volume", "load_volume"),
    "warpmesh.mesh": ("Mesh", "load"),
    "warpmesh.numbering.high_order": ("to_order",),
    "warpmesh.numbering.renumber": ("renumber",),
    "warpmesh.optimize.remesh": ("optimize", "simplify"),
    "warpmesh.planar.curves": ("mesh_curve",),
    "warpmesh.solid.pipeline": ("mesh_domain",),
    "warpmesh.surface.orientation": ("orient", "orient_faces"),
    "warpmesh.surface.options": ("AdaptiveOptions", "ContinuationOptions", "GridOptions", "VolumeOptions"),
    "warpmesh.surface.pipeline": ("mesh_surface",),
    "warpmesh.preview.session": ("Preview",),
}
#: public names that are modules
_MODULES = {"geometry": "warpmesh.frep.geometry", "transforms": "warpmesh.modify.transforms"}
#: subpackages and top modules, reachable as ``wm.<name>``
_SUBMODULES = ("frep", "surface", "planar", "solid", "optimize", "modify", "numbering", "cells", "io", "preview",
               "distributed", "cli", "kernels", "mesh", "errors")
_ORIGIN = {name: module for module, names in _EXPORTS.items() for name in names}

if TYPE_CHECKING:  # what static tools see; at run time the names come from __getattr__
    from warpmesh.errors import MergeError as MergeError
    from warpmesh.errors import ReadError as ReadError
    from warpmesh.errors import WriteError as WriteError
    from warpmesh.errors import SizeError as SizeError
    from warpmesh.errors import TopologyError as TopologyError
    from warpmesh.errors import WarpMeshError as WarpMeshError
    from warpmesh.frep import geometry as geometry
    from warpmesh.modify import transforms as transforms
    from warpmesh.frep.expr import Expr as Expr
    from warpmesh.frep.expr import abs as abs  # noqa: A004  (reachable as wm.abs, kept out of __all__)
    from warpmesh.frep.expr import coords as coords
    from warpmesh.frep.expr import cos as cos
    from warpmesh.frep.expr import exp as exp
    from warpmesh.frep.expr import log as log
    from warpmesh.frep.expr import max as max  # noqa: A004
    from warpmesh.frep.expr import param as param
    from warpmesh.frep.expr import min as min  # noqa: A004
    from warpmesh.frep.expr import sin as sin
    from warpmesh.frep.expr import sqrt as sqrt
    from warpmesh.frep.projection import VolumeField as VolumeField
    from warpmesh.frep.projection import surface_error as surface_error
    from warpmesh.frep.examples import EXAMPLES as EXAMPLES
    from warpmesh.frep.examples import EXAMPLES_2D as EXAMPLES_2D
    from warpmesh.frep.examples import example as example
    from warpmesh.frep.shapes import Shape as Shape
    from warpmesh.frep.shapes import box as box
    from warpmesh.frep.shapes import capsule as capsule
    from warpmesh.frep.shapes import complement as complement
    from warpmesh.frep.shapes import cone as cone
    from warpmesh.frep.shapes import cylinder as cylinder
    from warpmesh.frep.shapes import difference as difference
    from warpmesh.frep.shapes import ellipsoid as ellipsoid
    from warpmesh.frep.shapes import halfspace as halfspace
    from warpmesh.frep.shapes import intersection as intersection
    from warpmesh.frep.shapes import sphere as sphere
    from warpmesh.frep.shapes import superquadric as superquadric
    from warpmesh.frep.shapes import supertorus as supertorus
    from warpmesh.frep.shapes import torus as torus
    from warpmesh.frep.shapes import union as union
    from warpmesh.frep.shapes2d import cassini as cassini
    from warpmesh.frep.shapes2d import circle as circle
    from warpmesh.frep.shapes2d import ellipse as ellipse
    from warpmesh.frep.shapes2d import halfplane as halfplane
    from warpmesh.frep.shapes2d import rectangle as rectangle
    from warpmesh.frep.shapes2d import regular_polygon as regular_polygon
    from warpmesh.frep.tape import Tape as Tape
    from warpmesh.frep.tape import compile_tape as compile_tape
    from warpmesh.frep.tape import evaluate as evaluate
    from warpmesh.frep.tape import evaluate_interval as evaluate_interval
    from warpmesh.cells.intersections import check as check
    from warpmesh.cells.quality import quality_summary as quality_summary
    from warpmesh.cells.quality import tetra_quality as tetra_quality
    from warpmesh.cells.quality import triangle_quality as triangle_quality
    from warpmesh.io.images import Volume as Volume
    from warpmesh.io.images import load_volume as load_volume
    from warpmesh.mesh import Mesh as Mesh
    from warpmesh.mesh import load as load
    from warpmesh.numbering.high_order import to_order as to_order
    from warpmesh.numbering.renumber import renumber as renumber
    from warpmesh.optimize.remesh import optimize as optimize
    from warpmesh.optimize.remesh import simplify as simplify
    from warpmesh.planar.curves import mesh_curve as mesh_curve
    from warpmesh.solid.pipeline import mesh_domain as mesh_domain
    from warpmesh.surface.orientation import orient as orient
    from warpmesh.surface.orientation import orient_faces as orient_faces
    from warpmesh.surface.options import AdaptiveOptions as AdaptiveOptions
    from warpmesh.surface.options import ContinuationOptions as ContinuationOptions
    from warpmesh.surface.options import GridOptions as GridOptions
    from warpmesh.surface.options import VolumeOptions as VolumeOptions
    from warpmesh.surface.pipeline import mesh_surface as mesh_surface
    from warpmesh.preview.session import Preview as Preview


def __getattr__(name: str):
    """Import a public name's module on first use (PEP 562) and keep the name here."""
    if name in _ORIGIN:
        value = getattr(_import_module(_ORIGIN[name]), name)
    elif name in _MODULES:
        value = _import_module(_MODULES[name])
    elif name in _SUBMODULES or (not name.startswith("_") and _find_spec(f"{__name__}.{name}")):
        value = _import_module(f"{__name__}.{name}")  # a subpackage or top module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """``__all__`` and the other public names (``min``, ``max``, ``abs``, the subpackages), then the private ones."""
    return sorted({n for n in globals() if n.startswith("_")} | set(_ORIGIN) | set(_MODULES) | set(_SUBMODULES))


class _Package(_ModuleType):
    """This package, whose function ``optimize`` keeps its name when the subpackage
    ``warpmesh.optimize`` is imported (Python's import sets the parent's attribute to the
    subpackage; the eager imports of old rebound it to the function afterwards)."""

    def __setattr__(self, name: str, value) -> None:
        if name in _ORIGIN and isinstance(value, _ModuleType):
            return  # the subpackage stays reachable as sys.modules["warpmesh.optimize"]
        super().__setattr__(name, value)


_sys.modules[__name__].__class__ = _Package


__all__ = [
    "Mesh", "load", "to_order", "renumber", "mesh_surface", "param", "Preview", "GridOptions", "ContinuationOptions",
    "load_volume", "Volume",
    "AdaptiveOptions", "VolumeOptions", "mesh_curve", "mesh_domain", "optimize",
    "simplify", "surface_error", "VolumeField", "orient", "orient_faces",
    "triangle_quality", "tetra_quality", "quality_summary", "check",
    "Shape", "Expr", "coords", "sqrt", "sin", "cos", "exp", "log",
    "sphere", "box", "cylinder", "cone", "torus", "ellipsoid", "halfspace", "capsule",
    "superquadric", "supertorus", "union", "intersection", "difference", "complement",
    "example", "EXAMPLES",
    "circle", "ellipse", "rectangle", "halfplane", "regular_polygon", "cassini", "EXAMPLES_2D",
    "Tape", "compile_tape", "evaluate", "evaluate_interval", "geometry", "transforms",
    "WarpMeshError", "ReadError", "WriteError", "TopologyError", "MergeError", "SizeError",
]
