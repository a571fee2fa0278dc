"""Benchmark of pliant's distance structures on CAD-sized meshes, against libigl and
embree on the same meshes, in one run.

    .venv/bin/pip install -e '.[bench]'      # libigl, embreex
    .venv/bin/python benchmarks/cad.py [--sizes 1 5] [--points 200]

For each size (millions of triangles; a subdivided sphere of 0.3 m radius, the closed
and curved kind of mesh a CAD export gives), each tool runs in its own process so that
its peak memory is its own:

- pliant: ``Obstacle.from_mesh`` (pseudonormals, box tree, signed distance grid) from an
  empty cache, and again from the disk cache (the same file loaded a second time: the
  grid, and for a large mesh the tree and pseudonormals, read back), and ``DistanceField.query`` of
  200 points near the surface (exact
  there), then of the same points again (warm);
- libigl: ``AABB.init`` and ``AABB.squared_distance`` (unsigned), and
  ``signed_distance`` with pseudonormals (its tree built inside each call);
- embree (embreex, through trimesh's ``RayMeshIntersector``): building its BVH and
  ``contains_points`` (inside or out by ray parity), the sign only.

Printed: time to load (generate) the mesh, to build, the first and the warm query, the
peak resident memory of the process, and the largest disagreement of the distances with
the exact |x| - r of a sphere (the mesh's own chord error aside, which bounds all three).
Timings are machine-dependent; the ratios, measured in the same run, are the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

RADIUS = 0.3


def _sphere(million: float):
    import trimesh

    level = int(round(np.log(million * 1e6 / 20.0) / np.log(4.0)))
    mesh = trimesh.creation.icosphere(subdivisions=level, radius=RADIUS)
    return np.ascontiguousarray(mesh.vertices), np.ascontiguousarray(mesh.faces, np.int64)


def _points(n: int) -> np.ndarray:
    rng = np.random.default_rng(1)
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    return p * RADIUS * (1.0 + 0.02 * rng.uniform(-1.0, 1.0, (n, 1)))


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def one(tool: str, million: float, n: int) -> dict:
    """Run one tool on one mesh size in this process."""
    start = time.perf_counter()
    V, F = _sphere(million)
    out = {"tool": tool, "triangles": len(F), "load": time.perf_counter() - start}
    P = _points(n)
    exact = np.linalg.norm(P, axis=1) - RADIUS
    if tool == "pliant":
        import tempfile

        os.environ["PLIANT_CACHE"] = tempfile.mkdtemp()  # an empty cache: the whole build
        from pliant.scene.distance import DistanceField, Obstacle, prepare_mesh

        prepare_mesh(V[:3], np.array([[0, 1, 2]]), 8, cache=False)  # kernels loaded
        start = time.perf_counter()
        field = DistanceField([Obstacle.from_mesh("mesh", V, F)])
        out["build"] = time.perf_counter() - start
        start = time.perf_counter()
        Obstacle.from_mesh("mesh", V, F)  # the same file again: read from the cache
        out["rebuild"] = time.perf_counter() - start
        band = 0.05 * RADIUS
        start = time.perf_counter()
        d = field.query(P, band)[0]
        out["first"] = time.perf_counter() - start
        start = time.perf_counter()
        d = field.query(P, band)[0]
        out["warm"] = time.perf_counter() - start
        out["error"] = float(np.abs(d - exact).max())
    elif tool == "libigl":
        import igl

        start = time.perf_counter()
        tree = igl.AABB()
        tree.init(V, F)
        out["build"] = time.perf_counter() - start
        start = time.perf_counter()
        sq = tree.squared_distance(V, F, P)[0]
        out["first"] = time.perf_counter() - start
        start = time.perf_counter()
        sq = tree.squared_distance(V, F, P)[0]
        out["warm"] = time.perf_counter() - start
        out["error"] = float(np.abs(np.sqrt(sq) - np.abs(exact)).max())
        start = time.perf_counter()
        s = igl.signed_distance(P, V, F, igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL)[0]
        out["signed_call"] = time.perf_counter() - start
        out["signed_error"] = float(np.abs(s - exact).max())
    else:
        import trimesh
        from trimesh.ray.ray_pyembree import RayMeshIntersector

        mesh = trimesh.Trimesh(V, F, process=False)
        start = time.perf_counter()
        rays = RayMeshIntersector(mesh)
        rays.intersects_first(P[:1], -P[:1])  # builds and commits its scene
        out["build"] = time.perf_counter() - start
        start = time.perf_counter()
        inside = rays.contains_points(P)
        out["first"] = time.perf_counter() - start
        start = time.perf_counter()
        inside = rays.contains_points(P)
        out["warm"] = time.perf_counter() - start
        out["wrong_signs"] = int(np.sum(inside != (exact < 0)))
    out["peak_mb"] = _peak_mb()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1.0, 5.0],
                        help="millions of triangles")
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(one(args.one[0], float(args.one[1]), args.points)))
        return
    for million in args.sizes:
        rows = {}
        for tool in ("pliant", "libigl", "embree"):
            done = subprocess.run([sys.executable, __file__, "--one", tool, str(million),
                                   "--points", str(args.points)], capture_output=True,
                                  text=True, check=False)
            if done.returncode != 0:
                print(f"{tool}: failed: {done.stderr.strip().splitlines()[-1:]}")
                continue
            rows[tool] = json.loads(done.stdout.strip().splitlines()[-1])
        first = next(iter(rows.values()))
        print(f"{first['triangles'] / 1e6:.2f} M triangles (generated in {first['load']:.1f} s), "
              f"{args.points} points near the surface:")
        for tool, r in rows.items():
            line = (f"  {tool:7s} build {r['build']:7.2f} s, first query "
                    f"{r['first'] * 1e3:8.2f} ms, warm {r['warm'] * 1e3:8.3f} ms, peak "
                    f"{r['peak_mb']:6.0f} MB")
            if "rebuild" in r:
                line += f" (again, from the disk cache: {r['rebuild']:.2f} s)"
            if "error" in r:
                line += f", |error| {r['error']:.1e} m"
            if "signed_call" in r:
                line += (f"; signed_distance (tree built per call) {r['signed_call']:.2f} s, "
                         f"|error| {r['signed_error']:.1e} m")
            if "wrong_signs" in r:
                line += f", signs wrong: {r['wrong_signs']}"
            print(line)
        if "pliant" in rows and "libigl" in rows:
            p, g = rows["pliant"], rows["libigl"]
            print(f"  pliant / libigl: build {p['build'] / g['build']:.1f}x, warm query "
                  f"{p['warm'] / g['warm']:.2f}x, memory {p['peak_mb'] / g['peak_mb']:.1f}x")


if __name__ == "__main__":
    main()
