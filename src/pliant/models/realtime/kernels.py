"""Numba kernels of the real-time bar network.

The network's nodes X_i (i = 0..n-1) are the control points of the part's B-spline. Its
bars join each node to the next ``reach`` nodes; bar b = (i, j) carries the force density
w_b (force per unit length, fictive), so it pulls node i by w_b (X_j - X_i). The first
family (i, i+1) keeps its length: its force density is q_b + mu_b, mu_b the multiplier of
the constraint |X_j - X_i|^2 = l_b^2. Grips constrain linear combinations of the nodes,
one coordinate at a time: sum_a G[r, a] X[start_r + a, c] = g_k for a point of the curve,
and = alpha_r t_c for its derivative (the tangent's direction t is held, its parametric
speed alpha_r is free: the lengths set it), with multiplier lam_k (the fictive grip
force). Fixed fictive nodal
loads p close the balance: the bar forces on each node, its load and the grip forces:

    R_node(i, c)  = sum_{b = (i, j)} w_b (X_j - X_i)_c + sum_{b = (j, i)} w_b (X_j - X_i)_c
                    + p_ic + sum_k G_ki lam_k [c_k = c] = 0
    R_length(b)   = (|X_j - X_i|^2 - l_b^2) / 2 = 0
    R_grip(k)     = sum_a G[r_k, a] X[start_{r_k} + a, c_k] - g_k (or - alpha_r t_c) = 0
    R_alpha(r)    = - sum_{k of row r} lam_k t_{c_k} = 0

Obstacles (3D): the curve's points C(u_m) = sum_a N_ma X_a at fixed parameters u_m keep
a gap g_m = (D(C L) - r) / L >= 0 (D the scene's signed distance, r the tube's radius),
each with a multiplier gam_m >= 0 pushing along the obstacle's normal n; the unilateral
condition is min(gam_m, scale g_m) = 0 (a semismooth Newton, as in the accurate model):

    R_node(i, c) += sum_m N_mi gam_m n_c        R_contact(m) = scale g_m or gam_m

The equations are those of a constrained stationary point of
E = 1/2 sum_b q_b |X_j - X_i|^2 - p . X (R is minus its gradient); for fixed mu they
are linear in X: the force density method. Unknowns are numbered node by node (its
coordinates, the multiplier of the bar that starts there, the grips anchored there, the
speeds of the tangents held there) so the Jacobian is banded.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from pliant.models.banded import add, band_lu, band_lu_solve
from pliant.scene.distance import hessian_point, query_points

CONVERGED = 0
NOT_CONVERGED = 1
SINGULAR = 2


class Network(NamedTuple):
    """The bars and grips (see the module docstring): each bar's nodes, force density q
    and squared length l0sq (the first family's), the fictive nodal loads p (n, d); the
    grips' rows (each a first node g_start and weights g_val), and per constraint its
    row, coordinate, target (or held tangent component) and tangent speed (-1: a point)."""

    bar_i: np.ndarray
    bar_j: np.ndarray
    q: np.ndarray
    l0sq: np.ndarray
    p: np.ndarray
    g_start: np.ndarray
    g_val: np.ndarray
    con_row: np.ndarray
    con_c: np.ndarray
    con_rhs: np.ndarray
    con_alpha: np.ndarray


class Numbering(NamedTuple):
    """The first unknown of each node (ix), first-family bar (imu), constraint (icon),
    tangent speed (ialpha) and contact sample (igam); the system's size and half band
    widths."""

    ix: np.ndarray
    imu: np.ndarray
    icon: np.ndarray
    ialpha: np.ndarray
    igam: np.ndarray
    n_unknowns: int
    kl: int
    ku: int


class Touch(NamedTuple):
    """The curve's contact samples (each a first node and weights), (L, radius / L,
    band [m], scale) and the scene's packed distance field."""

    c_start: np.ndarray
    c_val: np.ndarray
    contact: tuple
    field: tuple


class Limits(NamedTuple):
    """When a frame's Newton stops: the residual it must reach and its iterations."""

    tol: float
    max_iter: int


@njit(cache=True)
def assemble(X, mu, lam, alpha, gam, net, num, touch, keep, want_jac):
    """Residual (n_unknowns,) and, with want_jac, its banded Jacobian (net, num, touch: a
    ``Network``, ``Numbering`` and ``Touch``). keep: hold the first family's lengths;
    else mu stays as it is and the system is linear in X (the plain force density
    method)."""
    bar_i, bar_j, q, l0sq, p, g_start, g_val, con_row, con_c, con_rhs, con_alpha = net
    ix, imu, icon, ialpha, _, n_unknowns, kl, ku = num
    n, d = X.shape
    R = np.zeros(n_unknowns)
    ab = np.zeros((n_unknowns if want_jac else 0, 2 * kl + ku + 1))
    n_len = mu.shape[0]
    for b in range(bar_i.shape[0]):
        i = bar_i[b]
        j = bar_j[b]
        w = q[b] + (mu[b] if b < n_len else 0.0)
        for c in range(d):
            v = X[j, c] - X[i, c]
            R[ix[i] + c] += w * v
            R[ix[j] + c] -= w * v
            if want_jac:
                add(ab, kl, ku, ix[i] + c, ix[i] + c, -w)
                add(ab, kl, ku, ix[i] + c, ix[j] + c, w)
                add(ab, kl, ku, ix[j] + c, ix[i] + c, w)
                add(ab, kl, ku, ix[j] + c, ix[j] + c, -w)
        if b < n_len and not keep:
            if want_jac:
                add(ab, kl, ku, imu[b], imu[b], 1.0)  # mu frozen: d mu = 0
        elif b < n_len:
            sq = 0.0
            for c in range(d):
                v = X[j, c] - X[i, c]
                sq += v * v
                if want_jac:
                    add(ab, kl, ku, ix[i] + c, imu[b], v)
                    add(ab, kl, ku, ix[j] + c, imu[b], -v)
                    add(ab, kl, ku, imu[b], ix[i] + c, -v)
                    add(ab, kl, ku, imu[b], ix[j] + c, v)
            R[imu[b]] = 0.5 * (sq - l0sq[b])
    for i in range(n):
        for c in range(d):
            R[ix[i] + c] += p[i, c]
    for k in range(con_row.shape[0]):
        r = con_row[k]
        c = con_c[k]
        value = -con_rhs[k]
        for a in range(g_val.shape[1]):
            node = g_start[r] + a
            gv = g_val[r, a]
            if gv == 0.0:
                continue
            value += gv * X[node, c]
            R[ix[node] + c] += gv * lam[k]
            if want_jac:
                add(ab, kl, ku, ix[node] + c, icon[k], gv)
                add(ab, kl, ku, icon[k], ix[node] + c, gv)
        a = con_alpha[k]
        if a >= 0:  # a held tangent: its direction, at the free speed alpha
            value += con_rhs[k] - alpha[a] * con_rhs[k]
            R[ialpha[a]] -= lam[k] * con_rhs[k]
            if want_jac:
                add(ab, kl, ku, icon[k], ialpha[a], -con_rhs[k])
                add(ab, kl, ku, ialpha[a], icon[k], -con_rhs[k])
        R[icon[k]] = value
    if touch.c_start.shape[0]:
        _contacts(X, gam, touch, num, R, ab, want_jac)
    return R, ab


@njit(cache=True)
def _contacts(X, gam, touch, num, R, ab, want_jac):
    """Add the contact terms of the curve points (see the module docstring)."""
    c_start, c_val, contact, field = touch
    ix, igam, kl, ku = num.ix, num.igam, num.kl, num.ku
    L, radius, band, scale = contact
    width = c_val.shape[1]
    points = _curve_points(X, c_start, c_val, L)
    dist, normals, found = query_points(points, band, field)
    for m in range(c_start.shape[0]):
        s0 = c_start[m]
        d, o = dist[m], found[m]
        n = (normals[m, 0], normals[m, 1], normals[m, 2])
        g = (d / L - radius)
        lam = gam[m]
        touching = lam > scale * g
        R[igam[m]] = scale * g if touching else lam
        for a in range(width):
            w = c_val[m, a]
            if w == 0.0:
                continue
            for c in range(3):
                R[ix[s0 + a] + c] += w * lam * n[c]
        if not want_jac:
            continue
        if touching:
            for a in range(width):
                w = c_val[m, a]
                for c in range(3):
                    add(ab, kl, ku, igam[m], ix[s0 + a] + c, scale * w * n[c])
        else:
            add(ab, kl, ku, igam[m], igam[m], 1.0)
        for a in range(width):
            w = c_val[m, a]
            for c in range(3):
                add(ab, kl, ku, ix[s0 + a] + c, igam[m], w * n[c])
        if lam != 0.0 and o >= 0:
            H = hessian_point(points[m], o, field) * L  # d n / d (X in units of L)
            for a in range(width):
                for b in range(width):
                    wab = lam * c_val[m, a] * c_val[m, b]
                    if wab == 0.0:
                        continue
                    for c in range(3):
                        for e in range(3):
                            if H[c, e] != 0.0:
                                add(ab, kl, ku, ix[s0 + a] + c, ix[s0 + b] + e, wab * H[c, e])


@njit(cache=True)
def max_abs(v):
    m = 0.0
    for x in v:
        a = abs(x)
        if a > m or not math.isfinite(a):
            m = a if math.isfinite(a) else math.inf
    return m


@njit(cache=True)
def apply_step(X, mu, lam, alpha, gam, du, num, step):
    ix, imu, icon, ialpha, igam = num.ix, num.imu, num.icon, num.ialpha, num.igam
    n, d = X.shape
    Xn = X.copy()
    mun = mu.copy()
    lamn = lam.copy()
    alphan = alpha.copy()
    gamn = gam.copy()
    for m in range(gam.shape[0]):
        gamn[m] += step * du[igam[m]]
    for a in range(alpha.shape[0]):
        alphan[a] += step * du[ialpha[a]]
    for i in range(n):
        for c in range(d):
            Xn[i, c] += step * du[ix[i] + c]
    for b in range(mu.shape[0]):
        mun[b] += step * du[imu[b]]
    for k in range(lam.shape[0]):
        lamn[k] += step * du[icon[k]]
    return Xn, mun, lamn, alphan, gamn


@njit(cache=True)
def newton(X, mu, lam, alpha, gam, net, num, touch, keep, limits):
    """Newton with backtracking on the largest residual entry from (X, mu, lam, alpha,
    gam); a full step that changes which curve points touch is taken as the active-set
    update; limits: ``Limits``. Returns (X, mu, lam, alpha, gam, residual, iterations,
    status)."""
    tol, max_iter = limits.tol, limits.max_iter
    ix, kl, ku = num.ix, num.kl, num.ku
    yes = num.n_unknowns >= 0  # a runtime True: a literal would compile assemble once more
    R, ab = assemble(X, mu, lam, alpha, gam, net, num, touch, keep, yes)
    r = max_abs(R)
    it = 0
    switches = 0
    while r > tol and it < max_iter:
        it += 1
        piv, ok = band_lu(ab, kl, ku)
        if not ok:
            return X, mu, lam, alpha, gam, r, it, SINGULAR
        du = band_lu_solve(ab, piv, kl, ku, -R)
        step = 1.0
        # No node moves more than a tenth of the part's length in one iteration: a
        # near-singular system (contacts about to switch) cannot throw the network away.
        move = 0.0
        for i in range(X.shape[0]):
            for c in range(X.shape[1]):
                move = max(move, abs(du[ix[i] + c]))
        if move > 0.1:
            step = 0.1 / move
        accepted = False
        for _ in range(12):
            Xn, mun, lamn, alphan, gamn = apply_step(X, mu, lam, alpha, gam, du, num, step)
            Rn, abn = assemble(Xn, mun, lamn, alphan, gamn, net, num, touch, keep, yes)
            rn = max_abs(Rn)
            if rn < r or rn <= tol:
                accepted = True
                break
            if (_ == 0 and switches < 6 and math.isfinite(rn)
                    and _switched(gam, gamn, Xn, X, touch)):
                switches += 1
                accepted = True
                break
            step *= 0.5
        if not accepted:
            return X, mu, lam, alpha, gam, r, it, NOT_CONVERGED
        X, mu, lam, alpha, gam, R, ab, r = Xn, mun, lamn, alphan, gamn, Rn, abn, rn
    return X, mu, lam, alpha, gam, r, it, CONVERGED if r <= tol else NOT_CONVERGED


@njit(cache=True)
def _switched(gam, gamn, Xn, X, touch):
    """Whether a step changes which curve points touch (lam > scale g)."""
    if touch.c_start.shape[0] == 0:
        return False
    before = _touching(X, gam, touch)
    after = _touching(Xn, gamn, touch)
    for m in range(before.shape[0]):
        if before[m] != after[m]:
            return True
    return False


@njit(cache=True)
def _touching(X, gam, touch):
    c_start, c_val, contact, field = touch
    L, radius, band, scale = contact
    out = np.zeros(c_start.shape[0], dtype=np.bool_)
    dist = query_points(_curve_points(X, c_start, c_val, L), band, field)[0]
    for m in range(c_start.shape[0]):
        out[m] = gam[m] > scale * (dist[m] / L - radius)
    return out


@njit(cache=True)
def _curve_points(X, c_start, c_val, L):
    """The curve's points [m] at the contact samples."""
    points = np.zeros((c_start.shape[0], 3))
    for m in range(c_start.shape[0]):
        for c in range(3):
            v = 0.0
            for a in range(c_val.shape[1]):
                v += c_val[m, a] * X[c_start[m] + a, c]
            points[m, c] = v * L
    return points
