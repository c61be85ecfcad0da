"""The planar and domain sub-commands of ``warpmesh`` [FG §16.3, §16.5.2]: curve and domain.

Both mesh a shape given as a bundled example, a Python file or an expression
(:mod:`warpmesh.cli.sources`), print the statistics (:mod:`warpmesh.cli.report`) and,
with ``-o``, write the mesh atomically to a format that stores its cells.

Examples
--------
``warpmesh curve --example lemniscate --method grid --resolution 64 -o lemniscate.vtu``
``warpmesh curve --expr "1 - x**2 - 4 * y**2" --bounds -1.5 -1 1.5 1 --tolerance 1e-3``
``warpmesh domain --example gear --size 0.05 -o gear.msh``
``warpmesh domain --example part --size 0.04 --smooth 2 -o part.msh`` (3D: tetrahedra by
isosurface stuffing, :mod:`warpmesh.solid`)
``warpmesh domain shapes.py:bracket --size 0.1 -o bracket.mesh`` (2D or 3D, by its bounds)
``warpmesh domain --example torus --size curvature -o torus.vtu`` (3D: graded by curvature)
``warpmesh domain --volume frog_tissues.vti --labels all --size 4 -o frog.msh`` (a label
image: conforming tetrahedra of its regions by lattice cleaving, one physical group per
label and per interface in the ``.msh``; :func:`warpmesh.solid.regions.mesh_regions`)
"""

from __future__ import annotations

import argparse

from warpmesh.cli.report import progress_bars

COMMANDS = ("curve", "domain")
#: flags by the keyword of :func:`warpmesh.mesh_curve` / :func:`warpmesh.mesh_domain` they set
_FLAGS = {"size": "--size", "tolerance": "--tolerance", "min_angle": "--min-angle", "method": "--method",
          "smooth": "--smooth", "bounds": "--bounds", "resolution": "--resolution", "device": "--device",
          "labels": "--labels", "snap": "--snap", "min_size": "--min-size", "spacing": "--spacing",
          "origin": "--origin"}
#: ``domain`` flags of a shape that a ``--volume`` does not take, and the other way round
_SHAPE_ONLY = {"bounds": "--bounds", "tolerance": "--tolerance", "min_angle": "--min-angle", "method": "--method"}
_VOLUME_ONLY = {"array": "--array", "spacing": "--spacing", "origin": "--origin", "labels": "--labels",
                "snap": "--snap", "min_size": "--min-size"}


def add_parsers(sub) -> None:
    """Add the sub-commands to the ``warpmesh`` parser's sub-parsers."""
    from warpmesh.cli.output import add_ascii_argument, extensions_text
    from warpmesh.cli.sources import add_shape_arguments, add_volume_arguments
    from warpmesh.planar.curves import CURVE_METHODS

    c = sub.add_parser("curve", help="mesh an implicit curve f(x, y) = 0 with line segments ([FG §16.3])")
    add_shape_arguments(c, c.add_mutually_exclusive_group(required=True), dims=(2,))
    c.add_argument("--method", choices=list(CURVE_METHODS), default="continuation",
                   help="sampling method of [FG §16.3.1] (default continuation)")
    c.add_argument("--tolerance", type=float, default=1e-2, help="relative chord deviation (default 1e-2)")
    c.add_argument("--resolution", type=int, help="cells along the longer side (grid, freudenthal, progression)")
    c.add_argument("--raw", action="store_true", help="the method's raw polyline, no geometric remeshing")
    c.add_argument("--size", type=float, help="largest edge length (a constant size field)")
    c.add_argument("-o", "--output", help=f"mesh file to write ({extensions_text(('line',))})")
    d = sub.add_parser("domain", help="mesh an implicit domain f > 0: triangles in the plane, tetrahedra in 3D "
                                      "([FG §16.5.2])")
    source = d.add_mutually_exclusive_group(required=True)
    add_shape_arguments(d, source, dims=(2, 3))
    add_volume_arguments(d, source, labels_help="--volume: the regions to mesh, 'all' (default: every value "
                                                "but 0) or label values (0 included when listed)")
    d.add_argument("--size", type=_domain_size, help="target edge length (default: box diagonal / 20; 3D: the "
                                                     "smallest side / 20; --volume: 4 voxels, less in a thinner volume), or, in 3D, "
                                                     "'curvature': graded by the surface's curvature")
    d.add_argument("--snap", type=float, help="--volume: cut points this fraction of their edge from a lattice "
                                              "node are snapped onto it, in [0, 0.5) (default 0.3)")
    d.add_argument("--min-size", type=float, help="--volume: smallest edge of the lattice graded where regions "
                                                  "are thin (default --size / 2; --size or more: uniform)")
    d.add_argument("--tolerance", type=float, help="planar: relative chord deviation of the boundary (default 1e-2)")
    d.add_argument("--min-angle", type=float, help="planar: smallest angle aimed at, degrees (default 28)")
    d.add_argument("--method", choices=["global", "triangle", "stuffing", "delaunay", "tetgen"],
                   help="planar: global (default) or triangle; 3D: stuffing (default), delaunay or tetgen")
    d.add_argument("--smooth", type=int, default=0, help="3D: smoothing sweeps that never lower the smallest "
                                                         "dihedral angle; --volume: passes of interface smoothing "
                                                         "(each vertex within a voxel of its cleaved place)")
    d.add_argument("-o", "--output", help=f"mesh file to write (planar: {extensions_text(('triangle', 'line'))}; "
                                          f"3D: {extensions_text(('tetra', 'triangle'))})")
    for p in (c, d):
        add_ascii_argument(p)
        p.add_argument("--json", action="store_true", help="print the whole statistics as JSON")
        p.add_argument("--device", default="cpu", help="Warp device (cpu, cuda)")


def _domain_size(text: str):
    """``--size`` of ``domain``: a number, or the word ``curvature`` (a 3D graded size)."""
    if text.strip().lower() == "curvature":
        return "curvature"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or 'curvature', got {text!r}") from None


def run(wm, args, clock) -> int:
    """Run one of :data:`COMMANDS` (errors propagate to the caller, which prints them)."""
    from warpmesh.cli.flags import in_flags
    from warpmesh.cli.output import check_output, save_output
    from warpmesh.cli.report import print_report
    from warpmesh.cli.sources import shape_source

    if args.command == "curve":
        check_output(args.output, cells=("line",), ascii=args.ascii)
        with clock.stage("read input"):
            source = shape_source(args, dims=(2,))
        options = {} if args.resolution is None else {"resolution": args.resolution}
        with clock.stage("mesh"), in_flags(_FLAGS):
            mesh = wm.mesh_curve(source.shape, source.bounds, method=args.method, tolerance=args.tolerance,
                                 geometric=not args.raw, size=args.size, device=args.device, **options)
    elif args.volume is not None:
        mesh = _regions(wm, args, clock)
    else:
        _refuse(args, _VOLUME_ONLY, "a shape")
        check_output(args.output, ascii=args.ascii)  # extension and folder before any work; the cells once the bounds are known
        with clock.stage("read input"):
            source = shape_source(args, dims=(2, 3))
        solid = len(source.bounds[0]) == 3
        if args.output:  # the bounds say which cells the file must store
            check_output(args.output, cells=("tetra", "triangle") if solid else ("triangle", "line"),
                         ascii=args.ascii)
        if solid and (args.tolerance is not None or args.min_angle is not None):
            raise ValueError("--tolerance and --min-angle shape planar domains; 3D domains take --size and --smooth")
        if not solid and args.size == "curvature":
            raise ValueError("--size curvature grades 3D domains (3-value --bounds); planar domains take a number")
        if not solid and args.smooth:
            raise ValueError("--smooth applies to 3D domains (3-value --bounds); planar domains are smoothed "
                             "by their own pipeline")
        planar = {k: v for k, v in (("tolerance", args.tolerance), ("min_angle", args.min_angle)) if v is not None}
        with clock.stage("mesh"), in_flags(_FLAGS):
            mesh = wm.mesh_domain(source.shape, source.bounds, size=args.size, method=args.method,
                                  smooth=args.smooth, device=args.device, **planar)
    if args.output:
        with clock.stage("save"):
            save_output(mesh, args.output, ascii=args.ascii)
    with clock.stage("statistics"):
        stats = mesh.stats()
    if args.output:
        stats["written"] = args.output
    print_report(mesh, stats, clock, args.json)
    return 0


def _refuse(args, flags: dict[str, str], what: str) -> None:
    """A ValueError naming the ``flags`` given (``--smooth`` counts when above its default 0)."""
    given = [flag for name, flag in flags.items()
             if getattr(args, name) is not None and not (name == "smooth" and getattr(args, name) == 0)]
    if given:
        raise ValueError(f"{' '.join(given)} {'does' if len(given) == 1 else 'do'} not apply to {what}")


def _regions(wm, args, clock):
    """``domain --volume``: the conforming tetrahedra of the image's labels."""
    from warpmesh.cli.flags import in_flags
    from warpmesh.cli.output import check_output
    from warpmesh.cli.sources import parse_labels, volume_source

    check_output(args.output, cells=("tetra", "triangle"), ascii=args.ascii)  # before any work
    _refuse(args, _SHAPE_ONLY, "--volume (a label image: --labels, --size, --snap, --min-size, --smooth)")
    if args.size == "curvature":
        raise ValueError("--size curvature grades shapes; a --volume takes a number (world units)")
    labels = parse_labels(args.labels)
    options = {k: v for k, v in (("snap", args.snap), ("min_size", args.min_size)) if v is not None}
    if args.smooth:
        options["smooth"] = args.smooth
    with clock.stage("read input"):
        volume = volume_source(args)
    with clock.stage("mesh"), in_flags(_FLAGS):
        return wm.mesh_domain(volume, labels="all" if labels is None else labels, size=args.size,
                              device=args.device, progress=progress_bars(), **options)
