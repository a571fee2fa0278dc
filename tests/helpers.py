"""Shared test problems."""

from __future__ import annotations

import shutil
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path

import numpy as np

import pliant as pl
from pliant.io.problem_file import load_problem

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@lru_cache(maxsize=1)
def zoo() -> dict[str, pl.Problem]:
    """A spread of well-posed 2D problems: the paper's cases and everyday variants."""
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3)
    curved = pl.Part(length=1.0, bending_stiffness=1.0,
                     rest_curvature=((0.0, 2.0), (0.5, -1.0), (1.0, 0.0)))
    unit = pl.Part(length=1.0, bending_stiffness=1.0)
    problems = {f"case{i}": load_problem(EXAMPLES / "paper" / f"case{i}.toml")
                for i in (1, 2, 3)}
    problems["gravity grip"] = pl.Problem(
        hose, (pl.clamp(0.0), pl.grip(0.6, position=(0.5, -0.1), name="hand")),
        gravity=(0.0, -9.81))
    problems["pre-curved pin"] = pl.Problem(
        curved, (pl.pin(0.0), pl.grip(1.0, position=(0.6, 0.3), name="hand")))
    problems["two hands, free ends"] = pl.Problem(
        hose, (pl.grip(0.2, position=(0.0, 0.0), angle=0.3, name="left"),
               pl.grip(0.85, position=(0.45, 0.1), name="right")), gravity=(0.0, -9.81))
    problems["compressed cantilever"] = pl.Problem(
        unit, (pl.clamp(0.0), pl.push(1.0, force=(-30.0, 3.0), name="tip")))
    problems["follower and moment"] = pl.Problem(
        unit, (pl.clamp(0.0, angle=0.4), pl.push(0.4, moment=-2.0, name="twist"),
               pl.push(1.0, force=(1.0, 4.0), follower=True, name="tip")))
    return problems


def cli(*args: str):
    """Run ``pliant ARGS`` in this process (the subprocess path, with its start-up and
    one-line errors, is tested in test_cli.py): (returncode, stdout, stderr) like
    subprocess.run's result, without a new interpreter's seconds of imports."""
    from types import SimpleNamespace

    from typer.testing import CliRunner

    from pliant.cli.app import app

    result = CliRunner().invoke(app, [str(a) for a in args])
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return SimpleNamespace(returncode=result.exit_code, stdout=result.stdout,
                           stderr=result.stderr)


def shooting_jacobians(low, z, mesh) -> tuple:
    """(the shooting's Jacobian at z, its central differences) for a 2D lowering."""
    _, jac = low.shoot(z, low.target, mesh)
    fd = np.empty_like(jac)
    for j in range(low.nz):
        h = 1e-6 * max(1.0, abs(z[j]))
        zp, zm = z.copy(), z.copy()
        zp[j] += h
        zm[j] -= h
        rp, _ = low.shoot(zp, low.target, mesh, want_jac=False)
        rm, _ = low.shoot(zm, low.target, mesh, want_jac=False)
        fd[:, j] = (rp - rm) / (2 * h)
    return jac, fd


def precurved_3d() -> pl.Problem:
    """A pre-curved part held by its axis at both ends where a cold solve's first route
    found a stable equilibrium of 11.47 J and another of 9.85 J exists."""
    part = pl.Part(1.0, 1.0, rest_curvature=-1.8746682220224526,
                   rest_curvature_2=-2.110183111379974)
    return pl.Problem(part, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0)),
        pl.grip(1.0, (0.037373700440417025, 0.428805391043273, -0.09993627965470883),
                tangent=(0.11971269704277052, 0.46351305555694045, -0.877966125482649),
                name="hand")))


def balance_3d(eq) -> tuple[np.ndarray, np.ndarray]:
    """Net force and moment (about the origin) of loads, reactions and the weight, lumped
    at the nodes as the model applies it."""
    problem = eq.problem
    weight = problem.part.mass_per_length * np.asarray(problem.gravity)
    h = np.diff(eq.s)
    lumped = np.zeros_like(eq.position)
    lumped[:-1] += 0.5 * h[:, None] * weight
    lumped[1:] += 0.5 * h[:, None] * weight
    force = lumped.sum(axis=0) + sum(ld.force for ld in eq.loads.values())
    moment = np.cross(eq.position, lumped).sum(axis=0)
    for ld in eq.loads.values():
        i = int(np.argmin(np.abs(eq.s - ld.s)))
        moment += np.cross(eq.position[i], ld.force) + ld.moment
    return force, moment


def shape_at(eq, s: np.ndarray) -> np.ndarray:
    """A 2D equilibrium's position at arc lengths s [m], read between its samples by a
    cubic Hermite spline on their tangents (error like h^4 / R^3): two answers on
    different shooting intervals are sampled at different points."""
    from scipy.interpolate import CubicHermiteSpline

    grid, first = np.unique(eq.s, return_index=True)  # a station's row comes twice
    tangent = np.column_stack([np.cos(eq.angle[first]), np.sin(eq.angle[first])])
    return CubicHermiteSpline(grid, eq.position[first], tangent)(s)


def hand_held_hose(at: tuple[float, float, float], tangent: tuple[float, float, float],
                   od: float = 0.016) -> str:
    """The [part] and the hand of a scene file: an EPDM hose 0.6 m long (``od`` [m]
    across) held by one hand at its middle, at ``at`` along ``tangent``."""
    x, y, z = at
    return f"""
[part]
name = "hose"
length = 0.6
outer_diameter = {od}
inner_diameter = 0.010
min_bend_radius = 0.05
[part.material]
name = "EPDM"
youngs_modulus = 8.0e6
density = 1150.0
poisson_ratio = 0.49

[[condition]]
name = "hand"
hand = true
s = 0.3
x = {x}
y = {y}
z = {z}
tangent = {list(tangent)}
normal = [0.0, 0.0, 1.0]
"""


# A line from a clip to a hand in one vertical plane, lowered onto a boss (its port)
# below the hand: x, y the boss; yc the clip; ys the hand at the start; the path's steps.
LINE_ONTO_BOSS = """
name = "line down onto a boss"
gravity = [0.0, 0.0, -9.81]
[part]
name = "line"
length = 0.40
outer_diameter = 0.008
bending_stiffness = 0.02
mass_per_length = 0.05
min_bend_radius = 0.03
[solver]
elements = 16
[[port]]
name = "boss"
position = [{x}, {y}, 0.33]
axis = [0.0, 0.0, 1.0]
[[condition]]
name = "clip"
s = 0.0
x = {x}
y = {yc}
z = 0.31
tangent = [0.0, -1.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "hand"
s = 0.40
x = {x}
y = {ys}
z = 0.56
tangent = [0.0, -1.0, 0.0]
[path]
grip = "hand"
waypoints = [[{x}, {y}, 0.48], [{x}, {y}, 0.33]]
tangents = [[0.0, -0.5, -1.0], [0.0, 0.0, -1.0]]
steps = {steps}
"""


def straight_harness(nodes: dict[str, tuple[float, float, float]],
                     segments: list[tuple], held: list[str], *,
                     wire: tuple[float, float, float] = (2e-3, 5e-3, 0.02),
                     clips: dict[str, str] | None = None):
    """A harness of straight-designed segments (no centre curves) carrying one wire
    (outside diameter [m], bend radius [m], mass [kg/m]; 1 mm2), with a placed connector
    at each ``held`` node. ``segments``: (id, start node, end node, length [m]), with
    optionally a fifth item, ((fixing id, location as a fraction), ...); ``clips``:
    each fixing's id and name."""
    from pliant.core.harness import (
        UNCLAMPED,
        Connector,
        Fixing,
        FixingPlace,
        Harness,
        HarnessNode,
        HarnessSegment,
        Placement,
        Wire,
        WireType,
    )

    diameter, bend_radius, mass = wire
    wire_type = WireType("T", "T1", "test wire", diameter, 1e-6, bend_radius, mass)
    segs = {s[0]: HarnessSegment(s[0], s[0], s[1], s[2], s[3], (), fixings=tuple(
        FixingPlace(f, w) for f, w in (s[4] if len(s) > 4 else ()))) for s in segments}
    connectors = {f"C{n}": Connector(f"C{n}", f"C{n}", "", "",
                                     Placement(nodes[n], (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)), n)
                  for n in held}
    fixings = {f: Fixing(f, name, "", "", "clip") for f, name in (clips or {}).items()}
    return Harness("test", "", "test", "2.4", UNCLAMPED,
                   {n: HarnessNode(n, n, p) for n, p in nodes.items()}, segs,
                   {"T": wire_type}, {"W": Wire("W", "W", "T", None, tuple(segs))}, fixings,
                   connectors, {})


CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


@contextmanager
def offline_report(path: Path):
    """A report opened in headless chromium (Debian's), its page: checked to have
    fetched nothing but itself (a report opens offline)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=[
            "--no-sandbox", "--disable-gpu", "--disable-background-networking"])
        page = browser.new_page()
        fetched: list[str] = []
        page.on("request", lambda r: fetched.append(r.url))
        page.goto(path.as_uri())
        assert fetched == [path.as_uri()]  # one file: nothing else is fetched
        try:
            yield page
        finally:
            browser.close()


def view_data(page) -> dict:
    """The data of the page's first 3D view (``cli.view3d``)."""
    import json

    return json.loads(page.inner_text("figure.view3d script[type='application/json']"))


def drawn_in_view(page, points, colour: str, step: int | None = None) -> int:
    """How many of ``points`` (n, 3) [m] the report's 3D view (``cli.view3d``, the
    page's first) draws in ``colour`` (within 3 px and 40 of each channel, where the
    point projects), after showing ``step`` where given."""
    rgb = [int(colour[i:i + 2], 16) for i in (1, 3, 5)]
    return page.evaluate("""([points, rgb, step]) => {
        const root = document.querySelector("figure.view3d"), view = window.pliantViews[root.id];
        if (step !== null) view.show(step);
        const g = root.querySelector("canvas").getContext("2d");
        let hits = 0;
        for (const p of points) {
            const [x, y] = view.project(p), px = g.getImageData(Math.round(x) - 3,
                Math.round(y) - 3, 7, 7).data;
            for (let i = 0; i < px.length; i += 4)
                if (px[i + 3] > 200 && Math.abs(px[i] - rgb[0]) < 40 &&
                    Math.abs(px[i + 1] - rgb[1]) < 40 && Math.abs(px[i + 2] - rgb[2]) < 40) {
                    hits++; break; }
        }
        return hits; }""", [np.asarray(points, float).tolist(), rgb, step])


def localized_helix(bending: float = 1.345, twisting: float = 0.789, length: float = 1.0,
                    slack: float = 0.03, turns: int = 27, points: int = 20001):
    """PyElastica's localized helical buckling case (Gazzola et al. 2018, section 3.4.1)
    in closed form, computed here: the end moment M [N m] and tension T [N] from van der
    Heijden, Thompson et al.'s clamped-rod equations (Writhing instabilities of twisted
    rods, 2001, eqs 14-15: d = sqrt(16/t (1 - m^2/(4t))), R = m/gamma +
    4 acos(m/(2 sqrt t)), in m = M L / B, t = T L^2 / B), solved by fsolve, and the
    localized helix (van der Heijden, Neukirch, Goss and Thompson 2003, eqs 27 and 52)
    as (points, 3) [m] from the origin, its axis along z. (curve, M, T, its largest
    distance from the axis [m])."""
    import math

    from scipy.optimize import fsolve

    gamma = twisting / bending
    m, t = fsolve(lambda v: [math.sqrt(16.0 / v[1] * (1.0 - v[0] ** 2 / (4.0 * v[1])))
                             - slack, v[0] / gamma + 4.0 * math.acos(v[0] / (2.0 * math.sqrt(
                                 v[1]))) - turns * 2.0 * math.pi], [100.0, 3000.0],
                  xtol=1e-13)
    moment, tension = m * bending / length, t * bending / length**2
    tt = tension * length**2 / (4.0 * math.pi**2 * bending)
    mz = moment * length / (2.0 * math.pi * bending)
    root = math.sqrt(4.0 * tt - mz * mz)
    u = np.linspace(-0.5, 0.5, points)
    amplitude = root / (2.0 * math.pi * tt)
    envelope = amplitude / np.cosh(math.pi * u * root)
    curve = length * np.column_stack([envelope * np.sin(mz * math.pi * u),
                                      -envelope * np.cos(mz * math.pi * u),
                                      u - amplitude * np.tanh(math.pi * u * root)])
    return curve - curve[0], moment, tension, amplitude * length
