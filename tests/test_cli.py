"""The command line: summaries, JSON, plots, and one-line errors without tracebacks."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from .helpers import EXAMPLES, cli

PLIANT = [sys.executable, "-m", "pliant.cli.app"]


def run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([*PLIANT, *args], capture_output=True, text=True, timeout=300,
                          cwd=cwd)


def test_help_does_not_load_the_solvers():
    code = ("import sys, pliant.cli.app as a\n"
            "heavy = [m for m in ('numba', 'scipy', 'matplotlib', 'pydantic') "
            "if m in sys.modules]\nprint(heavy)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "[]"


def _flat(text: str) -> str:
    """Rendered help without its boxes and line breaks, one space between words."""
    return " ".join(text.translate({ord(c): " " for c in "│╭╮╰╯─"}).split())


def test_help_keeps_every_sentence_and_bracketed_name():
    """``pliant --help`` gives each command its docstring's first paragraph whole (not
    cut at the source's line breaks), and no help text loses a ``[section]`` name to
    rich's markup (``run``'s file argument once read "with a" and stopped)."""
    import re

    import typer

    from pliant.cli.app import app

    top = _flat(cli("--help").stdout)
    group = typer.main.get_command(app)
    checked = 0
    for name, command in group.commands.items():
        first = " ".join((command.callback.__doc__ or "").split("\n\n")[0].split())
        assert first.replace("\\[", "[") in top, name
        page = _flat(cli(name, "--help").stdout)
        for param in command.params:
            for section in re.findall(r"\[[a-z_]+\]", getattr(param, "help", "") or ""):
                assert section in page, (name, param.name, section)
                checked += 1
    assert checked >= 2  # run's and evaluate's file arguments at least


def test_solve_prints_a_summary(tmp_path):
    out = run("solve", str(EXAMPLES / "paper" / "case3.toml"), "--plot",
              str(tmp_path / "case3.png"))
    assert out.returncode == 0, out.stderr
    assert "paper case 3" in out.stdout
    assert "hole" in out.stdout and "reaction" in out.stdout
    assert "s [m]" in out.stdout  # the unit, not read as markup
    assert "-38.006" in out.stdout and "4.63997" in out.stdout
    assert "smallest bend radius" in out.stdout
    png = (tmp_path / "case3.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20000


def test_solve_json():
    out = run("solve", str(EXAMPLES / "paper" / "case1.toml"), "--json", "-")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["loads"]["clamp"]["force"] == pytest.approx([0.0, -7.0], abs=1e-9)
    assert len(data["s"]) == len(data["x"]) == len(data["M"])
    assert data["units"]["force"] == "N"
    assert data["residual"] < 1e-9


def test_every_json_option_takes_a_path_and_a_dash_for_standard_output(tmp_path):
    """One convention on every surface (issue 61): ``--json PATH`` writes the file (the
    words still on screen), ``--json -`` makes standard output the JSON alone; the same
    answer either way."""
    case1 = str(EXAMPLES / "paper" / "case1.toml")
    out = run("solve", case1, "--json", str(tmp_path / "case1.json"))
    assert out.returncode == 0, out.stderr
    assert "reaction" in out.stdout and "JSON written to" in out.stdout
    written = json.loads((tmp_path / "case1.json").read_text())
    printed = json.loads(run("solve", case1, "--json", "-").stdout)
    assert written["loads"] == printed["loads"] and written["s"] == printed["s"]
    scene = str(EXAMPLES / "scenes" / "hose_past_post.toml")
    out = run("evaluate", scene, "--json", "-")
    data = json.loads(out.stdout)  # nothing but the JSON
    assert data["schema_version"] == 1 and data["grips"] == ["hand"]
    assert "FITS" in out.stderr or "DOES NOT FIT" in out.stderr


@pytest.mark.parametrize("content,message", [
    (None, "no such file"),
    ("[part]\nlength = 1.0\nbending_stiffness = 1.0\n", "too few conditions"),
    ("[part]\nlength = -1.0\nbending_stiffness = 1.0\n", "part.length"),
    ("[part]\nlength = 1.0\nbending_stiffness = 1.0\n[[condition]]\ns = 0.0\nx = 0.0\n"
     "y = 0.0\nangle = 0.0\n[[condition]]\ns = 1.0\nx = 2.0\ny = 0.0\n", "inextensible"),
])
def test_bad_input_is_one_line_without_traceback(tmp_path, content, message):
    path = tmp_path / "bad.toml"
    if content is not None:
        path.write_text(content)
    out = run("solve", str(path))
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0]


def test_plot_is_written_atomically(tmp_path):
    """A plot into a folder that cannot be written fails cleanly and leaves no
    half-written file behind."""
    target = tmp_path / "existing.png"
    target.write_bytes(b"keep me")
    blocked = tmp_path / "blocked"
    blocked.write_text("a file, not a folder")
    out = run("solve", str(EXAMPLES / "paper" / "case1.toml"), "--plot",
              str(blocked / "x.png"))
    assert out.returncode == 2
    # (the last line: a first run says before it that it compiles)
    assert out.stderr.strip().splitlines()[-1].startswith("error: cannot write the plot")
    assert "Traceback" not in out.stderr
    assert target.read_bytes() == b"keep me"
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


@pytest.mark.parametrize("case", [1, 2, 3])
def test_the_paper_cases_solve_and_plot(tmp_path, case):
    from typer.testing import CliRunner  # in this process: the subprocess is tested above

    from pliant.cli.app import app

    out = CliRunner().invoke(app, ["solve", str(EXAMPLES / "paper" / f"case{case}.toml"),
                                   "--plot", str(tmp_path / f"case{case}.png")])
    assert out.exit_code == 0, out.output
    assert f"paper case {case}" in out.output
    # case 2 has follower loads: a static test does not decide its stability
    assert ("not decided" if case == 2 else "stability: stable") in out.output
    assert (tmp_path / f"case{case}.png").stat().st_size > 20000


def test_solve_3d_with_plot_and_meshes(tmp_path):
    import trimesh

    out = cli("solve", str(EXAMPLES / "hoses" / "hose3d.toml"), "--plot",
              str(tmp_path / "hose.png"), "--mesh", str(tmp_path / "hose.glb"),
              "--elements", "40")
    assert out.returncode == 0, out.stderr
    assert "3D, 40 elements" in out.stdout and "stability: stable" in out.stdout
    # An isotropic part free to twist at the hand carries no torque anywhere (m . t is
    # conserved along it): the solver's round-off there is printed as the 0 it is.
    assert "max |torque| = 0 N m" in " ".join(out.stdout.split())
    assert (tmp_path / "hose.png").stat().st_size > 20000
    scene = trimesh.load(tmp_path / "hose.glb")
    mesh = next(iter(scene.geometry.values())) if hasattr(scene, "geometry") else scene
    assert mesh.is_watertight
    # The tube's volume: the hose's section times its length, within the polygon's loss.
    assert mesh.volume == pytest.approx(math.pi * 0.01**2 * 1.0, rel=0.03)
    out = cli("solve", str(EXAMPLES / "hoses" / "hose3d.toml"), "--mesh",
              str(tmp_path / "hose.stl"), "--json", "-", "--elements", "40")
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    assert data["dimension"] == 3 and data["stable"] is True
    # The hand holds the end's axis, (0, 1, 0), and lets it twist: its moment about that
    # axis is 0, written as 0 (not the solver's 1e-16), the other two as they are.
    hand = data["loads"]["hand"]["moment"]
    assert hand[1] == 0.0 and abs(hand[0]) > 0.1
    assert data["tip"][1] == pytest.approx([0.0, 1.0, 0.0], abs=1e-12)  # a unit vector
    assert trimesh.load(tmp_path / "hose.stl").is_watertight


def test_a_scene_without_a_path_is_evaluated_as_its_one_pose():
    """No [path]: the pose is solved and judged, and the words say so (not "0 of 0
    steps solved" and "the path was followed to its end"); counts agree in number."""
    out = cli("evaluate", str(EXAMPLES / "scenes" / "hose_past_post.toml"))
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())
    assert "1 obstacle, one pose (no [path])" in text
    assert "the pose: the force and moment at hand" in text
    assert "steps solved" not in text and "followed to its end" not in text
    assert "peak force" not in text and "progress" not in text


def test_plan_writes_the_planned_scene_and_its_evaluation(tmp_path):
    scene = EXAMPLES / "scenes" / "hose_past_post.toml"
    out = cli("plan", str(scene), "--out", str(tmp_path), "--attempts", "1")
    assert out.returncode == 0, out.stderr  # planned, and the evaluation passes
    assert "(1 obstacle, budget" in " ".join(out.stdout.split())
    assert "found a path in" in out.stdout and "FITS" in out.stdout
    planned = tmp_path / "hose_past_post-planned.toml"
    text = planned.read_text()
    assert "# planned by `pliant plan` into 'port'" in text
    assert "# A planning example" in text  # the scene's own comments are kept
    from pliant.assembly.scenes import load_scene

    assert len(load_scene(planned).path) > 1  # test_plan.py follows such a file again
    record = json.loads((tmp_path / "hose_past_post-plan.json").read_text())
    assert record["schema_version"] == 1 and record["run"]["complete"]
    assert record["units"]["waypoints"] == "m" and record["units"]["run"]["force"] == "N"
    assert len(record["waypoints"]) == len(record["tangents"]) > 1
    report = json.loads((tmp_path / "hose_past_post-planned-evaluation.json").read_text())
    assert report["verdict"]["passes"]
    assert (tmp_path / "hose_past_post-planned.html").read_text().startswith("<!doctype html>")


def test_plan_without_a_goal_is_one_line(tmp_path):
    scene = EXAMPLES / "scenes" / "hose_past_post.toml"
    text = scene.read_text().replace('goal = "port"\n', "")
    (tmp_path / "nogoal.toml").write_text(text)
    out = run("plan", str(tmp_path / "nogoal.toml"), "--out", str(tmp_path))
    assert out.returncode == 2 and out.stderr.startswith("error: ")
    assert "give --goal PORT" in out.stderr and "Traceback" not in out.stderr
    # (An unknown port and a bad budget are typed errors too: test_plan.py.)


def test_version_answers_at_once():
    out = run("--version")
    from pliant import __version__

    assert out.returncode == 0 and out.stdout.strip() == f"pliant {__version__}"


def test_an_interrupt_after_some_outputs_says_which_were_written(monkeypatch, capsys,
                                                                  tmp_path):
    """Issue 54: 30 of 139 interrupts left an incomplete set of outputs with nothing
    marking it. A command interrupted after writing one of its files says so, naming the
    one it wrote (whole: written atomically) and that the set is incomplete."""
    import pliant.cli.app as cli_app
    from pliant.io.atomic import atomic_write

    def halfway():
        atomic_write(tmp_path / "e.json", lambda h: h.write(b"{}"), "the JSON")
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_app, "app", halfway)
    with pytest.raises(SystemExit) as stop:
        cli_app.main()
    said = capsys.readouterr().err
    assert stop.value.code == 130 and said.startswith("interrupted: the outputs are incomplete")
    assert str(tmp_path / "e.json") in said and (tmp_path / "e.json").read_text() == "{}"


def test_an_interrupted_command_counts_every_file_it_wrote():
    """A study interrupted after 400 voxel files said the last 64 paths one by one (and
    dropped the first files it wrote, its store among them). Every file is counted now,
    a folder of many by its count, the few by name, each once."""
    from pathlib import Path

    from pliant.io.atomic import Written

    written = Written()
    study = Path("/work/study")
    written.append(study / "samples.jsonl")
    for k in range(400):
        written.append(study / "voxels" / f"{k}.npy")
    written.append(study / "samples.jsonl")  # a store appended to again: once
    written.append(study / "report.html")
    assert len(written) == 402
    said = written.summary()
    assert said == (f"{study / 'samples.jsonl'}, {study / 'report.html'}, "
                    f"{study / 'voxels'}/ (400 files)")


def test_ctrl_c_on_the_command_says_what_it_wrote(tmp_path):
    """End to end: Ctrl+C on ``pliant study`` once it has stored a sample (Typer turns
    the interrupt into a silent exit 130; the command says what it had written, the
    store among them, and its lines are whole)."""
    import signal
    import time

    out = tmp_path / "study"
    process = subprocess.Popen(
        [sys.executable, "-m", "pliant.cli.app", "study",
         str(EXAMPLES / "scenes" / "engine_bay.toml"), "--vary", "bending_stiffness=20%",
         "--samples", "50", "--workers", "0", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    store = out / "samples.jsonl"
    deadline = time.monotonic() + 240
    while not (store.is_file() and store.read_text().count("\n")) and process.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert err.startswith("interrupted: the outputs are incomplete") and str(store) in err
    lines = store.read_text().splitlines()
    assert 1 <= len(lines) < 50 and all(json.loads(x)["index"] >= 0 for x in lines)


def test_ctrl_c_inside_a_compiled_kernel_is_interrupted_not_a_traceback(monkeypatch, capsys):
    import pliant.cli.app as cli_app

    def kernel_interrupted():
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:  # what CPython raises from a kernel's return
            raise SystemError("newton_contact returned a result with an exception set") \
                from interrupt

    monkeypatch.setattr(cli_app, "app", kernel_interrupted)
    with pytest.raises(SystemExit) as stop:
        cli_app.main()
    assert stop.value.code == 130
    assert capsys.readouterr().err == "interrupted: nothing written\n"

    def broken():
        raise SystemError("a real one")

    monkeypatch.setattr(cli_app, "app", broken)
    with pytest.raises(SystemError, match="a real one"):  # not hidden
        cli_app.main()


def test_solve_a_harness_reports_its_branches():
    """`pliant solve` on a harness: the summary names each branch with what holds it, the
    JSON carries the branches' loads, each port's reaction and the junction's."""
    harness = EXAMPLES / "harness" / "harness_y.toml"
    out = run("solve", str(harness))
    assert out.returncode == 0, out.stderr
    assert "branch 'left branch'" in out.stdout and "left port" in out.stdout
    assert "stability: stable" in out.stdout  # the parts together: the coupled verdict
    data = json.loads(run("solve", str(harness), "--json", "-").stdout)
    names = [b["name"] for b in data["branches"]]
    assert names == ["left branch", "right branch"]
    loads = {load["name"] for load in data["branches"][0]["loads"]}
    assert {"left port", "Y-piece: left branch"} <= loads


def test_vectors_print_round_off_as_zero_and_keep_small_values():
    """Issue: numerical noise was printed (-2.06e-17 beside 4.93 N). Below 1e-9 of the
    vector's size or the problem's scale it prints as 0; a small but real value stays."""
    from pliant.cli.report import vector_text

    assert vector_text((4.932, -2.0604e-17, 0.6461), 1.0) == "(4.932, 0, 0.6461)"
    assert vector_text((-1.9e-17, -0.44208, -1.96e-18), 2.5) == "(0, -0.44208, 0)"
    assert vector_text((1e-6, 1.0)) == "(1e-06, 1)"
    assert vector_text((3e-12, 0.0), 1.0) == "(0, 0)"  # noise against the problem's scale


def test_the_path_table_fits_80_columns_with_its_units(tmp_path, monkeypatch):
    """A path's table at 80 columns: one line per step (no cell wrapped onto three), the
    units shown in the headers (rich read "[m]" and "[mm]" as markup and dropped them)."""
    from typer.testing import CliRunner

    from pliant.cli.app import app

    monkeypatch.chdir(tmp_path)  # pliant run writes its files into pliant-out/ here
    scene = EXAMPLES / "scenes" / "cable_through_clip.toml"
    result = CliRunner().invoke(app, ["run", str(scene)], env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("along the path"))
    table = lines[start:next(i for i in range(start, len(lines))
                             if lines[i].startswith("peak force"))]
    assert max(len(line.rstrip()) for line in table) <= 80
    header = "\n".join(table[:5])
    for unit in ("x y z [m]", "[N]", "[N m]", "[mm]"):
        assert unit in header
    rows = [line for line in table if line.strip()[:1].isdigit()]
    assert len(rows) >= 2 and all(len(line.split()) >= 7 for line in rows)
    # The grip moves in the x-z plane: its y, round-off, reads 0.00, never -0.00; with
    # no obstacle there is no clearance to show (not "inf") and no clearance table.
    assert all(line.split()[2] == "0.00" for line in rows)
    assert "inf" not in "\n".join(rows) and all(line.split()[6] == "–" for line in rows)
    assert "clearance: the scene has no obstacles" in result.output


@pytest.mark.parametrize(("argv", "status", "said"), [
    (["--version"], 0, "pliant "), (["solve", "no-such-file.toml"], 2, "no such file")])
def test_the_command_leaves_at_once_with_its_status_its_output_and_exit_handlers(
        tmp_path, argv, status, said):
    """``entry`` (the console script) skips the interpreter's teardown, not what a
    command leaves to it: the status, the output flushed, the exit handlers run (Dask's
    and multiprocessing's close their processes there)."""
    code = ("import atexit, sys; atexit.register(lambda: print('handler ran'));"
            "from pliant.cli.app import entry; sys.argv = ['pliant', *sys.argv[1:]]; entry()")
    out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True,
                         cwd=tmp_path, timeout=120)
    assert out.returncode == status
    assert said in out.stdout + out.stderr and "handler ran" in out.stdout


def test_under_a_profiler_the_command_exits_as_usual(tmp_path):
    """``python -m cProfile`` writes its profile: ``entry`` leaves the usual way there."""
    profile = tmp_path / "run.prof"
    out = subprocess.run([sys.executable, "-m", "cProfile", "-o", str(profile), "-m",
                          "pliant.cli.app", "--version"], capture_output=True, text=True,
                         cwd=tmp_path, timeout=120)
    assert out.returncode == 0 and profile.stat().st_size > 0


def test_the_examples_copy_out_to_a_folder_of_ones_own_and_run_there(tmp_path):
    """``pliant examples`` (what a wheel's user has instead of the repository): every
    example file, links copied as files, into a new folder; never over a folder that
    holds anything; and a copied problem solves where it landed."""
    out = run("examples", str(tmp_path / "ex"))
    assert out.returncode == 0, out.stderr
    ours = sorted(p.relative_to(EXAMPLES) for p in EXAMPLES.rglob("*") if p.is_file()
                  and "__pycache__" not in p.parts)
    theirs = sorted(p.relative_to(tmp_path / "ex") for p in (tmp_path / "ex").rglob("*")
                    if p.is_file())
    assert ours == theirs
    engine = tmp_path / "ex" / "scenes" / "engine_bay.toml"
    assert not engine.is_symlink() and engine.read_text() == (
        EXAMPLES / "scenes" / "engine_bay.toml").read_text()
    again = run("examples", str(tmp_path / "ex"))
    assert again.returncode != 0 and "never writes over your files" in again.stderr
    solved = run("solve", str(tmp_path / "ex" / "paper" / "case1.toml"), "--json", "-")
    assert json.loads(solved.stdout)["loads"]["clamp"]["force"] == pytest.approx(
        [0.0, -7.0], abs=1e-9)


@pytest.mark.parametrize("command", [
    ("plan", "scenes/hose_past_post.toml"), ("sequence", "sequence/engine_bay.toml"),
    ("study", "scenes/engine_bay.toml", "--vary", "length=5mm", "--samples", "2"),
    ("run", "hoses/carry_past_post.toml"), ("demo",)])
def test_an_out_that_is_a_file_is_refused_before_any_work(tmp_path, command):
    """``--out`` naming a file, not a folder: refused at once, the option named, before
    a search whose outputs could then not be written (issue 54: a plan was lost); from
    the shell, exit status 2 and one line."""
    from pliant.errors import PliantError

    taken = tmp_path / "taken.txt"
    taken.write_text("mine")
    name, *rest = command
    scene = [str(EXAMPLES / rest[0])] if rest else []
    with pytest.raises(PliantError, match="is a file, not a folder"):
        cli(name, *scene, *rest[1:], "--out", taken)
    assert taken.read_text() == "mine"
    if name == "plan":
        done = run(name, *scene, "--out", str(taken))
        assert done.returncode == 2
        assert done.stderr.strip() == (f"error: --out {taken}: is a file, not a folder; give "
                                        "a folder for the outputs (new or existing)")
