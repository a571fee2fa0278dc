"""The routes to an answer solved together (``coupled``): a part among flexible parts
already fitted, in sliding or pivoting clips, or with harness branches.

``solve_fitted`` is what ``rod3d.solve`` calls for such a problem: it solves the part
first as the single-part model does (fitted parts as rigid tubes, sliding clips holding
it where they start, branches apart), and where that answer touches a fitted part, or
the problem has clips that slide or pivot or junctions, solves the parts together from
there (``coupled.solve_coupled``), letting go what was held. A warm start solved together
is followed together. What it returns is the part's ``Equilibrium3D`` with the fitted
parts and branches as they deformed (``fitted``, ``branches``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pliant.core.equilibrium import Equilibrium3D, potential_energy
from pliant.core.events import HeldRigid, LeftUnstable, ReachedBy
from pliant.core.rotations import qconj, qmul, quat_matrix
from pliant.errors import ConvergenceError
from pliant.models import clock, continuation
from pliant.models.rod3d import coupled
from pliant.models.rod3d.coupled import Coupling, close_pairs, no_contact_forces
from pliant.models.rod3d.coupled_results import equilibria as parts_equilibria
from pliant.models.rod3d.coupled_settling import downhill
from pliant.models.rod3d.links import Joint, Pivot, Slider
from pliant.models.rod3d.lowering import Rod, State
from pliant.models.rod3d.results import WarmState
from pliant.models.rod3d.settling import jump_by_energy, where_settled
from pliant.models.rod3d.solver import RodSolver, Run, reached, same_shape, solve


@dataclass(frozen=True, eq=False)
class _TogetherState:
    """What a warm start needs of an equilibrium solved together: each part's rod and
    state (the part being fitted first), the contact forces and clips' unknowns, the
    pairs, the fitted parts and the sliding clips."""

    rods: tuple[Rod, ...]
    states: tuple
    gauges: tuple
    mus: tuple
    pairs: tuple
    fitted: tuple  # the FittedPart of each part after the first
    sliders: tuple = ()  # Slider
    joints: tuple = ()  # Joint
    junctions: tuple = ()  # the problem's Junction, to tell whether they are the same
    pivots: tuple = ()  # Pivot
    friction: tuple = ()  # between parts: (references, states, directions) by pair

    @property
    def clips(self) -> tuple:
        """The problem's SlidingClip, in order (to tell whether they are the same)."""
        return tuple(sl.clip for sl in self.sliders)

    @property
    def pins(self) -> tuple:
        """The problem's PivotClip, in order."""
        return tuple(pv.clip for pv in self.pivots)


def fitted_of(problem) -> list:
    """The obstacles of ``problem`` that are flexible parts already fitted."""
    return [o for o in problem.obstacles if getattr(o, "fitted", None) is not None]


def _held_problem(problem):
    """The problem with its sliding clips as clips that hold the part where it starts
    (the rigid answer the coupled solve starts from)."""
    from pliant.core.conditions import Condition  # noqa: PLC0415

    if not (problem.sliders or problem.junctions or problem.pivots):
        return problem  # (fitted parts only: the problem as it is, not rebuilt each step)
    held = tuple(Condition(s=c.s, name=c.name, position=c.position,
                           tangent=c.axis if c.holds_axis else None) for c in problem.sliders)
    return replace(problem, conditions=problem.conditions + held, sliders=(), junctions=(),
                   pivots=())


def _own_problem(problem, together):
    """The part's own problem in the coupled solve: without the tubes of the fitted parts
    solved with it (``together``, FittedPart; the coupling touches those; the others
    stay rigid obstacles) and with the sliding clips as free stations (the mesh keeps a
    node where each clip starts, as the held problem's)."""
    from pliant.core.conditions import Condition  # noqa: PLC0415

    free = tuple(Condition(s=c.s, name=c.name) for c in problem.sliders)
    return replace(problem, conditions=problem.conditions + free, sliders=(), junctions=(),
                   pivots=(), obstacles=tuple(o for o in problem.obstacles
                                   if getattr(o, "fitted", None) not in together))


def solve_fitted(problem, warm_start, solver: RodSolver, follow_only: bool) -> Equilibrium3D:
    """The equilibrium of a part among flexible parts already fitted (obstacles with
    ``fitted``) or in sliding clips: solved with the fitted parts' tubes as rigid
    obstacles and the sliding clips holding it where they start first; where it touches
    a fitted part, or where it has sliding clips, the parts are solved together from
    there (the fitted parts let go from held still, the clips let it slide). A warm
    start that was solved together is followed together."""
    from pliant.models.rod3d.solver import _solve  # noqa: PLC0415

    fitted = fitted_of(problem)
    if warm_start is not None and isinstance(warm_start.state, _TogetherState):
        old = warm_start.state
        present = {id(o.fitted) for o in fitted}
        if (all(id(f) in present for f in old.fitted) and problem.sliders == old.clips
                and problem.junctions == old.junctions and problem.pivots == old.pins):
            try:
                eq = _follow_together(problem, _own_problem(problem, old.fitted), old,
                                      solver, settle=solver.settle and not follow_only,
                                      warm=warm_start)
                # A fitted part held rigid that it now touches: solve again, with it.
                rigid_ones = {o.name for o in fitted} - {f.name for f in old.fitted}
                if not rigid_ones & set(eq.contacts.obstacle):
                    return eq
            except ConvergenceError:
                if follow_only:
                    raise
        warm_start = None  # the rigid solve below starts cold
    cold = warm_start is None
    rigid = _solve(_held_problem(problem), warm_start, solver, follow_only, rigid=True)
    touched = _touched(problem, rigid)
    try:
        return _from_rigid(problem, rigid, touched, solver,
                           settle=solver.settle and not follow_only, warm=warm_start)
    except ConvergenceError as err:
        if follow_only:
            raise
        names = tuple(touched + [c.name for c in problem.sliders])
        held = ", ".join(names)
        if cold:
            # Another route's answer may be solved together (the first's may lie past a
            # fold that letting the fitted parts go crosses): the best of those, where it
            # is stable (an unstable one, such as a route's answer without the obstacles
            # that touches none, is no answer a real part settles in: the rigid one is).
            found = [e for e in equilibria(problem, solver, solver.time_budget)
                     if e.verdict != "unstable"]
            if found:
                best = found[0]
                note = (f"the first route's answer could not be solved together with "
                        f"{held} ({err}); this is the best of the equilibria the other "
                        "routes lead to, solved together from there (stable first, then "
                        "the least energy of all the parts)")
                return replace(best, notes=best.notes + (note,))
        if problem.junctions:  # a harness has no answer without its branches
            raise
        # Said, not hidden: the answer is the one with those parts held still.
        note = HeldRigid(f"{held} could not be solved together with the part ({err}); "
                         "held rigid here: fitted parts at rest (their deformation and their "
                         "clamps' share of the contact not computed), sliding clips where "
                         "they start", held=names)
        return replace(rigid, problem=problem, notes=rigid.notes + (note,))


def equilibria(problem, solver: RodSolver, budget: float) -> list[Equilibrium3D]:
    """The distinct equilibria of a problem solved together that pliant's routes reach
    within ``budget`` seconds: every route's equilibrium of the part with the fitted
    parts as rigid tubes, its sliding clips held where they start and its branches apart
    (``solver.reached``), each solved together from there as ``solve_fitted`` does (one
    that touches no fitted part, in a problem with nothing else to solve together, as it
    is). Stable and neutral ones first, then by the potential energy of all the parts
    (``potential_energy``: the touched fitted parts' change included), each with a note
    saying how it was reached; one the parts cannot be solved together from is left
    out."""
    deadline = clock.now() + budget
    found: list[Equilibrium3D] = []
    for rigid in reached(_held_problem(problem), solver, deadline):
        left = deadline - clock.now()
        if left <= 0.0:
            break
        touched = _touched(problem, rigid)
        how = next(n for n in rigid.notes if isinstance(n, ReachedBy))
        try:
            eq = _from_rigid(problem, rigid, touched, replace(solver, time_budget=left))
        except ConvergenceError:
            continue
        if eq is not rigid:
            with_whom = ", ".join(touched + [f"clip {c.name}" for c in problem.sliders]
                                  + [f"junction {j.name}" for j in problem.junctions]
                                  + [f"clip {c.name}" for c in problem.pivots])
            how = ReachedBy(f"{how}, then solved together with {with_whom}",
                            route=how.route, how=f"{how.how}, solved together")
        eq = replace(eq, notes=(how, *(n for n in eq.notes if not isinstance(n, ReachedBy))))
        if not any(same_shape(eq, other) for other in found):
            found.append(eq)
    return continuation.best_first(found, problem.part)


def _touched(problem, rigid: Equilibrium3D) -> list[str]:
    """The flexible fitted parts a rigid answer (``_held_problem``'s) touches, by name."""
    return sorted(set(rigid.contacts.obstacle) & {o.name for o in fitted_of(problem)})


def _from_rigid(problem, rigid: Equilibrium3D, touched: list[str], solver: RodSolver,
                settle: bool = False, warm: Equilibrium3D | None = None) -> Equilibrium3D:
    """The problem's equilibrium from a rigid answer: that answer itself where it touches
    no fitted part and nothing else is solved together (its problem is then this one);
    else the parts solved together from it (``_start_together``: raises
    ConvergenceError where they cannot be). ``settle``: an unstable answer is left for the
    stable one the parts settle in (``_settled``), the nearest to ``warm`` where given."""
    if not (touched or problem.sliders or problem.junctions or problem.pivots):
        return rigid
    parts = [o.fitted for o in fitted_of(problem) if o.name in touched]
    return _start_together(problem, _own_problem(problem, parts), rigid, parts, solver,
                           settle, warm)


def _start_together(problem, own, rigid: Equilibrium3D, parts: list, solver: RodSolver,
                    settle: bool = False, warm: Equilibrium3D | None = None):
    """From the rigid answer: the fitted parts held still under the contact and the
    clips where they start, then let go."""
    from pliant.models.rod3d.lowering import axis_basis, lower  # noqa: PLC0415

    first = Run(lower(own, elements=solver.elements), solver)
    old = rigid.state
    assert isinstance(old, WarmState)
    X, Q, lam, _, gam = old.state
    first.gauge_quat = old.gauge_quat
    rod = first.rod
    nu = _station_multipliers(old.rod, old.state[3], rod)
    names: list[str] = []
    if old.rod.iprobe.shape[0]:
        which = Run(old.rod, solver).contacts(old.state, old.rod.target)[2]
        names = [old.rod.distance_field.obstacles[o].name if o >= 0 else "" for o in which]
    on_part = np.array([n in {p.name for p in parts} for n in names], dtype=bool)
    if rod.islot.shape[0] == old.rod.islot.shape[0] and rod.slot == old.rod.slot:
        # The same probes: keep their forces on the rigid obstacles, drop those on the
        # fitted parts' tubes (the coupling takes those).
        gam = (gam.reshape(-1, rod.slot) * ~on_part[:, None]).ravel()
    else:
        gam = np.zeros(rod.islot.shape[0])
    runs = [first]
    states = [(X.copy(), Q.copy(), lam.copy(), nu, gam.copy())]
    branches = [b for jn in problem.junctions for b in jn.branches]
    for member in branches + parts:
        runs.append(_fitted_run(member, solver))
        states.append(solved_alone(member).state.state)
    harness = 1 + len(branches)  # the part and its branches: one harness, no contact
    pairs = [replace(p, friction=parts[p.b - harness].friction)
             if p.a == 0 and p.b >= harness else p
             for p in close_pairs([r.rod for r in runs])
             if not (p.a < harness and p.b < harness)]
    joints = _joints(problem, runs, states)
    # The rigid answer's contact forces on each fitted part start the coupling's: each
    # probe's force on the nearest probe of the pair (the part is first in its pairs).
    mus = no_contact_forces(pairs)
    s_old = old.rod.s_node[old.rod.probe_elem] + old.rod.probe_a * old.rod.h[old.rod.probe_elem]
    force = old.state[4].reshape(-1, old.rod.slot)[:, 0] if old.rod.iprobe.shape[0] else \
        np.zeros(0)
    for pair, mu in zip(pairs, mus):
        if pair.a != 0:
            continue
        s_pair = rod.s_node[pair.elem] + pair.alpha * rod.h[pair.elem]
        mine = on_part & np.array([n == parts[pair.b - harness].name for n in names],
                                  dtype=bool)
        for k in np.nonzero(mine & (force > 0.0))[0]:
            mu[int(np.argmin(np.abs(s_pair - s_old[k])))] += force[k]
    # The sliding clips start where they held the part, with its reaction there.
    sliders = []
    for clip in problem.sliders:
        sliders.append(Slider(0, clip, np.asarray(clip.position) / rod.length,
                              axis_basis(np.asarray(clip.axis)), clip.s / rod.length))
        w = np.zeros(6)
        w[0] = clip.s / rod.length
        w[1:4] = -np.asarray(rigid.loads[clip.name].force) / rod.force_scale
        mus.append(w)
    mus += [np.zeros(6) for _ in joints]
    pivots = []
    for clip in problem.pivots:
        at = next(i for i, st in enumerate(rod.stations)
                  if any(c.name == clip.name for c in st.conditions))
        frame = int(rod.st_frame[at])
        pivots.append(Pivot(clip, frame, quat_matrix(states[0][1][frame])[:, 0].copy(),
                            np.asarray(clip.pivot, float)))
        mus.append(np.zeros(2))
    coupling, states, mus = coupled.solve_coupled(runs, states, solver=solver, held_first=True,
                                          pairs=pairs, mus=mus, sliders=sliders, joints=joints,
                                          pivots=pivots)
    return _result(problem, coupling, states, mus, parts, rigid.iterations, rigid.steps,
                   settle=settle, warm=warm)


def _joints(problem, runs: list[Run], states: list[State]) -> list[Joint]:
    """The problem's junctions as joints between the part (run 0) and its branches (the
    runs after it, in order), each closing from where the parts start apart."""
    from pliant.core.rotations import quat_from_matrix, rotation_between  # noqa: PLC0415

    out = []
    k = 1
    rod = runs[0].rod
    for jn in problem.junctions:
        end_a = 0 if jn.s < 0.5 * problem.part.length else rod.elements
        # The junction's frame: the part's end frame, turned so its d3 points out of it.
        flip = np.array([1.0, 0.0, 0.0, 0.0]) if end_a else np.array([0.0, 1.0, 0.0, 0.0])
        for branch in jn.branches:
            rb = runs[k].rod
            end_b = 0 if branch.end == 0 else rb.elements
            leaving = np.asarray(branch.axis, float)
            d3 = leaving if end_b == 0 else -leaving  # the branch's tangent there
            q_rel = qmul(flip, quat_from_matrix(rotation_between(np.array([0.0, 0.0, 1.0]),
                                                                  d3)))
            qa = states[0][1][rod.node_frame[end_a]]
            qb = states[k][1][rb.node_frame[end_b]]
            gap = states[k][0][end_b] * rb.length - states[0][0][end_a] * rod.length
            out.append(Joint(f"{jn.name}: {branch.name}", 0, end_a, k, end_b, q_rel, gap,
                             qmul(qconj(qa), qb)))
            k += 1
    return out


def _station_multipliers(old: Rod, nu: np.ndarray, rod: Rod) -> np.ndarray:
    """The station multipliers of ``old`` (a rod with the same stations) for ``rod``:
    station by station where their counts agree (a clip that became a free station
    has none), and the twist gauge's."""
    out = np.zeros(rod.m)
    for k in range(min(len(old.stations), len(rod.stations))):
        n = int(rod.nu_cnt[k])
        if n and n == int(old.nu_cnt[k]):
            out[rod.nu_off[k]:rod.nu_off[k] + n] = nu[old.nu_off[k]:old.nu_off[k] + n]
    if rod.gauge_frame >= 0 and old.gauge_frame >= 0:
        out[-1] = nu[-1]
    return out


def solved_alone(part) -> Equilibrium3D:
    """The equilibrium of a fitted part or harness branch (``FittedPart``, ``Branch``)
    on its own, untouched: where a solve together with it starts. Solved on first use
    and kept on the part (``part.solved``)."""
    if part.solved is None:
        object.__setattr__(part, "solved", solve(part.problem,
                                                 solver=RodSolver(elements=part.elements)))
    return part.solved


def _fitted_run(part, solver: RodSolver) -> Run:
    warm = solved_alone(part).state
    run = Run(warm.rod, replace(solver, elements=part.elements))
    run.gauge_quat = warm.gauge_quat
    return run


def _follow_together(problem, own, old: _TogetherState, solver: RodSolver,
                     settle: bool = False, warm: Equilibrium3D | None = None) -> Equilibrium3D:
    from pliant.models.rod3d.lowering import lower  # noqa: PLC0415

    rod = old.rods[0].retarget(own, solver.elements) or lower(own, elements=solver.elements)
    if rod.key != old.rods[0].key:
        raise ConvergenceError("the mesh changed", residual=math.inf)
    runs = [Run(rod, solver)] + [Run(r, solver) for r in old.rods[1:]]
    for run, gauge in zip(runs, old.gauges):
        run.gauge_quat = gauge
    start = [old.rods[0].target] + [r.target for r in old.rods[1:]]
    coupling, states, mus = coupled.solve_coupled(runs, list(old.states), solver=solver,
                                          start=start, mus=[m.copy() for m in old.mus],
                                          pairs=list(old.pairs), sliders=list(old.sliders),
                                          joints=list(old.joints), pivots=list(old.pivots),
                                          held_first=False, friction=old.friction)
    return _result(problem, coupling, states, mus, list(old.fitted), 0, 0, settle=settle,
                   warm=warm)


def _result(problem, coupling: Coupling, states, mus, parts, iterations: int,
            steps: int, *, settle: bool = False, warm: Equilibrium3D | None = None
            ) -> Equilibrium3D:
    """The part's answer with its branches and fitted parts as they deformed; where
    ``settle`` and it is unstable, the stable one the parts settle in (``_settled``)."""
    branches = [b for jn in problem.junctions for b in jn.branches]
    names = ([problem.name or problem.part.name] + [b.name for b in branches]
             + [p.name for p in parts])
    first = _assembled(problem, coupling, states, mus, parts, names)
    if settle and first.verdict == "unstable":
        first = _settled(problem, coupling, (states, mus), parts, names, first, warm)
    return replace(first, iterations=first.iterations + iterations + coupling.iterations,
                   steps=first.steps + steps + coupling.steps)


def _assembled(problem, coupling: Coupling, states, mus, parts, names: list[str]
               ) -> Equilibrium3D:
    """The part's equilibrium at (states, mus), its branches' and fitted parts' with it
    and the state a warm start follows together from."""
    # The targets before the contact forces join them as loads (for the warm starts).
    rods = tuple(run.rod for run in coupling.runs)
    gauges = tuple(run.gauge_quat.copy() for run in coupling.runs)
    branches = [b for jn in problem.junctions for b in jn.branches]
    eqs = parts_equilibria(coupling, states, mus, names)
    nb = len(branches)
    return replace(eqs[0], problem=problem,
                   state=_TogetherState(rods, tuple(states), gauges, tuple(mus),
                                        tuple(coupling.pairs), tuple(parts),
                                        tuple(coupling.sliders), tuple(coupling.joints),
                                        tuple(problem.junctions), tuple(coupling.pivots),
                                        (coupling.fric_ref, coupling.fric_mode,
                                         coupling.fric_dir)),
                   branches=tuple(replace(eq, problem=b.problem)
                                  for eq, b in zip(eqs[1:1 + nb], branches)),
                   fitted=tuple(replace(eq, problem=p.problem)
                                for eq, p in zip(eqs[1 + nb:], parts)))


def _settled(problem, coupling: Coupling, at: tuple, parts, names: list[str],
             eq: Equilibrium3D, warm: Equilibrium3D | None) -> Equilibrium3D:
    """An unstable answer of the parts together left along its unstable mode, both ways
    (``coupled_settling.downhill``), for the stable one they settle in: from a warm start
    the nearest to it (where the parts were), from rest the lowest in the energy of all
    the parts; the unstable answer itself where they settle nowhere (its verdict says
    so). Said by a ``LeftUnstable`` note. From a warm start it is taken as a jump where
    settling releases more than a tenth of the energy the step changed (the single
    part's square-root test of a bifurcation's branch is not made here)."""
    deadline = clock.now() + coupling.solver.time_budget
    found = [_assembled(problem, coupling, s, m, parts, names)
             for s, m in downhill(coupling, at[0], at[1], deadline,
                                  coupling.runs[0].rod.length)]
    found = [e for e in found if e.verdict != "unstable"]
    if not found:
        return eq
    best = where_settled(found, warm)
    released = potential_energy(eq) - potential_energy(best)
    distance = max(float(np.linalg.norm(b.position - a.position, axis=1).max())
                   for a, b in zip((eq, *eq.branches, *eq.fitted),
                                   (best, *best.branches, *best.fitted)))
    if warm is None:
        jump, how = False, "the lowest of those they settle in from there"
    else:
        jump, why = jump_by_energy(eq, warm, released)
        how = ("a jump (a snap): real parts jump here" if jump else "no jump") + f" ({why})"
    note = LeftUnstable(
        f"the equilibrium of the parts together is unstable (smallest eigenvalue "
        f"{eq.stability[1]:.3g}): they leave it along that mode and settle here "
        f"({best.verdict}), {distance:.3g} m away at most, releasing {released:.3g} J; "
        f"{how}", eigenvalue=float(eq.stability[1] or 0.0), distance=distance,
        released=released, jump=jump)
    return replace(best, notes=(*eq.notes, note))
