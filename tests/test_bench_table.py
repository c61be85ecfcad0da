"""The pure logic of ``benchmarks/bench_table22.py``: target evaluation, the table, and
reading the benchmark scripts' JSON documents into rows (documents written here, in the
shape those scripts write). Nothing is timed."""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_table22.py"


@pytest.fixture(scope="module")
def bt():
    import sys

    sys.path.insert(0, str(_PATH.parent))  # the script imports its sibling _report
    try:
        spec = importlib.util.spec_from_file_location("bench_table22", _PATH)
        mod = importlib.util.module_from_spec(spec)
        sys.modules["bench_table22"] = mod  # dataclasses look their module up while it runs
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(_PATH.parent))
        sys.modules.pop("bench_table22", None)
    return mod


def _row(bt, ratio=None, seconds=None, target=None, conditions=()):
    r = bt.Row("g", "task", "w", "p", ratio=ratio, target=target, seconds=seconds, conditions=list(conditions))
    r.met = bt.evaluate(r)
    return r


def test_ratio_targets(bt):
    assert _row(bt, 1.0, target=bt.at_most(1)).met is True  # at most: equality meets it
    assert _row(bt, 1.01, target=bt.at_most(1)).met is False
    assert _row(bt, 0.3, target=bt.at_most(1 / 3)).met is True
    assert _row(bt, 0.34, target=bt.at_most(1 / 3)).met is False
    strict = bt.Target("ratio", "<", 0.1, "< 0.1x")
    assert _row(bt, 0.1, target=strict).met is False
    assert _row(bt, 0.0999, target=strict).met is True


def test_seconds_targets_use_the_warpmesh_seconds_not_the_ratio(bt):
    t = bt.Target("seconds", "<=", 0.3, "<= 0.3 s")
    assert _row(bt, ratio=5.0, seconds=0.25, target=t).met is True
    assert _row(bt, ratio=0.1, seconds=0.31, target=t).met is False


def test_conditions_must_all_hold(bt):
    t = bt.at_most(1)
    r = _row(bt, 0.5, target=t, conditions=[("worst Q 2.4", False), ("closed", True)])
    assert r.met is False
    assert bt.verdict(r) == "NO (worst Q 2.4)"
    assert _row(bt, 0.5, target=t, conditions=[("closed", True)]).met is True
    only = bt.Target("conditions", "<=", 0.0, "notice")
    assert _row(bt, target=only, conditions=[("notice", True), ("adds up", True)]).met is True
    assert _row(bt, target=only, conditions=[("notice", False)]).met is False
    assert _row(bt, target=only).met is None  # nothing to check is not a pass


def test_no_target_or_no_figure(bt):
    assert _row(bt, 3.0).met is None
    assert bt.verdict(_row(bt, 3.0)) == "-"
    r = _row(bt, None, target=bt.at_most(1))
    assert r.met is None and bt.verdict(r) == "?"
    assert _row(bt, math.nan, target=bt.at_most(1)).met is None


def test_bad_targets(bt):
    with pytest.raises(ValueError, match="quantity"):
        bt.Target("speed", "<=", 1.0, "x")
    with pytest.raises(ValueError, match="op"):
        bt.Target("ratio", ">=", 1.0, "x")


def test_format_table(bt):
    rows = [_row(bt, 12.3, target=bt.at_most(1, "<= 1x")), _row(bt, 0.5)]
    rows[1].note = "a note"
    rows[0].before = "2 s"
    text = bt.format_table(rows, with_before=True)
    lines = text.splitlines()
    assert lines[0] == "| task | warpmesh | peer | ratio | target | met? | before |"
    assert lines[2] == "| task | w | p | 12x | <= 1x | NO | 2 s |"
    assert lines[3] == "| task [1] | w | p | 0.5x | - | - | - |"
    assert lines[-1] == "[1] a note"
    assert "before" not in bt.format_table(rows).splitlines()[0]


def test_stats_rows(bt):
    doc = {"rows": [{"resolution": 1024, "triangles": 6_017_848, "mesh_s": 10.0, "stats_s": 0.9, "stats_cpu_s": 1.2,
                     "topology_s": 0.3, "measures_s": 0.1, "quality_s": 0.2, "self_intersections_s": 0.3,
                     "figures_equal_one_figure_functions": True}]}
    (r,) = bt.stats_rows(doc)
    r.met = bt.evaluate(r)
    assert r.ratio == pytest.approx(0.09) and r.met is True
    doc["rows"][0]["stats_s"] = 1.0
    (r,) = bt.stats_rows(doc)
    assert bt.evaluate(r) is False  # 0.10 is not below 10 %


def test_renumber_rows_apply_the_target_from_100k_nodes(bt):
    def mesh(name, n, tg, ts, profile):
        return {"name": name, "np": n, "tools": {
            "gibbs": {"time_s": tg, "cpu_s": tg, "nodes_per_second": n / tg, "profile_vs_scipy": profile},
            "scipy rcm": {"time_s": ts, "cpu_s": ts, "nodes_per_second": n / ts}}}

    rows = bt.renumber_rows({"meshes": [mesh("small", 66_000, 0.1, 0.05, 0.9), mesh("big", 262_000, 0.2, 0.25, 0.95),
                                        mesh("wide", 500_000, 0.2, 0.25, 1.02),
                                        {"name": "x", "np": 200_000, "tools": {"gibbs": {"error": "boom"},
                                                                               "scipy rcm": {}}}]})
    for r in rows:
        r.met = bt.evaluate(r)
    assert rows[0].target is None and rows[0].met is None
    assert rows[1].ratio == pytest.approx(0.8) and rows[1].met is True
    assert rows[2].met is False and bt.verdict(rows[2]).startswith("NO (profile 1.02")
    assert rows[3].warpmesh == "failed: boom"


def test_surface_rows_take_the_default_method_and_the_right_peer(bt):
    def part(case, peer, peer_s):
        return {"case": case, "cells": 256, "rows": [
            {"tool": "warpmesh mc", "total_s": 9.0, "triangles": 1, "closed": True},
            {"tool": "warpmesh mc33", "total_s": 0.1, "triangles": 376_088, "closed": True,
             "stages_s": {"extract": 0.05}},
            {"tool": peer, "total_s": peer_s, "evaluate_s": 0.4, "extract_s": 0.04, "triangles": 373_688}]}

    doc = {"environment": {"warpmesh default method": "mc33"},
           "cases": [part("part-rfunction", "numpy + VTK flying edges", 0.45),
                     part("part-minmax", "Warp sparse_marching_cubes (L=1)", 0.2)]}
    r_rf, r_mm = bt.surface_rows(doc)
    assert r_rf.ratio == pytest.approx(0.1 / 0.45) and bt.evaluate(r_rf) is False  # needs <= 0.2
    assert r_mm.ratio == pytest.approx(0.5) and bt.evaluate(r_mm) is False  # needs <= 1/3
    assert "extract stage 0.05 s" in r_mm.warpmesh and "mc33" in r_mm.warpmesh
    doc["cases"][1]["rows"][2]["total_s"] = 0.31
    assert bt.evaluate(bt.surface_rows(doc)[1]) is True


def test_group_selection(bt, tmp_path):
    args = bt.parse_args(["--only", "stats,volume", "--skip", "volume", "--logs", str(tmp_path)])
    assert args.groups == ["stats"]
    assert bt.parse_args(["--quick", "--logs", str(tmp_path)]).repeat == 1
    with pytest.raises(SystemExit):
        bt.parse_args(["--only", "nope", "--logs", str(tmp_path)])
    with pytest.raises(SystemExit):
        bt.parse_args(["--only", "stats", "--skip", "stats", "--logs", str(tmp_path)])


def test_before_cell(bt):
    r = _row(bt, 2.5, seconds=0.2, target=bt.at_most(1), conditions=[("closed", True)])
    r.warpmesh = "0.2 s (CPU 0.3), mc33"
    assert bt.before_cell(r) == "0.2 s (CPU 0.3) (2.5x of its run's peer; met? NO)"
    assert bt.before_cell(_row(bt, 0.5)) == "w (0.5x of its run's peer)"
    assert bt.before_cell(bt.failed_row("g", "t", "boom")) == "failed: boom"
