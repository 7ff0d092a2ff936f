// Keyframe and constrained animation (issue 16): keys from a CSV, cubic Bézier interpolation
// in time, the solver filling in every frame, the glTF animation and the command.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "posture/model.hpp"
#include "rigging/animation.hpp"
#include "rigging/gltf.hpp"
#include "test_util.hpp"

using namespace handskin;
namespace fs = std::filesystem;

TEST(Animation, KeysComeFromAJointAngleTableWithATimeColumn) {
  const KeyFrames k = parse_keyframes("L2.flex, time ,index.mcp.flex\n0,0,10\n\n60,1.5,\n", "k.csv");
  ASSERT_EQ(k.times.size(), 2u);
  EXPECT_EQ(k.times[1], 1.5);
  ASSERT_EQ(k.dofs.size(), 2u);
  EXPECT_EQ(k.dofs[0], dof_index("little.mcp.flex").value());
  EXPECT_EQ(k.values[1][0], 60);
  EXPECT_TRUE(std::isnan(k.values[1][1]));  // an empty cell: not given
  EXPECT_EQ(k.lines[1], 4);
  // Without a time column the keys are a second apart.
  EXPECT_EQ(parse_keyframes("L2.flex\n0\n30\n60\n", "k.csv").times, (std::vector<double>{0, 1, 2}));
  // Bad keys: one line naming the file and line.
  auto err = [](const std::string& text) { return test::input_error_of([&] { parse_keyframes(text, "k.csv"); }); };
  EXPECT_NE(err("time,L2.flex\n0,0\n").find("at least two keys"), std::string::npos);
  EXPECT_NE(err("time,L2.flex\n0,0\n0,10\n").find("k.csv:3: time 0 s is not after"), std::string::npos);
  EXPECT_NE(err("time,L2.flex\n0,0\nsoon,10\n").find("k.csv:3: time 'soon'"), std::string::npos);
  EXPECT_NE(err("time,L2.flex\n0,0\n1e300,10\n").find("[0, 3600]"), std::string::npos);
  EXPECT_NE(err("time,toe.flex\n0,0\n1,10\n").find("unknown DOF 'toe.flex'"), std::string::npos);
  EXPECT_NE(err("time,L2.flex\n0,0\n1,x\n").find("k.csv:3"), std::string::npos);
}

TEST(Animation, BezierInterpolationPassesThroughTheKeysSmoothly) {
  const std::vector<double> T = {0, 1, 3, 4, 5}, V = {0, 30, 70, 70, 10};
  for (size_t k = 0; k < T.size(); ++k) EXPECT_NEAR(bezier_at(T, V, T[k]), V[k], 1e-12);
  // C1: the slope is the same either side of every inner key; at a key on the way up, the
  // slope between its neighbours; at a turning point or beside an equal key, flat.
  const double h = 1e-6;
  for (size_t k = 1; k + 1 < T.size(); ++k) {
    const double left = (bezier_at(T, V, T[k]) - bezier_at(T, V, T[k] - h)) / h;
    const double right = (bezier_at(T, V, T[k] + h) - bezier_at(T, V, T[k])) / h;
    EXPECT_NEAR(left, right, 1e-3) << k;
  }
  EXPECT_NEAR((bezier_at(T, V, 1 + h) - 30) / h, (70.0 - 0) / 3, 1e-3);
  EXPECT_NEAR(bezier_at(T, V, 3.5), 70, 1e-12);  // equal keys hold still between them
  // Never beyond the keys' range around a turning point; at rest at the ends; held beyond them.
  for (double t = 0; t <= 5; t += 0.01) {
    EXPECT_LE(bezier_at(T, V, t), 70 + 1e-9);
    EXPECT_GE(bezier_at(T, V, t), 0 - 1e-9);
  }
  EXPECT_NEAR((bezier_at(T, V, h) - V[0]) / h, 0, 1e-3);
  EXPECT_EQ(bezier_at(T, V, -1), 0);
  EXPECT_EQ(bezier_at(T, V, 9), 10);
}

TEST(Animation, KeyframesAndConstrainedAnimationGiveTheWholeHandEveryFrame) {
  const PostureSolver solver(builtin_model("anatomical"));
  const int l2 = dof_index("little.mcp.flex").value(), r2 = dof_index("ring.mcp.flex").value();
  const KeyFrames keys = parse_keyframes("time,L2.flex\n0,0\n2,80\n", "k.csv");
  // Constrained: the input follows its curve exactly; the solver moves its neighbour with it.
  const PostureAnimation c = animate(solver, keys, 30, true, "k.csv");
  ASSERT_EQ(c.frames.size(), 61u);
  EXPECT_EQ(c.times.back(), 2.0);
  for (size_t f = 0; f < c.frames.size(); ++f) EXPECT_NEAR(c.frames[f][l2], bezier_at({0, 2}, {0, 80}, c.times[f]), 1e-6);
  EXPECT_GT(c.frames.back()[r2] - c.frames.front()[r2], 5.0);  // the ring MCP follows the little one
  // Keyframes: the keys solved into whole postures, every DOF interpolated between them.
  const PostureAnimation k = animate(solver, keys, 10, false, "k.csv");
  ASSERT_EQ(k.frames.size(), 21u);
  PostureInputs last;
  last.pins = {{l2, 80}};
  const Angles end = solver.solve(last).angles;
  for (int d = 0; d < kDofCount; ++d) EXPECT_NEAR(k.frames.back()[d], end[d], 1e-9) << dofs()[d].name;
  // A frame rate that does not divide the length still ends on the last key.
  const PostureAnimation odd = animate(solver, parse_keyframes("time,L2.flex\n0,0\n1.05,40\n", "k.csv"), 10, true, "k.csv");
  EXPECT_EQ(odd.times.back(), 1.05);
  EXPECT_NEAR(odd.frames.back()[l2], 40, 1e-9);
  // Constrained animation needs every input at every key; the frame rate is bounded.
  EXPECT_NE(test::input_error_of([&] {
              animate(solver, parse_keyframes("time,L2.flex,I2.flex\n0,0,0\n1,10,\n", "k.csv"), 30, true, "k.csv");
            }).find("k.csv:3: key gives no index.mcp.flex"),
            std::string::npos);
  EXPECT_NE(test::input_error_of([&] { animate(solver, keys, 0.5, true, "k.csv"); }).find("--fps"), std::string::npos);
  // The CSV: a time column and every DOF, one row per frame.
  const std::string csv = animation_csv(c);
  EXPECT_EQ(csv.substr(0, 15), "time,wrist.tx,w");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 62);
}

TEST(Animation, TheCommandWritesAGlbWithAnAnimationAndItsFrames) {
  const std::string kBin = HANDSKIN_BINARY;
  const std::string run = test::default_fixture_run();
  const std::string dir = test::temp_dir("animate");
  test::write_text(dir + "/keys.csv", "time,L2.flex,I2.flex\n0,0,0\n1,60,0\n2,60,60\n");
  std::string out;
  const std::string cmd = kBin + " -q animate --skin " + run + "/skin.glb --keys " + dir + "/keys.csv --inputs-only --fps 20 --out " +
                          dir + "/anim.glb --csv " + dir + "/anim.csv";
  ASSERT_EQ(test::run(cmd, &out), 0) << out;
  // The glb is still the rigged skin (it reads back), and it now carries the animation.
  const RiggedSkin back = read_skin_glb(dir + "/anim.glb");
  EXPECT_GT(back.mesh.vertices.size(), 3000u);
  const std::string glb = read_file(dir + "/anim.glb");
  EXPECT_NE(glb.find("\"animations\""), std::string::npos);
  EXPECT_NE(glb.find("\"rotation\""), std::string::npos);
  const KeyFrames frames = read_keyframes(dir + "/anim.csv");  // a time column and every DOF
  EXPECT_EQ(frames.values.size(), 41u);
  EXPECT_EQ(frames.dofs.size(), static_cast<size_t>(kDofCount));
  EXPECT_EQ(frames.times.back(), 2.0);
  // Same inputs, same bytes.
  const std::string first = read_file(dir + "/anim.glb");
  ASSERT_EQ(test::run(cmd, &out), 0) << out;
  EXPECT_TRUE(first == read_file(dir + "/anim.glb"));
  // Bad input: one line, nothing written.
  test::write_text(dir + "/bad.csv", "time,L2.flex\n0,0\n0,10\n");
  EXPECT_EQ(test::run(kBin + " -q animate --skin " + run + "/skin.glb --keys " + dir + "/bad.csv --out " + dir + "/bad.glb", &out), 1);
  EXPECT_NE(out.find("bad.csv:3"), std::string::npos) << out;
  EXPECT_FALSE(fs::exists(dir + "/bad.glb"));
  EXPECT_EQ(test::run(kBin + " -q animate --skin " + run + "/skin.glb --keys " + dir + "/keys.csv --out " + dir + "/a.gltf", &out), 2);
  EXPECT_NE(out.find("written as a .glb"), std::string::npos) << out;
}
