"""Path planning (``pliant.assembly.plan``): a detour found where the straight path
collides, every step of it re-solved independently from the written scene; a walled-in
port answered by a typed error inside its budget; a seed that reproduces the path."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pliant.assembly import follow_path
from pliant.assembly.evaluate import bend_limit
from pliant.assembly.plan import NoPathError, Planner, path_problems, plan
from pliant.assembly.scenes import load_scene, parse_scene, scene_from_data
from pliant.core.planning import PlanSettings
from pliant.errors import FileFormatError, InputError
from pliant.io.problem_file import read_text, with_path_table
from pliant.io.rules_file import load_rules
from pliant.io.tomlfile import read_toml

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "hose_past_post.toml"


@pytest.fixture(scope="module")
def found():
    scene = load_scene(EXAMPLE)
    return scene, plan(scene, "port", PlanSettings(budget=60.0, seed=1, attempts=1))


def _straight(scene):
    """The problems of the straight move from the start to the seated pose."""
    planner = Planner(scene, PlanSettings())
    seated, _ = planner.goal_pose("port")
    tree = planner.tree("port")
    return path_problems(tree.problem_at, planner.start_pose(), [seated], 40)


def test_the_straight_path_hits_the_post():
    scene = load_scene(EXAMPLE)
    run = follow_path(scene.problem, _straight(scene), "hand", margin=scene.margin,
                      elements=scene.solver.elements)
    # Carried straight, the hand itself would go through the post: the run stops before
    # it, the part already within the margin.
    assert not run.complete and len(run.steps) < 40
    assert min(dict(r.clearances)["post"] for r in run.steps) < scene.margin


def test_the_planned_detour_holds_when_followed_again_from_the_written_file(found, tmp_path):
    scene, result = found
    text = with_path_table(read_text(EXAMPLE), result.path_table(), str(EXAMPLE),
                           EXAMPLE.parent, tmp_path)
    (tmp_path / "planned.toml").write_text(text)
    planned = load_scene(tmp_path / "planned.toml")
    assert planned.grip == "hand" and len(planned.path) == result.steps
    # Re-solved independently: a fresh solver, every step of the path as the file says.
    run = follow_path(planned.problem, planned.path, "hand", margin=planned.margin,
                      elements=planned.solver.elements)
    assert run.complete, run.stopped
    assert all(r.stable is True for r in run.steps)
    assert not run.snaps
    assert min(r.clearance for r in run.steps) >= scene.margin
    rules = load_rules(None)
    limit = bend_limit(scene.problem.part, rules.kind(scene.problem.part.kind))[0]
    assert min(r.bend_radius for r in run.steps) >= limit
    # It ends seated: the hand at the port, holding the part along the port's axis.
    port = scene.ports["port"]
    last = planned.path[-1].condition("hand")
    assert np.allclose(last.position, port.position, atol=1e-5)
    assert np.allclose(last.tangent, -np.asarray(port.axis), atol=1e-5)
    end = run.final
    assert np.allclose(end.position[-1], port.position, atol=1e-6)
    # Balance of the whole part at the last step: the two held ends, gravity and no
    # contact (it kept the margin) sum to zero.
    loads = end.loads
    weight = scene.problem.part.mass_per_length * scene.problem.part.length * 9.81
    total = loads["hand"].force + loads["fitting end"].force + np.array([0, 0, -weight])
    assert np.abs(total).max() < 1e-6 * weight


def test_the_plan_reports_what_it_cost_and_its_demand(found):
    _, result = found
    assert result.solves > 0 and result.motions > 0 and result.trees >= 1
    assert len(result.demands) == result.steps + 1
    assert result.peak_demand == pytest.approx(max(result.demands))
    assert result.cost[0] == pytest.approx(max(result.demands[1:]), abs=1e-3)


def test_a_seed_reproduces_the_path(found):
    scene, result = found
    again = plan(scene, "port", PlanSettings(budget=60.0, seed=1, attempts=1))
    assert [p.position for p in again.poses] == [p.position for p in result.poses]
    assert again.solves == result.solves


def _walled(margin: float = 0.01) -> dict:
    """The example with its port walled in by a closed box of 1 cm walls."""
    data = read_toml(read_text(EXAMPLE), str(EXAMPLE))
    centre = np.array(data["port"][1]["position"])
    inner, wall = 0.08, 0.01
    for axis in range(3):
        for side in (-1, 1):
            size = [2 * (inner + wall)] * 3
            size[axis] = wall
            at = centre.copy()
            at[axis] += side * (inner + wall / 2)
            data["obstacle"].append({"name": f"cage {'xyz'[axis]}{'-+'[side > 0]}",
                                     "shape": "box", "size": size,
                                     "position": [float(x) for x in at]})
    data["margin"] = margin
    return data


def test_a_walled_in_port_is_a_typed_error_inside_its_budget():
    scene = scene_from_data(_walled(), "walled", EXAMPLE.parent)
    budget = 4.0
    with pytest.raises(NoPathError) as err:
        plan(scene, "port", PlanSettings(budget=budget, seed=1))
    e = err.value
    assert e.seconds < budget + 3.0  # at most the solve under way when the time ran out
    assert e.closest is not None and e.distance > 0.05
    centre = np.asarray(scene.ports["port"].position)
    assert np.abs(np.asarray(e.closest.position) - centre).max() > 0.08  # never got in
    assert e.blocked and all(n > 0 for n in e.blocked.values())
    assert "no path found" in str(e) and "--budget" in str(e)
    assert next(iter(e.blocked)) in str(e)  # the commonest reason is named


def test_bad_requests_name_the_field():
    scene = load_scene(EXAMPLE)
    with pytest.raises(InputError, match=r"plan.goal: no \[\[port\]\] named 'nowhere'"):
        plan(scene, "nowhere")
    with pytest.raises(InputError, match=r"plan.grip: no condition named 'elbow'"):
        Planner(scene, grip="elbow")
    data = read_toml(read_text(EXAMPLE), str(EXAMPLE))
    del data["condition"][1]["tangent"]  # the hand holds a position only
    with pytest.raises(InputError, match=r"plan.grip: 'hand' must hold x, y, z and a tangent"):
        Planner(scene_from_data(data, "x"))
    free = replace(scene, problem=scene.problem.with_conditions(
        [scene.problem.condition("hand")]))
    with pytest.raises(InputError, match="nothing else holds the part"):
        Planner(free)
    for field, value in (("budget", 0.0), ("step", -1.0), ("goal_bias", 1.0),
                         ("attempts", 0), ("seed", 0), ("approach", math.nan)):
        with pytest.raises(InputError, match=f"plan.{field}"):
            PlanSettings(**{field: value})


def test_the_scene_file_reads_its_plan_table():
    scene = load_scene(EXAMPLE)
    assert scene.plan.goal == "port" and scene.plan.budget == 30.0
    data = read_toml(read_text(EXAMPLE), str(EXAMPLE))
    data["plan"]["budget"] = -1
    with pytest.raises(FileFormatError, match=r"plan.budget"):
        scene_from_data(data, "x")
    data["plan"] = {"goal": "port", "speed": 2}
    with pytest.raises(FileFormatError, match=r"plan.speed"):
        scene_from_data(data, "x")


def test_the_path_table_replaces_the_old_one_and_keeps_the_rest(tmp_path):
    text = ('name = "x"  # a comment\n[part]\nlength = 1.0\nbending_stiffness = 1.0\n'
            '[path]\ngrip = "hand"\nwaypoints = [\n  [0.0, 0.0, 1.0],\n]\n'
            '# the next table\n[[obstacle]]\nname = "a"\nshape = "mesh"\nfile = "m.stl"\n')
    table = '[path]\ngrip = "hand"\nwaypoints = [[1.0, 2.0, 3.0]]\nsteps = 4\n'
    out = with_path_table(text, table, "x", tmp_path / "a", tmp_path / "b")
    doc = read_toml(out, "x")
    assert doc["path"] == {"grip": "hand", "waypoints": [[1.0, 2.0, 3.0]], "steps": 4}
    assert doc["obstacle"][0]["file"] == str((tmp_path / "a" / "m.stl").resolve())
    assert "# the next table" in out and "# a comment" in out
    # Without a [path], the table is added before the first table.
    bare = with_path_table('name = "x"\n[part]\nlength = 1.0\n', table)
    assert read_toml(bare, "x")["path"]["steps"] == 4
    # Read back, it must hold the same scene: a path written where no table header is
    # found would lose what follows it.
    with pytest.raises(FileFormatError, match="add the planned \\[path\\] by hand"):
        with_path_table('name = "x"\npath = { grip = "a" }\n[part]\nlength = 1.0\n', table)


def test_the_planned_scene_parses_with_the_same_problem(found):
    _, result = found
    text = with_path_table(read_text(EXAMPLE), result.path_table())
    scene = parse_scene(text, "planned", EXAMPLE.parent)
    original = load_scene(EXAMPLE)
    assert scene.problem.conditions == original.problem.conditions
    assert [o.name for o in scene.problem.obstacles] == ["post"]


def test_ctrl_c_ends_a_plan_at_once_and_gives_the_handler_back(tmp_path):
    """Ctrl+C while OMPL searches: the planner's own handler refuses every motion from
    then on and ends the search at its next check; KeyboardInterrupt, the previous
    handler back. In a child process, the signal sent once the planner holds it."""
    import subprocess
    import sys

    script = """
import os, signal, threading, time
from pliant.assembly.plan import Planner
from pliant.core.planning import PlanSettings
from pliant.assembly.scenes import scene_from_data
from tests.test_plan import _walled, EXAMPLE
scene = scene_from_data(_walled(), "walled", EXAMPLE.parent)
def press():
    while signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        time.sleep(0.01)
    time.sleep(0.5)
    os.kill(os.getpid(), signal.SIGINT)
threading.Thread(target=press, daemon=True).start()
begin = time.perf_counter()
try:
    Planner(scene, PlanSettings(budget=120.0)).plan("port")
except KeyboardInterrupt:
    print("interrupted", time.perf_counter() - begin)
print(signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300, cwd=Path(__file__).resolve().parents[1], check=False)
    assert out.returncode == 0, out.stderr
    first, second = out.stdout.split("\n")[:2]
    assert first.startswith("interrupted") and float(first.split()[1]) < 60.0
    assert second == "True"


def test_a_query_to_another_port_grows_from_the_poses_reached_before():
    """The roadmap is reused: every pose an earlier query reached (with the equilibrium
    it was reached with) seeds the next query's tree, and the path found through them
    holds when followed again from the start. The second port sits where the first
    path passed, facing it."""
    scene = load_scene(EXAMPLE)
    planner = Planner(scene, PlanSettings(budget=60.0, seed=1, attempts=1))
    first = planner.plan("port")
    middle = first.poses[len(first.poses) // 2]
    ports = dict(scene.ports)
    ports["midway"] = ports["port"].model_copy(update={
        "name": "midway", "position": middle.position,
        "axis": tuple(-x for x in middle.tangent)})
    planner.scene = replace(scene, ports=ports)
    before = len(planner.forest)
    second = planner.plan("midway")
    assert first.reused == 0 and before > 5
    assert second.reused > 0  # its search went through poses the first query reached
    run = follow_path(scene.problem, second.path, "hand", margin=scene.margin,
                      elements=scene.solver.elements)
    assert run.complete and all(r.stable is True for r in run.steps) and not run.snaps
    assert min(r.clearance for r in run.steps) >= scene.margin
    np.testing.assert_allclose(run.final.position[-1], middle.position, atol=1e-6)


def test_the_kink_limit_is_brazier_at_the_rules_red_flattening():
    from pliant.assembly.checks import brazier_flattening, tube_section
    from pliant.assembly.plan import kink_radius
    from pliant.core.part import Part

    rules = load_rules(None)
    kind = rules.kind("thin-walled tube")
    part = Part(length=1.0, bending_stiffness=0.1, outer_diameter=0.02,
                inner_diameter=0.019, poisson_ratio=0.4)
    radius = kink_radius(part, kind, rules)
    a, t = tube_section(0.02, 0.019)
    assert brazier_flattening(1.0 / radius, a, t, 0.4) == pytest.approx(rules.kink_red,
                                                                          rel=1e-12)
    # A thick wall (the engine bay's PA12 line, a/t = 3.5) and a hose: no kink limit.
    bay = load_scene(EXAMPLE.parent / "engine_bay.toml").problem.part
    assert kink_radius(bay, rules.kind(bay.kind), rules) is None
    assert kink_radius(part, rules.kind("rubber hose"), rules) is None


def test_the_path_table_reads_back_whatever_the_grip_is_called(found):
    _, result = found
    odd = replace(result, grip='left "hand"\\\n\tnaïve')
    doc = read_toml(odd.path_table(), "table")
    assert doc["path"]["grip"] == odd.grip
    assert doc["path"]["waypoints"] == [list(map(float, f"{x:.6g} {y:.6g} {z:.6g}".split()))
                                        for x, y, z in (p.position for p in result.poses)]


@pytest.mark.parametrize(("gap", "blocked"), [(0.04, True), (0.2, False)])
def test_the_planner_carries_the_hands_envelope_with_the_part(gap, blocked):
    """A pose whose hand sits between two walls 40 mm apart (parallel to the part, the
    part clear of both by more than the margin) is refused for want of room for the
    hand, and one between walls wide enough for it is not."""
    from pliant.assembly.plan import _Blocked
    from pliant.models import rod3d
    from pliant.scene.distance import Obstacle

    scene = load_scene(EXAMPLE)
    hand = scene.problem.condition("hand")
    t = np.asarray(hand.tangent)
    n = np.array([0.866025, 0.5, 0.0])  # horizontal, square to the part there
    frame = np.column_stack([t, n, np.cross(t, n)])
    walls = tuple(Obstacle.box(name, (0.4, 0.2, 0.4),
                               np.asarray(hand.position) + side * (gap / 2 + 0.1) * n,
                               frame) for name, side in (("left wall", 1), ("right wall", -1)))
    problem = replace(scene.problem, obstacles=scene.problem.obstacles + walls)
    scene = replace(scene, problem=problem)
    if blocked:  # the start pose itself: refused before any search, saying why
        with pytest.raises(InputError, match=r"no room for the hand \((left|right) wall\); "
                           "move the grip's start where a hand fits"):
            Planner(scene, PlanSettings()).tree("port")
        return
    tree = Planner(scene, PlanSettings()).tree("port")
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=scene.solver.elements))
    tree.check_step(eq)
    narrow = replace(problem, obstacles=scene.problem.obstacles[:-2] + tuple(
        replace(w, translation=w.translation - np.sign(w.translation @ n - hand.position @ n)
                * (gap / 2 - 0.02) * n) for w in walls))
    eq = rod3d.solve(narrow, solver=rod3d.RodSolver(elements=scene.solver.elements))
    with pytest.raises(_Blocked, match=r"no room for the hand \((left|right) wall\)"):
        tree.check_step(eq)
