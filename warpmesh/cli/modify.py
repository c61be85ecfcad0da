"""The mesh-modification sub-commands of ``warpmesh`` [FG ch. 17]: transform, refine,
convert, merge, crack, periodic. Each reads any format meshio reads, writes atomically
(nothing is written when the operation fails) and prints the statistics of the result.

Examples
--------
``warpmesh transform in.msh out.msh --rotate 30 --axis 0 0 1 --center 0 0 0``
``warpmesh transform in.vtu out.vtu --mirror 1 0 0 0`` (the plane x = 0)
``warpmesh refine in.msh out.msh -n 2``; ``warpmesh refine in.msh out.msh --max-length 0.05``
``warpmesh convert hex.vtu tet.vtu --to tetra``
``warpmesh merge left.msh right.msh whole.msh --tolerance 1e-9``
``warpmesh crack in.msh out.msh --ref 7``
``warpmesh periodic blade.msh wheel.msh --rotate 60 --axis 0 0 1 --copies 6``
"""

from __future__ import annotations

import argparse
import json

import numpy as np

COMMANDS = ("transform", "refine", "convert", "merge", "crack", "periodic")
_SHOWN = ("np", "ne", "n_cells", "volume", "area", "worst_q", "mean_q")


def _io(p: argparse.ArgumentParser, *inputs: str) -> None:
    from warpmesh.cli.output import add_ascii_argument, extensions_text

    for name in inputs:
        p.add_argument(name, help=f"mesh file to read ({extensions_text(())})")
    p.add_argument("output", help=f"mesh file to write ({extensions_text(())}; the format must store the "
                                  "result's cells)")
    add_ascii_argument(p)
    p.add_argument("--json", action="store_true", help="print the statistics as JSON")


def _motion(p: argparse.ArgumentParser) -> None:
    p.add_argument("--matrix", metavar="FILE",
                   help="a (d+1)x(d+1) homogeneous or dxd matrix, as .npy or whitespace text")
    p.add_argument("--scale", type=float, nargs="+", metavar="S", help="dilation factor(s) about --center")
    p.add_argument("--rotate", type=float, metavar="DEGREES", help="rotation angle about --center")
    p.add_argument("--axis", type=float, nargs=3, metavar=("AX", "AY", "AZ"), help="3D rotation axis (default z)")
    p.add_argument("--center", type=float, nargs="+", help="centre of rotation / dilation")
    p.add_argument("--mirror", type=float, nargs="+", metavar="C",
                   help="symmetry about the line A B C (2D: Ax+By+C=0) or the plane A B C D (3D)")
    p.add_argument("--translate", type=float, nargs="+", metavar="T", help="translation vector")


def add_parsers(sub) -> None:
    """Add the sub-commands to the ``warpmesh`` parser's sub-parsers."""
    t = sub.add_parser("transform", help="apply symmetries, rotations, dilations, translations ([FG §17.1.1])",
                       description="Applied in this order: --matrix, --scale, --rotate, --mirror, --translate.")
    _io(t, "input")
    _motion(t)
    r = sub.add_parser("refine", help="refine globally (-n) or locally (--max-length) ([FG §17.1.2])")
    _io(r, "input")
    r.add_argument("-n", type=int, help="split every element into n^d (default 2 without --max-length)")
    r.add_argument("--max-length", type=float, help="bisect longest edges until every edge is at most this")
    r.add_argument("--vertices", metavar="FILE", help="refine around these vertex indices (.npy or text)")
    r.add_argument("--example", help="project new boundary nodes onto this bundled example shape")
    c = sub.add_parser("convert", help="split elements into another type ([FG §17.1.3])")
    _io(c, "input")
    c.add_argument("--to", required=True, choices=["triangle", "quad", "tetra", "hexahedron"],
                   help="the element type to split into: triangle (a quad -> 2 or 4), quad (a triangle -> 3), "
                        "tetra (a hexahedron -> 5 or 6, a wedge -> 3, a pyramid -> 2), hexahedron (a "
                        "tetrahedron -> 4)")
    c.add_argument("--quads", choices=["best", "min", "4"],
                   help="--to triangle: quad -> 2 triangles on the best diagonal (default), through the "
                        "smallest vertex number, or 4 around the centroid")
    c.add_argument("--hexes", choices=["auto", "5", "6"],
                   help="--to tetra: conforming 5- or 6-tetra split per hexahedron (auto, default), "
                        "all 5 (alternating, structured meshes) or all 6")
    m = sub.add_parser("merge", help="merge two meshes along their common boundary ([FG §17.2])")
    _io(m, "first", "second")
    m.add_argument("--tolerance", type=float, help="absolute distance under which points merge "
                   "(default 2.4e-7 of the bounding box: a few float32 ulps)")
    m.add_argument("--refs", action="store_true", help="merge only points with equal refs")
    m.add_argument("--duplicates", choices=["merge", "keep", "drop"], default="merge",
                   help="cells found in both meshes: keep one (default), both, or none")
    k = sub.add_parser("crack", help="cut the mesh open along interior facets ([FG §17.5])")
    _io(k, "input")
    src = k.add_mutually_exclusive_group(required=True)
    src.add_argument("--ref", type=int, help="the facets of the boundary blocks with this ref")
    src.add_argument("--facets", metavar="FILE", help="(k, 2|3|4) vertex indices (.npy or text)")
    k.add_argument("--side-refs", type=int, nargs=2, metavar=("R1", "R2"),
                   help="refs of the two lips (default: both keep the facet ref)")
    p = sub.add_parser("periodic", help="repeat a pattern by a transformation and merge ([FG §17.5])",
                       description="The transformation is built as for 'transform'.")
    _io(p, "input")
    _motion(p)
    p.add_argument("--copies", type=int, required=True, help="number of patterns in the result")
    p.add_argument("--tolerance", type=float, help="absolute merge tolerance")


def _array(path: str, name: str, dtype) -> np.ndarray:
    try:
        return np.load(path, allow_pickle=False) if path.endswith(".npy") else np.loadtxt(path, dtype=dtype, ndmin=2)
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read {name} {path!r}: {exc}") from None


def _matrix(wm, args, dim: int) -> np.ndarray:
    tr = wm.transforms
    steps = []
    if args.matrix:
        steps.append(tr.matrix(_array(args.matrix, "--matrix", float), dim=dim))
    center = args.center
    if args.scale:
        factors = args.scale[0] if len(args.scale) == 1 else args.scale
        steps.append(tr.dilation(factors, center=center, dim=dim))
    if args.rotate is not None:
        angle = np.deg2rad(args.rotate)
        if dim == 3:  # about z unless an axis is given
            steps.append(tr.rotation(angle, axis=args.axis or (0.0, 0.0, 1.0), center=center))
        elif args.axis is not None:
            raise ValueError("expected no --axis for a 2D mesh (rotations are about --center)")
        else:
            steps.append(tr.rotation(angle, center=center))
    elif args.axis is not None:
        raise ValueError("expected --rotate with --axis, got --axis alone")
    if args.mirror:
        steps.append(tr.symmetry(args.mirror))
    if args.translate:
        steps.append(tr.translation(args.translate))
    if not steps:
        raise ValueError("expected at least one of --matrix --scale --rotate --mirror --translate")
    return tr.compose(*steps)


def _motion_of(wm, mesh, args) -> np.ndarray:
    """The homogeneous matrix of the motion flags for ``mesh``: 2D flags (``--translate X Y``,
    ``--mirror A B C``, ``--center X Y``, ``--scale SX SY``) on a mesh in the plane z = 0 read
    from a format that stores three coordinates (.vtu, .msh: a planar mesh comes back 3D) are
    the planar motion, lifted to 3D (z kept)."""
    if mesh.dim == 3 and args.matrix is None and args.axis is None and not np.any(mesh.points[:, 2]):
        planar = [len(v) == k for v, k in ((args.translate, 2), (args.mirror, 3), (args.center, 2),
                                           (args.scale, 2)) if v]
        if any(planar) and all(planar):
            m2 = _matrix(wm, args, 2)
            m3 = np.eye(4)
            m3[:2, :2], m3[:2, 3] = m2[:2, :2], m2[:2, 2]
            return m3
    return _matrix(wm, args, mesh.dim)


#: the library's keywords that the modification commands' errors quote, as their flags
_FLAGS = {"vector": "--translate", "angle": "--rotate", "factors": "--scale", "center": "--center",
          "n": "-n", "max_length": "--max-length", "where": "--vertices", "tolerance": "--tolerance",
          "copies": "--copies", "side_refs": "--side-refs", "facets": "--facets", "ref": "--ref",
          "duplicates": "--duplicates", "quads": "--quads", "hexes": "--hexes"}


def _report(before: dict, mesh, args) -> None:
    after = mesh.stats()
    facts = {k: v for k, v in mesh.info.items()
             if isinstance(v, (int, float, str, bool, np.integer, np.floating)) and k not in _SHOWN}
    if args.json:  # the whole statistics of both meshes
        print(json.dumps({"before": before, "after": after, **facts, "written": args.output},
                         default=lambda v: v.tolist() if hasattr(v, "tolist") else str(v)))
        return
    print(f"{'':>14}" + "".join(f"{k:>12}" for k in _SHOWN))
    for name, s in (("before", before), ("after", after)):
        # "-": a figure stats() does not give for these cells (the quality of hexahedra)
        cells = [f"{s.get(k):>12.6g}" if isinstance(s.get(k), float) else
                 f"{'-' if s.get(k) is None else str(s.get(k)):>12}" for k in _SHOWN]
        print(f"{name:>14}" + "".join(cells))
    for key, value in facts.items():
        print(f"{key:>22}: {value}")
    print(f"written {args.output}")


def run(wm, args) -> int:
    """Run one of :data:`COMMANDS` (errors propagate to the caller, which prints them)."""
    from warpmesh.cli.output import check_output, read_mesh, save_output

    from warpmesh.cli.flags import in_flags

    check_output(args.output, flag="output", ascii=args.ascii)  # a bad extension or folder fails before any work
    mesh = read_mesh(args.first if args.command == "merge" else args.input, "input")
    before = mesh.stats()
    with in_flags(_FLAGS):
        out = _modified(wm, mesh, args)
    save_output(out, args.output, "output", ascii=args.ascii)
    _report(before, out, args)
    return 0


def _modified(wm, mesh, args):
    """The command's result (:func:`run`)."""
    from warpmesh.cli.output import read_mesh

    if args.command == "transform":
        out = mesh.transform(_motion_of(wm, mesh, args))
    elif args.command == "refine":
        where = None if args.vertices is None else _array(args.vertices, "--vertices", np.int64).ravel()
        shape = wm.example(args.example)[0] if args.example else None
        if where is None and args.max_length is None:
            out = mesh.refine(2 if args.n is None else args.n, shape)
        else:
            if args.n is not None:
                raise ValueError("expected -n or --max-length/--vertices, got both")
            out = mesh.refine(shape=shape, where=where, max_length=args.max_length)
    elif args.command == "convert":
        options = {}
        if args.quads is not None:
            options["quads"] = 4 if args.quads == "4" else args.quads
        if args.hexes is not None:
            options["hexes"] = args.hexes if args.hexes == "auto" else int(args.hexes)
        out = mesh.convert(args.to, **options)
    elif args.command == "merge":
        out = mesh.merge(read_mesh(args.second, "input"), args.tolerance, refs=args.refs, duplicates=args.duplicates)
    elif args.command == "crack":
        side = None if args.side_refs is None else tuple(args.side_refs)
        if args.ref is not None:
            out = mesh.crack(ref=args.ref, side_refs=side)
        else:
            out = mesh.crack(_array(args.facets, "--facets", np.int64), side_refs=side)
    else:
        out = mesh.periodic(_motion_of(wm, mesh, args), args.copies, tolerance=args.tolerance)
    return out
