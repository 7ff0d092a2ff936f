// The handskin command as users and scripts drive it.
#include <gtest/gtest.h>

#include <fstream>
#include <iterator>

#include <regex>
#include <sstream>

#include <algorithm>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/json_util.hpp"
#include "core/png_io.hpp"
#include "mesh/mesh.hpp"
#include "posture/angle_table.hpp"
#include "core/dof.hpp"
#include "core/rig.hpp"
#include "scan/cloud.hpp"
#include "scan/cubist_io.hpp"
#include "core/output_set.hpp"
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

// The heavy libraries that only some commands need are modules loaded at their first use
// (core/module.hpp): Open CASCADE (STEP), PCL's readers and VTK behind them (cloud files),
// cpp-httplib with OpenSSL and brotli (the studio). A process's start loads none of them: the
// loader's own list of what it maps at start (LD_TRACE_LOADED_OBJECTS, as ldd asks it).
TEST(Cli, AProcessStartLoadsNoneOfTheModulesLibraries) {
  std::string out;
  ASSERT_EQ(test::run("LD_TRACE_LOADED_OBJECTS=1 " + kBin, &out), 0) << out;
  ASSERT_NE(out.find("libstdc++"), std::string::npos) << out;  // the list is the loader's
  for (const char* lib : {"libTKernel", "libpcl_io", "libvtk", "libcpp-httplib", "libssl", "libbrotli"})
    EXPECT_EQ(out.find(lib), std::string::npos) << lib << " is loaded at start:\n" << out;
}

// Bad usage exits 2 with one line naming the flag or the command (issue 40's list), and
// writes nothing; bad data exits 1.
TEST(Cli, EveryUsageErrorExitsTwoInOneLineNamingItsFlag) {
  const std::string dir = test::temp_dir("usage") + "/out";
  const std::string glb = test::default_fixture_run() + "/skin.glb", skin = test::default_fixture_run() + "/skin.ply";
  const std::pair<std::string, std::string> cases[] = {
      {"rnu", "unknown command 'rnu' (did you mean run?)"},
      {"--threads 2 rnu", "unknown command 'rnu'"},
      {"render --out " + dir + "/x.png", "give exactly one of --mesh or --scan"},
      {"render --mesh " + skin + " --scan " + kFix + "back --out " + dir + "/x.png", "give exactly one of --mesh or --scan"},
      {"render --mesh " + skin + " --view top --out " + dir + "/x.png", "--view: unknown view 'top'"},
      {"pose --skin " + glb, "nothing to write"},
      {"synth hand --side middle --out " + dir, "--side: 'middle'"},
      {"calibrate --angles " + kFix + "rig.json --weights foo --out " + dir + "/m.json", "--weights: must be 'thesis' or 'inverse'"},
      {"solve --model builtin:anatomical --set X=abc", "--set: unknown DOF 'X'"},
      {"solve --model builtin:anatomical --set index.pip.flex=abc", "--set: 'index.pip.flex=abc'"},
      {"solve --model builtin:nope", "--model: unknown built-in model 'nope'"},
      {"patches --skin-dir " + test::default_fixture_run() + " --count 24 --out " + dir, "--count: patches.count 24 cannot be honoured"},
      {"pose --model " + glb + " --out " + dir + "/x.ply", "--model"},
      {"synth scan --mesh " + kFix + "truth_skin.ply --rig " + kFix + "rig.json --marker-radius 50 --out " + dir, "--marker-radius: must be in"},
      {"synth hand --hand-length 5 --out " + dir, "--hand-length: must be in [120, 260]"},
  };
  for (const auto& [args, says] : cases) {
    std::string out;
    EXPECT_EQ(test::run(kBin + " -q " + args, &out), 2) << args << ": " << out;
    EXPECT_NE(out.find(says), std::string::npos) << args << ": " << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << args << ": " << out;
    EXPECT_EQ(out.rfind("error: ", 0), 0u) << out;
  }
  EXPECT_FALSE(fs::exists(dir));
  // Bad data stays 1: a scan stem that is no scan.
  std::string out;
  EXPECT_EQ(test::run(kBin + " -q render --scan " + kFix + "nothing --out " + dir + "/x.png", &out), 1) << out;
  // A scan named by one of its files is its stem: the same picture as by the stem.
  const std::string pics = test::temp_dir("scan_by_file");
  for (const char* given : {"back", "back.json", "back.png"})
    EXPECT_EQ(test::run(kBin + " -q render --scan " + kFix + given + " --out " + pics + "/" + given + ".png", &out), 0)
        << given << ": " << out;
  EXPECT_EQ(read_file(pics + "/back.json.png"), read_file(pics + "/back.png"));
  EXPECT_EQ(read_file(pics + "/back.png.png"), read_file(pics + "/back.png"));
  // At the scan's proportions: the fixture's 512 scanlines 250/512 mm apart and 512 points
  // 200/512 mm apart cover 250 x 200 mm, so its picture is 512 wide and 640 tall (it was 512 x
  // 512, the hand 20 % short); --size sets the width.
  const auto png_size = [](const std::string& png) {
    const auto be32 = [&](size_t at) {
      return (static_cast<unsigned>(static_cast<unsigned char>(png[at])) << 24) |
             (static_cast<unsigned>(static_cast<unsigned char>(png[at + 1])) << 16) |
             (static_cast<unsigned>(static_cast<unsigned char>(png[at + 2])) << 8) |
             static_cast<unsigned>(static_cast<unsigned char>(png[at + 3]));
    };
    return std::make_pair(be32(16), be32(20));  // IHDR: width, height
  };
  EXPECT_EQ(png_size(read_file(pics + "/back.png")), std::make_pair(512u, 640u));
  ASSERT_EQ(test::run(kBin + " -q render --scan " + kFix + "back --size 300 --out " + pics + "/small.png", &out), 0) << out;
  EXPECT_EQ(png_size(read_file(pics + "/small.png")), std::make_pair(300u, 375u));
}

TEST(Cli, PipelineCommandsRunOnHugePagesWhereTheKernelGivesThemOnRequest) {
  // Where transparent huge pages are given to memory that asks ("[madvise]"), a pipeline
  // command runs itself again with glibc's allocator asking (docs/performance.md) — unless a
  // 4 kB page's first touch is cheap here, which the command times and says; its --verbose
  // last line says which. HANDSKIN_HUGE_PAGES=1 asks for them without the probe,
  // HANDSKIN_HUGE_PAGES=0 keeps the pages as they are, as does a preloaded library; other
  // commands (here `solve`) do not run again.
  std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
  const std::string mode((std::istreambuf_iterator<char>(thp)), std::istreambuf_iterator<char>());
  const bool on_request = mode.find("[madvise]") != std::string::npos;
  const std::string dir = test::temp_dir("hugepages");
  const std::string reg = kBin + " -v register --back " + kFix + "back --palm " + kFix + "palm --out ";
  const std::string note = "(allocator on transparent huge pages)";
  const std::string probed = "(allocator on 4 kB pages: a page's first touch takes ";
  std::string out;
  ASSERT_EQ(test::run("env -u GLIBC_TUNABLES -u LD_PRELOAD HANDSKIN_HUGE_PAGES=1 " + reg + dir + "/a 2>&1", &out), 0) << out;
  EXPECT_EQ(out.find(note) != std::string::npos, on_request) << mode << out;
  EXPECT_EQ(out.find(probed), std::string::npos) << out;
  // Left to the probe: one or the other where the kernel gives them on request.
  ASSERT_EQ(test::run("env -u GLIBC_TUNABLES -u LD_PRELOAD " + reg + dir + "/d 2>&1", &out), 0) << out;
  EXPECT_EQ(out.find(note) != std::string::npos || out.find(probed) != std::string::npos, on_request) << mode << out;
  ASSERT_EQ(test::run("env -u GLIBC_TUNABLES -u LD_PRELOAD HANDSKIN_HUGE_PAGES=0 " + reg + dir + "/b 2>&1", &out), 0) << out;
  EXPECT_EQ(out.find(note), std::string::npos) << out;
  EXPECT_EQ(out.find(probed), std::string::npos) << out;
  // Nor under a preloaded library (a profiler's, another allocator): libm stands for one here.
  ASSERT_EQ(test::run("env -u GLIBC_TUNABLES LD_PRELOAD=libm.so.6 " + reg + dir + "/c 2>&1", &out), 0) << out;
  EXPECT_EQ(out.find(note), std::string::npos) << out;
  ASSERT_EQ(test::run("env -u GLIBC_TUNABLES -u LD_PRELOAD " + kBin + " -v solve --model builtin:anatomical --set index.mcp.flex=40 2>&1", &out), 0)
      << out;
  EXPECT_EQ(out.find(note), std::string::npos) << out;
  EXPECT_EQ(out.find(probed), std::string::npos) << out;
  // The folders hold the same registration (the pages change no result).
  const Json a = Json::parse(read_file(dir + "/a/registration.json")), b = Json::parse(read_file(dir + "/b/registration.json"));
  EXPECT_EQ(a.at("back_to_palm").dump(), b.at("back_to_palm").dump());
  EXPECT_EQ(a.at("markers_palm").dump(), b.at("markers_palm").dump());
  const Json d = Json::parse(read_file(dir + "/d/registration.json"));
  EXPECT_EQ(a.at("back_to_palm").dump(), d.at("back_to_palm").dump());
}

// A run folder travels (issue 40): report.json's inputs are relative to the report, and
// absolute in inputs_absolute; `patches --skin-dir` works from another working directory on a
// moved copy (finding the rig by its absolute path), and says which rig is missing when it is
// gone.
TEST(Cli, ARunFolderWorksFromAnywhereAndWhenMoved) {
  const std::string base = test::temp_dir("travel");
  fs::create_directories(base + "/work");
  std::string out;
  // The run started from a working directory of its own, with relative paths.
  const std::string rel_fix = fs::relative(kFix, base + "/work").string() + "/";
  ASSERT_EQ(test::run("cd " + base + "/work && " + kBin + " -q run --back " + rel_fix + "back --palm " + rel_fix + "palm --rig " +
                          rel_fix + "rig.json --out out/r",
                      &out),
            0)
      << out;
  const std::string run = base + "/work/out/r";
  const Json r = load_json_object(run + "/report.json");
  for (const char* key : {"back", "palm", "rig"}) {
    const std::string rel = r["inputs"][key].get<std::string>(), abs = r["inputs_absolute"][key].get<std::string>();
    EXPECT_TRUE(fs::path(abs).is_absolute()) << abs;
    EXPECT_EQ(fs::weakly_canonical(fs::path(run) / rel), fs::weakly_canonical(abs)) << key << ": " << rel;
  }
  EXPECT_TRUE(fs::exists(fs::path(run) / r["inputs"]["rig"].get<std::string>()));
  EXPECT_EQ(r["inputs"]["pipeline"], "(built-in defaults)");
  EXPECT_EQ(r["inputs_absolute"]["posture_model"], r["inputs"]["posture_model"]);  // builtin: no path
  // From elsewhere, on a copy moved away from its inputs.
  fs::copy(run, base + "/moved", fs::copy_options::recursive);
  fs::create_directories(base + "/elsewhere");
  ASSERT_EQ(test::run("cd " + base + "/elsewhere && " + kBin + " -q patches --skin-dir ../moved --out p", &out), 0) << out;
  EXPECT_TRUE(fs::exists(base + "/elsewhere/p/patches.step"));
  // Its rig gone as well: one line naming --rig and the rig looked for.
  Json broken = r;
  broken["inputs"]["rig"] = "../nowhere/rig.json";
  broken["inputs_absolute"]["rig"] = base + "/nowhere/rig.json";
  save_json(base + "/moved/report.json", broken);
  EXPECT_EQ(test::run("cd " + base + "/elsewhere && " + kBin + " -q patches --skin-dir ../moved --out q", &out), 2) << out;
  EXPECT_NE(out.find("--rig: the rig"), std::string::npos) << out;
  EXPECT_NE(out.find("nowhere/rig.json"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(base + "/elsewhere/q"));
}

TEST(Cli, TheScansAsCloudsAreWrittenOnRequestOnly) {
  // back.ply and palm.ply repeat the input scans (6 MB): --scan-clouds asks for them
  // (RunOnTheFixtureWritesItsOutputs checks them then); a scan pair's run without it has none.
  const std::string dir = test::default_fixture_run();
  EXPECT_FALSE(std::filesystem::exists(dir + "/back.ply"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/palm.ply"));
  EXPECT_FALSE(load_json_object(dir + "/report.json")["outputs"].contains("back_cloud"));
  std::string out;
  EXPECT_EQ(test::run(kBin + " run --cloud " + kFix + "back.json --scan-clouds --out " + test::temp_dir("sc") + "/o", &out), 2)
      << out;
  EXPECT_NE(out.find("--scan-clouds"), std::string::npos) << out;
}

TEST(Cli, RunOnTheFixtureWritesItsOutputs) {
  const std::string dir = test::temp_dir("run") + "/out";
  std::string out;
  ASSERT_EQ(test::run(run_args(dir) + " --baseline --scan-clouds --pipeline " + HANDSKIN_SOURCE_DIR + "/pipelines/cubist.json", &out), 0)
      << out;
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
  // Skin stage: a watertight labelled mesh, the baseline beside it (asked for), the files on disk.
  const Json& skin = report["stages"][2];
  EXPECT_EQ(skin["name"], "skin");
  EXPECT_EQ(skin["skeleton"]["used"], "given");
  EXPECT_TRUE(skin["mesh"]["watertight"].get<bool>());
  EXPECT_LE(skin["mesh"]["triangles"].get<int>(), 10000);
  EXPECT_LT(skin["cloud_to_skin_mm"]["mean"].get<double>(), 0.15);
  EXPECT_GT(skin["baseline"]["mesh"]["triangles"].get<int>(), 1000);
  EXPECT_LT(skin["baseline"]["cloud_to_baseline_mm"]["mean"].get<double>(), 0.2);
  for (const char* f : {"skin.ply", "skin.obj", "skin.png", "slices.json", "baseline.ply"})
    EXPECT_TRUE(fs::exists(dir + "/" + f)) << f;
  EXPECT_EQ(report["stages"][3]["name"], "patches");
  EXPECT_LT(report["stages"][3]["continuity"]["g0_gap_mm"].get<double>(), 1e-9);
  EXPECT_EQ(load_json_object(dir + "/patches.json")["patches"].size(), 98u);
  EXPECT_EQ(report["stages"][4]["name"], "rigging");
  EXPECT_EQ(report["stages"][4]["binding"], "smooth");
  EXPECT_GT(fs::file_size(dir + "/skin.glb"), 100000u);
  {  // report.html shows the rigged skin posed: six pictures after the four of the patches
    const std::string html = read_file(dir + "/report.html");
    const size_t at = html.find("The rigged skin, posed");
    ASSERT_NE(at, std::string::npos);
    size_t pictures = 0;
    for (size_t k = html.find("data:image/png;base64,", at); k != std::string::npos; k = html.find("data:image/png;base64,", k + 1))
      ++pictures;
    EXPECT_EQ(pictures, 6u);
  }
  EXPECT_EQ(report["stages"][5]["name"], "texture");  // the fixture has its photos
  EXPECT_EQ(report["stages"][5]["size"], 1024);
  EXPECT_TRUE(fs::exists(dir + "/texture.png"));
  EXPECT_EQ(report["stages"][6]["name"], "pictures");
  EXPECT_GT(report["stages"][6]["patches_step_seconds"].get<double>(), 0.0);
  EXPECT_EQ(report["stages"][7]["name"], "write");
  {  // the stages account for the run: their seconds add up to its total, but the few steps between them
    double sum = 0;
    for (const auto& st : report["stages"]) sum += st["seconds"].get<double>();
    const double total = report["total_seconds"].get<double>();
    EXPECT_LE(sum, total * (1 + 1e-9));
    EXPECT_GT(sum, 0.9 * total) << "stages " << sum << " s of a run of " << total << " s";
  }
  EXPECT_EQ(report["outputs"]["report"], "report.json");  // relative to the report: the folder travels
  EXPECT_EQ(load_json_object(dir + "/slices.json")["format"], "handskin-slices/1");
  // Only what the run wrote is in the folder (and the manifest of it, listing each): no
  // staging folder left beside it.
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file() && e.path().filename() != kManifestName;
  EXPECT_EQ(files, report["outputs"].size());
  EXPECT_EQ(read_manifest(dir).size(), files);
  for (const auto& e : fs::directory_iterator(fs::path(dir).parent_path()))
    EXPECT_EQ(e.path().filename().string().find(".handskin-staging"), std::string::npos) << e.path();
  // A run without --baseline does not make one, and takes the earlier run's away with it:
  // left beside the new report it would look like part of it.
  ASSERT_EQ(test::run(run_args(dir) + " -q", &out), 0) << out;
  EXPECT_FALSE(fs::exists(dir + "/baseline.ply"));
  // A posture model that does not load stops the run before any work, naming it.
  const std::string bad = test::temp_dir("badmodel") + "/out";
  EXPECT_EQ(test::run(run_args(bad) + " -q --posture-model builtin:nonesuch", &out), 2);
  EXPECT_NE(out.find("nonesuch"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(bad));
  EXPECT_FALSE(load_json_object(dir + "/report.json")["stages"][2].contains("baseline"));
}

TEST(Cli, SkinFromAMergedCloudWithAndWithoutARig) {
  const std::string reg = test::temp_dir("skinreg") + "/reg";
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --out " + reg, &out), 0) << out;
  const std::string pipe = test::temp_dir("skinpipe") + "/p.json";
  test::write_text(pipe, R"({"format": "handskin-pipeline/1", "skin": {"baseline": false, "slices_json": false}})");
  // Given rig, automatic placement compared with it, and the truth's figures.
  const std::string dir = test::temp_dir("skin") + "/out";
  ASSERT_EQ(test::run(kBin + " -q skin --merged " + reg + "/merged.ply --rig " + kFix + "rig.json --auto-rig --truth " + kFix +
                          "truth.json --pipeline " + pipe + " --out " + dir,
                      &out),
            0)
      << out;
  EXPECT_NE(out.find("watertight yes"), std::string::npos) << out;
  const Json r = load_json_object(dir + "/skin_report.json");
  EXPECT_EQ(r["format"], "handskin-skin-report/1");
  EXPECT_EQ(r["skeleton"]["used"], "automatic");
  EXPECT_LE(r["skeleton"]["automatic"]["against_given_rig"]["mean_joint_error_mm"].get<double>(), 3.0);
  EXPECT_LE(r["truth"]["skin_to_truth_mm"]["mean"].get<double>(), 0.15);
  EXPECT_GE(r["truth"]["truth_to_skin_mm"]["within_1mm"].get<double>(), 0.98);
  EXPECT_TRUE(fs::exists(dir + "/rig_auto.json"));
  EXPECT_FALSE(fs::exists(dir + "/baseline.ply"));
  EXPECT_NO_THROW(load_rig(dir + "/rig_auto.json"));
  // No rig at all: placed automatically.
  const std::string dir2 = test::temp_dir("skin2") + "/out";
  ASSERT_EQ(test::run(kBin + " -q skin --merged " + reg + "/merged.ply --pipeline " + pipe + " --out " + dir2, &out), 0) << out;
  EXPECT_EQ(load_json_object(dir2 + "/skin_report.json")["skeleton"]["used"], "automatic");
  // A tube that folds into itself on the placed skeleton (HANDSKIN_FAULT=fold:1: the first
  // stitch finds the palm folded) is that skeleton's refusal: the next placement is built
  // (the WebXR hand's bent thumb had been refused so). On a given rig the fold is the error.
  const std::string dir5 = test::temp_dir("skin5") + "/out";
  ASSERT_EQ(test::run("HANDSKIN_FAULT=fold:1 " + kBin + " -q skin --merged " + reg + "/merged.ply --pipeline " + pipe +
                          " --out " + dir5,
                      &out),
            0)
      << out;
  const Json r5 = load_json_object(dir5 + "/skin_report.json");
  EXPECT_NE(r5["skeleton"]["automatic"]["notes"].dump().find("the palm tube folds into itself"), std::string::npos) << r5["skeleton"];
  const std::string dir6 = test::temp_dir("skin6") + "/out";
  EXPECT_EQ(test::run("HANDSKIN_FAULT=fold:1 " + kBin + " -q skin --merged " + reg + "/merged.ply --rig " + kFix +
                          "rig.json --pipeline " + pipe + " --out " + dir6,
                      &out),
            1)
      << out;
  EXPECT_NE(out.find("the palm tube folds into itself"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir6));
  // Folded on every placement: the automatic skeleton's failure, with the way on.
  const std::string dir6b = test::temp_dir("skin6b") + "/out";
  EXPECT_EQ(test::run("HANDSKIN_FAULT=fold:all " + kBin + " -q skin --merged " + reg + "/merged.ply --pipeline " + pipe +
                          " --out " + dir6b,
                      &out),
            1)
      << out;
  EXPECT_NE(out.find("error: automatic skeleton: the palm tube folds into itself"), std::string::npos) << out;
  EXPECT_NE(out.find("give its rig (--rig)"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir6b));
  // A placed skeleton that misses the hand (HANDSKIN_FAULT=placement-off: 25 mm aside, its
  // links off their sections) is no evidence against the given rig, on which the skin builds:
  // the rig is used, with a warning -q shows, and the report says the placement failed.
  const std::string dir7 = test::temp_dir("skin7") + "/out";
  ASSERT_EQ(test::run("HANDSKIN_FAULT=placement-off " + kBin + " -q skin --merged " + reg + "/merged.ply --rig " + kFix +
                          "rig.json --pipeline " + pipe + " --out " + dir7,
                      &out),
            0)
      << out;
  EXPECT_NE(out.find("warning: the given rig is used unchecked"), std::string::npos) << out;
  const Json r7 = load_json_object(dir7 + "/skin_report.json");
  EXPECT_EQ(r7["skeleton"]["used"], "given");
  EXPECT_NE(r7["skeleton"]["automatic"]["failed"].get<std::string>().find("middle of its sections"), std::string::npos)
      << r7["skeleton"];
  // `run -q` shows its stages' warnings too (they had been progress lines "skin: warning: …").
  const std::string dir8 = test::temp_dir("skin8") + "/out";
  ASSERT_EQ(test::run("HANDSKIN_FAULT=placement-off " + kBin + " -q run --back " + kFix + "back --palm " + kFix +
                          "palm --rig " + kFix + "rig.json --out " + dir8,
                      &out),
            0)
      << out;
  EXPECT_NE(out.find("warning: skin: the given rig is used unchecked"), std::string::npos) << out;
  // A rig with two fingers swapped would still close, but bound wrongly: it is refused, naming the file.
  Json swapped = load_json_object(kFix + "rig.json");
  for (const char* j : {"metacarpal", "phalanx-proximal", "phalanx-intermediate", "phalanx-distal", "tip"})
    std::swap(swapped["joints"][std::string("index-finger-") + j], swapped["joints"][std::string("ring-finger-") + j]);
  const std::string bad_rig = test::temp_dir("skinrig") + "/rig.json";
  test::write_text(bad_rig, swapped.dump());
  const std::string dir4 = test::temp_dir("skin4") + "/out";
  ASSERT_EQ(test::run(kBin + " -q skin --merged " + reg + "/merged.ply --rig " + bad_rig + " --pipeline " + pipe +
                          " --out " + dir4,
                      &out),
            1)
      << out;
  EXPECT_EQ(out.rfind("error: " + bad_rig + ": its joints lie", 0), 0u) << out;
  EXPECT_NE(out.find("out of order"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir4));
  // Bad inputs: one line naming the file or key, nothing written.
  const std::string dir3 = test::temp_dir("skin3") + "/out";
  const std::string junk = test::temp_dir("skinjunk") + "/merged.ply";
  test::write_text(junk, "ply\nformat ascii 1.0\nelement vertex 2\nend_header\n1 2\n");
  EXPECT_EQ(test::run(kBin + " -q skin --merged " + junk + " --out " + dir3, &out), 1);
  EXPECT_EQ(out.rfind("error: " + junk, 0), 0u) << out;
  EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  test::write_text(pipe, R"({"format": "handskin-pipeline/1", "skin": {"max_triangles": 12}})");
  EXPECT_EQ(test::run(kBin + " -q skin --merged " + reg + "/merged.ply --pipeline " + pipe + " --out " + dir3, &out), 1);
  EXPECT_NE(out.find("skin.max_triangles"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir3));
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
  // Out-of-range option of the synthetic scanner: bad usage (exit 2).
  EXPECT_EQ(test::run(kBin + " -q synth scan --mesh " + kFix + "truth_skin.ply --rig " + kFix + "rig.json --marker-radius -2 --out " + dir, &out), 2);
  EXPECT_NE(out.find("error: --marker-radius: must be in"), std::string::npos) << out;
  // The synthetic hand's posture and side: an unknown DOF, a value that is no number, a
  // joint bent past what the family allows, a side that is neither: flags' values, so bad
  // usage (exit 2).
  const std::string hand = kBin + " -q synth hand --no-render --out " + dir;
  EXPECT_EQ(test::run(hand + " --set index.pip.flx=30", &out), 2);
  EXPECT_EQ(out, "error: --set: unknown DOF 'index.pip.flx' (names as in docs/formats.md, e.g. index.mcp.flex or I2.flex) (see --help)\n");
  EXPECT_EQ(test::run(hand + " --set index.pip.flex=3O", &out), 2);
  EXPECT_EQ(out, "error: --set: 'index.pip.flex=3O': the value must be a finite number within ±1e4 (see --help)\n");
  EXPECT_EQ(test::run(hand + " --set index.pip.flex=95", &out), 2);
  EXPECT_NE(out.find("index.pip.flex"), std::string::npos) << out;
  EXPECT_EQ(test::run(hand + " --side middle", &out), 2);
  EXPECT_EQ(out, "error: --side: 'middle': must be right or left (see --help)\n");
  EXPECT_EQ(test::run(hand + " --forearm 60", &out), 2);
  EXPECT_NE(out.find("error: --forearm: must be in"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir));
}

TEST(Cli, ConvertBetweenScansAndClouds) {
  const std::string dir = test::temp_dir("conv");
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q convert --in " + kFix + "back --out " + dir + "/b.pcd", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q convert --in " + dir + "/b.pcd --out " + dir + "/b --side back", &out), 0) << out;
  EXPECT_EQ(load_scan(dir + "/b").values, load_scan(kFix + "back").values);
  EXPECT_EQ(test::run(kBin + " -q convert --in " + dir + "/b.pcd --out " + dir + "/c", &out), 2);
  EXPECT_NE(out.find("--side"), std::string::npos) << out;
  // A scan given by either of its files, as every other command takes it (it was looked for
  // as "back.png.json").
  ASSERT_EQ(test::run(kBin + " -q convert --in " + kFix + "back.png --out " + dir + "/bp.pcd", &out), 0) << out;
  EXPECT_EQ(read_file(dir + "/bp.pcd"), read_file(dir + "/b.pcd"));
  // A scanner's text cloud, as `run --cloud` reads it, to PLY and to a scan; written only as
  // .ply or .pcd.
  {
    std::string xyz = "# x y z\n";
    for (int i = 0; i < 50; ++i) xyz += std::to_string(i) + " " + std::to_string(2 * i) + " 1.5\n";
    test::write_text(dir + "/t.xyz", xyz);
  }
  ASSERT_EQ(test::run(kBin + " -q convert --in " + dir + "/t.xyz --out " + dir + "/t.ply", &out), 0) << out;
  EXPECT_EQ(load_cloud(dir + "/t.ply")->size(), 50u);
  EXPECT_EQ(test::run(kBin + " -q convert --in " + dir + "/t.xyz --out " + dir + "/u.xyz", &out), 2);
  EXPECT_EQ(out, "error: --out: '" + dir + "/u.xyz': a cloud is written as .ply or .pcd (by its extension) (see --help)\n");
  // A merged cloud (normals, side labels) to PCD and back: nothing lost (its normals and labels
  // were dropped). Onto itself: refused, the file as it was (it was rewritten without them).
  {
    pcl::PointCloud<pcl::PointXYZLNormal> m;
    for (int i = 0; i < 40; ++i) {
      pcl::PointXYZLNormal q;
      q.x = static_cast<float>(i), q.y = 0.5f * static_cast<float>(i), q.z = 3;
      q.normal_x = 0, q.normal_y = 0.6f, q.normal_z = 0.8f;
      q.label = static_cast<std::uint32_t>(i % 2);
      m.push_back(q);
    }
    save_cloud(dir + "/m.ply", m);
  }
  ASSERT_EQ(test::run(kBin + " -q convert --in " + dir + "/m.ply --out " + dir + "/m.pcd", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q convert --in " + dir + "/m.pcd --out " + dir + "/m2.ply", &out), 0) << out;
  EXPECT_EQ(read_file(dir + "/m2.ply"), read_file(dir + "/m.ply"));
  const std::string before = read_file(dir + "/m2.ply");
  EXPECT_EQ(test::run(kBin + " -q convert --in " + dir + "/m2.ply --out " + dir + "/./m2.ply --force", &out), 2);
  EXPECT_NE(out.find("is the file --in reads"), std::string::npos) << out;
  EXPECT_EQ(read_file(dir + "/m2.ply"), before);
  // A file of a kind convert does not read: said as such, not looked for as a scan's sidecar.
  test::write_text(dir + "/p.step", "ISO-10303-21;\n");
  EXPECT_EQ(test::run(kBin + " -q convert --in " + dir + "/p.step --out " + dir + "/p.ply", &out), 1);
  EXPECT_NE(out.find(dir + "/p.step: not a file convert reads"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/p.ply"));
}

TEST(Cli, SynthScanRunsOnAnotherHand) {
  const std::string dir = test::temp_dir("synth");
  std::string out;
  // A left hand, in its relaxed posture (the default), of another size.
  ASSERT_EQ(test::run(kBin + " -q synth hand --side left --hand-length 172 --spread 8 --thickness 0.9 --facet-size 2.2 --no-render --out " + dir + "/hand", &out), 0) << out;
  EXPECT_EQ(rig_side(load_rig(dir + "/hand/hand_rig.json")), HandSide::Left);
  ASSERT_EQ(test::run(kBin + " -q synth scan --mesh " + dir + "/hand/hand.ply --rig " + dir + "/hand/hand_rig.json --seed 5 --out " + dir + "/scan", &out), 0) << out;
  for (const char* f : {"back.png", "back.json", "palm.png", "palm.json", "rig.json", "truth.json", "truth_skin.ply", "back_preview.png"})
    EXPECT_TRUE(fs::exists(dir + "/scan/" + f)) << f;
  EXPECT_EQ(load_json_object(dir + "/scan/truth.json")["hand"], "left");
  ASSERT_EQ(test::run(kBin + " -q run --back " + dir + "/scan/back --palm " + dir + "/scan/palm --rig " + dir + "/scan/rig.json --out " + dir + "/out", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q render --mesh " + dir + "/hand/hand.ply --rig " + dir + "/hand/hand_rig.json --out " + dir + "/r.png", &out), 0) << out;
  EXPECT_GT(fs::file_size(dir + "/r.png"), 1000u);
}

TEST(Cli, SolveSingleAndBatch) {
  const std::string dir = test::temp_dir("solve");
  std::string out;
  ASSERT_EQ(test::run(kBin + " -q solve --model builtin:anatomical --set L2.flex=60 --torque I3.flex=5 --target "
                             "thumb.ip.flex=30@2 --rig " + kFix + "rig.json --json",
                      &out),
            0)
      << out;
  const Json j = parse_json_object(out, "stdout");
  EXPECT_EQ(j["angles"]["little.mcp.flex"].get<double>(), 60.0);
  EXPECT_GT(j["angles"]["ring.mcp.flex"].get<double>(), 30.0);
  EXPECT_EQ(j["joints"].size(), 25u);
  EXPECT_EQ(j["pinned"], Json::array({"little.mcp.flex"}));
  // Batch: every row's given cells pinned, rows in order, out-of-limit cells clamped and
  // counted in one warning.
  test::write_text(dir + "/in.csv", "L2.flex,index.mcp.flex\n10,\n,45\n200,30\n");
  ASSERT_EQ(test::run(kBin + " solve --model builtin:thesis --inputs " + dir + "/in.csv --out " + dir + "/out.csv", &out), 0)
      << out;
  EXPECT_NE(out.find("1 input value(s) in 1 row(s)"), std::string::npos) << out;
  const AngleTable t = read_angle_table(dir + "/out.csv");
  ASSERT_EQ(t.rows.size(), 3u);
  ASSERT_EQ(t.columns.size(), 35u);
  const int l2 = dof_index("little.mcp.flex").value(), i2 = dof_index("index.mcp.flex").value();
  EXPECT_EQ(t.rows[0][l2], 10.0);
  EXPECT_EQ(t.rows[1][i2], 45.0);
  EXPECT_EQ(t.rows[2][l2], 90.0);  // clamped onto the limit
  // Malformed rows and unknown names: one line naming the line or the name; no output.
  test::write_text(dir + "/bad.csv", "L2.flex,index.mcp.flex\n10,\n1,2,3\n");
  EXPECT_EQ(test::run(kBin + " -q solve --model builtin:thesis --inputs " + dir + "/bad.csv --out " + dir + "/o2.csv", &out), 1);
  EXPECT_NE(out.find("bad.csv:3"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/o2.csv"));
  EXPECT_EQ(test::run(kBin + " -q solve --model builtin:thesis --set pinky.mcp.flex=3", &out), 2);
  EXPECT_NE(out.find("unknown DOF 'pinky.mcp.flex'"), std::string::npos) << out;
  test::write_text(dir + "/m.json", R"({"format": "hand-posture/1", "dofs": {"ring.pip.flex": {"stiffness": 0}}})");
  EXPECT_EQ(test::run(kBin + " -q solve --model " + dir + "/m.json --set L2.flex=3", &out), 1);
  EXPECT_NE(out.find("stiffness"), std::string::npos) << out;
}

TEST(Cli, CalibrateSeveralRecordingsAndMixture) {
  const std::string dir = test::temp_dir("calib-many");
  std::string out;
  for (int p = 1; p <= 3; ++p)
    ASSERT_EQ(test::run(kBin + " -q synth angles --rows 600 --seed " + std::to_string(p) + " --person " + std::to_string(p) +
                            " --gaps 0.05 --out " + dir + "/p" + std::to_string(p) + ".csv --truth " + dir + "/t" +
                            std::to_string(p) + ".json",
                        &out),
              0)
        << out;
  EXPECT_EQ(load_json_object(dir + "/t1.json")["format"].get<std::string>(), "handskin-angle-truth/1");
  ASSERT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/p1.csv --angles " + dir + "/p2.csv --angles " + dir +
                          "/p3.csv --out " + dir + "/m.json --report " + dir + "/r.json",
                      &out),
            0)
      << out;
  // The terminal table: both schemes, the three tasks, the baselines.
  for (const char* s : {"held-out blocks", "held-out recordings", "PIPs -> DIPs", "MCPs -> the rest", "linreg", "mean"})
    EXPECT_NE(out.find(s), std::string::npos) << s << "\n" << out;
  const Json r = load_json_object(dir + "/r.json");
  EXPECT_EQ(r["recordings"].size(), 3u);
  EXPECT_EQ(r["cross_validation"]["recordings"]["tasks"].size(), 3u);
  EXPECT_GT(r["frames"].get<long>(), r["frames_complete"].get<long>());  // the gaps are counted
  ASSERT_EQ(test::run(kBin + " -q solve --model " + dir + "/m.json --set middle.mcp.flex=50 --json", &out), 0) << out;
  // The mixture on a curved grasp: solve reports its posterior weights.
  ASSERT_EQ(test::run(kBin + " -q synth angles --kind curved --rows 1500 --out " + dir + "/c.csv", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/c.csv --method mixture --components 3 --out " + dir + "/x.json",
                      &out),
            0)
      << out;
  EXPECT_NE(out.find("3 mixture components"), std::string::npos) << out;
  ASSERT_EQ(test::run(kBin + " -q solve --model " + dir + "/x.json --set middle.mcp.flex=50", &out), 0) << out;
  EXPECT_NE(out.find("mixture of 3 Gaussians"), std::string::npos) << out;
  // Bad usage (exit 2) and bad data (exit 1), no model written.
  for (const std::string bad : {"--method pca", "--shrinkage 2", "--components 1", "--offsets some", "--folds 1"}) {
    EXPECT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/c.csv --out " + dir + "/bad.json " + bad, &out), 2) << bad;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  }
  EXPECT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/c.csv --out " + dir + "/bad.json --grids", &out), 2);
  EXPECT_NE(out.find("thesis-pairs"), std::string::npos) << out;
  test::write_text(dir + "/flat.csv", "I2.flex,I3.flex\n1,2\n1,2\n1,2\n1,2\n1,2\n1,2\n1,2\n1,2\n1,2\n1,2\n1,2\n");
  EXPECT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/flat.csv --out " + dir + "/bad.json", &out), 1);
  EXPECT_NE(out.find("flat.csv"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/bad.json"));
  EXPECT_EQ(test::run(kBin + " -q synth angles --kind spiral --out " + dir + "/s.csv", &out), 2);
  EXPECT_EQ(test::run(kBin + " -q synth angles --rows 5 --out " + dir + "/s.csv", &out), 2);
}

TEST(Cli, MocapCalibrateModel) {
  const std::string dir = test::temp_dir("calib");
  std::string out;
  const std::string tsv = std::string(HANDSKIN_SOURCE_DIR) + "/../shared/data/mocap/qualisys-hand-recording.tsv";
  ASSERT_EQ(test::run(kBin + " -q mocap --in " + tsv + " --out " + dir + "/a.csv --every 10", &out), 0) << out;
  EXPECT_EQ(read_angle_table(dir + "/a.csv").rows.size(), 600u);
  ASSERT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/a.csv --out " + dir + "/m.json --method thesis-pairs --grids --report " + dir +
                          "/r.json",
                      &out),
            0)
      << out;
  const Json r = load_json_object(dir + "/r.json");
  EXPECT_GE(r["pairs"].size(), 3u);
  ASSERT_EQ(test::run(kBin + " -q solve --model " + dir + "/m.json --set little.mcp.flex=40", &out), 0) << out;
  EXPECT_NE(out.find("Gauss-Newton"), std::string::npos) << out;
  // Too short a table.
  test::write_text(dir + "/s.csv", "I2.flex,I3.flex\n1,2\n3,4\n");
  EXPECT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/s.csv --out " + dir + "/s.json", &out), 1);
  EXPECT_NE(out.find("at least"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/s.json"));
  // Built-in sets write out and read back.
  ASSERT_EQ(test::run(kBin + " -q model --model builtin:thesis --out " + dir + "/t.json", &out), 0) << out;
  ASSERT_EQ(test::run(kBin + " -q solve --model " + dir + "/t.json --set L2.flex=60", &out), 0) << out;
}

// --log-json: every stderr line one JSON object (progress and errors); -v: peak memory and a
// last line; -q: no progress lines, warnings still.
TEST(Cli, LogJsonVerboseAndQuietShapeStderr) {
  const std::string dir = test::temp_dir("logjson");
  std::string out;
  auto stderr_of = [](const std::string& cmd) { return "{ " + cmd + " 2>&1 >/dev/null; }"; };
  auto lines_of = [](const std::string& text) {
    std::vector<std::string> v;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) v.push_back(l);
    return v;
  };
  ASSERT_EQ(test::run(stderr_of(kBin + " --log-json register --back " + kFix + "back --palm " + kFix + "palm --out " + dir + "/r"), &out), 0) << out;
  const auto lines = lines_of(out);
  ASSERT_GE(lines.size(), 3u) << out;
  double t = 0;
  for (const auto& l : lines) {
    const Json j = Json::parse(l);  // throws (fails the test) on a line that is not JSON
    EXPECT_EQ(j["level"], "info") << l;
    EXPECT_EQ(j["stage"], "register") << l;
    EXPECT_GE(j["t"].get<double>(), t);
    EXPECT_GT(j["peak_mb"].get<double>(), 0);
    t = j["t"].get<double>();
  }
  ASSERT_EQ(test::run(stderr_of(kBin + " --log-json solve --model builtin:nope"), &out), 2);
  ASSERT_EQ(lines_of(out).size(), 1u) << out;
  const Json e = Json::parse(lines_of(out)[0]);
  EXPECT_EQ(e["level"], "error");
  EXPECT_EQ(e["exit"], 2);
  EXPECT_NE(e["message"].get<std::string>().find("--model: unknown built-in model 'nope'"), std::string::npos);

  ASSERT_EQ(test::run(stderr_of(kBin + " -v solve --model builtin:anatomical --set index.pip.flex=30"), &out), 0) << out;
  EXPECT_TRUE(std::regex_search(lines_of(out).back(), std::regex(R"(solve: done in [0-9.]+ s, peak memory [0-9]+ MB$)"))) << out;

  const std::string glb = test::default_fixture_run() + "/skin.glb";
  ASSERT_EQ(test::run(stderr_of(kBin + " -q pose --skin " + glb + " --set index.pip.flex=400 --out " + dir + "/p.ply"), &out), 0) << out;
  EXPECT_EQ(lines_of(out).size(), 1u) << out;
  EXPECT_EQ(out.rfind("warning: ", 0), 0u) << out;  // the clamped input, with -q too
}

// render, convert and pose read every mesh the project writes and write by extension; a
// picture is a .png or refused.
TEST(Cli, MeshesTheProjectWritesAreReadAndWrittenByExtension) {
  const std::string run = test::default_fixture_run(), dir = test::temp_dir("meshfiles");
  std::string out;
  for (const char* in : {"skin.glb", "patches.obj", "skin.obj", "patches.ply"}) {
    ASSERT_EQ(test::run(kBin + " -q render --mesh " + run + "/" + in + " --out " + dir + "/r.png", &out), 0) << in << out;
    EXPECT_EQ(decode_rgb8_png(read_file(dir + "/r.png"), "r.png").width, 1024);
  }
  ASSERT_EQ(test::run(kBin + " -q convert --in " + run + "/skin.glb --out " + dir + "/skin.stl", &out), 0) << out;
  const Mesh stl = load_mesh(dir + "/skin.stl");
  EXPECT_EQ(stl.faces.size(), 8000u);
  ASSERT_EQ(test::run(kBin + " -q convert --in " + run + "/patches.obj --out " + dir + "/patches.off", &out), 0) << out;
  const Mesh patches = load_mesh(dir + "/patches.off");
  EXPECT_EQ(patches.faces.size(), 98u * 2 * 12 * 12);  // 98 patches, each 12 x 12 quads
  EXPECT_GT(mesh_health(patches).volume_mm3, 0);      // turned outward
  ASSERT_EQ(test::run(kBin + " -q pose --skin " + run + "/skin.glb --set index.pip.flex=60 --out " + dir + "/posed.stl", &out), 0) << out;
  EXPECT_EQ(load_mesh(dir + "/posed.stl").faces.size(), 8000u);
  for (const std::string& bad : {"render --mesh " + run + "/skin.glb --out " + dir + "/r.jpg",
                                "pose --skin " + run + "/skin.glb --png " + dir + "/p.gif",
                                "pose --skin " + run + "/skin.glb --out " + dir + "/p.fbx",
                                "convert --in " + run + "/skin.glb --out " + dir + "/x.3ds"}) {
    EXPECT_EQ(test::run(kBin + " -q " + bad, &out), 2) << bad << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
  }
  EXPECT_FALSE(std::filesystem::exists(dir + "/r.jpg"));
}
