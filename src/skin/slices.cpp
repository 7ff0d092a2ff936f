#include "skin/slices.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include "core/dof.hpp"
#include "core/errors.hpp"
#include "skin/profile.hpp"

namespace handskin {

bool SliceOptions::IsValid(std::string* error) const {
  if (planes < 3 || planes > 1000) return invalid(error, "slicing.planes must be in [3, 1000]");
  if (points_per_segment < 2 || points_per_segment > 200) return invalid(error, "slicing.points_per_segment must be in [2, 200]");
  if (smoothing < 0 || smoothing > 5) return invalid(error, "smoothing must be in [0, 5]");
  if (!(closed_gap_deg > 0 && closed_gap_deg < 360)) return invalid(error, "closed_gap_deg must be in (0, 360)");
  if (min_points < 2) return invalid(error, "min_points must be >= 2");
  return true;
}

using profile::kTwoPi;
using profile::Profile;
using profile::segment_distance2;
using profile::wrap;

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
      if (P.closed) profile::fit_fourier(&P);
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

}  // namespace handskin
