"""The A/D evaluation as files: JSON (with a schema version and units; its schema is the
pydantic model below, ``pliant evaluate --schema`` prints it) and CSV (a row per step).

Both are written atomically. The JSON is what other tools read: ``EvaluationReport``
validates it, so a consumer can check a file against the same schema pliant writes by.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from pliant.io.atomic import atomic_write
from pliant.io.jsontext import finite

Zone = Literal["green", "yellow", "red", "unchecked", "info"]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


class CheckModel(_Model):
    rule: str
    title: str
    family: Literal["ergonomics", "damage", "interference", "stability", "solve"]
    value: float | None = Field(description="the worst value; null where not finite")
    unit: str
    zone: Zone
    worse: Literal["above", "below"]
    yellow_at: float | None
    red_at: float | None
    step: int | None
    grip: str | None
    s: float | None = Field(description="[m]")
    note: str
    source: str
    provenance: str
    yellow_steps: list[int]
    red_steps: list[int]


class RatingModel(_Model):
    force: float = Field(description="[N]")
    moment: float = Field(description="[N m]")


class AccessModel(_Model):
    clearance: float = Field(description="[m] the best approach's room; negative: none fits")
    approach: list[float] = Field(description="(3,) the forearm's direction from the part")
    bound_by: str = Field(description="what is nearest the best approach's envelope")
    centre: list[float] = Field(description="(3,) [m] the hand's centre on the part")
    s: float = Field(description="[m] the hand's centre's arc length")
    reach: float = Field(0.0, description="[m] the envelope's reach out along the approach")
    ring: float = Field(0.0, description="[m] the hand's radius round the part")


class ReachModel(_Model):
    excess: float = Field(description="[m] beyond the arm's reach; negative: within it")
    trunk: float = Field(description="[deg] the trunk bend it takes")
    upper_arm: float = Field(description="[deg] the upper arm's elevation from hanging")
    distance: float = Field(description="[m] shoulder to grip")
    arm: float = Field(description="[m] the arm's reach")
    shoulder: list[float] = Field(description="(3,) [m]")
    elbow: list[float] = Field(description="(3,) [m]")
    side: Literal["right", "left"]
    hip: list[float] = Field(default_factory=list, description="(3,) [m]")
    feet: list[float] = Field(default_factory=list, description="(3,) [m] on the floor")
    hand: list[float] = Field(default_factory=list, description="(3,) [m] the grip reached")


class OperatorModel(_Model):
    operator: str
    zone: Zone
    passes: bool
    summary: str
    second_hand_s: float | None = Field(description="[m]")
    second_hand_forces: dict[str, list[float]] = Field(
        description="step -> the second hand's push (3,) [N], global frame")
    rating: RatingModel | None
    solves: int
    checks: list[CheckModel]
    access: dict[str, list[AccessModel]] = Field(
        default_factory=dict, description="grip -> the hand's access at each step "
        "(pliant.assembly.access)")
    reach: dict[str, list[ReachModel]] = Field(
        default_factory=dict, description="grip -> the worker's reach to it at each step "
        "(pliant.assembly.posture), where the scene has a [worker]")


class VerdictModel(_Model):
    passes: bool
    assemblable: bool
    operator: str | None
    headline: str
    reasons: list[str]
    decided: bool = Field(True, description="false: the answer rests on a fallback (a "
                          "part held rigid), and the verdict is UNDECIDED")


class EvaluationReport(_Model):
    """The JSON pliant writes for an evaluation (schema_version 1)."""

    schema_version: Literal[1]
    name: str
    part: str
    grips: list[str]
    verdict: VerdictModel
    steps_planned: int
    steps_solved: int
    stopped: str | None
    checks: list[CheckModel]
    operators: list[OperatorModel]
    table: list[dict[str, float | int | str | bool | None]]
    path: dict[str, Any] = Field(description="the path followed: pliant run's record")
    rules: str
    settings: dict[str, Any]
    units: dict[str, str]


def evaluation_json(evaluation: Any) -> str:
    """The evaluation as JSON text (non-finite numbers as null)."""
    return json.dumps(finite(evaluation.to_dict()), indent=1, allow_nan=False)


def write_json(evaluation: Any, path: str | Path) -> Path:
    text = evaluation_json(evaluation)
    return atomic_write(path, lambda h: h.write(text.encode()), "the evaluation (JSON)")


def write_csv(evaluation: Any, path: str | Path) -> Path:
    """A row per step: the grips' forces and moments and their parts, the bend radius,
    clearances and the rest of ``Evaluation.table``; units in the header."""
    rows = evaluation.table
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow([_with_unit(c) for c in columns])
    for row in rows:
        writer.writerow(["" if row.get(c) is None else row.get(c) for c in columns])
    data = text.getvalue().encode()
    return atomic_write(path, lambda h: h.write(data), "the evaluation (CSV)")


def _with_unit(column: str) -> str:
    unit = column_unit(column)
    return f"{column} [{unit}]" if unit else column


def column_unit(column: str) -> str:
    """The SI unit of a column of ``Evaluation.table`` ("" where it has none)."""
    last = column.rsplit(" ", 1)[-1]
    if last in ("Fx", "Fy", "Fz", "axial", "lateral") or column == "contact force":
        return "N"
    if last in ("Mx", "My", "Mz", "twist", "bending"):
        return "N m"
    if column.startswith(("bend", "clearance")):
        return "m"
    if column == "twist rate":
        return "deg/m"
    return ""


def schema() -> dict[str, Any]:
    """The JSON Schema of ``EvaluationReport``."""
    return EvaluationReport.model_json_schema()
