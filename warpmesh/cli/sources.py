"""Where the command line's shape comes from: a bundled example, a Python file, an expression.

``warpmesh mesh | curve | domain | view`` take one of

- ``--example NAME``: a bundled shape with its bounds (:func:`warpmesh.example`);
- ``FILE.py[:NAME]``: a Python file that defines the shape as ``NAME`` (default ``shape``)
  and may define ``bounds``; the file is run as Python, with your permissions;
- ``--expr "..."``: an expression of ``x, y, z`` (``x, y`` in the plane) and the ``wm``
  functions, evaluated as Python in a namespace without builtins;

and ``--bounds x0 y0 z0 x1 y1 z1`` (``x0 y0 x1 y1`` in the plane), which an expression
needs and which replaces the bounds of an example or a file. ``mesh`` and ``domain`` also
take ``--volume FILE`` (an image :func:`warpmesh.load_volume` reads) with ``--array``,
``--spacing``, ``--origin`` and ``--labels`` (:func:`add_volume_arguments`, :func:`volume_source`).

Examples
--------
>>> import argparse
>>> from warpmesh.cli.sources import add_shape_arguments, shape_source
>>> p = argparse.ArgumentParser()
>>> add_shape_arguments(p, p.add_mutually_exclusive_group(required=True), dims=(3,))
>>> args = p.parse_args(["--expr", "1 - x**2 - y**2 - z**2", "--bounds", "-2", "-2", "-2", "2", "2", "2"])
>>> source = shape_source(args, dims=(3,))
>>> source.label, source.bounds
('--expr', ((-2.0, -2.0, -2.0), (2.0, 2.0, 2.0)))
"""

from __future__ import annotations

import ast
import math
import os
import runpy
import traceback
from dataclasses import dataclass

__all__ = ["ShapeSource", "add_shape_arguments", "shape_source", "is_shape_file", "expression_namespace",
           "add_volume_arguments", "volume_source", "parse_labels"]

#: the functions an expression may call, besides the ``wm`` module itself
_FUNCTIONS = ("sqrt", "abs", "min", "max", "sin", "cos", "exp", "log")


@dataclass(frozen=True)
class ShapeSource:
    """A shape named on the command line: the shape, its bounds and how the user named it."""

    shape: object
    bounds: tuple
    label: str  # "--example part", "torus.py:shape", "--expr"


def add_shape_arguments(parser, group, *, dims: tuple[int, ...], file_argument: bool = True) -> None:
    """Add ``--example``, ``FILE.py[:NAME]``, ``--expr`` (to ``group``) and ``--bounds``.

    ``dims`` are the dimensions the command meshes: ``(3,)``, ``(2,)`` or ``(2, 3)``.
    With ``file_argument=False`` the positional file is left to the caller (``view``
    takes a mesh file or a shape file in one positional).
    """
    from warpmesh.frep.examples import EXAMPLES, EXAMPLES_2D

    names = [*(EXAMPLES_2D if 2 in dims else ()), *(EXAMPLES if 3 in dims else ())]
    coords = "x, y, z" if dims == (3,) else "x, y" if dims == (2,) else "x, y (2D bounds) or x, y, z (3D bounds)"
    box = {(3,): "x0 y0 z0 x1 y1 z1", (2,): "x0 y0 x1 y1"}.get(dims, "x0 y0 x1 y1 | x0 y0 z0 x1 y1 z1")
    group.add_argument("--example", choices=names, help="a bundled example shape (with its bounds)")
    if file_argument:
        group.add_argument("shape_file", nargs="?", metavar="FILE.py[:NAME]",
                           help="a Python file defining the shape as NAME (default 'shape') and optionally "
                                "'bounds'; the file runs as Python, with your permissions")
    group.add_argument("--expr", metavar="EXPRESSION",
                       help=f"f({coords}) > 0 inside, e.g. \"1 - x**2 - y**2\"; may call {', '.join(_FUNCTIONS)} "
                            "and wm.<name>; evaluated as Python without builtins (only run expressions you trust); "
                            "needs --bounds")
    parser.add_argument("--bounds", type=float, nargs="+", metavar="V",
                        help=f"the box to mesh in: {box} (replaces the bounds of an example or a file)")


def is_shape_file(text: str | None) -> bool:
    """True for ``FILE.py`` or ``FILE.py:NAME`` (the shape-file positional).

    Examples
    --------
    >>> is_shape_file("torus.py:ring"), is_shape_file("torus.py"), is_shape_file("torus.ply")
    (True, True, False)
    """
    return text is not None and _split_file(text)[0].lower().endswith(".py")


def _split_file(text: str) -> tuple[str, str]:
    head, sep, tail = text.rpartition(":")
    if sep and head.lower().endswith(".py") and tail.isidentifier():
        return head, tail
    return text, "shape"


def expression_namespace(dim: int) -> dict:
    """The names an ``--expr`` sees: the coordinates, :data:`_FUNCTIONS`, ``pi`` and ``wm``.

    Examples
    --------
    >>> sorted(expression_namespace(2))[:6]
    ['__builtins__', 'abs', 'cos', 'exp', 'log', 'max']
    """
    import warpmesh as wm

    names = dict(zip("xyz", wm.coords(dim)))
    names.update({f: getattr(wm, f) for f in _FUNCTIONS}, pi=math.pi, wm=wm, __builtins__={})
    return names


def _shape_from_expr(text: str, dim: int):
    import warpmesh as wm

    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ValueError(f"expected a Python expression for --expr, got {text!r}: {exc.msg}") from None
    _check_tree(tree, wm)
    names = expression_namespace(dim)
    try:
        value = eval(compile(tree, "--expr", "eval"), names)  # noqa: S307 - restricted namespace, documented
    except NameError as exc:
        known = ", ".join(k for k in names if k != "__builtins__")
        raise ValueError(f"--expr: {exc}; the names are {known}") from None
    except Exception as exc:  # the user's expression may raise anything
        raise ValueError(f"--expr {text!r} failed: {type(exc).__name__}: {exc}") from None
    if not isinstance(value, (wm.Shape, wm.Expr)):
        raise ValueError(f"expected --expr to depend on {', '.join('xyz'[:dim])}, got the constant {value!r}")
    return value


def _check_tree(tree: ast.AST, wm) -> None:
    """Refuse what an expression of a shape never needs: names starting with '_', lambdas,
    ``wm`` other than as ``wm.<public function or shape>``, and the subpackages of ``wm``
    (a way to the modules they import). Not a sandbox: the help says --expr runs Python."""
    bare = {id(node.value) for node in ast.walk(tree) if isinstance(node, ast.Attribute)}
    for node in ast.walk(tree):
        name = node.id if isinstance(node, ast.Name) else node.attr if isinstance(node, ast.Attribute) else ""
        if name.startswith("_"):
            raise ValueError(f"expected no names starting with '_' in --expr, got {name!r}")
        if isinstance(node, (ast.Lambda, ast.NamedExpr)):
            raise ValueError("expected an expression of the coordinates in --expr, got a lambda or an assignment")
        if isinstance(node, ast.Name) and node.id == "wm" and id(node) not in bare:
            raise ValueError("expected wm.<name> in --expr, got wm alone")
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "wm":
            value = getattr(wm, node.attr, None)
            if node.attr not in wm.__all__ + ["min", "max", "abs"] or type(value) is type(ast):
                raise ValueError(f"expected a function or shape of warpmesh in --expr, got wm.{node.attr}")


def _run_file(text: str):
    path, name = _split_file(text)
    if not os.path.isfile(path):
        raise ValueError(f"no such shape file: {path!r}")
    try:
        names = runpy.run_path(path, run_name="__warpmesh_shape__")
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # the user's file may raise anything, SystemExit included
        line = getattr(exc, "lineno", None)
        if line is None:
            here = os.path.abspath(path)
            lines = [f.lineno for f in traceback.extract_tb(exc.__traceback__) if os.path.abspath(f.filename) == here]
            line = lines[-1] if lines else None
        where = f"{path}, line {line}" if line else path
        raise ValueError(f"running the shape file {where}: {type(exc).__name__}: {exc}") from None
    if name not in names:
        found = sorted(k for k, v in names.items() if _is_shape(v))
        raise ValueError(f"expected {path!r} to define {name!r}; shapes found there: {found or 'none'} "
                         f"(pick one as {path}:NAME)")
    if not _is_shape(names[name]):
        raise ValueError(f"expected {path}:{name} to be a warpmesh Shape or expression, "
                         f"got {type(names[name]).__name__}")
    return names[name], names.get("bounds"), f"{path}:{name}"


def _is_shape(value) -> bool:
    import warpmesh as wm

    return isinstance(value, (wm.Shape, wm.Expr))


def _box(values, where: str, dims: tuple[int, ...]) -> tuple:
    flat = [float(v) for v in (values if not _nested(values) else [*values[0], *values[1]])]
    if len(flat) // 2 not in dims or len(flat) % 2:
        want = " or ".join(str(2 * d) for d in dims)
        raise ValueError(f"expected {want} numbers for {where} (x0 y0{' z0' if 3 in dims else ''} x1 ...), "
                         f"got {len(flat)}")
    d = len(flat) // 2
    lo, hi = tuple(flat[:d]), tuple(flat[d:])
    if not all(math.isfinite(v) for v in flat) or not all(a < b for a, b in zip(lo, hi)):
        raise ValueError(f"expected finite {where} with x0 < x1, y0 < y1{', z0 < z1' if d == 3 else ''}, "
                         f"got {lo} {hi}")
    return lo, hi


def _nested(values) -> bool:
    try:
        return len(values) == 2 and all(len(v) in (2, 3) for v in values)
    except TypeError:
        return False


def shape_source(args, *, dims: tuple[int, ...], file_text: str | None = None) -> ShapeSource:
    """The shape, bounds and label named by ``--example | FILE.py[:NAME] | --expr`` and ``--bounds``.

    ``file_text`` is the shape-file positional when the caller parses it itself (``view``).

    Raises
    ------
    ValueError
        A missing or unreadable file, a file that does not define the shape, an expression
        that does not evaluate to one, missing or malformed bounds, a 3D shape where the
        command meshes planar ones.
    """
    import warpmesh as wm

    text = file_text if file_text is not None else getattr(args, "shape_file", None)
    if args.example:
        shape, bounds = wm.example(args.example)
        label, where = f"--example {args.example}", f"the bounds of --example {args.example}"
    elif text is not None:
        shape, bounds, label = _run_file(text)
        where = f"'bounds' in {_split_file(text)[0]}"
    else:
        shape, bounds, label, where = None, None, "--expr", "--bounds"
    if args.bounds is not None:
        bounds, where = _box(args.bounds, "--bounds", dims), "--bounds"
    elif bounds is None:
        need = "--expr" if text is None else f"{label} (it defines no 'bounds')"
        raise ValueError(f"expected --bounds with {need}")
    else:
        bounds = _box(bounds, where, dims)
    dim = len(bounds[0])
    if shape is None:
        shape = _shape_from_expr(args.expr, dim)
    if isinstance(shape, wm.Expr):
        shape = wm.Shape(shape)
    if dim == 2 and shape.dim == 3:
        raise ValueError(f"expected a planar shape (of x, y) with 2D bounds, but {label} depends on z")
    return ShapeSource(shape, bounds, label)


def add_volume_arguments(parser, group, *, labels_help: str) -> None:
    """Add ``--volume`` (to ``group``, beside the shape sources), ``--array``, ``--spacing``,
    ``--origin`` and ``--labels``."""
    group.add_argument("--volume", metavar="FILE",
                       help="a 3D image: .vti .vtk .nii .nii.gz .nrrd .nhdr .mha .mhd .npy .npz, or a DICOM series "
                            "folder (the medical formats need pip install 'warpmesh[images]')")
    parser.add_argument("--array", metavar="NAME",
                        help="--volume: the array (VTK point/cell array, .npz key) or DICOM series ID to read")
    parser.add_argument("--spacing", type=float, nargs="+",
                        help="sample spacing, 1 or 3 values (volumes; replaces the image's own)")
    parser.add_argument("--origin", type=float, nargs=3,
                        help="position of sample [0, 0, 0] (volumes; replaces the image's own)")
    parser.add_argument("--labels", nargs="+", metavar="LABEL", help=labels_help)


def parse_labels(values):
    """``--labels``: None, ``"all"`` or a list of ints.

    Examples
    --------
    >>> parse_labels(["all"]), parse_labels(["3", "0"]), parse_labels(None)
    ('all', [3, 0], None)
    """
    if values is None:
        return None
    if values == ["all"]:
        return "all"
    try:
        return [int(v) for v in values]
    except ValueError:
        raise ValueError(f"expected --labels all or integer labels, got {' '.join(values)}") from None


def volume_source(args):
    """``--volume`` as a :class:`~warpmesh.io.images.Volume`, with ``--spacing`` / ``--origin``
    in place of the file's own.

    Raises
    ------
    ValueError
        A file that is missing, does not parse, or needs a reader that is not installed
        (the message names ``--volume`` and the path).
    """
    import warpmesh as wm

    try:
        volume = wm.load_volume(args.volume, name=args.array)
    except (OSError, ValueError, ImportError) as exc:
        raise ValueError(f"cannot read --volume {args.volume!r}: {exc}") from None
    if args.spacing is not None:
        volume = volume.replace(spacing=args.spacing if len(args.spacing) > 1 else args.spacing[0])
    if args.origin is not None:
        volume = volume.replace(origin=args.origin)
    return volume
