"""Find a path for the grip: from the scene's start pose to the pose that seats the
part's end in a port, through stable equilibria of the accurate 3D model only.

The planner is OMPL's RRT over the hand's pose, and a motion validator that knows the
part is flexible:

- **The hand's pose in five coordinates** (``RealVectorStateSpace(5)``): its position,
  and its axis (the direction it holds the part's end along; its roll follows the
  turn, as along a scene's [path]) as (u, v) on a band of the sphere: u turns the axis
  along the great circle from its start direction to the one the port needs (and up to
  30 degrees past either), v tilts it off that circle by up to 60 degrees. Both are in
  metres of the metric (``rotation_length`` per radian), so that a turn of the hand
  weighs against a move. Two earlier designs were measured and dropped: the axis
  anywhere on the sphere (SE(3), uniform samples of the axis) mostly samples poses a
  hand would not take, and on the bundled engine bay 950 solves in 20 s did not reach
  the port; a relaxed wrist (the end held by position only, its axis the part's own)
  makes the engine bay's start unstable once the hand's moment is released (smallest
  eigenvalue -1.86: the line would swing over).
- **A pose's shape is the one reached along the tree.** A flexible part held at a pose
  can sit in several equilibria; which one it is in depends on how the hand got there.
  Every node of the tree stores the equilibrium reached by continuation along the edges
  from the start (``_Tree``), and an edge is checked by following the part from its
  first node's equilibrium to its last pose in steps (warm solves that may not jump to
  another branch). A single tree grown from the start is the faithful model of this
  hysteresis: a second tree grown from the goal (RRT-Connect) would need the seated
  shape before the route to it is known, and that shape depends on the route (the
  bundled engine bay, solved cold at the port, reaches a shape pressed on the manifold
  after a snap, in 6 s).
- **A step is valid** when it converges without a fold (the part keeps its shape), its
  tube keeps the scene's margin from every obstacle (or only stays out of them, with
  ``allow_contact``), no obstacle presses harder than ``max_contact_force``, and the
  part keeps the evaluation's damage limits that apply along a path: its bend radius,
  a thin-walled tube's flattening (Brazier, as a radius) and a cable's twist rate (when
  ``max_twist_rate`` is given); the edge's last pose must be stable. What blocked each rejected
  edge is counted: the error of a failed plan says
  what stood in the way.
- **The cost is the evaluation's ergonomic demand**: at each step, the largest ratio of
  a hand demand (push or pull, grip force, wrist twist, bending at the hand) to its red
  onset in the rules table. A node keeps the worst ratio on its way from the start; the
  shortcuts that simplify the found path keep every step valid and never raise it, and
  with time left further trees (``attempts``) are grown and the path of least peak
  demand is kept.
- **The last leg enters the port along its axis**: the tree's goal is the point
  ``approach`` metres out along the port's axis, holding the axis the port needs (within
  ``goal_tolerance`` in the metric: a last straight leg goes there); from it the hand
  pushes the end straight in (that leg may touch the port's own parts: it is only kept
  out of obstacles). The insertion force is evaluated at the last step.

The found path is written as the scene's [path] (a waypoint every ``step``, with the
axis the part had there), and that path is followed again at its own step count, as
``pliant run`` would, and evaluated (``pliant.assembly.evaluate``): a plan whose path
does not hold when followed so is discarded and the search goes on.

A ``Planner`` keeps its trees of equilibria, one per port: a second query to that port
(another seed, more time) reuses every motion already followed without a solve. A seed makes a plan
reproducible: OMPL's samplers are seeded before the planner is built, and the search
stops when the goal is reached, not when a clock runs out (it fails only on the clock).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pliant.assembly.access import hand_access
from pliant.assembly.checks import tube_section
from pliant.assembly.evaluate import (
    PENETRATION,
    bend_limit,
    grip_step,
    hand_rows,
    prepare,
    twist_rate,
)
from pliant.assembly.path import along_legs, carried_conditions, carry_with, follow_path, slerp
from pliant.core.equilibrium import Equilibrium3D
from pliant.core.numbers import triple
from pliant.core.planning import PlanSettings
from pliant.core.problem import Problem
from pliant.errors import ConvergenceError, InputError, PliantError, UnreachableTargetError
from pliant.models import clock, rod3d
from pliant.scene.distance import DistanceField
from pliant.scene.interference import of_equilibrium
from pliant.util.interrupts import on_ctrl_c


class NoPathError(PliantError):
    """No path was found within the budget.

    closest : the pose of the tree nearest the goal (a ``Pose``), distance : how far it
    is from the goal in the planner's metric [m], blocked : what rejected the motions
    tried ({reason: count}), seconds : the time spent on the budget's clock (this
    thread's CPU time, ``pliant.models.clock``), solves : accurate solves made.
    """

    def __init__(self, message: str, *, closest: Pose | None, distance: float,
                 blocked: dict[str, int], seconds: float, solves: int) -> None:
        self.closest = closest
        self.distance = distance
        self.blocked = blocked
        self.seconds = seconds
        self.solves = solves
        super().__init__(message)


@dataclass(frozen=True)
class Pose:
    """Where the hand holds the part: position [m] and the unit axis it holds the
    part's end along (the part's tangent there, pointing from s = 0 to s = L)."""

    position: tuple[float, float, float]
    tangent: tuple[float, float, float]

    def __str__(self) -> str:
        p = ", ".join(f"{x:.3f}" for x in self.position)
        t = ", ".join(f"{x:.2f}" for x in self.tangent)
        return f"({p}) m holding the axis ({t})"


@dataclass
class Plan:
    """A found path: the hand's poses from the start (excluded) to the seated pose
    (``poses``; the last is at the port), the problems along it at the scene's step
    count (``path``) and their run (``run``: every step solved again, in order), the
    peak ergonomic demand (the largest ratio of a hand demand to its red onset; per step
    in ``demands``), and what the search cost: seconds, accurate solves, motions
    checked, trees grown, nodes in the tree, the path's step count, and how many of the
    poses its search went through were reached by an earlier query (``reused``)."""

    grip: str
    port: str
    poses: list[Pose]
    path: list[Problem]
    run: Any
    peak_demand: float
    demands: list[float]
    seconds: float
    solves: int
    motions: int
    trees: int
    nodes: int
    steps: int
    reused: int = 0
    carry: tuple[str, ...] = ()  # the hands carried with the grip

    def path_table(self) -> str:
        """The path as a scene's [path] table (TOML): a waypoint and the hand's axis at
        every step of the planned legs."""
        def vec(v) -> str:
            return "[" + ", ".join(f"{float(x):.6g}" for x in v) + "]"

        return "\n".join([
            (f"[path]                         # planned by `pliant plan` into {self.port!r}: "
             f"peak hand demand {self.peak_demand:.2f} of the red onset"),
            f"grip = {json.dumps(self.grip, ensure_ascii=False)}",  # TOML's escapes too
            "waypoints = [", *[f"    {vec(p.position)}," for p in self.poses], "]",
            "tangents = [", *[f"    {vec(p.tangent)}," for p in self.poses], "]",
            f"steps = {self.steps}",
            *([f"carry = {json.dumps(list(self.carry), ensure_ascii=False)}"]
              if self.carry else []), ""])

    @property
    def cost(self) -> tuple[float, float]:
        """What the planner minimises: the peak hand demand once the part is moving
        (the start is given), then the mean over the steps."""
        values = self.demands[1:] or self.demands
        return (round(max(values), 3), float(np.mean(values)))

    def summary(self) -> dict[str, Any]:
        return {"grip": self.grip, "port": self.port, "peak_demand": self.peak_demand,
                "seconds": self.seconds, "solves": self.solves, "motions": self.motions,
                "trees": self.trees, "nodes": self.nodes, "steps": self.steps,
                "reused": self.reused,
                "waypoints": [list(p.position) for p in self.poses],
                "tangents": [list(p.tangent) for p in self.poses]}


# -- geometry -----------------------------------------------------------------------------
def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


# -- the hand's axis ----------------------------------------------------------------------
@dataclass(frozen=True)
class _Turning:
    """The axes the hand may hold, as coordinates (u, v) in metres of the planner's
    metric: u turns the axis along the great circle from its start direction to the one
    it must hold at the port (0 at the start, ``length`` at the port, and a little past
    either), v tilts it off that circle toward its pole (up to 60 degrees either way)."""

    start: np.ndarray
    normal: np.ndarray
    angle: float
    metre: float  # [m per rad]

    OVER = math.radians(30.0)
    TILT = math.radians(60.0)

    @classmethod
    def between(cls, t0, t1, toward, rotation_length: float) -> _Turning:
        """From axis t0 to t1; when they are opposite, turning toward ``toward``."""
        t0, t1 = _unit(t0), _unit(t1)
        angle = math.acos(max(-1.0, min(1.0, float(t0 @ t1))))
        normal = np.cross(t0, t1)
        if np.linalg.norm(normal) < 1e-6:
            normal = np.cross(t0, np.asarray(toward, dtype=float))
            if np.linalg.norm(normal) < 1e-6 * max(1.0, float(np.linalg.norm(toward))):
                normal = np.cross(t0, [1.0, 0.0, 0.0] if abs(t0[0]) < 0.9 else [0.0, 1.0, 0.0])
        return cls(t0, _unit(normal), angle, rotation_length)

    @property
    def length(self) -> float:
        """u at the port's axis."""
        return self.angle * self.metre

    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]:
        return ((-self.OVER * self.metre, (self.angle + self.OVER) * self.metre),
                (-self.TILT * self.metre, self.TILT * self.metre))

    def coordinates(self, axis) -> tuple[float, float] | None:
        """(u, v) of a unit axis, or None where it lies outside the band."""
        a = _unit(axis)
        t, n = self.start, self.normal
        lat = math.asin(max(-1.0, min(1.0, float(n @ a))))
        flat = a - float(n @ a) * n
        lon = math.atan2(float(np.cross(n, t) @ flat), float(t @ flat))
        if lon < -self.OVER - 1e-9:
            lon += 2.0 * math.pi
        (u_lo, u_hi), (v_lo, v_hi) = self.bounds()
        u, v = lon * self.metre, lat * self.metre
        if not (u_lo - 1e-12 <= u <= u_hi + 1e-12 and v_lo - 1e-12 <= v <= v_hi + 1e-12):
            return None
        return u, v

    def axis(self, u: float, v: float) -> tuple[float, float, float]:
        lon, lat = u / self.metre, v / self.metre
        t, n = self.start, self.normal
        along = t * math.cos(lon) + np.cross(n, t) * math.sin(lon)
        return triple(_unit(math.cos(lat) * along + math.sin(lat) * n))


# -- the search tree ----------------------------------------------------------------------
@dataclass(repr=False)
class _Node:
    """A pose reached: the hand's pose, the equilibrium there, the largest demand ratio
    on the way from the start, the waypoints of the edge that led here (for the written
    path), and the node it was reached from (None: the start)."""

    pose: Pose
    eq: Equilibrium3D
    peak: float
    via: tuple[Pose, ...] = ()
    parent: _Node | None = field(default=None, repr=False)
    query: int = 0  # the planner's query that reached it (0: the start)

    def chain(self) -> list[_Node]:
        """The nodes from the start to this one."""
        out: list[_Node] = []
        node: _Node | None = self
        while node is not None:
            out.append(node)
            node = node.parent
        return out[::-1]


class _Blocked(Exception):
    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(reason)


@dataclass(repr=False)
class _Tree:
    """The equilibria reached, by position, and the rules a step is checked against."""

    scene: Any
    grip: str
    settings: PlanSettings
    rules: Any
    solver: Any
    bend_limit: float | None
    turning: _Turning
    kink_limit: float | None = None
    twist_limit: float | None = None
    root: Any = None
    nodes: dict[tuple, _Node] = field(default_factory=dict)
    edges: dict[tuple, bool] = field(default_factory=dict)
    blocked: Counter = field(default_factory=Counter)
    solves: int = 0
    motions: int = 0
    deadline: float = math.inf
    interrupted: bool = False

    def interrupt(self) -> None:
        """Ctrl+C while planning: every motion is refused from now on and OMPL's search
        ends at its next check (a signal handler: no exception thrown through OMPL)."""
        self.interrupted = True
        self.deadline = -math.inf

    def problem_at(self, position, tangent) -> Problem:
        """The scene's problem with the grip at ``position`` holding the axis ``tangent``
        (its roll follows the turn, as along a scene's [path]), the hands it carries
        moved with it as one rigid carrier."""
        problem = self.scene.problem
        grip = problem.condition(self.grip)
        carried = carry_with(grip, position, tangent,
                             [problem.condition(n) for n in self.settings.carry])

        def moved(c):
            if c.name != self.grip:
                return carried.get(c.name, c)
            return replace(c, position=tuple(map(float, position)), normal=None,
                           tangent=tuple(map(float, tangent)))
        return replace(problem, conditions=tuple(moved(c) for c in problem.conditions))

    def demand(self, eq: Equilibrium3D) -> float:
        """The largest ratio of a hand demand at the grip (and the hands it carries) to
        its red onset."""

        settings = self.scene.evaluation
        rows = hand_rows(self.rules, settings, settings.hold)
        return max(grip_step(eq, g).wrench.demand(r.demand, self.rules.hand_friction)
                   / r.yellow for g in (self.grip, *self.settings.carry) for r in rows)

    def check_step(self, eq: Equilibrium3D, near_port: bool = False) -> None:
        """Raise ``_Blocked`` naming why the step ``eq`` is not acceptable."""

        if self.bend_limit is not None or self.kink_limit is not None:
            radius, _ = eq.min_bend_radius()
            if self.bend_limit is not None and radius < self.bend_limit:
                raise _Blocked(f"bend radius below {self.bend_limit * 1e3:.3g} mm")
            if self.kink_limit is not None and radius < self.kink_limit:
                raise _Blocked(f"a kink (Brazier: bend radius below "
                               f"{self.kink_limit * 1e3:.3g} mm)")
        if self.twist_limit is not None:

            if twist_rate(eq, self.scene.problem.part.stiffnesses[2]) > self.twist_limit:
                raise _Blocked(f"a twist rate above {self.twist_limit:.3g} deg/m")
        margin = self.scene.margin
        floor = -PENETRATION if (self.settings.allow_contact or near_port) else margin
        report = of_equilibrium(eq, margin=margin, subdivide=2)
        for c in report.clearances:
            if c.clearance < floor:
                raise _Blocked(f"clearance to {c.obstacle}")
        limit = self.scene.evaluation.max_contact_force
        if limit is not None and eq.contacts is not None:
            for name, f in eq.contacts.by_obstacle().items():
                if float(np.linalg.norm(f)) > limit:
                    raise _Blocked(f"contact force from {name}")
        # the hands move with the part: each envelope must fit round it from some side
        if self.rules.access is not None:
            for g in (self.grip, *self.settings.carry):
                room = hand_access(eq, eq.loads[g].s, self.rules.access,
                                   self.scene.evaluation.hold)
                if room.clearance < 0.0:
                    raise _Blocked(f"no room for the hand ({room.bound_by})")

    def _solve(self, problem: Problem, eq: Equilibrium3D) -> Equilibrium3D:
        """One step, followed from ``eq`` only: where its branch ends, the part would
        snap, and the step is refused rather than solved afresh."""

        if clock.now() > self.deadline:
            raise _Blocked("out of time")
        self.solves += 1
        try:
            return next(rod3d.trace([problem], start=eq, solver=self.solver))
        except ConvergenceError:
            raise _Blocked("a fold (the part would snap to another shape)") from None
        except UnreachableTargetError:
            raise _Blocked("out of reach") from None
        except PliantError as err:
            raise _Blocked(f"no equilibrium ({str(err).split(';')[0]})") from None

    def carry(self, start: _Node, point) -> _Node:
        """The node reached by carrying the hand from ``start`` straight to ``point``
        (x, y, z, u, v: its axis's coordinates in ``turning``) in steps; ``_Blocked``
        when a step is not acceptable."""
        uv = self.turning.coordinates(start.pose.tangent)
        if uv is None:
            raise _Blocked("an axis outside the turns planned")
        a, b = np.array([*start.pose.position, *uv]), np.asarray(point, dtype=float)
        turn = math.degrees(math.acos(max(-1.0, min(1.0, float(
            np.dot(start.pose.tangent, self.turning.axis(b[3], b[4])))))))
        n = max(1, math.ceil(float(np.linalg.norm(b[:3] - a[:3])) / self.settings.step),
                math.ceil(turn / self.settings.turn))
        poses = []
        for k in range(1, n + 1):
            x = a + (k / n) * (b - a)
            poses.append(Pose(triple(x[:3]), self.turning.axis(x[3], x[4])))
        return self._walk(start, poses, poses[-1], near_port=False)

    def turn_in(self, start: _Node, end: Pose, near_port: bool) -> _Node:
        """The node reached by taking hold of the end's axis at ``start`` and carrying
        the hand straight to ``end``, its axis turned onto ``end.tangent``."""
        a, b = np.asarray(start.pose.position), np.asarray(end.position)
        ta, tb = _unit(start.pose.tangent), _unit(end.tangent)
        angle = math.degrees(math.acos(max(-1.0, min(1.0, float(ta @ tb)))))
        if angle > 170.0:
            raise _Blocked("a half turn of the hand's axis in the last leg")
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / self.settings.step),
                math.ceil(angle / self.settings.turn))
        poses = [Pose(triple(a + (k / n) * (b - a)),
                      triple(_unit(slerp(ta, tb, k / n))))
                 for k in range(1, n + 1)]
        return self._walk(start, poses, end, near_port)

    def _walk(self, start: _Node, poses: list[Pose], end: Pose, near_port: bool) -> _Node:
        """The node at ``end`` reached by solving ``poses`` in turn from ``start``, each
        step checked; the last must be stable."""
        eq, peak = start.eq, start.peak
        for pose in poses:
            eq = self._solve(self.problem_at(pose.position, pose.tangent), eq)
            self.check_step(eq, near_port)
            peak = max(peak, self.demand(eq))
        if eq.stable is False:
            raise _Blocked("instability (the part would not stay in that shape)")
        return _Node(end, eq, peak, tuple(poses), start)

    def same_shape(self, a: Any, b: Any) -> bool:
        """Whether two equilibria at one pose are the same shape (not two branches)."""
        gap = float(np.abs(a.position - b.position).max())
        return gap < 1e-3 * self.scene.problem.part.length


def _key(position) -> tuple:
    return tuple(round(float(v), 9) for v in position)


# -- OMPL ---------------------------------------------------------------------------------
def _ompl():
    try:
        from ompl import base as ob  # noqa: PLC0415 (optional: only for planning)
        from ompl import geometric as og  # noqa: PLC0415
        from ompl import util as ou  # noqa: PLC0415
    except ImportError as err:  # pragma: no cover (a dependency of the package)
        raise PliantError(f"planning needs OMPL (pip install ompl): {err}") from None
    return ob, og, ou


class Planner:
    """Plans in one scene; every pose its trees reached (with its equilibrium) is kept
    between queries and seeds the next one's tree."""

    FOREST = 2000  # poses reached before that seed a new tree, at most (the latest)

    def __init__(self, scene: Any, settings: PlanSettings | None = None, *,
                 rules: Any = None, grip: str | None = None) -> None:

        self.scene = scene
        self.settings = settings or PlanSettings()
        rules, grips, _ = prepare(scene, rules)
        self.rules = rules
        if grip is None and not grips:
            raise InputError("plan.grip", "no condition is held by a hand: give [path] grip, "
                             "or hand = true on the [[condition]] to carry")
        self.grip = grip or grips[0]
        names = [c.name for c in scene.problem.conditions]
        if self.grip not in names:
            raise InputError("plan.grip", f"no condition named {self.grip!r}; known: "
                             f"{', '.join(names)}")
        condition = scene.problem.condition(self.grip)
        if condition.tangent is None or any(v is None for v in condition.position):
            raise InputError("plan.grip", f"{self.grip!r} must hold x, y, z and a tangent "
                             "(the hand's pose) to be planned for")
        carried_conditions(scene.problem, self.settings.carry, self.grip)
        if not any(c.name != self.grip and all(v is not None for v in c.position)
                   for c in scene.problem.conditions):
            raise InputError("plan", "nothing else holds the part in place: a plan carries "
                             "one end while the other is fitted (give it a port or x, y, z)")
        kind = rules.kind(scene.problem.part.kind)
        self.bend_limit = bend_limit(scene.problem.part, kind)[0]
        self.kink_limit = kink_radius(scene.problem.part, kind, rules)
        self.solver = rod3d.RodSolver(elements=self.settings.elements or scene.solver.elements)
        self.rotation_length = (self.settings.rotation_length
                                or 0.1 * scene.problem.part.length)
        self.trees: dict[str, _Tree] = {}
        self.forest: list[_Node] = []  # every pose reached from the start, any tree
        self.queries = 0
        self._start_eq: Equilibrium3D | None = None
        self._field: Any = None

    # -- the start and the goal -----------------------------------------------------------
    def start_pose(self) -> Pose:
        c = self.scene.problem.condition(self.grip)
        return Pose(triple(c.position), triple(_unit(c.tangent)))

    def goal_pose(self, port_name: str) -> tuple[Pose, np.ndarray]:
        """(the seated pose, the point ``approach`` out along the port's axis)."""
        ports = self.scene.ports
        if port_name not in ports:
            raise InputError("plan.goal", f"no [[port]] named {port_name!r}; known: "
                             f"{', '.join(ports) or 'none'}")
        port = ports[port_name]
        axis = _unit(port.axis)
        c = self.scene.problem.condition(self.grip)
        arriving = c.s > 0.5 * self.scene.problem.part.length
        tangent = triple(-axis if arriving else axis)
        seated = Pose(triple(port.position), tangent)
        return seated, np.asarray(port.position) + self.settings.approach * axis

    def tree(self, goal: str) -> _Tree:
        """The tree toward port ``goal``, its root the start pose (solved once)."""
        if goal in self.trees:
            return self.trees[goal]
        start = self.start_pose()
        seated, before = self.goal_pose(goal)
        turning = _Turning.between(start.tangent, seated.tangent,
                                   before - np.asarray(start.position), self.rotation_length)
        tree = _Tree(self.scene, self.grip, self.settings, self.rules, self.solver,
                     self.bend_limit, turning, self.kink_limit,
                     self.scene.evaluation.max_twist_rate)
        if self._start_eq is None:

            tree.solves += 1
            eq = rod3d.solve(tree.problem_at(start.position, start.tangent), solver=self.solver)
            try:
                tree.check_step(eq)
                if eq.stable is False:
                    raise _Blocked("it is unstable: the part would not stay in it")
            except _Blocked as why:
                fix = ("move the grip's start where a hand fits round the part"
                       if why.reason.startswith("no room for the hand") else
                       "move the grip's start, or plan with allow_contact (--allow-contact)")
                raise InputError("plan", f"the start pose is not acceptable: {why.reason}; "
                                 f"{fix}") from None
            self._start_eq = eq
        tree.root = _Node(start, self._start_eq, tree.demand(self._start_eq))
        tree.nodes[_key((*start.position, 0.0, 0.0))] = tree.root
        self.trees[goal] = tree
        return tree

    # -- one query ------------------------------------------------------------------------
    def plan(self, goal: str, *, on_progress: Callable[[str], None] | None = None) -> Plan:
        """A path for the grip to the port ``goal``; ``NoPathError`` within the budget
        when none is found; KeyboardInterrupt at once on Ctrl+C."""
        begin = clock.now()  # the budget's clock: what ``seconds`` reports too
        tree = self.tree(goal)  # checks the port first
        # The budget counts this thread's CPU time (``pliant.models.clock``): a loaded
        # machine does not turn a slower search into a refusal.
        tree.deadline = clock.now() + self.settings.budget
        tree.interrupted = False
        self.queries += 1
        with on_ctrl_c(tree.interrupt):
            return self._plan(tree, goal, begin, on_progress)

    def _plan(self, tree: _Tree, goal: str, begin: float,
              on_progress: Callable[[str], None] | None) -> Plan:
        s = self.settings
        seated, before = self.goal_pose(goal)
        solves0, motions0 = tree.solves, tree.motions
        best: Plan | None = None
        trees = paths = 0
        while paths < s.attempts:
            left = tree.deadline - clock.now()
            if left <= 0 or (best is not None and left < 0.3 * s.budget / s.attempts):
                break
            trees += 1
            found, reused = self._search(tree, before, s.seed + trees - 1)
            if found is None:
                continue
            try:  # to the point before the port, then straight in along its axis
                ready = Pose(triple(before), seated.tangent)
                nodes = list(found)
                if np.linalg.norm(np.subtract(found[-1].pose.position, before)) > 1e-9:
                    nodes.append(tree.turn_in(found[-1], ready, near_port=False))
                nodes.append(tree.turn_in(nodes[-1], seated, near_port=True))
            except _Blocked as why:
                tree.blocked[f"the last leg into the port: {why.reason}"] += 1
                continue
            result = self._result(tree, nodes, goal)
            result.reused = reused
            paths += 1
            broken = self._breaks(tree, result, seated)
            if broken is not None:
                tree.blocked[f"the written path, followed again: {broken}"] += 1
                continue
            if on_progress is not None:
                on_progress(f"tree {trees}: a path of {len(nodes) - 1} legs, peak "
                            f"hand demand {result.peak_demand:.2f} of the red onset")
            if best is not None and abs(result.cost[0] - best.cost[0]) < 5e-3 and (
                    abs(result.cost[1] - best.cost[1]) < 0.02 * best.cost[1]):
                break  # two trees, the same demand: the search has settled
            if best is None or result.cost < best.cost:
                best = result
        seconds = clock.now() - begin
        if tree.interrupted:
            raise KeyboardInterrupt
        if best is None:
            raise self._failure(tree, before, seconds, tree.solves - solves0)
        best.seconds, best.trees = seconds, trees
        best.solves, best.motions = tree.solves - solves0, tree.motions - motions0
        best.nodes = len(tree.nodes)
        return best

    def _search(self, tree: _Tree, goal: np.ndarray,
                seed: int) -> tuple[list[_Node] | None, int]:
        """Grow a tree from the start toward the point before the port with OMPL's RRT
        over (x, y, z, u, v), until the tree's deadline: the nodes of the path it finds,
        simplified (None: none found), and how many of them an earlier query reached."""
        ob, og, ou = _ompl()
        s = self.settings
        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)  # OMPL warns that seeding after its first use is late
        nodes, reused = None, 0
        try:
            ou.RNG.setSeed(seed)
            space = ob.RealVectorStateSpace(5)
            bounds = ob.RealVectorBounds(5)
            lo, hi = self._bounds(goal)
            for i in range(3):
                bounds.setLow(i, float(lo[i]))
                bounds.setHigh(i, float(hi[i]))
            for i, (low, high) in enumerate(tree.turning.bounds(), start=3):
                bounds.setLow(i, low)
                bounds.setHigh(i, high)
            space.setBounds(bounds)
            si = ob.SpaceInformation(space)
            si.setStateValidityChecker(self._valid_state)
            validator = _validator(ob)(si, self, tree)
            si.setMotionValidator(validator)
            si.setup()
            setup = og.SimpleSetup(si)
            target = si.allocState()
            for i in range(3):
                target[i] = float(goal[i])
            target[3], target[4] = tree.turning.length, 0.0
            setup.setGoalState(target, s.goal_tolerance)
            # The tree grows from the start and from every pose reached before in this
            # scene (toward any port, by any tree) whose axis its turns can express:
            # each keeps the equilibrium it was reached with, so the roadmap is reused.
            for node in [tree.root, *self.forest[-self.FOREST:]]:
                uv = tree.turning.coordinates(node.pose.tangent)
                if uv is None:
                    continue
                state = si.allocState()
                for i, x in enumerate((*node.pose.position, *uv)):
                    state[i] = float(x)
                tree.nodes.setdefault(_key(_point(state)), node)
                setup.addStartState(state)
            planner = og.RRT(si)
            planner.setRange(s.reach)
            planner.setGoalBias(s.goal_bias)
            setup.setPlanner(planner)
            status = setup.solve(ob.PlannerTerminationCondition(
                lambda: clock.now() > tree.deadline))
            if status and setup.haveExactSolutionPath():
                path = setup.getSolutionPath()
                nodes = [tree.nodes[_key(_point(path.getState(k)))]
                         for k in range(path.getStateCount())]
                nodes = nodes[0].chain()[:-1] + nodes  # from the start itself
                reused = sum(0 < n.query < self.queries for n in nodes)
            validator.planner = validator.tree = None  # no cycle through OMPL's objects
        finally:
            ou.setLogLevel(level)
        if nodes is None:
            return None, 0
        return (self._shortcut(tree, nodes) if s.simplify else nodes), reused

    def _shortcut(self, tree: _Tree, nodes: list[_Node]) -> list[_Node]:
        """Drop waypoints where the part can go straight from an earlier node to a later
        one: the direct leg must be valid, end in the same shape (one branch), and not
        raise the peak demand."""
        i = 0
        out = [nodes[0]]
        while i < len(nodes) - 1:
            j, reached = len(nodes) - 1, None
            while j > i + 1:
                try:
                    uv = tree.turning.coordinates(nodes[j].pose.tangent)
                    if uv is None:
                        raise _Blocked("an axis outside the turns planned")
                    node = tree.carry(out[-1], (*nodes[j].pose.position, *uv))
                except _Blocked:
                    node = None
                if (node is not None and tree.same_shape(node.eq, nodes[j].eq)
                        and node.peak <= nodes[j].peak):
                    reached = node
                    break
                j -= 1
            if reached is None:
                j = i + 1
                reached = replace(nodes[j], peak=max(out[-1].peak, nodes[j].peak))
            out.append(reached)
            i = j
        return out

    # -- OMPL callbacks -------------------------------------------------------------------
    def _valid_state(self, state: Any) -> bool:
        """A cheap test of a sampled pose: the hand within reach of the part's other
        held stations and outside every obstacle. The part itself is checked along the
        motions."""
        p = _point(state)[:3]
        problem = self.scene.problem
        grip = problem.condition(self.grip)
        for c in problem.conditions:
            if (c.name == self.grip or c.name in self.settings.carry
                    or any(v is None for v in c.position)):
                continue  # (a carried hand keeps its place on the carrier)
            if np.linalg.norm(p - np.asarray(c.position)) > 0.98 * abs(grip.s - c.s):
                return False
        field_ = self._hand_field()
        if field_ is not None:
            d, _, _ = field_.query(p[None, :])
            if d[0] - problem.part.tube_radius < (-PENETRATION if self.settings.allow_contact
                                else self.scene.margin):
                return False
        return True

    def check_motion(self, tree: _Tree, a: Any, b: Any) -> bool:
        """OMPL's motion check: carry the part from a's equilibrium to b."""
        tree.motions += 1
        start = tree.nodes.get(_key(_point(a)))
        if start is None or not self._valid_state(b):
            return False
        key = _key(_point(b))
        edge = (_key(_point(a)), key)
        if edge in tree.edges:
            return tree.edges[edge]
        try:
            reached = tree.carry(start, _point(b))
        except _Blocked as why:
            tree.blocked[why.reason] += 1
            if why.reason != "out of time":
                tree.edges[edge] = False
            return False
        known = tree.nodes.get(key)
        if known is not None and not tree.same_shape(known.eq, reached.eq):
            tree.blocked["another shape at a pose already reached"] += 1
            tree.edges[edge] = False
            return False
        reached.query = self.queries
        tree.nodes[key] = reached
        tree.edges[edge] = True
        self.forest.append(reached)
        return True

    # -- helpers --------------------------------------------------------------------------
    def _hand_field(self):
        if self._field is None and self.scene.problem.obstacles:

            self._field = DistanceField(list(self.scene.problem.obstacles))
        return self._field

    def _bounds(self, goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The box the hand may move in: as far as the part reaches round its other
        held stations, and round the start and the goal."""
        problem = self.scene.problem
        grip = problem.condition(self.grip)
        points, reach = [np.asarray(grip.position), goal], []
        for c in problem.conditions:
            if (c.name != self.grip and c.name not in self.settings.carry
                    and all(v is not None for v in c.position)):
                points.append(np.asarray(c.position))
                reach.append(abs(grip.s - c.s))
        pts = np.array(points)
        # carried by both hands, the part goes where the carrier takes it
        margin = min(reach) if reach else problem.part.length
        return pts.min(axis=0) - margin, pts.max(axis=0) + margin

    def _failure(self, tree: _Tree, goal: np.ndarray, seconds: float,
                 solves: int) -> NoPathError:
        closest, distance = None, math.inf
        for node in tree.nodes.values():
            d = float(np.linalg.norm(np.subtract(node.pose.position, goal)))
            if d < distance:
                closest, distance = node.pose, d
        blocked = dict(tree.blocked.most_common())
        blocked.pop("out of time", None)
        total = sum(blocked.values())
        why = "; ".join(f"{reason} ({100 * n / total:.0f} %)"
                        for reason, n in list(blocked.items())[:4]) if total else "nothing"
        where = (f"closest pose reached {distance:.3f} m from the point before the port, "
                 f"at {closest}" if closest is not None else "no pose reached")
        return NoPathError(
            f"no path found in {seconds:.1f} s of CPU ({solves} solves, seed "
            f"{self.settings.seed}); {where}; what blocked the motions tried: {why}. Give "
            "more time (--budget), allow contact (--allow-contact), or move what blocks it",
            closest=closest, distance=distance, blocked=blocked, seconds=seconds,
            solves=solves)

    def _result(self, tree: _Tree, nodes: list[_Node], goal: str) -> Plan:
        """Write the nodes as the scene's path (a waypoint at every step of every edge)
        and follow it again as ``pliant run`` would."""

        poses = [p for n in nodes[1:] for p in n.via]
        start = self.start_pose()
        points = np.array([start.position, *[p.position for p in poses]])
        length = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
        steps = max(len(poses), math.ceil(length / (0.5 * self.settings.step)))
        problems = path_problems(tree.problem_at, start, poses, steps)
        run = follow_path(self.scene.problem, problems, self.grip, margin=self.scene.margin,
                          elements=self.solver.elements)
        demands = [tree.demand(eq) for eq in run.equilibria]
        return Plan(self.grip, goal, poses, problems, run, max(demands, default=math.inf),
                    demands, 0.0, 0, 0, 0, 0, steps, carry=self.settings.carry)


    def _breaks(self, tree: _Tree, result: Plan, seated: Pose) -> str | None:
        """What the written path, followed again step by step, breaks of the rules its
        motions were checked by (None: nothing)."""
        run = result.run
        if not run.complete:
            return "it could not be solved to its end"
        port = np.asarray(seated.position)
        reach = self.settings.approach + 1e-6
        for k, (record, eq) in enumerate(zip(run.steps, run.equilibria)):
            if k == 0:
                continue  # the start, as given (checked when the tree was rooted)
            if record.snap:
                return f"a snap at step {k}"
            if record.stable is False:
                return f"an unstable shape at step {k}"
            near = np.linalg.norm(np.asarray(record.grip_position) - port) <= reach
            try:
                tree.check_step(eq, near_port=bool(near))
            except _Blocked as why:
                return f"{why.reason} at step {k}"
        return None


def kink_radius(part: Any, kind: Any, rules: Any) -> float | None:
    """The centreline bend radius [m] below which a thin-walled tube's section flattens
    past the rules' red limit (Brazier: zeta = (1 - nu^2) a^4 / (t^2 R^2)), None where the
    rule does not apply (not thin-walled, or a/t below the rules' ratio: the evaluation's
    own test). nu not given: 0, the larger flattening, as the evaluation assumes."""

    if kind is None or not kind.thin_walled or part.outer_diameter is None or not (
            part.inner_diameter and part.inner_diameter > 0.0):
        return None
    a, t = tube_section(part.outer_diameter, part.inner_diameter)
    if a / t < rules.kink_min_ratio:
        return None
    nu = part.poisson_ratio or 0.0
    return a * a * math.sqrt(1.0 - nu * nu) / (t * math.sqrt(rules.kink_red))


def _point(state: Any) -> np.ndarray:
    return np.array([state[i] for i in range(5)])


def path_problems(problem_at: Callable[..., Problem], start: Pose, poses: list[Pose],
                  steps: int) -> list[Problem]:
    """The problems along straight legs through ``poses`` (the hand's axis turned by
    slerp on each leg), in ``steps`` equal steps of length: what a scene's [path] gives."""
    points = np.array([start.position, *[p.position for p in poses]], dtype=float)
    tangents = np.array([start.tangent, *[p.tangent for p in poses]], dtype=float)
    return [problem_at(where, _unit(direction))
            for where, direction in along_legs(points, tangents, steps)]


def _validator(ob):
    """OMPL's MotionValidator class, subclassed once OMPL is imported."""
    global _VALIDATOR
    if _VALIDATOR is None:
        base: Any = ob.MotionValidator  # (OMPL has no type information)

        class _PartMotion(base):
            def __init__(self, si, planner: Planner, tree: _Tree) -> None:
                super().__init__(si)
                self.planner, self.tree = planner, tree

            def checkMotion(self, a, b) -> bool:
                return self.planner is not None and self.planner.check_motion(self.tree, a, b)

        _VALIDATOR = _PartMotion
    return _VALIDATOR


_VALIDATOR: Any = None


def plan(scene: Any, goal: str, settings: PlanSettings | None = None, *, rules: Any = None,
         grip: str | None = None, on_progress: Callable[[str], None] | None = None) -> Plan:
    """A path for ``scene``'s grip to the port ``goal`` (see the module docstring)."""
    return Planner(scene, settings, rules=rules, grip=grip).plan(goal, on_progress=on_progress)
