"""Benchmark of stretch (axial stiffness EA) in the 3D accurate model, in one run.

    .venv/bin/python benchmarks/stretch.py [--repeat N] [--elements N]

(a) The warm step with and without stretch: a 1 m rubber hose (EI = 0.05 N m^2,
0.3 kg/m) clamped at one end and carried by a hand along 100 small steps, once
inextensible and once with EA = 2 kN; the figure is the ratio of the median warm steps
(the issue's target: at most 1.3).
(b) A taut-cable sweep: 1 m of cable (EI = 0.02 N m^2, 0.05 kg/m, EA = 20 kN) clamped at
both ends, the second end moved away along the chord from 0.9 m until the cable is 5 mm
short (a chord of 1.005 m), in 60 warm steps; every step must solve. Printed: the
connector's pull at a few chords, against the straight bar's EA (chord - L) / L once
taut, and what an inextensible model says (it refuses every chord at or beyond 1 m).
Timings are machine-dependent; the ratios, measured in the same run, are the figures.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import pliant as pl
from pliant.errors import UnreachableTargetError
from pliant.models import rod3d

ORIGIN = (0.0, 0.0, 0.0)


def hose_path(axial: float | None, steps: int = 100) -> list[pl.Problem]:
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   axial_stiffness=axial)
    out = []
    for k in range(steps + 1):
        t = k / steps
        hand = (0.7 - 0.2 * t, 0.1 * t, -0.3 + 0.25 * t)
        out.append(pl.Problem(hose, (pl.clamp(0.0, position=ORIGIN),
                                     pl.grip(1.0, position=hand, name="hand")),
                              gravity=(0.0, 0.0, -9.81)))
    return out


def warm_step(problems: list[pl.Problem], solver: rod3d.RodSolver, repeat: int) -> float:
    """The median over ``repeat`` traces of the median warm step [s]."""
    medians = []
    for _ in range(repeat + 1):  # the first one loads the kernels
        times = []
        previous = None
        for problem in problems:
            start = time.perf_counter()
            previous = rod3d.solve(problem, warm_start=previous, solver=solver)
            times.append(time.perf_counter() - start)
        medians.append(statistics.median(times[1:]))
    return statistics.median(medians[1:])


def taut_sweep(elements: int) -> None:
    cable = pl.Part(length=1.0, bending_stiffness=0.02, mass_per_length=0.05,
                    axial_stiffness=2e4)
    marks = (0.99, 0.999, 1.0, 1.002, 1.005)
    chords = np.unique(np.concatenate([np.linspace(0.9, 1.005, 61), marks]))
    solver = rod3d.RodSolver(elements=elements)
    previous = None
    pulls = []
    start = time.perf_counter()
    for chord in chords:
        problem = pl.Problem(cable, (pl.clamp(0.0, position=ORIGIN),
                                     pl.clamp(1.0, position=(float(chord), 0.0, 0.0),
                                              name="connector")),
                             gravity=(0.0, 0.0, -9.81))
        previous = rod3d.solve(problem, warm_start=previous, solver=solver)
        pulls.append(float(previous.reactions["connector"].force[0]))
    seconds = time.perf_counter() - start
    print(f"(b) taut-cable sweep, {len(chords)} steps from a 0.9 m to a 1.005 m chord: all "
          f"solved in {seconds:.2f} s ({seconds / len(chords) * 1e3:.1f} ms a step)")
    for chord in marks:
        k = int(np.argmin(np.abs(chords - chord)))
        straight = 2e4 * (chords[k] - 1.0)
        line = f"    chord {chords[k]:.4f} m: the connector pulls {pulls[k]:9.3f} N"
        if chords[k] > 1.0:
            line += f" (straight bar EA (c - L) / L: {straight:.3f} N)"
        print(line)
    try:
        pl.Problem(pl.Part(1.0, 0.02), (pl.clamp(0.0, position=ORIGIN),
                                        pl.clamp(1.0, position=(1.0, 0.0, 0.0), name="c")))
    except UnreachableTargetError:
        print("    inextensible: every chord from 1 m on is refused (out of reach)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--elements", type=int, default=100)
    args = parser.parse_args()
    solver = rod3d.RodSolver(elements=args.elements)
    rigid = warm_step(hose_path(None), solver, args.repeat)
    stretchy = warm_step(hose_path(2e3), solver, args.repeat)
    print(f"(a) warm 3D step, {args.elements} elements, 100-step hand path: inextensible "
          f"{rigid * 1e3:.3f} ms, with stretch (EA = 2 kN) {stretchy * 1e3:.3f} ms: ratio "
          f"{stretchy / rigid:.2f} (target <= 1.3)")
    taut_sweep(args.elements)


if __name__ == "__main__":
    main()
