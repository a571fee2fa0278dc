"""The first run's compile on two cores (``pliant.models.first_run``): after the
ahead-of-time compile, split by its schedule with a helper process, the main job compiles
nothing (so the recorded signatures are those the kernels are called with, and the two
lists cover them); the schedule keeps each kernel after its callees; an unreadable
signature file leaves the kernels to compile lazily."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pliant.models import first_run

SCRIPT = """
import json, sys
from typer.testing import CliRunner
from pliant.cli.app import app
from numba.core import event
from pliant.models import clock, first_run
kind, job = sys.argv[2], sys.argv[3:]
cold = first_run.cold(kind)
first_run.spawn(kind)  # as the CLI does: the helper started before the signatures are read
helped = first_run.compile_ahead(cores=2, kind=kind)
ahead = clock.compiling()
late = []  # the kernels the job compiles itself, named in the failure
class Names(event.Listener):
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func; late.append(f"{f.__module__}.{f.__qualname__}")
    def on_end(self, ev):
        pass
event.register("numba:compile", Names())
codes = [CliRunner().invoke(app, j.split(",")).exit_code for j in job]
print(json.dumps({"cold": cold, "helped": helped, "ahead": ahead, "exit": max(codes),
                  "compiled": clock.compiling() - ahead, "late": late,
                  "cold_after": first_run.cold(kind)}))
"""
PAPER = Path(__file__).resolve().parents[1] / "examples" / "paper"


@pytest.mark.parametrize("kind", ["2d"])
def test_after_the_compile_ahead_the_main_job_compiles_nothing(tmp_path, kind):
    """2D: the paper's three cases, in an empty cache (a fresh machine). 3D, the demo:
    in ``test_wheel.py``, where a fresh install's first run is real (one cold compile of
    the 3D kernels in the suite, not two)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"),
               PLIANT_CACHE=str(tmp_path / "cache"))
    jobs = ([f"demo,--out,{tmp_path / 'out'}"] if kind == "3d" else
            [f"solve,{PAPER / f'case{i}.toml'}" for i in (1, 2, 3)])
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "out"), kind, *jobs],
                          env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    facts = json.loads(done.stdout.strip().splitlines()[-1])
    assert facts["cold"] and facts["helped"] and facts["exit"] == 0
    assert facts["ahead"] > 0.0  # this process compiled its half
    # nothing left for the job: all from the cache
    assert facts["compiled"] == 0.0, f"the job compiled {facts['late']}"
    assert not facts["cold_after"]
    # each kernel of both halves has its cache index, the helper's included
    cached = {p.name.split(".")[1].rsplit("-", 1)[0] for p in (tmp_path / "numba").rglob("*.nbi")}
    assert {name for _, name in first_run.recorded(kind)["signatures"]} <= cached


@pytest.mark.parametrize("kind", ["3d", "2d"])
def test_the_schedule_compiles_each_kernel_after_its_callees_and_balances_the_work(kind):
    data = first_run.recorded(kind)
    cost, calls = data["cost"], data["calls"]
    lists = first_run.plan(cost, calls)
    assert sorted(lists[0] + lists[1]) == sorted(cost)  # each kernel once
    # Replay it: a kernel starts once its callees are done, wherever they were done.
    finish: dict = {}
    clock = [0.0, 0.0]
    at = [0, 0]
    while at[0] < len(lists[0]) or at[1] < len(lists[1]):
        moved = False
        for w in (0, 1):
            if at[w] < len(lists[w]):
                k = lists[w][at[w]]
                if all(c in finish for c in calls[k] if c in cost):
                    clock[w] = max([clock[w], *(finish[c] for c in calls[k])]) + cost[k]
                    finish[k] = clock[w]
                    at[w] += 1
                    moved = True
        assert moved, "the two lists wait for each other"
    # Within a tenth of the bound: an even split of the work, or the longest chain of
    # callees (which no schedule can shorten).
    chain: dict = {}

    def longest(k):
        if k not in chain:
            chain[k] = cost[k] + max((longest(c) for c in calls[k] if c in cost), default=0.0)
        return chain[k]

    bound = max(sum(cost.values()) / 2, max(longest(k) for k in cost))
    assert max(clock) <= 1.1 * bound
    # This process's list (the first) ends first: it waits for the helper's last
    # kernels, and fills the wait with the job's own imports.
    assert clock[0] <= clock[1]
    assert first_run.estimate(kind) == pytest.approx(bound)  # what the CLI announces


def test_an_unreadable_signature_file_leaves_the_kernels_to_compile_lazily(tmp_path,
                                                                            monkeypatch):
    bad = tmp_path / "kernel_signatures.pkl"
    bad.write_bytes(b"not a pickle")
    monkeypatch.setitem(first_run.KINDS, "3d", (bad, "rod3d"))
    assert first_run.recorded() == {}
    assert first_run.compile_kernels([("pliant.models.banded", "band_lu")]) == 0
    assert first_run.compile_ahead(cores=1) is False


def test_a_helper_started_ahead_is_taken_once_and_ended_where_it_is_not_wanted(tmp_path,
                                                                              monkeypatch):
    """``spawn`` starts the helper once (a second call keeps the first); ``compile_ahead``
    takes it instead of starting another, and ends it where it cannot use it (here: no
    signatures to read), so that no process is left behind."""
    started = []

    def start(kind):
        proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        started.append(proc)
        return proc

    monkeypatch.setattr("pliant.models.first_run._start_helper", start)
    monkeypatch.setattr(first_run.os, "cpu_count", lambda: 2)
    bad = tmp_path / "kernel_signatures.pkl"
    bad.write_bytes(b"not a pickle")
    monkeypatch.setitem(first_run.KINDS, "3d", (bad, "rod3d"))
    first_run.spawn("3d")
    first_run.spawn("3d")
    assert len(started) == 1
    assert first_run.compile_ahead(cores=2) is False
    assert len(started) == 1  # taken, not started again
    assert started[0].wait(timeout=30) != 0  # killed: it would have slept a minute
    for stream in (started[0].stdin, started[0].stdout):
        stream.close()
