"""The 3D rod's answers: an ``Equilibrium3D`` built from a solved state (its arrays in SI
units made on first access, its loads, contacts and stability), the state a warm start
reads, and the softest mode in words."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from pliant.core.equilibrium import NO_CONTACTS, Contacts, Equilibrium3D, Samples3D, StationLoad
from pliant.core.rotations import qconj, qmul, quat_matrix, skew
from pliant.errors import IllPosedProblemError
from pliant.models.rod3d import contact_kernels, kernels
from pliant.models.rod3d.kernels import AXIS, FULL
from pliant.models.rod3d.lowering import Rod, State, axis_basis
from pliant.models.rod3d.stability import conservative, metric, stability_of

if TYPE_CHECKING:
    from pliant.models.rod3d.solver import Run



@dataclass(frozen=True, eq=False)
class WarmState:
    rod: Rod
    state: State
    gauge_quat: np.ndarray
    friction: tuple = ()  # the friction reference it was found with (see Run.hold)
    # The softest mode, once the stability test has found it: the next warm step's
    # Lanczos starts from it (a list, filled on first access of the stability).
    mode: list = field(default_factory=list, compare=False)



def build(run: Run, state: State, seed: np.ndarray | None = None) -> Equilibrium3D:
    rod = run.rod
    nu = state[3]
    if rod.gauge_frame >= 0 and abs(nu[-1]) > 1e-6:
        raise IllPosedProblemError(
            "nothing holds the part's twist, yet a twisting moment acts on it; prescribe an "
            "orientation (tangent and normal) somewhere")
    warm = WarmState(rod, state, run.gauge_quat, run.friction)
    done = run.converged
    if done is not None and done[0] is state and done[1] is rod.target:
        residual = done[2]  # what the Newton that found it measured
    else:
        R, _, _ = run.residual(state, rod.target)
        residual = (contact_kernels.contact_max(R, run.contact(rod.target))
                    if rod.iprobe.shape[0] else float(np.abs(R).max()))
    return Equilibrium3D(
        problem=rod.problem, residual=float(residual), iterations=run.iterations,
        steps=run.steps, sampler=Sampler(run, state), notes=tuple(run.notes),
        state=warm,
        stability_check=(lambda: stability_of(run, state, seed, warm.mode))
        if conservative(run, state) else None)



def probe(run: Run, state: State) -> Equilibrium3D:
    """A state reached as an equilibrium to measure (not the answer: no notes, no
    stability)."""
    return Equilibrium3D(problem=run.rod.problem, residual=0.0, iterations=0, steps=0,
                         sampler=Sampler(run, state))



@dataclass(frozen=True, eq=False)
class Sampler:
    """The arrays of an equilibrium, in SI units, made on first access."""

    run: Run
    state: State

    def __call__(self) -> Samples3D:
        rod = self.run.rod
        X, Q, lam = self.state[:3]
        L, fs, ms = rod.length, rod.force_scale, rod.moment_scale
        _, _, energy = self.run.residual(self.state, rod.target)
        frames, moments = kernels.node_outputs(Q, rod.elem_frame, rod.joint_hh,
                                               rod.target.joint_k0, rod.K, rod.node_frame)
        return Samples3D(s=rod.s_node * L, position=X * L, frames=frames,
                         element_s=0.5 * (rod.s_node[1:] + rod.s_node[:-1]) * L,
                         internal_force=lam * fs, internal_moment=moments * ms,
                         energy=energy * rod.stiffness / L,
                         loads=station_loads(self.run, self.state),
                         contacts=_contacts(self.run, self.state))



def _contacts(run: Run, state: State) -> Contacts:
    """The probes that push on the part: where, with what force, from which obstacle."""
    rod = run.rod
    gam = state[4]
    if not gam.shape[0]:
        return NO_CONTACTS
    _, normals, which, _, where, _, _ = run.contacts(state, rod.target)
    normal = gam[::rod.slot]
    # Forces at rounding level (a probe just touching) are not contacts.
    on = np.nonzero(normal > 1e-10 * max(1.0, float(normal.max())))[0]
    e, a = rod.probe_elem[on], where[on]
    points = rod.probe_points(state[0], where)[on] * rod.length
    names = tuple(rod.distance_field.obstacles[o].name for o in which[on])
    friction = np.zeros((on.shape[0], 3))
    if rod.friction:
        t = gam.reshape(-1, 3)[on, 1:]
        friction = np.einsum("ki,kic->kc", t, run.friction[2][on]) * rod.force_scale
    return Contacts(s=(rod.s_node[e] + a * rod.h[e]) * rod.length, point=points,
                    force=normal[on, None] * normals[on] * rod.force_scale + friction,
                    obstacle=names, friction=friction)



def station_loads(run: Run, state: State) -> dict[str, StationLoad]:
    """Each condition's load on the part [N, N m]: its reactions from the multipliers,
    its applied loads from the problem (followers resolved in their deformed frames)."""
    rod = run.rod
    Q, nu = state[1], state[3]
    fs, ms = rod.force_scale, rod.moment_scale
    e3 = np.array([0.0, 0.0, 1.0])
    out: dict[str, StationLoad] = {}
    for k, st in enumerate(rod.stations):
        Rm = quat_matrix(Q[rod.st_frame[k]])
        v = int(rod.nu_off[k])
        reaction_force = np.zeros(3)
        for c in range(3):
            if rod.st_pos_mask[k, c]:
                reaction_force[c] = -nu[v] * fs
                v += 1
        reaction_moment = np.zeros(3)
        if rod.st_kind[k] == AXIS:
            general = np.zeros(3)  # generalised force (material) of the axis constraint
            for bvec in axis_basis(rod.target.st_tangent[k]):
                general -= nu[v] * np.cross(e3, Rm.T @ bvec)
                v += 1
            reaction_moment = Rm @ general * ms
        elif rod.st_kind[k] == FULL:
            r = qmul(qconj(rod.target.st_quat[k]), Q[rod.st_frame[k]])
            grad = 0.5 * (r[0] * np.eye(3) + skew(r[1:]))
            reaction_moment = Rm @ (-(grad.T @ nu[v:v + 3])) * ms
        for cond in st.conditions:
            flags = [st.owner[c] == cond.name for c in range(5)]
            force = np.where(flags[:3], reaction_force, 0.0)
            moment = reaction_moment.copy() if flags[3] else np.zeros(3)
            applied_f = np.array([f or 0.0 for f in cond.force])
            applied_m = np.zeros(3) if cond.moment is None else np.array(cond.moment, float)
            if cond.follower:
                applied_f, applied_m = Rm @ applied_f, Rm @ applied_m
            out[cond.name] = StationLoad(cond.name, cond.s, force + applied_f,
                                         moment + applied_m, tuple(flags))
    return out



def describe_mode(eq: Equilibrium3D) -> str:
    """The softest mode of an equilibrium in words (for a neutral one: what it can do at
    no cost): a turn of the whole part about the line through its held ends, a twist of
    its sections with no change of shape, or a change of shape."""
    eq.stability  # noqa: B018 (the test fills the mode)
    warm = eq.state
    if not isinstance(warm, WarmState) or not warm.mode:
        return "a mode of the discrete rod"
    rod = warm.rod
    primal, _ = metric(rod)
    order = np.flatnonzero(primal)
    vector = np.asarray(warm.mode[0])
    if vector.shape != order.shape:
        return "a mode of the discrete rod"
    at = np.searchsorted(order, rod.ix[:, None] + np.arange(3))
    moved = vector[at]  # node displacements (units of L)
    turned = np.delete(vector, at.ravel())
    if np.linalg.norm(moved) < 1e-3 * np.linalg.norm(turned):
        return "a twist of its sections with no change of shape"
    X = warm.state[0]
    held = [i for i in range(len(X)) if np.linalg.norm(moved[i]) < 1e-6 * np.abs(
        moved).max()]
    if len(held) >= 2:
        a, b = X[held[0]], X[held[-1]]
        chord = (b - a) / max(float(np.linalg.norm(b - a)), 1e-300)
        arm = X - a
        # moved = omega x arm, with omega along the chord: a turn about it
        rotation = np.cross(chord[None, :], arm)
        scale = float(np.sum(rotation * moved) / max(float(np.sum(rotation * rotation)),
                                                     1e-300))
        if np.linalg.norm(moved - scale * rotation) < 1e-2 * np.linalg.norm(moved):
            return "a turn of the whole part about the line through its held ends"
    return "a change of shape"
