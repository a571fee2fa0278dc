"""The 3D rod's stability: the smallest eigenvalue of the Hessian of the Lagrangian on
the constraints' tangent space, in the metric of the part's length (so that it converges
as the mesh is refined), by shift-invert Lanczos on the band KKT matrix, with ARPACK and
a dense null space as fallbacks; and which loads make the test meaningful."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pliant.core.equilibrium import NEUTRAL
from pliant.models.banded import dense
from pliant.models.rod3d import kernels
from pliant.models.rod3d.lowering import Loads, Rod, State

if TYPE_CHECKING:
    from pliant.models.rod3d.solver import Run



def conservative(run: Run, state: State | None = None) -> bool:
    """Loads with a potential (no follower, no applied moment) and, at ``state``, no
    friction force: only then is stability the energy's minimum."""
    t = run.rod.target
    if state is not None and run.rod.friction and np.any(state[4].reshape(-1, 3)[:, 1:]):
        return False
    return not (np.any(t.st_moment) or np.any(t.st_ffollow) or np.any(t.st_mfollow)
                or (t.elem_follow is not None and np.any(t.elem_follow)))



def metric(rod: Rod) -> tuple[np.ndarray, np.ndarray]:
    """Which unknowns are primal (positions and frame rotations, not multipliers), and
    the length each stands for (lumped: half the elements at a node, a frame's element
    or joint span): the metric that makes the discrete Hessian's eigenvalues those of
    the continuous operator, and pseudo-time a physical relaxation."""
    n = rod.n
    ix = rod.ix[:, None] + np.arange(3)
    ith = rod.ith[:, None] + np.arange(3)
    primal = np.zeros(n, dtype=bool)
    weight = np.zeros(n)
    node_len = np.zeros(rod.elements + 1)
    node_len[:-1] += 0.5 * rod.h
    node_len[1:] += 0.5 * rod.h
    frame_len = np.zeros(rod.ith.shape[0])
    frame_len[rod.elem_frame] = rod.h
    end_len = np.concatenate([[rod.joint_hh[0]], rod.joint_hh[:-1] + rod.joint_hh[1:],
                              [rod.joint_hh[-1]]]) * 0.5
    frame_len = np.where(frame_len > 0.0, frame_len, end_len)
    primal[ix] = True
    weight[ix] = node_len[:, None]
    primal[ith] = True
    weight[ith] = frame_len[:, None]
    return primal, weight



def shift_bound(rod: Rod, state: State) -> float:
    """Twice a bound (in EI / L) on how negative the Hessian's geometric terms can make
    an eigenvalue: by Young's inequality, |n| + |m|^2 / 2 min(EI, GJ) in these units,
    n and m the largest internal force and moment; a shift below every eigenvalue."""
    _, moments = kernels.node_outputs(state[1], rod.elem_frame, rod.joint_hh,
                                      rod.target.joint_k0, rod.K, rod.node_frame)
    force = float(np.abs(state[2]).max(initial=0.0))
    moment = float(np.abs(moments).max(initial=0.0))
    return 2.0 * (1.0 + force + moment**2 / (2.0 * float(rod.K[:3].min())))


def stability_of(run: Run, state: State, seed: np.ndarray | None = None,
               found: list | None = None, loads: Loads | None = None) -> tuple[bool, float]:
    """(stable, smallest eigenvalue [N m]) of the Hessian of the Lagrangian on the
    constraints' tangent space (positions and frame rotations, weighed by the metric of
    ``metric``): positive definite means stable.

    Shift-invert Lanczos (``pliant.models.lanczos``, its steps compiled; ARPACK where it
    does not converge) at a shift -c below any negative eigenvalue, each step
    one solve with the band LU of the shifted KKT matrix (its solutions lie in the
    tangent space), so the eigenvalue nearest -c is the smallest: milliseconds where a
    dense null space takes a tenth of a second. The geometric terms that can make the
    Hessian indefinite are bounded by the internal force n and moment m (by Young's
    inequality, by |n| + |m|^2 / 2 min(EI, GJ) in these units); c is twice that bound.

    ``seed``: the softest mode of a nearby equilibrium on the same unknowns (the step
    before on a path), where Lanczos starts: along a path the mode changes little, so it
    needs fewer iterations. ``found`` (a list) receives this one's mode. ``loads``: those
    the state balances, when not the problem's (a state on the way).
    """
    from pliant.models.banded import band_factor_reduced  # noqa: PLC0415
    from pliant.models.lanczos import softest_mode  # noqa: PLC0415 (its own kernels)

    rod = run.rod
    c = shift_bound(rod, state)
    primal, weight = metric(rod)
    _, ab, _ = run.residual(state, rod.target if loads is None else loads, want_jac=True)
    kl, ku = rod.kl, rod.ku
    ab[:, kl + ku] += c * np.where(primal, weight, 0.0)
    # A free probe's row and column are the identity's and its part of every solve is 0:
    # they leave the factorisation (a narrower band, as in the Newton steps).
    drop = kernels.identity_rows(ab, kl, ku, rod.iprobe, rod.slot)
    reduced, lo, up, new, piv, ok = band_factor_reduced(ab, kl, ku, drop)
    if not ok:
        return stability_dense(run, state, loads)
    size = int(primal.sum())

    primal_index = new[np.flatnonzero(primal)]
    w = np.ascontiguousarray(weight[primal])
    # A fixed pseudo-random start (never orthogonal to the mode by a symmetry of the
    # problem), mixed with the nearby equilibrium's mode where there is one.
    start = np.random.default_rng(12345).standard_normal(size)
    start /= np.linalg.norm(start)
    if seed is not None and seed.shape == (size,):
        start = seed / np.linalg.norm(seed) + 0.3 * start
    theta, vector, converged, _ = softest_mode(reduced, piv, lo, up, primal_index, w, start,
                                               1e-10, 80)
    if converged and theta > 0.0:
        value = -c + 1.0 / theta
    else:
        keep = new >= 0
        value, vector = _stability_arpack(reduced, piv, int(keep.sum()), lo, up,
                                          primal[keep], weight[keep], c, size)
        if value is None:
            return stability_dense(run, state, loads)
    if found is not None:
        found[:] = [vector]
    # Neutral (zero to the solver's accuracy: a free family) is not unstable. That
    # accuracy is relative to the shift: Lanczos finds 1 / (value + c) to 1e-10.
    return value > -NEUTRAL * max(1.0, c), value * rod.moment_scale  # EI / L



def _stability_arpack(ab, piv, n, kl, ku, primal, weight, c, size):
    """The same eigenvalue by ARPACK (the fallback where the kernel's Lanczos did not
    converge): (value, vector), or (None, None)."""
    from pliant.models.lanczos import smallest_by_arpack  # noqa: PLC0415

    def solve(r: np.ndarray) -> np.ndarray:
        rhs = np.zeros(n)
        rhs[primal] = r.ravel()
        return kernels.band_lu_solve(ab, piv, kl, ku, rhs)[primal]

    return smallest_by_arpack(solve, weight[primal], -c)



def stability_dense(run: Run, state: State,
                     loads: Loads | None = None) -> tuple[bool, float]:
    """The same test with a dense null space and eigensolver (the fallback)."""
    from scipy.linalg import eigh, null_space  # noqa: PLC0415 (heavy; on demand)

    rod = run.rod
    _, ab, _ = run.residual(state, rod.target if loads is None else loads, want_jac=True)
    n, kl, ku = rod.n, rod.kl, rod.ku
    K = dense(ab, kl, ku, n)
    primal, weight = metric(rod)
    H = K[np.ix_(primal, primal)]
    A = K[np.ix_(~primal, primal)]
    Z = null_space(A)
    reduced = Z.T @ H @ Z
    mass = Z.T @ (weight[primal][:, None] * Z)
    smallest = float(eigh(0.5 * (reduced + reduced.T), 0.5 * (mass + mass.T),
                          eigvals_only=True, subset_by_index=(0, 0))[0])
    scale = rod.moment_scale  # EI / L
    return smallest > -NEUTRAL * max(1.0, shift_bound(rod, state)), smallest * scale
