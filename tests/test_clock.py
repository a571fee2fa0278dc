"""The solvers' clock stops while numba compiles: a time budget is the solver's own work,
not a fresh install's first compile (which takes minutes on a busy machine)."""

from __future__ import annotations

import time

import numpy as np
from numba import njit
from numba.core import event

from pliant.models import clock


def test_the_solvers_clock_leaves_out_exactly_the_compile_time():
    @njit  # defined here, uncached: its first call compiles
    def squares(x):
        total = 0.0
        for v in x:
            total += v * v
        return total

    durations: list[float] = []
    with event.install_timer("numba:compile", durations.append):
        wall, ticks = time.perf_counter(), clock.now()
        assert squares(np.arange(4.0)) == 14.0
        wall, ticks = time.perf_counter() - wall, clock.now() - ticks
    assert len(durations) == 1 and durations[0] > 0.0
    assert abs((wall - ticks) - durations[0]) < 0.05 * durations[0] + 1e-3
    wall, ticks = time.perf_counter(), clock.now()
    squares(np.arange(4.0))  # compiled: the clock runs with the wall's
    assert abs((time.perf_counter() - wall) - (clock.now() - ticks)) < 1e-3
