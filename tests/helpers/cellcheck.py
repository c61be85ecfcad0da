"""``check_cells(mesh)``: validity of a volume or planar mesh of any P1 cell types.

Checks, raising AssertionError with the first offender:
- every cell of the points' dimension is positively oriented (all corner Jacobians > 0);
- conformity: every facet (edge in 2D, triangle/quad face in 3D) of those cells is shared
  by at most two of them, and the facets used once (the boundary) form a closed curve or
  surface (each of their own facets used an even number of times), so no hanging node or
  half-shared face goes unnoticed;
- no cell repeats a vertex;
- embedded: no two planar triangles overlap (2D), no two triangular boundary faces cross
  (3D) — :func:`warpmesh.cells.intersections.find_self_intersections`; for tetrahedra,
  :func:`warpmesh.cells.intersections.find_tet_overlaps` also finds nothing (which adds the
  winding number: no shell of tetrahedra nested inside another one's tetrahedra).

Returns ``{"measure": total signed area/volume, "n_boundary": boundary facets,
"boundary_measure": their total length/area, "types": [...]}``.
"""

from __future__ import annotations

import numpy as np

from warpmesh.cells.intersections import find_self_intersections, find_tet_overlaps
from warpmesh.cells.reference import cell_measures, corner_jacobians, reference_cell


def _facets(cells: np.ndarray, cell_type: str) -> list[np.ndarray]:
    ref = reference_cell(cell_type)
    if ref.tdim == 2:
        return [cells[:, ref.edges].reshape(-1, 2)]
    out = []
    for size in (3, 4):
        faces = [f for f in ref.faces if len(f) == size]
        if faces:
            out.append(cells[:, np.array(faces)].reshape(-1, size))
    return out


def _keys(rows: np.ndarray, width: int = 4) -> np.ndarray:
    s = np.sort(rows, axis=1)
    return np.pad(s, ((0, 0), (0, width - s.shape[1])), constant_values=-1)


def check_cells(mesh, *, embedded: bool = True) -> dict:
    """See the module docstring; ``embedded=False`` skips the crossing check, for meshes with
    widthless regions (cracks: the two lips coincide by design)."""
    dim = mesh.dim
    blocks = {t: c for t, c in mesh.cells.items() if t != "vertex" and reference_cell(t).tdim == dim}
    assert blocks, f"no cells of dimension {dim} in {list(mesh.cells)}"
    total, facets = 0.0, []
    for t, c in blocks.items():
        srt = np.sort(c, axis=1)
        dup = (srt[:, 1:] == srt[:, :-1]).any(axis=1)
        assert not dup.any(), f"{t} cell {int(np.flatnonzero(dup)[0])} repeats a vertex: {c[dup][0]}"
        jac = corner_jacobians(mesh.points, c, t)
        bad = (jac <= 0).any(axis=1)
        assert not bad.any(), (f"{bad.sum()} {t} cells not positively oriented, first "
                               f"{int(np.flatnonzero(bad)[0])}: corner Jacobians {jac[bad][0]}")
        total += float(cell_measures(mesh.points, c, t).sum())
        facets += _facets(c, t)
    keys = np.concatenate([_keys(f) for f in facets])
    uniq, inv, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    assert counts.max() <= 2, f"a facet in {counts.max()} cells: {uniq[counts.argmax()]}"
    once = counts[inv.ravel()] == 1
    n_boundary = int(once.sum())
    # the boundary's own facets: vertices (2D) or edges (3D), each used an even number of times
    if dim == 2:
        boundary = np.concatenate(facets)[once]
        ends = np.bincount(boundary.ravel(), minlength=mesh.n_points)
        assert (ends % 2 == 0).all(), f"open boundary (hanging node?) at vertex {int(np.flatnonzero(ends % 2)[0])}"
        bmeasure = float(np.linalg.norm(mesh.points[boundary[:, 1]] - mesh.points[boundary[:, 0]], axis=1).sum())
        if embedded and "triangle" in blocks:
            p3 = np.column_stack([mesh.points, np.zeros(mesh.n_points)])
            pairs = find_self_intersections(p3, blocks["triangle"])
            assert len(pairs) == 0, f"{len(pairs)} pairs of overlapping triangles, first {pairs[0].tolist()}"
    else:  # rebuild the boundary faces from the unsorted facet rows (orientation kept)
        b_edges, bmeasure, start = [], 0.0, 0
        for f in facets:
            fb = f[counts[inv.ravel()[start: start + len(f)]] == 1]
            start += len(f)
            b_edges.append(np.sort(np.stack([fb, np.roll(fb, -1, axis=1)], axis=2).reshape(-1, 2), axis=1))
            p = mesh.points[fb]
            if fb.shape[1] == 3:
                bmeasure += float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())
            else:
                bmeasure += float(cell_measures(mesh.points, fb, "quad").sum())
        _, ec = np.unique(np.concatenate(b_edges), axis=0, return_counts=True)
        assert (ec % 2 == 0).all(), (f"open boundary surface (hanging node?): {int((ec % 2).sum())} "
                                     "edges used an odd number of times")
        tri = [f[counts[inv.ravel()[o: o + len(f)]] == 1] for f, o in zip(facets, np.cumsum([0] + [len(f) for f in facets]))]
        tri = [f for f in tri if f.shape[1] == 3 and len(f)]
        if embedded and tri:
            pairs = find_self_intersections(mesh.points, np.concatenate(tri))
            assert len(pairs) == 0, f"{len(pairs)} pairs of crossing boundary faces, first {pairs[0].tolist()}"
        if embedded and list(blocks) == ["tetra"]:
            pairs = find_tet_overlaps(mesh.points, blocks["tetra"])
            assert len(pairs) == 0, f"{len(pairs)} pairs of overlapping tetrahedra, first {pairs[0].tolist()}"
    return {"measure": total, "n_boundary": n_boundary, "boundary_measure": bmeasure,
            "types": list(blocks)}
