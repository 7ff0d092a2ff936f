#include "synth/cloud_sim.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "core/errors.hpp"
#include "core/random.hpp"
#include "mesh/triangle_tree.hpp"
#include "synth/replica.hpp"

namespace handskin {

bool CloudSimOptions::IsValid(std::string* e) const {
  if (views < 2 || views > 64) return invalid(e, "--views must be in [2, 64]");
  if (!(tilt_deg >= 0 && tilt_deg < 80)) return invalid(e, "--tilt must be in [0, 80) deg");
  if (!(spacing_mm >= 0.2 && spacing_mm <= 5)) return invalid(e, "--spacing must be in [0.2, 5] mm");
  if (!(noise_mm >= 0 && noise_mm <= 5)) return invalid(e, "--noise must be in [0, 5] mm");
  if (!(max_incidence_deg > 0 && max_incidence_deg <= 90)) return invalid(e, "--max-incidence must be in (0, 90] deg");
  if (!(dropout_from_deg >= 0 && dropout_from_deg <= max_incidence_deg))
    return invalid(e, "--dropout-from must be in [0, --max-incidence] deg");
  if (!(stand_radius_mm > 0) || !(stand_gap_mm >= 0)) return invalid(e, "the stand's radius must be > 0 and its gap >= 0");
  if (!(outlier_share >= 0 && outlier_share <= 0.2)) return invalid(e, "--outliers must be in [0, 0.2]");
  if (!(units_per_mm > 0) || !std::isfinite(units_per_mm)) return invalid(e, "units per mm must be > 0");
  return true;
}

namespace {

using K = cgal::K;

// A uniformly random rotation (a normalised 4-D Gaussian as a quaternion) and an offset.
Eigen::Isometry3d random_pose(Rng& rng, double offset_mm) {
  Eigen::Quaterniond q(rng.normal(), rng.normal(), rng.normal(), rng.normal());
  q.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = Eigen::Vector3d(rng.uniform(-offset_mm, offset_mm), rng.uniform(-offset_mm, offset_mm),
                                    rng.uniform(-offset_mm, offset_mm));
  return T;
}

// The stand: a disc square to the hand's long axis (X), `gap` beyond the wrist end.
void add_stand(const std::vector<Eigen::Vector3d>& hv, const CloudSimOptions& o, std::vector<Eigen::Vector3d>* v,
               std::vector<std::array<int, 3>>* f) {
  double x0 = 1e300;
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& p : hv) x0 = std::min(x0, p.x()), c += p;
  c /= static_cast<double>(hv.size());
  const Eigen::Vector3d centre(x0 - o.stand_gap_mm, c.y(), c.z());
  const int first = static_cast<int>(v->size());
  v->push_back(centre);
  constexpr int kRim = 64;
  for (int k = 0; k < kRim; ++k) {
    const double a = 2 * M_PI * k / kRim;
    v->push_back(centre + o.stand_radius_mm * Eigen::Vector3d(0, std::cos(a), std::sin(a)));
  }
  for (int k = 0; k < kRim; ++k) f->push_back({first, first + 1 + k, first + 1 + (k + 1) % kRim});
}

struct Hit {
  Eigen::Vector3d p;
  double incidence_deg;
  bool stand;
};

}  // namespace

CloudSim simulate_cloud(const Mesh& hand, const Rig& rig, const CloudSimOptions& o, std::uint64_t seed) {
  std::string err;
  if (!o.IsValid(&err)) throw InputError("synth cloud options", err);
  check_hand_and_rig(hand, rig);
  Rng rng(seed);
  const Eigen::Isometry3d T_hand_rig = hand_frame_from_rig(rig);
  std::vector<Eigen::Vector3d> v = hand.vertices;
  for (auto& p : v) p = T_hand_rig * p;
  std::vector<std::array<int, 3>> f = hand.faces;  // (not empty: check_hand_and_rig)
  const std::vector<Eigen::Vector3d> hv = v;
  const size_t hand_faces = f.size();
  if (o.stand) add_stand(hv, o, &v, &f);
  const cgal::TriangleTree tt(v, f);

  CloudSim out;
  std::vector<Eigen::Vector3d> A, B;  // hand frame: the back views' points, the palm views'
  for (int k = 0; k < o.views; ++k) {
    const double th = 2 * M_PI * (k + 0.5) / o.views, tilt = o.tilt_deg * M_PI / 180 * (k % 2 ? 1 : -1);
    const Eigen::Vector3d around = -(std::cos(th) * Eigen::Vector3d::UnitZ() + std::sin(th) * Eigen::Vector3d::UnitY());
    const Eigen::Vector3d d = (std::cos(tilt) * around + std::sin(tilt) * Eigen::Vector3d::UnitX()).normalized();
    const Eigen::Vector3d u = d.unitOrthogonal(), w = d.cross(u);
    double u0 = 1e300, u1 = -1e300, w0 = 1e300, w1 = -1e300, t0 = 1e300;
    for (const auto& p : hv)
      u0 = std::min(u0, p.dot(u)), u1 = std::max(u1, p.dot(u)), w0 = std::min(w0, p.dot(w)), w1 = std::max(w1, p.dot(w)),
      t0 = std::min(t0, p.dot(d));
    const int nu = static_cast<int>((u1 - u0) / o.spacing_mm) + 3, nw = static_cast<int>((w1 - w0) / o.spacing_mm) + 3;
    std::vector<std::optional<Hit>> hits(static_cast<size_t>(nu) * nw);
#pragma omp parallel for schedule(dynamic, 8)
    for (int i = 0; i < nu; ++i)
      for (int j = 0; j < nw; ++j) {
        const Eigen::Vector3d origin =
            (u0 + (i - 1) * o.spacing_mm) * u + (w0 + (j - 1) * o.spacing_mm) * w + (t0 - 20.0) * d;
        const auto hit = tt.tree.first_intersection(K::Ray_3(cgal::point(origin), K::Vector_3(d.x(), d.y(), d.z())));
        const K::Point_3* hp = hit ? boost::get<K::Point_3>(&hit->first) : nullptr;
        if (!hp) continue;
        const cgal::Triangle& t = *hit->second;
        const K::Vector_3 nk = CGAL::cross_product(t[1] - t[0], t[2] - t[0]);
        const double len = std::sqrt(nk.squared_length());
        if (!(len > 0)) continue;
        const double c = std::abs((nk.x() * d.x() + nk.y() * d.y() + nk.z() * d.z()) / len);
        const size_t face = static_cast<size_t>(hit->second - tt.triangles.begin());
        hits[static_cast<size_t>(i) * nw + j] = Hit{{hp->x(), hp->y(), hp->z()}, std::acos(std::min(1.0, c)) * 180 / M_PI,
                                                    face >= hand_faces};
      }
    // Dropouts and noise in ray order, from the one generator: the same cloud on any thread count.
    std::vector<Eigen::Vector3d>& half = d.z() < 0 ? A : B;
    for (const auto& h : hits) {
      if (!h) continue;
      if (h->incidence_deg > o.max_incidence_deg) {
        ++out.dropped_grazing;
        continue;
      }
      if (h->incidence_deg > o.dropout_from_deg &&
          rng.uniform() > (o.max_incidence_deg - h->incidence_deg) / (o.max_incidence_deg - o.dropout_from_deg)) {
        ++out.dropped_grazing;
        continue;
      }
      half.push_back(h->p + o.noise_mm * rng.normal() * d);
      ++(h->stand ? out.stand_points : out.hand_points);
    }
  }
  // Stray points in the box around the hand, dealt to the halves in turn.
  Eigen::Vector3d lo = hv[0], hi = hv[0];
  for (const auto& p : hv) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  lo.array() -= 20.0, hi.array() += 20.0;
  out.outliers = static_cast<size_t>(o.outlier_share * static_cast<double>(A.size() + B.size()));
  for (size_t k = 0; k < out.outliers; ++k)
    (k % 2 ? B : A).push_back({rng.uniform(lo.x(), hi.x()), rng.uniform(lo.y(), hi.y()), rng.uniform(lo.z(), hi.z())});

  const Eigen::Isometry3d T_a = o.arbitrary_pose ? random_pose(rng, 300) : Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d T_b = o.arbitrary_pose ? random_pose(rng, 300) : Eigen::Isometry3d::Identity();
  out.cloud_from_hand = T_b;
  out.a_to_b = T_b * T_a.inverse();
  const double s = o.units_per_mm;
  for (const auto& p : A) out.half_a.push_back(s * (T_a * p)), out.points.push_back(s * (T_b * p));
  for (const auto& p : B) out.half_b.push_back(s * (T_b * p)), out.points.push_back(s * (T_b * p));

  const Eigen::Isometry3d T_cloud_rig = T_b * T_hand_rig;
  out.skin = hand;
  for (Eigen::Vector3d& p : out.skin.vertices) p = T_cloud_rig * p;
  out.rig = rig;
  out.rig.frame = "palm";
  for (auto& j : out.rig.joints) j = T_cloud_rig * j;
  out.rig.palm_normal = T_b.linear() * Eigen::Vector3d::UnitZ();
  return out;
}

}  // namespace handskin
