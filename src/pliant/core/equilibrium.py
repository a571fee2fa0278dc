"""The answer of a solve: shape, internal forces, reactions, energy, convergence facts.

Internal force convention (stated once, used everywhere): ``internal_force[i]`` and
``bending_moment[i]`` are the force [N] and moment [N m] that the part beyond s_i exerts on
the part before s_i, in the global frame. Then N = n . t (tension positive) and
Q = n . nu with t = (cos theta, sin theta), nu = (-sin theta, cos theta), and
M = EI (dtheta/ds - kappa0). At a station the arrays hold two samples, before and after
its jump.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from pliant.core.events import Event, Status
from pliant.core.events import events as as_events
from pliant.core.numbers import clean
from pliant.core.problem import Problem

# The note of an answer whose warm start could not be followed to its problem: the part
# was solved afresh, so between the two it jumped (a fold, a snap): the message of a
# ``pliant.core.events.WarmStartLost``, which callers test for.
WARM_START_LOST = ("the warm start could not be followed to this problem; solved from the "
                   "rest state instead")


# The smallest eigenvalue below which an equilibrium is neutral, relative to EI / L: the
# solvers' own accuracy (a mode a symmetry makes free comes out near 1e-12). The 3D test
# scales it by the internal loads' own size (``rod3d.stability.shift_bound``), to which
# the eigensolver's accuracy is relative.
NEUTRAL = 1e-8


def stability_verdict(stability: tuple[bool | None, float | None], part) -> str:
    """The word for (stable, smallest eigenvalue [N m]): neutral where the eigenvalue is
    zero to the solver's accuracy (within NEUTRAL EI / L, or not positive in a test that
    judged it not unstable)."""
    stable, eigen = stability
    if stable is None or eigen is None:
        return "undecided"
    if abs(eigen) <= NEUTRAL * part.bending_stiffness / part.length or (stable
                                                                       and eigen <= 0.0):
        return "neutral"
    return "stable" if stable else "unstable"


@dataclass(frozen=True, eq=False)
class Unsolved:
    """A solve that found no equilibrium, as ``pl.solve(..., throw=False)`` returns it:
    a search over many poses (planning, studies, sequences) asks instead of catching.
    The problem and the typed error; from it, why (``status``, a
    ``pliant.core.events.Status`` where a solver's path stopped), where (``residual``,
    ``progress`` in [0, 1]) and the last equilibrium it had (``last_good``). ``ok`` is
    False; an equilibrium's is True."""

    problem: Problem
    error: Exception
    ok: ClassVar[bool] = False

    @property
    def status(self) -> Status | None:
        return getattr(self.error, "status", None)

    @property
    def residual(self) -> float:
        return float(getattr(self.error, "residual", math.inf))

    @property
    def progress(self) -> float:
        return float(getattr(self.error, "progress", 0.0))

    @property
    def last_good(self) -> Any:
        return getattr(self.error, "last_good", None)

    @property
    def message(self) -> str:
        return str(self.error)


@runtime_checkable
class Result(Protocol):
    """What every equilibrium gives, 2D (``Equilibrium``) or 3D (``Equilibrium3D``):
    the interface the CLI, the session, the evaluation and the reports read, so that
    none of them asks which model answered. Arrays along s are per node; moments
    [N m] and forces [N] in the global frame; ``bending_magnitude`` is |M| without the
    twist (what bends the part), ``curvature`` the bending curvature's size."""

    @property
    def problem(self) -> Problem: ...
    @property
    def residual(self) -> float: ...
    @property
    def iterations(self) -> int: ...
    @property
    def steps(self) -> int: ...
    @property
    def notes(self) -> tuple[str, ...]: ...
    @property
    def state(self) -> Any: ...
    @property
    def status(self) -> Status: ...
    @property
    def events(self) -> tuple[Event, ...]: ...
    @property
    def stability(self) -> tuple[bool | None, float | None]: ...
    @property
    def stable(self) -> bool | None: ...
    @property
    def verdict(self) -> str: ...
    @property
    def s(self) -> np.ndarray: ...
    @property
    def position(self) -> np.ndarray: ...
    @property
    def tangent(self) -> np.ndarray: ...
    @property
    def energy(self) -> float: ...
    @property
    def loads(self) -> dict[str, StationLoad]: ...
    @property
    def reactions(self) -> dict[str, StationLoad]: ...
    @property
    def axial_force(self) -> np.ndarray: ...
    @property
    def elongation(self) -> float: ...
    @property
    def curvature(self) -> np.ndarray: ...
    @property
    def bending_magnitude(self) -> np.ndarray: ...
    def max_moment(self) -> tuple[float, float]: ...
    def min_bend_radius(self) -> tuple[float, float]: ...
    def to_dict(self) -> dict[str, Any]: ...


def _strain(part, axial: np.ndarray) -> np.ndarray:
    if part.axial_stiffness is None:
        return np.zeros_like(axial)
    return axial / part.axial_stiffness


def stretch_summary(eq) -> dict[str, Any] | None:
    """What pulling did to an extensible part: elongation [m], the largest axial force
    [N] and strain [-] and where (s [m]); None for an inextensible part."""
    part = eq.problem.part
    if part.axial_stiffness is None:
        return None
    force = np.asarray(eq.axial_force)
    i = int(np.argmax(np.abs(force)))
    s = np.asarray(eq.s)
    at = float(s[i] if len(s) == len(force) else 0.5 * (s[i] + s[i + 1]))
    return {"elongation": eq.elongation, "max_axial_force": float(force[i]),
            "max_axial_strain": float(force[i] / part.axial_stiffness), "at": at,
            "axial_stiffness": part.axial_stiffness}


def potential_energy(eq) -> float:
    """The elastic energy plus the potential of the dead loads [J]: the part's weight and
    the applied forces (and, in 2D, the applied couples, -M theta). Of two stable
    equilibria of one problem, the lower is where a real part is likelier to settle; a
    held component's reaction does no work (its position is fixed), so the same targets
    add the same constant to every branch. Meaningless with follower loads.

    For parts solved together (a 3D answer with harness branches or fitted parts it
    touched), the whole system's, so that two answers of one problem compare: the part's
    and each branch's, and each touched fitted part's change from its own untouched
    equilibrium (``FittedPart.solved``; the fitted parts not touched are as they were).
    Junctions, clips and contacts between the parts are internal: they add no work. Left
    out: the contacts' own spring energy (their compliance times f^2 / 2, 5e-4 J at 10 N
    against the wall compliance's 1e-5 m/N)."""
    total = _own_potential_energy(eq)
    for branch in getattr(eq, "branches", ()):
        total += _own_potential_energy(branch)
    touched = getattr(eq, "fitted", ())
    if touched:
        alone = {id(o.fitted.problem): o.fitted.solved for o in eq.problem.obstacles
                 if getattr(o, "fitted", None) is not None}
        for part in touched:
            rest = alone.get(id(part.problem))
            if rest is not None:
                total += _own_potential_energy(part) - _own_potential_energy(rest)
    return total


def _own_potential_energy(eq) -> float:
    """``potential_energy`` of one part: its elastic energy and its dead loads'."""
    problem = eq.problem
    s = np.asarray(eq.s)
    r = np.asarray(eq.position)
    dim = problem.dimension
    q = np.asarray(problem.dead_load_per_length, dtype=float)
    total = float(eq.energy)
    weighed = bool(q.any())  # (the terms below are zero without: 25 us of a 2D solve's 1 ms)
    if weighed:
        total -= float(np.trapezoid(r @ q, s))
    if dim == 2 and weighed:
        # The smooth shape's samples: each interval's integral of its cubic Hermite
        # reading (the tangent is the position's derivative), an error like h^4, where
        # the trapezoid's h^2 left 4e-5 of a hanging part's energy (two answers of one
        # equilibrium on different samples then differed by that).
        angle = np.asarray(eq.angle)
        slope = np.cos(angle) * q[0] + np.sin(angle) * q[1]  # d(r . q) / ds
        h = np.diff(s)
        total -= float(np.sum(h**2 * (slope[:-1] - slope[1:]))) / 12.0
    for ld in problem.partial_loads:  # a dead load on a stretch: its work there
        if ld.follower:
            continue
        a, b = ld.span(problem.part.length)
        grid = np.union1d(s[(s > a) & (s < b)], [a, b])
        on = np.column_stack([np.interp(grid, s, r[:, k]) for k in range(dim)])
        total -= float(np.trapezoid(on @ np.asarray(ld.force, dtype=float), grid))
    for ld in eq.loads.values():
        if all(ld.prescribed):  # a reaction does no work
            continue
        at = np.array([np.interp(ld.s, s, r[:, k]) for k in range(dim)])
        for k in range(dim):
            if not ld.prescribed[k]:
                total -= float(ld.force[k]) * float(at[k])
        if dim == 2 and not ld.prescribed[2]:
            total -= float(ld.moment) * float(np.interp(ld.s, s, eq.angle))
    return total


def bow_side(eq) -> str:
    """A shape's summary in a few words, to tell equilibria of one problem apart: which
    side of the chord between its ends the part's middle lies on (2D, looking from the
    first end to the last: left, right or neither side); in 3D the direction it bows in
    from the chord, or straight."""
    r = np.asarray(eq.position, dtype=float)
    a, b = r[0], r[-1]
    chord = b - a
    if r.shape[1] == 3:
        mid = r[len(r) // 2] - a
        across = mid - (mid @ chord) / max(float(chord @ chord), 1e-300) * chord
        size = float(np.linalg.norm(across))
        if size <= 1e-9 * max(float(np.linalg.norm(chord)), 1e-300):
            return "straight"
        return "toward (" + ", ".join(f"{x:+.2f}" for x in across / size) + ")"
    mid = r[len(r) // 2]
    cross = chord[0] * (mid[1] - a[1]) - chord[1] * (mid[0] - a[0])
    if abs(cross) <= 1e-9 * max(float(np.dot(chord, chord)), 1e-300):
        return "neither side"
    return "left" if cross > 0 else "right"


@dataclass(frozen=True)
class StationLoad:
    """The load a condition applies to the part at its station.

    force : (2,) or (3,) float [N], global frame; moment : float [N m], counter-clockwise
        (2D), or (3,) float [N m] (3D).
    prescribed : which components are reactions (their pair was prescribed): (Fx, Fy,
        moment) in 2D, (Fx, Fy, Fz, moment normal to the axis, twisting moment) in 3D;
        the others are the loads that were applied (a follower force is resolved into
        the global frame at the deformed angle).
    """

    name: str
    s: float
    force: np.ndarray
    moment: Any
    prescribed: tuple[bool, ...]

    @property
    def is_reaction(self) -> bool:
        return any(self.prescribed)

    def to_dict(self) -> dict[str, Any]:
        """As written to JSON: a component that is round-off beside its vector's size
        (``numbers.clean``) as the 0 it is."""
        moment = (float(self.moment) if np.ndim(self.moment) == 0 else clean(self.moment))
        return {"name": self.name, "s": self.s, "force": clean(self.force),
                "moment": moment, "prescribed": list(self.prescribed)}


class PlanarArrays(Protocol):
    """What a 2D warm start reads of a shape (an equilibrium, a ``PlanarShape``, an
    energy minimum): its arrays along s and the loads at its stations by name (each
    with ``force`` (2,) [N] and ``moment`` [N m])."""

    @property
    def s(self) -> np.ndarray: ...
    @property
    def position(self) -> np.ndarray: ...
    @property
    def angle(self) -> np.ndarray: ...
    @property
    def internal_force(self) -> np.ndarray: ...
    @property
    def bending_moment(self) -> np.ndarray: ...
    @property
    def loads(self) -> Mapping[str, Any]: ...


@dataclass(frozen=True)
class PlanarLoad:
    """A 2D station's load on the part, as a warm start reads it: force (2,) [N], global
    frame; moment [N m], counter-clockwise."""

    force: np.ndarray
    moment: float


@dataclass(frozen=True, eq=False)
class PlanarShape:
    """A 2D shape with its internal and station loads that no 2D solve produced: the
    mirror twin of an equilibrium, the 3D rod's answer in the plane. What a 2D warm
    start reads (``elastica2d.lowering.Lowered.unknowns_from``); no solver state to
    reuse and nothing said of it."""

    problem: Any
    s: np.ndarray
    position: np.ndarray
    angle: np.ndarray
    internal_force: np.ndarray
    bending_moment: np.ndarray
    loads: dict[str, PlanarLoad]
    notes: tuple = ()
    state: None = None


def model_loads(eq: Any) -> dict[str, StationLoad]:
    """The loads at the stations the model holds (a hand over a length at its heel, not
    as ``loads`` reports it): what a warm start and a check against the model read."""
    samples = getattr(eq, "samples", None)
    return samples.loads if samples is not None else eq.loads


def held_over_length(loads: dict[str, StationLoad], problem: Any) -> dict[str, StationLoad]:
    """The loads with each hand held over a length (``Condition.grip_length``) as the
    hand's whole wrench: the force its heel's clamp gives (which carries the stretch in
    the hand too), the moment carried to the middle of the stretch, and that middle's
    s."""
    held = getattr(problem, "held_lengths", ())
    if not held:
        return loads
    out = dict(loads)
    for name, middle, lever in held:
        load = out.get(name)
        if load is None:
            continue
        f = np.asarray(load.force, float)
        if len(lever) == 3:
            moment: Any = np.asarray(load.moment, float) + np.cross(lever, f)
        else:
            moment = float(load.moment) + lever[0] * f[1] - lever[1] * f[0]
        out[name] = StationLoad(name, middle, f, moment, load.prescribed)
    return out


@dataclass(frozen=True, eq=False)
class Samples:
    """The arrays of an equilibrium along s (see ``Equilibrium``)."""

    s: np.ndarray
    position: np.ndarray
    angle: np.ndarray
    internal_force: np.ndarray
    bending_moment: np.ndarray
    energy: float
    loads: dict[str, StationLoad]


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """An equilibrium of a 2D problem.

    residual : float, the largest boundary residual where the solver stopped, relative
        (lengths by L, forces by EI/L^2, moments by EI/L)
    iterations : Newton iterations in all; steps : continuation steps taken
    notes : facts the user should know (a bifurcation passed, a branch chosen)
    state : the solver's own data for warm starts (opaque)

    The arrays are computed on first access (a solve in an interactive loop need not
    pay for them): s : (n,) float [m]; position : (n, 2) float [m]; angle : (n,) float
    [rad]; internal_force : (n, 2) float [N]; bending_moment : (n,) float [N m];
    energy : float [J], the elastic bending energy; loads : the load of every condition,
    by name (reactions where prescribed).
    """

    ok: ClassVar[bool] = True  # an equilibrium (``Unsolved``: none)
    problem: Problem
    residual: float
    iterations: int
    steps: int
    sampler: Callable[[], Samples] = field(repr=False)
    notes: tuple[str, ...] = ()
    state: Any = field(default=None, repr=False)
    stability_check: Callable[[Any], tuple[bool | None, float | None]] | None = field(
        default=None, repr=False)

    @cached_property
    def samples(self) -> Samples:
        return self.sampler()

    @cached_property
    def stability(self) -> tuple[bool | None, float | None]:
        """(stable, smallest eigenvalue [N m] of the second variation on the variations
        the conditions allow, in the metric int dtheta^2 ds / L); (None, None) with
        follower loads (not conservative: a static test does not decide). Computed on
        first access (``pliant.models.elastica2d.stability``)."""
        if self.stability_check is None:
            return None, None
        return self.stability_check(self)

    @property
    def stable(self) -> bool | None:
        return self.stability[0]

    @property
    def verdict(self) -> str:
        """"stable", "neutral" (a mode that costs no energy), "unstable" or "undecided"."""
        return stability_verdict(self.stability, self.problem.part)

    # An answer converged (a solver that cannot converge raises ``ConvergenceError``
    # with its own ``status``).
    status = Status.CONVERGED

    @property
    def events(self) -> tuple[Event, ...]:
        """The notes as typed records (``pliant.core.events``): the branch taken, a
        snap, a lost warm start, a lower equilibrium found."""
        return as_events(self.notes)

    @property
    def s(self) -> np.ndarray:
        return self.samples.s

    @property
    def position(self) -> np.ndarray:
        return self.samples.position

    @property
    def angle(self) -> np.ndarray:
        return self.samples.angle

    @property
    def internal_force(self) -> np.ndarray:
        return self.samples.internal_force

    @property
    def bending_moment(self) -> np.ndarray:
        return self.samples.bending_moment

    @property
    def bending_magnitude(self) -> np.ndarray:
        """|M| along s [N m] (see ``Result``)."""
        return np.abs(np.asarray(self.bending_moment, float))

    @property
    def energy(self) -> float:
        return self.samples.energy

    @property
    def loads(self) -> dict[str, StationLoad]:
        return held_over_length(self.samples.loads, self.problem)

    @property
    def reactions(self) -> dict[str, StationLoad]:
        """The loads of the conditions with at least one prescribed component."""
        return {k: v for k, v in self.loads.items() if v.is_reaction}

    @property
    def tangent(self) -> np.ndarray:
        return np.column_stack([np.cos(self.angle), np.sin(self.angle)])

    @property
    def axial_force(self) -> np.ndarray:
        """N [N], tension positive."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        return self.internal_force[:, 0] * c + self.internal_force[:, 1] * s

    @property
    def axial_strain(self) -> np.ndarray:
        """N / EA [-] along the part (zeros for an inextensible one)."""
        return _strain(self.problem.part, self.axial_force)

    @property
    def elongation(self) -> float:
        """How much longer the part is than unloaded [m]: the integral of N / EA."""
        return float(np.trapezoid(self.axial_strain, self.s))

    @property
    def shear_force(self) -> np.ndarray:
        """Q [N], along the left normal nu = (-sin theta, cos theta)."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        return -self.internal_force[:, 0] * s + self.internal_force[:, 1] * c

    @property
    def curvature(self) -> np.ndarray:
        """dtheta/ds [1/m] = kappa0 + M / EI."""
        part = self.problem.part
        kappa0 = part.rest_darboux_along(self.s)[:, 0]
        return kappa0 + self.bending_moment / part.bending_stiffness

    @property
    def tip(self) -> tuple[float, float, float]:
        """(x [m], y [m], angle [rad]) at s = L."""
        return (float(self.position[-1, 0]), float(self.position[-1, 1]),
                float(self.angle[-1]))

    def max_moment(self) -> tuple[float, float]:
        """(|M| max [N m], s [m] where it occurs)."""
        i = int(np.argmax(np.abs(self.bending_moment)))
        return float(abs(self.bending_moment[i])), float(self.s[i])

    def min_bend_radius(self) -> tuple[float, float]:
        """(smallest bend radius [m], s [m] where it occurs); inf for a straight part."""
        kappa = np.abs(self.curvature)
        i = int(np.argmax(kappa))
        radius = math.inf if kappa[i] == 0.0 else 1.0 / float(kappa[i])
        return radius, float(self.s[i])

    def to_dict(self) -> dict[str, Any]:
        """The full result as plain JSON-ready data (SI units)."""
        return {
            "problem": self.problem.name,
            "s": self.s.tolist(),
            "x": self.position[:, 0].tolist(),
            "y": self.position[:, 1].tolist(),
            "angle": self.angle.tolist(),
            "N": self.axial_force.tolist(),
            "Q": self.shear_force.tolist(),
            "M": self.bending_moment.tolist(),
            "internal_force": self.internal_force.tolist(),
            "loads": {k: v.to_dict() for k, v in self.loads.items()},
            "tip": list(self.tip),
            "energy": self.energy,
            "max_moment": list(self.max_moment()),
            "min_bend_radius": list(self.min_bend_radius()),
            "stretch": stretch_summary(self),
            "stable": self.stability[0],
            "smallest_eigenvalue": self.stability[1],
            "stability": self.verdict,
            "residual": self.residual,
            "iterations": self.iterations,
            "steps": self.steps,
            "notes": list(self.notes),
            "status": self.status.value,
            "events": [e.to_dict() for e in self.events],
            "units": {"length": "m", "force": "N", "moment": "N m", "angle": "rad",
                      "energy": "J", "smallest_eigenvalue": "N m"},
        }


@dataclass(frozen=True, eq=False)
class Contacts:
    """The contact forces on a part, one row per touching point.

    s (k,) [m] where along the part; point (k, 3) [m] the point of the neutral line;
    force (k, 3) [N] what the obstacle applies to the part, friction included; obstacle
    (k,) the obstacle's name; friction (k, 3) [N] the part of force along the surface
    (zero without friction). A distributed contact shows as several neighbouring rows.
    """

    s: np.ndarray
    point: np.ndarray
    force: np.ndarray
    obstacle: tuple[str, ...]
    friction: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.friction is None:
            object.__setattr__(self, "friction", np.zeros_like(self.force))

    def __len__(self) -> int:
        return int(self.s.shape[0])

    def by_obstacle(self) -> dict[str, np.ndarray]:
        """The total force [N] each obstacle applies to the part."""
        out: dict[str, np.ndarray] = {}
        for name, f in zip(self.obstacle, self.force):
            out[name] = out.get(name, np.zeros(3)) + f
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"s": self.s.tolist(), "point": self.point.tolist(),
                "force": self.force.tolist(), "friction": np.asarray(self.friction).tolist(),
                "obstacle": list(self.obstacle)}


NO_CONTACTS = Contacts(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), ())


@dataclass(frozen=True, eq=False)
class Samples3D:
    """The arrays of a 3D equilibrium (see ``Equilibrium3D``)."""

    s: np.ndarray
    position: np.ndarray
    frames: np.ndarray
    element_s: np.ndarray
    internal_force: np.ndarray
    internal_moment: np.ndarray
    energy: float
    loads: dict[str, StationLoad]
    contacts: Contacts = NO_CONTACTS


@dataclass(frozen=True, eq=False)
class Equilibrium3D:
    """An equilibrium of a 3D problem (the discrete rod).

    residual, iterations, steps, notes, state : as in 2D.

    The arrays are computed on first access: s : (N+1,) float [m], the nodes;
    position : (N+1, 3) float [m]; frames : (N+1, 3, 3) float, the material frame at each
    node (columns d1, d2, d3, d3 the tangent); element_s : (N,) float [m], element
    midpoints; internal_force : (N, 3) float [N], the force the part beyond exerts on the
    part before, global frame, per element; internal_moment : (N+1, 3) float [N m], the
    moment the part beyond exerts on the part before, global frame, at the nodes;
    loads : the load (force (3,) [N], moment (3,) [N m], global frame) every condition
    applies to the part, by name (reactions where prescribed); contacts : the forces
    obstacles apply to it (``Contacts``); energy : float [J], the elastic energy (bending
    and torsion). Stability is computed on first access too.
    """

    ok: ClassVar[bool] = True  # an equilibrium (``Unsolved``: none)
    problem: Problem
    residual: float
    iterations: int
    steps: int
    sampler: Callable[[], Samples3D] = field(repr=False)
    notes: tuple[str, ...] = ()
    state: Any = field(default=None, repr=False)
    stability_check: Callable[[], tuple[bool | None, float | None]] | None = field(
        default=None, repr=False)
    # The flexible parts already fitted that this part touched, as they deformed: each
    # the Equilibrium3D of its own problem, its clamps' reactions with the contact on it.
    fitted: tuple[Equilibrium3D, ...] = field(default=(), repr=False)
    # A harness's branches (the problem's junctions), each the Equilibrium3D of its own
    # problem, with what its junction applies to it among its loads.
    branches: tuple[Equilibrium3D, ...] = field(default=(), repr=False)
    # The reactions' relative discretisation error, estimated from the same equilibrium
    # on twice the elements (Richardson's rule; a cold solve without contact), or None.
    reaction_error: float | None = None

    @cached_property
    def samples(self) -> Samples3D:
        return self.sampler()

    @property
    def s(self) -> np.ndarray:
        return self.samples.s

    @property
    def position(self) -> np.ndarray:
        return self.samples.position

    @property
    def frames(self) -> np.ndarray:
        return self.samples.frames

    @property
    def element_s(self) -> np.ndarray:
        return self.samples.element_s

    @property
    def internal_force(self) -> np.ndarray:
        return self.samples.internal_force

    @property
    def internal_moment(self) -> np.ndarray:
        return self.samples.internal_moment

    @property
    def energy(self) -> float:
        return self.samples.energy

    @property
    def loads(self) -> dict[str, StationLoad]:
        return held_over_length(self.samples.loads, self.problem)

    @property
    def contacts(self) -> Contacts:
        return self.samples.contacts

    @cached_property
    def stability(self) -> tuple[bool | None, float | None]:
        """(stable, smallest eigenvalue of the constrained Hessian [N m]) for
        conservative loads; (None, None) where follower loads or dead moments make the
        problem non-conservative (a static test does not decide their stability). The
        eigenvalue is taken in the metric of the part's length (each unknown weighed by
        the length it stands for), so it converges as the mesh is refined; where the
        equilibrium is unstable it is the negative eigenvalue nearest zero."""
        if self.stability_check is None:
            return None, None
        return self.stability_check()

    @property
    def stable(self) -> bool | None:
        return self.stability[0]

    @property
    def verdict(self) -> str:
        """"stable", "neutral" (a mode that costs no energy: the part can move along a
        family of equilibria, such as a round strip turning about its chord), "unstable"
        or "undecided" (non-conservative loads)."""
        return stability_verdict(self.stability, self.problem.part)

    @property
    def reactions(self) -> dict[str, StationLoad]:
        return {k: v for k, v in self.loads.items() if v.is_reaction}

    status = Status.CONVERGED  # as in 2D

    @property
    def events(self) -> tuple[Event, ...]:
        """The notes as typed records (see ``Equilibrium.events``)."""
        return as_events(self.notes)

    @property
    def tangent(self) -> np.ndarray:
        return self.frames[:, :, 2]

    @property
    def tip(self) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,) [m], tangent (3,)) at s = L."""
        return self.position[-1].copy(), self.frames[-1, :, 2].copy()

    @property
    def torque(self) -> np.ndarray:
        """(N+1,) [N m], the twisting moment about the tangent."""
        return np.einsum("ij,ij->i", self.internal_moment, self.tangent)

    @property
    def axial_force(self) -> np.ndarray:
        """(N,) [N], tension positive, per element."""
        d3 = self.position[1:] - self.position[:-1]
        d3 /= np.linalg.norm(d3, axis=1)[:, None]
        return np.einsum("ij,ij->i", self.internal_force, d3)

    @property
    def axial_strain(self) -> np.ndarray:
        """(N,) N / EA [-] per element (zeros for an inextensible part)."""
        return _strain(self.problem.part, self.axial_force)

    @property
    def elongation(self) -> float:
        """How much longer the part is than unloaded [m]: its elements' strains times
        their unloaded lengths."""
        return float(self.axial_strain @ np.diff(self.s))

    @property
    def curvature(self) -> np.ndarray:
        """(N+1,) [1/m], the bending curvature |kappa| at the nodes (twist excluded)."""
        part = self.problem.part
        ei1, ei2, _ = part.stiffnesses
        local = np.einsum("nji,nj->ni", self.frames, self.internal_moment)
        rest = part.rest_darboux_along(self.s)
        k1 = local[:, 0] / ei1 + rest[:, 0]
        k2 = local[:, 1] / ei2 + rest[:, 1]
        return np.hypot(k1, k2)

    @property
    def bending_magnitude(self) -> np.ndarray:
        """(N+1,) [N m], |M| at the nodes without the twist (what bends the part)."""
        m = np.asarray(self.internal_moment, float)
        t = np.asarray(self.tangent, float)
        return np.linalg.norm(m - np.einsum("ij,ij->i", m, t)[:, None] * t, axis=1)

    def max_moment(self) -> tuple[float, float]:
        """(|M| max [N m] (bending and torsion), s [m] where it occurs)."""
        norms = np.linalg.norm(self.internal_moment, axis=1)
        i = int(np.argmax(norms))
        return float(norms[i]), float(self.s[i])

    def min_bend_radius(self) -> tuple[float, float]:
        """(smallest bend radius [m], s [m]); inf for a straight part."""
        kappa = self.curvature
        i = int(np.argmax(kappa))
        return (math.inf if kappa[i] == 0.0 else 1.0 / float(kappa[i])), float(self.s[i])

    def to_dict(self) -> dict[str, Any]:
        stable, eigen = self.stability
        return {
            "problem": self.problem.name,
            "dimension": 3,
            "s": self.s.tolist(),
            "position": self.position.tolist(),
            "frames": self.frames.tolist(),
            "element_s": self.element_s.tolist(),
            "internal_force": self.internal_force.tolist(),
            "internal_moment": self.internal_moment.tolist(),
            "loads": {k: v.to_dict() for k, v in self.loads.items()},
            "contacts": self.contacts.to_dict(),
            "tip": [clean(self.tip[0]), clean(self.tip[1])],
            "energy": self.energy,
            "max_moment": list(self.max_moment()),
            "min_bend_radius": list(self.min_bend_radius()),
            "stretch": stretch_summary(self),
            "stable": stable,
            "smallest_eigenvalue": eigen,
            "stability": self.verdict,
            "residual": self.residual,
            "reaction_error": self.reaction_error,
            "iterations": self.iterations,
            "steps": self.steps,
            "notes": list(self.notes),
            "status": self.status.value,
            "events": [e.to_dict() for e in self.events],
            "units": {"length": "m", "force": "N", "moment": "N m", "energy": "J"},
        }
