"""Readable and JSON summaries of an equilibrium (SI units)."""

from __future__ import annotations

import json
import math
import time
from typing import Any

from rich.console import Console
from rich.table import Table

from pliant.core.problem import Problem


def timed_solve(problem: Problem, elements: int = 100) -> tuple[Any, float]:
    """Solve, and time a second cold solve: the first one in a process also pays for
    loading the compiled kernels, which is not the solver's speed."""
    from pliant.models.dispatch import solve  # noqa: PLC0415

    solver = None
    if problem.dimension == 3:
        from pliant.models.rod3d import RodSolver  # noqa: PLC0415

        solver = RodSolver(elements=elements)
    eq = solve(problem, solver=solver)
    start = time.perf_counter()
    solve(problem, solver=solver)
    return eq, time.perf_counter() - start


def _fmt(value: float, unit: str) -> str:
    if math.isinf(value):
        return "inf"
    return f"{value:.6g} {unit}"


def print_summary(eq: Any, seconds: float, console: Console | None = None) -> None:
    console = console or Console()
    if eq.problem.dimension == 3:
        _summary_3d(eq, seconds, console)
        return
    problem = eq.problem
    x, y, angle = eq.tip
    console.print(f"[bold]{problem.name or 'problem'}[/bold]: solved in "
                  f"{seconds * 1e3:.2f} ms ({eq.iterations} Newton iterations, "
                  f"{eq.steps} continuation steps, relative residual {eq.residual:.1e})")
    console.print(f"tip (s = {problem.part.length:g} m): x = {_fmt(x, 'm')}, "
                  f"y = {_fmt(y, 'm')}, angle = {angle:.6g} rad ({math.degrees(angle):.2f} deg)")
    table = Table(title="loads on the part (global frame)", title_justify="left")
    for column in ("condition", "s [m]", "Fx [N]", "Fy [N]", "M [N m]", "kind"):
        table.add_column(column, justify="left" if column in ("condition", "kind")
                         else "right")
    for load in eq.loads.values():
        kind = ("reaction" if all(load.prescribed) else
                "reaction (" + ", ".join(n for n, p in zip(("Fx", "Fy", "M"), load.prescribed)
                                         if p) + ")" if any(load.prescribed) else "applied")
        table.add_row(load.name, f"{load.s:g}", f"{load.force[0]:.6g}",
                      f"{load.force[1]:.6g}", f"{load.moment:.6g}", kind)
    console.print(table)
    moment, at = eq.max_moment()
    console.print(f"max |M| = {_fmt(moment, 'N m')} at s = {at:.4g} m")
    radius, at = eq.min_bend_radius()
    line = f"smallest bend radius = {_fmt(radius, 'm')} at s = {at:.4g} m"
    allowed = problem.part.min_bend_radius
    if allowed is not None:
        verdict = "[red]below[/red]" if radius < allowed else "above"
        line += f" ({verdict} the part's minimum {allowed:g} m)"
    console.print(line)
    console.print(f"elastic energy = {_fmt(eq.energy, 'J')}")
    for note in eq.notes:
        console.print(f"note: {note}")


def _vec(v) -> str:
    return "(" + ", ".join(f"{x:.5g}" for x in v) + ")"


def _summary_3d(eq: Any, seconds: float, console: Console) -> None:
    problem = eq.problem
    console.print(f"[bold]{problem.name or 'problem'}[/bold] (3D, {eq.state.rod.elements} "
                  f"elements): solved in {seconds * 1e3:.2f} ms ({eq.iterations} Newton "
                  f"iterations, {eq.steps} continuation steps, residual {eq.residual:.1e})")
    position, tangent = eq.tip
    console.print(f"tip (s = {problem.part.length:g} m): position {_vec(position)} m, "
                  f"tangent {_vec(tangent)}")
    table = Table(title="loads on the part (global frame)", title_justify="left")
    for column in ("condition", "s [m]", "force [N]", "moment [N m]", "kind"):
        table.add_column(column)
    for load in eq.loads.values():
        names = ("Fx", "Fy", "Fz", "M (axis)", "M (twist)")
        kind = ("applied" if not any(load.prescribed) else "reaction (" + ", ".join(
            n for n, p in zip(names, load.prescribed) if p) + ")")
        table.add_row(load.name, f"{load.s:g}", _vec(load.force), _vec(load.moment), kind)
    console.print(table)
    moment, at = eq.max_moment()
    console.print(f"max |M| = {_fmt(moment, 'N m')} at s = {at:.4g} m; max |torque| = "
                  f"{_fmt(float(abs(eq.torque).max()), 'N m')}")
    radius, at = eq.min_bend_radius()
    line = f"smallest bend radius = {_fmt(radius, 'm')} at s = {at:.4g} m"
    allowed = problem.part.min_bend_radius
    if allowed is not None:
        verdict = "[red]below[/red]" if radius < allowed else "above"
        line += f" ({verdict} the part's minimum {allowed:g} m)"
    console.print(line)
    stable, eigen = eq.stability
    if stable is None:
        console.print("stability: not decided by a static test (follower loads or dead "
                      "moments make the problem non-conservative)")
    else:
        word = "stable" if stable else "[red]UNSTABLE[/red] (it would snap)"
        console.print(f"stability: {word}; smallest eigenvalue of the constrained "
                      f"Hessian {eigen:.4g} N m")
    console.print(f"elastic energy = {_fmt(eq.energy, 'J')}")
    for note in eq.notes:
        console.print(f"note: {note}")


def _finite(value: Any) -> Any:
    """JSON has no infinity: write null instead."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, list):
        return [_finite(v) for v in value]
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    return value


def print_json(eq: Any, seconds: float) -> None:
    data = eq.to_dict()
    data["solve_seconds"] = seconds
    print(json.dumps(_finite(data), indent=1, allow_nan=False))
