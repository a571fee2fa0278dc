"""``solve`` and ``trace`` for any problem: the 2D elastica or the 3D rod, by dimension.

This is the one module that knows both models, so it also holds the route between them:
a 2D problem the shooting solver refuses is the same problem in the plane z = 0 for the
3D rod, whose routes (bow sides, loads first, snaps past folds) reach equilibria the 2D
ones miss; its planar answer is then the start of the 2D Newton, and the 2D model
answers with its own accuracy.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Iterator
from dataclasses import replace
from typing import Any, Literal, overload

import numpy as np

from pliant.core.conditions import Condition
from pliant.core.equilibrium import PlanarLoad, PlanarShape, Result, Unsolved, model_loads
from pliant.core.events import PlanarRoute, WarmStartLost, has
from pliant.core.problem import Problem
from pliant.errors import ConvergenceError, IllPosedProblemError, PliantError


def _model(problem: Problem):
    if problem.dimension == 3:
        from pliant.models import rod3d  # noqa: PLC0415

        return rod3d
    from pliant.models import elastica2d  # noqa: PLC0415

    return elastica2d


PLANAR_BUDGET = 10.0  # s: the 3D route's own time budget
PLANAR_NOTE = ("found from the 3D model's equilibrium of the same problem in the plane "
               "(the 2D routes did not reach one)")


@overload
def solve(problem: Problem, *, warm_start: Any = ..., solver: Any = ...,
          throw: Literal[True] = ...) -> Result: ...
@overload
def solve(problem: Problem, *, warm_start: Any = ..., solver: Any = ...,
          throw: bool) -> Result | Unsolved: ...


def solve(problem: Problem, *, warm_start: Any = None, solver: Any = None,
          throw: bool = True) -> Result | Unsolved:
    """The equilibrium of a problem (``Equilibrium`` in 2D, ``Equilibrium3D`` in 3D).

    warm_start : an earlier equilibrium to start from; solver : the model's settings
    (``ShootingSolver`` in 2D, ``RodSolver`` in 3D). A cold 2D solve that finds nothing
    tries the route through the 3D model (see the module) before it gives up.
    throw : False returns an ``Unsolved`` (``ok`` False: why, where it stopped, the last
    good equilibrium) instead of raising pliant's typed error; an answer's ``ok`` is
    True.
    """
    if not throw:
        try:
            return _solve(problem, warm_start, solver)
        except PliantError as err:
            return Unsolved(problem, err)
    return _solve(problem, warm_start, solver)


def _solve(problem: Problem, warm_start: Any, solver: Any) -> Result:
    model = _model(problem)
    if problem.dimension == 3 or warm_start is not None:
        return model.solve(problem, warm_start=warm_start, solver=solver)
    try:
        return model.solve(problem, solver=solver)
    except ConvergenceError as refused:
        try:
            start = planar_start(problem)
            eq = model.solve(problem, warm_start=start, solver=solver)
        except PliantError:
            raise refused from None
        if has(eq.notes, WarmStartLost):  # Newton did not take the 3D answer: solved cold
            raise refused from None
        return replace(eq, notes=(*eq.notes, PlanarRoute(PLANAR_NOTE)))


def equilibria(problem: Problem, *, elements: int | None = None,
               budget: float | None = None) -> list[Result]:
    """The distinct equilibria of a problem that pliant's routes reach, within ``budget``
    seconds (the model's default where None: 5 s in 2D, 20 s in 3D): stable and neutral
    ones first, then unstable, each group by potential energy, each with a note saying
    how it was reached (``elastica2d.equilibria``, ``rod3d.equilibria``). ``elements``:
    the 3D model's resolution (100 where None). Empty when no route reaches one."""
    options: dict[str, Any] = {} if budget is None else {"budget": float(budget)}
    if problem.dimension == 2:
        from pliant.models import elastica2d  # noqa: PLC0415

        return list(elastica2d.equilibria(problem, **options))
    from pliant.models import rod3d  # noqa: PLC0415

    return list(rod3d.equilibria(problem, solver=rod3d.RodSolver(elements=elements or 100),
                                 **options))


def planar_start(problem: Problem) -> PlanarShape:
    """The 3D rod's equilibrium of a 2D problem lifted into z = 0, as the arrays a 2D
    warm start reads (s, position, angle, internal force, bending moment, loads)."""
    from pliant.models import rod3d  # noqa: PLC0415 (numba kernels: on demand)

    lifted = []
    for c in problem.conditions:
        position: tuple[float | None, ...] = ()
        if any(v is not None for v in c.position):
            position = (*c.position, 0.0)
        tangent: tuple[float, float, float] | None = None
        normal: tuple[float, float, float] | None = None
        if c.angle is not None:
            tangent, normal = (math.cos(c.angle), math.sin(c.angle), 0.0), (0.0, 0.0, 1.0)
        force: tuple = ()
        moment: tuple[float, float, float] | None = None
        if c.follower:
            # 2D (tangential, normal nu); 3D in (d1, d2, d3) with d1 = +z, d2 = -nu.
            ft, fn = (c.force[0] or 0.0), (c.force[1] or 0.0)
            force, follower = (0.0, -fn, ft), True
            if c.moment is not None:
                raise IllPosedProblemError("a follower moment in 2D: no planar route")
        else:
            follower = False
            if any(f is not None for f in c.force):
                force = (c.force[0] or 0.0, c.force[1] or 0.0, 0.0)
            if c.moment is not None:
                moment = (0.0, 0.0, float(c.moment))  # type: ignore[arg-type]  # 2D: a number
        lifted.append(Condition(s=c.s, name=c.name, position=position, force=force,
                                moment=moment, follower=follower, tangent=tangent,
                                normal=normal))
    gravity = (*(problem.gravity or (0.0, 0.0)), 0.0)
    space = Problem(problem.part, tuple(lifted), gravity, problem.name,
                    loads=tuple(replace(ld, force=(*ld.force, 0.0)) for ld in problem.distributed))
    # A route, not the answer: a coarse rod and a short budget (the 2D solve already
    # spent its own), so that a refusal still comes soon.
    eq = rod3d.solve(space, solver=rod3d.RodSolver(elements=80, time_budget=PLANAR_BUDGET))
    L = problem.part.length
    if np.abs(eq.position[:, 2]).max() > 1e-6 * L:
        raise IllPosedProblemError("the 3D answer left the plane")
    angle = np.unwrap(np.arctan2(eq.tangent[:, 1], eq.tangent[:, 0]))
    first = next((c for c in problem.conditions if c.angle is not None and c.s <= 1e-12),
                 None)
    if first is not None:
        angle += 2.0 * math.pi * round((first.angle - angle[0]) / (2.0 * math.pi))
    internal = np.column_stack([np.interp(eq.s, eq.element_s, eq.internal_force[:, i])
                                for i in range(2)])
    reactions = {name: PlanarLoad(np.asarray(ld.force[:2]), float(ld.moment[2]))
                 for name, ld in model_loads(eq).items()}
    return PlanarShape(problem, np.asarray(eq.s), eq.position[:, :2], angle, internal,
                       np.asarray(eq.internal_moment[:, 2]), reactions)


def trace(problems: Iterable[Problem], *, start: Any = None,
          solver: Any = None) -> Iterator[Result]:
    """Follow a sequence of problems, warm-starting each from the last (see the models'
    ``trace``); a fold raises ConvergenceError with the last good equilibrium."""
    iterator = iter(problems)
    try:
        first = next(iterator)
    except StopIteration:
        return iter(())
    return _model(first).trace(itertools.chain([first], iterator), start=start, solver=solver)
