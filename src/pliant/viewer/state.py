"""One browser tab's session: a scene, its grips and a coupled ``Session``, turned into the
protocol's messages. The server gives each connection its own ``ViewerState``; nothing
here knows about sockets, so it is tested directly.

Files: the scene, the meshes it names and the saved sessions are all read from the scene's
folder (``root``) and nowhere else; a name that resolves outside it is refused.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError

from pliant.assembly.checks import shape_warnings
from pliant.core.conditions import Condition
from pliant.errors import InputError, PliantError
from pliant.io.jsontext import finite
from pliant.session import grips
from pliant.viewer import protocol as P
from pliant.viewer.protocol import ProtocolError

if TYPE_CHECKING:
    from pliant.session import Session



class SessionFile(BaseModel):
    """A saved session: the scene file (by name, in the same folder) and every grip."""

    model_config = ConfigDict(extra="forbid")
    v: int = P.VERSION
    scene: str
    grips: list[P.Grip]


def save_folder(root: Path) -> Path:
    """Where a scene's sessions are saved: its own folder, unless that is the installed
    package's (the bundled scene: writing there would change the installation) or not
    writable; then ``$PLIANT_SESSIONS``, else ``~/.local/share/pliant/sessions``, in a
    folder named after the scene's."""
    package = Path(__file__).resolve().parents[1]
    if not root.is_relative_to(package) and os.access(root, os.W_OK):
        return root
    base = os.environ.get("PLIANT_SESSIONS")
    user = Path(base) if base else Path.home() / ".local" / "share" / "pliant" / "sessions"
    return (user / root.name).resolve()


def inside(root: Path, name: str, what: str) -> Path:
    """``root / name``, or a ``ProtocolError`` when it leaves ``root``. A scene is judged
    by its name as written (``..`` and absolute paths leave), so that a link the user put
    in their folder is followed (the bundled examples link to the package's demo scene);
    a session file, which clients write and name, also by where its links lead."""
    path = (root / name).resolve() if what != "scene" else Path(os.path.normpath(root / name))
    if not path.is_relative_to(root):
        raise ProtocolError(f"{what} {name!r} is outside the scene's folder {root}; the "
                            "server reads and writes only there", what)
    return path


class ViewerState:
    """The scene at ``scene_path`` (inside ``root``) in one coupled session.

    live : the accurate model runs in a worker process (the server); inline otherwise
    (tests: deterministic). ``elements`` overrides the scene's resolution. ``envelopes``:
    a variation study's envelope meshes (``load_envelope``) shown with the scene.
    """

    def __init__(self, scene_path: Path, root: Path, *, live: bool = True,
                 elements: int | None = None,
                 envelopes: list[P.ObstacleMesh] | None = None,
                 display: int | None = None) -> None:
        self.root = root.resolve()
        self.saves = save_folder(self.root)
        self.display = display  # triangles the page draws of the obstacles (None: default)
        self.live = live
        self.elements = elements
        self.envelopes = list(envelopes or [])
        self._listener: Callable[[], None] | None = None
        self._open(inside(self.root, str(scene_path), "scene"))

    # -- opening a scene -------------------------------------------------------------------
    def _open(self, path: Path) -> None:
        from pliant.assembly.scenes import load_scene  # noqa: PLC0415
        from pliant.session import Session  # noqa: PLC0415

        scene = load_scene(path)
        problem = scene.problem
        session = Session(problem, live=self.live,
                          elements=self.elements or scene.solver.elements)
        old: Session | None = getattr(self, "session", None)
        if old is not None:
            old.close()
        self.session: Session = session
        session.notify(self._listener)
        self.scene, self.path = scene, path
        self.original = {c.name: c for c in problem.conditions}
        self.modes = {c.name: grips.grip_mode(c, scene.fixed) for c in problem.conditions}
        self.radius = problem.part.drawn_radius
        self.bend_limit = _bend_limit(scene)
        self._published = session.solves.total
        self._searched = session.searches.total
        self._meshes: list[P.ObstacleMesh] | None = None

    def close(self) -> None:
        self.session.close()

    @property
    def dimension(self) -> int:
        return self.session.problem.dimension

    # -- messages in -----------------------------------------------------------------------
    def handle(self, message) -> list[P._Message]:
        """The replies to one parsed client message (``ProtocolError`` or ``PliantError``
        when it cannot be done: the caller replies with an error and goes on), with any
        accurate result the session published meanwhile."""
        if isinstance(message, P.ClientHello):
            replies = [self.scene_message(), self.accurate_message(), self.poll_frame(0)]
        elif isinstance(message, P.ClientMove):
            replies = [self.move(message)]
        elif isinstance(message, P.ClientMode):
            replies = [self.switch(message), self.scene_message()]
        elif isinstance(message, P.ClientSolve):
            self.session.request_accurate()
            replies = [self.poll_frame(0)]
        elif isinstance(message, P.ClientEquilibria):
            self.session.find_equilibria(message.budget)
            replies = [self.poll_frame(0)]
        elif isinstance(message, P.ClientChoose):
            self.session.choose(message.option)
            replies = [self.poll_frame(0)]
        elif isinstance(message, P.ClientSave):
            replies = [self.save(message.name)]
        elif isinstance(message, P.ClientLoad):
            self.load(message.name)
            replies = [self.scene_message(), self.accurate_message(), self.poll_frame(0)]
        else:
            raise ProtocolError(f"unknown message {type(message).__name__}", "type")
        return replies + self._published_since()

    def move(self, message: P.ClientMove) -> P.ServerFrame:
        mode = self.modes.get(message.grip)
        if mode is None:
            raise ProtocolError(f"no grip is named {message.grip!r}; the grips are "
                                + ", ".join(repr(n) for n, m in self.modes.items()
                                            if m != "fixed"), "grip")
        if mode != "position":
            how = "fixed" if mode == "fixed" else "pushed by a force"
            raise ProtocolError(f"{message.grip!r} is {how}; only a grip held by position "
                                "is moved", "grip")
        cond = self._condition(message.grip)
        try:
            event = grips.pose_event(cond, message.position, message.tangent, self.dimension)
        except InputError as err:  # a value of the message: the protocol's error
            raise ProtocolError(str(err), err.field) from None
        return self._frame_message(self.session.apply(event), message.seq)

    def switch(self, message: P.ClientMode) -> P.ServerFrame:
        """Hold a grip by position or push with a force (see ``ClientMode``; the rules
        are ``pliant.session.grips``'s)."""
        name = message.grip
        if self.modes.get(name) in (None, "fixed"):
            raise ProtocolError(f"{name!r} is not a grip the user drives", "grip")
        cond = self._condition(name)
        last = self.session.accurate
        if message.mode == "force":
            new = grips.pushed(cond, last, self.dimension, message.force, message.moment)
        else:
            new = grips.held(cond, self.original[name], last, self.dimension)
        problem = self.session.problem.with_conditions(
            new if c.name == name else c for c in self.session.problem.conditions)
        frame = self.session.replace(problem)
        self.modes[name] = message.mode
        return self._frame_message(frame, 0)

    def poll_frame(self, seq: int) -> P.ServerFrame:
        return self._frame_message(self.session.poll(), seq)

    def watch(self, listener: Callable[[], None] | None) -> None:
        """Have ``listener()`` called (from another thread) as each live answer of the
        accurate model arrives, this session's and those of a session loaded later: the
        server then calls ``take_accurate`` and pushes what it returns."""
        self._listener = listener
        self.session.notify(listener)

    def take_accurate(self) -> list[P._Message]:
        """What arrived from the accurate model since the last call: its results, then a
        frame of the network retuned to them; empty when nothing arrived."""
        frame = self.session.poll() if self.session.pending else None
        out = self._published_since()
        if out and frame is not None:
            out.append(self._frame_message(frame, 0))
        return out

    def _published_since(self) -> list[P._Message]:
        """The session's results not yet sent (a frame may have taken them in)."""
        out: list[P._Message] = []
        out += [self._accurate(r) for r in self.session.solves.since(self._published)]
        self._published = self.session.solves.total
        out += [self._equilibria(f) for f in self.session.searches.since(self._searched)]
        self._searched = self.session.searches.total
        return out

    def _equilibria(self, found) -> P.ServerEquilibria:
        return P.ServerEquilibria(
            index=found.index, current=found.index == self.session.index, ok=found.ok,
            error=found.error, seconds=found.seconds, options=[P.EquilibriumOption(
                position=_pad3(o.position).tolist(), potential_energy=o.potential_energy,
                energy=o.energy, verdict=o.verdict, smallest_eigenvalue=o.smallest_eigenvalue,
                bows=o.bows, max_moment=o.max_moment, notes=list(o.notes))
                for o in found.options])

    # -- sessions on disk ------------------------------------------------------------------
    def save(self, name: str) -> P.ServerSaved:
        from pliant.io.atomic import atomic_write  # noqa: PLC0415

        path = inside(self.saves, f"{name}.json", "name")
        record = SessionFile(scene=str(self.path.relative_to(self.root)), grips=self.grips())
        text = json.dumps(finite(record.model_dump()), indent=1).encode()
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda h: h.write(text), "the session")
        return P.ServerSaved(name=path.name, folder=str(path.parent))

    def load(self, name: str) -> None:
        path = inside(self.saves, f"{name}.json", "name")
        if not path.is_file():
            raise ProtocolError(f"no saved session {path.name} in {self.saves}", "name")
        try:
            record = SessionFile.model_validate_json(path.read_bytes())
        except (ValidationError, OSError) as err:
            raise ProtocolError(f"{path.name} is not a pliant session: "
                                f"{str(err).splitlines()[0]}", "name") from None
        scene = inside(self.root, record.scene, "scene")
        if scene != self.path:
            if not scene.is_file():
                raise ProtocolError(f"the session's scene {record.scene} is not in {self.root}",
                                    "scene")
            self._open(scene)
        conditions = {c.name: c for c in self.session.problem.conditions}
        for grip in record.grips:
            if grip.mode == "fixed" and self.modes.get(grip.name) == "fixed":
                continue  # clamps and ports stay as the scene has them
            if grip.name not in conditions or self.modes.get(grip.name) == "fixed":
                raise ProtocolError(f"{path.name}: {grip.name!r} is not a grip of this scene",
                                    "grips")
            conditions[grip.name] = grips.restored(
                conditions[grip.name], self.original[grip.name], grip.mode, grip.position,
                grip.tangent, grip.force, grip.moment, self.dimension)
            self.modes[grip.name] = grip.mode
        problem = self.session.problem.with_conditions(
            conditions[c.name] for c in self.session.problem.conditions)
        self.session.replace(problem)

    # -- messages out ----------------------------------------------------------------------
    def grips(self) -> list[P.Grip]:
        out = []
        last = self.session.accurate
        for cond in self.session.problem.conditions:
            mode = self.modes[cond.name]
            d = self.dimension
            if all(v is not None for v in cond.position):
                position = _pad(cond.position)
            elif last is not None and last.ok:
                position = _pad(grips.point_at(last.s, last.position, cond.s)[0])
            else:
                position = [0.0, 0.0, 0.0]
            tangent: list[float] | None = None
            if d == 3 and cond.tangent is not None:
                tangent = [float(x or 0.0) for x in cond.tangent]
            elif d == 2 and cond.angle is not None:
                tangent = [math.cos(cond.angle), math.sin(cond.angle), 0.0]
            force = moment = None
            if mode == "force":
                force = _pad(tuple(v or 0.0 for v in cond.force))
                m = cond.moment
                moment = ([0.0, 0.0, float(m or 0.0)] if not isinstance(m, tuple)
                          else [float(x or 0.0) for x in m])
            out.append(P.Grip(name=cond.name, s=cond.s, position=position, tangent=tangent,
                              mode=mode, force=force, moment=moment))
        return out

    def scene_message(self) -> P.ServerScene:
        problem = self.session.problem
        part = problem.part
        if self._meshes is None:
            from pliant.io.mesh_export import (  # noqa: PLC0415
                display_budgets,
                display_obstacle,
                triangles,
            )

            self._meshes = []
            budgets = display_budgets([triangles(o) for o in problem.obstacles], self.display)
            for obstacle, budget in zip(problem.obstacles, budgets):
                mesh = display_obstacle(obstacle, budget)
                self._meshes.append(P.ObstacleMesh(
                    name=obstacle.name,
                    vertices=np.round(mesh.vertices, 6).tolist(),
                    faces=mesh.faces.tolist()))
        return P.ServerScene(
            name=problem.name or self.path.stem, file=str(self.path.relative_to(self.root)),
            dimension=problem.dimension,
            part={"name": part.name, "length": part.length, "radius": self.radius,
                  "min_bend_radius": self.bend_limit},
            obstacles=self._meshes, grips=self.grips(), margin=self.scene.margin,
            envelopes=self.envelopes, path=self.path_play(),
            ports=[P.Port(name=name, position=[float(x) for x in port.position],
                          axis=[float(x) for x in port.axis], note=port.note)
                   for name, port in self.scene.ports.items() if port.position is not None])

    def path_play(self) -> P.PathPlay | None:
        """The scene's [path] as the grip's poses step by step (None without one)."""
        scene = self.scene
        if not scene.path or scene.grip is None or self.dimension != 3:
            return None
        n = len(scene.path)
        keep = (range(n) if n <= P.PATH_STEPS else
                sorted({round(k * (n - 1) / (P.PATH_STEPS - 1)) for k in range(P.PATH_STEPS)}))
        poses = [scene.path[k].condition(scene.grip) for k in keep]
        tangents = None
        if all(c.tangent is not None for c in poses):
            tangents = [[round(float(x or 0.0), 9) for x in c.tangent or ()] for c in poses]
        return P.PathPlay(grip=scene.grip, tangents=tangents,
                          positions=[[round(float(x or 0.0), 9) for x in c.position]
                                     for c in poses])

    def accurate_message(self) -> P.ServerAccurate:
        if self.session.accurate is None:
            why = getattr(self.session, "start_error", None)
            return P.ServerAccurate(index=0, ok=False, error=(
                f"the start pose has no equilibrium: {why}; move the grips to one that has"
                if why else "no accurate solve yet"))
        return self._accurate(self.session.accurate)

    def _accurate(self, result) -> P.ServerAccurate:
        if not result.ok:
            return P.ServerAccurate(index=result.index, ok=False, error=result.error,
                                    solve_seconds=result.solve_seconds)
        position = _pad3(result.position)
        loads = []
        for name, load in result.loads.items():
            # Where the load acts now (a sliding clip's s is where it slid to).
            point = grips.point_at(result.s, result.position, load.s)[0]
            moment = np.atleast_1d(np.asarray(load.moment, float))
            loads.append(P.Load(name=name, position=_pad(point),
                                force=_pad(load.force),
                                moment=([0.0, 0.0, float(moment[0])] if moment.size == 1
                                        else moment[:3].tolist()),
                                prescribed=list(load.prescribed)))
        contacts = []
        if result.contacts is not None:
            c = result.contacts
            contacts = [P.Contact(s=float(c.s[k]), point=c.point[k].tolist(),
                                  force=c.force[k].tolist(), obstacle=c.obstacle[k])
                        for k in range(len(c))]
        fitted = getattr(result, "fitted", {})
        interference = self._accurate_interference(result, position, fitted)
        radius, s_radius = result.min_bend_radius
        allowed = self.bend_limit
        warnings = shape_warnings(bend_radius=radius, bend_at=s_radius, allowed=allowed,
                                  stable=result.stable, eigenvalue=result.smallest_eigenvalue,
                                  penetrations=interference.penetrations)
        verdict = self._verdict(result, interference)
        return P.ServerAccurate(
            index=result.index, ok=True, s=result.s.tolist(), position=position.tolist(),
            curvature=result.curvature.tolist(), bending_moment=result.bending_moment.tolist(),
            loads=loads, contacts=contacts, interference=interference,
            min_bend_radius=radius, min_bend_radius_s=s_radius, allowed_bend_radius=allowed,
            stable=result.stable, smallest_eigenvalue=_finite(result.smallest_eigenvalue),
            residual=result.residual, iterations=result.iterations,
            solve_seconds=result.solve_seconds, warnings=warnings, notes=list(result.notes),
            verdict=verdict,
            fitted=[P.FittedShape(name=name, position=np.round(line, 6).tolist(), radius=r)
                    for name, (line, r, _) in fitted.items()],
            branches=[P.FittedShape(name=name, position=np.round(line, 6).tolist(), radius=r)
                      for name, (line, r) in getattr(result, "branches", {}).items()])

    def _verdict(self, result, interference: P.Interference) -> P.Verdict | None:
        """The pose's evaluation by the same rules as ``pliant evaluate`` (3D scenes);
        None where it cannot be judged (2D, no grip)."""
        if self.dimension != 3:
            return None
        from pliant.assembly.checks import Zone  # noqa: PLC0415
        from pliant.assembly.evaluate import evaluate_pose, worst_zone  # noqa: PLC0415

        clearances = {c.obstacle: c.clearance for c in interference.clearances}
        held = tuple(name for name, mode in self.modes.items() if mode != "fixed")
        try:
            ev = evaluate_pose(self.scene, result, clearances, grips=held or None)
        except PliantError:
            return None
        chosen = ev.chosen
        zone = worst_zone(ev.checks + (chosen.checks if chosen else []))
        if not ev.verdict.decided:  # a fallback: no colour of a verdict
            zone = Zone.UNCHECKED
        hands, worker = _bodies(ev)
        return P.Verdict(passes=ev.verdict.passes, headline=ev.verdict.headline,
                         operator=ev.verdict.operator, zone=zone.value,
                         items=[P.VerdictItem(zone=c.zone.value,
                                              text=c.sentence(with_step=False),
                                              source=f"{c.source} ({c.provenance})")
                                for c in ev.items], hands=hands, worker=worker)

    def _frame_message(self, frame, seq: int) -> P.ServerFrame:
        rt = frame.realtime
        curve = np.asarray(rt.curve, float)
        s = np.asarray(rt.s_curve, float)
        curvature = _curvature(s, curve)
        interference = self._preview_interference(s, curve)
        i = int(np.argmax(curvature)) if curvature.size else 0
        tightest = 1.0 / curvature[i] if curvature.size and curvature[i] > 0 else np.inf
        warnings = shape_warnings(
            bend_radius=float(tightest), bend_at=float(s[i]) if s.size else 0.0,
            allowed=self.bend_limit,
            penetrations=interference.penetrations, preview=True)
        return P.ServerFrame(
            seq=seq, index=frame.index, s=s.tolist(), curve=np.round(curve, 7).tolist(),
            curvature=curvature.tolist(),
            contacts=_pad3(np.asarray(rt.contact_points, float)).tolist(),
            interference=interference, converged=bool(rt.converged),
            drift=float(frame.drift.distance_to_accurate), pending=bool(frame.pending),
            seconds=float(frame.seconds), warnings=warnings)

    def _accurate_interference(self, result: Any, position: np.ndarray,
                               fitted: dict) -> P.Interference:
        """An accurate answer's interference, measured as the CLI and the files measure it
        (``interference.of_answer``: one number for one clearance), the flexible parts
        already fitted as it deformed them (``fitted``)."""
        from pliant.scene.interference import of_answer  # noqa: PLC0415

        obstacles = self.session.problem.obstacles
        if not obstacles:
            return _no_interference(self.scene.margin)
        return _interference_message(of_answer(
            result.s, position, result.contacts, self.session.problem.part.tube_radius,
            obstacles, margin=self.scene.margin, tubes=fitted))

    def _preview_interference(self, s: np.ndarray, points: np.ndarray) -> P.Interference:
        """A real-time frame's interference: coarser, at the drawn radius, the fitted
        parts at rest (as their tubes are)."""
        from pliant.scene.interference import of_curve  # noqa: PLC0415

        obstacles = self.session.problem.obstacles
        if not obstacles:
            return _no_interference(self.scene.margin)
        return _interference_message(of_curve(
            s, points, self.radius, obstacles, margin=self.scene.margin,
            tolerance=0.01 * self.radius, subdivide=2))

    def _condition(self, name: str) -> Condition:
        found = next((c for c in self.session.problem.conditions if c.name == name), None)
        if found is None:
            raise ProtocolError(f"no condition is named {name!r}", "grip")
        return found


# -- helpers ---------------------------------------------------------------------------------
def load_envelope(path: Path) -> list[P.ObstacleMesh]:
    """The meshes of a study's envelope GLB (a study folder: its envelope.glb), each
    named as ``pliant study`` named it."""
    import trimesh  # noqa: PLC0415

    from pliant.errors import InputError  # noqa: PLC0415

    path = Path(path)
    if path.is_dir():
        path = path / "envelope.glb"
    try:
        loaded = trimesh.load_scene(path)
    except (OSError, ValueError, NotImplementedError) as err:
        raise InputError("envelope", f"{path}: cannot be read as a GLB ({err}); give the "
                         "envelope.glb of a pliant study, or its folder") from None
    return [P.ObstacleMesh(name=name, vertices=np.round(mesh.vertices, 6).tolist(),
                           faces=mesh.faces.tolist())
            for name, mesh in loaded.geometry.items()]


def _pad(v) -> list[float]:
    v = [float(x) for x in v]
    return (v + [0.0, 0.0, 0.0])[:3]


def _pad3(a: np.ndarray) -> np.ndarray:
    """Points (n, 2 or 3) as (n, 3): a 2D scene lies in z = 0."""
    a = np.asarray(a, float)
    return a if a.shape[1] == 3 else np.column_stack([a, np.zeros((a.shape[0], 3 - a.shape[1]))])


def _curvature(s: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """|r' x r''| / |r'|^3 of a sampled curve [1/m] (second-order differences in s)."""
    d1 = np.gradient(curve, s, axis=0)
    d2 = np.gradient(d1, s, axis=0)
    speed = np.maximum(np.linalg.norm(d1, axis=1), 1e-300)
    return np.linalg.norm(np.cross(d1, d2), axis=1) / speed ** 3


def _span(span) -> P.Span:
    return P.Span(obstacle=span.obstacle, s_start=span.s_start, s_end=span.s_end,
                  worst=span.worst)


def _no_interference(margin: float) -> P.Interference:
    """A scene without obstacles: nothing to clear."""
    return P.Interference(margin=margin, clearances=[], penetrations=[], too_close=[])


def _interference_message(report: Any) -> P.Interference:
    """An interference report as the wire protocol carries it."""
    return P.Interference(
        margin=report.margin,
        clearances=[P.Clearance(obstacle=c.obstacle, clearance=c.clearance, s=c.s,
                                point=list(c.point)) for c in report.clearances],
        penetrations=[_span(x) for x in report.penetrations],
        too_close=[_span(x) for x in report.too_close])


def _bend_limit(scene: Any) -> float | None:
    """The part's centreline bend limit by the scene's rules: the one its verdict uses
    (``evaluate.centreline_bend_limit``); the part's minimum where the rules cannot be
    read (the verdict then says why)."""
    from pliant.assembly.evaluate import centreline_bend_limit  # noqa: PLC0415
    from pliant.io.rules_file import load_rules  # noqa: PLC0415

    try:
        rules = load_rules(scene.evaluation.rules)
    except PliantError:
        return scene.problem.part.min_bend_radius
    return centreline_bend_limit(scene.problem.part, rules)


def _bodies(ev: Any) -> tuple[list[P.HandShape], list[P.WorkerShape]]:
    """The hands' envelopes and the worker's stick figures the evaluation of a pose
    judged (``Evaluation.bodies``), to draw."""
    from pliant.assembly.evaluate import worst_zone  # noqa: PLC0415

    op = ev.bodies
    if op is None:
        return [], []

    def zone_of(grip: str, rules: tuple[str, ...]) -> str:
        return worst_zone([c for c in op.checks
                           if c.grip == grip and c.rule.startswith(rules)]).value

    hands = [P.HandShape(grip=g, centre=list(a[0].centre), approach=list(a[0].approach),
                         reach=a[0].reach, ring=a[0].ring, clearance=a[0].clearance,
                         bound_by=a[0].bound_by, zone=zone_of(g, ("access",)))
             for g, a in op.access.items()]
    workers = [P.WorkerShape(grip=g, chain=[list(p) for p in steps[0].chain],
                             side=steps[0].side, zone=zone_of(g, ("reach", "posture")))
               for g, steps in op.reach.items()]
    return hands, workers


def _finite(value: Any) -> float | None:
    """A number the page can show, or None (not known, or not finite)."""
    return float(value) if value is not None and math.isfinite(value) else None
