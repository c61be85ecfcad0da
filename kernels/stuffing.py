"""Isosurface stuffing on the body-centred cubic lattice (Labelle & Shewchuk 2007).

The lattice has black nodes ``B(i, j, k)`` at ``origin + h (i, j, k)`` (``dims`` per axis) and
red nodes ``R(i, j, k)`` at the cube centres ``origin + h (i + 1/2, j + 1/2, k + 1/2)`` (valid
for indices below ``dims - 1``). A node's id is ``2 cell + colour`` (black 0, red 1) with
``cell = i + nx (j + ny k)``. Every lattice edge has one owner cell and a slot ``d`` in
``[0, 14)``, so its global id is ``14 cell + d``:

- ``d = 0, 1, 2``: the black long edge B(c) - B(c + e_d);
- ``d = 3, 4, 5``: the red long edge R(c) - R(c + e_{d-3});
- ``d = 6 + (x + 2 y + 4 z)``: the short edge R(c) - B(c + (x, y, z)).

Each background tetrahedron has one black long edge; the twelve of a black node B(c) are the
four around each of its edges B(c) - B(c + e_a), given by ``layout`` (12, 4, 4): per local
vertex (colour, dx, dy, dz). Vertices of the output are nodes and cut points, named by these
ids, so the mesh is conforming by construction. Variable-size output is count -> prefix sum
-> allocate -> write; kernels over cells take ``first`` so the host can split launches.

A lattice may be a window of a larger one (a brick of a distributed run): ``offset`` is the
global cell of its cell (0, 0, 0), so node positions are the global nodes' bit for bit, and
only the tetrahedra of its owned black nodes (``own_lo <= c < own_hi``, window cells) are
emitted.
"""

from typing import Any

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})

SLOTS = 14
TETS_PER_CELL = 12
_SLOTS = wp.constant(SLOTS)
_TPC = wp.constant(TETS_PER_CELL)
_SHORT = wp.constant(0.8660254037844386)  # short edge / long edge
#: a point within this fraction of a voxel of a face between two voxels (on it included) is in
#: the upper one: far above the rounding of computed positions, far below any feature
VOXEL_TIE = 2.0**-20
_VOXEL_TIE = wp.constant(wp.float64(VOXEL_TIE))


@wp.func
def cell_coords(cell: int, dims: wp.vec3i):
    return wp.vec3i(cell % dims[0], (cell / dims[0]) % dims[1], cell / (dims[0] * dims[1]))


@wp.func
def cell_index(c: wp.vec3i, dims: wp.vec3i):
    return c[0] + dims[0] * (c[1] + dims[1] * c[2])


@wp.func
def node_valid(c: wp.vec3i, colour: int, dims: wp.vec3i):
    """A node exists: black inside dims, red one fewer per axis."""
    ok = True
    for a in range(3):
        if c[a] < 0 or c[a] >= dims[a] - colour:
            ok = False
    return ok


@wp.func
def node_local(node: int, dims: wp.vec3i, offset: wp.vec3i, h: float):
    """Position of a node relative to the lattice origin; ``offset``: the global cell of the
    window's cell (0, 0, 0) when the lattice is a window of a larger one (the position is the
    global node's, bit for bit)."""
    c = cell_coords(node / 2, dims) + offset
    s = 0.5 * float(node % 2)
    return wp.vec3((float(c[0]) + s) * h, (float(c[1]) + s) * h, (float(c[2]) + s) * h)


@wp.func
def slot_end(cell: int, d: int, dims: wp.vec3i):
    """The second node of edge slot d of ``cell`` (the first is B(cell) for d < 3, else
    R(cell)), or -1 when it does not exist."""
    c = cell_coords(cell, dims)
    colour = 1
    o = wp.vec3i(0, 0, 0)
    if d < 3:
        colour = 0
        o[d] = 1
    elif d < 6:
        o[d - 3] = 1
    else:
        k = d - 6
        colour = 0
        o = wp.vec3i(k & 1, (k >> 1) & 1, (k >> 2) & 1)
    e = c + o
    out = int(-1)
    if node_valid(c, wp.where(d < 3, 0, 1), dims) and node_valid(e, colour, dims):
        out = 2 * cell_index(e, dims) + colour
    return out


@wp.func
def slot_start(cell: int, d: int):
    return 2 * cell + wp.where(d < 3, 0, 1)


@wp.kernel
def lattice_points_kernel(dims: wp.vec3i, offset: wp.vec3i, origin: wp.vec3, h: float,
                          points: wp.array(dtype=wp.vec3)):
    """One thread per node: its world position (invalid red nodes too, evaluated but unused)."""
    n = wp.tid()
    points[n] = origin + node_local(n, dims, offset, h)


@wp.func
def box_distance(p: wp.vec3, lo: wp.vec3, hi: wp.vec3):
    d = float(3.0e38)
    for a in range(3):
        d = wp.min(d, wp.min(p[a] - lo[a], hi[a] - p[a]))
    return d


@wp.kernel
def clip_values_kernel(points: wp.array(dtype=wp.vec3), f: wp.array(dtype=wp.float32), lo: wp.vec3, hi: wp.vec3,
                       values: wp.array(dtype=wp.float32)):
    """One thread per point: min(f, signed distance to the box), the field of {f > 0} in bounds;
    NaN where f is NaN inside the box (the node classification counts it: min would drop it)."""
    i = wp.tid()
    v = f[i]
    d = box_distance(points[i], lo, hi)
    if v != v and d > 0.0:
        values[i] = v
    else:
        values[i] = wp.min(v, d)


@wp.kernel
def node_signs_kernel(dims: wp.vec3i, values: wp.array(dtype=wp.float32), signs: wp.array(dtype=wp.int8),
                      bad: wp.array(dtype=wp.int32)):
    """One thread per node: its sign (+1 inside, 0 on f = 0, -1 outside; nonexistent nodes
    outside); a NaN value counts in ``bad``."""
    n = wp.tid()
    c = cell_coords(n / 2, dims)
    v = values[n]
    s = int(-1)
    if node_valid(c, n % 2, dims):
        if v != v:
            wp.atomic_add(bad, 0, 1)
        elif v > 0.0:
            s = 1
        elif v == 0.0:
            s = 0
    signs[n] = wp.int8(s)


@wp.func
def is_cut(a: int, b: int, signs: wp.array(dtype=wp.int8)):
    return b >= 0 and int(signs[a]) * int(signs[b]) < 0


@wp.kernel
def count_cuts_kernel(first: int, dims: wp.vec3i, signs: wp.array(dtype=wp.int8), counts: wp.array(dtype=wp.int32)):
    """One thread per cell: how many of its 14 edge slots join a + node and a - node."""
    cell = first + wp.tid()
    k = int(0)
    for d in range(_SLOTS):
        if is_cut(slot_start(cell, d), slot_end(cell, d, dims), signs):
            k += 1
    counts[cell] = k


@wp.kernel
def write_cuts_kernel(first: int, dims: wp.vec3i, offset: wp.vec3i, h: float, signs: wp.array(dtype=wp.int8),
                      values: wp.array(dtype=wp.float32), offsets: wp.array(dtype=wp.int32),
                      edge_cut: wp.array(dtype=wp.int32), cut_slot: wp.array(dtype=wp.int32),
                      p0: wp.array(dtype=wp.vec3), p1: wp.array(dtype=wp.vec3), f_lo: wp.array(dtype=wp.float32),
                      f_hi: wp.array(dtype=wp.float32)):
    """One thread per cell: the cut edges' slots, end positions (local) and the field at both
    ends (the bracket of the root); ``edge_cut`` maps a slot to its cut index (-1 elsewhere)."""
    cell = first + wp.tid()
    k = offsets[cell]
    for d in range(_SLOTS):
        a = slot_start(cell, d)
        b = slot_end(cell, d, dims)
        slot = _SLOTS * cell + d
        if is_cut(a, b, signs):
            edge_cut[slot] = k
            cut_slot[k] = slot
            p0[k] = node_local(a, dims, offset, h)
            p1[k] = node_local(b, dims, offset, h)
            f_lo[k] = values[a]
            f_hi[k] = values[b]
            k += 1
        else:
            edge_cut[slot] = -1


@wp.kernel
def edge_points_kernel(t: wp.array(dtype=wp.float32), p0: wp.array(dtype=wp.vec3), p1: wp.array(dtype=wp.vec3),
                       origin: wp.vec3, out: wp.array(dtype=wp.vec3)):
    """One thread per cut edge: origin + p0 + t (p1 - p0)."""
    i = wp.tid()
    out[i] = origin + p0[i] + t[i] * (p1[i] - p0[i])


@wp.kernel
def false_position_init_kernel(f_lo: wp.array(dtype=wp.float32), f_hi: wp.array(dtype=wp.float32),
                               t: wp.array(dtype=wp.float32)):
    """One thread per cut edge: the first secant point of the bracket [0, 1]."""
    i = wp.tid()
    t[i] = wp.clamp(f_lo[i] / (f_lo[i] - f_hi[i]), 0.0, 1.0)


@wp.kernel
def false_position_step_kernel(values: wp.array(dtype=wp.float32), t_lo: wp.array(dtype=wp.float32),
                               t_hi: wp.array(dtype=wp.float32), f_lo: wp.array(dtype=wp.float32),
                               f_hi: wp.array(dtype=wp.float32), side: wp.array(dtype=wp.int32),
                               t: wp.array(dtype=wp.float32)):
    """One thread per cut edge: the Illinois variant of regula falsi. The new value replaces
    the bracket end of its sign; when the same end is replaced twice in a row, the other
    end's value is halved (superlinear, and the bracket always holds the root). An exact
    zero, or a bracket at float32 resolution, ends the search there."""
    i = wp.tid()
    v = values[i]
    if v == 0.0 or t_hi[i] - t_lo[i] <= 1.0e-7:
        t_lo[i] = t[i]
        t_hi[i] = t[i]
        f_lo[i] = 0.0
        f_hi[i] = 0.0
        return
    if (v > 0.0) == (f_lo[i] > 0.0):
        t_lo[i] = t[i]
        f_lo[i] = v
        if side[i] == -1:
            f_hi[i] = 0.5 * f_hi[i]
        side[i] = -1
    else:
        t_hi[i] = t[i]
        f_hi[i] = v
        if side[i] == 1:
            f_lo[i] = 0.5 * f_lo[i]
        side[i] = 1
    d = f_lo[i] - f_hi[i]
    nt = 0.5 * (t_lo[i] + t_hi[i])
    if d != 0.0:
        nt = t_lo[i] + f_lo[i] / d * (t_hi[i] - t_lo[i])
    t[i] = wp.clamp(nt, t_lo[i], t_hi[i])


@wp.kernel
def cut_positions_kernel(t: wp.array(dtype=wp.float32), p0: wp.array(dtype=wp.vec3), p1: wp.array(dtype=wp.vec3),
                         pos: wp.array(dtype=wp.vec3)):
    """One thread per cut edge: the cut point (local coordinates)."""
    i = wp.tid()
    pos[i] = p0[i] + t[i] * (p1[i] - p0[i])


@wp.func
def warp_candidate(slot: int, other: int, here: wp.vec3, length: float, alpha: float,
                   edge_cut: wp.array(dtype=wp.int32), cut_pos: wp.array(dtype=wp.vec3),
                   signs: wp.array(dtype=wp.int8)):
    """Distance from ``here`` to the cut point of ``slot`` when it violates the node (closer
    than alpha * length and the other end not warped away), else a huge value."""
    out = float(3.0e38)
    if other >= 0:
        c = edge_cut[slot]
        if c >= 0 and int(signs[other]) != 0:
            d = wp.length(cut_pos[c] - here)
            if d < alpha * length:
                out = d
    return out


@wp.kernel
def warp_nodes_kernel(first: int, which: int, dims: wp.vec3i, h: float, alpha_long: float, alpha_short: float,
                      edge_cut: wp.array(dtype=wp.int32), cut_pos: wp.array(dtype=wp.vec3),
                      signs: wp.array(dtype=wp.int8), node_pos: wp.array(dtype=wp.vec3),
                      warped: wp.array(dtype=wp.int32)):
    """One thread per node of sign ``which``: when a cut point on one of its 14 edges lies
    closer than alpha times the edge (alpha_long on long, alpha_short on short edges), the node
    moves to the nearest such cut point and its sign becomes 0 (the cut points on its edges
    are dropped: an edge with a zero end is not cut). Nodes of one sign share no cut edge,
    so a pass reads only nodes of the other sign: no race."""
    n = first + wp.tid()
    if int(signs[n]) != which:
        return
    cell = n / 2
    colour = n % 2
    c = cell_coords(cell, dims)
    here = node_pos[n]
    best = float(3.0e38)
    best_slot = int(-1)
    for a in range(3):  # long edges, both directions
        d_long = a + 3 * colour
        sl = _SLOTS * cell + d_long
        dist = warp_candidate(sl, slot_end(cell, d_long, dims), here, h, alpha_long, edge_cut, cut_pos, signs)
        if dist < best:
            best = dist
            best_slot = sl
        cm = c
        cm[a] = c[a] - 1
        if cm[a] >= 0:
            cc = cell_index(cm, dims)
            sl = _SLOTS * cc + d_long
            if slot_end(cc, d_long, dims) == n:
                dist = warp_candidate(sl, 2 * cc + colour, here, h, alpha_long, edge_cut, cut_pos, signs)
                if dist < best:
                    best = dist
                    best_slot = sl
    for k in range(8):  # short edges
        o = wp.vec3i(k & 1, (k >> 1) & 1, (k >> 2) & 1)
        sl = int(-1)
        other = int(-1)
        if colour == 1:
            sl = _SLOTS * cell + 6 + k
            other = slot_end(cell, 6 + k, dims)
        else:
            cr = c - o
            if cr[0] >= 0 and cr[1] >= 0 and cr[2] >= 0:
                cc = cell_index(cr, dims)
                if node_valid(cr, 1, dims):
                    sl = _SLOTS * cc + 6 + k
                    other = 2 * cc + 1
        if sl >= 0:
            dist = warp_candidate(sl, other, here, h * _SHORT, alpha_short, edge_cut, cut_pos, signs)
            if dist < best:
                best = dist
                best_slot = sl
    if best_slot >= 0:
        node_pos[n] = cut_pos[edge_cut[best_slot]]
        signs[n] = wp.int8(0)
        warped[n] = 1


@wp.func
def tet_node(cell: int, c: wp.vec3i, t: int, v: int, dims: wp.vec3i, layout: wp.array3d(dtype=wp.int32)):
    """Node id of local vertex v of background tetrahedron t of black node ``cell``, or -1."""
    colour = layout[t, v, 0]
    e = c + wp.vec3i(layout[t, v, 1], layout[t, v, 2], layout[t, v, 3])
    out = int(-1)
    if node_valid(e, colour, dims):
        out = 2 * cell_index(e, dims) + colour
    return out


@wp.func
def tet_case(cell: int, c: wp.vec3i, t: int, dims: wp.vec3i, layout: wp.array3d(dtype=wp.int32),
             face_bits: wp.array(dtype=wp.int32), signs: wp.array(dtype=wp.int8)):
    """The stencil case of a background tetrahedron (sign code * 16 + face bits), or -1 when
    a vertex does not exist or none is inside."""
    code = int(0)
    scale = int(1)
    plus = int(0)
    ok = True
    for v in range(4):
        nd = tet_node(cell, c, t, v, dims, layout)
        if nd < 0:
            ok = False
        else:
            s = int(signs[nd])
            code += (s + 1) * scale
            if s > 0:
                plus += 1
        scale *= 3
    out = int(-1)
    if ok and plus > 0:
        out = code * 16 + face_bits[t]
    return out


@wp.func
def owned(c: wp.vec3i, own_lo: wp.vec3i, own_hi: wp.vec3i):
    """A black node lies in the window's owned range of cells (its tetrahedra are emitted)."""
    ok = True
    for a in range(3):
        if c[a] < own_lo[a] or c[a] >= own_hi[a]:
            ok = False
    return ok


@wp.func
def stencil_count(case: int, count: wp.array(dtype=wp.int32)):
    k = int(0)
    if case >= 0:
        k = count[case]
    return k


@wp.kernel
def count_tets_kernel(first: int, dims: wp.vec3i, own_lo: wp.vec3i, own_hi: wp.vec3i,
                      layout: wp.array3d(dtype=wp.int32), face_bits: wp.array(dtype=wp.int32),
                      signs: wp.array(dtype=wp.int8), count: wp.array(dtype=wp.int32),
                      counts: wp.array(dtype=wp.int32)):
    """One thread per black node: the number of output tetrahedra of its twelve (none outside
    the owned cells ``own_lo <= c < own_hi``)."""
    cell = first + wp.tid()
    c = cell_coords(cell, dims)
    k = int(0)
    if node_valid(c, 0, dims) and owned(c, own_lo, own_hi):
        for t in range(_TPC):
            k += stencil_count(tet_case(cell, c, t, dims, layout, face_bits, signs), count)
    counts[cell] = k


@wp.kernel
def write_tets_kernel(first: int, dims: wp.vec3i, own_lo: wp.vec3i, own_hi: wp.vec3i, n_nodes: int, layout: wp.array3d(dtype=wp.int32),
                      face_bits: wp.array(dtype=wp.int32), edge_slot: wp.array3d(dtype=wp.int32),
                      signs: wp.array(dtype=wp.int8), count: wp.array(dtype=wp.int32),
                      tets: wp.array3d(dtype=wp.int32), edge_cut: wp.array(dtype=wp.int32), offsets: wp.array(dtype=wp.int32),
                      out: wp.array(dtype=wp.vec4i), used: wp.array(dtype=wp.int32)):
    """One thread per black node: its output tetrahedra as vertex keys (a node id, or
    n_nodes + the index of a cut point), and the keys marked used."""
    cell = first + wp.tid()
    c = cell_coords(cell, dims)
    if not (node_valid(c, 0, dims) and owned(c, own_lo, own_hi)):
        return
    k = offsets[cell]
    for t in range(_TPC):
        case = tet_case(cell, c, t, dims, layout, face_bits, signs)
        m = stencil_count(case, count)
        for j in range(m):
            key = wp.vec4i(0, 0, 0, 0)
            for v in range(4):
                r = tets[case, j, v]
                if r < 4:
                    key[v] = tet_node(cell, c, t, r, dims, layout)
                else:
                    e = r - 4
                    owner = cell_index(c + wp.vec3i(edge_slot[t, e, 0], edge_slot[t, e, 1], edge_slot[t, e, 2]),
                                       dims)
                    key[v] = n_nodes + edge_cut[_SLOTS * owner + edge_slot[t, e, 3]]
                used[key[v]] = 1
            out[k] = key
            k += 1


@wp.kernel
def remap_tets_kernel(ids: wp.array(dtype=wp.int32), tets: wp.array(dtype=wp.vec4i)):
    """One thread per tetrahedron: keys to compact vertex ids."""
    i = wp.tid()
    k = tets[i]
    tets[i] = wp.vec4i(ids[k[0]], ids[k[1]], ids[k[2]], ids[k[3]])


@wp.kernel
def gather_vertices_kernel(n_nodes: int, used: wp.array(dtype=wp.int32), ids: wp.array(dtype=wp.int32),
                           node_pos: wp.array(dtype=wp.vec3), cut_pos: wp.array(dtype=wp.vec3),
                           signs: wp.array(dtype=wp.int8), points: wp.array(dtype=wp.vec3),
                           on_surface: wp.array(dtype=wp.uint8)):
    """One thread per key: a used key's position (local) and whether it lies on f = 0 (a cut
    point, or a node of sign 0)."""
    key = wp.tid()
    if used[key] == 0:
        return
    v = ids[key]
    if key < n_nodes:
        points[v] = node_pos[key]
        on_surface[v] = wp.where(int(signs[key]) == 0, wp.uint8(1), wp.uint8(0))
    else:
        points[v] = cut_pos[key - n_nodes]
        on_surface[v] = wp.uint8(1)


@wp.func
def _cos_of(a: wp.vec3d, b: wp.vec3d, d: wp.float64):
    """The cosine of the angle of a and b, d = |a| |b| (1 when either is zero), clamped."""
    c = wp.float64(1.0)
    if d > wp.float64(0.0):
        c = wp.dot(a, b) / d
    return wp.clamp(c, wp.float64(-1.0), wp.float64(1.0))


@wp.kernel
def tet_quality_kernel(first: int, points: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.vec4i),
                       out: wp.array(dtype=wp.vec4d)):
    """One thread per tetrahedron i = first + tid, in float64: (smallest dihedral angle, largest (radians),
    circumradius / shortest edge, signed volume). The angle at edge ij is pi minus the angle
    between the outward normals of the two faces holding it."""
    i = first + wp.tid()
    t = tets[i]
    p0 = points[t[0]]
    p1 = points[t[1]]
    p2 = points[t[2]]
    p3 = points[t[3]]
    n0 = wp.cross(p2 - p1, p3 - p1)  # outward normals of the faces opposite each vertex
    n1 = wp.cross(p3 - p0, p2 - p0)
    n2 = wp.cross(p1 - p0, p3 - p0)
    n3 = wp.cross(p2 - p0, p1 - p0)
    l0 = wp.length(n0)
    l1 = wp.length(n1)
    l2 = wp.length(n2)
    l3 = wp.length(n3)
    pi = wp.float64(3.141592653589793)
    # edges (01, 02, 03, 12, 13, 23) are held by the faces opposite (23, 13, 12, 03, 02, 01);
    # the angle pi - acos(c) rises with c, so the extremes come from the extreme cosines: two
    # acos a tetrahedron instead of six, the same values (a monotone map commutes with min, max)
    c01 = _cos_of(n2, n3, l2 * l3)
    c02 = _cos_of(n1, n3, l1 * l3)
    c03 = _cos_of(n1, n2, l1 * l2)
    c12 = _cos_of(n0, n3, l0 * l3)
    c13 = _cos_of(n0, n2, l0 * l2)
    c23 = _cos_of(n0, n1, l0 * l1)
    lo = pi - wp.acos(wp.min(wp.min(wp.min(c01, c02), wp.min(c03, c12)), wp.min(c13, c23)))
    hi = pi - wp.acos(wp.max(wp.max(wp.max(c01, c02), wp.max(c03, c12)), wp.max(c13, c23)))
    a = p1 - p0
    b = p2 - p0
    c = p3 - p0
    det = wp.dot(a, wp.cross(b, c))
    num = wp.dot(a, a) * wp.cross(b, c) + wp.dot(b, b) * wp.cross(c, a) + wp.dot(c, c) * wp.cross(a, b)
    short = wp.min(wp.min(wp.min(wp.length(a), wp.length(b)), wp.min(wp.length(c), wp.length(p2 - p1))),
                   wp.min(wp.length(p3 - p1), wp.length(p3 - p2)))
    ratio = wp.float64(1.0e300)
    if det != wp.float64(0.0) and short > wp.float64(0.0):
        ratio = wp.length(num) / wp.abs(wp.float64(2.0) * det) / short
    out[i] = wp.vec4d(lo, hi, ratio, det / wp.float64(6.0))


# -- graded backgrounds: an explicit list of nodes, edges and tetrahedra ---------------------
# (warpmesh.solid.graded builds it; the vertices of each tetrahedron are listed by increasing
# global id, and ``flip`` marks those that are then negatively oriented)


@wp.kernel
def mesh_node_signs_kernel(values: wp.array(dtype=wp.float32), signs: wp.array(dtype=wp.int8),
                           bad: wp.array(dtype=wp.int32)):
    """One thread per background node: its sign (+1 inside, 0 on f = 0, -1 outside; a NaN
    value counts in ``bad`` and is outside)."""
    n = wp.tid()
    v = values[n]
    s = int(-1)
    if v != v:
        wp.atomic_add(bad, 0, 1)
    elif v > 0.0:
        s = 1
    elif v == 0.0:
        s = 0
    signs[n] = wp.int8(s)


@wp.kernel
def count_mesh_cuts_kernel(edges: wp.array(dtype=wp.vec2i), signs: wp.array(dtype=wp.int8),
                           flags: wp.array(dtype=wp.int32)):
    """One thread per background edge: 1 when it joins a + node and a - node."""
    e = wp.tid()
    flags[e] = wp.where(is_cut(edges[e][0], edges[e][1], signs), 1, 0)


@wp.kernel
def write_mesh_cuts_kernel(edges: wp.array(dtype=wp.vec2i), node_pos: wp.array(dtype=wp.vec3),
                           values: wp.array(dtype=wp.float32), flags: wp.array(dtype=wp.int32),
                           offsets: wp.array(dtype=wp.int32), edge_cut: wp.array(dtype=wp.int32),
                           p0: wp.array(dtype=wp.vec3), p1: wp.array(dtype=wp.vec3),
                           f_lo: wp.array(dtype=wp.float32), f_hi: wp.array(dtype=wp.float32)):
    """One thread per background edge: a cut edge's bracket (end positions, local, and the
    field at both ends); ``edge_cut`` maps an edge to its cut index (-1 elsewhere)."""
    e = wp.tid()
    if flags[e] == 0:
        edge_cut[e] = -1
        return
    k = offsets[e]
    a = edges[e][0]
    b = edges[e][1]
    edge_cut[e] = k
    p0[k] = node_pos[a]
    p1[k] = node_pos[b]
    f_lo[k] = values[a]
    f_hi[k] = values[b]


@wp.kernel
def warp_mesh_nodes_kernel(first: int, which: int, star: wp.array(dtype=wp.int32), star_edges: wp.array(dtype=wp.int32),
                           edges: wp.array(dtype=wp.vec2i), edge_length: wp.array(dtype=wp.float32),
                           edge_alpha: wp.array(dtype=wp.float32), edge_cut: wp.array(dtype=wp.int32),
                           cut_pos: wp.array(dtype=wp.vec3), signs: wp.array(dtype=wp.int8),
                           node_pos: wp.array(dtype=wp.vec3), warped: wp.array(dtype=wp.int32)):
    """One thread per background node of sign ``which``: when a cut point on one of its edges
    (``star_edges[star[n]:star[n + 1]]``) lies closer than the edge's alpha times its length,
    the node moves to the nearest such cut point and its sign becomes 0. Nodes of one sign
    share no cut edge, so a pass reads only nodes of the other sign: no race."""
    n = first + wp.tid()
    if int(signs[n]) != which:
        return
    here = node_pos[n]
    best = float(3.0e38)
    best_cut = int(-1)
    for j in range(star[n], star[n + 1]):
        e = star_edges[j]
        c = edge_cut[e]
        other = edges[e][0] + edges[e][1] - n
        if c >= 0 and int(signs[other]) != 0:
            d = wp.length(cut_pos[c] - here)
            if d < edge_alpha[e] * edge_length[e] and d < best:
                best = d
                best_cut = c
    if best_cut >= 0:
        node_pos[n] = cut_pos[best_cut]
        signs[n] = wp.int8(0)
        warped[n] = 1


@wp.func
def mesh_tet_case(t: wp.vec4i, signs: wp.array(dtype=wp.int8), local: wp.array(dtype=wp.vec3)):
    """The stencil case of a background tetrahedron (sign code * 16 + face bits), or -1 when
    none of its nodes is inside. Bit o is set when the face off vertex o has two inside
    vertices p < q and one outside n, and q is closer to n than p (on the background)."""
    code = int(0)
    scale = int(1)
    plus = int(0)
    for v in range(4):
        s = int(signs[t[v]])
        code += (s + 1) * scale
        if s > 0:
            plus += 1
        scale *= 3
    bits = int(0)
    for o in range(4):
        p = int(-1)
        q = int(-1)
        n = int(-1)
        k_minus = int(0)
        for v in range(4):
            if v != o:
                s = int(signs[t[v]])
                if s > 0:
                    if p < 0:
                        p = v
                    else:
                        q = v
                elif s < 0:
                    n = v
                    k_minus += 1
        if q >= 0 and k_minus == 1:
            dp = wp.length_sq(local[t[p]] - local[t[n]])
            dq = wp.length_sq(local[t[q]] - local[t[n]])
            if dq < dp:
                bits = bits | (1 << o)
    return wp.where(plus > 0, code * 16 + bits, -1)


@wp.kernel
def count_mesh_tets_kernel(first: int, tets: wp.array(dtype=wp.vec4i), signs: wp.array(dtype=wp.int8),
                           local: wp.array(dtype=wp.vec3), count: wp.array(dtype=wp.int32),
                           counts: wp.array(dtype=wp.int32)):
    """One thread per background tetrahedron: the number of output tetrahedra of its stencil."""
    i = first + wp.tid()
    counts[i] = stencil_count(mesh_tet_case(tets[i], signs, local), count)


@wp.kernel
def write_mesh_tets_kernel(first: int, n_nodes: int, tets: wp.array(dtype=wp.vec4i),
                           tet_edges: wp.array2d(dtype=wp.int32), flip: wp.array(dtype=wp.int32),
                           signs: wp.array(dtype=wp.int8), local: wp.array(dtype=wp.vec3),
                           count: wp.array(dtype=wp.int32),
                           table: wp.array3d(dtype=wp.int32), edge_cut: wp.array(dtype=wp.int32),
                           offsets: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.vec4i),
                           used: wp.array(dtype=wp.int32)):
    """One thread per background tetrahedron: its stencil's tetrahedra as vertex keys (a node
    id, or n_nodes + the index of a cut point), positive (two references swapped when the
    tetrahedron is flipped), and the keys marked used."""
    i = first + wp.tid()
    t = tets[i]
    case = mesh_tet_case(t, signs, local)
    m = stencil_count(case, count)
    k = offsets[i]
    for j in range(m):
        key = wp.vec4i(0, 0, 0, 0)
        for v in range(4):
            r = table[case, j, v]
            if r < 4:
                key[v] = t[r]
            else:
                key[v] = n_nodes + edge_cut[tet_edges[i, r - 4]]
            used[key[v]] = 1
        if flip[i] != 0:
            key = wp.vec4i(key[0], key[2], key[1], key[3])
        out[k] = key
        k += 1


# -- bulk geometry and indices of the host's tetrahedral meshes (warpmesh.solid.dihedral, .graded) --
# Numpy's operations in numpy's order, one rounding each (this module fuses no multiply-add), so
# the host's results do not change when a numpy pass moves here; indices are int64 (the host's).


@wp.kernel
def signed_volumes_kernel(first: int, points: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.int64),
                          out: wp.array(dtype=wp.float64)):
    """One thread per tetrahedron i = first + tid (``tets`` flat, 4 per row): det(b - a, c - a,
    d - a) / 6 as numpy 2 computes it on x86-64: ``np.cross(b - a, c - a)`` (each component a
    product minus a product), its ``einsum`` dot with d - a, which adds the products of the
    components 0 and 2 first, then the division."""
    i = first + wp.tid()
    a = points[int(tets[4 * i])]
    u = points[int(tets[4 * i + 1])] - a
    v = points[int(tets[4 * i + 2])] - a
    w = points[int(tets[4 * i + 3])] - a
    c0 = u[1] * v[2] - u[2] * v[1]
    c1 = u[2] * v[0] - u[0] * v[2]
    c2 = u[0] * v[1] - u[1] * v[0]
    out[i] = ((c0 * w[0] + c2 * w[2]) + c1 * w[1]) / wp.float64(6.0)


@wp.kernel
def longest_edges_kernel(first: int, coords: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.int64),
                         keys: wp.array(dtype=wp.int64), longest_key: wp.array(dtype=wp.int64),
                         longest_length: wp.array(dtype=wp.float64)):
    """One thread per tetrahedron i = first + tid: the key (``keys`` flat, 6 per row, local edges
    01, 02, 03, 12, 13, 23) and length of its longest edge, ties to the smallest key. Squared
    lengths summed in numpy's ``einsum`` order (x and z first, as :func:`signed_volumes_kernel`);
    the length is the square root of the largest."""
    i = first + wp.tid()
    p0 = coords[int(tets[4 * i])]
    p1 = coords[int(tets[4 * i + 1])]
    p2 = coords[int(tets[4 * i + 2])]
    p3 = coords[int(tets[4 * i + 3])]
    best = wp.float64(-1.0)
    key = wp.int64(0)
    for e in range(6):
        # ends of local edge e: (0,1) (0,2) (0,3) (1,2) (1,3) (2,3)
        d = p0 - p1
        if e == 1:
            d = p0 - p2
        elif e == 2:
            d = p0 - p3
        elif e == 3:
            d = p1 - p2
        elif e == 4:
            d = p1 - p3
        elif e == 5:
            d = p2 - p3
        l2 = (d[0] * d[0] + d[2] * d[2]) + d[1] * d[1]
        k = keys[6 * i + e]
        if l2 > best or (l2 == best and k < key):
            best = l2
            key = k
    longest_key[i] = key
    longest_length[i] = wp.sqrt(best)


@wp.func
def merge_split(a: wp.array(dtype=wp.int64), b: wp.array(dtype=wp.int64), d: int) -> int:
    """How many entries of ``a`` are among the first d of the stable merge of the sorted runs
    a and b (a's entries before equal ones of b): a binary search on the merge path."""
    lo = wp.max(0, d - b.shape[0])
    hi = wp.min(d, a.shape[0])
    while lo < hi:
        mid = (lo + hi) / 2
        if a[mid] <= b[d - mid - 1]:
            lo = mid + 1
        else:
            hi = mid
    return lo


@wp.kernel
def merge_sorted_kernel(first: int, per_thread: int, a_keys: wp.array(dtype=wp.int64),
                        a_values: wp.array(dtype=wp.int64), b_keys: wp.array(dtype=wp.int64),
                        b_values: wp.array(dtype=wp.int64), keys: wp.array(dtype=wp.int64),
                        values: wp.array(dtype=wp.int64)):
    """One thread per run t = first + tid of ``per_thread`` outputs of the stable merge of the
    sorted keys a and b (a's before equal ones of b), with their values: its start on the merge
    path found by :func:`merge_split`, then a sequential merge."""
    t = first + wp.tid()
    na = a_keys.shape[0]
    nb = b_keys.shape[0]
    d0 = t * per_thread
    d1 = wp.min(d0 + per_thread, na + nb)
    i = merge_split(a_keys, b_keys, d0)
    j = d0 - i
    for d in range(d0, d1):
        take_a = False
        if i < na:
            if j >= nb:
                take_a = True
            elif a_keys[i] <= b_keys[j]:
                take_a = True
        if take_a:
            keys[d] = a_keys[i]
            values[d] = a_values[i]
            i += 1
        else:
            keys[d] = b_keys[j]
            values[d] = b_values[j]
            j += 1


@wp.kernel
def tet_edge_keys_kernel(first: int, tets: wp.array(dtype=wp.int64), key_base: wp.int64,
                         keys: wp.array(dtype=wp.int64)):
    """One thread per tetrahedron i = first + tid: the key min * key_base + max of each local
    edge (01, 02, 03, 12, 13, 23) of its vertex ids, 6 per row."""
    i = first + wp.tid()
    for e in range(6):
        a = tets[4 * i]
        b = tets[4 * i + 1]
        if e == 1:
            b = tets[4 * i + 2]
        elif e == 2:
            b = tets[4 * i + 3]
        elif e == 3:
            a = tets[4 * i + 1]
            b = tets[4 * i + 2]
        elif e == 4:
            a = tets[4 * i + 1]
            b = tets[4 * i + 3]
        elif e == 5:
            a = tets[4 * i + 2]
            b = tets[4 * i + 3]
        keys[6 * i + e] = wp.min(a, b) * key_base + wp.max(a, b)


@wp.func
def voxel_code(codes: wp.array(dtype=Any), x: wp.vec3d, spacing: wp.vec3d, shape: wp.vec3i, strides: wp.vec3l,
               rest: int) -> int:
    """The code of the voxel holding local point x (voxel i at i * spacing: the nearest, a
    point on or within ``VOXEL_TIE`` of a face in the upper voxel, as
    :func:`warpmesh.solid.thin.labels_at`), ``rest`` outside the volume; ``strides`` in
    elements of the flat ``codes``."""
    flat = wp.int64(0)
    for k in range(3):
        q = wp.rint(x[k] / spacing[k] + _VOXEL_TIE)
        if not (q >= wp.float64(0.0) and q < wp.float64(shape[k])):  # NaN too
            return rest
        flat += wp.int64(int(q)) * strides[k]
    return int(codes[flat])


@wp.kernel
def unresolved_edges_kernel(first: int, a: wp.array(dtype=wp.vec3d), b: wp.array(dtype=wp.vec3d),
                            samples: wp.array(dtype=wp.int32), codes: wp.array(dtype=Any), spacing: wp.vec3d,
                            shape: wp.vec3i, strides: wp.vec3l, rest: int, min_run: int,
                            focus: wp.array(dtype=wp.int8), use_focus: int, out: wp.array(dtype=wp.int8)):
    """One thread per edge i = first + tid, a -> b, m = ``samples[i]``: the voxel codes at
    a + s (b - a) for s = 0, (k + 1/2) / m (k < m), 1 (:func:`voxel_code`), read as runs;
    a run shorter than ``min_run`` samples, but the first and the last, takes the code of the
    run before it (after that one's own merge); 1 in ``out`` when the codes then change more
    than once along the edge (and, with ``use_focus``, some run's code has ``focus``), else
    0. One pass, no sample stored: the host's numpy version is
    :func:`warpmesh.solid.thin.unresolved_edges` with ``kernel=False``."""
    i = first + wp.tid()
    pa = a[i]
    d = b[i] - pa
    m = samples[i]
    cur = voxel_code(codes, pa, spacing, shape, strides, rest)  # the open run's code, and its length
    length = int(1)
    runs = int(0)  # runs closed so far
    last = int(0)  # the (merged) code of the last closed run
    changes = int(0)
    hit_focus = int(0)
    for j in range(1, m + 3):  # j = m + 2: past the end, closes the last run
        c = int(0)
        if j <= m + 1:
            s = wp.float64(1.0)
            if j <= m:
                s = (wp.float64(j - 1) + wp.float64(0.5)) / wp.float64(m)
            c = voxel_code(codes, pa + s * d, spacing, shape, strides, rest)
            if c == cur:
                length += 1
                continue
        merged = cur
        if runs > 0 and j <= m + 1 and length < min_run:  # neither the first run nor the last
            merged = last
        if runs > 0 and merged != last:
            changes += 1
        if use_focus != 0:
            if focus[merged] != wp.int8(0):
                hit_focus = 1
        last = merged
        runs += 1
        cur = c
        length = 1
    flag = wp.int8(0)
    if changes > 1 and (use_focus == 0 or hit_focus != 0):
        flag = wp.int8(1)
    out[i] = flag


for _dtype in (wp.uint8, wp.uint16, wp.int32):  # the dtypes of multilabel.label_codes: compiled with the module
    wp.overload(unresolved_edges_kernel, {"codes": wp.array(dtype=_dtype)})


@wp.func
def _sorted_has(keys: wp.array(dtype=wp.int64), lo: int, end: int, key: wp.int64) -> bool:
    """Whether ``keys[lo:end]`` (sorted) holds ``key``: a binary search."""
    hi = end
    while lo < hi:
        mid = (lo + hi) / 2
        if keys[mid] < key:
            lo = mid + 1
        else:
            hi = mid
    found = False
    if lo < end:
        found = keys[lo] == key
    return found


@wp.kernel
def speck_sizes_kernel(first: int, nodes: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.int64),
                       spacing: wp.vec3d, shape: wp.vec3i, top: int, coarse: wp.array(dtype=wp.uint8),
                       coarse_shape: wp.vec3i, keys: wp.array(dtype=wp.int64), offsets: wp.array(dtype=wp.int32),
                       sizes: wp.array(dtype=wp.float64), out: wp.array(dtype=wp.float64)):
    """One thread per tetrahedron i = first + tid: the smallest of ``sizes`` whose speck blocks
    meet its bounding box, as :meth:`warpmesh.solid.thin.Specks.size_of` computes it (``out``
    left as it is, inf, when none does). The box in voxels: floor(min or max of node / spacing
    + 1/2), off the volume -> none, clamped to it; its centre's block of 2^top voxels must be
    marked in ``coarse`` (flat, C order, one block of margin); then k = the least with 2^k >=
    the box's largest span, and the 8 corners' keys of the blocks of 2^k voxels are searched
    in the sorted keys of each size, the smallest size last: ``keys[offsets[s (top + 1) + k]:
    offsets[s (top + 1) + k + 1]]`` for size index s."""
    i = first + wp.tid()
    p = wp.cw_div(nodes[int(tets[4 * i])], spacing)
    plo = p
    phi = p
    for v in range(1, 4):
        q = wp.cw_div(nodes[int(tets[4 * i + v])], spacing)
        plo = wp.min(plo, q)
        phi = wp.max(phi, q)
    lo = wp.vec3i()
    hi = wp.vec3i()
    for a in range(3):
        l = wp.floor(plo[a] + wp.float64(0.5) + _VOXEL_TIE)  # (voxel_code's voxels)
        h = wp.floor(phi[a] + wp.float64(0.5) + _VOXEL_TIE)
        if h < wp.float64(0.0) or l >= wp.float64(shape[a]):
            return
        lo[a] = wp.max(int(l), 0)
        hi[a] = wp.min(int(h), shape[a] - 1)
    c0 = (((lo[0] + hi[0]) >> 1) >> top) + 1  # the centre's block, past the margin
    c1 = (((lo[1] + hi[1]) >> 1) >> top) + 1
    c2 = (((lo[2] + hi[2]) >> 1) >> top) + 1
    if coarse[(c0 * coarse_shape[1] + c1) * coarse_shape[2] + c2] == wp.uint8(0):
        return
    span = wp.max(wp.max(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2])
    k = int(0)
    while (1 << k) < span and k < top:  # top: blocks of 2^top voxels hold any box asked (Specks' largest)
        k += 1
    n0 = (shape[0] >> k) + 1
    n1 = (shape[1] >> k) + 1
    got = wp.float64(-1.0)
    for s0 in range(sizes.shape[0]):
        s = sizes.shape[0] - 1 - s0  # the largest first: the smallest hit wins
        a = offsets[s * (top + 1) + k]
        b = offsets[s * (top + 1) + k + 1]
        if b > a:
            hit = False
            for c in range(8):
                x = lo[0] >> k
                if (c & 4) != 0:
                    x = hi[0] >> k
                y = lo[1] >> k
                if (c & 2) != 0:
                    y = hi[1] >> k
                z = lo[2] >> k
                if (c & 1) != 0:
                    z = hi[2] >> k
                key = wp.int64(x) + wp.int64(n0) * (wp.int64(y) + wp.int64(n1) * wp.int64(z))
                if _sorted_has(keys, a, b, key):
                    hit = True
            if hit:
                got = sizes[s]
    if got >= wp.float64(0.0):
        out[i] = got


# ----------------------------------------------------------------------------------- lattice cleaving
_vec6l = wp.types.vector(length=6, dtype=wp.int64)


@wp.kernel
def cleave_fans_kernel(first: int, write: int, rows: int, tets: wp.array(dtype=wp.int64),
                       codes: wp.array(dtype=wp.int32), cut_id: wp.array(dtype=wp.int64),
                       cut_vertex: wp.array(dtype=wp.int64), face_vertex: wp.array(dtype=wp.int64),
                       tet_base: wp.int64, rest: int, faces: wp.array(dtype=wp.int32),
                       edge_of: wp.array(dtype=wp.int32), tet_at: wp.array(dtype=wp.int64),
                       tri_at: wp.array(dtype=wp.int64), out_tets: wp.array(dtype=wp.int64),
                       out_codes: wp.array(dtype=wp.int64), out_tris: wp.array(dtype=wp.int64),
                       out_lower: wp.array(dtype=wp.int64), out_upper: wp.array(dtype=wp.int64)):
    """One thread per cleaved tetrahedron r = first + tid of ``rows`` (``tets`` (rows, 4) node
    ids, ``codes`` their codes, ``cut_id`` (rows, 6) the cut of each local edge or -1,
    ``face_vertex`` (rows, 4) each face's point, -1 where the face has one code): the
    sub-tetrahedra from its tet point (``tet_base + r``) over its faces and the interface
    triangles between them. Face f (corners ``faces[3 f:3 f + 3]``) of one code gives one
    sub-tetrahedron (none for ``rest``); a face of several codes the fan of its face point over
    the face's polygon: per corner k -> k' the segments (k, x) and (x, k'), x the edge's cut
    point (``cut_vertex``; k' when uncut), of k's and k''s code, none where a segment is one
    point; where two consecutive segments' codes differ, the triangle (tet point, face point,
    their shared point) is an interface, oriented from the lower code's side.

    ``write`` 0 counts: ``tet_at[(2 f + kind) rows + r]`` the sub-tetrahedra of face f (kind 0
    of one code, 1 the fan) and ``tri_at[f rows + r]`` the triangles; ``write`` 1 writes them
    at those entries (exclusive prefix sums of the counts, so the output goes face by face,
    the one-code ones first, each in row order)."""
    r = first + wp.tid()
    tp = tet_base + wp.int64(r)
    for f in range(4):
        c0 = int(faces[3 * f])
        fv = face_vertex[4 * r + f]
        n_one = 0
        n_fan = 0
        n_tri = 0
        if fv < wp.int64(0):
            if codes[4 * r + c0] != rest:
                n_one = 1
                if write == 1:
                    at = tet_at[2 * f * rows + r]
                    o = wp.int64(4) * at
                    out_tets[o] = tp
                    out_tets[o + wp.int64(1)] = tets[4 * r + c0]
                    out_tets[o + wp.int64(2)] = tets[4 * r + int(faces[3 * f + 1])]
                    out_tets[o + wp.int64(3)] = tets[4 * r + int(faces[3 * f + 2])]
                    out_codes[at] = wp.int64(codes[4 * r + c0])
        else:
            start = _vec6l()
            end = _vec6l()
            code = _vec6l()
            for q in range(3):
                a = int(faces[3 * f + q])
                b = int(faces[3 * f + (q + 1) % 3])
                e = cut_id[6 * r + int(edge_of[4 * a + b])]
                x = tets[4 * r + b]
                if e >= wp.int64(0):
                    x = cut_vertex[e]
                start[2 * q] = tets[4 * r + a]
                end[2 * q] = x
                code[2 * q] = wp.int64(codes[4 * r + a])
                start[2 * q + 1] = x
                end[2 * q + 1] = tets[4 * r + b]
                code[2 * q + 1] = wp.int64(codes[4 * r + b])
            at = wp.int64(0)
            if write == 1:
                at = tet_at[(2 * f + 1) * rows + r]
            for s in range(6):
                if start[s] != end[s] and code[s] != wp.int64(rest):
                    if write == 1:
                        o = wp.int64(4) * at
                        out_tets[o] = tp
                        out_tets[o + wp.int64(1)] = fv
                        out_tets[o + wp.int64(2)] = start[s]
                        out_tets[o + wp.int64(3)] = end[s]
                        out_codes[at] = code[s]
                        at += wp.int64(1)
                    n_fan += 1
            j = wp.int64(0)
            if write == 1:
                j = tri_at[f * rows + r]
            for s in range(6):
                if start[s] != end[s]:
                    nxt = 0  # the next segment that is not a point, cyclically (there are at least three)
                    found = 0
                    for d in range(1, 6):
                        c = (s + d) % 6
                        if found == 0 and start[c] != end[c]:
                            nxt = c
                            found = 1
                    if code[s] != code[nxt]:
                        if write == 1:
                            o = wp.int64(3) * j
                            out_tris[o] = tp
                            if code[s] < code[nxt]:  # (tp, fv, end) is the outward face of the slot's sub-tetrahedron
                                out_tris[o + wp.int64(1)] = fv
                                out_tris[o + wp.int64(2)] = end[s]
                            else:
                                out_tris[o + wp.int64(1)] = end[s]
                                out_tris[o + wp.int64(2)] = fv
                            out_lower[j] = wp.min(code[s], code[nxt])
                            out_upper[j] = wp.max(code[s], code[nxt])
                            j += wp.int64(1)
                        n_tri += 1
        if write == 0:
            tet_at[2 * f * rows + r] = wp.int64(n_one)
            tet_at[(2 * f + 1) * rows + r] = wp.int64(n_fan)
            tri_at[f * rows + r] = wp.int64(n_tri)
