"""Adaptive surface meshes of shapes: the pipeline behind ``mesh_surface(adaptive=True)``.

octree covering-up (:mod:`warpmesh.surface.adaptive.octree`: interval or Lipschitz culling, pruned tapes,
curvature criteria) -> face units, crossings and loops (:mod:`warpmesh.surface.adaptive.contour`)
-> roots on the exact function -> loop vertices (QEF, projection) -> fans -> feature
flips -> closed, oriented triangle mesh with statistics.

Example
-------
>>> import warpmesh as wm
>>> m = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), adaptive=True, max_level=5)
>>> s = m.stats()
>>> s["watertight"], s["euler"]
(True, 2)
"""

from __future__ import annotations

import threading
import time

import numpy as np
import warp as wp

from warpmesh._conventions import CAP_REF, SURFACE_REF
from warpmesh.errors import WarpMeshError
from warpmesh.surface.adaptive import contour as OC
from warpmesh.surface.block_grid import refine_roots
from warpmesh.surface.adaptive.octree import build_octree, cell_keys

NEWTON_STEPS = 4  # safeguarded Newton from the linear estimate (quadratic convergence)


def mesh_adaptive(tape, lo, hi, *, max_level, min_level, tolerance, angles, chord, bound, lipschitz, cap, prune,
                  features, root, root_iterations, gradient, device, timings, info, force=None, build=None):
    """(points, faces, triangle refs or None) of the adaptive surface; fills timings and info.

    Without ``cap`` the surface is the capped one less its cap triangles: an open surface
    that ends on the bounds (the octree's loops close only on a closed boundary).

    A leaf above ``max_level`` whose boundary (its neighbours' finer nodes included) holds
    two loops or more has two sheets, which its corners did not show: the octree is built
    again with those leaves refined (``force``), until none is left (``info["octree_rounds"]``;
    ``timings["octree"]`` sums the rounds).

    ``build``, when given, makes each round's tree in place of :func:`build_octree`, with
    its arguments, and returns the tree it would (the bricked build of
    :class:`warpmesh.distributed.adaptive.BrickedOctree`). A build with a ``join_crossings``
    method also takes ``roots`` (the root options) and contours the leaves where it built
    them: ``join_crossings(tree, timings)`` returns (minus, plus, segments, units, points,
    normals, cap_vertex) as the face units, crossings, roots and normals of one process
    would give them, array for array."""
    open_bounds, cap = not cap, True
    timings["octree"], rounds = 0.0, 0
    joined_roots = dict(root=root, root_iterations=root_iterations, gradient=gradient)
    # a build that contours its own leaves too (on the workers) takes the root options and joins them
    joined = dict(roots=joined_roots) if hasattr(build, "join_crossings") else None
    # The rounds end (no cap needed): a cell of ``force`` that a round reaches above max_level is
    # refined (or culled), never a leaf, so each round's two-sheet leaves are keys not yet in
    # ``force``, which grows strictly within the finite set of cells above max_level. That needs
    # the union: with ``force`` replaced by the new leaves, the rod beside a slab of
    # tests/surface/test_adaptive.py alternates between two trees forever. A rod across k coarse
    # leaves takes about k / 2 + 1 rounds (each round shows it to the next leaves from both ends).
    while True:
        rounds += 1
        t0 = time.perf_counter()
        tree = (build or build_octree)(tape, lo, hi, max_level=max_level, min_level=min_level, tolerance=tolerance,
                                       angles=angles, chord=chord, bound=bound, lipschitz=lipschitz, cap=cap,
                                       prune=prune, force=force, device=device, **(joined or {}))
        timings["octree"] += time.perf_counter() - t0

        t0 = time.perf_counter()
        if joined is not None:  # the workers' face units, crossings, roots and normals, joined
            minus, plus, segments, n_units, points, normals, cap_vertex = build.join_crossings(tree, timings)
            n_vertices = len(points)
        else:
            axis, origin, size, minus, plus, owner, side = OC.face_units(tree)
            node_of, ptr, node_keys = OC.boundary_cycles(tree, axis, owner, side)
            values, capped, vnodes, segments = OC.unit_segments(tree, axis, origin, size, node_of, ptr, node_keys)
            n_units, n_vertices = len(axis), len(vnodes)
        timings["faces"] = time.perf_counter() - t0
        info.update(leaves=len(tree.leaf_level), face_units=n_units, crossings=n_vertices)
        if not len(segments):
            info["octree_rounds"] = rounds
            _finish_info(tree, info, 0, 0, 0)
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64), None

        t0 = time.perf_counter()
        # the loops need only the segments: chain them on a second thread while the roots are found
        loops: list = []

        def chain_loops():
            try:
                loops.append(OC.leaf_loops(segments, minus, plus, n_vertices))
            except BaseException as exc:  # re-raised on the calling thread below
                loops.append(exc)

        chain = threading.Thread(target=chain_loops)
        chain.start()
        if joined is None:
            points, fg, cap_vertex = crossing_roots(tape, tree, vnodes, node_keys, values, capped, device=device,
                                                    timings=timings, **joined_roots)
        timings["root"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        chain.join()
        if isinstance(loops[0], WarpMeshError) and bound == "lipschitz":
            # leaves culled by a bound below the field's slope miss crossings their neighbours see
            raise ValueError(f"the octree's leaves do not close the surface with lipschitz={lipschitz!r}: a bound "
                             "below the field's largest slope culls cells the surface crosses; give a larger "
                             "'lipschitz' (warpmesh.frep.lipschitz.lipschitz_bound(shape, bounds) is one) or "
                             "bound='interval'") from loops[0]
        if isinstance(loops[0], BaseException):
            raise loops[0]
        half, loop_of, n_loops, loop_size, nxt = loops[0]
        two_sheets = _leaves_with_two_sheets(tree, half, loop_of, n_loops)
        if not len(two_sheets):
            break
        force = two_sheets if force is None else np.union1d(force, two_sheets)
    info["octree_rounds"] = rounds
    if joined is None:
        normals, cap_vertex = OC.vertex_normals(tree, points, vnodes, node_keys, capped, fg)
    centres, rank = OC.loop_vertices(tree, half, loop_of, n_loops, points, normals, features)
    unit_of_half = np.concatenate([segments[:, 0], segments[:, 0]])
    tris, tri_half = OC.fan_triangles(half, loop_of, loop_size, nxt, len(points), unit_of_half, rank >= 2,
                                      points, normals)
    fanned = np.zeros(n_loops, bool)
    fanned[loop_of[tri_half[tri_half >= 0]]] = True
    centres, rank = OC.settle_vertices(tree, half, loop_of, n_loops, centres, rank, points, normals, cap_vertex,
                                       fanned)
    # a QEF minimiser or a Newton step near the bounds may leave them (by up to 1.7 finest cells on a
    # slanted plane): back onto the box, before untangle checks the fans [issue 19 item 3]
    centres = np.clip(centres, tree.origin, tree.world(tree.lattice_max()))
    feature = (rank >= 2) & features
    all_points = np.concatenate([points, centres])
    fan_tris, flipped = tris, np.zeros((0, 2), np.int64)
    if features:
        tris, flipped = OC.flip_feature_edges(tree, tris, tri_half, half, loop_of, loop_size, feature, all_points)
    t1 = time.perf_counter()
    centres, rank, tris, moved, pairs = OC.untangle(half, loop_of, n_loops, centres, rank, points, tris, flipped,
                                                    fan_tris)
    timings["untangle"] = time.perf_counter() - t1
    flips = int(np.any(tris != fan_tris, axis=1).sum()) // 2
    feature = (rank >= 2) & features
    all_points = np.concatenate([points, centres])
    info.update(untangled=moved, crossing_pairs=int(len(pairs)))
    OC.check_closed(tris)
    refs = None
    if cap_vertex.any():  # a cap triangle has its three vertices on one face of the bounds
        refs = np.where(_on_one_face(tree, all_points, tris), CAP_REF, SURFACE_REF)
        if open_bounds:
            tris, refs = tris[refs == SURFACE_REF], None
    used = np.zeros(len(all_points), bool)
    used[tris.ravel()] = True
    renumber = np.cumsum(used) - 1
    all_points, tris = all_points[used], renumber[tris]
    timings["fans"] = time.perf_counter() - t0 - timings["untangle"]
    info.update(loops=int(n_loops), feature_vertices=int(feature.sum()), feature_flips=int(flips))
    _finish_info(tree, info, len(all_points), len(tris), n_loops)
    return all_points, tris, refs


def _leaves_with_two_sheets(tree, half, loop_of, n_loops) -> np.ndarray:
    """Sorted cell keys of the leaves above the finest level that hold two loops or more."""
    leaf_of_loop = np.full(n_loops, -1, np.int64)
    leaf_of_loop[loop_of] = half[:, 0]
    leaf_of_loop = leaf_of_loop[leaf_of_loop >= 0]
    many = np.flatnonzero(np.bincount(leaf_of_loop, minlength=len(tree.leaf_level)) > 1)
    many = many[tree.leaf_level[many] < tree.max_level]
    return np.unique(cell_keys(tree.leaf_level[many], tree.leaf_ijk[many]))


def _on_one_face(tree, points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Whether each triangle's three vertices lie on one face of the bounds (within a
    thousandth of the coarsest cell: cap vertices sit EDGE_T_MIN along their edge)."""
    lo, hi = tree.origin, tree.world(tree.lattice_max())
    tol = 1e-3 * float(np.max(tree.h)) * (1 << (tree.max_level - tree.base_level)) * 1.01
    faces = ((np.abs(points - lo) <= tol) << np.arange(3)).sum(axis=1) | \
        ((np.abs(points - hi) <= tol) << np.arange(3, 6)).sum(axis=1)  # a bit per face of the bounds
    return (faces[tris[:, 0]] & faces[tris[:, 1]] & faces[tris[:, 2]]) != 0


def crossing_roots(tape, tree, vnodes, node_keys, values, capped, *, root, root_iterations, gradient, device,
                   timings):
    """(points (nv, 3) float64, (f, grad f) (nv, 4) float32 or None, cap_vertex (nv,)) of the
    crossings ``vnodes`` (indices into ``node_keys``, node values ``values``, ``capped`` nodes,
    :func:`warpmesh.surface.adaptive.contour.unit_segments`): linear interpolation (eq. 16.12),
    then bisection or safeguarded Newton on the exact f (cap vertices stay). Each vertex is a
    function of its edge alone, so the workers' crossings of a bricked run are the same points.
    The tree's field counts the evaluations.

    Example: see :func:`mesh_adaptive` (the module's example runs it)."""
    p0, p1, t = OC.edge_points(tree, vnodes, node_keys, values)
    cap_vertex = capped[vnodes].any(axis=1)
    points = p0 + t[:, None] * (p1 - p0)
    fg = None  # (f, grad f) at the vertices, when the root finding leaves them behind
    if root != "linear":
        steps = root_iterations or (12 if root == "bisection" else NEWTON_STEPS)
        points, fg = _refine(tape, tree, p0, p1, t, values[vnodes[:, 0]] > 0, cap_vertex, root, steps,
                             gradient, device, timings)
        tree.field.counts["evaluations"] += len(points) * steps
    return points, fg, cap_vertex


def _refine(tape, tree, p0, p1, t, p0_inside, keep, root, iterations, gradient, device, timings):
    """Roots on the crossing edges by bisection or safeguarded Newton (cap vertices stay)."""
    org = tree.origin
    to_wp = lambda a: wp.array(np.ascontiguousarray(a, dtype=np.float32), dtype=wp.vec3, device=device)  # noqa: E731
    edges = {"t": wp.array(t.astype(np.float32), dtype=wp.float32, device=device),
             "flags": wp.array((p0_inside.astype(np.int32) | (keep.astype(np.int32) << 1)), dtype=wp.int32,
                               device=device),
             "p0": to_wp(p0 - org), "p1": to_wp(p1 - org)}
    verts = wp.empty(len(t), dtype=wp.vec3, device=device)
    fg = wp.empty(len(t), dtype=wp.vec4, device=device) if root == "newton" and gradient == "exact" else None
    refine_roots(tape, verts, edges, wp.vec3(*org.tolist()), root, iterations, timings, "interpreter",
                 gradient, tree.h, fg_out=fg)
    return verts.numpy().astype(np.float64) + org, None if fg is None else fg.numpy()


def _finish_info(tree, info, n_points, n_tris, n_loops):
    counts = tree.field.counts
    n_finest = int(np.prod(tree.n_finest + 1))
    info.update(counts)
    info["evaluation_seconds"] = {k: round(v, 4) for k, v in tree.field.seconds.items()}
    info["dense_evaluations"] = n_finest
    info["evaluation_ratio"] = round(n_finest / max(counts["evaluations"], 1), 1)
    info["levels"] = tree.levels
    culled = sum(lv["culled_inside"] + lv["culled_outside"] << 3 * (tree.max_level - lv["level"])
                 for lv in tree.levels)
    info["culled_fraction"] = round(culled / float(np.prod(tree.n_finest)), 4)
    info["finest_cell"] = tuple(float(v) for v in tree.h)
    info["max_level"] = tree.max_level
    info["leaf_levels"] = {int(lv): int(n) for lv, n in zip(*np.unique(tree.leaf_level, return_counts=True))}
