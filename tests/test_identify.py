"""Stiffness identification: closed forms, an independent integration, interval coverage,
the refusal of what a test cannot determine, and the test files."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

import pliant as pl
from pliant.core.measurement import Deflection, Shape, StiffnessTest, ThreePointBending, Twist
from pliant.errors import FileFormatError, InputError
from pliant.identify import (
    NotIdentifiableError,
    identify,
    project,
    support_force,
)
from pliant.io.identify_file import load_test, parse_table, parse_test

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "identify"


def cantilever(ei: float, tip: float = 0.2, mass: float = 0.05) -> pl.Problem:
    part = pl.Part(0.5, ei, mass_per_length=mass)
    return pl.Problem(part, (pl.clamp(0.0), pl.push(0.5, (0.0, -tip), name="tip")),
                      gravity=(0.0, -9.81))


def shape_points(problem: pl.Problem, n: int = 50) -> np.ndarray:
    eq = pl.solve(problem)
    s = np.linspace(0.02, problem.part.length, n)
    # points of the solver's curve itself (its Hermite interpolant), not a chord
    pts, _ = project(np.column_stack([np.interp(s, eq.s, eq.position[:, k])
                                      for k in range(2)]), eq.s, eq.position, eq.tangent)
    return pts


def test_projection_onto_a_sampled_circle_is_the_radial_distance():
    R = 0.3
    s = np.linspace(0.0, 0.5 * math.pi * R, 33)
    nodes = R * np.column_stack([np.cos(s / R), np.sin(s / R)])
    tangents = np.column_stack([-np.sin(s / R), np.cos(s / R)])
    rng = np.random.default_rng(3)
    phi = rng.uniform(0.05, 0.5 * math.pi - 0.05, 200)
    r = R + rng.uniform(-0.05, 0.05, 200)
    points = r[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])
    nearest, at = project(points, s, nodes, tangents)
    assert np.abs(np.linalg.norm(points - nearest, axis=1) - np.abs(r - R)).max() < 2e-8
    assert np.abs(at - R * phi).max() < 1e-7


def test_three_point_bending_small_deflection_is_the_beam_formula():
    """P = 48 EI d / span^3 as d / span -> 0 (EI = 1), the departure from it of second
    order in d (the geometric nonlinearity): halving d quarters it."""
    departure = [2.0 * support_force(0.25, 0.1, d, "t") / (48.0 * d / 0.2 ** 3) - 1.0
                 for d in (1e-4, 2e-4, 4e-4)]
    assert abs(departure[0]) < 1e-5
    assert departure[1] / departure[0] == pytest.approx(4.0, rel=0.02)
    assert departure[2] / departure[1] == pytest.approx(4.0, rel=0.02)


def test_three_point_bending_large_deflection_against_an_independent_integration():
    """The half part clamped level at the middle, its contact where the support's force
    is normal to it: shooting with scipy's solve_ivp on EI theta'' = F_x sin - F_y cos,
    unknowns (contact arc, force, contact angle, clamp curvature)."""
    a, half, delta = 0.1, 0.25, 0.06
    load = 2.0 * support_force(half, a, delta, "t")

    def shoot(u):
        ell, force, angle, k0 = u
        fx, fy = -force * math.sin(angle), force * math.cos(angle)

        def rhs(_s, y):
            return [math.cos(y[2]), math.sin(y[2]), y[3],
                    fx * math.sin(y[2]) - fy * math.cos(y[2])]

        end = solve_ivp(rhs, (0.0, ell), [0.0, 0.0, 0.0, k0], rtol=1e-12,
                        atol=1e-14).y[:, -1]
        return [end[0] - a, end[1] - delta, end[2] - angle, end[3]]

    guess = [a * 1.1, 3.0 * delta / a ** 3, 1.5 * delta / a, 3.0 * delta / a ** 2]
    ell, force, angle, _ = fsolve(shoot, guess, xtol=1e-13)
    assert np.abs(shoot([ell, force, angle, _])).max() < 1e-9
    assert ell < half
    assert load == pytest.approx(2.0 * force * math.cos(angle), rel=1e-7)
    assert load < 48.0 * delta / (2 * a) ** 3  # softer than the small-deflection line


def test_three_point_bending_identifies_the_stiffness_that_made_the_curve():
    part = pl.Part(0.3, 0.02)
    d = np.linspace(2e-3, 40e-3, 8)
    load = np.array([0.037 * 2.0 * support_force(0.15, 0.1, float(x), "t") for x in d])
    problem = pl.Problem(part, (pl.clamp(0.0),))
    result = identify(StiffnessTest(problem, ("bending_stiffness",),
                                    (ThreePointBending(0.2, d, load),)))
    assert result.value("bending_stiffness") == pytest.approx(0.037, rel=1e-9)


def test_twist_identifies_the_torsional_stiffness_of_m_equal_gj_phi_over_l():
    problem = pl.Problem(pl.Part(0.3, 0.02), (pl.clamp(0.0, (0.0, 0.0, 0.0)),))
    angle = np.radians([45.0, 90.0, 180.0, 270.0])
    moment = 0.0123 * angle / 0.25
    result = identify(StiffnessTest(problem, ("torsional_stiffness",),
                                    (Twist(0.25, angle, moment),)))
    # the discrete rod's twist is second order; the model takes 60 elements per radian
    assert result.value("torsional_stiffness") == pytest.approx(0.0123, rel=1e-4)


def test_a_shape_identifies_the_stiffness_from_a_guess_many_times_off():
    truth = cantilever(0.021)
    points = shape_points(truth)
    test = StiffnessTest(cantilever(0.2), ("bending_stiffness",), (Shape(points),))
    result = identify(test)
    assert result.value("bending_stiffness") == pytest.approx(0.021, rel=1e-6)
    assert result.fitted[0].rms < 1e-7


def test_shape_intervals_cover_the_truth_at_their_stated_rate():
    """40 noisy photographs: the 95 % interval holds the truth in about 38; the
    standardised errors have unit variance (too wide intervals fail as surely as too
    narrow ones)."""
    truth = cantilever(0.021)
    clean = shape_points(truth, 30)
    guess = cantilever(0.03)
    inside, z = 0, []
    for seed in range(40):
        noisy = clean + np.random.default_rng(seed).normal(0.0, 1e-3, clean.shape)
        result = identify(StiffnessTest(guess, ("bending_stiffness",), (Shape(noisy),)))
        e = result.estimates[0]
        inside += e.low <= 0.021 <= e.high
        z.append(math.log(e.value / 0.021) / e.relative_error)
    assert inside >= 34  # P(fewer | 95 %) < 0.5 %
    assert 0.45 < float(np.var(z)) < 1.8  # chi^2_39 / 39 outside this: < 0.1 %


def test_loads_separate_the_weight_from_the_stiffness():
    truth = cantilever(0.021, mass=0.052)
    loads = np.array([0.0, 0.1, 0.2, 0.4, 0.8])
    tips = np.array([pl.solve(pl.Problem(truth.part, (pl.clamp(0.0),
                                                      pl.push(0.5, (0.0, -f), name="tip")),
                                         gravity=(0.0, -9.81))).position[-1]
                     for f in loads])
    guess = cantilever(0.05, mass=0.03)
    tips_y = tips.copy()
    tips_y[:, 0] = np.nan  # a dial gauge reads y only
    for measured in (tips, tips_y):
        result = identify(StiffnessTest(guess, ("bending_stiffness", "mass_per_length"), (
            Deflection("tip", np.array([0.0, -1.0]), 0.5, loads, measured),)))
        assert result.value("bending_stiffness") == pytest.approx(0.021, rel=1e-6)
        assert result.value("mass_per_length") == pytest.approx(0.052, rel=1e-6)
        assert np.allclose(result.correlation, result.correlation.T)


def test_a_gauge_zeroed_under_the_parts_weight_reads_displacements():
    """relative = true: the table is the displacement from the pose under no tip load,
    so the part's own sag is not in the data; the fit must subtract it, not match it."""
    truth = cantilever(0.021, mass=0.052)
    loads = np.array([0.1, 0.2, 0.4, 0.8])

    def tip(problem, f):
        return pl.solve(pl.Problem(problem.part, (pl.clamp(0.0), pl.push(
            0.5, (0.0, -f), name="tip")), gravity=(0.0, -9.81))).position[-1]

    sag = tip(truth, 0.0)
    assert sag[1] < -0.05  # the weight alone bends it well past round-off
    shifted = np.array([tip(truth, f) for f in loads]) - sag
    guess = cantilever(0.05, mass=0.052)
    relative = Deflection("tip", np.array([0.0, -1.0]), 0.5, loads, shifted, relative=True)
    result = identify(StiffnessTest(guess, ("bending_stiffness",), (relative,)))
    assert result.value("bending_stiffness") == pytest.approx(0.021, rel=1e-6)
    assert result.fitted[0].y_label.startswith("displacement ")


def test_the_tested_curvature_range_is_the_largest_bend_the_test_reached():
    """A deflection test's largest curvature is at the clamp, M / EI = F x_tip / EI for a
    weightless part under a dead vertical load (any deflection); a shallow three-point
    bend's is under the ram, 3 delta / a^2 with a the half span."""
    part = pl.Part(0.5, 0.021)
    loads = np.array([0.05, 0.1, 0.2])
    tips = np.array([pl.solve(pl.Problem(part, (pl.clamp(0.0), pl.push(
        0.5, (0.0, -f), name="tip")))).position[-1] for f in loads])
    test = StiffnessTest(pl.Problem(replace(part, bending_stiffness=0.05), (
        pl.clamp(0.0), pl.push(0.5, (0.0, -0.1), name="tip"))), ("bending_stiffness",),
        (Deflection("tip", np.array([0.0, -1.0]), 0.5, loads, tips),))
    result = identify(test)
    assert result.curvature == pytest.approx(0.2 * tips[-1, 0] / 0.021, rel=1e-6)
    assert "bend radius" in result.part_table()
    delta = np.array([1e-4, 2e-4])
    loads = 0.021 * 48.0 * delta / 0.2 ** 3
    bend = StiffnessTest(pl.Problem(replace(part, bending_stiffness=0.05), (pl.clamp(
        0.0),)), ("bending_stiffness",), (ThreePointBending(0.2, delta, loads),))
    assert identify(bend).curvature == pytest.approx(3.0 * 2e-4 / 0.1 ** 2, rel=1e-3)


def test_published_measurements_of_a_cantilever_the_pazy_wing():
    """Measured data (examples/identify/measured: the Pazy wing's spar under tip masses,
    Avin et al. 2022, from the AePW3 repository): one stiffness fits eleven loads up to
    39 % of the span within 1.5 mm; linear beam theory's best stiffness misses by 5x
    that; the fit lies within 10 % of the stiffness the repository's finite-element
    model condenses to (4.42-4.71 N m^2), its own beam model being 6-7 % stiffer than
    the test."""
    test, _ = load_test(EXAMPLES / "measured" / "pazy_wing.toml")
    result = identify(test)
    ei = result.value("bending_stiffness")
    assert abs(ei / 4.45 - 1.0) < 0.10
    fit = result.fitted[0]
    assert fit.rms < 1.5e-3
    load, measured = fit.x[1:], fit.measured[1:]
    slope = float(load @ measured / (load @ load))  # small deflections: y = slope F
    linear_rms = float(np.sqrt(np.mean(np.append(measured - slope * load, 0.0) ** 2)))
    assert linear_rms > 3.0 * fit.rms
    assert result.estimates[0].low < ei < result.estimates[0].high


# The repository's beam model of the same wing (UM/NAST, Riso and Cesnik; file
# 03_2023_JA_Riso_Cesnik/03_Static_Structural/03_Beam_Bending/static_bending_sweep_skin0
# .txt): tip mass [kg] -> the tip's vertical and axial displacement [% of 0.55 m].
PAZY_BEAM_MODEL = {0.5: (-10.7831, -1.1423), 1.0: (-20.6406, -3.4664),
                   2.0: (-36.3954, -10.0161), 3.0: (-47.2928, -17.0152)}


def test_the_pazy_test_file_models_the_wing_as_its_authors_beam_model_does():
    """With the span-averaged stiffness of the authors' beam (4.43 N m^2), the test
    file's wing (length, weight, tip rod) follows their geometrically exact beam model's
    sweep within 2 %, the shortening included (which the weight changes by 10 %): the
    set-up the identification rests on is theirs."""
    test, _ = load_test(EXAMPLES / "measured" / "pazy_wing.toml")
    problem = test.problem
    part = replace(problem.part, bending_stiffness=4.43)

    def tip(mass):
        conditions = tuple(replace(c, force=(0.0, -9.81 * mass)) if c.name == "tip mass"
                           else c for c in problem.conditions)
        return pl.solve(replace(problem, part=part, conditions=conditions)).position[-1]

    rest = tip(0.0)
    for mass, (vertical, axial) in PAZY_BEAM_MODEL.items():
        dx, dy = (tip(mass) - rest) / 0.55 * 100.0
        assert dy == pytest.approx(vertical, rel=0.02)
        assert dx == pytest.approx(axial, rel=0.02)


def test_a_hanging_shape_cannot_tell_the_weight_from_the_stiffness():
    hanging = pl.Problem(pl.Part(0.5, 0.02, mass_per_length=0.05), (pl.clamp(0.0),),
                         gravity=(0.0, -9.81))
    points = shape_points(hanging, 20)
    with pytest.raises(NotIdentifiableError, match=r"cannot tell bending_stiffness from "
                       "mass_per_length.*bending_stiffness\\^\\+1.00 · mass_per_length"):
        identify(StiffnessTest(hanging, ("bending_stiffness", "mass_per_length"),
                               (Shape(points),)))


def test_bending_in_a_plane_says_it_does_not_load_the_torsion():
    part = pl.Part(0.5, 0.02, mass_per_length=0.05)
    flat = pl.Problem(part, (pl.clamp(0.0, (0.0, 0.0, 0.0)),), gravity=(0.0, -9.81, 0.0))
    points = pl.solve(flat).position[::5]
    with pytest.raises(NotIdentifiableError, match="do not depend on torsional_stiffness"):
        identify(StiffnessTest(flat, ("torsional_stiffness",), (Shape(points),)))
    with pytest.raises(InputError, match="2D test bends the part in its plane only"):
        StiffnessTest(cantilever(0.02), ("torsional_stiffness",), (Shape(points[:, :2]),))


def test_a_curved_part_bent_out_of_its_plane_gives_both_stiffnesses():
    truth = pl.Part(0.6, 0.05, torsional_stiffness=0.03, mass_per_length=0.1,
                    rest_curvature=2.5)
    problem = pl.Problem(truth, (pl.clamp(0.0, (0.0, 0.0, 0.0)),
                                 pl.push(0.6, (0.0, 0.0, -0.1), name="tip")),
                         gravity=(0.0, 0.0, -9.81))
    points = pl.solve(problem).position[5::5]
    guess = replace(problem, part=replace(truth, bending_stiffness=0.1,
                                          torsional_stiffness=0.1))
    result = identify(StiffnessTest(guess, ("bending_stiffness", "torsional_stiffness"),
                                    (Shape(points),)))
    assert result.value("bending_stiffness") == pytest.approx(0.05, rel=1e-5)
    assert result.value("torsional_stiffness") == pytest.approx(0.03, rel=1e-5)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(ei=st.floats(0.005, 0.5), tip=st.floats(0.0, 1.0), off=st.floats(0.2, 5.0))
def test_random_cantilevers_are_always_identified(ei, tip, off):
    """Noise-free shapes of cantilevers from nearly straight to strongly bent, from a
    first guess up to five times off: the stiffness comes back, every time."""
    truth = cantilever(ei, tip)
    points = shape_points(truth, 25)
    result = identify(StiffnessTest(cantilever(ei * off, tip), ("bending_stiffness",),
                                    (Shape(points),)))
    assert result.value("bending_stiffness") == pytest.approx(ei, rel=1e-5)


# --- the files ---------------------------------------------------------------------------


def test_greenhill_buckling_angle_gives_the_torsional_stiffness():
    """A straight length between clamps (one sliding along the axis) turned until it
    buckles: Greenhill's clamped-clamped moment M L / EI = 2.8606 pi, so the angle
    13.48 rad (the file's) means GJ = EI / 1.5 (the 3D rod at 100 elements, O(h^2))."""
    test, _ = load_test(EXAMPLES / "cable_greenhill.toml")
    result = identify(test)
    assert result.value("torsional_stiffness") == pytest.approx(0.02 / 1.5, rel=2e-3)
    assert result.fitted[0].rms < 1e-6
    assert result.dof == 0 and "from the stated uncertainties alone" in result.notes[0]


@pytest.mark.parametrize(("name", "truth"), [
    ("cable_shape", {"bending_stiffness": 0.021}),
    ("cable_tip_loads", {"bending_stiffness": 0.021, "mass_per_length": 0.052}),
    ("hose_bench", {"bending_stiffness": 0.021, "torsional_stiffness": 0.0115}),
])
def test_the_examples_recover_what_made_their_synthetic_data(name, truth):
    test, _ = load_test(EXAMPLES / f"{name}.toml")
    result = identify(test)
    for e in result.estimates:
        assert e.low <= truth[e.name] <= e.high
        assert e.value == pytest.approx(truth[e.name], rel=0.02)


@settings(max_examples=60, deadline=None)
@given(values=st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)), min_size=1,
                       max_size=8),
       unit=st.sampled_from([("m", 1.0), ("mm", 1e-3), ("cm", 1e-2), ("in", 0.0254)]),
       spaces=st.sampled_from(["[{}]", "({})", "[ {} ]"]))
def test_tables_read_back_in_si_whatever_their_unit(values, unit, spaces):
    header = ", ".join(f"{c} {spaces.format(unit[0])}" for c in "xy")
    text = "# a comment\n" + header + "\n" + "\n".join(f"{x!r}, {y!r}" for x, y in values)
    cols = parse_table(text, "shape", "t.csv")
    assert np.allclose(cols["x"], [v[0] * unit[1] for v in values], rtol=1e-15, atol=0)
    assert np.allclose(cols["y"], [v[1] * unit[1] for v in values], rtol=1e-15, atol=0)


@pytest.mark.parametrize(("text", "message"), [
    ("x, y\n1, 2\n", "column 'x' gives no unit; write the header as 'x \\[m\\]'"),
    ("x [furlong], y [m]\n1, 2\n", "not a unit of length; use one of m, cm, mm"),
    ("x [m]\n1\n", "no column 'y'"),
    ("x [m], y [m]\n1, two\n", "row 2, column 'y': 'two' is not a number"),
    ("x [m], y [m]\n", "a header and no rows"),
    ("x [m], w [m]\n1, 2\n", "column 'w' is not one a shape takes"),
])
def test_bad_tables_are_refused_by_name(text, message):
    with pytest.raises(FileFormatError, match=message):
        parse_table(text, "shape", "t.csv")


CLAMP = """
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
angle = 0.0
"""
BASE = """
gravity = [0.0, -9.81]
[part]
length = 0.5
bending_stiffness = 0.05
mass_per_length = 0.05
""" + CLAMP


IDENTIFY = '[identify]\nunknowns = ["bending_stiffness"]\n'
SHAPE = '[[measured]]\nkind = "shape"\npoints = [[0.1, 0.0], [0.2, -0.01], [0.3, -0.03]]\n'


@pytest.mark.parametrize(("tail", "message"), [
    ("", "no \\[identify\\] table"),
    (IDENTIFY, "no \\[\\[measured\\]\\] table"),
    (IDENTIFY.replace("bending_stiffness", "stiffness") + SHAPE,
     "'stiffness' is not a parameter"),
    (IDENTIFY + '[[measured]]\nkind = "shape"\npionts = [[0.1, 0.0]]\n',
     "measured\\[0\\]: pionts: unknown key"),
    (IDENTIFY + '[[measured]]\nkind = "shape"\npoints = [[0.1, 0.0]]\n',
     "1 point\\(s\\) do not make a shape"),
    (IDENTIFY + '[[measured]]\nkind = "deflection"\ncondition = "tip"\ndata = "x.csv"\n',
     "no condition named 'tip'"),
    (IDENTIFY + SHAPE + "relative = true\n",
     "measured\\[0\\].relative: only a deflection's table gives displacements"),
    (IDENTIFY + SHAPE + "uncertainty = 1e-3\n" + SHAPE,
     "give every \\[\\[measured\\]\\] an uncertainty, or none"),
])
def test_bad_tests_are_refused_by_name(tail, message):
    from pliant.identify import identify as fit

    with pytest.raises((FileFormatError, InputError), match=message):
        test, _ = parse_test(BASE + tail, "t.toml")
        fit(test)


def test_a_bending_curve_that_goes_back_is_refused(tmp_path):
    (tmp_path / "b.csv").write_text("displacement [mm], load [N]\n1, 0.1\n3, 0.3\n2, 0.2\n")
    text = BASE + ('[identify]\nunknowns = ["bending_stiffness"]\n[[measured]]\n'
                   'kind = "three_point_bending"\nspan = 0.2\ndata = "b.csv"\n')
    test, _ = parse_test(text, str(tmp_path / "t.toml"), tmp_path)
    with pytest.raises(InputError, match="displacement must grow from row to row"):
        identify(test)


def test_cli_writes_the_fit_and_a_part_entry_that_a_scene_reads(tmp_path):
    from typer.testing import CliRunner

    from pliant.cli.app import app

    out = CliRunner().invoke(app, ["identify", str(EXAMPLES / "cable_tip_loads.toml"),
                                   "--json", str(tmp_path / "fit.json"), "--part",
                                   str(tmp_path / "part.toml"), "--plot",
                                   str(tmp_path / "fit.png")])
    assert out.exit_code == 0, out.output
    assert "bending_stiffness" in out.output and "95% intervals" in out.output
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["schema_version"] == 1
    by_name = {e["name"]: e for e in fit["estimates"]}
    # Each value whole with its unit on an 80-column screen (not "0.021…" and "N m…").
    for e in fit["estimates"]:
        assert f"{e['value']:.4g} {e['unit']}" in out.output, e["name"]
    assert by_name["mass_per_length"]["low"] < 0.052 < by_name["mass_per_length"]["high"]
    assert (tmp_path / "fit.png").stat().st_size > 10_000
    scene = (tmp_path / "part.toml").read_text() + (
        "[[condition]]\nname = \"clamp\"\ns = 0.0\nx = 0.0\ny = 0.0\nangle = 0.0\n")
    from pliant.io.problem_file import parse_problem

    problem = parse_problem(scene, "part.toml")  # the entry reads as a problem's [part]
    assert problem.part.bending_stiffness == pytest.approx(
        by_name["bending_stiffness"]["value"], rel=1e-5)


def test_every_library_material_states_its_source_and_provenance():
    from pliant.io.materials import PROVENANCE, library

    entries = library()
    assert len(entries) >= 10
    for entry in entries.values():
        assert entry["provenance"] in PROVENANCE and len(entry["source"]) > 20


REINFORCED = """
[part]
length = 1.0
outer_diameter = 0.03
inner_diameter = 0.02
material = "EPDM"
kind = "reinforced hose"
{extra}
""" + CLAMP


def test_a_reinforced_hose_stiffened_only_by_its_rubber_is_warned_about():
    from pliant.assembly.scenes import parse_scene

    warned = parse_scene(REINFORCED.format(extra=""), "h.toml").warnings
    assert len(warned) == 1 and "plies make it many times stiffer" in warned[0]
    assert "pliant identify" in warned[0]
    measured = parse_scene(REINFORCED.format(extra="bending_stiffness = 2.5"), "h.toml")
    assert measured.warnings == ()
    assert measured.problem.part.bending_stiffness == 2.5
