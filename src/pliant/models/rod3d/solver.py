"""Solve the 3D rod: ``solve(problem)`` and ``trace(problems)``.

The route, for a problem with no warm start (as in the 2D model):

1. A homotopy from the unloaded part (loads scaled by t, prescribed positions moved
   along straight lines and orientations along the shortest arcs); each step a Newton
   corrector on the KKT system that must contract, with a tangent first predictor and
   secant ones after; steps are capped so that the loads' wavenumber grows by at most
   one per step (buckling modes appear about pi apart in it).
2. A singular start (an end pushed along the straight part: it may buckle to any side)
   runs on a part bowed toward the side the targets and loads push it to, then the bow
   is removed. If that branch meets a fold or ends unstable (for conservative loads),
   the opposite side and the two across are tried, and the first stable one is kept.
   A note says which.
3. When a route stalls at a fold, other routes are tried: targets first then loads,
   held points swung round the first support along arcs, loads first then targets.
4. When every route meets a fold, the part snaps there: just past the fold it is let
   settle by a pseudo-transient relaxation (implicit Euler of the constrained gradient
   flow), and the route goes on from where it lands. A note says so.

With a warm start, the previous equilibrium's mesh is reused when only targets and
loads moved, one Newton from it is tried, then a homotopy from it; ``trace`` never leaves
its branch: a fold ends it with a ConvergenceError carrying the last good equilibrium.

The answer is built in ``results`` (its arrays, loads, contacts, the warm start's
state) and its stability tested in ``stability``; the rod's unknowns and the lowering of
a problem onto them are ``lowering``'s, the compiled terms ``kernels``'.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field, replace
from functools import cached_property, partial

import numpy as np

from pliant.core.equilibrium import WARM_START_LOST, Equilibrium3D, StationLoad, potential_energy
from pliant.core.events import (
    NOT_EXHAUSTIVE,
    BranchTaken,
    LowestEquilibrium,
    ReachedBy,
    Status,
    WarmStartLost,
)
from pliant.core.problem import Problem
from pliant.core.rotations import qmul, quat_matrix
from pliant.errors import ConvergenceError, IllPosedProblemError, InputError
from pliant.models import clock, continuation
from pliant.models.continuation import Line, Stalled
from pliant.models.rod3d import contact_kernels, kernels
from pliant.models.rod3d.carrying import carried, pushed_out
from pliant.models.rod3d.kernels import AXIS
from pliant.models.rod3d.lowering import Loads, Rod, State, axis_basis, lower
from pliant.models.rod3d.results import WarmState, build, station_loads
from pliant.models.rod3d.routes import _BRANCH_NOTE, Routes
from pliant.models.rod3d.settling import (
    downhill_equilibria,
    same_family,
    same_shape,
    settled,
)
from pliant.models.rod3d.stability import conservative, metric, stability_of
from pliant.models.settings import check

# The Newton kernels' codes as the driver's statuses (a corrector that did not contract:
# the path turns back there).
_STATUS = {kernels.CONVERGED: Status.CONVERGED, kernels.SINGULAR: Status.SINGULAR,
           kernels.NOT_FINITE: Status.NOT_FINITE}
_SWITCHES = 6  # active-set changes a Newton may take without contracting


@functools.cache
def _empty_scene() -> tuple:
    """A scene without obstacles, packed as the contact kernel takes it (a free rod's)."""
    from pliant.scene.distance import DistanceField  # noqa: PLC0415 (the free rod only)

    return DistanceField([]).args


# Weighs a gap against a contact force in min(gam, scale g), times (0.01 / h)^2 past 100
# elements: the rows then grow with the bending terms (as 1 / h^2), so that the pivot of
# a probe that only the compliance keeps regular (flat contact) is not round-off beside
# them. It changes no answer, only how the rows compare.
CONTACT_SCALE = 1.0


@dataclass(frozen=True)
class RodSolver:
    """Settings of the 3D solver (an immutable config).

    elements : about how many elements the part is cut into (the error falls as h^2)
    tolerance : the largest KKT residual accepted (dimensionless: forces by EI/L^2)
    max_iterations : per Newton solve; contraction : how much each continuation
        corrector iteration must shrink the residual
    max_steps, min_step : budget of one homotopy (steps, smallest step in t)
    grow : the distance between a step's prediction and its corrected point that the
        step control aims at (each unknown relative to its size)
    wave_step : the most a step may raise the wavenumber of the loads
    bow : the chord shortening of the imperfection that leaves a singular start, as a
        fraction of what the targets ask
    time_budget : wall-clock seconds before a solve gives up
    accuracy : the relative error of the reactions a cold solve accepts from the
        discretisation (estimated by Richardson's rule from the same equilibrium on twice
        the elements, ``Equilibrium3D.reaction_error``); above it the answer says so and
        names the element count that meets it
    lowest : in a cold solve with positions held at two stations or more, run every
        route (with obstacles, without them, keeping the answers that touch none of
        them) and answer with the stable equilibrium of lowest potential energy (about
        four times the first route's time); False answers with the first route's
    settle : an answer that is unstable is left along its unstable mode, both ways, for
        the stable equilibrium the part settles in (from a warm start the nearest to it,
        from rest the lowest), with a note; False keeps the unstable equilibrium (to
        study that branch itself, as ``trace`` does)
    """

    elements: int = 100
    tolerance: float = 1e-10
    max_iterations: int = 25
    contraction: float = 0.5
    max_steps: int = 1000
    min_step: float = 1e-6
    grow: float = 0.1
    wave_step: float = 1.0
    bow: float = 0.8
    time_budget: float = 60.0
    accuracy: float = 0.01
    lowest: bool = True
    settle: bool = True

    def __post_init__(self) -> None:
        check(self, fractions=("contraction",))


_DEFAULT = RodSolver()  # (frozen: one shared, not validated again at every warm step)


# X, Q, lam, nu and gam: positions, frames, element and station multipliers, and the
# contact probes' normal forces (empty without obstacles).

ROUND_OFF_FLOOR = 0.03  # of eps / the axial compliance: the residual's floor (see Run)


@dataclass
class Run(Routes):
    rod: Rod
    solver: RodSolver
    gauge_quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    iterations: int = 0
    steps: int = 0
    notes: list[str] = field(default_factory=list)
    deadline: float = 0.0
    stall: Stalled | None = None  # why the last follow from a warm start stopped
    # Friction's reference (see contact_kernels.contact_terms): none yet, so no friction.
    friction: tuple = ()
    branch_note: str = _BRANCH_NOTE  # how a note on the buckling side begins
    # ``equilibria``: every branch a route reaches is kept here (state, gauge, note), not
    # only the one the route returns.
    reached: list | None = None
    # The last converged Newton: (state, loads, residual), so that the answer built from
    # that very state at those very loads need not evaluate its residual again.
    converged: tuple | None = None

    def __post_init__(self) -> None:
        self.deadline = clock.now() + self.solver.time_budget
        # A stiff axial spring (EA L^2 / EI = 1 / compliance, 2e8 for a steel cable of
        # 16 MN in a soft sheath) lifts the residual's round-off floor to about
        # 0.01 eps / compliance (5e-10 there, against a tolerance of 1e-10): asked for
        # less, Newton would refuse an answer that holds to round-off.
        compliance = float(self.rod.K[3])
        floor = ROUND_OFF_FLOOR * np.finfo(float).eps / compliance if compliance > 0 else 0.0
        if floor > self.solver.tolerance:
            self.solver = replace(self.solver, tolerance=floor)
        K = self.rod.probe_elem.shape[0]
        self.friction = (np.zeros(max(len(self.rod.problem.obstacles), 1)), np.zeros((K, 3)),
                         np.zeros((K, 2, 3)), np.ones(K))

    def hold(self, state: State, previous: tuple = ()) -> State:
        """Friction from here on is measured from ``state`` (the step's start): each probe's
        slip from its point there, in the tangent plane of the obstacle nearest it then.
        A cold solve has no such start, and no friction. Returns the state with its
        tangential forces, found in the ``previous`` reference's bases, in the new ones."""
        rod = self.rod
        if not rod.friction:
            return state
        points = rod.probe_points(state[0])
        _, normals, which = rod.distance_field.query(points * rod.length, band=math.inf)
        basis = axis_basis(normals)
        give = contact_kernels.ELASTIC_SLIP * rod.h[rod.probe_elem]
        gam = state[4].reshape(-1, 3).copy()
        if previous:
            force = np.einsum("ki,kic->kc", gam[:, 1:], previous[2])
            gam[:, 1:] = np.einsum("kic,kc->ki", basis, force)
            # A sticking probe's spring holds its force: its slip is measured from where
            # the spring is slack, so that the start stays in equilibrium.
            mu = rod.distance_field.friction
            rho = np.where(which >= 0, mu[np.maximum(which, 0)], 0.0) * np.maximum(gam[:, 0],
                                                                                     0.0)
            held = rho > 0.0
            points = points.copy()
            points[held] += (give[held] / rho[held])[:, None] * force[held]
        else:
            gam[:, 1:] = 0.0
        self.friction = (rod.distance_field.friction, points, basis, give)
        return (*state[:4], gam.ravel())

    def newton(self, state: State, loads: Loads, *, strict: bool, tol: float | None = None,
               predict: bool = False):
        """Newton from ``state`` at ``loads``; ``predict`` (with obstacles): a warm step
        from an equilibrium of nearby loads (``Settings``)."""
        opts = self.solver
        rod = self.rod
        tol = opts.tolerance if tol is None else tol
        # One kernel with and without obstacles (a free rod has no probes and an empty
        # scene): a second Newton kernel cost every first run 1.6 s of CPU to compile.
        settings = kernels.Settings(float(tol), int(opts.max_iterations),
                                    float(opts.contraction), bool(strict), _SWITCHES,
                                    bool(predict))
        X, Q, lam, nu, gam, r, it, status, energy = contact_kernels.newton_contact(
            *state[:5], rod.mesh, rod.targets(loads, self.gauge_quat), rod.numbering,
            self.contact(loads), settings)
        new = (X, Q, lam, nu, gam)
        self.iterations += it
        if status == kernels.CONVERGED and not self._axes_agree(new[1], loads):
            status = kernels.NOT_CONTRACTING
        self.converged = (new, loads, r) if status == kernels.CONVERGED else None
        return new, r, status, energy

    def _axes_agree(self, Q: np.ndarray, loads: Loads) -> bool:
        """An axis grip's constraint (d3 normal to two vectors across the axis) also holds
        with d3 reversed: a Newton that jumped to that sheet has not met the grip."""
        rod = self.rod
        for k in np.nonzero(rod.st_kind == AXIS)[0]:
            if quat_matrix(Q[rod.st_frame[k]])[:, 2] @ loads.st_tangent[k] <= 0.0:
                return False
        return True

    def residual(self, state: State, loads: Loads, want_jac: bool = False):
        return self.terms(state, loads, want_jac)[:3]

    def terms(self, state: State, loads: Loads, want_jac: bool = False):
        """``residual``'s (R, ab, energy), and each probe's contact state (0 free, else
        touching; none without probes): what a Newton that does not hold the obstacles'
        touching set compares between its steps."""
        rod = self.rod
        R, ab, energy = kernels.assemble(*state[:4], rod.mesh,
                                         rod.targets(loads, self.gauge_quat), rod.numbering,
                                         want_jac)
        active = np.zeros(0, dtype=np.int8)
        if rod.iprobe.shape[0]:
            active = self.contacts(state, loads, R, ab, want_jac)[3]
        return R, ab, energy, active

    def contacts(self, state: State, loads: Loads, R: np.ndarray | None = None,
                 ab: np.ndarray | None = None, want_jac: bool = False):
        """Add the contact terms to (R, ab) and return (gaps, normals, obstacles, active,
        places, takers, forces) of the probes (see ``contact_kernels.contact_terms``)."""
        rod = self.rod
        if R is None:
            R = np.zeros(rod.n)
        if ab is None:
            ab = np.zeros((0, 2 * rod.kl + rod.ku + 1))
        return contact_kernels.contact_terms(state[0], state[4], self.contact(loads),
                                             rod.numbering, R, ab, bool(want_jac), False)

    def solve_linear(self, ab: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, bool]:
        """Solve J du = rhs, J's band in ``ab`` (which may be overwritten). A free probe's
        rows are the identity's (its forces are 0): they leave the factorisation, which
        then costs what the part's own unknowns and the touching probes cost."""
        rod = self.rod
        if not rod.iprobe.shape[0]:
            return kernels.band_solve(ab, rod.kl, rod.ku, rhs)
        drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
        return kernels.band_solve_reduced(ab, rod.kl, rod.ku, rhs, drop)

    def contact(self, loads: Loads) -> kernels.Contact:
        """The contact terms' bundle at ``loads``: the band of exact distances reaches two
        radii and 5% of L past the tube."""
        return self._contact_bundle._replace(offset=float(loads.offset),
                                             friction=self.friction)

    @cached_property
    def _contact_bundle(self) -> kernels.Contact:
        """``contact``'s fixed part (built once: it is asked for at every residual)."""
        rod = self.rod
        return kernels.Contact(rod.probe_elem, rod.probe_a, rod.slider, rod.node_probe,
                               rod.iprobe, rod.slot, float(rod.length), float(rod.radius),
                               0.0, 2.0 * rod.radius + 0.05 * rod.length,
                               CONTACT_SCALE * max(1.0, (0.01 / float(rod.h.min())) ** 2),
                               _empty_scene() if rod.obstacles is None
                               else rod.distance_field.args, ())

    def step(self, state: State, du: np.ndarray, scale: float) -> State:
        rod = self.rod
        X, Q, lam, nu = kernels.apply_step(*state[:4], du, rod.numbering, scale)
        return X, Q, lam, nu, state[4] + scale * du[rod.islot]

    def difference(self, a: State, b: State) -> np.ndarray:
        rod = self.rod
        du = kernels.difference(*a[:4], *b[:4], rod.numbering)
        du[rod.islot] = b[4] - a[4]
        return du

    def follow(self, start: Loads, end: Loads, state: State) -> State:
        """Continuation from (start, state), an exact solution, to end (the shared
        driver's ``continuation.follow``)."""
        return continuation.follow(self, Line(start, end), state, self.stepping,
                                   self.deadline)

    # -- what the shared driver asks (continuation.Continuable, Relaxable) --------------
    @cached_property
    def stepping(self) -> continuation.Stepping:
        opts = self.solver
        return continuation.Stepping(
            tolerance=opts.tolerance, loose=max(opts.tolerance, 1e-7),
            min_step=opts.min_step, max_steps=opts.max_steps, grow=opts.grow,
            wave_step=opts.wave_step, time_budget=opts.time_budget)

    def correct(self, predictor: State, loads: Loads, *, strict: bool, tol: float | None
                ) -> tuple[State, float, Status]:
        state, r, status, _ = self.newton(predictor, loads, strict=strict, tol=tol)
        return state, r, _STATUS.get(status, Status.FOLD)

    def tangent(self, state: State, path: Line) -> np.ndarray | None:
        """J du = -dR/dt at the start, dR/dt by a forward difference."""
        eps = 1e-7
        R_eps, ab, _ = self.residual(state, path.at(eps), want_jac=True)
        du, ok = self.solve_linear(ab, -R_eps / eps)
        if not ok or not float(np.abs(du).max()) < 1e10:  # singular up to rounding
            return None
        return du

    def miss(self, predicted: State, corrected: State) -> float:
        du = self.difference(predicted, corrected)
        return float(np.max((np.abs(du) / self.sizes(corrected))[self.judged]))

    def load_size(self, path: Line) -> tuple[float, float]:
        return _load_size(path.start, path.end, self.rod.h)

    def begin_step(self, state: State) -> State:
        return state

    def memo(self) -> np.ndarray:
        return self.gauge_quat.copy()

    @cached_property
    def _metric(self) -> tuple[np.ndarray, np.ndarray]:
        primal, weight = metric(self.rod)
        return primal, np.where(primal, weight, 0.0)

    @property
    def tolerance(self) -> float:
        return self.solver.tolerance

    def gradient(self, state: State, loads: Loads) -> tuple[np.ndarray, np.ndarray]:
        R, ab, _ = self.residual(state, loads, want_jac=True)
        return R, ab

    def diagonal_scale(self, jac: np.ndarray) -> float:
        primal, shift = self._metric
        return float((np.abs(jac[primal, self.rod.kl + self.rod.ku]) / shift[primal]).max())

    def shifted_solve(self, jac: np.ndarray, sigma: float, rhs: np.ndarray
                      ) -> tuple[np.ndarray, bool]:
        jac[:, self.rod.kl + self.rod.ku] += sigma * self._metric[1]
        return self.solve_linear(jac, rhs)

    def primal_move(self, du: np.ndarray) -> float:
        return float(np.abs(du[self._metric[0]]).max())

    def unstable_mode(self, state: State, loads: Loads) -> np.ndarray | None:
        mode: list = []
        stable, _ = stability_of(self, state, found=mode, loads=loads)
        if stable or not mode:
            return None
        du = np.zeros(self.rod.n)
        du[np.flatnonzero(self._metric[0])] = mode[0]
        return du

    @cached_property
    def judged(self) -> np.ndarray:
        """The unknowns by which a step's prediction is judged: all of them; with
        obstacles, the positions and frames alone. A contact's force moves from probe to
        probe as the touching point runs along the part (and the internal forces between
        with it): a step no predictor foresees, which the semismooth corrector takes in
        stride, but which judged as a miss halved every step, more often the finer the
        mesh (the probes closer): Newton iterations grew with N."""
        rod = self.rod
        if not rod.iprobe.shape[0]:
            return np.arange(rod.n)
        three = np.arange(3)
        return np.concatenate([(rod.ix[:, None] + three).ravel(),
                               (rod.ith[:, None] + three).ravel()])

    def sizes(self, state: State) -> np.ndarray:
        """Each unknown's size, floored at 1 (frame rotations count as 1)."""
        rod = self.rod
        sizes = np.ones(rod.n)
        three = np.arange(3)
        sizes[rod.ix[:, None] + three] = np.maximum(1.0, np.abs(state[0]))
        sizes[rod.ilam[:, None] + three] = np.maximum(1.0, np.abs(state[2]))
        unknown = rod.station_unknowns
        sizes[unknown] = np.maximum(1.0, np.abs(state[3][:unknown.shape[0]]))
        sizes[rod.islot] = np.maximum(1.0, np.abs(state[4]))
        return sizes


    def warm(self, warm: Equilibrium3D) -> State | None:
        old = warm.state
        if not isinstance(old, WarmState):
            return None
        if old.rod.key != self.rod.key:
            return self.transfer(warm, old)
        self.gauge_quat = old.gauge_quat
        start = self.hold(old.state, old.friction)
        # Newton from the old state converges on one factorisation. With obstacles its
        # first step is the continuation's predictor (J du = -R at the new loads is, to
        # first order in the step, the tangent's), taken in full: judged by the
        # residual's largest entry (a probe's gap among them) it would often be refused
        # and crawl in halved steps. The corrector then keeps that factorisation while
        # it contracts. Where this fails, the continuation takes over from the start.
        state, _r, status, _ = self.newton(start, self.rod.target, strict=True,
                                           predict=True)
        if status == kernels.CONVERGED:
            self.steps += 1
            return state
        if status == kernels.SINGULAR:
            # A neutral start (a family it can drift along at no cost): the shifted
            # Newton takes the member nearest it, where the continuation's first
            # tangent could not be found.
            state = continuation.shifted_newton(self, start, self.rod.target,
                                                self.solver.tolerance)
            if state is not None:
                self.steps += 1
                return state
        try:
            return self.follow(old.rod.target, self.rod.target, start)
        except Stalled as stall:
            self.stall = stall
            return None

    def transfer(self, warm: Equilibrium3D, old: WarmState) -> State | None:
        """Start from an equilibrium of a problem with other conditions on the same mesh
        (a grip switched to force control, a second hand added at a node): positions,
        frames and internal forces carry over, a station's position multipliers come from
        its old reaction, and a damped Newton finds the nearby equilibrium."""
        rod = self.rod
        if (old.rod.s_node.shape != rod.s_node.shape or not np.allclose(old.rod.s_node,
                                                                         rod.s_node)):
            return None
        X, Q, lam = old.state[:3]
        if old.rod.frame_s.shape != rod.frame_s.shape or not np.allclose(old.rod.frame_s,
                                                                          rod.frame_s):
            Q = _frames_at(old.rod.frame_s, Q, rod.frame_s)
        nu = np.zeros(rod.m)
        loads = warm.loads
        for k, st in enumerate(rod.stations):
            v = int(rod.nu_off[k])
            for c in range(3):
                if rod.st_pos_mask[k, c]:
                    owner = st.owner[c]
                    if owner in loads:
                        nu[v] = -loads[owner].force[c] / rod.force_scale
                    v += 1
        self.gauge_quat = old.gauge_quat if rod.gauge_frame >= 0 else self.gauge_quat
        gam = old.state[4] if old.state[4].shape == rod.islot.shape else np.zeros(
            rod.islot.shape[0])
        start = self.hold((X.copy(), Q.copy(), lam.copy(), nu, gam.copy()),
                          old.friction if gam is old.state[4] else ())
        state, _, status, _ = self.newton(start, rod.target, strict=False)
        if status == kernels.CONVERGED:
            self.steps += 1
            return state
        return None


def _frames_at(old_s: np.ndarray, Q: np.ndarray, new_s: np.ndarray) -> np.ndarray:
    """Frame quaternions (F', 4) at the arc lengths ``new_s`` from frames ``Q`` (F, 4) at
    ``old_s`` on the same nodes: a frame that sits where an old one did keeps it; a frame
    a station adds at a node, between two element frames, takes their normalised mean
    (their rotation differs by one joint's bend, so the mean is within it)."""
    out = np.empty((new_s.shape[0], 4))
    for j, s in enumerate(new_s):
        i = int(np.searchsorted(old_s, s))
        if i < old_s.shape[0] and abs(old_s[i] - s) < 1e-12:
            out[j] = Q[i]
            continue
        a, b = Q[max(i - 1, 0)], Q[min(i, old_s.shape[0] - 1)]
        q = a + (b if np.dot(a, b) >= 0.0 else -b)
        out[j] = q / np.linalg.norm(q)
    return out


def _load_size(start: Loads, end: Loads, h: np.ndarray) -> tuple[float, float]:
    """How far the homotopy moves the forces and moments (dimensionless): the step
    control's wavenumber sqrt(force) + moment."""
    def follow(loads: Loads):
        return 0.0 if loads.elem_follow is None else loads.elem_follow

    moved = np.abs(follow(end) - follow(start))
    force = float(np.abs(end.fnode - start.fnode).sum(axis=0).max()
                  + np.abs(end.st_ffollow - start.st_ffollow).sum()
                  + float(np.sum(moved * h[:, None])))
    moment = float(np.abs(end.st_moment - start.st_moment).sum()
                   + np.abs(end.st_mfollow - start.st_mfollow).sum())
    return force, moment


def solve(problem: Problem, *, warm_start: Equilibrium3D | None = None,
          solver: RodSolver | None = None) -> Equilibrium3D:
    """The equilibrium of a 3D problem; see the module docstring."""
    return _solve(problem, warm_start, solver or _DEFAULT, follow_only=False)


def equilibria(problem: Problem, *, solver: RodSolver | None = None,
               budget: float = 20.0) -> list[Equilibrium3D]:
    """The distinct equilibria of a 3D problem that pliant's routes reach from the
    unloaded part within ``budget`` seconds: each route of a cold solve (straight,
    targets first then loads, a swing round the first support, loads first) and, from a
    singular start, each bow side (toward the push, away from it, and the two across).
    Stable and neutral ones first, then unstable, each group by potential energy; each
    carries a note saying how it was reached. A problem solved together (fitted parts,
    clips that slide or pivot, junctions) gets each of those routes' answers solved
    together from there (``together.equilibria``), ranked by the energy of all its
    parts."""
    if problem.dimension != 3:
        raise IllPosedProblemError("rod3d.equilibria enumerates 3D problems; this one is 2D")
    solver = solver or RodSolver()
    if problem.solved_together:
        from pliant.models.rod3d import together  # noqa: PLC0415 (it imports this module)

        return together.equilibria(problem, solver, budget)
    return continuation.best_first(reached(problem, solver, clock.now() + budget),
                                   problem.part)


def reached(problem: Problem, solver: RodSolver, deadline: float) -> list[Equilibrium3D]:
    """The distinct equilibria every route of a cold solve reaches before ``deadline``
    (``equilibria``'s, unranked, in the order reached), each with its ``ReachedBy`` note.
    Flexible parts already fitted count as rigid tubes here. With obstacles, also each
    route's answer without them that touches none of them (``_clear``): so an obstacle
    in a route's way hides no equilibrium it does not touch."""
    found: list[Equilibrium3D] = []
    rod = lower(problem, elements=solver.elements)
    for name in ("straight", "two_stage", "swing", "loads_first"):
        left = deadline - clock.now()
        if left <= 0.0:
            break
        run = Run(rod, replace(solver, time_budget=left))
        run.reached = []
        try:
            run.route(getattr(run, name))
        except Stalled:
            pass
        for state, gauge, how in run.reached:
            run.gauge_quat = gauge
            try:
                if rod.gauge_frame >= 0 and rod.K[0] != rod.K[1]:
                    state = _release_roll(run, state)
                eq = build(run, state)
            except (Stalled, IllPosedProblemError):
                continue
            route = name.replace('_', ' ')
            eq = replace(eq, notes=(ReachedBy(f"reached by the {route} route, {how}",
                                              route=route, how=how),))
            if not any(same_shape(eq, other) for other in found):
                found.append(eq)
    if solver.settle:
        found += _settled_from(found, solver, deadline)
    if problem.obstacles:
        found += [eq for eq in _clear(Run(rod, solver), deadline)
                  if not any(same_shape(eq, other) for other in found)]
    return found


def _settled_from(found: list[Equilibrium3D], solver: RodSolver, deadline: float
                  ) -> list[Equilibrium3D]:
    """The stable equilibria the unstable ones of ``found`` lead to, left along their
    unstable mode both ways (``Routes.downhill``), those not found already, each with
    its ``ReachedBy`` note."""
    out: list[Equilibrium3D] = []
    for eq in [e for e in found if e.verdict == "unstable"]:
        left = deadline - clock.now()
        if left <= 0.0:
            break
        run = Run(eq.state.rod, replace(solver, time_budget=left),
                  gauge_quat=eq.state.gauge_quat)
        for calm in downhill_equilibria(run, eq):
            if any(same_family(calm, other) for other in (*found, *out)):
                continue
            route = eq.notes[0].route if isinstance(eq.notes[0], ReachedBy) else ""
            out.append(replace(calm, notes=(ReachedBy(
                f"reached by the {route} route to an unstable equilibrium, then left along "
                "its unstable mode", route=route, how="left along its unstable mode"),)))
    return out


def _solve(problem: Problem, warm_start: Equilibrium3D | None, solver: RodSolver,
           follow_only: bool, rigid: bool = False, carry: bool = True) -> Equilibrium3D:
    """``rigid``: flexible parts already fitted (``coupled``) count as rigid tubes;
    ``carry``: a warm start whose obstacles moved may be followed with them carried
    (``carrying.carried``)."""
    if problem.dimension != 3:
        raise IllPosedProblemError("the 3D model solves 3D problems; this one is 2D "
                                   "(use pliant.solve, which picks the model)")
    if not rigid and problem.solved_together:
        from pliant.models.rod3d import together  # noqa: PLC0415

        return together.solve_fitted(problem, warm_start, solver, follow_only)
    rod = None
    if warm_start is not None and isinstance(warm_start.state, WarmState):
        rod = warm_start.state.rod.retarget(problem, solver.elements)  # skips re-meshing
    run = Run(rod or lower(problem, elements=solver.elements), solver)
    state = None
    try:
        if warm_start is not None:
            state = run.warm(warm_start)
            if state is None and carry:
                moved = carried(problem, warm_start, partial(_followed, solver=solver),
                                deadline=run.deadline)
                if moved is not None:
                    return moved
            if state is not None:
                run.notes[:0] = [n for n in warm_start.notes if isinstance(n, BranchTaken)]
            elif follow_only:
                raise run.stall or Stalled(0.0, math.inf, "the warm start could not be "
                                            "followed to this problem")
            else:
                # The part snaps where its path meets a fold: where it settles from
                # there is what a real one does (a cold solve may find another branch).
                snap = run.snapped(run.stall) if run.stall is not None else None
                run.notes.append(WarmStartLost(snap[1] if snap else WARM_START_LOST))
                state = snap[0] if snap else None
        if state is None:
            try:
                state = run.cold()
            except Stalled as stall:
                cleared = _clear_instead(run, stall) or pushed_out(
                    run, stall, partial(_followed, solver=solver))
                if cleared is None:
                    raise
                return cleared if problem.solved_together else _with_reaction_error(
                    Run(cleared.state.rod, run.solver, gauge_quat=cleared.state.gauge_quat),
                    cleared.state.state, cleared)
        if run.rod.gauge_frame >= 0 and run.rod.K[0] != run.rod.K[1]:
            state = _release_roll(run, state)
    except Stalled as stall:
        _held_inside(problem)  # the likeliest cause, named, where it is the cause
        raise ConvergenceError(
            f"no equilibrium reached: {stall.reason}; stopped at {stall.t:.3g} of the "
            f"way (relative residual {stall.residual:.2e}); {NOT_EXHAUSTIVE}; try smaller "
            "steps or check that the targets can be reached", residual=stall.residual,
            progress=stall.t,
            last_good=warm_start, status=stall.status) from None
    seed = None
    if warm_start is not None and isinstance(warm_start.state, WarmState):
        seed = warm_start.state.mode[0] if warm_start.state.mode else None
    eq = build(run, state, seed)
    if warm_start is None:
        eq, run = _lowest(run, eq)
    if run.solver.settle and not follow_only and eq.verdict == "unstable":
        eq = settled(run, eq, warm_start)
    if warm_start is None and not problem.solved_together:  # (else: the rigid first
        eq = _with_reaction_error(run, eq.state.state, eq)  # pass, solved together next)
    return eq


def _followed(problem: Problem, warm_start: Equilibrium3D | None, solver: RodSolver
              ) -> Equilibrium3D:
    """``problem`` solved warm from ``warm_start`` and followed only, or cold where it is
    None; never carried (``carrying``'s stages)."""
    return _solve(problem, warm_start, solver, warm_start is not None, carry=False)


def _lowest(run: Run, eq: Equilibrium3D) -> tuple[Equilibrium3D, Run]:
    """A cold answer in configuration space (positions held at two stations or more):
    the stable equilibrium of lowest potential energy among every route's
    (``equilibria``), not the first route's, which is kept on a tie; the note names the
    first route's. With the run the answer belongs to.

    With obstacles, the other routes run without them, and those of their answers that
    touch none of them count (``_clear``): an obstacle the lowest equilibrium does not
    touch changes nothing. Every route with the obstacles as well (what ``equilibria``
    lists) doubled that search's time and changed no answer: over 150 of the fuzz's
    problems with a ball, the answers without obstacles that touch none lowered two
    answers (by 0.012 and 0.93 J), and the search cost the cold solves 3.0 times their
    first route's time, 5.9 times with every route with the ball too; in parts solved
    together, every route with the fitted parts' contacts cost the demo's start 2.3 s."""
    rod = run.rod
    problem = rod.problem
    if (not run.solver.lowest or problem.held_stations < 2
            or not conservative(run, eq.state.state)):
        return eq, run
    deadline = run.deadline
    left = deadline - clock.now()
    if left <= 0.0:
        return eq, run
    first = potential_energy(eq)
    if problem.obstacles:
        found = _clear(run, deadline)
    else:
        found = equilibria(problem, solver=replace(run.solver, time_budget=left), budget=left)
    scale = problem.part.bending_stiffness / problem.part.length
    stable = eq.verdict != "unstable"
    better = [e for e in found if e.verdict != "unstable" and (
        not stable or potential_energy(e) < first - 1e-9 * (abs(first) + scale))]
    if not better:
        return eq, run
    best = min(better, key=potential_energy)
    energy = potential_energy(best)
    kept = [n for n in eq.notes if not isinstance(n, BranchTaken)]
    note = LowestEquilibrium(
        f"pliant took the stable equilibrium of lowest potential energy its routes "
        f"reach ({energy:.6g} J, {best.notes[0]}); the first route's has {first:.6g} J "
        f"and is {eq.verdict}", energy=energy, route_energy=first)
    chosen = replace(best, notes=(*kept, note), iterations=eq.iterations + best.iterations)
    again = Run(best.state.rod, run.solver, gauge_quat=best.state.gauge_quat)
    return chosen, again


def _clear_instead(run: Run, stall: Stalled) -> Equilibrium3D | None:
    """Where every route with the obstacles stalls (a fold as the part is pushed over
    one), the best of the routes' answers without them that touch none of them
    (``_clear``): stable before unstable, then the lowest potential energy, with a note
    that says so and names its stability; None where there is none (then the stall
    stands). Each is an equilibrium of the problem itself: an obstacle it does not
    touch changes nothing."""
    if not run.rod.problem.obstacles or clock.now() > run.deadline:
        return None
    found = _clear(run, run.deadline)
    if not found:
        return None
    energy_counts = conservative(run)
    best = min(found, key=lambda eq: (eq.verdict == "unstable",
                                      potential_energy(eq) if energy_counts else 0.0))
    energy = potential_energy(best)
    route = getattr(best.notes[0], "route", None)
    unstable = best.verdict == "unstable"
    note = LowestEquilibrium(
        f"every route with the obstacles stopped at {stall.t:.3g} of the way "
        f"({stall.reason}); pliant took the "
        f"{'' if unstable else 'stable '}equilibrium"
        f"{' of lowest potential energy' if energy_counts and not unstable else ''} that "
        f"its routes reach without them and that touches none of them ({energy:.6g} J"
        f"{f', by the {route} route' if route else ''})"
        f"{'; it is unstable, and no stable one was found' if unstable else ''}",
        energy=energy, route_energy=None)
    return replace(best, notes=(*best.notes[1:], note))


def _clear(run: Run, deadline: float) -> list[Equilibrium3D]:
    """Each route's equilibrium of ``run``'s problem without its obstacles that touches
    none of them: with a zero force on every probe it meets the contact conditions
    (each probe's gap >= 0, its force 0) and the rest of the problem's equations as it
    did, to the tolerance (checked on ``run``'s own residual, probes and sliders
    included): an equilibrium of the problem itself, built on its mesh."""
    rod = run.rod
    alone = replace(rod.problem, obstacles=())
    if alone.solved_together:
        return []
    out = []
    for eq in reached(alone, replace(run.solver, time_budget=max(deadline - clock.now(), 0.0)),
                      deadline):
        old = eq.state
        X, Q, lam, nu = old.state[:4]
        if (X.shape != (rod.s_node.shape[0], 3) or Q.shape[0] != rod.frame_s.shape[0]
                or nu.shape[0] != rod.m or not np.allclose(old.rod.s_node, rod.s_node)
                or not np.allclose(old.rod.frame_s, rod.frame_s)):
            continue  # (another mesh, where the two lowerings ever differ: a guard)
        state = (X, Q, lam, nu, np.zeros(rod.islot.shape[0]))
        there = Run(rod, run.solver, gauge_quat=old.gauge_quat)
        R, _, _ = there.residual(state, rod.target)
        r = contact_kernels.contact_max(R, there.contact(rod.target))
        if r > run.solver.tolerance:
            continue  # it passes through an obstacle (or sits in one)
        there.converged = (state, rod.target, r)  # (``build`` takes this residual)
        out.append(replace(build(there, state), notes=tuple(
            ReachedBy(f"{n}, without the obstacles, and touches none of them",
                      route=n.route, how=n.how) for n in eq.notes if isinstance(n, ReachedBy))))
    return out


def _twin(run: Run, state: State) -> tuple[int, dict[str, StationLoad], float,
                                          float] | int | None:
    """The same equilibrium on twice the elements (element count, station loads, the
    largest distance between the two neutral lines at this one's nodes, by L, and the
    largest angle between the two's material frames at this one's frames [rad]), by a
    damped Newton from this one carried over (positions and internal forces interpolated,
    frames from their neighbours): the same branch. None where there is contact (the
    touching set would have to be found again); the element count where it does not
    converge (the estimate is then unknown)."""
    rod = run.rod
    if rod.iprobe.shape[0]:
        return None
    fine = lower(rod.problem, elements=2 * rod.requested)
    if fine.m != rod.m:
        return None
    X, Q, lam, nu = state[:4]
    Xf = np.column_stack([np.interp(fine.s_node, rod.s_node, X[:, k]) for k in range(3)])
    mid, mid_f = (0.5 * (s[1:] + s[:-1]) for s in (rod.s_node, fine.s_node))
    lam_f = np.column_stack([np.interp(mid_f, mid, lam[:, k]) for k in range(3)])
    twin = Run(fine, run.solver)
    twin.gauge_quat = run.gauge_quat
    start = (Xf, _frames_at(rod.frame_s, Q, fine.frame_s), lam_f, nu.copy(),
             np.zeros(fine.islot.shape[0]))
    found, _, status, _ = twin.newton(start, fine.target, strict=False)
    if status != kernels.CONVERGED:
        return fine.elements
    back = np.column_stack([np.interp(rod.s_node, fine.s_node, found[0][:, k])
                            for k in range(3)])
    turned = np.abs(np.sum(_frames_at(fine.frame_s, found[1], rod.frame_s) * Q, axis=1))
    return fine.elements, station_loads(twin, found), float(
        np.linalg.norm(back - X, axis=1).max()), float(
        2.0 * np.arccos(np.clip(turned, -1.0, 1.0)).max())


def _with_reaction_error(run: Run, state: State, eq: Equilibrium3D) -> Equilibrium3D:
    """The answer with its reactions' discretisation error estimated, relative to the
    largest reaction, and a note where it or the shape's (relative to the part's length)
    exceeds the solver's accuracy, with the element count that would meet it.
    Richardson's rule on the same equilibrium with twice the elements: the model is
    second order, so the answer is off by about r^2 / (r^2 - 1)
    times its difference from the finer one (element ratio r); the finer twin is nearer
    the asymptotic regime than a coarser one, where a taut part's error falls slower."""
    twin = _twin(run, state)
    if twin is None:
        return eq
    if isinstance(twin, int):
        # Unknown, and said: an answer whose finer twin fails may be several per cent
        # off (issue 54), and no estimate is no word of it.
        out = replace(eq, notes=(*eq.notes, (
            f"the discretisation error is unknown: the same equilibrium on {twin} elements "
            f"did not converge, so the reactions and the shape at {run.rod.requested} "
            f"elements are not checked against a finer mesh (solve again with "
            f"RodSolver(elements={twin}) to see how far they move)")))
        out.__dict__["samples"] = eq.samples
        return out
    elements, finer, apart, turned = twin
    loads = eq.samples.loads  # as the twin's: at the stations the model holds
    ratio = elements / run.rod.elements
    factor = ratio**2 / (ratio**2 - 1.0)
    # Each block relative to the reactions' size in its units: the largest force, or
    # the largest moment over the part's length (and the force's times it), so that a
    # reaction that is zero (a rod only twisted has no force) divides nothing.
    blocks = []
    for block in (slice(0, 3), slice(3, 5)):  # forces, then moments
        held = [n for n in loads if any(loads[n].prescribed[block])]
        pairs = ([(loads[n].force, finer[n].force) for n in held] if block.start == 0
                 else [(loads[n].moment, finer[n].moment) for n in held])
        size = max((float(np.linalg.norm(a)) for a, _ in pairs), default=0.0)
        diff = max((float(np.linalg.norm(a - b)) for a, b in pairs), default=0.0)
        blocks.append((size, diff))
    length = run.rod.problem.part.length
    (force, force_diff), (moment, moment_diff) = blocks
    worst = 0.0
    for size, diff in ((max(force, moment / length), force_diff),
                       (max(moment, force * length), moment_diff)):
        if size > 0.0:
            worst = max(worst, factor * diff / size)
    notes = list(eq.notes)
    accuracy = run.solver.accuracy
    shape = factor * apart  # by L: where nothing holds it (a free end), the shape's own
    # The frames (a connector's orientation, the twist) to the same share of a turn.
    frames = factor * turned / (2.0 * math.pi)
    for error, what, them, unit, scale in (
            (worst, "the reactions may be off by about {}", "them", " %", 100.0),
            (shape, "the shape may be off by about {} of the part's length", "it", " %", 100.0),
            (frames, "the part's frames (its twist, its ends' orientation) may be off by "
             "about {}", "them", " degrees", 360.0)):
        if error > accuracy:
            need = int(math.ceil(run.rod.requested * math.sqrt(error / accuracy) / 10.0) * 10)
            size = scale * error
            said = (f"{size:.2g}" if size < 100 else f"{size:.0f}") + unit
            notes.append(f"{what.format(said)} at {run.rod.requested} elements "
                         f"(estimated from the same equilibrium "
                         f"on {elements}); about {need} elements bring {them} within "
                         f"{scale * accuracy:g}{unit} (RodSolver(elements={need}))")
    out = replace(eq, notes=tuple(notes), reaction_error=worst)
    out.__dict__["samples"] = eq.samples  # sampled already (its loads): not again
    return out


def _release_roll(run: Run, state: State) -> State:
    """A flat section that nothing holds in twist, straight at rest: its start has a free
    roll, so the solve ran with the twist gauge, which the loads must not lean on. Roll
    the gauge about the part's axis until it holds no moment (a secant on its multiplier,
    each point a Newton from the last), and keep the roll of least energy: where a root
    is a maximum of the energy (the stiff axis bent), start again a quarter turn off."""
    rod = run.rod
    base = run.gauge_quat.copy()
    loads = rod.target

    def at(phi: float, start: State):
        run.gauge_quat = qmul(base, np.array([math.cos(0.5 * phi), 0.0, 0.0,
                                               math.sin(0.5 * phi)]))
        new, _, status, energy = run.newton(start, loads, strict=False)
        return (new, float(new[3][-1]), energy) if status == kernels.CONVERGED else None

    def root(phi: float, start: State):
        first = at(phi, start)
        if first is None:
            return None
        (s0, m0, e0), p0 = first, phi
        if abs(m0) <= RELEASED:
            return p0, s0, e0
        p1 = p0 + 0.05
        for _ in range(40):
            trial = at(p1, s0)
            if trial is None:
                p1 = 0.5 * (p0 + p1)
                continue
            s1, m1, e1 = trial
            if abs(m1) <= RELEASED:
                return p1, s1, e1
            step = -m1 * (p1 - p0) / (m1 - m0) if m1 != m0 else 0.05
            p0, s0, m0 = p1, s1, m1
            p1 = p1 + max(-0.5, min(0.5, step))
        return None

    found = root(0.0, state)
    if found is not None:
        phi, s, energy = found
        lower = [at(phi + d, s) for d in (-0.05, 0.05)]
        if any(x is not None and x[2] < energy for x in lower):  # a maximum: the other axis
            other = root(phi + 0.5 * math.pi, s)
            if other is not None and other[2] < energy:
                found = other
    if found is None:
        found = _scanned_roll(at, root, state)
    if found is None:
        run.gauge_quat = base
        raise Stalled(1.0, math.inf, "the roll of the flat section that nothing holds in "
                       "twist could not be found; hold the section's orientation "
                       "(tangent and normal) somewhere", state=state, memo=base)
    phi, s, _ = found
    at(phi, s)  # the gauge where the root is, for the state and the warm starts after
    return s


RELEASED = 1e-10  # the gauge's multiplier (by EI / L) below which it holds nothing
ROLLS = 16  # rolls round a turn where the secant from the start finds no root


def _scanned_roll(at: Callable, root: Callable, state: State
                  ) -> tuple[float, State, float] | None:
    """Where the secant on the gauge's multiplier finds no root from the start (a
    Newton on its way fails, or it steps past the root: the multiplier's sign turns
    with the gauge's quaternion hemisphere, so a sign change is no bracket), the roll
    taken round a whole turn in ``ROLLS`` steps, each a Newton from the last (or from
    the start), and the secant started again from the rolls of least energy, lowest
    first: the first root found, (roll, state, energy), or None."""
    seen: list[tuple[float, float, State]] = []
    last = state
    for k in range(ROLLS):
        phi = 2.0 * math.pi * k / ROLLS
        got = at(phi, last) or at(phi, state)
        if got is not None:
            last = got[0]
            seen.append((got[2], phi, got[0]))
    for _, phi, start in sorted(seen, key=lambda x: x[0])[:3]:
        found = root(phi, start)
        if found is not None:
            return found
    return None


def _held_inside(problem: Problem) -> None:
    """Raise ``InputError`` naming the condition and the obstacle when a position the
    problem prescribes lies where the part's tube cannot be: inside an obstacle (what a
    solve that stalls most often means in a scene). Checked only once a solve failed."""
    held = [c for c in problem.conditions if c.holds_point]
    if not problem.obstacles or not held:
        return
    from pliant.scene.distance import field_of  # noqa: PLC0415

    radius = problem.part.tube_radius
    d, _, nearest = field_of(problem.obstacles).query(
        np.array([c.position for c in held]), band=radius + 1e-3)
    for c, gap, k in zip(held, d - radius, nearest):
        if gap < -1e-6:
            raise InputError(f"{c.name}.position",
                             f"the part's tube there would be {-gap * 1e3:.3g} mm inside "
                             f"the obstacle {problem.obstacles[k].name!r}; move the target "
                             "out of it")


def trace(problems: Iterable[Problem], *, start: Equilibrium3D | None = None,
          solver: RodSolver | None = None) -> Iterator[Equilibrium3D]:
    """Follow a sequence of 3D problems, warm-starting each from the last; raises
    ConvergenceError with ``last_good`` where the branch ends (a fold)."""
    solver = solver or RodSolver()
    previous = start
    for problem in problems:
        eq = _solve(problem, previous, solver, follow_only=previous is not None)
        previous = eq
        yield eq
