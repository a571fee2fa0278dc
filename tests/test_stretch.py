"""Parts that stretch (axial stiffness EA) in both accurate models: closed forms, the
inextensible limit and its order, an independent collocation twin, the extensible Euler
column, targets beyond the part's length, and near-taut grips under refinement."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import pliant as pl
from pliant.errors import InputError, UnreachableTargetError
from pliant.io.problem_file import dump_problem, parse_problem
from pliant.models import rod3d
from pliant.models.elastica2d import solve as solve_2d
from pliant.models.elastica2d import stability as planar
from pliant.models.elastica2d.reference import solve_reference

ORIGIN = (0.0, 0.0, 0.0)


def _3d(conditions, part, gravity=ORIGIN, elements=40):
    return rod3d.solve(pl.Problem(part, conditions, gravity=gravity),
                       solver=rod3d.RodSolver(elements=elements))


@pytest.mark.parametrize("force", [50.0, -1.5])  # Euler: buckles past -1.93 N
def test_a_straight_bar_pulled_or_pushed_changes_length_by_F_L_over_EA(force):
    L, EA = 0.8, 2e4
    part = pl.Part(length=L, bending_stiffness=0.5, axial_stiffness=EA)
    eq = solve_2d(pl.Problem(part, (pl.clamp(0.0), pl.push(L, force=(force, 0.0)))))
    assert eq.tip[0] == pytest.approx(L + force * L / EA, rel=1e-12)
    assert eq.elongation == pytest.approx(force * L / EA, rel=1e-10)
    assert np.allclose(eq.axial_strain, force / EA, rtol=1e-12)
    assert eq.energy == pytest.approx(force**2 * L / (2 * EA), rel=1e-10)
    three = _3d((pl.clamp(0.0, position=ORIGIN), pl.push(L, force=(force, 0.0, 0.0))), part)
    assert three.tip[0][0] == pytest.approx(L + force * L / EA, rel=1e-12)
    assert three.elongation == pytest.approx(force * L / EA, rel=1e-10)
    assert three.energy == pytest.approx(force**2 * L / (2 * EA), rel=1e-10)


def test_a_bar_hanging_under_its_weight_stretches_by_w_L2_over_2EA():
    L, EA, mass = 1.5, 3e3, 0.4
    w = mass * 9.81
    part = pl.Part(length=L, bending_stiffness=0.2, mass_per_length=mass, axial_stiffness=EA)
    eq = solve_2d(pl.Problem(part, (pl.clamp(0.0, angle=-math.pi / 2),), gravity=(0.0, -9.81)))
    assert eq.tip[1] == pytest.approx(-(L + w * L * L / (2 * EA)), rel=1e-12)
    three = _3d((pl.clamp(0.0, position=ORIGIN, tangent=(0.0, 0.0, -1.0),
                          normal=(1.0, 0.0, 0.0)),), part,
                gravity=(0.0, 0.0, -9.81))
    # lumped nodal weights load each element with the weight beyond its midpoint: exact
    assert three.tip[0][2] == pytest.approx(-(L + w * L * L / (2 * EA)), rel=1e-12)


def test_a_target_beyond_the_length_is_reached_with_EA_delta_over_L():
    L, EA, delta = 1.0, 1e4, 0.004
    part = pl.Part(length=L, bending_stiffness=1.0, axial_stiffness=EA)
    eq = solve_2d(pl.Problem(part, (pl.clamp(0.0), pl.clamp(L, position=(L + delta, 0.0),
                                                           name="connector"))))
    assert eq.reactions["connector"].force[0] == pytest.approx(EA * delta / L, rel=1e-6)
    three = _3d((pl.clamp(0.0, position=ORIGIN),
                 pl.clamp(L, position=(L + delta, 0.0, 0.0), name="connector")), part)
    assert three.reactions["connector"].force[0] == pytest.approx(EA * delta / L, rel=1e-6)
    stiff = pl.Part(length=L, bending_stiffness=1.0)
    with pytest.raises(UnreachableTargetError, match="axial_stiffness"):
        pl.Problem(stiff, (pl.clamp(0.0), pl.clamp(L, position=(L + delta, 0.0), name="c")))
    with pytest.raises(UnreachableTargetError, match="10%"):
        pl.Problem(part, (pl.clamp(0.0), pl.clamp(L, position=(1.2 * L, 0.0), name="c")))


def test_stretch_tends_to_the_inextensible_answer_at_first_order_in_1_over_EA():
    def tip(ea):
        part = pl.Part(length=1.0, bending_stiffness=1.0, axial_stiffness=ea)
        return np.array(solve_2d(pl.Problem(part, (pl.clamp(0.0),
                                                   pl.push(1.0, force=(0.0, 5.0))))).tip)

    limit = tip(None)
    errors = [np.linalg.norm(tip(ea) - limit) for ea in (1e3, 1e4, 1e5)]
    assert errors[0] / errors[1] == pytest.approx(10.0, rel=0.02)
    assert errors[1] / errors[2] == pytest.approx(10.0, rel=0.02)


@pytest.mark.parametrize(("force", "angle"), [((0.0, 8.0), 0.0), ((-3.0, 2.0), 0.6)])
def test_the_extensible_cantilever_matches_an_independent_collocation_twin(force, angle):
    part = pl.Part(length=1.0, bending_stiffness=1.0, axial_stiffness=300.0)
    problem = pl.Problem(part, (pl.clamp(0.0, angle=angle), pl.push(1.0, force=force)))
    eq = solve_2d(problem)
    twin = solve_reference(problem, tol=1e-9)
    assert twin.success
    assert np.allclose(eq.tip, twin.tip, atol=1e-7)
    moment = eq.reactions["clamp"].moment
    assert moment == pytest.approx(-twin.first[2], abs=1e-6)
    # the stretch is visible: the tip lies off the inextensible answer by far more
    rigid = solve_2d(pl.Problem(pl.Part(1.0, 1.0), problem.conditions))
    assert np.linalg.norm(np.subtract(eq.tip, rigid.tip)) > 1e-3


def _pinned_column(P: float, EA: float) -> pl.Problem:
    part = pl.Part(1.0, 1.0, axial_stiffness=EA)
    return pl.Problem(part, (pl.pin(0.0), pl.Condition(s=1.0, name="end", position=(None, 0.0),
                                                       force=(-P, None))))


def test_the_extensible_euler_column_buckles_at_its_closed_form_load():
    # P (1 - P / EA) = pi^2 EI / L^2: the compressed column is shorter, so it holds more
    EA = 200.0
    critical = 0.5 * EA * (1.0 - math.sqrt(1.0 - 4.0 * math.pi**2 / EA))
    assert critical > 1.05 * math.pi**2
    for fraction in (0.5, 0.97):
        P = fraction * critical
        eq = solve_2d(_pinned_column(P, EA))
        assert abs(eq.position[:, 1]).max() < 1e-12 and eq.stable
        expected = math.pi**2 - P * (1.0 - P / EA)
        assert planar.smallest_eigenvalue(eq) == pytest.approx(expected, abs=3e-4 * math.pi**2)
    beyond = solve_2d(_pinned_column(1.03 * critical, EA))
    assert beyond.stable and abs(beyond.position[:, 1]).max() > 0.05
    assert "its straight equilibrium is unstable" in beyond.notes[0]


@pytest.mark.parametrize("model", ["2d", "3d"])
def test_a_pushed_extensible_strip_buckles_instead_of_staying_straight(model):
    part = pl.Part(length=1.0, bending_stiffness=1.0, axial_stiffness=1e4)
    rigid = pl.Part(length=1.0, bending_stiffness=1.0)
    if model == "2d":
        def run(p):
            return solve_2d(pl.Problem(p, (pl.pin(0.0), pl.pin(1.0, position=(0.8, 0.0),
                                                              name="b"))))
        eq, ref = run(part), run(rigid)
        lateral = abs(eq.position[:, 1]).max()
    else:
        def run(p):
            return _3d((pl.pin(0.0, position=ORIGIN),
                        pl.pin(1.0, position=(0.8, 0.0, 0.0), name="b")), p)
        eq, ref = run(part), run(rigid)
        lateral = np.linalg.norm(eq.position[:, 1:], axis=1).max()
    assert eq.stable and lateral > 0.2
    # a stiff EA changes the buckled answer by little: the compression is 1e-3 of it
    force, ref_force = eq.reactions["b"].force[0], ref.reactions["b"].force[0]
    assert force == pytest.approx(ref_force, rel=2e-3)
    # N = Fx cos(theta) in a pin-pin strip: its elongation is Fx / EA times the chord
    assert eq.elongation == pytest.approx(force * 0.8 / 1e4, rel=2e-3)


def test_a_near_taut_cable_gives_forces_that_converge_under_refinement():
    # 1 m of cable, 0.2 kg/m, EA 20 kN, between clamps 0.999 m apart: inextensible, the
    # tension would grow without bound as the chord nears L; here it is the 3D model's
    # own refinement that is checked, and the 2D model's answer it converges to.
    part = pl.Part(length=1.0, bending_stiffness=0.02, mass_per_length=0.2,
                   axial_stiffness=2e4)
    conditions = (pl.clamp(0.0, position=ORIGIN),
                  pl.clamp(1.0, position=(0.999, 0.0, 0.0), name="connector"))
    forces = [_3d(conditions, part, gravity=(0.0, 0.0, -9.81), elements=n)
              .reactions["connector"].force[0] for n in (25, 50, 100)]
    plane = solve_2d(pl.Problem(part, (pl.clamp(0.0), pl.clamp(
        1.0, position=(0.999, 0.0), name="connector")), gravity=(0.0, -9.81)))
    exact = plane.reactions["connector"].force[0]
    errors = [abs(f - exact) for f in forces]
    assert errors[0] / errors[1] > 3.0 and errors[1] / errors[2] > 3.0  # second order
    assert errors[2] < 5e-3 * abs(exact)


def test_the_file_takes_EA_or_the_material_and_writes_it_back():
    text = """
[part]
length = 1.0
outer_diameter = 0.01
material = "PA12"
axial_stiffness = "material"
max_axial_strain = 0.02

[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
angle = 0.0

[[condition]]
name = "pull"
s = 1.0
Fx = 100.0
"""
    problem = parse_problem(text)
    part = problem.part
    area = math.pi * 0.01**2 / 4
    assert part.axial_stiffness == pytest.approx(part.bending_stiffness / (area * 0.01**2 / 16)
                                                 * area, rel=1e-12)  # E A = (EI / I) A
    assert part.max_axial_strain == 0.02
    again = parse_problem(dump_problem(problem))
    assert again.part.axial_stiffness == part.axial_stiffness
    assert again.part.max_axial_strain == 0.02
    with pytest.raises(Exception, match="needs a material"):
        parse_problem(text.replace('material = "PA12"\n', "bending_stiffness = 1.0\n"))
    with pytest.raises(InputError, match="axial_stiffness"):
        pl.Part(1.0, 1.0, axial_stiffness=10.0)  # EI / (EA L^2) = 0.1: a block, not a hose


def test_the_evaluation_judges_the_strain_against_what_the_part_tolerates():
    from types import SimpleNamespace

    from pliant.assembly.checks import Zone
    from pliant.assembly.evaluate import stretch_checks
    from pliant.io.rules_file import bundled_rules

    rules = bundled_rules()
    L, EA = 1.0, 1e4
    zones = []
    for delta in (0.0005, 0.0009, 0.0015):  # strain 0.05, 0.09, 0.15 % against 0.1 %
        part = pl.Part(length=L, bending_stiffness=1.0, axial_stiffness=EA,
                       max_axial_strain=0.001)
        eq = solve_2d(pl.Problem(part, (pl.clamp(0.0), pl.clamp(L, position=(L + delta, 0.0),
                                                                name="connector"))))
        (check,) = stretch_checks(SimpleNamespace(equilibria=[eq]), part, rules)
        # the solver meets positions to 1e-10 L: the strain to about that, absolutely
        assert check.value == pytest.approx(100.0 * delta / L, abs=1e-7)
        assert check.red_at == pytest.approx(0.1) and check.family == "damage"
        zones.append(check.zone)
    assert zones == [Zone.GREEN, Zone.YELLOW, Zone.RED]
    assert stretch_checks(SimpleNamespace(equilibria=[eq]), pl.Part(L, 1.0), rules) == []


def test_the_short_cable_example_reports_the_pull_and_the_strain_over_its_limit():
    import json

    from typer.testing import CliRunner

    from pliant.cli.app import app

    file = str(Path(__file__).resolve().parents[1] / "examples" / "cables" / "short_cable.toml")
    out = CliRunner().invoke(app, ["solve", file, "--json", "-"])
    assert out.exit_code == 0, out.output
    data = json.loads(out.output[out.output.index("{"):])
    stretch = data["stretch"]
    # 3 mm short of 0.6 m with EA = 60 kN: the straight bar's pull is 300 N; the sag
    # under its own weight at that tension changes it by far less than 1 %
    assert stretch["elongation"] == pytest.approx(0.003, rel=1e-3)
    assert stretch["max_axial_force"] == pytest.approx(6e4 * 0.003 / 0.6, rel=1e-3)
    text = CliRunner().invoke(app, ["solve", file]).output
    assert "stretch: +3.001 mm longer" in text and "above the part's allowed 0.4 %" in text

