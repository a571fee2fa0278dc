"""The accurate side of a session: warm-started solves, their picklable results, and the
executors that run them inline (deterministic) or in a worker process (live: the frame
loop never waits for them).

A worker process, not a thread: the accurate models spend their time in numba kernels
and Python loops that hold the GIL, so a thread would stall the frame loop for as long
as each of them runs; a process runs beside it on another core, and only the problem
and a summary of the answer cross the pipe.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Final

import numpy as np

from pliant.core.equilibrium import Equilibrium3D, StationLoad
from pliant.core.problem import Problem
from pliant.errors import PliantError
from pliant.scene.interference import fitted_tubes


@dataclass(frozen=True)
class AccurateResult:
    """An accurate equilibrium as a session publishes it (real forces, SI units).

    index : the event whose pose it answers; problem : that pose; s (N,) [m] and
    position (N, 2 or 3) [m] along the part; loads : by condition name, the real force
    [N] and moment [N m] each applies to the part (reactions where prescribed);
    curvature (N,) [1/m] and bending_moment (N,) [N m] (its magnitude; twist excluded)
    along s; contacts : where obstacles push the part (3D; ``Contacts``);
    min_bend_radius : (radius [m], s [m]); tangent (N, 3) and torque (N,) [N m], the
    unit tangent and the twisting moment along s (3D); residual, iterations, notes, stable,
    smallest_eigenvalue [N m] (3D, conservative loads), solve_seconds; error : why there
    is no equilibrium (then the arrays are empty and the session keeps the last good
    one).
    """

    index: int
    problem: Problem | None  # None on the way back from the worker (the session has it)
    s: np.ndarray
    position: np.ndarray
    loads: dict[str, StationLoad]
    residual: float = math.nan
    iterations: int = 0
    notes: tuple[str, ...] = ()
    stable: bool | None = None
    smallest_eigenvalue: float | None = None
    solve_seconds: float = 0.0
    error: str | None = None
    curvature: np.ndarray = field(default_factory=lambda: np.zeros(0))
    bending_moment: np.ndarray = field(default_factory=lambda: np.zeros(0))
    contacts: Any = None
    min_bend_radius: tuple[float, float] = (math.inf, 0.0)
    tangent: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    torque: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # The flexible parts already fitted, by name: (neutral line (m, 3) [m], outer radius
    # [m], the overlap [m] their contact allows), deformed where this pose touches them.
    fitted: dict[str, tuple[np.ndarray, float, float]] = field(default_factory=dict)
    # A harness's branches, by name: (neutral line (m, 3) [m], outer radius [m]).
    branches: dict[str, tuple[np.ndarray, float]] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.error is None

    @property
    def reactions(self) -> dict[str, StationLoad]:
        """The loads of the conditions that prescribe something (what a hand, a
        support or a robot must give)."""
        return {k: v for k, v in self.loads.items() if any(v.prescribed)}


@dataclass(frozen=True)
class Option:
    """One equilibrium of a pose that pliant's routes reached (``EquilibriaFound``):
    its shape (s (N,) [m], position (N, 2 or 3) [m]), its potential energy and elastic
    energy [J] (``pliant.core.equilibrium.potential_energy``), its stability verdict
    (stable, neutral, unstable or unknown) and smallest eigenvalue [N m], which way it
    bows (``bow_side``), its largest bending moment [N m] and how it was reached."""

    s: np.ndarray
    position: np.ndarray
    potential_energy: float
    energy: float
    verdict: str
    smallest_eigenvalue: float | None
    bows: str
    max_moment: float
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class EquilibriaFound:
    """The equilibria of the pose of event ``index`` (``pliant.models.dispatch.
    equilibria``), best first: stable and neutral ones by potential energy, then the
    unstable ones. ``error`` where the search itself failed; an empty list with no
    error means no route reached one."""

    index: int
    options: tuple[Option, ...]
    seconds: float = 0.0
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.error is None


SOLVE: Final = "solve"  # what a request asks of the accurate side (``AccurateSolver.run``)
FIND: Final = "find"  # (FIND, budget [s]): the pose's equilibria
CHOOSE: Final = "choose"  # (CHOOSE, k): the k-th equilibrium found becomes the answer
Request = str | tuple[str, float] | tuple[str, int]


@dataclass
class AccurateSolver:
    """Solves each pose warm-started from the last equilibrium (falling back to a cold
    solve when the warm start cannot be followed), keeping that equilibrium; lists a
    pose's equilibria and makes the one the user picks the answer (and the next warm
    start)."""

    elements: int | None = None
    last: Any = None
    found: list = field(default_factory=list)  # the equilibria of the last search
    _solver: Any = field(default=None, init=False, repr=False)

    def run(self, index: int, problem: Problem,
            what: Request = SOLVE) -> AccurateResult | EquilibriaFound:
        """Do what the request asks (``SOLVE``, ``(FIND, budget)``, ``(CHOOSE, k)``)."""
        if isinstance(what, str):
            if what == SOLVE:
                return self.solve(index, problem)
            raise ValueError(f"unknown request {what!r}")
        kind, value = what
        if kind == FIND:
            return self.find(index, problem, float(value))
        if kind == CHOOSE:
            return self.choose(index, problem, int(value))
        raise ValueError(f"unknown request {what!r}")

    def find(self, index: int, problem: Problem, budget: float) -> EquilibriaFound:
        """The pose's equilibria within ``budget`` seconds, kept for ``choose``."""
        from pliant.core.equilibrium import bow_side, potential_energy  # noqa: PLC0415
        from pliant.models import dispatch  # noqa: PLC0415

        start = time.perf_counter()
        self.found = []
        try:
            found = dispatch.equilibria(problem, elements=self.elements, budget=budget)
        except PliantError as err:
            return EquilibriaFound(index, (), time.perf_counter() - start, error=str(err))
        self.found = found
        options = tuple(Option(
            s=np.array(eq.s), position=np.array(eq.position),
            potential_energy=float(potential_energy(eq)), energy=float(eq.energy),
            verdict=str(eq.verdict), smallest_eigenvalue=eq.stability[1],
            bows=bow_side(eq), max_moment=float(eq.max_moment()[0]),
            notes=tuple(str(n) for n in eq.notes)) for eq in found)
        return EquilibriaFound(index, options, time.perf_counter() - start)

    def choose(self, index: int, problem: Problem, k: int) -> AccurateResult:
        """The k-th equilibrium of the last search as the answer, and the next solve's
        warm start (so the session follows that branch as the grips move)."""
        start = time.perf_counter()
        if not 0 <= k < len(self.found):
            return AccurateResult(index, problem, np.zeros(0),
                                  np.zeros((0, problem.dimension)), {},
                                  error=f"option: no equilibrium number {k + 1} was found "
                                  f"({len(self.found)} were); look for them again")
        self.last = self.found[k]
        return self._result(index, problem, self.found[k], start)

    def solve(self, index: int, problem: Problem) -> AccurateResult:
        from pliant.models import dispatch  # noqa: PLC0415 (the heavy models, on demand)

        start = time.perf_counter()
        solver = None
        if problem.dimension == 3 and self.elements:
            from pliant.models.rod3d import RodSolver  # noqa: PLC0415

            solver = RodSolver(elements=self.elements)
        try:
            try:
                eq = dispatch.solve(problem, warm_start=self.last, solver=solver)
            except PliantError:
                if self.last is None:
                    raise
                eq = dispatch.solve(problem, solver=solver)
        except PliantError as err:
            return AccurateResult(index, problem, np.zeros(0), np.zeros((0, problem.dimension)),
                                  {}, error=str(err),
                                  solve_seconds=time.perf_counter() - start)
        self.last = eq
        return self._result(index, problem, eq, start)

    def _result(self, index: int, problem: Problem, eq: Any, start: float) -> AccurateResult:
        stable, smallest = eq.stability
        three: dict[str, Any] = {  # what only the 3D model has
            "tangent": np.array(eq.tangent), "torque": np.array(eq.torque),
            "fitted": fitted_tubes(eq, problem.obstacles),
            "branches": {b.problem.name: (np.array(b.position), b.problem.part.tube_radius)
                         for b in eq.branches}} if isinstance(eq, Equilibrium3D) else {}
        return AccurateResult(index=index, problem=problem, s=np.array(eq.s),
                              position=np.array(eq.position), loads=dict(eq.loads),
                              residual=float(eq.residual), iterations=int(eq.iterations),
                              notes=tuple(eq.notes), stable=stable,
                              smallest_eigenvalue=smallest,
                              solve_seconds=time.perf_counter() - start,
                              curvature=np.abs(np.asarray(eq.curvature, float)),
                              bending_moment=eq.bending_magnitude,
                              contacts=eq.contacts if isinstance(eq, Equilibrium3D) else None,
                              min_bend_radius=eq.min_bend_radius(),
                              **three)


class InlineExecutor:
    """Runs each solve at once, in the caller: deterministic (replays, tests)."""

    def __init__(self, elements: int | None = None) -> None:
        self.solver = AccurateSolver(elements=elements)
        self._done: AccurateResult | EquilibriaFound | None = None

    @property
    def busy(self) -> bool:
        return False

    @property
    def answered(self) -> bool:
        """An answer waits to be taken in (by ``poll``)."""
        return self._done is not None

    def submit(self, index: int, problem: Problem, what: Request = SOLVE) -> None:
        self._done = self.solver.run(index, problem, what)

    def poll(self) -> AccurateResult | EquilibriaFound | None:
        done, self._done = self._done, None
        return done

    def wait(self, timeout: float | None = None) -> AccurateResult | EquilibriaFound | None:
        return self.poll()

    def close(self) -> None:
        pass


STOPPED_GRACE = 3.0  # s a worker may stay stopped mid-solve before it is replaced


def stopped(pid: int) -> bool:
    """Whether a process is stopped (SIGSTOP, Ctrl+Z, a debugger: state T or t in
    /proc); where there is no /proc, never."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            stat = f.read()
    except OSError:
        return False
    return stat.rsplit(")", 1)[-1].split()[:1] in (["T"], ["t"])


class ProcessExecutor:
    """Runs solves in one worker process (``python -m pliant.session.worker``), one at a
    time; ``poll`` never waits. Messages are length-prefixed pickles over the worker's
    stdin and stdout; a reader thread (blocked in I/O, so it holds no lock the frame loop
    needs) queues the answers. A plain subprocess rather than multiprocessing: a user's
    script needs no ``if __name__ == "__main__"`` guard, on any platform. A worker that
    dies, or stays stopped mid-solve for ``STOPPED_GRACE`` (a watchdog thread looks
    twice a second), is replaced and the request in flight sent to the new one once."""

    def __init__(self, elements: int | None = None) -> None:
        import queue  # noqa: PLC0415
        import threading  # noqa: PLC0415

        self.elements = elements
        self._answers: queue.Queue = queue.Queue()
        self._busy = False
        self._submitted: tuple[int, Problem, Request] | None = None
        self._sent: tuple = ()  # the obstacles the worker holds
        self.restarts = 0  # workers started again after one died
        self._retried = False  # the request in flight was sent again to a new worker
        # Called (from the reader thread) as each answer arrives, so that a server can
        # push it to its page at once instead of polling; it must not block.
        self.on_answer: Callable[[], None] | None = None
        self.stopped_replaced = 0  # workers killed for staying stopped mid-solve
        self._closing = threading.Event()
        self._start()
        threading.Thread(target=self._watch, daemon=True, name="pliant-accurate-watch").start()

    def _watch(self) -> None:
        """Kill a worker that stays stopped while it has a request (its reader then sees
        its pipe end, and ``_take`` starts another and sends the request again)."""
        since: tuple[Any, float] | None = None
        while not self._closing.wait(0.5):
            process = self._process
            if not (self._busy and stopped(process.pid)):
                since = None
                continue
            if since is None or since[0] is not process:
                since = (process, time.monotonic())
            elif time.monotonic() - since[1] >= STOPPED_GRACE:
                self.stopped_replaced += 1
                process.kill()
                since = None

    def _start(self) -> None:
        """A worker process and the thread that reads its answers."""
        import subprocess  # noqa: PLC0415
        import sys  # noqa: PLC0415
        import threading  # noqa: PLC0415

        self._process = subprocess.Popen(
            [sys.executable, "-m", "pliant.session.worker", str(self.elements or 0)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        self._sent = ()
        self._reader = threading.Thread(target=self._read,
                                        args=(self._process, self._answers, self._notify),
                                        daemon=True, name="pliant-accurate-reader")
        self._reader.start()

    @staticmethod
    def _read(process, answers, notify) -> None:
        stream = process.stdout
        while True:
            message = read_message(stream)
            answers.put((process, message))
            notify()
            if message is None:
                return

    def _notify(self) -> None:
        """Tell the listener an answer is queued; a listener that fails (its event loop
        closed, say) must not stop the reader."""
        listener = self.on_answer
        if listener is None:
            return
        try:
            listener()
        except Exception:  # whatever the listener's trouble, keep reading
            pass

    @property
    def busy(self) -> bool:
        return self._busy

    @property
    def answered(self) -> bool:
        """The worker's answer waits to be taken in (by ``poll``)."""
        return not self._answers.empty()

    @property
    def pid(self) -> int:
        """The worker process's id (tests, and a user looking at ``top``)."""
        return self._process.pid

    def submit(self, index: int, problem: Problem, what: Request = SOLVE) -> None:
        self._submitted = (index, problem, what)
        self._retried = False
        self._send(index, problem, what)
        self._busy = True

    def _send(self, index: int, problem: Problem, what: Request = SOLVE) -> None:
        # The obstacles go to the worker once (a CAD scene's are hundreds of megabytes):
        # while they are the same objects, a request carries the problem without them.
        same = bool(problem.obstacles) and len(problem.obstacles) == len(self._sent) and all(
            a is b for a, b in zip(problem.obstacles, self._sent))
        try:
            write_message(self._process.stdin, (index, replace(problem, obstacles=())
                                                if same else problem, same, what))
            self._sent = problem.obstacles
        except (OSError, ValueError):
            self._sent = ()  # the worker is gone: its reader says so, and _take restarts it

    def _take(self, item) -> AccurateResult | EquilibriaFound | None:
        """The answer the reader queued, or None when the worker died under this request
        and a new one is solving it (once: a request that kills two workers is answered
        with the error)."""
        process, message = item
        if process is not self._process:
            return None  # a dead worker's last word, after it was replaced
        index, problem, what = self._submitted or (0, None, SOLVE)
        if message is None:
            process.wait()
            _close_pipes(process)
            self.restarts += 1
            self._start()
            if problem is not None and not self._retried:
                self._retried = True
                self._send(index, problem, what)
                return None
            self._busy = False
            error = ("the accurate worker process stopped twice on this pose (it was "
                     "started again): move the grip elsewhere")
            if not isinstance(what, str) and what[0] == FIND:
                return EquilibriaFound(index, (), error=error)
            return AccurateResult(index, problem, np.zeros(0), np.zeros((0, 0)), {},
                                  error=error)
        self._busy = False
        if isinstance(message, AccurateResult) and message.problem is None:  # (the worker)
            message = replace(message, problem=problem)
        return message

    def poll(self) -> AccurateResult | EquilibriaFound | None:
        return self.wait(timeout=0.0)  # a queue's get with no time left never blocks

    def wait(self, timeout: float | None = None) -> AccurateResult | EquilibriaFound | None:
        import queue  # noqa: PLC0415
        import time  # noqa: PLC0415

        end = None if timeout is None else time.monotonic() + timeout
        while self._busy:
            left = None if end is None else max(end - time.monotonic(), 0.0)
            try:
                item = self._answers.get(timeout=left)
            except queue.Empty:
                return None
            result = self._take(item)
            if result is not None:
                return result
        return None

    def close(self) -> None:
        """Stop the worker: at once when it is solving (a tab closed mid-solve must not
        leave it running on), else by the stop message."""
        self._closing.set()
        process = self._process
        if self._busy:
            process.kill()
        else:
            try:
                write_message(process.stdin, None)
                if process.stdin is not None:
                    process.stdin.close()
            except (OSError, ValueError):
                pass
        try:
            process.wait(timeout=2.0)
        except Exception:
            process.kill()
            process.wait()
        _close_pipes(process)


def _close_pipes(process) -> None:
    """A finished worker's pipes, closed (their file descriptors are not left open)."""
    for stream in (process.stdin, process.stdout):
        try:
            if stream is not None:
                stream.close()
        except (OSError, ValueError):
            pass


def write_message(stream, message) -> None:
    """A length-prefixed pickle (None: the stop message)."""
    import pickle  # noqa: PLC0415

    payload = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    stream.write(len(payload).to_bytes(8, "little") + payload)
    stream.flush()


def read_message(stream):
    """The next message, or None at the end of the stream."""
    import pickle  # noqa: PLC0415

    head = stream.read(8)
    if len(head) < 8:
        return None
    size = int.from_bytes(head, "little")
    payload = stream.read(size)
    if len(payload) < size:
        return None
    return pickle.loads(payload)
