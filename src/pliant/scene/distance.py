"""Signed distances from points to the obstacles of a scene, with their gradients.

Primitives (sphere, box, capped cylinder, half-space) have exact closed-form distances.
A triangle mesh has two levels:

- a signed distance grid (trilinear interpolation and its gradient), computed once per
  mesh (exact in a band round the surface, a Euclidean distance transform beyond it)
  and cached on disk under the hash of its vertices and faces: cheap, and within 2.6
  cells of the truth;
- an exact query (the closest triangle found through a uniform hash of the triangles;
  the sign from the angle-weighted pseudonormal of the closest feature, Baerentzen and
  Aanaes, IEEE TVCG 11(3), 2005), used wherever the grid says the surface may be closer
  than the caller's band (where contact is decided).

A mesh that is not closed has no inside: its distance is unsigned (a shell the part must
keep clear of). Every obstacle is packed into flat arrays (``Packed``) so that the
accurate and real-time kernels can query the whole scene inside numba.
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from pliant.io import cache as disk
from pliant.io import progress

SPHERE, BOX, CYLINDER, HALFSPACE, MESH = 0, 1, 2, 3, 4


class Field(NamedTuple):
    """A scene's obstacles packed for the kernels (``DistanceField.args``): per obstacle
    its kind, rotation (3, 3) and translation (3,) into its local frame, parameters (4,)
    and mesh (-1: a primitive); the meshes' triangles (T, 3, 3), pseudo-normals
    (T, 7, 3), solidity and first triangle (tri_off); their bounding-volume trees
    (triangle order, node boxes, children, triangle ranges, first node); their distance
    grids (values, first value, origin, cell size, dimensions)."""

    kind: np.ndarray
    rot: np.ndarray
    trans: np.ndarray
    param: np.ndarray
    mesh_id: np.ndarray
    tri: np.ndarray
    pseudo: np.ndarray
    solid: np.ndarray
    tri_off: np.ndarray
    order: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    left: np.ndarray
    right: np.ndarray
    start: np.ndarray
    count: np.ndarray  # type: ignore[assignment]  # a field, over tuple.count
    node_off: np.ndarray
    g_values: np.ndarray
    g_off: np.ndarray
    g_origin: np.ndarray
    g_size: np.ndarray
    g_dims: np.ndarray
GRID_VERSION = 2
# How far a grid value may be from the truth, in cells: sqrt(3) beyond the exact band
# (the nearest-band-node bound), plus sqrt(3)/2 of trilinear interpolation.
GRID_ERROR = 2.6


# -- triangles -----------------------------------------------------------------------------
@njit(cache=True)
def closest_on_triangle(p, a, b, c):
    """The point of triangle abc closest to p, as (x, y, z, feature): feature 0 the face,
    1, 2, 3 the edges ab, bc, ca, 4, 5, 6 the vertices a, b, c (Ericson, Real-Time
    Collision Detection, 5.1.5). Scalars only: it runs in the innermost loop."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    acx, acy, acz = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    apx, apy, apz = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return a[0], a[1], a[2], 4
    bpx, bpy, bpz = p[0] - b[0], p[1] - b[1], p[2] - b[2]
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return b[0], b[1], b[2], 5
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return a[0] + v * abx, a[1] + v * aby, a[2] + v * abz, 1
    cpx, cpy, cpz = p[0] - c[0], p[1] - c[1], p[2] - c[2]
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return c[0], c[1], c[2], 6
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return a[0] + w * acx, a[1] + w * acy, a[2] + w * acz, 3
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return (b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2]),
                2)
    denom = 1.0 / (va + vb + vc)
    v = vb * denom
    w = vc * denom
    return (a[0] + abx * v + acx * w, a[1] + aby * v + acy * w, a[2] + abz * v + acz * w, 0)


@njit(cache=True)
def _select(order, key, lo, hi, target):
    """Reorder order[lo:hi + 1] so that the entry at ``target`` is the one a sort by key
    would put there, with no larger key before it and no smaller after (Hoare's
    selection: linear time, where a sort at every node of a tree costs a log more)."""
    while hi > lo:
        mid = (lo + hi) // 2
        a, b, c = key[order[lo]], key[order[mid]], key[order[hi]]
        pivot = max(min(a, b), min(max(a, b), c))  # the median of the three
        i, j = lo, hi
        while i <= j:
            while key[order[i]] < pivot:
                i += 1
            while key[order[j]] > pivot:
                j -= 1
            if i <= j:
                order[i], order[j] = order[j], order[i]
                i += 1
                j -= 1
        if target <= j:
            hi = j
        elif target >= i:
            lo = i
        else:
            return


@njit(cache=True)
def build_bvh(tri, leaf_size=4):
    """An axis-aligned bounding box tree over the triangles (median splits on the
    longest axis of the centroids, by selection). Returns (order, lo, hi, left, right, start,
    count):
    triangles order[start:start + count] in each leaf; left = -1 marks a leaf."""
    T = tri.shape[0]
    centroid = np.empty((T, 3))
    tlo = np.empty((T, 3))
    thi = np.empty((T, 3))
    for t in range(T):
        for a in range(3):
            x0, x1, x2 = tri[t, 0, a], tri[t, 1, a], tri[t, 2, a]
            centroid[t, a] = (x0 + x1 + x2) / 3.0
            tlo[t, a] = min(x0, min(x1, x2))
            thi[t, a] = max(x0, max(x1, x2))
    order = np.arange(T)
    cap = 2 * T + 1
    lo = np.empty((cap, 3))
    hi = np.empty((cap, 3))
    left = np.full(cap, -1, dtype=np.int64)
    right = np.full(cap, -1, dtype=np.int64)
    start = np.zeros(cap, dtype=np.int64)
    count = np.zeros(cap, dtype=np.int64)
    stack = np.empty((cap, 2), dtype=np.int64)  # (node, unused)
    nodes = 1
    start[0] = 0
    count[0] = T
    top = 1
    stack[0, 0] = 0
    while top > 0:
        top -= 1
        node = stack[top, 0]
        s0, n0 = start[node], count[node]
        for a in range(3):
            lo[node, a] = np.inf
            hi[node, a] = -np.inf
        for e in range(s0, s0 + n0):
            t = order[e]
            for a in range(3):
                lo[node, a] = min(lo[node, a], tlo[t, a])
                hi[node, a] = max(hi[node, a], thi[t, a])
        if n0 <= leaf_size:
            continue
        cmin = np.full(3, np.inf)
        cmax = np.full(3, -np.inf)
        for e in range(s0, s0 + n0):
            for a in range(3):
                c = centroid[order[e], a]
                cmin[a] = min(cmin[a], c)
                cmax[a] = max(cmax[a], c)
        axis = int(np.argmax(cmax - cmin))
        half = n0 // 2
        _select(order, centroid[:, axis], s0, s0 + n0 - 1, s0 + half)
        a_, b_ = nodes, nodes + 1
        nodes += 2
        left[node], right[node] = a_, b_
        start[a_], count[a_] = s0, half
        start[b_], count[b_] = s0 + half, n0 - half
        stack[top, 0] = a_
        stack[top + 1, 0] = b_
        top += 2
    return (order, lo[:nodes].copy(), hi[:nodes].copy(), left[:nodes].copy(),
            right[:nodes].copy(), start[:nodes].copy(), count[:nodes].copy())


@njit(cache=True, inline="always")
def _box_distance2(p, lo, hi):
    d2 = 0.0
    for a in range(3):
        if p[a] < lo[a]:
            d2 += (lo[a] - p[a]) ** 2
        elif p[a] > hi[a]:
            d2 += (p[a] - hi[a]) ** 2
    return d2


@njit(cache=True)
def _mesh_exact(p, tri, pseudo, solid, order, lo, hi, left, right, start, count):
    """(signed distance, unit gradient) from p to a mesh, exact: a branch-and-bound walk
    of its box tree. pseudo (T, 7, 3): the pseudonormals of each triangle's face, edges
    and vertices (the sign)."""
    dist, grad, _, _ = _mesh_feature(p, tri, pseudo, solid, order, lo, hi, left, right,
                                     start, count)
    return dist, grad


@njit(cache=True)
def _mesh_feature(p, tri, pseudo, solid, order, lo, hi, left, right, start, count):
    """(signed distance, unit gradient, triangle, feature) of the mesh point nearest p:
    the feature as ``closest_on_triangle`` numbers it."""
    best = np.inf
    best_t = -1
    best_r = 0
    bq0 = bq1 = bq2 = 0.0
    stack = np.empty(64, dtype=np.int64)
    stack[0] = 0
    top = 1
    while top > 0:
        top -= 1
        node = stack[top]
        if _box_distance2(p, lo[node], hi[node]) >= best:
            continue
        if left[node] < 0:
            for e in range(start[node], start[node] + count[node]):
                t = order[e]
                qx, qy, qz, region = closest_on_triangle(p, tri[t, 0], tri[t, 1], tri[t, 2])
                d2 = (p[0] - qx) ** 2 + (p[1] - qy) ** 2 + (p[2] - qz) ** 2
                if d2 < best:
                    best = d2
                    best_t = t
                    best_r = region
                    bq0, bq1, bq2 = qx, qy, qz
            continue
        a_, b_ = left[node], right[node]
        dl = _box_distance2(p, lo[a_], hi[a_])
        dr = _box_distance2(p, lo[b_], hi[b_])
        if top + 2 > stack.shape[0]:
            grown = np.empty(2 * stack.shape[0], dtype=np.int64)
            grown[:top] = stack[:top]
            stack = grown
        if dl < dr:  # the nearer child is walked first
            stack[top] = b_
            stack[top + 1] = a_
        else:
            stack[top] = a_
            stack[top + 1] = b_
        top += 2
    dist = math.sqrt(best)
    gx, gy, gz = p[0] - bq0, p[1] - bq1, p[2] - bq2
    if dist > 1e-300:
        grad = np.array([gx / dist, gy / dist, gz / dist])
    else:
        grad = pseudo[best_t, 0].copy()
    if solid:
        n = pseudo[best_t, best_r]
        if gx * n[0] + gy * n[1] + gz * n[2] < 0.0:
            return -dist, -grad, best_t, best_r
    return dist, grad, best_t, best_r


# -- primitives (local frame; scalars in and out: they run per point) ---------------------
@njit(cache=True)
def _box(x, y, z, hx, hy, hz):
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
def _cylinder(x, y, z, radius, half):
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
def _primitive(kind, x, y, z, param):
    """(distance, gradient x, y, z) of a primitive in its frame."""
    if kind == SPHERE:
        r = math.sqrt(x * x + y * y + z * z)
        if r > 1e-300:
            return r - param[0], x / r, y / r, z / r
        return -param[0], 0.0, 0.0, 1.0
    if kind == BOX:
        return _box(x, y, z, param[0], param[1], param[2])
    if kind == CYLINDER:
        return _cylinder(x, y, z, param[0], param[1])
    return z, 0.0, 0.0, 1.0  # HALFSPACE: solid below the local plane z = 0


@njit(cache=True, inline="always")
def _local(p, R, t):
    """p (world) in the frame of an obstacle placed by R (local to world) and t."""
    ux, uy, uz = p[0] - t[0], p[1] - t[1], p[2] - t[2]
    return (R[0, 0] * ux + R[1, 0] * uy + R[2, 0] * uz,
            R[0, 1] * ux + R[1, 1] * uy + R[2, 1] * uz,
            R[0, 2] * ux + R[1, 2] * uy + R[2, 2] * uz)


@njit(cache=True)
def _feature_hessian(dist, n, tangent, kind):
    """The signed distance's Hessian beyond a feature of the closest point: H = (I - n n^T
    - dc/dp) / d with dc/dp the closest point's motion (I - n n^T on a face: H = 0; the
    edge direction e e^T on an edge; 0 at a vertex). kind 0 face, 1 edge, 2 vertex."""
    H = np.zeros((3, 3))
    if kind == 0 or abs(dist) < 1e-12:
        return H
    for i in range(3):
        for j in range(3):
            H[i, j] = (1.0 if i == j else 0.0) - n[i] * n[j]
            if kind == 1:
                H[i, j] -= tangent[i] * tangent[j]
    return H / dist


@njit(cache=True)
def _primitive_hessian(kind, x, y, z, param):
    """The Hessian of a primitive's signed distance in its frame, exact piece by piece
    (the pieces meet where the gradient is continuous and its derivative jumps: a
    semismooth Newton needs the piece's own, not a difference straddling the seam)."""
    H = np.zeros((3, 3))
    if kind == SPHERE:
        r = math.sqrt(x * x + y * y + z * z)
        if r > 1e-12:
            u = np.array([x, y, z]) / r
            for i in range(3):
                for j in range(3):
                    H[i, j] = ((1.0 if i == j else 0.0) - u[i] * u[j]) / r
        return H
    if kind == BOX:
        q = np.array([abs(x) - param[0], abs(y) - param[1], abs(z) - param[2]])
        if q.max() <= 0.0:
            return H  # inside: a face's distance
        d, gx, gy, gz = _box(x, y, z, param[0], param[1], param[2])
        g = np.array([gx, gy, gz])
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
        t = np.array([-y / rho, x / rho, 0.0])
        if qx > 0.0 and qz > 0.0:  # the rim: a circle
            d, gx, gy, gz = _cylinder(x, y, z, radius, half)
            g = np.array([gx, gy, gz])
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


@njit(cache=True)
def hessian_point(p, o, field):
    """The Hessian (3, 3, world frame) of obstacle o's signed distance at p: the rate
    at which its unit gradient (the contact normal) turns as p moves. Takes the same
    packed ``Field`` as ``query_point`` (the grids unused: contact is decided exactly)."""
    kind, rot, trans, param, mesh_id, tri = (field.kind, field.rot, field.trans,
                                             field.param, field.mesh_id, field.tri)
    R = rot[o]
    x, y, z = _local(p, R, trans[o])
    if kind[o] == MESH:
        d, g, t, region = _packed_mesh_feature(x, y, z, mesh_id[o], field)
        e = np.zeros(3)
        feature = 0
        if 1 <= region <= 3:
            a = tri[t, region - 1]
            b = tri[t, region % 3]
            e = (b - a) / max(np.sqrt(((b - a) ** 2).sum()), 1e-300)
            feature = 1
        elif region >= 4:
            feature = 2
        Hl = _feature_hessian(d, g, e, feature)
    else:
        Hl = _primitive_hessian(kind[o], x, y, z, param[o])
    return R @ Hl @ R.T


# -- grids ---------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _onto_grid(f, top):
    """A grid coordinate clamped to [0, top], and how far (in cells) it lay beyond."""
    if f < 0.0:
        return 0.0, -f
    if f > top:
        return float(top), f - top
    return f, 0.0


@njit(cache=True)
def grid_sample(x, y, z, origin, size, dims, values, base):
    """Trilinear interpolation of a grid of node values (stored from ``base``) at the
    local point (x, y, z): (value, gradient x, y, z, how far the point lies outside the
    grid); outside, the values are those at the nearest grid point."""
    tx, ty, tz = dims[0] - 1, dims[1] - 1, dims[2] - 1
    fx, ox = _onto_grid((x - origin[0]) / size, tx)
    fy, oy = _onto_grid((y - origin[1]) / size, ty)
    fz, oz = _onto_grid((z - origin[2]) / size, tz)
    outside2 = (ox * ox + oy * oy + oz * oz) * size * size
    i0 = min(int(fx), tx - 1)
    j0 = min(int(fy), ty - 1)
    k0 = min(int(fz), tz - 1)
    fx -= i0
    fy -= j0
    fz -= k0
    sy = dims[2]
    sx = dims[1] * sy
    b = base + i0 * sx + j0 * sy + k0
    v0 = values[b]
    v1 = values[b + 1]
    v2 = values[b + sy]
    v3 = values[b + sy + 1]
    v4 = values[b + sx]
    v5 = values[b + sx + 1]
    v6 = values[b + sx + sy]
    v7 = values[b + sx + sy + 1]
    c00 = v0 * (1 - fx) + v4 * fx
    c01 = v1 * (1 - fx) + v5 * fx
    c10 = v2 * (1 - fx) + v6 * fx
    c11 = v3 * (1 - fx) + v7 * fx
    c0 = c00 * (1 - fy) + c10 * fy
    c1 = c01 * (1 - fy) + c11 * fy
    d = c0 * (1 - fz) + c1 * fz
    gx = ((v4 - v0) * (1 - fy) * (1 - fz) + (v5 - v1) * (1 - fy) * fz
          + (v6 - v2) * fy * (1 - fz) + (v7 - v3) * fy * fz) / size
    gy = ((v2 - v0) * (1 - fx) * (1 - fz) + (v3 - v1) * (1 - fx) * fz
          + (v6 - v4) * fx * (1 - fz) + (v7 - v5) * fx * fz) / size
    gz = (c1 - c0) / size
    return d, gx, gy, gz, math.sqrt(outside2)


# -- the whole scene -----------------------------------------------------------------------
@njit(cache=True)
def _packed_mesh_feature(x, y, z, m, f):
    """``_mesh_feature`` of packed mesh m of the ``Field`` f at the local point (x, y, z):
    (signed distance, unit gradient, the nearest triangle's index in ``f.tri``, its
    feature)."""
    t0, t1 = f.tri_off[m], f.tri_off[m + 1]
    n0, n1 = f.node_off[m], f.node_off[m + 1]
    d, g, t, region = _mesh_feature(np.array([x, y, z]), f.tri[t0:t1], f.pseudo[t0:t1],
                                    f.solid[m], f.order[t0:t1], f.node_lo[n0:n1],
                                    f.node_hi[n0:n1], f.left[n0:n1], f.right[n0:n1],
                                    f.start[n0:n1], f.count[n0:n1])
    return d, g, t0 + t, region


@njit(cache=True)
def query_point(p, band, field):
    """(signed distance, unit gradient x, y, z, obstacle) of the nearest obstacle to p
    (world frame): ``query_points`` for one point."""
    d, g, o = query_points(p.reshape(1, 3), band, field)
    return d[0], g[0, 0], g[0, 1], g[0, 2], o[0]


@njit(cache=True)
def query_points(points, band, field):
    """(signed distances (n,), unit gradients (n, 3), nearest obstacles (n,)) of points
    (n, 3), world frame. A mesh answers from its grid where the grid shows its surface
    farther than ``band`` beyond the grid's own error, else exactly. Obstacle by
    obstacle over all points: a call per point carrying the scene's many arrays would
    cost more than a primitive's distance. field: the scene's packed ``Field``."""
    kind, rot, trans, param, mesh_id = (field.kind, field.rot, field.trans, field.param,
                                        field.mesh_id)
    node_lo, node_hi, node_off = field.node_lo, field.node_hi, field.node_off
    g_values, g_off, g_origin, g_size, g_dims = (field.g_values, field.g_off, field.g_origin,
                                                 field.g_size, field.g_dims)
    n = points.shape[0]
    d = np.full(n, np.inf)
    g = np.zeros((n, 3))
    o = np.full(n, -1, dtype=np.int64)
    for ob in range(kind.shape[0]):
        R = rot[ob]
        t = trans[ob]
        prm = param[ob]
        k = kind[ob]
        for i in range(n):
            x, y, z = _local(points[i], R, t)
            if k == MESH:
                m = mesh_id[ob]
                di, gx, gy, gz, outside = grid_sample(x, y, z, g_origin[m], g_size[m],
                                                      g_dims[m], g_values, g_off[m])
                # No surface lies nearer than this: the grid's bound, or outside the grid
                # the distance to the mesh's box (its tree's root).
                lower = di
                if outside > 0.0:
                    n0 = node_off[m]
                    cx = max(node_lo[n0, 0] - x, 0.0, x - node_hi[n0, 0])
                    cy = max(node_lo[n0, 1] - y, 0.0, y - node_hi[n0, 1])
                    cz = max(node_lo[n0, 2] - z, 0.0, z - node_hi[n0, 2])
                    lower = max(di - outside, math.sqrt(cx * cx + cy * cy + cz * cz))
                    di += outside
                if lower <= band + GRID_ERROR * g_size[m] and lower < d[i]:
                    di, gm, _, _ = _packed_mesh_feature(x, y, z, m, field)
                    gx, gy, gz = gm[0], gm[1], gm[2]
            else:
                di, gx, gy, gz = _primitive(k, x, y, z, prm)
            if di < d[i]:
                d[i] = di
                g[i, 0] = R[0, 0] * gx + R[0, 1] * gy + R[0, 2] * gz
                g[i, 1] = R[1, 0] * gx + R[1, 1] * gy + R[1, 2] * gz
                g[i, 2] = R[2, 0] * gx + R[2, 1] * gy + R[2, 2] * gz
                o[i] = ob
    return d, g, o


@njit(cache=True)
def _band_values(origin, size, dims, reach, tri, pseudo, solid, bvh):
    """Exact signed distances at the grid nodes within ``reach`` of a triangle's bounding
    box (the band round the surface); NaN elsewhere."""
    order, lo_, hi_, left, right, start, count = bvh
    nx, ny, nz = dims[0], dims[1], dims[2]
    values = np.full(nx * ny * nz, np.nan)
    p = np.empty(3)
    lo = np.empty(3, dtype=np.int64)
    hi = np.empty(3, dtype=np.int64)
    for t in range(tri.shape[0]):
        for a in range(3):
            mn = min(tri[t, 0, a], min(tri[t, 1, a], tri[t, 2, a])) - reach
            mx = max(tri[t, 0, a], max(tri[t, 1, a], tri[t, 2, a])) + reach
            lo[a] = max(int(math.ceil((mn - origin[a]) / size)), 0)
            hi[a] = min(int(math.floor((mx - origin[a]) / size)), dims[a] - 1)
        for i in range(lo[0], hi[0] + 1):
            for j in range(lo[1], hi[1] + 1):
                for k in range(lo[2], hi[2] + 1):
                    node = (i * ny + j) * nz + k
                    if not math.isnan(values[node]):
                        continue
                    p[0] = origin[0] + i * size
                    p[1] = origin[1] + j * size
                    p[2] = origin[2] + k * size
                    values[node] = _mesh_exact(p, tri, pseudo, solid, order, lo_, hi_, left,
                                               right, start, count)[0]
    return values


def _fill_grid(origin, size, dims, tri, pseudo, solid, bvh):
    """The signed distance grid: exact in a band round the surface, and beyond it the
    distance to the nearest band node plus that node's distance (an upper bound within
    sqrt(3) cells of the truth), with that node's sign."""
    from scipy.ndimage import distance_transform_edt  # noqa: PLC0415 (set-up only)

    values = _band_values(origin, size, dims, 1.5 * size, tri, pseudo, solid, bvh)
    grid = values.reshape(tuple(dims))
    band = ~np.isnan(grid)
    gap, nearest = distance_transform_edt(~band, sampling=size, return_indices=True)
    near = grid[tuple(nearest)]
    filled = np.where(band, grid, np.sign(near) * (gap + np.abs(near)))
    return np.ascontiguousarray(filled.ravel())


# -- Python side ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MeshData:
    """A triangle mesh ready for queries, in its own frame: triangles, pseudonormals
    (face, 3 edges, 3 vertices per triangle), whether it is closed, its box tree
    (order, lo, hi, left, right, start, count) and its signed distance grid."""

    tri: np.ndarray
    pseudo: np.ndarray
    solid: bool
    bvh: tuple
    g_values: np.ndarray
    g_origin: np.ndarray
    g_size: float
    g_dims: np.ndarray

    @property
    def bounds(self) -> np.ndarray:
        flat = self.tri.reshape(-1, 3)
        return np.array([flat.min(axis=0), flat.max(axis=0)])


def check_mesh(vertices: np.ndarray, faces: np.ndarray) -> None:
    """A mesh an obstacle can be made of: finite vertices (v, 3), triangles (f, 3) that
    index them, and a surface (not every triangle degenerate); else a ValueError that
    says what is wrong."""
    if vertices.ndim != 2 or vertices.shape[1] != 3 or vertices.shape[0] < 3:
        raise ValueError("the mesh needs vertices (v, 3), at least 3 of them")
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise ValueError(f"the mesh has {bad} vertices that are not finite numbers (NaN or "
                         "inf); repair or re-export it")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] == 0:
        raise ValueError("the mesh needs triangles (f, 3)")
    if faces.min() < 0 or faces.max() >= vertices.shape[0]:
        raise ValueError("the mesh's triangles index vertices it does not have")
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    extent = float(np.ptp(vertices, axis=0).max())
    if not area.sum() > 1e-12 * max(extent, 1e-300) ** 2:
        raise ValueError("the mesh has no surface: every triangle is degenerate (no area)")


def prepare_mesh(vertices: np.ndarray, faces: np.ndarray, resolution: int = 64,
                 cache: bool = True) -> MeshData:
    """Pseudonormals, box tree and signed distance grid of a mesh (the grid cached on
    disk under the hash of the mesh and the resolution; for a mesh of LARGE_MESH
    triangles or more, the pseudonormals and the tree too). Its progress is reported in
    triangles (``pliant.io.progress``), each step by its share of the build."""
    triangles = int(np.shape(faces)[0]) if np.ndim(faces) == 2 else 0
    with progress.work(triangles):
        def done(share: float) -> None:
            progress.advance(share * triangles)

        vertices = np.ascontiguousarray(vertices, dtype=float)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        check_mesh(vertices, faces)
        tri = np.ascontiguousarray(vertices[faces])
        digest = disk.digest(vertices.tobytes(), faces.tobytes())
        done(_SHARE["check"])
        structure = f"{digest}-{GRID_VERSION}"
        large = cache and faces.shape[0] >= LARGE_MESH
        pseudo, solid, bvh = _load_structure(structure, faces.shape[0]) if large else (
            None, False, ())
        if pseudo is None:
            pseudo, solid = _pseudonormals(vertices, faces)
            done(_SHARE["pseudonormals"])
            bvh = build_bvh(tri)
            done(_SHARE["tree"])
            if large:
                _save_structure(structure, pseudo, solid, bvh)
        else:
            done(_SHARE["pseudonormals"] + _SHARE["tree"])
        done(_SHARE["save"])
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        extent = max(float((hi - lo).max()), 1e-9)
        # Distance grid: a margin of a tenth of the extent round the mesh.
        g_size = extent * 1.2 / (resolution - 1)
        g_origin = lo - 0.1 * extent
        g_dims = np.ceil((hi - lo + 0.2 * extent) / g_size).astype(np.int64) + 1
        path = disk.cache_dir() / "sdf" / f"{digest}-{resolution}-{GRID_VERSION}.npy"
        values = None
        if cache and path.is_file():
            try:
                values = np.load(path)
                if values.shape != (int(np.prod(g_dims)),):
                    values = None
            except (OSError, ValueError):
                values = None
        if values is None:
            values = _fill_grid(g_origin, g_size, g_dims, tri, pseudo, solid, bvh)
            if cache:
                _save_grid(path, values)
        done(_SHARE["grid"])
    return MeshData(tri, pseudo, solid, bvh, values, g_origin, g_size, g_dims)


# Each step's share of a large mesh's build, measured at 1.3 M triangles (check and hash
# 0.4 s, pseudonormals 0.8 s, tree 0.75 s, writing them 0.8 s, the grid 0.9 s).
_SHARE = {"check": 0.1, "pseudonormals": 0.22, "tree": 0.2, "save": 0.2, "grid": 0.28}


LARGE_MESH = 100_000  # triangles from which the tree and pseudonormals are cached too
_TREE = ("order", "lo", "hi", "left", "right", "start", "count")


def _load_structure(key: str, triangles: int) -> tuple[np.ndarray | None, bool, tuple]:
    """A large mesh's pseudonormals, closedness and box tree from the disk cache (a CAD
    part loaded again: seconds saved), or (None, False, ()) when absent or unreadable."""
    data = disk.load_arrays("mesh", key)
    if data is None or not {"pseudo", "solid", *_TREE} <= set(data):
        return None, False, ()
    pseudo, bvh = data["pseudo"], tuple(data[k] for k in _TREE)
    if pseudo.shape != (triangles, 7, 3) or bvh[0].shape != (triangles,):
        return None, False, ()
    return pseudo, bool(data["solid"]), bvh


def _save_structure(key: str, pseudo: np.ndarray, solid: bool, bvh: tuple) -> None:
    """Best effort, written whole or not at all (``pliant.io.cache``)."""
    disk.save_arrays("mesh", key, pseudo=pseudo, solid=np.array(solid),
                     **dict(zip(_TREE, bvh)))


def _save_grid(path: Path, values: np.ndarray) -> None:
    """Best effort: a cache that cannot be written only costs time."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        with open(tmp, "wb") as handle:
            np.save(handle, values)
        os.replace(tmp, path)
    except OSError:
        pass


def _pseudonormals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, bool]:
    """(T, 7, 3) pseudonormals: face normal, the three edges' (sum of the adjacent face
    normals), the three vertices' (angle-weighted); and whether every edge has exactly
    two faces (a closed mesh, with an inside). Edges are found by sorting one integer
    key per edge (numpy's radix sort), the sums run in one compiled pass: a CAD part of
    millions of triangles takes about a second."""
    a = np.minimum(faces, np.roll(faces, -1, axis=1))  # edges (ab, bc, ca) of each face
    b = np.maximum(faces, np.roll(faces, -1, axis=1))
    keys = (a * np.int64(vertices.shape[0]) + b).ravel()
    order = np.argsort(keys, kind="stable")
    pseudo = np.zeros((faces.shape[0], 7, 3))
    closed = _pseudonormal_sums(vertices, faces, keys, order, pseudo)
    return pseudo, bool(closed)


@njit(cache=True)
def _pseudonormal_sums(vertices, faces, keys, order, pseudo):
    """Fill ``pseudo`` (see ``_pseudonormals``) from the edges' keys sorted by ``order``;
    True when every edge has two faces."""
    T = faces.shape[0]
    vert = np.zeros((vertices.shape[0], 3))
    for f in range(T):
        i0, i1, i2 = faces[f, 0], faces[f, 1], faces[f, 2]
        ux = vertices[i1, 0] - vertices[i0, 0]
        uy = vertices[i1, 1] - vertices[i0, 1]
        uz = vertices[i1, 2] - vertices[i0, 2]
        wx = vertices[i2, 0] - vertices[i0, 0]
        wy = vertices[i2, 1] - vertices[i0, 1]
        wz = vertices[i2, 2] - vertices[i0, 2]
        nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            nx, ny, nz = nx / length, ny / length, nz / length
        pseudo[f, 0, 0], pseudo[f, 0, 1], pseudo[f, 0, 2] = nx, ny, nz
        for corner in range(3):
            ia = faces[f, corner]
            ib = faces[f, (corner + 1) % 3]
            ic = faces[f, (corner + 2) % 3]
            dot = 0.0
            uu = 0.0
            ww = 0.0
            for k in range(3):
                u = vertices[ib, k] - vertices[ia, k]
                w = vertices[ic, k] - vertices[ia, k]
                dot += u * w
                uu += u * u
                ww += w * w
            cos = dot / max(math.sqrt(uu * ww), 1e-300)
            angle = math.acos(min(1.0, max(-1.0, cos)))
            vert[ia, 0] += angle * nx
            vert[ia, 1] += angle * ny
            vert[ia, 2] += angle * nz
    for v in range(vert.shape[0]):
        length = max(math.sqrt(vert[v, 0] ** 2 + vert[v, 1] ** 2 + vert[v, 2] ** 2), 1e-300)
        for k in range(3):
            vert[v, k] /= length
    for f in range(T):
        for corner in range(3):
            for k in range(3):
                pseudo[f, 4 + corner, k] = vert[faces[f, corner], k]
    closed = True
    m = keys.shape[0]
    i = 0
    while i < m:
        j = i
        sx = sy = sz = 0.0
        while j < m and keys[order[j]] == keys[order[i]]:
            f = order[j] // 3
            sx += pseudo[f, 0, 0]
            sy += pseudo[f, 0, 1]
            sz += pseudo[f, 0, 2]
            j += 1
        if j - i != 2:
            closed = False
        length = max(math.sqrt(sx * sx + sy * sy + sz * sz), 1e-300)
        for e in range(i, j):
            f, edge = order[e] // 3, 1 + order[e] % 3
            pseudo[f, edge, 0] = sx / length
            pseudo[f, edge, 1] = sy / length
            pseudo[f, edge, 2] = sz / length
        i = j
    return closed


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A rigid obstacle: a primitive or a mesh, placed by a rotation and a translation
    (local to world: x = R x_local + t). param: sphere (radius), box (half sizes),
    cylinder (radius, half length, along local z), half-space (none: solid below the
    local plane z = 0)."""

    name: str
    kind: int
    rotation: np.ndarray
    translation: np.ndarray
    param: np.ndarray
    mesh: MeshData | None = None
    friction: float = 0.0  # Coulomb's coefficient between it and the part
    # A flexible part already fitted (pliant.core.problem.FittedPart) whose tube at rest
    # this is: the accurate model solves it with the part that touches it.
    fitted: object = None

    # By value (what it is, not which object): a scene read again gives equal obstacles,
    # so a problem read back from its file equals the one written and a warm start
    # carries over. The identity test first: the solver compares them at every step.
    def __eq__(self, other: object) -> bool:
        if self is other:
            return True
        if not isinstance(other, Obstacle):
            return NotImplemented
        return (self.name == other.name and self.kind == other.kind
                and self.friction == other.friction
                and np.array_equal(self.rotation, other.rotation)
                and np.array_equal(self.translation, other.translation)
                and np.array_equal(self.param, other.param)
                and _same_mesh(self.mesh, other.mesh) and _same_fitted(self.fitted, other.fitted))

    def __hash__(self) -> int:
        return hash((self.name, self.kind, self.translation.tobytes(), self.param.tobytes()))

    def with_friction(self, mu: float) -> Obstacle:
        """This obstacle with Coulomb friction ``mu`` (>= 0) against the part."""
        if not (math.isfinite(mu) and mu >= 0.0):
            raise ValueError(f"friction: {mu!r} must be a finite number >= 0")
        return replace(self, friction=float(mu))

    @staticmethod
    def sphere(name: str, radius: float, center) -> Obstacle:
        return Obstacle(name, SPHERE, np.eye(3), np.asarray(center, float),
                        np.array([radius, 0.0, 0.0, 0.0]))

    @staticmethod
    def box(name: str, size, position, rotation=None) -> Obstacle:
        half = 0.5 * np.asarray(size, float)
        return Obstacle(name, BOX, _rot(rotation), np.asarray(position, float),
                        np.array([*half, 0.0]))

    @staticmethod
    def cylinder(name: str, radius: float, length: float, position, rotation=None) -> Obstacle:
        return Obstacle(name, CYLINDER, _rot(rotation), np.asarray(position, float),
                        np.array([radius, 0.5 * length, 0.0, 0.0]))

    @staticmethod
    def halfspace(name: str, point, normal) -> Obstacle:
        """Solid on the side opposite ``normal`` of the plane through ``point``."""
        return Obstacle(name, HALFSPACE, _frame_with_z(normal), np.asarray(point, float),
                        np.zeros(4))

    @staticmethod
    def from_mesh(name: str, vertices, faces, position=(0.0, 0.0, 0.0), rotation=None,
                  resolution: int = 64) -> Obstacle:
        return Obstacle(name, MESH, _rot(rotation), np.asarray(position, float),
                        np.zeros(4), prepare_mesh(vertices, faces, resolution))


def _same_mesh(a: MeshData | None, b: MeshData | None) -> bool:
    """The same triangles (and so the same mesh: the rest is made from them)."""
    if a is b:
        return True
    return a is not None and b is not None and a.solid == b.solid and np.array_equal(
        a.tri, b.tri)


def _same_fitted(a, b) -> bool:
    """The same part already fitted: its problem, element count and friction."""
    if a is b:
        return True
    return a is not None and b is not None and (a.name, a.elements, a.friction) == (
        b.name, b.elements, b.friction) and a.problem == b.problem


def _rot(rotation) -> np.ndarray:
    if rotation is None:
        return np.eye(3)
    R = np.asarray(rotation, float)
    if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9):
        raise ValueError("a rotation must be a 3 x 3 orthonormal matrix")
    return R


def _frame_with_z(normal) -> np.ndarray:
    z = np.asarray(normal, float)
    z = z / np.linalg.norm(z)
    a = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = a - (a @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


_FIELDS: dict[tuple[int, ...], tuple[tuple[Obstacle, ...], DistanceField]] = {}
_FIELDS_KEPT = 8  # scenes whose packed fields are kept (a tab's session uses one)
_FIELDS_LOCK = threading.Lock()


def field_of(obstacles) -> DistanceField:
    """The scene's ``DistanceField``, packed once per set of obstacle objects: a CAD
    scene's packing copies hundreds of megabytes (1.5 s at 1.6 M triangles), which
    every solve would otherwise pay. Keyed by the obstacles' identity (they are
    immutable), the few most recent kept."""
    obstacles = tuple(obstacles)
    key = tuple(id(o) for o in obstacles)
    with _FIELDS_LOCK:  # the viewer's tabs open their scenes from threads
        hit = _FIELDS.pop(key, None)
    if hit is None or any(a is not b for a, b in zip(hit[0], obstacles)):
        hit = (obstacles, DistanceField(list(obstacles)))
    with _FIELDS_LOCK:
        _FIELDS[key] = hit  # the most recent last
        while len(_FIELDS) > _FIELDS_KEPT:
            del _FIELDS[next(iter(_FIELDS))]
    return hit[1]


class DistanceField:
    """The signed distance to the nearest of a scene's obstacles, for batches of points
    (``query``) and, packed in ``args``, inside numba kernels (``query_point``)."""

    def __init__(self, obstacles: list[Obstacle]) -> None:
        self.obstacles = list(obstacles)
        m = len(self.obstacles)
        self.friction = np.array([o.friction for o in self.obstacles], dtype=float)
        meshes = [o.mesh for o in self.obstacles if o.mesh is not None]
        mesh_id = np.full(m, -1, dtype=np.int64)
        k = 0
        for i, o in enumerate(self.obstacles):
            if o.mesh is not None:
                mesh_id[i] = k
                k += 1
        kind = np.array([o.kind for o in self.obstacles], dtype=np.int64)
        rot = np.array([o.rotation for o in self.obstacles]).reshape(m, 3, 3)
        trans = np.array([o.translation for o in self.obstacles]).reshape(m, 3)
        param = np.array([o.param for o in self.obstacles]).reshape(m, 4)

        def cat(arrays, shape, dtype=float):
            return np.concatenate(arrays) if arrays else np.zeros(shape, dtype=dtype)

        def offsets(sizes):
            return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)

        tri = cat([x.tri for x in meshes], (0, 3, 3))
        pseudo = cat([x.pseudo for x in meshes], (0, 7, 3))
        trees = [x.bvh for x in meshes]
        self.args = Field(
            kind, rot, trans, param, mesh_id, tri, pseudo,
            np.array([x.solid for x in meshes], dtype=np.bool_),
            offsets([x.tri.shape[0] for x in meshes]),
            cat([b[0] for b in trees], (0,), np.int64),
            cat([b[1] for b in trees], (0, 3)), cat([b[2] for b in trees], (0, 3)),
            cat([b[3] for b in trees], (0,), np.int64), cat([b[4] for b in trees], (0,), np.int64),
            cat([b[5] for b in trees], (0,), np.int64), cat([b[6] for b in trees], (0,), np.int64),
            offsets([b[1].shape[0] for b in trees]),
            cat([x.g_values for x in meshes], (0,)),
            offsets([x.g_values.shape[0] for x in meshes]),
            np.array([x.g_origin for x in meshes]).reshape(-1, 3),
            np.array([x.g_size for x in meshes], dtype=float),
            np.array([x.g_dims for x in meshes], dtype=np.int64).reshape(-1, 3),
        )

    def __len__(self) -> int:
        return len(self.obstacles)

    def query(self, points, band: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distances (n,), unit gradients (n, 3), obstacle indices (n,)) of
        points (n, 3) [m]; exact within ``band`` of a mesh's surface."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=float)
        if not self.obstacles:
            n = points.shape[0]
            return np.full(n, np.inf), np.zeros((n, 3)), np.full(n, -1, dtype=np.int64)
        return query_points(points, float(band), self.args)

    def query_one(self, k: int, points, band: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
        """(signed distances (n,), unit gradients (n, 3)) of points (n, 3) [m] to the
        ``k``-th obstacle alone: the packed arrays as they are, only the obstacle list
        cut to it (no copy of a mesh)."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=float)
        one = slice(k, k + 1)
        args = self.args._replace(**{name: getattr(self.args, name)[one]
                                     for name in Field._fields[:5]})
        d, g, _ = query_points(points, float(band), args)
        return d, g
