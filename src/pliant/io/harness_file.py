"""A harness's derived properties, design checks and centre curves out: JSON (one
document a script or the design tool reads) and CSV (a row per point of each segment's
curve, in metres, the form a routing tool imports as a polyline per segment)."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from pliant.core.harness import Harness
from pliant.io.atomic import atomic_write
from pliant.io.jsontext import finite

SCHEMA_VERSION = 1


def _derived(d) -> dict:
    return {"value": d.value, "source": d.source}


def harness_json(harness: Harness, props: Mapping, checks: Sequence,
                 installed=None, clip_order=None) -> str:
    """The import's summary, each segment's properties (SI, with sources), every check
    (the design's, and the installed harness's where it was solved), the installed
    answer and the clip order (``pliant.assembly.clip_order``; forces in N, radii in
    m), as JSON text."""
    doc = {
        "schema_version": SCHEMA_VERSION,
        "harness": {"name": harness.name, "part_number": harness.part_number,
                    "source": harness.source, "kbl_version": harness.version,
                    "curve_convention": harness.convention, "notes": list(harness.notes),
                    "counts": counts(harness), "length_m": harness.length},
        "segments": [
            {"id": seg.id, "name": seg.name, "start_node": harness.nodes[seg.start].name,
             "end_node": harness.nodes[seg.end].name, "virtual_length_m": seg.virtual_length,
             "wires": [harness.wires[w].name for w in props[seg.id].wires],
             "diameter_m": _derived(props[seg.id].diameter),
             "mass_per_length_kg_m": _derived(props[seg.id].mass_per_length),
             "bending_stiffness_N_m2": _derived(props[seg.id].bending_stiffness),
             "torsional_stiffness_N_m2": _derived(props[seg.id].torsional_stiffness),
             "min_bend_radius_m": _derived(props[seg.id].min_bend_radius)}
            for seg in harness.segments.values()],
        "design_checks": [
            {"where": c.where, "name": c.name, "what": c.what, "value": c.value, "limit": c.limit,
             "zone": c.zone.value, "message": c.message, "source": c.source,
             "also": list(c.also)}
            for c in checks],
    }
    if installed is not None:
        doc["installed"] = {
            "iterations": installed.iterations, "balance": installed.balance,
            "weight_N": installed.weight, "notes": list(installed.notes),
            "junctions": {harness.nodes[k].name: list(map(float, p))
                          for k, p in installed.junctions.items()},
            "held_loads": {k: {"force_N": list(map(float, f)), "moment_N_m": list(map(float, m))}
                           for k, (f, m) in installed.held.items()},
            "segments": [{"id": k, "deviation_m": s.deviation, "sag_m": s.sag,
                          "bend_radius_m": s.bend_radius, "bend_limit_m": s.bend_limit,
                          "interference": None if s.interference is None
                          else s.interference.to_dict()}
                         for k, s in installed.segments.items()],
        }
    if clip_order is not None:
        doc["clip_order"] = clip_order.to_dict()
    return json.dumps(finite(doc), indent=1)


def counts(harness: Harness) -> dict[str, int]:
    """How many of each element the harness holds (routed wires: those in a segment)."""
    return {"nodes": len(harness.nodes), "segments": len(harness.segments),
            "wire_types": len(harness.wire_types), "wires": len(harness.wires),
            "routed_wires": sum(1 for w in harness.wires.values() if w.segments),
            "connectors": len(harness.connectors), "fixings": len(harness.fixings),
            "fixing_assignments": sum(len(s.fixings) for s in harness.segments.values()),
            "protections": len(harness.protections), "modules": len(harness.modules)}


def write_curves(path: str | Path, curves: Mapping[str, tuple[str, np.ndarray]],
                 what: str = "curves") -> Path:
    """CSV of centre curves: ``curves`` maps a segment id to (its name, (n, 3) points
    [m]); a row per point with its arc length s [m] from the segment's start node."""
    text = io.StringIO()
    out = csv.writer(text, lineterminator="\n")
    out.writerow(["segment", "name", "point", "s_m", "x_m", "y_m", "z_m"])
    for key, (name, pts) in curves.items():
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
        for i, (p, si) in enumerate(zip(pts, s)):
            out.writerow([key, name, i, f"{si:.6g}", f"{p[0]:.7g}", f"{p[1]:.7g}",
                          f"{p[2]:.7g}"])
    return atomic_write(path, lambda h: h.write(text.getvalue().encode()), what)


def write_tubes(path: str | Path, tubes: Mapping[str, tuple[np.ndarray, float]],
                what: str = "the harness") -> Path:
    """One glTF binary (.glb) of tubes: ``tubes`` maps a name to ((n, 3) centre points
    [m], radius [m]); each a named node, in the same frame as ``export_scene``'s."""
    import trimesh  # noqa: PLC0415 (only an export needs it)

    from pliant.core.tube import tube_mesh  # noqa: PLC0415
    from pliant.errors import OutputError  # noqa: PLC0415

    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise OutputError(f"cannot write {path}: the harness is written as a .glb file")
    scene = trimesh.Scene()
    for name, (points, radius) in tubes.items():
        vertices, faces = tube_mesh(points, radius, sides=12)
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        mesh.visual.face_colors = (230, 120, 30, 255)  # type: ignore[union-attr]
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    return atomic_write(path, lambda handle: handle.write(scene.export(file_type="glb")), what)
