"""Lower a 2D ``Problem`` into the dimensionless arrays of the shooting kernel.

Scales: lengths by L, forces by EI/L^2, moments by EI/L, distributed loads by EI/L^3.
Kernel stations are the problem's stations plus both ends, the knots of the rest
curvature (so that no Runge-Kutta step straddles a kink of kappa0, which would cost
accuracy) and the restart nodes of multiple shooting.

A ``Lowered`` problem also knows its *rest state*: the unloaded part placed so that it
meets the prescribed components of the first station exactly and the others as well as a
rigid placement can. The solver's homotopy starts there (all loads zero, every prescribed
component at its rest value) and ends at the problem.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pliant.core.equilibrium import PlanarArrays, model_loads
from pliant.core.problem import Problem, Station
from pliant.models.elastica2d import kernels
from pliant.models.elastica2d.kernels import APPLIED, NODE, PRESCRIBED
from pliant.models.scale import force_terms, refuse, scale_terms

# Largest wavenumber times interval length between restart nodes: the sensitivities
# grow by at most about exp(NODE_SPAN) across one shooting interval.
NODE_SPAN = 8.0
_NO_ROWS = np.zeros((0, kernels.NSTATE))  # no trajectory asked for (the kernels only read it)


@dataclass(slots=True, eq=False)
class Arrays:
    """The load-dependent kernel inputs at one point of a homotopy."""

    val: np.ndarray  # (nst, 3): prescribed kinematics or applied dead loads
    fol: np.ndarray  # (nst, 2): follower loads (tangential, normal)
    prm: np.ndarray  # (6,): fx, fy, bow, bow from, bow to, axial compliance
    # (nst, 4): per segment (its first station's row) the distributed loads on a
    # stretch only, dead (fx, fy) and follower (ft, fn), per unit length
    dist: np.ndarray

    def lerp(self, other: Arrays, t: float) -> Arrays:
        return Arrays(self.val + t * (other.val - self.val),
                      self.fol + t * (other.fol - self.fol),
                      self.prm + t * (other.prm - self.prm),
                      self.dist + t * (other.dist - self.dist))

    def with_bow(self, bow: float, span: tuple[float, float]) -> Arrays:
        prm = self.prm.copy()
        prm[2:5] = (bow, span[0], span[1])
        return Arrays(self.val, self.fol, prm, self.dist)

    def unloaded(self) -> Arrays:
        """The same targets with every load (point and distributed) removed."""
        prm = self.prm.copy()
        prm[:2] = 0.0
        return Arrays(self.val, np.zeros_like(self.fol), prm, np.zeros_like(self.dist))

    @property
    def follower(self) -> bool:
        """Whether any load follows the part (no potential: no stability, no energy).
        (``count_nonzero``: a quarter of ``any``'s time on these few numbers.)"""
        return bool(np.count_nonzero(self.fol) or np.count_nonzero(self.dist[:, 2:]))

    @property
    def inputs(self) -> tuple:
        """The kernels' ``Inputs``, as the plain tuple they take from Python."""
        return self.val, self.fol, self.dist, self.prm


@dataclass(slots=True, eq=False)
class Mesh:
    """Runge-Kutta steps per segment."""

    steps: np.ndarray  # (nst - 1,) int64
    density: int  # steps per unit (dimensionless) length


@dataclass(eq=False)
class Lowered:
    problem: Problem
    length: float
    stiffness: float
    st_s: np.ndarray  # (nst,)
    st_kind: np.ndarray  # (nst, 3) int64: APPLIED, PRESCRIBED or NODE
    st_col: np.ndarray  # (nst, 3) int64: the unknown's column (a node's first column)
    seg_lo: np.ndarray  # (nst - 1,) int64: live sensitivity columns per segment
    seg_hi: np.ndarray
    st_kappa: np.ndarray  # (nst,) rest curvature at the stations, linear in between
    target: Arrays
    station_of: tuple[Station | None, ...]  # the problem's station behind each one
    nz: int
    key: tuple = ()  # equal keys: same structure (a warm start can reuse unknowns)
    inputs: tuple[float, ...] = ()  # what moves between problems (``_inputs``)
    nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    interval: float = 1.0  # the longest stretch between restarts (dimensionless)
    problem_rows: tuple[int, ...] = ()  # the kernel station of each problem station
    # The kernels' ``Stations`` of this lowering, as the plain tuple they take from
    # Python, and zero follower and distributed loads that the rest states share (the
    # kernels copy what they change): made once, not per solve.
    stations: tuple = ()
    unloaded: tuple = ()
    # The applied loads' wavenumber (``load_wavenumber``) where ``lower`` worked it out
    # (a cold solve's first mesh reads it); None on a retargeted lowering.
    wave: float | None = None

    def __post_init__(self) -> None:
        if not self.stations:
            self.stations = tuple(kernels.Stations(self.st_s, self.st_kind, self.st_col,
                                                   self.seg_lo, self.seg_hi, self.st_kappa))
            self.unloaded = (np.zeros(self.target.fol.shape), np.zeros(self.target.dist.shape))

    # -- scales ---------------------------------------------------------------------------
    @property
    def force_scale(self) -> float:
        return self.stiffness / self.length**2

    @property
    def moment_scale(self) -> float:
        return self.stiffness / self.length

    def retarget(self, problem: Problem) -> Lowered | None:
        """The same lowering for another problem with the same part and stations (only
        targets and loads moved: a hand's next pose), or None. Cheaper than ``lower``."""
        before = self.problem
        if problem.part is not before.part and problem.part != before.part:
            return None
        rows, stations = self.problem_rows, problem.stations
        if len(stations) != len(rows):
            return None
        length, stiffness = self.length, self.stiffness
        fs, ms = stiffness / (length * length), stiffness / length
        flat: list[float] = []
        for st, old in zip(stations, before.stations):
            if st.s != old.s or st.prescribed != old.prescribed:
                return None
            flat += _targets(st, length, fs, ms)
        if len(rows) == len(self.station_of):  # every kernel station a problem's
            station_of = stations
        else:
            listed = list(self.station_of)
            for k, st in zip(rows, stations):
                listed[k] = st
            station_of = tuple(listed)
        rows_of = np.array(flat).reshape(-1, 5)
        if len(rows) == self.st_s.shape[0]:  # every kernel station a problem's
            val, fol = rows_of[:, :3].copy(), rows_of[:, 3:].copy()
        else:  # the restart nodes' rows hold zeros
            val, fol = self.target.val.copy(), self.target.fol.copy()
            val[list(rows)], fol[list(rows)] = rows_of[:, :3], rows_of[:, 3:]
        dist = self.target.dist  # zeros without loads on stretches (the warm path)
        if problem.distributed or self.problem.distributed:
            if _load_spans(problem) != _load_spans(self.problem):
                return None  # the kernel's stations are cut where each load starts and ends
            dist = segment_loads(problem, self.st_s)
        prm = self.target.prm
        fx, fy = distributed_load(problem)
        if fx != prm[0] or fy != prm[1]:
            prm = prm.copy()  # the kernels copy what they change: arrays may be shared
            prm[0], prm[1] = fx, fy
        # A copy of this lowering with the new targets: its structure (the arrays the
        # kernels' ``Stations`` hold) is shared, and the per-field __init__ is skipped
        # (a warm step's budget is some tens of microseconds).
        out = object.__new__(Lowered)
        out.__dict__ = {**self.__dict__, "problem": problem,
                        "target": Arrays(val, fol, prm, dist),
                        "station_of": station_of,
                        "inputs": _inputs(flat, fx, fy, dist) if dist is not self.target.dist
                        else (*flat, fx, fy, *self.inputs[len(flat) + 2:]),  # the same tail
                        "wave": None}
        return out

    # -- kernel calls ---------------------------------------------------------------------
    def mesh(self, density: int) -> Mesh:
        return Mesh(steps=kernels.mesh_steps(self.st_s, int(density)), density=int(density))

    def args(self, arrays: Arrays, mesh: Mesh) -> tuple:
        """The shooting kernels' arguments after the unknowns: (stations, inputs, steps)."""
        return self.stations, arrays.inputs, mesh.steps

    def shoot(self, z: np.ndarray, arrays: Arrays, mesh: Mesh,
              want_jac: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """(residual, Jacobian; empty unless ``want_jac``). A trajectory's rows lie where
        ``rows`` says (``solver._Sampler`` shoots them itself)."""
        res, jac, _ = kernels.shoot(z, *self.args(arrays, mesh), want_jac, _NO_ROWS)  # type: ignore[call-arg]
        return res, jac

    def rows(self, mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
        """(s, rows): the arc length [m] of each trajectory row, and each station's row
        (the start of its segment; the end for the last station): ``kernels.sample_rows``."""
        return kernels.sample_rows(self.st_s, mesh.steps, self.length)

    # -- the rest state -------------------------------------------------------------------
    def rest(self, mesh: Mesh, bow: float = 0.0,
             span: tuple[float, float] = (0.0, 1.0)) -> tuple[Arrays, np.ndarray]:
        """The homotopy's start: (arrays, unknowns) of the unloaded, placed part,
        integrated on the mesh the homotopy will use, so that it is an exact start
        (see ``kernels.rest_state``)."""
        # An extensible part starts soft (EA at most 1e3 EI / L^2) and stiffens along the
        # homotopy: a stiff part pulled taut from its straight rest state is a stiff path.
        comp = self.target.prm[5]
        prm = np.array([0.0, 0.0, bow, span[0], span[1], max(comp, SOFT) if comp else 0.0])
        fol, dist = self.unloaded
        val, z = kernels.rest_state(self.stations, (self.target.val, fol, dist, prm),
                                    mesh.steps, self.nz)
        return Arrays(val, fol, prm, dist), z

    def chord(self) -> tuple[int, int] | None:
        """The first and last stations whose whole position is prescribed."""
        located = [k for k, (x, y, _) in enumerate(self.st_kind.tolist())
                   if x == PRESCRIBED and y == PRESCRIBED]
        if len(located) < 2:
            return None
        return located[0], located[-1]

    def shortening(self, rest: Arrays) -> float:
        """How much the targets shorten that chord (dimensionless, zero if they
        lengthen it)."""
        ends = self.chord()
        if ends is None:
            return 0.0
        a, b = ends
        ra, rb, ta, tb = (v[k].tolist() for v in (rest.val, self.target.val) for k in (a, b))
        return max(0.0, math.hypot(rb[0] - ra[0], rb[1] - ra[1])
                   - math.hypot(tb[0] - ta[0], tb[1] - ta[1]))

    def lateral_side(self, rest: Arrays) -> float:
        """+1 or -1: the side (left or right of the rest chord) the part is pushed to,
        by the targets' lateral motion and by the lateral loads, each measured as the
        deflection it makes (a load's by small-deflection beam theory over the chord).
        (In floats: a few stations' rows, where numpy's calls took 30 us of a 1.4 ms
        cold solve.)"""
        kind, st_s = self.st_kind.tolist(), self.st_s.tolist()
        target, at_rest = self.target.val.tolist(), rest.val.tolist()
        ends = self.chord()
        if ends is not None:
            a, b = ends
            cx, cy = at_rest[b][0] - at_rest[a][0], at_rest[b][1] - at_rest[a][1]
            width = st_s[b] - st_s[a]
        else:
            cx, cy, width = math.cos(at_rest[0][2]), math.sin(at_rest[0][2]), 1.0
        size = max(math.hypot(cx, cy), 1e-300)
        normal = (-cy / size, cx / size)
        moved = dead = 0.0
        for held, aim, was in zip(kind, target, at_rest):
            for i in (0, 1):
                if held[i] == PRESCRIBED:
                    moved += (aim[i] - was[i]) * normal[i]
                elif held[i] == APPLIED:
                    dead += aim[i] * normal[i]
        dist = self.target.dist.tolist()  # on stretches: each segment's first row
        spread = sum((dist[k][0] * normal[0] + dist[k][1] * normal[1]) * (st_s[k + 1] - st_s[k])
                     for k in range(len(st_s) - 1))
        follow = sum(row[1] for row in self.target.fol.tolist())
        fx, fy = self.target.prm[:2].tolist()
        # Distributed load q: deflection ~ q w^4 / 100; point load P: ~ P w^3 / 48.
        side = moved + (fx * normal[0] + fy * normal[1]) * width**4 / 100.0
        side += (spread + dead + follow) * width**3 / 48.0
        return -1.0 if side < -1e-12 else 1.0

    # -- unknowns <-> physical state ------------------------------------------------------
    def unknowns_from(self, eq: PlanarArrays) -> np.ndarray:
        """Dimensionless unknowns from any equilibrium of a problem with the same part:
        its pose at s = 0, the loads of the conditions (by name) and its state at the
        restart nodes."""
        z = np.zeros(self.nz)
        pose0 = (eq.position[0, 0] / self.length, eq.position[0, 1] / self.length,
                 float(eq.angle[0]))
        loads = model_loads(eq)
        for k, station in enumerate(self.station_of):
            if self.st_kind[k, 0] == NODE:
                s = self.st_s[k] * self.length
                c0 = self.st_col[k, 0]
                z[c0] = np.interp(s, eq.s, eq.position[:, 0]) / self.length
                z[c0 + 1] = np.interp(s, eq.s, eq.position[:, 1]) / self.length
                z[c0 + 2] = np.interp(s, eq.s, eq.angle)
                z[c0 + 3] = np.interp(s, eq.s, eq.internal_force[:, 0]) / self.force_scale
                z[c0 + 4] = np.interp(s, eq.s, eq.internal_force[:, 1]) / self.force_scale
                z[c0 + 5] = np.interp(s, eq.s, eq.bending_moment) / self.moment_scale
                continue
            for i in range(3):
                col = self.st_col[k, i]
                if col < 0:
                    continue
                if k == 0 and self.st_kind[0, i] == APPLIED:
                    z[col] = pose0[i]
                    continue
                owner = station.owner[i] if station is not None else None
                if owner is not None and owner in loads:
                    load = loads[owner]
                    z[col] = (load.force[i] / self.force_scale if i < 2
                              else load.moment / self.moment_scale)
        return z


def _targets(st: Station, length: float, fs: float, ms: float) -> tuple[float, ...]:
    """A problem station's row of the kernels' targets and applied loads (``Arrays.val``:
    each pair's prescribed kinematics or applied dead load) and of its follower loads
    (``Arrays.fol``), dimensionless by the length, the force scale fs and the moment
    scale ms: five floats."""
    (px, py, pa), (kx, ky, ka), (dx, dy, da) = st.prescribed, st.kinematics, st.dead_load
    ft, fn = st.follower_load
    return (kx / length if px else dx / fs, ky / length if py else dy / fs,
            ka if pa else da / ms, ft / fs, fn / fs)


def _inputs(flat: list[float], fx: float, fy: float,
            dist: np.ndarray) -> tuple[float, ...]:
    """What moves between two problems of one structure, as one tuple of floats: every
    problem station's ``_targets``, the dead load on the whole part and those on
    stretches. The solver measures the distance between two problems by them
    (``math.dist``, faster on floats than on arrays)."""
    return (*flat, fx, fy, *dist.ravel().tolist())


def distributed_load(problem: Problem) -> tuple[float, float]:
    """The dead load per unit length on the whole part (its weight and the dead loads
    that cover it), dimensionless (by EI / L^3); ``segment_loads`` has the others."""
    scale = problem.part.length**3 / problem.part.bending_stiffness
    fx, fy = problem.dead_load_per_length
    return scale * fx, scale * fy


def _load_spans(problem: Problem) -> list[float]:
    """Where the loads on stretches start and end (dimensionless): kernel stations."""
    L = problem.part.length
    return sorted({min(max(x / L, 0.0), 1.0) for ld in problem.partial_loads
                   for x in ld.span(L)})


def segment_loads(problem: Problem, st_s: np.ndarray) -> np.ndarray:
    """(nst, 4): on each segment [st_s[k], st_s[k + 1]] (the stations cut at each
    load's ends) the dead (fx, fy) and follower (ft, fn) loads per unit length that
    ``distributed_load`` leaves out, dimensionless (by EI / L^3)."""
    dist = np.zeros((st_s.shape[0], 4))
    if not problem.distributed:
        return dist
    part = problem.part
    L = part.length
    scale = L**3 / part.bending_stiffness
    mids = 0.5 * (st_s[:-1] + st_s[1:]) * L
    for ld in problem.partial_loads:
        a, b = ld.span(L)
        on = (mids > a) & (mids < b)
        cols = slice(2, 4) if ld.follower else slice(0, 2)
        dist[:-1][on, cols] += np.asarray(ld.force) * scale
    return dist


SOFT = 1e-3  # the axial compliance EI / (EA L^2) an extensible part's homotopy starts at


def axial_compliance(part) -> float:
    """EI / (EA L^2): the axial strain per unit dimensionless force; 0 when the part is
    inextensible (no axial stiffness given)."""
    if part.axial_stiffness is None:
        return 0.0
    return part.bending_stiffness / (part.axial_stiffness * part.length**2)


def load_wavenumber(problem: Problem) -> float:
    """A priori wavenumber (dimensionless) of the applied loads: sqrt of the total force
    plus the total moment and the largest rest curvature."""
    part = problem.part
    length, stiffness = part.length, part.bending_stiffness
    force = math.hypot(*problem.dead_load_per_length) * length
    for ld in problem.partial_loads:
        a, b = ld.span(length)
        force += math.hypot(*ld.force) * (b - a)
    moment = 0.0
    for st in problem.stations:
        force += math.hypot(st.dead_load[0], st.dead_load[1])
        force += math.hypot(*st.follower_load)
        moment += abs(st.dead_load[2])
    curvature = max(abs(k) for _, k in part.rest_knots)
    return (math.sqrt(force * length**2 / stiffness) + moment * length / stiffness
            + curvature * length)


MAX_WAVENUMBER = 1000.0  # k L: bending confined to layers of 1e-3 L; beyond, refused


def check_wavenumber(problem: Problem) -> float:
    """The loads' wavenumber (``load_wavenumber``), or an ``InputError`` naming what makes
    it so large: past ``MAX_WAVENUMBER`` the part bends only in layers thinner than a
    thousandth of its length (a string, not a beam), which the shooting would resolve
    with more intervals than it can afford, and which is more often a unit slip (N for
    kN, EI in N mm^2) than a real part."""
    wave = load_wavenumber(problem)
    if math.isfinite(wave) and wave <= MAX_WAVENUMBER:
        return wave
    length, stiffness = problem.part.length, problem.part.bending_stiffness

    def at(st: Station, name: str) -> list:
        force = math.hypot(st.dead_load[0], st.dead_load[1]) + math.hypot(*st.follower_load)
        return force_terms(force, abs(st.dead_load[2]), name, length, stiffness)

    refuse(problem, scale_terms(problem, at), wave, MAX_WAVENUMBER)


def lower(problem: Problem, nodes: int | None = None) -> Lowered:
    """Lower a 2D problem into kernel arrays (dimensionless).

    nodes : the number of shooting intervals (restart nodes + 1); by default enough for
        the applied loads' wavenumber (NODE_SPAN per interval).

    Written for speed as well as clarity (a cold solve's budget is some hundred
    microseconds): rows are built as Python lists and made arrays once each.
    """
    part = problem.part
    length, stiffness = part.length, part.bending_stiffness
    force_scale = stiffness / length**2
    moment_scale = stiffness / length
    wave = check_wavenumber(problem)
    if nodes is None:
        nodes = max(1, math.ceil(wave / NODE_SPAN))

    stations: list[tuple[float, Station | None, bool]] = [
        (st.s / length, st, False) for st in problem.stations]
    # Both ends, and every knot inside the part: a kink of kappa0 (two knots at 0.3 and
    # 0.7 m are two kinks, with constant curvature beyond them), a station so that the
    # kernel's linear interpolation between stations is the profile's; and where each
    # load on a stretch starts and ends (a segment is loaded whole or not at all).
    at = [s for s, _, _ in stations]
    extra = [0.0, 1.0] + [s / length for s, _ in part.rest_knots if 0.0 < s < length]
    if problem.partial_loads:
        extra += _load_spans(problem)
    for s in extra:
        if not any(abs(s - t) <= 1e-12 for t in at):
            stations.append((s, None, False))
            at.append(s)
    for i in range(1, nodes):
        s = i / nodes
        while any(abs(s - t) <= 1e-9 for t in at):
            s += 0.5 / (nodes * 64)  # never on a station: a node restarts, a station jumps
        stations.append((s, None, True))
        at.append(s)
    stations.sort(key=lambda item: item[0])
    nst = len(stations)
    # Filled row by row as Python lists (a NumPy item assignment costs as much as a
    # list's whole row), made arrays once.
    kind: list[list[int]] = []
    cols: list[list[int]] = []
    lows: list[int] = []
    highs: list[int] = []
    vals: list[tuple[float, ...]] = []
    fols: list[tuple[float, ...]] = []
    flat: list[float] = []
    node_rows: list[int] = []
    problem_rows: list[int] = []
    interval = last_cut = 0.0
    col = 3
    lo = 0
    for k, (s, st, is_node) in enumerate(stations):
        if is_node:
            kind.append([NODE] * 3)
            cols.append([col] * 3)
            vals.append((0.0, 0.0, 0.0))
            fols.append((0.0, 0.0))
            node_rows.append(k)
            interval = max(interval, s - last_cut)
            last_cut = s
            lo = col
            col += 6
        elif st is not None:
            targets = _targets(st, length, force_scale, moment_scale)
            vals.append(targets[:3])
            fols.append(targets[3:])
            flat += targets
            problem_rows.append(k)
            row_kind = [APPLIED] * 3
            row_cols = [0, 1, 2] if k == 0 else [-1] * 3
            for i, held in enumerate(st.prescribed):
                if held:
                    row_kind[i] = PRESCRIBED
                    if k > 0:
                        row_cols[i] = col
                        col += 1
            kind.append(row_kind)
            cols.append(row_cols)
        else:
            kind.append([APPLIED] * 3)
            cols.append([0, 1, 2] if k == 0 else [-1] * 3)
            vals.append((0.0, 0.0, 0.0))
            fols.append((0.0, 0.0))
        if k < nst - 1:
            lows.append(lo)
            highs.append(col)
    interval = max(interval, 1.0 - last_cut)
    st_s = np.array([s for s, _, _ in stations])
    st_s[0], st_s[-1] = 0.0, 1.0
    st_kind = np.array(kind, dtype=np.int64)
    fx, fy = distributed_load(problem)
    dist = segment_loads(problem, st_s)
    if part.straight_at_rest:
        st_kappa = np.zeros(nst)
    else:
        st_kappa = np.array([part.rest_curvature_at(s * length) * length for s in st_s])
    key = (length, stiffness, part.axial_stiffness, st_s.tobytes(), st_kind.tobytes(),
           st_kappa.tobytes())
    return Lowered(problem=problem, length=length, stiffness=stiffness, st_s=st_s,
                   st_kind=st_kind, st_col=np.array(cols, dtype=np.int64),
                   seg_lo=np.array(lows, dtype=np.int64),
                   seg_hi=np.array(highs, dtype=np.int64), st_kappa=st_kappa,
                   target=Arrays(np.array(vals), np.array(fols),
                                 np.array([fx, fy, 0.0, 0.0, 1.0, axial_compliance(part)]),
                                 dist),
                   station_of=tuple(st for _, st, _ in stations), nz=col, key=key,
                   inputs=_inputs(flat, fx, fy, dist),
                   nodes=np.array(node_rows, dtype=np.int64), interval=interval,
                   problem_rows=tuple(problem_rows), wave=wave)
