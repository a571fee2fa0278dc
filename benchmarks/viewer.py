"""Benchmark of the browser environment's server side and its latency, in one run.

    .venv/bin/python benchmarks/viewer.py

On the bundled engine-bay scene (80 elements, 5 obstacles, one a 1,800-triangle mesh):
(a) server-side cost of one frame: a grip move through the real-time model with contact,
    its curvature and interference, and the JSON message, split into those parts;
(b) server-side cost of one accurate update: the warm-started 3D solve with contact (as
    the worker runs it) and its message (loads, contacts, interference, warnings);
(c) the latency from a drag event to its frame over the websocket (a loopback client
    that sends a move and waits for the frame), against a display's frame budget
    (60 Hz: 16.7 ms; a VR headset at 90 Hz: 11.1 ms);
(d) where Debian's chromium is installed: in the page itself, from the drag's
    ``objectChange`` to the frame's arrival (Playwright drives the mouse).
Timings are machine-dependent; the ratios to the display budgets are the figures.
"""

from __future__ import annotations

import json
import shutil
import statistics
import time
from pathlib import Path

import numpy as np

from pliant.viewer import protocol as P
from pliant.viewer.server import Server
from pliant.viewer.state import ViewerState

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "examples" / "scenes" / "engine_bay.toml"
BUDGET_60, BUDGET_90 = 1e3 / 60, 1e3 / 90


def poses(n: int) -> list[list[float]]:
    """A hand moving 8 cm and back round its start pose, in n steps."""
    t = np.linspace(0.0, 2.0 * np.pi, n)
    return [[0.55 + 0.04 * np.sin(a), -0.12 + 0.04 * (1 - np.cos(a)), 0.35 + 0.02 * np.sin(2 * a)]
            for a in t]


def move(k: int, position) -> str:
    return json.dumps({"v": 1, "type": "move", "grip": "hand", "seq": k,
                       "position": list(position), "tangent": [0.0, 0.0, 1.0]})


def median_ms(values) -> float:
    return 1e3 * statistics.median(values)


def server_side() -> None:
    state = ViewerState(SCENE.relative_to(SCENE.parent), SCENE.parent, live=False)
    state.session.distance_tolerance = 1e9  # frames only: no accurate solve in (a)
    state.session.length_tolerance = 1e9
    state.handle(P.parse('{"v": 1, "type": "hello"}'))
    totals, realtime, curvature_interference, dump = [], [], [], []
    from pliant.session import GripEvent

    for k, position in enumerate(poses(200)):
        start = time.perf_counter()
        message = P.parse(move(k, position))
        frame = state.session.apply(GripEvent("hand", position=tuple(position),
                                              tangent=(0.0, 0.0, 1.0)))
        mid = time.perf_counter()
        reply = state._frame_message(frame, message.seq)
        mid2 = time.perf_counter()
        P.dump(reply)
        end = time.perf_counter()
        totals.append(end - start)
        realtime.append(mid - start)
        curvature_interference.append(mid2 - mid)
        dump.append(end - mid2)
    print("(a) one frame, server side (median of 200 moves):")
    print(f"    real-time model with contact   {median_ms(realtime):6.2f} ms")
    print(f"    curvature and interference     {median_ms(curvature_interference):6.2f} ms")
    print(f"    JSON message                   {median_ms(dump):6.2f} ms")
    print(f"    total                          {median_ms(totals):6.2f} ms "
          f"({median_ms(totals) / BUDGET_60:.2f} of a 60 Hz frame, "
          f"{median_ms(totals) / BUDGET_90:.2f} of a 90 Hz one)")
    # (b) accurate updates along the same poses, warm-started as the worker does.
    from pliant.session.accurate import AccurateSolver

    solver = AccurateSolver(elements=state.scene.solver.elements)
    solver.solve(0, state.session.problem)
    solves, messages = [], []
    for k, position in enumerate(poses(40)):
        problem = state.session.problem.with_conditions(
            c if c.name != "hand" else type(c)(s=c.s, name=c.name, position=tuple(position),
                                               tangent=(0.0, 0.0, 1.0))
            for c in state.session.problem.conditions)
        result = solver.solve(k + 1, problem)
        start = time.perf_counter()
        P.dump(state._accurate(result))
        messages.append(time.perf_counter() - start)
        solves.append(result.solve_seconds)
    print("(b) one accurate update (median of 40 poses, warm-started):")
    print(f"    3D solve with contact, stability  {median_ms(solves):6.2f} ms")
    print(f"    its message                       {median_ms(messages):6.2f} ms")
    print(f"    the frame is {median_ms(solves) / median_ms(totals):.0f}x cheaper than an "
          "accurate update: why the real-time model answers the drag")
    state.close()


def websocket_latency() -> None:
    from websockets.sync.client import connect

    with Server(SCENE, port=0, live=True) as server, \
            connect(f"ws://127.0.0.1:{server.port}/ws", open_timeout=120) as ws:
        ws.send('{"v": 1, "type": "hello"}')
        while json.loads(ws.recv(timeout=120))["type"] != "frame":
            pass
        times = []
        for k, position in enumerate(poses(200), start=1):
            start = time.perf_counter()
            ws.send(move(k, position))
            while True:
                reply = json.loads(ws.recv(timeout=60))
                if reply["type"] == "frame" and reply["seq"] == k:
                    break
            times.append(time.perf_counter() - start)
        accurate = []
        ws.send('{"v": 1, "type": "solve"}')
        deadline = time.perf_counter() + 60
        while time.perf_counter() < deadline and not accurate:
            reply = json.loads(ws.recv(timeout=60))
            if reply["type"] == "accurate":
                accurate.append(reply["solve_seconds"])
    print("(c) drag event to frame over the websocket (loopback, median of 200, live "
          "worker solving beside it):")
    print(f"    {median_ms(times):.2f} ms (95th percentile "
          f"{1e3 * float(np.percentile(times, 95)):.2f} ms): "
          f"{median_ms(times) / BUDGET_60:.2f} of a 60 Hz frame, "
          f"{median_ms(times) / BUDGET_90:.2f} of a 90 Hz one")


def browser_latency() -> None:
    chromium = shutil.which("chromium")
    if chromium is None:
        print("(d) skipped: Debian's chromium is not installed")
        return
    from playwright.sync_api import sync_playwright

    args = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader", "--disable-background-networking",
            "--disable-component-update", "--disable-sync", "--no-first-run"]
    with Server(SCENE, port=0, live=True) as server, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=args, headless=True)
        page = browser.new_page(viewport={"width": 1100, "height": 720})
        page.goto(server.url)
        page.wait_for_function("window.pliant && window.pliant.state.accurate && "
                               "window.pliant.state.frames > 0", timeout=120_000)
        xy = page.evaluate("window.pliant.gripScreen('hand')")
        page.mouse.move(xy["x"], xy["y"])
        page.mouse.down()
        for k in range(1, 41):
            page.mouse.move(xy["x"] + 2 * k, xy["y"] - (k % 10))
            page.wait_for_timeout(16)
        page.mouse.up()
        page.wait_for_function("!window.pliant.state.inFlight")
        latency = page.evaluate("window.pliant.state.latency")
        browser.close()
    print(f"(d) in headless chromium (software WebGL), drag to frame: median "
          f"{statistics.median(latency):.1f} ms over {len(latency)} moves (the page keeps one "
          "move in flight; its render loop in software WebGL sets the pace)")


if __name__ == "__main__":
    server_side()
    websocket_latency()
    browser_latency()
