"""Distributed loads as nouns (``pliant.core.loads``): dead and follower forces per unit
length on a stretch of the part, against closed forms, beam theory, independent
integration and finite differences, in both models, through files and with typed
errors."""

from __future__ import annotations

import dataclasses
import itertools
import math
import pickle

import numpy as np
import pytest
from scipy.integrate import quad

import pliant as pl
from pliant.errors import FileFormatError, InputError
from pliant.io.problem_file import dump_problem, parse_problem
from pliant.models import elastica2d, rod3d
from pliant.models.banded import dense
from pliant.models.elastica2d.lowering import lower as lower_2d
from pliant.models.elastica2d.reference import equilibrium_error, solve_reference
from pliant.models.rod3d.lowering import lower
from pliant.models.rod3d.solver import Run

from .helpers import shooting_jacobians

UNIT = pl.Part(length=1.0, bending_stiffness=1.0, torsional_stiffness=1.0)
CLAMP = pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0))


def arc_problem(kappa: float, q: float) -> pl.Problem:
    """A cantilever along +x under a follower pressure q [N/m] toward the centre of its
    curvature (material -d2 = +y at the clamp), a tip thrust -q / kappa along its tangent
    (follower) and a tip couple EI kappa about z. The circular arc of curvature kappa is
    an exact equilibrium: with t' = kappa nu and Q = 0, n' = -q nu gives N kappa = -q,
    so N = -q / kappa all along, and m = EI kappa balances the couple (m' = -Q = 0)."""
    return pl.Problem(UNIT, (
        CLAMP,
        pl.push(1.0, force=(0.0, 0.0, -q / kappa), follower=True, name="thrust"),
        pl.push(1.0, moment=(0.0, 0.0, kappa), name="couple")),
        loads=(pl.DistributedLoad((0.0, -q, 0.0), follower=True, name="pressure"),))


def test_a_follower_pressure_bends_a_cantilever_into_the_exact_arc():
    kappa, q = 1.5, 2.0
    exact = np.array([math.sin(kappa), 1.0 - math.cos(kappa), 0.0]) / kappa
    errors = []
    for n in (25, 50, 100):
        eq = rod3d.solve(arc_problem(kappa, q), solver=rod3d.RodSolver(elements=n))
        errors.append(float(np.linalg.norm(eq.tip[0] - exact)))
        # The hoop force N = -q / kappa along the whole part, to the discretisation.
        assert np.allclose(eq.axial_force, -q / kappa, rtol=2e-3 * (25 / n) ** 2)
        # Global balance: the clamp holds what the pressure and the thrust leave,
        # -(thrust + the pressure's integral q nu over the arc) = (q / kappa, 0, 0).
        assert np.allclose(eq.loads["clamp"].force, (q / kappa, 0.0, 0.0),
                           atol=2e-3 * (25 / n) ** 2 * q / kappa)
        assert eq.verdict == "undecided"  # a follower load has no potential
    assert errors[-1] < 3e-5
    orders = [math.log2(a / b) for a, b in itertools.pairwise(errors)]
    assert min(orders) > 1.9  # second order, as the rod's discretisation


def _beam_tip(w: float, a: float, L: float = 1.0, EI: float = 1.0) -> float:
    """Euler-Bernoulli tip deflection of a cantilever under w [N/m] on [a, L]: the unit
    load method, v(L) = int M(x) (L - x) dx / EI, M(x) = int_x^L w(xi) (xi - x) dxi."""
    def moment(x: float) -> float:
        lo = max(x, a)
        return w * ((L - x) ** 2 - (lo - x) ** 2) / 2.0
    return quad(lambda x: moment(x) * (L - x), 0.0, L, points=[a])[0] / EI


@pytest.mark.parametrize("follower", [False, True])
def test_a_load_on_a_stretch_matches_beam_theory_under_a_small_load(follower):
    """w on [0.4, 1] m of a unit cantilever: dead (global -y... here +z down) and
    follower (material -d1, which is -z at the clamp) agree with beam theory while the
    rotations are small (the nonlinear terms are O(w^3))."""
    w, a = 1e-3, 0.4
    force = (0.0, 0.0, -w) if not follower else (-w, 0.0, 0.0)
    problem = pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad(
        force, follower=follower, start=a, name="spread"),))
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=100))
    assert -eq.tip[0][2] == pytest.approx(_beam_tip(w, a), rel=1e-4)
    # The clamp carries the whole load, w (L - a), at its centroid's arm.
    assert eq.loads["clamp"].force[2] == pytest.approx(w * (1.0 - a), rel=1e-4)
    assert eq.loads["clamp"].moment[1] == pytest.approx(
        -w * (1.0 - a) * (1.0 + a) / 2.0, rel=1e-3)


def test_a_dead_load_on_the_whole_part_is_its_weight():
    """A dead load w [N/m] on the whole part and the weight mass_per_length g = w are
    one lowering: the same equilibrium in 3D and in 2D."""
    heavy = pl.Part(length=1.0, bending_stiffness=1.0, torsional_stiffness=1.0,
                    mass_per_length=0.5)
    weighed = pl.Problem(heavy, (CLAMP,), gravity=(0.0, 0.0, -9.81))
    loaded = pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad((0.0, 0.0, -0.5 * 9.81)),))
    a, b = rod3d.solve(weighed), rod3d.solve(loaded)
    assert np.allclose(a.position, b.position, atol=1e-12)
    flat = pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=0.5)
    a2 = elastica2d.solve(pl.Problem(flat, (pl.clamp(0.0),), gravity=(0.0, -9.81)))
    b2 = elastica2d.solve(pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0),
                                     (pl.clamp(0.0),),
                                     loads=(pl.DistributedLoad((0.0, -0.5 * 9.81)),)))
    assert np.allclose(a2.tip, b2.tip, atol=1e-10)
    # And the 2D answer is the 3D one's (the elastica and the rod agree in the plane).
    assert b2.tip[1] == pytest.approx(b.tip[0][2], rel=1e-3)


def test_a_problems_load_per_length_follows_its_gravity_and_loads():
    """The dead load on every metre (weight plus the dead loads that cover the part) and
    the loads left to the stretches are worked out once, when the problem is made: a
    problem remade with other gravity or loads (dataclasses.replace, a path's next
    problem) and one read back from a pickle carry their own."""
    part = pl.Part(length=2.0, bending_stiffness=1.0, mass_per_length=0.5)
    whole = pl.DistributedLoad((0.3, -1.0), name="whole")
    stretch = pl.DistributedLoad((0.0, -2.0), start=0.5, end=1.5, name="stretch")
    turning = pl.DistributedLoad((0.0, 0.7), follower=True, name="turning")
    problem = pl.Problem(part, (pl.clamp(0.0),), gravity=(0.0, -9.81),
                         loads=(whole, stretch, turning))
    assert problem.dead_load_per_length == pytest.approx((0.3, -0.5 * 9.81 - 1.0))
    assert {ld.name for ld in problem.partial_loads} == {"stretch", "turning"}
    moon = dataclasses.replace(problem, gravity=(0.0, -1.62), loads=(stretch,))
    assert moon.dead_load_per_length == pytest.approx((0.0, -0.5 * 1.62))
    assert [ld.name for ld in moon.partial_loads] == ["stretch"]
    back = pickle.loads(pickle.dumps(problem))
    assert back.dead_load_per_length == problem.dead_load_per_length
    assert back.partial_loads == problem.partial_loads


def test_2d_a_follower_pressure_bends_a_cantilever_into_the_exact_arc():
    """The same arc in the 2D model (mesh-free: to the shooting's tolerance), checked
    by re-integrating the ODE with scipy from the returned samples."""
    kappa, q = 1.5, 2.0
    problem = pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0), (
        pl.clamp(0.0), pl.push(1.0, force=(-q / kappa, 0.0), follower=True, name="thrust"),
        pl.push(1.0, moment=kappa, name="couple")),
        loads=(pl.DistributedLoad((0.0, q), follower=True, name="pressure"),))
    eq = elastica2d.solve(problem)
    assert np.allclose(eq.tip, (math.sin(kappa) / kappa, (1 - math.cos(kappa)) / kappa,
                                kappa), atol=1e-9)
    assert np.allclose(eq.axial_force, -q / kappa, atol=1e-9)
    assert np.allclose(eq.loads["clamp"].force, (q / kappa, 0.0), atol=1e-9)
    assert eq.verdict == "undecided"
    assert equilibrium_error(eq) < 1e-8


@pytest.mark.parametrize("follower", [False, True])
def test_2d_loads_on_a_stretch_match_the_3d_rod_and_an_independent_integration(follower):
    """A heavy load on [0.3, 0.8] m of a cantilever (rotations near 1 rad): the 2D
    shooting, re-integrated by scipy, and the 3D rod in the plane agree."""
    w = 4.0
    plane = pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0), (pl.clamp(0.0),),
                       loads=(pl.DistributedLoad((0.0, -w), follower=follower, start=0.3,
                                                 end=0.8, name="q"),))
    eq = elastica2d.solve(plane)
    assert equilibrium_error(eq) < 1e-8
    assert -0.9 < eq.tip[2] < -0.3  # a large deflection
    # The 3D rod in the plane z = 0 with d1 = +z: its material frame (d1, d2, d3) is
    # (z, -nu, t), so a 2D follower (ft, fn) is (0, -fn, ft) there.
    force = (0.0, -w, 0.0) if not follower else (0.0, w, 0.0)
    space = pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad(
        force, follower=follower, start=0.3, end=0.8, name="q"),))
    rod = rod3d.solve(space, solver=rod3d.RodSolver(elements=200))
    assert np.allclose(rod.tip[0][:2], eq.tip[:2], atol=2e-4)
    # And scipy's solve_bvp from the shooting's answer stays on it.
    ref = solve_reference(plane, guess=eq, tol=1e-8)
    assert ref.success and np.allclose(ref.tip, eq.tip, atol=1e-6)


@pytest.mark.parametrize("extensible", [False, True])
def test_2d_shooting_sensitivities_with_loads_on_stretches_match_finite_differences(
        extensible):
    """The shooting's Jacobian (sensitivities through the Runge-Kutta stages) against
    central differences, with a dead and a follower load on overlapping stretches and
    a restart node: the follower's n carried through the stages is the new term."""
    part = pl.Part(length=1.0, bending_stiffness=1.0, rest_curvature=0.4,
                   axial_stiffness=300.0 if extensible else None)
    problem = pl.Problem(part, (
        pl.clamp(0.0), pl.grip(1.0, position=(0.6, 0.5), name="hand")),
        loads=(pl.DistributedLoad((1.5, -3.0), start=0.2, end=0.7, name="dead"),
               pl.DistributedLoad((2.0, 4.0), follower=True, start=0.4, name="flow")))
    low = lower_2d(problem, nodes=2)
    z = np.random.default_rng(7).standard_normal(low.nz)
    jac, fd = shooting_jacobians(low, z, low.mesh(24))
    assert np.allclose(jac, fd, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(jac).max()))
    assert np.any(low.target.dist[:, 2:]) and np.any(low.target.dist[:, :2])


def test_2d_lowest_equilibrium_with_a_load_on_a_stretch():
    """Configuration space with a dead load on a stretch: the minimiser's lumped load
    and the shooting agree (the answer re-integrated), and it is stable."""
    problem = pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0), (
        pl.clamp(0.0), pl.clamp(1.0, position=(0.8, 0.0), angle=0.0, name="hand")),
        loads=(pl.DistributedLoad((0.0, -30.0), start=0.5, end=1.0, name="q"),))
    eq = elastica2d.solve(problem)
    assert equilibrium_error(eq) < 1e-8
    assert eq.verdict == "stable"
    # The hand and the clamp carry the whole load: 30 N/m over 0.5 m.
    total = eq.loads["clamp"].force[1] + eq.loads["hand"].force[1]
    assert total == pytest.approx(15.0, rel=1e-9)


def test_a_small_uniform_load_in_2d_is_beam_theory():
    w = 1e-3
    eq = elastica2d.solve(pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0),
                                     (pl.clamp(0.0),),
                                     loads=(pl.DistributedLoad((0.0, -w)),)))
    assert -eq.tip[1] == pytest.approx(w / 8.0, rel=1e-5)  # w L^4 / 8 EI


def test_the_jacobian_with_distributed_loads_matches_finite_differences():
    """The KKT Jacobian against central differences with a dead and a follower load on
    stretches (the follower's dependence on the element frames is the new term)."""
    part = pl.Part(length=1.0, bending_stiffness=1.0, torsional_stiffness=0.7,
                   rest_curvature=0.5)
    problem = pl.Problem(part, (
        pl.Condition(s=0.0, name="pin", position=(0.0, 0.0, 0.0), tangent=(1, 0, 0)),
        pl.grip(1.0, position=(0.7, 0.3, 0.2), name="hand")),
        loads=(pl.DistributedLoad((0.3, -0.4, 0.2), start=0.1, end=0.6, name="dead"),
               pl.DistributedLoad((0.5, -0.2, 0.4), follower=True, start=0.3, name="flow")))
    rod = lower(problem, elements=12)
    run = Run(rod, rod3d.RodSolver())
    _, state = rod.rest()
    run.gauge_quat = state[1][0].copy()
    state = run.step(state, 0.05 * np.random.default_rng(3).standard_normal(rod.n), 1.0)
    _R, ab, _ = run.residual(state, rod.target, want_jac=True)
    J = dense(ab, rod.kl, rod.ku, rod.n)
    fd = np.empty_like(J)
    for j in range(rod.n):
        du = np.zeros(rod.n)
        du[j] = 1e-6
        rp, _, _ = run.residual(run.step(state, du, 1.0), rod.target)
        rm, _, _ = run.residual(run.step(state, du, -1.0), rod.target)
        fd[:, j] = (rp - rm) / 2e-6
    assert np.allclose(J, fd, atol=1e-6 * max(1.0, np.abs(J).max()))
    # The mesh is cut where each load starts and ends.
    for x in (0.1, 0.3, 0.6):
        assert np.min(np.abs(rod.s_node - x)) < 1e-12


def test_a_file_with_loads_reads_back_what_it_wrote():
    text = """
name = "drag"
gravity = [0.0, 0.0, -9.81]
[part]
length = 0.8
bending_stiffness = 0.05
torsional_stiffness = 0.03
mass_per_length = 0.3
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[load]]
name = "flow"
follower_force = [0.0, 0.1, 0.3]
start = 0.2
[[load]]
force = [0.0, 0.5, 0.0]
start = 0.1
end = 0.5
"""
    problem = parse_problem(text)
    assert [ld.name for ld in problem.loads] == ["flow", "load2"]
    assert problem.loads[0].follower and problem.loads[0].span(0.8) == (0.2, 0.8)
    again = parse_problem(dump_problem(problem))
    assert again.loads == problem.loads
    assert again.conditions == problem.conditions and again.gravity == problem.gravity
    # The solve sees them: the follower load makes the stability undecided.
    eq = rod3d.solve(again)
    assert eq.verdict == "undecided"


@pytest.mark.parametrize(("make", "field"), [
    (lambda: pl.DistributedLoad((1.0,)), "load.force"),
    (lambda: pl.DistributedLoad((0.0, math.nan, 0.0), name="q"), "q.force"),
    (lambda: pl.DistributedLoad((0.0, 1.0, 0.0), start=0.5, end=0.5, name="q"), "q.end"),
    (lambda: pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad((0.0, 1.0, 0.0),
                                                                  end=2.0, name="q"),)),
     "q.start"),
    (lambda: pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad((0.0, 1.0), name="q"),)),
     "q.force"),
    (lambda: pl.Problem(UNIT, (pl.clamp(0.0),), loads=(
        pl.DistributedLoad((0.0, 1.0), start=-0.5, end=0.5, name="q"),)), "q.start"),
])
def test_bad_loads_are_named(make, field):
    with pytest.raises(InputError) as err:
        make()
    assert err.value.field == field


def test_a_path_carries_its_loads():
    """interpolate() moves a load matched by name with the conditions."""
    start = pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad((0.0, 0.0, 0.0), name="q"),))
    end = pl.Problem(UNIT, (CLAMP,), loads=(pl.DistributedLoad((0.0, 0.0, -2.0), name="q"),))
    half = pl.interpolate(start, end, 0.5)
    assert half.loads[0].force == (0.0, 0.0, -1.0)


# -- a load type added on top of the nouns: mass carried by a stretch ------------------------
SLEEVE_TEXT = """
name = "sleeved"
gravity = [0.0, 0.0, -9.81]
[part]
length = 1.0
bending_stiffness = 1.0
torsional_stiffness = 1.0
mass_per_length = 1e-5
[[condition]]
name = "clamp"
s = 0.0
x = 0.0
y = 0.0
z = 0.0
tangent = [1.0, 0.0, 0.0]
normal = [0.0, 0.0, 1.0]
[[load]]
name = "sleeve"
mass_per_length = 2e-4
start = 0.3
"""


def test_added_mass_on_a_stretch_weighs_as_beam_theory_says_in_both_models():
    """A sleeve of 2e-4 kg/m on [0.3, 1] m of a unit cantilever whose own mass is 1e-5
    kg/m, under g = 9.81: the tip falls by the beam theory of both weights (small
    rotations: the nonlinear terms are O(w^3)), and the clamp carries both exactly."""
    problem = parse_problem(SLEEVE_TEXT)
    (sleeve,) = problem.loads
    assert isinstance(sleeve, pl.loads.AddedMass) and (sleeve.start, sleeve.end) == (0.3, None)
    g, own, carried, a = 9.81, 1e-5, 2e-4, 0.3
    tip = _beam_tip(own * g, 0.0) + _beam_tip(carried * g, a)
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=100))
    assert -eq.tip[0][2] == pytest.approx(tip, rel=1e-4)
    weight = g * (own * 1.0 + carried * (1.0 - a))
    assert eq.loads["clamp"].force[2] == pytest.approx(weight, rel=1e-9)
    flat = pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=own),
                      (pl.clamp(0.0),), gravity=(0.0, -g),
                      loads=(pl.loads.AddedMass(carried, start=a, name="sleeve"),))
    eq2 = elastica2d.solve(flat)
    assert -eq2.tip[1] == pytest.approx(tip, rel=1e-4)
    assert eq2.loads["clamp"].force[1] == pytest.approx(weight, rel=1e-9)


def test_added_mass_reads_back_what_it_wrote_and_weighs_nothing_without_gravity():
    problem = parse_problem(SLEEVE_TEXT)
    again = parse_problem(dump_problem(problem))
    assert again.loads == problem.loads and again.distributed == problem.distributed
    weightless = pl.Problem(UNIT, (CLAMP,), loads=problem.loads)
    assert weightless.distributed[0].force == (0.0, 0.0, 0.0)
    with pytest.raises(FileFormatError, match=r"load\[0\]: give one of .* mass_per_length"):
        parse_problem(SLEEVE_TEXT + "force = [0.0, 0.0, 1.0]\n")


@pytest.mark.parametrize(("make", "field"), [
    (lambda: pl.loads.AddedMass(-1.0, name="sleeve"), "sleeve.mass_per_length"),
    (lambda: pl.loads.AddedMass(0.1, start=0.6, end=0.2, name="sleeve"), "sleeve.end"),
    (lambda: pl.Problem(UNIT, (CLAMP,), loads=(pl.loads.AddedMass(0.1, end=3.0,
                                                                  name="sleeve"),)),
     "sleeve.start"),
    (lambda: pl.Problem(UNIT, (CLAMP,), loads=("heavy",)), "loads[0]"),
])
def test_bad_added_masses_are_named(make, field):
    with pytest.raises(InputError) as err:
        make()
    assert err.value.field == field
