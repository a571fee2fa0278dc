"""The A/D evaluation: a verdict with its reasons, per operator.

``evaluate(scene)`` follows the scene's path (or solves its single pose) with the
accurate 3D model and judges every step by the rules of ``pliant/data/rules.toml``
(``../shared/EVALUATION.md`` gathers their sources): per grip, the wrench split into
axial push or pull, lateral load, twist and bending against the capacity of the grip
type; the bend radius against the part's minimum (inside or centreline by its kind, a
labelled fallback when none is given) and near its fittings; the kink of thin-walled
tubes (Brazier); the twist between fittings; stability and snaps; the clearance to each
obstacle with the scene's margin; the force each obstacle presses with; and the push that
seats the part in its port at the last step.

Each check keeps its value, thresholds, zone (green / yellow / red, or unchecked where a
value is missing), the step and grip where it is worst, and the rule's source and
provenance. Operators are tried, not guessed: one hand; then two hands, side by side or
with the second hand placed along the part where it lowers the worst demand most
(``pliant.assembly.operators``, solved with the accurate model); then a tool or a robot,
with the rating it needs. The verdict names the cheapest operator that passes.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pliant.assembly.checks import (
    Wrench,
    Zone,
    brazier_flattening,
    brazier_kink_curvature,
    centreline_min_radius,
    max_torque,
    split_wrench,
    tight_near,
    tube_section,
    twist_angle,
    zone_of,
)
from pliant.assembly.path import PathRun, StepRecord, follow_path
from pliant.core.equilibrium import Result, stretch_summary
from pliant.core.events import BRANCHED, HeldRigid, has, jumped
from pliant.core.numbers import ROUND_OFF, TOUCHING, clean, triple
from pliant.core.rules import (
    Capacity,
    EvaluationSettings,
    HandEnvelope,
    ObstacleRule,
    PartKind,
    Rules,
    Sourced,
)
from pliant.errors import InputError

SCHEMA_VERSION = 1
PENETRATION = 1e-6  # m: a clearance below minus this is inside the obstacle


@dataclass(frozen=True)
class Check:
    """One rule applied along the operation, reported at its worst.

    family : "ergonomics", "damage", "interference", "stability" or "solve"
    value [unit] : the worst value over the steps; worse : "above" (a demand) or
        "below" (a radius, a clearance); yellow_at, red_at : where the zones start
    step, grip, s [m] : where it is worst (None where it does not apply)
    yellow_steps, red_steps : every step in that zone
    """

    rule: str
    title: str
    family: str
    value: float
    unit: str
    zone: Zone
    worse: str
    yellow_at: float | None
    red_at: float | None
    source: str
    provenance: str
    step: int | None = None
    grip: str | None = None
    s: float | None = None
    note: str = ""
    yellow_steps: tuple[int, ...] = ()
    red_steps: tuple[int, ...] = ()

    @property
    def ratio(self) -> float:
        """How far into its limits: value / red_at for demands, red_at / value for
        radii and clearances (1 at the red limit; 0 where no limit applies)."""
        if self.red_at is None or self.zone in (Zone.INFO, Zone.UNCHECKED):
            return 0.0
        if self.worse == "above":
            return self.value / self.red_at if self.red_at > 0 else math.inf
        if self.value <= 0.0:
            return math.inf
        return self.red_at / self.value

    def sentence(self, with_step: bool = True) -> str:
        """The item in plain words: what, how much, against what, where (``with_step``:
        the step too, for a path), by which rule."""
        where = []
        if self.step is not None and with_step:
            where.append(f"step {self.step}")
        if self.grip and f"at {self.grip}" not in self.title:
            where.append(f"at {self.grip}")
        if self.s is not None:
            where.append(f"s = {self.s:.3g} m")
        limit = self.red_at if self.zone == Zone.RED else self.yellow_at
        against = ""
        if limit is not None and self.zone in (Zone.RED, Zone.YELLOW):
            word = "above" if self.worse == "above" else "below"
            against = f" ({word} {_fmt(limit, self.unit)})"
        # a check without a value (a file's warning) is its words alone
        text = self.title if math.isnan(self.value) else (
            f"{self.title}: {_fmt(self.value, self.unit)}{against}")
        if where:
            text += ", " + ", ".join(where)
        if with_step and len(self.red_steps) + len(self.yellow_steps) > 1:
            text += f"; {_ranges(self.red_steps)} red" if self.red_steps else ""
            text += f"; {_ranges(self.yellow_steps)} yellow" if self.yellow_steps else ""
        if self.note:
            text += f". {self.note}"
        return text

    def to_dict(self) -> dict[str, Any]:
        return {"rule": self.rule, "title": self.title, "family": self.family,
                "value": self.value, "unit": self.unit, "zone": self.zone.value,
                "worse": self.worse, "yellow_at": self.yellow_at, "red_at": self.red_at,
                "step": self.step, "grip": self.grip, "s": self.s, "note": self.note,
                "source": self.source, "provenance": self.provenance,
                "yellow_steps": list(self.yellow_steps), "red_steps": list(self.red_steps)}


def _fmt(value: float, unit: str) -> str:
    if math.isinf(value):
        return "none" if value > 0 else "-inf"
    if unit == "m":
        return "0 mm (touching)" if abs(value) < PENETRATION else f"{value * 1e3:.3g} mm"
    return f"{value:.3g} {unit}".rstrip()


def _ranges(steps: tuple[int, ...]) -> str:
    """'steps 3-7, 12' for (3, 4, 5, 6, 7, 12)."""
    parts: list[str] = []
    start = prev = None
    for k in steps:
        if prev is not None and k == prev + 1:
            prev = k
            continue
        if start is not None:
            parts.append(f"{start}" if start == prev else f"{start}-{prev}")
        start = prev = k
    if start is not None:
        parts.append(f"{start}" if start == prev else f"{start}-{prev}")
    return ("step " if len(steps) == 1 else "steps ") + ", ".join(parts)


def series_check(rule: str, title: str, family: str, values: list[float], unit: str,
                 worse: str, yellow_at: float | None, red_at: float | None, source: str,
                 provenance: str, *, grip: str | None = None,
                 where: Sequence[float | None] | None = None, unscored_below: float = 0.0,
                 note: str = "", steps: list[int] | None = None, scale: float = 0.0) -> Check:
    """A rule applied at each step's value, reported at the worst step (the highest
    zone, then the worst value); a demand's round-off (below ``ROUND_OFF`` of the
    largest of its values, its limits and ``scale``, a physical one) is 0."""
    steps = list(range(len(values))) if steps is None else steps
    if worse == "above":  # a demand's round-off is 0 (against its limits and its series)
        finite = [abs(v) for v in values if math.isfinite(v)]
        scale = max([*finite, abs(yellow_at or 0.0), abs(red_at or 0.0), scale])
        values = [0.0 if math.isfinite(v) and abs(v) <= ROUND_OFF * scale else float(v)
                  for v in values]
    zones = [zone_of(v, yellow_at, red_at, worse, unscored_below) for v in values]
    if not values:
        return Check(rule, title, family, math.nan, unit, Zone.UNCHECKED, worse, yellow_at,
                     red_at, source, provenance, note=note or "no step to judge")
    sign = 1.0 if worse == "above" else -1.0
    k = max(range(len(values)), key=lambda i: (zones[i].rank, sign * values[i]))
    return Check(rule, title, family, float(values[k]), unit, zones[k], worse, yellow_at,
                 red_at, source, provenance, step=steps[k], grip=grip,
                 s=None if where is None else where[k], note=note,
                 yellow_steps=tuple(steps[i] for i, z in enumerate(zones) if z == Zone.YELLOW),
                 red_steps=tuple(steps[i] for i, z in enumerate(zones) if z == Zone.RED))


def worst_zone(checks: list[Check]) -> Zone:
    return max((c.zone for c in checks), key=lambda z: z.rank, default=Zone.GREEN)


def worst_first(checks: list[Check]) -> list[Check]:
    """The checks ordered as a reader should meet them: highest zone, then deepest into
    its limits."""
    return sorted(checks, key=lambda c: (-c.zone.rank, -c.ratio))


# -- grips --------------------------------------------------------------------------------
@dataclass(frozen=True)
class GripStep:
    """A grip at one step: its wrench split at the part's tangent there, and the
    force and moment themselves (global frame)."""

    wrench: Wrench
    force: tuple[float, float, float]
    moment: tuple[float, float, float]
    tangent: tuple[float, float, float]
    s: float
    onto_port: bool = False  # the step that seats the part: its push goes onto the port


def tangent_at(eq: Result, s: float) -> np.ndarray:
    """The part's unit tangent (3,) at its node nearest arc length s [m]."""
    return eq.tangent[int(np.argmin(np.abs(eq.s - s)))]


def position_at(eq: Result, s: float) -> np.ndarray:
    """The part's position (3,) [m] at its node nearest arc length s [m]."""
    return eq.position[int(np.argmin(np.abs(eq.s - s)))]


def outward_sign(s: float, length: float) -> float:
    """+1 where the tangent points out of the part (its last half, the end at s = L),
    -1 where it points in: what makes a grip's axial force its pull."""
    return 1.0 if s > 0.5 * length else -1.0


def grip_step(eq: Result, name: str, extra_push: float = 0.0,
              push_axis: np.ndarray | None = None) -> GripStep:
    """The grip ``name`` at equilibrium ``eq``. ``extra_push`` [N] along ``push_axis`` is
    added to the force the grip applies (a connector's own mating force)."""
    load = eq.loads[name]
    tangent = tangent_at(eq, load.s)
    outward = outward_sign(load.s, eq.problem.part.length)
    force = np.array(load.force, float)
    if extra_push and push_axis is not None:
        force = force + extra_push * push_axis
    moment = np.array(load.moment, float)
    # Seating: a force along the arrival pushes the part onto the port (its end's
    # outward tangent is the arrival there), though along the part it reads as a pull.
    onto = push_axis is not None and float(np.dot(force, push_axis)) > 0.0
    return GripStep(split_wrench(force, moment, tangent, outward),
                    triple(force), triple(moment), triple(tangent), float(load.s), onto)


def hand_rows(rules: Rules, settings: EvaluationSettings, hold: str,
              axial_row: str = "palm push") -> list[Capacity]:
    """The capacity rows a hand is judged by, scaled by EN 1005-3's multipliers and,
    for repetitive work, with the lower yellow onsets."""
    ids = (["pinch", "wrist twist", "hand bending"] if hold == "pinch"
           else [axial_row, "power grip", "wrist twist", "hand bending"])
    out = []
    for i in ids:
        row = rules.capacities[i].scaled(settings.capacity_factor)
        if settings.repetitive and row.repetitive_yellow is not None:
            row = Capacity(row.id, row.title + " (repetitive work)", row.demand, row.unit,
                           min(row.green, row.repetitive_yellow), row.yellow, row.capacity,
                           0.0, row.repetitive_yellow, row.sourced)
        out.append(row)
    return out


def hand_checks(name: str, steps: list[GripStep], rows: list[Capacity], friction: float,
                *, share: float = 1.0, note: str = "",
                indices: list[int] | None = None) -> list[Check]:
    """One check per capacity row for a hand at grip ``name``; ``share`` is the part of
    each demand this hand carries (two hands side by side)."""
    out = []
    for row in rows:
        values = [share * g.wrench.demand(row.demand, friction) for g in steps]
        title = f"{row.title} at {name}"
        if row.demand == "axial" and steps:
            k = int(np.argmax([abs(g.wrench.axial) for g in steps]))
            title += (" (push onto the port)" if steps[k].onto_port else
                      " (push)" if steps[k].wrench.axial < 0 else " (pull)")
        out.append(series_check(
            f"grip: {row.id}", title, "ergonomics", values, row.unit, "above", row.green,
            row.yellow, row.sourced.source, row.sourced.provenance, grip=name,
            where=[g.s for g in steps], unscored_below=row.unscored_below, note=note,
            steps=indices))
    return out


def tool_checks(name: str, steps: list[GripStep], rules: Rules, rating_force: float,
                rating_moment: float | None, indices: list[int] | None = None) -> list[Check]:
    """A tool or robot at grip ``name`` against its rating."""
    source, provenance = rules.tool.source, rules.tool.provenance
    out = [series_check("tool: force", f"force on the tool at {name} (rated "
                        f"{rating_force:.4g} N)", "ergonomics",
                        [g.wrench.force for g in steps], "N", "above",
                        rules.tool_green * rating_force, rules.tool_yellow * rating_force,
                        source, provenance, grip=name, where=[g.s for g in steps],
                        steps=indices)]
    if rating_moment is not None:
        out.append(series_check("tool: moment", f"moment on the tool at {name} (rated "
                                f"{rating_moment:.4g} N m)", "ergonomics",
                                [g.wrench.moment for g in steps], "N m", "above",
                                rules.tool_green * rating_moment,
                                rules.tool_yellow * rating_moment, source, provenance,
                                grip=name, where=[g.s for g in steps], steps=indices))
    return out


# -- the result ---------------------------------------------------------------------------
@dataclass
class OperatorResult:
    """One way of doing the operation, judged: its checks, worst zone, and what it
    needs (the second hand's place, the tool's rating)."""

    operator: str
    checks: list[Check]
    summary: str
    second_hand_s: float | None = None
    second_hand_forces: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    rating: tuple[float, float] | None = None
    solves: int = 0
    # each hand's access along the path, by grip (``pliant.assembly.access.Access``)
    access: dict[str, list[Any]] = field(default_factory=dict)
    # the worker's reach to each grip along the path (``pliant.assembly.posture.Reach``)
    reach: dict[str, list[Any]] = field(default_factory=dict)

    @property
    def zone(self) -> Zone:
        return worst_zone(self.checks)

    @property
    def passes(self) -> bool:
        return self.zone != Zone.RED

    def to_dict(self) -> dict[str, Any]:
        return {"operator": self.operator, "zone": self.zone.value, "passes": self.passes,
                "summary": self.summary, "second_hand_s": self.second_hand_s,
                "second_hand_forces": {str(k): list(v)
                                       for k, v in self.second_hand_forces.items()},
                "rating": None if self.rating is None else {"force": self.rating[0],
                                                            "moment": self.rating[1]},
                "solves": self.solves, "checks": [c.to_dict() for c in self.checks],
                "access": {g: [a.to_dict() for a in steps]
                           for g, steps in self.access.items()},
                "reach": {g: [r.to_dict() for r in steps] for g, steps in self.reach.items()}}


@dataclass
class Verdict:
    """passes: the operation can be done (assemblable, by an operator that is not red);
    operator: the cheapest that passes (None: none); headline in plain words; reasons:
    each red and yellow item."""

    passes: bool
    assemblable: bool
    operator: str | None
    headline: str
    reasons: list[str]
    decided: bool = True  # False: the answer rests on a fallback (a part held rigid)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class Evaluation:
    """The evaluation of one operation: the checks on the part and the scene, each
    operator tried, the verdict, and a row per step (``table``)."""

    name: str
    part: str
    grips: tuple[str, ...]
    run: PathRun
    checks: list[Check]
    operators: list[OperatorResult]
    verdict: Verdict
    table: list[dict[str, Any]]
    rules_origin: str
    settings: EvaluationSettings

    @property
    def items(self) -> list[Check]:
        """The red and yellow checks (and the unchecked), worst first; the operators'
        of the one chosen (or of one hand when none passes)."""
        chosen = self.chosen
        pool = self.checks + (chosen.checks if chosen else [])
        return worst_first([c for c in pool
                            if c.zone in (Zone.RED, Zone.YELLOW, Zone.UNCHECKED)])

    @property
    def chosen(self) -> OperatorResult | None:
        for op in self.operators:
            if op.operator == self.verdict.operator:
                return op
        return self.operators[0] if self.operators else None

    @property
    def bodies(self) -> OperatorResult | None:
        """The operator whose hands and worker the report and the page draw: the one
        chosen, else the first that judged access or reach (None: none did)."""
        chosen = self.chosen
        if chosen is not None and (chosen.access or chosen.reach):
            return chosen
        return next((o for o in self.operators if o.access or o.reach), None)

    def worst_step(self) -> int:
        """The step of the worst red or yellow item (the last step when all is green)."""
        for c in self.items:
            if c.step is not None and c.zone in (Zone.RED, Zone.YELLOW):
                return c.step
        return len(self.run.steps) - 1

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema_version": SCHEMA_VERSION,
            "name": self.name, "part": self.part, "grips": list(self.grips),
            "verdict": self.verdict.to_dict(),
            "steps_planned": self.run.planned, "steps_solved": len(self.run.steps),
            "stopped": self.run.stopped,
            "checks": [c.to_dict() for c in self.checks],
            "operators": [o.to_dict() for o in self.operators],
            "table": self.table,
            "path": self.run.to_dict(),
            "rules": self.rules_origin,
            "settings": dict(self.settings.__dict__),
            "units": {"length": "m", "force": "N", "moment": "N m", "angle": "deg",
                      "twist_rate": "deg/m", "flattening": "1"},
        }


# -- the evaluation -----------------------------------------------------------------------
def evaluate(scene: Any, *, rules: Rules | None = None, run: PathRun | None = None,
             elements: int | None = None, search: bool = True,
             on_step: Callable[[int, Any], None] | None = None,
             start_from: Any = None) -> Evaluation:
    """Judge a scene's operation (``pliant.io.problem_file.Scene``): its [path] if it has
    one, else its single pose. ``rules`` default to the scene's ``[evaluation] rules``
    or the bundled table; ``run`` reuses a path already followed; ``search`` places a
    second hand with the accurate model where one hand is red (else two hands are only
    tried side by side); ``start_from`` an equilibrium to start the path from (see
    ``follow_path``)."""
    rules, grips, port = prepare(scene, rules)
    if run is None:
        run = follow_path(scene.problem, scene.path, scene.grip or _recorded(scene, grips),
                          margin=scene.margin, elements=elements or scene.solver.elements,
                          on_step=on_step, start_from=start_from)
    if not run.steps:
        raise InputError("scene", f"the start pose could not be solved: {run.stopped}")
    return _judge(scene, run, rules, grips, port, elements, search)


def evaluate_pose(scene: Any, pose: Any, clearances: dict[str, float], *,
                  rules: Rules | None = None,
                  grips: tuple[str, ...] | None = None) -> Evaluation:
    """Judge one pose already solved (the browser environment's accurate result, or an
    ``Equilibrium3D``) as a single pose of ``scene``: the same rules as ``evaluate``,
    without the second-hand search (it would take tens of solves). ``clearances``: the
    smallest clearance [m] to each obstacle, by name; ``grips`` the conditions a hand
    holds (default: as ``evaluate`` finds them)."""
    scene = replace(scene, path=[], problem=pose.problem)
    if grips is not None and not scene.evaluation.grips:
        scene = replace(scene, evaluation=replace(scene.evaluation, grips=tuple(grips)))
    rules, grips, port = prepare(scene, rules)
    recorded = _recorded(scene, grips)
    radius, at = pose.min_bend_radius if isinstance(pose.min_bend_radius, tuple) else (
        pose.min_bend_radius())
    nearest = min(clearances.items(), key=lambda kv: kv[1], default=("", math.inf))
    grip = pose.loads[recorded]
    record = StepRecord(
        progress=0.0, grip_position=(0.0, 0.0, 0.0), force=triple(grip.force),
        moment=triple(grip.moment), clearance=float(nearest[1]),
        nearest=nearest[0], contacts=0 if pose.contacts is None else len(pose.contacts),
        contact_force=0.0, bend_radius=float(radius), bend_at=float(at),
        stable=pose.stable, snap=jumped(pose.notes), seconds=0.0,
        clearances=tuple(clearances.items()))
    run = PathRun(grip=recorded, margin=scene.margin, steps=[record], final=pose,
                  equilibria=[pose], problems=[pose.problem])
    return _judge(scene, run, rules, grips, port, None, False)


def prepare(scene: Any, rules: Rules | None) -> tuple[Rules, tuple[str, ...], Any]:
    """The rules, the grips and the goal port, each checked before anything is solved."""
    from pliant.io.rules_file import load_rules  # noqa: PLC0415 (pydantic: on demand)

    settings: EvaluationSettings = scene.evaluation
    rules = rules or load_rules(settings.rules)
    if scene.problem.dimension != 3:
        raise InputError("problem", "the A/D evaluation judges 3D scenes; give the "
                         "conditions and gravity three components")
    rules.kind(scene.problem.part.kind)
    grips = _grips(scene, settings)
    return rules, grips, _goal_port(scene, settings, grips)


def _judge(scene: Any, run: PathRun, rules: Rules, grips: tuple[str, ...], port: Any,
           elements: int | None, search: bool) -> Evaluation:
    settings: EvaluationSettings = scene.evaluation
    problem = scene.problem
    part = problem.part
    kind = rules.kind(part.kind)
    eqs = run.equilibria
    last = len(eqs) - 1
    push_axis = None if port is None else _arrival(port)
    grip_steps = {g: [grip_step(eq, g, settings.connector_force if k == last and g == grips[0]
                                else 0.0, push_axis if k == last and g == grips[0] else None)
                      for k, eq in enumerate(eqs)]
                  for g in grips}
    checks = _part_checks(scene, run, rules, kind, settings, port, grips, grip_steps)
    operators = _operators(scene, run, rules, settings, grips, grip_steps, elements, search)
    verdict = _verdict(run, checks, operators)
    table = _table(run, grips, grip_steps, part, kind)
    return Evaluation(problem.name or "operation", part.name, grips, run, checks, operators,
                      verdict, table, rules.origin, settings)


def _grips(scene: Any, settings: EvaluationSettings) -> tuple[str, ...]:
    names = [c.name for c in scene.problem.conditions]
    if settings.grips:
        for g in settings.grips:
            if g not in names:
                raise InputError("evaluation.grips", f"no condition named {g!r}; known: "
                                 f"{', '.join(names)}")
        return tuple(settings.grips)
    if scene.grip:
        # the hands a [path] carries with its grip are hands too
        carried = scene.path_spec.carry if scene.path_spec is not None else ()
        return tuple(dict.fromkeys((scene.grip, *carried, *scene.hands)))
    # Without a path, only the conditions declared held by a hand are hands: a part
    # clamped at both ends is judged in its clamps, not as held by a hand at each.
    return tuple(scene.hands)


def _recorded(scene: Any, grips: tuple[str, ...]) -> str:
    """The condition whose wrench a step records: the first hand's, else (a part in its
    clamps) the first condition that holds the part."""
    if grips:
        return grips[0]
    return next((c.name for c in scene.problem.conditions if not c.loads_only),
                scene.problem.conditions[0].name)


def _goal_port(scene: Any, settings: EvaluationSettings, grips: tuple[str, ...]) -> Any:
    if settings.port is not None:
        if settings.port not in scene.ports:
            raise InputError("evaluation.port", f"no [[port]] named {settings.port!r}; "
                             f"known: {', '.join(scene.ports) or 'none'}")
        return scene.ports[settings.port]
    if not scene.path:
        return None
    end = scene.path[-1].condition(scene.grip)
    for port in scene.ports.values():
        if np.linalg.norm(np.subtract(end.position, port.position)) < 1e-3:
            return port
    return None


def _part_checks(scene: Any, run: PathRun, rules: Rules, kind: PartKind | None,
                 settings: EvaluationSettings, port: Any, grips: tuple[str, ...],
                 grip_steps: dict[str, list[GripStep]]) -> list[Check]:
    eqs = run.equilibria
    part = scene.problem.part
    checks: list[Check] = []
    # The path itself.
    solved = len(run.steps) - 1
    if run.stopped:
        checks.append(Check("path solved", "steps solved", "solve", float(solved), "",
                            Zone.RED, "below", None, float(run.planned), "the accurate model",
                            "computed", step=solved + 1, note=run.stopped))
    held = _held_rigid_check(run)
    if held is not None:
        checks.append(held)
    # What the file's reader warned of (a stiffness its material alone does not give)
    # stands beside the verdict in every output, not on the terminal only.
    checks += [Check("file warning", w, "solve", math.nan, "", Zone.UNCHECKED, "above", None,
                     None, "the scene file", "user") for w in scene.warnings]
    residual = max(eq.residual for eq in eqs)
    checks.append(Check("residual", "largest relative residual of the steps", "solve",
                        residual, "", Zone.INFO, "above", None, None,
                        "the accurate model's Newton", "computed"))
    checks += _bend_checks(run, part, kind, rules, scene, grips, port)
    checks += _kink_checks(run, part, kind, rules)
    checks += _twist_checks(run, part, kind, rules, settings, scene, grips)
    checks += stretch_checks(run, part, rules)
    checks.append(_stability_check(run))
    checks += _interference_checks(run, scene, rules)
    checks += _contact_checks(run, settings)
    if port is not None and grips:
        g = grip_steps[grips[0]][-1]
        push = float(np.dot(g.force, _arrival(port)))
        note = ("the hand pushes the part onto the port" if push > 0 else
                "the part goes onto the port by itself; the hand holds it back")
        if settings.connector_force:
            note += f" (with the connector's own {settings.connector_force:g} N)"
        checks.append(Check("insertion", f"push along {port.name}'s axis at the last step",
                            "ergonomics", push, "N", Zone.INFO, "above", None, None,
                            "the accurate model; judged by the grip rows", "computed",
                            step=len(eqs) - 1, grip=grips[0], s=g.s, note=note))
    return checks


def _arrival(port: Any) -> np.ndarray:
    """The unit direction a part arrives along at a port: against the axis it leaves
    by."""
    return -np.asarray(port.axis, float) / np.linalg.norm(port.axis)


def twist_rate(eq: Any, torsional_stiffness: float) -> float:
    """The largest twist rate [deg/m] along a shape: torque / GJ (``checks.max_torque``:
    round-off counts as 0)."""
    return math.degrees(max_torque(eq) / torsional_stiffness)


def bend_limit(part: Any, kind: PartKind | None) -> tuple[float | None, str, str, str]:
    """(the centreline minimum [m] or None, how it was found, its source, provenance)."""
    od = part.outer_diameter
    if part.min_bend_radius is not None:
        if kind is None:
            how = "the part's minimum, taken at the centreline (no kind given)"
            return part.min_bend_radius, how, "the part's datasheet", "user"
        try:
            limit = centreline_min_radius(part.min_bend_radius, od, kind.bend_radius_to)
        except ValueError:
            return None, "give the part's outer_diameter", kind.sourced.source, "user"
        how = (f"datasheet {part.min_bend_radius * 1e3:.3g} mm to the inside + OD/2"
               if kind.bend_radius_to == "inside" else "datasheet minimum, centreline")
        return limit, how, kind.sourced.source, "user"
    if kind is not None and kind.fallback_od is not None and od is not None:
        limit = centreline_min_radius(kind.fallback_od * od, od, kind.bend_radius_to)
        return (limit, f"fallback {kind.fallback_od:g} x OD ({kind.bend_radius_to})",
                kind.fallback_source, "fallback")
    why = ("give min_bend_radius (the datasheet value; this kind has no public fallback)"
           if kind is not None else "give min_bend_radius, or the part's kind for a fallback")
    return None, why, "", ""


def centreline_bend_limit(part: Any, rules: Rules | None = None) -> float | None:
    """The one bend limit [m] every output compares the centreline radius with: the one
    the verdict uses (``bend_limit``: a datasheet's inside radius plus OD / 2, a kind's
    fallback), by ``rules`` (default the bundled table); None where none is known. A
    kind the table does not know takes the part's minimum as given."""
    if rules is None:
        from pliant.io.rules_file import bundled_rules  # noqa: PLC0415 (pydantic: on demand)

        rules = bundled_rules()
    try:
        kind = rules.kind(part.kind)
    except InputError:
        return part.min_bend_radius
    return bend_limit(part, kind)[0]


def _bend_checks(run: PathRun, part: Any, kind: PartKind | None, rules: Rules, scene: Any,
                 grips: tuple[str, ...], port: Any) -> list[Check]:
    limit, how, source, provenance = bend_limit(part, kind)
    radii = [r.bend_radius for r in run.steps]
    where = [r.bend_at for r in run.steps]
    if limit is None:
        k = int(np.argmin(radii))
        return [Check("bend radius", "smallest bend radius (centreline)", "damage",
                      radii[k], "m", Zone.UNCHECKED, "below", None, None, source or
                      "no limit known", provenance or "none", step=k, s=where[k], note=how)]
    out = [series_check("bend radius", "smallest bend radius (centreline)", "damage", radii,
                        "m", "below", rules.bend_margin * limit, limit, source, provenance,
                        where=where, note=f"limit {limit * 1e3:.3g} mm: {how}; yellow "
                        f"within {rules.bend_margin:g} x ({rules.bend_margin_sourced.source})")]
    # A straight stretch after each fitting (ports and clips; at the last step, the port
    # the grip is seated in).
    fixed = [c for c in scene.problem.conditions if c.name in scene.fixed]
    values, at, steps = [], [], []
    straight = rules.fitting_straight * limit
    for k, eq in enumerate(run.equilibria):
        stations = [c.s for c in fixed]
        if port is not None and grips and k == len(run.equilibria) - 1:
            stations.append(eq.loads[grips[0]].s)
        if not stations:
            continue
        curvature = eq.curvature
        best = min((tight_near(eq.s, curvature, s_f, straight) for s_f in stations),
                   key=lambda x: x[0])
        values.append(best[0])
        at.append(best[1])
        steps.append(k)
    if values:
        out.append(series_check(
            "bend near a fitting", f"smallest bend radius within {straight * 1e3:.3g} mm of a "
            "fitting", "damage", values, "m", "below", rules.fitting_tight * limit, None,
            rules.fitting.source, rules.fitting.provenance, where=at, steps=steps,
            note=f"yellow below {rules.fitting_tight:g} x the minimum"))
    return out


def _kink_checks(run: PathRun, part: Any, kind: PartKind | None, rules: Rules) -> list[Check]:
    if kind is None or not kind.thin_walled:
        return []
    source = rules.kink.source
    if part.outer_diameter is None or part.inner_diameter <= 0.0:
        return [Check("kink", "flattening of the section (Brazier)", "damage", math.nan, "",
                      Zone.UNCHECKED, "above", rules.kink_yellow, rules.kink_red, source,
                      "derived", note="give outer_diameter and inner_diameter")]
    a, t = tube_section(part.outer_diameter, part.inner_diameter)
    if a / t < rules.kink_min_ratio:
        return [Check("kink", "flattening of the section (Brazier)", "damage", a / t, "",
                      Zone.INFO, "above", None, None, source, "derived",
                      note=f"not applicable: a/t = {a / t:.3g} < {rules.kink_min_ratio:g}, a "
                      "thick wall; the bend-radius rule stands in")]
    nu = part.poisson_ratio
    note = ""
    if nu is None:
        nu, note = 0.0, "nu not given: 0 assumed (the larger flattening)"
    zeta = [float(brazier_flattening(1.0 / r.bend_radius if r.bend_radius > 0 else math.inf,
                                     a, t, nu)) for r in run.steps]
    kink = brazier_kink_curvature(a, t, nu)
    note = (note + "; " if note else "") + (f"Brazier kinks at R = {1e3 / kink:.3g} mm "
                                            "(zeta = 2/9)")
    return [series_check("kink", "flattening of the section (Brazier)", "damage", zeta, "",
                         "above", rules.kink_yellow, rules.kink_red, source, "derived",
                         where=[r.bend_at for r in run.steps], note=note)]


def _twist_checks(run: PathRun, part: Any, kind: PartKind | None, rules: Rules,
                  settings: EvaluationSettings, scene: Any,
                  grips: tuple[str, ...]) -> list[Check]:
    gj = part.stiffnesses[2]
    eqs = run.equilibria
    held = sorted({c.s for c in scene.problem.conditions if not c.loads_only})
    if len(held) < 2:
        return []
    out = []
    # The twist a torque of the part's moment scale EI / L gives over its length: what
    # round-off in an angle [deg] is measured against.
    turn = math.degrees(part.bending_stiffness / gj)
    if kind is not None and kind.hose:
        last = len(eqs) - 1
        fittings = sorted({c.s for c in scene.problem.conditions if c.name in scene.fixed}
                          | ({eqs[-1].loads[run.grip].s} if scene.path else set(held)))
        spans = list(itertools.pairwise(fittings))
        if spans:
            twist = max((math.degrees(twist_angle(eqs[-1].s, eqs[-1].torque, gj, a, b))
                         for a, b in spans), key=abs)
            out.append(series_check("twist", "twist between the fittings, installed",
                                    "damage", [abs(twist)], "deg", "above",
                                    rules.twist_yellow, rules.twist_red, rules.twist.source,
                                    rules.twist.provenance, steps=[last], scale=turn))
        angles = [abs(math.degrees(twist_angle(eq.s, eq.torque, gj, held[0], held[-1])))
                  for eq in eqs]
        out.append(series_check("twist along the path", "twist between the held ends",
                                "damage", angles, "deg", "above", None, None,
                                rules.twist.source, "computed",
                                note="while handled; judged only installed", scale=turn))
        return out
    limit = settings.max_twist_rate
    rates = [twist_rate(eq, gj) for eq in eqs]
    return [series_check("twist rate", "largest twist rate", "damage", rates, "deg/m",
                         "above", None if limit is None else 0.8 * limit, limit,
                         "the user's torsion rating" if limit else "no torsion rating given",
                         "user" if limit else "computed",
                         note="" if limit else "give [evaluation] max_twist_rate to judge it",
                         scale=turn / part.length)]


def stretch_checks(run: PathRun, part: Any, rules: Rules) -> list[Check]:
    """An extensible part's largest axial strain [%] at each step, against the strain it
    tolerates (red) and that over the rules' margin (yellow); none for an inextensible
    part."""
    if part.axial_stiffness is None:
        return []
    # An extensible part's equilibria all have one.
    summaries = [x for eq in run.equilibria if (x := stretch_summary(eq)) is not None]
    strains = [100.0 * abs(x["max_axial_strain"]) for x in summaries]
    where = [x["at"] for x in summaries]
    allowed = part.max_axial_strain
    if allowed is None:
        return [series_check("axial strain", "largest axial strain (stretch)", "damage",
                             strains, "%", "above", None, None, "the accurate model",
                             "computed", where=where,
                             note="give [part] max_axial_strain to judge it")]
    red = 100.0 * allowed
    return [series_check("axial strain", "largest axial strain (stretch)", "damage", strains,
                         "%", "above", red / rules.stretch_margin, red, rules.stretch.source,
                         rules.stretch.provenance, where=where)]


def held_rigid_steps(run: PathRun) -> list[int]:
    """The steps whose answer is a fallback (``HeldRigid``): parts held still that
    could not be solved together with the part."""
    return [k for k, eq in enumerate(run.equilibria) if has(eq.notes, HeldRigid)]


def _held_rigid_check(run: PathRun) -> Check | None:
    """The fallback steps as an unchecked item: what was held and why, in every output
    (the verdict does not rest on them, see ``_verdict``)."""
    steps = held_rigid_steps(run)
    if not steps:
        return None
    notes = [n for n in run.equilibria[steps[0]].notes if isinstance(n, HeldRigid)]
    names = sorted({h for k in steps for n in run.equilibria[k].notes
                    if isinstance(n, HeldRigid) for h in n.held})
    return Check("held rigid", f"steps solved with {', '.join(names)} held rigid", "solve",
                 float(len(steps)), "", Zone.UNCHECKED, "above", None, None,
                 "the accurate model (a fallback, not the system's equilibrium)", "computed",
                 step=steps[0], note=f"{_ranges(tuple(steps))}: {notes[0]}; not judged there")


def _stability_check(run: PathRun) -> Check:
    bad = [k for k, r in enumerate(run.steps) if r.stable is False or r.snap]
    undecided = [k for k, r in enumerate(run.steps) if r.stable is None]
    source = "the accurate model's constrained Hessian; a snap: a shape that cannot be followed"
    if bad:
        snaps = [k for k in bad if run.steps[k].snap]
        note = (f"snaps at {_ranges(tuple(snaps))}; " if snaps else "") + (
            "a real part would jump there")
        return Check("stability", "unstable or snapping steps", "stability", float(len(bad)),
                     "", Zone.RED, "above", None, 0.0, source, "computed", step=bad[0],
                     note=note, red_steps=tuple(bad))
    if undecided:
        return Check("stability", "steps whose stability is not decided", "stability",
                     float(len(undecided)), "", Zone.UNCHECKED, "above", None, None, source,
                     "computed", step=undecided[0], note="follower loads or friction: a "
                     "static test does not decide")
    branched = run.branched
    note = f"{_ranges(tuple(branched))}: {BRANCHED}" if branched else ""
    return Check("stability", "unstable or snapping steps", "stability", 0.0, "", Zone.GREEN,
                 "above", None, 0.0, source, "computed", note=note)


def _interference_checks(run: PathRun, scene: Any, rules: Rules) -> list[Check]:
    """Each obstacle's clearance along the path: red inside it, yellow within its margin
    (its own, else the scene's), and its packaging rule (``ObstacleRule``): red closer
    than the table's clearance to a surface hotter than the part tolerates, or to a
    moving part, and red resting on a sharp edge."""
    out = []
    pack = rules.packaging
    part = scene.problem.part
    for obstacle in scene.problem.obstacles:
        name = obstacle.name
        values = [dict(r.clearances).get(name, math.inf) for r in run.steps]
        rule = scene.obstacle_rules.get(name, ObstacleRule())
        margin = scene.margin if rule.margin is None else rule.margin
        own = rule.margin is not None
        sources = [f"{'its' if own else 'the scene'}'s margin" if margin else
                   "no margin given"]
        red_at, said, provenance = -PENETRATION, [], "user" if margin else "computed"
        if rule.temperature is not None:
            limit = part.max_temperature
            if limit is None:
                out.append(Check(f"heat: {name}", f"heat of {name} ({rule.temperature:g} "
                                 "degC) against the part's limit", "damage", math.nan, "",
                                 Zone.UNCHECKED, "above", None, None, pack.hot.source,
                                 pack.hot.provenance, note="give [part] max_temperature "
                                 "(the datasheet's continuous service temperature)"))
            elif rule.temperature > limit:
                hot = pack.hot_shielded if rule.shielded else pack.hot_unshielded
                red_at = max(red_at, hot)
                said.append(f"{rule.temperature:g} degC, above the part's {limit:g} degC: "
                            f"red closer than {hot * 1e3:g} mm"
                            f"{' (shielded)' if rule.shielded else ''}")
                sources.append(pack.hot.source)
                provenance = pack.hot.provenance
        if rule.moving:
            red_at = max(red_at, pack.moving)
            said.append(f"it moves: red closer than {pack.moving * 1e3:g} mm")
            sources.append(pack.moving_sourced.source)
            provenance = pack.moving_sourced.provenance
        if rule.edge:
            red_at = max(red_at, TOUCHING)  # touching (shown as 0) is red
            said.append("a sharp edge: red where the part rests on it")
            sources.append(pack.edge.source)
            provenance = pack.edge.provenance
        note = f"margin {margin * 1e3:g} mm; red inside the obstacle"
        out.append(series_check(
            f"clearance: {name}", f"clearance to {name}", "interference", values, "m",
            "below", margin if margin > max(red_at, 0.0) else None, red_at,
            "; ".join(sources), provenance, note="; ".join([note, *said])))
    return out


def _contact_checks(run: PathRun, settings: EvaluationSettings) -> list[Check]:
    per: dict[str, list[float]] = {}
    for k, eq in enumerate(run.equilibria):
        if eq.contacts is None:
            continue
        for name, f in eq.contacts.by_obstacle().items():
            per.setdefault(name, [0.0] * len(run.equilibria))[k] = float(np.linalg.norm(f))
    limit = settings.max_contact_force
    return [series_check(f"contact: {name}", f"force {name} presses on the part with",
                         "interference", values, "N", "above",
                         None if limit is None else 0.8 * limit, limit,
                         "the scene's max_contact_force" if limit else "no limit given",
                         "user" if limit else "computed") for name, values in per.items()]


# -- operators ----------------------------------------------------------------------------
def _operators(scene: Any, run: PathRun, rules: Rules, settings: EvaluationSettings,
               grips: tuple[str, ...], grip_steps: dict[str, list[GripStep]],
               elements: int | None, search: bool) -> list[OperatorResult]:
    if not grips:  # the part in its clamps: nothing for a hand to do
        return [OperatorResult("no hand", _clamp_checks(scene, run),
                               "no hand: the part in its clamps")]
    friction = rules.hand_friction
    wanted = settings.operator
    out: list[OperatorResult] = []
    rows = hand_rows(rules, settings, settings.hold)
    access: dict = {}  # each hand's access, found once for every operator
    if wanted in ("auto", "one hand"):
        checks = [c for g in grips for c in hand_checks(g, grip_steps[g], rows, friction)]
        one = OperatorResult("one hand", checks, "one hand" if len(grips) == 1 else
                             "one hand at each of " + ", ".join(grips))
        _with_access(one, run, rules, settings, grips, memo=access)
        _with_reach(one, run, rules, scene, grips)
        if len(grips) == 2:
            _with_spread(one, run, rules, scene, grips[0], grips[1])
        out.append(one)
    if wanted == "two hands" or (wanted == "auto" and out[0].zone == Zone.RED):
        out += _two_hands(scene, run, rules, settings, grips, grip_steps, elements, search,
                          access)
    if wanted in ("tool", "robot"):
        rating = settings.rating_force
        assert rating is not None  # EvaluationSettings asks a tool or robot for one
        checks = [c for g in grips for c in tool_checks(
            g, grip_steps[g], rules, rating, settings.rating_moment)]
        out.append(OperatorResult(wanted, checks, f"a {wanted} rated for "
                                  f"{settings.rating_force:g} N"))
        _with_tool_access(out[-1], run, rules, settings, grips)
    elif wanted == "auto" and all(o.zone == Zone.RED for o in out):
        out.append(_tool_needed(rules, settings, grips, grip_steps))
        _with_tool_access(out[-1], run, rules, settings, grips)
    return out


def _with_tool_access(op: OperatorResult, run: PathRun, rules: Rules,
                      settings: EvaluationSettings, grips: tuple[str, ...]) -> None:
    """Add to ``op`` the room for the tool's or robot's gripper at each of ``grips``
    along the path, where the scene gives its envelope (``[evaluation] envelope``): the
    hand's check (``access.hand_access``) with the gripper's sizes, its jaws round the
    part and its body out along the best approach; red where none fits."""
    if settings.tool_envelope is None or not run.equilibria:
        return
    from pliant.assembly.access import hand_access  # noqa: PLC0415

    length, breadth, thickness, jaw = settings.tool_envelope
    allowance = rules.access.allowance if rules.access is not None else 0.0
    env = HandEnvelope(breadth, jaw, breadth, jaw, 1e-6, length, (breadth, thickness),
                       (breadth, thickness), 0.0, allowance, 36, Sourced(
                           "the tool's or robot's gripper as the scene gives it "
                           "([evaluation] envelope)", "given"))
    for g in grips:
        steps = [hand_access(eq, eq.loads[g].s, env) for eq in run.equilibria]
        op.access[g] = steps
        op.checks.append(access_check(g, steps, env, tool=True))


def _clamp_checks(scene: Any, run: PathRun) -> list[Check]:
    """The force and moment each clamp (every condition that holds the part) takes, at
    the worst step: reported, not judged (a clamp's rating is its datasheet's)."""
    out = []
    part = scene.problem.part
    scales = {"force": part.bending_stiffness / part.length**2,
              "moment": part.bending_stiffness / part.length}
    for c in scene.problem.conditions:
        if c.loads_only:
            continue
        for what, unit, attr in (("force", "N", "force"), ("moment", "N m", "moment")):
            values = [float(np.linalg.norm(getattr(eq.loads[c.name], attr)))
                      for eq in run.equilibria]
            check = series_check(f"clamp {what}: {c.name}", f"{what} at {c.name}",
                                 "ergonomics", values, unit, "above", None, None,
                                 "the accurate model (the clamp's reaction)", "computed",
                                 grip=c.name, note="compare it with the clamp's rating",
                                 scale=scales[attr])
            out.append(replace(check, zone=Zone.INFO))
    return out


def _two_hands(scene: Any, run: PathRun, rules: Rules, settings: EvaluationSettings,
               grips: tuple[str, ...], grip_steps: dict[str, list[GripStep]],
               elements: int | None, search: bool,
               access: dict | None = None) -> list[OperatorResult]:
    from pliant.assembly.operators import place_second_hand  # noqa: PLC0415

    friction = rules.hand_friction
    side_rows = hand_rows(rules, settings, settings.hold, axial_row="two-hand push")
    checks = []
    note = "the two hands share the load evenly (an assumption)"
    for g in grips:
        for row in side_rows:
            share = 1.0 if row.id == "two-hand push" else 0.5
            checks += hand_checks(g, grip_steps[g], [row], friction, share=share,
                                  note=note if share < 1 else "")
    out = [OperatorResult("two hands side by side", checks,
                          "two hands side by side at " + ", ".join(grips))]
    _with_access(out[0], run, rules, settings, grips, hands=2, memo=access)
    _with_reach(out[0], run, rules, scene, grips)
    # Side by side passes: no need to look for where else the second hand could go.
    if len(grips) == 1 and search and not out[0].passes:
        placed = place_second_hand(scene, run, rules, settings, grips[0], grip_steps[grips[0]],
                                   elements or scene.solver.elements)
        if placed is not None:
            _with_access(placed, run, rules, settings, grips, memo=access)
            if placed.second_hand_s is not None:
                _with_access(placed, run, rules, settings, (SECOND_HAND,),
                             at=placed.second_hand_s, memo=access)
            _with_reach(placed, run, rules, scene, grips, second=placed.second_hand_s)
            if placed.second_hand_s is not None:
                _with_spread(placed, run, rules, scene, grips[0], placed.second_hand_s)
            out.append(placed)
    return out


SECOND_HAND = "second hand"


def _with_access(op: OperatorResult, run: PathRun, rules: Rules,
                 settings: EvaluationSettings, grips: tuple[str, ...], hands: int = 1,
                 at: float | None = None, memo: dict | None = None) -> None:
    """Add to ``op`` the access of a hand (``hands`` side by side) at each of ``grips``
    along the path (``at``: at that arc length [m] instead of the grip's), a check each
    (``pliant.assembly.access``): red where no approach fits round the part. ``memo``:
    the accesses found for the evaluation's other operators, by (grip, hands, at): one
    hand at a grip is the same for every operator that puts one there."""
    env = rules.access
    if env is None or not run.equilibria:
        return
    from pliant.assembly.access import hand_access  # noqa: PLC0415

    memo = {} if memo is None else memo
    for g in grips:
        key = (g, hands, at)
        if key not in memo:
            memo[key] = [hand_access(eq, eq.loads[g].s if at is None else at, env,
                                     settings.hold, hands) for eq in run.equilibria]
        steps = memo[key]
        op.access[g] = steps
        op.checks.append(access_check(g, steps, env, hands))


def _with_reach(op: OperatorResult, run: PathRun, rules: Rules, scene: Any,
                grips: tuple[str, ...], second: float | None = None) -> None:
    """Add to ``op`` the scene's worker's reach to each hand's grip along the path
    (``second``: the placed second hand's arc length [m], the other arm), with its
    trunk bend and upper-arm elevation, a check each (``pliant.assembly.posture``)."""
    worker = getattr(scene, "worker", None)
    if worker is None or rules.body is None or rules.posture is None or not run.equilibria:
        return
    from pliant.assembly.posture import Figure, up_of  # noqa: PLC0415

    figure = Figure(worker, rules.body, up_of(scene.problem))
    eqs = run.equilibria
    spots = [(g, [position_at(eq, eq.loads[g].s) for eq in eqs]) for g in grips]
    if second is not None:
        spots.append((SECOND_HAND, [position_at(eq, second) for eq in eqs]))
    other = "left" if worker.side == "right" else "right"
    sides = [worker.side] * len(spots)
    if len(spots) == 2:  # each hand takes the grip on its side, at the start
        right = np.cross(figure.facing, figure.up)
        first_right = (spots[0][1][0] - spots[1][1][0]) @ right >= 0.0
        sides = ["right", "left"] if first_right else ["left", "right"]
    elif len(spots) > 2:
        sides = [worker.side] + [other] * (len(spots) - 1)
    env = rules.access
    for (g, points), side in zip(spots, sides):
        steps = [figure.reach(p, side, rules.posture) for p in points]
        rooms = []
        if env is not None:
            from pliant.assembly.posture import swivelled  # noqa: PLC0415
            from pliant.scene.distance import field_of  # noqa: PLC0415

            moved = [swivelled(figure, r, env.upper_arm, env.allowance,
                               field_of(eq.problem.obstacles)) for r, eq in zip(steps, eqs)]
            steps, rooms = [m[0] for m in moved], [m[1] for m in moved]
        op.reach[g] = steps
        op.checks += reach_checks(g, steps, rules, figure)
        if rooms:
            op.checks.append(upper_arm_check(g, rooms, env, side))


def _with_spread(op: OperatorResult, run: PathRun, rules: Rules, scene: Any, first: str,
                 second: str | float) -> None:
    """Add to ``op`` how far apart its two hands are along the path (at grip ``first``
    and at grip or arc length ``second``), a check: the distance against the spread at
    which the upper arms must be raised past the ``[posture]`` zones' onsets whatever
    the posture (``posture.spread``), for the scene's worker or, without one, the 5th
    percentile woman the worker defaults to."""
    from pliant.assembly.posture import spread_of  # noqa: PLC0415

    body = spread_of(rules, getattr(scene, "worker", None))
    if body is None or not run.equilibria:
        return
    where = second if isinstance(second, str) else SECOND_HAND
    apart = [float(np.linalg.norm(position_at(eq, eq.loads[first].s) - position_at(
        eq, eq.loads[second].s if isinstance(second, str) else second)))
        for eq in run.equilibria]
    widest = max(apart)
    reach = ("beyond what the arms span at all" if widest > body.most else
             f"the upper arms raised at least {body.elevation(widest):.0f} degrees")
    note = (f"{body.who}: shoulders {body.breadth * 1e3:.0f} mm apart, arm "
            f"{body.arm * 1e3:.0f} mm; at the widest, {widest * 1e3:.0f} mm apart, {reach}")
    op.checks.append(series_check(
        f"hands apart: {first} and {where}", f"distance between the hands at {first} and "
        f"{where}", "ergonomics", apart, "m", "above", body.limits[0], body.limits[1],
        body.source, "derived", grip=first, note=note))


def reach_checks(grip: str, steps: list[Any], rules: Rules, figure: Any) -> list[Check]:
    """The worker's reach to ``grip`` along the path as three checks: the grip beyond
    the arm's reach (red: out of reach even bent 90 degrees, by how much), the trunk
    bend it takes and the upper arm's elevation (the ``[posture]`` zones)."""
    assert rules.body is not None and rules.posture is not None
    w = figure.worker
    who = (f"a {w.percentile:g}th percentile {'man' if w.sex == 'men' else 'woman'} "
           f"({rules.body.population}), {w.posture}")
    side = steps[0].side
    worst = max(steps, key=lambda r: r.excess)
    bent = max(r.trunk for r in steps)
    note = f"{who}, {side} hand: arm's reach {worst.arm * 1e3:.0f} mm; " + (
        f"out of reach by {worst.excess * 1e3:.0f} mm even bent {worst.trunk:.0f} deg"
        if worst.excess > 0 else f"reached with the trunk bent up to {bent:.0f} deg"
        if bent > 0 else f"{-worst.excess * 1e3:.0f} mm to spare at its farthest")
    body, zones = rules.body.sourced, rules.posture
    out = [series_check("reach", f"the grip beyond the {side} arm's reach at {grip}",
                        "ergonomics", [r.excess for r in steps], "m", "above", None, 0.0,
                        body.source, body.provenance, grip=grip, note=note)]
    for what, key, limits in (("trunk bend", "trunk", zones.trunk),
                              ("upper-arm elevation", "upper_arm", zones.upper_arm)):
        values = [getattr(r, key) for r in steps]
        out.append(series_check(
            f"posture: {key}", f"{what} to reach {grip} ({side} hand)", "ergonomics",
            values, "deg", "above", limits[0], limits[1], zones.sourced.source,
            zones.sourced.provenance, grip=grip, note=who))
    return out


def upper_arm_check(grip: str, rooms: list[Any], env: Any, side: str) -> Check:
    """The room for the worker's upper arm reaching ``grip`` along the path
    (``posture.swivelled``): red where no swing of the elbow round the shoulder-hand
    line keeps the upper arm out of the obstacles, yellow within the movement
    allowance; the worst step's swing and what bounds it in the note."""
    values = [r.clearance for r in rooms]
    worst = rooms[int(np.argmin(values))]
    swung = (f"the elbow swung {worst.swivel:.0f} deg from hanging" if worst.swivel > 0.0
             else "the elbow hanging")
    note = (f"{side} upper arm (radius {env.upper_arm * 1e3:.0f} mm), {swung}: "
            + (f"inside {worst.bound_by} by {-worst.clearance * 1e3:.0f} mm in the best "
               "swing" if worst.clearance < 0.0 else f"bound by {worst.bound_by}"))
    return series_check("access: upper arm", f"room for the {side} upper arm at {grip}",
                        "ergonomics", values, "m", "below",
                        env.allowance if env.allowance > 0 else None, 0.0,
                        env.sourced.source, env.sourced.provenance, grip=grip, note=note)


def access_check(grip: str, steps: list[Any], env: Any, hands: int = 1,
                 tool: bool = False) -> Check:
    """The hand's (``tool``: the gripper's) access at ``grip`` along the path as a check,
    its worst step's best approach and what bounds it in the note."""
    values = [a.clearance for a in steps]
    k = int(np.argmin(values))
    worst = steps[k]
    who = ("the tool" if tool else "two hands side by side" if hands == 2 else "the hand")
    body = "its body" if tool else "forearm"
    if worst.clearance < 0.0:
        note = (f"no approach fits {who} and {body} round the part at s = {worst.s:.3g} m: "
                f"the best, from {_direction(worst.approach)}, needs "
                f"{-worst.clearance * 1e3:.0f} mm more room, bound by {worst.bound_by}")
    else:
        note = (f"best approach from {_direction(worst.approach)}, bound by "
                f"{worst.bound_by}")
    note += (f"; the gripper as given, {env.directions} approaches" if tool else
             f"; envelope of a large hand (95th percentile man), {env.directions} approaches")
    return series_check("access: tool" if tool else "access: hand",
                        f"room for {who} at {grip}", "ergonomics", values,
                        "m", "below", env.allowance if env.allowance > 0 else None, 0.0,
                        env.sourced.source, env.sourced.provenance, grip=grip,
                        where=[a.s for a in steps], note=note)


def _direction(v: tuple[float, float, float]) -> str:
    """A unit direction in words: the approach's, the side the forearm comes from."""
    return "(" + ", ".join(f"{c:+.2f}" for c in v) + ")"


def _tool_needed(rules: Rules, settings: EvaluationSettings, grips: tuple[str, ...],
                 grip_steps: dict[str, list[GripStep]]) -> OperatorResult:
    peak_f = max(g.wrench.force for name in grips for g in grip_steps[name])
    peak_m = max(g.wrench.moment for name in grips for g in grip_steps[name])
    force = settings.rating_force or peak_f / rules.tool_green
    moment = settings.rating_moment or peak_m / rules.tool_green
    checks = [c for g in grips for c in tool_checks(g, grip_steps[g], rules, force, moment)]
    given = settings.rating_force is not None
    summary = (f"a tool or robot rated {force:.3g} N, {moment:.3g} N m" if given else
               f"a tool or robot rated for at least {force:.3g} N and {moment:.3g} N m")
    return OperatorResult("tool or robot", checks, summary, rating=(force, moment))


# -- the verdict --------------------------------------------------------------------------
def _verdict(run: PathRun, checks: list[Check],
             operators: list[OperatorResult]) -> Verdict:
    red = [c for c in checks if c.zone == Zone.RED]
    assemblable = not red and run.complete
    chosen = next((o for o in operators if o.passes), None)
    ops = chosen or (operators[0] if operators else None)
    reasons = [f"[{c.zone.value}] {c.sentence()}"
               for group in (checks, ops.checks if ops is not None else [])
               for c in worst_first(group) if c.zone in (Zone.RED, Zone.YELLOW)]
    # why each operator tried before the one chosen is red: its worst item
    if chosen is not None:
        reasons += [f"[red] {o.operator}: {worst_first(o.checks)[0].sentence()}"
                    for o in operators[:operators.index(chosen)] if o.checks]
    # No verdict rests on a fallback: a red item stands only where it is red at a step
    # that was solved as the system it is; otherwise the operation is undecided.
    held = set(held_rigid_steps(run))
    if held:
        fallback = next(c for c in checks if c.rule == "held rigid")
        genuine = [c for c in red if c.family == "solve" or not held.issuperset(
            c.red_steps or ((c.step,) if c.step is not None else ()))]
        if not genuine:
            return Verdict(passes=False, assemblable=False, operator=None,
                           headline=f"UNDECIDED: {fallback.title} "
                                    f"({_ranges(tuple(sorted(held)))}); the verdict "
                                    "would rest on that fallback",
                           reasons=[f"[{fallback.zone.value}] {fallback.sentence()}",
                                    *reasons], decided=False)
        red = genuine
    if not assemblable:
        first = red[0] if red else None
        headline = ("DOES NOT FIT: " + first.sentence().split(". ")[0]) if first else (
            "DOES NOT FIT: the path could not be followed")
    elif chosen is None:
        headline = ("FITS, BUT NO OPERATOR TRIED CAN DO IT: "
                    + ", ".join(f"{o.operator} is red" for o in operators))
    elif chosen.operator == "no hand":
        headline = "FITS in its clamps (no hand holds it)"
    else:
        headline = f"FITS with {chosen.summary}"
        tried = [o.operator for o in operators if not o.passes]
        if tried:
            headline += f"; {' and '.join(tried)}: red"
        if chosen.zone == Zone.YELLOW or any(c.zone == Zone.YELLOW for c in checks):
            headline += "; with reservations (yellow items below)"
    return Verdict(passes=assemblable and chosen is not None, assemblable=assemblable,
                   operator=None if chosen is None else chosen.operator, headline=headline,
                   reasons=reasons)


def _table(run: PathRun, grips: tuple[str, ...], grip_steps: dict[str, list[GripStep]],
           part: Any, kind: PartKind | None) -> list[dict[str, Any]]:
    gj = part.stiffnesses[2]
    thin = (kind is not None and kind.thin_walled and part.outer_diameter is not None
            and part.inner_diameter > 0)
    if thin:
        a, t = tube_section(part.outer_diameter, part.inner_diameter)
    rows = []
    # Round-off as 0 (``pliant.core.numbers``): against the part's force and moment scales.
    forces, moments = part.bending_stiffness / part.length**2, part.bending_stiffness / part.length
    for k, (r, eq) in enumerate(zip(run.steps, run.equilibria)):
        row: dict[str, Any] = {"step": k, "progress": r.progress}
        for g in grips:
            gs = grip_steps[g][k]
            w = gs.wrench
            fx, fy, fz, axial, lateral = clean((*gs.force, w.axial, w.lateral), forces)
            mx, my, mz, twist, bending = clean((*gs.moment, w.twist, w.bending), moments)
            row.update({f"{g} Fx": fx, f"{g} Fy": fy, f"{g} Fz": fz, f"{g} Mx": mx,
                        f"{g} My": my, f"{g} Mz": mz, f"{g} axial": axial,
                        f"{g} lateral": lateral, f"{g} twist": twist,
                        f"{g} bending": bending})
        row.update({"bend radius": r.bend_radius, "bend at": r.bend_at,
                    "clearance": r.clearance, "nearest": r.nearest,
                    "contact force": r.contact_force,
                    "twist rate": twist_rate(eq, gj),
                    "stable": r.stable, "snap": r.snap})
        if thin:
            row["flattening"] = float(brazier_flattening(1.0 / r.bend_radius, a, t,
                                                         part.poisson_ratio or 0.0))
        for name, c in r.clearances:
            row[f"clearance {name}"] = c
        rows.append(row)
    return rows
