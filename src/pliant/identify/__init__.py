"""Stiffness from measurements (``pliant identify``): the part's parameters that make the
accurate model reproduce a bench test, with their intervals (``fit``). Above the models,
beside ``assembly``, which it does not need: a test is a part on a bench, not an
operation in a scene."""

from pliant.errors import IdentificationError, NotIdentifiableError
from pliant.identify.fit import (
    Estimate,
    Fitted,
    Identification,
    first_guess,
    identify,
    project,
    support_force,
)

__all__ = [
    "Estimate",
    "Fitted",
    "Identification",
    "IdentificationError",
    "NotIdentifiableError",
    "first_guess",
    "identify",
    "project",
    "support_force",
]
