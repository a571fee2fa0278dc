"""The banded LU on the accurate model's own matrices, measured in one run (ratios).

Two sets of KKT Jacobians, the free probes left out as the Newton leaves them out: the
bundled engine bay's path (100 steps at the scene's elements, contact on), and a hose's
end lowered onto a block (``benchmarks/contact.py``'s case (b), 100 elements, the steps
that touch). Each is factorised and solved by:

- LAPACK's dgbtrf / dgbtrs called from numba (``band_lu_lapack``), what the kernels
  used before;
- pliant's ``band_lu`` / ``band_lu_solve``: dgbtf2's algorithm in numba, each update
  over the nonzero multipliers only;
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

import pliant as pl
from pliant.assembly.path import follow_path
from pliant.assembly.scenes import load_scene
from pliant.models import rod3d
from pliant.models.banded import (
    band_lu,
    band_lu_lapack,
    band_lu_solve,
    band_lu_solve_lapack,
    band_reduce,
    dense,
)
from pliant.models.rod3d import RodSolver, kernels
from pliant.models.rod3d.solver import Run
from pliant.scene import Obstacle

SCENE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "engine_bay.toml"


def matrices() -> list[tuple[np.ndarray, int, int]]:
    """The reduced KKT band (ab, kl, ku) at each step of the engine bay's path."""
    scene = load_scene(SCENE)
    run = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                      elements=scene.solver.elements)
    return [_reduced(eq, scene.solver.elements) for eq in run.equilibria]


def block_matrices() -> list[tuple[np.ndarray, int, int]]:
    """The reduced KKT band at each touching step of the hose lowered onto a block."""
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)
    block = Obstacle.box("block", (0.2, 0.2, 0.1), (0.7, 0.0, -0.12))

    def held(z: float) -> pl.Problem:
        return pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                 pl.pin(1.0, position=(0.95, 0.0, z), name="hand")),
                          gravity=(0.0, 0.0, -9.81), obstacles=(block,))

    heights = np.linspace(0.2, -0.15, 101)
    eq = rod3d.solve(held(heights[0]))
    out = []
    for z in heights[1:]:
        eq = rod3d.solve(held(z), warm_start=eq)
        if len(eq.contacts):
            out.append(_reduced(eq, 100))
    return out


def _reduced(eq, elements: int) -> tuple[np.ndarray, int, int]:
    r = Run(eq.state.rod, RodSolver(elements=elements))
    r.gauge_quat = eq.state.gauge_quat
    rod = r.rod
    _, ab, _ = r.residual(eq.state.state, rod.target, want_jac=True)
    drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
    reduced, lo, up, _ = band_reduce(ab, rod.kl, rod.ku, drop)
    return np.ascontiguousarray(reduced), lo, up


def timed(fn, repeat: int = 5) -> tuple[float, np.ndarray]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        x = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), x


def main() -> None:
    compare(matrices(), "the engine bay's path")
    compare(block_matrices(), "a hose lowered onto a block (touching steps)")


def compare(mats: list[tuple[np.ndarray, int, int]], what: str) -> None:
    rng = np.random.default_rng(1)
    t_lapack = t_twin = t_scipy = 0.0
    worst = 0.0
    for ab, kl, ku in mats:
        n = ab.shape[0]
        b = rng.standard_normal(n)

        def lapack(ab=ab, kl=kl, ku=ku, b=b):
            work = ab.copy()
            piv, _ok = band_lu_lapack(work, kl, ku)
            return band_lu_solve_lapack(work, piv, kl, ku, b)

        def twin(ab=ab, kl=kl, ku=ku, b=b):
            work = ab.copy()
            piv, _ok = band_lu(work, kl, ku)
            return band_lu_solve(work, piv, kl, ku, b)

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
    print(f"{n} KKT matrices of {what} ({min(sizes)}-{max(sizes)} unknowns, "
          f"half bandwidths {mats[0][1]}, {mats[0][2]}), factorise and solve, median of 5:")
    print(f"  LAPACK dgbtrf/dgbtrs from numba          : {t_lapack / n * 1e3:.3f} ms")
    print(f"  band_lu (dgbtf2 over nonzero multipliers): {t_twin / n * 1e3:.3f} ms "
          f"({t_twin / t_lapack:.2f}x LAPACK's time)")
    print(f"  scipy.linalg.solve_banded               : {t_scipy / n * 1e3:.3f} ms "
          f"({t_scipy / t_lapack:.2f}x)")
    print(f"  largest relative residual or difference between them: {worst:.1e}")


if __name__ == "__main__":
    main()
