"""Leaving an unstable equilibrium (issue 60): where a solve ends on one, the part leaves
it along its unstable mode and settles on a stable one (``settled``). A warm step's
settling is told apart as a jump or as the stable branch that leaves a bifurcation
crossed on the way, which a real part follows without one (``_jumps``). Also the
comparisons of answers the solver's searches share (``shape_distance``, ``same_shape``,
``same_family``)."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pliant.core.equilibrium import Equilibrium3D, potential_energy
from pliant.core.events import LeftUnstable
from pliant.models.continuation import Stalled
from pliant.models.rod3d.results import WarmState, build
from pliant.models.rod3d.stability import stability_of

if TYPE_CHECKING:
    from pliant.models.rod3d.lowering import Loads, State
    from pliant.models.rod3d.solver import Run

_TRIES = 6  # regula falsi steps toward a point of the step a quarter as unstable


def shape_distance(a: Equilibrium3D, b: Equilibrium3D) -> float:
    """The largest distance [m] along any coordinate between two answers' neutral lines,
    sampled at 41 points of the part."""
    s = np.linspace(0.0, a.problem.part.length, 41)
    pa = np.column_stack([np.interp(s, a.s, a.position[:, k]) for k in range(3)])
    pb = np.column_stack([np.interp(s, b.s, b.position[:, k]) for k in range(3)])
    return float(np.abs(pa - pb).max())


def same_shape(a: Equilibrium3D, b: Equilibrium3D) -> bool:
    """One equilibrium reached twice: the same neutral line to 1e-6 of the part's length
    (``shape_distance``)."""
    return shape_distance(a, b) <= 1e-6 * a.problem.part.length


def same_family(a: Equilibrium3D, b: Equilibrium3D) -> bool:
    """One equilibrium, or two of one neutral family (the same energy to 1e-8: a round
    part's arch turned about its chord is the same answer)."""
    if same_shape(a, b):
        return True
    ea, eb = potential_energy(a), potential_energy(b)
    return (a.verdict == b.verdict == "neutral"
            and abs(ea - eb) <= 1e-8 * max(abs(ea), abs(eb), 1e-300))


def settled(run: Run, eq: Equilibrium3D, warm_start: Equilibrium3D | None
            ) -> Equilibrium3D:
    """An unstable answer left for the stable equilibrium the part settles in
    (``Routes.downhill``): from a warm start the nearest to it (where the part was), from
    rest the lowest; the unstable answer itself where it settles nowhere (its verdict
    says so)."""
    found = downhill_equilibria(run, eq)
    if not found:
        return eq
    best = where_settled(found, warm_start)
    released = potential_energy(eq) - potential_energy(best)
    distance = float(np.linalg.norm(best.position - eq.position, axis=1).max())
    if warm_start is None:
        jump, how = False, "the lowest of those it settles in from there"
    else:
        jump, why = _jumps(run, eq, best, warm_start, released)
        how = ("a jump (a snap): a real part jumps here" if jump else
               "the stable branch that leaves a bifurcation on the way, which a real part "
               "follows without a jump") + f" ({why})"
    note = LeftUnstable(
        f"the equilibrium reached is unstable (smallest eigenvalue {eq.stability[1]:.3g}): "
        f"the part leaves it along that mode and settles here ({best.verdict}), "
        f"{distance:.3g} m away at most, releasing {released:.3g} J; {how}",
        eigenvalue=float(eq.stability[1] or 0.0), distance=distance, released=released,
        jump=jump)
    return replace(best, notes=(*eq.notes, note), iterations=run.iterations)


def where_settled(found: list[Equilibrium3D], warm_start: Equilibrium3D | None
                  ) -> Equilibrium3D:
    """Of the equilibria an unstable answer settles in, the one a part takes: from a
    warm start the nearest to it (where the part was), then the lowest; from rest the
    lowest."""
    if warm_start is None:
        return min(found, key=potential_energy)
    return min(found, key=lambda e: (shape_distance(e, warm_start), potential_energy(e)))


def jump_by_energy(eq: Equilibrium3D, warm_start: Equilibrium3D, released: float
                   ) -> tuple[bool, str]:
    """Whether a warm step that ended on ``eq``, unstable, jumps where settling
    releases ``released`` [J]: more than a tenth of the energy the step itself
    changed; and why, in words."""
    step = abs(potential_energy(eq) - potential_energy(warm_start))
    return released > 0.1 * step, (f"it releases {released / step if step else math.inf:.2g} "
                                   "of the energy the step changed")


def downhill_equilibria(run: Run, eq: Equilibrium3D) -> list[Equilibrium3D]:
    """The stable or neutral equilibria an unstable one leads to, left along its unstable
    mode either way (``Routes.downhill``), built as answers of ``run``."""
    return [e for e in (build(run, s) for s in run.downhill(eq.state.state))
            if e.verdict != "unstable"]


def _jumps(run: Run, eq: Equilibrium3D, best: Equilibrium3D, warm_start: Equilibrium3D,
           released: float) -> tuple[bool, str]:
    """Whether a warm step that ended unstable makes the part jump, and why. On a stable
    branch that leaves a bifurcation, how far the part settles from the followed branch
    grows as the square root of the followed branch's negative eigenvalue; where it
    jumps, it moves about as far however little past it is. So the step is followed
    again from its stable start to where that eigenvalue is about a quarter of the
    end's (``_settled_nearer``), the part let settle there too, and the two distances
    compared: nearer the square-root law's ratio than 1 is no jump. Where the step
    cannot be followed again (another mesh, a start not decided stable), a jump where
    settling releases (``released`` [J]) more than a tenth of the energy the step itself
    changed."""
    old = warm_start.state
    start_eigen, end_eigen = warm_start.stability[1], float(eq.stability[1] or 0.0)
    far = run.primal_move(run.difference(eq.state.state, best.state.state))
    if (isinstance(old, WarmState) and old.rod.key == run.rod.key and warm_start.stable
            and start_eigen is not None and start_eigen > 0.0 and far > 0.0):
        gauge = run.gauge_quat.copy()
        try:
            nearer = _settled_nearer(run, old, float(start_eigen), end_eigen)
        finally:
            run.gauge_quat = gauge
        if nearer is not None:
            near, eigen = nearer
            ratio, law = near / far, math.sqrt(eigen / end_eigen)
            return ratio > 0.5 * (1.0 + law), (
                f"settled where the followed shape's eigenvalue is {eigen / end_eigen:.2f} "
                f"of this one's, it moves {ratio:.2f} as far: {law:.2f} on a branch that "
                "leaves a bifurcation, about 1 where it jumps")
    return jump_by_energy(eq, warm_start, released)


def _settled_nearer(run: Run, old: WarmState, eigen0: float, eigen1: float
                    ) -> tuple[float, float] | None:
    """(how far the part moves as it settles, in the unknowns' metric as
    ``primal_move``; the followed shape's eigenvalue there) at a point of the step where
    that eigenvalue is between a tenth and a half of the end's ``eigen1`` (found by
    regula falsi, Illinois' variant, on the eigenvalue less a quarter of ``eigen1``,
    from the start's ``eigen0``); None where none is found or it settles nowhere."""
    start, end = old.rod.target, run.rod.target
    goal = 0.25 * eigen1
    low, high, f_low, f_high = 0.0, 1.0, eigen0 - goal, eigen1 - goal
    side = 0
    for _ in range(_TRIES):
        t = low + (high - low) * f_low / (f_low - f_high)
        loads = start.lerp(end, t)
        try:
            state = run.follow(start, loads, old.state)
        except Stalled:
            return None
        stable, eigen = stability_of(run, state, loads=loads)
        if not stable and 0.1 <= eigen / eigen1 <= 0.5:
            moved = _settle_distance(run, state, loads)
            return None if moved is None else (moved, float(eigen))
        if eigen - goal > 0.0:
            low, f_low = t, eigen - goal
            f_high *= 0.5 if side == 1 else 1.0
            side = 1
        else:
            high, f_high = t, eigen - goal
            f_low *= 0.5 if side == -1 else 1.0
            side = -1
    return None


def _settle_distance(run: Run, state: State, loads: Loads) -> float | None:
    """The least distance the part moves settling from ``state`` (unstable at
    ``loads``) along its unstable mode, either way."""
    moves = [run.primal_move(run.difference(state, s))
             for s in run.downhill(state, loads)]
    return min(moves) if moves else None
