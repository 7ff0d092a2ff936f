// Stage contracts (issue 12): a failed command leaves its output folder exactly as it was;
// usage errors exit 2 in one line, data errors 1; numbers out of proportion are refused
// rather than solved into NaN; nothing is accepted silently.
#include <gtest/gtest.h>

#include <csignal>
#include <filesystem>
#include <map>
#include <random>
#include <sys/wait.h>
#include <thread>

#include "core/atomic_file.hpp"
#include "core/json_util.hpp"
#include "core/output_set.hpp"
#include "pipeline/options.hpp"
#include "posture/angle_table.hpp"
#include "posture/mocap.hpp"
#include "posture/model.hpp"
#include "posture/solver.hpp"
#include "scan/cubist_io.hpp"
#include "test_util.hpp"

using namespace handskin;
namespace fs = std::filesystem;

namespace {
const std::string kBin = HANDSKIN_BINARY;
const std::string kFix = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";

using test::snapshot;

// No staging folder of ours left in `parent`.
bool no_staging_left(const std::string& parent) {
  for (const auto& e : fs::directory_iterator(parent))
    if (e.path().filename().string().rfind(".handskin-staging", 0) == 0) return false;
  return true;
}

size_t lines(const std::string& s) { return static_cast<size_t>(std::count(s.begin(), s.end(), '\n')); }

std::string run_cmd(const std::string& out, const std::string& rig = kFix + "rig.json") {
  return kBin + " -q run --back " + kFix + "back --palm " + kFix + "palm --rig " + rig + " --out " + out;
}

// An output folder as a user left it: a good run's outputs and a file of their own.
const std::string& good_run() {
  static const std::string dir = [] {
    const std::string d = test::temp_dir("good") + "/out";
    std::string out;
    EXPECT_EQ(test::run(run_cmd(d), &out), 0) << out;
    test::write_text(d + "/my notes.txt", "the user's own file\n");
    return d;
  }();
  return dir;
}

std::string copy_of_good(const std::string& tag) {
  const std::string d = test::temp_dir(tag) + "/out";
  fs::copy(good_run(), d, fs::copy_options::recursive);
  return d;
}

std::string shifted_rig(const std::string& tag, const Eigen::Vector3d& by, double scale = 1.0) {
  Json j = load_json_object(kFix + "rig.json");
  const Eigen::Vector3d wrist = to_vec3(j["joints"]["wrist"], "wrist", "rig");
  for (auto it = j["joints"].begin(); it != j["joints"].end(); ++it)
    it.value() = to_json(wrist + scale * (to_vec3(it.value(), "joint", "rig") - wrist) + by);
  const std::string p = test::temp_dir(tag) + "/rig.json";
  test::write_text(p, j.dump());
  return p;
}
}  // namespace

TEST(Contracts, AFailedRunLeavesTheOutputFolderExactlyAsItWas) {
  const std::string pipe = test::temp_dir("planes") + "/p.json";
  test::write_text(pipe, R"({"format": "handskin-pipeline/1", "slicing": {"planes": 3}})");
  const std::string far = shifted_rig("far", {80, 0, 0});
  const std::string other = shifted_rig("other", {0, 0, 0}, 0.75);  // a smaller hand's rig
  struct Case {
    std::string name, command, expect;
  };
  const std::vector<Case> cases = {
      {"rig 80 mm off", run_cmd("{out}", far), far},
      {"rig of another hand", run_cmd("{out}", other), other},
      {"slicing.planes 3", run_cmd("{out}") + " --pipeline " + pipe, "error: "},
      {"the 4th write fails", "HANDSKIN_FAULT=stage:4 " + run_cmd("{out}"), "injected fault"},
      {"the 6th move fails", "HANDSKIN_FAULT=commit:6 " + run_cmd("{out}"), "is as it was"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    for (const bool fresh : {false, true}) {  // into an earlier good run's folder, and into a new one
      const std::string dir = fresh ? test::temp_dir("fresh") + "/a/out" : copy_of_good("case");
      const auto before = snapshot(dir);
      std::string cmd = c.command, out;
      cmd.replace(cmd.find("{out}"), 5, dir);
      EXPECT_EQ(test::run(cmd, &out), 1) << out;
      EXPECT_EQ(lines(out), 1u) << out;
      EXPECT_NE(out.find(c.expect), std::string::npos) << out;
      EXPECT_EQ(snapshot(dir), before);
      const fs::path parent = fs::path(dir).parent_path();
      if (fresh) {
        EXPECT_FALSE(fs::exists(parent));
      }  // not even its parent was made
      EXPECT_TRUE(no_staging_left((fresh ? parent.parent_path() : parent).string()));
    }
  }
}

TEST(Contracts, ASignalDuringTheWritesLeavesTheOutputFolderAsItWas) {
  for (const int sig : {SIGTERM, SIGINT}) {
    const std::string dir = copy_of_good("sig");
    const auto before = snapshot(dir);
    const std::string parent = fs::path(dir).parent_path().string();
    // The run stalls before its 3rd file (two already staged); the signal arrives then.
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      setenv("HANDSKIN_FAULT", "stall:3", 1);
      execl(kBin.c_str(), kBin.c_str(), "-q", "run", "--back", (kFix + "back").c_str(), "--palm", (kFix + "palm").c_str(),
            "--rig", (kFix + "rig.json").c_str(), "--out", dir.c_str(), static_cast<char*>(nullptr));
      _exit(127);
    }
    bool staged = false;
    for (int i = 0; i < 600 && !staged; ++i) {  // up to 60 s for the stages to compute
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      staged = !no_staging_left(parent);
    }
    ASSERT_TRUE(staged) << "the run never started writing";
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // two files written, stalled on the third
    kill(pid, sig);
    int status = 0;
    waitpid(pid, &status, 0);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << status;
    EXPECT_EQ(snapshot(dir), before);
    EXPECT_TRUE(no_staging_left(parent));
  }
}

TEST(Contracts, FailedRegisterSkinAndSynthLeaveTheirFoldersAsTheyWere) {
  const std::string reg = copy_of_good("reg");
  const auto before = snapshot(reg);
  std::string out;
  EXPECT_EQ(test::run("HANDSKIN_FAULT=commit:2 " + kBin + " -q register --back " + kFix + "back --palm " + kFix +
                          "palm --out " + reg,
                      &out),
            1);
  EXPECT_EQ(snapshot(reg), before);
  const std::string far = shifted_rig("skinfar", {80, 0, 0});
  EXPECT_EQ(test::run(kBin + " -q skin --merged " + reg + "/merged.ply --rig " + far + " --out " + reg, &out), 1);
  EXPECT_EQ(out.rfind("error: " + far, 0), 0u) << out;
  EXPECT_EQ(snapshot(reg), before);
  EXPECT_EQ(test::run("HANDSKIN_FAULT=stage:2 " + kBin + " -q synth scan --mesh " + kFix + "truth_skin.ply --rig " + kFix +
                          "rig.json --out " + reg,
                      &out),
            1);
  EXPECT_EQ(snapshot(reg), before);
  // An output that cannot be a folder (a file of the user's is there) is refused before any work.
  EXPECT_EQ(test::run(kBin + " -q register --back " + kFix + "back --palm " + kFix + "palm --out '" + reg + "/my notes.txt'",
                      &out),
            1);
  EXPECT_NE(out.find("exists and is not a folder"), std::string::npos) << out;
  EXPECT_EQ(snapshot(reg), before);
  EXPECT_TRUE(no_staging_left(fs::path(reg).parent_path().string()));
}

TEST(Contracts, OutputSetCommitsAllOrNothing) {
  const std::string dir = test::temp_dir("set") + "/out";
  {
    OutputSet set(dir);
    set.claim({"a.txt", "stale.txt"});
    write_file_atomic(set.stage("a.txt"), "old a");
    write_file_atomic(set.stage("stale.txt"), "stale");
    set.commit();
  }
  test::write_text(dir + "/user.txt", "mine");
  const std::string manifest = read_file(dir + "/.handskin-manifest.json");
  {
    OutputSet set(dir);
    set.claim({"a.txt", "b.txt"}, {"stale.txt"});
    write_file_atomic(set.stage("a.txt"), "new a");
    write_file_atomic(set.stage("b.txt"), "new b");
    EXPECT_EQ(read_file(dir + "/a.txt"), "old a");  // nothing moves before the commit
  }  // destroyed uncommitted: discarded
  EXPECT_EQ(snapshot(dir), (std::map<std::string, std::string>{{".handskin-manifest.json", manifest},
                                                               {"a.txt", "old a"},
                                                               {"stale.txt", "stale"},
                                                               {"user.txt", "mine"}}));
  OutputSet set(dir);
  set.claim({"a.txt", "b.txt"}, {"stale.txt"});
  write_file_atomic(set.stage("a.txt"), "new a");
  write_file_atomic(set.stage("b.txt"), "new b");
  set.commit();
  auto after = snapshot(dir);
  after.erase(".handskin-manifest.json");
  EXPECT_EQ(after, (std::map<std::string, std::string>{{"a.txt", "new a"}, {"b.txt", "new b"}, {"user.txt", "mine"}}));
  EXPECT_TRUE(no_staging_left(fs::path(dir).parent_path().string()));
  // An output path that is a file is refused before any work.
  EXPECT_NE(test::input_error_of([&] { OutputSet s(dir + "/user.txt"); }).find("not a folder"), std::string::npos);
}

TEST(Contracts, UsageErrorsExitTwoInOneLine) {
  std::string out;
  for (const std::string args : {"", "run --bogus", "solve", "synth", "render --mesh x.ply --out x.png --size 0",
                                 "render --mesh x.ply --out x.png --size 40000", "solve --model builtin:thesis --set"}) {
    SCOPED_TRACE(args);
    EXPECT_EQ(test::run(kBin + " " + args, &out), 2) << out;
    EXPECT_EQ(lines(out), 1u) << out;
    EXPECT_EQ(out.rfind("error: ", 0), 0u) << out;
  }
  // -q works after the subcommand too.
  EXPECT_EQ(test::run(kBin + " solve --model builtin:thesis --set L2.flex=10 -q --json", &out), 0) << out;
  EXPECT_EQ(out.find("[ "), std::string::npos) << out;
}

TEST(Contracts, FailedWritesNameTheirCause) {
  std::string out;
  // convert into a folder that does not exist: one line naming the file, no PCL chatter.
  EXPECT_EQ(test::run(kBin + " -q convert --in " + kFix + "back --out /nonexistent/x.pcd", &out), 1);
  EXPECT_EQ(out, "error: /nonexistent/x.pcd: cannot write: folder '/nonexistent' does not exist\n");
  // A rename onto a folder fails; the message says why, not "Success".
  const std::string dir = test::temp_dir("wr");
  fs::create_directories(dir + "/taken");
  const std::string e = test::input_error_of([&] { write_file_atomic(dir + "/taken", "x"); });
  EXPECT_NE(e.find("cannot write"), std::string::npos) << e;
  EXPECT_EQ(e.find("Success"), std::string::npos) << e;
  EXPECT_TRUE(fs::is_directory(dir + "/taken"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);  // no temporary left
  // Reading a merged cloud: PCL's own lines are silenced, ours is the one line.
  test::write_text(dir + "/bad.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n");
  EXPECT_EQ(test::run(kBin + " -q skin --merged " + dir + "/bad.ply --out " + dir + "/o", &out), 1);
  EXPECT_EQ(lines(out), 1u) << out;
  EXPECT_EQ(out.find("[pcl"), std::string::npos) << out;
}

TEST(Contracts, RenderRefusesTheRigsSolveRefuses) {
  // Two joints of the index finger at the same place: no link between them.
  Json j = load_json_object(kFix + "rig.json");
  j["joints"]["index-finger-phalanx-intermediate"] = j["joints"]["index-finger-phalanx-proximal"];
  const std::string rig = test::temp_dir("rrig") + "/rig.json";
  test::write_text(rig, j.dump());
  std::string solve_out, render_out;
  EXPECT_EQ(test::run(kBin + " -q solve --model builtin:thesis --rig " + rig, &solve_out), 1) << solve_out;
  EXPECT_EQ(test::run(kBin + " -q render --mesh " + kFix + "truth_skin.ply --rig " + rig + " --out " +
                          test::temp_dir("rr") + "/r.png",
                      &render_out),
            1)
      << render_out;
  EXPECT_EQ(render_out, solve_out);
}

TEST(Contracts, PostureNumbersAreBoundedAndSolutionsFinite) {
  const std::string dir = test::temp_dir("bounds");
  std::string out;
  // Models with numbers out of proportion: refused by `model` (and so by solve and pose).
  const std::vector<std::pair<std::string, std::function<void(Json&)>>> bad = {
      {"alpha", [](Json& j) { j["pairs"][0]["alpha"] = 1e300; }},
      {"weight", [](Json& j) { j["pairs"][0]["weight"] = 1e300; }},
      {"stiffness", [](Json& j) { j["dofs"]["index.mcp.flex"]["stiffness"] = 1e308; }},
      {"gamma", [](Json& j) { j["pairs"][0]["gamma"] = -1e200; }},
      {"limits", [](Json& j) { j["dofs"]["index.mcp.flex"]["limits"] = {-1e300, 1e300}; }},
  };
  for (const auto& [key, edit] : bad) {
    Json j = model_to_json(builtin_model("thesis"));
    edit(j);
    test::write_text(dir + "/m.json", j.dump());
    EXPECT_EQ(test::run(kBin + " -q model --model " + dir + "/m.json --out " + dir + "/o.json", &out), 1) << key;
    EXPECT_NE(out.find(key), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(dir + "/o.json"));
  }
  // Options out of proportion: bad usage (a flag's value), exit 2.
  for (const std::string opt : {"--target index.mcp.flex=10@1e308", "--torque index.mcp.flex=1e308",
                                "--set index.mcp.flex=1e308"}) {
    EXPECT_EQ(test::run(kBin + " -q solve --model builtin:thesis " + opt, &out), 2) << opt << out;
    EXPECT_EQ(lines(out), 1u) << out;
  }
  // Random models anywhere within the bounds: every solve is a finite posture within the
  // limits, or an InputError — never NaN with success.
  std::mt19937_64 rng(7);
  auto pick = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  auto log_pick = [&](double lo, double hi) { return std::exp(pick(std::log(lo), std::log(hi))); };
  int solved = 0;
  for (int trial = 0; trial < 200; ++trial) {
    PostureModel m = builtin_model("thesis");
    for (auto& d : m.dof) d.stiffness = log_pick(kMinStiffness, kMaxStiffness);
    for (auto& l : m.pairs) {
      l.alpha = pick(-1, 1) * log_pick(1e-3, kMaxCoefficient);
      l.beta = pick(-1, 1) * log_pick(1e-3, kMaxCoefficient);
      l.gamma = pick(-1, 1) * log_pick(1e-3, kMaxOffset);
      l.weight = log_pick(1e-6, kMaxWeight);
    }
    PostureInputs in;
    in.pins = {{1 + static_cast<int>(rng() % 30), pick(-200, 200)}};
    in.torques = {{1 + static_cast<int>(rng() % 30), pick(-kMaxTorque, kMaxTorque)}};
    in.targets = {{1 + static_cast<int>(rng() % 30), pick(-100, 100), log_pick(1e-3, kMaxTargetWeight)}};
    try {
      const PostureSolver s(parse_model(model_to_json(m), "random"));
      const PostureSolution sol = s.solve(in);
      for (int d = 0; d < kDofCount; ++d) ASSERT_TRUE(std::isfinite(sol.angles[d]));
      ASSERT_TRUE(std::isfinite(sol.energy));
      ++solved;
    } catch (const InputError&) {
    }
  }
  EXPECT_GT(solved, 150);
}

TEST(Contracts, NothingIsAcceptedSilently) {
  // An integer is range-checked before it is narrowed.
  const std::string meta = load_json_object(kFix + "back.json").dump();
  auto with = [&](const std::string& key, const std::string& value) {
    Json j = parse_json_object(meta, "m");
    j[key] = Json::parse(value);
    return j.dump();
  };
  EXPECT_NE(test::input_error_of([&] { parse_scan_meta(with("scanlines", "4294967808"), "b.json"); }).find("scanlines"),
            std::string::npos);
  EXPECT_NE(test::input_error_of([&] { parse_scan_meta(with("points", "-4294966784"), "b.json"); }).find("points"),
            std::string::npos);
  // The largest grid a small file can ask for is refused before anything is decoded.
  Json big = parse_json_object(meta, "m");
  big["scanlines"] = 16384;
  big["points"] = 16384;
  EXPECT_NE(test::input_error_of([&] { parse_scan_meta(big.dump(), "b.json"); }).find("'scanlines' must be in [1, 4096]"),
            std::string::npos);
  big["scanlines"] = 4096;
  big["points"] = 4096;
  EXPECT_NE(test::input_error_of([&] { parse_scan_meta(big.dump(), "b.json"); }).find("more than"), std::string::npos);
  big["x_step_mm"] = 1e308;
  big["points"] = 512;
  EXPECT_NE(test::input_error_of([&] { parse_scan_meta(big.dump(), "b.json"); }).find("x_step_mm"), std::string::npos);
  big["x_step_mm"] = 0.5;
  big["scanlines"] = 4096;
  big["points"] = 1024;
  EXPECT_NO_THROW(parse_scan_meta(big.dump(), "b.json"));
  EXPECT_NE(test::input_error_of([&] {
              parse_pipeline(Json::parse(R"({"format": "handskin-pipeline/1", "markers": {"count": 4294967305}})"), "p");
            }).find("markers.count"),
            std::string::npos);
  // Motion capture: a Qualisys file cut mid-row, a TRC whose NumFrames disagrees or that ends mid-row.
  const std::string tsv = "NO_OF_FRAMES\t2\nMARKER_NAMES\ta\tb\n1\t2\t3\t4\t5\t6\n1\t2\t3\t4";
  EXPECT_NE(test::input_error_of([&] { parse_qualisys_tsv(tsv, "q.tsv"); }).find("cut mid-row"), std::string::npos);
  const std::string trc_head =
      "PathFileType\t4\t(X/Y/Z)\tx.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\n100\t100\t3\t2\tmm\n"
      "Frame#\tTime\ta\t\t\tb\nX1\tY1\tZ1\tX2\tY2\tZ2\n";
  const std::string rows = "1\t0\t1\t2\t3\t4\t5\t6\n2\t0.01\t1\t2\t3\t4\t5\t6\n";
  EXPECT_NE(test::input_error_of([&] { parse_trc(trc_head + rows, "t.trc"); }).find("NumFrames says 3"), std::string::npos);
  EXPECT_NE(test::input_error_of([&] { parse_trc(trc_head + rows + "3\t0.02\t1\t2\t3\t4", "t.trc"); }).find("cut mid-row"),
            std::string::npos);
  EXPECT_EQ(parse_trc(trc_head + rows + "3\t0.02\t1\t2\t3\t4\t5\t6\n", "t.trc").frames.size(), 3u);
  // Angle CSVs: a byte-order mark is read past; ';' separators are named.
  const AngleTable t = parse_angle_table("\xEF\xBB\xBFL2.flex,index.mcp.flex\n10,20\n", "a.csv");
  ASSERT_EQ(t.columns.size(), 2u);
  EXPECT_EQ(t.rows[0][1], 20.0);
  EXPECT_EQ(test::input_error_of([&] { parse_angle_table("L2.flex;index.mcp.flex\n10;20\n", "a.csv"); }),
            "a.csv:1: the header is separated by ';'; this format uses ',' between cells and '.' in numbers");
  EXPECT_NE(test::input_error_of([&] { parse_angle_table("L2.fl\x01x\n10\n", "a.csv"); }).find("\\x01"), std::string::npos);
  // A calibration pair of one DOF (under two names) is refused before anything is written.
  const std::string dir = test::temp_dir("cal");
  test::write_text(dir + "/a.csv", "L2.flex,L3.flex\n10,20\n20,35\n30,52\n40,61\n");
  std::string out;
  EXPECT_EQ(test::run(kBin + " -q calibrate --angles " + dir + "/a.csv --pair L2.flex:little.mcp.flex --out " + dir + "/m.json", &out), 2);
  EXPECT_NE(out.find("two different DOFs"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/m.json"));
}

TEST(Contracts, TheBaselineIsOptInAndRepeatsByteForByte) {
  const std::string reg = good_run();
  std::string out;
  std::string bytes[2];
  for (int k = 0; k < 2; ++k) {
    const std::string dir = test::temp_dir("base") + "/out";
    ASSERT_EQ(test::run(kBin + " -q skin --merged " + reg + "/merged.ply --rig " + kFix + "rig.json --baseline --out " + dir, &out), 0) << out;
    bytes[k] = read_file(dir + "/baseline.ply");
    EXPECT_GT(load_json_object(dir + "/skin_report.json")["baseline"]["mesh"]["triangles"].get<int>(), 1000);
  }
  EXPECT_GT(bytes[0].size(), 10000u);
  EXPECT_TRUE(bytes[0] == bytes[1]) << "baseline.ply differs between two runs";
  EXPECT_FALSE(fs::exists(reg + "/baseline.ply"));  // not made unless asked for
}

TEST(Contracts, RunGivesTheSameBytesOnOneThreadAndOnTwo) {
  // Stages run pieces in parallel (registration's detections, the skin's check beside its
  // build, the patches' foot points), each into its own slot: the thread count changes nothing.
  // (--threads; scripts/check_threads.sh, test threads_same_bytes, compares every file of the
  // run and of a refined patch fit.)
  std::string out;
  const std::string one = test::temp_dir("t1") + "/out", two = test::temp_dir("t2") + "/out";
  ASSERT_EQ(test::run(run_cmd(one) + " --threads 1", &out), 0) << out;
  ASSERT_EQ(test::run(run_cmd(two) + " --threads 2", &out), 0) << out;
  for (const char* f : {"merged.ply", "skin.ply", "skin.obj", "slices.json", "patches.json", "patches.ply", "skin.glb", "skin.png"})
    EXPECT_TRUE(read_file(one + "/" + f) == read_file(two + "/" + f)) << f;
  Json a = load_json_object(one + "/registration.json"), b = load_json_object(two + "/registration.json");
  a.erase("timings_ms"), b.erase("timings_ms");
  EXPECT_TRUE(a == b);
}
