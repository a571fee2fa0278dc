"""Several flexible parts solved together: contact between parts, sliding and pivoting
clips, harness junctions. (The routes that use it: ``together``; the links' terms:
``links``; what the answer holds: ``coupled_results``.)

Each part keeps its own discrete rod (its banded KKT system, its obstacles); what joins
them, or holds one in a way its own stations cannot, enters as blocks of border unknowns
of one Newton system:

- contact between parts: for each pair (a, b), a < b, probes along a (the nodes and
  points evenly inside each element, close enough that two tubes cannot cross between
  two by more than PROBE_SAG of their radii), each against b's neutral line taken as the
  Catmull-Rom spline through its nodes: gap g = (|p - q| - r_a - r_b) / L, normal force
  mu >= 0, min(mu, g + C mu) = 0 with a compliant wall (C, core.problem.WALL_COMPLIANCE);
  mu n on the probe's two nodes and -mu n on the segment's: Newton's third law exactly;
- a sliding clip (or ring): a point of the part's cubic B-spline held at the clip, its
  direction held along the axis, the slide sigma and the multipliers unknown; the slide's
  row is the Lagrangian's stationarity in sigma, or Coulomb's stick or slide;
- a junction: a branch's end node and frame held to the part's end's, its force and
  moment unknown;
- a pivoting clip: the station frame's d1 held along the pin.

The Newton system is each part's band plus those blocks, which touch a part only at a
few coordinates (node positions, frame rotations). Each band is factorised once per
iteration and solved for the residual and for a unit load at each touched coordinate
(its compliance there); a dense system on the touched coordinates and the blocks'
unknowns joins them (static condensation: its size is a few times the number of blocks,
not the parts' unknowns). The touching set of the contacts and the clips' friction states
are held within a Newton solve and corrected between solves (a primal-dual active set).
Each part's contacts with the obstacles are not held: as in a part's own Newton, a full
step that changes which of its probes touch is taken (up to ``_SWITCHES`` in a solve),
not judged by the residual of the set it leaves (a harness's junction lifted by a box
stopped there: a probe let go with its force was a residual of thousands).

Units: each part's unknowns keep their own scales (lengths by its L, forces by its
EI / L^2); gaps are by the first part's length and contact forces by its force scale.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from pliant.core.events import NOT_EXHAUSTIVE, Status
from pliant.core.problem import PROBE_SAG, WALL_COMPLIANCE
from pliant.errors import ConvergenceError
from pliant.models import clock, continuation
from pliant.models.banded import band_factor_reduced, band_lu_solve
from pliant.models.continuation import Stalled
from pliant.models.rod3d import kernels, spline
from pliant.models.rod3d.links import Joint, LinkTerms, Pivot, Slider, _Block
from pliant.models.rod3d.lowering import Loads, Rod, State
from pliant.models.rod3d.solver import _SWITCHES, CONTACT_SCALE, RodSolver, Run

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
    friction: float = 0.0  # Coulomb's coefficient between the two parts


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
    run: Run
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
    states: Sequence[State] = ()
    touching: Sequence[np.ndarray] = ()  # per part, its obstacle probes' contact states


@dataclass
class Coupling(LinkTerms):
    """Parts solved together: their runs (each a rod with its own obstacles), the pairs
    of parts that may touch, and the solver's settings. ``weight`` scales the contact
    forces on the second part of every pair (the homotopy from it held still, 0, to the
    physical problem, 1)."""

    runs: list[Run]
    pairs: list[Pair]
    solver: RodSolver
    sliders: list[Slider] = field(default_factory=list)
    joints: list[Joint] = field(default_factory=list)
    pivots: list[Pivot] = field(default_factory=list)
    # Sliding clips with friction: each one's state (0 sticking, +-1 sliding that way)
    # held within a Newton solve, and where the load step started (what sticking keeps).
    slide_mode: dict = field(default_factory=dict)
    slide_ref: dict = field(default_factory=dict)
    # Friction between parts, per pair with friction: ``fric_ref`` where each probe and
    # the point of the other part it touched were when the load step started (probe
    # points (K, 3) [m], that point's four nodes (K, 4) and weights (K, 4), its position
    # (K, 3) [m], the tangent bases (K, 2, 3)); each probe's state: -1 free, 0 sticking,
    # 1 sliding (its force along ``fric_dir``, in the basis).
    fric_ref: dict = field(default_factory=dict)
    fric_mode: dict = field(default_factory=dict)
    fric_dir: dict = field(default_factory=dict)
    iterations: int = 0
    steps: int = 0
    notes: list[str] = field(default_factory=list)

    @property
    def rubbing(self) -> list[int]:
        """The pairs with friction, in the order of their tangential unknowns (after
        every other block's in ``mus``)."""
        return [p for p, pair in enumerate(self.pairs) if pair.friction > 0.0]

    def slot(self, kind: str, k: int) -> int:
        """Where the unknowns of the k-th "slider", "joint" or "pivot" are in ``mus``:
        after the pairs' contact forces, sliders, then joints, then pivots (then the
        tangential forces of the pairs with friction, ``t_slot``)."""
        base = len(self.pairs)
        for name, items in (("slider", self.sliders), ("joint", self.joints),
                            ("pivot", self.pivots)):
            if name == kind:
                return base + k
            base += len(items)
        raise ValueError(f"no block kind {kind!r}")

    def t_slot(self, p: int) -> int:
        """Where pair p's tangential forces (K, 2, flattened) are in ``mus``."""
        return self.slot("pivot", len(self.pivots)) + self.rubbing.index(p)

    def friction_unknowns(self) -> list[np.ndarray]:
        return [np.zeros(2 * self.pairs[p].elem.shape[0]) for p in self.rubbing]

    def hold_friction(self, states: Sequence[State], mus: list[np.ndarray]) -> None:
        """Friction between parts from here on is measured from ``states`` (a load
        step's start): each probe's point, the point of the other part nearest it (a
        material point of that part, followed as it moves) and the tangent basis across
        their normal; the tangential forces found in the old bases are carried into the
        new ones (in place, in ``mus``)."""
        from pliant.models.rod3d.lowering import axis_basis  # noqa: PLC0415

        for p in self.rubbing:
            pair = self.pairs[p]
            geo = self.geometry(pair, states, np.arange(pair.elem.shape[0]))
            al = pair.alpha[:, None]
            pa = (1.0 - al) * geo.y[:, 0:3] + al * geo.y[:, 3:6]
            tau = axis_basis(geo.n)
            slot = self.t_slot(p)
            t = mus[slot].reshape(-1, 2)
            old = self.fric_ref.get(p)
            if old is not None:
                force = np.einsum("ki,kic->kc", t, old[-1])
                t = np.einsum("kic,kc->ki", tau, force)
                mus[slot] = t.ravel()
                if p in self.fric_dir:
                    d = np.einsum("ki,kic->kc", self.fric_dir[p], old[-1])
                    d = np.einsum("kic,kc->ki", tau, d)
                    self.fric_dir[p] = d / np.maximum(np.linalg.norm(d, axis=1,
                                                                     keepdims=True), 1e-300)
            # The weights of b's material point on its four nodes, fixed for the step.
            wb = np.array([spline.weights(float(b), bool(lf), bool(rt))[0]
                           for b, lf, rt in zip(geo.beta, geo.left, geo.right)]).reshape(-1, 4)
            self.fric_ref[p] = (pa, geo.jb.copy(), wb, geo.q.copy(), tau)

    def _rub(self, p: int, states: Sequence[State], k: np.ndarray):
        """For probes k of friction pair p: their slip since the step's start (K, 2, by
        L_ref) in the tangent basis, and the weights on a's two nodes and on b's four
        (the material point of b it touched)."""
        pair = self.pairs[p]
        pa0, jb, wb, qb0, tau = self.fric_ref[p]
        ra, rb = self.runs[pair.a].rod, self.runs[pair.b].rod
        Xa = states[pair.a][0] * ra.length
        Xb = states[pair.b][0] * rb.length
        e, al = pair.elem[k], pair.alpha[k][:, None]
        pa = (1.0 - al) * Xa[e] + al * Xa[e + 1]
        qb = np.einsum("kj,kjc->kc", wb[k], Xb[jb[k]])
        move = (pa - pa0[k]) - (qb - qb0[k])
        slip = np.einsum("kic,kc->ki", tau[k], move) / self.L_ref
        return slip, wb[k], tau[k]

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
        R, ab, touching = [], [], []
        for run, state, load in zip(self.runs, states, loads):
            r, a, _, active = run.terms(state, load, want_jac)
            R.append(r)
            ab.append(a if want_jac else None)
            touching.append(active)
        Rmu: list[np.ndarray] = []
        geos: list[_Geometry | None] = []
        actives: list[np.ndarray] = []
        slopes: list = []
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
        out_of_clip = False
        for k in range(len(self.sliders)):
            rows, forces, nodes = self._slider_terms(k, states, mus, weight)[:3]
            if rows is None:  # the part slid out of the clip
                out_of_clip = True
                Rmu.append(np.full(6, math.inf))
                continue
            ix = self.runs[self.sliders[k].part].rod.ix
            for j, (_, node) in enumerate(nodes):
                R[self.sliders[k].part][ix[node]:ix[node] + 3] += forces[3 * j:3 * j + 3]
            Rmu.append(rows)
        for k in range(len(self.joints)):
            rows, forces = self._joint_terms(k, states, mus, weight)[:2]
            for (part, first), f in zip(self._joint_coords(k), forces):
                R[part][first:first + 3] += f
            Rmu.append(rows)
        for k in range(len(self.pivots)):
            rows, torque = self._pivot_terms(k, states, mus, weight)[:2]
            first = self._pivot_coord(k)
            R[0][first:first + 3] += torque
            Rmu.append(rows)
        for p in self.rubbing:
            Rmu.append(self._friction_terms(p, states, mus, weight, near[p],
                                            actives[p] if p < len(actives) else None, R))
        residual = max([float(np.abs(r).max(initial=0.0)) for r in R]
                       + [float(np.abs(r).max(initial=0.0)) for r in Rmu])
        if deep or out_of_clip:  # one tube half through the other, or out of a clip
            residual = math.inf
        return _Eval(R, ab, Rmu, geos, actives, list(near), residual, slopes, states,
                     touching)

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
    def blocks(self, ev: _Eval, mus: Sequence[np.ndarray], weight: float,
               sliding: bool = False) -> list[_Block]:
        """Every border block of the system at ``ev``: the contacts, the clips, the
        junctions, the pivots and the friction between parts. ``sliding``: each contact's
        curvature term as its point's, not its probe's (``_contact_blocks``)."""
        return self._contact_blocks(ev, mus, weight, sliding) + [
            self._slider_terms(k, ev.states, mus, weight, want_jac=True)[3]
            for k in range(len(self.sliders))] + [
            self._joint_terms(k, ev.states, mus, weight, want_jac=True)[2]
            for k in range(len(self.joints))] + [
            self._pivot_terms(k, ev.states, mus, weight, want_jac=True)[2]
            for k in range(len(self.pivots))] + self._friction_blocks(ev, mus, weight)

    def direction(self, ev: _Eval, mus: Sequence[np.ndarray], weight: float):
        """The Newton step (per part du, per pair or clip d mu) or None where singular."""
        blocks = self.blocks(ev, mus, weight)
        bands = [a for a in ev.ab if a is not None]
        assert len(bands) == len(self.runs)  # evaluated with its Jacobian
        return self.solved(bands, blocks, [-r for r in ev.R],
                           [-ev.Rmu[b.target[0]][b.target[1]] for b in blocks], mus)

    def solved(self, bands: Sequence[np.ndarray], blocks: Sequence[_Block],
               rhs: Sequence[np.ndarray], rows: Sequence[np.ndarray],
               mus: Sequence[np.ndarray]):
        """The system of the parts' ``bands`` (overwritten) and ``blocks`` solved for
        the parts' right sides ``rhs`` and the blocks' ``rows``: (du per part, d mu per
        pair or clip, zero where no block acts), or None where singular."""
        system = Condensed.of(self.runs, bands, blocks)
        if system is None:
            return None
        out = system.solve(rhs, rows)
        if out is None:
            return None
        du, dw = out
        dmus = [np.zeros_like(mu) for mu in mus]
        at = 0
        for b in blocks:
            nb = b.D.shape[0]
            dmus[b.target[0]][b.target[1]] = dw[at:at + nb]
            at += nb
        return du, dmus

    # -- friction between parts -----------------------------------------------------------
    def _friction_modes(self, p: int, active: np.ndarray | None, only: np.ndarray):
        """Each probe's friction state in ``only`` (-1 where it does not touch)."""
        K = self.pairs[p].elem.shape[0]
        mode = self.fric_mode.get(p, np.full(K, -1))[only]
        if active is None or not active.shape[0]:
            return np.full(only.shape[0], -1)
        return np.where(active, np.where(mode < 0, 0, mode), -1)

    def _friction_terms(self, p: int, states, mus, weight: float, only: np.ndarray,
                        active: np.ndarray | None, R: list[np.ndarray]) -> np.ndarray:
        """Pair p's tangential rows (K * 2): a free probe's force, a sticking one's slip,
        a sliding one's force less mu times its normal force along its direction; and
        their forces on both parts' nodes (in R)."""
        pair = self.pairs[p]
        t = mus[self.t_slot(p)].reshape(-1, 2)
        rows = t.copy()  # every probe not looked at: its force (0)
        if p not in self.fric_ref or not only.shape[0]:
            return rows.ravel()
        mode = self._friction_modes(p, active, only)
        slip, wb, tau = self._rub(p, states, only)
        mu_n = mus[p][only]
        d = self.fric_dir.get(p, np.zeros((pair.elem.shape[0], 2)))[only]
        # (A sticking probe gives as the walls do, compliance times its force: probes
        # stuck along a wrapped span are otherwise dependent constraints.)
        rows[only] = np.where((mode == 0)[:, None], slip + self.compliance * t[only],
                              np.where((mode == 1)[:, None],
                                       t[only] - pair.friction * mu_n[:, None] * d, t[only]))
        force = np.einsum("ki,kic->kc", t[only], tau)  # on a, by F_ref
        ra, rb = self.runs[pair.a].rod, self.runs[pair.b].rod
        e, al = pair.elem[only], pair.alpha[only]
        fa = -self.F_ref / ra.force_scale
        fb = weight * self.F_ref / rb.force_scale
        jb = self.fric_ref[p][1][only]
        for c in range(3):
            np.add.at(R[pair.a], ra.ix[e] + c, fa * (1.0 - al) * force[:, c])
            np.add.at(R[pair.a], ra.ix[e + 1] + c, fa * al * force[:, c])
            for j in range(4):
                np.add.at(R[pair.b], rb.ix[jb[:, j]] + c, fb * wb[:, j] * force[:, c])
        return rows.ravel()

    def _friction_blocks(self, ev: _Eval, mus, weight: float) -> list:
        out = []
        for p in self.rubbing:
            pair = self.pairs[p]
            if p not in self.fric_ref:
                continue
            only = ev.near[p]
            active = ev.active[p] if ev.geo[p] is not None else None
            t = mus[self.t_slot(p)].reshape(-1, 2)
            mode = self._friction_modes(p, active, only)
            keep = np.nonzero((mode >= 0) | np.any(t[only] != 0.0, axis=1))[0]
            if not keep.shape[0]:
                continue
            _, wb, tau = self._rub(p, ev.states, only[keep])
            ra, rb = self.runs[pair.a].rod, self.runs[pair.b].rod
            fa = -self.F_ref / ra.force_scale
            fb = weight * self.F_ref / rb.force_scale
            jb = self.fric_ref[p][1]
            slot = self.t_slot(p)
            for i, j in enumerate(keep):
                k = int(only[j])
                e, al = int(pair.elem[k]), float(pair.alpha[k])
                coords = [(pair.a, int(ra.ix[e])), (pair.a, int(ra.ix[e + 1]))] + [
                    (pair.b, int(rb.ix[n])) for n in jb[k]]
                w = np.concatenate([[1.0 - al, al], wb[i]])
                scale = np.array([fa, fa, fb, fb, fb, fb])
                E = np.zeros((18, 2))
                F = np.zeros((2, 18))
                for n in range(6):
                    E[3 * n:3 * n + 3] = (scale[n] * w[n]) * tau[i].T
                D = np.eye(2)
                if mode[j] == 0:  # sticking: the slip's rows
                    lengths = [ra.length] * 2 + [rb.length] * 4
                    sign = [1.0] * 2 + [-1.0] * 4
                    for n in range(6):
                        F[:, 3 * n:3 * n + 3] = (sign[n] * w[n] * lengths[n]
                                                 / self.L_ref) * tau[i]
                    D = self.compliance * np.eye(2)
                out.append(_Block(coords, E, F, D, np.zeros((18, 18)),
                                  (slot, slice(2 * k, 2 * k + 2))))
        return out

    def update_friction(self, ev: _Eval, mus, touching: list[np.ndarray]) -> bool:
        """Correct each probe's friction state between Newton solves (Coulomb): a probe
        that touches sticks; a sticking one whose force beats mu times its normal force
        slides along its force; a sliding one that slips along its force sticks, else its
        direction follows its slip. Returns whether any changed."""
        changed = False
        for p in self.rubbing:
            pair = self.pairs[p]
            K = pair.elem.shape[0]
            mode = self.fric_mode.get(p, np.full(K, -1)).copy()
            d = self.fric_dir.get(p, np.zeros((K, 2))).copy()
            t = mus[self.t_slot(p)].reshape(-1, 2)
            new = np.where(touching[p], np.where(mode < 0, 0, mode), -1)
            on = np.nonzero(touching[p] & (mode >= 0))[0]
            if on.shape[0] and p in self.fric_ref:
                slip = self._rub(p, ev.states, on)[0]
                limit = pair.friction * mus[p][on]
                size = np.linalg.norm(t[on], axis=1)
                for i, k in enumerate(on):
                    if mode[k] == 0 and size[i] > limit[i] * (1.0 + 1e-9) + 1e-12:
                        new[k] = 1
                        d[k] = t[k] / size[i]
                    elif mode[k] == 1:
                        s = slip[i]
                        n_s = float(np.linalg.norm(s))
                        if n_s > 1e-13 and float(s @ d[k]) > 0.0:
                            new[k] = 0  # slipping with its force: friction holds
                        elif n_s > 1e-13:
                            turned = -s / n_s
                            if np.linalg.norm(turned - d[k]) > 1e-6:
                                d[k] = turned
                                changed = True
            if not np.array_equal(new, mode):
                changed = True
            self.fric_mode[p] = new
            self.fric_dir[p] = d
        return changed

    def _contact_blocks(self, ev: _Eval, mus: Sequence[np.ndarray], weight: float,
                        sliding: bool = False) -> list:
        """A block per contact in the system: touching ones, and any with a force still
        on (a probe with no force and an open gap has the row d mu = 0: left out).

        ``sliding`` (the stability test's): a probe is a fixed point of its part, whose
        distance to the other part grows as the other slides along it (by the slip
        squared over 2 d, a softening -f / d the contact's force gives that slip); the
        real contact's point slides with it and two crossing tubes keep their distance.
        Where the least of that distance along the part lies within an element of the
        probe, the curvature term is the nearest point's (``spline.slide``): a line clamped across
        a soft hose was found to slide the hose from under it (an eigenvalue -0.68 m
        times the contact force) where both are stable."""
        out = []
        for p, (pair, geo) in enumerate(zip(self.pairs, ev.geo)):
            if geo is None:
                continue
            only = ev.near[p]
            m = mus[p][only]
            fac = self._factors(pair, weight)
            lengths = np.concatenate([np.full(6, self.runs[pair.a].rod.length),
                                      np.full(12, self.runs[pair.b].rod.length)])
            for j in np.nonzero((m != 0.0) | (ev.slopes[p][1] != 0.0))[0]:
                k = int(only[j])
                a = float(pair.alpha[k])
                y = geo.y[j]
                shape = (bool(geo.left[j]), bool(geo.right[j]), float(geo.beta[j]))
                grad = spline.gradient(y, a, *shape)[0]
                e = int(pair.elem[k])
                ia, ib = self.runs[pair.a].rod.ix, self.runs[pair.b].rod.ix
                nodes = [(pair.a, int(ia[e])), (pair.a, int(ia[e + 1]))] + [
                    (pair.b, int(ib[x])) for x in geo.jb[j]]
                K = np.zeros((18, 18))
                if m[j] != 0.0:
                    H = spline.hessian(y, a, *shape, _HESSIAN_STEP * pair.reach)
                    if sliding:
                        star, d2, c = spline.slide(y, a, *shape, _HESSIAN_STEP * pair.reach)
                        last = self.runs[pair.a].rod.elements - 1
                        # (the least within an element of the probe, the part going on
                        # there: past its end, a tip pressed is what it is)
                        if (d2 > 0.0 and abs(star - a) <= 1.0 and (star > 0.0 or e > 0)
                                and (star < 1.0 or e < last)):
                            H = H - np.outer(c, c) / d2
                    K = (fac * m[j])[:, None] * H * lengths[None, :]
                d_mu, d_g = ev.slopes[p][0][j], ev.slopes[p][1][j]
                out.append(_Block(
                    nodes, (fac * grad)[:, None],
                    (d_g * CONTACT_SCALE * grad * lengths / self.L_ref)[None, :],
                    np.array([[d_mu + d_g * CONTACT_SCALE * self.compliance]]), K,
                    (p, slice(k, k + 1))))
        return out

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
            modes = self._slide_modes(states, mus) if weight >= 1.0 else self.slide_mode
            rubbed = self.update_friction(ev, mus, touching) if self.rubbing else False
            if (fixed is not None and modes == self.slide_mode and not rubbed
                    and all(np.array_equal(a, b) for a, b in zip(touching, fixed))):
                return states, mus, ev.residual, ev.residual <= tol
            self.slide_mode = modes
            key = (b"".join(t.tobytes() for t in touching) + repr(sorted(modes.items())).encode()
                   + b"".join(self.fric_mode[p].tobytes() + self.fric_dir[p].round(6).tobytes()
                              for p in self.rubbing))
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

    def _slide_modes(self, states: Sequence[State], mus: Sequence[np.ndarray]) -> dict:
        """The sliding clips' friction states that hold at (states, mus): a sticking
        clip whose axial force G beats mu N slides (against G); a sliding one that went
        back sticks."""
        out = {}
        for k, sl in enumerate(self.sliders):
            if not sl.clip.friction > 0.0:
                continue
            w = mus[self.slot("slider", k)]
            sigma = float(w[0])
            mode = self.slide_mode.get(k, 0)
            if not 0.0 <= sigma <= 1.0:
                out[k] = mode
                continue
            f, _, y = self._slider_at(k, states, sigma)
            _, J = self._slider_E(k, y, sigma, f)
            nu = w[1:1 + sl.rows]
            G = float(nu @ J[:, 12])
            N = float(np.linalg.norm(nu[:3] - (nu[:3] @ sl.axis) * sl.axis))
            if mode == 0:
                out[k] = (-1 if G > 0.0 else 1) if abs(G) > sl.clip.friction * N * (
                    1.0 + 1e-9) + 1e-12 else 0
            else:
                moved = sigma - self.slide_ref.get(k, sl.s0)
                out[k] = 0 if moved * mode < 0.0 else mode
        return out

    def touching(self, ev: _Eval, mus: Sequence[np.ndarray]) -> list[np.ndarray]:
        """The touching set at ``ev``, from scratch (per pair, a flag per probe)."""
        return self._touching(ev, mus, None)

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
        switches = 0
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
                if (not accepted and step == 1.0 and switches < _SWITCHES and math.isfinite(rn)
                        and self._switched(ev, states, new)):
                    # The obstacles' probes are not held: a full step that changes which
                    # probes touch an obstacle, or gives one its first force, is taken as
                    # the part's own Newton takes it (``contact_kernels.newton_contact``):
                    # the residual of the set it leaves is no measure of the step.
                    switches += 1
                    accepted = True
                if accepted or (strict and step < 0.1):
                    break
                step *= 0.5
            if not accepted or (strict and step < 0.1):
                # A corrector crawling in short steps is far from its basin: the
                # continuation does better with a shorter load step.
                return states, mus, r, False
            states, mus, ev, r = new_states, new_mus, new, rn
        return states, mus, r, r <= tol

    def _switched(self, before: _Eval, states: Sequence[State], after: _Eval) -> bool:
        """Whether a step from ``before`` (at ``states``) to ``after`` changed which
        probes touch an obstacle, or started from a touching probe with no force yet (it
        takes its first in this step)."""
        for run, state, a, b in zip(self.runs, states, before.touching, after.touching):
            if not a.shape[0]:
                continue
            gam = state[4][::run.rod.slot]
            if ((a != 0) & (gam == 0.0)).any() or not np.array_equal(a != 0, b != 0):
                return True
        return False

    def direction_at(self, members: list[_Member], states: list[State],
                     mus: list[np.ndarray], w0: float, w1: float):
        """The path's tangent at its start, (du, dmu) per unit of t: J d/dt (u) = -dR/dt,
        dR/dt by a forward difference (the first predictor; secants after it). None
        where the start is singular."""
        eps = 1e-7
        near = [self.near(p, states, mu) for p, mu in zip(self.pairs, mus)]
        here = [m.start for m in members]
        ahead = [m.start.lerp(m.end, eps) for m in members]
        fixed = self._touching(self.evaluate(states, mus, here, w0, near, False), mus, None)
        a = self.evaluate(states, mus, here, w0, near, True, fixed)
        b = self.evaluate(states, mus, ahead, w0 + eps * (w1 - w0), near, False, fixed)
        a.R = [(rb - ra) / eps for ra, rb in zip(a.R, b.R)]
        a.Rmu = [(rb - ra) / eps for ra, rb in zip(a.Rmu, b.Rmu)]
        try:
            out = self.direction(a, mus, w0)
        except (np.linalg.LinAlgError, FloatingPointError):
            return None
        return out

    def follow(self, members: list[_Member], states: list[State], mus: list[np.ndarray],
               w0: float, w1: float, deadline: float, strict: bool = True):
        """Continuation from (states, mus), an equilibrium of the members' start loads at
        weight w0, to their end loads at weight w1, by the shared driver
        (``continuation.follow``): steps doubled after each success and cut where Newton
        fails (after one more try from the last point), secant predictors."""
        return continuation.follow(self, _Leg(members, w0, w1), (states, mus),
                                   self.stepping, deadline, strict=strict,
                                   need_tangent=False)

    # -- what the shared driver asks (continuation.Continuable) --------------------------
    @property
    def stepping(self) -> continuation.Stepping:
        opts = self.solver
        return continuation.Stepping(
            tolerance=opts.tolerance, loose=max(opts.tolerance, 1e-7), min_step=1e-5,
            max_steps=None, grow=None, retry_from_last=True, time_budget=opts.time_budget,
            fold_hint=", or parts driven through each other")

    def correct(self, predictor: tuple, loads: tuple, *, strict: bool, tol: float | None
                ) -> tuple[tuple, float, Status]:
        states, mus = predictor
        tol = self.solver.tolerance if tol is None else tol
        new, new_mu, r, ok = self.newton(states, mus, loads[0], loads[1], strict=strict,
                                         tol=tol)
        return (new, new_mu), r, Status.CONVERGED if ok else Status.FOLD

    def tangent(self, state: tuple, path: _Leg) -> tuple | None:
        states, mus = state
        return self.direction_at(path.members, states, mus, path.w0, path.w1)

    def step(self, state: tuple, du: tuple, scale: float) -> tuple:
        (states, mus), (dus, dmus) = state, du
        moved = [mu + scale * d for mu, d in zip(mus, dmus)]
        return ([run.step(s, d, scale) for run, s, d in zip(self.runs, states, dus)],
                [np.maximum(g, 0.0) if i < len(self.pairs) else g  # contact forces push
                 for i, g in enumerate(moved)])

    def difference(self, a: tuple, b: tuple) -> tuple:
        return ([run.difference(sa, sb) for run, sa, sb in zip(self.runs, a[0], b[0])],
                [mb - ma for ma, mb in zip(a[1], b[1])])

    def miss(self, predicted: tuple, corrected: tuple) -> float:
        return 0.0  # the steps double: no distance aimed at

    def load_size(self, path: _Leg) -> tuple[float, float]:
        return 0.0, 0.0

    def begin_step(self, state: tuple) -> tuple:
        """Friction in sliding clips, and between parts, is measured from where this
        step starts."""
        states, mus = state
        self.slide_ref = {k: float(mus[self.slot("slider", k)][0])
                          for k in range(len(self.sliders))}
        if self.rubbing:
            mus = [m.copy() for m in mus]
            self.hold_friction(states, mus)
        return states, mus

    def memo(self) -> None:
        return None


@dataclass(frozen=True)
class _Leg:
    """The coupled homotopy: each member's loads from its start to its end, and the
    weight of the contact forces on the second part of every pair from w0 to w1."""

    members: list[_Member]
    w0: float
    w1: float

    @property
    def end(self) -> tuple[list[Loads], float]:
        return self.at(1.0)

    def at(self, t: float) -> tuple[list[Loads], float]:
        return ([m.start.lerp(m.end, t) for m in self.members],
                self.w0 + t * (self.w1 - self.w0))


@dataclass
class Condensed:
    """The coupled Newton system (each part's band and the border blocks), factorised
    once and solved for any right-hand side by static condensation: each band is solved
    for its part's right side and for a unit load at each coordinate a block touches
    (its compliance there), and a dense system on those coordinates and the blocks'
    unknowns joins them (its size a few times the number of blocks, not the parts'
    unknowns). The Newton step's solve (``Coupling.direction``) and the coupled
    stability's shift-invert (``coupled_stability``) share it."""

    factors: list
    cols: list[np.ndarray]  # per part, its unknowns that are coupling coordinates
    offset: np.ndarray  # where each part's coordinates start among them
    W: list[np.ndarray]  # per part, its band's solution for each unit load
    Kc: np.ndarray
    E: np.ndarray
    lu: tuple  # the dense system's LU (scipy.linalg.lu_factor)

    @classmethod
    def of(cls, runs: Sequence[Run], bands: Sequence[np.ndarray],
           blocks: Sequence[_Block]) -> Condensed | None:
        """Factorise the parts' bands (``bands``, overwritten) and the blocks; None where
        a band or the joined system is singular."""
        from scipy.linalg import lu_factor  # noqa: PLC0415 (scipy.linalg: loaded by now)

        P = len(runs)
        slot: list[dict[int, int]] = [{} for _ in range(P)]
        coords: list[list[int]] = [[] for _ in range(P)]
        for b in blocks:
            for part, first in b.coords:
                if first not in slot[part]:
                    slot[part][first] = len(coords[part])
                    coords[part].append(first)
        offset = np.concatenate([[0], np.cumsum([3 * len(c) for c in coords])]).astype(int)
        nc = int(offset[-1])
        sizes = [b.D.shape[0] for b in blocks]
        m = sum(sizes)
        factors, W = [], []
        cols = [np.array([first + c for first in coords[i] for c in range(3)], dtype=np.int64)
                for i in range(P)]
        Z = np.zeros((nc, nc))
        for i, run in enumerate(runs):
            fac = _factor(run, bands[i])
            if fac is None:
                return None
            factors.append(fac)
            Wi = np.empty((run.rod.n, cols[i].shape[0]))
            for k, col in enumerate(cols[i]):
                unit = np.zeros(run.rod.n)
                unit[col] = 1.0
                Wi[:, k] = _solve(fac, unit)
            W.append(Wi)
            sl = slice(offset[i], offset[i + 1])
            Z[sl, sl] = Wi[cols[i]]
        # The blocks' terms on those coordinates.
        Kc = np.zeros((nc, nc))
        E = np.zeros((nc, m))
        Fm = np.zeros((m, nc))
        D = np.zeros((m, m))
        at = 0
        for b, nb in zip(blocks, sizes):
            idx = np.array([offset[part] + 3 * slot[part][first] + c
                            for part, first in b.coords for c in range(3)])
            block = slice(at, at + nb)
            np.add.at(E, (idx[:, None], np.arange(at, at + nb)[None, :]), b.E)
            np.add.at(Fm, (np.arange(at, at + nb)[:, None], idx[None, :]), b.F)
            np.add.at(Kc, (idx[:, None], idx[None, :]), b.K)
            D[block, block] = b.D
            at += nb
        A = np.block([[np.eye(nc) + Z @ Kc, Z @ E], [Fm, D]])
        if not np.all(np.isfinite(A)):
            return None
        with warnings.catch_warnings():  # (singular: said by its zero pivot, below)
            warnings.simplefilter("ignore")
            lu = lu_factor(A, check_finite=False)
        if not np.all(np.isfinite(lu[0])) or np.any(np.diag(lu[0]) == 0.0):
            return None
        return cls(factors, cols, offset, W, Kc, E, lu)

    def solve(self, rhs: Sequence[np.ndarray], rows: Sequence[np.ndarray]
              ) -> tuple[list[np.ndarray], np.ndarray] | None:
        """(du per part, the blocks' unknowns) for the parts' right sides ``rhs`` and the
        blocks' ``rows``; None where not finite."""
        from scipy.linalg import lu_solve  # noqa: PLC0415

        base = [_solve(fac, r) for fac, r in zip(self.factors, rhs)]
        z = np.concatenate([b[c] for b, c in zip(base, self.cols)] + [np.zeros(0)])
        sol = lu_solve(self.lu, np.concatenate([z, *rows]), check_finite=False)
        if not np.all(np.isfinite(sol)):
            return None
        nc = int(self.offset[-1])
        dv, dw = sol[:nc], sol[nc:]
        push = self.Kc @ dv + self.E @ dw
        du = [base[i] - self.W[i] @ push[self.offset[i]:self.offset[i + 1]]
              for i in range(len(base))]
        return du, dw


def _factor(run: Run, ab: np.ndarray):
    rod = run.rod
    drop = np.zeros(rod.n, dtype=bool)
    if rod.iprobe.shape[0]:
        drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
        idx = np.nonzero(drop)[0]
        if idx.shape[0]:  # its column must be empty too: its value then moves nothing
            drop[idx[np.count_nonzero(ab[idx], axis=1) != 1]] = False
    c, lo, up, new, piv, ok = band_factor_reduced(ab, rod.kl, rod.ku, drop)
    if not ok:
        return None
    return c, lo, up, piv, new >= 0


def _solve(fac, rhs: np.ndarray) -> np.ndarray:
    c, lo, up, piv, keep = fac
    x = rhs.copy()  # a left-out row is the identity's: its unknown is its right side
    x[keep] = band_lu_solve(c, piv, lo, up, np.ascontiguousarray(rhs[keep]))
    return x


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


def solve_coupled(runs: list[Run], states: list[State], *, solver: RodSolver,
                  start: list[Loads] | None = None, mus: list[np.ndarray] | None = None,
                  pairs: list[Pair] | None = None, sliders: list[Slider] | None = None,
                  joints: list[Joint] | None = None, pivots: list[Pivot] | None = None,
                  held_first: bool = True, friction: tuple = ()):
    """Solve parts together from ``states`` (each an equilibrium of its ``start`` loads,
    alone or with the others' contact forces and the clips' multipliers ``mus``) to their
    targets. With ``held_first``, the parts after the first start held still under the
    contact (the first sees them as rigid) and the sliding clips where they are, and are
    let go (weight 0 to 1). Returns (coupling, states, mus). Raises ConvergenceError
    with the residual and how far it got."""
    pairs = close_pairs([r.rod for r in runs]) if pairs is None else pairs
    sliders = sliders or []
    joints = joints or []
    pivots = pivots or []
    coupling = Coupling(runs, pairs, solver, sliders, joints, pivots)
    if friction:  # a warm start's friction references and states
        coupling.fric_ref, coupling.fric_mode, coupling.fric_dir = (dict(x) for x in friction)
    if mus is None:
        mus = (no_contact_forces(pairs) + [np.concatenate([[sl.s0], np.zeros(5)])
                                           for sl in sliders]
               + [np.zeros(6) for _ in joints] + [np.zeros(2) for _ in pivots])
    if len(mus) == coupling.slot("pivot", len(pivots)):  # none for friction yet
        mus = list(mus) + coupling.friction_unknowns()
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
    except Stalled as stall:
        raise ConvergenceError(
            f"no equilibrium of the parts together reached: {stall.reason}; stopped at "
            f"{stall.t:.3g} of the way ({NOT_EXHAUSTIVE})", residual=stall.residual,
            progress=stall.t,
            status=stall.status) from None
    return coupling, states, mus
