// The skeleton, the posture solver, calibration and motion capture (thesis chapter 3).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/random.hpp"
#include "posture/calibrate.hpp"
#include "posture/mocap.hpp"
#include "posture/skeleton.hpp"
#include "posture/solver.hpp"
#include "test_util.hpp"

using namespace handskin;
using test::input_error_of;

namespace {
const std::string kFixture = std::string(HANDSKIN_SOURCE_DIR) + "/fixtures/default/";
const std::string kMocap = std::string(HANDSKIN_SOURCE_DIR) + "/../shared/data/mocap/qualisys-hand-recording.tsv";
constexpr double kDeg = M_PI / 180.0;

int D(const char* n) { return dof_index(n).value(); }
int Jt(const char* n) { return joint_index(n).value(); }

Angles zeros() {
  Angles a{};
  a.fill(0.0);
  return a;
}


// A table with planted lines: b = 0.8 a + 5 (noise 1°), c = −0.5 a + 40 (noise 3°), e unrelated.
AngleTable planted(int rows, std::uint64_t seed) {
  Rng rng(seed);
  AngleTable t;
  t.columns = {D("index.mcp.flex"), D("index.pip.flex"), D("middle.mcp.flex"), D("thumb.ip.flex")};
  for (int r = 0; r < rows; ++r) {
    const double a = rng.uniform(0, 60);
    t.rows.push_back({a, 0.8 * a + 5 + rng.normal() * 1.0, -0.5 * a + 40 + rng.normal() * 3.0, rng.uniform(0, 40)});
    t.lines.push_back(r + 2);
  }
  return t;
}
}  // namespace

// ---------------------------------------------------------------- skeleton

TEST(Skeleton, ZeroAnglesReproduceTheRig) {
  const Rig rig = load_rig(kFixture + "rig.json");
  const Skeleton sk(rig);
  const auto p = sk.positions(zeros());
  for (int j = 0; j < kJointCount; ++j) EXPECT_LT((p[j] - rig.joints[j]).norm(), 1e-9) << joints()[j].name;
}

// A finger curled into a fist: its distal phalanx points at the palm, along the back-of-hand
// normal, where back x link gives no flexion axis. Such a rig (the automatic placement of a
// hand with its PIPs bent 55-60 deg put the ring's DIP -> tip link 3 deg off the normal) was
// refused by every command that poses; the link now takes its parent's flexion axis.
TEST(Skeleton, ALinkAlongTheBackNormalTakesItsParentsFlexionAxis) {
  Rig rig = load_rig(kFixture + "rig.json");
  const Eigen::Vector3d back = hand_frame_from_rig(rig).linear().row(2).transpose();
  const int dip = Jt("ring-finger-phalanx-distal"), tip = Jt("ring-finger-tip"), pip = Jt("ring-finger-phalanx-intermediate");
  rig.joints[tip] = rig.joints[dip] - 22.0 * back;  // straight at the palm
  const Skeleton sk(rig);
  const auto p = sk.positions(zeros());
  for (int j = 0; j < kJointCount; ++j) EXPECT_LT((p[j] - rig.joints[j]).norm(), 1e-9) << joints()[j].name;
  const Eigen::Vector3d x_dip = sk.rest_frame(dip).linear().col(0), x_pip = sk.rest_frame(pip).linear().col(0);
  EXPECT_LT(std::abs(x_dip.dot(rig.joints[tip] - rig.joints[dip])), 1e-9);
  EXPECT_GT(x_dip.dot(x_pip), 0.99);  // the PIP's hinge (the fixture's ring is straight: the same)
  // Flexing the DIP swings the tip toward the wrist (further into the fist), keeping its length.
  Angles a = zeros();
  a[D("ring.dip.flex")] = 30;
  const Eigen::Vector3d toward_wrist = (rig.joints[0] - rig.joints[Jt("ring-finger-phalanx-proximal")]).normalized();
  const auto q = sk.positions(a);
  EXPECT_NEAR((q[tip] - q[dip]).norm(), 22.0, 1e-9);
  EXPECT_GT((q[tip] - rig.joints[tip]).dot(toward_wrist), 5.0);
}

TEST(Skeleton, AbductionPointsAwayFromTheMiddleFingerOnLeftAndRightHands) {
  // A left hand is a right hand's mirror image: its rig's local frames are mirrored, and the
  // abduction signs follow, so "positive = away from the middle finger" holds for both.
  Rig right = load_rig(kFixture + "rig.json");
  Rig left = right;
  for (auto& j : left.joints) j.y() = -j.y();
  left.palm_normal->y() = -left.palm_normal->y();
  ASSERT_EQ(rig_side(right), HandSide::Right);
  ASSERT_EQ(rig_side(left), HandSide::Left);
  for (const Rig* rig : {&right, &left}) {
    const Skeleton sk(*rig);
    EXPECT_EQ(sk.side(), rig_side(*rig));
    const int mid = joint_index("middle-finger-tip").value();
    for (const char* f : {"index", "ring", "little"}) {
      Angles a{};
      const int tip = joint_index(std::string(f == std::string("little") ? "pinky" : f) + "-finger-tip").value();
      const double d0 = (sk.positions(a)[tip] - sk.positions(a)[mid]).norm();
      a[dof_index(std::string(f) + ".mcp.abd").value()] = 10;
      const double d1 = (sk.positions(a)[tip] - sk.positions(a)[mid]).norm();
      EXPECT_GT(d1, d0 + 3) << f << " " << hand_side_name(rig_side(*rig));
    }
    // Flexion bends toward the palm on both hands.
    Angles a{};
    const int tip = joint_index("index-finger-tip").value();
    const Eigen::Vector3d back = *rig->palm_normal;
    const double h0 = sk.positions(a)[tip].dot(back);
    a[dof_index("index.mcp.flex").value()] = 30;
    EXPECT_LT(sk.positions(a)[tip].dot(back), h0 - 10);
  }
}

TEST(Skeleton, ForwardKinematicsByHand) {
  const Rig rig = load_rig(kFixture + "rig.json");
  const Skeleton sk(rig);
  const int mcp = Jt("index-finger-phalanx-proximal"), pip = Jt("index-finger-phalanx-intermediate"),
            tip = Jt("index-finger-tip");
  const Eigen::Isometry3d F = sk.rest_frame(mcp);
  const Eigen::Vector3d back = hand_frame_from_rig(rig).linear().row(2).transpose();
  // Flexing the index MCP by 90°: the PIP joint swings from along the link to the palm side,
  // p' = p_mcp + L·z (z = x × y, palmar); the rest of the finger follows rigidly.
  Angles a = zeros();
  a[D("index.mcp.flex")] = 90;
  auto p = sk.positions(a);
  const double L = (rig.joints[pip] - rig.joints[mcp]).norm();
  const Eigen::Vector3d z = F.linear().col(2);
  EXPECT_LT((p[pip] - (rig.joints[mcp] + L * z)).norm(), 1e-9);
  EXPECT_LT(z.dot(back), -0.9);  // the palm side
  EXPECT_NEAR((p[tip] - p[mcp]).norm(), (rig.joints[tip] - rig.joints[mcp]).norm(), 1e-9);
  for (int j : {Jt("middle-finger-tip"), Jt("thumb-tip"), Jt("wrist")}) EXPECT_LT((p[j] - rig.joints[j]).norm(), 1e-12);
  // Abduction: positive moves the index toward the thumb, the little finger away from it.
  const Eigen::Vector3d thumb_side = hand_frame_from_rig(rig).linear().row(1).transpose();
  a = zeros();
  a[D("index.mcp.abd")] = 10;
  a[D("little.mcp.abd")] = 10;
  p = sk.positions(a);
  EXPECT_GT((p[pip] - rig.joints[pip]).dot(thumb_side), 0.5);
  const int lpip = Jt("pinky-finger-phalanx-intermediate");
  EXPECT_LT((p[lpip] - rig.joints[lpip]).dot(thumb_side), -0.5);
  EXPECT_NEAR((p[pip] - rig.joints[mcp]).norm(), L, 1e-9);
  // The carpus: translation moves every joint; a rotation about its Y (the hand's long axis)
  // keeps the middle MCP (on that axis) in place up to the wrist-to-MCP lever.
  a = zeros();
  a[D("wrist.tx")] = 5;
  a[D("wrist.ty")] = -3;
  a[D("wrist.tz")] = 2;
  p = sk.positions(a);
  for (int j = 0; j < kJointCount; ++j) EXPECT_LT((p[j] - rig.joints[j] - Eigen::Vector3d(5, -3, 2)).norm(), 1e-9);
  // 3-2-1 composition (eq. 3.4) against explicit matrices.
  const double zr = 20 * kDeg, yr = -35 * kDeg, xr = 50 * kDeg;
  Eigen::Matrix3d Rz, Ry, Rx;
  Rz << std::cos(zr), -std::sin(zr), 0, std::sin(zr), std::cos(zr), 0, 0, 0, 1;
  Ry << std::cos(yr), 0, std::sin(yr), 0, 1, 0, -std::sin(yr), 0, std::cos(yr);
  Rx << 1, 0, 0, 0, std::cos(xr), -std::sin(xr), 0, std::sin(xr), std::cos(xr);
  EXPECT_LT((Skeleton::euler321(20, -35, 50) - Rz * Ry * Rx).norm(), 1e-12);
}

// ---------------------------------------------------------------- solver

TEST(Solver, EquilibriumIsEq317) {
  for (const char* name : {"anatomical", "thesis"}) {
    PostureModel m = builtin_model(name);
    for (auto& d : m.dof) d.lo = -1000, d.hi = 1000;  // eq. 3.17 knows no limits
    const PostureSolver s(m);
    PostureInputs in;
    in.torques = {{D("little.mcp.flex"), 8.0}, {D("index.pip.flex"), 5.0}, {D("thumb.ip.flex"), -3.0}};
    const PostureSolution sol = s.solve_linear(in);
    ASSERT_TRUE(sol.at_limit.empty()) << name;
    // (K + AᵀWA) θ = τ̂ − AᵀWb, θ measured from the relaxed posture.
    Eigen::VectorXd tau = Eigen::VectorXd::Zero(kDofCount);
    for (const auto& [d, t] : in.torques) tau(d) = t;
    const Eigen::VectorXd theta = s.system_matrix().ldlt().solve(tau + s.system_rhs());
    for (int d = 0; d < kDofCount; ++d)
      EXPECT_NEAR(sol.angles[d], s.model().dof[d].relaxed + theta(d), 1e-9) << name << " " << dofs()[d].name;
  }
}

TEST(Solver, PinsExactLimitsHoldAndTheSolutionIsTheBoxMinimum) {
  const PostureSolver s(builtin_model("anatomical"));
  Rng rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    PostureInputs in;
    in.pins = {{D("little.mcp.flex"), rng.uniform(-20, 90)}, {D("index.pip.flex"), rng.uniform(0, 110)}};
    in.torques = {{D("ring.pip.flex"), rng.uniform(-200, 200)}, {D("middle.mcp.abd"), rng.uniform(-100, 100)}};
    const PostureSolution sol = s.solve_linear(in);
    for (const auto& [d, v] : in.pins) EXPECT_EQ(sol.angles[d], v);  // exactly
    for (int d = 0; d < kDofCount; ++d) {
      EXPECT_GE(sol.angles[d], s.model().dof[d].lo - 1e-9);
      EXPECT_LE(sol.angles[d], s.model().dof[d].hi + 1e-9);
    }
    // No feasible move of the free DOFs lowers the potential (the box QP's optimum).
    const double e0 = s.energy(sol.angles, in, false);
    for (int k = 0; k < 40; ++k) {
      Angles y = sol.angles;
      for (int d = 0; d < kDofCount; ++d) {
        bool pinned = false;
        for (const auto& pin : in.pins) pinned = pinned || pin.first == d;
        if (!pinned) y[d] = std::clamp(y[d] + rng.normal() * 0.5, s.model().dof[d].lo, s.model().dof[d].hi);
      }
      EXPECT_GE(s.energy(y, in, false), e0 - 1e-9);
    }
  }
  // A torque far past a limit: held at the limit, reported.
  PostureInputs in;
  in.torques = {{D("ring.pip.flex"), 1000.0}};
  const PostureSolution sol = s.solve_linear(in);
  EXPECT_DOUBLE_EQ(sol.angles[D("ring.pip.flex")], s.model().dof[D("ring.pip.flex")].hi);
  EXPECT_NE(std::find(sol.at_limit.begin(), sol.at_limit.end(), D("ring.pip.flex")), sol.at_limit.end());
  // A pin outside the limits is clamped and counted.
  in = {};
  in.pins = {{D("index.mcp.flex"), 140.0}};
  const PostureSolution c = s.solve_linear(in);
  EXPECT_EQ(c.clamped_inputs, 1);
  EXPECT_DOUBLE_EQ(c.angles[D("index.mcp.flex")], 90.0);
}

TEST(Solver, SoftTargetsPullInProportionToTheirWeight) {
  const PostureSolver s(builtin_model("anatomical"));
  const int d = D("middle.pip.flex");
  double last = s.model().dof[d].relaxed;
  for (double w : {0.1, 1.0, 10.0, 1000.0}) {
    PostureInputs in;
    in.targets = {{d, 80.0, w}};
    const double got = s.solve_linear(in).angles[d];
    EXPECT_GT(got, last);
    EXPECT_LT(got, 80.0 + 1e-9);
    last = got;
  }
  EXPECT_NEAR(last, 80.0, 0.1);
}

TEST(Solver, OneInputMovesTheOtherFingersPlausibly) {
  // Thesis Fig. 4.19–4.20: drive the little finger alone; the neighbours follow, less with
  // distance, and nothing bends backwards.
  const PostureSolver s(builtin_model("anatomical"));
  PostureInputs in;
  in.pins = {{D("little.mcp.flex"), 75.0}};
  const PostureSolution a = s.solve_linear(in);
  auto moved = [&](const char* n) { return a.angles[D(n)] - s.model().dof[D(n)].relaxed; };
  EXPECT_GT(moved("ring.mcp.flex"), moved("middle.mcp.flex"));
  EXPECT_GT(moved("middle.mcp.flex"), moved("index.mcp.flex"));
  EXPECT_GT(moved("index.mcp.flex"), 0.0);
  EXPECT_GT(moved("little.pip.flex"), 0.0);
  EXPECT_GT(moved("little.dip.flex"), 0.0);
  for (int d = 6; d < kDofCount; ++d) EXPECT_GE(a.angles[d], s.model().dof[d].lo);
}

TEST(Solver, NonlinearPotentialNeverIncreasesAndConverges) {
  // Curved joint-pair data (a quarter circle): a line fits it badly, the grid follows it.
  Rng rng(9);
  AngleTable t;
  t.columns = {D("ring.mcp.flex"), D("little.mcp.flex")};
  for (int r = 0; r < 400; ++r) {
    const double u = rng.uniform(0, M_PI / 2);
    t.rows.push_back({60 - 60 * std::cos(u) + rng.normal() * 0.5, 60 * std::sin(u) + rng.normal() * 0.5});
    t.lines.push_back(r + 2);
  }
  CalibrationOptions co;
  co.method = "thesis-pairs";
  co.grids = true;
  co.grid_weight = 2.0;
  const PostureModel m = calibrate(t, co, "curve.csv", nullptr);
  ASSERT_EQ(m.grids.size(), 1u);
  const PostureSolver s(m);
  for (double pin : {5.0, 20.0, 40.0, 55.0}) {
    PostureInputs in;
    in.pins = {{D("ring.mcp.flex"), pin}};
    const PostureSolution nl = s.solve_nonlinear(in);
    EXPECT_TRUE(nl.converged) << pin;
    for (size_t k = 1; k < nl.energy_trace.size(); ++k) EXPECT_LE(nl.energy_trace[k], nl.energy_trace[k - 1] + 1e-12);
    const PostureSolution lin = s.solve_linear(in);
    EXPECT_LE(nl.energy, s.energy(lin.angles, in, true) + 1e-9);
    // The little finger lands nearer the measured curve than the straight line puts it.
    const double expect = 60 * std::sin(std::acos((60 - pin) / 60));
    EXPECT_LT(std::abs(nl.angles[D("little.mcp.flex")] - expect), std::abs(lin.angles[D("little.mcp.flex")] - expect))
        << pin;
  }
}

TEST(Solver, BadInputsAndModelsAreClearErrors) {
  const PostureSolver s(builtin_model("anatomical"));
  PostureInputs in;
  in.pins = {{D("index.mcp.flex"), std::nan("")}};
  EXPECT_NE(input_error_of([&] { s.solve_linear(in); }).find("index.mcp.flex"), std::string::npos);
  in = {};
  in.targets = {{D("index.mcp.flex"), 10.0, 0.0}};
  EXPECT_NE(input_error_of([&] { s.solve_linear(in); }).find("weight"), std::string::npos);
  int d;
  double v, w;
  EXPECT_NE(input_error_of([&] { parse_assignment("index.mcp.flx=3", "--set", &d, &v); }).find("unknown DOF"), std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_assignment("index.mcp.flex", "--set", &d, &v); }).find("name=value"), std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_assignment("I2.flex=nan", "--set", &d, &v); }).find("finite"), std::string::npos);
  parse_assignment("l4.flex=12.5@3", "--target", &d, &v, &w);
  EXPECT_EQ(d, D("little.dip.flex"));
  EXPECT_EQ(v, 12.5);
  EXPECT_EQ(w, 3.0);
  // Models: zero stiffness (singular system), inverted limits, unknown DOF, relative pairs.
  Json j = model_to_json(builtin_model("anatomical"));
  j["dofs"]["ring.pip.flex"]["stiffness"] = 0.0;
  EXPECT_NE(input_error_of([&] { parse_model(j, "m.json"); }).find("stiffness"), std::string::npos);
  j = model_to_json(builtin_model("anatomical"));
  j["dofs"]["ring.pip.flex"]["limits"] = {50, 10};
  EXPECT_NE(input_error_of([&] { parse_model(j, "m.json"); }).find("ring.pip.flex"), std::string::npos);
  j = model_to_json(builtin_model("anatomical"));
  j["pairs"][0]["a"] = "ring.pip.flexion";
  EXPECT_NE(input_error_of([&] { parse_model(j, "m.json"); }).find("pairs[0]"), std::string::npos);
  // A model survives a round trip through its file.
  const PostureModel back = parse_model(model_to_json(builtin_model("thesis")), "t.json");
  const PostureSolver s2(back), s3(builtin_model("thesis"));
  PostureInputs pin;
  pin.pins = {{D("L2.flex"), 60.0}};
  EXPECT_EQ(s2.solve_linear(pin).angles, s3.solve_linear(pin).angles);
}

// ---------------------------------------------------------------- calibration

TEST(Calibrate, RecoversPlantedLinesAndWeightOrder) {
  const AngleTable t = planted(600, 3);
  for (const char* weights : {"thesis", "inverse"}) {
    CalibrationOptions o;
    o.method = "thesis-pairs";
    o.weights = weights;
    Json rep;
    const PostureModel m = calibrate(t, o, "planted.csv", &rep);
    // Automatic pairs: the two planted ones lead; the unrelated column is in none.
    ASSERT_GE(m.pairs.size(), 2u);
    const PairLine *ab = nullptr, *ac = nullptr;
    for (const auto& p : m.pairs) {
      EXPECT_NE(p.a, D("thumb.ip.flex"));
      EXPECT_NE(p.b, D("thumb.ip.flex"));
      if (p.a == D("index.mcp.flex") && p.b == D("index.pip.flex")) ab = &p;
      if (p.a == D("index.mcp.flex") && p.b == D("middle.mcp.flex")) ac = &p;
    }
    ASSERT_TRUE(ab && ac);
    EXPECT_NEAR(-ab->alpha / ab->beta, 0.8, 0.02);
    EXPECT_NEAR(-ab->gamma / ab->beta, 5.0, 0.5);
    EXPECT_NEAR(-ac->alpha / ac->beta, -0.5, 0.05);
    EXPECT_NEAR(-ac->gamma / ac->beta, 40.0, 1.5);
    // Eq. 3.18 weights the wider spread more; "inverse" the tighter one.
    if (std::string(weights) == "thesis") EXPECT_GT(ac->weight, 3 * ab->weight);
    else EXPECT_GT(ab->weight, 3 * ac->weight);
    double max_w = 0;
    for (const auto& p : m.pairs) max_w = std::max(max_w, p.weight);
    EXPECT_DOUBLE_EQ(max_w, 1.0);
  }
}

TEST(Calibrate, RelaxedLimitsAndMissingDofs) {
  AngleTable t = planted(200, 4);
  t.rows[17][0] = 120.0;  // beyond index.mcp.flex's 90° limit
  const PostureModel m = calibrate(t, CalibrationOptions{}, "p.csv", nullptr);
  EXPECT_GE(m.dof[D("index.mcp.flex")].hi, 120.0);
  bool noted = false;
  for (const auto& n : m.notes) noted = noted || n.find("index.mcp.flex") != std::string::npos;
  EXPECT_TRUE(noted);
  // A DOF not in the table keeps its defaults.
  EXPECT_EQ(m.dof[D("ring.dip.flex")].relaxed, default_dof_params()[D("ring.dip.flex")].relaxed);
  EXPECT_NEAR(m.dof[D("index.pip.flex")].relaxed, 0.8 * 30 + 5, 3.0);  // median of the planted data
}

TEST(Calibrate, TooShortRaggedOrBadTablesAreErrors) {
  EXPECT_NE(input_error_of([&] { calibrate(planted(6, 1), CalibrationOptions{}, "short.csv", nullptr); }).find("short.csv"),
            std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_angle_table("index.mcp.flex,I3.flex\n1,2\n3\n", "r.csv"); }).find("r.csv:3"),
            std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_angle_table("index.mcp.flex,I3.flex\n1,abc\n", "n.csv"); }).find("n.csv:2"),
            std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_angle_table("index.mcp.flex,I2.flex\n", "d.csv"); }).find("twice"), std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_angle_table("knuckle\n", "k.csv"); }).find("knuckle"), std::string::npos);
  EXPECT_NE(input_error_of([&] { parse_angle_table("I2.flex\n1e300\n", "h.csv"); }).find("plausible"), std::string::npos);
  // A recording in radians (every angle within ±π) is refused naming the file; in degrees it calibrates.
  AngleTable rad = planted(600, 3);
  for (auto& row : rad.rows)
    for (double& v : row) v *= M_PI / 180;
  const std::string why = input_error_of([&] { calibrate(rad, CalibrationOptions{}, "glove.csv", nullptr); });
  EXPECT_EQ(why.rfind("glove.csv", 0), 0u) << why;
  EXPECT_NE(why.find("radians?"), std::string::npos) << why;
  EXPECT_NO_THROW(calibrate(planted(600, 3), CalibrationOptions{}, "glove.csv", nullptr));
  // A hand held still (every row the same posture) calibrates nothing, by any method: before,
  // thesis-pairs correlated the columns' rounding and wrote lines with r = ±1.
  AngleTable still = planted(600, 3);
  for (auto& row : still.rows) row = still.rows[0];
  for (const char* method : {"gaussian", "mixture", "thesis-pairs"}) {
    CalibrationOptions o;
    o.method = method;
    EXPECT_NE(input_error_of([&] { calibrate(still, o, "still.csv", nullptr); }).find("nothing to correlate"),
              std::string::npos) << method;
    o.pairs = {{still.columns[0], still.columns[1]}};
    if (o.method == "thesis-pairs")
      EXPECT_NE(input_error_of([&] { calibrate(still, o, "still.csv", nullptr); }).find("the same value in every row"),
                std::string::npos);
  }
  const AngleTable t = parse_angle_table("I2.flex,I3.flex\n1,\n,2\n", "ok.csv");
  ASSERT_EQ(t.rows.size(), 2u);
  EXPECT_TRUE(std::isnan(t.rows[0][1]));
}

// ---------------------------------------------------------------- motion capture

TEST(Mocap, TrcAnglesByConstruction) {
  // Back of the hand in the XY plane (X along the hand, thumb toward +Y, back up +Z); the
  // index's middle marker 30° below the plane, its tip bending a further 40°.
  auto dir = [](double deg) { return Eigen::Vector3d(std::cos(deg * kDeg), 0, -std::sin(deg * kDeg)); };
  const Eigen::Vector3d top(0, 0, 0), left(-60, 20, 0), right(-60, -20, 0);
  const Eigen::Vector3d im = top + Eigen::Vector3d(0, 8, 0) + 40 * dir(30), it = im + 25 * dir(70);
  const Eigen::Vector3d mm = top + 45 * dir(10), mt = mm + 30 * dir(25);
  std::string trc =
      "PathFileType\t4\t(X/Y/Z)\tx.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
      "100\t100\t2\t7\tm\t100\t1\t2\nFrame#\tTime\thand_top\t\t\thand_left\t\t\thand_right\t\t\tindex_middle\t\t\tindex_tip\t\t\t"
      "middle_middle\t\t\tmiddle_tip\n\t\tX1\tY1\tZ1\tX2\tY2\tZ2\tX3\tY3\tZ3\tX4\tY4\tZ4\tX5\tY5\tZ5\tX6\tY6\tZ6\tX7\tY7\tZ7\n";
  for (int f = 1; f <= 2; ++f) {
    trc += std::to_string(f) + "\t" + std::to_string(0.01 * f);
    const Eigen::Vector3d markers[] = {top, left, right, im, it, mm, mt};
    for (int m = 0; m < 7; ++m) {
      for (int k = 0; k < 3; ++k) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "\t%.9f", markers[m](k) / 1000.0);
        trc += f == 2 && m == 4 ? std::string("\t") : std::string(buf);  // frame 2: the index tip is lost
      }
    }
    trc += "\n";
  }
  const std::string dir_ = test::temp_dir("trc");
  test::write_text(dir_ + "/m.trc", trc);
  const MarkerTrack track = read_marker_file(dir_ + "/m.trc");
  ASSERT_EQ(track.frames.size(), 2u);
  const MocapAngles a = angles_from_markers(track, "m.trc");
  auto col = [&](const char* n) {
    for (size_t k = 0; k < a.table.columns.size(); ++k)
      if (a.table.columns[k] == D(n)) return static_cast<int>(k);
    return -1;
  };
  ASSERT_GE(col("index.mcp.flex"), 0);
  EXPECT_NEAR(a.table.rows[0][col("index.mcp.flex")], 30.0, 1e-6);
  EXPECT_NEAR(a.table.rows[0][col("index.pip.flex")], 40.0, 1e-6);
  EXPECT_NEAR(a.table.rows[0][col("middle.mcp.flex")], 10.0, 1e-6);
  EXPECT_NEAR(a.table.rows[0][col("index.mcp.abd")], std::atan2(8.0, 40 * std::cos(30 * kDeg)) / kDeg, 1e-6);
  EXPECT_TRUE(std::isnan(a.table.rows[1][col("index.pip.flex")]));  // the lost marker leaves a gap
  EXPECT_EQ(a.frames_with_gaps, 1u);
  EXPECT_EQ(col("ring.mcp.flex"), -1);  // no ring markers: no ring angles
}

TEST(Mocap, SharedQualisysRecordingReadsAndCalibrates) {
  const MarkerTrack t = read_qualisys_tsv(kMocap);
  EXPECT_EQ(t.frames.size(), 6000u);
  EXPECT_EQ(t.names.size(), 21u);
  EXPECT_DOUBLE_EQ(t.rate_hz, 100.0);
  const MocapAngles a = angles_from_markers(t, kMocap);
  EXPECT_EQ(a.table.columns.size(), 14u);
  Json rep;
  CalibrationOptions o;
  o.method = "thesis-pairs";
  const PostureModel m = calibrate(a.table, o, kMocap, &rep);
  ASSERT_GE(m.pairs.size(), 3u);
  for (const auto& p : rep["pairs"]) EXPECT_GE(std::abs(p["r"].get<double>()), 0.5);
  EXPECT_FALSE(m.notes.empty());  // the recording drifts past textbook ranges: said so
  const PostureSolver s(m);
  PostureInputs in;
  in.pins = {{D("little.mcp.flex"), 45.0}};
  const PostureSolution sol = s.solve(in);
  for (double v : sol.angles) EXPECT_TRUE(std::isfinite(v));
}

// A left hand (the shared recording's mirror image), one whose side markers are named the
// other way round (hand_right on the thumb's side), and markers labelled for a subject
// ("P01:HAND_TOP") give the recording's own angles: the hand
// and the thumb's side are told from the markers, not assumed (before, the mirror image's
// flexions came out with their signs turned, index.mcp.flex up to 77° off).
TEST(Mocap, ALeftHandSwappedSideMarkersOrLabelledNamesGiveTheSameAngles) {
  const MarkerTrack right = read_qualisys_tsv(kMocap);
  const MocapAngles a = angles_from_markers(right, kMocap);
  auto said = [](const MocapAngles& m, const std::string& what) {
    for (const auto& n : m.notes)
      if (n.find(what) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(said(a, "a right hand"));
  MarkerTrack left = right;
  for (auto& f : left.frames)
    for (auto& p : f) p.x() = -p.x();
  MarkerTrack swapped = left;
  for (auto& n : swapped.names) n = n == "hand_left" ? "hand_right" : n == "hand_right" ? "hand_left" : n;
  MarkerTrack right_swapped = right;
  right_swapped.names = swapped.names;
  MarkerTrack labelled = right;  // as Vicon or QTM label a subject's markers
  for (auto& n : labelled.names) {
    std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
    n = "P01:" + n;
  }
  for (const MarkerTrack* t : {&left, &swapped, &right_swapped, &labelled}) {
    const MocapAngles b = angles_from_markers(*t, "variant");
    EXPECT_TRUE(said(b, t == &right_swapped || t == &labelled ? "a right hand" : "a left hand"));
    EXPECT_EQ(said(b, "hand_right is on the thumb's side"), t == &swapped || t == &right_swapped);
    ASSERT_EQ(b.table.columns, a.table.columns);
    ASSERT_EQ(b.table.rows.size(), a.table.rows.size());
    double worst = 0;
    for (size_t r = 0; r < a.table.rows.size(); ++r)
      for (size_t c = 0; c < a.table.columns.size(); ++c) {
        const double x = a.table.rows[r][c], y = b.table.rows[r][c];
        EXPECT_EQ(std::isnan(x), std::isnan(y));
        if (!std::isnan(x) && !std::isnan(y)) worst = std::max(worst, std::abs(x - y));
      }
    EXPECT_LT(worst, 1e-9);
  }
}

// A Qualisys export with more columns per marker than X Y Z (QTM's trajectory types: "hand_top
// Type" after each marker's Z) is read by the column header's names: the same positions as the
// plain export (before: "'Measured' is not a number").
TEST(Mocap, AQualisysExportWithTypeColumnsReadsByName) {
  std::istringstream in(read_file(kMocap));
  std::string text, line;
  bool data = false;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::istringstream row(line);
    for (std::string c; std::getline(row, c, '\t');) cells.push_back(c);
    if (!cells.empty() && (cells[0] == "Frame" || (data && cells.size() > 2))) {
      const bool header = cells[0] == "Frame";
      data = true;
      std::string out = cells[0] + "\t" + cells[1];
      for (size_t c = 2; c + 2 < cells.size(); c += 3)
        out += "\t" + cells[c] + "\t" + cells[c + 1] + "\t" + cells[c + 2] + "\t" +
               (header ? cells[c].substr(0, cells[c].size() - 2) + " Type" : std::string("Measured"));
      text += out + "\n";
    } else {
      text += line + "\n";
    }
  }
  const MarkerTrack plain = read_qualisys_tsv(kMocap), typed = parse_qualisys_tsv(text, "typed.tsv");
  ASSERT_EQ(typed.names, plain.names);
  ASSERT_EQ(typed.frames.size(), plain.frames.size());
  for (size_t f = 0; f < plain.frames.size(); ++f)
    for (size_t m = 0; m < plain.names.size(); ++m) {
      const Eigen::Vector3d &a = plain.frames[f][m], &b = typed.frames[f][m];
      ASSERT_TRUE((a.array().isNaN() && b.array().isNaN()).all() || a == b) << f << " " << plain.names[m];
    }
}

// Each angle is measured wherever its own markers are seen: an occluded fingertip leaves its
// finger's PIP bend out of that frame, not its MCP flexion; a recording without thumb_tip
// keeps thumb.cmc.abd (hand_left -> thumb_middle). An angle never measurable is left out and
// said, not written as an empty column; no hand frame or no angle at all is an error.
TEST(Mocap, EachAngleNeedsOnlyItsOwnMarkers) {
  const MarkerTrack full = read_qualisys_tsv(kMocap);
  const MocapAngles a = angles_from_markers(full, kMocap);
  auto column = [](const MocapAngles& m, const char* n) {
    for (size_t k = 0; k < m.table.columns.size(); ++k)
      if (m.table.columns[k] == D(n)) return static_cast<int>(k);
    return -1;
  };
  auto marker = [](const MarkerTrack& t, const std::string& n) {
    return static_cast<int>(std::find(t.names.begin(), t.names.end(), n) - t.names.begin());
  };
  auto said = [](const MocapAngles& m, const std::string& what) {
    for (const auto& n : m.notes)
      if (n.find(what) != std::string::npos) return true;
    return false;
  };
  // A frame where everything is seen; the index tip lost there.
  size_t f0 = 0;
  while (std::any_of(a.table.rows[f0].begin(), a.table.rows[f0].end(), [](double v) { return std::isnan(v); })) ++f0;
  MarkerTrack occluded = full;
  occluded.frames[f0][marker(full, "index_tip")] = Eigen::Vector3d::Constant(std::nan(""));
  const MocapAngles b = angles_from_markers(occluded, "occluded");
  EXPECT_EQ(b.table.rows[f0][column(b, "index.mcp.flex")], a.table.rows[f0][column(a, "index.mcp.flex")]);
  EXPECT_EQ(b.table.rows[f0][column(b, "index.mcp.abd")], a.table.rows[f0][column(a, "index.mcp.abd")]);
  EXPECT_TRUE(std::isnan(b.table.rows[f0][column(b, "index.pip.flex")]));
  EXPECT_EQ(b.frames_with_gaps, a.frames_with_gaps + 1);
  // No thumb_tip in the file: thumb.cmc.abd stays, the same values.
  MarkerTrack no_tip = full;
  const int k = marker(full, "thumb_tip");
  no_tip.names.erase(no_tip.names.begin() + k);
  for (auto& fr : no_tip.frames) fr.erase(fr.begin() + k);
  const MocapAngles c = angles_from_markers(no_tip, "no_tip");
  ASSERT_GE(column(c, "thumb.cmc.abd"), 0);
  EXPECT_EQ(column(c, "thumb.mcp.flex"), -1);
  EXPECT_TRUE(said(c, "thumb.mcp.flex: no marker thumb_tip"));
  for (size_t r = 0; r < a.table.rows.size(); ++r) {
    const double x = a.table.rows[r][column(a, "thumb.cmc.abd")], y = c.table.rows[r][column(c, "thumb.cmc.abd")];
    ASSERT_TRUE(x == y || (std::isnan(x) && (std::isnan(y) || std::isnan(a.table.rows[r][column(a, "thumb.mcp.flex")]))))
        << r;
  }
  // thumb_tip in the file but never seen: left out, said.
  MarkerTrack unseen = full;
  for (auto& fr : unseen.frames) fr[k] = Eigen::Vector3d::Constant(std::nan(""));
  const MocapAngles d = angles_from_markers(unseen, "unseen");
  EXPECT_EQ(column(d, "thumb.mcp.flex"), -1);
  EXPECT_EQ(d.table.columns.size(), a.table.columns.size() - 1);
  EXPECT_TRUE(said(d, "thumb.mcp.flex: its markers (thumb_middle, thumb_tip and the back's three) are never seen"));
  // The back never seen together, or no digit marker at all: errors naming the file.
  MarkerTrack no_back = full;
  for (auto& fr : no_back.frames) fr[marker(full, "hand_top")] = Eigen::Vector3d::Constant(std::nan(""));
  EXPECT_NE(input_error_of([&] { angles_from_markers(no_back, "noback.tsv"); }).find("never seen in the same frame"),
            std::string::npos);
  MarkerTrack back_only;
  back_only.names = {"hand_top", "hand_left", "hand_right"};
  for (const auto& fr : full.frames)
    back_only.frames.push_back({fr[marker(full, "hand_top")], fr[marker(full, "hand_left")], fr[marker(full, "hand_right")]});
  const std::string e = input_error_of([&] { angles_from_markers(back_only, "back.tsv"); });
  EXPECT_NE(e.find("back.tsv"), std::string::npos);
  EXPECT_NE(e.find("no joint angle"), std::string::npos);
}

TEST(Mocap, BadMarkerFilesAreErrors) {
  const std::string dir = test::temp_dir("mocapbad");
  test::write_text(dir + "/a.tsv", "NO_OF_FRAMES\t3\nMARKER_NAMES\thand_top\n1\t2\t3\n");
  EXPECT_NE(input_error_of([&] { read_qualisys_tsv(dir + "/a.tsv"); }).find("NO_OF_FRAMES"), std::string::npos);
  // A count out of range: the message gives the value and the range (it said only "is not a count").
  test::write_text(dir + "/big.tsv", "NO_OF_FRAMES\t2000000000\nMARKER_NAMES\thand_top\n1\t2\t3\n");
  EXPECT_NE(input_error_of([&] { read_qualisys_tsv(dir + "/big.tsv"); }).find("big.tsv:1: NO_OF_FRAMES '2000000000' is not a count in [0, 1e9]"),
            std::string::npos);
  test::write_text(dir + "/b.tsv", "MARKER_NAMES\tfoo\n1\t2\tx\n");
  EXPECT_NE(input_error_of([&] { read_qualisys_tsv(dir + "/b.tsv"); }).find("b.tsv:2"), std::string::npos);
  test::write_text(dir + "/c.tsv", "MARKER_NAMES\tfoo\tbar\n1\t2\t3\t4\t5\t6\n");
  const MarkerTrack t = read_qualisys_tsv(dir + "/c.tsv");
  EXPECT_NE(input_error_of([&] { angles_from_markers(t, "c.tsv"); }).find("hand_top"), std::string::npos);
  test::write_text(dir + "/d.xyz", "");
  EXPECT_NE(input_error_of([&] { read_marker_file(dir + "/d.xyz"); }).find("extension"), std::string::npos);
}
