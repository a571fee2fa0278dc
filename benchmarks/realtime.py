"""Benchmark of the real-time model and its coupling, in one run.

    .venv/bin/python benchmarks/realtime.py [--steps N]

(a) Frame cost: the bar network moved to a new grip pose (length-keeping Newton) plus the
tube mesh (64 rings of 16 vertices, 2,048 triangles), for 20, 50 and 100 control points,
along a hand's path in 2D and 3D; beside it, what a user would do without a real-time
model: a warm-started accurate solve per frame plus the same tube mesh.
(b) Latency from a grip event to the accurate forces of that pose in a live session (the
accurate model in its worker process), 2D and 3D, after one event that loads the
worker's kernels.
(c) The real-time shape against the accurate one along a 100-step manipulation: retuned
only once at the start, and coupled (a session retuning whenever drift passes 2% L).
Timings are machine-dependent; the ratios, measured in the same run, are the figures.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

import pliant as pl
from pliant.core.tube import rotation_minimizing_frames, tube_vertices
from pliant.models.realtime import RealtimeModel
from pliant.session import GripEvent, Session

HOSE = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3, outer_diameter=0.02)


def hose(t: float, dimension: int) -> pl.Problem:
    """A hose clamped at the origin, its end carried from (0.9, 0, 0) toward
    (0.55, 0.3, 0.2) as t goes from 0 to 1 (2D: in the x-y plane, gravity -y)."""
    end = (0.9 - 0.35 * t, 0.3 * t, 0.2 * t)[:dimension]
    origin = (0.0,) * dimension
    gravity = (0.0, 0.0, -9.81) if dimension == 3 else (0.0, -9.81)
    return pl.Problem(HOSE, (pl.clamp(0.0, position=origin),
                             pl.pin(1.0, position=end, name="hand")), gravity=gravity)


def frame_cost(dimension: int, count: int, steps: int) -> float:
    """Median seconds per real-time frame along the path."""
    model = RealtimeModel(hose(0.0, dimension), control_points=count)
    model.retune(pl.solve(hose(0.0, dimension)))
    path = [hose(t, dimension) for t in np.linspace(0.0, 0.3, steps)]
    model.frame(path[0])
    times = []
    for problem in path:
        start = time.perf_counter()
        model.frame(problem)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def accurate_per_frame(dimension: int, steps: int) -> float:
    """Median seconds per frame when every frame is a warm-started accurate solve and
    its tube mesh (the alternative to a real-time model)."""
    path = [hose(t, dimension) for t in np.linspace(0.0, 0.3, steps)]
    eq = pl.solve(path[0])
    times = []
    for problem in path:
        start = time.perf_counter()
        eq = pl.solve(problem, warm_start=eq)
        position = np.asarray(eq.position)
        if dimension == 2:
            position = np.column_stack([position, np.zeros(position.shape[0])])
        keep = np.concatenate([[True], np.diff(eq.s) > 0])
        points = position[keep]
        frames = rotation_minimizing_frames(points)
        tube_vertices(points, 0.01, frames, 16)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def latency(dimension: int, events: int) -> tuple[float, float]:
    """(median, max) seconds from a grip event to the accurate forces of its pose."""
    waits = []
    with Session(hose(0.0, dimension), live=True, control_points=50) as session:
        # One event first: the worker loads the kernels of a warm step once.
        session.request_accurate()
        session.apply(GripEvent("hand", position=hose(0.005, dimension)
                                .condition("hand").position))
        session.wait(timeout=60.0)
        for t in np.linspace(0.01, 0.5, events):
            session.request_accurate()
            start = time.perf_counter()
            frame = session.apply(GripEvent("hand", position=hose(t, dimension)
                                            .condition("hand").position))
            index = frame.index
            while session.accurate.index != index:
                session.wait(timeout=10.0)
            waits.append(time.perf_counter() - start)
    return statistics.median(waits), max(waits)


def shape_errors(dimension: int, steps: int) -> tuple[tuple[float, float], tuple[float, float],
                                                       int]:
    """((max, mean) error retuned once, (max, mean) error coupled, accurate solves) of the
    real-time curve against the accurate shape at each pose, relative to L."""
    path = [hose(t, dimension) for t in np.linspace(0.01, 1.0, steps)]
    truths = list(pl.trace(path, start=pl.solve(hose(0.0, dimension))))

    def error(curve: np.ndarray, eq) -> float:
        keep = np.concatenate([[True], np.diff(eq.s) > 0])
        s, x = eq.s[keep], eq.position[keep]
        ref = np.column_stack([np.interp(np.linspace(0, 1, curve.shape[0]), s, x[:, k])
                               for k in range(dimension)])
        return float(np.linalg.norm(curve[:, :dimension] - ref, axis=1).max())

    once = RealtimeModel(hose(0.0, dimension), control_points=50)
    once.retune(pl.solve(hose(0.0, dimension)))
    frozen = [error(once.frame(p).curve, eq) for p, eq in zip(path, truths)]
    events = [GripEvent("hand", position=p.condition("hand").position) for p in path]
    with Session(hose(0.0, dimension), control_points=50) as session:
        frames = [session.apply(e) for e in events]
        solves = len(session.solves) - 1
    coupled = [error(f.realtime.curve, eq) for f, eq in zip(frames, truths)]
    return ((max(frozen), float(np.mean(frozen))), (max(coupled), float(np.mean(coupled))),
            solves)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    args = parser.parse_args()
    print(f"pliant {pl.__version__}, python {sys.version.split()[0]}, {os.cpu_count()} cpus\n")
    print("(a) frame cost: network + tube mesh of 2,048 triangles (median over "
          f"{args.steps} frames)")
    for dimension in (2, 3):
        alternative = accurate_per_frame(dimension, args.steps)
        for count in (20, 50, 100):
            cost = frame_cost(dimension, count, args.steps)
            print(f"    {dimension}D, {count:3d} control points: {cost * 1e3:.3f} ms "
                  f"({1.0 / cost:,.0f} frames/s)")
        print(f"    {dimension}D, a warm accurate solve + mesh per frame instead: "
              f"{alternative * 1e3:.3f} ms")
    print("\n(b) latency from a grip event to its accurate forces (live session, worker "
          "process)")
    for dimension in (2, 3):
        median, worst = latency(dimension, 40)
        print(f"    {dimension}D: median {median * 1e3:.2f} ms, max {worst * 1e3:.2f} ms")
    print("\n(c) real-time shape against the accurate one, 100-step manipulation (largest "
          "distance along the part, in L)")
    for dimension in (2, 3):
        (fmax, fmean), (cmax, cmean), solves = shape_errors(dimension, 100)
        print(f"    {dimension}D: retuned once: max {fmax:.4f} mean {fmean:.4f}; coupled "
              f"(retuned when drift > 2% L, {solves} accurate solves): max {cmax:.4f} "
              f"mean {cmean:.4f}")


if __name__ == "__main__":
    main()
