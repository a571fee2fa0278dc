"""The demo's first run on a fresh machine, timed end to end (issue 19's 20 s).

    .venv/bin/python benchmarks/first_run.py [--runs N] [--against OTHER_CHECKOUT]
        [--solve PROBLEM_FILE]

``--solve examples/paper/case3.toml`` times ``pliant solve`` of that file instead (a 2D
problem's first run: the 2D model's kernels).

Each run empties what a fresh install has empty (a new ``NUMBA_CACHE_DIR`` and
``PLIANT_CACHE``: every kernel compiles, every scene structure is built) and times
``pliant demo`` from the process's start to its end, announcement, compile, solve and
report included. With ``--against``, the runs alternate with the same command on
another checkout (its ``src`` first on the path, this venv's packages): a machine whose
speed drifts from minute to minute is compared in the same minutes. Prints each run and
the median and range of each side.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The console script's entry, or main() in a checkout from before it existed.
CODE = ("import sys; from pliant.cli import app; sys.argv = ['pliant', *sys.argv[1:]]; "
        "(getattr(app, 'entry', None) or app.main)()")


def first_run(checkout: Path, solve: Path | None = None) -> float:
    """Seconds of one fresh ``pliant demo`` (or ``pliant solve`` of a file) with
    ``checkout``'s sources."""
    with tempfile.TemporaryDirectory() as folder:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(folder) / "numba"),
                   PLIANT_CACHE=str(Path(folder) / "cache"),
                   PYTHONPATH=str(checkout / "src"))
        job = (["demo", "--out", str(Path(folder) / "out")] if solve is None
               else ["solve", str(solve.resolve())])
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", CODE, *job], env=env, cwd=checkout,
                              capture_output=True, text=True)
        seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"pliant {job[0]} failed in {checkout}: {done.stderr[-2000:]}")
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--against", type=Path, help="another checkout, run alternately")
    parser.add_argument("--solve", type=Path, help="time pliant solve of this problem file")
    args = parser.parse_args()
    sides = {"this checkout": ROOT}
    if args.against is not None:
        sides[f"against {args.against}"] = args.against.resolve()
    times: dict[str, list[float]] = {name: [] for name in sides}
    for k in range(args.runs):
        for name, checkout in sides.items():
            times[name].append(first_run(checkout, args.solve))
            print(f"run {k + 1}, {name}: {times[name][-1]:.1f} s", flush=True)
    for name, values in times.items():
        print(f"{name}: median {statistics.median(values):.1f} s "
              f"({min(values):.1f}-{max(values):.1f} s, {len(values)} fresh first runs)")


if __name__ == "__main__":
    main()
