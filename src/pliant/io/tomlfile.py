"""TOML text in, with errors that name the file and the field: shared by every file
pliant reads (problems, scenes, rules)."""

from __future__ import annotations

import tomllib
from typing import Any

from pliant.errors import FileFormatError


def read_toml(text: str, source: str) -> dict[str, Any]:
    """The TOML document ``text``; invalid TOML is a ``FileFormatError`` naming
    ``source``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise FileFormatError(f"{source}: not valid TOML: {err}") from None
    except RecursionError:
        raise FileFormatError(f"{source}: not valid TOML for pliant: arrays or tables "
                              "nested too deeply") from None


def field_path(loc: tuple[Any, ...]) -> str:
    """A pydantic error location as the file's own path: ``condition[2].tangent``."""
    out = ""
    for item in loc:
        out += f"[{item}]" if isinstance(item, int) else (f".{item}" if out else str(item))
    return out or "(top level)"
