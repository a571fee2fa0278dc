"""What a stiffness test measured, in SI units: the nouns ``identify`` fits the model to.

A test is a problem (the part as first guessed, its conditions, gravity) plus which of the
part's parameters are unknown and one or more measurements. Each measurement says what was
measured and under which loads; its ``uncertainty`` (one standard deviation, in the unit of
what it measures) weighs it against the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pliant.core.problem import Problem
from pliant.errors import InputError

# The parameters a test can identify, with their units.
UNKNOWNS = {"bending_stiffness": "N m^2", "bending_stiffness_2": "N m^2",
            "torsional_stiffness": "N m^2", "mass_per_length": "kg/m"}


@dataclass(frozen=True, eq=False)
class Shape:
    """Points measured on the part's neutral line, (n, 2) or (n, 3) [m], under the test's
    own conditions; their order does not matter (the fit measures each point's distance
    to the curve, normal to it)."""

    points: np.ndarray
    uncertainty: float | None = None  # [m]
    name: str = "shape"
    unit: str = "m"


@dataclass(frozen=True, eq=False)
class Deflection:
    """The position of the station ``s`` [m] under each of several loads applied by the
    condition ``condition`` along ``direction``: ``load`` (n,) [N], ``position`` (n, d) [m]
    with NaN where a coordinate was not measured (a dial gauge reads one). ``relative``:
    the positions are displacements from the pose under no load from the condition (a
    gauge zeroed before the first weight is hung, the part's own weight already on it)."""

    condition: str
    direction: np.ndarray
    s: float
    load: np.ndarray
    position: np.ndarray
    uncertainty: float | None = None  # [m]
    name: str = "deflection"
    unit: str = "m"
    relative: bool = False


@dataclass(frozen=True, eq=False)
class ThreePointBending:
    """A three-point bending test: the part lies on two supports ``span`` [m] apart (it
    slides on them, frictionless) and is pushed down at its middle; ``displacement`` (n,)
    [m] of the middle against the supports and the ``load`` (n,) [N] the ram needs.
    Large deflections are fine; the part's weight is neglected, as the test does."""

    span: float
    displacement: np.ndarray
    load: np.ndarray
    uncertainty: float | None = None  # [N]
    name: str = "three-point bending"
    unit: str = "N"


@dataclass(frozen=True, eq=False)
class Twist:
    """A torsion test: a straight length ``length`` [m] of the part held in two chucks,
    one turned by ``angle`` (n,) [rad]; the ``moment`` (n,) [N m] it needs."""

    length: float
    angle: np.ndarray
    moment: np.ndarray
    uncertainty: float | None = None  # [N m]
    name: str = "twist"
    unit: str = "N m"


@dataclass(frozen=True, eq=False)
class TwistBuckling:
    """The angle ``angle`` [rad] by which the condition ``condition`` (a clamp) was turned
    about its own axis when the part, held as the test's conditions hold it (a straight
    length between chucks, a loop), buckled or snapped out of shape."""

    condition: str
    angle: float
    uncertainty: float | None = None  # [rad]
    name: str = "twist buckling"
    unit: str = "rad"


Measurement = Shape | Deflection | ThreePointBending | Twist | TwistBuckling


@dataclass(frozen=True, eq=False)
class StiffnessTest:
    """A problem, the unknowns among ``UNKNOWNS`` (the part's values are the first
    guess) and what was measured; ``confidence`` the level of the intervals."""

    problem: Problem
    unknowns: tuple[str, ...]
    measured: tuple[Measurement, ...]
    confidence: float = 0.95
    name: str = ""
    sources: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if not self.unknowns:
            raise InputError("identify.unknowns", "name at least one of "
                             + ", ".join(UNKNOWNS))
        for u in self.unknowns:
            if u not in UNKNOWNS:
                raise InputError("identify.unknowns", f"{u!r} is not a parameter a test "
                                 f"identifies; give any of {', '.join(UNKNOWNS)}")
        if len(set(self.unknowns)) != len(self.unknowns):
            raise InputError("identify.unknowns", "names a parameter twice")
        if self.problem.dimension == 2 and {"bending_stiffness_2", "torsional_stiffness"} & set(
                self.unknowns) and not any(isinstance(m, Twist) for m in self.measured):
            raise InputError("identify.unknowns", "a 2D test bends the part in its plane "
                             "only: it cannot tell bending_stiffness_2 or "
                             "torsional_stiffness; measure in 3D or twist the part")
        if not 0.5 <= self.confidence < 1.0:
            raise InputError("identify.confidence", f"must lie in [0.5, 1), got "
                             f"{self.confidence!r} (0.95 for 95 % intervals)")
        if not self.measured:
            raise InputError("measured", "give at least one [[measured]] table")
