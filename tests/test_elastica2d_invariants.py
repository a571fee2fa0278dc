"""Invariants of 2D equilibria: balance, the ODE itself, symmetry, round trips,
agreement with solve_bvp, exact derivatives, warm starts and continuation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.io.problem_file import load_problem
from pliant.models.elastica2d import ShootingSolver, kernels, minimum, solve, trace
from pliant.models.elastica2d.lowering import lower
from pliant.models.elastica2d.reference import equilibrium_error, solve_reference

from .helpers import EXAMPLES, shape_at, shooting_jacobians, zoo


def balance(eq: pl.Equilibrium) -> tuple[np.ndarray, float]:
    """Sum of all forces [N] and of all moments about the origin [N m] on the part."""
    problem = eq.problem
    q = problem.part.mass_per_length * np.asarray(problem.gravity)
    force = sum((ld.force for ld in eq.loads.values()), np.zeros(2))
    moment = sum(ld.moment for ld in eq.loads.values())
    for ld in eq.loads.values():
        i = int(np.argmin(np.abs(eq.s - ld.s)))
        r = eq.position[i]
        moment += r[0] * ld.force[1] - r[1] * ld.force[0]
    # Distributed weight: integrate r x q along s, segment by segment (trapezoid would
    # be too coarse; Simpson on each segment's uniform samples is plenty here).
    cuts = np.nonzero(np.diff(eq.s) == 0.0)[0] + 1
    for seg_s, seg_r in zip(np.split(eq.s, cuts), np.split(eq.position, cuts)):
        integrand = seg_r[:, 0] * q[1] - seg_r[:, 1] * q[0]
        moment += _simpson(integrand, seg_s)
    force = force + q * problem.part.length
    return force, moment


def _simpson(f: np.ndarray, s: np.ndarray) -> float:
    if f.size < 3:
        return float(np.trapezoid(f, s))
    if f.size % 2 == 0:  # odd number of intervals: Simpson on all but the last
        return _simpson(f[:-1], s[:-1]) + float(np.trapezoid(f[-2:], s[-2:]))
    h = (s[-1] - s[0]) / (f.size - 1)
    return float(h / 3.0 * (f[0] + f[-1] + 4.0 * f[1:-1:2].sum() + 2.0 * f[2:-1:2].sum()))


@pytest.mark.parametrize("name", sorted(zoo()))
def test_global_balance(name):
    eq = solve(zoo()[name])
    force, moment = balance(eq)
    scale = max(1.0, max(float(np.abs(ld.force).max()) for ld in eq.loads.values()))
    assert np.abs(force).max() <= 1e-9 * scale
    assert abs(moment) <= 1e-6 * scale * eq.problem.part.length


@pytest.mark.parametrize("name", sorted(zoo()))
def test_arrays_satisfy_the_elastica(name):
    """Differentiate the returned arrays numerically and check the paper's equations:
    x' = cos theta, y' = sin theta, EI (theta' - kappa0) = M, n' = -q, M' = -(t x n)."""
    eq = solve(zoo()[name], solver=ShootingSolver(samples=400))
    part = eq.problem.part
    q = part.mass_per_length * np.asarray(eq.problem.gravity)
    cuts = np.nonzero(np.diff(eq.s) == 0.0)[0] + 1
    worst = 0.0
    for idx in np.split(np.arange(eq.s.size), cuts):
        if idx.size < 7:
            continue
        s = eq.s[idx]
        h = s[1] - s[0]

        def d(f, h=h):  # 4th-order central difference at the interior samples
            return (f[:-4] - 8 * f[1:-3] + 8 * f[3:-1] - f[4:]) / (12 * h)

        inner = slice(2, -2)
        th = eq.angle[idx]
        n = eq.internal_force[idx]
        m = eq.bending_moment[idx]
        kappa0 = np.array([part.rest_curvature_at(v) for v in s])
        scale_m = max(1.0, np.abs(m).max())
        residuals = [
            d(eq.position[idx, 0]) - np.cos(th[inner]),
            d(eq.position[idx, 1]) - np.sin(th[inner]),
            (part.bending_stiffness * (d(th) - kappa0[inner]) - m[inner]) / scale_m,
            (d(n[:, 0]) + q[0]) / max(1.0, np.abs(n).max()),
            (d(n[:, 1]) + q[1]) / max(1.0, np.abs(n).max()),
            (d(m) + (np.cos(th) * n[:, 1] - np.sin(th) * n[:, 0])[inner]) / scale_m,
        ]
        worst = max(worst, max(float(np.abs(r).max()) for r in residuals))
    assert worst <= 1e-5


@pytest.mark.parametrize("name", ["case1", "case2", "case3", "gravity grip",
                                  "pre-curved pin"])
def test_mirroring_the_load_mirrors_the_answer(name):
    problem = zoo()[name]
    mirrored = problem.with_conditions(
        pl.Condition(s=c.s, name=c.name,
                     position=(c.position[0], None if c.position[1] is None else -c.position[1]),
                     angle=None if c.angle is None else -c.angle,
                     force=(c.force[0], None if c.force[1] is None else -c.force[1]),
                     moment=None if c.moment is None else -c.moment, follower=c.follower)
        for c in problem.conditions)
    part = problem.part
    mirrored = pl.Problem(
        pl.Part(length=part.length, bending_stiffness=part.bending_stiffness,
                mass_per_length=part.mass_per_length,
                rest_curvature=tuple((s, -k) for s, k in part.rest_knots)),
        mirrored.conditions, (problem.gravity[0], -problem.gravity[1]), problem.name)
    a, b = solve(problem), solve(mirrored)
    assert np.allclose(a.position[:, 0], b.position[:, 0], atol=1e-9)
    assert np.allclose(a.position[:, 1], -b.position[:, 1], atol=1e-9)
    assert np.allclose(a.bending_moment, -b.bending_moment, atol=1e-8)
    for key in a.loads:
        fa, fb = a.loads[key].force, b.loads[key].force
        assert np.allclose([fa[0], fa[1]], [fb[0], -fb[1]], atol=1e-8)


def test_case3_round_trip_through_force_space():
    """Case 3's computed tip load, applied as a load, brings the tip back to
    (0.7, 0.4, 0) within 1e-8: the reactions are the loads that make the shape."""
    problem = load_problem(EXAMPLES / "paper" / "case3.toml")
    eq = solve(problem)
    hole = eq.reactions["hole"]
    pushed = problem.with_conditions([problem.condition("clamp"),
                                      pl.push(1.0, force=tuple(hole.force),
                                              moment=hole.moment, name="hole")])
    back = solve(pushed, warm_start=eq)
    assert np.allclose(back.tip, (0.7, 0.4, 0.0), atol=1e-8)
    assert np.allclose(back.reactions["clamp"].force, eq.reactions["clamp"].force,
                       atol=1e-8)


def _case3_at(problem: pl.Problem, t: float) -> pl.Problem:
    """Case 3 with its hole moved t of the way from the straight shape's tip."""
    return problem.with_conditions([problem.condition("clamp"), pl.clamp(
        1.0, position=(1 - 0.3 * t, 0.4 * t), angle=0.0, name="hole")])


def test_case3_answer_is_stable_under_the_other_route():
    """Following the hand from the straight shape to the hole in 50 steps ends on the
    equilibrium the cold solve finds."""
    problem = load_problem(EXAMPLES / "paper" / "case3.toml")
    cold = solve(problem)
    hole = problem.condition("hole")
    path = [_case3_at(problem, t) for t in np.linspace(0.02, 1.0, 50)]
    *_, last = trace(path)
    assert last.problem.condition("hole").position == hole.position
    assert np.allclose(last.reactions["clamp"].force, cold.reactions["clamp"].force,
                       atol=1e-7)
    assert last.reactions["clamp"].moment == pytest.approx(cold.reactions["clamp"].moment,
                                                           abs=1e-7)


def test_a_path_that_reuses_its_jacobians_keeps_its_answers(monkeypatch):
    """Along a path a step starts from the cubic through the last answers, with the
    Jacobian extrapolated from the last ones shot: on most of 150 steps the kernel's
    Newton gets one (it need not integrate the sensitivities). Each answer is the one
    a warm start from the step before finds with a Jacobian of its own, re-integrated
    by solve_ivp to 1e-8, and out and back along the same line (where the
    extrapolation overshoots the turn) the answers on the way back are those on the
    way out."""
    problem = load_problem(EXAMPLES / "paper" / "case3.toml")
    given_jacobians = []
    newton = kernels.newton

    def counted(z0, jac0, *args):
        given_jacobians.append(jac0.shape[0] == z0.shape[0])
        return newton(z0, jac0, *args)

    monkeypatch.setattr(kernels, "newton", counted)
    ts = np.linspace(0.01, 0.75, 75)
    path = [_case3_at(problem, t) for t in np.concatenate([ts, ts[-2::-1]])]
    answers = list(trace(path))
    assert sum(given_jacobians) >= len(path) // 2
    for i in range(1, len(path), 15):
        mine = solve(path[i], warm_start=answers[i - 1])
        np.testing.assert_allclose(answers[i].position, mine.position, atol=1e-9)
        assert equilibrium_error(answers[i]) < 1e-8
    way_out, way_back = answers[:74], answers[-1:74:-1]
    for out, back in zip(way_out, way_back, strict=True):
        assert out.problem.condition("hole").position == back.problem.condition(
            "hole").position
        np.testing.assert_allclose(back.loads["clamp"].force, out.loads["clamp"].force,
                                   atol=1e-8)


def test_a_path_restarts_its_extrapolation_where_its_structure_changes():
    """A grip switched to force control half way along a path (and back) changes the
    unknowns: the steps after it start afresh and still hold the target."""
    part = pl.Part(length=1.0, bending_stiffness=0.4, mass_per_length=0.2)

    def held(t: float, pushed: pl.Equilibrium | None = None) -> pl.Problem:
        at = (0.45 - 0.1 * t, 0.2 + 0.1 * t)
        hand = (pl.grip(0.6, position=at, name="hand") if pushed is None else
                pl.push(0.6, force=tuple(pushed.loads["hand"].force), name="hand"))
        return pl.Problem(part, (pl.clamp(0.0), hand), gravity=(0.0, -9.81))

    first = list(trace([held(t) for t in np.linspace(0.0, 0.5, 8)]))
    switched = next(trace([held(0.5, first[-1])], start=first[-1]))
    rest = list(trace([held(t) for t in np.linspace(0.5, 1.0, 8)[1:]], start=switched))
    for eq in (*first, switched, *rest):
        assert equilibrium_error(eq) < 1e-8
    i = int(np.argmin(np.abs(switched.s - 0.6)))
    np.testing.assert_allclose(switched.position[i], first[-1].position[i], atol=1e-8)
    cold = solve(held(1.0), warm_start=rest[-2])
    np.testing.assert_allclose(rest[-1].position, cold.position, atol=1e-9)


@pytest.mark.parametrize("name", sorted(zoo()))
def test_agrees_with_solve_bvp(name):
    problem = zoo()[name]
    eq = solve(problem)
    ref = solve_reference(problem, guess=eq, tol=1e-8)
    assert ref.success, ref.message
    assert np.allclose(ref.tip, eq.tip, atol=1e-7)
    n0 = eq.internal_force[0]
    m0 = eq.bending_moment[0]
    scale = max(1.0, float(np.abs(n0).max()), abs(m0))
    assert np.allclose(ref.first, (n0[0], n0[1], m0), atol=1e-6 * scale)


@pytest.mark.parametrize("name", sorted(zoo()))
def test_jacobian_matches_finite_differences(name):
    problem = zoo()[name]
    eq = solve(problem)
    low = eq.state.low  # the lowering it was solved with (restart nodes included)
    rng = np.random.default_rng(7)
    z = eq.state.z + 0.05 * rng.standard_normal(low.nz)
    jac, fd = shooting_jacobians(low, z, low.mesh(24))
    assert np.allclose(jac, fd, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(jac).max()))


def test_warm_start_gives_the_cold_answer():
    problem = zoo()["case2"]
    cold = solve(problem)
    nearby = problem.with_conditions(
        [c if c.name != "hand 1" else pl.push(1.0, force=(0.0, 6.5), follower=True,
                                              name="hand 1") for c in problem.conditions])
    warm_from = solve(nearby)
    warm = solve(problem, warm_start=warm_from)
    assert np.allclose(warm.position, cold.position, atol=1e-9)
    assert warm.steps <= 2


def test_switching_a_grip_to_force_control_keeps_the_shape():
    """The reaction of a position-held grip, applied as a push, holds the same shape;
    the warm start crosses from one structure to the other."""
    part = pl.Part(length=1.0, bending_stiffness=0.4, mass_per_length=0.2)
    held = pl.Problem(part, (pl.clamp(0.0), pl.grip(0.6, position=(0.45, 0.2), name="hand")),
                      gravity=(0.0, -9.81))
    eq = solve(held)
    hand = eq.reactions["hand"]
    pushed = held.with_conditions([held.condition("clamp"),
                                   pl.push(0.6, force=tuple(hand.force), name="hand")])
    eq2 = solve(pushed, warm_start=eq)
    i = int(np.argmin(np.abs(eq2.s - 0.6)))
    assert np.allclose(eq2.position[i], (0.45, 0.2), atol=1e-8)


def test_a_long_path_stops_at_its_deadline_inside_the_kernel():
    """A cable clamped at one end under q L^3 / EI = 1e6 takes seconds in one
    continuation call (a budget read only between calls overran 0.01 s by seconds; on
    a cable held at both ends, by 1.9 s). With its deadline already past, the kernel
    stops at its first look at the clock, after CLOCK_WORK of work, on the way
    (0 < t < 1) and says why (BUDGET, OUT_OF_TIME); without one, the same path goes on
    past that point."""
    cable = pl.Problem(pl.Part(10.0, 0.01, mass_per_length=1.0), (pl.clamp(0.0),),
                       gravity=(0.0, -9.81))
    low = lower(cable)
    mesh = low.mesh(8)
    rest, z0 = low.rest(mesh)
    args = (z0, mesh.density, low.stations, rest.inputs, low.target.inputs)
    opts = ShootingSolver().options
    late = kernels.follow(*args, opts, low.interval, -math.inf)
    assert late[5] == kernels.BUDGET and late[6] == kernels.OUT_OF_TIME
    assert 0.0 < late[7] < 1.0 and late[9] >= 1
    more = opts.copy()
    more[kernels.OPT_MAX_STEPS] = late[9] + 5
    free = kernels.follow(*args, more, low.interval, math.inf)
    assert free[6] != kernels.OUT_OF_TIME and free[7] > late[7]


def test_kernel_newton_reports_a_singular_start():
    """The straight part with its tip pulled back along its axis is singular (the chord
    cannot shorten to first order): the kernel says so instead of diverging, and the
    solver still finds the buckled answer."""
    part = pl.Part(length=1.0, bending_stiffness=1.0)
    problem = pl.Problem(part, (pl.clamp(0.0), pl.clamp(1.0, position=(0.9, 0.0), name="tip")))
    low = lower(problem)
    mesh = low.mesh(16)
    rest, z0 = low.rest(mesh)
    _, jac = low.shoot(z0, rest, mesh)
    assert np.abs(jac[0]).max() == 0.0  # d(tip x)/d(anything) vanishes at the straight part
    target = low.target
    out = kernels.newton(z0, np.zeros((0, 0)), *low.args(target, mesh), 1e-10, 10, 0.0)
    assert out[3] == kernels.SINGULAR
    eq = solve(problem)
    assert eq.tip[0] == pytest.approx(0.9, abs=1e-10)
    assert eq.notes and "singular start" in eq.notes[0]
    # Clamped-clamped post-buckling (the elastica of a pinned column of length L/2):
    # P L^2 / EI = 16 K(k)^2 with end shortening 1 - x/L = 2 (1 - E(k) / K(k)).
    from scipy.optimize import brentq
    from scipy.special import ellipe, ellipk

    m = brentq(lambda m: 2 * (1 - ellipe(m) / ellipk(m)) - 0.1, 1e-9, 0.99, xtol=1e-15)
    compression = eq.reactions["clamp"].force[0]
    assert compression == pytest.approx(16 * ellipk(m) ** 2, rel=1e-9)


@pytest.mark.parametrize("name", sorted(zoo()))
def test_retarget_equals_a_fresh_lowering(name):
    """A warm step reuses the last lowering's structure with new targets and loads: it
    must give exactly the arrays a full lowering gives."""
    problem = zoo()[name]
    moved = problem.with_conditions(
        pl.Condition(s=c.s, name=c.name,
                     position=tuple(None if p is None else p + 0.01 for p in c.position),
                     angle=None if c.angle is None else c.angle - 0.02,
                     force=tuple(None if f is None else 1.1 * f for f in c.force),
                     moment=None if c.moment is None else 0.9 * c.moment,
                     follower=c.follower)
        for c in problem.conditions)
    moved = pl.Problem(moved.part, moved.conditions, (0.3, -9.0), moved.name)
    fresh = lower(moved)
    again = lower(problem).retarget(moved)
    assert again is not None and again.key == fresh.key
    for a, b in ((again.target.val, fresh.target.val), (again.target.fol, fresh.target.fol),
                 (again.target.prm, fresh.target.prm), (again.inputs, fresh.inputs)):
        assert np.array_equal(a, b)
    # A different structure (one more station) is refused.
    other = problem.with_conditions(problem.conditions + (
        pl.push(0.37 * problem.part.length, force=(0.0, 0.1), name="other"),))
    assert lower(problem).retarget(other) is None


@pytest.mark.parametrize(("hand", "name"), [
    (pl.pin(1.0, position=(-0.3, 0.2), name="hand"), "target behind the clamp"),
    (pl.grip(1.0, position=(0.7, 0.4), angle=math.pi / 2, name="hand"), "up at the tip"),
    (pl.grip(1.0, position=(0.2, 0.6), angle=math.pi, name="hand"), "turned back"),
])
def test_targets_the_2d_routes_missed_are_reached_and_the_3d_model_agrees(hand, name):
    """Issue reports: these were refused with "no equilibrium" although one exists (and
    it is stable). pliant now reaches each (by its routes, or where the paths meet a
    fold by minimising the energy); the answer is checked by integrating the ODE again
    (solve_ivp) and by the conditions, and the 3D model, solving the same problem in
    the plane by its own routes, leads the 2D Newton to the same shape."""
    from pliant.models.dispatch import planar_start
    from pliant.models.elastica2d.reference import equilibrium_error

    problem = pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), hand))
    eq = pl.solve(problem)
    assert equilibrium_error(eq) < 1e-8, name
    assert eq.residual < 1e-9
    assert eq.verdict == "stable"
    np.testing.assert_allclose(eq.position[-1], hand.position, atol=1e-9)
    other = pl.solve(problem, warm_start=planar_start(problem))
    assert equilibrium_error(other) < 1e-8
    s = np.linspace(0.0, problem.part.length, 101)  # (each may have its own samples)
    np.testing.assert_allclose(shape_at(other, s), shape_at(eq, s), atol=1e-7)


def test_a_hairpin_is_reached_from_the_3d_models_planar_answer():
    """The fuzz's problem 1645 (of 3,000, seed 1): a part 0.41 m long clamped along +x
    and its end held 0.39 m behind the clamp pointing on, a hairpin. The 2D routes meet
    folds; the 3D model's planar answer is a start, but its forces are too large for the
    shooting's default intervals: with 16 times the restart nodes the 2D Newton takes
    it. Checked by integrating the ODE again (solve_ivp) and by the conditions."""
    from pliant.core.events import WarmStartLost, has
    from pliant.models.dispatch import planar_start
    from pliant.models.elastica2d.reference import equilibrium_error

    L = 0.41151760493023815
    hand = pl.grip(L, position=(-0.3888529390134358, -0.020049302669242285),
                   angle=-0.013695720083418017, name="hand")
    problem = pl.Problem(pl.Part(L, 0.7377914023913281, mass_per_length=0.020010551440918734),
                         (pl.clamp(0.0), hand), gravity=(0.0, -9.81))
    eq = pl.solve(problem, warm_start=planar_start(problem))
    assert not has(eq.notes, WarmStartLost)
    assert equilibrium_error(eq) < 1e-8
    assert eq.verdict == "stable"
    np.testing.assert_allclose(eq.position[-1], hand.position, atol=1e-9)


@pytest.mark.parametrize("name", ["gravity grip", "two hands, free ends"])
def test_a_hanging_parts_potential_energy_is_converged_on_its_samples(name):
    """The weight's potential, integrated over the answer's 70-odd samples, equals that
    over 4,096 samples to 1e-6 (each interval read as the cubic Hermite of its ends'
    positions and tangents: h^4). The trapezoid alone erred by 6e-4 on the hanging hose,
    so two answers of one equilibrium sampled apart (on other shooting intervals) told
    different energies, and near twins were ranked by that error."""
    from pliant.core.equilibrium import potential_energy

    problem = zoo()[name]
    coarse = solve(problem)
    dense = solve(problem, solver=ShootingSolver(samples=4096))
    assert len(coarse.s) < 100
    assert potential_energy(coarse) == pytest.approx(potential_energy(dense), rel=1e-6)


def test_a_taut_hairpin_is_followed_on_more_intervals_as_its_forces_grow():
    """A part 1 m long clamped along +x and held 0.97 m away, at (0.76, -0.6) m, pointing
    back (angle pi): a taut hairpin, whose internal force reaches some 6,000 EI / L^2.
    Its routes start on one shooting interval; as the force grows, Newton's basin on it
    shrinks like exp(-k L) and the steps used to creep on by thousands (11,458 steps and
    3 s; every route stopped short and the answer came from minimising the energy). A path
    now stops where k times its longest interval passes ``ShootingSolver.node_limit`` and
    follows again on more: the route reaches the hairpin in a few hundred steps, and so
    does a hand carrying it there step by step (warm). Checked by integrating the ODE
    again (solve_ivp) and by the held end."""
    from pliant.core.events import BranchTaken, LowestEquilibrium, has

    def held(x: float, y: float) -> pl.Problem:
        return pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.grip(
            1.0, position=(x, y), angle=math.pi, name="hand")))

    eq = solve(held(0.76, -0.6))
    assert equilibrium_error(eq) < 1e-8
    np.testing.assert_allclose(eq.position[-1], (0.76, -0.6), atol=1e-9)
    assert eq.verdict == "stable"
    assert np.linalg.norm(eq.loads["hand"].force) > 3000.0  # taut: k L above 50
    assert eq.steps < 1000
    assert has(eq.notes, BranchTaken) and not has(eq.notes, LowestEquilibrium)
    carried = list(trace([held(0.5 + 0.26 * t, -0.5 - 0.1 * t)
                          for t in np.linspace(0.0, 1.0, 11)]))
    assert max(equilibrium_error(e) for e in carried) < 1e-8
    assert sum(e.steps for e in carried) < 1000
    assert carried[-1].energy == pytest.approx(eq.energy, rel=1e-9)


CHECKED: list[bool] = []  # each banded solve compared (well conditioned) or not


@settings(max_examples=200, deadline=None)
@given(n=st.integers(1, 60), kl=st.integers(0, 9), ku=st.integers(0, 5),
       seed=st.integers(0, 2**32 - 1), scales=st.booleans())
def test_the_shooting_solve_over_the_band_matches_lapack(n, kl, ku, seed, scales):
    """``kernels.lu_solve`` and ``det_sign`` visit only the band (multiple shooting's
    Jacobian: kl about 8, ku 3): on random banded matrices, rows of sizes 1e-6 to 1e6
    where ``scales``, the solution of LAPACK's dense solve (numpy, of the rows scaled to
    1 as ``lu_solve`` scales them) to its conditioning, and the sign of the
    determinant; a dense matrix is a band as wide as itself."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n)) + 4.0 * np.eye(n)
    A[np.subtract.outer(np.arange(n), np.arange(n)) > kl] = 0.0
    A[np.subtract.outer(np.arange(n), np.arange(n)) < -ku] = 0.0
    if scales:
        A *= 10.0 ** rng.uniform(-6.0, 6.0, n)[:, None]
    b = rng.standard_normal(n)
    x, ok = kernels.lu_solve(A, b)
    rows = np.abs(A).max(axis=1)[:, None]  # LAPACK on the rows scaled as it scales them
    cond = np.linalg.cond(A / rows)
    CHECKED.append(bool(cond < 1e10))
    if cond < 1e10:
        assert kernels.det_sign(A) == np.linalg.slogdet(A)[0]
        assert ok
        exact = np.linalg.solve(A / rows, b / rows[:, 0])
        assert np.abs(x - exact).max() <= 1e-13 * cond * (1.0 + np.abs(exact).max())


def test_the_banded_solves_were_compared_nearly_every_time():
    """The floor of the property above (it runs first: tests keep their file order): a
    test that skipped every ill-conditioned draw would pass on none compared."""
    assert len(CHECKED) >= 50
    assert sum(CHECKED) >= 0.95 * len(CHECKED)


@settings(max_examples=100, deadline=None)
@given(n=st.integers(7, 40), seed=st.integers(0, 2**32 - 1))
def test_the_reused_jacobians_update_keeps_its_band_and_the_secant(n, seed):
    """Broyden's update of a reused Jacobian (Schubert's where it is banded): afterwards
    J step equals the residual's change (the secant condition), and nothing outside the
    band moves, so the next solve stays banded."""
    from pliant.models.elastica2d.kernels import _broyden

    rng = np.random.default_rng(seed)
    below = np.subtract.outer(np.arange(n), np.arange(n))  # i - j
    outside = (below > 3) | (below < -2)
    J = np.where(outside, 0.0, rng.standard_normal((n, n)))
    step, r0, r1 = rng.standard_normal((3, n))
    _broyden(J, step, r1, r0)
    np.testing.assert_allclose(J @ step, r1 - r0, rtol=0.0,
                               atol=1e-12 * (1.0 + np.abs(J).max()))
    assert not J[outside].any()


@settings(max_examples=300, deadline=None)
@given(theta=st.floats(-4.0, 4.0), dth=st.floats(-0.8, 0.8))
def test_turned_angle_matches_the_library_sine_and_cosine(theta, dth):
    """The integrator's stage angle turned by Taylor's series (|dth| <= 0.5, else the
    library) is the cosine and sine of theta + dth to a few units of round-off (against
    the sum formulas with the library's values; a coefficient off by one in its
    denominator errs by 1e-10)."""
    c, s = kernels.turned(math.cos(theta), math.sin(theta), theta, dth)
    exact_c = math.cos(theta) * math.cos(dth) - math.sin(theta) * math.sin(dth)
    exact_s = math.sin(theta) * math.cos(dth) + math.cos(theta) * math.sin(dth)
    assert abs(c - exact_c) <= 2e-15
    assert abs(s - exact_s) <= 2e-15


def test_a_target_behind_the_clamp_is_reached_through_the_energy_minimum():
    """A target the part reaches only by turning back sharply at its clamp (the fuzz's
    2D problem 1577): every continuation route meets a fold or its step budget, and the
    energy's minimum holds internal forces of about 1,900 EI / L^2 that the loads do not
    show; Newton from it, cut into shooting intervals and meshed for its own wavenumber,
    converges. Checked by integrating the ODE again (solve_ivp) and against the discrete
    minimum's energy (48 elements: within 5 %)."""
    part = pl.Part(length=0.5647438357719201, bending_stiffness=0.044800894166508405,
                   rest_curvature=((0.06908137507346428, 0.692752063347229),
                                   (0.18263280779622046, -2.512908740416341)))
    problem = pl.Problem(part, (pl.clamp(0.0), pl.grip(
        part.length, position=(-0.37995196908847134, -0.3696498541478592),
        angle=2.693306808302032, name="hand")))
    eq = solve(problem)
    assert equilibrium_error(eq) <= 1e-8
    assert eq.stable
    np.testing.assert_allclose(eq.position[-1], (-0.37995196908847134, -0.3696498541478592),
                               atol=1e-9)
    lowest = minimum.minima(problem)[0]
    scale = part.bending_stiffness / part.length
    assert eq.energy == pytest.approx(lowest.energy * scale, rel=0.05)


def test_a_follower_load_every_route_misses_is_reached_from_its_dead_twin():
    """Issue 54: a clamp with a grip mid-span and a follower force and couple at the
    tip: every route stopped at 0.09 of the way ("no equilibrium") where an independent
    multiple shooting found one. Its dead twin (the same force fixed in direction) is
    solved, then followed as the force turns with the part; said. Checked by
    integrating the ODE again (solve_ivp, the follower turned to the tangent) and by
    the conditions: the grip's position held, the tip's force the follower's
    (ft, fn) turned to the tip's angle."""
    from pliant.models.elastica2d.reference import equilibrium_error

    C = pl.Condition
    ft, fn = 0.2247, -0.1464
    problem = pl.Problem(pl.Part(4.566, 0.3833, mass_per_length=0.2445), (
        C(s=0.0, name="clamp", position=(3.927, -2.585), angle=2.782),
        C(s=1.23, name="grip", position=(3.322, -2.914)),
        C(s=4.566, name="tip", force=(ft, fn), follower=True, moment=-0.05541)))
    eq = pl.solve(problem)
    assert any("dead" in n and "followers" in n for n in eq.notes)
    assert equilibrium_error(eq) < 1e-8
    k = int(np.argmin(np.abs(eq.s - 1.23)))
    np.testing.assert_allclose(eq.position[k], (3.322, -2.914), atol=1e-9)
    theta = eq.angle[-1]
    turned = (ft * math.cos(theta) - fn * math.sin(theta),
              ft * math.sin(theta) + fn * math.cos(theta))
    np.testing.assert_allclose(eq.loads["tip"].force, turned, atol=1e-9)


def test_a_follower_whose_dead_path_folds_is_reached_by_turning_the_dead_twin():
    """Issue 54: where the path from the dead twin to the follower meets a fold (a
    heavy tip follower, |f| L^2 / EI = 11), the twin is solved again with the force
    turned to where the last dead answer has the tip, until the follower can be followed
    from it. Checked by solve_ivp and the conditions, as above."""
    from pliant.models.elastica2d.reference import equilibrium_error

    C = pl.Condition
    L, EI, q = 0.686803596502608, 0.97144144829119, 0.024471416058477663
    ft, fn = 19.627425342811488, -12.41227778563599
    problem = pl.Problem(pl.Part(L, EI, mass_per_length=q), (
        C(s=0.0, name="clamp", position=(1.7899017415660783, 2.1861985868754843),
          angle=2.5647390341973306),
        C(s=0.07232533356302435, name="grip",
          position=(1.7330661751501215, 2.1946087874811218)),
        C(s=L, name="tip", force=(ft, fn), follower=True, moment=-0.10684243061081573)),
        gravity=(0.0, -9.81))
    eq = pl.solve(problem)
    assert equilibrium_error(eq) < 1e-8
    theta = eq.angle[-1]
    np.testing.assert_allclose(eq.loads["tip"].force, (
        ft * math.cos(theta) - fn * math.sin(theta),
        ft * math.sin(theta) + fn * math.cos(theta)), atol=1e-9)
