"""``pliant harness --report``: one self-contained HTML page (styles inline, drawings as
inline SVG, it opens offline) with the harness's checks worst first, its views from
above, the side and the front (the design dashed, the installed harness coloured by
each segment's worst check), each segment's properties and answer, the loads on its
connectors and fixings, and the sources of every number."""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from pliant.assembly.checks import Zone
from pliant.assembly.harness import sources, worst_zones
from pliant.cli.evaluation_report import COLOURS, STYLE, inline_svg
from pliant.core.harness import Harness
from pliant.io.atomic import atomic_write
from pliant.io.harness_file import counts

_VIEWS = (("from above (x, y)", 0, 1), ("from the side (x, z)", 0, 2),
          ("from the front (y, z)", 1, 2))


def views(harness: Harness, design: Mapping[str, np.ndarray], installed,
          checks: Sequence) -> str:
    """Three projections as one inline SVG: each segment's designed curve (grey,
    dashed) and, where solved, its installed one in its worst check's colour; the
    nodes with a placed connector as squares."""
    import matplotlib  # noqa: PLC0415 (only a report draws)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    worst = worst_zones(checks)
    fig, axes = plt.subplots(1, 3, figsize=(11.0, 3.9))
    for ax, (title, i, j) in zip(axes, _VIEWS):
        for seg_id, pts in design.items():
            p = pts * 1e3
            ax.plot(p[:, i], p[:, j], color="#999999", lw=0.8, ls="--")
            zone = worst.get(f"segment {seg_id}", Zone.GREEN)
            colour = COLOURS.get(zone.value, "#1b7f3b")
            if installed is not None:
                q = installed.segments[seg_id].equilibrium.position * 1e3
                ax.plot(q[:, i], q[:, j], color=colour, lw=1.6)
            elif zone.rank >= Zone.YELLOW.rank:
                ax.plot(p[:, i], p[:, j], color=colour, lw=1.6)
        held = [c.node for c in harness.connectors.values() if c.placement and c.node]
        if held:
            xyz = np.array([harness.nodes[n].position for n in held if n in harness.nodes])
            if xyz.size:
                ax.plot(xyz[:, i] * 1e3, xyz[:, j] * 1e3, "s", ms=3, color="#3d5a80")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("xyz"[i] + " [mm]", fontsize=8)
        ax.set_ylabel("xyz"[j] + " [mm]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_aspect("equal", adjustable="datalim")
    fig.tight_layout()
    return inline_svg(fig, plt)


def view(harness: Harness, design: Mapping[str, np.ndarray], installed, checks: Sequence,
         obstacles: Sequence = ()) -> str:
    """The interactive 3D view (``cli.view3d``): the scene's obstacles, each segment's
    designed curve (grey, dashed) and its installed one in its worst check's colour (the
    flagged designed ones where not solved), the placed connectors and the fixings."""
    from pliant.cli import view3d  # noqa: PLC0415

    worst = worst_zones(checks)
    lines = []
    for seg_id, pts in design.items():
        name = seg_id  # as the checks name it
        lines.append(view3d.line(pts, "#999999", 1.0, dashed=True, name=f"{name} (design)"))
        zone = worst.get(f"segment {seg_id}", Zone.GREEN)
        colour = COLOURS.get(zone.value, "#1b7f3b")
        if installed is not None:
            lines.append(view3d.line(installed.segments[seg_id].equilibrium.position,
                                     colour, 2.5, name=name))
        elif zone.rank >= Zone.YELLOW.rank:
            lines.append(view3d.line(pts, colour, 2.5, name=name))
    points = [view3d.point(harness.nodes[c.node].position, "#3d5a80", c.name)
              for c in harness.connectors.values()
              if c.placement and c.node and c.node in harness.nodes]
    return view3d.html_view(meshes=view3d.obstacle_meshes(obstacles), lines=lines,
                            points=points, caption="Dashed: the design. Solid: "
                            + ("the installed harness" if installed is not None
                               else "segments flagged by a check")
                            + ", coloured by its worst check. Squares: placed connectors.")


def render_html(harness: Harness, props: Mapping, checks: Sequence, installed=None,
                clip_order=None, obstacles: Sequence = ()) -> str:
    """The report as one HTML document (with the clip order, ``assembly.clip_order``'s
    answer, where one was searched, and the scene's ``obstacles`` in its 3D view)."""
    from pliant import __version__  # noqa: PLC0415
    from pliant.assembly.harness import centre_curve  # noqa: PLC0415

    e = html.escape
    n = counts(harness)
    tally = {z: sum(1 for c in checks if c.zone == z) for z in Zone}
    headline = ("The design has red checks." if tally[Zone.RED] else
                "No check is red." if not tally[Zone.YELLOW] else
                "No check is red; some are yellow.")
    parts = [f"<!doctype html><html lang=en><head><meta charset=utf-8><title>pliant "
             f"harness: {e(harness.name)}</title><style>{STYLE}</style></head><body><main>",
             f"<h1>{e(harness.name)} {e(harness.part_number)}</h1>",
             f"<div class=meta>KBL {e(harness.version)} · {e(harness.source)} · "
             f"{n['nodes']} nodes, {n['segments']} segments ({harness.length:.3f} m), "
             f"{n['routed_wires']} routed wires, {n['connectors']} connectors, "
             f"{n['fixing_assignments']} fixings on segments · pliant {__version__} · "
             f"{datetime.now(UTC):%Y-%m-%d %H:%M} UTC</div>",
             f"<p><b>{headline}</b> " + ", ".join(
                 f'{tally[z]} <span class="zone {z.value}">{z.value}</span>'
                 for z in (Zone.RED, Zone.YELLOW, Zone.UNCHECKED, Zone.GREEN) if tally[z])
             + "</p>"]
    if harness.notes:
        parts.append("<ul>" + "".join(f"<li>{e(x)}</li>" for x in harness.notes) + "</ul>")
    if installed is not None:
        parts.append(f"<p>Installed under gravity: {len(installed.junctions)} junctions "
                     f"balanced to {installed.balance:.1e} of the weight "
                     f"({installed.weight:.2f} N) in {installed.iterations} Newton "
                     "iterations.</p>")
        if installed.notes:
            parts.append("<ul>" + "".join(f"<li>{e(x)}</li>" for x in installed.notes)
                         + "</ul>")
    design = {k: centre_curve(harness, k) for k in harness.segments}
    parts.append("<h2>Views</h2><p>Dashed: the design. Solid: "
                 + ("the installed harness" if installed is not None
                    else "segments flagged by a check")
                 + ", coloured by its worst check. Squares: placed connectors.</p>")
    parts.append(view(harness, design, installed, checks, obstacles))
    parts.append(views(harness, design, installed, checks))
    parts.append("<h2>Checks, worst first</h2><table><tr><th>zone</th><th>where</th>"
                 "<th>what</th><th>finding</th><th>source</th></tr>")
    for c in sorted(checks, key=lambda c: -c.zone.rank):
        if c.zone.rank < Zone.YELLOW.rank:
            continue
        name = f"<br><small>{e(c.name)}</small>" if c.name else ""
        parts.append(f'<tr><td><span class="zone {c.zone.value}">{c.zone.value}</span></td>'
                     f"<td>{e(c.where)}{name}</td><td>{e(c.what)}</td><td>{e(c.message)}"
                     f"</td><td>{e(c.source)}</td></tr>")
    parts.append("</table>")
    worst = worst_zones(checks)
    parts.append("<h2>Segments</h2><table><tr><th>segment</th><th>length mm</th>"
                 "<th>wires</th><th>diameter mm</th><th>mass g/m</th><th>EI N mm²</th>"
                 "<th>R min mm</th>" + ("<th>off design mm</th><th>sag mm</th>"
                                        "<th>R mm</th>" if installed is not None else "")
                 + "<th>worst</th></tr>")
    for seg in harness.segments.values():
        p = props[seg.id]

        def mm(v):
            return "–" if v is None else f"{v * 1e3:.1f}"

        ei = p.bending_stiffness.value
        row = (f"<tr><td>{e(seg.id)}<br><small>{e(seg.name)}</small></td>"
               f"<td>{seg.virtual_length * 1e3:.1f}</td><td>{len(p.wires)}</td>"
               f"<td>{mm(p.diameter.value)}</td><td>{mm(p.mass_per_length.value)}</td>"
               f"<td>{'–' if ei is None else f'{ei * 1e6:.0f}'}</td>"
               f"<td>{mm(p.min_bend_radius.value)}</td>")
        if installed is not None:
            s = installed.segments[seg.id]
            row += f"<td>{mm(s.deviation)}</td><td>{mm(s.sag)}</td><td>{mm(s.bend_radius)}</td>"
        zone = worst.get(f"segment {seg.id}", Zone.GREEN).value
        parts.append(row + f'<td><span class="zone {zone}">{zone}</span></td></tr>')
    parts.append("</table>")
    if installed is not None and installed.held:
        parts.append("<h2>Loads the harness puts on its connectors and fixings</h2><table>"
                     "<tr><th>where</th><th>force N</th><th>moment N m</th></tr>")
        for key, (force, moment) in sorted(installed.held.items(),
                                           key=lambda kv: -float(np.linalg.norm(kv[1][0]))):
            parts.append(f"<tr><td>{e(key)}</td><td>{np.linalg.norm(force):.3g}</td>"
                         f"<td>{np.linalg.norm(moment):.3g}</td></tr>")
        parts.append("</table><p>No public rule limits them: compare with the connector's "
                     "or clip's rating.</p>")
    if clip_order is not None:
        parts.append(_clip_order_html(clip_order))
    parts.append("<h2>Sources</h2><ul>" + "".join(f"<li>{e(s)}</li>"
                                                  for s in sources(props, checks))
                 + "</ul></main></body></html>")
    return "".join(parts)


def _clip_order_html(result) -> str:
    """The clip order: the best order's operations, then each failing operation."""
    e = html.escape
    best = result.best
    out = [f"<h2>Clip order</h2><p>{len(result.fixings)} fixings, {e(result.method)}, "
           f"{result.operations} operations judged. "
           + ("<b>No order of the fixings passes.</b>" if best is None else
              f'Best: {e(" → ".join(best.fixings))} '
              f'(<span class="zone {best.zone}">{best.zone}</span>, the hand at most '
              f"{best.peak:.2f} N).") + "</p>"]
    out.append("<ul>" + "".join(f"<li>{e(n)}</li>" for n in result.notes) + "</ul>")
    if best is not None:
        out.append("<table><tr><th>#</th><th>fixing</th><th>hand force N</th>"
                   "<th>tightest bend mm</th><th>segment</th><th>R min mm</th>"
                   "<th>zone</th></tr>")
        for k, step in enumerate(best.steps, 1):
            segment, radius, limit = step.tightest
            out.append(f"<tr><td>{k}</td><td>{e(step.fixing)}</td><td>{step.force:.2f}</td>"
                       f"<td>{radius * 1e3:.1f}</td><td>{e(segment)}</td>"
                       f"<td>{'–' if limit is None else f'{limit * 1e3:.1f}'}</td>"
                       f'<td><span class="zone {step.zone}">{step.zone}</span></td></tr>')
        out.append("</table>")
    if result.failures:
        out.append("<p>Why the other orders fail:</p><ul>" + "".join(
            f"<li>{e(f.fixing)} fixed after {e(', '.join(sorted(f.before)) or 'no other')}: "
            f"{e('; '.join(f.reasons))}</li>" for f in result.failures) + "</ul>")
    return "".join(out)


def write_html(harness: Harness, props: Mapping, checks: Sequence, installed,
               path: str | Path, clip_order=None, obstacles: Sequence = ()) -> Path:
    text = render_html(harness, props, checks, installed, clip_order, obstacles).encode()
    return atomic_write(path, lambda h: h.write(text), "the report")
