"""A/D sequences: the bundled engine-bay example's orders and the reason the failing ones
fail (checked against the fitted hose's shape solved apart), the pruned search against
the exhaustive one on random scenes, an interrupted search resumed, Dask against this
process, the command line's outputs and exit codes, and bad sequence files."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from pliant.assembly.scenes import load_scene
from pliant.assembly.sequence import fitted_obstacles, load_sequence, sequence
from pliant.errors import FileFormatError
from tests.helpers import LINE_ONTO_BOSS, cli

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "sequence"
BAY = EXAMPLE / "engine_bay.toml"


@pytest.fixture(scope="module")
def bay(tmp_path_factory):
    """The example searched once (pruned), in this process, with its store."""
    out = tmp_path_factory.mktemp("bay")
    return sequence(BAY, out=out / "search", workers=0), out


def test_the_oil_line_must_go_before_the_hose_and_the_cable_anywhere(bay):
    result, _ = bay
    passing = {o.parts for o in result.orders if o.passes}
    every = set(itertools.permutations(("coolant hose", "oil line", "sensor cable")))
    expected = {p for p in every if p.index("oil line") < p.index("coolant hose")}
    assert passing == expected
    assert result.best is not None and result.best.parts in expected
    for order in result.orders:
        if order.passes:
            continue
        failing = order.failing
        assert failing["part"] == "oil line" and "coolant hose" in failing["prefix"]
        assert failing["blockers"] == ["coolant hose"]
    [rule] = result.precedences
    assert (rule.first, rule.then) == ("oil line", ("coolant hose",))
    # Judged once per prefix; the orders that fit the hose first and something else
    # before the oil line are pruned by the hose's failure, not judged again.
    assert result.pruned == 2 and result.judged == 3 + 6 + 3


def test_the_failing_order_fails_where_the_hose_lies_across_the_line_s_way(bay):
    """Independent of the search: the hose's fitted shape solved here, from its own
    file's last path step; the oil line's grip path (its file's waypoints) passes
    through the hose's tube, and the oil line alone does fit."""
    from pliant.models import rod3d

    result, _ = bay
    seq = load_sequence(BAY)
    hose = load_scene(EXAMPLE / "coolant_hose.toml")
    last = hose.path[-1]
    from dataclasses import replace
    alone = rod3d.solve(replace(last, obstacles=seq.obstacles),
                        solver=rod3d.RodSolver(elements=hose.solver.elements))
    line = load_scene(EXAMPLE / "oil_line.toml")
    grip = np.array([p.condition("hand").position for p in line.path])
    gaps = np.linalg.norm(grip[:, None, :] - alone.position[None, :, :], axis=2).min(axis=1)
    reach = hose.problem.part.drawn_radius + line.problem.part.drawn_radius
    assert gaps.min() < reach  # the hand's path runs through where the hose lies
    # The search's fitted hose is that same shape.
    [obstacle] = fitted_obstacles(seq, (seq.index("coolant hose"),))
    assert np.abs(np.asarray(obstacle.fitted.rest_line) - alone.position).max() < 1e-6
    first = result.operations[((), "oil line")]
    assert first["passes"]
    after = result.operations[(("coolant hose",), "oil line")]
    assert after["status"] == "fails" and "coolant hose" in " ".join(after["reasons"])


def test_fitted_parts_do_not_pass_through_each_other_in_the_best_order(bay):
    result, _ = bay
    seq = load_sequence(BAY)
    prefix = tuple(seq.index(p) for p in result.best.parts)
    obstacles = fitted_obstacles(seq, prefix)
    radii = {f.name: f.scene.problem.part.drawn_radius for f in seq.fits}
    for a, b in itertools.combinations(obstacles, 2):
        la, lb = np.asarray(a.fitted.rest_line), np.asarray(b.fitted.rest_line)
        gap = np.linalg.norm(la[:, None] - lb[None], axis=2).min()
        assert gap > radii[a.name] + radii[b.name] - 1e-3


def test_an_interrupted_search_resumes_to_the_same_answer(bay, tmp_path):
    result, out = bay
    folder = tmp_path / "resumed"
    folder.mkdir()
    (folder / "sequence.json").write_bytes((out / "search" / "sequence.json").read_bytes())
    lines = (out / "search" / "operations.jsonl").read_text().splitlines(keepends=True)
    # Five operations written whole, the sixth cut short by the interruption.
    (folder / "operations.jsonl").write_text("".join(lines[:5]) + lines[5][:40])
    resumed = sequence(BAY, out=folder, workers=0)
    assert resumed.reused == 5 and resumed.judged == len(lines) - 5
    assert [o.parts for o in resumed.orders] == [o.parts for o in result.orders]
    assert [o.to_dict() for o in resumed.orders] == [o.to_dict() for o in result.orders]
    assert [p.to_dict() for p in resumed.precedences] == [p.to_dict()
                                                          for p in result.precedences]


def test_the_search_refuses_a_store_of_other_files(bay, tmp_path):
    from pliant.errors import InputError

    _, out = bay
    other = tmp_path / "other.toml"
    other.write_text(BAY.read_text().replace("margin = 0.005", "margin = 0.004"))
    for name in ("coolant_hose.toml", "oil_line.toml", "sensor_cable.toml"):
        (tmp_path / name).write_text((EXAMPLE / name).read_text())
    with pytest.raises(InputError, match="holds the search of other files"):
        sequence(other, out=out / "search", workers=0)


# -- a parking clip: two parts that block each other ------------------------------------
CLIP = EXAMPLE / "parking_clip.toml"
ONTO, OFF = "coolant hose onto parking clip", "coolant hose off parking clip"


@pytest.fixture(scope="module")
def clipped(tmp_path_factory):
    """The parking-clip example searched once by the command, with its store."""
    out = tmp_path_factory.mktemp("clip")
    done = cli("sequence", CLIP, "--out", out / "search", "--json", out / "s.json")
    return done, json.loads((out / "s.json").read_text()), out


def test_a_parking_clip_fits_two_parts_that_block_each_other(clipped):
    """Neither direct order fits (each part's precedence over the other is found); with
    the hose left on the clip while the oil line goes in, the operations fit, at the
    cost of one re-grasp; the exhaustive twin finds the same orders."""
    done, data, out = clipped
    assert done.returncode == 0, done.stdout
    orders = {tuple(o["parts"]): o for o in data["orders"]}
    assert not orders[("coolant hose", "oil line")]["passes"]
    assert not orders[("oil line", "coolant hose")]["passes"]
    passing = [p for p, o in orders.items() if o["passes"]]
    assert (ONTO, "oil line", OFF) in passing
    assert all(ONTO in p and p.index(ONTO) < p.index(OFF) for p in passing)
    assert data["best"]["cost"][2] == 1.0 and "re-grasps" in data["cost"][2]
    assert {(p["first"], tuple(p["then"])) for p in data["precedences"]} == {
        ("coolant hose", ("oil line",)), ("oil line", ("coolant hose",))}
    # Hose onto the clip, straight off it, then the line: as the hose fitted first.
    assert "coolant hose in the way" in orders[(ONTO, OFF, "oil line")]["why"]
    slow = sequence(CLIP, out=out / "search", workers=0, exhaustive=True)
    assert [o.parts for o in slow.orders if o.passes] == passing
    assert slow.best.parts == tuple(data["best"]["parts"])
    page = (out / "search" / "report.html").read_text()
    assert ONTO in page and "re-grasp" in page


def test_why_the_clip_is_needed_from_shapes_solved_apart(clipped):
    """Independent of the search: each part solved alone along its own file's path.
    The hose carried straight from where it is picked up sweeps through the oil line's
    fitted tube; left on the clip it is the search's obstacle there, clear of the whole
    of the line's way down; taken from the clip it reaches the pipe without passing
    through the line (it rests on it at the end, as fitted after it directly)."""
    from dataclasses import replace

    from pliant.assembly.sequence import operation_scene, steps
    from pliant.models import rod3d

    _, data, _ = clipped
    seq = load_sequence(CLIP)
    names = [st.name for st in steps(seq)]
    hose = load_scene(EXAMPLE / "coolant_hose_behind.toml")
    line = load_scene(EXAMPLE / "oil_line.toml")
    reach = hose.problem.part.drawn_radius + line.problem.part.drawn_radius

    def alone(path, elements):
        return [eq.position for eq in rod3d.trace(
            [replace(p, obstacles=seq.obstacles) for p in path],
            solver=rod3d.RodSolver(elements=elements))]

    def gap(a, b):
        return float(np.linalg.norm(a[:, None] - b[None], axis=2).min())

    line_way = alone(line.path, line.solver.elements)
    fitted_line = line_way[-1]
    swept = [gap(x, fitted_line) for x in alone(hose.path, hose.solver.elements)]
    assert min(swept[:-1]) < reach  # through the line on the way, not only at the end
    failing = data["operations"]
    [direct] = [op for op in failing if op["part"] == "coolant hose"
                and op["prefix"] == ["oil line"]]
    assert direct["status"] == "fails" and direct["blockers"] == ["oil line"]
    onto = operation_scene(seq, names.index(ONTO))
    hanging = alone(onto.path, hose.solver.elements)[-1]
    [obstacle] = fitted_obstacles(seq, (names.index(ONTO),))
    assert obstacle.name == "coolant hose (on parking clip)"
    assert np.abs(np.asarray(obstacle.fitted.rest_line) - hanging).max() < 1e-6
    assert min(gap(x, hanging) for x in line_way) > reach
    off = operation_scene(seq, names.index(OFF))
    taken = [gap(x, fitted_line) for x in alone([off.problem, *off.path],
                                                 hose.solver.elements)]
    assert np.abs(taken[0] - gap(hanging, fitted_line)) < 1e-6  # it starts as it hangs
    assert min(taken[:-1]) > reach


# -- random scenes: the pruned search against the exhaustive one --------------------------
HOSE = """
name = "hose across"
gravity = [0.0, 0.0, -9.81]
[part]
name = "hose"
length = 0.43
outer_diameter = 0.025
bending_stiffness = 0.25
mass_per_length = 0.4
min_bend_radius = 0.06
[solver]
elements = 16
[[port]]
name = "pipe"
position = [0.2, {y}, 0.40]
axis = [-1.0, 0.0, 0.0]
[[condition]]
name = "housing"
s = 0.0
x = -0.2
y = {y}
z = 0.40
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "hand"
s = 0.43
x = 0.12
y = {y0}
z = 0.43
tangent = [0.6, 0.8, 0.0]
[path]
grip = "hand"
waypoints = [[0.17, {y1}, 0.41], [0.2, {y}, 0.40]]
tangents = [[0.9, 0.4, 0.0], [1.0, 0.0, 0.0]]
steps = 6
"""



def _random_scene(folder: Path, rng: np.random.Generator, lines: int) -> Path:
    y = float(rng.uniform(-0.06, 0.06))
    (folder / "hose.toml").write_text(HOSE.format(y=y, y0=y - 0.12, y1=y - 0.05))
    fits = ['[[fit]]\nname = "hose"\nfile = "hose.toml"\n']
    for k in range(lines):
        x, yl = float(rng.uniform(-0.12, 0.12)), float(rng.uniform(-0.08, 0.08))
        (folder / f"line{k}.toml").write_text(
            LINE_ONTO_BOSS.format(x=x, y=yl, yc=yl + 0.24, ys=yl + 0.06, steps=6))
        fits.append(f'[[fit]]\nname = "line {k}"\nfile = "line{k}.toml"\n')
    path = folder / "sequence.toml"
    path.write_text('name = "random"\nmargin = 0.003\n' + "\n".join(fits))
    return path


def test_the_pruned_search_finds_the_exhaustive_search_s_best_order(tmp_path):
    rng = np.random.default_rng(5)
    agree, cases, pruned, failing, fitting = 0, 4, 0, 0, 0
    for k in range(cases):
        folder = tmp_path / f"scene{k}"
        folder.mkdir()
        path = _random_scene(folder, rng, 1 + k % 2)
        fast = sequence(path, out=folder / "store", workers=0)
        # The exhaustive twin reuses the store (the operations judged are the same) and
        # judges the pruned ones.
        slow = sequence(path, out=folder / "store", workers=0, exhaustive=True)
        assert slow.pruned == 0 and slow.judged == fast.pruned
        pruned += fast.pruned
        failing += sum(not o.passes for o in slow.orders)
        best = (fast.best.parts if fast.best else None, slow.best.parts if slow.best else None)
        agree += best[0] == best[1]
        fitting += best[1] is not None
        assert {o.parts for o in fast.orders if o.passes} <= {o.parts for o in slow.orders
                                                              if o.passes}
    assert agree >= cases - 1  # a floor: the pruning assumption may miss, rarely
    assert failing > 0 and pruned > 0  # the cases do exercise the pruning
    assert fitting >= cases - 1  # and have a best order to agree on (not "none fits")


# -- Dask, the command line, bad files ---------------------------------------------------
def test_a_local_cluster_gives_what_this_process_gives(bay, tmp_path):
    here, _ = bay
    there = sequence(BAY, out=tmp_path / "search", workers=2)
    assert there.workers == 2 and there.judged == here.judged and there.pruned == here.pruned
    assert [o.to_dict() for o in there.orders] == [o.to_dict() for o in here.orders]
    assert [p.to_dict() for p in there.precedences] == [p.to_dict() for p in here.precedences]


def test_pliant_sequence_writes_json_and_a_report_and_exits_by_the_answer(bay, tmp_path):
    # The search's store with its last three operations not yet judged: the command
    # judges those and reads the others.
    _, searched = bay
    out = tmp_path / "search"
    out.mkdir()
    (out / "sequence.json").write_bytes((searched / "search" / "sequence.json").read_bytes())
    lines = (searched / "search" / "operations.jsonl").read_text().splitlines(keepends=True)
    (out / "operations.jsonl").write_text("".join(lines[:-3]))
    done = cli("sequence", BAY, "--out", out, "--json", tmp_path / "s.json")
    assert done.returncode == 0, done.stdout
    assert "FITS in 3 of 6 orders" in done.stdout
    assert "3 operations judged now" in " ".join(done.stdout.split())
    data = json.loads((tmp_path / "s.json").read_text())
    assert data["passes"] and data["best"]["parts"][0] in ("oil line", "sensor cable")
    assert data["precedences"][0]["first"] == "oil line"
    page = (out / "report.html").read_text()
    assert "precedence graph" in page and "oil line before coolant hose" in page
    # The 3D view: each part of the best order as it is left, among the bay's obstacles.
    start = page.index("<script type=application/json>") + len("<script type=application/json>")
    view = json.loads(page[start:page.index("</script>", start)].replace("<\\/", "</"))
    assert [x["n"] for x in view["lines"]] == data["best"]["parts"]
    assert all(len(x["p"]) >= 3 * 10 for x in view["lines"])
    assert {m["n"] for m in view["meshes"]} == {o.name for o in load_sequence(BAY).obstacles}
    # Run again: every operation comes from the store.
    again = cli("sequence", BAY, "--out", out)
    assert again.returncode == 0 and "0 operations judged now" in " ".join(again.stdout.split())


def test_a_part_that_fails_alone_fails_every_order_and_is_pruned_after_others(tmp_path):
    """An oil line whose datasheet allows no bend tighter than 0.2 m: red alone, so no
    order fits; after the cable it is pruned, not judged."""
    (tmp_path / "line.toml").write_text((EXAMPLE / "oil_line.toml").read_text().replace(
        "min_bend_radius = 0.04", "min_bend_radius = 0.2"))
    (tmp_path / "cable.toml").write_text((EXAMPLE / "sensor_cable.toml").read_text())
    path = tmp_path / "strict.toml"
    path.write_text('name = "strict"\n[[fit]]\nname = "line"\nfile = "line.toml"\n'
                    '[[fit]]\nname = "cable"\nfile = "cable.toml"\n')
    done = cli("sequence", path, "--out", tmp_path / "s", "--json", tmp_path / "s.json")
    assert done.returncode == 1
    assert "NO ORDER FITS" in " ".join(done.stdout.split())
    data = json.loads((tmp_path / "s.json").read_text())
    assert not data["passes"] and data["judged"] == 2 and data["pruned"] == 1
    assert data["precedences"] == []  # it fails alone: no other part is to blame
    for order in data["orders"]:
        assert "fitting line" in order["why"] and "bend radius" in order["why"]


@pytest.mark.parametrize("text, where", [
    ('[[fit]]\nname = "x"\nfile = "nowhere.toml"\n', "fit[0].file"),
    ('[[fit]]\nname = "x"\nfile = "oil_line.toml"\n[[fit]]\nname = "x"\nfile = '
     '"oil_line.toml"\n', "named 'x'"),
    ('[[fit]]\nname = "x"\nfile = "oil_line.toml"\ncolour = "red"\n', "fit[0].colour"),
    ('[[fit]]\nname = "engine block"\nfile = "oil_line.toml"\n[[obstacle]]\nname = '
     '"engine block"\nshape = "box"\nsize = [0.1, 0.1, 0.1]\nposition = [0, 0, 0]\n',
     "both an obstacle and a part"),
    ('[[fit]]\nname = "x"\nfile = "nopath.toml"\n', "has no [path]"),
    ('[[fit]]\nname = "x"\nfile = "oil_line.toml"\n[[hook]]\nname = "h"\npart = "y"\n'
     'position = [0, 0, 0.5]\n', "hook[0].part"),
    ('[[fit]]\nname = "x"\nfile = "oil_line.toml"\n[[hook]]\nname = "h"\npart = "x"\n'
     'position = [0, 0, 0.5]\ntangent = [0, 0, 0]\n', "hook[0].tangent"),
    ("margin = 0.01\n", "fit"),
])
def test_a_bad_sequence_file_is_refused_naming_the_field(tmp_path, text, where):
    (tmp_path / "oil_line.toml").write_text((EXAMPLE / "oil_line.toml").read_text())
    (tmp_path / "nopath.toml").write_text((EXAMPLE / "oil_line.toml").read_text()
                                          .split("[path]")[0])
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=r"bad\.toml") as err:
        load_sequence(path)
    assert where in str(err.value)


FAR_CABLE = """
name = "a short cable far away"
gravity = [0.0, 0.0, -9.81]
[part]
name = "cable"
length = 0.3
outer_diameter = 0.006
bending_stiffness = 0.05
mass_per_length = 0.05
[solver]
elements = 30
[[condition]]
name = "clip"
s = 0.0
x = 2.0
y = 0.0
z = 0.5
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "hand"
s = 0.3
x = 2.25
y = 0.0
z = 0.4
tangent = [1.0, 0.0, 0.0]
[path]
grip = "hand"
waypoints = [[2.25, 0.05, 0.4]]
steps = 3
"""


def test_a_part_without_a_path_is_planned_in_each_operation(tmp_path):
    """The hose round its post has no [path], only a [plan] goal: each operation plans
    it among the parts fitted before (here a cable far away, which changes nothing: the
    same seeded plan in both orders), every planned path followed and judged, and once
    fitted it sits seated at its port."""
    from pliant.assembly.sequence import seated

    scenes = Path(__file__).resolve().parents[1] / "examples" / "scenes"
    (tmp_path / "hose.toml").write_text((scenes / "hose_past_post.toml").read_text())
    (tmp_path / "cable.toml").write_text(FAR_CABLE)
    path = tmp_path / "planned.toml"
    path.write_text('name = "planned"\n[[fit]]\nname = "hose"\nfile = "hose.toml"\n'
                    '[[fit]]\nname = "cable"\nfile = "cable.toml"\n')
    result = sequence(path, out=tmp_path / "s", workers=0)
    assert {o.parts for o in result.orders if o.passes} == {("hose", "cable"),
                                                            ("cable", "hose")}
    records = [json.loads(line) for line in (tmp_path / "s" / "operations.jsonl")
               .read_text().splitlines()]
    hose = [r for r in records if r["part"] == "hose"]
    assert len(hose) == 2 and all(r["status"] == "passes" for r in hose)
    assert all(r["plan"]["waypoints"] > 0 for r in hose)
    assert hose[0]["plan"]["waypoints"] == hose[1]["plan"]["waypoints"]
    from pliant.cli.sequence_report import render_html

    page = render_html(result)
    assert page.count(f"planned: {hose[0]['plan']['waypoints']} waypoints") == 2
    seq = load_sequence(path)
    port = seq.fits[0].scene.ports["port"]
    done = seated(seq.fits[0].scene).condition("hand")
    np.testing.assert_allclose(done.position, port.position, atol=1e-12)
    np.testing.assert_allclose(done.tangent, -np.asarray(port.axis), atol=1e-6)


def test_a_planned_part_is_planned_from_its_hook_and_an_unneeded_hook_costs_a_re_grasp(
        tmp_path):
    """The hose round its post, planned, with a hook beside its start: carried straight
    to the hook (no plan), then planned from there to its port; both ways fit, green,
    with one hand, and the way without the hook ranks first by its re-grasp."""
    scenes = Path(__file__).resolve().parents[1] / "examples" / "scenes"
    (tmp_path / "hose.toml").write_text((scenes / "hose_past_post.toml").read_text())
    path = tmp_path / "hooked.toml"
    path.write_text('name = "hooked"\n[[fit]]\nname = "hose"\nfile = "hose.toml"\n'
                    '[[hook]]\nname = "hook"\npart = "hose"\n'
                    'position = [0.25, -0.35, 0.7]\n')
    result = sequence(path, workers=0)
    assert [(o.parts, o.passes) for o in result.orders] == [
        (("hose",), True), (("hose onto hook", "hose off hook"), True)]
    direct, hooked = (o.cost for o in result.orders)
    assert direct[:2] == hooked[:2] == (0.0, 0.0)  # green, one hand, both
    assert (direct[2], hooked[2]) == (0.0, 1.0)
    onto, off = result.orders[1].operations
    assert "plan" not in onto and off["plan"]["waypoints"] > 0


def test_a_path_that_cannot_be_planned_fails_blaming_the_parts_in_its_way():
    """Where no path is found, the operation fails and blames the fitted parts the
    rejected motions name (all of them where none is named)."""
    from pliant.assembly.plan import NoPathError
    from pliant.assembly.sequence import _unplanned

    err = NoPathError("no path found", closest=None, distance=0.2, seconds=6.0, solves=90,
                      blocked={"clearance to cable": 30, "no room for the hand (cable)": 4,
                               "a fold (the part would snap to another shape)": 2})
    record = _unplanned(err, ["line", "cable"])
    assert record["status"] == "fails" and record["blockers"] == ["cable"]
    assert record["reasons"][0] == "[red] no path found: clearance to cable (30 motions)"
    unnamed = NoPathError("no path found", closest=None, distance=0.2, seconds=6.0,
                          solves=90, blocked={"bend radius below 58 mm": 9})
    assert _unplanned(unnamed, ["line", "cable"])["blockers"] == ["line", "cable"]


@pytest.mark.parametrize(("options", "field"), [
    ({"scheduler": "not a url"}, "scheduler"), ({"workers": -3}, "workers")])
def test_a_bad_cluster_is_refused_at_once_naming_the_option(tmp_path, options, field):
    """A scheduler address that is none, or fewer than no workers: a typed error naming
    the option, before anything is judged (``assembly.cluster``, shared with studies)."""
    from pliant.errors import InputError

    with pytest.raises(InputError, match=field) as err:
        sequence(BAY, out=tmp_path / "s", **options)
    assert err.value.field == field
    assert not (tmp_path / "s" / "operations.jsonl").exists() or not (
        tmp_path / "s" / "operations.jsonl").read_text().strip()


def test_a_second_search_in_a_folder_in_use_is_refused(tmp_path):
    """Issue 54: one writer per store: a search's folder held by another is refused
    before anything is judged, naming the folder."""
    from pliant.errors import InputError
    from pliant.io.folder_lock import FolderLock

    out = tmp_path / "busy"
    with FolderLock(out, "sequence search"), pytest.raises(
            InputError, match="in use by another sequence search"):
        sequence(BAY, out=out, workers=0)
    assert not (out / "operations.jsonl").exists()
