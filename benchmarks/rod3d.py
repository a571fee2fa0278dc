"""Benchmark of the 3D accurate model against PyElastica, in one run.

    .venv/bin/pip install -e '.[bench]'      # PyElastica, once
    .venv/bin/python benchmarks/rod3d.py [--repeat N] [--elements N] [--fine N]

(a) The paper's case 1 as a 3D problem (clamped, dead tip force 7 EI/L^2 across the axis
and tip moment 3 EI/L), cold and as 100 warm-started steps of its load; tip error against
the 2D shooting solution (exact to 1e-10 L).
(b) A 1 m rubber hose (outer diameter 20 mm, EI = 0.05 N m^2, 0.3 kg/m) under its weight,
clamped at one end and carried by a hand (position held) along 100 small steps; cold
and warm steps. Its last pose is also solved in force space (the hand's force applied at
the tip) so that PyElastica can be brought to it; tip error against a Richardson
extrapolation of pliant at 400 and 800 elements.
PyElastica reaches a static equilibrium by damped dynamics (analytical linear damper at
about critical damping of the first mode, run until the tip stops moving); its rod is
shearable and extensible with realistic moduli (E = 6.4 MPa, G = E/3), as a user would
set it up; one short run before the timed ones leaves its JIT out. pliant is also timed
at a finer resolution (--fine, 300 elements by default): what a user who wants a
smaller error pays. Timings are machine-dependent; the ratios, measured in the same run, are the
figures.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

import pliant as pl  # noqa: E402
from pliant.models import rod3d  # noqa: E402

RADIUS = 0.01
E = 6.4e6  # a rubber hose: EI = E pi r^4 / 4 = 0.0503 N m^2
EI = E * np.pi * RADIUS**4 / 4


def median_time(fn, repeat: int):
    out = fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def warm_steps(problems: list[pl.Problem], solver: rod3d.RodSolver) -> tuple[float, float, object]:
    """(first step [s], median warm step [s], last equilibrium) of a trace."""
    times = []
    it = rod3d.trace(problems, solver=solver)
    eq = None
    while True:
        start = time.perf_counter()
        try:
            eq = next(it)
        except StopIteration:
            break
        times.append(time.perf_counter() - start)
    return times[0], statistics.median(times[1:]), eq


def case1(scale: float = 1.0, part: pl.Part | None = None) -> pl.Problem:
    part = part or pl.Part(length=1.0, bending_stiffness=EI, torsional_stiffness=EI / 1.5)
    return pl.Problem(part, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                             pl.push(1.0, force=(0.0, 7 * scale * EI, 0.0),
                                     moment=(0.0, 0.0, 3 * scale * EI), name="tip")),
                      name="paper case 1 (3D)")


HOSE = pl.Part(length=1.0, bending_stiffness=EI, torsional_stiffness=EI / 1.5,
               mass_per_length=0.30, outer_diameter=2 * RADIUS)


def hose(t: float) -> pl.Problem:
    """The hand carries the hose's end from (0.9, 0, 0) toward (0.55, 0.3, 0.2)."""
    hand = (0.9 - 0.35 * t, 0.3 * t, 0.2 * t)
    return pl.Problem(HOSE, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                             pl.pin(1.0, position=hand, name="hand")),
                      gravity=(0.0, 0.0, -9.81), name="hose carried by a hand")


def hose_pushed(force: np.ndarray) -> pl.Problem:
    return pl.Problem(HOSE, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                             pl.push(1.0, force=tuple(force), name="hand")),
                      gravity=(0.0, 0.0, -9.81), name="hose, hand force applied")


# -- PyElastica -------------------------------------------------------------------------
def elastica_tip(elements: int, tip_force: np.ndarray, tip_moment: np.ndarray,
                 mass_per_length: float, gravity: np.ndarray, final_time: float = 6.0,
                 damping: float = 2.6) -> tuple[np.ndarray, float]:
    """Static tip position of a clamped rod by damped dynamics; (tip, wall seconds)."""
    import elastica as ea

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping):
        pass

    class EndTorque(ea.NoForces):  # PyElastica has end forces but no end torque
        def __init__(self, torque, ramp):
            self.torque = np.asarray(torque, float)
            self.ramp = ramp

        def apply_torques(self, system, time=0.0):
            ramp = min(1.0, time / self.ramp)
            system.external_torques[..., -1] += ramp * (system.director_collection[..., -1]
                                                        @ self.torque)

    density = mass_per_length / (np.pi * RADIUS**2) if mass_per_length else 1150.0
    sim = Simulator()
    rod = ea.CosseratRod.straight_rod(elements, np.zeros(3), np.array([1.0, 0.0, 0.0]),
                                      np.array([0.0, 0.0, 1.0]), 1.0, RADIUS, density,
                                      youngs_modulus=E, shear_modulus=E / 3)
    sim.append(rod)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                             constrained_director_idx=(0,))
    sim.add_forcing_to(rod).using(ea.EndpointForces, np.zeros(3), np.asarray(tip_force),
                                  ramp_up_time=final_time / 5)
    if np.any(tip_moment):
        sim.add_forcing_to(rod).using(EndTorque, tip_moment, final_time / 5)
    if np.any(gravity):
        sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=np.asarray(gravity))
    dt = 0.3 * (1.0 / elements) / np.sqrt(E / density)
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=damping,
                          time_step=dt)
    sim.finalize()
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):  # it prints its final time
        ea.integrate(ea.PositionVerlet(), sim, final_time, int(final_time / dt),
                     progress_bar=False)
    return rod.position_collection[:, -1].copy(), time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--elements", type=int, default=100)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--fine", type=int, default=300,
                        help="pliant's finer resolution, compared at its own cost")
    args = parser.parse_args()
    solver = rod3d.RodSolver(elements=args.elements)
    print(f"pliant {pl.__version__}, python {sys.version.split()[0]}, {os.cpu_count()} cpus, "
          f"{args.elements} elements\n")
    try:
        import elastica  # noqa: F401

        have_elastica = True
        elastica_tip(10, np.zeros(3), np.ones(3), 0.1, np.zeros(3), final_time=1e-3)  # its JIT
    except ImportError:
        have_elastica = False
        print("PyElastica is not installed: .venv/bin/pip install -e '.[bench]'\n")

    # (a) case 1
    exact2d = pl.solve(pl.Problem(pl.Part(length=1.0, bending_stiffness=EI),
                                  (pl.clamp(0.0), pl.push(1.0, force=(0.0, 7 * EI),
                                                          moment=3 * EI, name="tip"))))
    cold_a, eq_a = median_time(lambda: rod3d.solve(case1(), solver=solver), args.repeat)
    err_a = float(np.abs(eq_a.tip[0][:2] - np.array(exact2d.tip[:2])).max())
    ramp = [case1(f) for f in np.linspace(1.0 / args.steps, 1.0, args.steps)]
    _first_a, warm_a, _ = warm_steps(ramp, solver)
    print("(a) paper case 1 as a 3D problem")
    print(f"    pliant: cold {cold_a * 1e3:.2f} ms, warm step (100-step load ramp) "
          f"{warm_a * 1e3:.3f} ms, tip error {err_a:.1e} L")
    fine_solver = rod3d.RodSolver(elements=args.fine)
    cold_af, eq_af = median_time(lambda: rod3d.solve(case1(), solver=fine_solver), args.repeat)
    err_af = float(np.abs(eq_af.tip[0][:2] - np.array(exact2d.tip[:2])).max())
    print(f"    pliant at {args.fine} elements: cold {cold_af * 1e3:.2f} ms, tip error "
          f"{err_af:.1e} L")
    if have_elastica:
        tip, wall = elastica_tip(args.elements, np.array([0.0, 7 * EI, 0.0]),
                                 np.array([0.0, 0.0, 3 * EI]), 0.0, np.zeros(3))
        err = float(np.abs(tip[:2] - np.array(exact2d.tip[:2])).max())
        print(f"    PyElastica: {wall:.2f} s of damped dynamics, tip error {err:.1e} L")
        print(f"    ratios: pliant cold is {wall / cold_a:.0f}x faster, its tip error "
              f"{err / err_a:.0f}x smaller (both at {args.elements} elements)")
        print(f"            pliant at {args.fine} elements: {wall / cold_af:.0f}x faster, "
              f"its tip error {err / err_af:.0f}x smaller")

    # (b) the hose carried by a hand
    path = [hose(t) for t in np.linspace(1.0 / args.steps, 1.0, args.steps)]
    cold_b, _eq_b = median_time(lambda: rod3d.solve(path[-1], solver=solver), args.repeat)
    _first_b, warm_b, last = warm_steps(path, solver)
    print("\n(b) 1 m rubber hose (20 mm, EI = 0.050 N m^2, 0.3 kg/m), clamped, carried by a hand")
    print(f"    pliant: cold {cold_b * 1e3:.2f} ms, warm step (100-step path) "
          f"{warm_b * 1e3:.3f} ms, stable: {last.stable}")
    force = last.reactions["hand"].force
    fine = [rod3d.solve(hose_pushed(force), solver=rod3d.RodSolver(elements=n), warm_start=None)
            for n in (400, 800)]
    reference = (4 * fine[1].tip[0] - fine[0].tip[0]) / 3
    pushed = rod3d.solve(hose_pushed(force), solver=solver)
    err_b = float(np.abs(pushed.tip[0] - reference).max())
    print(f"    pliant, its final pose in force space: tip error {err_b:.1e} L")
    cold_bf, pushed_f = median_time(lambda: rod3d.solve(hose_pushed(force), solver=fine_solver),
                                    args.repeat)
    err_bf = float(np.abs(pushed_f.tip[0] - reference).max())
    print(f"    pliant at {args.fine} elements, in force space: cold {cold_bf * 1e3:.2f} ms, "
          f"tip error {err_bf:.1e} L")
    if have_elastica:
        tip, wall = elastica_tip(args.elements, force, np.zeros(3), 0.30,
                                 np.array([0.0, 0.0, -9.81]))
        err = float(np.abs(tip - reference).max())
        print(f"    PyElastica: {wall:.2f} s of damped dynamics, tip error {err:.1e} L")
        print(f"    ratios: pliant cold is {wall / cold_b:.0f}x faster, its tip error "
              f"{err / err_b:.0f}x smaller (both at {args.elements} elements)")
        print(f"            pliant at {args.fine} elements: {wall / cold_bf:.0f}x faster, "
              f"its tip error {err / err_bf:.0f}x smaller")


if __name__ == "__main__":
    main()
