"""The block-sparse regular grid of an extraction [FG §16.4.1 exhaustive enumeration]:
block layout, interval culling, sampling, volume gathering and capping.

The grid of ``n = (nx, ny, nz)`` nodes is cut into blocks of ``BLOCK`` cells a side; a
block stores the values of its ``SIDE = BLOCK + 1`` nodes a side (faces shared with the
neighbours are stored twice). Blocks that cannot hold the surface are culled before any
point is evaluated; the others are compacted into *slots*.

Capping is per face of the grid: ``cap`` is a bit mask, bit ``2 a`` for the low face
of axis ``a`` and bit ``2 a + 1`` for its high face (a slab of a large volume caps only
the faces that are faces of the whole volume). Variable-size output is count -> prefix
sum -> allocate -> write. A thread works on one slot (a whole block); launches take
``first`` so the host can split them across cores. The surface itself is emitted by
:mod:`warpmesh.kernels.emit`.
"""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})  # forward only; node coordinates
# without FMA contraction, so every path computes them bit for bit alike

BLOCK = 8
SIDE = BLOCK + 1
NODES = SIDE * SIDE * SIDE  # values stored per block
CELLS = BLOCK * BLOCK * BLOCK
ALL_FACES = 0b111111  # cap mask: every face of the grid

_BLOCK = wp.constant(BLOCK)
_SIDE = wp.constant(SIDE)
_NODES = wp.constant(NODES)


@wp.func
def local_index(i: int, j: int, k: int):
    return i + _SIDE * (j + _SIDE * k)


@wp.func
def block_coords(b: int, nb: wp.vec3i):
    return wp.vec3i(b % nb[0], (b / nb[0]) % nb[1], b / (nb[0] * nb[1]))


@wp.kernel
def block_boxes_kernel(
    nb: wp.vec3i, n: wp.vec3i, origin: wp.vec3, h: wp.vec3, goff: wp.vec3i,
    box_lo: wp.array(dtype=wp.vec3), box_hi: wp.array(dtype=wp.vec3),
):
    """One thread: the axis-aligned box spanned by the nodes of one block (node g of the
    grid at origin + (g + goff) h, as ``node_point``)."""
    b = wp.tid()
    c = block_coords(b, nb)
    lo = wp.vec3(0.0)
    hi = wp.vec3(0.0)
    for a in range(3):
        g0 = c[a] * _BLOCK
        g1 = wp.min(g0 + _BLOCK, n[a] - 1)
        lo[a] = origin[a] + float(g0 + goff[a]) * h[a]
        hi[a] = origin[a] + float(g1 + goff[a]) * h[a]
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
    values: no evaluation needed); EVALUATE otherwise, and always when a bound is
    infinite or NaN (a node may be inf or NaN, which sampling reports)."""
    b = wp.tid()
    lo = intervals[b][0]
    hi = intervals[b][1]
    keep = EVALUATE
    if not (wp.isfinite(lo) and wp.isfinite(hi)):
        keep = EVALUATE
    elif hi < -rounding_slack(hi):
        keep = CULLED  # every node outside
    elif lo > rounding_slack(lo):
        keep = CULLED  # every node inside ...
        c = block_coords(b, nb)  # ... unless capping turns its nodes on a capped face out
        for a in range(3):
            if (c[a] == 0 and (cap >> (2 * a)) & 1 == 1) or \
                    (c[a] * _BLOCK + _BLOCK >= n[a] - 1 and (cap >> (2 * a + 1)) & 1 == 1):
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
def node_point(c: wp.vec3i, li: wp.vec3i, n: wp.vec3i, origin: wp.vec3, h: wp.vec3, goff: wp.vec3i):
    """Coordinates of local node li of the block at c (clamped into the grid); a grid that
    is a window of a larger one starting at its node goff passes that grid's origin, so
    its nodes get the larger grid's coordinates bit for bit (goff = 0 otherwise)."""
    p = wp.vec3(0.0)
    for a in range(3):
        g = wp.min(c[a] * _BLOCK + li[a], n[a] - 1)
        p[a] = origin[a] + float(g + goff[a]) * h[a]
    return p


@wp.kernel
def node_points_kernel(ids: wp.array(dtype=wp.int64), n: wp.vec3i, origin: wp.vec3, h: wp.vec3,
                       points: wp.array(dtype=wp.vec3)):
    """One thread per node id (i + nx (j + ny k)): its coordinates, as node_point computes them."""
    v = wp.tid()
    q = ids[v]
    nx = wp.int64(n[0])
    ny = wp.int64(n[1])
    g = wp.vec3i(int(q % nx), int((q / nx) % ny), int(q / (nx * ny)))
    points[v] = node_point(wp.vec3i(0, 0, 0), g, n, origin, h, wp.vec3i(0, 0, 0))


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
    goff: wp.vec3i, box_lo: wp.array(dtype=wp.vec3), box_hi: wp.array(dtype=wp.vec3),
):
    """One thread per (slot, sub-block): the box spanned by the sub-block's nodes."""
    s, q = wp.tid()
    c = block_coords(slot_block[s], nb)
    sq = wp.vec3i(q % _SUB_SIDE, (q / _SUB_SIDE) % _SUB_SIDE, q / (_SUB_SIDE * _SUB_SIDE))
    box_lo[s * _SUBS + q] = node_point(c, sq * _SUB, n, origin, h, goff)
    box_hi[s * _SUBS + q] = node_point(c, sq * _SUB + wp.vec3i(_SUB, _SUB, _SUB), n, origin, h, goff)


@wp.func
def sub_state(iv: wp.vec2):
    """0: the sub-block may hold the surface (or an infinite or NaN value: an interval
    with an infinite bound); +1 / -1: every node inside / outside."""
    r = int(0)
    if not (wp.isfinite(iv[0]) and wp.isfinite(iv[1])):
        r = 0
    elif iv[0] > rounding_slack(iv[0]):
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
    h: wp.vec3, goff: wp.vec3i, needs: wp.array(dtype=wp.int8), need_offset: wp.array(dtype=wp.int32),
    points: wp.array(dtype=wp.vec3),
):
    """One thread per slot: the coordinates of its nodes to evaluate, compacted."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    out = need_offset[s]
    for l in range(_NODES):
        if needs[s * _NODES + l] != wp.int8(0):
            points[out] = node_point(c, local_coords(l), n, origin, h, goff)
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


# -- a window: only some nodes are sampled (a brick's core and the node planes its seams read) ------
@wp.func
def owned_range(c: int, nb: int, n: int):
    """The nodes ``first, last`` (inclusive) that the block at c owns on one axis (the last
    block also owns the grid's far face)."""
    last = c * _BLOCK + _BLOCK - 1
    if c == nb - 1:
        last = n - 1
    return c * _BLOCK, last


@wp.func
def window_full(c: wp.vec3i, nb: wp.vec3i, n: wp.vec3i, boxes: wp.array(dtype=wp.vec3i)):
    """Whether the block at c meshes part of the window's first box (the cells it emits): it
    owns a node of it (an edge of its cells) or has a cell with all its corners in it. Such a
    block reads its own copies of its nodes' neighbours: it samples every copy in the window."""
    lo = boxes[0]
    hi = boxes[1]
    owns = int(1)
    cell = int(1)
    for a in range(3):
        first, last = owned_range(c[a], nb[a], n[a])
        if hi[a] < first or lo[a] > last:
            owns = 0
        if wp.min(c[a] * _BLOCK + _BLOCK - 1, n[a] - 2) < lo[a] or c[a] * _BLOCK > hi[a] - 1:
            cell = 0
    return owns == 1 or cell == 1


@wp.func
def window_covers(c: wp.vec3i, n: wp.vec3i, boxes: wp.array(dtype=wp.vec3i)):
    """Whether the window's first box holds every node copy of the block at c, with no padding
    beyond the grid: a core block of a brick, which samples every copy (nothing to drop)."""
    lo = boxes[0]
    hi = boxes[1]
    r = int(1)
    for a in range(3):
        if lo[a] > c[a] * _BLOCK or hi[a] < c[a] * _BLOCK + _BLOCK or c[a] * _BLOCK + _BLOCK > n[a] - 1:
            r = 0
    return r == 1


@wp.func
def window_range(c: wp.vec3i, nb: wp.vec3i, n: wp.vec3i, boxes: wp.array(dtype=wp.vec3i), m: int, full: bool):
    """(lo, hi) local node indices (inclusive, empty when lo > hi on an axis) of the copies in
    box m that the block at c samples: all its copies in the box when ``full``
    (``window_full``), else the box's nodes it owns (every other block reads them from it)."""
    lo = wp.vec3i(0, 0, 0)
    hi = wp.vec3i(0, 0, 0)
    for a in range(3):
        r0 = c[a] * _BLOCK
        r1 = wp.min(r0 + _BLOCK, n[a] - 1)
        if not full:
            r0, r1 = owned_range(c[a], nb[a], n[a])
        lo[a] = wp.max(boxes[2 * m][a], r0) - c[a] * _BLOCK
        hi[a] = wp.min(boxes[2 * m + 1][a], r1) - c[a] * _BLOCK
    return lo, hi


@wp.kernel
def window_blocks_kernel(
    nb: wp.vec3i, n: wp.vec3i, boxes: wp.array(dtype=wp.vec3i), state: wp.array(dtype=wp.int32),
):
    """One thread per block: CULLED unless the block owns a node of a window box (a node's
    owner is ``min(g // BLOCK, nb - 1)`` per axis, the block whose slot every other block
    reads it from)."""
    b = wp.tid()
    c = block_coords(b, nb)
    owns = int(0)
    for m in range(boxes.shape[0] / 2):
        lo = boxes[2 * m]
        hi = boxes[2 * m + 1]
        ok = int(1)
        for a in range(3):
            first, last = owned_range(c[a], nb[a], n[a])
            if hi[a] < first or lo[a] > last:
                ok = 0
        owns = wp.max(owns, ok)
    if owns == 0:
        state[b] = CULLED


@wp.kernel
def window_needs_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i,
    boxes: wp.array(dtype=wp.vec3i), fill: float, needs: wp.array(dtype=wp.int8),
    values: wp.array(dtype=wp.float32), need_count: wp.array(dtype=wp.int32), sampled: wp.array(dtype=wp.int8),
):
    """One thread per slot: marks the copies the block samples (``window_range`` of every box;
    all of them, unmarked, where ``window_covers``); a copy it does not sample is not
    evaluated (``fill`` where it still was to be); recounts the slot's nodes to evaluate."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    if window_covers(c, n, boxes):
        return
    full = window_full(c, nb, n, boxes)
    base = s * _NODES
    for l in range(_NODES):
        sampled[base + l] = wp.int8(0)
    for m in range(boxes.shape[0] / 2):
        lo, hi = window_range(c, nb, n, boxes, m, full)
        for k in range(lo[2], hi[2] + 1):
            for j in range(lo[1], hi[1] + 1):
                for i in range(lo[0], hi[0] + 1):
                    sampled[base + local_index(i, j, k)] = wp.int8(1)
    count = int(0)
    for l in range(_NODES):
        if needs[base + l] != wp.int8(0):
            if sampled[base + l] != wp.int8(0):
                count += 1
            else:
                needs[base + l] = wp.int8(0)
                values[base + l] = fill
    need_count[s] = count


@wp.kernel
def window_fill_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i,
    boxes: wp.array(dtype=wp.vec3i), sampled: wp.array(dtype=wp.int8), values: wp.array(dtype=wp.float32),
):
    """One thread per slot, after sampling: every copy the block does not sample
    (``window_needs_kernel``'s marks) takes the value of one it does, the node clamped into
    the first box the block samples copies of. A block around a node plane of one sign is
    then of one sign everywhere, and emits nothing (``kernels.emit.count_crossings_kernel``)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    if window_covers(c, n, boxes):
        return
    full = window_full(c, nb, n, boxes)
    base = s * _NODES
    src_lo = wp.vec3i(0, 0, 0)
    src_hi = wp.vec3i(-1, -1, -1)
    found = int(0)
    for m in range(boxes.shape[0] / 2):
        lo, hi = window_range(c, nb, n, boxes, m, full)
        if found == 0 and lo[0] <= hi[0] and lo[1] <= hi[1] and lo[2] <= hi[2]:
            src_lo = lo
            src_hi = hi
            found = 1
    if found == 1:
        for l in range(_NODES):
            if sampled[base + l] == wp.int8(0):
                q = local_coords(l)
                values[base + l] = values[base + local_index(wp.clamp(q[0], src_lo[0], src_hi[0]),
                                                             wp.clamp(q[1], src_lo[1], src_hi[1]),
                                                             wp.clamp(q[2], src_lo[2], src_hi[2]))]


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
def on_capped_face(g: wp.vec3i, n: wp.vec3i, cap: int):
    """Whether node g lies on a face of the grid that the mask ``cap`` caps."""
    r = False
    for a in range(3):
        if (g[a] == 0 and (cap >> (2 * a)) & 1 == 1) or (g[a] == n[a] - 1 and (cap >> (2 * a + 1)) & 1 == 1):
            r = True
    return r


@wp.kernel
def check_cap_values_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i, cap: int,
    values: wp.array(dtype=wp.float32), bad: wp.array(dtype=wp.int32),
):
    """One thread per slot: count non-finite values (into bad[slot]); cap the grid faces in the
    mask ``cap`` (their inside nodes become 0, i.e. outside, so every surface closes there)."""
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
                    if on_capped_face(g, n, cap):
                        values[idx] = 0.0
    bad[s] = n_bad


@wp.kernel
def trilinear_value_gradient_kernel(
    values: wp.array3d(dtype=wp.float64), origin: wp.vec3d, spacing: wp.vec3d,
    points: wp.array(dtype=wp.vec3d), f: wp.array(dtype=wp.float64), grad: wp.array(dtype=wp.vec3d),
):
    """Trilinear interpolant of node values (``values[i, j, k]`` at ``origin + (i, j, k) *
    spacing``) and its gradient at each point; points outside use the nearest cell's
    polynomial with the local coordinates clamped to it (the field is constant beyond)."""
    tid = wp.tid()
    q = points[tid] - origin
    n = wp.vec3i(values.shape[0], values.shape[1], values.shape[2])
    ix = wp.clamp(int(wp.floor(q[0] / spacing[0])), 0, n[0] - 2)
    iy = wp.clamp(int(wp.floor(q[1] / spacing[1])), 0, n[1] - 2)
    iz = wp.clamp(int(wp.floor(q[2] / spacing[2])), 0, n[2] - 2)
    tx = wp.clamp(q[0] / spacing[0] - wp.float64(ix), wp.float64(0.0), wp.float64(1.0))
    ty = wp.clamp(q[1] / spacing[1] - wp.float64(iy), wp.float64(0.0), wp.float64(1.0))
    tz = wp.clamp(q[2] / spacing[2] - wp.float64(iz), wp.float64(0.0), wp.float64(1.0))
    one = wp.float64(1.0)
    c000 = values[ix, iy, iz]
    c001 = values[ix, iy, iz + 1]
    c010 = values[ix, iy + 1, iz]
    c011 = values[ix, iy + 1, iz + 1]
    c100 = values[ix + 1, iy, iz]
    c101 = values[ix + 1, iy, iz + 1]
    c110 = values[ix + 1, iy + 1, iz]
    c111 = values[ix + 1, iy + 1, iz + 1]
    # along x, then y, then z
    c00 = c000 * (one - tx) + c100 * tx
    c01 = c001 * (one - tx) + c101 * tx
    c10 = c010 * (one - tx) + c110 * tx
    c11 = c011 * (one - tx) + c111 * tx
    c0 = c00 * (one - ty) + c10 * ty
    c1 = c01 * (one - ty) + c11 * ty
    f[tid] = c0 * (one - tz) + c1 * tz
    d00 = c100 - c000
    d01 = c101 - c001
    d10 = c110 - c010
    d11 = c111 - c011
    gx = (d00 * (one - ty) + d10 * ty) * (one - tz) + (d01 * (one - ty) + d11 * ty) * tz
    gy = (c10 - c00) * (one - tz) + (c11 - c01) * tz
    gz = c1 - c0
    grad[tid] = wp.vec3d(gx / spacing[0], gy / spacing[1], gz / spacing[2])
