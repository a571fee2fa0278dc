"""How a user drives a session's grips, below any interface: which conditions are grips
and how each is driven (held by position, pushed by a force, or fixed), the event a pose
of a held grip makes, and the condition a grip becomes when it is switched between held
and pushed. The browser environment's server and a script use the same rules.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from pliant.core.conditions import Condition
from pliant.errors import InputError, PliantError
from pliant.session.session import GripEvent, _distinct

GripMode = Literal["position", "force", "fixed"]


def grip_mode(cond: Condition, fixed: tuple[str, ...] = ()) -> GripMode:
    """How the condition is driven: ``fixed`` when the scene names it so (a clamp, a
    port, a clip) or it holds the section's normal; ``position`` when it holds its point;
    ``force`` when it applies a force or moment; else ``fixed``."""
    if cond.name in fixed or cond.normal is not None:
        return "fixed"
    if all(v is not None for v in cond.position):
        return "position"
    if any(v is not None for v in cond.force) or cond.moment is not None:
        return "force"
    return "fixed"


def pose_event(cond: Condition, position, tangent, dimension: int) -> GripEvent:
    """The ``GripEvent`` that moves a held grip to ``position`` [m] (its first
    ``dimension`` components) and, where the grip holds the part's direction, to the unit
    ``tangent`` (in 2D its angle). InputError for a zero tangent."""
    if dimension == 2:
        angle = None
        if cond.angle is not None and tangent is not None:
            angle = math.atan2(tangent[1], tangent[0])
        return GripEvent(cond.name, position=tuple(position[:2]), angle=angle)
    held = tangent if cond.tangent is not None else None
    if held is not None and not np.linalg.norm(held) > 1e-9:
        raise InputError("tangent", f"{cond.name}: the tangent must be a non-zero direction")
    return GripEvent(cond.name, position=tuple(position), tangent=held)


def pushed(cond: Condition, last, dimension: int, force=None, moment=None) -> Condition:
    """The grip ``cond`` switched to pushing: the force [N] and (3D) moment [N m] given,
    each defaulting to what it applies in the last accurate answer ``last`` (so that
    nothing jumps), or zero without one. A 2D grip keeps a moment only where it held
    the part's angle (or one is given: its z component)."""
    d = dimension
    load = last.loads.get(cond.name) if last is not None and last.ok else None
    f = (tuple(force) if force is not None
         else (tuple(load.force[:d]) if load is not None else (0.0,) * d))
    m: float | tuple[float, ...] | None = None
    if d == 3:
        if moment is not None:
            m = tuple(moment)
        elif load is not None:
            m = tuple(float(x) for x in np.atleast_1d(load.moment)[:3])
    elif moment is not None:
        m = float(moment[2])
    elif load is not None and cond.angle is not None:
        m = float(np.atleast_1d(load.moment)[0])
    return Condition(s=cond.s, name=cond.name, force=tuple(f[:d]), moment=m)


def held(cond: Condition, original: Condition, last, dimension: int) -> Condition:
    """The grip ``cond`` switched to holding by position: where the last accurate
    answer ``last`` has the part at the grip's station, and its direction there where
    the grip as first given (``original``) held it. PliantError without an answer."""
    if last is None or not last.ok:
        raise PliantError(f"{cond.name}: no accurate shape to take the grip's pose from; "
                          "solve first")
    point, tangent = point_at(last.s, last.position, cond.s)
    return _holding(cond, original, point, tangent, dimension)


def restored(cond: Condition, original: Condition, mode: GripMode, position, tangent,
             force, moment, dimension: int) -> Condition:
    """A grip as a saved session has it (its mode, pose, force and moment), on the
    station of ``cond``; a direction is held only where ``original`` held one."""
    d = dimension
    if mode == "force":
        m = moment or [0.0, 0.0, 0.0]
        return Condition(s=cond.s, name=cond.name, force=tuple((force or [0.0] * 3)[:d]),
                         moment=float(m[2]) if d == 2 else tuple(m))
    return _holding(cond, original, position, tangent, d)


def _holding(cond: Condition, original: Condition, point, tangent,
             dimension: int) -> Condition:
    """``cond`` held at ``point`` [m], along ``tangent`` (in 2D its angle) where
    ``original`` held the part's direction and a tangent is given."""
    along = tangent is not None and (original.angle if dimension == 2
                                     else original.tangent) is not None
    if dimension == 2:
        angle = math.atan2(tangent[1], tangent[0]) if along else None
        return Condition(s=cond.s, name=cond.name, position=tuple(point[:2]), angle=angle)
    return Condition(s=cond.s, name=cond.name, position=tuple(point),
                     tangent=tuple(tangent) if along else None)


def point_at(s, position, at: float) -> tuple[np.ndarray, np.ndarray]:
    """The point and unit tangent of a sampled shape at arc length ``at`` (repeated
    stations, as at a joint, counted once)."""
    s, x = _distinct(np.asarray(s, float), np.asarray(position, float))
    point = np.array([np.interp(at, s, x[:, c]) for c in range(x.shape[1])])
    k = int(np.clip(np.searchsorted(s, at) - 1, 0, len(s) - 2))
    tangent = x[k + 1] - x[k]
    return point, tangent / max(np.linalg.norm(tangent), 1e-300)
