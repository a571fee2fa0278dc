"""The clip order of a harness (issue 57, 5; ``pliant.assembly.clip_order``): the exact
search over sets of fixings against the slow twin that judges every order along its own
path (same best order, fewer operations) and the greedy search used past 10 fixings, on
the test's three-clip bundle and on fixings of the main harness (KBL), with how the work
grows with the fixings.

    .venv/bin/python benchmarks/clip_order.py [--main K]

``--main K``: order the K fixings of the main harness nearest its first (default 2;
0 skips it). Times are this process's CPU seconds.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pliant.assembly.clip_order import clip_order
from pliant.assembly.harness import properties
from pliant.io.kbl import read_kbl
from tests.test_clip_order import _bundle

ROOT = Path(__file__).resolve().parents[1]
MAIN = ROOT / "examples" / "harness" / "kbl" / "kblxml_2.4sr-1_tab016120_modulare_ltgs._160718.kbl"


def _timed(harness, props, **options):
    start = time.process_time()
    result = clip_order(harness, props, **options)
    return result, time.process_time() - start


def _row(label: str, result, seconds: float) -> None:
    best = result.best
    print(f"{label:34s} {result.method:34s} {result.operations:4d} ops {seconds:7.1f} s  "
          f"best {' > '.join(best.fixings) if best else 'none'}"
          + (f" ({best.zone}, peak {best.peak:.2f} N)" if best else ""))


def _nearest(harness, count: int) -> list[str]:
    """``count`` fixings placed on segments, the first by name and those nearest it."""
    where = {}
    for seg in harness.segments.values():
        for place in seg.fixings:
            fixing = harness.fixings[place.fixing]
            node = harness.nodes[seg.start if place.location < 0.5 else seg.end]
            where.setdefault(fixing.name, np.asarray(node.position, float))
    first = sorted(where)[0]
    return sorted(where, key=lambda n: float(np.linalg.norm(where[n] - where[first])))[:count]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--main", type=int, default=2)
    args = parser.parse_args()
    bundle = _bundle(bend_radius=0.09)
    props = properties(bundle)
    exact, t_exact = _timed(bundle, props)
    shared = {"installed": exact.installed, "hanging": exact.hanging}  # its cold solves
    slow, t_slow = _timed(bundle, props, search="every", **shared)
    greedy, t_greedy = _timed(bundle, props, search="greedy", **shared)
    print("three clips on a slack bundle (the test's), 90 mm bend limit (the exact search's "
          "time with the two cold solves, the others' without):")
    _row("  exact over sets", exact, t_exact)
    _row("  every order", slow, t_slow)
    _row("  greedy", greedy, t_greedy)
    same = exact.best is not None and slow.best is not None and \
        exact.best.fixings == slow.best.fixings
    print(f"  same best order: {same}; failing first clips: "
          f"{sorted({f.fixing for f in exact.failures if not f.before})}")
    for n in (3, 5, 8, 10):
        print(f"  {n:2d} fixings: exact {n * 2 ** (n - 1):6d} operations, every order "
              f"{sum(math.perm(n, k) for k in range(1, n + 1)):9d}")
    if args.main:
        harness = read_kbl(MAIN)
        props = properties(harness)
        names = _nearest(harness, args.main)
        result, seconds = _timed(harness, props, fixings=names)
        print(f"main harness ({len(harness.segments)} segments), {len(names)} fixings "
              f"(the others fixed):")
        _row("  exact over sets", result, seconds)
        for step in result.best.steps if result.best else ():
            print(f"    {step.fixing}: hand {step.force:.2f} N, tightest "
                  f"{step.tightest[1] * 1e3:.1f} mm in {step.tightest[0]} ({step.zone})")
        for note in result.notes[1:]:
            print(f"    note: {note[:160]}")


if __name__ == "__main__":
    main()
