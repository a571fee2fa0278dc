"""Progress of long reads (a CAD assembly's solids, large meshes' distance structures),
said to whoever listens: the CLI's progress bar. Library code calls ``say`` (what is done
now), ``work`` (a measured task: so many units, here triangles) and ``advance`` (units
done); without a listener they cost nothing.

Tasks do not nest: a task opened inside another counts towards the outer one, so that a
CAD table's bar runs over all its solids' triangles while each solid's own build only
advances it."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass
from typing import Protocol, cast


class Listener(Protocol):
    """What the CLI's bar (or a test) does with the reports."""

    def say(self, text: str) -> None: ...
    def start(self, total: float) -> None: ...
    def update(self, done: float) -> None: ...
    def stop(self) -> None: ...


@dataclass
class _Task:
    total: float
    done: float = 0.0


class _Said:
    """A listener of texts alone (a status line)."""

    def __init__(self, say: Callable[[str], None]) -> None:
        self.say = say

    def start(self, total: float) -> None:
        pass

    def update(self, done: float) -> None:
        pass

    def stop(self) -> None:
        pass


_LISTENER: ContextVar[Listener | None] = ContextVar("pliant_progress", default=None)
_TASK: ContextVar[_Task | None] = ContextVar("pliant_progress_task", default=None)


def say(text: str) -> None:
    """Tell the listener, if any, what is being done now."""
    listener = _LISTENER.get()
    if listener is not None:
        listener.say(text)


@contextlib.contextmanager
def work(total: float) -> Iterator[None]:
    """A task of ``total`` units inside the block (``advance`` counts them); inside
    another task it only adds to that one."""
    listener = _LISTENER.get()
    if listener is None or _TASK.get() is not None or not total > 0:
        yield
        return
    token = _TASK.set(_Task(float(total)))
    listener.start(float(total))
    try:
        yield
    finally:
        _TASK.reset(token)
        listener.stop()


def advance(amount: float) -> None:
    """``amount`` units of the open task are done (never past its total)."""
    listener, task = _LISTENER.get(), _TASK.get()
    if listener is not None and task is not None:
        task.done = min(task.total, task.done + max(float(amount), 0.0))
        listener.update(task.done)


@contextlib.contextmanager
def listening(listener: Listener | Callable[[str], None]) -> Iterator[None]:
    """Send the reports to ``listener`` inside the block (a bare callable gets the
    texts alone)."""
    token = _LISTENER.set(cast(Listener, listener) if hasattr(listener, "update")
                          else _Said(listener))
    try:
        yield
    finally:
        _LISTENER.reset(token)
