"""Make the synthetic measurements of the example stiffness tests.

They are made by pliant's own accurate model with known parameters plus Gaussian noise
(fixed seeds), so that `pliant identify` on them shows what a fit looks like and recovers
the parameters within its intervals. They are not measured data. Run from anywhere:

    python examples/identify/synthetic.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import pliant as pl
from pliant.assembly.identify import _support_force

HERE = Path(__file__).resolve().parent
TRUE_EI, TRUE_MASS, TRUE_GJ = 0.021, 0.052, 0.0115  # N m^2, kg/m, N m^2


def write(name: str, header: str, rows: np.ndarray, comment: str) -> None:
    lines = [f"# {comment}", header]
    lines += [", ".join(f"{v:.6g}" for v in row) for row in rows]
    (HERE / name).write_text("\n".join(lines) + "\n", encoding="utf-8")


def cable_shape() -> None:
    """A 0.5 m cable clamped level, sagging under its weight and a 20 g tip weight."""
    part = pl.Part(0.5, TRUE_EI, mass_per_length=TRUE_MASS)
    eq = pl.solve(pl.Problem(part, (pl.clamp(0.0), pl.push(0.5, (0.0, -0.02 * 9.81))),
                             gravity=(0.0, -9.81)))
    rng = np.random.default_rng(11)
    s = np.sort(rng.uniform(0.02, 0.5, 40))
    xy = np.column_stack([np.interp(s, eq.s, eq.position[:, k]) for k in range(2)])
    xy += rng.normal(0.0, 0.5e-3, xy.shape)
    write("cable_shape.csv", "x [mm], y [mm]", xy * 1e3,
          "synthetic: pliant's model, EI = 0.021 N m^2, 0.052 kg/m, noise 0.5 mm")


def cable_tip_loads() -> None:
    """The same cable's tip position under weights of 0 to 100 g."""
    part = pl.Part(0.5, TRUE_EI, mass_per_length=TRUE_MASS)
    rng = np.random.default_rng(12)
    rows = []
    for grams in (0, 10, 20, 40, 60, 100):
        eq = pl.solve(pl.Problem(part, (pl.clamp(0.0), pl.push(0.5, (0.0, -grams * 9.81e-3))),
                                 gravity=(0.0, -9.81)))
        x, y = eq.position[-1] + rng.normal(0.0, 0.5e-3, 2)
        rows.append((grams * 9.81e-3, x * 1e3, y * 1e3))
    write("cable_tip_loads.csv", "load [N], x [mm], y [mm]", np.array(rows),
          "synthetic: pliant's model, EI = 0.021 N m^2, 0.052 kg/m, noise 0.5 mm")


def hose_bending() -> None:
    """A 0.3 m hose in three-point bending on supports 0.2 m apart."""
    rng = np.random.default_rng(13)
    d = np.linspace(2e-3, 40e-3, 12)
    load = np.array([TRUE_EI * 2.0 * _support_force(0.15, 0.1, float(x), "") for x in d])
    load *= 1.0 + rng.normal(0.0, 0.01, load.shape)
    write("hose_bending.csv", "displacement [mm], load [N]",
          np.column_stack([d * 1e3, load]),
          "synthetic: pliant's model, EI = 0.021 N m^2, 1 % load noise")


def hose_twist() -> None:
    """The same hose, 0.25 m between chucks, turned to 360 degrees."""
    rng = np.random.default_rng(14)
    angle = np.linspace(30.0, 360.0, 12)
    moment = TRUE_GJ * np.radians(angle) / 0.25 + rng.normal(0.0, 0.5e-3, angle.shape)
    write("hose_twist.csv", "angle [deg], moment [N m]", np.column_stack([angle, moment]),
          "synthetic: GJ = 0.0115 N m^2 over 0.25 m, noise 0.5 mN m")


if __name__ == "__main__":
    cable_shape()
    cable_tip_loads()
    hose_bending()
    hose_twist()
    print("written:", ", ".join(sorted(p.name for p in HERE.glob("*.csv"))))
    print(f"true values: EI {TRUE_EI} N m^2, mass {TRUE_MASS} kg/m, GJ {TRUE_GJ} N m^2")
