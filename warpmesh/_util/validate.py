"""Argument validators shared by the entry points: one message style, "expected X for
'name', got Y", naming the argument."""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import REAL_DTYPE

__all__ = ["check_box", "check_device"]


def check_box(bounds, name: str = "bounds") -> np.ndarray:
    """((x0, y0), (x1, y1)) or ((x0, y0, z0), (x1, y1, z1)) as a (2, d) float64 array, lo < hi."""
    try:
        b = np.asarray(bounds, dtype=REAL_DTYPE)
    except (TypeError, ValueError):
        raise ValueError(f"expected '{name}' ((x0, y0), (x1, y1)) or ((x0, y0, z0), (x1, y1, z1)) of "
                         f"numbers, got {bounds!r}") from None
    if b.ndim != 2 or b.shape[0] != 2 or b.shape[1] not in (2, 3):
        raise ValueError(f"expected '{name}' of shape (2, 2) or (2, 3), got shape {b.shape}")
    if not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"expected finite '{name}' with lo < hi on every axis, got {b.tolist()}")
    return b


def check_device(device, name: str = "device"):
    """The Warp device named by ``device`` ("cpu", "cuda", "cuda:1" or a ``wp.Device``), or a
    ValueError naming the argument when it does not exist on this machine.

    Asking Warp directly for a CUDA device on a machine without a driver prints native
    CUDA errors and raises a bare RuntimeError; this asks whether CUDA is there first.

    Example
    -------
    >>> str(check_device("cpu"))
    'cpu'
    """
    import warp as wp

    from warpmesh.kernels.startup import start

    if isinstance(device, wp.Device):
        return device
    if not isinstance(device, str):
        raise TypeError(f"expected a device name such as 'cpu' or 'cuda' for '{name}', got {type(device).__name__}")
    start()
    if device.startswith("cuda") and not wp.is_cuda_available():
        raise ValueError(f"expected an available Warp device for '{name}', got {device!r}: this machine has "
                         "no CUDA device (Warp finds no CUDA driver); use 'cpu'")
    try:
        return wp.get_device(device)
    except (RuntimeError, ValueError) as error:
        names = [str(d) for d in wp.get_devices()]
        raise ValueError(f"expected one of the Warp devices {names} for '{name}', got {device!r} ({error})") from None


# -- interval helpers (arrays broadcast; (lo, hi) pairs) -------------------------------------
