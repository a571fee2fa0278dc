"""A wire harness as its design data describe it (KBL, VDA 4964), in SI units.

The nouns ``pliant.io.kbl`` builds and ``pliant.assembly.harness`` turns into properties,
checks and rods: nodes (points where segments meet, connectors sit or a bundle ends),
segments (a bundle between two nodes, its designed centre curve and length), the wire
types and the wires routed through the segments, fixings (clips, ducts) placed on
segments, connectors, protections (tape, tubes) and modules (the variants a harness is
built in). Ids are the file's element ids; names are the ids the designer gave
(``<Id>``). Every length is in metres, masses per length in kg/m.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pliant.errors import InputError

UNCLAMPED = "unclamped"  # a uniform knot vector 0, 1, ..., n + p: its domain is [p, n]
CLAMPED = "clamped"  # p + 1 equal knots at each end: the curve starts at its first point


@dataclass(frozen=True, eq=False)
class CentreCurve:
    """One piece of a segment's designed centre curve: a uniform non-rational B-spline
    of ``degree`` over ``control_points`` ((n, 3) float [m])."""

    degree: int
    control_points: np.ndarray

    def knots(self, convention: str) -> np.ndarray:
        """Its knot vector under ``convention`` (``UNCLAMPED`` or ``CLAMPED``)."""
        n, p = len(self.control_points), self.degree
        if convention == UNCLAMPED:
            return np.arange(n + p + 1, dtype=float)
        inner = n - p - 1
        return np.r_[np.zeros(p + 1), np.arange(1, inner + 1) / (inner + 1), np.ones(p + 1)]

    def domain(self, convention: str) -> tuple[float, float]:
        t = self.knots(convention)
        return float(t[self.degree]), float(t[len(self.control_points)])

    def points(self, convention: str, count: int = 64, derivative: int = 0) -> np.ndarray:
        """(count, 3) points [m] (or their ``derivative``-th derivatives in the curve's
        parameter), evenly in the parameter over its domain."""
        from scipy.interpolate import BSpline  # noqa: PLC0415 (scipy: only curves need it)

        a, b = self.domain(convention)
        spline = BSpline(self.knots(convention), self.control_points, self.degree)
        if derivative:
            spline = spline.derivative(derivative)
        return spline(np.linspace(a, b, count))

    def curvature(self, convention: str, count: int = 4001) -> np.ndarray:
        """(count,) curvature [1/m] |r' x r''| / |r'|^3 from the spline's derivatives,
        evenly in its parameter."""
        d1 = self.points(convention, count, 1)
        d2 = self.points(convention, count, 2) if self.degree >= 2 else np.zeros_like(d1)
        speed = np.linalg.norm(d1, axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.linalg.norm(np.cross(d1, d2), axis=1) / speed**3
        return np.nan_to_num(k)


@dataclass(frozen=True)
class HarnessNode:
    """A point of the harness's topology: ``position`` (3,) [m]; ``components``: the
    ids of what sits there (connectors, terminals, components)."""

    id: str
    name: str
    position: tuple[float, float, float]
    components: tuple[str, ...] = ()


@dataclass(frozen=True)
class FixingPlace:
    """A fixing assigned to a segment: at ``location`` (0 at the start node, 1 at the
    end), its ``orientation`` (3,) as the file gives it (a direction, or None)."""

    fixing: str  # a Fixing.id
    location: float
    orientation: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class ProtectionPlace:
    """A protection (tape, tube) over a stretch of a segment (fractions of its length)."""

    protection: str  # a Protection.id
    start: float
    end: float


@dataclass(frozen=True, eq=False)
class HarnessSegment:
    """A bundle between two nodes: its designed centre curve (one or more B-spline
    pieces, end to end, from the start node to the end node), its designed length
    ``virtual_length`` [m], the tangents it leaves its nodes with (unit, or None),
    the file's cross-section area [m^2] and how it was determined ("reserved",
    "calculated", ...), and the fixings and protections placed on it."""

    id: str
    name: str
    start: str  # a node id
    end: str
    virtual_length: float
    curves: tuple[CentreCurve, ...]
    start_vector: tuple[float, float, float] | None = None
    end_vector: tuple[float, float, float] | None = None
    cross_section_area: float | None = None
    cross_section_kind: str = ""
    fixings: tuple[FixingPlace, ...] = ()
    protections: tuple[ProtectionPlace, ...] = ()

    def __post_init__(self) -> None:
        if not self.virtual_length > 0:
            raise InputError(f"Segment {self.id}.Virtual_length",
                             f"{self.virtual_length} m: a segment's length must be positive")


@dataclass(frozen=True)
class WireType:
    """A wire (or a multicore cable) as a part: ``outside_diameter`` [m], conductor
    ``cross_section_area`` [m^2] (a multicore's: its cores' sum), the smallest
    ``bend_radius`` [m] it may be bent to, ``mass_per_length`` [kg/m] (None where the
    file gives none), and for a multicore its ``cores`` count and their diameters."""

    id: str
    part_number: str
    description: str
    outside_diameter: float | None
    cross_section_area: float | None
    bend_radius: float | None
    mass_per_length: float | None
    cores: int = 0
    core_diameters: tuple[float, ...] = ()  # [m] a multicore's cores' outside diameters


@dataclass(frozen=True)
class Wire:
    """A wire (or multicore cable) of the harness: an occurrence of a ``WireType``, its
    designed length [m] (None where the file gives none), and the segments it runs
    through, in order."""

    id: str
    name: str
    type: str  # a WireType.id
    length: float | None
    segments: tuple[str, ...] = ()


@dataclass(frozen=True)
class Placement:
    """Where a fixing or a connector sits: ``point`` (3,) [m] and its frame's first two
    axes ``u``, ``v`` (unit)."""

    point: tuple[float, float, float]
    u: tuple[float, float, float]
    v: tuple[float, float, float]


@dataclass(frozen=True)
class Fixing:
    """A clip, cable tie or duct of the harness: its part's ``kind`` (the file's
    ``Fixing_type``), description and where the design places it (or None)."""

    id: str
    name: str
    part_number: str
    description: str
    kind: str
    placement: Placement | None = None


@dataclass(frozen=True)
class Connector:
    """A connector (or a ring terminal) the harness ends in: its ``usage`` and where
    the design places it (or None), and the node it sits at (or "")."""

    id: str
    name: str
    description: str
    usage: str = ""
    placement: Placement | None = None
    node: str = ""


@dataclass(frozen=True)
class Protection:
    """A protection occurrence (tape, tube, sleeve): its ``kind``, ``length`` [m] and
    ``mass_per_length`` [kg/m] (None where the file gives none)."""

    id: str
    name: str
    kind: str
    description: str
    length: float | None
    mass_per_length: float | None


@dataclass(frozen=True)
class Module:
    """A module (a variant) of the harness: the ids of the occurrences it brings."""

    id: str
    part_number: str
    description: str
    components: frozenset[str] = frozenset()


@dataclass(frozen=True, eq=False)
class Harness:
    """A whole harness from its design data. ``convention``: how its centre curves'
    B-splines are read (decided from the data: ``UNCLAMPED`` or ``CLAMPED``);
    ``source``: the file and its KBL version; ``notes``: what the reader decided or
    found and the user should know (schema deviations, curves that miss their nodes)."""

    name: str
    part_number: str
    source: str
    version: str
    convention: str
    nodes: dict[str, HarnessNode]
    segments: dict[str, HarnessSegment]
    wire_types: dict[str, WireType]
    wires: dict[str, Wire]
    fixings: dict[str, Fixing]
    connectors: dict[str, Connector]
    protections: dict[str, Protection]
    modules: dict[str, Module] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def length(self) -> float:
        """The sum of the segments' designed lengths [m]."""
        return float(sum(s.virtual_length for s in self.segments.values()))

    def wires_in(self, segment: str) -> tuple[Wire, ...]:
        """The wires (each multicore cable once) that run through ``segment``."""
        return tuple(w for w in self.wires.values() if segment in w.segments)

    def degree(self, node: str) -> int:
        """How many segments meet at ``node``."""
        return sum((s.start == node) + (s.end == node) for s in self.segments.values())
