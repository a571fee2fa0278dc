"""KBL harness files in: every sample reads, its counts match the XML's own, units are
honoured once, the centre curves' B-spline convention is decided from the data, bad
files get typed errors naming the element, derived properties match a hand computation,
and the design checks match an independent twin (the curves' analytic curvature)."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import BSpline

from pliant.assembly.checks import Zone
from pliant.assembly.harness import (
    PACKING,
    centre_curve,
    design_checks,
    polyline_curvature,
    properties,
    select,
    wire_bending_stiffness,
)
from pliant.core.harness import CLAMPED, UNCLAMPED
from pliant.errors import FileFormatError, InputError
from pliant.io.kbl import read_kbl

from .helpers import CHROMIUM, drawn_in_view, offline_report, straight_harness, view_data

KBL = Path(__file__).resolve().parents[1] / "examples" / "harness" / "kbl"
GENERATOR = KBL / "kblxml_2.3sr-1_000971230_ltgs_generator_170718.kbl"
MOTOR = KBL / "kblxml_2.3sr-1_000971619_ltgs_movo_170718.kbl"
MAIN = KBL / "kblxml_2.4sr-1_tab016120_modulare_ltgs._160718.kbl"
SAMPLES = sorted(KBL.glob("*.kbl"))
NAMESPACE = "http://www.prostep.org/Car_electric_container/KBL2.3/KBLSchema"


@pytest.fixture(scope="module")
def main_harness():
    return read_kbl(MAIN)


def _count(text: str, tag: str) -> int:
    """An element's occurrences, counted on the raw text (not through a parser)."""
    return len(re.findall(rf"<{tag}[\s>]", text))


def _in_harness(text: str) -> str:
    """The Harness element's text (occurrences outside it belong to assembly parts)."""
    return text[text.index("<Harness "):text.index("</Harness>")]


@pytest.mark.parametrize("path", SAMPLES, ids=lambda p: p.name[:40])
def test_every_sample_reads_with_the_xmls_own_counts(path, main_harness):
    harness = main_harness if path == MAIN else read_kbl(path)
    text = path.read_text(encoding="utf-8")
    inside = _in_harness(text)
    assert len(harness.nodes) == _count(text, "Node")
    assert len(harness.segments) == _count(text, "Segment")
    assert len(harness.wire_types) == _count(text, "General_wire")
    assert len(harness.wires) == _count(inside, "General_wire_occurrence")
    assert len(harness.fixings) == _count(inside, "Fixing_occurrence") + _count(
        inside, "Accessory_occurrence")
    assert len(harness.connectors) == _count(inside, "Connector_occurrence") + _count(
        inside, "Special_terminal_occurrence")
    assert len(harness.protections) == _count(inside, "Wire_protection_occurrence")
    assert len(harness.modules) == _count(inside, "Module")
    assert sum(len(s.fixings) for s in harness.segments.values()) == _count(
        text, "Fixing_assignment")
    # Lengths in metres: the file's Virtual_length values are mm.
    lengths = [float(v) for v in re.findall(
        r"<Virtual_length[^>]*>\s*<Unit_component>[^<]*</Unit_component>\s*"
        r"<Value_component>([^<]+)</Value_component>", text)]
    assert len(lengths) == len(harness.segments)
    assert harness.length == pytest.approx(sum(lengths) * 1e-3, rel=1e-12)
    assert harness.convention == UNCLAMPED


def test_the_main_harness_is_what_its_readme_counts(main_harness):
    # ../shared/harness/README.md: 184 nodes, 183 segments, 36.7 m, 98 wire types,
    # 254 routed wires (routings), 141 connectors, 14 fixings (16 assignments),
    # 105 protections, 34 modules.
    h = main_harness
    assert (len(h.nodes), len(h.segments), len(h.wire_types)) == (184, 183, 98)
    assert round(h.length, 1) == 36.7
    assert sum(1 for c in h.connectors.values() if not c.usage == "terminal") == 141
    assert len(h.fixings) == 14 and len(h.protections) == 105 and len(h.modules) == 34
    assert sum(len(s.fixings) for s in h.segments.values()) == 16
    # Every routed connection reaches its wire (multicore cores reach their cable).
    text = MAIN.read_text(encoding="utf-8")
    assert _count(text, "Routing") == 254
    routed = {w.id for w in h.wires.values() if w.segments}
    assert len(routed) >= 200 and all(set(w.segments) <= set(h.segments)
                                       for w in h.wires.values())
    # The file breaks its schema once (an empty Modules list): read, and said.
    assert any("schema" in n and "Modules" in n for n in h.notes)
    with pytest.raises(FileFormatError, match="Harness_configuration"):
        read_kbl(MAIN, strict=True)


def _rescaled(path: Path, out: Path, prefix: str, factor: float) -> Path:
    """The file with its length unit changed from mm to ``prefix`` metre: every length
    value and coordinate times ``factor`` (mm per new unit, inverted), areas times
    factor^2. Written with ElementTree, independently of the reader."""
    ET.register_namespace("kbl", NAMESPACE)
    ET.register_namespace("xsi", "http://www.w3.org/2001/XMLSchema-instance")
    tree = ET.parse(path)
    root = tree.getroot()
    kinds = {}
    for unit in root.findall("Unit"):
        if unit.findtext("Si_unit_name") == "metre":
            unit.find("Si_prefix").text = prefix
            kinds[unit.get("id")] = 2 if unit.findtext("Si_dimension") == "square" else 1
    for el in root.iter():
        unit = el.find("Unit_component")
        if unit is not None and unit.text in kinds:
            value = el.find("Value_component")
            value.text = repr(float(value.text) * factor ** kinds[unit.text])
        if el.tag == "Cartesian_point":
            for c in el.findall("Coordinates"):
                c.text = repr(float(c.text) * factor)
    tree.write(out, xml_declaration=True, encoding="UTF-8")
    return out


def test_a_file_in_centimetres_gives_the_same_harness_in_metres(tmp_path):
    mm = read_kbl(GENERATOR)
    cm = read_kbl(_rescaled(GENERATOR, tmp_path / "cm.kbl", "centi", 0.1))
    for key, node in mm.nodes.items():
        assert np.allclose(cm.nodes[key].position, node.position, rtol=1e-12, atol=0)
    for key, seg in mm.segments.items():
        other = cm.segments[key]
        assert other.virtual_length == pytest.approx(seg.virtual_length, rel=1e-12)
        assert other.cross_section_area == pytest.approx(seg.cross_section_area, rel=1e-12)
        assert np.allclose(centre_curve(cm, key), centre_curve(mm, key), rtol=1e-9, atol=1e-12)
    for key, t in mm.wire_types.items():
        assert cm.wire_types[key].outside_diameter == pytest.approx(t.outside_diameter)
        assert cm.wire_types[key].bend_radius == pytest.approx(t.bend_radius)
        assert cm.wire_types[key].cross_section_area == pytest.approx(t.cross_section_area)
    assert mm.wire_types["id_327_2"].outside_diameter == pytest.approx(5.1e-3)
    assert mm.wire_types["id_327_2"].cross_section_area == pytest.approx(6e-6)
    assert mm.wire_types["id_327_2"].mass_per_length == pytest.approx(0.068)


def _minimal(curve_points: np.ndarray, degree: int, start, end, length_mm: float,
             unit_name: str = "metre", version: str = "2.3 SR-1", start_node="Node_1") -> str:
    """A small KBL file: two nodes, one segment with one centre curve."""
    points = "".join(
        f'<Cartesian_point id="P{i}">'
        + "".join(f"<Coordinates>{float(c)!r}</Coordinates>" for c in p)
        + "</Cartesian_point>" for i, p in enumerate([start, end, *curve_points]))
    refs = " ".join(f"P{i + 2}" for i in range(len(curve_points)))
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<kbl:KBL_container xmlns:kbl="{NAMESPACE}" id="C" version_id="{version}">{points}
<Harness id="H"><Part_number>1</Part_number><Company_name>x</Company_name><Version>1</Version>
<Abbreviation>x</Abbreviation><Description>test</Description><Project_number>x</Project_number>
<Car_classification_level_2>x</Car_classification_level_2><Model_year>x</Model_year>
<Content>harness complete set</Content></Harness>
<Node id="Node_1"><Id>A</Id><Cartesian_point>P0</Cartesian_point></Node>
<Node id="Node_2"><Id>B</Id><Cartesian_point>P1</Cartesian_point></Node>
<Segment id="Segment_1"><Id>S</Id>
<Virtual_length id="V1"><Unit_component>U1</Unit_component>
<Value_component>{length_mm}</Value_component></Virtual_length>
<End_node>Node_2</End_node><Start_node>{start_node}</Start_node>
<Center_curve id="C1"><Degree>{degree}</Degree>
<Control_points>{refs}</Control_points></Center_curve>
</Segment>
<Unit id="U1"><Si_unit_name>{unit_name}</Si_unit_name><Si_prefix>milli</Si_prefix></Unit>
</kbl:KBL_container>"""


def test_the_curve_convention_is_decided_from_the_data(tmp_path):
    # A cubic Bezier (a clamped B-spline with 4 points) starts and ends at its end
    # points; read unclamped it would not.
    cp = np.array([[0.0, 0.0, 0.0], [30.0, 0.0, 0.0], [70.0, 20.0, 0.0], [100.0, 20.0, 0.0]])
    path = tmp_path / "clamped.kbl"
    path.write_text(_minimal(cp, 3, cp[0], cp[-1], 105.0))
    harness = read_kbl(path)
    assert harness.convention == CLAMPED
    assert "clamped" in harness.notes[-1] and "1 of 1" in harness.notes[-1]
    curve = centre_curve(harness, "Segment_1")
    assert np.allclose(curve[0], cp[0] * 1e-3) and np.allclose(curve[-1], cp[-1] * 1e-3)
    # The same points read as the samples are (unclamped) start elsewhere: the reader
    # says which convention it took and on how many segments.
    t = np.arange(8.0)
    unclamped_start = BSpline(t, cp, 3)(3.0)
    assert np.linalg.norm(unclamped_start - cp[0]) > 1.0


def test_bad_files_get_typed_errors_naming_the_element(tmp_path):
    cp = np.array([[0.0, 0.0, 0.0], [30.0, 0.0, 0.0], [70.0, 20.0, 0.0], [100.0, 20.0, 0.0]])
    cases = {
        "missing.kbl": (None, "no such file"),
        "broken.kbl": ("<kbl:KBL_container", "not well-formed XML"),
        "other.kbl": ('<?xml version="1.0"?><svg id="x"/>', "not a KBL_container"),
        "node.kbl": (_minimal(cp, 3, cp[0], cp[-1], 105.0, start_node="Node_9"),
                     r"Segment Segment_1\.Start_node: refers to 'Node_9'"),
        "unit.kbl": (_minimal(cp, 3, cp[0], cp[-1], 105.0, unit_name="gram"),
                     r"Segment Segment_1\.Virtual_length: its unit U1 \(milligram\) is not a "
                     r"length"),
        "version.kbl": (_minimal(cp, 3, cp[0], cp[-1], 105.0, version="9.9"),
                        "version_id '9.9' is not one pliant reads"),
    }
    for name, (text, message) in cases.items():
        path = tmp_path / name
        if text is not None:
            path.write_text(text)
        with pytest.raises(FileFormatError, match=message) as info:
            read_kbl(path)
        assert name in str(info.value)


def test_derived_properties_match_a_hand_computation():
    # The generator cable's first segment carries three wires: two 0.5 mm2 of 1.6 mm
    # (6 g/m, bend radius 4.8 mm) and one 6 mm2 of 5.1 mm (68 g/m, 15.3 mm), under a PET
    # tape of 6 g/m from 4.5496 % of its length to its end.
    harness = read_kbl(GENERATOR)
    p = properties(harness)["Segment_1"]
    assert len(p.wires) == 3
    assert p.diameter.value == pytest.approx(math.sqrt((1.6**2 * 2 + 5.1**2) / PACKING) * 1e-3)
    assert p.mass_per_length.value == pytest.approx((6 + 6 + 68 + 6 * (1 - 0.045496)) * 1e-3)
    assert p.min_bend_radius.value == pytest.approx(15.3e-3)

    def wire(area_mm2, od_mm):  # copper strands of 0.2 mm, PVC tube of 50 MPa
        a, d = area_mm2 * 1e-6, od_mm * 1e-3
        dc = math.sqrt(4 * a / math.pi)
        return 110e9 * a * 0.2e-3**2 / 16 + 50e6 * math.pi * (d**4 - dc**4) / 64

    assert p.bending_stiffness.value == pytest.approx(2 * wire(0.5, 1.6) + wire(6, 5.1))
    assert wire_bending_stiffness(harness.wire_types["id_327_2"]) == pytest.approx(wire(6, 5.1))
    assert "estimate" in p.bending_stiffness.source and "lower bound" in \
        p.bending_stiffness.source
    # A measured value for one wire type replaces that wire's share; for a segment, the
    # whole value; an unknown name is refused.
    measured = properties(harness, {"O1a2913741a": {"bending_stiffness": 0.01}})["Segment_1"]
    assert measured.bending_stiffness.value == pytest.approx(2 * wire(0.5, 1.6) + 0.01)
    assert "1 given" in measured.bending_stiffness.source
    whole = properties(harness, {"Segment_1": {"bending_stiffness": 0.02}})["Segment_1"]
    assert whole.bending_stiffness == type(whole.bending_stiffness)(0.02, "given")
    with pytest.raises(InputError, match=r"overrides\.Segment_9"):
        properties(harness, {"Segment_9": {"bending_stiffness": 0.02}})


def test_polyline_curvature_is_the_circles():
    for radius in (0.005, 0.02, 1.0):
        angle = np.linspace(0.0, 2.0, 50)
        points = radius * np.column_stack([np.cos(angle), np.sin(angle), 0.0 * angle])
        assert np.allclose(polyline_curvature(points), 1.0 / radius, rtol=1e-9)
    line = np.column_stack([np.linspace(0, 1, 9), np.zeros(9), np.zeros(9)])
    assert np.all(polyline_curvature(line) == 0.0)


def _analytic_tightest(harness, segment) -> float:
    """The smallest radius of curvature along a segment's B-spline pieces, from the
    spline's derivatives: |r' x r''| / |r'|^3."""
    kmax = 0.0
    for c in harness.segments[segment].curves:
        spline = BSpline(c.knots(harness.convention), c.control_points, c.degree)
        a, b = c.domain(harness.convention)
        u = np.linspace(a, b, 20001)
        d1, d2 = spline.derivative(1)(u), spline.derivative(2)(u)
        k = np.linalg.norm(np.cross(d1, d2), axis=1) / np.linalg.norm(d1, axis=1) ** 3
        kmax = max(kmax, float(k.max()))
    return 1.0 / kmax


def test_design_checks_match_the_curves_analytic_curvature():
    harness = read_kbl(GENERATOR)
    checks = design_checks(harness, properties(harness))
    bends = {c.where: c for c in checks if c.what == "designed bend radius"}
    assert len(bends) == 3
    for seg in harness.segments:
        check = bends[f"segment {seg}"]
        assert check.value == pytest.approx(_analytic_tightest(harness, seg), rel=1e-3)
        # and a third way: circles through three points of the curve 0.05 mm apart
        fine = polyline_curvature(centre_curve(harness, seg, spacing=5e-5))
        assert check.value == pytest.approx(1.0 / fine.max(), rel=0.01)
        limit = check.limit
        expected = (Zone.RED if check.value < limit else Zone.YELLOW
                    if check.value < 1.2 * limit else Zone.GREEN)
        assert check.zone == expected
    # Segment 3 bends to 5.4 mm where its 6 mm2 wire allows 15.3 mm: red.
    assert bends["segment Segment_3"].zone == Zone.RED
    # Every curve is its designed length within 0.1 %.
    lengths = [c for c in checks if c.what == "curve length / designed length"]
    assert len(lengths) == 3 and all(c.zone == Zone.GREEN for c in lengths)


def test_a_curve_that_misses_its_node_is_red_and_not_used():
    harness = read_kbl(MOTOR)
    checks = design_checks(harness, properties(harness))
    missed = [c for c in checks if c.what == "centre curve at its nodes"]
    assert [c.where for c in missed] == ["segment Segment_6"]
    assert missed[0].zone == Zone.RED and missed[0].value == pytest.approx(0.050, abs=1e-4)
    # Its curve is not judged for its bend; every other segment's is.
    bends = {c.where for c in checks if c.what == "designed bend radius"}
    assert "segment Segment_6" not in bends and len(bends) == 29


def test_a_module_keeps_its_wires_and_what_no_module_controls(main_harness):
    h = main_harness
    module = next(iter(h.modules.values()))
    variant = select(h, [module.part_number])
    controlled = set().union(*(m.components for m in h.modules.values()))
    expected = {k for k in h.wires if k in module.components or k not in controlled}
    assert set(variant.wires) == expected
    assert set(variant.segments) == {s for k in expected for s in h.wires[k].segments}
    assert 0 < len(variant.segments) < len(h.segments)
    assert all(s.start in variant.nodes and s.end in variant.nodes
               for s in variant.segments.values())
    with pytest.raises(InputError, match="not a module"):
        select(h, ["no such module"])


def test_pliant_harness_reports_checks_and_writes_curves_in_metres(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "pliant.cli.app", "harness", str(GENERATOR), "--json", "-",
         "--curves", str(tmp_path / "curves.csv"), "--glb", str(tmp_path / "h.glb")],
        capture_output=True, text=True, timeout=300)
    assert out.returncode == 1, out.stderr  # a red check: the 5.4 mm bend
    doc = json.loads(out.stdout)
    assert doc["harness"]["counts"]["segments"] == 3
    assert doc["harness"]["curve_convention"] == "unclamped"
    assert any(c["zone"] == "red" and c["where"] == "segment Segment_3"
               for c in doc["design_checks"])
    seg = next(s for s in doc["segments"] if s["id"] == "Segment_1")
    assert seg["min_bend_radius_m"]["value"] == pytest.approx(0.0153)
    assert "red" in out.stderr and "Segment_3" in out.stderr
    assert "verdict: red (the design): 1 red and 2 yellow checks (exit status 1)" in \
        " ".join(out.stderr.split())
    rows = (tmp_path / "curves.csv").read_text().splitlines()
    assert rows[0] == "segment,name,point,s_m,x_m,y_m,z_m"
    harness = read_kbl(GENERATOR)
    first = [r.split(",") for r in rows[1:] if r.startswith("Segment_1,")]
    assert np.allclose([float(v) for v in first[0][4:]], harness.nodes["Node_1"].position)
    assert float(first[-1][3]) == pytest.approx(harness.segments["Segment_1"].virtual_length,
                                                rel=1e-3)
    assert (tmp_path / "h.glb").stat().st_size > 1000


# -- the installed harness -------------------------------------------------------------
def test_a_junction_where_one_part_runs_through_gives_the_one_parts_answer():
    """The junction's twin: two segments joined straight, clamped at their far ends,
    against one part of their length clamped the same way (same elements)."""
    import pliant as pl
    from pliant.assembly.harness_solve import solve_installed
    from pliant.models import rod3d

    harness = straight_harness({"A": (0.0, 0.0, 0.0), "M": (0.2, 0.0, 0.0),
                                 "B": (0.4, 0.0, 0.0)},
                                [("S1", "A", "M", 0.24), ("S2", "M", "B", 0.24)], ["A", "B"])
    props = properties(harness)
    installed = solve_installed(harness, props)
    part = installed.segments["S1"].equilibrium.problem.part
    one = pl.Part(length=0.48, bending_stiffness=part.bending_stiffness,
                  torsional_stiffness=part.torsional_stiffness,
                  mass_per_length=part.mass_per_length, outer_diameter=part.outer_diameter,
                  axial_stiffness=part.axial_stiffness)
    ends = installed.segments["S1"].equilibrium.problem.conditions[0]
    twin = rod3d.solve(pl.Problem(one, (
        pl.clamp(0.0, (0.0, 0.0, 0.0), tangent=ends.tangent, normal=ends.normal, name="a"),
        pl.clamp(0.48, (0.4, 0.0, 0.0), tangent=ends.tangent, normal=ends.normal, name="b")),
        gravity=(0.0, 0.0, -9.81)), solver=rod3d.RodSolver(elements=24))
    middle = twin.position[np.argmin(np.abs(twin.s - 0.24))]
    sag = float(-twin.position[:, 2].min())
    assert sag > 0.01  # a real slack sag, not a straight line
    # The junction replaces one discrete joint of the single rod by a rigid one: its
    # answer is the twin's within a small share of the sag.
    assert np.linalg.norm(installed.junctions["M"] - middle) < 0.02 * sag
    force_a = -np.asarray(twin.reactions["a"].force)
    assert np.allclose(installed.held["connector at A"][0], force_a,
                       atol=0.02 * np.linalg.norm(force_a))
    # Each end carries half the weight (symmetry), and the junction balances.
    assert installed.held["connector at A"][0][2] == pytest.approx(-installed.weight / 2,
                                                                     rel=1e-6)
    assert installed.balance <= 1e-7


def test_the_installed_harnesses_balance_and_keep_their_design_data():
    from pliant.assembly.harness_solve import solve_installed

    for path in (GENERATOR, MOTOR):
        harness = read_kbl(path)
        installed = solve_installed(harness, properties(harness))
        # Global balance: the loads on the connectors and fixings carry the weight.
        total = sum(f for f, _ in installed.held.values())
        assert np.allclose(total, [0.0, 0.0, -installed.weight], atol=1e-6 * installed.weight)
        # Each junction's segments' end loads balance.
        for node, position in installed.junctions.items():
            force = np.zeros(3)
            for seg_id, seg in harness.segments.items():
                for end, at in ((0, seg.start), (1, seg.end)):
                    if at == node:
                        eq = installed.segments[seg_id].equilibrium
                        force += np.asarray(next(ld.force for name, ld in eq.reactions.items()
                                                 if name.startswith(("start ", "end ")[end])))
                        assert np.allclose(eq.position[-1 if end else 0], position, atol=1e-9)
            assert np.linalg.norm(force) <= 1e-6 * installed.weight
        # Every connector end at its designed position within 0.1 mm; every rod its
        # designed length within 0.1 %.
        for connector in harness.connectors.values():
            if connector.placement is None or not connector.node:
                continue
            for seg_id, seg in harness.segments.items():
                if connector.node in (seg.start, seg.end):
                    eq = installed.segments[seg_id].equilibrium
                    end = eq.position[0 if seg.start == connector.node else -1]
                    assert np.linalg.norm(end - harness.nodes[connector.node].position) < 1e-4
        drawn = sum(float(np.linalg.norm(np.diff(s.equilibrium.position, axis=0),
                                         axis=1).sum()) for s in installed.segments.values())
        assert drawn == pytest.approx(harness.length, rel=1e-3)


def _two_spans(upper: tuple, lower: tuple, margin: float = 0.0):
    """Two separate segments, each held by connectors at both ends 0.4 m apart along
    x: (lateral offset y [m], height z [m], length [m]) each; solved installed."""
    from pliant.assembly.harness_solve import solve_installed

    (y1, z1, l1), (y2, z2, l2) = upper, lower
    harness = straight_harness(
        {"A": (0.0, y1, z1), "B": (0.4, y1, z1), "C": (0.0, y2, z2), "D": (0.4, y2, z2)},
        [("U", "A", "B", l1), ("L", "C", "D", l2)], ["A", "B", "C", "D"])
    return solve_installed(harness, properties(harness), margin=margin)


def _resampled_gap(installed, a: str, b: str) -> float:
    """The twin of the check's distance: both installed lines resampled every 0.2 mm,
    the smallest point distance less both radii."""
    def dense(name):
        eq = installed.segments[name].equilibrium
        s = np.linspace(0.0, eq.s[-1], 2001)
        return np.column_stack([np.interp(s, eq.s, eq.position[:, i]) for i in range(3)])

    d = min(float(np.linalg.norm(dense(a)[k:k + 200, None] - dense(b)[None], axis=2).min())
            for k in range(0, 2001, 200))
    radii = sum(installed.segments[n].equilibrium.problem.part.drawn_radius for n in (a, b))
    return d - radii


def test_branches_that_sag_through_each_other_are_said_not_to_hold():
    """A slack span 10 mm above a taut one (and 1 mm aside, so that their centre lines
    pass 1 mm apart rather than cross) sags through it: the check is unchecked, names
    both, and its gap is the resampled twin's (to 0.05 mm); the design had them
    apart."""
    from pliant.assembly.checks import Zone
    from pliant.assembly.harness_solve import installed_checks

    installed = _two_spans((0.001, 0.01, 0.43), (0.0, 0.0, 0.401))
    [check] = [c for c in installed_checks(installed) if c.what == "clearance between branches"]
    assert check.zone == Zone.UNCHECKED and check.where == "segment L"
    assert check.also == ("segment U",) and "pass through each other" in check.message
    twin = _resampled_gap(installed, "L", "U")
    assert twin < -0.001  # through each other, past the overlap tolerance
    assert check.value == pytest.approx(twin, abs=5e-5)
    radius = installed.segments["U"].equilibrium.problem.part.drawn_radius
    designed = math.hypot(0.01, 0.001) - 2 * radius
    assert f"designed {designed * 1e3:.1f} mm" in check.message


@pytest.mark.parametrize(("offset", "margin", "zone", "words"), [
    (0.5, 0.005, "yellow", "within the margin"),
    (-2.0, 0.0, "yellow", "no more than designed"),
    (3.0, 0.005, "green", "the closest branches"),
])
def test_branches_side_by_side_are_judged_by_their_gap(offset, margin, zone, words):
    """Two equal spans side by side hang in the same shape, so their gap is the design's
    at every point: offset x the margin (or x 1 mm without one) plus both radii apart,
    as the check finds it."""
    from pliant.assembly.harness_solve import installed_checks

    both = properties(straight_harness({"A": (0, 0, 0), "B": (0.4, 0, 0)},  # both radii
                                       [("U", "A", "B", 0.42)], ["A", "B"]))["U"].diameter.value
    gap = offset * (margin or 1e-3)
    installed = _two_spans((0.0, 0.0, 0.42), (both + gap, 0.0, 0.42), margin)
    [check] = [c for c in installed_checks(installed) if c.what == "clearance between branches"]
    assert check.zone.value == zone and words in check.message
    assert check.value == pytest.approx(gap, abs=1e-6)


def test_a_harness_held_nowhere_is_refused_with_its_nodes():
    from pliant.assembly.harness_solve import solve_installed
    from pliant.errors import IllPosedProblemError

    harness = straight_harness({"A": (0.0, 0.0, 0.0), "B": (0.2, 0.0, 0.0)},
                                [("S1", "A", "B", 0.25)], [])
    with pytest.raises(IllPosedProblemError, match="held nowhere"):
        solve_installed(harness, properties(harness))


def test_a_moved_fixing_is_followed_warm_and_the_harness_still_balances():
    from pliant.assembly.harness_solve import solve_installed

    harness = read_kbl(GENERATOR)
    props = properties(harness)
    before = solve_installed(harness, props)
    fixing = next(iter(harness.fixings.values())).name
    after = solve_installed(harness, props, moved={fixing: (0.0, 0.0, 0.005)}, warm=before)
    eq = after.segments["Segment_1"].equilibrium
    clip = next(c for c in eq.problem.conditions if c.name == f"fixing {fixing}")
    was = next(c for c in before.segments["Segment_1"].equilibrium.problem.conditions
               if c.name == f"fixing {fixing}")
    assert np.allclose(np.subtract(clip.position, was.position), (0.0, 0.0, 0.005))
    at = eq.position[np.argmin(np.abs(eq.s - clip.s))]
    assert np.allclose(at, clip.position, atol=1e-9)
    total = sum(f for f, _ in after.held.values())
    assert np.allclose(total, [0.0, 0.0, -after.weight], atol=1e-6 * after.weight)
    assert after.balance <= 1e-7 and not np.allclose(after.held[f"fixing {fixing}"][0],
                                                     before.held[f"fixing {fixing}"][0])


def test_pliant_harness_solve_reports_the_installed_harness(tmp_path):
    out = subprocess.run(
        [sys.executable, "-m", "pliant.cli.app", "harness", str(GENERATOR), "--solve",
         "--json", "-", "--curves", str(tmp_path / "installed.csv")],
        capture_output=True, text=True, timeout=300)
    assert out.returncode == 1, out.stderr  # the design's 5.4 mm bend is still red
    doc = json.loads(out.stdout)
    installed = doc["installed"]
    assert installed["balance"] <= 1e-7 and len(installed["segments"]) == 3
    total = np.sum([v["force_N"] for v in installed["held_loads"].values()], axis=0)
    assert np.allclose(total, [0.0, 0.0, -installed["weight_N"]], atol=1e-5)
    assert any(c["what"] == "installed bend radius" for c in doc["design_checks"])
    assert "installed under gravity" in out.stderr
    rows = (tmp_path / "installed.csv").read_text().splitlines()
    first = [r.split(",") for r in rows[1:] if r.startswith("Segment_3,")]
    # The installed curve, not the design: it sags away from the designed one.
    harness = read_kbl(GENERATOR)
    design = centre_curve(harness, "Segment_3")
    middle = np.array([float(v) for v in first[len(first) // 2][4:]])
    assert np.min(np.linalg.norm(design - middle, axis=1)) > 1e-3


def test_the_junctions_jacobian_from_the_rods_newton_systems_matches_re_solving():
    """The clamps' sensitivity from each segment's factorised Newton system against
    forward differences that re-solve the segments (at a step small enough that the
    stiff stretch of a short segment stays linear)."""
    from pliant.assembly import harness_solve as hs

    harness = read_kbl(MOTOR)
    net = hs.Network(harness, properties(harness), hs.GRAVITY)
    for seg_id in harness.segments:
        net.eqs[seg_id] = net.solve_segment(seg_id, warm=False)
    r = net.residual(net.eqs)
    exact = hs.jacobian(net, r)
    saved = hs.STEP_POSITION, hs.STEP_ROTATION
    try:
        hs.STEP_POSITION = hs.STEP_ROTATION = 1e-7
        differences = hs.jacobian_by_differences(net, r)
    finally:
        hs.STEP_POSITION, hs.STEP_ROTATION = saved
    assert np.abs(exact - differences).max() <= 5e-3 * np.abs(differences).max()
    # A junction's own block is the heart of it: each to 1 % of its size.
    for k in range(len(net.junctions)):
        block = np.s_[6 * k:6 * k + 6, 6 * k:6 * k + 6]
        assert np.abs(exact[block] - differences[block]).max() <= 0.01 * np.abs(
            differences[block]).max()


def test_a_floppy_segment_between_two_connectors_hangs_as_the_catenary():
    """The heavy elastica's limit: a segment far longer than the bending length
    sqrt(EI / H) hangs as the catenary (the clamps' boundary layers, 4 mm of a 0.5 m
    span here, are the difference)."""
    from scipy.optimize import brentq

    from pliant.assembly.harness_solve import solve_installed

    span, length, w = 0.5, 0.6, 0.02 * 9.81
    harness = straight_harness({"A": (0.0, 0.0, 0.0), "B": (span, 0.0, 0.0)},
                                [("S", "A", "B", length)], ["A", "B"])
    props = properties(harness, {"S": {"bending_stiffness": 1e-6, "mass_per_length": 0.02}})
    installed = solve_installed(harness, props)
    eq = installed.segments["S"].equilibrium
    sag = -float(eq.position[:, 2].min())
    c = brentq(lambda c: 2 * c * math.sinh(span / (2 * c)) - length, 0.01, 10.0)
    catenary = c * (math.cosh(span / (2 * c)) - 1.0)
    assert sag == pytest.approx(catenary, rel=0.02)
    # The horizontal pull the connectors feel is the catenary's H = w c.
    assert abs(installed.held["connector at A"][0][0]) == pytest.approx(w * c, rel=0.03)
    assert installed.held["connector at A"][0][2] == pytest.approx(-w * length / 2, rel=1e-6)


SCENE = KBL.parent / "generator_on_bracket.toml"


def test_a_harness_in_a_scene_rests_on_its_obstacle_and_still_balances(tmp_path):
    from pliant.assembly.harness_solve import installed_checks, solve_installed
    from pliant.io.harness_scene import load_harness_scene

    scene = load_harness_scene(SCENE)
    (harness, modules), = scene.harnesses
    assert modules == () and scene.margin == 0.005
    props = properties(harness)
    free = solve_installed(harness, props)
    held = solve_installed(harness, props, obstacles=scene.obstacles, margin=scene.margin)
    top = 0.4759
    radius = held.segments["Segment_3"].equilibrium.problem.part.outer_diameter / 2
    # Without the bracket the cable sags through its top; with it, it rests on it.
    assert free.segments["Segment_3"].equilibrium.position[:, 2].min() - radius < top - 1e-3
    eq = held.segments["Segment_3"].equilibrium
    over = (np.abs(eq.position[:, 0] - 2.526) < 0.02) & (np.abs(eq.position[:, 1] - 0.135) < 0.02)
    assert over.any() and (eq.position[over, 2] - radius).min() > top - 2e-4
    lift = float(np.sum(eq.contacts.force[:, 2]))
    assert lift > 0.0
    # The connectors, the fixing and the bracket carry the weight together (the loads
    # on the connectors and fixing are what the harness puts on them: the lift is less).
    total = sum(f for f, _ in held.held.values())
    assert total[2] - lift == pytest.approx(-held.weight, abs=1e-6 * held.weight)
    checks = [c for c in installed_checks(held) if c.what == "clearance"]
    resting = next(c for c in checks if c.where == "segment Segment_3")
    assert resting.zone == Zone.YELLOW and resting.value == pytest.approx(0.0, abs=1e-5)
    # The scene names its KBL file by a path of its own: a wrong one is said.
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENE.read_text().replace("kbl/kblxml", "kbl/missing"))
    from pliant.io.harness_scene import load_harness_scene as load

    with pytest.raises(FileFormatError, match=r"harness\[0\]\.file: .*no such file"):
        load(bad)


def test_pliant_harness_reads_a_scene_and_reports_its_clearances():
    out = subprocess.run([sys.executable, "-m", "pliant.cli.app", "harness", str(SCENE),
                          "--json", "-"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 1, out.stderr  # the design's own red bend
    doc = json.loads(out.stdout)
    seg = next(s for s in doc["installed"]["segments"] if s["id"] == "Segment_3")
    nearest = min(seg["interference"]["clearances"], key=lambda c: c["clearance"])
    assert nearest["obstacle"] == "bracket" and abs(nearest["clearance"]) < 1e-5
    assert "clearance mm" in out.stderr and "rests on it" in out.stderr


def test_pliant_harness_lists_the_modules_a_variant_is_built_from(main_harness):
    out = subprocess.run([sys.executable, "-m", "pliant.cli.app", "harness", str(MAIN),
                          "--modules"], capture_output=True, text=True, timeout=300,
                         env={**__import__("os").environ, "COLUMNS": "160"})
    assert out.returncode == 0, out.stderr
    assert "modules of MODULARE LTGS. (34)" in out.stdout
    module = next(iter(main_harness.modules.values()))
    wires = sum(1 for w in main_harness.wires if w in module.components)
    row = next(line for line in out.stdout.splitlines() if module.part_number in line)
    assert row.rstrip(" │").split()[-1] == str(wires)


def test_pliant_harness_writes_a_self_contained_report(tmp_path):
    report = tmp_path / "harness.html"
    out = subprocess.run([sys.executable, "-m", "pliant.cli.app", "harness", str(SCENE),
                          "--report", str(report)], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 1, out.stderr
    page = report.read_text()
    assert page.startswith("<!doctype html>") and page.count("<svg") == 1
    assert "The design has red checks." in page and "rests on it" in page
    assert "connector at PNID1" in page and "Segment_3" in page
    # Offline: nothing to fetch (the SVG's namespaces are names, not links; the 3D view's
    # script is inline).
    assert "<script src" not in page and 'src="http' not in page and "href=\"http" not in page
    if not Path(CHROMIUM).exists():
        return
    harness = read_kbl(GENERATOR)
    placed = [harness.nodes[c.node].position for c in harness.connectors.values()
              if c.placement and c.node]
    with offline_report(report) as view:
        data = view_data(view)
        assert [m["n"] for m in data["meshes"]] == ["bracket"]
        assert len(placed) == 3 and drawn_in_view(view, placed, "#3d5a80") == 3
        # The installed segments in their worst check's colour (Segment_3 rests on the
        # bracket: yellow at least), drawn where their installed points project.
        (seg3,) = [x for x in data["lines"] if x["n"] == "Segment_3"]
        assert seg3["c"] in ("#b07d00", "#c0262d")
        points = np.array(seg3["p"]).reshape(-1, 3)[5:-5:4]
        assert drawn_in_view(view, points, seg3["c"]) >= 0.7 * len(points)


def test_a_damaged_kbl_file_reads_or_gets_a_typed_error(tmp_path):
    """150 damaged copies of the generator cable's file (a line dropped, a value made a
    word or an extreme number, an id renumbered, two lines swapped; seeded): each one
    reads and is judged, or ends in pliant's typed error; never another exception or a
    numerical warning (the suite turns warnings into errors)."""
    import random

    from pliant.errors import PliantError

    lines = GENERATOR.read_text(encoding="utf-8").splitlines()
    rng = random.Random(7)
    outcomes = {"read": 0, "typed": 0}
    for k in range(150):
        damaged = list(lines)
        i = rng.randrange(len(damaged))
        kind = k % 5
        if kind == 0:
            del damaged[i]
        elif kind == 1:
            damaged[i] = re.sub(r">[^<]+<", ">x<", damaged[i])
        elif kind == 2:
            extreme = rng.choice(["nan", "inf", "-1", "0", "1e308", "1e-308"])
            damaged[i] = re.sub(r">([-0-9.]+)<", f">{extreme}<", damaged[i])
        elif kind == 3:
            damaged[i] = re.sub(r"(id_|Node_|Segment_|Cartesian_point_)(\d+)",
                                lambda m: m.group(1) + str(int(m.group(2)) + 97), damaged[i])
        else:
            j = rng.randrange(len(damaged))
            damaged[i], damaged[j] = damaged[j], damaged[i]
        path = tmp_path / f"damaged{k}.kbl"
        path.write_text("\n".join(damaged), encoding="utf-8")
        try:
            harness = read_kbl(path)
            design_checks(harness, properties(harness))
            outcomes["read"] += 1
        except PliantError as err:
            assert path.name in str(err) or "overrides" in str(err), str(err)
            outcomes["typed"] += 1
    assert outcomes["read"] + outcomes["typed"] == 150
    assert outcomes["typed"] >= 40 and outcomes["read"] >= 40  # both kinds were met
