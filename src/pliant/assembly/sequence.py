"""A/D sequences: in which order can several flexible parts be fitted, and why do the
other orders fail?

An order is a sequence of operations; each operation is one part carried along its own
``[path]`` and judged by ``pliant.assembly.evaluate``, with the product's obstacles and
every part fitted before it in the scene. Where the file declares a ``[[hook]]`` for a
part, that part may instead be fitted in two operations (a non-monotone move): carried
to the hook and left there, held in the hand's pose (``<part> onto <hook>``), then,
after other parts, taken from there to its goal along its own path or a planned one
(``<part> off <hook>``); between the two it is fitted in its shape on the hook, as the
obstacle ``<part> (on <hook>)``. Each part thus placed: a fitted part is a flexible obstacle
(``FittedPart``: a part that touches it deforms it, and the two are solved together) in
the shape it settles in once the fitter lets go (its last step's problem, the hand's
other grips released, solved alone with the parts fitted before it as rigid tubes; the
shape ``[[assembled]]`` parts take, so the same part fitted or assembled is one thing).

The search goes forward, depth by depth, over the tree of prefixes: an operation is
judged once for its prefix (the parts fitted before it, in their order) and reused by
every order that shares that prefix. Pruning: an operation that fails names the fitted
parts that make it fail (its ``blockers``: those it touches or comes within its margin
of, or that a red check names; all of the prefix where none can be named; none where
it fails alone). An operation of the same part after a prefix that holds all of some
failure's blockers is not judged: it is pruned with that failure's reason. This rests
on one assumption: a part fitted in the way stays in the way whatever else is fitted.
``exhaustive=True`` prunes nothing (the slow twin the tests compare with).

The operations of one depth run together, on Dask (the same local cluster or scheduler
as ``pliant study``) or in this process (``workers=0``); each result is appended to the
store's ``operations.jsonl`` as it arrives, so an interrupted search resumes with only
what is missing, to the same answer (nothing in it is random).

Costs of an order that passes, compared in turn: its worst zone (green before yellow),
the operator its hardest operation needs (one hand, then two hands, then a tool or a
robot), the re-grasps (the hooks it uses: each is a second grasp of the part), the peak
hand demand (a capacity check's value over its red limit), the sum of the operations'
peak demands.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from pliant.core.planning import PathSpec
from pliant.errors import InputError, PliantError
from pliant.io.jsonlines import JsonLines
from pliant.io.sequence_file import SequenceScene

SEQUENCE_VERSION = 1
ZONES = ("green", "yellow", "red")  # an operation's worst zone, by rank


# -- loading and composing --------------------------------------------------------------
def load_sequence(path: str | Path) -> SequenceScene:
    """Read a sequence file (``pliant.io.sequence_file``), its [[assembled]] parts
    settled as a scene's are."""
    from pliant.assembly.scenes import settle_fitted  # noqa: PLC0415
    from pliant.io.sequence_file import load_sequence as read  # noqa: PLC0415

    return read(path, settle=settle_fitted)


@dataclass(frozen=True)
class Step:
    """One operation a sequence may hold: part ``part`` (its index) fitted at once
    (``hook`` None), or left on hook ``hook`` (its index; ``onto``) or taken from it to
    its goal (not ``onto``); ``name`` is what records and orders call it."""

    part: int
    hook: int | None
    onto: bool
    name: str


def steps(seq: SequenceScene) -> list[Step]:
    """The operations of a sequence file, by index: each part fitted at once (index =
    the part's), then each hook's two operations (onto, then off). InputError where two
    would share a name."""
    out = [Step(i, None, False, f.name) for i, f in enumerate(seq.fits)]
    for h, hook in enumerate(seq.hooks):
        part = seq.fits[hook.part].name
        out += [Step(hook.part, h, True, f"{part} onto {hook.name}"),
                Step(hook.part, h, False, f"{part} off {hook.name}")]
    names = [st.name for st in out]
    for name in names:
        if names.count(name) > 1:
            raise InputError("hook", f"two operations would be called {name!r}; name the "
                             "hook or the part apart")
    return out


def placed_name(seq: SequenceScene, step: Step) -> str:
    """The obstacle a part is once placed by ``step``: its own name, or on a hook
    ``<part> (on <hook>)``."""
    name = seq.fits[step.part].name
    return f"{name} (on {seq.hooks[step.hook].name})" if step.onto and step.hook is not None \
        else name


def _next(all_steps: list[Step], prefix: Sequence[int]) -> list[int]:
    """The operations that may follow ``prefix``: a part not yet placed, fitted at once
    or left on one of its hooks; a part on a hook, taken from it."""
    touched = {all_steps[i].part for i in prefix}
    return [i for i, st in enumerate(all_steps)
            if (st.part not in touched if st.hook is None or st.onto
                else i - 1 in prefix and i not in prefix)]


def _complete(all_steps: list[Step], prefix: Sequence[int], parts: int) -> bool:
    """Whether every part is at its goal after ``prefix``."""
    return len({all_steps[i].part for i in prefix if not all_steps[i].onto}) == parts


def _placed(all_steps: list[Step], prefix: Sequence[int]) -> dict[int, int]:
    """Where in ``prefix`` each placed part's last operation is (part -> position), in
    the order they were last placed."""
    out: dict[int, int] = {}
    for k, i in enumerate(prefix):
        out.pop(all_steps[i].part, None)
        out[all_steps[i].part] = k
    return out


def _present(seq: SequenceScene, all_steps: list[Step], prefix: Sequence[int],
             part: int) -> list[str]:
    """The names of the parts placed after ``prefix`` that operations on part ``part``
    meet (its own shape on a hook is not an obstacle to it)."""
    return [placed_name(seq, all_steps[prefix[k]])
            for p, k in _placed(all_steps, prefix).items() if p != part]


def operation_scene(seq: SequenceScene, part: int, fitted: Sequence[Any] = ()) -> Any:
    """The scene of operation ``part`` (a ``steps`` index: a part's own index fits it at
    once) with ``fitted`` (obstacles of the parts placed before it) in place: its own
    file's scene with the sequence's obstacles, their packaging rules and margin added
    and its [path] carried among them; onto a hook, the grip carried to the hook (no
    port to seat); off it, the grip starting where the hook holds it."""
    from pliant.assembly.path import carry  # noqa: PLC0415

    step = steps(seq)[part]
    fit = seq.fits[step.part]
    scene = fit.scene
    problem = replace(scene.problem, obstacles=(*scene.problem.obstacles, *seq.obstacles,
                                                *fitted))
    margin = scene.margin if seq.margin is None else seq.margin
    spec = scene.path_spec
    if step.hook is not None:
        hook = seq.hooks[step.hook]
        grip = _hook_grip(scene, hook.name)
        if step.onto:
            points = (*hook.via, hook.position)
            spec = PathSpec(grip, points, None if hook.tangent is None
                            else (hook.tangent,) * len(points), hook.steps,
                            spec.carry if spec is not None else ())
            scene = replace(scene, grip=grip, evaluation=replace(scene.evaluation, port=None))
        else:
            problem = _at_hook(problem, grip, hook, spec)
    return replace(scene, problem=problem, margin=margin,
                   obstacle_rules={**seq.obstacle_rules, **scene.obstacle_rules},
                   path_spec=spec, path=carry(problem, spec))


def _hook_grip(scene: Any, hook: str) -> str:
    """The condition a hook holds: the part's [path] grip, else the hand a planned path
    carries; InputError naming the hook where the part has none."""
    if scene.path_spec is not None:
        return str(scene.path_spec.grip)
    if scene.grip:
        return str(scene.grip)
    if scene.hands:
        return str(scene.hands[0])
    raise InputError(f"hook {hook!r}", "its part has no hand to leave it on the hook: give "
                     "the part's file a [path] or a condition with hand = true")


def _at_hook(problem: Any, grip: str, hook: Any, spec: PathSpec | None) -> Any:
    """The part's problem with its grip where the hook holds it (the hook's pose) and
    the hands carried with it moved along, as a part taken from the hook starts."""
    from pliant.assembly.path import carried_conditions, carry_with  # noqa: PLC0415

    held = problem.condition(grip)
    tangent = held.tangent if hook.tangent is None else tuple(
        np.asarray(hook.tangent, float) / np.linalg.norm(hook.tangent))
    carried = carried_conditions(problem, spec.carry, grip) if spec is not None else []
    moved = carry_with(held, hook.position, tangent, carried)
    changes: dict[str, Any] = {"position": tuple(map(float, hook.position))}
    if hook.tangent is not None:
        changes["tangent"] = tuple(map(float, tangent))
        if held.normal is not None:
            changes["normal"] = None  # the hand's roll follows the turn, as a path's
    moved[grip] = replace(held, **changes)
    return problem.with_conditions(moved.get(c.name, c) for c in problem.conditions)


def fitted_problem(seq: SequenceScene, part: int, before: Sequence[Any]) -> Any:
    """The problem of operation ``part`` (a ``steps`` index) once done after the parts
    whose (rigid) obstacles are ``before``: its path's last step, the hand's other grips
    let go (the grip that seated it stays: the port, or the hook, holds it there),
    named as the part placed (``placed_name``)."""
    scene = operation_scene(seq, part, before)
    last = scene.path[-1] if scene.path else seated(scene)
    hands = set(scene.hands) - {scene.grip}
    return replace(last, conditions=tuple(c for c in last.conditions if c.name not in hands),
                   name=placed_name(seq, steps(seq)[part]))


def seated(scene: Any) -> Any:
    """The problem of a part whose path is planned, seated: its grip (the hand the
    planner carries) at its [plan] goal's port, holding the port's axis (the part's end
    going in), the hands it carries along where the carrier takes them."""
    from pliant.assembly.evaluate import prepare  # noqa: PLC0415
    from pliant.assembly.path import carry_with  # noqa: PLC0415

    _, grips, _ = prepare(scene, None)
    grip = scene.problem.condition(scene.grip or grips[0])
    port = scene.ports[scene.plan.goal]
    axis = -np.asarray(port.axis, float) / np.linalg.norm(port.axis)
    moved = carry_with(grip, port.position, axis,
                       [scene.problem.condition(n) for n in scene.plan.carry])
    moved[grip.name] = replace(grip, position=tuple(map(float, port.position)),
                               tangent=tuple(map(float, axis)), normal=None)
    return scene.problem.with_conditions(moved.get(c.name, c)
                                         for c in scene.problem.conditions)


_FITTED: dict[tuple, Any] = {}  # per process: each fitted part's obstacle, by prefix


def fitted_obstacles(seq: SequenceScene, prefix: Sequence[int]) -> list[Any]:
    """The obstacles of the parts placed by ``prefix`` (``steps`` indices, in the order
    done), each in the shape it settles in (see the module), solved once per process."""
    return list(_fitted_by_part(seq, prefix).values())


def _fitted_by_part(seq: SequenceScene, prefix: Sequence[int]) -> dict[int, Any]:
    """``fitted_obstacles`` by part index: a part taken from a hook replaces its shape
    on the hook."""
    from pliant.assembly.scenes import settle_fitted  # noqa: PLC0415

    all_steps = steps(seq)
    out: dict[int, Any] = {}
    for k, i in enumerate(prefix):
        key = (seq.key, tuple(prefix[:k + 1]))
        part = all_steps[i].part
        fit = seq.fits[part]
        out.pop(part, None)
        if key not in _FITTED:
            rigid = [replace(o, fitted=None) for o in out.values()]
            problem = fitted_problem(seq, i, rigid)
            _FITTED[key] = settle_fitted(problem.name, problem, fit.elements, True,
                                         fit.friction)
        obstacle = _FITTED[key]
        out[part] = obstacle if fit.flexible else replace(obstacle, fitted=None)
    return out


# -- one operation ----------------------------------------------------------------------
def judge_operation(seq: SequenceScene, prefix: tuple[int, ...], part: int) -> dict[str, Any]:
    """Do operation ``part`` (a ``steps`` index) after ``prefix``: its evaluation as a
    record (JSON-ready). A failure to solve is a record too (status "error", the fitted
    parts as blockers): a search never stops on one operation."""
    from pliant.assembly.evaluate import evaluate  # noqa: PLC0415 (loads the kernels)

    all_steps = steps(seq)
    step = all_steps[part]
    fit = seq.fits[step.part]
    start = time.process_time()
    record: dict[str, Any] = {"part": step.name,
                              "prefix": [all_steps[i].name for i in prefix]}
    names = _present(seq, all_steps, prefix, step.part)  # what the operation meets
    try:
        fitted = [o for p, o in _fitted_by_part(seq, prefix).items() if p != step.part]
        scene = operation_scene(seq, part, fitted)
        run = None
        if not scene.path:  # planned here, among the parts fitted before
            from pliant.assembly.plan import NoPathError, plan  # noqa: PLC0415

            settings = replace(scene.plan, elements=fit.elements)
            try:
                found = plan(scene, scene.plan.goal, settings)
            except NoPathError as err:
                record.update(_unplanned(err, names))
                record["seconds"] = time.process_time() - start
                return record
            scene = replace(scene, grip=found.grip, path=found.path)
            run = found.run
            record["plan"] = {"waypoints": len(found.poses), "steps": found.steps,
                                 "solves": found.solves, "seconds": found.seconds,
                                 "peak_demand": found.peak_demand}
        # Taken from a hook, the part starts as it hangs there, not from a cold solve.
        hanging = (_on_hook(seq, prefix, step.part)
                   if step.hook is not None and not step.onto and run is None else None)
        ev = evaluate(scene, elements=fit.elements, run=run, start_from=hanging)
        record.update(_judged(ev, names, scene.margin))
    except (PliantError, ValueError, ArithmeticError) as err:
        record = _unjudged(step.name, record["prefix"], "error", f"not judged: {err}",
                           [str(err)], names, stopped=str(err))
    record["seconds"] = time.process_time() - start
    return record


def _on_hook(seq: SequenceScene, prefix: Sequence[int], part: int) -> Any:
    """The equilibrium of part ``part`` as it hangs on its hook after ``prefix`` (whose
    last operation on it left it there)."""
    from pliant.models import rod3d  # noqa: PLC0415

    k = _placed(steps(seq), prefix)[part]
    return rod3d.solved_alone(_FITTED[(seq.key, tuple(prefix[:k + 1]))].fitted)


def _judged(ev: Any, fitted: list[str], margin: float) -> dict[str, Any]:
    """An evaluation's record: its verdict, costs, and the fitted parts it blames."""
    from pliant.assembly.checks import Zone  # noqa: PLC0415
    from pliant.assembly.evaluate import worst_zone  # noqa: PLC0415

    v = ev.verdict
    chosen = ev.chosen
    own = chosen.checks if chosen else []
    zone = worst_zone([c for c in ev.checks + own
                       if c.zone in (Zone.GREEN, Zone.YELLOW, Zone.RED)])
    demand = max((c.ratio for c in own
                  if c.family == "ergonomics" and math.isfinite(c.ratio)), default=0.0)
    forces = [r.force_norm for r in ev.run.steps]
    # A verdict that rests on a fallback passes nothing and prunes nothing: undecided.
    status = "undecided" if not v.decided else "passes" if v.passes else "fails"
    return {"status": status, "passes": status == "passes",
            "decided": bool(v.decided), "zone": zone.value,
            "operator": v.operator, "headline": v.headline, "reasons": list(v.reasons[:6]),
            "blockers": [] if status != "fails" else _blockers(ev, fitted, margin),
            "demand": float(demand), "peak_force": float(max(forces, default=0.0)),
            "steps": len(ev.run.steps), "planned": ev.run.planned,
            "stopped": ev.run.stopped, "notes": _fallbacks(ev),
            "clearance": {name: _smallest(ev.run, name) for name in fitted}}


def _unplanned(err: Any, fitted: list[str]) -> dict[str, Any]:
    """The record of an operation whose path could not be planned: it fails, blaming
    the fitted parts the rejected motions name (all of them where none is named)."""
    reasons = " ".join(err.blocked)
    named = [n for n in fitted if n in reasons]
    return {"status": "fails", "passes": False, "decided": True, "zone": "red",
            "operator": None, "headline": f"DOES NOT FIT: no path planned ({err})",
            "reasons": [f"[red] no path found: {r} ({k} motions)"
                        for r, k in list(err.blocked.items())[:5]],
            "blockers": named or list(fitted), "demand": 0.0, "peak_force": 0.0,
            "steps": 0, "planned": 0, "plan": {"failed": str(err)}, "stopped": str(err),
            "notes": [],
            "clearance": {}}


def _fallbacks(ev: Any) -> list[str]:
    """What the operation's answer did not judge: its unchecked items (a part held
    rigid where it could not be solved together, a stability a static test does not
    decide, a rule missing a value) and a verdict that rests on a fallback."""
    from pliant.assembly.checks import Zone  # noqa: PLC0415

    out = [c.sentence() for c in ev.items if c.zone == Zone.UNCHECKED]
    if not ev.verdict.decided:
        out.append("the verdict is undecided: it rests on a fallback")
    return out


def _smallest(run: Any, name: str) -> float:
    """The smallest clearance [m] to obstacle ``name`` along the run."""
    return min((dict(r.clearances).get(name, math.inf) for r in run.steps),
               default=math.inf)


def _blockers(ev: Any, fitted: list[str], margin: float) -> list[str]:
    """The fitted parts a failing operation blames: those a red check names, those in
    the way of the hand where no hand operator fits, those the part touches or comes
    within the margin of (at any step; where the path stopped, at its last step solved),
    else all of them (the cause cannot be named)."""
    from pliant.assembly.checks import Zone  # noqa: PLC0415

    if not fitted:
        return []
    named = {n for c in ev.checks if c.zone == Zone.RED
             for n in fitted if c.rule.endswith(f": {n}")}
    # a fitted part in the way of the hand (``pliant.assembly.access``) where no hand
    # operator could get round the part
    if all(not o.passes for o in ev.operators if o.access):
        for op in ev.operators:
            for steps in op.access.values():
                named |= {a.bound_by for a in steps if a.clearance < 0.0} & set(fitted)
    near = {n for n in fitted if _smallest(ev.run, n) <= max(margin, 1e-6)}
    for eq in ev.run.equilibria:
        if eq.contacts is not None:
            near |= set(eq.contacts.by_obstacle()) & set(fitted)
    found = named | near
    return [n for n in fitted if n in found] or list(fitted)


# -- the store --------------------------------------------------------------------------
class Store:
    """A search's folder: ``sequence.json`` (the files' digest) and ``operations.jsonl``
    (a line per operation judged, appended as each arrives)."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.log = JsonLines(self.folder / "operations.jsonl")

    def open(self, seq: SequenceScene, restart: bool = False) -> dict[tuple, dict]:
        """Create or reopen the folder for ``seq``: the operations already judged, by
        (prefix names, part name)."""
        from pliant.io.atomic import atomic_write  # noqa: PLC0415

        self.folder.mkdir(parents=True, exist_ok=True)
        meta = self.folder / "sequence.json"
        key = _store_key(seq)
        if meta.exists() and not restart:
            try:
                old = json.loads(meta.read_text(encoding="utf-8"))
            except (OSError, json.JSONDecodeError):
                old = {}
            if old.get("key") != key:
                raise InputError("out", f"{self.folder} holds the search of other files (or "
                                 "another pliant); choose another folder, or --restart")
            self.log.drop_torn()
            return {_op_key(r): r for r in self.log.read()}
        if self.log.path.exists():
            self.log.path.unlink()
        text = json.dumps({"key": key, "sequence": seq.source,
                           "version": SEQUENCE_VERSION}, indent=1).encode()
        atomic_write(meta, lambda h: h.write(text), "the search's key")
        return {}

    def add(self, record: dict[str, Any]) -> None:
        self.log.append(record)


def _store_key(seq: SequenceScene) -> str:
    from pliant import __version__  # noqa: PLC0415

    return hashlib.sha256(f"{seq.key}|{__version__}|{SEQUENCE_VERSION}".encode()).hexdigest()


def _op_key(record: dict[str, Any]) -> tuple:
    return (tuple(record["prefix"]), record["part"])


# -- the search -------------------------------------------------------------------------
@dataclass
class Order:
    """One order, judged: its operations (names: a part's own, or the part onto and off
    a hook), whether every operation passes, their records as far as they go (the last
    one the failing or pruned one), and for an order that passes its cost (see the
    module)."""

    parts: tuple[str, ...]
    passes: bool
    operations: list[dict[str, Any]]
    cost: tuple[float, ...] = ()

    @property
    def failing(self) -> dict[str, Any] | None:
        return None if self.passes else self.operations[-1]

    def why(self) -> str:
        """The first failing operation and its reason, in words."""
        op = self.failing
        if op is None:
            return "every operation passes"
        where = f"fitting {op['part']}" + (f" after {', '.join(op['prefix'])}"
                                           if op["prefix"] else " (first)")
        blame = (f" ({', '.join(op['blockers'])} in the way)" if op.get("blockers") else "")
        pruned = ""
        if op["status"] == "pruned":
            seen = op["pruned_by"][:-1]
            pruned = f"; pruned: it fails {'after ' + ', '.join(seen) if seen else 'alone'}"
        return f"{where} fails{blame}{pruned}: {_reason(op)}"

    def to_dict(self) -> dict[str, Any]:
        return {"parts": list(self.parts), "passes": self.passes,
                "cost": list(self.cost), "why": self.why(),
                "operations": [_op_key(o)[1] for o in self.operations]}


@dataclass
class Precedence:
    """A precedence found: ``first`` must be fitted before ``then`` (any one of them,
    where several block it together), and why (the failure it rests on)."""

    first: str
    then: tuple[str, ...]
    reason: str

    def sentence(self) -> str:
        them = " and ".join(self.then)
        return f"{self.first} before {them}: with {them} fitted first, {self.reason}"

    def to_dict(self) -> dict[str, Any]:
        return {"first": self.first, "then": list(self.then), "reason": self.reason,
                "sentence": self.sentence()}


@dataclass
class SequenceResult:
    """The search as run: every order (the best first: passing ones by cost, then the
    failing ones), the operations judged (by (prefix, part)), how many were judged in
    this run, reused from the store and pruned, the precedences found, on how many
    workers, in how many seconds (wall, this process)."""

    name: str
    source: str
    parts: tuple[str, ...]
    orders: list[Order]
    operations: dict[tuple, dict[str, Any]]
    judged: int
    reused: int
    pruned: int
    precedences: list[Precedence]
    exhaustive: bool
    workers: int
    seconds: float
    folder: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def best(self) -> Order | None:
        return self.orders[0] if self.orders and self.orders[0].passes else None

    @property
    def passes(self) -> bool:
        return self.best is not None

    def to_dict(self) -> dict[str, Any]:
        best = self.best
        return {"schema_version": 1, "name": self.name, "sequence": self.source,
                "parts": list(self.parts), "passes": self.passes,
                "best": None if best is None else best.to_dict(),
                "orders": [o.to_dict() for o in self.orders],
                "operations": [op for _, op in sorted(self.operations.items())],
                "precedences": [p.to_dict() for p in self.precedences],
                "judged": self.judged, "reused": self.reused, "pruned": self.pruned,
                "exhaustive": self.exhaustive, "workers": self.workers,
                "seconds": self.seconds, "notes": self.notes,
                "cost": ["worst zone (0 green, 1 yellow)",
                         "operator (0 one hand, 1 two hands, 2 tool or robot)",
                         "re-grasps (hooks used)",
                         "peak hand demand (value over red limit)",
                         "sum of the operations' peak demands"],
                "units": {"peak_force": "N", "clearance": "m", "seconds": "s (CPU)"}}


def sequence(seq: SequenceScene | str | Path, *, out: str | Path | None = None,
             exhaustive: bool | None = None, scheduler: str | None = None,
             workers: int | None = 0, restart: bool = False,
             on_done: Callable[[dict[str, Any]], None] | None = None) -> SequenceResult:
    """Search the orders of a sequence file's parts (see the module). ``out``: the
    store's folder (None: nothing kept); ``workers``: 0 judges in this process, None or
    N on a local Dask cluster of that many processes, ``scheduler`` an existing one's;
    ``on_done`` is called with each operation's record as it arrives."""
    if not isinstance(seq, SequenceScene):
        seq = load_sequence(seq)
    exhaustive = seq.exhaustive if exhaustive is None else exhaustive
    started = time.perf_counter()
    names = tuple(f.name for f in seq.fits)
    with ExitStack() as stack:
        store = Store(out) if out is not None else None
        if store is not None:  # one search at a time in a folder
            from pliant.io.folder_lock import FolderLock  # noqa: PLC0415

            stack.enter_context(FolderLock(store.folder, "sequence search"))
        ops: dict[tuple, dict[str, Any]] = store.open(seq, restart) if store else {}
        client = None
        if workers != 0 or scheduler is not None:
            from pliant.assembly.cluster import dask_client  # noqa: PLC0415

            client = stack.enter_context(dask_client(scheduler, workers))
        ops, counts = _search(seq, ops, exhaustive, client, store, on_done)
    orders = _orders(seq, ops)
    judged, reused, pruned, used = counts
    result = SequenceResult(seq.name, seq.source, names, orders, ops, judged, reused, pruned,
                            _precedences(ops, names, steps(seq)), exhaustive, used,
                            time.perf_counter() - started, store.folder if store else None)
    result.notes = _notes(ops)
    return result


def _search(seq: SequenceScene, ops: dict[tuple, dict[str, Any]], exhaustive: bool,
            client: Any, store: Store | None,
            on_done: Callable[[dict[str, Any]], None] | None
            ) -> tuple[dict[tuple, dict[str, Any]], tuple[int, int, int, int]]:
    """The forward search, depth by depth (see the module): every operation's record
    by (prefix, part), and (judged, reused, pruned, workers used)."""
    all_steps = steps(seq)
    names = [st.name for st in all_steps]
    reused = judged = pruned = 0
    used = 0
    alive: list[tuple[int, ...]] = [()]
    depth = 0
    while alive:
        # Pruning at this depth rests on the failures of the depths before it only
        # (whatever a resumed store holds, and in whatever order the operations came
        # back: the search is the same on any number of workers).
        failures = [op for op in ops.values()
                    if op["status"] in ("fails", "error") and len(op["prefix"]) < depth]
        children = [(prefix, part, (tuple(names[i] for i in prefix), names[part]))
                    for prefix in alive for part in _next(all_steps, prefix)]
        todo: list[tuple[tuple[int, ...], int]] = []
        for prefix, part, key in children:
            if key in ops and ops[key]["status"] not in ("pruned", "not judged"):
                reused += 1
                continue
            met = set(_present(seq, all_steps, prefix, all_steps[part].part))
            rule = None if exhaustive else _pruned_by(failures, names[part], met)
            if rule is not None:
                ops[key] = _pruned_record(key, rule)
                pruned += 1
            else:
                todo.append((prefix, part))
        results, used = _judge_all(seq, todo, client, used)
        for record in results:
            ops[_op_key(record)] = record
            judged += 1
            if store is not None:
                store.add(record)
            if on_done is not None:
                on_done(record)
        alive = [(*prefix, part) for prefix, part, key in children if ops[key]["passes"]
                 and not _complete(all_steps, (*prefix, part), len(seq.fits))]
        depth += 1
    return ops, (judged, reused, pruned, used)


def _pruned_by(failures: list[dict[str, Any]], part: str, fitted: set[str]
               ) -> dict[str, Any] | None:
    """The failure of ``part`` whose blockers are all among ``fitted`` (the one found
    with the fewest blockers), or None."""
    found = [f for f in failures if f["part"] == part and set(f["blockers"]) <= fitted]
    return min(found, key=lambda f: (len(f["blockers"]), len(f["prefix"]), f["prefix"]),
               default=None)


def _pruned_record(key: tuple, rule: dict[str, Any]) -> dict[str, Any]:
    prefix, part = key
    because = (f"it fails with {', '.join(rule['blockers'])} fitted (found after "
               f"{', '.join(rule['prefix'])})" if rule["blockers"]
               else "it fails with nothing else fitted")
    return _unjudged(part, list(prefix), "pruned",
                     f"pruned, not judged: {because}: {rule['headline']}", rule["reasons"],
                     rule["blockers"], decided=rule["decided"], zone=rule["zone"],
                     pruned_by=[*rule["prefix"], rule["part"]])


def _unjudged(part: str, prefix: list[str], status: str, headline: str, reasons: list[str],
              blockers: list[str], **fields: Any) -> dict[str, Any]:
    """The record of an operation with no evaluation of its own (an error, a pruned
    one, a lost worker's): red, no operator, no figures; ``fields`` add or replace."""
    return {"part": part, "prefix": prefix, "status": status, "passes": False,
            "decided": True, "zone": "red", "operator": None, "headline": headline,
            "reasons": reasons, "blockers": blockers, "demand": None, "peak_force": None,
            "steps": 0, "planned": 0, "stopped": None, "notes": [], "seconds": 0.0,
            **fields}


def _judge_all(seq: SequenceScene, todo: list[tuple[tuple[int, ...], int]], client: Any,
               used: int) -> tuple[list[dict[str, Any]], int]:
    """Judge the operations ``todo`` (in this process without a Dask ``client``): their
    records, in ``todo``'s order, and the workers used."""
    if not todo:
        return [], used
    if client is None:
        return [judge_operation(seq, prefix, part) for prefix, part in todo], max(used, 1)
    from pliant.assembly.cluster import worker_count  # noqa: PLC0415

    count = worker_count(client)
    futures = [client.submit(_remote_judge, seq.source, seq.key, prefix, part,
                             pure=False, retries=1) for prefix, part in todo]
    out = []
    for (prefix, part), future in zip(todo, futures, strict=True):
        try:
            out.append(future.result())
        except Exception as err:  # a worker lost: the operation is said, not judged
            all_steps = steps(seq)
            met = _present(seq, all_steps, prefix, all_steps[part].part)
            out.append(_unjudged(all_steps[part].name, [all_steps[i].name for i in prefix],
                                 "not judged", f"the worker failed: {err}",
                                 [f"{type(err).__name__}: {err}"], met, decided=False))
    return out, max(used, count)


_LOADED: dict[tuple[str, str], SequenceScene] = {}  # per worker process


def _remote_judge(source: str, key: str, prefix: tuple[int, ...], part: int
                  ) -> dict[str, Any]:
    """A worker's operation: the sequence file read once per process (and checked to be
    the version the search started from)."""
    if (source, key) not in _LOADED:
        seq = load_sequence(source)
        if seq.key != key:
            raise InputError("sequence", f"{source} changed while the search ran; run it "
                             "again")
        _LOADED[(source, key)] = seq
    return judge_operation(_LOADED[(source, key)], prefix, part)


def _orders(seq: SequenceScene, ops: dict[tuple, dict[str, Any]]) -> list[Order]:
    """Every order of the operations (each part fitted at once or by way of one of its
    hooks), each walked to its end or its first failing (or pruned) operation; passing
    orders first, by cost, then failing ones, the later they fail the earlier (then by
    name)."""
    all_steps = steps(seq)
    names = [st.name for st in all_steps]
    out = []
    for order in _completions(all_steps, (), len(seq.fits)):
        done = []
        passes = True
        for k, i in enumerate(order):
            op = ops[(tuple(names[j] for j in order[:k]), names[i])]
            done.append(op)
            if not op["passes"]:
                passes = False
                break
        cost: tuple[float, ...] = ()
        if passes:
            cost = (float(max(ZONES.index(o["zone"]) for o in done)),
                    float(max(_operator_rank(o["operator"]) for o in done)),
                    float(sum(all_steps[i].onto for i in order)),
                    max(o["demand"] or 0.0 for o in done),
                    math.fsum(o["demand"] or 0.0 for o in done))  # (any order: one sum)
        out.append(Order(tuple(names[i] for i in order), passes, done, cost))
    out.sort(key=lambda o: (not o.passes, o.cost if o.passes else (-len(o.operations),),
                            o.parts))
    return out


def _completions(all_steps: list[Step], prefix: tuple[int, ...], parts: int
                 ) -> list[tuple[int, ...]]:
    """Every whole order that begins with ``prefix`` (``steps`` indices)."""
    if _complete(all_steps, prefix, parts):
        return [prefix]
    return [order for i in _next(all_steps, prefix)
            for order in _completions(all_steps, (*prefix, i), parts)]


def _operator_rank(operator: str | None) -> int:
    """One hand 0, two hands 1, a tool or robot 2 (none that passes: 3)."""
    if operator is None:
        return 3
    if operator.startswith("one hand") or operator == "no hand":
        return 0
    if operator.startswith("two hands"):
        return 1
    return 2


def _precedences(ops: dict[tuple, dict[str, Any]], names: tuple[str, ...],
                 all_steps: list[Step]) -> list[Precedence]:
    """The precedences the failures show: a part that fits with nothing else fitted
    but fails once some parts are (its blockers) must go before them (before any one
    of them, where several block it together); the smallest blocking sets only. Only
    parts fitted at once and blocked by parts at their goals count: an operation on a
    hook is a way round a precedence, not one."""
    alone = {part: ops.get(((), part)) for part in names}
    at_once = {st.name for st in all_steps if st.hook is None}
    found: dict[tuple[str, tuple[str, ...]], str] = {}
    for (prefix, part), op in sorted(ops.items()):
        first = alone.get(part)
        if op["status"] not in ("fails", "error") or not op["blockers"]:
            continue
        if not set(prefix) <= at_once or not set(op["blockers"]) <= set(names):
            continue
        if first is None or not first["passes"]:
            continue
        key = (part, tuple(sorted(op["blockers"])))
        found.setdefault(key, _short(op))
    keys = [k for k in found if not any(o[0] == k[0] and set(o[1]) < set(k[1])
                                        for o in found)]
    return [Precedence(p, then, found[(p, then)]) for p, then in sorted(keys)]


def _short(op: dict[str, Any]) -> str:
    return f"fitting {op['part']} fails: {_reason(op)}"


def _reason(op: dict[str, Any]) -> str:
    """An operation's failure in a clause: its first red reason, else its headline."""
    red = next((r.removeprefix("[red] ") for r in op["reasons"] if r.startswith("[red]")),
               None)
    return red or op["headline"]


def _notes(ops: dict[tuple, dict[str, Any]]) -> list[str]:
    """What any operation's answer rests on that a solver gave up on, said once each."""
    out = []
    for (prefix, part), op in sorted(ops.items()):
        for note in op.get("notes", []):
            where = f"{part}" + (f" after {', '.join(prefix)}" if prefix else " (first)")
            out.append(f"{where}: {note}")
    return out


def final_lines(seq: SequenceScene, order: Sequence[str]) -> list[tuple[str, np.ndarray]]:
    """Each part of ``order`` (operation names) in the shape it settles in once at its
    goal: (name, (N+1, 3) neutral line [m]), for the report's picture."""
    all_steps = steps(seq)
    names = [st.name for st in all_steps]
    prefix = [names.index(name) for name in order]
    _fitted_by_part(seq, prefix)
    return [(seq.fits[p].name, np.asarray(_FITTED[(seq.key, tuple(prefix[:k + 1]))]
                                          .fitted.rest_line))
            for p, k in _placed(all_steps, prefix).items()]
