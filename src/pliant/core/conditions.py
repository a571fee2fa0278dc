"""Conditions at stations along the part: one vocabulary for both spaces, in 2D and 3D.

A station at arc length s has pairs of components; each pair is either *prescribed*
(configuration space: the position or orientation is given and the answer is the
reaction, the load the support or hand must apply) or *applied* (force space: the load
is given, zero when not mentioned, and the answer is the position).

In 2D the pairs are (x, Fx), (y, Fy) and (angle, moment). In 3D they are (x, Fx),
(y, Fy), (z, Fz) and the orientation: ``tangent`` prescribes the direction of the part's
axis (a hand holding a hose by its end, free to let it twist), ``tangent`` with
``normal`` the whole orientation (a clamp, a firm grip: the normal is the section's
first axis d1); an applied ``moment`` is only possible where no orientation is given.
Clamp, pin, free end, a hand holding the part and a hand pushing it are all the same
noun with different pairs prescribed, so switching a grip from position control to force
control is a one-word change (``position=`` to ``force=``).

Loads are forces on the part, in the global frame [N], and moments [N m], counter-
clockwise positive (2D) or as vectors (3D). A follower force keeps its angle to the
neutral line: in 2D its components are (tangential, normal) in the deformed local frame
t = (cos theta, sin theta), nu = (-sin theta, cos theta) (the paper's Fig. 2b); in 3D
follower force and moment are given in the material frame (d1, d2, d3) of the section.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pliant.errors import IllPosedProblemError, InputError

MAX_ANGLE = 1000.0  # rad: about 160 turns; beyond it a typo, never a part's angle

Vector = tuple[float | None, ...]


def _finite_or_none(field: str, value: float | None) -> float | None:
    if value is None:
        return None
    value = float(value)
    if not math.isfinite(value):
        raise InputError(field, f"must be a finite number, got {value!r}")
    return value


def _vector(field: str, value, allow_none: bool = True) -> Vector:
    if value is None:
        return ()
    try:
        items = tuple(value)
    except TypeError:
        raise InputError(field, f"must be a vector of 2 (2D) or 3 (3D) numbers, got "
                                f"{value!r}") from None
    if not items:
        return ()
    if len(items) not in (2, 3):
        raise InputError(field, f"must have 2 (2D) or 3 (3D) components, got {len(items)}")
    out = tuple(_finite_or_none(f"{field}[{i}]", v) for i, v in enumerate(items))
    if not allow_none and any(v is None for v in out):
        raise InputError(field, "every component must be given")
    return out


def _unit(field: str, value: Vector) -> tuple[float, float, float]:
    # Scaled by its largest component first: (1e200, 1e200, 0) squared overflows to inf,
    # and dividing by that norm would turn the direction into (0, 0, 0).
    big = max(abs(v) for v in value)  # type: ignore[arg-type]
    if not big > 0.0:
        raise InputError(field, f"must be a non-zero direction, got {value!r}")
    scaled = [v / big for v in value]  # type: ignore[operator]
    norm = math.sqrt(sum(v * v for v in scaled))
    if not norm * big > 1e-12:
        raise InputError(field, f"must be a non-zero direction, got {value!r}")
    return tuple(v / norm for v in scaled)  # type: ignore[return-value]


@dataclass(frozen=True)
class Condition:
    """What is known at one station of the part.

    s : float [m], arc length from the first end
    position : (x, y[, z]) [m], entries None where free; a number prescribes it
    angle : float [rad] or None (2D); prescribes the tangent angle from +x
    tangent : (3,) or None (3D); prescribes the direction of the axis (unit vector)
    normal : (3,) or None (3D, with tangent); prescribes the section's first axis d1
    force : (Fx, Fy[, Fz]) [N], applied force on the part; entries None where not given;
        with ``follower=True`` in the local frame (2D: tangential, normal; 3D: d1, d2, d3)
    moment : float [N m] (2D) or (3,) [N m] (3D), applied moment on the part
    grip_length : float [m], a hand holding the part straight over this length from the
        end at s (0 or L) inwards, not at a point: its force and moment are the hand's
        whole wrench, about the middle of that stretch (``Problem.held_lengths``)
    """

    s: float
    name: str = ""
    position: Vector = ()
    angle: float | None = None
    force: Vector = ()
    moment: float | Vector | None = None
    follower: bool = False
    tangent: Vector | None = None
    normal: Vector | None = None
    grip_length: float = 0.0

    def __post_init__(self) -> None:
        label = self.name or "condition"
        set_ = object.__setattr__
        grip_length = _finite_or_none(f"{label}.grip_length", self.grip_length)
        if grip_length is None or grip_length < 0.0:
            raise InputError(f"{label}.grip_length", "give the length of part the hand "
                             "holds [m], 0 for a point (or a hand's breadth, about 0.095)")
        set_(self, "grip_length", grip_length)
        s = _finite_or_none(f"{label}.s", self.s)
        if s is None:
            raise InputError(f"{label}.s", "give the station's arc length in m")
        set_(self, "s", s)
        position = _vector(f"{label}.position", self.position)
        force = _vector(f"{label}.force", self.force)
        angle = _finite_or_none(f"{label}.angle", self.angle)
        if angle is not None and abs(angle) > MAX_ANGLE:
            raise InputError(f"{label}.angle", f"a tangent angle in rad, within "
                                               f"+-{MAX_ANGLE:g} (2 pi is a full turn); got "
                                               f"{angle!r}")
        set_(self, "angle", angle)
        set_(self, "follower", bool(self.follower))
        moment = self.moment
        if moment is not None and not isinstance(moment, (int, float)):
            moment = _vector(f"{label}.moment", moment, allow_none=False)
            if len(moment) != 3:
                raise InputError(f"{label}.moment", "a 3D moment has 3 components; a 2D "
                                                    "moment is one number")
        elif moment is not None:
            moment = _finite_or_none(f"{label}.moment", moment)
        tangent = normal = None
        if self.tangent is not None:
            tangent = _unit(f"{label}.tangent", _vector(f"{label}.tangent", self.tangent,
                                                        allow_none=False))
        if self.normal is not None:
            if tangent is None:
                raise IllPosedProblemError(
                    f"{label}: a normal fixes the twist about a tangent; give the tangent too")
            n = _vector(f"{label}.normal", self.normal, allow_none=False)
            dot = sum(a * b for a, b in zip(n, tangent))  # type: ignore[operator,misc]
            normal = _unit(f"{label}.normal", tuple(a - dot * b for a, b in zip(n, tangent)))  # type: ignore[operator]
        # The dimension: what the given vectors say, and it must say one thing.
        dims = set()
        if any(v is not None for v in position):
            dims.add(len(position))
        if any(v is not None for v in force):
            dims.add(len(force))
        if self.angle is not None:
            dims.add(2)
        if tangent is not None:
            dims.add(3)
        if isinstance(moment, tuple):
            dims.add(3)
        elif moment is not None:
            dims.add(2)
        if len(dims) > 1:
            raise InputError(f"{label}", "mixes 2D and 3D components; give positions, "
                                         "forces and moments with the same number of axes")
        dim = dims.pop() if dims else 0
        if tangent is not None and any(len(v) == 2 for v in (position, force) if v):
            raise InputError(f"{label}", "a tangent is 3D; give 3D positions and forces")
        if dim:
            position = (tuple(position) + (None,) * dim)[:dim] if position else (None,) * dim
            force = (tuple(force) + (None,) * dim)[:dim] if force else (None,) * dim
        set_(self, "position", position)
        set_(self, "force", force)
        set_(self, "moment", moment)
        set_(self, "tangent", tangent)
        set_(self, "normal", normal)
        if self.follower:
            if any(p is not None for p in position):
                raise IllPosedProblemError(
                    f"{label}: a follower force cannot act where the position is prescribed "
                    "(the support takes it); drop the position or make the force dead")
        else:
            for axis, (p, f) in enumerate(zip(position, force)):
                if p is not None and f is not None:
                    name = "xyz"[axis]
                    raise IllPosedProblemError(
                        f"{label}: {name} is both prescribed (position) and applied (force); "
                        f"keep one: a prescribed {name} makes F{name} the answer")
        if self.angle is not None and moment is not None:
            raise IllPosedProblemError(
                f"{label}: the angle is both prescribed and a moment applied; keep one: "
                "a prescribed angle makes the moment the answer")
        if tangent is not None and moment is not None:
            raise IllPosedProblemError(
                f"{label}: the orientation is both prescribed (tangent) and a moment applied; "
                "keep one: a prescribed orientation makes the moment the answer")

    @property
    def dimension(self) -> int:
        """2 or 3; 0 for a condition with nothing that tells (a free station)."""
        if self.tangent is not None or isinstance(self.moment, tuple):
            return 3
        for v in (self.position, self.force):
            if v:
                return len(v)
        if self.angle is not None or self.moment is not None:
            return 2
        return 0

    @property
    def prescribed(self) -> tuple[bool, ...]:
        """2D: which of (x, y, angle) are prescribed. 3D: which of (x, y, z, axis
        direction, twist) are; their loads are reactions."""
        if self.dimension == 3:
            pos = tuple(p is not None for p in self.position) or (False, False, False)
            return pos + (self.tangent is not None, self.normal is not None)
        pos = tuple(p is not None for p in self.position) or (False, False)
        return pos + (self.angle is not None,)

    @property
    def loads_only(self) -> bool:
        return not any(self.prescribed)

    @property
    def holds_point(self) -> bool:
        """Whether it holds the whole position (every component) of its point."""
        return bool(self.position) and all(v is not None for v in self.position)


def _is_3d(*vectors) -> bool:
    return any(v is not None and not isinstance(v, (int, float)) and len(v) == 3
               for v in vectors)


def clamp(s: float = 0.0, position: tuple[float, ...] = (0.0, 0.0), angle: float = 0.0,
          name: str = "clamp", *, tangent: tuple[float, float, float] | None = None,
          normal: tuple[float, float, float] | None = None) -> Condition:
    """Position and orientation prescribed: the answer is the reaction force and moment.

    In 3D (a 3D position), the orientation is ``tangent`` (default +x) and ``normal``
    (the section's first axis, default +z).
    """
    if _is_3d(position) or tangent is not None:
        if angle not in (0.0, None):
            raise InputError(f"{name}.angle", "is 2D; in 3D give tangent and normal")
        return Condition(s=s, name=name, position=position,
                         tangent=tangent or (1.0, 0.0, 0.0), normal=normal or (0.0, 0.0, 1.0))
    return Condition(s=s, name=name, position=position, angle=angle)


def pin(s: float = 0.0, position: tuple[float, ...] = (0.0, 0.0),
        name: str = "pin") -> Condition:
    """Position prescribed, free rotation (zero moment)."""
    return Condition(s=s, name=name, position=position)


def grip(s: float, position: tuple[float, ...], angle: float | None = None,
         name: str = "grip", *, tangent: tuple[float, float, float] | None = None,
         normal: tuple[float, float, float] | None = None) -> Condition:
    """A hand holding the part by position, and by its angle (2D) or its axis direction
    ``tangent`` and twist ``normal`` (3D) when given: the answer is the force (and
    moment) the hand must apply."""
    return Condition(s=s, name=name, position=position, angle=angle, tangent=tangent,
                     normal=normal)


def push(s: float, force: tuple[float, ...] | None = None,
         moment: float | tuple[float, float, float] | None = None, follower: bool = False,
         name: str = "push") -> Condition:
    """A hand pushing, or any point load: force (and moment) applied, position found."""
    return Condition(s=s, name=name, force=() if force is None else force, moment=moment,
                     follower=follower)
