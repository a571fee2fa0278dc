"""Reach and posture (issue 56, item 3): the worker's stick figure against closed forms
(the arm's reach at a percentile of the cited table, the least trunk bend that brings a
grip within reach, the elbow's lowest place), and through the evaluation (a grip out of
reach is red and says by how much, each hand its own arm, the JSON, a bad [worker])."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pliant.assembly.checks import Zone
from pliant.assembly.evaluate import evaluate
from pliant.assembly.posture import Figure
from pliant.assembly.scenes import load_scene, parse_scene
from pliant.core.worker import Worker
from pliant.errors import FileFormatError, InputError
from pliant.io.evaluation_file import EvaluationReport
from pliant.io.rules_file import bundled_rules

from .helpers import hand_held_hose

BODY = bundled_rules().body
UP = np.array([0.0, 0.0, 1.0])
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def figure(**kw) -> Figure:
    return Figure(Worker((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), **kw), BODY, UP)


@pytest.mark.parametrize(("sex", "percentile", "table"), [
    ("men", 5, 0.610), ("men", 50, 0.665), ("men", 95, 0.715), ("women", 5, 0.555),
    ("women", 50, 0.600)])
def test_the_arm_reach_is_the_cited_tables_percentile(sex, percentile, table):
    """Bodyspace's shoulder-grip length (British adults 19 to 65): the figure's arm at a
    percentile (mean + z SD) is the table's value there, to the table's own rounding:
    its percentiles and mean to 5 mm (2.5 mm each) and its SD to 1 mm (times z = 1.645:
    0.8 mm), 5.8 mm at most."""
    assert figure(sex=sex, percentile=percentile).arm == pytest.approx(table, abs=0.0058)


def test_a_grip_within_reach_ahead_of_the_shoulder_needs_no_bend_and_the_elbow_hangs():
    """Straight ahead of the right shoulder at its height, nearer than the arm's reach:
    upright, and the upper arm's elevation is that of the elbow's lowest place on its
    circle: atan(x / rho), x = (a^2 - b^2 + d^2) / 2d along the reach, rho across."""
    f = figure()
    right = np.cross(f.facing, f.up)
    shoulder = f.hip + f.trunk * UP + f.half_breadth * right
    d = 0.8 * f.arm
    got = f.reach(shoulder + d * f.facing, "right")
    a, b = f.upper, f.arm - f.upper
    x = (a * a - b * b + d * d) / (2 * d)
    assert got.trunk == 0.0
    assert got.excess == pytest.approx(d - f.arm, abs=1e-12)
    assert got.upper_arm == pytest.approx(math.degrees(math.atan2(x, math.sqrt(a * a - x * x))),
                                          abs=1e-9)
    assert np.linalg.norm(np.subtract(got.elbow, got.shoulder)) == pytest.approx(a)
    assert np.linalg.norm(shoulder + d * f.facing - got.elbow) == pytest.approx(b)


@pytest.mark.parametrize("posture", ["standing", "kneeling"])
def test_the_least_trunk_bend_that_reaches_is_the_closed_form(posture):
    """A grip at hip height straight ahead of the hip, x from it: bent theta forward, the
    right shoulder is at (T sin theta, h, T cos theta) from the hip, so it reaches where
    x^2 - 2 x T sin theta + T^2 + h^2 = L^2."""
    f = figure(posture=posture)
    T, h, L = f.trunk, f.half_breadth, f.arm
    x = 0.9
    got = f.reach(f.hip + x * f.facing, "right")  # without zones: the least bend
    expected = math.degrees(math.asin((x * x + T * T + h * h - L * L) / (2 * x * T)))
    assert got.trunk == pytest.approx(expected, abs=1e-6)
    assert f.least_bend(f.hip + x * f.facing, "right") == got.trunk
    assert got.excess == pytest.approx(0.0, abs=1e-9)
    stature = BODY.stature["women"][0] - 1.6448536 * BODY.stature["women"][1]
    drop = BODY.knee_height * stature if posture == "kneeling" else 0.0
    assert f.hip[2] == pytest.approx(BODY.hip_height * stature - drop, abs=1e-6)


@pytest.mark.parametrize(("x", "z"), [(0.6, 0.9), (0.75, 1.2), (0.9, 0.6), (0.5, 1.5),
                                      (0.3, 0.4)])
def test_the_posture_kept_is_the_least_at_risk_an_exhaustive_search_finds(x, z):
    """Bending further than the least lowers the arm: the bend kept minimises the worse
    of the two ratios to their red onsets, as a search every 0.05 deg from the least
    bend finds (to the 0.5 deg grid's worth: 1 deg of trunk on its 60 deg scale)."""
    zones = bundled_rules().posture
    f = figure(sex="men", percentile=50)
    hand = np.array([x, -f.half_breadth, z])  # ahead of the right shoulder
    got = f.reach(hand, "right", zones)

    def cost(r):
        return max(r.trunk / zones.trunk[1], r.upper_arm / zones.upper_arm[1])

    least = f.least_bend(hand, "right")
    fine = [f.posture(hand, "right", b) for b in np.arange(least, 90.0 + 1e-9, 0.05)]
    assert got.excess <= 1e-12 and got.trunk >= least
    assert cost(got) <= cost(f.posture(hand, "right", least))
    assert cost(got) <= min(cost(r) for r in fine) + 1.0 / zones.trunk[1]


def test_out_of_reach_even_bent_over_by_the_closed_form():
    f = figure()
    x = f.trunk + f.arm + 0.25
    got = f.reach(f.hip + x * f.facing, "right")
    assert got.trunk == 90.0
    assert got.excess == pytest.approx(math.hypot(x - f.trunk, f.half_breadth) - f.arm,
                                       abs=1e-9)


def test_a_larger_worker_reaches_farther():
    hand = figure().hip + np.array([0.95, 0.0, 0.1])
    small = figure(sex="women", percentile=5).reach(hand, "right")
    large = figure(sex="men", percentile=95).reach(hand, "right")
    assert large.trunk < small.trunk


# -- through the evaluation -----------------------------------------------------------------
SCENE = """
name = "a hose held by one hand, a worker in front"
gravity = [0.0, 0.0, -9.81]
{hose}
[worker]
position = [{x}, 0.0, 0.0]
facing = [-1.0, 0.0, 0.0]
{more}
"""


HOSE = hand_held_hose((0.0, 0.0, 1.0), (0.0, 1.0, 0.0))


def _reach(result, operator="one hand"):
    op = next(o for o in result.operators if o.operator == operator)
    return {c.rule: c for c in op.checks}, op


def test_a_grip_out_of_reach_is_red_and_says_by_how_much():
    far = 2.0
    result = evaluate(parse_scene(SCENE.format(hose=HOSE, x=far, more="")), search=False)
    checks, op = _reach(result)
    reach = checks["reach"]
    assert reach.zone is Zone.RED
    got = op.reach["hand"][0]
    # nearest with the trunk pointing at the grip: the shoulder T from the hip towards
    # it, the right shoulder h aside (the grip is in the worker's mid-plane)
    f = Figure(Worker((far, 0.0, 0.0), (-1.0, 0.0, 0.0)), BODY, UP)
    rise, x = 1.0 - f.hip[2], far
    assert got.trunk == pytest.approx(math.degrees(math.atan2(x, rise)), abs=0.5)
    expected = math.hypot(math.hypot(x, rise) - f.trunk, f.half_breadth) - f.arm
    assert got.excess == pytest.approx(expected, abs=1e-4)
    assert f"out of reach by {got.excess * 1e3:.0f} mm" in reach.note
    assert "5th percentile woman" in reach.note
    assert reach.source == BODY.sourced.source
    assert result.verdict.operator not in ("one hand", "two hands side by side")
    data = json.loads(json.dumps(result.to_dict()))
    EvaluationReport.model_validate(data)
    assert data["operators"][0]["reach"]["hand"][0]["excess"] == pytest.approx(got.excess)


def test_a_grip_at_chest_height_in_front_is_green():
    result = evaluate(parse_scene(SCENE.format(hose=HOSE, x=0.35, more="")), search=False)
    checks, op = _reach(result)
    assert checks["reach"].zone is Zone.GREEN
    assert checks["posture: trunk"].zone is Zone.GREEN
    assert checks["posture: upper_arm"].zone is Zone.GREEN
    # kneeling, the same grip is higher above the shoulder: the arm rises
    kneeling = evaluate(parse_scene(SCENE.format(hose=HOSE, x=0.35, more='posture = "kneeling"')),
                        search=False)
    assert (_reach(kneeling)[1].reach["hand"][0].upper_arm
            > op.reach["hand"][0].upper_arm + 10.0)


def test_two_grips_each_take_the_arm_on_their_side():
    scene = load_scene(EXAMPLES / "hoses" / "two_hands.toml")
    # the worker faces -y from y = 0.8: +x is their left
    worker = Worker((0.35, 0.8, -0.9), (0.0, -1.0, 0.0), sex="men", percentile=50)
    result = evaluate(replace(scene, worker=worker), search=False)
    op = result.operators[0]
    assert op.reach["left hand"][0].side == "right"  # at x = 0.15: the worker's right
    assert op.reach["right hand"][0].side == "left"


def test_a_bad_worker_is_refused_naming_the_field():
    with pytest.raises(FileFormatError, match=r"worker\.posture"):
        parse_scene(SCENE.format(hose=HOSE, x=1.0, more='posture = "crouching"'))
    with pytest.raises(FileFormatError, match=r"worker\.percentile"):
        parse_scene(SCENE.format(hose=HOSE, x=1.0, more="percentile = 100"))
    with pytest.raises(FileFormatError, match="facing: give the direction"):
        parse_scene(SCENE.format(hose=HOSE, x=1.0, more="").replace(
            "facing = [-1.0, 0.0, 0.0]", "facing = [0.0, 0.0, 0.0]"))
    with pytest.raises(InputError, match=r"worker\.facing"):
        evaluate(parse_scene(SCENE.format(hose=HOSE, x=1.0, more="").replace(
            "facing = [-1.0, 0.0, 0.0]", "facing = [0.0, 0.0, 1.0]")), search=False)


@pytest.mark.parametrize("apart", [0.6, 0.9, 1.1, 1.25, 1.4])
def test_two_hands_spread_needs_the_upper_arms_raised_as_an_exhaustive_arm_search_finds(
        apart):
    """Issue 56 (two hands): hands ``apart`` need each hand (apart - breadth) / 2 to the
    side of its shoulder. The least upper-arm elevation that reaches that far, searched
    over a two-link arm (the upper arm at every elevation on a 0.1 degree grid and every
    azimuth, the forearm and hand pointing every way), is ``Spread.elevation``'s; and the
    stick figure's own posture for hands there (the elbow hanging as low as it can) is
    never below it."""
    from pliant.assembly.posture import spread

    rules = bundled_rules()
    body = spread(rules.body, rules.posture)
    f = figure()
    assert body.arm == pytest.approx(f.arm) and body.upper == pytest.approx(f.upper)
    side = 0.5 * (apart - body.breadth)
    rng = np.random.default_rng(3)
    fore = rng.normal(size=(4000, 3))
    fore /= np.linalg.norm(fore, axis=1)[:, None]
    azimuth = np.radians(np.arange(0.0, 360.0, 2.0))
    least = None
    for e in np.arange(0.0, 90.05, 0.1):  # the first elevation whose arm gets there
        upper = body.upper * math.sin(math.radians(e)) * np.cos(azimuth)  # to the side
        if (upper.max() + (body.arm - body.upper) * fore[:, 0].max()) >= side:
            least = e
            break
    assert least is not None
    assert body.elevation(apart) == pytest.approx(least, abs=0.15)
    right = np.cross(f.facing, f.up)
    middle = f.hip + f.trunk * UP + 0.3 * f.facing
    for sign, hand in ((1.0, "right"), (-1.0, "left")):
        got = f.reach(middle + sign * 0.5 * apart * right, hand)
        if got.excess <= 0.0:
            assert got.upper_arm >= body.elevation(apart) - 1e-9


def test_two_hands_spread_limits_are_the_posture_zones_onsets():
    """The spread's yellow and red distances are those at which the least elevation is
    the [posture] zones' upper-arm onsets (20 and 60 degrees, ISO 11226); past the
    breadth and both arms no hands reach."""
    from pliant.assembly.posture import spread

    rules = bundled_rules()
    body = spread(rules.body, rules.posture)
    for limit, onset in zip(body.limits, rules.posture.upper_arm):
        assert body.elevation(limit) == pytest.approx(onset, abs=1e-9)
    assert body.elevation(body.most) == pytest.approx(90.0)
    tall = spread(rules.body, rules.posture, "men", 95.0)
    assert tall.limits[0] > body.limits[0] and "95th percentile man" in tall.who


# -- the upper arm's room (issue 56, item 1: the upper arm's envelope) ------------------------
def test_the_elbow_swings_up_from_a_table_by_the_least_angle_the_closed_form_gives():
    """A grip straight ahead of the right shoulder at its height, 0.8 of the arm's reach
    away: the elbow hangs lowest on its circle round the shoulder-hand line (centre at
    the shoulder's height, radius rho). A table whose top lies 0.6 rho below the shoulder
    takes that upper arm (radius r). Swung by phi the elbow is rho cos(phi) below the
    shoulder, the arm's lowest point: clear by rho (0.6 - cos phi) - r. The least swing
    on the 10-degree grid that clears the allowance is taken, its clearance that, and its
    elevation the swung arm's; with no table the elbow hangs."""
    from pliant.assembly.posture import swivelled
    from pliant.scene import Obstacle
    from pliant.scene.distance import field_of

    f = figure()
    env = bundled_rules().access
    right = np.cross(f.facing, f.up)
    shoulder = f.hip + f.trunk * UP + f.half_breadth * right
    d = 0.8 * f.arm
    reach = f.reach(shoulder + d * f.facing, "right")
    a, b = f.upper, f.arm - f.upper
    x = (a * a - b * b + d * d) / (2 * d)
    rho = math.sqrt(a * a - x * x)
    top = shoulder[2] - 0.6 * rho
    table = Obstacle.box("table", (4.0, 4.0, 1.0), (0.0, 0.0, top - 0.5))
    r, allowance = env.upper_arm, env.allowance
    got, room = swivelled(f, reach, r, allowance, field_of([table]))
    need = math.degrees(math.acos(0.6 - (r + allowance) / rho))
    step = math.ceil(need / 10.0) * 10.0
    assert room.swivel == pytest.approx(step, abs=1e-6) and room.bound_by == "table"
    assert room.clearance == pytest.approx(rho * (0.6 - math.cos(math.radians(step))) - r,
                                           abs=1e-9)
    assert rho * (0.6 - math.cos(math.radians(step - 10.0))) - r < allowance
    elbow = np.asarray(got.elbow)
    assert elbow[2] == pytest.approx(shoulder[2] - rho * math.cos(math.radians(step)), abs=1e-9)
    arm = elbow - shoulder
    assert got.upper_arm == pytest.approx(
        math.degrees(math.acos(-arm[2] / np.linalg.norm(arm))), abs=1e-9)
    assert got.upper_arm > reach.upper_arm + 10.0
    free, room = swivelled(f, reach, r, allowance, field_of([]))
    assert free == reach and room.swivel == 0.0 and room.clearance == math.inf


def test_an_upper_arm_no_swing_frees_is_red_in_the_evaluation_and_names_the_obstacle():
    """Through the evaluation: the hose held at chest height in front of the worker
    (green above), under a low beam that takes the shoulder itself: no swing of the
    elbow frees the upper arm, red, by the best swing's depth, naming the beam; a beam
    high above leaves it green and the elbow hanging."""
    def evaluated(z: float):
        beam = f"""
[[obstacle]]
name = "beam"
shape = "box"
size = [0.3, 3.0, 0.2]
position = [0.35, 0.0, {z}]
"""
        scene = parse_scene(SCENE.format(hose=HOSE, x=0.35, more="") + beam)
        checks, _ = _reach(evaluate(scene, search=False))
        return checks["access: upper arm"]

    low = evaluated(1.25)  # its underside 1.15 m high: below the shoulder
    assert low.zone is Zone.RED and "inside beam" in low.note
    high = evaluated(2.5)
    assert high.zone is Zone.GREEN and "the elbow hanging" in high.note
