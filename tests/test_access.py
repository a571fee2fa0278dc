"""Hand access (issue 56, item 1): the hand-and-forearm envelope against closed-form gaps
(two parallel walls, a bore), through the evaluation (zones, the gap and what bounds it,
JSON), with fitted parts, pinch, two hands side by side, and a user's own rules table."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

import pliant as pl
from pliant.assembly.access import SELF, hand_access
from pliant.assembly.checks import Zone
from pliant.assembly.evaluate import evaluate
from pliant.assembly.scenes import load_scene, parse_scene
from pliant.errors import FileFormatError
from pliant.io.rules_file import bundled_rules, parse_rules
from pliant.scene.distance import Obstacle

from .helpers import hand_held_hose

ENV = bundled_rules().access
OD = 0.016  # m: the hose held


def straight(obstacles=(), length=1.0, nodes=101):
    """A straight part along x (an equilibrium's fields, unloaded)."""
    s = np.linspace(0.0, length, nodes)
    return SimpleNamespace(
        s=s, position=np.column_stack([s, 0 * s, 0 * s]),
        tangent=np.tile([1.0, 0.0, 0.0], (nodes, 1)),
        problem=SimpleNamespace(part=pl.Part(length, 1.0, outer_diameter=OD),
                                obstacles=tuple(obstacles)))


def walls(gap):
    """Two walls square to y, ``gap`` apart, the part midway between them."""
    return (Obstacle.box("left wall", (3.0, 0.5, 3.0), (0.5, gap / 2 + 0.25, 0.0)),
            Obstacle.box("right wall", (3.0, 0.5, 3.0), (0.5, -gap / 2 - 0.25, 0.0)))


@pytest.mark.parametrize("gap", [0.03, 0.06, 0.09, 0.12, 0.2])
def test_between_two_walls_the_clearance_is_the_closed_form(gap):
    """Between walls the ring (part radius + hand thickness) and the forearm edge-on
    (its thickness at the elbow across the gap) bound the hand; the best approach runs
    along the walls."""
    got = hand_access(straight(walls(gap)), 0.5, ENV)
    ring = OD / 2 + ENV.thickness
    expected = gap / 2 - max(ring, ENV.elbow[1] / 2)
    assert got.clearance == pytest.approx(expected, abs=1e-9)
    assert got.bound_by in ("left wall", "right wall")
    assert abs(got.approach[1]) < 1e-9  # along the walls, square to the part


@pytest.mark.parametrize("diameter", [0.09, 0.12, 0.16])
def test_down_a_bore_the_forearm_breadth_bounds_it(diameter):
    """The part across the bottom of a deep round bore (a mesh): only the bore's axis
    lets the forearm in, and its breadth near the elbow (along the part) is the widest
    thing in it: clearance = apothem - elbow breadth / 2."""
    sections = 256
    bore = trimesh.creation.annulus(r_min=diameter / 2, r_max=diameter / 2 + 0.2,
                                    height=1.2, sections=sections)
    well = Obstacle.from_mesh("bore", bore.vertices, bore.faces, position=(0.5, 0.0, 0.0))
    got = hand_access(straight((well,)), 0.5, ENV)
    apothem = diameter / 2 * math.cos(math.pi / sections)
    widest = max(ENV.elbow[0] / 2, ENV.breadth / 2)
    assert got.clearance == pytest.approx(apothem - widest, abs=2e-4)
    assert abs(abs(got.approach[2]) - 1.0) < 1e-9  # straight down the bore
    assert got.bound_by == "bore"


def test_nothing_near_leaves_the_hand_free_and_a_u_turn_blocks_it_with_the_part_itself():
    """With no obstacle the part's own line is what is nearest; a part folded back
    under the hand is the hand's own obstacle."""
    free = hand_access(straight(), 0.5, ENV)
    assert free.clearance > 0.1 or free.bound_by == SELF
    # a hairpin: back along x at 30 mm below the hand's stretch
    s = np.linspace(0.0, 1.0, 201)
    first = s <= 0.5
    pos = np.where(first[:, None], np.column_stack([s, 0 * s, 0 * s]),
                   np.column_stack([1.0 - s, 0 * s, 0 * s - 0.03]))
    tan = np.where(first[:, None], [1.0, 0.0, 0.0], [-1.0, 0.0, 0.0])
    eq = SimpleNamespace(s=s, position=pos, tangent=tan, problem=SimpleNamespace(
        part=pl.Part(1.0, 1.0, outer_diameter=OD), obstacles=()))
    got = hand_access(eq, 0.3, ENV)
    assert got.bound_by == SELF
    # the ring round the upper run, the lower run 30 mm below: the best approach is from
    # above, and the ring still reaches down onto the lower run
    assert got.clearance == pytest.approx(0.03 - OD / 2 - (OD / 2 + ENV.thickness),
                                          abs=2e-4)


def test_a_pinch_needs_less_room_than_a_power_grip_and_two_hands_more():
    eq = straight(walls(0.07))
    power = hand_access(eq, 0.5, ENV)
    pinch = hand_access(eq, 0.5, ENV, hold="pinch")
    two = hand_access(eq, 0.5, ENV, hands=2)
    assert pinch.clearance > power.clearance
    assert pinch.clearance == pytest.approx(0.035 - max(OD / 2 + ENV.pinch_thickness,
                                                        ENV.elbow[1] / 2), abs=1e-9)
    assert two.clearance == pytest.approx(power.clearance, abs=1e-9)  # walls along x
    # square to the part, two hands side by side take twice the breadth
    bore = trimesh.creation.annulus(r_min=0.075, r_max=0.3, height=1.2, sections=256)
    well = (Obstacle.from_mesh("bore", bore.vertices, bore.faces, position=(0.5, 0, 0)),)
    one, both = (hand_access(straight(well), 0.5, ENV, hands=n) for n in (1, 2))
    assert one.clearance > 0.0 > both.clearance


def test_a_hand_at_the_end_of_the_part_holds_a_hands_breadth_in_from_it():
    got = hand_access(straight(), 1.0, ENV)
    assert got.s == pytest.approx(1.0 - ENV.breadth / 2, abs=0.011)


# -- through the evaluation -----------------------------------------------------------------
SCENE = """
name = "hose held between two walls"
gravity = [0.0, 0.0, 0.0]
{hose}
[[obstacle]]
name = "left wall"
shape = "box"
size = [2.0, 0.5, 2.0]
position = [0.3, {left}, 0.0]

[[obstacle]]
name = "right wall"
shape = "box"
size = [2.0, 0.5, 2.0]
position = [0.3, {right}, 0.0]
{extra}
"""


HOSE = hand_held_hose((0.3, 0.0, 0.0), (1.0, 0.0, 0.0), OD)


def _scene(gap, extra=""):
    return parse_scene(SCENE.format(hose=HOSE, left=gap / 2 + 0.25, right=-gap / 2 - 0.25,
                                    extra=extra))


def _access(evaluation, operator="one hand"):
    op = next(o for o in evaluation.operators if o.operator == operator)
    return next(c for c in op.checks if c.rule == "access: hand"), op


@pytest.mark.parametrize(("gap", "zone"), [(0.03, Zone.RED), (0.06, Zone.RED),
                                           (0.12, Zone.GREEN)])
def test_the_issue_figures_between_walls(gap, zone):
    """A grip between walls 30 mm apart is red, 120 mm green, 60 mm red for the large
    hand; a red one says how much room the hand lacks and what bounds it."""
    result = evaluate(_scene(gap), search=False)
    check, _ = _access(result)
    expected = gap / 2 - max(OD / 2 + ENV.thickness, ENV.elbow[1] / 2)
    assert check.value == pytest.approx(expected, abs=1e-6)
    assert check.zone is zone
    assert check.source == ENV.sourced.source and check.provenance == "assumption"
    if zone is Zone.RED:
        assert f"needs {-expected * 1e3:.0f} mm more room" in check.note
        assert "wall" in check.note
        assert any(r.startswith("[red] one hand: room for the hand at hand")
                   for r in result.verdict.reasons)
        # one hand cannot get in: the verdict does not choose it
        assert result.verdict.operator != "one hand"
    data = json.loads(json.dumps(result.to_dict()))
    ops = {o["operator"]: o for o in data["operators"]}
    steps = ops["one hand"]["access"]["hand"]
    assert steps[0]["clearance"] == pytest.approx(expected, abs=1e-6)
    assert steps[0]["bound_by"] in ("left wall", "right wall")


def test_yellow_within_the_movement_allowance():
    gap = 2 * (max(OD / 2 + ENV.thickness, ENV.elbow[1] / 2) + ENV.allowance / 2)
    check, _ = _access(evaluate(_scene(gap), search=False))
    assert check.zone is Zone.YELLOW
    assert check.value == pytest.approx(ENV.allowance / 2, abs=1e-6)


CABLE = """
name = "cable"
gravity = [0.0, 0.0, 0.0]
[part]
name = "cable"
length = 0.5
outer_diameter = 0.01
[part.material]
name = "PVC"
youngs_modulus = 2.0e8
density = 1400.0
poisson_ratio = 0.4
[[condition]]
name = "a"
s = 0.0
x = 0.35
y = -0.25
z = 0.045
tangent = [0.0, 1.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "b"
s = 0.5
x = 0.35
y = 0.24
z = 0.045
tangent = [0.0, 1.0, 0.0]
"""


def test_a_fitted_part_in_the_way_bounds_the_hand(tmp_path):
    """A flexible part already fitted, running across the hand's reach 45 mm above the
    held part between wide walls, is what the hand meets (its tube at rest counts)."""
    (tmp_path / "cable.toml").write_text(CABLE)
    text = SCENE.format(hose=HOSE, left=0.4, right=-0.4, extra="")
    free, _ = _access(evaluate(parse_scene(text), search=False))
    (tmp_path / "scene.toml").write_text(text.replace(
        "[part]", '[[assembled]]\nname = "cable"\nfile = "cable.toml"\n\n[part]', 1))
    blocked, op = _access(evaluate(load_scene(tmp_path / "scene.toml"), search=False))
    assert blocked.value < free.value
    assert op.access["hand"][0].bound_by == "cable"


def test_a_rules_table_of_ones_own_sizes_the_hand():
    """A user's table without [access] keeps the bundled hand; with it, its own."""
    bundled = bundled_text()
    text = bundled.replace("thickness = 0.033", "thickness = 0.02")
    assert bundled != text
    own = parse_rules(text, "mine.toml")
    assert own.access.thickness == 0.02
    eq = straight(walls(0.09))
    assert hand_access(eq, 0.5, own.access).clearance > hand_access(eq, 0.5, ENV).clearance
    bare = text[:text.index("[access]")]
    assert parse_rules(bare, "mine.toml").access == ENV
    with pytest.raises(FileFormatError, match=r"access.wrist\[1\]"):
        parse_rules(text.replace("wrist = [0.065, 0.045]", "wrist = [0.065, 0.0]"), "mine")


def bundled_text() -> str:
    from importlib import resources

    return resources.files("pliant.data").joinpath("rules.toml").read_text("utf-8")


def test_walls_as_millimetre_meshes_give_their_primitive_twins_room(tmp_path):
    """The walls as STL meshes in millimetres (``units = "mm"``, read once into metres):
    the hand's room between them is the boxes' (its primitive twin), through evaluate."""
    gap = 0.12
    for name, _side in (("left", 1), ("right", -1)):
        box = trimesh.creation.box(extents=(2000.0, 500.0, 2000.0))  # mm
        box.export(tmp_path / f"{name}.stl")
    text = SCENE.format(hose=HOSE, left=gap / 2 + 0.25, right=-gap / 2 - 0.25, extra="")
    meshes = text
    for name, side in (("left", 1), ("right", -1)):
        y = side * (gap / 2 + 0.25)
        meshes = meshes.replace(
            f'name = "{name} wall"\nshape = "box"\nsize = [2.0, 0.5, 2.0]\n'
            f'position = [0.3, {y}, 0.0]',
            f'name = "{name} wall"\nshape = "mesh"\nfile = "{name}.stl"\n'
            f'position = [0.3, {y}, 0.0]')
    assert meshes.count('shape = "mesh"') == 2
    (tmp_path / "mesh.toml").write_text('units = "mm"\n' + meshes)
    twin, _ = _access(evaluate(parse_scene(text), search=False))
    mesh, _ = _access(evaluate(load_scene(tmp_path / "mesh.toml"), search=False))
    assert mesh.value == pytest.approx(twin.value, abs=1e-9)
    assert mesh.zone is twin.zone is Zone.GREEN


def test_a_fitted_part_through_the_hand_is_red_and_what_a_sequence_blames(tmp_path):
    """The fitted cable crossing 30 mm above the held hose, where the hand closes round
    it: no approach fits, the cable bounds it, and a sequence's failing operation blames
    the cable (``sequence._blockers``) though the hose keeps clear of it."""
    from pliant.assembly.sequence import _blockers

    taut = (CABLE.replace("x = 0.35", "x = 0.3").replace("z = 0.045", "z = 0.03")
            .replace("y = -0.25", "y = -0.2502").replace("y = 0.24", "y = 0.2502")
            .replace("outer_diameter = 0.01", "outer_diameter = 0.01\naxial_stiffness = 1e5"))
    assert taut.count("0.2502") == 2
    (tmp_path / "cable.toml").write_text(taut)  # pulled straight across the hand
    text = SCENE.format(hose=HOSE, left=0.4, right=-0.4, extra="")
    (tmp_path / "scene.toml").write_text(text.replace(
        "[part]", '[[assembled]]\nname = "cable"\nfile = "cable.toml"\n\n[part]', 1))
    ev = evaluate(load_scene(tmp_path / "scene.toml"), search=False)
    check, op = _access(ev)
    assert check.zone is Zone.RED and op.access["hand"][0].bound_by == "cable"
    assert min(r.clearance for r in ev.run.steps) > 0.0  # the hose itself is clear
    assert _blockers(ev, ["cable"], 0.0) == ["cable"]


def test_a_bent_wrist_reaches_down_a_slanted_bore():
    """A bore slanted 20 degrees along the part: square to the part no forearm gets down
    it; with the approach also tilted 20 degrees along the part (a bent wrist) the
    forearm goes down its axis, and the room is the upright bore's closed form."""
    from dataclasses import replace as swap

    sections, diameter, slant = 256, 0.12, math.radians(20.0)
    bore = trimesh.creation.annulus(r_min=diameter / 2, r_max=diameter / 2 + 0.2,
                                    height=1.2, sections=sections)
    turn = np.array([[math.cos(slant), 0.0, math.sin(slant)], [0.0, 1.0, 0.0],
                     [-math.sin(slant), 0.0, math.cos(slant)]])
    well = Obstacle.from_mesh("bore", bore.vertices, bore.faces, position=(0.5, 0.0, 0.0),
                              rotation=turn)
    square = hand_access(straight((well,)), 0.5, ENV)
    bent = hand_access(straight((well,)), 0.5, swap(ENV, tilts=(0.0, 20.0, -20.0)))
    apothem = diameter / 2 * math.cos(math.pi / sections)
    assert square.clearance < 0.0
    assert bent.clearance == pytest.approx(apothem - ENV.elbow[0] / 2, abs=2e-4)
    np.testing.assert_allclose(bent.approach, turn @ [0.0, 0.0, 1.0], atol=1e-9)


@pytest.mark.parametrize(("gap", "zone"), [(0.02, Zone.RED), (0.046, Zone.GREEN)])
def test_a_tools_gripper_between_walls_has_the_closed_form_room(gap, zone):
    """Issue 56: a tool's or robot's own envelope. Given as ``[evaluation] envelope``
    (its jaws round the part, its body out along the approach), the tool operator is
    checked for room as a hand is: between walls the jaws' ring (part radius + jaw) and
    the body edge-on (half its thickness) bound it, half the gap less the larger, to
    1e-6; red where none fits, naming a wall; green with room (up to about 46 mm, where
    the part running on past the short jaws comes nearer the body than the walls)."""
    envelope = """
[evaluation]
operator = "tool"
rating = { force = 500.0 }
envelope = { length = 0.2, breadth = 0.03, thickness = 0.02, jaw = 0.004 }
"""
    result = evaluate(_scene(gap, envelope), search=False)
    op = next(o for o in result.operators if o.operator == "tool")
    check = next(c for c in op.checks if c.rule == "access: tool")
    expected = gap / 2 - max(OD / 2 + 0.004, 0.02 / 2)
    assert check.value == pytest.approx(expected, abs=1e-6)
    assert check.zone is zone and check.provenance == "given"
    if zone is Zone.RED:
        assert "no approach fits the tool" in check.note and "wall" in check.note
    data = json.loads(json.dumps(result.to_dict()))
    ops = {o["operator"]: o for o in data["operators"]}
    assert ops["tool"]["access"]["hand"][0]["clearance"] == pytest.approx(expected, abs=1e-6)
