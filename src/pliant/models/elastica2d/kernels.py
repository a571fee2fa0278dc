"""Numba kernels of the 2D elastica: shooting with exact sensitivities, and Newton.

Everything here is dimensionless: arc length by the part length L, forces by EI/L^2,
moments by EI/L. The state along the neutral line is

    h(s) = [x, y, theta, nx, ny, m, e]

where (x, y) is the neutral line, theta the tangent angle from +x, n = (nx, ny) the
internal force in the global frame and m the bending moment, both exerted by the part
beyond s on the part before s, and e the accumulated elastic energy. The paper's
H = [x, y, theta, N, Q, M] follows from N = n . t and Q = n . nu with t = (cos theta,
sin theta) and nu = (-sin theta, cos theta). The equations (Kirchhoff, unshearable) are

    x' = lam cos theta,  y' = lam sin theta,  theta' = kappa0(s) + m,
    n' = -f,  m' = -lam (t x n) = -lam (cos theta ny - sin theta nx),
    e' = m^2 / 2 + c N^2 / 2,   lam = 1 + c N,

with f the distributed dead load (self-weight) and s the arc length of the unloaded
part. c = EI / (EA L^2) is the axial compliance: the part stretches by the axial strain
N / EA (Reissner's extensible elastica, unshearable); c = 0 is the inextensible part
(the paper's equations), the limit EA -> infinity of the same equations.

A station k applies a point force P_k and a point moment C_k to the part, so that
n(s_k-) = n(s_k+) + P_k and m(s_k-) = m(s_k+) + C_k, with n(0-) = 0 and n(1+) = 0 at the
two ends. Each of the three pairs (x, Px), (y, Py), (theta, C) of a station is either
prescribed (the position or angle is given, the load is an unknown reaction) or applied
(the load is given).

The unknowns z are, at s = 0, for each pair the unknown half (reaction or position), and
at every later station one reaction per prescribed component. The residuals are the
prescribed components at every later station, and n(1+) = 0, m(1+) = 0. The system is
square by construction. Sensitivities dh/dz are integrated with the same Runge-Kutta
stages as the state (internal differentiation), so the Jacobian is the exact derivative
of the discrete map and Newton converges quadratically.

Multiple shooting: under large loads the sensitivities grow like exp(k s), k the
wavenumber sqrt(|n|/EI), and single shooting loses all accuracy once k L passes about
20 (a floppy cable hanging under its weight reaches k L ~ 100). Restart *nodes* (kind
NODE) cut the part: the whole state at a node is 6 more unknowns, matched by 6 residuals
(the state arriving from the left minus them), and the integration restarts from them.
Sensitivities then only grow across one interval; a segment carries the sensitivity
columns [lo, hi) of the unknowns that act on it.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np
from numba import njit, objmode

from pliant.models.elastica2d.tableau import dop853

NSTATE = 7  # x, y, theta, nx, ny, m, e
APPLIED = 0
PRESCRIBED = 1
NODE = 2  # a restart node of multiple shooting (all of its pairs)

# The Runge-Kutta tableau, frozen into the compiled kernels as constants.
_A, _B, _C = dop853()



class Stations(NamedTuple):
    """What the lowering fixes: each kernel station's s (nst,), the kind of its three
    pairs (nst, 3: APPLIED, PRESCRIBED or NODE) and their unknowns' columns (nst, 3),
    the live sensitivity columns [seg_lo, seg_hi) of each segment (nst - 1,), and the
    rest curvature at the stations (nst,), linear in between."""

    st_s: np.ndarray
    st_kind: np.ndarray
    st_col: np.ndarray
    seg_lo: np.ndarray
    seg_hi: np.ndarray
    st_kappa: np.ndarray


class Inputs(NamedTuple):
    """What a homotopy moves: per station the prescribed kinematics or applied dead
    loads (nst, 3) and follower forces (nst, 2: tangential, normal); per segment (its
    first station's row) the distributed loads on it beyond ``prm``'s uniform one
    (nst, 4: dead fx, fy; follower ft, fn, per unit length); and
    prm (6,) = [fx, fy, bow, a, b, c] (see ``shoot``)."""

    val: np.ndarray
    fol: np.ndarray
    dist: np.ndarray
    prm: np.ndarray


class Work(NamedTuple):
    """The integrator's scratch and outputs: stage slopes K (nst, 4) of (theta, m, nx,
    ny) and their sensitivities KY (nst, 4, nz), the trajectory (rows, 7) with its
    cursor (1,), and the statistics (2,) max|theta'| and max|n|."""

    K: np.ndarray
    KY: np.ndarray
    traj: np.ndarray
    cursor: np.ndarray
    stats: np.ndarray


# Newton status codes, mirrored by ``solver.Status``.
CONVERGED = 0
MAX_ITERATIONS = 1
SINGULAR = 2
NOT_CONTRACTING = 3
NOT_FINITE = 4


@njit(cache=True, inline="always")
def _apply_station(k, y, Y, cols, z, stn, inp, out, row, want_jac):
    """Residuals of station k (k >= 1) and its jump, or its restart for a node, into
    out = (residual, Jacobian) from ``row``; returns the next residual row.

    cols = (lo, hi): the sensitivity columns [lo, hi) live from here on (those of the
    segment that ends here plus the ones this station introduces).
    """
    lo, hi = cols
    res, jac = out
    st_kind, st_col, st_val, st_fol = stn.st_kind, stn.st_col, inp.val, inp.fol
    if st_kind[k, 0] == NODE:
        c0 = st_col[k, 0]
        for q in range(6):
            res[row + q] = y[q] - z[c0 + q]
            if want_jac:
                for j in range(lo, hi):
                    jac[row + q, j] = Y[q, j]
                jac[row + q, c0 + q] -= 1.0
        for q in range(6):
            y[q] = z[c0 + q]
            if want_jac:
                for j in range(lo, hi):
                    Y[q, j] = 0.0
                Y[q, c0 + q] = 1.0
        return row + 6
    for i in range(3):
        if st_kind[k, i] == PRESCRIBED:
            res[row] = y[i] - st_val[k, i]
            if want_jac:
                for q in range(lo, hi):
                    jac[row, q] = Y[i, q]
            row += 1
    for i in range(3):
        if st_kind[k, i] == PRESCRIBED:
            col = st_col[k, i]
            y[3 + i] -= z[col]
            if want_jac:
                Y[3 + i, col] -= 1.0
        else:
            y[3 + i] -= st_val[k, i]
    _apply_follower(k, y, Y, lo, hi, st_fol, want_jac)
    return row


@njit(cache=True)
def _apply_follower(k, y, Y, lo, hi, st_fol, want_jac):
    """Subtract the follower force R(theta) (ft, fn) of station k from n."""
    ft = st_fol[k, 0]
    fn = st_fol[k, 1]
    if ft == 0.0 and fn == 0.0:
        return
    c = math.cos(y[2])
    sn = math.sin(y[2])
    y[3] -= ft * c - fn * sn
    y[4] -= ft * sn + fn * c
    if want_jac:
        dpx = -ft * sn - fn * c
        dpy = ft * c - fn * sn
        for q in range(lo, hi):
            Y[3, q] -= dpx * Y[2, q]
            Y[4, q] -= dpy * Y[2, q]


@njit(cache=True, inline="always")
def turned(c, s, theta, dth):
    """(cos, sin) of theta + dth from c, s = cos theta, sin theta: where |dth| <= 0.5 by
    Taylor's series of dth (to dth^14: a remainder below 1e-16) and the sum formulas, a
    third of the cost of calling both (the integrator's hot loop turns each stage's
    angle from its step's start by a small dth); else by calling them."""
    if abs(dth) <= 0.5:
        # Estrin's scheme: the powers and pairs are independent, so the polynomials'
        # latency is about half Horner's (each stage waits on its angle's turn).
        d2 = dth * dth
        d4 = d2 * d2
        d8 = d4 * d4
        cm1 = d2 * ((-0.5 + d2 * (1.0 / 24.0)) + d4 * (-1.0 / 720.0 + d2 * (1.0 / 40320.0))
                    + d8 * ((-1.0 / 3628800.0 + d2 * (1.0 / 479001600.0))
                            - d4 * (1.0 / 87178291200.0)))
        sd = dth * ((1.0 - d2 * (1.0 / 6.0)) + d4 * (1.0 / 120.0 - d2 * (1.0 / 5040.0))
                    + d8 * ((1.0 / 362880.0 - d2 * (1.0 / 39916800.0))
                            + d4 * (1.0 / 6227020800.0)))
        return c + (c * cm1 - s * sd), s + (s * cm1 + c * sd)
    return math.cos(theta + dth), math.sin(theta + dth)


@njit(cache=True, inline="always")
def _segment(k, stn, inp):
    """What ``_integrate`` needs of segment k, as scalars."""
    prm, dist = inp.prm, inp.dist
    return (stn.st_s[k], stn.st_s[k + 1], stn.st_kappa[k], stn.st_kappa[k + 1],
            prm[0] + dist[k, 0], prm[1] + dist[k, 1], dist[k, 2], dist[k, 3], prm[2],
            prm[3], prm[4], prm[5])


@njit(cache=True)
def _integrate(y, Y, lo, hi, seg, nsteps, work, want_jac):
    """Advance (y, Y) over a segment in nsteps fixed RK steps; write states to the
    trajectory (``Work``). seg = (s0, s1, kappa0, kappa1, fx, fy, ft, fn, bow, a, b, c):
    where it starts and ends, its rest curvature there, the dead (fx, fy) and follower
    (ft, fn) loads per length on it, and prm[2:] (see ``shoot``): scalars, which cost
    nothing to pass, where the bundles' arrays would be counted in and out per call.

    Only (theta, m) feed back into the equations, so only they (and their sensitivities)
    are carried through the stages; x, y and the energy are quadratures of the stage
    values with the weights b. With a dead distributed load f, n is exactly linear in s,
    n(s) = n(s0) - f (s - s0), and its sensitivities are constant on the segment. The
    rest curvature is linear on the segment, from kappa0 at s0 to kappa1 at s1 (its knots
    are stations); the imperfection bow cos(2 pi (s - a) / (b - a)) acts on [a, b] (both
    stations). stats[0], stats[1] accumulate max|theta'| and max|n| at step ends.
    A follower load f = ft t + fn nu on the segment makes n' = -(g + f) depend on theta:
    then n is integrated through the stages with theta and m, and so are its
    sensitivities (d f / d theta = ft nu - fn t). [lo, hi) the live columns.
    """
    a = _A
    b = _B
    c = _C
    K, KY, traj, stats = work.K, work.KY, work.traj, work.stats
    tpos = work.cursor[0]
    s0, s1, kappa0, kappa1, gx, gy, ft, fn, bow, bow_a, bow_b, comp = seg
    h = (s1 - s0) / nsteps
    slope = (kappa1 - kappa0) / (s1 - s0)
    follower = ft != 0.0 or fn != 0.0
    if s0 < bow_a - 1e-12 or s1 > bow_b + 1e-12:
        bow = 0.0
    span = bow_b - bow_a
    nx0 = y[3]
    ny0 = y[4]
    nst = b.shape[0]
    record = traj.shape[0] > 0
    if record:
        for q in range(NSTATE):
            traj[tpos, q] = y[q]
        tpos += 1
    # h a once per segment; the tableau's zeros are multiplied, not tested (the branch
    # cost more than the multiply-add it saved).
    ha = np.empty((nst, nst))
    for i in range(nst):
        for j in range(nst):
            ha[i, j] = h * a[i, j]
    for step in range(nsteps):
        s = s0 + step * h
        th0 = y[2]
        cos0 = math.cos(th0)
        sin0 = math.sin(th0)
        m0 = y[5]
        nxs = y[3]
        nys = y[4]
        dx = 0.0
        dy = 0.0
        de = 0.0
        for i in range(nst):
            dth = 0.0
            m = m0
            for j in range(i):
                w = ha[i, j]
                dth += w * K[j, 0]
                m += w * K[j, 1]
            si = s + c[i] * h
            if follower:
                nx = nxs
                ny = nys
                for j in range(i):
                    w = ha[i, j]
                    nx += w * K[j, 2]
                    ny += w * K[j, 3]
            else:
                nx = nx0 - gx * (si - s0)
                ny = ny0 - gy * (si - s0)
            ct, st = turned(cos0, sin0, th0, dth)
            if follower:  # n' = -(g + ft t + fn nu)
                K[i, 2] = -(gx + ft * ct - fn * st)
                K[i, 3] = -(gy + ft * st + fn * ct)
            kappa = kappa0 + slope * (si - s0) + m
            if bow != 0.0:
                kappa += bow * math.cos(2.0 * math.pi * (si - bow_a) / span)
            K[i, 0] = kappa
            shear = ct * ny - st * nx
            bi = b[i]
            if comp == 0.0:
                K[i, 1] = -shear
                if bi != 0.0:
                    dx += bi * ct
                    dy += bi * st
                    de += bi * 0.5 * m * m
            else:
                axial = ct * nx + st * ny
                lam = 1.0 + comp * axial
                K[i, 1] = -lam * shear
                if bi != 0.0:
                    dx += bi * lam * ct
                    dy += bi * lam * st
                    de += bi * 0.5 * (m * m + comp * axial * axial)
            if want_jac:
                dm_dth = st * ny + ct * nx
                hb = h * bi
                for q in range(lo, hi):
                    yth = Y[2, q]
                    ym = Y[5, q]
                    for j in range(i):
                        w = ha[i, j]
                        yth += w * KY[j, 0, q]
                        ym += w * KY[j, 1, q]
                    ynx = Y[3, q]
                    yny = Y[4, q]
                    if follower:
                        for j in range(i):
                            w = ha[i, j]
                            ynx += w * KY[j, 2, q]
                            yny += w * KY[j, 3, q]
                        # d/dtheta of -(ft t + fn nu) = (ft sin + fn cos, fn sin - ft cos)
                        KY[i, 2, q] = (ft * st + fn * ct) * yth
                        KY[i, 3, q] = (fn * st - ft * ct) * yth
                    KY[i, 0, q] = ym
                    if comp == 0.0:
                        KY[i, 1, q] = dm_dth * yth + st * ynx - ct * yny
                        if bi != 0.0:
                            Y[0, q] -= hb * st * yth
                            Y[1, q] += hb * ct * yth
                    else:
                        # dN = Q dtheta + t . dn, and lam = 1 + c N
                        dlam = comp * (shear * yth + ct * ynx + st * yny)
                        KY[i, 1, q] = (lam * (dm_dth * yth + st * ynx - ct * yny)
                                       - dlam * shear)
                        if bi != 0.0:
                            Y[0, q] += hb * (dlam * ct - lam * st * yth)
                            Y[1, q] += hb * (dlam * st + lam * ct * yth)
        for i in range(nst):
            w = h * b[i]
            if w != 0.0:
                y[2] += w * K[i, 0]
                y[5] += w * K[i, 1]
                if follower:
                    y[3] += w * K[i, 2]
                    y[4] += w * K[i, 3]
                if want_jac:
                    for q in range(lo, hi):
                        Y[2, q] += w * KY[i, 0, q]
                        Y[5, q] += w * KY[i, 1, q]
                        if follower:
                            Y[3, q] += w * KY[i, 2, q]
                            Y[4, q] += w * KY[i, 3, q]
        y[0] += h * dx
        y[1] += h * dy
        y[6] += h * de
        if not follower:
            y[3] = nx0 - gx * (s + h - s0)
            y[4] = ny0 - gy * (s + h - s0)
        if record:
            for q in range(NSTATE):
                traj[tpos, q] = y[q]
            tpos += 1
        kappa = abs(K[nst - 1, 0])
        if kappa > stats[0]:
            stats[0] = kappa
        force = math.sqrt(y[3] * y[3] + y[4] * y[4])
        if force > stats[1]:
            stats[1] = force
    work.cursor[0] = tpos


@njit(cache=True)
def shoot(z, stations, inputs, seg_steps, want_jac, traj):
    """``_shoot`` called from Python: stations and inputs the fields of ``Stations``
    and ``Inputs`` as plain tuples (numba types a plain tuple in C, a NamedTuple in
    Python, a microsecond a call on the warm path)."""
    return _shoot(z, Stations(*stations), Inputs(*inputs), seg_steps, want_jac, traj)


@njit(cache=True)
def _shoot(z, stn, inp, seg_steps, want_jac, traj):
    """Integrate from s = 0 to 1 with unknowns z (the ``Stations`` stn, the ``Inputs``
    inp, seg_steps RK steps per segment); return (residual, Jacobian, stats).

    prm : (6,) float, [fx, fy, bow, a, b, c]: the distributed dead load (fx, fy) per unit
        length, a rest-curvature imperfection bow * cos(2 pi (s - a) / (b - a)) on
        [a, b] that the solver adds, then removes, to leave a singular (symmetric) start,
        and the axial compliance c = EI / (EA L^2) (0: inextensible)
    stats : (2,) float, max|theta'| and max|n| over the step ends: the wavenumber
        max|theta'| + sqrt(max|n|) tells the caller whether the mesh resolves the solution
    traj : (npts, 7) float, written when it has rows: the state at both ends of every
        step, segment by segment (stations appear twice: before and after their jump)
    """
    nz = z.shape[0]
    st_kind, seg_lo, seg_hi = stn.st_kind, stn.seg_lo, stn.seg_hi
    st_val, st_fol = inp.val, inp.fol
    nstations = stn.st_s.shape[0]
    res = np.zeros(nz)
    jac = np.zeros((nz, nz))
    y = np.zeros(NSTATE)
    Y = np.zeros((6, nz))
    # Station 0: each pair gives one unknown, z[i].
    for i in range(3):
        if st_kind[0, i] == PRESCRIBED:
            y[i] = st_val[0, i]
            y[3 + i] = -z[i]
            Y[3 + i, i] = -1.0
        else:
            y[i] = z[i]
            y[3 + i] = -st_val[0, i]
            Y[i, i] = 1.0
    first = nstations * 0  # runtime ints, not literals (see newton)
    _apply_follower(first, y, Y, first, first + 3, st_fol, want_jac)
    nst = _B.shape[0]
    # The stages carry n (columns 2, 3) only where a follower load acts on a segment.
    carried = 2
    for k in range(nstations - 1):
        if inp.dist[k, 2] != 0.0 or inp.dist[k, 3] != 0.0:
            carried = 4
    work = Work(np.empty((nst, carried)), np.zeros((nst, carried, nz)), traj,
                np.zeros(1, dtype=np.int64), np.zeros(2))
    row = 0
    for k in range(nstations - 1):
        lo = seg_lo[k]
        _integrate(y, Y, lo, seg_hi[k], _segment(k, stn, inp), seg_steps[k], work,
                   want_jac)
        hi_next = seg_hi[k + 1] if k + 1 < nstations - 1 else nz
        row = _apply_station(k + 1, y, Y, (lo, hi_next), z, stn, inp, (res, jac), row,
                             want_jac)
    # Beyond the last end nothing acts: n(1+) = 0 and m(1+) = 0.
    lo = seg_lo[nstations - 2]
    for i in range(3):
        res[row] = y[3 + i]
        if want_jac:
            for q in range(lo, nz):
                jac[row, q] = Y[3 + i, q]
        row += 1
    return res, jac, work.stats


@njit(cache=True)
def bandwidths(A):
    """(kl, ku): the most any nonzero lies below and above the diagonal. Multiple
    shooting numbers its unknowns along the part, so its Jacobian is banded (each
    interval's end meets the next one's start): kl about 8 and ku 3 whatever the
    number of intervals."""
    n = A.shape[0]
    kl = 0
    ku = 0
    for i in range(n):
        for j in range(n):
            if A[i, j] != 0.0:
                if i - j > kl:
                    kl = i - j
                elif j - i > ku:
                    ku = j - i
    return kl, ku


@njit(cache=True)
def lu_solve(A, rhs):
    """Solve A x = rhs by Gaussian elimination with partial pivoting, each row first
    scaled by its largest entry (row equilibration: the shooting Jacobian's rows are
    conditions of very different sizes, a taut cable's axial stiffness beside a free
    end's moment, and a pivot is only small against its own row's scale).

    Only the band is visited (``bandwidths``: pivoting widens the upper band to kl + ku
    at most, and every entry outside stays zero): the same operations on every entry
    that is not zero, so the same answer as a dense elimination, in O(n kl (kl + ku))
    where a dense one took n^3 / 3 (40 intervals: 240 unknowns).

    Returns (x, ok); ok is False when a pivot falls below 1e-13 (the rows scaled to 1),
    which the caller reports as a singular Jacobian (a fold or bifurcation point, or an
    ill-posed problem).
    """
    n = rhs.shape[0]
    kl, ku = bandwidths(A)
    M = A.copy()
    x = rhs.copy()
    for i in range(n):
        big = 0.0
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            v = abs(M[i, j])
            if v > big:
                big = v
        if big == 0.0 or not math.isfinite(big):
            return x, False
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            M[i, j] /= big
        x[i] /= big
    scale = 1.0
    for col in range(n):
        below = min(n, col + kl + 1)
        right = min(n, col + kl + ku + 1)
        piv = col
        best = abs(M[col, col])
        for r in range(col + 1, below):
            v = abs(M[r, col])
            if v > best:
                best = v
                piv = r
        if best <= 1e-13 * scale:
            return x, False
        if piv != col:
            for j in range(col, right):
                t = M[col, j]
                M[col, j] = M[piv, j]
                M[piv, j] = t
            t = x[col]
            x[col] = x[piv]
            x[piv] = t
        for r in range(col + 1, below):
            f = M[r, col] / M[col, col]
            if f != 0.0:
                for j in range(col, right):
                    M[r, j] -= f * M[col, j]
                x[r] -= f * x[col]
    for col in range(n - 1, -1, -1):
        acc = x[col]
        for j in range(col + 1, min(n, col + kl + ku + 1)):
            acc -= M[col, j] * x[j]
        x[col] = acc / M[col, col]
    return x, True


@njit(cache=True)
def det_sign(A):
    """Sign of det(A) by Gaussian elimination with partial pivoting (0 if singular),
    over the band alone (as ``lu_solve``)."""
    n = A.shape[0]
    kl, ku = bandwidths(A)
    M = A.copy()
    sign = 1.0
    for col in range(n):
        below = min(n, col + kl + 1)
        right = min(n, col + kl + ku + 1)
        piv = col
        best = abs(M[col, col])
        for r in range(col + 1, below):
            if abs(M[r, col]) > best:
                best = abs(M[r, col])
                piv = r
        if best == 0.0:
            return 0.0
        if piv != col:
            sign = -sign
            for j in range(col, right):
                t = M[col, j]
                M[col, j] = M[piv, j]
                M[piv, j] = t
        if M[col, col] < 0.0:
            sign = -sign
        for r in range(col + 1, below):
            f = M[r, col] / M[col, col]
            for j in range(col, right):
                M[r, j] -= f * M[col, j]
    return sign


@njit(cache=True)
def max_abs(v):
    m = 0.0
    for i in range(v.shape[0]):
        a = abs(v[i])
        if a > m or a != a:
            m = a
    return m


@njit(cache=True)
def _broyden(jac, step, res_new, res_old):
    """Broyden's rank-one update of a reused Jacobian after a step: afterwards
    jac @ step equals the observed change of the residual. Where the Jacobian is banded
    (multiple shooting), Schubert's: each row changes only within the band, by the part
    of the step there (the same secant condition), so that the next solve stays banded
    (``lu_solve``); a dense update filled the band of 40 intervals' 240 unknowns."""
    n = step.shape[0]
    kl, ku = bandwidths(jac)
    if kl + ku + 1 >= n:
        kl = ku = n
    for i in range(n):
        lo, hi = max(0, i - kl), min(n, i + ku + 1)
        ss = 0.0
        for j in range(lo, hi):
            ss += step[j] * step[j]
        if ss == 0.0:
            continue
        miss = res_new[i] - res_old[i]
        for j in range(lo, hi):
            miss -= jac[i, j] * step[j]
        f = miss / ss
        for j in range(lo, hi):
            jac[i, j] += f * step[j]


# A damped Newton whose residual fell by less than 1 % over its last STALL_SPAN iterations
# is stuck (at a minimum of the residual's norm that is no root: the backtracking accepts
# steps that lower it by 1e-4 of itself); it stops there instead of running out its
# iterations. From the energy minima's starts over 900 held targets, 210 damped Newtons
# sat at one residual for 20 of their 25 iterations, a tenth of all the solves' time.
STALL_SPAN = 6
STALL_DROP = 0.99


@njit(cache=True)
def newton(z0, jac0, stations, inputs, seg_steps, tol, max_iter, contraction):
    """``_newton`` called from Python (stations and inputs as plain tuples, see
    ``shoot``)."""
    return _newton(z0, jac0, Stations(*stations), Inputs(*inputs), seg_steps, tol,
                   max_iter, contraction)


@njit(cache=True)
def _newton(z0, jac0, stn, inp, seg_steps, tol, max_iter, contraction):
    """Newton on the shooting residual, reusing its Jacobian while it contracts fast.

    jac0 : a Jacobian near z0 to start with (a warm start's), or an empty array.
    contraction > 0: a continuation corrector. No damping: the iteration is rejected
        (NOT_CONTRACTING) when, with a fresh Jacobian, the residual fails to shrink by
        that factor, which tells the caller to take a shorter step instead of letting
        Newton wander onto another branch.
    contraction <= 0: a damped Newton with backtracking on the residual norm.
    A reused (stale) Jacobian gets Broyden updates and is refreshed whenever an
    iteration contracts by less than 10x, so the convergence stays superlinear at a
    fraction of the cost of fresh Jacobians.

    Returns (z, residual_inf_norm, iterations, status, jac, stats, theta), theta the
    contraction r1 / r0 of the first iteration (of the failing one when rejected).
    """
    empty = np.zeros((0, NSTATE))
    nz = z0.shape[0]
    # Runtime flags, not the literals True and False: numba compiles a callee once more
    # for each literal it is called with (three versions of shoot, seven of _integrate).
    yes, no = nz >= 0, nz < 0
    z = z0.copy()
    fresh = jac0.shape[0] != nz
    res, jac, stats = _shoot(z, stn, inp, seg_steps, fresh, empty)
    if not fresh:
        jac = jac0.copy()
    r = max_abs(res)
    theta = 0.0
    if not math.isfinite(r):
        return z, r, 0, NOT_FINITE, jac, stats, 1.0
    it = 0
    past = np.empty(STALL_SPAN)  # the damped Newton's residuals, the last STALL_SPAN
    while it < max_iter:
        if r <= tol:
            return z, r, it, CONVERGED, jac, stats, theta
        if contraction <= 0.0:
            if it >= STALL_SPAN and r > STALL_DROP * past[it % STALL_SPAN]:
                return z, r, it, NOT_CONTRACTING, jac, stats, theta  # stuck: see STALL_SPAN
            past[it % STALL_SPAN] = r
        it += 1
        dz, ok = lu_solve(jac, -res)
        if not ok:
            if fresh:
                return z, r, it, SINGULAR, jac, stats, 1.0
            res, jac, stats = _shoot(z, stn, inp, seg_steps, yes, empty)
            fresh = True
            continue
        t = 1.0
        accepted = False
        for _ in range(40):
            zt = z + t * dz
            rt_vec, _, st = _shoot(zt, stn, inp, seg_steps, no, empty)
            rt = max_abs(rt_vec)
            if it == 1 or not math.isfinite(rt):
                theta = rt / r if math.isfinite(rt) else 1e3
            if contraction > 0.0:
                accepted = rt <= contraction * r or rt <= tol
                break
            if math.isfinite(rt) and rt <= (1.0 - 1e-4 * t) * r:
                accepted = True
                break
            if not fresh:
                break
            t *= 0.5
        if not accepted:
            if fresh:
                # At the round-off floor of a stiff problem (a taut cable: forces of
                # thousands of EI / L^2 in the residual's terms) no step lowers the
                # residual any more: the Newton step is then round-off itself.
                size = 1.0 + max_abs(z)
                if r <= 1e3 * tol * size and max_abs(dz) <= 1e-9 * size:
                    return z, r, it, CONVERGED, jac, stats, theta
                return z, r, it, NOT_CONTRACTING, jac, stats, max(theta, rt / r)
            # A stale Jacobian may be to blame: refresh it and try again from z.
            res, jac, stats = _shoot(z, stn, inp, seg_steps, yes, empty)
            fresh = True
            continue
        # Round-off floor: a step this small cannot lower the residual any further.
        stagnant = max_abs(t * dz) <= 1e-13 * (1.0 + max_abs(z)) and rt <= 1e3 * tol
        slow = rt > 0.1 * r
        if not fresh:
            _broyden(jac, t * dz, rt_vec, res)
        z = zt
        res = rt_vec
        r = rt
        stats = st
        if stagnant:
            return z, r, it, CONVERGED, jac, stats, theta
        if slow and r > tol:
            res, jac, stats = _shoot(z, stn, inp, seg_steps, yes, empty)
            fresh = True
        else:
            fresh = False
    if r <= tol:
        return z, r, it, CONVERGED, jac, stats, theta
    return z, r, it, MAX_ITERATIONS, jac, stats, theta


# Continuation status codes (beyond Newton's).
STALLED = 5
BUDGET = 6
# A continuation's forces outgrew its shooting intervals (``follow``'s last status).
NEEDS_NODES = 7
# A continuation ran past its deadline (``follow``'s last status, with BUDGET).
OUT_OF_TIME = 8
# The work (Runge-Kutta steps times the sensitivity columns carried, each Newton
# iteration) between two looks at the clock in ``follow``: some milliseconds, so that a
# path stops within about that of its deadline, and a small problem never looks (a look
# leaves the compiled code for the interpreter: a microsecond or two).
CLOCK_WORK = 100_000

# Layout of the options vector of ``follow``.
OPT_TOL, OPT_LOOSE, OPT_CONTRACTION, OPT_MIN_STEP, OPT_MAX_STEPS, OPT_MAX_ITER, \
    OPT_ACCURACY, OPT_MIN_DENSITY, OPT_GROW, OPT_SHRINK, OPT_PATH_ACCURACY, \
    OPT_WAVE_STEP, OPT_NODE_LIMIT, OPT_PATH_MIN_DENSITY = range(14)


# A step that would leave less than a quarter of itself to go takes the rest at once,
# up to a quarter longer than the caps allow: the sliver left would cost a corrector of
# its own to the full tolerance (the paper's case 1 reached t = 0.974 and then 1). The
# 2D model's shared driver takes it too (``continuation.Stepping.last_stretch``).
LAST_STRETCH = 1.25
# A path that creeps (more than CREEP_STEPS steps shorter than CREEP) on intervals its
# forces have outgrown by the answers' own bound (k times the longest past NODE_SPAN, two
# thirds of the node limit) asks for more intervals too: each widens Newton's basin, whose
# width there made the steps short (a hairpin's unbow leg crept from t = 0.98 to a fold
# at 0.99997 in 391 steps of 7e-5, 0.46 s; over 900 held targets, 12 % of the time).
CREEP = 1e-3
CREEP_STEPS = 25
CREEP_SPAN = 2.0 / 3.0

# A step refused leaves a memory: the steps after it grow to no more than half of it,
# and the memory fades by a factor REFUSED_FADE at each step taken. Without it the steps
# alternated near a fold or on a creeping path (taken at dt, grown fourfold and refused,
# taken at dt again): half of each such path's correctors were refused ones.
REFUSED_FADE = 1.5


@njit(cache=True)
def mesh_steps(st_s, density):
    """Runge-Kutta steps per segment for a number of steps per unit length."""
    n = st_s.shape[0] - 1
    steps = np.empty(n, dtype=np.int64)
    for k in range(n):
        steps[k] = max(1, int(math.ceil((st_s[k + 1] - st_s[k]) * density - 1e-9)))
    return steps


@njit(cache=True)
def sample_rows(st_s, steps, length):
    """Where a trajectory's rows lie (``shoot``'s traj on these steps per segment): the
    arc length of each, times ``length`` (each segment's points evenly spaced by numpy
    linspace's arithmetic, i (b - a) / n + a, its last exactly its end), and the row of
    each station (its segment's first; the last station's, the last row). One call where
    numpy's small-array calls took 6 us of a sample's 40."""
    n = st_s.shape[0] - 1
    total = 0
    for k in range(n):
        total += steps[k] + 1
    grid = np.empty(total)
    rows = np.empty(n + 1, dtype=np.int64)
    row = 0
    for k in range(n):
        a = st_s[k]
        b = st_s[k + 1]
        count = steps[k]
        step = (b - a) / count
        rows[k] = row
        for i in range(count):
            grid[row + i] = (i * step + a) * length
        grid[row + count] = b * length
        row += count + 1
    rows[n] = row - 1
    return grid, rows


@njit(cache=True)
def parabola_fits(loose, grow):
    """Whether a continuation predicts along the parabola through its last three points:
    their own errors, amplified by it up to about eightfold (``loose`` each), must stay
    within a hundredth of the corrector distance the steps aim at (``grow``). The rule
    of ``follow`` and of the shared driver's twin of it (``solver.Run.follow_shared``)."""
    return 8.0 * loose <= 0.01 * grow


@njit(cache=True)
def loose_at(t, span, loose, tol):
    """The tolerance of a continuation's point at t, its inputs moved by ``span`` in
    all (the largest change of a target or load, dimensionless): ``loose`` times that
    span (the residuals, and a stiff path's round-off, scale with its loads), but never
    more than a hundred times ``loose`` times how far the inputs have moved so far (at
    least one unit). Early on a heavy path its loads are still small: at ``loose *
    span`` throughout, a cable clamped at one end under q L^3 / EI = 3e5 accepted its
    first points untouched, with residuals up to a third of a unit (2 % of the weight it
    then carried), until no corrector could bring it back ("a fold" at t = 2e-4). A
    hundredth of that bound, throughout, cost the heavy paths 1.5 to 3 times the
    iterations. The twin of the shared driver's (``continuation.Stepping.loose_at``)."""
    return max(tol, loose * min(span, 100.0 * max(1.0, t * span)))


@njit(cache=True)
def extrapolated(a, b, c, d, ta, tb, tc, td, t):
    """The polynomial through the arrays a, b, c, d (of one shape) at the parameters
    ta < tb < tc < td, at t: a warm step's prediction (of its unknowns, of its
    Jacobian). A node whose parameter is NaN is left out (ta and tb: fewer points).
    Weights and sum here, one new array: in numpy, a dozen arrays and microseconds."""
    ts = np.array([ta, tb, tc, td])
    w = np.zeros(4)
    for i in range(4):
        if math.isnan(ts[i]):
            continue
        wi = 1.0
        for j in range(4):
            if j != i and not math.isnan(ts[j]):
                wi *= (t - ts[j]) / (ts[i] - ts[j])
        w[i] = wi
    fa, fb, fc, fd = a.ravel(), b.ravel(), c.ravel(), d.ravel()
    out = np.empty(fa.shape[0])
    for j in range(fa.shape[0]):
        out[j] = w[0] * fa[j] + w[1] * fb[j] + w[2] * fc[j] + w[3] * fd[j]
    return out.reshape(a.shape)


@njit(cache=True)
def needed_density(stats, accuracy, min_density):
    """Steps per unit length that resolve the wavenumber max|theta'| + sqrt(max|n|)."""
    k = stats[0] + math.sqrt(stats[1])
    return max(min_density, int(math.ceil(k / accuracy)))


@njit(cache=True)
def _lerp_into(out, a, b, t):
    """The homotopy's ``Inputs`` at t, written into out: (1 - t) * a + t * b."""
    _lerp_rows(out.val, a.val, b.val, t)
    _lerp_rows(out.fol, a.fol, b.fol, t)
    _lerp_rows(out.dist, a.dist, b.dist, t)
    for j in range(out.prm.shape[0]):
        out.prm[j] = a.prm[j] + t * (b.prm[j] - a.prm[j])


@njit(cache=True)
def _lerp_rows(out, a, b, t):
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = a[i, j] + t * (b[i, j] - a[i, j])


@njit(cache=True)
def _inputs_change(a, b):
    """The largest change of an input between two ``Inputs`` (loads and targets, not
    the bow's span [a, b] or the compliance)."""
    span = 0.0
    for i in range(a.val.shape[0]):
        for j in range(3):
            span = max(span, abs(b.val[i, j] - a.val[i, j]))
        for j in range(2):
            span = max(span, abs(b.fol[i, j] - a.fol[i, j]))
        for j in range(4):
            span = max(span, abs(b.dist[i, j] - a.dist[i, j]))
    for j in range(3):
        span = max(span, abs(b.prm[j] - a.prm[j]))
    return span


@njit(cache=True)
def follow(z0, density, stations, start, end, opts, longest, deadline):
    """Continuation from (start, z0), an exact solution, to end (``Inputs``, as plain
    tuples like the ``Stations``: see ``shoot``).

    The homotopy moves every input linearly, t from 0 to 1. The first predictor follows
    the tangent at the start, the second the secant through the last two points, the
    later ones the parabola through the last three (an error like dt^3: about one
    corrector iteration fewer a step than the secant) where the intermediate points are
    converged tightly: the parabola amplifies their own errors up to sevenfold (the
    secant threefold), and on a stiff path (a cable under its weight), whose loose
    tolerance scales with its large loads, it would carry the steps off the branch.
    Each step's Newton corrector starts from a fresh Jacobian at the prediction (the
    last point's contracts only by about the step, an iteration wasted) and must
    contract (see ``newton``); the next step aims at a corrector distance of ``grow``
    (each unknown relative to its size), and no step may raise the wavenumber by more
    than ``wave_step``. Intermediate points only need to be on the branch: they
    converge to a loose tolerance (``loose_at``: relative to how far the homotopy has
    moved its inputs so far) on a mesh of the coarser path accuracy (and of its own
    floor, ``OPT_PATH_MIN_DENSITY``, below the answer's). The end point
    converges to the full tolerance on a mesh refined until it resolves the solution
    to the accuracy asked for.

    The sign of det J is followed along the path: a step that flips it is rejected
    (it jumped to another branch, or crossed a fold or bifurcation too fast) until the
    step is so short that the crossing is genuine (a bifurcation on the path).

    longest : the longest shooting interval (``Lowered.interval``, dimensionless), by
    which the path's forces are judged against ``opts[OPT_NODE_LIMIT]``.
    deadline : ``time.thread_time()`` past which the path stops (BUDGET, OUT_OF_TIME),
    looked at after every CLOCK_WORK of work (a heavy cable's path took seconds in one
    call, past any budget the caller checked between calls).

    Returns (z, jac, density, stats, residual, status, last, t, iterations, steps,
    crossings); status is CONVERGED, STALLED or BUDGET, last the status of the last
    Newton (NEEDS_NODES where an intermediate point's wavenumber sqrt(max|n|) times the
    longest shooting interval passed ``opts[OPT_NODE_LIMIT]``, when that is positive, or
    two thirds of it on a path that creeps: see CREEP; OUT_OF_TIME past the deadline),
    crossings the number of genuine sign changes of det J on the way.
    """
    stn, inp0, inp1 = Stations(*stations), Inputs(*start), Inputs(*end)
    tol = opts[OPT_TOL]
    # Intermediate points converge relative to how far the homotopy moves the inputs
    # (``loose_at``); the end's tolerance decides the predictor.
    span = _inputs_change(inp0, inp1)
    loose = loose_at(1.0, span, opts[OPT_LOOSE], tol)
    contraction = opts[OPT_CONTRACTION]
    min_step = opts[OPT_MIN_STEP]
    max_steps = int(opts[OPT_MAX_STEPS])
    max_iter = int(opts[OPT_MAX_ITER])
    accuracy = opts[OPT_ACCURACY]
    min_density = int(opts[OPT_MIN_DENSITY])
    path_min_density = int(opts[OPT_PATH_MIN_DENSITY])
    grow = opts[OPT_GROW]
    shrink = opts[OPT_SHRINK]
    path_accuracy = opts[OPT_PATH_ACCURACY]
    wave_step = opts[OPT_WAVE_STEP]
    node_limit = opts[OPT_NODE_LIMIT]
    nz = z0.shape[0]
    # The wavenumber of the applied loads along the path, K(t) = sqrt(t F) + t C: the
    # homotopy crosses the loads at which buckling modes appear (about pi apart in K),
    # so no step may raise K by more than wave_step, or a step could skip the turn of
    # the branch there and land on another one.
    st_s, st_kind = stn.st_s, stn.st_kind
    val0, fol0, prm0 = inp0.val, inp0.fol, inp0.prm
    val1, fol1, prm1 = inp1.val, inp1.fol, inp1.prm
    load_f = 0.0
    load_c = 0.0
    for i in range(val0.shape[0]):
        for j in range(3):
            if st_kind[i, j] == APPLIED:
                if j < 2:
                    load_f += abs(val1[i, j] - val0[i, j])
                else:
                    load_c += abs(val1[i, j] - val0[i, j])
        load_f += abs(fol1[i, 0] - fol0[i, 0]) + abs(fol1[i, 1] - fol0[i, 1])
    load_f += math.sqrt((prm1[0] - prm0[0]) ** 2 + (prm1[1] - prm0[1]) ** 2)
    # The bow (prm[2]) is no load: the leg that removes it (the 2D cold solve's last,
    # from a singular start) is capped by the solution's own wavenumber, below. As a
    # moment it had cut case 3's into 5 steps of 1 (15 iterations; now 1 step, 8),
    # the same answers at 1,600 random targets held at a singular start and the 900.
    for k in range(st_s.shape[0] - 1):  # the distributed loads on stretches: their totals
        change = 0.0
        for j in range(4):
            change += abs(inp1.dist[k, j] - inp0.dist[k, j])
        load_f += change * (st_s[k + 1] - st_s[k])
    root_f = math.sqrt(load_f)
    k_prev = -1.0
    k_now = -1.0
    inp = Inputs(val0.copy(), fol0.copy(), inp0.dist.copy(), prm0.copy())
    z = z0.copy()
    z_prev = z0.copy()
    t_prev = -1.0
    z_prev2 = z0.copy()
    t_prev2 = -1.0
    parabola = parabola_fits(loose, grow)
    t = 0.0
    dt = 1.0
    r = math.inf
    steps = 0
    iterations = 0
    stats = np.zeros(2)
    seg_steps = mesh_steps(st_s, density)
    last_status = CONVERGED
    # The tangent dz/dt = -J^-1 dG/dt at the start, for a first-order first predictor
    # (dG/dt by a forward difference: G(z0, 0) = 0 at the exact start).
    empty = np.zeros((0, NSTATE))
    yes = z0.shape[0] >= 0  # a runtime True (see newton)
    eps = 1e-7
    _lerp_into(inp, inp0, inp1, eps)
    g_eps, j_eps, _ = _shoot(z, stn, inp, seg_steps, yes, empty)
    jac = j_eps
    no_jac = np.zeros((0, nz))  # each corrector starts from a fresh Jacobian
    tangent, ok = lu_solve(j_eps, -g_eps / eps)
    if not ok:
        return z, jac, density, stats, r, STALLED, SINGULAR, t, iterations, steps, 0
    # The sign of det J along the path: it flips where the path crosses a fold or a
    # bifurcation, and where a long step jumps to another branch of another stability
    # (Jacobi: the parity of the conjugate points). A flip rejects the step, until the
    # step is so short that the crossing is genuine; those are counted in ``crossings``.
    sign = det_sign(j_eps)
    crossings = 0
    refining = False
    work = 0.0
    creeping = 0
    refused = math.inf  # the last step refused, its memory fading (see REFUSED_FADE)
    columns = 1 + min(nz, 12)  # the live sensitivity columns, about (see _shoot)
    while steps < max_steps:
        if work >= CLOCK_WORK:
            work = 0.0
            with objmode(now="float64"):
                now = time.thread_time()
            if now > deadline:
                return (z, jac, density, stats, r, BUDGET, OUT_OF_TIME, t, iterations,
                        steps, crossings)
        # The cap on the step from the loads, then from the solution's own wavenumber
        # (which carries the unknown reactions too), extrapolated along the last step.
        k_load = math.sqrt(t) * root_f + t * load_c + wave_step
        if load_c > 0.0 or root_f > 0.0:
            # u = sqrt(t + dt) solves C u^2 + sqrt(F) u = k_load; this form of the root
            # does not cancel when C is tiny.
            u = 2.0 * k_load / (root_f + math.sqrt(root_f * root_f + 4.0 * load_c * k_load))
        else:
            u = 2.0
        dt = min(dt, max(u * u - t, min_step))
        if k_prev >= 0.0 and t_prev >= 0.0 and k_now > k_prev:
            dt = min(dt, max(wave_step * (t - t_prev) / (k_now - k_prev), min_step))
        if t + dt < 1.0 and t + LAST_STRETCH * dt >= 1.0:
            dt = 1.0 - t  # the rest at once (see LAST_STRETCH)
        t_next = min(1.0, t + dt)
        _lerp_into(inp, inp0, inp1, t_next)
        predictor = z.copy()
        if parabola and t_prev2 >= 0.0:  # Lagrange's through the last three points
            l0 = (t_next - t_prev) * (t_next - t) / ((t_prev2 - t_prev) * (t_prev2 - t))
            l1 = (t_next - t_prev2) * (t_next - t) / ((t_prev - t_prev2) * (t_prev - t))
            l2 = (t_next - t_prev2) * (t_next - t_prev) / ((t - t_prev2) * (t - t_prev))
            for q in range(nz):
                predictor[q] = l0 * z_prev2[q] + l1 * z_prev[q] + l2 * z[q]
        elif t_prev >= 0.0:
            w = (t_next - t) / (t - t_prev)
            for q in range(nz):
                predictor[q] += w * (z[q] - z_prev[q])
        elif t == 0.0:
            for q in range(nz):
                predictor[q] += (t_next - t) * tangent[q]
        final = t_next >= 1.0
        # Re-converging the end point on a finer mesh is no continuation step (the loads
        # do not move: a shorter step cannot help): a damped Newton, not a corrector that
        # must contract (a taut cable's first step there often does not).
        zn, rn, it, status, jn, st, _theta = _newton(
            predictor, no_jac, stn, inp, seg_steps,
            tol if final else loose_at(t_next, span, opts[OPT_LOOSE], tol), max_iter,
            0.0 if refining else contraction)
        iterations += it
        work += (it + 1) * columns * density  # RK steps (density a unit length) times columns
        if status == CONVERGED:
            # How far the corrector travelled from the prediction, each unknown relative
            # to its size: the secant and the first (tangent) predictors err like dt^2,
            # the parabola like dt^3; the step control aims the next step at a distance
            # of ``grow`` by the dt^2 rule, the more cautious of the two.
            miss = 0.0
            for q in range(nz):
                miss = max(miss, abs(zn[q] - predictor[q]) / max(1.0, abs(zn[q])))
        if status == CONVERGED:
            new_sign = det_sign(jn)
            if new_sign != sign:
                _, fresh_jac, _ = _shoot(zn, stn, inp, seg_steps, yes, empty)
                new_sign = det_sign(fresh_jac)
                if new_sign != sign:
                    if dt > 1e3 * min_step:
                        status = NOT_CONTRACTING
                    else:
                        crossings += 1
                        sign = new_sign
        if status == CONVERGED:
            refining = False
            steps += 1
            k_prev = k_now
            k_now = math.sqrt(st[1])  # buckling modes follow the force, not the curvature
            z_prev2 = z_prev
            t_prev2 = t_prev
            z_prev = z
            t_prev = t
            z = zn
            jac = jn
            r = rn
            t = t_next
            stats = st
            if final:
                need = needed_density(stats, accuracy, min_density)
            else:
                need = needed_density(stats, path_accuracy, path_min_density)
            if need > density:
                density = int(math.ceil(1.1 * need))
                seg_steps = mesh_steps(st_s, density)
                if final:
                    # Converge the end point once more, on the finer mesh.
                    t_prev = -1.0
                    t_prev2 = -1.0
                    t = 1.0 - 1e-12
                    dt = 1.0
                    refining = True
                    continue
            if final:
                return (z, jac, density, stats, r, CONVERGED, CONVERGED, t, iterations,
                        steps, crossings)
            if t - t_prev < CREEP:  # the step just taken (see CREEP)
                creeping += 1
            if node_limit > 0.0 and (k_now * longest > node_limit or (
                    creeping > CREEP_STEPS and k_now * longest > CREEP_SPAN * node_limit)):
                # The forces outgrew the shooting intervals: the sensitivities grow like
                # exp(k s) across one, Newton's basin shrinks with them, and the steps
                # would creep on by thousands (a part pulled into a hairpin). The caller
                # follows again with more intervals.
                return (z, jac, density, stats, r, STALLED, NEEDS_NODES, t, iterations,
                        steps, crossings)
            refused *= REFUSED_FADE
            grown = dt * min(4.0, max(0.5, math.sqrt(grow / max(miss, 1e-300))))
            dt = min(grown, max(dt, 0.5 * refused), 1.0)
        else:
            last_status = status
            refused = t_next - t
            dt *= shrink
            if dt < min_step:
                return (z, jac, density, stats, rn, STALLED, last_status, t, iterations,
                        steps, crossings)
    return z, jac, density, stats, r, BUDGET, last_status, t, iterations, steps, crossings


@njit(cache=True)
def rest_state(stations, inputs, seg_steps, nz):
    """The unloaded part, placed: (val, z) of the homotopy's exact start.

    The rest shape (kappa0 and the bow in inp.prm, with inp's loads: none) is
    integrated from the pose
    (0, 0, 0) at s = 0, then moved rigidly: its angle from the first station with a
    prescribed angle, or from the chord between the first and last stations with a
    prescribed position; its origin so that the first prescribed x and y are met.
    val holds the rest values of the prescribed components (zero loads elsewhere);
    z the rest unknowns (the pose where s = 0 is free, and the state at each node).
    """
    stn, inp = Stations(*stations), Inputs(*inputs)
    st_s, st_kind, st_col, st_val = stn.st_s, stn.st_kind, stn.st_col, inp.val
    nst = st_s.shape[0]
    shape = np.zeros((nst, 3))
    y = np.zeros(NSTATE)
    Y = np.zeros((6, 0))
    work = Work(np.zeros((_B.shape[0], 4)), np.zeros((_B.shape[0], 4, 0)),
                np.zeros((0, NSTATE)), np.zeros(1, dtype=np.int64), np.zeros(2))
    none = nst * 0  # runtime values, not literals (see newton)
    for k in range(nst - 1):
        _integrate(y, Y, none, none, _segment(k, stn, inp), seg_steps[k], work, nst < 0)
        shape[k + 1, 0] = y[0]
        shape[k + 1, 1] = y[1]
        shape[k + 1, 2] = y[2]
    angle = 0.0
    first_angle = -1
    first = -1
    last = -1
    for k in range(nst):
        if st_kind[k, 2] == PRESCRIBED and first_angle < 0:
            first_angle = k
        if st_kind[k, 0] == PRESCRIBED and st_kind[k, 1] == PRESCRIBED:
            if first < 0:
                first = k
            last = k
    if first_angle >= 0:
        angle = st_val[first_angle, 2] - shape[first_angle, 2]
    elif first >= 0 and last != first:
        want = math.atan2(st_val[last, 1] - st_val[first, 1], st_val[last, 0] - st_val[first, 0])
        have = math.atan2(shape[last, 1] - shape[first, 1], shape[last, 0] - shape[first, 0])
        angle = want - have
    c = math.cos(angle)
    sn = math.sin(angle)
    origin = np.zeros(2)
    for i in range(2):
        for k in range(nst):
            if st_kind[k, i] == PRESCRIBED:
                rotated = (c * shape[k, 0] - sn * shape[k, 1] if i == 0
                           else sn * shape[k, 0] + c * shape[k, 1])
                origin[i] = st_val[k, i] - rotated
                break
    val = np.zeros((nst, 3))
    z = np.zeros(nz)
    for k in range(nst):
        px = origin[0] + c * shape[k, 0] - sn * shape[k, 1]
        py = origin[1] + sn * shape[k, 0] + c * shape[k, 1]
        pa = angle + shape[k, 2]
        for i in range(3):
            if st_kind[k, i] == PRESCRIBED:
                val[k, i] = (px, py, pa)[i]
        if st_kind[k, 0] == NODE:
            c0 = st_col[k, 0]
            z[c0] = px
            z[c0 + 1] = py
            z[c0 + 2] = pa
    pose = (origin[0], origin[1], angle)
    for i in range(3):
        if st_kind[0, i] != PRESCRIBED:
            z[i] = pose[i]
    return val, z
