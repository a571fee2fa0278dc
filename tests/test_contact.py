"""Contact in the 3D rod against closed forms and the 2D model, a drape that statics
predicts, no penetration, warm steps through contact, and random grips round an
obstacle: a non-penetrating equilibrium or a typed error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

import pliant as pl
from pliant.core.events import PushedOut, jumped
from pliant.errors import PliantError
from pliant.models import rod3d
from pliant.models.banded import dense, identity_rows
from pliant.models.rod3d import contact_kernels
from pliant.models.rod3d.contact_kernels import COMPLIANCE
from pliant.models.rod3d.lowering import lower
from pliant.scene import Obstacle
from pliant.scene.interference import of_equilibrium

RADIUS = 0.01
ACROSS_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # z axis -> y


def part(weight: float) -> pl.Part:
    """L = 1 m, EI = 1 N m^2, weight q L^3 / EI = weight, outer radius 1 cm."""
    return pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=weight / 9.81,
                   outer_diameter=2 * RADIUS)


def penetration(eq) -> float:
    """The deepest the tube goes into any obstacle, sampled densely along the part,
    relative to its radius."""
    X = eq.position
    t = np.linspace(0.0, 1.0, 21)[:, None, None]
    points = (X[:-1] + t * (X[1:] - X[:-1])).reshape(-1, 3)
    d, _, _ = eq.state.rod.obstacles.query(points, band=1.0)
    return float(max(0.0, (RADIUS - d).max()) / RADIUS)


@pytest.mark.parametrize("a", [1.0, 0.8])
@pytest.mark.parametrize("kind", ["rod", "knife edge"])
def test_propped_cantilever(a, kind):
    """A cantilever under its weight (q L^3 / EI = 0.1, small deflection) resting on a
    thin rod across it, or on the sharp edge of a plate (1 mm thick, beyond x = a), at
    x = a: the prop carries P = q (6 L^2 - 4 L a + a^2) / 8a (3 q L / 8 at the tip), and
    the frictionless prop's force is square to the part where they touch, so it leans
    by the part's slope there, q (a^3 - 3 L a^2 + 3 L^2 a) / 6 EI - P a^2 / 2 EI. Over
    the knife's edge a probe fixed on the part would lean by up to half its spacing over
    the radius (0.125 here), not by the slope (2e-3 at the tip): the element's point
    nearest the edge takes the force (the straight element's slope is the part's to
    O(h) there: 2%)."""
    q = 0.1
    if kind == "rod":
        prop = Obstacle.cylinder("prop", 0.005, 0.2, (a, 0.0, -(RADIUS + 0.005)), ACROSS_Y)
    else:
        prop = Obstacle.box("prop", (0.001, 0.2, 0.1), (a + 0.0005, 0.0, -RADIUS - 0.05))
    problem = pl.Problem(part(q), (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),),
                         gravity=(0.0, 0.0, -9.81), obstacles=(prop,))
    eq = rod3d.solve(problem)
    total = eq.contacts.by_obstacle()["prop"]
    P = q * (6 - 4 * a + a * a) / (8 * a)
    assert total[2] == pytest.approx(P, rel=2e-3)
    slope = q * (a**3 - 3 * a * a + 3 * a) / 6 - P * a * a / 2  # downward, small
    assert total[0] / total[2] == pytest.approx(slope, rel=0.02) and total[1] == 0.0
    assert penetration(eq) < 1e-6


def test_tip_on_a_floor_matches_the_2d_model_with_the_tip_held_at_that_height():
    """Large deflection: a heavy cantilever (q L^3 / EI = 10) droops onto a frictionless
    floor that stops its tip 0.5 m down; the 2D model with the tip's height prescribed
    (and x free: a frictionless support) gives the same support force and tip."""
    floor = Obstacle.halfspace("floor", (0.0, 0.0, -0.5 - RADIUS), (0.0, 0.0, 1.0))
    problem = pl.Problem(part(10.0), (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),),
                         gravity=(0.0, 0.0, -9.81), obstacles=(floor,))
    eq = rod3d.solve(problem)
    planar = pl.solve(pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0,
                                         mass_per_length=10.0 / 9.81),
                                 (pl.clamp(0.0), pl.Condition(s=1.0, name="tip",
                                                              position=(None, -0.5))),
                                 gravity=(0.0, -9.81)))
    assert len(eq.contacts) == 1 and eq.contacts.s[0] == pytest.approx(1.0)
    assert eq.contacts.force[0, 2] == pytest.approx(planar.reactions["tip"].force[1], rel=5e-4)
    assert eq.position[-1, 0] == pytest.approx(planar.position[-1, 0], abs=1e-4)
    # The floor, the clamp and the weight balance.
    vertical = eq.contacts.force[:, 2].sum() + eq.loads["clamp"].force[2]
    assert vertical == pytest.approx(10.0, rel=1e-9)


def test_drape_over_a_drum_touches_where_statics_says():
    """A heavy part (q L^3 / EI = 400) clamped horizontally at the top of a drum (radius
    0.1 m) wraps round it: it conforms (curvature 1 / (R + r)) until the moment of the
    hanging rest falls to EI / (R + r). The 2D model of the hanging rest, clamped along
    the drum at angle phi, gives that angle; the 3D contact ends there (to a probe
    spacing), no probe is inside the drum and the tube penetrates by less than 1% of its
    radius anywhere (the chord sag between probes 2.5 mm apart round a radius of 0.11 m:
    0.07%)."""
    rho = 0.1 + RADIUS
    q = 400.0

    def clamp_moment(phi: float) -> float:
        rest = pl.Part(length=0.5 - rho * phi, bending_stiffness=1.0, mass_per_length=q / 9.81)
        free = pl.Problem(rest, (pl.clamp(0.0, position=(rho * math.sin(phi),
                                                         rho * math.cos(phi)),
                                          angle=-phi),), gravity=(0.0, -9.81))
        return pl.solve(free).loads["clamp"].moment

    phi = brentq(lambda f: clamp_moment(f) - 1.0 / rho, 0.05, 1.5, xtol=1e-10)
    drum = Obstacle.cylinder("drum", 0.1, 0.3, (0.0, 0.0, 0.0), ACROSS_Y)
    problem = pl.Problem(part(q), (pl.clamp(0.5, position=(0.0, 0.0, rho), tangent=(1, 0, 0),
                                            normal=(0, 0, 1), name="top"),),
                         gravity=(0.0, 0.0, -9.81), obstacles=(drum,))
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=200))
    reach = np.abs(eq.contacts.s - 0.5)
    assert reach.max() == pytest.approx(rho * phi, abs=0.0025)  # a probe spacing
    assert np.allclose(eq.contacts.s - 0.5, -(eq.contacts.s - 0.5)[::-1], atol=1e-9)
    assert np.allclose(eq.position[:, 0], -eq.position[::-1, 0], atol=1e-9)
    gaps = np.linalg.norm(eq.position[:, [0, 2]], axis=1) - rho
    assert gaps.min() > -1e-9 * RADIUS
    assert penetration(eq) < 0.01


def _lowered_onto_a_block(z: float) -> pl.Problem:
    """A 1 m hose (EI = 0.05 N m^2, 20 mm) clamped at the origin, its end held at
    (0.95, 0, z) over a block whose top is at z = -0.07."""
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=2 * RADIUS)
    block = Obstacle.box("block", (0.2, 0.2, 0.1), (0.7, 0.0, -0.12))
    return pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                             pl.pin(1.0, position=(0.95, 0.0, z), name="hand")),
                      gravity=(0.0, 0.0, -9.81), obstacles=(block,))


def test_warm_steps_press_a_part_onto_a_block_and_lift_it_off():
    """A hand lowers the end of a hose onto a block and lifts it again: contact comes
    and goes along the trace, each step balanced, the force continuous and zero when
    lifted. The hose bends over the block's edge: its probes (2.5 mm apart) keep the
    chord's sag round the edge, and so any penetration, under 1% of the radius."""
    held = _lowered_onto_a_block
    heights = np.concatenate([np.linspace(0.2, -0.15, 25), np.linspace(-0.15, 0.2, 25)[1:]])
    forces = []
    for eq in rod3d.trace([held(z) for z in heights]):
        assert eq.residual < 1e-9 and penetration(eq) < 0.01
        total = eq.contacts.by_obstacle().get("block", np.zeros(3))
        weight = 0.3 * 9.81
        vertical = total[2] + eq.loads["clamp"].force[2] + eq.loads["hand"].force[2]
        assert vertical == pytest.approx(weight, rel=1e-8)
        forces.append(total[2])
    forces = np.array(forces)
    assert forces[0] == 0.0 and forces[-1] == 0.0 and forces.max() > 0.1
    # Frictionless and elastic: no hysteresis, the way up retraces the way down.
    assert np.allclose(forces, forces[::-1], rtol=1e-6, atol=1e-9)
    # The force rises from zero at touchdown: between the last free step and the first
    # touching one, finer steps take it up from much nearer zero.
    first = int(np.argmax(forces > 0.0))
    fine = np.linspace(heights[first - 1], heights[first], 9)
    finer = [eq.contacts.by_obstacle().get("block", np.zeros(3))[2]
             for eq in rod3d.trace([held(z) for z in fine])]
    assert finer[0] == 0.0 and np.all(np.diff(finer) >= 0.0)
    assert 0.0 < max(f for f in finer if f > 0.0) and min(f for f in finer if f > 0.0) < (
        0.3 * forces[first])


def test_a_warm_contact_step_lands_where_a_cold_solve_does():
    """A warm step (its predictor, then chord steps on that one factorisation) and a
    cold solve (the continuation from the straight part, a fresh Jacobian every Newton
    step) reach a touching equilibrium by different iterations: the same one, to far
    below the discretisation's error, with the same contact force."""
    held = _lowered_onto_a_block
    warm = rod3d.solve(held(-0.02))
    for z in (-0.0235, -0.027, -0.0305):
        warm = rod3d.solve(held(z), warm_start=warm)
    cold = rod3d.solve(held(-0.0305))
    assert len(warm.contacts) and warm.residual < 1e-9 and cold.residual < 1e-9
    assert np.abs(warm.position - cold.position).max() < 1e-8
    force = warm.contacts.by_obstacle()["block"]
    assert np.allclose(force, cold.contacts.by_obstacle()["block"], rtol=1e-6, atol=1e-9)
    assert np.allclose(warm.loads["hand"].force, cold.loads["hand"].force, rtol=1e-6,
                       atol=1e-9)


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(x=st.floats(0.55, 0.85), y=st.floats(-0.3, 0.3), z=st.floats(-0.3, 0.3),
       height=st.floats(-0.12, 0.12), weight=st.floats(0.0, 2.0))
def test_random_grips_round_an_obstacle_never_penetrate(x, y, z, height, weight):
    """A hose clamped at the origin, its end held anywhere beyond a pole across its
    path: a converged equilibrium that keeps out of the pole (within 1% of the tube's
    radius, round its side or its rim's edge), or a typed error."""
    pole = Obstacle.cylinder("pole", 0.04, 0.6, (0.35, 0.0, height), ACROSS_Y)
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=weight / 9.81,
                   outer_diameter=2 * RADIUS)
    try:
        problem = pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                    pl.pin(1.0, position=(x, y, z), name="hand")),
                             gravity=(0.0, 0.0, -9.81), obstacles=(pole,))
        eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=60))
    except PliantError:
        return
    assert eq.residual < 1e-9
    assert penetration(eq) < 0.01
    assert np.all(eq.contacts.force @ np.array([0.0, 1.0, 0.0]) < 1e-9)  # normal to the pole


def _jacobians(run, state, eps: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
    """The KKT Jacobian at ``state`` as the kernels build it, and by central differences."""
    rod = run.rod
    _, ab, _ = run.residual(state, rod.target, want_jac=True)
    n = rod.n
    fd = np.zeros((n, n))
    for j in range(n):
        du = np.zeros(n)
        du[j] = eps
        plus = run.residual(run.step(state, du, 1.0), rod.target)[0]
        minus = run.residual(run.step(state, du, -1.0), rod.target)[0]
        fd[:, j] = (plus - minus) / (2.0 * eps)
    return dense(ab, rod.kl, rod.ku, n), fd


def _free_rows_agree(run, state) -> None:
    """The rows the contact Newton leaves out of its factorisation as the free probes'
    (read from the active set) are exactly those the band shows to be the identity's
    (``banded.identity_rows``), some of each kind present."""
    rod = run.rod
    _, ab, _ = run.residual(state, rod.target, want_jac=True)
    active = run.contacts(state, rod.target)[3]
    found = identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
    free = contact_kernels.free_rows(active, rod.iprobe, rod.slot, rod.n)
    assert np.array_equal(free, found)
    assert found[rod.islot].any() and not found[rod.islot].all()


def test_contact_jacobian_matches_finite_differences():
    """The KKT Jacobian with contacts (forces on the nodes, the gap rows of touching
    probes, the turning of the normals over a box's face, edge and corner and round a
    cylinder) against central differences, at a shape dipped into both obstacles with
    random forces on the probes near them."""
    from pliant.models.rod3d import solver as rod_solver
    from pliant.models.rod3d.lowering import lower

    block = Obstacle.box("block", (0.2, 0.2, 0.1), (0.7, 0.02, -0.12))
    drum = Obstacle.cylinder("drum", 0.05, 0.3, (0.4, 0.0, -0.08), ACROSS_Y)
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=2 * RADIUS)
    problem = pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                pl.pin(1.0, position=(0.95, 0.0, -0.05), name="hand")),
                         gravity=(0.0, 0.0, -9.81), obstacles=(block, drum))
    rod = lower(problem, 12)
    run = rod_solver.Run(rod, rod3d.RodSolver())
    _, rest = rod.rest()
    run.gauge_quat = rest[1][0].copy()
    X = rest[0].copy()
    X[:, 1] += 0.01 * np.sin(7.0 * np.linspace(0.0, 1.0, X.shape[0]))
    X[:, 2] -= 0.07 * np.sin(np.pi * np.linspace(0.0, 1.0, X.shape[0]))
    free = (X, rest[1], rest[2], rest[3], np.zeros(rod.iprobe.shape[0]))
    gaps = run.contacts(free, rod.target)[0]
    near = gaps < 0.05
    assert near.sum() > 10
    gam = np.where(near, np.random.default_rng(0).uniform(0.1, 1.0, gaps.shape), 0.0)
    state = (X, rest[1], rest[2], rest[3], gam)
    J, fd = _jacobians(run, state)
    touching = run.contacts(state, rod.target)[3]
    assert touching.sum() > 5
    # A free probe without force keeps only its row (d gam = 0): its column, which the
    # kernel leaves out, would only ever multiply zero.
    idle = rod.iprobe[(gam == 0.0) & (touching == 0)]
    fd[:, idle] = J[:, idle]
    assert np.all(J[np.ix_(idle, idle)] == np.eye(idle.size))
    assert np.abs(J - fd).max() < 1e-5 * max(1.0, np.abs(J).max())
    _free_rows_agree(run, state)


def test_sliders_jacobian_matches_finite_differences():
    """Over an edge or a curved obstacle an element's contact point is its point nearest
    the obstacle, which moves along it with the nodes: the force's Jacobian gains
    lam c c^T / g'' (contact_kernels._slide_jacobian). Checked against central
    differences where sliders rest inside their elements over a drum, a box's edge
    and a mesh's edges and vertices (an icosphere), each dipped 0.3 mm."""
    from dataclasses import replace

    import trimesh

    from pliant.models.rod3d import solver as rod_solver
    from pliant.scene.distance import DistanceField

    def height(x):
        return 0.03 * np.maximum(x - 0.45, 0.0)

    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.05)
    placed = (Obstacle.cylinder("drum", 0.05, 0.3, (0.2, 0.0, -0.1), ACROSS_Y),
              Obstacle.box("block", (0.12, 0.2, 0.1), (0.58, 0.0, -0.1)),
              Obstacle.from_mesh("ball", ball.vertices + [0.83, 0.013, -0.1], ball.faces,
                                 crease=0.0))  # its edges and vertices, sharp
    x = np.linspace(0.0, 1.0, 20001)
    line = np.column_stack([x, np.zeros_like(x), height(x)])
    obstacles = []
    for ob in placed:  # each raised until the part's axis dips 0.3 mm into its tube
        for _ in range(4):  # (a sloped line: a shift moves the nearest point a little)
            d, _, _ = DistanceField([ob]).query(line, band=1.0)
            ob = replace(ob, translation=ob.translation
                         + [0.0, 0.0, d.min() - (RADIUS - 0.0003)])
        obstacles.append(ob)
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=2 * RADIUS)
    problem = pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),),
                         gravity=(0.0, 0.0, -9.81), obstacles=tuple(obstacles))
    rod = lower(problem, 24)
    run = rod_solver.Run(rod, rod3d.RodSolver())
    _, rest = rod.rest()
    run.gauge_quat = rest[1][0].copy()
    X = rest[0].copy()
    X[:, 2] = height(X[:, 0])
    gaps = run.contacts((X, rest[1], rest[2], rest[3], np.zeros(rod.iprobe.shape[0])),
                        rod.target)[0]
    gam = np.where(gaps < 0.0, np.random.default_rng(1).uniform(0.5, 2.0, gaps.shape), 0.0)
    state = (X, rest[1], rest[2], rest[3], gam)
    _, _, which, touching, where, _, _ = run.contacts(state, rod.target)
    slid = rod.slider[(where[rod.slider] > 0.0) & (where[rod.slider] < 1.0)
                      & (where[rod.slider] != 0.5) & (gam[rod.slider] > 0.0)]
    names = {rod.distance_field.obstacles[o].name for o in which[slid]}
    assert names == {"drum", "block", "ball"}
    J, fd = _jacobians(run, state)
    idle = rod.iprobe[(gam == 0.0) & (touching == 0)]
    fd[:, idle] = J[:, idle]
    assert np.abs(J - fd).max() < 1e-5 * max(1.0, np.abs(J).max())
    _free_rows_agree(run, state)


# -- friction --------------------------------------------------------------------------
def _tip_on_a_floor(mu: float, x: float) -> pl.Problem:
    """The heavy cantilever (q L^3 / EI = 10) whose tip rests on a floor 0.5 m down, with
    Coulomb friction mu there, its clamp moved along x by ``x``."""
    floor = Obstacle.halfspace("floor", (0.0, 0.0, -0.5 - RADIUS), (0.0, 0.0, 1.0))
    return pl.Problem(part(10.0), (pl.clamp(0.0, position=(x, 0.0, 0.0)),),
                      gravity=(0.0, 0.0, -9.81), obstacles=(floor.with_friction(mu),))


def _pushed_tip_2d(force) -> np.ndarray:
    """The tip (x, z) of the 2D model of the same cantilever, its tip pushed by ``force``
    (horizontal, vertical) [N] instead of resting on the floor."""
    planar = pl.solve(pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0,
                                         mass_per_length=10.0 / 9.81),
                                 (pl.clamp(0.0), pl.push(1.0, force=tuple(force), name="tip")),
                                 gravity=(0.0, -9.81)))
    return planar.position[-1]


def test_friction_slides_on_the_cone_and_sticks_inside_it():
    """Coulomb friction at a tip on a floor (mu = 0.3), the clamp dragged along x in
    1 cm steps: the tip slides with it, the floor's force on the cone's rim (friction
    = mu N, against the motion), and the 2D model pushed at the tip by that force puts
    the tip where it is. Moved back 0.2 mm, the tip sticks: it stays within its elastic
    slip, moved by what the penalty law's spring gives, the
    friction falls inside the cone, and again the 2D model pushed by it agrees. With
    mu = 0 the answer is the frictionless one."""
    mu = 0.3
    eq = rod3d.solve(_tip_on_a_floor(mu, 0.0))
    frictionless = rod3d.solve(_tip_on_a_floor(0.0, 0.0))
    assert np.abs(eq.position - frictionless.position).max() < 1e-12
    assert not np.any(eq.contacts.friction)  # a cold solve has no history: no friction
    for x in (0.01, 0.02, 0.03):
        before = eq.position[-1].copy()
        eq = rod3d.solve(_tip_on_a_floor(mu, x), warm_start=eq)
        (normal, friction), moved = eq.contacts.force[0, [2, 0]], eq.position[-1] - before
        assert len(eq.contacts) == 1 and moved[0] > 5e-3
        assert friction == pytest.approx(-mu * normal, rel=1e-9)  # on the rim, backwards
        assert eq.contacts.friction[0, 1] == pytest.approx(0.0, abs=1e-12)
        # on the floor, by the contact's compliance (its gap per unit force, L = EI = 1)
        assert eq.position[-1, 2] == pytest.approx(-0.5 - COMPLIANCE * normal, abs=1e-12)
    tip = _pushed_tip_2d((friction, normal))
    assert tip == pytest.approx([eq.position[-1, 0] - 0.03, -0.5], abs=1e-4)
    # Weight, clamp and floor balance.
    total = eq.contacts.force.sum(axis=0) + eq.loads["clamp"].force
    assert total == pytest.approx([0.0, 0.0, 10.0], abs=1e-9)
    stuck, held, pressed = eq.position[-1].copy(), friction / (mu * normal), normal
    eq = rod3d.solve(_tip_on_a_floor(mu, 0.0298), warm_start=eq)
    (normal, friction) = eq.contacts.force[0, [2, 0]]
    assert abs(friction) < mu * normal * (1.0 - 1e-3)
    # It gives way as the contact's spring does: by its elastic slip (ELASTIC_SLIP of the
    # element, L = 1) per its share of the friction limit, from where it was slack; and
    # rises by the gap's compliance as the floor's force falls.
    give = contact_kernels.ELASTIC_SLIP / rod3d.RodSolver().elements
    moved = give * (held - friction / (mu * normal))
    assert eq.position[-1] - stuck == pytest.approx(
        [moved, 0.0, COMPLIANCE * (pressed - normal)], rel=1e-4, abs=1e-13)
    assert abs(moved) < give
    tip = _pushed_tip_2d((friction, normal))
    assert tip == pytest.approx([stuck[0] - 0.0298, -0.5], abs=1e-4)
    assert eq.stable is None  # with friction, stability is not the energy's minimum


def test_a_planar_contact_answer_holds_no_round_off_below_the_flush():
    """A hose lowered onto a block lies in the x-z plane: its out-of-plane components
    are zero, and Newton's round-off round them shrinks every iteration. Each update
    sets what falls below ``kernels.FLUSH`` to zero, so no component is left between
    zero and it (there, in the subnormal range, each operation costs a hundred). Pressed
    over the block's edge, the planar shape turns unstable (a real hose rolls off it
    sideways, as a default solve does): ``settle=False`` keeps the planar branch."""
    from pliant.models.rod3d.kernels import FLUSH

    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)
    block = Obstacle.box("block", (0.2, 0.2, 0.1), (0.7, 0.0, -0.12))
    eq = None
    for z in np.linspace(0.2, -0.05, 26):
        problem = pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                    pl.pin(1.0, position=(0.95, 0.0, float(z)), name="hand")),
                             gravity=(0.0, 0.0, -9.81), obstacles=(block,))
        eq = rod3d.solve(problem, warm_start=eq, solver=rod3d.RodSolver(settle=False))
    assert len(eq.contacts)  # it lies over the block's edge
    assert np.abs(eq.position[:, 1]).max() == 0.0  # in its plane exactly
    for part in eq.state.state:
        values = np.abs(np.asarray(part, dtype=float))
        assert not np.any((values > 0.0) & (values < FLUSH))


def _on_a_bench(mu: float, y: float) -> pl.Problem:
    """A hose lying along a bench (mu there), clamped at one end, its other end held and
    moved sideways by ``y`` (and drawn in by 0.3 y)."""
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=0.02)
    bench = Obstacle.box("bench", (0.6, 0.6, 0.1), (0.5, 0.0, -0.11)).with_friction(mu)
    return pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0), tangent=(1, 0, 0),
                                      normal=(0, 0, 1)),
                             pl.pin(1.0, position=(0.95 - 0.3 * y, y, 0.0), name="hand")),
                      gravity=(0.0, 0.0, -9.81), obstacles=(bench,))


def test_a_hose_dragged_along_a_bench_slides_on_the_friction_limit():
    """A hose lying along a flat face (sixty-odd contacts, all in one plane, so rigid
    sticks would be dependent: the KKT matrix was singular and the first drag step
    failed), dragged sideways in 5 mm steps with mu = 0.3: every step converges; bench,
    clamp, hand and weight balance; no contact's friction leaves Coulomb's disc; the
    sliding ones (on its rim: all of them, the whole hose is dragged) push against the
    way their point moved; the drag costs the work of friction."""
    mu = 0.3
    eq = rod3d.solve(_on_a_bench(mu, 0.0))
    weight = np.array([0.0, 0.0, -0.3 * 9.81])
    rim = 0
    for y in 0.005 * np.arange(1, 7):
        before = eq
        eq = rod3d.solve(_on_a_bench(mu, y), warm_start=eq)
        assert eq.residual < 1e-9
        c = eq.contacts
        assert len(c) > 40 and set(c.obstacle) == {"bench"}
        total = c.force.sum(axis=0) + eq.loads["clamp"].force + eq.loads["hand"].force
        assert total + weight == pytest.approx(np.zeros(3), abs=1e-9)
        friction = np.linalg.norm(c.friction, axis=1)
        normal = c.force[:, 2]  # the face is flat: the normal force is its z part
        assert np.all(normal > 0.0) and np.abs(c.friction[:, 2]).max() < 1e-12
        assert np.all(friction <= mu * normal * (1.0 + 1e-9))
        moved = c.point - np.column_stack([np.interp(c.s, before.s, before.position[:, j])
                                           for j in range(3)])
        sliding = (friction > mu * normal * (1.0 - 1e-9)) & (
            np.linalg.norm(moved, axis=1) > 1e-4)
        if y > 0.005:  # friction built up from the cold solve, which had none
            assert sliding.mean() > 0.9
        cosine = np.einsum("kc,kc->k", c.friction[sliding], moved[sliding]) / (
            friction[sliding] * np.linalg.norm(moved[sliding], axis=1))
        assert np.all(cosine < -0.99)
        rim += int(sliding.sum())
    assert rim > 200


def test_contact_jacobian_with_friction_matches_finite_differences():
    """The Jacobian of Coulomb's law (stuck, sliding and free probes) and of the
    tangential forces on the nodes against central differences."""
    from pliant.models.rod3d import solver as rod_solver
    from pliant.models.rod3d.lowering import lower

    drum = Obstacle.cylinder("drum", 0.05, 0.3, (0.4, 0.0, -0.08), ACROSS_Y).with_friction(0.4)
    hose = pl.Part(length=1.0, bending_stiffness=0.05, mass_per_length=0.3,
                   outer_diameter=2 * RADIUS)
    problem = pl.Problem(hose, (pl.clamp(0.0, position=(0.0, 0.0, 0.0)),
                                pl.pin(1.0, position=(0.95, 0.0, -0.05), name="hand")),
                         gravity=(0.0, 0.0, -9.81), obstacles=(drum,))
    rod = lower(problem, 12)
    assert rod.friction
    run = rod_solver.Run(rod, rod3d.RodSolver())
    _, rest = rod.rest()
    run.gauge_quat = rest[1][0].copy()
    X = rest[0].copy()
    X[:, 2] -= 0.07 * np.sin(np.pi * np.linspace(0.0, 1.0, X.shape[0]))
    start = (X, rest[1], rest[2], rest[3], np.zeros(rod.islot.shape[0]))
    run.hold(start)
    X = X.copy()
    # Some slip: a sticking probe gives way up to its elastic slip (contact_kernels.ELASTIC_SLIP
    # of its element), so slips of up to three of those put some probes inside the
    # friction disc and some on its rim.
    give = contact_kernels.ELASTIC_SLIP / 12
    X[:, 0] += 3.0 * give * np.cos(5.0 * np.linspace(0.0, 1.0, X.shape[0]))
    gaps = run.contacts(start, rod.target)[0]
    near = gaps < 0.05
    rng = np.random.default_rng(1)
    gam = np.zeros((rod.iprobe.shape[0], 3))
    gam[near, 0] = rng.uniform(0.1, 1.0, near.sum())
    gam[near, 1:] = rng.normal(scale=0.3, size=(near.sum(), 2))
    state = (X, rest[1], rest[2], rest[3], gam.ravel())
    J, fd = _jacobians(run, state)
    idle = rod.iprobe[(gam[:, 0] == 0.0) & (run.contacts(state, rod.target)[3] == 0)]
    fd[:, idle] = J[:, idle]
    # Both regimes are present among the probes with a normal force.
    slip = np.einsum("kic,kc->ki", run.friction[2], rod.probe_points(X) - run.friction[1])
    v = np.linalg.norm(slip, axis=1) / run.friction[3]
    on = gam[:, 0] > 0
    assert np.any(v[on] < 0.9) and np.any(v[on] > 1.1)
    assert np.abs(J - fd).max() < 1e-5 * max(1.0, np.abs(J).max())
    _free_rows_agree(run, state)


def test_the_rest_shape_through_an_obstacle_is_measured_in_metres_on_a_2_m_part():
    """The unloaded part's straight line from the clamp runs through a ball; the homotopy
    starts with every gap widened by how deep it goes, in units of L: (R + r) / L plus
    a hundredth. (It was queried at points in units of L, as if in metres: on a part
    that is not 1 m long the ball was missed, and the solve failed at the start.)"""
    part = pl.Part(length=2.0, bending_stiffness=2.0, outer_diameter=0.02)
    problem = pl.Problem(part, (pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1, 0, 0),
                                         normal=(0, 0, 1)),
                                pl.grip(2.0, (1.6, 0.6, 0.0), tangent=(0.0, 1.0, 0.0),
                                        name="hand")),
                         obstacles=(Obstacle.sphere("ball", 0.1, (1.5, 0.0, 0.0)),))
    loads, _ = lower(problem, elements=40).rest()
    assert loads.offset == pytest.approx((0.1 + 0.01) / 2.0 + 0.01, rel=1e-9)
    eq = rod3d.solve(problem, solver=rod3d.RodSolver(elements=40))
    assert eq.residual < 1e-9
    assert of_equilibrium(eq).smallest.clearance > 0.0


def test_a_hose_lying_along_a_floor_is_solved():
    """A hose held a few centimetres over a floor at both ends lies along it: its
    touching probes are dependent (a probe between two touching ones adds nothing), which
    made the Jacobian singular in 29 of 30 such cases. With the contact's compliance
    every one converges, in balance, lying on the floor by no more than the compliance
    times its force."""
    rng = np.random.default_rng(3)
    floor = Obstacle.halfspace("floor", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    for _ in range(4):
        part = pl.Part(1.0, rng.uniform(0.01, 0.1), mass_per_length=rng.uniform(0.1, 0.5),
                       outer_diameter=0.02)
        z = 0.01 + rng.uniform(0.0, 0.05)
        end = (rng.uniform(0.5, 0.9), rng.uniform(-0.2, 0.2), z)
        eq = rod3d.solve(pl.Problem(part, (
            pl.Condition(s=0.0, name="a", position=(0.0, 0.0, z), tangent=(1.0, 0.0, 0.0)),
            pl.Condition(s=1.0, name="b", position=end, tangent=(1.0, 0.0, 0.0))),
            gravity=(0.0, 0.0, -9.81), obstacles=(floor,)))
        weight = 9.81 * part.mass_per_length * part.length
        lying = eq.contacts.force[:, 2]
        assert len(eq.contacts) >= 3 and lying.sum() > 0.2 * weight  # along the floor
        total = (eq.contacts.force.sum(axis=0) + eq.loads["a"].force + eq.loads["b"].force)
        assert total == pytest.approx([0.0, 0.0, weight], abs=1e-9)
        deepest = eq.position[:, 2].min() - 0.01  # the tube's radius above the floor
        assert -1e-6 < deepest <= 0.0


def _cantilever_on_a_drum(delta: float, radius: float,
                          guess: tuple = (0.5, -0.5, 1.0, 0.6)) -> np.ndarray:
    """The independent twin of a weightless cantilever (EI 1, L 1 m, clamped at the
    origin along +x) lifted by a drum (axis along y at x = 0.6 m, its centre ``delta``
    - 0.3 m high) that its centreline touches at distance ``radius`` from the axis:
    the elastica from the clamp to a single frictionless contact, straight beyond it,
    shot with solve_ivp and fsolve (the contact on the circle, the part tangent to it,
    the force along its normal, no moment there). (The clamp's curvature, the drum's
    force on the part (x, z), the contact's s); ``guess``: where fsolve starts."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import fsolve

    centre = np.array([0.6, delta - 0.3])

    def residual(v):
        k0, fx, fz, sc = v

        def rhs(s, y):
            th, dth = y[0], y[1]
            return [dth, -(math.cos(th) * fz - math.sin(th) * fx), math.cos(th), math.sin(th)]

        th, dth, x, z = solve_ivp(rhs, (0.0, sc), [0.0, k0, 0.0, 0.0], rtol=1e-11,
                                  atol=1e-12).y[:, -1]
        d = np.array([x, z]) - centre
        return [dth, float(np.hypot(*d)) - radius, math.cos(th) * d[0] + math.sin(th) * d[1],
                fx * d[1] - fz * d[0]]

    solution, _, ok, _ = fsolve(residual, list(guess), full_output=True, xtol=1e-12)
    assert ok == 1 and np.abs(residual(solution)).max() < 1e-9
    return solution


def _under_a_drum(delta: float) -> pl.Problem:
    """The weightless cantilever of ``_cantilever_on_a_drum`` (EI 1, L 1 m, OD 10 mm,
    clamped at the origin along +x) and its drum (radius 0.3 m, axis along y at
    x = 0.6 m, its top ``delta`` high)."""
    drum = Obstacle.cylinder("drum", 0.3, 0.5, (0.6, 0.0, delta - 0.3), ACROSS_Y)
    return pl.Problem(pl.Part(1.0, 1.0, outer_diameter=0.01),
                      (pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
                                normal=(0.0, 0.0, 1.0)),), obstacles=(drum,))


def _drum_solved(delta: float):
    """``_under_a_drum`` solved cold on 100 elements: (answer, the drum's force (x, z))."""
    eq = rod3d.solve(_under_a_drum(delta), solver=rod3d.RodSolver(elements=100))
    return eq, eq.contacts.force.sum(axis=0)[[0, 2]]


def test_a_cantilever_lifted_by_a_drum_is_solved_cold_at_every_height():
    """Issue 60, item 2: a cantilever (EI 1, L 1 m, OD 10 mm) lifted by a drum of radius
    0.3 m at x = 0.6 m, its top at heights where cold solves used to end in "a fold" (7
    of 10): each is solved cold, stable, with the drum's force the twin's (its centreline
    0.305 m from the axis: the drum's radius and the part's) to 2e-3. With the drum's
    centre 0.1 m above the straight part, the nearer way out is under it: the mirror
    image of the drum 0.2 m below, force for force."""
    for delta in (0.11, 0.15, 0.2, 0.25):
        eq, force = _drum_solved(delta)
        twin = _cantilever_on_a_drum(delta, 0.305)[1:3]
        assert eq.verdict == "stable"
        assert np.linalg.norm(force - twin) < 2e-3 * np.linalg.norm(twin), (delta, force, twin)
    _, under = _drum_solved(0.4)
    above = _cantilever_on_a_drum(0.2, 0.305)[1:3]
    assert np.linalg.norm(under - above * [1.0, -1.0]) < 2e-3 * np.linalg.norm(above)


def test_a_part_through_a_drum_is_pushed_out_the_way_of_least_energy():
    """Issue 60, item 2: the same drum with its axis crossing the unloaded part (its
    centre on the straight part, a symmetric problem) or 50 mm above it: growing it back
    round the part stalled ("a fold"). It is carried in from outside, across the part,
    four ways; the answer is the stable one of least energy, said. Centred: over or under,
    mirror twins of equal energy, the drum's force the twin's (centre on the line) to
    2e-3. Above: under it, the mirror image of the drum 50 mm below, force for force,
    at less energy than over it."""
    eq, force = _drum_solved(0.3)
    pushed = [n for n in eq.notes if isinstance(n, PushedOut)]
    assert eq.verdict == "stable" and len(pushed) == 1 and pushed[0].twin
    assert pushed[0].obstacles == ("drum",) and abs(pushed[0].side[2]) == pytest.approx(1.0)
    twin = _cantilever_on_a_drum(0.3, 0.305)[1:3]
    side = np.sign(pushed[0].side[2])
    assert np.linalg.norm(force - twin * [1.0, side]) < 2e-3 * np.linalg.norm(twin)
    assert np.sign(eq.position[-1, 2]) == side
    eq, force = _drum_solved(0.35)
    pushed = [n for n in eq.notes if isinstance(n, PushedOut)]
    assert eq.verdict == "stable" and len(pushed) == 1 and not pushed[0].twin
    assert pushed[0].side[2] == pytest.approx(-1.0)
    assert all(e > pushed[0].energy for e in pushed[0].other_energies)
    mirror = _cantilever_on_a_drum(0.25, 0.305)[1:3]
    assert np.linalg.norm(force - mirror * [1.0, -1.0]) < 2e-3 * np.linalg.norm(mirror)


def test_a_drum_raised_in_steps_is_followed_with_the_part_on_it():
    """Issue 60, items 2 and 6: the same drum raised from 0.2 to 0.4 m in warm steps of
    50 mm (the continuation used to take an obstacle to its new place at once, so a
    move past the contact's give started inside it: "the start is singular", and
    ``trace`` stopped where ``solve`` fell back to a cold start under the drum). The
    obstacle is carried with the part now: every step is followed, the part stays on
    top, and the drum's force is the twin's followed the same way (to 2e-3)."""
    problem = _under_a_drum
    heights = np.linspace(0.2, 0.4, 5)
    solver = rod3d.RodSolver(elements=100)
    start = rod3d.solve(problem(0.2), solver=solver)
    followed = list(pl.trace([problem(d) for d in heights], start=start, solver=solver))
    guess: tuple = (0.5, -0.5, 1.0, 0.6)
    for delta, eq in zip(heights, followed, strict=True):
        twin = _cantilever_on_a_drum(float(delta), 0.305, guess)
        guess = tuple(twin)
        force = eq.contacts.force.sum(axis=0)[[0, 2]]
        assert force[1] > 0.0 and not jumped(eq.notes)
        assert np.linalg.norm(force - twin[1:3]) < 2e-3 * np.linalg.norm(twin[1:3]), delta
    warm = rod3d.solve(problem(0.25), warm_start=start, solver=solver)
    assert not jumped(warm.notes)  # followed, not solved again from rest
