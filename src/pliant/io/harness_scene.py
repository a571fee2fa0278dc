"""A harness in a scene: a TOML file whose ``[[harness]]`` tables name KBL files and
whose ``[[obstacle]]`` and ``[[cad]]`` tables (the scene file's own) place what it must
clear. ``pliant harness SCENE.toml`` reads it.

    [[harness]]
    file = "kbl/kblxml_2.3sr-1_000971230_ltgs_generator_170718.kbl"  # its own units
    module = []                   # the variant: module ids or part numbers (all: empty)

    margin = 0.005                # clearance wanted round the obstacles [m]
    [[obstacle]]                  # as in a scene file (SI), or [[cad]] (units declared)
    ...

The numbers of this file are SI; each file it names is read in its own declared unit
once (a KBL file by its ``Unit`` table, a STEP file by its header, a mesh by ``units``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError

from pliant.core.harness import Harness
from pliant.core.rules import ObstacleRule
from pliant.errors import FileFormatError, PliantError
from pliant.io.kbl import read_kbl
from pliant.io.problem_file import ObstacleModel, build_obstacles, check_names, read_text
from pliant.io.scene_sections import CadModel
from pliant.io.sections import _Strict
from pliant.io.tomlfile import field_path, read_toml

Vec3 = tuple[float, float, float]


class HarnessTable(_Strict):
    """One harness of the scene: its KBL file (relative to the scene file) and the
    modules to build (none: every wire)."""

    file: str
    module: list[str] = Field(default_factory=list)
    strict: bool = False


class HarnessSceneFile(_Strict):
    """A whole harness scene file."""

    name: str = ""
    description: str = ""
    harness: list[HarnessTable] = Field(min_length=1)
    gravity: Vec3 = (0.0, 0.0, -9.81)
    obstacle: list[ObstacleModel] = Field(default_factory=list)
    cad: list[CadModel] = Field(default_factory=list)
    margin: float = Field(0.0, ge=0, description="clearance wanted round obstacles [m]")
    units: str | None = Field(None, description="the length unit of the CAD and mesh files "
                              "that declare none (mm, cm, m, in)")


@dataclass(frozen=True)
class HarnessScene:
    """A harness scene as built: each harness with its modules, the obstacles (SI),
    the clearance margin [m], gravity [m/s^2] and what is said of each obstacle."""

    source: str
    harnesses: tuple[tuple[Harness, tuple[str, ...]], ...]
    obstacles: tuple[Any, ...]
    margin: float
    gravity: Vec3
    rules: dict[str, ObstacleRule] = field(default_factory=dict)


def is_harness_scene(text: str) -> bool:
    """Whether a TOML text is a harness scene (it has a [[harness]] table)."""
    return "[[harness]]" in text


def load_harness_scene(path: str | Path) -> HarnessScene:
    """Read a harness scene file; errors name the file and the field."""
    path = Path(path)
    data = read_toml(read_text(path), str(path))
    try:
        model = HarnessSceneFile.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        raise FileFormatError(f"{path}: {field_path(tuple(first['loc']))}: "
                              f"{first['msg'].removeprefix('Value error, ')}") from None
    base = path.parent
    try:
        obstacles, rules = build_obstacles(model.obstacle, model.cad, base, model.units)
        check_names(obstacles)
    except PliantError as err:
        raise FileFormatError(f"{path}: {err}") from None
    harnesses = []
    for i, table in enumerate(model.harness):
        kbl = (base / table.file) if not Path(table.file).is_absolute() else Path(table.file)
        try:
            harnesses.append((read_kbl(kbl, strict=table.strict), tuple(table.module)))
        except FileFormatError as err:
            raise FileFormatError(f"{path}: harness[{i}].file: {err}") from None
    return HarnessScene(str(path), tuple(harnesses), tuple(obstacles), model.margin,
                        model.gravity, {k: r for k, r in rules.items() if r != ObstacleRule()})
