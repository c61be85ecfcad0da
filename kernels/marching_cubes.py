"""Marching cubes over a block-sparse regular grid (seed §16.4.1 exhaustive enumeration,
§16.4.2 marching cubes).

The grid of ``n = (nx, ny, nz)`` nodes is cut into blocks of ``BLOCK`` cells a side; a
block stores the values of its ``SIDE = BLOCK + 1`` nodes a side (faces shared with the
neighbours are stored twice). Blocks that cannot hold the surface are culled before any
point is evaluated; the others are compacted into *slots*.

Every grid edge has exactly one owner block, the block of its origin node
(``owner = min(g // BLOCK, nb - 1)`` per axis), and that block creates the single
vertex of the edge when it crosses the surface, so the output is welded by construction.
Variable-size output is count -> prefix sum -> allocate -> write. A thread works on one
slot (a whole block); launches take ``first`` so the host can split them across cores.
"""

import numpy as np
import warp as wp

from warpmesh.kernels import mc_tables as T

wp.set_module_options({"enable_backward": False})  # forward evaluation only: halves the compile

BLOCK = 8
SIDE = BLOCK + 1
NODES = SIDE * SIDE * SIDE  # values stored per block
EDGE_SLOTS = NODES * 3  # edge -> vertex ids stored per block

_BLOCK = wp.constant(BLOCK)
_SIDE = wp.constant(SIDE)
_NODES = wp.constant(NODES)
_CELLS = wp.constant(BLOCK * BLOCK * BLOCK)
_EDGE_SLOTS = wp.constant(EDGE_SLOTS)
_MAX_TRIS = wp.constant(int(T.MAX_TRIS))

TABLE_ARRAYS = {
    "corners": np.ascontiguousarray(T.CORNERS, dtype=np.int32),
    "edge_origin": np.ascontiguousarray(T.EDGE_ORIGIN, dtype=np.int32),
    "tri_count": np.ascontiguousarray(T.TRI_COUNT, dtype=np.int32),
    "tri_table": np.ascontiguousarray(T.TRI_TABLE.reshape(256, -1), dtype=np.int32),
}


@wp.func
def local_index(i: int, j: int, k: int):
    return i + _SIDE * (j + _SIDE * k)


@wp.func
def block_coords(b: int, nb: wp.vec3i):
    return wp.vec3i(b % nb[0], (b / nb[0]) % nb[1], b / (nb[0] * nb[1]))


@wp.kernel
def block_boxes_kernel(
    nb: wp.vec3i, n: wp.vec3i, origin: wp.vec3, h: wp.vec3,
    box_lo: wp.array(dtype=wp.vec3), box_hi: wp.array(dtype=wp.vec3),
):
    """One thread: the axis-aligned box spanned by the nodes of one block."""
    b = wp.tid()
    c = block_coords(b, nb)
    lo = wp.vec3(0.0)
    hi = wp.vec3(0.0)
    for a in range(3):
        g0 = c[a] * _BLOCK
        g1 = wp.min(g0 + _BLOCK, n[a] - 1)
        lo[a] = origin[a] + float(g0) * h[a]
        hi[a] = origin[a] + float(g1) * h[a]
    box_lo[b] = lo
    box_hi[b] = hi


CULLED = wp.constant(0)
EVALUATE = wp.constant(1)
INSIDE = wp.constant(2)


@wp.func
def rounding_slack(bound: float):
    """How far a float32 point evaluation may stray past an interval bound near it."""
    return 1.0e-4 * wp.abs(bound) + 1.0e-7


@wp.kernel
def cull_blocks_kernel(
    nb: wp.vec3i, n: wp.vec3i, cap: int, intervals: wp.array(dtype=wp.vec2),
    state: wp.array(dtype=wp.int32),
):
    """One thread per block, from an interval enclosing f over it: CULLED when no node can
    change sign; INSIDE when every node is inside but the block touches the capped grid
    boundary (its crossings are the cap's, whose vertices do not depend on the inside
    values: no evaluation needed); EVALUATE otherwise."""
    b = wp.tid()
    lo = intervals[b][0]
    hi = intervals[b][1]
    keep = EVALUATE
    if hi < -rounding_slack(hi):
        keep = CULLED  # every node outside
    elif lo > rounding_slack(lo):
        keep = CULLED  # every node inside ...
        if cap != 0:  # ... unless capping at the grid boundary turns its boundary nodes out
            c = block_coords(b, nb)
            for a in range(3):
                if c[a] == 0 or c[a] * _BLOCK + _BLOCK >= n[a] - 1:
                    keep = INSIDE
    state[b] = keep


@wp.kernel
def compact_blocks_kernel(
    state: wp.array(dtype=wp.int32), evaluate_offsets: wp.array(dtype=wp.int32),
    inside_offsets: wp.array(dtype=wp.int32), n_evaluate: int,
    slot_block: wp.array(dtype=wp.int32), block_slot: wp.array(dtype=wp.int32),
):
    """One thread per block: its slot (-1 when culled); EVALUATE blocks take the first
    slots, INSIDE blocks the ones after them."""
    b = wp.tid()
    s = int(-1)
    if state[b] == EVALUATE:
        s = evaluate_offsets[b]
    elif state[b] == INSIDE:
        s = n_evaluate + inside_offsets[b]
    if s >= 0:
        slot_block[s] = b
    block_slot[b] = s


@wp.kernel
def flag_state_kernel(state: wp.array(dtype=wp.int32), which: int, flags: wp.array(dtype=wp.int32)):
    """One thread per block: 1 where state == which (input of a prefix sum)."""
    b = wp.tid()
    flags[b] = wp.where(state[b] == which, 1, 0)


@wp.kernel
def fill_values_kernel(first: int, value: float, values: wp.array(dtype=wp.float32)):
    """One thread per value from slot ``first`` on: a constant (inside blocks: +1)."""
    i = wp.tid()
    values[first * _NODES + i] = value


@wp.func
def node_point(c: wp.vec3i, li: wp.vec3i, n: wp.vec3i, origin: wp.vec3, h: wp.vec3):
    """Coordinates of local node li of the block at c (clamped into the grid)."""
    p = wp.vec3(0.0)
    for a in range(3):
        g = wp.min(c[a] * _BLOCK + li[a], n[a] - 1)
        p[a] = origin[a] + float(g) * h[a]
    return p


@wp.func
def local_coords(l: int):
    return wp.vec3i(l % _SIDE, (l / _SIDE) % _SIDE, l / (_SIDE * _SIDE))


# -- second level: sub-blocks of SUB^3 cells inside the blocks left to evaluate ------------------
SUB = 4
SUBS = (BLOCK // SUB) ** 3  # sub-blocks per block
_SUB = wp.constant(SUB)
_SUB_SIDE = wp.constant(BLOCK // SUB)
_SUBS = wp.constant(SUBS)


@wp.kernel
def sub_boxes_kernel(
    slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i, origin: wp.vec3, h: wp.vec3,
    box_lo: wp.array(dtype=wp.vec3), box_hi: wp.array(dtype=wp.vec3),
):
    """One thread per (slot, sub-block): the box spanned by the sub-block's nodes."""
    s, q = wp.tid()
    c = block_coords(slot_block[s], nb)
    sq = wp.vec3i(q % _SUB_SIDE, (q / _SUB_SIDE) % _SUB_SIDE, q / (_SUB_SIDE * _SUB_SIDE))
    box_lo[s * _SUBS + q] = node_point(c, sq * _SUB, n, origin, h)
    box_hi[s * _SUBS + q] = node_point(c, sq * _SUB + wp.vec3i(_SUB, _SUB, _SUB), n, origin, h)


@wp.func
def sub_state(iv: wp.vec2):
    """0: the sub-block may hold the surface; +1 / -1: every node inside / outside."""
    r = int(0)
    if iv[0] > rounding_slack(iv[0]):
        r = 1
    elif iv[1] < -rounding_slack(iv[1]):
        r = -1
    return r


@wp.func
def node_need(states: wp.array(dtype=wp.int32), base: int, li: wp.vec3i):
    """(need, fill) of a node from the states of the up to 2 x 2 x 2 sub-blocks whose
    closure holds it: evaluate it if any may hold the surface, else fill with the sign."""
    need = int(0)
    fill = float(-1.0)
    for q in range(8):
        sq = wp.vec3i(0, 0, 0)
        ok = True
        for a in range(3):
            k = li[a] / _SUB
            if (q >> a) & 1 == 1:
                if li[a] % _SUB != 0 or li[a] == 0:
                    ok = False
                k = (li[a] - 1) / _SUB
            sq[a] = wp.min(k, _SUB_SIDE - 1)
        if ok:
            st = states[base + sq[0] + _SUB_SIDE * (sq[1] + _SUB_SIDE * sq[2])]
            if st == 0:
                need = 1
            elif st > 0:
                fill = 1.0
    return need, fill


@wp.kernel
def node_needs_kernel(
    first: int, intervals: wp.array(dtype=wp.vec2), states: wp.array(dtype=wp.int32),
    values: wp.array(dtype=wp.float32), needs: wp.array(dtype=wp.int8),
    need_count: wp.array(dtype=wp.int32),
):
    """One thread per slot: which nodes must be evaluated (a sub-block holding them may
    contain the surface); the others get the sign their sub-blocks' intervals prove
    (cells of settled sub-blocks hold no crossing). Counts the nodes to evaluate."""
    s = wp.tid() + first
    for q in range(_SUBS):
        states[s * _SUBS + q] = sub_state(intervals[s * _SUBS + q])
    count = int(0)
    for l in range(_NODES):
        need, fill = node_need(states, s * _SUBS, local_coords(l))
        needs[s * _NODES + l] = wp.int8(need)
        if need == 0:
            values[s * _NODES + l] = fill
        count += need
    need_count[s] = count


@wp.kernel
def needed_points_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i, origin: wp.vec3,
    h: wp.vec3, needs: wp.array(dtype=wp.int8), need_offset: wp.array(dtype=wp.int32),
    points: wp.array(dtype=wp.vec3),
):
    """One thread per slot: the coordinates of its nodes to evaluate, compacted."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    out = need_offset[s]
    for l in range(_NODES):
        if needs[s * _NODES + l] != wp.int8(0):
            points[out] = node_point(c, local_coords(l), n, origin, h)
            out += 1


@wp.kernel
def scatter_values_kernel(
    first: int, needs: wp.array(dtype=wp.int8), need_offset: wp.array(dtype=wp.int32),
    compact: wp.array(dtype=wp.float32), values: wp.array(dtype=wp.float32),
):
    """One thread per slot: the evaluated values back into the block layout."""
    s = wp.tid() + first
    k = need_offset[s]
    for l in range(_NODES):
        if needs[s * _NODES + l] != wp.int8(0):
            values[s * _NODES + l] = compact[k]
            k += 1


@wp.kernel
def gather_volume_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, volume: wp.array3d(dtype=wp.float32),
    level: float, sign: float, values: wp.array(dtype=wp.float32),
):
    """One thread per slot: sign * (volume - level) at the block's nodes (clamped into
    the volume), in the block layout."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    for k in range(_SIDE):
        kk = wp.min(c[2] * _BLOCK + k, volume.shape[2] - 1)
        for j in range(_SIDE):
            jj = wp.min(c[1] * _BLOCK + j, volume.shape[1] - 1)
            for i in range(_SIDE):
                ii = wp.min(c[0] * _BLOCK + i, volume.shape[0] - 1)
                values[s * _NODES + local_index(i, j, k)] = sign * (volume[ii, jj, kk] - level)


@wp.kernel
def volume_block_range_kernel(
    first: int, nb: wp.vec3i, volume: wp.array3d(dtype=wp.float32), level: float, sign: float,
    intervals: wp.array(dtype=wp.vec2), bad: wp.array(dtype=wp.int32),
):
    """One thread per block: exact (min, max) of sign * (volume - level) over its nodes
    (k innermost: contiguous reads of a C-order array); non-finite samples into bad[block]."""
    b = wp.tid() + first
    c = block_coords(b, nb)
    lo = float(3.4e38)
    hi = float(-3.4e38)
    n_bad = int(0)
    k0 = c[2] * _BLOCK
    k1 = wp.min(k0 + _SIDE, volume.shape[2])
    for i in range(c[0] * _BLOCK, wp.min(c[0] * _BLOCK + _SIDE, volume.shape[0])):
        for j in range(c[1] * _BLOCK, wp.min(c[1] * _BLOCK + _SIDE, volume.shape[1])):
            for k in range(k0, k1):
                v = volume[i, j, k]
                lo = wp.min(lo, v)
                hi = wp.max(hi, v)
                if v - v != 0.0:  # NaN or infinite
                    n_bad += 1
    bad[b] = n_bad
    a = sign * (lo - level)
    z = sign * (hi - level)
    intervals[b] = wp.vec2(wp.min(a, z), wp.max(a, z))


@wp.func
def on_grid_boundary(g: wp.vec3i, n: wp.vec3i):
    r = False
    for a in range(3):
        if g[a] == 0 or g[a] == n[a] - 1:
            r = True
    return r


@wp.kernel
def check_cap_values_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i, cap: int,
    values: wp.array(dtype=wp.float32), bad: wp.array(dtype=wp.int32),
):
    """One thread per slot: count non-finite values (into bad[slot]); cap the grid boundary (boundary
    nodes become outside, so every surface closes on the bounds)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    hi = wp.vec3i(0, 0, 0)
    for a in range(3):
        hi[a] = wp.min(_BLOCK, n[a] - 1 - c[a] * _BLOCK)  # padding nodes beyond: never read
    n_bad = int(0)
    for k in range(hi[2] + 1):
        for j in range(hi[1] + 1):
            for i in range(hi[0] + 1):
                idx = s * _NODES + local_index(i, j, k)
                v = values[idx]
                if not wp.isfinite(v):
                    n_bad += 1
                elif cap != 0 and v > 0.0:
                    g = wp.vec3i(c[0] * _BLOCK + i, c[1] * _BLOCK + j, c[2] * _BLOCK + k)
                    if on_grid_boundary(g, n):
                        values[idx] = 0.0
    bad[s] = n_bad


@wp.func
def owned_hi(c: int, nb: int, n: int):
    """Highest local node index (inclusive) of the nodes a block owns along one axis."""
    hi = _BLOCK - 1
    if c == nb - 1:
        hi = _BLOCK
    return wp.min(hi, n - 1 - c * _BLOCK)


@wp.func
def cube_index(values: wp.array(dtype=wp.float32), base: int, i: int, j: int, k: int,
               corners: wp.array2d(dtype=wp.int32)):
    ci = int(0)
    for q in range(8):
        v = values[base + local_index(i + corners[q, 0], j + corners[q, 1], k + corners[q, 2])]
        if v > 0.0:
            ci = ci | (1 << q)
    return ci


@wp.kernel
def count_crossings_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i,
    values: wp.array(dtype=wp.float32), corners: wp.array2d(dtype=wp.int32),
    tri_count: wp.array(dtype=wp.int32),
    vertex_count: wp.array(dtype=wp.int32), triangle_count: wp.array(dtype=wp.int32),
    cube_indices: wp.array(dtype=wp.uint8),
):
    """One thread per slot: crossing edges the block owns, and triangles of its cells
    (their cube indices are kept for the triangle pass)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    base = s * _NODES
    nv = int(0)
    hx = owned_hi(c[0], nb[0], n[0])
    hy = owned_hi(c[1], nb[1], n[1])
    hz = owned_hi(c[2], nb[2], n[2])
    for k in range(hz + 1):
        for j in range(hy + 1):
            for i in range(hx + 1):
                inside = values[base + local_index(i, j, k)] > 0.0
                if c[0] * _BLOCK + i < n[0] - 1:
                    if (values[base + local_index(i + 1, j, k)] > 0.0) != inside:
                        nv += 1
                if c[1] * _BLOCK + j < n[1] - 1:
                    if (values[base + local_index(i, j + 1, k)] > 0.0) != inside:
                        nv += 1
                if c[2] * _BLOCK + k < n[2] - 1:
                    if (values[base + local_index(i, j, k + 1)] > 0.0) != inside:
                        nv += 1
    nt = int(0)
    cx = wp.min(_BLOCK, n[0] - 1 - c[0] * _BLOCK)
    cy = wp.min(_BLOCK, n[1] - 1 - c[1] * _BLOCK)
    cz = wp.min(_BLOCK, n[2] - 1 - c[2] * _BLOCK)
    for k in range(cz):
        for j in range(cy):
            for i in range(cx):
                ci = cube_index(values, base, i, j, k, corners)
                cube_indices[s * _CELLS + i + _BLOCK * (j + _BLOCK * k)] = wp.uint8(ci)
                nt += tri_count[ci]
    vertex_count[s] = nv
    triangle_count[s] = nt


@wp.func
def edge_vertex(values: wp.array(dtype=wp.float32), base: int, i: int, j: int, k: int,
                a: int, origin: wp.vec3, h: wp.vec3, g: wp.vec3i, t_min: float):
    """(position, t, inside end, outside end) of the crossing on edge (i,j,k)+axis a."""
    e = wp.vec3i(0, 0, 0)
    e[a] = 1
    v0 = values[base + local_index(i, j, k)]
    v1 = values[base + local_index(i + e[0], j + e[1], k + e[2])]
    t = wp.clamp(v0 / (v0 - v1), t_min, 1.0 - t_min)
    p0 = wp.vec3(origin[0] + float(g[0]) * h[0], origin[1] + float(g[1]) * h[1],
                 origin[2] + float(g[2]) * h[2])
    p1 = p0
    p1[a] = p1[a] + h[a]
    return p0 + t * (p1 - p0), t, p0, p1


@wp.kernel
def emit_vertices_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i,
    origin: wp.vec3, h: wp.vec3, t_min: float,
    values: wp.array(dtype=wp.float32), vertex_offset: wp.array(dtype=wp.int32),
    edge_vertex_id: wp.array(dtype=wp.int32), points: wp.array(dtype=wp.vec3),
    edge_t: wp.array(dtype=wp.float32), edge_p0: wp.array(dtype=wp.vec3),
    edge_p1: wp.array(dtype=wp.vec3), edge_flags: wp.array(dtype=wp.int32),
):
    """One thread per slot: place the vertex of every crossing edge the block owns by
    linear interpolation (eq. 16.12), t clamped to [t_min, 1 - t_min]; remember the
    edge so a root finder can refine it. Flags: bit 0 = first end inside, bit 1 = an
    end has the value 0 exactly (on the surface, or capped: keep the clamped t), bit 2 =
    that end is on the grid boundary (a cap vertex when capping)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    base = s * _NODES
    vid = vertex_offset[s]
    hx = owned_hi(c[0], nb[0], n[0])
    hy = owned_hi(c[1], nb[1], n[1])
    hz = owned_hi(c[2], nb[2], n[2])
    for k in range(hz + 1):
        for j in range(hy + 1):
            for i in range(hx + 1):
                l = local_index(i, j, k)
                v0 = values[base + l]
                inside = v0 > 0.0
                g = wp.vec3i(c[0] * _BLOCK + i, c[1] * _BLOCK + j, c[2] * _BLOCK + k)
                for a in range(3):
                    if g[a] < n[a] - 1:
                        e = wp.vec3i(0, 0, 0)
                        e[a] = 1
                        v1 = values[base + local_index(i + e[0], j + e[1], k + e[2])]
                        if (v1 > 0.0) != inside:
                            p, t, p0, p1 = edge_vertex(values, base, i, j, k, a, origin, h, g, t_min)
                            points[vid] = p
                            edge_t[vid] = t
                            edge_p0[vid] = p0
                            edge_p1[vid] = p1
                            flags = int(0)
                            if inside:
                                flags = 1
                            if v0 == 0.0 or v1 == 0.0:
                                flags = flags | 2
                                if on_grid_boundary(g, n) or on_grid_boundary(g + e, n):
                                    flags = flags | 4  # a capped (or zero) boundary end
                            edge_flags[vid] = flags
                            edge_vertex_id[s * _EDGE_SLOTS + l * 3 + a] = vid
                            vid += 1


@wp.kernel
def emit_triangles_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), block_slot: wp.array(dtype=wp.int32),
    nb: wp.vec3i, n: wp.vec3i, cube_indices: wp.array(dtype=wp.uint8),
    edge_origin: wp.array2d(dtype=wp.int32),
    tri_count: wp.array(dtype=wp.int32), tri_table: wp.array2d(dtype=wp.int32),
    triangle_offset: wp.array(dtype=wp.int32), edge_vertex_id: wp.array(dtype=wp.int32),
    points: wp.array(dtype=wp.vec3),
    triangles: wp.array(dtype=wp.vec3i), slot_volume: wp.array(dtype=wp.float64),
):
    """One thread per slot: the table's triangles of every cell of the block, with vertex
    ids looked up at the owner block of each edge; and the block's share of the signed
    volume they enclose (six times p0 . (p1 x p2), summed: the host checks the winding)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    out = triangle_offset[s]
    vol = wp.float64(0.0)
    cx = wp.min(_BLOCK, n[0] - 1 - c[0] * _BLOCK)
    cy = wp.min(_BLOCK, n[1] - 1 - c[1] * _BLOCK)
    cz = wp.min(_BLOCK, n[2] - 1 - c[2] * _BLOCK)
    for k in range(cz):
        for j in range(cy):
            for i in range(cx):
                ci = int(cube_indices[s * _CELLS + i + _BLOCK * (j + _BLOCK * k)])
                for q in range(tri_count[ci]):
                    tri = wp.vec3i(0, 0, 0)
                    for m in range(3):
                        e = tri_table[ci, q * 3 + m]
                        g = wp.vec3i(c[0] * _BLOCK + i + edge_origin[e, 0],
                                     c[1] * _BLOCK + j + edge_origin[e, 1],
                                     c[2] * _BLOCK + k + edge_origin[e, 2])
                        ob = wp.vec3i(0, 0, 0)
                        lo = wp.vec3i(0, 0, 0)
                        for a in range(3):
                            ob[a] = wp.min(g[a] / _BLOCK, nb[a] - 1)
                            lo[a] = g[a] - ob[a] * _BLOCK
                        os = block_slot[ob[0] + nb[0] * (ob[1] + nb[1] * ob[2])]
                        vid = int(-1)  # stays -1 if the owner was culled: the host refuses it
                        if os >= 0:
                            vid = edge_vertex_id[os * _EDGE_SLOTS + local_index(lo[0], lo[1], lo[2]) * 3
                                                 + edge_origin[e, 3]]
                        tri[m] = vid
                    triangles[out] = tri
                    out += 1
                    if tri[0] >= 0 and tri[1] >= 0 and tri[2] >= 0:
                        vol += wp.float64(wp.dot(points[tri[0]], wp.cross(points[tri[1]], points[tri[2]])))
    slot_volume[s] = vol


# -- root refinement along crossing edges (seed §16.3.3) ------------------------------------
@wp.kernel
def edge_points_kernel(
    t: wp.array(dtype=wp.float32), p0: wp.array(dtype=wp.vec3), p1: wp.array(dtype=wp.vec3),
    origin: wp.vec3, points: wp.array(dtype=wp.vec3),
):
    """One thread per vertex: origin + p0 + t (p1 - p0) (edge ends are grid-local)."""
    v = wp.tid()
    points[v] = origin + p0[v] + t[v] * (p1[v] - p0[v])


@wp.kernel
def bracket_init_kernel(
    flags: wp.array(dtype=wp.int32), midpoint: int, t_lo: wp.array(dtype=wp.float32),
    t_hi: wp.array(dtype=wp.float32), t: wp.array(dtype=wp.float32),
):
    """One thread per vertex: the bracket [0, 1] of the edge parameter; start at its
    midpoint (bisection) or keep the linear estimate (Newton)."""
    v = wp.tid()
    t_lo[v] = 0.0
    t_hi[v] = 1.0
    if midpoint != 0 and (flags[v] & 2) == 0:
        t[v] = 0.5


@wp.kernel
def bisection_step_kernel(
    flags: wp.array(dtype=wp.int32), f_mid: wp.array(dtype=wp.float32),
    t_lo: wp.array(dtype=wp.float32), t_hi: wp.array(dtype=wp.float32), t: wp.array(dtype=wp.float32),
):
    """One thread per vertex: keep the half of the bracket where f changes sign. The end
    at t_lo is the p0 end; 'inside' is f > 0, as in the classification, so a sub-segment
    where f vanishes is kept on the side of the outside end (seed Fig. 16.9)."""
    v = wp.tid()
    if (flags[v] & 2) != 0:
        return
    p0_inside = (flags[v] & 1) != 0
    if f_mid[v] == 0.0:  # an exact root: the bracket collapses onto it
        t_lo[v] = t[v]
        t_hi[v] = t[v]
        return
    if (f_mid[v] > 0.0) == p0_inside:
        t_lo[v] = t[v]
    else:
        t_hi[v] = t[v]
    t[v] = 0.5 * (t_lo[v] + t_hi[v])


@wp.kernel
def newton_step_kernel(
    flags: wp.array(dtype=wp.int32), fg: wp.array(dtype=wp.vec4), p0: wp.array(dtype=wp.vec3),
    p1: wp.array(dtype=wp.vec3), t_lo: wp.array(dtype=wp.float32), t_hi: wp.array(dtype=wp.float32),
    f_prev: wp.array(dtype=wp.float32), t: wp.array(dtype=wp.float32),
):
    """One thread per vertex: a safeguarded Newton step on g(t) = f(p0 + t (p1 - p0)):
    bisect instead when Newton would leave the sign-change bracket, or when a step that
    has not converged did not at least halve |g| (Newton stalls at the kinks of CSG edges)."""
    v = wp.tid()
    if (flags[v] & 2) != 0:
        return
    p0_inside = (flags[v] & 1) != 0
    f = fg[v][0]
    if f == 0.0:  # an exact root: the bracket collapses onto it
        t_lo[v] = t[v]
        t_hi[v] = t[v]
        return
    if (f > 0.0) == p0_inside:
        t_lo[v] = t[v]
    else:
        t_hi[v] = t[v]
    slope = wp.dot(wp.vec3(fg[v][1], fg[v][2], fg[v][3]), p1[v] - p0[v])
    tn = t_lo[v] - 1.0  # invalid unless the Newton step below is taken
    if slope != 0.0:
        tn = t[v] - f / slope
        # converged steps are always taken (a bisection from a one-sided bracket would
        # throw the root away); others only while |f| at least halves
        if wp.abs(tn - t[v]) > 1.0e-5 and 2.0 * wp.abs(f) > f_prev[v]:
            tn = t_lo[v] - 1.0
    f_prev[v] = wp.abs(f)
    if tn > t_lo[v] and tn < t_hi[v]:
        t[v] = tn
    else:
        t[v] = 0.5 * (t_lo[v] + t_hi[v])


@wp.kernel
def clamp_edge_t_kernel(t_min: float, t: wp.array(dtype=wp.float32)):
    """One thread per vertex: t into [t_min, 1 - t_min] (no vertex on a grid node)."""
    v = wp.tid()
    t[v] = wp.clamp(t[v], t_min, 1.0 - t_min)
