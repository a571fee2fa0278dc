"""The accurate-model worker of a live session: ``python -m pliant.session.worker N``
(N: the 3D resolution, 0 for the default). It reads (index, problem, same obstacles,
request) messages on stdin and writes ``AccurateResult``s (and ``EquilibriaFound``s) on stdout,
warm-starting each solve from the last (``AccurateSolver.run``)."""

from __future__ import annotations

import os
import sys
from dataclasses import replace

from pliant.session.accurate import AccurateResult, AccurateSolver, read_message, write_message


def main() -> None:
    elements = int(sys.argv[1]) if len(sys.argv) > 1 else 0
    # The protocol owns the real stdout; anything printed goes to stderr instead.
    channel = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    sys.stdout = sys.stderr
    requests = sys.stdin.buffer
    solver = AccurateSolver(elements=elements or None)
    kept: tuple = ()  # the scene's obstacles, sent once (see ProcessExecutor.submit)
    while True:
        message = read_message(requests)
        if message is None:
            return
        index, problem, same, what = message
        if same:
            problem = replace(problem, obstacles=kept)
        kept = problem.obstacles
        answer = solver.run(index, problem, what)
        # An answer goes back without its problem: the session has it (it sent it), and
        # with a scene's obstacle grids it is a megabyte a solve.
        if isinstance(answer, AccurateResult):
            answer = replace(answer, problem=None)
        write_message(channel, answer)


if __name__ == "__main__":
    main()
