"""Clamped uniform B-splines of the real-time model: basis rows at given parameters.

The neutral line is C(u) = sum_k N_k(u) P_k with u = s / L in [0, 1], a clamped
(open uniform) knot vector so that the curve starts at P_0 and ends at P_{n-1}, and
degree 3. Basis rows are built once (scipy) and a frame is then matrix products.
"""

from __future__ import annotations

import numpy as np

DEGREE = 3


def knots(count: int, degree: int = DEGREE) -> np.ndarray:
    """The clamped uniform knot vector of ``count`` control points."""
    if count < degree + 1:
        raise ValueError(f"a degree-{degree} B-spline needs at least {degree + 1} control "
                         f"points, not {count}")
    inner = np.linspace(0.0, 1.0, count - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def basis(u: np.ndarray, count: int, derivative: int = 0,
          degree: int = DEGREE) -> np.ndarray:
    """(len(u), count) rows of the basis (or its derivative in u) at the parameters u."""
    from scipy.interpolate import BSpline  # noqa: PLC0415 (set-up only)

    t = knots(count, degree)
    spline = BSpline(t, np.eye(count), degree, extrapolate=False)
    if derivative:
        spline = spline.derivative(derivative)
    rows = spline(np.clip(np.asarray(u, float), 0.0, 1.0))
    return np.nan_to_num(rows, nan=0.0)


def greville(count: int, degree: int = DEGREE) -> np.ndarray:
    """The Greville abscissae: the parameter each control point stands for."""
    t = knots(count, degree)
    return np.array([t[i + 1:i + degree + 1].mean() for i in range(count)])
