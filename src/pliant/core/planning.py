"""A scene's [path] as given (``PathSpec``; ``pliant.assembly.path.carry`` makes its
steps) and how a path is to be planned (a scene's [plan]; ``pliant.assembly.plan`` plans
it)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pliant.errors import InputError


@dataclass(frozen=True)
class PathSpec:
    """A manipulation as a scene file gives it: the condition ``grip`` carried from where
    the file puts it through ``waypoints`` (m, straight legs), its axis turned toward
    ``tangents`` when given, in ``steps`` equal steps of arc length; the conditions in
    ``carry`` (other hands) carried with it as one rigid carrier: moved as the grip
    moves, turned by the least rotation that takes the grip's first axis to its axis
    there."""

    grip: str
    waypoints: tuple[tuple[float, float, float], ...]
    tangents: tuple[tuple[float, float, float], ...] | None
    steps: int
    # other hands carried with the grip as one rigid carrier (both hands carrying)
    carry: tuple[str, ...] = ()


@dataclass(frozen=True)
class PlanSettings:
    """How to search.

    budget [s]: the wall time a query may take; seed: makes the plan reproducible;
    step [m] and turn [deg]: the largest move and turn of the hand between two solves
    along an edge; reach [m]: the longest edge (in the metric below); approach [m]: the
    straight last leg along the port's axis (the connector's engagement: the farther the
    part is pushed straight in, the more the hand must hold; a push-in connector engages
    a couple of centimetres); goal_bias: how often the tree grows toward
    the goal; goal_tolerance [m]: how near (in the metric) the tree must come to the
    point before the port, holding the port's axis, for a last leg to go there straight;
    allow_contact: the part may touch obstacles (not enter them) instead of
    keeping the scene's margin; rotation_length [m per rad]: what a turn of the hand
    weighs against a move in the metric (default a tenth of the part's length);
    attempts: paths found per query at most, each from a tree of its own, the least
    peak demand kept (time permitting; it stops early when two give the same demand;
    a tree whose path cannot be finished into the port is followed by another); simplify: shortcut
    the found path; elements: the accurate model's
    resolution (default the scene's); goal: the port to seat the part's end in (a
    scene's [plan] goal; the command line's --goal overrides it); carry: other hands
    carried with the grip as one rigid carrier (both hands carrying; see ``PathSpec``)."""

    budget: float = 30.0
    seed: int = 1
    step: float = 0.03
    turn: float = 15.0
    reach: float = 0.15
    approach: float = 0.02
    goal_bias: float = 0.2
    goal_tolerance: float = 0.04
    allow_contact: bool = False
    rotation_length: float | None = None
    attempts: int = 3
    simplify: bool = True
    elements: int | None = None
    goal: str | None = None
    carry: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for key in ("budget", "step", "turn", "reach", "goal_tolerance"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"plan.{key}", f"must be a finite number > 0, not {value!r}")
        if not (math.isfinite(self.approach) and self.approach >= 0):
            raise InputError("plan.approach", f"must be a length >= 0 [m], not "
                             f"{self.approach!r}")
        if not 0.0 <= self.goal_bias < 1.0:
            raise InputError("plan.goal_bias", f"must be in [0, 1), not {self.goal_bias!r}")
        if self.rotation_length is not None and not self.rotation_length > 0:
            raise InputError("plan.rotation_length", "must be > 0 [m per rad]")
        if self.attempts < 1:
            raise InputError("plan.attempts", "must be at least 1")
        if not 1 <= self.seed < 2**31:
            raise InputError("plan.seed", f"must be an integer in [1, 2^31), not {self.seed!r}")
