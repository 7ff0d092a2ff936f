// Calibration that generalises (issue 14): the Gaussian model and its factoring into springs
// and synergy rows, EM over gaps, several recordings with their offsets, the mixture, and
// the cross-validated figures against the mean posture and a linear regression.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>

#include "core/errors.hpp"
#include "posture/calibrate.hpp"
#include "posture/evaluate.hpp"
#include "posture/gaussian.hpp"
#include "posture/mocap.hpp"
#include "posture/solver.hpp"
#include "synth/angle_recording.hpp"
#include "test_util.hpp"

namespace handskin {
namespace {

const std::string kMocap = std::string(HANDSKIN_SOURCE_DIR) + "/../shared/data/mocap/qualisys-hand-recording.tsv";

AngleRecording recording(const std::string& kind, long rows, unsigned seed, int person = 0, double gaps = 0) {
  AngleRecordingOptions o;
  o.kind = kind;
  o.rows = rows;
  o.seed = seed;
  o.person = person;
  o.gaps = gaps;
  return synth_angle_recording(o);
}

// The model's Gaussian over the recorded DOFs: (K + AᵀWA) restricted to them, inverted, times
// the energy scale, and its conditional mean for some pins.
Eigen::MatrixXd model_covariance(const PostureModel& m, const std::vector<int>& cols, double scale) {
  const PostureSolver s(m);
  const Eigen::MatrixXd H = s.system_matrix();
  Eigen::MatrixXd Hm(cols.size(), cols.size());
  for (size_t a = 0; a < cols.size(); ++a)
    for (size_t b = 0; b < cols.size(); ++b) Hm(a, b) = H(cols[a], cols[b]);
  return scale * Hm.inverse();
}

// Each task's held-out figures from a report: model, linear regression, and (mixture) the
// single Gaussian.
struct Row {
  std::string task;
  double model, linreg, linear;
};
std::vector<Row> cv_rows(const Json& rep, const char* scheme) {
  std::vector<Row> out;
  for (const auto& t : rep["cross_validation"][scheme]["tasks"])
    out.push_back({t["task"].get<std::string>(), t["model_rms_deg"].get<double>(), t["linear_regression_rms_deg"].get<double>(),
                   t.contains("linear_model_rms_deg") ? t["linear_model_rms_deg"].get<double>() : std::nan("")});
  return out;
}

TEST(GaussianCalibration, FactoringIsExact) {
  // K + AᵀWA equals the scaled precision, every spring within the model's bounds.
  const AngleRecording r = recording("gaussian", 4000, 11);
  PostureSamples s;
  s.dofs = r.table.columns;
  s.x.resize(static_cast<Eigen::Index>(r.table.rows.size()), static_cast<Eigen::Index>(s.dofs.size()));
  for (size_t i = 0; i < r.table.rows.size(); ++i)
    for (size_t c = 0; c < s.dofs.size(); ++c) s.x(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c)) = r.table.rows[i][c];
  s.recording.assign(r.table.rows.size(), 0);
  for (double shrink : {0.0, 0.1}) {
    const GaussianStats st = gaussian_stats(s, true, shrink);
    const double scale = energy_scale_for({st.cov});
    std::vector<LinearConstraint> rows;
    const std::vector<double> k = factor_precision(st.cov, st.mean, s.dofs, scale, "test", &rows);
    const Eigen::Index m = st.cov.rows();
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(m, m);
    for (Eigen::Index i = 0; i < m; ++i) {
      H(i, i) = k[i];
      EXPECT_GE(k[i], kMinStiffness);
      EXPECT_LE(k[i], kMaxStiffness);
    }
    for (const auto& c : rows) {
      Eigen::VectorXd a = Eigen::VectorXd::Zero(m);
      for (const auto& [d, v] : c.terms)
        for (Eigen::Index i = 0; i < m; ++i)
          if (s.dofs[i] == d) a(i) = v;
      H += c.weight * a * a.transpose();
      EXPECT_LE(c.weight, kMaxWeight);
      EXPECT_NEAR(a.dot(st.mean) + c.offset, 0.0, 1e-9);  // every row holds at the mean
    }
    const Eigen::MatrixXd P = scale * st.cov.inverse();
    EXPECT_LT((H - P).norm() / P.norm(), 1e-9) << "shrinkage " << shrink;
  }
}

TEST(GaussianCalibration, RecoversTheSyntheticTruth) {
  // 20 000 frames of a known Gaussian: the rest posture is its mean, the model's covariance
  // is the truth's, and a solve with pins is the true conditional mean.
  for (double gaps : {0.0, 0.2}) {
    const AngleRecording r = recording("gaussian", 20000, 5, 0, gaps);
    CalibrationOptions o;
    o.shrinkage = 0;
    o.evaluate = false;
    Json rep;
    const PostureModel m = calibrate(r.table, o, "gauss.csv", &rep);
    const std::vector<int>& cols = r.table.columns;
    for (size_t c = 0; c < cols.size(); ++c) EXPECT_NEAR(m.dof[cols[c]].relaxed, r.mean(static_cast<Eigen::Index>(c)), 0.5);
    const Eigen::MatrixXd C = model_covariance(m, cols, rep["gaussian"]["energy_scale"].get<double>());
    EXPECT_LT((C - r.covariance).norm() / r.covariance.norm(), gaps > 0 ? 0.04 : 0.03) << "gaps " << gaps;
    // Pin the middle MCP and the index PIP 10° off their means.
    const PostureSolver solver(m);
    std::vector<Eigen::Index> given;
    for (Eigen::Index c = 0; c < static_cast<Eigen::Index>(cols.size()); ++c)
      if (cols[c] == dof_index("middle.mcp.flex").value() || cols[c] == dof_index("index.pip.flex").value()) given.push_back(c);
    ASSERT_EQ(given.size(), 2u);
    PostureInputs in;
    Eigen::Vector2d dx(10, -10);
    for (int k = 0; k < 2; ++k) in.pins.emplace_back(cols[given[k]], r.mean(given[k]) + dx(k));
    const PostureSolution sol = solver.solve(in);
    Eigen::Matrix2d Sgg;
    for (int a = 0; a < 2; ++a)
      for (int b = 0; b < 2; ++b) Sgg(a, b) = r.covariance(given[a], given[b]);
    for (Eigen::Index c = 0; c < static_cast<Eigen::Index>(cols.size()); ++c) {
      const Eigen::Vector2d Scg(r.covariance(c, given[0]), r.covariance(c, given[1]));
      const double truth = r.mean(c) + Scg.dot(Sgg.ldlt().solve(dx));
      EXPECT_NEAR(sol.angles[cols[c]], truth, 1.0) << dofs()[cols[c]].name << " gaps " << gaps;
    }
  }
}

TEST(GaussianCalibration, HeldOutNoWorseThanRegression) {
  // Held-out blocks: on a synthetic Gaussian with gaps and on the shared recording, the default
  // model is within 2 % of a linear regression fitted on the same frames on every task, and
  // well below the mean posture.
  const AngleRecording r = recording("gaussian", 8000, 2, 0, 0.05);
  const MocapAngles q = angles_from_markers(read_qualisys_tsv(kMocap), kMocap);
  for (const auto& [table, name] : {std::pair{r.table, std::string("gauss.csv")}, std::pair{q.table, kMocap}}) {
    Json rep;
    calibrate(table, CalibrationOptions{}, name, &rep);
    const auto rows = cv_rows(rep, "blocks");
    ASSERT_GE(rows.size(), 2u) << name;
    for (const auto& t : rows) {
      EXPECT_LE(t.model, 1.02 * t.linreg) << name << ": " << t.task;
      EXPECT_GT(t.model, 0);
    }
    for (const auto& t : rep["cross_validation"]["blocks"]["tasks"])
      EXPECT_LT(t["model_rms_deg"].get<double>(), 0.9 * t["mean_posture_rms_deg"].get<double>()) << name;
  }
}

TEST(GaussianCalibration, SeveralRecordingsLeaveOneOut) {
  // Five people, each with their own offsets (sd 6°): the offsets are removed, the
  // leave-one-person-out figures reported, and the model no worse than the regression there.
  std::vector<AngleTable> tables;
  std::vector<std::string> files;
  for (int p = 1; p <= 5; ++p) {
    AngleRecordingOptions o;
    o.rows = 2000;
    o.seed = 3;
    o.person = p;
    o.offset_sd = 6;
    tables.push_back(synth_angle_recording(o).table);
    files.push_back("person" + std::to_string(p) + ".csv");
  }
  Json rep;
  const PostureModel m = calibrate(tables, files, CalibrationOptions{}, &rep);
  EXPECT_EQ(rep["recordings"].size(), 5u);
  EXPECT_EQ(rep["frames"].get<long>(), 10000);
  EXPECT_EQ(rep["selection"]["scheme"].get<std::string>(), "leave one recording out");
  EXPECT_EQ(rep["offsets"].get<std::string>(), "removed per recording");
  const auto rows = cv_rows(rep, "recordings");
  ASSERT_EQ(rows.size(), 3u);
  for (const auto& t : rows) EXPECT_LE(t.model, 1.02 * t.linreg) << t.task;
  EXPECT_NE(m.description.find("person5.csv"), std::string::npos);
}

TEST(MixtureCalibration, BeatsTheLinearModelOnCurvedData) {
  const AngleRecording r = recording("curved", 4000, 4);
  CalibrationOptions o;
  o.method = "mixture";
  Json rep;
  const PostureModel m = calibrate(r.table, o, "curved.csv", &rep);
  ASSERT_GE(m.mixture.components.size(), 2u);
  for (const auto& t : cv_rows(rep, "blocks")) {
    EXPECT_LT(t.model, 0.9 * t.linear) << t.task;
    EXPECT_LT(t.model, t.linreg) << t.task;
  }
  // The model file round-trips, and solving it respects pins and limits.
  const PostureModel back = parse_model(model_to_json(m), "mixture.json");
  const PostureSolver a(m), b(back);
  PostureInputs in;
  in.pins = {{dof_index("middle.mcp.flex").value(), 60.0}};
  in.torques = {{dof_index("thumb.ip.flex").value(), 5.0}};
  const PostureSolution sa = a.solve(in), sb = b.solve(in);
  EXPECT_EQ(sa.angles, sb.angles);
  EXPECT_EQ(sa.angles[dof_index("middle.mcp.flex").value()], 60.0);
  ASSERT_EQ(sa.component_weights.size(), m.mixture.components.size());
  double total = 0;
  for (double w : sa.component_weights) total += w;
  EXPECT_NEAR(total, 1.0, 1e-12);
  for (int d = 0; d < kDofCount; ++d) {
    EXPECT_GE(sa.angles[d], m.dof[d].lo);
    EXPECT_LE(sa.angles[d], m.dof[d].hi);
  }
  // On the curve: a middle MCP of 60° means t ≈ 0.69, so its PIP ≈ 5 + 95 t² ≈ 50°; the
  // straight line through the data misses by more.
  const double t = (60.0 - 5) / 80, pip = 5 + 95 * t * t;
  EXPECT_NEAR(sa.angles[dof_index("middle.pip.flex").value()], pip, 4.0);
}

TEST(MixtureCalibration, KeepsTheLinearModelWhereItIsNoBetter) {
  // On Gaussian data a mixture only fits noise: whatever is chosen, no task is worse held out.
  const AngleRecording r = recording("gaussian", 3000, 9);
  CalibrationOptions o;
  o.method = "mixture";
  Json rep;
  const PostureModel m = calibrate(r.table, o, "g.csv", &rep);
  for (const auto& t : cv_rows(rep, "blocks"))
    if (!m.mixture.components.empty()) {
      EXPECT_LE(t.model, t.linear) << t.task;
    }
  for (const auto& c : rep["mixture"]["candidates"])
    if (c["components"].get<int>() == rep["mixture"]["components"].get<int>()) {
      EXPECT_TRUE(c["no_task_worse_than_linear"].get<bool>());
    }
}

TEST(GaussianCalibration, TasksAndSplits) {
  std::vector<int> cols;
  for (const char* n : {"index.mcp.flex", "index.pip.flex", "middle.mcp.flex", "middle.pip.flex", "middle.dip.flex"})
    cols.push_back(dof_index(n).value());
  std::vector<std::string> skipped;
  const auto tasks = standard_tasks(cols, &skipped);
  ASSERT_EQ(tasks.size(), 3u);
  EXPECT_EQ(tasks[0].name, "middle.mcp.flex -> the rest");
  EXPECT_EQ(tasks[0].predicted.size(), 4u);
  EXPECT_EQ(tasks[1].given.size(), 2u);     // both PIPs
  EXPECT_EQ(tasks[1].predicted.size(), 1u);  // the one DIP
  EXPECT_TRUE(skipped.empty());
  // Without DIPs the PIP task is skipped and said so.
  cols.pop_back();
  skipped.clear();
  EXPECT_EQ(standard_tasks(cols, &skipped).size(), 2u);
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_NE(skipped[0].find("DIP"), std::string::npos);
  // Blocks cover every row once as test; recordings split by recording.
  PostureSamples s;
  s.dofs = cols;
  s.recordings = 2;
  s.x = Eigen::MatrixXd::Zero(23, static_cast<Eigen::Index>(cols.size()));
  for (int i = 0; i < 23; ++i) s.recording.push_back(i < 10 ? 0 : 1);
  std::vector<int> seen(23, 0);
  for (const auto& sp : block_splits(s, 5)) {
    EXPECT_EQ(sp.train.size() + sp.test.size(), 23u);
    for (long i : sp.test) ++seen[i];
  }
  for (int v : seen) EXPECT_EQ(v, 1);
  const auto lo = recording_splits(s);
  ASSERT_EQ(lo.size(), 2u);
  EXPECT_EQ(lo[0].test.size(), 10u);
  EXPECT_EQ(lo[1].test.size(), 13u);
}

TEST(GaussianCalibration, BadModelsAndOptionsAreRefused) {
  const Json good = model_to_json(calibrate(recording("curved", 2000, 4).table,
                                            [] {
                                              CalibrationOptions o;
                                              o.method = "mixture";
                                              o.components = 3;
                                              o.evaluate = false;
                                              return o;
                                            }(),
                                            "c.csv", nullptr));
  ASSERT_TRUE(good.contains("mixture"));
  ASSERT_TRUE(good.contains("constraints"));
  auto refused = [&](const std::function<void(Json&)>& edit, const std::string& says) {
    Json j = good;
    edit(j);
    EXPECT_NE(test::input_error_of([&] { parse_model(j, "m.json"); }).find(says), std::string::npos) << says;
  };
  refused([](Json& j) { j["mixture"]["components"][0]["weight"] = 0.9; }, "sum to 1");
  refused([](Json& j) { j["mixture"]["components"][1]["stiffness"]["middle.mcp.flex"] = 0; }, "stiffness");
  refused([](Json& j) { j["mixture"]["components"][0]["relaxed"]["middle.mcp.flex"] = 900; }, "outside the limits");
  refused([](Json& j) { j["mixture"]["energy_scale"] = -1; }, "energy_scale");
  refused([](Json& j) { j["mixture"]["energy_scale"] = 1e-300; }, "energy_scale");
  refused([](Json& j) { j["mixture"]["components"] = Json::array(); }, "components");
  refused([](Json& j) { j["constraints"][0]["terms"] = Json::object(); }, "terms");
  refused([](Json& j) { j["constraints"][0]["terms"]["no.such.dof"] = 1; }, "unknown DOF");
  refused([](Json& j) { j["constraints"][0]["weight"] = 1e9; }, "weight");
  refused([](Json& j) { j["constraints"][0]["offset"] = std::nan(""); }, "offset");
  refused([](Json& j) { j["constraints"][0]["colour"] = 1; }, "colour");
  // Options.
  CalibrationOptions o;
  std::string err;
  o.method = "pca";
  EXPECT_FALSE(o.IsValid(&err));
  o = {};
  o.grids = true;
  EXPECT_FALSE(o.IsValid(&err));
  EXPECT_NE(err.find("thesis-pairs"), std::string::npos);
  o = {};
  o.components = 1;
  EXPECT_FALSE(o.IsValid(&err));
  o = {};
  o.shrinkage = 2;
  EXPECT_FALSE(o.IsValid(&err));
  // A table with one varying DOF has nothing to correlate.
  AngleTable t;
  t.columns = {dof_index("index.mcp.flex").value(), dof_index("index.pip.flex").value()};
  for (int i = 0; i < 50; ++i) t.rows.push_back({static_cast<double>(i), 10.0});
  EXPECT_NE(test::input_error_of([&] { calibrate(t, CalibrationOptions{}, "flat.csv", nullptr); }).find("flat.csv"), std::string::npos);
}

TEST(GaussianCalibration, Deterministic) {
  const AngleRecording r = recording("curved", 1500, 8, 0, 0.05);
  CalibrationOptions o;
  o.method = "mixture";
  o.components = 3;
  const Json a = model_to_json(calibrate(r.table, o, "c.csv", nullptr)), b = model_to_json(calibrate(r.table, o, "c.csv", nullptr));
  EXPECT_EQ(a.dump(), b.dump());
}

}  // namespace
}  // namespace handskin
