"""warpmesh: meshes from implicit geometry (F-Rep trees, sampled volumes) with Warp kernels.

Example
-------
>>> import warpmesh as wm
>>> part, bounds = wm.example("part")
>>> mesh = wm.mesh_surface(part, bounds=bounds, resolution=48)
>>> mesh.stats()["euler"]
-6
"""

import warp as _wp

if _wp.config.log_level < _wp.LOG_WARNING:  # Warp's banner and module-load lines would drown the results
    _wp.config.log_level = _wp.LOG_WARNING

from warpmesh.errors import ReadError, TopologyError, WarpMeshError
from warpmesh.expr import Expr, abs, coords, cos, exp, log, max, min, sin, sqrt  # noqa: A004
from warpmesh.mesh import Mesh, load
from warpmesh.merge import MergeError
from warpmesh.numbering import renumber
from warpmesh import coloring, geometry, graph, nodes, numbering, transforms  # noqa: E402,F401  (wm.coloring, wm.nodes, ...)
from warpmesh.nodes import to_order
from warpmesh.orientation import orient, orient_faces
from warpmesh.quality import quality_summary, tetra_quality, triangle_quality
from warpmesh.shapes import (EXAMPLES, Shape, box, capsule, complement, cone, cylinder, difference,
                             ellipsoid, example, halfspace, intersection, sphere, superquadric,
                             supertorus, torus, union)
from warpmesh.shapes2d import EXAMPLES_2D, cassini, circle, ellipse, halfplane, rectangle, regular_polygon
from warpmesh.surface import mesh_surface
from warpmesh.curves import mesh_curve, mesh_domain
from warpmesh.remesh import optimize, simplify
from warpmesh.projection import VolumeField, surface_error
from warpmesh.tape import Tape, compile_tape, evaluate, evaluate_interval

__version__ = "0.1.0"

__all__ = [
    "Mesh", "load", "to_order", "renumber", "mesh_surface", "mesh_curve", "mesh_domain", "optimize", "simplify", "surface_error", "VolumeField", "orient", "orient_faces",
    "triangle_quality", "tetra_quality", "quality_summary",
    "Shape", "Expr", "coords", "sqrt", "abs", "min", "max", "sin", "cos", "exp", "log",
    "sphere", "box", "cylinder", "cone", "torus", "ellipsoid", "halfspace", "capsule",
    "superquadric", "supertorus", "union", "intersection", "difference", "complement",
    "example", "EXAMPLES",
    "circle", "ellipse", "rectangle", "halfplane", "regular_polygon", "cassini", "EXAMPLES_2D",
    "Tape", "compile_tape", "evaluate", "evaluate_interval",
    "WarpMeshError", "ReadError", "TopologyError", "MergeError",
]
