"""Problem files: the examples parse, errors name file and field, and the parser never
fails with anything but a FileFormatError."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.errors import FileFormatError, OutputError
from pliant.io.problem_file import dump_problem, load_problem, parse_problem

from .helpers import EXAMPLES, zoo

MINIMAL = """
name = "m"
[part]
length = 1.0
bending_stiffness = 2.0
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
angle = 0.0
[[condition]]
name = "tip"
s = 1.0
Fy = 3.0
"""


def test_examples_parse():
    for i in (1, 2, 3):
        problem = load_problem(EXAMPLES / "paper" / f"case{i}.toml")
        assert problem.part.length == 1.0 and problem.part.bending_stiffness == 1.0
    case2 = load_problem(EXAMPLES / "paper" / "case2.toml")
    assert all(c.follower for c in case2.conditions if c.name != "clamp")
    assert case2.condition("hand 2").force == (0.0, 15.0)


@pytest.mark.parametrize("name", sorted(zoo()))
def test_dump_then_parse_round_trip(name):
    problem = zoo()[name]
    again = parse_problem(dump_problem(problem))
    assert again.conditions == problem.conditions
    assert again.gravity == problem.gravity
    assert again.part.rest_knots == problem.part.rest_knots
    assert again.part.bending_stiffness == problem.part.bending_stiffness


THREE_D = """
name = "hose"
gravity = [0.0, 0.0, -9.81]
[part]
length = 0.8
bending_stiffness = 0.05
torsional_stiffness = 0.03
mass_per_length = 0.3
[solver]
elements = 60
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "tap"
s = 0.4
follower_force = [0.0, 0.5, 0.0]
[[condition]]
name = "hand"
s = 0.8
x = 0.5
y = 0.2
z = 0.1
tangent = [0.0, 1.0, 0.0]
"""


def test_3d_file():
    from pliant.io.problem_file import parse_problem_file

    problem, settings = parse_problem_file(THREE_D)
    assert problem.dimension == 3 and settings.elements == 60
    tap = problem.condition("tap")
    assert tap.follower and tap.force == (0.0, 0.5, 0.0)
    hand = problem.condition("hand")
    assert hand.tangent == (0.0, 1.0, 0.0) and hand.normal is None
    again = parse_problem(dump_problem(problem))
    assert again.conditions == problem.conditions and again.gravity == problem.gravity


def test_tube_section_and_material():
    text = MINIMAL.replace("bending_stiffness = 2.0", """outer_diameter = 0.02
inner_diameter = 0.012
[part.material]
youngs_modulus = 5.0e6
density = 1150.0""")
    part = parse_problem(text).part
    assert part.bending_stiffness == pytest.approx(5e6 * math.pi * (0.02**4 - 0.012**4) / 64)
    assert part.mass_per_length == pytest.approx(1150 * math.pi * (0.02**2 - 0.012**2) / 4)


@pytest.mark.parametrize("change,where", [
    (("length = 1.0", "length = -1.0"), "part.length"),
    (("length = 1.0", 'length = "long"'), "part.length"),
    (("Fy = 3.0", "Fy = 3.0\nFw = 1.0"), "condition[1].Fw"),
    (("Fy = 3.0", "tangent = [1.0, 0.0, 0.0]"), "condition[0]: angle"),
    (("Fy = 3.0", "Fy = 3.0\nFt = 1.0"), "condition[1]"),
    (("bending_stiffness = 2.0", ""), "part"),
    (("s = 1.0", "s = 2.0"), "tip.s"),
    (("Fy = 3.0", "y = 3.0"), "tip.position"),
    (("Fy = 3.0", "Fy = nan"), "condition[1].Fy"),
])
def test_errors_name_the_field(change, where):
    text = MINIMAL.replace(*change)
    with pytest.raises(FileFormatError) as err:
        parse_problem(text, "bad.toml")
    message = str(err.value)
    assert message.startswith("bad.toml: ")
    assert where in message
    assert "\n" not in message


def test_invalid_toml_and_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="not valid TOML"):
        parse_problem("[part\nlength = 1", "x.toml")
    with pytest.raises(FileFormatError, match="no such file"):
        load_problem(tmp_path / "missing.toml")


values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5),
                   st.text(max_size=4), st.booleans(), st.none())
keys = st.sampled_from(["s", "x", "y", "angle", "Fx", "Fy", "moment", "Ft", "Fn", "name",
                        "bogus"])


@st.composite
def documents(draw):
    part = draw(st.dictionaries(st.sampled_from(["length", "bending_stiffness",
                                                 "mass_per_length", "rest_curvature",
                                                 "outer_diameter"]),
                                values, max_size=5))
    conditions = draw(st.lists(st.dictionaries(keys, values, max_size=6), max_size=4))
    return part, conditions


def _toml_value(v) -> str:
    if v is None:
        return '""'
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents())
def test_parser_gives_a_problem_or_a_file_error(doc):
    part, conditions = doc
    lines = ["[part]"] + [f"{k} = {_toml_value(v)}" for k, v in part.items()]
    for cond in conditions:
        lines.append("[[condition]]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in cond.items()]
    try:
        problem = parse_problem("\n".join(lines), "fuzz.toml")
    except FileFormatError as err:
        assert str(err).startswith("fuzz.toml: ")
    else:
        assert isinstance(problem, pl.Problem)


def test_a_misspelt_key_is_named_with_the_nearest_the_table_takes():
    from pliant.assembly.scenes import parse_scene
    from pliant.errors import FileFormatError

    with pytest.raises(FileFormatError) as err:
        parse_scene("[part]\nlenght = 1.0\nbending_stiffness = 1.0\n", "x.toml")
    message = str(err.value)
    assert message.startswith("x.toml: part.lenght: unknown key 'lenght'; did you mean "
                              "'length'? [part] takes ")
    assert "(and 1 more)" in message  # the length it then misses
    with pytest.raises(FileFormatError, match="did you mean 'tangent'\\? \\[condition\\] "
                                              "takes Fn, Ft"):
        parse_scene("[part]\nlength = 1.0\nbending_stiffness = 1.0\n[[condition]]\ns = 0\n"
                    "tangnet = [1, 0, 0]\n", "x.toml")
    with pytest.raises(FileFormatError, match="unknown key 'zzz'; the file's top level "
                                              "takes assembled"):
        parse_scene("zzz = 1\n[part]\nlength = 1.0\nbending_stiffness = 1.0\n", "x.toml")
    with pytest.raises(FileFormatError, match="'gravity' is a top-level key, but it stands "
                                              "under \\[part\\]"):
        parse_scene("[part]\nlength = 1.0\nbending_stiffness = 1.0\ngravity = [0, -9.81]\n",
                    "x.toml")


def test_a_diameter_given_in_millimetres_is_refused_with_the_units():
    from pliant.assembly.scenes import parse_scene

    with pytest.raises(FileFormatError, match=r"part: outer_diameter 20 m is more than half "
                                              "the part's length \\(1 m\\).*20 mm is 0.02"):
        parse_scene("[part]\nlength = 1.0\nbending_stiffness = 1.0\nouter_diameter = 20\n",
                    "x.toml")
    ok = parse_scene("[part]\nlength = 1.0\nbending_stiffness = 1.0\nouter_diameter = 0.02\n"
                     "[[condition]]\ns = 0.0\nx = 0.0\ny = 0.0\nangle = 0.0\n", "x.toml")
    assert ok.problem.part.outer_diameter == 0.02


def test_dump_keeps_the_obstacles_and_their_meshes(tmp_path):
    """Every kind of obstacle survives a dump and a parse (a recording of a scene used
    to lose them): the same shapes, places, friction and meshes, so the same distances
    everywhere; a mesh goes to a file of its own, every digit kept."""
    import trimesh

    from pliant.assembly.scenes import parse_scene
    from pliant.scene.distance import DistanceField, Obstacle

    turn = trimesh.transformations.rotation_matrix(0.4, [1, 2, 3])[:3, :3]
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.07)
    obstacles = (
        Obstacle.sphere("ball", 0.05, (0.3, -0.2, 0.0)),
        Obstacle.box("crate", (0.1, 0.2, 0.3), (0.5, 0.3, -0.1), turn).with_friction(0.3),
        Obstacle.cylinder("pipe", 0.02, 0.4, (0.2, 0.4, 0.1), turn),
        Obstacle.halfspace("floor", (0.0, 0.0, -0.3), (0.1, 0.0, 1.0)),
        Obstacle.from_mesh("a bolt head", ball.vertices * 1.0000001, ball.faces,
                           (0.6, -0.3, 0.2), turn, 32),
    )
    problem = pl.Problem(pl.Part(0.8, 0.05), (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),),
                         gravity=(0.0, 0.0, -9.81), obstacles=obstacles)
    with pytest.raises(OutputError, match="'a bolt head' is a mesh"):
        dump_problem(problem)
    text = dump_problem(problem, meshes=tmp_path / "meshes", base=tmp_path)
    assert 'file = "meshes/a_bolt_head.obj"' in text
    again = parse_scene(text, "dumped", tmp_path).problem
    assert [o.name for o in again.obstacles] == [o.name for o in obstacles]
    for a, b in zip(obstacles, again.obstacles):
        assert a.kind == b.kind and a.friction == b.friction
        assert np.array_equal(a.translation, b.translation)
        assert np.array_equal(a.param, b.param)
        if a.mesh is not None:
            assert np.array_equal(a.mesh.tri, b.mesh.tri)
            assert np.array_equal(a.mesh.g_values, b.mesh.g_values)
    points = np.random.default_rng(2).uniform(-0.6, 0.8, (300, 3))
    d0, _g0, o0 = DistanceField(list(obstacles)).query(points, band=0.05)
    d1, _g1, o1 = DistanceField(list(again.obstacles)).query(points, band=0.05)
    assert np.abs(d0 - d1).max() < 1e-12 and np.array_equal(o0, o1)


@st.composite
def _problems(draw) -> pl.Problem:
    """A random 3D problem with what a file can hold: a part (its rest curvature a number
    or knots), a clamp and a push or a grip, gravity, distributed loads on stretches and
    primitive obstacles turned and placed anywhere."""
    from pliant.core.loads import DistributedLoad
    from pliant.scene.distance import Obstacle

    finite = st.floats(-5.0, 5.0, allow_nan=False, width=64)
    length = draw(st.floats(0.2, 3.0))
    curvature = draw(st.one_of(st.floats(-2.0, 2.0), st.just(((0.0, 0.3), (length, -0.4)))))
    part = pl.Part(length=length, bending_stiffness=draw(st.floats(0.01, 50.0)),
                   torsional_stiffness=draw(st.floats(0.01, 50.0)),
                   mass_per_length=draw(st.floats(0.0, 2.0)), rest_curvature=curvature)
    end = (pl.push(length, force=tuple(draw(finite) for _ in range(3)), name="hand")
           if draw(st.booleans()) else
           pl.grip(length, position=(0.5 * length, 0.1 * length, 0.0), name="hand"))
    loads = []
    for i in range(draw(st.integers(0, 2))):
        a = draw(st.floats(0.0, 0.8)) * length
        b = draw(st.one_of(st.none(), st.floats(0.85, 1.0).map(lambda f: f * length)))
        loads.append(DistributedLoad(tuple(draw(finite) for _ in range(3)),
                                     follower=draw(st.booleans()), start=a, end=b,
                                     name=f"load{i}"))
    angle = draw(st.floats(-3.0, 3.0))
    turn = np.array([[math.cos(angle), -math.sin(angle), 0.0],
                     [math.sin(angle), math.cos(angle), 0.0], [0.0, 0.0, 1.0]])
    where = tuple(draw(finite) for _ in range(3))
    obstacles = [draw(st.sampled_from([
        Obstacle.sphere("ball", 0.1, where), Obstacle.box("block", (0.1, 0.2, 0.3), where, turn),
        Obstacle.cylinder("pipe", 0.05, 0.4, where, turn),
        Obstacle.halfspace("floor", where, turn[:, 0])]))]
    return pl.Problem(part, (pl.clamp(0.0, (0.0, 0.0, 0.0)), end),
                      gravity=(0.0, 0.0, -draw(st.floats(0.0, 20.0))), name="random",
                      obstacles=tuple(obstacles), loads=tuple(loads))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_problems())
def test_a_problem_written_reads_back_as_itself(problem):
    """Load, dump, load: the same problem (conditions, gravity, loads, the part's
    stiffness and rest curvature, and its obstacles' shapes and poses), equal as a whole
    (parts and obstacles compare by value), and writing it again gives the same text."""
    text = dump_problem(problem)
    again = parse_problem(text)
    assert again.conditions == problem.conditions
    assert again.gravity == problem.gravity and again.loads == problem.loads
    assert again.part.rest_knots == problem.part.rest_knots
    assert again.part.stiffnesses == problem.part.stiffnesses
    assert len(again.obstacles) == len(problem.obstacles)
    for a, b in zip(again.obstacles, problem.obstacles):
        assert (a.name, a.kind) == (b.name, b.kind)
        np.testing.assert_allclose(a.translation, b.translation, atol=1e-12)
        np.testing.assert_allclose(a.param, b.param, atol=1e-12)
        if a.kind != 3:  # a half-space is its plane: the turn about its normal is free
            np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-12)
        else:
            np.testing.assert_allclose(a.rotation[:, 2], b.rotation[:, 2], atol=1e-12)
    assert dump_problem(again) == text
    assert again == problem  # by value, obstacles included
