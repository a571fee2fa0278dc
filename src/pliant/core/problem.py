"""A problem: a part, the conditions at its stations, and gravity."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

from pliant.core.conditions import Condition
from pliant.core.part import Part
from pliant.errors import IllPosedProblemError, InputError, UnreachableTargetError

# Two conditions closer than this (relative to the length) share one station.
STATION_MERGE = 1e-12


@dataclass(frozen=True)
class Station:
    """The conditions that act at one arc length, merged.

    owner : for each of (x, y, angle), the name of the condition that prescribes it, or
        None where the pair is applied.
    prescribed : which of (x, y, angle) are prescribed
    kinematics : the prescribed (x [m], y [m], angle [rad]); 0 where applied
    dead_load : the applied dead (Fx [N], Fy [N], moment [N m]), summed
    follower_load : the follower force (tangential [N], normal [N]), summed
    """

    s: float
    conditions: tuple[Condition, ...]
    owner: tuple[str | None, str | None, str | None]
    prescribed: tuple[bool, bool, bool] = field(init=False)
    kinematics: tuple[float, float, float] = field(init=False)
    dead_load: tuple[float, float, float] = field(init=False)
    follower_load: tuple[float, float] = field(init=False)

    def __post_init__(self) -> None:
        kin = [0.0, 0.0, 0.0]
        dead = [0.0, 0.0, 0.0]
        fol = [0.0, 0.0]
        for c in self.conditions:
            for i, value in enumerate((c.position[0], c.position[1], c.angle)):
                if value is not None:
                    kin[i] = value
            if c.follower:
                fol[0] += c.force[0] or 0.0
                fol[1] += c.force[1] or 0.0
            else:
                dead[0] += c.force[0] or 0.0
                dead[1] += c.force[1] or 0.0
            dead[2] += c.moment or 0.0
        set_ = object.__setattr__
        set_(self, "prescribed", tuple(o is not None for o in self.owner))
        set_(self, "kinematics", tuple(kin))
        set_(self, "dead_load", tuple(dead))
        set_(self, "follower_load", tuple(fol))

    def kinematic(self, i: int) -> float:
        """The prescribed value of pair i (x [m], y [m], angle [rad])."""
        if not self.prescribed[i]:
            raise KeyError(i)
        return self.kinematics[i]


@dataclass(frozen=True)
class Problem:
    """A flexible part, conditions at stations along it, and gravity [m/s^2].

    Stations without a condition are free. The problem must fix the part's rigid motion:
    x and y prescribed somewhere, and the angle prescribed somewhere or positions
    prescribed at two stations.
    """

    part: Part
    conditions: tuple[Condition, ...]
    gravity: tuple[float, float] = (0.0, 0.0)
    name: str = ""
    stations: tuple[Station, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        conditions = tuple(self.conditions)
        if not all(isinstance(c, Condition) for c in conditions):
            raise InputError("conditions", "must be Condition objects (clamp, pin, grip, push)")
        conditions = tuple(_named(c, i) for i, c in enumerate(conditions))
        object.__setattr__(self, "conditions", conditions)
        gravity = tuple(float(g) for g in self.gravity)
        if len(gravity) != 2 or not all(math.isfinite(g) for g in gravity):
            raise InputError("gravity", f"must be 2 finite numbers in m/s^2, got {self.gravity!r}")
        object.__setattr__(self, "gravity", gravity)
        names = [c.name for c in conditions]
        for n in names:
            if names.count(n) > 1:
                raise InputError("conditions", f"two conditions are named {n!r}; "
                                 "names must be unique (reactions are reported by name)")
        length = self.part.length
        for c in conditions:
            if not -STATION_MERGE * length <= c.s <= length * (1 + STATION_MERGE):
                raise InputError(f"{c.name}.s", f"station s = {c.s} m lies outside the part "
                                 f"[0, {length}] m; move it onto the part")
        object.__setattr__(self, "stations", _merge(conditions, length))
        self._check_rigid_motion()
        self._check_reach()

    def with_conditions(self, conditions: Iterable[Condition]) -> Problem:
        return Problem(self.part, tuple(conditions), self.gravity, self.name)

    def condition(self, name: str) -> Condition:
        for c in self.conditions:
            if c.name == name:
                return c
        raise KeyError(name)

    def _check_rigid_motion(self) -> None:
        prescribed = [st.prescribed for st in self.stations]
        has_x = any(p[0] for p in prescribed)
        has_y = any(p[1] for p in prescribed)
        has_angle = any(p[2] for p in prescribed)
        located = sum(1 for p in prescribed if p[0] or p[1])
        missing = []
        if not has_x:
            missing.append("x")
        if not has_y:
            missing.append("y")
        if not (has_angle or located >= 2):
            missing.append("an angle (or positions at a second station)")
        if missing:
            raise IllPosedProblemError(
                "too few conditions: nothing fixes " + ", ".join(missing) +
                " of the part, so it can move rigidly; clamp or pin one end, or hold it by "
                "position at two stations")

    def _check_reach(self) -> None:
        """Prescribed positions must be closer than the part between them is long."""
        located = [st for st in self.stations if st.prescribed[0] or st.prescribed[1]]
        for i, a in enumerate(located):
            for b in located[i + 1:]:
                arc = b.s - a.s
                both = [k for k in (0, 1) if a.prescribed[k] and b.prescribed[k]]
                if not both:
                    continue
                gap = math.sqrt(sum((b.kinematic(k) - a.kinematic(k)) ** 2 for k in both))
                if gap >= arc * (1.0 - 1e-9):
                    what = "distance" if len(both) == 2 else f"{'xy'[both[0]]}-distance"
                    raise UnreachableTargetError(
                        f"{b.owner[both[0]]}.position",
                        f"the {what} {gap:.6g} m from {a.owner[both[0]]!r} reaches or exceeds "
                        f"the {arc:.6g} m of part between them; bring the target closer "
                        "(the part is inextensible)")


def _named(c: Condition, index: int) -> Condition:
    if c.name:
        return c
    return Condition(s=c.s, name=f"condition{index + 1}", position=c.position, angle=c.angle,
                     force=c.force, moment=c.moment, follower=c.follower)


def _merge(conditions: tuple[Condition, ...], length: float) -> tuple[Station, ...]:
    """Group conditions by station and check that no pair is claimed twice."""
    groups: list[list[Condition]] = []
    for c in sorted(conditions, key=lambda c: c.s):
        if groups and abs(c.s - groups[-1][0].s) <= STATION_MERGE * length:
            groups[-1].append(c)
        else:
            groups.append([c])
    stations = []
    for group in groups:
        owner: list[str | None] = [None, None, None]
        applied = [False, False, False]
        for c in group:
            for i, p in enumerate(c.prescribed):
                if p:
                    if owner[i] is not None:
                        raise IllPosedProblemError(
                            f"{owner[i]} and {c.name} both prescribe {('x', 'y', 'angle')[i]} "
                            f"at s = {c.s} m; keep one")
                    owner[i] = c.name
            if c.follower:
                if c.force != (None, None):
                    applied[0] = applied[1] = True
            else:
                applied[0] |= c.force[0] is not None
                applied[1] |= c.force[1] is not None
            applied[2] |= c.moment is not None
        for i in range(3):
            if owner[i] is not None and applied[i]:
                names = ", ".join(c.name for c in group)
                raise IllPosedProblemError(
                    f"at s = {group[0].s} m ({names}) {('x', 'y', 'angle')[i]} is both "
                    "prescribed and loaded; a prescribed component's load is the answer")
        s = min(max(group[0].s, 0.0), length)
        stations.append(Station(s=s, conditions=tuple(group), owner=tuple(owner)))
    return tuple(stations)


def _lerp(a: float | None, b: float | None, t: float) -> float | None:
    if a is None or b is None:
        return b
    return a + t * (b - a)


def interpolate(start: Problem, end: Problem, t: float) -> Problem:
    """The problem a fraction t of the way from start to end (same part, conditions
    matched by name): prescribed positions and angles and applied loads move linearly.

    Continuation follows such a path; an A/D operation is one.
    """
    by_name = {c.name: c for c in start.conditions}
    conditions = []
    for c in end.conditions:
        a = by_name.get(c.name)
        if a is None:
            conditions.append(c)
            continue
        conditions.append(Condition(
            s=a.s + t * (c.s - a.s), name=c.name,
            position=(_lerp(a.position[0], c.position[0], t),
                      _lerp(a.position[1], c.position[1], t)),
            angle=_lerp(a.angle, c.angle, t),
            force=(_lerp(a.force[0], c.force[0], t), _lerp(a.force[1], c.force[1], t)),
            moment=_lerp(a.moment, c.moment, t), follower=c.follower))
    gravity = tuple(ga + t * (gb - ga) for ga, gb in zip(start.gravity, end.gravity))
    return Problem(end.part, tuple(conditions), gravity, end.name)  # type: ignore[arg-type]
