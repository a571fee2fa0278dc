"""Round-off shown as what it is: zero.

A solver's answer carries components that should vanish but come out as 1e-17 or
6e-109 (a force along an axis nothing pushes along, a twist nothing applies). Printed or
written, they read as tiny real values. ``clean`` sets a component to 0 where it lies
below ``ROUND_OFF`` of the larger of its vector's size and a physical scale (the
problem's force EI / L^2, moment EI / L or length L): real small values stay.
"""

from __future__ import annotations

from collections.abc import Iterable

ROUND_OFF = 1e-9

# What a clearance resolves [m]: it is sampled on chords of the discretised neutral line,
# which over a curved obstacle beside a contact read a micrometre or two; a gap below
# this is touching, shown as 0 everywhere (the terminal, the page, the files, studies).
TOUCHING = 1e-5


def shown_clearance(gap: float, allowed: float = 0.0) -> float:
    """A clearance [m] as every output shows it: 0 (touching) from ``-allowed`` (the
    overlap the contact model allows) up to ``TOUCHING``, else as it is (negative:
    inside the obstacle)."""
    return 0.0 if -allowed <= gap < TOUCHING else float(gap)


def clean(values: Iterable[float], scale: float = 0.0) -> list[float]:
    """The components as floats, those below ROUND_OFF of max(|vector|, scale) as 0."""
    v = [float(x) for x in values]
    floor = ROUND_OFF * max(max((abs(x) for x in v), default=0.0), abs(scale))
    return [0.0 if abs(x) <= floor else x for x in v]


def triple(values: Iterable[float]) -> tuple[float, float, float]:
    """Three components as a typed 3-vector of floats (a position, force or moment)."""
    x, y, z = (float(v) for v in values)
    return (x, y, z)
