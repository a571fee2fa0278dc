"""Write ``bracket_assembly.step``: a tiny CAD assembly in millimetres for the tests and
the example scene (the committed file was made by this script).

Needs OpenCASCADE's Python bindings (``pip install cadquery-ocp``), which pliant itself
does not: pliant reads STEP through cascadio. The assembly has named products placed by
instances, as a CAD tool exports them:

- ``bracket``: a 120 x 40 x 10 mm plate, its corner at (100, -20, 0) mm;
- ``manifold``: a tube of 25 mm radius and 200 mm along y, its axis through (0, 0, 60) mm;
- ``bolt``: a 6 mm by 30 mm pin, two instances at (130, 0, 10) and (190, 0, 10) mm.
"""

from __future__ import annotations

import sys
from pathlib import Path

from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt, gp_Trsf, gp_Vec
from OCP.IFSelect import IFSelect_RetDone
from OCP.Interface import Interface_Static
from OCP.STEPCAFControl import STEPCAFControl_Writer
from OCP.STEPControl import STEPControl_AsIs
from OCP.TCollection import TCollection_ExtendedString
from OCP.TDataStd import TDataStd_Name
from OCP.TDocStd import TDocStd_Document
from OCP.TopLoc import TopLoc_Location
from OCP.XCAFDoc import XCAFDoc_DocumentTool


def _name(label, text: str) -> None:
    TDataStd_Name.Set_s(label, TCollection_ExtendedString(text))


def _placed(x: float, y: float, z: float) -> TopLoc_Location:
    move = gp_Trsf()
    move.SetTranslation(gp_Vec(x, y, z))
    return TopLoc_Location(move)


def main(path: Path) -> None:
    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    bay = tool.NewShape()
    _name(bay, "bay")
    plate = BRepPrimAPI_MakeBox(120.0, 40.0, 10.0).Shape()
    tube = BRepPrimAPI_MakeCylinder(
        gp_Ax2(gp_Pnt(0.0, -100.0, 60.0), gp_Dir(0.0, 1.0, 0.0)), 25.0, 200.0).Shape()
    pin = BRepPrimAPI_MakeCylinder(3.0, 30.0).Shape()
    for text, shape, places in (("bracket", plate, [(100.0, -20.0, 0.0)]),
                                ("manifold", tube, [(0.0, 0.0, 0.0)]),
                                ("bolt", pin, [(130.0, 0.0, 10.0), (190.0, 0.0, 10.0)])):
        product = tool.AddShape(shape, False)
        _name(product, text)
        for x, y, z in places:
            tool.AddComponent(bay, product, _placed(x, y, z))
    tool.UpdateAssemblies()
    Interface_Static.SetCVal_s("write.step.unit", "MM")
    Interface_Static.SetCVal_s("write.step.schema", "AP214IS")
    writer = STEPCAFControl_Writer()
    writer.SetNameMode(True)
    writer.Transfer(doc, STEPControl_AsIs)
    if writer.Write(str(path)) != IFSelect_RetDone:
        raise SystemExit(f"could not write {path}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1
         else Path(__file__).with_name("bracket_assembly.step"))
