"""A second hand, placed where it helps most: solved, not guessed.

When one hand at the grip is red, a fitter takes the part with the other hand somewhere
along it and pushes. Here the second hand is a force f (global frame, no moment) applied
at a node s2 while the first hand keeps its pose along the path: the vocabulary's
one-word change from holding to pushing. For each candidate s2 at the worst step, the
accurate model gives the first hand's wrench for three pushes along x, y and z (finite
differences from the one-hand equilibrium, which is the f = 0 one, each solve warm-started
from it); on that linear model
the push that minimises the worst ratio demand / red limit over both hands' checks is
found (Nelder-Mead: a few hundred evaluations of the linear model cost nothing), then
solved exactly. The best verified s2 is kept, and at every other red step the push is
found again at that s2 the same way (the hand stays where it took the part; how hard it
pushes changes). 4 solves per candidate (5 candidates, at sixths of the free span: 20
at the worst step), 4 at each other red step.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pliant.assembly.checks import split_wrench
from pliant.assembly.evaluate import (
    Check,
    GripStep,
    OperatorResult,
    grip_step,
    hand_checks,
    hand_rows,
    series_check,
)
from pliant.core.conditions import push
from pliant.core.rules import Capacity, EvaluationSettings, Rules
from pliant.errors import PliantError

SECOND = "second hand"
CANDIDATES = (1 / 6, 2 / 6, 3 / 6, 4 / 6, 5 / 6)  # fractions of the free span from the support to the grip


def _ratio(wrench: Any, rows: list[Capacity], friction: float) -> float:
    """The worst demand / red limit of a wrench over the rows (above 1: red)."""
    return max(wrench.demand(row.demand, friction) / row.yellow for row in rows)


def _candidates(run: Any, grip: str) -> list[float]:
    """Candidate s2 [m]: nodes at fractions of the span between the nearest other held
    station and the grip."""
    eq = run.equilibria[0]
    problem = eq.problem
    s_grip = problem.condition(grip).s
    others = [c.s for c in problem.conditions if c.name != grip and not c.loads_only]
    below = [s for s in others if s < s_grip]
    above = [s for s in others if s > s_grip]
    if below:
        a = max(below)
    elif above:
        a = min(above)
    else:
        a = problem.part.length - s_grip
    nodes = eq.s
    out = []
    for frac in CANDIDATES:
        s = a + frac * (s_grip - a)
        node = float(nodes[int(np.argmin(np.abs(nodes - s)))])
        if all(abs(node - c) > 1e-9 for c in [*others, s_grip, *out]):
            out.append(node)
    return out


class _Placement:
    """The second hand at one s2, solved at one step."""

    def __init__(self, problem: Any, eq: Any, grip: str, s2: float, solver: Any,
                 rows: list[Capacity], friction: float) -> None:
        self.problem, self.eq, self.grip, self.s2 = problem, eq, grip, s2
        self.solver, self.rows, self.friction = solver, rows, friction
        self.solves = 0

    def solve(self, f: np.ndarray) -> Any:
        from pliant.models import rod3d  # noqa: PLC0415

        conditions = [*self.problem.conditions,
                      push(self.s2, force=tuple(float(x) for x in f), name=SECOND)]
        self.solves += 1
        return rod3d.solve(self.problem.with_conditions(conditions), warm_start=self.eq,
                           solver=self.solver)

    def objective(self, eq: Any, f: np.ndarray) -> float:
        first = grip_step(eq, self.grip).wrench
        node = int(np.argmin(np.abs(eq.s - self.s2)))
        second = split_wrench(f, np.zeros(3), eq.tangent[node])
        return max(_ratio(first, self.rows, self.friction),
                   _ratio(second, self.rows, self.friction))

    def best_push(self) -> tuple[np.ndarray, Any, float] | None:
        """(f [N], its equilibrium, its worst ratio), or None where a solve failed."""
        from scipy.optimize import minimize  # noqa: PLC0415

        g0 = grip_step(self.eq, self.grip)
        w0 = np.concatenate([g0.force, g0.moment])
        delta = max(1.0, 0.1 * g0.wrench.force)
        columns = []
        for i in range(3):
            f = np.zeros(3)
            f[i] = delta
            try:
                eq = self.solve(f)
            except PliantError:
                return None
            g = grip_step(eq, self.grip)
            columns.append((np.concatenate([g.force, g.moment]) - w0) / delta)
        A = np.column_stack(columns)  # (6, 3): the first hand's wrench per newton pushed
        node = int(np.argmin(np.abs(self.eq.s - self.s2)))
        t2 = self.eq.tangent[node]
        t1 = np.array(g0.tangent)
        outward = 1.0 if g0.s > 0.5 * self.problem.part.length else -1.0

        def model(f: np.ndarray) -> float:
            w = w0 + A @ f
            first = split_wrench(w[:3], w[3:], t1, outward)
            second = split_wrench(f, np.zeros(3), t2)
            return max(_ratio(first, self.rows, self.friction),
                       _ratio(second, self.rows, self.friction))

        # Start from the push that cancels the first hand's force in least squares.
        start = np.linalg.lstsq(A[:3], -w0[:3], rcond=None)[0]
        best = min((minimize(model, x0, method="Nelder-Mead",
                             options={"xatol": 1e-3, "fatol": 1e-4, "maxiter": 2000})
                    for x0 in (np.zeros(3), 0.5 * start, start)), key=lambda r: r.fun)
        f = np.asarray(best.x, float)
        try:
            eq = self.solve(f)
        except PliantError:
            return None
        return f, eq, self.objective(eq, f)


def _steps(n: int) -> str:
    return "at the step" if n == 1 else f"at the {n} steps"


def place_second_hand(scene: Any, run: Any, rules: Rules, settings: EvaluationSettings,
                      grip: str, steps: list[GripStep], elements: int) -> OperatorResult | None:
    """The two-hand operator with the second hand at the best s2 (see the module), or
    None where no candidate could be solved."""
    from pliant.models import rod3d  # noqa: PLC0415

    friction = rules.hand_friction
    rows = hand_rows(rules, settings, settings.hold)
    ratios = [_ratio(g.wrench, rows, friction) for g in steps]
    red = [k for k, r in enumerate(ratios) if r > 1.0]
    if not red:
        return None
    worst = max(red, key=lambda k: ratios[k])
    solver = rod3d.RodSolver(elements=elements)
    found: list[tuple[float, float, np.ndarray, Any, int]] = []
    solves = 0
    for s2 in _candidates(run, grip):
        placement = _Placement(run.problems[worst], run.equilibria[worst], grip, s2, solver,
                               rows, friction)
        result = placement.best_push()
        solves += placement.solves
        if result is not None:
            found.append((result[2], s2, result[0], result[1], placement.solves))
    if not found:
        return None
    _, s2, f_worst, eq_worst, _ = min(found, key=lambda x: x[0])
    first = list(steps)
    pushes: dict[int, tuple[float, float, float]] = {}
    equilibria: dict[int, Any] = {worst: eq_worst}
    pushes[worst] = tuple(float(x) for x in f_worst)
    failed = []
    for k in red:
        if k == worst:
            continue
        placement = _Placement(run.problems[k], run.equilibria[k], grip, s2, solver, rows,
                               friction)
        result = placement.best_push()
        solves += placement.solves
        if result is None:
            failed.append(k)
            continue
        pushes[k] = tuple(float(x) for x in result[0])
        equilibria[k] = result[1]
    for k, eq in equilibria.items():
        first[k] = grip_step(eq, grip)
    checks: list[Check] = hand_checks(grip, first, rows, friction)
    second = []
    indices = sorted(equilibria)
    for k in indices:
        eq = equilibria[k]
        node = int(np.argmin(np.abs(eq.s - s2)))
        tangent = eq.tangent[node]
        second.append(GripStep(split_wrench(np.array(pushes[k]), np.zeros(3), tangent),
                               pushes[k], (0.0, 0.0, 0.0), tuple(float(x) for x in tangent),
                               s2))
    checks += hand_checks(f"{SECOND} (s = {s2:.3g} m)", second, rows, friction,
                          indices=indices)
    if failed:
        checks.append(series_check("second hand solved", "red steps where the second "
                                   "hand's push could not be solved", "solve",
                                   [float(len(failed))], "", "above", None, 0.0,
                                   "the accurate model", "computed",
                                   note=f"steps {', '.join(map(str, failed))}"))
    peak = max((math.hypot(*f) for f in pushes.values()), default=0.0)
    summary = (f"two hands: the second at s = {s2:.3g} m along the part, pushing with up "
               f"to {peak:.3g} N ({_steps(len(pushes))} where one hand is red)")
    return OperatorResult(f"two hands, second at s = {s2:.3g} m", checks, summary,
                          second_hand_s=s2, second_hand_forces=pushes, solves=solves)
