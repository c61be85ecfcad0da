"""Progress of a long call: a tqdm bar shown once the call has taken a second, a callback
``progress(done, total)``, or nothing.

The runs that take seconds to minutes on real data report through it: the shared surface
of a label volume (rows of the grid), its constrained smoothing (passes) and the
multi-region tetrahedra of a label volume (stages). A call that ends within the second
prints nothing.

Example
-------
>>> from warpmesh._util.progress import Progress
>>> seen = []
>>> bar = Progress(lambda done, total: seen.append((done, total)), 3, "demo")
>>> bar.update(); bar.update(2); bar.close()
>>> seen
[(1, 3), (3, 3)]
"""

from __future__ import annotations

import threading

import numpy as np

__all__ = ["Progress", "check_progress"]

#: seconds a call runs before its bar is drawn
DELAY = 1.0


def check_progress(progress, name: str = "progress") -> None:
    """Refuse anything but True, False or a callable ``progress(done, total)``."""
    if not (isinstance(progress, (bool, np.bool_)) or callable(progress)):
        raise TypeError(f"expected True, False or a callable progress(done, total) for {name!r}, got {progress!r}")


class Progress:
    """A tqdm bar (drawn after ``DELAY`` seconds, removed when closed), a callback
    ``progress(done, total)`` called at each update, or nothing (``progress`` False).
    Updates may come from several threads.

    Parameters
    ----------
    progress : bool or callable
    total : int
        Units of work in all.
    desc, unit : str
        The bar's label and unit.
    """

    def __init__(self, progress, total: int, desc: str, unit: str = "step"):
        check_progress(progress)
        self.callback, self.bar, self.done, self.total = None, None, 0, int(total)
        self.lock = threading.Lock()
        if callable(progress):
            self.callback = progress
        elif progress:
            from tqdm.auto import tqdm

            self.bar = tqdm(total=self.total, unit=unit, desc=desc, delay=DELAY, leave=False)

    def update(self, n: int = 1) -> None:
        with self.lock:
            self.done += int(n)
            if self.bar is not None:
                self.bar.update(int(n))
            if self.callback is not None:
                self.callback(self.done, self.total)

    def extend(self, n: int) -> None:
        """``n`` more units of work than announced (a run started again)."""
        with self.lock:
            self.total += int(n)
            if self.bar is not None:
                self.bar.total = self.total
                self.bar.refresh()

    def stage(self, name: str, n: int = 1) -> None:
        """``n`` more units done, the next one named ``name`` on the bar."""
        if self.bar is not None:
            self.bar.set_postfix_str(name, refresh=False)
        self.update(n)

    def finish(self) -> None:
        """Every unit done (the rest skipped), then closed."""
        if self.done < self.total:
            self.update(self.total - self.done)
        self.close()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
