"""How a 3D equilibrium's station loads change when its clamps move: d(load)/d(pose) of
the clamped stations, from the converged Newton system itself.

At an equilibrium R(u; t) = 0 of the targets t, a change dt of a clamp's pose moves the
answer by du = -J^-1 (dR/dt) dt (J = dR/du, the band the Newton solve factorises). A
clamp's position rows are R = X - t (dR/dt = -1); its orientation rows are
Im(conj(q_t) q), whose change under a turn dw of the target (global, q_t -> (1, dw/2)
q_t) is -(r0 / 2) R_t^T dw at the answer (where conj(q_t) q = (r0, 0), r0 = +-1). The
loads at u + du (``results.station_loads``, which is not linear in u: the frames turn)
are taken at a small multiple of du: one factorisation serves every clamp's six
directions, where re-solving the rod for each would factorise it at every Newton
iteration of each. Used for the Jacobian of a harness's junctions (``pliant.assembly.
harness_solve``), checked there against re-solving.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from pliant.core.equilibrium import Equilibrium3D
from pliant.core.rotations import qmul, quat_matrix
from pliant.errors import ConvergenceError
from pliant.models.banded import band_factor_reduced, band_solve_factored
from pliant.models.rod3d import kernels
from pliant.models.rod3d.results import WarmState, station_loads
from pliant.models.rod3d.solver import RodSolver, Run

_EPS = 1e-6  # the multiple of du the loads are taken at (they are smooth in it)


def clamp_sensitivity(eq: Equilibrium3D, clamps: Sequence[str], names: Sequence[str],
                      length_unit: float) -> np.ndarray:
    """d(load)/d(pose) at an equilibrium: rows, for each station name in ``names``, its
    load's force (3) [N] and moment (3) [N m] on the part; columns, for each clamp in
    ``clamps`` (a name of a FULL condition), a move of its position by ``length_unit``
    metres along x, y, z and a turn of its pose about the global x, y, z (per radian).
    Raises ConvergenceError where the Newton system is singular."""
    warm = eq.state
    if not isinstance(warm, WarmState):
        raise ConvergenceError("no Newton state to differentiate (a 2D answer, or parts "
                               "solved together)", residual=float("nan"))
    rod, state = warm.rod, warm.state
    run = Run(rod, RodSolver(elements=rod.requested))
    run.gauge_quat = warm.gauge_quat
    _, ab, _ = run.residual(state, rod.target, want_jac=True)
    drop = np.zeros(rod.n, dtype=bool)
    if rod.iprobe.shape[0]:
        drop = kernels.identity_rows(ab, rod.kl, rod.ku, rod.iprobe, rod.slot)
    c, lo, up, new, piv, ok = band_factor_reduced(ab, rod.kl, rod.ku, drop)
    if not ok:
        raise ConvergenceError("the Newton system is singular at this equilibrium",
                               residual=float("nan"))
    base = station_loads(run, state)
    index = {st_name: k for k, st in enumerate(rod.stations) for st_name in
             (cond.name for cond in st.conditions)}
    rows = []
    for name in names:
        rows.append(np.concatenate([base[name].force, base[name].moment]))
    base_vec = np.concatenate(rows) if rows else np.zeros(0)
    out = np.zeros((6 * len(names), 6 * len(clamps)))
    for j, clamp in enumerate(clamps):
        s = index[clamp]
        if rod.st_kind[s] != kernels.FULL or int(rod.st_pos_mask[s].sum()) != 3:
            raise ConvergenceError(f"{clamp} is not a clamp (a full pose)",
                                   residual=float("nan"))
        row = int(rod.inu[s])
        tq = rod.target.st_quat[s]
        r = qmul(np.array([tq[0], -tq[1], -tq[2], -tq[3]]), state[1][rod.st_frame[s]])
        Rt = quat_matrix(tq)
        for k in range(6):
            rhs = np.zeros(rod.n)
            target = rod.target
            if k < 3:
                rhs[row + k] = length_unit / rod.length
                moved = target.st_pos.copy()
                moved[s, k] += _EPS * length_unit / rod.length
                target = replace(target, st_pos=moved)
            else:
                w = np.zeros(3)
                w[k - 3] = 1.0
                rhs[row + 3:row + 6] = 0.5 * r[0] * (Rt.T @ w)
                turned = target.st_quat.copy()
                turned[s] = qmul(np.array([1.0, *(0.5 * _EPS * w)]), tq)
                turned[s] /= np.linalg.norm(turned[s])
                target = replace(target, st_quat=turned)
            du = band_solve_factored(ab, rod.kl, rod.ku, drop, c, lo, up, new, piv, rhs)
            after = run.step(state, du, _EPS)
            probe = Run(replace(rod, target=target), run.solver)
            probe.gauge_quat = run.gauge_quat
            loads = station_loads(probe, after)
            vec = np.concatenate([np.concatenate([loads[n].force, loads[n].moment])
                                  for n in names])
            out[:, 6 * j + k] = (vec - base_vec) / _EPS
    return out
