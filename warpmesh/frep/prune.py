"""Per-cell tape pruning: shorter tapes for the cells of an adaptive octree.

An interval over a box can decide a min/max branch: for ``min(a, b)``, if
``hi(a) <= lo(b)`` over the box then ``min(a, b) == a`` everywhere in it, so the box's
children may evaluate a shorter tape in which that instruction is a copy of ``a`` and
the instructions that only fed ``b`` are gone (libfive; Keeter, *Massively Parallel
Rendering of Complex Closed-Form Implicit Surfaces*, 2020). R-functions (RUNION,
RINTER) are smooth and depend on both operands everywhere, so they are never pruned:
only ``method="minmax"`` booleans (and the MAX/MAXC inside smooth blends and clamps)
shorten the tape.

The pieces, for one master :class:`~warpmesh.frep.tape.Tape`:

- a **selection** is a MIN, MAX, MINC or MAXC instruction; :func:`selections` numbers
  them ``0 .. n_sel - 1`` in tape order;
- a cell's **choices** are one byte per selection: 0 undecided, 1 the first operand
  decides it, 2 the second operand (or the immediate) decides it. Children inherit
  their parent's row; a decided entry is never un-decided;
- :func:`unique_patterns` reduces the choices of many cells to the distinct rows, and
  :func:`build_pool` turns each into a pruned tape, stored back to back in a
  :class:`TapePool`;
- :func:`eval_intervals_pruned` evaluates every cell with its own tape (cells sharing
  a tape are evaluated together, a batch per interpreter thread) and records the
  selections its box decides; :func:`eval_values_pruned` evaluates points.

A pruned tape keeps the master's registers and output register, so the interpreter
needs no other change. On a box where a pruned tape is used, its value at every point
equals the master tape's value, bit for bit: the intervals enclose the operands'
float32 point values (:mod:`warpmesh.kernels.tape`), and an operand that may be NaN
(the interval (-inf, inf)) never decides a branch, since NaN propagates through min
and max.

Example
-------
>>> import numpy as np, warpmesh as wm
>>> from warpmesh.frep import prune
>>> shape = wm.union(wm.sphere(0.5, (-1, 0, 0)), wm.sphere(0.5, (1, 0, 0)), method="minmax")
>>> tape = wm.compile_tape(shape)
>>> root = prune.pool_for_root(tape)
>>> lo = np.array([[-1.5, -0.5, -0.5], [0.5, -0.5, -0.5]])   # one box around each ball
>>> choices = np.zeros((2, prune.n_selections(tape)), np.uint8)
>>> iv = prune.eval_intervals_pruned(tape, root, np.zeros(2, np.int64), lo, lo + 1.0, choices)
>>> choices.tolist()          # the left box is decided by the left ball, the right by the right
[[1], [2]]
>>> pool, tape_id = prune.pool_from_choices(tape, choices)
>>> len(tape), pool.length.tolist()
(18, [12, 11])
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from warpmesh.kernels import opcodes as O
from warpmesh.kernels import tape as K
from warpmesh._util.parallel import run_parallel
from warpmesh.frep.tape import CHUNK_POINTS, Tape, batch_size

#: the opcodes an interval can decide (their ``sel`` column numbers them)
SELECTION_OPS = (O.MIN, O.MAX, O.MINC, O.MAXC)
UNDECIDED, FIRST, SECOND = 0, 1, 2  # the values of a choices entry

_POOL_COLUMNS = 5  # op, dst, a, b, sel
_PRUNE_CELLS = 1 << 22  # (instructions x patterns) per chunk of build_pool: bounds its memory
_MIN_ITEMS_PER_WORKER = 1 << 13  # below 2x this, one CPU thread evaluates everything


# -- selections and patterns ---------------------------------------------------------------
def selections(tape: Tape) -> np.ndarray:
    """The selection index of each instruction of a master tape.

    Parameters
    ----------
    tape : Tape
        A tape from :func:`warpmesh.compile_tape`.

    Returns
    -------
    (n,) int32 array
        ``0 .. n_sel - 1`` in tape order for the MIN, MAX, MINC and MAXC instructions,
        -1 for every other instruction.

    Example
    -------
    >>> import warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> x, y, z = wm.coords()
    >>> tape = wm.compile_tape(wm.max(wm.min(x, y), 0.5) * z)
    >>> prune.selections(tape).tolist()     # x, y, min, maxc, z, mul
    [-1, -1, 0, 1, -1, -1]
    """
    code = _check_tape(tape).code
    sel = np.full(len(code), -1, np.int32)
    mask = np.isin(code[:, 0], SELECTION_OPS)
    sel[mask] = np.arange(int(mask.sum()), dtype=np.int32)
    return sel


def n_selections(tape: Tape) -> int:
    """The number of MIN, MAX, MINC and MAXC instructions of a master tape: the width
    of a choices row.

    Example
    -------
    >>> import warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> prune.n_selections(wm.compile_tape(wm.box((1, 1, 1))))   # 3 max(q, 0), max of 3, min(., 0)
    6
    """
    code = _check_tape(tape).code
    return int(np.isin(code[:, 0], SELECTION_OPS).sum())


def unique_patterns(choices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct rows of ``choices`` and, for each row, the index of its pattern.

    Rows are compared as bytes (padded to 64-bit words and hashed to one word when
    they are longer than 8 bytes, with an exact check of the hashed groups), so this
    takes a single sort of N integers: about 0.1-0.2 s for 2 million rows.

    Parameters
    ----------
    choices : (N, n_sel) uint8 array
        One row per cell, entries 0 (undecided), 1 or 2.

    Returns
    -------
    patterns : (P, n_sel) uint8 array
        The distinct rows, in no particular order. With ``n_sel == 0`` every row is
        the same (empty) pattern: P = 1 (P = 0 when N = 0).
    inverse : (N,) int64 array
        ``patterns[inverse]`` equals ``choices``.

    Raises
    ------
    ValueError
        If ``choices`` is not a 2-D uint8 array with entries 0, 1, 2.

    Example
    -------
    >>> import numpy as np
    >>> from warpmesh.frep import prune
    >>> ch = np.array([[0, 1], [2, 0], [0, 1], [0, 1]], np.uint8)
    >>> patterns, inverse = prune.unique_patterns(ch)
    >>> len(patterns), bool((patterns[inverse] == ch).all()), bool(inverse[0] == inverse[2] != inverse[1])
    (2, True, True)
    """
    ch = _as_choices(choices, "choices", None, None)
    n, k = ch.shape
    if n == 0:
        return np.zeros((0, k), np.uint8), np.zeros(0, np.int64)
    if k == 0:
        return np.zeros((1, 0), np.uint8), np.zeros(n, np.int64)
    w = (k + 7) // 8
    if k == 8 * w and ch.flags.c_contiguous:
        words = ch.view(np.uint64)
    else:
        padded = np.zeros((n, 8 * w), np.uint8)
        padded[:, :k] = ch
        words = padded.view(np.uint64)
    if w == 1:
        key = words[:, 0]
    else:  # a multiplicative hash of the words, checked exactly below
        key = words[:, 0].copy()
        for j in range(1, w):
            key *= np.uint64(0x9E3779B97F4A7C15)
            key ^= words[:, j] + np.uint64(0x632BE59BD9B4E019) + (key >> np.uint64(29))
    _, first, inverse = np.unique(key, return_index=True, return_inverse=True)
    patterns = ch[first]
    inverse = inverse.reshape(-1).astype(np.int64, copy=False)
    if w > 1 and not np.array_equal(patterns[inverse], ch):  # a hash collision: exact, slower
        rows = np.ascontiguousarray(words).view(np.dtype((np.void, 8 * w))).reshape(-1)
        _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
        patterns = ch[first]
        inverse = inverse.reshape(-1).astype(np.int64, copy=False)
    return np.ascontiguousarray(patterns), inverse


# -- the pool of pruned tapes ----------------------------------------------------------------
@dataclass
class TapePool:
    """Pruned tapes of one master tape, stored back to back.

    Attributes
    ----------
    rows : (m, 5) int32 array
        Instructions ``(op, dst, a, b, sel)``; ``sel`` is the selection index of a
        MIN/MAX/MINC/MAXC still undecided in that tape, else -1.
    imm : (m,) float32 array
        The immediates.
    start : (P,) int64 array
        The first row of each tape.
    length : (P,) int64 array
        The number of rows of each tape.

    Every tape reads the master's registers and leaves its result in the master's
    output register.

    Example
    -------
    >>> import warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> tape = wm.compile_tape(wm.union(wm.sphere(1.0), wm.box((1, 1, 3)), method="minmax"))
    >>> root = prune.pool_for_root(tape)
    >>> root.n_tapes, int(root.length[0]) == len(tape), root.rows.shape[1]
    (1, True, 5)
    """

    rows: np.ndarray
    imm: np.ndarray
    start: np.ndarray
    length: np.ndarray
    _device_cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self):
        for name, value, ndim, dtype in (("rows", self.rows, 2, np.int32), ("imm", self.imm, 1, np.float32),
                                         ("start", self.start, 1, np.int64),
                                         ("length", self.length, 1, np.int64)):
            if not isinstance(value, np.ndarray) or value.ndim != ndim or value.dtype != dtype:
                got = (f"{value.dtype} array of shape {value.shape}" if isinstance(value, np.ndarray)
                       else type(value).__name__)
                raise ValueError(f"expected a {ndim}-D {np.dtype(dtype)} array for '{name}', got {got}")
        if self.rows.shape[1] != _POOL_COLUMNS or len(self.imm) != len(self.rows):
            raise ValueError(f"expected 'rows' of shape (m, 5) and 'imm' of shape (m,), got "
                             f"{self.rows.shape} and {self.imm.shape}")
        if self.start.shape != self.length.shape:
            raise ValueError(f"expected 'start' and 'length' of one shape, got {self.start.shape} "
                             f"and {self.length.shape}")
        if len(self.start) and (self.start.min() < 0 or self.length.min() < 1
                                or (self.start + self.length).max() > len(self.rows)):
            raise ValueError("expected every tape [start, start + length) inside 'rows' and not empty")
        if len(self.rows) >= 2**31:
            raise ValueError(f"expected fewer than 2**31 rows in a pool, got {len(self.rows)}")

    @property
    def n_tapes(self) -> int:
        """P, the number of tapes."""
        return len(self.start)

    def __len__(self) -> int:
        return len(self.start)

    def arrays(self, device="cpu") -> tuple[wp.array, wp.array]:
        """(rows, imm) as Warp arrays on ``device``, uploaded once per device."""
        key = str(wp.get_device(device))
        if key not in self._device_cache:
            rows = self.rows if len(self.rows) else np.zeros((1, _POOL_COLUMNS), np.int32)
            imm = self.imm if len(self.imm) else np.zeros(1, np.float32)
            self._device_cache[key] = (wp.array(rows, dtype=wp.int32, device=device),
                                       wp.array(imm, dtype=wp.float32, device=device))
        return self._device_cache[key]

    def mean_length(self, tape_id=None) -> float:
        """The mean tape length seen by items with these tape ids (over the tapes when
        ``tape_id`` is None)."""
        if tape_id is None:
            return float(self.length.mean()) if len(self.length) else 0.0
        tid = _as_tape_id(tape_id, self, None)
        return float(self.length[tid].mean()) if len(tid) else 0.0

    def describe(self, tape_id: int) -> str:
        """One tape as a listing, one instruction a line (as :meth:`Tape.describe`)."""
        s, n = int(self.start[tape_id]), int(self.length[tape_id])
        fake = Tape(self.rows[s:s + n, :4], self.imm[s:s + n], 1, 0)
        lines = fake.describe().splitlines()
        return "\n".join(f"{ln}  [sel {sel}]" if sel >= 0 else ln
                         for ln, sel in zip(lines, self.rows[s:s + n, 4].tolist()))


def build_pool(tape: Tape, patterns: np.ndarray) -> TapePool:
    """The pruned tape of each choices pattern.

    For each pattern, a decided MIN/MAX becomes a COPY of the deciding operand (and
    disappears when that operand is its own destination register), a decided MINC/MAXC
    a COPY of its operand (choice 1) or a CONST of its immediate (choice 2); undecided
    selections keep their opcode and selection index. Then dead code is removed: a
    backward pass over the master tape, by register (the master reuses registers),
    keeps an instruction iff its destination is live, which kills the destination and
    makes the operands it still reads live. The all-zero pattern gives the whole tape
    back (minus instructions that were already dead).

    Vectorised over patterns: one numpy step per instruction on a (registers x P)
    liveness matrix, in chunks of patterns that bound the memory.

    Parameters
    ----------
    tape : Tape
        The master tape.
    patterns : (P, n_sel) uint8 array
        Choices rows, e.g. from :func:`unique_patterns`.

    Returns
    -------
    TapePool
        Tape ``j`` is the pruned tape of ``patterns[j]``.

    Raises
    ------
    ValueError
        If ``patterns`` is not (P, n_selections(tape)) uint8 with entries 0, 1, 2.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> x, y, z = wm.coords()
    >>> tape = wm.compile_tape(wm.min(x * x, y + 1.0))
    >>> pool = prune.build_pool(tape, np.array([[0], [1], [2]], np.uint8))
    >>> print(pool.describe(0))        # undecided: the whole tape
    r0 = X()
    r0 = SQUARE(r0)
    r1 = Y()
    r1 = ADDC(r1) 1
    r1 = MIN(r0, r1)  [sel 0]
    >>> print(pool.describe(1))        # decided by x * x: y + 1 is dead
    r0 = X()
    r0 = SQUARE(r0)
    r1 = COPY(r0)
    >>> print(pool.describe(2))        # decided by y + 1, computed in the output register
    r1 = Y()
    r1 = ADDC(r1) 1
    """
    return _build_pool(tape, patterns)[0]


def _build_pool(tape: Tape, patterns: np.ndarray) -> tuple[TapePool, np.ndarray]:
    """build_pool, and a (P, n_sel) bool array: which selections each tape still uses
    (its instruction survived, decided or not)."""
    tape = _check_tape(tape)
    sel = selections(tape)
    k = int((sel >= 0).sum())
    pat = _as_choices(patterns, "patterns", None, k)
    n, n_pat = len(tape.code), len(pat)
    chunk = max(1, _PRUNE_CELLS // max(n, 1))
    parts = [_prune_chunk(tape, sel, pat[c0:c0 + chunk]) for c0 in range(0, n_pat, chunk)]
    if not parts:
        return (TapePool(np.zeros((0, _POOL_COLUMNS), np.int32), np.zeros(0, np.float32),
                         np.zeros(0, np.int64), np.zeros(0, np.int64)), np.zeros((0, k), bool))
    rows = np.concatenate([p[0] for p in parts])
    imm = np.concatenate([p[1] for p in parts])
    length = np.concatenate([p[2] for p in parts])
    start = np.cumsum(length) - length
    return TapePool(rows, imm, start, length), np.concatenate([p[3] for p in parts])


def _prune_chunk(tape: Tape, sel: np.ndarray, pat: np.ndarray):
    """build_pool for a chunk of patterns: (rows, imm, length) of their tapes."""
    code = tape.code
    n, n_pat = len(code), len(pat)
    pat_t = np.ascontiguousarray(pat.T)  # (n_sel, P): one selection's choices contiguous
    live = np.zeros((tape.n_registers, n_pat), bool)
    live[tape.output] = True
    keep = np.empty((n, n_pat), bool)
    for i, (op, d, a, b) in zip(range(n - 1, -1, -1), code[::-1].tolist()):
        kept = keep[i]
        kept[:] = live[d]
        live[d] = False  # killed before the operands are made live: dst may be an operand
        s = sel[i]
        if s < 0:
            if a >= 0:
                live[a] |= kept
            if b >= 0:
                live[b] |= kept
            continue
        ch = pat_t[s]
        live[a] |= kept & (ch != SECOND)
        if op == O.MIN or op == O.MAX:
            live[b] |= kept & (ch != FIRST)
    p_idx, i_idx = np.nonzero(keep.T)  # pattern-major, instructions in order
    rows = np.empty((len(i_idx), _POOL_COLUMNS), np.int32)
    rows[:, :4] = code[i_idx]
    s = sel[i_idx]
    has = s >= 0
    ch = np.zeros(len(i_idx), np.uint8)
    ch[has] = pat[p_idx[has], s[has]]
    rows[:, 4] = np.where(has & (ch == UNDECIDED), s, -1)
    op, a, b = rows[:, 0], rows[:, 2], rows[:, 3]  # views: edited in place below
    two = (op == O.MIN) | (op == O.MAX)
    second = two & (ch == SECOND)
    a[second] = b[second]
    decided_copy = (two & (ch != UNDECIDED)) | (has & ~two & (ch == FIRST))
    op[decided_copy] = O.COPY
    b[decided_copy] = -1
    to_const = has & ~two & (ch == SECOND)
    op[to_const] = O.CONST
    a[to_const] = -1
    keep_row = ~((op == O.COPY) & (a == rows[:, 1]))  # a copy of a register onto itself
    rows = rows[keep_row]
    imm = tape.imm[i_idx[keep_row]]
    length = np.bincount(p_idx[keep_row], minlength=n_pat).astype(np.int64)
    return rows, imm, length, keep[sel >= 0].T


def pool_for_root(tape: Tape) -> TapePool:
    """A pool of one tape, the whole master tape (the all-undecided pattern): what a
    level-0 cell evaluates, through the same path as the pruned levels.

    Example
    -------
    >>> import warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> tape = wm.compile_tape(wm.box((1, 2, 3)))
    >>> pool = prune.pool_for_root(tape)
    >>> pool.start.tolist(), pool.length.tolist() == [len(tape)]
    ([0], True)
    """
    return build_pool(tape, np.zeros((1, n_selections(tape)), np.uint8))


def pool_from_choices(tape: Tape, choices: np.ndarray) -> tuple[TapePool, np.ndarray]:
    """The pool of pruned tapes for cells with these choices, and each cell's tape id.

    Rows that differ only in selections their tapes no longer use (a selection that
    fed a discarded branch) share one tape: such an entry can never matter again,
    since a child's tape is a part of its parent's. So there are fewer tapes than
    :func:`unique_patterns` finds, and fuller batches when they are evaluated.

    Parameters
    ----------
    tape : Tape
    choices : (N, n_selections(tape)) uint8 array

    Returns
    -------
    pool : TapePool
    tape_id : (N,) int64 array

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> x, y, _ = wm.coords()
    >>> tape = wm.compile_tape(wm.max(x, y))
    >>> pool, tape_id = prune.pool_from_choices(tape, np.array([[1], [1], [0]], np.uint8))
    >>> pool.n_tapes, bool(tape_id[0] == tape_id[1] != tape_id[2])
    (2, True)
    """
    patterns, inverse = unique_patterns(choices)
    pool, used = _build_pool(tape, patterns)
    if used.all():
        return pool, inverse
    canonical, merged = unique_patterns(np.where(used, patterns, UNDECIDED).astype(np.uint8))
    if len(canonical) == len(patterns):
        return pool, inverse
    return build_pool(tape, canonical), merged[inverse]


# -- evaluation -------------------------------------------------------------------------------
def eval_intervals_pruned(tape: Tape, pool: TapePool, tape_id, lo, hi, choices: np.ndarray,
                          device="cpu") -> np.ndarray:
    """Intervals of f over boxes, each box with its own pruned tape; records the
    selections each box decides.

    Items may come in any order: they are grouped by tape (a stable sort) and cut into
    segments of at most ``warpmesh.frep.tape.batch_size(device)`` items, one interpreter
    thread per segment, split across the CPU cores.

    Parameters
    ----------
    tape : Tape
        The master tape the pool was built from.
    pool : TapePool
    tape_id : (N,) integer array
        The tape of each box, ``0 <= tape_id < pool.n_tapes``.
    lo, hi : (N, 3) float arrays (or Warp vec3 arrays on ``device``)
        The boxes (their number sets N).
    choices : (N, n_selections(tape)) uint8 numpy array, updated in place
        Each box's row (its parent's, to start with). An entry of a selection that is
        still undecided in the box's tape becomes 1 or 2 when the box's interval decides
        it, and is left as it is otherwise.
    device : str
        Warp device.

    Returns
    -------
    (N, 2) float32 array
        (lo, hi) of f over each box, in the caller's order.

    Raises
    ------
    ValueError
        On arrays of the wrong shape or dtype (the message names the argument), tape
        ids outside the pool, or a pool that does not fit the tape.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> x, y, _ = wm.coords()
    >>> tape = wm.compile_tape(wm.min(x, 0.0))
    >>> ch = np.zeros((2, 1), np.uint8)
    >>> lo = np.array([[-2.0, 0, 0], [1.0, 0, 0]])
    >>> prune.eval_intervals_pruned(tape, prune.pool_for_root(tape), [0, 0], lo, lo + 0.5, ch).tolist()
    [[-2.0, -1.5], [0.0, 0.0]]
    >>> ch.ravel().tolist()
    [1, 2]
    """
    blo = _as_vec3(lo, "lo", None, device)
    n = blo.shape[0]
    bhi = _as_vec3(hi, "hi", n, device)
    tape, pool, tid = _check_common(tape, pool, tape_id, n)
    if not isinstance(lo, wp.array) and not isinstance(hi, wp.array) and np.any(np.asarray(lo) > np.asarray(hi)):
        raise ValueError("expected lo <= hi for every box of 'lo' and 'hi'")
    k = n_selections(tape)
    ch = _as_choices(choices, "choices", n, k, writable=True)
    if n == 0:
        return np.zeros((0, 2), np.float32)
    out = wp.empty(n, dtype=wp.vec2, device=device)
    aliased = k > 0 and wp.get_device(device).is_cpu and ch.flags.c_contiguous
    if k == 0:
        dch = wp.zeros((1, 1), dtype=wp.uint8, device=device)  # never written: no selection
    elif aliased:  # the kernel writes straight into the caller's array
        dch = wp.array(ch, dtype=wp.uint8, device=device, copy=False)
    else:
        dch = wp.array(np.ascontiguousarray(ch), dtype=wp.uint8, device=device)
    _launch_segments(K.interval_segments_kernel, tape, pool, tid, [blo, bhi], out, [dch],
                     wp.vec2, device)
    if k > 0 and not aliased:
        ch[...] = dch.numpy()  # sync point
    return out.numpy()  # sync point


def eval_values_pruned(tape: Tape, pool: TapePool, tape_id, points, device="cpu") -> np.ndarray:
    """f at points, each point with its own pruned tape (segmented as
    :func:`eval_intervals_pruned`).

    Parameters
    ----------
    tape : Tape
    pool : TapePool
    tape_id : (N,) integer array
    points : (N, 3) float array (or a Warp vec3 array on ``device``)
    device : str

    Returns
    -------
    (N,) float32 array, in the caller's order.

    Raises
    ------
    ValueError
        As :func:`eval_intervals_pruned`.

    Example
    -------
    >>> import numpy as np, warpmesh as wm
    >>> from warpmesh.frep import prune
    >>> x, y, _ = wm.coords()
    >>> tape = wm.compile_tape(wm.max(x, y))
    >>> pool = prune.build_pool(tape, np.array([[1], [2]], np.uint8))   # x, then y
    >>> pts = np.array([[1.0, 5.0, 0.0]] * 2)
    >>> prune.eval_values_pruned(tape, pool, [0, 1], pts).tolist()
    [1.0, 5.0]
    """
    pts = _as_vec3(points, "points", None, device)
    n = pts.shape[0]
    tape, pool, tid = _check_common(tape, pool, tape_id, n)
    if n == 0:
        return np.zeros(0, np.float32)
    out = wp.empty(n, dtype=wp.float32, device=device)
    _launch_segments(K.eval_segments_kernel, tape, pool, tid, [pts], out, [], wp.float32, device)
    return out.numpy()  # sync point


def _segments(tid: np.ndarray, pool: TapePool, batch: int):
    """Group items by tape (stable) and cut the groups into segments of <= batch items:
    (items, seg_item, seg_count, seg_row, seg_rows) as int32 numpy arrays."""
    n = len(tid)
    if n > 1 and np.any(tid[1:] < tid[:-1]):
        order = np.argsort(tid, kind="stable")
    else:
        order = np.arange(n)
    st = tid[order]
    cut = np.flatnonzero(st[1:] != st[:-1]) + 1
    g_start = np.concatenate([[0], cut])
    g_end = np.concatenate([cut, [n]])
    n_seg = (g_end - g_start + batch - 1) // batch
    g_of_seg = np.repeat(np.arange(len(g_start)), n_seg)
    first = np.cumsum(n_seg) - n_seg
    seg_item = g_start[g_of_seg] + (np.arange(int(n_seg.sum())) - first[g_of_seg]) * batch
    seg_count = np.minimum(batch, g_end[g_of_seg] - seg_item)
    t = st[g_start][g_of_seg]
    i32 = lambda a: np.ascontiguousarray(a, dtype=np.int32)  # noqa: E731
    return i32(order), i32(seg_item), i32(seg_count), i32(pool.start[t]), i32(pool.length[t])


def _launch_segments(kernel, tape: Tape, pool: TapePool, tid: np.ndarray, inputs: list,
                     out: wp.array, outputs: list, dtype, device) -> None:
    """Launch a segment kernel over every item: two CPU workers (split where half of the
    work, items x rows, is done), launches of bounded scratch."""
    batch = batch_size(device)
    items, seg_item, seg_count, seg_row, seg_rows = _segments(tid, pool, batch)
    n_seg = len(seg_item)
    rows, imm = pool.arrays(device)
    dev = [wp.array(a, dtype=wp.int32, device=device) for a in (seg_item, seg_count, seg_row, seg_rows, items)]
    cpu = wp.get_device(device).is_cpu
    wp.load_module(K, device=device)  # compile/load once here, not in two worker threads at once
    ranges = [(0, n_seg)]
    if cpu and len(tid) >= 2 * _MIN_ITEMS_PER_WORKER and n_seg > 1:
        work = np.cumsum(seg_count.astype(np.int64) * seg_rows)
        mid = int(np.searchsorted(work, work[-1] / 2)) + 1
        ranges = [(0, mid), (mid, n_seg)] if mid < n_seg else ranges
    span = max(1, CHUNK_POINTS[cpu] // batch)  # segments per launch: bounds the scratch

    def job(lo, hi):
        width = min(span, hi - lo)
        scratch = wp.empty(width * tape.n_registers * batch, dtype=dtype, device=device)
        for start in range(lo, hi, width):
            stop = min(start + width, hi)
            wp.launch(kernel, dim=stop - start,
                      inputs=[rows, imm, tape.n_registers, tape.output, *dev, *inputs, start, stop, batch],
                      outputs=[scratch, out, *outputs], device=device)

    run_parallel([lambda lo=lo, hi=hi: job(lo, hi) for lo, hi in ranges])


# -- validation --------------------------------------------------------------------------------
def _check_tape(tape) -> Tape:
    if not isinstance(tape, Tape):
        raise TypeError(f"expected a Tape (warpmesh.compile_tape(shape)) for 'tape', got {type(tape).__name__}")
    return tape


def _check_common(tape, pool, tape_id, n: int):
    tape = _check_tape(tape)
    if not isinstance(pool, TapePool):
        raise TypeError(f"expected a TapePool (build_pool / pool_for_root) for 'pool', got {type(pool).__name__}")
    key = ("fits", id(tape))
    if pool._device_cache.get(key) is not tape:  # checked once per (pool, tape)
        rows = pool.rows
        if len(rows) and (rows[:, 1:4].max() >= tape.n_registers or rows[:, 1].min() < 0
                          or rows[:, 4].max() >= n_selections(tape)):
            raise ValueError("expected a 'pool' built from 'tape': its registers or selections "
                             "do not fit the tape")
        pool._device_cache[key] = tape
    return tape, pool, _as_tape_id(tape_id, pool, n)


def _as_tape_id(tape_id, pool: TapePool, n: int | None) -> np.ndarray:
    t = np.asarray(tape_id)
    if t.ndim != 1 or not (np.issubdtype(t.dtype, np.integer) or (t.size == 0 and t.dtype == np.float64)):
        raise ValueError(f"expected a 1-D integer array for 'tape_id', got {t.dtype} array of shape {t.shape}")
    if n is not None and len(t) != n:
        raise ValueError(f"expected {n} entries in 'tape_id' (one per item), got {len(t)}")
    if len(t) and (t.min() < 0 or t.max() >= pool.n_tapes):
        raise ValueError(f"expected 'tape_id' in [0, {pool.n_tapes}) (the pool's tapes), got values in "
                         f"[{t.min()}, {t.max()}]")
    return t.astype(np.int64, copy=False)


def _as_choices(choices, name: str, n: int | None, k: int | None, writable: bool = False) -> np.ndarray:
    if not isinstance(choices, np.ndarray):
        raise ValueError(f"expected a numpy uint8 array for '{name}', got {type(choices).__name__}")
    if choices.dtype != np.uint8:
        raise ValueError(f"expected uint8 entries in '{name}', got {choices.dtype}; "
                         f"convert with {name}.astype(np.uint8)")
    want = f"({'N' if n is None else n}, {'n_sel' if k is None else k})"
    if choices.ndim != 2 or (n is not None and choices.shape[0] != n) or (k is not None and choices.shape[1] != k):
        raise ValueError(f"expected '{name}' of shape {want} (items x selections of the tape), "
                         f"got {choices.shape}")
    if writable and not choices.flags.writeable:
        raise ValueError(f"expected a writable array for '{name}' (it is updated in place)")
    if choices.size and choices.max() > SECOND:
        raise ValueError(f"expected entries 0, 1 or 2 in '{name}', got {int(choices.max())}")
    return choices


def _as_vec3(value, name: str, n: int | None, device) -> wp.array:
    """(n, 3) floats (n = any when None) as a Warp vec3 array on ``device``."""
    if isinstance(value, wp.array):
        if value.dtype != wp.vec3 or value.ndim != 1 or (n is not None and value.shape[0] != n):
            raise ValueError(f"expected a Warp vec3 array of {'N' if n is None else n} entries for "
                             f"'{name}', got {value.dtype.__name__} array of shape {value.shape}")
        if str(value.device) != str(wp.get_device(device)):
            raise ValueError(f"expected '{name}' on device {device!r}, got {value.device}")
        return value
    a = np.asarray(value)
    if a.ndim != 2 or a.shape[1] != 3 or (n is not None and len(a) != n) or not np.issubdtype(a.dtype, np.number):
        raise ValueError(f"expected an ({'N' if n is None else n}, 3) float array for '{name}', got "
                         f"{a.dtype} array of shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"expected finite values in '{name}', got NaN or infinity")
    return wp.array(np.ascontiguousarray(a, dtype=np.float32), dtype=wp.vec3, device=device)
