"""Typed errors of pliant.

Every error says what is wrong and what to change, in one line. Errors about input name
the field (``field``) so that file loaders and the CLI can point at it. A solver that
cannot converge raises ``ConvergenceError`` carrying its residual and the last good state.
"""

from __future__ import annotations

from typing import Any


class PliantError(Exception):
    """Base class of every error pliant raises on purpose."""


class InputError(PliantError, ValueError):
    """A value given by the user is invalid; ``field`` names it."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        super().__init__(f"{field}: {message}")


class IllPosedProblemError(PliantError, ValueError):
    """The conditions do not define one equilibrium (too few, conflicting)."""


class UnreachableTargetError(InputError):
    """Prescribed positions farther apart than the part between them is long."""


class ConvergenceError(PliantError, RuntimeError):
    """A solver stopped without an equilibrium.

    residual : the relative residual where it stopped (dimensionless).
    last_good : the last converged state (an ``Equilibrium``) or None.
    progress : how far along its continuation path the solver got, in [0, 1].
    status : why it stopped (``pliant.core.events.Status``; its ``advice`` says what
        to do), or None where no solver's path was involved.
    """

    def __init__(self, message: str, *, residual: float, last_good: Any = None,
                 progress: float = 0.0, status: Any = None) -> None:
        self.residual = residual
        self.last_good = last_good
        self.progress = progress
        self.status = status
        super().__init__(message)


class FileFormatError(PliantError, ValueError):
    """A problem or scene file cannot be read; the message names file and field."""


class OutputError(PliantError, OSError):
    """A result could not be written (the message names the path); nothing was left
    half-written."""


class IdentificationError(PliantError, RuntimeError):
    """The fit could not be made (a solve failed, the budget ran out, an unknown ran to
    its bound); the message says at which values and what to change. ``last`` holds the
    last values tried, by name."""

    def __init__(self, message: str, last: dict[str, float] | None = None) -> None:
        self.last = last or {}
        super().__init__(message)


class NotIdentifiableError(IdentificationError):
    """The measurements do not determine an unknown, or determine only a combination."""
