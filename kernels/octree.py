"""Refinement criteria of the adaptive octree (seed §16.4.1, after [Schmidt-1993]), one
thread per cell; the host partner is :mod:`warpmesh.octree`."""

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
