"""A variation study for people: its summary in the terminal, and one self-contained HTML
report (distributions of the outputs, the probability of each verdict, the sensitivity
ranking, a picture of the tolerance envelope, the failed samples with their errors)."""

from __future__ import annotations

import html
import math
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from pliant.assembly.study import OUTPUTS
from pliant.cli.evaluation_report import STYLE, inline_svg, png_data_url
from pliant.cli.report import count
from pliant.io.atomic import atomic_write

SCALE = {"N": (1.0, "N"), "N m": (1.0, "N m"), "m": (1e3, "mm")}


def print_study(result: Any, summary: dict[str, Any], console: Console | None = None) -> None:
    console = console or Console()
    workers = summary["workers"]
    where = count(workers, "worker") if workers else "this process, no workers"
    console.print(f"[bold]{count(summary['samples'], 'sample')}[/bold] ({summary['computed']} "
                  f"computed now on {where} in {summary['seconds']:.1f} s; "
                  f"{summary['failed']} failed)")
    table = Table(title="verdicts", title_justify="left")
    for column in ("verdict", "samples", "probability"):
        table.add_column(column)
    for name, v in summary["verdicts"].items():
        table.add_row(escape(name), str(v["count"]), f"{v['probability']:.1%}")
    console.print(table)
    table = Table(title="outputs over the samples", title_justify="left")
    for column in ("output", "p5", "p50", "p95", "min", "max"):
        table.add_column(column, justify="left" if column == "output" else "right")
    for p in summary["percentiles"].values():
        if not p["count"]:
            continue
        scale, unit = SCALE[p["unit"]]
        table.add_row(escape(f"{p['title']} [{unit}]"),  # ("[mm]" would read as markup)
                      *(f"{p[k] * scale:.4g}" for k in ("p5", "p50", "p95", "min", "max")))
    console.print(table)
    if summary["sensitivity"]:
        table = Table(title="sensitivity (Spearman's rank correlation)", title_justify="left")
        keys = ("peak_force", "min_clearance", "min_bend_radius", "passes")
        titles = {key: title for key, title, _ in OUTPUTS} | {"passes": "passes"}
        for column in ("parameter", *(titles[k] for k in keys)):
            table.add_column(column, justify="left" if column == "parameter" else "right",
                             no_wrap=column == "parameter")  # (the headers wrap instead)
        for row in summary["sensitivity"]:
            table.add_row(escape(row["parameter"]), *(f"{row[k]:+.2f}" for k in keys))
        console.print(table)
    for e in summary["errors"][:5]:
        console.print(f"[red]sample {e['index']} failed[/red]: {escape(e['error'])}")


def render_html(result: Any, summary: dict[str, Any], envelope: np.ndarray,
                final: np.ndarray) -> str:
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    e = html.escape
    ok = result.ok
    head = (f"<!doctype html><html lang=en><head><meta charset=utf-8><title>pliant study"
            f"</title><style>{STYLE}</style></head><body><main>")
    title = f"<h1>Variation study: {e(str(result.scene.problem.name or 'scene'))}</h1>"
    meta = (f"<div class=meta>{summary['samples']} samples ({summary['evaluated']} "
            f"evaluated, {summary['failed']} failed) · variations: "
            f"{e(', '.join(v.name + ' ' + _tol(v) for v in result.variations))}</div>")
    parts = [head, title, meta]
    passing = sum(v["count"] for k, v in summary["verdicts"].items() if k.startswith("passes"))
    share = passing / max(summary["samples"], 1)
    parts.append(f'<div class="verdict {"pass" if share >= 0.99 else "fail"}" id=verdict>'
                 f"{share:.1%} of the samples pass"
                 f"<small>{e(_verdict_words(summary))}</small></div>")
    parts.append("<h2>Verdicts</h2><table><tr><th>verdict</th><th>samples</th>"
                 "<th>probability</th></tr>")
    for name, v in summary["verdicts"].items():
        parts.append(f"<tr><td>{e(name)}</td><td class=num>{v['count']}</td>"
                     f"<td class=num>{v['probability']:.1%}</td></tr>")
    parts.append("</table><h2>Outputs</h2><div class=figs>")
    fig, axes = plt.subplots(1, 4, figsize=(11, 2.8), layout="constrained", squeeze=False)
    for ax, (key, p) in zip(axes[0], summary["percentiles"].items()):
        scale, unit = SCALE[p["unit"]]
        values = np.array([r[key] for r in ok if r.get(key) is not None], float) * scale
        values = values[np.isfinite(values)]
        title = f"{p['title']} [{unit}]"
        if values.size:
            low, high = float(values.min()), float(values.max())
            if high - low <= 1e-9 * max(abs(low), abs(high), 1e-300):
                # The same for every sample (to round-off): one bar, said in the title,
                # where bins narrower than round-off could not be made.
                half = max(0.05 * abs(high), 1e-12)
                ax.hist(values, bins=1, range=(high - half, high + half), color="#3d5a80")
                title += f"\nthe same in every sample: {high:.4g}"
            else:
                ax.hist(values, bins=max(5, min(40, int(math.sqrt(values.size)) * 2)),
                        color="#3d5a80")
                for q, style in (("p5", ":"), ("p50", "-"), ("p95", ":")):
                    ax.axvline(p[q] * scale, color="#c0262d", ls=style, lw=1)
        ax.set_title(title, fontsize=9)
        ax.tick_params(labelsize=7)
    parts.append(inline_svg(fig, plt))
    parts.append("</div><table><tr><th>output</th><th>p5</th><th>p50</th><th>p95</th>"
                 "<th>min</th><th>max</th></tr>")
    for p in summary["percentiles"].values():
        if p["count"]:
            scale, unit = SCALE[p["unit"]]
            cells = "".join(f"<td class=num>{p[k] * scale:.4g}</td>"
                            for k in ("p5", "p50", "p95", "min", "max"))
            parts.append(f"<tr><td>{e(p['title'])} [{unit}]</td>{cells}</tr>")
    parts.append("</table>")
    if summary["sensitivity"]:
        keys = ("peak_force", "peak_moment", "min_clearance", "min_bend_radius", "passes")
        parts.append("<h2>Sensitivity</h2><p class=src>Spearman's rank correlation of each "
                     "output with each varied parameter over the evaluated samples (+1: the "
                     "output rises with it), most influential first.</p><table><tr>"
                     "<th>parameter</th>" + "".join(f"<th>{k}</th>" for k in keys) + "</tr>")
        for row in summary["sensitivity"]:
            parts.append(f"<tr><td>{e(row['parameter'])}</td>" + "".join(
                f"<td class=num>{row[k]:+.2f}</td>" for k in keys) + "</tr>")
        parts.append("</table>")
    parts.append("<h2>Tolerance envelope</h2><p class=src>The voxels (edge "
                 f"{result.voxel * 1e3:.3g} mm) the part passes through over every sample, "
                 "along the path (grey) and at the final pose (orange); as meshes in "
                 "envelope.glb.</p>")
    if envelope.shape[0]:
        fig = plt.figure(figsize=(6, 5), layout="constrained")
        ax = fig.add_subplot(projection="3d")
        pts = (envelope + 0.5) * result.voxel
        step = max(1, pts.shape[0] // 6000)
        ax.scatter(*pts[::step].T, s=1, c="#9aa3ad", alpha=0.25)
        if final.shape[0]:
            fp = (final + 0.5) * result.voxel
            ax.scatter(*fp.T, s=3, c="#e0701e")
        ax.set_box_aspect((1, 1, 1))
        ax.set_xlabel("x [m]", fontsize=7)
        ax.set_ylabel("y [m]", fontsize=7)
        ax.set_zlabel("z [m]", fontsize=7)
        ax.tick_params(labelsize=6)
        parts.append(f"<img alt='envelope' src='{png_data_url(fig, plt)}'>")
    if summary["errors"]:
        parts.append("<h2>Failed samples</h2><table><tr><th>sample</th><th>error</th></tr>")
        for err in summary["errors"]:
            parts.append(f"<tr><td class=num>{err['index']}</td><td>{e(err['error'])}</td></tr>")
        parts.append("</table>")
    parts.append("</main></body></html>")
    return "\n".join(parts)


def _tol(v: Any) -> str:
    if v.relative:
        tol = f"{v.tolerance * 100:.3g}%"
    elif v.quantity == "length":
        tol = f"{v.tolerance * 1e3:.3g} mm"
    else:
        tol = f"{v.tolerance:.3g} {v.unit}"
    return f"+- {tol}" + (" (3 sigma)" if v.distribution == "normal" else "")


def _verdict_words(summary: dict[str, Any]) -> str:
    parts = [f"{name}: {v['probability']:.1%}" for name, v in summary["verdicts"].items()]
    return "; ".join(parts)


def write_html(result: Any, summary: dict[str, Any], envelope: np.ndarray, final: np.ndarray,
               path: str | Path) -> Path:
    text = render_html(result, summary, envelope, final).encode()
    return atomic_write(path, lambda h: h.write(text), "the study's report")
