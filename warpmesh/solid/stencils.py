"""Stencil tables of isosurface stuffing (Labelle & Shewchuk 2007), generated in code.

A background tetrahedron of the body-centred cubic (BCC) lattice has local vertices
``(B0, B1, R0, R1)``: two nodes of the black (cube corner) lattice joined by a long edge and
two nodes of the red (cube centre) lattice joined by the other long edge; the four other
edges are short. After warping, each vertex has a sign: ``-`` (outside, f < 0), ``0`` (on the
surface) or ``+`` (inside). The stencil of a tetrahedron is the part of it on the inside,
cut along the sign-changing edges at their cut points and split into tetrahedra:

- no ``-`` vertex: the whole tetrahedron (with at least one ``+``);
- one ``+`` vertex: one tetrahedron (the ``+`` vertex, the zeros, the cut points);
- two ``+``, one ``0``, one ``-``: a pyramid on a quadrilateral (two tetrahedra);
- two ``+``, two ``-``, or three ``+``, one ``-``: a triangular prism (three tetrahedra).

Every quadrilateral face lies in a lattice face with two ``+`` vertices ``p, q`` and one ``-``
vertex ``n``, and both tetrahedra sharing that face must split it the same way. Each lattice
face has one long edge, and the diagonal is a function of the face alone:

- when ``n p`` is long, the diagonal joins ``q`` to the cut point on ``n p`` (and symmetrically);
- when ``p q`` is long, the *parity rule* picks the end: with doubled integer coordinates
  ``P`` (black nodes even, red nodes odd), long axis ``k``, the parity of
  ``[black edge] + [P_q[k] < P_p[k]] + sum_{j != k} [P_n[j] < P_p[j]]`` is even for exactly one
  of the two ends (swapping ``p`` and ``q`` flips it); the diagonal leaves that end. The
  fill kernel computes this bit per face and indexes the table with it.

The tables are built here from those rules alone: the polytope of each sign pattern, its
quadrilaterals' diagonals, and a generic split of pyramids and prisms (a prism splits into
three tetrahedra when its three diagonals are not cyclic; the tables assert that they never
are). Orientation is fixed on a reference tetrahedron and checked over random cut positions
(``tests/solid/test_stencils.py``).

Layout (all int32, uploaded by :mod:`warpmesh.solid.lattice`)
    ``STENCIL_COUNT[case]`` tetrahedra of a case, ``STENCIL_TETS[case, 3, 4]`` their local
    references, ``case = sign_code * 16 + face_bits`` with ``sign_code = sum (s_i + 1) 3^i``
    (``s_i`` in {-1, 0, 1}) and ``face_bits`` bit ``f`` set when the diagonal of long-edge face
    ``f`` (``LONG_FACES``) leaves the *second* end of its long edge. A reference ``r < 4`` is
    a local vertex, ``4 + e`` the cut point on local edge ``e`` (``EDGES``). A tetrahedron with
    no ``+`` vertex is left out, four zero vertices included: warped onto a flat stretch of the
    surface they can be coplanar (a sliver), and the tetrahedra around it close the mesh.

Example
-------
>>> count, tets = stencil_tables()
>>> int(count[sign_code((1, 1, 1, 1)) * 16]), int(count[sign_code((1, 1, 0, -1)) * 16])
(1, 2)
"""

from __future__ import annotations

import itertools
from functools import lru_cache

import numpy as np

__all__ = ["EDGES", "LONG", "LONG_FACES", "sign_code", "stencil", "stencil_tables",
           "REFERENCE_TET", "face_diagonal", "ranked_diagonal", "ranked_stencil_tables"]

#: local edges of a tetrahedron; the cut point on edge e has local reference 4 + e
EDGES = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
_EDGE_OF = {frozenset(e): i for i, e in enumerate(EDGES)}
#: the long edges (black B0-B1, red R0-R1)
LONG = (frozenset((0, 1)), frozenset((2, 3)))
#: faces holding a long edge, as (long-edge first end, second end, third vertex)
LONG_FACES = ((0, 1, 2), (0, 1, 3), (2, 3, 0), (2, 3, 1))
N_CASES = 81 * 16
#: a positively oriented BCC tetrahedron (B0, B1, R0, R1) in units of the cube side
REFERENCE_TET = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 0.5, -0.5], [0.5, 0.5, 0.5]])


def sign_code(signs) -> int:
    """The base-3 code of four signs in {-1, 0, 1}."""
    return int(sum((int(s) + 1) * 3 ** i for i, s in enumerate(signs)))


def _cut(a: int, b: int) -> int:
    return 4 + _EDGE_OF[frozenset((a, b))]


def face_diagonal(p: int, q: int, n: int, bits: int) -> tuple[int, int]:
    """The diagonal of the quadrilateral (p, q, cut(q, n), cut(p, n)) of lattice face (p, q, n),
    p and q inside, n outside, as (lattice vertex, cut point)."""
    if frozenset((n, p)) in LONG:
        return q, _cut(n, p)
    if frozenset((n, q)) in LONG:
        return p, _cut(n, q)
    for f, (u, v, w) in enumerate(LONG_FACES):  # p q is the long edge: the parity bit decides
        if {u, v} == {p, q} and w == n:
            end = v if (bits >> f) & 1 else u
            other = q if end == p else p
            return end, _cut(other, n)
    raise AssertionError("every lattice face has one long edge")


def ranked_diagonal(p: int, q: int, n: int, bits: int = 0) -> tuple[int, int]:
    """The diagonal of the quadrilateral of face (p, q, n) on a graded background, whose
    tetrahedra list their vertices by increasing global id: it leaves the first of p, q (the
    smaller id), or the second when bit ``o`` of ``bits`` is set, ``o`` the vertex off the
    face. The fill kernel sets the bit when the second is closer to n (ties by id), the
    paper's choice where one of n p, n q is long: a function of the face alone, so both
    tetrahedra sharing it agree; and a total order (distance to n, then id), so the
    diagonals of a prism around one outside vertex are never cyclic.

    Example
    -------
    Face (0, 1, 2), vertex 3 off it: from vertex 0 (the smaller id) to the cut point of
    edge 1-2, or from vertex 1 when bit 3 is set.

    >>> ranked_diagonal(0, 1, 2), ranked_diagonal(1, 0, 2), ranked_diagonal(0, 1, 2, bits=1 << 3)
    ((0, 7), (0, 7), (1, 5))
    """
    first, second = (p, q) if p < q else (q, p)
    off = 6 - p - q - n
    end, other = (second, first) if (bits >> off) & 1 else (first, second)
    return end, _cut(other, n)


def _orient(tet, pos) -> tuple[int, ...]:
    a, b, c, d = (pos[r] for r in tet)
    vol = np.dot(np.cross(b - a, c - a), d - a)
    assert abs(vol) > 1e-12, f"flat stencil tetrahedron {tet}"
    return tuple(tet) if vol > 0 else (tet[0], tet[2], tet[1], tet[3])


def _split_pyramid(apex: int, quad, diagonal) -> list[tuple[int, ...]]:
    """Two tetrahedra of the pyramid on quad (a cycle of 4) split along ``diagonal``."""
    i = quad.index(diagonal[0])
    assert quad[(i + 2) % 4] == diagonal[1], "a diagonal joins opposite corners"
    return [(apex, quad[i], quad[(i + 1) % 4], quad[(i + 2) % 4]),
            (apex, quad[i], quad[(i + 2) % 4], quad[(i + 3) % 4])]


def _split_prism(bottom, top, diagonals) -> list[tuple[int, ...]]:
    """Three tetrahedra of the prism bottom[i] - top[i]; ``diagonals[i]`` (a pair, or None when
    free) splits the side quad (bottom[i], bottom[i+1], top[i+1], top[i])."""
    rising = []  # per side: True when the diagonal is bottom[i] - top[i+1]
    for i, d in enumerate(diagonals):
        if d is None:
            rising.append(None)
            continue
        up = {bottom[i], top[(i + 1) % 3]}
        down = {bottom[(i + 1) % 3], top[i]}
        assert set(d) in (up, down), "a side diagonal joins opposite corners of its quad"
        rising.append(set(d) == up)
    fixed = [r for r in rising if r is not None]
    if None in rising:  # a free side: the choice that is not cyclic (forced when the others agree)
        free = rising.index(None)
        rising[free] = not fixed[0] if len(set(fixed)) == 1 else True
    assert len(set(rising)) == 2, "cyclic prism diagonals cannot be split into three tetrahedra"
    # a vertex touched by two diagonals: it sees the opposite triangle, the rest is a pyramid
    touched = {}
    for i, r in enumerate(rising):
        ends = (bottom[i], top[(i + 1) % 3]) if r else (bottom[(i + 1) % 3], top[i])
        for e in ends:
            touched[e] = touched.get(e, 0) + 1
    v = next(e for e in bottom + top if touched.get(e) == 2)
    opposite = top if v in bottom else bottom
    tets = [(v, *opposite)]
    # the pyramid: apex v, base the side quad not touching v
    for i, r in enumerate(rising):
        quad = [bottom[i], bottom[(i + 1) % 3], top[(i + 1) % 3], top[i]]
        if v not in quad:
            diag = (bottom[i], top[(i + 1) % 3]) if r else (bottom[(i + 1) % 3], top[i])
            tets += _split_pyramid(v, quad, diag)
    assert len(tets) == 3
    return tets


def stencil(signs, bits: int = 0, pos: np.ndarray | None = None, ranked: bool = False) -> list[tuple[int, ...]]:
    """The stencil of one background tetrahedron: a list of positive tetrahedra of local
    references (empty without a ``+`` vertex).

    ``pos`` (10, 3): positions of the 10 references used to orient the output (default: the
    reference tetrahedron with every cut point at its edge's midpoint). ``ranked``: split the
    quadrilaterals by :func:`ranked_diagonal` (graded backgrounds, ``bits`` per face) instead of
    the BCC lattice's long edges and parity bits.
    """

    def diagonal(p, q, n):
        return ranked_diagonal(p, q, n, bits) if ranked else face_diagonal(p, q, n, bits)

    if pos is None:
        pos = np.vstack([REFERENCE_TET, [(REFERENCE_TET[a] + REFERENCE_TET[b]) / 2 for a, b in EDGES]])
    s = [int(v) for v in signs]
    plus = [i for i in range(4) if s[i] > 0]
    zero = [i for i in range(4) if s[i] == 0]
    minus = [i for i in range(4) if s[i] < 0]
    if not plus:
        return []
    if not minus:
        tets = [(0, 1, 2, 3)]
    elif len(plus) == 1:
        p = plus[0]
        tets = [(p, *zero, *[_cut(p, n) for n in minus])]
    elif len(plus) == 2 and len(zero) == 1:
        (p, q), n, z = plus, minus[0], zero[0]
        quad = [p, q, _cut(q, n), _cut(p, n)]
        tets = _split_pyramid(z, quad, diagonal(p, q, n))
    elif len(plus) == 2:
        (p, q), (n, m) = plus, minus
        bottom, top = [p, _cut(p, n), _cut(p, m)], [q, _cut(q, n), _cut(q, m)]
        # sides: (p, c_pn | q, c_qn) lies in face (p, q, n); (c_pn, c_pm | ...) is the cut
        # surface (free); (c_pm, p | c_qm, q) lies in face (p, q, m)
        diags = [diagonal(p, q, n), None, diagonal(p, q, m)]
        tets = _split_prism(bottom, top, diags)
    else:  # three plus, one minus
        n = minus[0]
        bottom, top = list(plus), [_cut(v, n) for v in plus]
        diags = [diagonal(bottom[i], bottom[(i + 1) % 3], n) for i in range(3)]
        tets = _split_prism(bottom, top, diags)
    return [_orient(t, pos) for t in tets]


@lru_cache(maxsize=1)
def stencil_tables() -> tuple[np.ndarray, np.ndarray]:
    """(STENCIL_COUNT (81 * 16,), STENCIL_TETS (81 * 16, 3, 4)) int32 for every sign pattern and
    face-bit combination (see the module docstring)."""
    count = np.zeros(N_CASES, np.int32)
    tets = np.zeros((N_CASES, 3, 4), np.int32)
    for signs in itertools.product((-1, 0, 1), repeat=4):
        code = sign_code(signs)
        for bits in range(16):
            out = stencil(signs, bits)
            case = code * 16 + bits
            count[case] = len(out)
            for k, t in enumerate(out):
                tets[case, k] = t
    count.setflags(write=False)
    tets.setflags(write=False)
    return count, tets


@lru_cache(maxsize=1)
def ranked_stencil_tables() -> tuple[np.ndarray, np.ndarray]:
    """(count (81 * 16,), tets (81 * 16, 3, 4)) int32: the stencils of every sign pattern and
    face bits under :func:`ranked_diagonal` (``case = sign_code * 16 + bits``), oriented on the
    positive ``REFERENCE_TET`` (a background tetrahedron whose id-sorted vertices are
    negatively oriented swaps two references). Bits whose prism diagonals would be cyclic
    cannot come from a total order; their count is -1."""
    count = np.zeros(81 * 16, np.int32)
    tets = np.zeros((81 * 16, 3, 4), np.int32)
    for signs in itertools.product((-1, 0, 1), repeat=4):
        code = sign_code(signs)
        for bits in range(16):
            try:
                out = stencil(signs, bits, ranked=True)
            except AssertionError:  # cyclic diagonals
                count[code * 16 + bits] = -1
                continue
            count[code * 16 + bits] = len(out)
            for k, t in enumerate(out):
                tets[code * 16 + bits, k] = t
    count.setflags(write=False)
    tets.setflags(write=False)
    return count, tets
