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
one-word change: ``y = 0.3`` becomes ``Fy = 2.0``. See the README for the whole format.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from pliant.core.conditions import Condition
from pliant.core.loads import DistributedLoad
from pliant.core.numbers import triple
from pliant.core.part import Material, Part
from pliant.core.planning import PlanSettings
from pliant.core.problem import Problem
from pliant.core.rules import EvaluationSettings
from pliant.errors import FileFormatError, InputError, OutputError, PliantError
from pliant.io import cache, progress
from pliant.io.tomlfile import field_path, read_toml


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_booleans(cls, value: Any, info: ValidationInfo) -> Any:
        """``length = true`` is not 1 m: a TOML boolean is only taken where a field is
        one (pydantic would read it as 1.0)."""
        field = cls.model_fields.get(info.field_name or "")
        if _has_bool(value) and field is not None and "bool" not in str(field.annotation):
            raise ValueError("a number is wanted here, not true or false")
        return value


def _has_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return True
    if isinstance(value, (list, tuple)):
        return any(_has_bool(v) for v in value)
    return False


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
                  "max_axial_strain": self.max_axial_strain}
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


Vec3 = tuple[float, float, float]


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
                             force=planar, moment=self.moment, follower=follower)
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
                         moment=moment, follower=follower)


class ObstacleModel(_Strict):
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
                                      rotation, self.resolution)
        except ValueError as err:
            raise ValueError(f"{err} (the obstacle {self.name!r})") from None


def _referenced(name: str | None, base: Path | None, what: str) -> Path:
    """A file a scene names, relative to the scene's folder; a missing one says which
    path was looked at."""
    path = Path(name or "")
    if not path.is_absolute() and base is not None:
        path = base / path
    if not path.is_file():
        raise ValueError(f"file: no such {what} file {str(path)!r} (paths are relative "
                         "to the scene file)")
    return path


def read_mesh(name: str | None, base: Path | None) -> tuple[np.ndarray, np.ndarray]:
    """A mesh file's vertices and faces, checked and merged; kept in the disk cache under
    the hash of the file's bytes (a 65 MB STL parses in seconds, loads in a tenth)."""
    path = _referenced(name, base, "mesh")
    progress.say(f"{path.name}: reading")
    try:
        key = cache.digest(path.read_bytes(), path.suffix.lower().encode())
    except OSError as err:
        raise ValueError(f"file: cannot read {str(path)!r}: {err.strerror}") from None
    kept = cache.load_arrays("meshfile", key)
    if kept is not None and set(kept) == {"vertices", "faces"}:
        return kept["vertices"], kept["faces"]
    vertices, faces = _parse_mesh(path)
    cache.save_arrays("meshfile", key, vertices=vertices, faces=faces)
    return vertices, faces


def _parse_mesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import trimesh  # noqa: PLC0415

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as err:  # trimesh raises many kinds on a bad file
        raise ValueError(f"file: {str(path)!r} is not a mesh trimesh can read "
                         f"(STL, OBJ, PLY, glTF): {err}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ValueError(f"file: {str(path)!r} holds no triangles")
    # Checked as the file has it (processing would silently drop NaN vertices), then
    # merged (an STL repeats each vertex per triangle).
    from pliant.scene.distance import check_mesh  # noqa: PLC0415

    try:
        check_mesh(np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, np.int64))
    except ValueError as err:
        raise ValueError(f"file: {str(path)!r}: {err}") from None
    mesh.process()
    return np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces, dtype=np.int64)


class CadModel(_Strict):
    """[[cad]]: obstacles from a CAD assembly (STEP, or glTF, OBJ, ...): one per solid,
    named by its product, or all merged into one."""

    file: str = Field(description="STEP (.step, .stp), glTF, OBJ, PLY or STL, relative to "
                                  "this file")
    units: str | None = Field(None, description="the file's length unit (mm, cm, m, in) "
                              "where it declares none (STL, OBJ, PLY); a STEP file's own is "
                              "used")
    tolerance: float = Field(1e-4, gt=0, le=0.01, description="the tessellation's chord "
                             "error [m] (STEP)")
    keep: list[str] = Field(default_factory=list, description="name patterns of the "
                            "solids to take (default: all), shell-style: \"bolt*\"")
    drop: list[str] = Field(default_factory=list, description="name patterns to leave out")
    merge: bool = Field(False, description="one obstacle of all the solids taken, named "
                        "by name")
    name: str | None = Field(None, description="the merged obstacle's name, or a prefix "
                             "\"name/\" for each solid's")
    position: Vec3 = Field((0.0, 0.0, 0.0), description="where the file's origin goes [m]")
    rotation: tuple[Vec3, Vec3, Vec3] | None = None
    resolution: int = Field(64, ge=8, le=512, description="distance grid cells")
    friction: float = Field(0.0, ge=0, le=5)
    note: str = ""

    @model_validator(mode="after")
    def _merged_named(self) -> CadModel:
        if self.merge and not self.name:
            raise ValueError("merge = true needs the obstacle's name")
        return self

    def build(self, base: Path | None, units: str | None = None) -> list[Any]:
        """The obstacles; ``units`` the scene's, for a file that declares none."""
        from pliant.io.cad import STEP_SUFFIXES, read_assembly  # noqa: PLC0415 (cascadio)
        from pliant.scene.distance import Obstacle  # noqa: PLC0415

        path = _referenced(self.file, base, "CAD")
        progress.say(f"{path.name}: reading and tessellating")
        # the table's own unit, else the scene's, except for STEP: it declares its own
        if self.units is not None or path.suffix.lower() in STEP_SUFFIXES:
            units = self.units
        solids = read_assembly(path, units=units, tolerance=self.tolerance,
                               keep=self.keep, drop=self.drop)
        rotation = None if self.rotation is None else np.array(self.rotation, dtype=float)
        if self.merge:
            offsets = np.cumsum([0] + [len(s.vertices) for s in solids[:-1]])
            vertices = np.concatenate([s.vertices for s in solids])
            faces = np.concatenate([s.faces + o for s, o in zip(solids, offsets)])
            pieces = [(_given(self.name, "name"), vertices, faces)]
        else:
            prefix = f"{self.name}/" if self.name else ""
            pieces = [(prefix + s.name, s.vertices, s.faces) for s in solids]
        out = []
        # one bar over the whole assembly, in triangles: each solid's build advances it
        with progress.work(sum(len(faces) for _, _, faces in pieces)):
            for k, (name, vertices, faces) in enumerate(pieces):
                progress.say(f"{path.name}: distance structures of solid {k + 1} of "
                             f"{len(pieces)} ({name}, {len(faces):,} triangles)")
                try:
                    obstacle = Obstacle.from_mesh(name, vertices, faces, self.position,
                                                  rotation, self.resolution)
                except ValueError as err:
                    raise ValueError(f"{err} (the solid {name!r} of {path.name})") from None
                out.append(obstacle.with_friction(self.friction))
        return out


def _nested_problem(name: str, base: Path | None, what: str) -> tuple[Path, Problem]:
    """(path, problem) of a 3D problem file a scene refers to (an assembled part's, a
    branch's), its own [[assembled]] parts not followed; ValueError naming ``file``."""
    path = _referenced(name, base, "problem")
    try:
        text = path.read_text(encoding="utf-8")
        problem = parse_scene(text, str(path), path.parent, nested=True).problem
    except (OSError, PliantError) as err:
        raise ValueError(f"file: {err}") from None
    if problem.dimension != 3:
        raise ValueError(f"file: {str(path)!r} is a 2D problem; {what} is 3D")
    return path, problem


class AssembledModel(_Strict):
    """[[assembled]]: a flexible part already fitted, in its clamps: its own problem file
    (3D, relative to this one) is solved once and its tube becomes an obstacle. Its
    shape is kept in pliant's disk cache (``pliant.io.cache``) under the hash of its
    problem, its element count and the model's source: a scene read again does not
    solve it again (its equilibrium is then found on first use, by a part that touches
    it)."""

    name: str
    file: str = Field(description="its problem file, relative to this file")
    elements: int = Field(60, ge=4, le=2000)
    flexible: bool = Field(True, description="a part that touches it deforms it (they are "
                           "solved together); false: its tube is a rigid obstacle")
    friction: float = Field(0.0, ge=0.0, description="Coulomb's coefficient between it and "
                            "the part that touches it")
    note: str = ""

    def build(self, base: Path | None) -> Any:
        from pliant.core.problem import FittedPart  # noqa: PLC0415
        from pliant.core.tube import tube_mesh  # noqa: PLC0415
        from pliant.models import rod3d  # noqa: PLC0415
        from pliant.scene.distance import Obstacle  # noqa: PLC0415

        path, problem = _nested_problem(self.file, base, "an assembled part")
        key = _fitted_key(problem, self.elements)
        kept = cache.load_arrays("fitted", key) if key else None
        eq = None
        if kept is not None and kept.keys() >= {"position", "frames"}:
            position, frames = kept["position"], kept["frames"]
        else:
            try:
                eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=self.elements))
            except PliantError as err:
                raise ValueError(f"file: {str(path)!r} could not be solved: {err}") from None
            position, frames = eq.position, eq.frames
            if key:
                cache.save_arrays("fitted", key, position=position, frames=frames)
        part = problem.part
        radius = 0.5 * part.outer_diameter if part.outer_diameter else 0.01 * part.length
        vertices, faces = tube_mesh(position, radius, frames, sides=16, caps=True)
        obstacle = Obstacle.from_mesh(self.name, vertices, faces).with_friction(self.friction)
        if self.flexible:
            obstacle = replace(obstacle, fitted=FittedPart(self.name, problem, self.elements,
                                                           solved=eq, friction=self.friction,
                                                           line=position))
        return obstacle


def _fitted_key(problem: Problem, elements: int) -> str | None:
    """The cache key of a fitted part's shape: its problem as this module writes it,
    its element count and the source of the code that solves it (a changed solver is
    a new key); None where the problem cannot be written (a mesh obstacle of its own)."""
    try:
        text = dump_problem(problem)
    except OutputError:
        return None
    return cache.digest(text.encode(), str(elements).encode(), _solver_source())


@lru_cache(maxsize=1)
def _solver_source() -> bytes:
    """The hash of the modules an equilibrium of a 3D part depends on."""
    root = Path(__file__).resolve().parents[1]
    files = sorted([*(root / "core").glob("*.py"), *(root / "models").glob("*.py"),
                    *(root / "models" / "rod3d").glob("*.py"), *(root / "scene").glob("*.py")])
    return cache.digest(*(f.read_bytes() for f in files)).encode()


class PortModel(_Strict):
    """[[port]]: where an end must go: a position and the axis the part leaves it by
    (a condition at the port at the first end has that tangent; at the last end, the
    opposite: it arrives)."""

    name: str
    position: Vec3 | None = Field(None, description="[m]; or solid")
    solid: str | None = Field(None, description="a CAD solid (an obstacle's name) that is "
                              "the port: its end face along the axis is the position, and "
                              "it is no obstacle to the part it holds")
    axis: Vec3 = Field(description="the direction the part leaves the port along")
    note: str = ""

    @model_validator(mode="after")
    def _placed(self) -> PortModel:
        if (self.position is None) == (self.solid is None):
            raise ValueError("give position [m] or solid (the name of a CAD solid), one")
        return self


def _solid_vertices(obstacles: dict[str, Any], name: str) -> np.ndarray:
    """The world vertices of the mesh obstacle ``name`` (a solid of a [[cad]] import)."""
    obstacle = obstacles.get(name)
    if obstacle is None or obstacle.mesh is None:
        known = sorted(k for k, o in obstacles.items() if o.mesh is not None)
        raise ValueError(f"solid: no mesh obstacle named {name!r}; there are "
                         f"{', '.join(known[:20]) or 'none'}{' ...' if len(known) > 20 else ''}")
    return obstacle.mesh.tri.reshape(-1, 3) @ obstacle.rotation.T + obstacle.translation


def _given(value: Any, name: str) -> Any:
    """A field the validators ask for at this point (a clip's position from its solid, a
    sphere's radius): present, or a clear error if not."""
    if value is None:
        raise ValueError(f"{name}: give it")
    return value


def _end_face_centre(vertices: np.ndarray, axis: Vec3) -> tuple[float, float, float]:
    """The centre of a solid's face farthest along ``axis`` (a port stub's mouth): the
    middle of the box of its vertices on that face."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    along = vertices @ a
    extent = float(np.ptp(vertices, axis=0).max())
    face = vertices[along >= along.max() - 1e-6 * extent]
    return triple(0.5 * (face.min(axis=0) + face.max(axis=0)))


class ClipModel(_Strict):
    """[[clip]]: a clip or clamp holding the part at s by position and axis. ``kind``:
    "fixed" (the default; with ``normal``, the section's d1, it also stops twist),
    "turning" (the part turns freely about the axis in it: no moment about the axis),
    "sliding" (the part slides through along the axis, with Coulomb's ``friction`` or
    none: s is where it is at the start, the solve finds where it ends), "ring" (a
    grommet or a hole: the position only, the part slides and tilts in it), "pivot"
    (the part held firmly, the clip turning on a pin along ``pivot``)."""

    name: str
    s: float = Field(description="arc length [m]")
    position: Vec3 | None = Field(None, description="[m]; or solid")
    solid: str | None = Field(None, description="a CAD solid that is the clip: the centre "
                              "of its box is the position, and it is no obstacle to the part")
    axis: Vec3 = Field(description="the part's direction through the clip")
    normal: Vec3 | None = None
    kind: Literal["fixed", "turning", "sliding", "ring", "pivot"] = "fixed"
    pivot: Vec3 | None = Field(None, description="kind = \"pivot\": the pin the clip "
                               "turns on, across the part")
    friction: float = Field(0.0, ge=0.0, description="Coulomb's coefficient along the "
                            "axis of a sliding clip or ring")
    note: str = ""

    @model_validator(mode="after")
    def _placed(self) -> ClipModel:
        if (self.position is None) == (self.solid is None):
            raise ValueError("give position [m] or solid (the name of a CAD solid), one")
        return self

    def build(self) -> Any:
        """The condition (fixed, turning) or the sliding clip (sliding, ring)."""
        if self.normal is not None and self.kind != "fixed":
            raise ValueError(f"normal: a {self.kind} clip lets the part turn about its "
                             "axis; drop the normal, or make the clip kind = \"fixed\"")
        if (self.pivot is None) == (self.kind == "pivot"):
            raise ValueError("pivot: give the pin's direction for kind = \"pivot\" (and "
                             "only for it)")
        if self.kind == "pivot":
            from pliant.core.problem import PivotClip  # noqa: PLC0415

            return (Condition(s=self.s, name=self.name, position=self._at()),
                    PivotClip(self.name, self.s, self._at(), triple(_given(self.pivot, "pivot"))))
        if self.kind in ("sliding", "ring"):
            from pliant.core.problem import SlidingClip  # noqa: PLC0415

            return SlidingClip(self.name, self.s, self._at(), triple(self.axis),
                               holds_axis=self.kind == "sliding", friction=self.friction)
        if self.friction:
            raise ValueError(f"friction: a {self.kind} clip does not slide; friction is for "
                             "kind = \"sliding\" or \"ring\"")
        return Condition(s=self.s, name=self.name, position=self._at(),
                         tangent=self.axis, normal=self.normal)

    def _at(self) -> tuple[float, float, float]:
        """Its position: given, or its solid's, found before it is built."""
        return triple(_given(self.position, "position"))


class BranchModel(_Strict):
    """[[junction.branch]]: a branch of the harness: its own problem file (3D, relative
    to this one: its part and what holds its far end, a port's clamp), which of its ends
    meets the junction, and the direction it leaves the junction in, in the frame
    (d1, d2, d3) of the part's end (d3 pointing out of the part; d1 the section's first
    axis, the normal the part's clamps give)."""

    name: str
    file: str = Field(description="its problem file, relative to this file")
    end: Literal["first", "last"] = "first"
    axis: Vec3 = Field(description="where it leaves the junction, in the part's end frame")
    elements: int = Field(40, ge=4, le=2000)
    note: str = ""

    def build(self, base: Path | None) -> Any:
        from pliant.core.problem import Branch  # noqa: PLC0415

        _, problem = _nested_problem(self.file, base, "a branch")
        return Branch(self.name, problem, 0 if self.end == "first" else 1, triple(self.axis),
                      self.elements)


class JunctionModel(_Strict):
    """[[junction]]: a harness junction (a Y-piece of no size) at an end of the part
    (s: 0 or its length), its branches in [[junction.branch]] tables."""

    name: str
    s: float = Field(description="the part's end where it is [m]: 0 or its length")
    branch: list[BranchModel] = Field(min_length=1)
    note: str = ""

    def build(self, base: Path | None) -> Any:
        from pliant.core.problem import Junction  # noqa: PLC0415

        branches = []
        for i, b in enumerate(self.branch):
            try:
                branches.append(b.build(base))
            except ValueError as err:
                raise ValueError(f"branch[{i}].{err}") from None
        return Junction(self.name, self.s, tuple(branches))


class PathModel(_Strict):
    """[path]: a manipulation: the condition ``grip`` is carried from where the file
    puts it through ``waypoints`` (straight legs), its axis turned toward ``tangents``
    when given, in ``steps`` equal steps of arc length."""

    grip: str
    waypoints: list[Vec3] = Field(min_length=1)
    tangents: list[Vec3] | None = None
    steps: int = Field(50, ge=1, le=100000)

    @model_validator(mode="after")
    def _same_length(self) -> PathModel:
        if self.tangents is not None and len(self.tangents) != len(self.waypoints):
            raise ValueError("give one tangent per waypoint, or none")
        return self


class RatingModel(_Strict):
    force: float = Field(gt=0, description="rated force [N]")
    moment: float | None = Field(None, gt=0, description="rated moment [N m]")


class EvaluationModel(_Strict):
    """[evaluation]: how the operation is judged (see ``EvaluationSettings``)."""

    operator: Literal["auto", "one hand", "two hands", "tool", "robot"] = "auto"
    hold: Literal["power grip", "pinch"] = "power grip"
    grips: list[str] = Field(default_factory=list)
    repetitive: bool = False
    multipliers: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rating: RatingModel | None = None
    port: str | None = None
    connector_force: float = Field(0.0, ge=0, description="[N]")
    max_twist_rate: float | None = Field(None, gt=0, description="[deg/m]")
    max_contact_force: float | None = Field(None, gt=0, description="[N]")
    rules: str | None = Field(None, description="a rules file, relative to this file")

    def build(self, base: Path | None) -> EvaluationSettings:
        rules = None
        if self.rules is not None:
            try:
                rules = str(_referenced(self.rules, base, "rules"))
            except ValueError as err:
                raise InputError("evaluation.rules", str(err).removeprefix("file: ")) from None
        return EvaluationSettings(
            operator=self.operator, hold=self.hold, grips=tuple(self.grips),
            repetitive=self.repetitive, multipliers=self.multipliers,
            rating_force=self.rating.force if self.rating else None,
            rating_moment=self.rating.moment if self.rating else None, port=self.port,
            connector_force=self.connector_force, max_twist_rate=self.max_twist_rate,
            max_contact_force=self.max_contact_force, rules=rules)


class PlanModel(_Strict):
    """[plan]: how ``pliant plan`` searches for the grip's path (see ``PlanSettings``)."""

    goal: str | None = Field(None, description="the [[port]] the part's end is seated in")
    budget: float = Field(30.0, gt=0, le=3600, description="[s]")
    seed: int = Field(1, ge=1, lt=2**31)
    allow_contact: bool = False
    approach: float = Field(0.02, ge=0, description="[m]: the straight push into the port")
    attempts: int = Field(3, ge=1, le=100)
    step: float = Field(0.03, gt=0, description="[m]")
    turn: float = Field(15.0, gt=0, le=90, description="[deg]")

    def build(self) -> PlanSettings:
        return PlanSettings(budget=self.budget, seed=self.seed, step=self.step,
                            turn=self.turn, approach=self.approach,
                            allow_contact=self.allow_contact, attempts=self.attempts,
                            goal=self.goal)


class SolverModel(_Strict):
    """[solver]: settings of the model (3D: how many elements)."""

    elements: int = Field(100, ge=4, le=100000, description="about how many elements (3D)")


class LoadModel(_Strict):
    """[[load]]: a force per unit length [N/m] on the stretch [start, end] [m] of the part
    (``pliant.core.loads``): ``force`` dead, in the global frame, or ``follower_force``
    in the part's material frame (2D: tangential, normal; 3D: d1, d2, d3)."""

    name: str = ""
    force: tuple[float, float] | Vec3 | None = None
    follower_force: tuple[float, float] | Vec3 | None = None
    start: float = 0.0
    end: float | None = None

    @property
    def components(self) -> tuple[float, ...]:
        return self.force if self.force is not None else (self.follower_force or ())

    def build(self, index: int) -> DistributedLoad:
        name = self.name or f"load{index + 1}"
        if (self.force is None) == (self.follower_force is None):
            raise InputError(f"load[{index}]", "give either force (dead, global frame) or "
                             "follower_force (material frame), in N/m")
        return DistributedLoad(self.components, follower=self.follower_force is not None,
                               start=self.start, end=self.end, name=name)


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
    units: str | None = Field(None, description="the length unit of the CAD and mesh files "
                              "the scene reads, where they declare none (mm, cm, m, in); "
                              "the numbers in this file stay SI")
    evaluation: EvaluationModel = Field(default_factory=EvaluationModel)
    plan: PlanModel = Field(default_factory=PlanModel)

    @property
    def dimension(self) -> int:
        three = (self.gravity is not None and len(self.gravity) == 3) or any(
            c.is_3d for c in self.condition) or any(
            len(ld.components) == 3 for ld in self.load) or bool(
            self.obstacle or self.clip or self.junction
                                                     or self.assembled
                                                     or self.cad)
        return 3 if three else 2

    def build(self, base: Path | None = None, nested: bool = False) -> Problem:
        """The problem; ``nested`` (an assembled part's own file) skips its
        [[assembled]] parts: one level only."""
        part = self.part.build()
        dimension = self.dimension
        obstacles = self._obstacles(base, nested)
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

    def _obstacles(self, base: Path | None, nested: bool) -> list[Any]:
        obstacles = []
        for i, o in enumerate(self.obstacle):
            try:
                obstacles.append(o.build(base, self.units))
            except ValueError as err:
                raise InputError(f"obstacle[{i}]", str(err)) from None
        for i, c in enumerate(self.cad):
            try:
                obstacles.extend(c.build(base, self.units))
            except InputError as err:
                message = str(err).removeprefix(f"{err.field}: ")
                raise InputError(f"cad[{i}].{err.field}", message) from None
            except FileFormatError as err:
                raise FileFormatError(f"cad[{i}]: {err}") from None
            except ValueError as err:
                raise InputError(f"cad[{i}]", str(err)) from None
        for i, a in enumerate([] if nested else self.assembled):
            try:
                obstacles.append(a.build(base))
            except ValueError as err:
                raise InputError(f"assembled[{i}]", str(err)) from None
        names = [o.name for o in obstacles]
        if len(set(names)) != len(names):
            raise InputError("obstacle", "two obstacles share a name; name each one apart")
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

    def manipulation(self, problem: Problem) -> list[Problem]:
        """The problems along the [path]: its grip carried through the waypoints."""
        if self.path is None:
            return []
        path = self.path
        index = next((k for k, c in enumerate(problem.conditions) if c.name == path.grip),
                     None)
        if index is None:
            raise InputError("path.grip", f"no condition named {path.grip!r}; name the "
                             "[[condition]] the hand holds")
        grip = problem.conditions[index]
        if any(v is None for v in grip.position):
            raise InputError("path.grip", f"{path.grip!r} must hold x, y and z to be "
                             "carried along a path")
        points = np.array([grip.position, *path.waypoints], dtype=float)
        turn = path.tangents is not None and grip.tangent is not None
        tangents = (np.array([grip.tangent, *(path.tangents or [])], dtype=np.float64) if turn
                    else None)
        if float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()) == 0.0:
            raise InputError("path.waypoints", "the path has no length: move the grip")
        problems = []
        for where, direction in along_legs(points, tangents, path.steps):
            changes: dict[str, Any] = {"position": tuple(float(x) for x in where)}
            if direction is not None:
                changes["tangent"] = tuple(float(x) for x in direction)
                if grip.normal is not None:
                    changes["normal"] = None  # the hand's roll follows the turn
            conditions = list(problem.conditions)
            conditions[index] = replace(grip, **changes)
            problems.append(replace(problem, conditions=tuple(conditions)))
        return problems


def along_legs(points: np.ndarray, tangents: np.ndarray | None,
               steps: int) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """The poses a [path] gives: ``steps`` equal steps of arc length along straight legs
    through ``points`` (n, 3) [m], each with the axis turned at a constant rate from one
    of ``tangents`` (n, 3) to the next (None: no axis). A leg of no length gets no step."""
    legs = np.linalg.norm(np.diff(points, axis=0), axis=1)
    at = np.concatenate([[0.0], np.cumsum(legs)])
    total = float(at[-1])
    out = []
    for k in range(1, steps + 1):
        u = total * k / steps
        leg = min(int(np.searchsorted(at, u, side="right")) - 1, len(legs) - 1)
        t = (u - at[leg]) / legs[leg] if legs[leg] > 0 else 1.0
        where = points[leg] + t * (points[leg + 1] - points[leg])
        direction = None
        if tangents is not None:
            a = tangents[leg] / np.linalg.norm(tangents[leg])
            b = tangents[leg + 1] / np.linalg.norm(tangents[leg + 1])
            direction = slerp(a, b, t)
        out.append((where, direction))
    return out


def slerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """The unit vector a fraction t of the way from unit a to unit b along their great
    circle (a half turn has none: an error naming [path] tangents)."""
    angle = math.acos(max(-1.0, min(1.0, float(a @ b))))
    if angle < 1e-9:
        return a
    if math.pi - angle < 1e-9:
        raise InputError("path.tangents", "a tangent turns right round between two "
                         "waypoints; add a waypoint between them")
    return (math.sin((1 - t) * angle) * a + math.sin(t * angle) * b) / math.sin(angle)


@dataclass(frozen=True)
class Scene:
    """A whole file as built: the problem (with its obstacles), the solver settings,
    the manipulation along its [path] (empty without one) and the condition it carries
    (``grip``, None without a path), the clearance margin, ``fixed``: the conditions
    a user does not move (at ports, and clips), how it is judged (``evaluation``) and
    how a path for it is planned (``plan``)."""

    problem: Problem
    solver: SolverModel
    path: list[Problem] = field(default_factory=list)
    margin: float = 0.0
    ports: dict[str, PortModel] = field(default_factory=dict)
    grip: str | None = None
    fixed: tuple[str, ...] = ()
    evaluation: EvaluationSettings = field(default_factory=EvaluationSettings)
    plan: PlanSettings = field(default_factory=PlanSettings)
    warnings: tuple[str, ...] = ()


# Part kinds whose bending stiffness a solid section of their material does not give.
SECTION_MISLEADS = {
    "reinforced hose": "its braided or spiral plies make it many times stiffer in bending "
                       "than its rubber",
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
        "plan": PlanModel, "part.material": MaterialModel,
        "evaluation.rating": RatingModel}
    table = ".".join(names[:-1])
    model = tables.get(table, ProblemFile if not table else None)
    if model is None:
        return "unknown key; see the README's file format (SI units)"
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
                nested: bool = False) -> Scene:
    """Parse TOML text into a ``Scene``; mesh files are looked up relative to ``base``
    (the file's folder); ``nested`` (an assembled part's own file) skips its
    [[assembled]] parts."""
    return scene_from_data(read_toml(text, source), source, base, nested)


def scene_from_data(data: dict[str, Any], source: str = "<data>", base: Path | None = None,
                    nested: bool = False) -> Scene:
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
        problem = model.build(base, nested)
        return Scene(problem, model.solver, model.manipulation(problem), model.margin,
                     {p.name: p for p in model.port},
                     model.path.grip if model.path is not None else None,
                     tuple(c.name or f"condition{i + 1}" for i, c in enumerate(model.condition)
                           if c.port is not None) + tuple(c.name for c in model.clip),
                     model.evaluation.build(base), model.plan.build(),
                     _warnings(model, problem.part))
    except PliantError as err:
        raise FileFormatError(f"{source}: {err}") from None


def load_problem(path: str | Path) -> Problem:
    """Read a problem file (TOML, SI units)."""
    return load_problem_file(path)[0]


def load_problem_file(path: str | Path) -> tuple[Problem, SolverModel]:
    """Read a problem file (TOML, SI units) and its ``[solver]`` settings."""
    scene = load_scene(path)
    return scene.problem, scene.solver


def read_text(path: str | Path) -> str:
    """A file's text (UTF-8), or a one-line ``FileFormatError`` saying why not."""
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FileFormatError(f"{path}: no such file; check the path") from None
    except UnicodeDecodeError as err:
        raise FileFormatError(f"{path}: not a text file in UTF-8 (byte {err.start}); save "
                              "it as UTF-8 TOML") from None
    except OSError as err:
        raise FileFormatError(f"{path}: cannot be read: {err.strerror}") from None


def load_scene(path: str | Path) -> Scene:
    """Read a problem or scene file (TOML, SI units): obstacles, ports, clips, path."""
    path = Path(path)
    return parse_scene(read_text(path), str(path), path.parent)


def dump_problem(problem: Problem, description: str = "", meshes: Path | None = None,
                 base: Path | None = None) -> str:
    """Write a problem as TOML text that ``parse_problem`` reads back, obstacles
    included. A mesh obstacle's mesh goes to a file in ``meshes`` (OBJ, every digit
    kept), named in the text relative to ``base`` (the folder the text will be read
    from; absolute without one); without ``meshes`` a mesh obstacle is an error."""
    part = problem.part
    lines = [f"name = {_toml(problem.name)}"]
    if description:
        lines.append(f"description = {_toml(description)}")
    if any(problem.gravity or ()) or problem.dimension == 3:
        lines.append(f"gravity = {_vec(problem.gravity)}")
    lines += ["", "[part]", f"name = {_toml(part.name)}", f"length = {_num(part.length)}",
              f"bending_stiffness = {_num(part.bending_stiffness)}",
              f"mass_per_length = {_num(part.mass_per_length)}"]
    for key in ("torsional_stiffness", "bending_stiffness_2", "min_bend_radius",
                "poisson_ratio", "axial_stiffness", "max_axial_strain"):
        value = getattr(part, key)
        if value is not None:
            lines.append(f"{key} = {_num(value)}")
    if part.kind is not None:
        lines.append(f"kind = {_toml(part.kind)}")
    if part.outer_diameter is not None:
        lines.append(f"outer_diameter = {_num(part.outer_diameter)}")
        lines.append(f"inner_diameter = {_num(part.inner_diameter)}")
    for key, knots in (("rest_curvature", part.rest_knots),
                       ("rest_curvature_2", part.rest_knots_2), ("rest_twist", part.twist_knots)):
        lines.append(f"{key} = [{', '.join(f'[{_num(s)}, {_num(k)}]' for s, k in knots)}]")
    three = problem.dimension == 3
    for c in problem.conditions:
        lines += ["", "[[condition]]", f"name = {_toml(c.name)}", f"s = {_num(c.s)}"]
        for key, value in zip("xyz", c.position):
            if value is not None:
                lines.append(f"{key} = {_num(value)}")
        if c.angle is not None:
            lines.append(f"angle = {_num(c.angle)}")
        if c.tangent is not None:
            lines.append(f"tangent = {_vec(c.tangent)}")
        if c.normal is not None:
            lines.append(f"normal = {_vec(c.normal)}")
        if c.follower and three:
            if any(f is not None for f in c.force):
                lines.append(f"follower_force = {_vec(tuple(f or 0.0 for f in c.force))}")
            if c.moment is not None:
                lines.append(f"follower_moment = {_vec(c.moment)}")
            continue
        keys = ("Ft", "Fn") if c.follower else ("Fx", "Fy", "Fz")
        for key, value in zip(keys, c.force):
            if value is not None:
                lines.append(f"{key} = {_num(value)}")
        if c.moment is not None:
            moment = c.moment
            lines.append(f"moment = {_vec(moment) if isinstance(moment, tuple) else _num(moment)}")
    for ld in problem.loads:
        lines += ["", "[[load]]", f"name = {_toml(ld.name)}",
                  f"{'follower_force' if ld.follower else 'force'} = {_vec(ld.force)}",
                  f"start = {_num(ld.start)}"]
        if ld.end is not None:
            lines.append(f"end = {_num(ld.end)}")
    for obstacle in problem.obstacles:
        lines += ["", *_obstacle_lines(obstacle, meshes, base)]
    return "\n".join(lines) + "\n"


def _obstacle_lines(obstacle, meshes: Path | None, base: Path | None) -> list[str]:
    """An obstacle as an [[obstacle]] table (``dump_problem``)."""
    from pliant.io.atomic import atomic_write  # noqa: PLC0415
    from pliant.scene.distance import BOX, CYLINDER, HALFSPACE, SPHERE  # noqa: PLC0415

    p, R = obstacle.param, obstacle.rotation
    lines = ["[[obstacle]]", f"name = {_toml(obstacle.name)}",
             f"position = {_vec(obstacle.translation)}"]
    rotation = f"rotation = [{', '.join(_vec(row) for row in R)}]"
    if obstacle.kind == SPHERE:
        lines += ['shape = "sphere"', f"radius = {_num(p[0])}"]
    elif obstacle.kind == BOX:
        lines += ['shape = "box"', f"size = {_vec(2.0 * p[:3])}", rotation]
    elif obstacle.kind == CYLINDER:
        lines += ['shape = "cylinder"', f"radius = {_num(p[0])}", f"length = {_num(2.0 * p[1])}",
                  rotation]
    elif obstacle.kind == HALFSPACE:
        lines += ['shape = "halfspace"', f"axis = {_vec(R[:, 2])}"]
    else:
        if meshes is None:
            raise OutputError(f"the obstacle {obstacle.name!r} is a mesh: give a folder for "
                              "its mesh file (meshes=...)")
        mesh = obstacle.mesh
        flat = mesh.tri.reshape(-1, 3)
        vertices, faces = np.unique(flat, axis=0, return_inverse=True)
        faces = faces.reshape(-1, 3)
        stem = re.sub(r"[^A-Za-z0-9_-]+", "_", obstacle.name).strip("_") or "mesh"
        path = Path(meshes) / f"{stem}.obj"
        text = "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist()) + "".join(
            f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces.tolist())
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda handle: handle.write(text.encode()), "the mesh")
        name = str(path.relative_to(base)) if base is not None and path.is_relative_to(
            base) else str(path.resolve())
        extent = float(np.ptp(flat, axis=0).max())
        resolution = int(round(extent * 1.2 / mesh.g_size)) + 1
        lines += ['shape = "mesh"', f"file = {_toml(name)}", "scale = 1.0",
                  f"resolution = {resolution}", rotation]
    if obstacle.friction:
        lines.append(f"friction = {_num(obstacle.friction)}")
    return lines


def _vec(values) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def _num(value: float) -> str:
    if not math.isfinite(value):
        raise FileFormatError(f"cannot write the non-finite number {value!r}")
    return repr(float(value))


def _toml(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{escaped}"'


_HEADER = re.compile(r'^\s*\[\[?\s*[A-Za-z_"]')
_PATH_HEADER = re.compile(r"^\s*\[\s*path\s*\]")
_FILE_KEY = re.compile(r'^(\s*(?:file|rules)\s*=\s*)"([^"\\]*)"(.*)$')


def with_path_table(text: str, table: str, source: str = "<string>",
                    moved_from: Path | None = None, moved_to: Path | None = None) -> str:
    """A scene's TOML text with its [path] table replaced by ``table`` (or added): what
    ``pliant plan`` writes, comments and all. When the copy goes to another folder
    (``moved_from`` -> ``moved_to``), its relative ``file`` and ``rules`` references are
    made absolute so that they still point at the same files. The result is read back
    and must hold the same document but for the path: otherwise a ``FileFormatError``."""
    lines = text.splitlines()
    start = next((k for k, line in enumerate(lines) if _PATH_HEADER.match(line)), None)
    if start is not None:
        end = next((k for k in range(start + 1, len(lines)) if _HEADER.match(lines[k])),
                   len(lines))
        # A comment right above the next table belongs to it.
        while end - 1 > start and lines[end - 1].lstrip().startswith("#"):
            end -= 1
        lines = lines[:start] + table.rstrip("\n").splitlines() + [""] + lines[end:]
    else:
        first = next((k for k, line in enumerate(lines) if _HEADER.match(line)), len(lines))
        lines = lines[:first] + table.rstrip("\n").splitlines() + [""] + lines[first:]
    if moved_from is not None and moved_to is not None and (
            moved_from.resolve() != moved_to.resolve()):
        for k, line in enumerate(lines):
            m = _FILE_KEY.match(line)
            if m and not Path(m.group(2)).is_absolute():
                target = (moved_from / m.group(2)).resolve()
                lines[k] = f"{m.group(1)}{_toml(str(target))}{m.group(3)}"
    out = "\n".join(lines) + "\n"
    before = read_toml(text, source)
    try:
        after = read_toml(out, source)
    except FileFormatError:
        after = None
    for doc in (before, after or {}):
        doc.pop("path", None)
    if after is None or _without_files(before) != _without_files(after):
        raise FileFormatError(f"{source}: the planned path could not be written into a "
                              "copy of this file (its [path] table is not where a table "
                              "header can find it); add the planned [path] by hand")
    return out


def _without_files(doc: Any) -> Any:
    if isinstance(doc, dict):
        return {k: _without_files(v) for k, v in doc.items() if k not in ("file", "rules")}
    if isinstance(doc, list):
        return [_without_files(v) for v in doc]
    return doc
