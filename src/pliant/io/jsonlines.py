"""A file of JSON lines that long work appends a result to as each arrives (a study's
samples, a sequence's operations): each line written whole and flushed to disk, and a
last line cut short by an interruption dropped on reading, so that the work resumes
with only what is missing."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from pliant.io.atomic import WRITTEN
from pliant.io.jsontext import finite


class JsonLines:
    """``path``: the file (created on the first ``append``)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def drop_torn(self) -> None:
        """Cut off a last line without its newline (an interruption mid-write), so that
        the next line starts on its own."""
        if not self.path.exists():
            return
        with open(self.path, "rb+") as handle:
            text = handle.read()
            if text and not text.endswith(b"\n"):
                handle.truncate(text.rfind(b"\n") + 1)

    def append(self, record: dict[str, Any]) -> None:
        """Write ``record`` as one line (non-finite numbers as null) and flush it."""
        line = json.dumps(finite(record), allow_nan=False) + "\n"
        with open(self.path, "a", encoding="utf-8") as handle:
            handle.write(line)
            handle.flush()
            os.fsync(handle.fileno())
        WRITTEN.append(self.path)  # (once: a store a resumed run goes on with)

    def read(self) -> list[dict[str, Any]]:
        """Every complete line's record, in the file's order (a torn one left out)."""
        if not self.path.exists():
            return []
        out = []
        for line in self.path.read_text(encoding="utf-8").splitlines():
            try:
                out.append(json.loads(line))
            except json.JSONDecodeError:
                continue
        return out
