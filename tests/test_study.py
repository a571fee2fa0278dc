"""Variation studies: parsing tolerances (and refusing bad ones), applying a sample to a
scene, the sample plan's distributions, serial against a two-worker LocalCluster,
resuming an interrupted study, failed samples kept with their error, an external
scheduler started here, and the summary and envelope."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pliant.assembly.scenes import parse_scene
from pliant.assembly.study import Store, final_voxels, study, summarize
from pliant.assembly.variation import apply, nominal_values, parse_variation, plan
from pliant.errors import InputError
from pliant.io.mesh_export import voxel_surface
from pliant.io.tomlfile import read_toml

SCENE = """
name = "hose onto a port past a block"
gravity = [0.0, 0.0, -9.81]
margin = 0.01

[part]
name = "hose"
length = 0.6
bending_stiffness = 0.08
mass_per_length = 0.2
outer_diameter = 0.012
inner_diameter = 0.008
min_bend_radius = 0.05
kind = "rubber hose"

[solver]
elements = 20

[[port]]
name = "outlet"
position = [0.0, 0.0, 0.0]
axis = [1.0, 0.0, 0.0]

[[port]]
name = "inlet"
position = [0.35, 0.2, 0.0]
axis = [0.0, -1.0, 0.0]

[[condition]]
name = "fitting"
s = 0.0
port = "outlet"
normal = [0.0, 0.0, 1.0]

[[condition]]
name = "hand"
s = 0.6
x = 0.45
y = 0.15
z = 0.0
tangent = [0.0, 1.0, 0.0]

[path]
grip = "hand"
waypoints = [[0.35, 0.2, 0.0]]
tangents = [[0.0, 1.0, 0.0]]
steps = 3

[[obstacle]]
name = "block"
shape = "box"
size = [0.1, 0.1, 0.1]
position = [0.2, -0.15, 0.0]
"""


@pytest.fixture
def scene_file(tmp_path: Path) -> Path:
    path = tmp_path / "hose.toml"
    path.write_text(SCENE)
    return path


def data() -> dict:
    return read_toml(SCENE, "hose.toml")


# -- tolerances ---------------------------------------------------------------------------
def test_tolerances_parse_with_their_units_and_distributions():
    v = parse_variation("bending_stiffness=20%", data())
    assert (v.path, v.tolerance, v.relative, v.distribution) == (
        ("part", "bending_stiffness"), pytest.approx(0.2), True, "uniform")
    v = parse_variation("length=5mm", data())
    assert v.tolerance == pytest.approx(0.005) and not v.relative
    v = parse_variation("port[inlet].position=1.5 mm,normal", data())
    assert v.path == ("port", 1, "position") and v.vector and v.distribution == "normal"
    assert v.columns == ["port[inlet].position.x", "port[inlet].position.y",
                         "port[inlet].position.z"]
    assert parse_variation("condition[hand].x=2mm", data()).path == ("condition", 1, "x")


@pytest.mark.parametrize(("spec", "message"), [
    ("stiffnes=20%", r"vary\[0\] \(stiffnes\): unknown parameter"),
    ("length=5", r"vary\[0\] \(length\): the tolerance 5 has no unit"),
    ("length=-5mm", r"vary\[0\] \(length\): the tolerance must be a positive number"),
    ("length=5 furlongs", r"unit 'furlongs' is not one for a length"),
    ("clip[0].position=2mm", r"the scene has 0 \[\[clip\]\] tables"),
    ("port[drain].position=2mm", r"no \[\[port\]\] named 'drain'; known: outlet, inlet"),
    ("port[0].position=5%", r"a position's tolerance is a length"),
    ("length=5mm,lognormal", r"unknown distribution 'lognormal'"),
    ("length", r"write NAME=TOL with a unit"),
])
def test_bad_tolerances_are_typed_errors_naming_the_argument(spec, message):
    with pytest.raises(InputError, match=message):
        parse_variation(spec, data())


def test_a_sample_changes_the_file_and_what_depends_on_it():
    doc = data()
    vs = [parse_variation(s, doc, i) for i, s in enumerate(
        ["length=5mm", "port[inlet].position=2mm", "bending_stiffness=10%"])]
    part = parse_scene(SCENE, "hose.toml").problem.part
    nominal = nominal_values(vs, doc, part)
    row = np.array([0.004, 0.001, -0.002, 0.0, -0.05])
    changed, values = apply(doc, vs, nominal, row)
    assert changed["part"]["length"] == pytest.approx(0.604)
    assert changed["condition"][1]["s"] == pytest.approx(0.604)  # the hand's end moves
    assert changed["port"][1]["position"] == pytest.approx([0.351, 0.198, 0.0])
    assert changed["path"]["waypoints"][-1] == pytest.approx([0.351, 0.198, 0.0])
    assert changed["part"]["bending_stiffness"] == pytest.approx(0.08 * 0.95)
    assert doc["part"]["length"] == 0.6  # the nominal document is untouched
    assert values["length"] == pytest.approx(0.604)


def test_the_plan_spans_the_tolerance_uniformly_or_as_three_sigma():
    doc = data()
    uniform = parse_variation("length=5mm", doc)
    normal = parse_variation("bending_stiffness=30%,normal", doc)
    x = plan([uniform, normal], 3000, "lhs", seed=7)
    assert x.shape == (3000, 2)
    # Latin hypercube: one sample in each of the 3000 strata of +- 5 mm.
    strata = np.floor((x[:, 0] / 0.005 + 1.0) / 2.0 * 3000).astype(int)
    assert sorted(strata) == list(range(3000))
    assert np.std(x[:, 1]) == pytest.approx(0.1, rel=0.02)  # 3 sigma = 30 %
    assert np.array_equal(plan([uniform], 16, "sobol", 3), plan([uniform], 16, "sobol", 3))
    assert not np.array_equal(plan([uniform], 16, "lhs", 3), plan([uniform], 16, "lhs", 4))


def test_the_swept_voxels_make_a_closed_surface():
    import trimesh

    vertices, faces = voxel_surface(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0]]), 0.01)
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    assert mesh.is_watertight and mesh.volume == pytest.approx(3 * 0.01**3)


# -- running ------------------------------------------------------------------------------
VARY = ["bending_stiffness=20%", "port[inlet].position=3mm", "length=4mm"]


def _comparable(records):
    return [{k: v for k, v in r.items() if k != "seconds"} for r in records]


def test_a_local_cluster_gives_what_the_serial_twin_gives_and_a_study_resumes(scene_file,
                                                                            tmp_path):
    serial = study(scene_file, VARY, 6, out=tmp_path / "serial", workers=0, seed=11)
    assert len(serial.ok) == 6
    cluster = study(scene_file, VARY, 6, out=tmp_path / "cluster", workers=2, seed=11,
                    batch=2)
    assert cluster.workers == 2
    assert _comparable(cluster.records) == _comparable(serial.records)
    # Interrupted after 2 samples, then run again: only the 4 missing are computed.
    seen = []

    def stop(done, total):
        seen.append(done)
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        study(scene_file, VARY, 6, out=tmp_path / "resumed", workers=0, seed=11,
              on_done=stop)
    assert len(Store(tmp_path / "resumed").records()) == 2
    # A line cut short by the interruption is dropped and its sample done again.
    with open(tmp_path / "resumed" / "samples.jsonl", "a") as handle:
        handle.write('{"index": 5, "stat')
    resumed = study(scene_file, VARY, 6, out=tmp_path / "resumed", workers=0, seed=11)
    assert resumed.computed == 4
    assert _comparable(resumed.records) == _comparable(serial.records)
    with pytest.raises(InputError, match="holds another study"):
        study(scene_file, VARY, 6, out=tmp_path / "resumed", workers=0, seed=12)


def test_a_failing_sample_is_recorded_with_its_error_and_the_rest_go_on(scene_file, tmp_path):
    # A part 40 % shorter cannot reach the port: those samples fail, typed, and are kept.
    result = study(scene_file, ["length=40%"], 8, out=tmp_path / "short", workers=0, seed=1)
    assert len(result.records) == 8
    failed = result.failed
    assert failed and all("Error" in r["error"] for r in failed)
    assert all(r["values"]["length"] < 0.6 for r in failed)
    assert result.ok  # the longer ones are evaluated
    summary = summarize(result)
    assert summary["failed"] == len(failed)
    assert summary["verdicts"]["failed to evaluate"]["count"] == len(failed)


def test_the_summary_ranks_the_parameter_that_drives_the_force(scene_file, tmp_path):
    result = study(scene_file, ["bending_stiffness=30%", "condition[hand].z=0.1mm"], 12,
                   out=tmp_path / "s", workers=0, seed=3)
    summary = summarize(result)
    top = summary["sensitivity"][0]
    assert top["parameter"] == "bending_stiffness"
    assert top["peak_force"] > 0.9  # a stiffer hose needs more force, monotonically
    p = summary["percentiles"]["peak_force"]
    forces = sorted(r["peak_force"] for r in result.ok)
    assert p["min"] == forces[0] and p["max"] == forces[-1] and p["p5"] <= p["p50"] <= p["p95"]
    swept = Store(result.folder).swept([r["index"] for r in result.ok])
    final = final_voxels(result)
    # The final pose's voxels lie inside the path's envelope.
    keys = {tuple(v) for v in swept}
    assert final.shape[0] and all(tuple(v) in keys for v in final)
    # Printed: every output with its unit (rich once read "[mm]" as markup and dropped
    # it), the sensitivity's columns named as the outputs are, the workers counted.
    from io import StringIO

    from rich.console import Console

    from pliant.cli.study_report import print_study

    console = Console(file=StringIO(), width=100)
    print_study(result, summary, console)
    text = " ".join(console.file.getvalue().split())
    for label in ("peak grip force [N]", "smallest clearance [mm]",
                  "smallest bend radius [mm]", "on this process, no workers"):
        assert label in text, label
    # Issue 54: an output the same in every sample but for round-off (a clearance varied
    # by 1e-16) crashed the report ("Too many bins"); it is drawn as one bar, said so.
    from dataclasses import replace

    from pliant.cli.study_report import render_html

    flat = replace(result, records=[dict(r, min_clearance=0.01 + k * 1e-18)
                                    for k, r in enumerate(result.records)])
    page = render_html(flat, summarize(flat), swept, final)
    assert "the same in every sample: 10" in page  # mm


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.skipif(shutil.which("dask", path=str(Path(sys.executable).parent)) is None,
                    reason="the dask command is not installed beside this Python")
def test_pliant_study_runs_on_a_scheduler_and_a_worker_started_here(scene_file, tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    dask = str(Path(sys.executable).parent / "dask")
    scheduler = subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port",
                                  str(port), "--no-dashboard"], stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
    worker = subprocess.Popen([dask, "worker", address, "--nworkers", "1", "--nthreads",
                               "1", "--no-dashboard", "--host", "127.0.0.1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(1.0)
        out = subprocess.run([sys.executable, "-m", "pliant.cli.app", "study",
                              str(scene_file), "--vary", "bending_stiffness=10%",
                              "--samples", "3", "--out", str(tmp_path / "remote"),
                              "--scheduler", address], capture_output=True, text=True,
                             timeout=300, check=False)
        assert out.returncode == 0, out.stderr
        assert "3 samples (3 computed now on 1 worker in" in out.stdout
        summary = json.loads((tmp_path / "remote" / "summary.json").read_text())
        assert summary["evaluated"] == 3
        assert (tmp_path / "remote" / "report.html").stat().st_size > 10000
        assert (tmp_path / "remote" / "envelope.glb").stat().st_size > 1000
    finally:
        for p in (worker, scheduler):
            p.terminate()
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def test_a_sample_starts_from_the_nominal_start_and_gets_the_cold_answer(scene_file):
    """Each sample's path starts from the nominal start pose (solved once per process):
    the same equilibrium as a cold start, to the solver's tolerance, the same verdict."""
    from pliant.assembly.evaluate import evaluate
    from pliant.assembly.scenes import scene_from_data
    from pliant.assembly.study import StudySpec, evaluate_samples, nominal_start

    doc = data()
    parsed = [parse_variation("bending_stiffness=20%", doc, 0),
              parse_variation("length=5mm", doc, 1)]
    nominal = nominal_values(parsed, doc, parse_scene(SCENE).problem.part)
    spec = StudySpec(doc, str(scene_file), str(scene_file.parent), tuple(parsed), nominal,
                     0.012)
    assert nominal_start(spec) is nominal_start(spec)  # solved once
    row = [0.15, -0.004]  # +15 % stiffness, 4 mm shorter (the plan's units)
    (record, _), = evaluate_samples(spec, [(0, row)])
    sample, _ = apply(doc, parsed, nominal, np.asarray(row))
    cold = evaluate(scene_from_data(sample, str(scene_file), scene_file.parent))
    assert record["status"] == "ok"
    assert record["peak_force"] == pytest.approx(cold.run.peak("force")[0], rel=1e-6)
    assert record["headline"] == cold.verdict.headline
    np.testing.assert_allclose(record["final"], cold.run.final.position, atol=1e-8)


def test_a_study_of_more_samples_than_a_machine_can_judge_is_refused_at_once():
    """Issue 54: --samples 1e9 allocated its plan and ran; the plan is bounded, and a
    study that large is refused naming the field before anything is sampled."""
    from pliant.errors import InputError

    v = [parse_variation("length=5mm", data())]
    assert plan(v, 100_000).shape == (100_000, 1)
    with pytest.raises(InputError, match="samples: must be 1 to 100,000"):
        plan(v, 100_001)
    with pytest.raises(InputError, match="samples"):
        plan(v, 0)


def test_a_relative_tolerance_of_a_hundred_percent_or_more_is_refused():
    """Issue 54: --vary bending_stiffness=100% took the stiffness to zero and below."""
    from pliant.errors import InputError

    with pytest.raises(InputError, match="less than 100 %"):
        parse_variation("bending_stiffness=100%", data())
    assert parse_variation("bending_stiffness=99%", data()).tolerance == pytest.approx(0.99)


def test_a_second_study_in_a_folder_in_use_is_refused_naming_it(scene_file, tmp_path):
    """Issue 54: two studies in one folder each computed every sample beside the other.
    A folder held by a running study (its lock, as a study takes it) refuses a second
    before anything is sampled, naming the folder and the holder's process; once the
    first ends the folder is free again, and a lock left by a process that died is no
    lock (the kernel drops it with the process)."""
    import os
    import subprocess
    import sys

    from pliant.errors import InputError
    from pliant.io.folder_lock import FolderLock

    out = tmp_path / "busy"
    with FolderLock(out, "study"):
        with pytest.raises(InputError, match=f"in use by another study \\(process "
                                             f"{os.getpid()}\\)"):
            study(scene_file, VARY, 2, out=out, workers=0)
        assert not (out / "samples.jsonl").exists()
    with FolderLock(out, "study"):  # free again
        pass
    died = subprocess.run([sys.executable, "-c", (
        "import os; from pliant.io.folder_lock import FolderLock; "
        f"FolderLock({str(out)!r}, 'study').acquire(); os._exit(0)")], timeout=120)
    assert died.returncode == 0
    with FolderLock(out, "study"):
        pass


def test_a_study_whose_every_sample_fails_still_writes_its_report(tmp_path):
    """Issue 54: a study whose every sample failed crashed at its last step ("Can't export
    empty scenes!") and wrote no report. The hand 0.1 mm short of the part's length from
    its fitting, straight out, and varied across: both samples of seed 0 (y 36 and
    -27 mm) put it beyond the part's reach, so every sample fails, typed; the summary
    and the report are written, the envelope is said to be missing, not crashed on."""
    from .helpers import cli

    short = tmp_path / "short.toml"
    short.write_text(SCENE.replace("x = 0.45\ny = 0.15", "x = 0.5999\ny = 0.0", 1))
    out = tmp_path / "study"
    done = cli("study", short, "--vary", "condition[hand].y=100mm", "--samples", "2",
               "--workers", "0", "--seed", "0", "--out", out)
    assert done.returncode == 0, done.stdout
    records = [json.loads(line) for line in (out / "samples.jsonl").read_text().splitlines()]
    assert len(records) == 2 and all(r["status"] != "ok" for r in records)
    assert all("reaches or exceeds" in r["error"] for r in records)
    assert "no envelope written: no sample was evaluated" in " ".join(done.stdout.split())
    assert not (out / "envelope.glb").exists()
    assert (out / "report.html").stat().st_size > 1000
    assert json.loads((out / "summary.json").read_text())["failed"] == 2


def _sleep_then_write(path: str) -> str:
    time.sleep(3.0)
    Path(path).write_text("finished")
    return path


def test_ctrl_c_stops_a_local_clusters_workers_instead_of_waiting_for_them(tmp_path):
    """Ctrl+C during a distributed search: the local cluster's workers are killed, not
    asked to finish what they are solving (which made closing take 4 s a study: a
    sample's solve). A task that writes a file after 3 s never writes it, and its worker
    process is gone when the block exits; the interrupt goes on up."""
    import os

    from pliant.assembly.cluster import dask_client

    marker = tmp_path / "finished.txt"
    pids = []
    with pytest.raises(KeyboardInterrupt):
        with dask_client(None, 1) as client:
            future = client.submit(_sleep_then_write, str(marker), pure=False)
            pids = list(client.run(os.getpid).values())
            while not any(client.processing().values()):
                time.sleep(0.01)
            assert future.status == "pending"  # (held: a future dropped is cancelled)
            raise KeyboardInterrupt
    time.sleep(4.0)  # past when the task would have written its file
    assert not marker.exists()
    assert pids
    for pid in pids:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)
