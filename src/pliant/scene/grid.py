"""A mesh's signed distance grid: exact in a band round the surface, a Euclidean
distance transform beyond it, sampled by trilinear interpolation with its gradient;
within ``GRID_ERROR`` cells of the truth."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from pliant.scene.triangles import mesh_exact

# How far a grid value may be from the truth, in cells: sqrt(3) beyond the exact band
# (the nearest-band-node bound), plus sqrt(3)/2 of trilinear interpolation.
GRID_ERROR = 2.6


@njit(cache=True)
def onto_grid(f, top):
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
    fx, ox = onto_grid((x - origin[0]) / size, tx)
    fy, oy = onto_grid((y - origin[1]) / size, ty)
    fz, oz = onto_grid((z - origin[2]) / size, tz)
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


@njit(cache=True)
def band_values(origin, size, dims, reach, tri, pseudo, solid, bvh):
    """Exact signed distances at the grid nodes within ``reach`` of a triangle's bounding
    box (the band round the surface); NaN elsewhere."""
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
                    values[node] = mesh_exact(p, tri, pseudo, solid, bvh)[0]
    return values


def fill_grid(origin, size, dims, tri, pseudo, solid, bvh):
    """The signed distance grid: exact in a band round the surface, and beyond it the
    distance to the nearest band node plus that node's distance (an upper bound within
    sqrt(3) cells of the truth), with that node's sign."""
    from scipy.ndimage import distance_transform_edt  # noqa: PLC0415 (set-up only)

    values = band_values(origin, size, dims, 1.5 * size, tri, pseudo, solid, bvh)
    grid = values.reshape(tuple(dims))
    band = ~np.isnan(grid)
    gap, nearest = distance_transform_edt(~band, sampling=size, return_indices=True)
    near = grid[tuple(nearest)]
    filled = np.where(band, grid, np.sign(near) * (gap + np.abs(near)))
    return np.ascontiguousarray(filled.ravel())
