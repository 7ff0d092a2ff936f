#include "skin/slices.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "core/dof.hpp"
#include "core/errors.hpp"

namespace handskin {

std::string Bone::name() const { return std::string(joints()[joint].name) + ">" + joints()[child].name; }

std::vector<Bone> bones_from_rig(const Rig& rig) {
  std::vector<Bone> out;
  for (int j = 1; j < kJointCount; ++j) {
    const int p = joints()[j].parent;
    out.push_back({p, j, rig.joints[p], rig.joints[j]});
  }
  return out;
}

bool SliceOptions::IsValid(std::string* error) const {
  auto bad = [&](const std::string& m) {
    if (error) *error = m;
    return false;
  };
  if (planes < 3 || planes > 1000) return bad("slicing.planes must be in [3, 1000]");
  if (points_per_segment < 2 || points_per_segment > 200) return bad("slicing.points_per_segment must be in [2, 200]");
  if (smoothing < 0 || smoothing > 5) return bad("smoothing must be in [0, 5]");
  if (!(closed_gap_deg > 0 && closed_gap_deg < 360)) return bad("closed_gap_deg must be in (0, 360)");
  if (min_points < 2) return bad("min_points must be >= 2");
  return true;
}

namespace {

constexpr double kTwoPi = 2 * M_PI;

double wrap(double a) {  // to [0, 2π)
  a = std::fmod(a, kTwoPi);
  return a < 0 ? a + kTwoPi : a;
}

// A plane's measured profile of one link: radius against angle, sorted.
struct Profile {
  std::vector<double> phi, rho;  ///< sorted by phi in [0, 2π)
  bool closed = false;
  std::vector<std::pair<double, double>> arcs;  ///< covered arcs: start, length (counter-clockwise)
  double largest_gap = 0;
  bool has(double p) const {
    if (closed) return true;
    for (const auto& [a, l] : arcs)
      if (wrap(p - a) <= l + 1e-12) return true;
    return false;
  }
  /// Closed profiles: a second-order Fourier fit ρ(φ) = a0 + Σ ak cos kφ + bk sin kφ — an
  /// off-centre ellipse — to bridge the gaps neither scan saw (the flanks).
  Eigen::Matrix<double, 5, 1> fourier = Eigen::Matrix<double, 5, 1>::Zero();
  bool has_fourier = false;
  double fourier_at(double p) const {
    return fourier(0) + fourier(1) * std::cos(p) + fourier(2) * std::sin(p) + fourier(3) * std::cos(2 * p) +
           fourier(4) * std::sin(2 * p);
  }
  // The radius at angle p: the mean of the measured radii within ±window of p where the data
  // are dense (a scan gives many points per angle and plane, so one neighbour pair would
  // pick noise); else linear interpolation between the measured neighbours (eqs. 4.1–4.2);
  // across a gap wider than `bridge` a closed profile takes its Fourier fit instead.
  double at(double p, double window = 0.035, double bridge = 0.2) const {
    const size_t n = phi.size();
    p = wrap(p);
    double sum = 0;
    int count = 0;
    auto add_range = [&](double a, double b) {  // [a, b] within [0, 2π)
      for (auto it = std::lower_bound(phi.begin(), phi.end(), a); it != phi.end() && *it <= b; ++it)
        sum += rho[static_cast<size_t>(it - phi.begin())], ++count;
    };
    if (p - window < 0) add_range(0, p + window), add_range(p - window + kTwoPi, kTwoPi);
    else if (p + window >= kTwoPi) add_range(p - window, kTwoPi), add_range(0, p + window - kTwoPi);
    else add_range(p - window, p + window);
    if (count >= 3) return sum / count;
    const auto it = std::upper_bound(phi.begin(), phi.end(), p);
    size_t hi = static_cast<size_t>(it - phi.begin()) % n;
    size_t lo = (hi + n - 1) % n;
    double span = wrap(phi[hi] - phi[lo]);
    if (span == 0) return rho[lo];
    if (has_fourier && span > bridge) return fourier_at(p);
    const double t = wrap(p - phi[lo]) / span;
    return rho[lo] + t * (rho[hi] - rho[lo]);
  }
};

double segment_distance2(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-12), 0.0, 1.0);
  return (a + t * ab - p).squaredNorm();
}

}  // namespace

Slicing slice_cloud(const std::vector<Eigen::Vector3d>& points, const Rig& rig, const SliceOptions& o) {
  return slice_cloud(points, bones_from_rig(rig), hand_frame_from_rig(rig), o);
}

Slicing slice_cloud(const std::vector<Eigen::Vector3d>& pts, const std::vector<Bone>& bones,
                    const Eigen::Isometry3d& T, const SliceOptions& o) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("slicing options", err);
  if (pts.size() < 100) throw InputError("merged cloud", "only " + std::to_string(pts.size()) + " points to slice");
  Slicing s;
  s.T_hand_rig = T;
  s.bones = bones;
  s.points = pts.size();
  std::vector<Eigen::Vector3d> q(pts.size());
  double x0 = 1e300, x1 = -1e300;
  for (size_t i = 0; i < pts.size(); ++i) {
    q[i] = T * pts[i];
    x0 = std::min(x0, q[i].x());
    x1 = std::max(x1, q[i].x());
  }
  s.spacing = (x1 - x0) / o.planes;
  for (int k = 0; k < o.planes; ++k) s.plane_x.push_back(x0 + (k + 0.5) * s.spacing);
  std::vector<Eigen::Vector3d> A, B;
  for (const Bone& b : bones) A.push_back(T * b.a), B.push_back(T * b.b);

  // --- each point to its plane's slab, projected, and to its nearest link (3D distance) ---
  const size_t nb = bones.size();
  std::vector<std::vector<std::vector<Eigen::Vector2d>>> groups(o.planes, std::vector<std::vector<Eigen::Vector2d>>(nb));
  for (const Eigen::Vector3d& p : q) {
    const int k = std::clamp(static_cast<int>((p.x() - x0) / s.spacing), 0, o.planes - 1);
    const Eigen::Vector3d pp(s.plane_x[k], p.y(), p.z());
    size_t best = 0;
    double bd = 1e300;
    for (size_t b = 0; b < nb; ++b) {
      const double d = segment_distance2(pp, A[b], B[b]);
      if (d < bd) bd = d, best = b;
    }
    groups[k][best].emplace_back(p.y(), p.z());
  }

  // --- per plane and link: the link's crossing as centre, the measured profile ---
  auto centre_of = [&](size_t b, double x) {
    const Eigen::Vector3d a = A[b], c = B[b];
    Eigen::Vector3d m;
    if ((a.x() - x) * (c.x() - x) <= 0 && std::abs(c.x() - a.x()) > 1e-9) m = a + (x - a.x()) / (c.x() - a.x()) * (c - a);
    else m = std::abs(a.x() - x) < std::abs(c.x() - x) ? a : c;
    return Eigen::Vector2d(m.y(), m.z());
  };
  std::vector<std::vector<std::optional<Profile>>> prof(o.planes, std::vector<std::optional<Profile>>(nb));
  std::vector<std::vector<Eigen::Vector2d>> centre(o.planes, std::vector<Eigen::Vector2d>(nb));
  const double closed_gap = o.closed_gap_deg * M_PI / 180.0;
  for (int k = 0; k < o.planes; ++k)
    for (size_t b = 0; b < nb; ++b) {
      centre[k][b] = centre_of(b, s.plane_x[k]);
      const auto& g = groups[k][b];
      if (static_cast<long>(g.size()) < o.min_points) continue;
      std::vector<std::pair<double, double>> pr;
      for (const auto& yz : g) {
        const Eigen::Vector2d d = yz - centre[k][b];
        pr.emplace_back(wrap(std::atan2(d.y(), d.x())), d.norm());
      }
      std::sort(pr.begin(), pr.end());
      Profile P;
      for (const auto& [a, r] : pr) P.phi.push_back(a), P.rho.push_back(r);
      // Gaps in angle wider than the limit split the profile into arcs: a metacarpal's sector
      // of the palm is a dorsal and a palmar arc, with the neighbours' sectors between. A
      // profile without such a gap goes all the way round (closed).
      const size_t m = P.phi.size();
      std::vector<size_t> gap_after;  // index i: a wide gap from phi[i] to phi[i + 1]
      for (size_t i = 0; i < m; ++i) {
        const double g = i + 1 < m ? P.phi[i + 1] - P.phi[i] : P.phi.front() + kTwoPi - P.phi.back();
        P.largest_gap = std::max(P.largest_gap, g);
        if (g >= closed_gap) gap_after.push_back(i);
      }
      P.closed = gap_after.empty();
      if (P.closed && m >= 10) {
        Eigen::MatrixXd M(m, 5);
        Eigen::VectorXd r(m);
        for (size_t i = 0; i < m; ++i) {
          const double a = P.phi[i];
          M.row(i) << 1, std::cos(a), std::sin(a), std::cos(2 * a), std::sin(2 * a);
          r(i) = P.rho[i];
        }
        P.fourier = M.colPivHouseholderQr().solve(r);
        P.has_fourier = P.fourier.allFinite();
      }
      for (size_t g = 0; g < gap_after.size(); ++g) {
        const size_t first = (gap_after[g] + 1) % m;
        const size_t last = gap_after[(g + 1) % gap_after.size()];
        P.arcs.emplace_back(P.phi[first], wrap(P.phi[last] - P.phi[first]));
      }
      prof[k][b] = std::move(P);
    }

  // --- resample, smoothing each radius over neighbouring planes (binomial weights) ---
  const int n = o.points_per_segment;
  std::vector<double> weights;
  for (int d = -o.smoothing; d <= o.smoothing; ++d) {
    double w = 1;  // binomial coefficient C(2m, m + d)
    for (int i = 1; i <= o.smoothing + d; ++i) w = w * (2 * o.smoothing - i + 1) / i;
    weights.push_back(w);
  }
  for (int k = 0; k < o.planes; ++k)
    for (size_t b = 0; b < nb; ++b) {
      if (!prof[k][b]) continue;
      const Profile& P = *prof[k][b];
      Section sec;
      sec.plane = k;
      sec.bone = static_cast<int>(b);
      sec.closed = P.closed;
      sec.measured = groups[k][b].size();
      sec.largest_gap_deg = P.largest_gap * 180.0 / M_PI;
      const Eigen::Vector2d c = centre[k][b];
      sec.centre = T.inverse() * Eigen::Vector3d(s.plane_x[k], c.x(), c.y());
      std::vector<double> sample_phi;  // closed: fixed angles, the same in every plane; else each arc, ends included
      if (P.closed)
        for (int j = 0; j < n; ++j) sample_phi.push_back(kTwoPi * j / n);
      else
        for (const auto& [a, l] : P.arcs)
          for (int j = 0; j < n; ++j) sample_phi.push_back(wrap(a + l * j / (n - 1)));
      sec.arcs = P.closed ? 0 : static_cast<int>(P.arcs.size());
      for (const double phi : sample_phi) {
        const double raw = P.at(phi);
        double sum = 0, wsum = 0;
        for (int d = -o.smoothing; d <= o.smoothing; ++d) {
          const int kk = k + d;
          if (kk < 0 || kk >= o.planes || !prof[kk][b] || !prof[kk][b]->has(phi)) continue;
          sum += weights[d + o.smoothing] * prof[kk][b]->at(phi);
          wsum += weights[d + o.smoothing];
        }
        const double rho = wsum > 0 ? sum / wsum : raw;
        sec.phi.push_back(phi);
        sec.rho_raw.push_back(raw);
        sec.rho.push_back(rho);
        sec.points.push_back(T.inverse() *
                             Eigen::Vector3d(s.plane_x[k], c.x() + rho * std::cos(phi), c.y() + rho * std::sin(phi)));
      }
      s.sections.push_back(std::move(sec));
    }
  if (s.sections.empty()) throw InputError("merged cloud", "no plane holds enough points of any bone link");
  return s;
}

Json slicing_to_json(const Slicing& s) {
  Json j;
  j["format"] = "handskin-slices/1";
  j["spacing_mm"] = s.spacing;
  j["plane_x_mm"] = s.plane_x;
  j["hand_from_rig"] = Json::array();
  for (int r = 0; r < 4; ++r) {
    Json row = Json::array();
    for (int c = 0; c < 4; ++c) row.push_back(s.T_hand_rig.matrix()(r, c));
    j["hand_from_rig"].push_back(row);
  }
  Json bones = Json::array();
  for (const auto& b : s.bones) bones.push_back(b.name());
  j["bones"] = bones;
  Json secs = Json::array();
  for (const auto& sec : s.sections) {
    Json pts = Json::array(), phi = Json::array(), rho = Json::array();
    for (size_t i = 0; i < sec.points.size(); ++i) {
      pts.push_back(to_json(sec.points[i]));
      phi.push_back(sec.phi[i] * 180.0 / M_PI);
      rho.push_back(sec.rho[i]);
    }
    secs.push_back({{"plane", sec.plane}, {"bone", sec.bone}, {"closed", sec.closed}, {"measured", sec.measured},
                    {"largest_gap_deg", sec.largest_gap_deg}, {"centre", to_json(sec.centre)}, {"phi_deg", phi},
                    {"rho_mm", rho}, {"points", pts}});
  }
  j["sections"] = secs;
  return j;
}

}  // namespace handskin
