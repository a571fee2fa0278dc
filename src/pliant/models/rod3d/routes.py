"""The 3D model's routes to an equilibrium from the unloaded part (``Routes``, a
part of ``solver.Run``): straight, targets first then loads, a swing round the first
support, loads first; from a singular start each bow side; past a fold, a snap by
relaxation pushed along the fold's null vector so that it cannot stall at a saddle."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING, cast

import numpy as np

from pliant.core.equilibrium import potential_energy
from pliant.core.events import BranchTaken, Event, NoStableBranch, Snapped, Status
from pliant.core.numbers import clean
from pliant.core.rotations import quat_matrix
from pliant.models import clock, continuation
from pliant.models.continuation import Candidate, Stalled, first_route, ranked
from pliant.models.rod3d.lowering import Loads, Rod, State
from pliant.models.rod3d.results import probe
from pliant.models.rod3d.stability import conservative, stability_of

if TYPE_CHECKING:
    from pliant.models.rod3d.solver import RodSolver, Run


_BRANCH_NOTE = "the unloaded part was a singular start"
SWING = 0.01  # of the first leg: the load under which a part free to turn is let settle
SWING_STRIDE = 0.01  # L: a held point's move a stage as it settles on, free to turn


class Routes:
    """The routes, as ``solver.Run`` has them (its rod, settings, continuation and
    Newton)."""

    rod: Rod
    solver: RodSolver
    iterations: int
    notes: list
    deadline: float
    reached: list | None

    if TYPE_CHECKING:  # Run's: the driver's settings
        @property
        def stepping(self) -> continuation.Stepping: ...

    # -- routes ---------------------------------------------------------------------------
    def cold(self) -> State:
        """Try the routes in turn (``continuation.first_route``); past a fold on all,
        look beyond it; else raise the furthest stall."""
        try:
            return first_route([partial(self.route, legs) for legs in (
                self.straight, self.two_stage, self.swing, self.loads_first)],
                self.notes, self.deadline)
        except Stalled as best:
            if best.budget:
                raise
            return self.beyond_fold(best)

    def route(self, legs: Callable[[Loads], list[Loads]]) -> State:
        """Follow the legs from the rest state to the problem. A singular start (an end
        pushed along the straight part: it may buckle to any side) runs the whole route
        on a part bowed toward the side the targets and loads push it to, and a last leg
        removes the bow."""
        rod, opts = self.rod, self.solver
        rest, state = rod.rest()
        self.gauge_quat = state[1][max(rod.gauge_frame, 0)].copy()
        straight: tuple[State, np.ndarray] | None = None
        try:
            found = self.through(rest, legs(rest), state)
            if self.reached is not None:
                self.reached.append((found, self.gauge_quat.copy(), "the straight branch"))
            # An extensible part's start is not singular: its chord shortens by
            # compression, and the route stays on the straight branch past buckling.
            run = cast("Run", self)
            if rod.K[3] == 0.0 or not conservative(run, found) or stability_of(run, found)[0]:
                return found
            straight = (found, self.gauge_quat)
        except Stalled as stall:
            if not stall.singular_start:
                # A start free to turn whose tangent rounding let through: singular at
                # once, a hair along the way.
                if (stall.status == Status.SINGULAR and stall.t < SWING and not stall.budget
                        and rod.K[3] == 0.0):
                    swung = self.swung(legs, rest, state)
                    if swung is not None:
                        return swung
                raise
        self.branch_note = _BRANCH_NOTE if straight is None else (
            f"{_BRANCH_NOTE} for the inextensible part; this one shortens, and its straight "
            "equilibrium is unstable")
        side, chord, (a, b) = _bow_direction(rod, rest, state)
        # A bow b cos(2 pi u) over a span w shortens its chord by w (b w)^2 / 16 pi^2; make
        # that most of what the targets ask, as in 2D.
        width = b - a
        wanted = opts.bow * _shortening(rod, rest)
        amplitude = min(40.0, max(0.01, 4.0 * math.pi / width * math.sqrt(wanted / width)))
        mids = 0.5 * (rod.frame_s[:-1] + rod.frame_s[1:])
        inside = (mids >= a) & (mids <= b)
        shape = amplitude * np.cos(2 * math.pi * (mids[inside] - a) / width)[:, None]
        across = np.cross(chord, side)
        # The side the targets and loads push it to first; if that branch meets a fold,
        # the opposite side, then the two across.
        best: Stalled | None = None
        unstable: tuple[State, np.ndarray, np.ndarray] | None = None
        stable: list[tuple[State, np.ndarray, np.ndarray, float]] = []
        sides = []
        for bow_side in (side, -side, across, -across):
            # Bending about chord x side turns the tangent toward the side; in the rest
            # frames (the straight part has one frame throughout).
            axis = quat_matrix(state[1][0]).T @ np.cross(chord, bow_side)
            bowed_k0 = rod.rest_k0.copy()
            bowed_k0[inside] += shape * axis[None, :]
            sides.append((bow_side, bowed_k0, rod.rest(bowed_k0)))
        # A bow into an obstacle starts inside it (the obstacle then grows back round the
        # part, dragging it over its edges): the sides that keep clear come first.
        sides.sort(key=lambda c: c[2][0].offset > 0.0)
        for bow_side, bowed_k0, (rest_b, bowed) in sides:
            self.gauge_quat = bowed[1][max(rod.gauge_frame, 0)].copy()
            targets = [replace(leg, joint_k0=bowed_k0) for leg in legs(rest_b)] + [rod.target]
            try:
                found = self.through(rest_b, targets, bowed)
            except Stalled as stall:
                if best is None or stall.t > best.t:
                    best = stall
                if stall.budget:
                    break
                continue
            if self.reached is not None:
                self.reached.append((found, self.gauge_quat.copy(),
                                     f"bowed toward {np.round(bow_side, 3).tolist()}"))
            # An unstable branch is not where a real part settles: try the other sides
            # for a stable one (for conservative loads, where stability is defined).
            if not conservative(cast("Run", self)):
                self._bow_note(bow_side, "where its targets and loads push it" if bow_side
                               is side else "as the side its targets and loads push it to "
                               "gives no branch")
                return found
            if not stability_of(cast("Run", self), found)[0]:
                if unstable is None:
                    unstable = (found, bow_side, self.gauge_quat)
                continue
            stable.append((found, bow_side, self.gauge_quat,
                           potential_energy(probe(cast("Run", self), found))))
            if len(stable) == 2 and self.reached is None:
                break
        if stable:
            # The lowest stable branch (``continuation.ranked``); the side the targets
            # push to keeps a tie (mirror twins).
            part = rod.problem.part
            first = stable[0]
            chosen = ranked([Candidate(True, c[3], c) for c in stable],
                            part.bending_stiffness / part.length)[0].item
            found, bow_side, self.gauge_quat, energy = chosen
            if chosen is first and first[1] is side:
                why = "where its targets and loads push it"
            elif chosen is first:
                why = "as the side its targets and loads push it to gives no stable branch"
            else:
                why = (f"whose potential energy {energy:.6g} J is below the "
                       f"{first[3]:.6g} J of the side its targets and loads push it to")
            self._bow_note(bow_side, why)
            return found
        if unstable is not None:
            found, bow_side, self.gauge_quat = unstable
            self._bow_note(bow_side, "the only branch found, and it is unstable")
            return found
        if straight is not None:
            found, self.gauge_quat = straight
            self.notes.append(NoStableBranch(
                "the straight equilibrium of this compressed part is unstable, and no route "
                "to a buckled one converged"))
            return found
        assert best is not None
        if straight is None and best.singular_start and not best.budget:
            swung = self.swung(legs, rest, state)
            if swung is not None:
                return swung
        raise best

    def swung(self, legs: Callable[[Loads], list[Loads]], rest: Loads, state: State
              ) -> State | None:
        """A start no bow makes regular: the unloaded part turns at no cost (a curved
        part held by two pins turns about their chord), so the path's tangent is
        undefined on every side. Under the first ``SWING`` of the route's first leg the
        part is let settle (``settle``: the relaxation swings it to where that load
        holds it, as a real part swings when let go), then followed on; said. None
        where it does not settle or the route stalls from there."""
        targets = legs(rest)
        first = rest.lerp(targets[0], SWING)
        settled = self.settle(state, first)
        if settled is None:
            return None
        how = "then followed on"
        try:
            found = self.through(first, targets, settled)
        except Stalled as stall:
            if stall.budget or not stall.singular_start:
                return None
            # Free to turn all the way (no load holds the turn: a weightless part between
            # two pins is a family of equilibria): let it settle in stages instead.
            try:
                found, count = self.settled_along(Stalled(
                    0.0, math.inf, stall.reason, state=settled, loads=first,
                    memo=self.gauge_quat.copy()), SWING_STRIDE)
            except Stalled:
                return None
            how = f"then let settle as the load goes on, in {count} stages"
        if self.reached is not None:
            self.reached.append((found, self.gauge_quat.copy(),
                                 "let settle under the first load, free to turn"))
        self.notes.append(Event(
            "the unloaded part is free to turn (a mechanism: held where it can turn at no "
            f"cost, e.g. a curved part between two pins); pliant let it settle under the "
            f"first {SWING:.0%} of the load, where that load holds it, {how}; other "
            "equilibria may exist"))
        return found

    def _bow_note(self, side: np.ndarray, why: str) -> None:
        self.notes.append(BranchTaken(
            f"{self.branch_note} (a bifurcation: it can buckle to any side); pliant took the "
            f"branch that bows toward ({', '.join(f'{c:.3g}' for c in clean(side))}), {why}; "
            "other equilibria may exist", side=tuple(float(c) for c in side)))

    def through(self, start: Loads, targets: list[Loads], state: State) -> State:
        """Follow the homotopies start -> targets[0] -> targets[1] -> ...
        (``continuation.through``)."""
        return continuation.through(cast("Run", self), start, targets, state,
                                    self.stepping, self.deadline)

    def straight(self, rest: Loads) -> list[Loads]:
        """Loads and targets together: positions along straight lines, orientations along
        the shortest arcs."""
        return [self.rod.target]

    def two_stage(self, rest: Loads) -> list[Loads]:
        """Targets first, with no load; then the loads."""
        t = self.rod.target
        zeros = np.zeros_like(t.st_moment)
        placed = Loads(np.zeros_like(t.fnode), t.st_pos, t.st_tangent, t.st_quat, zeros,
                       zeros, zeros, t.joint_k0, rest.turn)
        return [placed, t]

    def loads_first(self, rest: Loads) -> list[Loads]:
        """Loads first, with the held points where the rest shape has them; then the
        targets."""
        t = self.rod.target
        loaded = Loads(t.fnode, rest.st_pos, rest.st_tangent, rest.st_quat, t.st_moment,
                       t.st_ffollow, t.st_mfollow, t.joint_k0, rest.turn,
                       elem_follow=t.elem_follow)
        return [loaded, t]

    def swing(self, rest: Loads, legs: int = 8) -> list[Loads]:
        """Carry the held points round the first one along arcs (their distance from it
        and their bearing, turned about one axis, move linearly), as a hand would,
        instead of along straight lines that may sweep through the first support."""
        rod = self.rod
        ends = _chord(rod)
        if ends is None:
            raise Stalled(0.0, math.inf, "nothing to swing around", status=Status.NO_ROUTE)
        pivot = ends[0]
        located = [k for k in range(rod.st_kind.shape[0])
                   if rod.st_pos_mask[k].all() and k != pivot]
        arcs: list[tuple[np.ndarray, float, float, np.ndarray, float] | None] = []
        for k in located:
            a = rest.st_pos[k] - rest.st_pos[pivot]
            b = rod.target.st_pos[k] - rod.target.st_pos[pivot]
            ra, rb = float(np.linalg.norm(a)), float(np.linalg.norm(b))
            if ra < 1e-12 or rb < 1e-12:
                arcs.append(None)
                continue
            normal = np.cross(a, b)
            if np.linalg.norm(normal) < 1e-9 * ra * rb:  # collinear: any axis across a
                normal = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
            normal /= np.linalg.norm(normal)
            angle = math.atan2(float(np.dot(np.cross(a, b), normal)), float(np.dot(a, b)))
            arcs.append((a / ra, ra, rb, normal, angle))

        def at(t: float) -> Loads:
            loads = rest.lerp(rod.target, t)
            pos = loads.st_pos.copy()
            for k, arc in zip(located, arcs):
                if arc is None:
                    continue
                u, ra, rb, normal, angle = arc
                turn = t * angle
                direction = (u * math.cos(turn) + np.cross(normal, u) * math.sin(turn)
                             + normal * np.dot(normal, u) * (1 - math.cos(turn)))
                pos[k] = pos[pivot] + ((1 - t) * ra + t * rb) * direction
            return replace(loads, st_pos=pos)

        return [at(i / legs) for i in range(1, legs)] + [rod.target]

    def beyond_fold(self, stall: Stalled, snaps: int = 4) -> State:
        """Every route met a fold: a part loaded that way snaps through there. Follow
        what it does: just past the fold, let it settle by a pseudo-transient relaxation
        (an implicit gradient flow under the constraints) from the last state before the
        fold, then go on along the route; up to ``snaps`` times. Where that cannot go on
        (it does not settle just past the fold, or snaps again and again), let it
        settle as the targets move on to the problem's in stages (``settle_on``). Say
        so."""
        at: list[float] = []
        while True:
            if (stall.state is None or stall.loads is None or stall.memo is None
                    or not stall.ahead or len(at) >= snaps):
                return self.settle_on(stall, at)
            at.append(stall.t)
            self.gauge_quat = stall.memo
            end, *rest = stall.ahead
            past = stall.loads.lerp(end, min(1.0, max(1e-3, 10.0 * self.solver.min_step)))
            state = self.settle(stall.state, past)
            if state is None:
                return self.settle_on(stall, at[:-1])
            try:
                state = self.through(past, [end, *rest], state)
            except Stalled as again:
                stall = again
                continue
            times = "once" if len(at) == 1 else f"{len(at)} times"
            self.notes.append(Snapped(
                f"every path from the unloaded part meets a fold: loaded along it, the part "
                f"snaps through ({times}, first at {at[0]:.3g} of the way); this is the "
                "equilibrium it reaches after the snap, found by letting it settle (a "
                "pseudo-transient relaxation) and following on: other equilibria may exist",
                at=float(at[0]), count=len(at)))
            return state

    def settle_on(self, stall: Stalled, at: list[float]) -> State:
        """Every route met a fold it cannot follow: where the part settles as the
        targets move on from the last state before it (``settled_along``). In 2,000
        random 3D problems it answered 13 of the 15 that every route and the snap left
        unsolved, each stable and in balance. Raises the stall where it does not
        settle."""
        state, count = self.settled_along(stall)
        first = at[0] if at else stall.t
        self.notes.append(Snapped(
            f"every path from the unloaded part meets a fold (first at {first:.3g} of the "
            f"way): loaded along it, the part snaps through; this is the equilibrium it "
            f"settles in as the targets move on from the last state before the fold at "
            f"{stall.t:.3g} (a pseudo-transient relaxation in {count} stages): other "
            "equilibria may exist", at=float(first), count=len(at) + 1))
        return state

    def snapped(self, stall: Stalled) -> tuple[State, str] | None:
        """A warm start whose path to this problem met a fold (the part snaps through
        there, as a real one would): where it settles from the last state before the
        fold (``settled_along``), with the words that say so; None where it does not
        settle (the solve then starts from the unloaded part, with at least three
        quarters of the time left: this may take no more than a quarter)."""
        deadline = self.deadline
        self.deadline = min(deadline, clock.now() + 0.25 * max(deadline - clock.now(), 0.0))
        try:
            state, count = self.settled_along(stall)
        except Stalled:
            return None
        finally:
            self.deadline = deadline
        return state, (
            f"the warm start could not be followed to this problem: at {stall.t:.3g} of "
            "the way its path meets a fold and the part snaps through; this is where it "
            f"settles from there (a pseudo-transient relaxation in {count} "
            f"stage{'s' if count > 1 else ''})")

    def settled_along(self, stall: Stalled, stride: float = 0.02) -> tuple[State, int]:
        """From the last state before a fold, the targets and loads moved on to the
        problem's in stages small enough for the relaxation (``stages``), the part let
        settle at each (``settle``: stable or neutral, pushed off any saddle): a relaxed
        continuation, which a Newton corrector cannot do past the fold. (state, stages);
        raises the stall where a stage does not settle."""
        if stall.state is None or stall.loads is None:
            raise stall
        if stall.memo is not None:
            self.gauge_quat = stall.memo
        count = stages(stall.loads, self.rod.target, stride)
        state = stall.state
        for k in range(1, count + 1):
            settled = self.settle(state, stall.loads.lerp(self.rod.target, k / count))
            if settled is None:
                raise stall
            state = settled
        return state, count

    def downhill(self, state: State, loads: Loads | None = None) -> list[State]:
        """An unstable equilibrium (of the problem, or of ``loads`` on the way to it)
        left along its unstable mode, one way then the other (pushed as
        ``continuation.settle`` pushes off a saddle): the stable or neutral equilibria the
        part settles in, one per way that settles."""
        run = cast("Run", self)
        loads = self.rod.target if loads is None else loads
        mode = run.unstable_mode(state, loads)
        if mode is None:
            return []
        du = mode * (continuation.PUSH / max(float(np.abs(mode).max()), 1e-300))
        found = []
        for sign in (1.0, -1.0):
            settled = self.settle(run.step(state, sign * du, 1.0), loads)
            if settled is not None:
                found.append(settled)
        return found

    def settle(self, state: State, loads: Loads) -> State | None:
        """Let the part settle past a fold (``continuation.settle``: a relaxation pushed
        along a saddle's unstable mode)."""
        return continuation.settle(cast("Run", self), state, loads)


def stages(start: Loads, end: Loads, stride: float = 0.02, turn: float = 0.1) -> int:
    """How many stages take the targets from ``start`` to ``end`` with each held point
    moving at most ``stride`` (of the part's length: the relaxation's own step,
    ``continuation.relax``), each held axis or frame turning at most ``turn`` rad and each rest
    curvature changing by at most 1 / L (a route's bow let go): a stage's constraints
    then ask no longer a move than the relaxation takes. At most 400."""
    move = float(np.abs(end.st_pos - start.st_pos).max(initial=0.0))
    cos = np.clip(np.einsum("ij,ij->i", start.st_tangent, end.st_tangent), -1.0, 1.0)
    angle = float(np.arccos(cos).max(initial=0.0))
    # A held orientation also turns about its axis (a clamp twisted): its quaternion's
    # angle, where both ends of the stage hold one.
    held = ((np.linalg.norm(start.st_quat, axis=1) > 0.5)
            & (np.linalg.norm(end.st_quat, axis=1) > 0.5))
    if held.any():
        dot = np.abs(np.einsum("ij,ij->i", start.st_quat[held], end.st_quat[held]))
        angle = max(angle, float((2.0 * np.arccos(np.clip(dot, 0.0, 1.0))).max()))
    bend = float(np.abs(end.joint_k0 - start.joint_k0).max(initial=0.0))
    return min(400, max(1, math.ceil(max(move / stride, angle / turn, bend))))


def _chord(rod: Rod) -> tuple[int, int] | None:
    located = [k for k in range(rod.st_kind.shape[0]) if rod.st_pos_mask[k].all()]
    return (located[0], located[-1]) if len(located) >= 2 else None


def _shortening(rod: Rod, rest: Loads) -> float:
    ends = _chord(rod)
    if ends is None:
        return 0.0
    a, b = ends
    have = float(np.linalg.norm(rest.st_pos[b] - rest.st_pos[a]))
    want = float(np.linalg.norm(rod.target.st_pos[b] - rod.target.st_pos[a]))
    return max(0.0, have - want)


def _bow_direction(rod: Rod, rest: Loads, state: State):
    """The side (a unit vector normal to the rest chord) the targets' motion and the
    loads push the part to, the chord's direction and its span (s_a, s_b)."""
    X, Q = state[0], state[1]
    ends = _chord(rod)
    if ends is not None:
        a, b = ends
        chord = rest.st_pos[b] - rest.st_pos[a]
        span = (float(rod.s_node[rod.st_node[a]]), float(rod.s_node[rod.st_node[b]]))
    else:
        chord = X[-1] - X[0]
        span = (0.0, 1.0)
    chord = chord / max(float(np.linalg.norm(chord)), 1e-300)
    push = np.zeros(3)
    for k in range(rod.st_kind.shape[0]):
        moved = np.where(rod.st_pos_mask[k] == 1, rod.target.st_pos[k] - rest.st_pos[k], 0.0)
        push += moved
    width = span[1] - span[0]
    push += rod.target.fnode.sum(axis=0) * width**3 / 48.0
    side = push - np.dot(push, chord) * chord
    if np.linalg.norm(side) < 1e-12:
        # Nothing says: bend about the weaker section axis (a strip bows flatwise; an
        # isotropic part bows toward d2, in the plane normal to d1, as the 2D model does).
        frame = quat_matrix(Q[0])
        weak, other = (0, 1) if rod.K[0] <= rod.K[1] else (1, 0)
        side = frame[:, other] - np.dot(frame[:, other], chord) * chord
        if np.linalg.norm(side) < 1e-12:
            side = frame[:, weak]
    return side / np.linalg.norm(side), chord, span
