"""A manipulation session: the coupling of the paper's Fig. 1.

Grip events come in (a hand, a tracker); each returns a real-time frame at once (the bar
network moved to the new grip poses, its tube mesh). The session measures drift: the
network's length error and the distance from its curve to the last accurate shape. Past
a tolerance, or when asked, it hands the current pose to the accurate model
(warm-started from the last equilibrium); when the answer arrives it is published (shape
and real forces) and the network is retuned to it. In live mode the accurate model runs
in a worker process and ``apply`` never waits for it; in inline mode (replays, tests) it
runs at once, so a replayed event stream gives the same frames every time.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

from pliant.core.conditions import Condition
from pliant.core.problem import Problem
from pliant.errors import ConvergenceError, InputError
from pliant.models.realtime import RealtimeFrame, RealtimeModel
from pliant.session.accurate import (
    CHOOSE,
    FIND,
    SOLVE,
    AccurateResult,
    EquilibriaFound,
    InlineExecutor,
    ProcessExecutor,
    Request,
)

T = TypeVar("T")


@dataclass(frozen=True)
class GripEvent:
    """A grip moved: the condition ``grip`` takes the given position [m] and, where
    given, its axis ``tangent`` and section ``normal`` (3D) or ``angle`` [rad] (2D).
    ``t`` is when it happened [s] (recorded; replays ignore it)."""

    grip: str
    position: tuple[float | None, ...] | None = None
    tangent: tuple[float, float, float] | None = None
    normal: tuple[float, float, float] | None = None
    angle: float | None = None
    t: float = 0.0


@dataclass(frozen=True)
class Drift:
    """How far the real-time shape may be from the truth: the control polygon's length
    error and the curve's (relative), and the largest distance from the curve to the last
    accurate shape at the same s (relative to L; it grows as the grips move away from
    the accurate pose)."""

    length_error: float
    curve_length_error: float
    distance_to_accurate: float


@dataclass(frozen=True)
class Frame:
    """What a session returns for each event, at once.

    index : the event's number; realtime : the network's frame (curve, tube mesh,
    fictive grip forces); drift; accurate : the latest accurate result (real forces),
    answering event ``accurate.index`` (it may be older than this frame); pending : an
    accurate solve is running; solved : this event triggered one; seconds : how long
    this call took.
    """

    index: int
    realtime: RealtimeFrame
    drift: Drift
    accurate: AccurateResult | None
    pending: bool
    solved: bool
    seconds: float


KEPT = 64  # results a session keeps (the page takes each as it is published)


class Kept(Generic[T]):
    """The last ``size`` items appended, and how many were appended in all (``total``):
    what a long session keeps of its history without growing with it. Reads as a list
    of the items kept, oldest first; ``since(count)`` the items appended after the
    first ``count`` that are still kept."""

    def __init__(self, size: int) -> None:
        self._items: deque[T] = deque(maxlen=size)
        self.total = 0

    def append(self, item: T) -> None:
        self._items.append(item)
        self.total += 1

    def since(self, count: int) -> list[T]:
        new = self.total - count
        return list(self._items)[-new:] if new > 0 else []

    def __len__(self) -> int:
        return len(self._items)

    def __iter__(self) -> Iterator[T]:
        return iter(self._items)

    def __getitem__(self, key: int | slice) -> Any:
        return list(self._items)[key]


@dataclass
class Session:
    """An interactive session on one problem (2D or 3D).

    live : run the accurate model in a worker process (else inline, deterministic);
    control_points, bending : of the real-time model; distance_tolerance and
    length_tolerance : the drift (relative to L) past which an accurate solve is started;
    elements : the 3D model's resolution; on_accurate : called with each accurate
    result as it is published.
    """

    problem: Problem
    live: bool = False
    control_points: int = 50
    bending: float = 0.1
    distance_tolerance: float = 0.02
    length_tolerance: float = 0.005
    elements: int | None = None
    on_accurate: Callable[[AccurateResult], None] | None = None
    index: int = field(default=0, init=False)
    events: list[GripEvent] = field(default_factory=list, init=False)
    accurate: AccurateResult | None = field(default=None, init=False)
    # The latest accurate results as published (``Kept``: a sitting of thousands of
    # solves keeps the last KEPT, about 31 KB each, and counts them all).
    solves: Kept[AccurateResult] = field(default_factory=lambda: Kept(KEPT), init=False)
    start_error: str | None = field(default=None, init=False)  # why the start pose has no
    # equilibrium (the session opens all the same)
    searches: Kept[EquilibriaFound] = field(default_factory=lambda: Kept(KEPT),
                                            init=False)  # each search for the pose's
    # equilibria, as published (``find_equilibria``)

    def __post_init__(self) -> None:
        self.model = RealtimeModel(self.problem, control_points=self.control_points,
                                   bending=self.bending)
        self._executor = (ProcessExecutor(self.elements) if self.live
                          else InlineExecutor(self.elements))
        self._requested = False
        self._asked: Request | None = None  # a search or a choice, sent when the worker is free
        self._reference: np.ndarray | None = None  # the accurate shape at the curve's s
        self._start = time.perf_counter()
        # The first accurate solve, waited for: the network starts from it. When the
        # start pose has no equilibrium the session still opens (the scene can be seen
        # and its grips moved to a pose that has one): the failed result says why, and
        # the network starts from its own shape until an accurate answer arrives.
        self._executor.submit(0, self.problem)
        first = self._executor.wait(timeout=None if not self.live else 600.0)
        if first is None:
            self.close()
            raise ConvergenceError("the session cannot start: the accurate model did not "
                                   "answer", residual=float("nan"))
        self._publish(first)
        self.start_error = None if first.ok else first.error
        self.model.frame(self.problem)  # loads the kernels now, not in the first frame

    # -- events ----------------------------------------------------------------------------
    def apply(self, event: GripEvent) -> Frame:
        """Move a grip; return the frame at once (never waits for the accurate model)."""
        start = time.perf_counter()
        if not any(c.name == event.grip for c in self.problem.conditions):
            raise InputError("grip", f"no condition is named {event.grip!r}; the conditions "
                             "are " + ", ".join(repr(c.name) for c in self.problem.conditions))
        self.problem = self.problem.with_conditions(
            _moved(c, event) if c.name == event.grip else c for c in self.problem.conditions)
        self.index += 1
        stamped = event if event.t else dataclasses.replace(event, t=start - self._start)
        self.events.append(stamped)
        return self._frame(start)

    def replace(self, problem: Problem) -> Frame:
        """Change what the conditions prescribe (a grip switched between holding by
        position and pushing with a force, a force edited): the network is rebuilt for
        the new grips, fitted to the last accurate shape, and an accurate solve of the
        new problem is asked for. The part and the condition names must stay."""
        if problem.dimension != self.problem.dimension or problem.part != self.problem.part:
            raise InputError("problem", "a session keeps its part and dimension; start a new "
                             "session for another part")
        names = sorted(c.name for c in problem.conditions)
        if names != sorted(c.name for c in self.problem.conditions):
            raise InputError("problem", "a session keeps its conditions' names: "
                             + ", ".join(repr(c.name) for c in self.problem.conditions))
        start = time.perf_counter()
        self.problem = problem
        self.model = RealtimeModel(problem, control_points=self.control_points,
                                   bending=self.bending)
        if self.accurate is not None:
            self.model.retune(dataclasses.replace(self.accurate, problem=problem))
        self._requested = True
        self.index += 1
        return self._frame(start)

    @property
    def pending(self) -> bool:
        """An accurate solve is running (its answer comes with a later frame)."""
        return self._executor.busy

    @property
    def answered(self) -> bool:
        """The accurate answer has arrived; the next event or ``poll`` takes it in."""
        return self._executor.answered

    def notify(self, listener: Callable[[], None] | None) -> None:
        """Have ``listener()`` called as each live answer arrives (from the worker's
        reader thread: it must only hand over, say ``loop.call_soon_threadsafe``), so
        that a server pushes it instead of polling. Inline answers come with the call
        that asked for them."""
        if isinstance(self._executor, ProcessExecutor):
            self._executor.on_answer = listener

    def request_accurate(self) -> None:
        """Ask for an accurate solve at the next event (or ``poll``), drift or not."""
        self._requested = True

    def find_equilibria(self, budget: float = 10.0) -> None:
        """Ask for the current pose's equilibria (``pliant.models.dispatch.equilibria``,
        within ``budget`` seconds), sent at the next event or ``poll`` once the accurate
        model is free; the answer is appended to ``searches`` (best first)."""
        if not 0.0 < budget <= 600.0:
            raise InputError("budget", f"a search's time budget is from 0 to 600 s, got "
                             f"{budget!r}")
        self._asked = (FIND, float(budget))

    @property
    def found(self) -> EquilibriaFound | None:
        """The last search's answer while the pose is still the one it was made for."""
        last = self.searches[-1] if self.searches else None
        return last if last is not None and last.index == self.index else None

    def choose(self, k: int) -> None:
        """Make the k-th equilibrium (0-based) of the last search the accurate answer
        and the next solve's warm start, so the session follows that branch as the grips
        move on (published at the next event or ``poll``)."""
        found = self.found
        if found is None:
            raise InputError("option", "no search for this pose's equilibria has answered "
                             "(the grips moved since, or none was asked): look for them "
                             "first")
        if not 0 <= k < len(found.options):
            raise InputError("option", f"equilibrium {k + 1} does not exist: the search "
                             f"found {len(found.options)}")
        self._asked = (CHOOSE, int(k))
        self._requested = False

    def poll(self) -> Frame:
        """A frame at the current pose, taking any accurate result that has arrived."""
        return self._frame(time.perf_counter())

    def wait(self, timeout: float = 60.0) -> AccurateResult | EquilibriaFound | None:
        """Block until the running accurate solve ends (for scripts and tests; a frame
        loop polls instead); publish its result."""
        done = self._executor.wait(timeout)
        if done is not None:
            self._publish(done)
        return done

    def close(self) -> None:
        self._executor.close()

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals -------------------------------------------------------------------------
    def _frame(self, start: float) -> Frame:
        done = self._executor.poll()
        if done is not None:
            self._publish(done)
        realtime = self.model.frame(self.problem)
        drift = self._drift(realtime)
        solved = False
        if not self._executor.busy and self._asked is not None:
            asked, self._asked = self._asked, None
            if self._submit(asked):
                realtime = self.model.frame(self.problem)
                drift = self._drift(realtime)
        if not self._executor.busy and (
                self._requested or not realtime.converged
                or drift.distance_to_accurate > self.distance_tolerance
                or max(drift.length_error, drift.curve_length_error) > self.length_tolerance):
            self._requested = False
            solved = True
            if self._submit(SOLVE):
                realtime = self.model.frame(self.problem)
                drift = self._drift(realtime)
        return Frame(index=self.index, realtime=realtime, drift=drift, accurate=self.accurate,
                     pending=self._executor.busy, solved=solved,
                     seconds=time.perf_counter() - start)

    def _submit(self, what: Request) -> bool:
        """Hand the current pose to the accurate side; True when the answer is already
        there and published (inline), so the frame must be made again."""
        self._executor.submit(self.index, self.problem, what)
        done = self._executor.poll()  # inline: already there
        if done is not None:
            self._publish(done)
        return done is not None

    def _publish(self, result: AccurateResult | EquilibriaFound) -> None:
        if isinstance(result, EquilibriaFound):
            self.searches.append(result)
            return
        self.solves.append(result)
        if not result.ok:
            return  # keep the last good shape; the drift stays and says so
        self.accurate = result
        self.model.retune(result)
        L = self.problem.part.length
        s_curve = self.model.u_curve * L
        self._reference = np.column_stack([np.interp(s_curve, *_distinct(result.s, x))
                                           for x in result.position.T])
        if self.on_accurate is not None:
            self.on_accurate(result)

    def _drift(self, realtime: RealtimeFrame) -> Drift:
        L = self.problem.part.length
        curve = realtime.curve[:, :self.problem.dimension]
        distance = (float(np.linalg.norm(curve - self._reference, axis=1).max()) / L
                    if self._reference is not None else float("inf"))
        return Drift(realtime.length_error, realtime.curve_length_error, distance)


def replay(problem: Problem, events: Iterable[GripEvent], **options) -> list[Frame]:
    """Replay a recorded event stream inline: the same frames and the same accurate
    solves every run."""
    options.pop("live", None)
    with Session(problem, live=False, **options) as session:
        return [session.apply(event) for event in events]


def _moved(cond: Condition, event: GripEvent) -> Condition:
    changes: dict[str, Any] = {}
    if event.position is not None:
        changes["position"] = tuple(event.position)
    if event.tangent is not None:
        changes["tangent"] = tuple(event.tangent)
    if event.normal is not None:
        changes["normal"] = tuple(event.normal)
    if event.angle is not None:
        changes["angle"] = event.angle
    return dataclasses.replace(cond, **changes)


def _distinct(s: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    keep = np.concatenate([[True], np.diff(s) > 0.0])
    return s[keep], x[keep]
