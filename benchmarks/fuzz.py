"""Random problems, each answer checked independently of pliant's own residual.

2D (the elastica): clamped parts under random end loads (force space), and parts held
by a clamp or a pin and a hand at a random reachable target (configuration space), with
weight and rest curvature. Each equilibrium is checked by integrating the ODE again from
s = 0 with scipy's solve_ivp (x' = cos theta, y' = sin theta, theta' = kappa0 + M / EI,
n' = -q, M' = -(t x n)), applying every condition's load (reactions included) as a jump
at its station: the integrated shape must follow the returned one, every prescribed
value must hold, and past the last station nothing may be left over (n = 0, M = 0).

3D (the Kirchhoff rod): a clamp and a hand at a random reachable pose (position, and
axis or not), with weight, rest curvature and sometimes a ball to avoid. Each is checked
by global balance of forces and moments (conditions, weight and contacts), the
prescribed positions and axes, inextensibility (every element its rest length) and the
tube outside the ball.

    .venv/bin/python benchmarks/fuzz.py [N2D] [N3D] [NFLOPPY]

NFLOPPY (200 by default) floppy cables, clamped at one end or held at a target
(``problem_floppy``), checked as the 2D ones.

It prints, per family: tried, converged and checked right, converged but wrong, typed
errors, untyped exceptions, and runs slower than the solver's budget; and the index of
each problem refused or wrong in its model's sequence (seed 1: ``problem_2d`` or
``problem_3d`` called that many times before it), so that one can be looked at again.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter, defaultdict

import numpy as np

import pliant as pl
from pliant.errors import PliantError

BUDGET = 20.0  # s: a solve past this counts as a timeout
WORST: dict[str, float] = defaultdict(float)  # the largest error of a converged answer
REFUSED: dict[str, list[int]] = defaultdict(list)  # the indices of typed errors and wrong answers
TIMES: dict[str, list[float]] = defaultdict(list)  # each converged solve's seconds


def random_part(rng: np.random.Generator, three: bool) -> pl.Part:
    length = float(rng.uniform(0.3, 2.0))
    stiffness = float(10 ** rng.uniform(-2, 1))
    mass = float(rng.choice([0.0, 10 ** rng.uniform(-2, 0)]))
    curvature: float | tuple = 0.0
    kind = rng.integers(3)
    if kind == 1:
        curvature = float(rng.uniform(-2, 2) / length)
    elif kind == 2:
        knots = np.sort(rng.uniform(0, length, 2))
        curvature = tuple((float(s), float(rng.uniform(-2, 2) / length)) for s in knots)
    return pl.Part(length, stiffness, mass_per_length=mass, rest_curvature=curvature,
                   outer_diameter=0.01 * length if three else None)


def problem_2d(rng: np.random.Generator) -> tuple[str, pl.Problem]:
    part = random_part(rng, False)
    L = part.length
    gravity = (0.0, -9.81) if part.mass_per_length else None
    if rng.random() < 0.4:
        scale = part.bending_stiffness / L**2
        force = tuple(float(x) for x in rng.uniform(-10, 10, 2) * scale)
        moment = float(rng.uniform(-3, 3) * part.bending_stiffness / L)
        return "2D force space", pl.Problem(
            part, (pl.clamp(0.0), pl.push(L, force=force, moment=moment)), gravity=gravity)
    return "2D configuration space", held(
        rng, part, lambda g: pl.clamp(0.0) if g.random() < 0.7 else pl.pin(0.0), gravity)


def held(rng: np.random.Generator, part: pl.Part, start_of, gravity) -> pl.Problem:
    """The part held by ``start_of(rng)`` at s = 0 and a hand at its end at a random
    target within reach (0.05 to 0.9 of the area of the disc of radius L), its angle
    held or free (held where the start holds none)."""
    L = part.length
    r = L * math.sqrt(rng.uniform(0.05, 0.9))
    a = rng.uniform(-math.pi, math.pi)
    target = (float(r * math.cos(a)), float(r * math.sin(a)))
    start = start_of(rng)
    angle = float(rng.uniform(-math.pi, math.pi)) if rng.random() < 0.5 else None
    if start.angle is None and angle is None:
        angle = float(rng.uniform(-math.pi, math.pi))
    return pl.Problem(part, (start, pl.grip(L, position=target, angle=angle, name="hand")),
                      gravity=gravity)


def problem_floppy(rng: np.random.Generator) -> tuple[str, pl.Problem]:
    """A floppy cable (q L^3 / EI from 1e3 to 6.6e5, log-uniform: with an end load of up
    to half the weight the loads' wavenumber stays within the model's k L = 1000).
    Half of them clamped at one end at any angle and hanging, half of those with such an
    end load (force space: until stop 49 a cable from q L^3 / EI = 3e5 on stopped at "a
    fold" that is not there); half held by a clamp at any angle or a pin and a hand at a
    random reachable target (configuration space, as ``problem_2d``'s)."""
    length = float(rng.uniform(0.5, 10.0))
    stiffness = float(10 ** rng.uniform(-2, 1))
    q = float(10 ** rng.uniform(3, np.log10(6.6e5))) * stiffness / length**3
    part = pl.Part(length, stiffness, mass_per_length=q / 9.81)
    gravity = (0.0, -9.81)
    if rng.random() < 0.5:
        conditions = [pl.clamp(0.0, angle=float(rng.uniform(-math.pi, math.pi)))]
        if rng.random() < 0.5:
            direction = rng.normal(size=2)
            force = direction / np.linalg.norm(direction) * rng.uniform(0.0, 0.5) * q * length
            conditions.append(pl.push(length, force=tuple(float(f) for f in force),
                                      name="tip"))
        return "2D floppy cable, clamped", pl.Problem(part, tuple(conditions),
                                                      gravity=gravity)
    return "2D floppy cable, held", held(
        rng, part, lambda g: (pl.clamp(0.0, angle=float(g.uniform(-math.pi, math.pi)))
                              if g.random() < 0.5 else pl.pin(0.0)), gravity)


def check_2d(eq) -> float:
    """The independent 2D check (``pliant.models.elastica2d.reference.equilibrium_error``:
    the ODE integrated again with solve_ivp sample to sample, the jumps at the stations,
    the prescribed values)."""
    from pliant.models.elastica2d.reference import equilibrium_error

    return equilibrium_error(eq)


def problem_3d(rng: np.random.Generator) -> tuple[str, pl.Problem]:
    from pliant.scene.distance import Obstacle

    part = random_part(rng, True)
    L = part.length
    r = L * rng.uniform(0.3, 0.9)
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    target = tuple(float(x) for x in r * direction)
    tangent = None
    if rng.random() < 0.6:
        t = rng.normal(size=3)
        tangent = tuple(float(x) for x in t / np.linalg.norm(t))
    obstacles = ()
    family = "3D"
    if rng.random() < 0.3:
        centre = 0.5 * np.array(target) + rng.normal(size=3) * 0.2 * L
        radius = 0.1 * L
        if np.linalg.norm(centre) > radius + 0.05 * L and np.linalg.norm(
                centre - np.array(target)) > radius + 0.05 * L:
            obstacles = (Obstacle.sphere("ball", radius, tuple(float(x) for x in centre)),)
            family = "3D with a ball"
    return family, pl.Problem(
        part, (pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0), normal=(0, 0, 1)),
               pl.grip(L, target, tangent=tangent, name="hand")),
        gravity=(0.0, 0.0, -9.81), obstacles=obstacles)


def check_3d(eq) -> float:
    problem = eq.problem
    part = problem.part
    L, EI = part.length, part.bending_stiffness
    q = part.mass_per_length * np.array(problem.gravity, float)
    x = eq.position
    ds = np.diff(eq.s)
    mid = 0.5 * (x[1:] + x[:-1])
    force = q * L + sum(ld.force for ld in eq.loads.values())
    moment = np.cross(mid, q[None, :] * ds[:, None]).sum(axis=0)
    for ld in eq.loads.values():
        k = int(np.argmin(np.abs(eq.s - ld.s)))
        moment = moment + np.cross(x[k], ld.force) + ld.moment
    c = eq.contacts
    if len(c):
        force = force + c.force.sum(axis=0)
        moment = moment + np.cross(c.point, c.force).sum(axis=0)
    errors = [np.abs(force).max() / (EI / L**2), np.abs(moment).max() / (EI / L)]
    lengths = np.linalg.norm(np.diff(x, axis=0), axis=1)
    errors.append(np.abs(lengths - ds).max() / L)
    for cond in problem.conditions:
        k = int(np.argmin(np.abs(eq.s - cond.s)))
        for i in range(3):
            if cond.position[i] is not None:
                errors.append(abs(x[k, i] - cond.position[i]) / L)
        if cond.tangent is not None:
            errors.append(float(np.linalg.norm(eq.tangent[k] - np.array(cond.tangent))))
    if problem.obstacles:
        from pliant.scene.interference import of_equilibrium

        gap = of_equilibrium(eq).smallest.clearance
        errors.append(max(0.0, -gap - 0.01 * 0.5 * part.outer_diameter) / L)
    return float(max(errors))


def run(kind: str, count: int, seed: int, tolerance: float) -> dict[str, Counter]:
    rng = np.random.default_rng(seed)
    table: dict[str, Counter] = defaultdict(Counter)
    solver = None
    if kind == "3D":
        solver = pl.RodSolver(elements=40)
    make = {"2D": problem_2d, "3D": problem_3d, "2D floppy": problem_floppy}[kind]
    for index in range(count):
        family, problem = make(rng)
        row = table[family]
        row["tried"] += 1
        start = time.perf_counter()
        try:
            eq = pl.solve(problem, solver=solver)
            TIMES[family].append(time.perf_counter() - start)
            error = check_3d(eq) if kind == "3D" else check_2d(eq)
        except PliantError:
            row["typed error"] += 1
            REFUSED[family].append(index)
            continue
        except Exception:
            row["untyped"] += 1
            continue
        finally:
            if time.perf_counter() - start > BUDGET:
                row["timeout"] += 1
        WORST[family] = max(WORST[family], error)
        row["right" if error < tolerance else "wrong"] += 1
        if error >= tolerance:
            REFUSED[family].append(index)
    return table


def main() -> None:
    n2 = int(sys.argv[1]) if len(sys.argv) > 1 else 3000
    n3 = int(sys.argv[2]) if len(sys.argv) > 2 else 2000
    floppy = int(sys.argv[3]) if len(sys.argv) > 3 else 200
    print(f"{'family':26s} {'tried':>6s} {'right':>6s} {'wrong':>6s} {'typed':>6s} "
          f"{'untyped':>8s} {'timeout':>8s}  converged")
    for kind, count, tolerance in (("2D", n2, 1e-6), ("3D", n3, 1e-6),
                                   ("2D floppy", floppy, 1e-6)):
        start = time.perf_counter()
        for family, row in sorted(run(kind, count, 1, tolerance).items()):
            done = row["right"] + row["wrong"]
            print(f"{family:26s} {row['tried']:6d} {row['right']:6d} {row['wrong']:6d} "
                  f"{row['typed error']:6d} {row['untyped']:8d} {row['timeout']:8d}  "
                  f"{done / max(row['tried'], 1):.1%} (worst error {WORST[family]:.1e})")
            took = np.array(TIMES[family]) * 1e3
            if took.size:  # each answer's solve (not its check): the tail is the long paths
                print(f"    solve time: median {np.median(took):.1f} ms, 90th percentile "
                      f"{np.percentile(took, 90):.1f} ms, slowest {took.max():.0f} ms, "
                      f"all {took.sum() / 1e3:.1f} s")
            if REFUSED[family]:  # to look at one again: the same seed, the same index
                print(f"    refused or wrong, by index of the {kind} sequence: "
                      f"{REFUSED[family]}")
        print(f"  ({kind}: {time.perf_counter() - start:.0f} s)")


if __name__ == "__main__":
    main()
