"""An equilibrium followed from a given shape: the shape (a polyline, and the sections'
twist along it) made the rod's rest shape and free of loads is an equilibrium, with the
clamps where it puts its ends; the continuation then takes the rest shape to the part's
own and the loads from nothing to theirs, while the clamps go to their poses
(``Run.follow``). The branch it ends on is the one the shape leads to: a harness
segment from its designed route, a twisted rod from a published solution's shape."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pliant.core.equilibrium import Equilibrium3D
from pliant.core.problem import Problem
from pliant.core.rotations import exp_map, qconj, qmul, quat_from_matrix
from pliant.core.tube import rotation_minimizing_frames
from pliant.errors import ConvergenceError
from pliant.models.continuation import Stalled
from pliant.models.rod3d.kernels import FULL
from pliant.models.rod3d.lowering import lower
from pliant.models.rod3d.results import build
from pliant.models.rod3d.solver import RodSolver, Run


def from_shape(problem: Problem, points: np.ndarray, first_normal: np.ndarray,
               solver: RodSolver | None = None, *, twist: float = 0.0) -> Equilibrium3D:
    """The equilibrium of ``problem`` followed from the shape ``points`` ((n, 3) [m],
    taken along its own length as the part's s from 0 to L). ``first_normal``: the
    sections' d1 at s = 0; d1 is carried along by rotation-minimising transport and
    turned about the axis by ``twist`` [rad] in all, evenly along s (a twisted rod's
    frames). Raises ConvergenceError where the continuation cannot follow."""
    solver = solver or RodSolver()
    points = np.asarray(points, float)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    rod = lower(problem, elements=solver.elements)

    def shape(s: np.ndarray) -> np.ndarray:  # s in [0, 1] along the shape's length
        x = np.clip(s, 0.0, 1.0) * arc[-1]
        return np.column_stack([np.interp(x, arc, points[:, i]) for i in range(3)])

    s_node, h, n = rod.s_node, rod.h, rod.h.shape[0]
    chords = np.diff(shape(s_node), axis=0)
    d3_elem = chords / np.linalg.norm(chords, axis=1)[:, None]
    eps = 1e-4
    d3_frames = np.empty((rod.frame_s.shape[0], 3))
    d3_frames[rod.elem_frame] = d3_elem
    for i in np.nonzero(rod.node_frame >= 0)[0]:
        a, b = shape(np.array([s_node[i] - eps, s_node[i] + eps]))
        d3_frames[rod.node_frame[i]] = (b - a) / np.linalg.norm(b - a)
    # d1 carried along the frames by rotation-minimising transport from the start's,
    # then turned by the twist; quaternions kept in one hemisphere (the discrete
    # Darboux vector is 2/hh Im(conj(q_a) q_b)).
    frames = rotation_minimizing_frames(shape(rod.frame_s), first_normal, tangents=d3_frames)
    if twist:
        turns = twist * rod.frame_s / rod.frame_s[-1]
        frames = np.array([f @ exp_map(np.array([0.0, 0.0, psi]))
                           for f, psi in zip(frames, turns)])
    Q = np.empty((d3_frames.shape[0], 4))
    for k, frame in enumerate(frames):
        q = quat_from_matrix(frame)
        Q[k] = -q if k and q @ Q[k - 1] < 0.0 else q
    X = np.empty((n + 1, 3))
    X[0] = shape(np.array([0.0]))[0] / rod.length
    X[1:] = X[0] + np.cumsum(h[:, None] * d3_elem, axis=0)
    k0 = np.array([2.0 / hh * qmul(qconj(a), b)[1:] for a, b, hh in
                   zip(Q[:-1], Q[1:], rod.joint_hh)])
    target = rod.target
    st_pos = np.where(rod.st_pos_mask > 0, X[rod.st_node], 0.0)
    st_tangent = np.where((rod.st_kind > 0)[:, None], d3_frames[rod.st_frame],
                          target.st_tangent)
    st_quat = target.st_quat.copy()
    for k in range(st_quat.shape[0]):
        if rod.st_kind[k] == FULL:
            q = Q[rod.st_frame[k]]
            st_quat[k] = q if q @ target.st_quat[k] >= 0.0 else -q
    start = replace(target, fnode=np.zeros_like(target.fnode), st_pos=st_pos,
                    st_tangent=st_tangent, st_quat=st_quat, joint_k0=k0)
    run = Run(rod, solver)
    state = (X, Q, np.zeros((n, 3)), np.zeros(rod.m), np.zeros(rod.islot.shape[0]))
    try:
        state = run.follow(start, target, state)
    except Stalled as stall:
        raise ConvergenceError(f"from the given shape: {stall.reason}",
                               residual=stall.residual) from None
    return build(run, state, None)
