"""Numba kernels of the contact between two parts (``coupled``): distances from points to
another part's neutral line, taken as the Catmull-Rom spline through its nodes.

A segment f of the spline (nodes x_f .. x_f+1) depends on four nodes x_f-1 .. x_f+2:
q(beta) = sum_j w_j(beta) x_j, tangent-continuous at the nodes, the first and last
segments extended by a straight phantom node (x_-1 = 2 x_0 - x_1). A probe on the first
part is p = (1 - alpha) x_e + alpha x_e+1. The coordinates of one contact are y (18,):
x_e, x_e+1, then the four nodes of the segment (a phantom's slot is its real neighbour's
duplicate, with weight 0).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _basis(b, out, d1, d2):
    """Catmull-Rom weights at b and their first and second derivatives."""
    b2 = b * b
    b3 = b2 * b
    out[0] = 0.5 * (-b3 + 2.0 * b2 - b)
    out[1] = 0.5 * (3.0 * b3 - 5.0 * b2 + 2.0)
    out[2] = 0.5 * (-3.0 * b3 + 4.0 * b2 + b)
    out[3] = 0.5 * (b3 - b2)
    d1[0] = 0.5 * (-3.0 * b2 + 4.0 * b - 1.0)
    d1[1] = 0.5 * (9.0 * b2 - 10.0 * b)
    d1[2] = 0.5 * (-9.0 * b2 + 8.0 * b + 1.0)
    d1[3] = 0.5 * (3.0 * b2 - 2.0 * b)
    d2[0] = 0.5 * (-6.0 * b + 4.0)
    d2[1] = 0.5 * (18.0 * b - 10.0)
    d2[2] = 0.5 * (-18.0 * b + 8.0)
    d2[3] = 0.5 * (6.0 * b - 2.0)


@njit(cache=True, inline="always")
def _fold(w, left, right):
    """A phantom node's weight moved onto the real ones (x_-1 = 2 x_0 - x_1)."""
    if left:
        w[1] += 2.0 * w[0]
        w[2] -= w[0]
        w[0] = 0.0
    if right:
        w[2] += 2.0 * w[3]
        w[1] -= w[3]
        w[3] = 0.0


@njit(cache=True)
def project(p, yb, left, right, beta, loose):
    """Newton on beta for the point of the segment (nodes yb (4, 3)) nearest p, from
    ``beta``; in [0, 1], or with ``loose`` past the segment's inner ends (its cubic
    extended: what a derivative needs where a point crosses to the next segment).
    Returns (beta, w (4,) the folded weights there)."""
    lo = 0.0 if (left or not loose) else -0.5
    hi = 1.0 if (right or not loose) else 1.5
    w = np.empty(4)
    w1 = np.empty(4)
    w2 = np.empty(4)
    for _ in range(12):
        _basis(beta, w, w1, w2)
        _fold(w, left, right)
        _fold(w1, left, right)
        _fold(w2, left, right)
        phi = 0.0
        a = 0.0
        b = 0.0
        for c in range(3):
            q = 0.0
            q1 = 0.0
            q2 = 0.0
            for j in range(4):
                q += w[j] * yb[j, c]
                q1 += w1[j] * yb[j, c]
                q2 += w2[j] * yb[j, c]
            v = q - p[c]
            phi += v * q1
            a += q1 * q1
            b += v * q2
        dphi = a + b if a + b > 0.0 else a + 1e-300
        new = min(hi, max(lo, beta - phi / dphi))
        if abs(new - beta) < 1e-15:
            beta = new
            break
        beta = new
    _basis(beta, w, w1, w2)
    _fold(w, left, right)
    return beta, w


@njit(cache=True)
def nearest(points, nodes):
    """Each point's nearest point of the spline through ``nodes`` (M + 1, 3): the
    polyline's nearest segment and its two neighbours, each projected. Returns (f,
    beta, jb (K, 4), left, right, q (K, 3))."""
    K = points.shape[0]
    M = nodes.shape[0] - 1
    f_out = np.empty(K, dtype=np.int64)
    b_out = np.empty(K)
    jb = np.empty((K, 4), dtype=np.int64)
    left = np.empty(K, dtype=np.bool_)
    right = np.empty(K, dtype=np.bool_)
    q_out = np.empty((K, 3))
    yb = np.empty((4, 3))
    for k in range(K):
        p = points[k]
        best = 1e300
        f0 = 0
        b0 = 0.0
        for f in range(M):
            ss = 0.0
            rs = 0.0
            for c in range(3):
                s = nodes[f + 1, c] - nodes[f, c]
                ss += s * s
                rs += (p[c] - nodes[f, c]) * s
            t = min(1.0, max(0.0, rs / max(ss, 1e-300)))
            d2 = 0.0
            for c in range(3):
                v = p[c] - nodes[f, c] - t * (nodes[f + 1, c] - nodes[f, c])
                d2 += v * v
            if d2 < best:
                best = d2
                f0 = f
                b0 = t
        best = 1e300
        for shift in range(-1, 2):
            f = f0 + shift
            if f < 0 or f > M - 1:
                continue
            start = b0 if shift == 0 else (1.0 if shift < 0 else 0.0)
            for j in range(4):
                node = min(M, max(0, f - 1 + j))
                for c in range(3):
                    yb[j, c] = nodes[node, c]
            lf = f == 0
            rt = f == M - 1
            beta, w = project(p, yb, lf, rt, start, False)
            d2 = 0.0
            q = np.zeros(3)
            for c in range(3):
                for j in range(4):
                    q[c] += w[j] * yb[j, c]
                d2 += (p[c] - q[c]) ** 2
            if d2 < best:
                best = d2
                f_out[k] = f
                b_out[k] = beta
                left[k] = lf
                right[k] = rt
                for j in range(4):
                    jb[k, j] = min(M, max(0, f - 1 + j))
                for c in range(3):
                    q_out[k, c] = q[c]
    return f_out, b_out, jb, left, right, q_out


@njit(cache=True, inline="always")
def _unpack(y, alpha):
    """The probe p (3,) at ``alpha`` of y's element (its first 6 entries) and the four
    nodes (4, 3) of the other part's curve there (its last 12)."""
    p = np.empty(3)
    yb = np.empty((4, 3))
    for c in range(3):
        p[c] = (1.0 - alpha) * y[c] + alpha * y[3 + c]
        for j in range(4):
            yb[j, c] = y[6 + 3 * j + c]
    return p, yb


@njit(cache=True)
def gradient(y, alpha, left, right, beta):
    """d |p - q| / d y (18,) (envelope theorem: beta's change does not enter), and
    beta; q is projected afresh (loosely) from ``beta``."""
    p, yb = _unpack(y, alpha)
    beta, w = project(p, yb, left, right, beta, True)
    n = np.empty(3)
    d = 0.0
    for c in range(3):
        q = 0.0
        for j in range(4):
            q += w[j] * yb[j, c]
        n[c] = p[c] - q
        d += n[c] * n[c]
    d = max(math.sqrt(d), 1e-300)
    g = np.empty(18)
    for c in range(3):
        n[c] /= d
        g[c] = (1.0 - alpha) * n[c]
        g[3 + c] = alpha * n[c]
        for j in range(4):
            g[6 + 3 * j + c] = -w[j] * n[c]
    return g, beta


@njit(cache=True)
def gradients(y, alpha, left, right, beta):
    """``gradient`` for K contacts: (K, 18)."""
    out = np.empty((y.shape[0], 18))
    for k in range(y.shape[0]):
        out[k] = gradient(y[k], alpha[k], left[k], right[k], beta[k])[0]
    return out


@njit(cache=True)
def hessian(y, alpha, left, right, beta, h):
    """The distance's Hessian (18, 18): central differences of ``gradient``,
    symmetrised."""
    H = np.empty((18, 18))
    z = y.copy()
    for j in range(18):
        z[j] = y[j] + h
        up = gradient(z, alpha, left, right, beta)[0]
        z[j] = y[j] - h
        down = gradient(z, alpha, left, right, beta)[0]
        z[j] = y[j]
        for i in range(18):
            H[j, i] = (up[i] - down[i]) / (2.0 * h)
    for i in range(18):
        for j in range(i + 1, 18):
            v = 0.5 * (H[i, j] + H[j, i])
            H[i, j] = v
            H[j, i] = v
    return H


@njit(cache=True)
def _distance(y, alpha, left, right, beta):
    """|p - q|: the probe at ``alpha`` of y's element to its nearest point of the curve."""
    p, yb = _unpack(y, alpha)
    _, w = project(p, yb, left, right, beta, True)
    d = 0.0
    for c in range(3):
        q = 0.0
        for j in range(4):
            q += w[j] * yb[j, c]
        d += (p[c] - q) ** 2
    return math.sqrt(d)


@njit(cache=True)
def slide(y, alpha, left, right, beta, h):
    """Where along its element the probe's distance to the curve is least, and the
    correction that turns the fixed probe's Hessian into that nearest point's: (alpha*,
    d2 = d^2 D / d alpha^2, c = d (dD / d alpha) / d y (18,)), by central differences
    (steps 1e-4 in alpha, h in y). The Hessian of min over alpha of D is H - c c^T / d2
    where the least lies inside the element (the envelope theorem, as
    ``contact_kernels._slide_jacobian`` for obstacles)."""
    da = 1e-4
    d0 = _distance(y, alpha, left, right, beta)
    up = _distance(y, alpha + da, left, right, beta)
    down = _distance(y, alpha - da, left, right, beta)
    d1 = (up - down) / (2.0 * da)
    d2 = (up - 2.0 * d0 + down) / (da * da)
    c = np.empty(18)
    z = y.copy()
    for j in range(18):
        z[j] = y[j] + h
        hi = (_distance(z, alpha + da, left, right, beta)
              - _distance(z, alpha - da, left, right, beta)) / (2.0 * da)
        z[j] = y[j] - h
        lo = (_distance(z, alpha + da, left, right, beta)
              - _distance(z, alpha - da, left, right, beta)) / (2.0 * da)
        z[j] = y[j]
        c[j] = (hi - lo) / (2.0 * h)
    star = alpha - d1 / d2 if d2 > 0.0 else -1.0
    return star, d2, c


@njit(cache=True)
def weights(beta, left, right):
    """The folded Catmull-Rom weights (4,) at beta and their first and second
    derivatives in beta (a point, tangent and curvature vector of a segment)."""
    w = np.empty(4)
    w1 = np.empty(4)
    w2 = np.empty(4)
    _basis(beta, w, w1, w2)
    _fold(w, left, right)
    _fold(w1, left, right)
    _fold(w2, left, right)
    return w, w1, w2


@njit(cache=True)
def bspline_weights(beta, left, right):
    """The uniform cubic B-spline's weights (4,) on the same four nodes, and their first
    and second derivatives in beta, folded as ``weights``. The curve passes within
    h^2 kappa / 6 of the nodes and, unlike Catmull-Rom's, its curvature is continuous:
    what a clip that slides along it needs (the slide's equation holds the tangent's
    derivative, which must not jump at the nodes). With the straight phantom nodes it
    starts and ends at the end nodes."""
    b = beta
    c = 1.0 - b
    w = np.array([c * c * c / 6.0, (3.0 * b * b * b - 6.0 * b * b + 4.0) / 6.0,
                  (-3.0 * b * b * b + 3.0 * b * b + 3.0 * b + 1.0) / 6.0, b * b * b / 6.0])
    w1 = np.array([-0.5 * c * c, 0.5 * (3.0 * b * b - 4.0 * b),
                   0.5 * (-3.0 * b * b + 2.0 * b + 1.0), 0.5 * b * b])
    w2 = np.array([c, 3.0 * b - 2.0, -3.0 * b + 1.0, b])
    _fold(w, left, right)
    _fold(w1, left, right)
    _fold(w2, left, right)
    return w, w1, w2
