"""A harness's segments as a physics model needs them, and the checks a harness DMU
checker runs on its design: ``properties`` derives each segment's bundle diameter, mass
per length, bending and torsional stiffness and minimum bend radius, each with the rule
or data it came from; ``design_checks`` judges the designed centre curves (do they meet
their nodes, is their length the designed one, is their tightest bend within the wires'
limits, does the bundle fit its reserved section, does the route kink where a bundle
runs through a node); ``select`` keeps one variant's modules.

The stiffness model (an estimate, stated so it can be replaced): the wires of a taped
bundle slide on one another, so the bundle's stiffness is the sum of its wires'; a
wire's conductor is strands that bend each about its own axis (n strands of diameter
d_s: EI = E_cu n pi d_s^4 / 64 = E_cu A d_s^2 / 16 with A = n pi d_s^2 / 4) and its
insulation a tube over it. The sum is a lower bound (tape, friction and the strands'
lay stiffen a real bundle): replace it per segment or per wire type with a measured
value (``overrides``; ``pliant identify`` measures one).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from pliant.assembly.checks import Zone, zone_of
from pliant.core.harness import Harness, HarnessSegment, Wire, WireType
from pliant.errors import InputError
from pliant.io.kbl import NODE_TOLERANCE, curve_meets_nodes

PACKING = 0.75  # share of a round taped bundle's section its round wires fill
PACKING_SOURCE = ("packing rule D = sqrt(sum d_i^2 / 0.75): round wires fill about 75 % of "
                  "a taped bundle's section (a 1.15 packing factor on sqrt(N) d)")
COPPER_E = 110e9  # Pa, annealed copper
COPPER_G = 42e9  # Pa
COPPER_DENSITY = 8960.0  # kg/m^3
STRAND = 0.2e-3  # m, a stranded automotive conductor's strand diameter (assumed)
INSULATION_E = 50e6  # Pa, plasticised PVC (assumed)
INSULATION_DENSITY = 1400.0  # kg/m^3, PVC
STIFFNESS_SOURCE = ("estimate: the sum of its wires' (wires slide in the bundle), each "
                    "wire's copper as 0.2 mm strands bending alone (E 110 GPa) and its "
                    "insulation a tube (E 50 MPa); a lower bound, replace with a measured "
                    "value")
LENGTH_TOLERANCE = 1e-3  # a centre curve's length within 0.1 % of the designed length
KINK_ANGLE = 10.0  # degrees: a bundle running through a node turns by more: a kink


@dataclass(frozen=True)
class Derived:
    """A value [SI] and where it came from (None: unknown, and ``source`` says why)."""

    value: float | None
    source: str


@dataclass(frozen=True)
class SegmentProperties:
    """What a rod model needs of one segment, each value with its provenance."""

    segment: str
    wires: tuple[str, ...]
    diameter: Derived  # [m] the bundle's outside diameter
    mass_per_length: Derived  # [kg/m]
    bending_stiffness: Derived  # [N m^2]
    torsional_stiffness: Derived  # [N m^2]
    min_bend_radius: Derived  # [m] to the bundle's centreline
    axial_stiffness: Derived = Derived(None, "")  # [N] EA


@dataclass(frozen=True)
class DesignCheck:
    """One check of the design data: the segment (or node), what was checked, the value
    and its limit [SI, ``unit`` as shown], the zone, and a sentence saying what to do."""

    where: str
    what: str
    value: float | None
    limit: float | None
    zone: Zone
    message: str
    source: str = ""
    name: str = ""  # the segment's or node's name in the design tool
    also: tuple[str, ...] = ()  # other places it concerns (a pair's other segment)


def wire_diameter(t: WireType) -> float | None:
    """[m] its outside diameter, or a multicore's from its cores by the packing rule
    (the file gives the cores' and not the sheath's)."""
    if t.outside_diameter is not None:
        return t.outside_diameter
    if t.cores and len(t.core_diameters) == t.cores:
        return max(max(t.core_diameters),
                   math.sqrt(sum(d * d for d in t.core_diameters) / PACKING))
    return None


def worst_zones(checks: Iterable[DesignCheck]) -> dict[str, Zone]:
    """Each checked place's (``where``) worst zone."""
    out: dict[str, Zone] = {}
    for c in checks:
        for where in (c.where, *c.also):
            if where not in out or c.zone.rank > out[where].rank:
                out[where] = c.zone
    return out


def sources(props: Mapping[str, SegmentProperties], checks: Iterable[DesignCheck]) -> list[str]:
    """Every source the derived properties and the checks name, once each, sorted."""
    return sorted({d.source for p in props.values()
                   for d in (p.diameter, p.mass_per_length, p.bending_stiffness,
                             p.torsional_stiffness, p.min_bend_radius) if d.source}
                  | {c.source for c in checks if c.source})


def _conductor_diameter(t: WireType) -> float:
    return math.sqrt(4.0 * (t.cross_section_area or 0.0) / math.pi)


def wire_bending_stiffness(t: WireType) -> float | None:
    """[N m^2] the stated estimate for one wire (or multicore cable) type."""
    d = wire_diameter(t)
    if d is None or t.cross_section_area is None:
        return None
    dc = min(_conductor_diameter(t), d)
    return COPPER_E * t.cross_section_area * STRAND**2 / 16.0 + \
        INSULATION_E * math.pi * (d**4 - dc**4) / 64.0


def wire_torsional_stiffness(t: WireType) -> float | None:
    """[N m^2] strands twisting each about its own axis, the insulation a tube
    (G = E / 3, an incompressible polymer)."""
    d = wire_diameter(t)
    if d is None or t.cross_section_area is None:
        return None
    dc = min(_conductor_diameter(t), d)
    return COPPER_G * t.cross_section_area * STRAND**2 / 8.0 + \
        INSULATION_E / 3.0 * math.pi * (d**4 - dc**4) / 32.0


def wire_axial_stiffness(t: WireType) -> float | None:
    """[N] the copper's EA (the insulation's share is left out: 2000 times softer)."""
    if t.cross_section_area is None:
        return None
    return COPPER_E * t.cross_section_area


def wire_mass_per_length(t: WireType) -> Derived:
    """[kg/m] the file's, or copper and PVC by their sections and densities."""
    if t.mass_per_length is not None:
        return Derived(t.mass_per_length, "the file's Mass_information")
    d = wire_diameter(t)
    if d is None or t.cross_section_area is None:
        return Derived(None, "no mass, outside diameter or conductor section in the file")
    outer = math.pi * d**2 / 4.0
    return Derived(COPPER_DENSITY * t.cross_section_area
                   + INSULATION_DENSITY * max(outer - t.cross_section_area, 0.0),
                   "copper and PVC by their sections (no mass in the file)")


def _wire_bend_limit(t: WireType, rules) -> tuple[float | None, str]:
    if t.bend_radius is not None:
        return t.bend_radius, f"{t.part_number or t.id}'s Bend_radius"
    kind = rules.kinds.get("multi-core cable" if t.cores else "wire")
    d = wire_diameter(t)
    if kind is None or kind.fallback_od is None or d is None:
        return None, ""
    return kind.fallback_od * d, (
        f"{t.part_number or t.id}: no Bend_radius; {kind.fallback_source}")


def properties(harness: Harness, overrides: Mapping[str, Mapping[str, float]] | None = None,
               rules=None) -> dict[str, SegmentProperties]:
    """Each segment's derived properties. ``overrides``: by segment id or name, or by
    wire type id or part number, a mapping of ``bending_stiffness`` /
    ``torsional_stiffness`` [N m^2], ``axial_stiffness`` [N], ``diameter`` [m] or
    ``mass_per_length`` [kg/m]
    measured or given (a wire type's replace that wire's share)."""
    from pliant.io.rules_file import load_rules  # noqa: PLC0415 (pydantic: on use)

    rules = rules or load_rules()
    overrides = dict(overrides or {})
    known = set(harness.segments) | {s.name for s in harness.segments.values()} | \
        set(harness.wire_types) | {t.part_number for t in harness.wire_types.values()}
    for key, values in overrides.items():
        if key not in known:
            raise InputError(f"overrides.{key}", "not a segment or wire type of the harness")
        for name in values:
            if name not in ("bending_stiffness", "torsional_stiffness", "diameter",
                            "mass_per_length", "axial_stiffness"):
                raise InputError(f"overrides.{key}.{name}", "give bending_stiffness, "
                                 "torsional_stiffness, axial_stiffness, diameter or "
                                 "mass_per_length")
    out = {}
    for seg in harness.segments.values():
        out[seg.id] = _segment(harness, seg, overrides, rules)
    return out


def _given(overrides, keys: Iterable[str], name: str) -> float | None:
    for key in keys:
        if key in overrides and name in overrides[key]:
            return float(overrides[key][name])
    return None


def _segment(harness: Harness, seg: HarnessSegment, overrides, rules) -> SegmentProperties:
    wires: tuple[Wire, ...] = harness.wires_in(seg.id)
    types = [harness.wire_types[w.type] for w in wires]
    seg_keys = (seg.id, seg.name)

    def per_wire(name: str, own) -> tuple[float | None, str]:
        total, given, missing = 0.0, 0, 0
        for t in types:
            v = _given(overrides, (t.id, t.part_number), name)
            if v is not None:
                given += 1
            else:
                v = own(t)
            if v is None:
                missing += 1
                continue
            total += v
        if not types:
            return None, "no wire runs through it"
        if missing:
            return None, f"{missing} of its {len(types)} wires lack the data for it"
        return total, (f"the sum of its {len(types)} wires' ({given} given)" if given else "")

    # Diameter: given, else the packing rule over the wires' outside diameters.
    d = _given(overrides, seg_keys, "diameter")
    if d is not None:
        diameter = Derived(d, "given")
    else:
        ods = [od for od in (wire_diameter(t) for t in types) if od is not None]
        if types and len(ods) == len(types):
            squares = sum(od * od for od in ods)
            cored = any(t.outside_diameter is None for t in types)
            diameter = Derived(max(max(ods), math.sqrt(squares / PACKING)),
                               (PACKING_SOURCE if len(types) > 1 else "its one wire's diameter")
                               + (" (a multicore cable's from its cores)" if cored else ""))
        elif seg.cross_section_area is not None:
            diameter = Derived(math.sqrt(4 * seg.cross_section_area / math.pi),
                               f"the file's {seg.cross_section_kind or ''} cross-section")
        else:
            diameter = Derived(None, "no wire diameters and no cross-section in the file")

    m = _given(overrides, seg_keys, "mass_per_length")
    if m is not None:
        mass = Derived(m, "given")
    else:
        wires_mass, source = per_wire("mass_per_length", lambda t: wire_mass_per_length(t).value)
        if wires_mass is None:
            mass = Derived(None, source)
        else:
            cover = 0.0
            for place in seg.protections:
                p = harness.protections[place.protection]
                if p.mass_per_length is not None:
                    cover += p.mass_per_length * max(0.0, place.end - place.start)
            estimated = any(t.mass_per_length is None for t in types)
            mass = Derived(wires_mass + cover, (source or "its wires' Mass_information") + (
                " (some by copper and PVC sections)" if estimated else "") + (
                " and its protections' over their stretch" if cover else ""))

    stiffness = []
    for name, own in (("bending_stiffness", wire_bending_stiffness),
                      ("torsional_stiffness", wire_torsional_stiffness)):
        v = _given(overrides, seg_keys, name)
        if v is not None:
            stiffness.append(Derived(v, "given"))
            continue
        total, source = per_wire(name, own)
        stiffness.append(Derived(total, source if total is None else (
            STIFFNESS_SOURCE + (f" ({source})" if source else ""))))

    ea, ea_source = per_wire("axial_stiffness", wire_axial_stiffness)
    v = _given(overrides, seg_keys, "axial_stiffness")
    axial = Derived(v, "given") if v is not None else Derived(
        ea, ea_source if ea is None else "the sum of its wires' copper E A (E 110 GPa)"
        + (f" ({ea_source})" if ea_source else ""))
    limits = [(_wire_bend_limit(t, rules), t) for t in types]
    known = [(r, s) for (r, s), _ in limits if r is not None]
    if known:
        radius, why = max(known, key=lambda x: x[0])
        bend = Derived(radius, f"the largest of its wires' limits ({why})")
    else:
        bend = Derived(None, "no wire gives a bend radius or a diameter")
    return SegmentProperties(seg.id, tuple(w.id for w in wires), diameter, mass,
                             stiffness[0], stiffness[1], bend, axial)


# -- the design's centre curves ---------------------------------------------------------
def centre_curve(harness: Harness, segment: str, spacing: float = 2e-3) -> np.ndarray:
    """(n, 3) [m] points along a segment's designed centre curve, start node to end
    node, about ``spacing`` apart (a straight line where it has no curve, or a curve
    that misses its nodes: ``design_checks`` says so)."""
    seg = harness.segments[segment]
    a = np.array(harness.nodes[seg.start].position)
    b = np.array(harness.nodes[seg.end].position)
    if not seg.curves or not curve_meets_nodes(seg, harness.nodes, harness.convention):
        count = max(2, int(math.ceil(np.linalg.norm(b - a) / spacing)) + 1)
        return a + np.linspace(0.0, 1.0, count)[:, None] * (b - a)
    pieces = []
    for k, c in enumerate(seg.curves):
        rough = c.points(harness.convention, 32)
        length = float(np.linalg.norm(np.diff(rough, axis=0), axis=1).sum())
        count = max(8, int(math.ceil(length / spacing)) + 1)
        pts = c.points(harness.convention, count)
        pieces.append(pts if k == 0 else pts[1:])
    return np.concatenate(pieces)


def polyline_curvature(points: np.ndarray) -> np.ndarray:
    """The curvature [1/m] at each interior point of a polyline: the circle through it
    and its neighbours (1 / circumradius)."""
    a, b, c = points[:-2], points[1:-1], points[2:]
    ab, bc, ca = (np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                  np.linalg.norm(a - c, axis=1))
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = 2.0 * area2 / (ab * bc * ca)
    return np.nan_to_num(k)


def design_checks(harness: Harness, props: Mapping[str, SegmentProperties],
                  rules=None) -> list[DesignCheck]:
    """The design data's checks, worst first within each segment."""
    from pliant.io.rules_file import load_rules  # noqa: PLC0415 (pydantic: on use)

    rules = rules or load_rules()
    margin = rules.bend_margin
    out: list[DesignCheck] = []
    ends: dict[str, list[tuple[str, np.ndarray]]] = {}
    for seg in harness.segments.values():
        where = f"segment {seg.id}"
        first = len(out)
        pts = centre_curve(harness, seg.id)
        length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
        meets = curve_meets_nodes(seg, harness.nodes, harness.convention) if seg.curves else True
        if not meets:
            a = np.array(harness.nodes[seg.start].position)
            b = np.array(harness.nodes[seg.end].position)
            head = seg.curves[0].points(harness.convention, 2)[0]
            tail = seg.curves[-1].points(harness.convention, 2)[-1]
            miss = max(float(np.linalg.norm(head - a)), float(np.linalg.norm(tail - b)))
            out.append(DesignCheck(where, "centre curve at its nodes", miss, NODE_TOLERANCE,
                                   Zone.RED, f"its centre curve ends {miss * 1e3:.1f} mm from "
                                   "its node: the route was moved and the curve not updated "
                                   "(re-route the segment); a straight line between its "
                                   "nodes stands in for it"))
        else:
            ratio = length / seg.virtual_length - 1.0
            zone = Zone.GREEN if abs(ratio) <= LENGTH_TOLERANCE else Zone.YELLOW
            out.append(DesignCheck(where, "curve length / designed length", length,
                                   seg.virtual_length, zone,
                                   f"centre curve {length * 1e3:.1f} mm, Virtual_length "
                                   f"{seg.virtual_length * 1e3:.1f} mm ({ratio:+.2%})"))
        p = props[seg.id]
        limit = p.min_bend_radius.value
        if meets and len(pts) >= 3:
            kmax = max((float(c.curvature(harness.convention).max()) for c in seg.curves),
                       default=0.0)
            radius = math.inf if kmax == 0 else 1.0 / kmax
            if limit is None:
                out.append(DesignCheck(where, "designed bend radius", radius, None,
                                       Zone.UNCHECKED, "no bend limit: "
                                       + p.min_bend_radius.source))
            else:
                zone = zone_of(radius, margin * limit, limit, "below")
                out.append(DesignCheck(
                    where, "designed bend radius", radius, limit, zone,
                    f"tightest {radius * 1e3:.1f} mm against {limit * 1e3:.1f} mm "
                    f"({p.min_bend_radius.source})", rules.bend_margin_sourced.source))
        if (seg.cross_section_area is not None and p.diameter.value is not None
                and p.diameter.source != "given" and "cross-section" not in p.diameter.source):
            reserved = math.sqrt(4 * seg.cross_section_area / math.pi)
            zone = Zone.GREEN if p.diameter.value <= reserved else Zone.YELLOW
            out.append(DesignCheck(where, "bundle in its reserved section", p.diameter.value,
                                   reserved, zone,
                                   f"bundle {p.diameter.value * 1e3:.1f} mm in a reserved "
                                   f"{reserved * 1e3:.1f} mm ({seg.cross_section_kind})",
                                   PACKING_SOURCE))
        out[first:] = [replace(c, name=seg.name) for c in out[first:]]
        if meets and len(pts) >= 2:
            ends.setdefault(seg.start, []).append((seg.id, _unit(pts[1] - pts[0])))
            ends.setdefault(seg.end, []).append((seg.id, _unit(pts[-2] - pts[-1])))
    for node, leaving in ends.items():
        if len(leaving) == 2 and harness.degree(node) == 2:
            (sa, ta), (sb, tb) = leaving
            turn = math.degrees(math.acos(float(np.clip(-ta @ tb, -1.0, 1.0))))
            zone = Zone.RED if turn > KINK_ANGLE else Zone.GREEN
            out.append(DesignCheck(f"node {node}", "turn through the node",
                                   turn, KINK_ANGLE, zone,
                                   f"the bundle turns {turn:.1f} degrees where segments "
                                   f"{sa} and {sb} meet (a kink: no bend radius)",
                                   name=harness.nodes[node].name))
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else v


# -- variants ---------------------------------------------------------------------------
def select(harness: Harness, modules: Iterable[str]) -> Harness:
    """The harness built with ``modules`` (ids or part numbers): the wires, fixings,
    connectors and protections those modules control, and what no module controls;
    the segments that still carry a wire, and their nodes."""
    wanted = list(modules)
    chosen = []
    for name in wanted:
        found = [m for m in harness.modules.values() if name in (m.id, m.part_number)]
        if not found:
            names = sorted(m.part_number or m.id for m in harness.modules.values())
            raise InputError("module", f"{name!r} is not a module of {harness.name} (its "
                             f"modules: {', '.join(names[:8])}{' ...' if len(names) > 8 else ''})")
        chosen.extend(found)
    controlled = set().union(*(m.components for m in harness.modules.values())) \
        if harness.modules else set()
    keep = set().union(*(m.components for m in chosen)) if chosen else set()

    def kept(key: str) -> bool:
        return key in keep or key not in controlled

    wires = {k: w for k, w in harness.wires.items() if kept(k)}
    used = {s for w in wires.values() for s in w.segments}
    segments = {k: s for k, s in harness.segments.items() if k in used}
    nodes = {k: n for k, n in harness.nodes.items()
             if any(k in (s.start, s.end) for s in segments.values())}
    segments = {k: replace(s, fixings=tuple(f for f in s.fixings if kept(f.fixing)),
                           protections=tuple(p for p in s.protections if kept(p.protection)))
                for k, s in segments.items()}
    return replace(harness, nodes=nodes, segments=segments, wires=wires,
                   fixings={k: f for k, f in harness.fixings.items() if kept(k)},
                   connectors={k: c for k, c in harness.connectors.items() if kept(k)},
                   protections={k: p for k, p in harness.protections.items() if kept(k)},
                   notes=harness.notes + (f"modules {', '.join(wanted)}: {len(segments)} of "
                                          f"{len(harness.segments)} segments carry a wire",))
