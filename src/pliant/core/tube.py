"""The tube surface of a part: a circular section swept along its neutral line.

Pure numpy, shared by the accurate models' exports and the real-time display. When the
section frames are not known (a display curve), rotation-minimising frames are computed
by the double reflection method (Wang, Juettler, Zheng and Liu, ACM TOG 27, 2008), which
does not twist the tube needlessly.
"""

from __future__ import annotations

import numpy as np


def rotation_minimizing_frames(points: np.ndarray, first_normal: np.ndarray | None = None
                               ) -> np.ndarray:
    """(n, 3, 3) frames with columns (normal, binormal, tangent) along a polyline.

    points : (n, 3) float [m]; first_normal : (3,) the normal at the start (any vector
    not along the first tangent; default: the coordinate axis most normal to it).
    """
    points = np.asarray(points, float)
    n = points.shape[0]
    chords = np.diff(points, axis=0)
    lengths = np.linalg.norm(chords, axis=1)
    chords = chords / np.where(lengths > 0.0, lengths, 1.0)[:, None]
    tangents = np.empty((n, 3))
    tangents[0] = chords[0]
    tangents[-1] = chords[-1]
    mid = chords[:-1] + chords[1:]
    norms = np.linalg.norm(mid, axis=1)
    tangents[1:-1] = np.where(norms[:, None] > 1e-12, mid / np.where(norms > 0, norms, 1)[:, None],
                              chords[1:])
    t0 = tangents[0]
    if first_normal is None:
        first_normal = np.eye(3)[int(np.argmin(np.abs(t0)))]
    r = np.asarray(first_normal, float) - np.dot(first_normal, t0) * t0
    r /= np.linalg.norm(r)
    frames = np.empty((n, 3, 3))
    frames[0] = np.column_stack([r, np.cross(t0, r), t0])
    for i in range(n - 1):
        v1 = points[i + 1] - points[i]
        c1 = float(v1 @ v1)
        if c1 == 0.0:
            frames[i + 1] = frames[i]
            continue
        r_l = r - (2.0 / c1) * float(v1 @ r) * v1
        t_l = tangents[i] - (2.0 / c1) * float(v1 @ tangents[i]) * v1
        v2 = tangents[i + 1] - t_l
        c2 = float(v2 @ v2)
        r = r_l - (2.0 / c2) * float(v2 @ r_l) * v2 if c2 > 1e-30 else r_l
        t = tangents[i + 1]
        frames[i + 1] = np.column_stack([r, np.cross(t, r), t])
    return frames


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
    n = points.shape[0]
    angles = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (sides, 2)
    offsets = np.einsum("sk,nck->nsc", ring, frames[:, :, :2])  # (n, sides, 3)
    vertices = (points[:, None, :] + radius * offsets).reshape(-1, 3)
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
        vertices = np.vstack([vertices, points[0], points[-1]])
        ring0 = np.arange(sides)
        ring1 = (n - 1) * sides + ring0
        cap0 = np.stack([np.full(sides, start), (ring0 + 1) % sides, ring0], -1)
        cap1 = np.stack([np.full(sides, start + 1), ring1, (n - 1) * sides
                         + (ring0 + 1) % sides], -1)
        faces = np.concatenate([faces, cap0, cap1])
    return vertices, faces.astype(np.int64)
