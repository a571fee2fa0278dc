"""A scene file's sections beyond the part, its conditions and obstacles: CAD
assemblies, flexible parts already fitted, ports, clips, harness branches and
junctions, the [path], the [evaluation]'s ratings and the [plan]. Each validates its
table (pydantic) and builds its core object."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator

from pliant.core.conditions import Condition
from pliant.core.numbers import triple
from pliant.core.planning import PathSpec, PlanSettings
from pliant.core.problem import Problem
from pliant.core.rules import EvaluationSettings
from pliant.core.worker import Worker
from pliant.errors import InputError, PliantError
from pliant.io.sections import PackagingFields, Vec3, _referenced, _Strict
from pliant.io.tomlfile import read_text
from pliant.util import progress


class CadModel(PackagingFields):
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
    crease: float = Field(
        10.0, ge=0.0, lt=90.0,
        description="[deg] faces meeting within this angle tessellate one smooth surface: "
        "a contact reads its normal interpolated across them (0: every facet flat, "
        "every edge sharp)")
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
                                                  rotation, self.resolution,
                                                  crease=self.crease)
                except ValueError as err:
                    raise ValueError(f"{err} (the solid {name!r} of {path.name})") from None
                out.append(obstacle.with_friction(self.friction))
        return out


def _nested_problem(name: str, base: Path | None, what: str) -> tuple[Path, Problem]:
    """(path, problem) of a 3D problem file a scene refers to (an assembled part's, a
    branch's), its own [[assembled]] parts not followed; ValueError naming ``file``."""
    from pliant.io.problem_file import parse_scene  # noqa: PLC0415 (it reads our sections)

    path = _referenced(name, base, "problem")
    try:
        text = read_text(path, "problem file")
        problem = parse_scene(text, str(path), path.parent, nested=True).problem
    except (OSError, PliantError) as err:
        raise ValueError(f"file: {err}") from None
    if problem.dimension != 3:
        raise ValueError(f"file: {str(path)!r} is a 2D problem; {what} is 3D")
    return path, problem


# What settles a flexible part already fitted: (name, its problem, elements, flexible,
# friction) -> its obstacle (``pliant.assembly.scenes.settle_fitted``).
SettleFitted = Callable[[str, Problem, int, bool, float], Any]


class AssembledModel(_Strict):
    """[[assembled]]: a flexible part already fitted, in its clamps: its own problem file
    (3D, relative to this one), solved as the scene is loaded (``pliant.assembly.
    scenes``, which keeps its shape in the disk cache), and its tube becomes an
    obstacle."""

    name: str
    file: str = Field(description="its problem file, relative to this file")
    elements: int = Field(60, ge=4, le=2000)
    flexible: bool = Field(True, description="a part that touches it deforms it (they are "
                           "solved together); false: its tube is a rigid obstacle")
    friction: float = Field(0.0, ge=0.0, description="Coulomb's coefficient between it and "
                            "the part that touches it")
    note: str = ""

    def build(self, base: Path | None, settle: SettleFitted | None) -> Any:
        """Its obstacle, by ``settle`` (which solves the part's own problem: io only reads
        files, ``pliant.assembly.scenes`` settles); ValueError without one."""
        path, problem = _nested_problem(self.file, base, "an assembled part")
        if settle is None:
            raise ValueError(f"{self.name!r} is a flexible part already fitted, whose shape "
                             "is solved as the scene is loaded: read this file with "
                             "pliant.assembly.load_scene (pliant.io only reads files)")
        try:
            return settle(self.name, problem, self.elements, self.flexible, self.friction)
        except PliantError as err:
            raise ValueError(f"file: {str(path)!r} could not be solved: {err}") from None


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


MOST_STEPS = 10_000  # a [path]'s steps at most: each keeps its equilibrium (tens of kB)


class PathModel(_Strict):
    """[path]: a manipulation: the condition ``grip`` is carried from where the file
    puts it through ``waypoints`` (straight legs), its axis turned toward ``tangents``
    when given, in ``steps`` equal steps of arc length."""

    grip: str
    waypoints: list[Vec3] = Field(min_length=1)
    tangents: list[Vec3] | None = None
    steps: int = Field(50, ge=1, le=MOST_STEPS)
    carry: list[str] = Field(default_factory=list, description="other hands carried with "
                             "the grip as one rigid carrier (both hands carrying)")

    @model_validator(mode="after")
    def _same_length(self) -> PathModel:
        if self.tangents is not None and len(self.tangents) != len(self.waypoints):
            raise ValueError("give one tangent per waypoint, or none")
        return self

    def build(self) -> PathSpec:
        return PathSpec(self.grip, tuple(tuple(w) for w in self.waypoints),  # type: ignore[misc]
                        None if self.tangents is None
                        else tuple(tuple(t) for t in self.tangents),  # type: ignore[misc]
                        self.steps, tuple(self.carry))


class RatingModel(_Strict):
    force: float = Field(gt=0, description="rated force [N]")
    moment: float | None = Field(None, gt=0, description="rated moment [N m]")


class EnvelopeModel(_Strict):
    """[evaluation] envelope: the room a tool or robot's gripper takes round the part."""

    length: float = Field(gt=0, description="[m] from the part's axis to the tool's far end")
    breadth: float = Field(gt=0, description="[m] along the part (the jaws' and the body's)")
    thickness: float = Field(gt=0, description="[m] the body's, across the part")
    jaw: float = Field(0.005, ge=0, description="[m] the jaws' thickness round the part")


class EvaluationModel(_Strict):
    """[evaluation]: how the operation is judged (see ``EvaluationSettings``)."""

    operator: Literal["auto", "one hand", "two hands", "tool", "robot"] = "auto"
    hold: Literal["power grip", "pinch"] = "power grip"
    grips: list[str] = Field(default_factory=list)
    repetitive: bool = False
    multipliers: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rating: RatingModel | None = None
    envelope: EnvelopeModel | None = None
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
            rating_moment=self.rating.moment if self.rating else None,
            tool_envelope=None if self.envelope is None else (
                self.envelope.length, self.envelope.breadth, self.envelope.thickness,
                self.envelope.jaw), port=self.port,
            connector_force=self.connector_force, max_twist_rate=self.max_twist_rate,
            max_contact_force=self.max_contact_force, rules=rules)


class WorkerModel(_Strict):
    """[worker]: who does the operation and where (see ``pliant.core.worker.Worker``)."""

    position: Vec3 = Field(description="[m] on the floor, between the feet")
    facing: Vec3 = (1.0, 0.0, 0.0)
    posture: Literal["standing", "kneeling"] = "standing"
    sex: Literal["men", "women"] = "women"
    percentile: float = Field(5.0, ge=1, le=99, description="of stature and reach")
    side: Literal["right", "left"] = "right"

    @model_validator(mode="after")
    def _faces_somewhere(self) -> WorkerModel:
        if not any(self.facing):
            raise ValueError("facing: give the direction the worker faces (not zero)")
        return self

    def build(self) -> Worker:
        return Worker(triple(self.position), triple(self.facing), self.posture, self.sex,
                      self.percentile, self.side)


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
    carry: list[str] = Field(default_factory=list, description="other hands carried with "
                             "the grip as one rigid carrier")

    def build(self) -> PlanSettings:
        return PlanSettings(budget=self.budget, seed=self.seed, step=self.step,
                            turn=self.turn, approach=self.approach,
                            allow_contact=self.allow_contact, attempts=self.attempts,
                            goal=self.goal, carry=tuple(self.carry))
