"""Conditions at stations along the part: one vocabulary for both spaces.

A station at arc length s has three pairs of components: (x, Fx), (y, Fy) and
(angle, moment). Each pair is either *prescribed* (configuration space: the position or
angle is given and the answer is the reaction, the load the support or hand must apply)
or *applied* (force space: the load is given, zero when not mentioned, and the answer is
the position). Clamp, pin, free end, a hand holding the part and a hand pushing it are
all the same noun with different pairs prescribed, so switching a grip from position
control to force control is a one-word change (``position=`` to ``force=``).

Loads are forces on the part, in the global frame [N] and moments [N m], counter-clockwise
positive. A follower force keeps its angle to the neutral line: its two components are
(tangential, normal) in the local frame t = (cos theta, sin theta),
nu = (-sin theta, cos theta) of the deformed part (the paper's Fig. 2b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pliant.errors import IllPosedProblemError, InputError

Pair = tuple[float | None, float | None]


def _finite_or_none(field: str, value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    if not math.isfinite(value):
        raise InputError(field, f"must be a finite number, got {value!r}")
    return value


def _pair(field: str, value) -> Pair:
    if value is None:
        return (None, None)
    try:
        items = tuple(value)
    except TypeError:
        raise InputError(field, f"must be a pair (x, y), got {value!r}") from None
    if len(items) != 2:
        raise InputError(field, f"must have 2 components in 2D, got {len(items)}")
    return (_finite_or_none(f"{field}[0]", items[0]), _finite_or_none(f"{field}[1]", items[1]))


@dataclass(frozen=True)
class Condition:
    """What is known at one station of the part.

    s : float [m], arc length from the first end
    position : (x [m] or None, y [m] or None); a number prescribes that coordinate
    angle : float [rad] or None; prescribes the tangent angle (counter-clockwise from +x)
    force : (Fx [N] or None, Fy [N] or None); applied force on the part; with
        ``follower=True`` the pair is (tangential, normal) in the deformed local frame
    moment : float [N m] or None; applied moment on the part
    """

    s: float
    name: str = ""
    position: Pair = (None, None)
    angle: float | None = None
    force: Pair = (None, None)
    moment: float | None = None
    follower: bool = False

    def __post_init__(self) -> None:
        label = self.name or "condition"
        s = _finite_or_none(f"{label}.s", self.s)
        if s is None:
            raise InputError(f"{label}.s", "give the station's arc length in m")
        object.__setattr__(self, "s", s)
        position = _pair(f"{label}.position", self.position)
        force = _pair(f"{label}.force", self.force)
        object.__setattr__(self, "position", position)
        object.__setattr__(self, "force", force)
        object.__setattr__(self, "angle", _finite_or_none(f"{label}.angle", self.angle))
        object.__setattr__(self, "moment", _finite_or_none(f"{label}.moment", self.moment))
        object.__setattr__(self, "follower", bool(self.follower))
        if self.follower:
            if any(p is not None for p in position):
                raise IllPosedProblemError(
                    f"{label}: a follower force cannot act where the position is prescribed "
                    "(the support takes it); drop the position or make the force dead")
        else:
            for axis, (p, f) in enumerate(zip(position, force)):
                if p is not None and f is not None:
                    name = "xy"[axis]
                    raise IllPosedProblemError(
                        f"{label}: {name} is both prescribed (position) and applied (force); "
                        f"keep one: a prescribed {name} makes F{name} the answer")
        if self.angle is not None and self.moment is not None:
            raise IllPosedProblemError(
                f"{label}: the angle is both prescribed and a moment applied; keep one: "
                "a prescribed angle makes the moment the answer")

    @property
    def prescribed(self) -> tuple[bool, bool, bool]:
        """Which of (x, y, angle) are prescribed; their loads are reactions."""
        return (self.position[0] is not None, self.position[1] is not None,
                self.angle is not None)

    @property
    def loads_only(self) -> bool:
        return not any(self.prescribed)


def clamp(s: float = 0.0, position: tuple[float, float] = (0.0, 0.0), angle: float = 0.0,
          name: str = "clamp") -> Condition:
    """Position and angle prescribed: the answer is the reaction force and moment."""
    return Condition(s=s, name=name, position=position, angle=angle)


def pin(s: float = 0.0, position: tuple[float, float] = (0.0, 0.0),
        name: str = "pin") -> Condition:
    """Position prescribed, free rotation (zero moment)."""
    return Condition(s=s, name=name, position=position)


def grip(s: float, position: tuple[float, float], angle: float | None = None,
         name: str = "grip") -> Condition:
    """A hand holding the part by position (and angle when given): the answer is the
    force (and moment) the hand must apply."""
    return Condition(s=s, name=name, position=position, angle=angle)


def push(s: float, force: tuple[float, float] = (0.0, 0.0), moment: float | None = None,
         follower: bool = False, name: str = "push") -> Condition:
    """A hand pushing, or any point load: force (and moment) applied, position found."""
    return Condition(s=s, name=name, force=force, moment=moment, follower=follower)
