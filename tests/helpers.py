"""Shared test problems."""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import pliant as pl
from pliant.io.problem_file import load_problem

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@lru_cache(maxsize=1)
def zoo() -> dict[str, pl.Problem]:
    """A spread of well-posed 2D problems: the paper's cases and everyday variants."""
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3)
    curved = pl.Part(length=1.0, bending_stiffness=1.0,
                     rest_curvature=((0.0, 2.0), (0.5, -1.0), (1.0, 0.0)))
    unit = pl.Part(length=1.0, bending_stiffness=1.0)
    problems = {f"case{i}": load_problem(EXAMPLES / "paper" / f"case{i}.toml")
                for i in (1, 2, 3)}
    problems["gravity grip"] = pl.Problem(
        hose, (pl.clamp(0.0), pl.grip(0.6, position=(0.5, -0.1), name="hand")),
        gravity=(0.0, -9.81))
    problems["pre-curved pin"] = pl.Problem(
        curved, (pl.pin(0.0), pl.grip(1.0, position=(0.6, 0.3), name="hand")))
    problems["two hands, free ends"] = pl.Problem(
        hose, (pl.grip(0.2, position=(0.0, 0.0), angle=0.3, name="left"),
               pl.grip(0.85, position=(0.45, 0.1), name="right")), gravity=(0.0, -9.81))
    problems["compressed cantilever"] = pl.Problem(
        unit, (pl.clamp(0.0), pl.push(1.0, force=(-30.0, 3.0), name="tip")))
    problems["follower and moment"] = pl.Problem(
        unit, (pl.clamp(0.0, angle=0.4), pl.push(0.4, moment=-2.0, name="twist"),
               pl.push(1.0, force=(1.0, 4.0), follower=True, name="tip")))
    return problems


def cli(*args: str):
    """Run ``pliant ARGS`` in this process (the subprocess path, with its start-up and
    one-line errors, is tested in test_cli.py): (returncode, stdout, stderr) like
    subprocess.run's result, without a new interpreter's seconds of imports."""
    from types import SimpleNamespace

    from typer.testing import CliRunner

    from pliant.cli.app import app

    result = CliRunner().invoke(app, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return SimpleNamespace(returncode=result.exit_code, stdout=result.stdout,
                           stderr=result.stderr)
