"""The order a harness's fixings are fixed in: which clip first, and why the other
orders fail (issue 57's clip order, on the installed harness of
``pliant.assembly.harness_solve``).

The harness starts with its placed connectors plugged and every fixing to be ordered
released: it hangs from its connectors (and the fixings not ordered) under gravity.
Fixing a clip is one operation: the fitter takes the bundle where it hangs at the clip's
mark and carries it, with the bundle's axis, to the clip's designed place and axis
(``harness_solve.fix``: every segment followed warm, so the shape is the one the move
leads to). Judged at each operation:

- the hand's force: the largest force the bundle pushes back on the clip along the move
  (the fitter holds it there until the clip snaps in), against the rules' one-hand
  "palm push" row (the clip's own insertion force, a datasheet value, is the same in
  every order and is left out);
- the harness as it then hangs (``harness_solve.installed_checks``): every segment's
  tightest bend against its limit, a segment pulled straight, the clearance to the
  scene's obstacles.

An order's cost, compared in turn: its worst zone, its largest hand force, the sum of
its hand forces. The search is exact: over the sets of fixings already fixed (each
set's harness solved once, from the first order that reaches it; n 2^(n-1) operations
for n fixings, up to ``MAX_EXACT``), keeping for each set the orders no other beats on
all three costs. Beyond that, greedy (each time the operation of least cost from the
harness as it is; said). ``search="every"`` judges every one of the n! orders along
its own path instead (the slow twin the tests compare with); a set reached by two
orders in two different shapes (a branch) is said in the notes.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pliant.errors import InputError, PliantError

MAX_EXACT = 10  # fixings: 2^10 sets of fixings, 5,120 operations at most
MAX_EVERY = 7  # fixings: 7! orders, 13,699 operations at most
ZONES = ("green", "yellow", "red")
SAME_SHAPE = 1e-6  # a set reached twice: the held loads' difference, by the weight


@dataclass(frozen=True)
class FixStep:
    """One operation: ``fixing`` fixed after ``before`` (the fixings fixed already, in
    the order's order); ``force``: the largest force [N] on the hand along the move
    (``forces``: at each step of it); ``zone`` the worst of the hand's and the
    harness's checks after it; ``reasons``: every yellow or red check, in words."""

    fixing: str
    before: tuple[str, ...]
    force: float
    forces: tuple[float, ...]
    zone: str
    reasons: tuple[str, ...]
    tightest: tuple[str, float, float | None]  # segment, bend radius [m], its limit [m]

    def to_dict(self) -> dict[str, Any]:
        return {"fixing": self.fixing, "before": list(self.before), "force": self.force,
                "forces": list(self.forces), "zone": self.zone, "reasons": list(self.reasons),
                "tightest": {"segment": self.tightest[0], "bend_radius": self.tightest[1],
                             "limit": self.tightest[2]}}


@dataclass(frozen=True)
class FixOrder:
    """An order of fixings with its operations; ``passes``: no operation is red."""

    fixings: tuple[str, ...]
    steps: tuple[FixStep, ...]

    @property
    def zone(self) -> str:
        return max((s.zone for s in self.steps), key=ZONES.index, default="green")

    @property
    def passes(self) -> bool:
        return self.zone != "red"

    @property
    def peak(self) -> float:
        return max((s.force for s in self.steps), default=0.0)

    @property
    def total(self) -> float:
        return float(sum(s.force for s in self.steps))

    @property
    def failing(self) -> FixStep | None:
        """Its first red operation (None where it passes)."""
        return next((s for s in self.steps if s.zone == "red"), None)

    def key(self) -> tuple:
        return (ZONES.index(self.zone), _rounded(self.peak), _rounded(self.total),
                self.fixings)

    def to_dict(self) -> dict[str, Any]:
        failing = self.failing
        return {"fixings": list(self.fixings), "zone": self.zone, "passes": self.passes,
                "peak_force": self.peak, "total_force": self.total,
                "failing": None if failing is None else failing.to_dict(),
                "steps": [s.to_dict() for s in self.steps]}


@dataclass(frozen=True)
class ClipOrder:
    """The search's answer: the fixings ordered, the best order (the least cost among
    those that pass; None where none passes), the best order beginning with each
    fixing that no other beats on every cost (exact) or every order (exhaustive), each
    operation that is red after which fixings (why the orders through it fail), how
    many operations were judged (each a warm solve of the harness along the clip's
    move), and notes (what was assumed, what the installed harness itself breaks, a
    branch met)."""

    harness: str
    fixings: tuple[str, ...]
    best: FixOrder | None
    orders: tuple[FixOrder, ...]
    failures: tuple[FixStep, ...]
    operations: int
    method: str
    notes: tuple[str, ...] = field(default=())
    # The harness with every fixing fixed, and hanging with those ordered released
    # (``harness_solve.Installed``): for another search of the same harness.
    installed: Any = field(default=None, repr=False)
    hanging: Any = field(default=None, repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {"harness": self.harness, "fixings": list(self.fixings), "method": self.method,
                "best": None if self.best is None else self.best.to_dict(),
                "orders": [o.to_dict() for o in self.orders],
                "failures": [f.to_dict() for f in self.failures],
                "operations": self.operations, "notes": list(self.notes)}


def _rounded(force: float) -> float:
    """A force as the search compares it: to a micronewton, so that orders equal but for
    round-off are ranked by name, the same on every machine."""
    return round(force, 6)


def _hand_zone(force: float, rules) -> tuple[str, str]:
    from pliant.assembly.checks import zone_of  # noqa: PLC0415 (the rules' checks)

    row = rules.capacities["palm push"]
    zone = zone_of(force, row.green, row.yellow, "above", row.unscored_below).value
    return zone, (f"the hand holds {force:.3g} N against the bundle to fix it (one hand: "
                  f"yellow above {row.green:.0f} N, red above {row.yellow:.0f} N; "
                  f"{row.sourced.source})")


def _judged(fixing: str, before: tuple[str, ...], forces: list[float], after, rules,
            design: Mapping[tuple[str, str], int]) -> FixStep:
    """The operation's step: the hand's zone, and each check of the harness after it
    that is worse than the same check of the installed harness (``design``: each
    check's zone rank there; what the design itself breaks, every order ends with, so
    it is no order's doing)."""
    from pliant.assembly.harness_solve import installed_checks  # noqa: PLC0415

    force = max(forces)
    zone, said = _hand_zone(force, rules)
    reasons = [said] if zone != "green" else []
    for check in installed_checks(after, rules):
        if check.zone.value in ("yellow", "red") and ZONES.index(check.zone.value) > \
                design.get((check.where, check.what), -1):
            reasons.append(f"{check.where} ({check.what}): {check.message}")
            zone = max(zone, check.zone.value, key=ZONES.index)
    seg_id, seg = min(after.segments.items(), key=lambda kv: kv[1].bend_radius / (
        kv[1].bend_limit or math.inf) if kv[1].bend_limit else math.inf)
    return FixStep(fixing, before, force, tuple(forces), zone, tuple(reasons),
                   (seg_id, float(seg.bend_radius), seg.bend_limit))


def _loads_differ(a, b) -> bool:
    scale = max(a.weight, 1e-12)
    return any(float(np.abs(a.held[k][0] - b.held[k][0]).max()) > SAME_SHAPE * scale
               for k in a.held if k in b.held)


def clip_order(harness, props: Mapping[str, Any], *, fixings: Sequence[str] | None = None,
               gravity: tuple[float, float, float] | None = None, obstacles: tuple = (),
               margin: float = 0.0, rules=None, search: str = "auto",
               steps: int = 4, installed=None, hanging=None) -> ClipOrder:
    """The order to fix ``fixings`` (names; default: every fixing placed on a segment)
    of ``harness`` (``pliant.core.harness.Harness``, its ``props`` from
    ``assembly.harness.properties``) in; see the module. ``search``: "exact" (over the
    sets of fixings fixed), "every" (every order along its own path: the slow twin, at
    most MAX_EVERY fixings), "greedy" (each time the operation of least cost from the
    harness as it is: n (n + 1) / 2 operations, not proven the best) or "auto" (exact up
    to MAX_EXACT fixings, greedy beyond, said in the notes). ``installed`` and ``hanging``:
    the harness solved with every fixing fixed and with ``fixings`` released, where the
    caller has them (``ClipOrder.installed`` and ``.hanging`` of an earlier search of the
    same harness; each a cold solve otherwise). Raises ``InputError`` for a fixing the
    harness does not have or too many to search exactly, and the solver's errors where
    the harness cannot be solved with them released."""
    from pliant.assembly.harness_solve import (  # noqa: PLC0415 (loads the solver)
        GRAVITY,
        fix,
        installed_checks,
        solve_installed,
    )
    from pliant.io.rules_file import load_rules  # noqa: PLC0415

    rules = rules or load_rules()
    gravity = GRAVITY if gravity is None else gravity
    on_segments = {harness.fixings[p.fixing].name for seg in harness.segments.values()
                   for p in seg.fixings}
    names = tuple(sorted(on_segments)) if fixings is None else tuple(fixings)
    for name in names:
        if name not in on_segments:
            raise InputError("fixings", f"{name!r} is not a fixing placed on a segment of "
                             f"{harness.name} (those placed: "
                             f"{', '.join(sorted(on_segments)[:8]) or 'none'})")
    if len(set(names)) != len(names):
        raise InputError("fixings", "a fixing is named twice")
    if not names:
        raise InputError("fixings", "give at least one fixing to order" if on_segments else
                         f"{harness.name} has no fixing placed on a segment: there is no "
                         "clip order to find")
    if search == "auto":
        search = "exact" if len(names) <= MAX_EXACT else "greedy"
    most = {"exact": MAX_EXACT, "every": MAX_EVERY, "greedy": None}
    if search not in most:
        raise InputError("search", f"must be auto, exact, every or greedy; got {search!r}")
    if most[search] is not None and len(names) > most[search]:  # type: ignore[operator]
        raise InputError("fixings", f"{len(names)} fixings: the {search} search would judge "
                         f"too many operations; order at most {most[search]} at a time "
                         "(give them with fixings=...), or search greedy")
    if hanging is not None and hanging.released != frozenset(names):
        raise InputError("hanging", "an answer with other fixings released than those "
                         "ordered; leave it out")
    start = hanging or solve_installed(harness, props, gravity=gravity, obstacles=obstacles,
                                       margin=margin, released=names)
    installed = installed or solve_installed(harness, props, gravity=gravity,
                                             obstacles=obstacles, margin=margin)
    design: dict[tuple[str, str], int] = {}
    notes = ["the placed connectors are plugged first; each clip is carried from where "
             "the harness hangs to its place, the bundle's axis with it, and held there "
             "(the clip's own insertion force is the same in every order: left out)"]
    flagged = []
    for check in installed_checks(installed, rules):
        if check.zone.value in ZONES:
            design[(check.where, check.what)] = ZONES.index(check.zone.value)
            if check.zone.value != "green":
                flagged.append(f"{check.where} ({check.what}) {check.zone.value}: "
                               f"{check.message}")
    if flagged:
        notes.append(f"the installed harness itself has {len(flagged)} yellow or red "
                     f"check(s) ({'; '.join(flagged[:3])}{' ...' if len(flagged) > 3 else ''}"
                     "): every order ends there, so an operation counts only where it makes "
                     "one worse")

    failures: dict[tuple[frozenset, str], FixStep] = {}  # red operations, by what is fixed

    def step(state, before: tuple[str, ...], name: str):
        """The harness after fixing ``name`` and the operation judged (a red one kept in
        ``failures``); where the harness cannot follow the clip (a snap, a fold), no
        harness and the operation red, saying so: the orders through it fail there, and
        the search goes on."""
        try:
            after, forces = fix(state, props, name, gravity=gravity, obstacles=obstacles,
                                margin=margin, steps=steps)
        except PliantError as err:
            after, judged = None, FixStep(name, before, math.inf, (), "red", (
                f"the harness could not follow {name} to its place ({err}): it would "
                "snap or jam on the way",), ("", math.nan, None))
        else:
            judged = _judged(name, before, forces, after, rules, design)
        if judged.zone == "red":
            failures.setdefault((frozenset(before), name), judged)
        return after, judged
    if search == "every":
        orders, judged = _every_order(names, start, step)
        method = f"every order ({math.factorial(len(names))})"
    elif search == "greedy":
        orders, judged = _greedy(names, start, step)
        method = "greedy: each time the operation of least cost (not proven the best)"
        if len(names) > MAX_EXACT:
            notes.append(f"{len(names)} fixings: more than the exact search takes "
                         f"({MAX_EXACT}); the order is the greedy one, not proven the best")
    else:
        orders, judged, branched = _over_sets(names, start, step)
        method = f"exact over the {2 ** len(names)} sets of fixings fixed"
        notes += branched
    ranked = sorted(orders, key=FixOrder.key)
    passing = [o for o in ranked if o.passes]
    return ClipOrder(harness.name, names, passing[0] if passing else None, tuple(ranked),
                     tuple(sorted(failures.values(), key=lambda f: (f.fixing, f.before))),
                     judged, method, tuple(notes), installed, start)


def _greedy(names, start, step) -> tuple[list[FixOrder], int]:
    """Each time, every fixing left fixed from the harness as it is, and the operation
    of least cost (zone, then force, then name) kept; the order ends where none can be
    done."""
    state, taken, judged = start, [], 0
    order: tuple[str, ...] = ()
    while len(order) < len(names):
        tried = []
        for name in names:
            if name not in order:
                after, step_ = step(state, order, name)
                judged += 1
                tried.append((ZONES.index(step_.zone), _rounded(step_.force), name, after,
                              step_))
        done = [t for t in tried if t[3] is not None]
        if not done:  # nothing can be fixed from here: the order ends failing
            taken.append(min(tried, key=lambda t: t[:3])[4])
            order = (*order, taken[-1].fixing)
            break
        _, _, name, state, step_ = min(done, key=lambda t: t[:3])
        order = (*order, name)
        taken.append(step_)
    return [FixOrder(order, tuple(taken))], judged


def _every_order(names, start, step) -> tuple[list[FixOrder], int]:
    """Every order along its own path (each prefix solved once)."""
    states: dict[tuple[str, ...], Any] = {(): start}
    done: dict[tuple[str, ...], FixStep] = {}
    out = []
    for order in itertools.permutations(names):
        taken = []
        for k in range(len(order)):
            prefix = order[:k + 1]
            if prefix not in done:
                states[prefix], done[prefix] = step(states[order[:k]], order[:k], order[k])
            taken.append(done[prefix])
            if states[prefix] is None:  # could not be done: the order ends there
                break
        out.append(FixOrder(order, tuple(taken)))
    return out, len(done)


def _over_sets(names, start, step) -> tuple[list[FixOrder], int, list[str]]:
    """Over the sets of fixings fixed: each set's harness solved once (from the first
    order to reach it), each set keeping the orders no other beats on zone, peak and
    sum together; returns, of the full set's, the best beginning with each fixing."""
    states: dict[frozenset, Any] = {frozenset(): start}
    fronts: dict[frozenset, list[tuple]] = {frozenset(): [(0, 0.0, 0.0, ())]}
    branched: list[str] = []
    moves: dict[tuple[frozenset, str], FixStep] = {}
    for size in range(len(names)):
        for done in sorted((s for s in fronts if len(s) == size), key=sorted):
            front = fronts[done]
            before = min(front, key=lambda label: label[:3])[3]  # any order of it: its state
            for name in names:
                if name in done:
                    continue
                after_set = done | {name}
                after, judged = step(states[done], before, name)
                moves[(done, name)] = judged
                if after is None:  # could not be done: no order goes on from here
                    continue
                if after_set not in states:
                    states[after_set] = after
                elif _loads_differ(states[after_set], after):
                    branched.append(f"{', '.join(sorted(after_set))} fixed: the harness hangs "
                                    "in another shape when they are fixed in another order "
                                    "(a branch); the search takes the first order's")
                rank, force = ZONES.index(judged.zone), _rounded(judged.force)
                labels = fronts.setdefault(after_set, [])
                for z, peak, total, order in front:
                    labels.append((max(z, rank), max(peak, force), _rounded(total + force),
                                   (*order, name)))
                fronts[after_set] = _pareto(labels)
    full = frozenset(names)
    best: dict[str, tuple] = {}
    for label in fronts.get(full, []):  # none where no order could be carried through
        first = label[3][0] if label[3] else ""
        if first not in best or (label[:3], label[3]) < (best[first][:3], best[first][3]):
            best[first] = label
    orders = []
    for label in best.values():
        order = label[3]
        orders.append(FixOrder(order, tuple(
            replace(moves[(frozenset(order[:k]), order[k])], before=order[:k])
            for k in range(len(order)))))
    return orders, len(moves), branched


def _pareto(labels: list[tuple]) -> list[tuple]:
    """The labels no other beats (or equals) on zone, peak and sum together: of equal
    costs, the first order by name."""
    out: list[tuple] = []
    for label in sorted(labels, key=lambda x: (x[:3], x[3])):
        if not any(o[0] <= label[0] and o[1] <= label[1] and o[2] <= label[2] for o in out):
            out.append(label)
    return out
