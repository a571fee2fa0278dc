"""Scene files (obstacles, ports, clips, a path, materials by name), the material
library, following a path, and `pliant run` / `pliant demo` on the bundled scene."""

from __future__ import annotations

import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.assembly import follow_path
from pliant.assembly.scenes import load_scene, parse_scene
from pliant.errors import FileFormatError, InputError
from pliant.io.materials import library, material
from pliant.scene.distance import BOX, CYLINDER, HALFSPACE, MESH, SPHERE

from .helpers import EXAMPLES, cli

BAY = EXAMPLES / "scenes" / "engine_bay.toml"

SMALL = """
name = "small"
gravity = [0.0, 0.0, -9.81]
margin = 0.005
[part]
length = 1.0
outer_diameter = 0.01
inner_diameter = 0.008
material = "pa12"
[[port]]
name = "inlet"
position = [0.0, 0.0, 0.0]
axis = [1.0, 0.0, 0.0]
[[port]]
name = "outlet"
position = [0.8, 0.0, 0.0]
axis = [-1.0, 0.0, 0.0]
[[condition]]
name = "inlet end"
s = 0.0
port = "inlet"
[[condition]]
name = "hand"
s = 1.0
port = "outlet"
[[clip]]
name = "clip"
s = 0.5
position = [0.4, 0.0, 0.15]
axis = [1.0, 0.0, 0.0]
[[obstacle]]
name = "floor"
shape = "halfspace"
position = [0.0, 0.0, -0.3]
[[obstacle]]
name = "ball"
shape = "sphere"
radius = 0.05
position = [0.4, 0.3, 0.0]
[[obstacle]]
name = "pipe"
shape = "cylinder"
radius = 0.02
length = 0.5
position = [0.2, 0.0, -0.2]
axis = [0.0, 1.0, 0.0]
[[obstacle]]
name = "crate"
shape = "box"
size = [0.1, 0.2, 0.3]
position = [0.6, -0.3, 0.0]
rotation = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
"""


def test_a_scene_builds_its_obstacles_ports_clips_and_material():
    scene = parse_scene(SMALL, "small.toml")
    problem = scene.problem
    part = problem.part
    # PA12 from the library: E = 1.1 GPa on a 10 x 8 mm section.
    inertia = math.pi / 64 * (0.01**4 - 0.008**4)
    assert part.bending_stiffness == pytest.approx(1.1e9 * inertia, rel=1e-12)
    assert part.mass_per_length == pytest.approx(1020.0 * math.pi / 4 * (0.01**2 - 0.008**2))
    kinds = {o.name: o.kind for o in problem.obstacles}
    assert kinds == {"floor": HALFSPACE, "ball": SPHERE, "pipe": CYLINDER, "crate": BOX}
    conditions = {c.name: c for c in problem.conditions}
    # A port gives the first end its axis, the last end the opposite (it arrives).
    assert conditions["inlet end"].tangent == (1.0, 0.0, 0.0)
    assert conditions["hand"].tangent == (1.0, -0.0, -0.0)
    assert conditions["hand"].position == (0.8, 0.0, 0.0)
    assert conditions["clip"].position == (0.4, 0.0, 0.15) and conditions["clip"].s == 0.5
    pipe = next(o for o in problem.obstacles if o.name == "pipe")
    assert np.allclose(pipe.rotation[:, 2], (0.0, 1.0, 0.0))
    assert scene.margin == 0.005 and not scene.path
    # The crate's rotation turns its local x (0.1 m) onto y: it spans 0.1 m along y.
    crate = next(o for o in problem.obstacles if o.name == "crate")
    d, _, _ = pl.scene.DistanceField([crate]).query([[0.6, -0.3 + 0.05 + 0.01, 0.0]])
    assert d[0] == pytest.approx(0.01)


def test_meshes_are_read_relative_to_the_scene_file(tmp_path):
    folder = tmp_path / "scene"
    (folder / "cad").mkdir(parents=True)
    trimesh.creation.box(extents=(100.0, 100.0, 100.0)).export(folder / "cad" / "cube.stl")
    text = SMALL + """
[[obstacle]]
name = "cube"
shape = "mesh"
file = "cad/cube.stl"
scale = 0.001
position = [0.4, 0.0, 0.6]
"""
    (folder / "scene.toml").write_text(text)
    scene = load_scene(folder / "scene.toml")
    cube = next(o for o in scene.problem.obstacles if o.name == "cube")
    assert cube.kind == MESH
    d, _, _ = pl.scene.DistanceField([cube]).query([[0.4, 0.0, 0.8]], band=0.5)
    assert d[0] == pytest.approx(0.15, abs=1e-9)  # 100 mm cube, its top at 0.65 m
    shutil.move(folder / "cad" / "cube.stl", folder / "cube.stl")
    with pytest.raises(FileFormatError, match=r"obstacle\[4\]: file: no such mesh file .*"
                                              r"cad/cube.stl"):
        load_scene(folder / "scene.toml")
    (folder / "cad" / "cube.stl").write_text("not a mesh at all")
    with pytest.raises(FileFormatError, match=r"obstacle\[4\]: file: "):
        load_scene(folder / "scene.toml")


@pytest.mark.parametrize("change, where", [
    (('shape = "sphere"', 'shape = "cone"'), "obstacle[1].shape"),
    (("radius = 0.05\n", ""), "obstacle[1]: a sphere needs radius"),
    (('position = [0.6, -0.3, 0.0]\n', 'position = [0.6, -0.3, 0.0]\naxis = [0, 0, 1]\n'),
     "give rotation or axis, not both"),
    (('material = "pa12"', 'material = "unobtainium"'), "no material 'unobtainium'"),
    (('port = "outlet"', 'port = "exit"'), "condition[1]: port: no [[port]] named 'exit'"),
    (("[[0.0, -1.0, 0.0]", "[[0.0, -2.0, 0.0]"), "obstacle[3]: a rotation must be"),
    (('port = "inlet"', 'port = "inlet"\nx = 0.1'), "takes its position and axis"),
    (('name = "floor"', 'name = "floor"\nfriction = -0.2'), "obstacle[0].friction"),
])
def test_scene_errors_name_the_field(change, where):
    assert change[0] in SMALL
    with pytest.raises(FileFormatError) as err:
        parse_scene(SMALL.replace(*change, 1), "bad.toml")
    assert str(err.value).startswith("bad.toml: ") and where in str(err.value)


def test_the_path_carries_the_grip_through_its_waypoints_at_even_steps():
    text = SMALL.replace('port = "outlet"', 'x = 0.8\ny = 0.0\nz = 0.0\ntangent = [1, 0, 0]')
    text += """
[path]
grip = "hand"
waypoints = [[0.8, 0.0, 0.3], [0.56, 0.32, 0.3]]
tangents = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
steps = 7
"""
    scene = parse_scene(text, "path.toml")
    assert len(scene.path) == 7
    held = [next(c for c in p.conditions if c.name == "hand") for p in scene.path]
    positions = np.array([c.position for c in held])
    start = np.array([0.8, 0.0, 0.0])
    walked = np.linalg.norm(np.diff(np.vstack([start, positions]), axis=0), axis=1)
    assert np.allclose(walked, 0.7 / 7)  # equal steps along 0.3 + 0.4 m
    assert np.allclose(positions[-1], (0.56, 0.32, 0.3))
    tangents = np.array([c.tangent for c in held])
    assert np.allclose(np.linalg.norm(tangents, axis=1), 1.0)
    assert np.allclose(tangents[-1], (0.0, 1.0, 0.0))
    # 3 steps of 0.1 m reach the first waypoint, whose tangent is (0, 0, 1).
    assert np.allclose(tangents[2], (0.0, 0.0, 1.0))
    # Every other condition stays as it was.
    assert all(p.conditions[0] == scene.problem.conditions[0] for p in scene.path)
    with pytest.raises(FileFormatError, match=r"path.grip"):
        parse_scene(text.replace('grip = "hand"', 'grip = "foot"'), "path.toml")
    with pytest.raises(FileFormatError, match="turns right round"):
        parse_scene(text.replace("[[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]",
                                 "[[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]"), "path.toml")


def test_the_library_has_sources_and_sane_values():
    assert len(library()) >= 8
    for name, entry in library().items():
        assert entry["source"] and entry["description"], name
        assert 1e5 < entry["youngs_modulus"] < 3e11 and 800 < entry["density"] < 9000, name
    assert material("Steel").youngs_modulus == 2.0e11
    with pytest.raises(InputError, match=r"known: .*PA12"):
        material("kevlar")


def test_following_the_bundled_path_keeps_out_of_everything():
    """The default scene: every step solved, balanced and stable, no snap, the line
    never into an obstacle by 1% of its radius, and touching the manifold at the end."""
    scene = load_scene(BAY)
    run = follow_path(scene.problem, scene.path, "hand", margin=scene.margin,
                      elements=scene.solver.elements)
    assert run.complete and len(run.steps) == len(scene.path) + 1
    assert not run.snaps and not run.unstable
    assert min(r.clearance for r in run.steps) > -0.01 * 0.004
    assert run.final.contacts.obstacle and set(run.final.contacts.obstacle) == {
        "exhaust manifold"}
    last = run.steps[-1]
    assert np.allclose(last.grip_position, (0.30, 0.10, 0.52), atol=1e-9)
    assert run.final.residual < 1e-8


def test_a_path_into_an_obstacle_stops_with_the_reason_and_keeps_the_steps():
    text = SMALL.replace('port = "outlet"', 'x = 0.8\ny = 0.0\nz = 0.0')
    # Into the ball: the end cannot be held inside it.
    text += '[path]\ngrip = "hand"\nwaypoints = [[0.4, 0.3, 0.0]]\nsteps = 3\n'
    scene = parse_scene(text, "into.toml")
    run = follow_path(scene.problem, scene.path, "hand", elements=40)
    assert not run.complete and "could not be solved" in run.stopped
    assert 1 <= len(run.steps) < 4
    # It says why: the hand's target is inside the ball (the part's tube round it).
    assert "hand.position: the part's tube there would be" in run.stopped
    assert "inside the obstacle 'ball'; move the target out of it" in run.stopped
    end = np.array(scene.path[len(run.steps) - 1].condition("hand").position)
    depth = 0.05 + 0.005 - np.linalg.norm(end - [0.4, 0.3, 0.0])
    assert f"would be {depth * 1e3:.3g} mm inside" in run.stopped


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "pliant.cli.app", *args],
                          capture_output=True, text=True, timeout=300)


def test_demo_follows_the_bundled_scene_and_writes_its_report(tmp_path):
    out = cli("demo", "--out", str(tmp_path / "demo"))
    assert out.returncode == 0, out.stderr
    assert "followed to its end" in out.stdout and "exhaust manifold" in out.stdout
    assert "FITS with one hand" in out.stdout
    evaluation = json.loads((tmp_path / "demo" / "engine_bay.json").read_text())
    report = evaluation["path"]
    assert report["complete"] and len(report["steps"]) == 101
    assert report["interference"]["penetrations"] == []
    assert evaluation["verdict"]["passes"] and evaluation["verdict"]["operator"] == "one hand"
    assert (tmp_path / "demo" / "engine_bay.html").stat().st_size > 100000
    assert len((tmp_path / "demo" / "engine_bay.csv").read_text().splitlines()) == 102
    assert (tmp_path / "demo" / "engine_bay.png").stat().st_size > 20000
    glb = trimesh.load(tmp_path / "demo" / "engine_bay.glb")
    assert {"exhaust manifold", "engine block"} <= set(glb.geometry)


def test_run_writes_its_records_with_their_units(tmp_path, capsys):
    from pliant.cli.app import run_scene

    text = SMALL.replace('port = "outlet"', 'x = 0.8\ny = 0.0\nz = 0.0')
    text += '[path]\ngrip = "hand"\nwaypoints = [[0.75, 0.0, 0.05]]\nsteps = 3\n'
    (tmp_path / "s.toml").write_text(text)
    run_scene(tmp_path / "s.toml", tmp_path / "out", 30)
    record = json.loads((tmp_path / "out" / "s.json").read_text())
    assert record["schema_version"] == 1 and record["complete"]
    assert record["units"]["force"] == "N" and record["units"]["clearance"] == "m"
    assert set(record["steps"][0]) - {"snap", "stable", "nearest", "contacts", "notes"} <= set(
        record["units"])  # every number has its unit (notes: the step's events, in words)
    # And on screen (rich once read "[mm]" and "[m]" as markup and dropped them).
    printed = " ".join(capsys.readouterr().out.split())
    for header in ("smallest clearance [mm]", "at s [m]", "x y z [m]"):
        assert header in printed, header


def test_run_without_a_path_is_a_one_line_error(tmp_path):
    (tmp_path / "s.toml").write_text(SMALL)
    out = _cli("run", str(tmp_path / "s.toml"), "--out", str(tmp_path))
    assert out.returncode == 2 and "no [path]" in out.stderr
    assert "Traceback" not in out.stderr


shapes = st.sampled_from(["box", "sphere", "cylinder", "halfspace", "mesh", "cone"])
numbers = st.one_of(st.floats(-1.0, 1.0), st.floats(allow_nan=True, allow_infinity=True),
                    st.integers(-3, 3))
vectors = st.one_of(st.lists(numbers, min_size=0, max_size=4), numbers)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.fixed_dictionaries({"shape": shapes}, optional={
    "size": vectors, "radius": numbers, "length": numbers, "position": vectors,
    "axis": vectors, "file": st.sampled_from(["none.stl", ""]), "scale": numbers}),
    max_size=3))
def test_the_scene_parser_gives_a_scene_or_a_file_error(obstacles):
    lines = ['gravity = [0.0, 0.0, -9.81]', "[part]", "length = 1.0",
             "bending_stiffness = 1.0"]
    for i, o in enumerate(obstacles):
        lines += ["[[obstacle]]", f'name = "o{i}"']
        for key, value in o.items():
            lines.append(f"{key} = {_toml(value)}")
    try:
        scene = parse_scene("\n".join(lines), "fuzz.toml")
    except FileFormatError as err:
        assert str(err).startswith("fuzz.toml: ")
    else:
        assert len(scene.problem.obstacles) == len(obstacles)


def _toml(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value == math.inf else (
            "-inf" if value == -math.inf else repr(value)))
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)


def test_an_assembled_flexible_part_becomes_an_obstacle_round_its_solved_shape(tmp_path):
    """The engine bay's coolant hose: its own file is solved and its tube (25 mm, 16
    sides, capped) is a closed mesh: its neutral line lies inside by the polygon's
    apothem, r cos(pi / 16), and a point 10 mm beyond the tube is 10 mm out."""
    from pliant.io.problem_file import load_problem_file
    from pliant.models import rod3d

    scene = load_scene(BAY)
    hose = next(o for o in scene.problem.obstacles if o.name == "coolant hose")
    assert hose.kind == MESH and hose.mesh.solid
    problem, _ = load_problem_file(EXAMPLES / "scenes" / "coolant_hose.toml")
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=60))
    field = pl.scene.DistanceField([hose])
    inside = field.query(eq.position[5:-5], band=0.05)[0]
    assert np.allclose(inside, -0.0125 * math.cos(math.pi / 16), atol=2e-4)
    top = eq.position[30] + np.array([0.0, 0.0, 0.0125 + 0.01])
    assert field.query(top[None], band=0.05)[0][0] == pytest.approx(0.01, abs=1e-3)
    text = BAY.read_text().replace('file = "coolant_hose.toml"', 'file = "gone.toml"')
    (tmp_path / "bay.toml").write_text(text)
    shutil.copy(EXAMPLES / "scenes" / "manifold.stl", tmp_path)
    with pytest.raises(FileFormatError, match=r"assembled\[0\]: file: no such problem file"):
        load_scene(tmp_path / "bay.toml")


def test_an_obstacle_takes_its_friction():
    """friction = mu on an [[obstacle]] reaches the problem's obstacle; none means 0."""
    scene = parse_scene(SMALL.replace('name = "floor"', 'name = "floor"\nfriction = 0.35', 1),
                        "small.toml")
    mu = {o.name: o.friction for o in scene.problem.obstacles}
    assert mu["floor"] == 0.35 and all(v == 0.0 for k, v in mu.items() if k != "floor")


@pytest.mark.parametrize(("obj", "message"), [
    ("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n", "not finite"),
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "no surface"),
    ("v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nf 1 2 3\n", "spans 1e.300 m.*check its unit"),
])
def test_a_mesh_with_nan_vertices_or_no_area_is_refused_naming_the_obstacle(tmp_path, obj,
                                                                           message):
    (tmp_path / "bad.obj").write_text(obj)
    text = SMALL + '[[obstacle]]\nname = "bracket"\nshape = "mesh"\nfile = "bad.obj"\n'
    with pytest.raises(FileFormatError,
                       match=rf"obstacle\[\d\].*bad\.obj.*{message}.*'bracket'"):
        parse_scene(text, "s.toml", tmp_path)


def test_a_boolean_is_not_a_length_and_a_huge_tangent_keeps_its_direction():
    with pytest.raises(FileFormatError, match=r"part\.length: a number is wanted here"):
        parse_scene(SMALL.replace("length = 1.0", "length = true", 1), "s.toml")
    from pliant.core.conditions import Condition

    c = Condition(s=0.0, position=(0.0, 0.0, 0.0), tangent=(1e200, 1e200, 0.0))
    assert c.tangent == pytest.approx((2**-0.5, 2**-0.5, 0.0))


def test_a_paths_steps_are_made_by_assembly_not_by_the_reader():
    """io reads the [path] as given (``path_spec``) and makes no steps; assembly's
    loader carries the grip through them: ``steps`` problems, the last at the last
    waypoint, each equal to the one before but for the grip."""
    from pliant.assembly.path import carry
    from pliant.io import problem_file

    file = EXAMPLES / "scenes" / "cable_through_clip.toml"
    read = problem_file.load_scene(file)
    assert read.path == [] and read.path_spec is not None
    scene = load_scene(file)
    spec = scene.path_spec
    assert len(scene.path) == spec.steps
    assert scene.path == carry(read.problem, spec)
    end = scene.path[-1].condition(spec.grip).position
    np.testing.assert_allclose(end, spec.waypoints[-1], atol=1e-12)
    for before, after in zip([scene.problem, *scene.path], scene.path):
        assert [c for c in before.conditions if c.name != spec.grip] == \
               [c for c in after.conditions if c.name != spec.grip]


def test_a_device_a_folder_or_a_huge_file_is_refused_unread(tmp_path, monkeypatch):
    """No file pliant reads is read without bound (issue 54: /dev/zero as the scene or
    the rules hung): a device or a folder is no regular file, and a file larger than
    the limit is refused after reading just past it."""
    from pliant.io import tomlfile
    from pliant.io.rules_file import load_rules

    with pytest.raises(FileFormatError, match="not a regular file"):
        load_scene("/dev/zero")
    with pytest.raises(FileFormatError, match=r"not a regular file.*rules file"):
        load_rules("/dev/zero")
    with pytest.raises(FileFormatError, match="not a regular file"):
        load_scene(tmp_path)
    with pytest.raises(FileFormatError, match="no such file"):
        load_scene(tmp_path / "nope.toml")
    monkeypatch.setattr(tomlfile, "LARGEST_TEXT", 100)
    (tmp_path / "big.toml").write_text("# " + "x" * 200 + "\n" + SMALL)
    with pytest.raises(FileFormatError, match="larger than"):
        load_scene(tmp_path / "big.toml")


@pytest.mark.parametrize(("change", "where"), [
    (('name = "floor"', 'name = "fl\\u001b[31moor"'), "obstacle[0].name"),
    (('[part]\nlength', '[part]\nname = "\\u0007hose"\nlength'), "part.name"),
])
def test_a_name_with_an_escape_sequence_is_refused(change, where):
    """Issue 54: names with ANSI escapes reached the terminal raw; a control character
    other than a tab or a line break is refused naming the field (multi-line notes stay
    valid: the paper's cases keep theirs)."""
    old, new = change
    assert old in SMALL
    with pytest.raises(FileFormatError, match=re.escape(where)):
        parse_scene(SMALL.replace(old, new, 1), "s.toml")
    load_scene(Path(__file__).resolve().parents[1] / "examples" / "paper" / "case1.toml")


def test_a_path_of_more_steps_than_memory_holds_is_refused():
    """Issue 54: steps = 100000 reached 4 GiB; the bound is checked as the file is read."""
    text = SMALL + '[path]\ngrip = "hand"\nwaypoints = [[0.5, 0.0, 0.3]]\nsteps = 20000\n'
    with pytest.raises(FileFormatError, match=r"path\.steps"):
        parse_scene(text, "s.toml")
