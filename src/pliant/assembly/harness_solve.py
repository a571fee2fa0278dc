"""The installed harness: every segment a 3D rod, solved under gravity with its
connectors and fixings held where the design puts them and its segments joined at their
nodes.

The network is solved by substructuring. Each junction (a node where segments meet
that nothing holds) is a small rigid body of no size whose pose (position p_j, rotation
R_j) is unknown; given those poses, every segment is a well-posed rod on its own: its
ends clamped at its junctions' poses (each end turned from the junction's frame as the
design turns it) or at its placed connector, its fixings holding its position and axis,
a connector the design does not place left free. The junctions' equations are their
balance: the forces and moments the segments' ends take from a junction sum to zero.
The balance is the gradient of the harness's energy with respect to the junction
poses (6 unknowns each): Levenberg-Marquardt's method on them, every step downhill in
the energy, with the Jacobian assembled from each segment's clamp sensitivities (from
its own factorised Newton system, ``rod3d.sensitivity``; forward differences that
re-solve the segments are its tested twin) and Broyden's update between fresh ones,
solves the network; every segment solve is pliant's accurate rod (``rod3d.solve``), so
the answer is the same rod model as a single part, and the same rods join exactly where
a single part would run through (tested against its one-part twin). The segments'
natural shape is straight (a bundle taped on a formboard); the design is a route.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from pliant.assembly.harness import SegmentProperties, centre_curve, select
from pliant.core.equilibrium import Equilibrium3D
from pliant.core.events import jumped
from pliant.core.harness import Harness, HarnessSegment
from pliant.core.rotations import exp_map, log_map
from pliant.core.tube import rotation_minimizing_frames
from pliant.errors import ConvergenceError, IllPosedProblemError, PliantError

# m: elements about this long, 16 to 120 per segment. The tightest bend near a clamp
# converges slowly: the generator cable's branches read 7.0, 4.9 and 4.3 mm at 20, 10
# and 5 mm elements; the main harness costs the same at 5 mm as at 20 (its time is
# per segment, not per element).
ELEMENT_LENGTH = 0.005
STEP_POSITION = 1e-6  # the twin Jacobian's differences, by the mean segment length
STEP_ROTATION = 1e-6  # rad
TOLERANCE = 1e-7  # the junctions' balance, by the weight (and weight x length) of all
MAX_ITERATIONS = 200
NEAR_DEPTH = 1  # junctions this many segments from a moved fixing's balance first
GROW_ROUNDS = 4  # times that region grows by the junctions still off balance about it
SETTLE_ROUNDS = 3  # unstable segments settled and the junctions balanced again
DESIGN_LENGTH = 0.01  # a design curve this far from its segment's length is no start
AT_NODE = 1e-3  # m: a fixing this near a segment's end holds the node there
GRAVITY = (0.0, 0.0, -9.81)


@dataclass(frozen=True)
class _End:
    """A segment's end at a node: which end (0 its start, 1 its end), and its design
    frame (3, 3) (columns d1, d2, d3 with d3 along the segment's arc length)."""

    segment: str
    end: int
    frame: np.ndarray


@dataclass
class _Junction:
    node: str
    ends: list[_End]
    position: np.ndarray  # (3,) [m], now
    rotation: np.ndarray  # (3, 3), now: from the design frame ``base`` to the present
    base: np.ndarray  # (3, 3): the first end's design frame


@dataclass(frozen=True)
class InstalledSegment:
    """One segment installed: its equilibrium (``pliant.core.Equilibrium3D``), how far it
    lies from its designed centre curve at the same arc length (largest distance [m] and
    its largest drop below it [m]), its tightest bend radius [m] against its limit, and
    its clearance to the scene's obstacles (None without)."""

    segment: str
    equilibrium: Equilibrium3D
    deviation: float
    sag: float
    bend_radius: float
    bend_limit: float | None
    interference: object = None  # ``pliant.scene.interference.Interference`` or None


@dataclass(frozen=True)
class Installed:
    """The installed harness: each segment's answer, each junction's position [m], each
    held point's load (name: (force (3,) [N], moment (3,) [N m]), the load the harness
    puts on the connector or fixing), how many Newton iterations the junctions took and
    their final balance (relative), and notes (free connectors, what was not solved)."""

    harness: Harness
    segments: dict[str, InstalledSegment]
    junctions: dict[str, np.ndarray]
    held: dict[str, tuple[np.ndarray, np.ndarray]]
    iterations: int
    balance: float
    notes: tuple[str, ...] = field(default=())
    rotations: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    jacobian: np.ndarray | None = field(default=None, repr=False)  # for a warm re-solve
    prepared: tuple | None = field(default=None, repr=False)  # design curves and frames
    released: frozenset[str] = frozenset()  # the fixings not fixed (by name)
    margin: float = 0.0  # [m] the clearance wanted round obstacles and other branches

    @property
    def weight(self) -> float:
        """The harness's weight [N]."""
        g = float(np.linalg.norm(GRAVITY))
        return float(sum(s.equilibrium.problem.part.mass_per_length
                         * s.equilibrium.problem.part.length * g
                         for s in self.segments.values()))


def _end_frames(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Design frames (d1, d2, d3 as columns) at a curve's two ends: d3 along it, d1
    carried by rotation-minimising (parallel) transport, no twist along the design."""
    frames = rotation_minimizing_frames(points)
    return frames[0], frames[-1]


def _vec3(v) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def _elements(length: float) -> int:
    return int(min(120, max(16, math.ceil(length / ELEMENT_LENGTH))))


class Network:
    """The harness's segments as rods and its junctions as unknown poses."""

    def __init__(self, harness: Harness, props: Mapping[str, SegmentProperties],
                 gravity: tuple[float, float, float],
                 moved: Mapping[str, tuple[float, float, float]] | None = None,
                 prepared: tuple | None = None, obstacles: tuple = (),
                 released: Collection[str] = ()) -> None:
        import pliant as pl  # noqa: PLC0415 (the solver: only a solve needs it)

        self.pl = pl
        self.obstacles = tuple(obstacles)
        self.moved = dict(moved or {})
        self.released = frozenset(released)
        # Fixings on their way from where the harness hung to their designed place
        # (``pliant.assembly.clip_order``): (name, segment) -> (point [m], tangent), and
        # how far along (0 where it hung, 1 its designed place).
        self.approach: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
        self.along = 1.0
        names = {f.name for f in harness.fixings.values()}
        for what, given in (("moved", self.moved), ("released", self.released)):
            for name in given:
                if name not in names:
                    raise IllPosedProblemError(
                        f"{what}: {name!r} is not a fixing of the harness (its fixings: "
                        f"{', '.join(sorted(names)[:8])})")
        self.harness = harness
        self.gravity = gravity
        self.notes: list[str] = []
        held = {c.node for c in harness.connectors.values() if c.placement is not None and c.node}
        # A fixing at a segment's end holds the node itself (its place and the design's
        # frames there, as a connector does): grips a hair inside the segments beside a
        # free junction would pin it from both sides, an ill-posed balance.
        self.at_fixing: dict[str, str] = {}  # node -> the fixing holding it
        self.node_approach: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # see ``fix``
        for seg in harness.segments.values():
            for place in seg.fixings:
                node = self.node_of(seg, place)
                if node is not None and node not in held and self._fixed(place):
                    self.at_fixing[node] = harness.fixings[place.fixing].name
        self.connected = frozenset(held)  # the nodes a placed connector holds
        held |= set(self.at_fixing)
        self.design: dict[str, np.ndarray] = {}
        ends: dict[str, list[_End]] = {}
        self.frames: dict[tuple[str, int], np.ndarray] = {}
        self.parts = {}
        for seg in harness.segments.values():
            if prepared is not None and seg.id in prepared[0]:  # an earlier answer's
                pts = prepared[0][seg.id]
                f0, f1 = prepared[1][(seg.id, 0)], prepared[1][(seg.id, 1)]
            else:
                pts = centre_curve(harness, seg.id)
                f0, f1 = _end_frames(pts)
            self.design[seg.id] = pts
            self.frames[(seg.id, 0)], self.frames[(seg.id, 1)] = f0, f1
            ends.setdefault(seg.start, []).append(_End(seg.id, 0, f0))
            ends.setdefault(seg.end, []).append(_End(seg.id, 1, f1))
            self.parts[seg.id] = self._part(seg, props[seg.id])
        self.held = held
        self.junctions: list[_Junction] = []
        self.free: set[str] = set()
        for node, at in ends.items():
            if node in held:
                continue
            if len(at) == 1:
                self.free.add(node)
                continue
            base = at[0].frame
            self.junctions.append(_Junction(node, at, np.array(harness.nodes[node].position),
                                            np.eye(3), base))
        self.at_node = {j.node: k for k, j in enumerate(self.junctions)}
        self._check_held(ends)
        lengths = [s.virtual_length for s in harness.segments.values()]
        self.L_ref = float(np.mean(lengths))
        g = float(np.linalg.norm(gravity))
        weight = sum(p.mass_per_length * p.length for p in self.parts.values()) * g
        self.F_ref = max(weight, 1e-6)
        self.eqs: dict[str, Equilibrium3D] = {}
        self._contributions: dict[int, tuple[Equilibrium3D, np.ndarray]] = {}

    def _part(self, seg: HarnessSegment, p: SegmentProperties):
        missing = [name for name, d in (("bending stiffness", p.bending_stiffness),
                                        ("diameter", p.diameter),
                                        ("mass per length", p.mass_per_length)) if d.value is None]
        if missing:
            raise IllPosedProblemError(
                f"segment {seg.id} ({seg.name}): no {', '.join(missing)} ("
                f"{p.bending_stiffness.source if p.bending_stiffness.value is None else ''}); "
                "give it in the overrides")
        return self.pl.Part(length=seg.virtual_length, name=seg.id,
                            bending_stiffness=float(p.bending_stiffness.value),  # type: ignore[arg-type]
                            torsional_stiffness=p.torsional_stiffness.value,
                            mass_per_length=float(p.mass_per_length.value),  # type: ignore[arg-type]
                            outer_diameter=p.diameter.value, kind="wire",
                            axial_stiffness=p.axial_stiffness.value,
                            min_bend_radius=p.min_bend_radius.value)

    def _check_held(self, ends: dict[str, list[_End]]) -> None:
        """Every connected piece of the harness must be held somewhere."""
        seen: set[str] = set()
        for start in ends:
            if start in seen:
                continue
            piece, stack = set(), [start]
            while stack:
                node = stack.pop()
                if node in piece:
                    continue
                piece.add(node)
                for e in ends[node]:
                    s = self.harness.segments[e.segment]
                    stack += [s.start, s.end]
            seen |= piece
            segs = {e.segment for n in piece for e in ends[n]}
            if not (piece & self.held) and not any(self._fixed(p) for s in segs
                                                    for p in self.harness.segments[s].fixings):
                names = sorted(self.harness.nodes[n].name for n in piece)[:5]
                raise IllPosedProblemError(
                    f"the harness piece with nodes {', '.join(names)} is held nowhere: no "
                    "placed connector and no fixing (place a connector in the design, or "
                    "hold it with a fixing)")

    @staticmethod
    def node_of(seg: HarnessSegment, place) -> str | None:
        """The node a fixing place sits at (within ``AT_NODE`` of the segment's end), or
        None where it is inside the segment."""
        s = place.location * seg.virtual_length
        return (seg.start if s <= AT_NODE else
                seg.end if s >= seg.virtual_length - AT_NODE else None)

    def _fixed(self, place) -> bool:
        """Whether the fixing at ``place`` holds the harness (not one of ``released``)."""
        return self.harness.fixings[place.fixing].name not in self.released

    # -- one segment's problem --------------------------------------------------------
    def _end_condition(self, seg: HarnessSegment, end: int):
        node = seg.start if end == 0 else seg.end
        s = 0.0 if end == 0 else seg.virtual_length
        name = f"{'start' if end == 0 else 'end'} {self.harness.nodes[node].name}"
        if node in self.held:
            frame = self.frames[(seg.id, end)]
            position = np.array(self.harness.nodes[node].position)
            if node in self.at_fixing:
                fixing = self.at_fixing[node]
                position = position + np.asarray(self.moved.get(fixing, (0.0, 0.0, 0.0)),
                                                 float)
                if node in self.node_approach:  # carried from where it hung (``fix``)
                    hung, turned = self.node_approach[node]
                    position = (1.0 - self.along) * hung + self.along * position
                    frame = exp_map((1.0 - self.along) * log_map(turned)) @ frame
        elif node in self.at_node:
            j = self.junctions[self.at_node[node]]
            frame = j.rotation @ self.frames[(seg.id, end)]
            position = j.position
        else:
            return None
        return self.pl.clamp(s, _vec3(position), name=name,
                             tangent=_vec3(frame[:, 2]),
                             normal=_vec3(frame[:, 0]))

    def problem(self, seg_id: str):
        seg = self.harness.segments[seg_id]
        conditions = [c for c in (self._end_condition(seg, 0), self._end_condition(seg, 1))
                      if c is not None]
        pts = self.design[seg_id]
        arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
        for place in seg.fixings:
            fixing = self.harness.fixings[place.fixing]
            s = place.location * seg.virtual_length
            if s <= 1e-9 * seg.virtual_length or s >= (1 - 1e-9) * seg.virtual_length:
                s = min(max(s, 1e-3 * seg.virtual_length), (1 - 1e-3) * seg.virtual_length)
            if not self._fixed(place) or self.node_of(seg, place) is not None:
                # Its mark stays a station of the rod (a load of nothing), so that fixing
                # it later keeps the mesh: the shape carries over as it is. (At a node
                # the fixing holds the node: the segment's end condition.)
                conditions.append(self.pl.push(s, force=(0.0, 0.0, 0.0),
                                               name=f"mark {fixing.name}"))
                continue
            at = place.location * arc[-1]
            k = int(np.clip(np.searchsorted(arc, at) - 1, 0, len(pts) - 2))
            w = (at - arc[k]) / max(arc[k + 1] - arc[k], 1e-300)
            point = (1 - w) * pts[k] + w * pts[k + 1]
            tangent = pts[k + 1] - pts[k]
            tangent /= np.linalg.norm(tangent)
            point = point + np.asarray(self.moved.get(fixing.name, (0.0, 0.0, 0.0)), float)
            if (fixing.name, seg_id) in self.approach:
                hung, turned = self.approach[(fixing.name, seg_id)]
                point = (1.0 - self.along) * hung + self.along * point
                tangent = (1.0 - self.along) * turned + self.along * tangent
                tangent /= np.linalg.norm(tangent)
            conditions.append(self.pl.grip(s, _vec3(point),
                                           name=f"fixing {fixing.name}",
                                           tangent=_vec3(tangent)))
        conditions.sort(key=lambda c: c.s)
        return self.pl.Problem(self.parts[seg_id], tuple(conditions), gravity=self.gravity,
                               name=seg_id, obstacles=self.obstacles)

    def solve_segment(self, seg_id: str, warm: bool = True):
        from pliant.models import rod3d  # noqa: PLC0415

        problem = self.problem(seg_id)
        # Not settled: the junctions' Newton solves each segment again and again, and a
        # segment that left its branch between two of them would break that Newton.
        solver = rod3d.RodSolver(elements=_elements(problem.part.length), settle=False)
        previous = self.eqs.get(seg_id) if warm else None
        if previous is not None:
            try:
                return rod3d.solve(problem, solver=solver, warm_start=previous)
            except PliantError:
                pass
        if previous is None:
            try:  # from the design's shape, its stresses let go and its weight laid on
                return _from_design(problem, self.design[seg_id],
                                    self.frames[(seg_id, 0)][:, 0], solver)
            except PliantError:
                pass
        try:
            return rod3d.solve(problem, solver=solver)
        except ConvergenceError:
            if previous is not None:
                raise
            # A cold start whose first route crosses a fold: the best equilibrium any
            # route reaches (stable first, then the least energy).
            found = rod3d.equilibria(problem, solver=solver, budget=5.0)
            if not found:
                raise
            return found[0]

    # -- the junctions' balance -------------------------------------------------------
    def contribution(self, seg_id: str, eq: Equilibrium3D) -> np.ndarray:
        """(6 J,) what one segment's ends add to the junctions' balance (scaled), kept
        per answer: a Jacobian's column changes only its junction's segments'."""
        key = id(eq)
        hit = self._contributions.get(key)
        if hit is not None and hit[0] is eq:
            return hit[1]
        out = np.zeros(6 * len(self.junctions))
        seg = self.harness.segments[seg_id]
        reactions = eq.reactions
        for end, node in ((0, seg.start), (1, seg.end)):
            k = self.at_node.get(node)
            if k is None:
                continue
            name = f"{'start' if end == 0 else 'end'} {self.harness.nodes[node].name}"
            load = reactions[name]
            out[6 * k:6 * k + 3] += np.asarray(load.force) / self.F_ref
            out[6 * k + 3:6 * k + 6] += np.asarray(load.moment) / (self.F_ref * self.L_ref)
        if len(self._contributions) > 20 * len(self.harness.segments):
            self._contributions.clear()
        self._contributions[key] = (eq, out)
        return out

    def residual(self, eqs: Mapping[str, Equilibrium3D]) -> np.ndarray:
        """(6 J,) each junction's balance: the forces and moments its segments' ends
        take from it, by the harness's weight (and weight times its mean segment)."""
        r = np.zeros(6 * len(self.junctions))
        for seg_id, eq in eqs.items():
            r += self.contribution(seg_id, eq)
        return r

    def energy(self, eqs: Mapping[str, Equilibrium3D]) -> float:
        """All the segments' elastic (bending, twist and stretch) and weight's potential
        energy [J]: the junctions' balance is its gradient."""
        from pliant.core.equilibrium import potential_energy  # noqa: PLC0415

        return float(sum(potential_energy(eq) for eq in eqs.values()))

    def move(self, k: int, dq: np.ndarray) -> None:
        j = self.junctions[k]
        j.position = j.position + dq[:3] * self.L_ref
        j.rotation = exp_map(dq[3:]) @ j.rotation

    def segments_at(self, k: int) -> list[str]:
        return sorted({e.segment for e in self.junctions[k].ends})

    def held_by(self, fixings: Collection[str]) -> list[str]:
        """The segments (sorted) these fixings (by name) hold: those they are placed on,
        and every segment at a node one of them holds."""
        nodes = {n for n, name in self.at_fixing.items() if name in fixings}
        return sorted(seg_id for seg_id, seg in self.harness.segments.items()
                      if seg.start in nodes or seg.end in nodes or any(
                          self.harness.fixings[p.fixing].name in fixings
                          for p in seg.fixings))

    def near(self, segments: Collection[str], depth: int = 1) -> set[int]:
        """The junctions (indices) at these segments' ends, and those up to ``depth``
        segments further on."""
        ends = self.harness.segments
        found = {self.at_node[n] for s in segments for n in (ends[s].start, ends[s].end)
                 if n in self.at_node}
        for _ in range(depth):
            found |= {self.at_node[n] for k in list(found) for s in self.segments_at(k)
                      for n in (ends[s].start, ends[s].end) if n in self.at_node}
        return found


def _from_design(problem, points: np.ndarray, first_normal: np.ndarray,
                 solver) -> Equilibrium3D:
    """A segment's equilibrium followed from its designed shape (``rod3d.from_shape``:
    that shape, made the rod's rest shape and free of gravity, is an equilibrium; the
    rest shape is then taken to straight and the weight to its own). ``first_normal``:
    the section's d1 at s = 0 (the start clamp's)."""
    from pliant.models import rod3d  # noqa: PLC0415

    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    if abs(arc[-1] / problem.part.length - 1.0) > DESIGN_LENGTH:
        raise ConvergenceError("the design's curve is not the segment's length: no shape "
                               "to start from", residual=math.inf)
    return rod3d.from_shape(problem, points, first_normal, solver)


def solve_installed(harness: Harness, props: Mapping[str, SegmentProperties], *,
                    modules: list[str] | None = None,
                    gravity: tuple[float, float, float] = GRAVITY,
                    moved: Mapping[str, tuple[float, float, float]] | None = None,
                    warm: Installed | None = None, obstacles: tuple = (),
                    margin: float = 0.0, released: Collection[str] = ()) -> Installed:
    """The harness installed under ``gravity``: see the module. ``moved``: fixings (by
    name) displaced from their designed place [m]; ``warm``: an earlier answer of the
    same harness to start from (a fixing moved, re-solved in a fraction of the cold
    solve's time); ``obstacles``: the scene's (``pliant.scene.Obstacle``), each segment
    in contact with them and its clearance reported against ``margin`` [m];
    ``released``: fixings (by name) not fixed yet, the harness hanging past them
    (``pliant.assembly.clip_order``). Raises
    ``ConvergenceError`` (naming the junction that would not balance) or
    ``IllPosedProblemError`` (a piece held nowhere, a property missing)."""
    if modules:
        harness = select(harness, modules)
    if moved and warm is None:  # as designed first, then the fixings moved from there
        warm = solve_installed(harness, props, gravity=gravity, obstacles=obstacles,
                               margin=margin, released=released)
    net = Network(harness, props, gravity, moved,
                  None if warm is None else warm.prepared, obstacles, released)
    if warm is not None and set(warm.segments) == set(harness.segments) and \
            set(warm.rotations) == {j.node for j in net.junctions}:
        # From an earlier answer (a fixing moved): its junction poses and its segments'
        # equilibria, each followed to its new targets.
        for j in net.junctions:
            j.position = np.array(warm.junctions[j.node], float)
            j.rotation = np.array(warm.rotations[j.node], float)
        for seg_id in harness.segments:
            net.eqs[seg_id] = warm.segments[seg_id].equilibrium
        if warm.released != net.released:  # other fixings hold it: each segment followed
            net.eqs = {seg_id: net.solve_segment(seg_id) for seg_id in harness.segments}
    else:
        warm = None
        for seg_id in harness.segments:
            net.eqs[seg_id] = net.solve_segment(seg_id, warm=False)
    if warm is not None and moved:
        # The fixings moved as far as their segments follow at once (all the way first,
        # halved where a segment cannot), the junctions balanced after each step.
        target = dict(net.moved)

        def to(t: float) -> None:
            net.moved = {name: _vec3(np.asarray(v, float) * t) for name, v in target.items()}

        # Only the moved fixings' segments' problems change: they follow, the junctions
        # about them balance on their own, then the whole harness from there.
        carrying = net.held_by(target)
        iterations, r, jac = _stepped(net, warm.jacobian, to, lambda: {
            seg_id: net.solve_segment(seg_id, warm=True) for seg_id in carrying},
            step=1.0, near=net.near(carrying, NEAR_DEPTH))
    else:
        iterations, r, jac = _balance(net, None)
        for _ in range(SETTLE_ROUNDS):
            if not _settle_unstable(net):
                break
            more, r, jac = _balance(net, None)
            iterations += more
    return _installed(harness, net, iterations, float(np.abs(r).max(initial=0.0)), jac,
                      margin)


def _settle_unstable(net: Network) -> list[str]:
    """Each segment whose answer is unstable with its ends held where they are (then so
    is the harness, whose junctions hold them less) left along its unstable mode for the
    stable shape it settles in (``rod3d``'s settle); the ids of those that were. A
    cold start can end there: a design shorter than its segment, straight, gives the
    segment pushed straight between its ends."""
    from pliant.models import rod3d  # noqa: PLC0415

    settled = []
    for seg_id, eq in net.eqs.items():
        if eq.verdict != "unstable":
            continue
        solver = rod3d.RodSolver(elements=_elements(eq.problem.part.length), settle=True)
        try:
            stable = rod3d.solve(net.problem(seg_id), solver=solver, warm_start=eq)
        except PliantError:
            continue
        if stable.verdict != "unstable":
            net.eqs[seg_id] = stable
            settled.append(seg_id)
    return settled


def fix(before: Installed, props: Mapping[str, SegmentProperties], fixing: str, *,
        gravity: tuple[float, float, float] = GRAVITY, obstacles: tuple = (),
        margin: float = 0.0, steps: int = 4) -> tuple[Installed, list[float]]:
    """The harness of ``before`` with one of its released fixings fixed: the fixing is
    taken where the harness hangs (its point and the bundle's axis there) and carried to
    its designed place and axis in ``steps`` steps (halved where the harness cannot
    follow), the junctions balanced after each; every segment follows warm, so the
    answer is the branch the fitter's move leads to. Also returns the force [N] the
    harness pushes back on the fixing (on the fitter's hand) at each step."""
    from pliant.models import rod3d  # noqa: PLC0415 (the solver: only a solve needs it)

    if fixing not in before.released:
        raise IllPosedProblemError(f"fixing {fixing!r} is not released in this answer (the "
                                   f"released: {', '.join(sorted(before.released)) or 'none'})")
    harness = before.harness
    net = Network(harness, props, gravity, None, before.prepared, obstacles,
                  before.released - {fixing})
    for j in net.junctions:
        j.position = np.array(before.junctions[j.node], float)
        j.rotation = np.array(before.rotations[j.node], float)
    net.eqs = {seg_id: seg.equilibrium for seg_id, seg in before.segments.items()}
    (fid,) = [f.id for f in harness.fixings.values() if f.name == fixing]
    carrying = net.held_by({fixing})
    if not carrying:  # placed on no segment: it holds nothing
        return replace(before, released=net.released), [0.0]
    at = next((n for n, name in net.at_fixing.items() if name == fixing), None)
    if at is not None:  # it holds a node: every segment there loads it
        seg_id = carrying[0]
        eq = before.segments[seg_id].equilibrium
        end = 0 if harness.segments[seg_id].start == at else 1
        # Where the node hung, and its turn from the design's frames there.
        net.node_approach[at] = (np.array(eq.position[-end]),
                                 eq.frames[-end] @ net.frames[(seg_id, end)].T)
    for seg_id in carrying if at is None else ():  # (a clip may hold two segments)
        eq = before.segments[seg_id].equilibrium
        place = next(p for p in harness.segments[seg_id].fixings if p.fixing == fid)
        s = min(max(place.location * eq.problem.part.length, 1e-3 * eq.problem.part.length),
                (1 - 1e-3) * eq.problem.part.length)
        # Where the bundle is at the clip's mark, and its axis there: between the nodes
        # about it, in proportion.
        k = int(np.clip(np.searchsorted(eq.s, s) - 1, 0, len(eq.s) - 2))
        w = (s - eq.s[k]) / (eq.s[k + 1] - eq.s[k])
        axis = (1.0 - w) * eq.frames[k][:, 2] + w * eq.frames[k + 1][:, 2]
        net.approach[(fixing, seg_id)] = ((1.0 - w) * eq.position[k]
                                          + w * eq.position[k + 1],
                                          axis / np.linalg.norm(axis))
    solver = {seg: rod3d.RodSolver(elements=_elements(harness.segments[seg].virtual_length),
                                   settle=False) for seg in harness.segments}
    forces: list[float] = []

    def follow(seg: str) -> Equilibrium3D:  # warm only: a cold solve is another branch
        eq = rod3d.solve(net.problem(seg), solver=solver[seg], warm_start=net.eqs[seg])
        if jumped(eq.notes):
            raise ConvergenceError(f"segment {seg} cannot follow fixing {fixing} there",
                                   residual=math.inf)
        return eq

    def to(t: float) -> None:
        net.along = t

    def felt() -> None:  # the force on the hand: the clip's load from every segment it holds
        names = ([f"fixing {fixing}"] if at is None else
                 [f"start {harness.nodes[at].name}", f"end {harness.nodes[at].name}"])
        held = [net.eqs[seg].reactions.get(name) for seg in carrying for name in names]
        forces.append(float(np.linalg.norm(sum(np.asarray(h.force) for h in held
                                               if h is not None))))

    # Only the clip's segments' problems change between two balances.
    same = {j.node for j in net.junctions} == set(before.junctions)
    iterations, r, jac = _stepped(net, before.jacobian if same else None, to, lambda: {
        seg: follow(seg) for seg in carrying}, step=1.0 / steps, from_start=True,
        after=felt, near=net.near(carrying, NEAR_DEPTH))
    return _installed(harness, net, iterations, float(np.abs(r).max(initial=0.0)), jac,
                      margin), forces


def _stepped(net: Network, jac: np.ndarray | None, to: Callable[[float], None],
             resolve: Callable[[], dict[str, Equilibrium3D]], *, step: float,
             from_start: bool = False, after: Callable[[], None] | None = None,
             near: Collection[int] = ()) -> tuple[int, np.ndarray, np.ndarray | None]:
    """Take the network from where it is (0) to ``to(1)`` in steps of ``step``, halved
    where it cannot follow (down to a thousandth of the first): at each, ``resolve`` the
    segments whose problems changed, balance the junctions, then ``after()``.
    ``from_start``: a first step at 0 itself, which must succeed. ``near``: the junctions
    (indices) about what moved, balanced first on their own (the rest held: only their
    segments are solved again), then all together from there. (iterations, the last
    balance, the last Jacobian); the solver's error where a step cannot be taken."""
    iterations, done, least = 0, 0.0, 1e-3 * step
    r = net.residual(net.eqs)
    first = from_start
    while first or done < 1.0:
        t = 0.0 if first else min(1.0, done + step)
        kept = dict(net.eqs)
        saved = [(j.position.copy(), j.rotation.copy()) for j in net.junctions]
        to(t)
        try:
            net.eqs = {**net.eqs, **resolve()}
            count = 0
            if near and len(near) < len(net.junctions):
                count, r = _balance_growing(net, set(near))
            more, r, jac = _balance(net, jac)
            count += more
        except PliantError:
            if first:
                raise
            net.eqs = kept
            for j, (p, rot) in zip(net.junctions, saved):
                j.position, j.rotation = p, rot
            step *= 0.5
            if step < least:
                raise
            continue
        iterations += count
        done, first = t, False
        if after is not None:
            after()
    return iterations, r, jac


def _balance_growing(net: Network, region: set[int]) -> tuple[int, np.ndarray]:
    """Balance the junctions of ``region`` on their own (the rest held), then, while
    junctions outside it are off balance, the region grown by them and their
    neighbours, balanced again (up to ``GROW_ROUNDS`` times): each round solves only
    the segments at the region's junctions, where the whole harness's balance would
    solve every segment at each iteration. (iterations, the last balance)."""
    count, r, _ = _balance(net, None, only=region)
    for _ in range(GROW_ROUNDS):
        off = {k for k in range(len(net.junctions))
               if float(np.abs(r[6 * k:6 * k + 6]).max()) > TOLERANCE} - region
        if not off or len(region) >= len(net.junctions):
            break
        region |= net.near(sorted({s for k in off for s in net.segments_at(k)}), 0)
        more, r, _ = _balance(net, None, only=region)
        count += more
    return count, r


def _balance(net: Network, jac: np.ndarray | None, only: Collection[int] | None = None
             ) -> tuple[int, np.ndarray, np.ndarray | None]:
    """Newton (Levenberg-Marquardt, downhill in the harness's energy) on the junction
    poses from where they are: (iterations, the last balance, the last Jacobian).
    ``only``: those junctions (indices), the others held where they are; only the
    segments at them are solved again, and the Jacobian is theirs (``jac`` then the
    whole harness's, or None)."""
    harness = net.harness
    chosen = sorted(only) if only is not None else list(range(len(net.junctions)))
    n = len(chosen)
    rows = np.array([6 * k + c for k in chosen for c in range(6)], dtype=int)
    moving = (sorted({s for k in chosen for s in net.segments_at(k)}) if only is not None
              else list(harness.segments))
    if only is not None and jac is not None:
        jac = jac[np.ix_(rows, rows)]
    full_r = net.residual(net.eqs)
    r = full_r[rows]

    def fresh_jacobian() -> np.ndarray:  # the chosen junctions' rows and columns
        return jacobian(net, full_r, moving if only is not None else None)[
            np.ix_(rows, rows)]

    energy = net.energy(net.eqs)
    iterations = 0
    damping = 1e-6
    fresh = 0  # Jacobians computed afresh (the rest are Broyden's updates)
    updated = jac is not None  # an earlier answer's: refreshed where it misleads
    while n and float(np.abs(r).max()) > TOLERANCE:
        if iterations >= MAX_ITERATIONS:
            worst = chosen[int(np.argmax(np.abs(r))) // 6]
            raise ConvergenceError(
                f"the harness's junctions would not balance in {MAX_ITERATIONS} "
                f"iterations (junction {harness.nodes[net.junctions[worst].node].name} "
                f"off by {float(np.abs(r).max()):.2g} of the harness's weight)",
                residual=float(np.abs(r).max()))
        if jac is None:
            jac = fresh_jacobian()
            fresh += 1
            updated = False
        hessian = 0.5 * (jac + jac.T)  # the balance is the energy's gradient
        scale = float(np.abs(np.diag(hessian)).max(initial=1.0))
        accepted = False
        while damping < 1e8:
            try:
                dq = np.linalg.solve(hessian + damping * scale * np.eye(6 * n), -r)
            except np.linalg.LinAlgError:
                damping *= 10.0
                continue
            # No junction moves more than a quarter of the mean segment or turns 0.5 rad.
            moves = np.abs(dq.reshape(n, 2, 3)).max(axis=2).max(axis=0)
            dq *= 1.0 / max(1.0, moves[0] / 0.25, moves[1] / 0.5)
            saved = [(j.position.copy(), j.rotation.copy()) for j in net.junctions]
            for i, k in enumerate(chosen):
                net.move(k, dq[6 * i:6 * i + 6])
            try:
                trial = {**net.eqs, **{s: net.solve_segment(s) for s in moving}}
                full_new = net.residual(trial)
                r_new, e_new = full_new[rows], net.energy(trial)
            except PliantError:
                r_new = None
            # Downhill in the energy, or (near the answer, where the energy's change is
            # below its round-off) a smaller imbalance.
            if r_new is not None and (e_new < energy - 1e-12 * abs(energy) or (
                    np.linalg.norm(r_new) < np.linalg.norm(r) and e_new <= energy
                    + 1e-9 * abs(energy))):
                # Broyden's update: the Jacobian taken along by this step's change.
                jac = jac + np.outer(r_new - r - jac @ dq, dq) / float(dq @ dq)
                updated = True
                net.eqs, r, energy, accepted = trial, r_new, e_new, True
                full_r = full_new
                damping = max(damping / 4.0, 1e-9)
                break
            for j, (p, rot) in zip(net.junctions, saved):
                j.position, j.rotation = p, rot
            if updated:  # an updated Jacobian misled the step: a fresh one, same damping
                jac = fresh_jacobian()
                fresh += 1
                updated = False
                hessian = 0.5 * (jac + jac.T)
                scale = float(np.abs(np.diag(hessian)).max(initial=1.0))
            else:
                damping *= 8.0
        iterations += 1
        if not accepted:
            raise ConvergenceError("the harness's junctions would not balance: no step "
                                   "lowers the harness's energy from here",
                                   residual=float(np.abs(r).max()))
    return iterations, full_r, jac


def jacobian(net: Network, r: np.ndarray, segments: Collection[str] | None = None
             ) -> np.ndarray:
    """d(balance)/d(junction poses): each segment's clamps' sensitivity from its own
    factorised Newton system (``rod3d.sensitivity``), assembled; where one cannot be
    had, that segment's columns by re-solving it (``jacobian_by_differences``).
    ``segments``: only theirs (exact in the rows and columns of their junctions)."""
    from pliant.models.rod3d.sensitivity import clamp_sensitivity  # noqa: PLC0415

    n = len(net.junctions)
    jac = np.zeros((6 * n, 6 * n))
    scale = np.r_[np.full(3, 1.0 / net.F_ref), np.full(3, 1.0 / (net.F_ref * net.L_ref))]
    for seg_id, eq in net.eqs.items():
        if segments is not None and seg_id not in segments:
            continue
        seg = net.harness.segments[seg_id]
        ends = [(f"{'start' if end == 0 else 'end'} {net.harness.nodes[node].name}",
                 net.at_node[node]) for end, node in ((0, seg.start), (1, seg.end))
                if node in net.at_node]
        if not ends:
            continue
        names = [name for name, _ in ends]
        try:
            sens = clamp_sensitivity(eq, names, names, net.L_ref)
        except PliantError:
            return jacobian_by_differences(net, r)
        for a, (_, ka) in enumerate(ends):
            for b, (_, kb) in enumerate(ends):
                block = sens[6 * a:6 * a + 6, 6 * b:6 * b + 6] * scale[:, None]
                jac[6 * ka:6 * ka + 6, 6 * kb:6 * kb + 6] += block
    return jac


def jacobian_by_differences(net: Network, r: np.ndarray) -> np.ndarray:
    """``jacobian``'s twin by forward differences; a column re-solves only the segments
    at its junction, and changes only their share of the balance."""
    n = len(net.junctions)
    jac = np.zeros((6 * n, 6 * n))
    for k in range(n):
        segs = net.segments_at(k)
        base = sum(net.contribution(s, net.eqs[s]) for s in segs)
        for c in range(6):
            dq = np.zeros(6)
            h = STEP_POSITION if c < 3 else STEP_ROTATION
            dq[c] = h
            saved = (net.junctions[k].position.copy(), net.junctions[k].rotation.copy())
            net.move(k, dq)
            moved = sum(net.contribution(s, net.solve_segment(s)) for s in segs)
            jac[:, 6 * k + c] = (moved - base) / h
            net.junctions[k].position, net.junctions[k].rotation = saved
    return jac


def _installed(harness: Harness, net: Network, iterations: int, balance: float,
               jac: np.ndarray | None, margin: float = 0.0) -> Installed:
    segments = {}
    held: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    down = np.asarray(net.gravity, float)
    down = down / max(float(np.linalg.norm(down)), 1e-300)
    for seg_id, eq in net.eqs.items():
        design = net.design[seg_id]
        arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(design, axis=0), axis=1))]
        s = eq.s / eq.problem.part.length * arc[-1]
        at_s = np.column_stack([np.interp(s, arc, design[:, i]) for i in range(3)])
        offset = eq.position - at_s
        radius, _ = eq.min_bend_radius()
        report = None
        if net.obstacles:
            from pliant.scene.interference import of_answer  # noqa: PLC0415

            report = of_answer(eq.s, eq.position, eq.contacts,
                                            eq.problem.part.drawn_radius,
                                            net.obstacles, margin=margin)
        segments[seg_id] = InstalledSegment(
            seg_id, eq, float(np.linalg.norm(offset, axis=1).max()),
            float(max(0.0, (offset @ down).max())), float(radius),
            eq.problem.part.min_bend_radius, report)
        seg = harness.segments[seg_id]
        for name, load in eq.reactions.items():
            node = (seg.start if name.startswith("start ") else
                    seg.end if name.startswith("end ") else None)
            if node in net.at_fixing:
                key = f"fixing {net.at_fixing[node]}"
            elif node in net.connected:
                key = f"connector at {harness.nodes[node].name}"
            elif name.startswith("fixing "):
                key = name
            else:
                continue
            f, m = held.get(key, (np.zeros(3), np.zeros(3)))
            # The load on the connector or fixing: the opposite of what it applies.
            held[key] = (f - np.asarray(load.force), m - np.asarray(load.moment))
    notes = []
    unstable = sorted(seg_id for seg_id, eq in net.eqs.items() if eq.verdict == "unstable")
    if unstable:
        notes.append(f"{len(unstable)} segment(s) unstable as installed (the harness would "
                     f"snap to another shape; their checks are unchecked): "
                     + ", ".join(unstable[:6]) + (" ..." if len(unstable) > 6 else ""))
    if net.free:
        notes.append(f"{len(net.free)} segment end(s) hang free: no placed connector at "
                     + ", ".join(sorted(harness.nodes[n].name for n in net.free)[:6])
                     + (" ..." if len(net.free) > 6 else ""))
    return Installed(harness, segments, {j.node: j.position.copy() for j in net.junctions},
                     held, iterations, balance, tuple(notes),
                     {j.node: j.rotation.copy() for j in net.junctions}, jac,
                     (net.design, net.frames), net.released, margin)


def installed_checks(installed: Installed, rules=None) -> list:
    """The installed harness's checks (``assembly.harness.DesignCheck`` records): each
    segment's tightest bend against its limit (the bend margin as in the A/D
    evaluation), a segment pulled straight (no slack left: a harness too short), its
    branches against each other (``assembly.harness_clearance``), and the load on each
    connector and fixing (reported: no public rule limits it)."""
    from pliant.assembly.checks import Zone, zone_of  # noqa: PLC0415
    from pliant.assembly.harness import DesignCheck  # noqa: PLC0415
    from pliant.io.rules_file import load_rules  # noqa: PLC0415

    rules = rules or load_rules()
    out = []
    for seg_id, seg in installed.segments.items():
        name = installed.harness.segments[seg_id].name
        where = f"segment {seg_id}"
        if seg.bend_limit is None:
            out.append(DesignCheck(where, "installed bend radius", seg.bend_radius, None,
                                   Zone.UNCHECKED, "no bend limit for its wires", name=name))
        else:
            zone = zone_of(seg.bend_radius, rules.bend_margin * seg.bend_limit,
                           seg.bend_limit, "below")
            out.append(DesignCheck(where, "installed bend radius", seg.bend_radius,
                                   seg.bend_limit, zone,
                                   f"tightest {seg.bend_radius * 1e3:.1f} mm against "
                                   f"{seg.bend_limit * 1e3:.1f} mm",
                                   rules.bend_margin_sourced.source, name=name))
        eq = seg.equilibrium
        if eq.verdict == "unstable":
            _, eigen = eq.stability
            out.append(DesignCheck(where, "stability", eigen, 0.0, Zone.UNCHECKED,
                                   f"its installed shape is unstable (smallest eigenvalue "
                                   f"{eigen:.3g} N m): it would snap to another, so this "
                                   "segment's other checks do not hold", name=name))
        chord = float(np.linalg.norm(eq.position[-1] - eq.position[0]))
        ends_held = sum(1 for c in eq.problem.conditions if c.s in (0.0, eq.problem.part.length))
        if ends_held == 2 and chord >= 0.999 * eq.problem.part.length:
            out.append(DesignCheck(where, "slack", chord, eq.problem.part.length, Zone.YELLOW,
                                   f"pulled straight: its ends {chord * 1e3:.1f} mm apart, it is "
                                   f"{eq.problem.part.length * 1e3:.1f} mm long (no slack for "
                                   "tolerances: lengthen it)", name=name))
        report = seg.interference
        if report is not None:
            nearest = report.smallest  # type: ignore[attr-defined]
            if nearest is not None:
                gap = float(nearest.clearance)
                zone = (Zone.RED if report.penetrations  # type: ignore[attr-defined]
                        else Zone.YELLOW if report.too_close  # type: ignore[attr-defined]
                        else Zone.GREEN)
                out.append(DesignCheck(
                    where, "clearance", gap, report.margin, zone,  # type: ignore[attr-defined]
                    f"{gap * 1e3:.1f} mm from {nearest.obstacle}" + (
                        " (it rests on it)" if gap <= 1e-5 and zone != Zone.RED else ""),
                    "the scene's margin", name=name))
    if len(installed.segments) > 1:
        from pliant.assembly.harness_clearance import branch_checks  # noqa: PLC0415

        out += branch_checks(installed, installed.margin)
    for key, (force, moment) in installed.held.items():
        out.append(DesignCheck(key, "load from the harness", float(np.linalg.norm(force)), None,
                               Zone.INFO, f"{np.linalg.norm(force):.2f} N, "
                               f"{np.linalg.norm(moment):.3f} N m (no public rule: compare "
                               "with the connector's or clip's rating)"))
    return out
