"""Property tests: over random well-posed 2D problems the solver returns a converged
equilibrium that meets its conditions and balances, or a typed error. Never anything
else, and never a silent wrong answer."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.errors import ConvergenceError, PliantError
from pliant.models.elastica2d import solve

from .test_elastica2d_invariants import balance


@st.composite
def problems(draw):
    length = draw(st.floats(0.3, 2.0))
    stiffness = draw(st.floats(0.01, 10.0))
    mass = draw(st.sampled_from([0.0, draw(st.floats(0.0, 0.5))]))
    kappa0 = draw(st.sampled_from([0.0, draw(st.floats(-2.0, 2.0)) / length]))
    part = pl.Part(length=length, bending_stiffness=stiffness, mass_per_length=mass,
                   rest_curvature=kappa0)
    gravity = draw(st.sampled_from([(0.0, 0.0), (0.0, -9.81), (3.0, -9.0)]))
    force = stiffness / length**2  # F L^2 / EI = 1
    origin = (draw(st.floats(-1, 1)), draw(st.floats(-1, 1)))
    angle0 = draw(st.floats(-math.pi, math.pi))
    first = draw(st.sampled_from(["clamp", "pin"]))
    conditions = [pl.clamp(0.0, position=origin, angle=angle0) if first == "clamp"
                  else pl.pin(0.0, position=origin)]
    magnitude = st.floats(-15.0, 15.0)
    if draw(st.booleans()):
        s_mid = draw(st.floats(0.2, 0.8)) * length
        if draw(st.booleans()):
            conditions.append(pl.push(s_mid, force=(draw(magnitude) * force,
                                                    draw(magnitude) * force),
                                      follower=draw(st.booleans()), name="middle"))
        else:
            reach = draw(st.floats(0.3, 0.95)) * s_mid
            heading = draw(st.floats(-math.pi, math.pi))
            conditions.append(pl.grip(s_mid, position=(origin[0] + reach * math.cos(heading),
                                                       origin[1] + reach * math.sin(heading)),
                                      name="middle"))
    tip = draw(st.sampled_from(["free", "load", "moment", "grip", "pose"]))
    if tip == "load":
        conditions.append(pl.push(length, force=(draw(magnitude) * force,
                                                 draw(magnitude) * force),
                                  follower=draw(st.booleans()), name="tip"))
    elif tip == "moment":
        conditions.append(pl.push(length, moment=draw(st.floats(-6, 6)) * stiffness / length,
                                  name="tip"))
    elif tip in ("grip", "pose"):
        reach = draw(st.floats(0.3, 0.95)) * length
        heading = draw(st.floats(-math.pi, math.pi))
        conditions.append(pl.grip(length, position=(origin[0] + reach * math.cos(heading),
                                                    origin[1] + reach * math.sin(heading)),
                                  angle=draw(st.floats(-math.pi, math.pi)) if tip == "pose"
                                  else None, name="tip"))
    return part, tuple(conditions), gravity


@settings(max_examples=60, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(problems())
def test_converged_and_consistent_or_typed_error(spec):
    part, conditions, gravity = spec
    try:
        problem = pl.Problem(part, conditions, gravity)
        eq = solve(problem)
    except ConvergenceError as err:
        assert err.residual >= 0.0 and "no equilibrium" in str(err)
        return
    except PliantError:
        return
    assert eq.residual <= 1e-9
    length = part.length
    for cond in problem.conditions:
        i = int(np.argmin(np.abs(eq.s - cond.s)))
        for k in (0, 1):
            if cond.position[k] is not None:
                assert abs(eq.position[i, k] - cond.position[k]) <= 1e-8 * length
        if cond.angle is not None:
            assert abs(eq.angle[i] - cond.angle) <= 1e-8
    force, moment = balance(eq)
    scale = max(1.0, max(float(np.abs(ld.force).max()) for ld in eq.loads.values()),
                part.mass_per_length * 9.81 * length)
    assert np.abs(force).max() <= 1e-8 * scale
    assert abs(moment) <= 1e-5 * scale * (length + 2.0)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(fx=st.floats(-50, 50), fy=st.floats(-50, 50), moment=st.floats(-6.0, 6.0),
       follower=st.booleans(), weight=st.floats(0.0, 30.0))
def test_everyday_loadings_always_converge(fx, fy, moment, follower, weight):
    """A clamped part under any tip load up to F L^2 / EI = 50, a tip moment up to one
    full turn and its own weight up to q L^3 / EI = 30: always an answer."""
    part = pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=weight / 9.81)
    problem = pl.Problem(part, (pl.clamp(0.0),
                                pl.push(1.0, force=(fx, fy), moment=moment, follower=follower,
                                        name="tip")), gravity=(0.0, -9.81))
    eq = solve(problem)
    assert eq.residual <= 1e-9
    assert np.isclose(eq.tip[0], eq.position[-1, 0])


_STRETCH_RUNS = {"tried": 0, "converged": 0}


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(fx=st.floats(-40, 40), fy=st.floats(-40, 40), weight=st.floats(0.0, 20.0),
       slenderness=st.floats(-6.0, -2.5), reach=st.floats(-1.0, 1.0),
       held=st.booleans())
def test_extensible_parts_converge_and_meet_the_re_integrated_ode(fx, fy, weight,
                                                                  slenderness, reach, held):
    """Random extensible parts (EI / EA L^2 from 1e-6 to 3e-3): a clamped part under a
    tip load and its weight, or held at its tip at about its length (a cable pulled
    taut). Each answer is re-integrated with solve_ivp from its own samples (the
    extensible ODE) and must meet it; at least 95 % converge (the floor is checked by the
    next test). Before the homotopy started soft, 6 of these 40 failed (stiff parts held
    taut: tensions of hundreds to thousands of EI / L^2)."""
    from pliant.models.elastica2d.reference import equilibrium_error

    part = pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=weight / 9.81,
                   axial_stiffness=10.0 ** -slenderness)
    if held:
        tip = pl.grip(1.0, position=(1.0 + 0.01 * reach, 0.1 * fy / 40.0), name="tip")
    else:
        tip = pl.push(1.0, force=(fx, fy), name="tip")
    problem = pl.Problem(part, (pl.clamp(0.0), tip), gravity=(0.0, -9.81))
    _STRETCH_RUNS["tried"] += 1
    try:
        eq = solve(problem)
    except ConvergenceError as err:
        assert "no equilibrium" in str(err)
        return
    _STRETCH_RUNS["converged"] += 1
    assert eq.residual <= 1e-9
    assert equilibrium_error(eq) <= 1e-7


def test_extensible_parts_converge_at_least_95_percent_of_the_time():
    if _STRETCH_RUNS["tried"] == 0:  # run alone: run the property test first
        test_extensible_parts_converge_and_meet_the_re_integrated_ode()
    assert _STRETCH_RUNS["converged"] >= 0.95 * _STRETCH_RUNS["tried"]
