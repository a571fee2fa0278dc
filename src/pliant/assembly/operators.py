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
pushes changes), walking out from the worst step: a step starts from its neighbour's
push and sensitivity (2 solves), measured again where that push is still red (3 more).
4 solves per candidate at the worst step (5 candidates, at sixths of the free span: 20).
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
    outward_sign,
    position_at,
    series_check,
    tangent_at,
)
from pliant.core.conditions import push
from pliant.core.equilibrium import Equilibrium3D
from pliant.core.events import HeldRigid, has
from pliant.core.numbers import triple
from pliant.core.rules import Capacity, EvaluationSettings, Rules
from pliant.errors import PliantError

SECOND = "second hand"
# Fractions of the free span from the support to the grip.
CANDIDATES = (1 / 6, 2 / 6, 3 / 6, 4 / 6, 5 / 6)


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
    out: list[float] = []
    for frac in CANDIDATES:
        s = a + frac * (s_grip - a)
        node = float(nodes[int(np.argmin(np.abs(nodes - s)))])
        if all(abs(node - c) > 1e-9 for c in [*others, s_grip, *out]):
            out.append(node)
    return out


class _Placement:
    """The second hand at s2 at one step: the first hand's wrench as a linear function of
    the push (its value at a push f0 and its sensitivity A), and the push that minimises
    the worst ratio on that model."""

    def __init__(self, problem: Any, warm: Any, grip: str, s2: float, solver: Any,
                 rows: list[Capacity], friction: float) -> None:
        self.problem, self.warm, self.grip, self.s2 = problem, warm, grip, s2
        self.solver, self.rows, self.friction = solver, rows, friction
        self.solves = 0

    def solve(self, f: np.ndarray) -> Equilibrium3D:
        """The equilibrium with the push f, warm-started from the last one solved here
        (the first from ``warm``: the one-hand equilibrium, or a neighbouring step's
        with the second hand)."""
        from pliant.models import rod3d  # noqa: PLC0415

        conditions = [*self.problem.conditions,
                      push(self.s2, force=tuple(float(x) for x in f), name=SECOND)]
        self.solves += 1
        eq = rod3d.solve(self.problem.with_conditions(conditions), warm_start=self.warm,
                         solver=self.solver)
        self.warm = eq
        return eq

    def worst(self, first: Any, f: np.ndarray, tangent: np.ndarray) -> float:
        """The worst ratio over both hands: the first hand's wrench, and the push f
        split at the part's tangent where the second hand holds it."""
        second = split_wrench(f, np.zeros(3), tangent)
        return max(_ratio(first, self.rows, self.friction),
                   _ratio(second, self.rows, self.friction))

    def objective(self, eq: Equilibrium3D, f: np.ndarray) -> float:
        return self.worst(grip_step(eq, self.grip).wrench, f, tangent_at(eq, self.s2))

    def sensitivity(self, eq0: Any, f0: np.ndarray) -> np.ndarray | None:
        """(6, 3): the first hand's (force, moment) per newton pushed, by finite
        differences about the push f0 whose equilibrium is eq0 (3 solves)."""
        g0 = grip_step(eq0, self.grip)
        w0 = np.concatenate([g0.force, g0.moment])
        delta = max(1.0, 0.1 * g0.wrench.force)
        columns = []
        for i in range(3):
            f = f0.copy()
            f[i] += delta
            try:
                eq = self.solve(f)
            except PliantError:
                return None
            g = grip_step(eq, self.grip)
            columns.append((np.concatenate([g.force, g.moment]) - w0) / delta)
        return np.column_stack(columns)

    def best_push(self, eq0: Any, f0: np.ndarray, A: np.ndarray
                  ) -> tuple[np.ndarray, Any, float] | None:
        """Minimise the worst ratio on the linear model about (eq0, f0) with sensitivity
        A, then solve there: (f [N], its equilibrium, its worst ratio), or None where the
        solve failed."""
        from scipy.optimize import minimize  # noqa: PLC0415

        g0 = grip_step(eq0, self.grip)
        w0 = np.concatenate([g0.force, g0.moment])
        t2 = tangent_at(eq0, self.s2)
        t1 = np.array(g0.tangent)
        outward = outward_sign(g0.s, self.problem.part.length)

        def model(f: np.ndarray) -> float:
            w = w0 + A @ (f - f0)
            return self.worst(split_wrench(w[:3], w[3:], t1, outward), f, t2)

        # Also start from the push that cancels the first hand's force in least squares.
        cancel = f0 + np.linalg.lstsq(A[:3], -w0[:3], rcond=None)[0]
        best = min((minimize(model, x0, method="Nelder-Mead",
                             options={"xatol": 1e-3, "fatol": 1e-4, "maxiter": 2000})
                    for x0 in (f0, 0.5 * (f0 + cancel), cancel)), key=lambda r: r.fun)
        f = np.asarray(best.x, float)
        try:
            eq = self.solve(f)
        except PliantError:
            return None
        return f, eq, self.objective(eq, f)


def _at_worst(run: Any, k: int, grip: str, s2: float, solver: Any, rows: list[Capacity],
              friction: float) -> tuple[tuple[np.ndarray, Any, float] | None, np.ndarray | None,
                                        int]:
    """The best push at s2 at step k from the one-hand equilibrium (f = 0): 4 solves.
    (result, sensitivity, solves)."""
    place = _Placement(run.problems[k], run.equilibria[k], grip, s2, solver, rows, friction)
    A = place.sensitivity(run.equilibria[k], np.zeros(3))
    if A is None:
        return None, None, place.solves
    return place.best_push(run.equilibria[k], np.zeros(3), A), A, place.solves


def _steps(n: int) -> str:
    return "at the step" if n == 1 else f"at the {n} steps"


def _too_far(scene: Any, rules: Rules, grip: str):
    """Whether two hands, at ``grip`` and at s2 on an equilibrium, are farther apart than
    the worker (the 5th percentile woman without one) holds them with the upper arms
    below the red onset (``posture.spread``): such a place is taken only where no other
    is solved."""
    from pliant.assembly.posture import spread_of  # noqa: PLC0415

    body = spread_of(rules, getattr(scene, "worker", None))
    if body is None:
        return lambda eq, s2: False
    red = body.limits[1]
    return lambda eq, s2: bool(np.linalg.norm(position_at(eq, eq.loads[grip].s)
                                              - position_at(eq, s2)) > red)


def place_second_hand(scene: Any, run: Any, rules: Rules, settings: EvaluationSettings,
                      grip: str, steps: list[GripStep], elements: int) -> OperatorResult | None:
    """The two-hand operator with the second hand at the best s2 (see the module), or
    None where no candidate could be solved."""
    from pliant.models import rod3d  # noqa: PLC0415

    friction = rules.hand_friction
    rows = hand_rows(rules, settings, settings.hold)
    ratios = [_ratio(g.wrench, rows, friction) for g in steps]
    # A step solved with a fitted part or clip held rigid (a fallback) is not judged, so
    # no second hand is placed from it either.
    held = {k for k, eq in enumerate(run.equilibria) if has(eq.notes, HeldRigid)}
    red = {k for k, r in enumerate(ratios) if r > 1.0 and k not in held}
    if not red:
        return None
    worst = max(red, key=lambda k: ratios[k])
    # Not settled: each push's effect on the first hand is measured on the branch the
    # hands hold (finite differences), not on one a settled answer jumped to.
    solver = rod3d.RodSolver(elements=elements, settle=False)
    found: list[tuple[float, float, Any, np.ndarray | None]] = []
    solves = 0
    for s2 in _candidates(run, grip):
        result, A, used = _at_worst(run, worst, grip, s2, solver, rows, friction)
        solves += used
        if result is not None:
            found.append((result[2], s2, result, A))
    if not found:
        return None
    too_far = _too_far(scene, rules, grip)
    _, s2, (f_worst, eq_worst, _), A_worst = min(
        found, key=lambda x: (too_far(x[2][1], x[1]), x[0]))
    first = list(steps)
    pushes: dict[int, tuple[float, float, float]] = {worst: triple(f_worst)}
    equilibria: dict[int, Any] = {worst: eq_worst}
    failed = []
    # Out from the worst step, each red step from its neighbour's: the push there and its
    # sensitivity predict this step's push (2 solves); where that push is still red, the
    # sensitivity is measured again here (3 more).
    for side in (1, -1):
        near = (eq_worst, np.array(f_worst), A_worst)
        k = worst + side
        while 0 <= k < len(steps):
            if k not in red:
                k += side
                continue
            eq_near, f_near, A = near
            place = _Placement(run.problems[k], eq_near, grip, s2, solver, rows, friction)
            try:
                base = place.solve(f_near)
            except PliantError:
                base = None
            result = None if base is None or A is None else place.best_push(base, f_near, A)
            if result is not None and result[2] > 1.0:
                A_here = place.sensitivity(result[1], result[0])
                if A_here is not None:
                    retry = place.best_push(result[1], result[0], A_here)
                    if retry is not None and retry[2] < result[2]:
                        result, A = retry, A_here
            solves += place.solves
            if result is None:
                failed.append(k)
            else:
                pushes[k] = triple(result[0])
                equilibria[k] = result[1]
                near = (result[1], result[0], A)
            k += side
    for k, eq in equilibria.items():
        first[k] = grip_step(eq, grip)
    checks: list[Check] = hand_checks(grip, first, rows, friction)
    second = []
    indices = sorted(equilibria)
    for k in indices:
        tangent = tangent_at(equilibria[k], s2)
        second.append(GripStep(split_wrench(np.array(pushes[k]), np.zeros(3), tangent),
                               pushes[k], (0.0, 0.0, 0.0), triple(tangent),
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
