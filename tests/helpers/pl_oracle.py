"""Exact topology oracle for the piecewise-linear interpolant on the Kuhn triangulation.

The node grid ``(nx, ny, nz)`` is triangulated by the Kuhn (Freudenthal) split: every
simplex is ``{p + s_0, p + s_1, ..., p + s_k}`` for a node ``p`` and a strictly increasing
chain of axis sets ``{} = s_0 < s_1 < ... < s_k`` (each ``s_j`` a 0/1 offset), which
gives per node 7 edge types (the offsets +x, +y, +z, +x+y, +x+z, +y+z, +x+y+z), 12
triangle types and the 6 tetrahedra of the cube at ``p``. Let ``f`` be the linear
interpolant of node values on this triangulation and ``S`` the set of nodes with f > 0
(a boolean mask ``inside``).

Why the full subcomplex is exact
    The full subcomplex ``K(S)`` (every simplex whose vertices all lie in ``S``) is a
    deformation retract of the region ``{f > 0}``: a point ``x = sum l_i v_i`` of a
    simplex with ``f(x) > 0`` has some weight on ``S``, and ``x`` slides along a segment
    on which ``f`` stays positive (``f`` is linear on it and positive at both ends) to
    ``sum_{v_i in S} l_i v_i / sum_{v_i in S} l_i``. So ``K(S)`` and ``{f > 0}`` have the
    same Euler characteristic and the same connected components, with no resolution
    caveat (unlike a sampled smooth function, the PL region *is* what a marching
    tetrahedra mesher bounds). Nothing here knows about tables or meshers.

From solid to surface
    When no node value is 0, the closure of ``{f > 0}`` is a compact 3-manifold with
    boundary ``M``, and ``chi(boundary M) = 2 chi(M)``. If the inside nodes stay off the
    grid's border the boundary is the zero set, a closed surface with
    ``chi = 2 * kuhn_euler(inside)`` (``kuhn_surface_euler``). The outside ``{f < 0}``
    (nodes ``~inside`` when no value is 0) is handled the same way: with a border of
    outside nodes, the number of cavities is ``kuhn_components(~inside) - 1``.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy import ndimage

__all__ = [
    "KUHN_CHAINS",
    "KUHN_STRUCTURE",
    "kuhn_simplex_counts",
    "kuhn_euler",
    "kuhn_surface_euler",
    "kuhn_label",
    "kuhn_components",
]


def _offset(bits: int) -> tuple[int, int, int]:
    return (bits & 1, (bits >> 1) & 1, (bits >> 2) & 1)


def _chains() -> tuple[tuple[tuple[tuple[int, int, int], ...], ...], ...]:
    """Per dimension k = 0..3, the chains {} < s_1 < ... < s_k as tuples of offsets."""
    out = []
    for k in range(4):
        chains = []
        for sets in itertools.permutations(range(1, 8), k):
            chain = (0, *sets)
            if all(a != b and a & ~b == 0 for a, b in zip(chain, chain[1:])):
                chains.append(tuple(_offset(s) for s in chain))
        out.append(tuple(chains))
    return tuple(out)


#: simplex types anchored at their minimum node: 1 vertex, 7 edges, 12 triangles, 6 tets
KUHN_CHAINS = _chains()

#: 3x3x3 structuring element for ``ndimage.label``: the 14 Kuhn neighbours and the centre
KUHN_STRUCTURE = np.zeros((3, 3, 3), dtype=bool)
for _off in KUHN_CHAINS[1]:
    KUHN_STRUCTURE[tuple(1 + np.array(_off[1]))] = KUHN_STRUCTURE[tuple(1 - np.array(_off[1]))] = True
KUHN_STRUCTURE[1, 1, 1] = True
del _off


def _mask3(inside) -> np.ndarray:
    m = np.asarray(inside)
    if m.ndim != 3 or m.dtype != bool:
        raise ValueError(f"expected a 3D boolean node mask, got dtype {m.dtype} and shape {m.shape}")
    return m


def _count(m: np.ndarray, chain) -> int:
    """Number of anchors p with m[p + s] true for every offset s of the chain."""
    top = np.max(chain, axis=0)  # 1 on the axes the simplex extends along
    n = np.array(m.shape) - top
    if np.any(n <= 0):
        return 0
    acc = np.ones(tuple(n), dtype=bool)
    for s in chain:
        acc &= m[s[0] : s[0] + n[0], s[1] : s[1] + n[1], s[2] : s[2] + n[2]]
    return int(np.count_nonzero(acc))


def kuhn_simplex_counts(inside) -> tuple[int, int, int, int]:
    """Numbers (V, E, F, T) of vertices, edges, triangles, tetrahedra of ``K(S)``.

    ``inside`` is a (nx, ny, nz) bool node mask; a simplex counts when all its vertices
    are inside.
    """
    m = _mask3(inside)
    return tuple(sum(_count(m, chain) for chain in KUHN_CHAINS[k]) for k in range(4))


def kuhn_euler(inside) -> int:
    """Euler characteristic ``V - E + F - T`` of ``K(S)``, i.e. of ``{f > 0}``."""
    v, e, f, t = kuhn_simplex_counts(inside)
    return v - e + f - t


def kuhn_surface_euler(inside) -> int:
    """Euler characteristic of the surface bounding ``{f > 0}``: ``2 * kuhn_euler``."""
    return 2 * kuhn_euler(inside)


def kuhn_label(inside) -> tuple[np.ndarray, int]:
    """Components of the inside nodes joined by Kuhn edges: (labels, count)."""
    labels, count = ndimage.label(_mask3(inside), structure=KUHN_STRUCTURE)
    return labels, int(count)


def kuhn_components(inside) -> int:
    """Number of connected components of ``{f > 0}``."""
    return kuhn_label(inside)[1]
