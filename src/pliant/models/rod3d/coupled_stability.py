"""The stability of parts solved together (``coupled``): the smallest eigenvalue of the
coupled system's second variation on the variations its conditions allow, as one part's
(``stability``) but over every part at once, the contacts between them, the clips and
the junctions included.

Each part's rows are its energy's gradient in its own units (forces by its EI / L^2,
moments by its EI / L, positions by its L), and the contacts' and links' blocks keep that
scale (Newton's third law in each part's units). So the coupled Jacobian J is the
Hessian of the total energy in the parts' scaled unknowns, each part's rows divided by
its EI / L, and the pencil J v = lambda M v with M = each part's metric (``stability
.metric``) divided by its EI / L has lambda in N m, each part's eigenvalue where the
parts do not touch: positive on every allowed variation means stable. The contacts'
normal forces, the clips' slides and the multipliers carry no metric: they follow the
parts (static condensation), the touching set held (a compliant contact is a stiff
spring while it presses).

Shift-invert Arnoldi (ARPACK's ``eigs``: the scalings keep J similar to a symmetric
matrix, not symmetric) on (J + c M)^-1 M, each step one solve of the condensed system
(``coupled.Condensed``). The shift c is the parts' bound plus an estimate of the
contacts' share (``_contact_shift``), raised where an eigenvalue comes near it, and
checked by a second, loose pass at four times it for one far below it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from pliant.core.equilibrium import NEUTRAL
from pliant.models.rod3d.coupled import Condensed, Coupling
from pliant.models.rod3d.lowering import State
from pliant.models.rod3d.stability import conservative, metric, shift_bound

# The eigenvalue nearest the shift: three took 70 Arnoldi steps a verdict on the clip
# scene's path, one 41, to the same eigenvalue (a lower one near the shift shows itself
# by its size, and raises the shift, below).
_EIGENVALUES = 1
_RAISES = 4  # times the shift may be raised (fourfold each) before giving up


def not_assessed(coupling: Coupling, states: Sequence[State],
                 mus: Sequence[np.ndarray]) -> str | None:
    """Why a static test would not decide the coupled system's stability (friction
    acting, a follower load or an applied moment on a part), or None."""
    for run, state in zip(coupling.runs, states):
        if not conservative(run, state):
            return (f"{run.rod.problem.name}: follower loads, applied moments or friction "
                    "with obstacles acting")
    for p in coupling.rubbing:
        if np.any(mus[coupling.t_slot(p)] != 0.0):
            return "friction between the parts acting"
    if any(sl.clip.friction > 0.0 for sl in coupling.sliders):
        return "a sliding clip with friction"
    return None


def _shift(coupling: Coupling, states: Sequence[State]) -> float:
    """A bound [N m] on the most negative eigenvalue any part's internal forces can
    give (``stability.shift_bound``, in N m), the largest over the parts."""
    return max(shift_bound(run.rod, state) * run.rod.moment_scale
               for run, state in zip(coupling.runs, states))


def _contact_shift(coupling: Coupling, ev, mus: Sequence[np.ndarray], length: float) -> float:
    """An estimate [N m] of how far the contacts between the parts can lower an
    eigenvalue: a contact's force f turns with the line between the centrelines, d
    apart, a stiffness -f / d to their slip across it (two tubes pressed tip to tip slide
    off each other by it, which no part's internal forces bound). A mode of unit norm
    spread along a part of length L_a moves a point by about (length^3 / L_a)^(1/2)
    (the metric's weights); twice that sum over the touching probes. Not a bound for
    a mode held at one node (a point stiffness over a node's small weight, thousands of
    times larger): such a mode costs the part's bending far more, and an eigenvalue
    found near the shift raises it (``coupled_stability``)."""
    out = 0.0
    for p, (pair, geo) in enumerate(zip(coupling.pairs, ev.geo)):
        if geo is None:
            continue
        force = mus[p][ev.near[p]] * coupling.F_ref  # N
        on = force > 0.0
        if not np.any(on):
            continue
        shortest = min(coupling.runs[pair.a].rod.length, coupling.runs[pair.b].rod.length)
        out += float(np.sum(force[on] / geo.d[on])) * length**3 / shortest
    return 2.0 * out


def system_metric(coupling: Coupling, length: float) -> list[np.ndarray]:
    """Each part's diagonal of M (see the module): one metric for every part,
    ``stability.metric``'s of a part of ``length`` (positions by ``length``, each
    unknown weighed by the length it stands for, by ``length``), in each part's scaled
    unknowns and divided by its EI / L (its rows' scale)."""
    out = []
    for run in coupling.runs:
        rod = run.rod
        primal, weight = metric(rod)
        ratio = np.full(rod.n, rod.length / length)  # a rotation's weight: by the length
        ratio[(rod.ix[:, None] + np.arange(3)).ravel()] **= 3  # a position's: by it cubed
        out.append(np.where(primal, weight * ratio, 0.0) / rod.moment_scale)
    return out


def coupled_stability(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray],
                      length: float | None = None, found: list | None = None
                      ) -> tuple[bool | None, float | None]:
    """(stable, smallest eigenvalue [N m]) of the parts together at (states, mus), an
    equilibrium of their targets, in the metric of a part of ``length`` (the first
    part's unless given: that part's own eigenvalue where the others do not touch it);
    (None, None) where the loads are not conservative (``not_assessed``) or no
    eigenvalue converged. ``found``, where given, gets the mode: per part, its primal
    unknowns' values (the unknowns ``system_metric`` weighs)."""
    from scipy.sparse.linalg import (  # noqa: PLC0415 (scipy.sparse: on demand)
        ArpackError,
        ArpackNoConvergence,
        LinearOperator,
        eigs,
    )

    if not_assessed(coupling, states, mus) is not None:
        return None, None
    runs = coupling.runs
    loads = [run.rod.target for run in runs]
    near = [coupling.near(p, states, mu) for p, mu in zip(coupling.pairs, mus)]
    here = coupling.evaluate(states, mus, loads, 1.0, near, False)
    fixed = coupling.touching(here, mus)
    ev = coupling.evaluate(states, mus, loads, 1.0, near, True, fixed)
    blocks = coupling.blocks(ev, mus, 1.0, sliding=True)
    metric_length = runs[0].rod.length if length is None else length
    mass = system_metric(coupling, metric_length)
    primal = [np.flatnonzero(m) for m in mass]
    cuts = np.cumsum([0, *(p.shape[0] for p in primal)])
    n = int(cuts[-1])
    rows = [np.zeros(b.D.shape[0]) for b in blocks]
    start = np.random.default_rng(12345).standard_normal(n)

    def nearest(c: float, tol: float, vectors: bool = False
                ) -> tuple[float, np.ndarray | None] | None:
        """The eigenvalue nearest -c (shift-invert Arnoldi), with its vector where
        ``vectors``; None where the shifted system is singular or Arnoldi does not
        converge."""
        bands = []
        for run, ab, m in zip(runs, ev.ab, mass):
            assert ab is not None
            shifted = ab.copy()
            shifted[:, run.rod.kl + run.rod.ku] += c * m
            bands.append(shifted)
        system = Condensed.of(runs, bands, blocks)
        if system is None:
            return None

        def apply(x: np.ndarray) -> np.ndarray:
            rhs = []
            for i, run in enumerate(runs):
                r = np.zeros(run.rod.n)
                r[primal[i]] = mass[i][primal[i]] * x[cuts[i]:cuts[i + 1]]
                rhs.append(r)
            out = system.solve(rhs, rows)
            if out is None:
                raise FloatingPointError("the shifted coupled system is singular")
            return np.concatenate([d[p] for d, p in zip(out[0], primal)])

        operator = LinearOperator((n, n), matvec=apply, dtype=float)
        try:
            out = eigs(operator, k=min(_EIGENVALUES, n - 2), which="LM", v0=start,
                       tol=tol, maxiter=50 * n, return_eigenvectors=vectors)
        except (ArpackError, ArpackNoConvergence, FloatingPointError):
            return None
        theta, vec = out if vectors else (out, None)
        keep = np.abs(theta) > 0.0
        if not keep.any():
            return None
        k = int(np.argmin(np.where(keep, 1.0 / np.where(keep, theta.real, 1.0) - c, np.inf)))
        return float(1.0 / theta[k].real - c), None if vec is None else vec[:, k].real

    c = _shift(coupling, states) + _contact_shift(coupling, ev, mus, metric_length)
    for _ in range(_RAISES + 1):
        got = nearest(c, 1e-12, found is not None)
        if got is None:
            c *= 1.5  # c itself an eigenvalue (to round-off), or no convergence: move off
            continue
        value, vector = got
        if value <= -0.5 * c:  # near the shift: a lower one may hide below it
            c *= 4.0
            continue
        # The shift is an estimate, not a bound: an eigenvalue far below -c is the one
        # nearest it no more. A shift four times as large shows one down to about -9 c,
        # loosely (it only has to show that one is there: below -c, it lies more than
        # c / 2 below ``value``, far past the loose answer's error).
        check = nearest(4.0 * c, 1e-3)
        if check is not None and check[0] < value - 0.1 * (abs(value) + c):
            c = max(4.0 * c, -2.0 * check[0])
            continue
        if found is not None and vector is not None:
            found.append([vector[cuts[i]:cuts[i + 1]] for i in range(len(runs))])
        scale = min(run.rod.moment_scale for run in runs)
        return value > -NEUTRAL * scale, value
    return None, None
