"""Stable 2D equilibria found by minimising the energy of a discretised part.

The shooting routes follow a path from the unloaded part to the targets; where every
path meets a fold (the part would snap through on the way) they stop, although the
problem itself has a stable equilibrium: a stable equilibrium is a local minimum of the
potential energy on the configurations the conditions allow, and a part held by its
positions and angles always has one within reach. This route looks for those minima
directly, from a few starting shapes (an even turn between the held angles, and that
bowed to either side), on a part cut into elements of constant angle (the discrete
elastica):

    E = sum EI / 2h (theta_k - theta_(k-1) - h kappa0_k)^2 - sum f_k . x_k - sum m_k theta_k

with x_k = x_0 + h sum_(j<k) (cos theta_j, sin theta_j), the weight and dead forces f_k
lumped at the nodes, a held end angle bending a half element (second order in h), and
the held positions and interior angles as equality constraints. The minimiser is an SQP
with the exact Hessian of the Lagrangian (``_sqp``), scipy's SLSQP where it fails. The
reactions are the constraints' Lagrange multipliers (least squares on the stationarity
condition). Each minimum is only a start: the shooting Newton then converges to the
part's own equilibrium with its own accuracy (``solver.Run.minima``).

Only conservative, inextensible problems with at least one prescribed position: a
follower load has no potential, and an extensible part's start would miss its stretch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from pliant.core.equilibrium import PlanarLoad
from pliant.core.problem import Problem
from pliant.models import clock
from pliant.models.elastica2d.bordered import kkt_negatives, kkt_solve, tridiagonal_times
from pliant.models.elastica2d.kernels import max_abs

ELEMENTS = 48  # elements of the discrete part: a start for Newton, not an answer
BOWS = (0.0, 1.5, -1.5)  # starting bows [rad]: straight, and to either side
REFINED_TOLERANCE = 1e-7  # the refined grid's stationarity (relative): see ``refined``
# Where an SQP stops (``_sqp_kernel``).
FAILED, CONVERGED, KNOWN = 0, 1, 2
# rad: an SQP iterate this close to an equilibrium found already, settling, is that
# one's (half the ``solver.MATCHED`` by which a minimum is recognised as the route's)
NEAR = 0.05
MAX_TURN = 1.0  # rad: the largest change of an element's angle in one SQP step (a
# longer step from a poor start leaps into a tangled shape of far higher energy)


def applicable(problem: Problem) -> bool:
    """Whether the problem is one this route can minimise (see the module)."""
    conds = problem.model_conditions
    if problem.part.axial_stiffness is not None or any(c.follower for c in conds) or any(
            ld.follower for ld in problem.distributed):
        return False
    return any(all(v is not None for v in c.position) and len(c.position) == 2
               for c in conds)


class Arrays(NamedTuple):
    """The discrete part for the compiled kernels (units of L and EI / L): rest
    curvature, dead forces and couples at the nodes, the dead forces' sums from each node
    on, held positions (node, component, value), held interior angles (node, value) and
    held end angles (node, value)."""

    h: float
    kappa0: np.ndarray
    f: np.ndarray
    tail: np.ndarray
    m: np.ndarray
    pos_k: np.ndarray
    pos_i: np.ndarray
    pos_v: np.ndarray
    ang_k: np.ndarray
    ang_v: np.ndarray
    end_k: np.ndarray
    end_v: np.ndarray


class Discrete:
    """The discrete part in units of L (lengths), EI / L (energies)."""

    def __init__(self, problem: Problem, elements: int) -> None:
        part = problem.part
        L, EI = part.length, part.bending_stiffness
        self.problem, self.n, self.h = problem, elements, 1.0 / elements
        n, h = elements, self.h
        s = np.linspace(0.0, 1.0, n + 1)
        self.s = s
        kappa0 = part.rest_curvature_along(s * L) * L
        qx, qy = problem.dead_load_per_length
        f = np.zeros((n + 1, 2))  # dead forces at the nodes
        if qx or qy:
            f[:] = (h * (qx * L**3 / EI), h * (qy * L**3 / EI))
            f[[0, -1]] *= 0.5
        for ld in problem.partial_loads:  # a dead load on a stretch: each node's cell
            lo = np.maximum(s - 0.5 * h, 0.0) * L
            hi = np.minimum(s + 0.5 * h, 1.0) * L
            cover = np.array([ld.overlap(a, b, L) for a, b in zip(lo, hi)]) / L
            f += cover[:, None] * np.asarray(ld.force)[None, :] * L**3 / EI
        m = np.zeros(n + 1)  # dead couples at the nodes
        self.position: list[tuple[int, int, float]] = []  # (node, component, value)
        self.angle: list[tuple[int, float]] = []  # interior: constraints
        self.ends: list[tuple[int, float]] = []  # at an end: a half element's bending
        self.node_of: dict[int, int] = {}
        for index, c in enumerate(problem.model_conditions):
            k = int(round(c.s / L * n))
            self.node_of[index] = k
            for i in range(2):
                v = c.position[i] if c.position else None
                if v is not None:
                    self.position.append((k, i, float(v) / L))
                elif c.force and c.force[i] is not None:
                    f[k, i] += float(c.force[i] or 0.0) * L**2 / EI
            if c.angle is not None and k in (0, n):
                self.ends.append((k, float(c.angle)))
            elif c.angle is not None:
                self.angle.append((k, float(c.angle)))
            elif c.moment is not None:
                m[k] += float(c.moment) * L / EI  # type: ignore[arg-type]  # 2D: a number
        ints = np.int64

        def column(rows: list, j: int, kind: type) -> np.ndarray:
            return np.array([row[j] for row in rows], kind)

        self.arrays = Arrays(
            h, kappa0, f, np.cumsum(f[::-1], axis=0)[::-1].copy(), m,
            column(self.position, 0, ints), column(self.position, 1, ints),
            column(self.position, 2, float), column(self.angle, 0, ints),
            column(self.angle, 1, float), column(self.ends, 0, ints),
            column(self.ends, 1, float))

    def nodes(self, u: np.ndarray) -> np.ndarray:
        return _nodes(u, self.h)

    def energy(self, u: np.ndarray) -> tuple[float, np.ndarray]:
        return _energy(u, self.arrays)

    def end_terms(self, theta: np.ndarray) -> list[tuple[int, float, float]]:
        """Each end whose angle is held: (node, angle, the curvature's excess M / EI)."""
        excess = _end_excess(np.ascontiguousarray(theta), self.arrays)
        return [(k, v, float(e)) for (k, v), e in zip(self.ends, excess)]

    def hessian(self, u: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """The Hessian of the Lagrangian E - lam . c in u."""
        return _hessian(u, lam, self.arrays)

    def constraints(self, u: np.ndarray) -> np.ndarray:
        return _constraints(u, self.arrays)

    def jacobian(self, u: np.ndarray) -> np.ndarray:
        return _jacobian(u, self.arrays)

    # -- starts --------------------------------------------------------------------------
    def start(self, bow: float) -> np.ndarray:
        """A start: the part from its first end along its first prescribed angle (or
        toward its last prescribed position), turning at a constant rate to its last
        prescribed angle, bowed by ``bow`` rad (sin(pi s) profile)."""
        theta, sine, anchor, base = self._unbowed
        u = np.concatenate([[0.0, 0.0], theta + bow * sine])
        u[:2] = base - self.nodes(u)[anchor]
        return u

    def straight(self) -> bool:
        """Whether the unbowed start is straight (a chord that must shorten cannot to
        first order: no start)."""
        return bool(np.ptp(self._unbowed[0]) < 1e-9)

    @cached_property
    def _unbowed(self) -> tuple[np.ndarray, np.ndarray, int, np.ndarray]:
        """The starts' common part: (the unbowed angles, the bow's profile, the node
        whose position they are placed by, that position)."""
        s_el = (np.arange(self.n) + 0.5) * self.h
        first = next((v for k, v in self.ends if k == 0), None)
        last = next((v for k, v in self.ends if k == self.n), None)
        anchor = min(self.position, key=lambda p: p[0])[0]
        xs = {(k, i): v for k, i, v in self.position}
        base = np.array([xs.get((anchor, 0), 0.0), xs.get((anchor, 1), 0.0)])
        far = max(self.position, key=lambda p: p[0])[0]
        if first is None:
            if far != anchor:
                chord = np.array([xs.get((far, 0), base[0]), xs.get((far, 1), base[1])]) - base
                first = math.atan2(chord[1], chord[0]) if np.any(chord) else 0.0
            else:
                first = last if last is not None else 0.0
        turn = 0.0 if last is None else last - first
        return first + turn * s_el, np.sin(math.pi * s_el), anchor, base


def minima(problem: Problem, *, elements: int = ELEMENTS, deadline: float | None = None,
           bows: tuple[float, ...] = BOWS, known: Sequence[Any] = ()) -> list[Minimum]:
    """Local minima of the discrete part's energy under the problem's conditions, one per
    start that converged, lowest first, as the arrays a 2D warm start reads (s, position,
    angle, internal_force, bending_moment, loads by name).

    known : equilibria found already (each with s [m] and angle arrays): a start whose
        SQP comes within ``NEAR`` of one, settling (``_sqp_kernel``), is that one's and is
        left out, its last iterations not spent."""
    disc = Discrete(problem, elements)
    middles = (np.arange(elements) + 0.5) * (problem.part.length / elements)
    known_angles = np.array([np.interp(middles, eq.s, eq.angle) for eq in known]).reshape(
        len(known), elements)
    found: list[Minimum] = []
    for bow in bows:
        if deadline is not None and clock.now() > deadline:
            break
        if bow == 0.0 and disc.straight():
            continue  # straight: a chord that must shorten cannot to first order
        with np.errstate(over="ignore", invalid="ignore"):  # a trial step too far: refused
            u = _minimise(disc, disc.start(bow), known_angles)
        # (a minimum found again is not made into arrays again: case 3's two starts
        # find one)
        if u is not None and not any(
                np.abs(u[2:] - other.u[2:]).max() < 1e-4 for other in found):
            found.append(Minimum(disc, u))
    found.sort(key=lambda state: state.energy)
    return found


def refined(state: Minimum, factor: int = 4) -> Minimum | None:
    """The minimum again on a grid ``factor`` times finer, from the coarse one: where
    the part bends sharply (a taut part's U-turn) a coarse start is too far from the
    part's own equilibrium for Newton. Converged to ``REFINED_TOLERANCE`` only: it is a
    start for that Newton, and a fine grid's minimum is often nearly neutral (a flat
    valley along which the SQP creeps). By the SQP alone: SLSQP's dense steps on the
    fine grid took half a second a start, and on 1,000 random inverse targets its starts
    never changed an answer."""
    coarse = state.disc
    disc = Discrete(coarse.problem, factor * coarse.n)
    theta = np.repeat(state.u[2:], factor)
    u = np.concatenate([state.u[:2], theta])
    with np.errstate(over="ignore", invalid="ignore"):
        found, status = _sqp(disc, u, tolerance=REFINED_TOLERANCE)
        return Minimum(disc, found) if status == CONVERGED else None


def _minimise(disc: Discrete, u0: np.ndarray, known: np.ndarray) -> np.ndarray | None:
    """The minimum's unknowns from u0: the exact-Hessian SQP (``_sqp_kernel``, a few
    milliseconds), or where it fails, scipy's SLSQP (quasi-Newton, slower, but it gets
    through the tangled shapes a bad start leads the SQP into); None where neither
    converges, or the SQP settles next to an equilibrium ``known`` (element angles)."""
    found, status = _sqp(disc, u0, known=known)
    if status == CONVERGED:
        return found
    if status == KNOWN:
        return None
    from scipy.optimize import minimize  # noqa: PLC0415 (scipy.optimize: on demand)

    result = minimize(disc.energy, u0, jac=True, method="SLSQP",
                      constraints=[{"type": "eq", "fun": disc.constraints,
                                    "jac": disc.jacobian}],
                      options={"maxiter": 400, "ftol": 1e-12})
    if not result.success or np.abs(disc.constraints(result.x)).max() > 1e-8:
        return None
    return result.x


def _sqp(disc: Discrete, u: np.ndarray, iterations: int = 60, tolerance: float = 1e-10,
         known: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """The compiled SQP (``_sqp_kernel``) from u: (its last iterate, how it stopped:
    CONVERGED, KNOWN next to a row of ``known``, or FAILED)."""
    if known is None:
        known = np.zeros((0, disc.n))
    return _sqp_kernel(np.ascontiguousarray(u, float), disc.arrays, iterations,
                       tolerance, MAX_TURN, known, NEAR)


# -- compiled kernels (the discrete elastica and its SQP) --------------------------------
# The kernels below write their array arithmetic as loops: numba compiles each array
# expression as a function of its own, and an array assigned to a slice links a shape
# check whose message pulls in its unicode code, which every caller optimises again (the
# SQP's kernels took 20 of the 2D model's 33 s of compiling; see docs/first-run.md). The
# loops do the same operations in the same order as the expressions they replace (the
# minima came out bit for bit the same on the paper's cases and 25 held tips).
# ``tangent_shift`` and the two searches it runs are inlined into their one caller: as
# kernels of their own, each was compiled, then compiled again inside its caller.


@njit(cache=True)
def _dot(a, b):
    """sum(a * b), summed in order (as numpy's sum in a kernel)."""
    acc = 0.0
    for j in range(a.shape[0]):
        acc += a[j] * b[j]
    return acc


@njit(cache=True)
def _abs_sum(a):
    acc = 0.0
    for j in range(a.shape[0]):
        acc += abs(a[j])
    return acc


@njit(cache=True)
def _nonzero(a):
    """Whether any entry is not zero (numpy's any)."""
    for j in range(a.shape[0]):
        if a[j] != 0.0:
            return True
    return False


@njit(cache=True)
def _axpy(x, alpha, y):
    """x + alpha y, a new array."""
    out = np.empty(x.shape[0])
    for j in range(x.shape[0]):
        out[j] = x[j] + alpha * y[j]
    return out


@njit(cache=True)
def _divided(x, d):
    """x / d, a new array."""
    out = np.empty(x.shape[0])
    for j in range(x.shape[0]):
        out[j] = x[j] / d
    return out


@njit(cache=True)
def _negated(x):
    out = np.empty(x.shape[0])
    for j in range(x.shape[0]):
        out[j] = -x[j]
    return out


@njit(cache=True)
def _shifted(diag, shift):
    """diag + shift, a new array."""
    out = np.empty(diag.shape[0])
    for j in range(diag.shape[0]):
        out[j] = diag[j] + shift
    return out


@njit(cache=True)
def _trig(u):
    """The cosine and sine of each element's angle: the SQP's kernels at one point all
    read them (each worked them out again: nine times an iteration, a third of its
    time)."""
    n = u.shape[0] - 2
    c = np.empty(n)
    s = np.empty(n)
    for j in range(n):
        c[j] = math.cos(u[2 + j])
        s[j] = math.sin(u[2 + j])
    return c, s


@njit(cache=True)
def _nodes(u, h):
    c, s = _trig(u)
    return _nodes_at(u, h, c, s)


@njit(cache=True)
def _nodes_at(u, h, c, s):
    """``_nodes`` from the angles' cosines and sines (``_trig``)."""
    n = u.shape[0] - 2
    x = np.empty((n + 1, 2))
    x[0, 0], x[0, 1] = u[0], u[1]
    for j in range(n):
        x[j + 1, 0] = x[j, 0] + h * c[j]
        x[j + 1, 1] = x[j, 1] + h * s[j]
    return x


@njit(cache=True)
def _end_excess(theta, a):
    """M / EI at each held end: the half element between the end and the middle of its
    element bends from the held angle (second order; an element angle set to it is
    first)."""
    n = theta.shape[0]
    out = np.empty(a.end_k.shape[0])
    for r in range(a.end_k.shape[0]):
        if a.end_k[r] == 0:
            out[r] = (theta[0] - a.end_v[r]) / (0.5 * a.h) - a.kappa0[0]
        else:
            out[r] = (a.end_v[r] - theta[n - 1]) / (0.5 * a.h) - a.kappa0[n]
    return out


@njit(cache=True)
def _energy(u, a):
    """E and its gradient (see the module)."""
    c, s = _trig(u)
    return _energy_at(u, a, c, s)


@njit(cache=True)
def _energy_at(u, a, c, s):
    """``_energy`` from the angles' cosines and sines (``_trig``)."""
    n, h = u.shape[0] - 2, a.h
    theta = u[2:]
    x = _nodes_at(u, h, c, s)
    g = np.zeros_like(u)
    e = 0.0
    for k in range(n + 1):
        e -= a.f[k, 0] * x[k, 0] + a.f[k, 1] * x[k, 1]
    g[0], g[1] = -a.tail[0, 0], -a.tail[0, 1]
    for j in range(n):
        g[2 + j] = h * (s[j] * a.tail[j + 1, 0] - c[j] * a.tail[j + 1, 1])
    for k in range(1, n):
        d = (theta[k] - theta[k - 1]) / h - a.kappa0[k]
        e += 0.5 * h * d * d
        g[2 + k] += d
        g[2 + k - 1] -= d
    excess = _end_excess(theta, a)
    for r in range(excess.shape[0]):
        e += 0.25 * h * excess[r] * excess[r]
        if a.end_k[r] == 0:
            g[2] += excess[r]
        else:
            g[2 + n - 1] -= excess[r]
    for k in range(n + 1):
        if a.m[k] != 0.0:
            lo, hi = max(k - 1, 0), min(k, n - 1)
            w = 1.0 if lo == hi else 0.5
            for j in range(lo, hi + 1):
                e -= w * a.m[k] * theta[j]
                g[2 + j] -= w * a.m[k]
    return e, g


@njit(cache=True)
def _constraints(u, a):
    c, s = _trig(u)
    return _constraints_at(u, a, c, s)


@njit(cache=True)
def _constraints_at(u, a, c, s):
    """``_constraints`` from the angles' cosines and sines (``_trig``)."""
    x = _nodes_at(u, a.h, c, s)
    n = u.shape[0] - 2
    P, A = a.pos_k.shape[0], a.ang_k.shape[0]
    out = np.empty(P + A)
    for r in range(P):
        out[r] = x[a.pos_k[r], a.pos_i[r]] - a.pos_v[r]
    for r in range(A):
        k = a.ang_k[r]  # interior: the mean of its two elements
        out[P + r] = 0.5 * (u[2 + k - 1] + u[2 + min(k, n - 1)]) - a.ang_v[r]
    return out


@njit(cache=True)
def _jacobian(u, a):
    c, s = _trig(u)
    return _jacobian_at(u, a, c, s)


@njit(cache=True)
def _jacobian_at(u, a, c, s):
    """``_jacobian`` from the angles' cosines and sines (``_trig``)."""
    n, h = u.shape[0] - 2, a.h
    P, A = a.pos_k.shape[0], a.ang_k.shape[0]
    rows = np.zeros((P + A, u.shape[0]))
    for r in range(P):
        i = a.pos_i[r]
        rows[r, i] = 1.0
        for j in range(a.pos_k[r]):
            rows[r, 2 + j] = -h * s[j] if i == 0 else h * c[j]
    for r in range(A):
        k = a.ang_k[r]
        rows[P + r, 2 + k - 1] += 0.5
        rows[P + r, 2 + min(k, n - 1)] += 0.5
    return rows


@njit(cache=True)
def _tridiagonal(u, lam, a):
    c, s = _trig(u)
    return _tridiagonal_at(u, lam, a, c, s)


@njit(cache=True)
def _tridiagonal_at(u, lam, a, c, s):
    """The Hessian of the Lagrangian E - lam . c, which is zero in the translations and
    tridiagonal in the angles: (diagonal, off-diagonal) of the angles' block. Bending
    couples neighbours; the loads' and the constraints' second derivatives lie on the
    diagonal (d2 x_k / d theta_j^2 = -h (cos, sin) theta_j for j < k)."""
    n, h = u.shape[0] - 2, a.h
    diag = np.zeros(n)
    off = np.zeros(max(n - 1, 0))
    for k in range(1, n):
        diag[k] += 1.0 / h
        diag[k - 1] += 1.0 / h
        off[k - 1] -= 1.0 / h
    for r in range(a.end_k.shape[0]):
        diag[0 if a.end_k[r] == 0 else n - 1] += 2.0 / h
    pull = a.tail[1:].copy()
    for r in range(a.pos_k.shape[0]):
        for j in range(a.pos_k[r]):
            pull[j, a.pos_i[r]] += lam[r]
    for j in range(n):
        diag[j] += h * (c[j] * pull[j, 0] + s[j] * pull[j, 1])
    return diag, off


@njit(cache=True)
def _hessian(u, lam, a):
    """``_tridiagonal`` as a dense matrix over all the unknowns (for the tests)."""
    diag, off = _tridiagonal(u, lam, a)
    n = diag.shape[0]
    hess = np.zeros((n + 2, n + 2))
    for j in range(n):
        hess[2 + j, 2 + j] = diag[j]
    for j in range(n - 1):
        hess[2 + j, 3 + j] = off[j]
        hess[3 + j, 2 + j] = off[j]
    return hess


@njit(cache=True)
def _tangent_positive(diag, off, jac, shift):
    """Whether H + shift I is positive definite on the null space of J (of full rank):
    exactly when the KKT matrix has m negative eigenvalues and none zero (Gould;
    ``bordered.kkt_negatives``)."""
    return kkt_negatives(_shifted(diag, shift), off, jac, shift) == jac.shape[0]


@njit(cache=True, inline="always")
def tangent_shift(diag, off, jac, guess, mode):
    """The least shift (plus 1e-6) that makes the Hessian positive definite on the null
    space of the constraints' Jacobian, 0 where it already is. The least that works: a
    larger shift, as interior-point codes raise it tenfold, was seen to steer the steps
    toward a saddle's basin.

    First by Rayleigh quotient iteration from ``mode`` (the last SQP iteration's softest
    mode, which moves slowly; an empty array where there is none), checked by one
    inertia count (``_rayleigh_shift``); else bracketed by ``_tangent_positive`` in
    growing steps from ``guess`` (the last iteration's shift), bisected to 1 % and
    refined (``_refined_shift``). ``mode`` receives the softest mode found."""
    if _tangent_positive(diag, off, jac, 0.0):
        return 0.0
    if mode.shape[0] == diag.shape[0] + 2:
        # No mode yet (the first iteration that needs a shift): the angles' two
        # half-waves, then one (bisecting took 66 us; from these the iteration proved the
        # least shift at 247 and 25 more of 277 such first iterations, 12 us each).
        waves = 0 if _nonzero(mode) else 2
        while True:
            if waves:
                _half_waves(mode, waves)
            least = _rayleigh_shift(diag, off, jac, mode)
            if least > 0.0:
                return least + 1e-6
            if waves != 2:
                break
            waves = 1
    bound = 1e-6  # Gershgorin's: past it the whole Hessian is positive definite
    for j in range(diag.shape[0]):
        bound = max(bound, -diag[j] + (abs(off[j]) if j < off.shape[0] else 0.0)
                    + (abs(off[j - 1]) if j > 0 else 0.0))
    bound *= 1.01
    x = min(guess, bound) if guess > 0.0 else bound
    factor = 1.01
    if _tangent_positive(diag, off, jac, x):
        hi = x
        while True:  # down until it fails
            lo = hi / factor
            if lo < 1e-12 or not _tangent_positive(diag, off, jac, lo):
                break
            hi, factor = lo, factor * factor
    else:
        lo = x
        while True:  # up until it holds
            hi = min(lo * factor, bound)
            if hi >= bound or _tangent_positive(diag, off, jac, hi):
                break
            lo, factor = hi, factor * factor
    while hi > 1.01 * lo and lo > 1e-12:
        mid = math.sqrt(lo * hi)
        if _tangent_positive(diag, off, jac, mid):
            hi = mid
        else:
            lo = mid
    return _refined_shift(diag, off, jac, lo, hi, mode) + 1e-6


@njit(cache=True, inline="always")
def _rayleigh_shift(diag, off, jac, mode):
    """The least shift from the softest mode's estimate ``mode`` (updated in place), by
    Rayleigh quotient iteration on the constraints' null space (each step a KKT solve at
    minus the last quotient: cubic convergence, three or four solves where the
    bisection took a dozen inertia counts); 0 where it is not proven least. Proof: the
    quotient q of a vector of the null space bounds the least eigenvalue there from
    above (Courant), and an inertia count at -q + 1e-6 that finds H + (1e-6 - q) I
    positive there bounds it from below, 1e-6 under q."""
    size = math.sqrt(_dot(mode, mode))
    if not size > 0.0 or not math.isfinite(size):
        return 0.0
    v = _divided(mode, size)
    m = jac.shape[0]
    zero = np.zeros(m)
    scale = max_abs(diag) + (max_abs(off) if off.shape[0] else 0.0)
    quotient = _dot(v[2:], tridiagonal_times(diag, off, v[2:]))
    size_j = 0.0
    for r in range(m):
        size_j = max(size_j, max_abs(jac[r]))
    solved = False  # v in the null space: after one solve
    for _ in range(8):
        # (H - q I) w + J^T y = v, J w = 0: one pass of the condensed solve, without
        # ``kkt_step``'s refinement (these systems are singular by design, and only the
        # solution's direction counts)
        w, _, ok = kkt_solve(_shifted(diag, -quotient), off, jac, -quotient, 0.0, v,
                                   zero)
        size = math.sqrt(_dot(w, w))
        if not ok or not size > 0.0 or not math.isfinite(size):
            break  # singular at the quotient: it is an eigenvalue to round-off
        off_null = 0.0  # |J w|
        for r in range(m):
            off_null = max(off_null, abs(_dot(jac[r], w)))
        if off_null > 1e-10 * size * size_j:
            break  # off the null space beyond round-off: an ill-conditioned solve
        v = _divided(w, size)
        solved = True
        last = quotient
        quotient = _dot(v[2:], tridiagonal_times(diag, off, v[2:]))
        # (H - q) v = v_old / |w| on the null space: the new quotient is exact to
        # round-off once |w| is 1e9 times the Hessian's scale's inverse.
        if size * scale >= 1e9 or abs(quotient - last) <= 1e-14 * scale:
            break
    if not solved:
        return 0.0
    _copy_into(mode, v)
    if quotient < 0.0 and _tangent_positive(diag, off, jac, 1e-6 - quotient):
        return -quotient
    return 0.0


@njit(cache=True)
def _half_waves(out, waves):
    """out = sin(waves pi s) on the angles at the elements' middles, 0 on the
    translations: a smooth start for the softest mode."""
    n = out.shape[0] - 2
    out[0], out[1] = 0.0, 0.0
    for j in range(n):
        out[2 + j] = math.sin(waves * math.pi * (j + 0.5) / n)


@njit(cache=True, inline="always")
def _copy_into(out, v):
    """out[:] = v, in a loop (see ``bordered.tridiagonal_times``: no shape check's
    unicode code linked in)."""
    for j in range(v.shape[0]):
        out[j] = v[j]


@njit(cache=True, inline="always")
def _refined_shift(diag, off, jac, lo, hi, mode):
    """The least shift in [lo, hi] (1 % apart) to round-off: minus the Rayleigh quotient
    of the reduced Hessian's softest mode, found by inverse iteration at the shift hi
    (where the softest mode dominates by the 1 % gap). The basin the steps descend into
    depends on it: 1 % more led a heavy cable's starts to another, higher minimum than
    the exact shift's. hi where the quotient falls outside [lo, hi]. ``mode`` (of the
    unknowns' size, else left alone) receives the mode."""
    n = diag.shape[0]
    v = np.ones(n + 2)
    zero = np.zeros(jac.shape[0])
    least = hi
    for _ in range(30):
        w, _ = kkt_step(diag, off, jac, _negated(v), zero, hi)  # (H + hi I) w + J^T y = v
        size = math.sqrt(_dot(w, w))  # (and J w = 0)
        if not size > 0.0 or not math.isfinite(size):
            return hi
        v = _divided(w, size)
        # v . H v (H zero on the translations)
        quotient = _dot(v[2:], tridiagonal_times(diag, off, v[2:]))
        change = abs(-quotient - least)
        least = -quotient
        if change <= 1e-14 * abs(least):
            break
    if mode.shape[0] == n + 2:
        _copy_into(mode, v)
    # The quotient is the softest mode's eigenvalue from above: the shift from below.
    # Positive definite 1e-6 past it, or the bracket's top.
    if lo <= least <= hi and _tangent_positive(diag, off, jac, least + 1e-6):
        return least
    return hi


@njit(cache=True)
def kkt_step(diag, off, jac, g, c, shift):
    """The SQP step (du, new multipliers) from the KKT system with the Hessian shifted by
    ``shift``, condensed (``bordered.condensed``), with one step of iterative refinement where
    its residual is not at round-off (the angles' block alone may be near singular).
    Where the constraints are dependent (a straight part whose chord must shorten) the
    multipliers' block takes -1e-8 on its diagonal, so that a step still comes, which
    bends the part; a system singular even so gives a step of NaN (refused)."""
    n, m = diag.shape[0], jac.shape[0]
    shifted = _shifted(diag, shift)
    du = np.zeros(n + 2)
    y = np.zeros(m)
    r_u = np.empty(n + 2)
    r_c = np.empty(m)
    ok = False
    for reg in (0.0, 1e-8):
        du[:] = 0.0
        y[:] = 0.0
        for j in range(n + 2):
            r_u[j] = -g[j]
        for r in range(m):
            r_c[r] = -c[r]
        for _ in range(2):  # a solve, then a correction from its residual
            dx, dy, ok = kkt_solve(shifted, off, jac, shift, reg, r_u, r_c)
            if not ok:
                break
            for j in range(n + 2):
                du[j] += dx[j]
            for r in range(m):
                y[r] += dy[r]
            # The residual of the whole system at (du, y).
            t_du = tridiagonal_times(diag, off, du[2:])
            for j in range(n + 2):
                r_u[j] = -g[j] - shift * du[j]
                if j >= 2:
                    r_u[j] -= t_du[j - 2]
            for r in range(m):
                r_c[r] = -c[r] + reg * y[r]
            for r in range(m):
                for j in range(n + 2):
                    r_u[j] -= jac[r, j] * y[r]
                    r_c[r] -= jac[r, j] * du[j]
            size = max_abs(g) + max_abs(c) + 1e-300
            if max(max_abs(r_u), max_abs(r_c)) <= 1e-12 * size:
                break
        if ok:
            break
    if not ok:
        du[:] = np.nan
    return du, _negated(y)


@njit(cache=True)
def _row_basis(jac):
    """J^T = Q R by modified Gram-Schmidt (J has a few rows): (q, r), the rows of q
    orthonormal, r upper triangular; a dependent row of J gets a zero row in q."""
    m, n = jac.shape
    q = jac.copy()
    r = np.zeros((m, m))
    for a in range(m):
        for b in range(a):
            dot = 0.0
            for j in range(n):
                dot += q[b, j] * q[a, j]
            r[b, a] = dot
            for j in range(n):
                q[a, j] -= dot * q[b, j]
        norm = math.sqrt(_dot(q[a], q[a]))
        r[a, a] = norm
        keep = norm > 1e-12 * (1.0 + max_abs(jac[a]))
        for j in range(n):
            q[a, j] = q[a, j] / norm if keep else 0.0
    return q, r


@njit(cache=True)
def _multipliers(q, r, g):
    """lam with grad E = J^T lam in the least-squares sense (``_row_basis``'s q, r of
    J): lam = R^-1 Q^T g; a dependent row gets 0."""
    m = q.shape[0]
    lam = np.zeros(m)
    for a in range(m - 1, -1, -1):
        acc = _dot(q[a], g)
        for b in range(a + 1, m):
            acc -= r[a, b] * lam[b]
        lam[a] = acc / r[a, a] if _nonzero(q[a]) else 0.0
    return lam


@njit(cache=True)
def _back_onto(q, r, c):
    """The least move (minimum norm) that cancels the constraints' values c to first
    order, J d = -c, with ``_row_basis``'s q, r of J: d = Q^T y, R^T y = -c (a
    dependent row is left out)."""
    m = q.shape[0]
    y = np.zeros(m)
    for a in range(m):
        if _nonzero(q[a]):
            acc = -c[a]
            for b in range(a):
                acc -= r[b, a] * y[b]
            y[a] = acc / r[a, a]
    out = np.zeros(q.shape[1])
    for a in range(m):
        for j in range(q.shape[1]):
            out[j] += y[a] * q[a, j]
    return out


@njit(cache=True)
def _merit(u, a, rho):
    c, s = _trig(u)
    return _energy_at(u, a, c, s)[0] + rho * _abs_sum(_constraints_at(u, a, c, s))


@njit(cache=True)
def _near_known(u, known, near):
    """Whether u's element angles all lie within ``near`` of one row of ``known``."""
    for row in range(known.shape[0]):
        off = 0.0
        for j in range(known.shape[1]):
            off = max(off, abs(u[2 + j] - known[row, j]))
        if off < near:
            return True
    return False


@njit(cache=True)
def _sqp_kernel(u, a, iterations, tolerance, max_turn, known, near):
    """Sequential quadratic programming with the exact Hessian of the Lagrangian. Where
    that Hessian is not positive on the constraints' tangent space it is shifted until
    it is, so each step descends toward a minimum, not a saddle; an element's angle turns
    by at most ``max_turn`` a step (a longer one from a poor start leaps into a tangled
    shape); a step the l1 merit function cuts back raises a damping shift for the next
    (Levenberg's rule), which a full step lowers again.

    An iterate within ``near`` of a row of ``known`` (element angles of equilibria found
    already) where the Hessian needs no shift (a minimum's basin) and the step is
    shorter than ``near`` converges to that equilibrium's minimum: it stops there.
    (u, CONVERGED, KNOWN or FAILED)."""
    m = a.pos_k.shape[0] + a.ang_k.shape[0]
    lam = np.zeros(m)
    q, r = np.zeros((m, u.shape[0])), np.zeros((m, m))  # J's row basis (``_row_basis``)
    damping = 0.0
    shift = 0.0
    mode = np.zeros(u.shape[0])  # the softest mode on the constraints' null space
    for _ in range(iterations):
        cos_u, sin_u = _trig(u)
        e, g = _energy_at(u, a, cos_u, sin_u)
        c, jac = _constraints_at(u, a, cos_u, sin_u), _jacobian_at(u, a, cos_u, sin_u)
        if m:
            q, r = _row_basis(jac)
            lam = _multipliers(q, r, g)
        station = g.copy()  # grad E - J^T lam
        for row in range(m):
            for j in range(station.shape[0]):
                station[j] -= lam[row] * jac[row, j]
        if (max_abs(station) < tolerance * (1.0 + max_abs(g))
                and (m == 0 or max_abs(c) < tolerance)):
            return u, CONVERGED
        diag, off = _tridiagonal_at(u, lam, a, cos_u, sin_u)
        shift = tangent_shift(diag, off, jac, shift, mode) if m else 0.0
        du, lam_new = kkt_step(diag, off, jac, g, c, damping + shift)
        biggest = max_abs(du)
        if not math.isfinite(biggest):
            return u, FAILED
        if m and shift == 0.0 and biggest < near and _near_known(u, known, near):
            return u, KNOWN
        cut = min(1.0, max_turn / max(biggest, 1e-300))
        for j in range(du.shape[0]):
            du[j] *= cut
        rho = 2.0 * (max_abs(lam_new) if m else 0.0) + 1.0
        merit = e + rho * _abs_sum(c)
        slope = min(_dot(g, du) - rho * _abs_sum(c), 0.0)
        alpha = 1.0
        trial = _axpy(u, 1.0, du)
        # (the last term: round-off at the minimum)
        enough = merit + 1e-4 * slope + 1e-12 * abs(merit)
        if _merit(trial, a, rho) > enough:
            # The full step refused: first with its second-order correction (the least
            # move back onto the constraints, which bend away from their linearisation;
            # without it the l1 merit cuts every step near a curved constraint short,
            # the Maratos effect: case 3's starts took 43 and 26 steps, with it 16 and 12).
            alpha = 0.5
            if m:
                corrected = _axpy(trial, 1.0, _back_onto(q, r, _constraints(trial, a)))
                if _merit(corrected, a, rho) <= enough:
                    trial = corrected
                    alpha = 1.0
        while alpha < 1.0:
            trial = _axpy(u, alpha, du)
            enough = merit + 1e-4 * alpha * slope + 1e-12 * abs(merit)
            if _merit(trial, a, rho) <= enough:
                break
            if m:  # the shorter step with its correction too (a curvilinear search)
                trial = _axpy(trial, 1.0, _back_onto(q, r, _constraints(trial, a)))
                if _merit(trial, a, rho) <= enough:
                    break
            alpha *= 0.5
            if alpha < 1e-6:
                return u, FAILED
        damping = damping / 4.0 if alpha == 1.0 else max(4.0 * damping, 1.0)
        u = trial
    return u, FAILED


class Minimum:
    """A discrete minimum as the arrays a 2D warm start reads (s, position, angle,
    internal_force, bending_moment, loads by name, with the reactions from the
    multipliers) and its unknowns u and energy. Its angles come at once, the rest when
    first read: a minimum the route reached already is recognised by its angles
    (``solver.Run.minima``), and the rest took 42 us of a 1.4 ms cold solve."""

    notes = ()
    state = None

    def __init__(self, disc: Discrete, u: np.ndarray) -> None:
        problem = disc.problem
        self.problem, self.disc, self.u = problem, disc, u
        part = problem.part
        L, EI = part.length, part.bending_stiffness
        e, self._gradient = disc.energy(u)
        self.energy = float(e)
        theta = u[2:]
        node_theta = np.empty(disc.n + 1)  # each interior node: its elements' mean
        node_theta[1:-1] = 0.5 * (theta[1:] + theta[:-1])
        node_theta[0], node_theta[-1] = theta[0], theta[-1]
        self._ends = disc.end_terms(theta)
        for k, v, _ in self._ends:
            node_theta[k] = v
        self.s, self.angle = disc.s * L, node_theta
        self._scales = (L, EI)

    @cached_property
    def position(self) -> np.ndarray:
        return self.disc.nodes(self.u) * self._scales[0]

    @property
    def internal_force(self) -> np.ndarray:
        return self._forces[0]

    @property
    def bending_moment(self) -> np.ndarray:
        return self._forces[1]

    @property
    def loads(self) -> dict[str, PlanarLoad]:
        return self._forces[2]

    @cached_property
    def _forces(self) -> tuple[np.ndarray, np.ndarray, dict[str, PlanarLoad]]:
        """(internal force, bending moment, loads by name), from the multipliers."""
        disc, problem, u = self.disc, self.problem, self.u
        L, EI = self._scales
        jac = disc.jacobian(u)
        q, r = _row_basis(jac)
        lam = _multipliers(q, r, self._gradient)  # grad E = J^T lambda (least squares)
        force = disc.arrays.f.copy()  # every point load on the part, reactions included
        reactions = {}
        for row, (k, i, _) in enumerate(disc.position):
            force[k, i] += lam[row]
            reactions[(k, i)] = lam[row]
        for row, (k, _) in enumerate(disc.angle, start=len(disc.position)):
            reactions[(k, 2)] = lam[row]
        n, h = disc.n, disc.h
        moment = np.zeros(n + 1)  # M / EI - the rest curvature
        moment[1:-1] = (np.diff(u[2:]) / h - disc.arrays.kappa0[1:-1])
        moment[0], moment[-1] = moment[1], moment[-2]
        for k, _, end in self._ends:
            moment[k] = end
            # The held end's couple on the part: -M at the first end, +M at the last.
            reactions[(k, 2)] = -end if k == 0 else end
        # Internal force at node k: the loads of the later nodes (what lies beyond it).
        beyond = np.zeros((n + 1, 2))
        beyond[:-1] = np.cumsum(force[::-1], axis=0)[::-1][1:]
        loads = {}
        for index, c in enumerate(problem.model_conditions):
            k = disc.node_of[index]
            applied = [float(c.force[i] or 0.0) * L**2 / EI
                       if c.force and c.force[i] is not None else 0.0 for i in range(2)]
            f = np.array([reactions.get((k, i), applied[i]) for i in range(2)])
            m = reactions.get((k, 2), float(c.moment or 0.0) * L / EI)  # type: ignore[arg-type]
            loads[c.name] = PlanarLoad(f * EI / L**2, m * EI / L)
        return beyond * EI / L**2, moment * EI / L, loads
