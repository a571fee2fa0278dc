"""The Runge-Kutta tableau the 2D shooting kernel integrates with.

We integrate on a fixed mesh (so that Newton sees one smooth discrete map and its exact
derivative) with the 12-stage, 8th-order explicit method of Dormand and Prince (DOP853,
the high-order solution without its error estimators). Its coefficients are published
constants that scipy already ships; we read them from scipy's coefficient file instead
of retyping 78 irrational numbers. The file is loaded on its own, so the (slow)
``scipy.integrate`` package is not imported just for this.
"""

from __future__ import annotations

import importlib.util
from functools import lru_cache
from pathlib import Path

import numpy as np

N_STAGES = 12
ORDER = 8


@lru_cache(maxsize=1)
def dop853() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(a, b, c)`` of the 8th-order DOP853 method: (12, 12), (12,), (12,) floats."""
    module = _load_coefficients()
    a = np.ascontiguousarray(module.A[:N_STAGES, :N_STAGES], dtype=np.float64)
    b = np.ascontiguousarray(module.B[:N_STAGES], dtype=np.float64)
    c = np.ascontiguousarray(module.C[:N_STAGES], dtype=np.float64)
    return a, b, c


def _load_coefficients():
    spec = importlib.util.find_spec("scipy")
    if spec is not None and spec.origin is not None:
        path = Path(spec.origin).parent / "integrate" / "_ivp" / "dop853_coefficients.py"
        if path.is_file():
            file_spec = importlib.util.spec_from_file_location("_pliant_dop853", path)
            if file_spec is not None and file_spec.loader is not None:
                module = importlib.util.module_from_spec(file_spec)
                file_spec.loader.exec_module(module)
                return module
    # Layout changed in some future scipy: fall back to the (slower) regular import.
    from scipy.integrate._ivp import dop853_coefficients  # noqa: PLC0415

    return dop853_coefficients
