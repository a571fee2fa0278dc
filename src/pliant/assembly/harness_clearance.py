"""A harness's own branches against each other, as installed: where two segments that do
not meet at a node come closer than their bundles' radii allow.

The installed harness is solved segment by segment, balanced at its junctions; contact
between its own segments is not solved. Two branches that sag into each other are then
drawn passing through each other, and the shapes of both there are not the real ones
(they would push each other aside). A harness DMU checker flags such places; so does
this module, comparing each pair's installed gap with its designed one:

- installed through each other by more than the design has them (``OVERLAP``): the
  check is unchecked, and says that the two segments' installed shapes do not hold
  there (route them apart, or add a fixing that holds them);
- overlapping no more than designed (bundles routed side by side, or past a junction):
  yellow, as designed;
- closer than the margin (touching, with a margin of 0): yellow, a chafing risk where
  they are not fixed together;
- else one green check with the smallest gap of all.

Segments that share a node are not compared (they meet there by design).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from pliant.core.numbers import triple

# [m] how much more than designed two bundles may overlap before the answer is said not
# to hold: half a millimetre, the order of the bundle diameters' packing estimate
# (engineering choice).
OVERLAP = 5e-4


@dataclass(frozen=True)
class BranchGap:
    """Two segments' smallest clearance [m] (centre lines less both radii; negative
    where they pass through each other), installed and designed, and where installed:
    the arc length [m] along each and the midpoint between the closest points."""

    a: str
    b: str
    installed: float
    designed: float
    s_a: float
    s_b: float
    at: tuple[float, float, float]


def _closest(p: np.ndarray, q: np.ndarray) -> tuple[float, int, int, np.ndarray, np.ndarray]:
    """The smallest distance between polylines p (n, 3) and q (m, 3): (distance, the
    segment of p and of q where it is, and the two closest points). Exact for segment
    pairs (clamped closest points), found on the pairs whose boxes come near."""
    a0, a1 = p[:-1], p[1:]
    b0, b1 = q[:-1], q[1:]
    best = (np.inf, 0, 0, p[0], q[0])
    # candidate pairs: the segment pairs whose boxes lie within the best so far
    lo_a, hi_a = np.minimum(a0, a1), np.maximum(a0, a1)
    lo_b, hi_b = np.minimum(b0, b1), np.maximum(b0, b1)
    d_nodes = np.linalg.norm(p[:, None] - q[None], axis=2)
    bound = float(d_nodes.min())
    gap = np.maximum(0.0, np.maximum(lo_a[:, None] - hi_b[None], lo_b[None] - hi_a[:, None]))
    cand = np.argwhere(np.linalg.norm(gap, axis=2) <= bound)
    for i, j in cand:
        d, x, y = _segment_pair(a0[i], a1[i], b0[j], b1[j])
        if d < best[0]:
            best = (d, int(i), int(j), x, y)
    return best


def _segment_pair(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray
                  ) -> tuple[float, np.ndarray, np.ndarray]:
    """The closest points of segments p0-p1 and q0-q1 and their distance."""
    u, v, w = p1 - p0, q1 - q0, p0 - q0
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    den = a * c - b * b
    s = 0.0 if den <= 1e-30 * max(a * c, 1e-300) else float(np.clip((b * e - c * d) / den,
                                                                      0.0, 1.0))
    t = (b * s + e) / c if c > 0.0 else 0.0
    if t < 0.0 or t > 1.0:
        t = float(np.clip(t, 0.0, 1.0))
        s = float(np.clip((b * t - d) / a, 0.0, 1.0)) if a > 0.0 else 0.0
    x, y = p0 + s * u, q0 + t * v
    return float(np.linalg.norm(x - y)), x, y


def branch_gaps(installed: Any, within: float = 0.0) -> list[BranchGap]:
    """Every pair of segments that share no node and whose installed clearance is under
    ``within`` [m], or whose clearance is the smallest of all (the first, then, where
    no pair is that close), closest first."""
    harness = installed.harness
    design = installed.prepared[0] if installed.prepared is not None else {}
    lines = {k: s.equilibrium.position for k, s in installed.segments.items()}
    radius = {k: s.equilibrium.problem.part.drawn_radius
              for k, s in installed.segments.items()}
    boxes = {k: (p.min(axis=0) - radius[k], p.max(axis=0) + radius[k])
             for k, p in lines.items()}
    reach = max(within, 0.0)
    out: list[BranchGap] = []
    smallest: BranchGap | None = None
    for a, b in itertools.combinations(sorted(lines), 2):
        sa, sb = harness.segments[a], harness.segments[b]
        if {sa.start, sa.end} & {sb.start, sb.end}:
            continue
        (lo_a, hi_a), (lo_b, hi_b) = boxes[a], boxes[b]
        apart = np.maximum(0.0, np.maximum(lo_a - hi_b, lo_b - hi_a))
        if smallest is not None and float(np.linalg.norm(apart)) > max(
                reach, smallest.installed):
            continue
        d, i, j, x, y = _closest(lines[a], lines[b])
        gap = d - radius[a] - radius[b]
        if smallest is not None and gap >= max(reach, smallest.installed):
            continue
        eq_a, eq_b = installed.segments[a].equilibrium, installed.segments[b].equilibrium
        designed = (_closest(np.asarray(design[a]), np.asarray(design[b]))[0]
                    - radius[a] - radius[b]) if a in design and b in design else np.inf
        found = BranchGap(a, b, float(gap), float(designed), _s_at(eq_a, i, x),
                          _s_at(eq_b, j, y), triple(0.5 * (x + y)))
        if smallest is None or gap < smallest.installed:
            smallest = found
        if gap < reach:
            out.append(found)
    if not out and smallest is not None:
        out.append(smallest)
    return sorted(out, key=lambda g: g.installed)


def _s_at(eq: Any, k: int, point: np.ndarray) -> float:
    """The arc length [m] of ``point`` on the element k of ``eq``'s line."""
    a, b = eq.position[k], eq.position[k + 1]
    f = float(np.clip((point - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-300), 0, 1))
    return float(eq.s[k] + f * (eq.s[k + 1] - eq.s[k]))


def branch_checks(installed: Any, margin: float = 0.0) -> list:
    """The checks of the harness's branches against each other (see the module), as
    ``assembly.harness.DesignCheck`` records."""
    from pliant.assembly.checks import Zone  # noqa: PLC0415
    from pliant.assembly.harness import DesignCheck  # noqa: PLC0415

    harness = installed.harness
    out = []
    gaps = branch_gaps(installed, within=max(margin, 0.0) + OVERLAP)
    for g in gaps:
        names = f"{harness.segments[g.a].name} / {harness.segments[g.b].name}"
        where = f"segment {g.a}"
        both = (f"{g.a} and {g.b}, {g.installed * 1e3:.1f} mm (designed "
                f"{g.designed * 1e3:.1f} mm) at s = {g.s_a:.3f} m and {g.s_b:.3f} m")
        if g.installed < -OVERLAP and g.installed < g.designed - OVERLAP:
            zone, message = Zone.UNCHECKED, (
                f"{both}: they pass through each other as solved. pliant does not solve "
                "contact between a harness's own segments, so neither's installed shape "
                "holds there (they would push each other aside): route them apart or add "
                "a fixing that holds them")
        elif g.installed < -OVERLAP:
            zone, message = Zone.YELLOW, (f"{both}: they overlap no more than designed "
                                          "(bundles side by side, or past a junction): "
                                          "taped together there?")
        elif g.installed < max(margin, 0.0) + OVERLAP:
            zone, message = Zone.YELLOW, (f"{both}: they touch or come within the margin: "
                                          "a chafing risk where they are not fixed together")
        else:
            zone, message = Zone.GREEN, f"the closest branches: {both}"
        out.append(DesignCheck(where, "clearance between branches", g.installed,
                               max(margin, 0.0), zone, message,
                               "the scene's margin" if margin > 0 else "", name=names,
                               also=(f"segment {g.b}",)))
    return out
