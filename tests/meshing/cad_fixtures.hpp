// CAD test models written by OpenCASCADE itself: a box (12 line edges), a B-spline curve, a circle.
#pragma once

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <GC_MakeCircle.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_Circle.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Controller.hxx>
#include <IGESControl_Writer.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_Printer.hxx>
#include <STEPControl_Writer.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array1OfPnt.hxx>
#include <TopoDS_Shape.hxx>

#include <stdexcept>
#include <string>

namespace rodfab::testing {

// OpenCASCADE's writers report to stdout by default.
inline void quiet() { Message::DefaultMessenger()->RemovePrinters(STANDARD_TYPE(Message_Printer)); }

inline void writeStep(const TopoDS_Shape& shape, const std::string& file) {
  quiet();
  STEPControl_Writer writer;
  if (writer.Transfer(shape, STEPControl_AsIs) != IFSelect_RetDone || writer.Write(file.c_str()) != IFSelect_RetDone)
    throw std::runtime_error("cannot write " + file);
}

inline void writeIges(const TopoDS_Shape& shape, const std::string& file) {
  quiet();
  IGESControl_Controller::Init();
  IGESControl_Writer writer("MM", 1);  // BRep mode
  writer.AddShape(shape);
  writer.ComputeModel();
  if (!writer.Write(file.c_str())) throw std::runtime_error("cannot write " + file);
}

inline TopoDS_Shape box(double dx, double dy, double dz) { return BRepPrimAPI_MakeBox(dx, dy, dz).Shape(); }

// A cubic B-spline with 6 poles and non-uniform interior knots, not in a plane.
inline Handle(Geom_BSplineCurve) testSpline() {
  TColgp_Array1OfPnt poles(1, 6);
  poles(1) = gp_Pnt(0, 0, 0), poles(2) = gp_Pnt(10, 5, 2), poles(3) = gp_Pnt(20, -5, 6);
  poles(4) = gp_Pnt(30, 8, 1), poles(5) = gp_Pnt(38, 0, -4), poles(6) = gp_Pnt(45, 3, 0);
  TColStd_Array1OfReal knots(1, 4);
  knots(1) = 0, knots(2) = 0.3, knots(3) = 0.45, knots(4) = 1;
  TColStd_Array1OfInteger mults(1, 4);
  mults(1) = 4, mults(2) = 1, mults(3) = 1, mults(4) = 4;
  return new Geom_BSplineCurve(poles, knots, mults, 3);
}

inline Handle(Geom_Circle) testCircle() {
  return new Geom_Circle(gp_Ax2(gp_Pnt(3, -2, 7), gp_Dir(1, 1, 1)), 5.0);
}

inline TopoDS_Shape edgeOf(const Handle(Geom_Curve)& curve) { return BRepBuilderAPI_MakeEdge(curve).Edge(); }

}  // namespace rodfab::testing
