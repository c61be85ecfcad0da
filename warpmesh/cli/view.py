"""The ``view`` sub-command of ``warpmesh``: a picture or a WebGL page of a mesh file or example.

``-o out.png`` renders off-screen (pyvista/VTK, no display needed); ``-o out.html`` writes
the self-contained WebGL page (:mod:`warpmesh.preview.render`); without ``-o`` the page
goes to a temporary file whose path is printed (``--open`` opens it in the browser).

Examples
--------
``warpmesh view --example part --resolution 96 -o part.png``
``warpmesh view part.ply -o part.html``
``warpmesh view --example torus --open``
``warpmesh view shapes.py:bracket -o bracket.png``; ``warpmesh view --expr "1 - x**4 - y**4 - z**4" --bounds -1.2 -1.2 -1.2 1.2 1.2 1.2``
"""

from __future__ import annotations

import os
import sys
import tempfile

COMMANDS = ("view",)
_OUTPUTS = (".png", ".html", ".htm")


def add_parsers(sub) -> None:
    """Add the sub-command to the ``warpmesh`` parser's sub-parsers."""
    from warpmesh.cli.output import extensions_text
    from warpmesh.cli.sources import add_shape_arguments

    v = sub.add_parser("view", help="a picture (.png, off-screen) or a WebGL page (.html) of a mesh or shape")
    src = v.add_mutually_exclusive_group(required=True)
    src.add_argument("path", nargs="?", metavar="FILE",
                     help=f"a mesh file ({extensions_text(())}) or a shape file FILE.py[:NAME] (run as Python)")
    add_shape_arguments(v, src, dims=(3,), file_argument=False)
    v.add_argument("--resolution", type=int, default=128, help="shapes: cells along the longest side (128)")
    v.add_argument("-o", "--output", help="out.png (off-screen picture) or out.html (WebGL page)")
    v.add_argument("--window-size", type=int, nargs=2, default=(800, 600), metavar=("W", "H"),
                   help="picture size in pixels (.png)")
    v.add_argument("--edges", action="store_true", help="draw the triangle edges (.png)")
    v.add_argument("--clip", choices=["auto", "x", "y", "z", "none"], default="auto",
                   help="volume meshes: cut through the middle across this axis (auto: x), or none: the outside only")
    v.add_argument("--open", action="store_true", help="open the page in the web browser")
    v.add_argument("--device", default="cpu", help="Warp device (cpu, cuda)")


def run(wm, args) -> int:
    """Run ``view`` (errors propagate to the caller, which prints them)."""
    from warpmesh.cli.output import check_folder, read_mesh
    from warpmesh.cli.sources import is_shape_file, shape_source
    from warpmesh.preview.render import render_png, write_html

    out = args.output
    if out is not None:
        if os.path.splitext(out)[1].lower() not in _OUTPUTS:
            raise ValueError(f"expected an output ending in {' '.join(_OUTPUTS)} for -o/--output, got {out!r}")
        check_folder(out, "-o/--output")
    if args.edges and (out is None or not out.lower().endswith(".png")):
        raise ValueError("--edges draws the triangle edges of a .png picture; the .html page (the default without "
                         "-o) has its own view: give -o out.png, or drop --edges")
    if args.path is not None and not is_shape_file(args.path):
        if args.bounds is not None:
            raise ValueError("--bounds sets the box of a shape; a mesh file has its own")
        mesh = read_mesh(args.path, "the mesh file")
        title = os.path.basename(args.path)
    else:
        source = shape_source(args, dims=(3,), file_text=args.path)
        mesh = wm.mesh_surface(source.shape, bounds=source.bounds, resolution=args.resolution, device=args.device,
                               evaluator="interpreter")
        title = f"warpmesh {source.label} ({args.resolution})"
    clip = None if args.clip == "none" else args.clip
    if out is None:
        fd, out = tempfile.mkstemp(prefix="warpmesh-view-", suffix=".html")
        os.close(fd)
    if out.lower().endswith(".png"):
        render_png(mesh, out, window_size=tuple(args.window_size), show_edges=args.edges, clip=clip)
    else:
        write_html(mesh, out, title=title, clip=clip)
    print(f"{title}: {mesh.n_points} points, {mesh.n_cells} cells -> {out}")
    if args.open:
        import webbrowser

        if not webbrowser.open("file://" + os.path.abspath(out)):
            print("warpmesh: no web browser to open; the page is at the path above", file=sys.stderr)
    return 0
