"""Export the deformed part as a surface mesh (glTF, STL, OBJ, PLY) through trimesh."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pliant.core.tube import tube_mesh
from pliant.errors import OutputError
from pliant.io.atomic import atomic_write

FORMATS = {".glb": "glb", ".gltf": "gltf", ".stl": "stl", ".obj": "obj", ".ply": "ply"}


def part_radius(eq) -> float:
    """The tube radius [m]: the part's outer radius, or 1% of its length when the part
    gives no diameter (a display radius)."""
    part = eq.problem.part
    return part.outer_diameter / 2.0 if part.outer_diameter else 0.01 * part.length


def centreline_and_frames(eq) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) points and (n, 3, 3) section frames of a 2D or 3D equilibrium."""
    if eq.problem.dimension == 3:
        return eq.position, eq.frames
    points = np.column_stack([eq.position, np.zeros(eq.position.shape[0])])
    d3 = np.column_stack([np.cos(eq.angle), np.sin(eq.angle), np.zeros_like(eq.angle)])
    d1 = np.broadcast_to([0.0, 0.0, 1.0], d3.shape)
    frames = np.stack([d1, np.cross(d3, d1), d3], axis=2)
    # Drop the repeated samples at stations (before and after a jump: same point).
    keep = np.concatenate([[True], np.any(np.diff(points, axis=0) != 0.0, axis=1)])
    return points[keep], frames[keep]


def export_mesh(eq, path: str | Path, sides: int = 24) -> Path:
    """Write the deformed tube of an equilibrium to path (format from its suffix),
    atomically: a failure leaves any earlier file untouched."""
    import trimesh  # noqa: PLC0415 (imported on demand)

    path = Path(path)
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise OutputError(f"cannot write {path}: give a .glb, .gltf, .stl, .obj or .ply file")
    points, frames = centreline_and_frames(eq)
    vertices, faces = tube_mesh(points, part_radius(eq), frames, sides=sides)
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    return atomic_write(path, lambda handle: mesh.export(file_obj=handle, file_type=kind),
                        "the mesh")
