"""The solvers' clock: the solving thread's CPU time, less what numba spends compiling.

A solver's time budget bounds its own work. Counted in wall time, the same problem would
fail on a loaded machine (another process, a full Dask worker, a busy browser session)
and pass on an idle one; counted in the thread's CPU time, a thread that waits for a
core (or for the GIL) spends none of its budget. The first solve in a fresh install also
compiles its kernels (a minute or more on a slow machine): that is left out too.

Reading a thread's CPU time is a system call (0.7 us here, against 0.06 us for the wall
clock), and warm steps read the clock a few times in 30 us. So ``now`` reads it at most
every ``REFRESH`` seconds and adds the wall time since: CPU time never runs faster than
the wall, so this over-counts by less than ``REFRESH`` and never stretches a budget.
"""

from __future__ import annotations

import threading
import time

from numba.core import event

REFRESH = 0.005  # s of wall time between two reads of the thread's CPU time, at most


class _CompileTimer(event.Listener):
    """Sums outermost compilations (they nest: a kernel compiles the kernels it calls;
    cache loads are not compilations): their wall time, for reports (``compiling``),
    and each thread's CPU time in them, which its clock leaves out. Numba compiles
    under one lock, in the thread that asked."""

    def __init__(self) -> None:
        self.total = 0.0
        self._depth = 0
        self._start = 0.0
        self._cpu_start = 0.0
        self._lock = threading.Lock()

    def on_start(self, event: event.Event) -> None:
        with self._lock:
            if self._depth == 0:
                self._start = time.perf_counter()
                self._cpu_start = time.thread_time()
            self._depth += 1

    def on_end(self, event: event.Event) -> None:
        with self._lock:
            if self._depth == 1:
                self.total += time.perf_counter() - self._start
                _LOCAL.compiled = (getattr(_LOCAL, "compiled", 0.0)
                                   + time.thread_time() - self._cpu_start)
                _LOCAL.sample = None  # the next reading is exact
            self._depth -= 1


_LOCAL = threading.local()  # per thread: compiled (CPU s), sample (wall, clock), last
_TIMER = _CompileTimer()
event.register("numba:compile", _TIMER)


def compiling() -> float:
    """Seconds (wall) spent compiling kernels in this process so far (0 once they are
    cached)."""
    with _TIMER._lock:
        return _TIMER.total + (time.perf_counter() - _TIMER._start if _TIMER._depth else 0.0)


def cpu() -> float:
    """This thread's CPU time [s] less its compiling, read exactly (a system call)."""
    return time.thread_time() - getattr(_LOCAL, "compiled", 0.0)


def now() -> float:
    """Seconds on the solvers' clock: this thread's CPU time less its compile time,
    read every ``REFRESH`` s and carried forward by the wall clock between (see the
    module); never decreasing in a thread."""
    wall = time.perf_counter()
    sample = getattr(_LOCAL, "sample", None)
    if sample is not None and wall - sample[0] < REFRESH:
        value = sample[1] + (wall - sample[0])
    else:
        value = cpu()
        _LOCAL.sample = (wall, value)
    last = getattr(_LOCAL, "last", value)
    if value < last:  # the estimate ran ahead of the CPU time read since
        value = last
    _LOCAL.last = value
    return value
