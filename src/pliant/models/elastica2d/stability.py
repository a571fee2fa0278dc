"""Stability of a 2D equilibrium: the second variation of its potential energy on the
variations its conditions allow.

For dead loads (point forces, couples, self-weight; a couple's potential -M theta is
linear, so dead moments are conservative in the plane) the second variation about an
equilibrium theta(s) with internal force n(s) is

    Q(dtheta) = int EI dtheta'^2 ds + int N dtheta^2 ds,   N = n . t (tension positive),

on the variations dtheta that keep every prescribed position (int over the part before
the station of (-sin theta, cos theta) dtheta ds = 0, plus the first end's own shift where
its position is free) and every prescribed angle (dtheta = 0 there). The load term is
the dead loads' -F . r differentiated twice, summed over everything beyond s: by
equilibrium that sum is the internal force (reactions included, as Lagrange multipliers).

It is discretised with element angles on a grid whose nodes include every station; the
smallest eigenvalue of Q on the constraints' null space, in the metric int dtheta^2 ds / L,
is returned in N m (for a cantilever under an axial dead load P: L (EI (pi / 2L)^2 - P)).
Positive: stable; negative: unstable; zero to 1e-8 EI / L: neutral (a mode that costs
no energy). Follower loads are not conservative: stability is undecided.

An extensible part (axial stiffness EA, axial strain eps = N / EA, r' = (1 + eps) t) has
the element stretches deps as unknowns too:

    Q = int EI dtheta'^2 + EA deps^2 + (1 + eps) N dtheta^2 - 2 Q_s deps dtheta ds,

Q_s = n . nu the shear force, and a prescribed position constrains
int (1 + eps) nu dtheta + t deps ds. The stretches take the same metric as the angles (the
sign of the smallest eigenvalue, which is what decides, does not depend on the metric).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from numba import njit

from pliant.core.equilibrium import NEUTRAL

ELEMENTS = 240  # about this many elements over the part: the eigenvalue's error is O(h^2)
# Up to this many unknowns the dense null space and eigensolver are quicker than the
# shift-invert Lanczos (0.4 against 2.2 ms at 60 elements; they cost about the same near
# 120, and the dense one its cube beyond). An inextensible part's Sturm count comes
# first at any size (case 3: 60 us at 60 elements against the dense 290 us; 160 us at
# 240, where the Lanczos takes 2.9 and the dense 8 ms).
DENSE_UP_TO = 100


def stability(eq, elements: int | None = None) -> tuple[bool | None, float | None]:
    """(stable, smallest eigenvalue [N m]); (None, None) with follower loads. A neutral
    equilibrium (see ``NEUTRAL``) counts as stable: nothing makes it move. ``elements``
    as in ``smallest_eigenvalue``."""
    value = smallest_eigenvalue(eq, elements)
    if value is None:
        return None, None
    scale = eq.problem.part.bending_stiffness / eq.problem.part.length
    return value > -NEUTRAL * scale, value


def smallest_eigenvalue(eq, elements: int | None = None) -> float | None:
    """The smallest eigenvalue [N m] (see the module), None with follower loads;
    ``elements`` about how many (default ``ELEMENTS``; fewer for a quick verdict: the
    dense algebra costs their cube)."""
    form = _second_variation(eq, elements)
    return None if form is None else _smallest(form)


def _smallest(form: Form) -> float:
    """``smallest_eigenvalue`` of a second variation already assembled."""
    from scipy.linalg import eigh, null_space  # noqa: PLC0415 (heavy; on demand)

    assemble, A, metric, bound, w = form.assemble, form.A, form.metric, form.bound, form.w
    n = metric.shape[0]
    value = None
    Q = None  # the dense form, assembled once where an eigensolver needs it
    value = _smallest_sturm(form) if not w else None
    if value is None and n > DENSE_UP_TO:
        Q = assemble()
        value = _smallest_sparse(Q, A, metric, -2.0 * bound)
    if value is not None:
        return value
    if Q is None:
        Q = assemble()
    Z = null_space(A) if A.shape[0] else np.eye(n)
    reduced = Z.T @ Q @ Z
    mass = Z.T @ (metric[:, None] * Z)
    return float(eigh(0.5 * (reduced + reduced.T), 0.5 * (mass + mass.T),
                      eigvals_only=True, subset_by_index=(0, 0))[0])


def stable_sign(eq, elements: int | None = None) -> bool | None:
    """``stability(eq, elements)[0]`` without the eigenvalue: whether none lies below
    the neutral band (-``NEUTRAL`` EI / L), by one Sturm count of the constrained
    pencil (``bordered``: n m operations, where the dense eigensolver costs n^3). For
    choosing among equilibria, where only the sign counts. The eigensolvers answer where
    the count cannot (an extensible part, dependent constraints, a singular count)."""
    form = _second_variation(eq, elements)
    if form is None:
        return None
    part = eq.problem.part
    scale = part.bending_stiffness / part.length
    threshold = -NEUTRAL * scale
    pencil = None if form.w else _bordered(form)
    if pencil is not None:
        from pliant.models.elastica2d.bordered import below  # noqa: PLC0415

        diag, off, jac, mass = pencil
        count = below(diag, off, jac, mass, threshold, scale)
        if count >= 0:
            return count == 0
    return _smallest(form) > threshold


@dataclass(eq=False)
class Form:
    """The discretised second variation (see the module) of a part (L, EI, EA) on the
    element nodes s: the element lengths h, tangents, axial and shear forces; the
    angles' tridiagonal block (diagonal, -k); the constraints' rows, at arc lengths
    ``row_s`` along ``row_axis``, in the Sturm counts' order (``pencil_rows``: the first
    end's shift, then the angles, for an inextensible part); the number of stretch
    unknowns w. What only the eigensolvers read (the rows over every unknown A, the
    metric, a bound below every eigenvalue, the dense form) is made when first asked:
    a quick verdict's Sturm count reads the block and the rows alone."""

    length: float
    stiffness: float
    axial_stiffness: float | None
    s: np.ndarray
    row_s: list[float]
    row_axis: list[int]
    h: np.ndarray
    tangent: np.ndarray
    axial: np.ndarray
    shear: np.ndarray
    diagonal: np.ndarray
    k: np.ndarray
    pencil_rows: np.ndarray
    w: int

    @property
    def weight(self) -> np.ndarray:
        """The angles' weight in the metric, h / L."""
        return self.h / self.length

    @cached_property
    def A(self) -> np.ndarray:
        """The constraints' rows over the unknowns: the element angles, the stretches
        (extensible), then the first end's shift (dx0, dy0)."""
        m, w = self.h.shape[0], self.w
        A = np.zeros((len(self.row_s), m + w + 2))
        A[:, :m] = self.pencil_rows[:, 2:]
        A[:, m + w:] = self.pencil_rows[:, :2]
        if w:
            mid = 0.5 * (self.s[:-1] + self.s[1:])
            for r, (at, axis) in enumerate(zip(self.row_s, self.row_axis)):
                A[r, m:m + w] = np.where(mid < at, self.h * self.tangent[:, axis], 0.0)
        return A

    @cached_property
    def metric(self) -> np.ndarray:
        return np.concatenate([self.weight, self.h[:self.w] / self.length, [0.0, 0.0]])

    @cached_property
    def bound(self) -> float:
        """Below every eigenvalue [N m]: the bending's scale plus the geometric terms'
        bound (h N theta^2 in the metric h / L is N L; the shear's coupling to the
        stretches lowers it by at most S^2 L / EA)."""
        L, ea = self.length, self.axial_stiffness
        stretch = 1.0 if ea is None else 1.0 + self.axial / ea
        bound = self.stiffness / L + L * float(np.abs(self.axial * stretch).max(initial=0.0))
        if self.w and ea is not None:
            bound += L * float(np.max(self.shear**2, initial=0.0)) / ea
        return bound

    def assemble(self) -> np.ndarray:
        """The form as a dense matrix (the angles, the stretches, the first end's shift):
        built when asked (its n^2 zeros took two thirds of a verdict's time)."""
        m, w = self.h.shape[0], self.w
        n = m + w + 2
        Q = np.zeros((n, n))
        idx = np.arange(m)
        Q[idx, idx] = self.diagonal
        Q[idx[:-1], idx[1:]] = -self.k
        Q[idx[1:], idx[:-1]] = -self.k
        if w:
            Q[m + idx, m + idx] = self.h * self.axial_stiffness
            Q[idx, m + idx] = Q[m + idx, idx] = -self.h * self.shear
        return Q


def _bordered(form: Form) -> tuple[np.ndarray, ...] | None:
    """An inextensible part's pencil as ``bordered``'s counts take it: (the angles'
    tridiagonal diagonal, off-diagonal, the constraints' rows with the first end's shift
    first, the angles' weight); None where the rows are dependent (a zero eigenvalue the
    count cannot tell from the part's)."""
    rows = form.pencil_rows
    if rows.shape[0] and not _independent(rows):
        return None
    return form.diagonal, -form.k, rows, form.weight


def _second_variation(eq, elements: int | None) -> Form | None:
    """The discretised second variation (``Form``); None with follower loads. The
    element terms come from one compiled pass (``_element_form``: numpy's forty calls
    on arrays of 60 took 70 us of a verdict's 110)."""
    problem = eq.problem
    if any(st.follower_load != (0.0, 0.0) for st in problem.stations) or any(
            ld.follower for ld in problem.distributed):
        return None
    part = problem.part
    L, EI = part.length, part.bending_stiffness
    s, held = _grid(L, tuple(st.s for st in problem.stations),
                    tuple(st.s for st in problem.stations if st.prescribed[2]),
                    elements or ELEMENTS)
    row_s = [st.s for st in problem.stations for axis in (0, 1) if st.prescribed[axis]]
    row_axis = [axis for st in problem.stations for axis in (0, 1) if st.prescribed[axis]]
    ea = part.axial_stiffness
    terms = _element_form(
        s, np.ascontiguousarray(eq.s, dtype=float), np.ascontiguousarray(eq.angle, dtype=float),
        np.ascontiguousarray(eq.internal_force, dtype=float), held,
        np.array(row_s, dtype=float), np.array(row_axis, dtype=np.int64), float(EI),
        0.0 if ea is None else 1.0 / ea)
    h, tangent, axial, shear, diagonal, k, pencil_rows = terms
    return Form(L, EI, ea, s, row_s, row_axis, h, tangent, axial, shear, diagonal, k,
                pencil_rows, w=len(s) - 1 if ea is not None else 0)


@lru_cache(maxsize=64)
def _grid(length: float, stations: tuple[float, ...], fixed: tuple[float, ...],
          elements: int) -> tuple[np.ndarray, np.ndarray]:
    """The elements' nodes [m], about ``elements`` over the part, every station a node,
    and whether each is one whose angle is held (at a station of ``fixed``). Made once
    per part and stations (a verdict's grid), read only."""
    knots = sorted({0.0, length, *(min(max(at, 0.0), length) for at in stations)})
    nodes = [np.array([0.0])]
    for a, b in itertools.pairwise(knots):
        if b - a <= 1e-12 * length:
            continue
        count = max(2, math.ceil(elements * (b - a) / length))
        nodes.append(np.linspace(a, b, count + 1)[1:])
    grid = np.concatenate(nodes)
    held = np.array([any(abs(x - f) <= 1e-12 * length for f in fixed) for x in grid.tolist()])
    grid.flags.writeable = held.flags.writeable = False
    return grid, held


@njit(cache=True)
def _element_form(s, eq_s, eq_angle, eq_force, held, row_s, row_axis, EI, inv_ea):
    """The element terms of the second variation on the nodes s, read from the
    equilibrium's samples (linearly, at the elements' middles): (h, tangent, axial
    force, shear force, the angles' diagonal, the coupling k between neighbours, the
    constraints' rows as the Sturm counts take them: the first end's shift, then the
    angles, each scaled by the stretch 1 + N inv_ea). A held node bends each side from
    its angle over half an element; a held position constrains the angles of the
    elements before it."""
    m = s.shape[0] - 1
    mid = np.empty(m)
    h = np.empty(m)
    for e in range(m):
        h[e] = s[e + 1] - s[e]
        mid[e] = 0.5 * (s[e] + s[e + 1])
    theta = np.empty(m)
    fx = np.empty(m)
    fy = np.empty(m)
    j = 0  # numpy's interp, as a walk along both ascending grids
    last = eq_s.shape[0] - 1
    for e in range(m):
        x = mid[e]
        while j < last - 1 and eq_s[j + 1] <= x:
            j += 1
        if x <= eq_s[0]:
            theta[e], fx[e], fy[e] = eq_angle[0], eq_force[0, 0], eq_force[0, 1]
        elif x >= eq_s[last]:
            theta[e], fx[e], fy[e] = eq_angle[last], eq_force[last, 0], eq_force[last, 1]
        else:
            gap = eq_s[j + 1] - eq_s[j]
            theta[e] = (eq_angle[j + 1] - eq_angle[j]) / gap * (x - eq_s[j]) + eq_angle[j]
            fx[e] = (eq_force[j + 1, 0] - eq_force[j, 0]) / gap * (x - eq_s[j]) + eq_force[j, 0]
            fy[e] = (eq_force[j + 1, 1] - eq_force[j, 1]) / gap * (x - eq_s[j]) + eq_force[j, 1]
    tangent = np.empty((m, 2))
    axial = np.empty(m)
    shear = np.empty(m)
    diagonal = np.empty(m)
    rows = np.zeros((row_s.shape[0], m + 2))
    for e in range(m):
        c, sn = math.cos(theta[e]), math.sin(theta[e])
        tangent[e, 0], tangent[e, 1] = c, sn
        axial[e] = fx[e] * c + fy[e] * sn
        shear[e] = fx[e] * -sn + fy[e] * c
        stretch = 1.0 + axial[e] * inv_ea
        diagonal[e] = h[e] * axial[e] * stretch
        for r in range(row_s.shape[0]):
            if mid[e] < row_s[r]:
                rows[r, 2 + e] = h[e] * stretch * (-sn if row_axis[r] == 0 else c)
    for r in range(row_s.shape[0]):
        rows[r, row_axis[r]] = 1.0
    k = np.zeros(max(m - 1, 0))
    for e in range(m - 1):  # node e + 1, between elements e and e + 1
        if held[e + 1]:
            diagonal[e] += 2.0 * EI / h[e]
            diagonal[e + 1] += 2.0 * EI / h[e + 1]
    if held[0]:
        diagonal[0] += 2.0 * EI / h[0]
    if held[m]:
        diagonal[m - 1] += 2.0 * EI / h[m - 1]
    for e in range(m - 1):  # interior free nodes
        if not held[e + 1]:
            k[e] = EI / (0.5 * (h[e] + h[e + 1]))
            diagonal[e] += k[e]
            diagonal[e + 1] += k[e]
    return h, tangent, axial, shear, diagonal, k, rows


@njit(cache=True)
def _independent(rows):
    """Whether the rows are linearly independent: Gram-Schmidt, twice over, each row's
    remainder above 1e-10 of its own size (numpy's matrix_rank, by an SVD, took 15 us)."""
    m, n = rows.shape
    q = np.zeros((m, n))
    for a in range(m):
        size = 0.0
        for j in range(n):
            q[a, j] = rows[a, j]
            size += rows[a, j] * rows[a, j]
        for _ in range(2):
            for b in range(a):
                dot = 0.0
                for j in range(n):
                    dot += q[b, j] * q[a, j]
                for j in range(n):
                    q[a, j] -= dot * q[b, j]
        norm = 0.0
        for j in range(n):
            norm += q[a, j] * q[a, j]
        if not norm > 1e-20 * size:
            return False
        norm = math.sqrt(norm)
        for j in range(n):
            q[a, j] /= norm
    return True


def _smallest_sturm(form: Form) -> float | None:
    """An inextensible part's smallest eigenvalue in n m operations a count: bisection on
    the number of eigenvalues below lambda (``bordered.smallest_constrained``: a Sturm
    sequence on the angles' tridiagonal block, the element angles' (diagonal, -k), and
    the small Schur complement of the first end's shift and the held positions' rows A,
    from -2 ``bound``, below every eigenvalue), then Rayleigh quotient iteration proved
    by two counts, to 1e-12 of ``bound``. 160 us at 240 elements where the Lanczos
    takes 2.9 ms (the bisection alone took 0.45 ms). None where A's rows are dependent (a zero
    eigenvalue the count cannot tell from the part's) or a count fails: the eigensolvers
    then answer."""
    from pliant.models.elastica2d.bordered import smallest_constrained  # noqa: PLC0415

    pencil = _bordered(form)
    if pencil is None:
        return None
    diag, off, jac, mass = pencil
    value = smallest_constrained(diag, off, jac, mass, -2.0 * form.bound, form.bound)
    return None if math.isnan(value) else float(value)


def _smallest_sparse(Q: np.ndarray, A: np.ndarray, metric: np.ndarray,
                     shift: float) -> float | None:
    """The smallest eigenvalue of Q on A v = 0 in the metric, by shift-invert Lanczos
    (ARPACK) at ``shift`` (below every eigenvalue): each step a solve with the sparse LU
    of [Q - shift M, A^T; A, 0], whose solutions lie in the constraints' null space.
    Milliseconds where the dense null space and eigensolver take a tenth of a second;
    None where it does not converge (the dense path then answers)."""
    from scipy.sparse import bmat, csc_matrix  # noqa: PLC0415 (heavy; on demand)
    from scipy.sparse.linalg import splu  # noqa: PLC0415

    from pliant.models.lanczos import smallest_by_arpack  # noqa: PLC0415

    n, m = Q.shape[0], A.shape[0]
    primal = metric > 0.0
    K = csc_matrix(Q - shift * np.diag(metric))
    if m:
        K = bmat([[K, csc_matrix(A.T)], [csc_matrix(A), None]], format="csc")
    try:
        lu = splu(K)
    except RuntimeError:  # singular
        return None

    def solve(r: np.ndarray) -> np.ndarray:
        rhs = np.zeros(n + m)
        rhs[:n][primal] = r.ravel()
        return lu.solve(rhs)[:n][primal]

    start = np.random.default_rng(12345).standard_normal(int(primal.sum()))  # no symmetry
    value, _ = smallest_by_arpack(solve, metric[primal], shift, tol=1e-12, v0=start)
    return value
