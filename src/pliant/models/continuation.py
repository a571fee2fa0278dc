"""One continuation and Newton driver for the accurate models.

A model gives the driver a few small operations on its own unknowns (``Continuable``:
correct a predicted point with its Newton, the path's tangent at its start, a step, the
difference of two points, how far a corrector moved; ``Relaxable`` for the snap), and
the driver owns what every model needs the same way:

- ``follow``: the homotopy from an exact start to the problem, t from 0 to 1: a tangent
  first predictor and secants after, a corrector that must contract (or the step is cut
  by ``shrink``), steps aimed at a corrector distance of ``grow`` and capped so that the
  loads' wavenumber sqrt(t F) + t C rises by at most ``wave_step`` (buckling modes appear
  about pi apart in it), step and time budgets, and a typed ``Stalled`` that keeps the
  last good point, where it stopped and what was left of the way.
- ``first_route``: the ladder of fallback routes (straight, two-stage, swing, loads
  first, more restart nodes...): each in turn, what a failed route said dropped, the
  furthest stall raised when all fail.
- ``ranked``: which of several equilibria to answer with: stable (or neutral) before
  unstable, then the lower potential energy; a tie keeps the earlier (mirror twins).
- ``settle``: a snap past a fold, by a pseudo-transient relaxation that is pushed along a
  saddle's unstable mode so that it cannot stall there.

The 3D rod (``rod3d.solver.Run``) and parts solved together (``rod3d.coupled``) are
driven by ``follow``; the 2D shooting model runs the same algorithm compiled
(``elastica2d.kernels.follow``, for its microsecond steps) and also implements
``Continuable``, so that this driver's path and the compiled one are checked against
each other (``tests/test_continuation.py``). Every answer's ``Status`` and the events on
the way are ``pliant.core.events``'.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np

from pliant.core.equilibrium import potential_energy
from pliant.core.events import Status
from pliant.models import clock

T = TypeVar("T")


@dataclass
class Stalled(Exception):
    """Why a route stopped short of the problem, and where.

    t : how far along the route (0: its start, 1: the problem)
    residual : the last corrector's residual (the model's own scale)
    state : the last good point on the way (the model's unknowns), or None
    memo : what the model needs besides ``state`` to go on from it (3D: the twist
        gauge's frame), or None
    loads : the homotopy's loads at ``state``; ahead : what was left of the route: the
        leg's end and the legs after it
    singular_start : the path's start is singular (it may buckle to either side)
    budget : a step or time budget ran out (not a property of the path)
    intervals : the shooting intervals the path asks for to go on, where its forces
        outgrew the model's (2D); 0 otherwise
    """

    t: float
    residual: float
    reason: str
    singular_start: bool = False
    budget: bool = False
    state: Any = None
    memo: Any = None
    loads: Any = None
    ahead: tuple = ()
    status: Status = Status.FOLD
    intervals: int = 0


@dataclass(frozen=True)
class Stepping:
    """How ``follow`` steps (dimensionless t from 0 to 1).

    tolerance, loose : the corrector's tolerance at the end point and on the way
    min_step : the shortest step before the path counts as stalled (a fold)
    max_steps : the steps one homotopy may take (None: the time budget alone bounds it)
    grow : the corrector distance the next step aims at (each unknown relative to its
        size; the secant errs like dt^2, so dt scales by sqrt(grow / miss), within
        [0.5, 4]); None doubles each step that converged
    shrink : the step's factor after a corrector that failed
    wave_step : the most a step may raise the loads' wavenumber
    retry_from_last : a corrector that failed from the secant's prediction tries once
        from the last point before the step is cut (parts solved together: the secant
        overshoots where the set of touching probes changes)
    time_budget : the solve's budget [s], for the message when it runs out
    fold_hint : what else a stall on the way may mean, added to its reason
    parabola : from the third step on, predict along the parabola through the last
        three points (an error like dt^3) instead of the secant (the 2D model's twin of
        its compiled ``follow``; dt still scales by the secant's rule, the more cautious)
    loose_at : the tolerance of the point at t on the way, where it is not ``loose``
        throughout (the 2D model's: relative to how far its inputs have moved so far)
    last_stretch : a step that would leave less than (last_stretch - 1) of itself to go
        takes the rest at once, past the caps by that much at most (the sliver would
        cost a corrector of its own); 1 (never) by default, the 2D model's driver sets
        its kernel's ``LAST_STRETCH``
    refused_fade : where set, a refused step leaves a memory: the steps after it grow to
        no more than half of it, the memory fading by this factor at each step taken
        (steps that alternated, taken, grown fourfold and refused, waste half their
        correctors); None (off) by default, the 2D model's driver sets its kernel's
        ``REFUSED_FADE``
    """

    tolerance: float
    loose: float
    min_step: float
    max_steps: int | None
    grow: float | None
    shrink: float = 0.25
    wave_step: float = 1.0
    retry_from_last: bool = False
    time_budget: float = math.inf
    fold_hint: str = ""
    parabola: bool = False
    last_stretch: float = 1.0
    loose_at: Callable[[float], float] | None = None
    refused_fade: float | None = None


class Path(Protocol):
    """A homotopy's loads and targets: ``at(t)``, ``end`` = at(1)."""

    @property
    def end(self) -> Any: ...

    def at(self, t: float) -> Any: ...


@dataclass(frozen=True)
class Line:
    """The straight homotopy between two loads that know ``lerp``."""

    start: Any
    end: Any

    def at(self, t: float) -> Any:
        return self.start.lerp(self.end, t)


class Continuable(Protocol):
    """What ``follow`` asks of a model. ``correct`` adds its Newton iterations to the
    model's count; the driver adds the steps.

    A model may also offer ``det_sign(point, loads, fresh) -> float``, the sign of its
    Jacobian's determinant at a converged point (its corrector's Jacobian, or a fresh
    one where ``fresh``), and ``crossed()``: the driver then follows that sign along the
    path as the 2D model's compiled twin does (``elastica2d.kernels.follow``). A step
    that flips it jumped to another branch or crossed a fold or bifurcation too fast,
    and is refused, until the step is so short (1e3 ``min_step``) that the crossing is
    genuine: then ``crossed()`` is told, so that the model can say so. And
    ``stepped(dt)``: told the length of each step taken but the last (the 2D model
    counts the short ones, as its twin's rule on creeping paths does)."""

    steps: int

    def correct(self, predictor: Any, loads: Any, *, strict: bool, tol: float | None
                ) -> tuple[Any, float, Status]:
        """Newton from ``predictor`` at ``loads`` to ``tol`` (None: the model's own
        tolerance): (point, residual, status); strict: each iteration must contract (a
        continuation corrector), else damped."""
        ...

    def tangent(self, state: Any, path: Any) -> Any | None:
        """d state / dt at the path's start (the first predictor's direction), or None
        where the start is singular."""
        ...

    def step(self, state: Any, du: Any, scale: float) -> Any: ...

    def difference(self, a: Any, b: Any) -> Any: ...

    def miss(self, predicted: Any, corrected: Any) -> float:
        """How far the corrector moved from the prediction, each unknown relative to its
        size (the step control's measure)."""
        ...

    def load_size(self, path: Any) -> tuple[float, float]:
        """(F, C): the change of the forces and of the moments along the path
        (dimensionless), which the wavenumber rule caps; (0, 0) for no cap."""
        ...

    def begin_step(self, state: Any) -> Any:
        """Called before each step with its start point (friction measured from it);
        returns the point to step from."""
        ...

    def memo(self) -> Any:
        """What a stall keeps besides its state (see ``Stalled``)."""
        ...


def _stall_words(status: Status) -> str:
    if status == Status.SINGULAR:
        return ("the Jacobian became singular (a fold or bifurcation: the branch ends or "
                "turns back here)")
    return ("Newton stopped contracting however short the step (a fold: the branch ends "
            "or turns back here)")


def follow(model: Continuable, path: Path, state: Any, stepping: Stepping,
           deadline: float, *, strict: bool = True, need_tangent: bool = True) -> Any:
    """Continuation from ``state``, an exact solution at ``path.at(0)``, to
    ``path.at(1)``; see the module. Raises ``Stalled``. ``strict=False``: damped
    correctors (nothing moves on the path, a first solve); ``need_tangent=False``: a
    singular start is no stall, the first predictor is then the start itself."""
    direction = model.tangent(state, path)
    if need_tangent and direction is None:
        raise Stalled(0.0, math.inf, "the start is singular", singular_start=True,
                      status=Status.SINGULAR)
    load_f, load_c = model.load_size(path)
    root_f = math.sqrt(load_f)
    signed = getattr(model, "det_sign", None)  # optional (see ``Continuable``)
    stepped = getattr(model, "stepped", None)
    sign = signed(state, path.at(0.0), True) if signed is not None else None
    t, dt = 0.0, 1.0
    refused = math.inf  # the last step refused (``Stepping.refused_fade``)
    prev: tuple[float, Any] | None = None
    prev2: tuple[float, Any] | None = None
    steps = 0
    while True:
        if stepping.max_steps is not None and steps >= stepping.max_steps:
            raise Stalled(t, math.inf, f"the continuation budget of {stepping.max_steps} "
                          "steps ran out", budget=True, state=state, memo=model.memo(),
                          status=Status.STEP_BUDGET)
        if clock.now() > deadline:
            raise Stalled(t, math.inf, f"the time budget of {stepping.time_budget} s ran "
                          "out", budget=True, state=state, memo=model.memo(),
                          status=Status.TIME_BUDGET)
        # No step may raise the loads' wavenumber sqrt(t F) + t C by more than wave_step:
        # u = sqrt(t + dt) solves C u^2 + sqrt(F) u = K, in a form that does not cancel.
        if load_c > 0.0 or root_f > 0.0:
            k_next = math.sqrt(t) * root_f + t * load_c + stepping.wave_step
            u = 2.0 * k_next / (root_f + math.sqrt(root_f**2 + 4.0 * load_c * k_next))
            dt = min(dt, max(u * u - t, stepping.min_step))
        if t + dt < 1.0 and t + stepping.last_stretch * dt >= 1.0:
            dt = 1.0 - t  # the rest at once: no sliver that costs a corrector of its own
        t_next = min(1.0, t + dt)
        loads = path.at(t_next)
        state = model.begin_step(state)
        if stepping.parabola and prev2 is not None and prev is not None:
            (t0, s0), (t1, s1) = prev2, prev  # Lagrange's parabola through three points
            l0 = (t_next - t1) * (t_next - t) / ((t0 - t1) * (t0 - t))
            l1 = (t_next - t0) * (t_next - t) / ((t1 - t0) * (t1 - t))
            predictor = model.step(model.step(state, model.difference(state, s0), l0),
                                   model.difference(state, s1), l1)
        elif prev is not None:
            t_prev, s_prev = prev
            predictor = model.step(state, model.difference(s_prev, state),
                                   (t_next - t) / (t - t_prev))
        elif direction is not None:
            predictor = model.step(state, direction, t_next - t)
        else:
            predictor = state
        final = t_next >= 1.0
        tol = stepping.tolerance if final else (
            stepping.loose if stepping.loose_at is None else stepping.loose_at(t_next))
        corrected, r, status = model.correct(predictor, loads, strict=strict, tol=tol)
        if (status != Status.CONVERGED and stepping.retry_from_last and prev is not None):
            # The secant overshot: the corrector once more from the last point.
            predictor = state
            corrected, r, status = model.correct(state, loads, strict=strict, tol=tol)
        if status == Status.CONVERGED and signed is not None:
            new_sign = signed(corrected, loads, False)
            if new_sign != sign:
                new_sign = signed(corrected, loads, True)  # (a corrector's may be updated)
            if new_sign != sign:
                if dt > 1e3 * stepping.min_step:
                    status = Status.FOLD  # refused: shorter, until the crossing is genuine
                else:
                    sign = new_sign
                    model.crossed()  # type: ignore[attr-defined]
        if status == Status.CONVERGED:
            steps += 1
            model.steps += 1
            miss = model.miss(predictor, corrected) if stepping.grow is not None else 0.0
            prev2, prev, state, t = prev, (t, state), corrected, t_next
            if final:
                return state
            if stepped is not None:
                stepped(dt)
            if stepping.grow is None:
                grown = min(1.0 - t, 2.0 * dt)
            else:
                grown = min(1.0, dt * min(4.0, max(0.5, math.sqrt(
                    stepping.grow / max(miss, 1e-300)))))
            if stepping.refused_fade is not None:
                refused *= stepping.refused_fade
                grown = min(grown, max(dt, 0.5 * refused))
            dt = grown
        else:
            refused = t_next - t
            dt *= stepping.shrink
            if dt < stepping.min_step:
                raise Stalled(t, r, _stall_words(status) + stepping.fold_hint,
                              state=state, memo=model.memo(),
                              loads=path.at(t), ahead=(path.end,),
                              status=Status.SINGULAR if status == Status.SINGULAR
                              else Status.FOLD)


def through(model: Continuable, start: Any, targets: Sequence[Any], state: Any,
            stepping: Stepping, deadline: float) -> Any:
    """Follow the straight homotopies start -> targets[0] -> targets[1] -> ...; a stall's
    progress counts over the whole route, and it keeps the legs it did not reach."""
    for i, end in enumerate(targets):
        try:
            state = follow(model, Line(start, end), state, stepping, deadline)
        except Stalled as stall:
            stall.t = (i + stall.t) / len(targets)
            stall.ahead = stall.ahead + tuple(targets[i + 1:])
            raise
        start = end
    return state


def first_route(routes: Iterable[Callable[[], T]], notes: list, deadline: float) -> T:
    """The first route that reaches the problem: each in turn; the notes a failed route
    added are dropped (what it found does not hold); when all fail, the stall that got
    furthest is raised (a budget stall ends the ladder once the time is out)."""
    best: Stalled | None = None
    for route in routes:
        said = len(notes)
        try:
            return route()
        except Stalled as stall:
            del notes[said:]
            if best is None or stall.t > best.t:
                best = stall
            if stall.budget and clock.now() > deadline:
                break
    if best is None:
        raise Stalled(0.0, math.inf, "no route to try", status=Status.NO_ROUTE)
    raise best


@dataclass(frozen=True)
class Candidate:
    """An equilibrium found, as ``ranked`` weighs it: ``stable`` True, False or None
    (neutral or undecided counts as not unstable), its potential ``energy`` [J]."""

    stable: bool | None
    energy: float
    item: Any


def ranked(candidates: Sequence[Candidate], scale: float = 0.0) -> list[Candidate]:
    """The candidates best first: stable (or neutral, or undecided) before unstable,
    then the lower potential energy; energies within 1e-9 of the largest (and of
    ``scale`` [J], the part's EI / L) are one level, where the earlier candidate stays
    first (a mirror twin does not displace the side the targets push to)."""
    step = 1e-9 * (max((abs(c.energy) for c in candidates), default=0.0) + scale) or 1e-300

    def level(c: Candidate) -> tuple[bool, int]:
        return c.stable is False, round(c.energy / step)

    return sorted(candidates, key=level)  # a stable sort: ties keep their order


def best_first(found: Sequence[T], part: Any) -> list[T]:
    """Equilibria of one problem (``Result``s) in ``ranked``'s order: stable and neutral
    first, then by potential energy, twins in the order they were reached (what
    ``equilibria`` lists, in both models)."""
    return [c.item for c in ranked(
        [Candidate(e.verdict != "unstable", potential_energy(e), e)  # type: ignore[attr-defined]
         for e in found], part.bending_stiffness / part.length)]


class Relaxable(Protocol):
    """What ``settle`` asks of a model, besides ``Continuable``'s step: the pseudo-time
    system W du / dtau = -grad E under the constraints, in the model's own storage."""

    iterations: int
    deadline: float

    @property
    def tolerance(self) -> float:
        """The largest residual entry an equilibrium may leave."""
        ...

    def gradient(self, state: Any, loads: Any) -> tuple[np.ndarray, Any]:
        """(R, J): the residual and its Jacobian (the KKT system)."""
        ...

    def diagonal_scale(self, jac: Any) -> float:
        """max |J_ii| / W_i over the primal unknowns: the shift at which relaxing
        starts."""
        ...

    def shifted_solve(self, jac: Any, sigma: float, rhs: np.ndarray
                      ) -> tuple[np.ndarray, bool]:
        """Solve (J + sigma W) du = rhs, W the metric on the primal unknowns (J may be
        overwritten)."""
        ...

    def primal_move(self, du: np.ndarray) -> float:
        """The largest move of a primal unknown (dimensionless, in units of L)."""
        ...

    def unstable_mode(self, state: Any, loads: Any) -> np.ndarray | None:
        """At an equilibrium: None where it is stable (or neutral), else its softest
        mode as a step (an unknown vector)."""
        ...

    def step(self, state: Any, du: Any, scale: float) -> Any: ...

    def correct(self, predictor: Any, loads: Any, *, strict: bool, tol: float | None
                ) -> tuple[Any, float, Status]: ...


def relax(model: Relaxable, state: Any, loads: Any, max_steps: int = 600,
          stride: float = 0.02) -> Any | None:
    """Pseudo-transient continuation: implicit Euler steps of the gradient flow
    W du/dtau = -grad E under the constraints, each one Newton iteration on
    [K + W / dtau, A^T; A, 0] [du; dlam] = -R. The pseudo-time step adapts so that each
    step moves the part about ``stride`` L; as the flow settles the steps grow and it
    ends as Newton. Implicit Euler leaves a saddle (an equilibrium just past a fold)
    along its unstable direction, where a Newton would stay or wander. None where it
    does not settle."""
    R, jac = model.gradient(state, loads)
    if not np.isfinite(R).all():
        return None
    sigma = model.diagonal_scale(jac)
    ceiling = 1e8 * max(sigma, 1.0)
    neutral = 1e-6 * sigma
    for _ in range(max_steps):
        if clock.now() > model.deadline or sigma > ceiling:
            return None  # out of time, or no step short enough: it cannot settle
        du, ok = model.shifted_solve(jac, sigma, -R)
        if not ok and sigma < neutral:
            # Singular only as the shift vanishes: settled on a neutral equilibrium (a
            # round part's arch turning about its chord), which Newton closes on.
            break
        move = model.primal_move(du) if ok else math.inf
        if not math.isfinite(move) or move > 4.0 * stride:
            sigma *= 4.0  # too long a step: a shorter one
            R, jac = model.gradient(state, loads)
            continue
        state = model.step(state, du, 1.0)
        R, jac = model.gradient(state, loads)
        model.iterations += 1
        if move < 0.25 * stride:
            sigma *= 0.25
            if sigma < 1e-12:  # a Newton step: settled
                break
        elif move < stride:
            sigma *= 0.5
        else:
            sigma *= 2.0
    else:
        return None
    state, _r, status = model.correct(state, loads, strict=False, tol=None)
    if status == Status.SINGULAR:
        # Settled on a family it drifts along at no cost (a weightless curved part
        # between two pins turns about their chord): the shifted Newton closes on the
        # member where it came to rest.
        return shifted_newton(model, state, loads, model.tolerance)
    return state if status == Status.CONVERGED else None


def shifted_newton(model: Relaxable, state: Any, loads: Any, tolerance: float,
                   iterations: int = 25, stalls: int = 6) -> Any | None:
    """Newton on J + mu W (mu 1e-9 of the diagonal's scale, W the relaxation's metric):
    where J is singular along a neutral family (a round part's arch turning about its
    chord at no cost), which plain Newton cannot factorise, the shift takes the member
    nearest the start and leaves the rest of the step Newton's. Up to ``stalls``
    iterations may fail to halve the residual (a contact switching); None where it does
    not reach ``tolerance``, or the closing Newton (``correct``) refuses it."""
    R, jac = model.gradient(state, loads)
    mu = 1e-9 * model.diagonal_scale(jac)
    size = float(np.abs(R).max())
    for _ in range(iterations):
        if not math.isfinite(size):
            return None
        if size <= tolerance:
            state, _r, status = model.correct(state, loads, strict=False, tol=None)
            return state if status == Status.CONVERGED else None
        du, ok = model.shifted_solve(jac, mu, -R)
        if not ok:
            return None
        state = model.step(state, du, 1.0)
        R, jac = model.gradient(state, loads)
        model.iterations += 1
        new = float(np.abs(R).max())
        if not new <= 0.5 * size:
            stalls -= 1
            if stalls < 0:
                return None
        size = new
    return None


PUSH = 0.05  # how far a saddle is pushed along its unstable mode, in L


def settle(model: Relaxable, state: Any, loads: Any, push: float = PUSH,
           stride: float = 0.02) -> Any | None:
    """Relax (``relax``, each step about ``stride`` L); where that ends on a saddle (an
    unstable equilibrium: the flow slowed next to it and the closing Newton landed on
    it), push the part along the saddle's unstable mode by ``push`` L, one way then the
    other, and relax again, so that the snap cannot stall at a saddle: the state it
    settles in is stable (or neutral), or None."""
    current = relax(model, state, loads, stride=stride)
    for _ in range(3):
        if current is None:
            return None
        mode = model.unstable_mode(current, loads)
        if mode is None:
            return current
        du = mode * (push / max(float(np.abs(mode).max()), 1e-300))
        pushed = None
        for sign in (1.0, -1.0):
            pushed = relax(model, model.step(current, sign * du, 1.0), loads, stride=stride)
            if pushed is not None:
                break
        current = pushed
    return None
