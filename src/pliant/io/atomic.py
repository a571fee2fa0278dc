"""Atomic file writes: a result is written to a temporary file beside its target and
renamed over it, so a failure leaves any earlier file untouched and never a half-written
one."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from pliant.errors import OutputError


class Written:
    """The files this process has written whole, each once, in the order first written:
    what an interrupted command says it left (``pliant.cli.app.main`` empties it as a
    command starts), so that an incomplete set of outputs is marked. As many as the
    command writes (a study's voxels: one a sample, 100,000 at most)."""

    LISTED = 4  # a folder's files named one by one up to this many, else counted

    def __init__(self) -> None:
        self._paths: dict[Path, None] = {}

    def append(self, path: Path) -> None:
        self._paths[path] = None

    def clear(self) -> None:
        self._paths.clear()

    def __len__(self) -> int:
        return len(self._paths)

    def summary(self) -> str:
        """The files written, a folder that got more than ``LISTED`` of them as its
        count: "a.json, b.html, study/voxels/ (400 files)"."""
        folders: dict[Path, list[Path]] = {}
        for path in self._paths:
            folders.setdefault(path.parent, []).append(path)
        return ", ".join(
            f"{folder}{os.sep} ({len(paths)} files)" if len(paths) > self.LISTED
            else ", ".join(str(p) for p in paths) for folder, paths in folders.items())


WRITTEN = Written()


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
