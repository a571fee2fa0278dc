"""Plots of an equilibrium: the shape with its loads, and the N, Q, M diagrams."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pliant.core.equilibrium import Equilibrium


def plot_equilibrium(eq, path: str | Path) -> Path:
    """Draw the deformed part (loads as arrows) and its internal forces against s to a
    PNG file (2D: N, Q, M; 3D: the shape coloured by bending moment, |M|, torque, N).

    The file is written atomically: a failure leaves any earlier file untouched.
    """
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    path = Path(path)
    fig = plt.figure(figsize=(11, 6.5), layout="constrained")
    if eq.problem.dimension == 3:
        _draw_3d(fig, eq)
    else:
        _draw_2d(fig, eq)
    _save(fig, path, plt)
    return path


def _draw_2d(fig, eq: Equilibrium) -> None:
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


def _draw_3d(fig, eq) -> None:
    from matplotlib import cm  # noqa: PLC0415
    from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: PLC0415

    grid = fig.add_gridspec(3, 2, width_ratios=(1.3, 1))
    ax = fig.add_subplot(grid[:, 0], projection="3d")
    pos = eq.position
    tangent = eq.tangent
    bending = np.linalg.norm(eq.internal_moment - eq.torque[:, None] * tangent, axis=1)
    segments = np.stack([pos[:-1], pos[1:]], axis=1)
    norm = matplotlib_norm(bending)
    lines = Line3DCollection(segments, cmap=cm.viridis, norm=norm, linewidths=3.0)
    lines.set_array(0.5 * (bending[:-1] + bending[1:]))
    ax.add_collection3d(lines)
    fig.colorbar(lines, ax=ax, shrink=0.6, label="bending moment |M| [N m]")
    length = eq.problem.part.length
    scale = max((float(np.linalg.norm(ld.force)) for ld in eq.loads.values()), default=0.0)
    for ld in eq.loads.values():
        i = int(np.argmin(np.abs(eq.s - ld.s)))
        colour = "tab:red" if ld.is_reaction else "tab:green"
        ax.scatter(*pos[i], color=colour, s=25)
        if scale > 0.0 and np.linalg.norm(ld.force) > 0.0:
            ax.quiver(*pos[i], *(ld.force / scale * 0.25 * length), color=colour)
        ax.text(*pos[i], f" {ld.name}", color=colour, fontsize=8)
    span = np.ptp(pos, axis=0).max() / 2 or length / 2
    centre = pos.mean(axis=0)
    ax.set_xlim(centre[0] - span, centre[0] + span)
    ax.set_ylim(centre[1] - span, centre[1] + span)
    ax.set_zlim(centre[2] - span, centre[2] + span)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    ax.set_title(f"{eq.problem.name or 'equilibrium'}: shape and loads on the part\n"
                 "(red: reactions a support or hand must give, green: applied)", fontsize=10)
    panels = ((eq.s, bending, "|M| bending [N m]"), (eq.s, eq.torque, "torque [N m]"),
              (eq.element_s, eq.axial_force, "N [N]"))
    for row, (s, values, label) in enumerate(panels):
        axp = fig.add_subplot(grid[row, 1])
        axp.plot(s, values, color="tab:purple")
        axp.axhline(0.0, color="grey", lw=0.6)
        axp.set_ylabel(label)
        axp.grid(alpha=0.3)
        if row == 2:
            axp.set_xlabel("s [m]")


def matplotlib_norm(values: np.ndarray):
    from matplotlib.colors import Normalize  # noqa: PLC0415

    top = float(values.max()) if values.size else 1.0
    return Normalize(vmin=0.0, vmax=top if top > 0.0 else 1.0)


def margins(fig, left: float = 0.8, bottom: float = 0.55, right: float = 0.15,
            top: float = 0.3, wspace: float = 0.0, hspace: float = 0.0) -> None:
    """Fixed margins [in] round the axes and between them (wspace, hspace: the gaps
    between columns and rows), instead of a layout engine: constrained layout measures
    every label's extent, about 0.15 s a figure, most of the time of a report's plots
    (a run's first report is part of its first run). They suit the reports' plots,
    whose labels are known: the tick labels' width is what they leave room for."""
    width, height = fig.get_size_inches()
    grid = fig.axes[0].get_gridspec() if fig.axes else None
    cols, rows = (grid.ncols, grid.nrows) if grid is not None else (1, 1)
    inner_w = width - left - right - (cols - 1) * wspace
    inner_h = height - bottom - top - (rows - 1) * hspace
    fig.subplots_adjust(left=left / width, right=1.0 - right / width,
                        bottom=bottom / height, top=1.0 - top / height,
                        wspace=wspace * cols / max(inner_w, 1e-9),
                        hspace=hspace * rows / max(inner_h, 1e-9))


def _save(fig, path: Path, plt) -> None:
    from pliant.io.atomic import atomic_write  # noqa: PLC0415

    try:
        atomic_write(path, lambda handle: fig.savefig(handle, format="png", dpi=110),
                     "the plot")
    finally:
        plt.close(fig)


def plot_path(run, path: str | Path, min_bend_radius: float | None = None) -> Path:
    """Draw a manipulation's record against its progress: the grip's force and moment,
    the smallest clearance (with the margin) and the smallest bend radius (with the
    part's minimum), to a PNG file, atomically."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    path = Path(path)
    steps = run.steps
    progress = np.array([r.progress for r in steps]) * 100.0
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    margins(fig, wspace=0.9, hspace=0.25)
    (force, moment), (clearance, bend) = axes
    force.plot(progress, [r.force_norm for r in steps], color="tab:blue")
    force.set_ylabel(f"|force| at {run.grip} [N]")
    for k in run.snaps:
        for ax in (force, moment):
            ax.axvline(progress[k], color="tab:red", ls=":", label="snap")
    moment.plot(progress, [r.moment_norm for r in steps], color="tab:purple")
    moment.set_ylabel(f"|moment| at {run.grip} [N m]")
    clearance.plot(progress, [r.clearance * 1e3 for r in steps], color="tab:green")
    clearance.axhline(run.margin * 1e3, color="tab:orange", ls="--", label="margin")
    clearance.axhline(0.0, color="tab:red", lw=0.8)
    touching = [p for p, r in zip(progress, steps) if r.contacts]
    if touching:
        clearance.plot(touching, [0.0] * len(touching), "x", color="tab:red",
                       label="touching")
    clearance.set_ylabel("smallest clearance [mm]")
    clearance.legend(loc="best")
    bend.plot(progress, [r.bend_radius * 1e3 for r in steps], color="tab:brown")
    if min_bend_radius is not None:
        bend.axhline(min_bend_radius * 1e3, color="tab:red", ls="--",
                     label="the part's limit (centreline)")
        bend.legend(loc="best")
    bend.set_ylabel("smallest bend radius [mm]")
    for ax in (clearance, bend):
        ax.set_xlabel("progress along the path [%]")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    _save(fig, path, plt)
    return path
