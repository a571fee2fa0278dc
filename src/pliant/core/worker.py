"""Who does the operation and where they stand (a scene's ``[worker]``): plain data that
``pliant.assembly.posture`` turns into reach, arm elevation and trunk bend."""

from __future__ import annotations

import math
from dataclasses import dataclass

from pliant.errors import InputError

POSTURES = ("standing", "kneeling")
SEXES = ("men", "women")
SIDES = ("right", "left")


@dataclass(frozen=True)
class Worker:
    """position [m]: on the floor, between the feet; facing: the direction they face
    (its part square to up counts); posture: standing or kneeling; sex and percentile:
    whose body sizes (the rules table's ``[body]``), a percentile of stature and of
    reach taken together (a small worker, the 5th percentile woman, by default: reach is
    designed for the small); side: the hand a one-hand grip uses."""

    position: tuple[float, float, float]
    facing: tuple[float, float, float] = (1.0, 0.0, 0.0)
    posture: str = "standing"
    sex: str = "women"
    percentile: float = 5.0
    side: str = "right"

    def __post_init__(self) -> None:
        if self.posture not in POSTURES:
            raise InputError("worker.posture", f"must be one of {', '.join(POSTURES)}; got "
                             f"{self.posture!r}")
        if self.sex not in SEXES:
            raise InputError("worker.sex", f"must be one of {', '.join(SEXES)} (whose body "
                             f"sizes); got {self.sex!r}")
        if self.side not in SIDES:
            raise InputError("worker.side", f"must be one of {', '.join(SIDES)}; got "
                             f"{self.side!r}")
        if not (math.isfinite(self.percentile) and 1.0 <= self.percentile <= 99.0):
            raise InputError("worker.percentile", "give a percentile from 1 to 99 (5: a "
                             f"small worker, 95: a large one); got {self.percentile!r}")
        if not all(math.isfinite(v) for v in (*self.position, *self.facing)):
            raise InputError("worker.position", "give finite numbers [m]")
