"""Triangle meshes: the closest point on a triangle, a bounding-volume tree over the
triangles (built by median splits with a linear-time selection), the exact signed query
through it (the sign from the angle-weighted pseudonormal of the closest feature,
Baerentzen and Aanaes, IEEE TVCG 11(3), 2005), the Hessian beyond a feature, the
pseudonormals themselves, and the interpolated normal by which a contact reads facets
that tessellate a smooth surface as that surface (``smooth_normal``, ``smooth_rate``)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit


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
def select(order, key, lo, hi, target):
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
        axis = 0  # the widest spread (written out: an array expression compiles slowly)
        for a in (1, 2):
            if cmax[a] - cmin[a] > cmax[axis] - cmin[axis]:
                axis = a
        half = n0 // 2
        select(order, centroid[:, axis], s0, s0 + n0 - 1, s0 + half)
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


@njit(cache=True)
def box_distance2(p, lo, hi):
    d2 = 0.0
    for a in range(3):
        if p[a] < lo[a]:
            d2 += (lo[a] - p[a]) ** 2
        elif p[a] > hi[a]:
            d2 += (p[a] - hi[a]) ** 2
    return d2


@njit(cache=True)
def mesh_exact(p, tri, pseudo, solid, bvh):
    """(signed distance, unit gradient) from p to a mesh, exact: a branch-and-bound walk
    of its box tree bvh (``build_bvh``'s tuple). pseudo (T, 7, 3): the pseudonormals of
    each triangle's face, edges and vertices (the sign)."""
    dist, grad, _, _ = mesh_feature(p, tri, pseudo, solid, bvh)
    return dist, grad


@njit(cache=True)
def mesh_feature(p, tri, pseudo, solid, bvh):
    """(signed distance, unit gradient, triangle, feature) of the mesh point nearest p:
    the feature as ``closest_on_triangle`` numbers it; bvh: ``build_bvh``'s tuple."""
    order, lo, hi, left, right, start, count = bvh
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
        if box_distance2(p, lo[node], hi[node]) >= best:
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
        dl = box_distance2(p, lo[a_], hi[a_])
        dr = box_distance2(p, lo[b_], hi[b_])
        if top + 2 > stack.shape[0]:
            grown = np.empty(2 * stack.shape[0], dtype=np.int64)
            for i in range(top):
                grown[i] = stack[i]
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
    grad = np.empty(3)
    if dist > 1e-300:
        grad[0], grad[1], grad[2] = gx / dist, gy / dist, gz / dist
    else:
        for c in range(3):
            grad[c] = pseudo[best_t, 0, c]
    if solid:
        n = pseudo[best_t, best_r]
        if gx * n[0] + gy * n[1] + gz * n[2] < 0.0:
            for c in range(3):
                grad[c] = -grad[c]
            return -dist, grad, best_t, best_r
    return dist, grad, best_t, best_r


@njit(cache=True)
def feature_hessian(dist, n, tangent, kind):
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


def _unit_rows(v: np.ndarray) -> None:
    """Each row of v (k, 3) scaled to length 1, in place; a zero row stays zero."""
    v /= np.maximum(np.sqrt(np.einsum("ik,ik->i", v, v)), 1e-300)[:, None]


class _Topology(NamedTuple):
    """A mesh's face normals (T, 3), corner angles (T, 3) and edge uses (face * 3 + its
    edge ab, bc or ca) sorted by edge (``order``), with where each edge's run starts."""

    n: np.ndarray
    angle: np.ndarray
    order: np.ndarray
    first: np.ndarray


def _topology(vertices: np.ndarray, faces: np.ndarray) -> _Topology:
    corner = vertices[faces]  # (T, 3 corners, 3)
    u = np.roll(corner, -1, axis=1) - corner  # each corner to the next
    w = -np.roll(u, 1, axis=1)  # and to the one before
    n = np.cross(u[:, 0], w[:, 0])
    _unit_rows(n)
    uu = np.einsum("tck,tck->tc", u, u)
    cos = np.einsum("tck,tck->tc", u, w) / np.maximum(np.sqrt(uu * np.roll(uu, 1, axis=1)),
                                                         1e-300)
    angle = np.arccos(np.clip(cos, -1.0, 1.0))  # (T, 3) each corner's
    a = np.minimum(faces, np.roll(faces, -1, axis=1))  # edges (ab, bc, ca) of each face
    b = np.maximum(faces, np.roll(faces, -1, axis=1))
    keys = (a * np.int64(vertices.shape[0]) + b).ravel()
    order = np.argsort(keys, kind="stable")
    ordered = keys[order]
    first = np.empty(ordered.shape[0], dtype=bool)  # where an edge's run of faces starts
    first[:1] = True
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    return _Topology(n, angle, order, first)


def pseudonormals(vertices: np.ndarray, faces: np.ndarray,
                  topology: _Topology | None = None) -> tuple[np.ndarray, bool]:
    """(T, 7, 3) pseudonormals: face normal, the three edges' (sum of the adjacent face
    normals), the three vertices' (angle-weighted); and whether every edge has exactly
    two faces (a closed mesh, with an inside). Edges are found by sorting one integer
    key per edge (numpy's radix sort) and summed by segments, vertices by ``bincount``:
    whole-array numpy, 0.25 s for 330,000 triangles where a compiled loop took 0.1 s
    but cost every first run 1.1 s of compiling (a scene's structures are cached)."""
    T = faces.shape[0]
    n, angle, order, first = topology or _topology(vertices, faces)
    vert = np.empty((vertices.shape[0], 3))
    for k in range(3):
        vert[:, k] = np.bincount(faces.ravel(), (angle * n[:, k, None]).ravel(),
                                 vertices.shape[0])
    _unit_rows(vert)
    pseudo = np.empty((T, 7, 3))
    pseudo[:, 0] = n
    pseudo[:, 4:7] = vert[faces]
    starts = np.flatnonzero(first)
    sums = np.add.reduceat(n[order // 3], starts, axis=0)
    _unit_rows(sums)
    edge = np.empty(order.shape[0], dtype=np.int64)
    edge[order] = np.cumsum(first) - 1
    pseudo[:, 1:4] = sums[edge].reshape(T, 3, 3)
    closed = bool(np.all(np.diff(np.append(starts, order.shape[0])) == 2))
    return pseudo, closed


CREASE = 10.0  # deg: faces meeting at a smaller angle tessellate one smooth surface


def contact_normals(vertices: np.ndarray, faces: np.ndarray, crease: float = CREASE
                    ) -> tuple[np.ndarray, bool]:
    """(T, 12, 3) what a mesh's queries read: ``pseudonormals`` (rows 0-6), then
    ``smooth_normals`` (rows 7-11), from one pass over its topology; and whether it is
    closed."""
    topology = _topology(vertices, faces)
    pseudo, closed = pseudonormals(vertices, faces, topology)
    smooth = smooth_normals(vertices, faces, crease, topology)
    return np.concatenate([pseudo, smooth], axis=1), closed


def smooth_normals(vertices: np.ndarray, faces: np.ndarray, crease: float = CREASE,
                   topology: _Topology | None = None) -> np.ndarray:
    """(T, 5, 3) what a contact needs to read a tessellated smooth surface as smooth (see
    ``smooth_normal``): rows 0-2 each corner's normal, the angle-weighted face normals
    of the faces round its vertex joined to it across edges whose faces meet within
    ``crease`` degrees (a smoothing group, as a CAD tessellation's shading reads it;
    0: none, each face its own); row 3 whether each edge (ab, bc, ca) is such a smooth
    edge (1.0; a crease or a border: 0.0); row 4 whether each corner's vertex has only
    smooth edges."""
    from scipy.sparse import coo_matrix  # noqa: PLC0415
    from scipy.sparse.csgraph import connected_components  # noqa: PLC0415

    T, V = faces.shape[0], vertices.shape[0]
    out = np.zeros((T, 5, 3))
    if T == 0:
        return out
    n, angle, order, first = topology or _topology(vertices, faces)
    runs = np.diff(np.append(np.flatnonzero(first), order.shape[0]))
    pair = np.flatnonzero(first)[runs == 2]  # the first use of each two-face edge
    e1, e2 = order[pair], order[pair + 1]  # (face * 3 + local edge) of its two uses
    f1, k1, f2, k2 = e1 // 3, e1 % 3, e2 // 3, e2 % 3
    smooth = (np.einsum("tk,tk->t", n[f1], n[f2]) >= math.cos(math.radians(crease))
              if crease > 0.0 else np.zeros(f1.shape[0], dtype=bool))
    flags = np.zeros(T * 3)
    flags[e1[smooth]] = 1.0
    flags[e2[smooth]] = 1.0
    out[:, 3] = flags.reshape(T, 3)
    # Corners joined across smooth edges: each end of the edge, in both faces (the
    # second face runs the edge the other way round where the two are oriented alike).
    f1, k1, f2, k2 = f1[smooth], k1[smooth], f2[smooth], k2[smooth]
    j1 = (k1 + 1) % 3
    j2 = (k2 + 1) % 3
    same = faces[f2, k2] == faces[f1, k1]
    rows = np.concatenate([f1 * 3 + k1, f1 * 3 + j1])
    cols = np.concatenate([f2 * 3 + np.where(same, k2, j2), f2 * 3 + np.where(same, j2, k2)])
    graph = coo_matrix((np.ones(rows.shape[0]), (rows, cols)), shape=(3 * T, 3 * T))
    groups, group = connected_components(graph, directed=False)
    weighted = angle.ravel()[:, None] * np.repeat(n, 3, axis=0)
    sums = np.column_stack([np.bincount(group, weighted[:, k], groups) for k in range(3)])
    _unit_rows(sums)
    out[:, 0:3] = sums[group].reshape(T, 3, 3)
    # A vertex is smooth where every edge round it is: no crease, no border.
    sharp = np.zeros(V, dtype=bool)
    bad = flags.reshape(T, 3) == 0.0
    sharp[faces[bad]] = True
    sharp[np.roll(faces, -1, axis=1)[bad]] = True
    out[:, 4] = np.where(sharp[faces], 0.0, 1.0)
    return out


@njit(cache=True, inline="always")
def _interpolated(p, dist, g, t, region, tri, pseudo):
    """The corners' normals (``smooth_normals``, ``pseudo`` rows 7-11) interpolated at
    the closest point q = p - dist g's place on triangle t (its barycentric coordinates;
    along an edge, between its two corners; at a vertex, its own), not yet unit:
    (whether q lies on the smooth surface, mx, my, mz). p and g (the exact gradient) as
    3-tuples; scalars only (it runs per query)."""
    px, py, pz = p
    gx, gy, gz = g
    if region >= 4:
        k = region - 4
        if pseudo[t, 11, k] == 0.0:
            return False, gx, gy, gz
        return True, pseudo[t, 7 + k, 0], pseudo[t, 7 + k, 1], pseudo[t, 7 + k, 2]
    qx, qy, qz = px - dist * gx, py - dist * gy, pz - dist * gz
    if region >= 1:
        k = region - 1
        if pseudo[t, 10, k] == 0.0:
            return False, gx, gy, gz
        j = (k + 1) % 3
        ex, ey, ez = (tri[t, j, 0] - tri[t, k, 0], tri[t, j, 1] - tri[t, k, 1],
                      tri[t, j, 2] - tri[t, k, 2])
        tau = ((qx - tri[t, k, 0]) * ex + (qy - tri[t, k, 1]) * ey
               + (qz - tri[t, k, 2]) * ez) / (ex * ex + ey * ey + ez * ez)
        tau = min(max(tau, 0.0), 1.0)
        return (True, (1.0 - tau) * pseudo[t, 7 + k, 0] + tau * pseudo[t, 7 + j, 0],
                (1.0 - tau) * pseudo[t, 7 + k, 1] + tau * pseudo[t, 7 + j, 1],
                (1.0 - tau) * pseudo[t, 7 + k, 2] + tau * pseudo[t, 7 + j, 2])
    nx, ny, nz = pseudo[t, 0, 0], pseudo[t, 0, 1], pseudo[t, 0, 2]
    area2 = _area2(tri, t)
    mx = my = mz = 0.0
    for i in range(3):
        a, b = (i + 1) % 3, (i + 2) % 3
        vx, vy, vz = (tri[t, b, 0] - tri[t, a, 0], tri[t, b, 1] - tri[t, a, 1],
                      tri[t, b, 2] - tri[t, a, 2])
        # corner i's barycentric coordinate: its gradient n x (v_b - v_a) / 2A
        bi = ((ny * vz - nz * vy) * (qx - tri[t, a, 0])
              + (nz * vx - nx * vz) * (qy - tri[t, a, 1])
              + (nx * vy - ny * vx) * (qz - tri[t, a, 2])) / area2
        mx += bi * pseudo[t, 7 + i, 0]
        my += bi * pseudo[t, 7 + i, 1]
        mz += bi * pseudo[t, 7 + i, 2]
    return True, mx, my, mz


@njit(cache=True, inline="always")
def _area2(tri, t):
    """Twice triangle t's area."""
    ux, uy, uz = (tri[t, 1, 0] - tri[t, 0, 0], tri[t, 1, 1] - tri[t, 0, 1],
                  tri[t, 1, 2] - tri[t, 0, 2])
    wx, wy, wz = (tri[t, 2, 0] - tri[t, 0, 0], tri[t, 2, 1] - tri[t, 0, 1],
                  tri[t, 2, 2] - tri[t, 0, 2])
    cx, cy, cz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    return math.sqrt(cx * cx + cy * cy + cz * cz)


@njit(cache=True, inline="always")
def _unit_outward(mx, my, mz, gx, gy, gz):
    """(ok, size, sign): m's length, signed to point where the exact gradient does (an
    open shell's back: its distance's gradient points off it); not ok where m is none."""
    size = math.sqrt(mx * mx + my * my + mz * mz)
    if not size > 1e-12:
        return False, size, 1.0
    return True, size, (-1.0 if mx * gx + my * gy + mz * gz < 0.0 else 1.0)


@njit(cache=True, inline="always")
def smooth_normal(p, dist, g, t, region, tri, pseudo):
    """The normal a contact at p reads from a mesh whose faces tessellate a smooth
    surface: the corners' normals interpolated at the closest point
    (``_interpolated``), as FE codes' contact surface smoothing does. The exact normal
    turns only in the wedge beyond each edge and vertex, a facet's angle across a tenth
    of a millimetre on a dense CAD mesh, so that a straight element's nearest point
    jumps from edge to edge as it turns and a Newton iterate flips between them; the
    interpolated one turns continuously across each face, the surface the facets stand
    for. The distance stays the mesh's exact one. Beyond a crease or a border
    (``CREASE``) the exact normal is kept: a sharp edge is one. (p, g: the point and the
    exact gradient as 3-tuples; dist: ``mesh_feature``'s.) Returns (whether the point
    reads the smooth surface, nx, ny, nz)."""
    ok, mx, my, mz = _interpolated(p, dist, g, t, region, tri, pseudo)
    if ok:
        ok, size, sign = _unit_outward(mx, my, mz, g[0], g[1], g[2])
    if not ok:
        return False, g[0], g[1], g[2]
    f = sign / size
    return True, f * mx, f * my, f * mz


@njit(cache=True)
def smooth_rate(p, dist, grad, t, region, tri, pseudo):
    """(d n / d p (3, 3), whether it applies) of ``smooth_normal``'s n: the
    interpolation's derivative as the closest point moves with p (none at a vertex);
    not where p reads the exact normal (a crease, a border)."""
    H = np.zeros((3, 3))
    g = (grad[0], grad[1], grad[2])
    ok, mx, my, mz = _interpolated((p[0], p[1], p[2]), dist, g, t, region, tri, pseudo)
    if ok:
        ok, size, sign = _unit_outward(mx, my, mz, g[0], g[1], g[2])
    if not ok:
        return H, False
    dm = np.zeros((3, 3))
    if 1 <= region <= 3:
        k = region - 1
        a, b = tri[t, k], tri[t, (k + 1) % 3]
        e = b - a
        ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2]
        ca, cb = pseudo[t, 7 + k], pseudo[t, 7 + (k + 1) % 3]
        for i in range(3):
            for j in range(3):
                dm[i, j] = (cb[i] - ca[i]) * e[j] / ee
    elif region == 0:
        nf = pseudo[t, 0]
        area2 = _area2(tri, t)
        for i in range(3):
            gi = np.cross(nf, tri[t, (i + 2) % 3] - tri[t, (i + 1) % 3]) / area2
            for r in range(3):
                for j in range(3):
                    dm[r, j] += pseudo[t, 7 + i, r] * gi[j]
    n = np.array([mx, my, mz]) * (sign / size)
    for i in range(3):
        for j in range(3):
            v = 0.0
            for r in range(3):
                v += ((1.0 if i == r else 0.0) - n[i] * n[r]) * dm[r, j]
            H[i, j] = sign * v / size
    return H, True
