"""What holds a part in a way its own stations cannot, solved with the parts
(``coupled``): sliding clips, harness junctions and pivoting clips, and their terms in
the coupled Newton system (``LinkTerms``, a part of ``coupled.Coupling``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pliant.core.problem import PivotClip, SlidingClip
from pliant.core.rotations import qconj, qmul, quat_matrix
from pliant.models.rod3d import spline
from pliant.models.rod3d.kernels import qexp as _qexp
from pliant.models.rod3d.lowering import State
from pliant.models.rod3d.solver import Run


@dataclass
class _Block:
    """Border unknowns of the condensed Newton system (a contact's force; a sliding
    clip's slide and multipliers; a junction's multipliers) and the coupling coordinates
    they touch: ``coords`` (part, the first of three unknowns of that part: a node's
    position or a frame's rotation); E (3n, nb) the residual's change on those
    coordinates per unknown; F (nb, 3n) and D (nb, nb) the block's rows' change per
    coordinate and per unknown; K (3n, 3n) the residual's change per coordinate;
    target (index in mus, slice): its unknowns, whose rows in ``_Eval.Rmu`` are the
    system's right-hand side there (the residual's, or dR/dt for the tangent)."""

    coords: list
    E: np.ndarray
    F: np.ndarray
    D: np.ndarray
    K: np.ndarray
    target: tuple


@dataclass(frozen=True, eq=False)
class Slider:
    """A sliding clip (``core.problem.SlidingClip``) on part ``part``, in that part's
    units: point (3,) its position by L, basis (2, 3) two directions across its axis,
    s0 where along the part it starts (by L). Its unknowns (6): the slide sigma (s / L
    at the clip) and the multipliers of position (3) and direction (2)."""

    part: int
    clip: SlidingClip
    point: np.ndarray
    basis: np.ndarray
    s0: float

    @property
    def axis(self) -> np.ndarray:
        return np.asarray(self.clip.axis, dtype=float)

    @property
    def rows(self) -> int:
        """Its constraints: position, and direction when it holds the axis."""
        return 5 if self.clip.holds_axis else 3


@dataclass(frozen=True, eq=False)
class Joint:
    """A junction: part b's end node ``end_b`` held rigidly to part a's end node
    ``end_a`` (a harness's Y-piece, of no size): at the same point, b's end frame turned
    from a's by ``q_rel``. Its unknowns (6): the force (by F_ref) and moment (by F_ref
    L_ref) it passes. ``gap`` [m] and ``turn`` are b's end's offset and relative
    rotation where the parts start apart (each alone): the homotopy closes them."""

    name: str
    a: int
    end_a: int
    b: int
    end_b: int
    q_rel: np.ndarray
    gap: np.ndarray
    turn: np.ndarray


@dataclass(frozen=True, eq=False)
class Pivot:
    """A pivoting clip (``core.problem.PivotClip``) on part 0: its station's frame keeps
    its first axis d1 along the pin ``pin`` (turning from ``start``, d1 where the part
    starts, as the weight goes 0 to 1). Its unknowns (2): the multipliers, moments
    across the pin (by the part's moment scale)."""

    clip: PivotClip
    frame: int  # the station's frame in the part's rod
    start: np.ndarray
    pin: np.ndarray


# -- banded solves with the free probes left out ---------------------------------------
def _frame_hessian(jacobian, frames: tuple[np.ndarray, ...], mult: np.ndarray,
                   step: float = 1e-6) -> np.ndarray:
    """mult . d(jacobian)/d(theta) over material increments theta of each frame in turn
    (3 per frame), by central differences of the exact Jacobian, symmetrised: the
    geometric stiffness of a constraint on frame rotations (junctions, pivots)."""
    size = 3 * len(frames)
    H = np.empty((size, size))
    for c in range(size):
        d = np.zeros(3)
        d[c % 3] = step
        e = _qexp(d)
        plus, minus = list(frames), list(frames)
        plus[c // 3] = qmul(frames[c // 3], e)
        minus[c // 3] = qmul(frames[c // 3], qconj(e))
        H[c] = mult @ (jacobian(*plus) - jacobian(*minus)) / (2 * step)
    return 0.5 * (H + H.T)


class LinkTerms:
    """The links' residuals and Jacobian blocks, as ``coupled.Coupling`` has them (its
    parts' runs and the links it holds)."""

    runs: list[Run]
    sliders: list[Slider]
    joints: list[Joint]
    pivots: list[Pivot]
    slide_mode: dict
    slide_ref: dict

    if TYPE_CHECKING:  # Coupling's: the unknowns' numbering and the system's scales
        def slot(self, kind: str, k: int) -> int: ...

        @property
        def L_ref(self) -> float: ...

        @property
        def F_ref(self) -> float: ...

    # -- sliding clips ------------------------------------------------------------------
    def _slider_at(self, k: int, states: Sequence[State], sigma: float):
        """The segment of the clip's part at the slide sigma, its four nodes and their
        positions (12,), by L."""
        sl = self.sliders[k]
        rod = self.runs[sl.part].rod
        N = rod.elements
        f = int(np.clip(np.searchsorted(rod.s_node, sigma, side="right") - 1, 0, N - 1))
        jb = np.clip(np.arange(f - 1, f + 3), 0, N)
        return f, jb, states[sl.part][0][jb].ravel()

    def _slider_E(self, k: int, y: np.ndarray, sigma: float, f: int):
        """The clip's constraints (position, direction) at the nodes y and slide sigma on
        segment f, and their Jacobian (rows, 13): by the 12 coordinates, then sigma."""
        sl = self.sliders[k]
        rod = self.runs[sl.part].rod
        h = rod.h[f]
        w, w1, w2 = spline.bspline_weights((sigma - rod.s_node[f]) / h, f == 0,
                                           f == rod.elements - 1)
        Y = y.reshape(4, 3)
        q, qb, qbb = w @ Y, w1 @ Y, w2 @ Y
        norm = math.sqrt(float(qb @ qb))
        t = qb / norm
        P = (np.eye(3) - np.outer(t, t)) / norm
        rows = sl.rows
        E = np.empty(rows)
        J = np.zeros((rows, 13))
        E[:3] = q - sl.point
        for j in range(4):
            J[:3, 3 * j:3 * j + 3] = w[j] * np.eye(3)
        J[:3, 12] = qb / h
        if rows == 5:
            E[3:] = sl.basis @ t
            bP = sl.basis @ P
            for j in range(4):
                J[3:, 3 * j:3 * j + 3] = w1[j] * bP
            J[3:, 12] = bP @ qbb / h
        return E, J

    def _slider_terms(self, k: int, states: Sequence[State], mus: Sequence[np.ndarray],
                      weight: float, want_jac: bool = False):
        """(rows (6,), forces on the four nodes (12,), nodes, block or None). The clip
        holds the part where it is (sigma = s0) at weight 0 and lets it slide freely at
        1: the slide row is (1 - weight) (sigma - s0) + weight nu . dE/dsigma (no axial
        force)."""
        sl = self.sliders[k]
        w = mus[self.slot("slider", k)]
        sigma = float(w[0])
        if not 0.0 <= sigma <= 1.0:
            return None, None, None, None
        f, jb, y = self._slider_at(k, states, sigma)
        E, J = self._slider_E(k, y, sigma, f)
        n = sl.rows
        nu = w[1:1 + n]
        forces = J[:, :12].T @ nu
        rows = np.zeros(6)
        # The slide's row at weight 1: frictionless, G = nu . dE/dsigma = 0 (no work along
        # the slide); with Coulomb's friction mu, sticking (sigma where the step started)
        # or sliding s = +-1 with G = -s mu N (N the clip's force across its axis).
        # (While the clip is let go from where it starts, weight < 1, it slides freely:
        # a cold start finds its frictionless place, one of the equilibria friction
        # allows; friction acts from there on, along the path.)
        mode = (self.slide_mode.get(k, 0) if sl.clip.friction > 0.0 and weight >= 1.0
                else None)
        G = float(nu @ J[:, 12])
        across = nu[:3] - (nu[:3] @ sl.axis) * sl.axis
        N = float(np.linalg.norm(across))
        if mode is None:
            slide = G
        elif mode == 0:
            slide = sigma - self.slide_ref.get(k, sl.s0)
        else:
            slide = G + mode * sl.clip.friction * N
        rows[0] = (1.0 - weight) * (sigma - sl.s0) + weight * slide
        rows[1:1 + n] = E
        rows[1 + n:] = w[1 + n:]  # a ring's unused direction multipliers stay 0
        nodes = [(sl.part, int(j)) for j in jb]
        if not want_jac:
            return rows, forces, nodes, None
        # nu . d2E, by central differences of the exact Jacobian (13 variables).
        step = 1e-6
        H = np.empty((13, 13))
        for v in range(13):
            yp, ym = y.copy(), y.copy()
            sp = sm = sigma
            if v < 12:
                yp[v] += step
                ym[v] -= step
            else:
                sp, sm = sigma + step, sigma - step
            Jp = self._slider_E(k, yp, sp, f)[1]
            Jm = self._slider_E(k, ym, sm, f)[1]
            H[v] = nu @ (Jp - Jm) / (2.0 * step)
        H = 0.5 * (H + H.T)
        Eb = np.zeros((12, 6))
        Eb[:, 0] = H[:12, 12]
        Eb[:, 1:1 + n] = J[:, :12].T
        F = np.zeros((6, 12))
        F[1:1 + n] = J[:, :12]
        D = np.zeros((6, 6))
        D[1:1 + n, 0] = J[:, 12]
        if mode == 0:  # sticking: sigma held
            D[0, 0] = 1.0
        else:
            F[0] = weight * H[12, :12]
            D[0, 0] = (1.0 - weight) + weight * H[12, 12]
            D[0, 1:1 + n] = weight * J[:, 12]
            if mode and N > 0.0:  # sliding: + s mu dN/dnu
                D[0, 1:4] += weight * mode * sl.clip.friction * (across / N)
        for r in range(1 + n, 6):
            D[r, r] = 1.0
        ix = self.runs[sl.part].rod.ix
        block = _Block([(part, int(ix[node])) for part, node in nodes], Eb, F, D, H[:12, :12],
                       (self.slot("slider", k), slice(0, 6)))
        return rows, forces, nodes, block

    # -- junctions -------------------------------------------------------------------------
    def _joint_coords(self, k: int) -> list[tuple[int, int]]:
        """The junction's coordinates: a's end node and frame, b's end node and frame."""
        j = self.joints[k]
        out = []
        for part, node in ((j.a, j.end_a), (j.b, j.end_b)):
            rod = self.runs[part].rod
            out += [(part, int(rod.ix[node])), (part, int(rod.ith[rod.node_frame[node]]))]
        return out

    def _joint_rotation(self, k: int, qa: np.ndarray, qb: np.ndarray, weight: float):
        """The relative rotation's error c = Im(conj(qa q) qb) (3,), q turned from where
        the parts start (weight 0) to the junction's (1), and its Jacobian (3, 6) in the
        frames' material increments (q <- q exp(theta)): for qb 0.5 (r0 I + [r]x), for
        qa -0.5 (r0 I - [r]x) R(q)^T."""
        from pliant.models.rod3d.lowering import _slerp_quats  # noqa: PLC0415

        j = self.joints[k]
        q = _slerp_quats(j.turn[None], j.q_rel[None], weight)[0]
        r = qmul(qconj(qmul(qa, q)), qb)
        sign = 1.0 if r[0] >= 0.0 else -1.0
        skew = np.array([[0.0, -r[3], r[2]], [r[3], 0.0, -r[1]], [-r[2], r[1], 0.0]])
        J = np.empty((3, 6))
        J[:, :3] = -0.5 * sign * (r[0] * np.eye(3) - skew) @ quat_matrix(q).T
        J[:, 3:] = 0.5 * sign * (r[0] * np.eye(3) + skew)
        return sign * r[1:], J

    def _joint_terms(self, k: int, states: Sequence[State], mus: Sequence[np.ndarray],
                     weight: float, want_jac: bool = False):
        """(rows (6,), forces on the four coordinates (4, 3), block or None)."""
        j = self.joints[k]
        ra, rb = self.runs[j.a].rod, self.runs[j.b].rod
        Lr, Fr = self.L_ref, self.F_ref
        w = mus[self.slot("joint", k)]
        lam, mom = w[:3], w[3:]
        xa = states[j.a][0][j.end_a] * ra.length
        xb = states[j.b][0][j.end_b] * rb.length
        qa = states[j.a][1][ra.node_frame[j.end_a]]
        qb = states[j.b][1][rb.node_frame[j.end_b]]
        rows = np.empty(6)
        rows[:3] = (xb - xa - (1.0 - weight) * j.gap) / Lr
        rows[3:], Jr = self._joint_rotation(k, qa, qb, weight)
        fa = Fr * Lr / ra.moment_scale  # the junction's energy in each part's units
        fb = Fr * Lr / rb.moment_scale
        forces = np.array([fa * (-ra.length / Lr) * lam, fa * (Jr[:, :3].T @ mom),
                           fb * (rb.length / Lr) * lam, fb * (Jr[:, 3:].T @ mom)])
        if not want_jac:
            return rows, forces, None
        # mom . d2(rotation error), by central differences of its exact Jacobian.
        H = _frame_hessian(lambda a, b: self._joint_rotation(k, a, b, weight)[1],
                           (qa, qb), mom)
        eye = np.eye(3)
        E = np.zeros((12, 6))
        E[0:3, :3] = fa * (-ra.length / Lr) * eye
        E[3:6, 3:] = fa * Jr[:, :3].T
        E[6:9, :3] = fb * (rb.length / Lr) * eye
        E[9:12, 3:] = fb * Jr[:, 3:].T
        F = np.zeros((6, 12))
        F[:3, 0:3] = -ra.length / Lr * eye
        F[:3, 6:9] = rb.length / Lr * eye
        F[3:, 3:6] = Jr[:, :3]
        F[3:, 9:12] = Jr[:, 3:]
        K = np.zeros((12, 12))
        rot = [3, 4, 5, 9, 10, 11]
        scale = np.array([fa] * 3 + [fb] * 3)
        K[np.ix_(rot, rot)] = scale[:, None] * H
        block = _Block(self._joint_coords(k), E, F, np.zeros((6, 6)), K,
                       (self.slot("joint", k), slice(0, 6)))
        return rows, forces, block

    # -- pivoting clips -------------------------------------------------------------------
    def _pivot_coord(self, k: int) -> int:
        return int(self.runs[0].rod.ith[self.pivots[k].frame])

    def _pivot_rows(self, k: int, q: np.ndarray, weight: float):
        """(c (2,), J (2, 3)): d1 across the pin's direction (turned from where the part
        starts), and its change per material increment of the frame (d1 <- R (e1 +
        theta x e1))."""
        from pliant.models.rod3d.lowering import axis_basis, slerp_vectors  # noqa: PLC0415

        pv = self.pivots[k]
        target = slerp_vectors(pv.start[None], pv.pin[None], weight)[0]
        basis = axis_basis(target / np.linalg.norm(target))
        R = quat_matrix(q)
        d1 = R[:, 0]
        e1x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # [e1]x
        return basis @ d1, -basis @ R @ e1x

    def _pivot_terms(self, k: int, states: Sequence[State], mus: Sequence[np.ndarray],
                     weight: float, want_jac: bool = False):
        """(rows (2,), the torque on the frame's three rows, block or None)."""
        pv = self.pivots[k]
        nu = mus[self.slot("pivot", k)]
        q = states[0][1][pv.frame]
        c, J = self._pivot_rows(k, q, weight)
        torque = J.T @ nu
        if not want_jac:
            return c, torque, None
        H = _frame_hessian(lambda a: self._pivot_rows(k, a, weight)[1], (q,), nu)
        block = _Block([(0, self._pivot_coord(k))], J.T, J, np.zeros((2, 2)), H,
                       (self.slot("pivot", k), slice(0, 2)))
        return c, torque, block
