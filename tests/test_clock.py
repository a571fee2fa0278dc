"""The solvers' clock counts the solving thread's own CPU time, less numba's compiling: a
time budget is the solver's own work, not a fresh install's first compile (minutes on a
busy machine), not the time it waited for a core or for the GIL on a loaded machine."""

from __future__ import annotations

import threading
import time

import numpy as np
from numba import njit
from numba.core import event

from pliant.models import clock


def _spin(seconds: float) -> None:
    """Burn this thread's CPU for about ``seconds`` of its own CPU time."""
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


def _fresh():
    @njit  # defined anew, uncached: its first call compiles
    def squares(x):
        total = 0.0
        for v in x:
            total += v * v
        return total

    return squares


def test_the_solvers_clock_leaves_out_the_compile_time():
    # Compile fresh functions until the compiles took well over the clock's carried
    # estimate (0.2 s of compiling: one compile on a slow machine, several on a fast one),
    # so that what is left out is large against what the clock may carry.
    durations: list[float] = []  # numba's own timer: the compiles' total, at the end
    compiled = clock.compiling()
    calls = 0
    with event.install_timer("numba:compile", durations.append):
        ticks = clock.now()
        while clock.compiling() - compiled < 0.2 and calls < 1000:
            assert _fresh()(np.arange(4.0)) == 14.0
            calls += 1
        ticks = clock.now() - ticks
    assert sum(durations) >= 0.2
    # The compiles' CPU time is left out: what remains is the calls' own (microseconds
    # each) and the clock's carried estimate (at most REFRESH).
    assert ticks < 2 * clock.REFRESH + 0.02 * sum(durations)


def test_waiting_spends_no_budget_and_working_spends_it():
    """Asleep (as a thread waiting for a core is), the clock stands; working, it runs
    with the thread's CPU time, to within its carried estimate (REFRESH)."""
    ticks = clock.now()
    time.sleep(0.2)
    assert clock.now() - ticks < 2 * clock.REFRESH
    ticks, cpu = clock.now(), clock.cpu()
    _spin(0.1)
    spent, burnt = clock.now() - ticks, clock.cpu() - cpu
    assert burnt >= 0.1 and abs(spent - burnt) <= 2 * clock.REFRESH


def test_another_busy_thread_does_not_spend_this_ones_budget():
    """A sibling thread burning CPU (a loaded machine, or the GIL taken from this one)
    makes this thread slower in wall time but not on its clock: each thread's clock
    counts its own work, and the two clocks never count each other's."""
    stop = threading.Event()
    other: list[float] = []

    def busy() -> None:
        start = clock.now()
        while not stop.is_set():
            _spin(0.01)
        other.append(clock.now() - start)

    thread = threading.Thread(target=busy)
    ticks = clock.now()
    thread.start()
    try:
        _spin(0.2)
    finally:
        stop.set()
        thread.join()
    ticks = clock.now() - ticks
    assert ticks < 0.2 + 2 * clock.REFRESH + 0.02  # its own 0.2 s, not the other's
    assert other and other[0] > 0.0


def test_the_clock_never_goes_back_within_a_thread():
    """Its carried estimate runs ahead of the CPU time it reads next: the reading is
    held, not allowed to step back (a remaining budget never grows)."""
    readings = []
    for _ in range(2000):
        readings.append(clock.now())
        _spin(1e-5)
    assert np.all(np.diff(readings) >= 0.0)
    assert readings[-1] - readings[0] > 0.01  # and it ran
