"""Stiffness identification's figures, measured in one run (ratios: machines vary).

The issue's targets: a shape fit of 50 points with one unknown <= 0.5 s, with two
unknowns <= 2 s. Each case is fitted 5 times from a first guess 2.5 times off (the median
time is the figure), on synthetic photographs (pliant's model plus 0.5 mm noise, seeded):

A. a 0.5 m cable clamped level, sagging under its weight and a 20 g tip weight (2D):
   bending_stiffness;
B. the same, bending_stiffness and mass_per_length together (the tip weight separates
   them);
C. a pre-curved 0.6 m hose (2.5 1/m) sagging out of its plane (3D, 100 elements):
   bending_stiffness and torsional_stiffness.

For A and B, the tool a user would pick instead, in the same run: scipy.optimize's
curve_fit around scipy.integrate.solve_bvp of the same elastica (theta' = M / EI,
M' = (w (L - s) + P) cos theta (theta counter-clockwise), theta(0) = 0, M(L) = 0; the points'
distance to the
densely sampled curve), tolerance 1e-8.

    .venv/bin/python benchmarks/identify.py
"""

from __future__ import annotations

import statistics
import time
from dataclasses import replace

import numpy as np
from scipy.integrate import cumulative_trapezoid, solve_bvp
from scipy.optimize import curve_fit
from scipy.spatial import cKDTree

import pliant as pl
from pliant.core.measurement import Shape, StiffnessTest
from pliant.identify import identify

L, EI, MASS, TIP, G = 0.5, 0.021, 0.052, 0.02 * 9.81, 9.81


def cable(ei: float, mass: float) -> pl.Problem:
    return pl.Problem(pl.Part(L, ei, mass_per_length=mass),
                      (pl.clamp(0.0), pl.push(L, (0.0, -TIP), name="weight")),
                      gravity=(0.0, -G))


def photograph(eq, dim: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    s = np.sort(rng.uniform(0.03 * L, eq.s[-1], 50))
    points = np.column_stack([np.interp(s, eq.s, eq.position[:, k]) for k in range(dim)])
    return points + rng.normal(0.0, 0.5e-3, points.shape)


def scipy_shape(ei: float, mass: float, n: int = 2000) -> np.ndarray:
    """The reference model: the cantilever's shape from solve_bvp, sampled densely."""
    s = np.linspace(0.0, L, 41)

    def rhs(s, y):
        return np.vstack([y[1] / ei, (mass * G * (L - s) + TIP) * np.cos(y[0])])

    def bc(a, b):
        return np.array([a[0], b[1]])

    guess = np.zeros((2, s.size))
    sol = solve_bvp(rhs, bc, s, guess, tol=1e-8, max_nodes=100000)
    if not sol.success:
        raise RuntimeError(sol.message)
    fine = np.linspace(0.0, L, n)
    theta = sol.sol(fine)[0]
    return np.column_stack([cumulative_trapezoid(np.cos(theta), fine, initial=0.0),
                            cumulative_trapezoid(np.sin(theta), fine, initial=0.0)])


def scipy_fit(points: np.ndarray, guess: list[float], both: bool) -> list[float]:
    def distances(_x, *p):
        ei, mass = (p[0], p[1]) if both else (p[0], MASS)
        return cKDTree(scipy_shape(ei, mass)).query(points)[0]

    popt, _ = curve_fit(distances, np.zeros(len(points)), np.zeros(len(points)), p0=guess,
                        bounds=(0, np.inf))
    return list(popt)


def median_time(work, repeats: int = 5) -> tuple[float, object]:
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = work()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def main() -> None:
    truth = pl.solve(cable(EI, MASS))
    points = photograph(truth, 2, 7)
    identify(StiffnessTest(cable(EI, MASS), ("bending_stiffness",), (Shape(points),)))  # warm
    rows = []
    for label, unknowns, guess in (("A 2D, EI", ("bending_stiffness",), [2.5 * EI]),
                                   ("B 2D, EI and mass", ("bending_stiffness",
                                                          "mass_per_length"),
                                    [2.5 * EI, MASS / 2.5])):
        first = cable(guess[0], guess[1] if len(guess) > 1 else MASS)
        test = StiffnessTest(first, unknowns, (Shape(points, 0.5e-3),))
        ours, result = median_time(lambda test=test: identify(test))
        both = len(guess) > 1
        theirs, popt = median_time(lambda g=guess, b=both: scipy_fit(points, g, b))
        values = [result.value(n) for n in unknowns]
        rows.append((label, ours, theirs, values, popt, result.solves))
    for label, ours, theirs, values, popt, solves in rows:
        print(f"{label}: pliant {ours:.3f} s ({solves} solves), curve_fit + solve_bvp "
              f"{theirs:.3f} s: {theirs / ours:.0f}x; values "
              + ", ".join(f"{v:.5g}" for v in values) + " against "
              + ", ".join(f"{v:.5g}" for v in popt) + f" (truth {EI}"
              + (f", {MASS})" if len(values) > 1 else ")"))
    part = pl.Part(0.6, 0.05, torsional_stiffness=0.03, mass_per_length=0.1,
                   rest_curvature=2.5)
    hose = pl.Problem(part, (pl.clamp(0.0, (0.0, 0.0, 0.0)),
                             pl.push(0.6, (0.0, 0.0, -0.1), name="tip")),
                      gravity=(0.0, 0.0, -G))
    points3 = photograph(pl.solve(hose), 3, 8)
    first = replace(hose, part=replace(part, bending_stiffness=0.125,
                                       torsional_stiffness=0.075))
    test = StiffnessTest(first, ("bending_stiffness", "torsional_stiffness"),
                         (Shape(points3, 0.5e-3),))
    ours, result = median_time(lambda: identify(test))
    print(f"C 3D, EI and GJ: pliant {ours:.3f} s ({result.solves} solves); values "
          + ", ".join(f"{e.value:.5g} [{e.low:.4g}, {e.high:.4g}]" for e in result.estimates)
          + " (truth 0.05, 0.03)")
    print(f"targets: A <= 0.5 s ({'met' if rows[0][1] <= 0.5 else 'missed'}), "
          f"two unknowns <= 2 s (B {'met' if rows[1][1] <= 2 else 'missed'}, "
          f"C {'met' if ours <= 2 else 'missed'})")


if __name__ == "__main__":
    main()
