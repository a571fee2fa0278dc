"""The ``pliant`` command line.

Heavy modules (numba kernels, scipy, matplotlib, pydantic) are imported inside the
commands that need them, so ``pliant --help`` answers at once. Every error pliant raises
on purpose ends the command with a one-line message and exit status 2, never a
traceback.
"""

from __future__ import annotations

import importlib
import inspect
import os
import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from pliant.errors import PliantError

app = typer.Typer(
    name="pliant",
    help="Flexible parts (hoses, pipes, cables) in assembly and disassembly.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)

# The bundled default scene, package data (examples/scenes/ links to it in a checkout).
DEMO = Path(__file__).resolve().parents[1] / "data" / "demo" / "engine_bay.toml"


def _version(value: bool) -> None:
    if value:
        from pliant import __version__  # noqa: PLC0415

        typer.echo(f"pliant {__version__}")
        raise typer.Exit()


@app.callback()
def _main(version: Annotated[bool, typer.Option(
        "--version", callback=_version, is_eager=True,
        help="print pliant's version and exit")] = False) -> None:
    """Flexible parts (hoses, pipes, cables) in assembly and disassembly."""


def _first_run_note(three_d: bool = True, plots: bool = True) -> None:
    """On a first run of a model (its numba kernels not cached yet), say so on stderr,
    with about how long it takes, so that a fresh install does not look hung, and
    compile the model's kernels ahead on two cores (``pliant.models.first_run``), with
    the kernel being compiled shown on a terminal. ``plots``: the job draws or writes
    meshes (its libraries are imported while the compile waits, ``_HEAD_START``); a job
    that does not is not delayed by them."""
    from pliant.models import first_run  # noqa: PLC0415 (light: no numba until used)

    kind = "3d" if three_d else "2d"
    if not first_run.cold(kind):
        return
    first_run.spawn(kind)  # its start overlaps the signatures' reading (numba's import)
    cores = min(os.cpu_count() or 1, 2)
    seconds = max(5, 5 * round(first_run.estimate(kind, cores) / 5))
    typer.echo(f"compiling the {kind.upper()} solvers (first run only, on {cores} "
               f"core{'s' if cores > 1 else ''}, about {seconds} s)…", err=True)
    from rich.console import Console  # noqa: PLC0415

    console = Console(stderr=True)
    if not console.is_terminal:
        first_run.compile_ahead(kind=kind, idle=_HEAD_START if plots else ())
        return
    with console.status("compiling…") as status:
        first_run.compile_ahead(lambda name: status.update(f"compiling {name}…"), kind=kind,
                                idle=_HEAD_START if plots else ())


def _plotting() -> None:
    import matplotlib  # noqa: PLC0415 (a head start: see _HEAD_START)

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: PLC0415


def _first_figure() -> None:
    """Draw a small figure with text to SVG and PNG: the fonts are found, loaded and
    cached (the first text drawn costs more than any later)."""
    import io  # noqa: PLC0415

    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, ax = plt.subplots(figsize=(2, 1.5), layout="constrained")
    ax.plot([0, 1], [0, 1], label="x")
    ax.set_title("t", fontsize=10)
    ax.legend(fontsize=8)
    for form in ("svg", "png"):
        fig.savefig(io.BytesIO(), format=form, dpi=40)
    plt.close(fig)


# What a job does after its solve anyway (the report's and plots' libraries and first
# figure, the meshes' library), done on a first run while the compile waits for its
# helper process (first_run.compile_ahead's idle work), so that it costs nothing there.
_HEAD_START = (_plotting, lambda: importlib.import_module("mpl_toolkits.mplot3d"),
               lambda: importlib.import_module("trimesh"), _first_figure)


class _ReadingBar:
    """``pliant.util.progress``'s listener on the terminal: what is being read, and for the
    distance structures a bar over the triangles with the time left (rich's estimate
    from the rate so far); a spinner while the amount is not known (tessellating)."""

    def __init__(self, name: str, console) -> None:
        from rich.progress import (  # noqa: PLC0415
            BarColumn,
            Progress,
            SpinnerColumn,
            TaskProgressColumn,
            TextColumn,
            TimeRemainingColumn,
        )

        self.name = name
        self.shown = console.is_terminal  # a pipe or a file gets nothing (not even a newline)
        self.bar = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                            TaskProgressColumn(), TimeRemainingColumn(), console=console,
                            transient=True)
        self.task = self.bar.add_task(f"reading {name}…", total=None)

    def __enter__(self) -> _ReadingBar:
        if self.shown:
            self.bar.start()
        return self

    def __exit__(self, *exc) -> None:
        if self.shown:
            self.bar.stop()

    def say(self, text: str) -> None:
        self.bar.update(self.task, description=f"reading {self.name}: {text}")

    def start(self, total: float) -> None:
        self.bar.reset(self.task, total=total)

    def update(self, done: float) -> None:
        self.bar.update(self.task, completed=done)

    def stop(self) -> None:
        self.bar.reset(self.task, total=None)


def _out_folder(out: Path) -> Path:
    """``--out``, checked before any work: a folder, or nothing yet (never a file: the
    work would be lost when its outputs cannot be written)."""
    if out.exists() and not out.is_dir():
        raise PliantError(f"--out {out}: is a file, not a folder; give a folder for the "
                          "outputs (new or existing)")
    return out


def _load_scene(file: Path):
    """The scene file, its warnings said on stderr (a valid file may still mislead)."""
    from rich.console import Console  # noqa: PLC0415

    from pliant.assembly.scenes import load_scene  # noqa: PLC0415

    # A CAD assembly of millions of triangles takes seconds to tessellate and to build
    # its distance structures: a bar with the time left (on a terminal only).
    from pliant.util.progress import listening  # noqa: PLC0415

    with _ReadingBar(file.name, Console(stderr=True)) as bar, listening(bar):
        scene = load_scene(file)
    for warning in scene.warnings:
        typer.echo(f"warning: {warning}", err=True)
    return scene


def _elements(value: int | None) -> int | None:
    """``--elements``, checked: None (the file's), or a count the 3D model takes."""
    if value is not None and not 4 <= value <= 100000:
        raise PliantError(f"--elements: must be from 4 to 100000, got {value}; leave it out "
                          "for the file's [solver] elements")
    return value


@app.command()
def solve(
    file: Annotated[Path, typer.Argument(help="a problem file (TOML, SI units)")],
    json: Annotated[Path | None, typer.Option("--json", help="write the full result as "
                                              "JSON to this file; - for standard output")]
    = None,
    plot: Annotated[Path | None, typer.Option(help="draw the shape and its internal forces "
                                                   "to this PNG file")] = None,
    mesh: Annotated[Path | None, typer.Option(help="export the deformed tube (.glb, .gltf, "
                                                   ".stl, .obj, .ply)")] = None,
    elements: Annotated[int | None, typer.Option(help="3D: about how many elements "
                                                      "(default: the file's \\[solver], or 100)")]
    = None,
    all_: Annotated[bool, typer.Option("--all", help="list every equilibrium the routes "
                                                     "reach, with its energy and "
                                                     "stability")] = False,
) -> None:
    """Solve a problem file (2D or 3D): shape, internal forces, reactions."""
    from pliant.cli.report import (  # noqa: PLC0415
        print_interference,
        print_summary,
        solve_json,
        timed_solve,
    )

    elements = _elements(elements)
    scene = _load_scene(file)
    problem = scene.problem
    _first_run_note(problem.dimension == 3, plots=plot is not None or mesh is not None)
    if all_:
        all_equilibria(problem, json, elements or scene.solver.elements)
        return
    eq, seconds = timed_solve(problem, elements or scene.solver.elements)
    report = None
    if problem.obstacles:
        from pliant.scene import interference  # noqa: PLC0415

        report = interference(eq, margin=scene.margin)
    quiet = _to_stdout(json)  # the JSON is standard output: nothing else is printed
    if not quiet:
        print_summary(eq, seconds, report=report)
        if report is not None:
            print_interference(report)
    if json is not None:
        written = emit_json(solve_json(eq, seconds, report), json, "the result (JSON)")
        if written is not None:
            typer.echo(f"JSON written to {written}")
    if plot is not None:
        from pliant.cli.plot import plot_equilibrium  # noqa: PLC0415

        plot_equilibrium(eq, plot)
        if not quiet:
            typer.echo(f"plot written to {plot}")
    if mesh is not None:
        from pliant.io.mesh_export import export_mesh, part_radius  # noqa: PLC0415

        export_mesh(eq, mesh)
        if not quiet:
            note = "" if problem.part.outer_diameter else " (display radius: no outer_diameter)"
            typer.echo(f"mesh written to {mesh}, radius {part_radius(eq):.4g} m{note}")


def _to_stdout(target: Path | None) -> bool:
    """Whether an output path is ``-``: standard output."""
    return target is not None and str(target) == "-"


def emit_json(text: str, target: Path, what: str) -> Path | None:
    """JSON ``text`` to ``target``: standard output for ``-`` (None), else the file,
    written atomically (its path). Every command's ``--json`` takes a path this way."""
    if _to_stdout(target):
        typer.echo(text)
        return None
    from pliant.io.atomic import atomic_write  # noqa: PLC0415

    return atomic_write(target, lambda h: h.write(text.encode()), what)


def all_equilibria(problem, as_json: Path | None, elements: int | None = None) -> None:
    """``pliant solve --all``: the equilibria the routes reach (2D or 3D), best first."""
    import time  # noqa: PLC0415

    from pliant.core.equilibrium import bow_side, potential_energy  # noqa: PLC0415
    from pliant.models import dispatch  # noqa: PLC0415

    start = time.perf_counter()
    found = dispatch.equilibria(problem, elements=elements)
    seconds = time.perf_counter() - start
    if as_json is not None:
        import json as _json  # noqa: PLC0415

        from pliant.io.jsontext import finite  # noqa: PLC0415

        text = _json.dumps(finite({"schema_version": 1, "seconds": seconds, "equilibria": [
            {**eq.to_dict(), "potential_energy": potential_energy(eq)} for eq in found]}))
        written = emit_json(text, as_json, "the equilibria (JSON)")
        if written is None:
            return
        typer.echo(f"JSON written to {written}")
    from rich.console import Console  # noqa: PLC0415
    from rich.table import Table  # noqa: PLC0415

    from pliant.cli.report import count  # noqa: PLC0415

    if not found:
        raise PliantError("no equilibrium reached: no route reached one, and the routes do not "
                          "search every shape (see pliant solve for why)")
    first = ("the first is pliant's answer" if problem.dimension == 2 else
             "stable first, then by potential energy"
             + (" (of all the parts solved together)" if problem.solved_together else ""))
    table = Table(title=f"{problem.name or 'problem'}: "
                        f"{count(len(found), 'equilibrium', 'equilibria')} found in "
                        f"{seconds:.2f} s; {first}",
                  title_justify="left")
    for col in ("#", "potential\n[J]", "elastic\n[J]", "stability", "eigenvalue\n[N m]",
                "bows", "max |M|\n[N m]"):
        table.add_column(col, justify="left" if col in ("stability", "bows") else "right")
    for i, eq in enumerate(found, 1):
        table.add_row(str(i), f"{potential_energy(eq):.6g}", f"{eq.energy:.6g}", eq.verdict,
                      f"{eq.stability[1]:.4g}" if eq.stability[1] is not None else "-",
                      bow_side(eq), f"{eq.max_moment()[0]:.4g}")
    Console().print(table)


@app.command()
def run(
    file: Annotated[Path, typer.Argument(help="a scene file (TOML, SI units) with a \\[path]")],
    out: Annotated[Path, typer.Option(help="folder for the report (JSON), the plot (PNG) "
                                           "and the final scene (GLB)")] = Path("pliant-out"),
    elements: Annotated[int | None, typer.Option(help="about how many elements "
                                                      "(default: the file's \\[solver])")]
    = None,
) -> None:
    """Follow a scene's manipulation: solve every step of its \\[path], report the force and
    moment at the grip, contacts, clearances and bend radius, and write them out."""
    run_scene(file, _out_folder(out), _elements(elements))


def _with_progress(console, scene, file: Path, work):
    """Say what is being solved, then run ``work(on_step)`` under a progress bar over the
    path's steps; its result."""
    from rich.progress import Progress  # noqa: PLC0415

    from pliant.cli.report import count  # noqa: PLC0415

    problem = scene.problem
    console.print(f"[bold]{problem.name or file.stem}[/bold]: {problem.part.name}, "
                  f"{count(len(problem.obstacles), 'obstacle')}, "
                  + (count(len(scene.path), "step") if scene.path else "one pose (no \\[path])"))
    _first_run_note(problem.dimension == 3)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("solving the path", total=len(scene.path) + 1)
        return work(lambda k, r: bar.advance(task))


def run_scene(file: Path, out: Path, elements: int | None) -> None:
    import json as _json  # noqa: PLC0415

    from rich.console import Console  # noqa: PLC0415

    from pliant.assembly import follow_path  # noqa: PLC0415
    from pliant.assembly.path import STEP_UNITS  # noqa: PLC0415
    from pliant.cli.plot import plot_path  # noqa: PLC0415
    from pliant.cli.report import (  # noqa: PLC0415
        print_contacts,
        print_interference,
        print_path,
    )
    from pliant.io.atomic import atomic_write  # noqa: PLC0415
    from pliant.io.jsontext import finite  # noqa: PLC0415
    from pliant.io.mesh_export import export_scene  # noqa: PLC0415

    scene = _load_scene(file)
    if not scene.path:
        raise PliantError(f"{file}: no [path] to follow; give one (docs/reference.md, scene "
                          "files), or use `pliant solve` for a single pose")
    problem = scene.problem
    console = Console()
    result = _with_progress(console, scene, file, lambda step: follow_path(
        problem, scene.path, scene.grip, margin=scene.margin,
        elements=elements or scene.solver.elements, on_step=step))
    if not result.steps:
        raise PliantError(f"{file}: the start pose could not be solved: {result.stopped}")
    print_path(result, problem.part, console)
    console.print("at the last step solved:")
    print_interference(result.interference, console)
    print_contacts(result.final, console)
    stem = file.stem
    report = out / f"{stem}.json"
    record = {"schema_version": 1, "units": STEP_UNITS, **result.to_dict()}
    atomic_write(report, lambda h: h.write(_json.dumps(finite(record), indent=1).encode()),
                 "the report")
    from pliant.assembly.evaluate import centreline_bend_limit  # noqa: PLC0415

    plot = plot_path(result, out / f"{stem}.png", centreline_bend_limit(problem.part))
    glb = export_scene(result.final, out / f"{stem}.glb")
    console.print(f"written: {report}, {plot}, {glb} (the last pose with the obstacles)")


@app.command()
def evaluate(
    file: Annotated[Path, typer.Argument(help="a scene file (TOML, SI units): its \\[path], "
                                              "or its single pose")],
    report: Annotated[Path | None, typer.Option(help="write the self-contained HTML "
                                                     "report here")] = None,
    json: Annotated[Path | None, typer.Option("--json", help="write the evaluation as JSON "
                                                             "(schema_version 1) to this "
                                                             "file; - for standard output")]
    = None,
    csv: Annotated[Path | None, typer.Option("--csv", help="write a row per step as CSV")]
    = None,
    rules: Annotated[Path | None, typer.Option(help="a rules table replacing the bundled "
                                                    "one (see pliant/data/rules.toml)")]
    = None,
    operator: Annotated[str | None, typer.Option(help="judge only this operator: 'one hand', "
                                                      "'two hands', 'tool', 'robot' "
                                                      "(default: the scene's, or try them "
                                                      "cheapest first)")] = None,
    elements: Annotated[int | None, typer.Option(help="about how many elements "
                                                      "(default: the file's \\[solver])")]
    = None,
    schema: Annotated[bool, typer.Option("--schema", help="print the JSON schema of the "
                                                          "evaluation and exit")] = False,
) -> None:
    """Judge an A/D operation: forces per grip against hand capacities, bend radius, kink,
    twist, stability, clearance and contact, each with its threshold and source; the
    operator it needs (one hand, two hands, a tool or robot). Exit status 0 when it
    passes, 1 when it does not."""
    if schema:
        import json as _json  # noqa: PLC0415

        from pliant.io.evaluation_file import schema as evaluation_schema  # noqa: PLC0415

        typer.echo(_json.dumps(evaluation_schema(), indent=1))
        return
    passes = _evaluate_scene(file, report, json, csv, rules, operator, elements)
    raise typer.Exit(0 if passes else 1)


def _evaluate_scene(file: Path, report: Path | None, json_out: Path | None,
                    csv_out: Path | None, rules_file: Path | None, operator: str | None,
                    elements: int | None, pictures: Path | None = None) -> bool:
    """Evaluate a scene, print the verdict and write what was asked; ``pictures`` also
    writes the path's plot (PNG) and the last pose with the obstacles (GLB) with that
    stem. True when the operation passes."""
    # A missing file or a bad count is said at once; then a first run's compile starts
    # before the scene (its fitted parts are solved as it is read) and before the
    # modules below, so that the helper process starts compiling at once.
    from pliant.io.problem_file import read_text  # noqa: PLC0415

    elements = _elements(elements)
    read_text(file)
    _first_run_note()
    from dataclasses import replace  # noqa: PLC0415

    from rich.console import Console  # noqa: PLC0415

    from pliant.assembly.evaluate import evaluate as evaluate_scene  # noqa: PLC0415
    from pliant.cli.evaluation_report import print_evaluation, write_html  # noqa: PLC0415
    from pliant.io.evaluation_file import evaluation_json, write_csv  # noqa: PLC0415
    from pliant.io.rules_file import load_rules  # noqa: PLC0415

    scene = _load_scene(file)
    if operator is not None:  # checked as the file's would be (EvaluationSettings)
        scene = replace(scene, evaluation=replace(scene.evaluation, operator=operator))
    rules = load_rules(rules_file if rules_file is not None else scene.evaluation.rules)
    problem = scene.problem
    # With --json -, standard output is the JSON alone: the words go to standard error.
    console = Console(stderr=_to_stdout(json_out))
    ev = _with_progress(console, scene, file, lambda step: evaluate_scene(
        scene, rules=rules, elements=elements, on_step=step))
    from pliant.cli.report import print_path  # noqa: PLC0415

    print_path(ev.run, problem.part, console, rules=rules)
    print_evaluation(ev, console)
    written = []
    if json_out is not None:
        path = emit_json(evaluation_json(ev), json_out, "the evaluation (JSON)")
        written += [path] if path is not None else []
    if csv_out is not None:
        written.append(write_csv(ev, csv_out))
    if report is not None:
        written.append(write_html(ev, report))
    if pictures is not None:
        from pliant.assembly.evaluate import centreline_bend_limit  # noqa: PLC0415
        from pliant.cli.plot import plot_path  # noqa: PLC0415
        from pliant.io.mesh_export import export_scene  # noqa: PLC0415

        written.append(plot_path(ev.run, pictures.with_suffix(".png"),
                                 centreline_bend_limit(problem.part, rules)))
        written.append(export_scene(ev.run.final, pictures.with_suffix(".glb")))
    if written:
        console.print("written: " + ", ".join(str(w) for w in written))
    return ev.verdict.passes


@app.command()
def study(
    file: Annotated[Path, typer.Argument(help="a scene file (TOML, SI units) whose operation "
                                              "is evaluated for each sample")],
    vary: Annotated[list[str], typer.Option(help="NAME=TOL[UNIT][,normal], e.g. "
                                                 "bending_stiffness=20%, length=5mm, "
                                                 "'clip[0].position=2mm' (repeat it)")],
    samples: Annotated[int, typer.Option(help="how many samples")] = 64,
    out: Annotated[Path, typer.Option(help="the study's folder: its samples as they come "
                                           "(run again to resume), report, envelope")]
    = Path("pliant-study"),
    method: Annotated[str, typer.Option(help="lhs (Latin hypercube) or sobol")] = "lhs",
    seed: Annotated[int, typer.Option(help="the sample plan's seed")] = 0,
    scheduler: Annotated[str | None, typer.Option(help="a Dask scheduler's address "
                                                       "(tcp://HOST:PORT); default: a local "
                                                       "cluster on this machine")] = None,
    workers: Annotated[int | None, typer.Option(min=0, help="local worker processes (default: "
                                                     "one per core; 0: in this process)")] = None,
    restart: Annotated[bool, typer.Option(help="discard the folder's samples and start "
                                               "again")] = False,
    elements: Annotated[int | None, typer.Option(help="about how many elements (default: "
                                                      "the file's \\[solver])")] = None,
) -> None:
    """How robust is the verdict to real parts? Sample the tolerances, evaluate every
    sample's operation (on Dask), and report the probability of each verdict, the
    outputs' percentiles, the sensitivities and the tolerance envelope."""
    import json as _json  # noqa: PLC0415

    from rich.console import Console  # noqa: PLC0415
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn  # noqa: PLC0415

    from pliant.assembly.study import Store, final_voxels, summarize  # noqa: PLC0415
    from pliant.assembly.study import study as run_study  # noqa: PLC0415

    _out_folder(out)
    from pliant.cli.study_report import print_study, write_html  # noqa: PLC0415
    from pliant.io.atomic import atomic_write  # noqa: PLC0415
    from pliant.io.jsontext import finite  # noqa: PLC0415
    from pliant.io.mesh_export import export_envelope  # noqa: PLC0415

    elements = _elements(elements)
    console = Console()
    columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed}/"
               "{task.total}"), TimeRemainingColumn())
    with Progress(*columns, console=console) as bar:
        task = bar.add_task("samples", total=samples)
        result = run_study(file, vary, samples, out=out, method=method, seed=seed,
                           scheduler=scheduler, workers=workers, elements=elements,
                           restart=restart,
                           on_done=lambda n, total: bar.update(task, completed=n))
    summary = summarize(result)
    print_study(result, summary, console)
    envelope = Store(result.folder).swept([r["index"] for r in result.ok])
    result_envelope = final_voxels(result)
    text = _json.dumps(finite(summary), indent=1).encode()
    glb = export_envelope([("envelope along the path", envelope, (150, 160, 170, 90)),
                           ("envelope at the final pose", result_envelope,
                            (224, 112, 30, 160))], result.voxel,
                          result.folder / "envelope.glb")
    if glb is None:
        console.print("no envelope written: no sample was evaluated")
    written = [atomic_write(result.folder / "summary.json", lambda h: h.write(text),
                            "the study's summary"), *([glb] if glb else []),
               write_html(result, summary, envelope, result_envelope,
                          result.folder / "report.html")]
    console.print("written: " + ", ".join(str(w) for w in written))


@app.command()
def plan(
    file: Annotated[Path, typer.Argument(help="a scene file (TOML, SI units): its grip's "
                                              "start pose, its ports and obstacles")],
    goal: Annotated[str | None, typer.Option(help="the \\[\\[port]] to seat the part's end in "
                                                  "(default: the file's \\[plan] goal)")]
    = None,
    out: Annotated[Path, typer.Option(help="folder for the planned scene (TOML), its "
                                           "evaluation (HTML, JSON) and the plan (JSON)")]
    = Path("pliant-plan"),
    budget: Annotated[float | None, typer.Option(help="seconds the search may take "
                                                      "(default: \\[plan] budget, 30)")]
    = None,
    seed: Annotated[int | None, typer.Option(help="the search's seed: the same seed, the "
                                                  "same path")] = None,
    allow_contact: Annotated[bool | None, typer.Option(
        "--allow-contact/--keep-margin", help="let the part touch obstacles (not enter "
        "them), or keep the scene's margin (default: \\[plan] allow_contact)")] = None,
    attempts: Annotated[int | None, typer.Option(help="trees grown at most; the path of "
                                                      "least hand demand is kept")] = None,
    elements: Annotated[int | None, typer.Option(help="about how many elements "
                                                      "(default: the file's \\[solver])")]
    = None,
) -> None:
    """Find the grip's path: from the scene's start pose to the port, through stable
    equilibria of the accurate model only, clear of the obstacles, within the part's
    bend limit, with the least hand demand found. Writes the scene with that \\[path]
    (play it with `pliant view`) and its evaluation. Exit status 0 when the planned
    operation passes the evaluation, 1 when it does not, 2 when no path is found."""
    _plan_scene(file, goal, _out_folder(out), budget, seed, allow_contact, attempts,
                _elements(elements))


def _plan_scene(file: Path, goal: str | None, out: Path, budget: float | None,
                seed: int | None, allow_contact: bool | None, attempts: int | None,
                elements: int | None) -> None:
    import json as _json  # noqa: PLC0415
    from dataclasses import replace  # noqa: PLC0415

    from rich.console import Console  # noqa: PLC0415

    from pliant.assembly.evaluate import evaluate as evaluate_scene  # noqa: PLC0415
    from pliant.assembly.path import STEP_UNITS  # noqa: PLC0415
    from pliant.assembly.plan import Planner  # noqa: PLC0415
    from pliant.cli.evaluation_report import print_evaluation, write_html  # noqa: PLC0415
    from pliant.cli.report import print_path  # noqa: PLC0415
    from pliant.io.atomic import atomic_write  # noqa: PLC0415
    from pliant.io.evaluation_file import write_json  # noqa: PLC0415
    from pliant.io.jsontext import finite  # noqa: PLC0415
    from pliant.io.problem_file import read_text, with_path_table  # noqa: PLC0415

    scene = _load_scene(file)
    changes = {k: v for k, v in (("budget", budget), ("seed", seed), ("attempts", attempts),
                                 ("allow_contact", allow_contact), ("elements", elements),
                                 ("goal", goal)) if v is not None}
    settings = replace(scene.plan, **changes)  # checked as the file's would be
    if settings.goal is None:
        raise PliantError(f"{file}: which port? give --goal PORT, or [plan] goal in the file "
                          f"(ports: {', '.join(scene.ports) or 'none'})")
    from pliant.cli.report import count  # noqa: PLC0415

    console = Console()
    problem = scene.problem
    console.print(f"[bold]{problem.name or file.stem}[/bold]: planning {problem.part.name} "
                  f"into {settings.goal!r} ({count(len(problem.obstacles), 'obstacle')}, budget "
                  f"{settings.budget:g} s, seed {settings.seed}, "
                  + ("contact allowed" if settings.allow_contact
                     else f"margin {scene.margin * 1e3:g} mm") + ")")
    _first_run_note()
    planner = Planner(scene, settings)
    try:
        with console.status("searching (OMPL's RRT over accurate equilibria)…"):
            found = planner.plan(settings.goal, on_progress=console.print)
    except KeyboardInterrupt:
        typer.echo("interrupted: no path yet, nothing written", err=True)
        raise typer.Exit(130) from None
    console.print(f"found a path in {found.seconds:.1f} s: {count(len(found.poses), 'waypoint')}, "
                  f"{count(found.solves, 'accurate solve')}, "
                  f"{count(found.motions, 'motion')} checked, {count(found.trees, 'tree')}; "
                  f"followed again in {count(found.steps, 'step')}")
    planned = replace(scene, path=found.path, grip=found.grip,
                      evaluation=replace(scene.evaluation, port=settings.goal))
    ev = evaluate_scene(planned, run=found.run, elements=elements)
    print_path(found.run, problem.part, console)
    print_evaluation(ev, console)
    out.mkdir(parents=True, exist_ok=True)
    stem = file.stem
    text = with_path_table(read_text(file), found.path_table(), str(file), file.parent, out)
    written = [atomic_write(out / f"{stem}-planned.toml", lambda h: h.write(text.encode()),
                            "the planned scene")]
    summary = _json.dumps(finite({"schema_version": 1, **found.summary(),
                                  "units": {"waypoints": "m", "tangents": "1",
                                            "seconds": "s", "run": STEP_UNITS},
                                  "run": found.run.to_dict()}), indent=1).encode()
    written.append(atomic_write(out / f"{stem}-plan.json", lambda h: h.write(summary),
                                "the plan"))
    written.append(write_json(ev, out / f"{stem}-planned-evaluation.json"))
    written.append(write_html(ev, out / f"{stem}-planned.html"))
    console.print("written: " + ", ".join(str(w) for w in written))
    console.print(f"play it: pliant view {written[0]}")
    raise typer.Exit(0 if ev.verdict.passes else 1)


@app.command()
def sequence(
    file: Annotated[Path, typer.Argument(help="a sequence file (TOML, SI units): a \\[\\[fit]] "
                                              "table per part (its own scene file with its "
                                              "\\[path]) and the obstacles they share")],
    out: Annotated[Path, typer.Option(help="the search's folder: each operation judged, as "
                                           "it comes (run again to resume), and the report")]
    = Path("pliant-sequence"),
    json: Annotated[Path | None, typer.Option("--json", help="write the search as JSON "
                                                             "(schema_version 1) to this file; "
                                                             "- for standard output")] = None,
    report: Annotated[Path | None, typer.Option(help="write the HTML report here (default: "
                                                     "OUT/report.html)")] = None,
    exhaustive: Annotated[bool | None, typer.Option(
        "--exhaustive/--prune", help="judge every operation of every order, or prune those a "
        "failure already decides (default: the file's \\[sequence] exhaustive, else prune)")]
    = None,
    scheduler: Annotated[str | None, typer.Option(help="a Dask scheduler's address "
                                                       "(tcp://HOST:PORT)")] = None,
    workers: Annotated[int, typer.Option(min=0, help="local Dask worker processes (0: in "
                                              "this process)")] = 0,
    restart: Annotated[bool, typer.Option(help="discard the folder's operations and start "
                                               "again")] = False,
) -> None:
    """In which order can the parts be fitted? Judge each part's operation (its path,
    with the parts fitted before it in place, flexible) over the orders, pruning those a
    failure decides; print the best order, why each other order fails and the
    precedences found. Exit status 0 when an order fits every part, 1 when none does."""
    from pliant.io.problem_file import read_text  # noqa: PLC0415

    read_text(file)
    _out_folder(out)
    _first_run_note()
    from rich.console import Console  # noqa: PLC0415

    from pliant.assembly.sequence import final_lines, load_sequence  # noqa: PLC0415
    from pliant.assembly.sequence import sequence as search  # noqa: PLC0415
    from pliant.cli.sequence_report import print_sequence, write_html  # noqa: PLC0415
    from pliant.io.jsontext import finite  # noqa: PLC0415

    console = Console(stderr=_to_stdout(json))
    seq = load_sequence(file)
    with console.status(f"judging the operations of {len(seq.fits)} parts…") as status:
        result = search(seq, out=out, exhaustive=exhaustive, scheduler=scheduler,
                        workers=workers, restart=restart,
                        on_done=lambda op: status.update(
                            f"judged {op['part']}"
                            + (f" after {', '.join(op['prefix'])}" if op["prefix"] else "")))
    print_sequence(result, console)
    import json as _json  # noqa: PLC0415

    written = []
    if json is not None:
        text = _json.dumps(finite(result.to_dict()), indent=1)
        path = emit_json(text, json, "the search (JSON)")
        written += [path] if path is not None else []
    lines = final_lines(seq, result.best.parts) if result.best is not None else None
    written.append(write_html(result, report or out / "report.html", lines,
                              list(seq.obstacles)))
    console.print("written: " + ", ".join(str(w) for w in written))
    raise typer.Exit(0 if result.passes else 1)


@app.command()
def identify(
    file: Annotated[Path, typer.Argument(help="a stiffness test (TOML): a problem file with "
                                              "\\[identify] and \\[\\[measured]] tables")],
    json_out: Annotated[Path | None, typer.Option("--json", help="write the estimates, "
                                                  "intervals and fit as JSON to this file; "
                                                  "- for standard output")] = None,
    plot: Annotated[Path | None, typer.Option(help="draw measured against fitted (PNG)")]
    = None,
    part: Annotated[Path | None, typer.Option(help="write the fitted \\[part] entry "
                                                   "(TOML) to paste into a scene")] = None,
) -> None:
    """Identify the part's stiffness (or weight) from a test: the accurate model fitted
    to what was measured (a shape, deflections under loads, a three-point bending curve,
    a twist curve) by weighted least squares, each value with its confidence interval."""
    from rich.console import Console  # noqa: PLC0415

    from pliant.cli.identify_report import plot_identification, print_identification  # noqa: PLC0415
    from pliant.identify import identify as fit  # noqa: PLC0415
    from pliant.io.atomic import atomic_write  # noqa: PLC0415
    from pliant.io.identify_file import load_test  # noqa: PLC0415
    from pliant.io.jsontext import finite  # noqa: PLC0415

    test, settings = load_test(file)
    console = Console(stderr=_to_stdout(json_out))  # with --json -, the JSON alone on stdout
    from pliant.cli.report import count  # noqa: PLC0415

    console.print(f"[bold]{test.name}[/bold]: fitting {', '.join(test.unknowns)} to "
                  f"{count(len(test.measured), 'measurement')}")
    _first_run_note(test.problem.dimension == 3)
    solver = None
    if test.problem.dimension == 3:
        from pliant.models.rod3d import RodSolver  # noqa: PLC0415

        solver = RodSolver(elements=settings.elements)
    with console.status("fitting the accurate model…"):
        result = fit(test, solver=solver)
    print_identification(result, console)
    written = []
    if json_out is not None:
        import json as _json  # noqa: PLC0415

        text = _json.dumps(finite({"schema_version": 1, **result.to_dict()}), indent=1)
        path = emit_json(text, json_out, "the JSON")
        written += [path] if path is not None else []
    if plot is not None:
        written.append(plot_identification(result, plot))
    if part is not None:
        entry = result.part_table()
        written.append(atomic_write(part, lambda h: h.write(entry.encode()), "the part"))
    else:
        console.print(result.part_table().rstrip(), markup=False, highlight=False,
                      soft_wrap=True)
    if written:
        console.print("written: " + ", ".join(str(w) for w in written))


@app.command()
def demo(
    out: Annotated[Path, typer.Option(help="folder for the report, plot and scene")] = Path(
        "pliant-demo"),
) -> None:
    """The main job on the bundled default scene: the evaluation of an oil line carried
    round an engine bay's exhaust manifold onto its port (examples/scenes/engine_bay.toml),
    with its HTML report, JSON and CSV."""
    scene = DEMO
    if not scene.is_file():
        raise PliantError(f"the bundled scene is missing: {scene}")
    _out_folder(out)
    stem = scene.stem
    _evaluate_scene(scene, out / f"{stem}.html", out / f"{stem}.json", out / f"{stem}.csv",
                    None, None, None, pictures=out / stem)


@app.command()
def harness(
    file: Annotated[Path, typer.Argument(help="a KBL harness file (VDA 4964, 2.3 or 2.4), "
                                              "or a scene file (TOML) whose \\[\\[harness]] "
                                              "tables name one or more among \\[\\[obstacle]] and "
                                              "\\[\\[cad]] tables (solved there)")],
    module: Annotated[list[str] | None, typer.Option(
        help="build this module (a variant; id or part number; repeat for several): its "
             "wires and what no module controls")] = None,
    curves: Annotated[Path | None, typer.Option(help="write each segment's designed centre "
                                                     "curve as CSV (metres), for the design "
                                                     "tool")] = None,
    glb: Annotated[Path | None, typer.Option(help="write the designed harness as tubes of "
                                                  "the bundles' diameters (.glb)")] = None,
    json: Annotated[Path | None, typer.Option("--json", help="write the import, each "
                                                             "segment's properties with "
                                                             "their sources and the checks "
                                                             "as JSON; - for standard "
                                                             "output")] = None,
    all_segments: Annotated[bool, typer.Option("--all", help="list every segment, not only "
                                                             "those a check flags")] = False,
    report: Annotated[Path | None, typer.Option(help="write a self-contained HTML report "
                                                     "(checks, views of the design and the "
                                                     "installed harness, loads, sources)")]
    = None,
    modules: Annotated[bool, typer.Option("--modules", help="list the harness's modules "
                                                            "(the variants --module "
                                                            "builds) and exit")] = False,
    strict: Annotated[bool, typer.Option(help="refuse a file that breaks its KBL "
                                              "schema")] = False,
    solve: Annotated[bool, typer.Option(help="solve the installed harness under gravity "
                                             "(connectors and fixings where the design "
                                             "puts them) and judge it; --curves and --glb "
                                             "then write its installed shape")] = False,
    rules: Annotated[Path | None, typer.Option(help="a rules table replacing the bundled "
                                                    "one (bend margins, fallback limits)")]
    = None,
    clip_order: Annotated[bool, typer.Option(
        "--clip-order", help="find the order to fix the fixings in (the connectors "
                             "plugged first): the hand's force and the bends after each "
                             "clip, and why the other orders fail; implies --solve")] = False,
    fixing: Annotated[list[str] | None, typer.Option(
        help="with --clip-order: order only this fixing (its name; repeat for several; "
             "the others stay fixed). Default: every fixing placed on a segment")] = None,
) -> None:
    """Read a harness's design data (KBL): every segment's bundle diameter, mass,
    stiffness and bend limit with their sources, and the design's checks (curves that
    miss their nodes or their length, bends tighter than the wires allow, bundles
    larger than their reserved section, kinks at nodes). Exit status 1 when a check is
    red, or when no clip order passes."""
    from rich.console import Console  # noqa: PLC0415

    from pliant.assembly import harness as design  # noqa: PLC0415
    from pliant.io import harness_file  # noqa: PLC0415
    from pliant.io.kbl import read_kbl  # noqa: PLC0415
    from pliant.io.rules_file import load_rules  # noqa: PLC0415

    console = Console(stderr=_to_stdout(json))
    table = load_rules(rules)
    obstacles: tuple = ()
    margin = 0.0
    if file.suffix.lower() == ".toml":  # a harness in a scene: solved among its obstacles
        from pliant.io.harness_scene import load_harness_scene  # noqa: PLC0415

        scene = load_harness_scene(file)
        # Each harness of the scene judged in turn among its obstacles (not against each
        # other: contact between harnesses is not modelled).
        harnesses = [(m, list(module or from_scene)) for m, from_scene in scene.harnesses]
        obstacles, margin, solve = scene.obstacles, scene.margin, True
    else:
        harnesses = [(read_kbl(file, strict=strict), list(module or []))]
    solve = solve or clip_order
    if modules:
        from pliant.cli.harness_report import print_modules  # noqa: PLC0415

        for model, _ in harnesses:
            print_modules(console, model)
        return
    several = len(harnesses) > 1

    def own(path: Path | None, k: int) -> Path | None:
        """A file of harness ``k`` (1-based): the path given, numbered where several."""
        if path is None or not several or str(path) == "-":
            return path
        return path.with_name(f"{path.stem}-{k}{path.suffix}")

    texts, verdicts = [], []
    for k, (model, chosen) in enumerate(harnesses, 1):
        if several:
            console.rule(f"harness {k} of {len(harnesses)}: {model.name}")
        if chosen:
            model = design.select(model, chosen)
        props, checks, installed, order = _judge_harness(
            console, model, table, solve, clip_order, fixing, obstacles, margin,
            all_segments, own(curves, k), own(glb, k), own(report, k))
        texts.append(harness_file.harness_json(model, props, checks, installed, order))
        verdicts.append(_harness_verdict(console, checks, installed, order,
                                         f"harness {k} ({model.name}): " if several else ""))
    if json is not None:
        text = texts[0] if not several else (
            '{"schema_version": ' + str(harness_file.SCHEMA_VERSION)
            + ', "harnesses": [' + ", ".join(texts) + "]}")
        written = emit_json(text, json, "the harness JSON")
        if written is not None:
            console.print(f"JSON: {written}")
    if several:
        failed = sum(not v for v in verdicts)
        console.print(f"verdict over the scene's {len(harnesses)} harnesses: "
                      + (f"[bold red]red[/] ({failed} red, exit status 1)" if failed
                         else "[green]no harness red[/]"))
    raise typer.Exit(0 if all(verdicts) else 1)


def _judge_harness(console: Any, model: Any, table: Any, solve: bool, clip_order: bool,
                   fixing: list[str] | None, obstacles: tuple, margin: float,
                   all_segments: bool, curves: Path | None, glb: Path | None,
                   report: Path | None) -> tuple[Any, list, Any, Any]:
    """One harness of ``pliant harness``: its design printed and checked, installed and
    its clip order where asked, its files written; (props, checks, installed, order)."""
    from pliant.assembly import harness as design  # noqa: PLC0415
    from pliant.cli.harness_report import print_harness  # noqa: PLC0415
    from pliant.io import harness_file  # noqa: PLC0415

    props = design.properties(model, rules=table)
    checks = design.design_checks(model, props, rules=table)
    print_harness(console, model, props, checks, show_all=all_segments)
    installed = None
    if solve:
        import time  # noqa: PLC0415

        from pliant.assembly.harness_solve import (  # noqa: PLC0415
            installed_checks,
            solve_installed,
        )
        from pliant.cli.harness_report import print_installed  # noqa: PLC0415

        began = time.perf_counter()
        with console.status("solving the installed harness ..."):
            installed = solve_installed(model, props, obstacles=obstacles, margin=margin)
        after = installed_checks(installed, table)
        print_installed(console, installed, after, time.perf_counter() - began,
                        show_all=all_segments)
        checks = checks + after
    order = None
    if clip_order:
        from pliant.assembly.clip_order import clip_order as search  # noqa: PLC0415
        from pliant.cli.harness_report import print_clip_order  # noqa: PLC0415

        with console.status("searching the clip order ..."):
            order = search(model, props, fixings=fixing or None, obstacles=obstacles,
                           margin=margin, rules=table, installed=installed)
        print_clip_order(console, order)

    def shape(k: str):
        if installed is not None:
            return installed.segments[k].equilibrium.position
        return design.centre_curve(model, k)

    if curves is not None:
        shapes = {k: (s.name, shape(k)) for k, s in model.segments.items()}
        written_curves = harness_file.write_curves(curves, shapes)
        console.print(f"{'installed' if installed else 'designed'} centre curves: "
                      f"{written_curves}")
    if glb is not None:
        tubes = {s.name: (shape(k), 0.5 * (props[k].diameter.value or 2e-3))
                 for k, s in model.segments.items()}
        console.print(f"tubes: {harness_file.write_tubes(glb, tubes)}")
    if report is not None:
        from pliant.cli.harness_html import write_html  # noqa: PLC0415

        written = write_html(model, props, checks, installed, report, order, obstacles)
        console.print(f"report: {written}")
    return props, checks, installed, order


def _harness_verdict(console: Any, checks: list, installed: Any, order: Any,
                     who: str) -> bool:
    """Print one harness's verdict; whether it passes (no red check, an order found)."""
    reds = sum(c.zone.value == "red" for c in checks)
    yellows = sum(c.zone.value == "yellow" for c in checks)
    what = "the design and the installed harness" if installed is not None else "the design"
    if order is not None and order.best is None:
        console.print(f"{who}verdict: [bold red]red[/]: no order of the fixings passes (exit "
                      "status 1)")
        return False
    unchecked = sum(c.zone.value == "unchecked" for c in checks)
    unstable = sum(c.zone.value == "unchecked" and c.what == "stability" for c in checks)
    also = f"; {unchecked} unchecked" if unchecked else ""
    if reds:
        console.print(f"{who}verdict: [bold red]red[/] ({what}): {reds} red and {yellows} "
                      f"yellow checks{also} (exit status 1)")
    elif unstable:  # its checks rest on a shape the harness would not keep
        console.print(f"{who}verdict: [bold]undecided[/] ({what}): {unstable} segment(s) "
                      "unstable as installed, their checks do not hold (exit status 1)")
        return False
    elif yellows:
        console.print(f"{who}verdict: [yellow]yellow[/] ({what}): no red check, {yellows} "
                      f"yellow{also}")
    else:
        console.print(f"{who}verdict: [green]green[/] ({what}): no red or yellow check"
                      + (f", {unchecked} unchecked (see the checks)" if unchecked
                         else ": every check is green"))
    return not reds


def examples_folder() -> Path:
    """The example scenes: those a wheel carries (``pliant/examples``, copied at build time
    by setup.py), else the repository's ``examples`` (a development install)."""
    bundled = Path(__file__).resolve().parents[1] / "examples"
    if bundled.is_dir():
        return bundled
    return Path(__file__).resolve().parents[3] / "examples"


@app.command()
def examples(
    out: Annotated[Path, typer.Argument(help="a new (or empty) folder to copy them into")]
    = Path("pliant-examples"),
) -> None:
    """Copy the example scenes, problems and tests (the docs') into a folder of your
    own, to run and to edit: the paper's cases, hoses, cables, harnesses, CAD, scenes and
    stiffness tests."""
    import shutil  # noqa: PLC0415

    source = examples_folder()
    if not source.is_dir():
        raise PliantError(f"the examples are missing: {source}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise PliantError(f"{out}: exists and is not an empty folder; give a new one (pliant "
                          "never writes over your files)")
    partial = out.with_name(f".{out.name}.partial")
    shutil.rmtree(partial, ignore_errors=True)
    # Links (the demo scenes in the repository) are copied as the files they point to;
    # a whole copy appears at once, or none.
    shutil.copytree(source, partial, symlinks=False,
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    if out.exists():
        out.rmdir()
    partial.rename(out)
    count = sum(1 for p in out.rglob("*.toml"))
    typer.echo(f"{count} example files copied to {out}; try: pliant evaluate "
               f"{out / 'scenes' / 'engine_bay.toml'}")


@app.command()
def view(
    scene: Annotated[Path | None, typer.Argument(help="a scene or problem file (TOML); "
                                                     "default: the bundled engine bay")]
    = None,
    port: Annotated[int, typer.Option(help="the port to listen on (0: any free one)")] = 8765,
    host: Annotated[str, typer.Option(help="the address to listen on; 127.0.0.1 keeps it to "
                                           "this machine (0.0.0.0: every interface, only "
                                           "when you mean it)")] = "127.0.0.1",
    elements: Annotated[int | None, typer.Option(help="3D: about how many elements "
                                                      "(default: the file's \\[solver])")]
    = None,
    envelope: Annotated[Path | None, typer.Option(help="show a variation study's tolerance "
                                                       "envelope (its folder or "
                                                       "envelope.glb)")] = None,
    triangles: Annotated[int | None, typer.Option(help="how many triangles the page draws "
                                                       "of the obstacles at most (default "
                                                       "400000; decimated for the eye, "
                                                       "contact keeps the exact meshes); "
                                                       "lower it for a slow GPU")] = None,
    sessions: Annotated[int | None, typer.Option(help="the most browser tabs served at once, "
                                                      "each with its own solver process "
                                                      "(default: the cores, at least 2)")]
    = None,
    idle: Annotated[float, typer.Option(help="seconds a tab may send nothing before its "
                                             "session is closed and its place freed (the "
                                             "page says to reload)")] = 1800.0,
) -> None:
    """The interactive environment in the browser: drag the part's grips (mouse or VR
    controllers), see its shape, the force and moment each hand must apply, what it
    touches and how close it passes. Each browser tab gets its own session."""
    from pliant.viewer.server import Server  # noqa: PLC0415
    from pliant.viewer.state import ViewerState  # noqa: PLC0415

    elements = _elements(elements)
    if triangles is not None and not 1_000 <= triangles <= 50_000_000:
        raise PliantError(f"--triangles: must be from 1000 to 50000000, got {triangles}")
    scene = scene or DEMO
    if sessions is not None and not 1 <= sessions <= 256:
        raise PliantError(f"--sessions: must be from 1 to 256, got {sessions}")
    server = Server(scene, host=host, port=port, elements=elements, envelope=envelope,
                    display=triangles, sessions=sessions, idle=idle)
    typer.echo(f"checking {scene.name} and loading the solvers…")
    check = ViewerState(server.scene, server.root, live=False, elements=elements)
    check.close()
    if check.session.start_error:
        typer.echo(f"warning: the start pose has no equilibrium ({check.session.start_error});"
                   " the page opens: move the grips to a pose that has one", err=True)
    if host not in ("127.0.0.1", "localhost", "::1"):
        typer.echo(f"warning: listening on {host}: other machines can reach this server",
                   err=True)
    server.run(on_ready=lambda url: typer.echo(f"pliant view: open {url} in a browser "
                                               "(Ctrl+C stops)"))


def _summaries() -> None:
    """Each command's line in ``pliant --help``: its docstring's first paragraph as one
    line (typer keeps the source's line breaks there, which wrap mid-sentence)."""
    for info in app.registered_commands:
        doc = inspect.cleandoc(info.callback.__doc__ or "") if info.callback else ""
        if info.short_help is None and doc:
            info.short_help = " ".join(doc.split("\n\n")[0].split())


_summaries()


def main() -> None:
    """Run the app, turning pliant's errors into one-line messages (``SystemExit`` with
    the status)."""
    from pliant.io.atomic import WRITTEN  # noqa: PLC0415

    WRITTEN.clear()  # what this command writes, said if it is interrupted
    try:
        app()
    except PliantError as err:
        typer.echo(f"error: {err}", err=True)
        sys.exit(2)
    except SystemExit as done:
        # Typer turns Ctrl+C into a silent exit with 130 (its Exit raised from the
        # KeyboardInterrupt): say what was written. A command that said it already
        # raised its own Exit from None.
        if done.code == 130 and _caused_by_interrupt(done):
            typer.echo(_interrupted(), err=True)
        raise
    except KeyboardInterrupt:
        typer.echo(_interrupted(), err=True)
        sys.exit(130)
    except SystemError as err:
        # Ctrl+C that lands while a compiled kernel hands back its result comes out as
        # "returned a result with an exception set", caused by the KeyboardInterrupt.
        if _caused_by_interrupt(err):
            typer.echo(_interrupted(), err=True)
            sys.exit(130)
        raise


def _caused_by_interrupt(error: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in the exception's chain of causes (its
    ``__cause__``, else its unsuppressed ``__context__``)."""
    seen: set[int] = set()
    at: BaseException | None = error
    while at is not None and id(at) not in seen:
        if isinstance(at, KeyboardInterrupt):
            return True
        seen.add(id(at))
        at = at.__cause__ if at.__cause__ is not None else (
            None if at.__suppress_context__ else at.__context__)
    return False


def _interrupted() -> str:
    """The line an interrupted command ends with: what it had written (each file whole),
    so that a set of outputs cut short is marked as such, or that it wrote nothing."""
    from pliant.io.atomic import WRITTEN  # noqa: PLC0415

    if not WRITTEN:
        return "interrupted: nothing written"
    return (f"interrupted: the outputs are incomplete; written before the interrupt (each "
            f"file whole, a store's lines each whole: run the command again to resume "
            f"where it can): {WRITTEN.summary()}")


def entry() -> None:
    """The ``pliant`` command: ``main``, then leave at once (``_leave``)."""
    try:
        main()
    except SystemExit as done:
        _leave(done.code)
    _leave(0)


def _leave(code: object) -> None:
    """End the process once the command is done: wait for its threads, run the exit
    handlers (Dask's and multiprocessing's close their processes), flush the output,
    and exit without tearing the interpreter down module by module, which after a
    solve (numba's compiled libraries, matplotlib's state) took 0.5-0.9 s of a 5 s
    demo. Every file pliant writes is closed (and renamed into place) before this.
    Under a profiler or tracer (``python -m cProfile``, coverage) it exits as usual, so
    that they write what they found."""
    import atexit  # noqa: PLC0415
    import threading  # noqa: PLC0415

    if sys.getprofile() is not None or sys.gettrace() is not None:
        sys.exit(code)  # type: ignore[arg-type]
    if isinstance(code, str):  # sys.exit("message"), as Python prints it
        print(code, file=sys.stderr)
        code = 1
    status = 0 if code is None else code if isinstance(code, int) else 1
    for thread in threading.enumerate():
        if thread is not threading.current_thread() and not thread.daemon:
            thread.join()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: nothing more can be said
            pass
    os._exit(status)


if __name__ == "__main__":
    entry()
