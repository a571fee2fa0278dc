"""The coupling layer: frames at once, drift-triggered accurate solves that retune the
network, deterministic replays, recordings, and a live frame loop that an accurate
solve does not block."""

from __future__ import annotations

import time

import numpy as np
import pytest

import pliant as pl
from pliant.core.equilibrium import Result
from pliant.errors import FileFormatError, InputError, PliantError, UnreachableTargetError
from pliant.session import GripEvent, Session, replay
from pliant.session.recording import load_recording, save_recording

from .helpers import EXAMPLES

HOSE = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3, outer_diameter=0.02)
PROBLEM_3D = pl.Problem(HOSE, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                               pl.pin(1.0, position=(0.9, 0.0, 0.0), name="hand")),
                        gravity=(0.0, 0.0, -9.81))
PROBLEM_2D = pl.Problem(HOSE, (pl.clamp(0.0), pl.pin(1.0, position=(0.9, 0.0), name="hand")),
                        gravity=(0.0, -9.81))


def carried(dimension: int, steps: int) -> list[GripEvent]:
    """A hand carrying the end from (0.9, 0, 0) to (0.55, 0.3, 0.2) (2D: (0.55, 0.3))."""
    return [GripEvent("hand", position=(0.9 - 0.35 * t, 0.3 * t, 0.2 * t)[:dimension])
            for t in np.linspace(1.0 / steps, 1.0, steps)]


@pytest.mark.parametrize("problem", [PROBLEM_2D, PROBLEM_3D], ids=["2D", "3D"])
def test_replay_is_deterministic_and_publishes_real_forces(problem):
    """A replayed manipulation gives the same frames and the same accurate solves every
    run; every accurate solve answers the pose of the event that triggered it, with the
    forces a direct solve of that pose gives; inline, no frame is ever farther from its
    accurate shape than the drift tolerance."""
    events = carried(problem.dimension, 40)
    first = replay(problem, events, control_points=30)
    second = replay(problem, events, control_points=30)
    assert len(first) == len(second) == 40
    for a, b in zip(first, second):
        assert np.array_equal(a.realtime.curve, b.realtime.curve)
        assert np.array_equal(a.realtime.vertices, b.realtime.vertices)
        assert a.solved == b.solved and a.accurate.index == b.accurate.index
        assert np.array_equal(a.accurate.reactions["hand"].force,
                              b.accurate.reactions["hand"].force)
    triggered = [f for f in first if f.solved]
    assert 3 <= len(triggered) < 40  # the network carries the frames in between
    for frame in triggered:
        assert frame.accurate.index == frame.index
    for frame in first:
        assert frame.drift.distance_to_accurate <= 0.02
        assert frame.drift.length_error < 1e-6
    last = triggered[-1].accurate
    direct = pl.solve(last.problem)
    assert np.allclose(last.reactions["hand"].force, direct.reactions["hand"].force,
                       rtol=1e-6, atol=1e-9)
    # the same answer as the direct solve's in both models, its stability included (a
    # 2D session had none), through the one interface both equilibria give
    assert isinstance(direct, Result)
    assert last.stable is direct.stable is True
    assert last.smallest_eigenvalue == pytest.approx(direct.stability[1], rel=1e-6)
    assert np.allclose(last.bending_moment, direct.bending_magnitude, rtol=1e-6, atol=1e-9)


def test_drift_tolerance_and_requests_set_when_to_solve():
    events = carried(2, 30)
    loose = replay(PROBLEM_2D, events, control_points=20, distance_tolerance=0.05)
    tight = replay(PROBLEM_2D, events, control_points=20, distance_tolerance=0.01)
    assert sum(f.solved for f in loose) < sum(f.solved for f in tight)
    with Session(PROBLEM_2D, control_points=20, distance_tolerance=10.0) as session:
        quiet = session.apply(events[0])
        assert not quiet.solved and quiet.accurate.index == 0
        session.request_accurate()
        asked = session.apply(events[1])
        assert asked.solved and asked.accurate.index == 2


def test_bad_events_are_typed_and_leave_the_session_usable():
    with Session(PROBLEM_3D, control_points=20) as session:
        with pytest.raises(InputError, match="no condition is named 'foot'"):
            session.apply(GripEvent("foot", position=(0.5, 0.0, 0.0)))
        with pytest.raises(UnreachableTargetError):
            session.apply(GripEvent("hand", position=(2.0, 0.0, 0.0)))
        frame = session.apply(GripEvent("hand", position=(0.85, 0.05, 0.0)))
        assert frame.index == 1 and frame.realtime.converged
        assert np.allclose(frame.realtime.curve[-1], (0.85, 0.05, 0.0), atol=1e-12)


def test_recordings_round_trip_and_reject_bad_files(tmp_path):
    events = [GripEvent("hand", position=(0.8, 0.1, 0.05), t=0.5),
              GripEvent("hand", position=(0.7, 0.2, 0.1), tangent=(0.0, 1.0, 0.0), t=1.0)]
    path = save_recording(tmp_path / "take.json", PROBLEM_3D, events)
    problem, loaded = load_recording(path)
    assert loaded == events
    assert problem.conditions == PROBLEM_3D.conditions and problem.gravity == PROBLEM_3D.gravity
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "pliant-recording", "version": 1, "problem": "", '
                   '"events": [{"grip": "hand", "t": -1}]}')
    with pytest.raises(FileFormatError, match=r"bad.json: events.0.t"):
        load_recording(bad)
    bad.write_text("not json")
    with pytest.raises(FileFormatError, match="not valid JSON"):
        load_recording(bad)


@pytest.mark.serial  # timed against a worker process: alone, not beside the parallel suite
def test_live_frames_are_not_blocked_by_accurate_solves():
    """Live, the accurate model runs in a worker process: with every accurate solve
    taking tens of milliseconds (3D, 400 elements) and one almost always running, no
    frame waits for one (frame times measured by the session's own clock). A frame that
    waited would take about half a solve or more, and so would most of them: the median
    is judged, not the slowest frames, which the operating system's descheduling of this
    process stretches on a loaded 2-core machine (the suite runs two test processes
    beside the solver's worker)."""
    events = carried(3, 300)
    with Session(PROBLEM_3D, live=True, elements=400, control_points=30) as session:
        frames = [session.apply(event) for event in events]
        session.wait(timeout=60.0)
        final = session.poll()
    solves = [r for r in session.solves[1:] if r.ok]
    assert len(solves) >= 3
    fastest_solve = min(r.solve_seconds for r in solves)
    overlapped = [f for f in frames if f.pending]
    assert len(overlapped) > len(frames) / 2
    assert np.median([f.seconds for f in overlapped]) < 0.25 * fastest_solve
    assert final.accurate.index > frames[len(frames) // 2].index


def test_the_worker_sends_results_back_without_the_scene():
    """A live result comes back from the worker process without its problem (a scene's
    obstacle grids: about a megabyte a solve, kept for every solve); the session puts
    back the problem it sent, the very object."""
    import pickle
    from dataclasses import replace

    from pliant.assembly.scenes import load_scene
    from pliant.session.accurate import ProcessExecutor

    problem = load_scene(EXAMPLES / "scenes" / "engine_bay.toml").problem
    executor = ProcessExecutor(elements=30)
    try:
        executor.submit(7, problem)
        result = executor.wait(timeout=240)
    finally:
        executor.close()
    assert result is not None and result.ok and result.index == 7
    assert result.problem is problem
    sent = len(pickle.dumps(replace(result, problem=None)))
    assert sent < 100_000 < len(pickle.dumps(result))


def test_the_worker_is_sent_the_scenes_obstacles_once(monkeypatch):
    """A request carries the obstacles only when they change (a CAD scene's are hundreds
    of megabytes a solve otherwise); the answers are those of the solver in-process, and
    a new set of obstacles is sent again."""
    import pickle
    from dataclasses import replace

    from pliant.assembly.scenes import load_scene
    from pliant.session import accurate
    from pliant.session.accurate import AccurateSolver, ProcessExecutor

    problem = load_scene(EXAMPLES / "scenes" / "engine_bay.toml").problem
    moved = problem.with_conditions(
        replace(c, position=tuple(x + 0.01 for x in c.position)) if c.name == "hand" else c
        for c in problem.conditions)
    sizes: list[int] = []
    write = accurate.write_message
    monkeypatch.setattr(accurate, "write_message",
                        lambda stream, m: (sizes.append(len(pickle.dumps(m))), write(stream, m)))
    executor = ProcessExecutor(elements=30)
    try:
        answers = []
        for k, p in enumerate((problem, moved, load_scene(EXAMPLES / "scenes" /
                                                           "engine_bay.toml").problem)):
            executor.submit(k, p)
            answers.append(executor.wait(timeout=240))
    finally:
        executor.close()
    assert sizes[1] < 20_000 < 1_000_000 < sizes[0]  # the second without its obstacles
    assert sizes[2] > 1_000_000  # new obstacle objects: sent again
    inline = AccurateSolver(elements=30)
    for k, p in enumerate((problem, moved)):
        here = inline.solve(k, p)
        assert answers[k].ok and answers[k].problem is p
        assert np.allclose(answers[k].position, here.position, atol=1e-9)
        assert answers[k].contacts is not None or here.contacts is None


def test_a_worker_that_dies_is_started_again_and_the_pose_solved():
    """A killed worker (the OOM killer, a user's kill) is replaced and the request in
    flight sent to the new one: the session answers, it does not end. Closing while a
    solve runs stops the worker at once."""
    import os
    import signal
    import time

    from pliant.session.accurate import AccurateSolver, ProcessExecutor

    executor = ProcessExecutor(elements=30)
    try:
        first = executor.pid
        executor.submit(1, PROBLEM_3D)
        os.kill(first, signal.SIGKILL)
        result = executor.wait(timeout=240)
        assert result is not None and result.ok and result.index == 1
        assert executor.restarts == 1 and executor.pid != first
        here = AccurateSolver(elements=30).solve(1, PROBLEM_3D)
        assert np.allclose(result.position, here.position, atol=1e-9)
        executor.submit(2, PROBLEM_3D)  # the new worker goes on serving
        assert executor.wait(timeout=240).ok
        executor.submit(3, PROBLEM_3D)
        worker = executor.pid
        started = time.monotonic()
    finally:
        executor.close()
    assert time.monotonic() - started < 5.0
    with pytest.raises(ProcessLookupError):
        os.kill(worker, 0)  # gone (and reaped)


def test_a_worker_stopped_mid_solve_is_replaced_and_the_pose_solved(monkeypatch):
    """A worker stopped while it solves (SIGSTOP, Ctrl+Z on it, a debugger) answers
    nothing and never dies: after ``STOPPED_GRACE`` the watchdog kills it, a new one
    takes the request, and the answer is the inline solver's. A stopped worker with
    nothing to do is left alone."""
    import os
    import signal

    from pliant.session import accurate
    from pliant.session.accurate import AccurateSolver, ProcessExecutor, stopped

    monkeypatch.setattr(accurate, "STOPPED_GRACE", 1.0)  # (3 s in use)
    executor = ProcessExecutor(elements=30)
    try:
        idle = executor.pid
        os.kill(idle, signal.SIGSTOP)
        time.sleep(2.5)
        assert stopped(idle) and executor.pid == idle and executor.stopped_replaced == 0
        os.kill(idle, signal.SIGCONT)
        executor.submit(1, PROBLEM_3D)
        os.kill(idle, signal.SIGSTOP)
        result = executor.wait(timeout=240)
        assert result is not None and result.ok and result.index == 1
        assert executor.stopped_replaced == 1 and executor.restarts == 1
        assert executor.pid != idle and not stopped(executor.pid)
        here = AccurateSolver(elements=30).solve(1, PROBLEM_3D)
        assert np.allclose(result.position, here.position, atol=1e-9)
    finally:
        executor.close()
    with pytest.raises(ProcessLookupError):
        os.kill(idle, 0)  # killed and reaped


def test_a_recording_of_a_scene_keeps_its_obstacles(tmp_path):
    """The engine bay (boxes, cylinders, a manifold mesh) recorded and read back: the
    same obstacles, the mesh beside the recording, the same clearances (they used to be
    dropped, so a replay ran through the engine)."""
    from pliant.assembly.scenes import load_scene
    from pliant.scene.distance import DistanceField

    problem = load_scene(EXAMPLES / "scenes" / "engine_bay.toml").problem
    path = save_recording(tmp_path / "take.json", problem, [])
    again, _ = load_recording(path)
    assert [o.name for o in again.obstacles] == [o.name for o in problem.obstacles]
    assert any((tmp_path / "take-meshes").glob("*.obj"))
    points = np.random.default_rng(4).uniform(-0.2, 0.8, (300, 3))
    before = DistanceField(list(problem.obstacles)).query(points, band=0.05)[0]
    after = DistanceField(list(again.obstacles)).query(points, band=0.05)[0]
    assert np.abs(before - after).max() < 1e-12


# A tip held at (0.333, -0.002) with its tangent at -1.106 rad: two stable equilibria, the
# part bowing to the left of the chord (20.9 J) or to the right (45.1 J).
TWO_SHAPES = pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.grip(
    1.0, (0.333, -0.002), angle=-1.106, name="hand")))


def test_a_session_lists_the_poses_equilibria_and_follows_the_one_chosen():
    """Asked, a session lists its pose's equilibria as ``pliant.models.dispatch.
    equilibria`` finds them (best first, energies and verdicts alike), each holding the
    grip's target; the one chosen becomes the accurate answer and the next warm start,
    so a small move of the grip stays on that branch (the higher one, bowing right),
    where a fresh session's answer bows left. Once the grip has moved, the list is
    stale and choosing from it is a typed error naming the option."""
    from pliant.core.equilibrium import bow_side, potential_energy
    from pliant.models import dispatch

    expected = dispatch.equilibria(TWO_SHAPES)
    with Session(TWO_SHAPES) as session:
        session.find_equilibria(budget=5.0)
        session.poll()
        found = session.found
        assert found is not None and found.ok
        assert [o.potential_energy for o in found.options] == pytest.approx(
            [potential_energy(eq) for eq in expected], rel=1e-9)
        assert [o.verdict for o in found.options] == [eq.verdict for eq in expected]
        assert [o.bows for o in found.options][:2] == ["left", "right"]
        for option in found.options:
            assert np.abs(option.position[-1] - (0.333, -0.002)).max() < 1e-8
        assert found.options[0].potential_energy < found.options[1].potential_energy
        session.choose(1)
        session.poll()
        chosen = found.options[1]
        assert np.abs(session.accurate.position - chosen.position).max() < 1e-12
        session.apply(GripEvent("hand", position=(0.34, 0.0)))
        session.request_accurate()
        session.poll()
        assert session.accurate.ok and session.accurate.index == session.index
        assert bow_side(session.accurate) == "right"
        assert session.found is None
        with pytest.raises(InputError, match="option"):
            session.choose(0)
        with pytest.raises(InputError, match="budget"):
            session.find_equilibria(budget=0.0)
    moved = TWO_SHAPES.with_conditions(
        [TWO_SHAPES.conditions[0], pl.grip(1.0, (0.34, 0.0), angle=-1.106, name="hand")])
    with Session(moved) as fresh:
        assert bow_side(fresh.accurate) == "left"


def test_a_live_session_finds_and_chooses_through_its_worker():
    """The same search and choice through the worker process (its request protocol)."""
    with Session(TWO_SHAPES, live=True) as session:
        session.find_equilibria(budget=5.0)
        session.poll()  # a frame: the answer may already be in, and taken in here
        found = session.wait(timeout=60.0) or session.found
        assert found is not None and found.ok and len(found.options) >= 2
        assert session.found is found
        session.choose(1)
        session.poll()
        chosen = session.wait(timeout=60.0) or session.accurate
        assert chosen is not None and chosen.ok
        assert np.abs(chosen.position - found.options[1].position).max() < 1e-12


def test_grip_rules_below_the_interfaces():
    """``pliant.session.grips``: how each condition is driven, the event a held grip's
    pose makes (a 2D angle from the tangent), the pose a grip switched back to holding
    takes (the answer's point and direction at its station, a repeated station counted
    once), and the typed errors for a zero tangent or no answer yet."""
    from pliant.session import grips

    clamp = pl.clamp(0.0, position=(0, 0, 0), tangent=(1, 0, 0), normal=(0, 0, 1))
    hand = pl.pin(1.0, position=(0.9, 0.0, 0.0), name="hand")
    push = pl.push(1.0, force=(0.0, 0.0, -1.0), name="tip")
    assert [grips.grip_mode(c) for c in (clamp, hand, push)] == ["fixed", "position", "force"]
    assert grips.grip_mode(hand, fixed=("hand",)) == "fixed"
    turned = pl.grip(1.0, (0.5, 0.2), angle=0.0, name="hand")
    event = grips.pose_event(turned, (0.4, 0.3, 0.0), (0.0, 2.0, 0.0), 2)
    assert event.position == (0.4, 0.3) and event.angle == pytest.approx(np.pi / 2)
    with pytest.raises(InputError, match="tangent"):
        grips.pose_event(pl.grip(1.0, (0.9, 0, 0), tangent=(1, 0, 0), name="h"),
                         (0.9, 0.0, 0.0), (0.0, 0.0, 0.0), 3)
    with pytest.raises(PliantError, match="hand: no accurate shape"):
        grips.held(hand, hand, None, 3)
    s = np.array([0.0, 0.5, 0.5, 1.0])
    line = np.array([[0.0, 0.0, 0.0], [0.3, 0.4, 0.0], [0.3, 0.4, 0.0], [0.6, 0.8, 0.0]])
    point, tangent = grips.point_at(s, line, 0.75)
    np.testing.assert_allclose(point, [0.45, 0.6, 0.0], atol=1e-12)
    np.testing.assert_allclose(tangent, [0.6, 0.8, 0.0], atol=1e-12)


def test_a_long_session_keeps_its_last_results_and_counts_them_all():
    """Issue 54: the viewer kept every accurate solve of a sitting (31 KB each: 2,000
    solves took it from 290 to 351 MB). A session keeps the last KEPT and counts them
    all; the latest is the one it publishes, and a reader that has taken the first n
    gets exactly the ones after (those still kept)."""
    from pliant.session.session import KEPT, Kept

    kept = Kept(3)
    for k in range(5):
        kept.append(k)
    assert list(kept) == [2, 3, 4] and kept.total == 5 and kept[-1] == 4 and kept[1:] == [3, 4]
    assert kept.since(4) == [4] and kept.since(0) == [2, 3, 4] and kept.since(5) == []
    events = carried(2, KEPT + 10)
    with Session(PROBLEM_2D, control_points=20) as session:
        for event in events:
            session.request_accurate()
            session.apply(event)
        assert session.solves.total == KEPT + 11  # the start's, then one a move
        assert len(session.solves) == KEPT
        assert session.solves[-1].index == session.index == session.accurate.index
