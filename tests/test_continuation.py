"""The shared continuation driver (``pliant.models.continuation``): its stepping on a
model with a closed-form path and fold, its budgets and stalls, the branch ranking, and
the 2D model driven by it against its compiled twin."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pytest

import pliant as pl
from pliant.core.events import Status
from pliant.models import clock, continuation, elastica2d
from pliant.models.continuation import Candidate, Stalled, Stepping, ranked

from .helpers import shape_at, zoo
from .test_elastica2d_closed_form import cantilever_tip


@dataclass
class Cubic:
    """x^3 - 3 x = lam, lam from ``start`` to ``end``: the middle branch (|x| < 1) runs
    from x = 0 at lam = 0 down to its fold at x = -1, lam = 2 (dlam/dx = 3 x^2 - 3)."""

    steps: int = 0
    iterations: int = 0
    force: float = 0.0  # the load size F that the wavenumber rule caps

    def correct(self, predictor, loads, *, strict, tol):
        x, lam = float(predictor), float(loads)
        r0 = abs(x**3 - 3 * x - lam)
        tol = 1e-12 if tol is None else tol
        for _ in range(30):
            r = x**3 - 3 * x - lam
            if abs(r) <= tol:
                return np.float64(x), abs(r), Status.CONVERGED
            slope = 3 * x * x - 3
            if abs(slope) < 1e-14:
                return np.float64(x), abs(r), Status.SINGULAR
            new = x - r / slope
            self.iterations += 1
            if strict and abs(new**3 - 3 * new - lam) > 0.5 * max(abs(r), 1e-300) \
                    and abs(new**3 - 3 * new - lam) > tol:
                return np.float64(x), r0, Status.FOLD
            x = new
        return np.float64(x), abs(x**3 - 3 * x - lam), Status.FOLD

    def tangent(self, state, path):
        slope = 3 * float(state) ** 2 - 3
        return None if abs(slope) < 1e-14 else np.float64((path.end - path.start) / slope)

    def step(self, state, du, scale):
        return state + scale * du

    def difference(self, a, b):
        return b - a

    def miss(self, predicted, corrected):
        return abs(float(corrected) - float(predicted)) / max(1.0, abs(float(corrected)))

    def load_size(self, path):
        return self.force, 0.0

    def begin_step(self, state):
        return state

    def memo(self):
        return "memo"


@dataclass(frozen=True)
class Lam:
    start: float
    end: float

    def at(self, t: float) -> float:
        return self.start + t * (self.end - self.start)


STEPPING = Stepping(tolerance=1e-12, loose=1e-9, min_step=1e-7, max_steps=500, grow=0.1)


def middle_root(lam: float) -> float:
    roots = np.roots([1.0, 0.0, -3.0, -lam])
    return float(next(r.real for r in roots if abs(r.imag) < 1e-9 and abs(r.real) < 1.0))


def test_the_driver_follows_a_branch_to_its_end():
    model = Cubic()
    x = continuation.follow(model, Lam(0.0, 1.5), np.float64(0.0), STEPPING,
                            clock.now() + 10.0)
    assert float(x) == pytest.approx(middle_root(1.5), abs=1e-11)
    assert 1 <= model.steps < 50


@dataclass
class Pitchfork(Cubic):
    """x^3 - lam x = 0 on its trivial branch x = 0, lam from -1 to 1.1: its Jacobian
    3 x^2 - lam changes sign at lam = 0, the bifurcation. The model offers the sign of
    its determinant (``det_sign``) and is told of crossings (``crossed``) and of each
    step taken (``stepped``)."""

    crossings: int = 0
    taken: list = None  # type: ignore[assignment]

    def correct(self, predictor, loads, *, strict, tol):
        x, lam = float(predictor), float(loads)
        for _ in range(30):
            r = x**3 - lam * x
            if abs(r) <= (1e-12 if tol is None else tol):
                return np.float64(x), abs(r), Status.CONVERGED
            x -= r / (3 * x * x - lam)
            self.iterations += 1
        return np.float64(x), abs(x**3 - lam * x), Status.FOLD

    def tangent(self, state, path):
        return np.float64(0.0)  # d x / d lam = x / (3 x^2 - lam) = 0 on the branch

    def det_sign(self, point, loads, fresh):
        return float(np.sign(3 * float(point) ** 2 - float(loads)))

    def crossed(self):
        self.crossings += 1

    def stepped(self, dt):
        self.taken = (self.taken or []) + [dt]


def test_the_driver_refuses_a_step_that_flips_det_j_until_the_crossing_is_genuine():
    """On the pitchfork's trivial branch the driver does not step over lam = 0 in one
    long step: the steps that flip the sign are refused and shortened until 1e3
    ``min_step`` short, the crossing then counted once; every step taken but the last is
    reported, the last ending at lam = 1.1."""
    model = Pitchfork()
    x = continuation.follow(model, Lam(-1.0, 1.1), np.float64(0.0), STEPPING,
                            clock.now() + 10.0)
    assert float(x) == 0.0
    assert model.crossings == 1
    steps = model.taken
    assert len(steps) == model.steps - 1 and min(steps) > 0.0
    assert min(steps) <= 1e3 * STEPPING.min_step  # the crossing step, cut short
    assert sum(steps) > 1.0 / 2.1  # past lam = 0 before the last step
    plain = Cubic()  # no det_sign: the driver follows as before
    continuation.follow(plain, Lam(0.0, 1.5), np.float64(0.0), STEPPING, clock.now() + 10.0)
    assert plain.steps >= 1


def test_no_step_raises_the_loads_wavenumber_by_more_than_one():
    """With F = 100 the wavenumber sqrt(t F) reaches 10 at t = 1: steps of one in it end
    at t = (n / 10)^2, ten steps, where the corrector alone would take one."""
    model = Cubic(force=100.0)
    x = continuation.follow(model, Lam(0.0, 1.5), np.float64(0.0), STEPPING,
                            clock.now() + 10.0)
    assert float(x) == pytest.approx(middle_root(1.5), abs=1e-11)
    assert model.steps in (10, 11)  # (11 where round-off leaves t a hair below 1)
    free = Cubic()
    continuation.follow(free, Lam(0.0, 1.5), np.float64(0.0), STEPPING, clock.now() + 10.0)
    assert free.steps < model.steps


def test_a_step_that_would_leave_a_sliver_takes_the_rest_at_once():
    """With F = 10.1^2 the wavenumber caps end steps at t = (n / 10.1)^2: the tenth at
    t = 0.980 leaves a sliver of 0.02 that costs an eleventh corrector. With
    last_stretch = 1.25 the tenth step (0.19 long, the sliver under a quarter of it)
    takes the rest at once, raising the wavenumber by 1.1, within 1.25 of the cap."""
    capped = Cubic(force=10.1**2)
    x = continuation.follow(capped, Lam(0.0, 1.5), np.float64(0.0), STEPPING,
                            clock.now() + 10.0)
    stretched = Cubic(force=10.1**2)
    y = continuation.follow(stretched, Lam(0.0, 1.5), np.float64(0.0),
                            replace(STEPPING, last_stretch=1.25), clock.now() + 10.0)
    assert float(x) == pytest.approx(middle_root(1.5), abs=1e-11)
    assert float(y) == pytest.approx(middle_root(1.5), abs=1e-11)
    assert (capped.steps, stretched.steps) == (11, 10)


@dataclass
class NarrowBasin(Cubic):
    """The cubic, with Newton's basin a load step of 0.01 wide (a creeping path's: its
    intervals' sensitivities narrow it): a longer step's corrector fails."""

    tries: int = 0
    last: float = 0.0

    def correct(self, predictor, loads, *, strict, tol):
        self.tries += 1
        if strict and abs(float(loads) - self.last) > 0.01:
            return predictor, 1.0, Status.FOLD
        out = super().correct(predictor, loads, strict=strict, tol=tol)
        if out[2] == Status.CONVERGED:
            self.last = float(loads)
        return out


def test_a_refused_steps_memory_spares_correctors_where_the_basin_is_narrow():
    """Without it the steps alternate where Newton's basin is narrower than the step
    control's aim: taken, grown fourfold and refused, taken again (half the correctors
    refused). With ``refused_fade`` (the 2D model's) the next steps grow to half the one
    refused at most, the memory fading by 1.5 a step: a third fewer refused, fewer
    correctors in all, the same root."""
    plain, fading = NarrowBasin(), NarrowBasin()
    x = continuation.follow(plain, Lam(0.0, 1.5), np.float64(0.0), STEPPING,
                            clock.now() + 10.0)
    y = continuation.follow(fading, Lam(0.0, 1.5), np.float64(0.0),
                            replace(STEPPING, refused_fade=1.5), clock.now() + 10.0)
    assert float(x) == pytest.approx(middle_root(1.5), abs=1e-11)
    assert float(y) == pytest.approx(middle_root(1.5), abs=1e-11)
    refused = [m.tries - m.steps for m in (plain, fading)]
    assert refused[0] >= 0.45 * plain.tries  # alternating
    assert refused[1] < 0.7 * refused[0] and fading.tries < 0.9 * plain.tries


def test_the_driver_stops_at_a_fold_and_keeps_the_last_good_point():
    """Past lam = 2 the middle branch has no point: the stall is at t = 2/3 of the way
    0 -> 3, a fold, with the last good point on the branch next to x = -1."""
    with pytest.raises(Stalled) as err:
        continuation.follow(Cubic(), Lam(0.0, 3.0), np.float64(0.0), STEPPING,
                            clock.now() + 10.0)
    stall = err.value
    assert stall.status in (Status.FOLD, Status.SINGULAR) and not stall.budget
    assert stall.t == pytest.approx(2.0 / 3.0, abs=1e-3)
    lam = 3.0 * stall.t
    x = float(stall.state)  # on the middle branch, to the path's loose tolerance
    assert -1.0 < x < -0.99 and abs(x**3 - 3 * x - lam) <= STEPPING.loose
    assert x == pytest.approx(middle_root(lam), abs=STEPPING.loose / abs(3 * x * x - 3))
    assert stall.memo == "memo" and stall.ahead == (3.0,) and stall.loads == lam


def test_a_singular_start_and_the_budgets_are_typed_stalls():
    with pytest.raises(Stalled) as err:  # x = 1 is the other fold: singular at the start
        continuation.follow(Cubic(), Lam(-2.0, -1.0), np.float64(1.0), STEPPING,
                            clock.now() + 10.0)
    assert err.value.singular_start and err.value.status == Status.SINGULAR
    tight = Stepping(tolerance=1e-12, loose=1e-9, min_step=1e-7, max_steps=2, grow=0.1)
    with pytest.raises(Stalled) as err:
        continuation.follow(Cubic(force=100.0), Lam(0.0, 1.5), np.float64(0.0), tight,
                            clock.now() + 10.0)
    assert err.value.budget and err.value.status == Status.STEP_BUDGET
    assert 0.0 < err.value.t < 1.0
    with pytest.raises(Stalled) as err:
        continuation.follow(Cubic(), Lam(0.0, 1.5), np.float64(0.0), STEPPING,
                            clock.now() - 1.0)
    assert err.value.budget and err.value.status == Status.TIME_BUDGET


def test_the_route_ladder_takes_the_first_that_arrives_and_drops_what_failed_said():
    notes: list[str] = []

    def fails(t: float):
        def route():
            notes.append(f"said by a route that stalls at {t}")
            raise Stalled(t, 1.0, "a fold")
        return route

    assert continuation.first_route([fails(0.2), lambda: "arrived"], notes,
                                    clock.now() + 1.0) == "arrived"
    assert notes == []
    with pytest.raises(Stalled) as err:
        continuation.first_route([fails(0.2), fails(0.7), fails(0.4)], notes,
                                 clock.now() + 1.0)
    assert err.value.t == 0.7 and notes == []


def test_ranked_puts_stable_first_then_the_lower_energy_and_keeps_ties_in_order():
    a = Candidate(True, 5.0, "a")
    b = Candidate(False, 1.0, "b")  # lower but unstable
    c = Candidate(None, 4.0, "c")  # neutral: not unstable
    d = Candidate(True, 4.0 + 1e-12, "d")  # c's mirror twin
    assert [x.item for x in ranked([a, b, c, d])] == ["c", "d", "a", "b"]
    assert [x.item for x in ranked([d, c])] == ["d", "c"]
    # Energies far apart in size still order by value (not by their relative size).
    assert [x.item for x in ranked([Candidate(True, 45.1, 1), Candidate(True, 20.9, 2)])] \
        == [2, 1]


@pytest.mark.parametrize("name", ["case1", "case2", "case3", "gravity grip",
                                  "pre-curved pin", "compressed cantilever",
                                  "follower and moment"])
def test_the_2d_model_driven_by_the_shared_driver_matches_its_compiled_twin(name):
    """The 2D model implements the driver's protocol: solved through it (in Python) and
    through the compiled ``kernels.follow``, the same equilibrium to 1e-9 L and its
    reactions to 1e-7 of their size. (Where the routes differ, the answers may lie on
    different shooting intervals, so each is sampled densely and read at common arc
    lengths: between 64 samples a spline errs by 5e-8 L on the gravity grip.)"""
    problem = zoo()[name]
    compiled = elastica2d.solve(problem, solver=elastica2d.ShootingSolver(samples=512))
    shared = elastica2d.solve(problem, solver=elastica2d.ShootingSolver(shared_driver=True,
                                                                         samples=512))
    L = problem.part.length
    s = np.linspace(0.0, L, 201)
    assert np.abs(shape_at(shared, s) - shape_at(compiled, s)).max() <= 1e-9 * L
    for key, load in compiled.reactions.items():
        other = shared.reactions[key]
        size = max(np.abs(load.force).max(), 1.0)
        assert np.abs(np.asarray(other.force) - load.force).max() <= 1e-7 * size
    assert shared.residual <= 1e-9


@pytest.mark.parametrize("factor", [1.2, 3.0])
def test_both_drivers_say_a_column_pushed_past_its_critical_load_crossed_a_bifurcation(
        factor):
    """A cantilever pushed along its axis past Euler's load EI (pi / 2L)^2, solved cold:
    the path of growing load stays on the straight branch, whose det J changes sign at
    the critical load. Both the compiled ``kernels.follow`` and the shared driver (the
    model's ``det_sign``) refuse the steps that flip it until they are short enough that
    the crossing is genuine, then say so; the answer is the straight column (its tip at
    (L, 0), pointing along x) and unstable (its eigenvalue L (EI (pi / 2L)^2 - P) < 0)."""
    from pliant.core.events import CrossedBifurcation

    critical = math.pi**2 / 4.0
    problem = pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0), pl.push(
        1.0, force=(-factor * critical, 0.0), name="tip")))
    for shared in (False, True):
        eq = elastica2d.solve(problem, solver=elastica2d.ShootingSolver(shared_driver=shared))
        assert sum(isinstance(n, CrossedBifurcation) for n in eq.notes) == 1
        assert np.allclose(eq.tip, (1.0, 0.0, 0.0), atol=1e-12)
        assert eq.verdict == "unstable"
        assert eq.steps > 10  # the refused steps shortened until the crossing


def test_a_warm_2d_step_through_the_shared_driver_meets_the_elliptic_solution():
    """A warm start far from the next problem (a tip load from 1 to 15 N on a unit
    cantilever: one Newton from it does not contract) is followed by continuation; in
    both drivers the tip is Bisshopp and Drucker's elliptic-integral one to 1e-8 L (the
    closed-form tests' bound; the two differ by about that, each refining its own
    mesh)."""
    part = pl.Part(length=1.0, bending_stiffness=1.0)
    path = [pl.Problem(part, (pl.clamp(0.0), pl.push(1.0, force=(0.0, -f), name="tip")))
            for f in (1.0, 15.0)]
    x, y, phi = cantilever_tip(15.0)
    for shared in (False, True):
        answers = list(elastica2d.trace(path, solver=elastica2d.ShootingSolver(
            shared_driver=shared)))
        assert answers[-1].steps > 1  # the continuation ran, not one Newton
        tip = answers[-1].tip
        assert abs(tip[0] - x) <= 1e-8 and abs(tip[1] + y) <= 1e-8
        assert abs(tip[2] + phi) <= 1e-8
