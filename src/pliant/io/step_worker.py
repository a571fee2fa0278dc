"""One STEP file read in a process of its own (``pliant.io.cad``): OpenCASCADE can crash
on a damaged file, and a Ctrl+C inside it crashed pliant with it; here either ends only
this process, and pliant says so.

    python -m pliant.io.step_worker FILE TOLERANCE_MM ANSWER.npz

Writes the placed solids (names, vertices [m], faces) to ANSWER.npz; what OpenCASCADE
prints is this process's output. Exit status 3 with one line naming the error where
the file cannot be read."""

from __future__ import annotations

import sys

import numpy as np


def main(argv: list[str] | None = None) -> int:
    path, tolerance, answer = argv if argv is not None else sys.argv[1:]
    import trimesh  # noqa: PLC0415 (and cascadio, through it)

    from pliant.io.cad import placed_solids  # noqa: PLC0415

    try:
        scene = trimesh.load(path, file_type="step", tol_linear=float(tolerance))
        solids = placed_solids(scene, 1.0)
    except Exception as err:  # trimesh and cascadio raise many kinds on a bad file
        print(f"ERROR: {type(err).__name__}: {err}", flush=True)
        return 3
    arrays: dict[str, np.ndarray] = {"names": np.array([s.name for s in solids], dtype=str)}
    for k, s in enumerate(solids):
        arrays[f"v{k}"], arrays[f"f{k}"] = s.vertices, s.faces
    np.savez(answer, **arrays)  # type: ignore[arg-type]
    return 0


if __name__ == "__main__":
    sys.exit(main())
