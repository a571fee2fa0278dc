"""Benchmark of the 2D accurate model against scipy's solve_bvp, in one run.

    .venv/bin/python benchmarks/elastica2d.py [--repeat N]

Prints, for cold solves (no initial guess from the user) of the cantilever closed-form
cases and the paper's three cases, and for a 100-step manipulation (case 3's target
moving from the straight shape to (0.7, 0.4), each solve warm-started from the last):
medians, the ratio solve_bvp / pliant, and tip errors against the closed form (the
cantilever) or against a tightly converged reference (the paper's cases). solve_bvp runs
with analytic Jacobians at tol = 1e-6 (tip errors near 1e-9, a hundred times pliant's)
and, for the cold solves, at matched accuracy: the loosest tolerance whose error is at
most pliant's.
Timings are machine-dependent; the ratios, measured in the same run, are the figures.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import pliant as pl  # noqa: E402
from pliant.io.problem_file import load_problem  # noqa: E402
from pliant.models.elastica2d import ShootingSolver, solve, trace  # noqa: E402
from pliant.models.elastica2d.reference import solve_reference  # noqa: E402
from tests.test_elastica2d_closed_form import cantilever_tip  # noqa: E402

REFERENCE = ShootingSolver(tolerance=1e-13, accuracy=0.1)


def median_time(fn, repeat: int) -> tuple[float, object]:
    """Median wall time [s] of fn() over repeat calls, after one warm-up call."""
    out = fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def cantilever(alpha: float) -> pl.Problem:
    part = pl.Part(length=1.0, bending_stiffness=1.0)
    return pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, force=(0.0, alpha), name="tip")),
                      name=f"cantilever F L^2/EI = {alpha:g}")


def case3_path(steps: int) -> list[pl.Problem]:
    base = load_problem(ROOT / "examples" / "paper" / "case3.toml")
    clamp = base.condition("clamp")
    return [base.with_conditions([clamp, pl.clamp(1.0, position=(1 - 0.3 * t, 0.4 * t),
                                                  angle=0.0, name="hole")])
            for t in np.linspace(1.0 / steps, 1.0, steps)]


TOLERANCES = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10)  # solve_bvp's, loosest first


def _bvp_value(problem: pl.Problem, bvp) -> np.ndarray:
    """What a solve_bvp answer is compared by: the tip pose, or for case 3 (the tip
    held) the tip's load."""
    if problem.name != "paper case 3":
        return np.array(bvp.tip)
    n_end = bvp.station_states[-1]
    EI, L = problem.part.bending_stiffness, problem.part.length
    return np.array([n_end[3] * EI / L**2, n_end[4] * EI / L**2, n_end[5] * EI / L])


def cold(repeat: int) -> None:
    print("cold solves (no initial guess from the user), median of", repeat)
    print("solve_bvp at tol = 1e-6, and at matched accuracy: the loosest of tol = "
          f"{', '.join(f'{t:g}' for t in TOLERANCES)} whose error is at most pliant's")
    header = (f"{'problem':34s} {'pliant':>9s} {'err':>8s} | {'bvp 1e-6':>9s} {'err':>8s} "
              f"{'ratio':>5s} | {'bvp matched':>12s} {'err':>8s} {'ratio':>5s}")
    print(header)
    print("-" * len(header))
    default, route_only = ShootingSolver(), ShootingSolver(lowest=False)
    rows = [(cantilever(a), "closed form", default, "") for a in (2.0, 10.0, 50.0)]
    rows += [(load_problem(ROOT / "examples" / "paper" / f"case{i}.toml"), "reference",
              default, "") for i in (1, 2, 3)]
    # Case 3 holds the tip: by default a cold solve also minimises the energy from a few
    # starting shapes for a lower stable equilibrium; lowest=False is the route alone.
    rows.append((rows[-1][0], "reference", route_only, ", route only"))
    notes = []
    for problem, against, settings, label in rows:
        t_pl, eq = median_time(lambda p=problem, s=settings: solve(p, solver=s), repeat)
        if against == "closed form":
            exact = np.array(cantilever_tip(problem.condition("tip").force[1]))
        else:
            ref = solve(problem, solver=REFERENCE)
            exact = np.array(ref.tip)
        value = np.array(eq.tip)
        if problem.name == "paper case 3":  # the tip is prescribed: compare the load
            exact = np.append(ref.reactions["hole"].force, ref.reactions["hole"].moment)
            value = np.append(eq.reactions["hole"].force, eq.reactions["hole"].moment)
        err_pl = float(np.abs(value - exact).max())
        guess = None
        if not solve_reference(problem).success:  # case 3: singular from the straight shape
            guess = eq
            if "from pliant's answer" not in " ".join(notes):
                notes.append(f"{problem.name}: solve_bvp fails from the straight shape "
                             "(a singular Jacobian); timed from pliant's answer instead")
        timed = []
        for tol in TOLERANCES:
            t_bvp, bvp = median_time(lambda p=problem, g=guess, t=tol: solve_reference(
                p, guess=g, tol=t), max(3, repeat // 10))
            err_bvp = float(np.abs(_bvp_value(problem, bvp) - exact).max())
            timed.append((t_bvp, err_bvp, tol))
            if err_bvp <= err_pl:
                break
        (t_6, err_6, _), (t_m, err_m, tol_m) = timed[0], timed[-1]
        print(f"{problem.name + label:34s} {t_pl * 1e3:7.3f}ms {err_pl:8.1e} | "
              f"{t_6 * 1e3:7.2f}ms {err_6:8.1e} {t_6 / t_pl:4.0f}x | "
              f"{t_m * 1e3:7.2f}ms {tol_m:.0e} {err_m:8.1e} {t_m / t_pl:4.0f}x")
    for note in notes:
        print(" ", note)


def manipulation(steps: int, repeat: int) -> None:
    path = case3_path(steps)
    print(f"\n{steps}-step manipulation: case 3's target from the straight shape to "
          "(0.7, 0.4), each solve warm-started")
    per_step_pl: list[float] = []
    mean_pl: list[float] = []
    for _ in range(repeat):
        times = []
        it = trace(path)
        while True:
            start = time.perf_counter()
            try:
                eq = next(it)
            except StopIteration:
                break
            times.append(time.perf_counter() - start)
        per_step_pl.append(statistics.median(times[1:]))
        mean_pl.append(statistics.fmean(times[1:]))
        first_pl = times[0]
    t_pl = min(per_step_pl)  # the least disturbed of the repeats
    # solve_bvp: from the straight shape the first step is singular, so it starts from
    # pliant's first answer and then warm-starts from its own previous solution.
    first = solve(path[0])
    bvp_times = []
    bvp = solve_reference(path[0], guess=first)
    for problem in path[1:]:
        start = time.perf_counter()
        bvp = solve_reference(problem, guess=bvp)
        bvp_times.append(time.perf_counter() - start)
        if not bvp.success:
            print("  solve_bvp failed on the way:", bvp.message)
            break
    t_bvp = statistics.median(bvp_times)
    ref = solve(path[-1], solver=REFERENCE)
    exact = np.append(ref.reactions["hole"].force, ref.reactions["hole"].moment)
    value = np.append(eq.reactions["hole"].force, eq.reactions["hole"].moment)
    fs = 1.0
    n_end = bvp.station_states[-1]
    bvp_value = np.array([n_end[3] * fs, n_end[4] * fs, n_end[5]])
    print(f"  pliant    : first step (cold) {first_pl * 1e3:.2f} ms, then median "
          f"{t_pl * 1e6:.0f} us per warm step (mean {min(mean_pl) * 1e6:.0f} us: a step "
          f"that shoots its Jacobian costs more); final tip load error "
          f"{np.abs(value - exact).max():.1e}")
    print(f"  solve_bvp : median {t_bvp * 1e3:.2f} ms per warm step; final tip load error "
          f"{np.abs(bvp_value - exact).max():.1e}")
    print(f"  ratio     : {t_bvp / t_pl:.0f}x")


def enumeration(repeat: int) -> None:
    """equilibria() on the paper's case 3 (the issue's target: 50 ms) and on a tip held
    near the clamp's axis, where the two bow sides differ."""
    from pliant.core.equilibrium import potential_energy
    from pliant.models.elastica2d import equilibria

    near = pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.grip(1.0, (0.333, -0.002),
                                                                  angle=-1.106)))
    print("\nequilibria(problem): every route and bow side, distinct, best first")
    for name, problem in (("paper case 3", load_problem(ROOT / "examples/paper/case3.toml")),
                          ("tip near the clamp's axis", near)):
        found = equilibria(problem)
        times = []
        for _ in range(repeat):
            start = time.perf_counter()
            equilibria(problem)
            times.append(time.perf_counter() - start)
        listed = ", ".join(f"{potential_energy(e):.5g} J {e.verdict}" for e in found)
        print(f"  {name:28s} {statistics.median(times) * 1e3:7.1f} ms: {listed}")


def heavy(repeat: int) -> None:
    """Cold solves whose forces outgrow one shooting interval: a taut hairpin (a part
    held 0.97 L away, pointing back) and cables hanging under their weight. The
    continuation re-lowers onto more intervals as its forces grow, and the Newton solves
    over the Jacobian's band; solve_bvp (tol 1e-6) is timed from pliant's answer (from the
    straight shape it does not converge on these)."""
    hairpin = pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.grip(
        1.0, (0.76, -0.6), angle=math.pi, name="hand")), name="taut hairpin")
    cables = [pl.Problem(pl.Part(10.0, ei, mass_per_length=1.0), (pl.pin(0.0), pl.pin(
        10.0, position=(8.0, 0.0), name="hand")), gravity=(0.0, -9.81),
        name=f"cable, q L^3 / EI = {9810.0 / ei:.0e}") for ei in (1.0, 0.1)]
    # Clamped level at one end, hanging under its weight (force space): until stop 49
    # the path's first points drifted off the branch and it stopped at "a fold" from
    # q L^3 / EI = 3e5 on.
    hanging = [pl.Problem(pl.Part(10.0, ei, mass_per_length=1.0), (pl.clamp(0.0),),
                          gravity=(0.0, -9.81),
                          name=f"cable clamped, hanging, {9810.0 / ei:.0e}")
               for ei in (0.1, 0.0327)]
    print("\nheavy cold solves, best of", repeat)
    for problem in [hairpin, *cables, *hanging]:
        times = []
        for _ in range(repeat):
            start = time.perf_counter()
            eq = solve(problem)
            times.append(time.perf_counter() - start)
        start = time.perf_counter()
        bvp = solve_reference(problem, guess=eq, tol=1e-6)
        t_bvp = time.perf_counter() - start
        said = f"{t_bvp * 1e3:8.1f} ms" if bvp.success else "  failed"
        print(f"  {problem.name:28s} {min(times) * 1e3:8.1f} ms ({len(eq.state.low.nodes) + 1}"
              f" intervals, {eq.steps} steps, {eq.iterations} iterations) | solve_bvp "
              f"from it {said}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=50)
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args()
    print(f"pliant {pl.__version__}, python {sys.version.split()[0]}, "
          f"{os.cpu_count()} cpus\n")
    cold(args.repeat)
    manipulation(args.steps, max(3, args.repeat // 10))
    enumeration(max(3, args.repeat // 5))
    heavy(max(3, args.repeat // 10))


if __name__ == "__main__":
    main()
