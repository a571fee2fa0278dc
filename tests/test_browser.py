"""End to end in a real browser: Debian's chromium, headless, driven by Playwright (no
browser download), against ``pliant view``'s server on the bundled default scene, with
the accurate model in its worker process as a user runs it."""

from __future__ import annotations

import contextlib
import io
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from pliant.assembly.scenes import load_scene
from pliant.core.conditions import Condition

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
pytestmark = pytest.mark.skipif(not Path(CHROMIUM).exists(),
                                reason="Debian's chromium is not installed (the README's "
                                       "test command installs it)")
SCENE = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "engine_bay.toml"
# Headless, software WebGL, and none of the background connections a closed network refuses.
ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-quic"]
LOADED = ("window.pliant && window.pliant.state.accurate && window.pliant.state.frames > 0"
          " && window.pliant.state.rendered > 2")


@pytest.fixture(scope="module")
def server():
    from pliant.viewer.server import Server

    with Server(SCENE, port=0, live=True) as running:
        yield running


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser, server):
    page = browser.new_page(viewport={"width": 1100, "height": 720})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    yield page, server, errors
    page.close()
    assert not errors, errors


def image(png: bytes) -> np.ndarray:
    from matplotlib.image import imread

    return imread(io.BytesIO(png), format="png")[..., :3]


def test_the_page_renders_the_scene_and_the_tube(page):
    page, server, _ = page
    page.goto(server.url)
    page.wait_for_function(LOADED, timeout=120_000)
    view = page.locator("#view canvas").first
    shown = image(view.screenshot())
    # Not blank: the obstacles and the part cover much of the view in many shades.
    background = np.array([0xE9, 0xED, 0xF1]) / 255.0
    drawn = np.abs(shown - background).sum(axis=2) > 0.05
    assert drawn.mean() > 0.1
    assert len(np.unique((shown * 255).astype(int).reshape(-1, 3), axis=0)) > 200
    # The tube is there: hiding it changes the picture where it lies.
    page.evaluate("window.pliant.world.getObjectByName('tube').visible = false")
    page.wait_for_function("(n => window.pliant.state.rendered > n + 2)",
                           arg=page.evaluate("window.pliant.state.rendered"))
    hidden = image(view.screenshot())
    changed = np.abs(shown - hidden).sum(axis=2) > 0.1
    assert changed.sum() > 500
    assert "oil line" in page.inner_text("#scene-name")
    clearances = page.inner_text("#clearance")
    for name in ("engine block", "exhaust manifold", "oil cooler", "coolant hose"):
        assert name in clearances


def test_dragging_a_grip_moves_the_tube_and_shows_the_apis_force(page):
    page, server, _ = page
    page.goto(server.url)
    page.wait_for_function(LOADED, timeout=120_000)
    start = np.array(page.evaluate("window.pliant.state.frame.curve.at(-1)"))
    xy = page.evaluate("window.pliant.gripScreen('hand')")
    page.mouse.move(xy["x"], xy["y"])
    page.mouse.down()
    for k in range(1, 13):
        page.mouse.move(xy["x"] + 5 * k, xy["y"] - 3 * k)
        page.wait_for_timeout(25)
    page.mouse.up()
    page.wait_for_function("!window.pliant.state.inFlight && !window.pliant.state.queued")
    pose = page.evaluate("window.pliant.state.lastPose")
    end = np.array(page.evaluate("window.pliant.state.frame.curve.at(-1)"))
    assert np.linalg.norm(end - start) > 0.01  # the tube followed the hand
    np.testing.assert_allclose(end, pose["position"], atol=1e-6)
    # An accurate solve at this pose: the panel shows the force the Python API gives.
    page.click("#solve")
    page.wait_for_function("(() => { const s = window.pliant.state; return s.accurate && "
                           "s.frame && s.accurate.index === s.frame.index && "
                           "!s.frame.pending; })()", timeout=120_000)
    shown = float(page.get_attribute("#grip-hand .force-value", "data-newton"))
    assert f"{shown:.3f} N" in page.inner_text("#grip-hand .force-value")
    assert page.inner_text("#status") == "forces and verdict are for this pose"
    scene = load_scene(SCENE)
    from pliant.session.accurate import AccurateSolver

    solver = AccurateSolver(elements=scene.solver.elements)
    solver.solve(0, scene.problem)
    moved = scene.problem.with_conditions(
        Condition(s=c.s, name=c.name, position=tuple(pose["position"]),
                  tangent=tuple(pose["tangent"])) if c.name == "hand" else c
        for c in scene.problem.conditions)
    api = solver.solve(1, moved)
    assert api.ok
    assert shown == pytest.approx(float(np.linalg.norm(api.loads["hand"].force)), rel=1e-6)
    start_force = np.linalg.norm(solver.solve(2, scene.problem).loads["hand"].force)
    assert abs(shown - start_force) > 1e-3  # it changed with the pose


def test_a_vr_controller_grabs_the_grip_and_moves_it(page):
    """WebXR through the iwer emulator (npm): the trigger near the grip takes it, and
    the part follows the controller."""
    page, server, _ = page
    page.goto(server.url + "?xr=emulate")
    page.wait_for_function(LOADED, timeout=120_000)
    assert page.inner_text("#VRButton") == "ENTER VR"
    page.click("#VRButton")
    page.wait_for_function("window.pliant.state.xr === true", timeout=30_000)
    grip = page.evaluate("window.pliant.state.scene.grips.find(g => g.name === 'hand')"
                         ".position")
    at = page.evaluate("p => window.pliant.worldOf(p)", grip)
    right = "window.pliant.xrDevice.controllers.right"
    page.evaluate(f"p => {right}.position.set(p[0], p[1], p[2])", at)
    page.wait_for_timeout(200)
    page.evaluate(f"{right}.updateButtonValue('trigger', 1)")
    page.wait_for_function("window.pliant.hands.some(h => h.userData.held)")
    for k in range(1, 11):  # 5 cm along XR's x (the scene's x), 4 cm up (the scene's z)
        page.evaluate(f"p => {right}.position.set(p[0] + {0.005 * k}, p[1] + {0.004 * k},"
                      " p[2])", at)
        page.wait_for_timeout(60)
    page.evaluate(f"{right}.updateButtonValue('trigger', 0)")
    page.wait_for_function("!window.pliant.hands.some(h => h.userData.held) && "
                           "!window.pliant.state.inFlight && !window.pliant.state.queued")
    pose = page.evaluate("window.pliant.state.lastPose")
    np.testing.assert_allclose(pose["position"], np.array(grip) + [0.05, 0.0, 0.04],
                               atol=1e-5)
    end = page.evaluate("window.pliant.state.frame.curve.at(-1)")
    np.testing.assert_allclose(end, pose["position"], atol=1e-6)


def test_the_panel_shows_the_poses_verdict_from_the_server(page):
    """The verdict panel shows what the server's evaluation says (no rules in the page):
    the bundled start pose fits with one hand, its reservations listed with sources."""
    page, server, _ = page
    page.goto(server.url)
    page.wait_for_function(LOADED, timeout=120_000)
    page.wait_for_function("window.pliant.state.accurate.verdict !== null")
    verdict = page.evaluate("window.pliant.state.accurate.verdict")
    assert page.inner_text("#verdict") == verdict["headline"]
    assert verdict["headline"].startswith("FITS with one hand") and verdict["passes"]
    items = page.locator("#verdict-items li")
    assert items.count() == len(verdict["items"]) >= 1
    assert "bending moment at the hand" in page.inner_text("#verdict-items")
    # the solver's details name the stability test's smallest eigenvalue
    value = page.evaluate("window.pliant.state.accurate.smallest_eigenvalue")
    assert value > 0
    details = page.evaluate("document.querySelector('#accurate-details').textContent")
    shown = float(details.split("smallest eigenvalue ")[1].split()[0])
    assert shown == pytest.approx(value, rel=0.01)  # three figures
    # One clearance (issue 61): the table is the accurate model's, as the verdict's, and
    # says so; the real-time preview's only while the accurate answer is on its way.
    page.wait_for_function("document.querySelector('#clearance-source').textContent"
                           ".includes('accurate model')")
    accurate = page.evaluate("window.pliant.state.accurate.interference.clearances")
    shown = page.inner_text("#clearance")
    for c in accurate:
        value = "0 (touching)" if c["clearance"] == 0 else f"{c['clearance'] * 1e3:.1f} mm"
        assert f"{c['obstacle']}\t{value}" in shown


def test_the_page_plays_the_scenes_path_step_by_step(page):
    """Play path carries the grip through every pose of the scene's [path] (what
    `pliant plan` writes), each sent once the server has answered the last: the tube
    ends where the path ends. (Every fourth pose of the engine bay's, and its last:
    software WebGL draws a frame in about 0.15 s here.)"""
    page, server, _ = page
    page.goto(server.url)
    page.wait_for_function(LOADED, timeout=120_000)
    scene = load_scene(SCENE)
    assert page.evaluate("window.pliant.state.scene.path.positions.length") == len(scene.path)
    assert page.is_visible("#play")
    steps = page.evaluate("""(() => {
        const p = window.pliant.state.scene.path;
        const keep = p.positions.map((_, k) => k).filter((k) => k % 4 === 3);
        p.positions = keep.map((k) => p.positions[k]);
        p.tangents = keep.map((k) => p.tangents[k]);
        return keep.length; })()""")
    seq = page.evaluate("window.pliant.state.seq")
    solved = page.evaluate("window.pliant.state.accurates")
    page.click("#play")
    page.wait_for_function(f"document.querySelector('#path-step').textContent === "
                           f"'played {steps} steps, each solved accurately'",
                           timeout=240_000)
    page.wait_for_function("!window.pliant.state.inFlight && !window.pliant.state.queued")
    assert page.evaluate("window.pliant.state.seq") - seq == steps  # none skipped
    # Every step shown was solved accurately, each from the one before (issue 61: the
    # page solved 2 of 40), and the last answer is the last pose's, as pliant
    # evaluate's last step: the same force at the hand.
    assert page.evaluate("window.pliant.state.accurates") - solved >= steps
    assert page.evaluate("window.pliant.state.accurate.index === "
                         "window.pliant.state.frame.index")
    loads = {x["name"]: x for x in page.evaluate("window.pliant.state.accurate.loads")}
    from pliant.assembly.evaluate import evaluate

    final = evaluate(scene, search=False).run.equilibria[-1].loads["hand"]
    np.testing.assert_allclose(loads["hand"]["force"], final.force, rtol=1e-5, atol=1e-6)
    last = scene.path[-1].condition("hand")
    pose = page.evaluate("window.pliant.state.lastPose")
    np.testing.assert_allclose(pose["position"], last.position, atol=1e-6)
    np.testing.assert_allclose(pose["tangent"], last.tangent, atol=1e-6)
    end = np.array(page.evaluate("window.pliant.state.frame.curve.at(-1)"))
    np.testing.assert_allclose(end, last.position, atol=1e-6)


def test_the_view_reads_as_an_engineering_view(page):
    """The task and the frame of reference are on the screen: a floor grid with its cell
    said, the axis triad, standard views, the ports with their axes and names, the path,
    each obstacle's name; the force and moment labels at their own arrow tips, apart; a
    colour bar with its unit; plain words on how current the forces are; no VR button
    where the browser has no VR, and no loading text once the part is there."""
    page, server, _ = page
    page.goto(server.url)
    page.wait_for_function(LOADED, timeout=120_000)
    page.wait_for_timeout(300)
    assert page.evaluate("!!window.pliant.world.getObjectByName('floor')")
    assert page.inner_text("#grid-cell") == "grid 100 mm"
    for name in ("port oil filter", "port oil cooler", "path"):
        assert page.evaluate(f"!!window.pliant.world.getObjectByName('{name}')"), name
    labels = page.locator(".label.obstacle").all_inner_texts()
    assert {"engine block", "exhaust manifold", "oil cooler"} <= set(labels)
    assert "port: oil cooler" in page.locator(".label.port").all_inner_texts()
    # Labels: each within a few pixels of its own arrow's tip, the two texts apart.
    force, moment = (page.evaluate(f"window.pliant.arrowLabel('{k}')")
                     for k in ("force", "moment"))
    for label in (force, moment):  # on its arrow's line, just past the tip
        (ax, ay), (tx, ty), (bx, by), (px, py) = ((label[k]["x"], label[k]["y"]) for k in
                                                  ("anchor", "tip", "base", "at"))
        assert math.hypot(ax - px, ay - py) < 2
        assert math.hypot(ax - tx, ay - ty) < 0.1 * math.hypot(tx - bx, ty - by) + 2
    a, b = force["text"], moment["text"]
    assert (a["right"] <= b["left"] or b["right"] <= a["left"] or a["bottom"] <= b["top"]
            or b["bottom"] <= a["top"])
    # The triad: the three axis colours in the view's lower left corner.
    view = page.locator("#view canvas").first
    corner = image(view.screenshot())[-110:, :110]
    for rgb in ((0.83, 0.18, 0.18), (0.22, 0.56, 0.24), (0.08, 0.40, 0.75)):
        assert (np.abs(corner - rgb).sum(axis=2) < 0.25).sum() > 10, rgb
    # Standard views look along the scene's axes, z up.
    for name, direction in (("top", [0, 0, -1]), ("front", [0, 1, 0]), ("right", [-1, 0, 0])):
        page.click(f"#view-{name}")
        np.testing.assert_allclose(page.evaluate("window.pliant.viewDirection()"), direction,
                                   atol=2e-3)
    assert "N m" in page.inner_text("#colour-bar")
    assert page.inner_text("#status") == "forces and verdict are for this pose"
    # The hand's force and moment as numbers for people: a component that is round-off
    # reads 0, never -0.000 (the grip's moment about z here).
    grips = page.inner_text("#grips")
    assert "hand moment" in grips and "-0.00" not in grips
    assert page.locator("#VRButton").count() == 0
    assert page.is_hidden("#loading")


TWO_HANDS = """
name = "a hose in two hands"
gravity = [0.0, 0.0, -9.81]

[part]
name = "hose"
length = 0.8
outer_diameter = 0.02
bending_stiffness = 0.05
mass_per_length = 0.3

[[condition]]
name = "left hand"
s = 0.0
x = 0.0
y = 0.0
z = 0.3
tangent = [1.0, 0.0, 0.0]

[[condition]]
name = "right hand"
s = 0.8
x = 0.6
y = 0.0
z = 0.3
tangent = [1.0, 0.0, 0.0]
"""


def test_two_vr_controllers_each_hold_their_own_grip_and_feel_its_force(browser, tmp_path):
    """Two hands in VR (iwer): each trigger takes the grip nearest it (not the one the
    other hand holds), both move at once and neither is starved (the part ends where
    each hand put its end), and an accurate answer pulses each controller with its own
    hand's force (full at 50 N)."""
    from pliant.viewer.server import Server

    (tmp_path / "two.toml").write_text(TWO_HANDS)
    with Server(tmp_path / "two.toml", port=0, live=True) as server:
        page = browser.new_page(viewport={"width": 1100, "height": 720})
        page.goto(server.url + "?xr=emulate")
        page.wait_for_function(LOADED, timeout=120_000)
        page.click("#VRButton")
        page.wait_for_function("window.pliant.state.xr === true", timeout=30_000)
        device = "window.pliant.xrDevice.controllers"
        start = {}
        for side, grip in (("left", "left hand"), ("right", "right hand")):
            at = page.evaluate(f"window.pliant.state.scene.grips.find(g => g.name === "
                               f"'{grip}').position")
            start[side] = np.array(at)
            xr = page.evaluate("p => window.pliant.worldOf(p)", at)
            page.evaluate(f"p => {device}.{side}.position.set(p[0], p[1], p[2])", xr)
            page.wait_for_timeout(150)
            page.evaluate(f"{device}.{side}.updateButtonValue('trigger', 1)")
        page.wait_for_function("window.pliant.hands.filter(h => h.userData.held).length === 2")
        held = page.evaluate("window.pliant.hands.map(h => h.userData.held.name)")
        assert sorted(held) == ["left hand", "right hand"]
        for _ in range(1, 11):  # both at once: left 3 cm along -x, right 4 cm up (XR's y)
            page.evaluate(f"""(() => {{
                const l = {device}.left.position, r = {device}.right.position;
                l.set(l.x - 0.003, l.y, l.z); r.set(r.x, r.y + 0.004, r.z); }})()""")
            page.wait_for_timeout(60)
        page.wait_for_function("!window.pliant.state.inFlight && !window.pliant.state.queued")
        page.evaluate("document.getElementById('solve').click()")  # (iwer's canvas is over it)
        page.wait_for_function("(() => { const s = window.pliant.state; return s.accurate && "
                               "s.frame && s.accurate.index === s.frame.index && "
                               "!s.frame.pending && s.haptics.length >= 2; })()",
                               timeout=120_000)
        curve = np.array(page.evaluate("window.pliant.state.frame.curve"))
        np.testing.assert_allclose(curve[0], start["left"] + [-0.03, 0.0, 0.0], atol=1e-5)
        np.testing.assert_allclose(curve[-1], start["right"] + [0.0, 0.0, 0.04], atol=1e-5)
        accurate = page.evaluate("window.pliant.state.accurate")
        pulses = page.evaluate("window.pliant.state.haptics")[-2:]
        assert sorted(p["hand"] for p in pulses) == ["left", "right"]
        for pulse in pulses:
            load = next(x for x in accurate["loads"] if x["name"] == pulse["grip"])
            force = float(np.linalg.norm(load["force"]))
            assert force > 0.5  # a 0.8 m hose of 0.3 kg/m weighs 2.4 N
            assert pulse["force"] == pytest.approx(force)
            assert pulse["value"] == pytest.approx(min(force / 50.0, 1.0))
        for side in ("left", "right"):
            page.evaluate(f"{device}.{side}.updateButtonValue('trigger', 0)")
        page.close()


@contextlib.contextmanager
def scene_page(browser, scene: Path):
    """A page on its own server for ``scene``, loaded (the first accurate answer in);
    no page error may have happened by the end."""
    from pliant.viewer.server import Server

    with Server(scene, port=0, live=True) as server:
        page = browser.new_page(viewport={"width": 1100, "height": 720})
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(server.url)
        page.wait_for_function(LOADED, timeout=120_000)
        yield page
        page.close()
    assert not errors, errors


def test_the_page_draws_a_harness_with_its_branches(browser):
    """A harness scene: the accurate answer carries its two branches and the page draws
    each as a tube of its own, where the answer has it (its end at the trunk's end)."""
    harness = Path(__file__).resolve().parents[1] / "examples" / "harness" / "harness_y.toml"
    with scene_page(browser, harness) as page:
        page.wait_for_function("window.pliant.state.accurate.branches.length === 2",
                               timeout=60_000)
        drawn = page.evaluate("""() => ['left branch', 'right branch'].map((n) => {
            const m = window.pliant.world.getObjectByName(n);
            if (!m) return null;
            m.geometry.computeBoundingBox();
            const b = m.geometry.boundingBox;
            return [b.min.toArray(), b.max.toArray()];
        })""")
        trunk_end = page.evaluate("window.pliant.state.accurate.position.at(-1)")
    for box in drawn:
        assert box is not None
        lo, hi = np.array(box)
        assert np.all(lo - 0.01 <= trunk_end) and np.all(trunk_end <= hi + 0.01)


def test_the_page_draws_the_hands_and_the_worker_the_verdict_judged(browser):
    """A scene with a worker and two hands: the verdict carries each hand's envelope and
    the worker's arm to each grip, and the page draws them where the verdict has them
    (the ring round the hand's centre, the forearm out along the approach, the stick
    figure from the feet to the grip)."""
    scene = Path(__file__).resolve().parents[1] / "examples" / "hoses" / "two_hands.toml"
    with scene_page(browser, scene) as page:
        page.wait_for_function("window.pliant.state.accurate.verdict?.worker.length === 2",
                               timeout=60_000)
        verdict = page.evaluate("window.pliant.state.accurate.verdict")
        drawn = page.evaluate("""() => {
            const g = window.pliant.world.getObjectByName('bodies');
            return g.children.map((m) => {
                m.geometry.computeBoundingBox();
                const b = m.geometry.boundingBox;
                return {name: m.name, at: m.position.toArray(), lo: b.min.toArray(),
                        hi: b.max.toArray()};
            });
        }""")
    by_name = {d["name"]: d for d in drawn}
    assert len(verdict["hands"]) == 2 and len(drawn) == 6
    for h in verdict["hands"]:
        ring = by_name[f"hand {h['grip']}"]
        np.testing.assert_allclose(ring["at"], h["centre"], atol=1e-9)
        assert ring["hi"][0] == pytest.approx(h["ring"], rel=1e-6)
        arm = by_name[f"forearm {h['grip']}"]
        middle = np.array(h["centre"]) + 0.5 * h["reach"] * np.array(h["approach"])
        np.testing.assert_allclose(arm["at"], middle, atol=1e-9)
    for w in verdict["worker"]:
        line = by_name[f"worker {w['grip']}"]
        chain = np.array(w["chain"])
        np.testing.assert_allclose(line["lo"], chain.min(axis=0), atol=1e-6)
        np.testing.assert_allclose(line["hi"], chain.max(axis=0), atol=1e-6)


def test_the_page_draws_a_fitted_part_as_the_accurate_answer_has_it(browser):
    """A scene with a flexible part already fitted: each accurate answer carries that
    part's neutral line and the page redraws its obstacle as a tube along it."""
    scene = Path(__file__).resolve().parents[1] / "examples" / "scenes" / "line_over_hose.toml"
    with scene_page(browser, scene) as page:
        page.wait_for_function("window.pliant.state.accurate.fitted.length === 1",
                               timeout=60_000)
        drawn = page.evaluate("""() => {
            const m = window.pliant.world.getObjectByName('coolant hose');
            m.geometry.computeBoundingBox();
            const b = m.geometry.boundingBox;
            return {fitted: m.userData.fitted === true, top: b.max.z,
                    line: window.pliant.state.accurate.fitted[0].position.map((p) => p[2])};
        }""")
    assert drawn["fitted"]
    # The tube's top is its neutral line's highest point plus its radius (12.5 mm).
    assert drawn["top"] == pytest.approx(max(drawn["line"]) + 0.0125, abs=1e-3)


def test_the_page_lists_the_other_shapes_and_takes_the_one_chosen(browser):
    """The paper's case 3 holds its tip where the part can bow either way (two stable
    shapes of equal energy): Other shapes lists both with their stability and energy;
    pointing at a row draws that shape as a dashed line through the same held tip; Use
    on the one not shown makes it the accurate answer the page draws."""
    case3 = Path(__file__).resolve().parents[1] / "examples" / "paper" / "case3.toml"
    with scene_page(browser, case3) as page:
        page.click("#find")
        page.wait_for_function("document.querySelectorAll('#equilibria tr[data-k]').length >= 2",
                               timeout=60_000)
        listed = page.evaluate("window.pliant.state.equilibria")
        assert listed["ok"] and listed["current"]
        assert [o["verdict"] for o in listed["options"][:2]] == ["stable", "stable"]
        assert {o["bows"] for o in listed["options"][:2]} == {"left", "right"}
        shown = page.evaluate("window.pliant.state.accurate.position")
        other = next(k for k, o in enumerate(listed["options"])
                     if np.abs(np.array(o["position"]) - shown).max() > 1e-3)
        page.hover(f"#equilibria tr[data-k='{other}']")
        drawn = page.evaluate("""() => {
            const line = window.pliant.world.getObjectByName('candidate');
            const a = line.geometry.attributes.position;
            return [a.getX(a.count - 1), a.getY(a.count - 1), a.getZ(a.count - 1)];
        }""")
        assert np.abs(np.array(drawn) - shown[-1]).max() < 1e-6  # the same held tip
        page.click(f"#equilibria tr[data-k='{other}'] button")
        page.wait_for_function(f"document.querySelector(\"#equilibria tr[data-k='{other}']\")"
                               ".classList.contains('shown')", timeout=60_000)
        now = page.evaluate("window.pliant.state.accurate.position")
    assert np.abs(np.array(now) - listed["options"][other]["position"]).max() < 1e-9


def test_the_page_sends_only_what_the_protocol_takes(page):
    """The page's protocol module (made from the pydantic models) builds each message and
    throws on a type or a field the server does not take, before anything is sent."""
    page, server, _ = page
    page.goto(server.url)
    page.wait_for_function(LOADED, timeout=120_000)
    checked = page.evaluate("""async () => {
        const p = await import('/static/protocol.js');
        const tried = (f) => { try { f(); return 'sent'; } catch (e) { return e.message; } };
        return {
            move: JSON.parse(p.message('move', {grip: 'hand', position: [0, 0, 0], seq: 1})),
            type: tried(() => p.message('teleport', {})),
            field: tried(() => p.message('move', {grip: 'hand', speed: 3})),
        };
    }""")
    assert checked["move"] == {"v": 1, "type": "move", "grip": "hand",
                               "position": [0, 0, 0], "seq": 1}
    assert "no client message 'teleport'" in checked["type"]
    assert "move has no field 'speed'" in checked["field"]
