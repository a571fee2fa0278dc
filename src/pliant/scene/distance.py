"""Signed distances from points to the obstacles of a scene, with their gradients.

Primitives (sphere, box, capped cylinder, half-space) have exact closed-form distances
(``primitives``). A triangle mesh has two levels:

- a signed distance grid (``grid``: trilinear interpolation and its gradient), computed
  once per mesh (exact in a band round the surface, a Euclidean distance transform beyond
  it) and cached on disk under the hash of its vertices and faces: cheap, and within 2.6
  cells of the truth;
- an exact query (``triangles``: the closest triangle found through a bounding-volume
  tree; the sign from the angle-weighted pseudonormal of the closest feature, Baerentzen
  and Aanaes, IEEE TVCG 11(3), 2005), used wherever the grid says the surface may be
  closer than the caller's band (where contact is decided).

A mesh that is not closed has no inside: its distance is unsigned (a shell the part must
keep clear of). Every obstacle is packed into flat arrays (``Field``) so that the
accurate and real-time kernels can query the whole scene inside numba; this module packs
them and answers the queries over the whole scene (``query_points``, ``hessian_point``).
"""

from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from pliant.scene.grid import GRID_ERROR, fill_grid, grid_sample
from pliant.scene.primitives import (
    BOX,
    CYLINDER,
    HALFSPACE,
    MESH,
    SPHERE,
    primitive,
    primitive_hessian,
    to_local,
)
from pliant.scene.triangles import (
    CREASE,
    build_bvh,
    contact_normals,
    feature_hessian,
    mesh_feature,
    smooth_normal,
    smooth_rate,
)
from pliant.util import cache as disk
from pliant.util import progress


class Field(NamedTuple):
    """A scene's obstacles packed for the kernels (``DistanceField.args``): per obstacle
    its kind, rotation (3, 3) and translation (3,) into its local frame, parameters (4,)
    and mesh (-1: a primitive); the meshes' triangles (T, 3, 3), pseudo-normals
    (T, 7, 3), solidity and first triangle (tri_off); their bounding-volume trees
    (triangle order, node boxes, children, triangle ranges, first node); their distance
    grids (values, first value, origin, cell size, dimensions)."""

    kind: np.ndarray
    rot: np.ndarray
    trans: np.ndarray
    param: np.ndarray
    mesh_id: np.ndarray
    tri: np.ndarray
    pseudo: np.ndarray
    solid: np.ndarray
    tri_off: np.ndarray
    order: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    left: np.ndarray
    right: np.ndarray
    start: np.ndarray
    count: np.ndarray  # type: ignore[assignment]  # a field, over tuple.count
    node_off: np.ndarray
    g_values: np.ndarray
    g_off: np.ndarray
    g_origin: np.ndarray
    g_size: np.ndarray
    g_dims: np.ndarray
GRID_VERSION = 3
PSEUDO_ROWS = 12  # per triangle: pseudonormals (7), then smooth_normals (5)


# -- triangles -----------------------------------------------------------------------------


# -- primitives (local frame; scalars in and out: they run per point) ---------------------


@njit(cache=True)
def hessian_point(p, o, field):
    """The Hessian (3, 3, world frame) of obstacle o's signed distance at p: the rate
    at which its unit gradient (the contact normal) turns as p moves. Takes the same
    packed ``Field`` as ``query_point`` (the grids unused: contact is decided exactly)."""
    kind, rot, trans, param, mesh_id, tri = (field.kind, field.rot, field.trans,
                                             field.param, field.mesh_id, field.tri)
    R = rot[o]
    x, y, z = to_local(p, R, trans[o])
    if kind[o] == MESH:
        d, g, t, region = _packed_mesh_feature(x, y, z, mesh_id[o], field)
        Hl, smooth = smooth_rate(np.array([x, y, z]), d, g, t, region, tri, field.pseudo)
        if not smooth:  # the exact normal's rate, beyond its feature
            e = np.zeros(3)
            feature = 0
            if 1 <= region <= 3:
                a = tri[t, region - 1]
                b = tri[t, region % 3]
                size = max(math.sqrt((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2
                                     + (b[2] - a[2]) ** 2), 1e-300)
                for c in range(3):  # (written out: an array expression compiles slowly)
                    e[c] = (b[c] - a[c]) / size
                feature = 1
            elif region >= 4:
                feature = 2
            Hl = feature_hessian(d, g, e, feature)
    else:
        Hl = primitive_hessian(kind[o], x, y, z, param[o])
    H = np.zeros((3, 3))  # R Hl R^T, written out: numba's matrix product compiles slowly
    for i in range(3):
        for j in range(3):
            v = 0.0
            for k in range(3):
                for m in range(3):
                    v += R[i, k] * Hl[k, m] * R[j, m]
            H[i, j] = v
    return H


# -- grids ---------------------------------------------------------------------------------


# -- the whole scene -----------------------------------------------------------------------
@njit(cache=True, inline="always")
def _packed_mesh_feature(x, y, z, m, f):
    """``mesh_feature`` of packed mesh m of the ``Field`` f at the local point (x, y, z):
    (signed distance, unit gradient, the nearest triangle's index in ``f.tri``, its
    feature)."""
    t0, t1 = f.tri_off[m], f.tri_off[m + 1]
    n0, n1 = f.node_off[m], f.node_off[m + 1]
    bvh = (f.order[t0:t1], f.node_lo[n0:n1], f.node_hi[n0:n1], f.left[n0:n1],
           f.right[n0:n1], f.start[n0:n1], f.count[n0:n1])
    d, g, t, region = mesh_feature(np.array([x, y, z]), f.tri[t0:t1], f.pseudo[t0:t1],
                                    f.solid[m], bvh)
    return d, g, t0 + t, region


@njit(cache=True)
def query_point(p, band, field):
    """(signed distance, unit gradient x, y, z, obstacle) of the nearest obstacle to p
    (world frame): ``query_points`` for one point."""
    d, g, o = query_points(p.reshape(1, 3), band, field)
    return d[0], g[0, 0], g[0, 1], g[0, 2], o[0]


@njit(cache=True)
def query_points(points, band, field):
    """(signed distances (n,), unit gradients (n, 3), nearest obstacles (n,)) of points
    (n, 3), world frame. A mesh answers from its grid where the grid shows its surface
    farther than ``band`` beyond the grid's own error, else exactly. Obstacle by
    obstacle over all points: a call per point carrying the scene's many arrays would
    cost more than a primitive's distance. field: the scene's packed ``Field``."""
    kind, rot, trans, param, mesh_id = (field.kind, field.rot, field.trans, field.param,
                                        field.mesh_id)
    node_lo, node_hi, node_off = field.node_lo, field.node_hi, field.node_off
    g_values, g_off, g_origin, g_size, g_dims = (field.g_values, field.g_off, field.g_origin,
                                                 field.g_size, field.g_dims)
    n = points.shape[0]
    d = np.full(n, np.inf)
    g = np.zeros((n, 3))
    o = np.full(n, -1, dtype=np.int64)
    for ob in range(kind.shape[0]):
        R = rot[ob]
        t = trans[ob]
        prm = param[ob]
        k = kind[ob]
        for i in range(n):
            x, y, z = to_local(points[i], R, t)
            if k == MESH:
                m = mesh_id[ob]
                di, gx, gy, gz, outside = grid_sample(x, y, z, g_origin[m], g_size[m],
                                                      g_dims[m], g_values, g_off[m])
                # No surface lies nearer than this: the grid's bound, or outside the grid
                # the distance to the mesh's box (its tree's root).
                lower = di
                if outside > 0.0:
                    n0 = node_off[m]
                    cx = max(node_lo[n0, 0] - x, 0.0, x - node_hi[n0, 0])
                    cy = max(node_lo[n0, 1] - y, 0.0, y - node_hi[n0, 1])
                    cz = max(node_lo[n0, 2] - z, 0.0, z - node_hi[n0, 2])
                    lower = max(di - outside, math.sqrt(cx * cx + cy * cy + cz * cz))
                    di += outside
                if lower <= band + GRID_ERROR * g_size[m] and lower < d[i]:
                    di, gm, tm, rm = _packed_mesh_feature(x, y, z, m, field)
                    _, gx, gy, gz = smooth_normal((x, y, z), di, (gm[0], gm[1], gm[2]), tm,
                                                  rm, field.tri, field.pseudo)
            else:
                di, gx, gy, gz = primitive(k, x, y, z, prm)
            if di < d[i]:
                d[i] = di
                g[i, 0] = R[0, 0] * gx + R[0, 1] * gy + R[0, 2] * gz
                g[i, 1] = R[1, 0] * gx + R[1, 1] * gy + R[1, 2] * gz
                g[i, 2] = R[2, 0] * gx + R[2, 1] * gy + R[2, 2] * gz
                o[i] = ob
    return d, g, o


# -- Python side ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MeshData:
    """A triangle mesh ready for queries, in its own frame: triangles, pseudonormals
    (face, 3 edges, 3 vertices per triangle), whether it is closed, its box tree
    (order, lo, hi, left, right, start, count) and its signed distance grid."""

    tri: np.ndarray
    pseudo: np.ndarray
    solid: bool
    bvh: tuple
    g_values: np.ndarray
    g_origin: np.ndarray
    g_size: float
    g_dims: np.ndarray

    @property
    def bounds(self) -> np.ndarray:
        flat = self.tri.reshape(-1, 3)
        return np.array([flat.min(axis=0), flat.max(axis=0)])


LARGEST_MESH = 1.0e5  # m: a mesh wider than this is in the wrong unit


def check_mesh(vertices: np.ndarray, faces: np.ndarray) -> None:
    """A mesh an obstacle can be made of: finite vertices (v, 3), triangles (f, 3) that
    index them, and a surface (not every triangle degenerate); else a ValueError that
    says what is wrong."""
    if vertices.ndim != 2 or vertices.shape[1] != 3 or vertices.shape[0] < 3:
        raise ValueError("the mesh needs vertices (v, 3), at least 3 of them")
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise ValueError(f"the mesh has {bad} vertices that are not finite numbers (NaN or "
                         "inf); repair or re-export it")
    if faces.ndim != 2 or faces.shape[1] != 3 or faces.shape[0] == 0:
        raise ValueError("the mesh needs triangles (f, 3)")
    if faces.min() < 0 or faces.max() >= vertices.shape[0]:
        raise ValueError("the mesh's triangles index vertices it does not have")
    extent = float(np.ptp(vertices, axis=0).max())
    if not extent <= LARGEST_MESH:
        raise ValueError(f"the mesh spans {extent:.3g} m, more than {LARGEST_MESH:g} m: check "
                         "its unit (the obstacle's scale, or the scene's units)")
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not area.sum() > 1e-12 * max(extent, 1e-300) ** 2:
        raise ValueError("the mesh has no surface: every triangle is degenerate (no area)")


def prepare_mesh(vertices: np.ndarray, faces: np.ndarray, resolution: int = 64,
                 cache: bool = True, crease: float = CREASE) -> MeshData:
    """Pseudonormals (and the smoothing groups of faces meeting within ``crease``
    degrees, ``smooth_normals``), box tree and signed distance grid of a mesh (the grid cached on
    disk under the hash of the mesh and the resolution; for a mesh of LARGE_MESH
    triangles or more, the pseudonormals and the tree too). Its progress is reported in
    triangles (``pliant.util.progress``), each step by its share of the build."""
    triangles = int(np.shape(faces)[0]) if np.ndim(faces) == 2 else 0
    with progress.work(triangles):
        def done(share: float) -> None:
            progress.advance(share * triangles)

        vertices = np.ascontiguousarray(vertices, dtype=float)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        check_mesh(vertices, faces)
        tri = np.ascontiguousarray(vertices[faces])
        digest = disk.digest(vertices.tobytes(), faces.tobytes())
        done(_SHARE["check"])
        structure = f"{digest}-{GRID_VERSION}-{crease!r}"
        large = cache and faces.shape[0] >= LARGE_MESH
        pseudo, solid, bvh = _load_structure(structure, faces.shape[0]) if large else (
            None, False, ())
        if pseudo is None:
            pseudo, solid = contact_normals(vertices, faces, crease)
            done(_SHARE["pseudonormals"])
            bvh = build_bvh(tri)
            done(_SHARE["tree"])
            if large:
                _save_structure(structure, pseudo, solid, bvh)
        else:
            done(_SHARE["pseudonormals"] + _SHARE["tree"])
        done(_SHARE["save"])
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        extent = max(float((hi - lo).max()), 1e-9)
        # Distance grid: a margin of a tenth of the extent round the mesh.
        g_size = extent * 1.2 / (resolution - 1)
        g_origin = lo - 0.1 * extent
        g_dims = np.ceil((hi - lo + 0.2 * extent) / g_size).astype(np.int64) + 1
        path = disk.cache_dir() / "sdf" / f"{digest}-{resolution}-{GRID_VERSION}.npy"
        values = None
        if cache and path.is_file():
            try:
                values = np.load(path)
                if values.shape != (int(np.prod(g_dims)),):
                    values = None
            except (OSError, ValueError):
                values = None
        if values is None:
            values = fill_grid(g_origin, g_size, g_dims, tri, pseudo, solid, bvh)
            if cache:
                _save_grid(path, values)
        done(_SHARE["grid"])
    return MeshData(tri, pseudo, solid, bvh, values, g_origin, g_size, g_dims)


# Each step's share of a large mesh's build, measured at 1.3 M triangles (check and hash
# 0.4 s, pseudonormals 0.8 s, tree 0.75 s, writing them 0.8 s, the grid 0.9 s).
_SHARE = {"check": 0.1, "pseudonormals": 0.22, "tree": 0.2, "save": 0.2, "grid": 0.28}


LARGE_MESH = 100_000  # triangles from which the tree and pseudonormals are cached too
_TREE = ("order", "lo", "hi", "left", "right", "start", "count")


def _load_structure(key: str, triangles: int) -> tuple[np.ndarray | None, bool, tuple]:
    """A large mesh's pseudonormals, closedness and box tree from the disk cache (a CAD
    part loaded again: seconds saved), or (None, False, ()) when absent or unreadable."""
    data = disk.load_arrays("mesh", key)
    if data is None or not {"pseudo", "solid", *_TREE} <= set(data):
        return None, False, ()
    pseudo, bvh = data["pseudo"], tuple(data[k] for k in _TREE)
    if pseudo.shape != (triangles, PSEUDO_ROWS, 3) or bvh[0].shape != (triangles,):
        return None, False, ()
    return pseudo, bool(data["solid"]), bvh


def _save_structure(key: str, pseudo: np.ndarray, solid: bool, bvh: tuple) -> None:
    """Best effort, written whole or not at all (``pliant.util.cache``)."""
    disk.save_arrays("mesh", key, pseudo=pseudo, solid=np.array(solid),
                     **dict(zip(_TREE, bvh)))


def _save_grid(path: Path, values: np.ndarray) -> None:
    """Best effort: a cache that cannot be written only costs time."""
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as handle:
            np.save(handle, values)
        os.replace(tmp, path)
    except OSError:
        disk.discard(tmp)  # a full disk leaves no half-written file behind


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A rigid obstacle: a primitive or a mesh, placed by a rotation and a translation
    (local to world: x = R x_local + t). param: sphere (radius), box (half sizes),
    cylinder (radius, half length, along local z), half-space (none: solid below the
    local plane z = 0)."""

    name: str
    kind: int
    rotation: np.ndarray
    translation: np.ndarray
    param: np.ndarray
    mesh: MeshData | None = None
    friction: float = 0.0  # Coulomb's coefficient between it and the part
    # A flexible part already fitted (pliant.core.problem.FittedPart) whose tube at rest
    # this is: the accurate model solves it with the part that touches it.
    fitted: object = None

    # By value (what it is, not which object): a scene read again gives equal obstacles,
    # so a problem read back from its file equals the one written and a warm start
    # carries over. The identity test first: the solver compares them at every step.
    def __eq__(self, other: object) -> bool:
        if self is other:
            return True
        if not isinstance(other, Obstacle):
            return NotImplemented
        return (self.name == other.name and self.kind == other.kind
                and self.friction == other.friction
                and np.array_equal(self.rotation, other.rotation)
                and np.array_equal(self.translation, other.translation)
                and np.array_equal(self.param, other.param)
                and _same_mesh(self.mesh, other.mesh) and _same_fitted(self.fitted, other.fitted))

    def __hash__(self) -> int:
        return hash((self.name, self.kind, self.translation.tobytes(), self.param.tobytes()))

    def with_friction(self, mu: float) -> Obstacle:
        """This obstacle with Coulomb friction ``mu`` (>= 0) against the part."""
        if not (math.isfinite(mu) and mu >= 0.0):
            raise ValueError(f"friction: {mu!r} must be a finite number >= 0")
        return replace(self, friction=float(mu))

    @staticmethod
    def sphere(name: str, radius: float, center) -> Obstacle:
        return Obstacle(name, SPHERE, np.eye(3), np.asarray(center, float),
                        np.array([radius, 0.0, 0.0, 0.0]))

    @staticmethod
    def box(name: str, size, position, rotation=None) -> Obstacle:
        half = 0.5 * np.asarray(size, float)
        return Obstacle(name, BOX, _rot(rotation), np.asarray(position, float),
                        np.array([*half, 0.0]))

    @staticmethod
    def cylinder(name: str, radius: float, length: float, position, rotation=None) -> Obstacle:
        return Obstacle(name, CYLINDER, _rot(rotation), np.asarray(position, float),
                        np.array([radius, 0.5 * length, 0.0, 0.0]))

    @staticmethod
    def halfspace(name: str, point, normal) -> Obstacle:
        """Solid on the side opposite ``normal`` of the plane through ``point``."""
        return Obstacle(name, HALFSPACE, _frame_with_z(normal), np.asarray(point, float),
                        np.zeros(4))

    @staticmethod
    def from_mesh(name: str, vertices, faces, position=(0.0, 0.0, 0.0), rotation=None,
                  resolution: int = 64, crease: float = CREASE) -> Obstacle:
        """A triangle mesh; faces meeting within ``crease`` degrees are read as one
        smooth surface by a contact (``triangles.smooth_normal``; 0: every facet flat,
        every edge sharp)."""
        if not 0.0 <= crease < 90.0:
            raise ValueError(f"crease must be from 0 to 90 degrees, not {crease}")
        return Obstacle(name, MESH, _rot(rotation), np.asarray(position, float),
                        np.zeros(4), prepare_mesh(vertices, faces, resolution, crease=crease))


def _same_mesh(a: MeshData | None, b: MeshData | None) -> bool:
    """The same triangles (and so the same mesh: the rest is made from them)."""
    if a is b:
        return True
    return a is not None and b is not None and a.solid == b.solid and np.array_equal(
        a.tri, b.tri)


def _same_fitted(a, b) -> bool:
    """The same part already fitted: its problem, element count and friction."""
    if a is b:
        return True
    return a is not None and b is not None and (a.name, a.elements, a.friction) == (
        b.name, b.elements, b.friction) and a.problem == b.problem


def _rot(rotation) -> np.ndarray:
    if rotation is None:
        return np.eye(3)
    R = np.asarray(rotation, float)
    if R.shape != (3, 3) or not np.allclose(R.T @ R, np.eye(3), atol=1e-9):
        raise ValueError("a rotation must be a 3 x 3 orthonormal matrix")
    return R


def _frame_with_z(normal) -> np.ndarray:
    z = np.asarray(normal, float)
    z = z / np.linalg.norm(z)
    a = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = a - (a @ z) * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


_FIELDS: dict[tuple[int, ...], tuple[tuple[Obstacle, ...], DistanceField]] = {}
_FIELDS_KEPT = 8  # scenes whose packed fields are kept (a tab's session uses one)
_FIELDS_LOCK = threading.Lock()


def field_of(obstacles) -> DistanceField:
    """The scene's ``DistanceField``, packed once per set of obstacle objects: a CAD
    scene's packing copies hundreds of megabytes (1.5 s at 1.6 M triangles), which
    every solve would otherwise pay. Keyed by the obstacles' identity (they are
    immutable), the few most recent kept."""
    obstacles = tuple(obstacles)
    key = tuple(id(o) for o in obstacles)
    with _FIELDS_LOCK:  # the viewer's tabs open their scenes from threads
        hit = _FIELDS.pop(key, None)
    if hit is None or any(a is not b for a, b in zip(hit[0], obstacles)):
        hit = (obstacles, DistanceField(list(obstacles)))
    with _FIELDS_LOCK:
        _FIELDS[key] = hit  # the most recent last
        while len(_FIELDS) > _FIELDS_KEPT:
            del _FIELDS[next(iter(_FIELDS))]
    return hit[1]


class DistanceField:
    """The signed distance to the nearest of a scene's obstacles, for batches of points
    (``query``) and, packed in ``args``, inside numba kernels (``query_point``)."""

    def __init__(self, obstacles: list[Obstacle]) -> None:
        self.obstacles = list(obstacles)
        m = len(self.obstacles)
        self.friction = np.array([o.friction for o in self.obstacles], dtype=float)
        meshes = [o.mesh for o in self.obstacles if o.mesh is not None]
        mesh_id = np.full(m, -1, dtype=np.int64)
        k = 0
        for i, o in enumerate(self.obstacles):
            if o.mesh is not None:
                mesh_id[i] = k
                k += 1
        kind = np.array([o.kind for o in self.obstacles], dtype=np.int64)
        rot = np.array([o.rotation for o in self.obstacles]).reshape(m, 3, 3)
        trans = np.array([o.translation for o in self.obstacles]).reshape(m, 3)
        param = np.array([o.param for o in self.obstacles]).reshape(m, 4)

        def cat(arrays, shape, dtype=float):
            return np.concatenate(arrays) if arrays else np.zeros(shape, dtype=dtype)

        def offsets(sizes):
            return np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)

        tri = cat([x.tri for x in meshes], (0, 3, 3))
        pseudo = cat([x.pseudo for x in meshes], (0, PSEUDO_ROWS, 3))
        trees = [x.bvh for x in meshes]
        self.args = Field(
            kind, rot, trans, param, mesh_id, tri, pseudo,
            np.array([x.solid for x in meshes], dtype=np.bool_),
            offsets([x.tri.shape[0] for x in meshes]),
            cat([b[0] for b in trees], (0,), np.int64),
            cat([b[1] for b in trees], (0, 3)), cat([b[2] for b in trees], (0, 3)),
            cat([b[3] for b in trees], (0,), np.int64), cat([b[4] for b in trees], (0,), np.int64),
            cat([b[5] for b in trees], (0,), np.int64), cat([b[6] for b in trees], (0,), np.int64),
            offsets([b[1].shape[0] for b in trees]),
            cat([x.g_values for x in meshes], (0,)),
            offsets([x.g_values.shape[0] for x in meshes]),
            np.array([x.g_origin for x in meshes]).reshape(-1, 3),
            np.array([x.g_size for x in meshes], dtype=float),
            np.array([x.g_dims for x in meshes], dtype=np.int64).reshape(-1, 3),
        )

    def __len__(self) -> int:
        return len(self.obstacles)

    def query(self, points, band: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distances (n,), unit gradients (n, 3), obstacle indices (n,)) of
        points (n, 3) [m]; exact within ``band`` of a mesh's surface."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=float)
        if not self.obstacles:
            n = points.shape[0]
            return np.full(n, np.inf), np.zeros((n, 3)), np.full(n, -1, dtype=np.int64)
        return query_points(points, float(band), self.args)

    def query_one(self, k: int, points, band: float = 0.0
                  ) -> tuple[np.ndarray, np.ndarray]:
        """(signed distances (n,), unit gradients (n, 3)) of points (n, 3) [m] to the
        ``k``-th obstacle alone: the packed arrays as they are, only the obstacle list
        cut to it (no copy of a mesh)."""
        points = np.ascontiguousarray(np.atleast_2d(points), dtype=float)
        one = slice(k, k + 1)
        args = self.args._replace(**{name: getattr(self.args, name)[one]
                                     for name in Field._fields[:5]})
        d, g, _ = query_points(points, float(band), args)
        return d, g
