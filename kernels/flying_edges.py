"""Dense extraction of a sampled volume row by row, after flying edges (Schroeder,
Maynard & Geveci 2015) [FG §16.4.1-16.4.2]: "mc" and "mc33" with the tables of
:mod:`warpmesh.kernels.emit`, the same vertices and triangles as its block emission.

The volume ``volume[i, j, k]`` (C order: k contiguous) is read in place, a *row* being
the samples of one (i, j), ``r = i * n1 + j``. A node's value is ``sign * (raw - level)``
in float32, capped (0, i.e. outside, where an inside node lies on a capped face of the
grid: bit ``2 a`` / ``2 a + 1`` of ``cap`` for the low / high face of axis a), with
``raw`` the float32 sample (mode 0), the uint8 sample (mode 1) or the indicator of
``label`` in a uint8 volume (mode 2). Edge types are those of ``emit.TYPE_DELTA``: 0
towards row (i + 1, j), 1 towards row (i, j + 1), 2 along the row.

1. ``classify_rows_kernel`` reads every sample once: each row's node classes (inside:
   value > 0) packed 64 to a word (bit b of word w is node k = 64 w + b; ``WORD_BITS``),
   its raw value range and its non-finite samples.
2. ``count_rows_kernel``, on the words alone: per node row its crossing edges of each
   type (bit counts of xors), per cell row (the cells between rows (i, j), (i + 1, j),
   (i, j + 1), (i + 1, j + 1)) the triangles and interior vertices of the cells whose
   eight corners are not all alike (a word of such cells at a time: the others are
   skipped 64 at once, where flying edges trims each row at its first and last crossing).
3. The host's prefix sums give each row its first vertex and triangle.
4. ``emit_row_vertices_kernel`` places each row's vertices, type 0 then 1 then 2, each in
   k order; ``emit_row_triangles_kernel`` numbers a cell's edge vertices by counting the
   crossings before it in the edge's row (nothing to look up, nothing to weld).

Values are read only where an edge crosses (and at the corners of crossed cells for
"mc33"). One thread works on one row; launches take ``first`` so the host can split
them across cores.
"""

from typing import Any

import warp as wp

from warpmesh.kernels.block_grid import on_capped_face
from warpmesh.kernels.emit import (
    Tables,
    interior_count,
    mc33_entry,
    mc33_hub,
    spoke_point,
    trilinear,
    vec8d,
)
from warpmesh.kernels.emit import mc33_row as table_row

wp.set_module_options({"enable_backward": False, "fuse_fp": False})  # bit for bit as kernels.emit

MODE_FLOAT = 0  # float32 samples
MODE_UINT8 = 1  # uint8 samples, their values
MODE_LABEL = 2  # uint8 samples, the indicator of one label
WORD_BITS = 64  # node classes per word

_METHOD_MC33 = wp.constant(1)  # emit.METHOD_MC33
_CENTER = wp.constant(7)  # emit.CENTER
_CENTER_VERTEX = wp.constant(12)  # emit.CENTER_VERTEX
_HUB_MARGIN = wp.constant(0.05)  # emit.HUB_MARGIN
vec8f = wp.types.vector(length=8, dtype=wp.float32)
vec4u64 = wp.types.vector(length=4, dtype=wp.uint64)
vec2u64 = wp.types.vector(length=2, dtype=wp.uint64)


@wp.func
def raw_value(vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
              i: int, j: int, k: int):
    r = float(0.0)
    if mode == 0:
        r = vf[i, j, k]
    elif mode == 1:
        r = float(vu[i, j, k])
    elif int(vu[i, j, k]) == label:
        r = 1.0
    return r


@wp.func
def row_capped(i: int, j: int, n: wp.vec3i, cap: int):
    """Whether the whole row (i, j) lies on a capped face."""
    return (i == 0 and (cap & 1) != 0) or (i == n[0] - 1 and (cap & 2) != 0) or \
        (j == 0 and (cap & 4) != 0) or (j == n[1] - 1 and (cap & 8) != 0)


@wp.func
def capped_value(v: float, rowcap: bool, k: int, n2: int, cap: int):
    """An inside value on a capped face becomes 0 (outside)."""
    r = v
    if v > 0.0:
        if rowcap or (k == 0 and (cap & 16) != 0) or (k == n2 - 1 and (cap & 32) != 0):
            r = 0.0
    return r


@wp.func
def node_value(vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
               level: float, sign: float, cap: int, n: wp.vec3i, rowcap: bool, i: int, j: int, k: int):
    """The field at node (i, j, k) of row (i, j) (``rowcap``: the row is on a capped face)."""
    return capped_value(sign * (raw_value(vf, vu, mode, label, i, j, k) - level), rowcap, k, n[2], cap)

@wp.kernel
def classify_rows_kernel(
    first: int, vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
    level: float, sign: float, cap: int, n: wp.vec3i, words: int, present: wp.array(dtype=wp.uint64),
    bit: wp.uint64,
    classes: wp.array(dtype=wp.uint64), row_range: wp.array(dtype=wp.vec2), row_bad: wp.array(dtype=wp.int32),
):
    """One thread per row: its node classes (``classes[r * words + w]``, capped nodes
    outside, bits past the row's end 0); the (min, max) of its raw samples, and in
    ``row_bad`` a positive count when a sample or its value is not finite. With
    ``present`` (one entry per row: ``label_rows_kernel``), a label's row that lacks
    ``bit`` is all outside without a read."""
    r = wp.tid() + first
    i = r / n[1]
    j = r % n[1]
    if present.shape[0] > 1:
        if (present[r] & bit) == wp.uint64(0):  # the indicator is 0 along the row
            for w in range(words):
                classes[r * words + w] = wp.uint64(0)
            row_range[r] = wp.vec2(0.0, 0.0)
            row_bad[r] = 0
            return
    lo = wp.vec4(3.4e38)
    hi = wp.vec4(-3.4e38)
    bad = int(0)
    one = wp.uint64(1)
    for w in range(words):
        k0 = w * 64
        k1 = wp.min(k0 + 64, n[2])
        word = wp.uint64(0)
        quads = (k1 - k0) / 4
        for q in range(quads):  # four samples a step: four independent min / max chains
            k = k0 + 4 * q
            raw = wp.vec4(raw_value(vf, vu, mode, label, i, j, k), raw_value(vf, vu, mode, label, i, j, k + 1),
                          raw_value(vf, vu, mode, label, i, j, k + 2), raw_value(vf, vu, mode, label, i, j, k + 3))
            lo = wp.min(lo, raw)
            hi = wp.max(hi, raw)
            v = sign * (raw - wp.vec4(level))
            if wp.dot(v - v, v - v) != 0.0:  # NaN or infinite (a sample, or its value beyond float32's range)
                bad += 1
            bits = wp.where(v[0] > 0.0, 1, 0) | wp.where(v[1] > 0.0, 2, 0) | wp.where(v[2] > 0.0, 4, 0) | \
                wp.where(v[3] > 0.0, 8, 0)
            word = word | (wp.uint64(bits) << wp.uint64(4 * q))
        for k in range(k0 + 4 * quads, k1):
            rs = raw_value(vf, vu, mode, label, i, j, k)
            lo[0] = wp.min(lo[0], rs)
            hi[0] = wp.max(hi[0], rs)
            vs = sign * (rs - level)
            if vs - vs != 0.0:
                bad += 1
            word = word | (wp.uint64(wp.where(vs > 0.0, 1, 0)) << wp.uint64(k - k0))
        classes[r * words + w] = word
    if row_capped(i, j, n, cap):
        for w in range(words):
            classes[r * words + w] = wp.uint64(0)
    else:
        if (cap & 16) != 0:
            classes[r * words] = classes[r * words] & ~one
        if (cap & 32) != 0:
            last = r * words + (n[2] - 1) / 64
            classes[last] = classes[last] & ~(one << wp.uint64((n[2] - 1) & 63))
    row_range[r] = wp.vec2(wp.min(wp.min(lo[0], lo[1]), wp.min(lo[2], lo[3])),
                           wp.max(wp.max(hi[0], hi[1]), wp.max(hi[2], hi[3])))
    row_bad[r] = bad


@wp.kernel
def label_rows_kernel(
    first: int, vu: wp.array3d(dtype=wp.uint8), slot: wp.array(dtype=wp.int32), n: wp.vec3i,
    present: wp.array(dtype=wp.uint64),
):
    """One thread per row of a uint8 label volume: bit ``slot[value]`` set for each value
    in the row that has a slot (``slot``: 256 entries, -1 for values not meshed)."""
    r = wp.tid() + first
    i = r / n[1]
    j = r % n[1]
    m = wp.uint64(0)
    for k in range(n[2]):
        q = slot[int(vu[i, j, k])]
        if q >= 0:
            m = m | (wp.uint64(1) << wp.uint64(q))
    present[r] = m


@wp.func
def word_of(classes: wp.array(dtype=wp.uint64), row: int, w: int, words: int):
    return classes[row * words + w]


@wp.func
def next_of(classes: wp.array(dtype=wp.uint64), row: int, w: int, words: int):
    """The classes of nodes k + 1 at the bits of nodes k (word w of the row)."""
    x = classes[row * words + w] >> wp.uint64(1)
    if w + 1 < words:
        x = x | (classes[row * words + w + 1] << wp.uint64(63))
    return x


@wp.func
def valid_edges(w: int, n2: int):
    """Bits of word w whose node k has a node k + 1 (k < n2 - 1)."""
    m = ~wp.uint64(0)
    top = n2 - 1 - 64 * w  # valid bits in this word
    if top <= 0:
        m = wp.uint64(0)
    elif top < 64:
        m = (wp.uint64(1) << wp.uint64(top)) - wp.uint64(1)
    return m


@wp.func
def low_bit(x: wp.uint64):
    """Index of the lowest set bit of x (x != 0)."""
    return wp.bit_count((x & (~x + wp.uint64(1))) - wp.uint64(1))


@wp.func
def below(b: int):
    """Bits below bit b."""
    return (wp.uint64(1) << wp.uint64(b)) - wp.uint64(1)


@wp.func
def cell_masks(classes: wp.array(dtype=wp.uint64), rows: wp.vec4i, w: int, words: int, n2: int):
    """(low face, high face) classes of the four rows (bits dx + 2 dy ... as words) and
    the mask of word w's cells whose eight corners are not all alike."""
    a = vec4u64()
    b = vec4u64()
    for q in range(4):
        a[q] = word_of(classes, rows[q], w, words)
        b[q] = next_of(classes, rows[q], w, words)
    m = (a[0] ^ a[1]) | (a[0] ^ a[2]) | (a[0] ^ a[3]) | (a[0] ^ b[0]) | (a[0] ^ b[1]) | (a[0] ^ b[2]) | \
        (a[0] ^ b[3])
    return a, b, m & valid_edges(w, n2)


@wp.func
def cell_config(a: vec4u64, b: vec4u64, bit: int):
    ci = int(0)
    for q in range(4):
        ci = ci | (int((a[q] >> wp.uint64(bit)) & wp.uint64(1)) << q)
        ci = ci | (int((b[q] >> wp.uint64(bit)) & wp.uint64(1)) << (q + 4))
    return ci


@wp.func
def cell_rows(r: int, n1: int):
    """Rows of cell row r: (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)."""
    return wp.vec4i(r, r + n1, r + 1, r + n1 + 1)


@wp.kernel
def count_rows_kernel(
    first: int, vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
    level: float, sign: float, cap: int, n: wp.vec3i, words: int, method: int, tab: Tables,
    classes: wp.array(dtype=wp.uint64),
    count_i: wp.array(dtype=wp.int32), count_j: wp.array(dtype=wp.int32), vertex_count: wp.array(dtype=wp.int32),
    triangle_count: wp.array(dtype=wp.int32), center_count: wp.array(dtype=wp.int32),
):
    """One thread per row: its crossing edges of types 0 and 1 and of all three types;
    the triangles and interior vertices of its cell row (none for i = n0 - 1 or j = n1 - 1).
    Classes only; "mc33" reads the values at the corners of crossed cells."""
    r = wp.tid() + first
    i = r / n[1]
    j = r % n[1]
    ci = int(0)
    cj = int(0)
    ck = int(0)
    nt = int(0)
    nc = int(0)
    cells = i < n[0] - 1 and j < n[1] - 1
    rows = cell_rows(r, n[1])
    for w in range(words):
        a = word_of(classes, r, w, words)
        ck += wp.bit_count((a ^ next_of(classes, r, w, words)) & valid_edges(w, n[2]))
        if i < n[0] - 1:
            ci += wp.bit_count(a ^ word_of(classes, r + n[1], w, words))
        if j < n[1] - 1:
            cj += wp.bit_count(a ^ word_of(classes, r + 1, w, words))
        if cells:
            lo, hi, m = cell_masks(classes, rows, w, words, n[2])
            while m != wp.uint64(0):
                bit = low_bit(m)
                m = m & (m - wp.uint64(1))
                cfg = cell_config(lo, hi, bit)
                row = cfg
                if method == _METHOD_MC33:
                    row = mc33_plain(cfg, tab)
                    if row < 0:
                        k = 64 * w + bit
                        row = mc33_row(corner_values(vf, vu, mode, label, level, sign, cap, n, i, j, k),
                                       corner_values(vf, vu, mode, label, level, sign, cap, n, i, j, k + 1), cfg,
                                       tab)
                nt += tab.tri_count[row]
                nc += interior_count(tab.center[row])
    count_i[r] = ci
    count_j[r] = cj
    vertex_count[r] = ci + cj + ck
    triangle_count[r] = nt
    center_count[r] = nc


@wp.func
def corner_values(vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
                  level: float, sign: float, cap: int, n: wp.vec3i, i: int, j: int, k: int):
    """The four rows' values at position k: (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)."""
    return wp.vec4(node_value(vf, vu, mode, label, level, sign, cap, n, row_capped(i, j, n, cap), i, j, k),
                   node_value(vf, vu, mode, label, level, sign, cap, n, row_capped(i + 1, j, n, cap), i + 1, j, k),
                   node_value(vf, vu, mode, label, level, sign, cap, n, row_capped(i, j + 1, n, cap), i, j + 1, k),
                   node_value(vf, vu, mode, label, level, sign, cap, n, row_capped(i + 1, j + 1, n, cap),
                              i + 1, j + 1, k))


@wp.func
def cell_values(cur: wp.vec4, nxt: wp.vec4):
    """The 8 corner values in float64 (corner order of ``emit.Tables.corners``: bits dx,
    dy, dz; cur / nxt hold the four rows at k / k + 1)."""
    v = vec8d()
    for q in range(4):
        v[q] = wp.float64(cur[q])
        v[q + 4] = wp.float64(nxt[q])
    return v


@wp.func
def mc33_plain(ci: int, tab: Tables):
    """The "mc33" table row of configuration ci when the corner values cannot change it
    (no face with two diagonal corners inside and the other two outside, no interior
    test), else -1."""
    row = tab.case_offset[ci * 64]
    if tab.interior_test[ci * 64] >= 0:
        row = -1
    for q in range(6):
        ia = (ci >> tab.face_corners[q, 0]) & 1
        ib = (ci >> tab.face_corners[q, 1]) & 1
        if ia == ((ci >> tab.face_corners[q, 2]) & 1) and ib == ((ci >> tab.face_corners[q, 3]) & 1) and ia != ib:
            row = -1
    return row


@wp.func
def mc33_row(cur: wp.vec4, nxt: wp.vec4, ci: int, tab: Tables):
    """Table row of an "mc33" cell (``emit.mc33_row`` of its corner values)."""
    return table_row(cell_values(cur, nxt), tab, ci)


@wp.func
def edge_point(v0: float, v1: float, g: wp.vec3i, d: wp.vec3i, h: wp.vec3, capped0: bool, capped1: bool,
               t_min: float, gap: float):
    """(position, t) of the crossing on the edge from node g in direction d, as
    ``emit.crossing`` with ``emit.clamped_t`` (volumes: no lonely-node exemption;
    ``capped0`` / ``capped1``: whether the edge's ends lie on a capped face)."""
    lo = gap
    hi = 1.0 - gap
    if capped0:
        lo = t_min
    if capped1:
        hi = 1.0 - t_min
    t = wp.clamp(v0 / (v0 - v1), lo, hi)
    p0 = wp.vec3(0.0 + float(g[0]) * h[0], 0.0 + float(g[1]) * h[1], 0.0 + float(g[2]) * h[2])
    p1 = wp.vec3(p0[0] + float(d[0]) * h[0], p0[1] + float(d[1]) * h[1], p0[2] + float(d[2]) * h[2])
    return p0 + t * (p1 - p0), t


@wp.func
def node_capped(rowcap: bool, k: int, n2: int, cap: int):
    """Whether node k of a row lies on a capped face (``rowcap``: the whole row does)."""
    return rowcap or (k == 0 and (cap & 16) != 0) or (k == n2 - 1 and (cap & 32) != 0)


@wp.func
def put_vertex(vid: int, v0: float, v1: float, g: wp.vec3i, d: wp.vec3i, h: wp.vec3, capped0: bool, capped1: bool,
               t_min: float, gap: float, origin: wp.vec3d, points: wp.array(dtype=wp.vec3d),
               flags: wp.array(dtype=wp.int32)):
    """Store the vertex of a crossing edge with the flags of ``emit.emit_vertices_kernel``;
    1 when the clearance moved it. The point is stored in float64: ``origin`` plus its
    float32 position relative to node (0, 0, 0)."""
    p, te = edge_point(v0, v1, g, d, h, capped0, capped1, t_min, gap)
    points[vid] = wp.vec3d(p) + origin
    f = wp.where(v0 > 0.0, 1, 0)
    if v0 == 0.0 or v1 == 0.0:
        f = f | 2
        if capped0 or capped1:
            f = f | 4
        else:
            f = f | 8
    flags[vid] = f
    return wp.where(te != wp.clamp(v0 / (v0 - v1), t_min, 1.0 - t_min), 1, 0)


@wp.kernel
def emit_row_vertices_kernel(
    first: int, vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
    level: float, sign: float, cap: int, n: wp.vec3i, words: int, h: wp.vec3, t_min: float, clearance: float,
    classes: wp.array(dtype=wp.uint64), vertex_offset: wp.array(dtype=wp.int32),
    origin: wp.vec3d, points: wp.array(dtype=wp.vec3d), flags: wp.array(dtype=wp.int32),
    moved: wp.array(dtype=wp.int32),
):
    """One thread per row: its vertices, type 0 then 1 then 2, each in k order, from
    ``vertex_offset[r]`` (positions relative to node (0, 0, 0))."""
    r = wp.tid() + first
    i = r / n[1]
    j = r % n[1]
    gap = wp.max(t_min, clearance)
    vid = vertex_offset[r]
    n_moved = int(0)
    ca = row_capped(i, j, n, cap)
    for t in range(3):
        d = wp.vec3i(wp.where(t == 0, 1, 0), wp.where(t == 1, 1, 0), wp.where(t == 2, 1, 0))
        if i + d[0] < n[0] and j + d[1] < n[1]:
            rb = r + d[0] * n[1] + d[1]
            cb = row_capped(i + d[0], j + d[1], n, cap)
            for w in range(words):
                x = word_of(classes, r, w, words)
                if t == 2:
                    x = (x ^ next_of(classes, r, w, words)) & valid_edges(w, n[2])
                else:
                    x = x ^ word_of(classes, rb, w, words)
                while x != wp.uint64(0):
                    k = 64 * w + low_bit(x)
                    x = x & (x - wp.uint64(1))
                    v0 = node_value(vf, vu, mode, label, level, sign, cap, n, ca, i, j, k)
                    v1 = node_value(vf, vu, mode, label, level, sign, cap, n, cb, i + d[0], j + d[1], k + d[2])
                    n_moved += put_vertex(vid, v0, v1, wp.vec3i(i, j, k), d, h, node_capped(ca, k, n[2], cap),
                                          node_capped(cb, k + d[2], n[2], cap), t_min, gap, origin, points,
                                          flags)
                    vid += 1
    moved[r] = n_moved


@wp.func
def signed_volume6(points: wp.array(dtype=wp.vec3d), tri: wp.vec3i, centre: wp.vec3d):
    """Six times the signed volume of the tetrahedron (centre, triangle), in float64."""
    a = points[tri[0]] - centre
    b = points[tri[1]] - centre
    c = points[tri[2]] - centre
    return wp.dot(a, wp.cross(b, c))

@wp.kernel
def emit_row_triangles_kernel(
    first: int, vf: wp.array3d(dtype=wp.float32), vu: wp.array3d(dtype=wp.uint8), mode: int, label: int,
    level: float, sign: float, cap: int, n: wp.vec3i, words: int, h: wp.vec3, t_min: float, clearance: float,
    method: int, tab: Tables, centre: wp.vec3d, classes: wp.array(dtype=wp.uint64),
    count_i: wp.array(dtype=wp.int32), count_j: wp.array(dtype=wp.int32), vertex_offset: wp.array(dtype=wp.int32),
    triangle_offset: wp.array(dtype=wp.int32), center_offset: wp.array(dtype=wp.int32), n_edge_vertices: int,
    origin: wp.vec3d, points: wp.array(dtype=wp.vec3d), flags: wp.array(dtype=wp.int32),
    triangles: wp.array(dtype=wp.int64),
    row_volume: wp.array(dtype=wp.float64),
):
    """One thread per cell row: the tables' triangles of its crossed cells in k order. The
    vertex of an edge of type t from node k of a row is that row's first vertex of type t
    plus the row's crossings of type t before k (counted a word at a time); interior
    vertices of "mc33" cells as ``emit.emit_triangles_kernel`` places them (after the
    n_edge_vertices edge vertices); points in float64 (``origin`` plus the float32
    position), triangles as int64 rows; six times the signed volume about ``centre``."""
    r = wp.tid() + first
    i = r / n[1]
    j = r % n[1]
    vol = wp.float64(0.0)
    if i < n[0] - 1 and j < n[1] - 1:
        gap = wp.max(t_min, clearance)
        rows = cell_rows(r, n[1])
        # first ids: type 2 in the four rows; type 0 in rows (i, j), (i, j + 1); type 1 in (i, j), (i + 1, j)
        id2 = wp.vec4i(0, 0, 0, 0)
        for q in range(4):
            id2[q] = vertex_offset[rows[q]] + count_i[rows[q]] + count_j[rows[q]]
        id0 = wp.vec2i(vertex_offset[rows[0]], vertex_offset[rows[2]])
        id1 = wp.vec2i(vertex_offset[rows[0]] + count_i[rows[0]], vertex_offset[rows[1]] + count_i[rows[1]])
        out = triangle_offset[r]
        cid = center_offset[r] + n_edge_vertices
        for w in range(words):
            lo, hi, m = cell_masks(classes, rows, w, words, n[2])
            x2 = vec4u64()
            for q in range(4):
                x2[q] = (lo[q] ^ hi[q]) & valid_edges(w, n[2])
            x0 = vec2u64(lo[0] ^ lo[1], lo[2] ^ lo[3])
            x1 = vec2u64(lo[0] ^ lo[2], lo[1] ^ lo[3])
            while m != wp.uint64(0):
                bit = low_bit(m)
                m = m & (m - wp.uint64(1))
                k = 64 * w + bit
                under = below(bit)
                cfg = cell_config(lo, hi, bit)
                case = cfg
                cv0 = wp.vec4(0.0)
                cv1 = wp.vec4(0.0)
                if method == _METHOD_MC33:
                    case = mc33_plain(cfg, tab)
                    if case < 0:
                        cv0 = corner_values(vf, vu, mode, label, level, sign, cap, n, i, j, k)
                        cv1 = corner_values(vf, vu, mode, label, level, sign, cap, n, i, j, k + 1)
                        case = mc33_row(cv0, cv1, cfg, tab)
                g = wp.vec3i(i, j, k)
                mask = tab.center[case]
                if mask != 0 and mc33_plain(cfg, tab) >= 0:  # interior vertices: placed from the values
                    cv0 = corner_values(vf, vu, mode, label, level, sign, cap, n, i, j, k)
                    cv1 = corner_values(vf, vu, mode, label, level, sign, cap, n, i, j, k + 1)
                center = int(-1)
                if mask != 0:
                    center = cid
                    cid += interior_count(mask)
                    cv = vec8f()
                    for q in range(4):
                        cv[q] = cv0[q]
                        cv[q + 4] = cv1[q]
                    if (mask & 1) != 0:  # vertex 12: the mean of the cell's edge vertices
                        acc = wp.vec3(0.0)
                        mm = float(0.0)
                        for t in range(3):
                            d = wp.vec3i(tab.type_delta[t, 0], tab.type_delta[t, 1], tab.type_delta[t, 2])
                            for q in range(8):
                                if tab.corners[q, t] == 0:
                                    va = cv[q]
                                    vb = cv[q | (1 << t)]
                                    if (va > 0.0) != (vb > 0.0):
                                        ge = g + wp.vec3i(tab.corners[q, 0], tab.corners[q, 1], tab.corners[q, 2])
                                        p, te = edge_point(va, vb, ge, d, h, on_capped_face(ge, n, cap),
                                                           on_capped_face(ge + d, n, cap), t_min, gap)
                                        acc = acc + p
                                        mm += 1.0
                        points[center] = wp.vec3d(acc / wp.max(mm, 1.0)) + origin
                        flags[center] = 2
                    if mask > 1:  # the spokes of the hub construction
                        v = cell_values(cv0, cv1)
                        test = tab.interior_test[mc33_entry(v, tab, cfg)]
                        hub = mc33_hub(v, tab, test, wp.float64(_HUB_MARGIN))
                        f_hub = trilinear(v, tab, hub)
                        for q in range(8):
                            if ((mask >> (q + 1)) & 1) != 0:
                                u = spoke_point(v, tab, hub, f_hub, q, wp.float64(gap))
                                vq = center + interior_count(mask & ((2 << q) - 1))
                                pq = wp.vec3(0.0 + (float(g[0]) + float(u[0])) * h[0],
                                             0.0 + (float(g[1]) + float(u[1])) * h[1],
                                             0.0 + (float(g[2]) + float(u[2])) * h[2])
                                points[vq] = wp.vec3d(pq) + origin
                                flags[vq] = 2
                for q in range(tab.tri_count[case]):
                    tri = wp.vec3i(0, 0, 0)
                    for m3 in range(3):
                        lv = tab.tris[case, q * 3 + m3]
                        dx = tab.origin[lv, 0]
                        dy = tab.origin[lv, 1]
                        dz = tab.origin[lv, 2]
                        t = tab.origin[lv, 3]
                        vid = int(-1)
                        if t == _CENTER:
                            vid = center + interior_count(mask & ((1 << (lv - _CENTER_VERTEX)) - 1))
                        elif t == 2:
                            vid = id2[dx + 2 * dy] + wp.bit_count(x2[dx + 2 * dy] & under)
                        elif t == 0:
                            xw = x0[dy]
                            vid = id0[dy] + wp.bit_count(xw & under) + dz * int((xw >> wp.uint64(bit)) & wp.uint64(1))
                        else:
                            xw = x1[dx]
                            vid = id1[dx] + wp.bit_count(xw & under) + dz * int((xw >> wp.uint64(bit)) & wp.uint64(1))
                        tri[m3] = vid
                    for m3 in range(3):  # int64 rows of the host's connectivity
                        triangles[3 * out + m3] = wp.int64(tri[m3])
                    out += 1
                    vol += signed_volume6(points, tri, centre)
            for q in range(4):
                id2[q] += wp.bit_count(x2[q])
            id0 = id0 + wp.vec2i(wp.bit_count(x0[0]), wp.bit_count(x0[1]))
            id1 = id1 + wp.vec2i(wp.bit_count(x1[0]), wp.bit_count(x1[1]))
    row_volume[r] = vol


# -- surface nets of a label volume (warpmesh.surface.multilabel) ------------------------------------------------
# The samples (flat, C order; uint8, uint16 or int32: one overload each, declared below) map to small codes through
# ``table`` (an entry per 8- or 16-bit pattern, or per int32 code). The grid is read as if padded with one layer of
# the rest's code on every side when ``pad`` is 1 (virtual index i is sample i - pad): no padded copy. A *cube* is
# named by its lowest sample and gets a vertex when a quad uses it. Rows are the (i, j) of the virtual grid (shape
# ``p``), k contiguous; the cube bits of cube row (i, j) are at row r = i * p[1] + j, ``words`` uint64 a row (bit b
# of word w: cube k = 64 w + b).
LABEL_DTYPES = (wp.uint8, wp.uint16, wp.int32)  # the sample types of the overloads
vec8i = wp.types.vector(length=8, dtype=wp.int32)


@wp.func
def label_row_base(i: int, j: int, pad: int, n: wp.vec3i):
    """Flat index of sample (i - pad, j - pad, 0), or -1 for a row of the padding (or past the grid)."""
    a = i - pad
    b = j - pad
    base = int(-1)
    if a >= 0 and a < n[0] and b >= 0 and b < n[1]:
        base = (a * n[1] + b) * n[2]
    return base


@wp.func
def code_at(values: wp.array(dtype=Any), table: wp.array(dtype=wp.int32), rest: int, pad: int, n: wp.vec3i, i: int,
            j: int, k: int):
    """The code of virtual sample (i, j, k): ``rest`` in the padding."""
    base = label_row_base(i, j, pad, n)
    c = k - pad
    code = rest
    if base >= 0 and c >= 0 and c < n[2]:
        code = table[int(values[base + c])]
    return code


@wp.func
def distinct_codes(c0: int, c1: int, c2: int, c3: int, c4: int, c5: int, c6: int, c7: int):
    """How many distinct values among eight."""
    v = vec8i(c0, c1, c2, c3, c4, c5, c6, c7)
    count = int(0)
    for m in range(8):
        seen = int(0)
        for l in range(m):
            if v[l] == v[m]:
                seen = 1
        count += 1 - seen
    return count


@wp.func
def inside_span(x: int, size: int):
    """1 <= x <= size - 2: an edge at x has cubes on both sides along that axis."""
    return x >= 1 and x + 2 <= size


@wp.func
def boundary_cube_used(q: wp.vec4i, c: wp.vec4i, i: int, j: int, k: int, p: wp.vec3i):
    """Whether cube (i, j, k) (corner codes ``q`` at k and ``c`` at k + 1, entry a + 2 b
    at i + a, j + b) has a crossing edge with 4 cubes around it: a quad uses its vertex."""
    used = False
    for d in range(2):
        for e in range(2):
            lo = q
            if e == 1:
                lo = c
            # along axis 0 at (j + d, k + e); along axis 1 at (i + d, k + e); along axis 2 at (i + d, j + e)
            if lo[2 * d] != lo[2 * d + 1] and inside_span(j + d, p[1]) and inside_span(k + e, p[2]):
                used = True
            if lo[d] != lo[d + 2] and inside_span(i + d, p[0]) and inside_span(k + e, p[2]):
                used = True
            if q[d + 2 * e] != c[d + 2 * e] and inside_span(i + d, p[0]) and inside_span(j + e, p[1]):
                used = True
    return used


@wp.func
def row_code(values: wp.array(dtype=Any), table: wp.array(dtype=wp.int32), rest: int, base: int, kk: int,
             inside: bool):
    """The code of sample kk of the row at ``base`` (``rest`` for a padding row or outside)."""
    code = rest
    if base >= 0 and inside:
        code = table[int(values[base + kk])]
    return code


@wp.kernel
def count_label_rows_kernel(
    first: int, values: wp.array(dtype=Any), table: wp.array(dtype=wp.int32), rest: int, pad: int, n: wp.vec3i,
    p: wp.vec3i, words: int, bits: wp.array(dtype=wp.uint64), vertex_count: wp.array(dtype=wp.int32),
    quad_count: wp.array(dtype=wp.int32),
    junction_count: wp.array(dtype=wp.int32), seen: wp.array(dtype=wp.uint8),
):
    """One thread per row (i, j) of the virtual grid, reading rows (i, j), (i + 1, j),
    (i, j + 1), (i + 1, j + 1) once along k: the bits and count of the cubes of cube row (i, j) that get a vertex
    (8 codes not all alike; on the grid's faces without ``pad``, a crossing edge with 4
    cubes around it), those holding three codes or more, and the quads of the crossing
    edges starting on row (i, j) along each axis (an edge makes a quad when the 4 cubes
    around it exist); ``seen[code]`` set for the codes of row (i, j)'s samples."""
    r = wp.tid() + first
    i = r / p[1]
    j = r % p[1]
    has_i = i + 1 < p[0]
    has_j = j + 1 < p[1]
    cubes = has_i and has_j
    inner_i = inside_span(i, p[0])
    inner_j = inside_span(j, p[1])
    edge_i = has_i and inner_j  # quads of the edges towards row (i + 1, j), for k inside
    edge_j = has_j and inner_i
    edge_k = inner_i and inner_j
    face = pad == 0 and (i == 0 or i + 2 == p[0] or j == 0 or j + 2 == p[1])  # cubes on the grid's faces
    base0 = label_row_base(i, j, pad, n)  # rows (i + a, j + b): variables named a b
    base1 = int(-1)
    base2 = int(-1)
    base3 = int(-1)
    if has_i:
        base1 = label_row_base(i + 1, j, pad, n)
    if has_j:
        base2 = label_row_base(i, j + 1, pad, n)
    if cubes:
        base3 = label_row_base(i + 1, j + 1, pad, n)
    nv = int(0)
    nq = int(0)
    nj = int(0)
    c00 = row_code(values, table, rest, base0, -pad, pad == 0)  # k = 0
    c10 = row_code(values, table, rest, base1, -pad, pad == 0)
    c01 = row_code(values, table, rest, base2, -pad, pad == 0)
    c11 = row_code(values, table, rest, base3, -pad, pad == 0)
    seen[c00] = wp.uint8(1)
    for w in range(words):  # the cubes k - 1 of word w: k from 64 w + 1
        word = wp.uint64(0)
        for k in range(64 * w + 1, wp.min(64 * w + 65, p[2])):
            kk = k - pad
            inside = kk >= 0 and kk < n[2]
            q00 = c00  # the codes at k - 1
            q10 = c10
            q01 = c01
            q11 = c11
            c00 = row_code(values, table, rest, base0, kk, inside)
            c10 = row_code(values, table, rest, base1, kk, inside)
            c01 = row_code(values, table, rest, base2, kk, inside)
            c11 = row_code(values, table, rest, base3, kk, inside)
            if ((c00 ^ q00) | (c10 ^ q00) | (c01 ^ q00) | (c11 ^ q00) | (q10 ^ q00) | (q01 ^ q00) | (q11 ^ q00)) == 0:
                continue  # the usual case: 8 codes alike, no crossing edge at k, no vertex in cube k - 1
            if c00 != q00:
                seen[c00] = wp.uint8(1)
            inner_k = k + 1 < p[2]  # edges at k have cubes k - 1 and k
            if edge_i and inner_k and c10 != c00:
                nq += 1
            if edge_j and inner_k and c01 != c00:
                nq += 1
            if edge_k and c00 != q00:  # the edge (k - 1, k) along the row
                nq += 1
            if cubes:
                used = True
                if face or (pad == 0 and (k == 1 or k == p[2] - 1)):
                    used = boundary_cube_used(wp.vec4i(q00, q10, q01, q11), wp.vec4i(c00, c10, c01, c11), i, j, k - 1,
                                              p)
                if used:
                    word = word | (wp.uint64(1) << wp.uint64((k - 1) & 63))
                    nv += 1
                    if distinct_codes(q00, q10, q01, q11, c00, c10, c01, c11) >= 3:
                        nj += 1
        if cubes:
            bits[r * words + w] = word
    vertex_count[r] = nv
    quad_count[r] = nq
    junction_count[r] = nj


@wp.func
def cube_rank(bits: wp.array(dtype=wp.uint64), row: int, w: int, words: int, bit: int, before: int):
    """Vertices of cube row ``row`` before cube 64 w + bit, given ``before`` up to word w."""
    return before + wp.bit_count(bits[row * words + w] & below(bit))


@wp.func
def write_quad(q: wp.vec4i, flip: bool, lo: int, hi: int, ids: wp.array(dtype=Any),
               pair_seen: wp.array(dtype=wp.uint8), n_codes: int, out: int, triangles: wp.array(dtype=wp.int32),
               lower: wp.array(dtype=Any), upper: wp.array(dtype=Any)):
    """Quad ``q`` (counter-clockwise about its edge's + direction) as triangles 2 out and
    2 out + 1, split along q0-q2, the winding reversed where ``flip``, with the labels
    ``ids[lo]`` and ``ids[hi]`` (in the labels' own narrow type); flags the pair of codes in
    ``pair_seen`` (codes ``n_codes`` a row) when ``n_codes`` > 0."""
    a = q
    if flip:
        a = wp.vec4i(q[3], q[2], q[1], q[0])
    t = 6 * out
    triangles[t + 0] = a[0]
    triangles[t + 1] = a[1]
    triangles[t + 2] = a[2]
    triangles[t + 3] = a[0]
    triangles[t + 4] = a[2]
    triangles[t + 5] = a[3]
    lower[2 * out] = ids[lo]
    lower[2 * out + 1] = ids[lo]
    upper[2 * out] = ids[hi]
    upper[2 * out + 1] = ids[hi]
    if n_codes > 0:
        pair_seen[lo * n_codes + hi] = wp.uint8(1)


@wp.kernel
def emit_label_quads_kernel(
    first: int, values: wp.array(dtype=Any), table: wp.array(dtype=wp.int32), rest: int, pad: int, n: wp.vec3i,
    p: wp.vec3i, words: int, bits: wp.array(dtype=wp.uint64), vertex_first: wp.array(dtype=wp.int32),
    quad_count: wp.array(dtype=wp.int32),
    quad_first: wp.array(dtype=wp.int64), ids: wp.array(dtype=Any), reverse: int,
    pair_seen: wp.array(dtype=wp.uint8), n_codes: int, triangles: wp.array(dtype=wp.int32),
    lower: wp.array(dtype=Any), upper: wp.array(dtype=Any),
):
    """One thread per row (i, j): the quads of the crossing edges starting on it, in k
    order and axis 0, 1, 2 at each k, as ``count_label_rows_kernel`` counted them. A
    quad's vertices are the cubes around its edge (lowest samples at (0, -1, -1), (0, 0,
    -1), (0, 0, 0), (0, -1, 0) from the edge's first sample about axis 0, and the same
    turned for axes 1 and 2), numbered by the cube bits before them in their rows. The
    winding runs from the lower code to the higher, reversed once more with ``reverse``
    (the points' axes swapped). Only the cubes (i, j, k) with a vertex are visited: every
    crossing edge's cubes have one."""
    r = wp.tid() + first
    if quad_count[r] == 0:
        return
    i = r / p[1]
    j = r % p[1]
    inner_i = inside_span(i, p[0])
    inner_j = inside_span(j, p[1])
    r_j = r - 1  # cube rows (i, j - 1), (i - 1, j), (i - 1, j - 1)
    r_i = r - p[1]
    r_ij = r - p[1] - 1
    b00 = vertex_first[r]
    b0j = int(0)
    bi0 = int(0)
    bij = int(0)
    if j >= 1:
        b0j = vertex_first[r_j]
    if i >= 1:
        bi0 = vertex_first[r_i]
    if i >= 1 and j >= 1:
        bij = vertex_first[r_ij]
    turn = reverse != 0
    out = int(quad_first[r])
    for w in range(words):
        m = bits[r * words + w]
        while m != wp.uint64(0):
            bit = low_bit(m)
            m = m & (m - wp.uint64(1))
            k = 64 * w + bit
            inner_k = inside_span(k, p[2])
            c00 = code_at(values, table, rest, pad, n, i, j, k)
            v00 = cube_rank(bits, r, w, words, bit, b00)  # cube (i, j, k)
            if inner_j and inner_k:  # axis 0
                c = code_at(values, table, rest, pad, n, i + 1, j, k)
                if c != c00:
                    v0j = cube_rank(bits, r_j, w, words, bit, b0j)
                    write_quad(wp.vec4i(v0j - 1, v00 - 1, v00, v0j), (c00 > c) != turn, wp.min(c, c00),
                               wp.max(c, c00), ids, pair_seen, n_codes, out, triangles, lower, upper)
                    out += 1
            if inner_i and inner_k:  # axis 1
                c = code_at(values, table, rest, pad, n, i, j + 1, k)
                if c != c00:
                    vi0 = cube_rank(bits, r_i, w, words, bit, bi0)
                    write_quad(wp.vec4i(vi0 - 1, vi0, v00, v00 - 1), (c00 > c) != turn, wp.min(c, c00),
                               wp.max(c, c00), ids, pair_seen, n_codes, out, triangles, lower, upper)
                    out += 1
            if inner_i and inner_j and k + 1 < p[2]:  # axis 2
                c = code_at(values, table, rest, pad, n, i, j, k + 1)
                if c != c00:
                    vij = cube_rank(bits, r_ij, w, words, bit, bij)
                    v0j = cube_rank(bits, r_j, w, words, bit, b0j)
                    vi0 = cube_rank(bits, r_i, w, words, bit, bi0)
                    write_quad(wp.vec4i(vij, v0j, v00, vi0), (c00 > c) != turn, wp.min(c, c00), wp.max(c, c00),
                               ids, pair_seen, n_codes, out, triangles, lower, upper)
                    out += 1
        b00 += wp.bit_count(bits[r * words + w])
        if j >= 1:
            b0j += wp.bit_count(bits[r_j * words + w])
        if i >= 1:
            bi0 += wp.bit_count(bits[r_i * words + w])
        if i >= 1 and j >= 1:
            bij += wp.bit_count(bits[r_ij * words + w])


@wp.kernel
def emit_label_points_kernel(
    first: int, p: wp.vec3i, words: int, bits: wp.array(dtype=wp.uint64), vertex_first: wp.array(dtype=wp.int32),
    origin: wp.vec3d, spacing: wp.vec3d, reverse: int, points: wp.array(dtype=wp.float32),
):
    """One thread per cube row: each of its vertices at its cube's centre,
    ``origin + (index + 1/2) * spacing`` (``origin``: the virtual grid's sample 0), in k
    order, computed in float64 and stored in float32 (the compact mesh's points); the
    coordinates written z, y, x with ``reverse``."""
    r = wp.tid() + first
    i = r / p[1]
    j = r % p[1]
    v = vertex_first[r]
    x = origin[0] + (wp.float64(i) + wp.float64(0.5)) * spacing[0]
    y = origin[1] + (wp.float64(j) + wp.float64(0.5)) * spacing[1]
    for w in range(words):
        m = bits[r * words + w]
        while m != wp.uint64(0):
            bit = low_bit(m)
            m = m & (m - wp.uint64(1))
            z = origin[2] + (wp.float64(64 * w + bit) + wp.float64(0.5)) * spacing[2]
            if reverse != 0:
                points[3 * v] = wp.float32(z)
                points[3 * v + 2] = wp.float32(x)
            else:
                points[3 * v] = wp.float32(x)
                points[3 * v + 2] = wp.float32(z)
            points[3 * v + 1] = wp.float32(y)
            v += 1


#: the label types of the triangles, per sample type: the narrowest of int16, int32 and int64
#: that holds the region ids. Every pair is compiled with the module: 8-bit samples read in
#: place have ids within [-129, 255] and 16-bit ones within [-32769, 65535], but wider
#: volumes are coded first into uint8, uint16 or int32 codes by their count of regions
#: (multilabel.label_codes), whatever their ids
LABEL_OUT_DTYPES = {dtype: (wp.int16, wp.int32, wp.int64) for dtype in LABEL_DTYPES}

for _dtype in LABEL_DTYPES:  # compiled with the module, once: no instance made at the first launch of a new type
    wp.overload(count_label_rows_kernel, {"values": wp.array(dtype=_dtype)})
    for _out in LABEL_OUT_DTYPES[_dtype]:
        wp.overload(emit_label_quads_kernel, {"values": wp.array(dtype=_dtype), "ids": wp.array(dtype=_out),
                                              "lower": wp.array(dtype=_out), "upper": wp.array(dtype=_out)})
