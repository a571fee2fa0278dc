"""Plots of an equilibrium: the shape with its loads, and the N, Q, M diagrams."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from pliant.core.equilibrium import Equilibrium
from pliant.errors import OutputError


def plot_equilibrium(eq: Equilibrium, path: str | Path) -> Path:
    """Draw the deformed part (loads as arrows) and N, Q, M against s to a PNG file.

    The file is written atomically: a failure leaves any earlier file untouched.
    """
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    path = Path(path)
    fig = plt.figure(figsize=(11, 6.5), layout="constrained")
    grid = fig.add_gridspec(3, 2, width_ratios=(1.25, 1))
    shape = fig.add_subplot(grid[:, 0])
    length = eq.problem.part.length
    shape.plot(eq.position[:, 0], eq.position[:, 1], lw=2.5, color="tab:blue",
               label="deformed part")
    rest = np.linspace(0.0, length, 2)
    x0, y0 = eq.position[0]
    a0 = eq.angle[0]
    shape.plot(x0 + rest * np.cos(a0), y0 + rest * np.sin(a0), ls=":", color="grey",
               label="straight, from the first end")
    loads = list(eq.loads.values())
    scale = max((float(np.hypot(*ld.force)) for ld in loads), default=0.0)
    for ld in loads:
        i = int(np.argmin(np.abs(eq.s - ld.s)))
        px, py = eq.position[i]
        colour = "tab:red" if ld.is_reaction else "tab:green"
        shape.plot(px, py, "o", color=colour, ms=6)
        if scale > 0.0 and np.hypot(*ld.force) > 0.0:
            dx, dy = ld.force / scale * 0.25 * length
            shape.annotate("", xy=(px + dx, py + dy), xytext=(px, py),
                           arrowprops={"arrowstyle": "->", "color": colour, "lw": 1.8})
        shape.annotate(f"{ld.name}\nF = ({ld.force[0]:.3g}, {ld.force[1]:.3g}) N\n"
                       f"M = {ld.moment:.3g} N m", (px, py), textcoords="offset points",
                       xytext=(6, -28), fontsize=8, color=colour)
    shape.set_aspect("equal", adjustable="datalim")
    shape.set_xlabel("x [m]")
    shape.set_ylabel("y [m]")
    shape.set_title(f"{eq.problem.name or 'equilibrium'}: shape and loads on the part\n"
                    "(red: reactions a support or hand must give, green: applied)",
                    fontsize=10)
    shape.grid(alpha=0.3)
    shape.legend(loc="best", fontsize=8)
    for row, (values, label) in enumerate(((eq.axial_force, "N [N]"),
                                           (eq.shear_force, "Q [N]"),
                                           (eq.bending_moment, "M [N m]"))):
        ax = fig.add_subplot(grid[row, 1])
        ax.plot(eq.s, values, color="tab:purple")
        ax.axhline(0.0, color="grey", lw=0.6)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if row == 2:
            ax.set_xlabel("s [m]")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=".png", dir=path.parent, prefix=f".{path.stem}-")
    except OSError as err:
        plt.close(fig)
        raise OutputError(f"cannot write the plot {path}: {err.strerror or err}") from None
    try:
        with os.fdopen(fd, "wb") as handle:
            fig.savefig(handle, format="png", dpi=110)
        os.replace(tmp, path)
    except OSError as err:
        raise OutputError(f"cannot write the plot {path}: {err.strerror or err}") from None
    finally:
        Path(tmp).unlink(missing_ok=True)
        plt.close(fig)
    return path
