"""CAD assemblies as obstacles: STEP through cascadio (OpenCASCADE), and any scene format
trimesh reads (glTF, OBJ, ...), one named solid per instance of each product.

A STEP file declares its own length unit; OpenCASCADE converts it, and the solids come
out in metres. Formats without a unit (STL, OBJ, PLY) take the scene's ``units``. The
tessellation tolerance is the largest distance [m] between a curved face and its
triangles; the contact's accuracy is no better than it.
"""

from __future__ import annotations

import contextlib
import fnmatch
import os
import re
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pliant.errors import FileFormatError, InputError

UNITS = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "in": 0.0254, "inch": 0.0254, "ft": 0.3048}
STEP_SUFFIXES = (".step", ".stp")
TOLERANCE = 1e-4  # m: the default chord error of the tessellation (0.1 mm)


@dataclass(frozen=True, eq=False)
class Solid:
    """One solid of an assembly, placed, in metres: its name (the product's, with _1,
    _2 ... for its further instances) and its triangles."""

    name: str
    vertices: np.ndarray  # (v, 3) [m]
    faces: np.ndarray  # (f, 3) int

    @property
    def bounds(self) -> np.ndarray:
        return np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)])


def unit_scale(units: str, field: str = "units") -> float:
    """Metres per unit of a CAD file's lengths."""
    key = units.strip().lower()
    if key not in UNITS:
        raise InputError(field, f"unknown unit {units!r}; give one of "
                         f"{', '.join(sorted(UNITS))}")
    return UNITS[key]


@contextlib.contextmanager
def _captured_output() -> Iterator[list[str]]:
    """OpenCASCADE writes its messages to the process's stdout and stderr: keep them out
    of the user's terminal, and hand them back (to explain a failure)."""
    lines: list[str] = []
    with tempfile.TemporaryFile(mode="w+b") as sink:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace")
            lines.extend(re.sub(r"\x1b\[[0-9;]*m", "", line).strip()
                         for line in text.splitlines() if line.strip())


def read_assembly(path: Path, *, units: str | None = None, tolerance: float = TOLERANCE,
                  keep: Sequence[str] = (), drop: Sequence[str] = ()) -> list[Solid]:
    """The solids of a CAD file, placed and in metres, filtered by name patterns (``keep``:
    only those matching one, when given; ``drop``: not those; shell-style, case-blind).

    Raises FileFormatError naming the file when it cannot be read or holds no solid, and
    InputError when the patterns leave nothing or a unit is wrong.
    """
    import trimesh  # noqa: PLC0415 (heavy; only scenes that import CAD)

    path = Path(path)
    if not path.is_file():
        raise FileFormatError(f"{path}: no such CAD file (paths are relative to the scene "
                              "file)")
    step = path.suffix.lower() in STEP_SUFFIXES
    if step and units is not None:
        raise InputError("units", f"{path.name} is a STEP file: it declares its own unit, "
                         "which is used; leave units out")
    scale = 1.0 if step or path.suffix.lower() in (".gltf", ".glb") else unit_scale(
        units or "m")
    if not tolerance > 0.0:
        raise InputError("tolerance", f"must be a positive length in m, got {tolerance!r}")
    # OpenCASCADE works in mm.
    options: dict[str, Any] = {"tol_linear": tolerance * 1e3} if step else {}
    messages: list[str] = []
    try:
        if step:
            with _captured_output() as messages:
                scene = trimesh.load(path, file_type="step", **options)
        else:
            scene = trimesh.load(path, force="scene")
    except Exception as err:  # trimesh and cascadio raise many kinds on a bad file
        said = next((m for m in messages if "ERR" in m or "rror" in m), "")
        raise FileFormatError(
            f"{path}: not a CAD file pliant can read"
            f"{' (' + said + ')' if said else ''}"
            f"{'' if step else f': {err}'}; export it again as STEP (AP203, AP214 or "
            "AP242), or as glTF") from None
    solids = [s if s.name != path.name else Solid(path.stem, s.vertices, s.faces)
              for s in _solids(scene, scale)]  # a mesh file's one solid: its file's stem
    if not solids:
        raise FileFormatError(f"{path}: holds no solid with triangles")
    chosen = [s for s in solids if _wanted(s.name, keep, drop)]
    if not chosen:
        raise InputError("keep", f"no solid of {path.name} matches keep = {list(keep)} "
                         f"without matching drop = {list(drop)}; its solids: "
                         f"{', '.join(s.name for s in solids[:20])}"
                         f"{' ...' if len(solids) > 20 else ''}")
    return chosen


def _wanted(name: str, keep: Sequence[str], drop: Sequence[str]) -> bool:
    lower = name.lower()
    if keep and not any(fnmatch.fnmatchcase(lower, k.lower()) for k in keep):
        return False
    return not any(fnmatch.fnmatchcase(lower, d.lower()) for d in drop)


def _solids(scene, scale: float) -> list[Solid]:
    import trimesh  # noqa: PLC0415

    if isinstance(scene, trimesh.Trimesh):
        scene = trimesh.Scene(scene)
    out: list[Solid] = []
    seen: dict[str, int] = {}
    for node in scene.graph.nodes_geometry:
        transform, key = scene.graph[node]
        mesh = scene.geometry.get(key)
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        vertices = (np.asarray(mesh.vertices, float) @ transform[:3, :3].T
                    + transform[:3, 3]) * scale
        name = str(key)
        count = seen.get(name, 0)
        seen[name] = count + 1
        if count:
            name = f"{name}#{count + 1}"
        out.append(Solid(name, vertices, np.asarray(mesh.faces, dtype=np.int64)))
    return out
