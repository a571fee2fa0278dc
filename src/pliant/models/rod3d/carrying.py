"""Obstacles carried in stages (issue 60): a warm start's obstacles that moved are taken
to their new poses gradually (``carried``), and a part whose unloaded shape passes
through obstacles is pushed out of them by carrying each in from outside, across the
part (``pushed_out``), where growing them back round it stalled."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pliant.core.equilibrium import Equilibrium3D, potential_energy
from pliant.core.events import PushedOut
from pliant.core.numbers import clean
from pliant.core.problem import Problem
from pliant.core.rotations import exp_map, log_map
from pliant.errors import ConvergenceError
from pliant.models import clock

if TYPE_CHECKING:
    from pliant.models.continuation import Stalled
    from pliant.models.rod3d.solver import Run
    from pliant.scene.distance import Obstacle

# Solves ``problem`` warm from an answer (None: cold), followed only (no cold fallback).
Follow = Callable[[Problem, Equilibrium3D | None], Equilibrium3D]

CARRY_STEP = 0.25  # an obstacle carried at most this many of the part's radii a stage
CARRY_MOST = 400  # stages at most for a warm start's move (beyond: not followed)
PUSH_MOST = 2000  # stages at most for an obstacle carried in round an unloaded part
CLEAR = 2.0  # an obstacle carried in starts this many of the part's radii clear of it
_SCAN = 64  # steps of the scan for the move that clears, before bisection


def carried(problem: Problem, warm_start: Equilibrium3D, follow: Follow,
            most: int = CARRY_MOST, deadline: float = math.inf) -> Equilibrium3D | None:
    """A warm start whose obstacles moved (the same ones, placed elsewhere: a drum
    raised, a part of the scene turned) followed with them: the continuation changes the
    targets and loads gradually but takes the obstacles where they now are at once, so
    a move of more than the contact's give started inside them ("the start is
    singular"). Here they are carried from their old poses to the new in stages of at
    most ``CARRY_STEP`` of the part's radius (a move of 3 mm into a 10 mm part at rest on
    a drum was singular; 2 mm was not), each solved warm from the last; None where they
    did not move, cannot be followed in ``most`` stages, or the ``deadline`` passes."""
    before, after = warm_start.problem.obstacles, problem.obstacles
    if not before or len(before) != len(after):
        return None
    for a, b in zip(before, after):
        if (a.name != b.name or a.kind != b.kind or a.mesh is not b.mesh
                or a.fitted is not None or b.fitted is not None
                or not np.array_equal(a.param, b.param)):
            return None
    if all(np.array_equal(a.translation, b.translation)
           and np.array_equal(a.rotation, b.rotation) for a, b in zip(before, after)):
        return None

    turns = [log_map(a.rotation.T @ b.rotation) for a, b in zip(before, after)]

    def between(a: Obstacle, b: Obstacle, turn: np.ndarray, t: float) -> Obstacle:
        return replace(b, translation=(1.0 - t) * a.translation + t * b.translation,
                       rotation=a.rotation @ exp_map(t * turn))

    move = max(float(np.linalg.norm(b.translation - a.translation))
               + float(np.linalg.norm(turn)) * _reach(a)
               for a, b, turn in zip(before, after, turns))
    first = max(2, math.ceil(move / (CARRY_STEP * problem.part.drawn_radius)))
    for stages in (first, 4 * first):
        if stages > most:
            return None
        previous = warm_start
        try:
            for k in range(1, stages):
                if clock.now() > deadline:
                    return None
                stage = replace(problem, obstacles=tuple(
                    between(a, b, turn, k / stages)
                    for a, b, turn in zip(before, after, turns)))
                previous = follow(stage, previous)
            return follow(problem, previous)
        except ConvergenceError:
            continue
    return None


def _reach(o: Obstacle) -> float:
    """How far [m] a point of the obstacle lies from its origin, at most (a mesh's
    corners; a primitive's sizes; 0 for a half-space, which a turn moves nowhere)."""
    if o.mesh is not None:
        return float(np.abs(o.mesh.tri).max())
    return float(np.abs(o.param).max(initial=0.0))


def pushed_out(run: Run, stall: Stalled, follow: Follow) -> Equilibrium3D | None:
    """Where every route stalled and the unloaded part passes through obstacles, the part
    pushed out of them: each such obstacle carried in (``carried``) from where it clears
    the unloaded part by ``CLEAR`` radii, moved across the part along one of four ways
    (the deepest probe's outward normal, both ways, and the normal to it and the part,
    both ways), the part solved cold there first. Growing an obstacle back round the part
    (the routes' start) pushes along the part as well as across it, and a part through
    an obstacle's middle is a symmetric problem: a drum whose axis the part crosses
    stalled there ("a fold"). The stable answer of least potential energy among the
    ways', said by a ``PushedOut`` note; None where the part is clear of its obstacles
    at rest or no way is followed (then the stall stands)."""
    rod = run.rod
    problem = rod.problem
    if rod.obstacles is None or problem.solved_together or clock.now() > run.deadline:
        return None
    _, state = rod.rest()
    points = rod.probe_points(state[0]) * rod.length
    held = np.array([c.position for c in problem.conditions if c.holds_point]).reshape(-1, 3)
    margin = rod.radius + CLEAR * problem.part.drawn_radius
    deepest, inside = math.inf, []
    normal, at = np.zeros(3), 0
    for k, o in enumerate(problem.obstacles):
        if o.fitted is not None:
            continue
        d, g = rod.obstacles.query_one(k, points, band=margin)
        if (d - rod.radius).min() < 0.0:
            inside.append(k)
            i = int(np.argmin(d))
            if d[i] < deepest:
                deepest, normal, at = float(d[i]), g[i], i
    if not inside:
        return None
    ways = _ways(points, at, normal)
    found: list[tuple[Equilibrium3D, np.ndarray, float]] = []
    for way in ways:
        moves = [_clearing_move(rod.obstacles.query_one, k, points, held, way, margin,
                                _size(points, problem.obstacles[k]))
                 for k in inside]
        if any(m is None for m in moves) or clock.now() > run.deadline:
            continue
        away = list(problem.obstacles)
        for k, m in zip(inside, moves):
            away[k] = replace(away[k], translation=away[k].translation - m * way)
        try:
            start = follow(replace(problem, obstacles=tuple(away)), None)
        except ConvergenceError:
            continue
        eq = carried(problem, start, follow, most=PUSH_MOST, deadline=run.deadline)
        if eq is not None:
            found.append((eq, way, max(m for m in moves if m is not None)))
    if not found:
        return None
    best = min(found, key=lambda f: (f[0].verdict == "unstable", potential_energy(f[0])))
    eq, way, move = best
    energy = potential_energy(eq)
    others = [potential_energy(f[0]) for f in found if f is not best]
    scale = problem.part.bending_stiffness / problem.part.length
    twin = any(abs(e - energy) <= 1e-6 * (abs(energy) + scale) for e in others)
    names = ", ".join(repr(problem.obstacles[k].name) for k in inside)
    side = ", ".join(f"{c:.3g}" for c in clean(way))
    tried = (f"the stable one of least potential energy ({energy:.6g} J) of the "
             f"{len(found)} ways across the part that were followed"
             f"{'; its mirror twin has the same energy' if twin else ''}"
             if eq.verdict != "unstable" else "unstable: no way gave a stable one")
    note = PushedOut(
        f"the unloaded part passes through {names} ({(rod.radius - deepest) * 1e3:.3g} mm "
        f"deep), and every route that grows the obstacles back round it stopped at "
        f"{stall.t:.3g} of the way ({stall.reason}); pliant carried them in from "
        f"{move:.3g} m away instead, pushing the part toward ({side}): {tried}; other "
        "equilibria may exist", obstacles=tuple(problem.obstacles[k].name for k in inside),
        side=tuple(float(c) for c in way), move=move, energy=energy,
        other_energies=tuple(others), twin=twin)
    return replace(eq, notes=(*eq.notes, note))


def _ways(points: np.ndarray, at: int, normal: np.ndarray) -> list[np.ndarray]:
    """Four unit vectors across the part at probe ``at``: the obstacle's outward
    ``normal`` there (its part across the part), both ways, and the normal to it and the
    part, both ways. Where the normal runs along the part or is undefined (the probe on a
    drum's axis), the world axis least along the part stands for it."""
    i0, i1 = max(at - 1, 0), min(at + 1, points.shape[0] - 1)
    tangent = points[i1] - points[i0]
    tangent /= max(float(np.linalg.norm(tangent)), 1e-300)
    across = normal - np.dot(normal, tangent) * tangent
    if not np.all(np.isfinite(across)) or np.linalg.norm(across) < 0.5:
        axis = np.eye(3)[int(np.argmin(np.abs(tangent)))]
        across = axis - np.dot(axis, tangent) * tangent
    n = across / np.linalg.norm(across)
    b = np.cross(tangent, n)
    return [n, -n, b, -b]


def _size(points: np.ndarray, o: Obstacle) -> float:
    """How far an obstacle may have to move to clear the part at most [m]: the part's
    extent and the obstacle's, each twice over."""
    return 2.0 * (float(np.ptp(points, axis=0).max()) + _reach(o))


def _clearing_move(query, k: int, points: np.ndarray, held: np.ndarray, way: np.ndarray,
                   margin: float, most: float) -> float | None:
    """The least distance [m] (to 1e-6 of ``most``) that obstacle ``k`` moved against
    ``way`` keeps ``margin`` from every probe and held point (a scan of ``_SCAN`` steps,
    then bisection); None where no move up to ``most`` does. A point p against the
    obstacle moved by -m way is the point p + m way against the obstacle in place."""
    if not math.isfinite(most) or most <= 0.0:
        return None
    both = np.vstack([points, held])

    def clear(m: float) -> bool:
        d, _ = query(k, both + m * way, band=margin)
        return bool(d.min() >= margin)

    lo = 0.0
    for j in range(1, _SCAN + 1):
        hi = most * j / _SCAN
        if clear(hi):
            break
        lo = hi
    else:
        return None
    while hi - lo > 1e-6 * most:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if clear(mid) else (mid, hi)
    return hi
