"""The primitive obstacles' signed distances in their own frames, exact and closed
form (sphere, box, capped cylinder, half-space), with their gradients and Hessians: what
``distance``'s packed queries call for an obstacle that is not a mesh."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

SPHERE, BOX, CYLINDER, HALFSPACE, MESH = 0, 1, 2, 3, 4


@njit(cache=True)
def box(x, y, z, hx, hy, hz):
    qx, qy, qz = abs(x) - hx, abs(y) - hy, abs(z) - hz
    ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
    out_len = math.sqrt(ox * ox + oy * oy + oz * oz)
    sx = 1.0 if x >= 0.0 else -1.0
    sy = 1.0 if y >= 0.0 else -1.0
    sz = 1.0 if z >= 0.0 else -1.0
    if out_len > 0.0:
        return out_len, sx * ox / out_len, sy * oy / out_len, sz * oz / out_len
    if qx >= qy and qx >= qz:
        return qx, sx, 0.0, 0.0
    if qy >= qz:
        return qy, 0.0, sy, 0.0
    return qz, 0.0, 0.0, sz


@njit(cache=True)
def cylinder(x, y, z, radius, half):
    """Capped cylinder along local z."""
    rho = math.sqrt(x * x + y * y)
    qx = rho - radius
    qz = abs(z) - half
    rx, ry = (x / rho, y / rho) if rho > 1e-300 else (1.0, 0.0)
    sz = 1.0 if z >= 0.0 else -1.0
    if qx > 0.0 and qz > 0.0:  # beyond the rim
        d = math.sqrt(qx * qx + qz * qz)
        return d, qx * rx / d, qx * ry / d, qz * sz / d
    if qx >= qz:  # the side is nearer (or the only face outside)
        return qx, rx, ry, 0.0
    return qz, 0.0, 0.0, sz


@njit(cache=True)
def primitive(kind, x, y, z, param):
    """(distance, gradient x, y, z) of a primitive in its frame."""
    if kind == SPHERE:
        r = math.sqrt(x * x + y * y + z * z)
        if r > 1e-300:
            return r - param[0], x / r, y / r, z / r
        return -param[0], 0.0, 0.0, 1.0
    if kind == BOX:
        return box(x, y, z, param[0], param[1], param[2])
    if kind == CYLINDER:
        return cylinder(x, y, z, param[0], param[1])
    return z, 0.0, 0.0, 1.0  # HALFSPACE: solid below the local plane z = 0


@njit(cache=True)
def to_local(p, R, t):
    """p (world) in the frame of an obstacle placed by R (local to world) and t."""
    ux, uy, uz = p[0] - t[0], p[1] - t[1], p[2] - t[2]
    return (R[0, 0] * ux + R[1, 0] * uy + R[2, 0] * uz,
            R[0, 1] * ux + R[1, 1] * uy + R[2, 1] * uz,
            R[0, 2] * ux + R[1, 2] * uy + R[2, 2] * uz)


@njit(cache=True)
def primitive_hessian(kind, x, y, z, param):
    """The Hessian of a primitive's signed distance in its frame, exact piece by piece
    (the pieces meet where the gradient is continuous and its derivative jumps: a
    semismooth Newton needs the piece's own, not a difference straddling the seam)."""
    H = np.zeros((3, 3))
    if kind == SPHERE:
        r = math.sqrt(x * x + y * y + z * z)
        if r > 1e-12:
            u = np.empty(3)  # (written out: array expressions compile slowly)
            u[0], u[1], u[2] = x / r, y / r, z / r
            for i in range(3):
                for j in range(3):
                    H[i, j] = ((1.0 if i == j else 0.0) - u[i] * u[j]) / r
        return H
    if kind == BOX:
        q = np.empty(3)
        q[0], q[1], q[2] = abs(x) - param[0], abs(y) - param[1], abs(z) - param[2]
        if max(q[0], q[1], q[2]) <= 0.0:
            return H  # inside: a face's distance
        d, gx, gy, gz = box(x, y, z, param[0], param[1], param[2])
        g = np.empty(3)
        g[0], g[1], g[2] = gx, gy, gz
        for i in range(3):
            for j in range(3):
                H[i, j] = ((1.0 if (i == j and q[i] > 0.0) else 0.0) - g[i] * g[j]) / d
        return H
    if kind == CYLINDER:
        rho = math.sqrt(x * x + y * y)
        if rho < 1e-12:
            return H
        radius, half = param[0], param[1]
        qx, qz = rho - radius, abs(z) - half
        t = np.empty(3)
        t[0], t[1], t[2] = -y / rho, x / rho, 0.0
        if qx > 0.0 and qz > 0.0:  # the rim: a circle
            d, gx, gy, gz = cylinder(x, y, z, radius, half)
            g = np.empty(3)
            g[0], g[1], g[2] = gx, gy, gz
            for i in range(3):
                for j in range(3):
                    H[i, j] = ((1.0 if i == j else 0.0) - g[i] * g[j]
                               - radius / rho * t[i] * t[j]) / d
            return H
        if qx >= qz:  # the side: curved round the axis only
            for i in range(3):
                for j in range(3):
                    H[i, j] = t[i] * t[j] / rho
        return H
    return H  # HALFSPACE, caps
