"""Reach and posture: whether the scene's worker (``[worker]``) can reach each grip from
where they stand, how far they must bend the trunk to, and how high the upper arm is
raised; each judged by the rules table's ``[posture]`` zones (ISO 11226).

The body is a stick figure sized from the rules table's ``[body]``: stature and
shoulder-grip length (the arm's reach to the centre of a gripped rod, straight) at the
worker's percentile of their sex's table, the shoulder, hip and knee heights, the
shoulder breadth and the upper arm as fractions of stature (Drillis and Contini). The
worker stands where ``[worker]`` puts them, facing its way; the trunk pivots forward at
the hip, the shoulders square to the facing (a grip to the side is that much farther:
turning or side-bending is not modelled); kneeling lowers hip and shoulder by the knee
height. The trunk bends at least as far as brings the grip within the arm's reach (none
where it already is; a grip out of reach even bent 90 degrees is red, by how much), and
further where that lowers the arm enough: the bend kept is the one whose worse of trunk
bend and upper-arm elevation, each over its red onset, is smallest (on a 0.5 degree
grid): the posture least at risk by the zones it is judged by. The arm is two
segments, shoulder to elbow and elbow to grip, with the elbow as low as it can hang (the
comfortable choice a planner of postures makes first); the upper-arm elevation is the
angle of shoulder to elbow from hanging straight down.

Not modelled: stepping, turning or leaning on something, the trunk's twist and side
bend, the wrist's angles, and capacities scaled by posture.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from statistics import NormalDist
from typing import Any

import numpy as np

from pliant.core.numbers import triple
from pliant.core.rules import Body, PostureZones, Rules
from pliant.core.worker import Worker
from pliant.errors import InputError

BEND_STEP = 0.5  # deg: the trunk bends tried, before bisection
MOST_BEND = 90.0  # deg


@dataclass(frozen=True)
class Reach:
    """One hand at one step: how far beyond the arm's reach the grip is at the trunk bend
    found (negative: within it by that much) [m], that bend and the upper-arm elevation
    [deg], the shoulder-to-grip distance and the arm's reach [m], and where the shoulder,
    elbow, hip, feet and hand are (global frame) [m]: the stick figure a report draws."""

    excess: float
    trunk: float
    upper_arm: float
    distance: float
    arm: float
    shoulder: tuple[float, float, float]
    elbow: tuple[float, float, float]
    side: str
    hip: tuple[float, float, float] = (0.0, 0.0, 0.0)
    feet: tuple[float, float, float] = (0.0, 0.0, 0.0)
    hand: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def chain(self) -> list[tuple[float, float, float]]:
        """The stick figure to draw: feet, hip, shoulder, elbow, hand [m]."""
        return [self.feet, self.hip, self.shoulder, self.elbow, self.hand]

    def to_dict(self) -> dict[str, Any]:
        return {"excess": self.excess, "trunk": self.trunk, "upper_arm": self.upper_arm,
                "distance": self.distance, "arm": self.arm, "shoulder": list(self.shoulder),
                "elbow": list(self.elbow), "side": self.side, "hip": list(self.hip),
                "feet": list(self.feet), "hand": list(self.hand)}


@dataclass(frozen=True)
class Spread:
    """How far apart two hands can be, for a body: shoulder breadth, the arm's reach
    (shoulder to grip, straight) and the upper arm [m]; ``limits`` the hands' distances
    [m] at which the upper arms must be raised past the ``[posture]`` zones' yellow and
    red onsets, whatever the rest of the posture, and ``most`` the widest two hands
    reach at all; ``who`` whose body, ``source`` where its sizes and zones come from."""

    breadth: float
    arm: float
    upper: float
    limits: tuple[float, float]
    who: str
    source: str = ""

    @property
    def most(self) -> float:
        return self.breadth + 2.0 * self.arm

    def elevation(self, apart: float) -> float:
        """The least upper-arm elevation [deg] that holds two hands ``apart`` [m]: each
        hand at least (apart - breadth) / 2 to the side of its shoulder, of which the
        forearm and hand (the arm's reach less the upper arm, turned any way) give at
        most their length and the upper arm raised by e the rest, upper sin(e)."""
        side = 0.5 * (apart - self.breadth) - (self.arm - self.upper)
        if side <= 0.0:
            return 0.0
        return math.degrees(math.asin(min(1.0, side / self.upper)))


def body_sizes(body: Body, sex: str, percentile: float) -> tuple[float, float]:
    """Stature and shoulder-grip length (the arm's reach) [m] at ``percentile`` of
    ``sex``'s table, taken together."""
    z = NormalDist().inv_cdf(percentile / 100.0)
    (stature, sd_stature), (arm, sd_arm) = body.stature[sex], body.shoulder_grip[sex]
    return stature + z * sd_stature, arm + z * sd_arm


def spread(body: Body, zones: PostureZones, sex: str = "women",
           percentile: float = 5.0) -> Spread:
    """Two hands' spread for the ``percentile`` of ``sex`` (the 5th percentile woman by
    default, as the worker: reach is designed for the small)."""
    stature, arm = body_sizes(body, sex, percentile)
    upper = body.upper_arm * stature
    breadth = body.shoulder_breadth * stature
    limits = tuple(breadth + 2.0 * ((arm - upper) + upper * math.sin(math.radians(e)))
                   for e in zones.upper_arm)
    who = f"a {percentile:g}th percentile {'man' if sex == 'men' else 'woman'}"
    return Spread(breadth, arm, upper, (limits[0], limits[1]), who,
                  f"{body.sourced.source}; {zones.sourced.source}")


def spread_of(rules: Rules, worker: Worker | None) -> Spread | None:
    """The spread of ``worker`` (the scene's; None: the 5th percentile woman the worker
    defaults to), or None where the rules table has no ``[body]`` or ``[posture]``."""
    if rules.body is None or rules.posture is None:
        return None
    if worker is None:
        return spread(rules.body, rules.posture)
    return spread(rules.body, rules.posture, worker.sex, worker.percentile)


class Figure:
    """The worker's stick figure: where the hip is, how long the trunk and the arm are,
    which way is up, forward and right."""

    def __init__(self, worker: Worker, body: Body, up: np.ndarray) -> None:
        self.stature, self.arm = body_sizes(body, worker.sex, worker.percentile)
        self.upper = body.upper_arm * self.stature
        self.up = up / np.linalg.norm(up)
        facing = np.asarray(worker.facing, float)
        facing = facing - (facing @ self.up) * self.up
        if np.linalg.norm(facing) < 1e-9:
            raise InputError("worker.facing", "give the direction the worker faces, not "
                             "straight up or down")
        self.facing = facing / np.linalg.norm(facing)
        drop = body.knee_height * self.stature if worker.posture == "kneeling" else 0.0
        self.hip = (np.asarray(worker.position, float)
                    + (body.hip_height * self.stature - drop) * self.up)
        self.trunk = (body.shoulder_height - body.hip_height) * self.stature
        self.half_breadth = 0.5 * body.shoulder_breadth * self.stature
        self.worker = worker

    def shoulders(self, side: str, bends: np.ndarray) -> np.ndarray:
        """The shoulder ``side`` (n, 3) with the trunk bent forward ``bends`` (n,) [deg]."""
        b = np.radians(np.asarray(bends, float))[:, None]
        right = np.cross(self.facing, self.up)
        lateral = self.half_breadth * (1.0 if side == "right" else -1.0)
        return (self.hip + self.trunk * (np.cos(b) * self.up + np.sin(b) * self.facing)
                + lateral * right)

    def shoulder(self, side: str, bend: float) -> np.ndarray:
        """The shoulder ``side`` with the trunk bent forward ``bend`` [deg]."""
        return self.shoulders(side, np.array([bend]))[0]

    def least_bend(self, hand: np.ndarray, side: str) -> float:
        """The least forward trunk bend [deg] that brings ``hand`` within the arm's reach
        (to a hair of a degree); where none does, the bend that brings it nearest (to
        ``BEND_STEP``)."""

        def gap(bend: float) -> float:
            return float(np.linalg.norm(hand - self.shoulder(side, bend))) - self.arm

        bends = np.arange(0.0, MOST_BEND + BEND_STEP / 2, BEND_STEP)
        gaps = np.linalg.norm(hand - self.shoulders(side, bends), axis=1) - self.arm
        inside = np.nonzero(gaps <= 0.0)[0]
        if inside.size == 0:
            return float(bends[int(np.argmin(gaps))])
        if inside[0] == 0:
            return 0.0
        lo, hi = float(bends[inside[0] - 1]), float(bends[inside[0]])
        for _ in range(40):  # bisection
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if gap(mid) <= 0.0 else (mid, hi)
        return hi

    def elevations(self, shoulders: np.ndarray, elbows: np.ndarray) -> np.ndarray:
        """The upper arm's elevation from hanging down [deg] (n,)."""
        arm = elbows - shoulders
        down = (arm @ -self.up) / np.linalg.norm(arm, axis=1)
        return np.degrees(np.arccos(np.clip(down, -1.0, 1.0)))

    def posture(self, hand: np.ndarray, side: str, bend: float) -> Reach:
        """The arm's posture reaching ``hand`` with the trunk bent ``bend`` [deg]."""
        shoulder = self.shoulders(side, np.array([bend]))
        elbow = self.elbows(shoulder, hand)
        elevation = float(self.elevations(shoulder, elbow)[0])
        distance = float(np.linalg.norm(hand - shoulder[0]))
        return Reach(distance - self.arm, bend, elevation, distance, self.arm,
                     triple(shoulder[0]), triple(elbow[0]), side, triple(self.hip),
                     triple(self.worker.position), triple(hand))

    def reach(self, hand, side: str, zones: PostureZones | None = None) -> Reach:
        """The posture that reaches ``hand`` [m]: with ``zones``, the trunk bend from the
        least that reaches (``least_bend``) to 90 degrees that keeps the worse of trunk
        bend and upper-arm elevation, each over its red onset, smallest (bending more
        lowers the arm); without, the least bend."""
        hand = np.asarray(hand, float)
        least = self.least_bend(hand, side)
        best = self.posture(hand, side, least)
        if zones is None or best.excess > 0.0:
            return best

        # every bend further on the grid at once: the first of least risk, if it is less
        bends = np.arange(math.ceil(least / BEND_STEP) * BEND_STEP, MOST_BEND + 1e-9,
                          BEND_STEP)
        if not bends.size:
            return best
        shoulders = self.shoulders(side, bends)
        risk = np.maximum(bends / zones.trunk[1],
                          self.elevations(shoulders, self.elbows(shoulders, hand))
                          / zones.upper_arm[1])
        k = int(np.argmin(risk))
        if risk[k] < max(best.trunk / zones.trunk[1], best.upper_arm / zones.upper_arm[1]):
            return self.posture(hand, side, float(bends[k]))
        return best

    def circles(self, shoulders: np.ndarray, hand: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The circle each elbow may lie on, the upper arm from ``shoulders`` (n, 3) and
        the forearm to ``hand``: (shoulder-hand distances d (n,), unit directions u
        (n, 3), the circle's centre x along u from the shoulder (n,), its radius (n,))."""
        a, b = self.upper, self.arm - self.upper
        along = hand - shoulders
        d = np.linalg.norm(along, axis=1)
        u = along / np.maximum(d, 1e-300)[:, None]
        x = (a * a - b * b + d * d) / (2.0 * np.maximum(d, 1e-300))
        return d, u, x, np.sqrt(np.maximum(a * a - x * x, 0.0))

    def elbows(self, shoulders: np.ndarray, hand: np.ndarray) -> np.ndarray:
        """The elbows (n, 3) as low as they can hang with the upper arm from ``shoulders``
        (n, 3) and the forearm to ``hand`` (the arm straight towards the hand where it
        does not reach; hanging where the hand is at the shoulder)."""
        a, b = self.upper, self.arm - self.upper
        d, u, x, rho = self.circles(shoulders, hand)
        down = -self.up - (u @ -self.up)[:, None] * u
        n = np.linalg.norm(down, axis=1)
        aside = np.cross(u, self.facing)
        aside /= np.maximum(np.linalg.norm(aside, axis=1), 1e-12)[:, None]
        w = np.where((n > 1e-9)[:, None], down / np.maximum(n, 1e-300)[:, None], aside)
        out = np.where(((d >= a + b) | (d <= abs(a - b)))[:, None], shoulders + a * u,
                       shoulders + x[:, None] * u + rho[:, None] * w)
        return np.where((d < 1e-9)[:, None], shoulders - a * self.up, out)


SWIVELS = 36  # elbow places tried round the shoulder-hand line (every 10 degrees)
ARM_SPACING = 0.02  # m between the upper arm's samples


@dataclass(frozen=True)
class ArmRoom:
    """The upper arm at one step (``Figure.swivelled``): its clearance to the obstacles
    [m] (negative: inside one by that much), how far the elbow swung from hanging lowest
    round the shoulder-hand line [deg], and what bounds it."""

    clearance: float
    swivel: float
    bound_by: str


def swivelled(figure: Figure, reach: Reach, radius: float, allowance: float,
              field: Any) -> tuple[Reach, ArmRoom]:
    """The reach with its upper arm (a capsule of ``radius`` from the shoulder to the
    elbow) clear of the obstacles in ``field``: the elbow hanging lowest where that
    clears them by ``allowance``, else swung round the shoulder-hand line (every
    360 / ``SWIVELS`` degrees) by the least angle that does, else the swing that clears
    most, as a fitter lifts the elbow round an edge. The reach keeps the elbow it takes
    and that upper arm's elevation (the posture check judges the arm as it is)."""
    shoulder, hand = np.asarray(reach.shoulder, float), np.asarray(reach.hand, float)
    a, b = figure.upper, figure.arm - figure.upper
    (d,), (u,), (x,), (rho,) = figure.circles(shoulder[None, :], hand)
    hanging = np.asarray(reach.elbow, float)
    angles = np.zeros(1)
    elbows = hanging[None, :]
    if abs(a - b) < d < a + b:  # the elbow may swing on a circle round the line
        centre = shoulder + x * u
        w = (hanging - centre) / max(rho, 1e-300)
        v = np.cross(u, w)
        angles = 2.0 * math.pi * np.arange(SWIVELS) / SWIVELS
        elbows = (centre + rho * (np.cos(angles)[:, None] * w
                                  + np.sin(angles)[:, None] * v))
    count = max(2, int(math.ceil(a / ARM_SPACING)) + 1)
    f = np.linspace(0.0, 1.0, count)
    points = shoulder + f[None, :, None] * (elbows - shoulder)[:, None, :]
    if len(field):
        dist, _, who = field.query(points.reshape(-1, 3), band=radius + 0.05)
        dist = np.asarray(dist, float).reshape(points.shape[:2]) - radius
        who = np.asarray(who).reshape(points.shape[:2])
    else:
        dist = np.full(points.shape[:2], np.inf)
        who = np.full(points.shape[:2], -1)
    room = dist.min(axis=1)
    wrapped = np.abs((angles + math.pi) % (2.0 * math.pi) - math.pi)
    ok = np.nonzero(room >= allowance)[0]
    k = int(ok[np.argmin(wrapped[ok])]) if ok.size else int(np.argmax(room))
    j = int(np.argmin(dist[k]))
    by = (field.obstacles[int(who[k, j])].name if len(field) and who[k, j] >= 0
          else "nothing")
    elbow = elbows[k]
    elevation = float(figure.elevations(shoulder[None, :], elbow[None, :])[0])
    return (replace(reach, elbow=triple(elbow), upper_arm=elevation),
            ArmRoom(float(room[k]), math.degrees(float(wrapped[k])), by))


def up_of(problem: Any) -> np.ndarray:
    """Up: against gravity where the problem has it, else +z."""
    g = np.asarray(getattr(problem, "gravity", None) or (0.0, 0.0, 0.0), float)
    if g.shape == (3,) and np.linalg.norm(g) > 0:
        return -g / np.linalg.norm(g)
    return np.array([0.0, 0.0, 1.0])

