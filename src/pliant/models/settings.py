"""Checks of the solvers' settings (``ShootingSolver``, ``RodSolver``): a count below one
or a tolerance of zero would otherwise come back as "no equilibrium", which sends the
user after the wrong cause."""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

from pliant.errors import InputError

MAX_ELEMENTS = 100_000  # beyond this a solve runs for hours: a typo, not a request


def check(config: Any, fractions: tuple[str, ...] = ()) -> None:
    """Every bool field a bool, every int field a whole number >= 1 (``elements`` from 4 to
    MAX_ELEMENTS), every
    float field finite and positive, those in ``fractions`` below 1 too; InputError
    naming the setting otherwise."""
    kind = type(config).__name__
    for f in fields(config):
        value = getattr(config, f.name)
        name = f"{kind}.{f.name}"
        if f.type in (bool, "bool"):
            if not isinstance(value, bool):
                raise InputError(name, f"must be true or false, got {value!r}")
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(name, f"must be a number, got {value!r}")
        if f.type in (int, "int"):
            low = 4 if f.name == "elements" else 1
            high = MAX_ELEMENTS if f.name == "elements" else math.inf
            if value != int(value) or not low <= value <= high:
                raise InputError(name, f"must be a whole number from {low}"
                                       + (f" to {high:,}" if high < math.inf else " up")
                                       + f", got {value!r}")
        elif not math.isfinite(value) or value <= 0.0 or (f.name in fractions
                                                          and value >= 1.0):
            raise InputError(name, "must be a finite number above 0"
                                   + (" and below 1" if f.name in fractions else "")
                                   + f", got {value!r}")
