"""A hand that holds a length of the part (issue 56, item 2): ``grip_length`` at an end,
against its independent twin (the shorter part clamped where the hand's stretch
starts), the closed form of a cantilever held over a stretch, the 2D and 3D models
against each other, and through a scene file, a path and the evaluation."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import pliant as pl
from pliant.assembly.evaluate import evaluate
from pliant.assembly.scenes import load_scene
from pliant.errors import FileFormatError, InputError
from pliant.models import elastica2d, rod3d

G = 9.81
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def held(s, position, grip, dim=3):
    if dim == 3:
        return pl.Condition(s=s, name="hand", position=position, tangent=(1.0, 0.0, 0.0),
                            normal=(0.0, 0.0, 1.0), grip_length=grip)
    return pl.Condition(s=s, name="hand", position=position, angle=0.0, grip_length=grip)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_hand_over_a_length_is_its_twin_clamped_where_the_stretch_starts(dim):
    """Clamp at 0, the hand holding the last l of L at (0.93, 0.05): the part up to the
    hand is the part of length L - l clamped at the heel (same shape), and the hand's
    wrench is the twin's clamp's plus the held stretch's weight (at the stretch's middle,
    about which the moment is taken)."""
    L, EI, q, grip, x = 1.0, 1.0, 3.0, 0.1, 0.93
    up = (0.0, 0.05, 0.0)[:dim] if dim == 2 else (0.0, 0.0, 0.05)
    g = (0.0, -G) if dim == 2 else (0.0, 0.0, -G)
    start = pl.clamp(0.0, (0.0,) * dim) if dim == 3 else pl.clamp(0.0, (0.0, 0.0), 0.0)

    def problem(length, s, at, grip):
        return pl.Problem(pl.Part(length, EI, mass_per_length=q / G),
                          (start, held(s, tuple(a + b for a, b in zip(at, up)), grip, dim)),
                          gravity=g)

    long_ = problem(L, L, (x, 0.0, 0.0)[:dim], grip)
    twin = problem(L - grip, L - grip, (x - grip, 0.0, 0.0)[:dim], 0.0)
    if dim == 3:
        a = rod3d.solve(long_, solver=rod3d.RodSolver(elements=200))
        b = rod3d.solve(twin, solver=rod3d.RodSolver(elements=180))
    else:
        a, b = elastica2d.solve(long_), elastica2d.solve(twin)
    hand, clamp = a.loads["hand"], b.loads["hand"]
    scale = float(np.abs(clamp.force).max())
    # the same solution up to the heel: the same reaction where the part starts
    np.testing.assert_allclose(a.loads["clamp"].force, b.loads["clamp"].force,
                               atol=1e-7 * scale)
    np.testing.assert_allclose(a.loads["clamp"].moment, b.loads["clamp"].moment,
                               atol=1e-7 * scale * L)
    if dim == 3:
        # its error estimate compares like with like (the heel's clamp in both twins of
        # Richardson's rule), as small as the point-clamped twin's
        assert a.reaction_error < 3 * b.reaction_error + 1e-4
        assert not any("reactions may be off" in n for n in a.notes)
    if dim == 3:  # nodes every 5 mm in both: the same shape node by node
        inside = a.s <= L - grip + 1e-12
        shape = np.column_stack([np.interp(a.s[inside], b.s, b.position[:, k])
                                 for k in range(dim)])
        assert np.abs(a.position[inside] - shape).max() < 1e-8 * L
    assert hand.s == pytest.approx(L - grip / 2)
    weight = np.zeros(dim)
    weight[-1] = q * grip
    np.testing.assert_allclose(hand.force, np.asarray(clamp.force) + weight,
                               atol=1e-7 * scale)
    lever = np.zeros(dim)
    lever[0] = -grip / 2
    f = np.asarray(clamp.force)
    if dim == 3:
        moment = np.asarray(clamp.moment) + np.cross(lever, f)
        np.testing.assert_allclose(hand.moment, moment, atol=1e-7 * scale * L)
    else:
        moment = clamp.moment + lever[0] * f[1] - lever[1] * f[0]
        assert hand.moment == pytest.approx(moment, abs=1e-7 * scale * L)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_cantilever_held_over_a_stretch_is_the_closed_form(dim):
    """A stiff heavy part held level by one hand over [0, l]: small deflection, so the
    tip sags q (L - l)^4 / 8 EI, the tightest bend is 2 EI / q (L - s)^2 at s = l, and
    the hand carries q L with the moment q L (L - l) / 2 about its middle (a point grip:
    q L^4 / 8 EI, at s = 0, and q L^2 / 2)."""
    L, EI, q, stretch = 1.0, 200.0, 2.0, 0.1
    g = (0.0, -G) if dim == 2 else (0.0, 0.0, -G)
    for grip, span, at in ((stretch, L - stretch, stretch), (0.0, L, 0.0)):
        problem = pl.Problem(pl.Part(L, EI, mass_per_length=q / G),
                             (held(0.0, (0.0,) * dim, grip, dim),), gravity=g)
        eq = (rod3d.solve(problem, solver=rod3d.RodSolver(elements=300)) if dim == 3
              else elastica2d.solve(problem))
        sag = q * span**4 / (8 * EI)  # 1.6e-3 L: nonlinear terms ~ sag^2
        assert -eq.position[-1, -1] == pytest.approx(sag, rel=2e-3)
        radius, where = eq.min_bend_radius()
        # the tightest bend at the stretch's heel (the 3D model's curvatures sit between
        # its nodes: half an element in), the closed form's curvature there
        assert where == pytest.approx(at, abs=L / 300)
        assert radius == pytest.approx(2 * EI / (q * (L - where)**2), rel=2e-3)
        hand = eq.loads["hand"]
        assert hand.force[-1] == pytest.approx(q * L, rel=1e-9)
        moment = abs(hand.moment[1]) if dim == 3 else abs(hand.moment)
        assert moment == pytest.approx(q * L * span / 2, rel=2e-3)


@pytest.mark.parametrize(("x", "y", "angle"), [(0.78, 0.05, 0.0), (0.6, 0.1, 0.5)])
def test_the_2d_and_3d_models_agree_on_a_hand_over_a_length(x, y, angle):
    """The same planar problem in both models (the 3D one in the x-z plane, its sections
    square to it): the hand's wrench agrees to the 3D model's discretisation."""
    L, EI, q, grip = 0.8, 0.5, 2.0, 0.095
    two = pl.Problem(pl.Part(L, EI, mass_per_length=q / G),
                     (pl.clamp(0.0, (0.0, 0.0), angle), held(L, (x, y), grip, 2)),
                     gravity=(0.0, -G))
    c, s = np.cos(angle), np.sin(angle)
    three = pl.Problem(pl.Part(L, EI, mass_per_length=q / G),
                       (pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(c, 0.0, s), normal=(-s, 0.0, c)),
                        held(L, (x, 0.0, y), grip)), gravity=(0.0, 0.0, -G))
    a = elastica2d.solve(two).loads["hand"]
    b = rod3d.solve(three, solver=rod3d.RodSolver(elements=300)).loads["hand"]
    np.testing.assert_allclose([b.force[0], b.force[2]], a.force, rtol=1e-3)
    assert -b.moment[1] == pytest.approx(a.moment, rel=1e-3)  # y turns x onto -z


def test_a_hand_over_a_length_is_refused_where_it_is_not_modelled():
    part = pl.Part(1.0, 1.0)
    with pytest.raises(InputError, match="end of the part"):
        pl.Problem(part, (pl.clamp(0.0, (0, 0, 0)), held(0.5, (0.5, 0.0, 0.0), 0.1)))
    with pytest.raises(InputError, match="not shorter than the part"):
        pl.Problem(part, (held(1.0, (0.5, 0.0, 0.0), 1.0),))
    with pytest.raises(InputError, match="give the position and the tangent"):
        pl.Problem(part, (pl.clamp(0.0, (0, 0, 0)),
                          pl.Condition(s=1.0, name="hand", position=(0.9, 0, 0),
                                       grip_length=0.1)))
    with pytest.raises(InputError, match="inside the stretch the hand holds"):
        pl.Problem(part, (pl.clamp(0.0, (0, 0, 0)), pl.pin(0.95, (0.85, 0.0, 0.0), "clip"),
                          held(1.0, (0.9, 0.0, 0.0), 0.1)))
    with pytest.raises(InputError, match="grip_length"):
        pl.Condition(s=1.0, name="hand", grip_length=-0.1)


def test_a_scene_path_and_evaluation_with_the_hand_over_a_length(tmp_path):
    """The engine bay with the fitter holding the oil line's last 95 mm: the path is
    followed, the tightest bend is off the hand's stretch, the hand's wrench is the
    heel's carried to the stretch's middle, and a point grip bends the line at the
    hand itself."""
    text = (EXAMPLES / "scenes" / "engine_bay.toml").read_text()
    text = text.replace('tangent = [0.0, 0.0, 1.0]      # the free end picked up, pointing up',
                        'tangent = [0.0, 0.0, 1.0]\ngrip_length = 0.095')
    assert "grip_length" in text
    for name in ("manifold.stl", "coolant_hose.toml"):
        (tmp_path / name).write_bytes((EXAMPLES / "scenes" / name).read_bytes())
    (tmp_path / "scene.toml").write_text(text)
    scene = load_scene(tmp_path / "scene.toml")
    assert scene.problem.condition("hand").grip_length == 0.095
    ev = evaluate(scene, search=False)
    assert ev.run.complete, ev.run.stopped
    L = scene.problem.part.length
    for eq in ev.run.equilibria:
        assert eq.loads["hand"].s == pytest.approx(L - 0.095 / 2)
        _, at = eq.min_bend_radius()
        assert at <= L - 0.095 + 1e-9
    # the same scene file refuses a hand over a length in the middle of the part
    (tmp_path / "mid.toml").write_text(text.replace("s = 0.75\nx = 0.55", "s = 0.7\nx = 0.55"))
    with pytest.raises(FileFormatError, match=r"hand\.grip_length"):
        load_scene(tmp_path / "mid.toml")
    point = replace(scene, problem=scene.problem.with_conditions(
        replace(c, grip_length=0.0) for c in scene.problem.conditions))
    eq = rod3d.solve(point.problem, solver=rod3d.RodSolver(elements=80))
    assert eq.loads["hand"].s == L


def test_a_2d_hand_over_a_length_warm_starts_and_passes_the_independent_check():
    """Moved in steps, the 2D model warm-starts from each answer (its unknowns read at
    the heel the model holds), and each answer passes the independent integration
    check of its equations and its stations' jumps (``reference.equilibrium_error``)."""
    from pliant.models.elastica2d.reference import equilibrium_error

    part = pl.Part(0.8, 0.5, mass_per_length=2.0 / G)

    def at(x):
        return pl.Problem(part, (pl.clamp(0.0, (0.0, 0.0), 0.5), held(0.8, (x, 0.1), 0.095, 2)),
                          gravity=(0.0, -G))
    start = elastica2d.solve(at(0.6))
    steps = list(elastica2d.trace([at(0.62), at(0.64), at(0.66)], start=start))
    assert len(steps) == 3
    for eq in (start, *steps):
        assert equilibrium_error(eq) < 1e-7
        assert not any("solved from" in n for n in eq.notes)  # warm, not started over
