"""The same 2D problems through scipy's collocation solver (solve_bvp).

solve_bvp is the analogue of Matlab's bvp4c, which the paper used. It serves as an
independent cross-check of the shooting solver (tests) and as the tool a user would pick
instead (benchmarks). It solves two-point problems only, so a problem with interior
stations becomes one block of states per segment, each mapped onto tau in [0, 1], glued
by continuity of (x, y, theta) and the jump of (n, m) at every station.

Per block, h = [x, y, theta, nx, ny, m] in the dimensionless variables of ``lowering``;
with sigma_k the segment's length, dh/dtau = sigma_k * f(h, s), f written here anew from
the extensible elastica's equations (the kernels' docstring), so that it checks them.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from pliant.core.equilibrium import model_loads
from pliant.core.problem import Problem
from pliant.models.elastica2d.lowering import PRESCRIBED, Lowered, lower


@dataclass(frozen=True)
class ReferenceSolution:
    """A solve_bvp answer, in SI units like ``Equilibrium``'s arrays.

    tip : (x [m], y [m], angle [rad]) at s = L
    first : (Fx [N], Fy [N], M [N m]): n(0+) and m(0+), the internal loads at s = 0
    station_states : (nst, 6) the dimensionless state at each station (before its jump)
    """

    success: bool
    message: str
    tip: tuple[float, float, float]
    first: tuple[float, float, float]
    s: np.ndarray
    position: np.ndarray
    angle: np.ndarray
    bending_moment: np.ndarray
    nodes: int
    station_states: np.ndarray
    bvp: object = None  # scipy's result, to warm-start the next solve


def _curvature(low: Lowered, k: int, s: np.ndarray) -> np.ndarray:
    s0, s1 = low.st_s[k], low.st_s[k + 1]
    k0, k1 = low.st_kappa[k], low.st_kappa[k + 1]
    return k0 + (k1 - k0) * (s - s0) / (s1 - s0)


def solve_reference(problem: Problem, guess: object | None = None, *, tol: float = 1e-6,
                    max_nodes: int = 100000, nodes: int = 21) -> ReferenceSolution:
    """Solve with scipy.integrate.solve_bvp (analytic Jacobians).

    guess : None (the straight, unloaded part along +x from the first station's
        prescribed pose), an ``Equilibrium``, or an earlier ``ReferenceSolution`` of a
        problem with the same stations (its mesh and values are reused).
    """
    from scipy.integrate import solve_bvp  # noqa: PLC0415 (heavy; only here)

    low = lower(problem, nodes=1)  # solve_bvp needs no restart nodes
    nst = low.st_s.shape[0]
    nblk = nst - 1
    sigma = np.diff(low.st_s)
    fx, fy = low.target.prm[0], low.target.prm[1]
    comp = low.target.prm[5]  # EI / (EA L^2): the stretch lam = 1 + comp N
    val, fol, kind = low.target.val, low.target.fol, low.st_kind
    dist = low.target.dist  # per block: dead (fx, fy) and follower (ft, fn) on stretches

    def fun(tau, y):
        out = np.empty_like(y)
        for k in range(nblk):
            h = y[6 * k:6 * k + 6]
            s = low.st_s[k] + sigma[k] * tau
            c, sn = np.cos(h[2]), np.sin(h[2])
            lam = 1.0 + comp * (c * h[3] + sn * h[4])
            out[6 * k + 0] = sigma[k] * lam * c
            out[6 * k + 1] = sigma[k] * lam * sn
            out[6 * k + 2] = sigma[k] * (_curvature(low, k, s) + h[5])
            ft, fn = dist[k, 2], dist[k, 3]  # n' = -(f + ft t + fn nu)
            out[6 * k + 3] = -sigma[k] * (fx + dist[k, 0] + ft * c - fn * sn)
            out[6 * k + 4] = -sigma[k] * (fy + dist[k, 1] + ft * sn + fn * c)
            out[6 * k + 5] = -sigma[k] * lam * (c * h[4] - sn * h[3])
        return out

    def fun_jac(tau, y):
        n = 6 * nblk
        jac = np.zeros((n, n, tau.size))
        for k in range(nblk):
            h = y[6 * k:6 * k + 6]
            c, sn = np.cos(h[2]), np.sin(h[2])
            axial, shear = c * h[3] + sn * h[4], c * h[4] - sn * h[3]
            lam = 1.0 + comp * axial
            o, sg = 6 * k, sigma[k]
            jac[o + 0, o + 2] = sg * (comp * shear * c - lam * sn)
            jac[o + 0, o + 3] = sg * comp * c * c
            jac[o + 0, o + 4] = sg * comp * sn * c
            jac[o + 1, o + 2] = sg * (comp * shear * sn + lam * c)
            jac[o + 1, o + 3] = sg * comp * c * sn
            jac[o + 1, o + 4] = sg * comp * sn * sn
            jac[o + 2, o + 5] = sg
            ft, fn = dist[k, 2], dist[k, 3]
            jac[o + 3, o + 2] = sg * (ft * sn + fn * c)
            jac[o + 4, o + 2] = sg * (fn * sn - ft * c)
            jac[o + 5, o + 2] = sg * (lam * axial - comp * shear * shear)
            jac[o + 5, o + 3] = -sg * (comp * c * shear - lam * sn)
            jac[o + 5, o + 4] = -sg * (comp * sn * shear + lam * c)
        return jac

    def follower(k, theta):
        ft, fn = fol[k]
        return (ft * math.cos(theta) - fn * math.sin(theta),
                ft * math.sin(theta) + fn * math.cos(theta),
                -ft * math.sin(theta) - fn * math.cos(theta),
                ft * math.cos(theta) - fn * math.sin(theta))

    def bc(ya, yb):
        res = []
        # Station 0: n(0-) = 0 = n(0+) + P0.
        h = ya[0:6]
        px, py, _, _ = follower(0, h[2])
        for i in range(3):
            if kind[0, i] == PRESCRIBED:
                res.append(h[i] - val[0, i])
        for i in range(3):
            if kind[0, i] != PRESCRIBED:
                extra = (px, py, 0.0)[i]
                res.append(h[3 + i] + val[0, i] + extra)
        # Interior stations: continuity, then the jump or the prescribed component.
        for k in range(1, nst - 1):
            before, after = yb[6 * (k - 1):6 * k], ya[6 * k:6 * k + 6]
            for i in range(3):
                res.append(after[i] - before[i])
            px, py, _, _ = follower(k, before[2])
            for i in range(3):
                if kind[k, i] == PRESCRIBED:
                    res.append(before[i] - val[k, i])
                else:
                    extra = (px, py, 0.0)[i]
                    res.append(before[3 + i] - after[3 + i] - val[k, i] - extra)
        # Last station: n(1-) = P_last, or the prescribed component.
        h = yb[6 * (nblk - 1):6 * nblk]
        px, py, _, _ = follower(nst - 1, h[2])
        for i in range(3):
            if kind[nst - 1, i] == PRESCRIBED:
                res.append(h[i] - val[nst - 1, i])
            else:
                extra = (px, py, 0.0)[i]
                res.append(h[3 + i] - val[nst - 1, i] - extra)
        return np.array(res)

    def bc_jac(ya, yb):
        n = 6 * nblk
        ja = np.zeros((n, n))
        jb = np.zeros((n, n))
        row = 0
        _, _, dpx, dpy = follower(0, ya[2])
        for i in range(3):
            if kind[0, i] == PRESCRIBED:
                ja[row, i] = 1.0
                row += 1
        for i in range(3):
            if kind[0, i] != PRESCRIBED:
                ja[row, 3 + i] = 1.0
                if i < 2:
                    ja[row, 2] += (dpx, dpy)[i]
                row += 1
        for k in range(1, nst - 1):
            ob, oa = 6 * (k - 1), 6 * k
            for i in range(3):
                ja[row, oa + i] = 1.0
                jb[row, ob + i] = -1.0
                row += 1
            _, _, dpx, dpy = follower(k, yb[ob + 2])
            for i in range(3):
                if kind[k, i] == PRESCRIBED:
                    jb[row, ob + i] = 1.0
                else:
                    jb[row, ob + 3 + i] = 1.0
                    ja[row, oa + 3 + i] = -1.0
                    if i < 2:
                        jb[row, ob + 2] -= (dpx, dpy)[i]
                row += 1
        o = 6 * (nblk - 1)
        _, _, dpx, dpy = follower(nst - 1, yb[o + 2])
        for i in range(3):
            if kind[nst - 1, i] == PRESCRIBED:
                jb[row, o + i] = 1.0
            else:
                jb[row, o + 3 + i] = 1.0
                if i < 2:
                    jb[row, o + 2] -= (dpx, dpy)[i]
            row += 1
        return ja, jb

    tau = np.linspace(0.0, 1.0, nodes)
    y0 = np.zeros((6 * nblk, tau.size))
    if isinstance(guess, ReferenceSolution) and guess.bvp is not None:
        tau, y0 = guess.bvp.x, guess.bvp.y  # type: ignore[attr-defined]
    elif guess is None:
        x0 = val[0, 0] if kind[0, 0] == PRESCRIBED else 0.0
        yy0 = val[0, 1] if kind[0, 1] == PRESCRIBED else 0.0
        th0 = val[0, 2] if kind[0, 2] == PRESCRIBED else 0.0
        for k in range(nblk):
            s = low.st_s[k] + sigma[k] * tau
            y0[6 * k + 0] = x0 + s * math.cos(th0)
            y0[6 * k + 1] = yy0 + s * math.sin(th0)
            y0[6 * k + 2] = th0
    else:
        eq = guess
        s_eq = eq.s / low.length  # type: ignore[attr-defined]
        arrays = np.column_stack([eq.position[:, 0] / low.length,  # type: ignore[attr-defined]
                                  eq.position[:, 1] / low.length,  # type: ignore[attr-defined]
                                  eq.angle,  # type: ignore[attr-defined]
                                  eq.internal_force / low.force_scale,  # type: ignore[attr-defined]
                                  eq.bending_moment / low.moment_scale])  # type: ignore[attr-defined]
        # A station appears twice in the arrays (before and after its jump): sampling
        # just inside each block reads the right side of every jump.
        inside = np.clip(tau, 1e-9, 1.0 - 1e-9)
        for k in range(nblk):
            s = low.st_s[k] + sigma[k] * inside
            for q in range(6):
                y0[6 * k + q] = np.interp(s, s_eq, arrays[:, q])
    sol = solve_bvp(fun, bc, tau, y0, fun_jac=fun_jac, bc_jac=bc_jac, tol=tol,
                    max_nodes=max_nodes)
    yt = sol.sol(np.linspace(0.0, 1.0, 201))
    s_all, pos, ang, mom = [], [], [], []
    for k in range(nblk):
        s_all.append(low.st_s[k] + sigma[k] * np.linspace(0.0, 1.0, 201))
        pos.append(yt[6 * k:6 * k + 2].T)
        ang.append(yt[6 * k + 2])
        mom.append(yt[6 * k + 5])
    end = sol.sol(1.0)[6 * (nblk - 1):6 * nblk]
    start = sol.sol(0.0)[0:6]
    states = np.array([sol.sol(0.0)[0:6]] + [sol.sol(1.0)[6 * k:6 * k + 6]
                                             for k in range(nblk)])
    return ReferenceSolution(
        success=bool(sol.success), message=str(sol.message),
        tip=(end[0] * low.length, end[1] * low.length, float(end[2])),
        first=(start[3] * low.force_scale, start[4] * low.force_scale,
               start[5] * low.moment_scale),
        s=np.concatenate(s_all) * low.length, position=np.vstack(pos) * low.length,
        angle=np.concatenate(ang), bending_moment=np.concatenate(mom) * low.moment_scale,
        nodes=int(sol.x.size), station_states=states, bvp=sol)


def equilibrium_error(eq) -> float:
    """The largest error of a 2D equilibrium, checked without the shooting solver (the
    fuzz benchmark's and the tests' independent check), relative: lengths by L, forces
    by EI / L^2, moments by EI / L.

    The ODE x' = lam cos theta, y' = lam sin theta, theta' = kappa0 + M / EI, n' = -q
    (q the dead loads per length, and the follower ones turned to the tangent),
    M' = -lam (t x n), lam = 1 + N / EA (1 for an inextensible part) is integrated again
    by solve_ivp (DOP853, rtol 1e-11) from each returned sample to the next (one long
    shot from s = 0 would lose its digits on a floppy, heavy part), the loads of the
    conditions at a station (reactions included) are the jump n(s+) = n(s-) - F,
    M(s+) = M(s-) - M_load there, with nothing before s = 0 or beyond s = L, and every
    prescribed value must hold.
    """
    from scipy.integrate import solve_ivp  # noqa: PLC0415

    problem = eq.problem
    part = problem.part
    L, EI = part.length, part.bending_stiffness
    q = np.array(problem.dead_load_per_length, float)
    scale = np.array([L, L, 1.0, EI / L**2, EI / L**2, EI / L])

    compliance = 0.0 if part.axial_stiffness is None else 1.0 / part.axial_stiffness

    partial = problem.partial_loads

    def rhs(s, h):
        t = (math.cos(h[2]), math.sin(h[2]))
        stretch = 1.0 + compliance * (t[0] * h[3] + t[1] * h[4])  # 1 + N / EA
        fx, fy = q
        for ld in partial:
            a, b = ld.span(L)
            if a <= s <= b:
                f0, f1 = ld.force
                if ld.follower:  # f0 along t, f1 along nu = (-sin, cos)
                    f0, f1 = f0 * t[0] - f1 * t[1], f0 * t[1] + f1 * t[0]
                fx, fy = fx + f0, fy + f1
        return [stretch * t[0], stretch * t[1], part.rest_curvature_at(s) + h[5] / EI,
                -fx, -fy, -stretch * (t[0] * h[4] - t[1] * h[3])]

    s = eq.s
    H = np.column_stack([eq.position, eq.angle, eq.internal_force, eq.bending_moment])
    knots = sorted({k for k, _ in part.rest_knots if 0.0 < k < L}
                   | {x for ld in partial for x in ld.span(L) if 0.0 < x < L})
    errors = [0.0]
    for i in range(len(s) - 1):
        if s[i + 1] - s[i] <= 1e-14 * L:  # a station's two samples: its jump
            continue
        a, b = s[i], s[i + 1]
        cuts = [a, *[k for k in knots if a < k < b], b]
        state = H[i].copy()
        for lo, hi in itertools.pairwise(cuts):
            state = solve_ivp(rhs, (lo, hi), state, rtol=1e-11, atol=1e-13,
                              method="DOP853").y[:, -1]
        d = state - H[i + 1]
        d[2] = (d[2] + math.pi) % (2 * math.pi) - math.pi
        errors.append(float(np.max(np.abs(d) / scale)))
    at: dict[float, np.ndarray] = {}  # the loads of the conditions sharing a station
    for ld in model_loads(eq).values():
        key = next((x for x in at if abs(x - ld.s) <= 1e-12 * L), ld.s)
        at[key] = at.get(key, np.zeros(3)) + np.array([*ld.force, float(ld.moment)])
    for station, load in at.items():
        near = np.flatnonzero(np.abs(s - station) <= 1e-12 * L)
        before = np.zeros(3) if station <= 1e-12 * L else H[near[0], 3:]
        after = np.zeros(3) if station >= L * (1 - 1e-12) else H[near[-1], 3:]
        jump = before - load - after
        errors.append(float(np.max(np.abs(jump) / scale[3:])))
    for c in problem.model_conditions:
        k = int(np.argmin(np.abs(s - c.s)))
        for i in range(2):
            if c.position[i] is not None:
                errors.append(abs(eq.position[k, i] - c.position[i]) / L)
        if c.angle is not None:
            errors.append(abs((eq.angle[k] - c.angle + math.pi) % (2 * math.pi) - math.pi))
    return float(max(errors))
