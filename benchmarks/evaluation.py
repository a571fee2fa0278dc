"""The A/D evaluation's cost, measured in one run (ratios: this machine's speed varies).

1. The bundled engine bay (100 steps at 80 elements), end to end: following the path
   (solves, stability, interference), the checks and verdict, and the HTML report;
   against following the path alone (what `pliant run` does).
2. The stability test at every step of that path: the Lanczos kernel against ARPACK's
   eigsh (what the solver used before; a user of scipy would pick it) on the same
   factorised KKT matrices, and the largest difference of the eigenvalues.
3. The second-hand search on a heavy hose held at one end: accurate solves and seconds.
4. Hand access (issue 56) at every step of the engine bay against following the path,
   in CPU time (the issue's budget: at most 20 % of a path step).

    .venv/bin/python benchmarks/evaluation.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from pliant.assembly.evaluate import evaluate
from pliant.assembly.path import follow_path
from pliant.assembly.scenes import load_scene, parse_scene
from pliant.cli.evaluation_report import write_html

SCENE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "engine_bay.toml"
HEAVY = """
name = "a heavy hose held at one end"
gravity = [0.0, 0.0, -9.81]
[part]
name = "heavy hose"
length = 1.0
bending_stiffness = 20.0
mass_per_length = 4.0
outer_diameter = 0.04
kind = "rubber hose"
[solver]
elements = 60
[[condition]]
name = "hand"
hand = true
s = 1.0
x = 1.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
"""


def engine_bay(repeats: int = 3) -> None:
    scene = load_scene(SCENE)
    evaluate(scene)  # load the kernels
    follow, judged, report = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                          elements=scene.solver.elements)
        t1 = time.perf_counter()
        ev = evaluate(scene, run=run)
        t2 = time.perf_counter()
        with tempfile.TemporaryDirectory() as folder:
            write_html(ev, Path(folder) / "r.html")
        t3 = time.perf_counter()
        follow.append(t1 - t0)
        judged.append(t2 - t1)
        report.append(t3 - t2)
    solve = sum(r.seconds for r in run.steps)
    print(f"engine bay, {len(run.steps) - 1} steps at {scene.solver.elements} elements "
          f"(best of {repeats}):")
    print(f"  following the path (solves, stability, interference): {min(follow):.3f} s "
          f"(of which the solves {solve:.3f} s)")
    print(f"  checks and verdict: {min(judged) * 1e3:.1f} ms "
          f"({min(judged) / min(follow):.1%} of following)")
    print(f"  HTML report (plots, pictures): {min(report):.2f} s")
    print(f"  verdict: {ev.verdict.headline}")


def stability() -> None:
    from pliant.models.banded import band_reduce
    from pliant.models.lanczos import softest_mode
    from pliant.models.rod3d import RodSolver, kernels
    from pliant.models.rod3d.solver import Run
    from pliant.models.rod3d.stability import _stability_arpack, shift_bound
    from pliant.models.rod3d.stability import metric as _metric

    scene = load_scene(SCENE)
    run = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                      elements=scene.solver.elements)
    t_lanczos = t_arpack = 0.0
    worst = 0.0
    for eq in run.equilibria:
        r = Run(eq.state.rod, RodSolver(elements=scene.solver.elements))
        r.gauge_quat = eq.state.gauge_quat
        state = eq.state.state
        rod = r.rod
        c = shift_bound(rod, state)
        primal, weight = _metric(rod)
        _, ab, _ = r.residual(state, rod.target, want_jac=True)
        ab[:, rod.kl + rod.ku] += c * np.where(primal, weight, 0.0)
        drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
        reduced, lo, up, new = band_reduce(ab, rod.kl, rod.ku, drop)
        piv, _ = kernels.band_lu(reduced, lo, up)
        keep = new >= 0
        size = int(primal.sum())
        start = np.random.default_rng(12345).standard_normal(size)
        t0 = time.perf_counter()
        theta, _, _, _ = softest_mode(reduced, piv, lo, up, new[np.flatnonzero(primal)],
                                      np.ascontiguousarray(weight[primal]), start, 1e-10, 80)
        t1 = time.perf_counter()
        value, _ = _stability_arpack(reduced, piv, int(keep.sum()), lo, up, primal[keep],
                                     weight[keep], c, size)
        t2 = time.perf_counter()
        t_lanczos += t1 - t0
        t_arpack += t2 - t1
        worst = max(worst, abs((-c + 1.0 / theta) - value) / max(abs(value), 1e-12))
    n = len(run.equilibria)
    print(f"stability at {n} steps (free probes out of the factorisation): Lanczos kernel "
          f"{t_lanczos / n * 1e3:.2f} ms a step, ARPACK eigsh {t_arpack / n * 1e3:.2f} ms: "
          f"{t_arpack / t_lanczos:.1f}x; largest relative difference of the eigenvalues "
          f"{worst:.1e}")


def second_hand() -> None:
    scene = parse_scene(HEAVY, "heavy.toml")
    evaluate(scene)
    t0 = time.perf_counter()
    ev = evaluate(scene)
    seconds = time.perf_counter() - t0
    placed = ev.operators[-1]
    print(f"second hand on a heavy hose held at one end: {placed.solves} accurate solves, "
          f"{seconds * 1e3:.0f} ms for the whole evaluation; {ev.verdict.headline}")


def hand_access_cost(repeats: int = 3) -> None:
    from pliant.assembly.access import hand_access
    from pliant.io.rules_file import bundled_rules

    env = bundled_rules().access
    scene = load_scene(SCENE)
    run = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                      elements=scene.solver.elements)
    hand_access(run.equilibria[0], 0.75, env)  # the field packed once, as in evaluate
    follow, access = [], []
    for _ in range(repeats):
        t0 = time.process_time()
        run = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                          elements=scene.solver.elements)
        t1 = time.process_time()
        found = [hand_access(eq, eq.loads["hand"].s, env) for eq in run.equilibria]
        t2 = time.process_time()
        follow.append(t1 - t0)
        access.append(t2 - t1)
    n = len(run.equilibria)
    tight = min(found, key=lambda a: a.clearance)
    print(f"hand access on the engine bay ({env.directions} approaches, best of {repeats}, "
          f"CPU): {min(access) / n * 1e3:.2f} ms a step against {min(follow) / n * 1e3:.2f} "
          f"ms a path step: {min(access) / min(follow):.0%}; tightest "
          f"{tight.clearance * 1e3:.1f} mm (bound by {tight.bound_by})")


if __name__ == "__main__":
    engine_bay()
    stability()
    second_hand()
    hand_access_cost()
