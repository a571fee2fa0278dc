"""Progress of long reads (a CAD assembly's solids, large meshes' distance structures),
said to whoever listens: the CLI's status line. Library code calls ``say``; without a
listener it costs nothing."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from contextvars import ContextVar

_LISTENER: ContextVar[Callable[[str], None] | None] = ContextVar("pliant_progress",
                                                                  default=None)


def say(text: str) -> None:
    """Tell the listener, if any, what is being done now."""
    listener = _LISTENER.get()
    if listener is not None:
        listener(text)


@contextlib.contextmanager
def listening(listener: Callable[[str], None]) -> Iterator[None]:
    """Send ``say``'s texts to ``listener`` inside the block."""
    token = _LISTENER.set(listener)
    try:
        yield
    finally:
        _LISTENER.reset(token)
