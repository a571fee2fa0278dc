"""A problem: a part, the conditions at its stations, and gravity."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from pliant.core.conditions import Condition, _unit, _vector
from pliant.core.loads import DistributedLoad, Load
from pliant.core.part import Part
from pliant.errors import IllPosedProblemError, InputError, UnreachableTargetError

if TYPE_CHECKING:  # (core.equilibrium imports this module)
    from pliant.core.equilibrium import Equilibrium3D

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
            dead[2] += c.moment or 0.0  # type: ignore[operator]  # 2D: a number
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
class Station3D:
    """The conditions that act at one arc length of a 3D part, merged.

    owner : for each of (x, y, z, axis direction, twist), the name of the condition that
        prescribes it, or None where it is applied.
    position : the prescribed (x, y, z) [m]; 0 where free
    tangent, normal : the prescribed axis direction and section axis d1 (unit), or None
    dead_force, dead_moment : applied in the global frame [N], [N m], summed
    follower_force, follower_moment : applied in the material frame (d1, d2, d3), summed
    """

    s: float
    conditions: tuple[Condition, ...]
    owner: tuple[str | None, ...]
    position: tuple[float, float, float] = field(init=False)
    tangent: tuple[float, float, float] | None = field(init=False)
    normal: tuple[float, float, float] | None = field(init=False)
    dead_force: tuple[float, float, float] = field(init=False)
    dead_moment: tuple[float, float, float] = field(init=False)
    follower_force: tuple[float, float, float] = field(init=False)
    follower_moment: tuple[float, float, float] = field(init=False)
    # Which of (x, y, z, axis, twist) a condition prescribes (owner's not None), read
    # many times per solve.
    prescribed: tuple[bool, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        pos = [0.0, 0.0, 0.0]
        tangent = normal = None
        loads: dict[str, list[float]] = {"dead_force": [0.0] * 3, "dead_moment": [0.0] * 3,
                 "follower_force": [0.0] * 3, "follower_moment": [0.0] * 3}
        for c in self.conditions:
            for i, value in enumerate(c.position):
                if value is not None:
                    pos[i] = value
            if c.tangent is not None:
                tangent = c.tangent
            if c.normal is not None:
                normal = c.normal
            kind = "follower" if c.follower else "dead"
            for i, value in enumerate(c.force):
                loads[f"{kind}_force"][i] += value or 0.0
            if c.moment is not None:
                for i, m in enumerate(c.moment):  # type: ignore[arg-type]
                    loads[f"{kind}_moment"][i] += m or 0.0
        set_ = object.__setattr__
        set_(self, "prescribed", tuple(o is not None for o in self.owner))
        set_(self, "position", tuple(pos))
        set_(self, "tangent", tangent)
        set_(self, "normal", normal)
        for key, total in loads.items():
            set_(self, key, tuple(total))


# Contact between two parts (the accurate model's ``coupled``): walls flatten 10
# micrometres per newton where two tubes press together (a contact stiffness of 1e5 N/m,
# a hose wall's local ovalisation under a line load), and probes along the first part sit
# close enough that the tubes cannot pass between two by more than PROBE_SAG of the sum
# of their radii. A clearance report counts an overlap within both as touching.
WALL_COMPLIANCE = 1e-5  # m/N
PROBE_SAG = 0.01


def _point3(field_name: str, value) -> tuple[float, float, float]:
    """A 3D vector, every component given and finite (``conditions._vector``)."""
    v = _vector(field_name, value, allow_none=False)
    if len(v) != 3:
        raise InputError(field_name, f"give 3 components, not {len(v)}")
    return v  # type: ignore[return-value]


class _SolvedAlone:
    """A part of a scene solved on its own first (a fitted part, a harness branch): its
    ``problem`` with ``elements`` elements and, once a model has solved it alone
    (``pliant.models.rod3d.solved_alone``, or the scene's loader), that equilibrium in
    ``solved``. core keeps the answer and never solves. It pickles without that
    equilibrium (which holds the solver's closures)."""

    def __getstate__(self) -> dict:
        return {**self.__dict__, "solved": None}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)


@dataclass(frozen=True, eq=False)
class FittedPart(_SolvedAlone):
    """A flexible part already assembled, in its clamps and clips: its own problem, the
    element count it is solved with, and its equilibrium there (untouched). A part being
    fitted that touches it is solved together with it: it deforms, and its clamps feel
    the contact (``pliant.models.rod3d.coupled``). It pickles without its equilibrium
    (which holds the solver's closures), found again on first use."""

    name: str
    problem: Problem
    elements: int
    solved: Equilibrium3D | None = field(default=None, repr=False)  # alone
    friction: float = 0.0  # Coulomb's coefficient between it and the part that touches it
    # (N+1, 3) [m] its neutral line alone, where known without its equilibrium (a scene
    # file's cache of it): clearances to it need no solve.
    line: object = field(default=None, repr=False)

    @property
    def rest_line(self):
        """(N+1, 3) [m]: its neutral line alone, untouched."""
        if self.line is not None:
            return self.line
        if self.solved is None:
            raise InputError(f"{self.name}.line", "its shape at rest is not known: load "
                             "the scene with pliant.assembly.load_scene, or solve the part "
                             "alone first (pliant.models.rod3d.solved_alone)")
        return self.solved.position



@dataclass(frozen=True)
class SlidingClip:
    """A clip the part slides through (3D): it holds the part's neutral line at
    ``position`` [m] and, with ``holds_axis``, its direction along ``axis``, whatever
    point of the part is there; the part slides along the axis, freely or, with
    ``friction`` > 0, against Coulomb's friction (it sticks while the axial force is
    below friction times the force across the clip). ``s`` [m] is where along the part the clip is
    at the start; the solve
    finds where it ends (the slide). Without ``holds_axis`` it is a ring or grommet that
    holds the position only."""

    name: str
    s: float
    position: tuple[float, float, float]
    axis: tuple[float, float, float]
    holds_axis: bool = True
    friction: float = 0.0  # Coulomb's coefficient along the axis (0: frictionless)

    def __post_init__(self) -> None:
        if not (math.isfinite(float(self.friction)) and float(self.friction) >= 0.0):
            raise InputError(f"{self.name}.friction", f"must be a number >= 0 (Coulomb's "
                             f"coefficient), not {self.friction!r}")
        object.__setattr__(self, "friction", float(self.friction))
        object.__setattr__(self, "position", _point3(f"{self.name}.position", self.position))
        object.__setattr__(self, "axis", _unit(f"{self.name}.axis",
                                               _point3(f"{self.name}.axis", self.axis)))
        if not math.isfinite(float(self.s)):
            raise InputError(f"{self.name}.s", "give the arc length [m] at the clip")
        object.__setattr__(self, "s", float(self.s))


@dataclass(frozen=True)
class PivotClip:
    """A clip that holds the part firmly at ``s`` [m] and ``position`` [m] but turns on
    a pin along ``pivot`` (3D): the part's section keeps its first axis d1 along the pin
    and may turn about it; the clip takes no moment about the pin."""

    name: str
    s: float
    position: tuple[float, float, float]
    pivot: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _point3(f"{self.name}.position", self.position))
        object.__setattr__(self, "pivot", _unit(f"{self.name}.pivot",
                                                _point3(f"{self.name}.pivot", self.pivot)))
        object.__setattr__(self, "s", float(self.s))


@dataclass(frozen=True, eq=False)
class Branch(_SolvedAlone):
    """A branch of a harness: its own problem (its part and what holds its far end: a
    port's clamp), which of its ends meets the junction (``end``: 0 its first, 1 its
    last), the direction it leaves the junction in (``axis``, in the frame (d1, d2, d3)
    of the main part's end there, d3 pointing out of the part) and its element count."""

    name: str
    problem: Problem
    end: int
    axis: tuple[float, float, float]
    elements: int = 60
    solved: Equilibrium3D | None = field(default=None, repr=False,
                                         compare=False)  # alone, on demand

    def __post_init__(self) -> None:
        if self.end not in (0, 1):
            raise InputError(f"{self.name}.end", "give 0 (its first end) or 1 (its last)")
        if self.problem.dimension != 3:
            raise InputError(f"{self.name}.file", "a harness branch is a 3D problem")
        object.__setattr__(self, "axis", _unit(f"{self.name}.axis",
                                               _point3(f"{self.name}.axis", self.axis)))


@dataclass(frozen=True, eq=False)
class Junction:
    """A harness junction (a Y-piece of no size) at an end of the part (``s``: 0 or its
    length): each branch's end is held rigidly to the part's end there."""

    name: str
    s: float
    branches: tuple[Branch, ...]


@dataclass(frozen=True)
class Problem:
    """A flexible part, conditions at stations along it, gravity [m/s^2] and
    loads (``loads``: ``pliant.core.loads``' nouns, lowered once to the distributed forces
    the models read, ``distributed``).

    Stations without a condition are free. The problem must fix the part's rigid motion:
    x and y prescribed somewhere, and the angle prescribed somewhere or positions
    prescribed at two stations. ``obstacles`` (3D): rigid obstacles the part must not
    enter (``pliant.scene.Obstacle``); the part touches them with its outer radius.
    """

    part: Part
    conditions: tuple[Condition, ...]
    gravity: tuple[float, ...] | None = None
    name: str = ""
    obstacles: tuple = ()
    sliders: tuple[SlidingClip, ...] = ()
    junctions: tuple[Junction, ...] = ()
    pivots: tuple[PivotClip, ...] = ()
    loads: tuple[Load, ...] = ()
    stations: tuple = field(init=False, repr=False, compare=False)
    # The conditions held over a length (a hand's breadth at an end): (name, the middle
    # of the stretch's s [m], the lever from that middle to where the station holds the
    # part [m]) each, for ``held_over_length``.
    held_lengths: tuple = field(init=False, repr=False, compare=False)
    distributed: tuple[DistributedLoad, ...] = field(init=False, repr=False, compare=False)
    dimension: int = field(init=False, repr=False, compare=False)
    # The dead load [N/m] on every metre of the part, global frame: its weight (mass per
    # length times gravity) plus the dead loads that cover it whole; and the
    # ``distributed`` loads that it leaves out (followers, dead loads on a stretch only).
    # Worked out once here: every solve reads them, a warm step several times.
    dead_load_per_length: tuple[float, ...] = field(init=False, repr=False, compare=False)
    partial_loads: tuple[DistributedLoad, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        conditions = tuple(self.conditions)
        if not all(isinstance(c, Condition) for c in conditions):
            raise InputError("conditions", "must be Condition objects (clamp, pin, grip, push)")
        gravity = self.gravity
        if gravity is not None:
            try:
                gravity = tuple(float(g) for g in gravity)
            except (TypeError, ValueError):
                raise InputError("gravity", f"must be 2 or 3 numbers in m/s^2, got "
                                            f"{self.gravity!r}") from None
            if len(gravity) not in (2, 3) or not all(math.isfinite(g) for g in gravity):
                raise InputError("gravity", f"must be 2 (2D) or 3 (3D) finite numbers in m/s^2,"
                                            f" got {self.gravity!r}")
        loads = tuple(self.loads)
        for k, ld in enumerate(loads):
            if not isinstance(ld, Load):
                raise InputError(f"loads[{k}]", f"must be a load of pliant.core.loads "
                                 f"(DistributedLoad, AddedMass), not {type(ld).__name__}")
        dims = {c.dimension for c in conditions} - {0}
        if gravity is not None and any(gravity):
            dims.add(len(gravity))
        if len(dims) > 1:
            raise InputError("conditions", "mix 2D and 3D conditions (or gravity); give every "
                                           "vector with the same number of axes")
        told = [ld.dimension for ld in loads if isinstance(ld, DistributedLoad)]
        if not dims and told:  # only the loads tell (each is checked below)
            dims.add(told[0])
        dimension = dims.pop() if dims else (len(gravity) if gravity else 2)
        if gravity is None or not any(gravity):
            gravity = (0.0,) * dimension
        elif len(gravity) != dimension:
            raise InputError("gravity", f"has {len(gravity)} components in a {dimension}D "
                                        "problem")
        conditions = tuple(_named(_dimensioned(c, dimension), i)
                           for i, c in enumerate(conditions))
        object.__setattr__(self, "conditions", conditions)
        object.__setattr__(self, "gravity", gravity)
        object.__setattr__(self, "dimension", dimension)
        obstacles = tuple(self.obstacles)
        if obstacles and dimension != 3:
            raise InputError("obstacles", "contact with obstacles is 3D; give the conditions "
                             "and gravity three components")
        object.__setattr__(self, "obstacles", obstacles)
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
        sliders = tuple(self.sliders)
        if sliders and dimension != 3:
            raise InputError("sliders", "a sliding clip is 3D; give the conditions and "
                             "gravity three components")
        for clip in sliders:
            if not isinstance(clip, SlidingClip):
                raise InputError("sliders", "must be SlidingClip objects")
            if not 0.0 < clip.s < length:
                raise InputError(f"{clip.name}.s", f"the clip must hold the part inside it: "
                                 f"s = {clip.s} m is not within (0, {length}) m")
            if clip.name in names or [x.name for x in sliders].count(clip.name) > 1:
                raise InputError(f"{clip.name}.name", "a sliding clip needs a name of its own "
                                 "(its reaction is reported by name)")
        object.__setattr__(self, "sliders", sliders)
        junctions = tuple(self.junctions)
        for jn in junctions:
            if not isinstance(jn, Junction):
                raise InputError("junctions", "must be Junction objects")
            if dimension != 3:
                raise InputError(f"{jn.name}", "a harness junction is 3D")
            if not (abs(jn.s) <= STATION_MERGE * length
                    or abs(jn.s - length) <= STATION_MERGE * length):
                raise InputError(f"{jn.name}.s", f"a junction is at an end of the part: "
                                 f"0 or {length} m, not {jn.s} m")
            if not jn.branches:
                raise InputError(f"{jn.name}.branch", "give its branches ([[junction.branch]])")
        object.__setattr__(self, "junctions", junctions)
        pivots = tuple(self.pivots)
        for pivot in pivots:
            if not isinstance(pivot, PivotClip):
                raise InputError("pivots", "must be PivotClip objects")
            if dimension != 3:
                raise InputError(f"{pivot.name}", "a pivoting clip is 3D")
            if pivot.name not in names:
                raise InputError(f"{pivot.name}", "a pivoting clip holds the part by a "
                                 "condition of its name (its position); give one")
        object.__setattr__(self, "pivots", pivots)
        for ld in loads:
            ld.check(length, dimension)
        object.__setattr__(self, "loads", loads)
        object.__setattr__(self, "distributed", tuple(
            d for ld in loads for d in ld.distributed(gravity)))
        self._split_loads()
        merge = _merge if dimension == 2 else _merge3
        held, at_heel = _held_over_length(conditions, length, dimension)
        object.__setattr__(self, "held_lengths", held)
        object.__setattr__(self, "stations", merge(at_heel, length))
        self._check_rigid_motion()
        self._check_reach()

    @property
    def solved_together(self) -> bool:
        """Whether the 3D model solves it with other parts or clips (``rod3d.together``):
        flexible parts already fitted among its obstacles, clips that slide or pivot,
        harness junctions."""
        return bool(self.sliders or self.junctions or self.pivots or any(
            getattr(o, "fitted", None) is not None for o in self.obstacles))

    def _split_loads(self) -> None:
        """Sets ``dead_load_per_length`` and ``partial_loads`` (see their fields)."""
        length = self.part.length
        total = [self.part.mass_per_length * g for g in self.gravity or ()]
        partial = []
        for ld in self.distributed:
            whole = ld.overlap(0.0, length, length) >= length * (1.0 - 1e-12)
            if whole and not ld.follower:
                total = [a + b for a, b in zip(total, ld.force)]
            else:
                partial.append(ld)
        object.__setattr__(self, "dead_load_per_length", tuple(total))
        object.__setattr__(self, "partial_loads", tuple(partial))

    @property
    def model_conditions(self) -> tuple[Condition, ...]:
        """The conditions as the models hold the part: each held over a length
        (``Condition.grip_length``) at its heel (see ``_held_over_length``)."""
        if not self.held_lengths:
            return self.conditions
        return tuple(c for st in self.stations for c in st.conditions)

    @property
    def held_stations(self) -> int:
        """How many conditions hold a position component: two or more is a problem in
        configuration space (a hand at a target), where a cold solve looks for the
        lowest stable equilibrium among those it finds."""
        return sum(any(v is not None for v in c.position) for c in self.conditions)

    def with_conditions(self, conditions: Iterable[Condition]) -> Problem:
        return Problem(self.part, tuple(conditions), self.gravity, self.name, self.obstacles,
                       self.sliders, self.junctions, self.pivots, self.loads)

    def _located(self, st) -> list[int]:
        """The coordinates a station prescribes."""
        n = self.dimension
        return [k for k in range(n) if st.prescribed[k]]

    def _coordinate(self, st, k: int) -> float:
        return st.kinematic(k) if self.dimension == 2 else st.position[k]

    def condition(self, name: str) -> Condition:
        for c in self.conditions:
            if c.name == name:
                return c
        raise KeyError(name)

    def _check_rigid_motion(self) -> None:
        n = self.dimension
        prescribed = [st.prescribed for st in self.stations]
        missing = ["xyz"[k] for k in range(n) if not any(p[k] for p in prescribed)]
        located = sum(1 for p in prescribed if any(p[:n]))
        if n == 2:
            turns = any(p[2] for p in prescribed) or located >= 2
            what = "an angle (or positions at a second station)"
        else:
            turns = any(p[3] for p in prescribed) or located >= 2
            what = "an orientation (or positions at a second station)"
        if not turns:
            missing.append(what)
        if missing:
            raise IllPosedProblemError(
                "too few conditions: nothing fixes " + ", ".join(missing) +
                " of the part, so it can move rigidly; clamp or pin one end, or hold it by "
                "position at two stations")

    def _check_reach(self) -> None:
        """Prescribed positions must be closer than the part between them is long (an
        extensible part: than it is long stretched by MAX_STRETCH)."""
        extensible = self.part.axial_stiffness is not None
        reach = 1.0 + MAX_STRETCH if extensible else 1.0 - 1e-9
        located = [st for st in self.stations if self._located(st)]
        for i, a in enumerate(located):
            for b in located[i + 1:]:
                arc = b.s - a.s
                both = [k for k in self._located(a) if k in self._located(b)]
                if not both:
                    continue
                gap = math.hypot(*(self._coordinate(b, k) - self._coordinate(a, k)
                                   for k in both))  # no overflow at 1e160 m
                if gap >= arc * reach:
                    what = ("distance" if len(both) == self.dimension
                            else "-".join("xyz"[k] for k in both) + "-distance")
                    why = (f"stretched by {MAX_STRETCH:.0%}, beyond which a linear axial "
                           "stiffness does not hold" if extensible else
                           "(the part is inextensible; give its axial_stiffness EA [N] to "
                           "let it stretch)")
                    raise UnreachableTargetError(
                        f"{b.owner[both[0]]}.position",
                        f"the {what} {gap:.6g} m from {a.owner[both[0]]!r} reaches or exceeds "
                        f"the {arc * max(reach, 1.0):.6g} m of part between them"
                        f"{' ' + why if extensible else ''}; bring the target closer"
                        f"{'' if extensible else ' ' + why}")


MAX_STRETCH = 0.1  # the largest chord strain an extensible part is asked to take


def _held_over_length(conditions: tuple[Condition, ...], length: float, dimension: int
                      ) -> tuple[tuple, tuple[Condition, ...]]:
    """A hand holding the part straight over ``grip_length`` from an end is, for the
    models, a clamp where the stretch it holds starts (its heel: the same axis, the
    position ``grip_length`` back along it), the stretch inside the hand carried by that
    clamp. (Two clamps at both ends of a straight inextensible stretch would leave its
    tension undetermined.) Returns ((name, s of the stretch's middle, lever from that
    middle to the heel) per such condition, the conditions with each moved to its
    heel)."""
    held, out = [], []
    for c in conditions:
        if not c.grip_length:
            out.append(c)
            continue
        grip = c.grip_length
        label = f"{c.name}.grip_length"
        at_end = abs(c.s - length) <= 1e-9 * length
        if not (at_end or abs(c.s) <= 1e-9 * length):
            raise InputError(label, "a hand over a length is modelled at an end of the part "
                             "(s = 0 or s = L) for now; elsewhere give grip_length = 0 (a "
                             "point)")
        if not grip < length:
            raise InputError(label, f"{grip} m is not shorter than the part ({length} m)")
        axis = (c.tangent if dimension == 3 else None if c.angle is None
                else (math.cos(c.angle), math.sin(c.angle)))
        if axis is None or any(v is None for v in c.position):
            raise InputError(label, "a hand over a length holds the part's position and "
                             "axis there: give the position and the tangent (2D: angle)")
        inward = -1.0 if at_end else 1.0
        heel = tuple(float(p) + inward * grip * float(a)  # type: ignore[arg-type]
                     for p, a in zip(c.position, axis))
        s_heel = c.s + inward * grip
        for other in conditions:
            if other is not c and min(s_heel, c.s) < other.s < max(s_heel, c.s) + 1e-12:
                raise InputError(label, f"{other.name} at s = {other.s:g} m is inside the "
                                 f"stretch the hand holds ({min(s_heel, c.s):g} to "
                                 f"{max(s_heel, c.s):g} m); shorten grip_length or move it")
        held.append((c.name, c.s + 0.5 * inward * grip,
                     tuple(0.5 * inward * grip * float(a) for a in axis)))  # type: ignore[arg-type]
        out.append(replace(c, s=s_heel, position=heel, grip_length=0.0))
    return tuple(held), tuple(out)


def _named(c: Condition, index: int) -> Condition:
    if c.name:
        return c
    return replace(c, name=f"condition{index + 1}")


def _dimensioned(c: Condition, dimension: int) -> Condition:
    """A condition that tells no dimension (a free station), made the problem's."""
    if c.dimension:
        if c.dimension != dimension:
            raise InputError(f"{c.name or 'condition'}", f"is {c.dimension}D in a "
                                                         f"{dimension}D problem")
        return c
    return replace(c, position=(None,) * dimension, force=(None,) * dimension)


def _merge(conditions: tuple[Condition, ...], length: float) -> tuple[Station, ...]:
    """Group conditions by station and check that no pair is claimed twice."""
    groups = _group(conditions, length)
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
        stations.append(Station(s=s, conditions=tuple(group), owner=(owner[0], owner[1], owner[2])))
    return tuple(stations)


def _merge3(conditions: tuple[Condition, ...], length: float) -> tuple[Station3D, ...]:
    """Group 3D conditions by station and check that no component is claimed twice."""
    groups = _group(conditions, length)
    stations = []
    names = ("x", "y", "z", "axis direction", "twist")
    for group in groups:
        owner: list[str | None] = [None] * 5
        for c in group:
            for i, p in enumerate(c.prescribed):
                if p:
                    if owner[i] is not None:
                        raise IllPosedProblemError(
                            f"{owner[i]} and {c.name} both prescribe the {names[i]} at "
                            f"s = {c.s} m; keep one")
                    owner[i] = c.name
        for c in group:
            for i in range(3):
                if owner[i] is not None and c.force[i] is not None and (
                        c.follower or owner[i] != c.name):
                    raise IllPosedProblemError(
                        f"at s = {c.s} m ({c.name}) {'xyz'[i]} is both prescribed and loaded; "
                        "a prescribed component's load is the answer")
            if c.moment is not None and owner[3] is not None:
                raise IllPosedProblemError(
                    f"at s = {c.s} m ({c.name}) the orientation is prescribed and a moment "
                    "applied; a prescribed orientation's moment is the answer")
        s = min(max(group[0].s, 0.0), length)
        stations.append(Station3D(s=s, conditions=tuple(group), owner=tuple(owner)))
    return tuple(stations)


def _group(conditions: tuple[Condition, ...], length: float) -> list[list[Condition]]:
    groups: list[list[Condition]] = []
    for c in sorted(conditions, key=lambda c: c.s):
        if groups and abs(c.s - groups[-1][0].s) <= STATION_MERGE * length:
            groups[-1].append(c)
        else:
            groups.append([c])
    return groups


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
            position=_lerp_vector(a.position, c.position, t),
            angle=_lerp(a.angle, c.angle, t),
            force=_lerp_vector(a.force, c.force, t),
            moment=(_lerp(a.moment, c.moment, t)  # type: ignore[arg-type]
                    if not isinstance(c.moment, tuple)
                    else _lerp_vector(a.moment, c.moment, t)),
            follower=c.follower,
            tangent=_lerp_vector(a.tangent, c.tangent, t) if c.tangent else None,
            normal=_lerp_vector(a.normal, c.normal, t) if c.normal else None))
    gravity = tuple(ga + t * (gb - ga) for ga, gb in zip(start.gravity or (), end.gravity or ()))
    # A distributed force moves linearly from its start to its end value (by name);
    # other loads are the end's.
    was = {ld.name: ld for ld in start.loads if isinstance(ld, DistributedLoad)}
    loads = tuple(replace(ld, force=_lerp_vector(was[ld.name].force, ld.force, t))
                  if isinstance(ld, DistributedLoad) and ld.name in was else ld
                  for ld in end.loads)
    return Problem(end.part, tuple(conditions), gravity, end.name, end.obstacles, loads=loads)


def _lerp_vector(a, b, t: float):
    """Component by component; a missing start takes the end's value."""
    if not b:
        return b
    if not a or not isinstance(a, tuple):
        return b
    return tuple(_lerp(x, y, t) for x, y in zip(a, b))
