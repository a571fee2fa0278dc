"""pliant's disk cache: results that cost seconds and depend only on the bytes they were
made from (a mesh file's parse, a mesh's display decimation, distance structures), kept
under the hash of those bytes, so that a changed input is simply a new key. Written
whole or not at all (a temporary file, then a rename); a cache that cannot be read or
written only costs time."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np


def cache_dir() -> Path:
    """Where the cache is kept: $PLIANT_CACHE, else ~/.cache/pliant."""
    root = os.environ.get("PLIANT_CACHE")
    return Path(root) if root else Path.home() / ".cache" / "pliant"


def digest(*parts: bytes) -> str:
    """The key of some bytes (32 hex digits of their SHA-256)."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part)
    return h.hexdigest()[:32]


def load_arrays(kind: str, key: str) -> dict[str, np.ndarray] | None:
    """The arrays kept under ``kind/key``, or None (absent or unreadable)."""
    path = cache_dir() / kind / f"{key}.npz"
    try:
        with np.load(path) as data:
            return {name: np.ascontiguousarray(data[name]) for name in data.files}
    except (OSError, ValueError, KeyError):
        return None


def save_arrays(kind: str, key: str, **arrays: np.ndarray) -> None:
    """Keep ``arrays`` under ``kind/key`` (best effort, whole or not at all)."""
    path = cache_dir() / kind / f"{key}.npz"
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, **arrays)  # type: ignore[arg-type]  # numpy's stub: names as flags
        os.replace(tmp, path)
    except OSError:
        discard(tmp)  # a full disk leaves no half-written file behind


def discard(path: Path) -> None:
    """Remove a temporary file that could not be finished, if it is there."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass
