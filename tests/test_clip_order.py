"""The clip order of a harness (``pliant.assembly.clip_order``): each clip carried from
where the bundle hangs to its place, checked against the closed form of a bundle held
level at both ends of each span; the exact search over sets against every order along
its own path; an order that fails, for the bend its first clip leaves."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pliant.assembly.harness import properties
from pliant.errors import InputError

from .helpers import cli, straight_harness

GENERATOR = (Path(__file__).resolve().parents[1] / "examples" / "harness" / "kbl"
             / "kblxml_2.3sr-1_000971230_ltgs_generator_170718.kbl")

LENGTH, CHORD, MASS = 1.25, 1.2, 0.2  # m, m, kg/m: a slack bundle between two connectors
WHERE = (0.25, 0.5, 0.75)  # the clips' marks, as fractions of the bundle's length


def _bundle(bend_radius: float = 5e-3):
    """One segment between two plugged connectors at the same height, designed straight
    (so every clip's place and axis are level), carrying one 6 mm wire."""
    return straight_harness(
        {"A": (0.0, 0.0, 0.0), "B": (CHORD, 0.0, 0.0)},
        [("S", "A", "B", LENGTH, [(f"F{k}", w) for k, w in enumerate(WHERE)])], ["A", "B"],
        wire=(6e-3, bend_radius, MASS), clips={f"F{k}": f"clip {k}" for k in range(3)})


def test_each_clip_carries_half_the_weight_of_the_spans_beside_it_in_every_order():
    """Closed form: held level at both ends, every span between two held points is
    symmetric, so each end carries half its weight; a clip, half of each span beside
    it, whatever the bundle's sag and slack. Checked after every operation of two
    orders; both end where the harness solved with every clip fixed is (the order does
    not change the installed harness)."""
    from pliant.assembly.harness_solve import fix, solve_installed

    harness = _bundle()
    props = properties(harness)
    weight_per_length = MASS * 9.81
    hanging = solve_installed(harness, props, released=[f"clip {k}" for k in range(3)])
    installed = solve_installed(harness, props)
    for order in ((1, 0, 2), (0, 2, 1)):
        state, fixed = hanging, []
        for k in order:
            state, forces = fix(state, props, f"clip {k}")
            fixed.append(k)
            marks = [0.0, *sorted(WHERE[j] for j in fixed), 1.0]
            for j in fixed:
                i = marks.index(WHERE[j])
                expected = 0.5 * (marks[i + 1] - marks[i - 1]) * LENGTH * weight_per_length
                assert -state.held[f"fixing clip {j}"][0][2] == pytest.approx(
                    expected, rel=1e-4)
            assert forces[0] < 1e-4 * state.weight  # taken where it hung: nothing yet
            final = float(np.linalg.norm(state.held[f"fixing clip {k}"][0]))
            assert forces[-1] == pytest.approx(final, rel=1e-9) and max(forces) >= forces[-1]
        for name, (force, moment) in installed.held.items():
            assert np.abs(state.held[name][0] - force).max() < 1e-6 * installed.weight
            assert np.abs(state.held[name][1] - moment).max() < 1e-6 * installed.weight


def test_the_exact_search_finds_every_order_s_best_and_names_why_the_others_fail():
    """A bundle whose wire may not bend tighter than 90 mm: a clip at a quarter fixed
    first leaves the long span sagging into an 87 mm bend at it (red), the middle clip
    first a 102 mm one (yellow, within 1.2 times the limit, as installed). The exact
    search over the
    sets of clips and the slow twin (every order along its own path) agree on the best
    order and its costs, and both name the failing first clips."""
    from pliant.assembly.clip_order import clip_order

    harness = _bundle(bend_radius=0.09)
    props = properties(harness)
    exact = clip_order(harness, props)
    slow = clip_order(harness, props, search="every", installed=exact.installed,
                      hanging=exact.hanging)  # the same two cold solves
    assert len(slow.orders) == 6 and exact.operations == 12 and slow.operations == 15
    assert exact.best is not None and slow.best is not None
    assert exact.best.fixings == slow.best.fixings and exact.best.fixings[0] == "clip 1"
    assert exact.best.key() == slow.best.key()
    # The installed harness's own bend is yellow (102 mm, within 1.2 times 90 mm): the
    # design's, not the order's, so the best order is green.
    assert exact.best.zone == "green"
    assert any("the installed harness itself" in n and "yellow" in n for n in exact.notes)
    failing = [o for o in slow.orders if not o.passes]
    assert {o.fixings[0] for o in failing} == {"clip 0", "clip 2"} and len(failing) == 4
    for order in failing:
        step = order.failing
        assert step.before == () and step.tightest[0] == "S"
        assert 0.08 < step.tightest[1] < 0.09 == step.tightest[2]
        assert any("installed bend radius" in r for r in step.reasons)
    assert {(f.fixing, f.before) for f in exact.failures} == {("clip 0", ()), ("clip 2", ())}
    assert not any("another shape" in n for n in exact.notes)  # no branch met
    # The greedy search (past 10 fixings, where the exact one stops) takes the middle
    # clip first here too, in n (n + 1) / 2 = 6 operations, with the same costs.
    greedy = clip_order(harness, props, search="greedy", installed=exact.installed,
                        hanging=exact.hanging)
    assert greedy.operations == 6 and greedy.best is not None
    assert greedy.best.key() == exact.best.key() and "not proven" in greedy.method


def test_a_fixing_the_harness_lacks_is_a_typed_error_naming_it():
    from pliant.assembly.clip_order import clip_order

    harness = _bundle()
    with pytest.raises(InputError, match="'clip 9' is not a fixing"):
        clip_order(harness, properties(harness), fixings=["clip 9"])
    with pytest.raises(InputError, match="search: must be auto, exact, every or greedy"):
        clip_order(harness, properties(harness), search="best")
    with pytest.raises(InputError, match="give at least one fixing to order"):
        clip_order(harness, properties(harness), fixings=[])


def test_pliant_harness_orders_the_generator_cable_s_clip_and_writes_it_in_json(tmp_path):
    """The generator cable (its KBL, millimetres): its one clip carried from where the
    cable hangs off its connectors to its place. The hand's last force is the load the
    installed harness (solved cold, apart) puts on that clip; the design's own red bend
    (segment 2) is said as the design's, not blamed on the order."""
    done = cli("harness", GENERATOR, "--clip-order", "--json", tmp_path / "h.json",
               "--report", tmp_path / "h.html")
    out = " ".join(done.stdout.split())
    assert "clip order of 1 fixings" in out and "best order: green" in out
    assert "the installed harness itself has" in out
    assert done.returncode == 1  # the design's red bend, as without --clip-order
    data = json.loads((tmp_path / "h.json").read_text())
    order = data["clip_order"]
    assert order["best"]["fixings"] == ["CL_01_Gen"] and order["failures"] == []
    [step] = order["best"]["steps"]
    held = np.linalg.norm(data["installed"]["held_loads"]["fixing CL_01_Gen"]["force_N"])
    assert step["forces"][-1] == pytest.approx(held, abs=1e-6 * data["installed"]["weight_N"])
    assert step["forces"][0] < 1e-4 * data["installed"]["weight_N"] < step["force"]
    page = (tmp_path / "h.html").read_text()
    assert "<h2>Clip order</h2>" in page and "Best: CL_01_Gen" in page


def test_the_clip_order_among_a_scene_s_obstacles_ends_at_the_installed_harness(tmp_path):
    """Features together: the generator cable's KBL (millimetres) in a scene (SI) with a
    bracket its branch rests on. The clip is carried among the obstacle, its last force
    is the load the installed harness (solved cold with the bracket, apart) puts on it,
    and the operation is not red (a segment through the bracket would make it so; the
    installed harness passes through nothing)."""
    done = cli("harness", GENERATOR.parents[1] / "generator_on_bracket.toml", "--clip-order",
               "--json", tmp_path / "h.json")
    data = json.loads((tmp_path / "h.json").read_text())
    order = data["clip_order"]
    [step] = order["best"]["steps"]
    held = np.linalg.norm(data["installed"]["held_loads"]["fixing CL_01_Gen"]["force_N"])
    assert step["forces"][-1] == pytest.approx(held, rel=1e-4)
    assert step["zone"] != "red" and "rests on it" in " ".join(done.stdout.split())
    for segment in data["installed"]["segments"]:
        assert not segment["interference"]["penetrations"]


def test_an_operation_the_harness_cannot_follow_fails_its_orders_and_the_search_goes_on(
        monkeypatch):
    """Where the harness cannot follow a clip to its place (the solver meets a fold: here
    the middle clip, made to fail once the quarter ones are in), that operation is red
    with why, the orders through it end there, and the search goes on: both searches
    agree on the best order, which avoids it, and neither raises."""
    from pliant.assembly import harness_solve
    from pliant.assembly.clip_order import clip_order
    from pliant.errors import ConvergenceError

    harness = _bundle()
    props = properties(harness)
    real = harness_solve.fix

    def jams(before, props, fixing, **options):
        if fixing == "clip 1" and len(before.released) == 1:
            raise ConvergenceError("segment S cannot follow fixing clip 1 there",
                                   residual=math.inf)
        return real(before, props, fixing, **options)

    monkeypatch.setattr(harness_solve, "fix", jams)
    exact = clip_order(harness, props)
    slow = clip_order(harness, props, search="every", installed=exact.installed,
                      hanging=exact.hanging)
    assert exact.best is not None and exact.best.fixings == slow.best.fixings
    assert exact.best.fixings[-1] != "clip 1"
    stuck = [f for f in exact.failures if f.fixing == "clip 1"]
    assert [set(f.before) for f in stuck] == [{"clip 0", "clip 2"}]
    assert "could not follow clip 1" in stuck[0].reasons[0]
    cut = [o for o in slow.orders if o.fixings[-1] == "clip 1"]
    assert len(cut) == 2 and all(not o.passes and len(o.steps) == 3 for o in cut)
    # A clip that can never be fixed: no order passes, and each says where it stops.

    def never(before, props, fixing, **options):
        if fixing == "clip 1":
            raise ConvergenceError("segment S cannot follow fixing clip 1", residual=1.0)
        return real(before, props, fixing, **options)

    monkeypatch.setattr(harness_solve, "fix", never)
    none = clip_order(harness, props, installed=exact.installed, hanging=exact.hanging)
    assert none.best is None and none.orders == ()
    assert {frozenset(f.before) for f in none.failures if f.fixing == "clip 1"} == {
        frozenset(), frozenset({"clip 0"}), frozenset({"clip 2"}),
        frozenset({"clip 0", "clip 2"})}


def test_a_scene_with_two_harnesses_judges_each_and_writes_each_its_files(tmp_path):
    """Issue 55: a scene's second harness was left out ("this command judges the first").
    The generator cable and the battery cable in one scene: each is solved and judged
    with the same checks as alone, each report gets its own numbered file, the JSON
    holds both, and the exit status is the worse of their verdicts."""
    battery = GENERATOR.parent / "kblxml_2.3sr-1_000971228_ltgs_batterie_plus_170718.kbl"
    scene = tmp_path / "two.toml"
    scene.write_text(f'name = "two cables"\nmargin = 0.005\n[[harness]]\nfile = "{GENERATOR}"'
                     f'\n[[harness]]\nfile = "{battery}"\n')
    done = cli("harness", scene, "--json", tmp_path / "h.json", "--report",
               tmp_path / "h.html")
    said = " ".join(done.stdout.split())
    assert "harness 1 of 2" in said and "harness 2 of 2" in said
    assert "verdict over the scene's 2 harnesses" in said
    both = json.loads((tmp_path / "h.json").read_text())["harnesses"]
    codes = []
    for k, path in enumerate((GENERATOR, battery), 1):
        alone = cli("harness", path, "--solve", "--json", tmp_path / f"alone-{k}.json")
        codes.append(alone.returncode)
        mine = json.loads((tmp_path / f"alone-{k}.json").read_text())
        assert both[k - 1]["harness"]["name"] == mine["harness"]["name"]
        assert [(c["where"], c["what"], c["zone"]) for c in both[k - 1]["design_checks"]] == [
            (c["where"], c["what"], c["zone"]) for c in mine["design_checks"]]
        assert (tmp_path / f"h-{k}.html").stat().st_size > 1000
    assert done.returncode == max(codes) == 1


def test_a_clip_right_at_a_junction_holds_the_node_installed_moved_and_fixed():
    """A fixing assigned to two segments at the node where they meet (a third branch
    leaves it) holds the node, as a connector would: grips a hair inside each segment
    would pin the free junction from both sides. Three spans clamped level at both ends,
    each symmetric: the clip carries half of each one's weight (closed form) and nothing
    along the two in line. Moved, the node goes with it; released and fixed again, the
    hand's force goes from nothing (the node taken where it hangs) to that load, and the
    harness ends as installed. A place within 1 mm of the node is at the node. (S1 and
    S2 start from their designs, straight and 5 mm shorter: pushed straight between
    their ends, unstable; each is settled to its sag, a stable shape.)"""
    from pliant.assembly.harness_solve import Network, fix, solve_installed

    lengths = {"S1": 0.605, "S2": 0.605, "S3": 0.52}
    harness = straight_harness(
        {"A": (0.0, 0.0, 0.0), "M": (0.6, 0.0, 0.0), "B": (1.2, 0.0, 0.0),
         "C": (0.6, 0.5, 0.0)},
        [("S1", "A", "M", lengths["S1"], [("F", 1.0)]),
         ("S2", "M", "B", lengths["S2"], [("F", 0.0)]), ("S3", "M", "C", lengths["S3"])],
        ["A", "B", "C"], wire=(6e-3, 5e-3, MASS), clips={"F": "node clip"})
    s1, place = harness.segments["S1"], harness.segments["S1"].fixings[0]
    assert Network.node_of(s1, place) == "M"
    assert Network.node_of(s1, replace(place, location=1.0 - 0.9e-3 / 0.605)) == "M"
    assert Network.node_of(s1, replace(place, location=1.0 - 1.1e-3 / 0.605)) is None
    props = properties(harness)
    installed = solve_installed(harness, props)
    force = installed.held["fixing node clip"][0]
    halves = 0.5 * installed.weight  # (the segments' own mass per length: properties)
    assert not installed.junctions  # the node is held, not balanced
    assert {seg.equilibrium.verdict for seg in installed.segments.values()} == {"stable"}
    assert min(installed.segments["S1"].equilibrium.position[:, 2]) < -0.02
    # (to the mirror images' meshes: each segment's mark of the clip is a station)
    assert force[0] == pytest.approx(0.0, abs=1e-5 * halves)
    assert force[2] == pytest.approx(-halves, rel=1e-5)
    moved = solve_installed(harness, props, moved={"node clip": (0.0, 0.0, 0.005)},
                            warm=installed)
    for seg, k in (("S1", -1), ("S2", 0), ("S3", 0)):
        assert moved.segments[seg].equilibrium.position[k] == pytest.approx(
            [0.6, 0.0, 0.005], abs=1e-9)
    hanging = solve_installed(harness, props, released=["node clip"])
    assert hanging.junctions["M"][2] < -0.02  # it hangs below its clip
    after, forces = fix(hanging, props, "node clip")
    assert forces[0] < 1e-6 * installed.weight
    assert forces[-1] == pytest.approx(float(np.linalg.norm(force)), rel=1e-6)
    for seg in lengths:
        assert np.abs(after.segments[seg].equilibrium.position
                      - installed.segments[seg].equilibrium.position).max() < 1e-8


def test_a_clip_holding_two_segments_at_a_node_takes_both_their_loads():
    """A fixing assigned to both segments that meet at a junction, a little way along each
    (KBL allows it: the main harness has 16 assignments for 14 fixings; a duct holding
    both): the hand carries the two segments' loads together, so its last force is the
    load the installed harness puts on the fixing (both assignments summed), and it starts
    at nothing (each segment taken where it hangs). (Right at the junction, it holds the
    node: the test before.)"""
    from pliant.assembly.harness_solve import fix, solve_installed

    harness = straight_harness(
        {"A": (0.0, 0.0, 0.0), "M": (0.6, 0.0, 0.0), "B": (1.2, 0.0, 0.0)},
        [("S1", "A", "M", 0.625, [("F", 0.9)]), ("S2", "M", "B", 0.625, [("F", 0.1)])],
        ["A", "B"], wire=(6e-3, 5e-3, MASS), clips={"F": "middle clip"})
    props = properties(harness)
    hanging = solve_installed(harness, props, released=["middle clip"])
    after, forces = fix(hanging, props, "middle clip")
    installed = solve_installed(harness, props)
    load = np.linalg.norm(installed.held["fixing middle clip"][0])
    assert load > 0.5 * installed.weight  # it carries a good share of the harness
    assert forces[0] < 1e-4 * installed.weight
    assert forces[-1] == pytest.approx(load, rel=1e-5)
    assert np.abs(after.held["fixing middle clip"][0]
                  - installed.held["fixing middle clip"][0]).max() < 1e-6 * installed.weight


def test_a_segment_left_unstable_is_said_and_the_verdict_does_not_rest_on_it(monkeypatch):
    """Where an unstable segment is not settled (the settling switched off here), the
    installed harness says so in its notes and in an unchecked stability check per
    segment, and the harness's verdict is undecided (exit status 1), not green."""
    import io

    from rich.console import Console

    import pliant.assembly.harness_solve as harness_solve
    from pliant.cli.app import _harness_verdict

    harness = straight_harness(  # straight designs 5 mm shorter: pushed straight
        {"A": (0.0, 0.0, 0.0), "B": (0.6, 0.0, 0.0)}, [("S1", "A", "B", 0.605)], ["A", "B"],
        wire=(6e-3, 5e-3, MASS))
    props = properties(harness)
    monkeypatch.setattr(harness_solve, "_settle_unstable", lambda net: [])
    installed = harness_solve.solve_installed(harness, props)
    assert installed.segments["S1"].equilibrium.verdict == "unstable"
    assert any("unstable as installed" in n and "S1" in n for n in installed.notes)
    checks = harness_solve.installed_checks(installed)
    (stability,) = [c for c in checks if c.what == "stability"]
    assert stability.zone.value == "unchecked" and stability.value < 0.0
    out = io.StringIO()
    assert _harness_verdict(Console(file=out, width=200), checks, installed, None, "") is False
    assert "undecided" in out.getvalue() and "exit status 1" in out.getvalue()
    monkeypatch.undo()
    settled = harness_solve.solve_installed(harness, props)
    assert settled.segments["S1"].equilibrium.verdict == "stable" and not settled.notes
    assert not [c for c in harness_solve.installed_checks(settled) if c.what == "stability"]
