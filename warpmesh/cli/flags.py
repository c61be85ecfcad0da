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
    >>> with in_flags({"smoothing": "--smoothing"}):
    ...     raise ValueError("got smoothing=3")
    Traceback (most recent call last):
    ...
    ValueError: got --smoothing 3
    >>> with in_flags({"cap": "--no-cap"}):  # a --no- flag is the keyword's False
    ...     raise ValueError("too thin (cap=False leaves it open)")
    Traceback (most recent call last):
    ...
    ValueError: too thin (--no-cap leaves it open)
    """
    try:
        yield
    except (ValueError, TypeError) as exc:
        text = str(exc)
        for name, flag in flags.items():
            if flag.startswith("--no-"):
                text = re.sub(rf"\b{name}=False\b", flag, text)
        text = re.sub(r"'(\w+)'|\b(\w+)=(?!=)", lambda m: _flag(m, flags), text)
        if text == str(exc):
            raise
        try:
            reworded = type(exc)(text)
        except Exception:  # an exception class with another signature
            reworded = ValueError(text)
        raise reworded from None


def _flag(match, flags: dict[str, str]) -> str:
    """'name' -> --flag, name= -> '--flag ' (a flag and its value, as typed); unknown names kept."""
    if match.group(1):
        return flags.get(match.group(1), match.group(0))
    flag = flags.get(match.group(2))
    return match.group(0) if flag is None else f"{flag} "
