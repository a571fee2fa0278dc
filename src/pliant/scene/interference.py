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

from pliant.core.equilibrium import Equilibrium3D, Result
from pliant.core.numbers import shown_clearance, triple
from pliant.core.problem import PROBE_SAG, WALL_COMPLIANCE
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
             tolerance: float = 1e-6, subdivide: int = 8,
             tubes: dict[str, tuple[np.ndarray, float, float]] | None = None
             ) -> Interference:
    """The interference of a tube of ``radius`` round the polyline ``points`` (n, 3)
    [m] at arc lengths ``s`` (n,) [m] with each obstacle. ``tubes``: obstacles that are
    other parts' tubes, by name: (their neutral line's points (m, 3) [m], their radius
    [m], the overlap [m] their contact model allows: walls' give and probes' spacing);
    the clearance to those is measured to that line (as it deformed), and an overlap
    within that allowance is touching, not penetrating."""
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
    tubes = tubes or {}
    for k, obstacle in enumerate(obstacles):
        deep = tolerance
        if obstacle.name in tubes:
            line, outer, allowed = tubes[obstacle.name]
            d = polyline_distance(dense, np.asarray(line, dtype=float)) - outer
            deep += allowed
        else:
            d, _ = field.query_one(k, dense, band=band)
        gap = d - radius
        k = int(np.argmin(gap))
        clearances.append(Clearance(obstacle.name, shown_clearance(float(gap[k]), deep),
                                    float(ds[k]), triple(dense[k])))
        penetrations += _spans(obstacle.name, ds, gap, gap < -deep)
        too_close += _spans(obstacle.name, ds, gap, (gap >= -deep) & (gap < margin))
    return Interference(margin, tolerance, tuple(clearances), tuple(penetrations),
                        tuple(too_close))


SAMPLES = 4  # points per element an answer's clearance is sampled at, on every surface


def of_equilibrium(eq: Result, obstacles: tuple[Obstacle, ...] | None = None, *,
                   margin: float = 0.0, tolerance: float = 1e-6,
                   subdivide: int = SAMPLES) -> Interference:
    """The interference of a 3D equilibrium with its problem's obstacles (or others).
    The tube's radius is the part's outer radius (0: a line, when it has none). A
    flexible part already fitted is measured as it is in this answer: deformed where
    the part touched it (``eq.fitted``), else at rest."""
    if not isinstance(eq, Equilibrium3D):
        raise InputError("eq", "interference is checked in 3D scenes; this is a 2D answer")
    obstacles = eq.problem.obstacles if obstacles is None else obstacles
    return of_answer(eq.s, eq.position, eq.contacts, eq.problem.part.tube_radius, obstacles,
                     margin=margin, tolerance=tolerance, subdivide=subdivide,
                     tubes=fitted_tubes(eq, obstacles))


def of_answer(s: np.ndarray, points: np.ndarray, contacts: Any, radius: float,
              obstacles: tuple[Obstacle, ...] | list[Obstacle], *, margin: float = 0.0,
              tolerance: float = 1e-6, subdivide: int = SAMPLES,
              tubes: dict[str, tuple[np.ndarray, float, float]] | None = None
              ) -> Interference:
    """The interference of an accurate answer (its neutral line ``points`` at ``s``, its
    ``contacts``) as every surface reports it (the terminal, the files, the page): one
    number for one clearance."""
    if contacts is not None and len(contacts):
        # The touching points themselves (on the neutral line's straight pieces, so the
        # line is unchanged): where the part touches, its clearance is the contact's 0,
        # not what samples beside it read over a curved obstacle (a micrometre or two).
        s = np.concatenate([s, contacts.s])
        points = np.concatenate([points, contacts.point])
        order = np.argsort(s, kind="stable")
        s, points = s[order], points[order]
    return of_curve(s, points, radius, obstacles, margin=margin, tolerance=tolerance,
                    subdivide=subdivide, tubes=tubes)


def fitted_tubes(eq: Equilibrium3D, obstacles) -> dict[str, tuple[np.ndarray, float, float]]:
    """The fitted flexible parts among ``obstacles``, by name: (neutral line [m], outer
    radius [m], allowed overlap [m]), deformed as in ``eq`` where it touched them, else
    at rest (see ``of_curve``)."""
    out = {}
    deformed = {id(f.problem): f for f in eq.fitted}
    forces = eq.contacts.by_obstacle() if deformed else {}
    for o in obstacles:
        fit = getattr(o, "fitted", None)
        if fit is None:
            continue
        touched = deformed.get(id(fit.problem))
        line = touched.position if touched is not None else fit.rest_line
        outer = fit.problem.part.tube_radius
        allowed = (PROBE_SAG * (outer + eq.problem.part.tube_radius)
                   + WALL_COMPLIANCE * float(np.linalg.norm(forces.get(o.name, np.zeros(3)))))
        out[o.name] = (line, outer, allowed)
    return out


def polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """The distance [m] of each point (k, 3) to the polyline ``line`` (m, 3): to the
    nearest of its segments, in whole-array numpy over blocks of points (about a
    million point-segment pairs a block). A kernel took microseconds less on a part's
    few hundred points and cost half a second of every first run to compile."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    line = np.asarray(line, dtype=float).reshape(-1, 3)
    if line.shape[0] == 1:
        return np.linalg.norm(points - line[0], axis=1)
    start, along = line[:-1], np.diff(line, axis=0)
    length2 = np.maximum(np.einsum("ij,ij->i", along, along), 1e-300)
    out = np.empty(points.shape[0])
    block = max(1, 2**20 // start.shape[0])
    for i in range(0, points.shape[0], block):
        rel = points[i:i + block, None, :] - start[None, :, :]  # (b, m - 1, 3)
        t = np.clip(np.einsum("bmc,mc->bm", rel, along) / length2, 0.0, 1.0)
        off = rel - t[..., None] * along
        out[i:i + block] = np.sqrt(np.einsum("bmc,bmc->bm", off, off).min(axis=1))
    return out


def _spans(name: str, s: np.ndarray, gap: np.ndarray, mask: np.ndarray) -> list[Span]:
    """The runs of True in mask as spans, each with its worst gap."""
    out: list[Span] = []
    if not mask.any():
        return out
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
        k = a + int(np.argmin(gap[a:b]))
        out.append(Span(name, float(s[a]), float(s[b - 1]), float(gap[k]), float(s[k])))
    return out
