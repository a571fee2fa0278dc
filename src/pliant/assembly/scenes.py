"""Loading a scene: its file read by ``pliant.io`` (which only reads), and its flexible
parts already fitted settled here: each one's own problem solved alone (the 3D model),
its shape kept in pliant's disk cache (``pliant.util.cache``) under the hash of its
problem, its element count and the solver's source, so that a scene read again does
not solve it again (its equilibrium is then found on first use, by a part that touches
it), and its tube made an obstacle. Load scenes through these functions.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

from pliant.assembly.path import carry
from pliant.core.problem import FittedPart, Problem
from pliant.errors import FileFormatError, OutputError, PliantError
from pliant.io import problem_file as files
from pliant.io.problem_file import Scene
from pliant.util import cache


def settle_fitted(name: str, problem: Problem, elements: int, flexible: bool,
                  friction: float) -> Any:
    """The obstacle of a flexible part already fitted (``[[assembled]]``): its tube
    along its equilibrium alone (from the disk cache where kept), with its friction;
    a flexible one carries its ``FittedPart`` (a part that touches it deforms it)."""
    from pliant.core.tube import tube_mesh  # noqa: PLC0415 (the solver, on demand)
    from pliant.models import rod3d  # noqa: PLC0415
    from pliant.scene.distance import Obstacle  # noqa: PLC0415

    key = _fitted_key(problem, elements)
    kept = cache.load_arrays("fitted", key) if key else None
    eq = None
    if kept is not None and kept.keys() >= {"position", "frames"}:
        position, frames = kept["position"], kept["frames"]
    else:
        eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=elements))
        position, frames = eq.position, eq.frames
        if key:
            cache.save_arrays("fitted", key, position=position, frames=frames)
    vertices, faces = tube_mesh(position, problem.part.drawn_radius, frames, sides=16,
                                caps=True)
    obstacle = Obstacle.from_mesh(name, vertices, faces).with_friction(friction)
    if flexible:
        obstacle = replace(obstacle, fitted=FittedPart(name, problem, elements, solved=eq,
                                                       friction=friction, line=position))
    return obstacle


def load_scene(path: str | Path) -> Scene:
    """Read a problem or scene file (TOML, SI units): obstacles, ports, clips, and its
    flexible parts already fitted, settled, and its [path]'s steps."""
    return _with_path(files.load_scene(path, settle=settle_fitted), str(path))


def parse_scene(text: str, source: str = "<string>", base: Path | None = None) -> Scene:
    """A ``Scene`` from TOML text (mesh files relative to ``base``), settled."""
    return _with_path(files.parse_scene(text, source, base, settle=settle_fitted), source)


def scene_from_data(data: dict[str, Any], source: str = "<data>",
                    base: Path | None = None) -> Scene:
    """A ``Scene`` from a scene file's document already read (what a variation study
    changes sample by sample), settled."""
    return _with_path(files.scene_from_data(data, source, base, settle=settle_fitted),
                      source)


def _with_path(scene: Scene, source: str) -> Scene:
    """The scene with its [path]'s steps (``pliant.assembly.path.carry``); a path that
    cannot be carried is the file's error, named as io names its own."""
    if scene.path_spec is None:
        return scene
    try:
        return replace(scene, path=carry(scene.problem, scene.path_spec))
    except PliantError as err:
        raise FileFormatError(f"{source}: {err}") from None


def _fitted_key(problem: Problem, elements: int) -> str | None:
    """The cache key of a fitted part's shape: its problem as pliant writes it, its
    element count and the source of the code that solves it (a changed solver is a new
    key); None where the problem cannot be written (a mesh obstacle of its own)."""
    try:
        text = files.dump_problem(problem)
    except OutputError:
        return None
    return cache.digest(text.encode(), str(elements).encode(), _solver_source())


@lru_cache(maxsize=1)
def _solver_source() -> bytes:
    """The hash of the modules an equilibrium of a 3D part depends on."""
    root = Path(__file__).resolve().parents[1]
    folders = (root / "core", root / "models", root / "models" / "rod3d", root / "scene")
    files_ = sorted(f for folder in folders for f in folder.glob("*.py"))
    return cache.digest(*(f.read_bytes() for f in files_)).encode()
