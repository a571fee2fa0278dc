"""The banded LU on the accurate model's own matrices, measured in one run (ratios).

The KKT Jacobians of the bundled engine bay's path (100 steps at the scene's elements,
contact on, the free probes left out as the Newton leaves them out), each factorised
and solved by:

- pliant's ``band_lu`` / ``band_lu_solve``: LAPACK's dgbtrf / dgbtrs called from numba;
- the hand-written twin (dgbtf2's algorithm in numba), what the kernels used before;
- scipy.linalg.solve_banded (LAPACK's dgbsv behind Python), what a scipy user would pick.

Each is timed on every matrix (median of 5), and the solutions are compared.

    .venv/bin/python benchmarks/banded.py
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np
from scipy.linalg import solve_banded

from pliant.assembly.path import follow_path
from pliant.assembly.scenes import load_scene
from pliant.models.banded import (
    band_lu,
    band_lu_solve,
    band_lu_solve_twin,
    band_lu_twin,
    band_reduce,
    dense,
)
from pliant.models.rod3d import RodSolver, kernels
from pliant.models.rod3d.solver import Run

SCENE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "engine_bay.toml"


def matrices() -> list[tuple[np.ndarray, int, int]]:
    """The reduced KKT band (ab, kl, ku) at each step of the engine bay's path."""
    scene = load_scene(SCENE)
    run = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                      elements=scene.solver.elements)
    out = []
    for eq in run.equilibria:
        r = Run(eq.state.rod, RodSolver(elements=scene.solver.elements))
        r.gauge_quat = eq.state.gauge_quat
        rod = r.rod
        _, ab, _ = r.residual(eq.state.state, rod.target, want_jac=True)
        drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
        reduced, lo, up, _ = band_reduce(ab, rod.kl, rod.ku, drop)
        out.append((np.ascontiguousarray(reduced), lo, up))
    return out


def timed(fn, repeat: int = 5) -> tuple[float, np.ndarray]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        x = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), x


def main() -> None:
    mats = matrices()
    rng = np.random.default_rng(1)
    t_lapack = t_twin = t_scipy = 0.0
    worst = 0.0
    for ab, kl, ku in mats:
        n = ab.shape[0]
        b = rng.standard_normal(n)

        def lapack(ab=ab, kl=kl, ku=ku, b=b):
            work = ab.copy()
            piv, _ok = band_lu(work, kl, ku)
            return band_lu_solve(work, piv, kl, ku, b)

        def twin(ab=ab, kl=kl, ku=ku, b=b):
            work = ab.copy()
            piv, _ok = band_lu_twin(work, kl, ku)
            return band_lu_solve_twin(work, piv, kl, ku, b)

        # scipy's layout: rows are diagonals (ku above, kl below), ab_s[ku + i - j, j].
        scipy_ab = ab.T[kl:, :].copy()

        def scipy(scipy_ab=scipy_ab, kl=kl, ku=ku, b=b):
            return solve_banded((kl, ku), scipy_ab, b, check_finite=False)

        lapack(), twin(), scipy()  # compiled and warm
        a, x = timed(lapack)
        t, xt = timed(twin)
        s, xs = timed(scipy)
        t_lapack += a
        t_twin += t
        t_scipy += s
        A = dense(ab, kl, ku, n)
        scale = np.abs(A).max() * np.abs(x).max()
        worst = max(worst, float(np.abs(A @ x - b).max() / scale),
                    float(np.abs(xt - x).max() / np.abs(x).max()),
                    float(np.abs(xs - x).max() / np.abs(x).max()))
    n = len(mats)
    sizes = [m[0].shape[0] for m in mats]
    print(f"{n} KKT matrices of the engine bay's path ({min(sizes)}-{max(sizes)} unknowns, "
          f"half bandwidths {mats[0][1]}, {mats[0][2]}), factorise and solve, median of 5:")
    print(f"  band_lu (LAPACK dgbtrf/dgbtrs from numba): {t_lapack / n * 1e3:.3f} ms")
    print(f"  hand-written twin (dgbtf2 in numba)      : {t_twin / n * 1e3:.3f} ms "
          f"({t_twin / t_lapack:.2f}x LAPACK's time)")
    print(f"  scipy.linalg.solve_banded               : {t_scipy / n * 1e3:.3f} ms "
          f"({t_scipy / t_lapack:.2f}x)")
    print(f"  largest relative residual or difference between them: {worst:.1e}")


if __name__ == "__main__":
    main()
