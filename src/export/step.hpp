#pragma once
/// The patches as STEP, for CAD (FreeCAD, Rhino, SolidWorks, Fusion): one Bézier face per
/// patch, named after it, sewn into one shell (a solid when closed), in millimetres. Open
/// CASCADE does the work, in a module loaded at the first call (libhandskin_step.so,
/// step_module.cpp), so that its libraries are not loaded by commands that write no STEP.
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "patches/patches.hpp"

namespace handskin {

/// A STEP shape as OCCT sees it.
struct StepSummary {
  int faces = 0, shells = 0, closed_shells = 0, solids = 0;
  int free_edges = 0;  ///< edges bounding one face only (0 when closed)
  bool valid = false;  ///< OCCT's BRepCheck finds the shape valid
  Eigen::AlignedBox3d box;  ///< as OCCT bounds the faces untessellated: their control points' box
  std::vector<std::string> names;  ///< the faces' names (read_step only)
};

/// Loads the Open CASCADE module on a thread of its own, ahead of the first STEP call (it is
/// loaded at the first call otherwise): for commands that will write STEP, so that the loading
/// overlaps their other work.
void preload_step();

/// Writes `patches` to `path` (STEP AP214, mm), their borders sewn within `sew_tolerance_mm`
/// (the shared borders are the same curves to rounding). Read the file back (read_step) for
/// the shape as written. Throws InputError naming the path when OCCT cannot.
void write_patches_step(const std::vector<BezierPatch>& patches, const std::string& path,
                               double sew_tolerance_mm = 1e-3);

/// A STEP file made in memory: its bytes, and its shape as OCCT reads it back from them.
struct StepFile {
  std::string bytes;
  StepSummary shape;
};

/// `patches` as a STEP file (write_patches_step, through a private temporary file), with the
/// shape read back from the bytes: for a caller that writes its outputs later (run makes it
/// beside its pictures). Throws InputError naming "patches.step" when OCCT cannot.
StepFile patches_step_file(const std::vector<BezierPatch>& patches, double sew_tolerance_mm = 1e-3);

/// Reads a STEP file with OCCT and summarises its shape (faces, shells, the box, the faces'
/// names) as the file holds it: without the shape healing OCCT's reader applies by default
/// (a CAD program's), so a shape that is valid and closed only once repaired is not found so.
/// Throws InputError naming the path when it cannot be read.
StepSummary read_step(const std::string& path);

}  // namespace handskin
