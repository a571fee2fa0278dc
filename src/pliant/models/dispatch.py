"""``solve`` and ``trace`` for any problem: the 2D elastica or the 3D rod, by dimension."""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Iterator
from typing import Any

from pliant.core.problem import Problem


def _model(problem: Problem):
    if problem.dimension == 3:
        from pliant.models import rod3d  # noqa: PLC0415

        return rod3d
    from pliant.models import elastica2d  # noqa: PLC0415

    return elastica2d


def solve(problem: Problem, *, warm_start: Any = None, solver: Any = None):
    """The equilibrium of a problem (``Equilibrium`` in 2D, ``Equilibrium3D`` in 3D).

    warm_start : an earlier equilibrium to start from; solver : the model's settings
    (``ShootingSolver`` in 2D, ``RodSolver`` in 3D).
    """
    return _model(problem).solve(problem, warm_start=warm_start, solver=solver)


def trace(problems: Iterable[Problem], *, start: Any = None,
          solver: Any = None) -> Iterator[Any]:
    """Follow a sequence of problems, warm-starting each from the last (see the models'
    ``trace``); a fold raises ConvergenceError with the last good equilibrium."""
    iterator = iter(problems)
    try:
        first = next(iterator)
    except StopIteration:
        return iter(())
    return _model(first).trace(itertools.chain([first], iterator), start=start, solver=solver)
