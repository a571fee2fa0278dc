"""Numba kernels of the 3D rod: a discrete inextensible Kirchhoff (Cosserat) rod.

The discretisation is that of Lang, Linn and Arnold's quaternion Cosserat rods
(Multibody System Dynamics 25, 2011), the model behind industrial cable simulation,
made inextensible and unshearable by constraints:

- nodes x_i (i = 0..N) on the centreline, elements e between x_e and x_e+1 of length h_e,
  each with a unit quaternion q_e for its material frame (d1, d2, d3), d3 the tangent;
- a *station frame* at every station node (the ends always), so that clamps, grips and
  applied moments act on the section exactly where they are, not half an element away;
- consecutive frames a, b meet at a joint with cell length hh (the distance between the
  frames' locations); the discrete Darboux vector there is kappa = (2/hh) Im(conj(q_a) q_b),
  a second-order approximation of the curvatures about d1, d2 and the twist;
- elastic energy sum over joints of (hh/2) (kappa - kappa0)^T K (kappa - kappa0), with
  K = diag(EI1, EI2, GJ);
- constraints c_e = x_e+1 - x_e - h_e R(q_e) e3 = 0 (inextensible, unshearable); their
  multipliers lambda_e are the internal forces n (the force the part beyond exerts on the
  part before, as in 2D); station constraints' multipliers are the reactions.
- an extensible part (axial compliance C = 1 / EA, K[3] here) relaxes them to
  c_e - h_e C N_e d3 = 0, N_e = lambda_e . d3: the element stretches by the axial strain
  C N_e. That is the stationarity of the mixed Lagrangian with the complementary energy
  -(h_e C / 2) N_e^2 added (so the Jacobian stays symmetric), and C = 0 is the
  inextensible rod exactly.

The unknowns are node positions, frame rotation increments theta (material, q <- q exp
(theta)), element multipliers and station multipliers. The KKT residual is

    R_x = -f + (d c / d x)^T lambda + (d s / d x)^T nu      (force balance at nodes)
    R_theta = dU/dtheta + (d c / d theta)^T lambda + (d s / d theta)^T nu - Q   (moments)
    R_lambda = c,  R_nu = s

with f the applied nodal forces and Q the applied generalised moments (dead moments in
the global frame, follower loads in the material frame). Its exact Jacobian is banded
when the unknowns are numbered along s; it is solved by a banded LU with partial
pivoting. Everything is dimensionless (lengths by L, stiffness by EI1). Contact with
obstacles, and the one Newton solve with or without them, are ``contact_kernels``'s.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from pliant.models.banded import add_block as _add_block
from pliant.models.banded import (  # noqa: F401
    band_lu,
    band_lu_solve,
    band_solve,
    band_solve_reduced,
    identity_rows,
)

# Orientation kinds of a station.
FREE = 0
AXIS = 1
FULL = 2


# -- the kernels' arguments, in named bundles (numba takes NamedTuples as structs) --------
class Mesh(NamedTuple):
    """What a discretisation fixes (dimensionless): elements, frames, joints, stations."""

    h: np.ndarray  # (N,) element lengths
    elem_frame: np.ndarray  # (N,) int, each element's frame
    joint_hh: np.ndarray  # (J,) each joint's cell length (J = F - 1)
    K: np.ndarray  # (4,) EI1, EI2, GJ by EI1, and the axial compliance EI1 / (EA L^2)
    st_node: np.ndarray  # (S,) int, each station's node
    st_frame: np.ndarray  # (S,) int, and frame
    st_pos_mask: np.ndarray  # (S, 3) int, which positions it prescribes
    st_kind: np.ndarray  # (S,) int, FREE, AXIS or FULL


class Targets(NamedTuple):
    """What moves along a homotopy (dimensionless): rest curvature, targets, loads."""

    joint_k0: np.ndarray  # (J, 3) rest Darboux vectors
    fnode: np.ndarray  # (N+1, 3) applied dead nodal forces
    st_pos: np.ndarray  # (S, 3) prescribed positions
    st_axis_b: np.ndarray  # (S, 2, 3) the basis across a prescribed axis (AXIS)
    st_quat: np.ndarray  # (S, 4) prescribed orientations (FULL)
    st_moment: np.ndarray  # (S, 3) dead moments (global)
    st_ffollow: np.ndarray  # (S, 3) follower forces (material)
    st_mfollow: np.ndarray  # (S, 3) follower moments (material)
    elem_follow: np.ndarray  # (N, 3) follower force per length on each element (material)
    gauge: np.ndarray  # (4,) the frame whose twist the twist gauge holds


class Numbering(NamedTuple):
    """Where each unknown sits: the first of each node (ix), frame (ith), element
    multiplier (ilam) and station multiplier (inu); each station's first entry (nu_off)
    and count (nu_cnt) in nu; the twist gauge's frame and unknown (-1: none); the
    system's size n and half band widths kl, ku."""

    ix: np.ndarray
    ith: np.ndarray
    ilam: np.ndarray
    inu: np.ndarray
    nu_off: np.ndarray
    nu_cnt: np.ndarray
    gauge_frame: int
    igauge: int
    n: int
    kl: int
    ku: int


class Contact(NamedTuple):
    """The probes and the scene (see ``contact_terms``): each probe's element and place
    in it; each element's slider (a probe, see ``_slide``) and each node's probe (-1
    where a station holds the node whole); each probe's first unknown; unknowns per probe (1, or 3
    with friction); L [m], the tube's radius [m], the offset added to every gap, the
    exact-distance band [m], the complementarity's scale; the scene's packed distance
    field; and friction's reference (mu per obstacle, where each probe's spring is
    slack (K, 3, by L), their tangent bases (K, 2, 3), their elastic slips (K,, by L))."""

    probe_elem: np.ndarray
    probe_a: np.ndarray
    slider: np.ndarray
    node_probe: np.ndarray
    iprobe: np.ndarray
    slot: int
    length: float
    radius: float
    offset: float
    band: float
    scale: float
    field: tuple
    friction: tuple


class Settings(NamedTuple):
    """A Newton's budget: tolerance, iterations, the contraction a corrector must reach,
    whether it is a corrector (else a damped Newton), the active-set switches a
    full step may make, and whether it is a warm step (contact: its first step the
    predictor, taken in full, then chord steps while they contract)."""

    tol: float
    max_iter: int
    contraction: float
    strict: bool
    max_switches: int
    predict: bool


# -- quaternions (w, x, y, z) ------------------------------------------------------------
@njit(cache=True)
def _qexp_t(t0, t1, t2):
    """exp of the rotation vector (t0, t1, t2) as a quaternion tuple (no array: the
    Newton update's, on every frame); unit but for the first order at tiny angles."""
    angle = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    if angle < 1e-12:
        return 1.0, 0.5 * t0, 0.5 * t1, 0.5 * t2
    c = math.cos(0.5 * angle)
    s = math.sin(0.5 * angle) / angle
    return c, s * t0, s * t1, s * t2


def qexp(theta: np.ndarray) -> np.ndarray:
    """exp of a rotation vector (3,) as a quaternion (4,): ``_qexp_t`` from Python."""
    return np.array(_qexp_t(float(theta[0]), float(theta[1]), float(theta[2])))


# -- assembly -----------------------------------------------------------------------------
@njit(cache=True)
def _qm(aw, ax, ay, az, bw, bx, by, bz):
    """Quaternion product as a tuple (no allocation)."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(cache=True)
def _rot_into(q, out):
    w, x, y, z = q[0], q[1], q[2], q[3]
    out[0, 0] = 1 - 2 * (y * y + z * z)
    out[0, 1] = 2 * (x * y - w * z)
    out[0, 2] = 2 * (x * z + w * y)
    out[1, 0] = 2 * (x * y + w * z)
    out[1, 1] = 1 - 2 * (x * x + z * z)
    out[1, 2] = 2 * (y * z - w * x)
    out[2, 0] = 2 * (x * z - w * y)
    out[2, 1] = 2 * (y * z + w * x)
    out[2, 2] = 1 - 2 * (x * x + y * y)


@njit(cache=True)
def _tmul(Rm, v0, v1, v2):
    """R^T v as a tuple."""
    return (Rm[0, 0] * v0 + Rm[1, 0] * v1 + Rm[2, 0] * v2,
            Rm[0, 1] * v0 + Rm[1, 1] * v1 + Rm[2, 1] * v2,
            Rm[0, 2] * v0 + Rm[1, 2] * v1 + Rm[2, 2] * v2)


@njit(cache=True)
def _mul(Rm, v0, v1, v2):
    """R v as a tuple."""
    return (Rm[0, 0] * v0 + Rm[0, 1] * v1 + Rm[0, 2] * v2,
            Rm[1, 0] * v0 + Rm[1, 1] * v1 + Rm[1, 2] * v2,
            Rm[2, 0] * v0 + Rm[2, 1] * v1 + Rm[2, 2] * v2)


@njit(cache=True)
def _sym_e3(H, mu0, mu1, mu2, factor):
    """H += factor * (e3 mu^T + mu e3^T - 2 mu3 I) / 2 (the second derivative of
    R exp(theta) e3 contracted with R mu)."""
    H[2, 0] += 0.5 * factor * mu0
    H[2, 1] += 0.5 * factor * mu1
    H[2, 2] += factor * mu2
    H[0, 2] += 0.5 * factor * mu0
    H[1, 2] += 0.5 * factor * mu1
    H[0, 0] -= factor * mu2
    H[1, 1] -= factor * mu2
    H[2, 2] -= factor * mu2


@njit(cache=True)
def assemble(X, Q, lam, nu, mesh, tg, num, want_jac):
    """KKT residual R (n,) and Jacobian in band storage (n, 2 kl + ku + 1), and energy.

    X (N+1, 3) node positions; Q (F, 4) frame quaternions; lam (N, 3) element
    multipliers; nu (m,) station multipliers (in station order, each station's position
    components first, then its 2 (axis) or 3 (full) orientation ones; the twist gauge
    last); mesh, tg, num: ``Mesh``, ``Targets`` (with the frame whose twist the gauge
    holds), ``Numbering``.
    """
    h, elem_frame, joint_hh, K, st_node, st_frame, st_pos_mask, st_kind = mesh
    joint_k0, fnode, st_pos, st_axis_b, st_quat, st_moment, st_ffollow, st_mfollow, _, _ = tg
    ix, ith, ilam, inu, nu_off, _, gauge_frame, igauge, n, kl, ku = num
    R = np.zeros(n)
    ab = np.zeros((n, 2 * kl + ku + 1)) if want_jac else np.zeros((0, 0))
    Rm = np.empty((3, 3))
    B = np.empty((3, 3))
    H = np.empty((3, 3))
    Ja = np.empty((3, 3))
    Jb = np.empty((3, 3))
    Haa = np.empty((3, 3))
    Hbb = np.empty((3, 3))
    Hab = np.empty((3, 3))
    applied = np.zeros((Q.shape[0], 3))  # generalised applied moments on each frame
    energy = 0.0
    N = h.shape[0]
    kv = kl + ku
    # Applied nodal forces (dead: weight, point loads).
    for i in range(X.shape[0]):
        for c in range(3):
            R[ix[i] + c] -= fnode[i, c]
    # Elements: inextensibility constraints c = x_e+1 - x_e - h R e3 (with stretch:
    # c - h C N d3).
    comp = K[3]
    for e in range(N):
        f = elem_frame[e]
        _rot_into(Q[f], Rm)
        row = ilam[e]
        he = h[e]
        mu0, mu1, mu2 = _tmul(Rm, lam[e, 0], lam[e, 1], lam[e, 2])
        stretch = 1.0 + comp * mu2
        for c in range(3):
            R[row + c] = X[e + 1, c] - X[e, c] - he * stretch * Rm[c, 2]
            R[ix[e] + c] -= lam[e, c]
            R[ix[e + 1] + c] += lam[e, c]
        # (dc/dtheta)^T lambda = -h e3 x mu (times the stretch)
        t = ith[f]
        R[t] += he * stretch * mu1
        R[t + 1] -= he * stretch * mu0
        if comp != 0.0:
            energy += 0.5 * he * comp * mu2 * mu2
        # A distributed follower load q (material, per unloaded length): h R q, half on
        # each node; d/dtheta (R exp(theta) q) = -R [q]x, so dR_x/dtheta = +(h/2) R [q]x.
        F0, F1, F2 = tg.elem_follow[e, 0], tg.elem_follow[e, 1], tg.elem_follow[e, 2]
        if F0 != 0.0 or F1 != 0.0 or F2 != 0.0:
            g0, g1, g2 = _mul(Rm, F0, F1, F2)
            for node in (e, e + 1):
                R[ix[node]] -= 0.5 * he * g0
                R[ix[node] + 1] -= 0.5 * he * g1
                R[ix[node] + 2] -= 0.5 * he * g2
            if want_jac:
                for a in range(3):
                    B[a, 0] = 0.5 * he * (Rm[a, 1] * F2 - Rm[a, 2] * F1)
                    B[a, 1] = 0.5 * he * (Rm[a, 2] * F0 - Rm[a, 0] * F2)
                    B[a, 2] = 0.5 * he * (Rm[a, 0] * F1 - Rm[a, 1] * F0)
                _add_block(ab, kl, ku, ix[e], t, B)
                _add_block(ab, kl, ku, ix[e + 1], t, B)
        if want_jac:
            for c in range(3):
                ab[ix[e + 1] + c, kv + row - ix[e + 1]] += 1.0
                ab[ix[e] + c, kv + row - ix[e]] -= 1.0
                ab[row + c, kv + ix[e + 1] - row] += 1.0
                ab[row + c, kv + ix[e] - row] -= 1.0
            hc = he * comp
            if comp != 0.0:
                for a in range(3):
                    for b in range(3):
                        H[a, b] = -hc * Rm[a, 2] * Rm[b, 2]  # dR_lambda / dlambda
                _add_block(ab, kl, ku, row, row, H)
            # dR_lambda/dtheta = h R [e3]x (1 + C N) plus h C d3 (dN/dtheta)^T: columns
            # h (1 + C N) (R[:,1], -R[:,0], 0) + h C (mu1, -mu0, 0) d3; and its transpose
            for c in range(3):
                d0 = he * stretch * Rm[c, 1] + hc * mu1 * Rm[c, 2]
                d1 = -(he * stretch * Rm[c, 0] + hc * mu0 * Rm[c, 2])
                ab[t, kv + row + c - t] += d0
                ab[t + 1, kv + row + c - t - 1] += d1
                ab[row + c, kv + t - row - c] += d0
                ab[row + c, kv + t + 1 - row - c] += d1
            # d2/dtheta2 of -h (N + C N^2 / 2): -h (1 + C N) d2N - h C dN dN^T
            for a in range(3):
                for b in range(3):
                    H[a, b] = 0.0
            _sym_e3(H, mu0, mu1, mu2, -he * stretch)
            if comp != 0.0:
                H[0, 0] -= hc * mu1 * mu1
                H[0, 1] += hc * mu1 * mu0
                H[1, 0] += hc * mu0 * mu1
                H[1, 1] -= hc * mu0 * mu0
            _add_block(ab, kl, ku, t, t, H)
    # Joints: bending and twisting energy (hh/2) e^T K e, e = (2/hh) Im(conj(p) q) - k0.
    for j in range(joint_hh.shape[0]):
        hh = joint_hh[j]
        p = Q[j]
        q = Q[j + 1]
        r0, r1, r2, r3 = _qm(p[0], -p[1], -p[2], -p[3], q[0], q[1], q[2], q[3])
        k_0 = 2.0 / hh * r1
        k_1 = 2.0 / hh * r2
        k_2 = 2.0 / hh * r3
        e0 = k_0 - joint_k0[j, 0]
        e1 = k_1 - joint_k0[j, 1]
        e2 = k_2 - joint_k0[j, 2]
        ke0 = K[0] * e0
        ke1 = K[1] * e1
        ke2 = K[2] * e2
        energy += 0.5 * hh * (e0 * ke0 + e1 * ke1 + e2 * ke2)
        # Ja = -(r0 I - [rv]x) / hh, Jb = (r0 I + [rv]x) / hh
        inv = 1.0 / hh
        Ja[0, 0] = -r0 * inv
        Ja[0, 1] = -r3 * inv
        Ja[0, 2] = r2 * inv
        Ja[1, 0] = r3 * inv
        Ja[1, 1] = -r0 * inv
        Ja[1, 2] = -r1 * inv
        Ja[2, 0] = -r2 * inv
        Ja[2, 1] = r1 * inv
        Ja[2, 2] = -r0 * inv
        Jb[0, 0] = r0 * inv
        Jb[0, 1] = -r3 * inv
        Jb[0, 2] = r2 * inv
        Jb[1, 0] = r3 * inv
        Jb[1, 1] = r0 * inv
        Jb[1, 2] = -r1 * inv
        Jb[2, 0] = -r2 * inv
        Jb[2, 1] = r1 * inv
        Jb[2, 2] = r0 * inv
        ta = ith[j]
        tb = ith[j + 1]
        for c in range(3):
            R[ta + c] += hh * (Ja[0, c] * ke0 + Ja[1, c] * ke1 + Ja[2, c] * ke2)
            R[tb + c] += hh * (Jb[0, c] * ke0 + Jb[1, c] * ke1 + Jb[2, c] * ke2)
        if want_jac:
            diag = -0.25 * hh * (ke0 * k_0 + ke1 * k_1 + ke2 * k_2)
            for a in range(3):
                for b in range(3):
                    Haa[a, b] = hh * (Ja[0, a] * K[0] * Ja[0, b] + Ja[1, a] * K[1] * Ja[1, b]
                                      + Ja[2, a] * K[2] * Ja[2, b])
                    Hbb[a, b] = hh * (Jb[0, a] * K[0] * Jb[0, b] + Jb[1, a] * K[1] * Jb[1, b]
                                      + Jb[2, a] * K[2] * Jb[2, b])
                    Hab[a, b] = hh * (Ja[0, a] * K[0] * Jb[0, b] + Ja[1, a] * K[1] * Jb[1, b]
                                      + Ja[2, a] * K[2] * Jb[2, b])
                Haa[a, a] += diag
                Hbb[a, a] += diag
            # Mixed second derivatives: d2 kappa / dtheta_a,k dtheta_b,l
            # = -Im(E_k r E_l) / (2 hh), E_k the pure quaternion of e_k; contracted with
            # K e and times hh this adds -Im(E_k r E_l) . (K e) / 2.
            for k in range(3):
                for ll in range(3):
                    ek = (0.0, 1.0 if k == 0 else 0.0, 1.0 if k == 1 else 0.0,
                          1.0 if k == 2 else 0.0)
                    m0, m1, m2, m3 = _qm(ek[0], ek[1], ek[2], ek[3], r0, r1, r2, r3)
                    w0, w1, w2, w3 = _qm(m0, m1, m2, m3, 0.0, 1.0 if ll == 0 else 0.0,
                                         1.0 if ll == 1 else 0.0, 1.0 if ll == 2 else 0.0)
                    Hab[k, ll] -= 0.5 * (ke0 * w1 + ke1 * w2 + ke2 * w3)
            _add_block(ab, kl, ku, ta, ta, Haa)
            _add_block(ab, kl, ku, tb, tb, Hbb)
            _add_block(ab, kl, ku, ta, tb, Hab)
            for a in range(3):
                for b in range(3):
                    ab[ta + b, kv + tb + a - ta - b] += Hab[b, a]
    # Stations: prescribed components, applied moments and follower loads.
    for s in range(st_node.shape[0]):
        i = st_node[s]
        f = st_frame[s]
        _rot_into(Q[f], Rm)
        t = ith[f]
        k = inu[s]  # the unknown (and equation) of the station's next multiplier
        v = nu_off[s]  # and its entry in nu
        for c in range(3):
            if st_pos_mask[s, c]:
                R[k] = X[i, c] - st_pos[s, c]
                R[ix[i] + c] += nu[v]
                if want_jac:
                    ab[ix[i] + c, kv + k - ix[i] - c] += 1.0
                    ab[k, kv + ix[i] + c - k] += 1.0
                k += 1
                v += 1
        kind = st_kind[s]
        if kind == AXIS:
            w0 = 0.0
            w1 = 0.0
            w2 = 0.0
            for b in range(2):
                b0, b1, b2 = st_axis_b[s, b, 0], st_axis_b[s, b, 1], st_axis_b[s, b, 2]
                R[k] = b0 * Rm[0, 2] + b1 * Rm[1, 2] + b2 * Rm[2, 2]
                mu0, mu1, mu2 = _tmul(Rm, b0, b1, b2)
                g0, g1 = -mu1, mu0  # e3 x mu
                nk = nu[v]
                R[t] += nk * g0
                R[t + 1] += nk * g1
                w0 += nk * b0
                w1 += nk * b1
                w2 += nk * b2
                if want_jac:
                    ab[t, kv + k - t] += g0
                    ab[t + 1, kv + k - t - 1] += g1
                    ab[k, kv + t - k] += g0
                    ab[k, kv + t + 1 - k] += g1
                k += 1
                v += 1
            if want_jac:
                mu0, mu1, mu2 = _tmul(Rm, w0, w1, w2)
                for a in range(3):
                    for b in range(3):
                        H[a, b] = 0.0
                _sym_e3(H, mu0, mu1, mu2, 1.0)
                _add_block(ab, kl, ku, t, t, H)
        elif kind == FULL:
            tq = st_quat[s]
            fq = Q[f]
            r0, r1, r2, r3 = _qm(tq[0], -tq[1], -tq[2], -tq[3], fq[0], fq[1], fq[2], fq[3])
            # ds/dtheta = (r0 I + [rv]x) / 2
            B[0, 0] = 0.5 * r0
            B[0, 1] = -0.5 * r3
            B[0, 2] = 0.5 * r2
            B[1, 0] = 0.5 * r3
            B[1, 1] = 0.5 * r0
            B[1, 2] = -0.5 * r1
            B[2, 0] = -0.5 * r2
            B[2, 1] = 0.5 * r1
            B[2, 2] = 0.5 * r0
            R[k] = r1
            R[k + 1] = r2
            R[k + 2] = r3
            for c in range(3):
                R[t + c] += B[0, c] * nu[v] + B[1, c] * nu[v + 1] + B[2, c] * nu[v + 2]
            if want_jac:
                for a in range(3):
                    for b in range(3):
                        ab[t + b, kv + k + a - t - b] += B[a, b]
                        ab[k + a, kv + t + b - k - a] += B[a, b]
                d = -0.25 * (nu[v] * r1 + nu[v + 1] * r2 + nu[v + 2] * r3)
                for c in range(3):
                    ab[t + c, kv] += d
            k += 3
        # Applied dead moment (global): generalised force R^T M on the frame.
        M0, M1, M2 = st_moment[s, 0], st_moment[s, 1], st_moment[s, 2]
        if M0 != 0.0 or M1 != 0.0 or M2 != 0.0:
            m0, m1, m2 = _tmul(Rm, M0, M1, M2)
            R[t] -= m0
            R[t + 1] -= m1
            R[t + 2] -= m2
            applied[f, 0] += m0
            applied[f, 1] += m1
            applied[f, 2] += m2
            if want_jac:  # -[R^T M]x
                ab[t + 1, kv + t - t - 1] += m2
                ab[t + 2, kv + t - t - 2] -= m1
                ab[t, kv + t + 1 - t] -= m2
                ab[t + 2, kv + t + 1 - t - 2] += m0
                ab[t, kv + t + 2 - t] += m1
                ab[t + 1, kv + t + 2 - t - 1] -= m0
        # Follower moment (material): a constant generalised force.
        for c in range(3):
            R[t + c] -= st_mfollow[s, c]
            applied[f, c] += st_mfollow[s, c]
        # Follower force (material) at the node: R F_loc, d/dtheta = -R [F]x.
        F0, F1, F2 = st_ffollow[s, 0], st_ffollow[s, 1], st_ffollow[s, 2]
        if F0 != 0.0 or F1 != 0.0 or F2 != 0.0:
            g0, g1, g2 = _mul(Rm, F0, F1, F2)
            R[ix[i]] -= g0
            R[ix[i] + 1] -= g1
            R[ix[i] + 2] -= g2
            if want_jac:  # R [F]x
                for a in range(3):
                    B[a, 0] = Rm[a, 1] * F2 - Rm[a, 2] * F1
                    B[a, 1] = Rm[a, 2] * F0 - Rm[a, 0] * F2
                    B[a, 2] = Rm[a, 0] * F1 - Rm[a, 1] * F0
                _add_block(ab, kl, ku, ix[i], t, B)
    # Twist gauge: the twist of one frame held where it was (isotropic parts that nothing
    # else holds in twist; its multiplier must end near zero, else the problem is ill-posed).
    if gauge_frame >= 0:
        k = igauge
        f = gauge_frame
        t = ith[f]
        gq = tg.gauge
        fq = Q[f]
        r0, r1, r2, r3 = _qm(gq[0], -gq[1], -gq[2], -gq[3], fq[0], fq[1], fq[2], fq[3])
        R[k] = r3
        g0, g1, g2 = -0.5 * r2, 0.5 * r1, 0.5 * r0  # row 3 of (r0 I + [rv]x) / 2
        ng = nu[nu.shape[0] - 1]
        R[t] += ng * g0
        R[t + 1] += ng * g1
        R[t + 2] += ng * g2
        if want_jac:
            ab[t, kv + k - t] += g0
            ab[t + 1, kv + k - t - 1] += g1
            ab[t + 2, kv + k - t - 2] += g2
            ab[k, kv + t - k] += g0
            ab[k, kv + t + 1 - k] += g1
            ab[k, kv + t + 2 - k] += g2
            d = -0.25 * ng * r3
            for c in range(3):
                ab[t + c, kv] += d
    # Frames are updated in moving exponential coordinates, q <- q exp(delta), so the
    # derivative of a frame's residual g (a gradient at the current frame) carries the
    # commutator of exp(delta) exp(theta) = exp(delta + theta + delta x theta / 2 + ...):
    # d g / d delta = (symmetric Hessian) + [g]x / 2. It vanishes at an equilibrium
    # (g = 0), but Newton converges quadratically only with it. Applied moments are not
    # gradients (their derivatives above are taken in the moving coordinates already).
    if want_jac:
        for f in range(Q.shape[0]):
            t = ith[f]
            g0 = R[t] + applied[f, 0]
            g1 = R[t + 1] + applied[f, 1]
            g2 = R[t + 2] + applied[f, 2]
            ab[t + 1, kv + t - t - 1] += -0.5 * g2
            ab[t + 2, kv + t - t - 2] += 0.5 * g1
            ab[t, kv + t + 1 - t] += 0.5 * g2
            ab[t + 2, kv + t + 1 - t - 2] += -0.5 * g0
            ab[t, kv + t + 2 - t] += -0.5 * g1
            ab[t + 1, kv + t + 2 - t - 1] += 0.5 * g0
    return R, ab, energy


# A state component below this (dimensionless: lengths by L, forces by EI / L^2) is
# round-off round an exact zero: a planar part's out-of-plane components shrink to it as
# Newton converges. Left alone they reach the subnormal range, where each operation costs
# a hundred times a normal one (the LU of a planar contact step took 1.4x as long).
FLUSH = 1e-150


@njit(cache=True)
def _flushed(v):
    return 0.0 if abs(v) < FLUSH else v


@njit(cache=True)
def apply_step(X, Q, lam, nu, du, num, step):
    """New (X, Q, lam, nu) after the Newton update step * du (frames on the group),
    components below ``FLUSH`` set to zero."""
    ix, ith, ilam, inu, nu_off, nu_cnt, _, igauge, _, _, _ = num
    Xn = X.copy()
    Qn = Q.copy()
    lamn = lam.copy()
    nun = nu.copy()
    for i in range(X.shape[0]):
        for c in range(3):
            Xn[i, c] = _flushed(Xn[i, c] + step * du[ix[i] + c])
    for f in range(Q.shape[0]):
        t = ith[f]
        e0, e1, e2, e3 = _qexp_t(step * du[t], step * du[t + 1], step * du[t + 2])
        q0, q1, q2, q3 = _qm(Q[f, 0], Q[f, 1], Q[f, 2], Q[f, 3], e0, e1, e2, e3)
        norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        Qn[f, 0] = _flushed(q0 / norm)
        Qn[f, 1] = _flushed(q1 / norm)
        Qn[f, 2] = _flushed(q2 / norm)
        Qn[f, 3] = _flushed(q3 / norm)
    # Keep consecutive frames in the same hemisphere (q and -q are the same rotation;
    # the discrete curvature needs the short way round).
    for f in range(1, Q.shape[0]):
        a, b = Qn[f - 1], Qn[f]
        if a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] < 0.0:
            for c in range(4):
                Qn[f, c] = -Qn[f, c]
    for e in range(lam.shape[0]):
        for c in range(3):
            lamn[e, c] = _flushed(lamn[e, c] + step * du[ilam[e] + c])
    for s in range(inu.shape[0]):
        for k in range(nu_cnt[s]):
            nun[nu_off[s] + k] = _flushed(nun[nu_off[s] + k] + step * du[inu[s] + k])
    if igauge >= 0:
        nun[nu.shape[0] - 1] = _flushed(nun[nu.shape[0] - 1] + step * du[igauge])
    return Xn, Qn, lamn, nun


@njit(cache=True)
def max_abs(v):
    m = 0.0
    for i in range(v.shape[0]):
        a = abs(v[i])
        if a > m or a != a:
            m = a
    return m


# Newton status codes (as in 2D).
CONVERGED = 0
MAX_ITERATIONS = 1
SINGULAR = 2
NOT_CONTRACTING = 3
NOT_FINITE = 4


@njit(cache=True)
def difference(X1, Q1, l1, n1, X2, Q2, l2, n2, num):
    """The unknowns' change from state 1 to state 2 (frames as rotation vectors)."""
    ix, ith, ilam, inu, nu_off, nu_cnt, _, igauge, n, _, _ = num
    du = np.zeros(n)
    for i in range(X1.shape[0]):
        for c in range(3):
            du[ix[i] + c] = X2[i, c] - X1[i, c]
    for f in range(Q1.shape[0]):
        r0, r1, r2, r3 = _qm(Q1[f, 0], -Q1[f, 1], -Q1[f, 2], -Q1[f, 3],
                             Q2[f, 0], Q2[f, 1], Q2[f, 2], Q2[f, 3])
        if r0 < 0.0:
            r0, r1, r2, r3 = -r0, -r1, -r2, -r3
        s = math.sqrt(r1 * r1 + r2 * r2 + r3 * r3)
        angle = 2.0 * math.atan2(s, r0)
        factor = angle / s if s > 1e-14 else 2.0
        du[ith[f]] = factor * r1
        du[ith[f] + 1] = factor * r2
        du[ith[f] + 2] = factor * r3
    for e in range(l1.shape[0]):
        for c in range(3):
            du[ilam[e] + c] = l2[e, c] - l1[e, c]
    for s in range(inu.shape[0]):
        for k in range(nu_cnt[s]):
            du[inu[s] + k] = n2[nu_off[s] + k] - n1[nu_off[s] + k]
    if igauge >= 0:
        du[igauge] = n2[n2.shape[0] - 1] - n1[n1.shape[0] - 1]
    return du


@njit(cache=True)
def node_outputs(Q, elem_frame, joint_hh, joint_k0, K, node_station_frame):
    """Material frames (N+1, 3, 3) and internal moments (N+1, 3, global, dimensionless)
    at the nodes. A node with a station frame takes that frame and the mean moment of
    its two half-joints; any other node the normalised mean of its two elements' frames
    and the moment of the joint between them."""
    J = joint_hh.shape[0]
    joint_m = np.empty((J, 3))
    Rm = np.empty((3, 3))
    for j in range(J):
        p = Q[j]
        q = Q[j + 1]
        _r0, r1, r2, r3 = _qm(p[0], -p[1], -p[2], -p[3], q[0], q[1], q[2], q[3])
        inv = 2.0 / joint_hh[j]
        l0 = K[0] * (inv * r1 - joint_k0[j, 0])
        l1 = K[1] * (inv * r2 - joint_k0[j, 1])
        l2 = K[2] * (inv * r3 - joint_k0[j, 2])
        half = p + q
        half /= math.sqrt(half[0] ** 2 + half[1] ** 2 + half[2] ** 2 + half[3] ** 2)
        _rot_into(half, Rm)
        m0, m1, m2 = _mul(Rm, l0, l1, l2)
        joint_m[j, 0] = m0
        joint_m[j, 1] = m1
        joint_m[j, 2] = m2
    n_nodes = node_station_frame.shape[0]
    frames = np.empty((n_nodes, 3, 3))
    moments = np.zeros((n_nodes, 3))
    for i in range(n_nodes):
        f = node_station_frame[i]
        if f >= 0:
            _rot_into(Q[f], Rm)
            count = 0
            for j in (f - 1, f):
                if 0 <= j < J:
                    for c in range(3):
                        moments[i, c] += joint_m[j, c]
                    count += 1
            for c in range(3):
                moments[i, c] /= max(count, 1)
        else:
            a = elem_frame[i - 1]
            q = Q[a] + Q[elem_frame[i]]
            q /= math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
            _rot_into(q, Rm)
            for c in range(3):
                moments[i, c] = joint_m[a, c]
        for r in range(3):
            for c in range(3):
                frames[i, r, c] = Rm[r, c]
    return frames, moments


@njit(cache=True)
def rest_shape(h, elem_frame, joint_hh, joint_k0):
    """Nodes (N+1, 3) and frames (F, 4) of the unloaded part from the origin with the
    identity frame (d3 = +z): consecutive frames differ by the relative rotation whose
    discrete curvature is exactly the rest curvature, so the shape has zero energy."""
    F = joint_hh.shape[0] + 1
    Q = np.zeros((F, 4))
    Q[0, 0] = 1.0
    for j in range(F - 1):
        v0 = 0.5 * joint_hh[j] * joint_k0[j, 0]
        v1 = 0.5 * joint_hh[j] * joint_k0[j, 1]
        v2 = 0.5 * joint_hh[j] * joint_k0[j, 2]
        w = math.sqrt(max(0.0, 1.0 - v0 * v0 - v1 * v1 - v2 * v2))
        q0, q1, q2, q3 = _qm(Q[j, 0], Q[j, 1], Q[j, 2], Q[j, 3], w, v0, v1, v2)
        Q[j + 1, 0] = q0
        Q[j + 1, 1] = q1
        Q[j + 1, 2] = q2
        Q[j + 1, 3] = q3
    N = h.shape[0]
    X = np.zeros((N + 1, 3))
    Rm = np.empty((3, 3))
    for e in range(N):
        _rot_into(Q[elem_frame[e]], Rm)
        for c in range(3):
            X[e + 1, c] = X[e, c] + h[e] * Rm[c, 2]
    return X, Q
