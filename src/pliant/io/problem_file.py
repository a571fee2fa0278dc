"""Problem files: TOML, validated with pydantic, SI units.

A file holds a ``[part]``, an optional ``gravity``, one ``[[condition]]`` table per
station and one ``[[load]]`` table per distributed load. A 3D file may also be a scene:
``[[obstacle]]`` tables (primitives, or meshes read by trimesh from paths relative to
the file), ``[[port]]`` tables (a position and an axis a condition can name),
``[[clip]]`` tables (the part held at a point along it, by position and axis), a
``[path]`` for one grip to follow and a clearance ``margin``.

A condition's keys say which components are prescribed and which are applied: ``x``,
``y``, ``angle`` prescribe (the answer is the reaction), ``Fx``, ``Fy``,
``moment`` apply a dead load, and ``Ft``, ``Fn`` apply a follower force (tangential and
normal to the deformed neutral line). Switching a hand from holding to pushing is a
one-word change: ``y = 0.3`` becomes ``Fy = 2.0``. See docs/reference.md for the whole format.

This module holds the part, conditions, obstacles, loads and the file as a whole, and
reads them; a scene's other sections are ``scene_sections``'s, the strict base and mesh
reading ``sections``'s, and writing a problem back ``problem_dump``'s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, Field, PrivateAttr, ValidationError, model_validator

from pliant.core.conditions import Condition
from pliant.core.loads import AddedMass, DistributedLoad, Load
from pliant.core.numbers import triple
from pliant.core.part import Material, Part
from pliant.core.planning import PathSpec, PlanSettings
from pliant.core.problem import Problem
from pliant.core.rules import EvaluationSettings, ObstacleRule
from pliant.core.worker import Worker
from pliant.errors import FileFormatError, InputError, PliantError
from pliant.io.problem_dump import dump_problem as dump_problem
from pliant.io.problem_dump import with_path_table as with_path_table
from pliant.io.scene_sections import (
    AssembledModel,
    BranchModel,
    CadModel,
    ClipModel,
    EvaluationModel,
    JunctionModel,
    PathModel,
    PlanModel,
    PortModel,
    RatingModel,
    SettleFitted,
    WorkerModel,
    _end_face_centre,
    _given,
    _solid_vertices,
)
from pliant.io.sections import PackagingFields, Vec3, _Strict, read_mesh
from pliant.io.tomlfile import field_path, read_text, read_toml
from pliant.util import progress


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
    material: MaterialModel | str | None = Field(
        None, description="a [part.material] table, or a name from the bundled library")
    rest_curvature: float | list[tuple[float, float]] = Field(
        0.0, description="[1/m], or [[s, kappa], ...] knots (about d1)")
    rest_curvature_2: float | list[tuple[float, float]] = Field(
        0.0, description="[1/m] about d2 (3D)")
    rest_twist: float | list[tuple[float, float]] = Field(0.0, description="[1/m] (3D)")
    bending_stiffness_2: float | None = Field(None, gt=0, description="EI about d2 (3D)")
    min_bend_radius: float | None = Field(None, gt=0, description="[m], as the datasheet "
                                          "quotes it (inside of the bend for hoses)")
    kind: str | None = Field(None, min_length=1, description="the evaluation's part kind "
                             "(coolant hose, thin-walled tube, wire, ...)")
    poisson_ratio: float | None = Field(None, gt=-1, le=0.5, description="of the wall "
                                        "(default: the material's)")
    axial_stiffness: float | Literal["material"] | None = Field(
        None, description="EA [N], or \"material\" for E times the section's area; "
        "not given: inextensible")
    max_axial_strain: float | None = Field(None, gt=0, description="the axial strain the "
                                           "part tolerates (0.01 = 1 %)")
    max_temperature: float | None = Field(None, gt=-273.15, description="[degC] the "
                                          "highest temperature the part tolerates (its "
                                          "datasheet's continuous service temperature)")

    @model_validator(mode="after")
    def _stiffness_given(self) -> PartModel:
        if self.bending_stiffness is None and self.material is None:
            raise ValueError("give bending_stiffness [N m^2], or outer_diameter and a "
                             "material (a library name, or a [part.material] table with "
                             "youngs_modulus)")
        if self.material is not None and self.outer_diameter is None:
            raise ValueError("a material needs outer_diameter [m] to make a section")
        if self.axial_stiffness == "material" and self.material is None:
            raise ValueError("axial_stiffness = \"material\" needs a material and "
                             "outer_diameter [m]; or give EA in N")
        if self.outer_diameter is not None and self.outer_diameter > 0.5 * self.length:
            raise ValueError(f"outer_diameter {self.outer_diameter:g} m is more than half the "
                             f"part's length ({self.length:g} m): no hose or cable is that "
                             "fat; the file's units are SI (metres: 20 mm is 0.02)")
        return self

    def build(self) -> Part:
        def knots(value):
            return value if isinstance(value, float) else tuple(value)

        common = {"name": self.name, "rest_curvature": knots(self.rest_curvature),
                  "rest_curvature_2": knots(self.rest_curvature_2),
                  "rest_twist": knots(self.rest_twist),
                  "bending_stiffness_2": self.bending_stiffness_2,
                  "min_bend_radius": self.min_bend_radius, "kind": self.kind,
                  "max_axial_strain": self.max_axial_strain,
                  "max_temperature": self.max_temperature}
        if isinstance(self.axial_stiffness, float):
            common["axial_stiffness"] = self.axial_stiffness
        if self.poisson_ratio is not None:
            common["poisson_ratio"] = self.poisson_ratio
        if self.material is not None:
            assert self.outer_diameter is not None
            if isinstance(self.material, str):
                from pliant.io.materials import material as library_material  # noqa: PLC0415

                material = library_material(self.material)
            else:
                material = Material(**self.material.model_dump())
            part = Part.tube(self.length, self.outer_diameter, material,
                             inner_diameter=self.inner_diameter,
                             extensible=self.axial_stiffness == "material", **common)
            # Measured values, when also given, win over the section's.
            overrides: dict[str, Any] = {}
            for key in ("bending_stiffness", "torsional_stiffness", "mass_per_length"):
                value = getattr(self, key)
                if value is not None:
                    overrides[key] = value
            return replace(part, **overrides) if overrides else part
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
    z: float | None = Field(None, description="prescribed z [m] (3D)")
    angle: float | None = Field(None, description="prescribed tangent angle [rad] (2D)")
    tangent: Vec3 | None = Field(None, description="prescribed axis direction (3D)")
    normal: Vec3 | None = Field(None, description="with tangent, the section axis d1 (3D)")
    Fx: float | None = Field(None, description="applied dead force, x [N]")
    Fy: float | None = Field(None, description="applied dead force, y [N]")
    Fz: float | None = Field(None, description="applied dead force, z [N] (3D)")
    moment: float | Vec3 | None = Field(None, description="applied moment [N m]: a number "
                                                          "in 2D, [Mx, My, Mz] in 3D")
    Ft: float | None = Field(None, description="follower force along the tangent [N] (2D)")
    Fn: float | None = Field(None, description="follower force along the normal [N] (2D)")
    follower_force: Vec3 | None = Field(None, description="follower force in the section "
                                                          "frame (d1, d2, d3) [N] (3D)")
    follower_moment: Vec3 | None = Field(None, description="follower moment in the section "
                                                           "frame (d1, d2, d3) [N m] (3D)")
    port: str | None = Field(None, description="at a [[port]]: its position and axis")
    grip_length: float = Field(0.0, ge=0, description="[m] a hand holds the part straight "
                               "over this length from the end at s (s = 0 or L); 0: a point")
    hand: bool = Field(False, description="a hand holds the part here: the evaluation "
                       "judges it against hand capacities (a [path]'s grip always is one; "
                       "without either, the part is judged in its clamps)")
    note: str = ""

    @model_validator(mode="after")
    def _one_kind_of_load(self) -> ConditionModel:
        if self.port is not None and any(v is not None for v in (
                self.x, self.y, self.z, self.tangent, self.angle)):
            raise ValueError("a condition at a port takes its position and axis from the "
                             "port; drop x, y, z, tangent (or drop port)")
        dead = any(v is not None for v in (self.Fx, self.Fy, self.Fz))
        follower = any(v is not None for v in (self.Ft, self.Fn, self.follower_force,
                                               self.follower_moment))
        if dead and follower:
            raise ValueError("a condition applies either dead forces (Fx, Fy, Fz) or "
                             "follower loads; split it into two conditions")
        if self.follower_moment is not None and self.moment is not None:
            raise ValueError("a condition applies either a dead moment or a follower "
                             "moment; split it into two conditions")
        return self

    @property
    def is_3d(self) -> bool:
        return (self.z is not None or self.Fz is not None or self.tangent is not None
                or self.port is not None
                or self.normal is not None or isinstance(self.moment, tuple)
                or self.follower_force is not None or self.follower_moment is not None)

    def build(self, index: int, dimension: int) -> Condition:
        name = self.name or f"condition{index + 1}"
        if dimension == 2:
            follower = self.Ft is not None or self.Fn is not None
            planar: tuple[float | None, ...] = ((self.Ft or 0.0, self.Fn or 0.0) if follower
                                                else (self.Fx, self.Fy))
            return Condition(s=self.s, name=name, position=(self.x, self.y), angle=self.angle,
                             force=planar, moment=self.moment, follower=follower,
                             grip_length=self.grip_length)
        if self.angle is not None or self.Ft is not None or self.Fn is not None:
            raise ValueError("angle, Ft and Fn are 2D; in 3D give tangent (and normal), "
                             "follower_force and follower_moment")
        follower = self.follower_force is not None or self.follower_moment is not None
        force: tuple[float | None, ...] | None
        moment: float | tuple[float, ...] | None
        if follower:
            force = self.follower_force
            moment = self.follower_moment
        else:
            force, moment = (self.Fx, self.Fy, self.Fz), self.moment
        if isinstance(moment, (int, float)):
            raise ValueError("in 3D a moment is a vector [Mx, My, Mz]")
        return Condition(s=self.s, name=name, position=(self.x, self.y, self.z),
                         tangent=self.tangent, normal=self.normal,
                         force=force if force is not None else (None, None, None),
                         moment=moment, follower=follower, grip_length=self.grip_length)


class ObstacleModel(PackagingFields):
    """[[obstacle]]: a rigid obstacle of the scene, placed by position and rotation
    (local to world, rows) or by axis (where its local z points: a cylinder's axis, a
    half-space's outward normal)."""

    name: str
    shape: Literal["box", "sphere", "cylinder", "halfspace", "plane", "mesh"]
    position: Vec3 = Field((0.0, 0.0, 0.0), description="centre, or a point of the "
                                                         "plane, or the mesh's origin [m]")
    rotation: tuple[Vec3, Vec3, Vec3] | None = None
    axis: Vec3 | None = None
    size: Vec3 | None = Field(None, description="box: full sizes along local x, y, z [m]")
    radius: float | None = Field(None, gt=0, description="sphere, cylinder [m]")
    length: float | None = Field(None, gt=0, description="cylinder [m]")
    file: str | None = Field(None, description="mesh: STL, OBJ, PLY, glTF, relative to "
                                               "this file")
    scale: float | None = Field(None, gt=0, description="mesh: its units in m (0.001 for "
                                "mm); default the scene's units, else 1")
    resolution: int = Field(64, ge=8, le=512, description="mesh: distance grid cells")
    crease: float = Field(
        10.0, ge=0.0, lt=90.0,
        description="[deg] faces meeting within this angle tessellate one smooth surface: "
        "a contact reads its normal interpolated across them (0: every facet flat, "
        "every edge sharp)")
    friction: float = Field(0.0, ge=0, le=5, description="Coulomb's coefficient between "
                                                          "the obstacle and the part")
    note: str = ""

    @model_validator(mode="after")
    def _shape_fields(self) -> ObstacleModel:
        need = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length"),
                "halfspace": (), "plane": (), "mesh": ("file",)}[self.shape]
        missing = [k for k in need if getattr(self, k) is None]
        if missing:
            raise ValueError(f"a {self.shape} needs {', '.join(missing)}")
        if self.rotation is not None and self.axis is not None:
            raise ValueError("give rotation or axis, not both")
        if self.size is not None and min(self.size) <= 0.0:
            raise ValueError("size: every side must be > 0 [m]")
        return self

    def build(self, base: Path | None, units: str | None = None) -> Any:
        return self._shape(base, units).with_friction(self.friction)

    def _shape(self, base: Path | None, units: str | None = None) -> Any:
        from pliant.scene.distance import Obstacle, _frame_with_z  # noqa: PLC0415

        rotation = None
        if self.rotation is not None:
            rotation = np.array(self.rotation, dtype=float)
        elif self.axis is not None:
            if np.linalg.norm(self.axis) == 0.0:
                raise ValueError("axis must not be zero")
            rotation = _frame_with_z(self.axis)
        if self.shape == "box":
            return Obstacle.box(self.name, self.size, self.position, rotation)
        if self.shape == "sphere":
            return Obstacle.sphere(self.name, _given(self.radius, "radius"), self.position)
        if self.shape == "cylinder":
            return Obstacle.cylinder(self.name, _given(self.radius, "radius"),
                                     _given(self.length, "length"), self.position,
                                     rotation)
        if self.shape in ("halfspace", "plane"):
            normal = (0.0, 0.0, 1.0) if rotation is None else rotation[:, 2]
            return Obstacle.halfspace(self.name, self.position, normal)
        try:
            vertices, faces = read_mesh(self.file, base)
            if self.scale is not None:
                scale = self.scale
            else:
                from pliant.io.cad import unit_scale  # noqa: PLC0415

                scale = unit_scale(units, "units") if units else 1.0
            progress.say(f"{self.name}: distance structures ({len(faces):,} triangles)")
            return Obstacle.from_mesh(self.name, vertices * scale, faces, self.position,
                                      rotation, self.resolution, crease=self.crease)
        except ValueError as err:
            raise ValueError(f"{err} (the obstacle {self.name!r})") from None


class SolverModel(_Strict):
    """[solver]: settings of the model (3D: how many elements)."""

    elements: int = Field(100, ge=4, le=100000, description="about how many elements (3D)")


class LoadModel(_Strict):
    """[[load]]: a force per unit length [N/m] on the stretch [start, end] [m] of the part
    (``pliant.core.loads``): ``force`` dead, in the global frame, or ``follower_force``
    in the part's material frame (2D: tangential, normal; 3D: d1, d2, d3); or mass the
    stretch carries besides the part's own, ``mass_per_length`` [kg/m] (a sleeve, tape, a
    hose's fluid), weighing under the problem's gravity."""

    name: str = ""
    force: tuple[float, float] | Vec3 | None = None
    follower_force: tuple[float, float] | Vec3 | None = None
    mass_per_length: float | None = None
    start: float = 0.0
    end: float | None = None

    @property
    def components(self) -> tuple[float, ...]:
        return self.force if self.force is not None else (self.follower_force or ())

    def build(self, index: int) -> Load:
        name = self.name or f"load{index + 1}"
        given = [self.force, self.follower_force, self.mass_per_length]
        if sum(v is not None for v in given) != 1:
            raise InputError(f"load[{index}]", "give one of force (dead, global frame) or "
                             "follower_force (material frame), in N/m, or mass_per_length "
                             "(kg/m)")
        if self.mass_per_length is not None:
            return AddedMass(self.mass_per_length, start=self.start, end=self.end, name=name)
        return DistributedLoad(self.components, follower=self.follower_force is not None,
                               start=self.start, end=self.end, name=name)


def build_obstacles(obstacle: list[ObstacleModel], cad: list[CadModel], base: Path | None,
                    units: str | None) -> tuple[list[Any], dict[str, ObstacleRule]]:
    """A scene's ``[[obstacle]]`` and ``[[cad]]`` tables as obstacles (SI; a CAD or mesh
    file in its declared unit, else ``units``) and the packaging rule of each, by name;
    errors name the table and its index."""
    obstacles: list[Any] = []
    rules: dict[str, ObstacleRule] = {}
    for i, o in enumerate(obstacle):
        try:
            obstacles.append(o.build(base, units))
        except ValueError as err:
            raise InputError(f"obstacle[{i}]", str(err)) from None
        rules[o.name] = o.rule
    for i, c in enumerate(cad):
        try:
            solids = c.build(base, units)
            obstacles.extend(solids)
            rules.update({s.name: c.rule for s in solids})
        except InputError as err:
            message = str(err).removeprefix(f"{err.field}: ")
            raise InputError(f"cad[{i}].{err.field}", message) from None
        except FileFormatError as err:
            raise FileFormatError(f"cad[{i}]: {err}") from None
        except ValueError as err:
            raise InputError(f"cad[{i}]", str(err)) from None
    return obstacles, rules


def check_names(obstacles: list[Any]) -> None:
    """Every obstacle of a scene has a name of its own."""
    names = [o.name for o in obstacles]
    if len(set(names)) != len(names):
        raise InputError("obstacle", "two obstacles share a name; name each one apart")


class ProblemFile(_Strict):
    """A whole problem file."""

    name: str = ""
    description: str = ""
    choices: str = ""
    part: PartModel
    gravity: tuple[float, float] | Vec3 | None = None
    solver: SolverModel = Field(default_factory=SolverModel)
    condition: list[ConditionModel] = Field(default_factory=list)
    obstacle: list[ObstacleModel] = Field(default_factory=list)
    cad: list[CadModel] = Field(default_factory=list)
    assembled: list[AssembledModel] = Field(default_factory=list)
    port: list[PortModel] = Field(default_factory=list)
    clip: list[ClipModel] = Field(default_factory=list)
    junction: list[JunctionModel] = Field(default_factory=list)
    load: list[LoadModel] = Field(default_factory=list)
    path: PathModel | None = None
    margin: float = Field(0.0, ge=0, description="clearance wanted round obstacles [m]")
    _rules: dict[str, ObstacleRule] = PrivateAttr(default_factory=dict)  # by obstacle
    units: str | None = Field(None, description="the length unit of the CAD and mesh files "
                              "the scene reads, where they declare none (mm, cm, m, in); "
                              "the numbers in this file stay SI")
    evaluation: EvaluationModel = Field(default_factory=EvaluationModel)
    plan: PlanModel = Field(default_factory=PlanModel)
    worker: WorkerModel | None = None

    @property
    def dimension(self) -> int:
        three = (self.gravity is not None and len(self.gravity) == 3) or any(
            c.is_3d for c in self.condition) or any(
            len(ld.components) == 3 for ld in self.load) or bool(
            self.obstacle or self.clip or self.junction
                                                     or self.assembled
                                                     or self.cad)
        return 3 if three else 2

    def build(self, base: Path | None = None, nested: bool = False,
              settle: SettleFitted | None = None) -> Problem:
        """The problem; ``nested`` (an assembled part's own file) skips its
        [[assembled]] parts: one level only; ``settle`` solves them (see
        ``AssembledModel``)."""
        part = self.part.build()
        dimension = self.dimension
        obstacles = self._obstacles(base, nested, settle)
        obstacles = self._place_on_solids(obstacles)
        ports = {p.name: p for p in self.port}
        conditions = []
        for i, c in enumerate(self.condition):
            try:
                if c.port is not None:
                    if c.port not in ports:
                        raise ValueError(f"port: no [[port]] named {c.port!r}; known: "
                                         f"{', '.join(sorted(ports)) or 'none'}")
                    port = ports[c.port]
                    # The part leaves a port along its axis: the first end's tangent is
                    # the axis, the last end's (arriving) its opposite.
                    axis = (port.axis if c.s < 0.5 * part.length
                            else tuple(-a for a in port.axis))
                    x, y, z = _given(port.position, "position")
                    c = c.model_copy(update={"x": x, "y": y, "z": z, "tangent": axis})
                conditions.append(c.build(i, dimension))
            except ValueError as err:
                if isinstance(err, PliantError):
                    raise
                raise InputError(f"condition[{i}]", str(err)) from None
        sliders: list[Any] = []
        pivots: list[Any] = []
        for i, clip in enumerate(self.clip):
            try:
                built = clip.build()
            except ValueError as err:
                raise InputError(f"clip[{i}]", str(err).removeprefix("Value error, ")) from None
            if isinstance(built, tuple):  # a pivot: its position, and its pin
                conditions.append(built[0])
                pivots.append(built[1])
            else:
                (conditions if isinstance(built, Condition) else sliders).append(built)
        if dimension == 2 and obstacles:
            raise InputError("obstacle", "obstacles are 3D: give gravity as [gx, gy, gz]")
        junctions = []
        for i, j in enumerate([] if nested else self.junction):
            try:
                junctions.append(j.build(base))
            except ValueError as err:
                raise InputError(f"junction[{i}]", str(err).removeprefix("Value error, ")
                                 ) from None
        loads = tuple(ld.build(i) for i, ld in enumerate(self.load))
        return Problem(part, tuple(conditions), self.gravity, self.name,
                       obstacles=tuple(obstacles), sliders=tuple(sliders),
                       junctions=tuple(junctions), pivots=tuple(pivots), loads=loads)

    def _obstacles(self, base: Path | None, nested: bool,
                   settle: SettleFitted | None) -> list[Any]:
        obstacles, rules = build_obstacles(self.obstacle, self.cad, base, self.units)
        self._rules.update(rules)
        for i, a in enumerate([] if nested else self.assembled):
            try:
                obstacles.append(a.build(base, settle))
            except ValueError as err:
                raise InputError(f"assembled[{i}]", str(err)) from None
        check_names(obstacles)
        return obstacles

    def _place_on_solids(self, obstacles: list[Any]) -> list[Any]:
        """Ports and clips given by a solid take their position from it (this model's
        lists are updated in place, for everything that reads them later), and those
        solids leave the obstacles: they hold the part."""
        by_name = {o.name: o for o in obstacles}
        used: set[str] = set()
        placed: tuple[tuple[str, list[Any]], ...] = (("port", self.port), ("clip", self.clip))
        for table, rows in placed:
            for i, row in enumerate(rows):
                if row.solid is None:
                    continue
                try:
                    vertices = _solid_vertices(by_name, row.solid)
                except ValueError as err:
                    raise InputError(f"{table}[{i}].solid", str(err).removeprefix(
                        "solid: ")) from None
                if table == "port":
                    at = _end_face_centre(vertices, row.axis)
                else:
                    at = triple(0.5 * (vertices.min(axis=0) + vertices.max(axis=0)))
                rows[i] = row.model_copy(update={"position": at})
                used.add(row.solid)
        return [o for o in obstacles if o.name not in used]


@dataclass(frozen=True)
class Scene:
    """A whole file as built: the problem (with its obstacles), the solver settings,
    the manipulation along its [path] (its steps, made by ``pliant.assembly`` from
    ``path_spec`` as the scene is loaded; empty without one) and the condition it
    carries (``grip``, None without a path), the clearance margin, ``fixed``: the conditions
    a user does not move (at ports, and clips), ``hands``: those a hand holds (the grip
    besides), how it is judged (``evaluation``) and
    how a path for it is planned (``plan``)."""

    problem: Problem
    solver: SolverModel
    path: list[Problem] = field(default_factory=list)  # its steps (``pliant.assembly``)
    margin: float = 0.0
    ports: dict[str, PortModel] = field(default_factory=dict)
    grip: str | None = None
    fixed: tuple[str, ...] = ()
    evaluation: EvaluationSettings = field(default_factory=EvaluationSettings)
    plan: PlanSettings = field(default_factory=PlanSettings)
    warnings: tuple[str, ...] = ()
    path_spec: PathSpec | None = None  # the [path] as given
    hands: tuple[str, ...] = ()  # the conditions a hand holds (``hand = true``)
    # What a packaging engineer says of each obstacle, by name (those that say anything)
    obstacle_rules: dict[str, ObstacleRule] = field(default_factory=dict)
    worker: Worker | None = None  # who does it and where they stand ([worker])


# Part kinds whose bending stiffness a solid section of their material does not give.
SECTION_MISLEADS = {
    "reinforced hose": "its braided or spiral plies make it many times stiffer in bending "
                       "than its rubber",
    "coolant hose": "a coolant hose is plied (textile or aramid layers in its rubber), which "
                    "makes it stiffer in bending than its rubber alone",
    "metal hose": "its corrugations and braid make it far softer in bending than a solid "
                  "tube of its metal",
    "multi-core cable": "its strands slide on each other, so it is far softer than a solid "
                        "section of its material",
    "coax": "its braid and dielectric do not bend as one solid section",
}


def _warnings(model: ProblemFile, part: Part) -> tuple[str, ...]:
    """What the user should know about the file although it is valid."""
    why = SECTION_MISLEADS.get(part.kind or "")
    if why and model.part.bending_stiffness is None:
        return (f"part: a {part.kind} whose bending stiffness comes from its material and "
                f"section ({part.bending_stiffness:.3g} N m^2): {why}; give a measured "
                "bending_stiffness (pliant identify fits one to a bench test)",)
    return ()


def _unknown_key(loc: tuple) -> str:
    """The message for a key no table of that name takes: the nearest it does take, and
    all of them (SI units)."""
    import difflib  # noqa: PLC0415

    names = [x for x in loc if isinstance(x, str)]
    key = names[-1]
    tables: dict[str, type[BaseModel]] = {
        "part": PartModel, "condition": ConditionModel, "obstacle": ObstacleModel, "cad": CadModel,
        "assembled": AssembledModel, "port": PortModel, "clip": ClipModel,
        "junction": JunctionModel, "junction.branch": BranchModel,
        "path": PathModel, "evaluation": EvaluationModel, "solver": SolverModel,
        "plan": PlanModel, "part.material": MaterialModel, "worker": WorkerModel,
        "evaluation.rating": RatingModel}
    table = ".".join(names[:-1])
    model = tables.get(table, ProblemFile if not table else None)
    if model is None:
        return "unknown key; see docs/reference.md's file format (SI units)"
    known = sorted(model.model_fields)
    if table and key in ProblemFile.model_fields:
        return (f"{key!r} is a top-level key, but it stands under [{table}]: TOML puts a "
                "key in the table above it; write it before the file's first [table]")
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}? " if close else ""
    where = f"[{table}]" if table else "the file's top level"
    return f"unknown key {key!r}; {hint}{where} takes {', '.join(known)} (SI units)"


def parse_problem(text: str, source: str = "<string>") -> Problem:
    """Parse TOML text into a ``Problem``; errors name the source and the field."""
    return parse_problem_file(text, source)[0]


def parse_problem_file(text: str, source: str = "<string>") -> tuple[Problem, SolverModel]:
    """Parse TOML text into a ``Problem`` and its ``[solver]`` settings."""
    scene = parse_scene(text, source)
    return scene.problem, scene.solver


def parse_scene(text: str, source: str = "<string>", base: Path | None = None,
                nested: bool = False, settle: SettleFitted | None = None) -> Scene:
    """Parse TOML text into a ``Scene``; mesh files are looked up relative to ``base``
    (the file's folder); ``nested`` (an assembled part's own file) skips its
    [[assembled]] parts, which ``settle`` solves (without it, a file that has one is
    refused: ``pliant.assembly.parse_scene`` passes it)."""
    return scene_from_data(read_toml(text, source), source, base, nested, settle)


def scene_from_data(data: dict[str, Any], source: str = "<data>", base: Path | None = None,
                    nested: bool = False, settle: SettleFitted | None = None) -> Scene:
    """A ``Scene`` from a scene file's document already read (a TOML table as dicts and
    lists: what a variation study changes sample by sample)."""
    try:
        model = ProblemFile.model_validate(data)
    except ValidationError as err:
        errors = err.errors()
        # A misspelt key explains the key "missing" beside it: name it first.
        first = next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])
        where = field_path(tuple(first["loc"]))
        message = first["msg"].removeprefix("Value error, ")
        if first["type"] == "extra_forbidden":
            message = _unknown_key(tuple(first["loc"]))
        more = f" (and {len(err.errors()) - 1} more)" if len(err.errors()) > 1 else ""
        raise FileFormatError(f"{source}: {where}: {message}{more}") from None
    try:
        problem = model.build(base, nested, settle)
        return Scene(problem, model.solver, [], model.margin,
                     {p.name: p for p in model.port},
                     model.path.grip if model.path is not None else None,
                     tuple(c.name or f"condition{i + 1}" for i, c in enumerate(model.condition)
                           if c.port is not None) + tuple(c.name for c in model.clip),
                     model.evaluation.build(base), model.plan.build(),
                     _warnings(model, problem.part),
                     model.path.build() if model.path is not None else None,
                     tuple(c.name or f"condition{i + 1}" for i, c in enumerate(model.condition)
                           if c.hand),
                     {k: r for k, r in model._rules.items() if r != ObstacleRule()},
                     None if model.worker is None else model.worker.build())
    except PliantError as err:
        raise FileFormatError(f"{source}: {err}") from None


def load_problem(path: str | Path) -> Problem:
    """Read a problem file (TOML, SI units)."""
    return load_problem_file(path)[0]


def load_problem_file(path: str | Path) -> tuple[Problem, SolverModel]:
    """Read a problem file (TOML, SI units) and its ``[solver]`` settings."""
    scene = load_scene(path)
    return scene.problem, scene.solver


def load_scene(path: str | Path, settle: SettleFitted | None = None) -> Scene:
    """Read a problem or scene file (TOML, SI units): obstacles, ports, clips, path; its
    flexible parts already fitted by ``settle`` (``pliant.assembly.load_scene``)."""
    path = Path(path)
    return parse_scene(read_text(path), str(path), path.parent, settle=settle)
