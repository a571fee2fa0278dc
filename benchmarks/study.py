"""A variation study's throughput on Dask, measured in one run.

The bundled engine bay's operation (100 steps at 80 elements) with its stiffness, length
and the cooler port's position varied: samples a second at 1 and 2 local workers (the
scaling efficiency), the overhead per sample against the evaluation's own time (the
study's wall time times its workers, less the samples' own seconds, per sample), and
what 1,000 samples would take on this machine.

    .venv/bin/python benchmarks/study.py [SAMPLES] [WORKERS ...]

(workers 1 and 2 by default; `benchmarks/study.py 1000 2` runs the issue's 1,000 samples
on two workers only, about nine minutes.)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from pliant.assembly.study import study

SCENE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "engine_bay.toml"
VARY = ["bending_stiffness=20%", "length=5mm", "port[oil cooler].position=2mm"]


def run(samples: int, workers: int) -> tuple[float, float, int]:
    """(wall seconds, the samples' own seconds, samples evaluated)."""
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        result = study(SCENE, VARY, samples, out=Path(folder) / "s", workers=workers, seed=1)
        wall = time.perf_counter() - start
    return wall, sum(r["seconds"] for r in result.records), len(result.ok)


def main(samples: int, counts: tuple[int, ...] = (1, 2)) -> None:
    run(2, 0)  # load the kernels in this process
    print(f"engine bay, {samples} samples, varying {', '.join(VARY)}:")
    rates = {}
    for workers in counts:
        wall, own, ok = run(samples, workers)
        rates[workers] = samples / wall
        overhead = (wall * workers - own) / samples
        print(f"  {workers} worker{'s' if workers > 1 else ''}: {wall:.1f} s, "
              f"{rates[workers]:.2f} samples/s, {own / samples:.2f} s a sample's evaluation, "
              f"overhead {overhead:.2f} s a sample ({overhead / (own / samples):.0%}; the "
              f"cluster's start and each worker's first load of the kernels included), "
              f"{ok} evaluated")
    if 1 in rates and 2 in rates:
        print(f"  scaling efficiency at 2 workers: {rates[2] / (2 * rates[1]):.0%}")
    if 2 in rates:
        print(f"  1,000 samples at 2 workers: about {1000 / rates[2] / 60:.1f} minutes")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 16,
         tuple(int(a) for a in sys.argv[2:]) or (1, 2))
