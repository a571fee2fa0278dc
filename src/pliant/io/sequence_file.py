"""Sequence files: several flexible parts to fit, in an order to be found.

A sequence file (TOML, SI units) names each part to fit in a ``[[fit]]`` table: its own
scene file (the part, where the fitter picks it up, its ports and its ``[path]``), read
as ``pliant evaluate`` reads it. The sequence file adds what every operation shares: the
product's ``[[obstacle]]``, ``[[cad]]`` and ``[[assembled]]`` tables (the parts fitted
before the sequence starts), a ``margin``, the ``[[hook]]`` tables (a temporary place
the fitter may leave a part on, to finish it later) and a ``[sequence]`` table. A
part's own file stays a valid single-part scene: ``pliant evaluate`` judges it alone.

Like every io module this one only reads; ``pliant.assembly.sequence`` composes each
operation's scene (the shared obstacles and the parts fitted before it) and solves.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError, model_validator

from pliant.core.rules import ObstacleRule
from pliant.errors import FileFormatError, InputError, PliantError
from pliant.io.problem_file import (
    ObstacleModel,
    Scene,
    build_obstacles,
    check_names,
    parse_scene,
    read_text,
)
from pliant.io.scene_sections import AssembledModel, CadModel, SettleFitted
from pliant.io.sections import Vec3, _referenced, _Strict
from pliant.io.tomlfile import field_path, read_toml

MAX_PARTS = 7  # 7! = 5,040 orders: beyond it, split the product into groups
MAX_HOOKS = 3  # each hook adds orders: a part fitted directly, or in two operations


class FitModel(_Strict):
    """[[fit]]: a part to fit: its own scene file (relative to this one) and how it
    behaves once fitted, for the parts fitted after it."""

    name: str = Field(min_length=1, description="the part's name in the sequence")
    file: str = Field(description="its scene file: the part, its start, ports and [path]")
    elements: int | None = Field(None, ge=4, le=2000, description="about how many elements "
                                 "(default: its file's [solver])")
    flexible: bool = Field(True, description="once fitted, a part that touches it deforms "
                           "it (they are solved together); false: a rigid tube")
    friction: float = Field(0.0, ge=0.0, description="Coulomb's coefficient between it, "
                            "fitted, and a part that touches it")
    note: str = ""


class HookModel(_Strict):
    """[[hook]]: a temporary place (a parking clip, a hook on a fixture) the fitter may
    leave a part on: the part's grip carried there (through ``via``), held there in
    the hand's pose while other parts are fitted, and later taken from there along
    the part's own [path] (or its planned one) to its goal."""

    name: str = Field(min_length=1, description="what the hook is called")
    part: str = Field(min_length=1, description="the [[fit]] part it may hold")
    position: Vec3 = Field(description="where it holds the part's grip [m]")
    tangent: Vec3 | None = Field(None, description="the hand's axis as it leaves the part "
                                 "there (default: the grip's axis where it is picked up)")
    via: list[Vec3] = Field(default_factory=list, description="waypoints on the way "
                            "there [m]")
    steps: int = Field(20, ge=1, le=2000, description="steps of the carry to the hook")
    note: str = ""


class SequenceModel(_Strict):
    """[sequence]: how the orders are searched."""

    exhaustive: bool = Field(False, description="judge every operation of every order, "
                             "pruning nothing (the slow twin of the search)")


class SequenceFileModel(_Strict):
    """A whole sequence file."""

    name: str = ""
    description: str = ""
    margin: float | None = Field(None, ge=0, description="clearance wanted round "
                                 "obstacles [m] (default: each part's file's)")
    units: str | None = Field(None, description="the length unit of the CAD and mesh files "
                              "this file reads, where they declare none")
    fit: list[FitModel] = Field(min_length=1, max_length=MAX_PARTS)
    obstacle: list[ObstacleModel] = Field(default_factory=list)
    cad: list[CadModel] = Field(default_factory=list)
    assembled: list[AssembledModel] = Field(default_factory=list)
    hook: list[HookModel] = Field(default_factory=list, max_length=MAX_HOOKS)
    sequence: SequenceModel = Field(default_factory=SequenceModel)

    @model_validator(mode="after")
    def _names_apart(self) -> SequenceFileModel:
        names = [f.name for f in self.fit]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"fit: two parts are named {twice[0]!r}; name each apart")
        hooks = [h.name for h in self.hook]
        for i, h in enumerate(self.hook):
            if h.part not in names:
                raise ValueError(f"hook[{i}].part: no [[fit]] part named {h.part!r}; "
                                 f"known: {', '.join(names)}")
            if h.tangent is not None and sum(x * x for x in h.tangent) == 0.0:
                raise ValueError(f"hook[{i}].tangent: give the hand's axis, not zero")
            if hooks.count(h.name) > 1:
                raise ValueError(f"hook[{i}].name: two hooks are named {h.name!r}; name "
                                 "each apart")
        return self


@dataclass(frozen=True)
class Fit:
    """A part to fit, as read: its name, its scene file and that scene (built with its
    own obstacles, its [path] not yet carried: the sequence adds obstacles first), the
    element count its operations and its fitted shape are solved with, and how it
    behaves once fitted."""

    name: str
    file: Path
    scene: Scene
    elements: int
    flexible: bool
    friction: float


@dataclass(frozen=True)
class Hook:
    """A [[hook]] as read: its name, the index of the part it may hold, the pose it
    holds the part's grip in (position [m]; the hand's axis, None: the grip's own where
    it is picked up), the waypoints on the way there [m] and the carry's steps."""

    name: str
    part: int
    position: Vec3
    tangent: Vec3 | None = None
    via: tuple[Vec3, ...] = ()
    steps: int = 20


@dataclass(frozen=True)
class SequenceScene:
    """A sequence file as built: the parts to fit (in the file's order), the obstacles
    every operation shares (the product, and parts fitted before the sequence) with
    their packaging rules by name, the margin (None: each part's own), the search's
    settings, and ``key``: a digest of every file read (a store of operations judged
    for another version of the files is not reused)."""

    name: str
    source: str
    fits: tuple[Fit, ...]
    obstacles: tuple[Any, ...] = ()
    obstacle_rules: dict[str, ObstacleRule] = field(default_factory=dict)
    margin: float | None = None
    exhaustive: bool = False
    key: str = ""
    hooks: tuple[Hook, ...] = ()

    def index(self, name: str) -> int:
        """The position of the part named ``name``; InputError naming the known ones."""
        for i, f in enumerate(self.fits):
            if f.name == name:
                return i
        raise InputError("fit", f"no part to fit named {name!r}; known: "
                         f"{', '.join(f.name for f in self.fits)}")


def is_sequence(data: dict[str, Any]) -> bool:
    """Whether a TOML document read is a sequence file (it has [[fit]] tables)."""
    return "fit" in data


def load_sequence(path: str | Path, settle: SettleFitted | None = None) -> SequenceScene:
    """Read a sequence file and every part's scene file; ``settle`` solves the
    [[assembled]] parts (``pliant.assembly.sequence.load_sequence`` passes it).
    Errors name the file, the table and the field."""
    path = Path(path)
    text = read_text(path)
    data = read_toml(text, str(path))
    try:
        model = SequenceFileModel.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        where = field_path(tuple(first["loc"]))
        message = first["msg"].removeprefix("Value error, ")
        if first["type"] == "extra_forbidden":
            message = ("not a key of a sequence file (its tables: [[fit]], [[obstacle]], "
                       "[[cad]], [[assembled]], [[hook]], [sequence]; a part's own keys go "
                       "in its scene file)")
        more = f" (and {len(err.errors()) - 1} more)" if len(err.errors()) > 1 else ""
        raise FileFormatError(f"{path}: {where}: {message}{more}") from None
    base = path.parent
    digest = hashlib.sha256(text.encode())
    try:
        obstacles, rules = build_obstacles(model.obstacle, model.cad, base, model.units)
        for i, a in enumerate(model.assembled):
            try:
                obstacles.append(a.build(base, settle))
            except ValueError as err:
                raise InputError(f"assembled[{i}]", str(err)) from None
        check_names(obstacles)
        fits = []
        for i, f in enumerate(model.fit):
            fits.append(_fit(f, i, base, settle, digest))
        _check_apart(fits, obstacles)
    except PliantError as err:
        if isinstance(err, FileFormatError) and str(err).startswith(str(path)):
            raise
        raise FileFormatError(f"{path}: {err}") from None
    names = [f.name for f in fits]
    hooks = tuple(Hook(h.name, names.index(h.part), h.position, h.tangent, tuple(h.via),
                       h.steps) for h in model.hook)
    return SequenceScene(model.name or path.stem, str(path), tuple(fits), tuple(obstacles),
                         {k: r for k, r in rules.items() if r != ObstacleRule()},
                         model.margin, model.sequence.exhaustive, digest.hexdigest(), hooks)


def _fit(f: FitModel, i: int, base: Path, settle: SettleFitted | None,
         digest: Any) -> Fit:
    """One [[fit]] table's part, its scene file read (a 3D scene with a [path], or a
    [plan] goal: its path is then planned in each operation)."""
    try:
        file = _referenced(f.file, base, "scene")
    except ValueError as err:
        raise InputError(f"fit[{i}].file", str(err).removeprefix("file: ")) from None
    text = read_text(file)
    digest.update(text.encode())
    scene = parse_scene(text, str(file), file.parent, settle=settle)
    if scene.problem.dimension != 3:
        raise InputError(f"fit[{i}].file", f"{str(file)!r} is a 2D problem; parts fitted in "
                         "a sequence are 3D (give gravity and conditions three components)")
    if scene.path_spec is None:
        goal = scene.plan.goal
        if goal is None:
            raise InputError(f"fit[{i}].file", f"{str(file)!r} has no [path] and no [plan] "
                             "goal: give the fitter's path, or the port to plan one into "
                             "(planned in each operation, with the parts fitted before)")
        if goal not in scene.ports:
            raise InputError(f"fit[{i}].file", f"{str(file)!r}: [plan] goal {goal!r} is no "
                             f"[[port]] of it; known: {', '.join(scene.ports) or 'none'}")
    return Fit(f.name, file, scene, f.elements or scene.solver.elements, f.flexible,
               f.friction)


def _check_apart(fits: list[Fit], obstacles: list[Any]) -> None:
    """A part's name is no obstacle's (a fitted part becomes one), and every part falls
    under the same gravity."""
    taken = {o.name for o in obstacles}
    for i, f in enumerate(fits):
        own = {o.name for o in f.scene.problem.obstacles}
        clash = ({f.name} & taken) or (own & taken) or (own & {g.name for g in fits})
        if clash:
            raise InputError(f"fit[{i}]", f"the name {sorted(clash)[0]!r} is both an "
                             "obstacle and a part (or two obstacles); name each apart")
    gravity = {tuple(f.scene.problem.gravity or ()) for f in fits}
    if len(gravity) > 1:
        raise InputError("fit", "the parts' files give different gravity vectors; give them "
                         "the same")
