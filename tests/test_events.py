"""Status and events as data (``pliant.core.events``): how a solve ended and what
happened on the way, typed, in both models, through pickling and JSON; the values the
events carry are checked against the answers they describe."""

from __future__ import annotations

import json
import math
import pickle
import time

import numpy as np
import pytest

import pliant as pl
from pliant.core.equilibrium import potential_energy
from pliant.core.events import (
    BranchTaken,
    Event,
    LowestEquilibrium,
    Status,
    WarmStartLost,
    has,
)
from pliant.errors import ConvergenceError
from pliant.models import clock, elastica2d, rod3d

from .helpers import precurved_3d


def test_a_singular_start_says_which_side_it_took_with_both_energies():
    """2D: the tip held near the clamp's axis (tests/test_stability.py: 20.86 J and
    45.14 J, both stable): the branch event names the side and the two energies, and
    its energy is the answer's."""
    eq = pl.solve(pl.Problem(pl.Part(1.0, 1.0), (
        pl.clamp(0.0), pl.grip(1.0, (0.333, -0.002), angle=-1.106, name="hand"))),
        solver=elastica2d.ShootingSolver(lowest=False))
    taken = [e for e in eq.events if isinstance(e, BranchTaken)]
    assert len(taken) == 1
    event = taken[0]
    assert event.side in ("left", "right")
    assert event.energy == pytest.approx(potential_energy(eq), rel=1e-6)
    assert event.energy == pytest.approx(20.86, abs=0.01)
    assert event.other_energy == pytest.approx(45.14, abs=0.01)
    assert not event.twin
    # The shape bows to the side it names: left is the chord turned by +90 degrees.
    chord = eq.position[-1] - eq.position[0]
    normal = np.array([-chord[1], chord[0]])
    middle = eq.position[len(eq.s) // 2] - eq.position[0]
    assert (middle @ normal > 0) == (event.side == "left")


def test_the_3d_lowest_equilibrium_event_carries_both_energies():
    """The pre-curved part of tests/test_rod3d.py: 9.85 J taken where the first route
    gave 11.47 J."""
    eq = rod3d.solve(precurved_3d(), solver=rod3d.RodSolver(elements=40))
    lowest = next(e for e in eq.events if isinstance(e, LowestEquilibrium))
    assert lowest.energy == pytest.approx(potential_energy(eq), rel=1e-9)
    assert lowest.route_energy == pytest.approx(11.47, abs=0.01)
    assert not any(isinstance(e, BranchTaken) for e in eq.events)  # replaced by it


STRIP = pl.Part(length=1.0, bending_stiffness=1.0, bending_stiffness_2=30.0,
                torsional_stiffness=1.0)


def strip_turned(turn: float) -> pl.Problem:
    """The flat strip of tests/test_rod3d.py clamped at both ends 10% closer than its
    length, the far end turned by ``turn`` about y: bowed up, its branch ends at a fold
    near 0.57 rad."""
    return pl.Problem(STRIP, (
        pl.clamp(0.0, position=(0.0, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 1, 0)),
        pl.clamp(1.0, position=(0.9, 0.0, 0.0), tangent=(math.cos(turn), 0.0, math.sin(turn)),
                 normal=(0, 1, 0), name="end")))


def test_a_warm_start_that_cannot_be_followed_is_an_event():
    """From the branch bowed up, turned past its fold: the warm start cannot be followed
    (the part snaps), so the solve lets the part settle from the last state before the
    fold and says so with a WarmStartLost, the event a path follower counts as a snap;
    here where it settles is the cold solve's answer too (the strip bowed down). A turn
    short of the fold is followed, with no such event."""
    start = rod3d.solve(strip_turned(-0.01))
    near = rod3d.solve(strip_turned(0.3), warm_start=start)
    assert not has(near.notes, WarmStartLost)
    far = rod3d.solve(strip_turned(0.8), warm_start=start)
    event = next(e for e in far.events if isinstance(e, WarmStartLost))
    assert event.to_dict()["kind"] == "warm_start_lost"
    assert "snaps through; this is where it settles from there" in event
    assert far.verdict == "stable"
    cold = rod3d.solve(strip_turned(0.8))
    assert np.allclose(far.position, cold.position, atol=1e-8)


def test_events_survive_pickling_and_read_as_their_words():
    event = BranchTaken("pliant took the branch that bows to the left", side="left",
                        energy=1.5, other_energy=2.5)
    again = pickle.loads(pickle.dumps(event))
    assert type(again) is BranchTaken and again == event
    assert (again.side, again.energy, again.other_energy, again.twin) == (
        "left", 1.5, 2.5, False)
    assert again.startswith("pliant took")  # the words, as before
    record = json.loads(json.dumps(again.to_dict()))
    assert record == {"kind": "branch", "message": str(event), "side": "left",
                      "energy": 1.5, "other_energy": 2.5, "twin": False}
    assert Event("a plain note").to_dict() == {"kind": "note", "message": "a plain note"}


@pytest.mark.parametrize("model", ["2d", "3d"])
def test_an_answer_says_it_converged_and_lists_its_events_in_json(model):
    if model == "2d":
        eq = pl.solve(pl.Problem(pl.Part(1.0, 1.0), (pl.clamp(0.0),
                                                     pl.push(1.0, (0.0, -1.0), name="tip"))))
    else:
        eq = rod3d.solve(pl.Problem(pl.Part(1.0, 1.0, torsional_stiffness=1.0), (
            pl.clamp(0.0, (0.0, 0.0, 0.0)), pl.push(1.0, (0.0, -1.0, 0.0), name="tip"))))
    data = json.loads(json.dumps(eq.to_dict()))
    assert eq.status is Status.CONVERGED and data["status"] == "converged"
    assert data["events"] == [e.to_dict() for e in eq.events]


@pytest.mark.parametrize(("settings", "status", "words"), [
    ({"max_steps": 1}, Status.STEP_BUDGET, "max_steps"),
    ({"time_budget": 1e-9}, Status.TIME_BUDGET, "time_budget"),
])
@pytest.mark.parametrize("model", ["2d", "3d"])
def test_a_budget_that_runs_out_is_its_status_with_what_to_do(model, settings, status,
                                                              words, monkeypatch):
    """A follower load (no energy minimum to fall back on) with a starved budget.

    The solvers' clock is the wall clock here: the CPU clock is held still for up to
    ``clock.REFRESH`` after its estimate ran ahead (a loaded machine), and that stall
    outlasts a 1e-9 s budget on a problem too small for the kernels to look at the
    clock, so which of the two ran out would be a matter of scheduling."""
    monkeypatch.setattr(clock, "now", time.perf_counter)
    if model == "2d":
        problem = pl.Problem(pl.Part(1.0, 1.0), (
            pl.clamp(0.0), pl.push(1.0, force=(0.0, 8.0), follower=True, name="tip")))
        solver = elastica2d.ShootingSolver(**settings)
        solve = elastica2d.solve
    else:
        problem = pl.Problem(pl.Part(1.0, 1.0, torsional_stiffness=1.0), (
            pl.clamp(0.0, (0.0, 0.0, 0.0)),
            pl.push(1.0, force=(0.0, 8.0, 0.0), follower=True, name="tip")))
        solver = rod3d.RodSolver(**settings)
        solve = rod3d.solve
    with pytest.raises(ConvergenceError) as err:
        solve(problem, solver=solver)
    assert err.value.status is status
    assert words in err.value.status.advice
