"""Banded linear algebra in numba: LU with partial pivoting on LAPACK's band layout,
A[i, j] = ab[j, kl + ku + i - j], ab of shape (n, 2 kl + ku + 1) in C order, which is
LAPACK's AB (ldab = 2 kl + ku + 1, column-major) itself: each matrix column one
contiguous row. The accurate 3D rod and the real-time network both number their
unknowns along the part, so their Jacobians are banded and a solve costs
O(n (kl + ku)^2).

``band_lu`` and ``band_lu_solve`` are dgbtf2's and dgbtrs's algorithms written out,
each pivot's update taken over its nonzero multipliers only: on pliant's own KKT
matrices (``benchmarks/banded.py``, factorise and solve) that is 0.81x LAPACK's time on
the engine bay's path and 0.59x on a hose lowered onto a block, whose band is sparser. LAPACK's
dgbtrf and dgbtrs (scipy's cython_lapack, called from the compiled kernels; their
addresses are registered as named symbols when this module loads, so the kernels that
call them still cache) are ``band_lu_lapack`` and ``band_lu_solve_lapack``, the tested
twin.
"""

from __future__ import annotations

import math

import llvmlite.binding as ll
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

for _name in ("dgbtrf", "dgbtrs"):
    ll.add_symbol(f"pliant_{_name}",
                  get_cython_function_address("scipy.linalg.cython_lapack", _name))
# Fortran's calling convention: every argument by address.
_dgbtrf = types.ExternalFunction("pliant_dgbtrf", types.void(*(types.voidptr,) * 8))
_dgbtrs = types.ExternalFunction("pliant_dgbtrs", types.void(*(types.voidptr,) * 11))


@njit(cache=True)
def add(ab, kl, ku, i, j, v):
    """A[i, j] += v."""
    ab[j, kl + ku + i - j] += v


@njit(cache=True)
def add_block(ab, kl, ku, i0, j0, block):
    """A[i0:, j0:] += block (zeros skipped)."""
    for r in range(block.shape[0]):
        for c in range(block.shape[1]):
            v = block[r, c]
            if v != 0.0:
                ab[j0 + c, kl + ku + i0 + r - j0 - c] += v


@njit(cache=True)
def _scale(ab):
    """The largest entry's size, or NaN where an entry is not finite (the sum of the
    sizes is finite exactly when every entry is, short of 1e308). Four running maxima
    and sums, so that the loop is not one chain of dependent operations: 0.34x the time
    of one (a float reduction does not vectorise without reassociation)."""
    flat = ab.ravel()
    n = flat.shape[0]
    s0 = s1 = s2 = s3 = 0.0
    t0 = t1 = t2 = t3 = 0.0
    k = 0
    while k + 4 <= n:
        a, b, c, d = abs(flat[k]), abs(flat[k + 1]), abs(flat[k + 2]), abs(flat[k + 3])
        s0, s1, s2, s3 = max(s0, a), max(s1, b), max(s2, c), max(s3, d)
        t0, t1, t2, t3 = t0 + a, t1 + b, t2 + c, t3 + d
        k += 4
    while k < n:
        a = abs(flat[k])
        s0 = max(s0, a)
        t0 += a
        k += 1
    scale = max(max(s0, s1), max(s2, s3))
    return scale if math.isfinite((t0 + t1) + (t2 + t3)) else math.nan


@njit(cache=True)
def band_lu_lapack(ab, kl, ku):
    """LU with partial pivoting of a band matrix, in place (LAPACK's dgbtrf): the twin
    ``band_lu`` is tested against. Returns (pivots, ok), ok as ``band_lu``'s."""
    n = ab.shape[0]
    piv = np.zeros(n, dtype=np.int32)
    scale = _scale(ab)
    if n == 0 or scale == 0.0 or not math.isfinite(scale):
        return piv, n == 0
    if not ab.flags.c_contiguous:  # LAPACK reads it in place: every caller builds one
        raise ValueError("band_lu: the band array must be C-contiguous")
    ints = np.array([n, n, kl, ku, ab.shape[1], 0], dtype=np.int32)  # m n kl ku ldab info
    _dgbtrf(ints[0:].ctypes, ints[1:].ctypes, ints[2:].ctypes,  # type: ignore[call-overload]
            ints[3:].ctypes, ab.ctypes, ints[4:].ctypes, piv.ctypes, ints[5:].ctypes)
    if ints[5] < 0:
        return piv, False
    kv = kl + ku
    for j in range(n):  # U's diagonal: the pivots
        if not abs(ab[j, kv]) > 1e-14 * scale:
            return piv, False
    return piv, True


@njit(cache=True)
def band_lu_solve_lapack(ab, piv, kl, ku, rhs):
    """Solve with the factors of ``band_lu_lapack`` (LAPACK's dgbtrs)."""
    n = ab.shape[0]
    x = rhs.copy()
    if n == 0:
        return x
    ints = np.array([n, kl, ku, 1, ab.shape[1], 0], dtype=np.int32)  # n kl ku nrhs ldab info
    trans = np.array([78], dtype=np.uint8)  # "N"
    _dgbtrs(trans.ctypes, ints[0:].ctypes, ints[1:].ctypes,  # type: ignore[call-overload]
            ints[2:].ctypes,
            ints[3:].ctypes, ab.ctypes, ints[4:].ctypes, piv.ctypes, x.ctypes,
            ints[0:].ctypes, ints[5:].ctypes)
    return x


@njit(cache=True)
def band_lu(ab, kl, ku):
    """LU with partial pivoting of a band matrix, in place: LAPACK's dgbtf2 written out,
    each pivot's update over its nonzero multipliers only (a KKT band is mostly zeros,
    which LAPACK multiplies through). Returns (pivots, ok); ok is False where a pivot is
    below 1e-14 of the largest entry (the matrix is singular to round-off: a fold, a
    bifurcation) or an entry is not finite."""
    n = ab.shape[0]
    kv = kl + ku
    piv = np.zeros(n, dtype=np.int64)
    rows = np.empty(kl + 1, dtype=np.int64)
    ju = 0
    scale = _scale(ab)
    if n == 0 or scale == 0.0 or not math.isfinite(scale):
        return piv, n == 0
    for j in range(n):
        km = min(kl, n - 1 - j)
        p = 0
        best = abs(ab[j, kv])
        for r in range(1, km + 1):
            v = abs(ab[j, kv + r])
            if v > best:
                best = v
                p = r
        piv[j] = j + p
        if best <= 1e-14 * scale:
            return piv, False
        ju = max(ju, min(j + ku + p, n - 1))
        if p != 0:
            for c in range(j, ju + 1):
                a = ab[c, kv + j - c]
                ab[c, kv + j - c] = ab[c, kv + j + p - c]
                ab[c, kv + j + p - c] = a
        inv = 1.0 / ab[j, kv]
        nz = 0  # the nonzero multipliers: a KKT band is mostly zeros
        for r in range(1, km + 1):
            ab[j, kv + r] *= inv
            if ab[j, kv + r] != 0.0:
                rows[nz] = r
                nz += 1
        if nz == 0:
            continue
        for c in range(j + 1, ju + 1):
            u = ab[c, kv + j - c]
            if u != 0.0:
                base = kv + j - c
                for t in range(nz):
                    r = rows[t]
                    ab[c, base + r] -= ab[j, kv + r] * u
    return piv, True


@njit(cache=True)
def band_lu_solve(ab, piv, kl, ku, rhs):
    """Solve with the factors of ``band_lu`` (dgbtrs written out, over slices: see
    ``band_lu``; 0.7x the time of indexed loops)."""
    n = ab.shape[0]
    kv = kl + ku
    x = rhs.copy()
    for j in range(n):
        km = min(kl, n - 1 - j)
        p = piv[j]
        if p != j:
            t = x[j]
            x[j] = x[p]
            x[p] = t
        t = x[j]
        if t != 0.0:
            mult = ab[j, kv + 1: kv + km + 1]
            below = x[j + 1: j + km + 1]
            for r in range(km):
                below[r] -= mult[r] * t
    for j in range(n - 1, -1, -1):
        t = x[j] / ab[j, kv]
        x[j] = t
        if t != 0.0:
            top = max(0, j - kv)
            column = ab[j, kv + top - j: kv]
            above = x[top: j]
            for i in range(j - top):
                above[i] -= column[i] * t
    return x


def band_solve(ab, kl, ku, rhs):
    """Solve A x = rhs for a band matrix (ab is overwritten); returns (x, ok). Not a
    kernel of its own: its two calls cost microseconds, a kernel's compile half a
    second on a first run."""
    piv, ok = band_lu(ab, kl, ku)
    if not ok:
        return rhs.copy(), False
    return band_lu_solve(ab, piv, kl, ku, rhs), True


@njit(cache=True)
def identity_rows(ab, kl, ku, first, width):
    """(n,) True where a row among first[k] .. first[k] + width - 1 is the identity's:
    1 on the diagonal and nothing else (a free contact probe's, whose force is 0)."""
    n = ab.shape[0]
    kv = kl + ku
    out = np.zeros(n, dtype=np.bool_)
    for k in range(first.shape[0]):
        for i in range(first[k], first[k] + width):
            if ab[i, kv] != 1.0:
                continue
            plain = True
            for j in range(max(0, i - kl), min(n, i + ku + 1)):
                if j != i and ab[j, kv + i - j] != 0.0:
                    plain = False
                    break
            out[i] = plain
    return out


@njit(cache=True)
def band_reduce(ab, kl, ku, drop):
    """The band matrix without the rows and columns where ``drop`` (n,) is True,
    renumbered in order and as narrow as its entries allow: (c, lo, up, new), c in the
    same layout with lo sub- and up superdiagonals, new (n,) each unknown's number in it
    (-1 where dropped). Each column is searched from its band's ends inward, only as far
    as it could widen the band found so far, and copied in runs of kept rows: the band
    is mostly zeros, and the copy is what the time goes to."""
    n = ab.shape[0]
    kv = kl + ku
    new = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if drop[i]:
            new[i] = -1
        else:
            new[i] = m
            m += 1
    lo = 0
    up = 0
    for j in range(n):
        if drop[j]:
            continue
        nj = new[j]
        for i in range(max(0, j - ku), j):  # above the diagonal, farthest first
            if not drop[i]:
                if nj - new[i] <= up:
                    break
                if ab[j, kv + i - j] != 0.0:
                    up = nj - new[i]
                    break
        for i in range(min(n - 1, j + kl), j, -1):  # below it
            if not drop[i]:
                if new[i] - nj <= lo:
                    break
                if ab[j, kv + i - j] != 0.0:
                    lo = new[i] - nj
                    break
    w = 2 * lo + up + 1
    c = np.zeros((m, w))
    for j in range(n):
        if drop[j]:
            continue
        jn = new[j]
        i = max(0, j - ku)
        end = min(n, j + kl + 1)
        while i < end:
            if drop[i]:
                i += 1
                continue
            k = i + 1
            while k < end and not drop[k]:
                k += 1
            # Rows i .. k - 1 are kept: consecutive in both numberings. Entries outside
            # the narrowed band are zeros.
            off = lo + up + new[i] - jn
            src = kv + i - j
            for t in range(max(0, lo - off), min(k - i, w - off)):
                c[jn, off + t] = ab[j, src + t]
            i = k
    return c, lo, up, new


@njit(cache=True)
def band_factor_reduced(ab, kl, ku, drop):
    """The LU factors of A without the identity rows ``drop`` (see
    ``band_solve_reduced``): (c, lo, up, new, piv, ok); ``ab`` is left as it was, and
    with it they solve any right-hand side (``band_solve_factored``)."""
    c, lo, up, new = band_reduce(ab, kl, ku, drop)
    if c.shape[0] == 0:
        return c, lo, up, new, np.zeros(0, dtype=np.int64), True
    piv, ok = band_lu(c, lo, up)
    return c, lo, up, new, piv, ok


@njit(cache=True)
def band_solve_factored(ab, kl, ku, drop, c, lo, up, new, piv, rhs):
    """Solve A x = rhs with ``band_factor_reduced``'s factors of A (``ab``, unchanged):
    the known unknowns (x_i = rhs_i where drop[i]) go to the right-hand side through
    A's columns, the others through the factors."""
    n = ab.shape[0]
    if c.shape[0] == n:  # nothing dropped (c is A's band, perhaps narrowed)
        return band_lu_solve(c, piv, lo, up, rhs)
    x = np.zeros(n)
    b = rhs.copy()
    for j in range(n):
        if drop[j]:
            xj = rhs[j]
            x[j] = xj
            if xj != 0.0:
                for i in range(max(0, j - ku), min(n, j + kl + 1)):
                    if i != j:
                        b[i] -= ab[j, kl + ku + i - j] * xj
    m = c.shape[0]
    if m == 0:
        return x
    bc = np.empty(m)
    for j in range(n):
        if not drop[j]:
            bc[new[j]] = b[j]
    y = band_lu_solve(c, piv, lo, up, bc)
    for i in range(n):
        if not drop[i]:
            x[i] = y[new[i]]
    return x


def band_solve_reduced(ab, kl, ku, rhs, drop):
    """Solve A x = rhs where each row i with drop[i] is the identity's (x_i = rhs_i is
    known): those unknowns go to the right-hand side and only the others are factorised,
    in a band renumbered without them (``band_reduce``). The contact probes far from
    everything are such rows: leaving them out halves the factorisation. ``ab`` is left
    as it was. Returns (x, ok). Not a kernel of its own (see ``band_solve``)."""
    c, lo, up, new, piv, ok = band_factor_reduced(ab, kl, ku, drop)
    if not ok:
        return np.zeros(ab.shape[0]), False
    return band_solve_factored(ab, kl, ku, drop, c, lo, up, new, piv, rhs), True


def dense(ab, kl: int, ku: int, n: int) -> np.ndarray:
    """The n x n matrix stored in band form (for dense fallbacks and checks)."""
    out = np.zeros((n, n))
    for j in range(n):
        for i in range(max(0, j - ku), min(n, j + kl + 1)):
            out[i, j] = ab[j, kl + ku + i - j]
    return out
