"""The softest mode of a banded symmetric pencil by shift-invert Lanczos, its steps in a
numba kernel: the stability test of the accurate 3D rod at every step of a path, without the
Python round trips of ARPACK's reverse communication (about 80 per eigenvalue, each a
band solve: most of its cost at a few hundred unknowns).

For the pencil (A, M) restricted to some unknowns (``primal``; A's other rows are
constraints, eliminated by solving the whole KKT system), with M = diag(weight) > 0 and
a shift sigma below every eigenvalue, the operator OP = (A - sigma M)^-1 M is symmetric
in the M inner product and its largest eigenvalue theta belongs to the smallest
eigenvalue lambda = sigma + 1 / theta of the pencil. Lanczos builds an M-orthonormal
Krylov basis of OP from a start vector (fully reorthogonalised, twice: a few tens of
vectors), and stops when the Ritz pair's residual beta |s_last| falls below
tol * theta (ARPACK's test).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from pliant.models.banded import band_lu_solve


@njit(cache=True)
def _inner(u, v, weight):
    """sum(weight u v), written out: numba's array expressions compile their
    broadcasting checks, seconds on a first run."""
    total = 0.0
    for i in range(u.shape[0]):
        total += weight[i] * u[i] * v[i]
    return total


@njit(cache=True)
def _take(z, c, v):
    """z -= c v, in place."""
    for i in range(z.shape[0]):
        z[i] -= c * v[i]


class Basis(NamedTuple):
    """What the Lanczos steps fill: the M-orthonormal basis Q (rows), the tridiagonal's
    diagonal alpha and off-diagonal beta, and a right-hand side's room (n,)."""

    Q: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    rhs: np.ndarray


@njit(cache=True)
def _lanczos_steps(ab, piv, kl, ku, primal, weight, basis, first, last):
    """Lanczos steps first .. last - 1 (see the module): alpha[j], beta[j] and the next
    basis vector Q[j + 1], each from one solve with the band LU factors (ab, piv); the
    number of steps done in all, fewer where the Krylov space is exhausted (beta[j] 0
    to round-off: its Ritz values are then exact)."""
    Q, alpha, beta, rhs = basis
    p = primal.shape[0]
    for j in range(first, last):
        for i in range(rhs.shape[0]):
            rhs[i] = 0.0
        for i in range(p):
            rhs[primal[i]] = weight[i] * Q[j, i]
        x = band_lu_solve(ab, piv, kl, ku, rhs)
        z = np.empty(p)
        for i in range(p):
            z[i] = x[primal[i]]
        a = _inner(z, Q[j], weight)
        _take(z, a, Q[j])
        if j > 0:
            _take(z, beta[j - 1], Q[j - 1])
        for _ in range(2):  # full reorthogonalisation, twice ("twice is enough")
            for k in range(j + 1):
                _take(z, _inner(z, Q[k], weight), Q[k])
        b = math.sqrt(_inner(z, z, weight))
        alpha[j] = a
        beta[j] = b
        if b <= 1e-14 * (abs(a) + (beta[j - 1] if j > 0 else 0.0)) or b <= 1e-300:
            return j + 1
        for i in range(p):
            Q[j + 1, i] = z[i] / b
    return last


def softest_mode(ab, piv, kl, ku, primal, weight, v0, tol, max_steps, block: int = 4):
    """(theta, vector (p,), converged, steps): the largest eigenvalue of OP (see the
    module) and its M-normalised vector over the ``primal`` unknowns (p,), from the band
    LU factors (ab, piv) of A - sigma M. ``weight`` (p,) is M's diagonal.

    The steps run compiled, ``block`` at a time; the tridiagonal's eigenpair is found
    here between blocks (numpy's eigh of at most ``max_steps`` rows, microseconds): in
    the kernel, numba's eigh cost every first run 0.9 s of compiling. A converged mode
    takes up to ``block`` - 1 steps more than it needs, each one band solve."""
    p = primal.shape[0]
    steps = min(max_steps, p)  # at most p: the space is exhausted by then
    Q = np.zeros((steps + 1, p))
    alpha = np.zeros(steps)
    beta = np.zeros(steps)
    Q[0] = v0 / math.sqrt(float(np.sum(weight * v0 * v0)))
    basis = Basis(Q, alpha, beta, np.zeros(ab.shape[0]))
    done, theta, s = 0, 0.0, np.ones(1)
    while done < steps:
        last = _lanczos_steps(ab, piv, kl, ku, primal, weight, basis, done,
                              min(steps, done + block))
        exhausted = last < min(steps, done + block)
        done = last
        T = np.diag(alpha[:done]) + np.diag(beta[:done - 1], 1) + np.diag(beta[:done - 1], -1)
        values, vectors = np.linalg.eigh(T)
        theta, s = float(values[-1]), vectors[:, -1]
        if exhausted or beta[done - 1] * abs(s[-1]) <= tol * abs(theta) or done == p:
            return theta, -(s @ Q[:done]), True, done
    return theta, -(s @ Q[:done]), False, done


def smallest_by_arpack(solve, weight: np.ndarray, shift: float, tol: float = 1e-10,
                       v0: np.ndarray | None = None):
    """(value, vector) of the smallest eigenvalue of a pencil (A, diag(weight)) by
    ARPACK's shift-invert mode, or (None, None) where it does not converge. ``solve(r)``
    returns (A - shift M)^-1 r on the weighted unknowns (the constrained system solved
    whole, its other unknowns dropped); ``shift`` lies below every eigenvalue. The
    fallback of ``softest_mode`` in 3D and the 2D verdict's solver."""
    from scipy.sparse import diags  # noqa: PLC0415 (heavy; on demand)
    from scipy.sparse.linalg import ArpackError, LinearOperator, eigsh  # noqa: PLC0415

    size = weight.shape[0]
    inverse = LinearOperator((size, size), matvec=solve, dtype=float)
    unused = LinearOperator((size, size), matvec=lambda x: x, dtype=float)
    try:
        values, vectors = eigsh(unused, k=1, M=diags(weight), sigma=shift, which="LM",
                                OPinv=inverse, tol=tol, v0=v0)
    except ArpackError:
        return None, None
    return float(values[0]), vectors[:, 0]
