"""The scale a problem's loads bend its part on, for both accurate models: loads that
would bend it in layers far thinner than its length are a unit slip or a typo (N for
kN, EI in N mm^2, 1e38), refused by name before any work."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any, NoReturn

from pliant.errors import InputError

Term = tuple[float, str, str]  # (k L, the field that makes it, in words)


def scale_terms(problem: Any, station_terms: Callable[[Any, str], Iterable[Term]]
                ) -> list[Term]:
    """Each load's k L: sqrt(F L^2 / EI) for a force, M L / EI for a moment: the weight
    and distributed loads, each station's (``station_terms(station, its name)``) and the
    rest curvature's kappa L."""
    part = problem.part
    length, stiffness = part.length, part.bending_stiffness
    weight = math.hypot(*problem.dead_load_per_length) if problem.dead_load_per_length else 0.0
    terms = [(math.sqrt(weight * length**3 / stiffness), "part.mass_per_length",
              "the part's weight and distributed loads")]
    for ld in problem.partial_loads:
        a, b = ld.span(length)
        total = math.hypot(*ld.force) * (b - a)
        terms.append((math.sqrt(total * length**2 / stiffness), f"{ld.name}.force",
                      f"a distributed load of {total:.3g} N in all"))
    for st in problem.stations:
        name = "/".join(c.name for c in st.conditions) or f"s = {st.s:g} m"
        terms += station_terms(st, name)
    curvature = max((abs(k) for _, k in part.rest_knots), default=0.0)
    terms.append((curvature * length, "part.rest_curvature",
                  f"a rest curvature of {curvature:.3g} 1/m"))
    return terms


def force_terms(force: float, moment: float, name: str, length: float,
                stiffness: float) -> list[Term]:
    """A station's force's and moment's k L."""
    return [(math.sqrt(force * length**2 / stiffness), f"{name}.force",
             f"a force of {force:.3g} N"),
            (moment * length / stiffness, f"{name}.moment", f"a moment of {moment:.3g} N m")]


def refuse(problem: Any, terms: list[Term], wave: float, limit: float) -> NoReturn:
    """The ``InputError`` naming the largest term's field (the stiffness where it is
    vanishing or a term is not finite)."""
    part = problem.part
    length, stiffness = part.length, part.bending_stiffness
    size, field, what = max(terms, key=lambda t: t[0] if math.isfinite(t[0]) else math.inf)
    if stiffness < 1e-12 or not math.isfinite(size):
        field = "part.bending_stiffness"
    raise InputError(field, f"{what} on a part of bending stiffness {stiffness:.3g} N m^2 and "
                     f"length {length:.3g} m bends it on a scale of {1.0 / max(wave, 1e-300):.2g} "
                     f"of its length (k L = {wave:.3g}, beyond {limit:g}): check the units "
                     "(N, not kN; N m^2, not N mm^2); a part that slack is a string, outside "
                     "what the accurate model resolves")
