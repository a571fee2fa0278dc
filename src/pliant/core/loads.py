"""Loads as nouns: what acts on a part besides its conditions and its own weight.

Every load type lowers itself once to ``DistributedLoad`` (``Load.distributed``, given the
problem's gravity), the one form both models read (``Problem.distributed``); a new type is
a class here with ``check``, ``distributed`` and ``to_dict`` (its file table's keys), its
[[load]] keys in ``pliant.io.problem_file``, and its tests. ``AddedMass`` is one such.

A ``DistributedLoad`` acts on the arc lengths [start, end] of the unloaded part with the
force ``force`` [N/m] per metre of it. It is *dead* (``follower=False``: fixed in the
global frame, as the part's weight is) or a *follower* (``follower=True``: fixed in the
part's material frame, so it turns with the part: 2D (tangential, normal), the normal
nu = (-sin theta, cos theta) to the tangent's left; 3D (d1, d2, d3), d3 the tangent).
A follower load models what presses on the part's surface as it moves (the drag of a
flow along it, a pressure on one side) and has no potential: a solve with one reports
its stability as undecided and looks for no lower-energy branch.

Each model lowers the problem's loads once (``pliant.models.elastica2d.lowering``,
``pliant.models.rod3d.lowering``); the part's weight stays ``Problem.gravity`` times
``Part.mass_per_length`` and is lowered beside them as a dead load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from pliant.errors import InputError


@dataclass(frozen=True)
class DistributedLoad:
    """A force per unit length on the arc lengths [start, end] [m] of the unloaded part.

    force : (2,) or (3,) float [N/m]: global (dead) or material (follower) components
    follower : whether it turns with the part (see the module)
    start, end : where it acts [m]; end None: to the part's end
    name : what reports and errors call it
    """

    force: tuple[float, ...]
    follower: bool = False
    start: float = 0.0
    end: float | None = None
    name: str = "load"

    def __post_init__(self) -> None:
        label = self.name or "load"
        try:
            force = tuple(float(f) for f in self.force)
        except (TypeError, ValueError):
            raise InputError(f"{label}.force", f"give 2 (2D) or 3 (3D) numbers in N/m, not "
                             f"{self.force!r}") from None
        if len(force) not in (2, 3) or not all(math.isfinite(f) for f in force):
            raise InputError(f"{label}.force", f"give 2 (2D) or 3 (3D) finite numbers in "
                             f"N/m, not {self.force!r}")
        for key in ("start", "end"):
            value = getattr(self, key)
            if value is not None and not math.isfinite(float(value)):
                raise InputError(f"{label}.{key}", f"give an arc length in m, not {value!r}")
        start = float(self.start)
        end = None if self.end is None else float(self.end)
        if end is not None and end <= start:
            raise InputError(f"{label}.end", f"must lie beyond start = {start} m, not {end} m;"
                             " give the stretch of part the load acts on")
        object.__setattr__(self, "force", force)
        object.__setattr__(self, "follower", bool(self.follower))
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "end", end)
        object.__setattr__(self, "name", label)

    @property
    def dimension(self) -> int:
        return len(self.force)

    def span(self, length: float) -> tuple[float, float]:
        """(start, end) [m] on a part of this length."""
        return self.start, length if self.end is None else self.end

    def check(self, length: float, dimension: int) -> None:
        """Raise ``InputError`` unless the load fits a part of ``length`` in a problem
        of ``dimension``."""
        if self.dimension != dimension:
            raise InputError(f"{self.name}.force", f"has {self.dimension} components in a "
                             f"{dimension}D problem; give {dimension}")
        a, b = self.span(length)
        tol = 1e-12 * length
        if a < -tol or b > length * (1 + 1e-12):
            raise InputError(f"{self.name}.start", f"the load acts on [{a}, {b}] m, outside "
                             f"the part [0, {length}] m; move it onto the part")

    def overlap(self, a: float, b: float, length: float) -> float:
        """How much of [a, b] [m] the load covers [m]."""
        lo, hi = self.span(length)
        return max(0.0, min(b, hi) - max(a, lo))

    def distributed(self, gravity: tuple[float, ...]) -> tuple[DistributedLoad, ...]:
        return (self,)

    def to_dict(self) -> dict:
        """Its [[load]] table (``pliant.io.problem_file.LoadModel``'s keys)."""
        key = "follower_force" if self.follower else "force"
        return {"name": self.name, key: self.force, "start": self.start, "end": self.end}


@runtime_checkable
class Load(Protocol):
    """What ``Problem.loads`` holds: a load that names itself, checks that it fits the
    part, lowers itself to distributed forces and writes its file table."""

    @property
    def name(self) -> str: ...

    def check(self, length: float, dimension: int) -> None: ...

    def distributed(self, gravity: tuple[float, ...]) -> tuple[DistributedLoad, ...]: ...

    def to_dict(self) -> dict: ...


@dataclass(frozen=True)
class AddedMass:
    """Mass carried by a stretch [start, end] [m] of the part besides its own,
    ``mass_per_length`` [kg/m]: a sleeve, tape or a harness's wrapping, a hose's fluid.
    It weighs under the problem's gravity (a dead load of mass_per_length * g)."""

    mass_per_length: float
    start: float = 0.0
    end: float | None = None
    name: str = "added mass"

    def __post_init__(self) -> None:
        label = self.name or "added mass"
        m = self.mass_per_length
        if not isinstance(m, int | float) or not math.isfinite(m) or m < 0:
            raise InputError(f"{label}.mass_per_length", f"give a mass per length >= 0 in "
                             f"kg/m, not {m!r}")
        span = DistributedLoad((0.0, 0.0), start=self.start, end=self.end, name=label)
        object.__setattr__(self, "mass_per_length", float(m))
        object.__setattr__(self, "start", span.start)
        object.__setattr__(self, "end", span.end)
        object.__setattr__(self, "name", label)

    def check(self, length: float, dimension: int) -> None:
        DistributedLoad((0.0,) * dimension, start=self.start, end=self.end,
                        name=self.name).check(length, dimension)

    def distributed(self, gravity: tuple[float, ...]) -> tuple[DistributedLoad, ...]:
        force = tuple(self.mass_per_length * g for g in gravity)
        return (DistributedLoad(force, start=self.start, end=self.end, name=self.name),)

    def to_dict(self) -> dict:
        return {"name": self.name, "mass_per_length": self.mass_per_length,
                "start": self.start, "end": self.end}
