"""Numba kernels of the 3D rod's contact with obstacles: the contact terms (a
complementarity per probe, compliant by ``COMPLIANCE``, with Coulomb friction as a
penalty return map whose elastic slip is ``ELASTIC_SLIP`` of an element), their largest
residual, and the Newton solve of the rod with them (a semismooth Newton with an active
set). The rod's own terms and the arguments' bundles are ``kernels``'s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pliant.models.banded import add as _add
from pliant.models.banded import band_solve_reduced, identity_rows
from pliant.models.rod3d.kernels import (
    CONVERGED,
    MAX_ITERATIONS,
    NOT_CONTRACTING,
    NOT_FINITE,
    SINGULAR,
    apply_step,
    assemble,
    max_abs,
)
from pliant.scene.distance import hessian_point, query_points

# -- contact -------------------------------------------------------------------------------
COMPLIANCE = 1e-9  # a contact's gap per unit normal force, dimensionless (see below)


@njit(cache=True)
def contact_terms(X, gam, con, num, R, ab, want_jac):
    """Add the contacts (``Contact``) to a KKT residual (and its Jacobian), in place.

    Each probe p = (1 - a) x_e + a x_e+1 has the gap g = (D(p L) - radius) / L + offset
    (D the scene's signed distance) and the multiplier gam >= 0, the normal force it takes
    (by EI / L^2); the force gam n (n = grad D) acts on its two nodes. The unilateral
    condition is the complementarity function min(gam, scale g) = 0, solved by a
    semismooth Newton: a probe with gam <= scale g is free (its row: gam = 0), else it
    touches (its row: g = 0); switching is the active-set update. The curvature of the
    surface (d n / d p) enters the force's Jacobian, from the obstacle's exact Hessian.

    With friction (slot 3) each probe also has a tangential force t = (t1, t2) in the
    basis (tau1, tau2) of its tangent plane at the step's start, friction = (mu per
    obstacle, where each probe's spring was slack at the step's start (K, 3, by L), the
    bases (K, 2, 3), each probe's elastic slip (K,, by L)). Its slip is
    s_i = tau_i . (p / L - p0), and
    Coulomb's law is the penalty return map of the commercial codes (Abaqus's "elastic
    slip"): t = rho proj onto the unit disc of (-s / slip), rho = mu gam. It sticks
    inside the disc, slipping at most ``ELASTIC_SLIP`` of its element by the time the
    friction reaches its limit, and slides (t = rho against the slip) on the rim. A
    rigid stick (s = 0) makes the KKT matrix singular where the sticking probes are
    dependent (a part lying along a face: its inextensible axis already ties their slips
    along it), and a stiff one leaves Newton a disc too narrow to land in: its iterates
    jump from rim to rim.
    Returns (gaps (K,), normals (K, 3), obstacles (K,), state (K,) int8: 0 free,
    1 touching (sticking, with friction), 2 touching and sliding).
    """
    probe_elem, probe_a, iprobe, slot = con.probe_elem, con.probe_a, con.iprobe, con.slot
    L, radius, offset, scale, field = con.length, con.radius, con.offset, con.scale, con.field
    ix, kl, ku = num.ix, num.kl, num.ku
    K = probe_elem.shape[0]
    gaps = np.empty(K)
    which = np.empty(K, dtype=np.int64)
    active = np.zeros(K, dtype=np.int8)
    points = np.empty((K, 3))
    for k in range(K):
        e = probe_elem[k]
        a = probe_a[k]
        for c in range(3):
            points[k, c] = ((1.0 - a) * X[e, c] + a * X[e + 1, c]) * L
    # One batched query: a call per probe would pay the scene's many arrays each time.
    dist, normals, found = query_points(points, con.band, field)
    for k in range(K):
        e = probe_elem[k]
        a = probe_a[k]
        d, o = dist[k], found[k]
        g = (d - radius) / L + offset
        gaps[k] = g
        which[k] = o
        ip = iprobe[k]
        w0, w1 = 1.0 - a, a
        n = normals[k]
        lam = gam[k * slot]
        for c in range(3):
            R[ix[e] + c] -= w0 * lam * n[c]
            R[ix[e + 1] + c] -= w1 * lam * n[c]
        # A touching probe's row is g + COMPLIANCE lam = 0: a contact stiff to a part in
        # 1e9 (of L per EI / L^2), which keeps the KKT matrix regular where the active
        # probes are dependent (a part lying along a plane: a probe between two
        # touching ones adds no new constraint) and changes no gap beyond 1e-9 L a unit.
        soft = g + COMPLIANCE * lam
        touching = lam > scale * soft
        R[ip] = scale * soft if touching else lam
        kind = 0
        if slot == 3:
            kind = _friction_terms(gam, k, o, points[k] / L, con, num, R, ab, want_jac)
        active[k] = (2 if kind == 2 else 1) if touching else 0
        if not want_jac:
            continue
        if touching or lam != 0.0:
            # (A free probe with no force has the row d gam = 0: its column would only
            # ever multiply zero, so it is left out, which halves the work of the many
            # probes far from everything.)
            for c in range(3):
                _add(ab, kl, ku, ix[e] + c, ip, -w0 * n[c])
                _add(ab, kl, ku, ix[e + 1] + c, ip, -w1 * n[c])
        if touching:
            for c in range(3):
                _add(ab, kl, ku, ip, ix[e] + c, scale * w0 * n[c])
                _add(ab, kl, ku, ip, ix[e + 1] + c, scale * w1 * n[c])
            _add(ab, kl, ku, ip, ip, scale * COMPLIANCE)
        else:
            _add(ab, kl, ku, ip, ip, 1.0)
        if lam != 0.0:
            # d n / d p, the surface's curvature, exact on the piece p lies on; times L.
            H = hessian_point(points[k], o, field) * L
            for c in range(3):
                for j in range(3):
                    v = -lam * H[c, j]
                    if v != 0.0:
                        _add(ab, kl, ku, ix[e] + c, ix[e] + j, w0 * w0 * v)
                        _add(ab, kl, ku, ix[e] + c, ix[e + 1] + j, w0 * w1 * v)
                        _add(ab, kl, ku, ix[e + 1] + c, ix[e] + j, w1 * w0 * v)
                        _add(ab, kl, ku, ix[e + 1] + c, ix[e + 1] + j, w1 * w1 * v)
    return gaps, normals, which, active


ELASTIC_SLIP = 0.005  # a sticking probe's slip at the friction limit, by its element
# On the disc's rim both laws give one residual; the sliding one's Jacobian is taken
# there, so that a step that starts where the last one slid predicts further sliding.
RIM = 1.0 - 1e-9


@njit(cache=True)
def _friction_terms(gam, k, o, p, con, num, R, ab, want_jac):
    """Probe k's Coulomb friction (see ``contact_terms``), at p (by L) and nearest
    obstacle o: its tangential force on the nodes and its two rows, the return map
    t = rho proj onto the unit disc of (-s / slip), times slip (rows in L, as a gap's),
    with their semismooth Jacobian. Returns 0 (no friction force), 1 (sticks) or
    2 (slides)."""
    e = con.probe_elem[k]
    w1 = con.probe_a[k]
    w0 = 1.0 - w1
    ip = con.iprobe[k]
    lam = gam[3 * k]
    mu_of, ref, basis, give = con.friction
    mu = mu_of[o] if o >= 0 else 0.0
    p0 = ref[k]
    tau = basis[k]
    gk = give[k]
    ix, kl, ku = num.ix, num.kl, num.ku
    t1 = gam[3 * k + 1]
    t2 = gam[3 * k + 2]
    for c in range(3):
        f = t1 * tau[0, c] + t2 * tau[1, c]
        R[ix[e] + c] -= w0 * f
        R[ix[e + 1] + c] -= w1 * f
    s1 = 0.0
    s2 = 0.0
    for c in range(3):
        s1 += tau[0, c] * (p[c] - p0[c])
        s2 += tau[1, c] * (p[c] - p0[c])
    rho = mu * lam if lam > 0.0 else 0.0
    v1 = -s1 / gk  # the trial force by rho: the slip held by the spring
    v2 = -s2 / gk
    vn = math.sqrt(v1 * v1 + v2 * v2)
    i1 = ip + 1
    i2 = ip + 2
    if rho <= 0.0:  # free, or no friction: t = 0
        R[i1] = t1
        R[i2] = t2
        kind = 0
    elif vn < RIM:  # sticks: t = -rho s / slip
        R[i1] = gk * t1 + rho * s1
        R[i2] = gk * t2 + rho * s2
        kind = 1
    else:  # slides: t on the disc's rim, against the slip
        u1 = v1 / vn
        u2 = v2 / vn
        R[i1] = gk * (t1 - rho * u1)
        R[i2] = gk * (t2 - rho * u2)
        kind = 2
    if not want_jac:
        return kind
    for c in range(3):
        for i in range(2):
            _add(ab, kl, ku, ix[e] + c, ip + 1 + i, -w0 * tau[i, c])
            _add(ab, kl, ku, ix[e + 1] + c, ip + 1 + i, -w1 * tau[i, c])
    if kind == 0:
        _add(ab, kl, ku, i1, i1, 1.0)
        _add(ab, kl, ku, i2, i2, 1.0)
        return kind
    # dF/dt = slip I; dF/ds (2 x 2, on tau w) and dF/dgam (2,): stick F = slip t + rho s;
    # slide F = slip (t - rho u), u = v / |v|, v = -s / slip: dF/ds = rho (I - u u^T) / |v|.
    _add(ab, kl, ku, i1, i1, gk)
    _add(ab, kl, ku, i2, i2, gk)
    if kind == 1:
        ds00, ds01, ds11 = rho, 0.0, rho
        _add(ab, kl, ku, i1, ip, mu * s1)
        _add(ab, kl, ku, i2, ip, mu * s2)
    else:
        q = rho / vn
        ds00, ds01, ds11 = q * (1.0 - u1 * u1), -q * u1 * u2, q * (1.0 - u2 * u2)
        _add(ab, kl, ku, i1, ip, -gk * mu * u1)
        _add(ab, kl, ku, i2, ip, -gk * mu * u2)
    for c in range(3):  # ds_i / dx = tau_i w
        a1 = ds00 * tau[0, c] + ds01 * tau[1, c]
        a2 = ds01 * tau[0, c] + ds11 * tau[1, c]
        _add(ab, kl, ku, i1, ix[e] + c, w0 * a1)
        _add(ab, kl, ku, i1, ix[e + 1] + c, w1 * a1)
        _add(ab, kl, ku, i2, ix[e] + c, w0 * a2)
        _add(ab, kl, ku, i2, ix[e + 1] + c, w1 * a2)
    return kind


@njit(cache=True, inline="always")
def _contact_residual(X, Q, lam, nu, gam, mesh, tg, num, con):
    """The KKT residual and Jacobian with the contact terms; (R, ab, energy, active)."""
    yes = num.n >= 0  # a runtime True (see newton)
    R, ab, energy = assemble(X, Q, lam, nu, mesh, tg, num, yes)
    active = contact_terms(X, gam, con, num, R, ab, yes)[3]
    return R, ab, energy, active


@njit(cache=True)
def contact_max(R, con):
    """The residual's size with obstacles: its largest entry, a friction row read in
    force (its row is the force's error times the probe's elastic slip, kept small for
    the pivots' scale), so that a converged friction force is as exact as a balance. A
    free probe's rows (t = 0, unscaled) are read the same way, stricter by 1 / slip:
    they are linear, and one Newton step meets them exactly."""
    r = max_abs(R)
    if con.slot != 3:
        return r
    give = con.friction[3]
    for k in range(con.iprobe.shape[0]):
        for j in (1, 2):
            v = abs(R[con.iprobe[k] + j]) / give[k]
            if not v <= r:  # (and a NaN)
                r = v
    return r


@njit(cache=True)
def newton_contact(X, Q, lam, nu, gam, mesh, tg, num, con, opts):
    """The semismooth Newton of a problem with obstacles, in one kernel, its Jacobian
    rebuilt every iteration (the active set may change). Acceptance (opts: ``Settings``):

    - a corrector (strict) with no probe touching: the full step must contract by
      ``contraction``;
    - while probes touch, or not strict: any step that lowers the residual, backtracking
      from the full one (the Jacobian jumps on an obstacle's seams, a face meeting an
      edge's rounding, so convergence there is not quadratic); a corrector gives up
      below a tenth of a step, and its continuation shortens the load step instead;
    - a full step that changes which probes touch, up to ``max_switches`` times.

    Returns (X, Q, lam, nu, gam, residual, iterations, status, energy)."""
    tol, max_iter, contraction, strict, max_switches = opts
    iprobe, slot = con.iprobe, con.slot
    R, ab, energy, active = _contact_residual(X, Q, lam, nu, gam, mesh, tg, num, con)
    r = contact_max(R, con)
    if not math.isfinite(r):
        return X, Q, lam, nu, gam, r, 0, NOT_FINITE, energy
    it = 0
    switches = 0
    while r > tol:
        if it >= max_iter:
            return X, Q, lam, nu, gam, r, it, MAX_ITERATIONS, energy
        it += 1
        # The free probes' rows are the identity's: they leave the factorisation.
        du, ok = band_solve_reduced(ab, num.kl, num.ku, -R,
                                    identity_rows(ab, num.kl, num.ku, iprobe, slot))
        if not ok:
            return X, Q, lam, nu, gam, r, it, SINGULAR, energy
        damped = not strict
        for k in range(active.shape[0]):
            if active[k]:
                damped = True
        step = 1.0
        accepted = False
        for _ in range(30 if damped else 1):
            Xn, Qn, ln, nn = apply_step(X, Q, lam, nu, du, num, step)
            gn = gam.copy()
            for k in range(iprobe.shape[0]):
                for j in range(slot):
                    gn[k * slot + j] += step * du[iprobe[k] + j]
            Rn, abn, en, an = _contact_residual(Xn, Qn, ln, nn, gn, mesh, tg, num, con)
            rn = contact_max(Rn, con)
            finite = math.isfinite(rn)
            if damped:
                accepted = finite and rn <= (1.0 - 1e-4 * step) * r
            else:
                accepted = rn <= contraction * r or rn <= tol
            if not accepted and step == 1.0 and switches < max_switches and finite:
                changed = False
                for k in range(an.shape[0]):
                    if an[k] != active[k]:
                        changed = True
                if changed:
                    switches += 1
                    accepted = True
            if accepted:
                break
            step *= 0.5
        if not accepted or (strict and step < 0.1):
            # A corrector crawling in tiny steps is far from its basin: the
            # continuation does better with a shorter step in the load.
            return X, Q, lam, nu, gam, r, it, NOT_CONTRACTING, energy
        X, Q, lam, nu, gam, R, ab, r, energy, active = (Xn, Qn, ln, nn, gn, Rn, abn, rn, en,
                                                        an)
    return X, Q, lam, nu, gam, r, it, CONVERGED, energy
