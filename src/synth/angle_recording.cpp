#include "synth/angle_recording.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <random>

#include "core/dof.hpp"
#include "core/errors.hpp"

namespace handskin {

bool AngleRecordingOptions::IsValid(std::string* error) const {
  if (kind != "gaussian" && kind != "curved") return invalid(error, "kind must be 'gaussian' or 'curved'");
  if (rows < 10 || rows > 1000000) return invalid(error, "rows must be in [10, 1000000]");
  if (person < 0 || person > 1000) return invalid(error, "person must be in [0, 1000]");
  if (!(offset_sd >= 0 && offset_sd <= 30)) return invalid(error, "offset sd must be in [0, 30] deg");
  if (!(gaps >= 0 && gaps <= 0.5)) return invalid(error, "gaps must be a fraction in [0, 0.5]");
  if (!(noise >= 0 && noise <= 20)) return invalid(error, "noise must be in [0, 20] deg");
  return true;
}

namespace {

const char* const kFingers[] = {"index", "middle", "ring", "little"};

std::vector<std::string> recorded_dofs() {
  std::vector<std::string> d = {"thumb.cmc.abd", "thumb.mcp.flex", "thumb.ip.flex"};
  for (const char* f : kFingers)
    for (const char* j : {".mcp.flex", ".pip.flex", ".dip.flex", ".mcp.abd"}) d.push_back(std::string(f) + j);
  return d;
}

}  // namespace

AngleRecording synth_angle_recording(const AngleRecordingOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("synth angles", err);
  const std::vector<std::string> names = recorded_dofs();
  const Eigen::Index m = static_cast<Eigen::Index>(names.size());
  auto col = [&](const std::string& n) {
    for (Eigen::Index c = 0; c < m; ++c)
      if (names[c] == n) return c;
    HS_CHECK(false, "unknown recorded DOF");
    return Eigen::Index{0};
  };
  // The hand (its loadings and means) comes from the seed alone; the person's offsets from
  // the seed and the person; the frames from all three.
  std::mt19937 hand_rng(o.seed * 7919u + 17u);
  std::normal_distribution<double> N01(0, 1);
  AngleRecording r;
  r.table.columns.clear();
  for (const auto& n : names) r.table.columns.push_back(dof_index(n).value());
  Eigen::VectorXd offset = Eigen::VectorXd::Zero(m);
  if (o.person > 0) {
    std::mt19937 prng(o.seed * 104729u + static_cast<unsigned>(o.person) * 1299709u);
    for (Eigen::Index c = 0; c < m; ++c) offset(c) = o.offset_sd * N01(prng);
  }
  std::mt19937 rng(o.seed * 31u + static_cast<unsigned>(o.person) * 1000003u + 5u);
  std::uniform_real_distribution<double> U(0, 1);
  Eigen::MatrixXd X(o.rows, m);
  Json truth = {{"format", "handskin-angle-truth/1"}, {"kind", o.kind}, {"seed", o.seed}, {"person", o.person}};
  if (o.kind == "gaussian") {
    Eigen::VectorXd mu(m);
    Eigen::MatrixXd L = Eigen::MatrixXd::Zero(m, 3);
    Eigen::VectorXd sd(m);
    for (Eigen::Index c = 0; c < m; ++c) {
      const std::string& n = names[c];
      const double jitter = 1 + 0.2 * N01(hand_rng);
      const bool mcp = n.find(".mcp.flex") != std::string::npos, pip = n.find(".pip.") != std::string::npos,
                 dip = n.find(".dip.") != std::string::npos, abd = n.find(".abd") != std::string::npos;
      mu(c) = mcp ? 35 : pip ? 40 : dip ? 25 : abd ? 0 : 20;
      mu(c) += 3 * N01(hand_rng);
      // Synergy 1: grasp (every flexion); 2: distal curl against the MCPs; 3: spread.
      L(c, 0) = (mcp || pip ? 15 : dip ? 10 : abd ? -1 : 8) * jitter;
      L(c, 1) = (mcp ? -4 : pip ? 10 : dip ? 8 : 0) * jitter;
      L(c, 2) = abd ? (n.rfind("index", 0) == 0 ? -4 : n.rfind("middle", 0) == 0 ? 1 : 4) * jitter : (n == "thumb.cmc.abd" ? 6 : 0);
      sd(c) = dip ? 2 : 3;
    }
    const Eigen::MatrixXd S = L * L.transpose() + Eigen::MatrixXd(sd.array().square().matrix().asDiagonal());
    const Eigen::MatrixXd C = S.llt().matrixL();
    for (long i = 0; i < o.rows; ++i) {
      Eigen::VectorXd e(m);
      for (Eigen::Index c = 0; c < m; ++c) e(c) = N01(rng);
      X.row(i) = (mu + offset + C * e).transpose();
    }
    r.mean = mu + offset;
    r.covariance = S;
    Json cov = Json::array();
    for (Eigen::Index a = 0; a < m; ++a) {
      Json row = Json::array();
      for (Eigen::Index b = 0; b < m; ++b) row.push_back(S(a, b));
      cov.push_back(row);
    }
    truth["mean"] = std::vector<double>(mu.data(), mu.data() + m);
    truth["covariance"] = cov;
  } else {
    // One grasp closure t per frame, each finger a little ahead or behind; the joints follow
    // curves of t that no straight line holds.
    for (long i = 0; i < o.rows; ++i) {
      const double t = U(rng);
      for (const char* f : kFingers) {
        const double tj = std::clamp(t + 0.05 * N01(rng), 0.0, 1.0);
        const std::string s = f;
        X(i, col(s + ".mcp.flex")) = 5 + 80 * tj;
        X(i, col(s + ".pip.flex")) = 5 + 95 * tj * tj;
        X(i, col(s + ".dip.flex")) = 3 + 70 * tj * tj * tj;
        X(i, col(s + ".mcp.abd")) = (s == "index" ? -1 : s == "middle" ? 0 : 1) * 12 * std::cos(M_PI * tj / 2);
      }
      X(i, col("thumb.cmc.abd")) = 20 + 30 * std::sin(M_PI * t);
      X(i, col("thumb.mcp.flex")) = 10 + 45 * t * t;
      X(i, col("thumb.ip.flex")) = 10 + 50 * t * t * t;
      for (Eigen::Index c = 0; c < m; ++c) X(i, c) += o.noise * N01(rng) + offset(c);
    }
    truth["formulas"] = {"t ~ U(0,1) per frame; per finger tj = clamp(t + 0.05 N(0,1), 0, 1)",
                         "mcp.flex = 5 + 80 tj", "pip.flex = 5 + 95 tj^2", "dip.flex = 3 + 70 tj^3",
                         "mcp.abd = (-1, 0, 1, 1 for index, middle, ring, little) * 12 cos(pi tj / 2)",
                         "thumb.cmc.abd = 20 + 30 sin(pi t)", "thumb.mcp.flex = 10 + 45 t^2", "thumb.ip.flex = 10 + 50 t^3",
                         "plus noise N(0, noise^2) per joint and the person's offsets"};
    truth["noise_deg"] = o.noise;
  }
  truth["dofs"] = names;
  truth["person_offsets"] = std::vector<double>(offset.data(), offset.data() + m);
  for (long i = 0; i < o.rows; ++i) {
    std::vector<double> row(static_cast<size_t>(m));
    for (Eigen::Index c = 0; c < m; ++c) row[c] = (o.gaps > 0 && U(rng) < o.gaps) ? std::nan("") : X(i, c);
    r.table.rows.push_back(std::move(row));
    r.table.lines.push_back(i + 2);
  }
  r.truth = truth;
  return r;
}

}  // namespace handskin
