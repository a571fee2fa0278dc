"""Stiffness test files: a problem file plus ``[identify]`` and ``[[measured]]`` tables.

```toml
[identify]
unknowns = ["bending_stiffness"]     # any of bending_stiffness, bending_stiffness_2,
                                     # torsional_stiffness, mass_per_length
[[measured]]
kind = "shape"                       # shape, deflection, three_point_bending, twist,
                                     # twist_buckling
points = "loop_shape.csv"            # columns x, y[, z], each header with its unit
uncertainty = 0.5e-3                 # one standard deviation, SI (m here)
```

Measured tables are CSV files whose header names each column with its unit, ``x [mm]``
or ``load (N)``: the unit is the file's edge, everything past it is SI. A column without
a unit is refused, as a guessed millimetre would scale the answer by a thousand.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, ValidationError

from pliant.core.measurement import (
    Deflection,
    Shape,
    StiffnessTest,
    ThreePointBending,
    Twist,
    TwistBuckling,
)
from pliant.errors import FileFormatError, InputError, PliantError
from pliant.io.problem_file import SolverModel, _Strict, read_text, scene_from_data
from pliant.io.tomlfile import field_path, read_toml

# Units a CSV header may give, by quantity: the factor to SI.
UNITS = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "in": 0.0254},
    "force": {"N": 1.0, "kN": 1e3, "mN": 1e-3, "lbf": 4.4482216152605},
    "moment": {"N m": 1.0, "N*m": 1.0, "N.m": 1.0, "Nm": 1.0, "N mm": 1e-3, "Nmm": 1e-3,
               "N cm": 1e-2, "mN m": 1e-3},
    "angle": {"rad": 1.0, "deg": math.pi / 180.0, "°": math.pi / 180.0},
}
COLUMNS = {  # kind -> (column, quantity, required)
    "shape": (("x", "length", True), ("y", "length", True), ("z", "length", False)),
    "deflection": (("load", "force", True), ("x", "length", False), ("y", "length", False),
                   ("z", "length", False)),
    "three_point_bending": (("displacement", "length", True), ("load", "force", True)),
    "twist": (("angle", "angle", True), ("moment", "moment", True)),
}
_HEADER = re.compile(r"^\s*([A-Za-z_][A-Za-z_0-9 ]*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")


class IdentifyModel(_Strict):
    """[identify]: what is unknown, and at which confidence."""

    unknowns: list[str] = Field(min_length=1)
    confidence: float = Field(0.95, ge=0.5, lt=1.0)
    source: str = Field("", description="where the test comes from (lab, report)")


class MeasuredModel(_Strict):
    """[[measured]]: one measurement (see docs/guide.md, "Stiffness from a test")."""

    kind: Literal["shape", "deflection", "three_point_bending", "twist", "twist_buckling"]
    name: str = ""
    points: str | list[list[float]] | None = Field(
        None, description="a CSV file, or rows [[x, y(, z)], ...] in m (shape)")
    data: str | None = Field(None, description="a CSV file (deflection, bending, twist)")
    uncertainty: float | None = Field(None, gt=0, description="one standard deviation, SI")
    condition: str | None = Field(None, description="the loaded condition (deflection)")
    direction: list[float] | None = Field(None, description="the load's direction")
    s: float | None = Field(None, ge=0, description="the measured station [m]")
    relative: bool = Field(False, description="deflection: the table gives displacements "
                           "from the unloaded pose (a gauge zeroed before loading)")
    span: float | None = Field(None, gt=0, description="between the supports [m]")
    length: float | None = Field(None, gt=0, description="between the chucks [m]")
    angle: float | None = Field(None, gt=0, description="the critical turn [rad] "
                                "(twist_buckling)")
    source: str = ""


def read_table(path: Path, kind: str, label: str) -> dict[str, np.ndarray]:
    """A measured CSV table's columns in SI units, by name; errors name the file, the
    row and the column."""
    text = read_text(path)
    return parse_table(text, kind, f"{path}", label)


def parse_table(text: str, kind: str, source: str, label: str = "") -> dict[str, np.ndarray]:
    """The columns of CSV ``text`` for a measurement of ``kind`` (see ``COLUMNS``)."""
    rows = [r for r in csv.reader(io.StringIO(text)) if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise FileFormatError(f"{source}: empty; give a header (e.g. x [mm], y [mm]) and rows")
    wanted = {name: (quantity, required) for name, quantity, required in COLUMNS[kind]}
    columns: dict[str, tuple[int, float]] = {}
    for i, cell in enumerate(rows[0]):
        match = _HEADER.match(cell)
        bare = cell.strip().lower()
        if match is None:
            if bare in wanted:
                quantity = wanted[bare][0]
                raise FileFormatError(
                    f"{source}: column {cell.strip()!r} gives no unit; write the header as "
                    f"'{bare} [{next(iter(UNITS[quantity]))}]' (or "
                    f"{', '.join(u for u in UNITS[quantity] if u != next(iter(UNITS[quantity])))})")
            raise FileFormatError(f"{source}: header cell {cell.strip()!r} is not 'name [unit]'"
                                  f"; {kind} takes {', '.join(wanted)}")
        name, unit = match.group(1).strip().lower(), match.group(2).strip()
        if name not in wanted:
            raise FileFormatError(f"{source}: column {name!r} is not one a {kind} takes ("
                                  f"{', '.join(wanted)})")
        units = UNITS[wanted[name][0]]
        factor = units.get(unit) or units.get(unit.replace("·", " "))
        if factor is None:
            raise FileFormatError(f"{source}: column {name!r} in {unit!r}: not a unit of "
                                  f"{wanted[name][0]}; use one of {', '.join(units)}")
        if name in columns:
            raise FileFormatError(f"{source}: column {name!r} is given twice")
        columns[name] = (i, factor)
    for name, (_quantity, required) in wanted.items():
        if required and name not in columns:
            raise FileFormatError(f"{source}: no column {name!r}; a {kind} needs "
                                  + ", ".join(n for n, (_, r) in wanted.items() if r))
    if len(rows) < 2:
        raise FileFormatError(f"{source}: a header and no rows")
    out = {name: np.empty(len(rows) - 1) for name in columns}
    for r, row in enumerate(rows[1:], start=2):
        for name, (i, factor) in columns.items():
            cell = row[i].strip() if i < len(row) else ""
            if cell == "" and kind == "deflection" and name != "load":
                out[name][r - 2] = math.nan  # a coordinate not measured in this row
                continue
            try:
                value = float(cell)
            except ValueError:
                raise FileFormatError(f"{source}: row {r}, column {name!r}: {cell!r} is not "
                                      "a number") from None
            if not math.isfinite(value):
                raise FileFormatError(f"{source}: row {r}, column {name!r}: {cell!r} is not "
                                      "a finite number")
            out[name][r - 2] = value * factor
    return out


def _data(m: MeasuredModel, key: str, base: Path | None, label: str) -> dict[str, np.ndarray]:
    value = getattr(m, key)
    if value is None:
        raise InputError(f"{label}.{key}", f"a {m.kind} needs {key} = \"file.csv\"")
    if isinstance(value, list):
        rows = np.array(value, dtype=float)
        if rows.ndim != 2 or rows.shape[1] not in (2, 3):
            raise InputError(f"{label}.{key}", "give rows [x, y] or [x, y, z] in m")
        return dict(zip("xyz", rows.T))
    path = Path(value) if base is None else base / value
    return read_table(path, m.kind, label)


def _build(m: MeasuredModel, index: int, problem, base: Path | None):
    label = f"measured[{index}]"
    name = m.name or f"{m.kind.replace('_', ' ')} {index + 1}"
    dim = problem.dimension
    if m.relative and m.kind != "deflection":
        raise InputError(f"{label}.relative", "only a deflection's table gives displacements "
                         "from the unloaded pose; remove relative")
    if m.kind == "shape":
        cols = _data(m, "points", base, label)
        if dim == 3 and "z" not in cols:
            raise InputError(f"{label}.points", "a 3D test's shape needs x, y and z")
        if dim == 2 and "z" in cols:
            raise InputError(f"{label}.points", "a 2D test's shape has x and y only")
        points = np.column_stack([cols[k] for k in "xyz"[:dim]])
        return Shape(points, m.uncertainty, name)
    if m.kind == "deflection":
        if m.condition is None:
            raise InputError(f"{label}.condition", "name the [[condition]] whose load the "
                             "table's load column gives")
        try:
            c = problem.condition(m.condition)
        except KeyError:
            raise InputError(f"{label}.condition", f"no condition named {m.condition!r}; "
                             "known: " + ", ".join(x.name for x in problem.conditions)) from None
        cols = _data(m, "data", base, label)
        if m.direction is not None:
            direction = np.array(m.direction, dtype=float)
        else:
            given = np.array([f or 0.0 for f in c.force] or [0.0] * dim, dtype=float)
            if not np.any(given):
                raise InputError(f"{label}.direction", f"{m.condition!r} applies no force to "
                                 "take the direction from; give direction = [...]")
            direction = given
        norm = float(np.linalg.norm(direction))
        if len(direction) != dim or not norm > 0 or not math.isfinite(norm):
            raise InputError(f"{label}.direction", f"give a non-zero direction with {dim} "
                             "components")
        measured = [k for k in "xyz"[:dim] if k in cols]
        if not measured:
            raise InputError(f"{label}.data", "give at least one measured coordinate column "
                             "(x, y" + (", z" if dim == 3 else "") + ")")
        if dim == 2 and "z" in cols:
            raise InputError(f"{label}.data", "a 2D test measures x and y only")
        rows = len(cols["load"])
        position = np.column_stack([cols.get(k, np.full(rows, math.nan)) for k in "xyz"[:dim]])
        return Deflection(m.condition, direction / norm, c.s if m.s is None else m.s,
                          cols["load"], position, m.uncertainty, name, relative=m.relative)
    if m.kind == "three_point_bending":
        if m.span is None:
            raise InputError(f"{label}.span", "give the distance between the supports [m]")
        cols = _data(m, "data", base, label)
        return ThreePointBending(m.span, cols["displacement"], cols["load"], m.uncertainty,
                                 name)
    if m.kind == "twist_buckling":
        if m.condition is None or m.angle is None:
            raise InputError(label, "a twist_buckling names the turned clamp (condition) and "
                             "the angle [rad] at which the part buckled")
        return TwistBuckling(m.condition, m.angle, m.uncertainty, name)
    cols = _data(m, "data", base, label)
    return Twist(m.length or problem.part.length, cols["angle"], cols["moment"],
                 m.uncertainty, name)


def load_test(path: str | Path) -> tuple[StiffnessTest, SolverModel]:
    """Read a stiffness test file (TOML, SI units; tables in CSV with their units)."""
    path = Path(path)
    return parse_test(read_text(path), str(path), path.parent)


def parse_test(text: str, source: str = "<string>",
               base: Path | None = None) -> tuple[StiffnessTest, SolverModel]:
    """A ``StiffnessTest`` from the TOML text of a test file; errors name the source."""
    data = read_toml(text, source)
    identify = data.pop("identify", None)
    measured = data.pop("measured", None)
    if identify is None:
        raise FileFormatError(f"{source}: no [identify] table; say which parameters are "
                              "unknown: [identify] unknowns = [\"bending_stiffness\"]")
    if not measured:
        raise FileFormatError(f"{source}: no [[measured]] table; give what the test measured")
    settings = _validated(IdentifyModel, identify, "identify", source)
    if not isinstance(measured, list):
        raise FileFormatError(f"{source}: measured: write [[measured]] (a list of tables)")
    tables = [_validated(MeasuredModel, m, f"measured[{i}]", source)
              for i, m in enumerate(measured)]
    scene = scene_from_data(data, source, base)
    try:
        measured_nouns = tuple(_build(m, i, scene.problem, base) for i, m in enumerate(tables))
        test = StiffnessTest(scene.problem, tuple(settings.unknowns), measured_nouns,
                             settings.confidence, scene.problem.name or Path(source).stem,
                             tuple(s for s in [settings.source, *(m.source for m in tables)]
                                   if s))
    except FileFormatError:
        raise
    except PliantError as err:
        raise FileFormatError(f"{source}: {err}") from None
    return test, scene.solver


def _validated(model, data, table: str, source: str):
    """``data`` validated as ``model``; the first error names the table and the key."""
    try:
        return model.model_validate(data)
    except ValidationError as err:
        first = next((e for e in err.errors() if e["type"] == "extra_forbidden"),
                     err.errors()[0])
        where = field_path(tuple(first["loc"]))
        msg = first["msg"].removeprefix("Value error, ")
        if first["type"] == "extra_forbidden":
            msg = f"unknown key; [{table}] takes {', '.join(sorted(model.model_fields))}"
        raise FileFormatError(f"{source}: {table}: {where}: {msg}") from None
