"""Bad input gets a typed error that names the field and says what to change."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pliant as pl
from pliant.errors import ConvergenceError, IllPosedProblemError, InputError, UnreachableTargetError
from pliant.models.elastica2d import ShootingSolver, solve
from pliant.models.rod3d import RodSolver

UNIT = pl.Part(length=1.0, bending_stiffness=1.0)


@pytest.mark.parametrize("kwargs,field", [
    ({"length": 0.0, "bending_stiffness": 1.0}, "length"),
    ({"length": -1.0, "bending_stiffness": 1.0}, "length"),
    ({"length": math.nan, "bending_stiffness": 1.0}, "length"),
    ({"length": 1.0, "bending_stiffness": 0.0}, "bending_stiffness"),
    ({"length": 1.0, "bending_stiffness": -2.0}, "bending_stiffness"),
    ({"length": 1.0, "bending_stiffness": 1.0, "mass_per_length": -1.0}, "mass_per_length"),
    ({"length": 1.0, "bending_stiffness": 1.0, "outer_diameter": 0.01,
      "inner_diameter": 0.02}, "inner_diameter"),
    ({"length": 1.0, "bending_stiffness": 1.0,
      "rest_curvature": ((0.0, 1.0), (2.0, 1.0))}, "rest_curvature[1]"),
    ({"length": 1.0, "bending_stiffness": 1.0,
      "rest_curvature": ((0.5, 1.0), (0.2, 1.0))}, "rest_curvature[1]"),
])
def test_invalid_part(kwargs, field):
    with pytest.raises(InputError) as err:
        pl.Part(**kwargs)
    assert err.value.field == field
    assert str(err.value).startswith(field)


def test_invalid_material():
    with pytest.raises(InputError, match="youngs_modulus"):
        pl.Material(youngs_modulus=0.0)
    with pytest.raises(InputError, match="poisson_ratio"):
        pl.Material(youngs_modulus=1e6, poisson_ratio=0.7)


def test_station_outside_the_part():
    with pytest.raises(InputError, match=r"hand\.s: station s = 1\.5 m lies outside"):
        pl.Problem(UNIT, (pl.clamp(0.0), pl.push(1.5, force=(0, 1), name="hand")))


def test_component_both_prescribed_and_applied():
    with pytest.raises(IllPosedProblemError, match="both prescribed"):
        pl.Condition(s=1.0, name="tip", position=(0.5, None), force=(2.0, None))
    with pytest.raises(IllPosedProblemError, match="angle is both prescribed"):
        pl.Condition(s=1.0, name="tip", angle=0.0, moment=1.0)
    # Two conditions at one station claiming the same component.
    with pytest.raises(IllPosedProblemError, match="both prescribed and loaded"):
        pl.Problem(UNIT, (pl.clamp(0.0), pl.grip(1.0, position=(0.5, 0.5), name="hand"),
                          pl.push(1.0, force=(1.0, 0.0), name="other")))
    with pytest.raises(IllPosedProblemError, match="both prescribe x"):
        pl.Problem(UNIT, (pl.clamp(0.0), pl.grip(1.0, position=(0.5, 0.5), name="a"),
                          pl.grip(1.0, position=(0.6, 0.5), name="b")))
    with pytest.raises(IllPosedProblemError, match="follower force cannot act"):
        pl.Condition(s=1.0, position=(0.5, 0.5), force=(0, 1), follower=True)


@pytest.mark.parametrize("conditions,missing", [
    ((), "x, y"),
    ((pl.push(1.0, force=(0, 1)),), "x, y"),
    ((pl.pin(0.0),), "an angle"),
    ((pl.Condition(s=0.0, name="roller", position=(None, 0.0), angle=0.0),), "x"),
])
def test_too_few_conditions(conditions, missing):
    with pytest.raises(IllPosedProblemError, match="too few conditions") as err:
        pl.Problem(UNIT, conditions)
    assert missing in str(err.value)


def test_duplicate_names():
    with pytest.raises(InputError, match="two conditions are named 'a'"):
        pl.Problem(UNIT, (pl.clamp(0.0, name="a"), pl.push(1.0, force=(0, 1), name="a")))


@pytest.mark.parametrize("target", [(1.2, 0.0), (0.0, 1.0), (0.8, 0.7), (1.0, 0.0)])
def test_target_out_of_reach(target):
    with pytest.raises(UnreachableTargetError, match="inextensible") as err:
        pl.Problem(UNIT, (pl.clamp(0.0), pl.grip(1.0, position=target, name="hand")))
    assert err.value.field == "hand.position"


def test_interior_target_out_of_reach():
    with pytest.raises(UnreachableTargetError):
        pl.Problem(UNIT, (pl.clamp(0.0), pl.grip(0.3, position=(0.0, 0.35), name="hand")))


def test_non_convergence_says_so_with_residual():
    # A follower load: no potential, so no energy minimum to fall back on.
    problem = pl.Problem(UNIT, (pl.clamp(0.0), pl.push(1.0, force=(0.0, 50.0),
                                                        follower=True)))
    with pytest.raises(ConvergenceError) as err:
        solve(problem, solver=ShootingSolver(max_steps=2))
    assert "budget" in str(err.value)
    assert err.value.residual > 0.0
    assert 0.0 <= err.value.progress < 1.0


def test_a_solve_asked_not_to_throw_returns_what_its_error_would_say():
    """``pl.solve(..., throw=False)`` (issue 59: a search asks instead of catching):
    where the solve raises, the same problem gives an ``Unsolved`` carrying that error's
    status, residual, progress and message, ``ok`` False; where it answers, the same
    equilibrium, ``ok`` True. 2D and 3D, cold and warm."""
    def follower(force: float) -> pl.Problem:
        return pl.Problem(UNIT, (pl.clamp(0.0), pl.push(1.0, force=(0.0, force),
                                                         follower=True)))

    start = pl.solve(follower(1.0), throw=False)
    assert start.ok is True
    budget = ShootingSolver(max_steps=2)  # a warm step of 49 N in 2 steps: refused
    with pytest.raises(ConvergenceError) as raised:
        pl.solve(follower(50.0), warm_start=start, solver=budget)
    failed = pl.solve(follower(50.0), warm_start=start, solver=budget, throw=False)
    assert isinstance(failed, pl.Unsolved) and failed.ok is False
    assert type(failed.error) is ConvergenceError and failed.problem == follower(50.0)
    assert failed.status is not None
    assert (failed.status, failed.residual, failed.progress, failed.message) == (
        raised.value.status, raised.value.residual, raised.value.progress,
        str(raised.value))
    good = pl.Problem(UNIT, (pl.clamp(0.0), pl.grip(1.0, position=(0.6, 0.5), angle=1.0)))
    answer = pl.solve(good, throw=False)
    assert answer.ok is True
    assert np.array_equal(answer.position, pl.solve(good).position)
    rod = pl.Part(1.0, 1.0)
    far = pl.Problem(rod, (pl.clamp(0.0, (0.0, 0.0, 0.0)),
                           pl.grip(1.0, (0.5, 0.5, 0.0), tangent=(0.0, 1.0, 0.0))))
    cold = pl.solve(far, throw=False)
    assert cold.ok and pl.solve(far, warm_start=cold, throw=False).ok


def test_trace_stops_at_a_snap_through_with_the_last_good_state():
    """A clamped-clamped strip, buckled by pushing its ends together, snaps through when
    one end is turned far enough (a fold of the equilibrium path). Following the turn,
    trace stops there with a ConvergenceError carrying the last equilibrium, instead of
    jumping silently to the snapped shape; the fold is genuine: the mid-span's
    sensitivity to the turn grows without bound as it nears."""
    def problem(turn: float) -> pl.Problem:
        return pl.Problem(UNIT, (pl.clamp(0.0),
                                 pl.clamp(1.0, position=(0.9, 0.0), angle=turn, name="end")))

    turns = np.linspace(0.0, 1.0, 101)[1:]
    # The branch that bows to the left (the lower of the two at a turn of -0.01 rad; at
    # +0.01 the lower bows right, and turning on from there does not snap).
    left = pl.solve(problem(-0.01))
    assert left.position[50, 1] > 0.05
    seen = []
    with pytest.raises(ConvergenceError) as err:
        for eq in pl.trace([problem(a) for a in turns], start=left):
            seen.append(eq)
    assert "fold" in str(err.value)
    assert err.value.last_good is seen[-1]
    assert 0.3 < seen[-1].problem.condition("end").angle < 0.9
    mid = np.array([eq.position[np.argmin(np.abs(eq.s - 0.5)), 1] for eq in seen])
    slope = np.abs(np.diff(mid) / np.diff(turns[:len(seen)]))
    assert slope[-1] > 10 * slope[0]
    # Turned the other way, the strip follows smoothly.
    *_, last = pl.trace([problem(-a) for a in turns], start=left)
    assert last.residual < 1e-9


def test_files_that_are_not_text_too_deep_or_far_out_get_one_line_errors(tmp_path):
    from pliant.errors import FileFormatError, UnreachableTargetError
    from pliant.io.problem_file import load_problem

    (tmp_path / "binary.toml").write_bytes(b"x = \xff\xfe\n")
    with pytest.raises(FileFormatError, match="not a text file in UTF-8"):
        load_problem(tmp_path / "binary.toml")
    (tmp_path / "deep.toml").write_text("a = " + "[" * 100000 + "]" * 100000 + "\n")
    with pytest.raises(FileFormatError, match="nested too deeply"):
        load_problem(tmp_path / "deep.toml")
    with pytest.raises(UnreachableTargetError, match="reaches or exceeds"):
        pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.pin(1.0, position=(1e160, 0.0))))


def test_a_terminal_escape_in_a_name_is_refused_naming_the_field(tmp_path):
    """Issue 54: names with ANSI escapes reached the terminal raw (an ESC [2J in a part's
    name clears the user's screen). Any string or key of a TOML file holding a control
    character is refused, naming where; tabs and line breaks are text. Through the CLI:
    one line, no traceback, and no escape written."""
    import subprocess
    import sys

    from pliant.errors import FileFormatError
    from pliant.io.problem_file import load_problem

    good = (tmp_path / "ok.toml")
    good.write_text('[part]\nlength = 1.0\nbending_stiffness = 1.0\nname = "hose\\tA"\n'
                    '[[condition]]\nname = "clamp"\ns = 0.0\nx = 0.0\ny = 0.0\nangle = 0.0\n'
                    '[[condition]]\nname = "tip"\ns = 1.0\nFx = 0.0\nFy = -1.0\n')
    assert load_problem(good).part.name == "hose\tA"
    bad = tmp_path / "escape.toml"
    bad.write_text(good.read_text().replace('name = "tip"', 'name = "tip\\u001b[2J"'))
    with pytest.raises(FileFormatError, match=r"condition\[1\]\.name: holds the control "
                                              r"character U\+001B"):
        load_problem(bad)
    done = subprocess.run([sys.executable, "-m", "pliant.cli.app", "solve", str(bad)],
                          capture_output=True, text=True, timeout=300)
    said = done.stdout + done.stderr
    assert done.returncode != 0 and "\x1b" not in said and "Traceback" not in said
    assert "U+001B" in said and len(said.strip().splitlines()) == 1


@pytest.mark.parametrize(("problem", "field"), [
    (lambda pl: pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.push(
        1.0, force=(0.0, 1e38), name="tip"))), "tip.force"),
    (lambda pl: pl.Problem(pl.Part(1.0, 1e-300), (pl.clamp(0.0), pl.push(
        1.0, force=(0.0, 1.0), name="tip"))), "part.bending_stiffness"),
    (lambda pl: pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.push(
        1.0, force=(0.0, 0.0), moment=1e12, name="tip"))), "tip.moment"),
    (lambda pl: pl.Problem(pl.Part(1.0, 1.0, rest_curvature=1e12), (pl.clamp(0.0), pl.push(
        1.0, force=(0.0, 0.0), name="tip"))), "part.rest_curvature"),
    # a 10 m cable of EI 1e-4 pulled with 100 N: F L^2 / EI = 1e8 (it grew to 1 GB)
    (lambda pl: pl.Problem(pl.Part(10.0, 1e-4), (pl.clamp(0.0), pl.push(
        10.0, force=(100.0, 1.0), name="tip"))), "tip.force"),
    # 3D (issue 54: "the start is singular"), past a millionth of the length
    (lambda pl: pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0, (0, 0, 0)), pl.push(
        1.0, force=(0.0, 0.0, 1e38), name="tip"))), "tip.force"),
    (lambda pl: pl.Problem(pl.Part(1.0, 1e-300), (pl.clamp(0.0, (0, 0, 0)), pl.push(
        1.0, force=(0.0, 0.0, 1.0), name="tip"))), "part.bending_stiffness"),
    (lambda pl: pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0, (0, 0, 0)), pl.push(
        1.0, force=(0.0, 0.0, 0.0), moment=(0.0, 1e12, 0.0), name="tip"))), "tip.moment"),
])
def test_loads_far_past_bending_are_refused_at_once_by_name(problem, field):
    """Loads that bend the part on a scale under a thousandth of its length (a unit slip
    far more often than a part) are refused before any work, naming what does it; they
    looped in the 2D set-up, one for minutes and a gigabyte."""
    import pliant as pl
    from pliant.errors import InputError

    with pytest.raises(InputError, match="k L = ") as err:
        pl.solve(problem(pl))
    assert err.value.field == field


@pytest.mark.parametrize(("make", "field"), [
    (lambda: RodSolver(elements=0), "RodSolver.elements"),
    (lambda: RodSolver(elements=-5), "RodSolver.elements"),
    (lambda: RodSolver(elements=200_000), "RodSolver.elements"),
    (lambda: RodSolver(tolerance=0.0), "RodSolver.tolerance"),
    (lambda: ShootingSolver(max_steps=0), "ShootingSolver.max_steps"),
    (lambda: ShootingSolver(contraction=1.5), "ShootingSolver.contraction"),
    (lambda: ShootingSolver(time_budget=float("nan")), "ShootingSolver.time_budget"),
    (lambda: pl.grip(1.0, position=(0.5, 0.5), angle=1e300, name="hand"), "hand.angle"),
])
def test_settings_and_angles_out_of_range_are_named_not_no_equilibrium(make, field):
    """Issue: `elements` of 0 or -5 and an angle of 1e300 came back as "no equilibrium",
    which sends the user after the wrong cause."""
    with pytest.raises(InputError) as err:
        make()
    assert err.value.field == field
