"""Benchmark of the scene layer and contact, in one run.

    .venv/bin/pip install -e '.[bench]'      # rtree, for trimesh's queries
    .venv/bin/python benchmarks/contact.py

(a) Signed distances of 200 points to a 50k-triangle mesh (a torus), the points within
a few tube radii of its surface (where contact is decided): pliant's exact query (box
tree, pseudonormal signs) and its grid answer (far points), against trimesh's
`proximity.signed_distance` (rtree, the library a user would reach for), with their
largest disagreement.
(b) A warm step of the 3D rod at 100 elements with contacts active (a hose's end lowered
onto a block), against the same steps without the block: the least disturbed of three
passes after a first (which also loads the kernels from numba's cache).
(c) The bundled engine-bay scene: its 100-step manipulation end to end (every step a warm
accurate solve with contact, its interference and stability checks).
(d) A real-time frame (50 control points, curve points held out of a drum) against the
same frame without the drum.
(e) `benchmarks/contact.py resolution`: (b)'s lowering at 100, 400 and 1,600 elements,
the Newton iterations per warm step (issue 20: they should not grow with N; since stop
39 they count a warm step's chord steps, on one factorisation, with its fresh ones) and
the hand's force at the end (its change with N: the discretisation's error).
(f) Friction while sliding: a hose lying along a bench (mu = 0.3), its end dragged
sideways in 5 mm steps, against the same drag on a frictionless bench.
Timings are machine-dependent; the ratios, measured in the same run, are the figures.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import numpy as np
import trimesh

import pliant as pl
from pliant.assembly import follow_path
from pliant.assembly.scenes import load_scene
from pliant.models import rod3d
from pliant.scene import DistanceField, Obstacle

ROOT = Path(__file__).resolve().parents[1]


def best(f, repeat: int = 20) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        f()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def distances() -> None:
    mesh = trimesh.creation.torus(0.3, 0.08, major_sections=400, minor_sections=64)
    print(f"(a) 200 points against a torus of {len(mesh.faces)} triangles")
    field = DistanceField([Obstacle.from_mesh("torus", mesh.vertices, mesh.faces)])
    rng = np.random.default_rng(0)
    on = mesh.sample(200, seed=1) if hasattr(mesh, "sample") else mesh.vertices[:200]
    near = on + rng.normal(scale=0.01, size=on.shape)  # within a few radii of a hose
    far = rng.uniform(-0.6, 0.6, size=(200, 3))
    field.query(near, band=0.02)  # compile and warm
    exact = best(lambda: field.query(near, band=0.05))
    grid = best(lambda: field.query(far, band=0.0))
    try:
        import rtree  # noqa: F401
    except ImportError:
        print("    trimesh needs rtree for its queries: pip install -e '.[bench]'")
        print(f"    pliant exact near the surface {exact * 1e3:.3f} ms, grid far "
              f"{grid * 1e3:.3f} ms")
        return
    theirs = -trimesh.proximity.signed_distance(mesh, near)  # trimesh: positive inside
    start = time.perf_counter()
    for _ in range(3):
        trimesh.proximity.signed_distance(mesh, near)
    t_trimesh = (time.perf_counter() - start) / 3
    ours, _, _ = field.query(near, band=0.05)
    print(f"    pliant exact (near): {exact * 1e3:.3f} ms   trimesh signed_distance: "
          f"{t_trimesh * 1e3:.1f} ms   ratio {t_trimesh / exact:.0f}x   largest "
          f"difference {np.abs(ours - theirs).max():.1e} m")
    print(f"    pliant grid (far points, bound {field.obstacles[0].mesh.g_size * 2.6:.1e} "
          f"m): {grid * 1e3:.3f} ms")


def warm_steps() -> None:
    print("(b) warm steps of the 3D rod, 100 elements: a hose's end lowered onto a block "
          "(it bends over the block's edge)")
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)
    block = Obstacle.box("block", (0.2, 0.2, 0.1), (0.7, 0.0, -0.12))

    def held(z: float, obstacles) -> pl.Problem:
        return pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                 pl.pin(1.0, position=(0.95, 0.0, z), name="hand")),
                          gravity=(0.0, 0.0, -9.81), obstacles=obstacles)

    heights = np.linspace(0.2, -0.15, 101)
    figures = {}
    for label, obstacles in (("with the block", (block,)), ("no obstacles", ())):
        # The first pass in a process also loads each kernel from numba's cache where it
        # is first called (some milliseconds, in the steps that first touch): the path
        # runs once first, then three times, and the least disturbed pass counts.
        passes = []
        for _ in range(4):
            eq = rod3d.solve(held(heights[0], obstacles))
            times, touching, iterations = [], [], []
            for z in heights[1:]:
                start = time.perf_counter()
                eq = rod3d.solve(held(z, obstacles), warm_start=eq)
                times.append(time.perf_counter() - start)
                touching.append(len(eq.contacts))
                iterations.append(eq.iterations)
            passes.append(([t for t, c in zip(times, touching) if c] or times, touching,
                           iterations))
        first = statistics.median(passes[0][0])
        on, touching, iterations = min(passes[1:], key=lambda p: statistics.median(p[0]))
        figures[label] = statistics.median(on)
        over = f"the {len(on)} steps touching" if obstacles else f"all {len(on)} steps"
        print(f"    {label}: {statistics.median(on) * 1e3:.2f} ms per step (median over "
              f"{over}; 90th percentile "
              f"{np.percentile(on, 90) * 1e3:.2f} ms, slowest {max(on) * 1e3:.1f} ms; "
              f"{statistics.median(iterations):.0f} Newton iterations; at most "
              f"{max(touching)} contact points; the first pass, kernels loading: "
              f"{first * 1e3:.2f} ms)")
    print(f"    contact costs {figures['with the block'] / figures['no obstacles']:.1f}x a "
          "free step")


def scene() -> None:
    bay = load_scene(ROOT / "examples" / "scenes" / "engine_bay.toml")
    follow_path(bay.problem, bay.path[:2], "hand", margin=bay.margin,
                elements=bay.solver.elements)  # load the kernels
    start = time.perf_counter()
    run = follow_path(bay.problem, bay.path, "hand", margin=bay.margin,
                      elements=bay.solver.elements)
    total = time.perf_counter() - start
    solve = sum(r.seconds for r in run.steps)
    print(f"(c) engine bay, {len(run.steps) - 1} steps at {bay.solver.elements} elements: "
          f"{total:.2f} s end to end ({total / len(run.steps) * 1e3:.1f} ms a step, of "
          f"which {solve / len(run.steps) * 1e3:.1f} ms solving); complete: {run.complete}")


def realtime() -> None:
    from pliant.models.realtime import RealtimeModel

    drum = Obstacle.cylinder("drum", 0.08, 0.4, (0.5, 0.0, -0.15),
                             [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)

    def held(z: float, obstacles) -> pl.Problem:
        return pl.Problem(hose, (pl.clamp(0.0, position=(0, 0, 0), tangent=(1, 0, 0),
                                          normal=(0, 0, 1)),
                                 pl.pin(1.0, position=(0.9, 0.0, z), name="hand")),
                          gravity=(0, 0, -9.81), obstacles=obstacles)

    figures = {}
    for label, obstacles in (("with the drum", (drum,)), ("no obstacles", ())):
        model = RealtimeModel(held(0.2, obstacles), control_points=50)
        model.retune(rod3d.solve(held(0.2, obstacles)))
        problems = [held(z, obstacles) for z in np.linspace(0.2, -0.3, 101)[1:]]
        model.frame(problems[0])
        times, touching = [], 0
        for problem in problems:
            start = time.perf_counter()
            frame = model.frame(problem)
            times.append(time.perf_counter() - start)
            touching += frame.contact_s.size > 0
        figures[label] = statistics.median(times)
        print(f"    {label}: {figures[label] * 1e3:.2f} ms a frame (network and tube mesh; "
              f"{touching} of 100 frames touching)")
    print(f"    contact costs {figures['with the drum'] / figures['no obstacles']:.1f}x a "
          "free frame")


def resolution(counts: tuple[int, ...] = (100, 400, 1600)) -> None:
    """(e) The same lowering onto the block at finer resolutions: Newton iterations per
    warm step (they should not grow with N), any step that fails, and the hand's force
    at the end (x and z), whose change with N is the discretisation's error. Over the
    block's sharp edge each element's slider holds the point nearest the edge, where
    the normal is square to the part (fixed probes leaned by up to half their spacing
    over the radius: 3 % at 100 elements)."""
    from pliant.errors import PliantError

    print("(e) the hose's end lowered onto the block at", ", ".join(map(str, counts)),
          "elements: Newton iterations per warm step")
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)
    block = Obstacle.box("block", (0.2, 0.2, 0.1), (0.7, 0.0, -0.12))
    for count in counts:
        solver = rod3d.RodSolver(elements=count)

        def held(z: float) -> pl.Problem:
            return pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                     pl.pin(1.0, position=(0.95, 0.0, z), name="hand")),
                              gravity=(0.0, 0.0, -9.81), obstacles=(block,))

        heights = np.linspace(0.2, -0.15, 101)
        eq = rod3d.solve(held(heights[0]), solver=solver)
        iterations, touching, failed = [], [], None
        start = time.perf_counter()
        for step, z in enumerate(heights[1:], start=1):
            try:
                eq = rod3d.solve(held(z), warm_start=eq, solver=solver)
            except PliantError as err:
                failed = f"step {step} failed: {str(err)[:80]}"
                break
            iterations.append(eq.iterations)
            if len(eq.contacts):
                touching.append(eq.iterations)
        force = eq.reactions["hand"].force
        print(f"    {count:5d} elements: {len(iterations)} steps, iterations median "
              f"{statistics.median(iterations):.1f} "
              f"(touching {statistics.median(touching or [0]):.1f}), "
              f"max {max(iterations)}; {time.perf_counter() - start:.1f} s; the hand's "
              f"force at the end ({force[0]:.4f}, {force[2]:.4f}) N"
              + (f"; {failed}" if failed else ""))


def sliding(steps: int = 40) -> None:
    """(f) A warm step with Coulomb friction while the part slides along a face."""
    print("(f) warm steps with friction, 100 elements: a hose lying along a bench, its end "
          "dragged sideways in 5 mm steps")
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)

    def held(y: float, mu: float) -> pl.Problem:
        bench = Obstacle.box("bench", (0.6, 0.6, 0.1), (0.5, 0.0, -0.11)).with_friction(mu)
        return pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0), tangent=(1, 0, 0),
                                          normal=(0, 0, 1)),
                                 pl.pin(1.0, position=(0.95 - 0.3 * y, y, 0.0), name="hand")),
                          gravity=(0.0, 0.0, -9.81), obstacles=(bench,))

    figures = {}
    for label, mu in (("mu = 0.3", 0.3), ("frictionless", 0.0)):
        eq = rod3d.solve(held(0.0, mu))
        eq = rod3d.solve(held(0.005, mu), warm_start=eq)  # friction builds up: not timed
        times, iterations, slide = [], [], []
        for y in 0.005 * np.arange(2, steps + 2):
            start = time.perf_counter()
            eq = rod3d.solve(held(y, mu), warm_start=eq)
            times.append(time.perf_counter() - start)
            iterations.append(eq.iterations)
            if mu:
                c = eq.contacts
                normal = np.linalg.norm(c.force - c.friction, axis=1)
                slide.append(np.mean(np.linalg.norm(c.friction, axis=1) > mu * normal
                                     * (1.0 - 1e-6)))
        figures[label] = statistics.median(times)
        extra = (f"; {100 * statistics.median(slide):.0f} % of the contacts sliding"
                 if slide else "")
        print(f"    {label}: {statistics.median(times) * 1e3:.2f} ms per step (median; 90th "
              f"percentile {np.percentile(times, 90) * 1e3:.2f} ms, slowest "
              f"{max(times) * 1e3:.1f} ms; {statistics.median(iterations):.0f} Newton "
              f"iterations{extra})")
    print(f"    friction costs {figures['mu = 0.3'] / figures['frictionless']:.1f}x a "
          "frictionless step")


if __name__ == "__main__":
    import sys

    if sys.argv[1:] == ["resolution"]:  # (e) alone: it takes a minute
        resolution()
        raise SystemExit
    if sys.argv[1:] == ["sliding"]:  # (f) alone
        sliding()
        raise SystemExit
    distances()
    warm_steps()
    scene()
    print("(d) real-time frames, 50 control points, a hose's end lowered past a drum")
    realtime()
    sliding()
