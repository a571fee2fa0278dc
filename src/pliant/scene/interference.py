"""Interference of a part with a scene: clearances, penetrations, spans too close.

The part is a tube of its outer radius round its neutral line. Its clearance to an
obstacle at s is the signed distance from the neutral line to the obstacle minus the
radius: negative where the tube is inside the obstacle. The report gives, per obstacle,
the smallest clearance and where it is, and the spans of s where the tube penetrates
(clearance below ``-tolerance``) or passes closer than the user's ``margin``: what a
design engineer checks a routing against ("keep 10 mm from the exhaust manifold").

It works on any sampled neutral line: an accurate equilibrium (``of_equilibrium``) or a
frame of the real-time model (``of_curve``). Sampling is dense (the polyline between the
samples is cut into ``subdivide`` pieces) and the distances exact near the surfaces.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pliant.errors import InputError
from pliant.scene.distance import Obstacle, field_of


@dataclass(frozen=True)
class Span:
    """A stretch of the part, s_start to s_end [m], against one obstacle, with its
    worst clearance [m] (negative: a penetration that deep) at s_worst."""

    obstacle: str
    s_start: float
    s_end: float
    worst: float
    s_worst: float

    def to_dict(self) -> dict[str, Any]:
        return {"obstacle": self.obstacle, "s_start": self.s_start, "s_end": self.s_end,
                "worst": self.worst, "s_worst": self.s_worst}


@dataclass(frozen=True)
class Clearance:
    """The smallest clearance [m] of the tube to one obstacle, where along the part
    (s [m]) and the neutral line's point there."""

    obstacle: str
    clearance: float
    s: float
    point: tuple[float, float, float]

    def to_dict(self) -> dict[str, Any]:
        return {"obstacle": self.obstacle, "clearance": self.clearance, "s": self.s,
                "point": list(self.point)}


@dataclass(frozen=True)
class Interference:
    """The interference report of one shape of the part against a scene."""

    margin: float
    tolerance: float
    clearances: tuple[Clearance, ...]
    penetrations: tuple[Span, ...]
    too_close: tuple[Span, ...]

    @property
    def clear(self) -> bool:
        """No penetration and nothing closer than the margin."""
        return not self.penetrations and not self.too_close

    @property
    def smallest(self) -> Clearance | None:
        return min(self.clearances, key=lambda c: c.clearance, default=None)

    def to_dict(self) -> dict[str, Any]:
        return {"margin": self.margin, "tolerance": self.tolerance, "clear": self.clear,
                "clearances": [c.to_dict() for c in self.clearances],
                "penetrations": [p.to_dict() for p in self.penetrations],
                "too_close": [p.to_dict() for p in self.too_close]}


def of_curve(s: np.ndarray, points: np.ndarray, radius: float,
             obstacles: tuple[Obstacle, ...] | list[Obstacle], *, margin: float = 0.0,
             tolerance: float = 1e-6, subdivide: int = 8) -> Interference:
    """The interference of a tube of ``radius`` round the polyline ``points`` (n, 3)
    [m] at arc lengths ``s`` (n,) [m] with each obstacle."""
    s = np.asarray(s, dtype=float)
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or s.shape != (points.shape[0],):
        raise InputError("points", "give s (n,) and points (n, 3) of the same n")
    for key, value in (("radius", radius), ("margin", margin), ("tolerance", tolerance)):
        if not np.isfinite(value) or value < 0.0:
            raise InputError(key, f"must be a finite length >= 0 [m], not {value!r}")
    if subdivide < 1:
        raise InputError("subdivide", "must be at least 1")
    t = np.linspace(0.0, 1.0, subdivide + 1)[:-1]
    dense = (points[:-1, None, :] + t[None, :, None] * (points[1:] - points[:-1])[:, None, :])
    dense = np.concatenate([dense.reshape(-1, 3), points[-1:]])
    ds = (s[:-1, None] + t[None, :] * (s[1:] - s[:-1])[:, None]).ravel()
    ds = np.concatenate([ds, s[-1:]])
    band = radius + margin + 1e-3
    clearances, penetrations, too_close = [], [], []
    field = field_of(obstacles)
    for k, obstacle in enumerate(obstacles):
        d, _ = field.query_one(k, dense, band=band)
        gap = d - radius
        k = int(np.argmin(gap))
        clearances.append(Clearance(obstacle.name, float(gap[k]), float(ds[k]),
                                    tuple(float(x) for x in dense[k])))
        penetrations += _spans(obstacle.name, ds, gap, gap < -tolerance)
        too_close += _spans(obstacle.name, ds, gap, (gap >= -tolerance) & (gap < margin))
    return Interference(margin, tolerance, tuple(clearances), tuple(penetrations),
                        tuple(too_close))


def of_equilibrium(eq: Any, obstacles: tuple[Obstacle, ...] | None = None, *,
                   margin: float = 0.0, tolerance: float = 1e-6,
                   subdivide: int = 8) -> Interference:
    """The interference of a 3D equilibrium with its problem's obstacles (or others).
    The tube's radius is the part's outer radius (0: a line, when it has none)."""
    if eq.problem.dimension != 3:
        raise InputError("eq", "interference is checked in 3D scenes; this is a 2D answer")
    return of_curve(eq.s, eq.position, eq.problem.part.tube_radius,
                    eq.problem.obstacles if obstacles is None else obstacles,
                    margin=margin, tolerance=tolerance, subdivide=subdivide)


def _spans(name: str, s: np.ndarray, gap: np.ndarray, mask: np.ndarray) -> list[Span]:
    """The runs of True in mask as spans, each with its worst gap."""
    out = []
    if not mask.any():
        return out
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
        k = a + int(np.argmin(gap[a:b]))
        out.append(Span(name, float(s[a]), float(s[b - 1]), float(gap[k]), float(s[k])))
    return out
