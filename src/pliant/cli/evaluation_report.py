"""The A/D evaluation for people: a rich summary in the terminal, and one self-contained
HTML report (it opens offline: styles inline, plots as inline SVG, pictures as embedded
PNG) with the verdict, the red and yellow items with their rules and sources, plots
along the path, pictures of the start, worst and last poses with the obstacles and the
hand's force, and the table of every step.
"""

from __future__ import annotations

import base64
import html
import io
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from pliant.assembly.checks import Zone
from pliant.io.atomic import atomic_write
from pliant.io.evaluation_file import column_unit

COLOURS = {"green": "#1b7f3b", "yellow": "#b07d00", "red": "#c0262d", "unchecked": "#6b6b6b",
           "info": "#3d5a80"}
RICH = {"green": "green", "yellow": "yellow", "red": "bold red", "unchecked": "dim",
        "info": "cyan"}


# -- terminal -----------------------------------------------------------------------------
def print_evaluation(ev: Any, console: Console | None = None) -> None:
    """The verdict, the operators tried and the red, yellow and unchecked items."""
    console = console or Console()
    # The push that seats the part (its connector's own force included): the path's
    # peak above is the grip's alone.
    for c in ev.checks:
        if c.rule == "insertion":
            console.print(f"seating: {escape(c.sentence())}")
    v = ev.verdict
    style = "bold green" if v.passes else "bold red" if v.decided else "bold yellow"
    console.print(f"[{style}]{v.headline}[/{style}]")
    table = Table(title="operators tried", title_justify="left")
    for column in ("operator", "zone", "what it takes"):
        table.add_column(column)
    for op in ev.operators:
        table.add_row(op.operator, f"[{RICH[op.zone.value]}]{op.zone.value}[/]", op.summary)
    console.print(table)
    items = ev.items
    if items:
        table = Table(title="items to act on (worst first)", title_justify="left")
        for column in ("zone", "check", "source"):
            table.add_column(column)
        for c in items:
            table.add_row(f"[{RICH[c.zone.value]}]{c.zone.value}[/]", c.sentence(),
                          f"{c.source} ({c.provenance})")
        console.print(table)
    else:
        console.print("every check is green")


# -- plots --------------------------------------------------------------------------------
def _figure(plt, rows: int = 1, cols: int = 1, height: float = 3.0):
    from pliant.cli.plot import margins  # noqa: PLC0415 (matplotlib's side of the CLI)

    fig, axes = plt.subplots(rows, cols, figsize=(9.5, height), squeeze=False)
    margins(fig, wspace=0.9, hspace=0.5)
    return fig, axes


def inline_svg(fig, plt) -> str:
    """The figure as SVG markup to put in a page as it is (and the figure closed)."""
    buffer = io.StringIO()
    fig.savefig(buffer, format="svg")
    plt.close(fig)
    text = buffer.getvalue()
    return text[text.index("<svg"):]


def png_data_url(fig, plt, dpi: int = 90) -> str:
    """The figure as a PNG data URL for an <img> of a self-contained page (closed)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode()


def _limits(ax, check: Any, scale: float = 1.0) -> None:
    if check is None:
        return
    if check.yellow_at is not None and math.isfinite(check.yellow_at):
        ax.axhline(check.yellow_at * scale, color=COLOURS["yellow"], ls="--", lw=1,
                   label="yellow from")
    if check.red_at is not None and math.isfinite(check.red_at):
        ax.axhline(check.red_at * scale, color=COLOURS["red"], ls="--", lw=1,
                   label="red from")


def figures(ev: Any) -> list[tuple[str, str]]:
    """(title, inline SVG) of each plot along the path."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    table = ev.table
    steps = np.array([r["step"] for r in table])
    by_rule = {c.rule: c for c in ev.checks}
    op = ev.chosen
    grip_checks = {} if op is None else {(c.rule, c.grip): c for c in op.checks}
    out = []
    for g in ev.grips:
        fig, axes = _figure(plt, 1, 2)
        force, moment = axes[0]
        for part, colour in (("axial", "tab:blue"), ("lateral", "tab:orange")):
            force.plot(steps, [r[f"{g} {part}"] for r in table], color=colour,
                       label=("axial (+: a pull along the part; at the port, a push "
                              "onto it)" if part == "axial" else "lateral |.|"))
        _limits(force, grip_checks.get(("grip: palm push", g)))
        force.set_ylabel("force [N]")
        force.set_title(f"force at {g}", fontsize=10)
        for part, colour in (("twist", "tab:purple"), ("bending", "tab:brown")):
            moment.plot(steps, [abs(r[f"{g} {part}"]) for r in table], color=colour,
                        label=part)
        _limits(moment, grip_checks.get(("grip: wrist twist", g)))
        moment.set_ylabel("|moment| [N m]")
        moment.set_title(f"moment at {g}", fontsize=10)
        for ax in (force, moment):
            ax.set_xlabel("step")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
        out.append((f"Force and moment at {g}", inline_svg(fig, plt)))
    obstacles = [k.removeprefix("clearance ") for k in table[0] if k.startswith("clearance ")]
    if obstacles:
        fig, axes = _figure(plt)
        ax = axes[0][0]
        clipped = False
        for name in obstacles:
            values = np.array([r[f"clearance {name}"] for r in table], float) * 1e3
            shown = np.clip(values, -50, 300)
            clipped |= bool(np.any(shown != values))
            ax.plot(steps, shown, label=name)
        margin = ev.run.margin * 1e3
        if margin:
            ax.axhline(margin, color=COLOURS["yellow"], ls="--", lw=1, label="margin")
        ax.axhline(0.0, color=COLOURS["red"], lw=1)
        # Where a curve leaves the axis it is drawn at its edge, and the axis says so.
        ax.set_ylabel("clearance [mm]" + (" (clipped to -50...300)" if clipped else ""))
        ax.set_xlabel("step")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, ncol=3)
        out.append(("Clearance to each obstacle" + (
            " (drawn from -50 to 300 mm: values beyond lie on the edge)" if clipped else ""),
            inline_svg(fig, plt)))
    fig, axes = _figure(plt, 1, 2)
    bend, twist = axes[0]
    straight = any(r["bend radius"] > 10.0 for r in table)
    bend.plot(steps, [min(r["bend radius"], 10.0) * 1e3 for r in table], color="tab:brown",
              label="smallest bend radius" + (" (10 m and over drawn at 10 m)" if straight
                                              else ""))
    _limits(bend, by_rule.get("bend radius"), 1e3)
    bend.set_ylabel("radius [mm]")
    bend.set_title("bend radius (centreline)", fontsize=10)
    rates = [r["twist rate"] for r in table]
    twist.plot(steps, rates, color="tab:purple", label="largest twist rate")
    # A magnitude from 0 (a part free to twist reads a flat 0, not a band round it),
    # its line just clear of the axis.
    top = max(rates, default=0.0)
    top = 1.1 * top if top > 0.0 else 1.0
    twist.set_ylim(-0.03 * top, top)
    twist.set_ylabel("twist rate [deg/m]")
    twist.set_title("twist", fontsize=10)
    for k, r in enumerate(table):
        if r["snap"] or r["stable"] is False:
            for ax in (bend, twist):
                ax.axvline(steps[k], color=COLOURS["red"], ls=":", lw=1)
    for ax in (bend, twist):
        ax.set_xlabel("step")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    out.append(("Damage: bend radius and twist (red dotted: unstable or snapping)",
                inline_svg(fig, plt)))
    return out


def pictures(ev: Any, steps: list[tuple[str, int]]) -> list[tuple[str, str]]:
    """(caption, PNG data URL) of the part at the given steps, with the obstacles, the
    force each grip applies, each hand's envelope and the worker where one is given."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: PLC0415

    from pliant.assembly.evaluate import position_at  # noqa: PLC0415 (loaded: an evaluation is given)
    from pliant.io.mesh_export import obstacle_mesh  # noqa: PLC0415

    eq0 = ev.run.equilibria[0]
    meshes = []
    for obstacle in eq0.problem.obstacles:
        mesh = obstacle_mesh(obstacle, halfspace_size=1.0)
        if len(mesh.faces) > 4000:
            mesh = mesh.simplify_quadric_decimation(face_count=4000) if hasattr(
                mesh, "simplify_quadric_decimation") else mesh
        meshes.append((obstacle.name, mesh))
    shown = ev.bodies
    figure_points = [np.asarray(pts, float) for k in {k for _, k in steps}
                     for r in (shown.reach.values() if shown else ())
                     for pts in r[k].chain]
    every = np.concatenate([ev.run.equilibria[k].position for _, k in steps]
                           + [np.array(figure_points).reshape(-1, 3)])
    lo, hi = every.min(axis=0), every.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.6 * float((hi - lo).max()) + 0.05
    out = []
    for caption, k in steps:
        eq = ev.run.equilibria[k]
        fig = plt.figure(figsize=(4.6, 4.0))
        ax = fig.add_subplot(projection="3d")
        fig.subplots_adjust(left=0.02, right=0.92, bottom=0.1, top=0.92)
        for _, mesh in meshes:
            tri = mesh.vertices[mesh.faces]
            ax.add_collection3d(Poly3DCollection(tri, facecolor="#b9c0c8", edgecolor="none",
                                                 alpha=0.35))
        x = eq.position
        ax.plot(x[:, 0], x[:, 1], x[:, 2], color="#1f4e9c", lw=3)
        for g in ev.grips:
            load = eq.loads[g]
            p = position_at(eq, load.s)
            f = np.asarray(load.force, float)
            norm = float(np.linalg.norm(f))
            if norm > 0:
                arrow = f / norm * 0.25 * half
                ax.quiver(*p, *arrow, color=COLOURS["red"], lw=2)
                ax.text(*(p + arrow), f"{g}: {norm:.3g} N", fontsize=7,
                        color=COLOURS["red"])
        if shown is not None:
            _draw_body(ax, shown, k)
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel("x [m]", fontsize=7)
        ax.set_ylabel("y [m]", fontsize=7)
        ax.set_zlabel("z [m]", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.set_title(f"{caption}: step {k}", fontsize=9)
        out.append((f"{caption} (step {k})", png_data_url(fig, plt)))
    return out


def view(ev: Any) -> str:
    """The interactive 3D view (``cli.view3d``): the obstacles, and at each step the part,
    its grips, each hand's envelope and the worker, from the worst step."""
    from pliant.assembly.evaluate import position_at  # noqa: PLC0415 (loaded: an evaluation is given)
    from pliant.cli import view3d  # noqa: PLC0415

    eq0 = ev.run.equilibria[0]
    shown = ev.bodies
    steps, labels = [], []
    for k, eq in enumerate(ev.run.equilibria):
        items = [view3d.line(eq.position, "#1f4e9c", 4.0, name="part")]
        for g in ev.grips:
            load = eq.loads[g]
            items.append(view3d.point(position_at(eq, load.s), COLOURS["red"], g))
        if shown is not None:
            for g, at in shown.access.items():
                centre = np.asarray(at[k].centre)
                items.append(view3d.line([centre, centre + at[k].reach * np.asarray(
                    at[k].approach)], COLOURS[_hand_zone(shown, g, k)], 7.0, name=f"{g}: hand"))
            for r in shown.reach.values():
                items.append(view3d.line(np.array(r[k].chain), "#5b3a87", 2.5, name="worker"))
        steps.append(items)
        labels.append(f"step {k} of {len(ev.run.equilibria) - 1}")
    return view3d.html_view(meshes=view3d.obstacle_meshes(eq0.problem.obstacles),
                            steps=steps, labels=labels, start=ev.worst_step(),
                            caption="The part at each step (blue), its grips (red), the "
                            "hands' envelopes in their access zone's colour and the worker "
                            "(purple); the slider picks the step, from the worst.")


def _hand_zone(op: Any, grip: str, k: int) -> str:
    """The zone of the access check of the hand at ``grip`` at step k (green where it
    has none)."""
    check = next((c for c in op.checks if c.rule == "access: hand" and c.grip == grip), None)
    return ("red" if check is not None and k in check.red_steps else
            "yellow" if check is not None and k in check.yellow_steps else "green")


def _draw_body(ax, op: Any, k: int) -> None:
    """The hands' envelopes at step k (the ring round the part, the forearm out along
    the best approach, coloured by the access check's zone there) and the worker's
    stick figure (feet, hip, shoulder, elbow, grip)."""
    for g, steps in op.access.items():
        a = steps[k]
        zone = _hand_zone(op, g, k)
        c, d = np.asarray(a.centre), np.asarray(a.approach)
        end = c + a.reach * d
        ax.plot(*zip(c, end), color=COLOURS[zone], lw=7, alpha=0.45, solid_capstyle="round")
        ax.scatter(*c, s=90, color=COLOURS[zone], alpha=0.6)
    for steps in op.reach.values():
        r = steps[k]
        chain = np.array(r.chain)
        ax.plot(chain[:, 0], chain[:, 1], chain[:, 2], color="#5b3a87", lw=2.5)
        ax.scatter(*np.array(r.shoulder), s=18, color="#5b3a87")


# -- HTML ---------------------------------------------------------------------------------
STYLE = """
body{font:14px/1.45 system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1d232a;
background:#f4f6f8}
main{max-width:1100px;margin:0 auto;padding:24px}
h1{font-size:22px;margin:0 0 4px} h2{font-size:17px;margin:28px 0 8px;border-bottom:1px solid
#d5dbe1;padding-bottom:4px} .meta{color:#56606b;font-size:12.5px}
.verdict{border-radius:8px;padding:16px 20px;margin:16px 0;color:#fff;font-size:18px;
font-weight:600} .verdict.pass{background:#1b7f3b} .verdict.fail{background:#c0262d}
.verdict.undecided{background:#8a6d00}
.verdict small{display:block;font-weight:400;font-size:13px;opacity:.92;margin-top:6px}
table{border-collapse:collapse;width:100%;background:#fff;font-size:13px}
th,td{border-bottom:1px solid #e3e7eb;padding:5px 8px;text-align:left;vertical-align:top}
th{background:#eef1f4;font-weight:600} td.num{text-align:right;font-variant-numeric:tabular-nums}
.zone{display:inline-block;min-width:64px;text-align:center;border-radius:4px;color:#fff;
padding:1px 6px;font-size:12px;font-weight:600}
.green{background:#1b7f3b}.yellow{background:#b07d00}.red{background:#c0262d}
.unchecked{background:#6b6b6b}.info{background:#3d5a80}
.figs svg{width:100%;height:auto;background:#fff;border-radius:6px;margin:6px 0}
.poses{display:flex;gap:10px;flex-wrap:wrap} .poses figure{margin:0;background:#fff;
border-radius:6px;padding:6px} .poses img{width:320px} figcaption{font-size:12px;color:#56606b}
details{margin:8px 0} summary{cursor:pointer;font-weight:600} .scroll{overflow-x:auto}
.src{color:#56606b;font-size:12px}
"""


def _zone(z: str) -> str:
    return f'<span class="zone {z}">{z}</span>'


def _num(value: Any, unit: str = "") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if unit == "m":
            return "0 (touching)" if abs(value) < 1e-6 else f"{value * 1e3:.4g} mm"
        return f"{value:.4g} {unit}".strip()
    return html.escape(str(value))


def _cell(value: Any, column: str, unit: str) -> str:
    """A step table's cell under its header's unit: lengths in mm, a clearance of 0 as
    touching."""
    if unit == "m" and isinstance(value, float) and math.isfinite(value):
        if column.startswith("clearance") and value == 0.0:
            return "0 (touching)"
        return f"{value * 1e3:.4g}"
    if isinstance(value, float) and math.isfinite(value):
        return f"{value:.4g}"
    return _num(value)


def render_html(ev: Any) -> str:
    """The report as one HTML document."""
    from pliant import __version__  # noqa: PLC0415

    e = html.escape
    v = ev.verdict
    worst = ev.worst_step()
    last = len(ev.run.steps) - 1
    poses = [("start (worst)" if worst == 0 else "start", 0)]
    if 0 < worst < last:
        poses.append(("worst", worst))
    if last > 0:
        poses.append(("last (worst)" if worst == last else "last", last))
    passes = ("The operation passes." if v.passes else "The operation does not pass." if
              v.decided else "The operation is undecided: its answer rests on a fallback.")
    head = (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>pliant "
            f"evaluation: {e(ev.name)}</title><style>{STYLE}</style></head><body><main>")
    meta = (f"<h1>{e(ev.name)}</h1><div class=meta>{e(ev.part)} · {len(ev.run.steps) - 1} "
            f"of {ev.run.planned} steps solved · grips: {e(', '.join(ev.grips))} · rules: "
            f"{e(ev.rules_origin)} · pliant {__version__} · "
            f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC</div>")
    look = "pass" if v.passes else "fail" if v.decided else "undecided"
    verdict = (f'<div class="verdict {look}" id=verdict>'
               f"{e(v.headline)}<small>{passes} Exit status of <code>pliant evaluate</code>: "
               f"{0 if v.passes else 1}.</small></div>")
    parts = [head, meta, verdict]
    parts.append("<h2>Operators tried</h2><table><tr><th>operator</th><th>zone</th>"
                 "<th>what it takes</th><th title='accurate solves beyond the path&#39;s own, "
                 "to find and check the operator&#39;s grips'>extra solves</th></tr>")
    for op in ev.operators:
        parts.append(f"<tr><td>{e(op.operator)}</td><td>{_zone(op.zone.value)}</td>"
                     f"<td>{e(op.summary)}</td><td class=num>{op.solves}</td></tr>")
    parts.append("</table>")
    items = ev.items
    parts.append("<h2>Items to act on</h2>")
    if items:
        parts.append("<table id=items><tr><th>zone</th><th>check</th><th>value</th>"
                     "<th>threshold</th><th>where</th><th>rule's source (provenance)</th></tr>")
        for c in items:
            parts.append(_check_row(c))
        parts.append("</table>")
    else:
        parts.append("<p>Every check is green.</p>")
    parts.append("<h2>Along the path</h2><div class=figs>")
    for title, svg in figures(ev):
        parts.append(f"<h3 style='font-size:14px;margin:10px 0 0'>{e(title)}</h3>{svg}")
    parts.append("</div><h2>Poses</h2>")
    parts.append(view(ev))
    parts.append("<div class=poses>")
    for caption, url in pictures(ev, poses):
        parts.append(f"<figure><img alt='{e(caption)}' src='{url}'><figcaption>{e(caption)}"
                     "</figcaption></figure>")
    parts.append("</div><h2>Every check</h2><details><summary>the part, the scene and "
                 "the chosen operator's checks</summary><table><tr><th>zone</th><th>check"
                 "</th><th>value</th><th>threshold</th><th>where</th><th>rule's source "
                 "(provenance)</th></tr>")
    chosen = ev.chosen
    for c in ev.checks + (chosen.checks if chosen else []):
        parts.append(_check_row(c))
    parts.append("</table></details>")
    parts.append("<h2>Every step</h2><details><summary>the table (also in the CSV)</summary>"
                 "<div class=scroll><table><tr>")
    columns = list(ev.table[0]) if ev.table else []
    units = {c: column_unit(c) for c in columns}  # the CSV's, lengths shown in mm
    shown = {c: f" [{'mm' if u == 'm' else u}]" if u else "" for c, u in units.items()}
    parts += [f"<th>{e(c)}{shown[c]}</th>" for c in columns]
    parts.append("</tr>")
    for row in ev.table:
        cells = "".join(f"<td class=num>{_cell(row.get(c), c, units[c])}</td>"
                        for c in columns)
        parts.append(f"<tr>{cells}</tr>")
    parts.append("</table></div></details>")
    if ev.run.stopped:
        parts.append(f"<p><b>Stopped:</b> {e(ev.run.stopped)}</p>")
    parts.append("<p class=src>Forces are those the grip applies to the part, global frame; "
                 "axial is the pull along the part's tangent at the grip (push negative; at "
                 "the step that seats the part, a positive axial is the push onto the port). "
                 "Zones after EN 1005-3's risk multiplier; every threshold names its source "
                 "and can be replaced by your own table (<code>--rules</code>).</p>")
    parts.append("</main></body></html>")
    return "\n".join(parts)


def _check_row(c: Any) -> str:
    e = html.escape
    limit = c.red_at if c.zone == Zone.RED else c.yellow_at
    if limit is None:
        limit = c.red_at
    word = "" if limit is None else ("> " if c.worse == "above" else "< ")
    where = ", ".join(x for x in (
        f"step {c.step}" if c.step is not None else "", c.grip or "",
        f"s = {c.s:.3g} m" if c.s is not None else "") if x)
    note = f"<div class=src>{e(c.note)}</div>" if c.note else ""
    return (f"<tr><td>{_zone(c.zone.value)}</td><td>{e(c.title)}{note}</td>"
            f"<td class=num>{_num(c.value, c.unit)}</td><td class=num>"
            f"{word}{_num(limit, c.unit) if limit is not None else '–'}</td>"
            f"<td>{e(where)}</td><td class=src>{e(c.source)} ({e(c.provenance)})</td></tr>")


def write_html(ev: Any, path: str | Path) -> Path:
    text = render_html(ev).encode()
    return atomic_write(path, lambda h: h.write(text), "the report")
