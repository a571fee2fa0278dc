"""Tube surfaces: closed, of the right volume, with frames that do not twist needlessly."""

from __future__ import annotations

import math

import numpy as np
import trimesh

from pliant.core.tube import rotation_minimizing_frames, tube_mesh


def test_straight_tube_is_watertight_with_the_polygon_volume():
    points = np.column_stack([np.linspace(0.0, 2.0, 21), np.zeros(21), np.zeros(21)])
    radius, sides = 0.1, 12
    vertices, faces = tube_mesh(points, radius, sides=sides)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight
    area = 0.5 * sides * radius**2 * math.sin(2 * math.pi / sides)
    assert mesh.volume == np.float64(mesh.volume) and mesh.volume > 0  # outward normals
    assert mesh.volume == pytest_approx(area * 2.0)


def pytest_approx(value, rel=1e-12):
    import pytest

    return pytest.approx(value, rel=rel)


def test_rotation_minimizing_frames_on_a_planar_curve():
    """On a plane curve the RMF's binormal stays the plane's normal: no twist."""
    t = np.linspace(0.0, 3.0, 200)
    points = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    frames = rotation_minimizing_frames(points, first_normal=np.array([0.0, 0.0, 1.0]))
    for f in frames:
        assert np.allclose(f.T @ f, np.eye(3), atol=1e-12)
    assert np.allclose(frames[:, :, 0], [0.0, 0.0, 1.0], atol=1e-9)


def test_helix_tube_volume_converges():
    """A tube swept along a helix keeps the volume pi r^2 L (Pappus) as it is refined."""
    errors = []
    for n in (100, 200):
        s = np.linspace(0.0, 4.0, n)
        a, c = 0.5, 0.2
        w = 1.0 / math.hypot(a, c)
        points = np.column_stack([a * np.cos(w * s), a * np.sin(w * s), c * w * s])
        vertices, faces = tube_mesh(points, 0.05, sides=64)
        volume = trimesh.Trimesh(vertices, faces, process=False).volume
        area = 0.5 * 64 * 0.05**2 * math.sin(2 * math.pi / 64)
        errors.append(abs(volume - area * 4.0) / (area * 4.0))
    assert errors[1] < 1e-3 and errors[1] < errors[0]
