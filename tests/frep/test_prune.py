"""Per-cell tape pruning (warpmesh.frep.prune) and the COPY opcode in every interpreter.

The pruned tape of a box must give, at every point of the box and of its children, the
value the master tape gives there; its intervals over child boxes must enclose f. The
interval of a decided MIN/MAX holds the float values the points evaluate, so a decision
is exact for float point values too: on min/max CSG of sphere, box, cylinder, torus and
capsule (operations whose float interval bounds are monotone) the pruned values and the
child intervals are bit for bit those of the master tape. With sin, cos, exp, ... in the
tree a bound can be one rounding off, so there the check is 1e-5 of the largest
intermediate value, as in test_tape.py.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import warpmesh as wm
import warpmesh.frep.tape as T
from warpmesh.frep import codegen
from warpmesh.frep import prune
from warpmesh.kernels import opcodes as O
from tests.helpers.random_shapes import ISLACK, RTOL, f32, intermediate_scale, random_shape

wp.config.quiet = True
wp.init()

HALF_WIDTHS = (0.02, 0.1, 0.4, 1.2)


# -- shapes and boxes ------------------------------------------------------------------------------
def random_csg(rng, depth):
    """Min/max CSG of random primitives, with rigid motions."""
    if depth == 0 or rng.random() < 0.15:
        c = tuple(rng.uniform(-1.0, 1.0, 3))
        k = rng.integers(5)
        if k == 0:
            return wm.sphere(rng.uniform(0.2, 0.8), c)
        if k == 1:
            return wm.box(rng.uniform(0.3, 1.4, 3), c)
        if k == 2:
            return wm.cylinder(rng.uniform(0.1, 0.6), rng.uniform(0.4, 1.6), "xyz"[rng.integers(3)], c)
        if k == 3:
            return wm.torus(rng.uniform(0.4, 0.8), rng.uniform(0.1, 0.3), "xyz"[rng.integers(3)], c)
        return wm.capsule(rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3), rng.uniform(0.1, 0.4))
    parts = [random_csg(rng, depth - 1) for _ in range(rng.integers(2, 4))]
    op = (wm.union, wm.intersection, wm.difference)[rng.integers(3)]
    s = op(*parts, method="minmax")
    if rng.random() < 0.3:
        s = s.rotate(rng.uniform(-3, 3), rng.normal(size=3)).translate(rng.uniform(-0.3, 0.3, 3))
    return s


def random_boxes(rng, n_per_size):
    los, his = [], []
    for hw in HALF_WIDTHS:
        c = rng.uniform(-2.0, 2.0, (n_per_size, 3))
        w = hw * rng.uniform(0.3, 1.0, (n_per_size, 3))
        los.append(c - w)
        his.append(c + w)
    return f32(np.concatenate(los)), f32(np.concatenate(his))


def points_in(rng, lo, hi, m):
    """m float32 points in each box (float32 boxes: rounding keeps them inside)."""
    t = rng.uniform(0.0, 1.0, (len(lo), m, 3))
    t[:, 0] = 0.0
    t[:, 1] = 1.0
    return f32(lo[:, None, :] + t * (hi - lo)[:, None, :]).reshape(-1, 3)


def octants(lo, hi):
    """The 8 children of each box, grouped by parent."""
    mid = f32(0.5 * (lo + hi))
    corner = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], bool)
    clo = np.where(corner[None], mid[:, None], lo[:, None]).reshape(-1, 3)
    chi = np.where(corner[None], hi[:, None], mid[:, None]).reshape(-1, 3)
    return clo, chi


# -- a scalar reference of build_pool ----------------------------------------------------------------
def reference_tape(tape, pattern):
    """The pruned tape of one pattern, by a plain scalar dead-code pass."""
    sel = prune.selections(tape)
    eff = []
    for (op, d, a, b), c, s in zip(tape.code.tolist(), tape.imm.tolist(), sel.tolist()):
        ch = int(pattern[s]) if s >= 0 else 0
        if s >= 0 and ch:
            if op in (O.MIN, O.MAX):
                op, a, b = O.COPY, (a if ch == 1 else b), -1
            elif ch == 1:
                op, b = O.COPY, -1
            else:
                op, a, b = O.CONST, -1, -1
            s = -1
        eff.append((op, d, a, b, s if s >= 0 and ch == 0 else -1, np.float32(c)))
    live, kept = {tape.output}, []
    for row in reversed(eff):
        op, d, a, b = row[:4]
        if d in live:
            kept.append(row)
            live.discard(d)
            live |= {r for r in (a, b) if r >= 0}
    return [r for r in reversed(kept) if not (r[0] == O.COPY and r[2] == r[1])]


def pool_tape(pool, j):
    s, n = int(pool.start[j]), int(pool.length[j])
    return [(*map(int, r), np.float32(c)) for r, c in zip(pool.rows[s:s + n].tolist(), pool.imm[s:s + n])]


def assert_no_dead_code(tape, rows):
    """Every value a pruned tape computes is read later, or is the output."""
    pending = {}
    for i, (op, d, a, b, *_) in enumerate(rows):
        for r in (a, b):
            if r >= 0:
                assert r in pending, f"instruction {i} reads r{r} before any write"
                pending[r] = None
        assert pending.get(d, None) is None, f"the value written to r{d} before instruction {i} is dead"
        pending[d] = i
    assert rows[-1][1] == tape.output, "the last instruction does not write the output"
    dead = [r for r, i in pending.items() if i is not None and r != tape.output]
    assert not dead, f"registers {dead} hold values nobody reads"


# -- (a) the property test ---------------------------------------------------------------------------
SHAPES = ([pytest.param("csg", s, id=f"minmax-csg-{s}") for s in range(8)]
          + [pytest.param("any", s, id=f"random-shape-{s}") for s in range(8)])
_RATIOS: dict[str, list] = {"csg": [], "any": []}


@pytest.mark.parametrize("kind, seed", SHAPES)
def test_pruned_tapes_agree_with_the_master_tape(kind, seed):
    rng = np.random.default_rng(100 + seed)
    shape = random_csg(rng, 3) if kind == "csg" else random_shape(rng, 4)
    tape = wm.compile_tape(shape)
    k = prune.n_selections(tape)
    lo, hi = random_boxes(rng, 150)
    n = len(lo)

    # level 0: the root pool is the whole tape, and gives the master's intervals
    root = prune.pool_for_root(tape)
    assert np.array_equal(root.rows[:, :4], tape.code) and np.array_equal(root.imm, tape.imm)
    assert np.array_equal(root.rows[:, 4], prune.selections(tape))
    choices = np.zeros((n, k), np.uint8)
    iv = prune.eval_intervals_pruned(tape, root, np.zeros(n, np.int64), lo, hi, choices)
    assert np.array_equal(iv, wm.evaluate_interval(shape, lo, hi))

    pool, tape_id = prune.pool_from_choices(tape, choices)
    assert np.all(pool.length[tape_id] <= len(tape))
    patterns, _ = prune.unique_patterns(choices)
    assert pool.n_tapes <= len(patterns)  # rows differing in dead selections share a tape
    direct = prune.build_pool(tape, patterns)
    for j in range(min(len(patterns), 12)):  # against a scalar reference, and no dead code
        want = reference_tape(tape, patterns[j])
        assert pool_tape(direct, j) == want, f"tape {j} of pattern {patterns[j].tolist()}"
        assert_no_dead_code(tape, want)
    for i in rng.choice(n, 40, replace=False):  # each box's tape is its own choices' tape
        assert pool_tape(pool, tape_id[i]) == reference_tape(tape, choices[i]), f"box {i}"

    # (1) values at points of each box: the master tape's values
    m = 10
    pts = points_in(rng, lo, hi, m)
    got = prune.eval_values_pruned(tape, pool, np.repeat(tape_id, m), pts)
    want = wm.evaluate(shape, pts, evaluator="interpreter")
    if kind == "csg":
        assert np.array_equal(got, want, equal_nan=True), f"{np.sum(got != want)} of {len(got)} values differ"
    else:
        tol = RTOL * intermediate_scale(shape.field, pts.astype(np.float64))
        ok = (np.abs(got - want) <= tol) | (np.isnan(got) & np.isnan(want))
        assert ok.all(), f"{np.sum(~ok)} values off, e.g. {got[~ok][:3]} vs {want[~ok][:3]}"

    # (2) children evaluated with the parent's tape: their intervals enclose f, and the
    #     parent's decisions are kept
    clo, chi = octants(lo, hi)
    child_choices = np.repeat(choices, 8, axis=0)
    civ = prune.eval_intervals_pruned(tape, pool, np.repeat(tape_id, 8), clo, chi, child_choices)
    inherited = np.repeat(choices, 8, axis=0)
    assert np.all((inherited == 0) | (child_choices == inherited)), "a decided entry changed"
    full = wm.evaluate_interval(shape, clo, chi)
    if kind == "csg":
        assert np.array_equal(civ, full)
    cpts = points_in(rng, clo, chi, 6).reshape(len(clo), 6, 3)
    vals = shape.eval_numpy(cpts[..., 0], cpts[..., 1], cpts[..., 2])
    finite = np.isfinite(vals)
    slack = ISLACK * np.maximum(1.0, np.abs(civ).max(axis=1))
    vlo = np.where(finite, vals, np.inf).min(axis=1)
    vhi = np.where(finite, vals, -np.inf).max(axis=1)
    bad = (vlo < civ[:, 0] - slack) | (vhi > civ[:, 1] + slack)
    assert not bad.any(), f"{bad.sum()} child intervals miss sampled values, e.g. {civ[bad][:2]} vs {vlo[bad][:2]}"
    # the children's own pool again gives the master's values
    pool2, tid2 = prune.pool_from_choices(tape, child_choices)
    cgot = prune.eval_values_pruned(tape, pool2, np.repeat(tid2, 6), cpts.reshape(-1, 3))
    cwant = wm.evaluate(shape, cpts.reshape(-1, 3), evaluator="interpreter")
    if kind == "csg":
        assert np.array_equal(cgot, cwant, equal_nan=True)

    # (3) shorter tapes
    ratio = pool.mean_length(tape_id) / len(tape)
    _RATIOS[kind].append(ratio)
    print(f"\n{kind} {seed}: {len(tape)} instructions, {k} selections, {pool.n_tapes} tapes; "
          f"mean pruned length / full: boxes {ratio:.2f}, children {pool2.mean_length(tid2) / len(tape):.2f}")
    assert pool2.mean_length(tid2) <= pool.mean_length(tape_id) + 1e-9 or k == 0
    if kind == "csg":
        assert k > 0 and ratio < 1.0, f"min/max CSG with {k} selections gave no pruning"


def test_min_max_csg_prunes_to_well_under_the_full_length():
    ratios = []
    for seed in range(6):
        rng = np.random.default_rng(200 + seed)
        shape = random_csg(rng, 3)
        tape = wm.compile_tape(shape)
        lo, hi = random_boxes(rng, 100)
        ch = np.zeros((len(lo), prune.n_selections(tape)), np.uint8)
        prune.eval_intervals_pruned(tape, prune.pool_for_root(tape), np.zeros(len(lo), int), lo, hi, ch)
        pool, tid = prune.pool_from_choices(tape, ch)
        ratios.append(pool.mean_length(tid) / len(tape))
    mean = float(np.mean(ratios))
    print(f"\nmin/max CSG: mean pruned length / full length = {mean:.2f} ({np.round(ratios, 2).tolist()})")
    assert mean < 0.6, f"mean pruned length ratio {mean:.2f} (per shape {np.round(ratios, 2).tolist()})"


def test_decisions_by_hand():
    x, y, z = wm.coords()
    tape = wm.compile_tape(wm.max(wm.min(x, y), 0.25) + z)  # x y MIN MAXC z ADD
    assert tape.code[:, 0].tolist() == [O.X, O.Y, O.MIN, O.MAXC, O.Z, O.ADD]
    lo = np.array([[-1.0, 1.0, 0], [1.0, -1.0, 0], [-1.0, -1.0, 0], [0.5, 1.5, 0], [-2, -2, 0]])
    hi = lo + [0.5, 0.5, 0.0]
    ch = np.zeros((5, 2), np.uint8)
    ch[4] = (2, 0)  # inherited: left as it is where the box decides nothing
    prune.eval_intervals_pruned(tape, prune.pool_for_root(tape), np.zeros(5, int), lo, hi, ch)
    # min: x below y -> 1, y below x -> 2, overlap -> 0; maxc: below 0.25 -> 2, above -> 1
    assert ch.tolist() == [[1, 2], [2, 2], [0, 2], [1, 1], [2, 2]]
    pool, tid = prune.pool_from_choices(tape, ch)
    # max(., 0.25) decided to its immediate needs neither x nor y nor the min
    for i in (0, 1, 2, 4):
        assert [r[0] for r in pool_tape(pool, tid[i])] == [O.CONST, O.Z, O.ADD]
        assert pool.imm[pool.start[tid[i]]] == np.float32(0.25)
    ops = {r[0] for r in pool_tape(pool, tid[3])}  # min -> x, maxc -> its operand
    assert O.X in ops and ops <= {O.X, O.COPY, O.Z, O.ADD}
    p = np.array([[0.7, 1.8, 0.1]], np.float32)
    assert prune.eval_values_pruned(tape, pool, tid[3:4], p)[0] == np.float32(0.7) + np.float32(0.1)


def test_pruning_chains_through_levels_and_dead_selections():
    """A selection that only fed a discarded branch is dead: its entry stays 0 and its
    instructions are gone, whatever the child boxes would say."""
    x, y, z = wm.coords()
    tape = wm.compile_tape(wm.max(x, wm.min(y, z)))
    sel = prune.selections(tape)
    s_min, s_max = sel[tape.code[:, 0] == O.MIN][0], sel[tape.code[:, 0] == O.MAX][0]
    ch = np.zeros((1, 2), np.uint8)
    lo, hi = f32([[2.0, -1.0, -1.0]]), f32([[3.0, 1.0, 1.0]])
    prune.eval_intervals_pruned(tape, prune.pool_for_root(tape), [0], lo, hi, ch)
    assert ch[0, s_min] == 0 and ch[0, s_max] != 0
    pool, _ = prune.pool_from_choices(tape, ch)
    ops = [r[0] for r in pool_tape(pool, 0)]
    assert ops[0] == O.X and set(ops) <= {O.X, O.COPY} and pool.rows[-1, 1] == tape.output
    clo, chi = octants(lo, hi)  # children where min(y, z) alone would be decided
    clo[:, 1:], chi[:, 1:] = 0.5, 1.0
    cch = np.repeat(ch, 8, axis=0)
    civ = prune.eval_intervals_pruned(tape, pool, np.zeros(8, int), clo, chi, cch)
    assert np.all(cch == ch) and np.array_equal(civ, np.stack([clo[:, 0], chi[:, 0]], axis=1))
    # rows that differ only in the dead selection share one tape
    rows = np.repeat(ch, 3, axis=0)
    rows[:, s_min] = (0, 1, 2)
    pool3, tid3 = prune.pool_from_choices(tape, rows)
    assert pool3.n_tapes == 1 and tid3.tolist() == [0, 0, 0] and len(prune.unique_patterns(rows)[0]) == 3


# -- (b) COPY in every interpreter -----------------------------------------------------------------
def copy_tape():
    """f = x * y through copies: r2 = r0, r2 = r2 * r1, r0 = r2 (output r0)."""
    code = np.array([[O.X, 0, -1, -1], [O.Y, 1, -1, -1], [O.COPY, 2, 0, -1], [O.MUL, 2, 2, 1],
                     [O.COPY, 0, 2, -1]], np.int32)
    return T.Tape(code, np.zeros(5, np.float32), 3, 0)


def test_copy_in_the_value_gradient_and_interval_interpreters():
    tape = copy_tape()
    rng = np.random.default_rng(3)
    p = rng.uniform(-2, 2, (1000, 3)).astype(np.float32)
    pts = wp.array(p, dtype=wp.vec3)
    want = p[:, 0] * p[:, 1]  # one float32 rounding, as on the device
    assert np.array_equal(T.eval_values(tape, pts, evaluator="interpreter").numpy(), want)
    g = T.eval_gradients(tape, pts).numpy()
    assert np.array_equal(g, np.stack([want, p[:, 1], p[:, 0], np.zeros_like(want)], axis=1))
    lo, hi = p, p + np.float32(0.5)
    iv = T.eval_intervals(tape, wp.array(lo, dtype=wp.vec3), wp.array(hi, dtype=wp.vec3)).numpy()
    x, y, _ = wm.coords()
    assert np.array_equal(iv, wm.evaluate_interval(x * y, lo, hi))
    # and in the segment kernels
    pool = prune.TapePool(np.concatenate([tape.code, np.full((5, 1), -1, np.int32)], axis=1), tape.imm,
                          np.array([0], np.int64), np.array([5], np.int64))
    assert np.array_equal(prune.eval_values_pruned(tape, pool, np.zeros(len(p), int), p), want)
    assert np.array_equal(prune.eval_intervals_pruned(tape, pool, np.zeros(len(p), int), lo, hi,
                                                      np.zeros((len(p), 0), np.uint8)), iv)


def test_copy_in_generated_kernels(tmp_path, monkeypatch):
    monkeypatch.setenv("WARPMESH_CACHE_DIR", str(tmp_path))
    assert set(codegen._TEMPLATES) == set(O.NAMES), "an opcode without a codegen template"
    tape = copy_tape()
    assert "r2 = r0" in codegen.source(tape)
    p = np.random.default_rng(4).uniform(-2, 2, (500, 3)).astype(np.float32)
    got = T.eval_values(tape, wp.array(p, dtype=wp.vec3), evaluator="compiled").numpy()
    assert np.array_equal(got, p[:, 0] * p[:, 1])


# -- (c) unique_patterns ----------------------------------------------------------------------------
@pytest.mark.parametrize("n_sel", [0, 1, 5, 8, 9, 16, 17, 40])
def test_unique_patterns_round_trip(n_sel):
    rng = np.random.default_rng(n_sel)
    base = rng.integers(0, 3, (37, n_sel)).astype(np.uint8)
    choices = base[rng.integers(0, len(base), 5000)]
    patterns, inverse = prune.unique_patterns(choices)
    assert patterns.dtype == np.uint8 and inverse.dtype == np.int64 and inverse.shape == (5000,)
    assert np.array_equal(patterns[inverse], choices)
    assert len(patterns) == len({r.tobytes() for r in choices}) == len({r.tobytes() for r in patterns})
    # a non-contiguous view gives the same grouping
    wide = np.zeros((5000, n_sel + 3), np.uint8)
    wide[:, 1:n_sel + 1] = choices
    p2, i2 = prune.unique_patterns(wide[:, 1:n_sel + 1])
    assert np.array_equal(p2[i2], choices) and len(p2) == len(patterns)


def test_unique_patterns_edge_cases():
    p, i = prune.unique_patterns(np.zeros((4, 0), np.uint8))
    assert p.shape == (1, 0) and i.tolist() == [0, 0, 0, 0]
    p, i = prune.unique_patterns(np.zeros((0, 3), np.uint8))
    assert p.shape == (0, 3) and i.shape == (0,)


# -- chunks, threads and the item order ------------------------------------------------------------
def test_many_segments_chunks_threads_and_order(monkeypatch):
    monkeypatch.setitem(T.CHUNK_POINTS, True, 4 * T.BATCH)  # 4 segments per launch
    monkeypatch.setattr(prune, "_MIN_ITEMS_PER_WORKER", 256)
    rng = np.random.default_rng(9)
    shape = random_csg(np.random.default_rng(201), 3)
    tape = wm.compile_tape(shape)
    lo, hi = random_boxes(rng, 1500)
    k = prune.n_selections(tape)
    ch = np.zeros((len(lo), k), np.uint8)
    prune.eval_intervals_pruned(tape, prune.pool_for_root(tape), np.zeros(len(lo), int), lo, hi, ch)
    pool, tid = prune.pool_from_choices(tape, ch)
    assert pool.n_tapes > 5
    perm = rng.permutation(len(lo))  # any order in, the caller's order out
    ch_f = np.asfortranarray(ch[perm])  # a non-contiguous choices array is written back too
    iv = prune.eval_intervals_pruned(tape, pool, tid[perm], lo[perm], hi[perm], ch_f)
    assert np.array_equal(iv, wm.evaluate_interval(shape, lo[perm], hi[perm]))
    assert np.array_equal(ch_f, ch[perm])
    pts = points_in(rng, lo, hi, 3)
    ids = np.repeat(tid, 3)
    got = prune.eval_values_pruned(tape, pool, ids, wp.array(pts, dtype=wp.vec3))
    assert np.array_equal(got, wm.evaluate(shape, pts, evaluator="interpreter"))


def test_no_selections_and_no_items():
    tape = wm.compile_tape(wm.sphere(1.0))
    root = prune.pool_for_root(tape)
    assert prune.n_selections(tape) == 0 and root.n_tapes == 1
    lo = np.array([[0.0, 0, 0], [2.0, 0, 0]])
    iv = prune.eval_intervals_pruned(tape, root, [0, 0], lo, lo + 0.1, np.zeros((2, 0), np.uint8))
    assert np.array_equal(iv, wm.evaluate_interval(wm.sphere(1.0), lo, lo + 0.1))
    empty = np.zeros((0, 3))
    assert prune.eval_intervals_pruned(tape, root, [], empty, empty, np.zeros((0, 0), np.uint8)).shape == (0, 2)
    assert prune.eval_values_pruned(tape, root, np.zeros(0, int), empty).shape == (0,)
    assert prune.build_pool(tape, np.zeros((0, 0), np.uint8)).n_tapes == 0


# -- (d) bad input ---------------------------------------------------------------------------------
def test_bad_input_names_the_argument():
    x, y, _ = wm.coords()
    tape = wm.compile_tape(wm.max(wm.min(x, y), 0.0))  # two selections
    root = prune.pool_for_root(tape)
    lo, hi = np.zeros((3, 3)), np.ones((3, 3))
    ch = np.zeros((3, 2), np.uint8)
    ids = np.zeros(3, np.int64)
    run = lambda **kw: prune.eval_intervals_pruned(  # noqa: E731
        tape, kw.get("pool", root), kw.get("tape_id", ids), kw.get("lo", lo), hi, kw.get("choices", ch))
    for bad in (ch.astype(np.int64), ch.astype(bool), np.zeros((3, 3), np.uint8), np.zeros((2, 2), np.uint8),
                np.zeros(3, np.uint8), [[0, 0]] * 3, np.full((3, 2), 3, np.uint8)):
        with pytest.raises(ValueError, match="'choices'"):
            run(choices=bad)
    frozen = ch.copy()
    frozen.flags.writeable = False
    with pytest.raises(ValueError, match="'choices'"):
        run(choices=frozen)
    for bad in (ids.astype(np.float32), ids[:, None], np.zeros(4, np.int64), np.array([0, 1, 0]),
                np.array([0, -1, 0])):
        with pytest.raises(ValueError, match="'tape_id'"):
            run(tape_id=bad)
    with pytest.raises(ValueError, match="'lo'"):
        run(lo=np.zeros((3, 2)))
    with pytest.raises(ValueError, match="'lo'"):
        run(lo=np.full((3, 3), 2.0))  # lo > hi
    with pytest.raises(ValueError, match="'points'"):
        prune.eval_values_pruned(tape, root, ids, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="'tape_id'"):
        prune.eval_values_pruned(tape, root, ids, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="'patterns'"):
        prune.build_pool(tape, np.zeros((2, 3), np.uint8))
    with pytest.raises(ValueError, match="'patterns'"):
        prune.build_pool(tape, np.zeros((2, 2), np.int32))
    with pytest.raises(ValueError, match="'choices'"):
        prune.unique_patterns(np.zeros((2, 2), np.int8))
    with pytest.raises(ValueError, match="'pool'"):  # a pool of another tape
        other = prune.pool_for_root(wm.compile_tape(wm.max(wm.box((1, 1, 1)), 0.2)))
        run(pool=other)
    with pytest.raises(TypeError, match="'tape'"):
        prune.selections(wm.sphere(1.0))
    with pytest.raises(ValueError, match="'rows'"):
        prune.TapePool(np.zeros((2, 4), np.int32), np.zeros(2, np.float32), np.zeros(1, np.int64),
                       np.ones(1, np.int64))
