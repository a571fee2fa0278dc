"""Record the signatures the 3D kernels are called with (``pliant.models.first_run``),
after changing a kernel's arguments: a developer's command, at the top layer because it
runs the main job::

    python -m pliant.cli.record_kernels
"""

from __future__ import annotations

import os
import pickle
import tempfile
from pathlib import Path
from typing import Any

from typer.testing import CliRunner

from pliant.cli.app import app
from pliant.models.first_run import OURS, SIGNATURES, THEIRS, dispatcher


def record(path: Path = SIGNATURES) -> dict[tuple[str, str], list[Any]]:
    """Run the main job (``pliant demo``, in a temporary folder, with an empty disk cache
    as on a fresh machine, so that the scene's fitted parts are solved too) and write the
    signatures its kernels were called with to ``path``."""
    with tempfile.TemporaryDirectory() as folder:
        os.environ["PLIANT_CACHE"] = str(Path(folder) / "cache")
        result = CliRunner().invoke(app, ["demo", "--out", folder])
    if result.exit_code != 0:
        raise RuntimeError(f"pliant demo failed: {result.output[-2000:]}")
    data = {(m, n): list(dispatcher(m, n).signatures) for m, n in OURS + THEIRS}
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(pickle.dumps(data, protocol=4))
    tmp.replace(path)
    return data


if __name__ == "__main__":
    for key, value in record().items():
        print(*key, len(value))
