"""Sequential graph walks of node renumbering and element colouring [FG §17.4]:
breadth-first searches, Cuthill–McKee numbering over a level structure, connected
components of a node subset, greedy colouring.

These walks are sequential by nature — the order of a level depends on the order of the
one before, a node's colour on the colours before it — so each such kernel is launched
with ``dim=1`` and one thread walks the whole graph: compiled code instead of one Python
round of array operations per level (a 2D mesh has about a thousand levels). The same
code runs on CUDA, on one thread.

Graphs are CSR arrays (``indptr``, ``indices``: no diagonal; rows in any order), int32. The
per-node kernels (relabelling, profile) take ``first`` so the host can split a launch
across CPU cores; those that count with atomic adds (Step 2's pairs, column counts) are
one launch each (Warp's CPU atomics are plain adds, its CPU launch one thread).

Inner loops over a row are ``while`` loops: Warp's ``range()`` loops cost ~20 % more in
these walks, and so does bookkeeping (a read-modify-write per node) inside a
random-access search, which is why candidates and counts get passes of their own.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})

#: how many nodes ahead of the one it takes a search prefetches rows (measured on a
#: 500 k-node plate: 4-16 alike; the first search of the randomly numbered graph 51 ->
#: 30 ms, a descent of the relabelled graph from an end of its diameter 16 -> 12 ms)
PREFETCH_AHEAD = wp.constant(8)


@wp.func_native("""
#if !defined(__CUDA_ARCH__)
__builtin_prefetch((const char*)a.data + (size_t)i * a.strides[0]);
#endif
""")
def prefetch(a: wp.array(dtype=wp.int32), i: int):
    """A hint that ``a[i]`` is read soon: on the CPU the cache line is fetched while
    the thread works on (``i`` may be one past the end: a prefetch never faults); nothing
    on CUDA."""
    ...


@wp.kernel
def number_levels_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32),
    lev: wp.array(dtype=wp.int32), key: wp.array(dtype=wp.int32),
    members: wp.array(dtype=wp.int32), bounds: wp.array(dtype=wp.int32),
    comp_start: wp.array(dtype=wp.int32), comp_levels: wp.array(dtype=wp.int32),
    comp_first: wp.array(dtype=wp.int32),
    num: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32), buf: wp.array(dtype=wp.int32),
    delta: wp.array(dtype=wp.int32), delta_reversed: wp.array(dtype=wp.int32), stray: wp.array(dtype=wp.int32),
):
    """One thread numbers every component level by level (Gibbs Step 3, Cuthill–McKee).

    Component c starts at node ``comp_start[c]`` with number ``comp_first[c]``; its
    levels are the global level indices ``comp_levels[c]`` .. ``comp_levels[c + 1] - 1``.
    ``lev`` is each node's global level index, overwritten with -1 as nodes get their
    number (one load tells "in level k and not yet numbered"); ``members[bounds[k]:
    bounds[k + 1]]`` are level k's nodes by increasing (key, index). In level k (phase
    0) the numbered nodes, in number order, number their unnumbered neighbours of
    level k; when none is left to reach, the unnumbered member of smallest key starts
    again. Then (phase 1) the level's nodes, in number order, number their neighbours
    of level k + 1. A node numbers its neighbours by increasing key (ties: index, the
    row order).

    The profile of the numbering and of its reverse come on the way (``delta``,
    ``delta_reversed``: as :func:`profile_kernel`'s, i - j_i [FG Table 17.1] per node),
    as levels hold neighbours at most one apart: a node's smallest neighbour number is
    the one of the node that numbered it (0 for a start), its largest the last one it
    gives in phase 1 or, if it gives none, the largest in its row then (every neighbour
    is numbered by then); a component's last level reads its rows once more at the
    end. ``num`` starts at -1; ``stray[0]`` (starting at 0) counts the neighbours found
    unnumbered in phase 1 outside level k + 1: not 0 when ``lev`` is not a level
    structure (or a start is not in its component's first level), and then the profile
    is not this kernel's to tell.
    """
    strays = int(0)
    for c in range(comp_start.shape[0]):
        nxt = comp_first[c]
        start = comp_start[c]
        if lev[start] != comp_levels[c]:
            strays += 1
        num[start] = nxt
        out[nxt] = start
        lev[start] = -1
        delta[start] = 0
        nxt += 1
        level_first = comp_first[c]
        for k in range(comp_levels[c], comp_levels[c + 1]):
            size = bounds[k + 1] - bounds[k]
            scan = bounds[k]
            head = level_first
            stop = int(0)
            phase = int(0)
            while phase < 2:
                u = int(-1)
                target = k
                if phase == 0:
                    if nxt - level_first >= size:  # level complete: on to its next level
                        phase = 1
                        head = level_first
                        stop = nxt
                        if k + 1 >= comp_levels[c + 1]:
                            phase = 2
                    elif head < nxt:
                        u = out[head]
                        if head + PREFETCH_AHEAD < nxt:  # as in descent_kernel
                            prefetch(indices, indptr[out[head + PREFETCH_AHEAD]])
                        head += 1
                    else:  # no numbered node reaches the rest: smallest key starts again
                        while lev[members[scan]] < 0:
                            scan += 1
                        v = members[scan]
                        num[v] = nxt
                        out[nxt] = v
                        lev[v] = -1
                        delta[v] = 0
                        nxt += 1
                else:
                    if head < stop:
                        u = out[head]
                        if head + PREFETCH_AHEAD < stop:
                            prefetch(indices, indptr[out[head + PREFETCH_AHEAD]])
                        head += 1
                        target = k + 1
                    else:
                        level_first = stop
                        phase = 2
                if u >= 0:
                    m = int(0)
                    e = indptr[u]
                    end = indptr[u + 1]
                    while e < end:
                        v = indices[e]
                        e += 1
                        lv = lev[v]
                        if lv == target:  # in the target level and not yet numbered
                            t = m  # insertion sort by (key, index): rows need not be sorted
                            kv = key[v]
                            while t > 0:
                                w = buf[t - 1]
                                kw = key[w]
                                if kw < kv or (kw == kv and w < v):
                                    break
                                buf[t] = w
                                t -= 1
                            buf[t] = v
                            m += 1
                        elif lv >= 0 and target > k:  # unnumbered, and not by u: no level structure
                            strays += 1
                    own = num[u]
                    for t in range(m):
                        num[buf[t]] = nxt
                        out[nxt] = buf[t]
                        lev[buf[t]] = -1
                        delta[buf[t]] = nxt - own
                        nxt += 1
                    if target > k:  # phase 1: every neighbour of u has its number now
                        hi = nxt - 1
                        if m == 0:
                            hi = own
                            e = indptr[u]
                            while e < end:
                                hi = wp.max(hi, num[indices[e]])
                                e += 1
                        delta_reversed[u] = hi - own
        h = level_first  # the last level's rows, read once more: every number is given
        while h < nxt:
            u = out[h]
            h += 1
            own = num[u]
            hi = own
            e = indptr[u]
            end = indptr[u + 1]
            while e < end:
                hi = wp.max(hi, num[indices[e]])
                e += 1
            delta_reversed[u] = hi - own
    stray[0] = strays


@wp.kernel
def sort_levels_kernel(
    level: wp.array(dtype=wp.int32), key: wp.array(dtype=wp.int32), span: int,
    count: wp.array(dtype=wp.int32), members: wp.array(dtype=wp.int32), bounds: wp.array(dtype=wp.int32),
):
    """One thread sorts the nodes by (``level``, ``key``, index) with a counting sort over
    the buckets level * ``span`` + key (``key`` < ``span``; ``count`` of length
    levels * span + 1, starting at 0): ``members`` gets the nodes in that order and
    ``bounds[k]`` (levels + 1 entries) where level k starts in it."""
    n = level.shape[0]
    v = int(0)
    while v < n:
        count[level[v] * span + key[v] + 1] += 1
        v += 1
    b = int(1)
    while b < count.shape[0]:  # count[b]: where bucket b starts
        count[b] += count[b - 1]
        b += 1
    for k in range(bounds.shape[0]):
        bounds[k] = count[k * span]
    v = int(0)
    while v < n:
        b = level[v] * span + key[v]
        members[count[b]] = v
        count[b] += 1
        v += 1


@wp.kernel
def descent_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32),
    sources: wp.array(dtype=wp.int32), comp: wp.array(dtype=wp.int32), deg: wp.array(dtype=wp.int32),
    level: wp.array(dtype=wp.int32), queue: wp.array(dtype=wp.int32),
    depth: wp.array(dtype=wp.int32), last: wp.array(dtype=wp.int32), finished: wp.array(dtype=wp.int32),
    columns: wp.array(dtype=wp.int32),
):
    """One thread searches breadth-first from all ``sources`` at once (one per component):
    ``level`` (starting at -1) gets each node's distance to the source of its component
    ``comp``. Then, walking the queue back from its end (levels come in nondecreasing
    order), for each such component c: ``depth[c]`` (starting at -1) gets its last level
    and ``last[c]`` the node of that level of smallest (``deg``, index), the next
    candidate end of a pseudo-diameter [FG §17.4, Step 1]; ``finished`` (starting at 0)
    marks the components passed. Bookkeeping inside the search loop cost a third more.
    ``queue`` has n + 1 slots: every neighbour is written at the tail and kept only when
    new (no branch on it: 17 -> 11.5 ms on a 500 k-node plate). ``columns`` counts the
    entries of each column met on the way (all of them when the sources reach every
    node: a symmetry check almost free here, 4 ms as a pass of its own)."""
    tail = int(0)
    for s in range(sources.shape[0]):
        level[sources[s]] = 0
        queue[tail] = sources[s]
        tail += 1
    head = int(0)
    while head < tail:
        u = queue[head]
        a = head + PREFETCH_AHEAD  # rows read later, fetched now: the search's order is not the memory's
        if a < tail:
            prefetch(indices, indptr[queue[a]])
            if a + PREFETCH_AHEAD < tail:
                prefetch(indptr, queue[a + PREFETCH_AHEAD])
        head += 1
        lv = level[u] + 1
        e = indptr[u]
        end = indptr[u + 1]
        while e < end:  # a while loop: Warp's range() loops cost ~20 % more here
            v = indices[e]
            e += 1
            x = level[v]
            columns[v] += 1
            level[v] = wp.where(x < 0, lv, x)  # branch-free (which neighbours are new is unpredictable)
            queue[tail] = v  # kept only if new: the queue has a spare slot at its end
            tail += int(x < 0)
    remaining = sources.shape[0]
    t = tail - 1
    while t >= 0 and remaining > 0:
        v = queue[t]
        t -= 1
        c = comp[v]
        if depth[c] < 0:  # the last node of c in the queue: its level is c's depth
            depth[c] = level[v]
            last[c] = v
        elif level[v] == depth[c]:
            w = last[c]
            if deg[v] < deg[w] or (deg[v] == deg[w] and v < w):
                last[c] = v
        elif finished[c] == 0:
            finished[c] = 1
            remaining -= 1


@wp.kernel
def pair_levels_kernel(
    p_level: wp.array(dtype=wp.int32), q_level: wp.array(dtype=wp.int32), comp: wp.array(dtype=wp.int32),
    first_level: wp.array(dtype=wp.int32), depth: wp.array(dtype=wp.int32),
    fi: wp.array(dtype=wp.int32), fj: wp.array(dtype=wp.int32), label: wp.array(dtype=wp.int32),
    fixed_count: wp.array(dtype=wp.int32), width_p: wp.array(dtype=wp.int32), width_q: wp.array(dtype=wp.int32),
):
    """A thread takes one node v of Gibbs Step 2 [FG §17.4]: its pair (i, j) = (D(P),
    d - 1 - D(Q)) as "flat" levels (its component's first level + the level) ``fi``,
    ``fj``; ``label`` -2 when i = j (fixed, counted in ``fixed_count``), else -1 (to be
    placed); the widths of D(P) and D(Q) counted in ``width_p``, ``width_q``. The counts
    are atomic adds (plain adds on the CPU, where the launch runs on one thread)."""
    v = wp.tid()
    c = comp[v]
    base = first_level[c]
    a = base + p_level[v]
    b = base + depth[c] - 1 - q_level[v]
    fi[v] = a
    fj[v] = b
    wp.atomic_add(width_p, a, 1)
    wp.atomic_add(width_q, base + q_level[v], 1)
    if a == b:
        wp.atomic_add(fixed_count, a, 1)
        label[v] = -2
    else:
        label[v] = -1


@wp.kernel
def label_components_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32), nodes: wp.array(dtype=wp.int32),
    label: wp.array(dtype=wp.int32), queue: wp.array(dtype=wp.int32), starts: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
):
    """One thread labels the connected components of the subgraph induced by ``nodes``
    (ascending; ``label`` starts at -1 on them, at any other negative value elsewhere),
    numbered in the order of their smallest node. ``queue`` (one slot more than the
    nodes) ends with every component's nodes, one after the other, each in
    breadth-first order from its smallest node; component c is ``queue[starts[c]:
    starts[c + 1]]`` (``starts`` as long as ``queue``); ``count[0]`` gets the number of
    components."""
    c = int(0)
    tail = int(0)
    for t in range(nodes.shape[0]):
        s = nodes[t]
        if label[s] == -1:
            starts[c] = tail
            label[s] = c
            queue[tail] = s
            head = tail
            tail += 1
            while head < tail:
                u = queue[head]
                if head + PREFETCH_AHEAD < tail:  # as in descent_kernel
                    prefetch(indices, indptr[queue[head + PREFETCH_AHEAD]])
                head += 1
                e = indptr[u]
                end = indptr[u + 1]
                while e < end:
                    v = indices[e]
                    e += 1
                    x = label[v]
                    label[v] = wp.where(x == -1, c, x)  # branch-free, as in descent_kernel
                    queue[tail] = v  # kept only if new: the queue has a spare slot at its end
                    tail += int(x == -1)
            c += 1
    starts[c] = tail
    count[0] = c


@wp.kernel
def place_pieces_kernel(
    grouped: wp.array(dtype=wp.int32), starts: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
    owner: wp.array(dtype=wp.int32), fi: wp.array(dtype=wp.int32), fj: wp.array(dtype=wp.int32),
    width_p: wp.array(dtype=wp.int32), width_q: wp.array(dtype=wp.int32),
    counts: wp.array(dtype=wp.int32), flat: wp.array(dtype=wp.int32),
    ci: wp.array(dtype=wp.int32), cj: wp.array(dtype=wp.int32),
):
    """One thread places the pieces of Gibbs Step 2 [FG §17.4] in ``order``: piece p
    (nodes ``grouped[starts[p]:starts[p + 1]]``, of component ``owner[p]``) goes to its
    nodes' levels ``fi`` (side i) or ``fj`` (side j), whichever keeps the widest level it
    touches smaller, counting the levels placed so far (``counts``, the fixed nodes to
    begin with); ties: side i when D(P)'s width ``width_p`` is at most D(Q)'s. ``flat``
    gets each placed node's level, ``counts`` grows; ``ci``, ``cj`` (one per level,
    starting at 0) are scratch and end at 0."""
    for r in range(order.shape[0]):
        p = order[r]
        first = starts[p]
        stop = starts[p + 1]
        h0 = int(0)
        l0 = int(0)
        t = first
        while t < stop:  # the piece's count per level, each side, and the widest level it would give
            v = grouped[t]
            a = fi[v]
            ci[a] += 1
            h0 = wp.max(h0, counts[a] + ci[a])  # a level's last count is its largest
            b = fj[v]
            cj[b] += 1
            l0 = wp.max(l0, counts[b] + cj[b])
            t += 1
        c = owner[p]
        side_i = h0 < l0 or (h0 == l0 and width_p[c] <= width_q[c])
        t = first
        while t < stop:
            v = grouped[t]
            a = fi[v]
            b = fj[v]
            ci[a] = 0
            cj[b] = 0
            if not side_i:
                a = b
            flat[v] = a
            counts[a] += 1
            t += 1


@wp.kernel
def relabel_rows_kernel(
    first: int, indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32),
    old_of_new: wp.array(dtype=wp.int32), new_of_old: wp.array(dtype=wp.int32),
    new_indptr: wp.array(dtype=wp.int32), new_indices: wp.array(dtype=wp.int32),
):
    """A thread writes row r = first + tid of the relabelled graph: the neighbours of
    node ``old_of_new[r]`` under their new labels, sorted (insertion sort: rows are
    short)."""
    r = first + wp.tid()
    u = old_of_new[r]
    base = new_indptr[r]
    m = int(0)
    for e in range(indptr[u], indptr[u + 1]):
        v = new_of_old[indices[e]]
        t = m
        while t > 0:
            w = new_indices[base + t - 1]
            if w <= v:
                break
            new_indices[base + t] = w
            t -= 1
        new_indices[base + t] = v
        m += 1


@wp.kernel
def profile_kernel(
    first: int, indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32), num: wp.array(dtype=wp.int32),
    delta: wp.array(dtype=wp.int32), delta_reversed: wp.array(dtype=wp.int32),
):
    """A thread finds, for one node, its distance to the first column of its matrix row
    [FG Table 17.1: i - j_i] under ``num`` and under the reversed numbering; node
    i = first + tid."""
    i = first + wp.tid()
    own = num[i]
    lo = own
    hi = own
    e = indptr[i]
    end = indptr[i + 1]
    while e < end:
        x = num[indices[e]]
        e += 1
        lo = wp.min(lo, x)
        hi = wp.max(hi, x)
    delta[i] = own - lo
    delta_reversed[i] = hi - own


@wp.kernel
def search_relabel_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32), start: int,
    new_of_old: wp.array(dtype=wp.int32), old_of_new: wp.array(dtype=wp.int32),
    level: wp.array(dtype=wp.int32), new_indptr: wp.array(dtype=wp.int32),
    new_indices: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32),
):
    """One thread searches breadth-first from ``start`` and relabels as it goes: a node's
    label is its place in the search, ``level`` (by label) its level, and row r of the
    relabelled graph (``new_indptr``, ``new_indices``) is written when node r is
    taken off the queue — by then every neighbour has its label; its labels stay in
    the input row's order (unsorted). One pass over the (randomly numbered) input
    instead of a search and then a relabelling. ``new_of_old`` starts at -1;
    ``count[0]`` gets the number of nodes reached, ``count[1]`` the number of diagonal
    entries met."""
    new_of_old[start] = 0
    old_of_new[0] = start
    level[0] = 0
    new_indptr[0] = 0
    tail = int(1)
    pos = int(0)
    head = int(0)
    diagonal = int(0)
    while head < tail:
        u = old_of_new[head]
        lv = level[head] + 1
        a = head + PREFETCH_AHEAD  # rows read later, fetched now: the input is in random order
        if a < tail:
            prefetch(indices, indptr[old_of_new[a]])
            if a + PREFETCH_AHEAD < tail:
                prefetch(indptr, old_of_new[a + PREFETCH_AHEAD])
        e = indptr[u]
        end = indptr[u + 1]
        while e < end:  # a while loop: Warp's range() loops cost ~20 % more here
            v = indices[e]
            e += 1
            x = new_of_old[v]
            if x < 0:  # a branch: branch-free writes to this randomly numbered array cost more (32 -> 42 ms)
                x = tail
                new_of_old[v] = x
                old_of_new[x] = v
                level[x] = lv
                tail += 1
            if x == head:
                diagonal += 1
            new_indices[pos] = x  # rows stay unsorted: sorting them cost 40 % of the pass
            pos += 1
        head += 1
        new_indptr[head] = pos
    count[0] = tail
    count[1] = diagonal


@wp.kernel
def count_columns_kernel(indices: wp.array(dtype=wp.int32), columns: wp.array(dtype=wp.int32)):
    """A thread counts one entry of a CSR graph in its column (``columns`` starts at 0;
    atomic adds: plain adds on the CPU, where the launch runs on one thread)."""
    wp.atomic_add(columns, indices[wp.tid()], 1)


@wp.kernel
def greedy_color_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32), order: wp.array(dtype=wp.int32),
    color: wp.array(dtype=wp.int32), stamp: wp.array(dtype=wp.int32),
):
    """One thread colours the nodes of a graph in ``order``: each takes the smallest
    colour no neighbour coloured before it has (``color`` starts at -1; ``stamp``, of
    length max degree + 2 and starting at -1, marks the colours seen around node t)."""
    for t in range(order.shape[0]):
        u = order[t]
        for e in range(indptr[u], indptr[u + 1]):
            c = color[indices[e]]
            if c >= 0:
                stamp[c] = t
        c = int(0)
        while stamp[c] == t:
            c += 1
        color[u] = c
