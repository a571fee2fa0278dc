"""The browser environment's server side: the protocol, one tab's session state, and the
server (files it serves or refuses, bad messages, two users at once). The page itself is
tested in a real browser in test_browser.py."""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pliant.assembly.scenes import load_scene
from pliant.core.conditions import Condition
from pliant.errors import InputError, PliantError
from pliant.session.accurate import AccurateSolver
from pliant.viewer import protocol as P
from pliant.viewer.protocol import ProtocolError
from pliant.viewer.state import ViewerState

SCENE = """
name = "hose by a drum"
gravity = [0.0, 0.0, -9.81]
margin = 0.02

[part]
name = "rubber hose 20/12"
length = 1.0
outer_diameter = 0.020
inner_diameter = 0.012
bending_stiffness = 0.05
torsional_stiffness = 0.035
mass_per_length = 0.30
min_bend_radius = 0.08

[solver]
elements = 30

[[condition]]
name = "connector"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]

[[condition]]
name = "hand"
s = 1.0
x = 0.55
y = 0.35
z = 0.15
tangent = [0.0, 1.0, 0.0]

[[obstacle]]
name = "drum"
shape = "sphere"
radius = 0.05
position = [0.3, -0.3, 0.0]
"""


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "hose.toml").write_text(SCENE)
    return tmp_path


@pytest.fixture
def state(folder: Path):
    viewer = ViewerState(Path("hose.toml"), folder, live=False)
    yield viewer
    viewer.close()


def msg(**fields) -> object:
    return P.parse(json.dumps({"v": 1, **fields}))


def by_type(replies, kind):
    return [r for r in replies if r.type == kind]


def hand_load(accurate: P.ServerAccurate) -> P.Load:
    return next(load for load in accurate.loads if load.name == "hand")


def solve_at(folder: Path, position, tangent) -> object:
    """The Python API's answer for the hand at a pose (warm-started from the start pose,
    as the session is)."""
    problem = load_scene(folder / "hose.toml").problem
    solver = AccurateSolver(elements=30)
    solver.solve(0, problem)
    moved = problem.with_conditions(
        Condition(s=c.s, name=c.name, position=tuple(position), tangent=tuple(tangent))
        if c.name == "hand" else c for c in problem.conditions)
    return solver.solve(1, moved)


# -- the protocol ----------------------------------------------------------------------------
def test_parse_names_what_is_wrong():
    assert isinstance(msg(type="hello"), P.ClientHello)
    move = msg(type="move", grip="hand", position=[0.1, 0.2, 0.3], seq=4)
    assert move.position == (0.1, 0.2, 0.3) and move.seq == 4
    cases = [
        ("{", "message"),                                                    # not JSON
        ("[1, 2]", "message"),                                               # not an object
        ('{"v": 2, "type": "hello"}', "v"),                                  # other version
        ('{"v": 1, "type": "jump"}', "type"),                                # unknown type
        ('{"v": 1, "type": "move", "grip": "hand", "position": [1, 2]}', "position"),
        ('{"v": 1, "type": "move", "grip": "hand", "position": [1, 2, NaN]}', "position"),
        ('{"v": 1, "type": "save", "name": "../escape"}', "name"),
        ('{"v": 1, "type": "hello", "extra": 1}', "extra"),
    ]
    for raw, field in cases:
        with pytest.raises(ProtocolError) as err:
            P.parse(raw)
        assert field in (err.value.field or ""), (raw, err.value.field, str(err.value))
    big = json.dumps({"v": 1, "type": "hello", "pad": "x" * P.MAX_MESSAGE})
    with pytest.raises(ProtocolError, match="limit"):
        P.parse(big)


JSONS = st.recursive(st.none() | st.booleans() | st.floats() | st.integers()
                     | st.text(max_size=20),
                     lambda inner: st.lists(inner, max_size=5)
                     | st.dictionaries(st.text(max_size=10), inner, max_size=5), max_leaves=20)
KEYS = st.sampled_from(["v", "type", "grip", "position", "tangent", "seq", "mode", "force",
                        "moment", "name", "budget", "option"])
FIELDS = st.dictionaries(KEYS, JSONS | st.sampled_from(
    [1, "hello", "move", "mode", "solve", "save", "load", "equilibria", "choose", "hand",
     "force", "position"])
    | st.lists(st.floats(-2, 2), min_size=3, max_size=3), max_size=7)


@settings(max_examples=300, deadline=None)
@given(raw=st.text(max_size=200) | st.binary(max_size=200) | JSONS.map(json.dumps)
       | FIELDS.map(json.dumps))
def test_parse_takes_or_refuses_anything(raw):
    """Random text, bytes and JSON: a message or a ProtocolError, nothing else."""
    try:
        message = P.parse(raw)
    except ProtocolError as err:
        assert str(err)
    else:
        assert message.v == P.VERSION


def test_the_pages_protocol_module_is_made_from_the_python_protocol():
    """``static/protocol.js`` is what ``protocol.javascript()`` makes from the pydantic
    models (run ``python -m pliant.viewer.protocol`` after changing one), and it names
    every client and server message type with its fields."""
    assert P.JAVASCRIPT.read_text(encoding="utf-8") == P.javascript()
    text = P.javascript()
    for kind in P.TYPES:
        assert f'"{kind}": [' in text
    for model in P.SERVER_MESSAGES:
        assert f'"{model.model_fields["type"].default}": [' in text
    assert '"move": [\n    "grip",\n    "position",\n    "tangent",\n    "seq"\n  ]' in text


def _unknown_reads(code: dict[str, str]) -> list[tuple[str, str]]:
    """(message or variable, field) for each field the page reads from a server message
    that its pydantic model does not have: ``msg.X`` in the handler the page calls for
    each message type, and ``X`` read from the ones it keeps (``state.accurate.X``, ...).
    Top-level fields (a nested one is a model of its own)."""
    import re

    fields = {m.model_fields["type"].default: set(m.model_fields) for m in P.SERVER_MESSAGES}

    def body(text: str, header: str) -> str:
        start = text.index("{", text.index(header))
        depth = 0
        for k in range(start, len(text)):
            depth += {"{": 1, "}": -1}.get(text[k], 0)
            if depth == 0:
                return text[start:k + 1]
        raise AssertionError(f"no end to {header}")

    app = code["app.js"]
    bad = []
    dispatch = re.findall(r"msg\.type === '(\w+)'\)\s*(?:\{\s*)?(?:(on\w+)\(msg\))?([^\n]*)", app)
    assert {kind for kind, _, _ in dispatch} == set(fields), "a message type the page ignores"
    for kind, handler, rest in dispatch:
        reads = set(re.findall(r"\bmsg\??\.(\w+)", rest))
        if handler:
            where = next(t for t in code.values() if f"function {handler}(msg)" in t)
            reads |= set(re.findall(r"\bmsg\??\.(\w+)", body(where, f"function {handler}(msg)")))
        bad += [(kind, f) for f in reads - fields[kind] - {"type"}]
    if "'error'" in app:  # its handler spans lines
        error = body(app, "msg.type === 'error')")
        bad += [("error", f) for f in set(re.findall(r"\bmsg\??\.(\w+)", error))
                - fields["error"]]
    for name, kind in (("accurate", "accurate"), ("failed", "accurate"), ("frame", "frame"),
                       ("scene", "scene"), ("equilibria", "equilibria")):
        for text in code.values():
            bad += [(f"state.{name}", f) for f in set(re.findall(
                rf"\bstate\.{name}\??\.(\w+)", text)) - fields[kind]]
    return sorted(set(bad))


def test_every_field_the_page_reads_is_in_the_protocol():
    """The page (plain JavaScript) reads each server message's fields by name; one that
    the protocol lacks reads as undefined, and its text never appears (the page once
    read ``smallest_eigenvalue`` from a message without it). None does now; a read of a
    missing field, put into the accurate message's handler, is found."""
    static = P.JAVASCRIPT.parent
    code = {p.name: p.read_text(encoding="utf-8") for p in static.glob("*.js")}
    assert _unknown_reads(code) == []
    broken = dict(code, **{"app.js": code["app.js"].replace(
        "function onAccurate(msg) {", "function onAccurate(msg) {\n  msg.no_such_field;", 1)})
    broken["view.js"] = broken["view.js"] + "\nstate.frame.nor_this;\n"
    assert _unknown_reads(broken) == [("accurate", "no_such_field"), ("state.frame", "nor_this")]


# -- one tab's session -----------------------------------------------------------------------
def test_hello_gives_the_scene_and_the_api_forces(state, folder):
    replies = state.handle(msg(type="hello"))
    scene = by_type(replies, "scene")[0]
    assert [(g.name, g.mode) for g in scene.grips] == [("connector", "fixed"),
                                                       ("hand", "position")]
    assert [o.name for o in scene.obstacles] == ["drum"]
    vertices = np.array(scene.obstacles[0].vertices)
    assert np.allclose(np.linalg.norm(vertices - [0.3, -0.3, 0.0], axis=1), 0.05, atol=1e-6)
    accurate = by_type(replies, "accurate")[0]
    api = AccurateSolver(elements=30).solve(0, load_scene(folder / "hose.toml").problem)
    np.testing.assert_allclose(hand_load(accurate).force, api.loads["hand"].force, rtol=1e-12)
    np.testing.assert_allclose(hand_load(accurate).moment, api.loads["hand"].moment,
                               rtol=1e-12, atol=1e-15)
    # The clearance to the drum, against its closed form along the shape.
    position = np.array(accurate.position)
    gap = np.linalg.norm(position - [0.3, -0.3, 0.0], axis=1) - 0.05 - 0.01
    drum = next(c for c in accurate.interference.clearances if c.obstacle == "drum")
    assert drum.clearance == pytest.approx(gap.min(), abs=2e-3)
    assert json.loads(P.dump(accurate))["type"] == "accurate"


def test_a_move_returns_the_frame_and_the_accurate_forces_follow(state, folder):
    state.handle(msg(type="hello"))
    target, tangent = [0.6, 0.3, 0.2], [0.0, 0.8, 0.6]
    frame = state.handle(msg(type="move", grip="hand", position=target, tangent=tangent,
                             seq=7))[0]
    assert frame.type == "frame" and frame.seq == 7
    # The network holds the grip exactly: the curve's end is the target.
    np.testing.assert_allclose(frame.curve[-1], target, atol=1e-9)
    assert len(frame.curvature) == len(frame.s) == len(frame.curve)
    replies = state.handle(msg(type="solve"))
    accurate = by_type(replies, "accurate")[-1]
    assert accurate.ok and accurate.index == frame.index
    api = solve_at(state.root, target, np.array(tangent) / np.linalg.norm(tangent))
    np.testing.assert_allclose(hand_load(accurate).force, api.loads["hand"].force,
                               rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(accurate.position[-1], target, atol=1e-9)


def test_a_grip_switched_to_force_keeps_its_shape_and_back(state):
    state.handle(msg(type="hello"))
    held = state.accurate_message()
    replies = state.handle(msg(type="mode", grip="hand", mode="force"))
    pushed = by_type(replies, "accurate")[-1]
    assert pushed.ok, pushed.error
    grip = next(g for g in by_type(replies, "scene")[-1].grips if g.name == "hand")
    assert grip.mode == "force"
    np.testing.assert_allclose(grip.force, hand_load(held).force, rtol=1e-12)
    # Pushing with the force the hand gave holds the same shape.
    np.testing.assert_allclose(pushed.position, held.position, atol=1e-6)
    assert not any(hand_load(pushed).prescribed[:3])
    # A pushed grip is not dragged.
    with pytest.raises(ProtocolError, match="force"):
        state.handle(msg(type="move", grip="hand", position=[0.5, 0.3, 0.1]))
    # A larger upward push lifts the end.
    force = list(np.array(grip.force) + [0.0, 0.0, 0.5])
    replies = state.handle(msg(type="mode", grip="hand", mode="force", force=force,
                               moment=grip.moment))
    lifted = by_type(replies, "accurate")[-1]
    assert lifted.ok and lifted.position[-1][2] > held.position[-1][2] + 1e-3
    # Back to holding by position: the hand holds the end where it now is.
    replies = state.handle(msg(type="mode", grip="hand", mode="position"))
    grip = next(g for g in by_type(replies, "scene")[-1].grips if g.name == "hand")
    assert grip.mode == "position"
    np.testing.assert_allclose(grip.position, lifted.position[-1], atol=1e-9)


def test_the_page_lists_the_poses_equilibria_and_takes_the_one_chosen(state):
    """``equilibria`` answers with the pose's equilibria as the session found them (best
    first, each ending at the hand's target); ``choose`` makes one the accurate answer
    the page shows; a choice out of range, or after the hand moved, is a typed error
    naming the option."""
    replies = state.handle(msg(type="equilibria", budget=10.0))
    (found,) = by_type(replies, "equilibria")
    assert found.ok and found.current and found.options
    options = state.session.found.options
    assert len(found.options) == len(options)
    for sent, option in zip(found.options, options):
        assert sent.potential_energy == option.potential_energy
        assert np.abs(np.array(sent.position) - option.position).max() == 0.0
        assert np.abs(np.array(sent.position[-1]) - (0.55, 0.35, 0.15)).max() < 1e-8
    stable = [o.potential_energy for o in found.options if o.verdict != "unstable"]
    assert stable == sorted(stable)
    last = len(found.options) - 1
    (accurate,) = by_type(state.handle(msg(type="choose", option=last)), "accurate")
    assert accurate.ok
    assert np.abs(np.array(accurate.position) - options[last].position).max() < 1e-12
    with pytest.raises(InputError, match="option"):
        state.handle(msg(type="choose", option=last + 1))
    state.handle(msg(type="move", grip="hand", position=[0.5, 0.35, 0.15]))
    with pytest.raises(InputError, match="option"):
        state.handle(msg(type="choose", option=0))
    with pytest.raises(ProtocolError, match="budget"):
        msg(type="equilibria", budget=1e9)


def test_the_page_lists_the_equilibria_of_parts_solved_together(tmp_path, monkeypatch):
    """A scene whose part rests on a fitted hose: *Other shapes* lists the cable on the
    hose (solved together, stable) and the free arch (unstable), ranked by the energy of
    both parts, and *Use* takes the arch, fitted part and all."""
    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    examples = Path(__file__).resolve().parents[1] / "examples" / "scenes"
    viewer = ViewerState(Path("cable_on_fitted_hose.toml"), examples, live=False)
    try:
        (found,) = by_type(viewer.handle(msg(type="equilibria", budget=20.0)), "equilibria")
        assert found.ok and [o.verdict for o in found.options][:2] == ["stable", "unstable"]
        assert found.options[0].potential_energy < found.options[1].potential_energy
        assert any("solved together with hose" in n for n in found.options[0].notes)
        (accurate,) = by_type(viewer.handle(msg(type="choose", option=1)), "accurate")
        assert accurate.ok and np.array(accurate.position)[20, 2] > 0.05  # the arch
    finally:
        viewer.close()


def test_sessions_are_saved_atomically_and_loaded_back(state, folder):
    state.handle(msg(type="hello"))
    target = [0.5, 0.4, 0.25]
    state.handle(msg(type="move", grip="hand", position=target, tangent=[0, 1, 0]))
    saved = state.handle(msg(type="save", name="trial 1"))[0]
    assert saved.type == "saved" and saved.name == "trial 1.json"
    record = json.loads((folder / "trial 1.json").read_text())
    assert record["scene"] == "hose.toml"
    assert sorted(os.listdir(folder)) == ["hose.toml", "trial 1.json"]  # no temporaries
    state.handle(msg(type="move", grip="hand", position=[0.6, 0.2, 0.1], tangent=[0, 1, 0]))
    replies = state.handle(msg(type="load", name="trial 1"))
    grip = next(g for g in by_type(replies, "scene")[0].grips if g.name == "hand")
    np.testing.assert_allclose(grip.position, target)
    np.testing.assert_allclose(by_type(replies, "frame")[0].curve[-1], target, atol=1e-9)
    with pytest.raises(ProtocolError, match="no saved session"):
        state.handle(msg(type="load", name="missing"))
    (folder / "broken.json").write_text("{not json")
    with pytest.raises(ProtocolError, match="not a pliant session"):
        state.handle(msg(type="load", name="broken"))


def test_no_file_outside_the_scene_folder(state, folder, tmp_path_factory):
    outside = tmp_path_factory.mktemp("elsewhere")
    (outside / "secret.json").write_text(json.dumps(
        {"v": 1, "scene": "hose.toml", "grips": []}))
    (folder / "link.json").symlink_to(outside / "secret.json")
    with pytest.raises(ProtocolError, match="outside the scene's folder"):
        state.handle(msg(type="load", name="link"))
    (folder / "escape.json").write_text(json.dumps(
        {"v": 1, "scene": "../elsewhere/x.toml", "grips": []}))
    with pytest.raises(ProtocolError, match="outside the scene's folder"):
        state.handle(msg(type="load", name="escape"))
    with pytest.raises(ProtocolError, match="outside"):
        ViewerState(Path("../hose.toml"), folder / "sub" if (folder / "sub").mkdir() is None
                    else folder, live=False)


def test_wrong_grips_get_typed_errors(state):
    state.handle(msg(type="hello"))
    with pytest.raises(ProtocolError, match="no grip is named 'foot'"):
        state.handle(msg(type="move", grip="foot", position=[0, 0, 0]))
    with pytest.raises(ProtocolError, match="fixed"):
        state.handle(msg(type="move", grip="connector", position=[0, 0, 0]))
    with pytest.raises(ProtocolError, match="not a grip"):
        state.handle(msg(type="mode", grip="connector", mode="force"))
    with pytest.raises(ProtocolError, match="non-zero"):
        state.handle(msg(type="move", grip="hand", position=[0.5, 0.3, 0.1],
                         tangent=[0, 0, 0]))


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(events=st.lists(st.tuples(
    st.sampled_from(["hand", "connector", "nobody"]),
    st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3),
    st.lists(st.floats(-1, 1), min_size=3, max_size=3)), min_size=1, max_size=4))
def test_random_moves_give_frames_or_typed_errors(state, events):
    """Any pose, reachable or not: a frame (and a good or failed accurate answer), or a
    typed error; the session goes on."""
    for grip, position, tangent in events:
        try:
            replies = state.handle(msg(type="move", grip=grip, position=position,
                                       tangent=tangent))
            replies += state.handle(msg(type="solve"))
        except (ProtocolError, PliantError) as err:
            assert str(err)
            continue
        frame = by_type(replies, "frame")[0]
        assert all(math.isfinite(x) for p in frame.curve for x in p)
        for accurate in by_type(replies, "accurate"):
            assert accurate.ok or accurate.error
    assert state.handle(msg(type="hello"))[0].type == "scene"


# -- the server ------------------------------------------------------------------------------
@pytest.fixture
def server(folder):
    from pliant.viewer.server import Server

    with Server(folder / "hose.toml", port=0, live=False) as running:
        yield running


def connect(server, **options):
    from websockets.sync.client import connect as ws_connect

    return ws_connect(f"ws://127.0.0.1:{server.port}/ws", open_timeout=60, **options)


def receive(ws, kind: str, timeout: float = 60.0) -> dict:
    while True:
        message = json.loads(ws.recv(timeout=timeout))
        if message["type"] == kind:
            return message


def get(server, path: str) -> tuple[int, bytes]:
    import http.client

    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    try:
        conn.request("GET", path)
        response = conn.getresponse()
        return response.status, response.read()
    finally:
        conn.close()


def test_the_server_listens_on_loopback_and_serves_only_its_files(server):
    assert server.host == "127.0.0.1"
    assert server.addresses == ["127.0.0.1"]
    status, body = get(server, "/")
    assert status == 200 and b"importmap" in body
    status, body = get(server, "/vendor/three/build/three.module.js")
    assert status == 200 and b"WebGLRenderer" in body
    for path in ("/../pyproject.toml", "/static/../../server.py", "/static/%2e%2e/server.py",
                 "/vendor/three/../../package.json", "/vendor/three/%2e%2e/%2e%2e/package.json",
                 "/hose.toml", "/etc/passwd", "/vendor/other/x.js"):
        status, _ = get(server, path)
        assert status == 404, path


def test_bad_messages_get_errors_and_the_server_goes_on(server):
    with connect(server) as ws:
        for raw in ("not json", b"\x00\xff\xfe", json.dumps({"v": 1, "type": "move"}),
                    json.dumps({"v": 1, "type": "hello", "pad": "x" * (P.MAX_MESSAGE + 1)}),
                    json.dumps({"v": 1, "type": "move", "grip": "hand",
                                "position": [1e308, 0, 0]})):
            ws.send(raw)
            error = receive(ws, "error")
            assert error["message"]
        ws.send(json.dumps({"v": 1, "type": "hello"}))
        assert receive(ws, "scene")["name"] == "hose by a drum"
    # A message past the websocket limit closes that connection only.
    from websockets.exceptions import ConnectionClosed

    with connect(server, max_size=None) as ws:
        ws.send("x" * (P.MAX_FRAME + 10))
        with pytest.raises(ConnectionClosed):
            ws.recv(timeout=30)
    with connect(server) as ws:
        ws.send(json.dumps({"v": 1, "type": "hello"}))
        assert receive(ws, "scene")["grips"][1]["name"] == "hand"


def test_a_cross_site_page_cannot_open_a_session(server):
    from websockets.exceptions import InvalidStatus

    with pytest.raises(InvalidStatus) as err:
        connect(server, origin="http://evil.example")
    assert err.value.response.status_code == 403


def test_two_users_get_their_own_sessions(server):
    with connect(server) as a, connect(server) as b:
        for ws in (a, b):
            ws.send(json.dumps({"v": 1, "type": "hello"}))
            receive(ws, "frame")
        a.send(json.dumps({"v": 1, "type": "move", "grip": "hand", "seq": 1,
                           "position": [0.6, 0.3, 0.2], "tangent": [0, 1, 0]}))
        moved = receive(a, "frame")
        b.send(json.dumps({"v": 1, "type": "solve"}))
        other = receive(b, "frame")
        np.testing.assert_allclose(moved["curve"][-1], [0.6, 0.3, 0.2], atol=1e-9)
        # The move drifted past the tolerance: its accurate answer follows on its own.
        answer = receive(a, "accurate")
        assert answer["ok"] and answer["index"] == moved["index"]
        np.testing.assert_allclose(answer["position"][-1], [0.6, 0.3, 0.2], atol=1e-9)
        np.testing.assert_allclose(other["curve"][-1], [0.55, 0.35, 0.15], atol=1e-9)
        assert server.connections == 2


def test_pliant_view_prints_its_address_and_stops_on_ctrl_c(folder):
    import signal
    import subprocess
    import sys
    import urllib.request

    process = subprocess.Popen(
        [sys.executable, "-c", "from pliant.cli.app import main; main()", "view",
         str(folder / "hose.toml"), "--port", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        lines = []
        for line in process.stdout:
            lines.append(line)
            if "open http://" in line:
                break
        url = lines[-1].split("open ", 1)[1].split(" ", 1)[0]
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=30) as response:
            assert b"importmap" in response.read()
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=30) == 130
    finally:
        process.kill()
        process.wait()
        process.stdout.close()


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(raws=st.lists(st.text(max_size=300) | st.binary(max_size=300) | FIELDS.map(json.dumps),
                     min_size=1, max_size=5))
def test_random_messages_never_crash_the_server(server, raws):
    """Random and malformed messages over a real connection: each gets a reply or is
    taken as a message, and the connection still answers a hello afterwards."""
    with connect(server) as ws:
        for raw in raws:
            ws.send(raw)
        ws.send(json.dumps({"v": 1, "type": "hello"}))
        assert receive(ws, "scene")["name"] == "hose by a drum"


@pytest.mark.serial  # timed against a worker process: alone, not beside the parallel suite
def test_a_live_result_taken_in_by_a_move_still_reaches_the_page(folder):
    """Live: an answer the worker sends while the user drags is published by the next
    move's frame; that move's replies carry it (else the page would never see it)."""
    import time

    state = ViewerState(Path("hose.toml"), folder, live=True)
    try:
        state.handle(msg(type="hello"))
        far = state.handle(msg(type="move", grip="hand", position=[0.6, 0.3, 0.25],
                               tangent=[0, 1, 0]))[0]
        assert far.pending  # the drift asked the worker for this pose
        deadline = time.monotonic() + 120
        while not state.session.answered and time.monotonic() < deadline:
            time.sleep(0.01)
        replies = state.handle(msg(type="move", grip="hand", position=[0.6, 0.3, 0.251],
                                   tangent=[0, 1, 0]))
        accurate = by_type(replies, "accurate")
        assert [a.index for a in accurate] == [far.index]
        np.testing.assert_allclose(accurate[0].position[-1], [0.6, 0.3, 0.25], atol=1e-9)
        again = by_type(state.take_accurate(), "accurate")
        assert far.index not in [a.index for a in again]  # sent once
    finally:
        state.close()


@pytest.mark.serial  # timed against a worker process: alone, not beside the parallel suite
def test_live_answers_are_pushed_as_they_arrive(folder):
    """Live, the worker's answer calls the watcher (the server's wake-up) from the reader
    thread, with no poll of the session in between; what the server then takes is that
    answer, for the pose asked. A session loaded later is watched too."""
    import threading

    state = ViewerState(Path("hose.toml"), folder, live=True)
    try:
        arrived = threading.Event()
        state.watch(arrived.set)
        state.handle(msg(type="hello"))
        far = state.handle(msg(type="move", grip="hand", position=[0.6, 0.3, 0.25],
                               tangent=[0, 1, 0]))[0]
        assert far.pending
        assert arrived.wait(timeout=120)
        accurate = by_type(state.take_accurate(), "accurate")
        assert [a.index for a in accurate] == [far.index]
        np.testing.assert_allclose(accurate[0].position[-1], [0.6, 0.3, 0.25], atol=1e-9)
        state.handle(msg(type="save", name="pushed"))
        state.handle(msg(type="load", name="pushed"))  # a new session, watched as well
        arrived.clear()
        state.handle(msg(type="solve"))
        assert arrived.wait(timeout=120)
        assert by_type(state.take_accurate(), "accurate")
    finally:
        state.close()


def test_the_page_gets_the_poses_verdict_by_the_same_rules_as_pliant_evaluate(state, folder):
    from pliant.assembly.evaluate import evaluate_pose

    replies = state.handle(msg(type="hello"))
    accurate = by_type(replies, "accurate")[0]
    verdict = accurate.verdict
    assert verdict is not None and verdict.passes
    # The same pose judged through the Python API gives the same words.
    scene = load_scene(folder / "hose.toml")
    api = AccurateSolver(elements=30).solve(0, scene.problem)
    clearances = {c.obstacle: c.clearance for c in accurate.interference.clearances}
    ev = evaluate_pose(scene, api, clearances, grips=("hand",))
    assert verdict.headline == ev.verdict.headline
    assert [i.text for i in verdict.items] == [c.sentence(with_step=False)
                                               for c in ev.items]
    # the hand it judged, to draw: the same access as the API's
    (hand,) = verdict.hands
    access = ev.chosen.access["hand"][0]
    assert hand.grip == "hand" and hand.clearance == pytest.approx(access.clearance)
    assert hand.centre == pytest.approx(list(access.centre))
    assert verdict.worker == []  # no [worker] in this scene
    # the solver's details the page shows: the stability test's smallest eigenvalue,
    # the API's own (the field the page read had not been sent before)
    assert accurate.stable is True and accurate.smallest_eigenvalue > 0
    assert accurate.smallest_eigenvalue == pytest.approx(api.smallest_eigenvalue)
    # A hose whose datasheet asks for more than the shape's bend is judged red, live.
    (folder / "stiff.toml").write_text(SCENE.replace("min_bend_radius = 0.08",
                                                     "min_bend_radius = 0.5"))
    strict = ViewerState(Path("stiff.toml"), folder, live=False)
    try:
        red = by_type(strict.handle(msg(type="hello")), "accurate")[0]
    finally:
        strict.close()
    assert red.min_bend_radius < 0.5 and not red.verdict.passes
    assert red.verdict.headline.startswith("DOES NOT FIT: smallest bend radius")
    assert red.verdict.items[0].zone == "red"


def test_a_studys_envelope_is_sent_with_the_scene(folder):
    from pliant.io.mesh_export import export_envelope, voxel_surface
    from pliant.viewer.state import load_envelope

    voxels = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [5, 5, 5]])
    export_envelope([("envelope along the path", voxels, (150, 160, 170, 90))], 0.01,
                    folder / "study" / "envelope.glb")
    meshes = load_envelope(folder / "study")
    viewer = ViewerState(Path("hose.toml"), folder, live=False, envelopes=meshes)
    try:
        scene = by_type(viewer.handle(msg(type="hello")), "scene")[0]
    finally:
        viewer.close()
    assert [e.name for e in scene.envelopes] == ["envelope along the path"]
    _, faces = voxel_surface(voxels, 0.01)
    assert len(scene.envelopes[0].faces) == len(faces)
    with pytest.raises(InputError, match="envelope"):
        load_envelope(folder / "hose.toml")


def _raw_get(server, path: str, host: str, origin: str | None = None) -> int:
    """The status of a GET sent with exactly these Host and Origin headers."""
    import http.client

    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=30)
    try:
        conn.putrequest("GET", path, skip_host=True, skip_accept_encoding=True)
        conn.putheader("Host", host)
        if origin is not None:
            conn.putheader("Origin", origin)
        conn.endheaders()
        return conn.getresponse().status
    finally:
        conn.close()


def test_a_rebinding_page_under_another_name_is_refused(server):
    """DNS rebinding: evil.example resolving to 127.0.0.1, its page at
    http://evil.example:PORT sends Host and Origin of its own name. The server answers only
    to its own address (localhost, an IP, the --host it was given)."""
    port = server.port
    assert _raw_get(server, "/", f"127.0.0.1:{port}") == 200
    assert _raw_get(server, "/", f"localhost:{port}") == 200
    assert _raw_get(server, "/", f"evil.example:{port}") == 403
    assert _raw_get(server, "/", f"127.0.0.1:{port + 1}") == 403
    assert _raw_get(server, "/ws", f"evil.example:{port}", f"http://evil.example:{port}") == 403
    from websockets.exceptions import InvalidStatus

    with pytest.raises(InvalidStatus) as err:
        connect(server, additional_headers={"Host": f"evil.example:{port}"},
                origin=f"http://evil.example:{port}")
    assert err.value.response.status_code == 403


def test_odd_paths_and_values_get_clean_answers(server):
    for path in ("/static/%00x.js", "/static/" + "a" * 5000 + ".js", "/" + "b" * 300):
        status, _ = get(server, path)
        assert status == 404, path[:40]
    with connect(server) as ws:
        ws.send(json.dumps({"v": 1, "type": "hello"}))
        receive(ws, "scene")
        ws.send(json.dumps({"v": 1, "type": "move", "grip": "hand",
                            "position": [1e308, 0.0, 0.0], "seq": 1}))
        error = receive(ws, "error")
        assert "position" in error["message"] and "internal" not in error["message"]
        ws.send("[" * 30000 + "]" * 30000)
        error = receive(ws, "error")
        assert "nested too deeply" in error["message"]
        ws.send(json.dumps({"v": 1, "type": "hello"}))
        assert receive(ws, "scene")["type"] == "scene"  # it goes on serving


def test_the_scene_message_carries_the_path_to_play(folder):
    """A scene's [path] reaches the page as the grip's pose at each step; a long path
    is thinned to PATH_STEPS poses, evenly, its first and last kept."""
    plain = ViewerState(Path("hose.toml"), folder, live=False)
    try:
        assert by_type(plain.handle(msg(type="hello")), "scene")[0].path is None
    finally:
        plain.close()
    for steps, shown in ((40, 40), (2500, P.PATH_STEPS)):
        (folder / "walk.toml").write_text(SCENE + f"""
[path]
grip = "hand"
waypoints = [[0.5, 0.4, 0.3], [0.4, 0.5, 0.3]]
tangents = [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
steps = {steps}
""")
        viewer = ViewerState(Path("walk.toml"), folder, live=False)
        try:
            play = by_type(viewer.handle(msg(type="hello")), "scene")[0].path
        finally:
            viewer.close()
        scene = load_scene(folder / "walk.toml")
        assert play.grip == "hand" and len(play.positions) == len(play.tangents) == shown
        for k, j in ((0, 0), (-1, -1), (shown // 2, round((shown // 2) * (steps - 1)
                                                              / (shown - 1)))):
            c = scene.path[j].condition("hand")
            np.testing.assert_allclose(play.positions[k], c.position, atol=1e-9)
            np.testing.assert_allclose(play.tangents[k], c.tangent, atol=1e-9)


def test_the_page_draws_the_obstacles_within_the_display_budget(folder):
    """Two mesh parts of 20,480 triangles each: drawn whole by default, within a
    10,000-triangle budget each at half (in proportion), close to its surface."""
    import trimesh

    for k, x in enumerate((0.3, -0.3)):
        ball = trimesh.creation.icosphere(subdivisions=5, radius=0.05)
        ball.apply_translation([x, 0.3, 0.0])
        ball.export(folder / f"ball{k}.stl")
    text = SCENE + "".join(f'\n[[obstacle]]\nname = "ball {k}"\nshape = "mesh"\n'
                           f'file = "ball{k}.stl"\n' for k in range(2))
    (folder / "balls.toml").write_text(text)
    drawn = {}
    for budget in (None, 10_000):
        viewer = ViewerState(Path("balls.toml"), folder, live=False, display=budget)
        try:
            scene = by_type(viewer.handle(msg(type="hello")), "scene")[0]
        finally:
            viewer.close()
        drawn[budget] = {o.name: o for o in scene.obstacles}
    assert [len(drawn[None][f"ball {k}"].faces) for k in range(2)] == [20_480, 20_480]
    for k, x in enumerate((0.3, -0.3)):
        ball = drawn[10_000][f"ball {k}"]
        assert 4_000 <= len(ball.faces) <= 5_000
        radius = np.linalg.norm(np.array(ball.vertices) - [x, 0.3, 0.0], axis=1)
        assert np.abs(radius - 0.05).max() < 5e-4


def test_past_its_bound_the_server_says_busy_and_frees_the_place_on_close(folder):
    """At most ``sessions`` tabs at once (each has its own solver process): one more
    is told so, by name of the option, and closed; a closed tab frees its place."""
    from websockets.exceptions import ConnectionClosed

    from pliant.viewer.server import Server

    hello = json.dumps({"v": 1, "type": "hello"})
    with Server(folder / "hose.toml", port=0, live=False, sessions=2) as server:
        with connect(server) as a, connect(server) as b:
            for ws in (a, b):
                ws.send(hello)
                receive(ws, "frame")
            with connect(server) as c:
                refused = json.loads(c.recv(timeout=60))
                assert refused["type"] == "error" and "busy" in refused["message"]
                assert "--sessions" in refused["message"]
                with pytest.raises(ConnectionClosed):
                    c.recv(timeout=60)
                assert c.close_code == 1013
        deadline = time.monotonic() + 30
        while server.open_sessions and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.open_sessions == 0
        with connect(server) as d:
            d.send(hello)
            receive(d, "frame")


def test_a_tab_that_sends_nothing_is_closed_and_frees_its_place(folder):
    """Issue 54: idle websockets held their session slots forever. A tab that sends
    nothing for the server's ``idle`` seconds is told why and closed (going away), its
    place freed for another tab; a tab that keeps sending is not."""
    from websockets.exceptions import ConnectionClosed

    from pliant.errors import InputError
    from pliant.viewer.server import Server

    hello = json.dumps({"v": 1, "type": "hello"})
    with pytest.raises(InputError, match="idle"):
        Server(folder / "hose.toml", port=0, live=False, idle=0.0)
    with Server(folder / "hose.toml", port=0, live=False, sessions=1, idle=1.5) as server:
        with connect(server) as quiet:
            quiet.send(hello)
            said = receive(quiet, "error", timeout=60)
            assert "sent nothing for 1.5 s" in said["message"]
            assert "reload the page" in said["message"]
            with pytest.raises(ConnectionClosed):
                while True:
                    quiet.recv(timeout=60)
            assert quiet.close_code == 1001
        deadline = time.monotonic() + 30
        while server.open_sessions and time.monotonic() < deadline:
            time.sleep(0.05)
        assert server.open_sessions == 0 and server.idled == 1
        with connect(server) as busy:  # its place is free, and sending keeps it open
            busy.send(hello)
            receive(busy, "frame")
            for _ in range(3):
                time.sleep(0.7)
                busy.send(hello)
                receive(busy, "scene")
        assert server.idled == 1


def _raw_websocket(port: int):
    """A websocket client that sends but never reads: a socket with a small receive
    buffer, the opening handshake by hand, and masked text frames."""
    import os
    import socket

    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    sock.sendall((f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                  "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                  "Sec-WebSocket-Version: 13\r\n\r\n").encode())
    answer = b""
    while b"\r\n\r\n" not in answer:
        answer += sock.recv(1)
    assert answer.startswith(b"HTTP/1.1 101")

    def send(text: str) -> None:
        payload = text.encode()
        mask = os.urandom(4)
        head = bytes([0x81]) + (bytes([0x80 | len(payload)]) if len(payload) < 126 else
                                bytes([0x80 | 126]) + len(payload).to_bytes(2, "big"))
        sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    return sock, send


def test_a_client_that_never_reads_is_dropped_and_its_session_freed(folder, monkeypatch):
    """A page that sends and never reads would hold its session (and in a live server
    its solver process) forever: past the send timeout the server drops it and goes on
    serving the others."""

    from pliant.viewer import server as server_module
    from pliant.viewer.server import Server

    monkeypatch.setattr(server_module, "SEND_TIMEOUT", 1.0)
    with Server(folder / "hose.toml", port=0, live=False, sessions=2) as server:
        sock, send = _raw_websocket(server.port)
        sock.settimeout(2.0)
        try:
            send(json.dumps({"v": 1, "type": "hello"}))
            for k in range(20_000):  # each reply a frame of the whole part: kilobytes
                send(json.dumps({"v": 1, "type": "move", "grip": "hand", "seq": k + 1,
                                 "position": [0.55, 0.35 - 1e-5 * (k % 100), 0.15],
                                 "tangent": [0, 1, 0]}))
        except (TimeoutError, OSError):
            pass  # the server stopped reading it: its replies are piled up unread
        deadline = time.monotonic() + 60
        while (server.dropped == 0 or server.open_sessions) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert server.dropped == 1 and server.open_sessions == 0
        sock.close()
        with connect(server) as other:  # the others are served on
            other.send(json.dumps({"v": 1, "type": "hello"}))
            receive(other, "frame")


def test_the_bundled_scenes_sessions_are_saved_in_the_users_folder(tmp_path, monkeypatch):
    """The bundled scene lives in the installed package: its sessions go to the user's
    folder ($PLIANT_SESSIONS here), named after the scene's folder, and load from there;
    the package is left as installed."""
    from pliant.viewer.state import save_folder

    demo = Path(__file__).resolve().parents[1] / "src" / "pliant" / "data" / "demo"
    monkeypatch.setenv("PLIANT_SESSIONS", str(tmp_path))
    assert save_folder(demo.resolve()) == (tmp_path / "demo").resolve()
    before = sorted(os.listdir(demo))
    viewer = ViewerState(Path("engine_bay.toml"), demo, live=False)
    try:
        viewer.handle(msg(type="hello"))
        saved = viewer.handle(msg(type="save", name="trial"))[0]
        assert Path(saved.folder) == (tmp_path / "demo").resolve()
        assert json.loads((tmp_path / "demo" / "trial.json").read_text())["scene"] == (
            "engine_bay.toml")
        viewer.handle(msg(type="load", name="trial"))
    finally:
        viewer.close()
    assert sorted(os.listdir(demo)) == before


def test_a_scene_whose_start_pose_fails_still_opens_with_the_reason(folder):
    """The hand's start inside the drum: no equilibrium there, but the scene opens (the
    obstacles, the grips, a real-time shape) with the reason; moving the hand out of
    the drum brings the accurate answer."""
    (folder / "bad.toml").write_text(SCENE.replace("x = 0.55\ny = 0.35\nz = 0.15",
                                                   "x = 0.3\ny = -0.3\nz = 0.0"))
    viewer = ViewerState(Path("bad.toml"), folder, live=False)
    try:
        replies = viewer.handle(msg(type="hello"))
        scene = by_type(replies, "scene")[0]
        assert [o.name for o in scene.obstacles] == ["drum"]
        first = by_type(replies, "accurate")[0]
        assert not first.ok and "start pose has no equilibrium" in first.error
        assert "inside the obstacle 'drum'" in first.error
        assert by_type(replies, "frame")
        moved = viewer.handle(msg(type="move", grip="hand", seq=1,
                                  position=[0.55, 0.35, 0.15], tangent=[0, 1, 0]))
        answer = by_type(moved, "accurate")[-1]
        assert answer.ok
        np.testing.assert_allclose(answer.position[-1], [0.55, 0.35, 0.15], atol=1e-9)
    finally:
        viewer.close()


def test_the_page_the_cli_and_the_frames_warn_in_the_same_words(folder):
    """Warnings are made once (``checks.shape_warnings``): a pose bent below the part's
    minimum radius (raised to 0.5 m here) warns in the same words in the viewer's
    accurate answer and in ``pliant solve``'s summary of the same pose, and the frame
    carries the preview's own, from its curvature (the page only shows them)."""
    from rich.console import Console

    from pliant.assembly.checks import PREVIEW, shape_warnings
    from pliant.cli.report import print_summary
    from pliant.models import rod3d
    from pliant.scene import interference

    (folder / "tight.toml").write_text(SCENE.replace("min_bend_radius = 0.08",
                                                     "min_bend_radius = 0.5"))
    viewer = ViewerState(Path("tight.toml"), folder, live=False)
    try:
        replies = viewer.handle(msg(type="hello"))
        accurate = by_type(replies, "accurate")[-1]
        frame = by_type(replies, "frame")[-1]
    finally:
        viewer.close()
    assert accurate.ok and any("below the part's limit 500.0 mm (centreline)" in w
                               for w in accurate.warnings)
    scene = load_scene(folder / "tight.toml")
    eq = rod3d.solve(scene.problem, solver=rod3d.RodSolver(elements=30))
    console = Console(record=True, width=200)
    print_summary(eq, 0.0, console, report=interference(eq, margin=scene.margin))
    printed = [line.removeprefix("warning: ") for line in console.export_text().splitlines()
               if line.startswith("warning: ")]
    assert printed == accurate.warnings
    k = int(np.argmax(frame.curvature))
    assert frame.warnings == shape_warnings(
        bend_radius=1.0 / frame.curvature[k], bend_at=frame.s[k], allowed=0.5,
        penetrations=frame.interference.penetrations, preview=True)
    assert frame.warnings and all(w.startswith(PREVIEW) for w in frame.warnings)


def test_a_scene_linked_into_the_folder_opens_and_a_name_that_leaves_does_not(tmp_path):
    """The bundled examples link to the package's demo scene: a link in the user's own
    folder is followed; a name that climbs out (``..``, an absolute path) is refused."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "hose.toml").write_text(SCENE)
    (folder / "hose.toml").symlink_to(elsewhere / "hose.toml")
    viewer = ViewerState(Path("hose.toml"), folder, live=False)
    assert viewer.path == folder / "hose.toml" and viewer.scene is not None
    viewer.close()
    for name in ("../elsewhere/hose.toml", str(elsewhere / "hose.toml")):
        with pytest.raises(ProtocolError, match="outside the scene's folder"):
            ViewerState(Path(name), folder, live=False)
