"""The 2D elastica against closed forms: elliptic integrals, arcs, small deflections."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

import pliant as pl
from pliant.core.events import LoadsStaged
from pliant.models.elastica2d import ShootingSolver, solve
from pliant.models.elastica2d.reference import equilibrium_error


def cantilever_tip(alpha: float) -> tuple[float, float, float]:
    """Tip (x/L, y/L, angle) of a cantilever clamped along +x with a dead tip force P
    along +y, alpha = P L^2 / EI (Bisshopp and Drucker's elliptic-integral solution).

    With EI theta'' = -P cos(theta) and theta'(L) = 0, the substitution
    1 + sin(theta) = 2 k^2 sin^2(psi), k^2 = (1 + sin(phi0)) / 2, phi0 the tip angle, gives
        sqrt(alpha) = K(k) - F(psi1, k),       sin(psi1) = 1 / (k sqrt 2)   (theta = 0)
        y / L = 1 - 2 (E(k) - E(psi1, k)) / sqrt(alpha)
        x / L = sqrt(2 sin(phi0) / alpha).
    """

    def length_mismatch(phi0: float) -> float:
        m = (1.0 + math.sin(phi0)) / 2.0
        psi1 = math.asin(1.0 / math.sqrt(2.0 * m))
        return ellipk(m) - ellipkinc(psi1, m) - math.sqrt(alpha)

    phi0 = brentq(length_mismatch, 1e-12, math.pi / 2 - 1e-12, xtol=1e-15, rtol=1e-15)
    m = (1.0 + math.sin(phi0)) / 2.0
    psi1 = math.asin(1.0 / math.sqrt(2.0 * m))
    y = 1.0 - 2.0 * (ellipe(m) - ellipeinc(psi1, m)) / math.sqrt(alpha)
    x = math.sqrt(2.0 * math.sin(phi0) / alpha)
    return x, y, phi0


def test_closed_form_matches_small_deflection_limit():
    # The helper itself: for a small load the tip deflection is P L^3 / 3 EI.
    _x, y, phi = cantilever_tip(1e-4)
    assert y == pytest.approx(1e-4 / 3.0, rel=1e-6)
    assert phi == pytest.approx(1e-4 / 2.0, rel=1e-6)


@pytest.mark.parametrize("alpha", [0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 35.0, 50.0])
@pytest.mark.parametrize("length,stiffness", [(1.0, 1.0), (0.8, 0.05)])
def test_cantilever_dead_tip_load_elliptic(alpha, length, stiffness):
    part = pl.Part(length=length, bending_stiffness=stiffness)
    force = alpha * stiffness / length**2
    problem = pl.Problem(part, (pl.clamp(0.0), pl.push(length, force=(0.0, force))))
    eq = solve(problem)
    x, y, phi = cantilever_tip(alpha)
    tip = eq.tip
    assert abs(tip[0] - x * length) <= 1e-8 * length
    assert abs(tip[1] - y * length) <= 1e-8 * length
    assert abs(tip[2] - phi) <= 1e-8
    # The path ran on its own floor (path_min_density, 4 steps per length where the
    # loads are light); the answer is on the answers' (min_density) or finer.
    assert eq.state.mesh.density >= ShootingSolver().min_density
    # The clamp takes the whole load, and the moment P x_tip.
    clamp = eq.reactions["clamp"]
    assert clamp.force == pytest.approx([0.0, -force], abs=1e-9 * force)
    assert clamp.moment == pytest.approx(-force * x * length, rel=1e-8)


@pytest.mark.parametrize("turns", [0.1, 0.25, 0.5, 0.9])
def test_end_moment_bends_an_arc(turns):
    length, stiffness = 1.3, 2.0
    moment = 2.0 * math.pi * turns * stiffness / length
    part = pl.Part(length=length, bending_stiffness=stiffness)
    eq = solve(pl.Problem(part, (pl.clamp(0.0), pl.push(length, moment=moment))))
    kappa = moment / stiffness
    s = eq.s
    assert np.allclose(eq.position[:, 0], np.sin(kappa * s) / kappa, atol=1e-10)
    assert np.allclose(eq.position[:, 1], (1.0 - np.cos(kappa * s)) / kappa, atol=1e-10)
    assert np.allclose(eq.bending_moment, moment, atol=1e-10 * moment)
    assert eq.energy == pytest.approx(moment**2 * length / (2.0 * stiffness), rel=1e-10)


def test_moment_two_pi_rolls_a_full_circle():
    length, stiffness = 1.0, 1.0
    part = pl.Part(length=length, bending_stiffness=stiffness)
    eq = solve(pl.Problem(part, (pl.clamp(0.0),
                                 pl.push(length, moment=2 * math.pi * stiffness / length))))
    x, y, angle = eq.tip
    assert abs(x) <= 1e-9 and abs(y) <= 1e-9
    assert angle == pytest.approx(2 * math.pi, abs=1e-9)
    radius, _ = eq.min_bend_radius()
    assert radius == pytest.approx(length / (2 * math.pi), rel=1e-9)


def test_self_weight_small_deflection():
    # q L^4 / (8 EI) for a cantilever under its own weight; q L^3 / EI = 1e-3 keeps the
    # geometric nonlinearity (relative size ~ (q L^3 / EI)^2) far below the tolerance.
    length, stiffness, g = 0.7, 3.0, 9.81
    mass = 1e-3 * stiffness / (g * length**3)
    part = pl.Part(length=length, bending_stiffness=stiffness, mass_per_length=mass)
    eq = solve(pl.Problem(part, (pl.clamp(0.0),), gravity=(0.0, -g)))
    q = mass * g
    assert eq.tip[1] == pytest.approx(-q * length**4 / (8 * stiffness), rel=1e-5)
    assert eq.tip[2] == pytest.approx(-q * length**3 / (6 * stiffness), rel=1e-5)
    assert eq.reactions["clamp"].force[1] == pytest.approx(q * length, rel=1e-12)


def test_rest_curvature_unloaded_is_the_rest_arc():
    kappa = 2.5
    part = pl.Part(length=1.0, bending_stiffness=1.0, rest_curvature=kappa)
    eq = solve(pl.Problem(part, (pl.clamp(0.0),)))
    assert np.allclose(eq.position[:, 1], (1 - np.cos(kappa * eq.s)) / kappa, atol=1e-12)
    assert np.allclose(eq.bending_moment, 0.0, atol=1e-12)
    # Straightening it takes the moment -EI kappa0.
    eq = solve(pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, moment=-kappa))))
    assert np.allclose(eq.position[:, 1], 0.0, atol=1e-10)


def test_convergence_order_is_eight():
    """Tip error against a fine mesh falls like h^8, the order of the Runge-Kutta
    scheme (checked on the elastica itself, alpha = 50)."""
    part = pl.Part(length=1.0, bending_stiffness=1.0)
    problem = pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, force=(0.0, 50.0))))
    x, y, phi = cantilever_tip(50.0)

    def error(density: int) -> float:
        solver = ShootingSolver(accuracy=1e9, path_accuracy=1e9, min_density=density,
                                path_min_density=density, samples=density)
        eq = solve(problem, solver=solver)
        assert eq.state.mesh.density == density
        return max(abs(eq.tip[0] - x), abs(eq.tip[1] - y), abs(eq.tip[2] - phi))

    e1, e2 = error(10), error(20)
    order = math.log2(e1 / e2)
    assert 7.0 <= order <= 9.5, (e1, e2, order)


def test_a_heavy_cable_clamped_at_one_end_hangs_under_its_weight():
    """A cable clamped level at one end hangs down under q L^3 / EI = 3e5 (a thin cable
    10 m long, EI = 0.03 N m^2): its continuation used to accept its first points at a
    loose tolerance set by the full weight, drift off the branch and stop at "a fold"
    at t = 2e-4. Checked without the shooting: re-integrated by solve_ivp from its
    samples, the clamp carries the whole weight, and the moment of the weight about
    the clamp; the tip hangs within a bending layer of the clamp's vertical."""
    length, q = 10.0, 9.81
    part = pl.Part(length=length, bending_stiffness=q * length**3 / 3e5, mass_per_length=1.0)
    eq = solve(pl.Problem(part, (pl.clamp(0.0),), gravity=(0.0, -9.81)),
               solver=ShootingSolver(time_budget=3600.0))
    assert equilibrium_error(eq) < 1e-7
    clamp = eq.reactions["clamp"]
    assert clamp.force == pytest.approx([0.0, q * length], abs=1e-8 * q * length)
    x = eq.position[:, 0]
    assert clamp.moment == pytest.approx(q * float(np.trapezoid(x, eq.s)), rel=1e-5)
    layer = (part.bending_stiffness / q) ** (1.0 / 3.0)  # where the part turns down
    assert eq.tip[1] < -(length - 3.0 * layer) and 0.0 < eq.tip[0] < 3.0 * layer


def test_a_heavy_cable_clamped_pointing_up_falls_over_and_hangs():
    """A cable clamped pointing up, 0.6 degrees off the vertical, under q L^3 / EI = 3e5:
    past Greenhill's load (7.84) it falls over to its tilt's side, then hangs. Every path
    from the unloaded part to the whole weight left its branch at a thousandth of the
    way (a "fold" that is not there: at each load on the way a solve of its own answers),
    so the weight is applied in stages, and the answer says so. Checked without the
    shooting, as the clamped level cable above."""
    length, q = 1.0, 3e5
    part = pl.Part(length=length, bending_stiffness=1.0, mass_per_length=q / 9.81)
    angle = math.pi / 2 - 0.011
    eq = solve(pl.Problem(part, (pl.clamp(0.0, angle=angle),), gravity=(0.0, -9.81)),
               solver=ShootingSolver(time_budget=3600.0))
    assert any(isinstance(n, LoadsStaged) for n in eq.notes)
    assert equilibrium_error(eq) < 1e-7
    clamp = eq.reactions["clamp"]
    assert clamp.force == pytest.approx([0.0, q * length], abs=1e-8 * q * length)
    x = eq.position[:, 0]
    assert clamp.moment == pytest.approx(q * float(np.trapezoid(x, eq.s)), rel=1e-5)
    layer = (part.bending_stiffness / q) ** (1.0 / 3.0)
    # fallen to the side it leans to (+x), hanging within a bending layer of the clamp
    assert eq.tip[1] < -(length - 3.0 * layer) and 0.0 < eq.tip[0] < 3.0 * layer
    assert eq.stable


def test_floppy_cable_hangs_as_a_catenary():
    """A cable pinned at both ends under its own weight tends to the catenary
    y = a cosh(x / a) as EI -> 0; at q L^3 / EI = 1e5 single shooting would be hopeless
    (sensitivities ~ exp(300)), multiple shooting is not, up to 1e6."""
    length, span = 1.0, 0.8
    a = brentq(lambda a: 2 * a * math.sinh(span / (2 * a)) - length, 0.01, 100.0)

    # The stiffest path takes about a second of its 30 s budget here; compiled without
    # optimisation (NUMBA_OPT=0) it took longer than that. The shape is what is tested.
    patient = ShootingSolver(time_budget=3600.0)

    def shape_error(q_l3_ei: float) -> float:
        part = pl.Part(length=length, bending_stiffness=1.0, mass_per_length=q_l3_ei / 9.81)
        eq = solve(pl.Problem(part, (pl.pin(0.0, (0.0, 0.0)),
                                     pl.pin(length, (span, 0.0), name="right")),
                              gravity=(0.0, -9.81)), solver=patient)
        x, y = eq.position[:, 0], eq.position[:, 1]
        catenary = a * np.cosh((x - span / 2) / a) - a * math.cosh(span / (2 * a))
        return float(np.abs(y - catenary).max())

    coarse, fine = shape_error(1e3), shape_error(1e5)
    assert fine < 1e-3 * length
    assert fine < coarse / 3.0
    # The heaviest cable a problem may be (k L near 1000, on 124 intervals): its answer
    # used to time out after 74 s of a 30 s budget, the energy's minimum tried on 1,984
    # intervals (a gigabyte's Jacobian); now on no more than MAX_INTERVALS. Its boundary
    # layers, about 1 / k thick, shrink with sqrt(10) from 1e5.
    assert shape_error(1e6) < fine / 2.0


def test_no_branch_jump_over_a_dense_load_sweep():
    """The answer is the branch continuity from the unloaded part reaches: for every
    load up to F L^2 / EI = 100 the tip is the elliptic-integral one (a jump to one of
    the looped equilibria that coexist at large loads would miss it by ~0.1 L)."""
    part = pl.Part(length=1.0, bending_stiffness=1.0)
    worst = 0.0
    for alpha in np.linspace(0.5, 100.0, 60):
        eq = solve(pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, force=(0.0, alpha)))))
        x, y, phi = cantilever_tip(alpha)
        worst = max(worst, abs(eq.tip[0] - x), abs(eq.tip[1] - y), abs(eq.tip[2] - phi))
    assert worst <= 1e-8


@pytest.mark.parametrize("scale", [0.7, 2.05])
def test_deep_compression_follows_the_stable_branch(scale):
    """A cantilever pushed along its axis at 8 to 25 times its Euler load (with a small
    side load): the cold solve ends where a slow continuation of 400 small steps ends,
    not on the nearby unstable S-shapes (which have a higher potential energy)."""
    part = pl.Part(length=1.0, bending_stiffness=1.0)

    def problem(f: float) -> pl.Problem:
        return pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, force=(-30 * f, 3 * f),
                                                        name="tip")))

    *_, slow = pl.trace([problem(f) for f in np.linspace(0.0, scale, 401)[1:]])
    cold = solve(problem(scale))
    assert np.allclose(cold.tip, slow.tip, atol=1e-8)
    load = np.array([-30 * scale, 3 * scale])
    potential = cold.energy - load @ np.array(cold.tip[:2])
    assert potential < 0.0  # the S-shaped equilibria have a positive potential energy


@pytest.mark.parametrize("knots", [((0.0, 0.0), (0.5, 2.0)), ((0.3, 1.0), (0.7, -1.0)),
                                   ((0.2, 3.0),), ((0.1, 0.0), (0.4, 2.0), (0.9, -1.0))])
def test_an_unloaded_part_takes_its_rest_profile_whatever_its_knots(knots):
    """With nothing on it the free end's angle is the rest curvature's integral: linear
    between the knots and constant beyond the first and the last (two knots inside the
    part used to be read as a line from s = 0 to L)."""
    part = pl.Part(1.0, 1.0, rest_curvature=knots)
    eq = pl.solve(pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, force=(0.0, 0.0)))))
    s = np.linspace(0.0, 1.0, 20001)
    kappa = np.array([part.rest_curvature_at(x) for x in s])
    expected = float(np.sum(0.5 * (kappa[1:] + kappa[:-1]) * np.diff(s)))
    assert eq.tip[2] == pytest.approx(expected, abs=1e-7)
    assert eq.residual < 1e-10
