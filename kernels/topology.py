"""Half-edge topology of triangle meshes for the mesh statistics: twins of every
half-edge, fans around every vertex, edge-connected components, face measures and quality.

Half-edge ``h = 3 f + j`` runs from ``faces[h]`` to ``faces[3 f + (j + 1) % 3]``
(``faces`` flattened, the numbering of :mod:`warpmesh.cells.topology`). The host sorts
the half-edges by their smaller end (:func:`count_keys_kernel`, :func:`scatter_keys_kernel`:
a counting sort with one count row and one range per CPU worker), so one thread per
vertex matches the half-edges of its run among themselves: no sort of the edges; the
half-edges leaving each vertex (``offsets``, ``out_of``) come from the same sort by start
vertex, for the fans. Faces with a repeated vertex are handled on the host (these
kernels assume three distinct corners). The per-vertex and per-face kernels take
``first`` so the host can split a launch across CPU cores; the union-find runs on one
thread.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.func
def next_half_edge(h: int) -> int:
    """The half-edge after ``h`` in its face (its destination's corner)."""
    if h % 3 == 2:
        return h - 2
    return h + 1


@wp.func
def prev_half_edge(h: int) -> int:
    """The half-edge before ``h`` in its face (it ends where ``h`` starts)."""
    if h % 3 == 0:
        return h + 2
    return h - 1


@wp.func
def walk_fan(faces: wp.array(dtype=wp.int32), twin: wp.array(dtype=wp.int32), v: int, start: int, leave: int,
             limit: int) -> wp.vec2i:
    """From the corner of half-edge ``start`` (leaving v), cross edge ``leave`` and go
    on around v from corner to corner through the twins. Returns (corners met besides
    ``start``, 1 if the walk came back to ``start``)."""
    e = leave
    met = int(0)
    closed = int(0)
    while met <= limit:
        t = twin[e]
        if t < 0:  # a boundary edge (no edge of v has more than two faces here)
            break
        c = t
        if faces[t] == v:  # t leaves v: its corner is t, left by the edge into v
            e = prev_half_edge(t)
        else:  # t enters v: v's corner is the next half-edge, left by itself
            c = next_half_edge(t)
            e = c
        if c == start:
            closed = 1
            break
        met += 1
    return wp.vec2i(met, closed)


@wp.kernel
def fan_check_kernel(
    first: int, faces: wp.array(dtype=wp.int32), offsets: wp.array(dtype=wp.int32),
    out_of: wp.array(dtype=wp.int32), twin: wp.array(dtype=wp.int32), bad: wp.array(dtype=wp.int8),
):
    """A thread takes vertex v = first + tid and marks it non-manifold (``bad``) when an
    edge through it has more than two faces or its faces do not form one fan: the walk
    around v from its first corner, both ways, must meet all of its corners."""
    v = first + wp.tid()
    lo = offsets[v]
    corners = offsets[v + 1] - lo
    bad[v] = wp.int8(0)
    if corners == 0:
        return
    for k in range(lo, lo + corners):
        h = out_of[k]
        if twin[h] == -2 or twin[prev_half_edge(h)] == -2:
            bad[v] = wp.int8(1)
            return
    h0 = out_of[lo]
    a = walk_fan(faces, twin, v, h0, h0, corners)
    met = 1 + a[0]
    if a[1] == 0:
        b = walk_fan(faces, twin, v, h0, prev_half_edge(h0), corners)
        met += b[0]
    if met != corners:
        bad[v] = wp.int8(1)


@wp.func
def find_root(parent: wp.array(dtype=wp.int32), x: int) -> int:
    """Union-find root of ``x``, halving the path on the way."""
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@wp.kernel
def union_faces_kernel(rep: wp.array(dtype=wp.int32), parent: wp.array(dtype=wp.int32),
                       count: wp.array(dtype=wp.int32)):
    """One thread joins the face of every half-edge with the face of its edge's
    representative (``parent`` starts as the identity), then counts the roots: the
    edge-connected components."""
    for h in range(rep.shape[0]):
        r = rep[h]
        if r != h:
            a = find_root(parent, h // 3)
            b = find_root(parent, r // 3)
            if a < b:
                parent[b] = a
            elif b < a:
                parent[a] = b
    c = int(0)
    for f in range(parent.shape[0]):
        if parent[f] == f:
            c += 1
    count[0] = c


@wp.kernel
def label_faces_kernel(parent: wp.array(dtype=wp.int32), rank: wp.array(dtype=wp.int32),
                       labels: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32)):
    """One thread labels every face f with its union-find root's component, the components
    numbered 0.. in order of first appearance (``rank`` starts at -1 for every face);
    ``count[0]`` the number of components."""
    c = int(0)
    for f in range(parent.shape[0]):
        r = find_root(parent, f)
        if rank[r] < 0:
            rank[r] = c
            c += 1
        labels[f] = rank[r]
    count[0] = c


@wp.kernel
def face_measures_kernel(
    first: int, points: wp.array(dtype=wp.vec3d), faces: wp.array(dtype=wp.int32), centre: wp.vec3d,
    alpha: wp.float64, rel_tol: wp.float64,
    area: wp.array(dtype=wp.float64), volume6: wp.array(dtype=wp.float64), quality: wp.array(dtype=wp.float64),
):
    """A thread takes face f = first + tid: its area |(p1 - p0) x (p2 - p0)| / 2, six
    times the signed volume of the tetrahedron (centre, p0, p1, p2), and its shape
    measure Q = alpha h_max / rho with rho = 2 area / perimeter [FG eq. 16.15], or -1
    when degenerate (area <= rel_tol h_max^2; the host makes that inf)."""
    f = first + wp.tid()
    p0 = points[faces[3 * f]]
    p1 = points[faces[3 * f + 1]]
    p2 = points[faces[3 * f + 2]]
    c = wp.cross(p1 - p0, p2 - p0)
    a = wp.float64(0.5) * wp.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])
    area[f] = a
    volume6[f] = wp.dot(p0 - centre, wp.cross(p1 - centre, p2 - centre))
    la = wp.length(p1 - p0)
    lb = wp.length(p2 - p1)
    lc = wp.length(p0 - p2)
    h = wp.max(wp.max(la, lb), lc)
    if a <= rel_tol * h * h:
        quality[f] = wp.float64(-1.0)
    else:
        quality[f] = alpha * h * (la + lb + lc) / (wp.float64(2.0) * a)


@wp.func
def twice_area(a: wp.vec3d, b: wp.vec3d) -> wp.float64:
    """|a x b|: twice the area of the triangle spanned by a and b."""
    c = wp.cross(a, b)
    return wp.sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2])


@wp.kernel
def tet_measures_kernel(
    first: int, points: wp.array(dtype=wp.vec3d), tets: wp.array(dtype=wp.int32), alpha: wp.float64,
    rel_tol: wp.float64, volume6: wp.array(dtype=wp.float64), quality: wp.array(dtype=wp.float64),
):
    """A thread takes tetrahedron t = first + tid: six times its signed volume,
    det(p1 - p0, p2 - p0, p3 - p0), and its shape measure Q = alpha h_max / rho with
    rho = 3 volume / (sum of the face areas) [FG eq. 16.15], i.e. alpha h_max S2 / |det|
    with S2 twice the total area; -1 when degenerate (volume <= rel_tol h_max^3; the host
    makes that inf)."""
    t = first + wp.tid()
    p0 = points[tets[4 * t]]
    p1 = points[tets[4 * t + 1]]
    p2 = points[tets[4 * t + 2]]
    p3 = points[tets[4 * t + 3]]
    a = p1 - p0
    b = p2 - p0
    c = p3 - p0
    d = p2 - p1
    e = p3 - p1
    f = p3 - p2
    h2 = wp.max(wp.max(wp.max(wp.dot(a, a), wp.dot(b, b)), wp.max(wp.dot(c, c), wp.dot(d, d))),
                wp.max(wp.dot(e, e), wp.dot(f, f)))
    h = wp.sqrt(h2)
    v6 = wp.dot(a, wp.cross(b, c))
    volume6[t] = v6
    s2 = twice_area(a, b) + twice_area(a, c) + twice_area(b, c) + twice_area(d, e)
    if wp.abs(v6) / wp.float64(6.0) <= rel_tol * h2 * h:
        quality[t] = wp.float64(-1.0)
    else:
        quality[t] = alpha * h * s2 / wp.abs(v6)


@wp.kernel
def count_keys_kernel(lo: int, hi: int, keys: wp.array(dtype=wp.int32), counts: wp.array(dtype=wp.int32)):
    """One thread counts the items of [lo, hi) by key into its own ``counts`` row (a
    counting sort's first pass, one launch per worker; no atomics)."""
    for i in range(lo, hi):
        k = keys[i]
        counts[k] = counts[k] + 1


@wp.kernel
def scatter_keys_kernel(lo: int, hi: int, keys: wp.array(dtype=wp.int32), cursor: wp.array(dtype=wp.int32),
                        order: wp.array(dtype=wp.int32)):
    """One thread places the items of [lo, hi) at their key's next free slot (``cursor``:
    this worker's own start of each key's run, advanced as it goes): ``order[slot] = i``,
    so each key's run holds its items in ascending order."""
    for i in range(lo, hi):
        k = keys[i]
        s = cursor[k]
        order[s] = i
        cursor[k] = s + 1


@wp.kernel
def cell_extents_kernel(first: int, x: wp.array(dtype=wp.float64), cells: wp.array(dtype=wp.int64), k: int,
                        lo: wp.array(dtype=wp.float64), hi: wp.array(dtype=wp.float64)):
    """A thread takes cell c = first + tid of k corners (``cells[k c : k c + k]``): the
    smallest and largest of the coordinate ``x`` over its corners."""
    c = first + wp.tid()
    base = wp.int64(k) * wp.int64(c)  # (beyond 2^31 corners)
    a = x[cells[base]]
    b = a
    for j in range(1, k):
        v = x[cells[base + wp.int64(j)]]
        a = wp.min(a, v)
        b = wp.max(b, v)
    lo[c] = a
    hi[c] = b


@wp.kernel
def match_half_edges_by_lead_kernel(
    first: int, offsets: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
    other: wp.array(dtype=wp.int32), forward: wp.array(dtype=wp.int8),
    rep: wp.array(dtype=wp.int32), twin: wp.array(dtype=wp.int32), tally: wp.array(dtype=wp.int32),
):
    """A thread takes vertex w = first + tid and matches the half-edges whose smaller end
    is w among themselves (one contiguous run of the half-edges sorted by smaller end,
    ``order``; ``other`` their larger end, ``forward`` 1 when they run from w): for each
    such half-edge h, ``rep[h]`` the smallest half-edge of its undirected edge and
    ``twin[h]`` the other one when the edge has two, -1 when one, -2 when more (as
    the undirected edges of a triangle mesh). ``tally`` (this launch's own) counts edges, edges in
    one face, edges in more than two, and half-edges that repeat a direction."""
    w = first + wp.tid()
    lo = offsets[w]
    hi = offsets[w + 1]
    for i in range(lo, hi):
        x = other[i]
        d = forward[i]
        h = order[i]
        m = int(0)
        s = int(0)
        r = h
        t = int(-1)
        for j in range(lo, hi):
            if other[j] == x:
                g = order[j]
                m += 1
                if forward[j] == d:
                    s += 1
                r = wp.min(r, g)
                if g != h:
                    t = g
        rep[h] = r
        if m == 2:
            twin[h] = t
        elif m == 1:
            twin[h] = -1
        else:
            twin[h] = -2
        if r == h:
            tally[0] = tally[0] + 1
            if m == 1:
                tally[1] = tally[1] + 1
            if m > 2:
                tally[2] = tally[2] + 1
        if s > 1:
            tally[3] = tally[3] + 1


@wp.kernel
def face_volumes_kernel(
    first: int, points: wp.array(dtype=wp.vec3d), faces: wp.array(dtype=wp.int32),
    labels: wp.array(dtype=wp.int32), centres: wp.array(dtype=wp.vec3d), volume6: wp.array(dtype=wp.float64),
):
    """A thread takes face f = first + tid: six times the signed volume of the tetrahedron
    (c, p0, p1, p2) with c its group's centre ``centres[labels[f]]``."""
    f = first + wp.tid()
    c = centres[labels[f]]
    p0 = points[faces[3 * f]] - c
    p1 = points[faces[3 * f + 1]] - c
    p2 = points[faces[3 * f + 2]] - c
    volume6[f] = wp.dot(p0, wp.cross(p1, p2))
