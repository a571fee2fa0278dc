"""How smoothly the browser environment draws a CAD-sized scene, against the bundled
engine bay, in one run.

    .venv/bin/python benchmarks/browser_scene.py [--million 1.3] [--parts 20] [--seconds 5]

A generated scene of ``--parts`` closed, curved parts (subdivided spheres in a row, the
kind of surface a CAD export gives) of ``--million`` million triangles in all, beside
the cable of the bundled engine bay's size, is served by ``pliant view``'s server and
drawn by Debian's chromium, headless, with software WebGL (SwiftShader: no GPU here).
For each scene it prints the triangles drawn, the time from
opening the page to the first drawn frame with the accurate answer, and the frame rate
while nothing moves (the page's own render loop, counted over ``--seconds``); and, without
the browser, how long the live worker takes to answer a moved hand (the scene's
obstacles are sent to it once).

Five views: the bundled engine bay; the large scene as pliant draws it (decimated to
the default display budget), then opened again (its parse and drawing from the disk
cache), and with ``pliant view --triangles 100000``; and the same scene drawn whole
(budgets lifted), which is what the budget saves. The large scene's files are written
afresh each run, so its first opening pays for parsing and decimating them. Software rendering
makes every figure slow in absolute terms;
the ratios between the three, measured in the same run, are the figures.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-quic"]
LOADED = ("window.pliant && window.pliant.state.accurate && window.pliant.state.frames > 0"
          " && window.pliant.state.rendered > 2")

SCENE = """name = "large scene"
gravity = [0.0, 0.0, -9.81]

[part]
name = "cable"
length = 0.8
bending_stiffness = 0.02
mass_per_length = 0.1
outer_diameter = 0.012

[[condition]]
name = "clamp"
s = 0.0
x = -0.4
y = 0.0
z = 0.35
tangent = [1.0, 0.0, 0.0]

[[condition]]
name = "hand"
s = 0.8
x = 0.35
y = 0.0
z = 0.35
tangent = [1.0, 0.0, 0.0]
"""


def large_scene(folder: Path, million: float, parts: int) -> Path:
    """A scene file with ``parts`` sphere meshes of ``million`` M triangles in all."""
    import numpy as np
    import trimesh

    per = million * 1e6 / parts
    level = max(1, int(round(np.log(per / 20.0) / np.log(4.0))))
    text = SCENE
    for k in range(parts):
        sphere = trimesh.creation.icosphere(subdivisions=level, radius=0.04)
        sphere.apply_translation([-0.45 + 0.9 * k / max(parts - 1, 1), 0.0, 0.2])
        name = f"part_{k:03d}.stl"
        sphere.export(folder / name)
        text += f'\n[[obstacle]]\nname = "part {k}"\nshape = "mesh"\nfile = "{name}"\n'
    path = folder / "large.toml"
    path.write_text(text)
    return path


def measure(browser, scene: Path, seconds: float, display: int | None = None) -> dict:
    from pliant.viewer.server import Server

    with Server(scene, port=0, live=True, display=display) as server:
        page = browser.new_page(viewport={"width": 1280, "height": 720})
        start = time.perf_counter()
        page.goto(server.url)
        page.wait_for_function(LOADED, timeout=600_000)
        first = time.perf_counter() - start
        triangles = page.evaluate(
            "(() => { let n = 0; window.pliant.world.traverse(o => { if (o.isMesh && "
            "o.geometry.index) n += o.geometry.index.count / 3; }); return n; })()")
        before = page.evaluate("window.pliant.state.rendered")
        time.sleep(seconds)
        frames = page.evaluate("window.pliant.state.rendered") - before
        page.close()
    return {"triangles": int(triangles), "first": first, "fps": frames / seconds}


def live_round_trip(scene: Path, moves: int = 4) -> tuple[float, float]:
    """(first, median later) seconds from sending a pose to the live worker to its
    accurate answer, the hand moved 2 mm each time: what a drag waits for."""
    import statistics
    from dataclasses import replace

    from pliant.assembly.scenes import load_scene
    from pliant.session.accurate import ProcessExecutor

    problem = load_scene(scene).problem
    hand = problem.conditions[-1].name
    executor = ProcessExecutor(elements=60)
    times = []
    try:
        for k in range(moves):
            moved = problem.with_conditions(
                replace(c, position=tuple(x + 0.002 * k for x in c.position))
                if c.name == hand else c for c in problem.conditions)
            start = time.perf_counter()
            executor.submit(k, moved)
            executor.wait(timeout=600)
            times.append(time.perf_counter() - start)
    finally:
        executor.close()
    return times[0], statistics.median(times[1:])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--million", type=float, default=1.3)
    parser.add_argument("--parts", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    from playwright.sync_api import sync_playwright

    from pliant.io import mesh_export

    folder = Path(tempfile.mkdtemp())
    large = large_scene(folder, args.million, args.parts)
    rows = {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=ARGS, headless=True)
        rows["engine bay (bundled)"] = measure(
            browser, ROOT / "examples" / "scenes" / "engine_bay.toml", args.seconds)
        rows["large, default budget"] = measure(browser, large, args.seconds)
        rows["the same, opened again"] = measure(browser, large, args.seconds)
        rows["large, --triangles 100000"] = measure(browser, large, args.seconds, 100_000)
        per_part = mesh_export.DISPLAY_FACES
        mesh_export.DISPLAY_FACES = 10 ** 9
        try:
            rows["large, drawn whole"] = measure(browser, large, args.seconds, 10 ** 9)
        finally:
            mesh_export.DISPLAY_FACES = per_part
        browser.close()
    live = {"engine bay (bundled)": live_round_trip(
        ROOT / "examples" / "scenes" / "engine_bay.toml"), "large": live_round_trip(large)}
    shutil.rmtree(folder, ignore_errors=True)
    base = rows["engine bay (bundled)"]["fps"]
    print(f"{args.million:g} M triangles in {args.parts} parts; software WebGL, "
          f"{args.seconds:g} s idle each:")
    for name, r in rows.items():
        print(f"  {name:26s} {r['triangles']:>9,} triangles drawn, first frame "
              f"{r['first']:6.1f} s, {r['fps']:5.1f} frames/s ({r['fps'] / base:.2f} of "
              "the engine bay's)")
    for name, (first, later) in live.items():
        print(f"  live solve round trip, {name}: first {first:.2f} s, then {later:.3f} s a move")


if __name__ == "__main__":
    main()
