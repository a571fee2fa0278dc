"""What parts solved together (``coupled``) answer with: each part's contacts with
the others, the clips' and junctions' loads, and the equilibria built from the joint
state."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from pliant.core.equilibrium import Contacts, Equilibrium3D, Samples3D, StationLoad
from pliant.core.events import SolvedTogether
from pliant.core.rotations import quat_matrix
from pliant.models.rod3d import coupled_stability
from pliant.models.rod3d.lowering import State
from pliant.models.rod3d.results import build

if TYPE_CHECKING:
    from pliant.models.rod3d.coupled import Coupling


def part_contacts(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray],
                  names: Sequence[str]) -> list[Contacts]:
    """Each part's contacts with the others: rows as an obstacle's, named by the part
    that pushes (force on this part [N])."""
    rows: list[list] = [[] for _ in coupling.runs]
    for p, (pair, mu) in enumerate(zip(coupling.pairs, mus)):
        on = np.nonzero(mu > 1e-10 * max(1.0, float(mu.max(initial=0.0))))[0]
        if not on.shape[0]:
            continue
        geo = coupling.geometry(pair, states, on)
        ra, rb = coupling.runs[pair.a].rod, coupling.runs[pair.b].rod
        force = mu[on, None] * geo.n * coupling.F_ref
        rub = np.zeros_like(force)
        if pair.friction > 0.0 and p in coupling.fric_ref:
            t = mus[coupling.t_slot(p)].reshape(-1, 2)[on]
            rub = np.einsum("ki,kic->kc", t, coupling.fric_ref[p][-1][on]) * coupling.F_ref
            force = force + rub
        e, al = pair.elem[on], pair.alpha[on]
        s_a = (ra.s_node[e] + al * ra.h[e]) * ra.length
        s_b = (rb.s_node[geo.f] + geo.beta * rb.h[geo.f]) * rb.length
        p_a = (1.0 - al[:, None]) * geo.y[:, 0:3] + al[:, None] * geo.y[:, 3:6]
        p_b = geo.q
        for k in range(on.shape[0]):
            rows[pair.a].append((s_a[k], p_a[k], force[k], names[pair.b], rub[k]))
            rows[pair.b].append((s_b[k], p_b[k], -force[k], names[pair.a], -rub[k]))
    out = []
    for r in rows:
        r.sort(key=lambda row: row[0])
        out.append(Contacts(s=np.array([x[0] for x in r]),
                            point=np.array([x[1] for x in r]).reshape(-1, 3),
                            force=np.array([x[2] for x in r]).reshape(-1, 3),
                            obstacle=tuple(x[3] for x in r),
                            friction=np.array([x[4] for x in r]).reshape(-1, 3)))
    return out


@dataclass(frozen=True, eq=False)
class _WithContacts:
    """A part's sampler with its contacts with the other parts added, and the loads of
    its sliding clips (which the part's own stations do not hold)."""

    inner: Callable[[], Samples3D]
    extra: Contacts
    loads: dict = field(default_factory=dict)
    moments: dict = field(default_factory=dict)  # added to conditions' (pivoting clips)

    def __call__(self) -> Samples3D:
        samples = self.inner()
        if self.loads or self.moments:
            loads = {**samples.loads, **self.loads}
            for name, m in self.moments.items():
                load = loads[name]
                loads[name] = replace(load, moment=np.asarray(load.moment) + m,
                                      prescribed=load.prescribed[:3] + (True, True))
            samples = replace(samples, loads=loads)
        c = samples.contacts
        if not len(self.extra):
            return samples
        merged = Contacts(s=np.concatenate([c.s, self.extra.s]),
                          point=np.concatenate([c.point.reshape(-1, 3), self.extra.point]),
                          force=np.concatenate([c.force.reshape(-1, 3), self.extra.force]),
                          obstacle=tuple(c.obstacle) + tuple(self.extra.obstacle),
                          friction=np.concatenate([np.asarray(c.friction).reshape(-1, 3),
                                                   self.extra.friction]))
        return replace(samples, contacts=merged)


def slider_loads(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray]
                 ) -> list[dict[str, StationLoad]]:
    """Per part, each sliding clip's load on it [N, N m] (the moment about the clip's
    point), at the arc length where the clip now sits (s: the slide's result)."""
    out: list[dict[str, StationLoad]] = [{} for _ in coupling.runs]
    for k, sl in enumerate(coupling.sliders):
        rod = coupling.runs[sl.part].rod
        _, forces, nodes, _ = coupling._slider_terms(k, states, mus, 1.0)
        X = states[sl.part][0]
        on_nodes = -forces.reshape(4, 3) * rod.force_scale  # what the clip applies
        arms = (X[[node for _, node in nodes]] - sl.point) * rod.length
        force = on_nodes.sum(axis=0)
        moment = np.cross(arms, on_nodes).sum(axis=0)
        sigma = float(mus[coupling.slot("slider", k)][0])
        out[sl.part][sl.clip.name] = StationLoad(
            sl.clip.name, sigma * rod.length, force, moment,
            (True, True, True, bool(sl.clip.holds_axis), False))
    return out


def stability_note(why: str | None) -> SolvedTogether:
    """What a part solved together says of its stability: the coupled system's verdict,
    or why a static test would not decide it (``coupled_stability.not_assessed``)."""
    if why is None:
        return SolvedTogether(
            "solved together (parts in contact, joined or in a sliding clip): the verdict "
            "is the coupled system's, every part with its contacts, junctions and clips at "
            "once",
            assessed=True)
    return SolvedTogether(f"solved together: stability is not assessed ({why})",
                          assessed=False)


def equilibria(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray],
               names: Sequence[str]) -> list[Equilibrium3D]:
    """Each part's equilibrium: its own arrays, the coupled system's residual (its
    largest entry over all parts and couplings), its contacts with the other parts
    listed with its obstacles' under the other part's name, and the loads of its sliding
    clips and junctions with its conditions'."""
    near = [coupling.near(p, states, mu) for p, mu in zip(coupling.pairs, mus)]
    loads = [run.rod.target for run in coupling.runs]
    residual = coupling.evaluate(states, mus, loads, 1.0, near, False).residual
    contacts = part_contacts(coupling, states, mus, names)
    held = slider_loads(coupling, states, mus)
    for part, joint in enumerate(joint_loads(coupling, states, mus)):
        held[part].update(joint)
    pins = {}
    rod = coupling.runs[0].rod
    for k, pv in enumerate(coupling.pivots):
        _, torque, _ = coupling._pivot_terms(k, states, mus, 1.0)
        pins[pv.clip.name] = quat_matrix(states[0][1][pv.frame]) @ (-torque) * rod.moment_scale
    why = coupled_stability.not_assessed(coupling, states, mus)
    verdict = functools.cache(lambda: coupled_stability.coupled_stability(coupling, states,
                                                                           mus))
    out = []
    for i, (run, state, extra, mine) in enumerate(zip(coupling.runs, states, contacts, held)):
        eq = build(run, state)
        coupled = len(extra) > 0 or bool(mine) or (i == 0 and bool(pins))
        # One system, one verdict (computed once, when first asked, for every part).
        check = (None if why is not None else verdict) if coupled else eq.stability_check
        out.append(replace(eq, residual=residual,
                           sampler=_WithContacts(eq.sampler, extra, mine,
                                                 pins if i == 0 else {}),
                           notes=eq.notes + ((stability_note(why),) if coupled else ()),
                           stability_check=check))
    return out


def joint_loads(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray]
                ) -> list[dict[str, StationLoad]]:
    """Per part, what each junction applies to it at its end [N, N m] (equal and
    opposite on the two parts it joins), named by the junction."""
    out: list[dict[str, StationLoad]] = [{} for _ in coupling.runs]
    for k, j in enumerate(coupling.joints):
        _, forces, _ = coupling._joint_terms(k, states, mus, 1.0)
        for (part, node), f_x, f_th in (((j.a, j.end_a), forces[0], forces[1]),
                                        ((j.b, j.end_b), forces[2], forces[3])):
            rod = coupling.runs[part].rod
            Rm = quat_matrix(states[part][1][rod.node_frame[node]])
            force = -f_x * rod.force_scale  # the residual gained -f
            moment = Rm @ (-f_th) * rod.moment_scale
            out[part][j.name] = StationLoad(j.name, float(rod.s_node[node] * rod.length),
                                            force, moment, (True,) * 5)
    return out
