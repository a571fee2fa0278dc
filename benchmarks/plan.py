"""Path planning's figures, measured in one run (ratios: this machine's speed varies).

1. The bundled engine bay (examples/scenes/engine_bay.toml, its [plan]): planning time
   over 5 seeds (the median is the figure), accurate solves per plan, and the found
   path's peak hand force, moment and demand against the bundled hand-written [path]
   followed the same way.
2. Generated scenes: examples/scenes/hose_past_post.toml with 1 to 3 random posts, boxes
   and bars between the start and the port (the start and the port left clear), at
   least a third of them where the straight move is blocked: success rate, time and
   solves per plan. For comparison, Sintov, Macenski, Borum and Bretl ("Motion planning
   for dual-arm manipulation of elastic rods", IEEE RA-L 2020) report 2.5-2.8 s median
   per query with a precomputed 500-milestone roadmap of the rod's equilibria.

    .venv/bin/python benchmarks/plan.py [scenes]
"""

from __future__ import annotations

import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pliant.assembly.path import follow_path
from pliant.assembly.plan import NoPathError, Planner, _Blocked
from pliant.assembly.scenes import load_scene, scene_from_data
from pliant.errors import InputError
from pliant.io.problem_file import read_text
from pliant.io.tomlfile import read_toml

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "scenes"


def engine_bay() -> None:
    scene = load_scene(EXAMPLES / "engine_bay.toml")
    planner = Planner(scene, scene.plan)
    tree = planner.tree(scene.plan.goal)
    hand = follow_path(scene.problem, scene.path, scene.grip, margin=scene.margin,
                       elements=scene.solver.elements)
    demands = [tree.demand(eq) for eq in hand.equilibria]
    print(f"engine bay, the hand-written path ({len(scene.path)} steps): peak force "
          f"{hand.peak('force')[0]:.2f} N, moment {hand.peak('moment')[0]:.3f} N m, hand "
          f"demand {max(demands[1:]):.2f} of the red onset (mean {np.mean(demands):.2f})")
    for attempts in (1, scene.plan.attempts):
        times, solves, forces, moments, peaks = [], [], [], [], []
        for seed in range(1, 6):
            settings = replace(scene.plan, seed=seed, attempts=attempts)
            begin = time.perf_counter()
            found = Planner(scene, settings).plan(settings.goal)
            times.append(time.perf_counter() - begin)
            solves.append(found.solves)
            forces.append(found.run.peak("force")[0])
            moments.append(found.run.peak("moment")[0])
            peaks.append(found.cost[0])
        print(f"engine bay, planned ({attempts} tree(s) a query, seeds 1-5): median "
              f"{statistics.median(times):.2f} s (min {min(times):.2f}, max "
              f"{max(times):.2f}; target <= 10 s), {statistics.median(solves):.0f} solves; "
              f"peak force {statistics.median(forces):.2f} N, moment "
              f"{statistics.median(moments):.3f} N m, hand demand "
              f"{statistics.median(peaks):.2f} (medians)")


def _obstacle(rng: np.random.Generator, k: int) -> dict:
    """A post, a box or a bar, somewhere between the start and the port."""
    at = [float(rng.uniform(0.08, 0.30)), float(rng.uniform(-0.12, 0.12)),
          float(rng.uniform(0.45, 0.75))]
    kind = rng.integers(3)
    if kind == 0:
        return {"name": f"post {k}", "shape": "cylinder",
                "radius": float(rng.uniform(0.03, 0.07)),
                "length": float(rng.uniform(0.4, 0.9)), "position": at,
                "axis": [0.0, 0.0, 1.0]}
    if kind == 1:
        return {"name": f"box {k}", "shape": "box",
                "size": [float(x) for x in rng.uniform(0.04, 0.16, 3)], "position": at}
    return {"name": f"bar {k}", "shape": "cylinder", "radius": float(rng.uniform(0.015, 0.04)),
            "length": float(rng.uniform(0.2, 0.5)), "position": at,
            "axis": [float(rng.uniform(-1, 1)), 0.0, float(rng.uniform(-0.3, 0.3))] if
            rng.random() < 0.5 else [0.0, 1.0, 0.0]}


def scenes(count: int) -> list[tuple[object, bool]]:
    """``count`` generated scenes and whether the straight move works in each; at least
    a third of them blocked."""
    base = read_toml(read_text(EXAMPLES / "hose_past_post.toml"), "hose_past_post.toml")
    rng = np.random.default_rng(2026)
    out, blocked = [], 0
    tries = 0
    while len(out) < count and tries < 50 * count:
        tries += 1
        data = dict(base)
        data["obstacle"] = [_obstacle(rng, k) for k in range(int(rng.integers(1, 4)))]
        if any(o["shape"] == "cylinder" and np.linalg.norm(o["axis"]) < 0.2
               for o in data["obstacle"]):
            continue
        scene = scene_from_data(data, "generated", EXAMPLES)
        planner = Planner(scene, scene.plan)
        seated, before = planner.goal_pose("port")
        try:
            tree = planner.tree("port")
        except InputError:
            continue  # the start is not clear of it
        if not planner._valid_state([*seated.position, 0.0, 0.0]):
            continue  # the port is inside it
        try:
            node = tree.carry(tree.root, (*before, tree.turning.length, 0.0))
            tree.turn_in(node, seated, near_port=True)
            straight = True
        except _Blocked:
            straight = False
        need = -(-count // 3) - blocked  # blocked scenes still wanted
        if straight and count - len(out) <= need:
            continue
        blocked += not straight
        out.append((scene, straight))
    return out


def _seated(scene) -> str:
    """Evidence for a failure: the seated pose solved afresh (its cold branch), and how
    close it comes to each obstacle."""
    from pliant.models import rod3d
    from pliant.scene.interference import of_equilibrium

    planner = Planner(scene, scene.plan)
    seated, _ = planner.goal_pose("port")
    tree = planner.tree("port")
    eq = rod3d.solve(tree.problem_at(seated.position, seated.tangent), solver=planner.solver)
    worst = min(of_equilibrium(eq).clearances, key=lambda c: c.clearance)
    return (f"the seated shape solved afresh comes {worst.clearance * 1e3:.1f} mm from "
            f"{worst.obstacle} (margin {scene.margin * 1e3:g} mm)")


def generated(count: int) -> None:
    made = scenes(count)
    blocked = sum(not straight for _, straight in made)
    print(f"\n{len(made)} generated scenes ({blocked} where the straight move is blocked), "
          "30 s budget, seed 1, one tree:")
    ok, times, solves = 0, [], []
    for k, (scene, straight) in enumerate(made):
        names = ", ".join(o.name for o in scene.problem.obstacles)
        begin = time.perf_counter()
        try:
            found = Planner(scene, replace(scene.plan, attempts=1)).plan("port")
        except NoPathError as err:
            print(f"  {k:2d} {'straight' if straight else 'blocked '} {names}: no path in "
                  f"{err.seconds:.1f} s ({err.solves} solves): "
                  f"{', '.join(list(err.blocked)[:2])}; {_seated(scene)}")
            continue
        seconds = time.perf_counter() - begin
        ok += 1
        times.append(seconds)
        solves.append(found.solves)
        print(f"  {k:2d} {'straight' if straight else 'blocked '} {names}: {seconds:.2f} s, "
              f"{found.solves} solves, {len(found.poses)} waypoints, peak force "
              f"{found.run.peak('force')[0]:.1f} N")
    if times:
        print(f"found {ok} of {len(made)}; median {statistics.median(times):.2f} s and "
              f"{statistics.median(solves):.0f} solves a plan (max {max(times):.2f} s); "
              "reference: 2.5-2.8 s median a query with a 500-milestone roadmap "
              "(Sintov et al. 2020)")


if __name__ == "__main__":
    engine_bay()
    generated(int(sys.argv[1]) if len(sys.argv) > 1 else 12)
