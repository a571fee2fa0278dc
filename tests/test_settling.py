"""Leaving an unstable equilibrium (issue 60, ``rod3d.settling``): a solve that ends on
one settles on the stable equilibrium it leads to; a warm step tells the stable branch
that leaves a bifurcation (no jump) from a snap, and a path and its verdict say which.
Each against an independent value: the elastica's closed form, an independent
minimiser's energy, the branch kept by ``settle=False``."""

from __future__ import annotations

import itertools
import json
import math
import re

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

import pliant as pl
from pliant.core.equilibrium import potential_energy
from pliant.core.events import LeftUnstable, jumped
from pliant.models import rod3d

from .helpers import LINE_ONTO_BOSS, cli

ROUND = pl.Part(length=1.0, bending_stiffness=1.0, torsional_stiffness=0.8)
CRITICAL = math.pi**2 / 4  # the cantilever's Euler load, EI = L = 1


def _column(factor: float) -> pl.Problem:
    return pl.Problem(ROUND, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                              pl.push(1.0, force=(-factor * CRITICAL, 0.0, 0.0), name="tip")))


def _left(eq) -> LeftUnstable:
    (note,) = [n for n in eq.notes if isinstance(n, LeftUnstable)]
    return note


@pytest.mark.parametrize("past", [1.05, 1.2])
def test_a_warm_step_past_euler_s_load_takes_the_buckled_branch_without_a_jump(past):
    """A cantilever's end load stepped from 0.9 of Euler's to past it: the straight
    branch followed turns unstable at a supercritical bifurcation; the part settles on
    the buckled elastica (tip off its axis by 2 k / lambda, along it at
    2 E(k) / lambda - L, K(k) = lambda L) and it is no jump: settled a quarter as far
    past the bifurcation, it moves about half as far (the square-root law)."""
    start = rod3d.solve(_column(0.9))
    eq = rod3d.solve(_column(past), warm_start=start)
    kept = rod3d.solve(_column(past), warm_start=start, solver=rod3d.RodSolver(settle=False))
    assert kept.verdict == "unstable" and abs(kept.position[:, 1:]).max() < 1e-9
    assert eq.verdict in ("stable", "neutral")
    note = _left(eq)
    assert not note.jump and not jumped(eq.notes)
    moved, law = map(float, re.search(r"it moves ([0-9.]+) as far: ([0-9.]+)", note).groups())
    assert moved == pytest.approx(law, abs=0.1)  # the square-root law's ratio
    lam = math.sqrt(past * CRITICAL)
    k = brentq(lambda k: ellipk(k * k) - lam, 1e-6, 0.99)
    tip = eq.position[-1]
    assert np.hypot(tip[1], tip[2]) == pytest.approx(2 * k / lam, rel=2e-3)
    assert tip[0] == pytest.approx(2 * ellipe(k * k) / lam - 1.0, rel=2e-3, abs=2e-4)
    assert potential_energy(eq) < potential_energy(kept) - 1e-3


def _arch(push: float) -> pl.Problem:
    """A strip (EI 1, 50 about its other axis) clamped along x at both ends 0.95 m apart:
    an arch bowed toward -y, pushed at its middle toward +y."""
    strip = pl.Part(1.0, 1.0, torsional_stiffness=1.0, bending_stiffness_2=50.0)
    return pl.Problem(strip, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1)),
        pl.clamp(1.0, (0.95, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1), name="end"),
        pl.push(0.5, force=(0.0, push, 0.0), name="middle")))


def test_an_arch_pushed_through_snaps_and_says_so():
    """The arch's middle pushed from 20 N to 40 N: the branch it was on turns unstable
    (kept by ``settle=False``), the part snaps through to the arch bowed the other way
    (its middle from y < 0 to y > 0), and settling a quarter as far past moves it as
    far: a jump, which the answer's notes say (``jumped``)."""
    arch = rod3d.solve(_arch(-1.0))
    middle = len(arch.s) // 2
    assert arch.position[middle, 1] < -0.1
    arch = rod3d.solve(_arch(20.0), warm_start=arch)
    assert not any(isinstance(n, LeftUnstable) for n in arch.notes)
    kept = rod3d.solve(_arch(40.0), warm_start=arch, solver=rod3d.RodSolver(settle=False))
    eq = rod3d.solve(_arch(40.0), warm_start=arch)
    assert kept.verdict == "unstable" and eq.verdict == "stable"
    assert eq.position[middle, 1] > 0.1
    note = _left(eq)
    assert note.jump and jumped(eq.notes)
    moved, law = map(float, re.search(r"it moves ([0-9.]+) as far: ([0-9.]+)", note).groups())
    assert moved > 0.9 and law < 0.6
    assert note.released > 1.0  # joules: a snap's, not a bifurcation's next to nothing


def test_an_unstable_answer_is_left_for_the_stable_one_it_leads_to():
    """Issue 60's strut: a round part (EI 1, GJ = EI / 1.5, L 1 m) clamped at both ends
    along +x, its ends pushed 0.75 m together. The planar buckled shape is unstable out
    of its plane (the route's answer, kept by ``settle=False``); the solve leaves it
    along its unstable mode and settles on the non-planar equilibrium, neutral (it may
    turn about the chord), whose energy an independent minimiser puts at 32.99 J
    (pliant's, extrapolated by Richardson's rule from 50 and 100 elements: second
    order). ``equilibria`` lists it first."""
    part = pl.Part(1.0, 1.0, torsional_stiffness=1.0 / 1.5)
    strut = pl.Problem(part, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1)),
        pl.clamp(1.0, (0.25, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1), name="end")))
    planar_ = rod3d.solve(strut, solver=rod3d.RodSolver(settle=False))
    assert planar_.verdict == "unstable"
    energies = []
    for elements in (50, 100):
        eq = rod3d.solve(strut, solver=rod3d.RodSolver(elements=elements))
        assert eq.verdict == "neutral"
        assert any(isinstance(n, LeftUnstable) or "unstable mode" in n for n in eq.notes)
        energies.append(potential_energy(eq))
    assert energies[1] < potential_energy(planar_) - 4.0
    extrapolated = energies[1] + (energies[1] - energies[0]) / 3.0
    assert extrapolated == pytest.approx(32.99, rel=5e-4)
    spread = np.linalg.svd(eq.position - eq.position.mean(axis=0), compute_uv=False)
    assert spread[2] > 0.1 * spread[0]  # not planar (the planar one's is 0)
    listed = rod3d.equilibria(strut)
    assert listed[0].verdict == "neutral"
    assert potential_energy(listed[0]) == pytest.approx(energies[1], rel=1e-9)


def test_a_path_across_a_bifurcation_fits_and_every_output_says_where(tmp_path):
    """A line lowered onto a boss, clip and hand in one vertical plane: its shape starts
    bowed out of that plane, comes into it, and in the plane turns unstable (out of
    plane) for a stretch of the path. Followed with ``settle=False`` the step there is
    unstable, which a real part does not stay on; the evaluation takes the stable branch
    beside it, lower in energy, with no jump, so the line FITS, and the CLI and the JSON
    say at which step it left the unstable shape."""
    from pliant.assembly import load_scene

    path = tmp_path / "line.toml"
    path.write_text(LINE_ONTO_BOSS.format(x=0.07, y=0.0, yc=0.24, ys=0.06, steps=10))
    scene = load_scene(path)
    kept, settled = [], []
    for solver, out in ((rod3d.RodSolver(elements=16, settle=False), kept),
                        (rod3d.RodSolver(elements=16), settled)):
        eq = None
        for problem in [scene.problem, *scene.path]:
            eq = rod3d.solve(problem, warm_start=eq, solver=solver)
            out.append(eq)
    branched = [k for k, eq in enumerate(settled)
                if any(isinstance(n, LeftUnstable) for n in eq.notes)]
    assert branched and all(kept[k].verdict == "unstable" for k in branched)
    assert [k for k, eq in enumerate(kept) if eq.verdict == "unstable"] == branched
    for k in branched:
        assert settled[k].verdict == "stable" and not jumped(settled[k].notes)
        assert potential_energy(settled[k]) < potential_energy(kept[k])
    done = cli("evaluate", path, "--json", tmp_path / "e.json")
    words = " ".join(done.stdout.split())
    assert done.returncode == 0 and "FITS" in words
    assert f"(a bifurcation: no jump) at steps {', '.join(map(str, branched))}" in words
    steps = json.loads((tmp_path / "e.json").read_text())["path"]["steps"]
    assert [k for k, s in enumerate(steps) if any(n["kind"] == "left_unstable"
                                                  for n in s["notes"])] == branched
    assert all(s["stable"] and not s["snap"] for s in steps)


def _strut(d: float) -> pl.Problem:
    part = pl.Part(1.0, 1.0, torsional_stiffness=1.0 / 1.5)
    return pl.Problem(part, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1)),
        pl.clamp(1.0, (1.0 - d, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1), name="end")))


def test_a_neutral_shape_is_followed_by_warm_steps_and_by_trace():
    """Issue 60 (6): a round strut buckled between coaxial clamps turns about its chord
    at no cost (neutral), so its Jacobian is singular and the warm Newton could not
    factorise it: every step of a path was 'solved from the rest state' and counted as
    a snap, and ``trace`` refused its start. Warm steps and ``trace`` now follow it (a
    shifted Newton takes the member of the family nearest the start), and each answer's
    energy is the cold solve's of the same problem (found independently, from rest)."""
    ends = np.linspace(0.3, 0.4, 6)
    eq = rod3d.solve(_strut(0.3))
    assert eq.verdict == "neutral"
    warm = []
    for d in ends[1:]:
        eq = rod3d.solve(_strut(float(d)), warm_start=eq)
        assert not jumped(eq.notes) and eq.verdict == "neutral"
        warm.append(eq)
    traced = list(pl.trace([_strut(float(d)) for d in ends[1:]],
                           start=rod3d.solve(_strut(0.3))))
    assert len(traced) == len(warm)
    for d, a, b in zip(ends[1:], warm, traced):
        cold = potential_energy(rod3d.solve(_strut(float(d))))
        assert potential_energy(a) == pytest.approx(cold, rel=1e-6)
        assert potential_energy(b) == pytest.approx(cold, rel=1e-6)


def _turned(phi: float, gap: float, part: pl.Part) -> pl.Problem:
    normal = (0.0, math.sin(phi), math.cos(phi))
    return pl.Problem(part, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1, 0, 0), normal=(0, 0, 1)),
        pl.clamp(1.0, (gap, 0.0, 0.0), tangent=(1, 0, 0), normal=normal, name="end")))


def test_twist_accumulates_through_full_turns():
    """Issue 60 (3): one clamp of a round rod turned in warm 10-degree steps to 450
    degrees. Taut (EA 1e6 N, its ends a length apart), the couple is Saint-Venant's
    GJ phi / L at every step (below Greenhill's 8.99 EI / L), to the mesh's error.
    Slack (its ends 0.9 L apart), the rod is neutral at every step (it may turn about
    its chord), so the warm steps used to be dropped (37 of 45 'solved from the rest
    state') and the couple fell back to zero after each full turn; now every step is
    followed and the couple grows with the turn, a full turn on it far from where it
    was."""
    taut = pl.Part(1.0, 1.0, torsional_stiffness=0.8, axial_stiffness=1e6)
    slack = pl.Part(1.0, 1.0, torsional_stiffness=0.8)
    for part, gap in ((taut, 1.0), (slack, 0.9)):
        eq = rod3d.solve(_turned(0.0, gap, part))
        couples = []
        for k in range(1, 46):
            phi = math.radians(10 * k)
            eq = rod3d.solve(_turned(phi, gap, part), warm_start=eq)
            assert not jumped(eq.notes)
            couples.append(-eq.loads["end"].moment[0])
            if gap == 1.0:  # within the mesh's second-order error, (phi / N)^2 / 6
                assert couples[-1] == pytest.approx(0.8 * phi, rel=(phi / 100) ** 2 / 4)
        assert all(b > a for a, b in itertools.pairwise(couples))
        assert couples[38] > couples[2] + 4.0  # 390 against 30 degrees


def test_a_round_off_eigenvalue_is_neutral_not_unstable():
    """The first 240 of 540 steps of PyElastica's localized helical buckling ramp (a
    round rod, B 1.345, C 0.789, one clamp turned toward 27 turns as the ends close in
    by 3 %): buckled and twisted, the rod is neutral (it may turn about its chord), and
    its smallest eigenvalue comes out at round-off, -2e-8 EI / L with internal loads in
    the hundreds. Judged against a fixed 1e-8 EI / L, such steps were called unstable
    (12 of them at 100 elements, 'settled' a few millimetres along the family); the
    tolerance now scales with the loads the eigensolver's accuracy is relative to, and
    every step left as unstable is a genuine instability (eigenvalue below -1e-3
    EI / L)."""
    part = pl.Part(1.0, 1.345, torsional_stiffness=0.789, axial_stiffness=1.345e4)
    solver = rod3d.RodSolver(elements=60)

    def ramp(f: float) -> pl.Problem:
        phi = f * 27 * 2 * math.pi
        return pl.Problem(part, (
            pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(0, 0, 1), normal=(1, 0, 0)),
            pl.clamp(1.0, (0.0, 0.0, 1.0 - 0.03 * f), tangent=(0, 0, 1),
                     normal=(math.cos(phi), math.sin(phi), 0.0), name="end")))

    eq = rod3d.solve(ramp(0.0), solver=solver)
    left = []
    for k in range(1, 240):
        eq = rod3d.solve(ramp(k / 540), warm_start=eq, solver=solver)
        assert eq.verdict in ("stable", "neutral")
        left += [n for n in eq.notes if isinstance(n, LeftUnstable)]
    assert len(left) <= 3
    assert all(n.eigenvalue < -1e-3 * 1.345 for n in left)
