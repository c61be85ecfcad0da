"""Sequential graph walks of node renumbering (seed §17.4.1): Cuthill–McKee numbering
over a level structure, and connected components of a node subset.

Both walks are sequential by nature — the order of a level depends on the order of the
one before — so each kernel is launched with ``dim=1`` and one thread walks the whole
graph: compiled code instead of one Python round of array operations per level (a 2D
mesh has about a thousand levels). The same code runs on CUDA, on one thread.

Graphs are CSR arrays (``indptr``, ``indices``: sorted rows, no diagonal), int32.
"""

import warp as wp

wp.set_module_options({"enable_backward": False})


@wp.kernel
def number_levels_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32),
    lev: wp.array(dtype=wp.int32), key: wp.array(dtype=wp.int32),
    members: wp.array(dtype=wp.int32), bounds: wp.array(dtype=wp.int32),
    depth: int, start: int, first_number: int,
    num: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32), buf: wp.array(dtype=wp.int32),
    next_number: wp.array(dtype=wp.int32),
):
    """One thread numbers a component level by level (Gibbs Step 3, Cuthill–McKee).

    ``lev`` is each node's level (-1 outside the component); ``members[bounds[k]:
    bounds[k + 1]]`` are level k's nodes by increasing (key, index). In level k
    (phase 0) the numbered nodes, in number order, number their unnumbered neighbours
    of level k; when none is left to reach, the unnumbered member of smallest key
    starts again. Then (phase 1) the level's nodes, in number order, number their
    neighbours of level k + 1. A node numbers its neighbours by increasing key (ties:
    index, the row order).
    """
    nxt = first_number
    num[start] = nxt
    out[nxt] = start
    nxt += 1
    level_first = first_number
    for k in range(depth):
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
                    if k + 1 >= depth:
                        phase = 2
                elif head < nxt:
                    u = out[head]
                    head += 1
                else:  # no numbered node reaches the rest: smallest key starts again
                    while num[members[scan]] >= 0:
                        scan += 1
                    v = members[scan]
                    num[v] = nxt
                    out[nxt] = v
                    nxt += 1
            else:
                if head < stop:
                    u = out[head]
                    head += 1
                    target = k + 1
                else:
                    level_first = stop
                    phase = 2
            if u >= 0:
                m = int(0)
                for e in range(indptr[u], indptr[u + 1]):
                    v = indices[e]
                    if lev[v] == target:
                        if num[v] < 0:
                            t = m  # insertion sort by key, stable: equal keys keep index order
                            while t > 0:
                                w = buf[t - 1]
                                if key[w] <= key[v]:
                                    break
                                buf[t] = w
                                t -= 1
                            buf[t] = v
                            m += 1
                for t in range(m):
                    num[buf[t]] = nxt
                    out[nxt] = buf[t]
                    nxt += 1
    next_number[0] = nxt


@wp.kernel
def label_components_kernel(
    indptr: wp.array(dtype=wp.int32), indices: wp.array(dtype=wp.int32),
    inside: wp.array(dtype=wp.int32), nodes: wp.array(dtype=wp.int32),
    label: wp.array(dtype=wp.int32), queue: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32),
):
    """One thread labels the connected components of the subgraph induced by ``nodes``
    (``inside[v] == 1``), numbered in the order of their smallest node; ``label`` starts
    at -1."""
    c = int(0)
    for t in range(nodes.shape[0]):
        s = nodes[t]
        if label[s] < 0:
            label[s] = c
            queue[0] = s
            head = int(0)
            tail = int(1)
            while head < tail:
                u = queue[head]
                head += 1
                for e in range(indptr[u], indptr[u + 1]):
                    v = indices[e]
                    if inside[v] == 1 and label[v] < 0:
                        label[v] = c
                        queue[tail] = v
                        tail += 1
            c += 1
    count[0] = c
