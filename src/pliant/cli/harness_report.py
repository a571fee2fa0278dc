"""``pliant harness``'s terminal report: what the KBL file holds, each segment's derived
properties with their sources, and the design checks, worst first."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np
from rich.console import Console
from rich.table import Table

from pliant.assembly.checks import Zone
from pliant.assembly.harness import sources, worst_zones
from pliant.core.harness import Harness
from pliant.io.harness_file import counts

_STYLE = {Zone.RED: "bold red", Zone.YELLOW: "yellow", Zone.GREEN: "green",
          Zone.UNCHECKED: "magenta", Zone.INFO: ""}


def _mm(value: float | None, digits: int = 1) -> str:
    return "-" if value is None else f"{value * 1e3:.{digits}f}"


def print_harness(console: Console, harness: Harness, props: Mapping, checks: Sequence,
                  show_all: bool = False) -> None:
    """The report. ``show_all``: every segment's row (else the ones a check flags)."""
    n = counts(harness)
    console.print(f"[bold]{harness.name}[/bold] {harness.part_number}  (KBL "
                  f"{harness.version}, {harness.source})")
    console.print(f"{n['nodes']} nodes, {n['segments']} segments "
                  f"({harness.length:.3f} m designed), {n['routed_wires']} routed wires of "
                  f"{n['wire_types']} types, {n['connectors']} connectors and terminals, "
                  f"{n['fixings']} fixings ({n['fixing_assignments']} placed on segments), "
                  f"{n['protections']} protections, {n['modules']} modules")
    for note in harness.notes:
        console.print(f"  note: {note}")

    worst = worst_zones(checks)
    table = Table(title="segments (SI sources below)", show_lines=False)
    for col in ("segment", "mm", "wires", "Ø mm", "g/m", "EI N mm²", "R min mm", "check"):
        table.add_column(col, justify="left" if col == "segment" else "right")
    shown = 0
    for seg in harness.segments.values():
        p = props[seg.id]
        zone = worst.get(f"segment {seg.id}", Zone.GREEN)
        if not show_all and zone in (Zone.GREEN, Zone.INFO):
            continue
        shown += 1
        ei = p.bending_stiffness.value
        mass = p.mass_per_length.value
        table.add_row(seg.id, f"{seg.virtual_length * 1e3:.1f}", str(len(p.wires)),
                      _mm(p.diameter.value), "-" if mass is None else f"{mass * 1e3:.1f}",
                      "-" if ei is None else f"{ei * 1e6:.0f}", _mm(p.min_bend_radius.value),
                      f"[{_STYLE[zone]}]{zone.value}[/]")
    if shown:
        console.print(table)
    if not show_all:
        console.print(f"{shown} of {len(harness.segments)} segments flagged by a check shown "
                      "(--all: every segment)")

    tally = Counter(c.zone for c in checks)
    console.print("design checks: " + ", ".join(
        f"[{_STYLE[z]}]{tally[z]} {z.value}[/]" for z in (Zone.RED, Zone.YELLOW, Zone.UNCHECKED,
                                                           Zone.GREEN) if tally[z]))
    for c in sorted(checks, key=lambda c: -c.zone.rank):
        if c.zone.rank < Zone.YELLOW.rank:
            break
        console.print(f"  [{_STYLE[c.zone]}]{c.zone.value:6}[/] {c.where}: {c.what}: "
                      f"{c.message}")
    named = sources(props, checks)
    console.print("sources:")
    for s in named[:12]:
        console.print(f"  - {s}")
    if len(named) > 12:
        console.print(f"  ... and {len(named) - 12} more (--json lists each segment's)")


def print_installed(console: Console, installed, checks: Sequence, seconds: float,
                    show_all: bool = False) -> None:
    """The installed harness: how it was solved, each segment's deviation from its
    design, its sag and tightest bend, and the loads on the connectors and fixings."""
    n = len(installed.junctions)
    console.print(f"[bold]installed under gravity[/bold]: {len(installed.segments)} segments, "
                  f"{n} junctions balanced to {installed.balance:.1e} of the weight "
                  f"({installed.weight:.2f} N) in {installed.iterations} Newton iterations, "
                  f"{seconds:.1f} s")
    for note in installed.notes:
        console.print(f"  note: {note}")
    worst = worst_zones(checks)
    table = Table(title="installed segments")
    cols = ["segment", "off design mm", "sag mm", "R mm", "R min mm"]
    scene = any(s.interference is not None for s in installed.segments.values())
    if scene:
        cols.append("clearance mm")
    for col in [*cols, "check"]:
        table.add_column(col, justify="left" if col == "segment" else "right")
    shown = 0
    for key, seg in installed.segments.items():
        zone = worst.get(f"segment {key}", Zone.GREEN)
        if not show_all and zone in (Zone.GREEN, Zone.INFO):
            continue
        shown += 1
        row = [key, f"{seg.deviation * 1e3:.1f}", f"{seg.sag * 1e3:.1f}",
               f"{seg.bend_radius * 1e3:.1f}", _mm(seg.bend_limit)]
        if scene:
            near = seg.interference.smallest if seg.interference is not None else None
            row.append("-" if near is None else f"{near.clearance * 1e3:.1f}")
        table.add_row(*row, f"[{_STYLE[zone]}]{zone.value}[/]")
    if shown:
        console.print(table)
    worst_dev = max(installed.segments.values(), key=lambda s: s.deviation)
    console.print(f"{shown} of {len(installed.segments)} segments flagged shown; the largest "
                  f"deviation from the design: {worst_dev.deviation * 1e3:.1f} mm "
                  f"(segment {worst_dev.segment})")
    loads = sorted(installed.held.items(), key=lambda kv: -float(np.linalg.norm(kv[1][0])))
    console.print("loads from the harness (largest first):")
    for key, (force, moment) in loads[: None if show_all else 5]:
        console.print(f"  {key}: {np.linalg.norm(force):.2f} N, {np.linalg.norm(moment):.3f} N m")
    for c in checks:
        if c.zone.rank >= Zone.YELLOW.rank:
            console.print(f"  [{_STYLE[c.zone]}]{c.zone.value:6}[/] {c.where}: {c.what}: "
                          f"{c.message}")


def print_modules(console: Console, harness: Harness) -> None:
    """The harness's modules: each one's id, part number, description and how many of
    the harness's wires it brings (``--module`` takes the id or the part number)."""
    table = Table(title=f"modules of {harness.name} ({len(harness.modules)})")
    for col in ("id", "part number", "description", "wires"):
        table.add_column(col, justify="right" if col == "wires" else "left")
    for m in harness.modules.values():
        table.add_row(m.id, m.part_number or "-", m.description or "-",
                      str(sum(1 for w in harness.wires if w in m.components)))
    console.print(table)
    controlled = set().union(*(m.components for m in harness.modules.values())) \
        if harness.modules else set()
    console.print(f"{sum(1 for w in harness.wires if w not in controlled)} wires belong to "
                  "no module: every variant has them")


def print_clip_order(console: Console, result) -> None:
    """The clip order (``pliant.assembly.clip_order.ClipOrder``): the best order's
    operations (the hand's force, the tightest bend after each), then why the others
    fail: each clip that is red when fixed after which others."""
    console.print(f"[bold]clip order[/bold] of {len(result.fixings)} fixings "
                  f"({result.method}; {result.operations} operations judged)")
    for note in result.notes:
        console.print(f"  note: {note}")
    best = result.best
    if best is None:
        console.print("[bold red]no order of the fixings passes[/]")
    else:
        table = Table(title=f"best order: {best.zone}")
        for col in ("#", "fixing", "hand force N", "tightest bend mm", "segment",
                    "R min mm", "zone"):
            table.add_column(col, justify="left" if col in ("fixing", "segment") else "right")
        for k, step in enumerate(best.steps, 1):
            segment, radius, limit = step.tightest
            zone = Zone(step.zone)
            table.add_row(str(k), step.fixing, f"{step.force:.2f}", f"{radius * 1e3:.1f}",
                          segment, _mm(limit), f"[{_STYLE[zone]}]{zone.value}[/]")
        console.print(table)
        for step in best.steps:
            for reason in step.reasons:
                console.print(f"  {step.fixing}: {reason}")
    for step in result.failures:
        after = ", ".join(sorted(step.before)) or "no other"
        console.print(f"[red]fails[/]: {step.fixing} fixed after {after}: "
                      + "; ".join(step.reasons))
