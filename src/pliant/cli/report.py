"""Readable and JSON summaries of an equilibrium (SI units)."""

from __future__ import annotations

import json
import math
import time
from typing import Any

import numpy as np
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from pliant.assembly.checks import max_torque, shape_warnings
from pliant.core.equilibrium import Equilibrium, Equilibrium3D, Result, stretch_summary
from pliant.core.events import BRANCHED, SolvedTogether
from pliant.core.numbers import clean
from pliant.core.problem import Problem
from pliant.io.jsontext import finite


def timed_solve(problem: Problem, elements: int = 100) -> tuple[Result, float]:
    """Solve, timed without the first load of the compiled kernels (which is not the
    solver's speed): a coarse copy of the problem loads them first (8 elements in 3D,
    a few milliseconds; in 2D the problem itself, which costs about as little), then the
    problem is solved once, timed."""
    from pliant.errors import PliantError  # noqa: PLC0415
    from pliant.models.dispatch import solve  # noqa: PLC0415

    solver = coarse = None
    if problem.dimension == 3:
        from pliant.models.rod3d import RodSolver  # noqa: PLC0415

        solver, coarse = RodSolver(elements=elements), RodSolver(elements=8, time_budget=2.0)
    try:
        solve(problem, solver=coarse)
    except PliantError:
        pass  # it only loaded the kernels; the timed solve says what is wrong
    start = time.perf_counter()
    eq = solve(problem, solver=solver)
    return eq, time.perf_counter() - start


def count(n: int, noun: str, plural: str | None = None) -> str:
    """'1 obstacle', '3 obstacles'."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def _fixed(value: float, digits: int) -> str:
    """``value`` with ``digits`` decimals, a value that rounds to zero as 0 (not -0.00)."""
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def _fmt(value: float, unit: str) -> str:
    if math.isinf(value):
        return "inf"
    return f"{value:.6g} {unit}"


def print_summary(eq: Result, seconds: float, console: Console | None = None,
                  report: Any = None) -> None:
    """An answer in words and tables, then its warnings (``checks.shape_warnings``, the
    viewer's words); ``report``: its interference report, for what it enters."""
    console = console or Console()
    if isinstance(eq, Equilibrium3D):
        _summary_3d(eq, seconds, console)
    elif isinstance(eq, Equilibrium):
        _summary_2d(eq, seconds, console)
    radius, at = eq.min_bend_radius()
    stable, eigen = eq.stability
    for warning in shape_warnings(bend_radius=radius, bend_at=at,
                                  allowed=_bend_limit(eq.problem.part),
                                  stable=stable,
                                  eigenvalue=eigen,
                                  penetrations=() if report is None else report.penetrations):
        console.print(f"[red]warning[/red]: {escape(warning)}")


def _summary_2d(eq: Equilibrium, seconds: float, console: Console) -> None:
    problem = eq.problem
    x, y, angle = eq.tip
    console.print(f"[bold]{problem.name or 'problem'}[/bold]: solved in "
                  f"{seconds * 1e3:.2f} ms ({eq.iterations} Newton iterations, "
                  f"{eq.steps} continuation steps, relative residual {eq.residual:.1e})")
    console.print(f"tip (s = {problem.part.length:g} m): x = {_fmt(x, 'm')}, "
                  f"y = {_fmt(y, 'm')}, angle = {angle:.6g} rad ({math.degrees(angle):.2f} deg)")
    table = Table(title="loads on the part (global frame)", title_justify="left")
    for column in ("condition", "s [m]", "Fx [N]", "Fy [N]", "M [N m]", "kind"):
        table.add_column(escape(column), justify="left" if column in ("condition", "kind")
                         else "right")
    for load in eq.loads.values():
        kind = ("reaction" if all(load.prescribed) else
                "reaction (" + ", ".join(n for n, p in zip(("Fx", "Fy", "M"), load.prescribed)
                                         if p) + ")" if any(load.prescribed) else "applied")
        table.add_row(escape(load.name), f"{load.s:g}", f"{load.force[0]:.6g}",
                      f"{load.force[1]:.6g}", f"{load.moment:.6g}", kind)
    console.print(table)
    moment, at = eq.max_moment()
    console.print(f"max |M| = {_fmt(moment, 'N m')} at s = {at:.4g} m")
    console.print(_bend_radius_line(eq))
    _print_stretch(eq, console)
    console.print(_stability_line(eq))
    console.print(f"elastic energy = {_fmt(eq.energy, 'J')}")
    for note in eq.notes:
        console.print(f"note: {note}")


def _stability_line(eq: Result) -> str:
    """The stability verdict in words, with the smallest eigenvalue."""
    verdict = eq.verdict
    together = [n for n in eq.notes if isinstance(n, SolvedTogether)]
    if verdict == "undecided" and (together or (
            isinstance(eq, Equilibrium3D) and (eq.fitted or eq.branches))):
        why = ("the eigenvalue did not converge" if together and together[0].assessed
               else "friction or non-conservative loads between parts solved together")
        return f"stability: not assessed ({why}; see the note)"
    if verdict == "undecided":
        why = ("follower loads" if eq.problem.dimension == 2
               else "follower loads or dead moments")
        return f"stability: not decided by a static test ({why} make it non-conservative)"
    eigen = eq.stability[1]
    word = {"stable": "stable", "unstable": "[red]UNSTABLE[/red] (it would snap)",
            "neutral": "[yellow]neutral[/yellow] (a mode that costs no energy: the part "
                       "can drift along a family of equilibria)"}[verdict]
    what = "Hessian" if eq.problem.dimension == 3 else "second variation"
    if together:  # (assessed: the verdict of every part solved together at once)
        what += " of the parts together"
    elif verdict == "neutral" and isinstance(eq, Equilibrium3D):
        from pliant.models.rod3d.results import describe_mode  # noqa: PLC0415

        word += f"; its free mode: {describe_mode(eq)}"
    return f"stability: {word}; smallest eigenvalue of the constrained {what} {eigen:.4g} N m"


def _print_stretch(eq: Result, console: Console) -> None:
    """An extensible part's elongation and largest axial force and strain, against the
    strain it tolerates."""
    stretch = stretch_summary(eq)
    if stretch is None:
        return
    strain = stretch["max_axial_strain"]
    line = (f"stretch: {stretch['elongation'] * 1e3:+.4g} mm longer; largest axial force "
            f"{_fmt(stretch['max_axial_force'], 'N')} (strain {strain * 100:.3g} %) at s = "
            f"{stretch['at']:.4g} m")
    allowed = eq.problem.part.max_axial_strain
    if allowed is not None:
        verdict = "[red]above[/red]" if abs(strain) > allowed else "within"
        line += f" ({verdict} the part's allowed {allowed * 100:g} %)"
    console.print(line)


def _bend_radius_line(eq: Result) -> str:
    """The smallest bend radius, where, and against the part's minimum."""
    radius, at = eq.min_bend_radius()
    line = f"smallest bend radius = {_fmt(radius, 'm')} at s = {at:.4g} m"
    allowed = _bend_limit(eq.problem.part)
    if allowed is not None:
        verdict = "[red]below[/red]" if radius < allowed else "above"
        line += f" ({verdict} the part's limit {_fmt(allowed, 'm')}, centreline)"
    return line


def vector_text(v, scale: float = 0.0) -> str:
    """A vector in 5 figures, its round-off printed as 0: components below 1e-9 of the
    larger of its own size and ``scale`` (the problem's force or moment scale)."""
    return "(" + ", ".join(f"{x:.5g}" for x in clean(v, scale)) + ")"


def _summary_3d(eq: Equilibrium3D, seconds: float, console: Console) -> None:
    problem = eq.problem
    console.print(f"[bold]{problem.name or 'problem'}[/bold] (3D, {len(eq.s) - 1} "
                  f"elements): solved in {seconds * 1e3:.2f} ms ({eq.iterations} Newton "
                  f"iterations, {eq.steps} continuation steps, residual {eq.residual:.1e})")
    position, tangent = eq.tip
    part = problem.part
    length, forces, moments = (part.length, part.bending_stiffness / part.length**2,
                               part.bending_stiffness / part.length)
    console.print(f"tip (s = {length:g} m): position {vector_text(position, length)} m, "
                  f"tangent {vector_text(tangent, 1.0)}")
    table = Table(title="loads on the part (global frame)", title_justify="left")
    for column in ("condition", "s [m]", "force [N]", "moment [N m]", "kind"):
        table.add_column(escape(column))
    for load in eq.loads.values():
        names = ("Fx", "Fy", "Fz", "M (axis)", "M (twist)")
        kind = ("applied" if not any(load.prescribed) else "reaction (" + ", ".join(
            n for n, p in zip(names, load.prescribed) if p) + ")")
        table.add_row(escape(load.name), f"{load.s:g}", vector_text(load.force, forces),
                      vector_text(load.moment, moments), kind)
    console.print(table)
    moment, at = eq.max_moment()
    console.print(f"max |M| = {_fmt(moment, 'N m')} at s = {at:.4g} m; max |torque| = "
                  f"{_fmt(max_torque(eq), 'N m')}")
    console.print(_bend_radius_line(eq))
    _print_stretch(eq, console)
    print_contacts(eq, console)
    _print_others(eq, console)
    console.print(_stability_line(eq))
    console.print(f"elastic energy = {_fmt(eq.energy, 'J')}")
    for note in eq.notes:
        console.print(f"note: {note}")


def _print_others(eq: Result, console: Console) -> None:
    """The parts solved with this one (a harness's branches, flexible parts it touched):
    what holds each of them (their clamps' reactions), and what they take from it."""
    for kind, key in (("branch", "branches"), ("fitted part", "fitted")):
        for other in getattr(eq, key, ()):
            name = other.problem.name or other.problem.part.name
            rows = ", ".join(f"{load.name}: {vector_text(load.force)} N" for load in
                             other.loads.values() if load.is_reaction)
            console.print(f"{kind} {name!r}: {rows}")


def solve_json(eq: Result, seconds: float, interference: Any = None) -> str:
    """The answer of ``pliant solve`` as JSON text (non-finite numbers as null)."""
    data = eq.to_dict()
    if isinstance(eq, Equilibrium3D) and eq.verdict == "neutral":
        from pliant.models.rod3d.results import describe_mode  # noqa: PLC0415

        data["neutral_mode"] = describe_mode(eq)
    data["solve_seconds"] = seconds
    for key in ("branches", "fitted"):
        others = getattr(eq, key, ())  # (3D answers solved with other parts)
        if others:
            data[key] = [{"name": o.problem.name or o.problem.part.name,
                          "loads": [load.to_dict() for load in o.loads.values()],
                          "position": o.position.tolist()} for o in others]
    if interference is not None:
        data["interference"] = interference.to_dict()
    return json.dumps(finite(data), indent=1, allow_nan=False)


def print_contacts(eq: Equilibrium3D, console: Console) -> None:
    """What each obstacle applies to a 3D equilibrium's part, and at how many points."""
    for name, force in eq.contacts.by_obstacle().items():
        points = sum(1 for o in eq.contacts.obstacle if o == name)
        console.print(f"contact: {name} pushes on the part with {np.linalg.norm(force):.3g} "
                      f"N, {vector_text(force)} N ({points} points)")


def print_interference(report: Any, console: Console | None = None) -> None:
    """The clearance of the part to each obstacle, and what is too close or inside."""
    console = console or Console()
    if not report.clearances:
        console.print("clearance: the scene has no obstacles")
        return
    table = Table(title=f"clearance to the obstacles (margin {report.margin * 1e3:g} mm)",
                  title_justify="left")
    for column in ("obstacle", "smallest clearance [mm]", "at s [m]"):
        table.add_column(escape(column))  # ("[mm]" and "[m]" would read as markup)
    for c in report.clearances:
        style = "red" if c.clearance < -report.tolerance else (
            "yellow" if c.clearance < report.margin else "")
        text = ("0 (touching)" if abs(c.clearance) <= report.tolerance
                else f"{c.clearance * 1e3:.2f}")
        table.add_row(escape(c.obstacle), f"[{style}]{text}[/{style}]" if style else text,
                      f"{c.s:.4g}")
    console.print(table)
    for span in report.penetrations:
        console.print(f"[red]penetrates[/red] {span.obstacle} over s = {span.s_start:.4g} "
                      f"to {span.s_end:.4g} m, {-span.worst * 1e3:.2f} mm deep at "
                      f"s = {span.s_worst:.4g} m")
    for span in report.too_close:
        console.print(f"[yellow]within the margin[/yellow] of {span.obstacle} over s = "
                      f"{span.s_start:.4g} to {span.s_end:.4g} m (closest "
                      f"{max(span.worst, 0.0) * 1e3:.2f} mm at s = {span.s_worst:.4g} m)")


def _bend_limit(part: Any, rules: Any = None) -> float | None:
    """The verdict's own bend limit [m] (``evaluate.centreline_bend_limit``)."""
    from pliant.assembly.evaluate import centreline_bend_limit  # noqa: PLC0415 (the rules)

    return centreline_bend_limit(part, rules)


def print_path(run: Any, part: Any, console: Console | None = None, rows: int = 12,
               rules: Any = None) -> None:
    """A manipulation's record (about ``rows`` steps) and its verdict; the bend limit by
    ``rules`` (the scene's; default the bundled table)."""
    console = console or Console()
    # 80 columns: light rules, headers on two lines with their units, numbers right-aligned
    # and never wrapped, the obstacle's name cut to fit (the clearance table has it whole).
    pose = run.planned == 0  # a scene without a [path]: its one pose
    table = Table(title=f"the pose: the force and moment at {run.grip}" if pose else
                  f"along the path: {len(run.steps) - 1} of {count(run.planned, 'step')} "
                  f"solved; the force and moment at {run.grip}",
                  title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False,
                  collapse_padding=True)
    for column, width in (("step", 4), (f"{run.grip}\nx y z [m]", 16), ("|F|\n[N]", 4),
                          ("|M|\n[N m]", 5), ("clear.\n[mm]", 6), ("nearest", None),
                          ("contact\n[N]", 7), ("bend R\n[mm]", 6)):
        table.add_column(escape(column), justify="right" if width else "left", no_wrap=True,
                         min_width=width, max_width=None if width else 14,
                         overflow="ellipsis")
    every = max(1, (len(run.steps) - 1) // rows)
    shown = sorted(set(range(0, len(run.steps), every)) | {len(run.steps) - 1})
    for k in shown:
        r = run.steps[k]
        clear = ("–" if not math.isfinite(r.clearance)  # nothing to clear
                 else f"{max(r.clearance, 0.0) * 1e3:.1f}" if r.clearance > -1e-6
                 else f"[red]{r.clearance * 1e3:.1f}[/red]")
        table.add_row(str(k), " ".join(_fixed(x, 2) for x in r.grip_position),
                      f"{r.force_norm:.3g}", f"{r.moment_norm:.3g}", clear,
                      r.nearest, f"{r.contact_force:.3g}" if r.contacts else "",
                      f"{r.bend_radius * 1e3:.0f}")
    console.print(table)
    force, kf = run.peak("force")
    moment, km = run.peak("moment")
    tightest = min(run.steps, key=lambda r: r.bend_radius)
    if pose:
        console.print(f"force at {run.grip}: {force:.3g} N; moment: {moment:.3g} N m")
    else:
        console.print(f"peak force at {run.grip}: {force:.3g} N (step {kf}); peak moment: "
                      f"{moment:.3g} N m (step {km})")
    line = (f"tightest bend: radius {tightest.bend_radius * 1e3:.1f} mm at s = "
            f"{tightest.bend_at:.3g} m" + ("" if pose else
                                           f" (progress {tightest.progress:.0%})"))
    limit = _bend_limit(part, rules)
    if limit is not None:
        line += (" [red]below[/red]" if tightest.bend_radius < limit
                 else " above") + f" the part's limit {limit * 1e3:.3g} mm (centreline)"
    console.print(line)
    touching = [k for k, r in enumerate(run.steps) if r.contacts]
    inside = [k for k, r in enumerate(run.steps) if r.clearance < -1e-6]
    close = [k for k, r in enumerate(run.steps) if r.clearance < run.margin]
    console.print(f"steps touching an obstacle: {len(touching)}"
                  + (f" (first at step {touching[0]})" if touching else "")
                  + f"; within the {run.margin * 1e3:g} mm margin: {len(close)}"
                  + f"; penetrating: {len(inside)}")
    if run.snaps:
        console.print(f"[red]the part snaps[/red] (its shape could not be followed, it jumps "
                      f"to another) at steps {', '.join(map(str, run.snaps))}")
    if run.branched:
        console.print(f"{BRANCHED} at steps {', '.join(map(str, run.branched))}")
    if run.unstable:
        console.print(f"[red]unstable shapes[/red] (a real part would not stay there) at "
                      f"{len(run.unstable)} steps, first {run.unstable[0]}")
    if run.stopped:
        console.print(f"[red]stopped[/red]: {run.stopped}")
    elif not pose:
        console.print("the path was followed to its end")
    total = sum(r.seconds for r in run.steps[1:])
    if len(run.steps) > 1:
        console.print(f"solve time: {total * 1e3 / (len(run.steps) - 1):.1f} ms per step "
                      f"(warm), {run.steps[0].seconds * 1e3:.0f} ms for the start"
                      + (f"; compiling the solvers took {run.compiling:.0f} s more (a first "
                         "run only: they are cached now)" if run.compiling >= 0.5 else ""))
