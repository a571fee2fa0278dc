"""Atomic file writes: a result is written to a temporary file beside its target and
renamed over it, so a failure leaves any earlier file untouched and never a half-written
one."""

from __future__ import annotations

import os
import tempfile
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from pliant.errors import OutputError

# The files this process has written whole, latest last (the last 64: a server that
# writes for hours keeps no more): what an interrupted command says it left
# (``pliant.cli.app.main`` empties it as a command starts), so that an incomplete set
# of outputs is marked.
WRITTEN: deque[Path] = deque(maxlen=64)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, write: Callable[[BinaryIO], object], what: str) -> Path:
    """Call ``write`` with a binary file and move it to ``path`` when it succeeds;
    ``what`` names the result in errors ("the plot", "the mesh")."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=path.suffix, dir=path.parent, prefix=f".{path.stem}-")
    except OSError as err:
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from None
    try:
        with os.fdopen(fd, "wb") as handle:
            write(handle)
        # mkstemp makes the file 0600; a result is for colleagues too: the usual mode.
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except OSError as err:
        raise OutputError(f"cannot write {what} {path}: {err.strerror or err}") from None
    finally:
        Path(tmp).unlink(missing_ok=True)
    WRITTEN.append(path)
    return path
