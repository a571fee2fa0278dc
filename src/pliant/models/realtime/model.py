"""The real-time model: a bar network whose nodes are the control polygon of the part's
B-spline neutral line (the paper's section 4, after Leon's dual approach).

- The network joins each control point to the next ``reach`` ones. For fixed force
  densities its equilibrium is linear in the free node positions (the force density
  method); the first family of bars also keeps its lengths (a length-keeping functional:
  its force densities adjust, a few Newton steps per frame), so the part neither
  stretches nor shrinks while it is dragged; the farther families resist the turning of
  the polygon (negative force densities push second and third neighbours apart: a
  bending stiffness).
- Grips constrain points of the curve (and its tangent, C'(u) = L t with u = s / L),
  coordinate by coordinate; their multipliers are the network's grip forces. These
  forces are **fictive**: the network knows no material, so they are reported in
  dimensionless fictive units, never in newtons.
- Retuning fits the network to an accurate equilibrium: the control points by least
  squares with the grips exact, the bar lengths from them, and fixed fictive nodal loads
  that make that shape the network's equilibrium at that pose. Nearby poses then follow
  from the network, until drift asks for the next accurate solve.
- The display is the tube swept along the curve with rotation-minimising frames, a
  triangle mesh with constant faces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from pliant.core.problem import Problem
from pliant.core.tube import rotation_minimizing_frames, tube_faces, tube_vertices
from pliant.errors import InputError
from pliant.models.realtime import kernels
from pliant.models.realtime.bspline import DEGREE, basis, greville


@dataclass(frozen=True)
class GripRow:
    """A linear condition on the curve: its point (kind "position") or its derivative
    (kind "tangent") at u = s / L, for the coordinates ``coords``."""

    name: str
    kind: str
    u: float
    coords: tuple[int, ...]


@dataclass(frozen=True)
class RealtimeFrame:
    """What the display needs, at once. Positions in metres; forces fictive.

    curve : (m, 3) points of the neutral line at s_curve (m,); vertices (V, 3) and faces
    (F, 3) of the tube; control_points : (n, 3); fictive_grip_forces : by grip name, the
    network's multipliers (fictive units: not newtons, not to be shown as real forces);
    length_error : the largest relative error of the control polygon's bar lengths
    (zero when the length-keeping converged); curve_length_error : the curve's length
    against the part's, relative; converged, iterations : of that Newton; contact_s,
    contact_points : where the curve touches an obstacle (the curve points held out of
    the scene's obstacles, see ``contact_samples``).
    """

    curve: np.ndarray
    s_curve: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    control_points: np.ndarray
    fictive_grip_forces: dict[str, np.ndarray]
    length_error: float
    curve_length_error: float
    converged: bool
    iterations: int
    contact_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    contact_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    FORCES_ARE_FICTIVE: bool = True


@dataclass
class RealtimeModel:
    """The real-time model of one problem's part and grips (see the module docstring).

    problem : whose part and prescribed conditions define the grips (their targets are
    taken from the problem passed to ``frame``); control_points : n; reach : how many
    neighbours each node is joined to; bending : the magnitude of the farther families'
    (negative) force densities relative to the first's; samples, sides : the display
    curve's points and the tube's vertices per ring (64 x 16: about 2,000 triangles);
    keep_lengths : hold the control polygon's bar lengths (else the plain, linear force
    density method with the force densities as they are); contact_samples : how many
    points of the curve are held out of the problem's obstacles (default one per control
    point: more would lock the spline against a curved obstacle; the tube may cut an
    obstacle between two by their chord's sag).
    """

    problem: Problem
    control_points: int = 50
    reach: int = 3
    bending: float = 0.1
    samples: int = 64
    sides: int = 16
    keep_lengths: bool = True
    contact_samples: int | None = None
    tolerance: float = 1e-10
    max_iterations: int = 8
    # derived in __post_init__
    rows: tuple[GripRow, ...] = field(init=False)
    dim: int = field(init=False)
    length: float = field(init=False)

    def __post_init__(self) -> None:
        n = self.control_points
        if n < DEGREE + 2:
            raise InputError("control_points", f"the real-time model needs at least "
                             f"{DEGREE + 2} control points, not {n}")
        if self.reach < 2:
            raise InputError("reach", "join each node to at least its next two (reach >= 2) "
                             "for a bending stiffness")
        self.dim = self.problem.dimension
        self.length = self.problem.part.length
        self.rows = _grip_rows(self.problem)
        self._build()

    # -- structure -------------------------------------------------------------------------
    def _build(self) -> None:
        n, d, K = self.control_points, self.dim, self.reach
        pairs = [(i, i + k) for k in range(1, K + 1) for i in range(n - k)]
        self.bar_i = np.array([a for a, _ in pairs], dtype=np.int64)
        self.bar_j = np.array([b for _, b in pairs], dtype=np.int64)
        family = self.bar_j - self.bar_i
        self.q = np.where(family == 1, 1.0, -self.bending / np.maximum(family - 1.0, 1.0) ** 2)
        # Basis rows of the grips: 4 consecutive nonzeros from g_start.
        width = DEGREE + 1
        g_start = np.zeros(len(self.rows), dtype=np.int64)
        g_val = np.zeros((len(self.rows), width))
        for r, row in enumerate(self.rows):
            full = basis(np.array([row.u]), n, derivative=1 if row.kind == "tangent" else 0)[0]
            nz = np.nonzero(full)[0]
            start = int(min(nz.min(), n - width)) if nz.size else 0
            g_start[r] = start
            g_val[r] = full[start:start + width]
        self.g_start, self.g_val = g_start, g_val
        con = [(r, c) for r, row in enumerate(self.rows) for c in row.coords]
        self.con_row = np.array([r for r, _ in con], dtype=np.int64)
        self.con_c = np.array([c for _, c in con], dtype=np.int64)
        tangent_rows = [r for r, row in enumerate(self.rows) if row.kind == "tangent"]
        alpha_of = {r: a for a, r in enumerate(tangent_rows)}
        self.con_alpha = np.array([alpha_of.get(r, -1) for r, _ in con], dtype=np.int64)
        # Numbering along the polygon: a node's coordinates, the multiplier of the bar
        # that starts there, then the grips anchored there (the middle of their support),
        # the speeds of the tangents held there and the contacts of the curve points.
        middle = np.minimum(g_start + width // 2, n - 1)
        self._contact_rows()
        c_middle = np.minimum(self.c_start + width // 2, n - 1)
        igam = np.zeros(self.c_start.shape[0], dtype=np.int64)
        ix = np.zeros(n, dtype=np.int64)
        imu = np.zeros(n - 1, dtype=np.int64)
        icon = np.zeros(len(con), dtype=np.int64)
        ialpha = np.zeros(len(tangent_rows), dtype=np.int64)
        k = 0
        for i in range(n):
            ix[i] = k
            k += d
            if i < n - 1:
                imu[i] = k
                k += 1
            for c in range(len(con)):
                if middle[self.con_row[c]] == i:
                    icon[c] = k
                    k += 1
            for a, r in enumerate(tangent_rows):
                if middle[r] == i:
                    ialpha[a] = k
                    k += 1
            for m in np.nonzero(c_middle == i)[0]:
                igam[m] = k
                k += 1
        self.ix, self.imu, self.icon, self.ialpha, self.n_unknowns = ix, imu, icon, ialpha, k
        band = 0
        for b in range(self.bar_i.shape[0]):
            lo, hi = ix[self.bar_i[b]], ix[self.bar_j[b]] + d - 1
            if b < n - 1:
                hi = max(hi, imu[b])
            band = max(band, hi - lo)
        for c in range(len(con)):
            r = self.con_row[c]
            nodes = ix[g_start[r]], ix[g_start[r] + width - 1] + d - 1
            band = max(band, abs(icon[c] - nodes[0]), abs(icon[c] - nodes[1]))
            if self.con_alpha[c] >= 0:
                band = max(band, abs(icon[c] - ialpha[self.con_alpha[c]]))
        for k in range(self.c_start.shape[0]):
            lo = ix[self.c_start[k]]
            hi = ix[self.c_start[k] + width - 1] + d - 1
            band = max(band, abs(igam[k] - lo), abs(igam[k] - hi))
        self.igam = igam
        self.kl = self.ku = int(band)
        # Display.
        self.u_curve = np.linspace(0.0, 1.0, self.samples)
        self.B = basis(self.u_curve, n)
        self.dB = basis(self.u_curve, n, derivative=1)
        self.faces = tube_faces(self.samples, self.sides, caps=True)
        # State: the straight part along +x until the first retune.
        self.X = np.zeros((n, d))
        self.X[:, 0] = greville(n)
        self.mu = np.zeros(n - 1)
        self.lam = np.zeros(len(con))
        self.alpha = np.ones(len(tangent_rows))
        self.gam = np.zeros(self.c_start.shape[0])
        self.l0sq = np.sum(np.diff(self.X, axis=0) ** 2, axis=1)
        self.p = np.zeros((n, d))
        self.retuned_at: Problem | None = None
        self._prepare_fits()

    def _contact_rows(self) -> None:
        """The curve points held out of the obstacles (none without obstacles): their
        parameters, basis rows (4 nonzeros from c_start) and the kernel's constants."""
        from pliant.scene.distance import field_of  # noqa: PLC0415

        obstacles = self.problem.obstacles
        self.field = field_of(obstacles).args
        n = self.control_points
        width = DEGREE + 1
        m = 0
        if obstacles:
            m = self.contact_samples if self.contact_samples is not None else n
        self.c_u = np.linspace(0.0, 1.0, m)
        self.c_start = np.zeros(m, dtype=np.int64)
        self.c_val = np.zeros((m, width))
        if m:
            rows = basis(self.c_u, n)
            for k in range(m):
                nz = np.nonzero(rows[k])[0]
                start = int(min(nz.min(), n - width))
                self.c_start[k] = start
                self.c_val[k] = rows[k, start:start + width]
        part = self.problem.part
        radius = part.outer_diameter / 2.0 if part.outer_diameter else 0.0
        self.contact = (self.length, radius / self.length,
                        2.0 * radius + 0.05 * self.length, 1.0)

    # -- targets ---------------------------------------------------------------------------
    def targets(self, problem: Problem) -> np.ndarray:
        """The grips' right-hand sides (dimensionless) for a problem with the same grips."""
        by_name = {c.name: c for c in problem.model_conditions}
        out = np.zeros(self.con_row.shape[0])
        for k in range(out.shape[0]):
            row = self.rows[self.con_row[k]]
            c = self.con_c[k]
            cond = by_name.get(row.name)
            if cond is None:
                raise InputError("grip", f"the problem has no condition {row.name!r}: the "
                                 "real-time model was built for other grips")
            if row.kind == "position":
                value = cond.position[c]
                if value is None:
                    raise InputError("grip", f"{row.name!r} no longer prescribes coordinate "
                                     f"{'xyz'[c]}: rebuild the real-time model")
                out[k] = value / self.length
            else:
                out[k] = _unit_tangent(cond, self.dim)[c]
        return out

    # -- retuning --------------------------------------------------------------------------
    def retune(self, eq) -> float:
        """Fit the network to an accurate equilibrium (2D or 3D); returns the largest
        distance between the fitted curve and the accurate shape, relative to L.

        The fits' matrices depend only on the grips, so they are factorised once; a
        retune is a spline through the accurate samples and a few products."""
        L = self.length
        s, X = _samples(eq)
        from scipy.interpolate import CubicSpline  # noqa: PLC0415 (retuning only)

        Y = CubicSpline(s / L, X / L, axis=0)(self._fit_u)
        rhs = self.targets(eq.problem)
        n = self.control_points
        P = np.zeros((n, self.dim))
        for c in range(self.dim):
            ks, solve_fit, _ = self._fits[c]
            P[:, c] = solve_fit(np.concatenate([self._fit_B.T @ Y[:, c], rhs[ks]]))[:n]
        self.X = P
        self.mu = np.zeros(n - 1)
        self.alpha = np.ones(self.alpha.shape[0])  # the fit holds C'(u) = t: unit speed
        self.l0sq = np.sum(np.diff(P, axis=0) ** 2, axis=1)
        # Fictive loads: minus the bar forces at P, less what the grips can take
        # (least squares), so that P is the network's equilibrium at this pose.
        v = self.q[:, None] * (P[self.bar_j] - P[self.bar_i])
        force = np.zeros_like(P)
        np.add.at(force, self.bar_i, v)
        np.add.at(force, self.bar_j, -v)
        lam = np.zeros(self.con_row.shape[0])
        grip_force = np.zeros_like(P)
        for c in range(self.dim):
            ks, _, (G, G_pinv) = self._fits[c]
            if ks.size:
                lam[ks] = G_pinv @ -force[:, c]
                grip_force[:, c] = G @ lam[ks]
        self.lam = lam
        self.p = -(force + grip_force)
        self.retuned_at = eq.problem
        return float(np.abs(self._fit_B @ P - Y).max())

    def _prepare_fits(self) -> None:
        """Per coordinate: the constrained least-squares fit of the control points to
        samples (its KKT matrix factorised) and the pseudo-inverse that spreads the bar
        forces onto the grips."""
        import scipy.linalg as sla  # noqa: PLC0415 (set-up only)

        n = self.control_points
        self._fit_u = np.linspace(0.0, 1.0, max(4 * n, 200))
        self._fit_B = basis(self._fit_u, n)
        normal = self._fit_B.T @ self._fit_B
        self._fits = []
        for c in range(self.dim):
            ks = np.nonzero(self.con_c == c)[0]
            G = np.zeros((n, ks.size))
            for j, k in enumerate(ks):
                r = self.con_row[k]
                G[self.g_start[r]:self.g_start[r] + self.g_val.shape[1], j] = self.g_val[r]
            m = ks.size
            kkt = np.block([[normal, G], [G.T, np.zeros((m, m))]])
            factors = sla.lu_factor(kkt)
            self._fits.append((ks, lambda b, f=factors: sla.lu_solve(f, b),
                               (G, np.linalg.pinv(G) if m else np.zeros((0, n)))))

    def bundles(self, rhs: np.ndarray) -> tuple[kernels.Network, kernels.Numbering,
                                                 kernels.Touch]:
        """The kernels' arguments with the grips' targets ``rhs``."""
        return (kernels.Network(self.bar_i, self.bar_j, self.q, self.l0sq, self.p,
                                self.g_start, self.g_val, self.con_row, self.con_c, rhs,
                                self.con_alpha),
                kernels.Numbering(self.ix, self.imu, self.icon, self.ialpha, self.igam,
                                  self.n_unknowns, self.kl, self.ku),
                kernels.Touch(self.c_start, self.c_val, self.contact, self.field))

    # -- a frame ---------------------------------------------------------------------------
    def frame(self, problem: Problem) -> RealtimeFrame:
        """Move the grips to the problem's targets and return the display frame."""
        X, mu, lam, alpha, gam, _residual, iterations, status = kernels.newton(
            self.X, self.mu, self.lam, self.alpha, self.gam, *self.bundles(self.targets(problem)),
            self.keep_lengths, kernels.Limits(float(self.tolerance), int(self.max_iterations)))
        converged = status == kernels.CONVERGED
        if np.isfinite(X).all():
            self.X, self.mu, self.lam, self.alpha, self.gam = X, mu, lam, alpha, gam
        lengths = np.sqrt(np.sum(np.diff(self.X, axis=0) ** 2, axis=1))
        length_error = float(np.abs(lengths / np.sqrt(self.l0sq) - 1.0).max())
        return self._display(converged, iterations, length_error)

    def _display(self, converged: bool, iterations: int, length_error: float) -> RealtimeFrame:
        L = self.length
        P = self.X * L
        points = self.B @ P
        tangents = self.dB @ P
        if self.dim == 2:
            points = np.column_stack([points, np.zeros(points.shape[0])])
            tangents = np.column_stack([tangents, np.zeros(tangents.shape[0])])
            P = np.column_stack([P, np.zeros(P.shape[0])])
        norms = np.linalg.norm(tangents, axis=1)
        tangents = tangents / np.where(norms > 0.0, norms, 1.0)[:, None]
        du = self.u_curve[1] - self.u_curve[0]
        curve_length = du * (norms.sum() - 0.5 * (norms[0] + norms[-1]))  # trapezoid
        curve_length_error = abs(curve_length / L - 1.0)
        frames = rotation_minimizing_frames(points, tangents=tangents)
        vertices = tube_vertices(points, self.radius, frames, self.sides, caps=True)
        forces: dict[str, np.ndarray] = {}
        for k in range(self.lam.shape[0]):
            row = self.rows[self.con_row[k]]
            if row.kind == "position":
                forces.setdefault(row.name, np.zeros(3))[self.con_c[k]] = self.lam[k]
        on = self.gam > 1e-12
        contact_s = self.c_u[on] * L
        contact_points = (basis(self.c_u[on], self.control_points) @ P[:, :self.dim]
                          if on.any() else np.zeros((0, 3)))
        return RealtimeFrame(curve=points, s_curve=self.u_curve * L, vertices=vertices,
                             faces=self.faces, control_points=P, fictive_grip_forces=forces,
                             length_error=length_error,
                             curve_length_error=float(curve_length_error),
                             converged=converged, iterations=iterations,
                             contact_s=contact_s, contact_points=contact_points)

    @property
    def radius(self) -> float:
        return self.problem.part.drawn_radius

    def curve_at(self, s: np.ndarray) -> np.ndarray:
        """The neutral line [m] at arc lengths s (as the network holds it)."""
        return basis(np.asarray(s, float) / self.length, self.control_points) @ self.X \
            * self.length


def _unit_tangent(cond, dim: int) -> np.ndarray:
    if dim == 2:
        return np.array([math.cos(cond.angle), math.sin(cond.angle)])
    t = np.asarray(cond.tangent, float)
    return t / np.linalg.norm(t)


def _grip_rows(problem: Problem) -> tuple[GripRow, ...]:
    """The linear conditions the grips put on the curve: each prescribed position (its
    prescribed coordinates) and each prescribed tangent (2D: angle; 3D: tangent; a 3D
    pose's normal only turns the section, which a round tube does not show)."""
    L = problem.part.length
    dim = problem.dimension
    rows: list[GripRow] = []
    for cond in problem.model_conditions:
        coords = tuple(c for c in range(dim) if cond.position[c] is not None)
        if coords:
            rows.append(GripRow(cond.name, "position", cond.s / L, coords))
        held = cond.angle is not None if dim == 2 else cond.tangent is not None
        if held:
            rows.append(GripRow(cond.name, "tangent", cond.s / L, tuple(range(dim))))
    return tuple(rows)


def _samples(eq) -> tuple[np.ndarray, np.ndarray]:
    """(s, positions) of an equilibrium, one sample per distinct s."""
    s = np.asarray(eq.s, float)
    X = np.asarray(eq.position, float)
    keep = np.concatenate([[True], np.diff(s) > 0.0])
    return s[keep], X[keep]
