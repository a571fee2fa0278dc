"""The solvers' clock: wall time that stops while numba compiles.

A solver's time budget bounds its own work. The first solve in a fresh install also
compiles its kernels (a minute or more on a slow or busy machine); counting that would
make the same problem fail or pass with the machine's load.
"""

from __future__ import annotations

import threading
import time

from numba.core import event


class _CompileTimer(event.Listener):
    """Sums the wall time of outermost compilations (they nest: a kernel compiles the
    kernels it calls); cache loads are not compilations."""

    def __init__(self) -> None:
        self.total = 0.0
        self._depth = 0
        self._start = 0.0
        self._lock = threading.Lock()

    def on_start(self, event: event.Event) -> None:
        with self._lock:
            if self._depth == 0:
                self._start = time.perf_counter()
            self._depth += 1

    def on_end(self, event: event.Event) -> None:
        with self._lock:
            # The total first: ``now`` reads it without the lock once depth is 0.
            if self._depth == 1:
                self.total += time.perf_counter() - self._start
            self._depth -= 1


_TIMER = _CompileTimer()
event.register("numba:compile", _TIMER)


def compiling() -> float:
    """Seconds spent compiling kernels in this process so far (0 once they are cached)."""
    with _TIMER._lock:
        return _TIMER.total + (time.perf_counter() - _TIMER._start if _TIMER._depth else 0.0)


def now() -> float:
    """Seconds on the solvers' clock: ``time.perf_counter()`` less compile time."""
    if not _TIMER._depth:  # nothing compiling (the usual case): no lock to take
        return time.perf_counter() - _TIMER.total
    with _TIMER._lock:
        compiling = time.perf_counter() - _TIMER._start if _TIMER._depth else 0.0
        return time.perf_counter() - _TIMER.total - compiling
