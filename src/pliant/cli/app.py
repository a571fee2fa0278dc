"""The ``pliant`` command line.

Heavy modules (numba kernels, scipy, matplotlib, pydantic) are imported inside the
commands that need them, so ``pliant --help`` answers at once. Every error pliant raises
on purpose ends the command with a one-line message and exit status 2, never a
traceback.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from pliant.errors import PliantError

app = typer.Typer(
    name="pliant",
    help="Flexible parts (hoses, pipes, cables) in assembly and disassembly.",
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)

EXAMPLES = Path(__file__).resolve().parents[3] / "examples"  # the repository (editable install)


@app.command()
def solve(
    file: Annotated[Path, typer.Argument(help="a problem file (TOML, SI units)")],
    json: Annotated[bool, typer.Option("--json", help="print the full result as JSON")] = False,
    plot: Annotated[Path | None, typer.Option(help="draw the shape and its internal forces "
                                                   "to this PNG file")] = None,
    mesh: Annotated[Path | None, typer.Option(help="export the deformed tube (.glb, .gltf, "
                                                   ".stl, .obj, .ply)")] = None,
    elements: Annotated[int | None, typer.Option(help="3D: about how many elements "
                                                      "(default: the file's \\[solver], or 100)")]
    = None,
) -> None:
    """Solve a problem file (2D or 3D): shape, internal forces, reactions."""
    from pliant.cli.report import print_json, print_summary, timed_solve  # noqa: PLC0415
    from pliant.io.problem_file import load_problem_file  # noqa: PLC0415

    problem, settings = load_problem_file(file)
    eq, seconds = timed_solve(problem, elements or settings.elements)
    if json:
        print_json(eq, seconds)
    else:
        print_summary(eq, seconds)
    if plot is not None:
        from pliant.cli.plot import plot_equilibrium  # noqa: PLC0415

        plot_equilibrium(eq, plot)
        if not json:
            typer.echo(f"plot written to {plot}")
    if mesh is not None:
        from pliant.io.mesh_export import export_mesh, part_radius  # noqa: PLC0415

        export_mesh(eq, mesh)
        if not json:
            note = "" if problem.part.outer_diameter else " (display radius: no outer_diameter)"
            typer.echo(f"mesh written to {mesh}, radius {part_radius(eq):.4g} m{note}")


@app.command()
def demo(
    out: Annotated[Path, typer.Option(help="folder for the plots")] = Path("pliant-demo"),
) -> None:
    """The main job for now: solve and plot the paper's three cases (examples/paper)."""
    from pliant.cli.plot import plot_equilibrium  # noqa: PLC0415
    from pliant.cli.report import print_summary, timed_solve  # noqa: PLC0415
    from pliant.io.problem_file import load_problem  # noqa: PLC0415

    files = sorted((EXAMPLES / "paper").glob("case*.toml"))
    if not files:
        raise PliantError(f"no paper examples found under {EXAMPLES / 'paper'}")
    out.mkdir(parents=True, exist_ok=True)
    for file in files:
        problem = load_problem(file)
        eq, seconds = timed_solve(problem)
        print_summary(eq, seconds)
        target = out / f"{file.stem}.png"
        plot_equilibrium(eq, target)
        typer.echo(f"plot written to {target}\n")


def main() -> None:
    """Entry point: run the app, turning pliant's errors into one-line messages."""
    try:
        app()
    except PliantError as err:
        typer.echo(f"error: {err}", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
