"""The solvers' first compile, on two cores instead of one.

numba compiles a kernel when it is first called and keeps it (``cache=True``), so only a
fresh install pays. Compiled lazily, one kernel after the other in the one process, the
bundled scene's first ``pliant demo`` spent 24 of its 27 s compiling on one core. Here
every kernel a 3D scene needs, its callees included, is compiled ahead by the signatures
it is called with, split between this process and a helper process
(``python -m pliant.models.first_run``) that compile into the same cache; likewise the
2D model's kernels for a planar problem (``KINDS``).

The split is a schedule (``plan``): each kernel's own compile time and the kernels it
calls are recorded with its signatures (``SIGNATURES``, by ``python -m
pliant.cli.record_kernels``); the longest chain of callers goes first, and a kernel
starts once its callees are compiled, in either process (each process tells the other,
over a pipe, what it has finished), so that nothing is compiled twice: a callee the
other process cached is loaded, not compiled. Where the machine has one core, the cache
is warm, the recorded signatures are not those the code now uses, or the helper dies,
the kernels compile lazily or here instead: never wrong, at worst as slow as before.
``tests/test_first_run.py`` checks that after ``compile_ahead`` a scene's solve compiles
nothing.
"""

from __future__ import annotations

import importlib
import os
import pickle
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

SIGNATURES = Path(__file__).with_name("kernel_signatures.pkl")
# Each model's kernels: the 3D ones a scene needs (recorded from the demo) and the 2D
# ones a planar problem needs (from the paper's cases), each with the folder of the
# module that says whether they are cached.
KINDS = {"3d": (SIGNATURES, "rod3d"),
         "2d": (SIGNATURES.with_name("kernel_signatures_2d.pkl"), "elastica2d")}
HELPER_TIMEOUT = 300.0  # s: past this nothing waits for the other process any more

Key = tuple[str, str]  # (module, kernel)


def dispatcher(module: str, name: str) -> Any:
    return getattr(importlib.import_module(module), name)


def cold(kind: str = "3d") -> bool:
    """Whether the model's kernels (``KINDS``) are not cached yet (a fresh install, or a
    new ``NUMBA_CACHE_DIR``): numba keeps an index (.nbi) per kernel."""
    folder = KINDS[kind][1]
    source = Path(__file__).resolve().parent / folder
    cache, pattern = source / "__pycache__", "kernels.*.nbi"
    if os.environ.get("NUMBA_CACHE_DIR"):  # numba keeps a folder per source folder there
        cache, pattern = Path(os.environ["NUMBA_CACHE_DIR"]), f"{folder}_*/{pattern}"
    return not any(cache.glob(pattern))


def recorded(kind: str = "3d") -> dict[str, dict]:
    """The model's recorded kernels: {"signatures": {key: [signature]}, "cost": {key:
    seconds of its own compile}, "calls": {key: [keys it calls]}}; empty where the file
    cannot be read with this numba (then everything compiles lazily)."""
    try:
        with KINDS[kind][0].open("rb") as f:
            data = pickle.load(f)  # our own file, shipped with the package
    except Exception:  # another numba's types: compile lazily instead
        return {}
    if not isinstance(data, dict) or not isinstance(data.get("signatures"), dict):
        return {}
    return data


def plan(cost: dict[Key, float], calls: dict[Key, list[Key]],
         workers: int = 2) -> list[list[Key]]:
    """Each worker's kernels in order: list scheduling on ``workers`` processes. A kernel
    is ready once its callees are done; the worker free first takes, of those it can
    start at once, the one heading the longest chain of callers (else the one it waits
    least for). The list that ends first comes first: it is this process's, which then
    fills its wait for the helper's last kernels with the job's own work (``idle``:
    its imports, 0.9 s of the demo's; with the longest chain's end in this process it
    had none to wait). Deterministic: the helper computes the same plan from the same
    file."""
    keys = sorted(cost)
    callers: dict[Key, list[Key]] = {k: [] for k in keys}
    for k in keys:
        for c in calls.get(k, ()):
            if c in callers:
                callers[c].append(k)
    rank: dict[Key, float] = {}

    def chain(k: Key) -> float:  # its cost and the longest chain of callers after it
        if k not in rank:
            rank[k] = cost[k] + max((chain(c) for c in callers[k]), default=0.0)
        return rank[k]

    for k in keys:
        chain(k)
    finish: dict[Key, float] = {}
    free = [0.0] * workers
    lists: list[list[Key]] = [[] for _ in range(workers)]
    left = set(keys)
    while left:
        w = min(range(workers), key=lambda i: (free[i], i))
        ready = [k for k in left if all(c in finish or c not in cost for c in calls.get(k, ()))]
        ready = ready or list(left)  # (a cycle: recursion)

        # What can start at once, the longest chain first; else what waits least.
        at = {k: max([free[w], *(finish[c] for c in calls.get(k, ()) if c in finish)])
              for k in ready}
        k = min(ready, key=lambda k: (at[k], -rank[k], k))
        start = at[k]
        finish[k] = free[w] = start + cost[k]
        lists[w].append(k)
        left.remove(k)
    return sorted(lists, key=lambda keys: max((finish[k] for k in keys), default=0.0))


def compile_kernels(kernels: Iterable[Key], on_kernel: Callable[[str], None] | None = None,
                    signatures: dict[Key, list[Any]] | None = None,
                    before: Callable[[Key], None] | None = None,
                    after: Callable[[Key], None] | None = None) -> int:
    """Compile (or load from the cache) each kernel for its recorded signatures (read
    from ``SIGNATURES`` unless given); the number compiled or loaded. ``before(key)`` is
    called before each (to wait for its callees), ``after(key)`` once it is done. A
    signature numba refuses is skipped: the kernel then compiles lazily for the one it is
    called with."""
    signatures = recorded().get("signatures", {}) if signatures is None else signatures
    done = 0
    for key in kernels:
        if before is not None:
            before(key)
        if on_kernel is not None:
            on_kernel(key[1])
        for signature in signatures.get(key, ()):
            try:
                dispatcher(*key).compile(signature)
                done += 1
            except Exception:  # a stale signature: the kernel compiles lazily
                continue
        if after is not None:
            after(key)
    return done


class _Peer:
    """What the other process has finished, read from its pipe line by line (a key's
    index among the recorded kernels, sorted); all of it at once when the pipe ends (it
    died: waiting for it would be waiting forever, and compiling here is never wrong)."""

    def __init__(self, stream, data: dict) -> None:
        self.index = {k: i for i, k in enumerate(sorted(data["signatures"]))}
        self.done = [threading.Event() for _ in self.index]
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream) -> None:
        try:
            for line in stream:
                i = int(line)
                if 0 <= i < len(self.done):
                    self.done[i].set()
        except (ValueError, OSError):
            pass
        for event in self.done:
            event.set()

    def wait(self, keys: Iterable[Key], deadline: float,
             idle: list[Callable[[], object]] | None = None) -> None:
        """Until those keys are done, or the deadline (``time.monotonic``) has passed;
        while a key is not done yet, the ``idle`` work is done first, one piece at a
        time (each taken off the list)."""
        for k in keys:
            if k in self.index:
                event = self.done[self.index[k]]
                while idle and not event.is_set():
                    _quietly(idle.pop(0))
                event.wait(max(0.0, deadline - time.monotonic()))


def _quietly(work: Callable[[], object]) -> None:
    """Idle work is a head start on what comes after, never needed: whatever fails in
    it is done (or fails, and says so) again where it is needed."""
    try:
        work()
    except Exception:
        pass


def _schedule(data: dict, workers: int) -> list[list[Key]]:
    """``plan`` over the recorded kernels (a kernel recorded without its cost counts
    0.1 s)."""
    cost = data.get("cost", {})
    return plan({k: float(cost.get(k, 0.1)) for k in sorted(data["signatures"])},
                data.get("calls", {}), workers)


def _run(mine: list[Key], theirs: list[Key], data: dict, peer: _Peer, out,
         on_kernel: Callable[[str], None] | None = None,
         alive: Callable[[], bool] = lambda: True) -> None:
    """Compile this process's list, each kernel after its callees of the other list
    (waiting at most ``HELPER_TIMEOUT`` in all), telling ``out`` the index of each one
    done; it stops where ``alive()`` turns false."""
    calls = data.get("calls", {})
    index = peer.index
    other = set(theirs)
    deadline = time.monotonic() + HELPER_TIMEOUT

    def before(key: Key) -> None:
        peer.wait([c for c in calls.get(key, ()) if c in other], deadline)

    def after(key: Key) -> None:
        try:
            out.write(f"{index[key]}\n")
            out.flush()
        except (OSError, ValueError):  # the other process is gone
            pass

    for key in mine:
        if not alive():
            return
        compile_kernels([key], on_kernel, data["signatures"], before, after)


def estimate(kind: str = "3d", cores: int = 2) -> float:
    """About how long [s] the ahead compile takes on ``cores`` (the recording machine's
    seconds: the longer of the work's share and the longest chain of callees)."""
    data = recorded(kind)
    cost = data.get("cost", {})
    if not cost:
        return 0.0
    calls = data.get("calls", {})
    chain: dict[Key, float] = {}

    def longest(k: Key) -> float:
        if k not in chain:
            chain[k] = cost.get(k, 0.0) + max((longest(c) for c in calls.get(k, ())
                                                if c in cost), default=0.0)
        return chain[k]

    return max(sum(cost.values()) / max(1, min(cores, 2)),
               max(longest(k) for k in cost))


_SPAWNED: dict[str, subprocess.Popen] = {}  # helpers started ahead (``spawn``), by kind


def _start_helper(kind: str) -> subprocess.Popen | None:
    try:
        return subprocess.Popen(
            [sys.executable, "-m", "pliant.models.first_run", str(os.getpid()), kind],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
            text=True, bufsize=1)
    except OSError:
        return None


def spawn(kind: str = "3d") -> None:
    """Start ``compile_ahead``'s helper process now, before this process reads the
    recorded signatures (which imports numba): the helper's own start, a Python and
    numba import of about half a second, then overlaps this one's instead of delaying
    its half of the compile (its first kernel began 0.63 s after this process's first,
    and now 0.08-0.12 s after). Without numba here; nothing on a machine with one core."""
    if kind not in _SPAWNED and (os.cpu_count() or 1) >= 2:
        helper = _start_helper(kind)
        if helper is not None:
            _SPAWNED[kind] = helper


def compile_ahead(on_kernel: Callable[[str], None] | None = None,
                  cores: int | None = None, kind: str = "3d",
                  idle: Iterable[Callable[[], object]] = ()) -> bool:
    """Compile the model's kernels (``KINDS``: the 3D ones a scene needs, or the 2D ones
    a planar problem needs), by ``plan``, here and in a helper process where the machine
    has a second core (see the module); True when a helper ran. ``on_kernel(name)`` is
    told each kernel this process starts. ``idle`` is work the job does later anyway
    (importing its plotting libraries): done here in the time this process would
    otherwise wait for the helper's last kernels, so that it costs the first run
    nothing; what does not fit is left for later. (Not while waiting for a callee
    half way: the helper may soon need a kernel of this process's, and would wait.)"""
    work = list(idle)
    cores = (os.cpu_count() or 1) if cores is None else cores
    helper = _SPAWNED.pop(kind, None)  # (started ahead by ``spawn``)
    data = recorded(kind)
    if helper is not None and (not data or cores < 2):  # (no data for it, or not wanted)
        _let_go(helper, kill=True)
        helper = None
    if not data:
        return False
    if helper is None and cores >= 2:
        helper = _start_helper(kind)
    if helper is None:  # one process: the one-worker schedule, callees first
        compile_kernels(_schedule(data, 1)[0], on_kernel, data["signatures"])
        return False
    ours, theirs = _schedule(data, 2)
    peer = _Peer(helper.stdout, data)
    _run(ours, theirs, data, peer, helper.stdin, on_kernel)
    if on_kernel is not None:
        on_kernel("the helper's half")
    peer.wait(theirs, time.monotonic() + HELPER_TIMEOUT, work)
    try:
        helper.stdin.close()  # type: ignore[union-attr]
    except OSError:
        pass
    # Its kernels are all in the cache (each is written before it is signalled): the job
    # goes on while it exits (killed where it hung: past the timeout).
    _let_go(helper, kill=not all(peer.done[peer.index[k]].is_set() for k in theirs))
    return True


def _let_go(helper: subprocess.Popen, kill: bool) -> None:
    """Leave the helper to exit (killed first where ``kill``), reaped by a thread that
    then closes its pipes (left open, they are a resource leak Python warns of)."""
    if kill:
        helper.kill()
    threading.Thread(target=_reap, args=(helper,), daemon=True).start()


def _reap(helper: subprocess.Popen) -> None:
    helper.wait()
    for stream in (helper.stdin, helper.stdout):
        if stream is not None:
            try:
                stream.close()
            except OSError:
                pass


def _helper(parent: int, kind: str = "3d") -> None:
    """The helper's work: the plan's second list, told by the parent (stdin) what it has
    finished; it stops early if the parent is gone (nothing would wait for it)."""
    data = recorded(kind)
    if not data:
        return
    ours, theirs = _schedule(data, 2)
    _run(theirs, ours, data, _Peer(sys.stdin, data), sys.stdout,
         alive=lambda: os.getppid() == parent)
    sys.stdout.flush()
    # Everything is cached and said: leave without tearing the interpreter down (0.6 s
    # after a compile, which the parent used to wait for).
    os._exit(0)


if __name__ == "__main__":
    _helper(int(sys.argv[1]), sys.argv[2] if len(sys.argv) > 2 else "3d")
