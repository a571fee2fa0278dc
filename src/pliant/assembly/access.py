"""Hand access: whether a fitter's hand fits round the part where it holds it, and its
forearm reaches in from outside, at every step of the path.

The envelope (``pliant.core.rules.HandEnvelope``, sized in the rules table from published
anthropometry) is a union of swept balls, so that its clearance to anything is the
distance field's value at its axis points less their radius:

- the hand round the part: a capsule along the part's tangent, centred on the part a
  half hand's breadth in from an end it holds there, radius the part's plus the hand's
  thickness (a pinch: a finger's), reaching a hand's breadth along the part;
- the palm and forearm: a slab from the part's axis out along an approach direction
  ``a`` square to the part (a power grip holds the part across the palm), its section
  the wrist's out to the palm's length, then widening linearly to the elbow's at the
  forearm's length; the section's breadth lies along the part (the knuckles' line), its
  thickness across. The slab is three lines of balls across its breadth.

Every approach direction round the part is tried (``HandEnvelope.directions`` of them,
at each of its ``tilts`` along the part: a bent wrist; square to the part by default):
the hand's access at a step is the clearance of the best one, and what bounds it. Red
where no approach fits (a negative clearance), yellow within the movement allowance.
Obstacles, fitted parts (their tubes at rest) and the held part's own spans all count,
but for the stretch within a hand's breadth and a ring's diameter of the hand (the part
running on from the hand, which the hand holds round). A tool's or robot's own envelope
is not checked here.

Clearances are sampled along each line of the slab every ``SPACING`` and refined round
the closest sample of each line that can decide the best approach (``REFINE`` rounds of
nine points, each a quarter of the last span): exact where the closest point is unique,
and never more than about half a spacing too large otherwise (the distance field is
1-Lipschitz). The ring, a few millimetres long, is sampled at ``RING`` points.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pliant.core.numbers import triple
from pliant.core.rules import HandEnvelope

SPACING = 0.02  # m between samples along a line of the envelope
REFINE = 3  # rounds of local refinement round each line's closest sample
LINES = 3  # lines of balls across the forearm slab's breadth
RING = 9  # samples along the ring's axis (a hand's breadth less its thickness)
OWN_STEP = 0.006  # m: the held part's own line resampled this finely
BAND = 0.1  # m: mesh distances exact within it (a forearm's radius and some)
SELF = "the part itself"


@dataclass(frozen=True)
class Access:
    """The hand at one step: the best approach's clearance [m] (negative: no approach
    fits, by that much), its direction (unit, global frame), what bounds it, the hand's
    centre on the part [m] (its arc length ``s``) and how far the envelope reaches out
    along the approach [m]."""

    clearance: float
    approach: tuple[float, float, float]
    bound_by: str
    centre: tuple[float, float, float]
    s: float
    reach: float = 0.0  # m: the envelope from the part's axis out to the elbow
    ring: float = 0.0  # m: the radius of the hand round the part

    def to_dict(self) -> dict[str, Any]:
        return {"clearance": self.clearance, "approach": list(self.approach),
                "bound_by": self.bound_by, "centre": list(self.centre), "s": self.s,
                "reach": self.reach, "ring": self.ring}


def _frame(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors square to t and to each other."""
    helper = np.array([0.0, 0.0, 1.0]) if abs(t[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    n0 = np.cross(t, helper)
    n0 /= np.linalg.norm(n0)
    return n0, np.cross(t, n0)


class _Shape:
    """The envelope of one hand (or two side by side) round a part: the ring round the
    part (a capsule along its tangent) and the palm-and-forearm slab's lines, each a
    function of the approach direction and of u in [0, 1] out along it."""

    def __init__(self, env: HandEnvelope, part_radius: float, hold: str, hands: int) -> None:
        glove = env.glove
        thick = env.pinch_thickness if hold == "pinch" else env.thickness
        breadth = (env.pinch_breadth if hold == "pinch" else env.breadth) * hands + 2 * glove
        self.breadth = breadth
        self.ring_radius = part_radius + thick + 2 * glove
        self.ring_half = max(0.5 * breadth - self.ring_radius, 0.0)
        self.reach = env.palm + env.forearm
        self.env = env
        # forearms side by side (two hands): spread over one hand's breadth more
        self.extra = (hands - 1) * env.breadth
        self.across = np.linspace(-1.0, 1.0, LINES)
        # how fast a line's clearance can change per metre out: the distance field's 1,
        # the line's drift along the part and its radius's growth
        grow_b = abs(env.elbow[0] - env.wrist[0]) / env.forearm
        grow_t = abs(env.elbow[1] - env.wrist[1]) / env.forearm
        self.lipschitz = 1.0 + 0.5 * (grow_b + grow_t) + 0.5 * grow_t

    def section(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(breadth, thickness) [m] of the palm-and-forearm slab at x [m] from the axis."""
        env = self.env
        f = np.clip((x - env.palm) / env.forearm, 0.0, 1.0)
        breadth = env.wrist[0] + f * (env.elbow[0] - env.wrist[0]) + self.extra
        thick = env.wrist[1] + f * (env.elbow[1] - env.wrist[1])
        return breadth, thick

    def ring(self, u: np.ndarray, centre: np.ndarray, t: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        """Points (k, 3) and radii (k,) along the ring's axis at u (k,)."""
        along = (2.0 * u - 1.0) * self.ring_half
        return centre + along[:, None] * t, np.full(u.shape, self.ring_radius)

    def slab(self, across: np.ndarray, a: np.ndarray, u: np.ndarray, centre: np.ndarray,
             b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points (n, k, 3) and radii (n, k) of slab lines at fractions ``across`` (n,)
        of its breadth, out along approaches a (n, 3), its breadth along b (n, 3), at u
        (n, k)."""
        x = u * self.reach
        breadth, thick = self.section(x)
        offset = across[:, None] * np.maximum(breadth - thick, 0.0) / 2.0
        pts = centre + offset[..., None] * b[:, None, :] + x[..., None] * a[:, None, :]
        return pts, thick / 2.0


def hand_access(eq: Any, s: float, env: HandEnvelope, hold: str = "power grip",
                hands: int = 1, field: Any = None) -> Access:
    """The hand (``hands`` side by side) holding the part at arc length s [m] of
    equilibrium ``eq``: the best approach's clearance and what bounds it. ``field``: the
    obstacles' distance field (default: the problem's, packed once per obstacle set)."""
    from pliant.scene.distance import field_of  # noqa: PLC0415 (numba kernels, on demand)

    part = eq.problem.part
    shape = _Shape(env, part.tube_radius, hold, hands)
    field = field if field is not None else field_of(eq.problem.obstacles)
    nodes_s, line = eq.s, eq.position
    length = part.length
    half = 0.5 * shape.breadth
    s_c = min(max(s, half), length - half) if length > 2 * half else 0.5 * length
    k = int(np.argmin(np.abs(nodes_s - s_c)))
    centre = np.asarray(line[k], float)
    t = np.asarray(eq.tangent[k], float)
    t /= np.linalg.norm(t)
    n0, n1 = _frame(t)
    angles = 2.0 * math.pi * np.arange(env.directions) / env.directions
    square = np.cos(angles)[:, None] * n0 + np.sin(angles)[:, None] * n1
    # each tilt of the forearm along the part (a bent wrist), its breadth kept square
    # to the forearm in the plane of the part's axis
    a = np.concatenate([math.cos(math.radians(tilt)) * square
                        + math.sin(math.radians(tilt)) * t for tilt in env.tilts])
    b = t - (a @ t)[:, None] * a
    b /= np.linalg.norm(b, axis=1)[:, None]
    # the part's own spans away from the hand (past its ends by a ring's diameter, where
    # the part running straight on is a hand's thickness clear of the ring), near enough
    keep = np.abs(nodes_s - s_c) > half + 2.0 * shape.ring_radius
    reach = shape.reach + 0.5 * max(env.elbow) + shape.extra + half
    near = keep & (np.linalg.norm(line - centre, axis=1) < reach)
    own = _Own(line, near)
    r_part = part.tube_radius

    def clearance(pts: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        flat = pts.reshape(-1, 3)
        if len(field):
            d, _, idx = field.query(flat, band=BAND)
            d, who = np.array(d, float), np.array(idx, np.int64)
        else:
            d, who = np.full(len(flat), np.inf), np.full(len(flat), -1, np.int64)
        d_own = own.distance(flat) - r_part
        closer = d_own < d
        d[closer] = d_own[closer]
        who[closer] = -2
        return d.reshape(pts.shape[:-1]) - radius, who.reshape(pts.shape[:-1])

    # The ring (which does not depend on the approach) and the slab's lines, every
    # approach at once, sampled coarsely in one query; then the lines that can decide
    # the best approach refined round their closest sample.
    n_dir = a.shape[0]
    pair_dir = np.repeat(np.arange(n_dir), LINES)
    pair_across = np.tile(shape.across, n_dir)
    count = max(2, int(math.ceil(shape.reach / SPACING)) + 1)
    grid = np.broadcast_to(np.linspace(0.0, 1.0, count), (pair_dir.size, count))
    ring_pts, ring_rad = shape.ring(np.linspace(0.0, 1.0, RING), centre, t)
    slab_pts, slab_rad = shape.slab(pair_across, a[pair_dir], grid, centre, b[pair_dir])
    val, who = clearance(np.concatenate([ring_pts, slab_pts.reshape(-1, 3)]),
                         np.concatenate([ring_rad, slab_rad.ravel()]))
    i = int(np.argmin(val[:RING]))
    ring_best, ring_by = float(val[i]), int(who[i])
    val, who = val[RING:].reshape(grid.shape), who[RING:].reshape(grid.shape)
    j = np.argmin(val, axis=1)
    rows = np.arange(pair_dir.size)
    line_best, line_by, line_u = val[rows, j], who[rows, j], grid[rows, j]
    slack = 0.5 * shape.lipschitz * shape.reach / (count - 1)  # a coarse min's error, at most
    per_dir = np.minimum(line_best.reshape(n_dir, LINES).min(axis=1), ring_best)
    wanted = (per_dir[pair_dir] >= per_dir.max() - slack) & (
        line_best - slack <= per_dir[pair_dir])
    pick = np.nonzero(wanted)[0]
    span = 1.0 / (count - 1)
    for _ in range(REFINE if pick.size else 0):
        grid = np.clip(line_u[pick, None] + span * np.linspace(-1.0, 1.0, 9)[None, :],
                       0.0, 1.0)
        val, who = clearance(*shape.slab(pair_across[pick], a[pair_dir[pick]], grid,
                                         centre, b[pair_dir[pick]]))
        j = np.argmin(val, axis=1)
        got = val[np.arange(pick.size), j]
        better = got < line_best[pick]
        line_best[pick[better]] = got[better]
        line_by[pick[better]] = who[np.arange(pick.size), j][better]
        line_u[pick] = grid[np.arange(pick.size), j]
        span /= 4.0
    per_line = line_best.reshape(n_dir, LINES)
    per_dir = np.minimum(per_line.min(axis=1), ring_best)
    r = int(np.argmax(per_dir))
    by = ring_by if ring_best <= per_line[r].min() else int(
        line_by.reshape(n_dir, LINES)[r, int(np.argmin(per_line[r]))])
    name = SELF if by == -2 else (field.obstacles[by].name if by >= 0 else "nothing")
    return Access(float(per_dir[r]), triple(a[r]), name, triple(centre),
                  float(nodes_s[k]), shape.reach, shape.ring_radius)


class _Own:
    """The part's own line where it has a node among ``near``, resampled every
    ``OWN_STEP`` at most: distances to it from a k-d tree of the samples, less what a
    sample's spacing can hide (a point at distance d from the line is within half a
    spacing of a sample along it: d >= sqrt(d_sample^2 - (step / 2)^2))."""

    def __init__(self, line: np.ndarray, near: np.ndarray) -> None:
        idx = np.nonzero(near)[0]
        segs = sorted({j for i in idx for j in (i - 1, i) if 0 <= j < len(line) - 1})
        self.tree = None
        if not segs:
            return
        from scipy.spatial import cKDTree  # noqa: PLC0415

        a, b = line[segs], line[np.add(segs, 1)]
        pieces = np.maximum(np.ceil(np.linalg.norm(b - a, axis=1) / OWN_STEP), 1).astype(int)
        f = np.concatenate([np.arange(n + 1) / n for n in pieces])
        which = np.repeat(np.arange(len(segs)), pieces + 1)
        samples = a[which] + f[:, None] * (b - a)[which]
        self.step = float((np.linalg.norm(b - a, axis=1) / pieces).max())
        self.tree = cKDTree(samples)

    def distance(self, points: np.ndarray) -> np.ndarray:
        """A lower bound on the distance of each point (k, 3) to the line (inf without
        one): below it by step^2 / 8d at most, 0.2 mm at 20 mm."""
        if self.tree is None:
            return np.full(points.shape[0], np.inf)
        d, _ = self.tree.query(points)
        return np.sqrt(np.maximum(d * d - 0.25 * self.step**2, 0.0))
