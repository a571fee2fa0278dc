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
    return eq.problem.part.drawn_radius


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


DISPLAY_FACES = 60_000  # per obstacle in the browser: a CAD part's millions would stall it
DISPLAY_BUDGET = 400_000  # the whole scene's: a vehicle assembly's hundreds of parts
DISPLAY_FLOOR = 500  # a part is never drawn with fewer (a bolt stays a bolt)


def display_budgets(faces: list[int], budget: int | None = None,
                    per_part: int | None = None) -> list[int]:
    """How many triangles to draw of each of the scene's meshes (``faces`` their
    counts): all of a scene that fits ``budget``; else each part a share in proportion
    to its count (never above ``per_part``, never below ``DISPLAY_FLOOR`` or its own),
    so that the big parts give up detail first and the sum stays near the budget."""
    budget = DISPLAY_BUDGET if budget is None else budget
    per_part = DISPLAY_FACES if per_part is None else per_part
    want = [min(n, per_part) for n in faces]
    if sum(want) <= budget:
        return want
    # the largest scale whose allotment fits: bisection on the share of each part
    low, high = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (low + high)
        if sum(min(w, max(DISPLAY_FLOOR, int(mid * n))) for w, n in zip(want, faces)) \
                <= budget:
            low = mid
        else:
            high = mid
    return [min(w, max(DISPLAY_FLOOR, int(low * n))) for w, n in zip(want, faces)]


def display_mesh(mesh, max_faces: int = DISPLAY_FACES):
    """The mesh to draw: above ``max_faces`` triangles, decimated by quadric error
    (fast-simplification, through trimesh). For the eye only: contact, clearances and
    exports keep the exact mesh (``display_obstacle`` keeps a drawing in the disk
    cache)."""
    if len(mesh.faces) <= max_faces:
        return mesh
    return mesh.simplify_quadric_decimation(face_count=int(max_faces))


def triangles(obstacle) -> int:
    """How many triangles an obstacle is drawn with, whole."""
    if obstacle.mesh is not None:
        return int(obstacle.mesh.tri.shape[0])
    return len(obstacle_mesh(obstacle).faces)


def display_obstacle(obstacle, max_faces: int = DISPLAY_FACES):
    """``display_mesh`` of an obstacle in the world frame. A mesh obstacle's drawing is
    kept in the disk cache under the hash of its triangles, its place and the count, so
    that a CAD scene's next tab neither merges its vertices nor decimates it again."""
    import trimesh  # noqa: PLC0415

    from pliant.util import cache  # noqa: PLC0415

    if obstacle.mesh is None:
        return display_mesh(obstacle_mesh(obstacle), max_faces)
    key = cache.digest(obstacle.mesh.tri.tobytes(), obstacle.rotation.tobytes(),
                       obstacle.translation.tobytes(), str(int(max_faces)).encode())
    kept = cache.load_arrays("drawn", key)
    if kept is not None and set(kept) == {"vertices", "faces"}:
        return trimesh.Trimesh(kept["vertices"], kept["faces"], process=False)
    drawn = display_mesh(obstacle_mesh(obstacle), max_faces)
    cache.save_arrays("drawn", key, vertices=np.asarray(drawn.vertices, dtype=float),
                      faces=np.asarray(drawn.faces, dtype=np.int64))
    return drawn


def obstacle_mesh(obstacle, halfspace_size: float = 2.0):
    """A trimesh of an obstacle in the world frame (a half-space as a square slab of
    ``halfspace_size`` [m] and 1 cm thick under its plane), for viewers and exports."""
    import trimesh  # noqa: PLC0415

    from pliant.scene.distance import BOX, CYLINDER, HALFSPACE, MESH, SPHERE  # noqa: PLC0415

    p = obstacle.param
    if obstacle.kind == SPHERE:
        mesh = trimesh.creation.icosphere(subdivisions=3, radius=p[0])
    elif obstacle.kind == BOX:
        mesh = trimesh.creation.box(extents=2.0 * p[:3])
    elif obstacle.kind == CYLINDER:
        mesh = trimesh.creation.cylinder(radius=p[0], height=2.0 * p[1], sections=48)
    elif obstacle.kind == HALFSPACE:
        mesh = trimesh.creation.box(extents=(halfspace_size, halfspace_size, 0.01))
        mesh.apply_translation((0.0, 0.0, -0.005))
    elif obstacle.kind == MESH:
        tri = obstacle.mesh.tri
        mesh = trimesh.Trimesh(vertices=tri.reshape(-1, 3),  # merged as it is made
                               faces=np.arange(tri.shape[0] * 3).reshape(-1, 3))
    else:  # pragma: no cover (every kind is above)
        raise ValueError(f"unknown obstacle kind {obstacle.kind}")
    transform = np.eye(4)
    transform[:3, :3] = obstacle.rotation
    transform[:3, 3] = obstacle.translation
    mesh.apply_transform(transform)
    return mesh


def export_scene(eq, path: str | Path, sides: int = 24) -> Path:
    """Write the deformed tube and its problem's obstacles to one glTF binary (.glb),
    each a named node (the part orange, the obstacles grey), atomically."""
    import trimesh  # noqa: PLC0415

    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise OutputError(f"cannot write {path}: a scene is written as a .glb file")
    points, frames = centreline_and_frames(eq)
    vertices, faces = tube_mesh(points, part_radius(eq), frames, sides=sides)
    scene = trimesh.Scene()
    part = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    part.visual.face_colors = (230, 120, 30, 255)  # type: ignore[union-attr]  # colour visuals
    scene.add_geometry(part, node_name=eq.problem.part.name or "part", geom_name="part")
    for obstacle in eq.problem.obstacles:
        mesh = obstacle_mesh(obstacle)
        mesh.visual.face_colors = (150, 155, 160, 255)
        scene.add_geometry(mesh, node_name=obstacle.name, geom_name=obstacle.name)
    return atomic_write(path, lambda handle: handle.write(scene.export(file_type="glb")),
                        "the scene")


def voxel_surface(voxels: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """The outer surface of a set of voxels (k, 3) int of edge ``size`` [m] (voxel
    (i, j, k) spans [i, i + 1) size along x, and so on): (vertices (v, 3) [m], triangles
    (t, 3)), only the faces between a filled voxel and an empty one."""
    voxels = np.asarray(voxels, dtype=np.int64).reshape(-1, 3)
    if voxels.shape[0] == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    lo = voxels.min(axis=0) - 1
    dims = voxels.max(axis=0) - lo + 2

    def key(v):
        v = v - lo
        return (v[:, 0] * dims[1] + v[:, 1]) * dims[2] + v[:, 2]

    filled = np.unique(key(voxels))
    # The unit cube's corners and, per direction, the face's corners (outward winding).
    faces = {(1, 0, 0): ((1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)),
             (-1, 0, 0): ((0, 0, 0), (0, 0, 1), (0, 1, 1), (0, 1, 0)),
             (0, 1, 0): ((0, 1, 0), (0, 1, 1), (1, 1, 1), (1, 1, 0)),
             (0, -1, 0): ((0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)),
             (0, 0, 1): ((0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)),
             (0, 0, -1): ((0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0))}
    quads = []
    for direction, corners in faces.items():
        outside = ~np.isin(key(voxels + np.array(direction)), filled)
        base = voxels[outside]
        quads.append(base[:, None, :] + np.array(corners)[None, :, :])
    quad = np.concatenate(quads)  # (q, 4, 3) integer corners
    vertices, inverse = np.unique(quad.reshape(-1, 3), axis=0, return_inverse=True)
    idx = inverse.reshape(-1, 4)
    tri = np.concatenate([idx[:, [0, 1, 2]], idx[:, [0, 2, 3]]])
    return vertices * float(size), tri.astype(np.int64)


def export_envelope(layers: list[tuple[str, np.ndarray, tuple[int, int, int, int]]],
                    size: float, path: str | Path) -> Path | None:
    """A GLB of voxel envelopes: each layer (name, voxels (k, 3), RGBA colour) as the
    surface of its voxels of edge ``size`` [m], in the scene's frame (as
    ``export_scene`` writes it, so that the two overlay). None, and nothing written,
    where every layer is empty (no sample was evaluated)."""
    import trimesh  # noqa: PLC0415

    from pliant.io.atomic import atomic_write  # noqa: PLC0415

    scene = trimesh.Scene()
    for name, voxels, colour in layers:
        vertices, faces = voxel_surface(voxels, size)
        if len(faces) == 0:
            continue
        mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
        colours = np.tile(np.array(colour, dtype=np.uint8), (len(faces), 1))
        mesh.visual.face_colors = colours  # type: ignore[union-attr]  # colour visuals
        scene.add_geometry(mesh, geom_name=name, node_name=name)
    if not scene.geometry:
        return None
    data = scene.export(file_type="glb")
    return atomic_write(path, lambda h: h.write(data), "the envelope")
