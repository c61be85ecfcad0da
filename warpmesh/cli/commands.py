"""The ``warpmesh`` command line.

Examples
--------
``warpmesh mesh --example part --resolution 256 -o part.ply``
    meshes the bundled CSG part and prints its statistics.
``warpmesh mesh torus.py:ring --resolution 128 -o ring.stl``
    meshes the shape ``ring`` that the Python file ``torus.py`` defines (with its ``bounds``
    or ``--bounds``); ``warpmesh mesh --expr "1 - x**2 - y**2 - z**2" --bounds -2 -2 -2 2 2 2``
    meshes an expression of x, y, z (see :mod:`warpmesh.cli.sources`).
``warpmesh mesh --volume ct.npy --level 300 --spacing 0.5 -o bone.stl``
    extracts an iso-surface of a volume saved with ``numpy.save``.
``warpmesh mesh --volume seg.nii.gz --labels all --method mt -o organs.vtu``
    meshes every label of a segmentation (triangle refs = labels) in the image's world
    coordinates; ``--volume`` takes any image :func:`warpmesh.load_volume` reads (.vti .vtk
    .nii .nii.gz .nrrd .nhdr .mha .mhd .npy .npz, a DICOM series folder).
``warpmesh transform | refine | convert | merge | crack | periodic ...``
    modify a mesh file [FG ch. 17]: see :mod:`warpmesh.cli.modify`.
``warpmesh curve | domain --example gear ...``
    mesh a planar curve or domain ([FG §16.3, 16.5.2]): see :mod:`warpmesh.cli.curves`.
``warpmesh view --example part -o part.png | part.html``
    an off-screen picture or a WebGL page of a mesh file or example: see :mod:`warpmesh.cli.view`.
``warpmesh info part.ply``
    prints the statistics of a mesh file.
``warpmesh renumber in.msh out.msh --method gibbs``
    renumbers nodes and elements for a small bandwidth and profile ([FG §17.4]) and prints
    the statistics table (Table 17.1).

Every command prints one line per figure (``--json``: the whole statistics as JSON and
nothing else on stdout), checks its output path before any work, names the user's paths
and flags in its errors (exit status 2), and ends on Ctrl-C with one line and status 130
(files are written atomically, so nothing is left half-written).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import threading
import warnings

import numpy as np

from warpmesh.cli.report import progress_bars


class _Parser(argparse.ArgumentParser):
    """argparse's parser, with every negative number a value, never a flag: ``--bounds -1e0 -inf
    ...`` (argparse's own pattern knows only ``-2`` and ``-2.5``, and took ``-1e0`` for an
    unknown option)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$|^-(inf|infinity|nan)$",
                                                   re.IGNORECASE)


def _parser() -> argparse.ArgumentParser:
    import warpmesh
    from warpmesh.cli.output import add_ascii_argument, extensions_text
    from warpmesh.cli.sources import add_shape_arguments, add_volume_arguments

    p = _Parser(prog="warpmesh", description="Meshes from implicit geometry.")
    p.add_argument("--version", action="version", version=f"warpmesh {warpmesh.__version__}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    m = sub.add_parser("mesh", help="mesh a shape (example, Python file, expression) or a volume image and "
                                    "print statistics")
    src = m.add_mutually_exclusive_group(required=True)
    add_shape_arguments(m, src, dims=(3,))
    add_volume_arguments(m, src, labels_help="integer volumes: mesh each label's region ('all' or label values)")
    m.add_argument("--resolution", type=int, help="cells along the longest side (shapes; default 128)")
    m.add_argument("--level", type=float, help="iso-level (volumes; default 0)")
    m.add_argument("--inside", choices=["above", "below"],
                   help="volumes: the inside is where the values are above --level (default) or below it")
    m.add_argument("--method", choices=["mc33", "mt", "mc"], default=None,
                   help="cell triangulation: marching cubes 33 (default), marching tetrahedra, plain mc")
    m.add_argument("--covering", choices=["grid", "continuation"], default=None,
                   help="shapes: culled grid (default) or continuation from seed cells")
    m.add_argument("--interfaces", choices=["separate", "shared"],
                   help="--labels: each label's own closed surface (separate, default) or one surface meshing "
                        "each interface between two labels once (shared; surface nets)")
    m.add_argument("--smoothing", type=int, metavar="PASSES",
                   help="--interfaces shared: passes of constrained smoothing (vertices kept in their voxels, "
                        "junction curves smoothed along themselves, no fold; default 0)")
    m.add_argument("--slab-voxels", type=int, help="volumes: samples per slab (default 16M)")
    m.add_argument("--root", choices=["linear", "bisection", "newton"], default=None,
                   help="vertex placement (default linear; newton with --adaptive)")
    m.add_argument("--adaptive", action="store_true",
                   help="shapes: adaptive octree (curvature-driven, sharp edges); --resolution is its finest level")
    m.add_argument("--tolerance", type=float, help="--adaptive: relative chord tolerance (default 0.02)")
    m.add_argument("--gradient", choices=["exact", "central", "forward"],
                   help="gradient for Newton roots: exact (default) or finite differences")
    m.add_argument("--no-cap", action="store_true", help="leave the surface open at the bounds")
    m.add_argument("--device", default="cpu", help="Warp device (cpu, cuda)")
    m.add_argument("-o", "--output", help=f"mesh file to write ({extensions_text(('triangle',))})")
    add_ascii_argument(m)
    m.add_argument("--root-iterations", type=int, help="iterations of bisection / Newton")
    m.add_argument("--evaluator", choices=["interpreter", "compiled"],
                   help="shapes: the tape interpreter (default, no compile) or a kernel generated for "
                        "the shape (about 1.5 s to compile once per structure, cached)")
    m.add_argument("--json", action="store_true", help="print the whole statistics as JSON (nothing else on stdout)")
    m.add_argument("--optimize", action="store_true",
                   help="optimise the mesh for finite elements on the exact surface ([FG §16.4.3]) and "
                        "print the before/after quality table")
    m.add_argument("--simplify", type=float, metavar="FRACTION",
                   help="decimate to about this fraction of the triangles within --max-error")
    m.add_argument("--size", type=float, help="--optimize: target edge length (default: the input's mean)")
    m.add_argument("--max-error", type=float,
                   help="--optimize/--simplify: largest distance to the surface accepted (absolute)")
    r = sub.add_parser("renumber", help="renumber a mesh file's nodes and elements (bandwidth, profile)")
    r.add_argument("input", help=f"mesh file to read ({extensions_text(())})")
    r.add_argument("output", help=f"mesh file to write ({extensions_text(())})")
    add_ascii_argument(r)
    r.add_argument("--method", choices=["gibbs", "rcm", "frontal", "frontal-diameter"], default="gibbs",
                   help="Gibbs-Poole-Stockmeyer (default), reverse Cuthill-McKee, or the frontal method "
                        "from a node of minimal degree or from the end of the pseudo-diameter ([FG §17.4])")
    r.add_argument("--higher-order", choices=["ball", "graph"], default="ball",
                   help="nodes other than vertices: by the book's ball rule (default) or the full graph")
    r.add_argument("--reverse", choices=["auto", "yes", "no"], default="auto",
                   help="reverse the numbering (auto: whichever gives the smaller profile)")
    r.add_argument("--reduced", action="store_true", help="quads/hexahedra connect along edges only")
    r.add_argument("--keep-elements", action="store_true", help="do not renumber the elements")
    r.add_argument("--color", choices=["face", "node"],
                   help="also sort the elements into colour packets (neighbours by face or by node)")
    r.add_argument("--json", action="store_true", help="print the statistics as JSON")
    from warpmesh.cli import curves as cli_curves
    from warpmesh.cli import modify as cli_modify
    from warpmesh.cli import view as cli_view

    cli_modify.add_parsers(sub)
    cli_curves.add_parsers(sub)
    cli_view.add_parsers(sub)
    i = sub.add_parser("info", help="print statistics of a mesh file")
    i.add_argument("path", help=f"mesh file to read ({extensions_text(())})")
    i.add_argument("--json", action="store_true", help="print the whole statistics as JSON")
    return p


#: ``mesh`` flags by the keyword of :func:`warpmesh.mesh_surface` they set
_MESH_FLAGS = {"resolution": "--resolution", "level": "--level", "inside": "--inside", "spacing": "--spacing",
               "origin": "--origin", "method": "--method", "labels": "--labels", "interfaces": "--interfaces",
               "smoothing": "--smoothing", "slab_voxels": "--slab-voxels",
               "root": "--root", "root_iterations": "--root-iterations", "gradient": "--gradient",
               "tolerance": "--tolerance", "evaluator": "--evaluator", "cap": "--no-cap", "bounds": "--bounds",
               "device": "--device"}
#: ``--optimize`` / ``--simplify`` flags by the keyword of :func:`warpmesh.optimize` / :func:`warpmesh.simplify`
_IMPROVE_FLAGS = {"size": "--size", "tolerance": "--max-error", "fraction": "--simplify", "bounds": "--bounds"}


def _check_mesh_flags(args) -> None:
    """Refuse, in one line, flags the chosen pipeline of ``mesh`` does not take (its option group's fields)."""
    import dataclasses

    from warpmesh.surface import options as O

    if args.volume is not None:
        group, what = O.VolumeOptions, "--volume"
    elif args.adaptive:
        group, what = O.AdaptiveOptions, "--adaptive"
    elif args.covering == "continuation":
        group, what = O.ContinuationOptions, "--covering continuation"
    else:
        group, what = O.GridOptions, "a shape on a grid"
    given = {"resolution": args.resolution, "level": args.level, "inside": args.inside, "spacing": args.spacing,
             "origin": args.origin, "method": args.method, "labels": args.labels, "interfaces": args.interfaces,
             "smoothing": args.smoothing, "slab_voxels": args.slab_voxels,
             "root": args.root, "root_iterations": args.root_iterations, "gradient": args.gradient,
             "tolerance": args.tolerance, "evaluator": args.evaluator, "cap": args.no_cap or None,
             "bounds": args.bounds}
    _check_improve_flags(args)
    names = {f.name for f in dataclasses.fields(group)}
    refused = [_MESH_FLAGS[k] for k, v in given.items() if v is not None and k not in names]
    if refused:
        takes = " ".join(_MESH_FLAGS[k] for k in _MESH_FLAGS if k in names and k != "bounds")
        raise ValueError(f"{' '.join(refused)} {'does' if len(refused) == 1 else 'do'} not apply to {what}, "
                         f"which takes {takes}")


def _check_improve_flags(args) -> None:
    """--optimize / --simplify and their numbers, checked before the mesh is made (a frog's
    surface takes minutes to simplify, and a bad flag found after it wastes the meshing)."""
    import math

    if args.optimize and args.simplify is not None:
        raise ValueError("expected one of --optimize and --simplify, got both")
    if args.simplify is not None and not 0.0 < args.simplify < 1.0:
        raise ValueError(f"expected --simplify in (0, 1) (the fraction of the triangles kept), got {args.simplify:g}")
    for flag, value in (("--size", args.size), ("--max-error", args.max_error)):
        if value is None:
            continue
        if not (args.optimize or args.simplify is not None):
            raise ValueError(f"{flag} applies with --optimize or --simplify, got {flag} {value:g} without them")
        if flag == "--size" and args.simplify is not None:
            raise ValueError("--size applies with --optimize (--simplify sizes by the curvature), got both")
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"expected a positive {flag}, got {value:g}")
    if (args.optimize or args.simplify is not None) and args.volume is not None and args.interfaces != "shared":
        from warpmesh.cli.sources import parse_labels

        labels = parse_labels(args.labels)
        if labels is not None and (labels == "all" or len(labels) != 1):
            raise ValueError("expected one label with --labels when optimising (one surface per run), or "
                             "--interfaces shared")


def _volume_target(wm, args, volume):
    if not volume.axis_aligned:
        raise ValueError("--optimize and --simplify take images whose axes are the world axes; this one's "
                         f"direction is {volume.direction.tolist()}")
    from warpmesh.cli.sources import parse_labels

    labels = parse_labels(args.labels)  # (one label: _check_improve_flags refused more before the meshing)
    if labels is not None:
        return wm.VolumeField(np.asarray(volume.values) == labels[0], spacing=volume.spacing,
                              origin=volume.origin, level=0.5)
    return wm.VolumeField(volume.values, spacing=volume.spacing, origin=volume.origin,
                          level=args.level or 0.0, inside=args.inside or "above")


def _improve_labels(wm, args, mesh, clock):
    """--optimize / --simplify of a shared multi-material surface (--interfaces shared): its
    own remeshing, which keeps every junction on its curve and measures the tolerance to the
    input surface."""
    from warpmesh.cli.flags import in_flags

    with clock.stage("optimize" if args.optimize else "simplify"), in_flags(_IMPROVE_FLAGS):
        if args.optimize:
            return wm.optimize(mesh, size=args.size, tolerance=args.max_error, progress=progress_bars())
        return wm.simplify(mesh, fraction=args.simplify, tolerance=args.max_error, progress=progress_bars())


def _improve(wm, args, mesh, bounds, target, clock):
    """--optimize / --simplify, and the largest distance of the result to the surface."""
    from warpmesh.cli.flags import in_flags

    capped = bounds is not None and not args.no_cap
    with clock.stage("optimize" if args.optimize else "simplify"), in_flags(_IMPROVE_FLAGS):
        if args.optimize:
            out = wm.optimize(mesh, target, bounds=bounds if capped else None, size=args.size,
                              tolerance=args.max_error, progress=progress_bars())
        else:
            out = wm.simplify(mesh, target, bounds=bounds if capped else None, fraction=args.simplify,
                              tolerance=args.max_error, progress=progress_bars())
    with clock.stage("distance check"), in_flags(_IMPROVE_FLAGS):
        distance = wm.surface_error(out, target, bounds=bounds if capped else None)["max"]
    return out, distance


def _renumber(wm, args) -> int:
    from warpmesh.cli.output import check_output, read_mesh, save_output
    from warpmesh.cli.report import mesh_figures
    from warpmesh.numbering.renumber import format_table

    check_output(args.output, flag="output", ascii=args.ascii)  # before any work
    mesh = read_mesh(args.input, "input")
    reverse = {"auto": "auto", "yes": True, "no": False}[args.reverse]
    out = mesh.renumber(args.method, reverse=reverse, higher_order=args.higher_order,
                        reduced=args.reduced, elements=not args.keep_elements)
    if args.color:
        out = out.color_elements(adjacency=args.color)
    save_output(out, args.output, "output", ascii=args.ascii)
    keys = ["np", "ne", "bandwidth_before", "profile_before", "profile_mean_before", "bandwidth",
            "profile", "profile_mean", "profile_ratio", "nodes_per_second", "renumber_time",
            "graph_time"] + (["n_colors", "packet_sizes"] if args.color else [])
    s = mesh_figures(out, keys)  # what the renumbering reported: no statistics recomputed
    row = {k: s[k] for k in keys}
    if args.json:
        print(json.dumps({**row, "method": args.method, "written": args.output}))
    else:
        print(format_table({args.input: row}))
        print(f"method {args.method}; written {args.output}")
        if args.color:
            print(f"{s['n_colors']} colours, packets {s['packet_sizes']}")
    return 0


def _mesh(wm, args, clock) -> int:
    from warpmesh.cli.flags import in_flags
    from warpmesh.cli.output import check_output, save_output
    from warpmesh.cli.report import print_report
    from warpmesh.cli.sources import parse_labels, shape_source, volume_source

    check_output(args.output, cells=("triangle",), ascii=args.ascii)  # before any work
    _check_mesh_flags(args)
    common = dict(root=args.root, root_iterations=args.root_iterations, cap=not args.no_cap,
                  device=args.device, gradient=args.gradient, labels=parse_labels(args.labels),
                  slab_voxels=args.slab_voxels, progress=progress_bars())
    if args.method:
        common["method"] = args.method
    for name in ("interfaces", "smoothing"):
        if getattr(args, name) is not None:
            common[name] = getattr(args, name)
    if args.covering:
        common["covering"] = args.covering
    if args.adaptive or args.tolerance is not None:
        common.update(adaptive=args.adaptive, tolerance=args.tolerance)
    if args.volume is None:
        if args.array is not None:
            raise ValueError("--array names an array of --volume; shapes have none")
        with clock.stage("read input"):
            source = shape_source(args, dims=(3,))
        shape, bounds = source.shape, source.bounds
        with clock.stage("mesh"), in_flags(_MESH_FLAGS):
            mesh = wm.mesh_surface(shape, bounds=bounds, resolution=args.resolution, level=args.level,
                                   evaluator=args.evaluator or (None if args.adaptive else "interpreter"),
                                   inside=args.inside, origin=args.origin,
                                   spacing=None if args.spacing is None else args.spacing[0], **common)
    else:
        if args.bounds is not None:
            raise ValueError("--bounds sets the box of a shape; a --volume's box is its grid (see --spacing, "
                             "--origin)")
        with clock.stage("read input"):
            volume = volume_source(args)
        bounds = None
        with clock.stage("mesh"), in_flags(_MESH_FLAGS):
            mesh = wm.mesh_surface(volume, resolution=args.resolution, level=args.level, inside=args.inside,
                                   evaluator=args.evaluator, **common)
    clock.split("mesh", mesh.info.get("time"))
    distance = None
    if (args.optimize or args.simplify is not None) and "label_above" in mesh.cell_data:
        mesh = _improve_labels(wm, args, mesh, clock)  # a shared multi-material surface
    elif args.optimize or args.simplify is not None:
        target = shape if args.volume is None else _volume_target(wm, args, volume)
        mesh, distance = _improve(wm, args, mesh, bounds, target, clock)
    if args.output:
        with clock.stage("save"):
            save_output(mesh, args.output, ascii=args.ascii)
    with clock.stage("statistics"):
        stats = mesh.stats()
    if distance is not None:
        opt = dict(stats["optimize"])
        opt["after"] = {**opt["after"], "distance_max": distance}
        stats["optimize"] = opt
    if args.output:
        stats["written"] = args.output
    print_report(mesh, stats, clock, args.json)
    return 0


def _info(wm, args, clock) -> int:
    from warpmesh.cli.output import read_mesh
    from warpmesh.cli.report import print_report

    with clock.stage("read"):
        mesh = read_mesh(args.path, "the mesh file")
    with clock.stage("statistics"):
        stats = mesh.stats()
    print_report(mesh, stats, clock, args.json)
    return 0


#: command -> the public names it calls, imported (with Warp) in the stage "import"
_IMPORTS = {"mesh": ("mesh_surface",), "curve": ("mesh_curve",), "domain": ("mesh_domain",), "info": ("load",)}


def _run(args, program: bool = False) -> int:
    import warpmesh as wm
    from warpmesh.cli import curves as cli_curves
    from warpmesh.cli import modify as cli_modify
    from warpmesh.cli import view as cli_view
    from warpmesh.cli.report import Clock, process_start

    clock = Clock(start=process_start() if program else None)  # the process is the command: from its start
    with clock.stage("import"):  # warpmesh imports lazily: the command's modules load here, not in its first stage
        for name in _IMPORTS.get(args.command, ()):
            getattr(wm, name)
    try:
        if args.command == "info":
            return _info(wm, args, clock)
        if args.command == "renumber":
            return _renumber(wm, args)
        if args.command in cli_modify.COMMANDS:
            return cli_modify.run(wm, args)
        if args.command in cli_curves.COMMANDS:
            return cli_curves.run(wm, args, clock)
        if args.command in cli_view.COMMANDS:
            return cli_view.run(wm, args)
        return _mesh(wm, args, clock)
    except BrokenPipeError:
        raise
    except (ValueError, TypeError, OSError, wm.WarpMeshError) as exc:
        print(f"warpmesh: error: {exc}", file=sys.stderr)
        return 2


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning as the command prints it: one line, ``warpmesh: warning: ...`` (not the
    source line that issued it)."""
    print(f"warpmesh: warning: {message}", file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    """Run the ``warpmesh`` command with ``argv`` (default ``sys.argv[1:]``); the exit status.

    0 on success, 2 on bad input (one line on stderr: ``warpmesh: error: ...``), 130 when
    interrupted (Ctrl-C: one line on stderr, no file written; run as the program, with
    ``argv=None``, the process ends at once rather than after the kernels of worker threads).

    Examples
    --------
    >>> main(["mesh", "--example", "sphere", "--resolution", "16", "-o", "no/such/folder/s.ply"])
    2
    """
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _warning_line
            return _run(_parser().parse_args(argv), program=argv is None)
    except BrokenPipeError:  # the reader left (| head): no traceback, no error line
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt:
        lead = "\n" if sys.stderr.isatty() else ""  # past the terminal's ^C or a progress bar
        print(f"{lead}warpmesh: interrupted", file=sys.stderr)
        if argv is None and threading.active_count() > 1:
            # the process itself (not a caller's main([...])): Warp launches still running in worker
            # threads would hold the exit until they end; files are written atomically, so leave now
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(130)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
