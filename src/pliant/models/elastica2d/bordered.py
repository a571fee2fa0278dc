"""Symmetric KKT systems whose Hessian is tridiagonal but for a small border, in n m
operations: the 2D discrete part's (``minimum``: zero on two translations, tridiagonal on
the element angles) and the second variation's (``stability``: on the element angles,
with the first end's shift).

The angles' tridiagonal block is eliminated (``condensed``), which leaves a Schur
complement of the border and the constraints' multipliers; its inertia plus the block's
(a Sturm sequence) is the whole matrix's by Sylvester's law (``kkt_negatives``). A
constrained Hessian is positive definite on the constraints' null space exactly when the
KKT matrix has as many negative eigenvalues as constraints (Gould), and the number of a
constrained pencil's eigenvalues below lambda is that count at H - lambda W less the
constraints (``smallest_constrained``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pliant.models.elastica2d.kernels import lu_solve


@njit(cache=True)
def tridiagonal_times(diag, off, x):
    """T x for T = tridiag(diag, off). In loops: an array assigned to a slice makes numba
    link a shape check whose message pulls its unicode code into every caller (a
    megabyte of IR that each compiled caller optimises again)."""
    n = diag.shape[0]
    out = np.empty(n)
    for j in range(n):
        acc = diag[j] * x[j]
        if j > 0:
            acc += off[j - 1] * x[j - 1]
        if j < n - 1:
            acc += off[j] * x[j + 1]
        out[j] = acc
    return out


@njit(cache=True)
def _tridiagonal_solve(diag, off, rhs):
    """Solve T X = rhs in place (rhs (n, k)) for the symmetric tridiagonal T by Gaussian
    elimination with partial pivoting (as LAPACK's gtsv: a row swap fills a second
    superdiagonal); False where a pivot vanishes against T's scale."""
    n, k = rhs.shape
    d = diag.copy()
    up = off.copy()  # the first superdiagonal of U
    low = off.copy()  # the subdiagonal, then U's second superdiagonal
    scale = 0.0
    for i in range(n):
        scale = max(scale, abs(diag[i]) + (abs(off[i]) if i < n - 1 else 0.0)
                    + (abs(off[i - 1]) if i > 0 else 0.0))
    tiny = 1e-14 * scale
    for i in range(n - 1):
        if abs(d[i]) >= abs(low[i]):
            if abs(d[i]) <= tiny:
                return False
            f = low[i] / d[i]
            d[i + 1] -= f * up[i]
            for c in range(k):
                rhs[i + 1, c] -= f * rhs[i, c]
            low[i] = 0.0
        else:  # swap rows i and i + 1
            f = d[i] / low[i]
            d[i] = low[i]
            below = d[i + 1]
            d[i + 1] = up[i] - f * below
            if i < n - 2:
                low[i] = up[i + 1]
                up[i + 1] = -f * low[i]
            else:
                low[i] = 0.0
            up[i] = below
            for c in range(k):
                top = rhs[i, c]
                rhs[i, c] = rhs[i + 1, c]
                rhs[i + 1, c] = top - f * rhs[i + 1, c]
    if abs(d[n - 1]) <= tiny:
        return False
    # Row by row, the columns innermost: their chains of divisions are independent,
    # so the processor overlaps them (column by column, each waited on the last).
    for c in range(k):
        rhs[n - 1, c] /= d[n - 1]
    if n > 1:
        for c in range(k):
            rhs[n - 2, c] = (rhs[n - 2, c] - up[n - 2] * rhs[n - 1, c]) / d[n - 2]
    for i in range(n - 3, -1, -1):
        for c in range(k):
            rhs[i, c] = (rhs[i, c] - up[i] * rhs[i + 1, c] - low[i] * rhs[i + 2, c]) / d[i]
    return True


@njit(cache=True)
def condensed(diag, off, jac, corner, reg, extra):
    """The KKT matrix [[H, J^T], [J, -reg I]], H = corner I on the two translations and
    T = tridiag(diag, off) on the n angles, condensed onto the translations and the m
    multipliers: T eliminated. (S, X, ok): S the (2 + m)-square Schur complement, X the
    solves T X = [extra | J_theta^T] (the angles' columns of J), ok False where T is
    singular. Costs n m, not the dense (n + m)^3."""
    n, m = diag.shape[0], jac.shape[0]
    X = np.empty((n, m + 1))
    for j in range(n):
        X[j, 0] = extra[j]
        for r in range(m):
            X[j, 1 + r] = jac[r, 2 + j]
    ok = _tridiagonal_solve(diag, off, X)
    S = np.zeros((2 + m, 2 + m))
    S[0, 0] = corner
    S[1, 1] = corner
    # J_theta X, each entry summed over the angles in order, all m^2 at once (one
    # chain of additions per entry, interleaved: the processor overlaps them).
    acc = np.zeros((m, m))
    for j in range(n):
        for r in range(m):
            a = jac[r, 2 + j]
            for q in range(m):
                acc[r, q] += a * X[j, 1 + q]
    for r in range(m):
        S[0, 2 + r] = S[2 + r, 0] = jac[r, 0]
        S[1, 2 + r] = S[2 + r, 1] = jac[r, 1]
        for q in range(m):
            S[2 + r, 2 + q] = -acc[r, q]
        S[2 + r, 2 + r] -= reg
    return S, X, ok


@njit(cache=True)
def kkt_negatives(diag, off, jac, corner):
    """The number of negative eigenvalues of [[H, J^T], [J, 0]] (H as in ``condensed``);
    -1 where the angles' block is singular to round-off, -2 where the Schur complement is
    singular (the whole matrix: for a pencil, lambda is an eigenvalue)."""
    n = diag.shape[0]
    negative = 0
    pivot = 1.0
    for j in range(n):  # the tridiagonal block's LDL^T pivots (a Sturm sequence)
        pivot = diag[j] - (off[j - 1] * off[j - 1] / pivot if j > 0 else 0.0)
        if pivot == 0.0:
            return -1
        if pivot < 0.0:
            negative += 1
    S, _, ok = condensed(diag, off, jac, corner, 0.0, np.zeros(n))
    if not ok:
        return -1
    # The signs as computed: a tolerance on S's small eigenvalues would be relative to
    # its largest, which grows without bound where the angles' block nears a singular
    # point (a pencil's eigenvalue that the constraints leave free), and would blur the
    # count over a band round it.
    count = negatives(S)
    if count < 0:
        return -2
    return negative + count


@njit(cache=True)
def kkt_solve(shifted, off, jac, corner, reg, r_u, r_c):
    """One solve of [[H, J^T], [J, -reg I]] (dx, dy) = (r_u, r_c), H = corner I on the
    translations and tridiag(shifted, off) on the angles, by its condensed form
    (``condensed``): (dx, dy, ok)."""
    n, m = shifted.shape[0], jac.shape[0]
    dx = np.zeros(n + 2)
    dy = np.zeros(m)
    S, X, ok = condensed(shifted, off, jac, corner, reg, r_u[2:])
    if not ok:
        return dx, dy, False
    rhs = np.empty(2 + m)
    rhs[0], rhs[1] = r_u[0], r_u[1]
    for r in range(m):
        acc = 0.0
        for j in range(n):
            acc += jac[r, 2 + j] * X[j, 0]
        rhs[2 + r] = r_c[r] - acc
    sol, ok = lu_solve(S, rhs)
    if not ok:
        return dx, dy, False
    dx[0], dx[1] = sol[0], sol[1]
    for j in range(n):
        acc = X[j, 0]
        for r in range(m):
            acc -= X[j, 1 + r] * sol[2 + r]
        dx[2 + j] = acc
    for r in range(m):
        dy[r] = sol[2 + r]
    return dx, dy, True


@njit(cache=True)
def negatives(A):
    """The number of negative eigenvalues of the small symmetric matrix A, by its
    Bunch-Kaufman factorisation P A P^T = L D L^T (LAPACK's sytf2 pivoting: 1x1 and 2x2
    blocks, backward stable, so the inertia is exact for a matrix within round-off of
    A; Sylvester's law gives it from D's blocks); -1 where A is singular (a zero pivot
    column). A third of the dense eigensolver's time on the 6x6 Schur complements."""
    n = A.shape[0]
    a = A.copy()
    alpha = (1.0 + np.sqrt(17.0)) / 8.0
    negative = 0
    k = 0
    while k < n:
        big, imax = 0.0, k
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big, imax = abs(a[i, k]), i
        diag = abs(a[k, k])
        if max(diag, big) == 0.0:
            return -1
        size, kp = 1, k
        if diag < alpha * big:
            row = 0.0  # the largest off-diagonal of row (and column) imax
            for j in range(k, n):
                if j != imax:
                    row = max(row, abs(a[imax, j]))
            if diag * row >= alpha * big * big:
                kp = k
            elif abs(a[imax, imax]) >= alpha * row:
                kp = imax
            else:
                size, kp = 2, imax
        kk = k + size - 1
        if kp != kk:  # swap rows and columns kk and kp
            for j in range(n):
                a[kk, j], a[kp, j] = a[kp, j], a[kk, j]
            for j in range(n):
                a[j, kk], a[j, kp] = a[j, kp], a[j, kk]
        if size == 1:
            d = a[k, k]
            if d < 0.0:
                negative += 1
            for i in range(k + 1, n):
                f = a[i, k] / d
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
        else:
            d11, d21, d22 = a[k, k], a[k + 1, k], a[k + 1, k + 1]
            det = d11 * d22 - d21 * d21
            # One eigenvalue of each sign: the pivoting takes a 2x2 block only where
            # |d11| < alpha |d21|^2 / row and |d22| < alpha row (row >= |d21|), so
            # d11 d22 < alpha^2 d21^2 and det < -(1 - alpha^2) d21^2 < 0.
            negative += 1
            for i in range(k + 2, n):
                # (w1, w2) = [a_ik, a_i,k+1] D^-1
                w1 = (a[i, k] * d22 - a[i, k + 1] * d21) / det
                w2 = (a[i, k + 1] * d11 - a[i, k] * d21) / det
                for j in range(k + 2, n):
                    a[i, j] -= w1 * a[k, j] + w2 * a[k + 1, j]
        k += size
    return negative


@njit(cache=True)
def below(diag, off, jac, weight, lam, scale):
    """How many eigenvalues of the pencil (H, W) on J v = 0 lie below lam (H tridiagonal
    on the angles, zero on the translations, W = diag(weight) on the angles); -2 where
    lam is one (to round-off), -1 where the angles' block stays singular with lam nudged
    by 1e-13 of ``scale`` (a few times)."""
    for attempt in range(4):
        at = lam + attempt * 1e-13 * scale
        shifted = np.empty(diag.shape[0])  # (a loop: see ``tridiagonal_times``)
        for j in range(diag.shape[0]):
            shifted[j] = diag[j] - at * weight[j]
        count = kkt_negatives(shifted, off, jac, 0.0)
        if count == -2:
            return -2
        if count >= 0:
            return count - jac.shape[0]
    return -1


@njit(cache=True)
def smallest_constrained(diag, off, jac, weight, lo, scale):
    """The smallest eigenvalue of the pencil (H, W) on J v = 0 (``below``) to 1e-12 of
    ``scale``, from lo (below every eigenvalue); NaN where a count fails or lo is not
    below them (the caller then asks a dense eigensolver). A lambda that is an
    eigenvalue itself (``below`` -2) is at or above the smallest.

    Bisection on the counts until the bracket holds the smallest alone, then Rayleigh
    quotient iteration (``_pencil_rayleigh``: cubic, four or five solves where the
    bisection took some thirty counts more), its value proved by two counts 1e-12 of
    ``scale`` either side; where the proof fails (a double eigenvalue), the bisection
    goes on to the end."""
    if below(diag, off, jac, weight, lo, scale) != 0:
        return np.nan
    hi = lo + scale
    count = 0
    for _ in range(80):  # up until one lies below
        count = below(diag, off, jac, weight, hi, scale)
        if count != 0:
            break
        step = 2.0 * (hi - lo)
        lo = hi
        hi += step
    if count == -1 or count == 0:
        return np.nan
    tried = False
    while hi - lo > 1e-12 * scale:
        if count == 1 and not tried:
            tried = True
            value = _pencil_rayleigh(diag, off, jac, weight, lo, hi, scale)
            if lo <= value <= hi:
                margin = 1e-12 * scale
                if (below(diag, off, jac, weight, value - margin, scale) == 0
                        and below(diag, off, jac, weight, value + margin, scale) != 0):
                    return value
        mid = 0.5 * (lo + hi)
        found = below(diag, off, jac, weight, mid, scale)
        if found == -1:
            return np.nan
        if found == -2 or found >= 1:
            hi = mid
            count = found
        else:
            lo = mid
    return 0.5 * (lo + hi)


@njit(cache=True)
def _pencil_rayleigh(diag, off, jac, weight, lo, hi, scale):
    """The eigenvalue of the pencil (H, W) on J v = 0 that the bracket [lo, hi] holds
    alone: two steps of inverse iteration at lo, then Rayleigh quotient iteration
    ((H - q W) w = W v, J w = 0: ``kkt_solve``), kept inside the bracket; NaN where a
    solve fails. The caller proves the value by counts."""
    n, m = diag.shape[0], jac.shape[0]
    v = np.zeros(n + 2)
    for j in range(n):
        v[2 + j] = 1.0
    zero = np.zeros(m)
    rhs = np.zeros(n + 2)
    shifted = np.empty(n)
    sigma = lo
    value = np.nan
    for it in range(10):
        for j in range(n):
            shifted[j] = diag[j] - sigma * weight[j]
            rhs[2 + j] = weight[j] * v[2 + j]
        w, _, ok = kkt_solve(shifted, off, jac, 0.0, 0.0, rhs, zero)
        size = 0.0
        for j in range(n):
            size += weight[j] * w[2 + j] * w[2 + j]
        if not ok or not size > 0.0 or not math.isfinite(size):
            break  # singular at the shift: it is an eigenvalue to round-off
        size = math.sqrt(size)
        for j in range(n + 2):
            v[j] = w[j] / size
        t = tridiagonal_times(diag, off, v[2:])
        quotient = 0.0  # v^T H v, v of unit W-norm (H, W zero on the translations)
        for j in range(n):
            quotient += v[2 + j] * t[j]
        if abs(quotient - value) <= 1e-14 * scale:
            return quotient
        value = quotient
        if it >= 1 and lo < quotient < hi:
            sigma = quotient
    return value
