"""An interactive 3D view inside a self-contained HTML report: the obstacles as shaded
triangles, the part (or a harness's segments) as lines, drawn on a canvas by a few lines
of inline JavaScript (orthographic, z up; drag to turn, wheel to zoom, double-click to
reset, a slider for the path's steps). Nothing is fetched, so the report still opens
offline; three.js inlined would have added about 1 MB to every report for what is here
lines and flat-shaded triangles.

The view's data is a JSON block beside the canvas (metres, rounded to 0.1 mm);
``window.pliantViews[id]`` gives a page (and the tests) its ``project([x, y, z])`` to
canvas pixels and ``show(step)``."""

from __future__ import annotations

import functools
import html
import itertools
import json
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

MAX_FACES = 3000  # an obstacle's triangles in the view (decimated beyond)
MAX_POINTS = 80  # points of a line in the view (every k-th beyond, the ends kept)
_ids = itertools.count()


def _coords(points: Any) -> list[float]:
    """(n, 3) points as a flat list in metres to 0.1 mm."""
    return [float(x) for x in np.round(np.asarray(points, float).reshape(-1), 4)]


def line(points: Any, colour: str, width: float = 2.0, *, dashed: bool = False,
         name: str = "") -> dict:
    """A polyline (n, 3) [m], thinned to at most ``MAX_POINTS`` points."""
    p = np.asarray(points, float).reshape(-1, 3)
    if len(p) > MAX_POINTS:
        keep = np.unique(np.r_[np.linspace(0, len(p) - 1, MAX_POINTS).round().astype(int)])
        p = p[keep]
    return {"p": _coords(p), "c": colour, "w": float(width), "d": bool(dashed), "n": name}


def point(position: Any, colour: str, name: str = "", size: float = 4.0) -> dict:
    return {"p": _coords(position), "c": colour, "n": name, "s": float(size)}


def mesh(name: str, vertices: Any, faces: Any, colour: str = "#b9c0c8") -> dict:
    """A triangle mesh, decimated to at most ``MAX_FACES`` triangles."""
    v, f = np.asarray(vertices, float), np.asarray(faces, int)
    if len(f) > MAX_FACES:
        import trimesh  # noqa: PLC0415 (only a report of a large mesh decimates)

        small = trimesh.Trimesh(v, f, process=False).simplify_quadric_decimation(
            face_count=MAX_FACES)
        v, f = np.asarray(small.vertices), np.asarray(small.faces)
    return {"n": name, "v": _coords(v), "f": [int(i) for i in f.reshape(-1)], "c": colour}


def obstacle_meshes(obstacles: Iterable, halfspace_size: float = 1.0) -> list[dict]:
    """The scene's obstacles (``pliant.scene.Obstacle``) as view meshes."""
    from pliant.io.mesh_export import obstacle_mesh  # noqa: PLC0415

    out = []
    for obstacle in obstacles:
        m = obstacle_mesh(obstacle, halfspace_size=halfspace_size)
        out.append(mesh(obstacle.name, m.vertices, m.faces))
    return out


def html_view(*, meshes: Sequence[dict] = (), lines: Sequence[dict] = (),
              points: Sequence[dict] = (), steps: Sequence[Sequence[dict]] = (),
              labels: Sequence[str] = (), start: int = 0, height: int = 520,
              caption: str = "") -> str:
    """The view as an HTML fragment: ``lines`` and ``points`` always drawn, ``steps``
    (one list of lines and points per path step, with their ``labels``) one at a time,
    from ``start``."""
    key = f"pliant-view-{next(_ids)}"
    data = {"meshes": list(meshes), "lines": list(lines), "points": list(points),
            "steps": [list(s) for s in steps], "labels": list(labels), "start": int(start)}
    blob = json.dumps(data, separators=(",", ":")).replace("</", "<\\/")
    slider = ""
    if len(steps) > 1:
        slider = (f"<input type=range min=0 max={len(steps) - 1} value={int(start)} "
                  f"style='width:60%'> <span class=src></span><br>")
    return (f"<figure class=view3d id={key} style='margin:8px 0;background:#fff;"
            f"border-radius:6px;padding:6px'><canvas width=1060 height={int(height)} "
            f"style='width:100%;touch-action:none;cursor:grab'></canvas>"
            f"<figcaption>{slider} <span class=src>{html.escape(caption)} Drag to turn, "
            f"wheel to zoom, double-click to reset.</span></figcaption>"
            f"<script type=application/json>{blob}</script>"
            f"<script>{_script().replace('__ID__', key)}</script></figure>")


@functools.cache
def _script() -> str:
    """The view's JavaScript, read once."""
    return Path(__file__).with_name("view3d.js").read_text(encoding="utf-8")

