"""Stiffness from measurements: the part's parameters that make the accurate model
reproduce a test.

The fit is weighted least squares over the logarithms of the unknowns (stiffnesses are
positive and scatter by factors, not by newtons): scipy's trust-region least squares with
a forward-difference Jacobian of warm solves. What each measurement contributes:

- a shape: every measured point's offset from the computed neutral line, measured normal
  to it (the projection onto the cubic Hermite curve through the solver's nodes and
  tangents), so the spacing of the points along the part does not matter;
- a deflection: the measured coordinates of a station under each load, minus the model's;
- three-point bending: the ram's load at each measured displacement, minus the model's;
  the half part between the middle (clamped level by symmetry) and a support it slides
  on is a 2D elastica pinned at the support, at the arc length where the support's force
  is normal to the part (frictionless); with no weight the load is EI times that of a
  unit stiffness, so the curve is solved once;
- a twist: the chuck's moment at each angle, from the 3D rod followed from 0 to the
  angle (a Greenhill buckle would show as a loss of stability).

The intervals are those of the linearised model at the optimum: covariance
s^2 (J^T W J)^-1 with s^2 the weighted residual's variance (as scipy's curve_fit does with
relative weights), Student's t quantile, taken back from the logarithm so that they are
never negative. An unknown that the measurements do not move, or two that they move only
together (a hanging shape knows only the weight over the stiffness), is said so by
``NotIdentifiableError`` instead of an interval of noise.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from pliant.core.conditions import Condition, clamp
from pliant.core.events import WarmStartLost, has
from pliant.core.measurement import (
    UNKNOWNS,
    Deflection,
    Measurement,
    Shape,
    StiffnessTest,
    ThreePointBending,
    Twist,
    TwistBuckling,
)
from pliant.core.part import Part
from pliant.core.problem import Problem
from pliant.errors import (
    ConvergenceError,
    IdentificationError,
    InputError,
    NotIdentifiableError,
)

RANGE = math.log(1e4)  # the fit may move each unknown by this factor either way
STEP = 1e-5  # the forward-difference step in the logarithm of an unknown (iterations)
CENTRAL = 1e-4  # the central-difference step (checks, intervals): O(1e-8) truncation
COLLINEAR = 1e-4  # smallest singular value of the normalised Jacobian: two unknowns as one
INSENSITIVE = 1e-4  # the largest change per e-fold, relative to the data: no information
# (a hundredth of a millimetre on a 0.1 m shape for a factor 2.7 in the parameter; the
# solvers' noise in a central difference is below 1e-6 of the data)


@dataclass(frozen=True)
class Estimate:
    """An identified parameter: its value, its interval at the test's confidence, its
    unit, the first guess it started from and its relative standard error."""

    name: str
    value: float
    low: float
    high: float
    unit: str
    first_guess: float
    relative_error: float

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "value": self.value, "low": self.low, "high": self.high,
                "unit": self.unit, "first_guess": self.first_guess,
                "relative_error": self.relative_error}


@dataclass(frozen=True, eq=False)
class Fitted:
    """One measurement against the fitted model, for tables and plots: ``x`` and
    ``measured`` / ``model`` columns in SI units (a shape: the points and the points of
    the curve nearest them; ``curve`` the whole fitted neutral line)."""

    name: str
    kind: str
    x_label: str
    y_label: str
    x: np.ndarray
    measured: np.ndarray
    model: np.ndarray
    rms: float
    unit: str
    curve: np.ndarray | None = None
    curvature: float = math.nan  # [1/m] the largest bending curvature the fitted model
    # reaches in this measurement: the range the identified stiffness was tested over


@dataclass(frozen=True, eq=False)
class Identification:
    """The answer of ``identify``: the estimates, the part with them, the fit of each
    measurement, the correlation of the estimates and what the fit cost."""

    test: StiffnessTest
    estimates: tuple[Estimate, ...]
    part: Part
    fitted: tuple[Fitted, ...]
    correlation: np.ndarray
    dof: int
    scale: float  # the weighted residual's standard deviation (1 when the data's
    # uncertainties are right)
    weighted: bool
    solves: int
    seconds: float
    notes: tuple[str, ...] = field(default=())

    def value(self, name: str) -> float:
        return next(e.value for e in self.estimates if e.name == name)

    @property
    def curvature(self) -> float:
        """The largest bending curvature [1/m] any measurement reached at the fitted
        values (NaN for twist tests alone): a stiffness holds over the range it was
        tested in, which matters for rubber and stranded parts whose moment is not
        linear in the curvature."""
        values = [f.curvature for f in self.fitted if not math.isnan(f.curvature)]
        return max(values) if values else math.nan

    def to_dict(self) -> dict[str, Any]:
        return {
            "test": self.test.name, "confidence": self.test.confidence,
            "estimates": [e.to_dict() for e in self.estimates],
            "correlation": self.correlation.tolist(),
            "fit": [{"name": f.name, "kind": f.kind, "rms": f.rms, "unit": f.unit,
                     "x_label": f.x_label, "y_label": f.y_label, "x": f.x.tolist(),
                     "measured": f.measured.tolist(), "model": f.model.tolist(),
                     "max_curvature": _finite(f.curvature)}
                    for f in self.fitted],
            "max_curvature": _finite(self.curvature),
            "degrees_of_freedom": self.dof, "residual_scale": self.scale,
            "weighted": self.weighted, "solves": self.solves, "seconds": self.seconds,
            "notes": list(self.notes),
            "units": {**{e.name: e.unit for e in self.estimates}, "seconds": "s",
                      "max_curvature": "1/m"},
        }

    def part_table(self) -> str:
        """The fitted values as a ``[part]`` entry of a problem file (TOML)."""
        p = self.part
        lines = ["[part]", f'name = "{p.name}"', f"length = {p.length!r}  # m",
                 f"bending_stiffness = {p.bending_stiffness:.6g}  # N m^2"]
        for key, unit in (("bending_stiffness_2", "N m^2"), ("torsional_stiffness", "N m^2"),
                          ("mass_per_length", "kg/m")):
            value = getattr(p, key)
            if value is not None and (value or key in self.test.unknowns):
                lines.append(f"{key} = {value:.6g}  # {unit}")
        for e in self.estimates:
            lines.append(f"# {e.name}: identified, {self.test.confidence:.0%} interval "
                         f"{e.low:.4g} to {e.high:.4g} {e.unit}"
                         + (f" ({self.test.name})" if self.test.name else ""))
        if not math.isnan(self.curvature) and self.curvature > 0.0:
            lines.append(f"# tested over bending curvatures up to {self.curvature:.4g} 1/m "
                         f"(bend radius {1.0 / self.curvature:.4g} m)")
        return "\n".join(lines) + "\n"


def _finite(value: float) -> float | None:
    """JSON has no NaN: a value not measured is null."""
    return None if math.isnan(value) else value


def first_guess(part: Part, name: str) -> float:
    """The value an unknown starts from: the part's own, or what the part implies."""
    if name == "bending_stiffness_2":
        return part.bending_stiffness_2 or part.bending_stiffness
    if name == "torsional_stiffness":
        return part.torsional_stiffness or part.bending_stiffness / 1.5
    value = float(getattr(part, name))
    if value <= 0.0:
        raise InputError(f"part.{name}", f"is an unknown but its first guess is {value!r}; "
                         "give a positive first guess (a handbook value)")
    return value


def identify(test: StiffnessTest, *, solver: Any = None, time_budget: float = 120.0,
             max_evaluations: int = 60) -> Identification:
    """Fit the test's unknowns (see the module); ``solver`` the 3D model's settings."""
    from pliant.models import clock  # noqa: PLC0415 (numba: on demand)

    started = time.perf_counter()
    spent = clock.now()  # the budget counts CPU time (``pliant.models.clock``)
    part0 = test.problem.part
    names = test.unknowns
    guess = np.array([first_guess(part0, n) for n in names])
    x0 = np.log(guess)
    models = [_model_for(m, i, test, solver) for i, m in enumerate(test.measured)]
    sigmas = [m.uncertainty for m in test.measured]
    weighted = all(s is not None for s in sigmas)
    if not weighted:
        if any(s is not None for s in sigmas):
            raise InputError("measured.uncertainty", "give every [[measured]] an "
                             "uncertainty, or none (then they are weighed alike)")
        units = {m.unit for m in test.measured}
        if len(units) > 1:
            raise InputError("measured.uncertainty", "measurements in different units ("
                             + ", ".join(sorted(units)) + ") can only be weighed together "
                             "by their uncertainty: give each [[measured]] one")
    m_eff = sum(model.dof for model in models)
    dof = m_eff - len(names)
    if dof < 0 or (dof == 0 and not weighted):
        raise InputError("measured", f"too few measured values: {m_eff} for {len(names)} "
                         "unknown(s); an interval needs at least one more (measure more "
                         "points or loads), or as many with their uncertainties")
    # the last values whose residual was computed, with it (errors name them)
    state: dict[str, Any] = {"solves": 0, "at": (x0, None)}

    def part_at(x: np.ndarray) -> Part:
        values = dict(zip(names, np.exp(x).tolist()))
        return replace(part0, **values)

    def residual(x: np.ndarray) -> np.ndarray:
        if clock.now() - spent > time_budget:
            raise IdentificationError(f"the fit ran past its {time_budget:g} s budget at "
                                      + _values(names, x), _named(names, state["at"][0]))
        part = part_at(x)
        out = []
        for model, sigma in zip(models, sigmas):
            try:
                r = model.residual(part)
            except ConvergenceError as err:
                raise IdentificationError(
                    f"{model.label}: the model found no equilibrium at {_values(names, x)} "
                    f"({err}); give a first guess closer to the part in [part]",
                    _named(names, state["at"][0])) from None
            out.append(r / sigma if sigma else r)
            state["solves"] += model.solves
        state["at"] = (x.copy(), np.concatenate(out))
        return state["at"][1]

    def jacobian(x: np.ndarray, r0: np.ndarray | None = None) -> np.ndarray:
        """Forward differences for the iterations, central ones (``r0`` None) for the
        identifiability checks and the intervals."""
        cols = []
        for k in range(len(x)):
            step = np.zeros_like(x)
            if r0 is None:
                step[k] = CENTRAL
                cols.append((residual(x + step) - residual(x - step)) / (2.0 * CENTRAL))
            else:
                step[k] = STEP
                cols.append((residual(x + step) - r0) / STEP)
        return np.column_stack(cols)

    def _latest(x: np.ndarray) -> np.ndarray:
        """The residual at x: least squares asks for the Jacobian where it just was."""
        at, r = state["at"]
        return r if r is not None and np.array_equal(at, x) else residual(x)

    _check_identifiable(names, jacobian(x0), models, weighted, "at the first guess")
    from scipy.optimize import least_squares  # noqa: PLC0415

    fit = least_squares(residual, x0, jac=lambda x: jacobian(x, _latest(x)), method="trf",
                        bounds=(x0 - RANGE, x0 + RANGE), x_scale=1.0, xtol=1e-10,
                        ftol=1e-12, gtol=1e-12, max_nfev=max_evaluations)
    x = fit.x
    at_bound = np.abs(x - x0) > RANGE * (1 - 1e-6)
    if at_bound.any():
        name = names[int(np.argmax(at_bound))]
        raise IdentificationError(
            f"{name} ran to {math.exp(RANGE):g} times its first guess without fitting the "
            "measurements: check their units and the test's conditions, or give a first "
            "guess nearer", _named(names, x))
    r = residual(x)
    J = jacobian(x)
    _check_identifiable(names, J, models, weighted, "at the fitted values")
    rss = float(r @ r)
    notes = []
    if dof == 0:  # as many values as unknowns: the interval is the uncertainties' alone
        from scipy.stats import norm  # noqa: PLC0415

        s2 = 1.0
        q = float(norm.ppf(0.5 + 0.5 * test.confidence))
        notes.append("as many measured values as unknowns: the intervals come from the "
                     "stated uncertainties alone (nothing checks them)")
    else:
        from scipy.stats import t as student  # noqa: PLC0415

        s2 = rss / dof
        q = float(student.ppf(0.5 + 0.5 * test.confidence, dof))
    cov = s2 * np.linalg.inv(J.T @ J)
    se = np.sqrt(np.diag(cov))
    values = np.exp(x)
    estimates = tuple(
        Estimate(n, float(v), float(v * math.exp(-q * e)), float(v * math.exp(q * e)),
                 UNKNOWNS[n], float(g), float(e))
        for n, v, e, g in zip(names, values, se, guess))
    correlation = cov / np.outer(se, se)
    part = part_at(x)
    fitted = tuple(model.fitted(part) for model in models)
    if weighted and dof >= 3:
        from scipy.stats import chi2  # noqa: PLC0415

        if rss > chi2.ppf(0.999, dof):
            notes.append(f"the scatter is {math.sqrt(s2):.2g} times the stated "
                         "uncertainties: the uncertainties are too small or the model "
                         "misses something (the intervals are widened accordingly)")
    for n, e in zip(names, se):
        if e > 0.5:
            notes.append(f"{n} is poorly determined (a factor {math.exp(e):.2g} at one "
                         "standard error): measure larger deflections or more points")
    return Identification(test, estimates, part, fitted, correlation, dof, math.sqrt(s2),
                          weighted, state["solves"], time.perf_counter() - started,
                          tuple(notes))


def _named(names: tuple[str, ...], x: np.ndarray) -> dict[str, float]:
    return dict(zip(names, np.exp(x).tolist()))


def _values(names: tuple[str, ...], x: np.ndarray) -> str:
    return ", ".join(f"{n} = {v:.4g} {UNKNOWNS[n]}" for n, v in _named(names, x).items())


def _check_identifiable(names: tuple[str, ...], J: np.ndarray, models: list,
                        weighted: bool, where: str) -> None:
    """Refuse an unknown the data do not move, and unknowns they move only together."""
    scale = 1.0 if weighted else max(m.scale for m in models)
    norms = np.abs(J).max(axis=0)
    for name, n in zip(names, norms):
        if not n > INSENSITIVE * scale:
            raise NotIdentifiableError(
                f"the measurements do not depend on {name} ({where}): this test cannot "
                f"determine it; fix it in [part] or add a measurement that loads it "
                "(a twist for torsional_stiffness, a known load for mass_per_length)")
    if len(names) < 2:
        return
    unit = J / np.linalg.norm(J, axis=0)
    _, sv, vt = np.linalg.svd(unit, full_matrices=False)
    if sv[-1] < COLLINEAR * sv[0]:
        v = vt[-1] / vt[-1][np.argmax(np.abs(vt[-1]))]
        together = " · ".join(f"{n}^{c:+.2f}" for n, c in zip(names, v) if abs(c) > 0.05)
        raise NotIdentifiableError(
            "the measurements cannot tell "
            f"{' from '.join(n for n, c in zip(names, v) if abs(c) > 0.05)}"
            f" ({where}): changing them together as {together} leaves the fit unchanged; "
            "fix one of them in [part], or add a measurement that separates them (a known "
            "load for a weight and a stiffness, a twist for a torsional stiffness)")


# --- one model per kind of measurement ------------------------------------------------


def _model_for(m: Measurement, index: int, test: StiffnessTest, solver: Any):
    label = f"measured[{index}] ({m.name})"
    if isinstance(m, Shape):
        return _ShapeModel(m, label, test.problem, solver)
    if isinstance(m, Deflection):
        return _DeflectionModel(m, label, test.problem, solver)
    if isinstance(m, ThreePointBending):
        return _BendingModel(m, label, test.problem)
    if isinstance(m, Twist):
        return _TwistModel(m, label, test.problem, solver)
    if isinstance(m, TwistBuckling):
        return _BucklingModel(m, label, test.problem, solver)
    raise InputError(label, f"unknown measurement {type(m).__name__}")


def _solve(problem: Problem, warm: Any, solver: Any):
    from pliant.models.dispatch import solve  # noqa: PLC0415 (numba kernels: on demand)

    if problem.dimension == 2:  # cold: a 2D solve costs less than a warm one's homotopy
        return solve(problem)
    from pliant.models.rod3d import RodSolver  # noqa: PLC0415

    # The branch the part was measured on: a fit's finite differences must not jump to
    # another, and settling would test each of its many solves' stability.
    return solve(problem, warm_start=warm, solver=replace(solver or RodSolver(), settle=False))


def _curve(eq) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(s, position, unit tangent) at the solver's nodes, either model."""
    s = np.asarray(eq.s, dtype=float)
    position = np.asarray(eq.position, dtype=float)
    tangent = np.asarray(eq.tangent, dtype=float)
    keep = np.concatenate([[True], np.diff(s) > 0.0])  # a station's doubled sample
    return s[keep], position[keep], tangent[keep]


def _hermite(p0, p1, m0, m1, h, t):
    """The cubic Hermite point, first and second derivatives (in t) on segments."""
    t = t[..., None]
    t2, t3 = t * t, t * t * t
    a, b = h[..., None] * m0, h[..., None] * m1
    point = (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + t) * a + (-2 * t3 + 3 * t2) * p1 \
        + (t3 - t2) * b
    d1 = (6 * t2 - 6 * t) * p0 + (3 * t2 - 4 * t + 1) * a + (-6 * t2 + 6 * t) * p1 \
        + (3 * t2 - 2 * t) * b
    d2 = (12 * t - 6) * p0 + (6 * t - 4) * a + (-12 * t + 6) * p1 + (6 * t - 2) * b
    return point, d1, d2


def project(points: np.ndarray, s: np.ndarray, position: np.ndarray,
            tangent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nearest points of the curve through ``position`` (with unit ``tangent`` at arc
    lengths ``s``) to each of ``points``, and their arc lengths. Between nodes the curve is
    the cubic Hermite interpolant (fourth-order accurate); past the ends it goes on
    straight along the end tangents."""
    d = np.linalg.norm(points[:, None, :] - position[None, :, :], axis=2)
    k = np.argmin(d, axis=1)
    segments = len(s) - 1
    best_point = np.empty_like(points)
    best_s = np.empty(len(points))
    best_d = np.full(len(points), np.inf)
    for seg in (np.clip(k - 1, 0, segments - 1), np.clip(k, 0, segments - 1)):
        p0, p1 = position[seg], position[seg + 1]
        m0, m1 = tangent[seg], tangent[seg + 1]
        h = s[seg + 1] - s[seg]
        chord = p1 - p0  # the chord's projection starts Newton close
        t = np.clip(np.einsum("ij,ij->i", points - p0, chord)
                    / np.einsum("ij,ij->i", chord, chord), 0.0, 1.0)
        for _ in range(12):  # Newton on |H(t) - q|^2, kept in the segment
            pt, d1, d2 = _hermite(p0, p1, m0, m1, h, t)
            diff = pt - points
            g = np.einsum("ij,ij->i", diff, d1)
            hess = np.einsum("ij,ij->i", d1, d1) + np.einsum("ij,ij->i", diff, d2)
            moved = np.clip(t - g / np.where(hess > 0, hess, np.inf), 0.0, 1.0)
            done = np.abs(moved - t).max() < 1e-12  # of a segment: 1e-14 m here
            t = moved
            if done:
                break
        pt = _hermite(p0, p1, m0, m1, h, t)[0]
        dist = np.linalg.norm(pt - points, axis=1)
        better = dist < best_d
        best_d[better] = dist[better]
        best_point[better] = pt[better]
        best_s[better] = (s[seg] + t * h)[better]
    # Past an end the curve goes on along its end tangent: the offset stays normal to it,
    # and smooth in the parameters when the end moves past a point.
    for end, sign in ((0, -1.0), (-1, 1.0)):
        along = (points - position[end]) @ tangent[end]
        past = sign * along > 0.0
        if end == 0:
            past &= best_s <= s[0]
        else:
            past &= best_s >= s[-1]
        best_point[past] = position[end] + along[past, None] * tangent[end]
        best_s[past] = s[end] + along[past]
    return best_point, best_s


def _at(s_query: float, s: np.ndarray, position: np.ndarray, tangent: np.ndarray):
    """The curve's point at arc length ``s_query`` (Hermite between nodes)."""
    seg = int(np.clip(np.searchsorted(s, s_query) - 1, 0, len(s) - 2))
    h = s[seg + 1] - s[seg]
    t = np.array([(s_query - s[seg]) / h])
    return _hermite(position[seg][None], position[seg + 1][None], tangent[seg][None],
                    tangent[seg + 1][None], np.array([h]), t)[0][0]


def _condition_index(problem: Problem, name: str, label: str) -> int:
    """Where the condition a measurement names stands in the problem's conditions."""
    for i, c in enumerate(problem.conditions):
        if c.name == name:
            return i
    raise InputError(f"{label}.condition", f"no condition named {name!r}; known: "
                     + ", ".join(c.name for c in problem.conditions))


class _ShapeModel:
    def __init__(self, m: Shape, label: str, problem: Problem, solver: Any) -> None:
        if m.points.ndim != 2 or m.points.shape[1] != problem.dimension:
            raise InputError(label, f"the points have {m.points.shape[-1]} coordinates in a "
                             f"{problem.dimension}D test; give x, y" +
                             (", z" if problem.dimension == 3 else ""))
        if len(m.points) < 3:
            raise InputError(label, f"{len(m.points)} point(s) do not make a shape; measure "
                             "at least 3 along the part (20 to 50 give a good interval)")
        self.m, self.label, self.problem, self.solver = m, label, problem, solver
        self.dof = len(m.points) * (problem.dimension - 1)
        self.scale = float(np.ptp(m.points, axis=0).max())
        self.warm = None
        self.solves = 0

    def _eq(self, part: Part):
        eq = _solve(replace(self.problem, part=part), self.warm, self.solver)
        self.solves = 1
        if self.warm is None:
            self.warm = eq
        return eq

    def residual(self, part: Part) -> np.ndarray:
        s, position, tangent = _curve(self._eq(part))
        nearest, _ = project(self.m.points, s, position, tangent)
        return (nearest - self.m.points).ravel()

    def fitted(self, part: Part) -> Fitted:
        eq = self._eq(part)
        s, position, tangent = _curve(eq)
        nearest, at = project(self.m.points, s, position, tangent)
        off = np.linalg.norm(nearest - self.m.points, axis=1)
        return Fitted(self.m.name, "shape", "s [m]", "offset [m]", at, self.m.points,
                      nearest, float(np.sqrt(np.mean(off ** 2))), "m", curve=position,
                      curvature=float(np.abs(eq.curvature).max()))


class _DeflectionModel:
    def __init__(self, m: Deflection, label: str, problem: Problem, solver: Any) -> None:
        self.index = _condition_index(problem, m.condition, label)
        c = problem.conditions[self.index]
        d = problem.dimension
        if len(m.direction) != d or m.position.shape[1] != d:
            raise InputError(label, f"give the direction and the measured coordinates with "
                             f"{d} axes in a {d}D test")
        if c.follower or any(p is not None and abs(u) > 0 for p, u in
                             zip(c.position, m.direction)):
            raise InputError(f"{label}.condition", f"{m.condition!r} holds the part where "
                             "the load acts; the loaded condition must apply a dead force "
                             "(Fx, Fy, ...) there, not prescribe the position")
        if not 0.0 <= m.s <= problem.part.length:
            raise InputError(f"{label}.s", f"s = {m.s} m lies outside the part")
        self.m, self.label, self.problem, self.solver = m, label, problem, solver
        self.mask = ~np.isnan(m.position)
        self.dof = int(self.mask.sum())
        self.scale = float(np.nanmax(np.abs(m.position))) or 1.0
        # A relative table is read against the pose under no load: solved first, as
        # load 0, and subtracted (a table's own zero row then fits by construction).
        self.loads = np.concatenate([[0.0], m.load]) if m.relative else m.load
        self.order = np.argsort(self.loads, kind="stable")
        self.warm: list = [None] * len(self.loads)
        self.solves = len(self.loads)

    def _positions(self, part: Part) -> np.ndarray:
        c = self.problem.conditions[self.index]
        out = np.empty((len(self.loads), self.m.position.shape[1]))
        self.curvature = 0.0
        previous = None
        for i in self.order:  # loads in order: each warm-starts the next
            force = tuple(float(v) for v in self.loads[i] * self.m.direction)
            conditions = list(self.problem.conditions)
            conditions[self.index] = replace(c, force=force)
            problem = Problem(part, tuple(conditions), self.problem.gravity,
                              self.problem.name, self.problem.obstacles)
            eq = _solve(problem, self.warm[i] or previous, self.solver)
            if self.warm[i] is None:
                self.warm[i] = eq
            previous = eq
            out[i] = _at(self.m.s, *_curve(eq))
            self.curvature = max(self.curvature, float(np.abs(eq.curvature).max()))
        return out[1:] - out[0] if self.m.relative else out

    def residual(self, part: Part) -> np.ndarray:
        return (self._positions(part) - self.m.position)[self.mask]

    def fitted(self, part: Part) -> Fitted:
        model = self._positions(part)
        zero = 0.0 if self.m.relative else self.m.position[int(np.argmin(np.abs(
            self.m.load)))]
        axis = int(np.argmax(np.nansum(np.abs(self.m.position - zero), axis=0)))
        off = (model - self.m.position)[self.mask]
        what = f"{'displacement ' if self.m.relative else ''}{'xyz'[axis]}"
        return Fitted(self.m.name, "deflection", "load [N]",
                      f"{what} at s = {self.m.s:g} m [m]", self.m.load,
                      self.m.position[:, axis], model[:, axis],
                      float(np.sqrt(np.mean(off ** 2))), "m", curvature=self.curvature)


class _BendingModel:
    def __init__(self, m: ThreePointBending, label: str, problem: Problem) -> None:
        if not 0.0 < m.span < problem.part.length:
            raise InputError(f"{label}.span", f"the span {m.span} m must be shorter than the "
                             f"part ({problem.part.length} m) lying across the supports")
        if np.any(np.diff(m.displacement) <= 0.0):
            raise InputError(f"{label}.data", "the displacement must grow from row to row "
                             "(one loading branch); drop the unloading rows or sort them")
        if np.any(m.displacement <= 0.0):
            raise InputError(f"{label}.data", "displacements are measured from first contact "
                             "and must be positive; drop the zero row")
        self.m, self.label, self.problem = m, label, problem
        self.dof = len(m.load)
        self.scale = float(np.abs(m.load).max()) or 1.0
        self.unit_load: np.ndarray | None = None
        self.curvature = math.nan
        self.solves = 0

    def _unit(self) -> np.ndarray:
        """The load per unit bending stiffness at each displacement [N per N m^2]."""
        if self.unit_load is None:
            part = self.problem.part
            half = 0.5 * part.length
            a = 0.5 * self.m.span
            contacts = [_support_contact(half, a, float(delta), self.label)
                        for delta in self.m.displacement]
            self.unit_load = 2.0 * np.array([force for force, _ in contacts])
            # the curvature under the ram is geometric: the same for any stiffness
            self.curvature = max(kappa for _, kappa in contacts)
        return self.unit_load

    def residual(self, part: Part) -> np.ndarray:
        return part.bending_stiffness * self._unit() - self.m.load

    def fitted(self, part: Part) -> Fitted:
        model = part.bending_stiffness * self._unit()
        return Fitted(self.m.name, "three-point bending", "displacement [m]", "load [N]",
                      self.m.displacement, self.m.load, model,
                      float(np.sqrt(np.mean((model - self.m.load) ** 2))), "N",
                      curvature=self.curvature)


def support_force(half: float, a: float, delta: float, label: str) -> float:
    """The vertical force [N] of ``_support_contact``."""
    return _support_contact(half, a, delta, label)[0]


def _support_contact(half: float, a: float, delta: float, label: str) -> tuple[float, float]:
    """(force, curvature under the ram [1/m]); the vertical force [N] a frictionless support ``a``
    from the middle and ``delta``
    above it applies to a half part of length ``half`` and unit stiffness, clamped level
    at the middle. Up to the contact the half part is a cantilever of length l loaded at
    its tip by the support's force, normal to it (a normal follower force F); beyond, it is
    straight and unloaded. Its tip is at l (X, Y)(beta) with beta = F l^2 / EI, so the
    contact is the root of Y / X = delta / a; then l = a / X and F = beta / l^2."""
    from scipy.optimize import brentq  # noqa: PLC0415

    from pliant.core.conditions import push  # noqa: PLC0415
    from pliant.models.dispatch import solve  # noqa: PLC0415

    unit = Part(1.0, 1.0)
    cache: dict[float, tuple[float, float, float, float]] = {}

    def tip(beta: float) -> tuple[float, float, float, float]:
        if beta not in cache:
            eq = solve(Problem(unit, (clamp(0.0, (0.0, 0.0), 0.0, "middle"),
                                      push(1.0, (0.0, beta), follower=True, name="support"))))
            x, y = eq.position[-1]
            tx, ty = eq.tangent[-1]
            cache[beta] = (float(x), float(y), math.atan2(ty, tx), float(eq.curvature[0]))
        return cache[beta]

    def gap(beta: float) -> float:
        x, y, _, _ = tip(beta)
        return math.atan2(y, x) - math.atan2(delta, a)

    low, high = 0.0, 3.0 * delta / a  # Y / X = beta / 3 for small beta
    while gap(high) < 0.0:
        x, _, _, _ = tip(high)
        if x <= 0.0 or a / x > half or high > 1e3:
            raise InputError(f"{label}.data", f"at a displacement of {delta * 1e3:.4g} mm the "
                             f"part ({2 * half} m) slides off its supports {2 * a} m apart: "
                             "drop those rows or use a longer specimen")
        low, high = high, 2.0 * high
    beta = brentq(gap, low, high, xtol=1e-14, rtol=1e-13)
    x, _, angle, kappa = tip(beta)
    length = a / x
    if length > half:
        raise InputError(f"{label}.data", f"at a displacement of {delta * 1e3:.4g} mm the part "
                         f"({2 * half} m) slides off its supports {2 * a} m apart: drop those "
                         "rows or use a longer specimen")
    return beta / length ** 2 * math.cos(angle), abs(kappa) / length


class _TwistModel:
    def __init__(self, m: Twist, label: str, problem: Problem, solver: Any) -> None:
        part = problem.part
        if any(np.any(np.asarray(k)[:, 1] != 0.0) for k in
               (part.rest_knots, part.rest_knots_2, part.twist_knots)):
            raise InputError(label, "a twist test holds a straight length of the part; "
                             "this part has a rest curvature or twist")
        if not 0.0 < m.length:
            raise InputError(f"{label}.length", "give the free length between the chucks")
        if np.any(np.diff(np.concatenate([[0.0], np.abs(m.angle)])) < 0):
            raise InputError(f"{label}.data", "the angle must grow from row to row (one "
                             "loading branch)")
        self.m, self.label, self.solver = m, label, solver
        self.warm: list | None = None
        self.dof = len(m.moment)
        self.scale = float(np.abs(m.moment).max()) or 1.0
        self.solves = 0

    def _moments(self, part: Part) -> np.ndarray:
        from pliant.models.rod3d import RodSolver  # noqa: PLC0415
        from pliant.models.rod3d.solver import solve, trace  # noqa: PLC0415

        L = self.m.length
        specimen = replace(part, length=L)
        base = clamp(0.0, (0.0, 0.0, 0.0), name="fixed chuck", tangent=(1.0, 0.0, 0.0),
                     normal=(0.0, 0.0, 1.0))
        steps: list[Problem] = []
        marks = []
        angle = 0.0
        for target in self.m.angle:  # at most a sixth of a turn per step
            n = max(1, math.ceil(abs(target - angle) / (math.pi / 3)))
            for k in range(1, n + 1):
                phi = angle + (target - angle) * k / n
                # The turning chuck slides along the axis (no axial load), as rigs do.
                turned = Condition(s=L, name="turned chuck", position=(None, 0.0, 0.0),
                                   tangent=(1.0, 0.0, 0.0),
                                   normal=(0.0, -math.sin(phi), math.cos(phi)))
                steps.append(Problem(specimen, (base, turned)))
            marks.append(len(steps) - 1)
            angle = float(target)
        # The discrete rod's twist per element is exact to O(h^2): a sixtieth of a radian
        # per element keeps it within 1e-4 of the smooth rod's.
        elements = max(40, min(4000, math.ceil(float(np.abs(self.m.angle).max()) * 60.0)))
        solver = RodSolver(elements=max(elements, self.solver.elements if self.solver else 0))
        if self.warm is None:  # followed from 0 once; later parameters start from it
            eqs = list(trace(steps, solver=solver))
            self.warm = [eqs[i] for i in marks]
            self.solves = len(eqs)
            found = self.warm
        else:
            found = [solve(steps[i], warm_start=w, solver=solver)
                     for i, w in zip(marks, self.warm)]
            self.solves = len(found)
        return np.array([eq.loads["turned chuck"].moment[0] for eq in found])

    def residual(self, part: Part) -> np.ndarray:
        return self._moments(part) - self.m.moment

    def fitted(self, part: Part) -> Fitted:
        model = self._moments(part)
        return Fitted(self.m.name, "twist", "angle [rad]", "moment [N m]", self.m.angle,
                      self.m.moment, model,
                      float(np.sqrt(np.mean((model - self.m.moment) ** 2))), "N m")


class _BucklingModel:
    """The clamp turned about its axis until the part's equilibrium loses stability (the
    smallest eigenvalue of the constrained Hessian crosses zero: Greenhill's buckle of a
    straight length, the snap of a loop) or its branch ends (a fold)."""

    def __init__(self, m: TwistBuckling, label: str, problem: Problem, solver: Any) -> None:
        if problem.dimension != 3:
            raise InputError(label, "a twist buckles in 3D: give the test 3D conditions")
        self.index = _condition_index(problem, m.condition, label)
        c = problem.conditions[self.index]
        if c.tangent is None or c.normal is None:
            raise InputError(f"{label}.condition", f"{m.condition!r} must hold the part's "
                             "axis and twist (tangent and normal) to be turned about its axis")
        if not m.angle > 0.0:
            raise InputError(f"{label}.angle", "give the critical angle in rad, positive (the "
                             "turn's sense is about the clamp's tangent)")
        from pliant.models.rod3d import RodSolver  # noqa: PLC0415

        # The branch itself, unstable past the critical angle: its eigenvalue's zero is
        # the measurement, so a solve must not leave it for the buckled shape.
        self.solver = replace(solver or RodSolver(), settle=False)
        self.m, self.label, self.problem = m, label, problem
        self.dof = 1
        self.scale = m.angle
        self.step = min(math.pi / 8.0, m.angle / 16.0)
        self.below: tuple[float, Any] | None = None  # the last stable pose under the angle
        self.solves = 0

    def _turned(self, part: Part, phi: float) -> Problem:
        c = self.problem.conditions[self.index]
        t, n = np.array(c.tangent), np.array(c.normal)
        normal = n * math.cos(phi) + np.cross(t, n) * math.sin(phi)
        conditions = list(self.problem.conditions)
        conditions[self.index] = replace(c, normal=tuple(float(v) for v in normal))
        return replace(self.problem, part=part, conditions=tuple(conditions))

    def _at(self, part: Part, phi: float, warm: Any):
        """(equilibrium, smallest eigenvalue) at phi, or None past a fold."""
        from pliant.models.rod3d.solver import solve  # noqa: PLC0415

        self.solves += 1
        try:
            eq = solve(self._turned(part, phi), warm_start=warm, solver=self.solver)
        except ConvergenceError:
            return None
        if has(eq.notes, WarmStartLost):
            return None  # the branch ended: it jumped
        stable, eigen = eq.stability
        if stable is None:
            raise InputError(self.label, "the test's loads are not conservative (a follower "
                             "load or a dead moment): stability is undecided")
        return eq, float(eigen or 0.0)  # decided: stable is not None

    def critical(self, part: Part) -> float:
        self.solves = 0
        h = self.step
        if self.below is None:
            phi, found = 0.0, self._at(part, 0.0, None)
        else:
            phi, warm = self.below
            found = self._at(part, phi, warm)
            while found is not None and found[1] <= 0.0 and phi > 0.0:  # back under it
                phi = max(0.0, phi - h)
                found = self._at(part, phi, found[0])
        if found is None or found[1] <= 0.0:
            raise IdentificationError(f"{self.label}: the part is not stable at "
                                      f"{phi:.3g} rad: it cannot be turned from there")
        low, low_eq = phi, found
        while True:  # step on until the eigenvalue crosses zero or the branch ends
            if low > 20.0 * self.m.angle:
                raise IdentificationError(f"{self.label}: no buckle up to {low:.3g} rad "
                                          f"(20 times the measured {self.m.angle:.3g} rad)")
            nxt = self._at(part, low + h, low_eq[0])
            if nxt is None or nxt[1] <= 0.0:
                break
            low, low_eq = low + h, nxt
        high, high_eq = low + h, nxt
        for _ in range(40):  # secant on the eigenvalue where both ends have one, else halves
            if high - low < 1e-9 * self.m.angle:
                break
            if high_eq is not None:
                mid = low + (high - low) * low_eq[1] / (low_eq[1] - high_eq[1])
                mid = min(max(mid, low + 0.05 * (high - low)), high - 0.05 * (high - low))
            else:
                mid = 0.5 * (low + high)
            probe = self._at(part, mid, low_eq[0])
            if probe is not None and probe[1] > 0.0:
                low, low_eq = mid, probe
                if high_eq is not None and abs(probe[1]) < 1e-10 * abs(high_eq[1] - probe[1]):
                    break
            else:
                high, high_eq = mid, probe
        self.below = (low, low_eq[0])
        if high_eq is None:
            return 0.5 * (low + high)
        return low + (high - low) * low_eq[1] / (low_eq[1] - high_eq[1])

    def residual(self, part: Part) -> np.ndarray:
        return np.array([self.critical(part) - self.m.angle])

    def fitted(self, part: Part) -> Fitted:
        model = self.critical(part)
        return Fitted(self.m.name, "twist buckling", "measurement", "critical angle [rad]",
                      np.array([0.0]), np.array([self.m.angle]), np.array([model]),
                      abs(model - self.m.angle), "rad")
