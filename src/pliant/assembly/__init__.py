"""Assembly and disassembly operations: a grip carried along a path through a scene,
step by step, with what the hand feels and what the part touches."""

from pliant.assembly.path import PathRun as PathRun
from pliant.assembly.path import StepRecord as StepRecord
from pliant.assembly.path import follow_path as follow_path


def __getattr__(name: str):
    """``load_scene``, ``parse_scene`` and ``scene_from_data`` (``assembly.scenes``),
    imported on first use: the file schema they read costs 0.17 s to import, which a
    script that only follows a path need not pay."""
    if name in ("load_scene", "parse_scene", "scene_from_data"):
        from pliant.assembly import scenes  # noqa: PLC0415

        return getattr(scenes, name)
    raise AttributeError(f"module 'pliant.assembly' has no attribute {name!r}")
