"""The interference report against geometry worked by hand: a straight tube beside and
through a sphere and a box, and the contacts of a solved part."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pliant as pl
from pliant.errors import InputError
from pliant.models import rod3d
from pliant.scene import Obstacle, interference, interference_of_curve
from pliant.scene.interference import polyline_distance

R, r = 0.1, 0.01  # the sphere's radius, the tube's


def straight(height: float, n: int = 201):
    """A 1 m tube along x from (-0.5, 0, height) to (0.5, 0, height)."""
    s = np.linspace(0.0, 1.0, n)
    return s, np.column_stack([s - 0.5, np.zeros(n), np.full(n, height)])


def test_a_tube_through_a_sphere_penetrates_over_the_chord_worked_by_hand():
    """Its neutral line passes h from the centre: the tube is inside over |x| <
    sqrt((R + r)^2 - h^2), deepest at x = 0 by R + r - h; a margin widens the span to
    the margin's circle."""
    h = 0.05
    s, points = straight(h)
    report = interference_of_curve(s, points, r, [Obstacle.sphere("ball", R, (0, 0, 0))],
                                   margin=0.02)
    (pen,) = report.penetrations
    half = math.sqrt((R + r) ** 2 - h * h)
    step = 1.0 / 200 / 8
    assert pen.s_start == pytest.approx(0.5 - half, abs=step)
    assert pen.s_end == pytest.approx(0.5 + half, abs=step)
    assert pen.worst == pytest.approx(h - R - r, abs=1e-12) and pen.s_worst == 0.5
    (smallest,) = report.clearances
    assert smallest.clearance == pen.worst and not report.clear
    # Too close: from the margin's circle in to the penetration, on both sides.
    near = sorted(report.too_close, key=lambda x: x.s_start)
    outer = math.sqrt((R + r + 0.02) ** 2 - h * h)
    assert len(near) == 2
    assert near[0].s_start == pytest.approx(0.5 - outer, abs=step)
    assert near[1].s_end == pytest.approx(0.5 + outer, abs=step)


def test_clearance_to_a_box_beside_the_tube_and_a_clear_report():
    s, points = straight(0.0)
    box = Obstacle.box("block", (0.2, 0.2, 0.2), (0.1, 0.0, -0.2))  # top at z = -0.1
    report = interference_of_curve(s, points, r, [box], margin=0.05)
    assert report.clear and not report.penetrations
    assert report.smallest.clearance == pytest.approx(0.1 - r, abs=1e-12)
    assert 0.5 <= report.smallest.s <= 0.7
    tight = interference_of_curve(s, points, r, [box], margin=0.1)
    (span,) = tight.too_close  # over the top, and round its edges while within 0.1 m
    reach = math.sqrt((0.1 + r) ** 2 - 0.1**2)
    assert (span.s_start, span.s_end) == pytest.approx((0.5 - reach, 0.7 + reach),
                                                       abs=1.0 / 200 / 8)


@settings(max_examples=60, deadline=None)
@given(h=st.floats(-0.2, 0.2), y=st.floats(-0.2, 0.2), radius=st.floats(0.0, 0.03))
def test_smallest_clearance_to_a_sphere_is_the_line_distance(h, y, radius):
    """The smallest clearance of a line passing (y, h) from a sphere's centre is
    sqrt(y^2 + h^2) - R - radius, attained at x = 0 (a sample lies there)."""
    s, points = straight(h)
    points[:, 1] = y
    report = interference_of_curve(s, points, radius, [Obstacle.sphere("b", R, (0, 0, 0))])
    assert report.smallest.clearance == pytest.approx(math.hypot(y, h) - R - radius,
                                                      abs=1e-12)
    assert bool(report.penetrations) == (math.hypot(y, h) - R - radius < -1e-6)


def test_a_solved_part_on_a_prop_touches_it_and_nothing_else():
    prop = Obstacle.cylinder("prop", 0.005, 0.2, (1.0, 0.0, -(r + 0.005)),
                             [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    wall = Obstacle.box("wall", (0.1, 0.4, 0.4), (0.5, 0.3, 0.0))
    part = pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=0.1 / 9.81,
                   outer_diameter=2 * r)
    eq = rod3d.solve(pl.Problem(part, (pl.clamp(0.0, position=(0, 0, 0)),),
                                gravity=(0, 0, -9.81), obstacles=(prop, wall)))
    report = interference(eq, margin=0.01)
    by_name = {c.obstacle: c for c in report.clearances}
    # Touching at the tip: the smallest clearance is at the contact point itself (the
    # report samples it), a few tens of micrometres before the tip where the drooping
    # part's axis passes nearest the prop's round top.
    assert abs(by_name["prop"].clearance) < 1e-7
    assert by_name["prop"].s == pytest.approx(1.0, abs=1e-4)
    assert by_name["prop"].s in eq.contacts.s
    assert by_name["wall"].clearance == pytest.approx(0.1 - r, abs=1e-4)
    assert not report.penetrations
    assert [x.obstacle for x in report.too_close] == ["prop"]
    assert report.to_dict()["clear"] is False


def test_bad_input_names_the_field():
    s, points = straight(0.0)
    with pytest.raises(InputError, match="margin"):
        interference_of_curve(s, points, r, [], margin=-1.0)
    with pytest.raises(InputError, match="points"):
        interference_of_curve(s[:-1], points, r, [])
    eq2d = pl.solve(pl.Problem(pl.Part(length=1.0, bending_stiffness=1.0), (pl.clamp(0.0),)))
    with pytest.raises(InputError):
        interference(eq2d)


def _point_to_polyline(p, line) -> float:
    """The slow twin: each segment in turn, the foot of the perpendicular clamped to it."""
    best = math.inf
    for a, b in itertools.pairwise(line):
        ab = [b[c] - a[c] for c in range(3)]
        ap = [p[c] - a[c] for c in range(3)]
        t = sum(x * y for x, y in zip(ap, ab)) / max(sum(x * x for x in ab), 1e-300)
        t = min(1.0, max(0.0, t))
        best = min(best, math.dist(p, [a[c] + t * ab[c] for c in range(3)]))
    return best


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(2, 30), st.integers(1, 50), st.integers(0, 2**32 - 1))
def test_the_distance_to_a_polyline_is_the_slow_twins(segments, count, seed):
    """The distance of points to another part's neutral line (numpy, in blocks) against
    the plain per-segment loop, with repeated vertices (zero-length segments) too."""
    rng = np.random.default_rng(seed)
    line = rng.normal(size=(segments, 3))
    line[rng.integers(segments)] = line[0]  # a vertex repeated
    points = rng.normal(size=(count, 3)) * 2.0
    got = polyline_distance(points, line)
    want = [_point_to_polyline(p.tolist(), line.tolist()) for p in points]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)


def test_the_distance_to_a_straight_line_is_the_perpendicular():
    """Closed form: points beside a segment along x are their (y, z) radius from it; past
    its end, the distance to the end; a one-point line, the distance to the point."""
    line = np.array([[0.0, 0.0, 0.0], [0.4, 0.0, 0.0], [1.0, 0.0, 0.0]])
    points = np.array([[0.3, 0.3, 0.4], [0.9, -0.05, 0.0], [1.3, 0.4, 0.0]])
    np.testing.assert_allclose(polyline_distance(points, line),
                               [0.5, 0.05, 0.5], rtol=1e-14)
    np.testing.assert_allclose(polyline_distance(points, line[:1]),
                               np.linalg.norm(points, axis=1), rtol=1e-14)


def test_a_part_resting_on_a_round_prop_reads_touching_where_it_touches():
    """The part sags onto a round prop between the answer's samples. The report samples
    the contact point itself: the clearance there is the contact's (nanometres: its
    compliance), not what the samples beside it read over the prop's curve (3 um), and
    nothing penetrates."""
    radius = 0.01
    prop = Obstacle.cylinder("prop", 0.03, 0.2, (0.55, 0.0, -(radius + 0.03) - 0.004),
                             [[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    part = pl.Part(length=1.0, bending_stiffness=0.5, mass_per_length=0.3,
                   outer_diameter=2 * radius)
    eq = rod3d.solve(pl.Problem(part, (pl.clamp(0.0, position=(0, 0, 0)),),
                                gravity=(0, 0, -9.81), obstacles=(prop,)))
    (where,) = eq.contacts.s
    assert where not in eq.s  # between samples: the case the samples alone misread
    report = interference(eq)
    assert abs(report.smallest.clearance) < 1e-7
    assert report.smallest.s == where
    assert not report.penetrations


@pytest.mark.parametrize(("gap", "shown"), [
    (3e-6, 0.0),       # below what a sampled clearance resolves: touching, 0
    (-5e-7, 0.0),      # within the contact's tolerance: touching, not inside
    (5e-4, 5e-4),      # half a millimetre: as it is
    (-2e-3, -2e-3),    # 2 mm inside: as it is, negative
])
def test_one_clearance_for_one_contact_touching_within_what_the_model_resolves(gap, shown):
    """One number for one thing (issue 61): the interference report, which the terminal,
    the page's verdict, the files and studies all read, shows a gap below what the
    sampled clearance resolves as 0 (touching), and real gaps as they are: a straight
    tube over a sphere, its distance worked by hand (R + r + gap at the top)."""
    s, points = straight(R + r + gap, n=401)
    report = interference_of_curve(s, points, r, [Obstacle.sphere("ball", R, (0, 0, 0))])
    (c,) = report.clearances
    if shown == 0.0:
        assert c.clearance == 0.0
    else:
        assert c.clearance == pytest.approx(shown, abs=1e-9)
