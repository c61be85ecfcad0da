"""Surface emission over the block-sparse grid [FG §16.4.2]: marching cubes ("mc", the
plain table), marching cubes 33 ("mc33", the topology of the trilinear interpolant) and
marching tetrahedra on the Kuhn split of each cube ("mt"); then root refinement along the
crossing edges (§16.3.3).

Vertices live on grid edges of a few direction *types* (``TYPE_DELTA``: the 3 axes, for
"mt" also the 3 face diagonals and the body diagonal of the Kuhn split), plus, for "mc33",
vertices inside a cell (type ``CENTER``: the apex of a disk's fan, or the spoke vertices
of a tube's hub construction, kernels/mc33_tables.py), created by the cell itself. Every
grid edge ``(node, type)`` has
exactly one owner block, the block of its lower node (``owner = min(g // BLOCK, nb - 1)``
per axis), and that block creates the single vertex of the edge when it crosses the
surface, so the output is welded by construction. A cell's polygons come from the
method's tables (``Tables``) as local vertex ids whose ``(dx, dy, dz, type)`` rows say
which grid edge each one is. Variable-size output is count -> prefix sum -> allocate ->
write; a thread works on one slot (a block of ``BLOCK^3`` cells), launches take ``first``
so the host can split them across cores.
"""

import numpy as np
import warp as wp

from warpmesh.kernels.block_grid import BLOCK, NODES, SIDE, block_coords, local_index, on_capped_face

wp.set_module_options({"enable_backward": False, "fuse_fp": False})  # decisions as the numpy reference

METHOD_MC = 0
METHOD_MC33 = 1
METHOD_MT = 2
CENTER = 7  # vertex type of a cell's interior vertices ("mc33")
CENTER_VERTEX = 12  # local id of a cell's first interior vertex ("mc33": mc33_tables.CENTER_VERTEX)
HUB_MARGIN = 0.05  # the hub's distance from the cube faces ("mc33": mc33_tables.HUB_MARGIN)
#: (8, 3) direction of each vertex type: +x, +y, +z, +x+y, +x+z, +y+z, +x+y+z; CENTER
TYPE_DELTA = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, 0, 1], [0, 1, 1], [1, 1, 1],
                       [0, 0, 0]], dtype=np.int32)

_BLOCK = wp.constant(BLOCK)
_SIDE = wp.constant(SIDE)
_NODES = wp.constant(NODES)
_CELLS = wp.constant(BLOCK * BLOCK * BLOCK)
_METHOD_MC33 = wp.constant(METHOD_MC33)
_CENTER = wp.constant(CENTER)
_CENTER_VERTEX = wp.constant(CENTER_VERTEX)
_HUB_MARGIN = wp.constant(HUB_MARGIN)
vec8d = wp.types.vector(length=8, dtype=wp.float64)


@wp.struct
class Tables:
    """A method's tables on one device (see ``warpmesh.surface.block_grid.method_tables``)."""

    corners: wp.array2d(dtype=wp.int32)  # (8, 3) corner offsets
    type_delta: wp.array2d(dtype=wp.int32)  # (8, 3) TYPE_DELTA
    origin: wp.array2d(dtype=wp.int32)  # (V, 4) local vertex -> (dx, dy, dz, type)
    tri_count: wp.array(dtype=wp.int32)  # per case
    tris: wp.array2d(dtype=wp.int32)  # per case: 3 local vertex ids per triangle
    quad_count: wp.array(dtype=wp.int32)  # per case ("mt": quads split at run time)
    quads: wp.array2d(dtype=wp.int32)  # per case: 4 local vertex ids per quad
    center: wp.array(dtype=wp.int32)  # per case: bit j set when it uses interior vertex j (local vertex 12 + j)
    case_offset: wp.array(dtype=wp.int32)  # "mc33": config * 64 + face bits -> first row
    interior_test: wp.array(dtype=wp.int32)  # "mc33": config * 64 + face bits -> test id or -1
    test_corners: wp.array2d(dtype=wp.int32)  # "mc33": parameters of each interior test
    face_corners: wp.array2d(dtype=wp.int32)  # (6, 4) corners of each cube face, cyclic


@wp.func
def config_of(values: wp.array(dtype=wp.float32), base: int, i: int, j: int, k: int, tab: Tables):
    ci = int(0)
    for q in range(8):
        if values[base + local_index(i + tab.corners[q, 0], j + tab.corners[q, 1], k + tab.corners[q, 2])] > 0.0:
            ci = ci | (1 << q)
    return ci


@wp.func
def interior_value(v: vec8d, tab: Tables, test: int):
    """Interior test of "mc33" (kernels/mc33_tables.py, ``interior_value``): 1 when the
    diagonal edges A, C of the slices along the test's axis join through the inside of
    a slice, 2 through the outside (a slice saddle on the level counts as outside), else 0."""
    a0 = v[tab.test_corners[test, 0]]
    a1 = v[tab.test_corners[test, 1]]
    c0 = v[tab.test_corners[test, 2]]
    c1 = v[tab.test_corners[test, 3]]
    b0 = v[tab.test_corners[test, 4]]
    b1 = v[tab.test_corners[test, 5]]
    d0 = v[tab.test_corners[test, 6]]
    d1 = v[tab.test_corners[test, 7]]
    da = a1 - a0
    dc = c1 - c0
    db = b1 - b0
    dd = d1 - d0
    alpha = da * dc - db * dd
    beta = a0 * dc + c0 * da - b0 * dd - d0 * db
    gamma = a0 * c0 - b0 * d0
    two = wp.float64(2.0)
    zero = wp.float64(0.0)
    r = int(0)
    if alpha < zero and beta > zero and beta < -two * alpha:
        disc = beta * beta - wp.float64(4.0) * alpha * gamma  # the sign of P(t*)
        sa = -two * alpha * a0 + da * beta
        sc = -two * alpha * c0 + dc * beta
        if disc > zero and sa > zero and sc > zero:
            r = 1
        elif disc >= zero and sa <= zero and sc <= zero:  # the level is outside: a tie joins
            r = 2
    return r


@wp.func
def mc33_values(values: wp.array(dtype=wp.float32), base: int, i: int, j: int, k: int, tab: Tables):
    """The cell's 8 corner values in float64 (products of two float32 values are exact)."""
    v = vec8d()
    for q in range(8):
        v[q] = wp.float64(values[base + local_index(i + tab.corners[q, 0], j + tab.corners[q, 1],
                                                    k + tab.corners[q, 2])])
    return v


@wp.func
def mc33_entry(v: vec8d, tab: Tables, ci: int):
    """Table entry ``config * 64 + face bits`` of "mc33": the asymptotic decider on each
    ambiguous face, by products of the corner values, so the two cells of a face agree;
    a tie keeps the inside corners apart (bit 0)."""
    zero = wp.float64(0.0)
    bits = int(0)
    for q in range(6):
        va = v[tab.face_corners[q, 0]]
        vb = v[tab.face_corners[q, 1]]
        vc = v[tab.face_corners[q, 2]]
        vd = v[tab.face_corners[q, 3]]
        ia = va > zero
        ib = vb > zero
        if ia == (vc > zero) and ib == (vd > zero) and ia != ib:
            pac = va * vc
            pbd = vb * vd
            joined = pbd > pac
            if ia:
                joined = pac > pbd
            if joined:
                bits = bits | (1 << q)
    return ci * 64 + bits


@wp.func
def mc33_row(v: vec8d, tab: Tables, ci: int):
    """Row of the "mc33" tables for a cell of configuration ci with corner values v: its
    entry, then the interior test the entry asks for."""
    entry = mc33_entry(v, tab, ci)
    row = tab.case_offset[entry]
    test = tab.interior_test[entry]
    if test >= 0:
        row += interior_value(v, tab, test)
    return row


@wp.func
def mc33_case(values: wp.array(dtype=wp.float32), base: int, i: int, j: int, k: int, tab: Tables, ci: int):
    """Row of the "mc33" tables for a cell of configuration ci of a block grid."""
    return mc33_row(mc33_values(values, base, i, j, k, tab), tab, ci)


@wp.func
def interior_count(mask: int):
    """Interior vertices of a case: the bits set in its ``center`` mask."""
    n = int(0)
    for b in range(9):
        n += (mask >> b) & 1
    return n


@wp.func
def trilinear(v: vec8d, tab: Tables, p: wp.vec3d):
    """The trilinear interpolant of the corner values at a point of the unit cube."""
    one = wp.float64(1.0)
    f = wp.float64(0.0)
    for q in range(8):
        w = one
        for a in range(3):
            if tab.corners[q, a] == 1:
                w = w * p[a]
            else:
                w = w * (one - p[a])
        f += w * v[q]
    return f


@wp.func
def mc33_hub(v: vec8d, tab: Tables, test: int, margin: wp.float64):
    """The hub of a cell whose interior test found a connection (kernels/mc33_tables.py,
    ``hub_point``): the saddle of the slice t* along the test's axis, kept ``margin``
    from the cube faces."""
    a0 = v[tab.test_corners[test, 0]]
    a1 = v[tab.test_corners[test, 1]]
    c0 = v[tab.test_corners[test, 2]]
    c1 = v[tab.test_corners[test, 3]]
    b0 = v[tab.test_corners[test, 4]]
    b1 = v[tab.test_corners[test, 5]]
    d0 = v[tab.test_corners[test, 6]]
    d1 = v[tab.test_corners[test, 7]]
    alpha = (a1 - a0) * (c1 - c0) - (b1 - b0) * (d1 - d0)
    beta = a0 * (c1 - c0) + c0 * (a1 - a0) - b0 * (d1 - d0) - d0 * (b1 - b0)
    t = -beta / (wp.float64(2.0) * alpha)
    axis = test // 2
    u = 0
    w = 2
    if axis == 0:
        u = 1
    if axis == 2:
        w = 1
    bit = 1 << axis
    s00 = v[0] + t * (v[bit] - v[0])
    s10 = v[1 << u] + t * (v[(1 << u) | bit] - v[1 << u])
    s01 = v[1 << w] + t * (v[(1 << w) | bit] - v[1 << w])
    s11 = v[(1 << u) | (1 << w)] + t * (v[(1 << u) | (1 << w) | bit] - v[(1 << u) | (1 << w)])
    e = s11 - s10 - s01 + s00
    hub = wp.vec3d()
    hub[axis] = t
    hub[u] = (s00 - s01) / e
    hub[w] = (s00 - s10) / e
    for a in range(3):
        hub[a] = wp.clamp(hub[a], margin, wp.float64(1.0) - margin)
    return hub


@wp.func
def spoke_point(v: vec8d, tab: Tables, hub: wp.vec3d, f_hub: wp.float64, q: int, t_min: wp.float64):
    """Spoke vertex of corner q (unit cube): the root of the trilinear interpolant between
    the hub and the corner by bisection (the midpoint when the hub's value has the
    corner's side), its parameter clamped to [t_min, 1 - t_min]."""
    corner = wp.vec3d(wp.float64(tab.corners[q, 0]), wp.float64(tab.corners[q, 1]), wp.float64(tab.corners[q, 2]))
    zero = wp.float64(0.0)
    tau = wp.float64(0.5)
    if (f_hub > zero) != (v[q] > zero):
        lo = zero
        hi = wp.float64(1.0)
        for _ in range(30):
            mid = wp.float64(0.5) * (lo + hi)
            if (trilinear(v, tab, hub + mid * (corner - hub)) > zero) == (f_hub > zero):
                lo = mid
            else:
                hi = mid
        tau = wp.float64(0.5) * (lo + hi)
    tau = wp.clamp(tau, t_min, wp.float64(1.0) - t_min)
    return hub + tau * (corner - hub)


@wp.func
def owned_count(c: wp.vec3i, nb: wp.vec3i, n: wp.vec3i):
    """Nodes per axis that the block at c owns (the last block also owns its far face)."""
    r = wp.vec3i(0, 0, 0)
    for a in range(3):
        hi = _BLOCK - 1
        if c[a] == nb[a] - 1:
            hi = _BLOCK
        r[a] = wp.min(hi, n[a] - 1 - c[a] * _BLOCK) + 1
    return r


@wp.func
def cell_count(c: wp.vec3i, n: wp.vec3i):
    """Cells per axis of the block at c (fewer in the last block of a short axis)."""
    return wp.vec3i(wp.min(_BLOCK, n[0] - 1 - c[0] * _BLOCK), wp.min(_BLOCK, n[1] - 1 - c[1] * _BLOCK),
                    wp.min(_BLOCK, n[2] - 1 - c[2] * _BLOCK))


@wp.func
def edge_in_grid(g: wp.vec3i, n: wp.vec3i, d: wp.vec3i):
    """Whether the edge from node g in direction d ends inside the grid."""
    ok = True
    for a in range(3):
        if d[a] == 1 and g[a] >= n[a] - 1:
            ok = False
    return ok


@wp.func
def type_dir(tab: Tables, t: int):
    return wp.vec3i(tab.type_delta[t, 0], tab.type_delta[t, 1], tab.type_delta[t, 2])


@wp.kernel
def count_crossings_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i, method: int, n_types: int,
    values: wp.array(dtype=wp.float32), tab: Tables, cell_mask: wp.array(dtype=wp.uint8),
    vertex_count: wp.array(dtype=wp.int32), triangle_count: wp.array(dtype=wp.int32),
    center_count: wp.array(dtype=wp.int32), cell_cases: wp.array(dtype=wp.int32),
):
    """One thread per slot: crossing edges the block owns (of the method's n_types
    directions), and the triangles and interior vertices of its cells (their cases are
    kept for the emission pass; -1 for an uncrossed cell, whose case has no polygon and no
    interior vertex, and for a cell outside ``cell_mask`` when it is given). A slot whose
    nodes all have one sign has neither (its edges and cells join its own nodes)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    base = s * _NODES
    nv = int(0)
    nt = int(0)
    nc = int(0)
    cells = cell_count(c, n)
    first_inside = values[base] > 0.0
    mixed = int(0)
    for l in range(_NODES):
        if (values[base + l] > 0.0) != first_inside:
            mixed = 1
            break
    if mixed == 0:
        for k in range(cells[2]):
            for j in range(cells[1]):
                for i in range(cells[0]):
                    cell_cases[s * _CELLS + i + _BLOCK * (j + _BLOCK * k)] = -1
        vertex_count[s] = 0
        triangle_count[s] = 0
        center_count[s] = 0
        return
    own = owned_count(c, nb, n)
    for k in range(own[2]):
        for j in range(own[1]):
            for i in range(own[0]):
                inside = values[base + local_index(i, j, k)] > 0.0
                g = wp.vec3i(c[0] * _BLOCK + i, c[1] * _BLOCK + j, c[2] * _BLOCK + k)
                for t in range(n_types):
                    d = type_dir(tab, t)
                    if edge_in_grid(g, n, d):
                        if (values[base + local_index(i + d[0], j + d[1], k + d[2])] > 0.0) != inside:
                            nv += 1
    for k in range(cells[2]):
        for j in range(cells[1]):
            for i in range(cells[0]):
                cell = s * _CELLS + i + _BLOCK * (j + _BLOCK * k)
                case = int(-1)
                if cell_mask.shape[0] == 1 or cell_mask[cell] != wp.uint8(0):
                    ci = config_of(values, base, i, j, k, tab)
                    if ci != 0 and ci != 255:  # an uncrossed cell has no polygon (checked with the tables)
                        case = ci
                        if method == _METHOD_MC33:
                            case = mc33_case(values, base, i, j, k, tab, ci)
                        nt += tab.tri_count[case] + 2 * tab.quad_count[case]
                        nc += interior_count(tab.center[case])
                cell_cases[cell] = case
    vertex_count[s] = nv
    triangle_count[s] = nt
    center_count[s] = nc


@wp.func
def node_inside(g: wp.vec3i, s: int, c: wp.vec3i, nb: wp.vec3i, n: wp.vec3i, block_slot: wp.array(dtype=wp.int32),
                values: wp.array(dtype=wp.float32), known: wp.array(dtype=wp.uint8)):
    """1 when node g is inside, 0 outside, -1 unknown, read in slot s (block c) or, beyond
    it, in the slot of g's owner block: unknown beyond the grid, in a culled block (an edge
    from a node of slot s into it lies in its closure, of one sign: never a crossing) and
    where ``known`` (one entry per slot node; a single entry: everything known) is 0."""
    r = int(-1)
    inside_grid = True
    for a in range(3):
        if g[a] < 0 or g[a] > n[a] - 1:
            inside_grid = False
    if inside_grid:
        li = g - c * _BLOCK
        slot = s
        if li[0] < 0 or li[1] < 0 or li[2] < 0 or li[0] > _BLOCK or li[1] > _BLOCK or li[2] > _BLOCK:
            ob = wp.vec3i(0, 0, 0)
            for a in range(3):
                ob[a] = wp.min(g[a] / _BLOCK, nb[a] - 1)
            slot = block_slot[ob[0] + nb[0] * (ob[1] + nb[1] * ob[2])]
            li = g - ob * _BLOCK
        if slot >= 0:
            idx = slot * _NODES + local_index(li[0], li[1], li[2])
            if known.shape[0] == 1 or known[idx] != wp.uint8(0):
                r = wp.where(values[idx] > 0.0, 1, 0)
    return r


@wp.func
def lonely(g: wp.vec3i, s: int, c: wp.vec3i, nb: wp.vec3i, n: wp.vec3i, block_slot: wp.array(dtype=wp.int32),
           values: wp.array(dtype=wp.float32), known: wp.array(dtype=wp.uint8), axis: int):
    """Whether node g (a node of slot s, block c) ends no crossing axis edge but its own
    along ``axis`` in any cell: no neighbour along another axis, either way, has the other
    sign (``node_inside``; an unknown node or neighbour never crosses). No triangle then
    has a second vertex next to it. Signs only: the copies of a node in two blocks may
    differ in magnitude (an evaluated value, a proven sign), never in sign, so every block
    gets the same answer for the same node."""
    r = True
    me = node_inside(g, s, c, nb, n, block_slot, values, known)
    if me >= 0:
        for b in range(3):
            if b != axis:
                for side in range(2):
                    e = wp.vec3i(g[0], g[1], g[2])
                    e[b] = g[b] + 2 * side - 1
                    other = node_inside(e, s, c, nb, n, block_slot, values, known)
                    if other >= 0 and other != me:
                        r = False
    return r


@wp.func
def clamped_t(v0: float, v1: float, g: wp.vec3i, d: wp.vec3i, axis: int, n: wp.vec3i, cap: int, n_types: int,
              t_min: float, clearance: float, crowding: int, s: int, c: wp.vec3i, nb: wp.vec3i,
              block_slot: wp.array(dtype=wp.int32), values: wp.array(dtype=wp.float32),
              known: wp.array(dtype=wp.uint8)):
    """The linear vertex parameter t on the crossing edge from node g (of slot s, block c)
    in direction d (vertex type ``axis``; end values v0, v1), clamped to [lo, hi]:
    ``clearance`` (at least t_min) away from each end, which bounds the shape of every
    table triangle (``_conventions.NODE_CLEARANCE``). With the axis edges alone (n_types
    3: "mc", "mc33") an end keeps t_min where no triangle can have a second vertex next to
    it: a node on a capped face (outside, as is every neighbour on its face: the caps stay
    on the bounds), and, when ``crowding`` is set, a *lonely* node (``lonely``; so a plane
    through grid nodes stays on them). A function of the global edge alone: every block
    that places the vertex agrees. An end's exemption is looked at only when t is closer
    to it than the clearance (elsewhere it cannot change the clamp)."""
    raw = v0 / (v0 - v1)
    gap = wp.max(t_min, clearance)
    lo = gap
    hi = 1.0 - gap
    end = int(-1)  # the end t is within the clearance of (at most one: gap <= 1/2)
    if n_types == 3:
        if raw < gap:
            end = 0
        elif raw > 1.0 - gap:
            end = 1
    if end >= 0:
        ge = g + end * d
        exempt = on_capped_face(ge, n, cap)
        if not exempt and crowding != 0:
            exempt = lonely(ge, s, c, nb, n, block_slot, values, known, axis)
        if exempt:
            if end == 0:
                lo = t_min
            else:
                hi = 1.0 - t_min
    return wp.clamp(raw, lo, hi)


@wp.func
def crossing(t: float, d: wp.vec3i, g: wp.vec3i, origin: wp.vec3, h: wp.vec3):
    """(position, t, inside end, outside end) of the crossing at parameter t (``clamped_t``:
    linear interpolation, eq. 16.12, clamped) on the edge from node g in direction d."""
    p0 = wp.vec3(origin[0] + float(g[0]) * h[0], origin[1] + float(g[1]) * h[1],
                 origin[2] + float(g[2]) * h[2])
    p1 = wp.vec3(p0[0] + float(d[0]) * h[0], p0[1] + float(d[1]) * h[1], p0[2] + float(d[2]) * h[2])
    return p0 + t * (p1 - p0), t, p0, p1


@wp.func
def node_key(g: wp.vec3i, goff: wp.vec3i, gn: wp.vec3i):
    """Linear index of node g in the whole grid (a slab's grid starts at goff)."""
    return wp.int64(g[0] + goff[0]) + wp.int64(gn[0]) * (wp.int64(g[1] + goff[1])
                                                         + wp.int64(gn[1]) * wp.int64(g[2] + goff[2]))


@wp.kernel
def emit_vertices_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), nb: wp.vec3i, n: wp.vec3i, n_types: int, cap: int,
    origin: wp.vec3, h: wp.vec3, t_min: float, clearance: float, goff: wp.vec3i, gn: wp.vec3i,
    tab: Tables, values: wp.array(dtype=wp.float32), block_slot: wp.array(dtype=wp.int32),
    known: wp.array(dtype=wp.uint8), crowding: int, vertex_count: wp.array(dtype=wp.int32),
    vertex_offset: wp.array(dtype=wp.int32),
    edge_vertex_id: wp.array(dtype=wp.int32), points: wp.array(dtype=wp.vec3),
    edge_t: wp.array(dtype=wp.float32), edge_p0: wp.array(dtype=wp.vec3),
    edge_p1: wp.array(dtype=wp.vec3), edge_flags: wp.array(dtype=wp.int32),
    edge_key: wp.array(dtype=wp.int64), moved: wp.array(dtype=wp.int32),
):
    """One thread per slot: place the vertex of every crossing edge the block owns by
    linear interpolation (eq. 16.12), t clamped by ``clamped_t`` (the clearance off the
    nodes; ``crowding`` 1 for the lonely-node exemption, ``known`` as in ``node_inside``);
    remember the edge so a root finder can refine it, and its key
    ``node * 8 + type`` in the whole grid; count the vertices the clearance moved.
    Flags: bit 0 = first end inside, bit 1 = an end has the value 0 exactly (on the
    surface, or capped: keep the clamped t), bit 2 = that end is on a capped face, bit 3
    = it is not (an exact root at a node: root refinement puts the vertex t_min from it).
    A slot that owns no crossing edge (``vertex_count``) is skipped."""
    s = wp.tid() + first
    if vertex_count[s] == 0:
        moved[s] = 0
        return
    c = block_coords(slot_block[s], nb)
    base = s * _NODES
    vid = vertex_offset[s]
    n_moved = int(0)
    own = owned_count(c, nb, n)
    for k in range(own[2]):
        for j in range(own[1]):
            for i in range(own[0]):
                l = local_index(i, j, k)
                v0 = values[base + l]
                inside = v0 > 0.0
                g = wp.vec3i(c[0] * _BLOCK + i, c[1] * _BLOCK + j, c[2] * _BLOCK + k)
                for t in range(n_types):
                    d = type_dir(tab, t)
                    if edge_in_grid(g, n, d):
                        v1 = values[base + local_index(i + d[0], j + d[1], k + d[2])]
                        if (v1 > 0.0) != inside:
                            tc = clamped_t(v0, v1, g, d, t, n, cap, n_types, t_min, clearance, crowding, s, c, nb,
                                        block_slot, values, known)
                            p, te, p0, p1 = crossing(tc, d, g + goff, origin, h)
                            if te != wp.clamp(v0 / (v0 - v1), t_min, 1.0 - t_min):
                                n_moved += 1
                            points[vid] = p
                            edge_t[vid] = te
                            edge_p0[vid] = p0
                            edge_p1[vid] = p1
                            flags = int(0)
                            if inside:
                                flags = 1
                            if v0 == 0.0 or v1 == 0.0:
                                flags = flags | 2
                                if on_capped_face(g, n, cap) or on_capped_face(g + d, n, cap):
                                    flags = flags | 4  # a capped (or zero) end on a capped face
                                else:
                                    flags = flags | 8
                            edge_flags[vid] = flags
                            edge_key[vid] = node_key(g, goff, gn) * wp.int64(8) + wp.int64(t)
                            edge_vertex_id[(s * _NODES + l) * n_types + t] = vid
                            vid += 1
    moved[s] = n_moved


@wp.func
def vertex_id(tab: Tables, v: int, g: wp.vec3i, nb: wp.vec3i, block_slot: wp.array(dtype=wp.int32),
              edge_vertex_id: wp.array(dtype=wp.int32), n_types: int, center_id: int, mask: int):
    """Global vertex id of local vertex v of the cell at node g (-1 if its owner block was
    culled, which the host refuses); the cell's interior vertices (``mask``, see
    ``Tables.center``) are numbered from center_id in the order of their local ids."""
    if tab.origin[v, 3] == _CENTER:
        return center_id + interior_count(mask & ((1 << (v - _CENTER_VERTEX)) - 1))
    e = wp.vec3i(g[0] + tab.origin[v, 0], g[1] + tab.origin[v, 1], g[2] + tab.origin[v, 2])
    ob = wp.vec3i(0, 0, 0)
    lo = wp.vec3i(0, 0, 0)
    for a in range(3):
        ob[a] = wp.min(e[a] / _BLOCK, nb[a] - 1)
        lo[a] = e[a] - ob[a] * _BLOCK
    os = block_slot[ob[0] + nb[0] * (ob[1] + nb[1] * ob[2])]
    vid = int(-1)
    if os >= 0:
        vid = edge_vertex_id[(os * _NODES + local_index(lo[0], lo[1], lo[2])) * n_types + tab.origin[v, 3]]
    return vid


@wp.func
def triangle_badness(a: wp.vec3, b: wp.vec3, c: wp.vec3):
    """h_max * perimeter / area (proportional to Q_K = alpha h_max / rho, eq. 16.15;
    larger is worse; a flat triangle scores infinity)."""
    la = wp.length(b - c)
    lb = wp.length(c - a)
    lc = wp.length(a - b)
    area = 0.5 * wp.length(wp.cross(b - a, c - a))
    r = float(3.0e38)
    if area > 0.0:
        r = wp.max(la, wp.max(lb, lc)) * (la + lb + lc) / area
    return r


@wp.func
def cell_point(tab: Tables, v: int, t: float, h: wp.vec3):
    """Position of local vertex v (at parameter t on its edge) relative to the cell origin:
    the same in every slab and block, so quad splits never depend on where the grid starts."""
    d = type_dir(tab, tab.origin[v, 3])
    return wp.vec3((float(tab.origin[v, 0]) + t * float(d[0])) * h[0],
                   (float(tab.origin[v, 1]) + t * float(d[1])) * h[1],
                   (float(tab.origin[v, 2]) + t * float(d[2])) * h[2])


@wp.func
def signed_volume6(points: wp.array(dtype=wp.vec3), tri: wp.vec3i):
    r = wp.float64(0.0)
    if tri[0] >= 0 and tri[1] >= 0 and tri[2] >= 0:
        r = wp.float64(wp.dot(points[tri[0]], wp.cross(points[tri[1]], points[tri[2]])))
    return r


@wp.func
def put_interior(vid: int, p: wp.vec3, cell_key: wp.int64, slot: int, points: wp.array(dtype=wp.vec3),
                 edge_t: wp.array(dtype=wp.float32), edge_p0: wp.array(dtype=wp.vec3),
                 edge_p1: wp.array(dtype=wp.vec3), edge_flags: wp.array(dtype=wp.int32),
                 edge_key: wp.array(dtype=wp.int64)):
    """Store interior vertex ``slot`` (local vertex 12 + slot) of a cell: not on an edge,
    flagged so that root refinement keeps it, keyed ``node * 8 + CENTER`` plus the slot
    in bits 56 and up (unique, never on a seam's edge)."""
    points[vid] = p
    edge_t[vid] = 0.0
    edge_p0[vid] = p
    edge_p1[vid] = p
    edge_flags[vid] = 2
    edge_key[vid] = cell_key * wp.int64(8) + wp.int64(_CENTER) + (wp.int64(slot) << wp.int64(56))


@wp.kernel
def emit_triangles_kernel(
    first: int, slot_block: wp.array(dtype=wp.int32), block_slot: wp.array(dtype=wp.int32),
    nb: wp.vec3i, n: wp.vec3i, n_types: int, cap: int, origin: wp.vec3, h: wp.vec3, t_min: float,
    clearance: float, goff: wp.vec3i, gn: wp.vec3i, tab: Tables, values: wp.array(dtype=wp.float32),
    known: wp.array(dtype=wp.uint8), crowding: int, cell_cases: wp.array(dtype=wp.int32),
    triangle_offset: wp.array(dtype=wp.int32),
    center_offset: wp.array(dtype=wp.int32), edge_vertex_id: wp.array(dtype=wp.int32),
    points: wp.array(dtype=wp.vec3), edge_t: wp.array(dtype=wp.float32), edge_p0: wp.array(dtype=wp.vec3),
    edge_p1: wp.array(dtype=wp.vec3), edge_flags: wp.array(dtype=wp.int32), edge_key: wp.array(dtype=wp.int64),
    triangles: wp.array(dtype=wp.vec3i), slot_volume: wp.array(dtype=wp.float64),
):
    """One thread per slot: the tables' triangles of every cell of the block, with vertex ids
    looked up at the owner block of each edge; interior vertices of "mc33" cells (vertex 12
    at the mean of the cell's edge vertices, placed as ``emit_vertices_kernel`` places
    them; a spoke vertex at the root of the trilinear interpolant between the cell's hub
    and its corner, ``mc33_tables.vertex_positions``); "mt"
    quadrilaterals split along the diagonal that gives the better worst triangle; and the
    block's share of the signed volume (six times p0 . (p1 x p2), summed: the host checks
    the winding)."""
    s = wp.tid() + first
    c = block_coords(slot_block[s], nb)
    out = triangle_offset[s]
    cid = center_offset[s]
    base = s * _NODES
    vol = wp.float64(0.0)
    cells = cell_count(c, n)
    for k in range(cells[2]):
        for j in range(cells[1]):
            for i in range(cells[0]):
                case = cell_cases[s * _CELLS + i + _BLOCK * (j + _BLOCK * k)]
                if case < 0:
                    continue
                g = wp.vec3i(c[0] * _BLOCK + i, c[1] * _BLOCK + j, c[2] * _BLOCK + k)
                center = int(-1)
                mask = tab.center[case]
                if mask != 0:
                    center = cid
                    cid += interior_count(mask)
                    acc = wp.vec3(0.0)
                    m = float(0.0)
                    for t in range(3):  # the cell's 12 axis edges
                        d = type_dir(tab, t)
                        for q in range(8):
                            li = wp.vec3i(i + tab.corners[q, 0], j + tab.corners[q, 1], k + tab.corners[q, 2])
                            if tab.corners[q, t] == 0:
                                v0 = values[base + local_index(li[0], li[1], li[2])]
                                v1 = values[base + local_index(li[0] + d[0], li[1] + d[1], li[2] + d[2])]
                                if (v0 > 0.0) != (v1 > 0.0):
                                    ge = li + c * _BLOCK
                                    tc = clamped_t(v0, v1, ge, d, t, n, cap, n_types, t_min, clearance, crowding, s,
                                                c, nb, block_slot, values, known)
                                    p, te, p0, p1 = crossing(tc, d, ge + goff, origin, h)
                                    acc = acc + p
                                    m += 1.0
                    if (mask & 1) != 0:  # vertex 12: the mean of the edge vertices
                        put_interior(center, acc / wp.max(m, 1.0), node_key(g, goff, gn), 0, points, edge_t,
                                     edge_p0, edge_p1, edge_flags, edge_key)
                    if mask > 1:  # the spokes of the hub construction (kernels/mc33_tables.py)
                        v = mc33_values(values, base, i, j, k, tab)
                        test = tab.interior_test[mc33_entry(v, tab, config_of(values, base, i, j, k, tab))]
                        hub = mc33_hub(v, tab, test, wp.float64(_HUB_MARGIN))
                        f_hub = trilinear(v, tab, hub)
                        gap = wp.float64(wp.max(t_min, clearance))
                        for q in range(8):
                            if ((mask >> (q + 1)) & 1) != 0:
                                u = spoke_point(v, tab, hub, f_hub, q, gap)
                                pq = wp.vec3(origin[0] + (float(g[0] + goff[0]) + float(u[0])) * h[0],
                                             origin[1] + (float(g[1] + goff[1]) + float(u[1])) * h[1],
                                             origin[2] + (float(g[2] + goff[2]) + float(u[2])) * h[2])
                                put_interior(center + interior_count(mask & ((2 << q) - 1)), pq,
                                             node_key(g, goff, gn), q + 1, points, edge_t, edge_p0, edge_p1,
                                             edge_flags, edge_key)
                for q in range(tab.tri_count[case]):
                    tri = wp.vec3i(0, 0, 0)
                    for m3 in range(3):
                        tri[m3] = vertex_id(tab, tab.tris[case, q * 3 + m3], g, nb, block_slot, edge_vertex_id,
                                            n_types, center, mask)
                    triangles[out] = tri
                    out += 1
                    vol += signed_volume6(points, tri)
                for q in range(tab.quad_count[case]):
                    a = vertex_id(tab, tab.quads[case, q * 4 + 0], g, nb, block_slot, edge_vertex_id, n_types, center, mask)
                    b = vertex_id(tab, tab.quads[case, q * 4 + 1], g, nb, block_slot, edge_vertex_id, n_types, center, mask)
                    e = vertex_id(tab, tab.quads[case, q * 4 + 2], g, nb, block_slot, edge_vertex_id, n_types, center, mask)
                    f = vertex_id(tab, tab.quads[case, q * 4 + 3], g, nb, block_slot, edge_vertex_id, n_types, center, mask)
                    t1 = wp.vec3i(a, b, e)
                    t2 = wp.vec3i(a, e, f)
                    if a >= 0 and b >= 0 and e >= 0 and f >= 0:
                        pa = cell_point(tab, tab.quads[case, q * 4 + 0], edge_t[a], h)
                        pb = cell_point(tab, tab.quads[case, q * 4 + 1], edge_t[b], h)
                        pe = cell_point(tab, tab.quads[case, q * 4 + 2], edge_t[e], h)
                        pf = cell_point(tab, tab.quads[case, q * 4 + 3], edge_t[f], h)
                        w02 = wp.max(triangle_badness(pa, pb, pe), triangle_badness(pa, pe, pf))
                        w13 = wp.max(triangle_badness(pa, pb, pf), triangle_badness(pb, pe, pf))
                        if w13 < w02:
                            t1 = wp.vec3i(a, b, f)
                            t2 = wp.vec3i(b, e, f)
                    triangles[out] = t1
                    triangles[out + 1] = t2
                    out += 2
                    vol += signed_volume6(points, t1) + signed_volume6(points, t2)
    slot_volume[s] = vol
# -- root refinement along crossing edges [FG §16.3.3] ------------------------------------
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
    flags: wp.array(dtype=wp.int32), midpoint: int, t_min: float, t_lo: wp.array(dtype=wp.float32),
    t_hi: wp.array(dtype=wp.float32), t: wp.array(dtype=wp.float32),
):
    """One thread per vertex: the bracket [0, 1] of the edge parameter; start at its
    midpoint (bisection) or keep the linear estimate (Newton). An exact root at a node
    (flag bit 3), which the emission's clearance moved off it, goes back to t_min from it."""
    v = wp.tid()
    t_lo[v] = 0.0
    t_hi[v] = 1.0
    if (flags[v] & 8) != 0:
        t[v] = wp.where(t[v] < 0.5, t_min, 1.0 - t_min)
    elif midpoint != 0 and (flags[v] & 2) == 0:
        t[v] = 0.5


@wp.kernel
def bisection_step_kernel(
    flags: wp.array(dtype=wp.int32), f_mid: wp.array(dtype=wp.float32),
    t_lo: wp.array(dtype=wp.float32), t_hi: wp.array(dtype=wp.float32), t: wp.array(dtype=wp.float32),
):
    """One thread per vertex: keep the half of the bracket where f changes sign. The end
    at t_lo is the p0 end; 'inside' is f > 0, as in the classification, so a sub-segment
    where f vanishes is kept on the side of the outside end [FG Fig. 16.9]."""
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


@wp.kernel
def add_offset_kernel(offset: int, values: wp.array(dtype=wp.int32)):
    """One thread per entry: values += offset."""
    i = wp.tid()
    values[i] = values[i] + offset


# -- finite-difference gradients [FG eq. 16.13, 16.14] --------------------------------------
@wp.kernel
def fd_points_kernel(points: wp.array(dtype=wp.vec3), step: wp.vec3, central: int,
                     shifted: wp.array(dtype=wp.vec3)):
    """One thread per point P: the points where f is sampled, P then P + step_a e_a for
    each axis a, and for the centred scheme also P - step_a e_a (7 or 4 per point)."""
    v = wp.tid()
    per = 4 + 3 * central
    p = points[v]
    shifted[v * per] = p
    for a in range(3):
        d = wp.vec3(0.0)
        d[a] = step[a]
        shifted[v * per + 1 + a] = p + d
        if central != 0:
            shifted[v * per + 4 + a] = p - d


@wp.kernel
def fd_gradient_kernel(values: wp.array(dtype=wp.float32), step: wp.vec3, central: int,
                       fg: wp.array(dtype=wp.vec4)):
    """One thread per point: (f, df/dx, df/dy, df/dz) by forward differences,
    (f(P + h e_a) - f(P)) / h (eq. 16.13), or centred ones,
    (f(P + h e_a) - f(P - h e_a)) / 2h (eq. 16.14)."""
    v = wp.tid()
    per = 4 + 3 * central
    f = values[v * per]
    r = wp.vec4(f, 0.0, 0.0, 0.0)
    for a in range(3):
        if central != 0:
            r[1 + a] = (values[v * per + 1 + a] - values[v * per + 4 + a]) / (2.0 * step[a])
        else:
            r[1 + a] = (values[v * per + 1 + a] - f) / step[a]
    fg[v] = r
