"""The rules an A/D evaluation judges by: grip capacities, part kinds and damage limits,
each with its source and provenance (``pliant/data/rules.toml``, replaceable by a user's
own table). Plain data: ``pliant.io.rules_file`` reads them, ``pliant.assembly`` applies
them.

Zones follow EN 1005-3's risk multiplier r = demand / capacity: green up to
``zones.green``, yellow up to ``zones.yellow``, red beyond. A row may give its own limits
(the pinch row, where no capacity is published).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from pliant.errors import InputError

DEMANDS = ("axial", "lateral", "grip", "force", "twist", "bending")
"""What a capacity row may limit, at a grip with tangent t, force F and moment M:
|F.t|, |F - (F.t)t|, the squeeze max(|F.t| / (2 mu), lateral), |F|, |M.t|,
|M - (M.t)t|."""


@dataclass(frozen=True)
class Sourced:
    """A threshold's source (where it was published) and provenance (standard, study,
    derived, fallback, engineering choice, assumption, user)."""

    source: str
    provenance: str


@dataclass(frozen=True)
class Capacity:
    """A grip type's limit on one demand: green up to ``green``, yellow up to
    ``yellow`` [unit]; below ``unscored_below`` green whatever the ratio (EAWS);
    ``repetitive_yellow`` lowers the yellow onset for work over 2 h a day."""

    id: str
    title: str
    demand: str
    unit: str
    green: float
    yellow: float
    capacity: float | None
    unscored_below: float
    repetitive_yellow: float | None
    sourced: Sourced

    def scaled(self, factor: float) -> Capacity:
        """The row with its capacity and limits times ``factor`` (EN 1005-3's
        m_v m_f m_d multipliers)."""
        return replace(self, green=self.green * factor, yellow=self.yellow * factor,
                       capacity=None if self.capacity is None else self.capacity * factor)


@dataclass(frozen=True)
class PartKind:
    """How a kind of part is judged: where its minimum bend radius is measured
    (``inside`` the bend or the ``centreline``), the fallback minimum (times the outer
    diameter; None: the datasheet value is required), whether Brazier's kink rule
    (thin-walled tubes) and the hose twist rule apply."""

    id: str
    bend_radius_to: str
    fallback_od: float | None
    fallback_source: str
    thin_walled: bool
    hose: bool
    sourced: Sourced


@dataclass(frozen=True)
class ObstacleRule:
    """What a packaging engineer says of one obstacle: its own clearance ``margin`` [m]
    (None: the scene's), its surface ``temperature`` [degC] (None: not hot), whether a
    heat ``shielded`` it, whether it is ``moving`` (a fan, a pulley, a shaft) and whether
    it has a sharp ``edge`` the part must not rest on."""

    margin: float | None = None
    temperature: float | None = None
    shielded: bool = False
    moving: bool = False
    edge: bool = False


@dataclass(frozen=True)
class Packaging:
    """The table's clearances to hot obstacles (unshielded, shielded) and to moving ones
    [m], and the sources of those and of the sharp-edge rule."""

    hot_unshielded: float
    hot_shielded: float
    hot: Sourced
    moving: float
    moving_sourced: Sourced
    edge: Sourced


@dataclass(frozen=True)
class HandEnvelope:
    """The space a fitter's hand and forearm take round a part they hold (the rules
    table's ``[access]``; ``pliant.assembly.access`` checks it), sized for the large
    hand that must fit: breadth across the knuckles and thickness at the metacarpals
    [m] (a pinch: two fingertips' breadth and a finger's thickness), from the part's axis
    to the wrist (``palm``) and on to the elbow (``forearm``) [m], the forearm's section
    (breadth, thickness) [m] at the wrist and at the elbow, a glove's thickness [m],
    the movement allowance [m] under which access is yellow, the approach directions
    tried round the part and the tilts [deg] of each along the part (a bent wrist), and
    the upper arm's radius [m] (``posture.Figure.swivelled``: where a worker is placed)."""

    breadth: float
    thickness: float
    pinch_breadth: float
    pinch_thickness: float
    palm: float
    forearm: float
    wrist: tuple[float, float]
    elbow: tuple[float, float]
    glove: float
    allowance: float
    directions: int
    sourced: Sourced
    tilts: tuple[float, ...] = (0.0,)  # deg: the forearm tilted along the part
    upper_arm: float = 0.06  # m: the upper arm's radius, shoulder to elbow (with clothing)


@dataclass(frozen=True)
class Body:
    """A population's body sizes (the rules table's ``[body]``): stature and
    shoulder-grip length (acromion to the centre of a gripped rod, arm straight) as
    (mean, SD) [m] per sex, and the heights and lengths the reach model needs as
    fractions of stature (shoulder, hip, knee, shoulder breadth, upper arm)."""

    population: str
    stature: dict[str, tuple[float, float]]
    shoulder_grip: dict[str, tuple[float, float]]
    shoulder_height: float
    hip_height: float
    knee_height: float
    shoulder_breadth: float
    upper_arm: float
    sourced: Sourced


@dataclass(frozen=True)
class PostureZones:
    """Where a held posture turns yellow and red (the rules table's ``[posture]``):
    upper-arm elevation and trunk inclination [deg] (yellow above the first, red above
    the second)."""

    upper_arm: tuple[float, float]
    trunk: tuple[float, float]
    sourced: Sourced


@dataclass(frozen=True)
class Rules:
    """The whole table (see ``pliant/data/rules.toml`` for every field's meaning)."""

    zones_green: float
    zones_yellow: float
    zones: Sourced
    hand_friction: float
    hand: Sourced
    capacities: dict[str, Capacity]
    tool_green: float
    tool_yellow: float
    tool: Sourced
    kinds: dict[str, PartKind]
    bend_margin: float
    bend_margin_sourced: Sourced
    fitting_straight: float
    fitting_tight: float
    fitting: Sourced
    kink_yellow: float
    kink_red: float
    kink_min_ratio: float
    kink: Sourced
    twist_yellow: float
    twist_red: float
    twist: Sourced
    packaging: Packaging
    stretch_margin: float = 1.25
    stretch: Sourced = Sourced("", "engineering choice")
    access: HandEnvelope | None = None  # None: the hand's access is not checked
    body: Body | None = None  # None: no reach or posture is judged
    posture: PostureZones | None = None
    origin: str = "bundled"

    def kind(self, name: str | None, field: str = "part.kind") -> PartKind | None:
        """The kind called ``name`` (None: not given); an unknown name is an error that
        lists the known ones."""
        if name is None:
            return None
        found = self.kinds.get(name.lower())
        if found is None:
            raise InputError(field, f"no part kind {name!r} in the rules ({self.origin}); "
                             f"known: {', '.join(sorted(self.kinds))}")
        return found


OPERATORS = ("auto", "one hand", "two hands", "tool", "robot")
HOLDS = ("power grip", "pinch")


@dataclass(frozen=True)
class EvaluationSettings:
    """How an operation is to be judged (a scene's ``[evaluation]``).

    operator : "auto" tries one hand, then two hands, then a tool or robot, and names the
        cheapest that passes; any other value judges that operator alone
    hold : how a hand holds the part: "power grip" (round it) or "pinch" (fingers)
    grips : the conditions a hand (or tool) holds; () for the path's grip, or every
        condition not at a port or clip when there is no path
    repetitive : work over 2 h a day (lower yellow onsets, Washington State checklist)
    multipliers : EN 1005-3's (m_v, m_f, m_d) on every hand capacity
    rating_force [N], rating_moment [N m] : the tool's or robot's rating, if known
    tool_envelope : the tool's or robot's gripper round the part, (length from the part's
        axis, breadth along the part, thickness across, jaws' thickness) [m], checked for
        room as a hand is (None: not checked)
    port : where the part is seated at the last step (None: the port at the path's end)
    connector_force [N] : the connector's own mating force, added to the last push
    max_twist_rate [deg/m] : a cable's torsion rating, if known
    max_contact_force [N] : the most any obstacle may press on the part, if limited
    rules : a rules file replacing the bundled table (None: bundled)
    """

    operator: str = "auto"
    hold: str = "power grip"
    grips: tuple[str, ...] = ()
    repetitive: bool = False
    multipliers: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rating_force: float | None = None
    rating_moment: float | None = None
    tool_envelope: tuple[float, float, float, float] | None = None
    port: str | None = None
    connector_force: float = 0.0
    max_twist_rate: float | None = None
    max_contact_force: float | None = None
    rules: str | None = None

    def __post_init__(self) -> None:
        if self.operator not in OPERATORS:
            raise InputError("evaluation.operator", f"must be one of {', '.join(OPERATORS)}; "
                             f"got {self.operator!r}")
        if self.hold not in HOLDS:
            raise InputError("evaluation.hold", f"must be one of {', '.join(HOLDS)}; got "
                             f"{self.hold!r}")
        if len(self.multipliers) != 3 or not all(0.0 < m <= 1.0 for m in self.multipliers):
            raise InputError("evaluation.multipliers", "give EN 1005-3's three multipliers "
                             f"(m_v, m_f, m_d), each in (0, 1]; got {self.multipliers!r}")
        for name in ("rating_force", "rating_moment", "max_twist_rate", "max_contact_force"):
            value = getattr(self, name)
            if value is not None and not value > 0.0:
                raise InputError(f"evaluation.{name}", f"must be positive, got {value!r}")
        if not self.connector_force >= 0.0:
            raise InputError("evaluation.connector_force", "must be zero or positive [N], "
                             f"got {self.connector_force!r}")
        if self.operator in ("tool", "robot") and self.rating_force is None:
            raise InputError("evaluation.rating", f"judging a {self.operator} needs its rating: "
                             "give rating = {force = N, moment = N m}")

    @property
    def capacity_factor(self) -> float:
        m_v, m_f, m_d = self.multipliers
        return m_v * m_f * m_d
