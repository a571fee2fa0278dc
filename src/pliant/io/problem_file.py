"""Problem files: TOML, validated with pydantic, SI units.

A file holds a ``[part]``, an optional ``gravity``, and one ``[[condition]]`` table per
station. A condition's keys say which components are prescribed and which are applied:
``x``, ``y``, ``angle`` prescribe (the answer is the reaction), ``Fx``, ``Fy``,
``moment`` apply a dead load, and ``Ft``, ``Fn`` apply a follower force (tangential and
normal to the deformed neutral line). Switching a hand from holding to pushing is a
one-word change: ``y = 0.3`` becomes ``Fy = 2.0``. See the README for the whole format.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from pliant.core.conditions import Condition
from pliant.core.part import Material, Part
from pliant.core.problem import Problem
from pliant.errors import FileFormatError, PliantError



class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class MaterialModel(_Strict):
    """[part.material]: an isotropic material."""

    youngs_modulus: float = Field(gt=0, description="Young's modulus [Pa]")
    density: float = Field(0.0, ge=0, description="[kg/m^3]")
    shear_modulus: float | None = Field(None, gt=0, description="[Pa]")
    poisson_ratio: float = Field(0.5, gt=-1, le=0.5)
    name: str = ""


class PartModel(_Strict):
    """[part]: give bending_stiffness directly, or a section and a material."""

    name: str = "part"
    length: float = Field(gt=0, description="[m]")
    bending_stiffness: float | None = Field(None, gt=0, description="EI [N m^2]")
    torsional_stiffness: float | None = Field(None, gt=0, description="GJ [N m^2]")
    mass_per_length: float | None = Field(None, ge=0, description="[kg/m]")
    outer_diameter: float | None = Field(None, gt=0, description="[m]")
    inner_diameter: float = Field(0.0, ge=0, description="[m]")
    material: MaterialModel | None = None
    rest_curvature: float | list[tuple[float, float]] = Field(
        0.0, description="[1/m], or [[s, kappa], ...] knots")
    min_bend_radius: float | None = Field(None, gt=0, description="[m]")

    @model_validator(mode="after")
    def _stiffness_given(self) -> PartModel:
        if self.bending_stiffness is None and self.material is None:
            raise ValueError("give bending_stiffness [N m^2], or outer_diameter and a "
                             "[part.material] with youngs_modulus")
        if self.material is not None and self.outer_diameter is None:
            raise ValueError("a [part.material] needs outer_diameter [m] to make a section")
        return self

    def build(self) -> Part:
        rest = (self.rest_curvature if isinstance(self.rest_curvature, float)
                else tuple(self.rest_curvature))
        common = {"name": self.name, "rest_curvature": rest,
                  "min_bend_radius": self.min_bend_radius}
        if self.material is not None:
            assert self.outer_diameter is not None
            material = Material(**self.material.model_dump())
            part = Part.tube(self.length, self.outer_diameter, material,
                             inner_diameter=self.inner_diameter, **common)
            # Measured values, when also given, win over the section's.
            overrides: dict[str, Any] = {}
            for key in ("bending_stiffness", "torsional_stiffness", "mass_per_length"):
                value = getattr(self, key)
                if value is not None:
                    overrides[key] = value
            if overrides:
                fields = {k: getattr(part, k) for k in (
                    "length", "bending_stiffness", "mass_per_length", "torsional_stiffness",
                    "outer_diameter", "inner_diameter", "rest_curvature", "min_bend_radius",
                    "name")}
                fields.update(overrides)
                part = Part(**fields)
            return part
        assert self.bending_stiffness is not None
        return Part(length=self.length, bending_stiffness=self.bending_stiffness,
                    torsional_stiffness=self.torsional_stiffness,
                    mass_per_length=self.mass_per_length or 0.0,
                    outer_diameter=self.outer_diameter, inner_diameter=self.inner_diameter,
                    **common)


class ConditionModel(_Strict):
    """[[condition]]: what is known at one station (see the module docstring)."""

    name: str | None = None
    s: float = Field(description="arc length from the first end [m]")
    x: float | None = Field(None, description="prescribed x [m]")
    y: float | None = Field(None, description="prescribed y [m]")
    angle: float | None = Field(None, description="prescribed tangent angle [rad]")
    Fx: float | None = Field(None, description="applied dead force, x [N]")
    Fy: float | None = Field(None, description="applied dead force, y [N]")
    moment: float | None = Field(None, description="applied moment [N m]")
    Ft: float | None = Field(None, description="follower force along the tangent [N]")
    Fn: float | None = Field(None, description="follower force along the normal [N]")
    note: str = ""

    @model_validator(mode="after")
    def _one_kind_of_force(self) -> ConditionModel:
        dead = self.Fx is not None or self.Fy is not None
        follower = self.Ft is not None or self.Fn is not None
        if dead and follower:
            raise ValueError("a condition applies either a dead force (Fx, Fy) or a "
                             "follower force (Ft, Fn); split it into two conditions")
        return self

    def build(self, index: int) -> Condition:
        follower = self.Ft is not None or self.Fn is not None
        force = (self.Ft, self.Fn) if follower else (self.Fx, self.Fy)
        if follower:
            force = (force[0] if force[0] is not None else 0.0,
                     force[1] if force[1] is not None else 0.0)
        return Condition(s=self.s, name=self.name or f"condition{index + 1}",
                         position=(self.x, self.y), angle=self.angle, force=force,
                         moment=self.moment, follower=follower)


class ProblemFile(_Strict):
    """A whole problem file."""

    name: str = ""
    description: str = ""
    choices: str = ""
    part: PartModel
    gravity: tuple[float, float] = (0.0, 0.0)
    condition: list[ConditionModel] = Field(default_factory=list)

    def build(self) -> Problem:
        part = self.part.build()
        conditions = tuple(c.build(i) for i, c in enumerate(self.condition))
        return Problem(part, conditions, self.gravity, self.name)


def _where(loc: tuple[Any, ...]) -> str:
    out = ""
    for item in loc:
        out += f"[{item}]" if isinstance(item, int) else (f".{item}" if out else str(item))
    return out or "(top level)"


def parse_problem(text: str, source: str = "<string>") -> Problem:
    """Parse TOML text into a ``Problem``; errors name the source and the field."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise FileFormatError(f"{source}: not valid TOML: {err}") from None
    try:
        model = ProblemFile.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        where = _where(tuple(first["loc"]))
        message = first["msg"]
        if first["type"] == "extra_forbidden":
            message = ("unknown key; a condition takes s, x, y, angle, Fx, Fy, moment, Ft, "
                       "Fn, name, note (SI units)")
        more = f" (and {len(err.errors()) - 1} more)" if len(err.errors()) > 1 else ""
        raise FileFormatError(f"{source}: {where}: {message}{more}") from None
    try:
        return model.build()
    except PliantError as err:
        raise FileFormatError(f"{source}: {err}") from None


def load_problem(path: str | Path) -> Problem:
    """Read a problem file (TOML, SI units)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileFormatError(f"{path}: no such file; check the path") from None
    except OSError as err:
        raise FileFormatError(f"{path}: cannot be read: {err.strerror}") from None
    return parse_problem(text, str(path))


def dump_problem(problem: Problem, description: str = "") -> str:
    """Write a problem as TOML text that ``parse_problem`` reads back."""
    part = problem.part
    lines = [f"name = {_toml(problem.name)}"]
    if description:
        lines.append(f"description = {_toml(description)}")
    if problem.gravity != (0.0, 0.0):
        lines.append(f"gravity = [{_num(problem.gravity[0])}, {_num(problem.gravity[1])}]")
    lines += ["", "[part]", f"name = {_toml(part.name)}", f"length = {_num(part.length)}",
              f"bending_stiffness = {_num(part.bending_stiffness)}",
              f"mass_per_length = {_num(part.mass_per_length)}"]
    if part.torsional_stiffness is not None:
        lines.append(f"torsional_stiffness = {_num(part.torsional_stiffness)}")
    if part.outer_diameter is not None:
        lines.append(f"outer_diameter = {_num(part.outer_diameter)}")
        lines.append(f"inner_diameter = {_num(part.inner_diameter)}")
    if part.min_bend_radius is not None:
        lines.append(f"min_bend_radius = {_num(part.min_bend_radius)}")
    if isinstance(part.rest_curvature, (int, float)):
        lines.append(f"rest_curvature = {_num(float(part.rest_curvature))}")
    else:
        knots = ", ".join(f"[{_num(s)}, {_num(k)}]" for s, k in part.rest_knots)
        lines.append(f"rest_curvature = [{knots}]")
    for c in problem.conditions:
        lines += ["", "[[condition]]", f"name = {_toml(c.name)}", f"s = {_num(c.s)}"]
        for key, value in (("x", c.position[0]), ("y", c.position[1]), ("angle", c.angle)):
            if value is not None:
                lines.append(f"{key} = {_num(value)}")
        keys = ("Ft", "Fn") if c.follower else ("Fx", "Fy")
        for key, value in zip(keys, c.force):
            if value is not None:
                lines.append(f"{key} = {_num(value)}")
        if c.moment is not None:
            lines.append(f"moment = {_num(c.moment)}")
    return "\n".join(lines) + "\n"


def _num(value: float) -> str:
    if not math.isfinite(value):
        raise FileFormatError(f"cannot write the non-finite number {value!r}")
    return repr(float(value))


def _toml(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{escaped}"'
