"""KBL (VDA 4964) harness files in: ``read_kbl`` builds a ``core.harness.Harness`` in SI.

The file is checked against its version's XML schema (KBL 2.3 SR-1, 2.4, 2.4 SR-1; the
prostep ivip schemas, MIT, shipped in ``pliant/data/kbl``) with xmlschema, then read with
the standard library's ElementTree. Every value with a unit goes through the file's own
``Unit`` table exactly once (lengths in mm become metres, g/m becomes kg/m); every id a
used element refers to must resolve, or a ``FileFormatError`` names the file, the
element, its id and the reference that did not resolve.

A segment's ``Center_curve`` pieces are uniform non-rational B-splines; the KBL
guidelines leave open whether their knot vectors are clamped. The reader tries both on
every segment and takes the one whose curves start and end at their segments' nodes
(within ``NODE_TOLERANCE``) more often, and says so in the harness's notes.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path

import numpy as np

from pliant.core.harness import (
    CLAMPED,
    UNCLAMPED,
    CentreCurve,
    Connector,
    Fixing,
    FixingPlace,
    Harness,
    HarnessNode,
    HarnessSegment,
    Module,
    Placement,
    Protection,
    ProtectionPlace,
    Wire,
    WireType,
)
from pliant.errors import FileFormatError

NODE_TOLERANCE = 1e-4  # m: a centre curve ends at its node within this (0.1 mm)
LARGEST = 1e4  # m: a coordinate or length beyond this is no vehicle's (a unit gone wrong)
SCHEMAS = {"2.3": "kbl23_sr1.xsd", "2.4": "kbl24.xsd", "2.4 SR-1": "kbl24_sr1.xsd"}
_XSI_TYPE = "{http://www.w3.org/2001/XMLSchema-instance}type"
_PREFIX = {"": 1.0, "milli": 1e-3, "centi": 1e-2, "micro": 1e-6, "kilo": 1e3}
_POWER = {"": 1, "square": 2, "cubic": 3}
# What a value's unit measures, and its SI factor, for the Unit_names outside the SI
# enumeration that KBL writers use (the samples: GramPerMetre).
_NAMED_UNITS = {"grampermetre": ("mass/length", 1e-3), "kilogrampermetre": ("mass/length", 1.0),
                "mm": ("length", 1e-3), "m": ("length", 1.0), "mm2": ("area", 1e-6),
                "g": ("mass", 1e-3), "kg": ("mass", 1.0)}
_SHOWN = {"length": "a length (metre)", "area": "an area (square metre)",
          "mass/length": "a mass per length (e.g. GramPerMetre)", "mass": "a mass (gram)"}


@dataclass(frozen=True)
class _Unit:
    kind: str  # "length", "area", "mass", "mass/length", or "" (not one pliant reads)
    factor: float  # SI per file unit
    text: str


def schema_path(version: str) -> Path:
    """The XML schema of a KBL ``version_id`` ("2.3 SR-1", "2.4", "2.4 SR-1")."""
    key = version.strip()
    name = SCHEMAS.get(key) or SCHEMAS.get(key.split()[0] if key else "")
    if name is None:
        raise FileFormatError(f"KBL version_id {version!r} is not one pliant reads; "
                              f"it reads {', '.join(SCHEMAS)} (export the harness as one)")
    return Path(str(resources.files("pliant.data").joinpath("kbl", name)))


@cache
def _schema(path: Path):
    import xmlschema  # noqa: PLC0415 (only a KBL import needs it: start-up time)

    return xmlschema.XMLSchema(str(path))


def schema_deviations(path: Path, version: str, limit: int = 20) -> list[str]:
    """Where the file breaks its version's schema (at most ``limit``), each with its
    XML path and the schema's reason."""
    out = []
    schema = _schema(schema_path(version))
    try:
        for error in schema.iter_errors(str(path)):
            out.append(f"{error.path}: {error.reason}")
            if len(out) >= limit:
                break
    except Exception as exc:  # xmlschema's own errors are of many kinds: each is said
        out.append(f"the schema check itself stopped: {exc}")
    return out


class _Reader:
    """One file's elements by id, its units, and typed errors that name them."""

    def __init__(self, path: Path, root: ET.Element) -> None:
        self.path = path
        self.root = root
        self.by_id: dict[str, ET.Element] = {}
        for el in root.iter():
            key = el.get("id")
            if key is not None:
                self.by_id[key] = el
        self.units = {u.get("id", ""): self._unit(u) for u in root.findall("Unit")}
        self.length_unit = _length_unit(self)
        self.notes: list[str] = []

    def fail(self, where: str, message: str) -> FileFormatError:
        return FileFormatError(f"{self.path}: {where}: {message}")

    def _unit(self, el: ET.Element) -> _Unit:
        name = (el.findtext("Si_unit_name") or "").strip()
        prefix = (el.findtext("Si_prefix") or "").strip()
        power = (el.findtext("Si_dimension") or "").strip()
        text = " ".join(x for x in (power, prefix + name, el.findtext("Unit_name") or "") if x)
        if name in ("metre", "gram") and prefix in _PREFIX and power in _POWER:
            base = 1.0 if name == "metre" else 1e-3
            n = _POWER[power] if name == "metre" else 1
            kind = {1: "length", 2: "area", 3: "volume"}[n] if name == "metre" else "mass"
            return _Unit(kind, (_PREFIX[prefix] * base) ** n if name == "metre"
                         else _PREFIX[prefix] * base, text)
        named = _NAMED_UNITS.get(re.sub(r"[\s_/-]", "", (el.findtext("Unit_name") or "")).lower())
        if named is not None:
            return _Unit(named[0], named[1], text)
        return _Unit("", 1.0, text)

    def ref(self, where: str, key: str, tags: Iterable[str]) -> ET.Element:
        el = self.by_id.get(key)
        tags = tuple(tags)
        if el is None or el.tag not in tags:
            what = f"a {el.tag}" if el is not None else "no element"
            raise self.fail(where, f"refers to {key!r}, {what}; it must name a "
                            f"{' or '.join(tags)} of the file (fix the reference)")
        return el

    def value(self, el: ET.Element | None, kind: str, where: str) -> float | None:
        """A Value_component in SI, its Unit_component checked to measure ``kind``."""
        if el is None:
            return None
        unit_id = (el.findtext("Unit_component") or "").strip()
        unit = self.units.get(unit_id)
        if unit is None:
            raise self.fail(where, f"Unit_component {unit_id!r} is not a Unit of the file "
                            "(add it to the Unit table)")
        if unit.kind != kind:
            raise self.fail(where, f"its unit {unit_id} ({unit.text or 'unnamed'}) is not "
                            f"{_SHOWN.get(kind, kind)} (fix the Unit_component)")
        value = number(el.findtext("Value_component"), where + ".Value_component",
                       self) * unit.factor
        if kind == "length" and abs(value) > LARGEST:
            raise self.fail(where, f"{value:g} m is longer than any harness (check the "
                            "value and its unit)")
        return value

    def point(self, key: str, where: str) -> np.ndarray:
        el = self.ref(where, key, ("Cartesian_point",))
        coords = [number(c.text, f"Cartesian_point {key}", self)
                  for c in el.findall("Coordinates")]
        if len(coords) != 3:
            raise self.fail(f"Cartesian_point {key}", f"{len(coords)} coordinates; a harness "
                            "point needs 3 (x, y, z)")
        point = np.array(coords) * self.length_unit
        if np.abs(point).max() > LARGEST:
            raise self.fail(f"Cartesian_point {key}", f"{coords} is more than "
                            f"{LARGEST / 1000:g} km from the origin: not a harness's point "
                            "(check the file's length unit)")
        return point


def number(text: str | None, where: str, reader: _Reader) -> float:
    try:
        value = float((text or "").strip())
    except ValueError:
        raise reader.fail(where, f"{text!r} is not a number") from None
    if not np.isfinite(value):
        raise reader.fail(where, f"{text!r} is not a finite number")
    return value


def _vector(el: ET.Element, tag: str, reader: _Reader, where: str
            ) -> tuple[float, float, float] | None:
    parts = [number(c.text, f"{where}.{tag}", reader) for c in el.findall(tag)]
    if not parts:
        return None
    if len(parts) == 2:
        parts.append(0.0)
    v = np.array(parts[:3])
    big = float(np.abs(v).max())
    if big == 0.0:
        return None
    v = v / big  # (a direction: its size does not matter, and squaring 1e308 overflows)
    return tuple(float(x) for x in v / np.linalg.norm(v))  # type: ignore[return-value]


def _ids(text: str | None) -> list[str]:
    return (text or "").split()


def _placement(el: ET.Element | None, reader: _Reader, where: str) -> Placement | None:
    if el is None:
        return None
    key = (el.findtext("Cartesian_point") or "").strip()
    p = reader.point(key, f"{where}.Placement")
    u = _vector(el, "U", reader, f"{where}.Placement") or (1.0, 0.0, 0.0)
    v = _vector(el, "V", reader, f"{where}.Placement") or (0.0, 1.0, 0.0)
    return Placement(tuple(float(x) for x in p), u, v)  # type: ignore[arg-type]


def _length_unit(reader: _Reader) -> float:
    """Cartesian points carry no unit: KBL writes them in the unit of its lengths.
    Take the file's length unit (all the samples: mm); a file with none is in mm."""
    lengths = {u.factor for u in reader.units.values() if u.kind == "length"}
    if len(lengths) > 1:
        raise reader.fail("Unit", "the file declares several length units; its "
                          "coordinates' unit is then unknown (use one length unit)")
    return lengths.pop() if lengths else 1e-3


def _text(el: ET.Element, tag: str) -> str:
    value = (el.findtext(tag) or "").strip()
    return "" if value == "/NULL" else value


def read_kbl(path: str | Path, *, strict: bool = False) -> Harness:
    """Read a KBL file into a ``Harness`` (SI units). ``strict``: a schema deviation is
    an error; otherwise the first few are listed in the harness's notes."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except FileNotFoundError:
        raise FileFormatError(f"{path}: no such file") from None
    except ET.ParseError as exc:
        raise FileFormatError(f"{path}: not well-formed XML ({exc}); export the KBL "
                              "file again") from None
    if not root.tag.endswith("KBL_container"):
        raise FileFormatError(f"{path}: its root element is {root.tag!r}, not a "
                              "KBL_container: not a KBL file")
    version = root.get("version_id", "")
    try:
        schema_path(version)
    except FileFormatError as exc:
        raise FileFormatError(f"{path}: {exc}") from None
    notes = []
    deviations = schema_deviations(path, version)
    if deviations:
        if strict:
            raise FileFormatError(f"{path}: breaks the KBL {version} schema at "
                                  f"{deviations[0]} (and {len(deviations) - 1} more)")
        notes.append(f"the file breaks its KBL {version} schema in {len(deviations)}"
                     f"{'+' if len(deviations) >= 20 else ''} place(s), read anyway; the "
                     f"first: {deviations[0]}")
    reader = _Reader(path, root)
    harness_el = root.find("Harness")
    if harness_el is None:
        raise reader.fail("KBL_container", "no Harness element (nothing to simulate)")

    wire_types = _wire_types(reader)
    wires = _wires(reader, harness_el, wire_types)
    nodes = _nodes(reader)
    fixings = _fixings(reader, harness_el)
    protections = _protections(reader, harness_el)
    segments = _segments(reader, nodes, fixings, protections)
    _route(reader, wires, segments)
    connectors = _connectors(reader, harness_el, nodes)
    modules = _modules(reader, harness_el)
    convention, note = _convention(segments, nodes)
    notes.append(note)
    notes.extend(reader.notes)
    return Harness(
        name=_text(harness_el, "Description") or path.stem,
        part_number=_text(harness_el, "Part_number"),
        source=str(path), version=version, convention=convention,
        nodes=nodes, segments=segments, wire_types=wire_types, wires=wires,
        fixings=fixings, connectors=connectors, protections=protections,
        modules=modules, notes=tuple(notes))


def _wire_types(reader: _Reader) -> dict[str, WireType]:
    out = {}
    for el in reader.root.findall("General_wire"):
        key = el.get("id", "")
        where = f"General_wire {key}"
        cores = el.findall("Core")
        core_ods: list[float | None] = []
        area = reader.value(el.find("Cross_section_area"), "area", where + ".Cross_section_area")
        bend = reader.value(el.find("Bend_radius"), "length", where + ".Bend_radius")
        if cores:
            core_areas = [reader.value(c.find("Cross_section_area"), "area",
                                       f"Core {c.get('id')}.Cross_section_area") for c in cores]
            if area is None and all(a is not None for a in core_areas):
                area = float(sum(core_areas))  # type: ignore[arg-type]
            core_bends = [reader.value(c.find("Bend_radius"), "length",
                                       f"Core {c.get('id')}.Bend_radius") for c in cores]
            core_ods = [reader.value(c.find("Outside_diameter"), "length",
                                     f"Core {c.get('id')}.Outside_diameter") for c in cores]
            if bend is None and any(b is not None for b in core_bends):
                bend = max(b for b in core_bends if b is not None)
        out[key] = WireType(
            id=key, part_number=_text(el, "Part_number"), description=_text(el, "Description"),
            outside_diameter=reader.value(el.find("Outside_diameter"), "length",
                                          where + ".Outside_diameter"),
            cross_section_area=area, bend_radius=bend,
            mass_per_length=_mass_per_length(reader, el, where), cores=len(cores),
            core_diameters=tuple(d for d in core_ods if d is not None) if cores else ())
    return out


def _mass_per_length(reader: _Reader, el: ET.Element, where: str) -> float | None:
    mass = el.find("Mass_information")
    if mass is None:
        return None
    unit = reader.units.get((mass.findtext("Unit_component") or "").strip())
    if unit is not None and unit.kind == "mass":  # a mass where a mass per length belongs
        reader.notes.append(f"{where}.Mass_information is a mass ({unit.text}), not a mass "
                            "per length: its mass per length is taken as unknown")
        return None
    return reader.value(mass, "mass/length", where + ".Mass_information")


def _wires(reader: _Reader, harness: ET.Element, types: dict[str, WireType]) -> dict[str, Wire]:
    out = {}
    for el in harness.findall("General_wire_occurrence"):
        key = el.get("id", "")
        where = f"General_wire_occurrence {key}"
        part = (el.findtext("Part") or "").strip()
        if part not in types:
            raise reader.fail(where + ".Part", f"refers to {part!r}, not a General_wire of "
                              "the file (fix the reference)")
        length_el = el.find("Length_information/Length_value")
        length = reader.value(length_el, "length", where + ".Length_value")
        name = _text(el, "Wire_number") or _text(el, "Special_wire_id") or key
        out[key] = Wire(id=key, name=name, type=part, length=length or None)
    return out


def _nodes(reader: _Reader) -> dict[str, HarnessNode]:
    out = {}
    for el in reader.root.findall("Node"):
        key = el.get("id", "")
        where = f"Node {key}"
        p = reader.point((el.findtext("Cartesian_point") or "").strip(), where + ".Cartesian_point")
        out[key] = HarnessNode(key, _text(el, "Id") or key,
                               (float(p[0]), float(p[1]), float(p[2])),
                               tuple(_ids(el.findtext("Referenced_components"))))
    return out


def _fixings(reader: _Reader, harness: ET.Element) -> dict[str, Fixing]:
    out = {}
    for el in harness.findall("Fixing_occurrence") + harness.findall("Accessory_occurrence"):
        key = el.get("id", "")
        where = f"{el.tag} {key}"
        part_id = (el.findtext("Part") or "").strip()
        part = reader.ref(where + ".Part", part_id, ("Fixing", "Accessory"))
        kind = _text(part, "Fixing_type") or _text(part, "Accessory_type") or part.tag.lower()
        out[key] = Fixing(key, _text(el, "Id") or key, _text(part, "Part_number"),
                          _text(part, "Description"), kind,
                          _placement(el.find("Placement"), reader, where))
    return out


def _protections(reader: _Reader, harness: ET.Element) -> dict[str, Protection]:
    out = {}
    for el in harness.findall("Wire_protection_occurrence"):
        key = el.get("id", "")
        where = f"Wire_protection_occurrence {key}"
        part = reader.ref(where + ".Part", (el.findtext("Part") or "").strip(),
                          ("Wire_protection",))
        out[key] = Protection(
            key, _text(el, "Id") or key, _text(part, "Protection_type"),
            _text(part, "Description"),
            reader.value(el.find("Protection_length"), "length", where + ".Protection_length"),
            _mass_per_length(reader, part, f"Wire_protection {part.get('id')}"))
    return out


def _segments(reader: _Reader, nodes: dict[str, HarnessNode], fixings: dict[str, Fixing],
              protections: dict[str, Protection]) -> dict[str, HarnessSegment]:
    out = {}
    for el in reader.root.findall("Segment"):
        key = el.get("id", "")
        where = f"Segment {key}"
        ends = []
        for tag in ("Start_node", "End_node"):
            node = (el.findtext(tag) or "").strip()
            if node not in nodes:
                raise reader.fail(f"{where}.{tag}", f"refers to {node!r}, not a Node of the "
                                  "file (fix the reference)")
            ends.append(node)
        length = reader.value(el.find("Virtual_length"), "length", where + ".Virtual_length")
        if length is None or not length > 0:
            raise reader.fail(where + ".Virtual_length", "missing or not positive; a segment "
                              "needs its designed length")
        curves = []
        for c in el.findall("Center_curve"):
            cw = f"{where}.Center_curve {c.get('id')}"
            degree = int(number(c.findtext("Degree"), cw + ".Degree", reader))
            points = [reader.point(p, cw + ".Control_points")
                      for p in _ids(c.findtext("Control_points"))]
            if degree < 1 or len(points) < degree + 1:
                raise reader.fail(cw, f"degree {degree} with {len(points)} control points; a "
                                  "B-spline needs at least degree + 1")
            curves.append(CentreCurve(degree, np.array(points)))
        area_el = el.find("Cross_section_area_information")
        area = kind = None
        if area_el is not None:
            area = reader.value(area_el.find("Area"), "area", where + ".Cross_section_area")
            kind = _text(area_el, "Value_determination")
        places = []
        for f in el.findall("Fixing_assignment"):
            ref = (f.findtext("Fixing") or "").strip()
            fw = f"{where}.Fixing_assignment {f.get('id')}"
            if ref not in fixings:
                raise reader.fail(fw + ".Fixing", f"refers to {ref!r}, not a Fixing_occurrence "
                                  "of the harness (fix the reference)")
            location = number(f.findtext("Location"), fw + ".Location", reader)
            if not -1e-9 <= location <= 1 + 1e-9:
                raise reader.fail(fw + ".Location", f"{location} is outside the segment "
                                  "(0 at its start node, 1 at its end)")
            places.append(FixingPlace(ref, min(max(location, 0.0), 1.0),
                                      _vector(f, "Orientation", reader, fw)))
        covers = []
        for p in el.findall("Protection_area"):
            ref = (p.findtext("Associated_protection") or "").strip()
            pw = f"{where}.Protection_area {p.get('id')}"
            if ref not in protections:
                raise reader.fail(pw, f"refers to {ref!r}, not a Wire_protection_occurrence "
                                  "(fix the reference)")
            covers.append(ProtectionPlace(ref, number(p.findtext("Start_location"), pw, reader),
                                          number(p.findtext("End_location"), pw, reader)))
        out[key] = HarnessSegment(
            id=key, name=_text(el, "Id") or key, start=ends[0], end=ends[1],
            virtual_length=length, curves=tuple(curves),
            start_vector=_vector(el, "Start_vector", reader, where),
            end_vector=_vector(el, "End_vector", reader, where),
            cross_section_area=area, cross_section_kind=kind or "",
            fixings=tuple(places), protections=tuple(covers))
    if not out:
        raise reader.fail("KBL_container", "no Segment: the file has no geometry to simulate "
                          "(export it with its topology)")
    return out


def _route(reader: _Reader, wires: dict[str, Wire], segments: dict[str, HarnessSegment]) -> None:
    """Each wire's segments, from the Routing elements (a routing's Routed_wire is a
    Connection, whose Wire is a wire occurrence or a core of a multicore cable)."""
    core_owner = {}
    for key, wire_el in ((k, reader.by_id[k]) for k in wires):
        for core in wire_el.findall("Core_occurrence"):
            core_owner[core.get("id", "")] = key
    routed: dict[str, list[str]] = {}
    for el in reader.root.findall("Routing"):
        where = f"Routing {el.get('id')}"
        connection = reader.ref(where + ".Routed_wire", (el.findtext("Routed_wire") or "").strip(),
                                ("Connection",))
        target = (connection.findtext("Wire") or "").strip()
        owner = target if target in wires else core_owner.get(target)
        if owner is None:
            raise reader.fail(f"Connection {connection.get('id')}.Wire", f"refers to {target!r}, "
                              "not a wire or core occurrence (fix the reference)")
        chain = routed.setdefault(owner, [])
        for seg in _ids(el.findtext("Segments")):
            if seg not in segments:
                raise reader.fail(where + ".Segments", f"lists {seg!r}, not a Segment of the "
                                  "file (fix the reference)")
            if seg not in chain:
                chain.append(seg)
    for key, chain in routed.items():
        w = wires[key]
        wires[key] = Wire(w.id, w.name, w.type, w.length, tuple(chain))


def _connectors(reader: _Reader, harness: ET.Element, nodes: dict[str, HarnessNode]
                ) -> dict[str, Connector]:
    at = {c: n.id for n in nodes.values() for c in n.components}
    out = {}
    for el in harness.findall("Connector_occurrence") + harness.findall(
            "Special_terminal_occurrence"):
        key = el.get("id", "")
        where = f"{el.tag} {key}"
        part = reader.by_id.get((el.findtext("Part") or "").strip())
        description = _text(el, "Description") or (_text(part, "Description") if part is not None
                                                    else "")
        usage = _text(el, "Usage") or ("terminal" if el.tag.startswith("Special") else "")
        out[key] = Connector(key, _text(el, "Id") or key, description, usage,
                             _placement(el.find("Placement"), reader, where), at.get(key, ""))
    return out


def _modules(reader: _Reader, harness: ET.Element) -> dict[str, Module]:
    out = {}
    configs = {c.get("id"): c for c in harness.findall("Module_configuration")}
    for el in harness.findall("Module"):
        key = el.get("id", "")
        controlled: set[str] = set()
        for conf in el.findall("Module_configuration"):
            inner = conf.find("Controlled_components")
            if inner is None and (conf.text or "").strip() in configs:
                inner = configs[(conf.text or "").strip()].find("Controlled_components")
            if inner is not None:
                controlled.update(_ids(inner.text))
        out[key] = Module(key, _text(el, "Part_number"), _text(el, "Description"),
                          frozenset(controlled))
    return out


def _convention(segments: dict[str, HarnessSegment], nodes: dict[str, HarnessNode]
                ) -> tuple[str, str]:
    """Which knot vector makes the centre curves start and end at their nodes."""
    fits = {}
    with_curves = [s for s in segments.values() if s.curves]
    for convention in (UNCLAMPED, CLAMPED):
        fits[convention] = sum(curve_meets_nodes(s, nodes, convention) for s in with_curves)
    best = max(fits, key=lambda k: (fits[k], k == UNCLAMPED))
    other = CLAMPED if best == UNCLAMPED else UNCLAMPED
    if not with_curves:
        return UNCLAMPED, "no segment has a centre curve: each starts straight"
    return best, (f"centre curves read as {best} uniform B-splines: {fits[best]} of "
                  f"{len(with_curves)} segments' curves start and end at their nodes within "
                  f"{NODE_TOLERANCE * 1e3:g} mm that way ({other}: {fits[other]})")


def curve_meets_nodes(segment: HarnessSegment, nodes: dict[str, HarnessNode],
                      convention: str) -> bool:
    """Whether the segment's curve pieces, end to end, run from its start node to its
    end node within ``NODE_TOLERANCE``."""
    if not segment.curves:
        return False
    first = segment.curves[0].points(convention, 2)[0]
    last = segment.curves[-1].points(convention, 2)[-1]
    return bool(np.linalg.norm(first - nodes[segment.start].position) <= NODE_TOLERANCE
                and np.linalg.norm(last - nodes[segment.end].position) <= NODE_TOLERANCE)
