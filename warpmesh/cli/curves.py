"""The planar sub-commands of ``warpmesh`` [FG §16.3, §16.5.2]: curve and domain.

Both mesh a bundled planar example (``wm.EXAMPLES_2D``), print the statistics and, with
``-o``, write the mesh atomically (any format meshio writes that keeps lines/triangles).

Examples
--------
``warpmesh curve --example lemniscate --method grid --resolution 64 -o lemniscate.vtu``
``warpmesh curve --example cassini --method continuation --tolerance 1e-4``
``warpmesh domain --example gear --size 0.05 -o gear.msh``
``warpmesh domain --example part --size 0.04 --smooth 2 -o part.msh`` (3D: tetrahedra by
isosurface stuffing, :mod:`warpmesh.solid`)
"""

from __future__ import annotations

import json

import numpy as np

COMMANDS = ("curve", "domain")
_CURVE_SHOWN = ("np", "n_cells", "components", "method", "max_deviation", "max_relative_deviation", "time_sample", "time_geometric")
_DOMAIN_SHOWN = ("np", "ne", "area", "min_angle", "mean_q", "worst_q", "boundary_distance", "boundary_components")
_SOLID_SHOWN = ("np", "ne", "volume", "euler", "dihedral_min", "dihedral_max", "radius_edge_max", "mean_q", "worst_q",
                "boundary_distance", "time_stuffing")


def add_parsers(sub) -> None:
    """Add the sub-commands to the ``warpmesh`` parser's sub-parsers."""
    from warpmesh.planar.curves import CURVE_METHODS
    from warpmesh.frep.examples import EXAMPLES, EXAMPLES_2D

    c = sub.add_parser("curve", help="mesh an implicit curve f(x, y) = 0 with line segments ([FG §16.3])")
    c.add_argument("--example", required=True, choices=list(EXAMPLES_2D), help="a bundled planar shape")
    c.add_argument("--method", choices=list(CURVE_METHODS), default="continuation")
    c.add_argument("--tolerance", type=float, default=1e-2, help="relative chord deviation (default 1e-2)")
    c.add_argument("--resolution", type=int, help="cells along the longer side (grid, freudenthal, progression)")
    c.add_argument("--raw", action="store_true", help="the method's raw polyline, no geometric remeshing")
    c.add_argument("--size", type=float, help="largest edge length (a constant size field)")
    d = sub.add_parser("domain", help="mesh an implicit domain f > 0: triangles in the plane, tetrahedra in 3D "
                                      "([FG §16.5.2])")
    d.add_argument("--example", required=True, choices=list(EXAMPLES_2D) + list(EXAMPLES),
                   help="a bundled planar or 3D shape")
    d.add_argument("--size", type=float, help="target edge length (default: box diagonal / 20)")
    d.add_argument("--tolerance", type=float, default=1e-2, help="relative chord deviation of the boundary (default 1e-2)")
    d.add_argument("--min-angle", type=float, default=28.0, help="smallest angle aimed at, degrees")
    d.add_argument("--method", choices=["global", "triangle", "stuffing"],
                   help="planar: global (default) or triangle; 3D: stuffing")
    d.add_argument("--smooth", type=int, default=0, help="3D: smoothing sweeps that never lower the smallest "
                                                         "dihedral angle")
    for p in (c, d):
        p.add_argument("-o", "--output", help="mesh file to write (.vtu .vtk .msh .mesh ...)")
        p.add_argument("--json", action="store_true", help="print the statistics as JSON")
        p.add_argument("--device", default="cpu", help="Warp device (cpu, cuda)")


def run(wm, args) -> int:
    """Run one of :data:`COMMANDS` (errors propagate to the caller, which prints them)."""
    from warpmesh.io.files import check_path

    if args.output:
        check_path(args.output)
    shape, bounds = wm.example(args.example)
    if args.command == "curve":
        options = {} if args.resolution is None else {"resolution": args.resolution}
        mesh = wm.mesh_curve(shape, bounds, method=args.method, tolerance=args.tolerance, geometric=not args.raw,
                             size=args.size, device=args.device, **options)
        shown = _CURVE_SHOWN
    elif len(bounds[0]) == 3:
        mesh = wm.mesh_domain(shape, bounds, size=args.size, method=args.method, smooth=args.smooth,
                              device=args.device)
        shown = _SOLID_SHOWN
    else:
        mesh = wm.mesh_domain(shape, bounds, size=args.size, tolerance=args.tolerance, min_angle=args.min_angle,
                              method=args.method or "global", device=args.device)
        shown = _DOMAIN_SHOWN
    if args.output:
        mesh.save(args.output)
    stats = mesh.stats()
    facts = {k: stats.get(k) for k in shown}
    if args.output:
        facts["written"] = args.output
    if args.json:
        print(json.dumps(facts, default=lambda v: v.item() if isinstance(v, np.generic) else str(v)))
    else:
        for key, value in facts.items():
            print(f"{key:>20}: {value:.6g}" if isinstance(value, float) else f"{key:>20}: {value}")
    return 0
