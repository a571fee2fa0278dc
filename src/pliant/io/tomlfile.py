"""Text and TOML in, with errors that name the file and the field: shared by every file
pliant reads (problems, scenes, rules, sequences)."""

from __future__ import annotations

import tomllib
import unicodedata
from pathlib import Path
from typing import Any

from pliant.errors import FileFormatError

LARGEST_TEXT = 64 * 2**20  # bytes: a scene, rules or sequence file larger is no such file


def read_text(path: str | Path, what: str = "file") -> str:
    """A text file's text (UTF-8), or a one-line ``FileFormatError`` saying why not: no
    such file, not a regular file (a device such as /dev/zero, a folder), larger than
    ``LARGEST_TEXT``, not UTF-8, unreadable. Never reads without bound."""
    path = Path(path)
    try:
        if not path.is_file():
            if not path.exists():
                raise FileFormatError(f"{path}: no such {what}; check the path")
            raise FileFormatError(f"{path}: not a regular file (a folder or a device); give "
                                  f"the {what}'s path")
        with path.open("rb") as handle:
            data = handle.read(LARGEST_TEXT + 1)
    except OSError as err:
        raise FileFormatError(f"{path}: cannot be read: {err.strerror}") from None
    if len(data) > LARGEST_TEXT:
        raise FileFormatError(f"{path}: larger than {LARGEST_TEXT // 2**20} MiB: not a "
                              f"{what} pliant reads")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise FileFormatError(f"{path}: not a text file in UTF-8 (byte {err.start}); save "
                              "it as UTF-8 TOML") from None


def read_toml(text: str, source: str) -> dict[str, Any]:
    """The TOML document ``text``; invalid TOML is a ``FileFormatError`` naming
    ``source``."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise FileFormatError(f"{source}: not valid TOML: {err}") from None
    except RecursionError:
        raise FileFormatError(f"{source}: not valid TOML for pliant: arrays or tables "
                              "nested too deeply") from None
    _printable(doc, source, ())
    return doc


def _printable(value: Any, source: str, where: tuple[Any, ...]) -> None:
    """Refuse a string or key holding a control character (a terminal escape such as
    ESC [31m would reach the user's terminal raw through every name printed); tabs and
    line breaks are text."""
    if isinstance(value, str):
        bad = next((c for c in value if unicodedata.category(c) == "Cc"
                    and c not in "\t\n\r"), None)
        if bad is not None:
            raise FileFormatError(f"{source}: {field_path(where)}: holds the control "
                                  f"character U+{ord(bad):04X}; names and texts must be "
                                  "printable (remove it)")
    elif isinstance(value, dict):
        for key, item in value.items():
            _printable(key, source, (*where, "(a key)"))
            _printable(item, source, (*where, key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            _printable(item, source, (*where, k))


def field_path(loc: tuple[Any, ...]) -> str:
    """A pydantic error location as the file's own path: ``condition[2].tangent``."""
    out = ""
    for item in loc:
        out += f"[{item}]" if isinstance(item, int) else (f".{item}" if out else str(item))
    return out or "(top level)"
