"""Stability verdicts: the 2D second variation against Euler's columns (closed forms, and
its convergence order), and the neutral verdict of a free family in 3D."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.models.elastica2d import equilibria
from pliant.models.elastica2d import stability as planar

from .helpers import shape_at


def column(P: float, end: str) -> pl.Problem:
    """A straight column (L = 1 m, EI = 1 N m^2) pushed along its axis by P at s = L."""
    part = pl.Part(1.0, 1.0)
    if end == "free":  # clamped-free: lambda = L (EI (pi / 2L)^2 - P)
        conditions = (pl.clamp(0.0), pl.push(1.0, (-P, 0.0)))
    elif end == "clamped":  # clamped-clamped, sliding along x: EI (2 pi / L)^2
        conditions = (pl.clamp(0.0), pl.Condition(s=1.0, name="end", position=(None, 0.0),
                                                  force=(-P, None), angle=0.0))
    else:  # pinned-pinned, sliding along x: EI (pi / L)^2
        conditions = (pl.pin(0.0), pl.Condition(s=1.0, name="end", position=(None, 0.0),
                                                force=(-P, None)))
    return pl.Problem(part, conditions)


@pytest.mark.parametrize(("end", "k"), [("free", math.pi / 2), ("clamped", 2 * math.pi),
                                        ("pinned", math.pi)])
def test_euler_columns_lose_stability_at_their_critical_loads(end, k):
    # Followed from below the critical load, the part stays on the straight branch
    # (a cold solve past it would give the stable buckled shape instead).
    eq = None
    for fraction in (0.5, 1.2):
        P = fraction * k * k
        eq = pl.solve(column(P, end), warm_start=eq)
        assert abs(eq.position[:, 1]).max() < 1e-12  # the straight branch
        stable, eigen = eq.stability
        assert eigen == pytest.approx(k * k - P, rel=2e-4, abs=2e-4 * k * k)
        assert stable is (fraction < 1.0)
        assert eq.verdict == ("stable" if fraction < 1.0 else "unstable")


def test_the_planar_eigenvalue_converges_at_second_order(monkeypatch):
    eq = pl.solve(column(10.0, "clamped"))
    exact = (2 * math.pi) ** 2 - 10.0
    errors = []
    for elements in (30, 60, 120):
        monkeypatch.setattr(planar, "ELEMENTS", elements)
        errors.append(abs(planar.smallest_eigenvalue(eq) - exact))
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.1)


def test_follower_loads_leave_the_planar_verdict_undecided():
    eq = pl.solve(pl.Problem(pl.Part(1.0, 1.0),
                             (pl.clamp(0.0), pl.push(1.0, (0.0, 2.0), follower=True))))
    assert eq.stability == (None, None) and eq.verdict == "undecided"
    assert eq.to_dict()["stability"] == "undecided"


def test_a_round_clamped_strip_is_neutral_about_its_chord_and_an_oval_one_stable():
    """Ends clamped along their chord: an isotropic rod's buckled arch turns about the
    chord at no cost (its frames counter-twist uniformly), so the verdict is neutral, not
    unstable; a section stiffer about one axis picks its plane (stable)."""
    ends = (pl.clamp(0.0, (0.0, 0.0, 0.0)), pl.clamp(1.0, (0.8, 0.0, 0.0), name="end"))
    from pliant.models.rod3d.results import describe_mode

    round_ = pl.solve(pl.Problem(pl.Part(1.0, 1.0), ends))
    assert round_.verdict == "neutral" and round_.stable is True
    assert describe_mode(round_) == "a turn of the whole part about the line through its held ends"
    oval = pl.solve(pl.Problem(pl.Part(1.0, 1.0, bending_stiffness_2=1.5), ends))
    assert oval.verdict == "stable" and oval.stability[1] > 1.0
    assert describe_mode(oval) == "a change of shape"


def test_a_singular_start_returns_the_lower_of_the_two_bow_sides():
    """Tip held at (0.333, -0.002) m at -1.106 rad: the side the target moves to leads to
    a stable equilibrium of 45.14 J, the other side to a stable one of 20.86 J. The answer
    is the lower; both are checked by an independent shooting (solve_ivp and fsolve from
    the answer's own clamp reaction, and from its mirror for the other side)."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import fsolve

    X, Y, A = 0.333, -0.002, -1.106
    eq = pl.solve(pl.Problem(pl.Part(1.0, 1.0),
                             (pl.clamp(0.0), pl.grip(1.0, (X, Y), angle=A, name="hand"))))
    note = next(n for n in eq.notes if "singular start" in n)

    def shoot(u):
        nx, ny, m0 = u  # the internal force (constant: no weight) and the clamp's moment

        def rhs(_s, z):
            return [math.cos(z[2]), math.sin(z[2]), z[3],
                    -(math.cos(z[2]) * ny - math.sin(z[2]) * nx), 0.5 * z[3] ** 2]

        end = solve_ivp(rhs, (0.0, 1.0), [0.0, 0.0, 0.0, m0, 0.0], rtol=1e-10,
                        atol=1e-12).y[:, -1]
        return [end[0] - X, end[1] - Y, end[2] - A], end[4]

    clamp = eq.loads["clamp"]
    answer = [-clamp.force[0], -clamp.force[1], -clamp.moment]  # n(0) = -reaction
    u = fsolve(lambda v: shoot(v)[0], answer, xtol=1e-12)
    assert np.allclose(u, answer, rtol=1e-6, atol=1e-6)
    assert shoot(u)[1] == pytest.approx(eq.energy, rel=1e-7)
    other = fsolve(lambda v: shoot(v)[0], [-75.0, -13.6, -13.8], xtol=1e-12)
    residual, other_energy = shoot(other)
    assert max(map(abs, residual)) < 1e-9
    assert eq.energy < 0.5 * other_energy
    assert f"{other_energy:.6g} J and is stable" in note
    assert eq.verdict == "stable"


def test_equilibria_lists_what_the_routes_reach_the_answer_first(capsys):
    from pliant.cli.app import all_equilibria
    from pliant.core.equilibrium import potential_energy

    problem = pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0),
                                             pl.grip(1.0, (0.333, -0.002), angle=-1.106,
                                                     name="hand")))
    found = equilibria(problem)
    answer = pl.solve(problem)
    assert len(found) >= 2
    assert np.abs(found[0].position[-1] - answer.position[-1]).max() < 1e-8
    assert found[0].energy == pytest.approx(answer.energy, rel=1e-9)
    energies = [potential_energy(e) for e in found if e.verdict != "unstable"]
    assert energies == sorted(energies)
    for eq in found:  # each a distinct equilibrium of the problem
        assert eq.residual < 1e-9
        assert np.abs(eq.position[-1] - (0.333, -0.002)).max() < 1e-8
    # at common arc lengths: two routes may answer on different shooting intervals, whose
    # samples lie apart (one equilibrium found twice is still one)
    s = np.linspace(0.0, 1.0, 41)
    shapes = [shape_at(e, s) for e in found]
    assert all(np.abs(a - b).max() > 1e-3 for i, a in enumerate(shapes) for b in shapes[:i])
    from pliant.core.events import ReachedBy  # how each was reached, as a typed record

    routes = {"straight", "two stage", "swing", "loads first", "energy minimum"}
    assert all(isinstance(e.events[0], ReachedBy) and e.events[0].route in routes
               for e in found)
    all_equilibria(problem, as_json=Path("-"))  # standard output
    import json

    listed = json.loads(capsys.readouterr().out)["equilibria"]
    assert [e["stability"] for e in listed][:2] == ["stable", "stable"]
    assert listed[0]["potential_energy"] == pytest.approx(answer.energy, rel=1e-9)


@pytest.mark.parametrize("hand, angle, mirror", [
    ((0.7, 0.4), 0.0, "turned"),  # the paper's case 3: ends held parallel, offset
    ((1.1, 0.9), 0.4, "turned"),  # the same, not along x
    ((0.8, 0.0), 0.0, "reflected"),  # a clamped strut: ends held along the chord
    ((0.5, 0.3), None, "reflected"),  # a pinned strut
])
def test_a_problem_that_is_its_own_mirror_image_lists_both_mirror_twins(hand, angle,
                                                                       mirror):
    """A problem that maps onto itself, turned half round about its chord's midpoint and
    read from the other end (theta(s) -> theta(L - s)) or reflected in its chord, has its
    equilibria in mirror pairs, one bowed to each side, of one energy: the route takes
    the other side's as this one's mirror image, converged, instead of a path of its own.
    Checked: each of the pair is an equilibrium by re-integration with solve_ivp, each
    the other's mirror image at 41 arc lengths, of one energy, both stable."""
    from pliant.core.equilibrium import bow_side, potential_energy
    from pliant.models.elastica2d.reference import equilibrium_error

    length = 1.5 if hand[0] > 1.0 else 1.0
    far = pl.pin(length, hand, name="hand") if angle is None else pl.grip(
        length, hand, angle=angle, name="hand")
    start = pl.pin(0.0) if angle is None else pl.clamp(0.0, angle=angle)
    problem = pl.Problem(pl.Part(length, 2.0), (start, far))
    found = equilibria(problem)
    answer = pl.solve(problem)
    assert "mirror twin" in answer.notes[0]
    pair = [e for e in found if abs(potential_energy(e) - potential_energy(answer))
            <= 1e-9 * potential_energy(answer)]
    assert len(pair) == 2 and {bow_side(e) for e in pair} == {"left", "right"}
    s = np.linspace(0.0, length, 41)
    a, b = (shape_at(e, s) for e in pair)
    chord = np.asarray(hand) / math.hypot(*hand)
    if mirror == "turned":  # r_b(s) = 2 c - r_a(L - s), c the chord's midpoint
        expected = np.asarray(hand) - a[::-1]
    else:  # r_b = 2 (r_a . u) u - r_a
        expected = 2.0 * (a @ chord)[:, None] * chord - a
    assert np.abs(b - expected).max() < 1e-8 * length
    for eq in pair:
        assert equilibrium_error(eq) < 1e-8
        assert eq.verdict == "stable"


def test_both_bow_sides_reaching_one_equilibrium_are_not_called_twins():
    """Held to wind a whole turn (the hand's angle the clamp's plus 2 pi), the part makes
    a loop, and the paths bowed to either side reach the same one: one equilibrium, said
    so, not a mirror pair (a mirror would reverse the turn: no mirror image of this
    problem is itself)."""
    from pliant.core.events import BranchTaken

    problem = pl.Problem(pl.Part(1.5, 2.0), (pl.clamp(0.0, angle=0.4), pl.grip(
        1.5, (1.1, 0.9), angle=0.4 + 2.0 * math.pi, name="hand")))
    answer = pl.solve(problem)
    taken = next(n for n in answer.notes if isinstance(n, BranchTaken))
    assert not taken.twin and "reached the same equilibrium" in taken
    assert answer.angle[-1] - answer.angle[0] == pytest.approx(2.0 * math.pi, abs=1e-9)
    assert len(equilibria(problem)) == 1



def test_one_equilibrium_reached_on_two_meshes_is_listed_once():
    """A part that turns 22 rad a length, reached by the route and again from the
    energy's minimum on other shooting intervals: read between one's samples at the
    other's (cubic Hermite, error h^4 k^3 / 384), the two missed each other by 2e-6 L,
    past the 1e-6 L that two answers of one equilibrium keep, and the answer was listed
    among the others found, with its own energy. The comparison now allows the reading's
    error, and no more: the other bow side's equilibrium, 0.2 L away, is still listed."""
    from pliant.core.equilibrium import potential_energy
    from pliant.core.events import OthersFound

    length = 1.0065514916069802
    problem = pl.Problem(pl.Part(length, 4.827332863489238, mass_per_length=0.49),
                         (pl.clamp(0.0, angle=-2.8776247977850966),
                          pl.grip(length, (0.7750919795880583, 0.27958225764938327),
                                  angle=0.2639678558046965, name="hand")))
    answer = pl.solve(problem)
    assert not any(isinstance(n, OthersFound) for n in answer.notes)
    found = equilibria(problem)
    s = np.linspace(0.0, length, 41)
    shapes = [shape_at(e, s) for e in found]
    assert len(found) == 2
    assert np.abs(shapes[0] - shapes[1]).max() > 0.1 * length
    assert potential_energy(found[0]) == pytest.approx(potential_energy(answer), rel=1e-9)
    assert np.abs(shapes[0] - shape_at(answer, s)).max() < 1e-6 * length
    assert [e.verdict for e in found] == ["stable", "unstable"]


def test_the_sparse_eigensolvers_agree_with_the_dense_one(monkeypatch):
    """The planar verdict's smallest eigenvalue by the Sturm count (an inextensible
    part: bisection, then Rayleigh quotient iteration proved by counts) and by
    shift-invert Lanczos on the sparse bordered system (milliseconds) against the dense
    null space and eigensolver, on a held tip (case 3's target), a heavy pinned part and
    a stretching cable (the Lanczos only): to 1e-9."""
    part = pl.Part(1.0, 1.0)
    heavy = pl.Part(1.2, 0.5, mass_per_length=0.3, rest_curvature=0.8)
    cable = pl.Part(1.0, 1.0, axial_stiffness=2e4)
    problems = [
        pl.Problem(part, (pl.clamp(0.0), pl.grip(1.0, position=(0.7, 0.4), angle=0.0,
                                                 name="hand"))),
        pl.Problem(heavy, (pl.pin(0.0), pl.grip(1.2, position=(0.8, -0.3), angle=-1.0,
                                                name="hand")), gravity=(0.0, -9.81)),
        pl.Problem(cable, (pl.clamp(0.0), pl.push(1.0, force=(30.0, -5.0), name="tip"))),
    ]
    for problem in problems:
        eq = pl.solve(problem)
        default = planar.smallest_eigenvalue(eq, 120)
        monkeypatch.setattr(planar, "_smallest_sturm", lambda *args: None)
        lanczos = planar.smallest_eigenvalue(eq, 120)
        monkeypatch.setattr(planar, "_smallest_sparse", lambda *args: None)
        dense = planar.smallest_eigenvalue(eq, 120)
        monkeypatch.undo()
        assert default == pytest.approx(dense, rel=1e-9, abs=1e-9)
        assert lanczos == pytest.approx(dense, rel=1e-9, abs=1e-9)
        # At 60 elements an inextensible part takes the Sturm count too, and the others
        # the dense path; forced through the dense one, the same eigenvalue.
        quick = planar.smallest_eigenvalue(eq, 60)
        monkeypatch.setattr(planar, "_smallest_sturm", lambda *args: None)
        monkeypatch.setattr(planar, "_smallest_sparse", lambda *args: None)
        assert planar.smallest_eigenvalue(eq, 60) == pytest.approx(quick, rel=1e-9, abs=1e-9)
        monkeypatch.undo()


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(0, 2**31), st.integers(6, 80), st.integers(2, 5))
def test_the_sturm_count_finds_the_constrained_pencils_smallest_eigenvalue(seed, n, m):
    """``bordered.smallest_constrained`` against scipy's dense generalised eigensolver on
    the constraints' null space, for random second variations of the verdict's shape
    (zero on two translations; on n element angles of random lengths h, bending EI / h
    between neighbours, clamped ends or not, and a random axial force's h N on the
    diagonal, tension or compression up to 50 EI / L^2; the weight h) under m random
    constraints whose first two hold the translations; and ``kkt_negatives`` against
    numpy's count of the whole KKT matrix's negative eigenvalues."""
    from scipy.linalg import eigh, null_space

    from pliant.models.elastica2d import bordered

    rng = np.random.default_rng(seed)
    h = rng.uniform(0.5, 1.5, size=n)
    h /= h.sum()
    k = 1.0 / (0.5 * (h[:-1] + h[1:]))
    diag = h * rng.uniform(-50.0, 50.0, size=n)
    diag[:-1] += k
    diag[1:] += k
    diag[[0, -1]] += rng.choice([0.0, 1.0], size=2) * 2.0 / h[[0, -1]]
    off, weight = -k, h
    jac = rng.normal(size=(m, n + 2))
    jac[:, :2] = 0.0
    jac[0, 0] = jac[1, 1] = 1.0
    H = np.zeros((n + 2, n + 2))
    H[2:, 2:] = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
    W = np.zeros((n + 2, n + 2))
    W[2:, 2:] = np.diag(weight)
    kkt = np.block([[H, jac.T], [jac, np.zeros((m, m))]])
    assert bordered.kkt_negatives(diag, off, jac, 0.0) == np.sum(np.linalg.eigvalsh(kkt) < 0)
    Z = null_space(jac)
    exact = eigh(Z.T @ H @ Z, Z.T @ W @ Z, eigvals_only=True)[0]
    bound = 1.0 + 50.0  # EI / L plus L |N|, below every eigenvalue (as the verdict's)
    value = bordered.smallest_constrained(diag, off, jac, weight, -2.0 * bound, bound)
    assert value == pytest.approx(exact, abs=1e-9 * bound)


def test_the_sturm_count_proves_its_rayleigh_value_or_bisects_a_double_one():
    """The count's answer comes from Rayleigh quotient iteration once the bracket holds
    the smallest eigenvalue alone, proved by two counts 1e-12 of the scale either side;
    a double eigenvalue (two identical halves, uncoupled) never stands alone, and the
    bisection answers. Both against numpy's eigenvalues of the angles' block (the
    constraints hold the translations only)."""
    from pliant.models.elastica2d import bordered

    rng = np.random.default_rng(4)
    half = 12
    h = np.full(2 * half, 1.0 / (2 * half))
    k = 1.0 / h[:-1]
    axial = rng.uniform(-30.0, 30.0, size=half)
    for double in (False, True):
        diag = h * np.concatenate([axial, axial if double else axial[::-1] + 1.0])
        diag[:-1] += k
        diag[1:] += k
        off = -k.copy()
        if double:  # two identical halves, uncoupled: every eigenvalue twice
            diag[half - 1] -= k[half - 1]
            diag[half] -= k[half - 1]
            off[half - 1] = 0.0
        jac = np.zeros((2, 2 * half + 2))
        jac[0, 0] = jac[1, 1] = 1.0
        T = np.diag(diag) + np.diag(off, 1) + np.diag(off, -1)
        exact = np.linalg.eigvalsh(T / np.sqrt(np.outer(h, h)))
        assert bool(abs(exact[1] - exact[0]) < 1e-9) == double
        value = bordered.smallest_constrained(diag, off, jac, h, -100.0, 40.0)
        assert value == pytest.approx(exact[0], abs=1e-10 * 40.0)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.integers(0, 2**31), st.integers(1, 9), st.integers(0, 9))
def test_the_inertia_of_a_small_symmetric_matrix_is_its_eigenvalues_signs(seed, n, zeros):
    """``bordered.negatives`` (Bunch-Kaufman) against numpy's eigenvalues: random
    symmetric matrices, some with a zero diagonal block as a KKT matrix's multipliers
    have (its 2x2 pivots), some rank-deficient (a column combined from the others: then
    -1, singular, or a count that takes the round-off eigenvalue either way), and each
    also with its rows and columns scaled by 1e-3 to 1e3 (D A D: the same inertia by
    Sylvester's law, as the Schur complements' rows of very different sizes)."""
    from pliant.models.elastica2d import bordered

    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, n))
    a = a + a.T
    a[n - min(zeros, n):, n - min(zeros, n):] = 0.0
    if seed % 4 == 0 and n > 1:  # rank n - 1
        mix = rng.normal(size=n - 1)
        a[:, -1] = a[:, :-1] @ mix
        a[-1, :] = a[:, -1]
        a[-1, -1] = mix @ a[:-1, :-1] @ mix
    values = np.linalg.eigvalsh(a)
    tiny = 1e-9 * np.abs(values).max(initial=0.0)
    clear, near = np.sum(values < -tiny), np.sum(np.abs(values) <= tiny)
    scale = 10.0 ** rng.uniform(-3.0, 3.0, size=n)
    for matrix in (a, scale[:, None] * a * scale[None, :]):
        count = bordered.negatives(matrix)
        if near:
            assert count == -1 or clear <= count <= clear + near
        else:
            assert count == clear


@pytest.mark.parametrize(("end", "k"), [("free", math.pi / 2), ("pinned", math.pi)])
def test_the_sign_by_one_sturm_count_is_the_eigenvalues(end, k):
    """``stable_sign`` (one count of the eigenvalues below the neutral band, what the
    solver's choice among equilibria asks) against ``stability`` (the eigenvalue itself):
    Euler's columns followed on their straight branch to either side of the critical
    load."""
    eq = None
    for fraction in (0.5, 0.99, 1.01, 1.5):
        eq = pl.solve(column(fraction * k * k, end), warm_start=eq)
        assert planar.stable_sign(eq, 60) is (fraction < 1.0)
        assert planar.stable_sign(eq, 60) is planar.stability(eq, 60)[0]


def test_the_sign_by_one_sturm_count_is_the_eigenvalues_at_random_targets():
    """The same, on every equilibrium found for a hand at random targets (a part under
    its weight, clamped, its end held by position and angle)."""
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(12):
        r = math.sqrt(rng.uniform(0.05, 0.9))
        a, angle = rng.uniform(-math.pi, math.pi, 2)
        problem = pl.Problem(pl.Part(1.0, 1.0, mass_per_length=float(rng.uniform(0, 1))),
                             (pl.clamp(0.0), pl.grip(1.0, (r * math.cos(a), r * math.sin(a)),
                                                     angle=float(angle), name="hand")),
                             gravity=(0.0, -9.81))
        for eq in equilibria(problem, budget=2.0):
            assert planar.stable_sign(eq, 60) is planar.stability(eq, 60)[0]
            checked += 1
    assert checked >= 12

