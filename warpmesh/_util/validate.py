"""Argument validators shared by the entry points: one message style, "expected X for
'name', got Y", naming the argument."""

from __future__ import annotations

import numpy as np

from warpmesh._conventions import REAL_DTYPE

__all__ = ["check_box"]


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


# -- interval helpers (arrays broadcast; (lo, hi) pairs) -------------------------------------
