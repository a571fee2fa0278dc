"""What ``pliant sequence`` says: the best order with each operation's verdict, why every
other order fails, the precedences found; in the terminal and as one HTML page (with the
precedence graph and the parts in the shape the best order leaves them)."""

from __future__ import annotations

import html
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from pliant.cli.evaluation_report import STYLE, inline_svg
from pliant.cli.report import count
from pliant.io.atomic import atomic_write

PALETTE = ("#1f4e9c", "#c05a1a", "#2f8a4c", "#7a3f98", "#b8912e", "#2a8a99")  # parts' lines


def verdict_line(result: Any) -> str:
    """The search's answer in one line."""
    best = result.best
    if best is None:
        return (f"NO ORDER FITS all {len(result.parts)} parts: each of the "
                f"{len(result.orders)} orders fails (see why below)")
    fits = sum(o.passes for o in result.orders)
    return (f"FITS in {fits} of {len(result.orders)} orders; best: "
            + " -> ".join(best.parts))


def print_sequence(result: Any, console: Console | None = None) -> None:
    console = console or Console()
    where = (count(result.workers, "worker") if result.workers > 1 else "this process")
    console.print(f"[bold]{escape(result.name)}[/bold]: {count(len(result.parts), 'part')}, "
                  f"{count(len(result.orders), 'order')}; "
                  f"{count(result.judged, 'operation')} judged now ({where}), "
                  f"{result.reused} reused from the store, {result.pruned} pruned"
                  f"{' (exhaustive: none pruned)' if result.exhaustive else ''}; "
                  f"{result.seconds:.1f} s")
    best = result.best
    if best is not None:
        table = Table(title="the best order", title_justify="left")
        for column in ("#", "operation", "verdict", "operator", "peak force", "zone"):
            table.add_column(column)
        for k, op in enumerate(best.operations, 1):
            table.add_row(str(k), escape(op["part"]), escape(op["headline"]),
                          escape(op["operator"] or "-"), _force(op["peak_force"]), op["zone"])
        console.print(table)
    table = Table(title="every order", title_justify="left")
    for column in ("order", "result", "why"):
        table.add_column(column)
    for o in result.orders:
        table.add_row(escape(" -> ".join(o.parts)),
                      "[green]fits[/green]" if o.passes else "[red]fails[/red]",
                      escape(_cost_words(o) if o.passes else o.why()))
    console.print(table)
    if result.precedences:
        console.print("[bold]precedences found[/bold]")
        for p in result.precedences:
            console.print(f"  {escape(p.sentence())}")
    for note in result.notes:
        console.print(f"[yellow]not judged[/yellow]: {escape(note)}")
    colour = "green" if result.passes else "red"
    console.print(f"[bold {colour}]{escape(verdict_line(result))}[/bold {colour}]")


def _force(value: float | None) -> str:
    return "-" if value is None else f"{value:.3g} N"


def _path_words(op: dict) -> str:
    """Where an operation's path came from: the part's file, or planned in the search."""
    plan = op.get("plan")
    if not plan:
        return "given" if op.get("status") not in ("pruned", "not judged") else "-"
    if "failed" in plan:
        return "none found"
    return f"planned: {plan['waypoints']} waypoints, {plan['seconds']:.1f} s"


def _cost_words(order: Any) -> str:
    zone, operator, hooks, peak, _ = order.cost
    who = ("one hand", "two hands", "a tool or robot")[int(operator)]
    regrasp = f", {int(hooks)} re-grasp{'s' if hooks != 1 else ''} (hooks)" if hooks else ""
    return (f"worst zone {('green', 'yellow', 'red')[int(zone)]}, {who}{regrasp}, peak hand "
            f"demand {peak:.0%} of its red limit")


# -- HTML -------------------------------------------------------------------------------
def precedence_svg(parts: tuple[str, ...], precedences: list[Any]) -> str:
    """The precedence graph: the parts on a circle, an arrow from each part that must go
    first to the part(s) it must precede."""
    e = html.escape
    n = len(parts)
    size, radius = 420, 140
    centre = size / 2
    at = {p: (centre + radius * math.cos(2 * math.pi * k / n - math.pi / 2),
              centre + radius * math.sin(2 * math.pi * k / n - math.pi / 2))
          for k, p in enumerate(parts)}
    out = [f"<svg xmlns='http://www.w3.org/2000/svg' width={size} height={size} "
           "role=img aria-label='precedence graph'><defs><marker id=arrow viewBox='0 0 10 10' "
           "refX=10 refY=5 markerWidth=8 markerHeight=8 orient=auto-start-reverse>"
           "<path d='M0,0 L10,5 L0,10 z' fill='#b3261e'/></marker></defs>"]
    for p in precedences:
        for then in p.then:
            (x0, y0), (x1, y1) = at[p.first], at[then]
            d = math.hypot(x1 - x0, y1 - y0) or 1.0
            ux, uy = (x1 - x0) / d, (y1 - y0) / d
            out.append(f"<line x1={x0 + 34 * ux:.1f} y1={y0 + 34 * uy:.1f} "
                       f"x2={x1 - 34 * ux:.1f} y2={y1 - 34 * uy:.1f} stroke='#b3261e' "
                       f"stroke-width=2 marker-end='url(#arrow)'><title>{e(p.sentence())}"
                       "</title></line>")
    for p, (x, y) in at.items():
        out.append(f"<circle cx={x:.1f} cy={y:.1f} r=30 fill='#e8eef5' stroke='#56606b'/>"
                   f"<text x={x:.1f} y={y + 4:.1f} text-anchor=middle font-size=11>"
                   f"{e(p)}</text>")
    out.append("</svg>")
    return "".join(out)


def shapes_svg(lines: list[tuple[str, np.ndarray]], obstacles: list[Any]) -> str:
    """The parts as fitted, seen from above and from the side (mm)."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    fig, axes = plt.subplots(1, 2, figsize=(9.5, 3.8))
    for ax, (i, j), title in zip(axes, ((0, 1), (0, 2)), ("from above (x, y)",
                                                           "from the side (x, z)"),
                                 strict=True):
        for o in obstacles:
            box = _extent(o)
            if box is not None:
                lo, hi = box * 1e3
                ax.add_patch(plt.Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j],
                                           color="#d5dbe1", zorder=0))
        for name, line in lines:
            ax.plot(line[:, i] * 1e3, line[:, j] * 1e3, lw=2.5, label=name)
        ax.set_title(title, fontsize=10)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("mm")
    axes[0].legend(fontsize=8, loc="best")
    fig.tight_layout()
    return inline_svg(fig, plt)


def _extent(obstacle: Any) -> np.ndarray | None:
    """An obstacle's world bounding box (2, 3) [m]: boxes and meshes (others: None)."""
    from pliant.scene.distance import BOX  # noqa: PLC0415

    if obstacle.mesh is not None:
        corners = np.array(np.meshgrid(*obstacle.mesh.bounds.T)).reshape(3, -1).T
    elif obstacle.kind == BOX:
        half = obstacle.param[:3]
        corners = np.array(np.meshgrid(*np.stack([-half, half]).T)).reshape(3, -1).T
    else:
        return None
    world = corners @ obstacle.rotation.T + obstacle.translation
    return np.array([world.min(axis=0), world.max(axis=0)])


def render_html(result: Any, lines: list[tuple[str, np.ndarray]] | None = None,
                obstacles: list[Any] | None = None) -> str:
    """The search as one HTML document."""
    from pliant import __version__  # noqa: PLC0415

    e = html.escape
    best = result.best
    look = "pass" if best is not None else "fail"
    parts = [f"<!doctype html><html lang=en><head><meta charset=utf-8><title>pliant "
             f"sequence: {e(result.name)}</title><style>{STYLE}</style></head><body><main>",
             f"<h1>{e(result.name)}</h1><div class=meta>{len(result.parts)} parts · "
             f"{len(result.orders)} orders · {result.judged} operations judged now, "
             f"{result.reused} reused, {result.pruned} pruned · pliant {__version__} · "
             f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC</div>",
             f"<div class='verdict {look}' id=verdict>{e(verdict_line(result))}<small>Exit "
             f"status of <code>pliant sequence</code>: {0 if best else 1}.</small></div>"]
    if best is not None:
        parts.append("<h2>The best order</h2><table id=best><tr><th>#</th><th>operation</th>"
                     "<th>verdict</th><th>operator</th><th>peak force</th><th>zone</th></tr>")
        for k, op in enumerate(best.operations, 1):
            parts.append(f"<tr><td>{k}</td><td>{e(op['part'])}</td><td>{e(op['headline'])}"
                         f"</td><td>{e(op['operator'] or '-')}</td><td class=num>"
                         f"{_force(op['peak_force'])}</td><td><span class='zone {op['zone']}'>"
                         f"{op['zone']}</span></td></tr>")
        parts.append("</table><p class=src>Costs, compared in turn: the worst zone, the "
                     "operator the hardest operation needs, the peak hand demand (a capacity "
                     "check's value over its red limit), the sum of the peak demands.</p>")
    parts.append("<h2>Precedences found</h2>")
    if result.precedences:
        parts.append("<ul id=precedences>" + "".join(f"<li>{e(p.sentence())}</li>"
                                                     for p in result.precedences) + "</ul>")
    else:
        parts.append("<p>None: no part's operation failed because of another part.</p>")
    parts.append(precedence_svg(result.parts, result.precedences))
    if lines:
        from pliant.cli import view3d  # noqa: PLC0415

        parts.append("<h2>The parts as the best order leaves them</h2>"
                     + view3d.html_view(
                         meshes=view3d.obstacle_meshes(obstacles or []),
                         lines=[view3d.line(line, PALETTE[k % len(PALETTE)], 4.0, name=name)
                                for k, (name, line) in enumerate(lines)],
                         caption="Each part in its own colour ("
                         + ", ".join(f"{name}: {PALETTE[k % len(PALETTE)]}"
                                     for k, (name, _) in enumerate(lines)) + ").")
                     + shapes_svg(lines, obstacles or []))
    parts.append("<h2>Every order</h2><table id=orders><tr><th>order</th><th>result</th>"
                 "<th>why</th></tr>")
    for o in result.orders:
        parts.append(f"<tr><td>{e(' → '.join(o.parts))}</td><td><span class='zone "
                     f"{'green' if o.passes else 'red'}'>{'fits' if o.passes else 'fails'}"
                     f"</span></td><td>{e(_cost_words(o) if o.passes else o.why())}</td></tr>")
    parts.append("</table><h2>Every operation</h2><details><summary>each part after each "
                 "prefix: judged, reused or pruned</summary><table><tr><th>fitted before"
                 "</th><th>operation</th><th>status</th><th>verdict</th><th>blamed</th>"
                 "<th>path</th><th>CPU s</th></tr>")
    for (prefix, part), op in sorted(result.operations.items()):
        parts.append(f"<tr><td>{e(', '.join(prefix) or '(nothing)')}</td><td>{e(part)}</td>"
                     f"<td>{e(op['status'])}</td><td>{e(op['headline'])}</td>"
                     f"<td>{e(', '.join(op.get('blockers') or []))}</td>"
                     f"<td>{e(_path_words(op))}</td>"
                     f"<td class=num>{op.get('seconds', 0.0):.2f}</td></tr>")
    parts.append("</table></details>")
    if result.notes:
        parts.append("<h2>Not judged</h2><ul>" + "".join(f"<li>{e(n)}</li>"
                                                         for n in result.notes) + "</ul>")
    parts.append("<p class=src>Each operation is <code>pliant evaluate</code> of the part's "
                 "own scene file with the parts fitted before it in place, flexible, in the "
                 "shape each settles in once let go. A pruned operation was not judged: an "
                 "operation of the same part failed with a subset of its fitted parts in the "
                 "way; <code>--exhaustive</code> judges every one.</p></main></body></html>")
    return "\n".join(parts)


def write_html(result: Any, path: str | Path, lines: list[tuple[str, np.ndarray]] | None = None,
               obstacles: list[Any] | None = None) -> Path:
    text = render_html(result, lines, obstacles).encode()
    return atomic_write(path, lambda h: h.write(text), "the report")
