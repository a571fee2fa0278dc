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
part's own equilibrium with its own accuracy (``solver._Run.minima``).

Only conservative, inextensible problems with at least one prescribed position: a
follower load has no potential, and an extensible part's start would miss its stretch.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

from pliant.core.problem import Problem
from pliant.models import clock

ELEMENTS = 48  # elements of the discrete part: a start for Newton, not an answer
BOWS = (0.0, 1.5, -1.5)  # starting bows [rad]: straight, and to either side
MAX_TURN = 1.0  # rad: the largest change of an element's angle in one SQP step (a
# longer step from a poor start leaps into a tangled shape of far higher energy)


def applicable(problem: Problem) -> bool:
    """Whether the problem is one this route can minimise (see the module)."""
    conds = problem.conditions
    if problem.part.axial_stiffness is not None or any(c.follower for c in conds):
        return False
    return any(all(v is not None for v in c.position) and len(c.position) == 2
               for c in conds)


class _Discrete:
    """The discrete part in units of L (lengths), EI / L (energies)."""

    def __init__(self, problem: Problem, elements: int) -> None:
        part = problem.part
        L, EI = part.length, part.bending_stiffness
        self.problem, self.n, self.h = problem, elements, 1.0 / elements
        n, h = elements, self.h
        s = np.linspace(0.0, 1.0, n + 1)
        self.s = s
        self.kappa0 = np.array([part.rest_curvature_at(x * L) for x in s]) * L
        weight = np.full(n + 1, h)
        weight[[0, -1]] = 0.5 * h
        q = part.mass_per_length * np.asarray(problem.gravity, float) * L**3 / EI
        self.f = weight[:, None] * q[None, :]  # dead forces at the nodes
        self.m = np.zeros(n + 1)  # dead couples at the nodes
        self.position: list[tuple[int, int, float]] = []  # (node, component, value)
        self.angle: list[tuple[int, float]] = []  # interior: constraints
        self.ends: list[tuple[int, float]] = []  # at an end: a half element's bending
        self.node_of: dict[int, int] = {}
        for index, c in enumerate(problem.conditions):
            k = int(round(c.s / L * n))
            self.node_of[index] = k
            for i in range(2):
                v = c.position[i] if c.position else None
                if v is not None:
                    self.position.append((k, i, float(v) / L))
                elif c.force and c.force[i] is not None:
                    self.f[k, i] += float(c.force[i]) * L**2 / EI
            if c.angle is not None and k in (0, n):
                self.ends.append((k, float(c.angle)))
            elif c.angle is not None:
                self.angle.append((k, float(c.angle)))
            elif c.moment is not None:
                self.m[k] += float(c.moment) * L / EI
        self.tail = np.cumsum(self.f[::-1], axis=0)[::-1]  # sum of f_k for k >= j

    # -- the node angle and its weights on the element angles ----------------------------
    def node_weights(self, k: int) -> list[tuple[int, float]]:
        if k == 0:
            return [(0, 1.0)]
        if k == self.n:
            return [(self.n - 1, 1.0)]
        return [(k - 1, 0.5), (k, 0.5)]

    def nodes(self, u: np.ndarray) -> np.ndarray:
        theta = u[2:]
        x = np.empty((self.n + 1, 2))
        x[0] = u[:2]
        x[1:, 0] = np.cos(theta)
        x[1:, 1] = np.sin(theta)
        x[1:] *= self.h
        return np.cumsum(x, axis=0)

    def energy(self, u: np.ndarray) -> tuple[float, np.ndarray]:
        theta, h = u[2:], self.h
        d = (np.diff(theta) - h * self.kappa0[1:-1]) / h
        x = self.nodes(u)
        e = 0.5 * h * float(d @ d) - float(np.vdot(self.f, x))
        g = np.empty_like(u)
        g[:2] = -self.tail[0]
        gt = g[2:]
        gt[:] = h * (np.sin(theta) * self.tail[1:, 0] - np.cos(theta) * self.tail[1:, 1])
        gt[1:] += d
        gt[:-1] -= d
        for k, v, j, sign, end in self.end_terms(theta):
            e += 0.25 * h * end * end
            gt[j] += sign * end
        for k in np.nonzero(self.m)[0]:
            for j, w in self.node_weights(int(k)):
                e -= w * self.m[k] * theta[j]
                gt[j] -= w * self.m[k]
        return e, g

    def end_terms(self, theta: np.ndarray) -> list[tuple[int, float, int, float, float]]:
        """Each end whose angle is held: (node, angle, its element, the sign of the
        element's angle in the curvature, the curvature's excess M / EI there). The held
        angle bends the half element between the end and the element's middle, which
        keeps the discretisation second order (an element angle set to it is first)."""
        out = []
        for k, v in self.ends:
            if k == 0:
                out.append((k, v, 0, 1.0, (theta[0] - v) / (0.5 * self.h) - self.kappa0[0]))
            else:
                out.append((k, v, self.n - 1, -1.0,
                            (v - theta[-1]) / (0.5 * self.h) - self.kappa0[-1]))
        return out

    def hessian(self, u: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """The Hessian of the Lagrangian E - lam . c in u."""
        theta, h, n = u[2:], self.h, self.n
        hess = np.zeros((u.size, u.size))
        b = hess[2:, 2:]
        idx = np.arange(n)
        b[idx[1:], idx[1:]] += 1.0 / h
        b[idx[:-1], idx[:-1]] += 1.0 / h
        b[idx[1:], idx[:-1]] -= 1.0 / h
        b[idx[:-1], idx[1:]] -= 1.0 / h
        for _, _, j, _, _ in self.end_terms(theta):
            b[j, j] += 2.0 / h
        # d2 x_k / d theta_j^2 = -h (cos, sin) theta_j for j < k: the loads beyond j
        # (E has -f . x), and minus the constraints' multipliers on their components.
        pull = self.tail[1:].copy()
        for r, (k, i, _) in enumerate(self.position):
            pull[:k, i] += lam[r]
        b[idx, idx] += h * (np.cos(theta) * pull[:, 0] + np.sin(theta) * pull[:, 1])
        return hess

    def constraints(self, u: np.ndarray) -> np.ndarray:
        x = self.nodes(u)
        out = [x[k, i] - v for k, i, v in self.position]
        for k, v in self.angle:
            out.append(sum(w * u[2 + j] for j, w in self.node_weights(k)) - v)
        return np.array(out)

    def jacobian(self, u: np.ndarray) -> np.ndarray:
        theta, h = u[2:], self.h
        rows = np.zeros((len(self.position) + len(self.angle), u.size))
        dx = h * np.column_stack([-np.sin(theta), np.cos(theta)])
        for r, (k, i, _) in enumerate(self.position):
            rows[r, i] = 1.0
            rows[r, 2:2 + k] = dx[:k, i]
        for r, (k, _) in enumerate(self.angle, start=len(self.position)):
            for j, w in self.node_weights(k):
                rows[r, 2 + j] = w
        return rows

    # -- starts --------------------------------------------------------------------------
    def start(self, bow: float) -> np.ndarray:
        """A start: the part from its first end along its first prescribed angle (or
        toward its last prescribed position), turning at a constant rate to its last
        prescribed angle, bowed by ``bow`` rad (sin(pi s) profile)."""
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
        theta = first + turn * s_el + bow * np.sin(math.pi * s_el)
        u = np.concatenate([[0.0, 0.0], theta])
        u[:2] = base - self.nodes(u)[anchor]
        return u


def minima(problem: Problem, *, elements: int = ELEMENTS, deadline: float | None = None,
           bows: tuple[float, ...] = BOWS) -> list[SimpleNamespace]:
    """Local minima of the discrete part's energy under the problem's conditions, one per
    start that converged, lowest first, as the arrays a 2D warm start reads (s, position,
    angle, internal_force, bending_moment, loads by name)."""
    disc = _Discrete(problem, elements)
    found: list[SimpleNamespace] = []
    for bow in bows:
        if deadline is not None and clock.now() > deadline:
            break
        start = disc.start(bow)
        if np.ptp(start[2:]) < 1e-9:
            continue  # straight: a chord that must shorten cannot to first order
        with np.errstate(over="ignore", invalid="ignore"):  # a trial step too far: refused
            state = _minimise(disc, start)
        if state is not None and not any(
                np.abs(state.u[2:] - other.u[2:]).max() < 1e-4 for other in found):
            found.append(state)
    found.sort(key=lambda state: state.energy)
    return found


def refined(state: SimpleNamespace, factor: int = 4) -> SimpleNamespace | None:
    """The minimum again on a grid ``factor`` times finer, from the coarse one: where
    the part bends sharply (a taut part's U-turn) a coarse start is too far from the
    part's own equilibrium for Newton."""
    coarse = state.disc
    disc = _Discrete(coarse.problem, factor * coarse.n)
    theta = np.repeat(state.u[2:], factor)
    u = np.concatenate([state.u[:2], theta])
    with np.errstate(over="ignore", invalid="ignore"):
        return _minimise(disc, u)


def _minimise(disc: _Discrete, u0: np.ndarray) -> SimpleNamespace | None:
    """The minimum from u0: the exact-Hessian SQP (``_sqp``, a few milliseconds), or
    where it fails, scipy's SLSQP (quasi-Newton, slower, but it gets through the tangled
    shapes a bad start leads the SQP into)."""
    found = _sqp(disc, u0)
    if found is not None:
        return found
    from scipy.optimize import minimize  # noqa: PLC0415 (scipy.optimize: on demand)

    result = minimize(disc.energy, u0, jac=True, method="SLSQP",
                      constraints=[{"type": "eq", "fun": disc.constraints,
                                    "jac": disc.jacobian}],
                      options={"maxiter": 400, "ftol": 1e-12})
    if not result.success or np.abs(disc.constraints(result.x)).max() > 1e-8:
        return None
    return _state(disc, result.x)


def _sqp(disc: _Discrete, u: np.ndarray, iterations: int = 60,
              tolerance: float = 1e-10) -> SimpleNamespace | None:
    """Sequential quadratic programming with the exact Hessian of the Lagrangian
    (tridiagonal: the bending, plus the loads' and constraints' second derivatives, which
    are diagonal in the element angles). Where that Hessian is not positive on the
    constraints' tangent space it is shifted until it is, so each step descends toward a
    minimum, not a saddle; a step the l1 merit function cuts back raises a damping shift
    for the next (Levenberg's rule), which a full step lowers again. None when it does not
    converge within ``iterations``."""
    m = len(disc.position) + len(disc.angle)
    lam = np.zeros(m)
    damping = 0.0
    for _ in range(iterations):
        e, g = disc.energy(u)
        c, jac = disc.constraints(u), disc.jacobian(u)
        if m:
            lam = np.linalg.lstsq(jac.T, g, rcond=None)[0]
        if (np.abs(g - jac.T @ lam).max() < tolerance * (1.0 + np.abs(g).max())
                and np.abs(c).max() < tolerance):
            return _state(disc, u)
        step = _kkt_step(disc.hessian(u, lam), jac, g, c, damping)
        if step is None:
            return None
        du, lam_new = step
        du *= min(1.0, MAX_TURN / max(float(np.abs(du).max()), 1e-300))
        rho = 2.0 * float(np.abs(lam_new).max(initial=0.0)) + 1.0
        merit = e + rho * float(np.abs(c).sum())
        slope = min(float(g @ du) - rho * float(np.abs(c).sum()), 0.0)
        alpha = 1.0
        while True:
            trial = u + alpha * du
            if disc.energy(trial)[0] + rho * float(np.abs(disc.constraints(trial)).sum()) \
                    <= merit + 1e-4 * alpha * slope + 1e-12 * abs(merit):  # round-off
                break
            alpha *= 0.5
            if alpha < 1e-6:
                return None
        damping = damping / 4.0 if alpha == 1.0 else max(4.0 * damping, 1.0)
        u = trial
    return None


def _kkt_step(hess: np.ndarray, jac: np.ndarray, g: np.ndarray, c: np.ndarray,
              damping: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The SQP step (du, new multipliers), the Hessian shifted until it is positive
    definite on the null space of the constraints' Jacobian, and by ``damping`` more."""
    n, m = hess.shape[0], jac.shape[0]
    if m:
        q = np.linalg.qr(jac.T, mode="complete")[0]
        null = q[:, m:]
    else:
        null = np.eye(n)
    reduced = null.T @ hess @ null
    shift = damping
    try:  # positive definite on the tangent space: no shift (the usual case)
        np.linalg.cholesky(reduced - 1e-6 * np.eye(reduced.shape[0]))
    except np.linalg.LinAlgError:
        shift += 1e-6 - float(np.linalg.eigvalsh(reduced)[0])
    kkt = np.zeros((n + m, n + m))
    kkt[:n, :n] = hess + shift * np.eye(n)
    kkt[:n, n:] = jac.T
    kkt[n:, :n] = jac
    try:
        sol = np.linalg.solve(kkt, -np.concatenate([g, c]))
    except np.linalg.LinAlgError:
        return None
    return sol[:n], -sol[n:]


def _state(disc: _Discrete, u: np.ndarray) -> SimpleNamespace:
    """The discrete minimum as physical arrays, with the reactions from the multipliers."""
    problem = disc.problem
    part = problem.part
    L, EI = part.length, part.bending_stiffness
    _, g = disc.energy(u)
    jac = disc.jacobian(u)
    lam = np.linalg.lstsq(jac.T, g, rcond=None)[0]  # grad E = J^T lambda
    force = disc.f.copy()  # every point load on the part, reactions included
    reactions = {}
    for r, (k, i, _) in enumerate(disc.position):
        force[k, i] += lam[r]
        reactions[(k, i)] = lam[r]
    for r, (k, _) in enumerate(disc.angle, start=len(disc.position)):
        reactions[(k, 2)] = lam[r]
    n, h = disc.n, disc.h
    theta = u[2:]
    x = disc.nodes(u)
    node_theta = np.concatenate([[theta[0]], 0.5 * (theta[1:] + theta[:-1]), [theta[-1]]])
    moment = np.zeros(n + 1)  # M / EI - the rest curvature
    moment[1:-1] = (np.diff(theta) / h - disc.kappa0[1:-1])
    moment[0], moment[-1] = moment[1], moment[-2]
    for k, v, _, _, end in disc.end_terms(theta):
        node_theta[k], moment[k] = v, end
        # The held end's couple on the part: -M at the first end, +M at the last.
        reactions[(k, 2)] = -end if k == 0 else end
    # Internal force at node k: the loads of the later nodes (what lies beyond it).
    beyond = np.zeros((n + 1, 2))
    beyond[:-1] = np.cumsum(force[::-1], axis=0)[::-1][1:]
    loads = {}
    for index, c in enumerate(problem.conditions):
        k = disc.node_of[index]
        applied = [float(c.force[i]) * L**2 / EI if c.force and c.force[i] is not None
                   else 0.0 for i in range(2)]
        f = np.array([reactions.get((k, i), applied[i]) for i in range(2)])
        m = reactions.get((k, 2), float(c.moment or 0.0) * L / EI)
        loads[c.name] = SimpleNamespace(force=f * EI / L**2, moment=m * EI / L)
    return SimpleNamespace(problem=problem, s=disc.s * L, position=x * L, angle=node_theta,
                           internal_force=beyond * EI / L**2, bending_moment=moment * EI / L,
                           loads=loads, notes=(), state=None, u=u, disc=disc,
                           energy=disc.energy(u)[0])
