"""Library errors told in the command line's words: Python keywords become CLI flags."""

from __future__ import annotations

import re
from contextlib import contextmanager

__all__ = ["in_flags"]


@contextmanager
def in_flags(flags: dict[str, str]):
    """Library errors raised inside, with the Python keywords they quote ('name', name=) as CLI flags.

    Examples
    --------
    >>> with in_flags({"root_iterations": "--root-iterations"}):
    ...     raise ValueError("expected 1 <= 'root_iterations' <= 64, got -1")
    Traceback (most recent call last):
    ...
    ValueError: expected 1 <= --root-iterations <= 64, got -1
    """
    try:
        yield
    except (ValueError, TypeError) as exc:
        text = re.sub(r"'(\w+)'|\b(\w+)=(?!=)",
                      lambda m: flags.get(m.group(1) or m.group(2), m.group(0)), str(exc))
        if text == str(exc):
            raise
        try:
            reworded = type(exc)(text)
        except Exception:  # an exception class with another signature
            reworded = ValueError(text)
        raise reworded from None
