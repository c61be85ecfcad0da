"""What the command line prints about a mesh: one line per figure, each once, with units.

A person gets ``label  value`` lines (counts per cell block, topology, measures, quality
[FG eq. 16.15], the mesher's own facts), the optimisation's before/after table, and the
time of each stage in seconds with an ``other`` line, so that the stages add up to the
total: run as the program, from the process's start (``import``: Python, warpmesh, Warp
and the command's modules; called as ``main([...])``, from the call), with the time Warp spent compiling warpmesh's kernels (a new machine, a first
run) as its own ``compile`` stage, taken out of the stage it happened in. ``--json`` prints the whole statistics as one JSON object and nothing else.

Figures that :meth:`warpmesh.mesh.Mesh.stats` gives under two names (``q_mean`` and
``mean_q``, ``n_triangles`` and ``ne``, ...) or that describe the mesh before a later stage
changed it (the mesher's ``vertices`` and ``triangles`` after ``--optimize``) are printed
once, or not at all.

Examples
--------
>>> import warpmesh as wm
>>> from warpmesh.cli.report import Clock, human_lines
>>> clock = Clock()
>>> mesh = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], {"triangle": [[0, 1, 2]]})
>>> stats = mesh.stats()
>>> [line.split()[0] for line in human_lines(mesh, stats, clock.times())][:3]
['points', 'triangles', 'watertight']
"""

from __future__ import annotations

import json
import os
import sys
import time
from contextlib import contextmanager

import numpy as np

__all__ = ["Clock", "human_lines", "mesh_figures", "print_report", "process_start", "progress_bars"]

def progress_bars() -> bool:
    """Whether the long stages draw progress bars: only on a terminal (stderr redirected to a
    file or a pipe would collect every frame of the bar, and the warnings after it)."""
    return sys.stderr.isatty()


_WIDTH = 32  # "boundary Euler characteristic" and its value
#: stats keys said twice (another key holds the same figure) or stale after a later stage
_HIDDEN = {"ne", "n_cells", "n_triangles", "n_tetra", "q_mean", "q_worst", "vertices", "triangles", "edges",
           "signed_volume", "enclosed_volume", "written", "time", "optimize", "label_boundaries", "orient"}
#: the whole-surface figures a shared multi-material surface does not have (its interfaces
#: meet at junction edges): said with a pointer to the per-label line
_WHOLE = {"watertight", "manifold", "oriented"}
#: the leading figures, in this order: key -> label
_LEADING = {"watertight": "watertight", "manifold": "manifold", "oriented": "oriented",
            "orientation": "orientation", "euler": "Euler characteristic", "components": "components",
            "genus": "genus", "area": "area", "volume": "volume", "self_intersections": "self-intersections",
            "mean_q": "Q_K mean", "worst_q": "Q_K worst", "bounds": "bounds"}
#: the leading figures of a volume mesh that describe its boundary
_BOUNDARY = {"watertight", "manifold", "oriented", "euler", "components", "genus", "area"}
_PLURAL = {"line": "segments", "triangle": "triangles", "quad": "quads", "tetra": "tetrahedra",
           "hexahedron": "hexahedra", "wedge": "wedges", "pyramid": "pyramids"}
#: optimisation facts printed under the table: key -> label
_OPTIMIZE = {"iterations": "iterations", "kept": "kept", "tolerance": "tolerance (absolute)", "creases": "crease points",
             "feature_edges": "feature edges", "corners": "corners", "splits": "splits", "collapses": "collapses",
             "flips": "flips", "moves": "moves", "rejected": "rejected moves"}


def process_start() -> float | None:
    """The ``time.perf_counter()`` reading at this process's start (Linux ``/proc``, 10 ms
    resolution), or None where the system does not say.

    Examples
    --------
    >>> start = process_start()
    >>> start is None or 0.0 <= time.perf_counter() - start < 3600.0
    True
    """
    try:
        with open("/proc/self/stat") as f:
            fields = f.read().rpartition(")")[2].split()  # after the command name, which may hold spaces
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        age = uptime - int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22: start time, in ticks since boot
    except (OSError, ValueError, IndexError, AttributeError):
        return None
    return time.perf_counter() - max(age, 0.0)


def _compile_seconds() -> float:
    """Seconds spent compiling warpmesh's kernels so far (0.0 before Warp was started)."""
    startup = sys.modules.get("warpmesh.kernels.startup")  # not imported here: that would start Warp
    return startup.compile_seconds() if startup is not None else 0.0


class Clock:
    """Wall time of the command's stages, from ``start`` (default: its creation) to :meth:`times`.

    With a ``start`` before the clock's creation (:func:`process_start`), the time until
    then is the stage ``import``. Time spent compiling warpmesh's Warp kernels inside a
    stage is moved to the stage ``compile``.

    Examples
    --------
    >>> clock = Clock()
    >>> with clock.stage("mesh"):
    ...     pass
    >>> t = clock.times()
    >>> list(t), abs(sum(v for k, v in t.items() if k != "total") - t["total"]) < 1e-12
    (['mesh', 'other', 'total'], True)
    >>> list(Clock(start=time.perf_counter() - 0.5).times())
    ['import', 'other', 'total']
    """

    def __init__(self, start: float | None = None) -> None:
        now = time.perf_counter()
        self.start = now if start is None else min(start, now)
        self.stages: dict[str, float] = {} if start is None else {"import": now - self.start}
        self.parts: dict[str, dict[str, float]] = {}

    @contextmanager
    def stage(self, name: str):
        t0, c0 = time.perf_counter(), _compile_seconds()
        try:
            yield
        finally:
            compiled = _compile_seconds() - c0
            self.stages[name] = self.stages.get(name, 0.0) + time.perf_counter() - t0 - compiled
            if compiled > 0.0:
                self.stages["compile"] = self.stages.get("compile", 0.0) + compiled

    def split(self, name: str, parts) -> None:
        """Show stage ``name`` as ``parts`` (a ``{stage: seconds}`` reported by the mesher).

        Used only when the parts are sequential (their sum is within the stage's time);
        otherwise the stage stays one line. A part named like a stage of the command is
        shown as ``"<name> <part>"``.
        """
        if not isinstance(parts, dict):
            return
        flat = {k: float(v) for k, v in parts.items() if k != "total" and isinstance(v, (int, float))}
        if flat and sum(flat.values()) <= self.stages.get(name, 0.0):
            self.parts[name] = {(f"{name} {k}" if k in self.stages else k): v for k, v in flat.items()}

    def times(self) -> dict[str, float]:
        """``{stage: seconds}``, the mesher's parts in place of their stage, then ``other`` and ``total``."""
        total = time.perf_counter() - self.start
        out: dict[str, float] = {}
        for name, seconds in self.stages.items():
            out.update(self.parts.get(name, {name: seconds}))
        out["other"] = total - sum(out.values())
        out["total"] = total
        return out


def _number(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return f"{int(v):,}"
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.5g}"
    return str(v)


def _value(key: str, v) -> str | None:
    """One line's value, or None for a figure the mesh does not have."""
    seconds = key.startswith("time") or key.endswith("seconds") or key.endswith("_time")
    unit = " s" if seconds else " MB" if key.endswith("_mb") else ""
    if v is None:
        return None
    if isinstance(v, dict):
        if not v:
            return None
        return ", ".join(f"{k}: {_number(x)}{unit}" for k, x in v.items())
    if isinstance(v, np.ndarray) and v.ndim == 2:
        if key == "bounds":
            return f"({', '.join(_number(float(a)) for a in v[0])}) to ({', '.join(_number(float(b)) for b in v[1])})"
        rows = [f"({', '.join(_number(float(a)) for a in r)})" for r in v[:4]]
        return f"{len(v)}" + (": " + " ".join(rows) if len(v) else "") + (" ..." if len(v) > 4 else "")
    if isinstance(v, (tuple, list, np.ndarray)):
        items = list(v)
        if not items:
            return "none"
        if all(isinstance(x, (tuple, list, np.ndarray)) for x in items):  # points
            return " ".join(f"({', '.join(_number(a) for a in x)})" for x in items)
        sep = " x " if key in ("grid", "lattice") else ", "
        return sep.join(_number(x) for x in items)
    return _number(v) + unit


def _table(rows: list[dict]) -> list[str]:
    cols = list(rows[0])
    out = ["  " + " ".join(f"{c:>15}" for c in cols)]
    for row in rows:
        out.append("  " + " ".join(f"{row.get(c, ''):>15.4g}" if isinstance(row.get(c), float)
                                   else f"{str(row.get(c, '')):>15}" for c in cols))
    return out


def _line(label: str, value: str) -> str:
    return f"{label:<{_WIDTH}}{value}"


def _separate_labels(mesh) -> bool:
    """A surface of several labels, each its own closed surface (not ``interfaces="shared"``)."""
    return len(mesh.info.get("labels") or ()) > 1 and "label_above" not in mesh.cell_data


def _label_boundaries(figures: dict, rest=None) -> str:
    """One line on the labels' boundaries of a shared surface: how many are closed and
    oriented outward, and which are not and what is wrong. ``rest``: the label holding the
    outside of the box (default: the one enclosing the least volume).

    Examples
    --------
    >>> ok = {"closed": True, "oriented": True, "volume": 2.0}
    >>> _label_boundaries({0: {**ok, "volume": -3.0}, 1: ok, 2: ok})
    '3 of 3 closed and oriented outward (the rest, 0, inward: it holds the outside)'
    >>> _label_boundaries({0: {**ok, "volume": -2.0}, 1: ok, 4: {**ok, "closed": False, "oriented": False}}, rest=0)
    '2 of 3 closed and oriented outward (the rest, 0, inward: it holds the outside); not 4 (open, not oriented)'
    >>> _label_boundaries({0: {**ok, "volume": -2.0}, 1: {**ok, "volume": -1.0}}, rest=0)
    '1 of 2 closed and oriented outward (the rest, 0, inward: it holds the outside); not 1 (inward)'
    """
    if rest not in figures:
        rest = min(figures, key=lambda k: figures[k]["volume"]) if figures else None
    bad = {}
    for label, f in figures.items():
        wrong = [word for key, word in (("closed", "open"), ("oriented", "not oriented")) if not f[key]]
        if not wrong and (f["volume"] <= 0.0) != (label == rest):
            wrong.append("inward")
        if wrong:
            bad[label] = ", ".join(wrong)
    text = f"{len(figures) - len(bad)} of {len(figures)} closed and oriented outward"
    if rest is not None and rest not in bad:
        text += f" (the rest, {rest}, inward: it holds the outside)"
    if bad:
        text += "; not " + ", ".join(f"{label} ({why})" for label, why in sorted(bad.items()))
    return text


def human_lines(mesh, stats: dict, times: dict | None = None) -> list[str]:
    """The lines a person reads: figures, the optimisation table, the written file, the stage times."""
    from warpmesh.cells.quality import format_table

    lines = []
    opt = stats.get("optimize") if isinstance(stats.get("optimize"), dict) else None
    shown_in_table = {"np", "mean_q", "worst_q"} if opt else set()  # the table's "after" row
    if "np" not in shown_in_table:
        lines.append(_line("points", _number(stats["np"])))
    for cell_type, block in mesh.cells.items():
        if not (opt and len(block) == opt["after"].get("ne")):
            lines.append(_line(_PLURAL.get(cell_type, f"{cell_type} cells"), _number(len(block))))
    # a volume mesh's topology and area are those of its boundary (``Mesh.stats``), not of
    # its triangle block, which may hold interfaces between regions as well
    of_boundary = mesh.dim == 3 and len(mesh.cells.get("tetra", ())) > 0 and not any(
        t in mesh.cells for t in ("hexahedron", "wedge", "pyramid"))
    noted = False  # the shared surface's note, said once
    for key, label in _LEADING.items():
        if key in shown_in_table or key not in stats:
            continue
        value = _value(key, stats[key])
        if value is not None:
            if key == "self_intersections" and stats[key] and _separate_labels(mesh):
                value += " (each label's own closed surface: where two labels touch, both are there; " \
                         "--interfaces shared meshes each interface once)"
            if key in _WHOLE and stats[key] is False and isinstance(stats.get("label_boundaries"), dict) \
                    and not noted:
                value += " (as one surface: its interfaces meet at junction edges; see label boundaries)"
                noted = True
            lines.append(_line(f"boundary {label}" if of_boundary and key in _BOUNDARY else label, value))
        if key == "bounds" and isinstance(stats.get("label_boundaries"), dict):
            lines.append(_line("label boundaries", _label_boundaries(stats["label_boundaries"], stats.get("rest"))))
    tables = []
    for key, v in stats.items():
        if key in _HIDDEN or key in _LEADING or key == "np":
            continue
        if isinstance(v, list) and v and all(isinstance(r, dict) for r in v):
            tables.append((key, v))
            continue
        value = _value(key, v)
        if value is not None:
            lines.append(_line(key.replace("_", " "), value))
    for key, rows in tables:
        lines.append(f"{key}:")
        lines += _table(rows)
    if opt:
        lines.append("optimisation (before / after):")
        if "np" in opt["before"]:
            lines += format_table({"before": opt["before"], "after": opt["after"]}).splitlines()
        else:  # a multi-material surface's remeshing reports its own figures
            lines += [_line(f"  {k.replace('_', ' ')}", f"{_number(v)} / {_number(opt['after'].get(k))}")
                      for k, v in opt["before"].items() if not isinstance(v, (dict, list))]
        for key, label in _OPTIMIZE.items():
            if key in opt and opt[key] is not None:
                lines.append(_line(label, _number(opt[key])))
    if stats.get("written"):
        path = stats["written"]
        try:
            import os

            size = f" ({os.path.getsize(path) / 1e6:.3g} MB)"
        except OSError:
            size = ""
        lines.append(_line("written", f"{path}{size}"))
    if times:
        lines.append("time:")
        lines += [_line(f"  {k}", f"{v:.3f} s") for k, v in times.items()]
    return lines


def _jsonable(o):
    if isinstance(o, np.generic):
        return o.item()
    if hasattr(o, "tolist"):
        return o.tolist()
    return str(o)


def print_report(mesh, stats: dict, clock: Clock | None, as_json: bool) -> None:
    """Print ``stats`` of ``mesh`` for a person, or as JSON (``as_json``: stdout gets that object only).

    With a ``clock``, ``stats["time"]`` becomes the command's stage times (the mesher's own
    parts, ``other`` and ``total``, in seconds).
    """
    stats = dict(stats)
    times = clock.times() if clock is not None else None
    if times is not None:
        stats["time"] = times
    if as_json:
        print(json.dumps(stats, indent=2, default=_jsonable, sort_keys=False))
        return
    print("\n".join(human_lines(mesh, stats, times)))


def mesh_figures(mesh, keys) -> dict:
    """The figures ``keys`` as the mesh already carries them: its counts (``np``, ``ne``,
    ``n_cells``, ``n_triangles``, ``n_tetra``) and its ``info`` (what the producer reported:
    a renumbering's bandwidth and profile, a colouring's packets, ...), without
    :meth:`warpmesh.mesh.Mesh.stats`, which also runs the topology, quality and
    self-intersection checks; ``stats()`` only for a key the mesh does not carry.

    Examples
    --------
    >>> import warpmesh as wm
    >>> m = wm.Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]}, info={"bandwidth": 2})
    >>> mesh_figures(m, ["np", "ne", "bandwidth"])
    {'np': 3, 'ne': 1, 'bandwidth': 2}
    """
    from warpmesh.cells.types import CELL_TYPES

    dims = {t: CELL_TYPES[t][1] for t in mesh.cells}
    top = max(dims.values(), default=-1)
    counts = {"np": mesh.n_points, "ne": sum(len(c) for t, c in mesh.cells.items() if dims[t] == top),
              "n_cells": mesh.n_cells, "n_triangles": len(mesh.cells.get("triangle", ())),
              "n_tetra": len(mesh.cells.get("tetra", ()))}
    carried = {**mesh.info, **counts}  # stats() lets the computed counts win too
    if any(k not in carried for k in keys):
        carried = {**mesh.stats(), **carried}
    return {k: carried[k] for k in keys}
