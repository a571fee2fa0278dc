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
from pliant.models.banded import band_factor_reduced, band_lu, band_solve_factored
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
def contact_terms(X, gam, con, num, R, ab, want_jac, hand_over):
    """Add the contacts (``Contact``) to a KKT residual (and its Jacobian), in place.

    Each probe p = (1 - a) x_e + a x_e+1 has the gap g = (D(p L) - radius) / L + offset
    (D the scene's signed distance; a fixed place a, but for each element's slider, which
    without friction may move to the element's point nearest an edge or a curved
    obstacle, see ``_slide``) and the multiplier gam >= 0, the normal force it takes
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
    1 touching (sticking, with friction), 2 touching and sliding, places a (K,), and
    for each probe held free where a slider took over, the probe its force goes to
    (K,; -1: none, see ``_hand_over``), and the forces gam, those handed over moved
    to their takers where ``hand_over`` (``newton_contact``)).
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
    where = probe_a.copy()
    slid = np.zeros(K, dtype=np.int8)  # each probe: ANCHORED, SLID, BOUND or DEFERS
    mode = np.zeros(X.shape[0] - 1, dtype=np.int8)  # each element: its slider's
    if slot == 1:  # (friction's slip is a material point's: its probes stay put)
        # An element whose two nodes and slider lie over one face (one obstacle, one
        # normal) lies over it whole (a face's region is convex), its distance linear: it
        # keeps its probes.
        for e in range(con.slider.shape[0]):
            k = con.slider[e]
            k0, k1 = con.node_probe[e], con.node_probe[e + 1]
            if k0 >= 0 and k1 >= 0 and found[k0] == found[k] and found[k1] == found[k]:
                c0 = (normals[k0, 0] * normals[k, 0] + normals[k0, 1] * normals[k, 1]
                      + normals[k0, 2] * normals[k, 2])
                c1 = (normals[k1, 0] * normals[k, 0] + normals[k1, 1] * normals[k, 1]
                      + normals[k1, 2] * normals[k, 2])
                if c0 > 1.0 - 1e-14 and c1 > 1.0 - 1e-14:
                    continue
            # The normal turns along the element where its ends' normals differ: over a
            # curved obstacle, or a mesh's facets that stand for one (a dense CAD
            # mesh's faces may be smaller than the element, its slider's iterates then
            # landing on a face where the local Hessian is 0).
            bent = False
            if k0 >= 0 and k1 >= 0 and found[k0] >= 0 and found[k0] == found[k1]:
                c01 = (normals[k0, 0] * normals[k1, 0] + normals[k0, 1] * normals[k1, 1]
                       + normals[k0, 2] * normals[k1, 2])
                bent = c01 < math.cos(SLIDE_TURN)
            slid[k] = _slide(X, k, e, con, dist, normals, found, points, where, bent)
            mode[e] = slid[k]
    takers = _hand_over(slid, mode, where, gam, probe_elem, con.slider, con.node_probe, slot)
    if hand_over:
        # A probe held free that still has a force (a slider took its element over, or
        # the nearest point passed a node) hands it to the probe that now holds that
        # point: dropped, the force would leave the part with nothing holding it for one
        # Newton step, and the step would run far into the obstacle.
        copied = False
        for k in range(K):
            if takers[k] >= 0 and gam[k * slot] != 0.0:
                if not copied:
                    gam = gam.copy()
                    copied = True
                gam[takers[k] * slot] += gam[k * slot]
                gam[k * slot] = 0.0
    for k in range(K):
        e = probe_elem[k]
        a = where[k]
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
        # Where its slider took over, an element's other probes are held free: their
        # gaps are no smaller than the slider's (see _slide).
        held_free = mode[e] != ANCHORED and (slid[k] == ANCHORED or slid[k] == DEFERS)
        touching = lam > scale * soft and not held_free
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
            if slid[k] == SLID:
                _slide_jacobian(X, e, a, lam, n, H, ix, ab, kl, ku)
    return gaps, normals, which, active, where, takers, gam


SLIDE_TURN = 1e-3  # an element whose normal turns less than this [rad] keeps its probes
ANCHORED, SLID, BOUND, DEFERS = 0, 1, 2, 3  # where _slide leaves a probe


@njit(cache=True, inline="always")
def _slide(X, k, e, con, dist, normals, found, points, where, bent):
    """Element e's slider, its probe k: moved to the element's point nearest the
    obstacles (a 1D Newton on the squared distance along the element: exact in one step
    at a mesh's edge or vertex), its entries in dist, normals, found, points [m] and
    where updated in place.

    Over a face, fixed probes spread the contact along the part and their normals are
    exact. Over an edge or a curved surface they are not: a fixed probe's normal leans
    by up to half the probes' spacing over the tube's radius, a force error first order
    in the spacing (3 % at the default resolution over a box's edge). There a straight
    element meets a convex obstacle at one point, the nearest, where the normal is
    square to the part's axis: the slider holds that point, and the element's other
    probes, whose gaps are no smaller, are held free (``contact_terms``).

    Returns ``ANCHORED`` where the element keeps its fixed probes (the slider one of
    them, at its place): its normal turns by less than ``SLIDE_TURN`` along it (a face,
    a gentle curve), or it is too far to touch. Else the element is the slider's:
    ``SLID`` where the nearest point lies inside it (it then moves with the nodes, see
    ``_slide_jacobian``); ``BOUND`` where it is an end node that the next element does
    not come nearer than (a kink at the nearest point: both elements' sliders hold it,
    one row twice, which the compliance keeps regular; or the part's end); ``DEFERS``
    where it is an end beyond which the next element comes nearer (its slider or its
    probes hold that): it is then held free. So, as the nearest point passes a node,
    the two sliders share it before the next takes it over: neither a point that
    nothing holds nor two rows at nearby points at once, which a straight element
    cannot meet together (see also ``_hand_over``).
    """
    radius, L = con.radius, con.length
    if con.node_probe[e] < 0 or con.node_probe[e + 1] < 0:
        # Beside a node a station holds, the nearest point can come to that node: a held
        # point on the surface about which the element turns, whose gap then changes
        # with the turn only to second order (no force could hold it).
        return ANCHORED
    # d p / d a [m], in scalars: an array here was an allocation per element per residual
    D0 = (X[e + 1, 0] - X[e, 0]) * L
    D1 = (X[e + 1, 1] - X[e, 1]) * L
    D2 = (X[e + 1, 2] - X[e, 2]) * L
    size = math.sqrt(D0 * D0 + D1 * D1 + D2 * D2)
    a, d, o = where[k], dist[k], found[k]
    if not (d - radius) + con.offset * L < size:  # no part of it can touch
        return ANCHORED
    # (Bound only here: binding the scene's packed arrays costs a reference count each,
    # some 0.1 us an element, and most elements return above.)
    field = con.field
    n0, n1, n2 = normals[k, 0], normals[k, 1], normals[k, 2]
    p = points[k].copy()
    turns = bent  # the ends' normals differ (see the caller), else the local curvature
    settled = False
    # A safeguarded Newton: along a line the distance to a convex piece is convex, so
    # the sign of its slope brackets the nearest point; a step past the bracket tries
    # the bracket's untried end (an end may be the nearest point), else halves it.
    lo, hi = 0.0, 1.0
    lo_seen, hi_seen = False, False
    for _ in range(40):
        if o < 0 or d <= 0.0:
            break
        H = hessian_point(p, o, field)
        fp = n0 * D0 + n1 * D1 + n2 * D2
        h0 = H[0, 0] * D0 + H[0, 1] * D1 + H[0, 2] * D2
        h1 = H[1, 0] * D0 + H[1, 1] * D1 + H[1, 2] * D2
        h2 = H[2, 0] * D0 + H[2, 1] * D1 + H[2, 2] * D2
        fpp = D0 * h0 + D1 * h1 + D2 * h2
        bend = h0 * h0 + h1 * h1 + h2 * h2
        if math.sqrt(bend) > SLIDE_TURN:
            turns = True
        if fp > 0.0:
            hi, hi_seen = a, True
        elif fp < 0.0:
            lo, lo_seen = a, True
        if fp == 0.0 or (fp > 0.0 and a == 0.0) or (fp < 0.0 and a == 1.0) or (
                hi - lo <= 1e-12):
            settled = True
            break
        den = fp * fp + d * fpp
        an = a - d * fp / den if den > 0.0 else -1.0
        if abs(an - a) <= 1e-12:  # the minimum
            settled = True
            break
        if not lo < an < hi:
            if fp > 0.0 and not lo_seen:
                an = lo
            elif fp < 0.0 and not hi_seen:
                an = hi
            else:
                an = 0.5 * (lo + hi)
        if abs(an - a) <= 1e-12:
            settled = True
            break
        a = an
        for c in range(3):
            p[c] = ((1.0 - a) * X[e, c] + a * X[e + 1, c]) * L
        dq, nq, oq = query_points(p.reshape(1, 3), con.band, field)
        d, n0, n1, n2, o = dq[0], nq[0, 0], nq[0, 1], nq[0, 2], oq[0]
    if not turns or not settled or not d > 0.5 * radius:
        # (Half the tube inside an obstacle: a homotopy's start or a wild iterate, where
        # the squared distance's minimum may be where the axis crosses the surface.)
        return ANCHORED
    kind = SLID
    if a == 0.0 or a == 1.0:
        node = e if a == 0.0 else e + 1
        other = node - 1 if a == 0.0 else node + 1  # the next element's far node
        kind = BOUND
        if 0 <= other < X.shape[0]:
            # Along the next element, away from the node: does the distance fall?
            fa = (n0 * (X[other, 0] - X[node, 0]) + n1 * (X[other, 1] - X[node, 1])
                  + n2 * (X[other, 2] - X[node, 2]))
            if fa < 0.0:
                kind = DEFERS
    where[k], dist[k], found[k] = a, d, o
    normals[k, 0], normals[k, 1], normals[k, 2] = n0, n1, n2
    for c in range(3):
        points[k, c] = p[c]
    return kind


NEAR_NODE = 0.25  # a nearest point this close to a node (by its element) is beside it


@njit(cache=True)
def _hand_over(slid, mode, where, gam, elem, slider, node_probe, slot):
    """Settle who holds what across nodes, and return, for each probe held free because
    a slider took its element over, the probe that takes its force over
    (``newton_contact``; -1 for none).

    First, a slider that defers across a node while it still has a force holds the node
    instead (``BOUND``) where the next element's nearest point lies just beside the
    node (within ``NEAR_NODE`` of that element): there the part touches on both sides
    of the node, two points a small turn apart, and a force handed from one to the other
    would hand itself back at the next Newton step, round and round. Where the nearest
    point walked farther (a long load step on fine elements) the hand-over stands.

    The taker: the element's slider where it holds a point; where it defers across a
    node, the next element's slider or, where that element keeps its probes, its probe
    nearest the node (none where a station holds the node: it has no probe)."""
    K = where.shape[0]
    N = mode.shape[0]
    out = np.full(K, -1, dtype=np.int64)
    if slider.shape[0] == 0:
        return out
    for e in range(N):
        k = slider[e]
        if mode[e] != DEFERS or gam[k * slot] == 0.0:
            continue
        node = e if where[k] == 0.0 else e + 1
        nxt = node - 1 if node == e else node
        if node_probe[node] < 0 or nxt < 0 or nxt >= N or mode[nxt] != SLID:
            continue
        a = where[slider[nxt]]
        if (1.0 - a if nxt < e else a) < NEAR_NODE:
            mode[e] = BOUND
            slid[k] = BOUND
    for k in range(K):
        e = elem[k]
        if mode[e] == ANCHORED or slid[k] == SLID or slid[k] == BOUND:
            continue
        for _ in range(4):  # (a chain of deferring sliders is short)
            if mode[e] == SLID or mode[e] == BOUND:
                out[k] = slider[e]
                break
            if mode[e] == ANCHORED:
                break
            node = e if where[slider[e]] == 0.0 else e + 1
            nxt = node - 1 if node == e else node
            if node_probe[node] < 0 or nxt < 0 or nxt >= N:
                break
            if mode[nxt] == ANCHORED:
                # It keeps its probes: the one nearest the node, the node's own on the
                # element after it, the one before that (probes run along the part) on
                # the element before.
                out[k] = node_probe[node] if nxt == node else node_probe[node] - 1
                break
            e = nxt
    return out


@njit(cache=True)
def _slide_jacobian(X, e, a, lam, n, H, ix, ab, kl, ku):
    """The force's Jacobian from its point's motion along its element (H: d n / d p, by
    L). The gap is g(x) = min over the element of the distance: its gradient is the one
    at the nearest point (the point's motion changes g only to second order), and its
    Hessian gains - c c^T / g'' with g' = n . (x_e+1 - x_e), c = d g' / d x and
    g'' = d g' / d a: the nearest point moves by - c . dx / g'' as the nodes move.
    (Written out in loops: array expressions cost seconds to compile.)"""
    D = np.empty(3)
    for i in range(3):
        D[i] = X[e + 1, i] - X[e, i]
    c = np.empty(6)  # d g' / d (x_e, x_e+1)
    fpp = 0.0
    for i in range(3):
        hd = H[i, 0] * D[0] + H[i, 1] * D[1] + H[i, 2] * D[2]
        fpp += D[i] * hd
        c[i] = (1.0 - a) * hd - n[i]
        c[3 + i] = a * hd + n[i]
    if not fpp > 0.0:
        return
    q = lam / fpp
    for i in range(6):
        row = ix[e + i // 3] + i % 3
        for j in range(6):
            _add(ab, kl, ku, row, ix[e + j // 3] + j % 3, q * c[i] * c[j])


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
def _contact_residual(X, Q, lam, nu, gam, mesh, tg, num, con, want_jac):
    """The KKT residual and, where ``want_jac`` (a runtime flag: see newton_contact), Jacobian
    with the contact terms, forces handed over (see ``contact_terms``); (R, ab, energy,
    active, gam)."""
    R, ab, energy = assemble(X, Q, lam, nu, mesh, tg, num, want_jac)
    if con.iprobe.shape[0] == 0:  # a part touching nothing (10 us of empty work at 100 elements)
        return R, ab, energy, np.zeros(0, dtype=np.int8), gam
    out = contact_terms(X, gam, con, num, R, ab, want_jac, num.n >= 0)
    return R, ab, energy, out[3], out[6]


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


@njit(cache=True, inline="always")
def free_rows(active, iprobe, slot, n):
    """(n,) True at the rows of the probes that touch nothing: ``contact_terms`` writes
    each of them as the identity's (1 on the diagonal, nothing else in the row), what
    ``banded.identity_rows`` would find by reading the band (tested to agree)."""
    out = np.zeros(n, dtype=np.bool_)
    for k in range(iprobe.shape[0]):
        if active[k] == 0:
            for j in range(slot):
                out[iprobe[k] + j] = True
    return out


# A chord step (the last factorisation reused) is taken where it shrinks the residual
# tenfold; it costs a residual and a back substitution, a fresh
# step a Jacobian and a band LU more (0.1, 0.05 and 0.25 gave the same time, within
# the machine's noise, on benchmarks/contact.py (b)).
CHORD = 0.1


@njit(cache=True)
def newton_contact(X, Q, lam, nu, gam, mesh, tg, num, con, opts):
    """The semismooth Newton of a problem with obstacles, in one kernel; also a part's
    without any (no probes, an empty scene: its chord steps kept while they contract as
    ``contraction`` asks of a corrector, or lower the residual in a damped Newton).
    Acceptance (opts: ``Settings``):

    - ``predict`` (a warm step, from an equilibrium of nearby loads): the first step is
      the continuation's predictor, taken in full;
    - a corrector (strict) with no probe touching: the full step must contract by
      ``contraction``;
    - while probes touch, or not strict: any step that lowers the residual, backtracking
      from the full one (the Jacobian jumps on an obstacle's seams, a face meeting an
      edge's rounding, so convergence there is not quadratic); a corrector gives up
      below a tenth of a step, and its continuation shortens the load step instead;
    - a full step that changes which probes touch, or gives a touching probe its first
      force, up to ``max_switches`` times.

    In a warm step the factorised Jacobian is kept (a chord step) while the same probes
    touch and a full step shrinks the residual by ``CHORD``; otherwise it is rebuilt
    where the iteration stands (the active set may have changed). A chord step is tried
    after the predictor and after steps that converged as fast. Not in a continuation's
    correctors: there chord steps took more load steps (105 to 112 on a hose lowered
    onto a block from straight at 400 elements, 20 % more time).

    Returns (X, Q, lam, nu, gam, residual, iterations, status, energy)."""
    tol, max_iter, contraction, strict, max_switches, predict = opts
    iprobe, slot = con.iprobe, con.slot
    kl, ku = num.kl, num.ku
    # Runtime flags, not the literals True and False: numba compiles a callee once more
    # for each literal it is called with.
    yes = num.n >= 0
    it = 0
    switches = 0
    # The last factorisation: of ``fab`` without its identity rows ``fdrop`` (none yet).
    fab, fdrop = np.zeros((0, 0)), np.zeros(0, dtype=np.bool_)
    c, lo, up, new, piv = np.zeros((0, 0)), 0, 0, np.zeros(0, dtype=np.int64), np.zeros(
        0, dtype=np.int64)
    chord = False  # whether the last step converged fast enough to try one
    # A part touching nothing (no probes) has no active set to change: chord steps pay
    # in every mode, each kept while it contracts as a fresh step must, so that a slower
    # one still makes its progress before the Jacobian is rebuilt.
    free = iprobe.shape[0] == 0
    chords = predict or free
    # A warm step's trial points are judged without their Jacobian (the next step is
    # often a chord step, which needs none); it is built where a fresh one is needed.
    jac = not chords
    R, ab, energy, r = np.zeros(0), np.zeros((0, 0)), 0.0, math.inf
    active = np.zeros(iprobe.shape[0], dtype=np.int8)
    while True:
        if ab.shape[0] == 0 and not chord and r > tol:
            # The residual and Jacobian where the iteration stands: at the start, and
            # where a fresh step follows a point judged without its Jacobian. (One call
            # site: each costs compile time, the arguments' bundles being large.)
            R, ab, energy, active, gam = _contact_residual(X, Q, lam, nu, gam, mesh, tg, num,
                                                           con, yes)
            r = contact_max(R, con)
            if not math.isfinite(r):
                return X, Q, lam, nu, gam, r, it, NOT_FINITE, energy
        if r <= tol:
            break
        if it >= max_iter:
            return X, Q, lam, nu, gam, r, it, MAX_ITERATIONS, energy
        it += 1
        fresh = not chord
        if fresh:
            if free:  # nothing to leave out: factorised in place (ab is not read again)
                piv, ok = band_lu(ab, kl, ku)
                c, lo, up = ab, kl, ku
            else:
                # The free probes' rows are the identity's: they leave the factorisation.
                fdrop = free_rows(active, iprobe, slot, ab.shape[0])
                c, lo, up, new, piv, ok = band_factor_reduced(ab, kl, ku, fdrop)
            if not ok:
                return X, Q, lam, nu, gam, r, it, SINGULAR, energy
            fab = ab
        du = band_solve_factored(fab, kl, ku, fdrop, c, lo, up, new, piv, -R)
        damped = not strict
        # A probe that touches with no force yet (it has just met the obstacle) takes its
        # first force in this step: its normal's turn as its point moves is then not in
        # the Jacobian (it scales with the force), so the residual may grow once. Like a
        # switch, that full step is taken.
        entering = False
        for k in range(active.shape[0]):
            if active[k]:
                damped = True
                if gam[k * slot] == 0.0:
                    entering = True
        step = 1.0
        accepted = False
        for _ in range(30 if damped and fresh else 1):
            Xn, Qn, ln, nn = apply_step(X, Q, lam, nu, du, num, step)
            gn = gam.copy()
            for k in range(iprobe.shape[0]):
                for j in range(slot):
                    gn[k * slot + j] += step * du[iprobe[k] + j]
            Rn, abn, en, an, gn = _contact_residual(Xn, Qn, ln, nn, gn, mesh, tg, num, con,
                                                    jac)
            rn = contact_max(Rn, con)
            finite = math.isfinite(rn)
            changed = False
            regrouped = False  # a probe went from free to touching or back
            for k in range(an.shape[0]):
                if an[k] != active[k]:
                    changed = True
                    if (an[k] == 0) != (active[k] == 0):
                        regrouped = True
            if not fresh:  # a chord step: the same probes touching, tenfold smaller
                if free:
                    accepted = finite and (rn <= tol or rn <= (
                        contraction if strict else 1.0 - 1e-4) * r)
                else:
                    accepted = rn <= CHORD * r and not changed
                break
            if it == 1 and predict:
                accepted = finite
            elif damped:
                accepted = finite and rn <= (1.0 - 1e-4 * step) * r
            else:
                accepted = rn <= contraction * r or rn <= tol
            if (not accepted and step == 1.0 and switches < max_switches and finite
                    and (changed or entering)):
                switches += 1
                accepted = True
            if accepted:
                break
            step *= 0.5
        if not fresh and not accepted:
            # Refused: a fresh step from where the iteration stands, in the same count.
            chord = False
            it -= 1
            continue
        if not accepted or (strict and step < 0.1):
            # A corrector crawling in tiny steps is far from its basin: the
            # continuation does better with a shorter step in the load.
            return X, Q, lam, nu, gam, r, it, NOT_CONTRACTING, energy
        # After the predictor, or a step that converged as fast as a chord must: the
        # next may keep this factorisation. Elsewhere (a probe entering, a step on an
        # obstacle's seam) a chord would only cost a residual before the rebuild. Not
        # where the step took a probe in or let one go: the factorisation leaves out the
        # rows of the probes that were free, and chord steps with it converge to the old
        # touching set, stall near it (2e-4 on a hose lowered onto a block's edge) and
        # leave a fresh step a probe to release with its whole force (a residual of
        # hundreds, two or three factorisations more).
        if fresh:
            chord = chords and not regrouped and ((predict and it == 1) or rn <= CHORD * r)
        elif rn > CHORD * r:  # (a free part's slower chord step) the next one is fresh
            chord = False
        X, Q, lam, nu, gam, R, ab, r, energy, active = (Xn, Qn, ln, nn, gn, Rn, abn, rn, en,
                                                        an)
    return X, Q, lam, nu, gam, r, it, CONVERGED, energy
