"""Features where they meet, two at a time (issue 61): every case of
``tests/combinations.py`` (the CI runs the fast ones), each against a value pliant did
not compute the same way, counted per pair as right, wrong, refused (a typed error) or
fallback (an answer resting on a part held rigid).

    .venv/bin/python benchmarks/combinations.py [--fast]

Goal: 0 wrong and 0 fallbacks; a refusal is said, not wrong, but is a combination that
does not work yet.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.combinations import CASES, outcome


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fast", action="store_true", help="only the CI subset")
    args = parser.parse_args()
    counts: dict[tuple[str, str], Counter] = {}
    total: Counter = Counter()
    for case in CASES:
        if args.fast and not case.fast:
            continue
        with tempfile.TemporaryDirectory() as folder:
            start = time.process_time()
            result = outcome(case, Path(folder))
            seconds = time.process_time() - start
        counts.setdefault(case.pair, Counter())[result.status] += 1
        total[result.status] += 1
        print(f"{' x '.join(case.pair):22} {result.status:8} {seconds:6.1f} s CPU  "
              f"{case.name}: {result.detail}", flush=True)
    print()
    print(f"{'pair':22} {'right':>6} {'wrong':>6} {'refused':>8} {'fallback':>9}")
    for pair, c in counts.items():
        print(f"{' x '.join(pair):22} {c['right']:6} {c['wrong']:6} {c['refused']:8} "
              f"{c['fallback']:9}")
    print(f"{'all':22} {total['right']:6} {total['wrong']:6} {total['refused']:8} "
          f"{total['fallback']:9}  ({sum(total.values())} cases, {len(counts)} pairs)")


if __name__ == "__main__":
    main()
