// The STEP writer and reader, a module of its own (libhandskin_step.so) that handskin loads
// when a STEP file is asked for (export/step.cpp): Open CASCADE's ~20 libraries would
// otherwise be loaded, and their symbols resolved, at every command's start. Its interface
// is C (step_module.h), so no C++ object or exception crosses the boundary.
//
// The patches become one Bézier face each (Geom_BezierSurface, 4 × 4 poles, P[4i + j] at
// (i, j): u along i), sewn by BRepBuilderAPI_Sewing into shells (a T-junction's long edge is
// cut where the short ones meet it), a closed shell made a solid. Each face is named after its
// patch (its ADVANCED_FACE's name), in millimetres, AP214. The names are set on the STEP
// entities the translator made of the faces (found through its finder process), and read back
// from the entities the reader translated each face from: no XCAF document, whose libraries
// (TKLCAF, TKCAF, TKXCAF, TKXDESTEP and through them TKV3d, TKService, X11, FreeImage…: 67
// shared libraries in all against 21) took this module's loading 45 → 17 ms in a bare process
// and more in handskin's, where each of their symbols is first looked for in the program's.
#include "export/step_module.h"

#include <APIHeaderSection_MakeHeader.hxx>
#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeSolid.hxx>
#include <BRepBuilderAPI_Sewing.hxx>
#include <BRepCheck_Analyzer.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <Geom_BezierSurface.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Interface_InterfaceModel.hxx>
#include <Interface_Static.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <STEPControl_Reader.hxx>
#include <STEPControl_Writer.hxx>
#include <StepRepr_RepresentationItem.hxx>
#include <StepBasic_Product.hxx>
#include <StepData_StepModel.hxx>
#include <StepShape_AdvancedFace.hxx>
#include <TopTools_DataMapOfShapeInteger.hxx>
#include <TransferBRep.hxx>
#include <TransferBRep_ShapeMapper.hxx>
#include <Transfer_FinderProcess.hxx>
#include <Transfer_TransientProcess.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_TransferWriter.hxx>
#include <XSControl_WorkSession.hxx>
#include <XSAlgo.hxx>
#include <XSAlgo_AlgoContainer.hxx>
#include <Standard_Failure.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TopExp.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedDataMapOfShapeListOfShape.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shell.hxx>
#include <TopoDS_Solid.hxx>

#include <cstdio>
#include <cstring>
#include <exception>
#include <mutex>
#include <string>
#include <vector>

namespace {

void say(HsStepSummary* out, const std::string& what) {
  std::snprintf(out->error, sizeof out->error, "%s", what.c_str());
}

// OCCT's own messages (its printers write to stdout) are silenced once: errors come back in
// the summary.
void quiet() {
  static std::once_flag once;
  std::call_once(once, [] {
    const Handle(Message_Messenger)& m = Message::DefaultMessenger();
    m->RemovePrinters(STANDARD_TYPE(Message_Printer));
  });
}

// OCCT's Interface_Static parameters are process-wide: one STEP call at a time.
std::mutex& occt_lock() {
  static std::mutex m;
  return m;
}

// Faces, shells (closed or not), solids, free edges and the bounding box of a shape.
void summarise(const TopoDS_Shape& shape, HsStepSummary* out) {
  out->faces = out->shells = out->closed_shells = out->solids = out->free_edges = 0;
  for (TopExp_Explorer e(shape, TopAbs_FACE); e.More(); e.Next()) ++out->faces;
  for (TopExp_Explorer e(shape, TopAbs_SOLID); e.More(); e.Next()) ++out->solids;
  for (TopExp_Explorer e(shape, TopAbs_SHELL); e.More(); e.Next()) {
    ++out->shells;
    if (BRep_Tool::IsClosed(e.Current())) ++out->closed_shells;
  }
  // Free edges: edges of the shape bounding one face only (none on a closed shell).
  TopTools_IndexedDataMapOfShapeListOfShape edge_faces;
  TopExp::MapShapesAndAncestors(shape, TopAbs_EDGE, TopAbs_FACE, edge_faces);
  for (int i = 1; i <= edge_faces.Extent(); ++i)
    if (edge_faces(i).Extent() < 2 && !BRep_Tool::Degenerated(TopoDS::Edge(edge_faces.FindKey(i)))) ++out->free_edges;
  // The box OCCT bounds the faces by without tessellating them: a Bézier face's control points
  // (as FreeCAD's BoundBox of an untessellated shape). The exact box (AddOptimal) took 0.1 s.
  Bnd_Box box;
  BRepBndLib::Add(shape, box, Standard_False);
  if (box.IsVoid()) {
    for (double& b : out->box) b = 0;
  } else {
    box.Get(out->box[0], out->box[1], out->box[2], out->box[3], out->box[4], out->box[5]);
  }
  out->valid = BRepCheck_Analyzer(shape).IsValid() ? 1 : 0;
}

// The read-back takes the file as written: OCCT's reader otherwise heals every shape it
// translates (ShapeFix_Shape through XSAlgo's ProcessShape: wires, faces, shells, the solid
// made again from its shell), ~70 % of its translation's time on the fixture's 98 faces. A
// CAD program heals what it reads; the check here is of what the file holds, before any
// repair: a closed, valid solid as written is one after healing too, and a file that needs
// healing to be one fails the check rather than passing it. XSAlgo's algorithm container is
// OCCT's hook for exactly this (XSAlgo::SetAlgoContainer); ours returns each shape as it was
// translated and records no healing history. It is installed for the read only, under the
// OCCT lock, and the one before it put back however the read ends.
class AsWritten : public XSAlgo_AlgoContainer {
 public:
  TopoDS_Shape ProcessShape(const TopoDS_Shape& shape, const Standard_Real, const Standard_Real, const Standard_CString,
                            const Standard_CString, Handle(Standard_Transient)& info, const Message_ProgressRange&,
                            const Standard_Boolean) const override {
    info.Nullify();
    return shape;
  }
  void MergeTransferInfo(const Handle(Transfer_TransientProcess)& tp, const Handle(Standard_Transient)& info,
                         const Standard_Integer start) const override {
    if (!info.IsNull()) XSAlgo_AlgoContainer::MergeTransferInfo(tp, info, start);
  }
  void MergeTransferInfo(const Handle(Transfer_FinderProcess)& fp, const Handle(Standard_Transient)& info) const override {
    if (!info.IsNull()) XSAlgo_AlgoContainer::MergeTransferInfo(fp, info);
  }
};

class ReadAsWritten {
 public:
  ReadAsWritten() {
    XSAlgo::Init();  // once per process; the reader's controller has called it already
    before_ = XSAlgo::AlgoContainer();
    Handle(XSAlgo_AlgoContainer) mine = new AsWritten;
    mine->SetToolContainer(before_->ToolContainer());
    XSAlgo::SetAlgoContainer(mine);
  }
  ~ReadAsWritten() { XSAlgo::SetAlgoContainer(before_); }
  ReadAsWritten(const ReadAsWritten&) = delete;
  ReadAsWritten& operator=(const ReadAsWritten&) = delete;

 private:
  Handle(XSAlgo_AlgoContainer) before_;
};

}  // namespace

extern "C" int handskin_step_write(int n_patches, const double* poles, const char* const* names, const char* path,
                                   double sew_tolerance_mm, HsStepSummary* out) {
  std::memset(out, 0, sizeof *out);
  std::lock_guard<std::mutex> lock(occt_lock());
  try {
    quiet();
    if (n_patches <= 0) return say(out, "no patches to write"), 1;
    // 1. One face per patch.
    std::vector<TopoDS_Face> faces;
    for (int p = 0; p < n_patches; ++p) {
      TColgp_Array2OfPnt P(1, 4, 1, 4);
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
          const double* c = poles + (static_cast<size_t>(p) * 16 + 4 * i + j) * 3;
          P.SetValue(i + 1, j + 1, gp_Pnt(c[0], c[1], c[2]));
        }
      Handle(Geom_BezierSurface) surface = new Geom_BezierSurface(P);
      BRepBuilderAPI_MakeFace make(surface, Precision::Confusion());
      if (!make.IsDone()) return say(out, "patch " + std::string(names[p]) + ": no face could be made of it"), 1;
      faces.push_back(make.Face());
    }
    // 2. Sewn: the shared borders are the same curves to rounding, so a small tolerance joins
    // them and nothing else.
    BRepBuilderAPI_Sewing sewing(sew_tolerance_mm);
    for (const TopoDS_Face& f : faces) sewing.Add(f);
    sewing.Perform();
    TopoDS_Shape sewn = sewing.SewedShape();
    // 3. A closed shell is a solid.
    TopoDS_Shape result = sewn;
    if (sewn.ShapeType() == TopAbs_SHELL && BRep_Tool::IsClosed(sewn)) {
      BRepBuilderAPI_MakeSolid solid(TopoDS::Shell(sewn));
      if (solid.IsDone()) result = solid.Solid();
    }
    // 4. The STEP model of the shape, each face's entity named after its patch.
    STEPControl_Writer writer;  // first: it registers the parameters set below
    Interface_Static::SetCVal("write.step.schema", "AP214IS");
    Interface_Static::SetCVal("write.step.unit", "MM");
    if (writer.Transfer(result, STEPControl_AsIs) != IFSelect_RetDone)
      return say(out, "OCCT could not translate the shape to STEP"), 1;
    const Handle(Transfer_FinderProcess) made = writer.WS()->TransferWriter()->FinderProcess();
    for (int p = 0; p < n_patches; ++p) {
      const TopoDS_Shape& modified = sewing.Modified(faces[static_cast<size_t>(p)]);
      const TopoDS_Shape& face = modified.IsNull() ? faces[static_cast<size_t>(p)] : modified;
      const Handle(StepRepr_RepresentationItem) item =
          Handle(StepRepr_RepresentationItem)::DownCast(made->FindTransient(TransferBRep::ShapeMapper(made, face)));
      // A face the sewing made into something else has no entity of its own: left unnamed, as
      // the XCAF writer did (the read-back names then count fewer than the patches).
      if (!item.IsNull()) item->SetName(new TCollection_HAsciiString(names[p]));
    }
    // The product named as the document's root was (write.step.product.name would number it).
    const Handle(Interface_InterfaceModel) model = writer.Model();
    for (int i = 1; i <= model->NbEntities(); ++i)
      if (const Handle(StepBasic_Product) product = Handle(StepBasic_Product)::DownCast(model->Value(i)); !product.IsNull()) {
        product->SetId(new TCollection_HAsciiString("handskin patches"));
        product->SetName(new TCollection_HAsciiString("handskin patches"));
      }
    // The header without the wall-clock time OCCT puts there: the same patches give the same
    // bytes.
    APIHeaderSection_MakeHeader header(writer.Model());
    header.SetName(new TCollection_HAsciiString("handskin patches"));
    header.SetTimeStamp(new TCollection_HAsciiString("2000-01-01T00:00:00"));
    header.SetAuthorValue(1, new TCollection_HAsciiString("handskin"));
    header.SetOrganizationValue(1, new TCollection_HAsciiString(""));
    header.SetOriginatingSystem(new TCollection_HAsciiString("handskin, Open CASCADE 7"));
    header.SetDescriptionValue(1, new TCollection_HAsciiString("bicubic Bezier patches of a hand's skin, mm"));
    if (writer.Write(path) != IFSelect_RetDone) return say(out, std::string("cannot write ") + path), 1;
    out->faces = n_patches;  // the shape's figures: read the file back (handskin_step_read)
    return 0;
  } catch (const Standard_Failure& e) {
    say(out, std::string("OCCT: ") + e.GetMessageString());
  } catch (const std::exception& e) {
    say(out, e.what());
  } catch (...) {
    say(out, "OCCT failed");
  }
  return 1;
}

extern "C" int handskin_step_read(const char* path, HsStepSummary* out, char* names, int names_size) {
  std::memset(out, 0, sizeof *out);
  if (names && names_size > 0) names[0] = 0;
  std::lock_guard<std::mutex> lock(occt_lock());
  try {
    quiet();
    STEPControl_Reader reader;  // first: it initialises XSAlgo, whose container is swapped
    const ReadAsWritten as_written;
    if (reader.ReadFile(path) != IFSelect_RetDone) return say(out, std::string(path) + ": not a STEP file OCCT can read"), 1;
    if (reader.TransferRoots() == 0) return say(out, std::string(path) + ": OCCT could not translate it"), 1;
    const TopoDS_Shape all = reader.OneShape();
    // Each face's name: that of the entity it was translated from (faces in the shape's order).
    const Handle(Transfer_TransientProcess) tp = reader.WS()->TransferReader()->TransientProcess();
    const Handle(Interface_InterfaceModel) model = reader.Model();
    TopTools_DataMapOfShapeInteger entity_of;
    for (int i = 1; i <= model->NbEntities(); ++i) {
      const Handle(StepShape_AdvancedFace) f = Handle(StepShape_AdvancedFace)::DownCast(model->Value(i));
      if (f.IsNull() || f->Name().IsNull() || f->Name()->Length() == 0) continue;
      const TopoDS_Shape face = TransferBRep::ShapeResult(tp, f);
      if (!face.IsNull()) entity_of.Bind(face, i);
    }
    std::string listed;
    for (TopExp_Explorer e(all, TopAbs_FACE); e.More(); e.Next())
      if (entity_of.IsBound(e.Current()))
        listed += std::string(Handle(StepShape_AdvancedFace)::DownCast(model->Value(entity_of(e.Current())))->Name()->ToCString()) + "\n";
    summarise(all, out);
    if (names && names_size > 0) std::snprintf(names, static_cast<size_t>(names_size), "%s", listed.c_str());
    return 0;
  } catch (const Standard_Failure& e) {
    say(out, std::string("OCCT: ") + e.GetMessageString());
  } catch (...) {
    say(out, "OCCT failed reading the file");
  }
  return 1;
}
