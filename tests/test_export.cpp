// The patches as STEP (issue 40): Open CASCADE writes them (libhandskin_step.so) and reads
// them back here. FreeCAD's reading is the slow test step_freecad (scripts/check_step_clients.sh).
#include <gtest/gtest.h>

#include <filesystem>
#include <limits>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "export/step.hpp"
#include "test_util.hpp"

namespace fs = std::filesystem;
using namespace handskin;

namespace {
// One bicubic patch of a plane z = 0 over [x0, x0 + 10] × [0, 10].
BezierPatch flat_patch(double x0, const std::string& name) {
  BezierPatch p;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) p.P[4 * i + j] = Eigen::Vector3d(x0 + 10.0 * i / 3, 10.0 * j / 3, 0);
  p.name = name;
  return p;
}
}  // namespace

TEST(Step, TheRunsPatchesAreOneClosedSolidOfNamedFaces) {
  const std::string run = test::default_fixture_run();
  const Json patches = load_json_object(run + "/patches.json");
  const StepSummary s = read_step(run + "/patches.step");
  ASSERT_EQ(static_cast<size_t>(s.faces), patches["patches"].size());
  EXPECT_EQ(s.shells, 1);
  EXPECT_EQ(s.closed_shells, 1);
  EXPECT_EQ(s.solids, 1);
  EXPECT_EQ(s.free_edges, 0);
  EXPECT_TRUE(s.valid);
  // Every face carries its patch's name, in the patches' order.
  ASSERT_EQ(s.names.size(), patches["patches"].size());
  Eigen::AlignedBox3d control;
  for (size_t f = 0; f < s.names.size(); ++f) {
    const Json& p = patches["patches"][f];
    EXPECT_EQ(s.names[f], p["name"].get<std::string>());
    for (const auto& c : p["control_points"]) control.extend(Eigen::Vector3d(c[0], c[1], c[2]));
  }
  // In millimetres, where the patches are: an untessellated Bézier face is bounded by its poles.
  EXPECT_LT((s.box.min() - control.min()).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_LT((s.box.max() - control.max()).cwiseAbs().maxCoeff(), 1e-6);
  // report.json gives the figures read back from the file as written.
  const Json r = load_json_object(run + "/report.json");
  EXPECT_EQ(r["patches_step"]["faces"], s.faces);
  EXPECT_EQ(r["patches_step"]["closed_shells"], 1);
  EXPECT_EQ(r["patches_step"]["solids"], 1);
  EXPECT_EQ(r["outputs"]["patches_step"], "patches.step");
}

TEST(Step, AFileThatIsASolidOnlyOnceRepairedIsReadAsItIs) {
  // The run's patches.step with one face written turned over (its ADVANCED_FACE's same_sense
  // flag .T. -> .F.): OCCT's default reading heals it (ShapeFix_Shell turns the face back) and
  // finds a valid solid; read_step takes the file as written and finds the shell's faces
  // disagree (BRepCheck: bad orientation), so a file a CAD program must repair is not passed.
  const std::string run = test::default_fixture_run();
  std::string text = read_file(run + "/patches.step");
  const size_t face = text.find("ADVANCED_FACE('palm.0.back1'");
  ASSERT_NE(face, std::string::npos);
  const size_t flag = text.find(".T.);", face);
  ASSERT_NE(flag, std::string::npos);
  ASSERT_LT(flag, text.find('\n', face));
  text.replace(flag, 3, ".F.");
  const std::string dir = test::temp_dir("step-turned");
  write_file_atomic(dir + "/turned.step", text);
  const StepSummary turned = read_step(dir + "/turned.step");
  EXPECT_EQ(turned.faces, 98);
  EXPECT_FALSE(turned.valid);
  // The file as the run wrote it reads as a valid closed solid without any repair.
  const StepSummary as_written = read_step(run + "/patches.step");
  EXPECT_TRUE(as_written.valid);
  EXPECT_EQ(as_written.closed_shells, 1);
  EXPECT_EQ(as_written.solids, 1);
}

TEST(Step, AnOpenSheetStaysAnOpenShellWithItsFreeEdges) {
  // Two flat patches sharing one border: sewn into one shell, open, not a solid; 6 free edges.
  const std::string dir = test::temp_dir("step-open");
  const std::string path = dir + "/sheet.step";
  write_patches_step({flat_patch(0, "left"), flat_patch(10, "right")}, path);
  const StepSummary s = read_step(path);
  EXPECT_EQ(s.faces, 2);
  EXPECT_EQ(s.shells, 1);
  EXPECT_EQ(s.closed_shells, 0);
  EXPECT_EQ(s.solids, 0);
  EXPECT_EQ(s.free_edges, 6);
  EXPECT_EQ(s.names, (std::vector<std::string>{"left", "right"}));
  EXPECT_NEAR(s.box.max().x(), 20, 1e-6);
  EXPECT_NEAR(s.box.min().y(), 0, 1e-6);
}

TEST(Step, BadInputIsRefusedInOneLineNamingTheFile) {
  const std::string dir = test::temp_dir("step-bad");
  BezierPatch p = flat_patch(0, "p");
  p.P[5].x() = std::numeric_limits<double>::quiet_NaN();
  try {
    write_patches_step({p}, dir + "/nan.step");
    ADD_FAILURE() << "a NaN control point was written";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("nan.step"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not finite"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir + "/nan.step"));
  EXPECT_THROW(write_patches_step({}, dir + "/none.step"), InputError);
  EXPECT_THROW(write_patches_step({flat_patch(0, "p")}, dir + "/no/such/folder/x.step"), InputError);
  write_file_atomic(dir + "/junk.step", "ISO-10303-21;\nthis is not STEP\n");
  EXPECT_THROW(read_step(dir + "/junk.step"), InputError);
  EXPECT_THROW(read_step(dir + "/missing.step"), InputError);
}
