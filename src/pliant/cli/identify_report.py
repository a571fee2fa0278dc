"""What ``pliant identify`` prints and draws: the estimates with their intervals, each
measurement's fit, and a plot of measured against fitted (SI units)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table


def print_identification(result, console: Console | None = None) -> None:
    """The fitted values with their intervals, how well each measurement fits, notes."""
    console = console or Console()
    test = result.test
    table = Table(title=f"{test.name}: identified ({test.confidence:.0%} intervals)",
                  title_justify="left")
    # The value with its unit, whole at 80 columns (a value column beside a unit column
    # cut both: "0.021…", "N m…").
    for col in ("parameter", "value", "interval", "±", "start"):
        table.add_column(col, justify="left" if col in ("parameter", "value") else "right",
                         no_wrap=True)
    for e in result.estimates:
        half = 0.5 * (e.high - e.low) / e.value
        table.add_row(escape(e.name), escape(f"{e.value:.4g} {e.unit}"),
                      f"{e.low:.4g}–{e.high:.4g}", f"{half:.1%}", f"{e.first_guess:.3g}")
    console.print(table)
    fits = Table(title="fit", title_justify="left")
    for col in ("measurement", "kind", "points", "rms residual", "bend radius down to"):
        fits.add_column(col, justify="left" if col in ("measurement", "kind") else "right")
    for f in result.fitted:
        fits.add_row(f.name, f.kind, str(len(f.x)), _size(f.rms, f.unit), _radius(f.curvature))
    console.print(fits)
    if result.curvature > 0.0:
        console.print(f"tested over bending curvatures up to {result.curvature:.3g} 1/m "
                      f"(bend radius {_radius(result.curvature)}): the values hold in that "
                      "range; a part bent tighter in use may be stiffer or softer")
    if len(result.estimates) > 1:
        names = [e.name for e in result.estimates]
        pairs = [f"{names[i]} / {names[j]} {result.correlation[i, j]:+.2f}"
                 for i in range(len(names)) for j in range(i + 1, len(names))]
        console.print("correlation: " + "; ".join(pairs))
    if result.dof == 0:
        scale = "the intervals from the stated uncertainties alone"
    elif result.weighted:
        scale = f"the scatter is {result.scale:.2f} times the stated uncertainties"
    else:
        scale = "weighed alike (no uncertainties given)"
    console.print(f"{result.dof} degrees of freedom; {scale}; {result.solves} solves in "
                  f"{result.seconds:.2f} s")
    for note in result.notes:
        console.print(f"[yellow]note:[/yellow] {note}")


def _radius(curvature: float) -> str:
    """A curvature as the bend radius it means ('-' where none was measured)."""
    if not curvature > 0.0:
        return "-"
    return _size(1.0 / curvature, "m")


def _size(value: float, unit: str) -> str:
    if unit == "m":
        return f"{value * 1e3:.3g} mm"
    return f"{value:.3g} {unit}"


def plot_identification(result, path: str | Path) -> Path:
    """Measured against fitted, one panel per measurement, to a PNG file (atomically)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    from pliant.cli.plot import _save  # noqa: PLC0415

    n = len(result.fitted)
    fig, axes = plt.subplots(1, n, figsize=(5.5 * n, 4.5), layout="constrained",
                             squeeze=False)
    for ax, f in zip(axes[0], result.fitted):
        if f.kind == "shape":
            measured, curve = f.measured * 1e3, f.curve * 1e3
            # 3D: the view across the two coordinates that move most
            k = np.argsort(np.ptp(curve, axis=0))[::-1][:2]
            k.sort()
            ax.plot(curve[:, k[0]], curve[:, k[1]], color="tab:blue", lw=2, label="fitted")
            ax.plot(measured[:, k[0]], measured[:, k[1]], "o", ms=4, mfc="none",
                    color="tab:red", label="measured")
            ax.set_xlabel(f"{'xyz'[k[0]]} [mm]")
            ax.set_ylabel(f"{'xyz'[k[1]]} [mm]")
            ax.set_aspect("equal", adjustable="datalim")
        else:
            order = np.argsort(f.x)
            ax.plot(f.x[order], f.model[order], color="tab:blue", lw=2, label="fitted")
            ax.plot(f.x, f.measured, "o", ms=5, mfc="none", color="tab:red",
                    label="measured")
            ax.set_xlabel(f.x_label)
            ax.set_ylabel(f.y_label)
        ax.set_title(f"{f.name}: rms {_size(f.rms, f.unit)}", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    values = ", ".join(f"{e.name} = {e.value:.4g} {e.unit}" for e in result.estimates)
    fig.suptitle(f"{result.test.name}: {values}", fontsize=11)
    path = Path(path)
    _save(fig, path, plt)
    return path
