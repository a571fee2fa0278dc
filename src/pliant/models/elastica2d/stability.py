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

import numpy as np

from pliant.core.equilibrium import NEUTRAL

ELEMENTS = 240  # about this many elements over the part: the eigenvalue's error is O(h^2)
# Up to this many unknowns the dense null space and eigensolver are quicker than the
# shift-invert Lanczos (0.4 against 2.2 ms at the solver's 60-element verdicts; they
# cost about the same near 120 elements, and the dense one its cube beyond) and than
# the Sturm count's bisection (0.39 against 0.43 ms at 60; 1.1 ms at 240, where the
# Lanczos takes 2.9 and the dense 8 ms).
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


def _smallest(form: tuple) -> float:
    """``smallest_eigenvalue`` of a second variation already assembled."""
    from scipy.linalg import eigh, null_space  # noqa: PLC0415 (heavy; on demand)

    assemble, A, metric, diagonal, k, weight, bound, w = form
    n = metric.shape[0]
    value = None
    Q = None  # the dense form, assembled once where an eigensolver needs it
    if n > DENSE_UP_TO:
        value = _smallest_sturm(diagonal, k, A, weight, bound) if not w else None
        if value is None:
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
    _, A, _, diagonal, k, weight, _, w = form
    part = eq.problem.part
    scale = part.bending_stiffness / part.length
    threshold = -NEUTRAL * scale
    pencil = None if w else _bordered(diagonal, k, A, weight)
    if pencil is not None:
        from pliant.models.elastica2d.bordered import below  # noqa: PLC0415

        diag, off, jac, mass = pencil
        count = below(diag, off, jac, mass, threshold, scale)
        if count >= 0:
            return count == 0
    return _smallest(form) > threshold


def _bordered(diagonal: np.ndarray, k: np.ndarray, A: np.ndarray, weight: np.ndarray
              ) -> tuple[np.ndarray, ...] | None:
    """An inextensible part's pencil as ``bordered``'s counts take it: (the angles'
    tridiagonal diagonal, off-diagonal, the constraints' rows with the first end's shift
    first, the angles' weight), contiguous; None where A's rows are dependent (a zero
    eigenvalue the count cannot tell from the part's)."""
    if A.shape[0] and np.linalg.matrix_rank(A) < A.shape[0]:
        return None
    return (np.ascontiguousarray(diagonal, dtype=float), np.ascontiguousarray(-k, dtype=float),
            np.ascontiguousarray(np.hstack([A[:, -2:], A[:, :-2]])),
            np.ascontiguousarray(weight, dtype=float))


def _second_variation(eq, elements: int | None):
    """The discretised second variation (see the module): (Q, A, metric, diagonal, k,
    weight, bound, w) with Q() the form on the element angles (then the stretches, then
    the first end's shift) as a dense matrix, assembled when asked (the Sturm counts read
    its tridiagonal block alone, and its n^2 zeros took two thirds of a verdict's time),
    A the constraints' rows, the metric, the angles' tridiagonal block (diagonal, -k),
    their weight h / L, a bound below every eigenvalue [N m] and the number of stretch
    unknowns; None with follower loads."""
    problem = eq.problem
    if any(st.follower_load != (0.0, 0.0) for st in problem.stations) or any(
            ld.follower for ld in problem.distributed):
        return None
    part = problem.part
    L, EI = part.length, part.bending_stiffness
    knots = sorted({0.0, L, *(min(max(st.s, 0.0), L) for st in problem.stations)})
    nodes = [np.array([0.0])]
    for a, b in itertools.pairwise(knots):
        if b - a <= 1e-12 * L:
            continue
        count = max(2, math.ceil((elements or ELEMENTS) * (b - a) / L))
        nodes.append(np.linspace(a, b, count + 1)[1:])
    s = np.concatenate(nodes)
    h = np.diff(s)
    mid = 0.5 * (s[:-1] + s[1:])
    m = len(h)
    theta = np.interp(mid, eq.s, eq.angle)
    tangent = np.column_stack([np.cos(theta), np.sin(theta)])
    force = np.column_stack([np.interp(mid, eq.s, eq.internal_force[:, k]) for k in range(2)])
    axial = np.einsum("ij,ij->i", force, tangent)
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
    ea = part.axial_stiffness
    stretch = 1.0 if ea is None else 1.0 + axial / ea
    fixed = np.array([st.s for st in problem.stations if st.prescribed[2]], dtype=float)
    held = (np.abs(s[:, None] - fixed[None, :]).min(axis=1) <= 1e-12 * L if fixed.size
            else np.zeros(len(s), dtype=bool))

    # unknowns: the element angles, the element stretches (extensible), then the first
    # end's shift (dx0, dy0)
    w = m if ea is not None else 0
    n = m + w + 2
    diagonal = h * axial * stretch
    # each side of a held node bends from the held angle over half an element
    diagonal[:-1] += np.where(held[1:-1], 2.0 * EI / h[:-1], 0.0)  # node j = e + 1
    diagonal[1:] += np.where(held[1:-1], 2.0 * EI / h[1:], 0.0)    # node j = e
    diagonal[0] += 2.0 * EI / h[0] if held[0] else 0.0
    diagonal[-1] += 2.0 * EI / h[-1] if held[-1] else 0.0
    k = np.where(held[1:-1], 0.0, EI / (0.5 * (h[:-1] + h[1:])))  # interior free nodes
    diagonal[:-1] += k
    diagonal[1:] += k
    shear = np.einsum("ij,ij->i", force, normal) if w else np.zeros(m)

    def assemble() -> np.ndarray:
        Q = np.zeros((n, n))
        idx = np.arange(m)
        Q[idx, idx] = diagonal
        Q[idx[:-1], idx[1:]] = -k
        Q[idx[1:], idx[:-1]] = -k
        if w:
            Q[m + idx, m + idx] = h * ea
            Q[idx, m + idx] = Q[m + idx, idx] = -h * shear
        return Q
    rows = []
    for st in problem.stations:
        before = mid < st.s
        for axis in (0, 1):
            if st.prescribed[axis]:
                row = np.zeros(n)
                row[:m] = np.where(before, h * stretch * normal[:, axis], 0.0)
                if w:
                    row[m:m + w] = np.where(before, h * tangent[:, axis], 0.0)
                row[m + w + axis] = 1.0
                rows.append(row)
    A = np.array(rows) if rows else np.zeros((0, n))
    metric = np.concatenate([h / L, h[:w] / L, [0.0, 0.0]])
    # Below every eigenvalue [N m]: the bending's scale plus the geometric terms' bound
    # (h N theta^2 in the metric h / L is N L; the shear's coupling to the stretches
    # lowers it by at most S^2 L / EA).
    bound = EI / L + L * float(np.abs(axial * stretch).max(initial=0.0))
    if w:
        bound += L * float(np.max(shear**2, initial=0.0)) / ea
    return assemble, A, metric, diagonal, k, h / L, bound, w


def _smallest_sturm(diagonal: np.ndarray, k: np.ndarray, A: np.ndarray,
                    weight: np.ndarray, bound: float) -> float | None:
    """An inextensible part's smallest eigenvalue in n m operations a count: bisection on
    the number of eigenvalues below lambda (``bordered.smallest_constrained``: a Sturm
    sequence on the angles' tridiagonal block, the element angles' (diagonal, -k), and
    the small Schur complement of the first end's shift and the held positions' rows A,
    from -2 ``bound``, below every eigenvalue, to 1e-12 of ``bound``). 1.1 ms at 240
    elements where the Lanczos takes 2.9 ms. None where A's rows are dependent (a zero
    eigenvalue the count cannot tell from the part's) or a count fails: the eigensolvers
    then answer."""
    from pliant.models.elastica2d.bordered import smallest_constrained  # noqa: PLC0415

    pencil = _bordered(diagonal, k, A, weight)
    if pencil is None:
        return None
    diag, off, jac, mass = pencil
    value = smallest_constrained(diag, off, jac, mass, -2.0 * bound, bound)
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
