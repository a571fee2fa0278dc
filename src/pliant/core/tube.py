"""The tube surface of a part: a circular section swept along its neutral line.

Shared by the accurate models' exports and the real-time display (where it runs every
frame, hence the numba kernel). When the section frames are not known (a display curve),
rotation-minimising frames are computed by the double reflection method (Wang, Juettler,
Zheng and Liu, ACM TOG 27, 2008), which does not twist the tube needlessly.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _double_reflection(points, tangents, r0):
    """(n, 3, 3) frames (normal, binormal, tangent in columns) transported along the
    polyline from the normal r0 at its start."""
    n = points.shape[0]
    frames = np.empty((n, 3, 3))
    r = r0.copy()
    for i in range(n):
        if i > 0:
            v1 = points[i] - points[i - 1]
            c1 = v1 @ v1
            if c1 > 0.0:
                t_prev = tangents[i - 1]
                r_l = r - (2.0 / c1) * (v1 @ r) * v1
                t_l = t_prev - (2.0 / c1) * (v1 @ t_prev) * v1
                v2 = tangents[i] - t_l
                c2 = v2 @ v2
                r = r_l - (2.0 / c2) * (v2 @ r_l) * v2 if c2 > 1e-30 else r_l
        t = tangents[i]
        r = r - (r @ t) * t  # keep it exactly normal (rounding)
        r = r / np.sqrt(r @ r)
        frames[i, :, 0] = r
        frames[i, 0, 1] = t[1] * r[2] - t[2] * r[1]
        frames[i, 1, 1] = t[2] * r[0] - t[0] * r[2]
        frames[i, 2, 1] = t[0] * r[1] - t[1] * r[0]
        frames[i, :, 2] = t
    return frames


def default_normal(tangent: np.ndarray) -> np.ndarray:
    """A unit vector normal to ``tangent``: the coordinate axis most normal to it, made
    normal."""
    axis = np.eye(3)[int(np.argmin(np.abs(tangent)))]
    r = axis - np.dot(axis, tangent) * tangent
    return r / np.linalg.norm(r)


def rotation_minimizing_frames(points: np.ndarray, first_normal: np.ndarray | None = None, *,
                               tangents: np.ndarray | None = None) -> np.ndarray:
    """(n, 3, 3) frames with columns (normal, binormal, tangent) along a polyline.

    points : (n, 3) float [m]; first_normal : (3,) the normal at the start (any vector
    not along the first tangent; default ``default_normal``); tangents : (n, 3) unit tangents
    where the curve's are known (a spline), else from the chords.
    """
    points = np.ascontiguousarray(points, dtype=float)
    if tangents is None:
        chords = np.diff(points, axis=0)
        lengths = np.linalg.norm(chords, axis=1)
        chords = chords / np.where(lengths > 0.0, lengths, 1.0)[:, None]
        tangents = np.empty_like(points)
        tangents[0] = chords[0]
        tangents[-1] = chords[-1]
        mid = chords[:-1] + chords[1:]
        norms = np.linalg.norm(mid, axis=1)
        tangents[1:-1] = np.where(norms[:, None] > 1e-12,
                                  mid / np.where(norms > 0, norms, 1)[:, None], chords[1:])
    tangents = np.ascontiguousarray(tangents, dtype=float)
    t0 = tangents[0]
    if first_normal is None:
        r = default_normal(t0)
    else:
        r = np.asarray(first_normal, float) - np.dot(first_normal, t0) * t0
    return _double_reflection(points, tangents, r / np.linalg.norm(r))


def tube_faces(n: int, sides: int, caps: bool = True) -> np.ndarray:
    """Triangles (m, 3) of a tube of n rings of ``sides`` vertices (and, with caps, one
    centre vertex at each end after the rings); they depend only on n and sides."""
    i = np.arange(n - 1)[:, None]
    j = np.arange(sides)[None, :]
    a = i * sides + j
    b = i * sides + (j + 1) % sides
    c = a + sides
    d = b + sides
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                            np.stack([a, d, c], -1).reshape(-1, 3)])
    if caps:
        start = n * sides
        ring0 = np.arange(sides)
        ring1 = (n - 1) * sides + ring0
        cap0 = np.stack([np.full(sides, start), (ring0 + 1) % sides, ring0], -1)
        cap1 = np.stack([np.full(sides, start + 1), ring1, (n - 1) * sides
                         + (ring0 + 1) % sides], -1)
        faces = np.concatenate([faces, cap0, cap1])
    return faces.astype(np.int64)


def tube_vertices(points: np.ndarray, radius: float, frames: np.ndarray, sides: int = 16,
                  caps: bool = True) -> np.ndarray:
    """Vertices (n * sides (+ 2), 3) [m] of the tube round ``points`` with the section
    axes in columns 0 and 1 of ``frames``; in the order ``tube_faces`` expects."""
    angles = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (sides, 2)
    offsets = ring @ frames[:, :, :2].transpose(0, 2, 1)  # (n, sides, 3)
    vertices = (points[:, None, :] + radius * offsets).reshape(-1, 3)
    if caps:
        vertices = np.vstack([vertices, points[0], points[-1]])
    return vertices


def tube_mesh(points: np.ndarray, radius: float, frames: np.ndarray | None = None,
              sides: int = 16, caps: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n * sides (+ 2), 3) [m] and triangles (m, 3) of a tube.

    points : (n, 3) the neutral line [m]; frames : (n, 3, 3) with the section's two axes
    in columns 0 and 1 (the material frame of a model), or None for rotation-minimising
    frames; caps closes both ends (a watertight surface).
    """
    points = np.asarray(points, float)
    if frames is None:
        frames = rotation_minimizing_frames(points)
    return (tube_vertices(points, radius, frames, sides, caps),
            tube_faces(points.shape[0], sides, caps))
