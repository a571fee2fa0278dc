"""Lower a 3D ``Problem`` into the discrete rod of ``kernels`` (dimensionless).

Scales: lengths by L, stiffnesses by EI1, forces by EI1/L^2, moments by EI1/L. The mesh
puts every station, and every knot of the rest-curvature profiles, on a node, and gives
each station a frame of its own. Unknowns are numbered along s so the KKT Jacobian is
banded: for each node its position, then its station's multipliers and frame, then the
element that starts there (frame and multiplier).
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from pliant.core.problem import Problem, Station3D
from pliant.core.rotations import cross as _cross
from pliant.core.rotations import frame_matrix, quat_from_matrix, quat_matrix, rotation_between
from pliant.models.rod3d import kernels
from pliant.models.rod3d.kernels import AXIS, FREE, FULL
from pliant.models.scale import force_terms, refuse, scale_terms

if TYPE_CHECKING:
    from pliant.scene.distance import DistanceField


def axis_basis(tangent) -> np.ndarray:
    """Two unit vectors completing a unit vector to a right-handed orthonormal basis:
    (2, 3) for one (3,), (K, 2, 3) for K of them (K, 3)."""
    t = np.asarray(tangent, float)
    helper = np.where(np.abs(t[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    b1 = _cross(t, helper)
    b1 /= np.linalg.norm(b1, axis=-1, keepdims=True)
    return np.stack([b1, _cross(t, b1)], axis=-2)


@dataclass(frozen=True, eq=False)
class Loads:
    """The load- and target-dependent kernel inputs at one point of a homotopy."""

    fnode: np.ndarray  # (N+1, 3) applied dead nodal forces
    st_pos: np.ndarray  # (S, 3) prescribed positions
    st_tangent: np.ndarray  # (S, 3) prescribed tangents (AXIS, FULL)
    st_quat: np.ndarray  # (S, 4) prescribed orientations (FULL)
    st_moment: np.ndarray  # (S, 3) dead moments (global)
    st_ffollow: np.ndarray  # (S, 3) follower forces (material)
    st_mfollow: np.ndarray  # (S, 3) follower moments (material)
    joint_k0: np.ndarray  # (J, 3) rest Darboux vectors (with any bow)
    turn: np.ndarray | None = None  # (S, 3) where to swing a tangent that must reverse
    offset: float = 0.0  # added to every contact gap: obstacles grown back from nothing
    elem_follow: np.ndarray | None = None  # (N, 3) follower load per length (material); None: 0

    def lerp(self, other: Loads, t: float) -> Loads:
        """Linear in everything but the orientations, which turn along the shortest arc
        (a tangent that must reverse turns toward ``turn``)."""
        hint = self.turn if self.turn is not None else other.turn
        tangent = slerp_vectors(self.st_tangent, other.st_tangent, t, hint)
        quat = _slerp_quats(self.st_quat, other.st_quat, t)
        return Loads(self.fnode + t * (other.fnode - self.fnode),
                     self.st_pos + t * (other.st_pos - self.st_pos), tangent, quat,
                     self.st_moment + t * (other.st_moment - self.st_moment),
                     self.st_ffollow + t * (other.st_ffollow - self.st_ffollow),
                     self.st_mfollow + t * (other.st_mfollow - self.st_mfollow),
                     self.joint_k0 + t * (other.joint_k0 - self.joint_k0), hint,
                     self.offset + t * (other.offset - self.offset),
                     _lerp_optional(self.elem_follow, other.elem_follow, t))


def _lerp_optional(a: np.ndarray | None, b: np.ndarray | None, t: float) -> np.ndarray | None:
    """(1 - t) a + t b, where None stands for zeros."""
    if a is None and b is None:
        return None
    if a is None:
        return t * np.asarray(b)
    if b is None:
        return (1.0 - t) * a
    return a + t * (b - a)


def slerp_vectors(a: np.ndarray, b: np.ndarray, t: float,
                   hint: np.ndarray | None = None) -> np.ndarray:
    """Rows of a turned toward the rows of b by the fraction t of their angle. Opposite
    rows have no shortest arc: they turn about the axis that swings a toward the hint's
    row (the way the station moves), or else toward the coordinate axis least along a."""
    out = np.empty_like(a)
    for k in range(a.shape[0]):
        cos = float(np.clip(np.dot(a[k], b[k]), -1.0, 1.0))
        angle = math.acos(cos)
        if angle < 1e-9:
            out[k] = b[k]
            continue
        if math.pi - angle < 1e-6:
            toward = hint[k] if hint is not None else np.zeros(a.shape[1])
            toward = toward - np.dot(toward, a[k]) * a[k]
            if np.linalg.norm(toward) < 1e-9:
                toward = np.eye(a.shape[1])[int(np.argmin(np.abs(a[k])))]
                toward = toward - np.dot(toward, a[k]) * a[k]
            toward = toward / np.linalg.norm(toward)
            turned = math.cos(t * math.pi) * a[k] + math.sin(t * math.pi) * toward
            out[k] = b[k] if t >= 1.0 else turned
            continue
        out[k] = (math.sin((1 - t) * angle) * a[k] + math.sin(t * angle) * b[k]) \
            / math.sin(angle)
    return out


def _slerp_quats(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    out = np.empty_like(a)
    for k in range(a.shape[0]):
        bk = b[k] if np.dot(a[k], b[k]) >= 0.0 else -b[k]
        out[k] = slerp_vectors(a[k:k + 1], bk[None, :], t)[0]
    return out


@dataclass(frozen=True, eq=False)
class Rod:
    """A 3D problem discretised: mesh, frames, joints, stations, unknown numbering."""

    problem: Problem
    length: float
    stiffness: float  # EI1 [N m^2], the stiffness scale
    s_node: np.ndarray  # (N+1,) dimensionless
    h: np.ndarray  # (N,)
    frame_s: np.ndarray  # (F,) where each frame sits
    elem_frame: np.ndarray  # (N,) the frame of each element
    joint_hh: np.ndarray  # (J,) cell length of each joint (J = F - 1)
    K: np.ndarray  # (4,) EI1, EI2, GJ by EI1, and the axial compliance EI1 / (EA L^2)
    stations: tuple[Station3D, ...]
    st_node: np.ndarray
    st_frame: np.ndarray
    st_pos_mask: np.ndarray  # (S, 3) int
    st_kind: np.ndarray  # (S,) FREE, AXIS or FULL
    gauge_frame: int
    ix: np.ndarray
    ith: np.ndarray
    ilam: np.ndarray
    inu: np.ndarray
    nu_off: np.ndarray
    nu_cnt: np.ndarray
    igauge: int
    n: int
    kl: int
    ku: int
    m: int  # number of station multipliers (with the gauge)
    target: Loads
    key: tuple = ()
    rest_k0: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    node_frame: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    requested: int = 0  # the element count asked of lower()
    # Contact: probes at every node and evenly inside each element, p = (1 - a) x_e + a x_e+1,
    # each with a multiplier (its contact force) numbered beside its node.
    probe_elem: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    probe_a: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # Each element's slider and each node's probe (probe indices, see
    # contact_kernels._slide; -1 where a station holds the node whole: it takes that point).
    slider: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    node_probe: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    iprobe: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    # Unknowns per probe: its normal force, and with friction two tangential ones after it.
    slot: int = 1
    obstacles: DistanceField | None = None
    radius: float = 0.0  # the part's outer radius [m]

    def retarget(self, problem: Problem, elements: int) -> Rod | None:
        """The same discretisation for another problem with the same part and stations
        (only targets and loads moved: a hand's next pose), or None."""
        if elements != self.requested or problem.dimension != 3:
            return None
        if problem.part is not self.problem.part and problem.part != self.problem.part:
            return None
        if problem.obstacles != self.problem.obstacles:
            return None
        old = self.stations
        if len(problem.stations) != len(old) or any(
                a.s != b.s or a.prescribed != b.prescribed for a, b in zip(problem.stations, old)):
            return None
        targets = _targets(problem, self.st_node, self.h)
        # A quaternion and its negative are one rotation: keep the old hemisphere so the
        # constraint's multipliers keep their signs.
        quat = targets[3]
        for k in range(quat.shape[0]):
            if np.dot(quat[k], self.target.st_quat[k]) < 0.0:
                quat[k] = -quat[k]
        if [(ld.span(self.length), ld.follower) for ld in problem.distributed] != [
                (ld.span(self.length), ld.follower) for ld in self.problem.distributed]:
            return None  # the mesh is cut where each load starts and ends
        return replace(self, problem=problem, stations=problem.stations,
                       target=_loads(targets, self.target.joint_k0))

    @property
    def islot(self) -> np.ndarray:
        """Every probe's unknowns in order: normal (and tangential) forces, probe by
        probe; the state's last array holds their values."""
        return (self.iprobe[:, None] + np.arange(self.slot)).ravel()

    @property
    def distance_field(self) -> DistanceField:
        """The obstacles' distance field: a rod with contact probes has one."""
        if self.obstacles is None:
            raise ValueError("this rod has no obstacles (no contact probes)")
        return self.obstacles

    def probe_points(self, X: np.ndarray, where: np.ndarray | None = None) -> np.ndarray:
        """The probes' points (K, 3) on the nodes X, in X's units, at their anchors or at
        the places ``where`` (K,) they slid to."""
        a = (self.probe_a if where is None else where)[:, None]
        return (1.0 - a) * X[self.probe_elem] + a * X[self.probe_elem + 1]

    @property
    def friction(self) -> bool:
        return self.slot == 3

    @property
    def force_scale(self) -> float:
        return self.stiffness / self.length**2

    @property
    def moment_scale(self) -> float:
        return self.stiffness / self.length

    @property
    def elements(self) -> int:
        return int(self.h.shape[0])

    @cached_property
    def mesh(self) -> kernels.Mesh:
        """The kernels' fixed arrays of this discretisation."""
        return kernels.Mesh(self.h, self.elem_frame, self.joint_hh, self.K, self.st_node,
                            self.st_frame, self.st_pos_mask, self.st_kind)

    @cached_property
    def numbering(self) -> kernels.Numbering:
        """Where the kernels find each unknown."""
        return kernels.Numbering(self.ix, self.ith, self.ilam, self.inu, self.nu_off,
                                 self.nu_cnt, self.gauge_frame, self.igauge, self.n,
                                 self.kl, self.ku)

    @cached_property
    def station_unknowns(self) -> np.ndarray:
        """The unknown of every station multiplier, in nu's order (the gauge's after)."""
        entry = np.arange(int(self.nu_cnt.sum()))
        return np.repeat(self.inu - self.nu_off, self.nu_cnt) + entry

    def targets(self, loads: Loads, gauge: np.ndarray) -> kernels.Targets:
        """The kernels' load- and target-dependent arrays at ``loads``, the twist gauge
        holding the twist of the frame ``gauge`` (4,)."""
        axis_b = np.zeros((loads.st_tangent.shape[0], 2, 3))
        for k in range(axis_b.shape[0]):
            if self.st_kind[k] == AXIS:
                axis_b[k] = axis_basis(loads.st_tangent[k])
        follow = (np.zeros((self.elements, 3)) if loads.elem_follow is None
                  else loads.elem_follow)
        return kernels.Targets(loads.joint_k0, loads.fnode, loads.st_pos, axis_b,
                               loads.st_quat, loads.st_moment, loads.st_ffollow,
                               loads.st_mfollow, follow, gauge)

    # -- the rest state -------------------------------------------------------------------
    def rest_shape(self, joint_k0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Nodes (N+1, 3) and frames (F, 4) of the unloaded part, from the origin with
        the identity frame (d3 = +z); exactly at rest in the discrete energy."""
        return kernels.rest_shape(self.h, self.elem_frame, self.joint_hh, joint_k0)

    def placement(self, X: np.ndarray, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rigid motion (G, T) that puts the rest shape where the conditions want it."""
        tgt = self.target
        G = None
        for k in range(self.st_kind.shape[0]):
            if self.st_kind[k] == FULL:
                G = quat_matrix(tgt.st_quat[k]) @ quat_matrix(Q[self.st_frame[k]]).T
                break
        if G is None:
            for k in range(self.st_kind.shape[0]):
                if self.st_kind[k] == AXIS:
                    have = quat_matrix(Q[self.st_frame[k]])[:, 2]
                    G = rotation_between(have, tgt.st_tangent[k])
                    break
        located = [k for k in range(self.st_kind.shape[0]) if self.st_pos_mask[k].all()]
        if G is None and len(located) >= 2:
            a, b = located[0], located[-1]
            have = X[self.st_node[b]] - X[self.st_node[a]]
            want = tgt.st_pos[b] - tgt.st_pos[a]
            if np.linalg.norm(have) > 1e-12 and np.linalg.norm(want) > 1e-12:
                G = rotation_between(have / np.linalg.norm(have), want / np.linalg.norm(want))
        if G is None:  # the 2D convention: d3 along +x, d1 along +z
            G = frame_matrix((1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        T = np.zeros(3)
        for c in range(3):
            for k in range(self.st_kind.shape[0]):
                if self.st_pos_mask[k, c]:
                    T[c] = tgt.st_pos[k, c] - (G @ X[self.st_node[k]])[c]
                    break
        return G, T

    def rest(self, joint_k0: np.ndarray | None = None) -> tuple[Loads, tuple]:
        """The homotopy's start: (loads, state) of the unloaded, placed part, where every
        prescribed component takes the value the rest shape gives it."""
        k0 = self.rest_k0 if joint_k0 is None else joint_k0
        X, Q = self.rest_shape(k0)
        G, T = self.placement(X, Q)
        qg = quat_from_matrix(G)
        X = X @ G.T + T
        Q = _qmul_rows(qg, Q)
        S = self.st_kind.shape[0]
        st_pos = np.zeros((S, 3))
        st_tangent = np.zeros((S, 3))
        st_quat = np.zeros((S, 4))
        for k in range(S):
            st_pos[k] = np.where(self.st_pos_mask[k] == 1, X[self.st_node[k]], 0.0)
            R = quat_matrix(Q[self.st_frame[k]])
            st_tangent[k] = R[:, 2]
            st_quat[k] = Q[self.st_frame[k]]
            if self.st_kind[k] == FULL and np.dot(st_quat[k], self.target.st_quat[k]) < 0:
                st_quat[k] = -st_quat[k]
        zeros = np.zeros((S, 3))
        turn = np.where(self.st_pos_mask == 1, self.target.st_pos - st_pos, 0.0)
        # Where the unloaded part passes through an obstacle, the homotopy starts with
        # every gap widened enough to clear it (the obstacles grow back along the way).
        offset = 0.0
        if self.obstacles is not None:
            d, _, _ = self.obstacles.query(self.probe_points(X) * self.length,
                                           band=2.0 * self.radius)
            deepest = float(np.min((d - self.radius) / self.length))
            if deepest < 0.0:
                offset = -deepest + 0.01
        loads = Loads(np.zeros_like(self.target.fnode), st_pos, st_tangent, st_quat, zeros,
                      zeros, zeros, k0, turn, offset)
        state = (X, Q, np.zeros((self.elements, 3)), np.zeros(self.m),
                 np.zeros(self.probe_elem.shape[0] * self.slot))
        return loads, state


def _qmul_rows(a: np.ndarray, B: np.ndarray) -> np.ndarray:
    """a * B[k] for every row k of B (F, 4)."""
    w, x, y, z = a
    return np.column_stack([w * B[:, 0] - x * B[:, 1] - y * B[:, 2] - z * B[:, 3],
                            w * B[:, 1] + x * B[:, 0] + y * B[:, 3] - z * B[:, 2],
                            w * B[:, 2] - x * B[:, 3] + y * B[:, 0] + z * B[:, 1],
                            w * B[:, 3] + x * B[:, 2] - y * B[:, 1] + z * B[:, 0]])


def _qmul(a, b):
    return np.array([a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
                     a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
                     a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
                     a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]])


def _profile(knots: tuple[tuple[float, float], ...], s: np.ndarray) -> np.ndarray:
    """A piecewise-linear rest-curvature profile at the arc lengths s [m]."""
    ks = np.array([k[0] for k in knots])
    kv = np.array([k[1] for k in knots])
    return np.interp(s, ks, kv)


_Targets = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                 np.ndarray, np.ndarray | None]


def _loads(targets: _Targets, joint_k0: np.ndarray) -> Loads:
    """The kernel's loads from ``_targets`` and the rest Darboux vectors."""
    fnode, st_pos, st_tangent, st_quat, st_moment, st_ffollow, st_mfollow, follow = targets
    return Loads(fnode, st_pos, st_tangent, st_quat, st_moment, st_ffollow, st_mfollow,
                 joint_k0=joint_k0, elem_follow=follow)


@functools.lru_cache(maxsize=256)
def _frame_quat(tangent: tuple, normal: tuple) -> tuple[float, ...]:
    """The quaternion of a station's frame (a clamp's pose is the same step after step)."""
    return tuple(quat_from_matrix(frame_matrix(tangent, normal)))


def _targets(problem: Problem, st_node: np.ndarray, h: np.ndarray) -> _Targets:
    """The load- and target-dependent arrays of a problem on a mesh (dimensionless):
    nodal dead forces, prescribed positions, tangents and orientations, moments and
    follower loads."""
    part = problem.part
    L, EI1 = part.length, part.bending_stiffness
    fs, ms = EI1 / L**2, EI1 / L
    stations = problem.stations
    S = len(stations)
    # (Built from lists in one call each: this runs at every warm step.)
    zero = (0.0, 0.0, 0.0)
    st_pos = np.array([[p if held else 0.0 for p, held in zip(st.position, st.prescribed)]
                       for st in stations], float).reshape(S, 3) / L
    st_tangent = np.array([st.tangent if st.tangent is not None else zero
                           for st in stations], float).reshape(S, 3)
    st_quat = np.zeros((S, 4))
    for k, st in enumerate(stations):
        if st.normal is not None:
            st_quat[k] = _frame_quat(tuple(st.tangent), tuple(st.normal))
    st_moment = np.array([st.dead_moment for st in stations], float).reshape(S, 3) / ms
    st_ffollow = np.array([st.follower_force for st in stations], float).reshape(S, 3) / fs
    st_mfollow = np.array([st.follower_moment for st in stations], float).reshape(S, 3) / ms
    applied = np.array([[0.0 if held else f for f, held in zip(st.dead_force, st.prescribed)]
                        for st in stations], float).reshape(S, 3) / fs
    fnode = np.zeros((h.shape[0] + 1, 3))
    for k in range(S):
        fnode[st_node[k]] += applied[k]
    # Distributed loads per element, by L^3 / EI1 (force per length by EI1 / L^3): the
    # weight and dead loads lumped half on each node, follower loads kept per element
    # (the kernel turns them with the element's frame). The mesh is cut where each
    # load starts and ends, so an element is covered whole or not at all.
    per_length = L**3 / EI1
    weight = part.mass_per_length * np.asarray(problem.gravity, float) * per_length
    follow = np.zeros((h.shape[0], 3))
    if problem.distributed:
        dead = np.tile(weight, (h.shape[0], 1))
        s_node = np.concatenate([[0.0], np.cumsum(h)]) * L
        for ld in problem.distributed:
            cover = np.array([ld.overlap(a, b, L) for a, b in itertools.pairwise(s_node)])
            share = cover / (h * L)
            (follow if ld.follower else dead)[:] += share[:, None] * np.asarray(ld.force) \
                * per_length
        half = 0.5 * h[:, None] * dead
    else:
        half = np.outer(0.5 * h, weight)
    fnode[:-1] += half
    fnode[1:] += half
    return fnode, st_pos, st_tangent, st_quat, st_moment, st_ffollow, st_mfollow, follow


MAX_SCALE = 1.0e6  # k L: loads that bend a part on a scale under a millionth of it


def check_scale(problem: Problem) -> None:
    """An ``InputError`` naming the field where a load (or the stiffness) is far past
    anything a part can be: it would bend the part on a scale under ``1 / MAX_SCALE`` of
    its length (``pliant.models.scale``). That is a unit slip or a typo (Fz = 1e38, EI =
    1e-300), which the solver would otherwise meet as "the start is singular"; tension
    the rod resolves (a taut cable) stays far below it."""
    length, stiffness = problem.part.length, problem.part.bending_stiffness

    def at(st: Station3D, name: str) -> list:
        force = math.hypot(*st.dead_force) + math.hypot(*st.follower_force)
        moment = math.hypot(*st.dead_moment) + math.hypot(*st.follower_moment)
        return force_terms(force, moment, name, length, stiffness)

    terms = scale_terms(problem, at)
    size = max(t[0] if math.isfinite(t[0]) else math.inf for t in terms)
    if size > MAX_SCALE:
        refuse(problem, terms, size, MAX_SCALE)


def lower(problem: Problem, elements: int = 100) -> Rod:
    """Discretise a 3D problem with about ``elements`` elements."""
    check_scale(problem)
    part = problem.part
    L = part.length
    EI1 = part.bending_stiffness
    # (EI1, EI2, GJ) / EI1 and the axial compliance EI1 / (EA L^2) (0: inextensible)
    EA = part.axial_stiffness
    K = np.array([*part.stiffnesses, 0.0 if EA is None else EI1 * EI1 / (EA * L**2)]) / EI1
    stations = problem.stations
    breaks = sorted({0.0, 1.0} | {st.s / L for st in stations}
                    | {k / L for k in part.knot_positions}
                    | {min(max(x / L, 0.0), 1.0) for ld in problem.distributed
                       for x in ld.span(L)})
    pieces = [np.linspace(a, b, max(2, round(elements * (b - a))) + 1)[1:]
              for a, b in itertools.pairwise(breaks)]
    s_node = np.concatenate([[0.0], *pieces])
    s_node[-1] = 1.0
    N = s_node.shape[0] - 1
    h = np.diff(s_node)
    st_node = np.array([int(np.argmin(np.abs(s_node - st.s / L))) for st in stations],
                       dtype=np.int64)
    S = len(stations)
    # Frames along s: one at each station node (and both ends), one in each element.
    has_frame = np.zeros(N + 1, dtype=bool)
    has_frame[[0, N]] = True
    has_frame[st_node] = True
    frames_before = np.cumsum(has_frame)  # station frames at nodes <= i
    node_frame = np.where(has_frame, frames_before - 1 + np.arange(N + 1), -1).astype(np.int64)
    elem_frame = (frames_before[:-1] + np.arange(N)).astype(np.int64)
    F = N + int(has_frame.sum())
    frame_s_arr = np.empty(F)
    frame_s_arr[elem_frame] = 0.5 * (s_node[1:] + s_node[:-1])
    frame_s_arr[node_frame[has_frame]] = s_node[has_frame]
    st_frame = node_frame[st_node]
    joint_hh = np.diff(frame_s_arr)
    mids = 0.5 * (frame_s_arr[:-1] + frame_s_arr[1:]) * L
    rest_k0 = np.column_stack([_profile(part.rest_knots, mids), _profile(part.rest_knots_2, mids),
                               _profile(part.twist_knots, mids)]) * L
    # Stations.
    st_pos_mask = np.array([st.prescribed[:3] for st in stations], dtype=np.int64).reshape(S, 3)
    st_kind = np.array([FULL if st.normal is not None else AXIS if st.tangent is not None
                        else FREE for st in stations], dtype=np.int64)
    targets = _targets(problem, st_node, h)
    # An isotropic part that nothing holds in twist has a free twist: a gauge fixes it.
    # Not when it has a rest curvature: that is set in the section's frame, so turning
    # the sections about the line changes the energy, which then holds the twist.
    # A flat section straight at rest has the same free roll at the start (the solver
    # then releases the gauge: the loads set the roll, see solver._release_roll).
    holds_twist = any(st.normal is not None for st in stations)
    curved = bool(np.abs(rest_k0[:, :2]).max(initial=0.0) > 1e-6)  # kappa0 L: not round-off
    gauge_frame = 0 if (not holds_twist and not curved) else -1
    # Unknowns along s: per node its position, its station's multipliers and frame (and
    # the gauge), then the element starting there: frame and multiplier.
    nu_cnt = (st_pos_mask.sum(axis=1) + 2 * (st_kind == AXIS) + 3 * (st_kind == FULL)).astype(
        np.int64)
    nu_off = np.concatenate([[0], np.cumsum(nu_cnt)[:-1]]).astype(np.int64)
    node_cnt = np.full(N + 1, 9, dtype=np.int64)  # x, element frame, element multiplier
    node_cnt[N] = 3
    node_cnt[has_frame] += 3
    node_cnt[st_node] += nu_cnt
    if gauge_frame >= 0:
        node_cnt[0] += 1
    # Contact probes, last in each node's block: the node (unless a station holds its
    # whole position: the hand or clamp takes that point), then points evenly inside its
    # element, enough that the tube cannot cut a sharp edge by more than 1% of its
    # radius between two (the chord's sag round the tube, s^2 / 8 r <= r / 100: a
    # spacing s <= 0.28 r), one at least, seven at most.
    contact = bool(problem.obstacles)
    held = np.zeros(N + 1, dtype=bool)
    held[st_node[st_pos_mask.all(axis=1)]] = True
    node_probe = contact & ~held
    slot = 3 if contact and any(o.friction > 0.0 for o in problem.obstacles) else 1
    radius = 0.5 * (part.outer_diameter or 0.0)
    longest = float(np.diff(s_node).max()) * L
    per = int(min(8, max(2, math.ceil(longest / (0.28 * radius))))) if radius > 0 else 2
    inner = np.zeros(N + 1, dtype=np.int64)
    inner[:N] = (per - 1) if contact else 0
    probes_at = node_probe.astype(np.int64) + inner
    node_cnt = node_cnt + probes_at * slot
    start = np.concatenate([[0], np.cumsum(node_cnt)[:-1]]).astype(np.int64)
    ix = start.copy()
    inu = (start[st_node] + 3).astype(np.int64)
    ith = np.empty(F, dtype=np.int64)
    after = start + 3 + np.where(np.isin(np.arange(N + 1), st_node),
                                 np.bincount(st_node, weights=nu_cnt, minlength=N + 1),
                                 0).astype(np.int64)
    ith[node_frame[has_frame]] = after[has_frame]
    after = after + 3 * has_frame
    igauge = -1
    if gauge_frame >= 0:
        igauge = int(after[0])
        after[0] += 1
    ith[elem_frame] = after[:-1]
    ilam = (after[:-1] + 3).astype(np.int64)
    n = int(node_cnt.sum())
    m = int(nu_cnt.sum()) + (1 if gauge_frame >= 0 else 0)
    # Band width: the widest coupling (element constraints, joints, stations, gauge).
    width = int(max((ilam + 2 - ix[:-1]).max(), (ix[1:] + 2 - ilam).max(),
                    (ilam + 2 - ith[elem_frame]).max(), (ith[1:] + 2 - ith[:-1]).max()))
    for k in range(S):
        ends = [inu[k] + max(nu_cnt[k], 1) - 1, ix[st_node[k]] + 2, ith[st_frame[k]] + 2]
        starts = [inu[k], ix[st_node[k]], ith[st_frame[k]]]
        width = max(width, max(ends) - min(starts))
    if igauge >= 0:
        width = max(width, abs(igauge - ith[gauge_frame]) + 2)
    probe_elem = np.zeros(0, dtype=np.int64)
    probe_a = np.zeros(0)
    slider = np.zeros(0, dtype=np.int64)
    probe_at_node = np.zeros(0, dtype=np.int64)
    iprobe = np.zeros(0, dtype=np.int64)
    obstacles = None
    if contact:
        from pliant.scene.distance import field_of  # noqa: PLC0415

        first = start + node_cnt - probes_at * slot
        nodes = np.nonzero(node_probe)[0]
        mids = np.repeat(np.arange(N), per - 1)
        j = np.tile(np.arange(1, per), N)
        probe_elem = np.concatenate([np.minimum(nodes, N - 1), mids])
        probe_a = np.concatenate([np.where(nodes < N, 0.0, 1.0), j / per])
        iprobe = np.concatenate([first[nodes],
                                 first[mids] + (node_probe[mids] + j - 1) * slot]).astype(np.int64)
        order = np.argsort(iprobe)
        probe_elem, probe_a, iprobe = probe_elem[order], probe_a[order], iprobe[order]
        # Each element's slider: its middle inner probe (see contact_kernels._slide).
        slider = np.nonzero(np.rint(probe_a * per) == per // 2)[0]
        slider = slider[np.argsort(probe_elem[slider])]
        probe_at_node = np.full(N + 1, -1, dtype=np.int64)
        at_node = (probe_a == 0.0) | (probe_a == 1.0)
        probe_at_node[probe_elem[at_node] + (probe_a[at_node] == 1.0)] = np.nonzero(at_node)[0]
        for k in range(iprobe.shape[0]):
            e = probe_elem[k]
            width = max(width, abs(iprobe[k] + slot - 1 - ix[e]), abs(ix[e + 1] + 2 - iprobe[k]))
        obstacles = field_of(problem.obstacles)
    target = _loads(targets, rest_k0.copy())
    key = (L, EI1, tuple(K), s_node.tobytes(), st_pos_mask.tobytes(), st_kind.tobytes(),
           rest_k0.tobytes(), iprobe.shape[0], slot)
    return Rod(problem=problem, length=L, stiffness=EI1, s_node=s_node, h=h,
               frame_s=frame_s_arr, elem_frame=elem_frame, joint_hh=joint_hh, K=K,
               stations=stations, st_node=st_node, st_frame=st_frame,
               st_pos_mask=st_pos_mask, st_kind=st_kind, gauge_frame=gauge_frame, ix=ix,
               ith=ith, ilam=ilam, inu=inu, nu_off=nu_off, nu_cnt=nu_cnt, igauge=igauge,
               n=n, kl=width, ku=width, m=m, target=target, key=key, rest_k0=rest_k0,
               node_frame=node_frame, requested=elements, probe_elem=probe_elem,
               probe_a=probe_a, slider=slider, node_probe=probe_at_node, iprobe=iprobe,
               slot=slot, obstacles=obstacles, radius=radius)


# The rod's unknowns: node positions, frame quaternions, element forces, station
# multipliers and contact (probe) forces, in the units of the lowering.
State = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


