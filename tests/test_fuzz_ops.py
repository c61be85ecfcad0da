"""A fuzz of the mesh operations (issue 19 item 7): every operation of :class:`warpmesh.Mesh`
on random good meshes and on degenerate ones, each case under a time limit.

Good meshes: closed surfaces from ``mesh_surface`` (sphere, torus, the part) at random
resolutions, planar triangles and quads, Kuhn tetrahedra and hexahedra, each moved by a
random rotation, a scale of 1e-6..1e6 and a translation. Degenerate ones: every point
duplicated with faces on both copies, a zero-area triangle, a cell with a repeated vertex,
many points collapsed onto one, a single triangle, an open two-triangle strip, a surface
far from its target shape, a 1e-150 or 1e150 scale.

Each case must, within ``TIME_LIMIT`` seconds (``signal.setitimer``: a hang in host code
is interrupted, one inside a single C call would be noticed on its return), either

- return a valid result: a :class:`~warpmesh.Mesh` (closed, oriented and embedded when its
  input was and the operation keeps the surface: ``tests/helpers/meshcheck.check_mesh``;
  positive, conforming and embedded cells for planar and volume meshes:
  ``tests/helpers/cellcheck.check_cells``) with the operation's own invariant (cell
  counts of a uniform refinement, the points of a transformation or a round trip through
  a file, ...); or
- raise a :class:`~warpmesh.WarpMeshError`, ``ValueError`` or ``TypeError`` whose
  message quotes what it refuses (never on a good closed surface for an operation made for one:
  ``SURFACE_OPERATIONS``): never another exception type, never a hang.

A bounded, derandomised slice runs in the normal suite; ``-m slow`` runs a longer one
(CI runs both); a long run is
``WARPMESH_FUZZ_OPS_EXAMPLES=2000 python -m pytest tests/test_fuzz_ops.py -m slow``, or
``python -m tests.test_fuzz_ops FIRST COUNT`` to count failures over seeds without stopping.
"""

from __future__ import annotations

import os
import re
import signal
import sys
import tempfile
import time
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import warpmesh as wm
from tests.helpers.fuzz_settings import seeded
from tests.helpers.blocks import hex_block, kuhn_block, tri_square
from tests.helpers.cellcheck import check_cells
from tests.helpers.meshcheck import check_mesh

#: seconds a case may take before it counts as a hang
TIME_LIMIT = 60.0
GOOD = ("sphere", "torus", "part", "tri2d", "quad2d", "tet", "hex")
DEGENERATE = ("duplicated points", "zero-area triangle", "repeated vertex", "collapsed points",
              "single triangle", "open strip", "far target", "tiny scale", "huge scale")
OPERATIONS = ("optimize", "simplify", "refine", "refine local", "transform", "merge", "periodic", "crack",
              "convert", "renumber", "color", "to order", "save load", "stats", "check", "orient",
              "surface error")
#: what a refusal may be
REFUSALS = (wm.WarpMeshError, ValueError, TypeError)
#: and what the message of a ValueError or TypeError must hold: a quoted name, or "expected X, got Y"
REFUSAL_TEXT = r"'[^']+'|expected .+ got "
SURFACES = ("sphere", "torus", "part")
#: operations that must not refuse a good closed surface
SURFACE_OPERATIONS = ("optimize", "simplify", "refine", "refine local", "transform", "renumber", "color",
                      "save load", "stats", "check", "orient", "surface error", "to order")


class Hang(BaseException):
    """The case ran out of time (a BaseException, so no ``except Exception`` swallows it)."""


@contextmanager
def time_limit(seconds: float):
    def alarm(signum, frame):
        raise Hang(f"no answer within {seconds:g} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


# ----------------------------------------------------------------------------- inputs
def _affine(rng, dim: int, scale: float) -> np.ndarray:
    """A random rotation, a uniform scale and a translation of a few sizes."""
    q, r = np.linalg.qr(rng.normal(size=(dim, dim)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    m = np.eye(dim + 1)
    m[:dim, :dim] = scale * q
    m[:dim, dim] = scale * rng.uniform(-3, 3, dim)
    return m


def _surface(rng, name: str):
    shape, bounds = wm.example(name)
    res = int(rng.integers(6, 15)) if name != "part" else int(rng.integers(14, 22))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = wm.mesh_surface(shape, bounds=bounds, resolution=res, method=("mc", "mc33", "mt")[int(rng.integers(3))])
    return m, shape


def _good(rng, kind: str):
    """(mesh, shape or None, closed surface?)"""
    if kind in SURFACES:
        m, shape = _surface(rng, kind)
        return m, shape, True
    if kind == "tri2d":
        return tri_square(int(rng.integers(2, 9)), seed=int(rng.integers(1000))), None, False
    if kind == "quad2d":
        n = int(rng.integers(1, 7))
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        pts = np.c_[i.ravel(), j.ravel()] / n
        k = (i[:-1, :-1] * (n + 1) + j[:-1, :-1]).ravel()
        return wm.Mesh(pts, {"quad": np.c_[k, k + n + 1, k + n + 2, k + 1]}), None, False
    if kind == "tet":
        return kuhn_block(int(rng.integers(1, 4))), None, False
    return hex_block(int(rng.integers(1, 4))), None, False


def _degenerate(rng, kind: str):
    """(mesh, shape or None): inputs an operation may refuse but must not hang on."""
    if kind == "single triangle":
        d = int(rng.integers(2, 4))
        return wm.Mesh(rng.normal(size=(3, d)), {"triangle": [[0, 1, 2]]}), None
    if kind == "open strip":
        p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.0]])
        return wm.Mesh(p, {"triangle": [[0, 1, 2], [1, 3, 2]]}), None
    m, shape = _surface(rng, ("sphere", "torus")[int(rng.integers(2))])
    pts, tri = m.points, m.triangles
    if kind == "duplicated points":  # every point twice, faces on either copy
        use = rng.integers(0, 2, tri.shape) * len(pts)
        return wm.Mesh(np.concatenate([pts, pts]), {"triangle": tri + use}), shape
    if kind == "zero-area triangle":  # a point on an edge's midpoint and the flat triangle it makes
        a, b = tri[0, 0], tri[0, 1]
        mid = 0.5 * (pts[a] + pts[b])
        return wm.Mesh(np.vstack([pts, mid]), {"triangle": np.vstack([tri, [[a, b, len(pts)]]])}), shape
    if kind == "repeated vertex":
        return wm.Mesh(pts, {"triangle": np.vstack([tri, [[tri[0, 0], tri[0, 1], tri[0, 0]]]])}), shape
    if kind == "collapsed points":  # a random part of the points moved onto one
        p = pts.copy()
        p[rng.random(len(p)) < rng.uniform(0.05, 0.6)] = p[int(rng.integers(len(p)))]
        return wm.Mesh(p, {"triangle": tri}), shape
    if kind == "far target":
        return m.transform(wm.transforms.translation(rng.uniform(5, 100, 3))), shape
    scale = 1e-150 if kind == "tiny scale" else 1e150
    return m.transform(wm.transforms.dilation(scale, dim=3)), None


def make_case(seed: int):
    """(description, input mesh, target shape or None, closed, operation, rng) of a seed;
    closed: True for a closed surface, False for another valid mesh, None if degenerate."""
    rng = np.random.default_rng(seed)
    op = OPERATIONS[int(rng.integers(len(OPERATIONS)))]
    if rng.random() < 0.3:
        kind = DEGENERATE[int(rng.integers(len(DEGENERATE)))]
        mesh, shape = _degenerate(rng, kind)
        closed = None
    else:
        kind = GOOD[int(rng.integers(len(GOOD)))]
        mesh, shape, closed = _good(rng, kind)
        if rng.random() < 0.7:  # moved, turned and scaled (1e-6..1e6)
            scale = 10.0 ** rng.uniform(-6, 6)
            t = _affine(rng, mesh.dim, scale)
            mesh = mesh.transform(t)
            if shape is not None:
                shape = shape.affine(t)
            kind += f" x{scale:.2g}"
    return f"seed {seed}: {op} of {kind} ({mesh.n_points} points, {mesh.n_cells} cells)", mesh, shape, closed, op, rng


# ----------------------------------------------------------------------------- operations
def _extent(mesh) -> float:
    return float(np.ptp(mesh.points, axis=0).max()) if mesh.n_points else 1.0


def _mean_edge(mesh) -> float:
    e = mesh.edges
    return float(np.linalg.norm(mesh.points[e[:, 0]] - mesh.points[e[:, 1]], axis=1).mean()) if len(e) else 1.0


def _top_cells(mesh) -> int:
    from warpmesh.cells.types import CELL_TYPES

    top = max((CELL_TYPES[t][1] for t in mesh.cells), default=0)
    return sum(len(c) for t, c in mesh.cells.items() if CELL_TYPES[t][1] == top), top


def _check_result(out, mesh, closed: bool | None, keeps_surface: bool, where: str) -> None:
    """``closed``: True for a closed surface, False for another valid mesh, None for a
    degenerate input (only the result's own construction is checked)."""
    assert isinstance(out, wm.Mesh), f"{where}: returned {type(out).__name__}"
    if not out.n_cells or closed is None:
        return
    if closed and keeps_surface:
        check_mesh(out)  # closed, manifold, oriented, embedded
    elif mesh.dim == 2 or "tetra" in mesh.cells or "hexahedron" in mesh.cells:
        if keeps_surface:
            check_cells(out)  # positive, conforming, embedded


def run_operation(op: str, mesh, shape, closed: bool, rng, where: str) -> None:
    """Run one operation, assert its result (a refusal is the caller's to judge)."""
    if op == "optimize":
        size = _mean_edge(mesh) * float(rng.uniform(0.7, 2.0)) if rng.random() < 0.5 else None
        out = wm.optimize(mesh, shape, size=size, iterations=int(rng.integers(1, 4)))
        _check_result(out, mesh, closed, True, where)
    elif op == "simplify":
        fraction = float(rng.uniform(0.2, 1.0)) if rng.random() < 0.5 else None
        out = wm.simplify(mesh, shape, fraction=fraction, iterations=int(rng.integers(1, 4)))
        _check_result(out, mesh, closed, True, where)
    elif op == "refine":
        n = int(rng.integers(1, 4))
        out = mesh.refine(n)
        count, top = _top_cells(mesh)
        assert _top_cells(out)[0] == count * n ** top, f"{where}: {_top_cells(out)[0]} cells after refine({n})"
        _check_result(out, mesh, closed, True, where)
    elif op == "refine local":
        out = mesh.refine(max_length=_mean_edge(mesh) * float(rng.uniform(0.4, 1.5)))
        assert _top_cells(out)[0] >= _top_cells(mesh)[0], where
        _check_result(out, mesh, closed, True, where)
    elif op == "transform":
        t = _affine(rng, mesh.dim, 10.0 ** rng.uniform(-3, 3))
        out = mesh.transform(t)
        want = mesh.points @ t[:-1, :-1].T + t[:-1, -1]
        np.testing.assert_allclose(out.points, want, rtol=1e-9, atol=1e-9 * np.abs(want).max(initial=0),
                                   err_msg=where)
        _check_result(out, mesh, closed, True, where)
    elif op == "merge":
        # with a copy shifted by its extent along x: the two touch where the box faces meet
        shift = np.zeros(mesh.dim)
        shift[0] = _extent(mesh)
        other = mesh.transform(wm.transforms.translation(shift))
        out = mesh.merge(other)
        assert out.n_cells <= 2 * mesh.n_cells and out.n_points <= 2 * mesh.n_points, where
    elif op == "periodic":
        shift = np.zeros(mesh.dim)
        shift[0] = _extent(mesh)
        copies = int(rng.integers(1, 6))
        out = mesh.periodic(wm.transforms.translation(shift), copies)
        assert _top_cells(out)[0] <= copies * _top_cells(mesh)[0], where
        if closed is False:
            _check_result(out, mesh, False, True, where)
    elif op == "crack":
        out = mesh.crack(ref=int(rng.integers(0, 3))) if rng.random() < 0.3 else mesh.crack(_facets(mesh, rng))
        assert out.n_cells == mesh.n_cells and out.n_points >= mesh.n_points, where
    elif op == "convert":
        target = ("triangle", "quad", "tetra", "hexahedron")[int(rng.integers(4))]
        out = mesh.convert(target)
        assert out.n_cells >= mesh.n_cells, where
        # splits into simplices keep a planar or volume mesh valid (and a surface, if already triangles)
        simplices = (target == "triangle" and mesh.dim == 2) or (target == "tetra" and closed is False)
        _check_result(out, mesh, closed, simplices or target in mesh.cells, where)
    elif op == "renumber":
        out = mesh.renumber(("gibbs", "rcm", "frontal", "frontal-diameter")[int(rng.integers(4))])
        assert out.n_cells == mesh.n_cells and out.n_points == mesh.n_points, where
        _check_result(out, mesh, closed, True, where)
    elif op == "color":
        out = mesh.color_elements()
        assert out.n_cells == mesh.n_cells, where
    elif op == "to order":
        out = mesh.to_order(int(rng.integers(1, 4)), shape if mesh.dim == 3 else None)
        assert out.n_cells == mesh.n_cells, where
    elif op == "save load":
        suffix = (".vtu", ".msh", ".obj", ".stl", ".ply", ".mesh")[int(rng.integers(6))]
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"m{suffix}"
            mesh.save(path)
            back = wm.load(path, dim=mesh.dim)
        assert back.n_cells == mesh.n_cells or suffix == ".stl", f"{where}: {back.n_cells} cells back from {suffix}"
        if back.n_points and mesh.n_points:  # some writers renumber or weld: every point comes back
            from scipy.spatial import cKDTree

            # float32 formats (STL) keep about 7 digits
            gap = float(cKDTree(back.points).query(mesh.points)[0].max())
            assert gap <= 1e-6 * np.abs(mesh.points).max(), f"{where}: a point moved by {gap:.3g} in {suffix}"
    elif op == "stats":
        s = mesh.stats()
        assert isinstance(s, dict) and s, where
    elif op == "check":
        crossing = mesh.check()
        assert crossing.ndim == 2 and crossing.shape[1] == 2, where
        if closed:
            assert len(crossing) == 0, f"{where}: a surface from the mesher crosses itself"
    elif op == "orient":
        out = wm.orient(mesh)
        assert out.n_cells == mesh.n_cells, where
        if closed:
            check_mesh(out)
    elif op == "surface error":
        err = (wm.surface_error(mesh, shape) if shape is not None
               else wm.surface_error(mesh, reference=(mesh.points, mesh.triangles)))
        assert np.isfinite(err["max"]) and err["max"] >= 0, f"{where}: {err}"
    else:  # pragma: no cover
        raise AssertionError(op)


def _facets(mesh, rng) -> np.ndarray:
    """A few random interior facets (edges in 2D and of surfaces, faces of tetrahedra)."""
    if "tetra" in mesh.cells:
        t = mesh.cells["tetra"]
        f = t[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]].reshape(-1, 3)
    else:
        f = mesh.edges
    if len(f) == 0:
        return np.zeros((0, 2), np.int64)
    return f[rng.choice(len(f), size=min(len(f), int(rng.integers(1, 6))), replace=False)]


# ----------------------------------------------------------------------------- a case
def check_case(seed: int) -> str:
    """Build the case of ``seed``, run its operation under the time limit, judge the
    outcome; returns "result" or the refusal's exception type."""
    where, closed, op = f"seed {seed}", None, None
    try:
        with time_limit(TIME_LIMIT), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            where, mesh, shape, closed, op, rng = make_case(seed)
            run_operation(op, mesh, shape, closed, rng, where)
    except Hang as error:
        raise AssertionError(f"{where}: {error}") from None
    except REFUSALS as error:
        # a refusal names what it refuses (an argument, a cell block or a file, in quotes), or
        # says "expected X, got Y"; an algorithm's failure (WarpMeshError) explains itself
        named = isinstance(error, wm.WarpMeshError) and str(error).strip() or re.search(REFUSAL_TEXT, str(error))
        assert named, f"{where}: {type(error).__name__} naming nothing: {error}"
        assert not (closed and op in SURFACE_OPERATIONS), f"{where}: a good surface refused: {error}"
        return type(error).__name__
    except AssertionError as error:
        if str(error).startswith(where):
            raise
        raise AssertionError(f"{where}: {error}") from None
    except Exception as error:  # noqa: BLE001: the point of the fuzz
        raise AssertionError(f"{where}: {type(error).__module__}.{type(error).__name__}: {error}") from error
    return "result"


FAST = seeded(60)
LONG = seeded(int(os.environ.get("WARPMESH_FUZZ_OPS_EXAMPLES", 200)))


@FAST
@given(st.integers(min_value=0, max_value=2**31 - 1))
def test_fuzz_operations(seed):
    check_case(seed)


@pytest.mark.slow
@LONG
@given(st.integers(min_value=2**31, max_value=2**32 - 1))
def test_fuzz_operations_long(seed):
    check_case(seed)


@pytest.mark.parametrize("kind", DEGENERATE)
def test_every_degenerate_input_is_refused_or_handled(kind):
    """Each degenerate input through the operations that hung or crashed on such input
    (issue 19 item 5): a result or a clear refusal, in time."""
    for op in ("optimize", "simplify", "refine local", "periodic"):
        rng = np.random.default_rng(7)
        with time_limit(TIME_LIMIT), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            mesh, shape = _degenerate(rng, kind)
            where = f"{op} of {kind}"
            try:
                run_operation(op, mesh, shape, None, rng, where)
            except REFUSALS as error:
                assert isinstance(error, wm.WarpMeshError) or re.search(REFUSAL_TEXT, str(error)), f"{where}: {error}"


def main(argv: list[str]) -> int:
    """``python -m tests.test_fuzz_ops FIRST COUNT``: run seeds FIRST..FIRST+COUNT-1, print
    each failure and the totals (a long run for the notes)."""
    first, count = int(argv[0]), int(argv[1])
    failures, outcomes, t0 = 0, {}, time.process_time()
    for seed in range(first, first + count):
        try:
            outcome = check_case(seed)
            outcomes[outcome] = outcomes.get(outcome, 0) + 1
        except AssertionError as error:
            failures += 1
            print(f"FAIL {str(error)[:400]}", flush=True)
    print(f"{count} cases from seed {first}: {failures} failures, {time.process_time() - t0:.0f} CPU s; "
          f"outcomes {outcomes}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
