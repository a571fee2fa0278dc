"""Several flexible parts solved together, touching one another.

Each part keeps its own discrete rod (its banded KKT system, its obstacles); contacts
between parts couple them. For each pair of parts (a, b), a < b, probes sit along a
(the nodes and points evenly inside each element, close enough that two tubes cannot
cross between two by more than 1 % of their radii) and each is paired with b's nearest
segment: its gap is g = (|p - q| - r_a - r_b) / L (q the nearest point of b's neutral
line) and its normal force mu >= 0, with min(mu, g + C mu) = 0 solved by the same
semismooth Newton as the obstacles' (``kernels.contact_terms``). The force mu n acts on
the probe's two nodes and -mu n on the segment's two: Newton's third law holds exactly,
so each part balances with the others' forces as loads.

The Newton system is each part's band plus the coupling, which enters a part only at
the nodes a contact touches. Each band is factorised once per iteration and solved for
the residual and for a unit load at each touched coordinate (the part's compliance
there); a dense system on the touched coordinates and the contact forces joins them
(static condensation onto the coupling: its size is a few times the number of contacts,
not the parts' unknowns). The curvature of the distance between the two lines (its
Hessian, by central differences of its exact gradient) enters, so the iteration keeps
Newton's convergence as the contact rolls along the parts.

Units: each part's unknowns keep their own scales (lengths by its L, forces by its
EI / L^2); gaps are by the first part's length and contact forces by its force scale.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from pliant.core.equilibrium import Contacts, Equilibrium3D, Samples3D
from pliant.core.problem import PROBE_SAG, WALL_COMPLIANCE
from pliant.errors import ConvergenceError
from pliant.models import clock
from pliant.models.banded import band_lu, band_lu_solve, band_reduce
from pliant.models.rod3d import kernels, spline
from pliant.models.rod3d.lowering import Loads, Rod
from pliant.models.rod3d.solver import (
    CONTACT_SCALE,
    RodSolver,
    State,
    _build,
    _Run,
    _Sampler,
)

# Contact between parts is compliant (core.problem.WALL_COMPLIANCE: a hose wall's give;
# a stiff pipe's is smaller, but the answer barely depends on it: 0.25 mm at 25 N), not
# rigid: along a span where one part wraps round another, the probes at a straight
# element's ends and middle cannot all lie on the curved surface, and a rigid contact
# would leave that set with no solution.
_SETS = 16  # corrections of the touching set in one Newton solve
_HELD_ITERATIONS = 12  # Newton iterations on one touching set
_PENETRATION = 1e-9  # a free probe's scaled gap below minus this: it touches
_HESSIAN_STEP = 1e-6  # central differences of the distance's gradient, by the reach
DEEP = 0.5  # a state with two centrelines closer than this many reaches is refused


@dataclass(frozen=True, eq=False)
class Pair:
    """Probes on part ``a`` against the neutral line of part ``b`` (a < b)."""

    a: int
    b: int
    elem: np.ndarray  # (K,) the element of a each probe lies on
    alpha: np.ndarray  # (K,) where in it: p = (1 - alpha) x_e + alpha x_e+1
    reach: float  # r_a + r_b [m]: the centrelines' distance at touch


def probes(rod: Rod, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Every node of ``rod`` and points evenly inside each element, spaced at most
    sqrt(8 PROBE_SAG) ``reach`` apart: two tubes whose radii add to ``reach`` cannot then
    pass each other between two probes by more than PROBE_SAG of it (the sag s^2 / 8
    reach)."""
    N = rod.elements
    longest = float(rod.h.max()) * rod.length
    spacing = math.sqrt(8.0 * PROBE_SAG) * reach
    per = int(min(16, max(1, math.ceil(longest / spacing))))
    elem = np.concatenate([np.arange(N), [N - 1], np.repeat(np.arange(N), per - 1)])
    alpha = np.concatenate([np.zeros(N), [1.0], np.tile(np.arange(1, per) / per, N)])
    order = np.lexsort((alpha, elem))
    return elem[order].astype(np.int64), alpha[order]


@dataclass(frozen=True, eq=False)
class _Geometry:
    """One pair's probes against the other part, at one state (SI lengths)."""

    f: np.ndarray  # (K,) b's nearest segment
    beta: np.ndarray  # (K,) where on it
    jb: np.ndarray  # (K, 4) the nodes of b its curve there depends on
    left: np.ndarray  # (K,) the segment is b's first (its curve starts straight)
    right: np.ndarray  # (K,) or its last
    y: np.ndarray  # (K, 18) a's x_e, x_e+1 and b's four nodes jb [m]
    q: np.ndarray  # (K, 3) the nearest point of b's neutral line [m]
    d: np.ndarray  # (K,) centreline distance [m]
    n: np.ndarray  # (K, 3) from b toward a
    gap: np.ndarray  # (K,) (d - reach) / L_ref


@dataclass
class _Member:
    run: _Run
    start: Loads  # the loads at the homotopy's start
    end: Loads  # and at its end


@dataclass
class _Eval:
    R: list[np.ndarray]
    ab: list[np.ndarray | None]
    Rmu: list[np.ndarray]
    geo: list[_Geometry | None]
    active: list[np.ndarray]
    near: list[np.ndarray]  # probe indices within reach of the band
    residual: float
    slopes: list  # per pair, the contact rows' d/dmu and d/dg (probes in ``near``)


@dataclass
class Coupling:
    """Parts solved together: their runs (each a rod with its own obstacles), the pairs
    of parts that may touch, and the solver's settings. ``weight`` scales the contact
    forces on the second part of every pair (the homotopy from it held still, 0, to the
    physical problem, 1)."""

    runs: list[_Run]
    pairs: list[Pair]
    solver: RodSolver
    iterations: int = 0
    steps: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def compliance(self) -> float:
        """The contact's gap per unit force in the system's units (see WALL_COMPLIANCE)."""
        return WALL_COMPLIANCE * self.F_ref / self.L_ref

    @property
    def L_ref(self) -> float:
        return self.runs[0].rod.length

    @property
    def F_ref(self) -> float:
        return self.runs[0].rod.force_scale

    def band(self, pair: Pair) -> float:
        """Past this distance [m] beyond touch a probe is not looked at in a solve."""
        return 2.0 * pair.reach + 0.05 * self.runs[pair.a].rod.length

    # -- residual ---------------------------------------------------------------------
    def geometry(self, pair: Pair, states: Sequence[State], only: np.ndarray) -> _Geometry:
        ra, rb = self.runs[pair.a].rod, self.runs[pair.b].rod
        Xa = states[pair.a][0] * ra.length
        Xb = states[pair.b][0] * rb.length
        e, al = pair.elem[only], pair.alpha[only]
        p = (1.0 - al[:, None]) * Xa[e] + al[:, None] * Xa[e + 1]
        f, beta, jb, left, right, q = spline.nearest(np.ascontiguousarray(p), Xb)
        v = p - q
        d = np.linalg.norm(v, axis=1)
        n = v / np.maximum(d, 1e-300)[:, None]
        y = np.concatenate([Xa[e], Xa[e + 1], Xb[jb].reshape(-1, 12)], axis=1)
        return _Geometry(f, beta, jb, left, right, y, q, d, n, (d - pair.reach) / self.L_ref)

    def near(self, pair: Pair, states: Sequence[State], mu: np.ndarray) -> np.ndarray:
        """The probes of ``pair`` within its band of the other part (all of them that can
        touch in a Newton from ``states``), and any with a force on."""
        ra, rb = self.runs[pair.a].rod, self.runs[pair.b].rod
        Xa = states[pair.a][0] * ra.length
        Xb = states[pair.b][0] * rb.length
        grow = pair.reach + self.band(pair)
        if np.any(Xa.min(axis=0) - grow > Xb.max(axis=0)) or np.any(
                Xb.min(axis=0) - grow > Xa.max(axis=0)):
            return np.nonzero(mu)[0]
        geo = self.geometry(pair, states, np.arange(pair.elem.shape[0]))
        return np.nonzero((geo.d < grow) | (mu != 0.0))[0]

    def evaluate(self, states: Sequence[State], mus: Sequence[np.ndarray],
                 loads: Sequence[Loads], weight: float, near: list[np.ndarray],
                 want_jac: bool, fixed: list[np.ndarray] | None = None) -> _Eval:
        R, ab = [], []
        for run, state, load in zip(self.runs, states, loads):
            r, a, _ = run.residual(state, load, want_jac)
            R.append(r)
            ab.append(a if want_jac else None)
        Rmu, geos, actives, slopes = [], [], [], []
        deep = False
        for pair, mu, only in zip(self.pairs, mus, near):
            if not only.shape[0]:
                Rmu.append(mu.copy())
                geos.append(None)
                actives.append(np.zeros(0, dtype=bool))
                slopes.append((np.zeros(0), np.zeros(0)))
                continue
            geo = self.geometry(pair, states, only)
            deep = deep or bool(np.any(geo.d < DEEP * pair.reach))
            m = mu[only]
            gs = CONTACT_SCALE * (geo.gap + self.compliance * m)
            # min(mu, g) = 0: a touching probe's row is its gap, a free one's its force.
            # Within a Newton the touching set may be held (``fixed``): the system is then
            # smooth, and the set is corrected between solves (a primal-dual active set
            # method; the semismooth Newton alone can flip a probe at the edge of a
            # contact back and forth between two iterates).
            active = m > gs if fixed is None else fixed[len(Rmu)][only]
            rmu = mu.copy()
            rmu[only] = np.where(active, gs, m)
            slopes.append((np.where(active, 0.0, 1.0), np.where(active, 1.0, 0.0)))
            Rmu.append(rmu)
            geos.append(geo)
            actives.append(active)
            self._forces(pair, geo, only, m, weight, R)
        residual = max([float(np.abs(r).max(initial=0.0)) for r in R]
                       + [float(np.abs(r).max(initial=0.0)) for r in Rmu])
        if deep:  # one tube half through the other: no Newton finds its way back
            residual = math.inf
        return _Eval(R, ab, Rmu, geos, actives, list(near), residual, slopes)

    def _factors(self, pair: Pair, weight: float) -> np.ndarray:
        """(12,) what turns mu d|p-q|/dy into each coordinate's residual entry."""
        ra, rb = self.runs[pair.a].rod, self.runs[pair.b].rod
        F = self.F_ref
        return np.concatenate([np.full(6, -F / ra.force_scale),
                               np.full(12, -weight * F / rb.force_scale)])

    def _forces(self, pair: Pair, geo: _Geometry, only: np.ndarray, mu: np.ndarray,
                weight: float, R: list[np.ndarray]) -> None:
        on = mu != 0.0
        if not on.any():
            return
        grad = spline.gradients(geo.y[on], pair.alpha[only][on], geo.left[on],
                                geo.right[on], geo.beta[on])
        value = mu[on, None] * grad * self._factors(pair, weight)
        for side, nodes in ((pair.a, (pair.elem[only][on], pair.elem[only][on] + 1)),
                            (pair.b, tuple(geo.jb[on, j] for j in range(4)))):
            ix = self.runs[side].rod.ix
            base = 0 if side == pair.a else 6
            for j, node in enumerate(nodes):
                for c in range(3):
                    np.add.at(R[side], ix[node] + c, value[:, base + 3 * j + c])

    # -- the Newton direction ---------------------------------------------------------
    def direction(self, ev: _Eval, mus: Sequence[np.ndarray], weight: float):
        """The Newton step (per part du, per pair dmu) or None where singular."""
        P = len(self.runs)
        # The contacts in the system: touching ones and any with a force still on.
        rows = []  # (pair index, probe index in ``near``, probe index)
        for p, (pair, geo) in enumerate(zip(self.pairs, ev.geo)):
            if geo is None:
                continue
            only = ev.near[p]
            m = mus[p][only]
            # (A probe with no force and an open gap has the row d mu = 0: left out.)
            for j in np.nonzero((m != 0.0) | (ev.slopes[p][1] != 0.0))[0]:
                rows.append((p, int(j), int(only[j])))
        # The coupling coordinates: x of every node those contacts touch, part by part.
        slot = [dict() for _ in range(P)]
        coords: list[list[int]] = [[] for _ in range(P)]
        nodes_of = []
        for p, j, _ in rows:
            pair, geo = self.pairs[p], ev.geo[p]
            e = int(pair.elem[ev.near[p][j]])
            nodes_of.append(((pair.a, e), (pair.a, e + 1))
                            + tuple((pair.b, int(x)) for x in geo.jb[j]))
            for part, node in nodes_of[-1]:
                if node not in slot[part]:
                    slot[part][node] = len(coords[part])
                    coords[part].append(node)
        offset = np.concatenate([[0], np.cumsum([3 * len(c) for c in coords])]).astype(int)
        nc, m = int(offset[-1]), len(rows)
        # Each part: its band factorised, solved for -R and the unit loads.
        base, W = [], []
        Z = np.zeros((nc, nc))
        z = np.zeros(nc)
        for i, run in enumerate(self.runs):
            fac = _factor(run, ev.ab[i])
            if fac is None:
                return None
            base.append(_solve(fac, -ev.R[i]))
            cols = np.array([run.rod.ix[node] + c for node in coords[i] for c in range(3)],
                            dtype=np.int64)
            Wi = np.empty((run.rod.n, cols.shape[0]))
            for k, col in enumerate(cols):
                unit = np.zeros(run.rod.n)
                unit[col] = 1.0
                Wi[:, k] = _solve(fac, unit)
            W.append(Wi)
            sl = slice(offset[i], offset[i + 1])
            Z[sl, sl] = Wi[cols]
            z[sl] = base[i][cols]
        # The coupling terms on those coordinates.
        Kc = np.zeros((nc, nc))
        E = np.zeros((nc, m))
        Fm = np.zeros((m, nc))
        G = np.zeros(m)
        rhs_mu = np.zeros(m)
        for c, (p, j, k) in enumerate(rows):
            pair, geo = self.pairs[p], ev.geo[p]
            a = pair.alpha[k]
            y = geo.y[j]
            shape = (bool(geo.left[j]), bool(geo.right[j]), float(geo.beta[j]))
            grad = spline.gradient(y, float(a), *shape)[0]
            fac = self._factors(pair, weight)
            lengths = np.concatenate([np.full(6, self.runs[pair.a].rod.length),
                                      np.full(12, self.runs[pair.b].rod.length)])
            idx = np.array([offset[part] + 3 * slot[part][node] + cc
                            for part, node in nodes_of[c] for cc in range(3)])
            np.add.at(E[:, c], idx, fac * grad)
            mu = mus[p][k]
            if mu != 0.0:
                H = spline.hessian(y, float(a), *shape, _HESSIAN_STEP * pair.reach)
                np.add.at(Kc, (idx[:, None], idx[None, :]),
                          (fac * mu)[:, None] * H * lengths[None, :])
            d_mu, d_g = ev.slopes[p][0][j], ev.slopes[p][1][j]
            np.add.at(Fm[c], idx, d_g * CONTACT_SCALE * grad * lengths / self.L_ref)
            G[c] = d_mu + d_g * CONTACT_SCALE * self.compliance
            rhs_mu[c] = -ev.Rmu[p][k]
        A = np.block([[np.eye(nc) + Z @ Kc, Z @ E], [Fm, np.diag(G)]])
        try:
            sol = np.linalg.solve(A, np.concatenate([z, rhs_mu]))
        except np.linalg.LinAlgError:
            return None
        if not np.all(np.isfinite(sol)):
            return None
        dv, dmu = sol[:nc], sol[nc:]
        push = Kc @ dv + E @ dmu
        du = [base[i] - W[i] @ push[offset[i]:offset[i + 1]] for i in range(P)]
        dmus = [np.zeros_like(mu) for mu in mus]
        for c, (p, _, k) in enumerate(rows):
            dmus[p][k] = dmu[c]
        return du, dmus

    # -- Newton and continuation ------------------------------------------------------
    def newton(self, states: list[State], mus: list[np.ndarray], loads: list[Loads],
               weight: float, *, strict: bool, tol: float):
        """Newton on the coupled system with the touching probes held, the set corrected
        between solves until it holds (a probe touching with a pull lets go, a free
        one that entered the other part touches). A held set that admits no solution (a
        straight element's ends and middle all on a curved surface) shows itself by the
        signs of its forces before its Newton converges: the set is corrected from
        there and the solve starts again from the last point that held. Returns
        (states, mus, residual, converged)."""
        fixed = None
        r = math.inf
        seen: set[bytes] = set()
        for _ in range(_SETS):
            near = [self.near(p, states, mu) for p, mu in zip(self.pairs, mus)]
            ev = self.evaluate(states, mus, loads, weight, near, False)
            if not math.isfinite(ev.residual):
                return states, mus, ev.residual, False
            touching = self._touching(ev, mus, fixed)
            if fixed is not None and all(np.array_equal(a, b) for a, b in zip(touching, fixed)):
                return states, mus, ev.residual, ev.residual <= tol
            key = b"".join(t.tobytes() for t in touching)
            if key in seen:  # the sets cycle: no set holds from here
                return states, mus, ev.residual, False
            seen.add(key)
            fixed = touching
            trial, trial_mus, r, ok = self._held(states, mus, loads, weight, fixed, strict, tol)
            if ok:
                states, mus = trial, trial_mus
                continue
            if not math.isfinite(r):
                return states, mus, r, False
            # Not solved: where did its forces pull? Those probes let go.
            near = [self.near(p, trial, mu) for p, mu in zip(self.pairs, trial_mus)]
            ev = self.evaluate(trial, trial_mus, loads, weight, near, False)
            changed = self._touching(ev, trial_mus, fixed)
            if all(np.array_equal(a, b) for a, b in zip(changed, fixed)):
                return states, mus, r, False
            fixed = changed
            trial, trial_mus, r, ok = self._held(states, mus, loads, weight, fixed, strict, tol)
            if not ok:
                return states, mus, r, False
            states, mus = trial, trial_mus
        return states, mus, r, False

    def _touching(self, ev: _Eval, mus: Sequence[np.ndarray],
                  fixed: list[np.ndarray] | None) -> list[np.ndarray]:
        """The touching set at ``ev``: from scratch, the probes whose force beats their
        gap; from a held set, it less those pulling and with those that went in."""
        out = []
        for p, (pair, geo) in enumerate(zip(self.pairs, ev.geo)):
            t = np.zeros(pair.elem.shape[0], dtype=bool)
            if geo is not None:
                only = ev.near[p]
                m = mus[p][only]
                gs = CONTACT_SCALE * (geo.gap + self.compliance * m)
                if fixed is None:
                    t[only] = m > gs
                else:
                    was = fixed[p][only]
                    t[only] = np.where(was, m >= 0.0, gs < -_PENETRATION)
            out.append(t)
        return out

    def _held(self, states, mus, loads, weight, fixed, strict: bool, tol: float):
        """Damped Newton with the touching set held: a smooth system."""
        near = [self.near(p, states, np.where(f, 1.0, mu))
                for p, mu, f in zip(self.pairs, mus, fixed)]
        ev = self.evaluate(states, mus, loads, weight, near, True, fixed)
        r = ev.residual
        for _ in range(_HELD_ITERATIONS):
            if r <= tol:
                return states, mus, r, True
            if not math.isfinite(r):
                return states, mus, r, False
            self.iterations += 1
            step_dir = self.direction(ev, mus, weight)
            if step_dir is None:
                return states, mus, r, False
            du, dmu = step_dir
            step, accepted = 1.0, False
            for _ in range(30):
                new_states = [run.step(s, d, step) for run, s, d in zip(self.runs, states, du)]
                new_mus = [mu + step * d for mu, d in zip(mus, dmu)]
                new = self.evaluate(new_states, new_mus, loads, weight, near, True, fixed)
                rn = new.residual
                accepted = math.isfinite(rn) and (rn <= (1.0 - 1e-4 * step) * r or rn <= tol)
                if accepted or (strict and step < 0.1):
                    break
                step *= 0.5
            if not accepted:
                return states, mus, r, False
            states, mus, ev, r = new_states, new_mus, new, rn
        return states, mus, r, r <= tol

    def follow(self, members: list[_Member], states: list[State], mus: list[np.ndarray],
               w0: float, w1: float, deadline: float, strict: bool = True):
        """Continuation from (states, mus), an equilibrium of the members' start loads at
        weight w0, to their end loads at weight w1: steps halved where Newton fails,
        secant predictors."""
        opts = self.solver
        t, dt = 0.0, 1.0
        prev = None
        while True:
            if clock.now() > deadline:
                raise _CoupledStall(t, "the time budget of "
                                    f"{opts.time_budget} s ran out", states, mus)
            t_next = min(1.0, t + dt)
            loads = [m.start.lerp(m.end, t_next) for m in members]
            weight = w0 + t_next * (w1 - w0)
            if prev is None:
                guess, guess_mu = states, mus
            else:
                t_prev, s_prev, mu_prev = prev
                f = (t_next - t) / (t - t_prev)
                guess = [run.step(s, run.difference(sp, s), f)
                         for run, s, sp in zip(self.runs, states, s_prev)]
                guess_mu = [mu + f * (mu - mp) for mu, mp in zip(mus, mu_prev)]
                guess_mu = [np.maximum(g, 0.0) for g in guess_mu]
            final = t_next >= 1.0
            tol = opts.tolerance if final else max(opts.tolerance, 1e-7)
            new, new_mu, r, ok = self.newton(guess, guess_mu, loads, weight, strict=strict,
                                             tol=tol)
            if not ok and prev is not None:  # the secant overshot: from the last point
                new, new_mu, r, ok = self.newton(states, mus, loads, weight, strict=strict,
                                                 tol=tol)
            if ok:
                self.steps += 1
                prev = (t, states, mus)
                states, mus, t = new, new_mu, t_next
                if final:
                    return states, mus
                dt = min(1.0 - t, 2.0 * dt)
            else:
                dt *= 0.25
                if dt < 1e-5:
                    raise _CoupledStall(t, f"Newton failed however short the step "
                                        f"(residual {r:.2e}): a fold, or parts driven "
                                        "through each other", states, mus, r)


@dataclass
class _CoupledStall(Exception):
    t: float
    reason: str
    states: list
    mus: list
    residual: float = math.inf


# -- banded solves with the free probes left out ---------------------------------------
def _factor(run: _Run, ab: np.ndarray):
    rod = run.rod
    drop = np.zeros(rod.n, dtype=bool)
    if rod.iprobe.shape[0]:
        drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
        idx = np.nonzero(drop)[0]
        if idx.shape[0]:  # its column must be empty too: its value then moves nothing
            drop[idx[np.count_nonzero(ab[idx], axis=1) != 1]] = False
    c, lo, up, new = band_reduce(ab, rod.kl, rod.ku, drop)
    piv, ok = band_lu(c, lo, up)
    if not ok:
        return None
    return c, lo, up, piv, new >= 0


def _solve(fac, rhs: np.ndarray) -> np.ndarray:
    c, lo, up, piv, keep = fac
    x = rhs.copy()  # a left-out row is the identity's: its unknown is its right side
    x[keep] = band_lu_solve(c, piv, lo, up, np.ascontiguousarray(rhs[keep]))
    return x


# -- results ------------------------------------------------------------------------------
def part_contacts(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray],
                  names: Sequence[str]) -> list[Contacts]:
    """Each part's contacts with the others: rows as an obstacle's, named by the part
    that pushes (force on this part [N])."""
    rows: list[list] = [[] for _ in coupling.runs]
    for pair, mu in zip(coupling.pairs, mus):
        on = np.nonzero(mu > 1e-10 * max(1.0, float(mu.max(initial=0.0))))[0]
        if not on.shape[0]:
            continue
        geo = coupling.geometry(pair, states, on)
        ra, rb = coupling.runs[pair.a].rod, coupling.runs[pair.b].rod
        force = mu[on, None] * geo.n * coupling.F_ref
        e, al = pair.elem[on], pair.alpha[on]
        s_a = (ra.s_node[e] + al * ra.h[e]) * ra.length
        s_b = (rb.s_node[geo.f] + geo.beta * rb.h[geo.f]) * rb.length
        p_a = (1.0 - al[:, None]) * geo.y[:, 0:3] + al[:, None] * geo.y[:, 3:6]
        p_b = geo.q
        for k in range(on.shape[0]):
            rows[pair.a].append((s_a[k], p_a[k], force[k], names[pair.b]))
            rows[pair.b].append((s_b[k], p_b[k], -force[k], names[pair.a]))
    out = []
    for r in rows:
        r.sort(key=lambda row: row[0])
        out.append(Contacts(s=np.array([x[0] for x in r]),
                            point=np.array([x[1] for x in r]).reshape(-1, 3),
                            force=np.array([x[2] for x in r]).reshape(-1, 3),
                            obstacle=tuple(x[3] for x in r)))
    return out


def nodal_loads(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray]
                ) -> list[np.ndarray]:
    """Each part's contact forces from the others as dead nodal forces (N+1, 3), in its
    own units: with them as loads, each part alone is in equilibrium."""
    R = [np.zeros(run.rod.n) for run in coupling.runs]
    for pair, mu in zip(coupling.pairs, mus):
        on = np.nonzero(mu != 0.0)[0]
        if on.shape[0]:
            coupling._forces(pair, coupling.geometry(pair, states, on), on, mu[on], 1.0, R)
    # The residual gained -f at each node's position rows.
    return [-r[run.rod.ix[:, None] + np.arange(3)] for run, r in zip(coupling.runs, R)]


@dataclass(frozen=True, eq=False)
class _WithContacts:
    """A part's sampler with its contacts with the other parts added."""

    inner: _Sampler
    extra: Contacts

    def __call__(self) -> Samples3D:
        samples = self.inner()
        c = samples.contacts
        if not len(self.extra):
            return samples
        merged = Contacts(s=np.concatenate([c.s, self.extra.s]),
                          point=np.concatenate([c.point.reshape(-1, 3), self.extra.point]),
                          force=np.concatenate([c.force.reshape(-1, 3), self.extra.force]),
                          obstacle=tuple(c.obstacle) + tuple(self.extra.obstacle),
                          friction=np.concatenate([c.friction.reshape(-1, 3),
                                                   self.extra.friction]))
        return replace(samples, contacts=merged)


STABILITY_NOTE = ("parts solved together: stability is that of each part with the others' "
                  "contact forces held as loads, not of the coupled system")


def equilibria(coupling: Coupling, states: Sequence[State], mus: Sequence[np.ndarray],
               names: Sequence[str]) -> list[Equilibrium3D]:
    """Each part's equilibrium: its own, with the others' contact forces as dead loads
    (so its residual, reactions and internal forces are the coupled system's), and those
    contacts listed with its obstacles' under the other part's name."""
    loads = nodal_loads(coupling, states, mus)
    contacts = part_contacts(coupling, states, mus, names)
    out = []
    for run, state, f, extra in zip(coupling.runs, states, loads, contacts):
        rod = run.rod
        run.rod = replace(rod, target=replace(rod.target, fnode=rod.target.fnode + f))
        eq = _build(run, state)
        touched = len(extra) > 0
        out.append(replace(eq, sampler=_WithContacts(eq.sampler, extra),
                           notes=eq.notes + ((STABILITY_NOTE,) if touched else ()),
                           stability_check=None if touched else eq.stability_check))
    return out


def close_pairs(rods: Sequence[Rod]) -> list[Pair]:
    """Every pair of parts, probes on the first of each."""
    out = []
    for a in range(len(rods)):
        for b in range(a + 1, len(rods)):
            reach = rods[a].radius + rods[b].radius
            if not reach > 0.0:
                reach = 0.01 * min(rods[a].length, rods[b].length)
            elem, alpha = probes(rods[a], reach)
            out.append(Pair(a, b, elem, alpha, reach))
    return out


def no_contact_forces(pairs: Sequence[Pair]) -> list[np.ndarray]:
    return [np.zeros(p.elem.shape[0]) for p in pairs]


def solve_coupled(runs: list[_Run], states: list[State], *, solver: RodSolver,
                  start: list[Loads] | None = None, mus: list[np.ndarray] | None = None,
                  pairs: list[Pair] | None = None, held_first: bool = True):
    """Solve parts together from ``states`` (each an equilibrium of its ``start`` loads,
    alone or with the others' contact forces ``mus``) to their targets. With
    ``held_first``, the parts after the first start held still under the contact (the
    first sees them as rigid) and let go (weight 0 to 1). Returns (coupling, states,
    mus). Raises ConvergenceError with the residual and how far it got."""
    pairs = close_pairs([r.rod for r in runs]) if pairs is None else pairs
    coupling = Coupling(runs, pairs, solver)
    mus = no_contact_forces(pairs) if mus is None else mus
    start = [r.rod.target for r in runs] if start is None else start
    members = [_Member(run, s, run.rod.target) for run, s in zip(runs, start)]
    deadline = clock.now() + solver.time_budget
    try:
        if held_first:
            fixed = [_Member(run, s, s) for run, s in zip(runs, start)]
            # Nothing moves in this first solve (a damped Newton, not a corrector).
            states, mus = coupling.follow(fixed, states, mus, 0.0, 0.0, deadline, strict=False)
            states, mus = coupling.follow(fixed, states, mus, 0.0, 1.0, deadline)
            members = [_Member(run, s, run.rod.target) for run, s in zip(runs, start)]
        states, mus = coupling.follow(members, states, mus, 1.0, 1.0, deadline)
    except _CoupledStall as stall:
        raise ConvergenceError(
            f"no equilibrium of the parts together: {stall.reason}; stopped at "
            f"{stall.t:.3g} of the way", residual=stall.residual, progress=stall.t) from None
    return coupling, states, mus


# -- a part fitted among flexible parts already assembled --------------------------------
@dataclass(frozen=True, eq=False)
class _TogetherState:
    """What a warm start needs of an equilibrium solved together: each part's rod and
    state (the part being fitted first), the contact forces, the pairs."""

    rods: tuple[Rod, ...]
    states: tuple
    gauges: tuple
    mus: tuple
    pairs: tuple
    fitted: tuple  # the FittedPart of each part after the first


def fitted_of(problem) -> list:
    """The obstacles of ``problem`` that are flexible parts already fitted."""
    return [o for o in problem.obstacles if getattr(o, "fitted", None) is not None]


def solve_fitted(problem, warm_start, solver: RodSolver, follow_only: bool) -> Equilibrium3D:
    """The equilibrium of a part among flexible parts already fitted (obstacles with
    ``fitted``): solved with their tubes as rigid obstacles first; where it touches one,
    it and the parts it touches are solved together from there (those parts let go
    from held still). A warm start that was solved together is followed together."""
    from pliant.models.rod3d.solver import _solve  # noqa: PLC0415

    fitted = fitted_of(problem)
    own = replace(problem, obstacles=tuple(o for o in problem.obstacles if o.fitted is None))
    if warm_start is not None and isinstance(warm_start.state, _TogetherState):
        old = warm_start.state
        if tuple(o.fitted for o in fitted) == old.fitted:
            try:
                return _follow_together(problem, own, old, solver)
            except ConvergenceError:
                if follow_only:
                    raise
        warm_start = None  # the rigid solve below starts cold
    rigid = _solve(problem, warm_start, solver, follow_only, rigid=True)
    touched = sorted({name for name in rigid.contacts.obstacle}
                     & {o.name for o in fitted})
    if not touched:
        return rigid
    parts = [o.fitted for o in fitted if o.name in touched]
    try:
        return _start_together(problem, own, rigid, parts, solver)
    except ConvergenceError as err:
        if follow_only:
            raise
        # Said, not hidden: the answer is the one with those parts held still.
        note = (f"{', '.join(touched)} could not be solved together with the part ({err}); "
                "held rigid here, at rest, its deformation and its clamps' share of the "
                "contact not computed")
        return replace(rigid, notes=rigid.notes + (note,))


def _start_together(problem, own, rigid: Equilibrium3D, parts: list, solver: RodSolver):
    """From the rigid answer: the fitted parts held still under the contact, then let
    go."""
    from pliant.models.rod3d.lowering import lower  # noqa: PLC0415
    from pliant.models.rod3d.solver import _WarmState  # noqa: PLC0415

    first = _Run(lower(own, elements=solver.elements), solver)
    old = rigid.state
    assert isinstance(old, _WarmState)
    X, Q, lam, nu, gam = old.state
    first.gauge_quat = old.gauge_quat
    # (Both rods are of the part, lowered alike: their unknowns' scales are the same.)
    rod = first.rod
    _, _, which, _ = _Run(old.rod, solver).contacts(old.state, old.rod.target)
    names = [old.rod.obstacles.obstacles[o].name if o >= 0 else "" for o in which]
    on_part = np.array([n in {p.name for p in parts} for n in names], dtype=bool)
    if rod.islot.shape[0] == old.rod.islot.shape[0] and rod.slot == old.rod.slot:
        # The same probes: keep their forces on the rigid obstacles, drop those on the
        # fitted parts' tubes (the coupling takes those).
        gam = (gam.reshape(-1, rod.slot) * ~on_part[:, None]).ravel()
    else:
        gam = np.zeros(rod.islot.shape[0])
    runs = [first]
    states = [(X.copy(), Q.copy(), lam.copy(), nu.copy(), gam.copy())]
    for part in parts:
        runs.append(_fitted_run(part, solver))
        states.append(part.equilibrium.state.state)
    pairs = close_pairs([r.rod for r in runs])
    # The rigid answer's contact forces on each fitted part start the coupling's: each
    # probe's force on the nearest probe of the pair (the part is first in its pairs).
    mus = no_contact_forces(pairs)
    s_old = old.rod.s_node[old.rod.probe_elem] + old.rod.probe_a * old.rod.h[old.rod.probe_elem]
    force = old.state[4].reshape(-1, old.rod.slot)[:, 0]
    for pair, mu in zip(pairs, mus):
        if pair.a != 0:
            continue
        s_pair = rod.s_node[pair.elem] + pair.alpha * rod.h[pair.elem]
        mine = on_part & np.array([n == parts[pair.b - 1].name for n in names], dtype=bool)
        for k in np.nonzero(mine & (force > 0.0))[0]:
            mu[int(np.argmin(np.abs(s_pair - s_old[k])))] += force[k]
    coupling, states, mus = solve_coupled(runs, states, solver=solver, held_first=True,
                                          pairs=pairs, mus=mus)
    return _result(problem, coupling, states, mus, parts, rigid.iterations, rigid.steps)


def _fitted_run(part, solver: RodSolver) -> _Run:
    warm = part.equilibrium.state
    run = _Run(warm.rod, replace(solver, elements=part.elements))
    run.gauge_quat = warm.gauge_quat
    return run


def _follow_together(problem, own, old: _TogetherState, solver: RodSolver) -> Equilibrium3D:
    from pliant.models.rod3d.lowering import lower  # noqa: PLC0415

    rod = old.rods[0].retarget(own, solver.elements) or lower(own, elements=solver.elements)
    if rod.key != old.rods[0].key:
        raise ConvergenceError("the mesh changed", residual=math.inf)
    runs = [_Run(rod, solver)] + [_Run(r, solver) for r in old.rods[1:]]
    for run, gauge in zip(runs, old.gauges):
        run.gauge_quat = gauge
    start = [old.rods[0].target] + [r.target for r in old.rods[1:]]
    coupling, states, mus = solve_coupled(runs, list(old.states), solver=solver, start=start,
                                          mus=list(old.mus), pairs=list(old.pairs),
                                          held_first=False)
    return _result(problem, coupling, states, mus, list(old.fitted), 0, 0)


def _result(problem, coupling: Coupling, states, mus, parts, iterations: int,
            steps: int) -> Equilibrium3D:
    # The targets before the contact forces join them as loads (for the warm starts).
    rods = tuple(run.rod for run in coupling.runs)
    gauges = tuple(run.gauge_quat.copy() for run in coupling.runs)
    names = [problem.name or problem.part.name] + [p.name for p in parts]
    eqs = equilibria(coupling, states, mus, names)
    first = replace(eqs[0], problem=problem,
                    iterations=eqs[0].iterations + iterations + coupling.iterations,
                    steps=eqs[0].steps + steps + coupling.steps,
                    state=_TogetherState(rods, tuple(states), gauges, tuple(mus),
                                         tuple(coupling.pairs), tuple(parts)),
                    fitted=tuple(replace(eq, problem=p.problem)
                                 for eq, p in zip(eqs[1:], parts)))
    return first
