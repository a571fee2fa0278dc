"""The flexible part: length, stiffness, mass and rest shape, in SI units."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pliant.errors import InputError


def _positive(name: str, value: float, unit: str) -> float:
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise InputError(name, f"must be a positive number in {unit}, got {value!r}")
    return value


def _non_negative(name: str, value: float, unit: str) -> float:
    value = float(value)
    if not math.isfinite(value) or value < 0.0:
        raise InputError(name, f"must be zero or a positive number in {unit}, got {value!r}")
    return value


@dataclass(frozen=True)
class Material:
    """An isotropic elastic material.

    youngs_modulus : float [Pa]
    density : float [kg/m^3]
    shear_modulus : float [Pa]; from the Poisson ratio when not given.
    """

    youngs_modulus: float
    density: float = 0.0
    shear_modulus: float | None = None
    poisson_ratio: float = 0.5
    name: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "youngs_modulus",
                           _positive("youngs_modulus", self.youngs_modulus, "Pa"))
        object.__setattr__(self, "density", _non_negative("density", self.density, "kg/m^3"))
        nu = float(self.poisson_ratio)
        if not -1.0 < nu <= 0.5:
            raise InputError("poisson_ratio", f"must lie in (-1, 0.5], got {nu!r}")
        if self.shear_modulus is None:
            object.__setattr__(self, "shear_modulus", self.youngs_modulus / (2.0 * (1.0 + nu)))
        else:
            object.__setattr__(self, "shear_modulus",
                               _positive("shear_modulus", self.shear_modulus, "Pa"))


@dataclass(frozen=True)
class Part:
    """A beam-type flexible part (hose, pipe, cable).

    length : float [m]
    bending_stiffness : float [N m^2], EI
    mass_per_length : float [kg/m], for self-weight
    torsional_stiffness : float [N m^2] or None, GJ (the 3D model); when not given, that
        of a solid round section of an incompressible material, GJ = EI / 1.5
    bending_stiffness_2 : float [N m^2] or None, EI about the section's second axis d2
        (3D, anisotropic sections); when not given, the section is isotropic
    outer_diameter, inner_diameter : float [m] or None, the tube section (display, contact)
    rest_curvature : float [1/m], or a sequence of (s [m], kappa [1/m]) knots interpolated
        linearly; the curvature of the unloaded neutral line (pre-formed hoses). In 3D it is
        the curvature about the first section axis d1 (the 2D plane's normal).
    rest_curvature_2, rest_twist : the same, about d2 and about the tangent d3 (3D)
    min_bend_radius : float [m] or None, the smallest radius the part tolerates (as its
        datasheet quotes it: to the inside of the bend for hoses, see ``kind``)
    kind : str or None, what the part is for the A/D evaluation's damage rules ("coolant
        hose", "thin-walled tube", "wire", ...: the rules table's kinds)
    poisson_ratio : float or None, of the wall's material (the kink rule of thin tubes)
    axial_stiffness : float [N] or None, EA: the part stretches by the axial strain N / EA
        (both accurate models); None is an inextensible part, the limit EA -> infinity.
        A cable's EA is far below its copper's (strands and lay); give a measured one.
    max_axial_strain : float or None, the axial strain the part tolerates (the damage
        rule of a part pulled taut)
    max_temperature : float [degC] or None, the highest surface temperature the part
        tolerates (its datasheet's continuous service temperature): the packaging rule
        of hot obstacles

    The material frame (d1, d2, d3) is right-handed with d3 the tangent; a 2D problem is
    the 3D one in the plane z = 0 with d1 = +z, so that bending there is about d1.
    """

    length: float
    bending_stiffness: float
    mass_per_length: float = 0.0
    torsional_stiffness: float | None = None
    outer_diameter: float | None = None
    inner_diameter: float = 0.0
    rest_curvature: float | tuple[tuple[float, float], ...] = 0.0
    min_bend_radius: float | None = None
    name: str = "part"
    bending_stiffness_2: float | None = None
    rest_curvature_2: float | tuple[tuple[float, float], ...] = 0.0
    rest_twist: float | tuple[tuple[float, float], ...] = 0.0
    kind: str | None = None
    poisson_ratio: float | None = None
    axial_stiffness: float | None = None
    max_axial_strain: float | None = None
    max_temperature: float | None = None
    rest_knots: tuple[tuple[float, float], ...] = field(init=False, repr=False)
    rest_knots_2: tuple[tuple[float, float], ...] = field(init=False, repr=False)
    twist_knots: tuple[tuple[float, float], ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "length", _positive("length", self.length, "m"))
        set_(self, "bending_stiffness",
             _positive("bending_stiffness", self.bending_stiffness, "N m^2"))
        set_(self, "mass_per_length",
             _non_negative("mass_per_length", self.mass_per_length, "kg/m"))
        if self.torsional_stiffness is not None:
            set_(self, "torsional_stiffness",
                 _positive("torsional_stiffness", self.torsional_stiffness, "N m^2"))
        if self.outer_diameter is not None:
            set_(self, "outer_diameter", _positive("outer_diameter", self.outer_diameter, "m"))
            inner = _non_negative("inner_diameter", self.inner_diameter, "m")
            if inner >= self.outer_diameter:
                raise InputError("inner_diameter",
                                 f"must be smaller than outer_diameter {self.outer_diameter} m, "
                                 f"got {inner} m")
            set_(self, "inner_diameter", inner)
        if self.min_bend_radius is not None:
            set_(self, "min_bend_radius",
                 _positive("min_bend_radius", self.min_bend_radius, "m"))
        if self.axial_stiffness is not None:
            set_(self, "axial_stiffness", _positive("axial_stiffness", self.axial_stiffness, "N"))
            slenderness = self.bending_stiffness / (self.axial_stiffness * self.length**2)
            if slenderness > 1e-2:
                raise InputError("axial_stiffness",
                                 f"EA = {self.axial_stiffness:g} N makes the part as short "
                                 f"and thick as a block (EI / (EA L^2) = {slenderness:.3g}, "
                                 "a hose or cable is below 1e-4): check its unit (N) and the "
                                 "length")
        if self.max_axial_strain is not None:
            set_(self, "max_axial_strain",
                 _positive("max_axial_strain", self.max_axial_strain, "(a strain, 0.01 = 1 %)"))
        if self.bending_stiffness_2 is not None:
            set_(self, "bending_stiffness_2",
                 _positive("bending_stiffness_2", self.bending_stiffness_2, "N m^2"))
        if self.kind is not None and not (isinstance(self.kind, str) and self.kind.strip()):
            raise InputError("kind", f"must be the name of a part kind, got {self.kind!r}")
        if self.poisson_ratio is not None:
            nu = float(self.poisson_ratio)
            if not -1.0 < nu <= 0.5:
                raise InputError("poisson_ratio", f"must lie in (-1, 0.5], got {nu!r}")
            set_(self, "poisson_ratio", nu)
        for given, knots in (("rest_curvature", "rest_knots"), ("rest_curvature_2", "rest_knots_2"),
                             ("rest_twist", "twist_knots")):
            profile = self._knots(getattr(self, given), given)
            set_(self, knots, profile)
            # A constant profile over the whole part is that number, however it was given
            # (a file writes it as knots): the same part compares equal.
            if len(profile) == 2 and profile[0] == (0.0, profile[1][1]) and \
                    profile[1][0] == self.length:
                set_(self, given, profile[1][1])

    def _knots(self, rest: float | Sequence[Sequence[float]],
               name: str) -> tuple[tuple[float, float], ...]:
        if isinstance(rest, (int, float)):
            kappa = float(rest)
            if not math.isfinite(kappa):
                raise InputError(name, f"must be finite, got {kappa!r}")
            return ((0.0, kappa), (self.length, kappa))
        knots: list[tuple[float, float]] = []
        for i, pair in enumerate(rest):
            if len(pair) != 2:
                raise InputError(f"{name}[{i}]", "each knot is a pair (s [m], curvature [1/m])")
            s, kappa = float(pair[0]), float(pair[1])
            if not (math.isfinite(s) and math.isfinite(kappa)):
                raise InputError(f"{name}[{i}]", "must be finite numbers")
            if not 0.0 <= s <= self.length:
                raise InputError(f"{name}[{i}]",
                                 f"s = {s} m lies outside the part [0, {self.length}] m")
            if knots and s <= knots[-1][0]:
                raise InputError(f"{name}[{i}]", "knots must be given with strictly increasing s")
            knots.append((s, kappa))
        if not knots:
            raise InputError(name, "give a number or at least one (s, kappa) knot")
        return tuple(knots)

    @classmethod
    def tube(cls, length: float, outer_diameter: float, material: Material,
             inner_diameter: float = 0.0, extensible: bool = False, **kwargs) -> Part:
        """A part with a circular (hollow) section of a given material.

        EI = E pi (D^4 - d^4) / 64, GJ = G pi (D^4 - d^4) / 32, mass = rho pi (D^2 - d^2) / 4,
        and with ``extensible`` EA = E pi (D^2 - d^2) / 4.
        """
        outer = _positive("outer_diameter", outer_diameter, "m")
        inner = _non_negative("inner_diameter", inner_diameter, "m")
        if inner >= outer:
            raise InputError("inner_diameter",
                             f"must be smaller than outer_diameter {outer} m, got {inner} m")
        second_moment = math.pi * (outer**4 - inner**4) / 64.0
        area = math.pi * (outer**2 - inner**2) / 4.0
        assert material.shear_modulus is not None
        kwargs.setdefault("poisson_ratio", material.poisson_ratio)
        if extensible:
            kwargs.setdefault("axial_stiffness", material.youngs_modulus * area)
        return cls(length=length,
                   bending_stiffness=material.youngs_modulus * second_moment,
                   torsional_stiffness=material.shear_modulus * 2.0 * second_moment,
                   mass_per_length=material.density * area,
                   outer_diameter=outer, inner_diameter=inner, **kwargs)

    @property
    def straight_at_rest(self) -> bool:
        return all(kappa == 0.0 for knots in (self.rest_knots, self.rest_knots_2,
                                              self.twist_knots) for _, kappa in knots)

    @property
    def tube_radius(self) -> float:
        """The radius [m] of the tube kept out of obstacles: half the outer diameter (0,
        a line, when the part has none)."""
        return 0.5 * self.outer_diameter if self.outer_diameter else 0.0

    @property
    def drawn_radius(self) -> float:
        """The radius [m] a tube of the part is drawn and measured with: half the outer
        diameter, or 1 % of the length for a part given none (a line has no surface)."""
        return 0.5 * self.outer_diameter if self.outer_diameter else 0.01 * self.length

    @property
    def stiffnesses(self) -> tuple[float, float, float]:
        """(EI1, EI2, GJ) [N m^2]: bending about d1 and d2, torsion about d3."""
        ei2 = self.bending_stiffness_2 or self.bending_stiffness
        gj = self.torsional_stiffness or self.bending_stiffness / 1.5
        return self.bending_stiffness, ei2, gj

    def rest_curvature_at(self, s: float) -> float:
        """Rest curvature [1/m] at arc length s [m] (linear between knots)."""
        return _interpolate(self.rest_knots, s)

    def rest_curvature_along(self, s: np.ndarray) -> np.ndarray:
        """``rest_curvature_at`` at every arc length of s [m] (2D)."""
        return _interpolate_many(self.rest_knots, np.asarray(s, float))

    def rest_darboux_along(self, s: np.ndarray) -> np.ndarray:
        """(n, 3) rest curvatures about (d1, d2) and rest twist [1/m] at arc lengths s
        (n,) [m]: ``rest_darboux_at`` for many points at once."""
        s = np.asarray(s, float)
        return np.column_stack([_interpolate_many(k, s) for k in (
            self.rest_knots, self.rest_knots_2, self.twist_knots)])

    def rest_darboux_at(self, s: float) -> tuple[float, float, float]:
        """Rest curvatures about (d1, d2) and rest twist [1/m] at s [m] (3D)."""
        return (_interpolate(self.rest_knots, s), _interpolate(self.rest_knots_2, s),
                _interpolate(self.twist_knots, s))

    @property
    def knot_positions(self) -> tuple[float, ...]:
        """Interior arc lengths [m] where a rest-curvature profile has a kink."""
        out: set[float] = set()
        for knots in (self.rest_knots, self.rest_knots_2, self.twist_knots):
            out.update(s for s, _ in knots if 0.0 < s < self.length)
        return tuple(sorted(out))


def _interpolate(knots: tuple[tuple[float, float], ...], s: float) -> float:
    if s <= knots[0][0]:
        return knots[0][1]
    for (s0, k0), (s1, k1) in itertools.pairwise(knots):
        if s <= s1:
            return k0 + (k1 - k0) * (s - s0) / (s1 - s0)
    return knots[-1][1]


def _interpolate_many(knots: tuple[tuple[float, float], ...], s: np.ndarray) -> np.ndarray:
    """``_interpolate`` at every s: linear between knots, constant beyond the ends."""
    xs = np.array([k[0] for k in knots])
    ys = np.array([k[1] for k in knots])
    return np.interp(s, xs, ys)
