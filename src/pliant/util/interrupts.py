"""Ctrl+C turned, for a while, into a call of one's own (a search that must stop at its
next check, a child process that must not be left behind)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator


@contextlib.contextmanager
def on_ctrl_c(handler: Callable[[], None]) -> Iterator[bool]:
    """While the block runs, Ctrl+C calls ``handler`` instead of raising
    KeyboardInterrupt; the previous handler is put back after. Only in the main thread
    (the only one a signal reaches), and not where Ctrl+C is ignored or handled outside
    Python (then nothing changes). Yields whether it took Ctrl+C."""
    previous = (signal.getsignal(signal.SIGINT)
                if threading.current_thread() is threading.main_thread() else None)
    if previous in (None, signal.SIG_IGN):
        yield False
        return
    # A plain function: signal.signal reprs a handler it cannot map to its enum.
    signal.signal(signal.SIGINT, lambda *_: handler())
    try:
        yield True
    finally:
        signal.signal(signal.SIGINT, previous)
