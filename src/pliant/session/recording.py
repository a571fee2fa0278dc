"""Recordings of manipulations: a problem and the grip events applied to it, as JSON,
so that a user's manipulation can be replayed (``pliant.session.replay``) exactly.

    {"format": "pliant-recording", "version": 1,
     "problem": "<the problem file's TOML text>",
     "events": [{"grip": "hand", "t": 0.016, "position": [0.55, 0.3, 0.2]}, ...]}

Event keys: grip (a condition's name), t [s], position [m] (entries null where free),
tangent and normal (3D), angle [rad] (2D). SI units.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pliant.core.problem import Problem
from pliant.errors import FileFormatError
from pliant.io.atomic import atomic_write
from pliant.io.problem_file import dump_problem, parse_scene
from pliant.session.session import GripEvent

Vec3 = tuple[float, float, float]


class _EventModel(BaseModel):
    model_config = ConfigDict(extra="forbid")

    grip: str = Field(min_length=1)
    t: float = Field(0.0, ge=0.0, description="[s]")
    position: list[float | None] | None = Field(None, min_length=2, max_length=3)
    tangent: Vec3 | None = None
    normal: Vec3 | None = None
    angle: float | None = None


class _RecordingModel(BaseModel):
    model_config = ConfigDict(extra="forbid")

    format: Literal["pliant-recording"]
    version: Literal[1]
    problem: str
    events: list[_EventModel]


def save_recording(path: str | Path, problem: Problem, events: list[GripEvent]) -> Path:
    """Write a recording (atomically)."""
    path = Path(path)
    # Mesh obstacles go beside it, in NAME-meshes/, named relative to its folder.
    meshes = path.parent / f"{path.stem}-meshes"
    data = {"format": "pliant-recording", "version": 1,
            "problem": dump_problem(problem, meshes=meshes, base=path.parent),
            "events": [{k: v for k, v in {
                "grip": e.grip, "t": e.t,
                "position": None if e.position is None else list(e.position),
                "tangent": None if e.tangent is None else list(e.tangent),
                "normal": None if e.normal is None else list(e.normal),
                "angle": e.angle}.items() if v is not None} for e in events]}
    text = json.dumps(data, indent=1).encode()
    return atomic_write(path, lambda handle: handle.write(text), "the recording")


def load_recording(path: str | Path) -> tuple[Problem, list[GripEvent]]:
    """Read a recording; a bad file raises FileFormatError naming the file and field."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise FileFormatError(f"{path}: cannot read it: {err.strerror or err}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise FileFormatError(f"{path}: not valid JSON: {err}") from None
    try:
        model = _RecordingModel.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(top level)"
        raise FileFormatError(f"{path}: {where}: {first['msg']}") from None
    problem = parse_scene(model.problem, f"{path} (its problem)", path.parent).problem
    events = [GripEvent(grip=e.grip, t=e.t,
                        position=None if e.position is None else tuple(e.position),
                        tangent=e.tangent, normal=e.normal, angle=e.angle)
              for e in model.events]
    return problem, events
