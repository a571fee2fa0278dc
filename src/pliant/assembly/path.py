"""Follow a manipulation: solve each step of a grip's path with the accurate 3D model
(warm-started from the step before), and record at each step what a fitter or a robot
would be asked about: the force and moment at the grip, the smallest clearance to the
scene and to what, the contacts, the tightest bend.

A step that cannot be solved ends the run with the reason and keeps every step solved so
far (``PathRun.stopped``): the path is not feasible as given beyond that point (the part
would snap, or the grip asks for something it cannot reach).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pliant.core.conditions import Condition
from pliant.core.equilibrium import Equilibrium3D
from pliant.core.events import LeftUnstable, WarmStartLost, events, jumped
from pliant.core.numbers import triple
from pliant.core.planning import PathSpec
from pliant.core.problem import Problem
from pliant.errors import InputError, PliantError
from pliant.scene.interference import Interference, of_equilibrium

# The units of a run's records, as its JSON states them.
STEP_UNITS = {"progress": "1", "grip_position": "m", "force": "N", "moment": "N m",
              "clearance": "m", "clearances": "m", "contact_force": "N", "bend_radius": "m",
              "bend_at": "m", "seconds": "s", "margin": "m"}


@dataclass(frozen=True)
class StepRecord:
    """One step of a path. progress in [0, 1] (0: the start pose); grip position [m],
    force [N] and moment [N m] the grip applies to the part (global frame); clearance
    [m] the smallest to any obstacle (negative: penetration) and which; contacts the
    number of touching points and their total force [N]; bend radius [m] the
    smallest along the part and where (s [m]); stable whether the part would stay there
    (None: not decided, under non-conservative loads); snap whether the step before's
    shape could not be followed here (a fold: the part jumps to another shape, which is
    what this step holds); seconds the solve's wall time; clearances the smallest
    clearance [m] to each obstacle, by name."""

    progress: float
    grip_position: tuple[float, float, float]
    force: tuple[float, float, float]
    moment: tuple[float, float, float]
    clearance: float
    nearest: str
    contacts: int
    contact_force: float
    bend_radius: float
    bend_at: float
    stable: bool | None
    snap: bool
    seconds: float
    clearances: tuple[tuple[str, float], ...] = ()

    @property
    def force_norm(self) -> float:
        return float(np.linalg.norm(self.force))

    @property
    def moment_norm(self) -> float:
        return float(np.linalg.norm(self.moment))

    def to_dict(self) -> dict[str, Any]:
        out = dict(self.__dict__)
        for key in ("grip_position", "force", "moment"):
            out[key] = list(out[key])
        out["clearances"] = dict(self.clearances)
        return out


@dataclass
class PathRun:
    """The steps solved (their records, and their equilibria in ``equilibria``), the
    last equilibrium, its interference report, and why the run stopped early (None when
    it reached the path's end)."""

    grip: str
    margin: float
    steps: list[StepRecord] = field(default_factory=list)
    final: Any = None
    interference: Interference | None = None
    stopped: str | None = None
    planned: int = 0
    equilibria: list[Any] = field(default_factory=list, repr=False)
    problems: list[Problem] = field(default_factory=list, repr=False)
    compiling: float = 0.0  # s the solvers spent compiling on the way (a first run only)

    @property
    def complete(self) -> bool:
        return self.stopped is None

    @property
    def snaps(self) -> list[int]:
        """The steps where the part jumped to another shape."""
        return [k for k, r in enumerate(self.steps) if r.snap]

    @property
    def branched(self) -> list[int]:
        """The steps where the followed shape was unstable and the part took the stable
        branch beside it without a jump (a bifurcation crossed: ``LeftUnstable``)."""
        return [k for k, eq in enumerate(self.equilibria)
                if any(isinstance(n, LeftUnstable) and not n.jump for n in eq.notes)]

    @property
    def unstable(self) -> list[int]:
        """The steps whose shape a real part would not keep."""
        return [k for k, r in enumerate(self.steps) if r.stable is False]

    def peak(self, what: str) -> tuple[float, int]:
        """The largest |force| or |moment| (what = "force" or "moment") and its step."""
        values = [getattr(r, f"{what}_norm") for r in self.steps]
        k = int(np.argmax(values))
        return values[k], k

    def to_dict(self) -> dict[str, Any]:
        return {"grip": self.grip, "margin": self.margin, "planned": self.planned,
                "complete": self.complete, "stopped": self.stopped,
                "steps": [r.to_dict() | {"notes": _step_notes(eq)} for r, eq in
                          itertools.zip_longest(self.steps, self.equilibria[:len(self.steps)])],
                "interference": None if self.interference is None
                else self.interference.to_dict()}


def _step_notes(eq: Any) -> list[dict[str, Any]]:
    """A step's events as JSON-ready records (none where its equilibrium is not kept)."""
    return [] if eq is None else [e.to_dict() for e in events(eq.notes)]


def carry(problem: Problem, path: PathSpec | None) -> list[Problem]:
    """The problems along a scene's [path]: its grip carried through the waypoints in
    its steps (empty without a path); InputError naming the [path]'s field."""
    if path is None:
        return []
    index = next((k for k, c in enumerate(problem.conditions) if c.name == path.grip),
                 None)
    if index is None:
        raise InputError("path.grip", f"no condition named {path.grip!r}; name the "
                         "[[condition]] the hand holds")
    grip = problem.conditions[index]
    if any(v is None for v in grip.position):
        raise InputError("path.grip", f"{path.grip!r} must hold x, y and z to be "
                         "carried along a path")
    points = np.array([grip.position, *path.waypoints], dtype=float)
    turn = path.tangents is not None and grip.tangent is not None
    tangents = (np.array([grip.tangent, *(path.tangents or [])], dtype=np.float64) if turn
                else None)
    if float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum()) == 0.0:
        raise InputError("path.waypoints", "the path has no length: move the grip")
    carried = carried_conditions(problem, path.carry, path.grip)
    problems = []
    for where, direction in along_legs(points, tangents, path.steps):
        changes: dict[str, Any] = {"position": tuple(float(x) for x in where)}
        if direction is not None:
            changes["tangent"] = tuple(float(x) for x in direction)
            if grip.normal is not None:
                changes["normal"] = None  # the hand's roll follows the turn
        conditions = list(problem.conditions)
        conditions[index] = replace(grip, **changes)
        moved = carry_with(grip, where, direction, carried)
        conditions = [moved.get(c.name, c) for c in conditions]
        problems.append(replace(problem, conditions=tuple(conditions)))
    return problems


def carried_conditions(problem: Problem, names: tuple[str, ...], grip: str
                       ) -> list[Condition]:
    """The conditions a [path] carries with its grip, each checked: another condition of
    the problem that holds a whole position (InputError naming ``path.carry``)."""
    out = []
    for name in names:
        found = next((c for c in problem.conditions if c.name == name), None)
        if found is None or name == grip:
            raise InputError("path.carry", f"{name!r} is not another condition of the "
                             "problem; name the hands carried with the grip")
        if any(v is None for v in found.position):
            raise InputError("path.carry", f"{name!r} must hold x, y and z to be carried")
        out.append(found)
    return out


def carry_with(grip: Condition, where: Any, direction: Any,
               carried: list[Condition]) -> dict[str, Condition]:
    """The carried conditions where the grip's move from its own pose to (``where``,
    ``direction``) takes them as one rigid body: turned by the least rotation from the
    grip's axis to ``direction`` (none without axes) about the grip, then moved with it."""
    if not carried:
        return {}
    from pliant.core.rotations import rotation_between  # noqa: PLC0415

    turn = np.eye(3)
    if direction is not None and grip.tangent is not None:
        to = np.asarray(direction, float)
        turn = rotation_between(np.asarray(grip.tangent, float), to / np.linalg.norm(to))
    origin, target = np.asarray(grip.position, float), np.asarray(where, float)
    out = {}
    for c in carried:
        changes: dict[str, Any] = {"position": tuple(
            float(x) for x in target + turn @ (np.asarray(c.position, float) - origin))}
        for key in ("tangent", "normal"):
            value = getattr(c, key)
            if value is not None:
                changes[key] = tuple(float(x) for x in turn @ np.asarray(value, float))
        out[c.name] = replace(c, **changes)
    return out


def along_legs(points: np.ndarray, tangents: np.ndarray | None,
               steps: int) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """The poses a [path] gives: ``steps`` equal steps of arc length along straight legs
    through ``points`` (n, 3) [m], each with the axis turned at a constant rate from one
    of ``tangents`` (n, 3) to the next (None: no axis). A leg of no length gets no step."""
    legs = np.linalg.norm(np.diff(points, axis=0), axis=1)
    at = np.concatenate([[0.0], np.cumsum(legs)])
    total = float(at[-1])
    out = []
    for k in range(1, steps + 1):
        u = total * k / steps
        leg = min(int(np.searchsorted(at, u, side="right")) - 1, len(legs) - 1)
        t = (u - at[leg]) / legs[leg] if legs[leg] > 0 else 1.0
        where = points[leg] + t * (points[leg + 1] - points[leg])
        direction = None
        if tangents is not None:
            a = tangents[leg] / np.linalg.norm(tangents[leg])
            b = tangents[leg + 1] / np.linalg.norm(tangents[leg + 1])
            direction = slerp(a, b, t)
        out.append((where, direction))
    return out


def slerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """The unit vector a fraction t of the way from unit a to unit b along their great
    circle (a half turn has none: an error naming [path] tangents)."""
    angle = math.acos(max(-1.0, min(1.0, float(a @ b))))
    if angle < 1e-9:
        return a
    if math.pi - angle < 1e-9:
        raise InputError("path.tangents", "a tangent turns right round between two "
                         "waypoints; add a waypoint between them")
    return (math.sin((1 - t) * angle) * a + math.sin(t * angle) * b) / math.sin(angle)


def follow_path(start: Problem, path: list[Problem], grip: str, *, margin: float = 0.0,
                elements: int = 100,
                on_step: Callable[[int, StepRecord], None] | None = None,
                start_from: Any = None) -> PathRun:
    """Solve ``start`` then each problem of ``path`` in turn (warm), recording each.
    ``start_from``: an equilibrium of a problem like ``start`` (a variation study's
    nominal start) to start from instead of the unloaded part: the same branch, found
    in a few Newton iterations; cold where it cannot be followed."""
    from pliant.models import clock, rod3d  # noqa: PLC0415 (numba kernels: on demand)

    solver = rod3d.RodSolver(elements=elements)
    run = PathRun(grip=grip, margin=margin, planned=len(path))
    eq = None
    compiled = clock.compiling()
    for k, problem in enumerate([start, *path]):
        begin = clock.now()  # solve time: a first run's compiling is left out
        try:
            if k == 0 and start_from is not None:
                eq = rod3d.solve(problem, warm_start=start_from, solver=solver)
                # A start solved cold after all is no snap along the path.
                eq = replace(eq, notes=tuple(n for n in eq.notes
                                             if not isinstance(n, WarmStartLost)))
            else:
                eq = rod3d.solve(problem, warm_start=eq, solver=solver)
        except PliantError as err:
            run.stopped = (f"step {k} of {len(path)} (progress {k / max(len(path), 1):.0%}) "
                           f"could not be solved: {err}")
            break
        record = _record(eq, grip, k / max(len(path), 1), margin, clock.now() - begin)
        run.steps.append(record)
        run.equilibria.append(eq)
        run.problems.append(problem)
        run.final = eq
        if on_step is not None:
            on_step(k, record)
    if run.final is not None:
        run.interference = of_equilibrium(run.final, margin=margin)
    run.compiling = clock.compiling() - compiled
    return run


def _record(eq: Equilibrium3D, grip: str, progress: float, margin: float,
            seconds: float) -> StepRecord:
    load = eq.loads[grip]
    report = of_equilibrium(eq, margin=margin, subdivide=4)
    nearest = report.smallest
    contacts = eq.contacts
    radius, at = eq.min_bend_radius()
    station = next(c for c in eq.problem.conditions if c.name == grip)
    position = eq.position[int(np.argmin(np.abs(eq.s - station.s)))]
    return StepRecord(
        progress=progress, grip_position=triple(position),
        force=triple(load.force), moment=triple(load.moment),
        clearance=float(nearest.clearance) if nearest else float("inf"),
        nearest=nearest.obstacle if nearest else "",
        contacts=len(contacts),
        contact_force=float(np.linalg.norm(contacts.force, axis=1).sum()),
        bend_radius=float(radius), bend_at=float(at), stable=eq.stable,
        snap=jumped(eq.notes), seconds=seconds,
        clearances=tuple((c.obstacle, float(c.clearance)) for c in report.clearances))
