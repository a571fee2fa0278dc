"""The rules of an A/D evaluation as pure functions of one equilibrium: a grip's wrench
split into the parts a hand feels, the bend radius against the part's minimum, the
flattening of a thin-walled tube (Brazier), the twist between fittings, and the zone a
value falls in. ``pliant.assembly.evaluate`` applies them along a path.

Brazier's flattening, derived again (Calladine, *Theory of Shell Structures*, 1983,
ch. 15; Brazier, Proc. R. Soc. A 116, 1927). A thin tube of mean radius a and wall t
bent to curvature kappa ovalises by the inextensional mode w = a zeta cos 2 phi,
v = -(a zeta / 2) sin 2 phi (hoop strain (v' + w) / a = 0). A wall point then lies at
y = a sin phi (1 - zeta sin^2 phi) from the neutral axis, so the axial strain kappa y
stores, per length, (1/2) E t kappa^2 a^3 (pi - 2 zeta 3 pi / 4 + zeta^2 5 pi / 8) =
(1/2) E I kappa^2 (1 - 3 zeta / 2 + 5 zeta^2 / 8) with I = pi a^3 t; the wall's hoop
bending, its curvature change -3 zeta cos 2 phi / a, stores 9 pi D zeta^2 / (2 a) with
D = E t^3 / (12 (1 - nu^2)). Minimising over zeta (to first order in zeta, as Brazier
did) gives zeta = (1 - nu^2) a^4 kappa^2 / t^2, and the moment M = dU/dkappa =
E I kappa (1 - 3 zeta / 2) peaks where 1 - 9 zeta / 2 = 0: zeta = 2/9 at
kappa_B = (sqrt 2 / 3) t / (a^2 sqrt(1 - nu^2)). Past it the section kinks.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum
from typing import Any

import numpy as np

from pliant.core.numbers import clean


class Zone(str, Enum):  # noqa: UP042 (str() and format() stay as they print now)
    """A check's result: green (acceptable), yellow (acceptable with reservations: a
    margin is used up, or a risk to watch), red (not acceptable), unchecked (the rule
    could not be applied: a value is missing, and the report says which), info (a
    figure reported with no threshold)."""

    GREEN = "green"
    YELLOW = "yellow"
    RED = "red"
    UNCHECKED = "unchecked"
    INFO = "info"

    @property
    def rank(self) -> int:
        return {"info": 0, "green": 0, "unchecked": 1, "yellow": 2, "red": 3}[self.value]


def zone_of(value: float, yellow_at: float | None, red_at: float | None, worse: str,
            unscored_below: float = 0.0) -> Zone:
    """The zone of ``value``: with worse = "above", yellow above ``yellow_at`` and red
    above ``red_at``; with "below", yellow below ``yellow_at`` and red below
    ``red_at``. A limit of None never trips; above-rules under ``unscored_below`` are
    green whatever (EAWS)."""
    if not math.isfinite(value) and worse == "below" and value > 0:
        return Zone.GREEN
    if worse == "above":
        if value < unscored_below:
            return Zone.GREEN
        if red_at is not None and value > red_at:
            return Zone.RED
        if yellow_at is not None and value > yellow_at:
            return Zone.YELLOW
        return Zone.GREEN
    if red_at is not None and value < red_at:
        return Zone.RED
    if yellow_at is not None and value < yellow_at:
        return Zone.YELLOW
    return Zone.GREEN


@dataclass(frozen=True)
class Wrench:
    """The load a grip applies to the part, split at the part's tangent t there.

    axial [N]: F . outward, positive when the grip pulls the part out along itself
    (tension), negative when it pushes; lateral [N]: |F - (F.t) t|; twist [N m]: M . t;
    bending [N m]: |M - (M.t) t|; force [N] |F|; moment [N m] |M|."""

    axial: float
    lateral: float
    twist: float
    bending: float
    force: float
    moment: float

    def grip_force(self, friction: float) -> float:
        """The squeeze [N] a power grip needs: the axial load carried by friction on
        both faces of the hand, |axial| / (2 mu), or the lateral load it bears
        directly, whichever is larger."""
        return max(abs(self.axial) / (2.0 * friction), self.lateral)

    def demand(self, name: str, friction: float) -> float:
        """The demand a capacity row limits (``pliant.core.rules.DEMANDS``)."""
        if name == "grip":
            return self.grip_force(friction)
        if name in ("axial", "twist"):
            return abs(getattr(self, name))
        return float(getattr(self, name))


def split_wrench(force: np.ndarray, moment: np.ndarray, tangent: np.ndarray,
                 outward: float = 1.0) -> Wrench:
    """Split force (3,) [N] and moment (3,) [N m] at a unit ``tangent`` (3,); ``outward``
    is +1 where the tangent points out of the part (its last end, s = L) and -1 where it
    points in (its first end), so that ``axial`` is the pull."""
    force = np.asarray(force, float)
    moment = np.asarray(moment, float)
    t = np.asarray(tangent, float) / np.linalg.norm(tangent)
    f_t = float(force @ t)
    m_t = float(moment @ t)
    return Wrench(axial=outward * f_t, lateral=float(np.linalg.norm(force - f_t * t)),
                  twist=m_t, bending=float(np.linalg.norm(moment - m_t * t)),
                  force=float(np.linalg.norm(force)), moment=float(np.linalg.norm(moment)))


def centreline_min_radius(min_bend_radius: float, outer_diameter: float | None,
                          measured_to: str) -> float:
    """The smallest centreline radius [m] a datasheet minimum allows: hoses quote it to
    the inside of the bend, so the centreline may come OD / 2 closer."""
    if measured_to == "inside":
        if outer_diameter is None:
            raise ValueError("an inside bend radius needs the part's outer_diameter")
        return min_bend_radius + 0.5 * outer_diameter
    return min_bend_radius


def tube_section(outer_diameter: float, inner_diameter: float) -> tuple[float, float]:
    """(mean radius a [m], wall t [m]) of a round tube."""
    return 0.25 * (outer_diameter + inner_diameter), 0.5 * (outer_diameter - inner_diameter)


def brazier_flattening(curvature: float | np.ndarray, mean_radius: float, wall: float,
                       poisson_ratio: float) -> float | np.ndarray:
    """zeta = (1 - nu^2) a^4 kappa^2 / t^2, the section's relative flattening at
    curvature kappa [1/m] (see the module's derivation)."""
    return (1.0 - poisson_ratio**2) * mean_radius**4 * np.square(curvature) / wall**2


def brazier_kink_curvature(mean_radius: float, wall: float, poisson_ratio: float) -> float:
    """kappa_B [1/m] = (sqrt 2 / 3) t / (a^2 sqrt(1 - nu^2)), where the bending moment of
    an ovalising tube peaks and it kinks (zeta = 2/9)."""
    return math.sqrt(2.0) / 3.0 * wall / (mean_radius**2 * math.sqrt(1.0 - poisson_ratio**2))


def max_torque(eq: Any) -> float:
    """The largest twisting moment [N m] along a 3D answer (an ``Equilibrium3D`` or the
    session's ``AccurateResult``); one that is the solver's round-off beside the part's
    bending moments (a part free to twist carries none) is the 0 it is."""
    bending = eq.bending_magnitude if hasattr(eq, "bending_magnitude") else eq.bending_moment
    scale = float(np.max(np.abs(bending), initial=0.0))
    return clean([float(np.max(np.abs(eq.torque), initial=0.0))], scale)[0]


def twist_angle(s: np.ndarray, torque: np.ndarray, torsional_stiffness: float,
                s_from: float, s_to: float) -> float:
    """The twist [rad] of the part between s_from and s_to [m]: the integral of the
    twist strain torque / GJ (Kirchhoff: m3 = GJ (kappa3 - kappa3_rest)), trapezoidal
    over the nodes (s (n,) [m], torque (n,) [N m])."""
    a, b = sorted((s_from, s_to))
    inside = (s >= a - 1e-12) & (s <= b + 1e-12)
    if inside.sum() < 2:
        return 0.0
    strain = torque[inside] / torsional_stiffness
    ss = s[inside]
    return float(np.sum(0.5 * (strain[1:] + strain[:-1]) * np.diff(ss)))


def tight_near(s: np.ndarray, curvature: np.ndarray, s_fitting: float,
               straight: float) -> tuple[float, float]:
    """(the smallest bend radius [m] within ``straight`` [m] of a fitting at s_fitting,
    and where): the vendor rule wants that stretch nearly straight."""
    near = np.abs(s - s_fitting) <= straight
    if not near.any():
        return math.inf, s_fitting
    k = np.where(near, curvature, 0.0)
    i = int(np.argmax(k))
    return (math.inf if k[i] == 0.0 else 1.0 / float(k[i])), float(s[i])


# -- warnings ------------------------------------------------------------------------------
# What a shape should warn a fitter of, said the same way everywhere: the CLI's summary,
# the viewer's accurate answers and its real-time frames (the page only shows what
# arrives) take their warnings from ``shape_warnings``. A real-time frame's are marked as
# the preview's: its shape is the bar network's, not the accurate model's.
PREVIEW = "the real-time preview: "  # how a real-time frame's warnings begin


def shape_warnings(*, bend_radius: float, bend_at: float, allowed: float | None,
                   stable: bool | None = None, eigenvalue: float | None = None,
                   penetrations: Iterable[Any] = (), preview: bool = False) -> list[str]:
    """The warnings of one shape, in plain words with their values and thresholds.

    bend_radius, bend_at : the smallest bend radius [m] and where [m]; allowed : the
        centreline limit [m] (``evaluate.centreline_bend_limit``; None: unchecked);
        stable, eigenvalue : the stability verdict and smallest eigenvalue [N m] (None:
        undecided or not computed); penetrations : spans (``obstacle``, ``s_start``,
        ``s_end``, ``worst`` [m], negative inside);
        preview : the shape is the real-time model's.
    """
    out = []
    if allowed and math.isfinite(bend_radius) and bend_radius < allowed:
        out.append(f"bend radius {bend_radius * 1e3:.1f} mm at s = {bend_at:.3f} m is "
                   f"below the part's limit {allowed * 1e3:.1f} mm (centreline)")
    if stable is False:
        detail = "" if eigenvalue is None else (
            f" (smallest stiffness eigenvalue {eigenvalue:.3g} N m)")
        out.append(f"unstable shape: the part would snap to another one{detail}")
    for span in penetrations:
        out.append(f"enters {span.obstacle} by {-span.worst * 1e3:.1f} mm over s = "
                   f"{span.s_start:.3f} to {span.s_end:.3f} m")
    return [PREVIEW + w for w in out] if preview else out
