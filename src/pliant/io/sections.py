"""The problem file's building blocks that every section shares: the strict pydantic
base (unknown keys refused, booleans not taken for numbers) and the meshes a section
names, read from paths relative to its file."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from pliant.core.rules import ObstacleRule
from pliant.util import cache, progress

Vec3 = tuple[float, float, float]


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
        if _has_control(value):
            raise ValueError("a control character (an escape sequence) stands in this "
                             "text: pliant prints names and notes to terminals and "
                             "reports; remove it")
        return value


def _has_bool(value: Any) -> bool:
    if isinstance(value, bool):
        return True
    if isinstance(value, (list, tuple)):
        return any(_has_bool(v) for v in value)
    return False


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


class PackagingFields(_Strict):
    """What a packaging engineer says of an obstacle (``[[obstacle]]``, or every solid of
    a ``[[cad]]``): its own margin and its packaging rule (``ObstacleRule``)."""

    margin: float | None = Field(None, ge=0, description="the clearance wanted round it "
                                 "[m] (default: the scene's)")
    temperature: float | None = Field(None, gt=-273.15, description="its surface "
                                      "temperature [degC] (an exhaust, a turbo)")
    shielded: bool = Field(False, description="a heat shield or blanket covers it")
    moving: bool = Field(False, description="it moves (a fan, a pulley, a shaft)")
    edge: bool = Field(False, description="a sharp edge the part must not rest on")

    @property
    def rule(self) -> ObstacleRule:
        """Its packaging rule (``pliant.core.rules.ObstacleRule``)."""
        return ObstacleRule(self.margin, self.temperature, self.shielded, self.moving,
                            self.edge)


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


def _has_control(value: Any) -> bool:
    """Whether a text (or a list of texts) holds a control character other than a tab or
    a line break (ANSI escapes would reach a terminal raw)."""
    if isinstance(value, str):
        return any((ord(ch) < 32 and ch not in "\t\n\r") or ord(ch) == 127 for ch in value)
    if isinstance(value, list):
        return any(_has_control(v) for v in value)
    return False
