"""Record what the first run compiles ahead (``pliant.models.first_run``), after changing
a kernel's arguments: a developer's command, at the top layer because it runs the main
job::

    python -m pliant.cli.record_kernels       # the 3D kernels, from pliant demo
    python -m pliant.cli.record_kernels 2d    # the 2D ones, from the paper's cases

It runs the job in a child process on a fresh machine's terms (empty numba and disk
caches, nothing compiled ahead), so that every kernel compiles in that process as it is
first called, and records for each of pliant's kernels the signatures it was called
with, its own compile time (without its callees') and the kernels it calls.
"""

from __future__ import annotations

import collections
import os
import pickle
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from pliant.models.first_run import KINDS, Key


def record(kind: str = "3d") -> dict[str, Any]:
    """Run the child (see the module) on the model's job and write what it found to its
    file (``first_run.KINDS``)."""
    path = KINDS[kind][0]
    with tempfile.TemporaryDirectory() as folder:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(folder) / "numba"),
                   PLIANT_CACHE=str(Path(folder) / "cache"))
        out = Path(folder) / "kernels.pkl"
        done = subprocess.run([sys.executable, "-m", "pliant.cli.record_kernels", "--child",
                               str(out), folder, kind], env=env, capture_output=True,
                              text=True)
        if done.returncode != 0:
            raise RuntimeError(f"the recording failed: {done.stderr[-2000:]}")
        data = pickle.loads(out.read_bytes())  # our own child's file
    tmp = path.with_suffix(".tmp")
    tmp.write_bytes(pickle.dumps(data, protocol=4))
    tmp.replace(path)
    return data


# The 2D job: the paper's three cases (force space, a follower load, a held tip that
# buckles: shooting, continuation and the stability check), and case 3's equilibria
# (``--all``: the energy's minima and the damped Newton from them, which its cold solve
# no longer needs since stop 51, nor records).
PAPER = Path(__file__).resolve().parents[3] / "examples" / "paper"


def _child(out: Path, folder: str, kind: str) -> None:
    from numba.core import event  # noqa: PLC0415 (the child only)
    from numba.core.registry import CPUDispatcher  # noqa: PLC0415
    from typer.testing import CliRunner  # noqa: PLC0415

    from pliant.cli.app import app  # noqa: PLC0415
    from pliant.models import first_run  # noqa: PLC0415

    own: collections.Counter[Key] = collections.Counter()
    stack: list[list] = []

    class Timer(event.Listener):
        """Each compile's time less the nested compiles of pliant's kernels (numba's
        own overloads count as their caller's)."""

        def on_start(self, ev) -> None:
            stack.append([ev.data["dispatcher"].py_func, time.perf_counter(), 0.0])

        def on_end(self, ev) -> None:
            func, t0, nested = stack.pop()
            spent = time.perf_counter() - t0
            if func.__module__.startswith("pliant"):
                own[(func.__module__, func.__name__)] += spent - nested
                if stack:
                    stack[-1][2] += spent

    event.register("numba:compile", Timer())
    first_run.compile_ahead = lambda *a, **k: False  # everything lazily, in this process
    # and no helper started ahead: it would compile its half of the last recording into
    # the same cache, and this process would load those kernels instead of compiling
    # them (recorded with no cost and no callees: the plan then runs them too early).
    first_run.spawn = lambda *a, **k: None
    jobs = ([["demo", "--out", folder]] if kind == "3d" else
            [["solve", str(PAPER / f"case{i}.toml")] for i in (1, 2, 3)]
            + [["solve", str(PAPER / "case3.toml"), "--all"]])
    for job in jobs:
        result = CliRunner().invoke(app, job)
        if result.exit_code != 0:
            raise SystemExit(f"pliant {job[0]} failed: {result.output[-2000:]}")
    kernels: dict[Key, Any] = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("pliant"):
            continue
        for attr, value in vars(module).items():
            if (isinstance(value, CPUDispatcher) and value.py_func.__module__ == name
                    and value.signatures):
                kernels[(name, attr)] = value
    library = {id(o.library): key for key, d in kernels.items() for o in d.overloads.values()}
    calls = {key: sorted({library[id(lib)] for o in d.overloads.values()
                          for lib in getattr(o.library, "_linking_libraries", ())
                          if id(lib) in library and library[id(lib)] != key})
             for key, d in kernels.items()}
    data = {"signatures": {k: list(d.signatures) for k, d in kernels.items()},
            "cost": {k: round(own[k], 3) for k in kernels}, "calls": calls}
    out.write_bytes(pickle.dumps(data, protocol=4))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--child"]:
        _child(Path(sys.argv[2]), sys.argv[3], sys.argv[4])
    else:
        found = record(sys.argv[1] if len(sys.argv) > 1 else "3d")
        for key in sorted(found["signatures"]):
            print(*key, len(found["signatures"][key]), found["cost"][key],
                  [c[1] for c in found["calls"][key]])
