"""Writing a problem back as a problem file (TOML, SI units) that reads back as the
same problem, and splicing a [path] table into a scene file's text."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from pliant.core.problem import Problem
from pliant.errors import FileFormatError, OutputError
from pliant.io.tomlfile import read_toml


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
                "poisson_ratio", "axial_stiffness", "max_axial_strain", "max_temperature"):
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
            lines.append(f"moment = {_value(c.moment)}")
    for ld in problem.loads:  # each writes its own table's keys
        lines += ["", "[[load]]"]
        for key, value in ld.to_dict().items():
            if value is not None:
                lines.append(f"{key} = {_value(value)}")
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


def _value(value) -> str:
    """A number, a vector or a text as TOML."""
    if isinstance(value, str):
        return _toml(value)
    return _vec(value) if isinstance(value, tuple | list) else _num(value)


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
