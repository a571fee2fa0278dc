"""What a variation study varies: tolerances on a scene file's fields, how they scatter,
how they are sampled, and how a sample changes the file.

A variation is written as a user would on the command line, ``NAME=TOL[UNIT][,normal]``:
``bending_stiffness=20%``, ``length=5mm``, ``"clip[0].position=2mm"``,
``"port[oil cooler].position=1.5mm,normal"``. The tolerance is +- TOL (uniform) or, with
``normal``, three standard deviations. A position varies in each of x, y and z. The
sample plan is a Latin hypercube or a scrambled Sobol sequence (scipy.stats.qmc) with a
seed, so a study is reproducible and can be resumed sample by sample.

A sample changes the scene's document (its TOML as dicts), which is then built like any
scene file: a longer part moves the conditions at its last end with it; a port that moves
takes the path's waypoints that end on it along.
"""

from __future__ import annotations

import copy
import math
import re
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from pliant.errors import InputError

PART_FIELDS = {
    "length": "length", "bending_stiffness": "stiffness", "bending_stiffness_2": "stiffness",
    "torsional_stiffness": "stiffness", "mass_per_length": "mass",
    "outer_diameter": "length", "inner_diameter": "length", "min_bend_radius": "length",
}
UNITS = {
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6},
    "stiffness": {"N m^2": 1.0, "Nm^2": 1.0, "Nm2": 1.0, "N*m^2": 1.0, "N m2": 1.0},
    "mass": {"kg/m": 1.0, "g/m": 1e-3},
}
SI = {"length": "m", "stiffness": "N m^2", "mass": "kg/m"}
TABLES = ("clip", "port", "obstacle", "condition")
_SPEC = re.compile(r"^\s*(?P<name>[^=]+?)\s*=\s*(?P<value>[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?)"
                   r"\s*(?P<unit>[^,]*?)\s*(,\s*(?P<dist>[A-Za-z]+))?\s*$")
_LOCATED = re.compile(r"^(?P<table>[a-z]+)\[(?P<key>[^\]]+)\]\.(?P<field>[a-z_]+)$")


@dataclass(frozen=True)
class Variation:
    """One varied field. name : as written; path : where in the document (("part",
    "length"), ("clip", 0, "position")); quantity : "length", "stiffness" or "mass";
    tolerance : +- in SI units, or a fraction of the nominal value when ``relative``;
    distribution : "uniform" (+- tolerance) or "normal" (tolerance = 3 sigma); vector :
    a position (x, y, z each varied)."""

    name: str
    path: tuple[Any, ...]
    quantity: str
    tolerance: float
    relative: bool
    distribution: str
    vector: bool

    @property
    def columns(self) -> list[str]:
        return [f"{self.name}.{a}" for a in "xyz"] if self.vector else [self.name]

    @property
    def unit(self) -> str:
        return "1" if self.relative else SI[self.quantity]

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "path": list(self.path), "quantity": self.quantity,
                "tolerance": self.tolerance, "relative": self.relative,
                "distribution": self.distribution, "vector": self.vector}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Variation:
        return cls(d["name"], tuple(d["path"]), d["quantity"], d["tolerance"], d["relative"],
                   d["distribution"], d["vector"])


def parse_variation(spec: str, data: dict[str, Any], index: int = 0) -> Variation:
    """A variation from ``NAME=TOL[UNIT][,normal]`` against the scene's document ``data``
    (to find the table rows it names); errors name the ``--vary`` argument and say what
    is known."""
    label = f"vary[{index}]"
    m = _SPEC.match(spec)
    if m is None:
        raise InputError(label, f"{spec!r}: write NAME=TOL with a unit, e.g. length=5mm, "
                         "bending_stiffness=20%, clip[0].position=2mm,normal")
    name, value, unit = m["name"].strip(), float(m["value"]), m["unit"].strip()
    dist = (m["dist"] or "uniform").lower()
    label = f"vary[{index}] ({name})"
    if dist not in ("uniform", "normal"):
        raise InputError(label, f"unknown distribution {dist!r}: uniform (+- TOL) or normal "
                         "(TOL = 3 sigma)")
    if not math.isfinite(value) or value <= 0.0:
        raise InputError(label, f"the tolerance must be a positive number, got {value!r}")
    path, quantity, vector = _locate(name, data, label)
    if not unit:
        units = ", ".join(["%", *UNITS[quantity]]) if not vector else ", ".join(UNITS[quantity])
        raise InputError(label, f"the tolerance {value:g} has no unit; give one of {units}")
    if unit == "%":
        if vector:
            raise InputError(label, "a position's tolerance is a length (mm, m), not %")
        if not value < 100.0:
            raise InputError(label, f"a tolerance of {value:g} % would take the value to zero "
                             "or below it; give less than 100 %")
        return Variation(name, path, quantity, value / 100.0, True, dist, vector)
    scale = UNITS[quantity].get(unit)
    if scale is None:
        known = ", ".join(([] if vector else ["%"]) + list(UNITS[quantity]))
        raise InputError(label, f"unit {unit!r} is not one for a {quantity}; give one of {known}")
    return Variation(name, path, quantity, value * scale, False, dist, vector)


def _locate(name: str, data: dict[str, Any], label: str) -> tuple[tuple[Any, ...], str, bool]:
    bare = name.removeprefix("part.")
    if bare in PART_FIELDS:
        return ("part", bare), PART_FIELDS[bare], False
    m = _LOCATED.match(name)
    if m is None:
        raise InputError(label, f"unknown parameter {name!r}; known: "
                         f"{', '.join(PART_FIELDS)}, clip[i].position, port[i].position, "
                         "obstacle[i].position, condition[i].x|y|z (i an index or a name)")
    table, key, field = m["table"], m["key"].strip(), m["field"]
    if table not in TABLES:
        raise InputError(label, f"unknown table {table!r}; known: {', '.join(TABLES)}")
    rows = data.get(table, [])
    if key.isdigit():
        i = int(key)
        if i >= len(rows):
            raise InputError(label, f"the scene has {len(rows)} [[{table}]] tables; "
                             f"{table}[{i}] is not one")
    else:
        names = [r.get("name") for r in rows]
        if key not in names:
            raise InputError(label, f"no [[{table}]] named {key!r}; known: "
                             f"{', '.join(str(n) for n in names) or 'none'}")
        i = names.index(key)
    if table == "condition":
        if field not in ("x", "y", "z"):
            raise InputError(label, "a condition varies by x, y or z")
        if field not in rows[i]:
            raise InputError(label, f"{table}[{i}] gives no {field}: nothing to vary")
        return (table, i, field), "length", False
    if field != "position":
        raise InputError(label, f"a [[{table}]] varies by its position")
    return (table, i, "position"), "length", True


MOST_SAMPLES = 100_000  # a study's samples at most (a day's work on 2 cores is 80,000)


def plan(variations: list[Variation], samples: int, method: str = "lhs",
         seed: int = 0) -> np.ndarray:
    """(samples, columns) deviations from nominal, in each column's unit (SI, or a
    fraction for relative ones): uniform in +- tolerance, or normal with the tolerance
    as 3 sigma, from a Latin hypercube or a scrambled Sobol sequence."""
    from scipy.stats import norm, qmc  # noqa: PLC0415

    if not 1 <= samples <= MOST_SAMPLES:
        raise InputError("samples", f"must be 1 to {MOST_SAMPLES:,} (each is an evaluation "
                         f"of about a second: split a larger study), got {samples:,}")
    if method not in ("lhs", "sobol"):
        raise InputError("method", f"must be lhs or sobol, got {method!r}")
    scales, normal = [], []
    for v in variations:
        k = 3 if v.vector else 1
        scales += [v.tolerance] * k
        normal += [v.distribution == "normal"] * k
    d = len(scales)
    if d == 0:
        raise InputError("vary", "give at least one --vary NAME=TOL")
    if method == "lhs":
        u = qmc.LatinHypercube(d, seed=seed).random(samples)
    else:
        with warnings.catch_warnings():  # a count that is not a power of 2 is still fine
            warnings.simplefilter("ignore", UserWarning)
            u = qmc.Sobol(d, scramble=True, seed=seed).random(samples)
    z = np.where(normal, norm.ppf(np.clip(u, 1e-12, 1 - 1e-12)) / 3.0, 2.0 * u - 1.0)
    return z * np.array(scales)


def nominal_values(variations: list[Variation], data: dict[str, Any],
                   part: Any) -> dict[str, Any]:
    """Each variation's nominal value: the document's, or the built part's where the
    file gives none (a bending stiffness from a material and a section)."""
    out: dict[str, Any] = {}
    for v in variations:
        value = _get(data, v.path)
        if value is None and v.path[0] == "part":
            value = getattr(part, v.path[1], None)
        if value is None and v.path[0] == "obstacle":
            value = [0.0, 0.0, 0.0]
        if value is None:
            raise InputError(f"vary ({v.name})", "the scene gives no value to vary")
        out[v.name] = list(map(float, value)) if v.vector else float(value)
        if not v.vector and v.relative and out[v.name] == 0.0:
            raise InputError(f"vary ({v.name})", "a relative tolerance of a zero value "
                             "varies nothing; give an absolute one")
    return out


def apply(data: dict[str, Any], variations: list[Variation], nominal: dict[str, Any],
          row: np.ndarray) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the document with ``row``'s deviations applied, each varied value by name)."""
    doc = copy.deepcopy(data)
    values: dict[str, Any] = {}
    k = 0
    for v in variations:
        base = nominal[v.name]
        if v.vector:
            delta: Any = row[k:k + 3]
            k += 3
            value = [float(b + d) for b, d in zip(base, delta)]
            if v.path[0] == "port":
                _move_waypoints(doc, base, value)
        else:
            delta = float(row[k])
            k += 1
            value = base * (1.0 + delta) if v.relative else base + delta
            if v.path == ("part", "length"):
                for c in doc.get("condition", []):
                    if abs(float(c.get("s", -1.0)) - base) <= 1e-9 * base:
                        c["s"] = value
        _set(doc, v.path, value)
        values[v.name] = value
    return doc, values


def _move_waypoints(doc: dict[str, Any], old: list[float], new: list[float]) -> None:
    """Waypoints that end on a port move with it (the path still seats the part)."""
    path = doc.get("path")
    if not path:
        return
    for w in path.get("waypoints", []):
        if all(abs(float(a) - b) <= 1e-9 for a, b in zip(w, old)):
            w[:] = new


def _get(data: dict[str, Any], path: tuple[Any, ...]) -> Any:
    node: Any = data
    for key in path:
        try:
            node = node[key]
        except (KeyError, IndexError, TypeError):
            return None
    return node


def _set(data: dict[str, Any], path: tuple[Any, ...], value: Any) -> None:
    node: Any = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
