"""Signed distances: exact mesh queries against a brute-force twin (every triangle, and
the winding number for the sign), grids within their error bound, gradients against
finite differences, primitives against meshes of the same shape, the disk cache."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from pliant.scene import distance
from pliant.scene.distance import GRID_ERROR, DistanceField, Obstacle
from pliant.scene.triangles import closest_on_triangle


@njit(cache=True)
def brute_unsigned(points, tri):
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        best = np.inf
        for t in range(tri.shape[0]):
            qx, qy, qz, _ = closest_on_triangle(points[i], tri[t, 0], tri[t, 1], tri[t, 2])
            best = min(best, (points[i, 0] - qx) ** 2 + (points[i, 1] - qy) ** 2
                       + (points[i, 2] - qz) ** 2)
        out[i] = np.sqrt(best)
    return out


@njit(cache=True)
def winding(points, tri):
    """The generalised winding number (Van Oosterom and Strackee's solid angles)."""
    out = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        w = 0.0
        for t in range(tri.shape[0]):
            a = tri[t, 0] - points[i]
            b = tri[t, 1] - points[i]
            c = tri[t, 2] - points[i]
            la, lb, lc = np.sqrt(a @ a), np.sqrt(b @ b), np.sqrt(c @ c)
            num = a @ np.cross(b, c)
            den = la * lb * lc + (a @ b) * lc + (b @ c) * la + (c @ a) * lb
            w += 2.0 * np.arctan2(num, den)
        out[i] = w / (4.0 * np.pi)
    return out


def twin(points, mesh, solid=True):
    tri = np.asarray(mesh.triangles)
    d = brute_unsigned(points, tri)
    return np.where(winding(points, tri) > 0.5, -d, d) if solid else d


@pytest.fixture(autouse=True)
def private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("PLIANT_CACHE", str(tmp_path / "cache"))


SHAPES = {
    "icosphere": trimesh.creation.icosphere(subdivisions=3, radius=0.1),
    "box": trimesh.creation.box(extents=(0.3, 0.1, 0.2)),
    "torus": trimesh.creation.torus(major_radius=0.1, minor_radius=0.03),
}


@pytest.mark.parametrize("name", list(SHAPES))
def test_mesh_distances_match_the_brute_force_twin(name):
    """Near the surface (within the band) the query is exact: every triangle's closest
    point, signed by the winding number, to 1e-12 m; away from it the grid is within
    its stated error; the sign is right everywhere (an angle-weighted pseudonormal
    decides it, also at edges and vertices)."""
    mesh = SHAPES[name]
    field = DistanceField([Obstacle.from_mesh(name, mesh.vertices, mesh.faces,
                                              position=(0.0, 0.0, 0.0))])
    rng = np.random.default_rng(7)
    surface = mesh.sample(300, seed=3) if hasattr(mesh, "sample") else None
    near = surface + rng.normal(scale=0.01, size=surface.shape)
    far = rng.uniform(-0.4, 0.4, size=(300, 3))
    band = 0.03
    data = field.obstacles[0].mesh
    h = data.g_size
    top = data.g_origin + (data.g_dims - 1) * h
    for points in (near, far):
        d, _, _ = field.query(points, band=band)
        truth = twin(points, mesh)
        exact = np.abs(truth) <= band
        assert np.allclose(d[exact], truth[exact], atol=1e-12)
        inside = np.all((points >= data.g_origin) & (points <= top), axis=1)
        grid = ~exact & inside
        assert np.all(np.abs(d[grid] - truth[grid]) <= GRID_ERROR * h + 1e-12)
        # Beyond the grid: an upper bound, never below the truth.
        assert np.all(d[~exact & ~inside] >= truth[~exact & ~inside] - 1e-12)
        assert np.all(np.sign(d[np.abs(truth) > 1e-9]) == np.sign(truth[np.abs(truth) > 1e-9]))


def test_gradients_match_finite_differences():
    """The exact gradients (a mesh with every edge sharp: ``crease = 0``; the normals a
    smoothed mesh gives are tested below)."""
    mesh = SHAPES["torus"]
    field = DistanceField([Obstacle.from_mesh("t", mesh.vertices, mesh.faces, crease=0.0),
                           Obstacle.cylinder("c", 0.05, 0.2, (0.3, 0.0, 0.0)),
                           Obstacle.box("b", (0.1, 0.2, 0.1), (-0.3, 0.0, 0.0),
                                        rotation=_rotation((1, 1, 0), 0.4)),
                           Obstacle.sphere("s", 0.05, (0.0, 0.3, 0.0))])
    rng = np.random.default_rng(2)
    points = rng.uniform(-0.4, 0.4, size=(200, 3))
    _d, g, _ = field.query(points, band=1.0)
    eps = 1e-7
    fd = np.column_stack([(field.query(points + eps * e, band=1.0)[0]
                           - field.query(points - eps * e, band=1.0)[0]) / (2 * eps)
                          for e in np.eye(3)])
    smooth = np.linalg.norm(fd, axis=1) > 0.999  # off the medial axis and the kinks
    assert smooth.mean() > 0.9
    assert np.allclose(g[smooth], fd[smooth], atol=1e-5)
    assert np.allclose(np.linalg.norm(g, axis=1), 1.0)


def test_hessians_match_finite_differences_of_the_gradient():
    """The contact Jacobian's curvature term: each obstacle's exact piecewise Hessian
    against central differences of its gradient at random points (none within the step of
    a seam between pieces), symmetric, with the gradient in its null space (a mesh with
    every edge sharp, ``crease = 0``)."""
    mesh = SHAPES["torus"]
    obstacles = [Obstacle.from_mesh("t", mesh.vertices, mesh.faces, crease=0.0),
                 Obstacle.cylinder("c", 0.05, 0.2, (0.3, 0.0, 0.0), _rotation((0, 1, 1), 0.7)),
                 Obstacle.box("b", (0.1, 0.2, 0.1), (-0.3, 0.0, 0.0),
                              rotation=_rotation((1, 1, 0), 0.4)),
                 Obstacle.sphere("s", 0.05, (0.0, 0.3, 0.0))]
    rng = np.random.default_rng(5)
    eps = 1e-7
    for o, obstacle in enumerate(obstacles):
        field = DistanceField(obstacles)
        args = field.args
        checked = 0
        for p in obstacle.translation + rng.normal(scale=0.12, size=(150, 3)):
            d, *g, nearest = distance.query_point(p, 1.0, args)
            if nearest != o or d < 0.0:
                continue
            H = distance.hessian_point(p, o, args)
            fd = np.column_stack([
                (np.array(distance.query_point(p + eps * e, 1.0, args)[1:4])
                 - np.array(distance.query_point(p - eps * e, 1.0, args)[1:4])) / (2 * eps)
                for e in np.eye(3)])
            checked += 1
            assert np.allclose(H, fd, atol=1e-4 * max(1.0, np.abs(fd).max()))
            assert np.allclose(H, H.T, atol=1e-9) and np.abs(H @ np.array(g)).max() < 1e-9
        assert checked > 40


def _normal_turn(a, b):
    return np.arccos(np.clip(np.einsum("ik,ik->i", a, b), -1.0, 1.0))


def test_a_dense_mesh_reads_as_the_smooth_surface_it_tessellates():
    """A cylinder in 1,024 facets (0.35 degrees apart, under the default crease): near
    its side the contact normal is the cylinder's to within the facet angle times
    (distance / radius) (the interpolation's lean at the closest point's place), where
    the same mesh with every edge sharp leans by up to half a facet's angle (its face
    normals); along a circle round it the smoothed normal turns across the faces,
    where the sharp one stays put across each face and turns in the thin wedge beyond
    each edge. The distance is the mesh's exact one either way."""
    sections, radius = 1024, 0.05
    cyl = trimesh.creation.cylinder(radius=radius, height=0.4, sections=sections)
    smooth = DistanceField([Obstacle.from_mesh("s", cyl.vertices, cyl.faces)])
    sharp = DistanceField([Obstacle.from_mesh("f", cyl.vertices, cyl.faces, crease=0.0)])
    facet = 2 * np.pi / sections
    rng = np.random.default_rng(7)
    phi = rng.uniform(0.0, 2 * np.pi, 400)
    out = rng.uniform(0.001, 0.015, 400)
    points = np.column_stack([(radius + out) * np.cos(phi), (radius + out) * np.sin(phi),
                              rng.uniform(-0.1, 0.1, 400)])
    radial = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(400)])
    d_s, n_s, _ = smooth.query(points, band=1.0)
    d_f, n_f, _ = sharp.query(points, band=1.0)
    assert np.array_equal(d_s, d_f)
    lean = _normal_turn(n_s, radial)
    assert np.all(lean <= facet * (out / radius + 0.01))
    assert _normal_turn(n_f, radial).max() > 0.4 * facet
    # Along an arc two facets long at 10 mm out: the sharp normal stands still over
    # each face's part of it and turns 6x the cylinder's rate (0.06 m / 0.01 m) across
    # the wedge beyond each edge; the smoothed one turns over the faces' part (at most
    # 1.2 / (1 - 0.01 / 0.06) = 1.44 times the rate), standing only over the wedges.
    arc = 0.3 + np.linspace(0.0, 2 * facet, 801)
    ring = np.column_stack([0.06 * np.cos(arc), 0.06 * np.sin(arc), np.zeros(801)])

    def rate(field):
        n = field.query(ring, band=1.0)[1]
        return _normal_turn(n[1:], n[:-1]) / np.diff(arc)

    rate_s, rate_f = rate(smooth), rate(sharp)
    assert rate_s.max() < 1.6 and np.mean(rate_s < 1e-6) < 0.25
    assert rate_f.max() > 4.0 and np.mean(rate_f < 1e-6) > 0.6


@pytest.mark.parametrize("name", ["torus", "icosphere"])
def test_smoothed_normals_rates_match_finite_differences(name):
    """The contact Jacobian's curvature term on a smoothed mesh: the interpolated
    normal's rate (``triangles.smooth_rate``) against central differences of the
    normal the query gives, at random points near the surface (the torus in 32 x 32
    facets 11 degrees apart smooths only across its quads' diagonals; the icosphere,
    6 degrees apart, all over)."""
    mesh = SHAPES[name]
    field = DistanceField([Obstacle.from_mesh("m", mesh.vertices, mesh.faces)])
    args = field.args
    assert 0.0 < args.pseudo[:, 10].mean() <= 1.0  # some edges smoothed
    rng = np.random.default_rng(11)
    on, face = trimesh.sample.sample_surface(mesh, 300, seed=3)
    points = on + mesh.face_normals[face] * rng.uniform(0.002, 0.02, (300, 1))
    eps, checked = 1e-7, 0
    for p in points:
        H = distance.hessian_point(p, 0, args)
        fd = np.column_stack([
            (np.array(distance.query_point(p + eps * e, 1.0, args)[1:4])
             - np.array(distance.query_point(p - eps * e, 1.0, args)[1:4])) / (2 * eps)
            for e in np.eye(3)])
        checked += bool(np.allclose(H, fd, atol=1e-4 * max(1.0, np.abs(fd).max())))
    assert checked >= 0.97 * len(points)  # (a difference may straddle a piece's seam)


def test_primitives_against_meshes_of_the_same_shape():
    """A box primitive is exactly its box mesh; a cylinder primitive is its fine mesh to
    within the tessellation's sagitta; rotated and moved consistently."""
    R = _rotation((1.0, 2.0, 0.5), 0.7)
    t = np.array([0.1, -0.2, 0.3])
    box = trimesh.creation.box(extents=(0.3, 0.1, 0.2))
    cyl = trimesh.creation.cylinder(radius=0.05, height=0.2, sections=256)
    rng = np.random.default_rng(4)
    points = t + rng.uniform(-0.3, 0.3, size=(400, 3))
    exact = [Obstacle.box("p", (0.3, 0.1, 0.2), t, R), Obstacle.cylinder("c", 0.05, 0.2, t, R)]
    meshes = [Obstacle.from_mesh("m", box.vertices, box.faces, t, R),
              Obstacle.from_mesh("m", cyl.vertices, cyl.faces, t, R)]
    sagitta = 0.05 * (1 - np.cos(np.pi / 256))
    for prim, mesh, tol in zip(exact, meshes, (1e-12, sagitta + 1e-12)):
        a = DistanceField([prim]).query(points, band=1.0)[0]
        b = DistanceField([mesh]).query(points, band=1.0)[0]
        assert np.abs(a - b).max() <= tol
    plane = DistanceField([Obstacle.halfspace("floor", (0, 0, -0.1), (0, 0, 1))])
    assert np.allclose(plane.query(points)[0], points[:, 2] + 0.1)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(axis=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda v: np.linalg.norm(v) > 0.1),
       angle=st.floats(-3.0, 3.0), shift=st.tuples(*[st.floats(-1, 1)] * 3))
def test_distances_move_with_their_obstacle(axis, angle, shift):
    """A rigid motion of the obstacle and the points together leaves distances alone
    and turns gradients with it."""
    R = _rotation(axis, angle)
    t = np.asarray(shift)
    rng = np.random.default_rng(0)
    points = rng.uniform(-0.3, 0.3, size=(50, 3))
    shapes = [lambda R, t: Obstacle.box("b", (0.2, 0.1, 0.05), t, R),
              lambda R, t: Obstacle.cylinder("c", 0.05, 0.2, t, R)]
    for make in shapes:
        d0, g0, _ = DistanceField([make(np.eye(3), np.zeros(3))]).query(points)
        d1, g1, _ = DistanceField([make(R, t)]).query(points @ R.T + t)
        assert np.allclose(d0, d1, atol=1e-12)
        assert np.allclose(g0 @ R.T, g1, atol=1e-9)


def test_open_meshes_are_shells_and_grids_are_cached(tmp_path):
    sheet = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                            faces=[[0, 1, 2], [0, 2, 3]])
    field = DistanceField([Obstacle.from_mesh("sheet", sheet.vertices, sheet.faces)])
    d, _, _ = field.query([[0.5, 0.5, -0.2], [0.5, 0.5, 0.2]], band=1.0)
    assert np.allclose(d, 0.2)  # no inside: both sides are outside
    mesh = SHAPES["icosphere"]
    before = set((tmp_path / "cache" / "sdf").glob("*.npy"))
    first = distance.prepare_mesh(mesh.vertices, mesh.faces)
    cached = list(set((tmp_path / "cache" / "sdf").glob("*.npy")) - before)
    assert len(cached) == 1
    cached[0].write_bytes(b"not a grid")  # a broken cache is recomputed, not trusted
    again = distance.prepare_mesh(mesh.vertices, mesh.faces)
    assert np.array_equal(first.g_values, again.g_values)
    third = distance.prepare_mesh(mesh.vertices, mesh.faces)
    assert np.array_equal(first.g_values, third.g_values)


def test_a_large_meshs_tree_and_pseudonormals_are_cached_too(tmp_path, monkeypatch):
    monkeypatch.setattr(distance, "LARGE_MESH", 100)  # this sphere counts as large
    mesh = SHAPES["icosphere"]
    first = distance.prepare_mesh(mesh.vertices, mesh.faces)
    (stored,) = (tmp_path / "cache" / "mesh").glob("*.npz")
    build = distance.build_bvh
    monkeypatch.setattr(distance, "build_bvh", None)  # a second load must not build
    again = distance.prepare_mesh(mesh.vertices, mesh.faces)
    assert np.array_equal(first.pseudo, again.pseudo) and again.solid == first.solid
    assert all(np.array_equal(a, b) for a, b in zip(first.bvh, again.bvh))
    stored.write_bytes(b"not an archive")  # a broken cache is rebuilt, not trusted
    monkeypatch.setattr(distance, "build_bvh", build)
    rebuilt = distance.prepare_mesh(mesh.vertices, mesh.faces)
    assert all(np.array_equal(a, b) for a, b in zip(first.bvh, rebuilt.bvh))


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_a_scenes_field_is_packed_once_per_set_of_obstacles():
    """field_of: the same obstacle objects give the same packed field (a CAD scene's
    packing costs seconds); other objects, even equal in shape, a new one."""
    from pliant.scene.distance import Obstacle, field_of

    ball = Obstacle.sphere("ball", 0.1, (0.0, 0.0, 0.0))
    box = Obstacle.box("box", (0.1, 0.1, 0.1), (0.5, 0.0, 0.0))
    first = field_of((ball, box))
    assert field_of([ball, box]) is first
    assert field_of((box, ball)) is not first
    other = field_of((Obstacle.sphere("ball", 0.1, (0.0, 0.0, 0.0)), box))
    assert other is not first
    assert np.allclose(other.query(np.array([[0.3, 0.0, 0.0]]))[0], 0.15)


def test_one_obstacles_distance_from_the_scenes_field_is_its_own():
    """query_one(k): the k-th obstacle alone, from the scene's packed arrays (no copy),
    equal to a field of that obstacle only, meshes included."""
    import trimesh

    from pliant.scene.distance import DistanceField, Obstacle

    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    obstacles = [Obstacle.box("box", (0.2, 0.2, 0.2), (0.5, 0.0, 0.0)),
                 Obstacle.from_mesh("ball", ball.vertices, ball.faces, (-0.4, 0.0, 0.0)),
                 Obstacle.sphere("sphere", 0.05, (0.0, 0.4, 0.0))]
    scene = DistanceField(obstacles)
    points = np.random.default_rng(5).uniform(-0.6, 0.6, (200, 3))
    for k, obstacle in enumerate(obstacles):
        d, g = scene.query_one(k, points, band=0.05)
        alone, g_alone, _ = DistanceField([obstacle]).query(points, band=0.05)
        assert np.array_equal(d, alone) and np.array_equal(g, g_alone)


def test_mesh_files_and_display_meshes_are_kept_by_content(tmp_path, monkeypatch):
    """A mesh file is parsed once: read again, its vertices and faces come from the disk
    cache (trimesh is not called); changed, it is parsed afresh. A mesh obstacle's
    drawing is kept the same way, per triangle count (decimated once)."""
    import trimesh as tm

    from pliant.io import problem_file
    from pliant.io.mesh_export import display_obstacle

    ball = tm.creation.icosphere(subdivisions=4, radius=0.1)
    path = tmp_path / "ball.stl"
    ball.export(path)
    vertices, faces = problem_file.read_mesh("ball.stl", tmp_path)
    calls = []
    real = tm.load
    monkeypatch.setattr(tm, "load", lambda *a, **k: (calls.append(a), real(*a, **k))[1])
    again = problem_file.read_mesh("ball.stl", tmp_path)
    assert calls == [] and np.array_equal(again[0], vertices) and np.array_equal(
        again[1], faces)
    tm.creation.icosphere(subdivisions=3, radius=0.2).export(path)  # the file changes
    changed = problem_file.read_mesh("ball.stl", tmp_path)
    assert len(calls) == 1 and len(changed[1]) == 1280
    obstacle = Obstacle.from_mesh("ball", ball.vertices, ball.faces, (0.1, 0.0, 0.0))
    decimated = []
    simplify = tm.Trimesh.simplify_quadric_decimation
    monkeypatch.setattr(tm.Trimesh, "simplify_quadric_decimation",
                        lambda self, **k: (decimated.append(k), simplify(self, **k))[1])
    drawn = display_obstacle(obstacle, 1000)
    kept = display_obstacle(obstacle, 1000)
    assert len(decimated) == 1  # the second drawing came from the disk cache
    assert len(drawn.faces) <= 1000 and np.array_equal(kept.vertices, drawn.vertices)
    assert np.array_equal(kept.faces, drawn.faces)
    assert len(display_obstacle(obstacle, 500).faces) <= 500  # another count, another entry


def _pseudonormals_by_definition(vertices, faces):
    """Baerentzen and Aanaes's pseudonormals, one face, edge and vertex at a time."""
    normals = []
    for f in faces:
        n = np.cross(vertices[f[1]] - vertices[f[0]], vertices[f[2]] - vertices[f[0]])
        normals.append(n / np.linalg.norm(n))
    vertex = np.zeros_like(vertices)
    edges: dict[tuple[int, int], np.ndarray] = {}
    for f, n in zip(faces, normals):
        for c in range(3):
            a, b, before = f[c], f[(c + 1) % 3], f[(c + 2) % 3]
            u, w = vertices[b] - vertices[a], vertices[before] - vertices[a]
            vertex[a] += np.arccos(np.clip(u @ w / np.linalg.norm(u) / np.linalg.norm(w),
                                           -1, 1)) * n
            key = (min(a, b), max(a, b))
            edges[key] = edges.get(key, 0.0) + n
    out = np.zeros((len(faces), 7, 3))
    for t, (f, n) in enumerate(zip(faces, normals)):
        out[t, 0] = n
        for c in range(3):
            e = edges[(min(f[c], f[(c + 1) % 3]), max(f[c], f[(c + 1) % 3]))]
            out[t, 1 + c] = e / np.linalg.norm(e)
            out[t, 4 + c] = vertex[f[c]] / np.linalg.norm(vertex[f[c]])
    return out


@settings(max_examples=25, deadline=None, derandomize=True)
@given(points=st.integers(8, 60), seed=st.integers(0, 2**31 - 1), cut=st.booleans())
def test_pseudonormals_match_their_definition(points, seed, cut):
    """The whole-array pseudonormals against the definition written one face at a time,
    on the convex hull of random points (closed: every edge has two faces; every
    pseudonormal points out of the hull) and on the hull with a face removed (open)."""
    from pliant.scene.triangles import pseudonormals

    rng = np.random.default_rng(seed)
    hull = trimesh.convex.convex_hull(rng.normal(size=(points, 3)))
    vertices, faces = np.asarray(hull.vertices, float), np.asarray(hull.faces, np.int64)
    if cut:
        faces = faces[1:]
    pseudo, closed = pseudonormals(vertices, faces)
    expected = _pseudonormals_by_definition(vertices, faces)
    assert closed is not cut
    assert np.abs(pseudo - expected).max() < 1e-12
    if not cut:  # outward: each feature's normal has its point on the hull's near side
        centre = vertices.mean(axis=0)
        for k, points_of in ((0, faces[:, 0]), (4, faces[:, 0]), (1, faces[:, 0])):
            assert np.all(np.einsum("tk,tk->t", pseudo[:, k], vertices[points_of] - centre) > 0)


def test_a_full_disk_leaves_no_half_written_cache_file(monkeypatch):
    """Issue 54: a full disk left zero-byte ``*.tmp.npz`` files in the cache. A write that
    fails (here numpy's, after it created its file, as a full disk does) leaves nothing
    behind, and the next read is a plain miss."""
    import errno

    from pliant.util import cache

    def full(path, **_):
        open(path, "wb").close()
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(cache.np, "savez", full)
    cache.save_arrays("mesh", "k" * 32, a=np.zeros(3))
    folder = cache.cache_dir() / "mesh"
    assert folder.is_dir() and list(folder.iterdir()) == []
    assert cache.load_arrays("mesh", "k" * 32) is None
