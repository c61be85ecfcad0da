"""Marching-squares and marching-triangles tables, generated from base cases [FG §16.3.2].

A cell of the covering-up is a convex polygon with ``n`` corners numbered counter-clockwise
(the square: c0 = (0, 0), c1 = (1, 0), c2 = (1, 1), c3 = (0, 1); the triangle: c0, c1, c2)
and edge ``e_k`` joining corner ``k`` to corner ``k + 1`` (mod n). A configuration is the
bit mask of the inside corners (bit ``c`` set when f > 0 at corner ``c``; f == 0 counts as
outside, as everywhere in warpmesh). Its entry lists directed segments ``(e_from, e_to)``
between the roots on the crossing edges, with the domain f > 0 on their left.

The 2^4 = 16 square patterns are not typed in: they are generated from four base cases
(no crossing; one inside corner; two adjacent inside corners; two diagonal inside
corners) by the symmetry group of the square (rotations, a reflection, which reverses the
segments) and the complement (inside <-> outside, which reverses them too). The two
diagonal patterns 5 and 10 are ambiguous [FG Figure 16.8, Exercise 16.1]: each has two
variants, ``SEPARATED`` (the inside corners cut off one by one) and ``JOINED`` (the inside
corners connected through the cell, the outside corners cut off). The complement swaps
the variants, so the generator checks that every entry it reaches twice agrees.

Which variant is right is decided per cell by :func:`asymptotic_decider`: the bilinear
interpolant of the corner values has one saddle, and its sign there says whether the
inside corners are connected (Nielson-Hamann). The triangles of a Freudenthal
triangulation have 2^3 = 8 patterns, none ambiguous, generated the same way.

Example
-------
>>> int(SEGMENT_COUNT[1]), SEGMENT_TABLE[SEPARATED, 1, 0].tolist()
(1, [0, 3])
>>> SEGMENT_TABLE[SEPARATED, 5, :2].tolist(), SEGMENT_TABLE[JOINED, 5, :2].tolist()
([[0, 3], [2, 1]], [[0, 1], [2, 3]])
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SQUARE_CORNERS", "TRIANGLE_CORNERS", "SEPARATED", "JOINED", "AMBIGUOUS",
    "SEGMENT_TABLE", "SEGMENT_COUNT", "TRIANGLE_SEGMENT_TABLE", "TRIANGLE_SEGMENT_COUNT",
    "generate_table", "rotate_case", "reflect_case", "complement_case",
    "square_configs", "triangle_configs", "saddle_value", "asymptotic_decider",
]

#: corners of the unit square, counter-clockwise; edge k joins corner k to corner k + 1
SQUARE_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
#: corners of the reference triangle (the lower triangle of a Freudenthal square)
TRIANGLE_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])

#: variant index of an ambiguous pattern: inside corners cut off one by one
SEPARATED = 0
#: variant index of an ambiguous pattern: inside corners connected across the cell
JOINED = 1

# -- group actions on a case (config, variant, segments) -----------------------------
# A case is (config, variant, segments) with segments a frozenset of (e_from, e_to).


def rotate_case(case, n: int, k: int = 1):
    """The case turned by ``k`` corner steps counter-clockwise: corner c -> c + k, edge
    e -> e + k (mod n). Orientation and variant are kept."""
    config, variant, segs = case
    new = 0
    for c in range(n):  # loop over the n <= 4 corners of one cell pattern
        if (config >> c) & 1:
            new |= 1 << ((c + k) % n)
    return new, variant, frozenset(((a + k) % n, (b + k) % n) for a, b in segs)


def reflect_case(case, n: int):
    """The mirror image fixing corner 0: corner ``c -> -c``, edge ``e_k = (c_k, c_k+1) ->
    (c_-k, c_-k-1) = e_(-k-1)`` (mod n). A reflection reverses the segments (the domain
    moves to their right otherwise); the variant is kept."""
    config, variant, segs = case
    new = 0
    for c in range(n):
        if (config >> c) & 1:
            new |= 1 << ((-c) % n)
    edge = [(-e - 1) % n for e in range(n)]
    return new, variant, frozenset((edge[b], edge[a]) for a, b in segs)


def complement_case(case, n: int):
    """Inside and outside swapped: the segments are reversed, SEPARATED <-> JOINED."""
    config, variant, segs = case
    return (~config) & ((1 << n) - 1), 1 - variant, frozenset((b, a) for a, b in segs)


def generate_table(n: int, base_cases) -> dict:
    """Close ``base_cases`` under rotations, the reflection and the complement.

    Parameters
    ----------
    n : int
        Corners of the cell (3 or 4).
    base_cases : iterable of (config, variant, segments)
        ``segments`` a sequence of directed (e_from, e_to) pairs.

    Returns
    -------
    dict
        ``{(config, variant): frozenset of segments}`` for every config in [0, 2^n) and
        variant in (SEPARATED, JOINED).

    Raises
    ------
    ValueError
        Two ways to reach an entry disagree, or the base cases do not reach every config.
    """
    table: dict = {}
    todo = [(c, v, frozenset(tuple(s) for s in segs)) for c, v, segs in base_cases]
    while todo:  # breadth-first closure over the (finite) group orbit of the base cases
        case = todo.pop()
        key = case[:2]
        if key in table:
            if table[key] != case[2]:
                raise ValueError(f"inconsistent base cases: config {key[0]} variant {key[1]} reached as "
                                 f"{sorted(table[key])} and {sorted(case[2])}")
            continue
        table[key] = case[2]
        todo += [rotate_case(case, n), reflect_case(case, n), complement_case(case, n)]
    missing = [(c, v) for c in range(1 << n) for v in (SEPARATED, JOINED) if (c, v) not in table]
    if missing:
        raise ValueError(f"base cases do not generate every configuration, missing {missing[:4]}")
    return table


def _pack(table: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(2, 2^n, max_segments, 2) int8 table padded with -1 and the (2^n,) segment counts."""
    most = max(len(s) for s in table.values())
    out = np.full((2, 1 << n, most, 2), -1, np.int8)
    count = np.zeros(1 << n, np.int8)
    for (config, variant), segs in table.items():
        rows = np.array(sorted(segs), np.int8).reshape(-1, 2)
        out[variant, config, : len(rows)] = rows
        count[config] = len(rows)
    return out, count


# Base cases. One inside corner c: the segment runs from the edge leaving c (e_c) to the
# edge entering it (e_(c-1)), so the corner is on its left.
_SQUARE_BASE = [
    (0b0000, SEPARATED, []), (0b0000, JOINED, []),
    (0b0001, SEPARATED, [(0, 3)]), (0b0001, JOINED, [(0, 3)]),
    (0b0011, SEPARATED, [(1, 3)]), (0b0011, JOINED, [(1, 3)]),
    (0b0101, SEPARATED, [(0, 3), (2, 1)]),  # corners 0 and 2 cut off one by one
    (0b0101, JOINED, [(0, 1), (2, 3)]),  # outside corners 1 and 3 cut off
]
_TRIANGLE_BASE = [
    (0b000, SEPARATED, []), (0b000, JOINED, []),
    (0b001, SEPARATED, [(0, 2)]), (0b001, JOINED, [(0, 2)]),
]

#: the two ambiguous square configurations (diagonal corners of the same sign)
AMBIGUOUS = (0b0101, 0b1010)
#: SEGMENT_TABLE[variant, config, slot] = (e_from, e_to) of the square, -1 padded
SEGMENT_TABLE, SEGMENT_COUNT = _pack(generate_table(4, _SQUARE_BASE), 4)
#: TRIANGLE_SEGMENT_TABLE[config] = (e_from, e_to) of the triangle, -1 when not crossed
_tri, TRIANGLE_SEGMENT_COUNT = _pack(generate_table(3, _TRIANGLE_BASE), 3)
if np.any(_tri[SEPARATED] != _tri[JOINED]):  # pragma: no cover - guarded by the generator
    raise ValueError("a triangle configuration is ambiguous")
TRIANGLE_SEGMENT_TABLE = _tri[SEPARATED, :, 0].copy()
del _tri


# -- vectorised configuration and decider ---------------------------------------------

def square_configs(inside: np.ndarray) -> np.ndarray:
    """Configuration of every cell of a grid from its node classification.

    Parameters
    ----------
    inside : (nx + 1, ny + 1) bool
        ``f > 0`` at the grid nodes, indexed [i, j] (x, then y).

    Returns
    -------
    (nx, ny) uint8
        Bit c set when corner c of cell [i, j] is inside (c0 = node (i, j), c1 = (i+1, j),
        c2 = (i+1, j+1), c3 = (i, j+1)).
    """
    b = np.asarray(inside, bool).astype(np.uint8)
    return b[:-1, :-1] | (b[1:, :-1] << 1) | (b[1:, 1:] << 2) | (b[:-1, 1:] << 3)


def triangle_configs(inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Configurations of the two Freudenthal triangles of every grid cell.

    The diagonal runs from node (i, j) to (i+1, j+1). The lower triangle has corners
    (c0, c1, c2) = nodes (i, j), (i+1, j), (i+1, j+1); the upper one (i, j), (i+1, j+1),
    (i, j+1); both counter-clockwise. Returns two (nx, ny) uint8 arrays.
    """
    b = np.asarray(inside, bool).astype(np.uint8)
    c00, c10, c11, c01 = b[:-1, :-1], b[1:, :-1], b[1:, 1:], b[:-1, 1:]
    return c00 | (c10 << 1) | (c11 << 2), c00 | (c11 << 1) | (c01 << 2)


def saddle_value(f0, f1, f2, f3) -> np.ndarray:
    """Value of the bilinear interpolant of corner values at its saddle point.

    With ``f(u, v) = f0 (1-u)(1-v) + f1 u (1-v) + f2 u v + f3 (1-u) v`` the saddle value is
    ``(f0 f2 - f1 f3) / (f0 - f1 + f2 - f3)``; the denominator is non-zero on every
    ambiguous cell (its diagonal corners have opposite signs). Arrays broadcast.
    """
    f0, f1, f2, f3 = (np.asarray(v, np.float64) for v in (f0, f1, f2, f3))
    return (f0 * f2 - f1 * f3) / (f0 - f1 + f2 - f3)


def asymptotic_decider(f0, f1, f2, f3) -> np.ndarray:
    """True (JOINED) where the inside corners of an ambiguous cell are connected.

    They are connected through the cell exactly when the bilinear interpolant is inside
    at its saddle (saddle value > 0; a zero saddle counts as outside, so the variant is
    SEPARATED). Equivalent to ``f_in_a * f_in_b > f_out_a * f_out_b`` on the two
    diagonals.

    Examples
    --------
    >>> asymptotic_decider([1.0, 1.0], [-2.0, -0.5], [1.0, 1.0], [-2.0, -0.5]).tolist()
    [False, True]
    """
    return saddle_value(f0, f1, f2, f3) > 0.0
