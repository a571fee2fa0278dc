"""Flexible parts solved together (``rod3d.coupled``): two cantilevers pressed tip to tip
against the symmetry and a single cantilever under the same load, Newton's third law
and each part's balance, and a scene's fitted hose that gives way under a line, its
clamps taking the push."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.assembly.scenes import load_scene
from pliant.core.equilibrium import potential_energy
from pliant.core.problem import (
    PROBE_SAG,
    WALL_COMPLIANCE,
    Branch,
    Junction,
    Problem,
    SlidingClip,
)
from pliant.errors import ConvergenceError, FileFormatError
from pliant.models import rod3d
from pliant.models.rod3d import coupled, coupled_results, coupled_stability
from pliant.models.rod3d.lowering import lower
from pliant.models.rod3d.solver import Run
from pliant.models.rod3d.stability import metric, stability_of
from pliant.scene.interference import of_equilibrium

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
L, GAP, TILT = 0.5, 0.1, 0.2  # m, m (clamps apart), rad (each clamp turned in)
PART = pl.Part(length=L, bending_stiffness=1.0, outer_diameter=0.01)
SOLVER = rod3d.RodSolver(elements=40)


def cantilevers(tilt: float, parts: tuple[pl.Part, pl.Part] = (PART, PART)) -> list[Problem]:
    """A along +x from the origin and B from (0, GAP, 0), each turned ``tilt`` toward
    the other: past about 0.1 rad their tips meet."""
    out = []
    for name, y, sign, part in (("A", 0.0, 1.0, parts[0]), ("B", GAP, -1.0, parts[1])):
        tangent = (math.cos(tilt), sign * math.sin(tilt), 0.0)
        out.append(Problem(part, (pl.clamp(0.0, (0.0, y, 0.0), tangent=tangent,
                                           normal=(0.0, 0.0, 1.0), name=f"{name} clamp"),),
                           name=name))
    return out


def _pressed_at(tilt: float, elements: int = 40,
                parts: tuple[pl.Part, pl.Part] = (PART, PART)):
    """The two cantilevers turned in from parallel by ``tilt`` (their tips pressing past
    about 0.1 rad), solved together: (coupling, states, mus)."""
    solver = rod3d.RodSolver(elements=elements)
    runs = [Run(lower(p, elements=elements), solver) for p in cantilevers(tilt, parts)]
    starts = [Run(r.rod.retarget(p, elements), solver)
              for r, p in zip(runs, cantilevers(0.0, parts))]
    return coupled.solve_coupled(runs, [r.cold() for r in starts], solver=solver,
                                 start=[r.rod.target for r in starts], held_first=False)


@pytest.fixture(scope="module")
def pressed():
    """The two cantilevers turned in from parallel until they press tip to tip."""
    coupling, states, mus = _pressed_at(TILT)
    return coupled_results.equilibria(coupling, states, mus, ["A", "B"])


def test_equal_and_opposite_and_each_part_balances(pressed):
    a, b = pressed
    fa, fb = a.contacts.force.sum(axis=0), b.contacts.force.sum(axis=0)
    assert np.linalg.norm(fa) > 0.5  # they do press (about 1.3 N)
    np.testing.assert_allclose(fa, -fb, atol=1e-12)
    assert set(a.contacts.obstacle) == {"B"} and set(b.contacts.obstacle) == {"A"}
    for eq, name in ((a, "A clamp"), (b, "B clamp")):
        assert eq.residual < 1e-9
        clamp = eq.loads[name]
        # Forces: the clamp takes the contact; moments about the clamp balance too. Each
        # to what the residual allows: the part's balance is the sum of its 40 elements'
        # equations, each off by at most the residual (relative: forces by EI / L^2,
        # moments by EI / L), a force's lever at most L (a bound that holds wherever
        # Newton's last iterate lands, not one set by its round-off).
        n, ei = 40, PART.bending_stiffness
        np.testing.assert_allclose(clamp.force + eq.contacts.force.sum(axis=0), 0.0,
                                   atol=n * eq.residual * ei / L**2 + 1e-12)
        arm = eq.contacts.point - eq.position[0]
        moment = clamp.moment + np.cross(arm, eq.contacts.force).sum(axis=0)
        np.testing.assert_allclose(moment, 0.0, atol=2 * n * eq.residual * ei / L + 1e-12)


def test_symmetric_and_as_a_single_cantilever_under_that_load(pressed):
    a, b = pressed
    mirror = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(b.position, a.position * mirror + [0.0, GAP, 0.0], atol=1e-9)
    # The tips touch: their centrelines a tube's diameter apart, less the walls' give.
    gap = b.position[-1, 1] - a.position[-1, 1]
    force = np.linalg.norm(a.contacts.force.sum(axis=0))
    assert gap == pytest.approx(0.01 - WALL_COMPLIANCE * force, abs=1e-9)
    # A alone, with B's push as a point load at its tip: the same shape.
    (s,) = a.contacts.s
    single = rod3d.solve(Problem(PART, (cantilevers(TILT)[0].conditions[0],
                                        pl.push(s, force=tuple(a.contacts.force[0]),
                                                name="push")), name="single"),
                         solver=SOLVER)
    assert np.abs(single.position - a.position).max() < 1e-8


def test_tubes_pressed_tip_to_tip_slide_off_past_the_two_spring_threshold():
    """Two round tips pressed together by f are a spring each (a cantilever's tip across
    its plane, k = 3 EI / L^3) joined by the contact, whose force turns with the line
    between the centrelines: a stiffness -f / d for their slip across it (d the
    centrelines' distance). They slide off each other (the coupled system's smallest
    eigenvalue crosses zero) where k - 2 f / d = 0: f = 3 EI d / (2 L^3), 0.12 N here.
    The force where the eigenvalue, interpolated between two tilts either side, crosses
    zero must be that one."""
    points = []
    for tilt in (0.1, 0.11):
        coupling, states, mus = _pressed_at(tilt)
        a, b = coupled_results.equilibria(coupling, states, mus, ["A", "B"])
        force = float(np.linalg.norm(a.contacts.force.sum(axis=0)))
        assert a.stability == b.stability  # one system, one verdict
        points.append((force, a.stability[1]))
    (f0, l0), (f1, l1) = points
    assert l0 > 0.0 > l1  # stable below the threshold, unstable past it
    crossing = f0 + l0 / (l0 - l1) * (f1 - f0)
    d = 0.01 - WALL_COMPLIANCE * crossing  # the tubes' diameters, less the walls' give
    assert crossing == pytest.approx(3.0 * PART.bending_stiffness * d / (2.0 * L**3),
                                     rel=0.02)


PRESSED: list[bool] = []  # each random pair below: solved (True) or a typed error


@settings(max_examples=10, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.floats(0.4, 0.6), st.floats(0.5, 2.0), st.floats(0.5, 2.0),
       st.one_of(st.floats(0.5, 0.85), st.floats(1.15, 2.0)))
def test_random_pairs_pressed_tip_to_tip_follow_the_two_spring_threshold(length, ei_a,
                                                                         ei_b, ratio):
    """Two cantilevers of one length and different stiffnesses, turned in until their
    tips press with ``ratio`` times the force at which two springs (their tips, k = 3 EI
    / L^3) joined by the contact's -f / d lose stability, f* = d k_a k_b / (k_a + k_b).
    The tips overlap by (ratio - 1) d past touching, which sets that force whatever the
    stiffnesses. Below f* (by 15 % or more) the coupled verdict is stable, past it
    unstable; the force is the one aimed at."""
    d = 0.01
    tilt = math.asin((GAP - d + ratio * d) / (2.0 * length))
    parts = tuple(pl.Part(length=length, bending_stiffness=ei, outer_diameter=d)
                  for ei in (ei_a, ei_b))
    try:
        coupling, states, mus = _pressed_at(tilt, elements=24, parts=parts)
    except ConvergenceError:
        PRESSED.append(False)
        return
    PRESSED.append(True)
    k_a, k_b = 3.0 * ei_a / length**3, 3.0 * ei_b / length**3
    threshold = d * k_a * k_b / (k_a + k_b)
    force = float(mus[0].sum()) * coupling.F_ref
    assert force == pytest.approx(ratio * threshold, rel=0.03)
    stable, _ = coupled_stability.coupled_stability(coupling, states, mus)
    assert stable is (ratio < 1.0)


def test_random_pressed_pairs_are_solved_at_least_nine_times_in_ten():
    """The floor of the property above (it runs first: tests keep their file order)."""
    assert len(PRESSED) >= 8
    assert sum(PRESSED) >= 0.9 * len(PRESSED)


def test_pressed_hard_the_tips_are_unstable_and_the_note_says_whose_verdict(pressed):
    a, b = pressed
    assert a.verdict == "unstable" and a.stability == b.stability
    assert any("the verdict is the coupled system's" in n for n in a.notes)


def test_an_eigenvalue_far_below_the_shift_is_still_found(monkeypatch):
    """The shift is an estimate, not a bound: without the contacts' share of it (the
    parts' bound alone, 5.6 N m for the pressed tips) the tips' -42.6 N m lies far below
    it, and the check at a shift four times as large still finds it, the same value."""
    coupling, states, mus = _pressed_at(0.2)
    expected = coupled_stability.coupled_stability(coupling, states, mus)
    monkeypatch.setattr("pliant.models.rod3d.coupled_stability._contact_shift",
                        lambda *args: 0.0)
    stable, value = coupled_stability.coupled_stability(coupling, states, mus)
    assert not stable and expected[1] < -40.0
    assert value == pytest.approx(expected[1], rel=1e-9)


def test_parts_apart_have_each_ones_own_stability():
    """Not touching, the coupled system's smallest eigenvalue is the smaller of the two
    parts' own (``stability_of``): the same metric, in the same units."""
    coupling, states, mus = _pressed_at(0.0)
    assert not np.any(mus[0])
    stable, value = coupled_stability.coupled_stability(coupling, states, mus)
    alone = min(stability_of(run, state)[1] for run, state in zip(coupling.runs, states))
    assert stable and value == pytest.approx(alone, rel=1e-9)


def _line_over_hose(entry: str, elements: int):
    """The example's line carried along its path onto the fitted hose, with ``entry``
    added to the hose's ``[[assembled]]`` table: (the last answer, the solver)."""
    from pliant.assembly.scenes import parse_scene

    path = EXAMPLES / "scenes" / "line_over_hose.toml"
    text = path.read_text(encoding="utf-8").replace(
        'file = "coolant_hose.toml"', f'file = "coolant_hose.toml"\n{entry}')
    scene = parse_scene(text, str(path), path.parent)
    solver = rod3d.RodSolver(elements=elements)
    eq = None
    for problem in [scene.problem, *scene.path]:
        eq = rod3d.solve(problem, warm_start=eq, solver=solver)
    return eq, solver


def _finite_difference_smallest(coupling, states, mus) -> float:
    """The smallest finite eigenvalue (QZ) of the dense pencil J v = lambda M v: J by
    central differences of the coupled residual (each part stepped by its own ``step``,
    the forces between the parts as they are, the touching set held), M each part's
    metric (``stability.metric``) in the first part's length (positions by the lengths'
    ratio cubed, rotations by the ratio) over its EI / L."""
    from scipy.linalg import eig

    loads = [run.rod.target for run in coupling.runs]
    near = [coupling.near(p, states, mu) for p, mu in zip(coupling.pairs, mus)]
    fixed = coupling.touching(coupling.evaluate(states, mus, loads, 1.0, near, False), mus)

    def residual(states, mus):
        ev = coupling.evaluate(states, mus, loads, 1.0, near, False, fixed)
        return np.concatenate([*ev.R, *ev.Rmu])

    columns, eps = [], 1e-6
    for i, run in enumerate(coupling.runs):
        for k in range(run.rod.n):
            du = np.zeros(run.rod.n)
            du[k] = eps
            ahead, behind = list(states), list(states)
            ahead[i], behind[i] = run.step(states[i], du, 1.0), run.step(states[i], -du, 1.0)
            columns.append((residual(ahead, mus) - residual(behind, mus)) / (2 * eps))
    for p, mu in enumerate(mus):
        for k in range(mu.shape[0]):
            ahead, behind = [m.copy() for m in mus], [m.copy() for m in mus]
            ahead[p][k] += eps
            behind[p][k] -= eps
            columns.append((residual(states, ahead) - residual(states, behind)) / (2 * eps))
    J = np.array(columns).T
    masses = []
    for run in coupling.runs:
        rod = run.rod
        primal, weight = metric(rod)
        ratio = rod.length / coupling.runs[0].rod.length
        position = np.isin(np.arange(rod.n), rod.ix[:, None] + np.arange(3))
        masses.append(np.where(primal, weight, 0.0) * np.where(position, ratio**3, ratio)
                      / rod.moment_scale)
    mass = np.concatenate(masses + [np.zeros(mu.shape[0]) for mu in mus])
    lam = eig(J, np.diag(mass), right=False)
    lam = lam[np.isfinite(lam) & (np.abs(lam) < 1e6)]
    assert np.abs(lam.imag).max() < 1e-6
    return float(lam.real.min())


def test_the_coupled_eigenvalue_is_that_of_a_finite_difference_jacobian():
    """The shift-invert on the condensed system against the dense pencil of a
    finite-difference Jacobian: the pressed tips (unstable), and the example's line on
    the fitted hose (12 elements each: parts of different stiffnesses and radii, the
    contact along the hose's curve, stable)."""
    coupling, states, mus = _pressed_at(0.2, elements=6)
    _, value = coupled_stability.coupled_stability(coupling, states, mus)
    assert value < 0.0  # pressed hard: unstable (the test above)
    assert value == pytest.approx(_finite_difference_smallest(coupling, states, mus),
                                  rel=1e-6)
    eq, solver = _line_over_hose("elements = 12", elements=12)
    state = eq.state
    runs = [Run(rod, solver, gauge_quat=g) for rod, g in zip(state.rods, state.gauges)]
    assert runs[0].rod.moment_scale != runs[1].rod.moment_scale  # (different EI / L)
    coupling = coupled.Coupling(runs, list(state.pairs), solver)
    stable, value = coupled_stability.coupled_stability(coupling, list(state.states),
                                                        list(state.mus))
    assert stable and value == pytest.approx(eq.stability[1], rel=1e-12)
    assert value == pytest.approx(
        _finite_difference_smallest(coupling, list(state.states), list(state.mus)),
        rel=1e-6)


@pytest.fixture(scope="module")
def draped():
    """The oil line of the example carried along its path and pulled down onto the
    fitted coolant hose (the last step)."""
    scene = load_scene(EXAMPLES / "scenes" / "line_over_hose.toml")
    eq = None
    for problem in [scene.problem, *scene.path]:
        eq = rod3d.solve(problem, warm_start=eq, solver=rod3d.RodSolver(elements=60))
    return eq


def test_a_fitted_hose_gives_way_and_its_clamps_take_the_push(draped):
    eq = draped
    assert eq.residual < 1e-9
    push = eq.contacts.by_obstacle()["coolant hose"]
    assert push[2] > 5.0  # the hose holds the line up (about 10 N)
    (hose,) = eq.fitted
    rest = rod3d.solved_alone(eq.problem.obstacles[0].fitted)
    # The hose's crest went down (it is no rigid tube) and it feels the line.
    assert rest.position[:, 2].max() - hose.position[:, 2].max() > 1e-3
    on_hose = hose.contacts.by_obstacle()
    np.testing.assert_allclose(on_hose[eq.problem.name], -push, atol=1e-9)
    # The hose balances: its clamps, its weight and the line's push.
    weight = hose.problem.part.mass_per_length * hose.problem.part.length * np.array(
        hose.problem.gravity)
    clamps = sum(load.force for load in hose.loads.values())
    np.testing.assert_allclose(clamps + weight + on_hose[eq.problem.name], 0.0, atol=1e-8)


def test_clearance_to_a_fitted_part_is_measured_as_it_deformed(draped):
    report = of_equilibrium(draped)
    (c,) = [c for c in report.clearances if c.obstacle == "coolant hose"]
    # Touching: within the walls' give under the contact force and the probes' spacing
    # (1 % of the radii's sum: see coupled.probes), not the centimetres the line would be
    # inside the hose at rest.
    force = np.linalg.norm(draped.contacts.by_obstacle()["coolant hose"])
    reach = 0.004 + 0.0125
    assert -WALL_COMPLIANCE * force - PROBE_SAG * reach < c.clearance < 1e-4
    assert not report.penetrations


def test_a_fitted_parts_shape_is_read_from_the_cache_the_second_time(tmp_path,
                                                                      monkeypatch):
    """Reading a scene solves its fitted parts (about a second each, with the search for
    the lowest equilibrium); read again, their shape comes from the disk cache, exactly
    the one solved, and their equilibrium is found only when a part touches them (the
    same one). Another part's file is another key: solved afresh."""
    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    folder = tmp_path / "scene"
    folder.mkdir()
    for name in ("line_over_hose.toml", "coolant_hose.toml"):
        (folder / name).write_text((EXAMPLES / "scenes" / name).read_text())
    first = load_scene(folder / "line_over_hose.toml").problem.obstacles[0]
    again = load_scene(folder / "line_over_hose.toml").problem.obstacles[0]
    assert first.fitted.solved is not None and again.fitted.solved is None
    assert np.array_equal(again.fitted.rest_line, rod3d.solved_alone(first.fitted).position)
    assert np.array_equal(again.mesh.tri, first.mesh.tri)
    assert np.allclose(rod3d.solved_alone(again.fitted).position, first.fitted.rest_line,
                       atol=1e-12)  # found on first use: the same equilibrium
    hose = folder / "coolant_hose.toml"
    hose.write_text(hose.read_text() + "\n# a comment: the same problem\n")
    same = load_scene(folder / "line_over_hose.toml").problem.obstacles[0]
    assert same.fitted.solved is None  # keyed by the problem, not the file's bytes
    hose.write_text(hose.read_text().replace("length = 0.5", "length = 0.51", 1))
    longer = load_scene(folder / "line_over_hose.toml").problem.obstacles[0]
    assert longer.fitted.solved is not None  # another problem: solved afresh
    assert longer.fitted.problem.part.length == 0.51


def test_the_file_reader_leaves_fitted_parts_to_assembly_to_solve(tmp_path, monkeypatch):
    """pliant.io only reads: given a scene with a flexible part already fitted and
    nothing to settle it with, it refuses and names the loader that solves it (even
    when the part's shape is in the disk cache, so the answer never depends on the
    cache); pliant.assembly's loader settles it into an obstacle with its fitted part."""
    from pliant.errors import FileFormatError
    from pliant.io import problem_file

    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    scene = EXAMPLES / "scenes" / "line_over_hose.toml"
    settled = load_scene(scene).problem.obstacles[0]
    assert settled.fitted is not None and settled.fitted.name == "coolant hose"
    with pytest.raises(FileFormatError, match=r"assembled\[0\].*pliant\.assembly\.load_scene"):
        problem_file.load_scene(scene)  # the shape is cached by now: still refused


def test_a_fitted_part_not_touched_stays_a_plain_solve():
    scene = load_scene(EXAMPLES / "scenes" / "line_over_hose.toml")
    eq = rod3d.solve(scene.problem, solver=rod3d.RodSolver(elements=60))
    assert not eq.fitted and "coolant hose" not in eq.contacts.obstacle


def test_parts_that_cannot_be_solved_together_say_so(monkeypatch):
    """No silent fallback: the rigid answer comes with a note naming the part."""
    scene = load_scene(EXAMPLES / "scenes" / "line_over_hose.toml")

    def refuse(*args, **kwargs):
        raise ConvergenceError("refused for the test", residual=1.0)

    monkeypatch.setattr(coupled, "solve_coupled", refuse)
    eq = rod3d.solve(scene.path[-1], solver=rod3d.RodSolver(elements=60))
    assert not eq.fitted and "coolant hose" in eq.contacts.obstacle
    assert any("coolant hose could not be solved together" in n and "held rigid" in n
               for n in eq.notes)


# -- clips that slide and turn ---------------------------------------------------------------
BEAM = pl.Part(length=1.0, bending_stiffness=1.0)
CLIP_AT = (0.6, 0.05, 0.0)  # 5 cm off the clamp's line: the part bends into an S to pass


@pytest.fixture(scope="module")
def slid():
    """A cantilever along +x, its tip pushed down by 2 N, led through a frictionless
    sliding clip 5 cm off its line that holds its direction along +x; the clip starts
    at s = 0.6025 m (just longer than the chord) and the part slides to balance."""
    clip = SlidingClip("clip", 0.6025, CLIP_AT, (1.0, 0.0, 0.0))
    problem = Problem(BEAM, (pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
                                      normal=(0.0, 0.0, 1.0), name="clamp"),
                             pl.push(1.0, force=(0.0, -2.0, 0.0), name="tip")),
                      sliders=(clip,))
    return rod3d.solve(problem, solver=rod3d.RodSolver(elements=100))


def test_a_part_slides_through_a_clip_as_the_2d_model_with_a_free_axial_pin(slid):
    eq = slid
    assert eq.residual < 1e-9
    clip = eq.loads["clip"]
    # The clip holds the part at its point, whatever point of the part is there (to
    # within h^2 kappa = 8e-5 m, h = 1 cm, kappa = 0.8 / m: the clip holds the smooth
    # B-spline of the nodes, not the polyline through them).
    at = np.array([np.interp(clip.s, eq.s, eq.position[:, c]) for c in range(3)])
    np.testing.assert_allclose(at, CLIP_AT, atol=8e-5)
    assert clip.s > math.hypot(0.6, 0.05)  # the S is longer than its chord
    # Balance: clamp, clip and tip.
    np.testing.assert_allclose(eq.loads["clamp"].force + clip.force + eq.loads["tip"].force,
                               0.0, atol=1e-9)
    # The 2D model with the clip as a station at that s, its x free (a pin with a free
    # axial component) and its angle held: the same shape, the clip where it is.
    plane = pl.solve(pl.Problem(BEAM, (pl.clamp(0.0), pl.Condition(
        s=clip.s, name="clip", position=(None, 0.05), angle=0.0),
        pl.push(1.0, force=(0.0, -2.0), name="tip"))))
    assert np.interp(clip.s, plane.s, plane.position[:, 0]) == pytest.approx(0.6, abs=8e-5)
    for c in range(2):
        mine = np.interp(plane.s, eq.s, eq.position[:, c])
        assert np.abs(mine - plane.position[:, c]).max() < 2e-4  # h = 1 cm
    assert clip.force[1] == pytest.approx(plane.loads["clip"].force[1], rel=1e-3)


def test_a_sliding_clip_pushes_along_the_part_by_its_bending_energys_jump(slid):
    """Frictionless, the clip still pushes along the part: by (M+^2 - M-^2) / 2 EI, the
    jump of the bending energy across it (the Eshelby-like force of Bigoni, Dal Corso,
    Bosi and Misseroni, Mech. Mater. 2015), which the 2D pin cannot have."""
    eq = slid
    clip = eq.loads["clip"]
    M = np.linalg.norm(eq.internal_moment, axis=1)
    k = int(np.searchsorted(eq.s, clip.s))  # the first node past the clip

    def side(i, j):  # the moment extrapolated to the clip from two nodes on one side
        return M[i] + (M[j] - M[i]) / (eq.s[j] - eq.s[i]) * (clip.s - eq.s[i])

    before, after = side(k - 3, k - 2), side(k + 1, k + 2)
    eshelby = (after**2 - before**2) / (2.0 * BEAM.bending_stiffness)
    assert abs(eshelby) > 0.01  # not nothing: about 0.03 N here
    assert clip.force[0] == pytest.approx(eshelby, rel=0.02)


def test_a_turning_clip_takes_no_moment_about_its_axis():
    """A clip without a normal lets the part turn in it: a twist at the tip goes to the
    clamp whole."""
    problem = Problem(BEAM, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0),
                 name="clamp"),
        pl.grip(0.5, (0.49, 0.0, 0.02), tangent=(1.0, 0.0, 0.0), name="turning clip"),
        pl.push(1.0, force=(0.0, 0.0, -1.0), moment=(0.3, 0.0, 0.0), name="tip")))
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=60))
    clip = eq.loads["turning clip"]
    axis = eq.frames[int(np.argmin(np.abs(eq.s - 0.5)))][:, 2]
    assert abs(clip.moment @ axis) < 1e-9
    assert np.linalg.norm(clip.moment) > 0.05  # it does hold the direction
    # The whole part balances in moment about the clamp (the twist goes round the clip
    # through the clamp).
    total = np.zeros(3)
    for load in eq.loads.values():
        at = eq.position[int(np.argmin(np.abs(eq.s - load.s)))]
        total += load.moment + np.cross(at, load.force)
    np.testing.assert_allclose(total, 0.0, atol=1e-9)


def test_clip_kinds_in_scene_files():
    text = """
gravity = [0.0, 0.0, -9.81]
[part]
length = 1.0
bending_stiffness = 1.0
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[clip]]
name = "sleeve"
s = 0.6025
position = [0.6, 0.05, 0.0]
axis = [1.0, 0.0, 0.0]
kind = "sliding"
"""
    from pliant.io.problem_file import parse_problem

    problem = parse_problem(text)
    (clip,) = problem.sliders
    assert clip.name == "sleeve" and clip.holds_axis
    assert parse_problem(text.replace('"sliding"', '"ring"')).sliders[0].holds_axis is False
    with pytest.raises(FileFormatError, match=r"clip\[0\]: normal: a turning clip"):
        parse_problem(text.replace('kind = "sliding"', 'kind = "turning"\nnormal = [0, 0, 1]'))
    with pytest.raises(FileFormatError, match=r"sleeve\.s"):
        parse_problem(text.replace("s = 0.6025", "s = 1.5"))


# -- harness junctions ---------------------------------------------------------------------
HALF = pl.Part(length=0.5, bending_stiffness=1.0, mass_per_length=2.0)
DOWN = (0.0, 0.0, -9.81)


def clamp_at(s, x, name):
    return pl.clamp(s, (x, 0.0, 0.0), tangent=(1.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0),
                    name=name)


def test_a_part_cut_in_two_and_joined_again_is_the_part():
    """A beam clamped at both ends under its weight, as two halves joined by a junction
    (the second leaving straight on), is the whole beam with a station where it was cut:
    the same shape to the solver's tolerance, the same reactions."""
    right = Problem(HALF, (clamp_at(0.5, 0.95, "right"),), gravity=DOWN, name="right half")
    joint = Junction("cut", 0.5, (Branch("right half", right, 0, (0.0, 0.0, 1.0), 40),))
    left = Problem(HALF, (clamp_at(0.0, 0.0, "left"),), gravity=DOWN, name="left half",
                   junctions=(joint,))
    eq = rod3d.solve(left, solver=rod3d.RodSolver(elements=40))
    (other,) = eq.branches
    whole = rod3d.solve(Problem(
        pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=2.0),
        (clamp_at(0.0, 0.0, "left"), pl.Condition(s=0.5, name="cut"),
         clamp_at(1.0, 0.95, "right")), gravity=DOWN), solver=rod3d.RodSolver(elements=80))
    joined = np.concatenate([eq.position, other.position[1:]])
    assert np.abs(joined - whole.position).max() < 1e-9
    # Its stability too: the halves together, in the whole's metric (a part 1 m long),
    # have the whole's smallest eigenvalue (the junction's rows and the metric's scales).
    state, solver = eq.state, rod3d.RodSolver(elements=40)
    runs = [Run(rod, solver, gauge_quat=g) for rod, g in zip(state.rods, state.gauges)]
    coupling = coupled.Coupling(runs, list(state.pairs), solver, list(state.sliders),
                                list(state.joints), list(state.pivots))
    together = coupled_stability.coupled_stability(coupling, list(state.states),
                                                   list(state.mus), length=1.0)
    assert together[0] and together[1] == pytest.approx(whole.stability[1], rel=1e-9)
    assert eq.stability == other.stability  # (in the first half's metric)
    for name, part in (("left", eq), ("right", other)):
        np.testing.assert_allclose(part.loads[name].force, whole.loads[name].force,
                                   atol=1e-7)
        np.testing.assert_allclose(part.loads[name].moment, whole.loads[name].moment,
                                   atol=1e-7)


def test_a_y_harness_balances():
    """A trunk clamped at its connector and two branches clamped at their ports, joined
    at a Y-piece: the clamps carry the whole weight, each junction load is equal and
    opposite on the two parts it joins, the two branches mirror each other."""
    twig = pl.Part(length=0.3, bending_stiffness=0.2, mass_per_length=0.2,
                   outer_diameter=0.008)
    branches = []
    for name, side in (("left", 1.0), ("right", -1.0)):
        d = np.array([math.cos(math.pi / 6), -side * 0.5, 0.0])
        port = np.array([0.38, 0.0, -0.01]) + 0.27 * d
        p = Problem(twig, (pl.clamp(0.3, tuple(port), tangent=tuple(d),
                                    normal=(0.0, 0.0, 1.0), name=f"{name} port"),),
                    gravity=DOWN, name=name)
        branches.append(Branch(name, p, 0, (0.0, side * 0.5, math.cos(math.pi / 6)), 30))
    trunk = pl.Part(length=0.4, bending_stiffness=0.5, mass_per_length=0.3,
                    outer_diameter=0.012)
    problem = Problem(trunk, (clamp_at(0.0, 0.0, "connector"),), gravity=DOWN,
                      name="trunk", junctions=(Junction("Y", 0.4, tuple(branches)),))
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=40))
    assert eq.residual < 1e-9
    left, right = eq.branches
    weight = 9.81 * (0.4 * 0.3 + 2 * 0.3 * 0.2)
    clamps = (eq.loads["connector"].force + left.loads["left port"].force
              + right.loads["right port"].force)
    np.testing.assert_allclose(clamps, [0.0, 0.0, weight], atol=1e-9)
    for branch in (left, right):
        name = f"Y: {branch.problem.name}"
        np.testing.assert_allclose(eq.loads[name].force, -branch.loads[name].force,
                                   atol=1e-9)
        # The junction point is one point: the trunk's end is the branch's first end.
        np.testing.assert_allclose(eq.position[-1], branch.position[0], atol=1e-9)
    mirror = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(left.position * mirror, right.position, atol=1e-8)


def test_harness_scene_file_with_junction_and_branches():
    from pliant.assembly.scenes import load_scene

    scene = load_scene(EXAMPLES / "harness" / "harness_y.toml")
    (jn,) = scene.problem.junctions
    assert [b.name for b in jn.branches] == ["left branch", "right branch"]
    eq = rod3d.solve(scene.problem, solver=rod3d.RodSolver(elements=40))
    assert eq.residual < 1e-9 and len(eq.branches) == 2
    assert "left port" in eq.branches[0].loads


def test_a_ring_with_friction_sticks_then_slides_at_mu_times_the_force_across():
    """A ring (holding the position only) with Coulomb's friction mu = 2, the tip pulled
    harder and harder along the part: the part sticks in the ring (the same point of it
    there) while the force along it is below mu times the force across the ring, then
    slides with the force along it at mu times the force across it."""
    def problem(pull, mu):
        ring = SlidingClip("ring", 0.6025, CLIP_AT, (1.0, 0.0, 0.0), holds_axis=False,
                           friction=mu)
        return Problem(BEAM, (pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
                                       normal=(0.0, 0.0, 1.0), name="clamp"),
                              pl.push(1.0, force=(pull, -2.0, 0.0), name="tip")),
                       sliders=(ring,))

    def along_across(eq):
        ring = eq.loads["ring"]
        k = int(np.searchsorted(eq.s, ring.s))
        t = eq.position[k] - eq.position[k - 1]
        t /= np.linalg.norm(t)
        return ring.s, ring.force @ t, float(np.linalg.norm(ring.force[1:]))

    solver = rod3d.RodSolver(elements=60)
    eq = None
    seen = []
    for pull in (0.0, 1.0, 2.0, 3.0):
        eq = rod3d.solve(problem(pull, 2.0), warm_start=eq, solver=solver)
        assert not any("could not" in n for n in eq.notes)
        seen.append(along_across(eq))
    (s0, a0, n0), (s1, a1, n1), (s2, a2, n2), (s3, a3, n3) = seen
    assert abs(a0) < 0.01 * n0  # installed where it slides freely (a cold start)
    assert s1 == s0 and abs(a1) < 2.0 * n1  # sticks
    for _s, a, n in ((s2, a2, n2), (s3, a3, n3)):  # slides, at the friction limit
        assert abs(a) == pytest.approx(2.0 * n, rel=0.01)
    assert s3 < s2 < s1


def test_a_pivoting_clip_takes_no_moment_about_its_pin():
    """A clip that holds the part firmly but turns on a pin: the section's d1 stays
    along the pin, the clip's moment about the pin is zero (not across it), and the
    part balances."""
    text = """
[part]
length = 1.0
bending_stiffness = 1.0
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "tip"
s = 1.0
Fx = 0.0
Fy = 0.5
Fz = -1.0
moment = [0.2, 0.0, 0.0]
[[clip]]
name = "pivot clip"
s = 0.5
position = [0.49, 0.0, 0.03]
axis = [1.0, 0.0, 0.0]
kind = "pivot"
pivot = [0.0, 1.0, 0.0]
"""
    from pliant.io.problem_file import parse_problem

    problem = parse_problem(text)
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=60))
    assert eq.residual < 1e-9
    clip = eq.loads["pivot clip"]
    pin = np.array([0.0, 1.0, 0.0])
    assert abs(clip.moment @ pin) < 1e-9
    assert np.linalg.norm(clip.moment) > 0.1  # it holds the other turns
    np.testing.assert_allclose(eq.frames[int(np.argmin(np.abs(eq.s - 0.5)))][:, 0], pin,
                               atol=1e-9)
    total = np.zeros(3)
    for load in eq.loads.values():
        at = eq.position[int(np.argmin(np.abs(eq.s - load.s)))]
        total += load.moment + np.cross(at, load.force)
    np.testing.assert_allclose(total, 0.0, atol=1e-8)
    with pytest.raises(FileFormatError, match=r"clip\[0\]: pivot"):
        parse_problem(text.replace('pivot = [0.0, 1.0, 0.0]', ''))


def test_friction_between_parts_obeys_coulomb_and_balances():
    """The example's line drawn over the hose with friction 0.5 between them: at every
    contact the force along the surfaces is at most 0.5 times the force across (at the
    limit where it slides), the hose balances with its clamps, its weight and the line's
    push friction included, and the line feels the opposite."""
    eq, _ = _line_over_hose("friction = 0.5", elements=60)
    assert not any("could not" in n for n in eq.notes)
    c = eq.contacts
    on = [i for i, name in enumerate(c.obstacle) if name == "coolant hose"]
    # Friction acts: a static test does not decide stability, and the note says why.
    assert eq.verdict == "undecided"
    assert any("not assessed (friction between the parts acting)" in n for n in eq.notes)
    along = np.linalg.norm(c.friction[on], axis=1)
    across = np.linalg.norm(c.force[on] - c.friction[on], axis=1)
    assert along.max() > 0.1  # friction acts
    assert np.all(along <= 0.5 * across * (1 + 1e-6) + 1e-9)
    (hose,) = eq.fitted
    push = hose.contacts.by_obstacle()[eq.problem.name]
    np.testing.assert_allclose(push, -c.force[on].sum(axis=0), atol=1e-9)
    weight = hose.problem.part.mass_per_length * hose.problem.part.length * np.array(
        hose.problem.gravity)
    np.testing.assert_allclose(sum(v.force for v in hose.loads.values()) + weight + push,
                               0.0, atol=1e-8)


def test_the_evaluation_decides_the_stability_of_steps_solved_together():
    """Every step of the clip scene is solved together (the cable slides through its
    clip): each now has the coupled system's verdict, where the evaluation listed all 31
    as "stability not decided" (unchecked), blaming follower loads or friction."""
    from pliant.assembly.evaluate import evaluate

    ev = evaluate(load_scene(EXAMPLES / "scenes" / "cable_through_clip.toml"))
    assert len(ev.run.steps) == 31
    assert all(step.stable is True for step in ev.run.steps)
    (check,) = [c for c in ev.checks if c.rule == "stability"]
    assert check.zone.value == "green" and check.value == 0.0


def test_the_equilibria_of_parts_solved_together_are_ranked_by_all_their_energy(
        tmp_path, monkeypatch):
    """``examples/scenes/cable_on_fitted_hose.toml``: a cable 0.55 m long clamped at both
    ends 0.5 m apart must bow: down, where it rests on a fitted hose across below it
    (solved together: the hose gives way), or up, free, an arch that gravity would turn
    over (unstable). Both are listed, the one on
    the hose first, and it is the cold solve's answer. The energy that ranks them is
    both parts': the hose's share is its change from untouched, which for a linear
    structure pushed by f from its equilibrium is the work f . delta / 2 (Clapeyron),
    delta the point's own displacement; here within 1e-3 of it. With the hose held
    rigid (the same system constrained) the minimum lies higher."""
    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    problem = load_scene(EXAMPLES / "scenes" / "cable_on_fitted_hose.toml").problem
    solver = rod3d.RodSolver(elements=40)
    found = rod3d.equilibria(problem, solver=solver)
    assert len(found) >= 2
    resting, arch = found[0], next(e for e in found[1:] if e.position[20, 2] > 0.05)
    assert resting.position[20, 2] < -0.05 and set(resting.contacts.obstacle) == {"hose"}
    assert resting.verdict == "stable" and arch.verdict == "unstable"
    energies = [potential_energy(e) for e in found]
    assert energies[0] < potential_energy(arch)
    assert "then solved together with hose" in str(resting.notes[0])
    # The cold solve answers with the same equilibrium.
    cold = rod3d.solve(problem, solver=solver)
    assert np.abs(cold.position - resting.position).max() < 1e-8
    # The hose gave way, balances, and its share of the energy is the contact's work.
    (hose,) = resting.fitted
    rest = rod3d.solved_alone(problem.obstacles[0].fitted)
    assert hose.position[:, 2].min() < rest.position[:, 2].min() - 1e-5
    weight = 0.2 * 0.5 * np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(hose.loads["hose clamp"].force + weight
                               + hose.contacts.force.sum(axis=0), 0.0, atol=1e-8)
    work = 0.0
    for s, f in zip(hose.contacts.s, hose.contacts.force):
        moved = [np.interp(s, hose.s, hose.position[:, k])
                 - np.interp(s, rest.s, rest.position[:, k]) for k in range(3)]
        work += 0.5 * float(f @ moved)
    share = potential_energy(resting) - potential_energy(
        dataclasses.replace(resting, fitted=()))
    assert work > 1e-5 and share == pytest.approx(work, rel=1e-3)
    # The hose held rigid is the same system constrained: its minimum lies higher.
    from pliant.assembly.scenes import parse_scene

    path = EXAMPLES / "scenes" / "cable_on_fitted_hose.toml"
    text = path.read_text(encoding="utf-8").replace(
        'file = "hose_across.toml"', 'file = "hose_across.toml"\nflexible = false')
    rigid = rod3d.solve(parse_scene(text, str(path), path.parent).problem, solver=solver)
    assert potential_energy(rigid) > potential_energy(resting) + 1e-5


def test_a_cold_solve_whose_first_route_cannot_be_solved_together_tries_the_others(
        tmp_path, monkeypatch):
    """Where the first route's answer cannot be solved together (here refused once, for
    the test), a cold solve does not fall back to holding the fitted part rigid while
    another route's answer can be: it answers with the best of those, solved together,
    and says why. Here that is the same cable resting on the hose (the straight route
    reaches it again), to 1e-9 m."""
    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    problem = load_scene(EXAMPLES / "scenes" / "cable_on_fitted_hose.toml").problem
    solver = rod3d.RodSolver(elements=40)
    plain = rod3d.solve(problem, solver=solver)
    real = coupled.solve_coupled
    calls = []

    def refuse_once(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1:
            raise ConvergenceError("refused for the test", residual=1.0)
        return real(*args, **kwargs)

    monkeypatch.setattr(coupled, "solve_coupled", refuse_once)
    eq = rod3d.solve(problem, solver=solver)
    assert eq.fitted and len(calls) >= 2
    assert any("the first route's answer could not be solved together with hose" in n
               for n in eq.notes)
    assert np.abs(eq.position - plain.position).max() < 1e-9
    assert eq.verdict == "stable"


def test_a_harness_s_energy_is_its_branches_too():
    """The beam cut in two and joined (above): the potential energy of the halves solved
    together is the whole beam's, and ``equilibria`` lists that equilibrium."""
    right = Problem(HALF, (clamp_at(0.5, 0.95, "right"),), gravity=DOWN, name="right half")
    joint = Junction("cut", 0.5, (Branch("right half", right, 0, (0.0, 0.0, 1.0), 40),))
    left = Problem(HALF, (clamp_at(0.0, 0.0, "left"),), gravity=DOWN, name="left half",
                   junctions=(joint,))
    whole = rod3d.solve(Problem(
        pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=2.0),
        (clamp_at(0.0, 0.0, "left"), pl.Condition(s=0.5, name="cut"),
         clamp_at(1.0, 0.95, "right")), gravity=DOWN), solver=rod3d.RodSolver(elements=80))
    (eq,) = rod3d.equilibria(left, solver=rod3d.RodSolver(elements=40))
    assert potential_energy(eq) == pytest.approx(potential_energy(whole), rel=1e-9)
    assert "solved together with junction cut" in str(eq.notes[0])


CROSSING_HOSE = """
name = "a soft hose, fitted"
[part]
name = "hose"
length = 0.4
outer_diameter = 0.025
bending_stiffness = {ei!r}
mass_per_length = 0.4
[[condition]]
name = "spigot"
s = 0.0
x = 0.3
y = -0.3
z = -0.0085
tangent = [0.0, 1.0, 0.0]
normal = [0.0, 0.0, 1.0]
"""
CROSSING_LINE = """
name = "an oil line clamped across the fitted hose"
gravity = [0.0, 0.0, -9.81]
[part]
name = "oil line"
length = 0.6005
outer_diameter = 0.008
bending_stiffness = 0.5
mass_per_length = 0.1
[solver]
elements = 60
[[condition]]
name = "clamp A"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[condition]]
name = "clamp B"
s = 0.6005
x = 0.6
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[assembled]]
name = "hose"
file = "hose.toml"
elements = 40
"""


@pytest.mark.parametrize("ei", [0.05, 0.005])
def test_a_line_resting_across_a_soft_hose_is_stable_as_the_hose_alone(tmp_path, ei):
    """Issue 61's oil line (EI 0.5 N m^2, 0.5 mm of slack over 0.6 m, its own weight),
    clamped across a fitted cantilever hose that overlaps it by 8 mm: the line sags onto
    the hose and pushes it down. Two crossing tubes keep their distance as one slides
    along the other, so the frictionless contact neither stiffens nor softens the hose's
    sideways swing under the line: the system's smallest eigenvalue, in the hose's
    metric, is the hose's own alone (its stability test as a single part), to 3 %. It
    was -0.68 m times the contact force (-0.072 N m): each probe, a fixed point of the
    line, softened the hose's slip along the line by -f / d. The answer is the lower of
    the two the line has: bowed up over the hose held rigid costs more energy."""
    (tmp_path / "hose.toml").write_text(CROSSING_HOSE.format(ei=ei))
    (tmp_path / "line.toml").write_text(CROSSING_LINE)
    scene = load_scene(tmp_path / "line.toml")
    eq = rod3d.solve(scene.problem, solver=rod3d.RodSolver(elements=60))
    force = eq.contacts.by_obstacle()["hose"]
    assert force[2] > 0.5 * 5.6 * (ei / 0.05) * 0.008  # it presses the hose down
    assert eq.stable
    # The other equilibrium, bowed up over the hose held rigid, is higher: this is the
    # system's lower one (the "hose giving way").
    from pliant.models.rod3d.solver import _solve

    over = _solve(scene.problem, None, rod3d.RodSolver(elements=60), False, rigid=True)
    assert over.position[:, 2].max() > 0.0 > eq.position[:, 2].min()
    assert potential_energy(eq) < potential_energy(over)
    hose = next(o.fitted for o in scene.problem.obstacles if o.fitted is not None)
    alone = rod3d.solve(hose.problem, solver=rod3d.RodSolver(elements=hose.elements))
    state = eq.state
    solver = rod3d.RodSolver(elements=60)
    coupling = coupled.Coupling([Run(r, solver) for r in state.rods], list(state.pairs),
                                solver, list(state.sliders), list(state.joints),
                                list(state.pivots))
    for run, gauge in zip(coupling.runs, state.gauges):
        run.gauge_quat = gauge
    stable, value = coupled_stability.coupled_stability(
        coupling, list(state.states), list(state.mus), length=hose.problem.part.length)
    assert stable and value == pytest.approx(alone.stability[1], rel=0.03)


SETTLED: list[int] = []  # per tilt below: how many ways of its mode settled


@pytest.mark.parametrize("tilt", [0.102, 0.105, 0.11, 0.112])
def test_tips_pressed_past_their_threshold_in_a_warm_step_slide_off_and_settle(
        tilt, tmp_path, monkeypatch):
    """Issue 60, item 1, for parts solved together: B fitted (a cantilever turned in by
    0.1 rad), A's clamp turned in from 0.095 rad to ``tilt`` in one warm step. The
    followed in-plane answer lies past the tips' threshold (above), unstable; the parts
    leave it along its mode, both ways (``coupled_settling.downhill``). Each way that
    settles is stable, lower than the unstable answer, and balanced: A is a single
    cantilever under its contact forces as point loads (its shape to 1e-7 m). Where
    both ways settle, they are mirror images through the clamps' plane at the same
    energies (the problem is symmetric), and the solve itself answers with one of them,
    said (a jump). The floor of ways settled is the next test's."""
    from pliant.assembly.scenes import settle_fitted
    from pliant.core.events import LeftUnstable
    from pliant.models import clock
    from pliant.models.rod3d import coupled_settling

    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))
    fitted = settle_fitted("B", cantilevers(0.1)[1], 40, True, 0.0)

    def problem(t: float) -> Problem:
        return Problem(PART, cantilevers(t)[0].conditions, name="A", obstacles=(fitted,))

    start = rod3d.solve(problem(0.095), solver=SOLVER)
    assert start.verdict == "stable" and start.fitted
    followed = rod3d.solve(problem(tilt), warm_start=start,
                           solver=dataclasses.replace(SOLVER, settle=False))
    assert followed.verdict == "unstable" and abs(followed.position[:, 2]).max() < 1e-9
    state = followed.state
    coupling = coupled.Coupling([Run(r, SOLVER) for r in state.rods], list(state.pairs),
                                SOLVER, list(state.sliders), list(state.joints),
                                list(state.pivots))
    for run, gauge in zip(coupling.runs, state.gauges):
        run.gauge_quat = gauge
    ways = coupled_settling.downhill(coupling, list(state.states), list(state.mus),
                                     clock.now() + 60.0, L)
    SETTLED.append(len(ways))
    pairs = [coupled_results.equilibria(coupling, s, m, ["A", "B"]) for s, m in ways]
    unstable = followed.energy + followed.fitted[0].energy
    for a, b in pairs:
        assert a.verdict == b.verdict == "stable" and a.energy + b.energy < unstable
        # Each contact's force shared between its element's nodes as the contact's
        # point is, (1 - a) and a: the same loads on the same mesh.
        h = L / SOLVER.elements
        nodal: dict[int, np.ndarray] = {}
        for s, f in zip(a.contacts.s, a.contacts.force):
            e = min(int(s // h), SOLVER.elements - 1)
            share = s / h - e
            nodal[e] = nodal.get(e, 0.0) + (1.0 - share) * f
            nodal[e + 1] = nodal.get(e + 1, 0.0) + share * f
        pushes = tuple(pl.push(float(a.s[k]), force=tuple(f), name=f"push {k}")
                       for k, f in sorted(nodal.items()))
        single = rod3d.solve(Problem(PART, (cantilevers(tilt)[0].conditions[0], *pushes),
                                     name="single"), solver=SOLVER)
        common = np.isclose(single.s[:, None], a.s[None, :], rtol=0.0, atol=1e-12).any(axis=1)
        assert np.abs(single.position[common] - a.position).max() < 1e-7
    if len(pairs) == 2:
        (a1, b1), (a2, b2) = pairs
        assert a1.position[-1, 2] * a2.position[-1, 2] < 0.0  # one tip up, one down
        for one, other in ((a1, a2), (b1, b2)):
            assert np.abs(one.position - other.position * [1.0, 1.0, -1.0]).max() < 1e-7
            assert one.energy == pytest.approx(other.energy, rel=1e-6)
        eq = rod3d.solve(problem(tilt), warm_start=start, solver=SOLVER)
        (note,) = [n for n in eq.notes if isinstance(n, LeftUnstable)]
        assert eq.verdict == "stable" and note.jump and note.eigenvalue < 0.0
        assert min(np.abs(eq.position - a.position).max() for a, _ in pairs) < 1e-9


def test_tips_past_their_threshold_settle_at_least_three_times_in_four():
    """The floor of the cases above (they run first: tests keep their file order): a
    way settles for at least three of the four steps, both ways for at least two."""
    assert len(SETTLED) == 4
    assert sum(n >= 1 for n in SETTLED) >= 3 and sum(n == 2 for n in SETTLED) >= 2
