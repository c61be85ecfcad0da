"""Cells with a repeated vertex ("collapsed" cells) and the operations that refuse them.

:class:`warpmesh.Mesh` accepts a collapsed cell (a quad with two equal corners, a
hexahedron standing for a wedge): files carry them, and statistics, numbering, colouring,
transformations, merges, periodic copies and file writers pass them through unchanged.
The operations that split or rebuild cells — uniform and local refinement, conversion
between cell types, cracks, higher-order nodes (``to_order``), and
:func:`warpmesh.optimize` / :func:`warpmesh.simplify` (which refuse any zero-area
triangle) — cannot give such a cell a shape: they call
:func:`reject_collapsed` first, so the answer is a ValueError naming the first one
instead of more collapsed cells (or a hang).

Example
-------
>>> from warpmesh.mesh import Mesh
>>> from warpmesh.cells.collapsed import collapsed_cells, reject_collapsed
>>> m = Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], {"triangle": [[0, 1, 2], [1, 3, 1]]})
>>> collapsed_cells(m)["triangle"].tolist()
[1]
>>> reject_collapsed(m, "refine")
Traceback (most recent call last):
...
ValueError: refine expected cells without a repeated vertex in 'mesh', got 1 collapsed cell(s), the first cells['triangle'][1] = [1, 3, 1]; drop them or give them their own type first
"""

from __future__ import annotations

import numpy as np

__all__ = ["collapsed_cells", "reject_collapsed"]


def collapsed_cells(mesh) -> dict[str, np.ndarray]:
    """Indices of the cells with a repeated vertex, per cell type (blocks with none left out).

    Parameters
    ----------
    mesh : Mesh

    Returns
    -------
    dict {str: (k,) int64}
    """
    out = {}
    for name, cells in mesh.cells.items():
        if cells.shape[1] < 2 or len(cells) == 0:
            continue
        srt = np.sort(cells, axis=1)
        bad = np.flatnonzero((srt[:, 1:] == srt[:, :-1]).any(axis=1))
        if len(bad):
            out[name] = bad
    return out


def reject_collapsed(mesh, operation: str) -> None:
    """Raise a ValueError naming the first collapsed cell of ``mesh``, if any.

    Parameters
    ----------
    mesh : Mesh
    operation : str
        The operation's name, for the message.

    Raises
    ------
    ValueError
        A cell repeats a vertex.
    """
    bad = collapsed_cells(mesh)
    if bad:
        name, rows = next(iter(bad.items()))
        total = sum(len(r) for r in bad.values())
        i = int(rows[0])
        raise ValueError(f"{operation} expected cells without a repeated vertex in 'mesh', got {total} collapsed "
                         f"cell(s), the first cells[{name!r}][{i}] = {mesh.cells[name][i].tolist()}; drop them or "
                         "give them their own type first")
