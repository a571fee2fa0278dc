"""CAD assemblies as obstacles: STEP through cascadio (OpenCASCADE), and any scene format
trimesh reads (glTF, OBJ, ...), one named solid per instance of each product.

A STEP file declares its own length unit; OpenCASCADE converts it, and the solids come
out in metres. Formats without a unit (STL, OBJ, PLY) take the scene's ``units``. The
tessellation tolerance is the largest distance [m] between a curved face and its
triangles; the contact's accuracy is no better than it.
"""

from __future__ import annotations

import fnmatch
import functools
import re
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pliant.errors import FileFormatError, InputError
from pliant.util.interrupts import on_ctrl_c

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
    if step:
        solids = list(_read_step(path, tolerance * 1e3))  # OpenCASCADE works in mm
    else:
        try:
            scene = trimesh.load(path, force="scene")
        except Exception as err:  # trimesh raises many kinds on a bad file
            raise FileFormatError(
                f"{path}: not a CAD file pliant can read: {err}; export it again as STEP "
                "(AP203, AP214 or AP242), or as glTF") from None
        solids = [s if s.name != path.name else Solid(path.stem, s.vertices, s.faces)
                  for s in placed_solids(scene, scale)]  # a mesh file's one solid: its stem
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


def _read_step(path: Path, tolerance_mm: float) -> tuple[Solid, ...]:
    """A STEP file's placed solids, read by OpenCASCADE in a process of its own
    (``pliant.io.step_worker``): a crash there on a damaged file, or a Ctrl+C while it
    reads, ends that process, not pliant (the Ctrl+C then stops pliant cleanly). Kept
    per file, size, time and tolerance for this process's later scenes."""
    where = path.resolve()
    stat = where.stat()
    return _read_step_once(str(where), stat.st_size, stat.st_mtime_ns, tolerance_mm)


@functools.lru_cache(maxsize=8)
def _read_step_once(path: str, size: int, mtime: int, tolerance_mm: float
                    ) -> tuple[Solid, ...]:
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415

    with tempfile.TemporaryDirectory(prefix="pliant-step-") as folder:
        answer = Path(folder) / "solids.npz"
        # A session of its own: the terminal's Ctrl+C reaches pliant, which ends it.
        pressed: list[bool] = []  # Ctrl+C held: not between its start and ``process``
        with on_ctrl_c(lambda: pressed.append(True)):
            process = subprocess.Popen(
                [sys.executable, "-m", "pliant.io.step_worker", path, repr(tolerance_mm),
                 str(answer)], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT, start_new_session=True)
        try:
            if pressed:
                raise KeyboardInterrupt
            output, _ = process.communicate()
        except BaseException:  # Ctrl+C, or anything else: the reader goes with it
            process.kill()
            process.wait()
            raise
        lines = [re.sub(r"\x1b\[[0-9;]*m", "", line).strip()
                 for line in output.decode("utf-8", "replace").splitlines() if line.strip()]
        if process.returncode != 0:
            said = next((m for m in lines if "ERR" in m or "rror" in m), "")
            crash = (f"OpenCASCADE stopped on it (signal {-process.returncode})"
                     if process.returncode < 0 else "")
            why = "; ".join(x for x in (crash, said[:300]) if x)
            raise FileFormatError(
                f"{path}: not a CAD file pliant can read{' (' + why + ')' if why else ''}; "
                "export it again as STEP (AP203, AP214 or AP242), or as glTF")
        with np.load(answer) as data:
            names = [str(x) for x in data["names"]]
            solids = []
            for k, solid in enumerate(names):
                vertices, faces = data[f"v{k}"], data[f"f{k}"]
                vertices.setflags(write=False)
                faces.setflags(write=False)
                solids.append(Solid(solid, vertices, faces))
    return tuple(solids)


def placed_solids(scene, scale: float) -> list[Solid]:
    """A trimesh scene's meshes, each placed by its node's transform and scaled, named
    by its geometry (with #2, #3 ... for further instances)."""
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
