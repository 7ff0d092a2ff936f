// The handskin command as users and scripts drive it.
#include <gtest/gtest.h>

#include <filesystem>

#include "core/json_util.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"
#include "test_util.hpp"

using namespace handskin;
namespace fs = std::filesystem;

namespace {
const std::string kBin = HANDSKIN_BINARY;
const std::string kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
std::string run_args(const std::string& out) {
  return kBin + " run --back " + kFix + "back --palm " + kFix + "palm --rig " + kFix + "rig.json --out " + out;
}
}  // namespace

TEST(Cli, HelpListsSubcommands) {
  std::string out;
  ASSERT_EQ(test::run(kBin + " --help", &out), 0) << out;
  for (const char* s : {"run", "synth", "render"}) EXPECT_NE(out.find(s), std::string::npos) << s;
  ASSERT_EQ(test::run(kBin + " synth scan --help", &out), 0) << out;
  EXPECT_NE(out.find("--seed"), std::string::npos);
  EXPECT_NE(test::run(kBin, &out), 0);
}

TEST(Cli, RunOnTheFixtureWritesItsOutputs) {
  const std::string dir = test::temp_dir("run") + "/out";
  std::string out;
  ASSERT_EQ(test::run(run_args(dir) + " --pipeline " + HANDSKIN_SOURCE_DIR + "/pipelines/cubist.json", &out), 0) << out;
  EXPECT_NE(out.find("ingest"), std::string::npos);  // progress lines
  const Json report = load_json_object(dir + "/report.json");
  EXPECT_EQ(report["format"], "handskin-report/1");
  const RangeScan back = load_scan(kFix + "back"), palm = load_scan(kFix + "palm");
  const Json& ingest = report["stages"][0];
  EXPECT_EQ(ingest["name"], "ingest");
  EXPECT_EQ(ingest["back"]["returns"].get<size_t>(), back.count_valid());
  EXPECT_EQ(ingest["palm"]["returns"].get<size_t>(), palm.count_valid());
  EXPECT_GE(ingest["seconds"].get<double>(), 0.0);
  EXPECT_EQ(load_cloud(dir + "/back.ply")->size(), back.count_valid());
  EXPECT_EQ(load_cloud(dir + "/palm.ply")->size(), palm.count_valid());
  EXPECT_EQ(report["pipeline"]["slicing"]["planes"], 50);
  // Registration stage: its figures in the report, its outputs on disk.
  const Json& reg = report["stages"][1];
  EXPECT_EQ(reg["name"], "registration");
  EXPECT_EQ(reg["markers_matched"], 9);
  EXPECT_EQ(reg["status"], "ok");
  EXPECT_GT(reg["seconds"].get<double>(), 0.0);
  const Json rj = load_json_object(dir + "/registration.json");
  EXPECT_EQ(rj["format"], "handskin-registration/1");
  EXPECT_EQ(load_cloud(dir + "/merged.ply")->size(), rj["merged"]["points"].get<size_t>());
  EXPECT_GT(fs::file_size(dir + "/merged.png"), 1000u);
}

TEST(Cli, RegisterReportsAgainstTruthAndRefusesBadMarkerFiles) {
  const std::string dir = test::temp_dir("reg");
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --truth " + kFix +
                          "truth.json --out " + dir + "/r",
                      &out),
            0)
      << out;
  EXPECT_NE(out.find("against truth"), std::string::npos) << out;
  const Json rj = load_json_object(dir + "/r/registration.json");
  EXPECT_LT(rj["against_truth"]["chosen"]["rotation_deg"].get<double>(), 0.02);
  EXPECT_LT(rj["against_truth"]["chosen"]["skin_max_mm"].get<double>(), 0.1);
  EXPECT_EQ(rj["method"], "refined");
  // Marker files: wrong format, too few positions, a non-number.
  const std::vector<std::pair<std::string, std::string>> bad = {
      {R"({"format": "markers/0", "back": []})", "format"},
      {R"({"format": "handskin-markers/1", "back": [[1, 2, 3], [4, 5, 6]]})", "fewer than 3"},
      {R"({"format": "handskin-markers/1", "palm": [[1, 2, 3], [4, "x", 6], [7, 8, 9]]})", "palm[1]"},
      {R"({"format": "handskin-markers/1", "plam": [[1, 2, 3]]})", "plam"}};
  for (const auto& [text, key] : bad) {
    test::write_text(dir + "/m.json", text);
    EXPECT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --markers " + dir +
                            "/m.json --out " + dir + "/bad",
                        &out),
              1);
    EXPECT_EQ(out.rfind("error: " + dir + "/m.json", 0), 0u) << out;
    EXPECT_NE(out.find(key), std::string::npos) << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
    EXPECT_FALSE(fs::exists(dir + "/bad"));
  }
}

TEST(Cli, BadInputIsOneLineAndLeavesNoOutput) {
  const std::string dir = test::temp_dir("bad") + "/out";
  std::string out;
  // Sides swapped.
  EXPECT_EQ(test::run(kBin + " -q run --back " + kFix + "palm --palm " + kFix + "back --rig " + kFix + "rig.json --out " + dir, &out), 1);
  EXPECT_EQ(out.rfind("error: ", 0), 0u) << out;
  EXPECT_NE(out.find("palm.json"), std::string::npos) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  EXPECT_FALSE(fs::exists(dir + "/report.json"));
  // Missing rig.
  EXPECT_EQ(test::run(kBin + " -q run --back " + kFix + "back --palm " + kFix + "palm --rig /nope/rig.json --out " + dir, &out), 1);
  EXPECT_EQ(out, "error: /nope/rig.json: no such file\n");
  EXPECT_FALSE(fs::exists(dir));
  // A pipeline file with a typo.
  const std::string pipe = test::temp_dir("pipe") + "/p.json";
  test::write_text(pipe, R"({"format": "handskin-pipeline/1", "slicing": {"plains": 40}})");
  EXPECT_EQ(test::run(run_args(dir) + " --pipeline " + pipe, &out), 1);
  EXPECT_NE(out.find("slicing.plains"), std::string::npos) << out;
  // Out-of-range option of the synthetic scanner.
  EXPECT_EQ(test::run(kBin + " -q synth scan --mesh " + kFix + "truth_skin.ply --rig " + kFix + "rig.json --marker-radius -2 --out " + dir, &out), 1);
  EXPECT_NE(out.find("marker_radius_mm"), std::string::npos) << out;
}

TEST(Cli, ConvertBetweenScansAndClouds) {
  const std::string dir = test::temp_dir("conv");
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q convert --in " + kFix + "back --out " + dir + "/b.pcd", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q convert --in " + dir + "/b.pcd --out " + dir + "/b --side back", &out), 0) << out;
  EXPECT_EQ(load_scan(dir + "/b").values, load_scan(kFix + "back").values);
  EXPECT_EQ(test::run(kBin + " -q convert --in " + dir + "/b.pcd --out " + dir + "/c", &out), 1);
  EXPECT_NE(out.find("--side"), std::string::npos) << out;
}

TEST(Cli, SynthScanRunsOnAnotherHand) {
  const std::string dir = test::temp_dir("synth");
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q synth hand --hand-length 172 --spread 8 --thickness 0.9 --facet-size 2.2 --no-render --out " + dir + "/hand", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q synth scan --mesh " + dir + "/hand/hand.ply --rig " + dir + "/hand/hand_rig.json --seed 5 --out " + dir + "/scan", &out), 0) << out;
  for (const char* f : {"back.png", "back.json", "palm.png", "palm.json", "rig.json", "truth.json", "truth_skin.ply", "back_preview.png"})
    EXPECT_TRUE(fs::exists(dir + "/scan/" + f)) << f;
  ASSERT_EQ(test::run(kBin + " -q run --back " + dir + "/scan/back --palm " + dir + "/scan/palm --rig " + dir + "/scan/rig.json --out " + dir + "/out", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q render --mesh " + dir + "/hand/hand.ply --rig " + dir + "/hand/hand_rig.json --out " + dir + "/r.png", &out), 0) << out;
  EXPECT_GT(fs::file_size(dir + "/r.png"), 1000u);
}
