"""The bundled example shapes, 3D and planar, by name: ``example(name) -> (shape, bounds)``.

Examples
--------
>>> from warpmesh.frep.examples import example
>>> part, bounds = example("part")       # a plate, four through-holes and a boss
>>> bounds
((-1.2, -1.2, -1.2), (1.2, 1.2, 1.2))
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from warpmesh.frep import expr as E
from warpmesh.frep.shapes import Shape, box, cylinder, sphere, torus, union
from warpmesh.frep.shapes2d import cassini, circle, rectangle

__all__ = ["example", "EXAMPLES", "EXAMPLES_2D"]

#: the 3D examples
EXAMPLES: Sequence[str] = ("part", "degree6", "sphere", "torus")
#: the planar examples: their bounds are ((x0, y0), (x1, y1))
EXAMPLES_2D: Sequence[str] = ("gear", "plate", "lemniscate", "cassini")


def _gear(teeth: int = 12) -> Shape:
    """A spur-gear-like CSG part: a disc with rectangular teeth, a bore and a key way."""
    tooth = rectangle((0.22, 0.3), center=(1.0, 0.0))
    ring = union(circle(1.0), *[tooth.rotate(2 * math.pi * k / teeth) for k in range(teeth)])
    return ring - circle(0.35) - rectangle((0.12, 0.16), center=(0.0, 0.4)) - union(
        *[circle(0.12, center=(0.62 * math.cos(t), 0.62 * math.sin(t)))
          for t in (2 * math.pi * k / 5 + 0.3 for k in range(5))])


def _plate() -> Shape:
    """A rectangular plate with corners rounded to radius 0.1 and five holes of two sizes."""
    body = rectangle((2.4, 1.4))
    # corner pieces reach past the body, so no side of theirs lies on the body's sides
    corners = union(*[rectangle((0.2, 0.2), center=(sx * 1.2, sy * 0.7)) - circle(0.1, (sx * 1.1, sy * 0.6))
                      for sx in (-1, 1) for sy in (-1, 1)])
    holes = union(circle(0.3), *[circle(0.12, (sx * 0.8, sy * 0.35)) for sx in (-1, 1) for sy in (-1, 1)])
    return body - corners - holes


def example(name: str) -> tuple[Shape, tuple]:
    """A bundled example by name: (shape, bounds).

    3D: 'part' (a plate, four through-holes and a boss: the CSG part of the benchmarks),
    'degree6' (the degree-six surface of [FG §16.4.5]), 'sphere', 'torus'. Planar, with
    bounds ((x0, y0), (x1, y1)): 'gear' and 'plate' (CSG domains), 'lemniscate' (a
    singular point at the origin), 'cassini' (one oval just past the topology change,
    b = 1.05 a).

    Raises
    ------
    ValueError
        An unknown name; the message lists the names.

    Examples
    --------
    >>> shape, bounds = example("gear")
    >>> shape.dim, bounds
    (2, ((-1.3, -1.3), (1.3, 1.3)))
    """
    if name == "part":
        holes = [cylinder(0.2).translate((sx * 0.6, sy * 0.6, 0)) for sx in (-1, 1) for sy in (-1, 1)]
        return (box((2, 2, 0.6)) - union(*holes)) | sphere(0.5), ((-1.2,) * 3, (1.2,) * 3)
    if name == "degree6":
        x, y, z = E.coords()
        f = (x**2 + y**2 - 4) * (x**2 + z**2 - 4) * (y**2 + z**2 - 4) - 4.0078
        return Shape(f), ((-3.0,) * 3, (3.0,) * 3)
    if name == "sphere":
        return sphere(1.0), ((-1.2,) * 3, (1.2,) * 3)
    if name == "torus":
        return torus(1.0, 0.35), ((-1.5, -1.5, -0.5), (1.5, 1.5, 0.5))
    if name == "gear":
        return _gear(), ((-1.3, -1.3), (1.3, 1.3))
    if name == "plate":
        return _plate(), ((-1.3, -0.8), (1.3, 0.8))
    if name == "lemniscate":
        return cassini(1.0, 1.0), ((-1.6, -0.6), (1.6, 0.6))
    if name == "cassini":
        return cassini(1.0, 1.05), ((-1.6, -0.7), (1.6, 0.7))
    raise ValueError(f"Unknown example {name!r}. Pick one of {list(EXAMPLES) + list(EXAMPLES_2D)}")
