"""Both hands carrying (issue 56, item 4, as far as it goes): a [path]'s ``carry`` moves
other hands with its grip as one rigid carrier, along a path and in the planner; a long
hose carried by both ends clears a post that it drags over with one hand."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pliant as pl
from pliant.assembly.evaluate import evaluate
from pliant.assembly.path import carry
from pliant.assembly.plan import Planner
from pliant.assembly.scenes import load_scene
from pliant.core.planning import PathSpec, PlanSettings
from pliant.core.rotations import rotation_between
from pliant.errors import FileFormatError, InputError

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "hoses" / "carry_past_post.toml"


def test_the_carried_hand_keeps_its_place_on_the_carrier():
    """Along a path that turns the grip's axis, the carried hand is where the least
    rotation from the grip's first axis and the grip's move take it: its distance to the
    grip and its axis's angle to the grip's stay those at the start."""
    part = pl.Part(1.0, 1.0)
    grip = pl.Condition(s=1.0, name="right", position=(0.6, 0.0, 0.0), tangent=(1, 0, 0),
                        normal=(0, 0, 1))
    other = pl.Condition(s=0.0, name="left", position=(0.0, 0.0, 0.0),
                         tangent=(0.0, 0.6, 0.8), normal=(1, 0, 0))
    problem = pl.Problem(part, (grip, other))
    spec = PathSpec("right", ((0.6, 0.2, 0.1), (0.3, 0.5, 0.2)),
                    ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), 10, ("left",))
    steps = carry(problem, spec)
    assert len(steps) == 10
    for p in steps:
        g, o = p.condition("right"), p.condition("left")
        turn = rotation_between(np.array([1.0, 0, 0]), np.asarray(g.tangent))
        np.testing.assert_allclose(o.position, np.asarray(g.position) + turn @ np.array(
            [-0.6, 0.0, 0.0]), atol=1e-12)
        np.testing.assert_allclose(o.tangent, turn @ np.array([0.0, 0.6, 0.8]), atol=1e-12)
        np.testing.assert_allclose(o.normal, turn @ np.array([1.0, 0.0, 0.0]), atol=1e-12)
    with pytest.raises(InputError, match=r"path\.carry"):
        carry(problem, replace(spec, carry=("nobody",)))


def test_rotation_between_is_the_least_rotation():
    rng = np.random.default_rng(7)
    for _ in range(20):
        a, b = (v / np.linalg.norm(v) for v in rng.normal(size=(2, 3)))
        r = rotation_between(a, b)
        np.testing.assert_allclose(r @ a, b, atol=1e-12)
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
        axis = np.cross(a, b)
        np.testing.assert_allclose(r @ axis, axis, atol=1e-12)  # about a x b only
    np.testing.assert_allclose(rotation_between(a, -a) @ a, -a, atol=1e-12)


def test_a_long_hose_carried_by_both_ends_clears_a_post_one_hand_drags_it_over():
    carried = load_scene(EXAMPLE)
    assert carried.path_spec.carry == ("left hand",)
    ev = evaluate(carried, search=False)
    assert ev.run.complete and ev.verdict.assemblable
    assert min(dict(r.clearances)["post"] for r in ev.run.steps) > carried.margin
    assert ev.grips == ("right hand", "left hand")  # both hands judged
    # the left hand went where the right went: (0.8, 0.9, 0.7) - (0.8, 0, 0.5) on
    np.testing.assert_allclose(carried.path[-1].condition("left hand").position,
                               (0.0, 0.9, 0.7), atol=1e-12)
    np.testing.assert_allclose(ev.run.equilibria[-1].position[0], (0.0, 0.9, 0.7),
                               atol=1e-9)
    # the same path with the left hand left at its start
    alone = replace(carried, path_spec=replace(carried.path_spec, carry=()),
                    path=carry(carried.problem, replace(carried.path_spec, carry=())))
    ev1 = evaluate(alone, search=False)
    assert min(dict(r.clearances)["post"] for r in ev1.run.steps) <= carried.margin
    assert not ev1.verdict.assemblable
    # The hands' distance (issue 56): carried, 0.8 m apart throughout (green for the 5th
    # percentile woman); left behind, as far as the path's targets take the right hand
    # from it (1.38 m, over the post), past the spread that raises her upper arms above
    # 20 degrees: yellow, with why.
    widest = max(float(np.linalg.norm(np.subtract(p.condition("right hand").position,
                                                  (0.0, 0.0, 0.5)))) for p in alone.path)
    assert 1.13 < widest < 1.42
    for result, apart, zone in ((ev, 0.8, "green"), (ev1, widest, "yellow")):
        [check] = [c for c in result.operators[0].checks
                   if c.rule == "hands apart: right hand and left hand"]
        assert check.value == pytest.approx(apart, abs=1e-6) and check.zone.value == zone
        assert "5th percentile woman" in check.note and "ISO 11226" in check.source


def test_the_planner_moves_the_carried_hand_with_the_grip_and_writes_it(tmp_path):
    """The planner's pose carries the other hand (its tree's problem at a pose), its
    written [path] keeps ``carry``, and a bad carry is refused by name."""
    from pliant.assembly.plan import Plan, Pose, _Tree, _Turning
    from pliant.io.problem_file import read_text, with_path_table

    scene = load_scene(EXAMPLE)
    planner = Planner(scene, PlanSettings(carry=("left hand",)), grip="right hand")
    turning = _Turning.between((0.87, 0.0, 0.5), (0.0, 1.0, 0.0), np.array([0, 1.0, 0]),
                               0.14)
    tree = _Tree(scene, "right hand", planner.settings, planner.rules, planner.solver,
                 planner.bend_limit, turning)
    p = tree.problem_at((0.8, 0.5, 1.0), (0.87, 0.0, 0.5))  # moved up and along, not turned
    np.testing.assert_allclose(p.condition("left hand").position, (0.0, 0.5, 1.0),
                               atol=1e-12)
    plan = Plan("right hand", "port", [Pose((0.8, 0.3, 1.0), (0.87, 0.0, 0.5))], [], None,
                1.0, [], 0.0, 0, 0, 0, 0, 5, carry=("left hand",))
    text = with_path_table(read_text(EXAMPLE), plan.path_table(), str(EXAMPLE),
                           EXAMPLE.parent, tmp_path)
    (tmp_path / "planned.toml").write_text(text)
    again = load_scene(tmp_path / "planned.toml")
    assert again.path_spec.carry == ("left hand",)
    np.testing.assert_allclose(again.path[-1].condition("left hand").position,
                               (0.0, 0.3, 1.0), atol=1e-9)
    with pytest.raises(InputError, match=r"path\.carry"):
        Planner(scene, PlanSettings(carry=("right hand",)), grip="right hand")
    bad = EXAMPLE.read_text().replace('carry = ["left hand"]', 'carry = ["nobody"]')
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(FileFormatError, match=r"path\.carry"):
        load_scene(tmp_path / "bad.toml")


def test_the_planner_carries_the_hose_by_both_ends_past_the_post_where_one_hand_cannot():
    """The issue's figure: carrying both ends, OMPL's search finds a way over the post
    into the bench port (every step followed again, the carried hand at the end where
    the carrier took it); carrying one end, with the other left where it started, no
    way is found within the budget."""
    from pliant.assembly.plan import NoPathError, plan

    scene = load_scene(EXAMPLE)
    both = plan(scene, "bench port", replace(scene.plan, budget=60.0, attempts=1))
    assert both.run.complete and both.carry == ("left hand",)
    assert min(dict(r.clearances)["post"] for r in both.run.steps) >= scene.margin
    end = both.run.equilibria[-1]
    np.testing.assert_allclose(end.position[-1], (0.8, 0.9, 0.7), atol=1e-6)
    np.testing.assert_allclose(end.position[0], (0.0, 0.9, 0.7), atol=1e-6)  # carried
    with pytest.raises(NoPathError):
        plan(scene, "bench port", replace(scene.plan, carry=(), budget=3.0, attempts=1))
