"""How a solve ended and what happened on the way, as data.

``Status`` says why a solver stopped, with what to do about it (every ``ConvergenceError``
carries one; an answer is ``Status.CONVERGED``). An ``Event`` is a fact about how an
answer was reached: the buckling side a solve took, a snap, a warm start that could not
be followed, a lower equilibrium found by minimising the energy. Each event *is* its
message (a ``str``, so an answer's ``notes`` read as plain words) and a typed record:
its class and fields, which callers test with ``isinstance`` instead of searching the
words, and which the JSON carries as ``{"kind": ..., "message": ..., fields}``.
"""

from __future__ import annotations

import enum
import math
from typing import Any


class Status(enum.Enum):
    """Why a solver stopped; ``advice`` says what to do."""

    CONVERGED = "converged"
    FOLD = "fold"
    SINGULAR = "singular"
    STEP_BUDGET = "step budget"
    TIME_BUDGET = "time budget"
    NOT_FINITE = "not finite"
    NO_ROUTE = "no route"

    @property
    def advice(self) -> str:
        return _ADVICE[self]


_ADVICE = {
    Status.CONVERGED: "the answer holds to the solver's tolerance",
    Status.FOLD: "the path from the unloaded part (or the warm start) meets a fold, where "
                 "the part would snap: move the target in smaller steps with trace(), or "
                 "check that the target is the one meant",
    Status.SINGULAR: "the equations are singular there (a bifurcation, or conditions that do "
                     "not fix the part): give the part a side to bow to, or hold it more",
    Status.STEP_BUDGET: "the continuation ran out of steps: raise the solver's max_steps",
    Status.TIME_BUDGET: "the solve ran out of time: raise the solver's time_budget",
    Status.NOT_FINITE: "the loads are too large for the model (the residual overflowed): "
                       "check their units",
    Status.NO_ROUTE: "no route from the unloaded part reached an equilibrium: check that the "
                     "targets can be reached",
}


# What a refusal says of the search behind it: the routes from the unloaded part (or the
# warm start) are not every shape the part can take.
NOT_EXHAUSTIVE = ("the routes pliant follows do not search every shape, so an equilibrium "
                  "may exist that none reached")


class Event(str):
    """A fact about how an answer was reached: its message, and its fields as
    attributes (see the module). A plain note is an ``Event`` of kind "note"."""

    kind = "note"

    def __new__(cls, message: str, **fields: Any) -> Event:
        self = super().__new__(cls, message)
        self.__dict__.update(fields)
        return self

    @property
    def message(self) -> str:
        return str(self)

    def to_dict(self) -> dict[str, Any]:
        names = [k for c in reversed(type(self).__mro__) for k in vars(c).get(
            "__annotations__", {}) if k != "kind"]
        names += [k for k in self.__dict__ if k not in names]
        return {"kind": self.kind, "message": str(self),
                **{k: _plain(getattr(self, k)) for k in names}}


def _plain(value: Any) -> Any:
    """A field as JSON-ready data (arrays as lists, inf as None)."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    return value


class WarmStartLost(Event):
    """The warm start could not be followed to the problem: it was solved from the rest
    state, so between the two the part jumped (a fold, a snap)."""

    kind = "warm_start_lost"


class BranchTaken(Event):
    """The unloaded part was a singular start (it can buckle to either side): the solve
    took ``side`` (2D: "left" or "right" of the chord; 3D: the unit vector it bows
    toward), of potential ``energy`` [J] (None where undecided), the other side's
    ``other_energy`` (None where none was found or compared), ``twin`` where it is a
    mirror image of equal energy."""

    kind = "branch"
    side: Any = None
    energy: float | None = None
    other_energy: float | None = None
    twin: bool = False


class LowestEquilibrium(Event):
    """The answer is the stable equilibrium of least potential ``energy`` [J] among
    those found; the path from the unloaded part led to one of ``route_energy`` (None
    where every path met a fold)."""

    kind = "lowest"
    energy: float | None = None
    route_energy: float | None = None


class OthersFound(Event):
    """Other equilibria of the problem, with their potential ``energies`` [J]."""

    kind = "others_found"
    energies: tuple = ()


class BeyondFold(Event):
    """The path from the unloaded part meets a fold at ``at`` (a fraction of the way):
    the answer lies beyond it."""

    kind = "beyond_fold"
    at: float = 0.0


class LoadsStaged(Event):
    """Every path from the unloaded part to the whole load met a fold (at ``at`` of the
    way): the loads were applied in stages, ``factors`` of them, each solved from the
    last."""

    kind = "loads_staged"
    factors: tuple = ()
    at: float = 0.0


class Snapped(Event):
    """On the way the part snapped through ``count`` times, the first at ``at`` of the
    way, and settled on a stable equilibrium."""

    kind = "snap"
    at: float = 0.0
    count: int = 1  # type: ignore[assignment]  # a field, over str.count


class PushedOut(Event):
    """The unloaded part passed through the ``obstacles`` (names), and growing them back
    round it stalled: they were carried in from ``move`` [m] away across the part
    instead, pushing it toward ``side`` (a unit vector); the answer's potential
    ``energy`` [J], the other ways' ``other_energies``, ``twin`` where one of those is
    a mirror image of equal energy (``rod3d.carrying``)."""

    kind = "pushed_out"
    obstacles: tuple = ()
    side: Any = None
    move: float = 0.0
    energy: float = 0.0
    other_energies: tuple = ()
    twin: bool = False


class LeftUnstable(Event):
    """The equilibrium reached was unstable (its smallest eigenvalue ``eigenvalue``
    [N m]): the part left it along its unstable mode and settled on this stable one,
    ``distance`` [m] away at most, releasing ``released`` [J] of potential energy.
    ``jump`` where that is a snap (a real part jumps there); else the stable branch that
    leaves a bifurcation, which a real part follows without a jump
    (``rod3d.settling``)."""

    kind = "left_unstable"
    eigenvalue: float = 0.0
    distance: float = 0.0
    released: float = 0.0
    jump: bool = False


# What every output says of a step where the part left an unstable shape without a jump.
BRANCHED = ("the followed shape turned unstable and the part took the stable branch that "
            "leaves it (a bifurcation: no jump)")


class CrossedBifurcation(Event):
    """The path crosses a bifurcation (det J changes sign): the answer continued through
    it may be unstable, and a neighbouring branch may be the one the part takes."""

    kind = "bifurcation_crossed"


class ReachedBy(Event):
    """How an equilibrium that ``equilibria`` lists was reached: the ``route`` it
    followed from the unloaded part ("straight", "two stage", "swing", "loads first",
    "energy minimum") and ``how`` (3D: which branch, as "bowed toward [0, 0, 1]")."""

    kind = "reached_by"
    route: str = ""
    how: str = ""


class NoStableBranch(Event):
    """The straight equilibrium of a compressed part is unstable and no route to a
    buckled one converged: the answer is that unstable equilibrium."""

    kind = "no_stable_branch"


class PlanarRoute(Event):
    """A 2D answer found from the 3D rod's equilibrium of the same problem in the plane."""

    kind = "planar_route"


class SolvedTogether(Event):
    """The part was solved together with others (parts in contact, sliding clips, a
    harness's junctions): its stability verdict is the coupled system's (``assessed``),
    or not assessed where friction or non-conservative loads act (that of one part with
    the others' forces held as loads would not be the coupled system's)."""

    kind = "solved_together"
    assessed: bool = False


class HeldRigid(Event):
    """A fallback: the parts named in ``held`` (fitted parts, sliding clips) could not be
    solved together with the part, so this answer holds them still (fitted parts at
    rest, clips where they start). It is not the system's equilibrium: a verdict must
    not rest on it."""

    kind = "held_rigid"
    held: tuple = ()


def has(notes, kind: type[Event]) -> bool:
    """Whether any of an answer's notes is an event of this kind."""
    return any(isinstance(n, kind) for n in notes)


def jumped(notes) -> bool:
    """Whether an answer's part jumped to reach it: its warm start could not be followed
    (``WarmStartLost``), or it left an unstable equilibrium with a snap (``LeftUnstable``)."""
    return any(isinstance(n, WarmStartLost) or (isinstance(n, LeftUnstable) and n.jump)
               for n in notes)


def events(notes) -> tuple[Event, ...]:
    """An answer's notes as events (a plain string becomes a note)."""
    return tuple(n if isinstance(n, Event) else Event(n) for n in notes)
