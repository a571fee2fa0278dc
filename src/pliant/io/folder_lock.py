"""One writer at a time in an output folder (a study's, a sequence search's): a second
run on the same folder would compute every item again beside the first and interleave
their lines. The lock is an advisory ``flock`` on the folder's ``.pliant.lock`` (POSIX),
released when the run ends or its process dies (the kernel drops it), so a crash never
leaves the folder locked; the file keeps the holder's process id, for the message."""

from __future__ import annotations

import os
from pathlib import Path
from types import TracebackType
from typing import IO

from pliant.errors import InputError

LOCK_NAME = ".pliant.lock"


class FolderLock:
    """``with FolderLock(folder, "study"):`` holds ``folder`` for this run, or raises
    ``InputError`` (field ``out``) naming the folder and the process that holds it."""

    def __init__(self, folder: str | Path, what: str) -> None:
        self.folder = Path(folder)
        self.what = what
        self._handle: IO[str] | None = None

    def acquire(self) -> FolderLock:
        import fcntl  # noqa: PLC0415 (POSIX only: imported where a lock is taken)

        self.folder.mkdir(parents=True, exist_ok=True)
        handle = open(self.folder / LOCK_NAME, "a+")  # held until release
        try:
            fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            handle.seek(0)
            holder = handle.read().strip() or "unknown"
            handle.close()
            raise InputError("out", f"{self.folder} is in use by another {self.what} "
                             f"(process {holder}): wait for it to end, or give another "
                             "folder") from None
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        self._handle = handle
        return self

    def release(self) -> None:
        if self._handle is not None:
            import fcntl  # noqa: PLC0415

            fcntl.flock(self._handle.fileno(), fcntl.LOCK_UN)
            self._handle.close()
            self._handle = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 trace: TracebackType | None) -> None:
        self.release()
