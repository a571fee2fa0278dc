"""Leaving an unstable equilibrium of parts solved together (issue 60), as a single part
leaves one (``settling``): the coupled system as ``continuation.settle`` asks
(``Relaxing``: the implicit gradient flow J + sigma M on the condensed system, M the
coupled stability's metric), so that an unstable coupled answer is left along its
unstable mode, both ways, for the stable ones the parts settle in (``downhill``)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from pliant.models import continuation
from pliant.models.rod3d.coupled import DEEP, Coupling
from pliant.models.rod3d.coupled_stability import coupled_stability, system_metric
from pliant.models.rod3d.lowering import Loads, State

Coupled = tuple[list[State], list[np.ndarray]]  # (each part's state, the blocks' unknowns)


class Relaxing:
    """The coupled system as ``continuation.Relaxable``: a step is one flat vector, each
    part's unknowns in turn and then every block's (the contact forces, clips' and
    junctions' multipliers), in the coupled state's order. The touching set between
    the parts is found afresh at every gradient, as the coupled stability finds it."""

    def __init__(self, coupling: Coupling, deadline: float, length: float) -> None:
        self.coupling = coupling
        self.iterations = 0
        self.deadline = deadline
        self.length = length
        self.mass = system_metric(coupling, length)
        self.primal = [np.flatnonzero(m) for m in self.mass]
        self.sizes = [run.rod.n for run in coupling.runs]
        self.at: Coupled | None = None  # where the last gradient was taken

    @property
    def tolerance(self) -> float:
        return self.coupling.solver.tolerance

    def _split(self, flat: np.ndarray, mus: Sequence[np.ndarray]
               ) -> tuple[list[np.ndarray], list[np.ndarray]]:
        cuts = np.cumsum([0, *self.sizes, *(m.shape[0] for m in mus)])
        parts = [flat[cuts[i]:cuts[i + 1]] for i in range(len(self.sizes))]
        first = len(self.sizes)
        return parts, [flat[cuts[first + j]:cuts[first + j + 1]] for j in range(len(mus))]

    def gradient(self, state: Coupled, loads: tuple[list[Loads], float]):
        c = self.coupling
        states, mus = state
        targets, weight = loads
        near = [c.near(p, states, mu) for p, mu in zip(c.pairs, mus)]
        here = c.evaluate(states, mus, targets, weight, near, False)
        fixed = c.touching(here, mus)
        self.at = state
        ev = c.evaluate(states, mus, targets, weight, near, True, fixed)
        blocks = c.blocks(ev, mus, weight)
        R = np.concatenate([*ev.R, *(ev.Rmu[b.target[0]][b.target[1]] for b in blocks)])
        return R, (ev, blocks, mus)

    def diagonal_scale(self, jac) -> float:
        ev = jac[0]
        out = 0.0
        for run, ab, m, p in zip(self.coupling.runs, ev.ab, self.mass, self.primal):
            diag = np.abs(ab[p, run.rod.kl + run.rod.ku]) / m[p]
            out = max(out, float(diag.max(initial=0.0)))
        return out

    def shifted_solve(self, jac, sigma: float, rhs: np.ndarray) -> tuple[np.ndarray, bool]:
        ev, blocks, mus = jac
        bands = []
        for run, ab, m in zip(self.coupling.runs, ev.ab, self.mass):
            shifted = ab.copy()
            shifted[:, run.rod.kl + run.rod.ku] += sigma * m
            bands.append(shifted)
        cuts = np.cumsum([0, *self.sizes])
        rows, at = [], int(cuts[-1])
        for b in blocks:
            rows.append(rhs[at:at + b.D.shape[0]])
            at += b.D.shape[0]
        out = self.coupling.solved(bands, blocks, [rhs[cuts[i]:cuts[i + 1]]
                                                   for i in range(len(self.sizes))], rows, mus)
        if out is None:
            return np.zeros(sum(self.sizes) + sum(m.shape[0] for m in mus)), False
        return np.concatenate([*out[0], *out[1]]), True

    def primal_move(self, du: np.ndarray) -> float:
        """The step's largest move; infinite where it would take two tubes half through
        each other (``coupled.DEEP``), which the relaxation then shortens as a step too
        long: past the other's centreline a probe's gap is positive again, and the
        parts would pass through each other."""
        cuts = np.cumsum([0, *self.sizes])
        move = max(float(np.abs(du[cuts[i]:cuts[i + 1]][p]).max(initial=0.0))
                   for i, p in enumerate(self.primal))
        if self.at is not None:
            trial = self.step(self.at, du, 1.0)
            if self._deep(trial):
                return math.inf
        return move

    def _deep(self, state: Coupled) -> bool:
        c = self.coupling
        states, mus = state
        for pair, mu in zip(c.pairs, mus):
            only = c.near(pair, states, mu)
            if only.shape[0] and np.any(c.geometry(pair, states, only).d < DEEP * pair.reach):
                return True
        return False

    def unstable_mode(self, state: Coupled, loads) -> np.ndarray | None:
        states, mus = state
        found: list = []
        stable, _ = coupled_stability(self.coupling, states, mus, length=self.length,
                                      found=found)
        if stable is not False or not found:
            return None
        du = [np.zeros(n) for n in self.sizes]
        for d, p, v in zip(du, self.primal, found[0]):
            d[p] = v
        return np.concatenate([*du, *(np.zeros_like(mu) for mu in mus)])

    def step(self, state: Coupled, du: np.ndarray, scale: float) -> Coupled:
        dus, dmus = self._split(du, state[1])
        return self.coupling.step(state, (dus, dmus), scale)

    def correct(self, predictor: Coupled, loads, *, strict: bool, tol: float | None):
        return self.coupling.correct(predictor, loads, strict=strict, tol=tol)


def downhill(coupling: Coupling, states: list[State], mus: list[np.ndarray],
             deadline: float, length: float) -> list[Coupled]:
    """The stable (or neutral) equilibria of the parts together that an unstable one,
    (states, mus) at their targets, leads to: left along its unstable mode one way then
    the other (pushed as ``continuation.settle`` pushes off a saddle), relaxed, each way
    that settles once."""
    model = Relaxing(coupling, deadline, length)
    loads = ([run.rod.target for run in coupling.runs], 1.0)
    mode = model.unstable_mode((states, mus), loads)
    if mode is None:
        return []
    # Steps and pushes of a quarter and one of the contacts' reach at most (two tubes'
    # radii, in L): the single part's (a fiftieth and a twentieth of L) can carry two
    # pressed tips past each other in a step, and the flow then wanders between
    # touching sets back to the saddle (docs/models.md).
    reach = min((pair.reach for pair in coupling.pairs), default=np.inf) / length
    stride, push = min(0.02, 0.25 * reach), min(continuation.PUSH, reach)
    du = mode * (push / max(float(np.abs(mode).max()), 1e-300))
    found = []
    for sign in (1.0, -1.0):
        settled = continuation.settle(model, model.step((states, mus), sign * du, 1.0), loads,
                                      push, stride)
        if settled is not None:
            found.append(settled)
    coupling.iterations += model.iterations
    return found
