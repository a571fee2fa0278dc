"""Solve the 2D elastica: ``solve(problem)`` and ``trace(problems)``.

The route, for a problem with no warm start:

1. Homotopy from the rest state (unloaded part, prescribed components where the rest
   shape puts them) to the problem: loads scaled by t and prescribed components moved
   linearly, t from 0 to 1 in adaptive steps. Each step is a Newton corrector that must
   contract (the residual at least halves each iteration) or the step is shortened: a
   contracting Newton converges to the solution continuously connected to the
   predictor, so the answer is the branch continuity from the unloaded part reaches.
2. When the rest state is itself singular (an end pushed along the straight part: an
   inextensible part cannot shorten its chord to first order, so buckling up or down
   are equally possible), the part is given a bow imperfection toward the side the
   targets moved to, the homotopy runs on that imperfect part, and the imperfection is
   then removed by a second homotopy. The choice is reported in ``Equilibrium.notes``.
3. When a homotopy stalls (a fold on that path, or sensitivities too large for the
   shooting intervals), other routes are tried: more restart nodes, the bowed route, and
   a two-stage path (positions first, then loads). Only when all stall does the solve
   fail, with the furthest progress and its residual.
4. The Runge-Kutta mesh is checked against the converged solution (its steps must
   resolve the local wavenumber max|theta'| + sqrt(|n|/EI)); if too coarse, it is
   refined and Newton polishes the answer.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace
from functools import cached_property, partial
from typing import Any

import numpy as np

from pliant.core.equilibrium import (
    WARM_START_LOST,
    Equilibrium,
    PlanarLoad,
    PlanarShape,
    Samples,
    StationLoad,
    model_loads,
    potential_energy,
)
from pliant.core.events import (
    NOT_EXHAUSTIVE,
    BeyondFold,
    BranchTaken,
    CrossedBifurcation,
    Event,
    LoadsStaged,
    LowestEquilibrium,
    OthersFound,
    ReachedBy,
    Status,
    WarmStartLost,
)
from pliant.core.loads import AddedMass, DistributedLoad
from pliant.core.problem import Problem
from pliant.errors import ConvergenceError
from pliant.models import clock, continuation
from pliant.models.continuation import Candidate, Line, Stalled, first_route, ranked
from pliant.models.elastica2d import kernels, minimum
from pliant.models.elastica2d.lowering import (
    APPLIED,
    NODE_SPAN,
    PRESCRIBED,
    Arrays,
    Lowered,
    Mesh,
    load_wavenumber,
    lower,
)
from pliant.models.elastica2d.stability import stability, stable_sign
from pliant.models.settings import check


@dataclass(frozen=True)
class ShootingSolver:
    """Settings of the 2D shooting solver (an immutable config).

    tolerance : relative residual at which Newton stops (lengths by L, forces by EI/L^2)
    accuracy : the largest h * k allowed, h a Runge-Kutta step and k the local wavenumber
        max|theta'| + sqrt(|n| / EI) (dimensionless); 0.5 keeps tip errors below 1e-10 L
    path_accuracy : the same, for the intermediate points of a continuation
    min_density, samples : Runge-Kutta steps per part length at least, while solving and
        in the returned arrays
    path_min_density : the same for a continuation's intermediate points (they need only
        be on the branch, at the path accuracy: a floor of 8 made the paper's case 1 a
        quarter slower for nothing)
    max_steps, min_step : continuation budget of one homotopy (steps, smallest step in t)
    contraction : the factor by which each corrector iteration must shrink the residual
    loose_tolerance : convergence of intermediate points, relative to the homotopy's size
    grow : the distance between a step's prediction and its corrected point that the
        continuation aims at (each unknown relative to its size)
    shrink : the step-size factor after a rejected continuation step
    wave_step : the most a step may raise the wavenumber of the loads and of the
        solution (buckling modes appear about pi apart in it)
    time_budget : wall-clock seconds before a solve gives up
    bow : the chord shortening of the imperfection that leaves a singular start, as a
        fraction of the shortening the targets ask for; bow_min, bow_max bound its
        curvature amplitude (dimensionless)
    shared_driver : run each continuation in Python through the shared driver
        (``pliant.models.continuation.follow``) instead of its compiled twin
        (``kernels.follow``, the same steps; both follow the sign of det J): some ten
        times slower; for checking one against the other
    node_limit : the wavenumber sqrt(max|n| L^2 / EI) times the longest shooting
        interval (dimensionless) past which a continuation stops and follows again with
        more intervals (a part pulled into a hairpin: its forces grow along the path,
        and one long interval's Newton basin shrinks like exp(-k s), so the steps would
        creep on by thousands); half as much again as NODE_SPAN, the bound the answers'
        own intervals keep (a path that ends a little past it finishes, and its answer is
        re-lowered after)
    lowest : in a cold solve with positions held at two stations or more, also minimise
        the energy from a few starting shapes and answer with the stable equilibrium of
        lowest energy found (at most a few ms more; none where the route bowed the part
        to both sides and took a stable one); False answers with the route's (as fast
        as the shooting, but it may be a higher or unstable branch)
    """

    tolerance: float = 1e-10
    max_iterations: int = 25
    accuracy: float = 0.5
    path_accuracy: float = 1.5
    min_density: int = 8
    path_min_density: int = 4
    samples: int = 64
    max_steps: int = 2000
    min_step: float = 1e-7
    contraction: float = 0.5
    loose_tolerance: float = 1e-6
    grow: float = 0.1
    wave_step: float = 1.0
    shrink: float = 0.25
    time_budget: float = 30.0
    bow: float = 0.8
    bow_min: float = 0.01
    bow_max: float = 40.0
    node_limit: float = 1.5 * NODE_SPAN
    lowest: bool = True
    shared_driver: bool = False

    def __post_init__(self) -> None:
        check(self, fractions=("contraction", "shrink"))

    @cached_property
    def options(self) -> np.ndarray:
        """The settings ``kernels.follow`` reads (its OPT_* indices), made once."""
        return np.array([self.tolerance, max(self.tolerance, self.loose_tolerance),
                         self.contraction, self.min_step, self.max_steps,
                         self.max_iterations, self.accuracy, self.min_density, self.grow,
                         self.shrink, self.path_accuracy, self.wave_step,
                         self.node_limit, self.path_min_density], dtype=float)

    @cached_property
    def fixed_options(self) -> np.ndarray:
        """``options`` for a path that may not ask for more shooting intervals."""
        opts = self.options.copy()
        opts[kernels.OPT_NODE_LIMIT] = 0.0
        return opts

    @cached_property
    def _leg_options(self) -> tuple[np.ndarray, np.ndarray]:
        """``options`` and ``fixed_options`` for a leg another leg starts from: its end
        meshed for the path's accuracy, not the answer's."""
        out = []
        for opts in (self.options, self.fixed_options):
            leg = opts.copy()
            leg[kernels.OPT_ACCURACY] = self.path_accuracy
            leg[kernels.OPT_MIN_DENSITY] = self.path_min_density
            out.append(leg)
        return out[0], out[1]

    def options_for(self, final: bool, more: bool) -> np.ndarray:
        """The options of a path: to an answer (``final``) or to another leg's start;
        that may ask for more shooting intervals (``more``) or not."""
        if final:
            return self.options if more else self.fixed_options
        return self._leg_options[0 if more else 1]


_DEFAULT = ShootingSolver()  # immutable: one instance (its checks cost microseconds)


@dataclass(slots=True, eq=False)
class _WarmState:
    """What a later solve needs to start from this one."""

    low: Lowered
    z: np.ndarray
    jac: np.ndarray
    mesh: Mesh
    # The distance travelled through the problems' inputs since this structure's first
    # (a cold solve's): the parameter a path's steps extrapolate in.
    travel: float = 0.0
    # The last four answers' unknowns on the way here, and the last four Jacobians shot
    # afresh, as ``_Memory``: a path's next step starts from their extrapolations.
    path: _Memory | None = None
    shot: _Memory | None = None
    refresh: bool = False  # the next step shoots its Jacobian afresh


@dataclass
class _Point:
    """A converged point of a route: unknowns, Jacobian, mesh, wavenumber statistics."""

    z: np.ndarray
    jac: np.ndarray
    mesh: Mesh
    stats: np.ndarray
    residual: float


_EMPTY_JAC = np.zeros((0, 0))
_BRANCH_NOTE = "the unloaded part was a singular start"
JUDGE_ELEMENTS = 60  # the grid on which the two bow sides' stability is compared
_REASONS = {
    kernels.SINGULAR: "the Jacobian became singular (a fold or bifurcation: the branch "
                      "ends or turns back here)",
    kernels.NOT_FINITE: "the shape blew up",
    kernels.MAX_ITERATIONS: "Newton ran out of iterations",
}
_STATUS = {kernels.SINGULAR: Status.SINGULAR, kernels.NOT_FINITE: Status.NOT_FINITE}


@dataclass
class Run:
    low: Lowered
    solver: ShootingSolver
    iterations: int = 0
    steps: int = 0
    notes: list[str] = field(default_factory=list)
    deadline: float = 0.0
    reached: list = field(default_factory=list)  # every point the last route reached
    sampled: dict = field(default_factory=dict)  # id(point): (point, low, equilibrium)
    verdicts: dict = field(default_factory=dict)  # id(point): (point, low, ``stable``)
    lowered: dict = field(default_factory=dict)  # restart nodes asked: (problem, lowering)
    needed: int = 0  # the most shooting intervals a path's forces asked for
    crossings: int = 0  # genuine sign changes of det J on the shared driver's paths
    creeping: int = 0  # short steps on the shared driver's path (``stepped``)
    travel: float = 0.0  # the answer's ``_WarmState.travel``
    path: _Memory | None = None  # the warm start's (``_WarmState.path``)
    shot: _Memory | None = None  # the warm start's (``_WarmState.shot``)
    reused: bool = False  # whether the answer came with an extrapolated Jacobian
    refresh: bool = True  # whether the next warm step should shoot one afresh
    # Bowed equilibria whose bow could not be removed: ((bow, structure), z, the stall)
    unbowed: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.deadline = clock.now() + self.solver.time_budget

    def lowering(self, problem: Problem, nodes: int | None = None) -> Lowered:
        """``lower(problem, nodes=nodes)``, each once a solve (the routes and the energy
        minima's starts ask for the same few)."""
        seen = self.lowered.get(nodes)
        if seen is None or seen[0] is not problem:
            seen = self.lowered[nodes] = (problem, lower(problem, nodes=nodes))
        return seen[1]

    def newton(self, z0: np.ndarray, arrays: Arrays, mesh: Mesh, *, strict: bool,
               tol: float, jac0: np.ndarray = _EMPTY_JAC, iterations: int = 0):
        """``kernels.newton`` from z0 (at most ``iterations`` iterations where given)."""
        opts = self.solver
        z, r, it, status, jac, stats, _ = kernels.newton(  # type: ignore[call-arg]
            z0, jac0, *self.low.args(arrays, mesh), tol,
            iterations or opts.max_iterations, opts.contraction if strict else 0.0)
        self.iterations += it
        return z, r, status, jac, stats

    def need(self, stats: np.ndarray) -> int:
        """Steps per unit length the solution with these statistics needs."""
        return int(kernels.needed_density(stats, self.solver.accuracy,
                                          self.solver.min_density))

    def renoded(self, route: Callable[[], _Point]) -> _Point:
        """route() on the present lowering, and again from the start on one with more
        shooting intervals each time its path's forces outgrow them (a ``Stalled`` with
        ``intervals``): what the abandoned try said is dropped."""
        while True:
            said = len(self.notes)
            try:
                return route()
            except Stalled as stall:
                if not stall.intervals:
                    raise
                del self.notes[said:]
                self.needed = max(self.needed, stall.intervals)
                self.low = self.lowering(self.low.problem, stall.intervals)

    def follow(self, start: Arrays, end: Arrays, z0: np.ndarray, mesh: Mesh,
               final: bool = True) -> _Point:
        """Continuation from (start, z0), an exact solution, to end (see
        ``kernels.follow``); a ``Stalled`` with ``intervals`` where the path's forces
        outgrow the shooting intervals (``ShootingSolver.node_limit``). The end point
        is converged fully, on a mesh of the answer's accuracy where it is ``final``, of
        the path's where another leg starts from it (a bowed part's leg before its bow
        is removed: a hairpin's end refined to 723 steps a length made its next leg cost
        1.3 s, where the path's accuracy asks for 220)."""
        opts, low = self.solver, self.low
        if opts.shared_driver:
            return self.follow_shared(start, end, z0, mesh, final)
        if clock.now() > self.deadline:
            raise Stalled(0.0, math.inf, f"the time budget of {opts.time_budget} s ran out",
                          budget=True, state=z0, status=Status.TIME_BUDGET)
        more = len(low.nodes) + 1 < MOST_INTERVALS
        # The kernel reads the thread's CPU time; the solvers' clock leaves out compiling.
        deadline = time.thread_time() + (self.deadline - clock.now())
        z, jac, density, stats, r, status, last, t, iterations, steps, crossings = kernels.follow(
            z0, mesh.density, low.stations, start.inputs, end.inputs,
            opts.options_for(final, more), low.interval, deadline)
        self.iterations += iterations
        self.steps += steps
        if last == kernels.NEEDS_NODES:
            raise self._outgrown(stats, t, z)
        if last == kernels.OUT_OF_TIME:
            raise Stalled(t, r, f"the time budget of {opts.time_budget} s ran out",
                          budget=True, state=z, status=Status.TIME_BUDGET)
        if status == kernels.BUDGET:
            raise Stalled(t, r, f"the continuation budget of {opts.max_steps} steps "
                          "ran out", budget=True, state=z, status=Status.STEP_BUDGET)
        if status != kernels.CONVERGED:
            raise Stalled(t, r, _REASONS.get(
                last, "Newton stopped contracting however short the step (a fold: the "
                "branch ends or turns back here)"), state=z,
                singular_start=last == kernels.SINGULAR and steps == 0 and t == 0.0,
                status=_STATUS.get(last, Status.FOLD))
        if crossings:
            self.notes.append(_crossed_note())
        return _Point(z, jac, low.mesh(density), stats, r)

    # -- the shared driver (continuation.Continuable) ------------------------------------
    def follow_shared(self, start: Arrays, end: Arrays, z0: np.ndarray,
                      mesh: Mesh, final: bool = True) -> _Point:
        """``follow`` by the shared driver (``continuation.follow``): its steps are the
        compiled ``kernels.follow``'s (the parabola's predictor, a fresh Jacobian in each
        corrector, the sign of det J followed: ``det_sign``, the creeping paths' rule:
        ``stepped``); the mesh is refined as the path's solution needs (``correct``),
        and at the end to the full accuracy where the end is ``final``."""
        opts = self.solver
        span = max(float(np.abs(end.val - start.val).max(initial=0.0)),
                   float(np.abs(end.fol - start.fol).max(initial=0.0)),
                   float(np.abs(end.dist - start.dist).max(initial=0.0)),
                   float(np.abs(end.prm[:3] - start.prm[:3]).max()))
        loose = max(opts.tolerance, opts.loose_tolerance * span)
        stepping = continuation.Stepping(
            tolerance=opts.tolerance, loose=loose, min_step=opts.min_step,
            loose_at=partial(kernels.loose_at, span=span, tol=opts.tolerance,
                             loose=max(opts.tolerance, opts.loose_tolerance)),
            max_steps=opts.max_steps, grow=opts.grow, shrink=opts.shrink,
            wave_step=opts.wave_step, time_budget=opts.time_budget,
            parabola=bool(kernels.parabola_fits(loose, opts.grow)),
            last_stretch=kernels.LAST_STRETCH, refused_fade=kernels.REFUSED_FADE)
        crossings, self.creeping = self.crossings, 0
        try:
            point = continuation.follow(self, Line(start, end),
                                        _Point(z0, _EMPTY_JAC, mesh, np.zeros(2), math.inf),
                                        stepping, self.deadline)
        except Stalled as stall:
            if isinstance(stall.state, _Point):
                stall.state = stall.state.z
            raise
        if self.crossings > crossings:
            self.notes.append(_crossed_note())
        # The end point on a mesh of the full accuracy (a leg's, of the path's: correct)
        return self.polish(point) if final else point

    def correct(self, predictor: _Point, loads: Arrays, *, strict: bool,
                tol: float | None) -> tuple[_Point, float, Status]:
        """Newton from the prediction, with a fresh Jacobian there (as ``kernels.follow``);
        a converged point whose wavenumber outgrew the mesh (at the path's accuracy)
        converges again on a finer one."""
        tol = self.solver.tolerance if tol is None else tol
        mesh = predictor.mesh
        z, r, status, jac, stats = self.newton(predictor.z, loads, mesh, strict=strict,
                                               tol=tol)
        need = int(kernels.needed_density(stats, self.solver.path_accuracy,
                                           self.solver.path_min_density))
        if status == kernels.CONVERGED and need > mesh.density:
            mesh = self.low.mesh(int(math.ceil(1.1 * need)))
            z, r, status, jac, stats = self.newton(z, loads, mesh, strict=False, tol=tol)
        word = Status.CONVERGED if status == kernels.CONVERGED else _STATUS.get(
            status, Status.FOLD)
        return _Point(z, jac, mesh, stats, r), r, word

    def det_sign(self, point: _Point, loads: Arrays, fresh: bool) -> float:
        """The sign of det J at a converged point: its corrector's Jacobian, or a fresh
        one (``continuation.Continuable``)."""
        jac = point.jac
        if fresh or jac.shape[0] != point.z.shape[0]:
            _, jac = self.low.shoot(point.z, loads, point.mesh)
        return float(kernels.det_sign(jac))

    def crossed(self) -> None:
        """A genuine crossing of det J's sign on a path (``continuation.follow``)."""
        self.crossings += 1

    def stepped(self, dt: float) -> None:
        """A step of length dt taken on a path (``continuation.follow``): the short ones
        counted, as ``kernels.follow`` counts them (``kernels.CREEP``)."""
        if dt < kernels.CREEP:
            self.creeping += 1

    def tangent(self, state: _Point, path: Line) -> np.ndarray | None:
        """dz/dt = -J^-1 dG/dt at the start, dG/dt by a forward difference."""
        eps = 1e-7
        res, jac, _ = kernels.shoot(  # type: ignore[call-arg]
            state.z, *self.low.args(path.at(eps), state.mesh), True,
            np.zeros((0, kernels.NSTATE)))
        dz, ok = kernels.lu_solve(jac, -res / eps)
        return dz if ok else None

    def step(self, state: _Point, du: np.ndarray, scale: float) -> _Point:
        return replace(state, z=state.z + scale * du)

    def difference(self, a: _Point, b: _Point) -> np.ndarray:
        return b.z - a.z

    def miss(self, predicted: _Point, corrected: _Point) -> float:
        z = corrected.z
        return float(np.max(np.abs(z - predicted.z) / np.maximum(1.0, np.abs(z)),
                            initial=0.0))

    def load_size(self, path: Line) -> tuple[float, float]:
        """(F, C), the change of the applied forces and moments on the path (as
        ``kernels.follow`` measures them, distributed loads by their totals; a bow's
        removal is none)."""
        low, a, b = self.low, path.start, path.end
        applied = low.st_kind == APPLIED
        dv = np.abs(b.val - a.val)
        force = (float(dv[:, :2][applied[:, :2]].sum()) + float(np.abs(b.fol - a.fol).sum())
                 + math.hypot(b.prm[0] - a.prm[0], b.prm[1] - a.prm[1])
                 + float((np.abs(b.dist - a.dist).sum(axis=1)[:-1] * np.diff(low.st_s)).sum()))
        moment = float(dv[:, 2][applied[:, 2]].sum())
        return force, moment

    def begin_step(self, state: _Point) -> _Point:
        """Where the last point's forces outgrew the shooting intervals, stop (as
        ``kernels.follow`` does after it accepts such a point), and sooner on a path
        that creeps (more than ``kernels.CREEP_STEPS`` short steps: ``stepped``)."""
        low = self.low
        span = math.sqrt(float(state.stats[1])) * low.interval
        limit = self.solver.node_limit
        if len(low.nodes) + 1 < MOST_INTERVALS and (span > limit or (
                self.creeping > kernels.CREEP_STEPS and span > kernels.CREEP_SPAN * limit)):
            raise self._outgrown(state.stats, math.nan, state.z)
        return state

    def _outgrown(self, stats: np.ndarray, t: float, z: np.ndarray) -> Stalled:
        """The stall of a path whose forces (``stats``) outgrew the shooting intervals,
        asking for enough that they may grow fourfold more (k s at NODE_SPAN / 2), and at
        least twice as many."""
        count = len(self.low.nodes) + 1
        more = min(MOST_INTERVALS, max(2 * count, math.ceil(
            2.0 * math.sqrt(float(stats[1])) / NODE_SPAN)))
        return Stalled(t, math.inf, f"its forces outgrew the {count} shooting intervals; "
                       f"follow again with {more}", state=z, intervals=more)

    def memo(self) -> None:
        return None

    # -- routes ---------------------------------------------------------------------------
    def cold(self) -> _Point:
        """Try the routes in turn (``continuation.first_route``), the shooting's
        intervals shortened once where the straight route stalls; where all meet a
        fold, the energy's minima, else beyond the fold; else the furthest stall."""
        problem = self.low.problem
        nodes = len(self.low.nodes) + 1

        tried: set[tuple[int, str]] = set()

        def attempt(count: int, legs: Callable[[Arrays], list[Arrays]]) -> _Point:
            # No fewer intervals than an earlier route's forces asked for, and no route
            # twice on the same intervals (a route re-lowered on its way has been tried
            # on the intervals it ended on: the straight route on four times as many
            # repeated it step for step, two bowed paths of 100 ms on a part held behind
            # its clamp).
            count = max(count, self.needed)
            if (count, legs.__name__) in tried:
                raise Stalled(0.0, math.inf, "tried already", status=Status.NO_ROUTE)
            tried.add((count, legs.__name__))
            if count != len(self.low.nodes) + 1:
                self.low = self.lowering(problem, count)
            try:
                return self.lowest(self.renoded(partial(self.route, legs)))
            finally:
                tried.add((len(self.low.nodes) + 1, legs.__name__))

        finer = [(min(4 * nodes, MAX_INTERVALS), self.straight)]
        others = [(nodes, self.two_stage), (nodes, self.swing), (nodes, self.loads_first)]
        # A heavy part's intervals, four times over, make each step cost a hundred times
        # one of the other routes' (a cable held at q L^3 / EI = 6e5 on 384 intervals: 95
        # s to a fold at the very end, where the two-stage route on 96 answered in 3 s):
        # there the finer straight route comes last.
        heavy = 4 * nodes > MOST_INTERVALS
        attempts = [(nodes, self.straight)] + (others + finer if heavy else finer + others)
        try:
            return first_route([partial(attempt, c, legs) for c, legs in attempts],
                               self.notes, self.deadline)
        except Stalled as stall:
            best = stall
        if clock.now() < self.deadline:  # a route's step budget is not the solve's
            point = self.minimised(best)
            if point is not None:
                return point
        if best.budget:
            raise best
        if clock.now() < self.deadline:
            point = self.staged(best)
            if point is not None:
                return point
        return self.beyond_fold(best)

    def route(self, legs: Callable[[Arrays], list[Arrays]]) -> _Point:
        """Follow the legs from the rest state to the problem.

        When the rest state is singular (an end pushed along the straight part: an
        inextensible part cannot shorten its chord to first order, so it may buckle to
        either side), the whole route runs on a bowed part, bowed toward the side the
        targets moved to, and a last leg removes the bow at the problem.
        """
        low = self.low
        mesh = self.first_mesh(path=True)
        rest, z = low.rest(mesh)
        straight = None
        before = len(self.notes)
        try:
            point = self.through(rest, legs(rest), z, mesh)
            # An extensible part's start is not singular: its chord shortens by
            # compression, and the route stays on the straight branch past buckling.
            if low.target.prm[5] == 0.0 or low.target.follower or self.stable(point):
                self.reached = [point]
                return point
            straight = point
        except Stalled as stall:
            if not stall.singular_start:
                raise
        # What the straight route said (a bifurcation it crossed) is of its own answer.
        said, self.notes[before:] = self.notes[before:], []
        why = _BRANCH_NOTE if straight is None else (
            f"{_BRANCH_NOTE} for the inextensible part; this one shortens, and its straight "
            "equilibrium is unstable")
        pushed = low.lateral_side(rest)
        mirrored = False
        # The side the targets and loads push to first; where its path meets a fold (a
        # part held below and on from its clamp, whose bow would have to turn over), the
        # other.
        found: list[tuple[float, _Point]] = []
        stalls: list[Stalled] = []
        for bow in (pushed, -pushed):
            try:
                found.append((bow, self.bowed(bow, legs, mesh, rest)))
                break
            except Stalled as stall:
                if stall.budget or stall.intervals:
                    raise
                stalls.append(stall)
        if not found:
            if straight is None:
                raise max(stalls, key=lambda stall: stall.t)
            self.notes.extend(said)
            self.reached = [straight]
            return straight
        fold = (f"; the path bowing to the other side, the one its targets and loads push "
                f"it to, met a fold at {stalls[0].t:.3g} of the way" if stalls else "")
        if low.target.follower:  # no potential to compare the sides by
            side = "left" if found[0][0] > 0 else "right"
            self.notes.append(BranchTaken(
                f"{why} (a bifurcation: it can buckle to either side); pliant took "
                f"the branch that bows to the {side} of its chord"
                + (fold or ", the side its targets and loads push it to; another "
                   "equilibrium may exist on the other side"), side=side))
            self.reached = [found[0][1]]
            return found[0][1]
        if not stalls:  # the other side too: keep the lower stable one, say what else exists
            # Where the problem is its own mirror image, the other side's equilibrium is
            # this one's, mirrored (``_mirror``), converged by Newton, not a path of its own.
            twin = self.mirrored(found[0][1])
            mirrored = twin is not None
            try:
                found.append((-pushed, twin if twin is not None
                              else self.bowed(-pushed, legs, mesh, rest)))
            except Stalled as stall:
                if stall.budget or stall.intervals:
                    raise
        if (len(found) == 2 and not mirrored and found[0][1].z.shape == found[1][1].z.shape
                and _one_point(found[0][1].z, found[1][1].z)):
            found.pop()  # both sides' paths reached one equilibrium (a loop's, say)
            fold = "; the path bowing to the other side reached the same equilibrium"
        energies = [self.energy(found[0][1])]
        if len(found) == 2:  # (a mirror twin's is the other's: the mirror keeps the
            # bending energy, and nothing else acts)
            energies.append(energies[0] if mirrored else self.energy(found[1][1]))
        twins = len(found) == 2 and abs(energies[1] - energies[0]) <= 1e-9 * abs(energies[0])
        judged = [(side, point, energy, self.stable(point) if len(found) == 2 and not twins
                   else None) for (side, point), energy in zip(found, energies)]
        # The side the targets push to, unless the other is better (stable or neutral
        # first, then the lower energy: ``continuation.ranked``).
        best = ranked([Candidate(j[3], j[2], j) for j in judged], self.scale)[0].item
        word = {True: "stable", False: "unstable", None: "stability undecided"}
        took = (f"{why} (a bifurcation: it can buckle to either side); pliant took "
                f"the branch that bows to the {'left' if best[0] > 0 else 'right'} of its "
                f"chord (potential energy {best[2]:.6g} J, {word[best[3]]})")
        side = "left" if best[0] > 0 else "right"
        if len(judged) == 1:
            self.notes.append(BranchTaken(
                took + (fold or "; the route to the other side found no equilibrium"),
                side=side, energy=best[2]))
            self.reached = [best[1]]
            return best[1]
        other = next(j for j in judged if j is not best)
        if twins:
            took = took.replace(", stability undecided)", ")")
            took += "; its mirror twin bows to the other side with the same energy"
        else:
            took += (f"; the other side's equilibrium has {other[2]:.6g} J and is "
                     f"{word[other[3]]}")
        self.notes.append(BranchTaken(took, side=side, energy=best[2], other_energy=other[2],
                                      twin=twins))
        self.reached = [best[1]] + [j[1] for j in judged if j is not best]
        return best[1]

    def mirrored(self, point: _Point) -> _Point | None:
        """The point's mirror twin (``_mirror``), converged on this lowering, where the
        problem maps onto itself; None where it does not, or Newton does not converge."""
        mirror = _mirror(self.low.problem)
        if mirror is None:
            return None
        z0 = mirror.unknowns(self.low, point.z)
        if z0 is None:  # restart nodes: their states read from the samples, mirrored
            z0 = self.low.unknowns_from(mirror(self._equilibrium(point)))
        # Often exact already (straight from z's where there are no restart nodes: case
        # 3's twin is off by 5e-11): then one shoot without the Jacobian shows it, and
        # the twin keeps none (a warm start from it makes its own).
        res, _ = self.low.shoot(z0, self.low.target, point.mesh, want_jac=False)
        r = float(np.abs(res).max())
        if r <= self.solver.tolerance and not _one_point(z0, point.z):
            return _Point(z0, _EMPTY_JAC, point.mesh, point.stats, r)
        z, r, status, jac, stats = self.newton(z0, self.low.target, point.mesh,
                                               strict=False, tol=self.solver.tolerance)
        if status != kernels.CONVERGED or _one_point(z, point.z):
            return None  # (its own mirror image: a loop's, say; the other side is followed)
        try:
            return self.polish(_Point(z, jac, point.mesh, stats, r))
        except Stalled:
            return None

    def bowed(self, side: float, legs: Callable[[Arrays], list[Arrays]],
              mesh: Mesh, rest: Arrays) -> _Point:
        """The route on a part bowed to ``side`` (+1 left of its chord, -1 right), with a
        last leg that removes the bow at the problem; rest: the unbowed rest state's
        arrays on the mesh."""
        low, opts = self.low, self.solver
        ends = low.chord()
        span = (0.0, 1.0)
        if ends is not None:
            span = (float(low.st_s[ends[0]]), float(low.st_s[ends[1]]))
        width = span[1] - span[0]
        # A bow b cos(2 pi u) over a span w shortens its chord by w (b w)^2 / 16 pi^2.
        # Making that most of what the targets ask lets the bowed part reach them under a
        # small axial force (a nearly straight inextensible part is so stiff axially that
        # the force would rise almost vertically along the path); removing the bow at the
        # targets then raises the force smoothly, on the branch that bows to that side.
        wanted = opts.bow * low.shortening(rest)
        amplitude = 4.0 * math.pi / width * math.sqrt(wanted / width)
        bow = side * min(opts.bow_max, max(opts.bow_min, amplitude))
        rest, z = low.rest(mesh, bow, span)
        bowed = [leg.with_bow(bow, span) for leg in legs(rest)]
        point = self.through(rest, bowed, z, mesh, final=False)
        # Removing the bow is the same path from the same bowed equilibrium whatever
        # route reached it: where it met a fold once, it meets it again (a part held
        # behind its clamp: the straight and two-stage routes reached one bowed
        # equilibrium, and each spent 60-100 ms creeping to the same fold).
        seen = (bow, low.key)
        for key, z_seen, stall in self.unbowed:
            if key == seen and np.abs(point.z - z_seen).max() <= 1e-6 * (
                    1.0 + np.abs(z_seen).max()):
                raise copy.copy(stall)
        try:
            return self.follow(bowed[-1], low.target, point.z, point.mesh)
        except Stalled as stall:
            if not stall.budget and not stall.intervals:
                self.unbowed.append((seen, point.z, copy.copy(stall)))
            raise

    def _once(self, store: dict, point: _Point, make: Callable[[], Any]) -> Any:
        """``make()`` for a point on the present lowering, made once: ``store`` keeps
        id(point): (point, lowering, value)."""
        seen = store.get(id(point))
        if seen is not None and seen[0] is point and seen[1] is self.low:
            return seen[2]
        value = make()
        store[id(point)] = (point, self.low, value)
        return value

    def _equilibrium(self, point: _Point) -> Equilibrium:
        """The point as an equilibrium (sampled once: its energy, stability and shape
        are each asked for while the routes' answers are compared)."""
        return self._once(self.sampled, point, lambda: Equilibrium(
            problem=self.low.problem, residual=point.residual, iterations=0, steps=0,
            sampler=_Sampler(self.low, point.z, max(point.mesh.density,
                                                    self.solver.samples))))

    def energy(self, point: _Point) -> float:
        """The potential energy [J] of a point reached (elastic, weight, dead loads)."""
        return potential_energy(self._equilibrium(point))

    def stable(self, point: _Point) -> bool | None:
        """Whether a point reached is stable, on a coarse grid (the sign is what counts;
        the answer's own verdict is computed finely when asked for). Judged once."""
        return self._once(self.verdicts, point, lambda: stable_sign(
            self._equilibrium(point), JUDGE_ELEMENTS))

    def through(self, start: Arrays, targets: list[Arrays], z: np.ndarray,
                mesh: Mesh, final: bool = True) -> _Point:
        """Follow the homotopies start -> targets[0] -> targets[1] -> ...; each leg's end
        meshed for the path's accuracy but the last's (``follow``'s ``final``)."""
        point = None
        for i, end in enumerate(targets):
            point = self.follow(start, end, z, mesh if point is None else point.mesh,
                                final=final and i == len(targets) - 1)
            start, z = end, point.z
        assert point is not None
        return point

    def straight(self, rest: Arrays) -> list[Arrays]:
        """Loads and positions together, along straight lines."""
        return [self.low.target]

    def two_stage(self, rest: Arrays) -> list[Arrays]:
        """Positions first, with no load; then the loads."""
        low = self.low
        placed = Arrays(np.where(low.st_kind == PRESCRIBED, low.target.val, 0.0),
                        np.zeros_like(low.target.fol), rest.prm,
                        np.zeros_like(low.target.dist))
        return [placed, low.target]

    def loads_first(self, rest: Arrays) -> list[Arrays]:
        """Loads first, with the held components where the rest shape has them; then
        the targets (as in 3D)."""
        low = self.low
        prm = rest.prm.copy()
        prm[:2] = low.target.prm[:2]
        loaded = Arrays(np.where(low.st_kind == PRESCRIBED, rest.val, low.target.val),
                        low.target.fol, prm, low.target.dist)
        return [loaded, low.target]

    def swing(self, rest: Arrays, legs: int = 8) -> list[Arrays]:
        """Carry the held points round the first one along arcs (their distance and
        bearing from it move linearly), as a hand would, instead of along straight
        lines that may sweep through the first support; loads grow linearly."""
        low = self.low
        ends = low.chord()
        if ends is None:
            raise Stalled(0.0, math.inf, "nothing to swing around", state=np.zeros(low.nz),
                          status=Status.NO_ROUTE)
        pivot = ends[0]
        located = np.nonzero((low.st_kind[:, 0] == PRESCRIBED)
                             & (low.st_kind[:, 1] == PRESCRIBED))[0]

        def at(t: float) -> Arrays:
            arrays = rest.lerp(low.target, t)
            val = arrays.val.copy()
            for k in located:
                if k == pivot:
                    continue
                a = rest.val[k, :2] - rest.val[pivot, :2]
                b = low.target.val[k, :2] - low.target.val[pivot, :2]
                turn = math.remainder(math.atan2(b[1], b[0]) - math.atan2(a[1], a[0]),
                                      2.0 * math.pi)
                radius = (1 - t) * math.hypot(*a) + t * math.hypot(*b)
                bearing = math.atan2(a[1], a[0]) + t * turn
                val[k, :2] = val[pivot, :2] + radius * np.array([math.cos(bearing),
                                                                math.sin(bearing)])
            return Arrays(val, arrays.fol, arrays.prm, arrays.dist)

        return [at(i / legs) for i in range(1, legs + 1)]

    def minima(self, reached: Iterable[_Point] = ()) -> list[tuple[Lowered, _Point]]:
        """The equilibria the discretised part's energy minima lead to
        (``minimum.minima``), each converged by a damped Newton of the shooting, with
        more restart nodes where the intervals are too long for its forces; each with
        the lowering its unknowns belong to. A minimum within ``MATCHED`` of a point
        ``reached`` on the present lowering is that point's equilibrium: left out, not
        converged again."""
        problem = self.low.problem
        if not minimum.applicable(problem):
            return []
        route_low, reached = self.low, list(reached)
        own = self.lowering(problem)
        loads = len(own.nodes) + 1

        def converged(start, summary: np.ndarray) -> tuple[Lowered, _Point] | None:
            # The start's own wavenumber, not only the loads': a target that makes the
            # part turn back sharply at a clamp is held by internal forces of thousands
            # of EI / L^2 the loads do not show. Its force sets the shooting intervals (as
            # for answers, ``_intervals``), all of it the mesh: a start for Newton, meshed
            # at half the path's accuracy (the answer is meshed for its own by ``polish``;
            # ``summary``: the start's ``_statistics``)
            base = _intervals(math.sqrt(summary[1]), own) or loads
            need = int(kernels.needed_density(summary, 2.0 * self.solver.path_accuracy,
                                              self.solver.min_density))
            # (more where the start's forces were underestimated; past 16 times the loads'
            # intervals not beyond 64, nor ever beyond MAX_INTERVALS: each Newton
            # iteration shoots a dense Jacobian of six unknowns an interval)
            most = min(MAX_INTERVALS, max(16 * loads, MOST_INTERVALS))
            for count in [c for c in (base, 4 * base, 16 * base) if c <= most]:
                if clock.now() > self.deadline:
                    return None
                self.low = low = self.lowering(problem, count)
                mesh = self.first_mesh()
                if need > mesh.density:
                    mesh = low.mesh(need)
                z, r, status, jac, stats = self.newton(
                    low.unknowns_from(start), low.target, mesh, strict=False,
                    tol=self.solver.tolerance)
                if status == kernels.CONVERGED:
                    try:
                        return low, self.polish(_Point(z, jac, mesh, stats, r))
                    except Stalled:
                        pass
            return None

        def matched(start) -> bool:
            for point in reached:
                eq = self._sampled(route_low, point)
                if np.abs(start.angle - np.interp(start.s, eq.s, eq.angle)).max() < MATCHED:
                    return True
            return False

        # The SQP stops next to the route's answer (``minimum.minima``'s ``known``; sampled
        # for its energy already, where the others are sampled only if a minimum needs).
        known = [self._sampled(route_low, reached[0])] if reached else []
        out: list[tuple[Lowered, _Point]] = []
        for start in minimum.minima(problem, deadline=self.deadline, known=known):
            if matched(start):
                continue
            # A start whose force's wavenumber k outgrows its elements (k h past
            # UNRESOLVED) cannot hold the part's boundary layers (1 / k wide): its finer
            # refinement is tried, not it.
            summary = _statistics(start)
            resolved = math.sqrt(float(summary[1])) * start.disc.h <= UNRESOLVED
            found = converged(start, summary) if resolved else None
            if found is None and clock.now() < self.deadline:
                finer = minimum.refined(start)
                found = converged(finer, _statistics(finer)) if finer is not None else None
            if found is not None:
                out.append(found)
        return out

    def _distinct(self, candidates: list[tuple[Lowered, _Point]]
                  ) -> list[tuple[Lowered, _Point]]:
        """The candidates, each equilibrium once (the first found of those that are one).
        Two on one structure are one where their unknowns are (``_one_point``), else
        compared by their shapes (``_same``, which samples them)."""
        out: list[tuple[Lowered, _Point]] = []
        for low, point in candidates:
            if any(o_low.key == low.key and _one_point(point.z, o_point.z)
                   for o_low, o_point in out):
                continue
            others = [(o_low, o_point) for o_low, o_point in out if o_low.key != low.key]
            if others and any(_same(self._sampled(low, point), self._sampled(*other))
                              for other in others):
                continue
            out.append((low, point))
        return out

    def _sampled(self, low: Lowered, point: _Point) -> Equilibrium:
        """``_equilibrium`` of a point on its own lowering (sampled once: cached)."""
        self.low = low
        return self._equilibrium(point)

    def _judged(self, candidates: list[tuple[Lowered, _Point]]) -> list[tuple]:
        """Distinct candidates (``_distinct``) as (unstable, energy, low, point), the best
        first (``continuation.ranked``: stable or neutral before unstable, then the lower
        potential energy; a tie, mirror twins to 1e-9, keeps the earlier first)."""
        judged: list[Candidate] = []
        for low, point in self._distinct(candidates):
            self.low = low
            stable = self.stable(point)
            energy = self.energy(point)
            judged.append(Candidate(stable, energy, (stable is False, energy, low, point)))
        return [c.item for c in ranked(judged, self.scale)]

    @property
    def scale(self) -> float:
        """The part's EI / L [J]: the energy below which two levels are one."""
        part = self.low.problem.part
        return part.bending_stiffness / part.length

    @staticmethod
    def _listed(judged: list[tuple]) -> str:
        return ", ".join(f"{e:.6g} J ({'unstable' if u else 'stable'})"
                         for u, e, *_ in judged)

    def lowest(self, point: _Point) -> _Point:
        """The route's answer, unless a minimum of the energy (``minima``) is a lower
        stable equilibrium (or the route's is unstable): a cold solve in configuration
        space (positions held at two stations or more) answers with where the part is
        likeliest to settle, and names the others. In force space (one held station) the
        route's answer is the branch the loads lead to from the unloaded part."""
        problem = self.low.problem
        if (not self.solver.lowest or problem.held_stations < 2
                or not minimum.applicable(problem) or clock.now() > self.deadline):
            return point  # force space: the path from the unloaded part is the answer
        if len(self.reached) == 2 and self.stable(point):
            # The route bowed the part to both sides and took a stable one: the minima's
            # starts are those two sides' bows (``minimum.BOWS``). On 1,600 random targets
            # held at a singular start (three seeds; both sides found at 687 of them)
            # they never led to a lower equilibrium.
            return point
        low, notes, reached = self.low, list(self.notes), list(self.reached)
        distinct = self._distinct([(low, point)] + self.minima(reached))
        if len(distinct) == 1:  # the minima found the route's answer again: nothing to rank
            self.low, self.notes, self.reached = low, notes, reached
            return point
        judged = self._judged(distinct)
        best = judged[0]
        if best[3] is point:
            self.low, self.notes, self.reached = low, notes, reached
            if len(judged) > 1:
                self.notes.append(OthersFound(
                    "the other equilibria found by minimising the energy from a few "
                    "starting shapes: " + self._listed(judged[1:]),
                    energies=tuple(j[1] for j in judged[1:])))
            return point
        self.low = best[2]
        route = next(j for j in judged if j[3] is point)
        self.notes[:] = [n for n in notes if not isinstance(n, BranchTaken)]
        self.notes.append(LowestEquilibrium(
            f"pliant took the equilibrium where the part's energy is least "
            f"({'unstable' if best[0] else 'stable'}, potential energy {best[1]:.6g} J, found "
            f"by minimising it from a few starting shapes); the path from the "
            f"unloaded part leads to another: " + self._listed([route])
            + "".join(f"; also found: {self._listed([j])}" for j in judged[1:] if j is not route),
            energy=best[1], route_energy=route[1]))
        self.reached = [best[3]]
        return best[3]

    def minimised(self, stall: Stalled) -> _Point | None:
        """Every path met a fold: the lowest stable equilibrium among those the energy
        minima lead to (``minima``), or None. Say so, and what else was found."""
        judged = self._judged(self.minima())
        if not judged:
            return None
        unstable, energy, self.low, point = judged[0]
        note = (f"the paths from the unloaded part stopped at {stall.t:.3g} of the way "
                f"({stall.reason}); this equilibrium "
                f"({'unstable' if unstable else 'stable'}, potential energy {energy:.6g} J) "
                f"is where the part's energy is least, found by minimising it from a few "
                "starting shapes")
        if len(judged) > 1:
            note += "; the others found: " + self._listed(judged[1:])
        self.notes.append(LowestEquilibrium(note, energy=energy))
        self.reached = [point]
        return point

    def staged(self, stall: Stalled) -> _Point | None:
        """Every path met a fold on a heavily loaded part (load wavenumber k L past
        ``STAGED_WAVE``): the loads applied in stages instead, each a solve of its own
        (the first cold, each next warm from the last), the wavenumber thrice the last's
        from ``STAGED_WAVE / 3`` on. One path from the unloaded part to the whole load
        converges its early points relative to the whole load and on the mesh and
        intervals of the whole load: a cable clamped pointing up under q L^3 / EI =
        7.5e5 (k L 866), which first falls over and then hangs, left its branch at
        0.1 % of the way; in stages it hangs. None where the part is not so loaded, or
        a stage found no equilibrium (the route's stall then stands)."""
        problem = self.low.problem
        k = load_wavenumber(problem)
        if k <= STAGED_WAVE or not all(isinstance(ld, DistributedLoad | AddedMass)
                                       for ld in problem.loads):
            return None
        waves = [STAGED_WAVE / 3.0]
        while 3.0 * waves[-1] < k:
            waves.append(3.0 * waves[-1])
        factors = [(w / k) ** 2 for w in waves] + [1.0]
        eq = None
        try:
            for f in factors:
                left = self.deadline - clock.now()
                if left <= 0.0:
                    return None
                stage = problem if f == 1.0 else _loads_scaled(problem, f)
                eq = _solve(stage, eq, replace(self.solver, time_budget=left),
                            follow_only=eq is not None)
        except ConvergenceError:
            return None
        assert eq is not None and isinstance(eq.state, _WarmState)
        self.low, state = eq.state.low, eq.state
        z, r, status, jac, stats = self.newton(state.z, self.low.target, state.mesh,
                                               strict=False, tol=self.solver.tolerance)
        if status != kernels.CONVERGED:
            return None
        self.notes[:] = [n for n in eq.notes if not isinstance(n, WarmStartLost)]
        self.notes.append(LoadsStaged(
            f"every path from the unloaded part to the whole load met a fold (at "
            f"{stall.t:.3g} of the way): the loads were applied in {len(factors)} stages "
            f"({', '.join(f'{f:.3g}' for f in factors)} of them), each solved from the last",
            factors=tuple(factors), at=stall.t))
        return _Point(z, jac, state.mesh, stats, r)

    def beyond_fold(self, stall: Stalled) -> _Point:
        """Every path met a fold (the part would snap through): look for an equilibrium
        of the problem itself with a damped Newton, from the last state before the fold,
        then from the rest state. Say so: it lies beyond a snap, on another branch."""
        low = self.low = self.lowering(self.low.problem)
        mesh = self.first_mesh()
        _, z_rest = low.rest(mesh)
        starts = [stall.state] if (stall.state is not None
                                   and stall.state.shape[0] == low.nz) else []
        for z0 in starts + [z_rest]:
            z, r, status, jac, stats = self.newton(z0, low.target, mesh, strict=False,
                                                   tol=self.solver.tolerance)
            if status == kernels.CONVERGED:
                self.notes.append(BeyondFold(
                    f"the path from the unloaded part meets a fold at {stall.t:.3g} of the "
                    "way (the part would snap through); this equilibrium lies beyond it, "
                    "found by a damped Newton: check that it is the one you expect",
                    at=stall.t))
                return _Point(z, jac, mesh, stats, r)
        raise stall

    def first_mesh(self, path: bool = False) -> Mesh:
        """A mesh for the applied loads at the path accuracy: a continuation's first
        (``path``, on its own floor), or a Newton's toward an answer."""
        k = self.low.wave
        if k is None:
            k = load_wavenumber(self.low.problem)
        opts = self.solver
        floor = opts.path_min_density if path else opts.min_density
        return self.low.mesh(max(floor, int(math.ceil(k / opts.path_accuracy))))

    def warm(self, warm: Equilibrium, follow_only: bool, extrapolate: bool) -> _Point | None:
        """From the equilibrium warm (the last step's, where ``extrapolate``, of a path);
        None where nothing nearby converges and not ``follow_only``."""
        low, opts = self.low, self.solver
        old = warm.state if isinstance(warm.state, _WarmState) else None
        same = old is not None and _same_structure(old.low, low)
        if same:
            assert old is not None
            z0, jac0, mesh = old.z, old.jac, old.mesh
            self.travel = travel = old.travel + math.dist(old.low.inputs, low.inputs)
            predictor = guess = None
            if extrapolate:
                # Cubic, but where the last step took three iterations or more: there
                # the steps are long for the path's bends, and a quadratic extrapolates
                # them better.
                predictor = _extrapolated(old.path, low.key, travel, 2,
                                          3 if warm.iterations > 2 else 4)
                if predictor is not None and not old.refresh:
                    guess = _extrapolated(old.shot, low.key, travel, 3)
            # First, where the path has them, the Jacobians shot on its last steps,
            # extrapolated: they contract Newton's residual some 1e-5 times (on case 3's
            # path of 100 steps), so one iteration (two allowed) usually converges without
            # shooting the sensitivities. Else, or where that fails, a fresh Jacobian at
            # the prediction, which converges in about one (the last point's would
            # contract by only ~the step size).
            tries = [(_EMPTY_JAC, 0)] if guess is None else [(guess, 2), (_EMPTY_JAC, 0)]
            for jac_try, most in tries:
                if predictor is None:
                    break
                before = self.iterations
                z, r, status, jac, stats = self.newton(predictor, low.target, mesh,
                                                       strict=True, tol=opts.tolerance,
                                                       jac0=jac_try, iterations=most)
                if status != kernels.CONVERGED:
                    continue
                used = self.iterations - before
                self.steps += 1
                self.reused = jac_try is guess
                # Shoot afresh next time after a step of more than one iteration (too
                # long for an old Jacobian), or a reused one that only just converged
                # (the Jacobians are getting old). A prediction that needed no
                # iteration did not try its Jacobian.
                self.refresh = used > 1 or (self.reused and used == 1
                                            and r > REUSE_MARGIN * opts.tolerance)
                return self.polish(_Point(z, jac, mesh, stats, r))
        else:
            z0 = low.unknowns_from(warm)
            jac0 = _EMPTY_JAC
            mesh = self.first_mesh()
            if old is not None and old.mesh.density > mesh.density:
                mesh = low.mesh(old.mesh.density)
        z, r, status, jac, stats = self.newton(z0, low.target, mesh, strict=True,
                                               tol=opts.tolerance, jac0=jac0)
        if status == kernels.CONVERGED:
            self.steps += 1
            return self.polish(_Point(z, jac, mesh, stats, r))
        if not same:
            # A different structure (a grip switched to force control, the 3D model's
            # planar answer): no path between the two problems, so let a damped Newton
            # find the nearby equilibrium, with 4 and 16 times the restart nodes where
            # the intervals are too long for its forces (a hairpin's: as ``minima``).
            base = len(low.nodes) + 1
            for count in (1, 4, 16):
                if count > 1 and count * base > MAX_INTERVALS:
                    break
                if count > 1:
                    self.low = low = lower(low.problem, nodes=count * base)
                    z0 = low.unknowns_from(warm)
                    mesh = low.mesh(mesh.density)
                z, r, status, jac, stats = self.newton(z0, low.target, mesh, strict=False,
                                                       tol=opts.tolerance)
                if status == kernels.CONVERGED:
                    self.steps += 1
                    return self.polish(_Point(z, jac, mesh, stats, r))
                if clock.now() > self.deadline:
                    break
            return None
        assert old is not None
        try:
            return self.follow(old.low.target, low.target, z0, mesh)
        except Stalled as stall:
            if not stall.budget:
                # Perhaps the shooting intervals are too long for the forces on the way:
                # follow again with twice the restart nodes, or as many as the path
                # asked for (both problems re-lowered, so the start is still exact).
                count = max(2 * (len(low.nodes) + 1), stall.intervals)
                while True:
                    self.low = low = lower(low.problem, nodes=count)
                    start = lower(warm.problem, nodes=count)
                    try:
                        return self.follow(start.target, low.target,
                                           start.unknowns_from(warm), low.mesh(mesh.density))
                    except Stalled as again:
                        if again.intervals <= count:
                            break
                        count = again.intervals
            if follow_only:
                raise
            return None

    def polish(self, point: _Point) -> _Point:
        """Refine the mesh where the converged solution outgrew it."""
        need = self.need(point.stats)
        if need <= point.mesh.density:
            return point
        mesh = self.low.mesh(int(math.ceil(1.1 * need)))
        z, r, status, jac, stats = self.newton(point.z, self.low.target, mesh, strict=False,
                                               tol=self.solver.tolerance, jac0=point.jac)
        if status != kernels.CONVERGED:
            raise Stalled(1.0, r, "the refined mesh did not converge", state=point.z)
        return _Point(z, jac, mesh, stats, r)


def _crossed_note() -> CrossedBifurcation:
    return CrossedBifurcation(
        "the path to this problem crosses a bifurcation (det J changes sign); the "
        "equilibrium continued through it may be unstable, and a neighbouring branch may "
        "be the one the part takes")


REUSE_MARGIN = 0.5  # of the tolerance: a residual past it, the Jacobians are too old
_NAN = math.nan


_Memory = tuple  # (structure, travel: 4 floats, values: 4 arrays), oldest first


def _remembered(memory: _Memory | None, key: tuple, travel: float,
                value: np.ndarray) -> _Memory:
    """memory with value at travel added and its oldest dropped; begun anew where the
    structure differs or the travel does not grow (a NaN travel: no value there)."""
    if memory is not None and (memory[0] is key or memory[0] == key) and (
            memory[1][3] < travel):
        return key, memory[1][1:] + (travel,), memory[2][1:] + (value,)
    return key, (_NAN, _NAN, _NAN, travel), (value, value, value, value)


def _extrapolated(memory: _Memory | None, key: tuple, travel: float, least: int,
                  most: int = 4) -> np.ndarray | None:
    """The polynomial through the last remembered values (cubic through four,
    quadratic through three, linear through two; at least ``least``, at most ``most``)
    at travel, or None."""
    if memory is None or not (memory[0] is key or memory[0] == key):
        return None
    ts = memory[1]
    if math.isnan(ts[4 - least]) or not ts[3] < travel:
        return None
    if most < 4:
        ts = (_NAN,) * (4 - most) + ts[4 - most:]
    return kernels.extrapolated(*memory[2], *ts, travel)  # type: ignore[call-arg]


STAGED_WAVE = 30.0  # the load wavenumber k L past which a part's loads may be staged


def _one_point(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two points' unknowns on one lowering are one equilibrium's."""
    return bool(np.abs(a - b).max() <= 1e-6 * (1.0 + np.abs(b).max()))


@dataclass(frozen=True, eq=False)
class _Mirror:
    """A problem's own mirror image (``_mirror``): reflected in the chord, or turned half
    round about the chord's midpoint and read from the other end. The chord runs from a
    along u (its angle phi) to a + size u; ``shift`` is the held angle's whole turns."""

    stations: tuple
    length: float
    reflected: bool
    a: tuple[float, float]
    u: tuple[float, float]
    size: float
    phi: float
    shift: float

    def _flip(self, v: np.ndarray) -> np.ndarray:
        """Reflected in the chord: v -> 2 (v . u) u - v (rows of v)."""
        u = np.array(self.u)
        return 2.0 * (v @ u)[..., None] * u - v

    def _ends(self, ends: list[tuple[np.ndarray, float]]) -> list[tuple[np.ndarray, float]]:
        """Each end's load on the part, (force, moment), mapped: reflected, the moments
        change sign; turned, each end takes the other's load, turned."""
        if self.reflected:
            return [(self._flip(f), -m) for f, m in ends]
        return [(-ends[1][0], ends[1][1]), (-ends[0][0], ends[0][1])]

    def __call__(self, eq: Equilibrium) -> PlanarShape:
        """The mirror twin of an equilibrium: its arrays (those ``Lowered.unknowns_from``
        reads)."""
        ends = []
        raw = model_loads(eq)
        for st in self.stations:  # each end's load on the part: (force, moment)
            f = (raw[st.owner[0]].force[0], raw[st.owner[1]].force[1])
            m = raw[st.owner[2]].moment if st.owner[2] is not None else 0.0
            ends.append((np.array(f, dtype=float), float(m)))
        loads = self._named(self._ends(ends))
        a = np.array(self.a)
        if self.reflected:  # theta -> 2 phi - theta (and the held angle's turns)
            return PlanarShape(
                eq.problem, eq.s, a + self._flip(eq.position - a),
                2.0 * self.phi + self.shift - eq.angle, self._flip(eq.internal_force),
                -eq.bending_moment, loads)
        # r(s) -> 2 c - r(L - s), theta and n the same at L - s, m the opposite
        centre = a + 0.5 * self.size * np.array(self.u)
        return PlanarShape(
            eq.problem, self.length - eq.s[::-1], 2.0 * centre - eq.position[::-1],
            eq.angle[::-1].copy(), eq.internal_force[::-1].copy(), -eq.bending_moment[::-1],
            loads)

    def _named(self, ends: list[tuple[np.ndarray, float]]) -> dict[str, PlanarLoad]:
        """Each condition's share of its station's (force, moment), by name."""
        parts: dict[str, list[float]] = {}
        for st, (f, m) in zip(self.stations, ends):
            for i, owner in enumerate(st.owner):
                if owner is not None:
                    parts.setdefault(owner, [0.0, 0.0, 0.0])[i] = float(f[i]) if i < 2 else m
        return {name: PlanarLoad(np.array(v[:2]), v[2]) for name, v in parts.items()}

    def unknowns(self, low: Lowered, z: np.ndarray) -> np.ndarray | None:
        """The twin's unknowns straight from z's, where the lowering has no restart nodes
        (none to read between samples): the ends' reactions mapped as ``__call__`` maps
        their loads (nothing else acts on a part that is its own mirror image), and a
        free first angle (a pin's) reflected. None where there are nodes."""
        if len(low.nodes) or low.st_s.shape[0] != 2:
            return None
        kind, col = low.st_kind.tolist(), low.st_col.tolist()
        ends = [(np.array([z[col[k][0]], z[col[k][1]]]),  # both ends' positions held
                 float(z[col[k][2]]) if kind[k][2] == PRESCRIBED else 0.0) for k in (0, 1)]
        twin = self._ends(ends)
        out = np.zeros(low.nz)
        for k in (0, 1):
            f, m = twin[k]
            out[col[k][0]], out[col[k][1]] = f[0], f[1]
            if kind[k][2] == PRESCRIBED:
                out[col[k][2]] = m
            elif k == 0:  # a free angle at s = 0 is an unknown (a pin's): reflected
                out[col[0][2]] = 2.0 * self.phi + self.shift - z[col[0][2]]
        return out


def _mirror(problem: Problem) -> _Mirror | None:
    """Where the problem is its own mirror image, its mirror (``_Mirror``); else None.

    Only a uniform straight part with nothing on it but its two ends' conditions, each
    holding the position (and both or neither the angle): turned half round about the
    chord's midpoint and read from its other end (theta(s) -> theta(L - s): ends held
    at one angle, a hose between two parallel ports, the paper's case 3), or reflected
    in the chord (ends held along the chord, or pinned: the buckled strut). Either maps
    a part bowed to one side of its chord onto one bowed to the other, of equal energy."""
    part, stations = problem.part, problem.stations
    length = part.length
    if (len(stations) != 2 or stations[0].s != 0.0 or stations[1].s != length
            or any(k != 0.0 for _, k in part.rest_knots) or problem.partial_loads
            or any(problem.dead_load_per_length) or problem.loads):
        return None
    first, last = stations
    if any(st.prescribed[:2] != (True, True) or any(st.dead_load) or any(st.follower_load)
           for st in (first, last)) or first.prescribed[2] != last.prescribed[2]:
        return None
    (ax, ay, theta0), (bx, by, theta1) = first.kinematics, last.kinematics
    size = math.hypot(bx - ax, by - ay)
    if size == 0.0:
        return None
    phi = math.atan2(by - ay, bx - ax)
    held = first.prescribed[2]
    # Held angles are read as turns too (theta(L) - theta(0) is how often the part winds
    # round): either mirror reverses that, so the two must be one angle; reflected, it
    # must lie along the chord, the angles then 2 phi - theta and a whole number of turns.
    if held and abs(theta1 - theta0) > 1e-12:
        return None
    turns = round((theta0 - phi) / math.pi)
    along = not held or abs(theta0 - phi - turns * math.pi) <= 1e-12
    if not along and not held:
        return None
    return _Mirror(stations=(first, last), length=length, reflected=along, a=(ax, ay),
                   u=((bx - ax) / size, (by - ay) / size), size=size, phi=phi,
                   shift=2.0 * math.pi * turns if held else 0.0)


def _loads_scaled(problem: Problem, f: float) -> Problem:
    """The problem with every load times f: the conditions' forces and moments, gravity
    (the weight of the part and of masses added to it) and the distributed loads."""
    def scaled(values):
        return tuple(None if v is None else f * v for v in values) if values else values

    conditions = tuple(replace(c, force=scaled(c.force), moment=None if c.moment is None
                               else f * c.moment)  # type: ignore[operator]  # 2D: a number
                       for c in problem.conditions)
    loads = tuple(replace(ld, force=scaled(ld.force)) if isinstance(ld, DistributedLoad)
                  else ld for ld in problem.loads)
    return replace(problem, conditions=conditions, gravity=scaled(problem.gravity),
                   loads=loads)


MOST_INTERVALS = 64  # see ``Run.minima``
# The largest wavenumber times element length of an energy minimum that starts a Newton
# (``Run.minima``; a coarser one goes to its refinement first). On 120 heavy held targets
# the Newtons from such starts converged at 8 of 124 tries on 500 unknowns or more, 76 ms
# a try; skipping them: 44.2 s against 52.5 s in all, every answer the same (and at the
# 900 random held targets).
UNRESOLVED = 2.0
# An energy minimum (48 elements) whose element angles all lie within MATCHED [rad] of
# an equilibrium a route reached is that equilibrium (``Run.minima``). On 900 random held
# targets every one of 936 such minima converged to the route's equilibrium (half within
# 2e-3 rad), and every minimum that converged to another equilibrium lay 0.59 rad or
# more from each the routes reached.
MATCHED = 0.1
# The most shooting intervals any lowering here asks for: the largest wavenumber a
# problem may have (k L = 1000, ``lowering.MAX_WAVENUMBER``) needs 157 at NODE_SPAN with a
# quarter to spare. A cable at q L^3 / EI = 1e6 (k L near 1000, on 124 intervals) had its
# energy's minimum tried on 16 times as many: a dense Jacobian of 12,000 unknowns, a
# gigabyte, for minutes past the time budget.
MAX_INTERVALS = 256


def _statistics(start) -> np.ndarray:
    """A start's arrays summed up as the kernels' statistics: (max|theta'|, max|n|),
    dimensionless."""
    part = start.problem.part
    L, EI = part.length, part.bending_stiffness
    s = np.asarray(start.s) / L
    step = np.diff(s)
    turn = np.abs(np.diff(np.asarray(start.angle)))[step > 0.0] / step[step > 0.0]
    force = np.linalg.norm(np.asarray(start.internal_force), axis=1).max() * L**2 / EI
    return np.array([turn.max(initial=0.0), force])


def _intervals(k: float, low: Lowered) -> int | None:
    """The shooting intervals an internal force of wavenumber k = sqrt(max|n|)
    (dimensionless) needs where it outgrows ``low``'s (k times the longest above
    ``NODE_SPAN``: its sensitivities would grow like exp(k s) across one): each then
    spans at most ``NODE_SPAN``, with a quarter to spare; None where ``low``'s do."""
    if k * low.interval <= NODE_SPAN:
        return None
    return min(MAX_INTERVALS, math.ceil(1.25 * k / NODE_SPAN))


def _same_structure(a: Lowered, b: Lowered) -> bool:
    return a.key == b.key


def solve(problem: Problem, *, warm_start: Equilibrium | None = None,
          solver: ShootingSolver | None = None) -> Equilibrium:
    """The equilibrium of a 2D problem.

    warm_start : an earlier equilibrium (of this or a nearby problem) to start from; the
        answer stays on its branch when a continuation from it can reach the problem.
    Raises ConvergenceError (with the residual and how far it got) when no equilibrium
    is found within the solver's budgets.
    """
    return _solve(problem, warm_start, solver or _DEFAULT, follow_only=False)


def _from_dead_twin(problem: Problem, solver: ShootingSolver, deadline: float,
                    stall: Stalled) -> Equilibrium | None:
    """Where every route from the unloaded part stalls on a problem with follower loads
    (a clamp with a grip mid-span and a follower at the tip, issue 54), its dead twin
    (each follower load's components held fixed in the global frame instead) solved
    first, then followed from there as the loads turn with the part; said. None where
    either fails or the time is out."""
    if not (any(c.follower for c in problem.conditions)
            or any(ld.follower for ld in problem.distributed)):
        return None
    left = deadline - clock.now()
    if left <= 0.0:
        return None
    twin = replace(problem, conditions=tuple(replace(c, follower=False)
                                             for c in problem.conditions),
                   loads=tuple(replace(ld, follower=False)
                               if isinstance(ld, DistributedLoad) else ld
                               for ld in problem.loads))
    try:
        dead = _solve(twin, None, replace(solver, time_budget=left), follow_only=False)
    except ConvergenceError:
        return None
    eq = None
    for _ in range(TURNS):
        left = deadline - clock.now()
        if left <= 0.0:
            return None
        try:
            eq = _solve(problem, dead, replace(solver, time_budget=left), follow_only=True)
            break
        except ConvergenceError:
            # Its path meets a fold: the twin again with each follower force turned to
            # where the last dead answer has its station (successive substitution: where
            # they agree, the dead answer is the follower's), followed from that one.
            twin = replace(twin, conditions=tuple(
                _turned(c, dead) if c.follower else replace(c, follower=False)
                for c in problem.conditions))
            try:
                dead = _solve(twin, dead, replace(solver, time_budget=left),
                              follow_only=False)
            except ConvergenceError:
                return None
    if eq is None:
        return None
    note = Event(
        f"every route from the unloaded part stopped ({stall.reason}, at {stall.t:.3g} of "
        "the way); pliant solved the same loads held fixed in direction first (dead), then "
        "turned them with the part (followers) from there; other equilibria may exist")
    return replace(eq, notes=(*eq.notes, note))


TURNS = 6  # dead twins tried, each with the followers turned to the last one's stations


def _turned(c: Any, eq: Equilibrium) -> Any:
    """A follower point force (tangential, normal) as the dead force it is where
    ``eq`` has its station (its angle there)."""
    theta = float(np.interp(c.s, eq.s, eq.angle))
    ft, fn = (float(v) for v in c.force)
    return replace(c, follower=False, force=(ft * math.cos(theta) - fn * math.sin(theta),
                                             ft * math.sin(theta) + fn * math.cos(theta)))


def _solve(problem: Problem, warm_start: Equilibrium | None, solver: ShootingSolver,
           follow_only: bool, extrapolate: bool = False) -> Equilibrium:
    old = warm_start.state if warm_start is not None else None
    low = old.low.retarget(problem) if isinstance(old, _WarmState) else None
    if low is None:
        low = lower(problem, nodes=len(old.low.nodes) + 1 if isinstance(old, _WarmState)
                    else None)
    run = Run(low, solver)
    if isinstance(old, _WarmState):
        if extrapolate:
            run.path, run.shot = old.path, old.shot
        else:  # a path begins here: what came before it is not its own
            run.path = _remembered(None, old.low.key, old.travel, old.z)
    else:
        run.lowered[None] = (problem, low)
    point = None
    try:
        if warm_start is not None:
            point = run.warm(warm_start, follow_only, extrapolate)
            if point is not None:
                # What was said of the branch still holds along it.
                run.notes[:0] = [n for n in warm_start.notes if isinstance(n, BranchTaken)]
            else:
                run.notes.append(WarmStartLost(WARM_START_LOST))
                run.low = lower(problem)
        if point is None:
            point = run.polish(run.cold())
    except Stalled as stall:
        if warm_start is None and not follow_only and not stall.budget:
            turned = _from_dead_twin(problem, solver, run.deadline, stall)
            if turned is not None:
                return turned
        raise ConvergenceError(
            f"no equilibrium reached: {stall.reason}; stopped at {stall.t:.3g} of the "
            f"way (relative residual {stall.residual:.2e}); {NOT_EXHAUSTIVE}; try smaller "
            "steps or check that the targets can be reached",
            residual=stall.residual, progress=stall.t, last_good=warm_start,
            status=stall.status) from None
    return _answer(run, point, problem, solver)


def _answer(run: Run, point: _Point, problem: Problem, solver: ShootingSolver,
            notes: tuple[str, ...] | None = None) -> Equilibrium:
    point = _renode(run, point)
    low = run.low
    sampler = _Sampler(low, point.z, max(point.mesh.density, solver.samples))
    key, shot = low.key, run.shot
    if not run.reused and point.jac.shape[0] == point.z.shape[0]:
        shot = _remembered(shot, key, run.travel, point.jac)
    return Equilibrium(problem=problem, residual=point.residual, iterations=run.iterations,
                       steps=run.steps, sampler=sampler,
                       notes=tuple(run.notes) if notes is None else notes,
                       state=_WarmState(low, point.z, point.jac, point.mesh, run.travel,
                                        _remembered(run.path, key, run.travel, point.z),
                                        shot, run.refresh),
                       stability_check=stability)


def equilibria(problem: Problem, *, solver: ShootingSolver | None = None,
               budget: float = 5.0) -> list[Equilibrium]:
    """The distinct equilibria of a 2D problem that pliant's routes reach from the
    unloaded part within ``budget`` seconds: each route of a cold solve (straight, more
    restart nodes, positions first, a swing round the first support, loads first) and,
    from a singular start, each bow side; then the minima of the energy from a few
    starting shapes (``minimum``). Stable (and neutral) ones first, then unstable, each
    group by potential energy (``continuation.best_first``); the first is what ``solve``
    would choose among them. Empty when no route reaches one."""
    solver = solver or _DEFAULT
    deadline = clock.now() + budget
    nodes = len(lower(problem).nodes) + 1
    found: list[Equilibrium] = []
    for count, name in ((nodes, "straight"), (4 * nodes, "straight"),
                        (nodes, "two_stage"), (nodes, "swing"), (nodes, "loads_first")):
        left = deadline - clock.now()
        if left <= 0.0:
            break
        run = Run(lower(problem, nodes=count), replace(solver, time_budget=left))
        try:
            run.renoded(partial(run.route, getattr(run, name)))
        except Stalled:
            continue
        low = run.low
        for point in run.reached:
            run.low = low  # each point's unknowns are those of the route's lowering
            try:
                route = name.replace('_', ' ')
                eq = _answer(run, run.polish(point), problem, solver, notes=(
                    ReachedBy(f"reached by the {route} route", route=route),))
            except Stalled:
                continue
            if not any(_same(eq, other) for other in found):
                found.append(eq)
    left = deadline - clock.now()
    if left > 0.0:  # and where the energy is least, from a few starting shapes
        run = Run(lower(problem), replace(solver, time_budget=left))
        for low, point in run.minima():
            run.low = low
            eq = _answer(run, point, problem, solver, notes=(
                ReachedBy("reached by minimising the energy", route="energy minimum"),))
            if not any(_same(eq, other) for other in found):
                found.append(eq)
    return continuation.best_first(found, problem.part)  # twins: solve's first


def _same(a: Equilibrium, b: Equilibrium) -> bool:
    """One equilibrium reached twice: the same shape to 1e-6 of the part's length, at
    b's samples. Where a's samples lie elsewhere (two routes may answer on different
    shooting intervals) a is read between its own by its tangents too (``_between``),
    and the tolerance grows by that reading's error (``_hermite_error``): a straight
    line between samples misses the arc by h^2 / 8R, some 1e-4 L, and the cubic, on a
    part turning 22 rad a length, 2e-6 L, which listed an answer among the others found
    as one more equilibrium of the same energy."""
    L = a.problem.part.length
    if a.s.shape == b.s.shape and np.array_equal(a.s, b.s):  # sampled alike
        return float(np.abs(a.position - b.position).max()) <= 1e-6 * L
    return float(np.abs(_between(a, b.s) - b.position).max()) <= 1e-6 * L + _hermite_error(a)


def _hermite_error(eq: Equilibrium) -> float:
    """A bound on ``_between``'s error [m]: the cubic Hermite interpolant's, h^4 / 384
    times the fourth derivative, which on an arc of curvature k is k^3: h dtheta^3 / 384
    an interval, here four times over (the curvature varies along it)."""
    h = np.diff(eq.s)
    return float(np.max(h * np.abs(np.diff(eq.angle)) ** 3, initial=0.0)) / 96.0


def _between(eq: Equilibrium, s: np.ndarray) -> np.ndarray:
    """The position at arc lengths s by cubic Hermite interpolation of the samples,
    whose tangents are (cos, sin) of the angle: an error like h^4 / R^3."""
    grid, pos, angle = eq.s, eq.position, eq.angle
    k = np.clip(np.searchsorted(grid, s, side="right") - 1, 0, grid.size - 2)
    h = grid[k + 1] - grid[k]
    u = np.divide(s - grid[k], h, out=np.zeros_like(s), where=h > 0.0)
    w0, w1 = (1 + 2 * u) * (1 - u) ** 2, u**2 * (3 - 2 * u)  # the ends' positions
    t0, t1 = u * (1 - u) ** 2 * h, -(u**2) * (1 - u) * h  # and tangents
    out = np.empty((s.size, 2))
    for i, trig in enumerate((np.cos, np.sin)):
        out[:, i] = (w0 * pos[k, i] + w1 * pos[k + 1, i] + t0 * trig(angle[k])
                     + t1 * trig(angle[k + 1]))
    return out


def _renode(run: Run, point: _Point) -> _Point:
    """More restart nodes when the solution's force outgrew the shooting intervals (a
    part pulled taut, a cable hanging): the answer is the same, but later warm starts
    from it stay well conditioned."""
    low = run.low
    count = _intervals(math.sqrt(float(point.stats[1])), low)
    if count is None:
        return point
    finer = lower(low.problem, nodes=count)
    here = Equilibrium(problem=low.problem, residual=point.residual, iterations=0, steps=0,
                       sampler=_Sampler(low, point.z, point.mesh.density))
    z0 = finer.unknowns_from(here)
    mesh = finer.mesh(point.mesh.density)
    run.low = finer
    z, r, status, jac, stats = run.newton(z0, finer.target, mesh, strict=False,
                                          tol=run.solver.tolerance)
    if status != kernels.CONVERGED:
        run.low = low  # keep the converged answer on the coarser intervals
        return point
    return _Point(z, jac, mesh, stats, r)


@dataclass(slots=True, eq=False)
class _Sampler:
    """Integrates the converged unknowns once more on the output grid."""

    low: Lowered
    z: np.ndarray
    density: int

    def __call__(self) -> Samples:
        low, z = self.low, self.z
        mesh = low.mesh(self.density)
        grid, rows = low.rows(mesh)
        traj = np.zeros((grid.shape[0], kernels.NSTATE))
        kernels.shoot(z, *low.args(low.target, mesh), False, traj)  # type: ignore[call-arg]
        fs, ms = low.force_scale, low.moment_scale
        loads: dict[str, StationLoad] = {}
        for k, station in enumerate(low.station_of):
            if station is None:
                continue
            theta = float(traj[rows[k], 2])
            for cond in station.conditions:
                loads[cond.name] = _station_load(low, k, station, cond, z, theta)
        return Samples(s=grid, position=traj[:, :2] * low.length,
                       angle=traj[:, 2].copy(), internal_force=traj[:, 3:5] * fs,
                       bending_moment=traj[:, 5] * ms,
                       energy=float(traj[-1, 6]) * low.stiffness / low.length, loads=loads)


def _station_load(low: Lowered, k: int, station, cond, z: np.ndarray,
                  theta: float) -> StationLoad:
    """The load of one condition: its reactions from the unknowns, its applied loads
    from the problem (a follower force resolved at the deformed angle theta)."""
    force = [0.0, 0.0]
    moment = 0.0
    flags = [False, False, False]
    cols = low.st_col[k].tolist()
    for i in range(3):
        if station.owner[i] == cond.name:
            flags[i] = True
            value = float(z[cols[i]])
            if i < 2:
                force[i] = value * low.force_scale
            else:
                moment = value * low.moment_scale
    if cond.follower:
        ft, fn = (cond.force[0] or 0.0), (cond.force[1] or 0.0)
        force[0] += ft * math.cos(theta) - fn * math.sin(theta)
        force[1] += ft * math.sin(theta) + fn * math.cos(theta)
    else:
        force[0] += cond.force[0] or 0.0
        force[1] += cond.force[1] or 0.0
    moment += cond.moment or 0.0
    return StationLoad(cond.name, cond.s, np.array(force), moment,
                       (flags[0], flags[1], flags[2]))


def trace(problems: Iterable[Problem], *, start: Equilibrium | None = None,
          solver: ShootingSolver | None = None) -> Iterator[Equilibrium]:
    """Follow a sequence of problems (a hand moving, a load growing), warm-starting each
    solve from the last equilibrium; yields one equilibrium per problem. From the second
    problem on, a step starts from the cubic through the path's last answers, with the
    Jacobian extrapolated from the last ones shot (``Run.warm``).

    It stays on the branch it is on: where the branch ends or turns back (a fold, a
    snap-through) it raises ConvergenceError with ``last_good`` the last equilibrium,
    instead of jumping silently to another branch.
    """
    solver = solver or _DEFAULT
    previous = start
    for problem in problems:
        # From the second step on, each starts from an extrapolation of the path's last
        # answers (``_WarmState.path``); the first from start itself.
        eq = _solve(problem, previous, solver, follow_only=previous is not None,
                    extrapolate=previous is not start)
        previous = eq
        yield eq


__all__ = ["ShootingSolver", "solve", "trace"]
