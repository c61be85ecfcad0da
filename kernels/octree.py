"""Refinement criteria of the adaptive octree [FG §16.4.1, after [Schmidt-1993]], one
thread per cell; the host partner is :mod:`warpmesh.surface.adaptive.octree`."""

import warp as wp

wp.set_module_options({"enable_backward": False, "fuse_fp": False})


@wp.kernel
def criteria_kernel(
    points: wp.array2d(dtype=wp.vec3), grads: wp.array2d(dtype=wp.vec3), cross: wp.array2d(dtype=wp.int32),
    centre_grad: wp.array(dtype=wp.vec3), sin1: float, chord: float, cos2: float, singular: float,
    min_length: float, fail: wp.array(dtype=wp.int32),
):
    """One thread per cell with crossings P_i (``cross[c, i] != 0``, i < 12) and the
    gradients there and at the centre M. Fails (1) when some |grad f(P_i)| or |grad f(M)|
    is below ``singular`` times the largest |grad f(P_i)|; when a normal nu(P_i) makes
    more than eps2 with nu(M) (``<nu_i, nu_M> < cos2``; skipped when cos2 < -1); when a
    chord P_i P_j of length L > ``min_length`` leaves the tangent plane at P_i:
    ``|<P_j - P_i, nu_i>| > sin1 * L``, or, with ``sin1 < 0``, ``> 4 * chord``."""
    c = wp.tid()
    big = float(0.0)
    small = float(3.0e38)
    for i in range(12):
        if cross[c, i] != 0:
            m = wp.length(grads[c, i])
            big = wp.max(big, m)
            small = wp.min(small, m)
    gm = centre_grad[c]
    mm = wp.length(gm)
    f = int(0)
    if big <= 0.0 or small < singular * big or mm < singular * big:
        f = 1
    if f == 0 and cos2 >= -1.0:
        for i in range(12):
            if cross[c, i] != 0:
                if wp.dot(grads[c, i], gm) < cos2 * wp.length(grads[c, i]) * mm:
                    f = 1
    if f == 0:
        for i in range(12):
            if cross[c, i] != 0 and f == 0:
                nu = wp.normalize(grads[c, i])
                for j in range(12):
                    if cross[c, j] != 0 and j != i:
                        d = points[c, j] - points[c, i]
                        length = wp.length(d)
                        off = wp.abs(wp.dot(d, nu))
                        if length > min_length:
                            if sin1 >= 0.0:
                                if off > sin1 * length:
                                    f = 1
                            elif off > 4.0 * chord:
                                f = 1
    fail[c] = f


@wp.kernel
def crossings_kernel(
    values: wp.array2d(dtype=wp.float32), ijk: wp.array(dtype=wp.vec3i), span: int, origin: wp.vec3,
    half_h: wp.vec3, edges: wp.array2d(dtype=wp.int32), points: wp.array2d(dtype=wp.vec3),
    cross: wp.array2d(dtype=wp.int32), centre: wp.array(dtype=wp.vec3),
):
    """One thread per cell: where f changes sign along each of its 12 edges (``edges``:
    corner pairs, corner k at offset (k & 1, k >> 1 & 1, k >> 2 & 1)), by linear
    interpolation of the corner values (inside is f > 0), and the cell's centre.
    Lattice coordinates are in half finest cells: world = origin + lattice * half_h."""
    c = wp.tid()
    base = wp.vec3(float(ijk[c][0] * span), float(ijk[c][1] * span), float(ijk[c][2] * span))
    s = float(span)
    for e in range(12):
        a = edges[e, 0]
        b = edges[e, 1]
        va = values[c, a]
        vb = values[c, b]
        if (va > 0.0) != (vb > 0.0):
            t = va / (va - vb)
            pa = base + s * wp.vec3(float(a & 1), float((a >> 1) & 1), float((a >> 2) & 1))
            pb = base + s * wp.vec3(float(b & 1), float((b >> 1) & 1), float((b >> 2) & 1))
            p = pa + t * (pb - pa)
            points[c, e] = origin + wp.cw_mul(p, half_h)
            cross[c, e] = 1
        else:
            points[c, e] = wp.vec3(0.0)
            cross[c, e] = 0
    centre[c] = origin + wp.cw_mul(base + wp.vec3(0.5 * s, 0.5 * s, 0.5 * s), half_h)
