"""Scenes from CAD: a committed STEP assembly in millimetres (examples/cad, written by its
make_bracket_step.py with OpenCASCADE) read into named obstacles in metres."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pliant.assembly.scenes import load_scene, parse_scene
from pliant.errors import FileFormatError, InputError
from pliant.io.cad import read_assembly

CAD = Path(__file__).resolve().parents[1] / "examples" / "cad"
STEP = CAD / "bracket_assembly.step"
# what make_bracket_step.py built, in metres
BOUNDS = {
    "bracket": [[0.100, -0.020, 0.000], [0.220, 0.020, 0.010]],
    "manifold": [[-0.025, -0.100, 0.035], [0.025, 0.100, 0.085]],
    "bolt": [[0.127, -0.003, 0.010], [0.133, 0.003, 0.040]],
    "bolt_1": [[0.187, -0.003, 0.010], [0.193, 0.003, 0.040]],
}


@pytest.fixture(scope="module")
def solids():
    return {s.name: s for s in read_assembly(STEP, tolerance=1e-4)}


def test_the_assembly_gives_each_instance_named_and_placed_in_metres(solids):
    assert set(solids) == set(BOUNDS)
    for name, bounds in BOUNDS.items():
        # a tessellated round face lies inside its circle: its box within the tolerance
        assert np.allclose(solids[name].bounds, bounds, atol=1e-4), name


def test_the_tessellation_keeps_within_its_chord_tolerance(solids):
    for tolerance in (1e-4, 1e-3):
        tube = next(s for s in read_assembly(STEP, tolerance=tolerance)
                    if s.name == "manifold")
        side = tube.vertices[tube.faces]
        lateral = np.ptp(side[:, :, 1], axis=1) > 1e-6  # faces along the axis (y)
        radius = np.hypot(side[lateral, :, 0], side[lateral, :, 2] - 0.06)
        assert np.allclose(radius, 0.025, atol=1e-9)  # vertices on the surface
        centres = side[lateral].mean(axis=1)
        sag = 0.025 - np.hypot(centres[:, 0], centres[:, 2] - 0.06)
        # a triangle's centroid lies 2/3 of the chord's sag in at most
        assert 0.0 < sag.max() <= tolerance
    coarse = next(s for s in read_assembly(STEP, tolerance=1e-3) if s.name == "manifold")
    assert len(coarse.faces) < len(solids["manifold"].faces)


def test_name_patterns_keep_and_drop_solids():
    names = {s.name for s in read_assembly(STEP, keep=["bolt*"])}
    assert names == {"bolt", "bolt_1"}
    names = {s.name for s in read_assembly(STEP, drop=["BOLT*"])}  # patterns are case-blind
    assert names == {"bracket", "manifold"}
    with pytest.raises(InputError, match=r"its solids: .*manifold"):
        read_assembly(STEP, keep=["exhaust*"])


def test_a_broken_step_file_is_a_typed_error_naming_it(tmp_path, capfd):
    bad = tmp_path / "truncated.step"
    bad.write_bytes(STEP.read_bytes()[:3000])
    with pytest.raises(FileFormatError, match=r"truncated.step"):
        read_assembly(bad)
    out, err = capfd.readouterr()
    assert "StepFile" not in out + err  # OpenCASCADE's own chatter is kept off the terminal
    with pytest.raises(FileFormatError, match="no such CAD file"):
        read_assembly(tmp_path / "missing.step")
    with pytest.raises(InputError, match="declares its own unit"):
        read_assembly(STEP, units="mm")


def test_a_mesh_without_units_takes_the_scenes(tmp_path):
    import trimesh

    plate = trimesh.creation.box(extents=(120.0, 40.0, 10.0))  # millimetres, centred
    plate.export(tmp_path / "plate.stl")
    (solid,) = read_assembly(tmp_path / "plate.stl", units="mm")
    assert np.allclose(solid.bounds, [[-0.06, -0.02, -0.005], [0.06, 0.02, 0.005]])
    with pytest.raises(InputError, match="unknown unit 'furlong'"):
        read_assembly(tmp_path / "plate.stl", units="furlong")
    # a scene's units: those of the files it reads; its own numbers stay SI
    scene = SCENE.replace('[[cad]]\nfile = "bracket_assembly.step"\n', "")
    scene = 'units = "mm"\n' + scene + PLATES
    obstacles = parse_scene(scene, "scene", tmp_path).problem.obstacles
    assert [o.name for o in obstacles] == ["from mesh", "from cad/plate"]
    for o, z in zip(obstacles, (-0.5, 0.0)):
        lo, hi = o.mesh.bounds + o.translation
        assert np.allclose([lo, hi], [[-0.06, -0.02, z - 0.005], [0.06, 0.02, z + 0.005]])


PLATES = """
[[cad]]
file = "plate.stl"
name = "from cad"

[[obstacle]]
name = "from mesh"
shape = "mesh"
file = "plate.stl"
position = [0.0, 0.0, -0.5]
"""


SCENE = """
name = "cad"
gravity = [0.0, 0.0, -9.81]

[part]
length = 0.3
bending_stiffness = 0.01

[[condition]]
name = "clamp"
s = 0.0
x = -0.1
y = 0.0
z = 0.2
tangent = [1.0, 0.0, 0.0]

[[cad]]
file = "bracket_assembly.step"
"""


def test_a_scene_imports_the_solids_as_obstacles_or_one_merged():
    problem = parse_scene(SCENE, "scene", CAD).problem
    obstacles = {o.name: o for o in problem.obstacles}
    assert set(obstacles) == set(BOUNDS)
    # above the bracket's flat top, between the bolts: 10 mm from the top face
    from pliant.scene.distance import DistanceField

    field = DistanceField(list(problem.obstacles))
    distance = field.query(np.array([[0.16, 0.0, 0.02]]))[0]
    assert distance == pytest.approx(0.010, abs=1e-9)
    merged = parse_scene(SCENE + 'merge = true\nname = "bay"\nkeep = ["b*"]\n', "scene",
                         CAD).problem.obstacles
    assert [o.name for o in merged] == ["bay"]
    assert np.allclose(merged[0].mesh.bounds, [[0.1, -0.02, 0.0], [0.22, 0.02, 0.04]],
                       atol=1e-4)
    with pytest.raises(FileFormatError, match=r"scene: cad\[0\].keep: no solid"):
        parse_scene(SCENE + 'keep = ["nothing"]\n', "scene", CAD)
    with pytest.raises(FileFormatError, match=r"cad\[0\].*merge = true needs"):
        parse_scene(SCENE + "merge = true\n", "scene", CAD)


def test_the_cad_example_rests_its_cable_on_the_far_bolt():
    from pliant.models import rod3d

    scene = load_scene(CAD / "cable_over_bracket.toml")
    eq = rod3d.solve(scene.problem, solver=rod3d.RodSolver(elements=scene.solver.elements))
    touched = eq.contacts.by_obstacle()
    assert set(touched) == {"bolt_1"}
    weight = 0.45 * 0.08 * 9.81
    total = sum(ld.force for ld in eq.reactions.values()) + sum(touched.values())
    assert np.allclose(total, [0.0, 0.0, weight], atol=1e-8)  # balance with the contact
    assert eq.stable


def test_large_meshes_are_drawn_decimated_and_close_to_the_exact_surface():
    import trimesh

    from pliant.io.mesh_export import display_mesh

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=0.3)  # 20,480 triangles
    drawn = display_mesh(sphere, max_faces=2000)
    assert len(drawn.faces) <= 2000 < len(sphere.faces)
    radius = np.linalg.norm(drawn.vertices, axis=1)
    assert np.abs(radius - 0.3).max() < 0.003  # within 1 % of the surface it stands for
    assert display_mesh(sphere, max_faces=30000) is sphere  # small enough: as it is


def test_a_scenes_display_budget_is_shared_in_proportion_and_keeps_small_parts():
    from pliant.io.mesh_export import DISPLAY_FLOOR, display_budgets

    assert display_budgets([1000, 2000, 3000]) == [1000, 2000, 3000]  # fits: all of it
    counts = [2_000_000, 500_000, 50_000, 3000, 300] + [40_000] * 100
    drawn = display_budgets(counts, budget=200_000)
    assert sum(drawn) <= 200_000
    assert drawn[4] == 300 and drawn[3] >= DISPLAY_FLOOR  # a bolt stays a bolt
    assert drawn[0] >= drawn[1] >= drawn[2] >= drawn[5]  # the big give up detail first
    assert sum(drawn) > 0.95 * 200_000  # and the budget is used, not wasted


def test_ports_and_clips_take_their_place_from_named_solids():
    text = SCENE.replace("length = 0.3", "length = 0.6") + """
[[port]]
name = "stub"
solid = "bolt"
axis = [0.0, 0.0, 1.0]

[[clip]]
name = "clip"
s = 0.45
solid = "bolt_1"
axis = [1.0, 0.0, 0.0]
"""
    scene = parse_scene(text, "scene", CAD)
    # the bolt's top face (z = 40 mm) at its axis; the other bolt's box centre
    assert np.allclose(scene.ports["stub"].position, [0.130, 0.0, 0.040], atol=1e-9)
    clip = scene.problem.condition("clip")
    assert np.allclose(clip.position, [0.190, 0.0, 0.025], atol=1e-9)
    # they hold the part: no longer obstacles to it
    assert {o.name for o in scene.problem.obstacles} == {"bracket", "manifold"}
    with pytest.raises(FileFormatError, match=r"port\[0\].solid: no mesh obstacle named "
                                              r"'nut'; there are bolt, bolt_1"):
        parse_scene(text.replace('solid = "bolt"', 'solid = "nut"'), "scene", CAD)
    with pytest.raises(FileFormatError, match="give position"):
        parse_scene(text.replace('solid = "bolt"', 'solid = "bolt"\nposition = [0, 0, 0]'),
                    "scene", CAD)


def test_reading_an_assembly_says_how_far_it_got():
    from pliant.util.progress import listening

    said: list[str] = []
    with listening(said.append):
        parse_scene(SCENE, "scene", CAD)
    assert said[0] == "bracket_assembly.step: reading and tessellating"
    assert said[-1].startswith("bracket_assembly.step: distance structures of solid 4 of 4")
    parse_scene(SCENE, "scene", CAD)  # nobody listening: nothing said, nothing fails
    assert len(said) == 5


class _Recorder:
    """A progress listener that keeps everything it is told."""

    def __init__(self) -> None:
        self.said: list[str] = []
        self.totals: list[float] = []
        self.done: list[float] = []
        self.stops = 0

    def say(self, text: str) -> None:
        self.said.append(text)

    def start(self, total: float) -> None:
        self.totals.append(total)

    def update(self, done: float) -> None:
        self.done.append(done)

    def stop(self) -> None:
        self.stops += 1


def test_the_progress_bar_runs_over_the_assemblys_triangles_once():
    """One task for the whole assembly (the solids' builds only advance it), counted in
    triangles, never backwards, ending at its total; a lone mesh gets a task of its own."""
    from pliant.scene.distance import prepare_mesh
    from pliant.util.progress import listening

    bar = _Recorder()
    with listening(bar):
        problem = parse_scene(SCENE, "scene", CAD).problem
    triangles = sum(len(o.mesh.tri) for o in problem.obstacles)
    assert bar.totals == [triangles] and bar.stops == 1
    assert np.all(np.diff(bar.done) >= 0.0)
    assert bar.done[-1] == pytest.approx(triangles, rel=1e-12)
    assert len(bar.done) >= 4 * len(problem.obstacles)  # each solid's steps move it
    lone = _Recorder()
    mesh = problem.obstacles[0].mesh
    flat = mesh.tri.reshape(-1, 3)
    with listening(lone):
        prepare_mesh(flat, np.arange(len(flat)).reshape(-1, 3), 16, cache=False)
    assert lone.totals == [len(mesh.tri)] and lone.done[-1] == pytest.approx(len(mesh.tri))


def test_a_cad_tables_packaging_rule_reaches_each_of_its_solids(tmp_path):
    """``[[cad]] temperature = ..., edge = true`` is the rule of every solid it brings
    (named by its prefix), as an ``[[obstacle]]``'s is its own; one left without says
    nothing."""
    import trimesh

    trimesh.creation.box(extents=(120.0, 40.0, 10.0)).export(tmp_path / "plate.stl")
    scene = SCENE.replace('[[cad]]\nfile = "bracket_assembly.step"\n', "")
    plates = PLATES.replace('name = "from cad"\n', 'name = "from cad"\ntemperature = 300.0\n'
                            'edge = true\n')
    built = parse_scene('units = "mm"\n' + scene + plates, "scene", tmp_path)
    rule = built.obstacle_rules["from cad/plate"]
    assert rule.temperature == 300.0 and rule.edge and not rule.moving
    assert "from mesh" not in built.obstacle_rules


_CHILDREN = """
import os, signal, sys, threading, time
from pathlib import Path
from pliant.errors import FileFormatError
from pliant.io.cad import read_assembly

def children():
    pid = os.getpid()
    return [int(c) for c in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]

def killer(sig):
    while True:
        found = children()
        if found:  # at once: it cannot have read the file yet
            os.kill(found[0], sig)
            return
        time.sleep(0.005)
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads /proc")
def test_opencascade_crashing_or_ctrl_c_ends_only_its_own_process():
    """OpenCASCADE reads a STEP file in a process of its own: where it crashes (killed
    here with SIGSEGV as it reads), the read is a typed error naming the signal and
    the file; a Ctrl+C while it reads raises KeyboardInterrupt in pliant at once, with
    the reader killed and reaped (no process left), not a crash."""
    import subprocess
    import sys

    crash = _CHILDREN + f"""
threading.Thread(target=killer, args=(signal.SIGSEGV,), daemon=True).start()
try:
    read_assembly(Path({str(STEP)!r}), tolerance=2e-4)
except FileFormatError as err:
    print("typed:", err)
print("left:", children())
"""
    out = subprocess.run([sys.executable, "-c", crash], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "typed:" in out.stdout and "signal 11" in out.stdout
    assert "bracket_assembly.step" in out.stdout and "left: []" in out.stdout
    interrupt = _CHILDREN + f"""
def press():
    while not children():
        time.sleep(0.005)
    os.kill(os.getpid(), signal.SIGINT)  # at once: it cannot have read the file yet
threading.Thread(target=press, daemon=True).start()
try:
    read_assembly(Path({str(STEP)!r}), tolerance=3e-4)
    print("finished first")
except KeyboardInterrupt:
    print("interrupted; left:", children())
"""
    out = subprocess.run([sys.executable, "-c", interrupt], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert "interrupted; left: []" in out.stdout, out.stdout


def test_a_crease_angle_reaches_meshes_and_cad_and_a_bad_one_is_refused(tmp_path):
    """``crease`` on an [[obstacle]] mesh and a [[cad]] file, in a scene in millimetres:
    a cylinder in 256 facets (1.4 degrees apart) is one smooth surface at the default
    10 degrees (its side's edges smooth, its rims sharp) and all facets at 0; the same
    smoothing a mesh given in metres gets; 90 degrees is refused naming the field."""
    import trimesh

    from pliant.errors import FileFormatError
    from pliant.scene.distance import Obstacle

    post = trimesh.creation.cylinder(radius=50.0, height=400.0, sections=256)  # mm
    post.export(tmp_path / "post.stl")
    base = SCENE.replace('[[cad]]\nfile = "bracket_assembly.step"\n', "")

    def flags(extra_obstacle: str, extra_cad: str) -> list[np.ndarray]:
        text = ('units = "mm"\n' + base + '\n[[cad]]\nfile = "post.stl"\nname = "cad"\n'
                + extra_cad + '\n[[obstacle]]\nname = "mesh"\nshape = "mesh"\n'
                'file = "post.stl"\nposition = [0.0, 0.0, -0.5]\n' + extra_obstacle)
        obstacles = parse_scene(text, "scene", tmp_path).problem.obstacles
        return [o.mesh.pseudo[:, 10] for o in obstacles]

    smooth = flags("", "")
    metres = Obstacle.from_mesh("m", post.vertices * 1e-3, post.faces).mesh.pseudo[:, 10]
    for f in smooth:  # 1,024 triangles' 3,072 edge uses; the two rims' 512 edges sharp
        assert np.array_equal(f, metres)
        assert f.size == 3 * 1024 and f.sum() == 3 * 1024 - 2 * 512
    assert all(f.sum() == 0 for f in flags("crease = 0.0\n", "crease = 0.0\n"))
    with pytest.raises(FileFormatError, match=r"crease"):
        flags("crease = 90.0\n", "")
