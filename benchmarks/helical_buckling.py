"""PyElastica's localized helical buckling case (Gazzola et al. 2018, section 3.4.1: a
rod, B 1.345, C 0.789, L 1, clamped at both ends, one end turned 27 times as they close
in by 3 %) against its closed form (van der Heijden et al.; ``tests/helpers.
localized_helix``): pliant's equilibrium followed from the closed form's shape
(``rod3d.from_shape``), by elements: the end tension, the end moment, the helix's
amplitude, their errors, the observed order and the Richardson extrapolation of the
finest two, and the CPU time.

    .venv/bin/python benchmarks/helical_buckling.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pliant.errors import PliantError
from tests.helpers import localized_helix
from tests.test_helical_buckling import _answer


def main() -> None:
    curve, moment, tension, amplitude = localized_helix()
    exact = (tension, moment, amplitude)
    print(f"closed form: T {tension:.2f} N, M {moment:.3f} N m, amplitude "
          f"{amplitude * 1e3:.4f} mm")
    print(f"{'elements':>8} {'T N':>9} {'err':>9} {'M N m':>9} {'err':>9} "
          f"{'amp mm':>8} {'err':>9} {'verdict':>8} {'CPU s':>6}")
    rows = []
    for n in (100, 200, 400, 800, 1600):
        t0 = time.process_time()
        try:
            got = _answer(curve, n)
        except PliantError as err:
            print(f"{n:8d} not followed: {str(err)[:90]}")
            continue
        seconds = time.process_time() - t0
        rows.append(got)
        errors = [(got[k] - exact[k]) / exact[k] for k in range(3)]
        print(f"{n:8d} {got[0]:9.2f} {errors[0]:+9.2e} {got[1]:9.3f} {errors[1]:+9.2e} "
              f"{got[2] * 1e3:8.4f} {errors[2]:+9.2e} {got[3]:>8} {seconds:6.2f}")
    (c, f) = rows[-2], rows[-1]
    for k, name in enumerate(("T", "M", "amplitude")):
        order = abs((c[k] - exact[k]) / (f[k] - exact[k]))
        richardson = f[k] + (f[k] - c[k]) / 3.0
        print(f"{name}: error ratio 800/1600 {order:.2f} (4 at second order); Richardson "
              f"{richardson:.6g} against {exact[k]:.6g} ({richardson / exact[k] - 1:+.1e})")


if __name__ == "__main__":
    main()
